#include "precompute/passes/irradiance_transport.h"

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <algorithm>
#include <cmath>

#include "common/util.h"
#include "common/bssrdf.h"
#include "common/cubemap.h"
#include "common/error.h"
#include "common/ground.h"
#include "common/sh_part.h"
#include "common/shapes.h"

using namespace prt;

namespace {

// Cosine-weighted Fresnel transmittance over the hemisphere:
// int F_t(eta, mu) mu dOmega = 2 pi int_0^1 F_t(eta, mu) mu dmu.
double hemisphericalFresnelCosine(double eta) {
    const int m = 200000;
    double sum = 0;
    for (int k = 0; k < m; ++k) {
        double mu = (k + 0.5) / m;
        sum += fresnelTransmittance(eta, mu) * mu;
    }
    return 2 * kPi * sum / m;
}

SurfaceSample sampleAt(glm::vec3 p, glm::vec3 n) {
    SurfaceSample s;
    s.position = p;
    s.normal = n;
    s.geometricNormal = n;
    return s;
}

TriangleMesh merge(TriangleMesh a, const TriangleMesh& b, glm::vec3 offsetB) {
    const uint32_t base = uint32_t(a.positions.size());
    for (size_t v = 0; v < b.positions.size(); ++v) {
        a.positions.push_back(b.positions[v] + offsetB);
        a.normals.push_back(b.normals[v]);
    }
    for (glm::uvec3 t : b.triangles) a.triangles.push_back(t + glm::uvec3(base));
    return a;
}

double sum(const std::vector<float>& v) {
    double s = 0;
    for (float x : v) s += x;
    return s;
}

// Slab method: does the ray o + t d (t > 0) hit the axis-aligned box [lo, hi]?
bool rayHitsBox(glm::dvec3 o, glm::dvec3 d, glm::dvec3 lo, glm::dvec3 hi) {
    double t0 = 0, t1 = 1e30;
    for (int a = 0; a < 3; ++a) {
        double inv = 1.0 / d[a];
        double ta = (lo[a] - o[a]) * inv, tb = (hi[a] - o[a]) * inv;
        if (ta > tb) std::swap(ta, tb);
        t0 = std::max(t0, ta);
        t1 = std::min(t1, tb);
    }
    return t0 <= t1;
}

}  // namespace

TEST(TexelDirections, SubSolidAnglesSumToFourPiAndDirectionsStayInTheirTexel) {
    for (int s : {1, 2, 3}) {
        TexelDirections d = makeTexelDirections(8, s);
        ASSERT_EQ(d.count(), size_t(6 * 64 * s * s));
        EXPECT_NEAR(sum(d.solidAngle), 4 * kPi, 1e-4);
        for (size_t k = 0; k < d.count(); ++k) {
            TexelCoord t = directionToTexel(8, glm::dvec3(d.x[k], d.y[k], d.z[k]));
            ASSERT_EQ(size_t(t.face * 64 + t.j * 8 + t.i), k / d.subPerTexel());
        }
    }
    EXPECT_THROW(makeTexelDirections(24, 2), Error);
    EXPECT_THROW(makeTexelDirections(32, 0), Error);
}

TEST(IrradianceTransport, UnoccludedEqualsAnalyticFresnelCosine) {
    // With no geometry the transport is F_t cos dOmega over the upper hemisphere.
    const double eta = 1.3;
    TexelDirections dirs = makeTexelDirections(32, 2);
    IrradianceTransportScratch scratch;
    std::vector<float> e(6 * 32 * 32);
    for (glm::vec3 n : {glm::vec3(0, 1, 0), glm::normalize(glm::vec3(0.3f, -0.5f, 0.8f))}) {
        irradianceTransport(nullptr, sampleAt({0, 0, 0}, n), dirs, eta, e.data(), scratch);
        // Total: the hemispherical integral (horizon texels are split by the
        // sub-direction grid, which limits agreement to ~1e-3).
        EXPECT_NEAR(sum(e), hemisphericalFresnelCosine(eta), 2e-3 * hemisphericalFresnelCosine(eta));
        // Per texel far from the horizon: F_t(w_j) cos_j dOmega_j to second order.
        for (int f = 0; f < 6; ++f)
            for (int j = 0; j < 32; ++j)
                for (int i = 0; i < 32; ++i) {
                    glm::dvec3 w = texelDirection(32, f, i, j);
                    double c = glm::dot(w, glm::dvec3(n));
                    size_t k = size_t(f * 1024 + j * 32 + i);
                    if (c < 0.1) {
                        if (c < -0.05) {
                            ASSERT_EQ(e[k], 0.0f);
                        }
                        continue;
                    }
                    // Reference: the texel integral of F_t cos on a fine 8 x 8 sub-grid.
                    double expected = 0;
                    for (int b = 0; b < 8; ++b)
                        for (int a = 0; a < 8; ++a) {
                            double s0 = (i + a / 8.0) / 32, t0 = (j + b / 8.0) / 32, h = 1.0 / 256;
                            double cs = glm::dot(faceUVToDirection(f, s0 + h / 2, t0 + h / 2), glm::dvec3(n));
                            expected += fresnelTransmittance(eta, cs) * cs *
                                        faceRegionSolidAngle(s0, t0, s0 + h, t0 + h);
                        }
                    // 2 x 2 stratified against 8 x 8: the midpoint error of the 2 x 2
                    // grid, largest near the horizon where F_t cos curves most.
                    double tolerance = c > 0.3 ? 1e-3 : 5e-3;
                    ASSERT_NEAR(e[k], expected, tolerance * expected) << f << " " << i << " " << j;
                }
    }
}

TEST(IrradianceTransport, ConvexMeshLosesNoVisibility) {
    // At the centre of a box face (shading normal = geometric normal) nothing of the
    // box can block the outer hemisphere: the transport equals the unoccluded one.
    TriangleMesh box = makeBox({4, 4, 4});
    RayScene scene(box);
    TexelDirections dirs = makeTexelDirections(16, 2);
    IrradianceTransportScratch scratch;
    std::vector<float> vis(6 * 256), free(6 * 256);
    const glm::vec3 points[] = {{0, 2, 0}, {2, 0.3f, -0.7f}, {0.5f, -1.1f, -2}};
    const glm::vec3 normals[] = {{0, 1, 0}, {1, 0, 0}, {0, 0, -1}};
    for (int p = 0; p < 3; ++p) {
        SurfaceSample s = sampleAt(points[p], normals[p]);
        uint64_t rays = irradianceTransport(&scene, s, dirs, 1.3, vis.data(), scratch);
        irradianceTransport(nullptr, s, dirs, 1.3, free.data(), scratch);
        EXPECT_GT(rays, dirs.count() / 2 - 64);  // about half the sub-directions face the normal
        for (size_t k = 0; k < vis.size(); ++k) ASSERT_EQ(vis[k], free[k]) << "texel " << k;
    }
}

TEST(IrradianceTransport, ConcaveSceneBlocksExactlyTheGeometricDirections) {
    // A sample on top of a wide slab under a floating box: a sub-direction is blocked
    // iff its ray hits the box (analytic slab test). The fast path must agree.
    TriangleMesh slab = makeBox({40, 1, 40});                     // top face at y = 0.5
    TriangleMesh scene = merge(slab, makeBox({3, 1, 2}), {1.0f, 3.0f, -0.5f});
    RayScene rayScene(scene);
    const int n = 16, s = 2;
    TexelDirections dirs = makeTexelDirections(n, s);
    IrradianceTransportScratch scratch;
    std::vector<float> e(6 * n * n), expected(6 * n * n, 0.0f);
    const glm::vec3 p(0.2f, 0.5f, 0.1f), up(0, 1, 0);
    irradianceTransport(&rayScene, sampleAt(p, up), dirs, 1.3, e.data(), scratch);

    const glm::dvec3 lo(1 - 1.5, 3 - 0.5, -0.5 - 1), hi(1 + 1.5, 3 + 0.5, -0.5 + 1);
    int blocked = 0;
    for (size_t k = 0; k < dirs.count(); ++k) {
        glm::dvec3 w(dirs.x[k], dirs.y[k], dirs.z[k]);
        if (w.y <= 0) continue;
        // Grazing the slab's own top (the far edge at 20 units) is not blocked for
        // w.y > 0, since the slab top is the plane of the sample.
        if (rayHitsBox(glm::dvec3(p), w, lo, hi)) {
            ++blocked;
            continue;
        }
        expected[k / dirs.subPerTexel()] +=
            float(fresnelTransmittance(1.3, w.y) * w.y * dirs.solidAngle[k]);
    }
    ASSERT_GT(blocked, 50);
    int mismatches = 0;
    for (size_t t = 0; t < e.size(); ++t)
        if (std::abs(e[t] - expected[t]) > 1e-6f) ++mismatches;
    // A sub-direction grazing a box edge may go either way in float arithmetic.
    EXPECT_LE(mismatches, 2);
    // The visible energy is the unoccluded one minus what the box hides.
    const double visibleEnergy = sum(expected);
    EXPECT_NEAR(sum(e), visibleEnergy, 1e-3 * visibleEnergy);
    EXPECT_LT(visibleEnergy, 0.95 * hemisphericalFresnelCosine(1.3));
}

TEST(IrradianceTransport, PassOneIsDeterministicAndKeepsTheLargestCoefficients) {
    TriangleMesh torus = makeTorus(3, 1, 48, 24);
    RayScene scene(torus);
    SampleSet samples = poissonDiskSamples(torus, 40, 5);
    IrradianceTransportOptions opt;
    opt.cubemapSize = 16;
    opt.sampleCoefficients = 6 * 16 * 16;  // everything: reconstruction must be exact
    opt.sampling = VisibilitySampling::Every;  // every ray, as irradianceTransport below
    IrradianceTransportResult all = computeIrradianceTransport(&scene, samples, opt);
    EXPECT_NEAR(all.retainedEnergyFraction, 1.0, 1e-6);
    EXPECT_GT(all.raysTraced, 40u * 6 * 256 * 4 / 3);

    // Reconstruct sample 7 and compare with the dense transport.
    TexelDirections dirs = makeTexelDirections(16, 2);
    IrradianceTransportScratch scratch;
    std::vector<float> dense(6 * 256), coeffs(6 * 256, 0.0f);
    irradianceTransport(&scene, samples.samples[7], dirs, 1.3, dense.data(), scratch);
    addTo(all.vectors[7], 1.0f, coeffs.data());
    for (int f = 0; f < 6; ++f) haarInverseFace(coeffs.data() + f * 256, 16);
    for (size_t k = 0; k < dense.size(); ++k) ASSERT_NEAR(coeffs[k], dense[k], 1e-6);

    // Truncated: exactly K kept, and the same result on one thread as on many.
    opt.sampleCoefficients = 32;
    IrradianceTransportResult many = computeIrradianceTransport(&scene, samples, opt);
    IrradianceTransportResult one;
    {
        tbb::global_control single(tbb::global_control::max_allowed_parallelism, 1);
        one = computeIrradianceTransport(&scene, samples, opt);
    }
    EXPECT_LT(many.retainedEnergyFraction, 1.0);
    EXPECT_GT(many.retainedEnergyFraction, 0.9);
    for (size_t i = 0; i < samples.samples.size(); ++i) {
        ASSERT_EQ(many.vectors[i].size(), 32u);
        ASSERT_EQ(many.vectors[i].index, one.vectors[i].index);
        ASSERT_EQ(many.vectors[i].value, one.vectors[i].value);
    }
    EXPECT_EQ(many.raysTraced, one.raysTraced);
}

// With an SH part (--sh-terms 9): every sample's vector ends with its 9 SH entries, and
// keeping everything it relights (Haar light + its SH projections) exactly as the
// plain vector does; truncated, it still holds exactly K entries, 9 of them SH.
TEST(IrradianceTransport, ShPartRelightsAsThePlainVector) {
    TriangleMesh torus = makeTorus(3, 1, 48, 24);
    RayScene scene(torus);
    SampleSet samples = poissonDiskSamples(torus, 30, 5);
    IrradianceTransportOptions opt;
    opt.cubemapSize = 16;
    const size_t count = 6 * 16 * 16;
    opt.sampleCoefficients = count;
    const IrradianceTransportResult plain = computeIrradianceTransport(&scene, samples, opt);
    opt.shTerms = 9;
    opt.sampleCoefficients = count + 9;
    const IrradianceTransportResult split = computeIrradianceTransport(&scene, samples, opt);
    EXPECT_NEAR(split.retainedEnergyFraction, 1.0, 1e-6);
    std::vector<float> light(count + 9);
    for (size_t k = 0; k < count; ++k) light[k] = float(0.5 + 0.5 * std::sin(0.37 * double(k)));
    prt::shProjectLight(light.data(), 16, 1, 9, light.data() + count);
    const auto relit = [&](const prt::SparseVector& v, bool absolute = false) {
        double s = 0.0;
        for (size_t k = 0; k < v.size(); ++k) {
            const double p = double(v.value[k]) * light[v.index[k]];
            s += absolute ? std::fabs(p) : p;
        }
        return s;
    };
    for (size_t i = 0; i < samples.samples.size(); ++i) {
        ASSERT_EQ(split.vectors[i].index.back(), count + 8);
        EXPECT_NEAR(relit(split.vectors[i]), relit(plain.vectors[i]), 1e-5 * relit(plain.vectors[i], true));
    }
    opt.sampleCoefficients = 32;
    const IrradianceTransportResult truncated = computeIrradianceTransport(&scene, samples, opt);
    for (const prt::SparseVector& v : truncated.vectors) {
        ASSERT_EQ(v.size(), 32u);
        EXPECT_EQ(v.index[32 - 9], count);
    }
}

// Coherent visibility traces one probe per texel and refines only texels next to a
// change: on a torus (self-shadowing along smooth boundaries) it must reproduce Every's
// cubemaps closely with far fewer rays, equal it exactly where nothing is occluded, and
// on a scene with an occluder narrower than a texel show the error it is documented to
// make (so this test can fail if the refinement rule were dropped or made too loose).
TEST(IrradianceTransport, CoherentVisibilityMatchesEveryRayWithFewerRays) {
    TriangleMesh torus = makeTorus(3, 1, 48, 24);
    RayScene scene(torus);
    SampleSet samples = poissonDiskSamples(torus, 60, 9);
    const TexelDirections dirs = makeTexelDirections(32, 2);
    IrradianceTransportScratch scratch;
    std::vector<float> every(6 * 1024), coherent(6 * 1024);
    uint64_t raysEvery = 0, raysCoherent = 0;
    double sumSq = 0.0, sumSqDiff = 0.0, worstTexel = 0.0, worstSample = 0.0;
    for (const SurfaceSample& s : samples.samples) {
        raysEvery += irradianceTransport(&scene, s, dirs, 1.3, every.data(), scratch, VisibilitySampling::Every);
        raysCoherent +=
            irradianceTransport(&scene, s, dirs, 1.3, coherent.data(), scratch, VisibilitySampling::Coherent);
        double total = 0.0, diff = 0.0, maxE = 0.0;
        for (size_t t = 0; t < every.size(); ++t) {
            total += double(every[t]) * every[t];
            diff += double(every[t] - coherent[t]) * (every[t] - coherent[t]);
            maxE = std::max(maxE, double(every[t]));
        }
        for (size_t t = 0; t < every.size(); ++t)
            worstTexel = std::max(worstTexel, std::abs(double(every[t] - coherent[t])) / maxE);
        sumSq += total;
        sumSqDiff += diff;
        worstSample = std::max(worstSample, std::sqrt(diff / total));
    }
    const double relative = std::sqrt(sumSqDiff / sumSq);
    std::printf("[ info ] torus, 60 samples, 6x32x32 s=2: rays %llu -> %llu (%.2fx), E relative L2 %.2e "
                "(worst sample %.2e, worst texel %.2e of the sample's largest)\n",
                (unsigned long long)raysEvery, (unsigned long long)raysCoherent,
                double(raysEvery) / double(raysCoherent), relative, worstSample, worstTexel);
    EXPECT_LT(double(raysCoherent), 0.6 * double(raysEvery));
    EXPECT_LT(relative, 1e-3);

    // Nothing occluded (the inside of nothing: one sample facing up over an empty scene
    // except a far-away triangle below the horizon): every probe agrees, identical result.
    TriangleMesh floor;
    floor.positions = {{-100, -50, -100}, {0, -50, 100}, {100, -50, -100}};
    floor.normals.assign(3, glm::vec3(0, 1, 0));
    floor.triangles = {{0, 1, 2}};
    RayScene open(floor);
    const SurfaceSample up = sampleAt({0, 0, 0}, {0, 1, 0});
    irradianceTransport(&open, up, dirs, 1.3, every.data(), scratch, VisibilitySampling::Every);
    irradianceTransport(&open, up, dirs, 1.3, coherent.data(), scratch, VisibilitySampling::Coherent);
    EXPECT_EQ(every, coherent);

    // A needle-thin occluder (a sliver 0.02 rad wide, under a texel of ~0.06 rad)
    // high above the sample: Every sees it in the sub-directions it crosses; Coherent
    // sees it only where it crosses a probe, so the two differ -- the documented limit.
    TriangleMesh needle;
    // Along z at x = 0.0469: the +Y face's sub-direction column a = 1 of texel column 16
    // (u = 33.5 / 64), between the probe columns at x = 0.0156 and 0.078.
    needle.positions = {{0.0369f, 1.0f, -0.6f}, {0.0469f, 1.0f, 0.6f}, {0.0569f, 1.0f, -0.6f}};
    needle.normals.assign(3, glm::vec3(0, -1, 0));
    needle.triangles = {{0, 1, 2}};
    RayScene thin(needle);
    irradianceTransport(&thin, up, dirs, 1.3, every.data(), scratch, VisibilitySampling::Every);
    irradianceTransport(&thin, up, dirs, 1.3, coherent.data(), scratch, VisibilitySampling::Coherent);
    double lostEvery = 0.0, lostCoherent = 0.0;
    std::vector<float> free(6 * 1024);
    irradianceTransport(nullptr, up, dirs, 1.3, free.data(), scratch);
    for (size_t t = 0; t < free.size(); ++t) {
        lostEvery += free[t] - every[t];
        lostCoherent += free[t] - coherent[t];
    }
    std::printf("[ info ] needle: irradiance blocked, every ray %.3e sr, coherent %.3e sr\n", lostEvery, lostCoherent);
    EXPECT_GT(lostEvery, 0.0);
    EXPECT_NE(every, coherent);
}

namespace {

// int F_t(eta, n . w) (n . w) dOmega over the directions above both the surface's
// horizon (n . w > 0) and the plane (w.y > 0): at cosine mu to n the directions form a
// circle, of which the fraction acos(c) / pi lies above the plane, c = -mu n_y /
// (sqrt(1 - mu^2) sqrt(1 - n_y^2)); then a 1D midpoint rule in mu.
double fresnelCosineAbovePlane(double eta, glm::dvec3 n) {
    n = glm::normalize(n);
    const double s = std::sqrt(std::max(0.0, 1.0 - n.y * n.y));
    const int m = 200000;
    double total = 0;
    for (int k = 0; k < m; ++k) {
        const double mu = (k + 0.5) / m;
        double fraction;
        if (s < 1e-12) fraction = n.y > 0 ? 1.0 : 0.0;
        else fraction = std::acos(std::clamp(-mu * n.y / (std::sqrt(1 - mu * mu) * s), -1.0, 1.0)) / kPi;
        total += fresnelTransmittance(eta, mu) * mu * fraction;
    }
    return 2 * kPi * total / m;
}

}  // namespace

TEST(IrradianceTransport, GroundPlaneOccludesExactlyTheDirectionsBelowIt) {
    // A sphere resting on the ground plane under a constant environment: each sample's
    // pass-1 transport sums to the integral of F_t cos over the directions above both
    // its horizon and the plane. Face centroids with face normals: the flat faces of a
    // convex solid do not shadow themselves, so only the plane occludes. The plane is
    // as wide as allowed; a ray from height h going below the horizontal can still miss
    // it when |w.y| < h / H (H its half side), which bounds the closed form's excess
    // over the finite plane by 2 h / H (the band's solid angle with F_t cos <= 1, over
    // half a circle); the rest of the tolerance is the cubemap's horizon texels.
    const double eta = 1.3;
    const TriangleMesh sphere = makeIcosphere(3, 10.0f);
    GroundSettings settings;
    settings.halfExtentPerDiagonal = kMaxGroundHalfExtent;
    settings.cells = 1;
    const GroundPlane plane = groundPlaneUnder(bounds(sphere), settings);
    const RayScene withPlane(withGround(sphere, groundMesh(plane)));
    const RayScene alone(sphere);
    const TexelDirections dirs = makeTexelDirections(32, 4);
    IrradianceTransportScratch scratch;
    std::vector<float> e(6 * 32 * 32);
    const double full = hemisphericalFresnelCosine(eta);
    int facingDown = 0;
    for (size_t t = 0; t < sphere.triangleCount(); t += 17) {
        const glm::uvec3 tri = sphere.triangles[t];
        const glm::vec3 a = sphere.positions[tri.x], b = sphere.positions[tri.y], c = sphere.positions[tri.z];
        const glm::vec3 n = glm::normalize(glm::cross(b - a, c - a));
        const SurfaceSample sample = sampleAt((a + b + c) / 3.0f, n);
        irradianceTransport(&withPlane, sample, dirs, eta, e.data(), scratch);
        const double expected = fresnelCosineAbovePlane(eta, glm::dvec3(n));
        const double band = 2.0 * (double(sample.position.y) - plane.height) / plane.halfExtent;
        EXPECT_NEAR(sum(e), expected, 3e-3 * full + band) << "face " << t << " normal y " << n.y;
        if (n.y < -0.3) {
            ++facingDown;
            // Without the plane the same sample sees the whole hemisphere.
            irradianceTransport(&alone, sample, dirs, eta, e.data(), scratch);
            EXPECT_NEAR(sum(e), full, 3e-3 * full);
            EXPECT_LT(expected, 0.8 * full);
        }
    }
    EXPECT_GT(facingDown, 5);
}
