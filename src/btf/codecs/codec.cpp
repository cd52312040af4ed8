// SPDX-License-Identifier: MIT
#include "btf/codecs/codec.h"

#include <fmt/format.h>

#include <algorithm>
#include <charconv>
#include <cmath>

#include "btf/bsvtf/material.h"
#include "btf/codecs/dfmf_export.h"
#include "btf/codecs/fmf/fmf.h"
#include "btf/codecs/lpca/lpca.h"
#include "btf/codecs/mlvq/mlvq.h"
#include "btf/codecs/param_schema.h"
#include "btf/codecs/pca_views/pca_views.h"
#include "btf/codecs/perceptual/perceptual.h"
#include "btf/io/ubo2014.h"
#include "btf/util/error.h"

namespace btf {

Params Params::parse(const std::vector<std::string>& items) {
    Params params;
    for (const std::string& item : items) {
        const size_t eq = item.find('=');
        if (eq == std::string::npos || eq == 0)
            fail("codec parameter '{}': expected key=value", item);
        params.set(item.substr(0, eq), item.substr(eq + 1));
    }
    return params;
}

std::string Params::get_string(const std::string& key, const std::string& fallback) const {
    m_used.insert(key);
    const auto it = m_values.find(key);
    return it == m_values.end() ? fallback : it->second;
}

std::string Params::get_choice(const std::string& key, const std::string& fallback,
                               const std::vector<std::string>& allowed) const {
    const std::string value = get_string(key, fallback);
    if (std::find(allowed.begin(), allowed.end(), value) == allowed.end())
        fail("parameter {}: '{}' is not one of {}", key, value, fmt::join(allowed, ", "));
    return value;
}

int Params::get_int(const std::string& key, int fallback, int min, int max) const {
    if (!has(key)) {
        m_used.insert(key);
        return fallback;
    }
    const std::string text = get_string(key, "");
    int value = 0;
    const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
    if (ec != std::errc() || end != text.data() + text.size())
        fail("parameter {}: '{}' is not an integer", key, text);
    if (value < min || value > max)
        fail("parameter {}: {} is outside [{}, {}]", key, value, min, max);
    return value;
}

double Params::get_double(const std::string& key, double fallback, double min, double max) const {
    if (!has(key)) {
        m_used.insert(key);
        return fallback;
    }
    const std::string text = get_string(key, "");
    char* end = nullptr;
    const double value = std::strtod(text.c_str(), &end);
    if (text.empty() || end != text.c_str() + text.size() || !std::isfinite(value))
        fail("parameter {}: '{}' is not a number", key, text);
    if (value < min || value > max)
        fail("parameter {}: {} is outside [{}, {}]", key, value, min, max);
    return value;
}

bool Params::get_bool(const std::string& key, bool fallback) const {
    const std::string text = get_string(key, fallback ? "true" : "false");
    if (text == "true" || text == "1" || text == "yes" || text == "on") return true;
    if (text == "false" || text == "0" || text == "no" || text == "off") return false;
    fail("parameter {}: '{}' is not true or false", key, text);
}

void Params::check_all_used(std::string_view codec, const std::vector<ParamInfo>& known) const {
    for (const auto& [key, value] : m_values) {
        if (m_used.count(key)) continue;
        std::vector<std::string> names;
        for (const ParamInfo& info : known) names.push_back(info.name);
        fail("codec {}: unknown parameter '{}' (known: {})", codec, key, fmt::join(names, ", "));
    }
}

namespace {

// fmt writes exponents with two digits at least ("3e-05"); parameters read better as "3e-5".
std::string plain_exponent(std::string text) {
    for (const char* sign : {"e-0", "e+0"}) {
        const size_t at = text.find(sign);
        if (at != std::string::npos) text.erase(at + 2, 1);
    }
    return text;
}

}  // namespace

std::string param_number_text(double value) {
    return plain_exponent(fmt::format("{}", value));
}

std::string param_number_text(float value) {
    return plain_exponent(fmt::format("{}", value));
}

void Codec::check_several(size_t count) const {
    if (count <= 1 || encodes_several()) return;
    std::vector<std::string> several;
    for (const Codec* codec : codecs())
        if (codec->encodes_several()) several.emplace_back(codec->name());
    fail("codec {} compresses one input; several inputs share code-books only with {}", name(),
         fmt::join(several, ", "));
}

Package Codec::encode_several(std::span<const BtfSource* const> sources,
                              std::span<const std::string>, const Params& params,
                              Progress& progress) const {
    check_several(sources.size());
    check(sources.size() == 1, "codec {}: no source to encode", name());
    return encode(*sources[0], params, progress);
}

std::vector<std::unique_ptr<Material>> Codec::open_all(const Package& package) const {
    std::vector<std::unique_ptr<Material>> out;
    out.push_back(open(package));
    return out;
}

const std::vector<const Codec*>& codecs() {
    static const std::vector<const Codec*> all = {&fmf_codec(), &pca_views_codec(), &lpca_codec(),
                                                  &perceptual_codec(), &mlvq_codec()};
    return all;
}

const Codec& find_codec(std::string_view name) {
    std::vector<std::string> names;
    for (const Codec* codec : codecs()) {
        if (codec->name() == name) return *codec;
        names.emplace_back(codec->name());
    }
    fail("unknown codec '{}' (known: {})", name, fmt::join(names, ", "));
}

std::unique_ptr<Material> open_material(const Package& package) {
    // A BSVTF file is made from an fmf package by `btf bsvtf`, not by a codec's encode.
    if (package.codec() == "bsvtf") return bsvtf::open_material(package, "bsvtf");
    return find_codec(package.codec()).open(package);
}

std::vector<std::unique_ptr<Material>> open_materials(const Package& package) {
    if (package.codec() == "bsvtf") {
        std::vector<std::unique_ptr<Material>> out;
        out.push_back(open_material(package));
        return out;
    }
    return find_codec(package.codec()).open_all(package);
}

namespace {

// open(package) for the package at `path`, its errors prefixed with the path (a UBO2014 .btf
// file is its own factors' material: open_ubo2014).
template <typename Open, typename OpenUbo2014>
auto open_file(const std::filesystem::path& path, Open open, OpenUbo2014 open_ubo2014) {
    if (ubo2014::probe(path)) return open_ubo2014(path);
    const Package package = read_package(path);
    try {
        return open(package);
    } catch (const Cancelled&) {
        throw;
    } catch (const Error& e) {
        fail("{}: {}", path.string(), e.what());
    }
}

}  // namespace

std::vector<std::unique_ptr<Material>> open_materials(const std::filesystem::path& path) {
    return open_file(
        path, [](const Package& p) { return open_materials(p); },
        [](const std::filesystem::path& p) {
            std::vector<std::unique_ptr<Material>> out;
            out.push_back(open_ubo2014_material(p));
            return out;
        });
}

std::unique_ptr<Material> open_material(const std::filesystem::path& path) {
    return open_file(
        path, [](const Package& p) { return open_material(p); },
        [](const std::filesystem::path& p) { return open_ubo2014_material(p); });
}

}  // namespace btf
