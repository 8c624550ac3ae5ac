// The point lights' surface terms with rays at the vertices (vertex_surface_terms.h),
// what the viewer draws: equal to the per-pixel terms (point_specular.h,
// point_single_scattering.h) wherever the interpolation is exact, and converging to them
// as the mesh is refined where it is not (shadow edges, the 1 / r^2 falloff, the view
// direction and the light's path changing across a triangle).

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "common/bssrdf.h"
#include "common/error.h"
#include "common/image_compare.h"
#include "common/materials.h"
#include "common/shapes.h"
#include "relight/pointlight/point_single_scattering.h"
#include "relight/pointlight/point_specular.h"
#include "relight/pointlight/vertex_surface_terms.h"
#include "relight/render/gbuffer.h"
#include "test_support.h"

using namespace prt;
using namespace prt::test;

namespace {

Camera cameraAt(const glm::dvec3& eye, int size = 96) {
    Camera c;
    c.eye = eye;
    c.target = glm::dvec3(0.0);
    c.fovY = 30.0;
    c.width = c.height = size;
    return c;
}

const Material kMarbleLike = customMaterial({2.19, 2.62, 3.00}, {0.0021, 0.0041, 0.0071}, 1.3, 0.3);

}  // namespace

// A directional light on a sphere: E is the same everywhere and every vertex facing the
// light sees it, so at pixels whose three vertices are lit the interpolation is exact
// and the per-vertex specular is the per-pixel one (float rounding of the stored
// irradiance apart).
TEST(VertexSurfaceTerms, SpecularIsThePerPixelOneWhereEveryVertexIsLit) {
    const TriangleMesh sphere = makeIcosphere(3, 10.0f);
    const RayScene scene(sphere);
    const std::vector<Light> lights = {parseLight("dir:0.3,1,0.6:100,150,200")};
    const std::vector<glm::vec3> s = vertexLightIrradiance(scene, sphere, lights);
    ASSERT_EQ(s.size(), sphere.vertexCount());
    const GBuffer g = traceGBuffer(scene, sphere, cameraAt({10, 20, 60}));
    const double eta = 1.3, alpha = 0.3;
    size_t compared = 0;
    double worst = 0.0;
    for (const GBufferPixel& px : g.pixels) {
        if (!px.hit) continue;
        const glm::uvec3 t = sphere.triangles[px.triangle];
        if (s[t.x].x == 0.0f || s[t.y].x == 0.0f || s[t.z].x == 0.0f) continue;
        const glm::dvec3 want = pointSpecular(scene, lights, surfacePointOf(sphere, px), glm::dvec3(px.toViewer), eta, alpha);
        const glm::dvec3 got = vertexSpecular(sphere, lights, s, px, eta, alpha);
        if (want.x <= 0.0) {
            EXPECT_EQ(got, glm::dvec3(0.0));
            continue;
        }
        ++compared;
        for (int c = 0; c < 3; ++c) worst = std::max(worst, std::abs(got[c] / want[c] - 1.0));
    }
    EXPECT_GT(compared, 1000u);
    EXPECT_LT(worst, 1e-5);
    // A vertex facing away from the light is shadowed by its own sphere.
    for (size_t v = 0; v < sphere.vertexCount(); ++v)
        if (glm::dot(glm::dvec3(sphere.normals[v]), lights[0].direction) < -0.05) {
            EXPECT_EQ(s[v], glm::vec3(0.0f));
        }
}

// At a vertex the term is pointSingleScattering there (its outgoing Fresnel factor
// apart), seen from the eye.
TEST(VertexSurfaceTerms, SingleScatteringAtAVertexIsThePerPixelTerm) {
    const TriangleMesh sphere = makeIcosphere(2, 10.0f);
    const RayScene scene(sphere);
    const std::vector<Light> lights = {parseLight("point:30,40,-10:0.05"), parseLight("dir:-1,0.2,0.5:50")};
    const glm::dvec3 eye(5, 10, 60);
    const std::vector<glm::vec3> t = vertexSingleScattering(scene, sphere, lights, kMarbleLike, eye);
    ASSERT_EQ(t.size(), sphere.vertexCount());
    size_t lit = 0;
    for (size_t v = 0; v < sphere.vertexCount(); ++v) {
        const glm::dvec3 x(sphere.positions[v]), n(sphere.normals[v]);
        const glm::dvec3 wo = glm::normalize(eye - x);
        const double cosO = glm::dot(n, wo);
        const glm::dvec3 want = pointSingleScattering(scene, sphere, lights, kMarbleLike,
                                                      {sphere.positions[v], sphere.normals[v], sphere.normals[v]}, wo);
        if (!(cosO > 0.0)) {
            EXPECT_EQ(t[v], glm::vec3(0.0f));
            continue;
        }
        const double ft = fresnelTransmittance(kMarbleLike.eta, cosO);
        for (int c = 0; c < 3; ++c) EXPECT_NEAR(ft * t[v][c], want[c], 1e-6 * std::max(want[c], 1e-12));
        lit += want.x > 0.0;
    }
    EXPECT_GT(lit, 20u);
}

// Where the interpolation is not exact (a point light's 1 / r^2 and shadow edges on a
// torus that shadows itself; the view direction and the light's paths across a
// triangle for single scattering), the per-vertex image converges to the per-pixel one
// as the mesh is refined: each refinement must reduce the relative RMSE, and the finest
// must be within a few per cent.
TEST(VertexSurfaceTerms, ConvergesToThePerPixelTermsAsTheMeshIsRefined) {
    const std::vector<Light> lights = {parseLight("point:25,30,-5:0.02"), parseLight("spot:-20,25,20:0.6,-0.6,-0.5:0.02:15,30")};
    const Camera camera = cameraAt({0, 45, 70}, 128);
    double previousSpecular = 1e30, previousSingle = 1e30;
    for (const int n : {16, 32, 64}) {
        const TriangleMesh torus = makeTorus(12.0f, 5.0f, 2 * n, n);
        const RayScene scene(torus);
        const GBuffer g = traceGBuffer(scene, torus, camera);
        const Image specularPixel = specularImage(g, torus, scene, lights, 1.3, 0.3);
        const Image specularVertex =
            vertexSpecularImage(g, torus, lights, vertexLightIrradiance(scene, torus, lights), 1.3, 0.3);
        const Image singlePixel = singleScatteringImage(g, torus, scene, lights, kMarbleLike);
        const Image singleVertex = vertexSingleScatteringImage(
            g, torus, vertexSingleScattering(scene, torus, lights, kMarbleLike, camera.eye), kMarbleLike.eta);
        const double es = compareImages(specularVertex, specularPixel).overall.relativeRmse;
        const double e1 = compareImages(singleVertex, singlePixel).overall.relativeRmse;
        std::printf("torus %d x %d: per-vertex vs per-pixel relative RMSE: specular %.4f, single scattering %.4f\n",
                    2 * n, n, es, e1);
        RecordProperty("specular_rel_rmse_" + std::to_string(n), std::to_string(es));
        RecordProperty("single_scattering_rel_rmse_" + std::to_string(n), std::to_string(e1));
        EXPECT_LT(es, previousSpecular);
        EXPECT_LT(e1, previousSingle);
        previousSpecular = es;
        previousSingle = e1;
    }
    EXPECT_LT(previousSpecular, 0.05);
    EXPECT_LT(previousSingle, 0.05);
}

TEST(VertexSurfaceTerms, RefusesMismatchedInputs) {
    TriangleMesh sphere = makeIcosphere(1, 10.0f);
    const RayScene scene(sphere);
    const std::vector<Light> lights = {parseLight("point:0,30,0:1")};
    const GBuffer g = traceGBuffer(scene, sphere, cameraAt({0, 0, 60}, 16));
    expectErrorSubject([&] { vertexSpecularImage(g, sphere, lights, std::vector<glm::vec3>(3), 1.3, 0.3); },
                       "per-vertex specular");
    expectErrorSubject([&] { vertexSingleScatteringImage(g, sphere, std::vector<glm::vec3>(3), 1.3); },
                       "per-vertex single scattering");
    expectErrorSubject(
        [&] { vertexSpecularImage(g, sphere, lights, vertexLightIrradiance(scene, sphere, lights), 1.3, 0.0); },
        "--specular-roughness");
    sphere.normals.clear();
    expectErrorSubject([&] { vertexLightIrradiance(scene, sphere, lights); }, "per-vertex surface terms");
    expectErrorSubject([&] { vertexSingleScattering(scene, sphere, lights, kMarbleLike, {0, 0, 60}); },
                       "per-vertex surface terms");
}
