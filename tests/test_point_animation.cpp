// prt-pointlight's animations (relight/pointlight/point_animation.h). Asserted: frame k of a
// turntable equals a single render with the camera at that azimuth (to float rounding
// of the camera; bit for bit against the single render from the orbited camera), so
// reusing the irradiance samples and the octree changes nothing; the light path's
// first and last frames (and a middle one) equal single renders with the light at P0,
// P1 (and the interpolated point) bit for bit, the other lights untouched; a path
// through the object and bad --light-path / --frames values are one-line errors
// raised before any frame is rendered; the material / size path's end frames (and a
// middle one) equal single renders with A at S_0 and B at S_1 bit for bit for every
// method (tsis included), a size path is scaledMaterial, and bad paths are one-line
// errors naming the option.

#include "relight/pointlight/point_animation.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <utility>
#include <vector>

#include "common/bssrdf.h"
#include "common/camera.h"
#include "common/error.h"
#include "common/material_edit.h"
#include "common/shapes.h"
#include "relight/pointlight/surface_atlas.h"
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
        // As prt-pointlight's single frame: the near-field cells, pass 1, the frame.
        const LitSamples lit = lightSamples(placed, scene, lights, s);
        return renderPointFrame(*lit.tree, traceGBuffer(scene, mesh, camera), s, false,
                                nearFieldCells(mesh, placed, s))
            .image;
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

// The material / size path (Chang et al. Fig. 11): frame 0 is a single render with A at
// S_0, frame N-1 with B at S_1, the middle frame with the interpolated material, bit for
// bit, although pass 1, the G-buffer and the renderer are kept between frames.
TEST(PointAnimation, MaterialPathEndsEqualSingleRenders) {
    const Scene s;
    const Material a = materialByName("Marble"), b = materialByName("Skin1");
    for (const PointMethod method : {PointMethod::Cache, PointMethod::JensenBuhler, PointMethod::Brute}) {
        const int size = method == PointMethod::Brute ? 16 : 32;
        const Camera cam = s.camera(15.0, size);
        PointAnimation anim{.kind = AnimationKind::MaterialPath, .frames = 3};
        anim.materials = std::make_pair(a, b);
        std::vector<AnimationFrameInfo> infos;
        const std::vector<Image> frames = s.animate(anim, kLights, cam, s.settings(method), &infos);
        ASSERT_EQ(frames.size(), 3u);
        auto single = [&](const Material& m) {
            PointRenderSettings st = s.settings(method);
            st.material = m;
            return s.single(cam, kLights, st);
        };
        EXPECT_TRUE(identical(frames[0], single(a))) << toString(method);
        EXPECT_TRUE(identical(frames[2], single(b))) << toString(method);
        EXPECT_TRUE(identical(frames[1], single(lerpMaterial(a, b, 0.5)))) << toString(method);
        EXPECT_FALSE(identical(frames[0], frames[2]));
        EXPECT_EQ(infos[0].material.sigmaA, a.sigmaA);
        EXPECT_EQ(infos[2].material.sigmaSPrime, b.sigmaSPrime);
        for (size_t k = 1; k < infos.size(); ++k) {
            EXPECT_EQ(infos[k].irradianceSeconds, 0.0);
            EXPECT_EQ(infos[k].gbufferSeconds, 0.0);
        }
    }
}

TEST(PointAnimation, SizePathIsAScaledMaterial) {
    const Scene s;
    const Material a = materialByName("Marble"), b = materialByName("Ketchup");
    const Camera camera = s.camera(-30.0, 32);
    auto single = [&](const Material& m) {
        PointRenderSettings st = s.settings();
        st.material = m;
        return s.single(camera, kLights, st);
    };
    // The size alone (the settings' material), then with the material.
    PointAnimation size{.kind = AnimationKind::MaterialPath, .frames = 4};
    size.sizesMm = std::make_pair(20.0, 45.0);
    size.geometrySizeMm = 30.0;
    std::vector<AnimationFrameInfo> infos;
    std::vector<Image> frames = s.animate(size, kLights, camera, s.settings(), &infos);
    ASSERT_EQ(frames.size(), 4u);
    EXPECT_TRUE(identical(frames[0], single(scaledMaterial(a, 20.0 / 30.0))));
    EXPECT_TRUE(identical(frames[3], single(scaledMaterial(a, 45.0 / 30.0))));
    EXPECT_EQ(infos[0].sizeMm, 20.0);
    EXPECT_EQ(infos[3].sizeMm, 45.0);
    EXPECT_DOUBLE_EQ(infos[1].sizeMm, 28.333333333333332);

    PointAnimation both = size;
    both.materials = std::make_pair(a, b);
    frames = s.animate(both, kLights, camera, s.settings());
    EXPECT_TRUE(identical(frames[0], single(scaledMaterial(a, 20.0 / 30.0))));
    EXPECT_TRUE(identical(frames[3], single(scaledMaterial(b, 45.0 / 30.0))));
    // The size at the geometry's own size is the plain material.
    EXPECT_EQ(animationMaterial(both, a, 0).sigmaA, scaledMaterial(a, 20.0 / 30.0).sigmaA);
    PointAnimation unit = size;
    unit.sizesMm = std::make_pair(30.0, 60.0);
    EXPECT_EQ(animationMaterial(unit, a, 0).sigmaSPrime, a.sigmaSPrime);
}

// --method tsis: the lit renderer is kept and only its material changes.
TEST(PointAnimation, TextureSpaceMaterialPathEndsEqualFreshRenderers) {
    const Scene s;
    const SurfaceAtlas atlas = buildSurfaceAtlas(s.mesh, 128);
    const Material a = materialByName("Skin2"), b = materialByName("Apple");
    const GBuffer g = traceGBuffer(s.scene, s.mesh, s.camera(40.0, 32));
    const TextureSpaceOptions o{.samples = 200, .seed = 3};
    PointAnimation anim{.kind = AnimationKind::MaterialPath, .frames = 2};
    anim.materials = std::make_pair(a, b);
    anim.sizesMm = std::make_pair(30.0, 15.0);
    anim.geometrySizeMm = 30.0;
    for (const bool perVertex : {false, true}) {
        TextureSpaceRenderer renderer(s.mesh, s.scene, atlas, a, o);
        renderer.setLights(kLights);
        std::vector<Image> frames;
        renderTextureSpaceAnimation(anim, renderer, g, perVertex, a, [&](const AnimationFrameInfo& info, PointFrame& f) {
            EXPECT_EQ(info.frame, int(frames.size()));
            frames.push_back(std::move(f.image));
        });
        ASSERT_EQ(frames.size(), 2u);
        auto fresh = [&](const Material& m) {
            TextureSpaceRenderer r(s.mesh, s.scene, atlas, m, o);
            r.setLights(kLights);
            return perVertex ? r.renderPerVertex(g) : r.render(g);
        };
        EXPECT_TRUE(identical(frames[0], fresh(a))) << perVertex;
        EXPECT_TRUE(identical(frames[1], fresh(scaledMaterial(b, 0.5)))) << perVertex;
    }
    TextureSpaceRenderer renderer(s.mesh, s.scene, atlas, a, o);
    PointAnimation turntable{.kind = AnimationKind::Turntable, .frames = 2};
    test::expectErrorSubject(
        [&] { renderTextureSpaceAnimation(turntable, renderer, g, false, a, [](const AnimationFrameInfo&, PointFrame&) {}); },
        "--method");
}

TEST(PointAnimation, MaterialPathErrors) {
    const Scene s;
    int rendered = 0;
    auto run = [&](const PointAnimation& a) {
        renderAnimation(a, s.mesh, s.scene, s.placed, kLights, s.camera(0.0, 8), s.pivot, s.settings(),
                        [&](const AnimationFrameInfo&, PointFrame&) { ++rendered; });
    };
    PointAnimation a{.kind = AnimationKind::MaterialPath, .frames = 1};
    a.materials = std::make_pair(materialByName("Marble"), materialByName("Skin1"));
    test::expectErrorSubject([&] { run(a); }, "--frames");
    a.frames = 3;
    a.materials->second.eta = 1.4;
    test::expectErrorSubject([&] { run(a); }, "--material-path");
    a.materials.reset();
    test::expectErrorSubject([&] { run(a); }, "--material-path");
    a.sizesMm = std::make_pair(10.0, 0.0);
    a.geometrySizeMm = 30.0;
    test::expectErrorSubject([&] { run(a); }, "--size-path");
    a.sizesMm = std::make_pair(10.0, 20.0);
    a.geometrySizeMm = 0.0;
    test::expectErrorSubject([&] { run(a); }, "--size-path");
    EXPECT_EQ(rendered, 0);

    double s0 = 0.0, s1 = 0.0;
    for (const char* bad : {"", "10", "10:", ":10", "10:20:30", "0:10", "10:-1", "x:10", "10,20:30", "nan:1", "1:inf"}) {
        const std::string e = test::errorOf([&] { parseSizePath(bad, s0, s1); });
        EXPECT_NE(e, test::kNoError) << bad;
        EXPECT_EQ(e.find('\n'), std::string::npos) << e;
        test::expectErrorSubject([&] { parseSizePath(bad, s0, s1); }, "--size-path");
    }
    parseSizePath(" 12.5 : 40", s0, s1);
    EXPECT_EQ(s0, 12.5);
    EXPECT_EQ(s1, 40.0);
}
