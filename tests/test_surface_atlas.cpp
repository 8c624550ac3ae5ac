// The area-preserving surface atlas (relight/pointlight/surface_atlas.h). Physics asserted: the
// texels' surface areas sum to the mesh area (the atlas covers the surface, Eq. 6's
// correction applied exactly), every triangle receives exactly its own area from the
// clipped texel pieces, texture area is proportional to surface area (distortion 1),
// charts do not overlap, every texel's point lies on its triangle, and the atlas is
// deterministic.

#include "relight/pointlight/surface_atlas.h"

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <cmath>

#include "common/shapes.h"
#include "tests/test_support.h"

using namespace prt;

namespace {

// A mesh of very unequal triangles: a box with uneven segments plus a torus.
TriangleMesh mixedMesh() {
    TriangleMesh mesh = makeBox({40.0f, 10.0f, 20.0f}, {2, 5, 9});
    const TriangleMesh torus = makeTorus(15.0f, 4.0f, 60, 20);
    const uint32_t base = uint32_t(mesh.positions.size());
    for (const glm::vec3& p : torus.positions) mesh.positions.push_back(p + glm::vec3(0, 30, 0));
    for (const glm::vec3& n : torus.normals) mesh.normals.push_back(n);
    for (const glm::uvec3& t : torus.triangles) mesh.triangles.push_back(t + glm::uvec3(base));
    return mesh;
}

}  // namespace

TEST(SurfaceAtlas, MappedAreaSumsToTheMeshArea) {
    for (int res : {64, 256, 1024}) {
        const TriangleMesh mesh = mixedMesh();
        const SurfaceAtlas atlas = buildSurfaceAtlas(mesh, res);
        const double meshArea = totalArea(mesh);
        EXPECT_NEAR(atlas.stats.mappedAreaMm2, meshArea, 1e-5 * meshArea) << res;
        EXPECT_NEAR(atlas.samples.totalArea(), meshArea, 1e-5 * meshArea) << res;
        EXPECT_EQ(atlas.samples.size(), atlas.stats.coveredTexels);
        // Shelf packing of bounding rectangles: a triangle fills half of its rectangle.
        EXPECT_GT(atlas.stats.coverage, 0.35) << res;
        EXPECT_LE(atlas.stats.coverage, 1.0) << res;
    }
}

TEST(SurfaceAtlas, EveryTriangleGetsItsOwnAreaAndDistortionIsOne) {
    const TriangleMesh mesh = mixedMesh();
    const SurfaceAtlas atlas = buildSurfaceAtlas(mesh, 32);  // many triangles smaller than a texel
    EXPECT_GT(atlas.stats.subTexelTriangles, 0u);
    const std::vector<double> areas = atlasTriangleAreas(mesh, atlas);
    for (size_t f = 0; f < mesh.triangleCount(); ++f)
        EXPECT_NEAR(areas[f], faceArea(mesh, f), 1e-4 * faceArea(mesh, f)) << f;
    EXPECT_NEAR(atlas.stats.minDistortion, 1.0, 1e-4);
    EXPECT_NEAR(atlas.stats.maxDistortion, 1.0, 1e-4);
    // Charts stay inside the unit square.
    for (const glm::vec2& uv : atlas.cornerUv) {
        EXPECT_GE(uv.x, 0.0f);
        EXPECT_GE(uv.y, 0.0f);
        EXPECT_LE(uv.x, 1.0f);
        EXPECT_LE(uv.y, 1.0f);
    }
}

// Charts must not overlap: then no texel holds more texture area than its own (1 texel^2).
TEST(SurfaceAtlas, ChartsDoNotOverlap) {
    const TriangleMesh mesh = mixedMesh();
    const SurfaceAtlas atlas = buildSurfaceAtlas(mesh, 512);
    const double s = atlas.stats.scale, r = atlas.resolution;
    const double mm2PerTexel = 1.0 / (s * s * r * r);
    double worst = 0.0;
    for (float a : atlas.texelArea) worst = std::max(worst, double(a) / mm2PerTexel);
    EXPECT_LE(worst, 1.0 + 1e-4);
}

TEST(SurfaceAtlas, TexelPointsLieOnTheirTriangles) {
    const TriangleMesh mesh = makeIcosphere(3, 10.0f);
    const SurfaceAtlas atlas = buildSurfaceAtlas(mesh, 256);
    const IrradianceSamples& s = atlas.samples;
    for (size_t i = 0; i < s.size(); i += 7) {
        const uint32_t f = s.triangles[i];
        const glm::uvec3 t = mesh.triangles[f];
        const glm::dvec3 a(mesh.positions[t.x]), b(mesh.positions[t.y]), c(mesh.positions[t.z]);
        const glm::dvec3 p(s.positions[i]);
        const glm::dvec3 n = glm::normalize(glm::cross(b - a, c - a));
        EXPECT_NEAR(glm::dot(p - a, n), 0.0, 1e-4);  // in the plane
        // inside: the three sub-triangle areas sum to the whole
        const double whole = glm::length(glm::cross(b - a, c - a));
        const double parts = glm::length(glm::cross(b - p, c - p)) + glm::length(glm::cross(c - p, a - p)) +
                             glm::length(glm::cross(a - p, b - p));
        EXPECT_NEAR(parts, whole, 1e-4 * whole);
        EXPECT_NEAR(glm::length(glm::dvec3(s.normals[i])), 1.0, 1e-5);
        EXPECT_GT(glm::dot(glm::dvec3(s.normals[i]), n), 0.0);
        EXPECT_EQ(atlas.texelSample[atlas.sampleTexel[i]], uint32_t(i));
    }
}

TEST(SurfaceAtlas, DeterministicOnAnyThreadCount) {
    const TriangleMesh mesh = mixedMesh();
    const SurfaceAtlas a = buildSurfaceAtlas(mesh, 256);
    SurfaceAtlas b;
    {
        tbb::global_control one(tbb::global_control::max_allowed_parallelism, 1);
        b = buildSurfaceAtlas(mesh, 256);
    }
    EXPECT_EQ(a.cornerUv, b.cornerUv);
    EXPECT_EQ(a.texelArea, b.texelArea);
    EXPECT_EQ(a.samples.positions, b.samples.positions);
}

TEST(SurfaceAtlas, BadInputsAreErrors) {
    const TriangleMesh mesh = makeIcosphere(1, 1.0f);
    for (int res : {0, 8, 100, 16384}) test::expectErrorSubject([&] { buildSurfaceAtlas(mesh, res); }, "atlas resolution");
    TriangleMesh flat;
    flat.positions = {{0, 0, 0}, {1, 0, 0}, {2, 0, 0}};
    flat.triangles = {{0, 1, 2}};
    test::expectErrorSubject([&] { buildSurfaceAtlas(flat, 64); }, "mesh");
    TriangleMesh nan = mesh;
    nan.positions[3].y = std::nanf("");
    test::expectErrorSubject([&] { buildSurfaceAtlas(nan, 64); }, "mesh");
}
