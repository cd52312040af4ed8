// SPDX-License-Identifier: MIT
#include "btf/io/ubo2003.h"

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>

#include "btf/io/image_set.h"
#include "btf/util/error.h"

namespace btf::ubo2003 {

namespace fs = std::filesystem;

namespace {

constexpr int kDirections = 81;
// Folder depth searched below a given folder: [top folder/]view folder/image.
constexpr int kFolderDepth = 3;

enum class Kind { kNone, kJpeg, kHdr };

Kind kind_of(std::string_view file_name) {
    const std::string ext = lower_extension(file_name);
    if (ext == ".jpg" || ext == ".jpeg") return Kind::kJpeg;
    if (ext == ".hdr") return Kind::kHdr;
    return Kind::kNone;
}

std::vector<std::string_view> split_path(std::string_view name) {
    std::vector<std::string_view> parts;
    size_t start = 0;
    for (;;) {
        const size_t slash = name.find('/', start);
        parts.push_back(name.substr(start, slash - start));
        if (slash == std::string_view::npos) break;
        start = slash + 1;
    }
    return parts;
}

// Archive tools add these; they are not part of a material.
bool ignored_component(std::string_view part) {
    return part.empty() || part.front() == '.' || part == "__MACOSX";
}

struct ImageName {
    long number = 0;
    AngleFields angles;
};

// "NNNNN tlTTT plPPP tvTTT pvPPP" (the stem of an image name).
std::optional<ImageName> parse_image_stem(std::string_view stem) {
    const size_t space = stem.find(' ');
    if (space == std::string_view::npos || space == 0) return std::nullopt;
    ImageName name;
    const std::string_view number = stem.substr(0, space);
    if (!std::all_of(number.begin(), number.end(), [](char c) { return c >= '0' && c <= '9'; }))
        return std::nullopt;
    auto [ptr, ec] = std::from_chars(number.data(), number.data() + number.size(), name.number);
    if (ec != std::errc() || ptr != number.data() + number.size()) return std::nullopt;
    auto angles = parse_angle_fields(stem.substr(space + 1), ' ');
    if (!angles) return std::nullopt;
    name.angles = *angles;
    return name;
}

// A view folder "tvTTT_pvPPP".
std::optional<Direction> parse_view_folder(std::string_view folder) {
    auto fields = parse_angle_fields("tl000_pl000_" + std::string(folder), '_');
    if (!fields) return std::nullopt;
    return fields->view();
}

std::string view_folder_name(int view) {
    return format_direction_fields(DirectionSet::ubo81()[view], "tv", "pv", '_');
}

std::string image_file_name(int view, int light, Kind kind) {
    const DirectionSet& set = DirectionSet::ubo81();
    return fmt::format("{:05d} {} {}{}", kDirections * light + view,
                       format_direction_fields(set[light], "tl", "pl", ' '),
                       format_direction_fields(set[view], "tv", "pv", ' '),
                       kind == Kind::kHdr ? ".hdr" : ".jpg");
}

std::string describe_direction(const Direction& d) {
    return fmt::format("θ={:g}°, φ={:g}°", std::round(d.theta_deg() * 1000) / 1000,
                       std::round(d.phi_deg() * 1000) / 1000);
}

// What the names of a material say: which file holds each (view, light).
struct Catalog {
    std::unique_ptr<ImageFiles> files;
    Kind kind = Kind::kNone;
    std::array<std::array<int, kDirections>, kDirections> file_of;  // [view][light], -1 = none
    std::array<int, kDirections> count_of{};                        // images per view
};

Catalog scan(const fs::path& path) {
    Catalog catalog;
    for (auto& row : catalog.file_of) row.fill(-1);
    std::error_code ec;
    if (fs::is_directory(path, ec))
        catalog.files = ImageFiles::folder(path, kFolderDepth);
    else if (fs::is_regular_file(path, ec))
        catalog.files = ImageFiles::zip(path);
    else
        fail("{}: no such file or folder", path.string());
    const ImageFiles& files = *catalog.files;
    const DirectionSet& set = DirectionSet::ubo81();
    int first_of_kind = -1;
    for (int i = 0; i < files.size(); ++i) {
        const std::vector<std::string_view> parts = split_path(files.name(i));
        if (std::any_of(parts.begin(), parts.end(), ignored_component)) continue;
        const std::string_view file_name = parts.back();
        const Kind kind = kind_of(file_name);
        if (kind == Kind::kNone) continue;
        const std::string_view stem = file_name.substr(0, file_name.rfind('.'));
        auto name = parse_image_stem(stem);
        if (!name)
            fail(
                "{}: image name is not of the form 'NNNNN tlTTT plPPP tvTTT pvPPP.jpg' (angles "
                "in degrees, fields separated by single spaces)",
                files.label(i));
        if (catalog.kind == Kind::kNone) {
            catalog.kind = kind;
            first_of_kind = i;
        } else if (kind != catalog.kind) {
            fail("{}: {} image in a material of {} images (first: {})", files.label(i),
                 kind == Kind::kHdr ? "HDR (.hdr)" : "JPEG", kind == Kind::kHdr ? "JPEG" : "HDR",
                 files.name(first_of_kind));
        }
        const Direction light_dir = name->angles.light(), view_dir = name->angles.view();
        const int light = set.find(light_dir, radians(0.25));
        const int view = set.find(view_dir, radians(0.25));
        if (light < 0)
            fail("{}: light direction {} is not one of the 81 UBO2003 directions", files.label(i),
                 describe_direction(light_dir));
        if (view < 0)
            fail("{}: view direction {} is not one of the 81 UBO2003 directions", files.label(i),
                 describe_direction(view_dir));
        const long expected = long(kDirections) * light + view;
        if (name->number != expected)
            fail(
                "{}: running number {} does not match the angles: light {} and view {} give "
                "81·{} + {} = {:05d}",
                files.label(i), stem.substr(0, stem.find(' ')), light, view, light, view, expected);
        if (parts.size() >= 2) {
            const std::string_view folder = parts[parts.size() - 2];
            if (auto folder_view = parse_view_folder(folder);
                folder_view && set.find(*folder_view, radians(0.25)) != view)
                fail("{}: image of view {} lies in view folder '{}'", files.label(i),
                     view_folder_name(view), folder);
        }
        int& slot = catalog.file_of[view][light];
        if (slot >= 0)
            fail("{}: duplicate image for light {}, view {} (also {})", files.label(i),
                 format_direction_fields(set[light], "tl", "pl", ' '),
                 format_direction_fields(set[view], "tv", "pv", ' '), files.name(slot));
        slot = i;
        ++catalog.count_of[view];
    }
    if (catalog.kind == Kind::kNone)
        fail(
            "{}: no UBO2003 images found (expected view folders 'tvTTT_pvPPP/' holding images "
            "'NNNNN tlTTT plPPP tvTTT pvPPP.jpg'{})",
            path.string(), files.is_archive() ? "" : ", at most two folders below this one");
    return catalog;
}

}  // namespace

bool probe(const fs::path& path) {
    std::error_code ec;
    std::unique_ptr<ImageFiles> files;
    try {
        if (fs::is_directory(path, ec)) {
            files = ImageFiles::folder(path, kFolderDepth);
        } else if (fs::is_regular_file(path, ec) &&
                   lower_extension(path.filename().string()) == ".zip") {
            try {
                files = ImageFiles::zip(path);
            } catch (const Error&) {
                return true;  // only this reader reads zip archives: let open() say what is wrong
            }
        } else {
            return false;
        }
    } catch (const Error&) {
        return false;  // an unreadable folder
    }
    for (int i = 0; i < files->size(); ++i) {
        const std::string_view file_name = split_path(files->name(i)).back();
        if (kind_of(file_name) != Kind::kNone &&
            parse_image_stem(file_name.substr(0, file_name.rfind('.'))))
            return true;
    }
    return false;
}

std::vector<int> list_views(const fs::path& path) {
    const Catalog catalog = scan(path);
    std::vector<int> views;
    for (int v = 0; v < kDirections; ++v)
        if (catalog.count_of[v] > 0) views.push_back(v);
    return views;
}

std::unique_ptr<BtfSource> open(const fs::path& path, const OpenOptions& options) {
    Catalog catalog = scan(path);
    const ImageFiles& files = *catalog.files;
    const DirectionSet& set = DirectionSet::ubo81();

    std::vector<int> present;
    for (int v = 0; v < kDirections; ++v)
        if (catalog.count_of[v] > 0) present.push_back(v);
    auto present_text = [&] {
        std::string text;
        for (int v : present) text += (text.empty() ? "" : ", ") + std::to_string(v);
        return text;
    };
    std::vector<int> views = options.views;
    if (views.empty()) views = present;
    std::sort(views.begin(), views.end());
    for (size_t k = 0; k < views.size(); ++k) {
        const int v = views[k];
        if (v < 0 || v >= kDirections)
            fail("{}: view index {} is out of range (UBO2003 views are 0 to 80)", path.string(), v);
        if (k > 0 && views[k - 1] == v) fail("{}: view {} is requested twice", path.string(), v);
        if (catalog.count_of[v] == 0)
            fail("{}: view {} ({}, folder {}) has no images in this material (views present: {})",
                 path.string(), v, describe_direction(set[v]), view_folder_name(v), present_text());
    }

    // Every chosen view must have all 81 lights; name the first missing one and count the rest.
    for (int v : views) {
        if (catalog.count_of[v] == kDirections) continue;
        int first_missing = -1;
        for (int l = 0; l < kDirections && first_missing < 0; ++l)
            if (catalog.file_of[v][l] < 0) first_missing = l;
        const int missing = kDirections - catalog.count_of[v];
        fail("{}: view folder {}: missing light image '{}'{}", path.string(), view_folder_name(v),
             image_file_name(v, first_missing, catalog.kind),
             missing > 1 ? fmt::format(" and {} more ({} of 81 lights present)", missing - 1,
                                       catalog.count_of[v])
                         : std::string());
    }

    std::vector<int> table;
    table.reserve(views.size() * kDirections);
    for (int v : views)
        for (int l = 0; l < kDirections; ++l) table.push_back(catalog.file_of[v][l]);

    Sampling sampling;
    sampling.lights = set;
    sampling.views = int(views.size()) == kDirections ? set : set.subset(views, "ubo81-partial");

    SourceInfo info;
    info.format = catalog.kind == Kind::kHdr ? "UBO2003 HDR" : "UBO2003";
    info.path = path;
    info.hdr = catalog.kind == Kind::kHdr;
    if (int(views.size()) < kDirections) {
        std::string listed;
        for (int v : views)
            listed +=
                fmt::format("{}{} ({})", listed.empty() ? "" : "; ", v, describe_direction(set[v]));
        info.note = fmt::format("partial material: {} of 81 views: {}", views.size(), listed);
    }
    if (files.is_archive()) {
        info.note += info.note.empty() ? "" : "; ";
        info.note += "read in place from a zip archive";
    }
    return std::make_unique<ImageSetSource>(std::move(catalog.files), std::move(sampling),
                                            std::move(table), std::move(info), options.encoding);
}

}  // namespace btf::ubo2003
