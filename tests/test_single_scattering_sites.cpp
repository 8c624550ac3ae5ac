// Tests of precompute/passes/single_scattering_sites (the sites neighbouring vertices
// share) and of the single-scattering pass computed at sites.

#include "precompute/passes/single_scattering_sites.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include "common/error.h"
#include "common/haar.h"
#include "common/materials.h"
#include "common/raytrace.h"
#include "common/shapes.h"
#include "precompute/passes/single_scattering.h"

using namespace prt;

namespace {

// The invariants of a choice: weights positive summing to 1, every blended site within
// 2 h with its normal within 60 degrees, every vertex with a site within h (the one that
// kept it from being a site, or itself), and no two sites within h of one another with
// normals within 60 degrees.
void expectValidSites(const TriangleMesh& mesh, const SingleScatteringSites& s, double h) {
    const size_t n = mesh.positions.size();
    ASSERT_EQ(s.vertexCount(), n);
    const auto dist = [&](uint32_t a, uint32_t b) { return double(glm::length(mesh.positions[a] - mesh.positions[b])); };
    for (size_t k = 1; k < s.site.size(); ++k) ASSERT_LT(s.site[k - 1], s.site[k]);
    for (uint32_t v = 0; v < n; ++v) {
        double sum = 0.0;
        bool nearSite = false;
        for (uint32_t b = s.offset[v]; b < s.offset[v + 1]; ++b) {
            const uint32_t site = s.site[s.blendSite[b]];
            EXPECT_GT(s.blendWeight[b], 0.0f);
            sum += s.blendWeight[b];
            EXPECT_LE(dist(v, site), 2.0 * h * (1 + 1e-6));
            EXPECT_GT(glm::dot(mesh.normals[v], mesh.normals[site]), 0.5f);
            if (b > s.offset[v]) {
                EXPECT_LT(s.blendSite[b - 1], s.blendSite[b]);
            }
            nearSite = nearSite || dist(v, site) <= h * (1 + 1e-6);
        }
        EXPECT_NEAR(sum, 1.0, 1e-5) << "vertex " << v;
        EXPECT_TRUE(nearSite) << "vertex " << v;
    }
    for (size_t a = 0; a < s.site.size(); ++a)
        for (size_t b = a + 1; b < s.site.size(); ++b)
            if (glm::dot(mesh.normals[s.site[a]], mesh.normals[s.site[b]]) > 0.5f) {
                EXPECT_GT(dist(s.site[a], s.site[b]), h * (1 - 1e-6)) << "sites " << a << ", " << b;
            }
}

}  // namespace

TEST(SingleScatteringSites, SpacingZeroIsEveryVertexAlone) {
    const TriangleMesh sphere = makeIcosphere(2, 5.0f);
    const SingleScatteringSites s = chooseSingleScatteringSites(sphere.positions, sphere.normals, 0.0);
    ASSERT_EQ(s.site.size(), sphere.positions.size());
    for (uint32_t v = 0; v < sphere.positions.size(); ++v) {
        EXPECT_EQ(s.site[v], v);
        ASSERT_EQ(s.offset[v + 1] - s.offset[v], 1u);
        EXPECT_EQ(s.blendSite[s.offset[v]], v);
        EXPECT_EQ(s.blendWeight[s.offset[v]], 1.0f);
    }
}

TEST(SingleScatteringSites, CoverPackAndBlendOnASphere) {
    const TriangleMesh sphere = makeIcosphere(4, 5.0f);  // 2,562 vertices ~0.39 mm apart
    for (double h : {0.3, 0.8, 2.0}) {
        SCOPED_TRACE(h);
        const SingleScatteringSites s = chooseSingleScatteringSites(sphere.positions, sphere.normals, h);
        expectValidSites(sphere, s, h);
        // Disks of radius h / 2 around the sites do not overlap: at most the area over
        // the disk's area; fewer sites than vertices once h is past the vertex spacing.
        const double area = 4.0 * M_PI * 25.0;
        EXPECT_LE(double(s.site.size()), area / (M_PI * h * h / 4.0) * 1.2);
        if (h > 0.5) {
            EXPECT_LT(s.site.size(), sphere.positions.size() / 2);
        }
        EXPECT_EQ(s.sitesOf(0, sphere.positions.size()).size(), s.site.size());
        // The same inputs, the same choice (shards rely on it).
        const SingleScatteringSites again = chooseSingleScatteringSites(sphere.positions, sphere.normals, h);
        EXPECT_EQ(again.site, s.site);
        EXPECT_EQ(again.blendSite, s.blendSite);
        EXPECT_EQ(again.blendWeight, s.blendWeight);
    }
}

TEST(SingleScatteringSites, TheTwoSidesOfAThinSheetKeepTheirOwnSites) {
    // A box 0.1 mm thick: its top and bottom faces are 0.1 mm apart, far inside the
    // spacing, with opposite normals; each blends only sites of its own side.
    const TriangleMesh sheet = makeBox({10.0f, 0.1f, 10.0f}, {20, 1, 20});
    const double h = 1.0;
    const SingleScatteringSites s = chooseSingleScatteringSites(sheet.positions, sheet.normals, h);
    expectValidSites(sheet, s, h);
    bool top = false, bottom = false;
    for (uint32_t k : s.site) {
        top = top || sheet.normals[k].y > 0.5f;
        bottom = bottom || sheet.normals[k].y < -0.5f;
    }
    EXPECT_TRUE(top && bottom);
}

TEST(SingleScatteringSites, AVertexWithoutANormalIsItsOwnSite) {
    std::vector<glm::vec3> positions = {{0, 0, 0}, {0.1f, 0, 0}, {0.2f, 0, 0}};
    std::vector<glm::vec3> normals = {{0, 1, 0}, {0, 0, 0}, {0, 1, 0}};
    const SingleScatteringSites s = chooseSingleScatteringSites(positions, normals, 1.0);
    EXPECT_EQ(s.site, (std::vector<uint32_t>{0, 1}));
    ASSERT_EQ(s.offset[2] - s.offset[1], 1u);
    EXPECT_EQ(s.site[s.blendSite[s.offset[1]]], 1u);
    EXPECT_EQ(s.blendWeight[s.offset[1]], 1.0f);
    ASSERT_EQ(s.offset[3] - s.offset[2], 1u);
    EXPECT_EQ(s.site[s.blendSite[s.offset[2]]], 0u);  // vertex 2 blends vertex 0, not the normal-less 1
}

TEST(SingleScatteringSites, RefusesABadSpacing) {
    const std::vector<glm::vec3> p = {{0, 0, 0}}, n = {{0, 1, 0}};
    EXPECT_THROW(chooseSingleScatteringSites(p, n, -1.0), Error);
    EXPECT_THROW(chooseSingleScatteringSites(p, n, std::numeric_limits<double>::quiet_NaN()), Error);
    EXPECT_THROW(chooseSingleScatteringSites(p, n, std::numeric_limits<double>::infinity()), Error);
    const std::vector<glm::vec3> two = {{0, 1, 0}, {0, 1, 0}};
    EXPECT_THROW(chooseSingleScatteringSites(p, two, 1.0), Error);
}

// The reuse's bias is a blur over about one spacing: none where the transport does not
// change from vertex to vertex. On the top of a thick slab (20 mm of Marble, ~50 mean
// free paths) the transport of vertices far from the edges is the same at every vertex,
// so the blend of sites 5 mm apart equals each vertex's own, with far fewer points
// computed.
TEST(SingleScatteringSites, BlendEqualsEveryVertexWhereTheTransportIsTheSame) {
    const TriangleMesh slab = makeSlab(60.0f, 60.0f, 20.0f, 24);  // top vertices 2.5 mm apart
    const RayScene scene(slab);
    const int n = 8;
    SingleScatteringOptions o;
    o.cubemapSize = n;
    o.vertexCoefficients = size_t(6) * n * n;  // keep every coefficient: no truncation
    std::vector<std::vector<SparseVector>> every, shared;
    const SingleScatteringContext all(scene, slab, materialByName("Marble"), nullptr, o);
    const SingleScatteringResult r0 = computeSingleScattering(all, every);
    o.siteSpacing = 5.0;
    const SingleScatteringContext sites(scene, slab, materialByName("Marble"), nullptr, o);
    const SingleScatteringResult r1 = computeSingleScattering(sites, shared);
    EXPECT_EQ(r0.stats.sites, slab.positions.size());
    EXPECT_LT(r1.stats.sites * 4, slab.positions.size());
    EXPECT_LT(r1.stats.exitRays * 4, r0.stats.exitRays);
    const size_t texels = size_t(6) * n * n;
    size_t checked = 0;
    for (size_t v = 0; v < slab.positions.size(); ++v) {
        const glm::vec3 p = slab.positions[v];
        // Top vertices whose sites (within 10 mm) are 10 mm or more from every edge
        // (e^-22 of their light comes through the sides).
        if (slab.normals[v].y < 0.99f || std::abs(p.x) > 10.0f || std::abs(p.z) > 10.0f) continue;
        std::vector<float> a(texels * 3, 0.0f), b(texels * 3, 0.0f);
        for (size_t e = 0; e < every[0][v].index.size(); ++e)
            for (int c = 0; c < 3; ++c) a[every[0][v].index[e] * 3 + c] = every[0][v].value[e * 3 + c];
        for (size_t e = 0; e < shared[0][v].index.size(); ++e)
            for (int c = 0; c < 3; ++c) b[shared[0][v].index[e] * 3 + c] = shared[0][v].value[e * 3 + c];
        double d2 = 0.0, r2 = 0.0;
        for (size_t i = 0; i < a.size(); ++i) {
            d2 += double(a[i] - b[i]) * double(a[i] - b[i]);
            r2 += double(a[i]) * double(a[i]);
        }
        ASSERT_GT(r2, 0.0);
        // Float rounding of the rays' origins and of the blend: ~1e-6.
        EXPECT_LT(std::sqrt(d2 / r2), 1e-4) << "vertex " << v;
        ++checked;
    }
    EXPECT_GE(checked, 64u);
}

// A vertex's vector is its blend of the sites' own vectors (the Haar transform is
// linear, so blending coefficients is blending transport), whichever range of vertices
// a call computes; checked on a torus, whose transport differs from vertex to vertex.
TEST(SingleScatteringSites, EveryVertexGetsTheBlendOfItsSitesInAnyRange) {
    const TriangleMesh torus = makeTorus(6.0f, 2.0f, 48, 24);
    const RayScene scene(torus);
    const int n = 8;
    const size_t texels = size_t(6) * n * n;
    SingleScatteringOptions o;
    o.cubemapSize = n;
    o.vertexCoefficients = texels;
    std::vector<std::vector<SparseVector>> every, shared;
    computeSingleScattering(SingleScatteringContext(scene, torus, materialByName("Skin1"), nullptr, o), every);
    o.siteSpacing = 1.0;
    const SingleScatteringContext ctx(scene, torus, materialByName("Skin1"), nullptr, o);
    computeSingleScattering(ctx, shared);
    const SingleScatteringSites s = chooseSingleScatteringSites(torus.positions, torus.normals, 1.0);
    ASSERT_LT(s.site.size(), torus.positions.size() / 2);
    const auto dense = [&](const SparseVector& sv, float w, std::vector<double>& out) {
        for (size_t e = 0; e < sv.index.size(); ++e)
            for (int c = 0; c < 3; ++c) out[sv.index[e] * 3 + c] += double(w) * sv.value[e * 3 + c];
    };
    double worst = 0.0;
    for (uint32_t v = 0; v < torus.positions.size(); ++v) {
        std::vector<double> blend(texels * 3, 0.0), got(texels * 3, 0.0);
        for (uint32_t b = s.offset[v]; b < s.offset[v + 1]; ++b)
            dense(every[0][s.site[s.blendSite[b]]], s.blendWeight[b], blend);
        dense(shared[0][v], 1.0f, got);
        double d2 = 0.0, r2 = 0.0;
        for (size_t i = 0; i < got.size(); ++i) d2 += (got[i] - blend[i]) * (got[i] - blend[i]), r2 += blend[i] * blend[i];
        ASSERT_GT(r2, 0.0);
        worst = std::max(worst, std::sqrt(d2 / r2));
    }
    EXPECT_LT(worst, 1e-5);  // float sums of a few sites

    // Ranges (interleaved blocks, as MPI ranks take them): the same vectors, bit for
    // bit, in the ranges' order, and each site computed once however many ranges blend it.
    const VertexRanges ranges = {{600, 700}, {500, 600}, {100, 120}};
    std::vector<size_t> order;
    const SingleScatteringResult r = computeSingleScattering(
        ctx,
        [&](size_t v, const std::vector<SparseVector>& terms) {
            EXPECT_EQ(terms[0].index, shared[0][v].index) << v;
            EXPECT_EQ(terms[0].value, shared[0][v].value) << v;
            order.push_back(v);
        },
        nullptr, ranges);
    std::vector<size_t> expected;
    for (const auto& [first, end] : ranges)
        for (size_t v = first; v < end; ++v) expected.push_back(v);
    EXPECT_EQ(order, expected);
    std::vector<uint32_t> needed;
    for (const auto& [first, end] : ranges) {
        const std::vector<uint32_t> of = s.sitesOf(first, end);
        needed.insert(needed.end(), of.begin(), of.end());
    }
    std::sort(needed.begin(), needed.end());
    const size_t withRepeats = needed.size();
    needed.erase(std::unique(needed.begin(), needed.end()), needed.end());
    ASSERT_GT(withRepeats, needed.size());  // neighbouring ranges blend some sites alike
    EXPECT_EQ(r.stats.sites, needed.size());
    EXPECT_THROW(computeSingleScattering(ctx, [](size_t, const std::vector<SparseVector>&) {}, nullptr,
                                         VertexRanges{{0, torus.positions.size() + 1}}),
                 Error);
}

// The two stages MPI ranks run when they share the sites: each of three parts computes
// an interleaved share of every site (computeSiteTransport), the shares are put
// together, and each part blends its own vertices (blendSiteTransport). The vectors
// equal one call's bit for bit, each site is computed once, and a blend missing one of
// its sites is an error.
TEST(SingleScatteringSites, SitesComputedInSharesAndBlendedEqualOneCall) {
    const TriangleMesh torus = makeTorus(6.0f, 2.0f, 48, 24);
    const RayScene scene(torus);
    SingleScatteringOptions o;
    o.cubemapSize = 8;
    o.vertexCoefficients = 64;
    o.siteSpacing = 1.0;
    const SingleScatteringContext ctx(scene, torus, materialByName("Skin1"), nullptr, o);
    std::vector<std::vector<SparseVector>> whole;
    const SingleScatteringResult one = computeSingleScattering(ctx, whole);

    const SingleScatteringSites s = chooseSingleScatteringSites(torus.positions, torus.normals, o.siteSpacing);
    const size_t count = s.site.size(), block = 7;
    std::vector<std::vector<SparseVector>> vectors(count);
    std::vector<uint32_t> held(count);
    SingleScatteringStats stats;
    for (int part = 0; part < 3; ++part) {
        std::vector<uint32_t> numbers;
        for (size_t b = size_t(part); b * block < count; b += 3)
            for (size_t i = b * block; i < std::min(count, (b + 1) * block); ++i) numbers.push_back(uint32_t(i));
        std::vector<std::vector<SparseVector>> mine = computeSiteTransport(ctx, s, numbers, stats);
        ASSERT_EQ(mine.size(), numbers.size());
        for (size_t i = 0; i < numbers.size(); ++i) vectors[numbers[i]] = std::move(mine[i]);
    }
    for (size_t i = 0; i < count; ++i) held[i] = uint32_t(i);
    EXPECT_EQ(stats.sites, count);
    EXPECT_EQ(stats.sites, one.stats.sites);
    EXPECT_EQ(stats.exitRays, one.stats.exitRays);

    const size_t n = torus.positions.size();
    const VertexRanges mine = {{n / 2, n}, {0, n / 5}};
    size_t seen = 0;
    blendSiteTransport(
        ctx, s, held, vectors,
        [&](size_t v, const std::vector<SparseVector>& terms) {
            ASSERT_EQ(terms.size(), 1u);
            EXPECT_EQ(terms[0].index, whole[0][v].index) << v;
            EXPECT_EQ(terms[0].value, whole[0][v].value) << v;
            ++seen;
        },
        nullptr, mine);
    EXPECT_EQ(seen, n - n / 2 + n / 5);

    // Without the site vertex 0 blends first.
    const uint32_t missing = s.blendSite[s.offset[0]];
    std::vector<uint32_t> fewer;
    std::vector<std::vector<SparseVector>> fewerVectors;
    for (size_t i = 0; i < count; ++i)
        if (i != missing) fewer.push_back(uint32_t(i)), fewerVectors.push_back(vectors[i]);
    EXPECT_THROW(blendSiteTransport(ctx, s, fewer, fewerVectors, [](size_t, const std::vector<SparseVector>&) {},
                                    nullptr, VertexRanges{{0, 1}}),
                 Error);
    EXPECT_THROW(blendSiteTransport(ctx, s, held, fewerVectors, [](size_t, const std::vector<SparseVector>&) {},
                                    nullptr, VertexRanges{{0, 1}}),
                 Error);
}

// A held site's vectors of another shape (phase terms, channels, cubemap) are refused.
TEST(SingleScatteringSites, BlendRefusesSiteVectorsOfAnotherShape) {
    const TriangleMesh torus = makeTorus(6.0f, 2.0f, 24, 12);
    const RayScene scene(torus);
    SingleScatteringOptions o;
    o.cubemapSize = 4;
    o.vertexCoefficients = 32;
    o.siteSpacing = 1.0;
    const SingleScatteringContext ctx(scene, torus, materialByName("Skin1"), nullptr, o);
    const SingleScatteringSites s = chooseSingleScatteringSites(torus.positions, torus.normals, o.siteSpacing);
    std::vector<uint32_t> held(s.site.size());
    for (size_t i = 0; i < held.size(); ++i) held[i] = uint32_t(i);
    SingleScatteringStats stats;
    const std::vector<std::vector<SparseVector>> good = computeSiteTransport(ctx, s, held, stats);
    const auto blend = [&](const std::vector<std::vector<SparseVector>>& v) {
        blendSiteTransport(ctx, s, held, v, [](size_t, const std::vector<SparseVector>&) {}, nullptr,
                           VertexRanges{{0, torus.positions.size()}});
    };
    EXPECT_NO_THROW(blend(good));
    std::vector<std::vector<SparseVector>> bad = good;
    bad[0].push_back(bad[0][0]);  // two phase terms for an isotropic context
    EXPECT_THROW(blend(bad), Error);
    bad = good;
    bad[1][0].channels = 1;
    EXPECT_THROW(blend(bad), Error);
    bad = good;
    bad[2][0].index.push_back(uint32_t(ctx.texelCount()));  // past the cubemap
    bad[2][0].value.insert(bad[2][0].value.end(), {1.0f, 1.0f, 1.0f});
    EXPECT_THROW(blend(bad), Error);
}
