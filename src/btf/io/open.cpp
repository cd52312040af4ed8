// SPDX-License-Identifier: MIT
#include "btf/io/open.h"

#include <cctype>

#include "btf/io/h5.h"
#include "btf/io/ubo2003.h"
#include "btf/io/ubo2014.h"
#include "btf/io/utia.h"
#include "btf/util/error.h"

namespace btf {

const std::vector<Reader>& readers() {
    static const std::vector<Reader> registry = {
        {"hdf5", "btfkit HDF5 raw BTF (interchange, readable with h5py)", h5::probe, h5::open},
        {"ubo2014", "Bonn UBO2014 factorized .btf (DFMF !DFMF08FC, FMF !FMF12FCE)", ubo2014::probe,
         ubo2014::open},
        {"ubo2003",
         "Bonn UBO2003 material: zip archive or folder of tvTTT_pvPPP/NNNNN tlTTT plPPP tvTTT "
         "pvPPP.jpg (.hdr)",
         ubo2003::probe, ubo2003::open},
        {"utia", "UTIA image set: folder of tlTTT_plPPP_tvTTT_pvPPP.png or .exr", utia::probe,
         utia::open},
    };
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

void write_source(const BtfSource& source, const std::filesystem::path& output,
                  const RawWriteOptions& options, Progress& progress) {
    std::string extension = output.extension().string();
    for (char& c : extension) c = char(std::tolower(static_cast<unsigned char>(c)));
    if (extension == ".h5" || extension == ".hdf5") {
        h5::WriteOptions h5_options;
        h5_options.half = options.half;
        h5_options.deflate = options.deflate;
        h5::write(source, output, h5_options, progress);
        return;
    }
    if (!extension.empty())
        fail(
            "{}: unknown output type '{}': name a .h5 file, or a folder without an extension for "
            "a UTIA image set",
            output.string(), extension);
    const std::string format = !options.format.empty() ? options.format
                               : source.info().hdr     ? "exr"
                                                       : "png";
    utia::write(source, output, format, progress);
}

}  // namespace btf
