#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# CTest's Install.consumer and Install.python (cmake/install.cmake): installs this build into a
# fresh temporary prefix and uses it there as a user would.
#
#   consumer  `cmake --install`: the files (public headers only, nothing naming this tree), the
#             installed `btf`, btf/btf.h compiled on its own, examples/cpp built with CMake
#             (find_package) and with pkg-config, both run, their output checked and compared
#   python    `cmake --install --component python`: only the module and the libraries it loads,
#             the module imported from the prefix
#   deb       the Debian package of `make package` (DEB, version VERSION): its fields and files,
#             lintian, and btf, the module and examples/cpp run from a copy unpacked by dpkg-deb
#
# Usage: install_consumer.sh consumer|python|deb BUILD_DIR SOURCE_DIR
# Environment (CTest sets it): CMAKE, CXX, NINJA, PKG_CONFIG, LIBDIR, INCLUDEDIR, BINDIR; for
# python also PYTHON and PYTHON_DIR (the module's folder relative to the prefix); for deb DEB,
# VERSION, RELEASE_BTF (this build's btf) and PYTHON.
# Nothing is written outside the temporary folder but CMake's install_manifest*.txt in BUILD_DIR.
set -euo pipefail

mode=$1 build=$2 source=$3
work=$(mktemp -d "${TMPDIR:-/tmp}/btfkit-install.XXXXXX")
trap 'rm -rf "$work"' EXIT
prefix=$work/prefix

fail() {
    echo "install_consumer.sh: $*" >&2
    exit 1
}

# Runs a command with its output in a log that is shown only when it fails.
quiet() {
    local log=$work/step.log
    if ! "$@" >"$log" 2>&1; then
        cat "$log" >&2
        fail "failed: $*"
    fi
}

# The output of examples/cpp (file $1): what it must say and values in their ranges. The numbers
# are the example's own (woven_fabric, 32×32 texels, seed 1, fmf with 8 components).
check_example_output() {
    local out=$1
    grep -qx 'source: synthetic, 32x32 texels, 81 views x 81 lights' "$out" ||
        fail "example: the source line is wrong or missing"
    awk '
        function bad(what) { print "example: " what ": " $0 > "/dev/stderr"; failed = 1 }
        /^package: / { packages++
                       if (!($3 + 0 > 10000 && $6 + 0 > 4)) bad("package size or ratio") }
        /^eval / { evals++
                   for (i = 12; i <= 14; i++) if (!($i > 0.01 && $i < 2)) bad("eval value")
                   if (evals > 1 && !($12 < last)) bad("red not falling as the light goes down")
                   last = $12 }
        /^sample: / { samples++; gsub(/[(),]/, "")
                      if (!($3 >= 0 && $3 <= 90 && $6 > 0 && $6 == $8)) bad("sample or its pdf") }
        /^albedo: / { albedos++
                      for (i = 3; i <= 5; i++) if (!($i > 0.01 && $i < 1)) bad("albedo") }
        /^quality: / { qualities++; gsub(/,/, "")
                       if (!($3 > 0 && $3 < 0.05 && $5 > 25 && $9 < 5)) bad("quality") }
        END { if (packages != 1 || evals != 3 || samples != 1 || albedos != 1 || qualities != 1) {
                  print "example: lines missing" > "/dev/stderr"; failed = 1 }
              exit failed }' "$out" || fail "the example's output is wrong"
}

install_consumer() {
    quiet "$CMAKE" --install "$build" --prefix "$prefix"

    # The files a user needs, and no internal header.
    for file in "$BINDIR/btf" "$LIBDIR/btfkit/libbtfkit_images.so" "$INCLUDEDIR/btf/btf.h" \
        "$INCLUDEDIR/btf/codecs/codec.h" "$INCLUDEDIR/btf/render/scene_file.h" \
        "$LIBDIR/cmake/btfkit/btfkitConfig.cmake" "$LIBDIR/cmake/btfkit/btfkitConfigVersion.cmake" \
        "$LIBDIR/pkgconfig/btfkit.pc"; do
        [[ -f $prefix/$file ]] || fail "not installed: $file"
    done
    compgen -G "$prefix/$LIBDIR/libbtfkit.*" >/dev/null || fail "libbtfkit not installed"
    for internal in btf/codecs/fmf/fmf.h btf/codecs/factor/model.h btf/stream/server.h \
        btf/testing/support.h btf/core/image_module.h; do
        [[ ! -e $prefix/$INCLUDEDIR/$internal ]] || fail "internal header installed: $internal"
    done
    ! find "$prefix/$INCLUDEDIR" -type f ! -name '*.h' | grep . || fail "not a header (above)"
    echo "installed $(find "$prefix/$INCLUDEDIR" -name '*.h' | wc -l) headers"
    # The package files name the prefix relative to themselves, never this tree.
    ! grep -rl -e "$source" -e "$build" "$prefix/$LIBDIR/cmake" "$prefix/$LIBDIR/pkgconfig" ||
        fail "the files above name the build or source tree"
    local codecs
    codecs=$("$prefix/$BINDIR/btf" codecs) || fail "the installed btf failed"
    grep -q '^fmf ' <<<"$codecs" || fail "the installed btf lists no fmf codec"
    # Pictures go through the image module installed beside it, not this build's (the prefix
    # differs from the configured one).
    local formats
    formats=$("$prefix/$BINDIR/btf" formats) || fail "btf formats failed"
    grep -q "^images .*through $prefix/$LIBDIR/btfkit/" <<<"$formats" ||
        fail "the installed btf does not load the installed image module: $(tail -1 <<<"$formats")"

    export PKG_CONFIG_PATH=$prefix/$LIBDIR/pkgconfig
    local cflags libs
    cflags=$("$PKG_CONFIG" --cflags btfkit) || fail "pkg-config --cflags btfkit failed"
    libs=$("$PKG_CONFIG" --libs btfkit) || fail "pkg-config --libs btfkit failed"

    # btf/btf.h on its own, with nothing but what pkg-config says.
    # shellcheck disable=SC2086  # the flags are words
    echo '#include <btf/btf.h>' | quiet "$CXX" -std=c++20 -fsyntax-only $cflags -x c++ -

    # examples/cpp through find_package(btfkit CONFIG).
    quiet "$CMAKE" -S "$source/examples/cpp" -B "$work/cmake-build" -G Ninja \
        -DCMAKE_MAKE_PROGRAM="$NINJA" -DCMAKE_CXX_COMPILER="$CXX" -DCMAKE_PREFIX_PATH="$prefix" \
        -DCMAKE_FIND_USE_PACKAGE_REGISTRY=OFF
    local cache=$work/cmake-build/CMakeCache.txt
    grep -qx "btfkit_DIR:PATH=$prefix/$LIBDIR/cmake/btfkit" "$cache" ||
        fail "find_package(btfkit) found another btfkit: $(grep btfkit_DIR "$cache")"
    quiet "$CMAKE" --build "$work/cmake-build"
    mkdir "$work/out-cmake" "$work/out-pc"
    "$work/cmake-build/btfkit_example" "$work/out-cmake" >"$work/cmake.txt" ||
        fail "the example (CMake) failed"
    cat "$work/cmake.txt"
    check_example_output "$work/cmake.txt"
    [[ -s $work/out-cmake/woven_fabric.btfpkg ]] || fail "the example wrote no package"

    # The same program through pkg-config: the same library, so the same numbers.
    # A shared libbtfkit is found at run time through an rpath, as a user would add one (or
    # LD_LIBRARY_PATH, or an ldconfig folder).
    [[ ! -e $prefix/$LIBDIR/libbtfkit.so ]] || libs="$libs -Wl,-rpath,$prefix/$LIBDIR"
    # shellcheck disable=SC2086
    quiet "$CXX" -std=c++20 "$source/examples/cpp/main.cpp" $cflags $libs -o "$work/pc_example"
    "$work/pc_example" "$work/out-pc" >"$work/pc.txt" || fail "the example (pkg-config) failed"
    diff <(sed "s|$work/out-cmake|OUT|" "$work/cmake.txt") \
        <(sed "s|$work/out-pc|OUT|" "$work/pc.txt") ||
        fail "the example built with pkg-config says something else (above)"
}

install_python() {
    quiet "$CMAKE" --install "$build" --component python --prefix "$prefix"
    local site=$prefix/$PYTHON_DIR
    [[ -f $site/btfkit/__init__.py ]] || fail "not installed: $PYTHON_DIR/btfkit/__init__.py"
    compgen -G "$site/btfkit/_btfkit*.so" >/dev/null || fail "not installed: the native module"
    # The module and the libraries it loads, nothing else.
    ! find "$prefix" -type f ! -path "$site/btfkit/*" ! -path "$prefix/$LIBDIR/btfkit/*" \
        ! -path "$prefix/$LIBDIR/libbtfkit.so*" | grep . ||
        fail "--component python installed more than the module (above)"
    [[ -f $prefix/$LIBDIR/btfkit/libbtfkit_images.so ]] || fail "not installed: the image module"
    # The folder is where this Python looks under some prefix (Debian's: /usr/local and /usr).
    "$PYTHON" -c 'import sys; sys.exit(not any(p.endswith("/" + sys.argv[1]) for p in sys.path))' \
        "$PYTHON_DIR" || fail "$PYTHON does not search */$PYTHON_DIR"
    # Imported from the prefix only (not from the build tree), and working.
    cat >"$work/import.py" <<'EOF'
import sys
import btfkit
assert btfkit.__file__.startswith(sys.argv[1]), btfkit.__file__
source = btfkit.synth("woven_fabric", 8)
image = source.image(0, 0)
assert image.shape == (8, 8, 3) and image.min() >= 0 and image.max() > 0, image
assert "fmf" in btfkit.codecs()
# Pictures through the image module installed beside it (the prefix is not the configured one).
module = btfkit._btfkit._image_module()
assert module.startswith(sys.argv[2] + "/"), module
print("imported", btfkit.__file__, "images through", module)
EOF
    (cd "$work" && PYTHONPATH=$site "$PYTHON" -s import.py "$site" "$prefix") ||
        fail "import from the prefix failed"
}

# The Debian package that `make package` built ($DEB): its control fields and files, lintian, and
# the command, the Python module and a C++ consumer run from a copy unpacked into a temporary root
# (dpkg-deb -x: no chroot, nothing installed on this machine).
install_deb() {
    [[ -f $DEB ]] || fail "$DEB is missing: \`make package\` builds it (\`make test\` does)"
    local field
    for field in Package:btfkit "Version:$VERSION" Architecture:amd64 Section:science; do
        [[ $(dpkg-deb -f "$DEB" "${field%%:*}") == "${field#*:}" ]] ||
            fail "control field ${field%%:*} is '$(dpkg-deb -f "$DEB" "${field%%:*}")', not '${field#*:}'"
    done
    # Depends as dpkg-shlibdeps computed it from the programs' shared libraries (versioned
    # entries for libc and the C++ library), and Python for the module.
    local depends
    depends=$(dpkg-deb -f "$DEB" Depends)
    echo "Depends: $depends"
    local need
    for need in 'libc6 (>= ' 'libstdc++6 (>= ' 'libopenimageio' 'libhdf5' 'libopenblas' \
        'python3 (>= ' 'python3-numpy'; do
        grep -qF "$need" <<<"$depends" || fail "Depends names no '$need'"
    done
    # docs/licences.md names every package the binary package depends on.
    local package
    for package in $(tr ',' '\n' <<<"$depends" | sed 's/[(|].*//' | tr -d ' ' | sort -u); do
        grep -q "^| $package |" "$source/docs/licences.md" ||
            fail "docs/licences.md does not list $package (scripts/licences.py remakes it)"
    done

    # The files: every one owned by root, and what each part needs.
    dpkg-deb -c "$DEB" >"$work/contents.txt"
    ! awk '$2 != "root/root"' "$work/contents.txt" | grep . || fail "files not owned by root (above)"
    local lib
    lib=usr/lib/$(dpkg-architecture -qDEB_HOST_MULTIARCH)
    local file
    for file in usr/bin/btf usr/share/man/man1/btf.1.gz usr/share/btfkit/web/index.html \
        usr/share/btfkit/web/viewer.js usr/share/doc/btfkit/copyright \
        usr/share/doc/btfkit/changelog.gz "$lib/btfkit/libbtfkit_images.so" "$lib/libbtfkit.a" \
        "$lib/cmake/btfkit/btfkitConfig.cmake" "$lib/pkgconfig/btfkit.pc" usr/include/btf/btf.h \
        usr/lib/python3/dist-packages/btfkit/__init__.py; do
        grep -q " \./$file\$" "$work/contents.txt" || fail "not in the package: /$file"
    done
    ! grep -E '\.map$' "$work/contents.txt" || fail "source maps in the package (above)"

    # lintian, Debian's package checker: no errors (its other findings are printed).
    lintian --fail-on error --tag-display-limit 0 "$DEB" >"$work/lintian.txt" 2>&1 || {
        cat "$work/lintian.txt" >&2
        fail "lintian reports errors (above)"
    }
    echo "lintian: no errors; $(grep -c '' "$work/lintian.txt") lines:"
    sed 's/^/  /' "$work/lintian.txt"

    local root=$work/root
    quiet dpkg-deb -x "$DEB" "$root"
    local btf=$root/usr/bin/btf
    # The version line (version and commit) is this checkout's build's.
    local version
    version=$("$btf" --version) || fail "the packaged btf --version failed"
    [[ $version == "$("$RELEASE_BTF" --version)" && $version == "btfkit $VERSION"* ]] ||
        fail "the packaged btf says '$version'; this build says '$("$RELEASE_BTF" --version)'"
    echo "btf --version: $version"
    # Pictures through the packaged image module.
    grep -q "^images .*through $root/$lib/btfkit/" <<<"$("$btf" formats)" ||
        fail "the packaged btf does not load the packaged image module"
    # A package made by the packaged command; `btf bundle` takes the packaged viewer.
    quiet "$btf" -q synth --preset woven_fabric --size 8 -o "$work/m.h5"
    quiet "$btf" -q compress "$work/m.h5" -o "$work/m.btfpkg" --codec fmf --components 2
    quiet "$btf" -q bundle "$work/m.btfpkg" -o "$work/site"
    cmp -s "$work/site/viewer.js" "$root/usr/share/btfkit/web/viewer.js" ||
        fail "btf bundle did not copy the packaged viewer"
    # The packaged evaluators run clones for this processor's x86-64 level (src/btf/util/clones.h):
    # they must give the native build's values. Deterministic queries to within float rounding,
    # and the sum of 65536 random stochastic ones (each drawn from the same numbers) to within 1e-5.
    local level
    level=$("$btf" --verbose codecs 2>&1 >/dev/null | grep -o 'evaluators: [^;]*') ||
        fail "btf --verbose names no evaluators' code"
    [[ $level =~ ^evaluators:\ x86-64(-v3|-v4)?\ clones$ ]] ||
        fail "the packaged btf says '$level': it has no clones of the evaluators"
    echo "packaged btf: $level"
    awk 'BEGIN { srand(7); for (i = 0; i < 64; i++)
                   printf "%.4f,%.4f %.2f,%.2f %.2f,%.2f\n", rand(), rand(), 85 * rand(),
                          360 * rand(), 85 * rand(), 360 * rand() }' >"$work/queries.txt"
    same_values() {
        local codec=$1 package=$2 b p
        "$btf" eval "$package" --queries "$work/queries.txt" >"$work/package.txt" ||
            fail "the packaged btf could not evaluate $codec's package"
        "$RELEASE_BTF" eval "$package" --queries "$work/queries.txt" >"$work/native.txt" ||
            fail "this build's btf could not evaluate $codec's package"
        paste -d ' ' "$work/package.txt" "$work/native.txt" | awk -v codec="$codec" '
            function abs(x) { return x < 0 ? -x : x }
            { for (i = 1; i <= 3; i++) if (abs($i - $(i + 3)) > 1e-5 * (1 + abs($(i + 3)))) {
                  printf "%s: query %d: the package gives %s, this build %s\n", codec, NR, $i,
                         $(i + 3) > "/dev/stderr"; exit 1 } }
            END { if (NR != 64) { print codec ": " NR " values, not 64" > "/dev/stderr"; exit 1 } }' ||
            fail "the packaged btf evaluates $codec's package differently"
        checksum() {
            "$1" -q bench eval "$package" --queries 65536 --repeat 1 --json |
                python3 -c 'import json, sys; print(json.load(sys.stdin)["checksum"])'
        }
        b=$(checksum "$btf") && p=$(checksum "$RELEASE_BTF") ||
            fail "btf bench eval failed on $codec's package"
        awk -v a="$b" -v b="$p" 'BEGIN { d = a - b; exit !(a > 0 && (d < 0 ? -d : d) <= 1e-5 * b) }' ||
            fail "$codec: the packaged btf's random stochastic values sum to $b, this build's to $p"
    }
    # Packages go between builds for different processors (this build is -march=native, the
    # package's x86-64): each codec's package from one opens and evaluates in the other.
    local codec options writer reader codecs=0
    while read -r codec options; do
        for writer in "$btf" "$RELEASE_BTF"; do
            reader=$RELEASE_BTF
            [[ $writer == "$RELEASE_BTF" ]] && reader=$btf
            # shellcheck disable=SC2086  # the options are words
            quiet "$writer" -q compress "$work/m.h5" -o "$work/x.btfpkg" --codec "$codec" \
                $options --no-error
            quiet "$reader" eval "$work/x.btfpkg" --uv 0.3,0.6 --light 30,40 --view 20,200
        done
        same_values "$codec" "$work/x.btfpkg"
        codecs=$((codecs + 1))
    done < <("$btf" codecs | awk '/^[a-z]/ { if (name) print name, opts; name = $1; opts = "" }
                                  /^ +components=/ { opts = "--components 2" }
                                  END { print name, opts }')
    ((codecs >= 5)) || fail "btf codecs lists $codecs codecs: the list was not read"
    echo "packages of each of the $codecs codecs open in both builds and evaluate to the same values"

    # The Python module, from the packaged folder only; the package's writer is its version.
    cat >"$work/import.py" <<'PY'
import json, struct, sys
import btfkit
root, version, package = sys.argv[1:]
assert btfkit.__file__.startswith(root + "/usr/lib/python3/dist-packages/"), btfkit.__file__
assert btfkit.__version__ == version, btfkit.__version__
assert btfkit._btfkit._image_module().startswith(root + "/"), btfkit._btfkit._image_module()
data = open(package, "rb").read()
header = json.loads(data[24:24 + struct.unpack_from("<I", data, 12)[0]])
assert header["writer"] == "btfkit " + btfkit.__version__, header["writer"]
rgb = btfkit.open_material(package).eval([[0.3, 0.6]], [[0.3, 0.2, 0.93]], [[-0.2, 0.1, 0.97]])
assert rgb.shape == (1, 3) and rgb.min() > 0, rgb
print("python: btfkit", btfkit.__version__, "from", btfkit.__file__)
PY
    (cd "$work" && PYTHONPATH=$root/usr/lib/python3/dist-packages "$PYTHON" -s import.py "$root" \
        "$VERSION" "$work/m.btfpkg") || fail "the packaged Python module failed"

    # btf(1): man formats it without a warning, and it describes every command of `btf --help`.
    local page=$root/usr/share/man/man1/btf.1.gz warnings
    warnings=$(MANWIDTH=100 man --warnings -l "$page" 2>&1 >"$work/man.txt") ||
        fail "man could not format btf(1): $warnings"
    [[ -z $warnings ]] || fail "man warns about btf(1): $warnings"
    local command count=0
    for command in $("$btf" --help | awk '/^Subcommands:/ { on = 1; next } on && NF { print $1 }'); do
        grep -q "^   btf $command\b" "$work/man.txt" || fail "btf(1) does not describe 'btf $command'"
        count=$((count + 1))
    done
    ((count >= 19)) || fail "btf --help lists $count commands: the list was not read"
    echo "btf(1): $count commands, no warnings from man"

    # A C++ program through find_package(btfkit) and through pkg-config, from the packaged files.
    quiet "$CMAKE" -S "$source/examples/cpp" -B "$work/cmake-build" -G Ninja \
        -DCMAKE_MAKE_PROGRAM="$NINJA" -DCMAKE_CXX_COMPILER="$CXX" -DCMAKE_PREFIX_PATH="$root/usr" \
        -DCMAKE_FIND_USE_PACKAGE_REGISTRY=OFF
    grep -qx "btfkit_DIR:PATH=$root/$lib/cmake/btfkit" "$work/cmake-build/CMakeCache.txt" ||
        fail "find_package(btfkit) found another btfkit"
    quiet "$CMAKE" --build "$work/cmake-build"
    mkdir "$work/out"
    "$work/cmake-build/btfkit_example" "$work/out" >"$work/example.txt" || fail "the example failed"
    check_example_output "$work/example.txt"
    export PKG_CONFIG_PATH=$root/$lib/pkgconfig
    [[ $("$PKG_CONFIG" --modversion btfkit) == "$VERSION" ]] || fail "btfkit.pc's version is not $VERSION"
    local cflags libs
    cflags=$("$PKG_CONFIG" --cflags btfkit) || fail "pkg-config --cflags btfkit failed"
    libs=$("$PKG_CONFIG" --libs btfkit) || fail "pkg-config --libs btfkit failed"
    # shellcheck disable=SC2086  # the flags are words
    quiet "$CXX" -std=c++20 "$source/examples/cpp/main.cpp" $cflags $libs -o "$work/pc_example"
    echo "consumer: examples/cpp built against the package with find_package(btfkit) and pkg-config"
}

case $mode in
    consumer) install_consumer ;;
    python) install_python ;;
    deb) install_deb ;;
    *) fail "unknown mode '$mode' (consumer, python or deb)" ;;
esac
