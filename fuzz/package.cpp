// SPDX-License-Identifier: MIT
// The package container (io/package.h): decode_package() on any bytes. What it accepts must
// survive a round trip: encoded again (zstd and raw) and decoded, the same sections come back.
#include <cstdlib>

#include "btf/io/package.h"
#include "fuzz/support/fuzz.h"
#include "fuzz/support/package_mutator.h"

BTF_FUZZ_PACKAGE_MUTATOR()

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    return btf::fuzz::run([&] {
        btf::Package package = btf::decode_package({data, size}, "input");
        if (!package.complete()) return;
        const std::vector<btf::PackageSection> sections = package.sections;
        for (int level : {0, 1}) {
            const std::vector<uint8_t> bytes = btf::encode_package(package, {level});
            const btf::Package again = btf::decode_package(bytes, "round trip");
            if (again.sections.size() != sections.size() || again.header != package.header)
                std::abort();
            for (size_t i = 0; i < sections.size(); ++i)
                if (again.sections[i].name != sections[i].name ||
                    again.sections[i].data != sections[i].data)
                    std::abort();
        }
    });
}
