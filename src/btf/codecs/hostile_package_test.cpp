// SPDX-License-Identifier: MIT
// Crafted package headers and sections against every codec's open(): each must be refused with a
// one-line btf::Error naming what is wrong, before anything is allocated for it, and never turn
// into NaN values, a silently narrowed integer or an ignored field. The cases are those a
// structure-aware fuzzing run found accepted (docs/reliability.md).

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <functional>
#include <limits>
#include <map>

#include "btf/codecs/codec.h"
#include "btf/synth/synth.h"
#include "btf/testing/sources.h"
#include "btf/testing/support.h"
#include "btf/util/limits.h"

namespace btf {
namespace {

using test::error_of;
using ::testing::AllOf;
using ::testing::HasSubstr;

const BtfSource& leather() {
    static const std::unique_ptr<FunctionSource> source =
        test::cached(*synth::make("leather", 16, test::ubo_subset(6, 8), 5));
    return *source;
}

const Package& encoded(const std::string& codec) {
    static std::map<std::string, Package> cache;
    auto it = cache.find(codec);
    if (it != cache.end()) return it->second;
    Params params;
    if (codec == "fmf") params = Params({{"components", "3"}});
    if (codec == "fmf-coded") {
        const Package p = find_codec("fmf").encode(
            leather(), Params({{"components", "3"}, {"quantize", "coded"}}));
        return cache[codec] = p;
    }
    if (codec == "mlvq")
        params = Params({{"n-alpha", "7"}, {"n-beta", "7"}, {"n-theta-v", "4"}, {"n-phi-v", "6"}});
    return cache[codec] = find_codec(codec).encode(leather(), params);
}

// The package after `edit`, written to bytes and read back (checksums recomputed: the edit
// reaches the codec, as a crafted file would), then opened.
std::string open_error(const std::string& codec, const std::function<void(Package&)>& edit) {
    Package p = encoded(codec);
    edit(p);
    const std::vector<uint8_t> bytes = encode_package(p, {0});
    test::TempFolder temp;
    const std::filesystem::path file = temp.path() / "crafted.btfpkg";
    test::write_file(file, std::string(bytes.begin(), bytes.end()));
    return error_of([&] { open_material(file); });
}

PackageSection& section(Package& p, const std::string& name) {
    for (PackageSection& s : p.sections)
        if (s.name == name) return s;
    ADD_FAILURE() << "no section " << name;
    return p.sections.front();
}

TEST(HostilePackage, TheUneditedPackagesOpen) {
    for (const char* codec : {"fmf", "mlvq"}) {
        Package p = encoded(codec);
        const std::vector<uint8_t> bytes = encode_package(p, {0});
        const auto material = open_material(decode_package(bytes, "plain.btfpkg"));
        const Rgb v =
            material->eval({0.3, 0.6}, Direction{0.3, 1.0}.vector(), Direction{0.2, 2.0}.vector());
        EXPECT_TRUE(std::isfinite(v.r) && std::isfinite(v.g) && std::isfinite(v.b)) << codec;
    }
}

// Coded components (factor/coded.h): damage is refused with the section's name, and codes so
// large that the decoded factor overflows are refused as not finite.
TEST(HostilePackage, DamagedCodedComponentsAreRefused) {
    EXPECT_THAT(open_error("fmf-coded", [](Package& p) { section(p, "b0.k1").data.pop_back(); }),
                HasSubstr("section 'b0.k1': the coded factors end early"));
    EXPECT_THAT(open_error("fmf-coded", [](Package& p) { section(p, "b0.k0").data[2] = 1 + 8; }),
                HasSubstr("section 'b0.k0': unknown texel coding 9"));
    EXPECT_THAT(open_error("fmf-coded",
                           [](Package& p) {
                               // a's step the largest float: every code of 2 or more times it
                               // overflows.
                               auto& d = section(p, "b0.k0").data;
                               const float huge = std::numeric_limits<float>::max();
                               std::memcpy(d.data() + 4, &huge, 4);
                           }),
                HasSubstr("not a finite number"));
}

TEST(HostilePackage, NonFiniteFactorsAreRefusedWhenOpened) {
    // An f16 NaN (0x7e00) as the first value of the first component: it used to evaluate to NaN.
    for (const uint16_t bits : {uint16_t(0x7e00), uint16_t(0x7c00)}) {
        const std::string e = open_error("fmf", [&](Package& p) {
            PackageSection& s = section(p, "b0.k0");
            std::memcpy(s.data.data(), &bits, 2);
        });
        EXPECT_THAT(e, AllOf(HasSubstr("crafted.btfpkg"), HasSubstr("not a finite number")));
    }
}

TEST(HostilePackage, HeaderIntegersMustBeExactAndInRange) {
    const nlohmann::json huge = uint64_t(1) << 40, half = 1.5;
    struct Case {
        const char* field;
        std::function<void(nlohmann::json&, const nlohmann::json&)> set;
    };
    const std::vector<Case> cases = {
        {"groups",
         [](nlohmann::json& h, const nlohmann::json& v) { h["model"]["groups"][0][0] = v; }},
        {"plane",
         [](nlohmann::json& h, const nlohmann::json& v) { h["model"]["blocks"][0]["plane"] = v; }},
        {"cluster", [](nlohmann::json& h,
                       const nlohmann::json& v) { h["model"]["blocks"][0]["cluster"] = v; }},
        {"clusters",
         [](nlohmann::json& h, const nlohmann::json& v) { h["model"]["clusters"] = v; }},
        {"levels", [](nlohmann::json& h, const nlohmann::json& v) { h["model"]["levels"] = v; }},
        {"width", [](nlohmann::json& h, const nlohmann::json& v) { h["width"] = v; }},
    };
    for (const Case& c : cases)
        for (const nlohmann::json& value : {huge, half}) {
            const std::string e = open_error("fmf", [&](Package& p) { c.set(p.header, value); });
            EXPECT_THAT(e, AllOf(HasSubstr("crafted.btfpkg"), HasSubstr(c.field),
                                 HasSubstr("must be an integer")))
                << c.field << " = " << value.dump();
        }
    for (const nlohmann::json& value : {huge, half}) {
        const std::string e =
            open_error("mlvq", [&](Package& p) { p.header["grid"]["n_alpha"] = value; });
        EXPECT_THAT(e, AllOf(HasSubstr("n_alpha"), HasSubstr("must be an integer"))) << value;
    }
}

TEST(HostilePackage, MlvqExtentMustBeStatedAndAgree) {
    for (const nlohmann::json& value : {nlohmann::json(0), nlohmann::json(-1), nlohmann::json()}) {
        const std::string e = open_error("mlvq", [&](Package& p) { p.header["width"] = value; });
        EXPECT_THAT(e, AllOf(HasSubstr("crafted.btfpkg"), HasSubstr("'width'"))) << value;
        const std::string e2 =
            open_error("mlvq", [&](Package& p) { p.header["materials"][0]["width"] = value; });
        EXPECT_THAT(e2, HasSubstr("width")) << value;
    }
    const std::string e = open_error("mlvq", [](Package& p) {
        p.header["views"]["theta"].erase(p.header["views"]["theta"].size() - 1);
    });
    EXPECT_THAT(e, HasSubstr("views"));
}

TEST(HostilePackage, CodeBookSizesAreCheckedAgainstTheSectionBeforeAllocating) {
    const std::string e =
        open_error("mlvq", [](Package& p) { p.header["codebooks"]["P1"] = int64_t(1) << 31; });
    EXPECT_THAT(e, AllOf(HasSubstr("crafted.btfpkg"), HasSubstr("P1"), HasSubstr("too short")));
}

TEST(HostilePackage, AnMlvqExtentLargerThanItsIndexSectionsIsRefusedBeforeAllocating) {
    // 20000 × 12 texels (two index levels) claimed by the index of a 16² material.
    const std::string e = open_error("mlvq", [](Package& p) {
        for (nlohmann::json* h : {&p.header, &p.header["materials"][0]}) {
            (*h)["width"] = 20000;
            (*h)["height"] = 12;
        }
        p.header["materials"][0]["P6_levels"] = 2;
        std::erase_if(p.sections, [](const PackageSection& s) { return s.name == "P6.2"; });
        --p.declared_sections;
    });
    EXPECT_THAT(e, AllOf(HasSubstr("crafted.btfpkg"), HasSubstr("section 'P6.1'"),
                         HasSubstr("is too short for the 60000 entries of P6 level 1")));
}

TEST(HostilePackage, UndeclaredSectionsAndTrailingBytesAreRefused) {
    for (const char* codec : {"fmf", "mlvq"}) {
        const std::string e = open_error(codec, [](Package& p) {
            PackageSection extra;
            extra.name = "extra";
            extra.data = {1, 2, 3};
            p.sections.push_back(extra);
            ++p.declared_sections;
        });
        EXPECT_THAT(e, AllOf(HasSubstr("crafted.btfpkg"), HasSubstr("unknown section 'extra'")))
            << codec;
    }
    const std::string e =
        open_error("fmf", [](Package& p) { section(p, "tables").data.push_back(0); });
    EXPECT_THAT(e, AllOf(HasSubstr("crafted.btfpkg"), HasSubstr("section 'tables'")));
}

// The viewer's interpolation tables must be those of the header's directions; their floats to
// within their last bits, which differ between builds and machines (a package written by a
// -march=native build opens in the Debian package's x86-64 build, and the other way round).
TEST(HostilePackage, TablesMatchTheDirectionsToTheLastBitsOfTheirFloats) {
    // Words 0-5 are the view set's counts; the first vertex's x follows.
    const auto word = [](Package& p, size_t index) -> uint8_t* {
        return section(p, "tables").data.data() + 4 * index;
    };
    const auto nudge = [&](Package& p, float by) {
        float x;
        std::memcpy(&x, word(p, 6), 4);
        x = x == 0 ? by : x * (1 + by);
        std::memcpy(word(p, 6), &x, 4);
    };
    Package close = encoded("fmf");
    nudge(close, 3e-7f);
    EXPECT_NO_THROW(open_material(decode_package(encode_package(close, {0}), "close.btfpkg")));
    EXPECT_THAT(open_error("fmf", [&](Package& p) { nudge(p, 1e-3f); }),
                HasSubstr("section 'tables'"));
    // The grid resolution, an integer, must be exact.
    EXPECT_THAT(open_error("fmf", [&](Package& p) { ++*reinterpret_cast<int32_t*>(word(p, 0)); }),
                HasSubstr("section 'tables'"));
}

TEST(HostilePackage, DirectionsMustLieOnTheHemisphere) {
    const std::string theta =
        open_error("fmf", [](Package& p) { p.header["views"]["theta"][1] = -2147483648.0; });
    EXPECT_THAT(theta, AllOf(HasSubstr("crafted.btfpkg"), HasSubstr("'theta' must be a number")));
    const std::string phi =
        open_error("fmf", [](Package& p) { p.header["lights"]["phi"][2] = 65537.0; });
    EXPECT_THAT(phi, AllOf(HasSubstr("crafted.btfpkg"), HasSubstr("'phi' must be a number")));
}

TEST(HostilePackage, DeclaredExtentsAndSectionsRespectTheLimits) {
    test::TempFolder temp;
    const std::filesystem::path file = temp.path() / "crafted.btfpkg";
    Package package = encoded("fmf");
    const std::vector<uint8_t> bytes = encode_package(package, {0});
    test::write_file(file, std::string(bytes.begin(), bytes.end()));
    std::string e, e2;
    {
        // The 16² test material has 256 texels.
        const test::ScopedLimits small([](Limits& l) { l.image_pixels = 100; });
        e = error_of([&] { open_material(file); });
    }
    {
        const test::ScopedLimits tiny_alloc([](Limits& l) { l.alloc_bytes = 64; });
        e2 = error_of([&] { open_material(file); });
        // The writer applies the reader's limit: what it writes can be read.
        EXPECT_THAT(
            error_of([&] { encode_package(package, {0}); }),
            AllOf(HasSubstr("section 'tables' needs"), HasSubstr("over the limit of 64 B")));
    }
    EXPECT_THAT(
        e, AllOf(HasSubstr("crafted.btfpkg"), HasSubstr("16×16"),
                 HasSubstr("exceeds the limit of 100 texels"), HasSubstr("--max-image-pixels")));
    EXPECT_THAT(e2, AllOf(HasSubstr("crafted.btfpkg"), HasSubstr("over the limit of 64 B"),
                          HasSubstr("--max-alloc")));
}

}  // namespace
}  // namespace btf
