// transport_blocking: a whole file's per-vertex components -> blocks of 16, as the
// writer and prt-merge both make them.
#include <gtest/gtest.h>

#include <random>
#include <set>

#include "common/blocked_vectors.h"
#include "common/transport_file.h"
#include "common/transport_file_format.h"
#include "precompute/job/transport_blocking.h"
#include "tests/test_support.h"

using namespace prt;
using prt::test::errorOf;

namespace {

// 37 vertices (two full blocks and a partial one), cubemap 2 (24 texels) + 4 SH terms.
TransportFile smallFile(bool profiles) {
    TransportFile f;
    f.cubemapSize = 2;
    f.shTerms = 4;
    f.mesh.vertexCount = 37;
    for (uint32_t k = 0; k < (profiles ? 3u : 2u); ++k) {
        TransportComponent c;
        c.kind = profiles ? ComponentKind::MultipleScatteringProfiles
                          : (k == 0 ? ComponentKind::MultipleScattering : ComponentKind::SingleScatteringIsotropic);
        c.term = profiles ? k : 0;
        c.vectors = prt::test::randomSparseVectors(37, 11 + k, 28, 3);
        f.components.push_back(std::move(c));
    }
    return f;
}

std::vector<glm::vec3> positions(size_t n) {
    std::vector<glm::vec3> p;
    for (size_t i = 0; i < n; ++i) p.push_back({float(i % 7), float((i * 5) % 11), float(i % 3)});
    return p;
}

}  // namespace

TEST(TransportBlocking, EachComponentIsItsJointTruncationInTheSpatialOrder) {
    TransportFile f = smallFile(false);
    const TransportFile before = f;
    const std::vector<glm::vec3> p = positions(37);
    const double retained = blockTransportComponents(f, 10, p);
    const std::vector<uint32_t> order = spatialBlockOrder(p);
    double expected = 0.0;
    for (size_t c = 0; c < f.components.size(); ++c) {
        ASSERT_TRUE(f.components[c].blocked());
        EXPECT_EQ(f.components[c].vectors.vertexCount(), 0u);
        const BlockedRgbVectors b = jointTruncate(before.components[c].vectors, 10, order, 24);
        EXPECT_EQ(f.components[c].blocks, b);
        EXPECT_EQ(f.components[c].blocks.shFrom, 24u);  // the SH part has scales of its own
        expected += retainedEnergyFraction(before.components[c].vectors, b);
    }
    EXPECT_DOUBLE_EQ(retained, expected / 2.0);
    EXPECT_LT(retained, 1.0);  // 10 of up to 28 indices: something was dropped
}

// The profiles keep nested lists (jointTruncateNested) and count as one component in
// the retained energy, beside the multiple scattering; the union of their lists is at
// most the 12 indices asked.
TEST(TransportBlocking, RadialProfilesKeepNestedListsPerBlock) {
    TransportFile f = smallFile(true);
    // The first profile component ten times weaker, so it keeps fewer indices; and a
    // multiple-scattering component beside the profiles, blocked on its own.
    for (int16_t& q : f.components[0].vectors.values) q = int16_t(q / 10);
    TransportComponent ms = smallFile(false).components[0];
    f.components.push_back(ms);
    const TransportFile before = f;
    const std::vector<glm::vec3> p = positions(37);
    const double retained = blockTransportComponents(f, 12, p);
    std::vector<const SparseRgbVectors*> sources;
    for (size_t k = 0; k < 3; ++k) sources.push_back(&before.components[k].vectors);
    const std::vector<uint32_t> order = spatialBlockOrder(p);
    const std::vector<BlockedRgbVectors> nested = jointTruncateNested(sources, 12, order, 24);
    std::vector<const BlockedRgbVectors*> kept;
    for (size_t k = 0; k < 3; ++k) {
        EXPECT_EQ(f.components[k].blocks, nested[k]);
        kept.push_back(&f.components[k].blocks);
    }
    EXPECT_TRUE(transport_format::blockedProfileListsDiffer(f));
    EXPECT_LT(f.components[0].blocks.indices.size(), f.components[1].blocks.indices.size());
    const BlockedRgbVectors msBlocks = jointTruncate(before.components[3].vectors, 12, order, 24);
    EXPECT_EQ(f.components[3].blocks, msBlocks);
    // The profiles count as one component beside the multiple scattering.
    EXPECT_DOUBLE_EQ(retained, (retainedEnergyFraction(sources, kept) +
                                retainedEnergyFraction(before.components[3].vectors, msBlocks)) / 2.0);
    for (size_t b = 0; b < f.components[0].blocks.blockCount(); ++b) {
        std::set<uint32_t> together;
        for (size_t k = 0; k < 3; ++k) {
            const BlockedRgbVectors& x = f.components[k].blocks;
            together.insert(x.indices.begin() + x.offsets[b], x.indices.begin() + x.offsets[b + 1]);
        }
        EXPECT_LE(together.size(), 12u);
    }
}

TEST(TransportBlocking, RefusesWhatItCannotBlock) {
    TransportFile f = smallFile(false);
    EXPECT_EQ(errorOf([&] { blockTransportComponents(f, 10, positions(36)); }),
              "blocks: the mesh has 36 vertices, the file 37");
    EXPECT_EQ(errorOf([&] { blockTransportComponents(f, 0, positions(37)); }),
              "--block-coefficients: must be at least 1");
    blockTransportComponents(f, 10, positions(37));
    EXPECT_NE(errorOf([&] { blockTransportComponents(f, 10, positions(37)); }).find("already blocked"),
              std::string::npos);
}
