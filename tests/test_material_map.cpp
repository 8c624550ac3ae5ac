// Material maps (relight/prt/material_map.h): a second material blended per vertex at the
// exit point on an editable file. Constant maps against the materials alone (exact),
// the linearity of the blend, the map's per-vertex t against the texture, the errors;
// the reference's per-pixel blend.

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>

#include "common/asset_io.h"
#include "common/envmap.h"
#include "common/error.h"
#include "common/image.h"
#include "common/material_edit.h"
#include "common/mesh_io.h"
#include "common/progress.h"
#include "common/shapes.h"
#include "precompute/job/pipeline.h"
#include "relight/combined/sun_split_frame.h"
#include "relight/prt/environment_frame.h"
#include "relight/prt/material_map.h"
#include "relight/prt/relight_object.h"
#include "tools/reference/reference.h"

using namespace prt;
namespace fs = std::filesystem;

namespace {

struct Scene {
    fs::path dir;
    std::string glb, prt;
};

// An editable sphere written as a .glb with spherical texture coordinates.
const Scene& scene() {
    static const Scene s = [] {
        Progress::setEnabled(false);
        Scene out;
        out.dir = fs::temp_directory_path() / ("prt_test_material_map_" + std::to_string(getpid()));
        fs::create_directories(out.dir);
        const TriangleMesh sphere = makeIcosphere(2, 5.0f);
        out.glb = (out.dir / "sphere.glb").string();
        saveTexturedGltf(out.glb, sphere, projectUvs(sphere, UvProjection::Spherical), makeCheckerTexture(8, 2));
        PrecomputeSettings p;
        p.meshPath = out.glb;
        p.outputPath = out.prt = (out.dir / "sphere.prt").string();
        p.scale.mmPerUnit = 1.0;
        p.material = materialByName("Marble");
        p.cubemapSize = 8;
        p.samples.count = 400;
        p.pass1.sampleCoefficients = p.pass2.nodeCoefficients = p.vertexCoefficients = 64;
        p.editable.enabled = true;
        precomputeTransport(p, true);
        return out;
    }();
    return s;
}

std::string constantMap(const std::string& name, float t) {
    const std::string path = (scene().dir / name).string();
    Image map(4, 4, 3, t);
    writeExr(path, map);
    return path;
}

Camera mapCamera() {
    Camera camera;
    camera.eye = {0.0, 5.0, 25.0};
    camera.width = camera.height = 48;
    return camera;
}

// A sky and a sun (radiance 3000 over one pixel of about 0.01 sr).
Image skyAndSun() {
    Image sky = constantEnvironment(64, {0.5f, 0.6f, 0.8f});
    const Image sun = sunEnvironment(64, glm::normalize(glm::dvec3(0.3, 1, 0.4)), {3000, 2800, 2500});
    for (size_t i = 0; i < sky.pixels.size(); ++i) sky.pixels[i] += sun.pixels[i];
    return sky;
}

Image renderWith(RelightObject& object) {
    EnvironmentFrameRenderer r(object, skyAndSun(), FrameSettings{}, ScatteringComponents{true, false});
    return r.render(mapCamera(), glm::dmat3(1.0));
}

// The same frame with the sun split (relight/combined/sun_split_frame.h).
Image renderSplitWith(RelightObject& object) {
    SunSplitFrameRenderer r(object, skyAndSun(), FrameSettings{}, ScatteringComponents{true, false}, {}, scene().prt);
    EXPECT_FALSE(r.split().lights.empty());
    return r.render(mapCamera(), glm::dmat3(1.0));
}

}  // namespace

TEST(MaterialMap, ConstantMapsGiveEachMaterialAndTheirMean) {
    const Scene& s = scene();
    RelightObject a = loadRelightObject(s.glb, s.prt);
    const Image plainA = renderWith(a);

    RelightObject zero = loadRelightObject(s.glb, s.prt);
    zero.materialMap = loadMaterialMap(zero, s.glb, constantMap("zero.exr", 0.0f), "Ketchup", s.prt);
    EXPECT_EQ(renderWith(zero).pixels, plainA.pixels) << "t = 0 is the object's material, exactly";

    RelightObject b = loadRelightObject(s.glb, s.prt);
    setObjectMaterial(b, parseMaterial("Ketchup", b.eta), objectSizeMm(b), s.prt);
    const Image plainB = renderWith(b);
    RelightObject one = loadRelightObject(s.glb, s.prt);
    one.materialMap = loadMaterialMap(one, s.glb, constantMap("one.exr", 1.0f), "Ketchup", s.prt);
    EXPECT_EQ(renderWith(one).pixels, plainB.pixels) << "t = 1 is the map's material, exactly";
    // The object keeps its own material after the map recombined B.
    EXPECT_EQ(one.editable->material().name, a.editable->material().name);

    RelightObject half = loadRelightObject(s.glb, s.prt);
    half.materialMap = loadMaterialMap(half, s.glb, constantMap("half.exr", 0.5f), "Ketchup", s.prt);
    const Image mean = renderWith(half);
    double worst = 0.0, peak = 0.0;
    for (size_t k = 0; k < mean.pixels.size(); ++k) {
        if (k % 4 == 3 || mean.pixels[k - k % 4 + 3] != 1.0f) continue;  // object pixels' RGB
        worst = std::max(worst, double(std::abs(mean.pixels[k] - 0.5f * (plainA.pixels[k] + plainB.pixels[k]))));
        peak = std::max(peak, double(plainA.pixels[k]));
    }
    EXPECT_LT(worst, 1e-5 * peak) << "the blend is linear in t";
    EXPECT_GT(peak, 0.0);
}

TEST(MaterialMap, VertexWeightsFollowTheTexture) {
    const Scene& s = scene();
    // Right half of u (0.5 .. 1) is B: every vertex whose corners all lie there has t = 1.
    const std::string path = (s.dir / "halves.exr").string();
    Image halves(64, 8, 3, 0.0f);
    for (int y = 0; y < 8; ++y)
        for (int x = 32; x < 64; ++x)
            for (int c = 0; c < 3; ++c) halves.pixel(x, y)[c] = 1.0f;
    writeExr(path, halves);
    RelightObject o = loadRelightObject(s.glb, s.prt);
    o.materialMap = loadMaterialMap(o, s.glb, path, "Ketchup", s.prt);
    const MaterialMap& m = *o.materialMap;
    size_t ones = 0, zeros = 0;
    for (float t : m.vertexT) {
        EXPECT_GE(t, 0.0f);
        EXPECT_LE(t, 1.0f);
        ones += t == 1.0f;
        zeros += t == 0.0f;
    }
    EXPECT_GT(ones, m.vertexT.size() / 4);
    EXPECT_GT(zeros, m.vertexT.size() / 4);
    // At a corner, at() is the texture at that corner's coordinate (bilinear, repeating).
    for (uint32_t f = 0; f < 40; ++f) {
        const glm::vec2 uv = m.asset->uvs[3 * f];
        EXPECT_FLOAT_EQ(m.at(f, {1, 0, 0}),
                        std::clamp(sampleTexture(halves, uv, TextureWrap::Repeat, TextureWrap::Repeat).r, 0.0f, 1.0f));
    }
}

TEST(MaterialMap, BadInputsAreRefused) {
    const Scene& s = scene();
    RelightObject o = loadRelightObject(s.glb, s.prt);
    const std::string bad = (s.dir / "bad.exr").string();
    writeExr(bad, Image(2, 2, 3, 1.5f));
    EXPECT_THROW(loadMaterialMap(o, s.glb, bad, "Ketchup", s.prt), Error);
    EXPECT_THROW(loadMaterialMap(o, s.glb, (s.dir / "missing.exr").string(), "Ketchup", s.prt), Error);
    EXPECT_THROW(loadMaterialMap(o, s.glb, constantMap("z.exr", 0.0f), "no such material", s.prt), Error);
    // An asset without texture coordinates.
    const std::string obj = (s.dir / "sphere.obj").string();
    saveMesh(makeIcosphere(2, 5.0f), obj);
    RelightObject plain = loadRelightObject(obj, s.prt);
    EXPECT_THROW(loadMaterialMap(plain, obj, constantMap("z2.exr", 0.0f), "Ketchup", s.prt), Error);
}

// The reference's blend at a pixel: (1 - t) first + t second, exactly, whatever t.
TEST(MaterialMap, ReferenceBlendIsTheConvexCombination) {
    struct Fixed : ReferenceComponent {
        glm::dvec3 v, var;
        std::string name() const override { return "fixed"; }
        RadianceEstimate radiance(const GBufferPixel&) const override { return {v, var}; }
    };
    Fixed a, b;
    a.v = {1, 2, 3};
    a.var = {0.04, 0.04, 0.04};
    b.v = {5, 6, 7};
    b.var = {0.16, 0.16, 0.16};
    for (float t : {0.0f, 0.25f, 1.0f}) {
        const MaterialBlendComponent blend(a, b, [t](const GBufferPixel&) { return t; });
        const RadianceEstimate r = blend.radiance(GBufferPixel{});
        EXPECT_DOUBLE_EQ(r.value.x, (1 - t) * 1.0 + t * 5.0);
        EXPECT_NEAR(r.variance.x, std::pow((1 - t) * 0.2 + t * 0.4, 2), 1e-12);
    }
}

// With the sun split the lights' sum is made for A and B and blended with the same t:
// a map of 0 is A's split frame exactly, a map of 1 B's to float rounding, a map of 1/2
// their mean.
TEST(MaterialMap, SunSplitBlendsTheLightsLikeTheTransport) {
    const Scene& s = scene();
    RelightObject a = loadRelightObject(s.glb, s.prt);
    const Image plainA = renderSplitWith(a);
    RelightObject zero = loadRelightObject(s.glb, s.prt);
    zero.materialMap = loadMaterialMap(zero, s.glb, constantMap("split_zero.exr", 0.0f), "Ketchup", s.prt);
    EXPECT_EQ(renderSplitWith(zero).pixels, plainA.pixels);

    RelightObject b = loadRelightObject(s.glb, s.prt);
    setObjectMaterial(b, parseMaterial("Ketchup", b.eta), objectSizeMm(b), s.prt);
    const Image plainB = renderSplitWith(b);
    RelightObject one = loadRelightObject(s.glb, s.prt);
    one.materialMap = loadMaterialMap(one, s.glb, constantMap("split_one.exr", 1.0f), "Ketchup", s.prt);
    {
        // t interpolated at a pixel is 1 to float rounding (the barycentrics' sum).
        const Image oneFrame = renderSplitWith(one);
        double d = 0.0, pk = 0.0;
        for (size_t k = 0; k < oneFrame.pixels.size(); ++k) {
            d = std::max(d, double(std::abs(oneFrame.pixels[k] - plainB.pixels[k])));
            pk = std::max(pk, double(std::abs(plainB.pixels[k])));
        }
        EXPECT_LE(d, 1e-6 * pk);
    }

    RelightObject half = loadRelightObject(s.glb, s.prt);
    half.materialMap = loadMaterialMap(half, s.glb, constantMap("split_half.exr", 0.5f), "Ketchup", s.prt);
    const Image mean = renderSplitWith(half);
    double worst = 0.0, peak = 0.0, apart = 0.0;
    for (size_t k = 0; k < mean.pixels.size(); ++k) {
        if (k % 4 == 3 || mean.pixels[k - k % 4 + 3] != 1.0f) continue;  // object pixels' RGB
        worst = std::max(worst, double(std::abs(mean.pixels[k] - 0.5f * (plainA.pixels[k] + plainB.pixels[k]))));
        peak = std::max(peak, double(plainA.pixels[k]));
        apart = std::max(apart, double(std::abs(plainA.pixels[k] - plainB.pixels[k])));
    }
    EXPECT_LT(worst, 1e-5 * peak);
    EXPECT_GT(apart, 0.05 * peak) << "the two materials differ, so the test can fail";
}
