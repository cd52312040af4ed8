# btfkit — the two commands of the quick start are `make demo` and `make test`.
# Both install what they need first (scripts/bootstrap.sh, idempotent).

PRESET    ?= release
BUILD_DIR := build/$(PRESET)
JOBS      ?= $(shell nproc)
BTF       := $(BUILD_DIR)/btf

.PHONY: all bootstrap configure build test demo format format-check bench clean

all: build

bootstrap:
	@bash scripts/bootstrap.sh

$(BUILD_DIR)/build.ninja: | bootstrap
	cmake --preset $(PRESET)

configure: bootstrap
	cmake --preset $(PRESET)

build: bootstrap $(BUILD_DIR)/build.ninja
	cmake --build $(BUILD_DIR) -j $(JOBS)

## The whole test suite: formatting, then every GoogleTest case through CTest.
test: build format-check
	ctest --test-dir $(BUILD_DIR) -j $(JOBS) --output-on-failure --timeout 900

## The main job: a built-in default material, synthesized and examined (see scripts/demo.sh).
demo: build
	@bash scripts/demo.sh $(BTF)

SOURCES = $(shell git ls-files -- '*.cpp' '*.h' 2>/dev/null)

format:
	clang-format -i $(SOURCES)

format-check: bootstrap
	@clang-format --dry-run -Werror $(SOURCES) && echo "format-check: $(words $(SOURCES)) files clean"

bench: build
	@bash scripts/bootstrap.sh --bench
	cmake --build $(BUILD_DIR) -j $(JOBS) --target benches
	@bash bench/run_all.sh $(BUILD_DIR)

clean:
	rm -rf build
