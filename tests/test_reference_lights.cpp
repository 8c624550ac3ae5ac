// The reference under point and directional lights (tools/reference/reference.h,
// "Irradiance from point and directional lights"): the exact irradiance against its
// closed forms, the tie between a directional light and a one-texel sun environment
// through the environment reference, and the vectorised dipole sum against the plain
// loop.

#include "tools/reference/reference.h"

#include <gtest/gtest.h>

#include <cmath>

#include "common/bssrdf.h"
#include "common/camera.h"
#include "common/envmap.h"
#include "common/error.h"
#include "common/image_compare.h"
#include "common/raytrace.h"
#include "common/sampling.h"
#include "common/shapes.h"
#include "common/util.h"
#include "relight/render/gbuffer.h"

using namespace prt;

namespace {

MultipleScatteringReference msReference(const Material& m, const SampleSet& samples, SampleIrradiance e) {
    std::vector<glm::vec3> positions;
    for (const SurfaceSample& s : samples.samples) positions.push_back(s.position);
    return MultipleScatteringReference(m, std::move(positions), samples.areaPerSample, std::move(e));
}

// A torus lying tilted, so that the light falls on it at every angle and its ring
// shadows part of itself.
TriangleMesh tiltedTorus() {
    TriangleMesh mesh = makeTorus(6.0f, 2.5f, 96, 48);
    const glm::dmat3 r = rotationAxisAngle({1.0, 0.0, 0.3}, 35.0);
    for (glm::vec3& p : mesh.positions) p = glm::vec3(r * glm::dvec3(p));
    for (glm::vec3& n : mesh.normals) n = glm::vec3(r * glm::dvec3(n));
    return mesh;
}

double relativeL2(const std::vector<glm::dvec3>& test, const std::vector<glm::dvec3>& reference) {
    double d = 0.0, r = 0.0;
    for (size_t i = 0; i < test.size(); ++i) {
        d += glm::dot(test[i] - reference[i], test[i] - reference[i]);
        r += glm::dot(reference[i], reference[i]);
    }
    return std::sqrt(d / r);
}

}  // namespace

TEST(ReferenceLightIrradiance, MatchesTheClosedFormsOfPointAndDirectionalLights) {
    // Within 1e-6: the normal is a float, normalised again in double.
    const double eta = 1.4;
    const glm::vec3 n = glm::normalize(glm::vec3(0.2f, 1.0f, -0.1f));
    const glm::dvec3 nd(n);
    for (double angle : {0.0, 40.0, 75.0}) {
        const glm::dvec3 t = glm::normalize(glm::cross(nd, glm::dvec3(0, 0, 1)));
        const glm::dvec3 w = std::cos(glm::radians(angle)) * nd + std::sin(glm::radians(angle)) * t;
        const double mu = glm::dot(nd, w), ft = fresnelTransmittance(eta, mu);
        // Point light of I = (1, 2, 3) mW/sr at 25 mm: E = F_t mu 1e6 I / r^2 W/m^2.
        const glm::dvec3 intensity(1e-3, 2e-3, 3e-3);
        const std::vector<Light> point{pointLight(25.0 * w, intensity)};
        const glm::dvec3 e = lightIrradiance(point, nullptr, glm::vec3(0), n, n, eta, false);
        for (int c = 0; c < 3; ++c) EXPECT_NEAR(e[c], ft * mu * 1e6 * intensity[c] / 625.0, 1e-6 * e[c]) << angle;
        // Directional light of E_perp (4, 5, 6) W/m^2: E = F_t mu E_perp.
        const std::vector<Light> sun{directionalLight(w, {4.0, 5.0, 6.0})};
        const glm::dvec3 es = lightIrradiance(sun, nullptr, glm::vec3(0), n, n, eta, false);
        for (int c = 0; c < 3; ++c) EXPECT_NEAR(es[c], ft * mu * (4.0 + c), 1e-6 * es[c]) << angle;
        // Lights add.
        std::vector<Light> both = point;
        both.push_back(sun[0]);
        const glm::dvec3 eb = lightIrradiance(both, nullptr, glm::vec3(0), n, n, eta, false);
        for (int c = 0; c < 3; ++c) EXPECT_NEAR(eb[c], e[c] + es[c], 1e-12 * eb[c]);
    }
    // Below the horizon, nothing.
    const std::vector<Light> below{directionalLight(-glm::dvec3(n) + glm::dvec3(0.3, 0, 0), glm::dvec3(1.0))};
    EXPECT_EQ(lightIrradiance(below, nullptr, glm::vec3(0), n, n, eta, false), glm::dvec3(0.0));
}

TEST(ReferenceLightIrradiance, ShadowRaysStopAtAPointLightButNotForTheSun) {
    // A 10 x 10 mm plate at y = 5 over the origin; a point at the origin facing up.
    const TriangleMesh plate = [] {
        TriangleMesh m = makeSlab(10.0f, 10.0f, 0.5f, 4);
        for (glm::vec3& p : m.positions) p.y += 5.0f;
        return m;
    }();
    const RayScene scene(plate);
    const glm::vec3 up(0, 1, 0);
    uint64_t rays = 0;
    // The sun overhead is blocked by the plate.
    EXPECT_EQ(lightIrradiance({directionalLight({0, 1, 0}, glm::dvec3(1.0))}, &scene, glm::vec3(0), up, up, 1.3, true,
                              &rays),
              glm::dvec3(0.0));
    // A point light between the point and the plate is not: the ray stops short of it.
    const glm::dvec3 lit = lightIrradiance({pointLight({0, 2, 0}, glm::dvec3(1e-3))}, &scene, glm::vec3(0), up, up,
                                           1.3, true, &rays);
    EXPECT_NEAR(lit.x, fresnelTransmittance(1.3, 1.0) * 1e3 / 4.0, 1e-9);
    // A point light above the plate is blocked.
    EXPECT_EQ(lightIrradiance({pointLight({0, 9, 0}, glm::dvec3(1e-3))}, &scene, glm::vec3(0), up, up, 1.3, true,
                              &rays),
              glm::dvec3(0.0));
    EXPECT_EQ(rays, 3u);
    EXPECT_THROW(lightIrradiance({}, nullptr, glm::vec3(0), up, up, 1.3, true), Error);
}

TEST(ReferenceLightIrradiance, DirectionalLightEqualsAOneTexelSunThroughTheEnvironmentReference) {
    // The tie between the two references: a sun texel of radiance L and solid angle
    // Omega lights like a directional light of E_perp = L Omega toward the texel's
    // centre, up to the variation of F_t mu across the texel (0.35 degrees wide at
    // 1024 x 512: ~1e-4 relative where mu is not small) and its penumbra (the texel is
    // an area light: samples within ~0.1 mm of the ring's shadow edge are partly lit in
    // one and not the other). Everything else is shared: samples, visibility (the same
    // ray origin), the dipole sum. Measured: per sample 0.12% (relative L2 over the
    // samples), the frames, where R_d smooths the penumbra, 0.006% relative RMSE, the
    // mean levels 6e-6 apart; asserted with margins of 4x to 16x. Dropping F_t from the
    // lights' irradiance gives 5.9%, 5.7% and 6.1% (tried); a solid angle off by the
    // texel's cos(latitude) would be 30%.
    const TriangleMesh mesh = tiltedTorus();
    const RayScene scene(mesh);
    const Material material = customMaterial({1.0, 1.5, 2.0}, {0.05, 0.03, 0.01}, 1.3);
    const SampleSet samples = poissonDiskSamples(mesh, 12000, 5);

    const int width = 1024, height = 512;
    const int tx = 300, ty = 140;  // a texel well above the horizon
    const glm::dvec3 toSun = latLongPixelDirection(tx, ty, width, height);
    const glm::vec3 radiance(2000.0f, 1500.0f, 1000.0f);
    const double omega = latLongPixelSolidAngle(ty, width, height);
    const EnvironmentSampler env(sunEnvironment(width, toSun, radiance));
    IrradianceEstimatorOptions o;
    o.directions = 16;
    o.environmentFraction = 1.0;  // every direction in the sun texel
    const SampleIrradiance fromEnvironment = computeSampleIrradiance(env, &scene, samples, material.eta, o);
    const std::vector<Light> lights{directionalLight(toSun, glm::dvec3(radiance) * omega)};
    const SampleIrradiance fromLight = computeLightIrradiance(lights, scene, samples, material.eta);
    for (const glm::dvec3& v : fromLight.variance) ASSERT_EQ(v, glm::dvec3(0.0));

    size_t lit = 0;
    for (const glm::dvec3& e : fromLight.value) lit += e.x > 0.0;
    EXPECT_GT(lit, samples.samples.size() / 4);  // lit, shadowed and facing away: all present
    EXPECT_LT(lit, samples.samples.size() * 3 / 4);
    const double perSample = relativeL2(fromEnvironment.value, fromLight.value);
    EXPECT_LT(perSample, 0.005);

    const MultipleScatteringReference msEnv = msReference(material, samples, fromEnvironment);
    const MultipleScatteringReference msLight = msReference(material, samples, fromLight);
    Camera camera;
    camera.eye = {0.0, 25.0, 40.0};
    camera.target = {0.0, 0.0, 0.0};
    camera.fovY = 30.0;
    camera.width = camera.height = 64;
    const GBuffer g = traceGBuffer(scene, mesh, camera);
    const ReferenceFrame a = renderReference(g, {&msEnv}, Image(), glm::dmat3(1.0));
    const ReferenceFrame b = renderReference(g, {&msLight}, Image(), glm::dmat3(1.0));
    ASSERT_GT(b.objectPixels, 1000u);
    const CompareResult r = compareImages(a.image, b.image);
    EXPECT_LT(r.overall.relativeRmse, 5e-4) << "per sample " << perSample;
    EXPECT_NEAR(r.overall.meanRatio, 1.0, 1e-4);
    EXPECT_EQ(b.expectedRelativeRmse, 0.0);  // exact irradiance: no Monte Carlo noise
}

TEST(ReferenceLightIrradiance, DistantPointLightEqualsTheDirectionalLight) {
    // A point light of I = E_perp D^2 / 1e6 W/sr at D = 1e5 mm: across the 17 mm torus
    // its direction turns by 1e-4 rad and 1 / r^2 changes by 2e-4, so each sample's
    // irradiance is within a few 1e-4 of the directional light's (measured 8.7e-5
    // relative L2; the inverse-square law's mm^2 -> m^2 factor off would be 1e6 times).
    const TriangleMesh mesh = tiltedTorus();
    const RayScene scene(mesh);
    const SampleSet samples = poissonDiskSamples(mesh, 4000, 9);
    const glm::dvec3 w = glm::normalize(glm::dvec3(0.3, 1.0, 0.4));
    const double d = 1e5;
    const glm::dvec3 ePerp(3.0, 2.0, 1.0);
    const SampleIrradiance sun = computeLightIrradiance({directionalLight(w, ePerp)}, scene, samples, 1.3);
    const SampleIrradiance point =
        computeLightIrradiance({pointLight(d * w, ePerp * d * d / kSquareMmPerSquareMetre)}, scene, samples, 1.3);
    EXPECT_LT(relativeL2(point.value, sun.value), 5e-4);
    EXPECT_EQ(sun.rays, point.rays);
}

TEST(ReferenceMultipleScattering, VectorisedSumEqualsThePlainLoopAndSkipsUnlitSamples) {
    const TriangleMesh mesh = tiltedTorus();
    const RayScene scene(mesh);
    const Material material = customMaterial({1.0, 1.5, 2.0}, {0.05, 0.03, 0.01}, 1.3);
    const SampleSet samples = poissonDiskSamples(mesh, 3001, 2);  // not a multiple of the block
    SampleIrradiance e =
        computeLightIrradiance({directionalLight({0.2, 1.0, 0.1}, glm::dvec3(1.0))}, scene, samples, material.eta);
    // Give a few samples a variance only: they must stay in the sum.
    e.variance[7] = glm::dvec3(0.5);
    e.value[7] = glm::dvec3(0.0);
    size_t contributing = 0;
    for (size_t i = 0; i < e.value.size(); ++i)
        contributing += e.value[i] != glm::dvec3(0.0) || e.variance[i] != glm::dvec3(0.0);
    const MultipleScatteringReference ms = msReference(material, samples, e);
    EXPECT_EQ(ms.sampleCount(), samples.samples.size());
    EXPECT_EQ(ms.contributingSamples(), contributing);
    EXPECT_LT(contributing, samples.samples.size());

    // The plain loop over every sample (unlit ones included) by dipoleRd.
    for (size_t v = 0; v < mesh.positions.size(); v += 97) {
        const glm::vec3 x = mesh.positions[v];
        const RadianceEstimate fast = ms.diffuse(x), slow = ms.diffuseScalar(x);
        glm::dvec3 all(0.0);
        for (size_t i = 0; i < samples.samples.size(); ++i)
            all += samples.areaPerSample / kPi * e.value[i] *
                   dipoleRd(material, glm::length(glm::dvec3(samples.samples[i].position) - glm::dvec3(x)));
        // The fast sum is single precision within blocks of 64 (measured within 3e-7).
        for (int c = 0; c < 3; ++c) {
            EXPECT_NEAR(fast.value[c], slow.value[c], 2e-6 * slow.value[c]);
            EXPECT_NEAR(slow.value[c], all[c], 1e-6 * all[c]);  // E_i held in float
            EXPECT_NEAR(fast.variance[c], slow.variance[c], 1e-5 * slow.variance[c]);  // one far term: 2e-6
            EXPECT_GT(slow.value[c], 0.0);
        }
    }
}
