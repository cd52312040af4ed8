// SPDX-License-Identifier: MIT
#pragma once
/// ParamSchema<Options>: a codec's parameters, each declared once — its name, type, range (or
/// choices), help text and the Options member it is stored in. Its default is that member's value
/// in a default-constructed Options, so the struct's initializer is the one place a default is
/// written. Everything else is derived from the declaration:
///   parse()    the codec parameters as text → Options, with the range and unknown-key errors;
///   to_json()  the package header's "params" object (every parameter as used, defaults included);
///   infos()    what `btf codecs`, the report's aliases and Python's keyword arguments show.
/// A field is a member pointer (&Options::components) or, for a nested member, a generic lambda
/// returning a reference ([](auto& o) -> auto& { return o.colour.log_eps; }).

#include <fmt/format.h>

#include <cstdint>
#include <functional>
#include <nlohmann/json.hpp>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include "btf/codecs/codec.h"
#include "btf/util/error.h"

namespace btf {

/// A number as parameter defaults and ranges are written: the shortest text that reads back to
/// the same value, with a plain exponent ("3e-5", not "3e-05").
std::string param_number_text(double value);
std::string param_number_text(float value);

template <class Options>
class ParamSchema {
  public:
    /// `codec` names the codec in the unknown-parameter error.
    explicit ParamSchema(std::string codec) : m_codec(std::move(codec)) {}

    /// An integer in [min, max], stored in an integral member (int, uint64_t, …).
    template <class Field>
    ParamSchema& integer(std::string name, Field field, int min, int max, std::string help) {
        using T = value_t<Field>;
        static_assert(std::is_integral_v<T> && !std::is_same_v<T, bool>);
        return add(
            {std::move(name), "int", "", fmt::format("{}..{}", min, max), std::move(help)},
            [=](const Params& p, const std::string& key, Options& o) {
                T& v = std::invoke(field, o);
                v = static_cast<T>(p.get_int(key, static_cast<int>(v), min, max));
            },
            [=](const Options& o) { return fmt::format("{}", std::invoke(field, o)); },
            [=](const Options& o) { return nlohmann::json(std::invoke(field, o)); });
    }

    /// A real number in [min, max], stored in a float or double member.
    template <class Field>
    ParamSchema& number(std::string name, Field field, double min, double max, std::string help) {
        using T = value_t<Field>;
        static_assert(std::is_floating_point_v<T>);
        return add(
            {std::move(name), "number", "", param_number_text(min) + ".." + param_number_text(max),
             std::move(help)},
            [=](const Params& p, const std::string& key, Options& o) {
                T& v = std::invoke(field, o);
                v = static_cast<T>(p.get_double(key, double(v), min, max));
            },
            [=](const Options& o) { return param_number_text(std::invoke(field, o)); },
            [=](const Options& o) { return nlohmann::json(std::invoke(field, o)); });
    }

    /// true or false (also 1/0, yes/no, on/off), stored in a bool member.
    template <class Field>
    ParamSchema& flag(std::string name, Field field, std::string help) {
        static_assert(std::is_same_v<value_t<Field>, bool>);
        return add(
            {std::move(name), "bool", "", "true|false", std::move(help)},
            [=](const Params& p, const std::string& key, Options& o) {
                bool& v = std::invoke(field, o);
                v = p.get_bool(key, v);
            },
            [=](const Options& o) -> std::string {
                return std::invoke(field, o) ? "true" : "false";
            },
            [=](const Options& o) { return nlohmann::json(std::invoke(field, o)); });
    }

    /// One of the named values `choices`, stored in a member of their type (an enum, an
    /// optional, …); the header records the name.
    template <class Field, class Value>
    ParamSchema& choice(std::string name, Field field,
                        std::vector<std::pair<std::string, Value>> choices, std::string help) {
        std::vector<std::string> names;
        for (const auto& c : choices) names.push_back(c.first);
        auto name_of = [choices, key = name](const Value& value) -> std::string {
            for (const auto& [text, v] : choices)
                if (v == value) return text;
            fail("parameter {}: the value held is none of its choices", key);
        };
        return add(
            {std::move(name), "choice", "", fmt::format("{}", fmt::join(names, "|")),
             std::move(help)},
            [=](const Params& p, const std::string& key, Options& o) {
                Value& v = std::invoke(field, o);
                const std::string text = p.get_choice(key, name_of(v), names);
                for (const auto& [t, value] : choices)
                    if (t == text) v = value;
            },
            [=](const Options& o) { return name_of(std::invoke(field, o)); },
            [=](const Options& o) { return nlohmann::json(name_of(std::invoke(field, o))); });
    }

    /// Runs after every parameter is read, in the order added: checks that involve several
    /// parameters (throwing btf::Error) and values derived from them.
    ParamSchema& then(std::function<void(Options&)> finish) {
        m_finish.push_back(std::move(finish));
        return *this;
    }

    /// Every parameter, with its default as text.
    std::vector<ParamInfo> infos() const {
        const Options defaults{};
        std::vector<ParamInfo> out;
        for (const Entry& e : m_entries) {
            ParamInfo info = e.info;
            info.default_value = e.text(defaults);
            out.push_back(std::move(info));
        }
        return out;
    }

    /// The options `params` give (defaults for the ones not given); throws btf::Error for a value
    /// of the wrong type or out of range, a failed check, and a parameter not declared here.
    Options parse(const Params& params) const {
        Options options{};
        for (const Entry& e : m_entries) e.read(params, e.info.name, options);
        for (const auto& finish : m_finish) finish(options);
        params.check_all_used(m_codec, infos());
        return options;
    }

    /// {"name": value, …} for every parameter: numbers and flags as JSON numbers and booleans,
    /// choices by name.
    nlohmann::json to_json(const Options& options) const {
        nlohmann::json out = nlohmann::json::object();
        for (const Entry& e : m_entries) out[e.info.name] = e.json(options);
        return out;
    }

  private:
    template <class Field>
    using value_t = std::remove_cvref_t<std::invoke_result_t<Field, Options&>>;

    struct Entry {
        ParamInfo info;
        std::function<void(const Params&, const std::string&, Options&)> read;
        std::function<std::string(const Options&)> text;
        std::function<nlohmann::json(const Options&)> json;
    };

    template <class Read, class Text, class Json>
    ParamSchema& add(ParamInfo info, Read read, Text text, Json json) {
        for (const Entry& e : m_entries)
            if (e.info.name == info.name)
                fail("codec {}: parameter {} declared twice", m_codec, info.name);
        m_entries.push_back({std::move(info), std::move(read), std::move(text), std::move(json)});
        return *this;
    }

    std::string m_codec;
    std::vector<Entry> m_entries;
    std::vector<std::function<void(Options&)>> m_finish;
};

}  // namespace btf
