// SPDX-License-Identifier: MIT
#pragma once
/// btfkit's own HDF5 form of a raw BTF: the interchange format that Python users read with h5py
/// and that the synthesizer and converters write. The layout is documented byte-exactly enough in
/// docs/formats.md ("btfkit HDF5"); in short:
///
///   /images         [n_views, n_lights, height, width, 3] float16 or float32, linear RGB,
///                   chunked one image per chunk [1, 1, height, width, 3], no filter or deflate
///                   (optionally after shuffle)
///   /views, /lights [n, 2] float64 (theta, phi) in degrees; attribute "name" (DirectionSet name)
///   /view_vectors, /light_vectors   [n, 3] float64 unit vectors (x, y, z) in the local frame
///   root attributes format = "btfkit-btf", format_version = 1, value_encoding = "linear-rgb",
///                   frame, hdr, source_format, source_path, source_note, metadata (JSON text)
///
/// libhdf5 (Debian's serial build) is not thread-safe: every HDF5 call in btfkit holds
/// library_mutex(). Images are read and written with direct chunk I/O so that (de)compression and
/// half-float conversion run outside that lock, in parallel.

#include <filesystem>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "btf/io/open.h"
#include "btf/io/source.h"
#include "btf/util/progress.h"

namespace btf::h5 {

/// Value of the root attribute "format".
inline constexpr const char* kFormatName = "btfkit-btf";
/// Value of the root attribute "format_version" this btfkit writes and reads.
inline constexpr int kFormatVersion = 1;
/// Value of the root attribute "value_encoding".
inline constexpr const char* kValueEncoding = "linear-rgb";
/// Value of the root attribute "frame" (the local-frame conventions of the stored directions).
inline constexpr const char* kFrame =
    "z = surface normal, x = tangent (direction of increasing u, along image rows), theta from +z, "
    "phi from +x toward +y, angles in degrees";

struct WriteOptions {
    /// Store IEEE half floats (float16, 2 bytes per value) rather than float32. Values beyond the
    /// half range (|v| > 65504) are rejected with an error naming the image.
    bool half = true;
    /// 0 = no compression (fastest to write and read); 1–9 = deflate level (HDF5's "gzip" filter,
    /// preceded by the byte shuffle filter, which makes float data compress better).
    int deflate = 0;
    /// Free-form JSON object stored as the root attribute "metadata" (checked to parse).
    std::string metadata = "{}";
};

/// Writes `source` to `path` in btfkit's HDF5 layout, streaming image by image (a batch of images
/// is read from the source in parallel; HDF5 writes are serialized). Atomic: the file appears only
/// when complete, and a failed or cancelled write leaves whatever was at `path` untouched.
/// Reports one progress unit per image. Throws btf::Error naming the image (view and light
/// indices and angles) for a NaN or infinite value, and for directions outside the hemisphere.
void write(const BtfSource& source, const std::filesystem::path& path,
           const WriteOptions& options = {}, Progress& progress = Progress::none());

/// True if `path` is an HDF5 file whose root attribute "format" is "btfkit-btf", or an HDF5 file
/// that HDF5 cannot open (truncated or corrupt), so that open() reports what is wrong with it.
/// Cheap: reads the signature and one attribute. Never throws.
bool probe(const std::filesystem::path& path);

/// Opens a btfkit HDF5 file as a BtfSource after validating the whole layout (attributes and their
/// version, dataset shapes against the direction counts, element type, chunking, filters,
/// direction ranges, that every image is present). `options.views` selects a subset of the file's
/// views (indices into the file's view set, in the given order). Values are linear, so
/// `options.encoding` must be Encoding::kLinear. read_image() is thread-safe and throws
/// btf::Error naming the view and light for a NaN or infinite value in the file.
std::unique_ptr<BtfSource> open(const std::filesystem::path& path, const OpenOptions& options = {});

/// open() for a file held in memory (HDF5's core driver on a copy of `image`, nothing read from or
/// written to disk); `name` stands for the file in errors and in info().
std::unique_ptr<BtfSource> open_memory(std::vector<uint8_t> image, const std::string& name,
                                       const OpenOptions& options = {});

/// The file-level description stored in a btfkit HDF5 file.
struct FileHeader {
    int version = 0;
    bool half = false;     ///< images stored as float16 (else float32)
    int deflate = 0;       ///< deflate level of the images (0 = not compressed)
    bool shuffle = false;  ///< byte shuffle filter before deflate
    bool hdr = false;
    std::string source_format;  ///< SourceInfo::format of the source the file was written from
    std::string source_path;
    std::string source_note;
    std::string metadata;  ///< the JSON text of the "metadata" attribute
};

/// Validates the file as open() does and returns its file-level attributes.
FileHeader read_header(const std::filesystem::path& path);

/// The lock every HDF5 call in the process must hold: Debian's libhdf5 is built without thread
/// safety. Recursive, so helpers that hold it may call each other.
std::recursive_mutex& library_mutex();

}  // namespace btf::h5
