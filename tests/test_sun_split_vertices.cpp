// The sun split at the vertices (relight/combined/sun_split_vertices.h), the viewer's:
// the correction turns the transport's radiance under the whole environment into the
// residual's plus the lights', and the frame shaded from it is the offline split frame
// up to the per-vertex interpolation of the lights; refusals.

#include "relight/combined/sun_split_vertices.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <string>

#include "common/envmap.h"
#include "common/error.h"
#include "common/image_compare.h"
#include "common/materials.h"
#include "common/mesh_io.h"
#include "common/shapes.h"
#include "relight/combined/sun_split_frame.h"
#include "relight/prt/translucent_shader.h"
#include "relight/render/gbuffer.h"
#include "tests/sun_split_support.h"

using namespace prt;

namespace {

VertexRadiance relit(const RelightObject& object, const Image& env, const glm::dmat3& rotation) {
    VertexRadiance r;
    relightVertices(object.transport, EnvironmentLight(env, int(object.transport.cubemapSize)).lightVector(rotation),
                    {true, false}, r);
    return r;
}

}  // namespace

// transport(environment) + correction = transport(residual) + lights at every vertex:
// the relight is linear in the light, so the excess's relight takes out exactly what the
// lights put back (to float rounding of the two sums).
TEST(SunSplitVertices, CorrectionTurnsTheWholeEnvironmentIntoTheResidualPlusTheLights) {
    const RelightObject object = test::sunSplitSphere("test_sun_split_vertices_scratch", "linear", true);
    const Image env = test::skyWithSun();
    const SunSplitOptions options{.threshold = 2.0, .cellDegrees = 8.0};
    SunSplitVertexLighting lighting(object, env, options, "sphere.prt");
    ASSERT_FALSE(lighting.split().lights.empty());
    const glm::dmat3 rotation = rotationY(57.0);
    const ScatteringComponents ms{true, false};
    const glm::dvec3 eye(0, 0, 30);
    const VertexRadiance full = relit(object, env, rotation);
    const VertexRadiance residual = relit(object, splitSun(env, options).residual, rotation);
    SunSplitVertexTimes times;
    const VertexRadiance correction = lighting.correction(rotation, ms, 0, eye, &times);
    const std::vector<glm::vec3> lights = lighting.lights(rotation, ms, eye);
    ASSERT_EQ(correction.diffuse.size(), object.mesh.vertexCount());
    EXPECT_TRUE(correction.terms.empty());
    double peak = 0.0, worst = 0.0, lightsPeak = 0.0;
    for (size_t v = 0; v < full.diffuse.size(); ++v)
        for (int c = 0; c < 3; ++c) {
            const double want = double(residual.diffuse[v][c]) + double(lights[v][c]);
            const double got = double(full.diffuse[v][c]) + double(correction.diffuse[v][c]);
            peak = std::max(peak, std::abs(want));
            lightsPeak = std::max(lightsPeak, double(lights[v][c]));
            worst = std::max(worst, std::abs(got - want));
        }
    EXPECT_GT(lightsPeak, 0.1 * peak);  // the lights matter here
    EXPECT_LT(worst, 1e-5 * peak);
    EXPECT_GT(times.lightsIrradiance + times.lightsDiffusion, 0.0);
    // Turned further, the lights turn with the environment: another correction.
    const VertexRadiance turned = lighting.correction(rotationY(147.0), ms, 0, eye);
    EXPECT_NE(turned.diffuse, correction.diffuse);
}

// The viewer's frame: the transport's per-vertex radiance under the whole environment
// plus the correction, shaded per pixel (TranslucentShader), against the offline split
// frame (SunSplitFrameRenderer: the lights' Jensen-Buhler sum at every pixel). They
// differ by the interpolation of the lights' exitance across each triangle, which the
// finer sphere shrinks: measured 0.07% (642 vertices) and 0.02% (2,562), where the
// plain frame (no split; this synthetic transport is no physical one) is 10.5% off.
TEST(SunSplitVertices, ShadedFrameIsTheOfflineSplitFrameUpToInterpolation) {
    for (int subdivisions : {3, 4}) {
        const RelightObject object = test::sunSplitSphere("test_sun_split_vertices_scratch",
                                                          "frame" + std::to_string(subdivisions), true, subdivisions);
        const Image env = test::skyWithSun();
        const SunSplitOptions options;
        const ScatteringComponents ms{true, false};
        const glm::dmat3 rotation = rotationY(30.0);
        const Camera camera = frameSphere(object.sphereCentre, object.sphereRadius, 20, 10, 30, 96, 96);
        SunSplitFrameRenderer offline(object, env, FrameSettings{}, ms, options, "sphere.prt");
        const Image want = offline.render(camera, rotation);
        SunSplitVertexLighting lighting(object, env, options, "sphere.prt");
        VertexRadiance radiance = relit(object, env, rotation);
        const VertexRadiance plain = radiance;
        const VertexRadiance correction = lighting.correction(rotation, ms, 0, camera.eye);
        for (size_t v = 0; v < radiance.diffuse.size(); ++v) radiance.diffuse[v] += correction.diffuse[v];
        const RayScene rays(object.mesh);
        const GBuffer g = traceGBuffer(rays, object.mesh, camera);
        const TranslucentShader shader(object.mesh, object.eta);
        const auto shade = [&](const VertexRadiance& r) {
            return compose(g, env, rotation, [&](const GBufferPixel& px) { return shader.shade(px, r); });
        };
        const double split = compareImages(shade(radiance), want).overall.relativeRmse;
        const double unsplit = compareImages(shade(plain), want).overall.relativeRmse;
        std::printf("%zu vertices: the viewer's split frame %.4f off the offline one, the plain frame %.4f\n",
                    object.mesh.vertexCount(), split, unsplit);
        EXPECT_LT(split, subdivisions == 3 ? 0.003 : 0.001);
        EXPECT_LT(split, 0.1 * unsplit);
    }
}

// Switching environments (the viewer's N / B keys) re-splits from the object's copies:
// the correction is a fresh lighting's for that environment, bit for bit.
TEST(SunSplitVertices, AnotherEnvironmentEqualsAFreshSplit) {
    const RelightObject object = test::sunSplitSphere("test_sun_split_vertices_scratch", "switch", true);
    const Image first = test::skyWithSun();
    Image second = twoToneEnvironment(64, {0.3f, 0.5f, 0.9f}, {0.2f, 0.1f, 0.05f});
    const Image sun = sunEnvironment(64, glm::normalize(glm::dvec3(-1, 0.5, 0.2)), {500.0f, 400.0f, 300.0f});
    for (size_t i = 0; i < second.pixels.size(); ++i) second.pixels[i] += sun.pixels[i];
    SunSplitVertexLighting switched(object, first, {}, "sphere.prt");
    switched.setEnvironment(second);
    SunSplitVertexLighting fresh(object, second, {}, "sphere.prt");
    EXPECT_EQ(switched.split().lights.size(), fresh.split().lights.size());
    const glm::dmat3 rotation = rotationY(20.0);
    const ScatteringComponents ms{true, false};
    const VertexRadiance a = switched.correction(rotation, ms, 0, glm::dvec3(0, 0, 30));
    const VertexRadiance b = fresh.correction(rotation, ms, 0, glm::dvec3(0, 0, 30));
    EXPECT_EQ(a.diffuse, b.diffuse);
    SunSplitVertexLighting unswitched(object, first, {}, "sphere.prt");
    EXPECT_NE(unswitched.correction(rotation, ms, 0, glm::dvec3(0, 0, 30)).diffuse, a.diffuse);
    // A file that is not editable keeps its material.
    const std::string refused = test::errorOf([&] { switched.setMaterial(materialByName("Ketchup"), 30.0); });
    EXPECT_NE(refused.find("not editable"), std::string::npos) << refused;
}

TEST(SunSplitVertices, RefusesWhatItCannotShow) {
    RelightObject object = test::sunSplitSphere("test_sun_split_vertices_scratch", "refusals", true);
    const Image env = test::skyWithSun();
    object.transport.parameters.clear();  // no material
    test::expectErrorSubject([&] { SunSplitVertexLighting(object, env, {}, "sphere.prt"); }, "sphere.prt");
    const RelightObject good = test::sunSplitSphere("test_sun_split_vertices_scratch", "refusals2", true);
    const std::string bad = test::errorOf([&] { SunSplitVertexLighting(good, env, {.threshold = -1.0}, "sphere.prt"); });
    EXPECT_NE(bad.find("threshold"), std::string::npos) << bad;
}
