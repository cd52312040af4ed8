// SPDX-License-Identifier: MIT
#pragma once
/// Shared machinery of the image-set formats (Bonn UBO2003, UTIA image sets): a BTF stored as one
/// image file per (view, light), the light and view angles written in each file's name. The
/// formats differ only in their name patterns and containers; each format module parses its names
/// into a file table and hands it to ImageSetSource, which checks the images and decodes them
/// lazily.

#include <cstdint>
#include <filesystem>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "btf/core/direction.h"
#include "btf/core/image.h"
#include "btf/io/source.h"

namespace btf {

/// The files of an image set: a folder tree on disk, or a zip archive read in place. Files are
/// addressed by index; names are paths relative to the container, '/'-separated, sorted.
class ImageFiles {
  public:
    virtual ~ImageFiles() = default;

    /// Regular files under `root`, at most `max_depth` path components deep (1 = only the files
    /// directly in `root`). Hidden files and folders (names starting with '.') are skipped.
    static std::unique_ptr<ImageFiles> folder(const std::filesystem::path& root, int max_depth);
    /// The file entries of a zip archive, read in place with libzip. Opening checks the archive's
    /// consistency (central directory against local headers); a file that is not a readable zip
    /// archive throws btf::Error naming it. Entry checksums are verified when an entry is read
    /// whole.
    static std::unique_ptr<ImageFiles> zip(const std::filesystem::path& archive);

    /// The folder or archive the files are in.
    const std::filesystem::path& container() const { return m_container; }
    bool is_archive() const { return m_archive; }
    int size() const { return static_cast<int>(m_names.size()); }
    /// Path of file `i` relative to the container, '/'-separated.
    const std::string& name(int i) const { return m_names[i]; }
    /// Size of file `i` in bytes (uncompressed size for archive entries).
    uint64_t file_size(int i) const { return m_sizes[i]; }
    /// How errors name file `i`: its full path for a folder, "<archive>: <entry>" for an archive.
    std::string label(int i) const;

    /// Reads up to `max_bytes` from the start of file `i` (all of it by default). Thread-safe.
    /// Throws btf::Error naming the file on a read error (for archives: also a checksum mismatch).
    virtual std::vector<unsigned char> read(
        int i, uint64_t max_bytes = std::numeric_limits<uint64_t>::max()) const = 0;
    /// Decodes file `i`: 8-bit and 16-bit files per `encoding`, float files as stored.
    /// Thread-safe; archive bytes are read under a lock and decoded outside it.
    virtual Image decode(int i, Encoding encoding) const = 0;
    /// Width and height from file `i`'s header, reading only as much of the file as the header
    /// needs. Throws btf::Error naming the file when it is not a readable image.
    std::pair<int, int> image_size(int i) const;

  protected:
    std::filesystem::path m_container;
    bool m_archive = false;
    std::vector<std::string> m_names;
    std::vector<uint64_t> m_sizes;
};

/// How the values stored in an image set's files relate to btfkit's linear RGB.
enum class StoredColor {
    kRgb,  ///< RGB (8-bit files sRGB-encoded per Encoding, float files linear)
    kXyz,  ///< CIE XYZ (D65, Y = 1 for white), converted with xyz_to_rgb (core/color.h)
};

/// A BtfSource over an image set: the image of view v and light l is file
/// `table[v * num_lights + l]` of `files`.
class ImageSetSource final : public BtfSource {
  public:
    /// Reads every file's header and checks that all images have the same width and height
    /// (the error names the first file, in table order, that differs, and the file it differs
    /// from). Pixels are decoded only in read_image().
    ImageSetSource(std::unique_ptr<ImageFiles> files, Sampling sampling, std::vector<int> table,
                   SourceInfo info, Encoding encoding, StoredColor color = StoredColor::kRgb);

    int width() const override { return m_width; }
    int height() const override { return m_height; }
    const Sampling& sampling() const override { return m_sampling; }
    const SourceInfo& info() const override { return m_info; }
    void read_image(int view, int light, Image& out) const override;

    /// The files behind the source, and the file holding (view, light).
    const ImageFiles& files() const { return *m_files; }
    int file_index(int view, int light) const {
        return m_table[size_t(view) * m_sampling.num_lights() + light];
    }

  private:
    std::unique_ptr<ImageFiles> m_files;
    Sampling m_sampling;
    std::vector<int> m_table;
    SourceInfo m_info;
    Encoding m_encoding;
    StoredColor m_color;
    int m_width = 0, m_height = 0;
};

// ---- angles in file names ----------------------------------------------------------------------

/// Parses an angle field of a file name, in degrees: digits, optionally followed by '.' and more
/// digits ("075", "023.5"). Returns nothing for anything else (signs, exponents, empty text).
std::optional<double> parse_angle_degrees(std::string_view text);

/// Writes an angle for a file name: whole degrees as three digits ("075") when the angle is
/// within 1e-6° of a whole degree, else the integer part as three digits, a '.', and up to three
/// decimals without trailing zeros ("023.5", "007.25"). parse_angle_degrees reads both forms.
std::string format_angle_degrees(double degrees);

/// The four angles of an image named "tlA<sep>plB<sep>tvC<sep>pvD", in degrees.
struct AngleFields {
    double light_theta = 0, light_phi = 0, view_theta = 0, view_phi = 0;
    Direction light() const { return Direction::from_degrees(light_theta, light_phi); }
    Direction view() const { return Direction::from_degrees(view_theta, view_phi); }
};

/// Parses "tlA<sep>plB<sep>tvC<sep>pvD" (exactly these four fields in this order). Returns
/// nothing when the text does not have that form or an angle is out of range (θ in [0, 90],
/// φ in [0, 360)).
std::optional<AngleFields> parse_angle_fields(std::string_view text, char separator);

/// θ and φ of a direction in degrees as a file name writes them ("tl015 pl060" style fields use
/// these): φ is written as 0 at the zenith, where it carries no information.
std::string format_direction_fields(const Direction& d, const char* theta_prefix,
                                    const char* phi_prefix, char separator);

/// An ordered DirectionSet from distinct directions found in file names: DirectionSet::ubo81()
/// or dome151() when the directions are exactly that set, else the directions ordered by θ, then
/// φ (both built-in sets are in that order too), named `name`.
DirectionSet direction_set_from(std::vector<Direction> directions, const std::string& name);

/// Lower-case extension of a file name including the dot (".jpg"), empty if none.
std::string lower_extension(std::string_view file_name);

}  // namespace btf
