// SPDX-License-Identifier: MIT
// Bonn UBO2014 .btf files (io/ubo2014.h): ubo2014::read() of any bytes (written to a scratch
// file: the reader takes a path), then the factorization as a Material (the fmf evaluator of its
// factors, and the RGB-interpolating one that cosine-weighted files use) and as a BtfSource, and
// re-wrapped as an fmf package (package_of, what `btf convert X.btf X.btfpkg` and `btf serve`
// do) that is opened and evaluated again.
#include "btf/io/ubo2014.h"
#include "btf/codecs/codec.h"
#include "btf/codecs/dfmf_export.h"
#include "fuzz/support/fuzz.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    const std::filesystem::path path = btf::fuzz::write_scratch("input.btf", {data, size});
    return btf::fuzz::run([&] {
        const auto factorization = btf::ubo2014::read(path);
        btf::fuzz::exercise(*btf::ubo2014_material(factorization, path.string()));
        btf::fuzz::exercise(*btf::ubo2014::make_material(factorization));
        btf::fuzz::exercise(*btf::ubo2014::make_source(factorization, path));
        btf::Package package = btf::package_of(*factorization, path.string());
        const std::vector<uint8_t> bytes = btf::encode_package(package);
        btf::fuzz::exercise(*btf::open_material(btf::decode_package(bytes, "converted")));
    });
}
