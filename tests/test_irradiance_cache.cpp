// The translucent irradiance cache (relight/pointlight/irradiance_cache.h, Keng et al. 2006).
// Physics asserted: a -> 0 (every pixel its own cache) is the Jensen-Buhler image bit
// for bit; the gradient of Eqs. 8-9 is the derivative of S (central differences, on a
// plane and on a sphere); the split-disk factor is the paper's four-sector integral,
// and the exact variant is the derivative of a numerically integrated half-bright
// disk; V of a half-bright plane is E/2; the error against Jensen-Buhler falls as `a`
// shrinks; caches are made in bottom-up scan-line order where no earlier cache is
// valid; the result does not depend on the thread count; bad options are one-line
// errors.

#include "relight/pointlight/irradiance_cache.h"

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "common/bssrdf.h"
#include "common/camera.h"
#include "common/error.h"
#include "common/image_compare.h"
#include "common/shapes.h"
#include "common/util.h"
#include "relight/pointlight/jensen_buhler.h"
#include "relight/render/gbuffer.h"
#include "test_support.h"

using namespace prt;

namespace {

IrradianceSamples litSamples(const TriangleMesh& mesh, const RayScene& scene, const std::vector<Light>& lights) {
    IrradianceSamples s = faceCentroidSamples(mesh);
    computeIrradiance(s, scene, lights, 1.3, FresnelModel::Exact);
    return s;
}

// A torus under a point light, seen from above at an angle: shadow terminators,
// self-shadowing and silhouettes in a small frame.
struct TorusScene {
    TriangleMesh mesh = makeTorus(12.0f, 5.0f, 96, 48);
    RayScene scene{mesh};
    IrradianceSamples samples;
    GBuffer g;
    explicit TorusScene(int size = 64) {
        samples = litSamples(mesh, scene, {parseLight("point:25,30,10:0.01")});
        g = traceGBuffer(scene, mesh, frameSphere({0, 0, 0}, 17.0, 20.0, 35.0, 30.0, size, size));
    }
};

// Largest |a - b| over the vector, relative to |b|.
double vectorError(const glm::dvec3& a, const glm::dvec3& b) { return glm::length(a - b) / glm::length(b); }

// S in double precision (dipoleRd per channel): the walk's R_d is single precision,
// whose rounding, summed over 10^4-10^5 samples, is noise of a few 1e-3 in central
// differences with h = 0.01 mm; the analytic gradient does not difference anything.
glm::dvec3 doubleS(const IrradianceSamples& s, const Material& m, const glm::dvec3& x) {
    glm::dvec3 sum(0.0);
    for (size_t i = 0; i < s.size(); ++i)
        sum += double(s.areas[i]) * dipoleRd(m, glm::length(x - glm::dvec3(s.positions[i]))) * glm::dvec3(s.irradiance[i]);
    return sum;
}

// Checks grad S of cache.evaluate (epsilon 0: the whole sum) against central
// differences of S at x (per channel, 3D gradient: S is the convolution of Eq. 6,
// defined off the surface too).
double worstGradientError(const IrradianceCache& cache, const IrradianceSamples& samples, const Material& m,
                          const std::vector<glm::dvec3>& points, double h) {
    double worst = 0.0;
    for (const glm::dvec3& x : points) {
        glm::dvec3 s, grad[3], v;
        cache.evaluate(x, s, grad, v);
        glm::dvec3 fd[3];
        for (int axis = 0; axis < 3; ++axis) {
            glm::dvec3 dx(0.0);
            dx[axis] = h;
            const glm::dvec3 sp = doubleS(samples, m, x + dx), sm = doubleS(samples, m, x - dx);
            for (int c = 0; c < 3; ++c) fd[c][axis] = (sp[c] - sm[c]) / (2.0 * h);
        }
        for (int c = 0; c < 3; ++c) {
            EXPECT_GT(glm::length(fd[c]), 0.0);
            worst = std::max(worst, vectorError(grad[c], fd[c]));
            if (vectorError(grad[c], fd[c]) > 1e-3)
                std::printf("  x (%.3g %.3g %.3g) c %d: analytic (%.4g %.4g %.4g) differences (%.4g %.4g %.4g)\n", x.x, x.y,
                            x.z, c, grad[c].x, grad[c].y, grad[c].z, fd[c].x, fd[c].y, fd[c].z);
        }
    }
    return worst;
}

}  // namespace

// a -> 0: no cache is valid anywhere but at its own point, so every shaded pixel gets
// a cache and Eq. 10 returns S_k itself: the Jensen-Buhler image, bit for bit.
TEST(IrradianceCache, ATendingToZeroEqualsJensenBuhlerExactly) {
    const TorusScene t(48);
    const Material m = materialByName("Skimmilk");
    for (const FresnelModel fresnel : {FresnelModel::Exact, FresnelModel::Keng}) {
        const JensenBuhler jb(m, IrradianceOctree(t.samples), {.epsilon = 0.05, .fresnel = fresnel});
        IrradianceCache cache(m, IrradianceOctree(t.samples), {.a = 1e-12, .epsilon = 0.05, .fresnel = fresnel});
        IrradianceCacheStats stats;
        const Image a = cache.render(t.g, &stats);
        const Image b = jb.render(t.g);
        EXPECT_EQ(stats.hitPixels, t.g.objectPixels());
        EXPECT_EQ(stats.caches, stats.shadedPixels);
        EXPECT_GT(stats.caches, 500u);
        ASSERT_EQ(a.pixels.size(), b.pixels.size());
        size_t differ = 0;
        for (size_t i = 0; i < a.pixels.size(); ++i) differ += a.pixels[i] != b.pixels[i] ? 1 : 0;
        EXPECT_EQ(differ, 0u) << toString(fresnel);
    }
}

// S of evaluate() is JensenBuhler::exitance bit for bit, and V of the scan's walk is
// V of the full walk.
TEST(IrradianceCache, WalkMatchesJensenBuhlerAndScanSpread) {
    const TorusScene t(16);
    const Material m = materialByName("Marble");
    const JensenBuhler jb(m, IrradianceOctree(t.samples), {.epsilon = 0.02});
    const IrradianceCache cache(m, IrradianceOctree(t.samples), {.epsilon = 0.02});
    size_t n = 0;
    for (size_t v = 0; v < t.mesh.vertexCount(); v += 97) {
        const glm::dvec3 x(t.mesh.positions[v]);
        glm::dvec3 s, grad[3], spread;
        size_t terms = 0, jbTerms = 0;
        cache.evaluate(x, s, grad, spread, &terms);
        const glm::dvec3 e = jb.exitance(x, &jbTerms);
        EXPECT_EQ(s, e);
        EXPECT_EQ(terms, jbTerms);
        EXPECT_EQ(spread, cache.spread(x));
        ++n;
    }
    EXPECT_GT(n, 20u);
}

// Eqs. 8-9 on a plane: a large slab under a point light; with epsilon = 0 the walk is
// the full cubature sum and its analytic gradient is the exact derivative of that sum;
// with the default epsilon the hierarchical gradient's first-order term over 0.5 mm
// (what Eq. 10 adds) differs from the exact one by less than 2% of the largest S.
TEST(IrradianceCache, GradientMatchesFiniteDifferencesOnAPlane) {
    const TriangleMesh slab = makeSlab(60.0f, 60.0f, 10.0f, 120);
    const RayScene scene(slab);
    const IrradianceSamples s = litSamples(slab, scene, {parseLight("point:4,12,-3:0.01")});
    const Material m = materialByName("Marble");
    const double top = bounds(slab).hi.y;
    std::vector<glm::dvec3> points;
    for (const double r : {1.0, 2.0, 5.0, 9.0, 14.0})  // not at the light's foot: grad S = 0 there
        points.push_back(glm::dvec3(4.0 + r * 0.8, top, -3.0 + r * 0.6));
    points.push_back(glm::dvec3(1.0, top - 0.7, 2.0));  // below the surface: S is a 3D field
    const IrradianceCache exact(m, IrradianceOctree(s), {.epsilon = 0.0});
    const double eExact = worstGradientError(exact, s, m, points, 1e-3);
    std::printf("plane: worst relative gradient error, epsilon 0: %.2e\n", eExact);
    EXPECT_LT(eExact, 1e-3);  // the issue asks for 2%
    // The hierarchical gradient (epsilon 0.05) against differences of the exact S.
    const IrradianceCache fast(m, IrradianceOctree(s), {.epsilon = 0.05});
    double worst = 0.0;
    glm::dvec3 sMax(0.0);  // errors relative to the brightest S of the points (the display's scale)
    for (const glm::dvec3& x : points) sMax = glm::max(sMax, doubleS(s, m, x));
    for (const glm::dvec3& x : points) {
        glm::dvec3 sv, gFast[3], gExact[3], v;
        fast.evaluate(x, sv, gFast, v);
        exact.evaluate(x, sv, gExact, v);
        // What Eq. 10 uses: the first-order change over 0.5 mm, relative to S there.
        for (int c = 0; c < 3; ++c) worst = std::max(worst, 0.5 * glm::length(gFast[c] - gExact[c]) / sMax[c]);
    }
    std::printf("plane: hierarchical (epsilon 0.05) gradient vs exact, 0.5 mm x |difference| / S: %.2e\n", worst);
    EXPECT_LT(worst, 0.02);
}

TEST(IrradianceCache, GradientMatchesFiniteDifferencesOnASphere) {
    const TriangleMesh sphere = makeIcosphere(5, 10.0f);
    const RayScene scene(sphere);
    const IrradianceSamples s = litSamples(sphere, scene, {parseLight("point:15,20,5:0.01")});
    const Material m = materialByName("Skin1");
    std::vector<glm::dvec3> points;
    for (const glm::dvec3 dir : {glm::dvec3(0.2, 0.9, 0.6), glm::dvec3(1, 0, 0), glm::dvec3(-0.3, 0.2, 1),
                                 glm::dvec3(0.1, -1, 0.3), glm::dvec3(-1, -0.2, -0.4)})
        points.push_back(10.0 * glm::normalize(dir));
    const IrradianceCache exact(m, IrradianceOctree(s), {.epsilon = 0.0});
    const double eExact = worstGradientError(exact, s, m, points, 1e-3);
    std::printf("sphere: worst relative gradient error, epsilon 0: %.2e\n", eExact);
    EXPECT_LT(eExact, 1e-3);  // the issue asks for 2%
    const IrradianceCache fast(m, IrradianceOctree(s), {.epsilon = 0.05});
    double worst = 0.0;
    glm::dvec3 sMax(0.0);  // errors relative to the brightest S of the points (the display's scale)
    for (const glm::dvec3& x : points) sMax = glm::max(sMax, doubleS(s, m, x));
    for (const glm::dvec3& x : points) {
        glm::dvec3 sv, gFast[3], gExact[3], v;
        fast.evaluate(x, sv, gFast, v);
        exact.evaluate(x, sv, gExact, v);
        // What Eq. 10 uses: the first-order change over 0.5 mm, relative to S there.
        for (int c = 0; c < 3; ++c) worst = std::max(worst, 0.5 * glm::length(gFast[c] - gExact[c]) / sMax[c]);
    }
    std::printf("sphere: hierarchical (epsilon 0.05) gradient vs exact, 0.5 mm x |difference| / S: %.2e\n", worst);
    EXPECT_LT(worst, 0.02);
}

// The split disk of radius R, bright (E) for x > 0 and dark for x < 0, V = E/2, with
// the point at u on the x axis and the disk centred on it.
//  - The paper's closed form is its own model: Delta S = 4 Delta S_A, the four
//    sectors of angle asin(du/R), integrated numerically.
//  - The exact factor is the derivative of the half-bright disk integrated
//    numerically (radial Simpson x the exact bright angle), by central differences.
//  - The paper's four sectors underestimate it (the strip is wide at the centre, the
//    sectors are not).
TEST(IrradianceCache, SplitDiskFactorMatchesNumericalIntegration) {
    const double e = 2.0, v = e / 2.0;
    for (const char* name : {"Skimmilk", "Marble", "Skin1"}) {
        const Material m = materialByName(name);
        for (int c = 0; c < 3; ++c) {
            const DipoleChannel d = makeDipoleChannel(m, c);
            for (const double radius : {0.5, 2.0, 6.0}) {
                SCOPED_TRACE(std::string(name) + " channel " + std::to_string(c) + " R " + std::to_string(radius));
                const int n = 20000;
                auto radial = [&](auto&& f) {  // Simpson over [0, R] of f(r)
                    const double h = radius / n;
                    double sum = f(0.0) + f(radius);
                    for (int i = 1; i < n; ++i) sum += (i % 2 ? 4.0 : 2.0) * f(i * h);
                    return sum * h / 3.0;
                };
                // Paper: 4 theta_R int_0^R E R_d r dr over du, du small.
                const double du = 1e-6 * radius;
                const double sectors = 4.0 * std::asin(du / radius) *
                                       radial([&](double r) { return e * dipoleRd(d, r) * r; });
                const double paper = splitDiskGradientFactor(d, radius, SplitDiskModel::Paper);
                EXPECT_NEAR(sectors / du, v * paper, 1e-6 * v * paper);
                // Exact: S(u) = int_0^R E R_d(r) r theta(r, u) dr, theta = pi + 2 asin(u/r)
                // the angle of the circle of radius r around the point that is bright.
                auto sAt = [&](double u) {
                    return radial([&](double r) {
                        const double theta = r <= std::abs(u) ? (u > 0 ? 2.0 * kPi : 0.0) : kPi + 2.0 * std::asin(u / r);
                        return e * dipoleRd(d, r) * r * theta;
                    });
                };
                const double h = 1e-3 * radius;
                const double numeric = (sAt(h) - sAt(-h)) / (2.0 * h);
                const double exact = splitDiskGradientFactor(d, radius, SplitDiskModel::Exact);
                EXPECT_NEAR(numeric, v * exact, 1e-2 * v * exact);
                EXPECT_LT(paper, exact);
                if (c == 1) std::printf("%s G R %.1f mm: paper / exact %.3f\n", name, radius, paper / exact);
            }
        }
    }
}

// V is the standard deviation of E within R: a plane half lit at E gives V = E / 2
// at the dividing line (Keng's E = 2V), and 0 deep inside either half.
TEST(IrradianceCache, SpreadOfAHalfLitPlaneIsHalfTheIrradiance) {
    const TriangleMesh slab = makeSlab(40.0f, 40.0f, 5.0f, 200);
    IrradianceSamples s = faceCentroidSamples(slab);
    const float top = bounds(slab).hi.y;
    for (size_t i = 0; i < s.size(); ++i)
        s.irradiance[i] = s.positions[i].y > top - 1e-3f && s.positions[i].x > 0.0f ? glm::vec3(50.0f) : glm::vec3(0.0f);
    const IrradianceCache cache(materialByName("Marble"), IrradianceOctree(s), {.radius = 3.0, .epsilon = 0.0});
    const glm::dvec3 v0 = cache.spread({0.0, top, 0.0});
    EXPECT_NEAR(v0.x, 25.0, 0.5);
    EXPECT_EQ(cache.spread({10.0, top, 0.0}).x, 0.0);
    EXPECT_EQ(cache.spread({-10.0, top, 0.0}).x, 0.0);
}

// The interpolation error against Jensen-Buhler falls as `a` shrinks, while the cache
// count grows.
TEST(IrradianceCache, ErrorFallsAsAShrinks) {
    const TorusScene t(96);
    const Material m = materialByName("Skimmilk");
    const Image reference = JensenBuhler(m, IrradianceOctree(t.samples), {.epsilon = 0.05}).render(t.g);
    double previousError = 1e30;
    size_t previousCaches = 0;
    for (const double a : {0.05, 0.0125, 0.003}) {
        IrradianceCache cache(m, IrradianceOctree(t.samples), {.a = a, .epsilon = 0.05});
        IrradianceCacheStats stats;
        const Image image = cache.render(t.g, &stats);
        const double error = compareImages(image, reference).overall.relativeRmse;
        std::printf("a %.3f: %zu caches (%.2f%%), relative RMSE %.3e (R %.3g mm, %.2f valid caches per pixel)\n", a,
                    stats.caches, 100.0 * stats.ratio(), error, stats.radius, stats.meanValidCaches);
        EXPECT_LT(error, previousError) << a;
        EXPECT_GT(stats.caches, previousCaches) << a;
        previousError = error;
        previousCaches = stats.caches;
    }
    EXPECT_LT(previousError, 0.01);
}

// Pass 2 visits pixels bottom row first, left to right: the caches come in that order,
// each at a pixel where no earlier cache was valid, and every shaded pixel is covered
// by a cache created no later than its visit.
TEST(IrradianceCache, CachesFollowTheBottomUpScan) {
    const TorusScene t(64);
    const Material m = materialByName("Marble");
    IrradianceCache cache(m, IrradianceOctree(t.samples), {.a = 0.2});
    cache.render(t.g);
    const std::vector<CacheRecord>& c = cache.caches();
    ASSERT_GT(c.size(), 5u);
    auto scanKey = [&](uint32_t pixel) {  // position in the bottom-up scan
        const uint32_t y = pixel / uint32_t(t.g.width), x = pixel % uint32_t(t.g.width);
        return uint64_t(t.g.height - 1 - y) * uint64_t(t.g.width) + x;
    };
    // The first cache is the first shaded pixel of the scan.
    uint64_t firstShaded = ~0ull;
    for (size_t i = 0; i < t.g.pixels.size(); ++i) {
        const GBufferPixel& p = t.g.pixels[i];
        if (p.hit && glm::dot(p.normal, p.toViewer) > 0.0f) firstShaded = std::min(firstShaded, scanKey(uint32_t(i)));
    }
    EXPECT_EQ(scanKey(c[0].pixel), firstShaded);
    auto valid = [](const CacheRecord& r, const glm::dvec3& p) {
        return glm::length(p - r.position) < r.validRadius;
    };
    for (size_t k = 1; k < c.size(); ++k) {
        EXPECT_LT(scanKey(c[k - 1].pixel), scanKey(c[k].pixel));
        for (size_t j = 0; j < k; ++j) ASSERT_FALSE(valid(c[j], c[k].position)) << k << " " << j;
    }
    for (size_t i = 0; i < t.g.pixels.size(); ++i) {
        const GBufferPixel& p = t.g.pixels[i];
        if (!p.hit || !(glm::dot(p.normal, p.toViewer) > 0.0f)) continue;
        bool covered = false;
        for (const CacheRecord& r : c)
            if (scanKey(r.pixel) <= scanKey(uint32_t(i)) && valid(r, glm::dvec3(p.position))) covered = true;
        ASSERT_TRUE(covered) << i;
    }
}

// One thread or all: the same caches and the same image, bit for bit.
TEST(IrradianceCache, ResultDoesNotDependOnThreads) {
    const TorusScene t(96);
    const Material m = materialByName("Skimmilk");
    IrradianceCache all(m, IrradianceOctree(t.samples), {.a = 0.3, .batch = 4});
    const Image a = all.render(t.g);
    Image b;
    std::vector<CacheRecord> cachesOne;
    {
        tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 1);
        IrradianceCache one(m, IrradianceOctree(t.samples), {.a = 0.3, .batch = 64});
        b = one.render(t.g);
        cachesOne = one.caches();
    }
    EXPECT_EQ(a.pixels, b.pixels);
    ASSERT_EQ(all.caches().size(), cachesOne.size());
    for (size_t k = 0; k < cachesOne.size(); ++k) {
        EXPECT_EQ(all.caches()[k].pixel, cachesOne[k].pixel);
        EXPECT_EQ(all.caches()[k].s, cachesOne[k].s);
        EXPECT_EQ(all.caches()[k].gradient[1], cachesOne[k].gradient[1]);
    }
}

TEST(IrradianceCache, BadOptionsAreOneLineErrors) {
    auto check = [](const IrradianceCacheOptions& o, const std::string& subject) {
        test::expectErrorSubject([&] { validateCacheOptions(o); }, subject);
        const std::string what = test::errorOf([&] { validateCacheOptions(o); });
        EXPECT_EQ(what.find('\n'), std::string::npos) << what;
    };
    check({.a = 0.0}, "--a");
    check({.a = -1.0}, "--a");
    check({.a = NAN}, "--a");
    check({.a = INFINITY}, "--a");
    check({.radius = -1.0}, "--radius");
    check({.radius = NAN}, "--radius");
    check({.radius = INFINITY}, "--radius");
    check({.epsilon = -0.1}, "--epsilon");
    check({.epsilon = NAN}, "--epsilon");
    check({.batch = 0}, "--cache-batch");
    EXPECT_NO_THROW(validateCacheOptions({}));
    EXPECT_THROW(splitDiskGradientFactor(makeDipoleChannel(materialByName("Marble"), 0), 0.0, SplitDiskModel::Paper),
                 Error);
    EXPECT_THROW(parseSplitDiskModel("sphere"), Error);
    EXPECT_EQ(parseSplitDiskModel("Exact"), SplitDiskModel::Exact);
    const TriangleMesh mesh = makeIcosphere(1, 5.0f);
    const IrradianceSamples s = faceCentroidSamples(mesh);
    EXPECT_THROW(IrradianceCache(materialByName("Marble"), IrradianceOctree(s), {.a = -2.0}), Error);
}

// setMaterial keeps the tree and rebuilds the rest (R, G, S_ref, the dipole lanes) and
// drops the caches: the next render equals a cache built with the new material, caches
// included; going back gives the first image; another eta is refused.
TEST(IrradianceCache, SetMaterialEqualsANewCacheBitForBit) {
    const TorusScene t(40);
    const Material a = materialByName("Skimmilk"), b = materialByName("Skin2");
    for (const SplitDiskModel model : {SplitDiskModel::Paper, SplitDiskModel::Exact}) {
        const IrradianceCacheOptions o{.splitDisk = model};
        auto fresh = [&](const Material& m, std::vector<CacheRecord>* caches) {
            IrradianceCache c(m, IrradianceOctree(t.samples), o);
            const Image image = c.render(t.g);
            *caches = c.caches();
            return image;
        };
        std::vector<CacheRecord> cachesA, cachesB;
        const Image imageA = fresh(a, &cachesA), imageB = fresh(b, &cachesB);
        ASSERT_NE(imageA.pixels, imageB.pixels);

        IrradianceCache cache(a, IrradianceOctree(t.samples), o);
        cache.render(t.g);
        cache.setMaterial(b);
        EXPECT_TRUE(cache.caches().empty());
        EXPECT_EQ(cache.radius(), defaultSplitDiskRadius(b));
        EXPECT_EQ(cache.render(t.g).pixels, imageB.pixels) << toString(model);
        ASSERT_EQ(cache.caches().size(), cachesB.size());
        for (size_t k = 0; k < cachesB.size(); ++k) {
            EXPECT_EQ(cache.caches()[k].pixel, cachesB[k].pixel);
            EXPECT_EQ(cache.caches()[k].s, cachesB[k].s);
            EXPECT_EQ(cache.caches()[k].validRadius, cachesB[k].validRadius);
        }
        cache.setMaterial(a);
        EXPECT_EQ(cache.render(t.g).pixels, imageA.pixels) << toString(model);
        EXPECT_EQ(cache.caches().size(), cachesA.size());

        Material otherEta = b;
        otherEta.eta = 1.2;
        test::expectErrorSubject([&] { cache.setMaterial(otherEta); }, "material");
        EXPECT_EQ(cache.render(t.g).pixels, imageA.pixels);
    }
    // An explicit radius stays.
    IrradianceCache fixed(a, IrradianceOctree(t.samples), {.radius = 0.8});
    fixed.setMaterial(b);
    EXPECT_EQ(fixed.radius(), 0.8);
}
