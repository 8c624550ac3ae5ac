// The diffuse baseline (precompute/passes/diffuse_baseline.h): a shadowed Lambertian PRT
// relit like any transport file, against the closed form on a convex surface and
// against the per-point Monte Carlo irradiance of the reference (no cubemap, no
// wavelets, no truncation) where the surface shadows itself.

#include "precompute/passes/diffuse_baseline.h"

#include <gtest/gtest.h>

#include <cmath>

#include "common/envmap.h"
#include "common/error.h"
#include "common/shapes.h"
#include "common/transport_params.h"
#include "common/util.h"
#include "relight/prt/light_vector.h"
#include "relight/prt/relight_kernel.h"
#include "tools/reference/reference.h"

using namespace prt;

namespace {

VertexRadiance relit(const TransportFile& file, const Image& environment) {
    const LightVector light = makeLightVector(environment, int(file.cubemapSize));
    VertexRadiance radiance;
    relightVertices(file, light, ScatteringComponents{true, false}, radiance);
    return radiance;
}

// The baseline of `mesh` (its normals computed, traced against itself).
TransportFile baselineOf(TriangleMesh mesh, const DiffuseBaselineOptions& o) {
    computeVertexNormals(mesh);
    const RayScene scene(mesh);
    return diffuseBaselineTransport(mesh, scene, {mesh.vertexCount(), 1}, 1.0, o);
}

}  // namespace

// A sphere sees the whole hemisphere above every vertex: under a constant radiance L the
// Lambertian surface sends albedo x L (E = pi L), per channel.
TEST(DiffuseBaseline, ConvexSurfaceUnderAConstantSkyReflectsAlbedoTimesL) {
    DiffuseBaselineOptions o;
    o.albedo = {0.25, 0.5, 0.9};
    o.cubemapSize = 16;
    const TransportFile file = baselineOf(makeIcosphere(3, 10.0f), o);
    EXPECT_EQ(file.parameter("baseline"), "diffuse-brdf");
    EXPECT_EQ(file.parameter("eta"), "1");
    const glm::vec3 L(2.0f, 1.0f, 0.5f);
    const VertexRadiance r = relit(file, constantEnvironment(64, L));
    double worst = 0.0, mean = 0.0;
    for (const glm::vec3& v : r.diffuse)
        for (int c = 0; c < 3; ++c) {
            const double ratio = v[c] / (o.albedo[c] * L[c]);
            worst = std::max(worst, std::abs(ratio - 1.0));
            mean += ratio / double(3 * r.diffuse.size());
        }
    std::printf("albedo x L: mean ratio %.5f, worst %.4f\n", mean, worst);
    // The cosine over the texels' 2 x 2 sub-directions at N = 16 (the horizon cuts
    // texels), and the light's and the vectors' quantization: measured mean 1.0002,
    // worst 0.83%.
    EXPECT_LT(std::abs(mean - 1.0), 2e-3);
    EXPECT_LT(worst, 1.5e-2);
}

// On a torus (its inner ring shadowed by the ring itself) under a sky with a sun, every
// tenth vertex against the reference's Monte Carlo estimate of E at that vertex (eta =
// 1, 65536 directions): within the 128-term truncation's error.
TEST(DiffuseBaseline, ShadowedSurfaceMatchesTheMonteCarloIrradiance) {
    TriangleMesh torus = makeTorus(10.0f, 4.0f, 48, 24);
    computeVertexNormals(torus);
    const RayScene scene(torus);
    DiffuseBaselineOptions o;
    o.albedo = glm::dvec3(0.7);
    o.cubemapSize = 32;
    const TransportFile file = diffuseBaselineTransport(torus, scene, {torus.vertexCount(), 1}, 1.0, o);
    Image sky = twoToneEnvironment(128, {1.0f, 1.1f, 1.3f}, {0.2f, 0.15f, 0.1f});
    const Image sun = sunEnvironment(128, glm::normalize(glm::dvec3(0.4, 1.0, 0.2)), {40.0f, 38.0f, 30.0f});
    for (size_t i = 0; i < sky.pixels.size(); ++i) sky.pixels[i] += sun.pixels[i];
    const VertexRadiance r = relit(file, sky);
    const EnvironmentSampler env(sky);
    IrradianceEstimatorOptions mc;
    mc.directions = 65536;
    double sumSq = 0.0, refSq = 0.0;
    size_t shadowed = 0;
    for (size_t v = 0; v < torus.vertexCount(); v += 10) {
        const IrradianceEstimate e =
            estimateIrradiance(env, &scene, torus.positions[v], torus.normals[v], torus.normals[v], 1.0, mc, v);
        const glm::dvec3 expected = o.albedo / kPi * e.value;
        for (int c = 0; c < 3; ++c) {
            sumSq += (r.diffuse[v][c] - expected[c]) * (r.diffuse[v][c] - expected[c]);
            refSq += expected[c] * expected[c];
        }
        const IrradianceEstimate open = estimateIrradiance(env, nullptr, torus.positions[v], torus.normals[v],
                                                           torus.normals[v], 1.0, {.directions = 4096,
                                                                                   .visibility = false}, v);
        shadowed += open.value.g > 1.2 * e.value.g ? 1 : 0;
    }
    const double rms = std::sqrt(sumSq / refSq);
    RecordProperty("relative_rms", std::to_string(rms));
    std::printf("baseline vs Monte Carlo E at %zu vertices: relative RMS %.4f\n", torus.vertexCount() / 10, rms);
    EXPECT_GT(shadowed, 10u);  // the ring does shadow itself
    EXPECT_LT(rms, 0.015);  // measured 0.56%: the 128-term truncation and the 6 x 32^2 cubemap
}

TEST(DiffuseBaseline, AlbedoOutsideTheUnitIntervalIsRefused) {
    DiffuseBaselineOptions o;
    o.albedo = {0.5, 1.2, 0.5};
    try {
        baselineOf(makeIcosphere(1, 10.0f), o);
        FAIL() << "accepted";
    } catch (const Error& e) {
        EXPECT_EQ(e.subject(), "--albedo");
    }
}
