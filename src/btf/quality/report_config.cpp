// SPDX-License-Identifier: MIT
// The report's codec configurations ("fmf:C=8,16,32") and its default selection of images.

#include <fmt/format.h>

#include <algorithm>
#include <map>

#include "btf/quality/report.h"
#include "btf/util/error.h"

namespace btf::quality {

namespace {

std::string trim(std::string_view text) {
    const size_t first = text.find_first_not_of(" \t");
    if (first == std::string_view::npos) return {};
    const size_t last = text.find_last_not_of(" \t");
    return std::string(text.substr(first, last - first + 1));
}

bool has_param(const Codec& codec, const std::string& name) {
    for (const ParamInfo& info : codec.params())
        if (info.name == name) return true;
    return false;
}

// Short names of the command line; they apply only to codecs that have the parameter.
std::string resolve_alias(const Codec& codec, const std::string& key) {
    static const std::map<std::string, std::string> aliases = {{"C", "components"},
                                                               {"k", "views-per-group"}};
    const auto it = aliases.find(key);
    if (it != aliases.end() && has_param(codec, it->second)) return it->second;
    return key;
}

std::vector<CodecConfig> parse_one(const std::string& text) {
    const size_t colon = text.find(':');
    const std::string name = trim(text.substr(0, colon));
    if (name.empty()) fail("no codec name (expected codec[:key=value,…])");
    const Codec& codec = find_codec(name);

    // Parameters with their values, in the order given.
    std::vector<std::pair<std::string, std::vector<std::string>>> params;
    if (colon != std::string::npos) {
        const std::string list = text.substr(colon + 1);
        if (trim(list).empty()) fail("no parameters after ':'");
        size_t start = 0;
        while (start <= list.size()) {
            size_t end = list.find(',', start);
            if (end == std::string::npos) end = list.size();
            const std::string item = trim(std::string_view(list).substr(start, end - start));
            start = end + 1;
            if (item.empty()) fail("empty item in the parameter list");
            const size_t eq = item.find('=');
            if (eq == std::string::npos) {
                if (params.empty())
                    fail("value '{}' has no parameter (expected key=value first)", item);
                params.back().second.push_back(item);
                continue;
            }
            const std::string key = trim(item.substr(0, eq));
            const std::string value = trim(item.substr(eq + 1));
            if (key.empty()) fail("'{}': parameter name missing", item);
            if (value.empty()) fail("parameter {}: value missing", key);
            const std::string resolved = resolve_alias(codec, key);
            for (const auto& [earlier, values] : params)
                if (earlier == resolved) fail("parameter {} is given twice", resolved);
            params.push_back({resolved, {value}});
        }
    }
    for (const auto& [key, values] : params)
        for (size_t i = 0; i < values.size(); ++i)
            for (size_t j = 0; j < i; ++j)
                if (values[i] == values[j])
                    fail("parameter {}: value {} is given twice", key, values[i]);

    // Cartesian product, the last parameter varying fastest.
    std::vector<CodecConfig> configs(1);
    configs[0].codec = std::string(codec.name());
    for (const auto& [key, values] : params) {
        std::vector<CodecConfig> next;
        for (const CodecConfig& partial : configs)
            for (const std::string& value : values) {
                CodecConfig config = partial;
                config.params.emplace_back(key, value);
                next.push_back(std::move(config));
            }
        configs = std::move(next);
    }
    // The codec's own message for a parameter it does not know or a value it refuses.
    for (const CodecConfig& config : configs) codec.validate(config.to_params());
    return configs;
}

}  // namespace

Params CodecConfig::to_params() const {
    Params params;
    for (const auto& [key, value] : this->params) params.set(key, value);
    return params;
}

std::string CodecConfig::parameters_text() const {
    if (params.empty()) return "defaults";
    std::string text;
    for (const auto& [key, value] : params) text += (text.empty() ? "" : ", ") + key + "=" + value;
    return text;
}

std::string CodecConfig::label() const {
    std::string text = codec;
    for (const auto& [key, value] : params) text += " " + key + "=" + value;
    return text;
}

std::vector<CodecConfig> parse_codec_configs(const std::string& text) {
    try {
        return parse_one(text);
    } catch (const Cancelled&) {
        throw;
    } catch (const Error& e) {
        fail("codec configuration '{}': {}", text, e.what());
    }
}

std::vector<CodecConfig> parse_codec_configs(const std::vector<std::string>& texts) {
    std::vector<CodecConfig> all;
    for (const std::string& text : texts) {
        for (CodecConfig& config : parse_codec_configs(text)) {
            if (std::find(all.begin(), all.end(), config) != all.end())
                fail("codec configuration '{}': {} appears twice", text, config.label());
            all.push_back(std::move(config));
        }
    }
    if (all.empty()) fail("no codec configuration given");
    return all;
}

std::vector<ReportImage> default_report_images(const Sampling& sampling) {
    const Vec3 normal = Direction{}.vector();
    auto most_grazing = [](const DirectionSet& set) {
        double theta = 0;
        for (const Direction& d : set.directions()) theta = std::max(theta, d.theta);
        return set.nearest(Direction{theta, 0}.vector());
    };
    const int normal_view = sampling.views.nearest(normal);
    const int frontal_light = sampling.lights.nearest(normal);
    const int grazing_light = most_grazing(sampling.lights);
    const int grazing_view = most_grazing(sampling.views);

    std::vector<ReportImage> images = {
        {normal_view, frontal_light, "normal view, frontal light", {}, {}},
        {normal_view, grazing_light, "normal view, grazing light", {}, {}},
        {grazing_view, frontal_light, "grazing view, frontal light", {}, {}}};
    std::vector<ReportImage> unique;
    for (ReportImage& image : images) {
        image.view_direction = sampling.views[image.view];
        image.light_direction = sampling.lights[image.light];
        const bool seen = std::any_of(unique.begin(), unique.end(), [&](const ReportImage& u) {
            return u.view == image.view && u.light == image.light;
        });
        if (!seen) unique.push_back(image);
    }
    return unique;
}

}  // namespace btf::quality
