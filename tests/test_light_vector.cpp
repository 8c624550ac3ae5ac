// EnvironmentLight (relight/prt/light_vector.h): light vectors of a prepared environment
// against makeLightVector of the same image, the reference.

#include "relight/prt/light_vector.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "common/envmap.h"
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

TEST(EnvironmentLight, OtherRotationsTakeTheExactPath) {
    const Image env = randomEnvironment(64, 32, 3);
    const EnvironmentLight light(env, 4);
    const glm::dmat3 r = prt::rotationAxisAngle({1, 2, 3}, 40.0);
    const LightVector a = light.lightVector(r, 20);
    const LightVector b = prt::makeLightVector(prt::latLongToCubemap(env, 4, r), 20);
    EXPECT_EQ(a.rgb, b.rgb);
    EXPECT_EQ(a.keptTerms, b.keptTerms);
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
