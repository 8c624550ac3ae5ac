#include "relight/prt/environment_frame.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <string>

#include "common/bssrdf.h"
#include "common/envmap.h"
#include "common/mesh_io.h"
#include "common/shapes.h"
#include "tests/test_support.h"

using namespace prt;

namespace {

// The synthetic sphere of test_relight_object (face scaling coefficients only), placed.
RelightObject sphereObject(const std::string& name, float R, double mmPerUnit, int n) {
    const std::filesystem::path dir = std::filesystem::current_path() / "test_environment_frame_scratch" / name;
    std::filesystem::remove_all(dir);
    std::filesystem::create_directories(dir);
    saveMesh(makeIcosphere(4, R), (dir / "sphere.obj").string());
    const TriangleMesh fileMesh = loadMesh((dir / "sphere.obj").string());
    saveTransportFile((dir / "sphere.prt").string(), test::syntheticFaceTransport(fileMesh, n, mmPerUnit, R));
    return loadRelightObject((dir / "sphere.obj").string(), (dir / "sphere.prt").string());
}

// Two-tone sky with a sun: a light that changes with the rotation.
Image testEnvironment() {
    Image env = twoToneEnvironment(64, {1.2f, 1.0f, 0.8f}, {0.1f, 0.2f, 0.3f});
    const Image sun = sunEnvironment(64, glm::normalize(glm::dvec3(1, 1, 0.3)), {30.0f, 28.0f, 25.0f});
    for (size_t i = 0; i < env.pixels.size(); ++i) env.pixels[i] += sun.pixels[i];
    return env;
}

}  // namespace

// The renderer's frame is the composition of the stages it runs, bit for bit.
TEST(EnvironmentFrame, FrameIsTheStagesComposed) {
    const RelightObject object = sphereObject("stages", 2.0f, 5.0, 8);
    const Image env = testEnvironment();
    FrameSettings look;
    const ScatteringComponents all = ScatteringComponents::all();
    EnvironmentFrameRenderer renderer(object, env, look, all);
    const Camera camera = frameSphere(object.sphereCentre, object.sphereRadius, 20, 10, 30, 48, 40);
    const glm::dmat3 rotation = rotationY(57.0);
    EnvironmentFrameTimes times;
    const Image frame = renderer.render(camera, rotation, &times);

    const LightVector light = makeLightVector(env, 8, rotation);
    VertexRadiance radiance;
    relightVertices(object.transport, light, all, radiance);
    const RayScene scene(object.mesh);
    const GBuffer g = traceGBuffer(scene, object.mesh, camera);
    const TranslucentShader shader(object.mesh, object.eta);
    const Image expected = compose(g, env, rotation, [&](const GBufferPixel& p) { return shader.shade(p, radiance); });
    ASSERT_EQ(frame.pixels.size(), expected.pixels.size());
    EXPECT_EQ(frame.pixels, expected.pixels);
    EXPECT_EQ(times.objectPixels, g.objectPixels());
    EXPECT_GT(times.objectPixels, 100u);
    EXPECT_EQ(times.lightTerms, light.keptTerms);
    EXPECT_EQ(renderer.vertexRadiance().diffuse, radiance.diffuse);
}

// A sequence's prepared environment (the fast path of a turntable or spin) gives the
// single frame's light to float rounding; the G-buffer is traced again only for a new
// camera.
TEST(EnvironmentFrame, SequenceMatchesSingleFramesAndCameraChangesRetrace) {
    const RelightObject object = sphereObject("sequence", 2.0f, 5.0, 8);
    const Image env = testEnvironment();
    FrameSettings look;
    EnvironmentFrameRenderer single(object, env, look, ScatteringComponents::all(), false);
    EnvironmentFrameRenderer sequence(object, env, look, ScatteringComponents::all(), true);
    const Camera a = frameSphere(object.sphereCentre, object.sphereRadius, 0, 15, 30, 32, 32);
    const Camera b = frameSphere(object.sphereCentre, object.sphereRadius, 90, 15, 30, 32, 32);
    for (double degrees : {0.0, 30.0, 200.0}) {
        const Image x = single.render(a, rotationY(degrees));
        const Image y = sequence.render(a, rotationY(degrees));
        double peak = 0.0, worst = 0.0;
        for (size_t i = 0; i < x.pixels.size(); ++i) {
            peak = std::max(peak, double(x.pixels[i]));
            worst = std::max(worst, std::abs(double(x.pixels[i]) - double(y.pixels[i])));
        }
        EXPECT_LT(worst, 1e-4 * peak) << degrees;
    }
    const Image fromA = single.render(a, glm::dmat3(1.0));
    const Image fromB = single.render(b, glm::dmat3(1.0));
    EXPECT_NE(fromA.pixels, fromB.pixels);
    EXPECT_EQ(single.render(a, glm::dmat3(1.0)).pixels, fromA.pixels);
}

// Constant environment c: at the centre pixel the frame is F_t(eta, cos) times the
// closed-form dot product of the synthetic vectors (test_relight_object's law).
TEST(EnvironmentFrame, ConstantEnvironmentClosedForm) {
    const float R = 2.0f;
    const double mmPerUnit = 5.0;
    const int n = 8;
    const RelightObject object = sphereObject("constant", R, mmPerUnit, n);
    const glm::vec3 c(0.7f, 1.1f, 1.9f);
    FrameSettings look;
    EnvironmentFrameRenderer renderer(object, constantEnvironment(64, c), look, ScatteringComponents::all());
    const Camera camera = frameSphere(object.sphereCentre, object.sphereRadius, 0, 0, 30, 65, 65);
    const Image frame = renderer.render(camera, rotationY(33.0));
    const GBufferPixel& centre = renderer.gbuffer().at(32, 32);
    ASSERT_TRUE(centre.hit);
    const double s = 1.0 + 0.1 * (centre.position.x / mmPerUnit) / R;
    const double cosO = glm::dot(centre.normal, centre.toViewer);
    const glm::dvec3 rgb(0.01, 0.02, 0.03);
    for (int ch = 0; ch < 3; ++ch) {
        const double closedForm = fresnelTransmittance(1.3, cosO) * s * 21.0 * rgb[ch] * n * c[ch];
        EXPECT_NEAR(frame.at(32, 32, ch), closedForm, 2e-4 * closedForm);
    }
    EXPECT_EQ(frame.at(32, 32, 3), 1.0f);
    EXPECT_FLOAT_EQ(frame.at(0, 0, 1), c.y);  // background: the environment
    EXPECT_EQ(frame.at(0, 0, 3), 0.0f);
}
