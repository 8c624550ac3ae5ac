// The sun split's frame (relight/combined/sun_split_frame.h): the residual's
// environment frame plus the lights' Jensen-Buhler frame, bit for bit; refusals.
// Its accuracy against the independent reference: Validation.SunSplit* (test_validation.cpp).

#include "relight/combined/sun_split_frame.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <string>

#include "common/envmap.h"
#include "common/error.h"
#include "common/mesh_io.h"
#include "common/shapes.h"
#include "tests/test_support.h"

using namespace prt;

namespace {

// test_environment_frame's synthetic sphere, with or without a material in its file.
RelightObject sphereObject(const std::string& name, bool withMaterial) {
    const std::filesystem::path dir = std::filesystem::current_path() / "test_sun_split_frame_scratch" / name;
    std::filesystem::remove_all(dir);
    std::filesystem::create_directories(dir);
    saveMesh(makeIcosphere(3, 2.0f), (dir / "sphere.obj").string());
    const TriangleMesh fileMesh = loadMesh((dir / "sphere.obj").string());
    TransportFile file = test::syntheticFaceTransport(fileMesh, 8, 5.0, 2.0f);
    if (withMaterial) {
        file.parameters.push_back({"sigma_s_prime", "2.19,2.62,3.00"});
        file.parameters.push_back({"sigma_a", "0.0021,0.0041,0.0071"});
    }
    saveTransportFile((dir / "sphere.prt").string(), file);
    return loadRelightObject((dir / "sphere.obj").string(), (dir / "sphere.prt").string());
}

Image skyWithSun() {
    Image env = twoToneEnvironment(64, {1.2f, 1.0f, 0.8f}, {0.1f, 0.2f, 0.3f});
    const Image sun = sunEnvironment(64, glm::normalize(glm::dvec3(1, 1, 0.3)), {300.0f, 280.0f, 250.0f});
    for (size_t i = 0; i < env.pixels.size(); ++i) env.pixels[i] += sun.pixels[i];
    return env;
}

}  // namespace

// The frame is its stages composed: the environment frame lit by the residual (the
// background the whole map), plus Jensen-Buhler over the face centroids lit by the
// split's lights turned with the environment.
TEST(SunSplitFrame, FrameIsTheResidualFramePlusTheLightsFrame) {
    const RelightObject object = sphereObject("stages", true);
    const Image env = skyWithSun();
    const FrameSettings look;
    const ScatteringComponents ms{true, false};
    const SunSplitOptions options{.threshold = 2.0, .cellDegrees = 8.0};
    SunSplitFrameRenderer renderer(object, env, look, ms, options, "sphere.prt");
    const Camera camera = frameSphere(object.sphereCentre, object.sphereRadius, 20, 10, 30, 40, 32);
    const glm::dmat3 rotation = rotationY(57.0);
    const Image frame = renderer.render(camera, rotation);

    const SunSplit split = splitSun(env, options);
    ASSERT_FALSE(split.lights.empty());
    EXPECT_EQ(renderer.split().lights.size(), split.lights.size());
    EnvironmentFrameRenderer residual(object, env, look, ms, false, split.residual);
    Image expected = residual.render(camera, rotation);
    PointRenderSettings settings;
    settings.material = sunSplitMaterial(object, "sphere.prt");
    settings.method = PointMethod::JensenBuhler;
    const IrradianceSamples placed = faceCentroidSamples(object.mesh);
    const RayScene scene(object.mesh);
    const LitSamples lit = lightSamples(placed, scene, rotatedLights(split.lights, rotation), settings);
    const PointFrame lights = renderPointFrame(*lit.tree, residual.gbuffer(), settings, false,
                                               nearFieldCells(object.mesh, placed, settings));
    for (size_t i = 0; i < size_t(expected.width) * size_t(expected.height); ++i)
        for (size_t c = 0; c < 3; ++c)
            expected.pixels[i * size_t(expected.channels) + c] +=
                lights.image.pixels[i * size_t(lights.image.channels) + c];
    ASSERT_EQ(frame.pixels.size(), expected.pixels.size());
    EXPECT_EQ(frame.pixels, expected.pixels);
    // The lights add light: the frame is brighter than the residual's alone.
    double withLights = 0.0, without = 0.0;
    const Image residualOnly = residual.render(camera, rotation);
    for (size_t i = 0; i < frame.pixels.size(); i += 4)
        if (frame.pixels[i + 3] == 1.0f) {  // object pixels
            withLights += frame.pixels[i];
            without += residualOnly.pixels[i];
        }
    EXPECT_GT(withLights, 1.05 * without);
}

TEST(SunSplitFrame, RefusesAFileWithoutAMaterialAndAnUnknownMethod) {
    const RelightObject bare = sphereObject("bare", false);
    const Image env = skyWithSun();
    try {
        SunSplitFrameRenderer renderer(bare, env, FrameSettings{}, {true, false}, {}, "bare.prt");
        FAIL() << "a file without a material was accepted";
    } catch (const Error& e) {
        EXPECT_NE(std::string(e.what()).find("bare.prt"), std::string::npos) << e.what();
        EXPECT_NE(std::string(e.what()).find("names no material"), std::string::npos) << e.what();
    }
    const RelightObject object = sphereObject("methods", true);
    EXPECT_THROW(SunSplitFrameRenderer(object, env, FrameSettings{}, {true, false}, {}, "sphere.prt", false,
                                       PointMethod::TextureSpace),
                 Error);
    EXPECT_EQ(parseSunSplitMethod("cache"), PointMethod::Cache);
    EXPECT_THROW(parseSunSplitMethod("tsis"), Error);
}
