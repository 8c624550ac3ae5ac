// fold_single_scattering: isotropic single scattering added into the
// multiple-scattering vectors; relit, the sum of the two (exact before truncation).
#include <gtest/gtest.h>

#include <random>

#include "common/transport_file.h"
#include "precompute/job/fold_single_scattering.h"
#include "tests/test_support.h"

using namespace prt;
using prt::test::errorOf;

namespace {

constexpr uint32_t kSpace = 40;  // 32 "Haar" indices + 8 "SH" ones from kShFrom
constexpr uint32_t kShFrom = 32;

SparseRgbVectors randomComponent(size_t vertices, uint32_t seed) {
    return prt::test::randomSparseVectors(vertices, seed, kSpace, 2);
}

// dot(vertex v's vector, light) per channel, from the dequantized values.
std::array<double, 3> relight(const SparseRgbVectors& t, size_t v, const std::vector<double>& light) {
    std::vector<uint32_t> idx;
    std::vector<float> rgb;
    t.dequantizeVertex(v, idx, rgb);
    std::array<double, 3> out{};
    for (size_t k = 0; k < idx.size(); ++k)
        for (int c = 0; c < 3; ++c) out[size_t(c)] += double(rgb[3 * k + size_t(c)]) * light[3 * idx[k] + size_t(c)];
    return out;
}

}  // namespace

TEST(FoldSingleScattering, KeepingEveryTermTheFoldedVectorRelightsAsTheSum) {
    const SparseRgbVectors ms = randomComponent(20, 1), ss = randomComponent(20, 2);
    const SparseRgbVectors folded = foldVectors(ms, ss, kSpace, kShFrom);
    std::mt19937 rng(3);
    std::vector<double> light(3 * kSpace);
    for (double& x : light) x = double(rng() % 1000) / 1000.0 - 0.3;
    for (size_t v = 0; v < 20; ++v) {
        const auto a = relight(ms, v, light), b = relight(ss, v, light), f = relight(folded, v, light);
        for (int c = 0; c < 3; ++c) {
            // int16 quantization of the sum: half a step (max |v| / 65534, |v| <= 20) per term,
            // times |light| < 0.7, over at most kSpace terms.
            const double bound = double(kSpace) * 0.7 * 20.0 / 65534.0 * 1.01;
            EXPECT_NEAR(f[size_t(c)], a[size_t(c)] + b[size_t(c)], bound) << v << " " << c;
        }
    }
}

TEST(FoldSingleScattering, TruncationKeepsTheShPartThenTheLargestTerms) {
    const SparseRgbVectors ms = randomComponent(12, 4), ss = randomComponent(12, 5);
    const SparseRgbVectors all = foldVectors(ms, ss, kSpace, kShFrom);
    const size_t keep = 12;
    const SparseRgbVectors folded = foldVectors(ms, ss, keep, kShFrom);
    std::vector<uint32_t> ia, ik;
    std::vector<float> va, vk;
    for (size_t v = 0; v < 12; ++v) {
        all.dequantizeVertex(v, ia, va);
        folded.dequantizeVertex(v, ik, vk);
        ASSERT_EQ(ik.size(), std::min(keep, ia.size()));
        // Brute force: every SH index of the sum is kept; every dropped Haar term is no
        // larger than the smallest kept Haar term.
        double smallestKept = 1e300, largestDropped = 0.0;
        for (size_t k = 0; k < ia.size(); ++k) {
            const double n2 = double(va[3 * k]) * va[3 * k] + double(va[3 * k + 1]) * va[3 * k + 1] +
                              double(va[3 * k + 2]) * va[3 * k + 2];
            const bool kept = std::find(ik.begin(), ik.end(), ia[k]) != ik.end();
            if (ia[k] >= kShFrom) {
                EXPECT_TRUE(kept) << "vertex " << v << " SH index " << ia[k];
                continue;
            }
            if (kept) smallestKept = std::min(smallestKept, n2);
            else largestDropped = std::max(largestDropped, n2);
        }
        EXPECT_LE(largestDropped, smallestKept * (1.0 + 1e-3)) << v;
    }
}

TEST(FoldSingleScattering, ReplacesTheTwoComponentsByOne) {
    std::vector<TransportComponent> components(2);
    components[0].kind = ComponentKind::MultipleScattering;
    components[0].vectors = randomComponent(8, 6);
    components[1].kind = ComponentKind::SingleScatteringIsotropic;
    components[1].vectors = randomComponent(8, 7);
    const SparseRgbVectors expected = foldVectors(components[0].vectors, components[1].vectors, 10, kShFrom);
    foldSingleScattering(components, 10, kShFrom);
    ASSERT_EQ(components.size(), 1u);
    EXPECT_EQ(components[0].kind, ComponentKind::MultipleScattering);
    EXPECT_EQ(components[0].vectors, expected);
    // Nothing to fold into, or nothing to fold: refused by name.
    EXPECT_NE(errorOf([&] { foldSingleScattering(components, 10, kShFrom); }).find("single scattering"),
              std::string::npos);
    EXPECT_EQ(errorOf([&] { foldVectors(randomComponent(3, 1), randomComponent(4, 1), 10); }),
              "fold: the components have 3 and 4 vertices");
}
