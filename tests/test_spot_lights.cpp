// Spot lights (relight/pointlight/point_lights.h, SPOT LIGHTS): inside the inner cone a
// spot is the point light of the same intensity, outside the outer cone it gives
// nothing, between them the smoothstep of the cosine; parsing from the command line and
// JSON (one-line errors, a round trip), the inside test, pass 1's batched irradiance,
// and a light path that moves a spot without re-aiming it.

#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "common/bssrdf.h"
#include "common/error.h"
#include "common/shapes.h"
#include "common/util.h"
#include "relight/pointlight/point_animation.h"
#include "relight/pointlight/point_lights.h"

using namespace prt;

namespace {

// The message of the prt::Error f throws ("" when none), checked to be one line.
template <class F>
std::string errorOf(F&& f) {
    try {
        f();
    } catch (const Error& e) {
        const std::string what = e.what();
        EXPECT_EQ(what.find('\n'), std::string::npos) << what;
        return what;
    }
    return "";
}

// The falloff written out from the header's formula, in its own terms.
double smoothstepFalloff(double innerDeg, double outerDeg, double angleDeg) {
    const double ci = std::cos(innerDeg * kPi / 180.0), co = std::cos(outerDeg * kPi / 180.0);
    const double c = std::cos(angleDeg * kPi / 180.0);
    double t = (c - co) / (ci - co);
    t = t < 0.0 ? 0.0 : t > 1.0 ? 1.0 : t;
    return 3.0 * t * t - 2.0 * t * t * t;
}

// A point on the slab's top (y = 5) seen from a light at (0, 80, 0) at `angleDeg` from
// the straight-down axis.
SurfacePoint slabPointAt(double angleDeg) {
    const double x = 75.0 * std::tan(angleDeg * kPi / 180.0);
    return SurfacePoint{glm::vec3(float(x), 5.0f, 0.0f), {0, 1, 0}, {0, 1, 0}};
}

}  // namespace

TEST(SpotLights, InsideTheInnerConeEqualsThePointLight) {
    const RayScene scene(makeSlab(400.0f, 400.0f, 10.0f, 4));
    const glm::dvec3 intensity(2.0, 1.0, 0.5);
    const std::vector<Light> point = {pointLight({0, 80, 0}, intensity)};
    const std::vector<Light> spot = {spotLight({0, 80, 0}, {0, -1, 0}, intensity, 20.0, 35.0)};
    for (double angle : {0.0, 5.0, 12.0, 19.9}) {
        const SurfacePoint x = slabPointAt(angle);
        const glm::dvec3 e = directIrradiance(scene, spot, x, 1.3, FresnelModel::Exact);
        EXPECT_GT(e.x, 0.0);
        EXPECT_EQ(e, directIrradiance(scene, point, x, 1.3, FresnelModel::Exact)) << angle;
    }
}

TEST(SpotLights, OutsideTheOuterConeGivesNothing) {
    const RayScene scene(makeSlab(400.0f, 400.0f, 10.0f, 4));
    const std::vector<Light> spot = {spotLight({0, 80, 0}, {0, -1, 0}, glm::dvec3(1.0), 20.0, 35.0)};
    for (double angle : {35.01, 40.0, 60.0, 80.0})
        EXPECT_EQ(directIrradiance(scene, spot, slabPointAt(angle), 1.3, FresnelModel::Exact), glm::dvec3(0.0))
            << angle;
    // A hard-edged cone (inner == outer): full inside, nothing outside.
    const std::vector<Light> hard = {spotLight({0, 80, 0}, {0, -1, 0}, glm::dvec3(1.0), 30.0, 30.0)};
    const std::vector<Light> point = {pointLight({0, 80, 0}, glm::dvec3(1.0))};
    EXPECT_EQ(directIrradiance(scene, hard, slabPointAt(29.9), 1.3, FresnelModel::Exact),
              directIrradiance(scene, point, slabPointAt(29.9), 1.3, FresnelModel::Exact));
    EXPECT_EQ(directIrradiance(scene, hard, slabPointAt(30.1), 1.3, FresnelModel::Exact), glm::dvec3(0.0));
}

// Between the cones E_spot / E_point = smoothstep(cos outer, cos inner, cos angle), at
// a few mid angles (the angle measured from the axis to the point as the light sees it).
TEST(SpotLights, FalloffIsTheSmoothstepOfTheCosine) {
    const RayScene scene(makeSlab(400.0f, 400.0f, 10.0f, 4));
    const std::vector<Light> point = {pointLight({0, 80, 0}, glm::dvec3(1.0))};
    const std::vector<Light> spot = {spotLight({0, 80, 0}, {0, -2, 0}, glm::dvec3(1.0), 20.0, 35.0)};
    for (double angle : {22.0, 27.5, 33.0}) {
        const SurfacePoint x = slabPointAt(angle);
        // The angle the float surface point really makes with the axis.
        const glm::dvec3 d = glm::dvec3(x.position) - spot[0].position;
        const double actual = std::acos(-d.y / glm::length(d)) * 180.0 / kPi;
        const double expected = smoothstepFalloff(20.0, 35.0, actual);
        EXPECT_GT(expected, 0.01);
        EXPECT_LT(expected, 0.99);
        const double ratio = directIrradiance(scene, spot, x, 1.3, FresnelModel::Exact).y /
                             directIrradiance(scene, point, x, 1.3, FresnelModel::Exact).y;
        EXPECT_NEAR(ratio, expected, 1e-12) << angle;
        EXPECT_NEAR(spotFalloff(spot[0], glm::normalize(d)), expected, 1e-12);
    }
    // At the mid cosine t = 1/2 the smoothstep is exactly 1/2.
    const Light& s = spot[0];
    const double cMid = 0.5 * (s.cosInner + s.cosOuter);
    const glm::dvec3 w(std::sqrt(1.0 - cMid * cMid), -cMid, 0.0);
    EXPECT_NEAR(spotFalloff(s, w), 0.5, 1e-12);
    EXPECT_EQ(spotFalloff(point[0], w), 1.0);
}

TEST(SpotLights, ParsesFromTheCommandLineAndJson) {
    const Light s = parseLight("spot:1,2,3:0,-2,0:1,0.5,0.25:10,30");
    EXPECT_EQ(s.type, LightType::Spot);
    EXPECT_EQ(s.position, glm::dvec3(1, 2, 3));
    EXPECT_EQ(s.direction, glm::dvec3(0, -1, 0));
    EXPECT_EQ(s.rgb, glm::dvec3(1, 0.5, 0.25));
    EXPECT_EQ(s.innerDegrees, 10.0);
    EXPECT_EQ(s.outerDegrees, 30.0);
    EXPECT_NEAR(s.cosInner, std::cos(10.0 * kPi / 180.0), 1e-15);
    EXPECT_NEAR(s.cosOuter, std::cos(30.0 * kPi / 180.0), 1e-15);
    EXPECT_EQ(parseLight(" SPOT : 0,0,0 : 1,0,0 : 2 : 0, 90 ").rgb, glm::dvec3(2.0));  // gray, full hemisphere
    const std::string d = describe(s);
    EXPECT_NE(d.find("spot"), std::string::npos) << d;
    EXPECT_NE(d.find("10..30 deg"), std::string::npos) << d;

    const std::vector<Light> json = parseLightScene(
        R"({"lights": [{"type": "spot", "position": [1, 2, 3], "direction": [0, -2, 0],
                        "intensity": [1, 0.5, 0.25], "inner": 10, "outer": 30}]})");
    ASSERT_EQ(json.size(), 1u);
    EXPECT_EQ(json[0].type, LightType::Spot);
    EXPECT_EQ(json[0].position, s.position);
    EXPECT_EQ(json[0].direction, s.direction);
    EXPECT_EQ(json[0].rgb, s.rgb);
    EXPECT_EQ(json[0].cosInner, s.cosInner);
    EXPECT_EQ(json[0].cosOuter, s.cosOuter);
}

TEST(SpotLights, BadSpotsAreOneLineErrors) {
    const std::vector<std::pair<std::string, std::string>> bad = {
        {"spot:0,0,0:0,-1,0:1", "spot:X,Y,Z:DX,DY,DZ:R,G,B:INNER,OUTER"},
        {"spot:0,0,0:0,-1,0:1:10,20:5", "spot:X,Y,Z:DX,DY,DZ:R,G,B:INNER,OUTER"},
        {"spot:0,0,0:0,0,0:1:10,20", "must not be zero"},
        {"spot:0,0,0:0,-1:1:10,20", "direction"},
        {"spot:0,0,0:0,-1,0:1:10", "cone needs 2 values"},
        {"spot:0,0,0:0,-1,0:1:30,20", "inner <= outer"},
        {"spot:0,0,0:0,-1,0:1:-5,20", "inner <= outer"},
        {"spot:0,0,0:0,-1,0:1:10,95", "<= 90"},
        {"spot:0,0,0:0,-1,0:1:0,0", "outer > 0"},
        {"spot:0,0,0:0,-1,0:1:nan,20", "cone"},
        {"spot:0,0,0:0,-1,0:-1:10,20", ">= 0"},
        {"spot:0,inf,0:0,-1,0:1:10,20", "finite"},
        {"cone:0,0,0:1", "unknown light type"},
    };
    for (const auto& [text, needle] : bad) {
        const std::string what = errorOf([&] { parseLight(text); });
        EXPECT_NE(what.find(needle), std::string::npos) << text << " -> " << what;
        EXPECT_NE(what.find("--light " + text), std::string::npos) << what;  // names the light
    }
    const std::vector<std::pair<std::string, std::string>> badJson = {
        {R"({"lights": [{"type": "spot", "position": [0,0,0], "direction": [0,-1,0], "intensity": 1, "inner": 10}]})",
         "missing \"outer\""},
        {R"({"lights": [{"type": "spot", "position": [0,0,0], "direction": [0,-1,0], "intensity": 1, "inner": 10,
             "outer": 20, "angle": 3}]})",
         "unknown key \"angle\""},
        {R"({"lights": [{"type": "spot", "position": [0,0,0], "direction": [0,-1,0], "intensity": 1, "inner": [10],
             "outer": 20}]})",
         "\"inner\" must be one number"},
        {R"({"lights": [{"type": "spot", "position": [0,0,0], "direction": [0,-1,0], "intensity": 1, "inner": 40,
             "outer": 20}]})",
         "inner <= outer"},
        {R"({"lights": [{"type": "spot", "position": [0,0,0], "direction": [0,0,0], "intensity": 1, "inner": 10,
             "outer": 20}]})",
         "must not be zero"},
    };
    for (const auto& [text, needle] : badJson) {
        const std::string what = errorOf([&] { parseLightScene(text, "scene.json"); });
        EXPECT_NE(what.find(needle), std::string::npos) << what;
        EXPECT_NE(what.find("scene.json: lights[0]"), std::string::npos) << what;
    }
}

TEST(SpotLights, JsonRoundTrip) {
    const std::vector<Light> lights = {parseLight("point:1.5,-2,3e2:0.1,0.2,0.3"),
                                       parseLight("dir:1,2,-0.3:500,400,300"),
                                       parseLight("spot:-10,40.25,7:0.3,-1,0.1:0.013,0.02,0.5:12.5,33.3")};
    const std::string text = lightSceneJson(lights);
    const std::vector<Light> back = parseLightScene(text, "round trip");
    ASSERT_EQ(back.size(), lights.size());
    for (size_t i = 0; i < lights.size(); ++i) {
        SCOPED_TRACE(i);
        EXPECT_EQ(back[i].type, lights[i].type);
        EXPECT_EQ(back[i].position, lights[i].position);
        EXPECT_EQ(back[i].rgb, lights[i].rgb);
        EXPECT_EQ(back[i].innerDegrees, lights[i].innerDegrees);
        EXPECT_EQ(back[i].outerDegrees, lights[i].outerDegrees);
        EXPECT_EQ(back[i].cosInner, lights[i].cosInner);
        EXPECT_EQ(back[i].cosOuter, lights[i].cosOuter);
        for (int k = 0; k < 3; ++k) EXPECT_NEAR(back[i].direction[k], lights[i].direction[k], 1e-15);
    }
}

TEST(SpotLights, InsideTheObjectIsRefused) {
    const RayScene sphere(makeIcosphere(3, 10.0f));
    const std::string what =
        errorOf([&] { checkLightsOutside(sphere, {parseLight("spot:0,1,0:0,-1,0:1:10,20")}); });
    EXPECT_NE(what.find("spot light"), std::string::npos) << what;
    EXPECT_NE(what.find("inside the object"), std::string::npos) << what;
    EXPECT_NO_THROW(checkLightsOutside(sphere, {parseLight("spot:0,30,0:0,-1,0:1:10,20")}));
}

// Pass 1's batched rays (the ray rescaled to the light) against directIrradiance with a
// spot that lights part of a torus.
TEST(SpotLights, BatchedIrradianceMatchesDirectIrradiance) {
    const TriangleMesh mesh = makeTorus(20.0f, 6.0f, 96, 48);
    const RayScene scene(mesh);
    const std::vector<Light> lights = {parseLight("spot:30,50,10:-0.5,-1,-0.2:2,1,1:10,25")};
    IrradianceSamples s = faceCentroidSamples(mesh);
    computeIrradiance(s, scene, lights, 1.3, FresnelModel::Exact);
    size_t differ = 0, lit = 0, dark = 0;
    for (size_t i = 0; i < s.size(); ++i) {
        const glm::dvec3 ref = directIrradiance(scene, lights, {s.positions[i], s.normals[i], s.geometricNormals[i]},
                                                1.3, FresnelModel::Exact);
        const glm::dvec3 got(s.irradiance[i]);
        if (glm::length(got - ref) > 1e-5 * (glm::length(ref) + 1e-30)) ++differ;
        lit += ref.x > 0.0 ? 1 : 0;
        // Facing the light, unshadowed, but outside the outer cone: dark.
        const glm::dvec3 w = glm::normalize(lights[0].position - glm::dvec3(s.positions[i]));
        if (glm::dot(glm::dvec3(s.normals[i]), w) > 0.2 && spotFalloff(lights[0], -w) == 0.0) {
            ++dark;
            EXPECT_EQ(ref, glm::dvec3(0.0));
        }
    }
    EXPECT_GT(lit, s.size() / 50);
    EXPECT_GT(dark, s.size() / 200);
    EXPECT_LE(differ, s.size() / 1000) << differ << " of " << s.size();
}

// A light path moves a spot's position and keeps its axis and cone.
TEST(SpotLights, LightPathMovesASpotKeepingItsAxis) {
    const std::vector<Light> lights = {parseLight("spot:0,50,0:0,-1,0.5:1:10,20"), parseLight("point:0,0,90:1")};
    PointAnimation a;
    a.kind = AnimationKind::LightPath;
    a.frames = 3;
    a.from = {-20, 50, 0};
    a.to = {20, 60, 0};
    EXPECT_NO_THROW(validateAnimation(a, lights));
    const std::vector<Light> mid = animationLights(a, lights, 1);
    EXPECT_EQ(mid[0].type, LightType::Spot);
    EXPECT_EQ(mid[0].position, glm::dvec3(0, 55, 0));
    EXPECT_EQ(mid[0].direction, lights[0].direction);
    EXPECT_EQ(mid[0].cosOuter, lights[0].cosOuter);
    EXPECT_EQ(animationLights(a, lights, 2)[0].position, a.to);
    const std::string what = errorOf([&] { validateAnimation(a, {parseLight("dir:0,1,0:1")}); });
    EXPECT_NE(what.find("point or spot"), std::string::npos) << what;
}
