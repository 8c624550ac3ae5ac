// A colour texture on a translucent object (relight/render/base_colour.h): the tint at
// the exit point, through the environment renderer, against the untextured frame.

#include "relight/render/base_colour.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <string>

#include "common/asset_io.h"
#include "common/envmap.h"
#include "common/error.h"
#include "common/mesh_io.h"
#include "common/shapes.h"
#include "relight/prt/environment_frame.h"
#include "tests/test_support.h"

using namespace prt;

namespace {

std::filesystem::path scratch(const std::string& name) {
    const auto dir = std::filesystem::current_path() / "test_base_colour_scratch" / name;
    std::filesystem::remove_all(dir);
    std::filesystem::create_directories(dir);
    return dir;
}

// The synthetic sphere of test_environment_frame, and beside it a .glb of the same mesh
// with spherical texture coordinates and `texture` as its base colour.
RelightObject texturedSphere(const std::filesystem::path& dir, const Image& texture) {
    saveMesh(makeIcosphere(3, 2.0f), (dir / "sphere.obj").string());
    const TriangleMesh fileMesh = loadMesh((dir / "sphere.obj").string());
    saveTransportFile((dir / "sphere.prt").string(), test::syntheticFaceTransport(fileMesh, 8, 5.0, 2.0f));
    saveTexturedGltf((dir / "sphere.glb").string(), fileMesh, projectUvs(fileMesh, UvProjection::Spherical), texture);
    return loadRelightObject((dir / "sphere.obj").string(), (dir / "sphere.prt").string());
}

Image uniformTexture(glm::vec3 c) {
    Image t(4, 4, 3);
    for (size_t p = 0; p < 16; ++p)
        for (int k = 0; k < 3; ++k) t.pixels[3 * p + size_t(k)] = c[k];
    return t;
}

Image sky() {
    Image env = twoToneEnvironment(64, {1.2f, 1.0f, 0.8f}, {0.1f, 0.2f, 0.3f});
    const Image sun = sunEnvironment(64, glm::normalize(glm::dvec3(1, 1, 0.3)), {30.0f, 28.0f, 25.0f});
    for (size_t i = 0; i < env.pixels.size(); ++i) env.pixels[i] += sun.pixels[i];
    return env;
}

Image renderFrame(const RelightObject& object, bool specular) {
    FrameSettings look;
    look.specular = specular;
    EnvironmentFrameRenderer renderer(object, sky(), look, ScatteringComponents::all());
    return renderer.render(frameSphere(object.sphereCentre, object.sphereRadius, 20, 10, 30, 48, 40), rotationY(30.0));
}

}  // namespace

// Where the texture is constant c, the textured frame is c times the untextured one
// (the PNG's sRGB texels decode to c' = srgbToLinear(round(255 srgb(c)) / 255), the
// value compared); the background is untouched.
TEST(BaseColour, ConstantTextureScalesTheExitance) {
    const glm::vec3 c(0.8f, 0.45f, 0.2f);
    const auto dir = scratch("constant");
    RelightObject object = texturedSphere(dir, uniformTexture(c));
    const Image plain = renderFrame(object, false);
    object.baseColour = BaseColour::load((dir / "sphere.glb").string(), object.mesh);
    ASSERT_TRUE(object.baseColour.enabled());
    const Image tinted = renderFrame(object, false);
    glm::vec3 decoded;
    for (int k = 0; k < 3; ++k) decoded[k] = srgbToLinear(std::round(linearToSrgb(c[k]) * 255.0f) / 255.0f);
    size_t objectPixels = 0;
    for (int y = 0; y < plain.height; ++y)
        for (int x = 0; x < plain.width; ++x) {
            const bool onObject = plain.at(x, y, 3) > 0.5f;
            objectPixels += onObject ? 1 : 0;
            for (int k = 0; k < 3; ++k) {
                const float expected = onObject ? decoded[k] * plain.at(x, y, k) : plain.at(x, y, k);
                EXPECT_NEAR(tinted.at(x, y, k), expected, 2e-6f * std::max(1.0f, expected)) << x << " " << y;
            }
        }
    EXPECT_GT(objectPixels, 500u);
}

// The specular layer is reflection at the surface: it is not tinted.
TEST(BaseColour, SpecularLayerIsNotTinted) {
    const glm::vec3 c(0.3f, 0.6f, 0.9f);
    const auto dir = scratch("specular");
    RelightObject object = texturedSphere(dir, uniformTexture(c));
    const Image diffuse = renderFrame(object, false), withSpecular = renderFrame(object, true);
    object.baseColour = BaseColour::load((dir / "sphere.glb").string(), object.mesh);
    const Image tinted = renderFrame(object, true);
    double worst = 0.0, specularEnergy = 0.0;
    for (int y = 0; y < diffuse.height; ++y)
        for (int x = 0; x < diffuse.width; ++x) {
            if (!(diffuse.at(x, y, 3) > 0.5f)) continue;
            for (int k = 0; k < 3; ++k) {
                const double cd = srgbToLinear(std::round(linearToSrgb(c[k]) * 255.0f) / 255.0f);
                const double spec = double(withSpecular.at(x, y, k)) - diffuse.at(x, y, k);
                specularEnergy += spec;
                const double expected = cd * diffuse.at(x, y, k) + spec;
                worst = std::max(worst, std::abs(tinted.at(x, y, k) - expected) / std::max(expected, 1e-3));
            }
        }
    EXPECT_GT(specularEnergy, 1.0);  // the layer is there to be left alone
    EXPECT_LT(worst, 1e-5);
}

// A varying texture: every object pixel is the untextured one times baseColorAt at the
// pixel's own triangle and barycentrics (the G-buffer's), so the lookup follows the
// surface point, not the pixel.
TEST(BaseColour, TintFollowsTheExitPoint) {
    const auto dir = scratch("checker");
    RelightObject object = texturedSphere(dir, makeCheckerTexture(64, 8));
    const Image plain = renderFrame(object, false);
    object.baseColour = BaseColour::load((dir / "sphere.glb").string(), object.mesh);
    const Image tinted = renderFrame(object, false);
    const Asset& asset = *object.baseColour.asset();
    const RayScene scene(object.mesh);
    const GBuffer g =
        traceGBuffer(scene, object.mesh, frameSphere(object.sphereCentre, object.sphereRadius, 20, 10, 30, 48, 40));
    size_t checked = 0;
    glm::vec3 lo(1e9f), hi(-1e9f);
    for (int y = 0; y < g.height; ++y)
        for (int x = 0; x < g.width; ++x) {
            const GBufferPixel& p = g.at(x, y);
            if (!p.hit) continue;
            const glm::vec3 c = baseColorAt(asset, p.triangle, p.barycentric);
            lo = glm::min(lo, c);
            hi = glm::max(hi, c);
            for (int k = 0; k < 3; ++k)
                EXPECT_NEAR(tinted.at(x, y, k), c[k] * plain.at(x, y, k), 2e-6f * std::max(1.0f, plain.at(x, y, k)));
            ++checked;
        }
    EXPECT_GT(checked, 500u);
    EXPECT_GT(hi.r - lo.r, 0.3f);  // the checker does vary over the frame
}

// An asset whose mesh is not the object's is refused, naming the asset.
TEST(BaseColour, AnotherMeshIsRefused) {
    const auto dir = scratch("mismatch");
    const RelightObject object = texturedSphere(dir, uniformTexture(glm::vec3(0.5f)));
    const TriangleMesh other = makeIcosphere(2, 2.0f);
    saveTexturedGltf((dir / "other.glb").string(), other, projectUvs(other, UvProjection::Box),
                     uniformTexture(glm::vec3(0.5f)));
    try {
        BaseColour::load((dir / "other.glb").string(), object.mesh);
        FAIL() << "accepted";
    } catch (const Error& e) {
        EXPECT_EQ(e.subject(), (dir / "other.glb").string());
        EXPECT_NE(std::string(e.what()).find("is not the object's"), std::string::npos) << e.what();
    }
    // Without texture coordinates (a plain mesh file) the factor, white, is the colour.
    const BaseColour plain = BaseColour::load((dir / "sphere.obj").string(), object.mesh);
    GBufferPixel p;
    p.hit = true;
    p.triangle = 0;
    p.barycentric = glm::vec3(1.0f / 3.0f);
    EXPECT_EQ(plain.at(p), glm::vec3(1.0f));
}
