// Tests of relight/prt/eye_path.h: the eye's-path factor of single scattering.

#include <gtest/gtest.h>

#include <cmath>

#include "common/bssrdf.h"
#include "common/cubemap.h"
#include "common/error.h"
#include "common/util.h"
#include "relight/prt/eye_path.h"

using namespace prt;

namespace {

// Single scattering of a half space H mm thick from one direction of light whose
// outside cosine is cosI, seen along a straight path into the medium whose cosine to
// the inward normal is cosPath (1: Wang's inward normal; cos_o': the eye's refracted
// ray). A point at distance s along the path lies at depth z = s cosPath; the light
// reaches it along Eq. 5's refracted path z / cos_t. Eq. 4 then gives
//   int_0^{H / cosPath} sigma_s F_t(cosI) e^(-sigma_t s (cosPath / cos_t + 1)) ds,
// per unit phase and solid angle.
double halfSpace(double sigmaS, double sigmaT, double eta, double cosI, double cosPath, double H) {
    const double cosT = std::sqrt(1.0 - (1.0 - cosI * cosI) / (eta * eta));
    const double k = sigmaT * (cosPath / cosT + 1.0);
    return sigmaS * fresnelTransmittance(eta, cosI) * -std::expm1(-k * H / cosPath) / k;
}

double grazingRefractedCosine(double eta) { return std::sqrt(1.0 - 1.0 / (eta * eta)); }

}  // namespace

TEST(EyePath, NamesRoundTripAndNonsenseIsRefused) {
    for (SingleScatteringView v : {SingleScatteringView::Refracted, SingleScatteringView::Normal})
        EXPECT_EQ(parseSingleScatteringView(toString(v)), v);
    EXPECT_THROW(parseSingleScatteringView("eye"), Error);
    EXPECT_THROW(parseSingleScatteringView(""), Error);
    EXPECT_THROW(eyePathFactor(0.0, 1.0), Error);
    EXPECT_THROW(eyePathFactor(std::nan(""), 1.0), Error);
}

TEST(EyePath, OneAtANormalViewBrighterTowardGrazing) {
    for (double eta : {1.1, 1.3, 1.5, 2.0}) {
        EXPECT_NEAR(eyePathFactor(eta, 1.0), 1.0, 1e-12) << eta;
        double previous = 1.0;
        for (double c = 0.95; c >= grazingRefractedCosine(eta); c -= 0.05) {
            const double v = eyePathFactor(eta, c);
            EXPECT_GT(v, previous) << eta << " " << c;
            previous = v;
        }
    }
    // eta = 1.3 at grazing: between the ratios of a light at normal incidence (1.22) and
    // a grazing light (1.28), (1 + c) / (c + cos_o').
    const double c0 = grazingRefractedCosine(1.3);
    EXPECT_GT(eyePathFactor(1.3, c0), 2.0 / (1.0 + c0));
    EXPECT_LT(eyePathFactor(1.3, c0), (1.0 + c0) / (2.0 * c0));
}

TEST(EyePath, ExactUnderUniformLightOverAThickHalfSpace) {
    // The ratio of the two paths' radiance, integrated over the upper hemisphere of
    // directions by a 6 x 96 x 96 cubemap's texels (their exact solid angles), not by
    // the factor's own quadrature in mu; Marble's three channels, 50 mm thick.
    const int n = 96;
    const double sigmaS[3] = {2.19, 2.62, 3.00}, sigmaT[3] = {2.1921, 2.6262, 3.0071};
    for (double eta : {1.3, 1.5}) {
        for (double cosO : {1.0, 0.9, 0.8, 0.7, grazingRefractedCosine(eta) + 1e-9}) {
            for (int ch = 0; ch < 3; ++ch) {
                double eye = 0.0, normal = 0.0;
                for (int face = 0; face < 6; ++face)
                    for (int j = 0; j < n; ++j)
                        for (int i = 0; i < n; ++i) {
                            const glm::dvec3 w = texelDirection(n, face, i, j);
                            if (w.y <= 0.0) continue;
                            const double dOmega = texelSolidAngle(n, i, j);
                            eye += dOmega * halfSpace(sigmaS[ch], sigmaT[ch], eta, w.y, cosO, 50.0);
                            normal += dOmega * halfSpace(sigmaS[ch], sigmaT[ch], eta, w.y, 1.0, 50.0);
                        }
                EXPECT_NEAR(eyePathFactor(eta, cosO), eye / normal, 2e-4) << eta << " " << cosO << " " << ch;
            }
        }
    }
}

TEST(EyePath, OneLightIsWithinTheSpreadTheNormalPathIsNot) {
    // For a single direction of light the eye's path is (1 + c) / (c + cos_o') times the
    // normal path; the factor of the view alone meets it within 3% for eta = 1.3 at every
    // light and view, while the inward normal (factor 1) misses it by more than 18% at
    // grazing views.
    const double eta = 1.3, c0 = grazingRefractedCosine(eta);
    double worstFactor = 0.0, worstNormal = 0.0;
    for (double cosI = 0.01; cosI <= 1.0; cosI += 0.01) {
        for (double cosO = c0 + 1e-9; cosO <= 1.0; cosO += 0.01) {
            const double truth = halfSpace(2.62, 2.63, eta, cosI, cosO, 50.0);
            const double normal = halfSpace(2.62, 2.63, eta, cosI, 1.0, 50.0);
            worstFactor = std::max(worstFactor, std::abs(eyePathFactor(eta, cosO) * normal / truth - 1.0));
            worstNormal = std::max(worstNormal, std::abs(normal / truth - 1.0));
        }
    }
    EXPECT_LT(worstFactor, 0.03);
    EXPECT_GT(worstNormal, 0.18);
}

TEST(EyePath, TableFollowsTheQuadrature) {
    for (double eta : {1.1, 1.3, 1.44, 2.0}) {
        const EyePathTable table(eta, SingleScatteringView::Refracted);
        for (double c = grazingRefractedCosine(eta); c <= 1.0; c += 0.0037)
            EXPECT_NEAR(table(c) / eyePathFactor(eta, c), 1.0, 1e-4) << eta << " " << c;
        EXPECT_DOUBLE_EQ(table(1.0), table(7.0));  // clamped
    }
    const EyePathTable normal(1.3, SingleScatteringView::Normal);
    for (double c = 0.0; c <= 1.0; c += 0.1) EXPECT_EQ(normal(c), 1.0);
    EXPECT_EQ(EyePathTable()(0.3), 1.0);
}
