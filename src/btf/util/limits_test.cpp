// SPDX-License-Identifier: MIT
#include "btf/util/limits.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "btf/testing/support.h"
#include "btf/util/json_fields.h"

namespace btf {
namespace {

using test::error_of;
using ::testing::AllOf;
using ::testing::HasSubstr;

TEST(Limits, ByteCountsParseWithBinarySuffixes) {
    EXPECT_EQ(parse_limit_bytes("123"), 123u);
    EXPECT_EQ(parse_limit_bytes("64K"), 64u << 10);
    EXPECT_EQ(parse_limit_bytes("512m"), 512u << 20);
    EXPECT_EQ(parse_limit_bytes("4G"), uint64_t(4) << 30);
    EXPECT_EQ(parse_limit_bytes("1T"), uint64_t(1) << 40);
    for (const char* bad :
         {"", "0", "-1", "4GB", "1.5G", "G", "99999999999999999999", "17179869184T"})
        EXPECT_EQ(parse_limit_bytes(bad), std::nullopt) << bad;
    EXPECT_EQ(format_limit_bytes(uint64_t(4) << 30), "4 GiB");
    EXPECT_EQ(format_limit_bytes(1000), "1000 B");
    EXPECT_EQ(format_limit_bytes(3 << 20), "3 MiB");
}

TEST(Limits, ImageSizesAreCheckedWithoutOverflow) {
    EXPECT_NO_THROW(check_image_size(8192, 8192, "a.jpg"));
    EXPECT_THAT(error_of([] { check_image_size(8193, 8192, "a.jpg"); }),
                AllOf(HasSubstr("a.jpg: image of 8193×8192 texels exceeds the limit of 67108864 "
                                "texels"),
                      HasSubstr("--max-image-pixels"), HasSubstr("BTF_MAX_IMAGE_PIXELS")));
    // A product that would overflow 64 bits is still refused.
    EXPECT_THAT(error_of([] { check_image_size(INT64_MAX, INT64_MAX, "b"); }),
                HasSubstr("exceeds the limit"));
    EXPECT_THAT(error_of([] { check_image_size(0, 5, "c"); }), HasSubstr("has no texels"));
    EXPECT_THAT(error_of([] { check_image_size(-1, 5, "c"); }), HasSubstr("has no texels"));
}

TEST(Limits, RaisedAndLoweredLimitsApplyToTheWholeProcess) {
    const Limits saved = limits();
    Limits l = saved;
    l.image_pixels = 100;
    l.alloc_bytes = 1000;
    set_limits(l);
    EXPECT_THAT(error_of([] { check_image_size(11, 10, "x"); }), HasSubstr("limit of 100"));
    EXPECT_THAT(error_of([] { check_alloc(1001, "x.btfpkg", "section 'a'"); }),
                HasSubstr("x.btfpkg: section 'a' needs 1001 bytes, over the limit of 1000 B "
                          "(raise it with --max-alloc or BTF_MAX_ALLOC)"));
    EXPECT_NO_THROW(check_alloc(1000, "x", "y"));
    EXPECT_THAT(error_of([] { set_limits(Limits{0, 1}); }), HasSubstr("positive"));
    set_limits(saved);
    EXPECT_EQ(limits().image_pixels, saved.image_pixels);
}

TEST(Limits, CheckedBytesReportsOverflow) {
    EXPECT_EQ(checked_bytes(3, 4), 12u);
    EXPECT_EQ(checked_bytes(uint64_t(1) << 40, uint64_t(1) << 30), std::nullopt);
}

TEST(JsonFields, IntegersMustBeExactAndInRange) {
    const nlohmann::json j = nlohmann::json::parse(
        R"({"a": 3, "big": 1099511627776, "half": 1.5, "neg": -2, "text": "3", "whole": 3.0,
            "huge": 18446744073709551615})");
    EXPECT_EQ(json_fields::integer_at(j, "a", 0, 10), 3);
    EXPECT_EQ(json_fields::integer_at(j, "neg", -5, 10), -2);
    EXPECT_EQ(json_fields::integer_or(j, "absent", 7, 0, 10), 7);
    for (const char* key : {"big", "half", "text", "whole", "huge"})
        EXPECT_THAT(error_of([&] { json_fields::integer_at(j, key, 0, 1 << 16); }),
                    AllOf(HasSubstr(std::string("'") + key +
                                    "' must be an integer from 0 to "
                                    "65536, not ")))
            << key;
    EXPECT_THAT(error_of([&] { json_fields::integer_at(j, "neg", 0, 10); }),
                HasSubstr("'neg' must be an integer from 0 to 10, not -2"));
}

TEST(JsonFields, NumbersMustBeFiniteAndInRange) {
    const nlohmann::json j = nlohmann::json::parse(R"({"x": 0.5, "y": 1e300, "s": "0.5"})");
    EXPECT_EQ(json_fields::number_at(j, "x", 0, 1), 0.5);
    EXPECT_THAT(error_of([&] { json_fields::number_at(j, "y", 0, 1e30); }),
                HasSubstr("'y' must be a number from 0 to 1e+30, not 1e+300"));
    EXPECT_THAT(error_of([&] { json_fields::number_at(j, "s", 0, 1); }),
                HasSubstr("'s' must be a number"));
}

TEST(JsonFields, ArraysAndKnownKeys) {
    const nlohmann::json j = nlohmann::json::parse(R"({"v": [1, 2, 3], "w": [1, 2.5]})");
    EXPECT_EQ(json_fields::integers(j["v"], "v", 0, 5, 3), (std::vector<int>{1, 2, 3}));
    EXPECT_THAT(error_of([&] { json_fields::integers(j["v"], "v", 0, 5, 2); }),
                HasSubstr("at most 2 integers"));
    EXPECT_THAT(error_of([&] { json_fields::integers(j["w"], "w", 0, 5, 4); }),
                HasSubstr("'w' must be an integer"));
    EXPECT_NO_THROW(json_fields::only_keys(j, "root", {"v", "w"}));
    EXPECT_THAT(error_of([&] { json_fields::only_keys(j, "root", {"v"}); }),
                HasSubstr("'root' has an unknown field 'w'"));
}

}  // namespace
}  // namespace btf
