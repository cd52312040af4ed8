#include "btf/io/open.h"

#include "btf/util/error.h"

namespace btf {

const std::vector<Reader>& readers() {
    static const std::vector<Reader> registry = {};
    return registry;
}

std::unique_ptr<BtfSource> open_source(const std::filesystem::path& path,
                                       const OpenOptions& options) {
    for (const Reader& reader : readers())
        if (reader.probe(path)) return reader.open(path, options);
    std::error_code ec;
    if (!std::filesystem::exists(path, ec)) fail("{}: no such file or folder", path.string());
    fail(
        "{}: not a BTF format btfkit reads (UBO2003 archive or folder, UBO2014 .btf, UTIA image "
        "set, btfkit HDF5)",
        path.string());
}

}  // namespace btf
