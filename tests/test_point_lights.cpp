// Lights, their parsing, the inside test and the direct irradiance of pass 1
// (relight/pointlight/point_lights.h). Physics asserted: the inverse-square law with the exact
// Fresnel transmittance and the mm -> m^2 factor, shadows, a far point light equal to a
// directional light, area-preserving samples, thread-count independence.

#include "relight/pointlight/point_lights.h"

#include <gtest/gtest.h>

#include <unistd.h>
#include <tbb/global_control.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "common/bssrdf.h"
#include "common/error.h"
#include "common/sampling.h"
#include "common/shapes.h"
#include "common/util.h"

using namespace prt;

namespace {

// Appends b to a (indices shifted), keeping per-vertex normals.
void append(TriangleMesh& a, const TriangleMesh& b, const glm::vec3& offset) {
    const uint32_t base = uint32_t(a.positions.size());
    for (const glm::vec3& p : b.positions) a.positions.push_back(p + offset);
    for (const glm::vec3& n : b.normals) a.normals.push_back(n);
    for (const glm::uvec3& t : b.triangles) a.triangles.push_back(t + glm::uvec3(base));
}

// Expects a prt::Error whose message is one line and contains `needle`.
template <class F>
void expectError(F&& f, const std::string& needle) {
    try {
        f();
        ADD_FAILURE() << "no error; expected one mentioning '" << needle << "'";
    } catch (const Error& e) {
        const std::string what = e.what();
        EXPECT_EQ(what.find('\n'), std::string::npos) << what;
        EXPECT_NE(what.find(needle), std::string::npos) << what;
    }
}

}  // namespace

// ---------------------------------------------------------------------------
// Parsing
// ---------------------------------------------------------------------------

TEST(PointLights, ParsesPointAndDirectionalLights) {
    const Light p = parseLight("point:10,-20.5,3e2:1,2,3");
    EXPECT_EQ(p.type, LightType::Point);
    EXPECT_EQ(p.position, glm::dvec3(10, -20.5, 300));
    EXPECT_EQ(p.rgb, glm::dvec3(1, 2, 3));
    EXPECT_NE(p.source.find("point:10"), std::string::npos);

    const Light d = parseLight(" DIR : 0, 2, 0 : 500 ");
    EXPECT_EQ(d.type, LightType::Directional);
    EXPECT_EQ(d.direction, glm::dvec3(0, 1, 0));  // normalised
    EXPECT_EQ(d.rgb, glm::dvec3(500));            // one value = gray

    const Light d2 = parseLight("directional:1,1,0:+1,0,0.5");
    EXPECT_NEAR(glm::length(d2.direction), 1.0, 1e-15);
    EXPECT_NEAR(d2.direction.x, std::sqrt(0.5), 1e-15);
    EXPECT_EQ(d2.rgb, glm::dvec3(1, 0, 0.5));
    EXPECT_NE(describe(p).find("W/sr"), std::string::npos);
    EXPECT_NE(describe(d).find("W/m^2"), std::string::npos);
}

TEST(PointLights, BadLightStringsAreOneLineErrors) {
    const std::vector<std::pair<std::string, std::string>> bad = {
        {"", "TYPE:X,Y,Z"},
        {"point", "TYPE:X,Y,Z"},
        {"point:1,2,3", "TYPE:X,Y,Z"},
        {"point:1,2,3:1,1,1:4", "TYPE:X,Y,Z"},
        {"area:1,2,3:1,1,1", "unknown light type"},
        {"point:1,2:1,1,1", "position needs 3"},
        {"point:1,2,3,4:1,1,1", "position needs 3"},
        {"point:1,,3:1,1,1", "empty number"},
        {"point:1,2,x:1,1,1", "not a number"},
        {"point:1,2,3mm:1,1,1", "not a number"},
        {"point:nan,2,3:1,1,1", "finite"},
        {"point:inf,2,3:1,1,1", "finite"},
        {"point:1,2,3:1,1", "1 (gray) or 3"},
        {"point:1,2,3:-1,1,1", ">= 0"},
        {"point:1,2,3:1,nan,1", ">= 0"},
        {"dir:0,0,0:1", "not be zero"},
        {"dir:0,1:1", "direction needs 3"},
        {"dir:0,1,0:-5", ">= 0"},
    };
    for (const auto& [text, needle] : bad) {
        SCOPED_TRACE(text);
        expectError([&] { parseLight(text); }, needle);
        // The message names the offending option value.
        try {
            parseLight(text);
        } catch (const Error& e) {
            EXPECT_EQ(e.subject(), "--light " + text);
        }
    }
}

TEST(PointLights, ParsesJsonScene) {
    const std::string json = R"({ "lights": [
        { "type": "point", "position": [0, 100, -50], "intensity": [1, 0.5, 0.25] },
        { "type": "directional", "direction": [0, 0, 3], "irradiance": 200 } ] })";
    const std::vector<Light> lights = parseLightScene(json, "s.json");
    ASSERT_EQ(lights.size(), 2u);
    EXPECT_EQ(lights[0].type, LightType::Point);
    EXPECT_EQ(lights[0].position, glm::dvec3(0, 100, -50));
    EXPECT_EQ(lights[0].rgb, glm::dvec3(1, 0.5, 0.25));
    EXPECT_EQ(lights[1].type, LightType::Directional);
    EXPECT_EQ(lights[1].direction, glm::dvec3(0, 0, 1));
    EXPECT_EQ(lights[1].rgb, glm::dvec3(200));
    EXPECT_EQ(lights[1].source, "s.json: lights[1]");
    EXPECT_TRUE(parseLightScene(R"({"lights": []})").empty());

    // Round trip through a file.
    const std::filesystem::path dir =
        std::filesystem::temp_directory_path() / ("prt_point_lights_" + std::to_string(::getpid()));
    std::filesystem::create_directories(dir);
    const std::string path = (dir / "scene.json").string();
    std::ofstream(path) << json;
    EXPECT_EQ(loadLightScene(path).size(), 2u);
    expectError([&] { loadLightScene((dir / "missing.json").string()); }, "cannot open");
    std::filesystem::remove_all(dir);
}

TEST(PointLights, BadJsonScenesAreOneLineErrors) {
    const std::vector<std::pair<std::string, std::string>> bad = {
        {"{", "not valid JSON"},
        {"[]", "JSON object"},
        {R"({"light": []})", "unknown key \"light\""},
        {R"({})", "\"lights\" must be a list"},
        {R"({"lights": {}})", "\"lights\" must be a list"},
        {R"({"lights": [3]})", "lights[0]: must be an object"},
        {R"({"lights": [{"position": [0,0,0], "intensity": 1}]})", "needs \"type\""},
        {R"({"lights": [{"type": "area", "position": [0,0,0], "intensity": 1}]})", "unknown type"},
        {R"({"lights": [{"type": "point", "intensity": 1}]})", "missing \"position\""},
        {R"({"lights": [{"type": "point", "position": [0,0,0]}]})", "missing \"intensity\""},
        {R"({"lights": [{"type": "point", "position": [0,0], "intensity": 1}]})", "position needs 3"},
        {R"({"lights": [{"type": "point", "position": [0,0,"a"], "intensity": 1}]})", "numbers only"},
        {R"({"lights": [{"type": "point", "position": 5, "intensity": 1}]})", "list of numbers"},
        {R"({"lights": [{"type": "point", "position": [0,0,0], "intensity": -1}]})", ">= 0"},
        {R"({"lights": [{"type": "point", "position": [0,0,0], "intensty": 1}]})", "unknown key \"intensty\""},
        {R"({"lights": [{"type": "point", "position": [0,0,0], "irradiance": 1}]})", "unknown key \"irradiance\""},
        {R"({"lights": [{"type": "directional", "direction": [0,0,0], "irradiance": 1}]})", "not be zero"},
        {R"({"lights": [{"type": "point", "position": [0,0,0], "intensity": 1},
                        {"type": "directional", "direction": [0,1,0], "irradiance": [1,2]}]})",
         "lights[1]"},
    };
    for (const auto& [text, needle] : bad) {
        SCOPED_TRACE(text);
        expectError([&] { parseLightScene(text, "scene.json"); }, needle);
    }
}

TEST(PointLights, ParsesOptionWords) {
    EXPECT_EQ(parseFresnelModel("Exact"), FresnelModel::Exact);
    EXPECT_EQ(parseFresnelModel("keng"), FresnelModel::Keng);
    expectError([] { parseFresnelModel("schlick"); }, "--fresnel");
    EXPECT_EQ(parseSampleSource("faces"), SampleSource::FaceCentroids);
    EXPECT_EQ(parseSampleSource("Poisson"), SampleSource::PoissonDisk);
    expectError([] { parseSampleSource("random"); }, "--samples");
}

// ---------------------------------------------------------------------------
// Inside / outside
// ---------------------------------------------------------------------------

TEST(PointLights, InsideTestOnSphereAndTorus) {
    const RayScene sphere(makeIcosphere(3, 10.0f));
    EXPECT_TRUE(insideClosedSurface(sphere, {0, 0, 0}));
    EXPECT_TRUE(insideClosedSurface(sphere, {0, 9.5, 0}));
    EXPECT_TRUE(insideClosedSurface(sphere, {3, -4, 5}));
    EXPECT_FALSE(insideClosedSurface(sphere, {0, 10.5, 0}));
    EXPECT_FALSE(insideClosedSurface(sphere, {100, 0, 0}));
    EXPECT_FALSE(insideClosedSurface(sphere, {-7.5, 7.5, 7.5}));

    // A torus (R = 20, r = 5 around +Y): the hole and the outside are outside, the tube inside.
    const RayScene torus(makeTorus(20.0f, 5.0f, 64, 32));
    EXPECT_FALSE(insideClosedSurface(torus, {0, 0, 0}));
    EXPECT_FALSE(insideClosedSurface(torus, {0, 10, 20}));
    EXPECT_TRUE(insideClosedSurface(torus, {20, 0, 0}));
    EXPECT_TRUE(insideClosedSurface(torus, {0, 2, -22}));
    // Along the axes (rays in the parity directions still cross edges of the grid mesh).
    for (int i = 0; i < 16; ++i) {
        const double a = 2 * kPi * i / 16;
        EXPECT_TRUE(insideClosedSurface(torus, {20 * std::cos(a), 0, 20 * std::sin(a)})) << i;
        EXPECT_FALSE(insideClosedSurface(torus, {27 * std::cos(a), 0, 27 * std::sin(a)})) << i;
        EXPECT_FALSE(insideClosedSurface(torus, {13 * std::cos(a), 0, 13 * std::sin(a)})) << i;
    }
}

TEST(PointLights, LightInsideTheObjectIsRefused) {
    const RayScene sphere(makeIcosphere(3, 10.0f));
    const std::vector<Light> ok = {parseLight("point:0,30,0:1"), parseLight("dir:0,-1,0:1")};
    EXPECT_NO_THROW(checkLightsOutside(sphere, ok));
    const std::vector<Light> bad = {parseLight("point:0,30,0:1"), parseLight("point:1,2,3:1")};
    expectError([&] { checkLightsOutside(sphere, bad); }, "inside the object");
    expectError([&] { checkLightsOutside(sphere, bad); }, "--light point:1,2,3:1");
}

// ---------------------------------------------------------------------------
// Direct irradiance
// ---------------------------------------------------------------------------

// A large slab whose top face is the plane y = 5, lit by an unoccluded point light:
// E^ = F_t(eta, cos) I cos / r^2 * 1e6 exactly, cos = n . w with n = +Y.
TEST(PointLights, InverseSquareLawWithExactFresnelOnAPlane) {
    const TriangleMesh slab = makeSlab(400.0f, 400.0f, 10.0f, 4);
    const RayScene scene(slab);
    const glm::dvec3 intensity(2.0, 1.0, 0.5);
    const std::vector<Light> lights = {pointLight({30.0, 80.0, -20.0}, intensity)};
    const double eta = 1.3;
    for (const glm::vec3 p : {glm::vec3(0, 5, 0), glm::vec3(30, 5, -20), glm::vec3(-150, 5, 120),
                              glm::vec3(180, 5, 170)}) {
        SCOPED_TRACE(p.x);
        const SurfacePoint x{p, {0, 1, 0}, {0, 1, 0}};
        const glm::dvec3 d = lights[0].position - glm::dvec3(p);
        const double r2 = glm::dot(d, d);
        const double cosT = d.y / std::sqrt(r2);
        const glm::dvec3 expected = intensity * cosT / r2 * 1e6 * fresnelTransmittance(eta, cosT);
        const glm::dvec3 e = directIrradiance(scene, lights, x, eta, FresnelModel::Exact);
        for (int c = 0; c < 3; ++c) EXPECT_NEAR(e[c], expected[c], 1e-13 * expected[c]);
        // Keng's diffuse transmittance instead of the exact one.
        const glm::dvec3 keng = directIrradiance(scene, lights, x, eta, FresnelModel::Keng);
        const double fdt = 1.0 - fresnelDiffuseReflectance(eta);
        for (int c = 0; c < 3; ++c) EXPECT_NEAR(keng[c], expected[c] / fresnelTransmittance(eta, cosT) * fdt, 1e-13 * expected[c]);
    }
    // Two lights add; a light below the horizon adds nothing.
    const std::vector<Light> two = {lights[0], pointLight({0, -50, 0}, glm::dvec3(100.0)), lights[0]};
    const SurfacePoint x{{0, 5, 0}, {0, 1, 0}, {0, 1, 0}};
    const glm::dvec3 one = directIrradiance(scene, lights, x, eta, FresnelModel::Exact);
    const glm::dvec3 sum = directIrradiance(scene, two, x, eta, FresnelModel::Exact);
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(sum[c], 2 * one[c], 1e-13 * one[c]);
    // A directional light: E^ = F_t(eta, cos) E_perp cos.
    const glm::dvec3 w = glm::normalize(glm::dvec3(1, 2, 0));
    const std::vector<Light> sun = {directionalLight(w, glm::dvec3(1000.0))};
    const glm::dvec3 es = directIrradiance(scene, sun, x, eta, FresnelModel::Exact);
    EXPECT_NEAR(es.x, 1000.0 * w.y * fresnelTransmittance(eta, w.y), 1e-10);
}

TEST(PointLights, ShadowedPointGetsZero) {
    // A 20 x 2 x 20 mm box floating 30 mm above the slab's top face, the light above it.
    TriangleMesh mesh = makeSlab(400.0f, 400.0f, 10.0f, 4);
    append(mesh, makeBox({20.0f, 2.0f, 20.0f}), {0.0f, 35.0f, 0.0f});
    const RayScene scene(mesh);
    const std::vector<Light> lights = {pointLight({0, 100, 0}, glm::dvec3(1.0)),
                                       directionalLight({0, 1, 0}, glm::dvec3(10.0))};
    const SurfacePoint under{{2, 5, -3}, {0, 1, 0}, {0, 1, 0}};
    EXPECT_EQ(directIrradiance(scene, lights, under, 1.3, FresnelModel::Exact), glm::dvec3(0.0));
    const SurfacePoint open{{100, 5, 0}, {0, 1, 0}, {0, 1, 0}};
    const glm::dvec3 e = directIrradiance(scene, lights, open, 1.3, FresnelModel::Exact);
    EXPECT_GT(e.x, 10.0 * fresnelTransmittance(1.3, 1.0) * 0.999);
    // The bottom of the slab, facing away from both lights.
    const SurfacePoint bottom{{0, -5, 0}, {0, -1, 0}, {0, -1, 0}};
    EXPECT_EQ(directIrradiance(scene, lights, bottom, 1.3, FresnelModel::Exact), glm::dvec3(0.0));
    // The light itself behind an occluder that lies BEYOND the light does not shadow.
    const std::vector<Light> low = {pointLight({0, 20, 0}, glm::dvec3(1.0))};
    EXPECT_GT(directIrradiance(scene, low, under, 1.3, FresnelModel::Exact).x, 0.0);
}

TEST(PointLights, FarPointLightEqualsDirectionalLight) {
    TriangleMesh mesh = makeIcosphere(3, 10.0f);
    append(mesh, makeBox({8.0f, 8.0f, 8.0f}), {0.0f, 0.0f, 20.0f});  // casts a shadow
    const RayScene scene(mesh);
    IrradianceSamples a = faceCentroidSamples(mesh);
    IrradianceSamples b = a;
    const glm::dvec3 w = glm::normalize(glm::dvec3(0.3, 0.4, 1.0));
    const double D = 1.0e6;                                  // mm
    const glm::dvec3 e(300.0, 200.0, 100.0);                 // W/m^2
    const glm::dvec3 intensity = e * (D * D / 1.0e6);        // W/sr giving e at distance D
    computeIrradiance(a, scene, {pointLight(D * w, intensity)}, 1.3, FresnelModel::Exact);
    computeIrradiance(b, scene, {directionalLight(w, e)}, 1.3, FresnelModel::Exact);
    size_t lit = 0, shadowed = 0;
    for (size_t i = 0; i < a.size(); ++i) {
        for (int c = 0; c < 3; ++c) EXPECT_NEAR(a.irradiance[i][c], b.irradiance[i][c], 2e-4 * e[c]) << i;
        const bool facing = glm::dot(glm::dvec3(a.normals[i]), w) > 0.05;
        if (facing && b.irradiance[i].x > 0) ++lit;
        if (facing && b.irradiance[i].x == 0) ++shadowed;
    }
    EXPECT_GT(lit, 100u);
    EXPECT_GT(shadowed, 10u);  // the box's shadow on the sphere
}

// ---------------------------------------------------------------------------
// Samples
// ---------------------------------------------------------------------------

TEST(PointLights, FaceCentroidSamplesCarryFaceAreas) {
    const TriangleMesh mesh = makeBox({40.0f, 10.0f, 20.0f}, {1, 3, 7});  // very unequal faces
    const IrradianceSamples s = faceCentroidSamples(mesh);
    ASSERT_EQ(s.size(), mesh.triangleCount());
    EXPECT_NEAR(s.totalArea(), totalArea(mesh), 1e-6 * totalArea(mesh));  // float areas
    EXPECT_NEAR(s.totalArea(), 2.0 * (40 * 10 + 40 * 20 + 10 * 20), 1e-3);
    for (size_t i = 0; i < s.size(); ++i) {
        const glm::uvec3 t = mesh.triangles[s.triangles[i]];
        const glm::vec3 c = (mesh.positions[t.x] + mesh.positions[t.y] + mesh.positions[t.z]) / 3.0f;
        EXPECT_NEAR(glm::length(s.positions[i] - c), 0.0f, 1e-5f);
        EXPECT_NEAR(s.areas[i], faceArea(mesh, s.triangles[i]), 1e-6f * s.areas[i]);
        EXPECT_NEAR(glm::length(s.normals[i]), 1.0f, 1e-6f);
        EXPECT_GT(glm::dot(s.normals[i], s.geometricNormals[i]), 0.99f);  // flat box
    }
    // A degenerate face gets no sample.
    TriangleMesh withDegenerate = mesh;
    withDegenerate.triangles.push_back({0, 0, 1});
    EXPECT_EQ(faceCentroidSamples(withDegenerate).size(), mesh.triangleCount());
}

TEST(PointLights, SampleSetSamplesUseAreaPerSample) {
    const TriangleMesh mesh = makeIcosphere(3, 10.0f);
    const SampleSet set = poissonDiskSamples(mesh, 500, 7);
    const IrradianceSamples s = samplesFromSampleSet(set);
    ASSERT_EQ(s.size(), 500u);
    for (size_t i = 0; i < s.size(); ++i) {
        EXPECT_EQ(s.areas[i], float(set.areaPerSample));
        EXPECT_EQ(s.positions[i], set.samples[i].position);
    }
    EXPECT_NEAR(s.totalArea(), totalArea(mesh), 1e-5 * totalArea(mesh));
}

// computeIrradiance traces directIrradiance's shadow rays in packets (the point-light
// ray rescaled so that t = 1 is the light): the same values, up to a ray grazing an
// edge that rounding sends the other way.
TEST(PointLights, BatchedIrradianceMatchesDirectIrradiance) {
    const TriangleMesh mesh = makeTorus(20.0f, 6.0f, 96, 48);
    const RayScene scene(mesh);
    const std::vector<Light> lights = {parseLight("point:40,60,30:2,1,1"), parseLight("dir:-1,0.5,0.2:100")};
    IrradianceSamples s = faceCentroidSamples(mesh);
    computeIrradiance(s, scene, lights, 1.3, FresnelModel::Exact);
    size_t differ = 0, lit = 0;
    for (size_t i = 0; i < s.size(); ++i) {
        const glm::dvec3 ref =
            directIrradiance(scene, lights, {s.positions[i], s.normals[i], s.geometricNormals[i]}, 1.3, FresnelModel::Exact);
        const glm::dvec3 got(s.irradiance[i]);
        if (glm::length(got - ref) > 1e-5 * (glm::length(ref) + 1e-30)) ++differ;
        lit += ref.x > 0.0 ? 1 : 0;
    }
    EXPECT_GT(lit, s.size() / 4);
    EXPECT_LE(differ, s.size() / 1000) << differ << " of " << s.size();
}

TEST(PointLights, IrradianceIsIndependentOfThreadCount) {
    const TriangleMesh mesh = makeTorus(20.0f, 6.0f, 96, 48);
    const RayScene scene(mesh);
    const std::vector<Light> lights = {parseLight("point:40,60,30:2,1,1"), parseLight("dir:-1,0.5,0.2:100")};
    IrradianceSamples many = faceCentroidSamples(mesh);
    IrradianceSamples one = many;
    computeIrradiance(many, scene, lights, 1.3, FresnelModel::Exact);
    {
        tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 1);
        computeIrradiance(one, scene, lights, 1.3, FresnelModel::Exact);
    }
    ASSERT_EQ(many.irradiance.size(), one.irradiance.size());
    size_t lit = 0;
    for (size_t i = 0; i < one.size(); ++i) {
        EXPECT_EQ(many.irradiance[i], one.irradiance[i]);
        lit += one.irradiance[i].x > 0 ? 1 : 0;
    }
    EXPECT_GT(lit, one.size() / 4);
    EXPECT_LT(lit, one.size());  // the torus shadows itself and faces away in places
}
