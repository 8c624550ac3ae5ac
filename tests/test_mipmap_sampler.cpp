// The mipmap-ordered inverse CDF (relight/pointlight/mipmap_sampler.h). Asserted: the pyramid
// holds block sums; inverting the CDF in mipmap order visits every texel with its
// exact probability (each texel's u-interval has the length of its weight); many
// stratified draws reproduce a known map's distribution (chi-square); zero-weight
// texels are never drawn; draws are deterministic per seed.

#include "relight/pointlight/mipmap_sampler.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

#include "tests/test_support.h"

using namespace prt;

namespace {

std::vector<float> knownMap(int res) {
    // A smooth bump, a bright spot, a hole of zeros.
    std::vector<float> w(size_t(res) * size_t(res));
    for (int y = 0; y < res; ++y)
        for (int x = 0; x < res; ++x) {
            const double u = (x + 0.5) / res, v = (y + 0.5) / res;
            double value = 0.2 + std::exp(-20.0 * ((u - 0.3) * (u - 0.3) + (v - 0.6) * (v - 0.6)));
            if (x == res - 3 && y == 2) value += 5.0;
            if (x < res / 4 && y < res / 4) value = 0.0;
            w[size_t(y) * size_t(res) + size_t(x)] = float(value);
        }
    return w;
}

}  // namespace

TEST(MipmapSampler, LevelsHoldBlockSums) {
    const int res = 16;
    const std::vector<float> w = knownMap(res);
    const MipmapSampler s(w, res);
    EXPECT_EQ(s.levels(), 5);
    double total = 0.0;
    for (float v : w) total += v;
    EXPECT_NEAR(s.total(), total, 1e-9 * total);
    double block = 0.0;
    for (int y = 4; y < 8; ++y)
        for (int x = 8; x < 12; ++x) block += w[size_t(y) * res + x];
    EXPECT_NEAR(s.blockSum(2, 2, 1), block, 1e-9 * block);
}

// Sweeping u over a fine grid, every texel is returned for a fraction of u equal to its
// probability: the inverse CDF is exact, not just plausible.
TEST(MipmapSampler, InverseCdfGivesEveryTexelItsProbability) {
    const int res = 8;
    const std::vector<float> w = knownMap(res);
    const MipmapSampler s(w, res);
    const int steps = 1 << 20;
    std::vector<double> hits(w.size(), 0.0);
    for (int i = 0; i < steps; ++i) hits[s.sample((i + 0.5) / steps)] += 1.0 / steps;
    for (size_t t = 0; t < w.size(); ++t) {
        EXPECT_NEAR(hits[t], s.probability(uint32_t(t)), 2.0 / steps) << t;
        if (w[t] == 0.0f) {
            EXPECT_EQ(hits[t], 0.0) << t;
        }
    }
    // The same distribution as the row-major inverse (Fig. 2a), in a different order.
    std::vector<double> rowMajor(w.size(), 0.0);
    for (int i = 0; i < steps; ++i) rowMajor[MipmapSampler::rowMajorInverse(w, (i + 0.5) / steps)] += 1.0 / steps;
    for (size_t t = 0; t < w.size(); ++t) EXPECT_NEAR(hits[t], rowMajor[t], 2.0 / steps);
}

// Chi-square of 200,000 jittered stratified draws on a 32 x 32 map against the
// weights, over bins of expected count >= 5 (1023 degrees of freedom at most); the
// 99.9% quantile for ~1000 dof is about 1145. Stratification makes the statistic
// smaller than for independent draws, never larger; a sampler that drew, say, in
// proportion to sqrt(w) gives a statistic in the tens of thousands.
TEST(MipmapSampler, DrawsReproduceTheMapChiSquare) {
    const int res = 32;
    const std::vector<float> w = knownMap(res);
    const MipmapSampler s(w, res);
    const size_t n = 200000;
    std::vector<double> count(w.size(), 0.0);
    for (uint32_t t : s.stratifiedSamples(n, 7)) count[t] += 1.0;
    double chi2 = 0.0;
    int bins = 0;
    for (size_t t = 0; t < w.size(); ++t) {
        const double expected = double(n) * s.probability(uint32_t(t));
        if (expected < 5.0) {
            if (w[t] == 0.0f) {
                EXPECT_EQ(count[t], 0.0);
            }
            continue;
        }
        chi2 += (count[t] - expected) * (count[t] - expected) / expected;
        ++bins;
    }
    EXPECT_GT(bins, 700);
    EXPECT_LT(chi2, 1145.0) << bins << " bins";

    // The same test catches a wrong distribution.
    std::vector<float> wrong = w;
    for (float& v : wrong) v = std::sqrt(v);
    const MipmapSampler bad(wrong, res);
    std::vector<double> badCount(w.size(), 0.0);
    for (uint32_t t : bad.stratifiedSamples(n, 7)) badCount[t] += 1.0;
    double badChi2 = 0.0;
    for (size_t t = 0; t < w.size(); ++t) {
        const double expected = double(n) * s.probability(uint32_t(t));
        if (expected >= 5.0) badChi2 += (badCount[t] - expected) * (badCount[t] - expected) / expected;
    }
    EXPECT_GT(badChi2, 10.0 * 1145.0);
}

TEST(MipmapSampler, DeterministicPerSeedAndStratified) {
    const int res = 64;
    const MipmapSampler s(knownMap(res), res);
    EXPECT_EQ(s.stratifiedSamples(1000, 3), s.stratifiedSamples(1000, 3));
    EXPECT_NE(s.stratifiedSamples(1000, 3), s.stratifiedSamples(1000, 4));
    // Stratified draws are ordered along the mipmap order: non-decreasing Morton code.
    auto morton = [&](uint32_t t) {
        uint32_t x = t % res, y = t / res, code = 0;
        for (int b = 0; b < 16; ++b) code |= ((x >> b) & 1u) << (2 * b) | ((y >> b) & 1u) << (2 * b + 1);
        return code;
    };
    const std::vector<uint32_t> d = s.stratifiedSamples(5000, 9);
    for (size_t i = 1; i < d.size(); ++i) EXPECT_LE(morton(d[i - 1]), morton(d[i]));
}

TEST(MipmapSampler, BadMapsAreErrors) {
    test::expectErrorSubject([] { MipmapSampler(std::vector<float>(12, 1.0f), 3); }, "importance map");
    test::expectErrorSubject([] { MipmapSampler(std::vector<float>(15, 1.0f), 4); }, "importance map");
    std::vector<float> w(16, 1.0f);
    w[5] = -1.0f;
    test::expectErrorSubject([&] { MipmapSampler(w, 4); }, "importance map");
    w[5] = std::nanf("");
    test::expectErrorSubject([&] { MipmapSampler(w, 4); }, "importance map");
}
