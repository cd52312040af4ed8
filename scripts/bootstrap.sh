#!/usr/bin/env bash
# Installs the Debian packages btfkit needs to build, test and run its demo. Idempotent: when
# everything is present it changes nothing and needs no network. Run as root or with sudo.
# With --bench it also installs what the benchmarks compare against (scikit-learn with OpenBLAS).
set -euo pipefail

packages=(
  build-essential cmake ninja-build pkg-config clang-format git
  libeigen3-dev libopenblas-dev liblapacke-dev
  libopenimageio-dev libimath-dev
  libzip-dev zip
  libhdf5-dev
  libqhull-dev
  libkissfft-dev
  libtbb-dev
  libembree-dev libtinyobjloader-dev
  libcli11-dev libfmt-dev nlohmann-json3-dev
  libxxhash-dev libzstd-dev libdeflate-dev
  libboost-dev
  libgtest-dev libgmock-dev libbenchmark-dev libexpat1-dev
  python3 python3-h5py python3-numpy
)
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
  exit 0
fi

echo "bootstrap: installing ${missing[*]}"
sudo=""
if [ "$(id -u)" -ne 0 ]; then sudo="sudo"; fi
export DEBIAN_FRONTEND=noninteractive
$sudo apt-get update -qq
$sudo apt-get install -y -qq --no-install-recommends "${missing[@]}"
echo "bootstrap: done"
