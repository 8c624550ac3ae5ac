// transport_blocking: a whole file's per-vertex components -> blocks of 16, as the
// writer and prt-merge both make them.
#include <gtest/gtest.h>

#include <random>
#include <set>

#include "common/blocked_vectors.h"
#include "common/transport_file.h"
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
    const TransportFile before = f;
    const std::vector<glm::vec3> p = positions(37);
    const double retained = blockTransportComponents(f, 12, p);
    std::vector<const SparseRgbVectors*> sources;
    for (const TransportComponent& c : before.components) sources.push_back(&c.vectors);
    const std::vector<BlockedRgbVectors> nested = jointTruncateNested(sources, 12, spatialBlockOrder(p), 24);
    std::vector<const BlockedRgbVectors*> kept;
    for (size_t k = 0; k < f.components.size(); ++k) {
        EXPECT_EQ(f.components[k].blocks, nested[k]);
        kept.push_back(&f.components[k].blocks);
    }
    EXPECT_DOUBLE_EQ(retained, retainedEnergyFraction(sources, kept));
    for (size_t b = 0; b < f.components[0].blocks.blockCount(); ++b) {
        std::set<uint32_t> together;
        for (const TransportComponent& c : f.components)
            together.insert(c.blocks.indices.begin() + c.blocks.offsets[b], c.blocks.indices.begin() + c.blocks.offsets[b + 1]);
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
