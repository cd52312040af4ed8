#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# Installs the Debian packages btfkit needs to build, test and run its demo, and the web viewer's
# npm packages. Idempotent: when everything is present it changes nothing and needs no network.
# Run as root or with sudo.
# With --bench it also installs what the benchmarks compare against (scikit-learn with OpenBLAS).
set -euo pipefail

packages=(
  build-essential cmake ninja-build pkg-config clang-format git
  libeigen3-dev libopenblas-dev liblapacke-dev
  libopenimageio-dev libimath-dev libjpeg-dev
  libzip-dev zip
  libhdf5-dev
  libqhull-dev
  libkissfft-dev
  libtbb-dev
  openmpi-bin libopenmpi-dev  # distributed compression (mpirun btf compress, compress-many)
  libembree-dev libtinyobjloader-dev
  libcli11-dev libfmt-dev nlohmann-json3-dev
  libxxhash-dev libzstd-dev libdeflate-dev
  libboost-dev
  libgtest-dev libgmock-dev libbenchmark-dev libexpat1-dev
  python3 python3-h5py python3-numpy python3-matplotlib
  python3-dev pybind11-dev python3-pytest  # the Python module (make python) and its tests
  chromium nginx
  clang-14 libfuzzer-14-dev  # make fuzz, make test-sanitize
  dpkg-dev lintian man-db  # make package (dpkg-shlibdeps), its test (lintian, man --warnings)
)
# The web viewer is built with node and npm; any node ≥ 18 will do (Debian's, or one installed
# from elsewhere, whose package may not be called nodejs).
if ! command -v node > /dev/null || ! command -v npm > /dev/null; then
  packages+=(nodejs npm)
fi
if [ "${1:-}" = "--bench" ]; then
  packages+=(python3-sklearn libopenblas0-pthread)
fi

missing=()
for p in "${packages[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if [ ${#missing[@]} -eq 0 ]; then
  echo "bootstrap: all ${#packages[@]} packages present"
else
  echo "bootstrap: installing ${missing[*]}"
  sudo=""
  if [ "$(id -u)" -ne 0 ]; then sudo="sudo"; fi
  export DEBIAN_FRONTEND=noninteractive
  $sudo apt-get update -qq
  # nginx is only for the tests, which start their own on a free port: keep Debian's service from
  # starting on port 80 (a policy-rc.d that denies, unless the machine has one already).
  policy=/usr/sbin/policy-rc.d
  if [ ! -e "$policy" ]; then
    printf '#!/bin/sh\nexit 101\n' | $sudo tee "$policy" > /dev/null
    $sudo chmod 755 "$policy"
    trap '$sudo rm -f "$policy"' EXIT
  fi
  $sudo apt-get install -y -qq --no-install-recommends "${missing[@]}"
  echo "bootstrap: done"
fi

# The viewer's npm packages, exactly as web/package-lock.json pins them; only when the lock file
# changed since the last install (npm writes node_modules/.package-lock.json).
web="$(cd "$(dirname "$0")/.." && pwd)/web"
if [ ! -f "$web/node_modules/.package-lock.json" ] ||
   [ "$web/package-lock.json" -nt "$web/node_modules/.package-lock.json" ]; then
  echo "bootstrap: installing the viewer's npm packages (web/package-lock.json)"
  (cd "$web" && npm ci --no-audit --no-fund --loglevel=error)
else
  echo "bootstrap: the viewer's npm packages are present"
fi
