// Tests of common/bssrdf: the dipole diffusion profile
// (checked against its exact plane integral and hand-evaluated values), the exact
// dielectric Fresnel terms, refraction and the Henyey-Greenstein phase function.
// Each test asserts a physical property, so a wrong sign, a missing factor or a
// mis-transcribed coefficient makes it fail.

#include "common/bssrdf.h"
#include "common/error.h"
#include "tests/test_support.h"

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <numbers>
#include <string>
#include <vector>

namespace {

using prt::test::expectErrorSubject;

using prt::DipoleChannel;
using prt::Material;

constexpr double kPi = std::numbers::pi;

// Composite Simpson rule on [a, b] with n (even) intervals.
double simpson(const std::function<double(double)>& f, double a, double b, int n) {
    if (n % 2) ++n;
    const double h = (b - a) / n;
    double sum = f(a) + f(b);
    for (int i = 1; i < n; ++i) sum += f(a + i * h) * (i % 2 ? 4.0 : 2.0);
    return sum * h / 3.0;
}

// int_0^R R_d(r) 2 pi r dr with the substitution r = e^t (dr = r dt), which spreads
// the quadrature points evenly over every length scale from 1e-8 z_r to R. The part
// below 1e-8 z_r is ~ R_d(0) pi (1e-8 z_r)^2, far below any tolerance used here.
double integrateRdNumerically(const DipoleChannel& d, double radius) {
    const double t0 = std::log(1e-8 * d.zr);
    const double t1 = std::log(radius);
    auto f = [&](double t) {
        const double r = std::exp(t);
        return prt::dipoleRd(d, r) * 2.0 * kPi * r * r;
    };
    const int n = 2 * static_cast<int>(std::ceil((t1 - t0) / 0.002));
    return simpson(f, t0, t1, n);
}

// A radius beyond which the plane integral's tail is negligible (< 1e-8 relative):
// the exponential tail needs sigma_tr R >> 1; with sigma_tr = 0 (Spectralon) the tail
// decays only like (z_r + z_v) / (2 R), so go to 1e9 z_v.
double farRadius(const DipoleChannel& d) {
    const double algebraic = 1e9 * d.zv;
    if (d.sigmaTr <= 0.0) return algebraic;
    return std::min(algebraic, 80.0 / d.sigmaTr + 100.0 * d.zv);
}


// ---------------------------------------------------------------------------
// Fresnel
// ---------------------------------------------------------------------------

TEST(Fresnel, DiffuseReflectanceAt13MatchesHandValue) {
    // -1.440/1.69 + 0.710/1.3 + 0.668 + 0.0636 * 1.3
    //   = -0.852071006 + 0.546153846 + 0.668 + 0.08268 = 0.444762840
    // (writing -1.440/eta*eta would give 0.0126 + ..., far off).
    EXPECT_NEAR(prt::fresnelDiffuseReflectance(1.3), 0.44476284023668644, 1e-14);
    // A = (1 + F_dr)/(1 - F_dr) = 1.444762840 / 0.555237160
    EXPECT_NEAR(prt::dipoleBoundaryA(1.3), 2.6020643878600627, 1e-12);
}

// 2 int_0^1 F_r(1/eta, mu) mu dmu: the diffuse reflectance of the boundary seen from
// inside the medium, which F_dr approximates.
double internalDiffuseReflectance(double eta) {
    return 2.0 * simpson([&](double mu) { return prt::fresnelReflectance(1.0 / eta, mu) * mu; },
                         0.0, 1.0, 200000);
}

TEST(Fresnel, DiffuseFitMatchesExactHemisphericalAverage) {
    for (double eta : {0.5, 0.6, 0.8, 0.9, 0.95, 1.05, 1.1, 1.3, 1.4, 1.5, 2.0, 2.5}) {
        const double fit = prt::fresnelDiffuseReflectance(eta);
        EXPECT_NEAR(fit, internalDiffuseReflectance(eta), 6e-3) << "eta " << eta;
        EXPECT_GE(fit, 0.0) << "eta " << eta;
        EXPECT_LT(fit, 1.0) << "eta " << eta;
    }
}

TEST(Fresnel, TransmittanceStaysInUnitInterval) {
    for (double eta : {0.5, 0.7, 1.0, 1.3, 1.5, 2.5}) {
        for (int i = 0; i <= 1000; ++i) {
            const double c = i / 1000.0;
            const double ft = prt::fresnelTransmittance(eta, c);
            ASSERT_GE(ft, 0.0) << eta << " " << c;
            ASSERT_LE(ft, 1.0) << eta << " " << c;
            // |cos| is what counts: a negative cosine is the same angle.
            ASSERT_EQ(ft, prt::fresnelTransmittance(eta, -c));
        }
    }
}

TEST(Fresnel, NormalIncidenceMatchesClosedForm) {
    for (double eta : {0.5, 0.8, 1.3, 1.5, 2.5}) {
        const double r0 = (eta - 1.0) / (eta + 1.0);
        EXPECT_NEAR(1.0 - prt::fresnelTransmittance(eta, 1.0), r0 * r0, 1e-15) << eta;
    }
    EXPECT_NEAR(prt::fresnelReflectance(1.5, 1.0), 0.04, 1e-15);
}

TEST(Fresnel, BrewsterAngleLeavesOnlyTheSPolarisation) {
    // At tan(theta_B) = eta, r_p = 0 and |r_s| = |cos 2 theta_B| = (eta^2-1)/(eta^2+1).
    for (double eta : {1.3, 1.5, 2.0}) {
        const double cosB = 1.0 / std::sqrt(1.0 + eta * eta);
        const double rs = (eta * eta - 1.0) / (eta * eta + 1.0);
        EXPECT_NEAR(prt::fresnelReflectance(eta, cosB), 0.5 * rs * rs, 1e-14) << eta;
    }
}

TEST(Fresnel, GrazingIncidenceReflectsEverything) {
    for (double eta : {0.7, 1.3, 1.5, 2.5}) {
        EXPECT_EQ(prt::fresnelReflectance(eta, 0.0), 1.0) << eta;
        EXPECT_EQ(prt::fresnelTransmittance(eta, 0.0), 0.0) << eta;
    }
    // Index matched: no interface, nothing reflected.
    EXPECT_EQ(prt::fresnelReflectance(1.0, 0.3), 0.0);
}

TEST(Fresnel, ReflectanceGrowsTowardGrazingForDenserMedia) {
    for (double eta : {1.3, 1.5, 2.5}) {
        double prev = prt::fresnelReflectance(eta, 1.0);
        for (int i = 999; i >= 0; --i) {
            const double f = prt::fresnelReflectance(eta, i / 1000.0);
            ASSERT_GE(f, prev - 1e-15) << eta << " " << i;
            prev = f;
        }
    }
}

TEST(Fresnel, TotalInternalReflectionBeyondCriticalAngle) {
    const double eta = 1.0 / 1.3;  // light inside a 1.3 medium heading out
    const double cosCritical = std::sqrt(1.0 - eta * eta);
    EXPECT_EQ(prt::fresnelReflectance(eta, cosCritical * 0.999), 1.0);
    EXPECT_EQ(prt::fresnelReflectance(eta, 0.1), 1.0);
    EXPECT_LT(prt::fresnelReflectance(eta, cosCritical * 1.01), 1.0);
    EXPECT_LT(prt::fresnelReflectance(eta, 1.0), 0.02);
}

TEST(Fresnel, ReciprocalFormIsSymmetric) {
    // F_r(eta, cos_i) == F_r(1/eta, cos_t), cos_t taken from the refracted direction.
    const glm::dvec3 n(0.0, 1.0, 0.0);
    for (double eta : {1.3, 1.5, 0.8}) {
        for (int i = 1; i <= 20; ++i) {
            const double ci = i / 20.0;
            const glm::dvec3 w(std::sqrt(1.0 - ci * ci), ci, 0.0);
            glm::dvec3 wt;
            if (!prt::refractDirection(w, n, eta, wt)) continue;  // TIR for eta < 1
            const double ct = -glm::dot(wt, n);
            EXPECT_NEAR(prt::fresnelReflectance(eta, ci), prt::fresnelReflectance(1.0 / eta, ct),
                        1e-13)
                << eta << " " << ci;
        }
    }
}

TEST(Fresnel, RejectsNonPositiveEta) {
    expectErrorSubject([] { prt::fresnelReflectance(0.0, 0.5); }, "eta");
    expectErrorSubject([] { prt::fresnelReflectance(-1.3, 0.5); }, "eta");
    expectErrorSubject([] { prt::fresnelDiffuseReflectance(std::nan("")); }, "eta");
}

// ---------------------------------------------------------------------------
// Dipole
// ---------------------------------------------------------------------------

TEST(Dipole, RdAtOriginMatchesHandValues) {
    // Marble red: sigma_t' = 2.1921, alpha' = 2.19/2.1921 = 0.99904201,
    // sigma_tr = sqrt(3 * 0.0021 * 2.1921) = 0.11751693, z_r = 0.45618357,
    // z_v = z_r (1 + 4 * 2.60206439 / 3) = 2.03887559. At r = 0, d = z:
    // R_d(0) = alpha'/(4 pi) [(1 + s z_r) e^(-s z_r)/z_r^2 + (1 + s z_v) e^(-s z_v)/z_v^2]
    //        = 0.40015368 mm^-2.
    // (A negative z_v would give 0.36284183; the closed form must not be off by that.)
    const Material marble = prt::materialByName("Marble");
    EXPECT_NEAR(prt::dipoleRd(prt::makeDipoleChannel(marble, 0), 0.0), 0.40015368118253525,
                1e-12);
    // Ketchup red has alpha' = 0.18 / 0.241 = 0.74688797, so leaving alpha' out would
    // give 0.00364170 instead of 0.00271994.
    const Material ketchup = prt::materialByName("Ketchup");
    EXPECT_NEAR(prt::dipoleRd(prt::makeDipoleChannel(ketchup, 0), 0.0), 0.0027199415634328113,
                1e-15);
}

TEST(Dipole, PlaneIntegralEqualsClosedFormForEveryMaterialAndChannel) {
    for (const std::string& name : prt::materialNames()) {
        const Material m = prt::materialByName(name);
        for (int c = 0; c < 3; ++c) {
            const DipoleChannel d = prt::makeDipoleChannel(m, c);
            const double closed = prt::dipoleTotalDiffuseReflectance(d);
            const double numeric = integrateRdNumerically(d, farRadius(d));
            EXPECT_NEAR(numeric / closed, 1.0, 1e-6) << name << " channel " << c;
        }
    }
}

TEST(Dipole, TotalReflectanceMatchesJensenAlbedoForm) {
    // Jensen et al. 2001: R_d = alpha'/2 (1 + e^(-4/3 A sqrt(3(1-alpha')))) e^(-sqrt(3(1-alpha'))),
    // written with alpha' only (sigma_tr z_r = sqrt(3 (1 - alpha'))).
    const double a = prt::dipoleBoundaryA(1.3);
    for (const std::string& name : prt::materialNames()) {
        const Material m = prt::materialByName(name);
        for (int c = 0; c < 3; ++c) {
            const double ap = m.alphaPrime()[c];
            const double s = std::sqrt(3.0 * (1.0 - ap));
            const double expected = 0.5 * ap * (1.0 + std::exp(-4.0 / 3.0 * a * s)) * std::exp(-s);
            EXPECT_NEAR(m.totalDiffuseReflectance()[c], expected, 1e-12) << name << " " << c;
        }
    }
}

TEST(Dipole, NonAbsorbingMediumReflectsAllTransmittedLight) {
    const Material spectralon = prt::materialByName("Spectralon");
    for (int c = 0; c < 3; ++c) {
        EXPECT_NEAR(spectralon.totalDiffuseReflectance()[c], 1.0, 1e-15);
    }
    // Absorbing media reflect strictly less than the transmitted energy.
    for (const std::string& name : prt::materialNames()) {
        if (name == "Spectralon") continue;
        const glm::dvec3 rd = prt::materialByName(name).totalDiffuseReflectance();
        for (int c = 0; c < 3; ++c) {
            EXPECT_GT(rd[c], 0.0) << name;
            EXPECT_LT(rd[c], 1.0) << name;
        }
    }
}

TEST(Dipole, PartialIntegralMatchesClosedFormAndFractionRadius) {
    for (const char* name : {"Marble", "Skin1", "Ketchup", "Spectralon"}) {
        const Material m = prt::materialByName(name);
        for (int c = 0; c < 3; ++c) {
            const DipoleChannel d = prt::makeDipoleChannel(m, c);
            for (double radius : {0.1, 1.0, 5.0, 20.0}) {
                const double closed = prt::dipoleDiffuseReflectanceWithin(d, radius);
                EXPECT_NEAR(integrateRdNumerically(d, radius) / closed, 1.0, 1e-8)
                    << name << " " << c << " R=" << radius;
            }
            const double total = prt::dipoleTotalDiffuseReflectance(d);
            EXPECT_NEAR(prt::dipoleDiffuseReflectanceWithin(d, 1e12), total, 1e-9 * total);
            const double r99 = prt::dipoleRadiusForFraction(d, 0.99);
            EXPECT_NEAR(prt::dipoleDiffuseReflectanceWithin(d, r99), 0.99 * total, 1e-9 * total);
            EXPECT_LT(prt::dipoleRadiusForFraction(d, 0.5), r99);
        }
    }
    const DipoleChannel d = prt::makeDipoleChannel(prt::materialByName("Marble"), 0);
    expectErrorSubject([&] { prt::dipoleRadiusForFraction(d, 1.0); }, "fraction");
    expectErrorSubject([&] { prt::dipoleRadiusForFraction(d, 0.0); }, "fraction");
}

TEST(Dipole, ScalesWithUnitsAsAnAreaDensity) {
    // Scaling every coefficient by k (lengths by 1/k) must scale R_d by k^2: R_d is
    // per unit area. A model in metres read as millimetres breaks exactly this.
    const Material m = prt::materialByName("Skin1");
    const double k = 1000.0;
    const Material mk = prt::customMaterial(m.sigmaSPrime * k, m.sigmaA * k, m.eta, m.g);
    for (double r : {0.0, 0.3, 1.0, 4.0}) {
        const glm::dvec3 a = prt::dipoleRd(m, r);
        const glm::dvec3 b = prt::dipoleRd(mk, r / k);
        for (int c = 0; c < 3; ++c) EXPECT_NEAR(b[c] / (a[c] * k * k), 1.0, 1e-12) << r;
    }
}

TEST(Dipole, ProfileDecreasesWithDistanceAndMatchesChannels) {
    const Material m = prt::materialByName("Apple");
    glm::dvec3 prev = prt::dipoleRd(m, 0.0);
    for (int i = 1; i <= 400; ++i) {
        const double r = 0.05 * i;
        const glm::dvec3 v = prt::dipoleRd(m, r);
        for (int c = 0; c < 3; ++c) {
            ASSERT_LT(v[c], prev[c]) << r;
            ASSERT_GT(v[c], 0.0) << r;
            ASSERT_EQ(v[c], prt::dipoleRd(prt::makeDipoleChannel(m, c), r));
        }
        prev = v;
    }
    // Apple absorbs blue much more strongly (sigma_a 0.046 vs 0.003): blue falls off faster.
    EXPECT_LT(prt::dipoleRd(m, 10.0).z / prt::dipoleRd(m, 0.0).z,
              prt::dipoleRd(m, 10.0).x / prt::dipoleRd(m, 0.0).x);
}

// ---------------------------------------------------------------------------
// Refraction
// ---------------------------------------------------------------------------

TEST(Refraction, SnellsLawUnitLengthAndIntoTheMedium) {
    const glm::dvec3 normals[] = {{0, 1, 0}, glm::normalize(glm::dvec3(0.3, -0.5, 0.8))};
    for (const glm::dvec3& n : normals) {
        // An orthonormal tangent frame around n.
        const glm::dvec3 t = glm::normalize(glm::cross(n, std::fabs(n.x) < 0.9
                                                              ? glm::dvec3(1, 0, 0)
                                                              : glm::dvec3(0, 1, 0)));
        const glm::dvec3 b = glm::cross(n, t);
        for (double eta : {1.3, 1.5, 2.5, 0.8}) {
            for (int i = 0; i <= 16; ++i) {
                for (int j = 0; j < 8; ++j) {
                    const double theta = 0.5 * std::numbers::pi * i / 16.0 * 0.999;
                    const double phi = 2.0 * std::numbers::pi * j / 8.0;
                    const glm::dvec3 w = std::cos(theta) * n + std::sin(theta) *
                                                                   (std::cos(phi) * t +
                                                                    std::sin(phi) * b);
                    glm::dvec3 wt(0.0);
                    const bool ok = prt::refractDirection(2.0 * w, n, eta, wt);
                    const double sinI = std::sin(theta);
                    if (sinI > eta) {
                        EXPECT_FALSE(ok) << "TIR expected";
                        continue;
                    }
                    ASSERT_TRUE(ok);
                    EXPECT_NEAR(glm::length(wt), 1.0, 1e-14);
                    EXPECT_LT(glm::dot(wt, n), 0.0);
                    const double sinT = glm::length(glm::cross(wt, n));
                    EXPECT_NEAR(eta * sinT, sinI, 1e-12);
                    // Refracted ray stays in the plane of incidence, on the far side of n.
                    EXPECT_NEAR(glm::dot(wt, glm::cross(w, n)), 0.0, 1e-12);
                    if (sinI > 1e-9) {
                        EXPECT_LT(glm::dot(wt - glm::dot(wt, n) * n, w - glm::dot(w, n) * n),
                                  0.0);
                    }
                }
            }
        }
    }
}

TEST(Refraction, NormalIncidenceGoesStraightIn) {
    glm::dvec3 wt;
    ASSERT_TRUE(prt::refractDirection({0, 3, 0}, {0, 2, 0}, 1.3, wt));
    EXPECT_NEAR(wt.x, 0.0, 1e-15);
    EXPECT_NEAR(wt.y, -1.0, 1e-15);
    EXPECT_NEAR(wt.z, 0.0, 1e-15);
}

TEST(Refraction, RejectsDirectionsBelowTheSurfaceAndTotalInternalReflection) {
    glm::dvec3 wt(7.0);
    EXPECT_FALSE(prt::refractDirection({0, -1, 0}, {0, 1, 0}, 1.3, wt));
    EXPECT_FALSE(prt::refractDirection({0, 0, 0}, {0, 1, 0}, 1.3, wt));
    // eta = 1/1.3: sin_i = 0.9 > 1/1.3 = 0.769 is beyond the critical angle.
    EXPECT_FALSE(prt::refractDirection({0.9, std::sqrt(1 - 0.81), 0}, {0, 1, 0}, 1 / 1.3, wt));
    EXPECT_EQ(wt, glm::dvec3(7.0));
    // Grazing incidence into a denser medium refracts to the critical angle; the light
    // arrives travelling along -w = -x and keeps going toward -x.
    ASSERT_TRUE(prt::refractDirection({1, 0, 0}, {0, 1, 0}, 1.3, wt));
    EXPECT_NEAR(wt.x, -1.0 / 1.3, 1e-14);
    EXPECT_LT(wt.y, 0.0);
}

// ---------------------------------------------------------------------------
// Henyey-Greenstein
// ---------------------------------------------------------------------------

const double kGs[] = {-0.9, -0.4, 0.0, 0.25, 0.4, 0.9};

// 2 pi int_a^b f(mu) p(mu) dmu (azimuth integrated analytically).
double hgMoment(double g, double a, double b, const std::function<double(double)>& f) {
    return 2.0 * kPi *
           simpson([&](double mu) { return f(mu) * prt::henyeyGreenstein(g, mu); }, a, b, 400000);
}

TEST(HenyeyGreenstein, IntegratesToOneOverTheSphere) {
    for (double g : kGs) {
        EXPECT_NEAR(hgMoment(g, -1.0, 1.0, [](double) { return 1.0; }), 1.0, 1e-8) << g;
    }
    // g = 0 is the isotropic 1/(4 pi).
    EXPECT_NEAR(prt::henyeyGreenstein(0.0, 0.3), 1.0 / (4.0 * kPi), 1e-16);
}

TEST(HenyeyGreenstein, MeanCosineIsGAndPositiveGScattersForward) {
    for (double g : kGs) {
        EXPECT_NEAR(hgMoment(g, -1.0, 1.0, [](double mu) { return mu; }), g, 1e-8) << g;
        const double forward = hgMoment(g, 0.0, 1.0, [](double) { return 1.0; });
        const double backward = hgMoment(g, -1.0, 0.0, [](double) { return 1.0; });
        if (g > 0) {
            EXPECT_GT(forward, backward) << g;
        } else if (g < 0) {
            EXPECT_LT(forward, backward) << g;
        } else {
            EXPECT_NEAR(forward, backward, 1e-12);
        }
    }
    EXPECT_GT(prt::henyeyGreenstein(0.5, 1.0), prt::henyeyGreenstein(0.5, -1.0));
}

TEST(HenyeyGreenstein, DirectionHelperUsesPropagationDirections) {
    const double g = 0.6;
    const glm::dvec3 d = glm::normalize(glm::dvec3(1, 2, 3));
    // Undeflected light (same propagation direction) is the forward peak.
    EXPECT_DOUBLE_EQ(prt::henyeyGreensteinDirections(g, d, 5.0 * d), prt::henyeyGreenstein(g, 1.0));
    EXPECT_DOUBLE_EQ(prt::henyeyGreensteinDirections(g, d, -d), prt::henyeyGreenstein(g, -1.0));
    // Single scattering seen head-on: light from straight above (w_i = n) enters along
    // w_i' = -n; the viewer straight above (w_o = n) sees light travelling along
    // -w_o' = +n. The light turns around: back-scattering, the minimum for g > 0.
    const glm::dvec3 n(0, 0, 1);
    glm::dvec3 wiPrime, woPrime;
    ASSERT_TRUE(prt::refractDirection(n, n, 1.3, wiPrime));
    ASSERT_TRUE(prt::refractDirection(n, n, 1.3, woPrime));
    EXPECT_DOUBLE_EQ(prt::henyeyGreensteinDirections(g, wiPrime, -woPrime),
                     prt::henyeyGreenstein(g, -1.0));
    EXPECT_LT(prt::henyeyGreensteinDirections(g, wiPrime, -woPrime), 1.0 / (4.0 * kPi));
    expectErrorSubject([] { prt::henyeyGreenstein(1.0, 0.5); }, "g");
}

}  // namespace
