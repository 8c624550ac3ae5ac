// The sun split (relight/pointlight/environment_lights.h): the residual and the lights
// add up to the environment texel by texel and over the sphere, a one-texel sun becomes
// one light in its texel's direction with the closed-form irradiance, rotating the
// lights equals splitting the rotated map, and bad options are refused.

#include "relight/pointlight/environment_lights.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "common/envmap.h"
#include "common/error.h"
#include "common/materials.h"

using namespace prt;

namespace {

constexpr double kFourPi = 4.0 * 3.14159265358979323846;

// A sky with noise, a sun in a glow and a dimmer lamp: texels on both sides of the threshold.
Image testSky(int width = 128) {
    Image env = twoToneEnvironment(width, {1.0f, 1.1f, 1.3f}, {0.2f, 0.15f, 0.1f});
    std::mt19937 rng(7);
    std::uniform_real_distribution<float> noise(0.0f, 0.5f);
    for (float& v : env.pixels) v += noise(rng);
    const Image sun = sunEnvironment(width, glm::normalize(glm::dvec3(0.6, 0.7, 0.4)), {3000.0f, 2800.0f, 2500.0f});
    const Image lamp = sunEnvironment(width, glm::normalize(glm::dvec3(-0.5, 0.2, -0.8)), {60.0f, 50.0f, 40.0f});
    for (size_t i = 0; i < env.pixels.size(); ++i) env.pixels[i] += sun.pixels[i] + lamp.pixels[i];
    // A glow of 10 degrees around the sun: many texels above the threshold.
    const glm::dvec3 toward = glm::normalize(glm::dvec3(0.6, 0.7, 0.4));
    for (int y = 0; y < env.height; ++y)
        for (int x = 0; x < env.width; ++x)
            if (glm::dot(latLongPixelDirection(x, y, env.width, env.height), toward) >
                std::cos(10.0 * 3.14159265 / 180))
                for (int c = 0; c < 3; ++c) env.at(x, y, c) += 40.0f;
    return env;
}

glm::dvec3 lightSum(const std::vector<Light>& lights) {
    glm::dvec3 sum(0.0);
    for (const Light& l : lights) sum += l.rgb;
    return sum;
}

}  // namespace

// residual + excess = the environment: each texel at or under the threshold is kept bit
// for bit, each above it keeps its colour at luminance tau, and per channel the lights
// carry the excess's integral (exactly for cells of one texel; less the cosines within a
// cell for larger ones).
TEST(SunSplit, ResidualAndLightsAddUpToTheEnvironment) {
    const Image env = testSky();
    for (double cell : {0.1, 6.0, 10.0}) {  // cells of 1, 2 and 4 texels
        const SunSplit s = splitSun(env, {.threshold = 4.0, .cellDegrees = cell});
        ASSERT_EQ(s.residual.pixels.size(), env.pixels.size());
        EXPECT_GT(s.texelsAbove, 1u);
        EXPECT_FALSE(s.lights.empty());
        const double tau = s.thresholdLuminance;
        EXPECT_NEAR(tau, 4.0 * s.meanLuminance, 1e-12 * tau);
        for (int y = 0; y < env.height; ++y)
            for (int x = 0; x < env.width; ++x) {
                const float* e = env.pixel(x, y);
                const float* r = s.residual.pixel(x, y);
                const double Y = luminance(glm::dvec3(e[0], e[1], e[2]));
                if (Y <= tau) {
                    for (int c = 0; c < 3; ++c) ASSERT_EQ(r[c], e[c]);
                } else {
                    EXPECT_NEAR(luminance(glm::dvec3(r[0], r[1], r[2])), tau, 1e-6 * tau);
                    for (int c = 0; c < 3; ++c) EXPECT_NEAR(r[c] / e[c], tau / Y, 1e-6);
                }
            }
        // The lights carry the excess's integral times the cosine of each texel from its
        // cell's light: all of it for cells of one texel, and at least the cosine of a
        // cell's half diagonal of it for larger ones.
        const glm::dvec3 lights = lightSum(s.lights);
        const double halfDiagonal = 0.5 * std::sqrt(2.0) * s.cellTexels * 2.0 * 3.14159265358979323846 / env.width;
        for (int c = 0; c < 3; ++c) {
            const double whole = latLongIntegral(env, c);
            const double excess = whole - latLongIntegral(s.residual, c);
            EXPECT_GT(excess, 0.1 * whole);
            if (s.cellTexels == 1) {
                EXPECT_NEAR(lights[c], excess, 1e-9 * whole) << "channel " << c;
            } else {
                EXPECT_LE(lights[c], excess * (1.0 + 1e-12)) << "channel " << c << ", cell " << cell;
                EXPECT_GE(lights[c], excess * std::cos(halfDiagonal)) << "channel " << c << ", cell " << cell;
                EXPECT_LT(lights[c], excess * (1.0 - 1e-6)) << "channel " << c << ", cell " << cell;
            }
        }
        for (const Light& l : s.lights) {
            EXPECT_EQ(l.type, LightType::Directional);
            EXPECT_NEAR(glm::length(l.direction), 1.0, 1e-12);
        }
    }
}

// Closed form: a constant sky of radiance c plus a one-texel sun of radiance S in texel
// t. Ybar = (4 pi c + (S - c) Omega_t) / 4 pi (luminance of gray = the value), the sun's
// texel is clamped to tau = k Ybar and the one light (cells of one texel) carries
// (S - tau) Omega_t from that texel's centre direction.
TEST(SunSplit, OneTexelSunIsOneLightWithTheClosedFormIrradiance) {
    const int W = 64, H = 32;
    const float c = 0.5f, S = 2000.0f;
    const glm::dvec3 toward = glm::normalize(glm::dvec3(0.3, 0.8, -0.5));
    Image env = constantEnvironment(W, {c, c, c});
    const glm::dvec2 uv = directionToLatLong(toward);
    const int tx = std::min(int(uv.x * W), W - 1), ty = std::min(int(uv.y * H), H - 1);
    for (int ch = 0; ch < 3; ++ch) env.at(tx, ty, ch) = S;
    const double omega = latLongPixelSolidAngle(ty, W, H);
    const double mean = (kFourPi * c + (S - c) * omega) / kFourPi;
    const SunSplit s = splitSun(env, {.threshold = 16.0, .cellDegrees = 1.0});
    EXPECT_EQ(s.cellTexels, 1);
    EXPECT_NEAR(s.meanLuminance, mean, 1e-6 * mean);
    ASSERT_EQ(s.texelsAbove, 1u);
    ASSERT_EQ(s.lights.size(), 1u);
    const double tau = 16.0 * mean;
    for (int ch = 0; ch < 3; ++ch) EXPECT_NEAR(s.lights[0].rgb[ch], (S - tau) * omega, 1e-5 * (S - tau) * omega);
    const glm::dvec3 centre = latLongPixelDirection(tx, ty, W, H);
    EXPECT_NEAR(glm::length(s.lights[0].direction - centre), 0.0, 1e-12);
    EXPECT_NEAR(s.lightFraction, (S - tau) * omega / (kFourPi * mean), 1e-6);
    EXPECT_NEAR(s.residual.at(tx, ty, 0), tau, 1e-4 * tau);
}

// Nothing above the threshold: no light, the residual is the environment. A constant
// environment is its own mean, so no k >= 1 takes anything; neither from a black one.
TEST(SunSplit, NothingAboveTheThresholdLeavesTheEnvironment) {
    for (const Image& env : {constantEnvironment(32, {0.7f, 0.7f, 0.7f}), constantEnvironment(32, {0, 0, 0})}) {
        const SunSplit s = splitSun(env, {.threshold = 1.0});
        EXPECT_TRUE(s.lights.empty());
        EXPECT_EQ(s.texelsAbove, 0u);
        EXPECT_EQ(s.residual.pixels, env.pixels);
        EXPECT_EQ(s.lightFraction, 0.0);
    }
    const Image sky = testSky();
    const SunSplit none = splitSun(sky, {.threshold = 1e9});
    EXPECT_TRUE(none.lights.empty());
    EXPECT_EQ(none.residual.pixels, sky.pixels);
}

// Larger cells merge lights, keep their sum up to the cosines within a cell, and each
// merged direction lies within its cell (here: within the cell's diagonal of one of the
// one-texel lights).
TEST(SunSplit, CellsMergeLightsAndKeepTheirSum) {
    const Image env = testSky(256);
    const SunSplit fine = splitSun(env, {.threshold = 2.0, .cellDegrees = 0.5});
    const SunSplit coarse = splitSun(env, {.threshold = 2.0, .cellDegrees = 8.0});
    EXPECT_EQ(fine.cellTexels, 1);
    EXPECT_EQ(coarse.cellTexels, 6);
    EXPECT_LT(coarse.lights.size(), fine.lights.size());
    const glm::dvec3 a = lightSum(fine.lights), b = lightSum(coarse.lights);
    const double cellRadians = 6.0 * 2.0 * 3.14159265358979323846 / 256 * std::sqrt(2.0);
    for (int c = 0; c < 3; ++c) {  // a cosine within each merged cell lost (the header's irradiance)
        EXPECT_LE(b[c], a[c]);
        EXPECT_GE(b[c], a[c] * std::cos(0.5 * cellRadians));
    }
    for (const Light& l : coarse.lights) {
        double nearest = 1e9;
        for (const Light& f : fine.lights)
            nearest = std::min(nearest, std::acos(std::min(1.0, glm::dot(l.direction, f.direction))));
        EXPECT_LT(nearest, cellRadians);
    }
}

// Round trip with the rotation convention: turning the map by k whole texel columns
// about +Y (a cyclic shift, L'(d) = L(R^T d)) and splitting it gives the lights of the
// unturned map turned by R.
TEST(SunSplit, RotatedLightsAreTheLightsOfTheRotatedMap) {
    const Image env = testSky(128);
    const int W = env.width, H = env.height, k = 19;
    Image turned(W, H, 3);
    // rotationY(+a) moves what was at u to u - a / 360 (envmap.h: -Z (u = 0.5) -> -X (u = 0.25)).
    for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x)
            for (int c = 0; c < 3; ++c) turned.at(((x - k) % W + W) % W, y, c) = env.at(x, y, c);
    const glm::dmat3 R = rotationY(360.0 * k / W);
    const SunSplitOptions one{.threshold = 3.0, .cellDegrees = 0.1};
    const std::vector<Light> expected = rotatedLights(splitSun(env, one).lights, R);
    const std::vector<Light> got = splitSun(turned, one).lights;
    ASSERT_EQ(got.size(), expected.size());
    // Cells are visited in another order: match each light by direction.
    for (const Light& e : expected) {
        double best = 1e9;
        const Light* match = nullptr;
        for (const Light& g : got)
            if (glm::length(g.direction - e.direction) < best) {
                best = glm::length(g.direction - e.direction);
                match = &g;
            }
        ASSERT_LT(best, 1e-12);
        for (int c = 0; c < 3; ++c) EXPECT_NEAR(match->rgb[c], e.rgb[c], 1e-9 * e.rgb[c]);
    }
}

TEST(SunSplit, BadOptionsAndImagesAreRefused) {
    const Image env = testSky(32);
    EXPECT_THROW(splitSun(env, {.threshold = 0.0}), Error);
    EXPECT_THROW(splitSun(env, {.threshold = -2.0}), Error);
    EXPECT_THROW(splitSun(env, {.threshold = std::nan("")}), Error);
    EXPECT_THROW(splitSun(env, {.cellDegrees = 0.0}), Error);
    EXPECT_THROW(splitSun(env, {.cellDegrees = 91.0}), Error);
    EXPECT_THROW(splitSun(Image(30, 20, 3, 1.0f)), Error);
    EXPECT_THROW(splitSun(Image(32, 16, 1, 1.0f)), Error);
    EXPECT_THROW(splitSun(Image()), Error);
    Image negative = env;
    negative.at(3, 4, 1) = -1.0f;
    EXPECT_THROW(splitSun(negative), Error);
    Image nan = env;
    nan.at(3, 4, 2) = std::nanf("");
    EXPECT_THROW(splitSun(nan), Error);
    try {
        splitSun(env, {.threshold = 0.0});
        FAIL() << "a threshold of 0 was accepted";
    } catch (const Error& e) {
        EXPECT_NE(std::string(e.what()).find("--sun-threshold"), std::string::npos) << e.what();
    }
}
