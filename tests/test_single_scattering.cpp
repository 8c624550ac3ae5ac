// Tests of the single-scattering precomputation (Wang et al. 2005, Eqs. 4, 5, 10, 11)
// and of its integration into the precompute pipeline.

#include "precompute/passes/single_scattering.h"

#include <gtest/gtest.h>
#include <tbb/global_control.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <limits>

#include "common/util.h"
#include "common/cubemap.h"
#include "common/error.h"
#include "common/haar.h"
#include "common/sh_part.h"
#include "common/mesh.h"
#include "precompute/passes/phase_factoring.h"
#include "precompute/job/pipeline.h"
#include "common/progress.h"
#include "common/shapes.h"
#include "common/transport_file.h"
#include "common/mesh_io.h"

using namespace prt;
namespace fs = std::filesystem;

namespace {

// Scratch files live under the test's working directory (the build tree).
fs::path scratchDir() {
    static const fs::path d = fs::current_path() / ("ss_test_" + std::to_string(getpid()));
    fs::create_directories(d);
    return d;
}

struct ScratchCleanup : ::testing::Environment {
    void TearDown() override {
        std::error_code ec;
        fs::remove_all(fs::current_path() / ("ss_test_" + std::to_string(getpid())), ec);
    }
};
const auto* const kCleanup = ::testing::AddGlobalTestEnvironment(new ScratchCleanup);

// The vertex at `p` whose normal is `n` (the slab's faces have their own vertices).
size_t findVertex(const TriangleMesh& mesh, glm::vec3 p, glm::vec3 n) {
    size_t best = 0;
    float bestD = std::numeric_limits<float>::infinity();
    for (size_t v = 0; v < mesh.positions.size(); ++v) {
        if (glm::dot(mesh.normals[v], n) < 0.99f) continue;
        const float d = glm::length(mesh.positions[v] - p);
        if (d < bestD) bestD = d, best = v;
    }
    EXPECT_LT(bestD, 1e-5f);
    return best;
}

TriangleMesh merge(const TriangleMesh& a, const TriangleMesh& b) {
    TriangleMesh m = a;
    const uint32_t base = uint32_t(a.positions.size());
    m.positions.insert(m.positions.end(), b.positions.begin(), b.positions.end());
    m.normals.insert(m.normals.end(), b.normals.begin(), b.normals.end());
    for (glm::uvec3 t : b.triangles) m.triangles.push_back(t + glm::uvec3(base));
    return m;
}

TriangleMesh translated(TriangleMesh m, glm::vec3 d) {
    for (glm::vec3& p : m.positions) p += d;
    return m;
}

// Dense single-scattering transport of one vertex.
std::vector<float> denseAt(const SingleScatteringContext& ctx, size_t v,
                           SingleScatteringStats* statsOut = nullptr) {
    std::vector<float> dense(ctx.denseSize());
    SingleScatteringScratch scratch;
    SingleScatteringStats stats;
    singleScatteringVertex(ctx, ctx.mesh().positions[v], ctx.mesh().normals[v], dense.data(),
                           scratch, stats);
    if (statsOut) *statsOut = stats;
    return dense;
}

// |a - ref| / |ref| (0 when both are zero).
double relativeL2(const std::vector<float>& a, const std::vector<float>& ref) {
    double d2 = 0.0, r2 = 0.0;
    for (size_t k = 0; k < a.size(); ++k) {
        d2 += double(a[k] - ref[k]) * (a[k] - ref[k]);
        r2 += double(ref[k]) * ref[k];
    }
    if (!(r2 > 0.0)) return d2 > 0.0 ? std::numeric_limits<double>::infinity() : 0.0;
    return std::sqrt(d2 / r2);
}

size_t texelIndex(int n, int face, int i, int j) { return (size_t(face) * n + j) * n + i; }

// Single scattering of a half space (flat surface, normal n), viewed along the normal,
// lit through one texel of direction w (cos_i = w . n) and solid angle dOmega, phase
// value p, path truncated at depth H (the slab's thickness):
//
//   The integration path is x_p = x_o - s n, which for a normal view IS the refracted
//   view ray (w_o' = -n), so the approximation of Wang Fig. 2b is exact here. The
//   light reaching x_p from w enters the flat surface and travels inside along the
//   refracted direction, whose cosine with the normal is cos_t = sqrt(1 - (1 -
//   cos_i^2) / eta^2); from depth s that is s_i' = s / cos_t. Eq. 5 gives exactly this:
//   the unrefracted ray from x_p toward w leaves after s_i = s / cos_i, and
//   s_i cos_i / cos_t = s / cos_t. Hence (Eq. 10 with Eq. 11)
//
//     T = int_0^H sigma_s p F_t(cos_i) e^(-sigma_t s / cos_t) dOmega e^(-sigma_t s) ds
//       = sigma_s p F_t(cos_i) dOmega (1 - e^(-k H)) / k,   k = sigma_t (1 + 1 / cos_t),
//
//   per channel. This is the Hanrahan-Krueger single-scattering term for a semi-
//   infinite medium (as in Jensen et al. 2001, Eq. 4, without the eta^2 radiance
//   factors, which Wang Eq. 4 also leaves out): with cos_o' = 1 the familiar
//   cos_i' / (sigma_t (cos_i' + cos_o')) = 1 / (sigma_t (1 + 1 / cos_t)). The relit
//   radiance under a light of radiance L in that texel is F_t(cos_o) T L.
double halfSpaceSingleScattering(double sigmaS, double sigmaT, double eta, double cosI,
                                 double dOmega, double phase, double H) {
    const double cosT = std::sqrt(1.0 - (1.0 - cosI * cosI) / (eta * eta));
    const double k = sigmaT * (1.0 + 1.0 / cosT);
    return sigmaS * phase * fresnelTransmittance(eta, cosI) * dOmega * -std::expm1(-k * H) / k;
}

// The isotropic closed form above at texel (i, j) of the +Y face (a slab's normal) of an
// N x N cubemap, channel ch, for material m and a slab H mm thick.
double halfSpaceTopTexel(const Material& m, int n, int i, int j, int ch, double H) {
    const glm::dvec3 w = texelDirection(n, 2, i, j);
    return halfSpaceSingleScattering(m.sigmaS()[ch], m.sigmaT()[ch], m.eta, w.y, texelSolidAngle(n, i, j),
                                     1.0 / (4.0 * kPi), H);
}

}  // namespace

// ---------------------------------------------------------------------------------
// Helpers
// ---------------------------------------------------------------------------------

TEST(SingleScatteringHelpers, PathSamplesFollowTheFormulas) {
    const double sigma = 2.0, dm = 0.5;
    const int n = 16;
    const double lambda = 1.0 - std::exp(-sigma * dm);
    EXPECT_NEAR(pathSampleLambda(sigma, dm), lambda, 1e-15);
    const std::vector<PathSample> s = makePathSamples(sigma, dm, n);
    ASSERT_EQ(s.size(), size_t(n));
    double sumUnit = 0, sumExp = 0;
    for (int i = 1; i <= n; ++i) {
        const PathSample& p = s[size_t(i - 1)];
        const double xi = (i - 0.5) / n;
        // s_i = -ln(1 - lambda xi_i) / |sigma_t|
        EXPECT_NEAR(p.distance, -std::log(1.0 - lambda * xi) / sigma, 1e-12);
        EXPECT_NEAR(p.distance, pathSampleDistance(sigma, dm, xi), 1e-12);
        EXPECT_GT(p.distance, 0.0);
        EXPECT_LT(p.distance, dm);
        if (i > 1) {
            EXPECT_GT(p.distance, s[size_t(i - 2)].distance);
        }
        // weight = 1 / (N pdf(s)), pdf(s) = sigma e^(-sigma s) / lambda
        const double pdf = sigma * std::exp(-sigma * p.distance) / lambda;
        EXPECT_NEAR(pathSamplePdf(sigma, dm, p.distance), pdf, 1e-12);
        EXPECT_NEAR(p.weight * n * pdf, 1.0, 1e-12);
        sumUnit += p.weight;
        sumExp += p.weight * std::exp(-sigma * p.distance);
    }
    // An integrand proportional to the pdf is integrated exactly:
    // int_0^dm e^(-sigma s) ds = lambda / sigma.
    EXPECT_NEAR(sumExp, lambda / sigma, 1e-12);
    // A constant is integrated by the midpoint rule in xi, of lambda / (sigma (1 -
    // lambda xi)): close to d_m while lambda is not near 1 (here sigma d_m = 1,
    // lambda = 0.63; the error is 1.3e-3). (For sigma d_m >> 1 this integrand is nearly
    // singular at xi = 1 and 16 samples underestimate it; the real integrand always
    // carries e^(-sigma_t s), which removes that.)
    EXPECT_NEAR(sumUnit, dm, 3e-3 * dm);
    // The pdf is normalised on [0, d_m] and zero outside.
    double integral = 0;
    const int steps = 200000;
    for (int k = 0; k < steps; ++k) integral += pathSamplePdf(sigma, dm, (k + 0.5) * dm / steps) * dm / steps;
    EXPECT_NEAR(integral, 1.0, 1e-8);
    EXPECT_EQ(pathSamplePdf(sigma, dm, -0.1), 0.0);
    EXPECT_EQ(pathSamplePdf(sigma, dm, dm + 0.1), 0.0);
    // Thin paths: lambda ~ sigma d_m stays accurate (expm1), samples ~ uniform.
    EXPECT_NEAR(pathSampleLambda(1.0, 1e-9) / 1e-9, 1.0, 1e-8);
    const std::vector<PathSample> thin = makePathSamples(1.0, 1e-6, 4);
    EXPECT_NEAR(thin[0].distance, 0.125e-6, 1e-12);
    EXPECT_NEAR(thin[3].distance, 0.875e-6, 1e-12);
    // Bad input.
    EXPECT_THROW(makePathSamples(0.0, 1.0, 16), Error);
    EXPECT_THROW(makePathSamples(1.0, 0.0, 16), Error);
    EXPECT_THROW(makePathSamples(1.0, std::numeric_limits<double>::infinity(), 16), Error);
    EXPECT_THROW(makePathSamples(1.0, 1.0, 0), Error);
}

TEST(SingleScatteringHelpers, GaussLegendrePathSamples) {
    EXPECT_EQ(parsePathQuadrature("midpoint"), PathQuadrature::Midpoint);
    EXPECT_EQ(parsePathQuadrature("gauss"), PathQuadrature::GaussLegendre);
    EXPECT_STREQ(toString(PathQuadrature::GaussLegendre), "gauss");
    EXPECT_STREQ(toString(PathQuadrature::Midpoint), "midpoint");
    EXPECT_THROW(parsePathQuadrature("Gauss"), Error);
    EXPECT_THROW(pathQuadratureRule(PathQuadrature::GaussLegendre, 0), Error);
    EXPECT_THROW(makePathSamples(1.0, 1.0, 0, PathQuadrature::GaussLegendre), Error);
    // The N-point rule on [0, 1]: nodes increasing inside (0, 1), symmetric about 1/2,
    // weights positive summing to 1, xi^k integrated exactly for k <= 2N - 1 (not 2N).
    for (int n = 1; n <= 12; ++n) {
        const std::vector<QuadratureNode> r = pathQuadratureRule(PathQuadrature::GaussLegendre, n);
        ASSERT_EQ(r.size(), size_t(n));
        for (int i = 0; i < n; ++i) {
            EXPECT_GT(r[size_t(i)].xi, 0.0);
            EXPECT_LT(r[size_t(i)].xi, 1.0);
            EXPECT_GT(r[size_t(i)].weight, 0.0);
            if (i > 0) {
                EXPECT_GT(r[size_t(i)].xi, r[size_t(i - 1)].xi);
            }
            EXPECT_NEAR(r[size_t(i)].xi + r[size_t(n - 1 - i)].xi, 1.0, 1e-14);
        }
        for (int k = 0; k <= 2 * n; ++k) {
            double sum = 0.0;
            for (const QuadratureNode& q : r) sum += q.weight * std::pow(q.xi, k);
            if (k < 2 * n) {
                EXPECT_NEAR(sum, 1.0 / (k + 1), 1e-13) << "n " << n << " k " << k;
            } else if (n <= 6) {  // (larger N: the error of degree 2N falls below rounding)
                EXPECT_GT(std::abs(sum - 1.0 / (k + 1)), 1e-9) << "n " << n << " k " << k;
            }
        }
    }
    // The midpoint rule's samples are those of the historical expression, bit for bit.
    {
        const double sigma = 2.57, dm = 7.3;
        const std::vector<PathSample> mid = makePathSamples(sigma, dm, 16, PathQuadrature::Midpoint);
        const double lambda = pathSampleLambda(sigma, dm);
        for (int i = 1; i <= 16; ++i) {
            const double xi = (i - 0.5) / 16;
            EXPECT_EQ(mid[size_t(i - 1)].distance, -std::log1p(-lambda * xi) / sigma);
            EXPECT_EQ(mid[size_t(i - 1)].weight, lambda / ((1.0 - lambda * xi) * 16 * sigma));
        }
    }
    // The flat-surface integrand e^(-k s), k = sigma_t^c (1 + 1/cos_t) (channel c, light
    // at cos_i; in xi it is (1 - lambda xi)^p, p = k / |sigma_t| - 1), for Marble over
    // the whole range of cos_i, on a half space (d_m = 20 mm) and thin paths: the
    // header's bounds, 4 Gauss points <= 8e-4, 6 <= 2.5e-4, against 16 midpoints'
    // <= 1.6e-3 (the previous rule). An integrand proportional to the pdf is exact.
    const Material m = materialByName("Marble");
    const double sigma = samplingExtinction(m);
    const glm::dvec3 sigmaT = m.sigmaT();
    double worst[3] = {0, 0, 0};
    for (double dm : {20.0, 1.0, 0.1})
        for (double cosI : {1.0, 0.7, 0.4, 0.1, 0.0})
            for (int c = 0; c < 3; ++c) {
                const double cosT = std::sqrt(1.0 - (1.0 - cosI * cosI) / (m.eta * m.eta));
                const double k = sigmaT[c] * (1.0 + 1.0 / cosT);
                const double exact = -std::expm1(-k * dm) / k;
                int slot = 0;
                for (auto [rule, n] : {std::pair{PathQuadrature::GaussLegendre, 4},
                                       std::pair{PathQuadrature::GaussLegendre, 6},
                                       std::pair{PathQuadrature::Midpoint, 16}}) {
                    double est = 0.0, pdfExact = 0.0;
                    for (const PathSample& p : makePathSamples(sigma, dm, n, rule)) {
                        est += p.weight * std::exp(-k * p.distance);
                        pdfExact += p.weight * std::exp(-sigma * p.distance);
                    }
                    worst[slot] = std::max(worst[slot], std::abs(est / exact - 1.0));
                    EXPECT_NEAR(pdfExact, pathSampleLambda(sigma, dm) / sigma, 1e-12 * dm);
                    ++slot;
                }
            }
    EXPECT_LT(worst[0], 8e-4);
    EXPECT_LT(worst[1], 2.5e-4);
    EXPECT_LT(worst[2], 1.6e-3);
    EXPECT_GT(worst[2], worst[1]);  // 6 Gauss points beat 16 midpoints on flat surfaces
}

TEST(SingleScatteringHelpers, RefractedPathLengthIsEquation5) {
    const double eta = 1.3;
    EXPECT_DOUBLE_EQ(refractedPathLength(2.5, 1.0, eta), 2.5);  // normal incidence
    // Flat surface, x_p at depth d: the unrefracted ray toward w leaves after
    // s_i = d / cos_i; the refracted light path from the surface down to x_p is
    // d / cos_t with cos_t from refractDirection.
    const glm::dvec3 n(0, 0, 1);
    for (double cosI : {0.95, 0.7, 0.3, 0.05}) {
        const glm::dvec3 w(std::sqrt(1 - cosI * cosI), 0, cosI);
        glm::dvec3 wt;
        ASSERT_TRUE(refractDirection(w, n, eta, wt));
        const double cosT = -glm::dot(wt, n);
        const double d = 0.8;
        EXPECT_NEAR(refractedPathLength(d / cosI, cosI, eta), d / cosT, 1e-12) << cosI;
        EXPECT_NEAR(refractedPathLength(d / cosI, -cosI, eta), d / cosT, 1e-12);  // |w . n|
        EXPECT_LE(refractedPathLength(d / cosI, cosI, eta), d / cosI);  // eta > 1: shorter
    }
    // eta < 1: total internal reflection beyond the critical angle.
    EXPECT_LT(refractedPathLength(1.0, 0.1, 0.8), 0.0);
    EXPECT_GT(refractedPathLength(1.0, 0.9, 0.8), 0.0);
}

TEST(SingleScatteringHelpers, FarSideDistanceAndCap) {
    const TriangleMesh slab = makeBox({10.0f, 3.0f, 10.0f}, {4, 2, 4});
    const RayScene scene(slab);
    const size_t top = findVertex(slab, {0, 1.5f, 0}, {0, 1, 0});
    FarSide f = farSideDistance(scene, slab.positions[top], slab.normals[top], 99.0);
    EXPECT_TRUE(f.hit);
    EXPECT_NEAR(f.distance, 3.0, 1e-5);
    // Side face.
    const size_t side = findVertex(slab, {5.0f, 0, 0}, {1, 0, 0});
    f = farSideDistance(scene, slab.positions[side], slab.normals[side], 99.0);
    EXPECT_TRUE(f.hit);
    EXPECT_NEAR(f.distance, 10.0, 1e-5);

    // Open mesh: the bottom face removed, nothing below the top face -> the cap.
    TriangleMesh open = slab;
    open.triangles.clear();
    for (size_t t = 0; t < slab.triangles.size(); ++t)
        if (faceNormal(slab, t).y > -0.5f) open.triangles.push_back(slab.triangles[t]);
    const RayScene openScene(open);
    f = farSideDistance(openScene, open.positions[top], open.normals[top], 7.0);
    EXPECT_FALSE(f.hit);
    EXPECT_EQ(f.distance, 7.0);

    // The kernel uses depthCapMeanFreePaths / |sigma_t| and counts the capped vertex.
    const Material m = materialByName("Marble");
    SingleScatteringOptions o;
    o.cubemapSize = 4;
    const SingleScatteringContext ctx(openScene, open, m, nullptr, o);
    EXPECT_NEAR(ctx.depthCap(), 16.0 / luminance(m.sigmaT()), 1e-12);
    EXPECT_NEAR(ctx.samplingSigma(), luminance(m.sigmaT()), 1e-12);
    SingleScatteringStats stats;
    denseAt(ctx, top, &stats);
    EXPECT_EQ(stats.cappedDepths, 1u);
    EXPECT_NEAR(stats.depthSum, ctx.depthCap(), 1e-12);
    EXPECT_GT(stats.escapedRays, 0u);  // downward rays leave through the missing face
}

TEST(SingleScatteringHelpers, FresnelTableAndLightMapLookup) {
    const TriangleMesh box = makeBox({1, 1, 1});
    const RayScene scene(box);
    Material m = materialByName("Marble");
    m.g = 0.3;
    const PhaseFactorization phase = factorPhaseFunction(m.g, 3, 16);
    for (double eta : {1.3, 0.8, 2.0}) {
        m.eta = eta;
        const SingleScatteringContext ctx(scene, box, m, &phase, {});
        double worst = 0;
        for (int k = 0; k <= 100000; ++k) {
            const float c = float(k / 100000.0);  // the kernel's cosines are floats
            worst = std::max(worst, std::abs(ctx.fresnel(c) - fresnelTransmittance(eta, c)));
        }
        EXPECT_LT(worst, 1e-6) << eta;
    }
    // The K-channel lookup equals Cubemap::sampleBilinear of each light map.
    m.eta = 1.3;
    const SingleScatteringContext ctx(scene, box, m, &phase, {});
    ASSERT_EQ(ctx.terms(), 3);
    EXPECT_FALSE(ctx.isotropic());
    uint32_t state = 12345;
    auto rnd = [&] { state = state * 1664525u + 1013904223u; return (state >> 8) / 16777216.0 * 2 - 1; };
    for (int t = 0; t < 1000; ++t) {
        const glm::dvec3 a = glm::normalize(glm::dvec3(rnd(), rnd(), rnd()));
        float g[3];
        ctx.lightMapValues(glm::vec3(a), g);
        for (int k = 0; k < 3; ++k)
            EXPECT_NEAR(g[k], phase.lightMaps[size_t(k)].sampleBilinear(a, 0), 1e-5);
    }
    // Isotropic: 1 / (4 pi).
    m.g = 0.0;
    const SingleScatteringContext iso(scene, box, m, nullptr, {});
    float g0 = 0;
    iso.lightMapValues(glm::vec3(0, 0, 1), &g0);
    EXPECT_FLOAT_EQ(g0, float(1.0 / (4.0 * kPi)));
    // Phase and material must agree; g != 0 needs a factorisation.
    EXPECT_THROW(SingleScatteringContext(scene, box, m, &phase, {}), Error);
    m.g = 0.3;
    EXPECT_THROW(SingleScatteringContext(scene, box, m, nullptr, {}), Error);
}

// ---------------------------------------------------------------------------------
// Physics
// ---------------------------------------------------------------------------------

TEST(SingleScattering, ThickSlabMatchesTheHalfSpaceClosedForm) {
    // Marble (sigma_t ~ 2.2-3.0 mm^-1, mean free path 0.39 mm): a 20 mm thick slab is
    // 51 mean free paths deep (e^-51: a half space), 60 mm wide; the paths that matter
    // end within ~1.5 mm of the centre vertex. Normal view at the top centre.
    const Material m = materialByName("Marble");
    const float H = 20.0f;
    const TriangleMesh slab = makeSlab(60.0f, 60.0f, H, 6);
    const RayScene scene(slab);
    const int n = 16;
    // The default rule (Gauss-Legendre, 6 points), 4 Gauss points and the previous
    // default (16 midpoints): all within the tolerance below.
    const SingleScatteringOptions defaults;
    for (auto [rule, samples] : {std::pair{defaults.pathQuadrature, defaults.pathSamples},
                                 std::pair{PathQuadrature::GaussLegendre, 4},
                                 std::pair{PathQuadrature::Midpoint, 16}}) {
    SCOPED_TRACE(std::string(toString(rule)) + " " + std::to_string(samples));
    SingleScatteringOptions o;
    o.cubemapSize = n;
    o.pathQuadrature = rule;
    o.pathSamples = samples;
    o.minThroughput = 0.0;
    o.vertexCoefficients = size_t(6) * n * n;  // keep everything: the Haar path is exact
    const SingleScatteringContext ctx(scene, slab, m, nullptr, o);
    const size_t v = findVertex(slab, {0, H / 2, 0}, {0, 1, 0});
    SingleScatteringStats stats;
    std::vector<float> dense = denseAt(ctx, v, &stats);
    EXPECT_EQ(stats.cappedDepths, 0u);
    EXPECT_NEAR(stats.depthSum, H, 1e-4);
    EXPECT_EQ(stats.reversedHits, 0u);
    EXPECT_EQ(stats.outsideSamples, 0u);
    EXPECT_EQ(stats.flippedNormals, 0u);
    EXPECT_EQ(stats.escapedRays, 0u);
    EXPECT_EQ(stats.exitRays, uint64_t(samples) * 6 * n * n);

    // TOLERANCE. In xi-space the integrand of channel c is proportional to
    // (1 - lambda xi)^p with p = sigma_t^c (1 + 1/cos_t) / |sigma_t| - 1, here
    // p in [0.71, 1.6]; the 16-point midpoint rule integrates it to within 7e-4, 4 and 6
    // Gauss-Legendre points to within 7.7e-4 and 2.2e-4 (all exact for p = 1, i.e. when
    // sigma_t^c = |sigma_t| at normal incidence; GaussLegendrePathSamples). Float
    // accumulation adds ~1e-6. Hence 0.2%.
    struct Case { int i, j; };
    double maxTop = 0;
    for (Case c : {Case{8, 8}, Case{7, 7}, Case{15, 8}, Case{3, 12}, Case{0, 0}}) {
        const size_t t = texelIndex(n, 2, c.i, c.j);  // +Y, the slab's normal
        for (int ch = 0; ch < 3; ++ch) {
            const double expected = halfSpaceTopTexel(m, n, c.i, c.j, ch, H);
            EXPECT_NEAR(dense[t * 3 + ch], expected, 2e-3 * expected)
                << "texel " << c.i << "," << c.j << " channel " << ch;
            maxTop = std::max(maxTop, expected);
        }
    }
    // Light from below the surface reaches x_p only through 20 mm of marble.
    for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i)
            for (int ch = 0; ch < 3; ++ch)
                EXPECT_LT(dense[texelIndex(n, 3, i, j) * 3 + ch], 1e-12 * maxTop);

    // Through the Haar transform and a single-texel light vector (all coefficients
    // kept): the sparse dot product gives the same number.
    std::vector<SparseVector> vectors;
    std::vector<float> copy = dense;
    EXPECT_NEAR(compressSingleScattering(ctx, copy.data(), vectors), 1.0, 1e-6);
    ASSERT_EQ(vectors.size(), 1u);
    Cubemap light(n, 1);
    const size_t t = texelIndex(n, 2, 15, 8);
    light.data()[t] = 1.0f;
    haarForward(light);
    float rgb[3];
    dotRGB(vectors[0], light.data().data(), 1, rgb);
    for (int ch = 0; ch < 3; ++ch) EXPECT_NEAR(rgb[ch], dense[t * 3 + ch], 1e-5 * dense[t * 3 + ch]);

    // The throughput threshold (default 1e-4) changes nothing that matters here.
    SingleScatteringOptions culled = o;
    culled.minThroughput = 1e-4;
    const SingleScatteringContext ctxCulled(scene, slab, m, nullptr, culled);
    const std::vector<float> denseCulled = denseAt(ctxCulled, v);
    for (size_t k = 0; k < dense.size(); ++k)
        EXPECT_NEAR(denseCulled[k], dense[k], 1e-4 * maxTop);
    }
}

TEST(SingleScattering, PipelineFileMatchesTheHalfSpaceClosedForm) {
    // The same slab through prt-precompute's pipeline: mesh file -> transport file ->
    // relit radiance F_t(w_o) dot(vector, light) for a light of radiance 1 in one
    // texel, at the top-centre vertex. Cubemap 8 (fast), all 384 coefficients kept, so
    // only 16-bit quantization (<= 1.5e-5 of the vertex's largest coefficient per
    // coefficient, summed over the light's Haar coefficients) adds to the 0.2% of the
    // test above: 0.3%.
    const Material m = materialByName("Marble");
    const float H = 20.0f;
    const fs::path meshPath = scratchDir() / "slab.obj";
    saveMesh(makeSlab(60.0f, 60.0f, H, 6), meshPath.string());
    const TriangleMesh mesh = loadMesh(meshPath.string());
    const size_t v = findVertex(mesh, {0, H / 2, 0}, {0, 1, 0});

    PrecomputeSettings s;
    s.meshPath = meshPath.string();
    s.outputPath = (scratchDir() / "slab.prt").string();
    s.scale.mmPerUnit = 1.0;
    s.material = m;
    s.cubemapSize = 8;
    s.vertexCoefficients = 6 * 8 * 8 + 9;  // everything: the residual and the SH part
    s.components = parseScatteringComponents("ss");
    Progress::setEnabled(false);
    const PrecomputeSummary summary = precomputeTransport(s, true);
    EXPECT_EQ(summary.singleScattering.terms, 1);
    EXPECT_TRUE(summary.singleScattering.isotropic);
    EXPECT_GT(summary.singleScattering.rays, 0u);

    const TransportFile file = loadTransportFile(s.outputPath);
    ASSERT_EQ(file.components.size(), 1u);
    const TransportComponent* ss = file.find(ComponentKind::SingleScatteringIsotropic);
    ASSERT_NE(ss, nullptr);
    std::vector<uint32_t> idx;
    std::vector<float> rgb;
    ss->vectors.dequantizeVertex(v, idx, rgb);
    SparseVector vec;
    vec.channels = 3;
    vec.index = idx;
    vec.value = rgb;

    const int n = 8;
    for (auto [i, j] : {std::pair{4, 4}, std::pair{7, 2}}) {
        Cubemap light(n, 1);
        light.data()[texelIndex(n, 2, i, j)] = 1.0f;
        haarForward(light);
        // The file's SH entries (6 N^2 + i) relight against the light's SH projections.
        std::vector<float> withSh = light.data();
        withSh.resize(size_t(6 * n * n + 9));
        shProjectLight(light.data().data(), n, 1, 9, withSh.data() + 6 * n * n);
        float out[3];
        dotRGB(vec, withSh.data(), 1, out);
        const double ftView = fresnelTransmittance(m.eta, 1.0);  // normal view
        for (int ch = 0; ch < 3; ++ch) {
            const double expected = ftView * halfSpaceTopTexel(m, n, i, j, ch, H);
            EXPECT_NEAR(ftView * out[ch], expected, 3e-3 * expected) << i << "," << j << " ch " << ch;
        }
    }
}

TEST(SingleScattering, ForwardScatteringFavoursBacklitViews) {
    // A thin slab (one mean free path |sigma_t|^-1 thick, 40 mm wide) seen along its
    // normal from the front, lit by one texel straight from the front (+Y) or straight
    // from behind (-Y). A 6 x 1 x 1 cubemap makes the texel directions exactly +-Y.
    //   front: light enters the top, a = w_i' = -Y, propagates down; the path to the
    //          viewer is -b = +Y (b = w_o' = -Y): p(a, b) = HG(cos = -1), backward.
    //          T = sigma_s g_k(a) F_t(1) dOmega int_0^H e^(-2 sigma_t s) ds.
    //   back:  light enters the bottom, a = +Y: p = HG(cos = +1), forward.
    //          T = sigma_s g_k(a) F_t(1) dOmega int_0^H e^(-sigma_t (H - s)) e^(-sigma_t s) ds
    //            = sigma_s g_k(a) F_t(1) dOmega H e^(-sigma_t H).
    // Relit: L = F_t(1) sum_k h_k(b) T_k = closed form with p_K(a, b) = evaluate(a, b).
    // With g = +0.4 the backlit/frontlit ratio must be far larger than with g = -0.4
    // (exact HG: ((1+g)/(1-g))^3 = 12.7 each way, so 161x between the two). With K = 4
    // (the default) the approximation of HG(0.4) at cos = -1 is slightly NEGATIVE
    // (-0.015 against 0.024: rms error 32%), so the ratio is taken with K = 8 (values
    // 0.221 and 0.032) and K = 4 is checked by sign: backlit brighter than frontlit
    // for g > 0, darker for g < 0. A flipped sign convention anywhere (light maps
    // indexed by -a, view maps by -b, HG(cos) of the wrong pair) swaps the two cases.
    double ratio[2] = {0, 0};
    int slot = 0;
    for (auto [g, terms] : {std::pair{0.4, 8}, std::pair{-0.4, 8}, std::pair{0.4, 4}, std::pair{-0.4, 4}}) {
        Material m = materialByName("Marble");
        m.g = g;
        const PhaseFactorization phase = factorPhaseFunction(g, terms, 16);
        const float H = float(1.0 / luminance(m.sigmaT()));
        const TriangleMesh slab = makeSlab(40.0f, 40.0f, H, 4);
        const RayScene scene(slab);
        SingleScatteringOptions o;
        o.cubemapSize = 1;
        o.minThroughput = 0.0;
        const SingleScatteringContext ctx(scene, slab, m, &phase, o);
        ASSERT_EQ(ctx.terms(), terms);
        const size_t v = findVertex(slab, {0, H / 2, 0}, {0, 1, 0});
        const std::vector<float> dense = denseAt(ctx, v);

        const glm::dvec3 b(0, -1, 0);  // refractDirection(+Y, +Y): the view ray into the medium
        glm::dvec3 bCheck;
        ASSERT_TRUE(refractDirection({0, 1, 0}, {0, 1, 0}, m.eta, bCheck));
        EXPECT_NEAR(glm::length(bCheck - b), 0.0, 1e-12);
        const double ft = fresnelTransmittance(m.eta, 1.0);
        const double dOmega = 4.0 * kPi / 6.0;
        auto relit = [&](int face, int ch) {
            double sum = 0;
            for (int k = 0; k < terms; ++k)
                sum += phase.viewMaps[size_t(k)].sampleBilinear(b, 0) * dense[(size_t(k) * 6 + face) * 3 + ch];
            return ft * sum;
        };
        const glm::dvec3 sigmaS = m.sigmaS(), sigmaT = m.sigmaT();
        for (int ch = 0; ch < 3; ++ch) {
            const double st = sigmaT[ch];
            const double front = sigmaS[ch] * ft * ft * dOmega * phase.evaluate({0, -1, 0}, b) *
                                 -std::expm1(-2 * st * H) / (2 * st);
            const double back = sigmaS[ch] * ft * ft * dOmega * phase.evaluate({0, 1, 0}, b) * H *
                                std::exp(-st * H);
            // Midpoint rule in xi (lambda = 1 - e^-1 here): within 0.5% for both.
            EXPECT_NEAR(relit(2, ch), front, 5e-3 * std::abs(front)) << "g " << g << " ch " << ch;
            EXPECT_NEAR(relit(3, ch), back, 5e-3 * std::abs(back)) << "g " << g << " ch " << ch;
        }
        for (int ch = 0; ch < 3; ++ch) {
            if (g > 0) EXPECT_GT(relit(3, ch), relit(2, ch)) << "g " << g << " K " << terms;
            else EXPECT_LT(relit(3, ch), relit(2, ch)) << "g " << g << " K " << terms;
        }
        if (terms == 8) ratio[slot++] = relit(3, 1) / relit(2, 1);
    }
    EXPECT_GT(ratio[0], 1.0) << "g = +0.4: backlit must be brighter than frontlit";
    EXPECT_LT(ratio[1], 1.0) << "g = -0.4: frontlit must be brighter than backlit";
    EXPECT_GT(ratio[0], 10.0 * ratio[1]);
}

TEST(SingleScattering, IsotropicEqualsOneTermFactorisationOfGZero) {
    // HG with g = 0 is the constant 1/(4 pi): its factorisation is rank one and the
    // K-term machinery (light map at w_i', view map at w_o') must reproduce the
    // isotropic vector exactly (up to float rounding).
    const Material m = materialByName("Skin1");
    const PhaseFactorization phase = factorPhaseFunction(0.0, 1, 8);
    const TriangleMesh torus = makeTorus(6.0f, 2.0f, 24, 12);
    const RayScene scene(torus);
    for (int stride : {1, 4}) {  // adaptive directions decide on the phase-free throughput
    SCOPED_TRACE("direction stride " + std::to_string(stride));
    SingleScatteringOptions o;
    o.cubemapSize = 16;
    o.directionStride = stride;
    const SingleScatteringContext iso(scene, torus, m, nullptr, o);
    const SingleScatteringContext one(scene, torus, m, &phase, o);
    for (size_t v : {size_t(0), size_t(37), size_t(200)}) {
        const std::vector<float> a = denseAt(iso, v);
        const std::vector<float> b = denseAt(one, v);
        ASSERT_EQ(a.size(), b.size());
        glm::dvec3 wo = glm::dvec3(torus.normals[v]), bDir;
        ASSERT_TRUE(refractDirection(wo, wo, m.eta, bDir));
        const double h0 = phase.viewMaps[0].sampleBilinear(bDir, 0);
        double maxA = 0;
        for (float x : a) maxA = std::max(maxA, double(x));
        ASSERT_GT(maxA, 0.0);
        for (size_t k = 0; k < a.size(); ++k) EXPECT_NEAR(b[k] * h0, a[k], 1e-5 * maxA);
    }
    }
}

TEST(SingleScattering, OccluderBlocksTheLight) {
    // A box floating above the slab's centre shadows the exit points of light from
    // straight above (V = 0) but not light from a low side direction.
    const Material m = materialByName("Marble");
    const TriangleMesh slab = makeSlab(60.0f, 60.0f, 20.0f, 6);
    const TriangleMesh withBox = merge(slab, translated(makeBox({8, 2, 8}), {0, 16, 0}));
    const RayScene sceneSlab(slab), sceneBox(withBox);
    SingleScatteringOptions o;
    o.cubemapSize = 8;
    const SingleScatteringContext a(sceneSlab, slab, m, nullptr, o);
    const SingleScatteringContext b(sceneBox, withBox, m, nullptr, o);
    const size_t v = findVertex(slab, {0, 10, 0}, {0, 1, 0});
    SingleScatteringStats sa, sb;
    const std::vector<float> open = denseAt(a, v, &sa), shadowed = denseAt(b, v, &sb);
    const size_t up = texelIndex(8, 2, 4, 4);   // ~ +Y
    const size_t low = texelIndex(8, 0, 4, 1);  // +X face, ~35 degrees above the horizon
    for (int ch = 0; ch < 3; ++ch) {
        EXPECT_GT(open[up * 3 + ch], 0.0f);
        EXPECT_EQ(shadowed[up * 3 + ch], 0.0f);
        EXPECT_GT(open[low * 3 + ch], 0.0f);
        EXPECT_EQ(shadowed[low * 3 + ch], open[low * 3 + ch]);
    }
    EXPECT_EQ(sa.occlusionRays, sb.occlusionRays);  // same exits, only V differs
    // Without visibility the box does not matter.
    o.visibility = false;
    const SingleScatteringContext c(sceneBox, withBox, m, nullptr, o);
    SingleScatteringStats sc;
    const std::vector<float> noVis = denseAt(c, v, &sc);
    EXPECT_EQ(sc.occlusionRays, 0u);
    EXPECT_EQ(noVis[up * 3], open[up * 3]);
}

TEST(SingleScattering, GaussPathSamplesMatchManyMidpointsOnACurvedMesh) {
    // Geometry makes the depth integrand non-smooth (exits that jump to the other side
    // of the ring or onto the sphere, shadow edges), where no rule has an order. A torus
    // (concave) under a floating sphere (occluders), Marble, cubemap 8, every third
    // vertex, each rule against 64 midpoints. Measured: 16 midpoints (the old rule)
    // change the uniform-light sum of a vertex by <= 2.2e-3 and the dense vector by
    // 0.83% mean / 1.6% worst relative L2; 6 Gauss points (the default of issue 16's
    // first round) by <= 6.2e-3 and 1.55% / 2.9%; 4 Gauss points (the default since the
    // adaptive directions) by <= 1.2e-2 and 2.2% / 3.9%: per texel 2-3x the old rule's
    // deviation, the size of the texel point-sampling error (1.7%,
    // docs/single-scattering.md) and far below the 128-term truncation (~17%); rendered,
    // the bunny changes by < 0.11% rel. RMSE, the dragon res2 by 0.15% (docs). The
    // bounds below are the measured values with margin.
    const Material m = materialByName("Marble");
    const TriangleMesh torus = makeTorus(6.0f, 2.5f, 24, 12);
    const TriangleMesh scene = merge(torus, translated(makeIcosphere(2, 2.0f), {0, 6, 0}));
    const RayScene rays(scene, RaySceneOptions{RayBuildQuality::High, true});
    auto context = [&](PathQuadrature rule, int samples) {
        SingleScatteringOptions o;
        o.cubemapSize = 8;
        o.pathQuadrature = rule;
        o.pathSamples = samples;
        return SingleScatteringContext(rays, scene, m, nullptr, o);
    };
    const SingleScatteringContext reference = context(PathQuadrature::Midpoint, 64);
    const SingleScatteringOptions defaults;
    struct Error2 {
        double sumWorst = 0, relL2Mean = 0, relL2Worst = 0;
        uint64_t exitRays = 0;
    };
    auto measure = [&](const SingleScatteringContext& ctx) {
        Error2 e;
        size_t count = 0;
        for (size_t v = 0; v < torus.positions.size(); v += 3) {
            SingleScatteringStats st;
            const std::vector<float> ref = denseAt(reference, v), a = denseAt(ctx, v, &st);
            e.exitRays += st.exitRays;
            double d2 = 0, r2 = 0, sa = 0, sr = 0;
            for (size_t k = 0; k < a.size(); ++k) {
                d2 += double(a[k] - ref[k]) * (a[k] - ref[k]);
                r2 += double(ref[k]) * ref[k];
                sa += a[k];
                sr += ref[k];
            }
            if (!(r2 > 0)) continue;
            e.sumWorst = std::max(e.sumWorst, std::abs(sa / sr - 1.0));
            e.relL2Mean += std::sqrt(d2 / r2);
            e.relL2Worst = std::max(e.relL2Worst, std::sqrt(d2 / r2));
            ++count;
        }
        e.relL2Mean /= double(count);
        return e;
    };
    const Error2 old = measure(context(PathQuadrature::Midpoint, 16));
    const Error2 gauss6 = measure(context(PathQuadrature::GaussLegendre, 6));
    const Error2 gauss = measure(context(defaults.pathQuadrature, defaults.pathSamples));
    EXPECT_EQ(defaults.pathSamples, 4);
    EXPECT_LT(gauss6.sumWorst, 1e-2);
    EXPECT_LT(gauss6.relL2Mean, 2.5e-2);
    EXPECT_LT(gauss6.relL2Worst, 5e-2);
    std::printf("16 midpoints: sum worst %.2e, rel L2 mean %.2e worst %.2e\n"
                "%d Gauss points: sum worst %.2e, rel L2 mean %.2e worst %.2e\n",
                old.sumWorst, old.relL2Mean, old.relL2Worst, defaults.pathSamples, gauss.sumWorst,
                gauss.relL2Mean, gauss.relL2Worst);
    EXPECT_EQ(gauss.exitRays * 16, old.exitRays * uint64_t(defaults.pathSamples));
    EXPECT_LT(old.sumWorst, 4e-3);
    EXPECT_LT(old.relL2Mean, 1.4e-2);
    EXPECT_LT(gauss.sumWorst, 1.8e-2);
    EXPECT_LT(gauss.relL2Mean, 3.2e-2);
    EXPECT_LT(gauss.relL2Worst, 6e-2);
    EXPECT_LT(gauss.relL2Mean, 3.5 * old.relL2Mean);
    EXPECT_LT(gauss6.relL2Mean, gauss.relL2Mean);  // more points, closer
}

// Adaptive directions (SingleScatteringOptions::directionStride): relative L2 and
// uniform-light sum of a against ref over the vertices (every `step`-th) of a mesh.
namespace {
struct DenseDeviation {
    double relL2Mean = 0, relL2Worst = 0, sumMean = 0, sumWorst = 0;
    uint64_t interpolated = 0, traced = 0, rays = 0;
};
DenseDeviation deviation(const SingleScatteringContext& ctx, const SingleScatteringContext& ref,
                         size_t vertices, size_t step) {
    DenseDeviation e;
    size_t count = 0;
    for (size_t v = 0; v < vertices; v += step) {
        SingleScatteringStats st;
        const std::vector<float> r = denseAt(ref, v), a = denseAt(ctx, v, &st);
        e.interpolated += st.interpolatedTexels;
        e.traced += st.tracedTexels;
        e.rays += st.rays();
        double d2 = 0, r2 = 0, sa = 0, sr = 0;
        for (size_t k = 0; k < a.size(); ++k) {
            d2 += double(a[k] - r[k]) * (a[k] - r[k]);
            r2 += double(r[k]) * r[k];
            sa += a[k];
            sr += r[k];
        }
        if (!(r2 > 0)) continue;
        const double l2 = std::sqrt(d2 / r2), dev = sa / sr - 1.0;
        e.relL2Mean += l2;
        e.relL2Worst = std::max(e.relL2Worst, l2);
        e.sumMean += dev;
        e.sumWorst = std::max(e.sumWorst, std::abs(dev));
        ++count;
    }
    e.relL2Mean /= double(count);
    e.sumMean /= double(count);
    return e;
}
}  // namespace

TEST(SingleScattering, AdaptiveDirectionsOnTheHalfSpace) {
    // The flat slab of ThickSlabMatchesTheHalfSpaceClosedForm at the production cubemap
    // size (N = 32): its transport is smooth over the upper hemisphere and zero below,
    // so most texels are interpolated, and every texel stays within 0.2% (of the
    // brightest texel) of the closed form: bilinear interpolation of a smooth function
    // over cells of at most 4 texels (~11 degrees), checked at every texel of the top
    // face, not only at lattice points. Measured: 78% of the texels interpolated, worst
    // texel 0.12% of the brightest.
    const Material m = materialByName("Marble");
    const float H = 20.0f;
    const TriangleMesh slab = makeSlab(60.0f, 60.0f, H, 6);
    const RayScene scene(slab);
    const int n = 32;
    SingleScatteringOptions o;
    o.cubemapSize = n;
    o.minThroughput = 0.0;
    const SingleScatteringContext every(scene, slab, m, nullptr, o);
    o.directionStride = 4;
    const SingleScatteringContext adaptive(scene, slab, m, nullptr, o);
    ASSERT_TRUE(adaptive.adaptiveDirections());
    ASSERT_FALSE(every.adaptiveDirections());
    const size_t v = findVertex(slab, {0, H / 2, 0}, {0, 1, 0});
    SingleScatteringStats st;
    const std::vector<float> a = denseAt(adaptive, v, &st), b = denseAt(every, v);
    double brightest = 0, worst = 0;
    for (size_t k = 0; k < a.size(); ++k) brightest = std::max(brightest, double(b[k]));
    for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i) {
            const size_t t = texelIndex(n, 2, i, j);
            for (int ch = 0; ch < 3; ++ch)
                worst = std::max(worst, std::abs(a[t * 3 + ch] - halfSpaceTopTexel(m, n, i, j, ch, H)) / brightest);
        }
    std::printf("interpolated %.1f%% of the texels, worst top texel %.2e of the brightest\n",
                100.0 * double(st.interpolatedTexels) / double(every.texelCount()), worst);
    EXPECT_LT(worst, 2e-3);
    EXPECT_GT(st.interpolatedTexels, every.texelCount() / 2);
    EXPECT_EQ(st.tracedTexels + st.interpolatedTexels, every.texelCount());
    EXPECT_EQ(st.exitRays, st.tracedTexels * uint64_t(o.pathSamples));
    // Below the surface: zero, interpolated or not.
    for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i)
            for (int ch = 0; ch < 3; ++ch) EXPECT_LT(a[texelIndex(n, 3, i, j) * 3 + ch], 1e-12 * brightest);
    double sa = 0, sb = 0;
    for (size_t k = 0; k < a.size(); ++k) {
        sa += a[k];
        sb += b[k];
    }
    // Linear interpolation of a concave function (the transport is a cap: largest at the
    // normal, zero at the horizon) falls below it between the corners, so the interpolated
    // texels are a little low: measured -0.28% of the uniform-light sum here (-0.07% more
    // than tracing every texel on the bunny, docs/single-scattering.md).
    EXPECT_LT(sa / sb, 1.0);
    EXPECT_GT(sa / sb, 1.0 - 4e-3);
    // With supersampling every sub-direction is traced (no adaptive directions).
    o.supersample = 2;
    o.cubemapSize = 8;
    const SingleScatteringContext super(scene, slab, m, nullptr, o);
    EXPECT_FALSE(super.adaptiveDirections());
    SingleScatteringStats ss;
    denseAt(super, v, &ss);
    EXPECT_EQ(ss.interpolatedTexels, 0u);
    EXPECT_EQ(ss.exitRays, uint64_t(o.pathSamples) * 6 * 8 * 8 * 4);
}

TEST(SingleScattering, AdaptiveDirectionsKeepSmallShadowsWhereLightIsBright) {
    // A 1.5 mm box 12 mm from the slab's centre vertex, toward the texels (13..14,
    // 13..14) of the top face (N = 32), casts a shadow about 2 texels wide near the
    // normal, the brightest part of the vertex's transport, strictly between corners of
    // the stride-4 lattice (12 and 16). Without the large-cell rule the lit corners agree
    // and the shadow is interpolated away; with it (the default) a bright cell wider than
    // 2 texels is always split, the new corner at 14 falls in the shadow, and the
    // shadowed light matches tracing every texel.
    const Material m = materialByName("Marble");
    const TriangleMesh slab = makeSlab(60.0f, 60.0f, 20.0f, 6);
    const int n = 32;
    const glm::vec3 xo(0, 10, 0);
    const glm::vec3 toward = glm::normalize(glm::vec3(texelDirection(n, 2, 13, 13) + texelDirection(n, 2, 14, 14)));
    const TriangleMesh scene = merge(slab, translated(makeBox({1.5f, 1.5f, 1.5f}), xo + 12.0f * toward));
    const RayScene rays(scene), slabRays(slab);
    SingleScatteringOptions o;
    o.cubemapSize = n;
    const SingleScatteringContext open(slabRays, slab, m, nullptr, o);
    const SingleScatteringContext every(rays, scene, m, nullptr, o);
    o.directionStride = 4;
    const SingleScatteringContext adaptive(rays, scene, m, nullptr, o);
    o.refineLargeCellValue = 1e30;
    const SingleScatteringContext loose(rays, scene, m, nullptr, o);
    const size_t v = findVertex(scene, xo, {0, 1, 0});
    const std::vector<float> lit = denseAt(open, findVertex(slab, xo, {0, 1, 0}));
    const std::vector<float> ref = denseAt(every, v), a = denseAt(adaptive, v), b = denseAt(loose, v);
    // The shadow: texels of the top face below half their unshadowed value.
    double shadowLit = 0, shadowRef = 0, shadowA = 0, shadowB = 0;
    int shadowTexels = 0;
    for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i) {
            const size_t t = texelIndex(n, 2, i, j) * 3 + 1;
            if (!(ref[t] < 0.5f * lit[t])) continue;
            ++shadowTexels;
            shadowLit += lit[t];
            shadowRef += ref[t];
            shadowA += a[t];
            shadowB += b[t];
        }
    std::printf("shadow: %d texels, light %.3g unshadowed, %.3g every texel, %.3g adaptive, %.3g without "
                "the large-cell rule\n",
                shadowTexels, shadowLit, shadowRef, shadowA, shadowB);
    ASSERT_GE(shadowTexels, 2);
    ASSERT_LE(shadowTexels, 12);
    EXPECT_LT(shadowRef, 0.5 * shadowLit);
    EXPECT_NEAR(shadowA, shadowRef, 0.1 * shadowLit);
    EXPECT_GT(shadowB, shadowRef + 0.3 * shadowLit);  // the rule is what finds it
}

TEST(SingleScattering, AdaptiveDirectionsKeepSmallLitGapsWhereLightIsBright) {
    // The mirror image of the test above: a 20 mm plate 12 mm above the slab's centre
    // vertex shadows the bright directions around the normal, except through a 1.5 mm
    // square hole toward the texels (13..14, 13..14). The lattice corners around the hole
    // are all occluded and agree on it; the large-cell rule looks at the light at stake
    // before occlusion, so the bright cell is split anyway and the hole's light is found.
    // Without the rule it is lost (checked).
    const Material m = materialByName("Marble");
    const TriangleMesh slab = makeSlab(60.0f, 60.0f, 20.0f, 6);
    const int n = 32;
    const glm::vec3 xo(0, 10, 0);
    const glm::vec3 toward = glm::normalize(glm::vec3(texelDirection(n, 2, 13, 13) + texelDirection(n, 2, 14, 14)));
    const glm::vec3 c = xo + (12.0f / toward.y) * toward;  // the hole's centre, 12 mm above
    const float g = 1.5f, w = 20.0f, t = 0.4f;
    TriangleMesh scene = slab;
    const float side = (w - g) / 2;
    scene = merge(scene, translated(makeBox({side, t, w}), c + glm::vec3(-(g + side) / 2, 0, 0)));
    scene = merge(scene, translated(makeBox({side, t, w}), c + glm::vec3((g + side) / 2, 0, 0)));
    scene = merge(scene, translated(makeBox({g, t, side}), c + glm::vec3(0, 0, -(g + side) / 2)));
    scene = merge(scene, translated(makeBox({g, t, side}), c + glm::vec3(0, 0, (g + side) / 2)));
    const RayScene rays(scene);
    SingleScatteringOptions o;
    o.cubemapSize = n;
    const SingleScatteringContext every(rays, scene, m, nullptr, o);
    o.directionStride = 4;
    const SingleScatteringContext adaptive(rays, scene, m, nullptr, o);
    o.refineLargeCellValue = 1e30;
    const SingleScatteringContext loose(rays, scene, m, nullptr, o);
    const size_t v = findVertex(scene, xo, {0, 1, 0});
    const std::vector<float> ref = denseAt(every, v), a = denseAt(adaptive, v), b = denseAt(loose, v);
    double gapRef = 0, gapA = 0, gapB = 0, total = 0;
    int gapTexels = 0;
    for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i) {
            const size_t k = texelIndex(n, 2, i, j) * 3 + 1;
            total += ref[k];
            if (std::abs(i - 13.5) > 3 || std::abs(j - 13.5) > 3 || !(ref[k] > 0)) continue;
            ++gapTexels;
            gapRef += ref[k];
            gapA += a[k];
            gapB += b[k];
        }
    std::printf("gap: %d lit texels, light %.3g every texel (%.1f%% of the top face), %.3g adaptive, %.3g "
                "without the large-cell rule\n",
                gapTexels, gapRef, 100.0 * gapRef / total, gapA, gapB);
    ASSERT_GE(gapTexels, 2);
    ASSERT_LE(gapTexels, 16);
    EXPECT_NEAR(gapA, gapRef, 0.1 * gapRef);
    EXPECT_LT(gapB, 0.5 * gapRef);  // the rule is what finds it
}

TEST(SingleScattering, AdaptiveDirectionsMatchEveryTexelOnACurvedMesh) {
    // The torus under a floating sphere of GaussPathSamplesMatchManyMidpointsOnACurvedMesh
    // (concave exits, occluders, shadow edges) at the production cubemap size (N = 32),
    // every ninth vertex, against 64 midpoints: 6 Gauss points with adaptive directions
    // (stride 4) deviate about as much as with every texel traced. Measured: relative L2
    // mean 2.04% against 2.00% (worst 3.0% / 2.7%); uniform-light sum mean -0.04% against
    // +0.06%; 65% of the texels interpolated, 2.8x fewer rays. The interpolation error
    // alone (adaptive against every texel) is 1.5%, mostly orthogonal to the quadrature's
    // own. Bounds: the measured values with margin.
    const Material m = materialByName("Marble");
    const TriangleMesh torus = makeTorus(6.0f, 2.5f, 24, 12);
    const TriangleMesh scene = merge(torus, translated(makeIcosphere(2, 2.0f), {0, 6, 0}));
    const RayScene rays(scene, RaySceneOptions{RayBuildQuality::High, true});
    auto context = [&](PathQuadrature rule, int samples, int stride) {
        SingleScatteringOptions o;
        o.pathQuadrature = rule;
        o.pathSamples = samples;
        o.directionStride = stride;
        return SingleScatteringContext(rays, scene, m, nullptr, o);
    };
    const SingleScatteringContext reference = context(PathQuadrature::Midpoint, 64, 1);
    const DenseDeviation every =
        deviation(context(PathQuadrature::GaussLegendre, 6, 1), reference, torus.positions.size(), 9);
    const DenseDeviation adaptive =
        deviation(context(PathQuadrature::GaussLegendre, 6, 4), reference, torus.positions.size(), 9);
    std::printf("every texel: rel L2 mean %.3e worst %.3e, sum mean %+.2e worst %.2e, %llu rays\n"
                "adaptive:    rel L2 mean %.3e worst %.3e, sum mean %+.2e worst %.2e, %llu rays, "
                "%.1f%% of the texels interpolated\n",
                every.relL2Mean, every.relL2Worst, every.sumMean, every.sumWorst, (unsigned long long)every.rays,
                adaptive.relL2Mean, adaptive.relL2Worst, adaptive.sumMean, adaptive.sumWorst,
                (unsigned long long)adaptive.rays,
                100.0 * double(adaptive.interpolated) / double(adaptive.interpolated + adaptive.traced));
    EXPECT_LT(adaptive.relL2Mean, 1.3 * every.relL2Mean);
    EXPECT_LT(adaptive.relL2Worst, 1.5 * every.relL2Worst);
    EXPECT_LT(std::abs(adaptive.sumMean), 2e-3);
    EXPECT_LT(adaptive.sumWorst, 1e-2);
    EXPECT_GT(adaptive.interpolated, adaptive.traced / 2);  // the shortcut acts
    EXPECT_LT(double(adaptive.rays), 0.7 * double(every.rays));

    // The interpolation alone at the default path rule (4 Gauss points), adaptive against
    // every texel. Measured: relative L2 mean 2.5%, sum mean -0.1%.
    const SingleScatteringContext every4 = context(PathQuadrature::GaussLegendre, 4, 1);
    const SingleScatteringContext adaptive4 = context(PathQuadrature::GaussLegendre, 4, 4);
    const DenseDeviation direct = deviation(adaptive4, every4, torus.positions.size(), 9);
    std::printf("4 Gauss points, adaptive against every texel: rel L2 mean %.3e worst %.3e, sum mean %+.2e "
                "worst %.2e\n",
                direct.relL2Mean, direct.relL2Worst, direct.sumMean, direct.sumWorst);
    EXPECT_LT(direct.relL2Mean, 3.5e-2);
    EXPECT_LT(direct.relL2Worst, 6e-2);
    EXPECT_LT(std::abs(direct.sumMean), 3e-3);

    // One scratch reused from vertex to vertex (as computeSingleScattering does) gives
    // what a fresh one does: no record of one vertex leaks into the next.
    SingleScatteringScratch shared;
    for (size_t v = 0; v < torus.positions.size(); v += 17) {
        std::vector<float> a(adaptive4.denseSize());
        SingleScatteringStats st;
        singleScatteringVertex(adaptive4, scene.positions[v], scene.normals[v], a.data(), shared, st);
        ASSERT_EQ(a, denseAt(adaptive4, v)) << "vertex " << v;
    }
}

TEST(SingleScattering, SharedVisibilityIsExactForWideOccluders) {
    // Shared visibility (not the default) traces the occlusion rays of only the
    // shallowest and deepest exit of each direction and gives the samples between their
    // V when both agree. Under a box much wider than the spread of the exit points the
    // shadow edge never falls strictly inside a direction's samples without also
    // separating its ends, so the result is that of one ray per exit, with fewer rays.
    const Material m = materialByName("Marble");
    const TriangleMesh slab = makeSlab(60.0f, 60.0f, 20.0f, 6);
    const TriangleMesh withBox = merge(slab, translated(makeBox({8, 2, 8}), {0, 16, 0}));
    const RayScene scene(withBox);
    SingleScatteringOptions o;
    o.cubemapSize = 8;
    o.pathSamples = 6;  // two ends and four samples between them
    o.visibilityFromExitRay = false;  // one occlusion ray per exit, which sharing saves
    const SingleScatteringContext every(scene, withBox, m, nullptr, o);
    o.sharedVisibility = true;
    const SingleScatteringContext shared(scene, withBox, m, nullptr, o);
    for (glm::vec3 p : {glm::vec3(0, 10, 0), glm::vec3(10, 10, 0), glm::vec3(-10, 10, 10)}) {
        const size_t v = findVertex(withBox, p, {0, 1, 0});
        SingleScatteringStats se, ss;
        const std::vector<float> a = denseAt(every, v, &se), b = denseAt(shared, v, &ss);
        for (size_t k = 0; k < a.size(); ++k) ASSERT_EQ(a[k], b[k]) << "vertex at " << p.x << " element " << k;
        EXPECT_GT(ss.sharedVisibility, 0u);
        EXPECT_EQ(ss.occlusionRays + ss.sharedVisibility, se.occlusionRays);
        EXPECT_LT(ss.occlusionRays, se.occlusionRays / 2);
        EXPECT_EQ(ss.occludedExits, se.occludedExits);
    }
}

TEST(SingleScattering, RobustToInconsistentOrientation) {
    // Scanned meshes have inward-pointing vertex normals and triangles wound the wrong
    // way round. Neither may change the result on a slab.
    const Material m = materialByName("Marble");
    const TriangleMesh slab = makeSlab(60.0f, 60.0f, 20.0f, 6);
    const RayScene scene(slab);
    SingleScatteringOptions o;
    o.cubemapSize = 8;
    const SingleScatteringContext ctx(scene, slab, m, nullptr, o);
    const size_t v = findVertex(slab, {0, 10, 0}, {0, 1, 0});
    SingleScatteringStats ref;
    const std::vector<float> expected = denseAt(ctx, v, &ref);
    EXPECT_EQ(ref.flippedNormals, 0u);
    EXPECT_EQ(ref.reversedHits, 0u);
    double maxValue = 0;
    for (float x : expected) maxValue = std::max(maxValue, double(x));

    // 1. The vertex normal points inward: all sample points below it along -n are
    //    outside, so the path is taken along +n.
    {
        std::vector<float> dense(ctx.denseSize());
        SingleScatteringScratch scratch;
        SingleScatteringStats stats;
        singleScatteringVertex(ctx, slab.positions[v], -slab.normals[v], dense.data(), scratch, stats);
        EXPECT_EQ(stats.flippedNormals, 1u);
        EXPECT_NEAR(stats.depthSum, 20.0, 1e-4);
        for (size_t k = 0; k < dense.size(); ++k) EXPECT_NEAR(dense[k], expected[k], 1e-6 * maxValue);
    }
    // 2. The top face's triangles wound the wrong way (their geometric normals and the
    //    normals of their vertices point into the slab): exits through them are used
    //    with the normals reversed. (The vertex's own normal is kept pointing out.)
    {
        TriangleMesh bad = slab;
        for (size_t t = 0; t < bad.triangles.size(); ++t)
            if (faceNormal(slab, t).y > 0.5f) std::swap(bad.triangles[t].y, bad.triangles[t].z);
        for (size_t i = 0; i < bad.normals.size(); ++i)
            if (slab.normals[i].y > 0.5f && i != v) bad.normals[i] = -slab.normals[i];
        const RayScene badScene(bad);
        const SingleScatteringContext badCtx(badScene, bad, m, nullptr, o);
        SingleScatteringStats stats;
        const std::vector<float> dense = denseAt(badCtx, v, &stats);
        EXPECT_GT(stats.reversedHits, 0u);
        EXPECT_EQ(stats.outsideSamples, 0u);
        for (size_t k = 0; k < dense.size(); ++k) EXPECT_NEAR(dense[k], expected[k], 1e-6 * maxValue);
    }
    // 3. A vertex on a flap 0.05 mm above the body: d_m passes through the gap and the
    //    body to the far side. (The sample points in the gap see the flap's underside,
    //    a back face, above and the body's top, a front face, below; they count as
    //    inside. The body's exits are shadowed by the flap.)
    {
        TriangleMesh flap;
        flap.positions = {{-1, 10.05f, -1}, {1, 10.05f, -1}, {1, 10.05f, 1}, {-1, 10.05f, 1}, {0, 10.05f, 0}};
        flap.normals.assign(5, glm::vec3(0, 1, 0));
        flap.triangles = {{0, 4, 1}, {1, 4, 2}, {2, 4, 3}, {3, 4, 0}};  // CCW from above
        const TriangleMesh both = merge(slab, flap);
        const RayScene bothScene(both);
        const size_t top = slab.positions.size() + 4;
        const FarSide f = farSideDistance(bothScene, both.positions[top], both.normals[top], 99.0);
        EXPECT_TRUE(f.hit);
        EXPECT_NEAR(f.distance, 20.05, 1e-4);
        const SingleScatteringContext flapCtx(bothScene, both, m, nullptr, o);
        SingleScatteringStats stats;
        const std::vector<float> dense = denseAt(flapCtx, top, &stats);
        EXPECT_EQ(stats.outsideSamples, 0u);
        EXPECT_EQ(stats.flippedNormals, 0u);
        const size_t up = texelIndex(8, 2, 4, 4);
        EXPECT_GT(dense[up * 3 + 1], 0.0f);
        EXPECT_LT(dense[up * 3 + 1], expected[up * 3 + 1]);
    }
}

TEST(SingleScattering, CoherentPacketsTraceTheSameRays) {
    // coherentRays (the default) traces the exit and occlusion rays in coherent packets
    // (Embree's coherent flag on the RayScene's batches); the hits, hence the transport,
    // must be those of the same robust RayScene's incoherent batches. A torus (concave: exits through the far side of the
    // ring, self-occlusion) with a sphere floating over it (occluders), Marble, every
    // vertex of the torus; the per-vertex dense vectors agree to float rounding and
    // the ray counts (which depend on every exit and cut-off decision) are equal.
    const Material m = materialByName("Marble");
    const TriangleMesh torus = makeTorus(6.0f, 2.5f, 24, 12);
    const TriangleMesh scene = merge(torus, translated(makeIcosphere(2, 2.0f), {0, 6, 0}));
    const RayScene rays(scene, RaySceneOptions{RayBuildQuality::High, true});
    SingleScatteringOptions o;
    o.cubemapSize = 8;
    for (bool fromExitRay : {true, false}) {  // V from the exit ray's traversal, or a second ray
        o.visibilityFromExitRay = fromExitRay;
        o.coherentRays = true;
        const SingleScatteringContext coherent(rays, scene, m, nullptr, o);
        o.coherentRays = false;
        const SingleScatteringContext incoherent(rays, scene, m, nullptr, o);
        SingleScatteringStats sa, sb;
        double worst = 0.0;
        for (size_t v = 0; v < torus.positions.size(); v += 3) {
            SingleScatteringStats a1, b1;
            const std::vector<float> a = denseAt(coherent, v, &a1), b = denseAt(incoherent, v, &b1);
            sa.add(a1);
            sb.add(b1);
            worst = std::max(worst, relativeL2(a, b));
        }
        EXPECT_LT(worst, 1e-5);
        EXPECT_EQ(sa.exitRays, sb.exitRays);
        EXPECT_EQ(sa.occlusionRays, sb.occlusionRays);
        EXPECT_EQ(sa.occludedExits, sb.occludedExits);
        EXPECT_EQ(sa.culledRays, sb.culledRays);
        EXPECT_EQ(sa.escapedRays, sb.escapedRays);
        EXPECT_GT(sa.occludedExits, 0u);
        EXPECT_EQ(sa.occlusionRays > 0, !fromExitRay);
    }
    // The sphere does shadow the torus: without visibility the transport is larger.
    o = SingleScatteringOptions{};
    o.cubemapSize = 8;
    const SingleScatteringContext coherent(rays, scene, m, nullptr, o);
    o.visibility = false;
    const SingleScatteringContext noVis(rays, scene, m, nullptr, o);
    const size_t top = findVertex(torus, {0, 2.5f, 6.0f}, {0, 1, 0});
    const std::vector<float> lit = denseAt(noVis, top), shadowed = denseAt(coherent, top);
    double sumLit = 0, sumShadowed = 0;
    for (size_t k = 0; k < lit.size(); ++k) sumLit += lit[k], sumShadowed += shadowed[k];
    EXPECT_LT(sumShadowed, 0.99 * sumLit);
}

TEST(SingleScattering, VisibilityFromTheExitRayEqualsASecondRay) {
    // visibilityFromExitRay (the default) takes V from the exit ray's own traversal (a
    // surface more than epsilon beyond x_i) instead of an occlusion ray from x_i offset
    // along its normal. On a clean mesh the two agree exit by exit: a torus (self-
    // shadowing through the hole) under a sphere, every texel and adaptive directions.
    const Material m = materialByName("Marble");
    const TriangleMesh torus = makeTorus(6.0f, 2.5f, 24, 12);
    const TriangleMesh scene = merge(torus, translated(makeIcosphere(2, 2.0f), {0, 6, 0}));
    const RayScene rays(scene, RaySceneOptions{RayBuildQuality::High, true});
    for (int stride : {1, 4}) {
        SingleScatteringOptions o;
        o.cubemapSize = 16;
        o.directionStride = stride;
        const SingleScatteringContext fromExit(rays, scene, m, nullptr, o);
        o.visibilityFromExitRay = false;
        const SingleScatteringContext secondRay(rays, scene, m, nullptr, o);
        SingleScatteringStats sa, sb;
        double worst = 0.0;
        for (size_t v = 0; v < torus.positions.size(); v += 2) {
            SingleScatteringStats a1, b1;
            const std::vector<float> a = denseAt(fromExit, v, &a1), b = denseAt(secondRay, v, &b1);
            sa.add(a1);
            sb.add(b1);
            worst = std::max(worst, relativeL2(a, b));
        }
        EXPECT_LT(worst, 1e-6) << "stride " << stride;
        EXPECT_EQ(sa.occludedExits, sb.occludedExits) << "stride " << stride;
        EXPECT_GT(sa.occludedExits, sa.exitRays / 20) << "stride " << stride;  // the sphere and the ring do shadow
        EXPECT_EQ(sa.exitRays, sb.exitRays);
        EXPECT_EQ(sa.occlusionRays, 0u);
        EXPECT_EQ(sb.occlusionRays, sb.exitRays - sb.culledRays - sb.escapedRays);
    }
}

TEST(SingleScattering, ResultDoesNotDependOnTheThreadCount) {
    const Material m = materialByName("Ketchup");
    const TriangleMesh sphere = makeIcosphere(2, 5.0f);
    const RayScene scene(sphere);
    SingleScatteringOptions o;
    o.cubemapSize = 8;
    o.vertexCoefficients = 40;
    const SingleScatteringContext ctx(scene, sphere, m, nullptr, o);
    std::vector<std::vector<SparseVector>> one, two;
    SingleScatteringResult r1, r2;
    {
        tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 1);
        r1 = computeSingleScattering(ctx, one);
    }
    {
        tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 2);
        r2 = computeSingleScattering(ctx, two);
    }
    ASSERT_EQ(one.size(), 1u);
    ASSERT_EQ(one[0].size(), sphere.positions.size());
    for (size_t v = 0; v < one[0].size(); ++v) {
        EXPECT_EQ(one[0][v].index, two[0][v].index);
        EXPECT_EQ(one[0][v].value, two[0][v].value);
        EXPECT_LE(one[0][v].size(), 40u);
    }
    EXPECT_EQ(r1.stats.rays(), r2.stats.rays());
    EXPECT_EQ(r1.stats.depthRays, sphere.positions.size());
    EXPECT_GT(r1.retainedEnergyFraction, 0.5);
    EXPECT_LE(r1.retainedEnergyFraction, 1.0 + 1e-9);
    // A sphere: every inward ray hits the far side (d_m ~ the diameter), no vertex capped.
    EXPECT_EQ(r1.stats.cappedDepths, 0u);
    EXPECT_NEAR(r1.stats.depthSum / double(sphere.positions.size()), 10.0, 0.05);
}

// ---------------------------------------------------------------------------------
// Pipeline
// ---------------------------------------------------------------------------------

TEST(SingleScatteringPipeline, ParametersAndDigest) {
    PrecomputeSettings s;
    s.meshPath = "x.obj";
    s.outputPath = "x.prt";
    s.scale.sizeMm = 30;
    s.material = materialByName("Marble");
    const MeshFingerprint fp{10, 42};
    auto value = [](const std::vector<std::pair<std::string, std::string>>& p, const std::string& k) {
        for (const auto& [key, v] : p)
            if (key == k) return v;
        return std::string("<absent>");
    };
    // Multiple scattering only: single-scattering settings are not recorded, so they
    // do not change the digest.
    const auto ms = settingsParameters(s, fp);
    EXPECT_EQ(value(ms, "components"), "ms");
    EXPECT_EQ(value(ms, "path_samples"), "<absent>");
    EXPECT_EQ(value(ms, "path_quadrature"), "<absent>");
    PrecomputeSettings s2 = s;
    s2.singleScattering.pathSamples = 8;
    s2.singleScattering.pathQuadrature = PathQuadrature::Midpoint;
    s2.phase.terms = 2;
    EXPECT_EQ(settingsParameters(s2, fp), ms);

    // With single scattering they are, and every one changes the digest.
    s.components = {true, true};
    const auto both = settingsParameters(s, fp);
    EXPECT_EQ(value(both, "components"), "ms,ss");
    EXPECT_EQ(value(both, "ss_phase"), "isotropic");
    EXPECT_EQ(value(both, "phase_terms"), "<absent>");  // isotropic: K unused
    EXPECT_EQ(value(both, "path_samples"), std::to_string(defaultPathSamples(PathQuadrature::GaussLegendre)));
    EXPECT_EQ(value(both, "path_quadrature"), "gauss");
    EXPECT_EQ(value(both, "ss_supersample"), "1");
    EXPECT_EQ(value(both, "ss_direction_stride"), "4");
    EXPECT_EQ(value(both, "ss_refine_tolerances"), "0.5 0.01 0.3");
    EXPECT_NE(value(both, "input_digest"), value(ms, "input_digest"));
    s2 = s;
    s2.singleScattering.pathSamples = 8;
    EXPECT_NE(value(settingsParameters(s2, fp), "input_digest"), value(both, "input_digest"));
    s2 = s;
    s2.singleScattering.supersample = 2;
    EXPECT_NE(value(settingsParameters(s2, fp), "input_digest"), value(both, "input_digest"));
    EXPECT_EQ(value(settingsParameters(s2, fp), "ss_direction_stride"), "<absent>");  // no effect there
    s2 = s;
    s2.singleScattering.directionStride = 8;
    EXPECT_NE(value(settingsParameters(s2, fp), "input_digest"), value(both, "input_digest"));
    s2.singleScattering.directionStride = 1;  // every texel: the parameters of files made before the option
    EXPECT_EQ(value(settingsParameters(s2, fp), "ss_direction_stride"), "<absent>");
    EXPECT_EQ(value(both, "ss_sites"), "0.292979119 mm, 4x coefficients per site");  // auto: 0.75 mean free paths
    s2 = s;
    s2.ssSiteSpacing = 0.25;
    EXPECT_EQ(value(settingsParameters(s2, fp), "ss_sites"), "0.25 mm, 4x coefficients per site");
    EXPECT_NE(value(settingsParameters(s2, fp), "input_digest"), value(both, "input_digest"));
    s2.ssSiteSpacing = 0.0;  // every vertex: the parameters of files made before the option
    EXPECT_EQ(value(settingsParameters(s2, fp), "ss_sites"), "<absent>");
    s2 = s;
    s2.singleScattering.pathQuadrature = PathQuadrature::Midpoint;
    EXPECT_EQ(value(settingsParameters(s2, fp), "path_quadrature"), "midpoint");
    EXPECT_NE(value(settingsParameters(s2, fp), "input_digest"), value(both, "input_digest"));
    s2 = s;
    s2.material.g = 0.25;
    const auto aniso = settingsParameters(s2, fp);
    EXPECT_EQ(value(aniso, "ss_phase"), "henyey-greenstein svd");
    EXPECT_EQ(value(aniso, "phase_terms"), "4");
    EXPECT_EQ(value(aniso, "phase_map_size"), "16");
    s2.phase.terms = 3;
    EXPECT_NE(value(settingsParameters(s2, fp), "input_digest"), value(aniso, "input_digest"));

    // Validation.
    s2 = s;
    s2.components = {false, false};
    EXPECT_THROW(validateSettings(s2), Error);
    s2 = s;
    s2.singleScattering.pathSamples = 0;
    EXPECT_THROW(validateSettings(s2), Error);
    s2 = s;
    s2.phase.terms = 0;
    EXPECT_THROW(validateSettings(s2), Error);
    s2 = s;
    s2.phase.mapSize = 12;
    EXPECT_THROW(validateSettings(s2), Error);
    s2 = s;
    s2.singleScattering.supersample = 9;
    EXPECT_THROW(validateSettings(s2), Error);
    s2 = s;
    s2.singleScattering.directionStride = 6;
    EXPECT_THROW(validateSettings(s2), Error);
    EXPECT_NO_THROW(validateSettings(s));
}

TEST(SingleScatteringPipeline, IsotropicFileHasOneDiffuseSingleScatteringComponent) {
    const fs::path meshPath = scratchDir() / "sphere.obj";
    saveMesh(makeIcosphere(2, 1.0f), meshPath.string());
    PrecomputeSettings s;
    s.meshPath = meshPath.string();
    s.outputPath = (scratchDir() / "iso.prt").string();
    s.scale.sizeMm = 12;
    s.material = materialByName("Skin1");
    s.cubemapSize = 8;
    s.pass1.supersample = 1;
    s.vertexCoefficients = 48;
    s.components = {true, true};
    Progress::setEnabled(false);
    const PrecomputeSummary sum = precomputeTransport(s, true);
    EXPECT_FALSE(sum.skipped);
    EXPECT_EQ(sum.singleScattering.terms, 1);
    EXPECT_GT(sum.singleScattering.rays, sum.singleScattering.exitRays);
    // Adaptive directions (the default): exit rays for the traced texels only, every
    // texel traced or interpolated.
    EXPECT_EQ(sum.singleScattering.exitRays, sum.singleScattering.tracedTexels * uint64_t(s.singleScattering.pathSamples));
    EXPECT_EQ(sum.singleScattering.tracedTexels + sum.singleScattering.interpolatedTexels, uint64_t(162) * 6 * 8 * 8);
    EXPECT_GT(sum.singleScattering.interpolatedTexels, 0u);
    EXPECT_NE(sum.format().find("interpolated from agreeing corners"), std::string::npos);
    EXPECT_NE(sum.format().find("single scattering"), std::string::npos);

    const TransportFile f = loadTransportFile(s.outputPath);
    ASSERT_EQ(f.components.size(), 2u);
    EXPECT_NE(f.find(ComponentKind::MultipleScattering), nullptr);
    const TransportComponent* ss = f.find(ComponentKind::SingleScatteringIsotropic);
    ASSERT_NE(ss, nullptr);
    EXPECT_EQ(f.find(ComponentKind::SingleScatteringTerm, 0), nullptr);
    EXPECT_FALSE(f.viewMaps.has_value());
    EXPECT_EQ(ss->vectors.vertexCount(), 162u);
    EXPECT_LE(ss->vectors.coefficientCount(), 162u * 48);
    EXPECT_EQ(f.parameter("components"), "ms,ss");
    EXPECT_EQ(f.parameter("path_samples"), std::to_string(s.singleScattering.pathSamples));
    EXPECT_EQ(f.parameter("path_quadrature"), "gauss");

    // Up to date: skipped; round trip through another file is exact.
    EXPECT_TRUE(precomputeTransport(s, false).skipped);
    const std::string copy = (scratchDir() / "iso_copy.prt").string();
    saveTransportFile(copy, f);
    EXPECT_EQ(loadTransportFile(copy), f);
}

TEST(SingleScatteringPipeline, AnisotropicFileHasKTermsAndViewMaps) {
    const fs::path meshPath = scratchDir() / "sphere_aniso.obj";
    saveMesh(makeIcosphere(1, 1.0f), meshPath.string());
    PrecomputeSettings s;
    s.meshPath = meshPath.string();
    s.outputPath = (scratchDir() / "aniso.prt").string();
    s.scale.sizeMm = 12;
    s.material = materialByName("Marble");
    s.material.g = 0.3;
    s.cubemapSize = 8;
    s.vertexCoefficients = 32;
    s.phase.terms = 3;
    s.components = parseScatteringComponents("ss");
    Progress::setEnabled(false);
    const PrecomputeSummary sum = precomputeTransport(s, true);
    EXPECT_EQ(sum.singleScattering.terms, 3);
    EXPECT_FALSE(sum.singleScattering.isotropic);
    EXPECT_GT(sum.singleScattering.phaseRmsError, 0.0);

    const TransportFile f = loadTransportFile(s.outputPath);
    ASSERT_EQ(f.components.size(), 3u);
    EXPECT_EQ(f.find(ComponentKind::MultipleScattering), nullptr);
    EXPECT_EQ(f.find(ComponentKind::SingleScatteringIsotropic), nullptr);
    for (uint32_t k = 0; k < 3; ++k) {
        const TransportComponent* c = f.find(ComponentKind::SingleScatteringTerm, k);
        ASSERT_NE(c, nullptr) << k;
        EXPECT_EQ(c->vectors.vertexCount(), 42u);
    }
    ASSERT_TRUE(f.viewMaps.has_value());
    EXPECT_EQ(f.viewMaps->size, 16);
    EXPECT_EQ(f.viewMaps->terms, 3);
    ASSERT_EQ(f.viewMaps->data.size(), size_t(3) * 6 * 16 * 16);
    const PhaseFactorization phase = factorPhaseFunction(0.3, 3, 16);
    for (int k = 0; k < 3; ++k)
        for (size_t t = 0; t < phase.viewMaps[size_t(k)].data().size(); ++t)
            ASSERT_EQ(f.viewMaps->term(k)[t], phase.viewMaps[size_t(k)].data()[t]);
    EXPECT_EQ(f.parameter("phase_terms"), "3");
    EXPECT_EQ(f.parameter("g"), "0.3");

    const std::string copy = (scratchDir() / "aniso_copy.prt").string();
    saveTransportFile(copy, f);
    EXPECT_EQ(loadTransportFile(copy), f);
}
