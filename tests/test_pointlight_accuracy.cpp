// The point-light renderers at their defaults against the independent reference
// (tools/reference/reference.h under lights: its own samples at 0.2 w, its own seed
// and irradiance code, the dipole summed over every sample at every pixel). Each test
// bounds one renderer's error the way a user would measure it (prt-compare's linear
// relative RMSE over the object pixels), with the reference's own remaining error
// estimated beside it, so that a bound cannot hide a reference as coarse as the method.
//
// The scene: a 14 mm torus (9,216 faces, centroids ~0.3 mm apart, 0.65 of Skimmilk's
// kernel width w = 0.455 mm) under one point light above and to the side, 96 x 96: lit
// tops, a shadow terminator, self-shadowing of the ring and silhouettes.

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "common/bssrdf.h"
#include "common/camera.h"
#include "common/image_compare.h"
#include "common/materials.h"
#include "common/raytrace.h"
#include "common/sampling.h"
#include "common/shapes.h"
#include "relight/pointlight/irradiance_cache.h"
#include "relight/pointlight/jensen_buhler.h"
#include "relight/pointlight/point_lights.h"
#include "relight/pointlight/surface_atlas.h"
#include "relight/pointlight/texture_space_sampling.h"
#include "relight/render/gbuffer.h"
#include "tools/reference/reference.h"

using namespace prt;

namespace {

struct LitTorus {
    TriangleMesh mesh = makeTorus(5.0f, 2.0f, 96, 48);
    RayScene scene{mesh};
    Material material = materialByName("Skimmilk");
    std::vector<Light> lights{parseLight("point:12,15,6:0.002")};
    GBuffer g;
    ReferenceFrame reference;
    DiscretisationEstimate referenceError;
    IrradianceSamples faces;  // the renderers' default samples, lit

    LitTorus() {
        g = traceGBuffer(scene, mesh, frameSphere({0, 0, 0}, 7.0, 20.0, 35.0, 30.0, 96, 96));
        auto render = [&](int level, const GBuffer& pixels) {
            const ReferenceSamplePlan plan = planReferenceSamples(material, totalArea(mesh), 1, kReferenceLightMaxSamples,
                                                                     kReferenceLightSpacingFraction);
            const size_t count = level == 0 ? plan.count : plan.count / 2;
            const SampleSet samples = poissonDiskSamples(mesh, count, referenceSampleSeed(1, level));
            std::vector<glm::vec3> positions;
            for (const SurfaceSample& s : samples.samples) positions.push_back(s.position);
            const MultipleScatteringReference ms(material, std::move(positions), samples.areaPerSample,
                                                 computeLightIrradiance(lights, scene, samples, material.eta));
            return renderReference(pixels, {&ms}, Image(), glm::dmat3(1.0));
        };
        reference = render(0, g);
        referenceError = estimateDiscretisationError(reference, render(1, subsampleObjectPixels(g, 2)));
        faces = faceCentroidSamples(mesh);
        computeIrradiance(faces, scene, lights, material.eta, FresnelModel::Exact);
    }

    // prt-compare's relative RMSE of `image` against the reference, printed.
    double error(const Image& image, const char* what) const {
        const CompareResult r = compareImages(image, reference.image);
        std::printf("%s: relative RMSE %.3f%% against the reference (its own estimated error %.3f%%), mean ratio "
                    "%.4f\n",
                    what, 100 * r.overall.relativeRmse, 100 * referenceError.estimatedError, r.overall.meanRatio);
        EXPECT_EQ(r.coverageMismatch, 0u);
        return r.overall.relativeRmse;
    }
};

const LitTorus& scene() {
    static const LitTorus s;
    return s;
}

}  // namespace

TEST(PointLightAccuracy, TheReferenceIsConvergedWellBelowTheBounds) {
    const LitTorus& s = scene();
    ASSERT_GT(s.reference.objectPixels, 2500u);
    // The light rule (0.1 w, 221 K samples here): measured 0.35%, a third of the
    // tightest bound below (at the environment's 0.2 w it was 0.69%, as large as
    // Jensen-Buhler's own error, and could not have judged it).
    EXPECT_LT(s.referenceError.estimatedError, 0.005);
    EXPECT_EQ(s.reference.expectedRelativeRmse, 0.0);  // exact irradiance
}

TEST(PointLightAccuracy, JensenBuhlerOverFaceCentroids) {
    // The face centroids' point rule at 0.65 w, and the octree's clusters at the default
    // epsilon. Measured 0.33% (epsilon 0.05) and 0.34% (epsilon 0): on this smooth
    // material the centroids are converged to what the reference resolves (0.35%).
    // epsilon 0.3 gives 2.1% (tried).
    const LitTorus& s = scene();
    const double walk = s.error(JensenBuhler(s.material, IrradianceOctree(s.faces), {}).render(s.g), "jb");
    const double brute =
        s.error(JensenBuhler(s.material, IrradianceOctree(s.faces), {.epsilon = 0.0}).render(s.g), "jb, epsilon 0");
    EXPECT_LT(walk, 0.01);
    EXPECT_LT(brute, 0.01);
}

TEST(PointLightAccuracy, IrradianceCacheAtItsDefaults) {
    const LitTorus& s = scene();
    // a = 0.01: measured 1.02% (1.13% at the former default 0.015), bound 2% (the
    // issue's goal for the cache). a = 0.1 gives 5.8% (tried).
    IrradianceCache cache(s.material, IrradianceOctree(s.faces), {});
    EXPECT_LT(s.error(cache.render(s.g), "cache"), 0.02);
}

TEST(PointLightAccuracy, TextureSpaceHybridAtItsDefaults) {
    const LitTorus& s = scene();
    const SurfaceAtlas atlas = buildSurfaceAtlas(s.mesh, kDefaultIrradianceMapSize);
    TextureSpaceRenderer hybrid(s.mesh, s.scene, atlas, s.material, {});
    hybrid.setLights(s.lights);
    // N = 3600, atlas 256^2, shadow map 256^2, 32 x 8 + 1 filter taps, theta 1.2:
    // measured 1.23% per pixel and 1.05% per vertex, bound 1.6% (N = 100 gives 1.79% and
    // 1.73%, tried).
    const double pixel = s.error(hybrid.render(s.g), "tsis hybrid, per pixel");
    const double vertex = s.error(hybrid.renderPerVertex(s.g), "tsis hybrid, per vertex");
    EXPECT_LT(pixel, 0.016);
    EXPECT_LT(vertex, 0.016);
}
