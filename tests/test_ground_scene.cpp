// The ground under the object (common/ground.h, precompute/passes/diffuse_baseline.h's
// groundTransport, relight/prt/ground_receiver.h): the object's shadow on the plane
// against the closed form of a sphere's form factor and against the reference's own
// Monte Carlo trace; the two files of a precompute with --ground and the checks that
// keep them together; the rendered plane.

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>

#include "common/envmap.h"
#include "common/error.h"
#include "common/ground.h"
#include "common/mesh_io.h"
#include "common/progress.h"
#include "common/shapes.h"
#include "common/util.h"
#include "precompute/job/pipeline.h"
#include "precompute/passes/diffuse_baseline.h"
#include "relight/combined/sun_split_frame.h"
#include "relight/prt/environment_frame.h"
#include "relight/prt/light_vector.h"
#include "relight/prt/relight_kernel.h"
#include "relight/prt/relight_object.h"
#include "tools/reference/reference.h"

using namespace prt;
namespace fs = std::filesystem;

namespace {

VertexRadiance relit(const TransportFile& file, const Image& environment) {
    const LightVector light = makeLightVector(environment, int(file.cubemapSize));
    VertexRadiance radiance;
    relightVertices(file, light, ScatteringComponents{true, false}, radiance);
    return radiance;
}

struct SphereOnGround {
    TriangleMesh sphere;
    GroundPlane plane;
    TriangleMesh ground;
    TransportFile file;
};

SphereOnGround sphereOnGround(int cells, double halfExtentPerDiagonal, const glm::dvec3& albedo, int cubemapSize) {
    SphereOnGround s;
    s.sphere = makeIcosphere(4, 10.0f);
    GroundSettings settings;
    settings.cells = cells;
    settings.halfExtentPerDiagonal = halfExtentPerDiagonal;
    settings.albedo = albedo;
    s.plane = groundPlaneUnder(bounds(s.sphere), settings);
    s.ground = groundMesh(s.plane);
    const RayScene scene(withGround(s.sphere, s.ground));
    DiffuseBaselineOptions o;
    o.albedo = albedo;
    o.cubemapSize = cubemapSize;
    s.file = groundTransport(s.plane, scene, {s.sphere.vertexCount(), 7}, o);
    return s;
}

fs::path tempDir() {
    fs::path d = fs::temp_directory_path() / ("prt_test_ground_" + std::to_string(getpid()));
    fs::create_directories(d);
    return d;
}

// The job of the tests below: a sphere of radius 5 mm (162 vertices, Skin1) on a plane
// of 40 x 40 cells and albedo (0.2, 0.4, 0.8), 6 x 16 x 16 cubemap, 128 terms.
PrecomputeSettings sphereOnPlaneJob(const fs::path& dir) {
    PrecomputeSettings s;
    s.meshPath = (dir / "sphere.obj").string();
    saveMesh(makeIcosphere(2, 5.0f), s.meshPath);
    s.outputPath = (dir / "sphere.prt").string();
    s.scale.mmPerUnit = 1.0;
    s.material = materialByName("Skin1");
    s.cubemapSize = 16;
    s.samples.count = 300;
    s.pass1.sampleCoefficients = s.pass2.nodeCoefficients = s.vertexCoefficients = 128;
    s.ground = GroundSettings{};
    s.ground->cells = 40;
    s.ground->albedo = {0.2, 0.4, 0.8};
    return s;
}

// Looking straight down at the plane from 30 mm, 90 degrees, `size` pixels square.
Camera topCamera(int size) {
    Camera camera;
    camera.eye = {0.0, 30.0, 0.1};
    camera.target = {0.0, 0.0, 0.0};
    camera.fovY = 90.0;
    camera.width = camera.height = size;
    return camera;
}

}  // namespace

// A point of the plane sees a sphere resting on it wholly above its horizon, so the
// sphere hides the fraction cos(theta) (R / d)^2 of its irradiance (the form factor of
// a sphere from a differential area: d the distance to the centre, theta the centre's
// angle from the normal). Under a constant radiance L the ground's radiance is
// albedo L (1 - cos(theta) R^2 / d^2) at every vertex.
TEST(GroundScene, SphereShadowOnThePlaneMatchesItsFormFactor) {
    const glm::dvec3 albedo(0.3, 0.5, 0.7);
    const SphereOnGround s = sphereOnGround(16, 1.0, albedo, 32);
    EXPECT_EQ(s.file.parameter("receiver"), "ground");
    EXPECT_EQ(s.file.parameter(kGroundPlaneParameter), formatGroundPlane(s.plane));
    EXPECT_EQ(s.file.parameter(kGroundObjectParameter), groundObjectText({s.sphere.vertexCount(), 7}));
    const glm::vec3 L(2.0f, 1.0f, 0.5f);
    const VertexRadiance r = relit(s.file, constantEnvironment(64, L));
    ASSERT_EQ(r.diffuse.size(), s.ground.vertexCount());
    // The icosphere's own radius: its vertices lie on R, its faces a little inside.
    const double R = 10.0;
    double worst = 0.0, darkest = 1.0;
    for (size_t v = 0; v < s.ground.vertexCount(); ++v) {
        const glm::dvec3 toCentre = glm::dvec3(0.0) - glm::dvec3(s.ground.positions[v]);
        const double d = glm::length(toCentre);
        const double visible = 1.0 - (toCentre.y / d) * (R * R) / (d * d);
        darkest = std::min(darkest, visible);
        for (int c = 0; c < 3; ++c) {
            const double expected = albedo[c] * L[c] * visible;
            worst = std::max(worst, std::abs(r.diffuse[v][c] - expected) / (albedo[c] * L[c]));
        }
    }
    std::printf("ground under a sphere: worst |error| %.4f of albedo x L, darkest vertex sees %.3f\n", worst, darkest);
    // The contact point sees almost nothing (the sphere covers its sky but a sliver).
    EXPECT_LT(darkest, 0.05);
    // The cubemap's horizon texels and the truncation to 128 terms (the shadow's edge is
    // a circle of the sphere on the cubemap), and the faceted sphere: within 2% of
    // albedo x L at every vertex.
    EXPECT_LT(worst, 2e-2);
}

// Under a sky with a sun (a hard shadow), every ground vertex against the reference's
// Monte Carlo estimate of its irradiance traced in the same object + plane scene (eta
// = 1, its own directions): no cubemap, no Haar truncation. Shared: the mesh of object
// and plane, the vertex positions and normals, the ray offsets.
TEST(GroundScene, ShadowUnderASunMatchesTheMonteCarloTrace) {
    const glm::dvec3 albedo(0.6);
    const SphereOnGround s = sphereOnGround(24, 1.0, albedo, 32);
    Image sky = constantEnvironment(256, {0.6f, 0.7f, 0.9f});
    const Image sun = sunEnvironment(256, glm::normalize(glm::dvec3(0.5, 1.0, 0.2)), {60.0f, 55.0f, 45.0f});
    for (size_t i = 0; i < sky.pixels.size(); ++i) sky.pixels[i] += sun.pixels[i];
    const VertexRadiance r = relit(s.file, sky);
    const RayScene scene(withGround(s.sphere, s.ground));
    const EnvironmentSampler sampler(sky);
    IrradianceEstimatorOptions mc;
    mc.directions = 16384;
    mc.seed = 12345;
    double num = 0.0, den = 0.0, noise = 0.0, brightest = 0.0;
    std::vector<double> green;
    for (size_t v = 0; v < s.ground.vertexCount(); ++v) {
        const glm::vec3 up(0, 1, 0);
        const IrradianceEstimate e = estimateIrradiance(sampler, &scene, s.ground.positions[v], up, up, 1.0, mc, v);
        const glm::dvec3 reference = albedo / kPi * e.value;
        for (int c = 0; c < 3; ++c) {
            num += std::pow(r.diffuse[v][c] - reference[c], 2);
            den += reference[c] * reference[c];
            noise += std::pow(albedo[c] / kPi, 2) * e.variance[c];
        }
        green.push_back(reference.g);
        brightest = std::max(brightest, reference.g);
    }
    size_t shadowed = 0, lit = 0;
    for (double v : green) (v < 0.6 * brightest ? shadowed : lit) += 1;
    const double error = std::sqrt(num / den), floor = std::sqrt(noise / den);
    std::printf("ground under a sun: rel RMSE %.4f against Monte Carlo (its noise %.4f), %zu shadowed and %zu lit "
                "vertices\n",
                error, floor, shadowed, lit);
    EXPECT_GT(shadowed, 10u);
    EXPECT_GT(lit, 10u);
    // The sun is a few texels of the 6 x 32 x 32 cubemap: the shadow's edge moves by up
    // to a texel, and 128 terms keep most of the rest (measured 0.7%, the Monte Carlo
    // noise 0.5% of it).
    EXPECT_LT(error, 0.03);
}

// The pipeline with --ground: two files that belong together, checked when loaded,
// skipped together when up to date; and the rendered plane.
TEST(GroundScene, PrecomputeWritesBothFilesAndTheRendererDrawsThePlane) {
    Progress::setEnabled(false);
    const fs::path dir = tempDir();
    const PrecomputeSettings s = sphereOnPlaneJob(dir);
    const PrecomputeSummary first = precomputeTransport(s, /*force=*/true);
    const std::string groundPath = groundTransportPath(s.outputPath);
    EXPECT_EQ(first.ground.path, groundPath);
    EXPECT_EQ(first.ground.vertices, 1681u);
    ASSERT_TRUE(fs::exists(groundPath));
    EXPECT_TRUE(precomputeTransport(s).skipped);
    // A missing ground file makes the job out of date.
    fs::remove(groundPath);
    EXPECT_FALSE(precomputeTransport(s).skipped);
    ASSERT_TRUE(fs::exists(groundPath));

    RelightObject object = loadRelightObject(s.meshPath, s.outputPath);
    EXPECT_NE(attachGround(object, groundPath, s.outputPath).find("1681 vertices"), std::string::npos);
    ASSERT_TRUE(object.ground.has_value());
    EXPECT_EQ(object.ground->albedo, glm::dvec3(0.2, 0.4, 0.8));

    // Under a constant sky a ground pixel is albedo x L less the sphere's form factor
    // (as SphereShadowOnThePlaneMatchesItsFormFactor): within 3%, the horizon of this
    // job's 6 x 16 x 16 cubemap (2 x 2 sub-directions per texel), its 128 terms, the
    // faceted sphere of 162 vertices and the blend between the plane's vertices.
    const glm::vec3 L(1.0f, 2.0f, 4.0f);
    FrameSettings look;
    EnvironmentFrameRenderer renderer(object, constantEnvironment(64, L), look, ScatteringComponents{true, false});
    const Camera camera = topCamera(64);
    const Image image = renderer.render(camera, glm::dmat3(1.0));
    const GBuffer& g = renderer.gbuffer();
    size_t groundPixels = 0, objectPixels = 0;
    for (int y = 0; y < g.height; ++y)
        for (int x = 0; x < g.width; ++x) {
            const GBufferPixel& p = g.at(x, y);
            if (!p.hit) continue;
            if (!isGroundTriangle(p.triangle, object.mesh.triangleCount())) {
                ++objectPixels;
                continue;
            }
            ++groundPixels;
            const glm::dvec3 toCentre = -glm::dvec3(p.position);
            const double d = glm::length(toCentre);
            const double visible = 1.0 - (toCentre.y / d) * 25.0 / (d * d);
            const float* px = &image.pixels[(size_t(y) * size_t(image.width) + size_t(x)) * size_t(image.channels)];
            for (int c = 0; c < 3; ++c) {
                const double unshadowed = object.ground->albedo[c] * L[c];
                ASSERT_NEAR(px[c], unshadowed * visible, 0.03 * unshadowed) << x << " " << y;
            }
            ASSERT_EQ(px[3], 1.0f);
        }
    EXPECT_GT(objectPixels, 50u);
    EXPECT_GT(groundPixels, 500u);

    // The files are checked against each other.
    RelightObject other = loadRelightObject(s.meshPath, s.outputPath);
    PrecomputeSettings plain = s;
    plain.ground.reset();
    plain.outputPath = (dir / "plain.prt").string();
    precomputeTransport(plain, true);
    RelightObject withoutGround = loadRelightObject(s.meshPath, plain.outputPath);
    try {
        attachGround(withoutGround, groundPath, plain.outputPath);
        ADD_FAILURE() << "a ground for an object precomputed without it was accepted";
    } catch (const Error& e) {
        EXPECT_NE(std::string(e.what()).find("without this ground"), std::string::npos) << e.what();
    }
    EXPECT_EQ(attachGround(withoutGround, "", plain.outputPath), "");
    EXPECT_NE(attachGround(other, "", s.outputPath).find("--ground"), std::string::npos);
    // Another object's ground; the object's own file as a ground.
    PrecomputeSettings bigger = s;
    bigger.meshPath = (dir / "big.obj").string();
    saveMesh(makeIcosphere(2, 6.0f), bigger.meshPath);
    bigger.outputPath = (dir / "big.prt").string();
    precomputeTransport(bigger, true);
    EXPECT_THROW(attachGround(other, groundTransportPath(bigger.outputPath), s.outputPath), Error);
    EXPECT_THROW(attachGround(other, s.outputPath, s.outputPath), Error);
    EXPECT_THROW(attachGround(other, (dir / "missing.ground.prt").string(), s.outputPath), Error);
    // A stale ground: the same object precomputed again with another albedo replaces
    // both files; the old ground file no longer belongs to the new object file.
    fs::copy_file(groundPath, dir / "old.ground.prt");
    PrecomputeSettings repainted = s;
    repainted.ground->albedo = {0.9, 0.9, 0.9};
    precomputeTransport(repainted, true);
    RelightObject fresh = loadRelightObject(s.meshPath, s.outputPath);
    try {
        attachGround(fresh, (dir / "old.ground.prt").string(), s.outputPath);
        ADD_FAILURE() << "a ground file of another job was accepted";
    } catch (const Error& e) {
        EXPECT_NE(std::string(e.what()).find("input digests differ"), std::string::npos) << e.what();
    }
    EXPECT_NO_THROW(attachGround(fresh, groundPath, s.outputPath));
    // Seen from below, the plane's back is black.
    {
        Camera below = camera;
        below.eye = {0.0, -30.0, 0.1};
        EnvironmentFrameRenderer under(fresh, constantEnvironment(64, L), look, ScatteringComponents{true, false});
        const Image dark = under.render(below, glm::dmat3(1.0));
        size_t back = 0;
        for (int y = 0; y < dark.height; ++y)
            for (int x = 0; x < dark.width; ++x) {
                const GBufferPixel& p = under.gbuffer().at(x, y);
                if (!p.hit || !isGroundTriangle(p.triangle, fresh.mesh.triangleCount())) continue;
                ++back;
                const float* px = &dark.pixels[(size_t(y) * size_t(dark.width) + size_t(x)) * size_t(dark.channels)];
                ASSERT_EQ(px[0] + px[1] + px[2], 0.0f);
            }
        EXPECT_GT(back, 500u);
    }
    // A pass-1 file made without the plane is refused by a job with it (its key differs).
    PrecomputeSettings cached = plain;
    cached.pass1File = (dir / "pass1.bin").string();
    precomputeTransport(cached, true);
    PrecomputeSettings cachedGround = s;
    cachedGround.pass1File = cached.pass1File;
    try {
        precomputeTransport(cachedGround, true);
        ADD_FAILURE() << "a pass-1 file made without the ground was reused";
    } catch (const Error& e) {
        EXPECT_NE(std::string(e.what()).find("other pass-1 inputs"), std::string::npos) << e.what();
    }
    // Settings the ground cannot honour.
    PrecomputeSettings shard = s;
    shard.shard = ShardSpec{0, 2};
    EXPECT_THROW(precomputeTransport(shard, true), Error);
    PrecomputeSettings huge = s;
    huge.ground->halfExtentPerDiagonal = 1000.0;
    EXPECT_THROW(precomputeTransport(huge, true), Error);
    fs::remove_all(dir);
}

// The sun split with a ground (relight/combined/sun_split_frame.h): under a one-texel
// sun the lights carry nearly all the light, and a ground pixel is the Lambertian
// albedo / pi E_perp cos(theta) where the sphere does not shadow it and nearly nothing
// where it does (the analytic shadow of the sphere; pixels within 0.6 mm of its edge,
// where the faceted sphere of 162 vertices differs, are skipped). Tolerance: 1% plus
// the residual's share of the light, which the ground's transport still carries.
TEST(GroundScene, SunSplitLightsTheGroundAndCastsTheSpheresShadow) {
    Progress::setEnabled(false);
    const fs::path dir = tempDir();
    const PrecomputeSettings s = sphereOnPlaneJob(dir);
    precomputeTransport(s, /*force=*/true);
    RelightObject object = loadRelightObject(s.meshPath, s.outputPath);
    attachGround(object, groundTransportPath(s.outputPath), s.outputPath);

    const glm::dvec3 toSun = glm::normalize(glm::dvec3(1.0, 0.7, 0.3));  // low: a long shadow
    const Image sky = sunEnvironment(128, toSun, {5000.0f, 5000.0f, 5000.0f});
    SunSplitFrameRenderer renderer(object, sky, FrameSettings{}, ScatteringComponents{true, false}, {},
                                   s.outputPath);
    ASSERT_EQ(renderer.split().lights.size(), 1u);
    const Light& sun = renderer.split().lights[0];
    const double residualShare = 1.0 - renderer.split().lightFraction;
    EXPECT_LT(residualShare, 0.01);
    const Camera camera = topCamera(96);
    const Image image = renderer.render(camera, glm::dmat3(1.0));
    const glm::dvec3 d = sun.direction;  // the sun texel's centre
    const TriangleMesh traced = withGround(object.mesh, object.ground->mesh);
    const GBuffer g = traceGBuffer(RayScene(traced), traced, camera);
    size_t lit = 0, shadowed = 0;
    for (size_t i = 0; i < g.pixels.size(); ++i) {
        const GBufferPixel& p = g.pixels[i];
        if (!p.hit || !isGroundTriangle(p.triangle, object.mesh.triangleCount())) continue;
        // The ray from the ground point toward the sun against the sphere of radius 5.
        const glm::dvec3 o(p.position);
        const double b = glm::dot(o, d), miss = std::sqrt(std::max(0.0, glm::dot(o, o) - b * b));
        if (std::abs(miss - 5.0) < 0.6) continue;
        const bool inShadow = b < 0.0 && miss < 5.0;
        for (int ch = 0; ch < 3; ++ch) {
            const double fromLight = object.ground->albedo[ch] / kPi * sun.rgb[ch] * d.y;
            const double wholeSun = fromLight / (1.0 - residualShare);
            ASSERT_NEAR(image.pixels[i * 4 + size_t(ch)], inShadow ? 0.0 : fromLight,
                        (0.01 + 1.5 * residualShare) * wholeSun)
                << "pixel " << i << (inShadow ? " (shadowed)" : " (lit)");
        }
        ++(inShadow ? shadowed : lit);
    }
    EXPECT_GT(lit, 500u);
    EXPECT_GT(shadowed, 30u);
    fs::remove_all(dir);
}
