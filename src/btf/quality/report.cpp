// SPDX-License-Identifier: MIT
// write_report(): encode with every configuration, measure, draw, and move the finished folder
// into place.

#include "btf/quality/report.h"

#include <fmt/chrono.h>
#include <fmt/format.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <ctime>
#include <fstream>

#include "btf/codecs/material_source.h"
#include "btf/core/color.h"
#include "btf/core/image.h"
#include "btf/io/package.h"
#include "btf/io/sampled_material.h"
#include "btf/quality/colormap.h"
#include "btf/quality/render_compare.h"
#include "btf/util/error.h"
#include "btf/util/parallel.h"

namespace btf::quality {

namespace fs = std::filesystem;

namespace {

constexpr const char* kGeneratorMark = "btfkit report";

// "report/" names the folder "report".
fs::path normalized(const fs::path& path) {
    fs::path p = path.lexically_normal();
    if (!p.has_filename() && p.has_parent_path()) p = p.parent_path();
    return p;
}

bool is_report_folder(const fs::path& folder) {
    std::ifstream in(folder / "report.json");
    if (!in) return false;
    try {
        const nlohmann::json j = nlohmann::json::parse(in);
        return j.is_object() && j.value("generator", "") == kGeneratorMark;
    } catch (const std::exception&) {
        return false;
    }
}

// The report under construction: a hidden folder beside the destination, removed unless it was
// moved into place.
class TempFolder {
  public:
    explicit TempFolder(const fs::path& destination) : m_destination(destination) {
        static std::atomic<unsigned> counter{0};
        m_parent = destination.parent_path();
        if (m_parent.empty()) m_parent = ".";
        const std::string stem = destination.filename().string();
        const unsigned n = counter.fetch_add(1);
        m_path = m_parent / fmt::format(".{}.tmp-{}-{}", stem, ::getpid(), n);
        m_old = m_parent / fmt::format(".{}.old-{}-{}", stem, ::getpid(), n);
        std::error_code ec;
        if (!fs::create_directory(m_path, ec))
            fail("{}: cannot create the temporary report folder: {}", m_path.string(),
                 ec ? ec.message() : "it exists");
    }
    ~TempFolder() {
        if (m_committed) return;
        std::error_code ec;
        fs::remove_all(m_path, ec);
    }
    TempFolder(const TempFolder&) = delete;
    TempFolder& operator=(const TempFolder&) = delete;

    const fs::path& path() const { return m_path; }

    // Moves the report into place. An empty folder there is replaced, an earlier report is moved
    // aside first and removed once the new one is in place; anything else is refused.
    void commit() {
        std::error_code ec;
        bool moved_old = false;
        if (fs::exists(m_destination, ec)) {
            if (fs::is_directory(m_destination, ec) && fs::is_empty(m_destination, ec)) {
                fs::remove(m_destination, ec);
                if (ec)
                    fail("{}: cannot replace the empty folder: {}", m_destination.string(),
                         ec.message());
            } else if (fs::is_directory(m_destination, ec) && is_report_folder(m_destination)) {
                fs::rename(m_destination, m_old, ec);
                if (ec)
                    fail("{}: cannot move the earlier report aside: {}", m_destination.string(),
                         ec.message());
                moved_old = true;
            } else {
                fail(
                    "{}: appeared while the report was written and is not a report: left as it "
                    "is",
                    m_destination.string());
            }
        }
        fs::rename(m_path, m_destination, ec);
        if (ec) {
            std::error_code restore;
            if (moved_old) fs::rename(m_old, m_destination, restore);
            fail("{}: cannot move the report into place: {}", m_destination.string(), ec.message());
        }
        m_committed = true;
        if (moved_old) fs::remove_all(m_old, ec);
    }

  private:
    fs::path m_destination, m_parent, m_path, m_old;
    bool m_committed = false;
};

// Reports an inner operation's stages to `outer` as "prefix + stage".
class StageForwarder {
  public:
    StageForwarder(Progress& outer, std::string prefix)
        : m_outer(outer),
          m_prefix(std::move(prefix)),
          m_inner([this](std::string_view stage, uint64_t done, uint64_t total) {
              forward(stage, done, total);
          }) {}
    StageForwarder(const StageForwarder&) = delete;
    StageForwarder& operator=(const StageForwarder&) = delete;

    Progress& progress() { return m_inner; }

  private:
    void forward(std::string_view stage, uint64_t done, uint64_t total) {
        if (stage != m_stage || total != m_total) {
            m_outer.begin(m_prefix + std::string(stage), total);
            m_stage = stage;
            m_total = total;
            m_done = 0;
        }
        if (done > m_done) {
            if (total > 0 && done >= total)
                m_outer.finish();
            else
                m_outer.advance(done - m_done);
            m_done = done;
        }
    }

    Progress& m_outer;
    std::string m_prefix;
    std::string m_stage;
    uint64_t m_total = 0, m_done = 0;
    Progress m_inner;
};

std::string slug(const std::string& text) {
    std::string out;
    for (const char c : text) {
        const bool keep =
            (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '.';
        if (keep)
            out += c;
        else if (!out.empty() && out.back() != '-')
            out += '-';
    }
    while (!out.empty() && out.back() == '-') out.pop_back();
    if (out.size() > 80) out.resize(80);
    return out;
}

double percentile(std::vector<float> values, double p) {
    if (values.empty()) return 0;
    const size_t k = std::min(values.size() - 1, size_t(p * double(values.size() - 1) + 0.5));
    std::nth_element(values.begin(), values.begin() + long(k), values.end());
    return values[k];
}

std::vector<float> de2000_map(const Image& reference, const Image& test) {
    const int w = reference.width(), h = reference.height();
    std::vector<float> out(size_t(w) * size_t(h));
    parallel_for(0, h, [&](int64_t y) {
        for (int x = 0; x < w; ++x)
            out[size_t(y) * size_t(w) + size_t(x)] = float(
                ciede2000(rgb_to_lab(reference.rgb(x, int(y))), rgb_to_lab(test.rgb(x, int(y)))));
    });
    return out;
}

// reference | decoded | difference × gain, as display (sRGB-encoded) values.
Image crops_image(const Image& reference, const Image& test, int x0, int y0, int cw, int ch,
                  double exposure, double gain) {
    Image out(3 * cw + 2 * kCropGap, ch, 3, 1.0f);
    for (int y = 0; y < ch; ++y)
        for (int x = 0; x < cw; ++x)
            for (int c = 0; c < 3; ++c) {
                auto display = [&](const Image& image) {
                    const float v = float(image.at(x0 + x, y0 + y, c) * exposure);
                    return linear_to_srgb(std::clamp(v, 0.0f, 1.0f));
                };
                const float r = display(reference), d = display(test);
                out.at(x, y, c) = r;
                out.at(cw + kCropGap + x, y, c) = d;
                out.at(2 * (cw + kCropGap) + x, y, c) =
                    std::min(1.0f, float(gain) * std::abs(d - r));
            }
    return out;
}

void write_text(const fs::path& path, const std::string& text) {
    std::ofstream out(path, std::ios::binary);
    out << text;
    out.close();
    if (!out) fail("{}: cannot write", path.string());
}

std::string utc_now() {
    const std::time_t now = std::time(nullptr);
    std::tm tm{};
    gmtime_r(&now, &tm);
    return fmt::format("{:%Y-%m-%d %H:%M:%S} UTC", tm);
}

}  // namespace

void check_report_output(const fs::path& folder_in, bool force) {
    const fs::path folder = normalized(folder_in);
    const std::string name = folder.filename().string();
    if (folder.empty() || name == "." || name == "..")
        fail("'{}': name the report folder (e.g. -o report)", folder_in.string());
    std::error_code ec;
    fs::path parent = folder.parent_path();
    if (parent.empty()) parent = ".";
    if (!fs::is_directory(parent, ec))
        fail("{}: cannot write the report: folder {} does not exist", folder.string(),
             parent.string());
    if (!fs::exists(folder, ec)) return;
    if (!fs::is_directory(folder, ec))
        fail("{}: exists and is not a folder; name a new folder for the report", folder.string());
    if (fs::is_empty(folder, ec)) return;
    if (!force)
        fail("{}: folder exists and is not empty (--force replaces an earlier btfkit report)",
             folder.string());
    if (!is_report_folder(folder))
        fail("{}: not a btfkit report folder (no report.json of btf report): it is never replaced",
             folder.string());
}

Report write_report(const BtfSource& reference, const ReportOptions& options, Progress& progress) {
    const auto start = std::chrono::steady_clock::now();
    const fs::path destination = normalized(options.output);
    check_report_output(destination, options.force);
    check(!options.configs.empty(), "report: no codec configuration given");
    check(options.crop >= 1, "report: crop size {} is not positive", options.crop);
    check(options.difference_gain > 0 && std::isfinite(options.difference_gain),
          "report: difference gain {} is not positive", options.difference_gain);
    check(options.heat_max >= 0 && std::isfinite(options.heat_max),
          "report: heat-map maximum {} is negative", options.heat_max);
    const Sampling& sampling = reference.sampling();
    const int width = reference.width(), height = reference.height();
    const std::string ref_name = !options.reference_name.empty()  ? options.reference_name
                                 : !reference.info().path.empty() ? reference.info().path.string()
                                                                  : reference.info().format;
    check(width > 0 && height > 0 && sampling.num_images() > 0, "{}: the reference is empty",
          ref_name);
    for (const CodecConfig& config : options.configs) find_codec(config.codec);

    Report report;
    report.folder = destination;
    report.generator = options.generator;
    report.command_line = options.command_line;
    report.created = utc_now();
    report.difference_gain = options.difference_gain;
    report.btf_cielab = options.btf_cielab;
    report.cielab_options = options.cielab;
    ReferenceFacts& facts = report.reference;
    facts.name = ref_name;
    facts.format = reference.info().format;
    facts.path = reference.info().path.string();
    facts.note = reference.info().note;
    facts.width = width;
    facts.height = height;
    facts.views = sampling.num_views();
    facts.lights = sampling.num_lights();
    facts.view_set = sampling.views.name();
    facts.light_set = sampling.lights.name();
    facts.hdr = reference.info().hdr;
    facts.raw_8bit_bytes = double(reference.num_texels()) * double(sampling.num_images()) * 3.0;

    report.images = options.images.empty() ? default_report_images(sampling) : options.images;
    for (ReportImage& image : report.images) {
        check(image.view >= 0 && image.view < sampling.num_views() && image.light >= 0 &&
                  image.light < sampling.num_lights(),
              "{}: image (view {}, light {}) outside {} views × {} lights", ref_name, image.view,
              image.light, sampling.num_views(), sampling.num_lights());
        image.view_direction = sampling.views[image.view];
        image.light_direction = sampling.lights[image.light];
        if (image.label.empty())
            image.label = fmt::format("view {}, light {}", image.view, image.light);
    }
    report.crop_width = std::min(options.crop, width);
    report.crop_height = std::min(options.crop, height);
    report.crop_x = (width - report.crop_width) / 2;
    report.crop_y = (height - report.crop_height) / 2;

    TempFolder temp(destination);
    const fs::path root = temp.path();
    fs::create_directory(root / "packages");
    fs::create_directory(root / "images");

    // The selected reference images, read once.
    std::vector<Image> ref_images;
    for (const ReportImage& image : report.images)
        ref_images.push_back(reference.image(image.view, image.light));
    if (reference.info().hdr) {
        // Display the crops so that the brightest percent of the reference saturates.
        std::vector<float> values;
        for (const Image& image : ref_images)
            for (int y = report.crop_y; y < report.crop_y + report.crop_height; ++y)
                for (int x = report.crop_x; x < report.crop_x + report.crop_width; ++x)
                    values.push_back(luminance(image.rgb(x, y)));
        const double p99 = percentile(std::move(values), 0.99);
        if (p99 > 0 && std::isfinite(p99)) report.exposure = 1 / p99;
    }

    // The reference rendered once; every configuration's render is compared with it.
    Image reference_render;
    std::vector<std::vector<float>> render_de;  // per configuration: ΔE00 per pixel
    if (options.render) {
        fs::create_directory(root / "renders");
        StageForwarder stages(progress, "reference: ");
        {
            const SampledMaterial material(reference, int64_t(8) << 30, stages.progress());
            ReportRender rendered = options.render(material, stages.progress());
            reference_render = std::move(rendered.image);
            report.render_caption = rendered.caption;
            report.render_exposure = rendered.exposure;
        }
        report.render_reference = "renders/reference.png";
        write_image(root / report.render_reference,
                    tone_map(reference_render, report.render_exposure));
    }

    const int n = int(options.configs.size());
    const double samples = double(reference.num_texels()) * double(sampling.num_images());
    std::vector<std::vector<std::vector<float>>> de_maps(
        static_cast<size_t>(n));  // [config][image]
    for (int i = 0; i < n; ++i) {
        const CodecConfig& config = options.configs[size_t(i)];
        const Codec& codec = find_codec(config.codec);
        StageForwarder stages(progress, fmt::format("{}/{} {}: ", i + 1, n, config.label()));
        ConfigResult result;
        result.config = config;
        result.id = fmt::format("{:02}-{}", i + 1, slug(config.label()));
        try {
            const auto encode_start = std::chrono::steady_clock::now();
            Package package = codec.encode(reference, config.to_params(), stages.progress());
            result.encode_seconds =
                std::chrono::duration<double>(std::chrono::steady_clock::now() - encode_start)
                    .count();
            const fs::path package_path = root / "packages" / (result.id + ".btfpkg");
            PackageWriteOptions write_options;
            write_options.zstd_level = options.zstd_level;
            write_package(package_path, package, write_options, stages.progress());
            result.bytes = package.file_bytes;
            result.ratio = facts.raw_8bit_bytes / double(result.bytes);
            result.bits_per_sample = 8.0 * double(result.bytes) / samples;
            if (options.keep_packages) result.package = "packages/" + result.id + ".btfpkg";

            const std::unique_ptr<MaterialSource> decoded = open_package_source(package_path);
            // The reference's peak (PSNR, SSIM range) is found once, by the first comparison.
            CompareOptions compare_options;
            if (!report.configs.empty()) compare_options.peak = report.configs.front().metrics.peak;
            result.metrics = compare(reference, *decoded, compare_options, stages.progress());
            if (options.btf_cielab)
                result.cielab = btf_cielab(reference, *decoded, options.cielab, stages.progress());

            stages.progress().begin("error images", report.images.size());
            const fs::path folder = root / "images" / result.id;
            fs::create_directory(folder);
            for (size_t k = 0; k < report.images.size(); ++k) {
                const ReportImage& image = report.images[k];
                const Image test = decoded->image(image.view, image.light);
                std::vector<float> de = de2000_map(ref_images[k], test);
                ConfigImage ci;
                const std::string stem = fmt::format("v{}-l{}", image.view, image.light);
                ci.crops = "images/" + result.id + "/" + stem + "-crops.png";
                ci.heat_map = "images/" + result.id + "/" + stem + "-heat.png";
                double sum = 0;
                for (const float v : de)
                    sum += v, ci.de2000_max = std::max(ci.de2000_max, double(v));
                ci.de2000_mean = sum / double(de.size());
                write_image(root / ci.crops,
                            crops_image(ref_images[k], test, report.crop_x, report.crop_y,
                                        report.crop_width, report.crop_height, report.exposure,
                                        options.difference_gain),
                            Encoding::kRaw);
                result.images.push_back(std::move(ci));
                de_maps[size_t(i)].push_back(std::move(de));
                stages.progress().advance();
            }
            stages.progress().finish();
            if (options.render) {
                const std::unique_ptr<Material> material = open_material(package_path);
                Image rendered = options.render(*material, stages.progress()).image;
                const RenderComparison cmp =
                    compare_renders(reference_render, rendered, report.render_exposure);
                ConfigRender r;
                r.image = "renders/" + result.id + ".png";
                r.heat_map = "renders/" + result.id + "-heat.png";
                r.de2000_mean = cmp.de2000_mean;
                r.de2000_p95 = cmp.de2000_p95;
                r.ssim = cmp.ssim;
                r.psnr = cmp.psnr;
                report.render_heat_max = std::max(report.render_heat_max, cmp.heat_max);
                write_image(root / r.image, tone_map(rendered, report.render_exposure));
                result.render = r;
                render_de.push_back(cmp.de2000);
            }
            if (!options.keep_packages) fs::remove(package_path);
        } catch (const Cancelled&) {
            throw;
        } catch (const Error& e) {
            fail("{}: {}", config.label(), e.what());
        }
        report.configs.push_back(std::move(result));
    }

    // Per selected image one heat-map scale for every configuration, so that their maps compare.
    progress.begin("writing the report", uint64_t(n) * report.images.size() + 1);
    for (size_t k = 0; k < report.images.size(); ++k) {
        double top = options.heat_max;
        if (top == 0) {
            double p99 = 0;
            for (const auto& maps : de_maps) p99 = std::max(p99, percentile(maps[k], 0.99));
            top = nice_ceil(std::max(p99, 0.1));
        }
        report.heat_max.push_back(top);
        for (int i = 0; i < n; ++i) {
            write_image(root / report.configs[size_t(i)].images[k].heat_map,
                        heat_map(de_maps[size_t(i)][k], width, height, top));
            progress.advance();
        }
        write_text(root / fmt::format("colorbar-{}.svg", k + 1), colorbar_svg(top, "\u0394E00"));
    }
    de_maps.clear();
    // The renders' heat maps on one scale, so that they compare.
    for (int i = 0; i < n && options.render; ++i)
        write_image(root / report.configs[size_t(i)].render->heat_map,
                    heat_map(render_de[size_t(i)], reference_render.width(),
                             reference_render.height(), report.render_heat_max));
    if (options.render)
        write_text(root / "colorbar-render.svg", colorbar_svg(report.render_heat_max, "\u0394E00"));
    if (!options.keep_packages) fs::remove(root / "packages");
    write_text(root / "rd-psnr.svg", rate_distortion_svg(report, RdMeasure::kPsnr));
    write_text(root / "rd-de2000.svg", rate_distortion_svg(report, RdMeasure::kDe2000));
    if (options.btf_cielab)
        write_text(root / "rd-btf-cielab.svg", rate_distortion_svg(report, RdMeasure::kBtfCielab));
    report.seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    write_text(root / "report.json", report_json(report).dump(2) + "\n");
    write_text(root / "index.html", report_html(report));
    progress.finish();
    temp.commit();
    return report;
}

}  // namespace btf::quality
