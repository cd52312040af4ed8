// SPDX-License-Identifier: MIT
#include "btf/quality/batch_colour.h"

#include <gtest/gtest.h>

#include <fstream>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "btf/core/color.h"
#include "btf/quality/metrics.h"

namespace btf::quality {
namespace {

// The float batch kernel against the double reference on random colours across the gamut,
// including neutral greys (zero chroma) and hue pairs across the 0°/360° seam.
TEST(BatchColour, Ciede2000MatchesTheDoubleReference) {
    std::mt19937 rng(7);
    std::uniform_real_distribution<float> l(0, 100), ab(-110, 110), small(-1, 1);
    const int n = 20000;
    std::vector<float> p[6];
    for (auto& v : p) v.resize(n);
    for (int i = 0; i < n; ++i) {
        p[0][i] = l(rng), p[1][i] = ab(rng), p[2][i] = ab(rng);
        const bool near = i % 3 == 0;  // small differences, as between good compressions
        p[3][i] = near ? p[0][i] + small(rng) : l(rng);
        p[4][i] = near ? p[1][i] + small(rng) : ab(rng);
        p[5][i] = near ? p[2][i] + small(rng) : ab(rng);
        if (i % 50 == 0) p[1][i] = p[2][i] = 0;  // a neutral colour
        if (i % 70 == 0) p[2][i] = 0.01f, p[5][i] = -0.01f, p[1][i] = p[4][i] = 20;  // hue seam
    }
    std::vector<float> out(n);
    ciede2000(Planes{p[0].data(), p[1].data(), p[2].data()},
              Planes{p[3].data(), p[4].data(), p[5].data()}, out.data(), n);
    double worst = 0;
    for (int i = 0; i < n; ++i) {
        const double ref =
            ciede2000(Lab{p[0][i], p[1][i], p[2][i]}, Lab{p[3][i], p[4][i], p[5][i]});
        worst = std::max(worst, std::abs(out[i] - ref) / std::max(1.0, ref));
    }
    EXPECT_LT(worst, 1e-3);
}

TEST(BatchColour, Ciede2000ReproducesSharmaPairs) {
    std::ifstream in(std::string(BTF_SHARED_DIR) + "/data/ciede2000_sharma2005.tsv");
    if (!in) GTEST_SKIP() << "../shared/data/ciede2000_sharma2005.tsv is absent";
    std::string line;
    int pairs = 0;
    while (std::getline(in, line)) {
        if (line.empty() || line[0] == '#' || line.rfind("pair", 0) == 0) continue;
        std::istringstream fields(line);
        int id;
        float v[6];
        double expected;
        fields >> id >> v[0] >> v[1] >> v[2] >> v[3] >> v[4] >> v[5] >> expected;
        float out = 0;
        ciede2000(Planes{&v[0], &v[1], &v[2]}, Planes{&v[3], &v[4], &v[5]}, &out, 1);
        EXPECT_NEAR(out, expected, 2e-4 * std::max(1.0, expected)) << "pair " << id;
        ++pairs;
    }
    EXPECT_EQ(pairs, 34);
}

TEST(BatchColour, IdenticalColoursGiveExactlyZero) {
    std::vector<float> l = {0, 50, 100, 30}, a = {0, 20, -3, 0}, b = {0, -40, 7, 0};
    std::vector<float> out(4, 1);
    ciede2000(Planes{l.data(), a.data(), b.data()}, Planes{l.data(), a.data(), b.data()},
              out.data(), 4);
    for (float d : out) EXPECT_EQ(d, 0.0f);
}

// RGB → lαβ → CIELab equals the direct RGB → CIELab conversion (the opponent transform is
// invertible above the cone-response floor).
TEST(BatchColour, OpponentRoundTripGivesCielab) {
    std::mt19937 rng(3);
    std::uniform_real_distribution<float> u(0.002f, 1.5f);
    const int n = 5000;
    std::vector<Rgb> rgb(n);
    std::vector<float> o[3], lab[3];
    for (int c = 0; c < 3; ++c) o[c].resize(n), lab[c].resize(n);
    for (int i = 0; i < n; ++i) {
        rgb[i] = {u(rng), u(rng), u(rng)};
        const auto v = rgb_to_opponent(rgb[i]);
        for (int c = 0; c < 3; ++c) o[c][i] = v[size_t(c)];
    }
    opponent_to_lab({o[0].data(), o[1].data(), o[2].data()},
                    {lab[0].data(), lab[1].data(), lab[2].data()}, n);
    for (int i = 0; i < n; ++i) {
        const Lab ref = rgb_to_lab(rgb[i]);
        EXPECT_NEAR(lab[0][i], ref.l, 2e-3 * std::max(1.0, ref.l)) << i;
        EXPECT_NEAR(lab[1][i], ref.a, 2e-2) << i;
        EXPECT_NEAR(lab[2][i], ref.b, 2e-2) << i;
    }
}

}  // namespace
}  // namespace btf::quality
