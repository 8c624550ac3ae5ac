#include "common/cubemap.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "common/error.h"
#include "common/util.h"

using namespace prt;

TEST(Cubemap, FaceCentresAreTheAxes) {
    const glm::dvec3 axes[6] = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
    for (int f = 0; f < 6; ++f) {
        glm::dvec3 d = faceUVToDirection(f, 0.5, 0.5);
        EXPECT_NEAR(glm::length(d - axes[f]), 0.0, 1e-12) << "face " << f;
    }
}

TEST(Cubemap, OpenGLOrientation) {
    // From the OpenGL cube-map selection table: on +X, s grows toward -Z and t toward -Y;
    // on +Y, t grows toward +Z; on -Z, s grows toward -X.
    EXPECT_LT(faceUVToDirection(0, 1.0, 0.5).z, 0.0);
    EXPECT_LT(faceUVToDirection(0, 0.5, 1.0).y, 0.0);
    EXPECT_GT(faceUVToDirection(2, 0.5, 1.0).z, 0.0);
    EXPECT_LT(faceUVToDirection(3, 0.5, 1.0).z, 0.0);
    EXPECT_GT(faceUVToDirection(4, 1.0, 0.5).x, 0.0);
    EXPECT_LT(faceUVToDirection(5, 1.0, 0.5).x, 0.0);
}

TEST(Cubemap, TexelDirectionRoundTrip) {
    for (int n : {1, 2, 8, 32, 64}) {
        for (int f = 0; f < 6; ++f)
            for (int j = 0; j < n; ++j)
                for (int i = 0; i < n; ++i) {
                    TexelCoord t = directionToTexel(n, texelDirection(n, f, i, j));
                    ASSERT_EQ(t.face, f);
                    ASSERT_EQ(t.i, i);
                    ASSERT_EQ(t.j, j);
                }
    }
}

TEST(Cubemap, DirectionRoundTripThroughFaceUV) {
    std::mt19937 rng(7);
    std::normal_distribution<double> g;
    for (int k = 0; k < 10000; ++k) {
        glm::dvec3 d = glm::normalize(glm::dvec3(g(rng), g(rng), g(rng)));
        int face;
        double s, t;
        directionToFaceUV(d, face, s, t);
        ASSERT_GE(s, 0.0);
        ASSERT_LE(s, 1.0);
        ASSERT_GE(t, 0.0);
        ASSERT_LE(t, 1.0);
        ASSERT_NEAR(glm::length(faceUVToDirection(face, s, t) - d), 0.0, 1e-12);
    }
}

TEST(Cubemap, SolidAnglesSumToFourPi) {
    for (int n : {1, 2, 4, 32, 64, 128}) {
        double sum = 0;
        for (double w : faceSolidAngles(n)) sum += 6 * w;
        EXPECT_NEAR(sum, 4 * kPi, 1e-6) << "n = " << n;
    }
}

TEST(Cubemap, SolidAngleMatchesNumericalIntegral) {
    // Midpoint rule on the projected-area density, fine enough to be trusted to 1e-7.
    const int n = 8;
    for (auto [i, j] : {std::pair{0, 0}, {3, 4}, {7, 2}}) {
        const int m = 400;
        double sum = 0;
        for (int b = 0; b < m; ++b)
            for (int a = 0; a < m; ++a) {
                double x = 2 * (i + (a + 0.5) / m) / n - 1, y = 2 * (j + (b + 0.5) / m) / n - 1;
                sum += std::pow(1 + x * x + y * y, -1.5) * (2.0 / n / m) * (2.0 / n / m);
            }
        EXPECT_NEAR(texelSolidAngle(n, i, j), sum, 1e-7);
    }
    // Corner texels are smaller than centre texels.
    EXPECT_LT(texelSolidAngle(8, 0, 0), texelSolidAngle(8, 3, 3));
}

TEST(Cubemap, RejectsBadSizes) {
    EXPECT_THROW(Cubemap(0, 1), Error);
    EXPECT_THROW(Cubemap(24, 1), Error);
    EXPECT_THROW(Cubemap(32, 0), Error);
    EXPECT_NO_THROW(Cubemap(32, 3));
}

TEST(Cubemap, ConstantIntegratesToFourPiTimesValue) {
    Cubemap c(16, 3);
    for (size_t k = 0; k < c.texelCount(); ++k) {
        c.data()[3 * k] = 1.0f;
        c.data()[3 * k + 1] = 2.0f;
        c.data()[3 * k + 2] = 0.5f;
    }
    std::vector<double> s = c.integrate();
    EXPECT_NEAR(s[0], 4 * kPi, 1e-5);
    EXPECT_NEAR(s[1], 8 * kPi, 1e-5);
    EXPECT_NEAR(s[2], 2 * kPi, 1e-5);
}

TEST(Cubemap, BilinearReproducesLinearFunctionInsideAFace) {
    // A function linear in texel coordinates is reproduced exactly between centres.
    const int n = 8;
    Cubemap c(n, 1);
    for (int f = 0; f < 6; ++f)
        for (int j = 0; j < n; ++j)
            for (int i = 0; i < n; ++i) c.texel(f, i, j)[0] = float(f * 100 + 3 * i + 5 * j);
    // At a texel centre: the texel value.
    EXPECT_FLOAT_EQ(c.sampleBilinear(texelDirection(n, 4, 2, 5), 0), 400 + 6 + 25);
    // Halfway between centres (2,5) and (3,5) in face coordinates.
    glm::dvec3 d = faceUVToDirection(4, 3.0 / n, 5.5 / n);
    EXPECT_NEAR(c.sampleBilinear(d, 0), 400 + 7.5 + 25, 1e-4);
    // Clamped at the border.
    EXPECT_FLOAT_EQ(c.sampleBilinear(faceUVToDirection(1, 0.0, 0.0), 0), 100);
}

TEST(Cubemap, BilinearTapsAreTheTexelsAroundADirection) {
    const int n = 8;
    for (int face = 0; face < 6; ++face)
        for (int j = 0; j < n; ++j)
            for (int i = 0; i < n; ++i) {
                // At a texel centre all weight is on that texel.
                const glm::dvec3 d = prt::texelDirection(n, face, i, j);
                const prt::BilinearTaps taps = prt::bilinearTaps(n, d);
                double sum = 0.0, onCentre = 0.0;
                for (int k = 0; k < 4; ++k) {
                    EXPECT_GE(taps.weight[k], 0.0);
                    sum += taps.weight[k];
                    if (taps.texel[k] == (size_t(face) * n + j) * n + i) onCentre += taps.weight[k];
                }
                EXPECT_NEAR(sum, 1.0, 1e-12);
                EXPECT_NEAR(onCentre, 1.0, 1e-9);
            }
}
