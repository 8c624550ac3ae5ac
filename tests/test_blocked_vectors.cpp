// Blocked transport vectors (common/blocked_vectors.h): quantization bound, the joint
// truncation against a brute-force choice, the spatial order, round trips and the
// validity check.

#include <gtest/gtest.h>

#include <glm/common.hpp>

#include <algorithm>
#include <cmath>
#include <map>
#include <numeric>
#include <random>
#include <set>
#include <vector>

#include "common/blocked_vectors.h"
#include "common/error.h"
#include "common/transport_file.h"

namespace prt {
namespace {

// Random per-vertex vectors: `terms` distinct indices below `count` per vertex,
// neighbouring vertices drawing from overlapping index ranges (like real transport).
SparseRgbVectors randomVectors(size_t vertices, size_t terms, uint32_t count, uint32_t seed) {
    std::mt19937 rng(seed);
    std::normal_distribution<float> value(0.0f, 1.0f);
    SparseRgbVectors out;
    for (size_t v = 0; v < vertices; ++v) {
        std::set<uint32_t> chosen;
        std::uniform_int_distribution<uint32_t> pick(0, count - 1);
        while (chosen.size() < terms) chosen.insert(pick(rng));
        std::vector<uint32_t> idx(chosen.begin(), chosen.end());
        std::vector<float> rgb;
        for (size_t n = 0; n < idx.size(); ++n)
            for (int c = 0; c < 3; ++c) rgb.push_back(value(rng) / float(1 + idx[n] % 17));
        out.appendVertex(idx, rgb);
    }
    return out;
}

std::vector<uint32_t> identityOrder(size_t n) {
    std::vector<uint32_t> o(n);
    std::iota(o.begin(), o.end(), 0u);
    return o;
}

// The brute-force joint choice of one block of 16 vertices (0..15) over `sources`: each
// index scores the sum over vertices of its energy share, summed over the sources, of
// the vertex's energy over all of them; the `keep` highest, sorted.
std::vector<uint32_t> bruteForceChoice(const std::vector<const SparseRgbVectors*>& sources, size_t keep) {
    std::map<uint32_t, double> score;
    std::vector<uint32_t> idx;
    std::vector<float> rgb;
    for (size_t v = 0; v < 16; ++v) {
        double e = 0;
        for (const SparseRgbVectors* src : sources) {
            src->dequantizeVertex(v, idx, rgb);
            for (float x : rgb) e += double(x) * x;
        }
        for (const SparseRgbVectors* src : sources) {
            src->dequantizeVertex(v, idx, rgb);
            for (size_t n = 0; n < idx.size(); ++n) {
                double s = 0;
                for (int c = 0; c < 3; ++c) s += double(rgb[3 * n + c]) * rgb[3 * n + c];
                score[idx[n]] += s / e;
            }
        }
    }
    std::vector<std::pair<double, uint32_t>> ranked;
    for (auto [i, s] : score) ranked.push_back({-s, i});
    std::sort(ranked.begin(), ranked.end());
    std::vector<uint32_t> expected;
    for (size_t k = 0; k < keep; ++k) expected.push_back(ranked[k].second);
    std::sort(expected.begin(), expected.end());
    return expected;
}

TEST(BlockedVectors, KeepingTheUnionIsLosslessUpToTheInt8Bound) {
    const SparseRgbVectors src = randomVectors(37, 20, 384, 1);  // last block partial (5 lanes)
    std::vector<uint32_t> order = identityOrder(37);
    std::shuffle(order.begin(), order.end(), std::mt19937(2));
    const BlockedRgbVectors b = jointTruncate(src, 100000, order);
    EXPECT_EQ(b.vertexCount(), 37u);
    EXPECT_EQ(b.blockCount(), 3u);
    EXPECT_EQ(checkBlockedVectors(b, 384), "");
    std::vector<uint32_t> si, bi;
    std::vector<float> sv, bv;
    for (size_t v = 0; v < 37; ++v) {
        src.dequantizeVertex(v, si, sv);
        b.dequantizeVertex(v, bi, bv);
        float maxAbs[3] = {};
        for (size_t n = 0; n < si.size(); ++n)
            for (int c = 0; c < 3; ++c) maxAbs[c] = std::max(maxAbs[c], std::fabs(sv[3 * n + c]));
        std::map<uint32_t, size_t> at;
        for (size_t n = 0; n < bi.size(); ++n) at[bi[n]] = n;
        for (size_t n = 0; n < si.size(); ++n) {
            ASSERT_TRUE(at.count(si[n])) << "vertex " << v << " lost index " << si[n];
            for (int c = 0; c < 3; ++c)
                EXPECT_LE(std::fabs(bv[3 * at[si[n]] + c] - sv[3 * n + c]),
                          kBlockQuantizationMaxRelativeError * maxAbs[c] * 1.0001f);
        }
        // Indices outside the vertex's own support are exact zeros.
        std::set<uint32_t> own(si.begin(), si.end());
        for (size_t n = 0; n < bi.size(); ++n) {
            if (own.count(bi[n])) continue;
            for (int c = 0; c < 3; ++c) EXPECT_EQ(bv[3 * n + c], 0.0f);
        }
    }
    EXPECT_NEAR(retainedEnergyFraction(src, b), 1.0, 1e-3);
}

// Vectors shaped like real transport with an SH part: Haar values of order 1 below
// `count`, and 9 SH entries from `count` up whose band-0 term is `shGain` times larger
// (on the bunny the SH band 0 is 10-190x, median 27x, the largest Haar value).
SparseRgbVectors vectorsWithShPart(size_t vertices, uint32_t count, float shGain, uint32_t seed) {
    const SparseRgbVectors haar = randomVectors(vertices, 20, count, seed);
    std::mt19937 rng(seed + 1);
    std::uniform_real_distribution<float> unit(-1.0f, 1.0f);
    SparseRgbVectors out;
    std::vector<uint32_t> idx;
    std::vector<float> rgb;
    for (size_t v = 0; v < vertices; ++v) {
        haar.dequantizeVertex(v, idx, rgb);
        for (uint32_t i = 0; i < 9; ++i) {
            idx.push_back(count + i);
            for (int c = 0; c < 3; ++c) rgb.push_back(i == 0 ? shGain * (1.0f + 0.5f * unit(rng)) : unit(rng));
        }
        out.appendVertex(idx, rgb);
    }
    return out;
}

// Largest per-vertex, per-channel error of `b` against `src` over the indices in
// [begin, end), relative to the vertex's channel maximum over those indices.
double worstRelativeError(const SparseRgbVectors& src, const BlockedRgbVectors& b, uint32_t begin, uint32_t end) {
    double worst = 0.0;
    std::vector<uint32_t> si, bi;
    std::vector<float> sv, bv;
    for (size_t v = 0; v < src.vertexCount(); ++v) {
        src.dequantizeVertex(v, si, sv);
        b.dequantizeVertex(v, bi, bv);
        std::map<uint32_t, size_t> at;
        for (size_t n = 0; n < bi.size(); ++n) at[bi[n]] = n;
        for (int c = 0; c < 3; ++c) {
            double maxAbs = 0.0, err = 0.0;
            for (size_t n = 0; n < si.size(); ++n) {
                if (si[n] < begin || si[n] >= end) continue;
                maxAbs = std::max(maxAbs, double(std::fabs(sv[3 * n + c])));
                err = std::max(err, std::fabs(double(bv[3 * at.at(si[n]) + c]) - sv[3 * n + c]));
            }
            if (maxAbs > 0.0) worst = std::max(worst, err / maxAbs);
        }
    }
    return worst;
}

TEST(BlockedVectors, ShPartHasScalesOfItsOwn) {
    const uint32_t count = 384;  // 6 N^2 for N = 8
    const SparseRgbVectors src = vectorsWithShPart(37, count, 30.0f, 7);
    const BlockedRgbVectors two = jointTruncate(src, 100000, identityOrder(37), count);
    EXPECT_EQ(two.shFrom, count);
    EXPECT_EQ(two.shScales.size(), two.scales.size());
    EXPECT_EQ(checkBlockedVectors(two, count + 9), "");
    for (size_t k = 0; k < two.blockCount(); ++k) EXPECT_EQ(two.offsets[k + 1] - two.shBegin(k), 9u);
    // Each part within half a step of its own maximum.
    EXPECT_LE(worstRelativeError(src, two, 0, count), kBlockQuantizationMaxRelativeError * 1.0001);
    EXPECT_LE(worstRelativeError(src, two, count, count + 9), kBlockQuantizationMaxRelativeError * 1.0001);
    // One scale for both (format version 3): the Haar values get steps set by the SH
    // band 0, ~30x coarser. This is the error the second scale removes.
    const BlockedRgbVectors one = jointTruncate(src, 100000, identityOrder(37));
    EXPECT_EQ(one.shFrom, UINT32_MAX);
    EXPECT_TRUE(one.shScales.empty());
    EXPECT_GT(worstRelativeError(src, one, 0, count), 10.0 * kBlockQuantizationMaxRelativeError);
    EXPECT_LE(worstRelativeError(src, one, count, count + 9), kBlockQuantizationMaxRelativeError * 1.0001);
    // Vectors without an SH part get no SH scales, whatever forcedFrom says.
    const BlockedRgbVectors none = jointTruncate(randomVectors(20, 8, count, 8), 24, identityOrder(20), count);
    EXPECT_EQ(none.shFrom, UINT32_MAX);
    EXPECT_TRUE(none.shScales.empty());
    EXPECT_EQ(checkBlockedVectors(none, count), "");
    // The check: SH scales iff shFrom, finite, zero in padding lanes, shFrom in range.
    BlockedRgbVectors b = two;
    b.shScales.pop_back();
    EXPECT_NE(checkBlockedVectors(b, count + 9), "");
    b = two;
    b.shScales.back() = 1.0f;  // a padding lane (37 vertices: lanes 5..15 of block 2)
    EXPECT_NE(checkBlockedVectors(b, count + 9), "");
    b = two;
    b.shScales[0] = std::nanf("");
    EXPECT_NE(checkBlockedVectors(b, count + 9), "");
    b = two;
    b.shFrom = UINT32_MAX;  // scales left over
    EXPECT_NE(checkBlockedVectors(b, count + 9), "");
    b = two;
    b.shFrom = count + 9;
    EXPECT_NE(checkBlockedVectors(b, count + 9), "");
    // shFrom must be set before the first block.
    BlockedRgbVectors late;
    late.appendBlock({1}, std::vector<float>(48, 1.0f), identityOrder(16));  // a whole block
    late.shFrom = 2;
    EXPECT_THROW(late.appendBlock({1, 2}, std::vector<float>(6, 1.0f), {16}), Error);
    late.shFrom = UINT32_MAX;
    EXPECT_NO_THROW(late.appendBlock({1, 2}, std::vector<float>(6, 1.0f), {16}));
}

TEST(BlockedVectors, IndexVarintsRoundTripAndRefuseBadStreams) {
    // Real-sized blocks: 160 of 6 x 32^2 + 9 indices, an empty block, a one-index block
    // at 65535 (3 bytes), gaps of exactly 127 and 128 (1 and 2 bytes).
    const SparseRgbVectors src = vectorsWithShPart(50, 6 * 32 * 32, 30.0f, 9);
    BlockedRgbVectors b = jointTruncate(src, 160, identityOrder(50), 6 * 32 * 32);
    std::vector<uint8_t> stream = encodeBlockIndices(b);
    std::vector<uint16_t> back;
    EXPECT_EQ(decodeBlockIndices(stream.data(), stream.size(), b.offsets, back), "");
    EXPECT_EQ(back, b.indices);
    EXPECT_LT(stream.size(), 2 * b.indices.size());
    const std::vector<uint32_t> offsets = {0, 0, 1, 4};
    const std::vector<uint16_t> edge = {65535, 0, 128, 257};
    {
        BlockedRgbVectors w;  // only offsets and indices matter to the coder: 3 blocks
        w.offsets = offsets;
        w.indices = edge;
        stream = encodeBlockIndices(w);
    }
    EXPECT_EQ(stream, (std::vector<uint8_t>{0xFF, 0xFF, 0x03, 0x00, 0x7F, 0x80, 0x01}));
    EXPECT_EQ(decodeBlockIndices(stream.data(), stream.size(), offsets, back), "");
    EXPECT_EQ(back, edge);
    const auto reason = [&](std::vector<uint8_t> s) {
        return decodeBlockIndices(s.data(), s.size(), offsets, back);
    };
    EXPECT_NE(reason({0xFF, 0xFF, 0x03, 0x00, 0x7F, 0x80}).find("ends inside block 2"), std::string::npos);
    EXPECT_NE(reason({0xFF, 0xFF, 0x03, 0x00, 0x7F, 0x80, 0x01, 0x00}).find("1 bytes after its last index"),
              std::string::npos);
    EXPECT_NE(reason({0xFF, 0xFF, 0x04, 0x00, 0x7F, 0x80, 0x01}).find("exceeds 16 bits"), std::string::npos);
    EXPECT_NE(reason({0xFF, 0xFF, 0x03, 0x80, 0x00, 0x7F, 0x80, 0x01}).find("overlong varint at byte 4"),
              std::string::npos);
    // Offsets that do not rise from 0 are refused before any index is written.
    EXPECT_NE(decodeBlockIndices(stream.data(), stream.size(), {0, 3, 1, 4}, back).find("do not rise from 0"),
              std::string::npos);
    EXPECT_NE(decodeBlockIndices(stream.data(), stream.size(), {1, 4}, back).find("do not rise from 0"),
              std::string::npos);
    // 65535 then +1: above 16 bits by the deltas.
    const std::vector<uint32_t> two = {0, 2};
    std::vector<uint8_t> s = {0xFF, 0xFF, 0x03, 0x00};
    EXPECT_NE(decodeBlockIndices(s.data(), s.size(), two, back).find("decodes index 65536"), std::string::npos);
}

// The blocks of a large set are chosen a batch of blocks at a time (jointTruncateShared
// keeps the float values of one batch): each block, at the start, on either side of a
// batch boundary and at the end, is the block the same 16 vertices make on their own.
TEST(BlockedVectors, EveryBlockOfALargeSetIsTheBlockOfItsVerticesAlone) {
    const size_t vertices = 4096 * 16 * 2 + 37;  // over two batches, the last block partial
    const SparseRgbVectors src = randomVectors(vertices, 6, 64, 21);
    const size_t keep = 10;
    const BlockedRgbVectors all = jointTruncate(src, keep, identityOrder(vertices));
    ASSERT_EQ(all.blockCount(), vertices / 16 + 1);
    std::vector<uint32_t> idx;
    std::vector<float> rgb;
    for (size_t b : {size_t(0), size_t(4095), size_t(4096), size_t(8191), size_t(8192), all.blockCount() - 1}) {
        SCOPED_TRACE(b);
        SparseRgbVectors alone;
        const size_t first = 16 * b, lanes = std::min<size_t>(16, vertices - first);
        for (size_t v = first; v < first + lanes; ++v) {
            src.dequantizeVertex(v, idx, rgb);
            alone.appendVertex(idx, rgb);
        }
        const BlockedRgbVectors one = jointTruncate(alone, keep, identityOrder(lanes));
        ASSERT_EQ(one.blockCount(), 1u);
        const uint32_t begin = all.offsets[b], end = all.offsets[b + 1];
        EXPECT_EQ(std::vector<uint32_t>(all.indices.begin() + begin, all.indices.begin() + end),
                  std::vector<uint32_t>(one.indices.begin(), one.indices.end()));
        EXPECT_EQ(std::vector<int8_t>(all.values.begin() + ptrdiff_t(begin) * kBlockValuesPerIndex,
                                      all.values.begin() + ptrdiff_t(end) * kBlockValuesPerIndex),
                  one.values);
        for (size_t k = 0; k < kBlockValuesPerIndex; ++k)
            EXPECT_NEAR(all.scales[b * kBlockValuesPerIndex + k], one.scales[k], 1e-6f * one.scales[k]);
    }
}

TEST(BlockedVectors, JointChoiceMatchesBruteForceScores) {
    const SparseRgbVectors src = randomVectors(16, 12, 64, 3);
    const size_t keep = 10;
    const BlockedRgbVectors b = jointTruncate(src, keep, identityOrder(16));
    // Brute force: energy-normalised score per index over the 16 vertices.
    const std::vector<uint32_t> expected = bruteForceChoice({&src}, keep);
    EXPECT_EQ(std::vector<uint32_t>(b.indices.begin(), b.indices.end()), expected);
}

// Several components sharing blocks (an editable file's radial profiles): one index
// list per block for all, chosen by the scores summed over the components with each
// lane's energy summed over them too (brute force), each component keeping its own
// values; one component alone is jointTruncate.
TEST(BlockedVectors, SharedChoiceSumsTheComponentsScores) {
    const SparseRgbVectors a = randomVectors(16, 12, 64, 5), b = randomVectors(16, 12, 64, 6);
    const size_t keep = 10;
    const std::vector<BlockedRgbVectors> shared = jointTruncateShared({&a, &b}, keep, identityOrder(16));
    ASSERT_EQ(shared.size(), 2u);
    EXPECT_EQ(shared[0].order, shared[1].order);
    EXPECT_EQ(shared[0].offsets, shared[1].offsets);
    EXPECT_EQ(shared[0].indices, shared[1].indices);
    EXPECT_NE(shared[0].values, shared[1].values);
    const std::vector<uint32_t> expected = bruteForceChoice({&a, &b}, keep);
    EXPECT_EQ(std::vector<uint32_t>(shared[0].indices.begin(), shared[0].indices.end()), expected);
    // Each component's values are its own at the shared indices (within int8 steps).
    for (size_t k = 0; k < 2; ++k) {
        const SparseRgbVectors& src = k == 0 ? a : b;
        std::vector<uint32_t> bi, si;
        std::vector<float> brgb, srgb;
        for (size_t v = 0; v < 16; ++v) {
            shared[k].dequantizeVertex(v, bi, brgb);
            src.dequantizeVertex(v, si, srgb);
            float maxAbs = 0.0f;
            for (float x : srgb) maxAbs = std::max(maxAbs, std::fabs(x));
            for (size_t n = 0; n < bi.size(); ++n) {
                const auto at = std::find(si.begin(), si.end(), bi[n]);
                for (int c = 0; c < 3; ++c) {
                    const float want = at == si.end() ? 0.0f : srgb[3 * size_t(at - si.begin()) + size_t(c)];
                    EXPECT_NEAR(brgb[3 * n + size_t(c)], want, maxAbs * kBlockQuantizationMaxRelativeError * 1.01f);
                }
            }
        }
    }
    EXPECT_EQ(jointTruncateShared({&a}, keep, identityOrder(16)).front(), jointTruncate(a, keep, identityOrder(16)));
    const SparseRgbVectors small = randomVectors(15, 12, 64, 7);
    EXPECT_THROW(jointTruncateShared({&a, &small}, keep, identityOrder(16)), Error);
    EXPECT_THROW(jointTruncateShared({}, keep, identityOrder(16)), Error);
}

// Nested lists (jointTruncateNested), against a brute force of the rule: per component
// the energy-normalised score (lane energy over all components), the union the `keep`
// indices of highest largest-component score, each component the union's indices whose
// own score reaches the lowest of those. A component ten times weaker keeps fewer.
TEST(BlockedVectors, NestedChoiceKeepsEveryPairAboveOneThreshold) {
    SparseRgbVectors strong = randomVectors(16, 12, 64, 8), weak;
    const SparseRgbVectors raw = randomVectors(16, 12, 64, 9);
    std::vector<uint32_t> idx;
    std::vector<float> rgb;
    for (size_t v = 0; v < 16; ++v) {
        raw.dequantizeVertex(v, idx, rgb);
        for (float& x : rgb) x *= 0.3f;
        weak.appendVertex(idx, rgb);
    }
    const std::vector<const SparseRgbVectors*> sources = {&weak, &strong};
    const size_t keep = 20;
    const std::vector<BlockedRgbVectors> nested = jointTruncateNested(sources, keep, identityOrder(16));
    ASSERT_EQ(nested.size(), 2u);
    EXPECT_EQ(nested[0].order, nested[1].order);
    // Brute force.
    std::vector<double> energy(16, 0.0);
    std::vector<std::map<uint32_t, double>> score(2);
    for (size_t v = 0; v < 16; ++v)
        for (const SparseRgbVectors* src : sources) {
            src->dequantizeVertex(v, idx, rgb);
            for (float x : rgb) energy[v] += double(x) * x;
        }
    for (size_t k = 0; k < 2; ++k)
        for (size_t v = 0; v < 16; ++v) {
            sources[k]->dequantizeVertex(v, idx, rgb);
            for (size_t n = 0; n < idx.size(); ++n) {
                double e = 0;
                for (int c = 0; c < 3; ++c) e += double(rgb[3 * n + c]) * rgb[3 * n + c];
                score[k][idx[n]] += e / energy[v];
            }
        }
    std::map<uint32_t, double> largest;
    for (const auto& s : score)
        for (auto [i, x] : s) largest[i] = std::max(largest[i], x);
    std::vector<std::pair<double, uint32_t>> ranked;
    for (auto [i, x] : largest) ranked.push_back({-x, i});
    std::sort(ranked.begin(), ranked.end());
    const double threshold = -ranked[keep - 1].first;
    std::vector<uint32_t> unionKept;
    for (size_t n = 0; n < keep; ++n) unionKept.push_back(ranked[n].second);
    std::sort(unionKept.begin(), unionKept.end());
    std::vector<uint32_t> together;
    for (size_t k = 0; k < 2; ++k) {
        std::vector<uint32_t> expected;
        for (uint32_t i : unionKept)
            if (score[k].count(i) && score[k][i] >= threshold) expected.push_back(i);
        const std::vector<uint32_t> got(nested[k].indices.begin(), nested[k].indices.end());
        EXPECT_EQ(got, expected) << "component " << k;
        together.insert(together.end(), got.begin(), got.end());
    }
    std::sort(together.begin(), together.end());
    together.erase(std::unique(together.begin(), together.end()), together.end());
    EXPECT_EQ(together, unionKept);
    EXPECT_LT(nested[0].indices.size(), nested[1].indices.size());
    EXPECT_GT(nested[0].indices.size(), 0u);
    // One component alone: nested and shared lists are the same choice.
    EXPECT_EQ(jointTruncateNested({&strong}, keep, identityOrder(16)).front(),
              jointTruncate(strong, keep, identityOrder(16)));
    // Keeping every index that scores: the union is all of them, and the weak component
    // still drops its pairs below the least union score.
    const std::vector<BlockedRgbVectors> whole = jointTruncateNested(sources, 64, identityOrder(16));
    std::set<uint32_t> wholeUnion(whole[0].indices.begin(), whole[0].indices.end());
    wholeUnion.insert(whole[1].indices.begin(), whole[1].indices.end());
    EXPECT_EQ(wholeUnion.size(), largest.size());
    EXPECT_LT(whole[0].indices.size(), jointTruncate(weak, 64, identityOrder(16)).indices.size());
    // Forced indices (an SH part from 60 on): every component keeps each one it has,
    // whatever the threshold, with scales of their own.
    const std::vector<BlockedRgbVectors> forced = jointTruncateNested(sources, keep, identityOrder(16), 60);
    for (size_t k = 0; k < 2; ++k) {
        std::set<uint32_t> support, kept;
        for (size_t v = 0; v < 16; ++v) {
            sources[k]->dequantizeVertex(v, idx, rgb);
            for (uint32_t i : idx)
                if (i >= 60) support.insert(i);
        }
        for (uint16_t i : forced[k].indices)
            if (i >= 60) kept.insert(i);
        ASSERT_FALSE(support.empty());
        EXPECT_EQ(kept, support) << k;
        EXPECT_EQ(forced[k].shFrom, 60u);
    }
    EXPECT_THROW(jointTruncateNested({}, keep, identityOrder(16)), Error);
}

TEST(BlockedVectors, JointTruncationKeepsAtLeastTheEnergyOfTheBestShare) {
    // The joint choice maximises the summed retained fraction over the block, so it keeps
    // at least what every vertex keeping its own top keep/16 would (a feasible choice).
    const SparseRgbVectors src = randomVectors(64, 40, 512, 4);
    const size_t keep = 96;
    const BlockedRgbVectors b = jointTruncate(src, keep, identityOrder(64));
    std::vector<uint32_t> idx;
    std::vector<float> rgb;
    double share = 0;
    for (size_t v = 0; v < 64; ++v) {
        src.dequantizeVertex(v, idx, rgb);
        std::vector<double> e(idx.size());
        double total = 0;
        for (size_t n = 0; n < idx.size(); ++n) {
            for (int c = 0; c < 3; ++c) e[n] += double(rgb[3 * n + c]) * rgb[3 * n + c];
            total += e[n];
        }
        std::sort(e.rbegin(), e.rend());
        share += std::accumulate(e.begin(), e.begin() + keep / 16, 0.0) / total;
    }
    share /= 64;
    // Tolerance: int8 quantization of the kept values changes their energy by < 1%.
    EXPECT_GE(retainedEnergyFraction(src, b), share * 0.99);
    EXPECT_LT(retainedEnergyFraction(src, b), 1.0);
}

TEST(BlockedVectors, SpatialOrderIsAPermutationOfCompactBlocks) {
    // A 40 x 25 grid of points: every full block's bounding box is far smaller than the
    // grid, and the order is a permutation with only the last block partial.
    std::vector<glm::vec3> p;
    for (int j = 0; j < 25; ++j)
        for (int i = 0; i < 40; ++i) p.push_back(glm::vec3(float(i), float(j), 0.0f));
    const std::vector<uint32_t> order = spatialBlockOrder(p);
    ASSERT_EQ(order.size(), p.size());
    std::vector<uint32_t> sorted = order;
    std::sort(sorted.begin(), sorted.end());
    EXPECT_EQ(sorted, identityOrder(p.size()));
    for (size_t b = 0; b + kVertexBlock <= order.size(); b += kVertexBlock) {
        glm::vec3 lo(1e9f), hi(-1e9f);
        for (size_t k = b; k < b + kVertexBlock; ++k) {
            lo = glm::min(lo, p[order[k]]);
            hi = glm::max(hi, p[order[k]]);
        }
        // 16 grid points: at best 4 x 4 (extent 3 + 3); median splits give at most 8 x 2.
        EXPECT_LE((hi.x - lo.x) + (hi.y - lo.y), 10.0f) << "block at " << b;
    }
    EXPECT_EQ(spatialBlockOrder(p), order);  // deterministic
    EXPECT_TRUE(spatialBlockOrder({}).empty());
}

TEST(BlockedVectors, ChecksRefuseInconsistentArrays) {
    const SparseRgbVectors src = randomVectors(20, 8, 96, 5);
    const BlockedRgbVectors good = jointTruncate(src, 24, identityOrder(20));
    ASSERT_EQ(checkBlockedVectors(good, 96), "");
    EXPECT_NE(checkBlockedVectors(good, 10), "");  // an index >= 6 N^2
    BlockedRgbVectors b = good;
    b.order[3] = b.order[4];
    EXPECT_NE(checkBlockedVectors(b, 96), "");
    b = good;
    b.values.pop_back();
    EXPECT_NE(checkBlockedVectors(b, 96), "");
    b = good;
    b.scales.back() = 1.0f;  // a padding lane (20 vertices: lanes 4..15 of block 1)
    EXPECT_NE(checkBlockedVectors(b, 96), "");
    b = good;
    b.values[b.offsets[1] * kBlockValuesPerIndex + 15] = 1;  // a padding lane's value
    EXPECT_NE(checkBlockedVectors(b, 96), "");
    b = good;
    b.offsets[1] = b.offsets[2] + 1;  // decreasing offsets, refused before any index read
    EXPECT_NE(checkBlockedVectors(b, 96), "");
    b = good;
    std::swap(b.indices[0], b.indices[1]);
    EXPECT_NE(checkBlockedVectors(b, 96), "");
    // Bad inputs to the builders.
    EXPECT_THROW(jointTruncate(src, 0, identityOrder(20)), Error);
    EXPECT_THROW(jointTruncate(src, 8, identityOrder(19)), Error);
    std::vector<uint32_t> dup = identityOrder(20);
    dup[0] = 1;
    EXPECT_THROW(jointTruncate(src, 8, dup), Error);
    BlockedRgbVectors a;
    EXPECT_THROW(a.appendBlock({2, 1}, std::vector<float>(6, 0.0f), {0}), Error);
    EXPECT_THROW(a.appendBlock({1}, {std::nanf(""), 0.0f, 0.0f}, {0}), Error);
    a.appendBlock({1}, {1.0f, 0.0f, 0.0f}, {0});  // a partial block ...
    EXPECT_THROW(a.appendBlock({1}, {1.0f, 0.0f, 0.0f}, {1}), Error);  // ... must be the last
}

TEST(BlockedVectors, ComponentDispatchesOnTheEncoding) {
    const SparseRgbVectors src = randomVectors(18, 6, 96, 6);
    TransportComponent perVertex;
    perVertex.vectors = src;
    TransportComponent blocked;
    blocked.blocks = jointTruncate(src, 1000, identityOrder(18));
    EXPECT_FALSE(perVertex.blocked());
    EXPECT_TRUE(blocked.blocked());
    EXPECT_EQ(blocked.vertexCount(), 18u);
    std::vector<uint32_t> idx;
    std::vector<float> rgb;
    blocked.dequantizeVertex(17, idx, rgb);
    EXPECT_GE(idx.size(), 6u);
    EXPECT_THROW(blocked.dequantizeVertex(18, idx, rgb), std::out_of_range);
}

}  // namespace
}  // namespace prt
