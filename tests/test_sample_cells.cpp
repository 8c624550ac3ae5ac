// The near field of the point-light renderers on the cell quadrature
// (relight/pointlight/sample_cells.h): the cells of face samples are the faces; a flat
// uniformly lit box far coarser than the kernel reaches the closed form with the cells
// where the point rule misses it; the renderers with cells keep their invariants
// (hierarchy against the brute-force order, the cache's S equal to Jensen-Buhler's,
// setMaterial equal to a new renderer).
#include "relight/pointlight/sample_cells.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <vector>

#include "common/bssrdf.h"
#include "common/error.h"
#include "common/sampling.h"
#include "common/shapes.h"
#include "relight/pointlight/irradiance_cache.h"
#include "relight/pointlight/jensen_buhler.h"

using namespace prt;

namespace {

IrradianceSamples litFaces(const TriangleMesh& mesh, const std::vector<Light>& lights, const Material& m) {
    const RayScene scene(mesh);
    IrradianceSamples s = faceCentroidSamples(mesh);
    computeIrradiance(s, scene, lights, m.eta, FresnelModel::Exact);
    return s;
}

}  // namespace

TEST(SampleCells, FaceCellsAreTheFaces) {
    const TriangleMesh torus = makeTorus(10.0f, 3.0f, 24, 12);
    const Material m = customMaterial({1.0, 1.5, 2.0}, {0.01, 0.02, 0.03});
    const IrradianceSamples s = faceCentroidSamples(torus);
    const SampleCells cells(torus, s, m);
    EXPECT_TRUE(cells.faceCells());
    ASSERT_EQ(cells.sampleCount(), s.size());
    for (uint32_t i = 0; i < s.size(); ++i) EXPECT_NEAR(cells.cellArea(i), s.areas[i], 1e-5 * s.areas[i]) << i;
    // Every sub-point of a face's cell lies on that face: within the face's own reach.
    for (uint32_t i = 0; i < s.size(); i += 37) {
        const glm::uvec3 t = torus.triangles[s.triangles[i]];
        const float reach = std::max({glm::length(torus.positions[t.x] - s.positions[i]),
                                      glm::length(torus.positions[t.y] - s.positions[i]),
                                      glm::length(torus.positions[t.z] - s.positions[i])});
        for (const glm::vec3& p : cells.quadrature().cellSubPoints(i))
            EXPECT_LE(glm::length(p - s.positions[i]), reach * 1.0001f) << i;
    }
    // Poisson-disk samples own the surface nearest them: areas near A / N, summing to the mesh.
    const IrradianceSamples poisson = samplesFromSampleSet(poissonDiskSamples(torus, 400, 7));
    const SampleCells nearest(torus, poisson, m);
    EXPECT_FALSE(nearest.faceCells());
    double sum = 0.0;
    for (uint32_t i = 0; i < poisson.size(); ++i) sum += nearest.cellArea(i);
    EXPECT_NEAR(sum, totalArea(torus), 1e-4 * totalArea(torus));
}

// A 40 x 40 mm slab under a vertical sun: E^ is the same at every face, so away from
// the edges M = F_t E R_total (the plane integral of R_d, bssrdf.h) whatever the faces.
// With faces of 2.5 mm and a kernel about 0.3 mm wide the point rule sees R_d only at
// the centroids and misses the peak around x by far; the cells integrate it.
TEST(SampleCells, CoarseFlatFacesReachTheClosedFormWithCells) {
    const Material m = customMaterial({3.0, 3.5, 4.0}, {0.02, 0.05, 0.1});
    const TriangleMesh box = makeBox({40.0f, 10.0f, 40.0f}, {16, 1, 16});
    const double ePerp = 1000.0;
    const std::vector<Light> sun = {directionalLight({0, 1, 0}, glm::dvec3(ePerp))};
    const IrradianceSamples s = litFaces(box, sun, m);
    const double ft = fresnelTransmittance(m.eta, 1.0);
    const SampleCells cells(box, s, m);
    const JensenBuhler withCells(m, IrradianceOctree(s), {.epsilon = 0.0}, cells);
    const JensenBuhler points(m, IrradianceOctree(s), {.epsilon = 0.0});
    // Points at a vertex, a centroid-ish place, mid-edge and an arbitrary place.
    const std::vector<glm::dvec3> xs = {glm::dvec3(0, 5, 0), glm::dvec3(0.8, 5, 0.8), glm::dvec3(1.25, 5, 0),
                                        glm::dvec3(-3.3, 5, 4.9)};
    double worstCells = 0.0, worstPoints = 0.0;
    for (const glm::dvec3& x : xs) {
        const glm::dvec3 c = withCells.exitance(x), p = points.exitance(x);
        for (int ch = 0; ch < 3; ++ch) {
            const double closed = ft * ePerp * dipoleTotalDiffuseReflectance(makeDipoleChannel(m, ch));
            worstCells = std::max(worstCells, std::abs(c[ch] - closed) / closed);
            worstPoints = std::max(worstPoints, std::abs(p[ch] - closed) / closed);
        }
    }
    std::printf("faces 2.5 mm, kernel ~0.3 mm: worst relative error cells %.2e, point rule %.2e\n", worstCells,
                worstPoints);
    EXPECT_LT(worstCells, 5e-3);
    EXPECT_GT(worstPoints, 0.2);  // the point rule's failure this test guards against
    // Auto picks the cells here (spacing 2 mm, narrowest kernel width 0.19 mm), the point
    // rule for samples closer than that width.
    EXPECT_TRUE(nearFieldNeedsCells(totalArea(box), s.size(), m));
    EXPECT_FALSE(nearFieldNeedsCells(totalArea(box), 200000, m));
}

TEST(SampleCells, HierarchyAndCacheAgreeWithTheBruteOrder) {
    const TriangleMesh torus = makeTorus(10.0f, 3.0f, 48, 24);
    const Material m = customMaterial({1.2, 1.6, 2.2}, {0.01, 0.03, 0.05});
    const std::vector<Light> lights = {pointLight({5, 30, 10}, glm::dvec3(0.02))};
    const IrradianceSamples s = litFaces(torus, lights, m);
    const SampleCells cells(torus, s, m);
    const JensenBuhler brute(m, IrradianceOctree(s), {.epsilon = 0.0}, cells);
    const JensenBuhler jb(m, IrradianceOctree(s), {.epsilon = 0.05}, cells);
    const IrradianceCache cache(m, IrradianceOctree(s), {.epsilon = 0.05}, cells);
    for (uint32_t i = 0; i < s.size(); i += 97) {
        const glm::dvec3 x(s.positions[i]);
        const glm::dvec3 b = brute.exitance(x), h = jb.exitance(x);
        glm::dvec3 sc, grad[3], v;
        cache.evaluate(x, sc, grad, v);
        for (int c = 0; c < 3; ++c) {
            EXPECT_NEAR(h[c], b[c], 5e-3 * b[c] + 1e-9) << i;
            EXPECT_EQ(sc[c], h[c]) << i;  // the cache's S is Jensen-Buhler's, bit for bit
        }
    }
}

TEST(SampleCells, SetMaterialEqualsNewCells) {
    const TriangleMesh torus = makeTorus(10.0f, 3.0f, 32, 16);
    const Material a = customMaterial({1.2, 1.6, 2.2}, {0.01, 0.03, 0.05});
    const Material b = customMaterial({3.0, 2.0, 0.6}, {0.2, 0.02, 0.01});
    const std::vector<Light> lights = {pointLight({5, 30, 10}, glm::dvec3(0.02))};
    const IrradianceSamples s = litFaces(torus, lights, a);
    JensenBuhler edited(a, IrradianceOctree(s), {}, SampleCells(torus, s, a));
    edited.setMaterial(b);
    const JensenBuhler fresh(b, IrradianceOctree(s), {}, SampleCells(torus, s, b));
    // Cells built for another material are set to the renderer's.
    const JensenBuhler adopted(b, IrradianceOctree(s), {}, SampleCells(torus, s, a));
    for (uint32_t i = 0; i < s.size(); i += 53) {
        const glm::dvec3 x(s.positions[i]);
        EXPECT_EQ(edited.exitance(x), fresh.exitance(x)) << i;
        EXPECT_EQ(adopted.exitance(x), fresh.exitance(x)) << i;
    }
}

TEST(SampleCells, BadInputsAreErrors) {
    const TriangleMesh torus = makeTorus(10.0f, 3.0f, 16, 8);
    const Material m = customMaterial({1.0, 1.0, 1.0}, {0.01, 0.01, 0.01});
    IrradianceSamples s = faceCentroidSamples(torus);
    EXPECT_THROW(SampleCells(torus, IrradianceSamples{}, m), Error);
    IrradianceSamples twice = s;
    twice.triangles[1] = twice.triangles[0];
    EXPECT_THROW(SampleCells(torus, twice, m), Error);
    IrradianceSamples outside = s;
    outside.triangles[0] = uint32_t(torus.triangles.size());
    EXPECT_THROW(SampleCells(torus, outside, m), Error);
    // Cells over other samples than the tree's.
    const RayScene scene(torus);
    computeIrradiance(s, scene, {pointLight({0, 20, 0}, glm::dvec3(1.0))}, m.eta, FresnelModel::Exact);
    IrradianceSamples fewer = s;
    fewer.positions.pop_back();
    fewer.normals.pop_back();
    fewer.geometricNormals.pop_back();
    fewer.areas.pop_back();
    fewer.triangles.pop_back();
    fewer.irradiance.pop_back();
    EXPECT_THROW(JensenBuhler(m, IrradianceOctree(fewer), {}, SampleCells(torus, s, m)), Error);
    EXPECT_EQ(parseNearFieldRule("Cells"), NearFieldRule::Cells);
    EXPECT_EQ(parseNearFieldRule("points"), NearFieldRule::Points);
    EXPECT_EQ(parseNearFieldRule("AUTO"), NearFieldRule::Auto);
    EXPECT_THROW(parseNearFieldRule("exact"), Error);
}
