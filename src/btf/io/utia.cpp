// SPDX-License-Identifier: MIT
#include "btf/io/utia.h"

#include <algorithm>
#include <cmath>
#include <map>

#include "btf/core/color.h"
#include "btf/io/image_set.h"
#include "btf/util/atomic_file.h"
#include "btf/util/error.h"
#include "btf/util/parallel.h"

namespace btf::utia {

namespace fs = std::filesystem;

namespace {

// A direction as its name writes it, in thousandths of a degree: names that write the same
// angles are the same direction, and a key orders directions by θ, then φ.
using Key = std::pair<long, long>;

Key key_of(const Direction& d) {
    const long theta = std::lround(d.theta_deg() * 1000);
    long phi = theta == 0 ? 0 : std::lround(d.phi_deg() * 1000);
    if (phi >= 360000) phi -= 360000;
    return {theta, phi};
}

// "png" or "exr" from what the caller wrote ("PNG", ".exr" are accepted too).
std::string normalized_format(const std::string& format) {
    std::string f = format;
    if (!f.empty() && f.front() == '.') f.erase(0, 1);
    std::transform(f.begin(), f.end(), f.begin(),
                   [](unsigned char c) { return char(std::tolower(c)); });
    return f;
}

std::string light_fields(const Direction& d) {
    return format_direction_fields(d, "tl", "pl", '_');
}
std::string view_fields(const Direction& d) {
    return format_direction_fields(d, "tv", "pv", '_');
}

}  // namespace

std::string file_name(const Direction& light, const Direction& view, const std::string& format) {
    const std::string f = normalized_format(format);
    if (f != "png" && f != "exr")
        fail("unknown UTIA image format '{}' (expected png or exr)", format);
    return light_fields(light) + "_" + view_fields(view) + "." + f;
}

bool probe(const fs::path& path) {
    std::error_code ec;
    if (!fs::is_directory(path, ec)) return false;
    for (const fs::directory_entry& entry : fs::directory_iterator(path, ec)) {
        const std::string name = entry.path().filename().string();
        const std::string ext = lower_extension(name);
        if ((ext == ".png" || ext == ".exr") && !name.starts_with(".") &&
            parse_angle_fields(std::string_view(name).substr(0, name.size() - 4), '_'))
            return true;
    }
    return false;
}

std::unique_ptr<BtfSource> open(const fs::path& path, const OpenOptions& options) {
    std::error_code ec;
    if (!fs::is_directory(path, ec))
        fail(
            "{}: not a folder (a UTIA image set is a folder of tlTTT_plPPP_tvTTT_pvPPP.png or "
            ".exr images)",
            path.string());
    std::unique_ptr<ImageFiles> files = ImageFiles::folder(path, 1);

    struct Entry {
        int file;
        Key light, view;
    };
    std::vector<Entry> entries;
    std::map<Key, Direction> lights, views;
    std::string ext;
    int first_of_ext = -1;
    for (int i = 0; i < files->size(); ++i) {
        const std::string& name = files->name(i);
        const std::string e = lower_extension(name);
        if (e != ".png" && e != ".exr") continue;
        auto fields = parse_angle_fields(std::string_view(name).substr(0, name.size() - 4), '_');
        if (!fields)
            fail(
                "{}: image name is not of the form 'tlTTT_plPPP_tvTTT_pvPPP{}' (angles in "
                "degrees: three digits, optionally '.' and decimals)",
                files->label(i), e);
        if (ext.empty()) {
            ext = e;
            first_of_ext = i;
        } else if (e != ext) {
            fail("{}: {} image in a set of {} images (first: {})", files->label(i), e, ext,
                 files->name(first_of_ext));
        }
        const Direction light = fields->light(), view = fields->view();
        entries.push_back({i, key_of(light), key_of(view)});
        lights.emplace(key_of(light), light);
        views.emplace(key_of(view), view);
    }
    if (entries.empty())
        fail("{}: no UTIA images found (expected tlTTT_plPPP_tvTTT_pvPPP.png or .exr files)",
             path.string());

    auto build = [](const std::map<Key, Direction>& found, const std::string& name) {
        std::vector<Direction> dirs;
        for (const auto& [key, d] : found) dirs.push_back(d);
        DirectionSet set = direction_set_from(std::move(dirs), name);
        std::map<Key, int> index;
        for (int i = 0; i < set.size(); ++i) index[key_of(set[i])] = i;
        return std::pair{std::move(set), std::move(index)};
    };
    auto [light_set, light_index] = build(lights, "utia-lights");
    auto [view_set, view_index] = build(views, "utia-views");
    // Every view carries the same lights, so a missing light image cannot be told from a
    // smaller light set by the pairs alone. A light set that is a known set less a few
    // directions is a missing image, not a design: report it.
    for (const DirectionSet* known : {&DirectionSet::ubo81(), &DirectionSet::dome151()}) {
        if (light_set.size() >= known->size() || light_set.size() < known->size() * 9 / 10)
            continue;
        std::vector<bool> present(known->size(), false);
        bool subset = true;
        for (const Direction& d : light_set.directions()) {
            const int i = known->find(d, radians(0.01));
            if (i < 0)
                subset = false;
            else
                present[i] = true;
        }
        if (!subset) continue;
        for (int i = 0; i < known->size(); ++i)
            if (!present[i])
                fail(
                    "{}: the lights are {} of the {} {} directions; missing light θ={}°, φ={}° "
                    "(e.g. {})",
                    path.string(), light_set.size(), known->size(), known->name(),
                    (*known)[i].theta_deg(), (*known)[i].phi_deg(),
                    file_name((*known)[i], view_set[0], ext.substr(1)));
    }
    const int num_lights = light_set.size(), num_views = view_set.size();
    check(int(light_index.size()) == num_lights && int(view_index.size()) == num_views,
          "{}: directions in the image names are too close to tell apart", path.string());

    std::vector<int> all(size_t(num_views) * num_lights, -1);
    for (const Entry& entry : entries) {
        auto l = light_index.find(entry.light);
        auto v = view_index.find(entry.view);
        check(l != light_index.end() && v != view_index.end(),
              "{}: directions in the image names are too close to tell apart", path.string());
        int& slot = all[size_t(v->second) * num_lights + l->second];
        if (slot >= 0)
            fail("{}: duplicate image for the same light and view (also {})",
                 files->label(entry.file), files->name(slot));
        slot = entry.file;
    }

    std::vector<int> chosen = options.views;
    if (chosen.empty())
        for (int v = 0; v < num_views; ++v) chosen.push_back(v);
    std::sort(chosen.begin(), chosen.end());
    for (size_t k = 0; k < chosen.size(); ++k) {
        if (chosen[k] < 0 || chosen[k] >= num_views)
            fail("{}: view index {} is out of range (this set has views 0 to {})", path.string(),
                 chosen[k], num_views - 1);
        if (k > 0 && chosen[k - 1] == chosen[k])
            fail("{}: view {} is requested twice", path.string(), chosen[k]);
    }

    const std::string format = ext.substr(1);
    std::vector<int> table;
    table.reserve(chosen.size() * num_lights);
    for (int v : chosen) {
        for (int l = 0; l < num_lights; ++l) {
            const int file = all[size_t(v) * num_lights + l];
            if (file < 0) {
                const int64_t missing = std::count(all.begin(), all.end(), -1);
                fail(
                    "{}: missing image '{}' ({} of {} views × {} lights = {} images present; "
                    "every pair must be)",
                    path.string(), file_name(light_set[l], view_set[v], format),
                    int64_t(all.size()) - missing, num_views, num_lights, all.size());
            }
            table.push_back(file);
        }
    }

    Sampling sampling;
    sampling.lights = std::move(light_set);
    sampling.views = int(chosen.size()) == num_views ? std::move(view_set)
                                                     : view_set.subset(chosen, view_set.name());
    SourceInfo info;
    info.format = "UTIA image set";
    info.path = path;
    const bool exr = format == "exr";
    info.hdr = exr;
    info.note = exr ? "OpenEXR half float, CIE XYZ converted to linear RGB" : "PNG, sRGB";
    if (int(chosen.size()) < num_views)
        info.note += fmt::format("; {} of {} views", chosen.size(), num_views);
    return std::make_unique<ImageSetSource>(std::move(files), std::move(sampling), std::move(table),
                                            std::move(info), options.encoding,
                                            exr ? StoredColor::kXyz : StoredColor::kRgb);
}

void write(const BtfSource& source, const fs::path& folder, const std::string& format,
           Progress& progress) {
    const std::string f = normalized_format(format);
    if (f != "png" && f != "exr")
        fail("{}: unknown UTIA image format '{}' (expected png or exr)", folder.string(), format);
    const Sampling& sampling = source.sampling();
    check(sampling.num_images() > 0 && source.width() > 0 && source.height() > 0,
          "{}: the source has no images to write", folder.string());

    // Names must be distinct per light and per view, or images would overwrite each other.
    auto names_of = [&](const DirectionSet& set, bool light, const char* what) {
        std::vector<std::string> names;
        std::map<std::string, int> seen;
        for (int i = 0; i < set.size(); ++i) {
            names.push_back(light ? light_fields(set[i]) : view_fields(set[i]));
            auto [it, fresh] = seen.emplace(names.back(), i);
            if (!fresh)
                fail("{}: {}s {} and {} of the source both write the name '{}'", folder.string(),
                     what, it->second, i, names.back());
        }
        return names;
    };
    const std::vector<std::string> light_names = names_of(sampling.lights, true, "light");
    const std::vector<std::string> view_names = names_of(sampling.views, false, "view");

    AtomicOutput out(folder, /*directory=*/true);
    const int num_lights = sampling.num_lights();
    const int64_t n = sampling.num_images();
    progress.begin("write UTIA image set", uint64_t(n));
    parallel_for(0, n, [&](int64_t k) {
        const int view = int(k / num_lights), light = int(k % num_lights);
        Image image;
        source.read_image(view, light, image);
        if (f == "exr") {
            float* p = image.data();
            for (int64_t i = 0; i < image.num_pixels(); ++i, p += 3) {
                const Xyz xyz = rgb_to_xyz(Rgb{p[0], p[1], p[2]});
                p[0] = float(xyz.x), p[1] = float(xyz.y), p[2] = float(xyz.z);
            }
        }
        write_image(out.temp_path() / (light_names[light] + "_" + view_names[view] + "." + f),
                    image, Encoding::kLinear);
        progress.advance();
    });
    progress.finish();
    out.commit();
}

}  // namespace btf::utia
