# SPDX-License-Identifier: MIT
# btfkit — the two commands of the quick start are `make demo` and `make test`.
# Both install what they need first (scripts/bootstrap.sh, idempotent).

PRESET    ?= release
BUILD_DIR := build/$(PRESET)
JOBS      ?= $(shell nproc)
BTF       := $(BUILD_DIR)/btf

.PHONY: all bootstrap configure build test demo format format-check bench clean \
        test-sanitize fuzz fuzz-corpus python package

all: build

bootstrap:
	@bash scripts/bootstrap.sh

$(BUILD_DIR)/build.ninja: | bootstrap
	cmake --preset $(PRESET)

configure: bootstrap
	cmake --preset $(PRESET)

build: bootstrap $(BUILD_DIR)/build.ninja
	cmake --build $(BUILD_DIR) -j $(JOBS)

## The Python module alone, into build/<preset>/python (PYTHONPATH=build/release/python
## /usr/bin/python3 -c "import btfkit"); `make build` builds it too. docs/python.md.
python: bootstrap $(BUILD_DIR)/build.ninja
	cmake --build $(BUILD_DIR) -j $(JOBS) --target python

## The Debian package, build/package/btfkit_<version>_amd64.deb (cmake/package.cmake): its own build
## in build/package, of x86-64 baseline code (the release build is tuned for this machine's CPU),
## installed under /usr; CPack, with Depends from dpkg-shlibdeps. Install it with
## `sudo apt-get install ./build/package/btfkit_*_amd64.deb`.
PACKAGE_DIR := build/package
$(PACKAGE_DIR)/build.ninja: | bootstrap
	cmake --preset package

package: bootstrap $(PACKAGE_DIR)/build.ninja
	cmake --build $(PACKAGE_DIR) -j $(JOBS)
	cd $(PACKAGE_DIR) && cpack --config CPackConfig.cmake
	@ls $(PACKAGE_DIR)/btfkit_*_amd64.deb

## The whole test suite: formatting, then every GoogleTest case, the Python module's pytest suite,
## the viewer's tests and the Debian package's (Install.deb) through CTest.
test: build format-check package
	ctest --test-dir $(BUILD_DIR) -j $(JOBS) --output-on-failure --timeout 900

## The C++ suite built with AddressSanitizer + UndefinedBehaviorSanitizer (clang, the `sanitize`
## preset in build/sanitize), fuzz corpus replays included. The web viewer's tests (node and
## chromium, no C++ of ours beyond the `btf` they call) are left out.
SANITIZE_DIR := build/sanitize
$(SANITIZE_DIR)/build.ninja: | bootstrap
	cmake --preset sanitize

test-sanitize: bootstrap $(SANITIZE_DIR)/build.ninja
	cmake --build $(SANITIZE_DIR) -j $(JOBS)
	LSAN_OPTIONS=suppressions=$(CURDIR)/fuzz/lsan.supp:print_suppressions=0 \
	  ctest --test-dir $(SANITIZE_DIR) -j $(JOBS) --output-on-failure --timeout 1800 -E '^(WebViewer[.]|Install[.]deb$$)'

## Every libFuzzer target in fuzz/ for FUZZ_SECONDS each (ASan + UBSan), from its corpus; new
## inputs go to build/sanitize/fuzz/<target>/, not into the repository (FUZZ_MERGE=1 merges them
## into fuzz/corpus/). FUZZ_TARGETS="package hdf5" runs only those; FUZZ_JOBS=2 two at a time.
FUZZ_SECONDS ?= 120
FUZZ_TARGETS ?=
FUZZ_JOBS ?= 1
fuzz: bootstrap $(SANITIZE_DIR)/build.ninja
	cmake --build $(SANITIZE_DIR) -j $(JOBS) --target fuzzers
	FUZZ_MERGE=$(FUZZ_MERGE) FUZZ_JOBS=$(FUZZ_JOBS) \
	  bash fuzz/run.sh $(SANITIZE_DIR) $(FUZZ_SECONDS) $(FUZZ_TARGETS)

## Rebuilds the seed corpora in fuzz/corpus/ and the fixtures in fuzz/data/ with this build's
## writers (fuzz/make_corpus.sh).
fuzz-corpus: build
	cmake --build $(BUILD_DIR) -j $(JOBS) --target fuzz_make_seeds
	bash fuzz/make_corpus.sh $(BUILD_DIR)

## The main job: a built-in default material, synthesized and examined (see scripts/demo.sh).
demo: build
	@bash scripts/demo.sh $(BTF)

SOURCES = $(shell git ls-files -- '*.cpp' '*.h' 2>/dev/null)

format:
	clang-format -i $(SOURCES)

## Formatting, and the licence line of every source file (scripts/check_spdx.sh).
format-check: bootstrap
	@clang-format --dry-run -Werror $(SOURCES) && echo "format-check: $(words $(SOURCES)) files clean"
	@bash scripts/check_spdx.sh

bench: build
	@bash scripts/bootstrap.sh --bench
	cmake --build $(BUILD_DIR) -j $(JOBS) --target benches
	@bash bench/run_all.sh $(BUILD_DIR)

clean:
	rm -rf build
