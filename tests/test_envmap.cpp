#include "common/envmap.h"

#include <gtest/gtest.h>
#include <tbb/task_arena.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <numbers>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include "common/error.h"

namespace fs = std::filesystem;
using prt::Cubemap;
using prt::Image;

namespace {

constexpr double kPi = std::numbers::pi;

std::string str(const glm::dvec3& d) {
    return "(" + std::to_string(d.x) + ", " + std::to_string(d.y) + ", " + std::to_string(d.z) + ")";
}

double angleBetween(const glm::dvec3& a, const glm::dvec3& b) {
    return std::acos(std::clamp(glm::dot(glm::normalize(a), glm::normalize(b)), -1.0, 1.0));
}

glm::dvec3 randomDirection(std::mt19937& rng) {
    std::normal_distribution<double> g;
    glm::dvec3 d;
    do d = {g(rng), g(rng), g(rng)};
    while (glm::length(d) < 1e-6);
    return glm::normalize(d);
}

void expectDirNear(const glm::dvec3& a, const glm::dvec3& b, double tol = 1e-12) {
    EXPECT_NEAR(a.x, b.x, tol);
    EXPECT_NEAR(a.y, b.y, tol);
    EXPECT_NEAR(a.z, b.z, tol);
}

// Lat-long image sampled from a function of direction at pixel centres.
template <class F>
Image latLongFrom(int width, F&& f) {
    Image img(width, width / 2, 3);
    for (int y = 0; y < img.height; ++y)
        for (int x = 0; x < img.width; ++x) {
            const glm::dvec3 v = f(prt::latLongPixelDirection(x, y, img.width, img.height));
            for (int c = 0; c < 3; ++c) img.at(x, y, c) = float(v[c]);
        }
    return img;
}

// A hostile synthetic map: per-pixel log-uniform noise over six decades, a fine
// checkerboard, thin bright lines and a few very bright single pixels (suns).
Image highFrequencyMap(int width, unsigned seed) {
    const int height = width / 2;
    Image img(width, height, 3);
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> expo(-3.0f, 3.0f);
    for (int y = 0; y < height; ++y)
        for (int x = 0; x < width; ++x)
            for (int c = 0; c < 3; ++c) {
                float v = std::pow(10.0f, expo(rng));
                if (((x / 2) + (y / 2)) % 2 == 0) v *= 0.01f;
                if (x % 97 == 0 || y % 61 == 0) v += 500.0f;
                img.at(x, y, c) = v;
            }
    std::uniform_int_distribution<int> px(0, width - 1), py(0, height - 1);
    for (int k = 0; k < 12; ++k) {
        const int x = px(rng), y = py(rng);
        for (int c = 0; c < 3; ++c) img.at(x, y, c) = 2.0e5f;
    }
    return img;
}

void expectIntegralPreserved(const Image& latlong, const Cubemap& cube, double relTol,
                             const std::string& what) {
    const std::vector<double> cubeSum = cube.integrate();
    for (int c = 0; c < latlong.channels; ++c) {
        const double ref = prt::latLongIntegral(latlong, c);
        const double rel = std::abs(cubeSum[size_t(c)] - ref) / ref;
        EXPECT_LT(rel, 0.005) << what;  // the specification's bound
        EXPECT_LT(rel, relTol) << what << " channel " << c << ": lat-long " << ref << " cube "
                               << cubeSum[size_t(c)];
        std::printf("[ info ] %s channel %d: relative integral error %.2e\n", what.c_str(), c,
                    rel);
    }
}

class EnvFileTest : public ::testing::Test {
protected:
    void SetUp() override {
        const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
        dir_ = fs::temp_directory_path() /
               ("prt_test_envmap_" + std::to_string(long(::getpid())) + "_" + info->name());
        fs::remove_all(dir_);
        fs::create_directories(dir_);
    }
    void TearDown() override {
        std::error_code ec;
        fs::remove_all(dir_, ec);
    }
    std::string file(const std::string& name) const { return (dir_ / name).string(); }
    fs::path dir_;
};

template <class F>
std::string errorMessage(F&& f) {
    try {
        f();
    } catch (const prt::Error& e) {
        return e.what();
    }
    return "";
}

}  // namespace

// ---------------------------------------------------------------- conventions

TEST(LatLong, ConventionDirections) {
    expectDirNear(prt::latLongToDirection(0.5, 0.5), {0, 0, -1});  // image centre is -Z
    expectDirNear(prt::latLongToDirection(0.75, 0.5), {1, 0, 0});  // u = 0.75 is +X
    expectDirNear(prt::latLongToDirection(0.25, 0.5), {-1, 0, 0});
    expectDirNear(prt::latLongToDirection(0.0, 0.5), {0, 0, 1});
    expectDirNear(prt::latLongToDirection(1.0, 0.5), {0, 0, 1});
    expectDirNear(prt::latLongToDirection(0.3, 0.0), {0, 1, 0});   // top row is +Y
    expectDirNear(prt::latLongToDirection(0.3, 1.0), {0, -1, 0});

    const glm::dvec2 px = prt::directionToLatLong({1, 0, 0});
    EXPECT_NEAR(px.x, 0.75, 1e-15);
    EXPECT_NEAR(px.y, 0.5, 1e-15);
    const glm::dvec2 mz = prt::directionToLatLong({0, 0, -3});  // need not be normalised
    EXPECT_NEAR(mz.x, 0.5, 1e-15);
    EXPECT_NEAR(mz.y, 0.5, 1e-15);
    EXPECT_NEAR(prt::directionToLatLong({0, 2, 0}).y, 0.0, 1e-15);
    const glm::dvec2 pz = prt::directionToLatLong({0, 0, 1});
    EXPECT_GE(pz.x, 0.0);
    EXPECT_LT(pz.x, 1.0);

    // Centre pixel of an even-width map sits just right of the centre line, at -Z.
    const glm::dvec3 c = prt::latLongPixelDirection(512, 256, 1024, 512);
    EXPECT_LT(angleBetween(c, {0, 0, -1}), 0.01);
    EXPECT_GT(c.x, 0.0);  // to the right of -Z is +X
    EXPECT_GT(c.y, -0.01);
}

TEST(LatLong, RoundTrip) {
    std::mt19937 rng(1);
    for (int k = 0; k < 10000; ++k) {
        const glm::dvec3 d = randomDirection(rng);
        const glm::dvec2 uv = prt::directionToLatLong(d);
        ASSERT_GE(uv.x, 0.0);
        ASSERT_LT(uv.x, 1.0);
        ASSERT_GE(uv.y, 0.0);
        ASSERT_LE(uv.y, 1.0);
        expectDirNear(prt::latLongToDirection(uv.x, uv.y), d, 1e-12);
    }
    std::uniform_real_distribution<double> u01(0.0, 1.0);
    for (int k = 0; k < 10000; ++k) {
        const double u = u01(rng), v = 0.001 + 0.998 * u01(rng);
        const glm::dvec2 uv = prt::directionToLatLong(prt::latLongToDirection(u, v));
        EXPECT_NEAR(uv.x, u, 1e-12);
        EXPECT_NEAR(uv.y, v, 1e-12);
    }
}

TEST(LatLong, PixelSolidAnglesAreExact) {
    for (int w : {2, 8, 64, 1024}) {
        const int h = w / 2;
        double sum = 0;
        for (int y = 0; y < h; ++y) sum += w * prt::latLongPixelSolidAngle(y, w, h);
        EXPECT_NEAR(sum, 4 * kPi, 1e-12);
    }
    EXPECT_NEAR(prt::latLongPixelSolidAngle(0, 2, 1), 2 * kPi, 1e-12);
    // Row y: 2 pi / W (cos theta0 - cos theta1).
    EXPECT_NEAR(prt::latLongPixelSolidAngle(3, 16, 8),
                2 * kPi / 16 * (std::cos(kPi * 3 / 8) - std::cos(kPi * 4 / 8)), 1e-15);
}

// ---------------------------------------------------------------- generated maps

TEST(Environment, ConstantGivesConstantCubemap) {
    const glm::vec3 value(0.25f, 1.5f, 3.0f);
    const Image env = prt::constantEnvironment(256, value);
    ASSERT_EQ(env.width, 256);
    ASSERT_EQ(env.height, 128);
    ASSERT_EQ(env.channels, 3);
    for (int c = 0; c < 3; ++c)
        EXPECT_NEAR(prt::latLongIntegral(env, c), 4 * kPi * value[c], 1e-6 * 4 * kPi * value[c]);
    for (int n : {1, 4, 32}) {
        const Cubemap cube = prt::latLongToCubemap(env, n, prt::rotationAxisAngle({1, 2, 3}, 37));
        ASSERT_EQ(cube.size(), n);
        ASSERT_EQ(cube.channels(), 3);
        for (size_t t = 0; t < cube.texelCount(); ++t)
            for (int c = 0; c < 3; ++c)
                ASSERT_NEAR(cube.data()[t * 3 + size_t(c)], value[c], 1e-6 * value[c]);
        const std::vector<double> sum = cube.integrate();
        for (int c = 0; c < 3; ++c) EXPECT_NEAR(sum[size_t(c)], 4 * kPi * value[c], 1e-6 * 4 * kPi * value[c]);
    }
}

TEST(Environment, TwoToneHemispheresExact) {
    const Image env = prt::twoToneEnvironment(512, {1, 0, 2}, {0, 3, 2});
    // Channel 0 is the upper hemisphere only, channel 1 the lower only.
    EXPECT_NEAR(prt::latLongIntegral(env, 0), 2 * kPi * 1, 1e-9);
    EXPECT_NEAR(prt::latLongIntegral(env, 1), 2 * kPi * 3, 1e-9);
    EXPECT_NEAR(prt::latLongIntegral(env, 2), 4 * kPi * 2, 1e-9);
    // The horizon is a texel border of every side face (even n): the cube is exact too.
    const Cubemap cube = prt::latLongToCubemap(env, 16);
    const std::vector<double> sum = cube.integrate();
    EXPECT_NEAR(sum[0], 2 * kPi * 1, 1e-6);
    EXPECT_NEAR(sum[1], 2 * kPi * 3, 1e-6);
    EXPECT_NEAR(sum[2], 4 * kPi * 2, 1e-6);
    for (int f = 0; f < prt::kCubeFaces; ++f)
        for (int j = 0; j < 16; ++j)
            for (int i = 0; i < 16; ++i) {
                const glm::dvec3 d = prt::texelDirection(16, f, i, j);
                const float* v = cube.texel(f, i, j);
                EXPECT_FLOAT_EQ(v[0], d.y > 0 ? 1.0f : 0.0f);
                EXPECT_FLOAT_EQ(v[1], d.y > 0 ? 0.0f : 3.0f);
            }

    // Odd height: the middle row straddles the horizon and gets the mean.
    const Image odd = prt::twoToneEnvironment(10, {1, 0, 0}, {0, 1, 0});
    ASSERT_EQ(odd.height, 5);
    EXPECT_FLOAT_EQ(odd.at(0, 2, 0), 0.5f);
    EXPECT_NEAR(prt::latLongIntegral(odd, 0), 2 * kPi, 1e-12);
    EXPECT_NEAR(prt::latLongIntegral(odd, 1), 2 * kPi, 1e-12);
}

TEST(Environment, SunEnergyPreservedAndLocalised) {
    const int width = 1024, n = 32;
    std::mt19937 rng(5);
    std::vector<glm::dvec3> dirs = {{0, 0, -1}, {1, 0, 0}, {0, 1, 0}, {0, -1, 0},
                                    {1, 1, 1},  {-1, 0.2, 1}};  // incl. a cube corner
    for (int k = 0; k < 6; ++k) dirs.push_back(randomDirection(rng));
    const double texelAngle = 2.0 / n;  // face-centre texel width (radians)
    for (const glm::dvec3& dir : dirs) {
        const Image env = prt::sunEnvironment(width, dir, {1000, 2000, 0});
        const double energy = prt::latLongIntegral(env, 0);
        int nonzero = 0;
        for (size_t p = 0; p < env.pixels.size(); p += 3) nonzero += env.pixels[p] != 0;
        ASSERT_EQ(nonzero, 1);

        const Cubemap cube = prt::latLongToCubemap(env, n);
        const std::vector<double> sum = cube.integrate();
        EXPECT_NEAR(sum[0] / energy, 1.0, 1e-5) << str(dir);  // exact up to rounding
        EXPECT_NEAR(sum[1] / sum[0], 2.0, 1e-5);
        EXPECT_EQ(sum[2], 0.0);

        // The brightest texel contains (or neighbours) the sun direction; all energy is
        // within two texels of it.
        const prt::TexelCoord sunTexel = prt::directionToTexel(n, dir);
        float best = -1;
        prt::TexelCoord bestTexel;
        double near = 0, omegaSum = 0;
        for (int f = 0; f < prt::kCubeFaces; ++f)
            for (int j = 0; j < n; ++j)
                for (int i = 0; i < n; ++i) {
                    const float v = cube.texel(f, i, j)[0];
                    if (v > best) best = v, bestTexel = {f, i, j};
                    const double e = v * prt::texelSolidAngle(n, i, j);
                    if (angleBetween(prt::texelDirection(n, f, i, j), dir) < 2.0 * texelAngle)
                        near += e;
                    omegaSum += e;
                }
        EXPECT_NEAR(near, omegaSum, 1e-9 * omegaSum) << str(dir);
        EXPECT_LT(angleBetween(prt::texelDirection(n, bestTexel.face, bestTexel.i, bestTexel.j),
                               prt::texelDirection(n, sunTexel.face, sunTexel.i, sunTexel.j)),
                  1.5 * texelAngle)
            << str(dir);
    }
}

TEST(Environment, GeneratorsRejectBadWidths) {
    EXPECT_THROW(prt::constantEnvironment(7, {1, 1, 1}), prt::Error);
    EXPECT_THROW(prt::constantEnvironment(0, {1, 1, 1}), prt::Error);
    EXPECT_THROW(prt::sunEnvironment(64, {0, 0, 0}, {1, 1, 1}), prt::Error);
    EXPECT_THROW(prt::twoToneEnvironment(-2, {1, 1, 1}, {0, 0, 0}), prt::Error);
}

// ---------------------------------------------------------------- rotation

TEST(Rotation, MatricesAndConvention) {
    const glm::dmat3 r = prt::rotationY(90);
    expectDirNear(r * glm::dvec3(0, 0, -1), {-1, 0, 0}, 0);  // exact at quarter turns
    expectDirNear(r * glm::dvec3(1, 0, 0), {0, 0, -1}, 0);
    expectDirNear(prt::rotationX(90) * glm::dvec3(0, 1, 0), {0, 0, 1}, 0);
    expectDirNear(prt::rotationZ(90) * glm::dvec3(1, 0, 0), {0, 1, 0}, 0);

    std::mt19937 rng(2);
    for (int k = 0; k < 20; ++k) {
        const glm::dvec3 axis = randomDirection(rng);
        const double deg = 360.0 * k / 20 + 3.7;
        const glm::dmat3 m = prt::rotationAxisAngle(axis * 2.5, deg);
        const glm::dmat3 mtm = glm::transpose(m) * m;
        for (int a = 0; a < 3; ++a)
            for (int b = 0; b < 3; ++b) EXPECT_NEAR(mtm[a][b], a == b ? 1.0 : 0.0, 1e-14);
        EXPECT_NEAR(glm::determinant(m), 1.0, 1e-14);
        expectDirNear(m * axis, axis, 1e-14);
        // Right-handed: a vector perpendicular to the axis turns counter-clockwise
        // when seen from the axis tip.
        const glm::dvec3 p = glm::normalize(glm::cross(axis, glm::dvec3(0.3, 0.5, 0.7)));
        const glm::dvec3 q = prt::rotationAxisAngle(axis, 90) * p;
        expectDirNear(q, glm::cross(axis, p), 1e-14);
    }
    const glm::dmat3 y37 = prt::rotationY(37), a37 = prt::rotationAxisAngle({0, 5, 0}, 37);
    for (int a = 0; a < 3; ++a)
        for (int b = 0; b < 3; ++b) EXPECT_NEAR(y37[a][b], a37[a][b], 1e-15);
    EXPECT_THROW(prt::rotationAxisAngle({0, 0, 0}, 10), prt::Error);
}

TEST(Rotation, SunAtMinusZTurnsToMinusX) {
    const int n = 16;
    const Image env = prt::sunEnvironment(512, {0, 0, -1}, {1, 1, 1});
    const Cubemap cube = prt::latLongToCubemap(env, n, prt::rotationY(90));
    float best = -1;
    glm::dvec3 bestDir;
    for (int f = 0; f < prt::kCubeFaces; ++f)
        for (int j = 0; j < n; ++j)
            for (int i = 0; i < n; ++i)
                if (cube.texel(f, i, j)[0] > best) {
                    best = cube.texel(f, i, j)[0];
                    bestDir = prt::texelDirection(n, f, i, j);
                }
    EXPECT_LT(angleBetween(bestDir, {-1, 0, 0}), 2.0 / n);
    EXPECT_EQ(prt::directionToTexel(n, bestDir).face, 1);  // the -X face
}

TEST(Rotation, RotatedCubemapSamplesRotatedEnvironment) {
    // Smooth map L(d) = (2 + d.x, 2 + d.y, 2 + d.z): a texel's average is its value at
    // the texel's centroid, close to the centre direction.
    auto L = [](const glm::dvec3& d) { return glm::dvec3(2.0) + d; };
    const Image env = latLongFrom(512, L);
    const glm::dmat3 r = prt::rotationAxisAngle({0.2, -1, 0.4}, 71);
    const int n = 16;
    const Cubemap cube = prt::latLongToCubemap(env, n, r);
    double worst = 0;
    for (int f = 0; f < prt::kCubeFaces; ++f)
        for (int j = 0; j < n; ++j)
            for (int i = 0; i < n; ++i) {
                const glm::dvec3 d = prt::texelDirection(n, f, i, j);
                const glm::dvec3 expect = L(glm::transpose(r) * d);  // L'(d) = L(R^T d)
                for (int c = 0; c < 3; ++c)
                    worst = std::max(worst, std::abs(cube.texel(f, i, j)[c] - expect[c]));
            }
    EXPECT_LT(worst, 0.01);
}

// ---------------------------------------------------------------- filtering

TEST(Filtering, IntegralPreservedOnHighFrequencyMap) {
    const Image env = highFrequencyMap(1024, 3);
    expectIntegralPreserved(env, prt::latLongToCubemap(env, 32), 1e-5, "synthetic N=32");
    expectIntegralPreserved(env, prt::latLongToCubemap(env, 32, prt::rotationAxisAngle({1, 1, 0}, 33)),
                            1e-5, "synthetic rotated N=32");
    expectIntegralPreserved(env, prt::latLongToCubemap(env, 64), 1e-5, "synthetic N=64");
    const Image small = highFrequencyMap(64, 4);  // cube finer than the lat-long
    expectIntegralPreserved(small, prt::latLongToCubemap(small, 32), 1e-5, "64x32 map N=32");
    const Image tiny = highFrequencyMap(8, 5);  // pixels of 45 degrees
    expectIntegralPreserved(tiny, prt::latLongToCubemap(tiny, 16), 1e-4, "8x4 map N=16");
    expectIntegralPreserved(env, prt::latLongToCubemap(env, 1), 1e-5, "synthetic N=1");
    expectIntegralPreserved(env, prt::latLongToCubemap(env, 256), 1e-5, "synthetic N=256");
}

TEST(Filtering, DeterministicAndValidated) {
    const Image env = highFrequencyMap(256, 8);
    const Cubemap a = prt::latLongToCubemap(env, 16);
    const Cubemap b = prt::latLongToCubemap(env, 16);
    EXPECT_EQ(a.data(), b.data());
    EXPECT_THROW(prt::latLongToCubemap(env, 12), prt::Error);
    EXPECT_THROW(prt::latLongToCubemap(Image(), 16), prt::Error);
    Image bad = env;
    bad.pixels.pop_back();
    EXPECT_THROW(prt::latLongToCubemap(bad, 16), prt::Error);
}

TEST(Filtering, CubemapToLatLongReproducesSmoothMap) {
    auto L = [](const glm::dvec3& d) { return glm::dvec3(1.0 + 0.5 * d.x, 1.0 + d.y * d.y, 1.5 - 0.5 * d.z); };
    const Image env = latLongFrom(256, L);
    const Image back = prt::cubemapToLatLong(prt::latLongToCubemap(env, 32), 128);
    ASSERT_EQ(back.width, 128);
    ASSERT_EQ(back.height, 64);
    double worst = 0;
    for (int y = 0; y < back.height; ++y)
        for (int x = 0; x < back.width; ++x) {
            const glm::dvec3 v = L(prt::latLongPixelDirection(x, y, 128, 64));
            for (int c = 0; c < 3; ++c) worst = std::max(worst, std::abs(back.at(x, y, c) - v[c]));
        }
    EXPECT_LT(worst, 0.03);
    EXPECT_THROW(prt::cubemapToLatLong(prt::latLongToCubemap(env, 4), 7), prt::Error);
}

// ---------------------------------------------------------------- rotation about +Y as a column shift

namespace {

// Largest |a - b| / (|b| + floor) over texels and channels, floor = floorFraction max |b|.
//
// Comparing with latLongToCubemap at rotationY(360 k / W), a small floor is needed: there
// the rotated corner directions carry ~1e-16 of rounding, so where a pixel-column border
// lies exactly on a texel border (e.g. the face centre lines) the exact path leaves
// slivers of ~1e-14 of a pixel's solid angle in the neighbouring texel, which the filter
// (built at identity) does not (measured: 2.4e-17 sr next to a 1.3e-3 sr piece). That is
// visible only next to a pixel ~1e9 times brighter, as in highFrequencyMap (suns of
// 2e5 beside pixels of 1e-5): an absolute difference of ~2e-14 of the brightest texel.
double worstRelativeDifference(const Cubemap& a, const Cubemap& b, double floorFraction = 1e-7) {
    EXPECT_EQ(a.size(), b.size());
    EXPECT_EQ(a.channels(), b.channels());
    if (a.data().size() != b.data().size()) return INFINITY;
    double largest = 0.0;
    for (float v : b.data()) largest = std::max(largest, double(std::abs(v)));
    const double floor = floorFraction * largest;
    double worst = 0.0;
    for (size_t k = 0; k < a.data().size(); ++k)
        worst = std::max(worst, std::abs(double(a.data()[k]) - double(b.data()[k])) /
                                    (std::abs(double(b.data()[k])) + floor));
    return worst;
}

// The filtered cubemap equals the exact rotated filter at whole-pixel angles.
void expectWholePixelShiftsExact(const Image& env, int n, const std::vector<int>& shifts,
                                 double tol, const std::string& what) {
    const prt::LatLongCubemapFilter filter(env.width, env.height, n);
    for (int k : shifts) {
        const double degrees = 360.0 * k / env.width;
        const double worst = worstRelativeDifference(filter.apply(env, degrees),
                                                     prt::latLongToCubemap(env, n, prt::rotationY(degrees)));
        EXPECT_LT(worst, tol) << what << ", shift " << k << " pixels (" << degrees << " degrees)";
        std::printf("[ info ] %s N=%d shift %d px: worst relative texel difference %.2e\n",
                    what.c_str(), n, k, worst);
    }
}

}  // namespace

TEST(Rotation, AboutYIsRecognisedWithItsAngle) {
    double deg = 1234.0;
    ASSERT_TRUE(prt::rotationAboutY(glm::dmat3(1.0), deg));
    EXPECT_EQ(deg, 0.0);
    for (double a : {37.5, -90.0, 90.0, 179.0, -0.001, 0.3515625}) {
        ASSERT_TRUE(prt::rotationAboutY(prt::rotationY(a), deg)) << a;
        EXPECT_NEAR(deg, a, 1e-12) << a;
    }
    ASSERT_TRUE(prt::rotationAboutY(prt::rotationY(180), deg));
    EXPECT_EQ(std::abs(deg), 180.0);
    // Products of rotationY matrices (turntable and spin frames) and the axis form.
    ASSERT_TRUE(prt::rotationAboutY(prt::rotationY(-30) * prt::rotationY(100), deg));
    EXPECT_NEAR(deg, 70.0, 1e-12);
    ASSERT_TRUE(prt::rotationAboutY(prt::rotationAxisAngle({0, 3, 0}, 200), deg));
    EXPECT_NEAR(deg, -160.0, 1e-12);
    // Anything else is not, and leaves the angle alone.
    deg = 5.0;
    EXPECT_FALSE(prt::rotationAboutY(prt::rotationX(10), deg));
    EXPECT_FALSE(prt::rotationAboutY(prt::rotationZ(0.001), deg));
    EXPECT_FALSE(prt::rotationAboutY(prt::rotationAxisAngle({0, 1, 1e-6}, 40), deg));
    EXPECT_FALSE(prt::rotationAboutY(prt::rotationY(40) * prt::rotationX(40), deg));
    EXPECT_FALSE(prt::rotationAboutY(glm::dmat3(2.0), deg));  // not a rotation
    EXPECT_FALSE(prt::rotationAboutY(glm::dmat3(-1.0), deg));
    glm::dmat3 nan(1.0);
    nan[0][0] = NAN;
    EXPECT_FALSE(prt::rotationAboutY(nan, deg));
    EXPECT_EQ(deg, 5.0);
}

TEST(LatLongFilter, WholePixelShiftsEqualExactRotationOfOnePixelSun) {
    // One-pixel suns, one on the horizon straddling the -Z face's centre lines, one in
    // a high row whose pixel straddles the +Y face's borders, one near the pole.
    Image env = prt::sunEnvironment(256, {0.3, 0.05, -1}, {1000, 2000, 3000});
    const Image sun2 = prt::sunEnvironment(256, {1, 1.2, 1}, {50, 0, 10});
    const Image sun3 = prt::sunEnvironment(256, {0.01, 1, 0.02}, {0, 7, 0});
    for (size_t k = 0; k < env.pixels.size(); ++k) env.pixels[k] += sun2.pixels[k] + sun3.pixels[k];
    expectWholePixelShiftsExact(env, 16, {0, 1, 7, 32, 64, 100, 128, 200, 255}, 1e-6, "suns 256x128");
    expectWholePixelShiftsExact(env, 64, {0, 3, 64, 129}, 1e-6, "suns 256x128");
    // Where the sun goes: rotationY(90) takes the -Z region to -X (64 pixels).
    const prt::LatLongCubemapFilter filter(256, 128, 16);
    const Image minusZ = prt::sunEnvironment(256, {0.2, 0.1, -1}, {1, 1, 1});
    const Cubemap turned = filter.apply(minusZ, 90.0);
    const std::vector<double> perFace = [&] {
        std::vector<double> e(6, 0.0);
        for (int f = 0; f < 6; ++f)
            for (int j = 0; j < 16; ++j)
                for (int i = 0; i < 16; ++i) e[size_t(f)] += turned.texel(f, i, j)[0];
        return e;
    }();
    EXPECT_EQ(std::max_element(perFace.begin(), perFace.end()) - perFace.begin(), 1);  // -X
}

TEST(LatLongFilter, WholePixelShiftsEqualExactRotationOnHighFrequencyMap) {
    const Image env = highFrequencyMap(512, 21);
    expectWholePixelShiftsExact(env, 32, {0, 1, 53, 128, 256, 511}, 1e-6, "synthetic 512x256");
    const Image small = highFrequencyMap(64, 22);  // cube texels smaller than the pixels
    expectWholePixelShiftsExact(small, 32, {0, 5, 16, 63}, 1e-6, "synthetic 64x32");
}

TEST(LatLongFilter, FractionalShiftIsTheInterpolatedMapAndKeepsTheIntegral) {
    const Image env = highFrequencyMap(256, 31);
    const int n = 16, W = env.width;
    const prt::LatLongCubemapFilter filter(W, env.height, n);
    for (double shift : {0.25, 17.5, 100.9, 255.6}) {
        SCOPED_TRACE(shift);
        const int k = int(std::floor(shift));
        const double f = shift - k;
        const double degrees = 360.0 * shift / W;
        const Cubemap blended = filter.apply(env, degrees);
        // (1 - f) cube(k) + f cube(k + 1), hence between the two at every texel.
        const Cubemap c0 = filter.apply(env, 360.0 * k / W), c1 = filter.apply(env, 360.0 * (k + 1) / W);
        Cubemap mix(n, 3);
        for (size_t t = 0; t < mix.data().size(); ++t)
            mix.data()[t] = float((1 - f) * c0.data()[t] + f * c1.data()[t]);
        EXPECT_LT(worstRelativeDifference(blended, mix), 1e-6);
        // ... which is the exact filter of the map linearly interpolated in longitude
        // (column x of the interpolated map: (1 - f) L(x) + f L(x + 1)), turned by k pixels.
        Image lerped(W, env.height, 3);
        for (int y = 0; y < env.height; ++y)
            for (int x = 0; x < W; ++x)
                for (int c = 0; c < 3; ++c)
                    lerped.at(x, y, c) = float((1 - f) * env.at(x, y, c) + f * env.at((x + 1) % W, y, c));
        EXPECT_LT(worstRelativeDifference(
                      blended, prt::latLongToCubemap(lerped, n, prt::rotationY(360.0 * k / W))),
                  1e-6);
        // The integral over the sphere is the map's (rotation about +Y only moves pixels
        // within their rows), as for the exact filter.
        expectIntegralPreserved(env, blended, 1e-5, "fractional shift");
    }
}

TEST(LatLongFilter, FractionalShiftIsSubPixelOnSmoothMap) {
    // Between whole pixels the filter differs from the exact rotated filter by much less
    // than turning the environment by one more pixel changes the exact filter.
    auto L = [](const glm::dvec3& d) { return glm::dvec3(2.0 + d.x, 2.0 + d.y * d.z, 2.0 - d.z * d.x); };
    const Image env = latLongFrom(256, L);
    const int n = 16;
    const prt::LatLongCubemapFilter filter(256, 128, n);
    auto maxAbsDifference = [](const Cubemap& a, const Cubemap& b) {
        double m = 0.0;
        for (size_t t = 0; t < a.data().size(); ++t)
            m = std::max(m, std::abs(double(a.data()[t]) - double(b.data()[t])));
        return m;
    };
    for (double degrees : {37.5, -123.4, 0.7}) {
        const Cubemap exact = prt::latLongToCubemap(env, n, prt::rotationY(degrees));
        const double error = maxAbsDifference(filter.apply(env, degrees), exact);
        const double onePixel =
            maxAbsDifference(prt::latLongToCubemap(env, n, prt::rotationY(degrees + 360.0 / 256)), exact);
        EXPECT_LT(error, 0.25 * onePixel) << degrees;
        EXPECT_LT(worstRelativeDifference(filter.apply(env, degrees), exact), 2e-3) << degrees;
        std::printf("[ info ] smooth map, %g degrees: max difference %.2e, one more pixel of turn %.2e\n",
                    degrees, error, onePixel);
    }
}

TEST(LatLongFilter, FullTurnsAndConstantMaps) {
    const Image env = highFrequencyMap(128, 41);
    const prt::LatLongCubemapFilter filter(128, 64, 8);
    const Cubemap zero = filter.apply(env, 0.0);
    EXPECT_EQ(filter.apply(env, 360.0).data(), zero.data());
    EXPECT_EQ(filter.apply(env, -360.0).data(), zero.data());
    EXPECT_EQ(filter.apply(env, 720.0).data(), zero.data());
    EXPECT_EQ(filter.apply(env, 360.0 + 90.0).data(), filter.apply(env, 90.0).data());
    EXPECT_EQ(filter.apply(env, -270.0).data(), filter.apply(env, 90.0).data());
    // A hair off a whole pixel is that pixel.
    EXPECT_EQ(filter.apply(env, 360.0 * (5 + 1e-12) / 128).data(), filter.apply(env, 360.0 * 5 / 128).data());
    EXPECT_EQ(filter.apply(env, 360.0 * (5 - 1e-12) / 128).data(), filter.apply(env, 360.0 * 5 / 128).data());
    EXPECT_LT(worstRelativeDifference(zero, prt::latLongToCubemap(env, 8)), 1e-6);
    // Weights of a texel sum to 1: a constant map gives a constant cubemap at any angle.
    const Image cst = prt::constantEnvironment(128, {0.5f, 2.0f, 4.0f});
    for (double degrees : {0.0, 33.3, 90.0}) {
        const Cubemap c = filter.apply(cst, degrees);
        for (size_t t = 0; t < c.texelCount(); ++t)
            for (int ch = 0; ch < 3; ++ch)
                EXPECT_NEAR(c.data()[3 * t + size_t(ch)], cst.at(0, 0, ch), 1e-6 * cst.at(0, 0, ch));
    }
    // Any channel count, like latLongToCubemap.
    Image gray(128, 64, 1);
    for (int y = 0; y < 64; ++y)
        for (int x = 0; x < 128; ++x) gray.at(x, y, 0) = env.at(x, y, 1);
    const Cubemap g = filter.apply(gray, 45.0);
    ASSERT_EQ(g.channels(), 1);
    EXPECT_LT(worstRelativeDifference(g, prt::latLongToCubemap(gray, 8, prt::rotationY(45.0))), 1e-6);
}

TEST(LatLongFilter, DeterministicValidatedAndShared) {
    const Image env = highFrequencyMap(128, 51);
    const prt::LatLongCubemapFilter a(128, 64, 16), b(128, 64, 16);
    EXPECT_EQ(a.entryCount(), b.entryCount());
    EXPECT_EQ(a.apply(env, 12.3).data(), b.apply(env, 12.3).data());
    EXPECT_GE(a.entryCount(), size_t(128 * 64));  // every pixel lands somewhere
    EXPECT_GT(a.memoryBytes(), a.entryCount() * 8);
    EXPECT_EQ(a.width(), 128);
    EXPECT_EQ(a.height(), 64);
    EXPECT_EQ(a.size(), 16);

    EXPECT_THROW(prt::LatLongCubemapFilter(128, 64, 12), prt::Error);
    EXPECT_THROW(prt::LatLongCubemapFilter(0, 64, 16), prt::Error);
    EXPECT_THROW(prt::LatLongCubemapFilter(70000, 35000, 16), prt::Error);
    EXPECT_THROW(a.apply(highFrequencyMap(256, 1), 0.0), prt::Error);  // other size
    EXPECT_THROW(a.apply(Image(), 0.0), prt::Error);
    EXPECT_THROW(a.apply(env, NAN), prt::Error);
    EXPECT_THROW(a.apply(env, INFINITY), prt::Error);
    Image bad = env;
    bad.pixels.pop_back();
    EXPECT_THROW(a.apply(bad, 0.0), prt::Error);

    // The shared cache: one filter per size, the same one from every thread.
    std::vector<std::shared_ptr<const prt::LatLongCubemapFilter>> got(4);
    std::vector<std::thread> threads;
    for (size_t t = 0; t < got.size(); ++t)
        threads.emplace_back([&got, t] { got[t] = prt::LatLongCubemapFilter::shared(64, 32, 8); });
    for (auto& th : threads) th.join();
    for (const auto& f : got) EXPECT_EQ(f.get(), got[0].get());
    ASSERT_TRUE(got[0]);
    EXPECT_EQ(got[0]->size(), 8);
    EXPECT_NE(prt::LatLongCubemapFilter::shared(64, 32, 4).get(), got[0].get());
    EXPECT_EQ(prt::LatLongCubemapFilter::shared(64, 32, 8).get(), got[0].get());
    EXPECT_THROW(prt::LatLongCubemapFilter::shared(64, 32, 3), prt::Error);
    EXPECT_THROW(prt::LatLongCubemapFilter::shared(64, 32, 3), prt::Error);  // not cached
}

// ---------------------------------------------------------------- running-sum apply

namespace {

// Any size and channel count (the filter takes any width and height): log-uniform noise
// over six decades plus a few pixels 1e4 times brighter.
Image noiseMap(int width, int height, int channels, unsigned seed) {
    Image img(width, height, channels);
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> expo(-3.0f, 3.0f);
    for (float& v : img.pixels) v = std::pow(10.0f, expo(rng));
    std::uniform_int_distribution<size_t> any(0, img.pixels.size() - 1);
    for (int k = 0; k < 3; ++k) img.pixels[any(rng)] = 1.0e7f;
    return img;
}

// Column x of the map linearly interpolated in longitude: (1 - f) L(x) + f L(x + 1).
Image lerpColumns(const Image& env, double f) {
    Image out(env.width, env.height, env.channels);
    for (int y = 0; y < env.height; ++y)
        for (int x = 0; x < env.width; ++x)
            for (int c = 0; c < env.channels; ++c)
                out.at(x, y, c) = float((1 - f) * env.at(x, y, c) + f * env.at((x + 1) % env.width, y, c));
    return out;
}

// Tolerances of the running-sum apply against the reference paths. Both applies use the
// same float weights with double sums, so against apply(const Image&) only the running
// sums' rounding shows: ~1e-16 of a row's total per texel (envmap.h), here at most
// 1e-16 x 1e7 x (a few pixels of weight ~1) against texels of >= ~1e-3, 1e-6 relative
// with a floor of 1e-12 of the brightest texel. Against latLongToCubemap the float
// weights add ~1e-7 relative (the existing filter tests' 1e-6, with their floor).
constexpr double kSameWeightsTolerance = 1e-6, kSameWeightsFloor = 1e-12;
constexpr double kExactTolerance = 1e-6;

// The running-sum apply of env at each of `shifts` (pixels) against apply(const Image&)
// and against latLongToCubemap: turned by the shift when whole, else of the map
// interpolated between columns turned by its whole part.
void expectRowSumsMatch(const Image& env, int n, const std::vector<double>& shifts, const std::string& what) {
    const prt::LatLongCubemapFilter filter(env.width, env.height, n);
    const prt::LatLongRowSums sums(env);
    for (double shift : shifts) {
        SCOPED_TRACE(what + ", N = " + std::to_string(n) + ", shift " + std::to_string(shift) + " px");
        const double degrees = 360.0 * shift / env.width;
        const Cubemap fast = filter.apply(sums, degrees);
        ASSERT_EQ(fast.channels(), env.channels);
        EXPECT_LT(worstRelativeDifference(fast, filter.apply(env, degrees), kSameWeightsFloor),
                  kSameWeightsTolerance);
        const int k = int(std::floor(shift));
        const double f = shift - k;
        const Cubemap exact = f == 0.0 ? prt::latLongToCubemap(env, n, prt::rotationY(degrees))
                                       : prt::latLongToCubemap(lerpColumns(env, f), n,
                                                               prt::rotationY(360.0 * k / env.width));
        EXPECT_LT(worstRelativeDifference(fast, exact), kExactTolerance);
    }
}

}  // namespace

TEST(LatLongFilter, RowSumsMatchReferenceAtWholeAndFractionalShifts) {
    // Whole shifts (0, 1, the last column, i.e. runs crossing the right edge after the
    // turn), fractional ones (one blending the last column with column 0), N = 1 .. 64.
    const Image env = noiseMap(256, 128, 3, 61);
    for (int n : {1, 2, 8, 32, 64})
        expectRowSumsMatch(env, n, {0.0, 1.0, 255.0, 100.0, 0.25, 37.5, 255.5, 254.999}, "256 x 128");
}

TEST(LatLongFilter, RowSumsMatchReferenceOnOddAndTinyMaps) {
    // Odd widths and heights (runs of odd lengths, a row straddling the horizon) and maps
    // smaller than the cubemap (one-pixel runs, texels sharing pixels, whole-row runs).
    struct Size {
        int width, height;
    };
    for (Size s : {Size{129, 64}, Size{77, 39}, Size{8, 4}, Size{3, 2}, Size{2, 1}, Size{1, 1}, Size{5, 1}})
        for (int n : {1, 4, 16})
            expectRowSumsMatch(noiseMap(s.width, s.height, 3, unsigned(s.width * 100 + s.height)), n,
                               {0.0, 1.0, double(s.width - 1), 0.5, s.width - 0.25},
                               std::to_string(s.width) + " x " + std::to_string(s.height));
}

TEST(LatLongFilter, RowSumsAnyChannelCount) {
    for (int channels : {1, 2, 4, 5})
        expectRowSumsMatch(noiseMap(64, 32, channels, unsigned(channels)), 8, {0.0, 9.0, 9.5, 63.5},
                           std::to_string(channels) + " channels");
}

TEST(LatLongFilter, RowSumsConstantMapAndFullTurns) {
    const prt::LatLongCubemapFilter filter(96, 48, 8);
    const Image cst = prt::constantEnvironment(96, {0.5f, 2.0f, 4.0f});
    const prt::LatLongRowSums constant(cst);
    for (double degrees : {0.0, 33.3, 90.0, 359.9}) {
        const Cubemap c = filter.apply(constant, degrees);
        for (size_t t = 0; t < c.texelCount(); ++t)
            for (int ch = 0; ch < 3; ++ch)
                ASSERT_NEAR(c.data()[3 * t + size_t(ch)], cst.at(0, 0, ch), 1e-6 * cst.at(0, 0, ch)) << degrees;
    }
    const prt::LatLongRowSums sums(noiseMap(96, 48, 3, 7));
    EXPECT_EQ(filter.apply(sums, 360.0 + 45.0).data(), filter.apply(sums, 45.0).data());
    EXPECT_EQ(filter.apply(sums, -315.0).data(), filter.apply(sums, 45.0).data());
    EXPECT_EQ(filter.apply(sums, 360.0 * (5 + 1e-12) / 96).data(), filter.apply(sums, 360.0 * 5 / 96).data());
}

TEST(LatLongFilter, RowSumsIndependentOfThreadCount) {
    const Image env = noiseMap(256, 128, 3, 8);
    const prt::LatLongCubemapFilter filter(256, 128, 32);
    const prt::LatLongRowSums sums(env);
    const Cubemap many = filter.apply(sums, 12.34);
    tbb::task_arena one(1);
    Cubemap single;
    one.execute([&] { single = filter.apply(sums, 12.34); });
    EXPECT_EQ(many.data(), single.data());
}

TEST(LatLongFilter, RowSumsValuesAndValidation) {
    const Image env = noiseMap(6, 3, 2, 9);
    const prt::LatLongRowSums sums(env);
    EXPECT_EQ(sums.width(), 6);
    EXPECT_EQ(sums.height(), 3);
    EXPECT_EQ(sums.channels(), 2);
    EXPECT_GT(sums.memoryBytes(), size_t(3 * 14 * 2) * sizeof(double));
    for (int y = 0; y < 3; ++y)
        for (int c = 0; c < 2; ++c) {
            double running = 0.0;
            for (int j = 0; j <= 13; ++j) {  // two periods and one more column
                EXPECT_NEAR(sums.at(y, j, c), running, 1e-12 * running) << y << " " << j;
                running += env.at(j % 6, y, c);
            }
        }

    const prt::LatLongCubemapFilter filter(6, 3, 4);
    EXPECT_THROW(filter.apply(prt::LatLongRowSums(noiseMap(8, 3, 3, 1)), 0.0), prt::Error);  // other size
    EXPECT_THROW(filter.apply(sums, NAN), prt::Error);
    EXPECT_THROW(filter.apply(sums, INFINITY), prt::Error);
    EXPECT_THROW(prt::LatLongRowSums{Image()}, prt::Error);
    Image bad = env;
    bad.pixels.pop_back();
    EXPECT_THROW(prt::LatLongRowSums{bad}, prt::Error);
    for (float v : {NAN, INFINITY, -INFINITY}) {
        Image nonFinite = env;
        nonFinite.at(4, 1, 1) = v;
        const std::string message = errorMessage([&] { prt::LatLongRowSums{nonFinite}; });
        EXPECT_NE(message.find("row 1"), std::string::npos) << message;
    }
}

// ---------------------------------------------------------------- cross layout

TEST(Cross, LayoutOrientationAndSeams) {
    const int n = 16;
    // A cubemap storing each texel's own centre direction.
    Cubemap dirs(n, 3);
    for (int f = 0; f < prt::kCubeFaces; ++f)
        for (int j = 0; j < n; ++j)
            for (int i = 0; i < n; ++i) {
                const glm::dvec3 d = prt::texelDirection(n, f, i, j);
                for (int c = 0; c < 3; ++c) dirs.texel(f, i, j)[c] = float(d[c]);
            }
    const Image cross = prt::cubemapToCross(dirs);
    ASSERT_EQ(cross.width, 4 * n);
    ASSERT_EQ(cross.height, 3 * n);
    ASSERT_EQ(cross.channels, 3);

    auto used = [&](int cx, int cy) { return cy == 1 || cx == 1; };
    auto dirAt = [&](int x, int y) {
        return glm::dvec3(cross.at(x, y, 0), cross.at(x, y, 1), cross.at(x, y, 2));
    };
    // Unused cells are black.
    for (int y = 0; y < cross.height; ++y)
        for (int x = 0; x < cross.width; ++x)
            if (!used(x / n, y / n)) {
                for (int c = 0; c < 3; ++c) ASSERT_EQ(cross.at(x, y, c), 0.0f) << x << "," << y;
            }

    // Cell centres and orientation (up on the page, right on the page).
    struct Expect {
        int cx, cy;
        glm::dvec3 forward, right, up;
    };
    const Expect cells[6] = {
        {0, 1, {-1, 0, 0}, {0, 0, -1}, {0, 1, 0}}, {1, 1, {0, 0, -1}, {1, 0, 0}, {0, 1, 0}},
        {2, 1, {1, 0, 0}, {0, 0, 1}, {0, 1, 0}},   {3, 1, {0, 0, 1}, {-1, 0, 0}, {0, 1, 0}},
        {1, 0, {0, 1, 0}, {1, 0, 0}, {0, 0, 1}},   {1, 2, {0, -1, 0}, {1, 0, 0}, {0, 0, -1}},
    };
    for (const Expect& e : cells) {
        const int x0 = e.cx * n, y0 = e.cy * n;
        const glm::dvec3 centre = dirAt(x0 + n / 2, y0 + n / 2) + dirAt(x0 + n / 2 - 1, y0 + n / 2 - 1);
        EXPECT_LT(angleBetween(centre, e.forward), 1e-6);
        const glm::dvec3 toRight = dirAt(x0 + n - 1, y0 + n / 2) - dirAt(x0, y0 + n / 2);
        const glm::dvec3 toUp = dirAt(x0 + n / 2, y0) - dirAt(x0 + n / 2, y0 + n - 1);
        EXPECT_GT(glm::dot(glm::normalize(toRight), e.right), 0.99);
        EXPECT_GT(glm::dot(glm::normalize(toUp), e.up), 0.99);
    }
    // The front cell reads like the lat-long map: its right is +X, as u = 0.75 is +X.
    EXPECT_GT(dirAt(2 * n - 1, n + n / 2).x, 0.5);

    // Seams: every pair of adjacent used pixels (including the horizontal wrap of the
    // middle row) shows directions at most about one texel apart.
    const double maxStep = 1.6 * 2.0 / n;
    int seamPairs = 0;
    for (int y = 0; y < cross.height; ++y)
        for (int x = 0; x < cross.width; ++x) {
            if (!used(x / n, y / n)) continue;
            const int xr = (y / n == 1) ? (x + 1) % cross.width : x + 1;
            if (xr < cross.width && used(xr / n, y / n)) {
                EXPECT_LT(angleBetween(dirAt(x, y), dirAt(xr, y)), maxStep) << x << "," << y;
                seamPairs += (xr / n != x / n);
            }
            if (y + 1 < cross.height && used(x / n, (y + 1) / n)) {
                EXPECT_LT(angleBetween(dirAt(x, y), dirAt(x, y + 1)), maxStep) << x << "," << y;
                seamPairs += ((y + 1) / n != y / n);
            }
        }
    EXPECT_EQ(seamPairs, 6 * n);  // 4 vertical seams (one wrapping) + 2 horizontal
}

// ---------------------------------------------------------------- loading

TEST_F(EnvFileTest, LoadsRgbGrayAndRgba) {
    Image rgba(8, 4, 4, 0.5f);
    rgba.at(3, 2, 0) = 7.0f;
    rgba.at(3, 2, 3) = 0.0f;  // alpha must not matter
    prt::writeExr(file("rgba.exr"), rgba);
    const Image a = prt::loadEnvironment(file("rgba.exr"));
    ASSERT_EQ(a.channels, 3);
    EXPECT_EQ(a.at(3, 2, 0), 7.0f);
    EXPECT_EQ(a.at(0, 0, 2), 0.5f);

    Image gray(8, 4, 1);
    for (size_t k = 0; k < gray.pixels.size(); ++k) gray.pixels[k] = float(k);
    prt::writeExr(file("gray.exr"), gray);
    const Image g = prt::loadEnvironment(file("gray.exr"));
    ASSERT_EQ(g.channels, 3);
    for (int c = 0; c < 3; ++c) EXPECT_EQ(g.at(5, 3, c), float(3 * 8 + 5));
}

TEST_F(EnvFileTest, WrongAspectRejected) {
    prt::writeExr(file("square.exr"), Image(16, 16, 3, 1.0f));
    const std::string msg = errorMessage([&] { prt::loadEnvironment(file("square.exr")); });
    EXPECT_NE(msg.find(file("square.exr")), std::string::npos) << msg;
    EXPECT_NE(msg.find("16 x 16"), std::string::npos) << msg;
    const std::string missing = errorMessage([&] { prt::loadEnvironment(file("none.exr")); });
    EXPECT_NE(missing.find(file("none.exr")), std::string::npos) << missing;
}

TEST_F(EnvFileTest, NonFiniteAndNegativeRejectedOrClamped) {
    struct Case {
        const char* name;
        float value;
        const char* word;
    };
    const Case cases[] = {{"nan", std::nanf(""), "NaN"},
                          {"inf", INFINITY, "+Inf"},
                          {"neginf", -INFINITY, "-Inf"},
                          {"negative", -0.25f, "negative"}};
    for (const Case& k : cases) {
        Image img(8, 4, 3, 1.0f);
        img.at(2, 1, 0) = 9.0f;  // the channel's largest finite value
        img.at(5, 3, 0) = k.value;
        const std::string path = file(std::string(k.name) + ".exr");
        prt::writeExr(path, img);
        const std::string msg = errorMessage([&] { prt::loadEnvironment(path); });
        EXPECT_NE(msg.find(path), std::string::npos) << msg;
        EXPECT_NE(msg.find("pixel (5, 3)"), std::string::npos) << msg;
        EXPECT_NE(msg.find(k.word), std::string::npos) << msg;

        const Image fixed = prt::loadEnvironment(path, prt::NonFinitePolicy::Clamp);
        const float expect = std::string(k.name) == "inf" ? 9.0f : 0.0f;
        EXPECT_EQ(fixed.at(5, 3, 0), expect) << k.name;
        EXPECT_EQ(fixed.at(5, 3, 1), 1.0f);
        for (float v : fixed.pixels) EXPECT_TRUE(std::isfinite(v) && v >= 0);
    }
    // ClampNegative repairs negatives but still refuses NaN and Inf.
    {
        Image img(8, 4, 3, 1.0f);
        img.at(1, 1, 1) = -0.003f;
        prt::writeExr(file("slightlyneg.exr"), img);
        const Image fixed = prt::loadEnvironment(file("slightlyneg.exr"), prt::NonFinitePolicy::ClampNegative);
        EXPECT_EQ(fixed.at(1, 1, 1), 0.0f);
        img.at(2, 2, 2) = INFINITY;
        prt::writeExr(file("neginf2.exr"), img);
        const std::string msg = errorMessage(
            [&] { prt::loadEnvironment(file("neginf2.exr"), prt::NonFinitePolicy::ClampNegative); });
        EXPECT_NE(msg.find("pixel (2, 2) is +Inf in channel B"), std::string::npos) << msg;
    }
    // -0 is fine.
    Image img(8, 4, 3, 1.0f);
    img.at(0, 0, 0) = -0.0f;
    EXPECT_EQ(prt::checkEnvironmentValues(img, "x", prt::NonFinitePolicy::Reject), 0u);
    img.at(1, 0, 2) = std::nanf("");
    img.at(2, 0, 2) = -1.0f;
    EXPECT_EQ(prt::checkEnvironmentValues(img, "x", prt::NonFinitePolicy::Clamp), 2u);
}

// ---------------------------------------------------------------------------------
// A real HDR map (data/envmaps/forest.exr: a sun and fine foliage, 1024 x 512), which
// tools/fetch-data.sh fetches and tools/test.sh (what CI runs) fetches first. Where it
// is missing the suite skips, and CTest reports the suite skipped, not passed
// (tests/CMakeLists.txt); with PRT_REQUIRE_DATA=1 in the environment (tools/test.sh
// sets it after fetching) a missing map fails instead.
// ---------------------------------------------------------------------------------

namespace {

const std::string kForestPath = std::string(PRT_SOURCE_DIR) + "/data/envmaps/forest.exr";

// Whether the map is there; when it is not and the data is required, a failure.
bool forestPresent() {
    if (fs::exists(kForestPath)) return true;
    const char* required = std::getenv("PRT_REQUIRE_DATA");
    if (required && std::string(required) == "1")
        ADD_FAILURE() << kForestPath << " not present, and PRT_REQUIRE_DATA=1 (tools/test.sh fetches it)";
    return false;
}

}  // namespace

TEST(ForestMap, IntegralPreserved) {
    if (!forestPresent()) GTEST_SKIP() << kForestPath << " not present (run tools/fetch-data.sh)";
    const std::string& path = kForestPath;
    // Blender's maps hold small negative values (resampling ringing), no NaN or Inf.
    const Image env = prt::loadEnvironment(path, prt::NonFinitePolicy::ClampNegative);
    expectIntegralPreserved(env, prt::latLongToCubemap(env, 32), 1e-5, "forest N=32");
    expectIntegralPreserved(env, prt::latLongToCubemap(env, 32, prt::rotationY(123)), 1e-5,
                            "forest rotated N=32");
}

TEST(ForestMap, WholePixelShiftsEqualExactRotation) {
    if (!forestPresent()) GTEST_SKIP() << kForestPath << " not present (run tools/fetch-data.sh)";
    const std::string& path = kForestPath;
    const Image env = prt::loadEnvironment(path, prt::NonFinitePolicy::ClampNegative);
    // 107 pixels = 37.6 degrees of a 1024-wide map.
    expectWholePixelShiftsExact(env, 32, {0, 107, 256, 1000}, 1e-6, "forest");
}

TEST(ForestMap, RowSumsMatchEntries) {
    if (!forestPresent()) GTEST_SKIP() << kForestPath << " not present (run tools/fetch-data.sh)";
    const std::string& path = kForestPath;
    const Image env = prt::loadEnvironment(path, prt::NonFinitePolicy::ClampNegative);
    const auto filter = prt::LatLongCubemapFilter::shared(env.width, env.height, 32);
    const prt::LatLongRowSums sums(env);
    double worst = 0.0;
    for (int i = 0; i < 12; ++i) {
        const double degrees = 0.37 + 31.01 * i;  // fresh, not whole-pixel angles
        worst = std::max(worst, worstRelativeDifference(filter->apply(sums, degrees), filter->apply(env, degrees),
                                                        kSameWeightsFloor));
    }
    EXPECT_LT(worst, kSameWeightsTolerance);
    // Runs are what make it fast: fewer than a third of the entries.
    EXPECT_LT(3 * filter->runCount(), filter->entryCount());
    std::printf("[ info ] forest N=32: %zu runs for %zu entries; worst relative texel difference %.2e\n",
                filter->runCount(), filter->entryCount(), worst);
}
