// SPDX-License-Identifier: MIT
#pragma once
/// Strict reading of the numbers in file headers (package headers, BSVTF headers): an integer
/// field must be a JSON integer (not 1.5, not 1e3) inside its range, a real field a finite number
/// inside its range. nlohmann's get<int>() would turn 1.5 into 1 and 2⁴⁰ into 0 without a word.
/// Errors name the field: "'model.clusters' must be an integer from 1 to 65536, not 1.5".

#include <cstdint>
#include <nlohmann/json.hpp>
#include <string_view>
#include <utility>
#include <vector>

namespace btf::json_fields {

/// `value` as an integer in [lo, hi]; `name` names it in the error.
int64_t integer(const nlohmann::json& value, std::string_view name, int64_t lo, int64_t hi);
/// `object.at(key)` as an integer in [lo, hi]; the error names `key`.
int64_t integer_at(const nlohmann::json& object, std::string_view key, int64_t lo, int64_t hi);
/// Like integer_at(), or `fallback` when `object` has no `key`.
int64_t integer_or(const nlohmann::json& object, std::string_view key, int64_t fallback, int64_t lo,
                   int64_t hi);
/// `value` as a finite number in [lo, hi].
double number(const nlohmann::json& value, std::string_view name, double lo, double hi);
/// `object.at(key)` as a finite number in [lo, hi].
double number_at(const nlohmann::json& object, std::string_view key, double lo, double hi);
/// An array of at most `max_count` integers, each in [lo, hi].
std::vector<int> integers(const nlohmann::json& value, std::string_view name, int64_t lo,
                          int64_t hi, size_t max_count);
/// A header's image extent: the integers "width" and "height" of `object`, each 1 to 65536 and
/// together within limits().image_pixels ("extent: image of W×H texels exceeds the limit …").
std::pair<int, int> extent(const nlohmann::json& object);
/// `value` must be an object with no keys other than `known`: an unknown key is an error, so a
/// misspelt or foreign field is never silently ignored.
void only_keys(const nlohmann::json& value, std::string_view name,
               std::initializer_list<std::string_view> known);

}  // namespace btf::json_fields
