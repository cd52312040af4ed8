// SPDX-License-Identifier: MIT
#include "btf/util/json_fields.h"

#include <algorithm>
#include <cmath>

#include "btf/util/error.h"
#include "btf/util/limits.h"

namespace btf::json_fields {

namespace {
// The value as the file wrote it, shortened: a crafted field may be megabytes long.
std::string shown(const nlohmann::json& value) {
    std::string text = value.dump();
    if (text.size() > 40) text = text.substr(0, 37) + "...";
    return text;
}
}  // namespace

int64_t integer(const nlohmann::json& value, std::string_view name, int64_t lo, int64_t hi) {
    bool ok = false;
    int64_t n = 0;
    if (value.is_number_unsigned()) {
        const uint64_t u = value.get<uint64_t>();
        ok = u <= uint64_t(INT64_MAX);
        n = ok ? int64_t(u) : 0;
    } else if (value.is_number_integer()) {
        ok = true;
        n = value.get<int64_t>();
    }
    if (!ok || n < lo || n > hi)
        fail("'{}' must be an integer from {} to {}, not {}", name, lo, hi, shown(value));
    return n;
}

int64_t integer_at(const nlohmann::json& object, std::string_view key, int64_t lo, int64_t hi) {
    return integer(object.at(std::string(key)), key, lo, hi);
}

int64_t integer_or(const nlohmann::json& object, std::string_view key, int64_t fallback, int64_t lo,
                   int64_t hi) {
    const auto it = object.find(std::string(key));
    return it == object.end() ? fallback : integer(*it, key, lo, hi);
}

double number(const nlohmann::json& value, std::string_view name, double lo, double hi) {
    const double x = value.is_number() ? value.get<double>() : NAN;
    if (!std::isfinite(x) || x < lo || x > hi)
        fail("'{}' must be a number from {:g} to {:g}, not {}", name, lo, hi, shown(value));
    return x;
}

double number_at(const nlohmann::json& object, std::string_view key, double lo, double hi) {
    return number(object.at(std::string(key)), key, lo, hi);
}

std::vector<int> integers(const nlohmann::json& value, std::string_view name, int64_t lo,
                          int64_t hi, size_t max_count) {
    if (!value.is_array() || value.size() > max_count)
        fail("'{}' must be an array of at most {} integers", name, max_count);
    std::vector<int> out;
    out.reserve(value.size());
    for (const nlohmann::json& v : value)
        out.push_back(int(
            integer(v, name, std::max<int64_t>(lo, INT32_MIN), std::min<int64_t>(hi, INT32_MAX))));
    return out;
}

void only_keys(const nlohmann::json& value, std::string_view name,
               std::initializer_list<std::string_view> known) {
    if (!value.is_object()) fail("'{}' must be an object", name);
    for (const auto& item : value.items())
        if (std::find(known.begin(), known.end(), item.key()) == known.end())
            fail("'{}' has an unknown field '{}'", name, item.key());
}

std::pair<int, int> extent(const nlohmann::json& object) {
    const int width = int(integer_at(object, "width", 1, 1 << 16));
    const int height = int(integer_at(object, "height", 1, 1 << 16));
    check_image_size(width, height, "extent");
    return {width, height};
}

}  // namespace btf::json_fields
