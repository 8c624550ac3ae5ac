// EnvironmentLight (relight/prt/light_vector.h): light vectors of a prepared environment
// against makeLightVector of the same image (turns about +Y, the fast path), and against
// a brute-force integral of the map over each cube texel (any other rotation).

#include "relight/prt/light_vector.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "common/cubemap.h"
#include "common/envmap.h"
#include "common/haar.h"
#include "common/error.h"

using prt::EnvironmentLight;
using prt::Image;
using prt::LightVector;

namespace {

// Log-uniform noise over six decades with a few suns 1e4 times brighter.
Image randomEnvironment(int width, int height, unsigned seed) {
    Image img(width, height, 3);
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> expo(-3.0f, 3.0f);
    for (float& v : img.pixels) v = std::pow(10.0f, expo(rng));
    std::uniform_int_distribution<size_t> any(0, img.pixels.size() / 3 - 1);
    for (int k = 0; k < 4; ++k) {
        const size_t p = any(rng);
        for (int c = 0; c < 3; ++c) img.pixels[3 * p + size_t(c)] = 1.0e7f;
    }
    return img;
}

double maxAbs(const std::vector<float>& v) {
    double m = 0.0;
    for (float x : v) m = std::max(m, double(std::abs(x)));
    return m;
}

// Haar coefficients are signed sums of texels, so they are compared against the largest:
// the texels agree to ~1e-7 relative (float weights either way, envmap.h), which bounds
// each coefficient's difference by ~1e-7 of the largest texel's contribution; 1e-6 of the
// largest coefficient leaves room for the float rounding of the transform.
void expectSameLight(const LightVector& a, const LightVector& b, const std::string& what) {
    ASSERT_EQ(a.size, b.size) << what;
    ASSERT_EQ(a.rgb.size(), b.rgb.size()) << what;
    const double tol = 1e-6 * maxAbs(b.rgb);
    double worst = 0.0;
    for (size_t t = 0; t < a.rgb.size(); ++t) worst = std::max(worst, std::abs(double(a.rgb[t]) - b.rgb[t]));
    EXPECT_LE(worst, tol) << what;
    EXPECT_EQ(a.keptTerms, b.keptTerms) << what;
    EXPECT_NEAR(a.relativeL2Error, b.relativeL2Error, 1e-5) << what;
}

}  // namespace

TEST(EnvironmentLight, MatchesMakeLightVectorAboutY) {
    for (int width : {64, 90}) {
        const Image env = randomEnvironment(width, width / 2, unsigned(width));
        const EnvironmentLight light(env, 8);
        EXPECT_EQ(light.size(), 8);
        EXPECT_EQ(light.image().pixels, env.pixels);
        // Whole-pixel, fractional and wrapped angles, composed rotations, kept terms.
        for (double degrees : {0.0, 360.0 / width, 37.5, -123.4, 359.9, 720.0 + 10.0})
            for (size_t keep : {size_t(0), size_t(40)}) {
                const glm::dmat3 r = prt::rotationY(degrees);
                expectSameLight(light.lightVector(r, keep), prt::makeLightVector(env, 8, r, keep),
                                std::to_string(width) + " wide, " + std::to_string(degrees) + " degrees, keep " +
                                    std::to_string(keep));
            }
        const glm::dmat3 composed = prt::rotationY(-45.0) * prt::rotationY(101.3);
        expectSameLight(light.lightVector(composed), prt::makeLightVector(env, 8, composed), "composed");
    }
}

// A rotation that is not about +Y, against a brute-force integral written here from the
// conventions alone (docs/conventions.md): each cube texel's mean radiance is the
// lat-long map (piecewise constant over its pixels) integrated over the texel by
// 256 x 256 sub-cells, each weighted by its exact solid angle and looked up at
// R^T d; then the Haar transform. On a map of moderate contrast (values in [0, 1] and
// a 4-pixel patch 100 times brighter) the light vector lies within 3e-4 of the largest
// coefficient of this integral (1.1e-3 with 64 x 64 sub-cells, 3e-4 again with
// 512 x 512: the floor of float sums), so 1e-3 separates the integral's own error
// from a wrong rotation (R in place of R^T: 1.0 of the largest) or a misplaced texel.
TEST(EnvironmentLight, OtherRotationsMatchABruteForceIntegral) {
    const int w = 64, h = 32, n = 4, sub = 256;
    Image env(w, h, 3);
    std::mt19937 rng(5);
    std::uniform_real_distribution<float> unit(0.0f, 1.0f);
    for (float& v : env.pixels) v = unit(rng);
    for (int y = 9; y <= 10; ++y)
        for (int x = 40; x <= 41; ++x)
            for (int c = 0; c < 3; ++c) env.at(x, y, c) = 100.0f * float(c + 1);
    const glm::dmat3 r = prt::rotationAxisAngle({1, 2, 3}, 40.0);
    const double pi = 3.14159265358979323846;
    auto radiance = [&](const glm::dvec3& d, int c) {  // L(d) of the map, piecewise constant
        const double u = 0.5 + std::atan2(d.x, -d.z) / (2.0 * pi), v = std::acos(std::clamp(d.y, -1.0, 1.0)) / pi;
        const int x = std::clamp(int(std::floor(u * w)), 0, w - 1) % w, y = std::clamp(int(std::floor(v * h)), 0, h - 1);
        return double(env.at(x, y, c));
    };
    prt::Cubemap expected(n, 3);
    const glm::dmat3 inverse = glm::transpose(r);
    for (int face = 0; face < 6; ++face)
        for (int j = 0; j < n; ++j)
            for (int i = 0; i < n; ++i) {
                double sum[3] = {0, 0, 0}, omega = 0.0;
                for (int b = 0; b < sub; ++b)
                    for (int a = 0; a < sub; ++a) {
                        const double s0 = (i + double(a) / sub) / n, s1 = (i + double(a + 1) / sub) / n;
                        const double t0 = (j + double(b) / sub) / n, t1 = (j + double(b + 1) / sub) / n;
                        const double dw = prt::faceRegionSolidAngle(s0, t0, s1, t1);
                        const glm::dvec3 d = inverse * prt::faceUVToDirection(face, 0.5 * (s0 + s1), 0.5 * (t0 + t1));
                        for (int c = 0; c < 3; ++c) sum[c] += dw * radiance(d, c);
                        omega += dw;
                    }
                for (int c = 0; c < 3; ++c) expected.texel(face, i, j)[c] = float(sum[c] / omega);
            }
    prt::haarForward(expected);
    const EnvironmentLight light(env, n);
    const LightVector all = light.lightVector(r, 0);
    ASSERT_EQ(all.rgb.size(), expected.data().size());
    const double largest = maxAbs(expected.data());
    double worst = 0.0;
    for (size_t t = 0; t < all.rgb.size(); ++t)
        worst = std::max(worst, std::abs(double(all.rgb[t]) - double(expected.data()[t])));
    std::printf("rotation about (1, 2, 3): worst coefficient difference from the brute-force integral %.2e of the "
                "largest\n", worst / largest);
    EXPECT_LT(worst, 1e-3 * largest);
    // Keeping 20 terms keeps the 20 largest by RGB magnitude, unchanged.
    const LightVector kept = light.lightVector(r, 20);
    EXPECT_EQ(kept.keptTerms, 20u);
    double smallestKept = 1e300, largestDropped = 0.0;
    int changed = 0;
    for (size_t k = 0; k < kept.coefficientCount(); ++k) {
        const double m = std::sqrt(double(all.rgb[3 * k]) * all.rgb[3 * k] + double(all.rgb[3 * k + 1]) * all.rgb[3 * k + 1] +
                                   double(all.rgb[3 * k + 2]) * all.rgb[3 * k + 2]);
        const bool isKept = kept.rgb[3 * k] != 0.0f || kept.rgb[3 * k + 1] != 0.0f || kept.rgb[3 * k + 2] != 0.0f;
        if (isKept) {
            smallestKept = std::min(smallestKept, m);
            for (int c = 0; c < 3; ++c) changed += kept.rgb[3 * k + c] != all.rgb[3 * k + c];
        } else {
            largestDropped = std::max(largestDropped, m);
        }
    }
    EXPECT_EQ(changed, 0);
    EXPECT_GE(smallestKept, largestDropped);
}

TEST(EnvironmentLight, ConcurrentCallsAgree) {
    EnvironmentLight light(randomEnvironment(128, 64, 4), 16);
    const LightVector reference = light.lightVector(prt::rotationY(12.3));
    std::vector<LightVector> got(4);
    std::vector<std::thread> threads;
    for (size_t t = 0; t < got.size(); ++t)
        threads.emplace_back([&, t] { got[t] = light.lightVector(prt::rotationY(12.3)); });
    for (auto& th : threads) th.join();
    for (const LightVector& l : got) EXPECT_EQ(l.rgb, reference.rgb);
    // Moving keeps it usable.
    const EnvironmentLight moved = std::move(light);
    EXPECT_EQ(moved.lightVector(prt::rotationY(12.3)).rgb, reference.rgb);
    EXPECT_GT(moved.memoryBytes(), size_t(128 * 64 * 3) * sizeof(float));
}

TEST(EnvironmentLight, RejectsBadInput) {
    auto message = [](auto&& f) -> std::string {
        try {
            f();
        } catch (const prt::Error& e) {
            return e.what();
        }
        return "";
    };
    EXPECT_NE(message([] { EnvironmentLight(Image(16, 8, 1, 1.0f), 4); }).find("channels"), std::string::npos);
    EXPECT_NE(message([] { EnvironmentLight(Image(16, 8, 3, 1.0f), 12); }).find("power of two"), std::string::npos);
    EXPECT_NE(message([] { EnvironmentLight(Image(0, 0, 3), 4); }).find("empty"), std::string::npos);
    Image bad(16, 8, 3, 1.0f);
    bad.pixels.pop_back();
    EXPECT_NE(message([&] { EnvironmentLight(bad, 4); }).find("inconsistent"), std::string::npos);
    Image nan(16, 8, 3, 1.0f);
    nan.at(3, 2, 0) = NAN;
    EXPECT_NE(message([&] { EnvironmentLight(nan, 4); }).find("row 2"), std::string::npos);
}
