// Bonn UBO2014 .btf files (io/ubo2014.h): ubo2014::read() of any bytes (written to a scratch
// file: the reader takes a path), then the factorization as a Material and as a BtfSource.
#include "btf/io/ubo2014.h"
#include "fuzz/support/fuzz.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    const std::filesystem::path path = btf::fuzz::write_scratch("input.btf", {data, size});
    return btf::fuzz::run([&] {
        const auto factorization = btf::ubo2014::read(path);
        btf::fuzz::exercise(*btf::ubo2014::make_material(factorization));
        btf::fuzz::exercise(*btf::ubo2014::make_source(factorization, path));
    });
}
