// prt-pointlight's animations (relight/pointlight/point_animation.h). Asserted: frame k of a
// turntable equals a single render with the camera at that azimuth (to float rounding
// of the camera; bit for bit against the single render from the orbited camera), so
// reusing the irradiance samples and the octree changes nothing; the light path's
// first and last frames (and a middle one) equal single renders with the light at P0,
// P1 (and the interpolated point) bit for bit, the other lights untouched; a path
// through the object and bad --light-path / --frames values are one-line errors
// raised before any frame is rendered.

#include "relight/pointlight/point_animation.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "common/bssrdf.h"
#include "common/camera.h"
#include "common/error.h"
#include "common/shapes.h"
#include "relight/render/gbuffer.h"
#include "test_support.h"

using namespace prt;

namespace {

struct Scene {
    TriangleMesh mesh = makeTorus(12.0f, 5.0f, 64, 32);
    RayScene scene{mesh};
    IrradianceSamples placed = faceCentroidSamples(mesh);
    glm::dvec3 pivot{0.0};
    double radius = 17.0;
    Scene() { pivot = glm::dvec3(bounds(mesh).centre()); }
    Camera camera(double azimuth, int size = 48) const {
        return frameSphere(pivot, radius, azimuth, 35.0, 30.0, size, size);
    }
    PointRenderSettings settings(PointMethod method = PointMethod::Cache) const {
        PointRenderSettings s{.material = materialByName("Marble")};
        s.method = method;
        return s;
    }
    // What prt-pointlight does for one frame.
    Image single(const Camera& camera, const std::vector<Light>& lights, const PointRenderSettings& s) const {
        const LitSamples lit = lightSamples(placed, scene, lights, s);
        return renderPointFrame(*lit.tree, traceGBuffer(scene, mesh, camera), s).image;
    }
    std::vector<Image> animate(const PointAnimation& a, const std::vector<Light>& lights, const Camera& base,
                               const PointRenderSettings& s, std::vector<AnimationFrameInfo>* infos = nullptr) const {
        std::vector<Image> frames;
        renderAnimation(a, mesh, scene, placed, lights, base, pivot, s,
                        [&](const AnimationFrameInfo& info, PointFrame& f) {
                            EXPECT_EQ(info.frame, int(frames.size()));
                            frames.push_back(std::move(f.image));
                            if (infos) infos->push_back(info);
                        });
        return frames;
    }
};

bool identical(const Image& a, const Image& b) {
    return a.width == b.width && a.height == b.height && a.channels == b.channels && a.pixels == b.pixels;
}

// Same coverage (alpha) everywhere, and the largest RGB difference relative to the
// image's brightest value.
double relativeDifference(const Image& a, const Image& b, size_t* coverageMismatches) {
    *coverageMismatches = 0;
    float peak = 0.0f, worst = 0.0f;
    for (int y = 0; y < a.height; ++y)
        for (int x = 0; x < a.width; ++x) {
            if (a.at(x, y, 3) != b.at(x, y, 3)) ++*coverageMismatches;
            for (int c = 0; c < 3; ++c) {
                peak = std::max(peak, std::abs(b.at(x, y, c)));
                worst = std::max(worst, std::abs(a.at(x, y, c) - b.at(x, y, c)));
            }
        }
    return peak > 0.0f ? double(worst / peak) : double(worst);
}

const std::vector<Light> kLights = {parseLight("point:25,30,10:0.01")};

}  // namespace

TEST(PointAnimation, TurntableFrameEqualsSingleRenderAtThatAzimuth) {
    const Scene s;
    const double azimuth = 20.0;
    PointAnimation a{.kind = AnimationKind::Turntable, .frames = 6};
    std::vector<AnimationFrameInfo> infos;
    const std::vector<Image> frames = s.animate(a, kLights, s.camera(azimuth), s.settings(), &infos);
    ASSERT_EQ(frames.size(), 6u);
    for (int k : {0, 1, 3, 5}) {
        const double degrees = 360.0 * k / 6;
        // Bit for bit against a single render from the orbited camera: the reused
        // samples and octree are those a single render computes.
        const Camera orbit = turntableCamera(s.camera(azimuth), s.pivot, degrees);
        EXPECT_TRUE(identical(frames[size_t(k)], s.single(orbit, kLights, s.settings()))) << "frame " << k;
        // Against --azimuth (azimuth - degrees): the cameras agree to double rounding,
        // the images to float rounding.
        const Camera az = s.camera(azimuth - degrees);
        EXPECT_LT(glm::length(orbit.eye - az.eye), 1e-9) << "frame " << k;
        EXPECT_LT(glm::length(orbit.up - az.up), 1e-12) << "frame " << k;
        size_t coverage = 0;
        const double diff = relativeDifference(frames[size_t(k)], s.single(az, kLights, s.settings()), &coverage);
        EXPECT_EQ(coverage, 0u) << "frame " << k;
        EXPECT_LT(diff, 1e-5) << "frame " << k;
        // The object turns: frames differ from each other.
        if (k > 0) {
            EXPECT_FALSE(identical(frames[size_t(k)], frames[0]));
        }
    }
    // Pass 1 ran once: reused afterwards (reported as 0 s).
    for (size_t k = 1; k < infos.size(); ++k) {
        EXPECT_EQ(infos[k].irradianceSeconds, 0.0);
        EXPECT_EQ(infos[k].octreeSeconds, 0.0);
        EXPECT_EQ(infos[k].lights.front().position, kLights.front().position);
    }
}

TEST(PointAnimation, TurntableWithJensenBuhler) {
    const Scene s;
    PointAnimation a{.kind = AnimationKind::Turntable, .frames = 4};
    const PointRenderSettings jb = s.settings(PointMethod::JensenBuhler);
    const std::vector<Image> frames = s.animate(a, kLights, s.camera(0.0), jb);
    ASSERT_EQ(frames.size(), 4u);
    EXPECT_TRUE(identical(frames[3], s.single(turntableCamera(s.camera(0.0), s.pivot, 270.0), kLights, jb)));
    size_t coverage = 0;
    EXPECT_LT(relativeDifference(frames[3], s.single(s.camera(-270.0), kLights, jb), &coverage), 1e-5);
    EXPECT_EQ(coverage, 0u);
}

TEST(PointAnimation, LightPathEndsEqualSingleRendersAtP0AndP1) {
    const Scene s;
    // Two lights: the first moves, the second stays.
    const std::vector<Light> lights = {parseLight("point:0,40,0:0.01"), parseLight("point:-30,10,25:0.004")};
    PointAnimation a{.kind = AnimationKind::LightPath, .frames = 5};
    parseLightPath("-30,25,10:30,25,-10", a.from, a.to);
    std::vector<AnimationFrameInfo> infos;
    const Camera camera = s.camera(15.0);
    const std::vector<Image> frames = s.animate(a, lights, camera, s.settings(), &infos);
    ASSERT_EQ(frames.size(), 5u);
    auto with = [&](const glm::dvec3& p) {
        std::vector<Light> l = lights;
        l.front() = pointLight(p, lights.front().rgb);
        return l;
    };
    EXPECT_TRUE(identical(frames[0], s.single(camera, with({-30, 25, 10}), s.settings())));
    EXPECT_TRUE(identical(frames[4], s.single(camera, with({30, 25, -10}), s.settings())));
    EXPECT_TRUE(identical(frames[2], s.single(camera, with({0, 25, 0}), s.settings())));
    EXPECT_FALSE(identical(frames[0], frames[4]));
    for (const AnimationFrameInfo& info : infos) {
        EXPECT_EQ(info.lights.size(), 2u);
        EXPECT_EQ(info.lights[1].position, lights[1].position);
        EXPECT_EQ(info.lights[0].rgb, lights[0].rgb);
    }
    EXPECT_EQ(infos[0].lights[0].position, glm::dvec3(-30, 25, 10));
    EXPECT_EQ(infos[4].lights[0].position, glm::dvec3(30, 25, -10));
    // The G-buffer is traced once (fixed camera), pass 1 every frame.
    for (size_t k = 1; k < infos.size(); ++k) EXPECT_EQ(infos[k].gbufferSeconds, 0.0);
}

TEST(PointAnimation, LightPathWithBruteForce) {
    const Scene s;
    PointAnimation a{.kind = AnimationKind::LightPath, .frames = 2};
    parseLightPath("0,30,0:0,0,30", a.from, a.to);
    const PointRenderSettings brute = s.settings(PointMethod::Brute);
    const Camera camera = s.camera(0.0, 24);
    const std::vector<Image> frames = s.animate(a, kLights, camera, brute);
    ASSERT_EQ(frames.size(), 2u);
    EXPECT_TRUE(identical(frames[0], s.single(camera, {parseLight("point:0,30,0:0.01")}, brute)));
    EXPECT_TRUE(identical(frames[1], s.single(camera, {parseLight("point:0,0,30:0.01")}, brute)));
}

TEST(PointAnimation, FrameNames) {
    EXPECT_EQ(animationFrameName("out/tt", 0), "out/tt_0000");
    EXPECT_EQ(animationFrameName("out/tt", 37), "out/tt_0037");
}

TEST(PointAnimation, ErrorsBeforeAnyFrame) {
    const Scene s;
    int rendered = 0;
    auto run = [&](const PointAnimation& a, const std::vector<Light>& lights) {
        renderAnimation(a, s.mesh, s.scene, s.placed, lights, s.camera(0.0, 8), s.pivot, s.settings(),
                        [&](const AnimationFrameInfo&, PointFrame&) { ++rendered; });
    };
    // The path's middle frames put the light inside the torus's tube (centre radius 12).
    PointAnimation through{.kind = AnimationKind::LightPath, .frames = 21};
    parseLightPath("-40,0,0:40,0,0", through.from, through.to);
    const std::string inside = test::errorOf([&] { run(through, kLights); });
    EXPECT_NE(inside.find("inside"), std::string::npos) << inside;
    EXPECT_EQ(rendered, 0);

    PointAnimation none{.kind = AnimationKind::Turntable, .frames = 0};
    test::expectErrorSubject([&] { run(none, kLights); }, "--turntable");
    PointAnimation path{.kind = AnimationKind::LightPath, .frames = 0};
    test::expectErrorSubject([&] { run(path, kLights); }, "--frames");
    path.frames = 3;
    test::expectErrorSubject([&] { run(path, {parseLight("dir:0,1,0:1")}); }, "--light-path");
    EXPECT_EQ(rendered, 0);

    glm::dvec3 p0, p1;
    for (const char* bad : {"", "1,2,3", "1,2:3,4,5", "1,2,3:4,5,6:7,8,9", "1,2,3:4,5,x", "1,2,3:4,5,6,", "nan,0,0:1,1,1",
                            "1,2,3:4,5,1e999"}) {
        const std::string e = test::errorOf([&] { parseLightPath(bad, p0, p1); });
        EXPECT_NE(e, test::kNoError) << bad;
        EXPECT_EQ(e.find('\n'), std::string::npos) << e;
        test::expectErrorSubject([&] { parseLightPath(bad, p0, p1); }, "--light-path");
    }
    parseLightPath("-1.5,2,3e1:4,-5,6", p0, p1);
    EXPECT_EQ(p0, glm::dvec3(-1.5, 2, 30));
    EXPECT_EQ(p1, glm::dvec3(4, -5, 6));
}
