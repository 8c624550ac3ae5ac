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
#include "tests/sun_split_support.h"

using namespace prt;


// The frame is its stages composed: the environment frame lit by the residual (the
// background the whole map), plus Jensen-Buhler over the face centroids lit by the
// split's lights turned with the environment.
TEST(SunSplitFrame, FrameIsTheResidualFramePlusTheLightsFrame) {
    const RelightObject object = test::sunSplitSphere("test_sun_split_frame_scratch", "stages", true);
    const Image env = test::skyWithSun();
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
    const RelightObject bare = test::sunSplitSphere("test_sun_split_frame_scratch", "bare", false);
    const Image env = test::skyWithSun();
    try {
        SunSplitFrameRenderer renderer(bare, env, FrameSettings{}, {true, false}, {}, "bare.prt");
        FAIL() << "a file without a material was accepted";
    } catch (const Error& e) {
        EXPECT_NE(std::string(e.what()).find("bare.prt"), std::string::npos) << e.what();
        EXPECT_NE(std::string(e.what()).find("names no material"), std::string::npos) << e.what();
    }
    const RelightObject object = test::sunSplitSphere("test_sun_split_frame_scratch", "methods", true);
    EXPECT_THROW(SunSplitFrameRenderer(object, env, FrameSettings{}, {true, false}, {}, "sphere.prt", false,
                                       PointMethod::TextureSpace),
                 Error);
    EXPECT_EQ(parseSunSplitMethod("cache"), PointMethod::Cache);
    EXPECT_THROW(parseSunSplitMethod("tsis"), Error);
}
