// SPDX-License-Identifier: MIT
#include "btf/codecs/param_schema.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <fstream>
#include <map>
#include <optional>
#include <sstream>

#include "btf/testing/support.h"

namespace btf {
namespace {

using testing::HasSubstr;

enum class Shape { kRound, kSquare };

struct Nested {
    float scale = 0.25f;
};

struct Toy {
    int count = 7;
    uint64_t seed = 3;
    double rate = 3e-5;
    bool fast = false;
    Shape shape = Shape::kSquare;
    std::optional<int> mode;  // none: "auto"
    Nested nested;
    int derived = 0;
};

ParamSchema<Toy> toy_schema() {
    ParamSchema<Toy> s("toy");
    s.integer("count", &Toy::count, 1, 100, "how many")
        .integer("seed", &Toy::seed, 0, 1 << 30, "random seed")
        .number("rate", &Toy::rate, 0, 1, "a rate")
        .flag("fast", &Toy::fast, "go fast")
        .choice("shape", &Toy::shape,
                std::vector<std::pair<std::string, Shape>>{{"round", Shape::kRound},
                                                           {"square", Shape::kSquare}},
                "the shape")
        .choice("mode", &Toy::mode,
                std::vector<std::pair<std::string, std::optional<int>>>{
                    {"auto", std::nullopt}, {"one", 1}, {"two", 2}},
                "the mode")
        .number(
            "scale", [](auto& t) -> auto& { return t.nested.scale; }, 0, 1, "nested member")
        .then([](Toy& t) {
            if (t.fast && t.shape == Shape::kRound) fail("parameter fast: not with round shapes");
            t.derived = 2 * t.count;
        });
    return s;
}

TEST(ParamSchema, DefaultsComeFromTheOptionsInitializers) {
    const std::vector<ParamInfo> infos = toy_schema().infos();
    ASSERT_EQ(infos.size(), 7u);
    const std::vector<std::vector<std::string>> expected = {
        {"count", "int", "7", "1..100", "how many"},
        {"seed", "int", "3", "0..1073741824", "random seed"},
        {"rate", "number", "3e-5", "0..1", "a rate"},
        {"fast", "bool", "false", "true|false", "go fast"},
        {"shape", "choice", "square", "round|square", "the shape"},
        {"mode", "choice", "auto", "auto|one|two", "the mode"},
        {"scale", "number", "0.25", "0..1", "nested member"},
    };
    for (size_t i = 0; i < infos.size(); ++i) {
        const ParamInfo& p = infos[i];
        EXPECT_EQ((std::vector<std::string>{p.name, p.type, p.default_value, p.range, p.help}),
                  expected[i]);
    }
}

TEST(ParamSchema, ParsesIntoTheDeclaredMembers) {
    const ParamSchema<Toy> schema = toy_schema();
    const Toy defaults = schema.parse(Params{});
    EXPECT_EQ(defaults.count, 7);
    EXPECT_EQ(defaults.derived, 14);  // then() ran
    EXPECT_FALSE(defaults.mode.has_value());

    const Toy t = schema.parse(Params{{"count", "9"},
                                      {"seed", "12"},
                                      {"rate", "0.5"},
                                      {"fast", "yes"},
                                      {"mode", "two"},
                                      {"scale", "0.75"}});
    EXPECT_EQ(t.count, 9);
    EXPECT_EQ(t.seed, 12u);
    EXPECT_EQ(t.rate, 0.5);
    EXPECT_TRUE(t.fast);
    EXPECT_EQ(t.mode, 2);
    EXPECT_EQ(t.nested.scale, 0.75f);
    EXPECT_EQ(t.derived, 18);

    // The header's record: JSON numbers and booleans, choices by name.
    EXPECT_EQ(schema.to_json(t), nlohmann::json::parse(R"({"count": 9, "seed": 12, "rate": 0.5,
        "fast": true, "shape": "square", "mode": "two", "scale": 0.75})"));
    // What the record says parses back to the same options.
    const nlohmann::json record = schema.to_json(t);
    std::map<std::string, std::string> text;
    for (const auto& [key, value] : record.items())
        text[key] = value.is_string() ? value.get<std::string>() : value.dump();
    EXPECT_EQ(schema.to_json(schema.parse(Params(text))), record);
}

TEST(ParamSchema, RefusesWhatTheDeclarationRulesOut) {
    const ParamSchema<Toy> schema = toy_schema();
    auto error = [&](Params p) { return test::error_of([&] { schema.parse(p); }); };
    EXPECT_EQ(error({{"count", "0"}}), "parameter count: 0 is outside [1, 100]");
    EXPECT_EQ(error({{"count", "2.5"}}), "parameter count: '2.5' is not an integer");
    EXPECT_EQ(error({{"rate", "nan"}}), "parameter rate: 'nan' is not a number");
    EXPECT_EQ(error({{"fast", "maybe"}}), "parameter fast: 'maybe' is not true or false");
    EXPECT_EQ(error({{"shape", "oval"}}), "parameter shape: 'oval' is not one of round, square");
    EXPECT_EQ(error({{"fast", "true"}, {"shape", "round"}}),
              "parameter fast: not with round shapes");
    EXPECT_EQ(error({{"cout", "3"}}),
              "codec toy: unknown parameter 'cout' (known: count, seed, rate, fast, shape, mode, "
              "scale)");
    ParamSchema<Toy> twice("toy");
    twice.integer("count", &Toy::count, 1, 2, "");
    EXPECT_EQ(test::error_of([&] { twice.flag("count", &Toy::fast, ""); }),
              "codec toy: parameter count declared twice");
}

// Every codec: its declared defaults, given explicitly, are accepted and change nothing; each
// declared integer or number range is enforced at both ends.
TEST(CodecParams, EveryCodecAcceptsItsDefaultsAndEnforcesItsRanges) {
    for (const Codec* codec : codecs()) {
        SCOPED_TRACE(std::string(codec->name()));
        std::map<std::string, std::string> defaults;
        for (const ParamInfo& p : codec->params()) defaults[p.name] = p.default_value;
        EXPECT_NO_THROW(codec->validate(Params(defaults)));
        for (const ParamInfo& p : codec->params()) {
            if (p.type != "int" && p.type != "number") continue;
            const size_t dots = p.range.find("..");
            ASSERT_NE(dots, std::string::npos) << p.name;
            const double low = std::stod(p.range.substr(0, dots));
            const double high = std::stod(p.range.substr(dots + 2));
            const double step = p.type == "int" ? 1 : std::max(1e-3, std::abs(high) * 1e-3);
            for (const double outside : {low - step, high + step}) {
                const std::string text = p.type == "int"
                                             ? std::to_string(static_cast<int64_t>(outside))
                                             : param_number_text(outside);
                EXPECT_THAT(test::error_of([&] {
                                codec->validate(Params{{p.name, text}});
                            }),
                            HasSubstr("parameter " + p.name + ": "))
                    << text;
            }
        }
        EXPECT_THAT(test::error_of([&] {
                        codec->validate(Params{{"no-such", "1"}});
                    }),
                    HasSubstr("unknown parameter 'no-such'"));
    }
}

// docs/codecs.md documents each codec's parameters in a table under the codec's heading; the
// declaration is the source of truth, and this keeps the table's names and defaults in step.
TEST(CodecParams, DocsTablesMatchTheDeclarations) {
    std::ifstream in(std::string(BTF_SOURCE_DIR) + "/docs/codecs.md");
    ASSERT_TRUE(in) << "docs/codecs.md";
    std::map<std::string, std::map<std::string, std::string>> documented;  // codec → name → default
    std::string line, section;
    auto split = [](const std::string& text) {
        std::vector<std::string> out;
        std::stringstream items(text);
        for (std::string item; std::getline(items, item, ',');) {
            const size_t a = item.find_first_not_of(" `"), b = item.find_last_not_of(" `");
            out.push_back(a == std::string::npos ? "" : item.substr(a, b - a + 1));
        }
        return out;
    };
    while (std::getline(in, line)) {
        if (line.rfind("## ", 0) == 0) section = line.substr(3);
        if (line.rfind("| `", 0) != 0) continue;
        const size_t bar = line.find('|', 1), next = line.find('|', bar + 1);
        const std::vector<std::string> names = split(line.substr(1, bar - 1));
        const std::vector<std::string> values = split(line.substr(bar + 1, next - bar - 1));
        ASSERT_EQ(names.size(), values.size()) << line;
        for (size_t i = 0; i < names.size(); ++i) documented[section][names[i]] = values[i];
    }
    for (const Codec* codec : codecs()) {
        const std::string name(codec->name());
        SCOPED_TRACE(name);
        ASSERT_TRUE(documented.count(name)) << "no '## " << name << "' table in docs/codecs.md";
        const auto& table = documented[name];
        for (const ParamInfo& p : codec->params()) {
            const auto it = table.find(p.name);
            ASSERT_NE(it, table.end()) << p.name << " is not in docs/codecs.md";
            EXPECT_EQ(it->second, p.default_value) << p.name;
        }
        EXPECT_EQ(table.size(), codec->params().size());
    }
}

}  // namespace
}  // namespace btf
