// The Jensen-Buhler hierarchical renderer (relight/pointlight/jensen_buhler.h). Physics asserted:
// epsilon = 0 is the brute-force sum; the octree's nodes carry area sums and
// AREA-weighted means (the SPEC's trap); a large flat box under a normal-incidence
// directional light reaches the closed-form exitance E F_t int R_d dA; a far point
// light renders like a directional light; the image does not depend on threads;
// setMaterial equals a new renderer bit for bit; the object scaled by s renders as the
// unscaled one with scaledMaterial(m, s) (size as material).

#include "relight/pointlight/jensen_buhler.h"

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <random>
#include <vector>

#include "common/bssrdf.h"
#include "common/camera.h"
#include "common/error.h"
#include "common/material_edit.h"
#include "relight/render/gbuffer.h"
#include "common/shapes.h"

using namespace prt;

namespace {

// Face-centroid samples of `mesh` lit by `lights` (exact Fresnel, eta 1.3).
IrradianceSamples litSamples(const TriangleMesh& mesh, const RayScene& scene, const std::vector<Light>& lights) {
    IrradianceSamples s = faceCentroidSamples(mesh);
    computeIrradiance(s, scene, lights, 1.3, FresnelModel::Exact);
    return s;
}

// Samples with unequal areas and random (deterministic) irradiance.
IrradianceSamples randomSamples(const TriangleMesh& mesh, uint32_t seed) {
    IrradianceSamples s = faceCentroidSamples(mesh);
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> u(0.0f, 100.0f);
    for (glm::vec3& e : s.irradiance) e = glm::vec3(u(rng), u(rng), u(rng));
    return s;
}

double relativeError(const glm::dvec3& a, const glm::dvec3& b) {
    double worst = 0.0;
    for (int c = 0; c < 3; ++c) worst = std::max(worst, std::abs(a[c] - b[c]) / std::max(std::abs(b[c]), 1e-300));
    return worst;
}

}  // namespace

TEST(JensenBuhler, DipoleRGBMatchesDipoleRd) {
    const Material m = materialByName("Skimmilk");
    const DipoleRGB d(m);
    for (double r : {0.0, 1e-3, 0.1, 0.7, 3.0, 25.0, 200.0}) {
        const glm::dvec3 ref = dipoleRd(m, r);
        const glm::dvec3 got = d.rd(r * r);
        for (int c = 0; c < 3; ++c) {
            // Single precision: a few ulps, plus the rounding of the float exponent
            // sigma_tr d (half an ulp of it, 2^-24 sigma_tr d relative) that e^x turns into
            // a relative error of the result -- 3.4e-6 for Skimmilk's blue at 200 mm.
            const DipoleChannel ch = makeDipoleChannel(m, c);
            const double dv = std::sqrt(r * r + ch.zv * ch.zv);
            const double tolerance = 2e-6 + std::ldexp(1.0, -23) * ch.sigmaTr * dv;
            EXPECT_NEAR(got[c], ref[c], tolerance * ref[c]) << r;
        }
    }
}

// Octree invariants: every node's area is the sum of its samples' areas, its position
// and irradiance the AREA-weighted means over its samples; children partition the
// parent's sample range; samples lie in their cells; leaves respect leafSize.
TEST(JensenBuhler, OctreeNodesHoldAreaSumsAndAreaWeightedMeans) {
    TriangleMesh mesh = makeBox({40.0f, 10.0f, 20.0f}, {2, 5, 9});  // faces of very unequal area
    const TriangleMesh torus = makeTorus(15.0f, 4.0f, 40, 16);
    const uint32_t base = uint32_t(mesh.positions.size());
    for (const glm::vec3& p : torus.positions) mesh.positions.push_back(p + glm::vec3(0, 30, 0));
    for (const glm::vec3& n : torus.normals) mesh.normals.push_back(n);
    for (const glm::uvec3& t : torus.triangles) mesh.triangles.push_back(t + glm::uvec3(base));
    const IrradianceSamples s = randomSamples(mesh, 11);
    const IrradianceOctree tree(s, OctreeOptions{.leafSize = 4, .maxDepth = 24});
    const std::vector<IrradianceOctree::Node>& nodes = tree.nodes();
    const std::vector<uint32_t>& order = tree.order();

    // order is a permutation and the tree's samples are the input's.
    std::vector<int> seen(s.size(), 0);
    for (size_t k = 0; k < order.size(); ++k) {
        ++seen[order[k]];
        EXPECT_EQ(tree.samples()[k].position, s.positions[order[k]]);
        EXPECT_EQ(tree.samples()[k].area, s.areas[order[k]]);
    }
    for (int v : seen) EXPECT_EQ(v, 1);
    EXPECT_EQ(tree.root().sampleCount, s.size());
    EXPECT_NEAR(tree.root().area, s.totalArea(), 1e-12 * s.totalArea());
    EXPECT_NEAR(tree.root().area, totalArea(mesh), 1e-6 * totalArea(mesh));

    double maxRelPos = 0.0, maxRelE = 0.0, maxRelA = 0.0;
    for (const IrradianceOctree::Node& node : nodes) {
        double a = 0.0;
        glm::dvec3 ap(0.0), ae(0.0);
        for (uint32_t k = node.firstSample; k < node.firstSample + node.sampleCount; ++k) {
            const size_t i = order[k];
            a += s.areas[i];
            ap += double(s.areas[i]) * glm::dvec3(s.positions[i]);
            ae += double(s.areas[i]) * glm::dvec3(s.irradiance[i]);
            EXPECT_TRUE(node.cellContains(glm::dvec3(s.positions[i])));
        }
        maxRelA = std::max(maxRelA, std::abs(node.area - a) / a);
        maxRelPos = std::max(maxRelPos, glm::length(node.position - ap / a) / glm::length(ap / a));
        maxRelE = std::max(maxRelE, relativeError(node.irradiance, ae / a));
        if (node.leaf()) {
            EXPECT_TRUE(node.sampleCount <= 4u || node.depth == 24u);
        } else {
            uint32_t next = node.firstSample;
            for (uint32_t c = 0; c < node.childCount; ++c) {
                const IrradianceOctree::Node& child = nodes[node.firstChild + c];
                EXPECT_EQ(child.firstSample, next);
                EXPECT_GT(child.sampleCount, 0u);
                EXPECT_EQ(child.depth, node.depth + 1);
                EXPECT_DOUBLE_EQ(child.cellSize, 0.5 * node.cellSize);
                next += child.sampleCount;
            }
            EXPECT_EQ(next, node.firstSample + node.sampleCount);
        }
    }
    EXPECT_LT(maxRelA, 1e-12);
    EXPECT_LT(maxRelPos, 1e-12);
    EXPECT_LT(maxRelE, 1e-12);
    EXPECT_GT(tree.leafCount(), s.size() / 8);
    EXPECT_GT(tree.depth(), 3);
}

// The SPEC's trap, in its smallest form: two samples of area 1 and 3 with irradiance
// 0 and 4 make a cluster of irradiance 3 (flux 12 over area 4), not the plain mean 2.
TEST(JensenBuhler, ClusterIrradianceIsAreaWeighted) {
    IrradianceSamples s;
    s.positions = {{0, 0, 0}, {1, 0, 0}};
    s.normals = s.geometricNormals = {{0, 1, 0}, {0, 1, 0}};
    s.areas = {1.0f, 3.0f};
    s.triangles = {0, 1};
    s.irradiance = {glm::vec3(0.0f), glm::vec3(4.0f)};
    const IrradianceOctree tree(s, OctreeOptions{.leafSize = 1});
    ASSERT_FALSE(tree.root().leaf());
    EXPECT_DOUBLE_EQ(tree.root().area, 4.0);
    EXPECT_DOUBLE_EQ(tree.root().irradiance.x, 3.0);
    EXPECT_DOUBLE_EQ(tree.root().position.x, 0.75);
    // Far away the root is used whole and carries the exact flux 12.
    const Material m = materialByName("Marble");
    const JensenBuhler jb(m, tree, {.epsilon = 1.0});
    size_t terms = 0;
    const glm::dvec3 far(0.75, 30.0, 0.0);
    const glm::dvec3 mFar = jb.exitance(far, &terms);
    EXPECT_EQ(terms, 1u);
    EXPECT_NEAR(mFar.x, 12.0 * dipoleRd(m, 30.0).x, 2e-6 * mFar.x);
}

TEST(JensenBuhler, EpsilonZeroEqualsBruteForce) {
    const TriangleMesh mesh = makeTorus(12.0f, 4.0f, 48, 24);
    const RayScene scene(mesh);
    const IrradianceSamples s =
        litSamples(mesh, scene, {parseLight("point:30,40,10:1,0.7,0.4"), parseLight("dir:-1,0.2,0.3:50")});
    const Material m = materialByName("Skimmilk");
    const JensenBuhler exact(m, IrradianceOctree(s), {.epsilon = 0.0});
    const JensenBuhler fast(m, IrradianceOctree(s), {.epsilon = 0.05});
    double worstExact = 0.0, worstFast = 0.0;
    size_t termsExact = 0, termsFast = 0;
    for (size_t v = 0; v < mesh.vertexCount(); v += 7) {
        const glm::dvec3 x(mesh.positions[v]);
        const glm::dvec3 brute = bruteForceExitance(s, m, x);
        size_t n = 0;
        worstExact = std::max(worstExact, relativeError(exact.exitance(x, &n), brute));
        termsExact += n;
        worstFast = std::max(worstFast, relativeError(fast.exitance(x, &n), brute));
        termsFast += n;
    }
    EXPECT_LT(worstExact, 1e-12);  // the same terms summed in another order, in double
    EXPECT_EQ(termsExact, s.size() * ((mesh.vertexCount() + 6) / 7));
    // The hierarchy: far fewer terms, a small error.
    EXPECT_LT(worstFast, 0.02);
    EXPECT_LT(termsFast * 2, termsExact);
}

// A 120 x 120 mm box 20 mm thick under a directional light at normal incidence. Far
// from the edges the top face is a plane under uniform irradiance E_perp, transmitted
// F_t(eta, 1) E_perp, so M = F_t(eta, 1) E_perp int R_d dA (the closed form
// dipoleTotalDiffuseReflectance). The face-centroid cubature approaches it as the
// faces shrink: its error is second order in h / z_r (z_r = 0.48 mm in blue here), so
// halving the face size divides it by about 4.
TEST(JensenBuhler, FlatBoxUnderNormalIncidenceReachesClosedForm) {
    const Material m = customMaterial({0.5, 1.0, 2.0}, {0.05, 0.08, 0.1});
    const double ePerp = 1000.0;
    const std::vector<Light> sun = {directionalLight({0, 1, 0}, glm::dvec3(ePerp))};
    const double ft = fresnelTransmittance(m.eta, 1.0);
    const std::vector<glm::dvec3> points = {glm::dvec3(0, 10, 0), glm::dvec3(20.25, 10, -15.5),
                                            glm::dvec3(-25, 10, 25)};
    glm::dvec3 previousError(0.0);
    for (const int cells : {120, 240}) {  // faces of 1 mm, then 0.5 mm
        SCOPED_TRACE(cells);
        const TriangleMesh box = makeBox({120.0f, 20.0f, 120.0f}, {cells, 1, cells});
        const RayScene scene(box);
        IrradianceSamples s = faceCentroidSamples(box);
        computeIrradiance(s, scene, sun, m.eta, FresnelModel::Exact);
        const JensenBuhler jb(m, IrradianceOctree(s), {.epsilon = 0.01});
        glm::dvec3 error(0.0);
        for (const glm::dvec3& x : points) {
            const glm::dvec3 brute = bruteForceExitance(s, m, x);
            const glm::dvec3 hier = jb.exitance(x);
            for (int c = 0; c < 3; ++c) {
                const double closed = ft * ePerp * dipoleTotalDiffuseReflectance(makeDipoleChannel(m, c));
                error[c] = std::max(error[c], std::abs(brute[c] - closed) / closed);
                // The hierarchy adds little to the cubature error at epsilon = 0.01.
                EXPECT_NEAR(hier[c], brute[c], 3e-3 * brute[c]) << c;
            }
        }
        std::printf("faces %.2g mm: relative error of M against the closed form R %.2e G %.2e B %.2e\n",
                    120.0 / cells, error.x, error.y, error.z);
        if (cells == 240) {
            for (int c = 0; c < 3; ++c) {
                EXPECT_LT(error[c], 1e-2) << c;
                EXPECT_LT(error[c], 0.35 * previousError[c] + 1e-4) << c;  // second order
            }
            // Keng's Fresnel: E^ = F_dt E_perp instead.
            computeIrradiance(s, scene, sun, m.eta, FresnelModel::Keng);
            const glm::dvec3 keng = bruteForceExitance(s, m, points[0]);
            const double fdt = 1.0 - fresnelDiffuseReflectance(m.eta);
            for (int c = 0; c < 3; ++c) {
                const double closed = fdt * ePerp * dipoleTotalDiffuseReflectance(makeDipoleChannel(m, c));
                EXPECT_NEAR(keng[c], closed, 1e-2 * closed) << c;
            }
        }
        previousError = error;
    }
}

// Radiance at G-buffer pixels: L = F_t(eta, n . w_o) M / pi; a far point light renders
// like the matching directional light; the frame is independent of the thread count.
TEST(JensenBuhler, RenderFarPointLightEqualsDirectionalLight) {
    const TriangleMesh mesh = makeTorus(12.0f, 5.0f, 64, 32);
    const RayScene scene(mesh);
    const Camera camera = frameSphere({0, 0, 0}, 17.0, 20.0, 35.0, 30.0, 96, 96);
    const GBuffer g = traceGBuffer(scene, mesh, camera);
    const Material m = materialByName("Marble");
    const glm::dvec3 w = glm::normalize(glm::dvec3(0.2, 1.0, 0.5));
    const double D = 1.0e6;
    const glm::dvec3 e(400.0, 300.0, 200.0);
    const IrradianceSamples sPoint = litSamples(mesh, scene, {pointLight(D * w, e * (D * D / 1.0e6))});
    const IrradianceSamples sDir = litSamples(mesh, scene, {directionalLight(w, e)});
    const JensenBuhler jbPoint(m, IrradianceOctree(sPoint), {.epsilon = 0.05});
    const JensenBuhler jbDir(m, IrradianceOctree(sDir), {.epsilon = 0.05});
    JensenBuhlerStats stats;
    const Image a = jbPoint.render(g, &stats);
    const Image b = jbDir.render(g, nullptr);
    EXPECT_EQ(stats.pixels, g.objectPixels());
    EXPECT_GT(stats.pixels, 1000u);
    EXPECT_GT(stats.meanTerms(), 10.0);
    EXPECT_LT(stats.meanTerms(), double(sDir.size()) / 4);
    float maxB = 0.0f;
    for (float v : b.pixels) maxB = std::max(maxB, v);
    ASSERT_GT(maxB, 0.0f);
    for (size_t i = 0; i < a.pixels.size(); ++i) ASSERT_NEAR(a.pixels[i], b.pixels[i], 2e-4f * maxB) << i;

    // Per pixel: the radiance formula and the alpha channel.
    size_t checked = 0;
    for (int y = 0; y < g.height; y += 5)
        for (int x = 0; x < g.width; x += 5) {
            const GBufferPixel& p = g.at(x, y);
            const float* o = b.pixel(x, y);
            EXPECT_EQ(o[3], p.hit ? 1.0f : 0.0f);
            if (!p.hit) {
                EXPECT_EQ(o[0], 0.0f);
                continue;
            }
            const double cosO = std::max(0.0, double(glm::dot(p.normal, p.toViewer)));
            const glm::dvec3 expected =
                fresnelTransmittance(m.eta, cosO) / std::numbers::pi * jbDir.exitance(glm::dvec3(p.position));
            for (int c = 0; c < 3; ++c) EXPECT_NEAR(o[c], expected[c], 1e-6 * expected[c] + 1e-30) << x << "," << y;
            ++checked;
        }
    EXPECT_GT(checked, 30u);

    // Keng's Fresnel: no Fresnel on the way out (Eq. 3).
    const JensenBuhler keng(m, IrradianceOctree(sDir), {.epsilon = 0.05, .fresnel = FresnelModel::Keng});
    for (const GBufferPixel& p : g.pixels) {
        if (!p.hit) continue;
        const glm::vec3 l = keng.radiance(p);
        const glm::dvec3 expected = keng.exitance(glm::dvec3(p.position)) / std::numbers::pi;
        EXPECT_NEAR(l.x, expected.x, 1e-6 * expected.x);
        break;
    }

    // Thread-count independence, bit for bit.
    Image single;
    {
        tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 1);
        single = jbDir.render(g);
    }
    EXPECT_EQ(single.pixels, b.pixels);
}

TEST(JensenBuhler, BadParametersAreErrors) {
    EXPECT_THROW(validateEpsilon(-0.1), Error);
    EXPECT_THROW(validateEpsilon(std::nan("")), Error);
    EXPECT_THROW(validateEpsilon(INFINITY), Error);
    EXPECT_NO_THROW(validateEpsilon(0.0));
    const TriangleMesh mesh = makeIcosphere(1, 5.0f);
    IrradianceSamples s = faceCentroidSamples(mesh);
    const Material m = materialByName("Marble");
    EXPECT_THROW(JensenBuhler(m, IrradianceOctree(s), {.epsilon = -1.0}), Error);
    EXPECT_THROW(IrradianceOctree(s, {.leafSize = 0}), Error);
    EXPECT_THROW(IrradianceOctree(s, {.leafSize = 8, .maxDepth = 65}), Error);
    IrradianceSamples empty;
    EXPECT_THROW(IrradianceOctree{empty}, Error);
    s.irradiance[3].y = -1.0f;
    EXPECT_THROW(IrradianceOctree{s}, Error);
    s.irradiance[3].y = 0.0f;
    s.areas[2] = NAN;
    EXPECT_THROW(IrradianceOctree{s}, Error);
}

// Coincident samples: the depth guard stops the subdivision, the sum stays exact.
TEST(JensenBuhler, CoincidentSamplesHitTheDepthGuard) {
    IrradianceSamples s;
    for (int i = 0; i < 50; ++i) {
        s.positions.push_back({1, 2, 3});
        s.normals.push_back({0, 1, 0});
        s.geometricNormals.push_back({0, 1, 0});
        s.areas.push_back(0.5f);
        s.triangles.push_back(0);
        s.irradiance.push_back(glm::vec3(float(i)));
    }
    s.positions.back() = {5, 2, 3};
    const IrradianceOctree tree(s, {.leafSize = 2, .maxDepth = 10});
    EXPECT_EQ(tree.depth(), 10);
    const Material m = materialByName("Marble");
    const JensenBuhler jb(m, tree, {.epsilon = 0.0});
    const glm::dvec3 x(1, 2.5, 3);
    EXPECT_LT(relativeError(jb.exitance(x), bruteForceExitance(s, m, x)), 1e-13);
}

// setMaterial keeps the tree and replaces the dipole: the image equals a renderer built
// with the new material, and going back gives the first image; another eta is refused.
TEST(JensenBuhler, SetMaterialEqualsANewRendererBitForBit) {
    const TriangleMesh mesh = makeTorus(12.0f, 4.0f, 48, 24);
    const RayScene scene(mesh);
    const IrradianceSamples s = litSamples(mesh, scene, {parseLight("point:30,40,10:1,0.7,0.4")});
    const GBuffer g = traceGBuffer(scene, mesh, frameSphere({0, 0, 0}, 17.0, 20.0, 35.0, 30.0, 40, 40));
    const Material a = materialByName("Skimmilk"), b = materialByName("Ketchup");
    const Image imageA = JensenBuhler(a, IrradianceOctree(s)).render(g);
    const Image imageB = JensenBuhler(b, IrradianceOctree(s)).render(g);
    ASSERT_NE(imageA.pixels, imageB.pixels);
    JensenBuhler jb(a, IrradianceOctree(s));
    jb.setMaterial(b);
    EXPECT_EQ(jb.render(g).pixels, imageB.pixels);
    jb.setMaterial(a);
    EXPECT_EQ(jb.render(g).pixels, imageA.pixels);
    Material otherEta = b;
    otherEta.eta = 1.5;
    try {
        jb.setMaterial(otherEta);
        ADD_FAILURE() << "another eta was accepted";
    } catch (const Error& e) {
        EXPECT_EQ(e.subject(), "material");
        EXPECT_EQ(std::string(e.what()).find('\n'), std::string::npos);
    }
    EXPECT_EQ(jb.material().sigmaA, a.sigmaA);
    EXPECT_EQ(jb.render(g).pixels, imageA.pixels);
}

// SIZE AS MATERIAL (common/material_edit.h): the mesh scaled by s with material m under
// a directional light (whose irradiance does not depend on the scale), seen by the
// camera scaled by s, renders as the unscaled mesh with scaledMaterial(m, s):
// R_d(r; s sigma) = s^2 R_d(s r; sigma) and the areas scale by s^2. Epsilon 0 (the
// brute-force sum). The two renders differ by float rounding only (the scaled float
// positions, hence hit points and distances): exactly 0 for s = 2 (a power of two
// scales every float exactly), 1.7e-5 of the peak for s = 0.37; the bound is 1e-4 of the
// peak at every pixel, with the same coverage.
TEST(JensenBuhler, ScaledObjectEqualsScaledMaterial) {
    const TriangleMesh mesh = makeTorus(6.0f, 2.5f, 48, 24);
    const Material m = materialByName("Skin1");
    const std::vector<Light> lights{parseLight("dir:0.4,1,0.3:500"), parseLight("dir:-1,0.2,-0.5:200,150,100")};
    const Camera base = frameSphere({0, 0, 0}, 9.0, 30.0, 35.0, 30.0, 40, 40);
    auto render = [&](double s, const Material& material) {
        TriangleMesh scaled = mesh;
        for (glm::vec3& p : scaled.positions) p = glm::vec3(glm::dvec3(p) * s);
        const RayScene scene(scaled);
        Camera camera = base;
        camera.eye *= s;
        camera.target *= s;
        const JensenBuhler jb(material, IrradianceOctree(litSamples(scaled, scene, lights)), {.epsilon = 0.0});
        return jb.render(traceGBuffer(scene, scaled, camera));
    };
    for (const double s : {2.0, 0.37}) {
        const Image big = render(s, m), same = render(1.0, scaledMaterial(m, s));
        ASSERT_EQ(big.pixels.size(), same.pixels.size());
        float peak = 0.0f, worst = 0.0f;
        size_t coverage = 0;
        for (size_t i = 0; i < big.pixels.size(); ++i) {
            if (i % 4 == 3) {
                coverage += big.pixels[i] != same.pixels[i] ? 1 : 0;
                continue;
            }
            peak = std::max(peak, same.pixels[i]);
            worst = std::max(worst, std::abs(big.pixels[i] - same.pixels[i]));
        }
        std::printf("size %g: scaled object vs scaled material, max |diff| %.3g of peak %.3g\n", s, worst, peak);
        EXPECT_EQ(coverage, 0u) << s;
        EXPECT_GT(peak, 0.0f);
        EXPECT_LT(worst, 1e-4f * peak) << s;
        // And it is not trivially true: the unscaled material looks different.
        const Image plain = render(1.0, m);
        EXPECT_NE(plain.pixels, same.pixels);
    }
}
