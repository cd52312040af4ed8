// SPDX-License-Identifier: MIT
#include "btf/codecs/factor/model.h"

#include <fmt/format.h>

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <cstring>
#include <numeric>
#include <span>
#include <tuple>

#include "btf/codecs/factor/coded.h"
#include "btf/core/angular_interpolator.h"
#include "btf/core/color.h"
#include "btf/util/error.h"
#include "btf/util/json_fields.h"
#include "btf/util/limits.h"
#include "btf/util/parallel.h"

namespace btf::factor {

// ---- names -----------------------------------------------------------------------------------

std::string to_string(Quantization q) {
    switch (q) {
        case Quantization::kF32:
            return "f32";
        case Quantization::kF16:
            return "f16";
        case Quantization::kU8:
            return "u8";
        case Quantization::kCoded:
            return "coded";
    }
    return "?";
}

Quantization parse_quantization(const std::string& text) {
    if (text == "f32") return Quantization::kF32;
    if (text == "f16") return Quantization::kF16;
    if (text == "u8") return Quantization::kU8;
    if (text == "coded") return Quantization::kCoded;
    fail("unknown quantization '{}' (known: f32, f16, u8, coded)", text);
}

std::string to_string(ColourBasis basis) {
    switch (basis) {
        case ColourBasis::kRgb:
            return "rgb";
        case ColourBasis::kDecorrelated:
            return "decorrelated";
        case ColourBasis::kPerChannel:
            return "per-channel";
        case ColourBasis::kUboModel11:
            return "model11";
        case ColourBasis::kLab:
            return "lab";
    }
    return "?";
}

ColourBasis parse_colour_basis(const std::string& text) {
    if (text == "rgb") return ColourBasis::kRgb;
    if (text == "decorrelated") return ColourBasis::kDecorrelated;
    if (text == "per-channel") return ColourBasis::kPerChannel;
    if (text == "model11") return ColourBasis::kUboModel11;
    if (text == "lab") return ColourBasis::kLab;
    fail("unknown colour handling '{}' (known: rgb, decorrelated, per-channel, model11, lab)",
         text);
}

size_t column_bytes(Quantization q, int64_t n) {
    switch (q) {
        case Quantization::kF32:
            return 4 * size_t(n);
        case Quantization::kF16:
        case Quantization::kCoded:
            return 2 * size_t(n);
        case Quantization::kU8:
            return 8 + size_t(n);
    }
    return 0;
}

std::vector<int> allocate_components(const std::vector<const Svd*>& planes, int components) {
    std::vector<std::pair<float, int>> all;  // (sigma, plane)
    for (size_t p = 0; p < planes.size(); ++p)
        for (int k = 0; k < planes[p]->sigma.size(); ++k)
            if (planes[p]->sigma[k] > 0) all.emplace_back(planes[p]->sigma[k], static_cast<int>(p));
    std::stable_sort(all.begin(), all.end(),
                     [](const auto& a, const auto& b) { return a.first > b.first; });
    std::vector<int> keep(planes.size(), 0);
    const size_t n = std::min<size_t>(std::max(components, 0), all.size());
    for (size_t i = 0; i < n; ++i) ++keep[all[i].second];
    return keep;
}

Block make_block(const Svd& svd, int plane, int group, int cluster, int keep) {
    Block block;
    block.plane = plane;
    block.group = group;
    block.cluster = cluster;
    block.mean = svd.mean;
    block.a = svd.u.leftCols(keep);
    block.b = svd.v.leftCols(keep) * svd.sigma.head(keep).asDiagonal();
    block.energy.assign(svd.sigma.data(), svd.sigma.data() + keep);
    return block;
}

// ---- colour ----------------------------------------------------------------------------------

const std::array<float, 9>& ColourHandling::decorrelation() {
    static const std::array<float, 9> t = [] {
        const float a = 1 / std::sqrt(3.0f), b = 1 / std::sqrt(2.0f), c = 1 / std::sqrt(6.0f);
        return std::array<float, 9>{a, a, a, b, -b, 0, c, c, -2 * c};
    }();
    return t;
}

Rgb ColourHandling::forward(const Rgb& rgb) const {
    if (basis == ColourBasis::kUboModel11) {
        const auto c = rgb_to_ubo_model11(rgb);
        return {c[0], c[1], c[2]};
    }
    if (basis == ColourBasis::kLab) {
        const Lab c = rgb_to_lab(rgb);
        return {static_cast<float>(c.l), static_cast<float>(c.a), static_cast<float>(c.b)};
    }
    Rgb v = rgb;
    if (log)
        v = {std::log(std::max(v.r, 0.0f) + log_eps), std::log(std::max(v.g, 0.0f) + log_eps),
             std::log(std::max(v.b, 0.0f) + log_eps)};
    if (basis == ColourBasis::kDecorrelated) {
        const auto& t = decorrelation();
        return {t[0] * v.r + t[1] * v.g + t[2] * v.b, t[3] * v.r + t[4] * v.g + t[5] * v.b,
                t[6] * v.r + t[7] * v.g + t[8] * v.b};
    }
    return v;
}

Rgb ColourHandling::inverse(const Rgb& p) const {
    if (basis == ColourBasis::kUboModel11) return ubo_model11_to_rgb({p.r, p.g, p.b});
    if (basis == ColourBasis::kLab) return lab_to_rgb({p.r, p.g, p.b});
    Rgb v = p;
    if (basis == ColourBasis::kDecorrelated) {
        const auto& t = decorrelation();  // orthonormal: the inverse is the transpose
        v = {t[0] * p.r + t[3] * p.g + t[6] * p.b, t[1] * p.r + t[4] * p.g + t[7] * p.b,
             t[2] * p.r + t[5] * p.g + t[8] * p.b};
    }
    if (log) v = {std::exp(v.r) - log_eps, std::exp(v.g) - log_eps, std::exp(v.b) - log_eps};
    return v;
}

// ---- model -----------------------------------------------------------------------------------

namespace {

// What is wrong with the angular levels of a sampling, or "".
std::string angular_levels_problem(const std::vector<AngularLevel>& levels,
                                   const Sampling& sampling) {
    for (size_t m = 0; m < levels.size(); ++m)
        for (const auto& [list, set, name] :
             {std::tuple{&levels[m].views, &sampling.views, "views"},
              std::tuple{&levels[m].lights, &sampling.lights, "lights"}}) {
            if (static_cast<int>(list->size()) < kMinAngularDirections)
                return fmt::format("angular level {} keeps {} {} (at least {})", m + 1,
                                   list->size(), name, kMinAngularDirections);
            for (size_t i = 0; i < list->size(); ++i)
                if ((*list)[i] < 0 || (*list)[i] >= set->size() ||
                    (i > 0 && (*list)[i] <= (*list)[i - 1]))
                    return fmt::format("angular level {} {} must be ascending indices below {}",
                                       m + 1, name, set->size());
        }
    return {};
}

}  // namespace

int64_t Model::rows(int group) const {
    return int64_t(groups[group].size()) * sampling.num_lights() * colour.channels();
}

int64_t Model::block_rows(int group, int angular) const {
    if (angular == 0) return rows(group);
    const AngularLevel& level = angular_levels[size_t(angular - 1)];
    return int64_t(level.views.size()) * int64_t(level.lights.size()) * colour.channels();
}

std::vector<std::vector<int32_t>> Model::cluster_texels() const {
    std::vector<std::vector<int32_t>> out(clusters);
    const int32_t texels = width * height;
    if (clusters == 1) {
        out[0].resize(texels);
        std::iota(out[0].begin(), out[0].end(), 0);
        return out;
    }
    for (int32_t t = 0; t < texels; ++t) out[texel_cluster[t]].push_back(t);
    return out;
}

int64_t Model::block_texels(const std::vector<std::vector<int32_t>>& lists, int cluster,
                            int level) const {
    if (level == 0) return static_cast<int64_t>(lists[cluster].size());
    return int64_t(level_width(level)) * level_height(level);
}

void Model::validate(const std::string& what) const {
    if (width < 1 || height < 1) fail("{}: bad extent {}×{}", what, width, height);
    if (sampling.views.empty() || sampling.lights.empty()) fail("{}: empty sampling", what);
    std::vector<int> seen(sampling.num_views(), 0);
    for (const auto& group : groups)
        for (int v : group) {
            if (v < 0 || v >= sampling.num_views()) fail("{}: group names view {}", what, v);
            ++seen[v];
        }
    for (int v = 0; v < sampling.num_views(); ++v)
        if (seen[v] != 1)
            fail("{}: view {} is in {} groups (must be in exactly one)", what, v, seen[v]);
    if (clusters < 1) fail("{}: {} clusters", what, clusters);
    if (clusters > 1) {
        if (static_cast<int64_t>(texel_cluster.size()) != int64_t(width) * height)
            fail("{}: {} texel clusters for {} texels", what, texel_cluster.size(), width * height);
        for (int32_t c : texel_cluster)
            if (c < 0 || c >= clusters) fail("{}: texel cluster {} of {}", what, c, clusters);
    }
    if (colour.log && colour.basis == ColourBasis::kLab) fail("{}: log with lab colour", what);
    if (levels < 1 || levels > 16) fail("{}: {} spatial levels", what, levels);
    if (levels > 1) {
        const int step = 1 << (levels - 1);
        if (clusters != 1)
            fail("{}: {} spatial levels with {} texel clusters (levels need one cluster)", what,
                 levels, clusters);
        if (width % step != 0 || height % step != 0)
            fail("{}: {} spatial levels need width and height divisible by {} ({}×{})", what,
                 levels, step, width, height);
    }
    if (angular_levels.size() > 15)
        fail("{}: {} angular levels (at most 15)", what, angular_levels.size());
    if (!angular_levels.empty()) {
        bool in_order = groups.size() == 1;
        for (size_t s = 0; in_order && s < groups[0].size(); ++s)
            in_order = groups[0][s] == static_cast<int>(s);
        if (!in_order)
            fail("{}: angular levels need one view group with the views in order ({} groups)", what,
                 groups.size());
        const std::string problem = angular_levels_problem(angular_levels, sampling);
        if (!problem.empty()) fail("{}: {}", what, problem);
    }
    const int64_t expected =
        int64_t(colour.planes()) * groups.size() * clusters * levels * angular_count();
    if (static_cast<int64_t>(blocks.size()) != expected)
        fail("{}: {} blocks, expected {}", what, blocks.size(), expected);
    const auto texels = cluster_texels();
    for (size_t i = 0; i < blocks.size(); ++i) {
        const Block& b = blocks[i];
        if (b.level < 0 || b.level >= levels || b.angular < 0 || b.angular >= angular_count() ||
            block_index(b.plane, b.group, b.cluster, b.level, b.angular) != static_cast<int>(i))
            fail("{}: block {} is out of order", what, i);
        if (b.angular > 0 && !b.mean.empty())
            fail("{}: block {} of angular level {} has row means", what, i, b.angular);
        const int64_t rows = block_rows(b.group, b.angular);
        if (b.a.rows() != rows || b.b.rows() != block_texels(texels, b.cluster, b.level) ||
            b.a.cols() != b.b.cols() || static_cast<int>(b.energy.size()) != b.components() ||
            (!b.mean.empty() && static_cast<int64_t>(b.mean.size()) != rows))
            fail("{}: block {} has inconsistent shapes", what, i);
    }
}

std::string source_name(const BtfSource& source) {
    return source.info().path.empty() ? source.info().format : source.info().path.string();
}

Model model_for(const BtfSource& source, const ColourHandling& colour, std::string_view codec) {
    check(source.num_views() > 0 && source.num_lights() > 0 && source.num_texels() > 0,
          "{}: {}: empty BTF ({} views, {} lights, {}x{} texels)", source_name(source), codec,
          source.num_views(), source.num_lights(), source.width(), source.height());
    Model model;
    model.width = source.width();
    model.height = source.height();
    model.sampling = source.sampling();
    model.hdr = source.info().hdr;
    model.colour = colour;
    model.groups.resize(1);
    model.groups[0].resize(source.num_views());
    std::iota(model.groups[0].begin(), model.groups[0].end(), 0);
    return model;
}

// ---- package ---------------------------------------------------------------------------------

namespace {

template <typename T>
void append(std::vector<uint8_t>& out, const T* values, size_t count) {
    // memcpy from the null data() of an empty vector is undefined even for 0 bytes.
    if (count == 0) return;
    const size_t at = out.size();
    out.resize(at + count * sizeof(T));
    std::memcpy(out.data() + at, values, count * sizeof(T));
}

/// One direction set's tables part by part, in the order section "tables" stores them:
/// part(values, count, floats) for each, until one returns false.
template <typename Part>
bool table_parts(const AngularInterpolator::Tables& t, Part&& part) {
    const int32_t head[6] = {t.grid_resolution,
                             t.num_directions,
                             t.num_vertices,
                             t.lifted_horizon ? 1 : 0,
                             static_cast<int32_t>(t.triangles.size() / 3),
                             static_cast<int32_t>(t.cell_triangles.size())};
    return part(head, size_t(6), false) && part(t.vertices.data(), t.vertices.size(), true) &&
           part(t.triangles.data(), t.triangles.size(), false) &&
           part(t.inverse.data(), t.inverse.size(), true) &&
           part(t.cell_offsets.data(), t.cell_offsets.size(), false) &&
           part(t.cell_triangles.data(), t.cell_triangles.size(), false);
}

void append_tables(std::vector<uint8_t>& out, const DirectionSet& set) {
    table_parts(AngularInterpolator(set).tables(), [&](const auto* values, size_t count, bool) {
        append(out, values, count);
        return true;
    });
}

/// Whether `stored` holds the tables append_tables() writes for `sets`, one after the other: the
/// counts, triangles and cell lists exactly, the vertices and inverse matrices within 1e-5 of the
/// ones computed here (relative to 1 or the value). Their last bits differ between machines and
/// builds: glibc's libm picks its code by CPU, and a build for a CPU with FMA contracts a·b + c.
bool tables_match(std::span<const uint8_t> stored,
                  std::initializer_list<const DirectionSet*> sets) {
    size_t at = 0;
    // The next `count` words of `stored` against `expected`: equal bits, or floats close enough.
    const auto take = [&](const auto* expected, size_t count, bool floats) {
        static_assert(sizeof(*expected) == 4);
        if (stored.size() - at < count * 4) return false;
        for (size_t i = 0; i < count; ++i, at += 4) {
            if (!floats) {
                if (std::memcmp(stored.data() + at, &expected[i], 4)) return false;
                continue;
            }
            float a;
            std::memcpy(&a, stored.data() + at, 4);
            const double b = double(expected[i]);
            if (!(std::abs(double(a) - b) <= 1e-5 * std::max(1.0, std::abs(b)))) return false;
        }
        return true;
    };
    for (const DirectionSet* set : sets)
        if (!table_parts(AngularInterpolator(*set).tables(), take)) return false;
    return at == stored.size();
}

// The viewer's copy of the angular levels' up-sampling (section "angular"): per level, U of the
// views then U of the lights, float32 row-major.
void append_upsampling(std::vector<uint8_t>& out, const Model& model) {
    for (const AngularLevel& level : model.angular_levels) {
        const AngularResampler r(model.sampling, level, model.colour.channels());
        for (const Eigen::MatrixXd* u : {&r.up_views(), &r.up_lights()})
            for (Eigen::Index i = 0; i < u->rows(); ++i)
                for (Eigen::Index j = 0; j < u->cols(); ++j) {
                    const float w = float((*u)(i, j));
                    append(out, &w, 1);
                }
    }
}

void put_column(std::vector<uint8_t>& out, Quantization q, const float* v, int64_t n,
                int64_t stride) {
    switch (q) {
        case Quantization::kF32:
            for (int64_t i = 0; i < n; ++i) append(out, &v[i * stride], 1);
            return;
        case Quantization::kF16:
            for (int64_t i = 0; i < n; ++i) {
                const uint16_t bits = Eigen::numext::bit_cast<uint16_t>(Eigen::half(v[i * stride]));
                append(out, &bits, 1);
            }
            return;
        case Quantization::kU8: {
            float lo = v[0], hi = v[0];
            for (int64_t i = 0; i < n; ++i) {
                lo = std::min(lo, v[i * stride]);
                hi = std::max(hi, v[i * stride]);
            }
            const float step = (hi - lo) / 255.0f;
            const float head[2] = {lo, step};
            append(out, head, 2);
            for (int64_t i = 0; i < n; ++i) {
                const float code = step > 0 ? std::round((v[i * stride] - lo) / step) : 0.0f;
                const uint8_t byte = static_cast<uint8_t>(std::clamp(code, 0.0f, 255.0f));
                append(out, &byte, 1);
            }
            return;
        }
        case Quantization::kCoded:
            break;  // coded sections are written whole (coded::put_component)
    }
}

const uint8_t* get_column(Quantization q, const uint8_t* in, float* v, int64_t n, int64_t stride) {
    switch (q) {
        case Quantization::kF32:
            for (int64_t i = 0; i < n; ++i, in += 4) std::memcpy(&v[i * stride], in, 4);
            return in;
        case Quantization::kF16:
            for (int64_t i = 0; i < n; ++i, in += 2) {
                uint16_t bits;
                std::memcpy(&bits, in, 2);
                v[i * stride] = static_cast<float>(Eigen::numext::bit_cast<Eigen::half>(bits));
            }
            return in;
        case Quantization::kU8: {
            float head[2];
            std::memcpy(head, in, 8);
            in += 8;
            for (int64_t i = 0; i < n; ++i) v[i * stride] = head[0] + head[1] * float(in[i]);
            return in + n;
        }
        case Quantization::kCoded:
            break;  // coded sections are read whole (coded::get_component)
    }
    return in;
}

// The RMS of the model's values over every block's rows and texels: Σ mean² per row and texel
// plus ‖A Bᵀ‖² = trace((AᵀA)(BᵀB)), in double.
double value_rms(const Model& model) {
    double sum = 0, count = 0;
    for (const Block& b : model.blocks) {
        const double texels = double(b.b.rows());
        for (const float m : b.mean) sum += double(m) * m * texels;
        const Eigen::MatrixXd a = b.a.cast<double>(), t = b.b.cast<double>();
        sum += ((a.transpose() * a) * (t.transpose() * t)).trace();
        count += double(b.a.rows()) * texels;
    }
    return count > 0 ? std::sqrt(sum / count) : 0.0;
}

// A block's texel factor as an image (one cluster: every texel of its level), else none.
coded::Image texel_image(const Model& model, const Block& b) {
    if (model.clusters != 1) return {};
    return {model.level_width(b.level), model.level_height(b.level)};
}

// The layout of a block's a rows for coded storage's prediction by neighbouring directions.
coded::AngularRows angular_rows(const Model& model, const Block& b) {
    const int64_t lights = b.angular > 0
                               ? int64_t(model.angular_levels[size_t(b.angular - 1)].lights.size())
                               : int64_t(model.sampling.num_lights());
    return {lights, model.colour.channels()};
}

std::string component_name(int block, int k) {
    return fmt::format("b{}.k{}", block, k);
}

// Directions a package may declare per set: far more than any measurement dome (151), few enough
// that triangulating them stays fast.
constexpr size_t kMaxDirections = 16384;

PackageSection named_section(std::string name) {
    PackageSection s;
    s.name = std::move(name);
    return s;
}

}  // namespace

nlohmann::json directions_json(const DirectionSet& set) {
    nlohmann::json theta = nlohmann::json::array(), phi = nlohmann::json::array();
    for (const Direction& d : set.directions()) {
        theta.push_back(d.theta);
        phi.push_back(d.phi);
    }
    return {{"name", set.name()}, {"theta", theta}, {"phi", phi}};
}

DirectionSet directions_from_json(const nlohmann::json& j) {
    json_fields::only_keys(j, "directions", {"name", "theta", "phi"});
    const auto& theta = j.at("theta");
    const auto& phi = j.at("phi");
    if (!theta.is_array() || !phi.is_array() || theta.size() != phi.size())
        fail("direction arrays differ in length");
    if (theta.empty() || theta.size() > kMaxDirections)
        fail("{} directions (1 to {} allowed)", theta.size(), kMaxDirections);
    // Radians: θ on the upper hemisphere, φ within one turn either way (a little slack for
    // rounding at the ends).
    constexpr double kSlack = 1e-6;
    std::vector<Direction> dirs;
    for (size_t i = 0; i < theta.size(); ++i)
        dirs.push_back({json_fields::number(theta[i], "theta", -kSlack, kPi / 2 + kSlack),
                        json_fields::number(phi[i], "phi", -2 * kPi - kSlack, 2 * kPi + kSlack)});
    return DirectionSet(j.at("name").get<std::string>(), std::move(dirs));
}

Package to_package(const Model& model, std::string_view codec, const nlohmann::json& params,
                   Quantization quantization, double quality) {
    model.validate(fmt::format("codec {}", codec));
    Package package;
    auto& h = package.header;
    h["codec"] = std::string(codec);
    h["params"] = params;
    h["width"] = model.width;
    h["height"] = model.height;
    h["views"] = directions_json(model.sampling.views);
    h["lights"] = directions_json(model.sampling.lights);
    h["hdr"] = model.hdr;
    h["raw_bytes_8bit"] = int64_t(model.width) * model.height * model.sampling.num_images() * 3;
    nlohmann::json m;
    m["colour"] = to_string(model.colour.basis);
    m["log"] = model.colour.log;
    m["log_eps"] = model.colour.log_eps;
    m["quantization"] = to_string(quantization);
    double step = 0;
    if (quantization == Quantization::kCoded) {
        if (!(quality >= 0 && quality <= 100)) fail("quality {} is outside [0, 100]", quality);
        step = coded::value_step(quality, value_rms(model));
        m["coding"] = {{"quality", quality}, {"step", step}};
    }
    m["groups"] = model.groups;
    m["clusters"] = model.clusters;
    // Single-level models keep the header they always had (no "levels", no block "level").
    if (model.levels > 1) m["levels"] = model.levels;
    if (!model.angular_levels.empty()) {
        nlohmann::json levels = nlohmann::json::array();
        for (const AngularLevel& a : model.angular_levels)
            levels.push_back({{"views", a.views}, {"lights", a.lights}});
        m["angular_levels"] = levels;
    }
    nlohmann::json blocks = nlohmann::json::array();
    for (const Block& b : model.blocks) {
        blocks.push_back({{"plane", b.plane},
                          {"group", b.group},
                          {"cluster", b.cluster},
                          {"components", b.components()},
                          {"mean", !b.mean.empty()},
                          {"energy", b.energy}});
        if (model.levels > 1) blocks.back()["level"] = b.level;
        if (!model.angular_levels.empty()) blocks.back()["angular"] = b.angular;
    }
    m["blocks"] = blocks;
    h["model"] = m;

    PackageSection tables = named_section("tables");
    append_tables(tables.data, model.sampling.views);
    append_tables(tables.data, model.sampling.lights);
    package.sections.push_back(std::move(tables));
    if (!model.angular_levels.empty()) {
        PackageSection angular = named_section("angular");
        append_upsampling(angular.data, model);
        package.sections.push_back(std::move(angular));
    }
    if (model.clusters > 1) {
        PackageSection clusters = named_section("clusters");
        append(clusters.data, model.texel_cluster.data(), model.texel_cluster.size());
        package.sections.push_back(std::move(clusters));
    }
    PackageSection means = named_section("means");
    for (const Block& b : model.blocks) append(means.data, b.mean.data(), b.mean.size());
    package.sections.push_back(std::move(means));

    // Components in decreasing energy over all blocks. Within a block the order must stay
    // k = 0, 1, …, so a component's sort key is the smallest energy up to it. With several view
    // groups (pca-views), components go in rounds instead, the thesis' progressive order: the
    // k-th component of every block before any (k+1)-th, so that a viewer has every group's
    // first component (a first picture of every view) after the first round.
    struct Entry {
        float key;
        int block, k;
    };
    std::vector<Entry> order;
    std::vector<AngularResampler> resamplers;  // coded storage weighs a by its up-sampling
    if (quantization == Quantization::kCoded)
        for (const AngularLevel& level : model.angular_levels)
            resamplers.emplace_back(model.sampling, level, model.colour.channels());
    for (size_t i = 0; i < model.blocks.size(); ++i) {
        float key = INFINITY;
        for (int k = 0; k < model.blocks[i].components(); ++k) {
            key = std::min(key, model.blocks[i].energy[k]);
            order.push_back({key, static_cast<int>(i), k});
        }
    }
    const bool rounds = model.groups.size() > 1;
    std::stable_sort(order.begin(), order.end(), [rounds](const Entry& x, const Entry& y) {
        if (rounds && x.k != y.k) return x.k < y.k;
        return x.key > y.key;
    });
    for (const Entry& e : order) {
        const Block& b = model.blocks[e.block];
        PackageSection s = named_section(component_name(e.block, e.k));
        if (quantization == Quantization::kCoded) {
            coded::put_component(s.data, {b.a.data() + e.k, b.a.rows(), b.a.cols()},
                                 {b.b.data() + e.k, b.b.rows(), b.b.cols()}, texel_image(model, b),
                                 step, b.angular > 0 ? &resamplers[size_t(b.angular - 1)] : nullptr,
                                 angular_rows(model, b));
            package.sections.push_back(std::move(s));
            continue;
        }
        s.data.reserve(column_bytes(quantization, b.a.rows()) +
                       column_bytes(quantization, b.b.rows()));
        put_column(s.data, quantization, b.a.data() + e.k, b.a.rows(), b.a.cols());
        put_column(s.data, quantization, b.b.data() + e.k, b.b.rows(), b.b.cols());
        package.sections.push_back(std::move(s));
    }
    package.declared_sections = static_cast<int>(package.sections.size());
    return package;
}

Model from_package(const Package& package) {
    const std::string what = fmt::format("package ({})", package.codec());
    return read_package_fields(what, [&] {
        const auto& h = package.header;
        Model model;
        std::tie(model.width, model.height) = json_fields::extent(h);
        model.sampling.views = directions_from_json(h.at("views"));
        model.sampling.lights = directions_from_json(h.at("lights"));
        model.hdr = h.value("hdr", false);
        const auto& m = h.at("model");
        model.colour.basis = parse_colour_basis(m.at("colour").get<std::string>());
        model.colour.log = m.at("log").get<bool>();
        model.colour.log_eps = float(json_fields::number_at(m, "log_eps", 0, 1e30));
        const Quantization q = parse_quantization(m.at("quantization").get<std::string>());
        const int views = model.sampling.views.size();
        const auto& groups = m.at("groups");
        if (!groups.is_array() || groups.empty() || int64_t(groups.size()) > views)
            fail("'groups' must be an array of 1 to {} view groups", views);
        for (const auto& g : groups)
            model.groups.push_back(json_fields::integers(g, "groups", 0, views - 1, views));
        model.clusters =
            int(json_fields::integer_at(m, "clusters", 1, int64_t(model.width) * model.height));
        model.levels = int(json_fields::integer_or(m, "levels", 1, 1, 16));
        if (model.levels > 1 &&
            (model.clusters != 1 || model.width % (1 << (model.levels - 1)) != 0 ||
             model.height % (1 << (model.levels - 1)) != 0))
            fail("{} spatial levels for {}×{} texels in {} clusters", model.levels, model.width,
                 model.height, model.clusters);
        if (m.contains("angular_levels")) {
            for (const auto& a : m.at("angular_levels"))
                model.angular_levels.push_back(
                    // Exact integers here; angular_levels_problem() says which are out of range.
                    {json_fields::integers(a.at("views"), "views", INT32_MIN, INT32_MAX, views),
                     json_fields::integers(a.at("lights"), "lights", INT32_MIN, INT32_MAX,
                                           model.sampling.lights.size())});
            if (model.angular_levels.empty() || model.angular_levels.size() > 15)
                fail("{} angular levels", model.angular_levels.size());
            const std::string problem =
                angular_levels_problem(model.angular_levels, model.sampling);
            if (!problem.empty()) fail("{}", problem);
        }
        const int64_t texels = int64_t(model.width) * model.height;
        if (model.clusters > 1) {
            if (const PackageSection* s = package.find("clusters")) {
                if (static_cast<int64_t>(s->data.size()) != texels * 4)
                    fail("section 'clusters' holds {} bytes, expected {}", s->data.size(),
                         texels * 4);
                model.texel_cluster.resize(texels);
                std::memcpy(model.texel_cluster.data(), s->data.data(), s->data.size());
                // Checked here, not only by validate() at the end: cluster_texels() below
                // indexes by these values.
                for (int64_t t = 0; t < texels; ++t)
                    if (model.texel_cluster[t] < 0 || model.texel_cluster[t] >= model.clusters)
                        fail("section 'clusters': texel {} is in cluster {} of {}", t,
                             model.texel_cluster[t], model.clusters);
            } else {
                model.texel_cluster.assign(texels, 0);  // a prefix without it has no factors yet
            }
        }
        const auto& blocks = m.at("blocks");
        const int planes = model.colour.planes();
        if (static_cast<int64_t>(blocks.size()) !=
            int64_t(planes) * static_cast<int64_t>(model.groups.size()) * model.clusters *
                model.levels * model.angular_count())
            fail("{} blocks for {} planes × {} groups × {} clusters × {} levels{}", blocks.size(),
                 planes, model.groups.size(), model.clusters, model.levels,
                 model.angular_levels.empty()
                     ? std::string()
                     : fmt::format(" × {} angular levels", model.angular_count()));
        std::vector<int> declared(blocks.size());
        model.blocks.resize(blocks.size());
        // Validate groups and clusters before sizing blocks from them.
        for (size_t i = 0; i < blocks.size(); ++i) {
            Block& b = model.blocks[i];
            const auto& bj = blocks[i];
            json_fields::only_keys(
                bj, "block",
                {"plane", "group", "cluster", "components", "mean", "energy", "level", "angular"});
            b.plane = int(json_fields::integer_at(bj, "plane", 0, planes - 1));
            b.group =
                int(json_fields::integer_at(bj, "group", 0, int64_t(model.groups.size()) - 1));
            b.cluster = int(json_fields::integer_at(bj, "cluster", 0, model.clusters - 1));
            b.level = int(json_fields::integer_or(bj, "level", 0, 0, model.levels - 1));
            b.angular =
                int(json_fields::integer_or(bj, "angular", 0, 0, model.angular_count() - 1));
            declared[i] = int(json_fields::integer_at(bj, "components", 0, 4096));
        }
        const auto texel_lists = model.cluster_texels();
        const PackageSection* means = package.find("means");
        size_t mean_at = 0;
        std::vector<std::vector<std::vector<float>>> columns(
            blocks.size());  // [block][k]: a then b
        for (size_t i = 0; i < blocks.size(); ++i) {
            Block& b = model.blocks[i];
            const int64_t rows = model.block_rows(b.group, b.angular);
            if (blocks[i].at("mean").get<bool>()) {
                check_alloc(uint64_t(rows) * 4, "header", fmt::format("the mean of block {}", i));
                b.mean.assign(rows, 0.0f);
                if (means) {
                    if (means->data.size() < (mean_at + rows) * 4)
                        fail("section 'means' is too short");
                    // Not for 0 rows: memcpy to the null data() of an empty vector is undefined.
                    if (rows > 0)
                        std::memcpy(b.mean.data(), means->data.data() + mean_at * 4, rows * 4);
                    mean_at += rows;
                }
            }
        }
        if (means && means->data.size() != mean_at * 4)
            fail("section 'means' holds {} bytes, expected {}", means->data.size(), mean_at * 4);
        // Component sections: count the leading components present per block.
        std::vector<int> present(blocks.size(), 0);
        std::vector<std::vector<const PackageSection*>> sections(blocks.size());
        for (const PackageSection& s : package.sections) {
            int block = -1, k = -1;
            char tail = 0;
            if (std::sscanf(s.name.c_str(), "b%d.k%d%c", &block, &k, &tail) != 2 ||
                s.name != component_name(block, k)) {
                if (s.name != "tables" && s.name != "angular" && s.name != "clusters" &&
                    s.name != "means")
                    fail("unknown section '{}'", s.name);
                continue;
            }
            if (block < 0 || block >= static_cast<int>(blocks.size()) || k != present[block] ||
                k >= declared[block])
                fail("component section '{}' is out of order or undeclared", s.name);
            const int64_t rows =
                model.block_rows(model.blocks[block].group, model.blocks[block].angular);
            const int64_t cols = model.block_texels(texel_lists, model.blocks[block].cluster,
                                                    model.blocks[block].level);
            if (q != Quantization::kCoded &&
                s.data.size() != column_bytes(q, rows) + column_bytes(q, cols))
                fail("section '{}' holds {} bytes, expected {}", s.name, s.data.size(),
                     column_bytes(q, rows) + column_bytes(q, cols));
            ++present[block];
            sections[block].push_back(&s);
        }
        for (size_t i = 0; i < blocks.size(); ++i) {
            Block& b = model.blocks[i];
            const int k = present[i];
            const auto energy = blocks[i].at("energy").get<std::vector<float>>();
            if (static_cast<int>(energy.size()) != declared[i])
                fail("block {} declares {} components but {} energies", i, declared[i],
                     energy.size());
            b.energy.assign(energy.begin(), energy.begin() + k);
            b.a.resize(model.block_rows(b.group, b.angular), k);
            b.b.resize(model.block_texels(texel_lists, b.cluster, b.level), k);
            for (int c = 0; c < k; ++c) {
                const PackageSection& s = *sections[i][c];
                if (q == Quantization::kCoded) {
                    coded::get_component(s.data.data(), s.data.size(),
                                         {b.a.data() + c, b.a.rows(), k},
                                         {b.b.data() + c, b.b.rows(), k}, texel_image(model, b),
                                         s.name, angular_rows(model, b));
                    continue;
                }
                const uint8_t* in = s.data.data();
                in = get_column(q, in, b.a.data() + c, b.a.rows(), k);
                get_column(q, in, b.b.data() + c, b.b.rows(), k);
            }
            // Non-finite numbers are refused where they enter, not where they would leave as
            // NaN pixels.
            if (!b.a.allFinite() || !b.b.allFinite() ||
                !std::all_of(b.mean.begin(), b.mean.end(),
                             [](float x) { return std::isfinite(x); }) ||
                !std::all_of(energy.begin(), energy.end(),
                             [](float x) { return std::isfinite(x); }))
                fail("block {}: a mean, factor or energy is not a finite number", i);
        }
        // The tables are the viewer's copy of the interpolation tables the evaluator builds from
        // the directions: they must be those (to the last bits of their floats, which differ
        // between machines), or the browser would not show this material as btfkit does.
        if (const PackageSection* tables = package.find("tables")) {
            if (!tables_match(tables->data, {&model.sampling.views, &model.sampling.lights}))
                fail("section 'tables' ({} bytes) is not the tables of the header's directions",
                     tables->data.size());
        }
        // The up-sampling weights come from AngularInterpolator::weights(), whose last bits may
        // change with the way it finds a query's triangle (a direction on an edge lies in two),
        // so packages of earlier versions hold weights that differ by rounding: equal within
        // 1e-6 is the same up-sampling (weights lie in [0, 1]).
        if (const PackageSection* angular = package.find("angular")) {
            std::vector<uint8_t> expected;
            if (!model.angular_levels.empty()) append_upsampling(expected, model);
            const size_t n = expected.size() / sizeof(float);
            double worst = 0;
            if (angular->data.size() == expected.size())
                for (size_t i = 0; i < n; ++i) {
                    float a, b;
                    std::memcpy(&a, angular->data.data() + i * sizeof(float), sizeof(float));
                    std::memcpy(&b, expected.data() + i * sizeof(float), sizeof(float));
                    const double d = std::abs(double(a) - double(b));
                    if (!(d <= worst)) worst = std::isnan(d) ? INFINITY : d;  // NaN: damage
                }
            if (angular->data.size() != expected.size() || !(worst <= 1e-6))
                fail(
                    "section 'angular' ({} bytes) is not the up-sampling of the header's angular "
                    "levels ({} bytes, weights differing by up to {:.3g})",
                    angular->data.size(), expected.size(), worst);
        }
        model.validate(what);
        return model;
    });
}

// ---- codec base ----------------------------------------------------------------------------

Package FactorCodec::encode(const BtfSource& source, const Params& params,
                            Progress& progress) const {
    const Result result = factorize(source, params, progress);
    return to_package(result.model, name(), result.params, result.quantization, result.quality);
}

std::unique_ptr<Material> FactorCodec::open(const Package& package) const {
    if (package.codec() != name())
        fail("package of codec '{}' opened as {}", package.codec(), name());
    return std::make_unique<FactorMaterial>(from_package(package));
}

// ---- source rows ----------------------------------------------------------------------------

SourceRows::SourceRows(const BtfSource& source, ColourHandling colour,
                       std::vector<std::vector<int>> groups)
    : m_source(source), m_colour(colour), m_groups(static_cast<int>(groups.size())) {
    m_group_of_view.assign(source.num_views(), -1);
    m_slot_of_view.assign(source.num_views(), -1);
    for (int g = 0; g < m_groups; ++g) {
        for (size_t s = 0; s < groups[g].size(); ++s) {
            const int v = groups[g][s];
            if (v < 0 || v >= source.num_views() || m_group_of_view[v] >= 0)
                fail("view groups: view {} is out of range or in two groups", v);
            m_group_of_view[v] = g;
            m_slot_of_view[v] = static_cast<int>(s);
        }
        m_group_rows.push_back(int64_t(groups[g].size()) * source.num_lights() * colour.channels());
    }
    for (int v = 0; v < source.num_views(); ++v)
        if (m_group_of_view[v] < 0) fail("view groups: view {} is in no group", v);
}

int SourceRows::matrices() const {
    return m_colour.planes() * m_groups;
}

int64_t SourceRows::rows(int matrix) const {
    return m_group_rows[matrix % m_groups];
}

int64_t SourceRows::batch_rows(int view, int matrix) const {
    return matrix % m_groups == m_group_of_view.at(view)
               ? int64_t(m_source.num_lights()) * m_colour.channels()
               : 0;
}

void SourceRows::read(int view, std::vector<int64_t>& first, std::vector<Matrix>& out) const {
    const int planes = m_colour.planes(), channels = m_colour.channels();
    const int lights = m_source.num_lights();
    const int64_t texels = m_source.num_texels();
    const int group = m_group_of_view[view];
    first.assign(matrices(), 0);
    out.resize(matrices());
    for (int m = 0; m < matrices(); ++m)
        if (m % m_groups != group) out[m].resize(0, texels);
    for (int p = 0; p < planes; ++p) {
        out[matrix(p, group)].resize(int64_t(lights) * channels, texels);
        first[matrix(p, group)] = int64_t(m_slot_of_view[view]) * lights * channels;
    }
    parallel_for(0, lights, [&](int64_t light) {
        thread_local Image image;
        m_source.read_image(view, static_cast<int>(light), image);
        const float* px = image.data();
        if (channels == 3 && !m_colour.log) {
            // Plain rgb: the planes are the pixels; de-interleave them directly (reading a
            // source is otherwise dominated by the per-texel colour transform).
            Matrix& rows = out[matrix(0, group)];
            float* r = &rows(light * 3, 0);
            float* g = &rows(light * 3 + 1, 0);
            float* b = &rows(light * 3 + 2, 0);
            for (int64_t t = 0; t < texels; ++t) {
                r[t] = px[3 * t];
                g[t] = px[3 * t + 1];
                b[t] = px[3 * t + 2];
            }
            return;
        }
        for (int64_t t = 0; t < texels; ++t) {
            const Rgb v = m_colour.forward({px[3 * t], px[3 * t + 1], px[3 * t + 2]});
            const float c[3] = {v.r, v.g, v.b};
            if (channels == 3) {
                Matrix& rows = out[matrix(0, group)];
                for (int ch = 0; ch < 3; ++ch) rows(light * 3 + ch, t) = c[ch];
            } else {
                for (int p = 0; p < 3; ++p) out[matrix(p, group)](light, t) = c[p];
            }
        }
    });
}

}  // namespace btf::factor
