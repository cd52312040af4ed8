// SPDX-License-Identifier: MIT
#include "btf/io/image_set.h"

#include <zip.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <fstream>
#include <map>
#include <mutex>

#include "btf/core/color.h"
#include "btf/util/error.h"
#include "btf/util/limits.h"
#include "btf/util/parallel.h"
#include "btf/util/progress.h"

namespace btf {

namespace fs = std::filesystem;

namespace {

// Files and archive entries are read in pieces of this size, checking for cancellation between.
constexpr uint64_t kReadChunk = uint64_t(1) << 20;

// The most bytes any encoding of a width × height image needs: uncompressed 32-bit floats of four
// channels, plus room for headers and metadata (ICC profiles, EXIF). A larger file is not an image
// of that size (a small JPEG followed by a gigabyte of something else).
uint64_t max_image_file_bytes(int width, int height) {
    return uint64_t(width) * uint64_t(height) * 16 + (uint64_t(16) << 20);
}

// Files are listed in name order, whatever order the folder or archive gives them in.
std::vector<size_t> name_order(const std::vector<std::string>& names) {
    std::vector<size_t> order(names.size());
    for (size_t i = 0; i < order.size(); ++i) order[i] = i;
    std::sort(order.begin(), order.end(), [&](size_t a, size_t b) { return names[a] < names[b]; });
    return order;
}

template <typename T>
std::vector<T> permuted(const std::vector<T>& values, const std::vector<size_t>& order) {
    std::vector<T> out;
    out.reserve(order.size());
    for (size_t i : order) out.push_back(values[i]);
    return out;
}

// ---- a folder tree on disk ---------------------------------------------------------------------

class FolderFiles final : public ImageFiles {
  public:
    FolderFiles(const fs::path& root, int max_depth) {
        m_container = root;
        std::error_code ec;
        if (!fs::is_directory(root, ec)) fail("{}: no such folder", root.string());
        collect(root, "", max_depth);
        const std::vector<size_t> order = name_order(m_names);
        m_names = permuted(m_names, order);
        m_sizes = permuted(m_sizes, order);
    }

    std::vector<unsigned char> read(int i, uint64_t max_bytes) const override {
        const fs::path path = m_container / m_names[i];
        std::ifstream in(path, std::ios::binary);
        if (!in) fail("{}: cannot open file", path.string());
        const uint64_t n = std::min(max_bytes, m_sizes[i]);
        check_alloc(n, path.string(), "reading the image file");
        std::vector<unsigned char> bytes(n);
        uint64_t done = 0;
        while (done < n) {
            Progress::check_all();
            const uint64_t piece = std::min(kReadChunk, n - done);
            in.read(reinterpret_cast<char*>(bytes.data() + done), std::streamsize(piece));
            done += uint64_t(in.gcount());
            if (uint64_t(in.gcount()) != piece) break;
        }
        if (done != n)
            fail("{}: read only {} of {} bytes (file changed or unreadable)", path.string(), done,
                 n);
        return bytes;
    }

    Image decode(int i, Encoding encoding) const override {
        return btf::read_image(m_container / m_names[i], encoding);
    }

  private:
    void collect(const fs::path& folder, const std::string& prefix, int depth) {
        if (depth <= 0) return;
        std::error_code ec;
        fs::directory_iterator it(folder, ec);
        if (ec) fail("{}: cannot list folder: {}", folder.string(), ec.message());
        while (it != fs::directory_iterator()) {
            const fs::directory_entry& entry = *it;
            const std::string name = entry.path().filename().string();
            std::error_code type_ec;
            if (name.empty() || name[0] == '.') {
                // hidden: skipped
            } else if (entry.is_directory(type_ec)) {
                collect(entry.path(), prefix + name + "/", depth - 1);
            } else if (entry.is_regular_file(type_ec)) {
                m_names.push_back(prefix + name);
                m_sizes.push_back(entry.file_size(type_ec));
            }
            it.increment(ec);
            if (ec) fail("{}: cannot list folder: {}", folder.string(), ec.message());
        }
    }
};

// ---- a zip archive read in place ---------------------------------------------------------------

std::string zip_error_text(int code) {
    zip_error_t error;
    zip_error_init_with_code(&error, code);
    std::string text = zip_error_strerror(&error);
    zip_error_fini(&error);
    return text;
}

class ZipFiles final : public ImageFiles {
  public:
    explicit ZipFiles(const fs::path& archive) {
        m_container = archive;
        m_archive = true;
        std::error_code ec;
        if (!fs::is_regular_file(archive, ec)) fail("{}: no such file", archive.string());
        int code = 0;
        m_zip = zip_open(archive.c_str(), ZIP_RDONLY | ZIP_CHECKCONS, &code);
        if (!m_zip)
            fail("{}: not a readable zip archive ({}){}", archive.string(), zip_error_text(code),
                 code == ZIP_ER_NOZIP || code == ZIP_ER_INCONS ? "; truncated or corrupt?" : "");
        const zip_int64_t entries = zip_get_num_entries(m_zip, 0);
        for (zip_int64_t e = 0; e < entries; ++e) {
            zip_stat_t st;
            zip_stat_init(&st);
            if (zip_stat_index(m_zip, zip_uint64_t(e), 0, &st) != 0 || !(st.valid & ZIP_STAT_NAME))
                fail("{}: entry {}: cannot read its directory record: {}", archive.string(), e,
                     zip_strerror(m_zip));
            std::string name = st.name;
            if (name.empty() || name.back() == '/') continue;  // folder entries
            if (!(st.valid & ZIP_STAT_SIZE) || !(st.valid & ZIP_STAT_COMP_SIZE))
                fail("{}: {}: the archive does not record the entry's size", archive.string(),
                     name);
            // Deflate cannot expand data more than about 1032:1; a larger ratio (or an entry
            // larger than the archive) means a corrupt directory, caught before allocating.
            if (st.comp_size > fs::file_size(archive, ec) || st.size > st.comp_size * 1100 + 4096)
                fail(
                    "{}: {}: entry declares {} bytes from {} compressed bytes in a {}-byte "
                    "archive (corrupt archive directory)",
                    archive.string(), name, st.size, st.comp_size, fs::file_size(archive, ec));
            m_names.push_back(std::move(name));
            m_sizes.push_back(st.size);
            m_entries.push_back(zip_uint64_t(e));
        }
        const std::vector<size_t> order = name_order(m_names);
        m_names = permuted(m_names, order);
        m_sizes = permuted(m_sizes, order);
        m_entries = permuted(m_entries, order);
    }

    ~ZipFiles() override {
        if (m_zip) zip_discard(m_zip);  // read-only: nothing to write back
    }

    std::vector<unsigned char> read(int i, uint64_t max_bytes) const override {
        const uint64_t n = std::min(max_bytes, m_sizes[i]);
        check_alloc(n, label(i), "reading the image file");
        std::vector<unsigned char> bytes(n);
        // libzip handles are not thread-safe: only the reading of the (compressed) bytes is
        // serialized; callers decode outside the lock.
        std::lock_guard<std::mutex> lock(m_mutex);
        zip_file_t* file = zip_fopen_index(m_zip, m_entries[i], 0);
        if (!file) fail("{}: cannot open archive entry: {}", label(i), zip_strerror(m_zip));
        uint64_t done = 0;
        while (done < n) {
            if (Progress::all_cancelled()) {
                zip_fclose(file);
                throw Cancelled();
            }
            const zip_int64_t got =
                zip_fread(file, bytes.data() + done, std::min(kReadChunk, n - done));
            if (got < 0) {
                const std::string error = zip_error_strerror(zip_file_get_error(file));
                zip_fclose(file);
                fail("{}: cannot read archive entry: {}", label(i), error);
            }
            if (got == 0) break;
            done += uint64_t(got);
        }
        if (n == m_sizes[i] && done == n) {
            // Reading to the end makes libzip verify the entry's CRC.
            unsigned char extra;
            const zip_int64_t got = zip_fread(file, &extra, 1);
            if (got < 0) {
                const std::string error = zip_error_strerror(zip_file_get_error(file));
                zip_fclose(file);
                fail("{}: cannot read archive entry: {}", label(i), error);
            }
        }
        zip_fclose(file);
        if (done != n)
            fail("{}: archive entry ends after {} of its {} bytes (truncated archive?)", label(i),
                 done, m_sizes[i]);
        return bytes;
    }

    Image decode(int i, Encoding encoding) const override {
        const std::vector<unsigned char> bytes = read(i, m_sizes[i]);
        return read_image_memory(bytes.data(), bytes.size(), label(i), encoding);
    }

  private:
    zip_t* m_zip = nullptr;
    std::vector<zip_uint64_t> m_entries;
    mutable std::mutex m_mutex;
};

}  // namespace

std::unique_ptr<ImageFiles> ImageFiles::folder(const fs::path& root, int max_depth) {
    return std::make_unique<FolderFiles>(root, max_depth);
}

std::unique_ptr<ImageFiles> ImageFiles::zip(const fs::path& archive) {
    return std::make_unique<ZipFiles>(archive);
}

std::string ImageFiles::label(int i) const {
    if (m_archive) return m_container.string() + ": " + m_names[i];
    return (m_container / m_names[i]).string();
}

std::pair<int, int> ImageFiles::image_size(int i) const {
    // Headers sit at the start of every format read here; a progressive JPEG's reader would
    // otherwise consume the whole file just to report its size. Read more only if needed.
    uint64_t prefix = 1024;
    std::string error;
    for (;;) {
        const std::vector<unsigned char> bytes = read(i, prefix);
        if (auto size = read_image_size_memory(bytes.data(), bytes.size(), label(i), &error)) {
            if (file_size(i) > max_image_file_bytes(size->first, size->second))
                fail(
                    "{}: file of {} bytes for a {}×{} image, more than any encoding of it needs "
                    "({} bytes at most): not an image of that size",
                    label(i), file_size(i), size->first, size->second,
                    max_image_file_bytes(size->first, size->second));
            return *size;
        }
        if (bytes.size() >= file_size(i)) break;
        prefix *= 16;
    }
    if (error.empty()) error = "unknown format";
    const size_t newline = error.find('\n');
    if (newline != std::string::npos) error.resize(newline);
    // OpenImageIO appends the name it was given; the message starts with it already.
    const std::string quoted = " (\"" + label(i) + "\")";
    if (const size_t at = error.find(quoted); at != std::string::npos)
        error.erase(at, quoted.size());
    fail("{}: not a readable image: {}", label(i), error);
}

// ---- ImageSetSource ----------------------------------------------------------------------------

ImageSetSource::ImageSetSource(std::unique_ptr<ImageFiles> files, Sampling sampling,
                               std::vector<int> table, SourceInfo info, Encoding encoding,
                               StoredColor color)
    : m_files(std::move(files)),
      m_sampling(std::move(sampling)),
      m_table(std::move(table)),
      m_info(std::move(info)),
      m_encoding(encoding),
      m_color(color) {
    check(m_table.size() == size_t(m_sampling.num_images()) && !m_table.empty(),
          "{}: image set has {} files for {} views × {} lights", m_files->container().string(),
          m_table.size(), m_sampling.num_views(), m_sampling.num_lights());
    for (int f : m_table)
        check(f >= 0 && f < m_files->size(), "{}: image table refers to file {} of {}",
              m_files->container().string(), f, m_files->size());
    // Read every header (in parallel; archive reads are serialized inside ImageFiles), keep the
    // errors, and report the first in table order so the message does not depend on threads.
    const int64_t n = int64_t(m_table.size());
    std::vector<std::pair<int, int>> sizes(n);
    std::vector<std::string> errors(n);
    parallel_for(0, n, [&](int64_t k) {
        try {
            sizes[k] = m_files->image_size(m_table[k]);
        } catch (const Cancelled&) {
            throw;  // stays a cancellation (exit 130), not an error about a file
        } catch (const Error& e) {
            errors[k] = e.what();
        }
    });
    for (int64_t k = 0; k < n; ++k)
        if (!errors[k].empty()) throw Error(errors[k]);
    m_width = sizes[0].first;
    m_height = sizes[0].second;
    for (int64_t k = 1; k < n; ++k)
        if (sizes[k] != sizes[0])
            fail(
                "{}: image is {}×{} but {} is {}×{} (all images of a BTF must have the same "
                "size)",
                m_files->label(m_table[k]), sizes[k].first, sizes[k].second,
                m_files->name(m_table[0]), m_width, m_height);
}

void ImageSetSource::read_image(int view, int light, Image& out) const {
    check(
        view >= 0 && view < m_sampling.num_views() && light >= 0 && light < m_sampling.num_lights(),
        "{}: image (view {}, light {}) is outside {} views × {} lights",
        m_files->container().string(), view, light, m_sampling.num_views(),
        m_sampling.num_lights());
    const int file = file_index(view, light);
    Image image = m_files->decode(file, m_encoding);
    if (image.width() != m_width || image.height() != m_height)
        fail("{}: image is {}×{} but the BTF's images are {}×{}", m_files->label(file),
             image.width(), image.height(), m_width, m_height);
    if (m_color == StoredColor::kXyz) {
        float* p = image.data();
        for (int64_t i = 0; i < image.num_pixels(); ++i, p += 3) {
            const Rgb rgb = xyz_to_rgb(Xyz{p[0], p[1], p[2]});
            p[0] = rgb.r, p[1] = rgb.g, p[2] = rgb.b;
        }
    }
    out = std::move(image);
}

// ---- angles in file names ----------------------------------------------------------------------

std::optional<double> parse_angle_degrees(std::string_view text) {
    if (text.empty()) return std::nullopt;
    const size_t dot = text.find('.');
    auto all_digits = [](std::string_view s) {
        return !s.empty() &&
               std::all_of(s.begin(), s.end(), [](char c) { return c >= '0' && c <= '9'; });
    };
    if (!all_digits(text.substr(0, dot))) return std::nullopt;
    if (dot != std::string_view::npos && !all_digits(text.substr(dot + 1))) return std::nullopt;
    double value = 0;
    auto [ptr, ec] =
        std::from_chars(text.data(), text.data() + text.size(), value, std::chars_format::fixed);
    if (ec != std::errc() || ptr != text.data() + text.size() || !std::isfinite(value))
        return std::nullopt;
    return value;
}

std::string format_angle_degrees(double degrees) {
    const double whole = std::round(degrees);
    if (std::abs(degrees - whole) < 1e-6) return fmt::format("{:03d}", int(whole));
    std::string text = fmt::format("{:07.3f}", degrees);
    while (text.back() == '0') text.pop_back();
    if (text.back() == '.') text.pop_back();
    return text;
}

std::optional<AngleFields> parse_angle_fields(std::string_view text, char separator) {
    static constexpr std::string_view kPrefixes[4] = {"tl", "pl", "tv", "pv"};
    double values[4];
    for (int f = 0; f < 4; ++f) {
        const size_t end = f < 3 ? text.find(separator) : text.size();
        if (end == std::string_view::npos) return std::nullopt;
        std::string_view field = text.substr(0, end);
        if (!field.starts_with(kPrefixes[f])) return std::nullopt;
        auto value = parse_angle_degrees(field.substr(2));
        if (!value) return std::nullopt;
        values[f] = *value;
        text.remove_prefix(f < 3 ? end + 1 : end);
    }
    for (int f = 0; f < 4; f += 2)
        if (values[f] > 90 || values[f + 1] >= 360) return std::nullopt;
    AngleFields fields{values[0], values[1], values[2], values[3]};
    // φ carries no information at the zenith; fold it so that names differing only there match.
    if (fields.light_theta == 0) fields.light_phi = 0;
    if (fields.view_theta == 0) fields.view_phi = 0;
    return fields;
}

std::string format_direction_fields(const Direction& d, const char* theta_prefix,
                                    const char* phi_prefix, char separator) {
    const std::string theta = format_angle_degrees(d.theta_deg());
    std::string phi = "000";
    if (theta != "000") {
        phi = format_angle_degrees(d.phi_deg());
        // φ just below 360° rounds to 360 in the name: that is φ = 0.
        if (auto value = parse_angle_degrees(phi); value && *value >= 360) phi = "000";
    }
    return fmt::format("{}{}{}{}{}", theta_prefix, theta, separator, phi_prefix, phi);
}

DirectionSet direction_set_from(std::vector<Direction> directions, const std::string& name) {
    for (const DirectionSet* known : {&DirectionSet::ubo81(), &DirectionSet::dome151()}) {
        if (int(directions.size()) != known->size()) continue;
        std::vector<bool> hit(known->size(), false);
        bool all = true;
        for (const Direction& d : directions) {
            const int i = known->find(d, radians(0.01));
            if (i < 0 || hit[i]) {
                all = false;
                break;
            }
            hit[i] = true;
        }
        if (all) return *known;
    }
    // Order by θ then φ on the values as the names write them (thousandths of a degree), so
    // that rounding noise in radians cannot reorder directions.
    auto key = [](const Direction& d) {
        const long theta = std::lround(d.theta_deg() * 1000);
        long phi = theta == 0 ? 0 : std::lround(d.phi_deg() * 1000);
        if (phi >= 360000) phi -= 360000;
        return std::pair<long, long>{theta, phi};
    };
    std::sort(directions.begin(), directions.end(),
              [&](const Direction& a, const Direction& b) { return key(a) < key(b); });
    return DirectionSet(name, std::move(directions));
}

std::string lower_extension(std::string_view file_name) {
    const size_t dot = file_name.rfind('.');
    if (dot == std::string_view::npos) return {};
    std::string ext(file_name.substr(dot));
    std::transform(ext.begin(), ext.end(), ext.begin(),
                   [](unsigned char c) { return char(std::tolower(c)); });
    return ext;
}

}  // namespace btf
