// Tests of common/radial_basis: the fixed radial profiles that stand in for the dipole
// R_d so that the material and the object's size can be edited after the precompute.
// Each test checks a physical or numerical property that a wrong fit, a wrong
// constraint, a wrong size identity or a lossy serialisation would break.

#include "common/radial_basis.h"

#include "common/bssrdf.h"
#include "common/error.h"
#include "common/material_edit.h"
#include "common/materials.h"
#include "tests/test_support.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <numbers>
#include <string>
#include <vector>

namespace {

using prt::DipoleChannel;
using prt::Material;
using prt::RadialBasis;
using prt::RadialBasisOptions;
using prt::RadialRange;
using prt::test::errorOf;
using prt::test::expectErrorSubject;

constexpr double kPi = std::numbers::pi;
constexpr double kRMax = 30.0;
const double kSizes[] = {0.5, 1.0, 2.0};

std::vector<Material> measuredAbsorbing() {
    std::vector<Material> out;
    for (const std::string& name : prt::materialNames()) {
        if (name != "Spectralon") out.push_back(prt::materialByName(name));
    }
    return out;
}

DipoleChannel scaledChannel(const Material& m, int c, double s) {
    return prt::makeDipoleChannel(s * m.sigmaSPrime[c], s * m.sigmaA[c], m.eta);
}

RadialRange fullRange() { return prt::rangeCovering(measuredAbsorbing(), 0.5, 2.0, kRMax); }
RadialRange marbleRange() {
    return prt::rangeCovering({prt::materialByName("Marble")}, 0.5, 2.0, kRMax);
}

// Built once: each takes ~30 ms.
const RadialBasis& basis(int which) {
    static const RadialBasis full12 = prt::makeRadialBasis(fullRange(), {});
    static const RadialBasis full16 = [] {
        RadialBasisOptions o;
        o.size = 16;
        return prt::makeRadialBasis(fullRange(), o);
    }();
    static const RadialBasis marble12 = prt::makeRadialBasis(marbleRange(), {});
    return which == 0 ? full12 : which == 1 ? full16 : marble12;
}

std::string caseName(const Material& m, int c, double s) {
    return m.name + " " + "RGB"[c] + " s=" + std::to_string(s);
}

void expectWithin(const RadialBasis& b, const std::vector<Material>& materials,
                  const prt::RadialFitTolerance& tol) {
    for (const Material& m : materials) {
        for (double s : kSizes) {
            for (int c = 0; c < 3; ++c) {
                const DipoleChannel d = scaledChannel(m, c, s);
                ASSERT_TRUE(b.covers(d)) << caseName(m, c, s);
                const prt::RadialFitError e = b.fitError(d);
                EXPECT_LT(e.integral, 1e-12) << caseName(m, c, s);
                EXPECT_LT(e.l1, tol.l1) << caseName(m, c, s);
                EXPECT_LT(e.disk, tol.disk) << caseName(m, c, s);
                EXPECT_LT(e.moment1, tol.moment) << caseName(m, c, s);
                EXPECT_LT(e.moment2, tol.moment) << caseName(m, c, s);
            }
        }
    }
}

// int_0^rMax f(r) 2 pi r dr (or of |f|) by the midpoint rule in ln r from 1e-6 mm (the
// part below is ~ R_d(0) pi 1e-12, nothing).
template <class F>
double areaIntegral(F f, double rMax, bool absolute = false) {
    const int n = 8000;
    const double t0 = std::log(1e-6), t1 = std::log(rMax);
    double sum = 0.0;
    for (int i = 0; i < n; ++i) {
        const double r = std::exp(t0 + (i + 0.5) * (t1 - t0) / n);
        sum += (absolute ? std::fabs(f(r)) : f(r)) * 2.0 * kPi * r * r;
    }
    return sum * (t1 - t0) / n;
}

// ---------------------------------------------------------------------------
// Accuracy
// ---------------------------------------------------------------------------

TEST(RadialBasisFit, MeasuredMaterialsWithinToleranceAtJ12) {
    expectWithin(basis(0), measuredAbsorbing(), prt::kRadialToleranceMeasuredJ12);
}

TEST(RadialBasisFit, MeasuredMaterialsWithinToleranceAtJ16) {
    expectWithin(basis(1), measuredAbsorbing(), prt::kRadialToleranceMeasuredJ16);
}

TEST(RadialBasisFit, MarbleRangeWithinTolerance) {
    expectWithin(basis(2), {prt::materialByName("Marble")}, prt::kRadialToleranceMarbleJ12);
}

// The constraint: int fit 2 pi r dr over [0, rMax] equals dipoleDiffuseReflectanceWithin,
// both through the exact profile integrals and through the tabulated profiles.
TEST(RadialBasisFit, KeepsTheIntegralWithinRMax) {
    const RadialBasis& b = basis(0);
    for (const Material& m : measuredAbsorbing()) {
        for (double s : kSizes) {
            for (int c = 0; c < 3; ++c) {
                const DipoleChannel d = scaledChannel(m, c, s);
                const std::vector<double> w = b.weights(d);
                double integral = 0.0;
                for (int j = 0; j < b.size(); ++j) integral += w[j] * b.profileIntegrals()[j];
                const double expected = prt::dipoleDiffuseReflectanceWithin(d, kRMax);
                EXPECT_NEAR(integral / expected, 1.0, 1e-6) << caseName(m, c, s);
                // Independent quadrature of the interpolated fit.
                const double quad = areaIntegral([&](double r) { return b.fit(w, r); }, kRMax);
                EXPECT_NEAR(quad / expected, 1.0, 1e-5) << caseName(m, c, s);
            }
        }
    }
}

// R_d(r; s sigma) = s^2 R_d(s r; sigma): the weights of the scaled material reproduce
// the original profile seen at 1/s of the distance.
TEST(RadialBasisFit, SizeIdentity) {
    const RadialBasis& b = basis(0);
    for (const char* name : {"Marble", "Skin1", "Chicken1", "Cream"}) {
        const Material m = prt::materialByName(name);
        for (double s : kSizes) {
            const auto w = b.materialWeights(m, s);
            for (int c = 0; c < 3; ++c) {
                const DipoleChannel original = prt::makeDipoleChannel(m, c);
                auto target = [&](double r) { return s * s * prt::dipoleRd(original, s * r); };
                const double err = areaIntegral(
                    [&](double r) { return b.fit(w[c], r) - target(r); }, kRMax, true);
                const double total = areaIntegral(target, kRMax);
                EXPECT_LT(err / total, prt::kRadialToleranceMeasuredJ12.l1) << caseName(m, c, s);
            }
        }
    }
}

// More profiles fit better (PCA is nested), and a one-point range is a single
// normalised dipole, reproduced to interpolation accuracy by one profile.
TEST(RadialBasisFit, Sanity) {
    RadialBasisOptions o;
    double previous = INFINITY;
    for (int J : {6, 9, 12, 16}) {
        o.size = J;
        const RadialBasis b = J == 12 ? basis(0) : J == 16 ? basis(1)
                                                           : prt::makeRadialBasis(fullRange(), o);
        double worst = 0.0;
        for (const Material& m : measuredAbsorbing()) {
            for (int c = 0; c < 3; ++c) worst = std::max(worst, b.fitError(scaledChannel(m, c, 1.0)).l1);
        }
        EXPECT_LT(worst, previous) << "J = " << J;
        previous = worst;
    }
    const DipoleChannel skin = prt::makeDipoleChannel(prt::materialByName("Skin1"), 1);
    const RadialRange point{skin.zr, skin.zr, skin.alphaPrime, skin.alphaPrime, 1.3, kRMax};
    o.size = 1;
    const RadialBasis one = prt::makeRadialBasis(point, o);
    ASSERT_TRUE(one.covers(skin));
    const prt::RadialFitError e = one.fitError(skin);
    EXPECT_LT(e.l1, 2e-4);  // the table's linear interpolation (header: < 2e-4)
    EXPECT_LT(e.disk, 1e-4);
    // Its single weight is the reflectance within rMax over the profile's integral.
    EXPECT_NEAR(one.weights(skin)[0] * one.profileIntegrals()[0],
                prt::dipoleDiffuseReflectanceWithin(skin, kRMax), 1e-12);
}

// The other constructions exist and are measurably worse than the default at J = 12.
TEST(RadialBasisFit, DefaultIsTheMostAccurateConstruction) {
    const RadialBasis& pca = basis(0);
    for (prt::RadialConstruction c : {prt::RadialConstruction::Greedy, prt::RadialConstruction::ExpLadder}) {
        RadialBasisOptions o;
        o.construction = c;
        const RadialBasis other = prt::makeRadialBasis(fullRange(), o);
        double worstPca = 0.0, worstOther = 0.0;
        for (const Material& m : measuredAbsorbing()) {
            for (int ch = 0; ch < 3; ++ch) {
                const DipoleChannel d = scaledChannel(m, ch, 1.0);
                worstPca = std::max(worstPca, pca.fitError(d).l1);
                worstOther = std::max(worstOther, other.fitError(d).l1);
            }
        }
        EXPECT_LT(worstPca, worstOther) << prt::radialConstructionName(c);
    }
}

// ---------------------------------------------------------------------------
// Tables and evaluation
// ---------------------------------------------------------------------------

TEST(RadialBasisTables, RoundTripGivesTheSameWeightsBitForBit) {
    const RadialBasis& b = basis(0);
    const RadialBasis copy(b.range(), b.tables());
    ASSERT_EQ(copy.size(), b.size());
    for (const Material& m : measuredAbsorbing()) {
        for (int c = 0; c < 3; ++c) {
            const DipoleChannel d = scaledChannel(m, c, 1.0);
            const std::vector<double> a = b.weights(d), w = copy.weights(d);
            ASSERT_EQ(a.size(), w.size());
            EXPECT_EQ(0, std::memcmp(a.data(), w.data(), a.size() * sizeof(double))) << m.name;
        }
    }
    std::vector<float> x(b.size()), y(b.size());
    for (double r : {0.0, 0.01, 0.3, 2.0, 29.9}) {
        b.evaluate(r, x.data());
        copy.evaluate(r, y.data());
        EXPECT_EQ(0, std::memcmp(x.data(), y.data(), x.size() * sizeof(float))) << r;
    }
}

TEST(RadialBasisTables, EvaluateMatchesProfilesAndNodes) {
    const RadialBasis& b = basis(0);
    const int J = b.size();
    std::vector<float> out(J);
    for (double r : {0.0, 1e-4, 0.0123, 0.5, 3.3, 17.0, kRMax, 2 * kRMax}) {
        b.evaluate(r, out.data());
        for (int j = 0; j < J; ++j) {
            const double p = b.profile(j, r);
            EXPECT_NEAR(out[j], p, 1e-6 * std::fabs(p) + 1e-9) << r << " " << j;
        }
    }
    // At the nodes the profiles are the stored values.
    const auto& nodes = b.nodes();
    EXPECT_EQ(nodes.front(), 0.0);
    EXPECT_EQ(nodes.back(), kRMax);
    for (size_t k = 0; k < nodes.size(); k += 37) {
        for (int j = 0; j < J; ++j) {
            EXPECT_FLOAT_EQ(static_cast<float>(b.profile(j, nodes[k])), b.tables().values[k * J + j]);
        }
    }
    // Beyond rMax: held at the value at rMax.
    for (int j = 0; j < J; ++j) EXPECT_EQ(b.profile(j, 40.0), b.profile(j, kRMax));
}

TEST(RadialBasisTables, BadTablesAreRefused) {
    const RadialBasis& b = basis(2);
    prt::RadialBasisTables t = b.tables();
    t.values.pop_back();
    expectErrorSubject([&] { RadialBasis x(b.range(), t); }, "radial basis");
    t = b.tables();
    t.values[5] = NAN;
    expectErrorSubject([&] { RadialBasis x(b.range(), t); }, "radial basis");
    t = b.tables();
    t.size = 0;
    expectErrorSubject([&] { RadialBasis x(b.range(), t); }, "radial basis");
    t = b.tables();
    for (int k = 0; k < t.nodeCount; ++k) t.values[size_t(k) * t.size + 1] = t.values[size_t(k) * t.size];
    expectErrorSubject([&] { RadialBasis x(b.range(), t); }, "radial basis");  // dependent
}

// ---------------------------------------------------------------------------
// Ranges and coverage
// ---------------------------------------------------------------------------

TEST(RadialBasisRange, CoversItsMaterialsAtEverySize) {
    const RadialRange r = fullRange();
    EXPECT_NEAR(r.zrMin, 1.0 / 7.38020 / 2.0, 1e-6);   // Cream R at s = 2
    EXPECT_NEAR(r.zrMax, 1.0 / 0.165 / 0.5, 1e-9);     // Chicken1 R at s = 0.5
    EXPECT_NEAR(r.alphaMin, 0.03 / 1.48, 1e-12);       // Ketchup B
    EXPECT_NEAR(r.alphaMax, 7.38 / 7.3802, 1e-12);     // Cream R
    const RadialBasis& b = basis(0);
    for (const Material& m : measuredAbsorbing()) {
        for (double s : {0.5, 0.7, 1.0, 1.9, 2.0}) {
            EXPECT_EQ(errorOf([&] { b.requireCovered(m, s); }), prt::test::kNoError) << m.name << s;
        }
    }
}

TEST(RadialBasisRange, RefusesSpectralonAndOutOfRangeInOneLineNamingTheBound) {
    const RadialBasis& marble = basis(2);
    const Material spectralon = prt::materialByName("Spectralon");
    EXPECT_FALSE(marble.covers(prt::makeDipoleChannel(spectralon, 0)));
    EXPECT_FALSE(basis(0).covers(prt::makeDipoleChannel(spectralon, 0)));
    std::string what = errorOf([&] { basis(0).requireCovered(spectralon); });
    EXPECT_NE(what.find("Spectralon"), std::string::npos) << what;
    EXPECT_NE(what.find("channel R"), std::string::npos) << what;
    EXPECT_NE(what.find("sigma_a = 0"), std::string::npos) << what;
    EXPECT_EQ(what.find('\n'), std::string::npos) << what;

    const Material m = prt::materialByName("Marble");
    what = errorOf([&] { marble.requireCovered(m, 4.0); });  // z_r / 4 below z_r min
    EXPECT_NE(what.find("Marble: channel R at size factor 4: z_r = "), std::string::npos) << what;
    EXPECT_NE(what.find("below the basis range's z_r min"), std::string::npos) << what;
    EXPECT_EQ(what.find('\n'), std::string::npos) << what;
    what = errorOf([&] { marble.requireCovered(m, 0.25); });
    EXPECT_NE(what.find("channel R at size factor 0.25"), std::string::npos) << what;
    EXPECT_NE(what.find("above the basis range's z_r max"), std::string::npos) << what;
    what = errorOf([&] { marble.requireCovered(prt::materialByName("Skin2")); });
    EXPECT_NE(what.find("alpha'"), std::string::npos) << what;
    EXPECT_NE(what.find("below the basis range's alpha' min"), std::string::npos) << what;
    what = errorOf([&] { basis(0).requireCovered(prt::customMaterial({1, 1, 1}, {0.01, 0.01, 0.01}, 1.5)); });
    EXPECT_NE(what.find("eta"), std::string::npos) << what;
    EXPECT_THROW(prt::rangeCovering({spectralon}, 1, 1, kRMax), prt::Error);
}

TEST(RadialBasisRange, InvalidRangesAndOptionsAreRefused) {
    const RadialRange good = marbleRange();
    EXPECT_EQ(errorOf([&] { prt::validateRadialRange(good); }), prt::test::kNoError);
    auto refused = [&](auto edit) {
        RadialRange r = good;
        edit(r);
        expectErrorSubject([&] { prt::validateRadialRange(r); }, "radial range");
        expectErrorSubject([&] { prt::makeRadialBasis(r, {}); }, "radial range");
    };
    refused([](RadialRange& r) { r.zrMin = 0.0; });
    refused([](RadialRange& r) { r.zrMax = 0.5 * r.zrMin; });
    refused([](RadialRange& r) { r.alphaMin = 0.0; });
    refused([](RadialRange& r) { r.alphaMax = 1.0; });
    refused([](RadialRange& r) { r.alphaMin = r.alphaMax + 1e-3; });
    refused([](RadialRange& r) { r.rMax = 0.0; });
    refused([](RadialRange& r) { r.rMax = NAN; });
    refused([](RadialRange& r) { r.eta = 3.0; });
    refused([](RadialRange& r) { r.zrMin = 1e-9; });
    expectErrorSubject([&] { prt::rangeCovering(measuredAbsorbing(), 2.0, 1.0, kRMax); }, "size factor");
    RadialBasisOptions o;
    o.size = 0;
    expectErrorSubject([&] { prt::makeRadialBasis(good, o); }, "radial basis options");
    o = {};
    o.normExponent = 5.0;
    expectErrorSubject([&] { prt::makeRadialBasis(good, o); }, "radial basis options");
    o = {};
    o.gridStep = 0.0;
    expectErrorSubject([&] { prt::makeRadialBasis(good, o); }, "radial basis options");
}

}  // namespace

namespace {

// The measurement table of docs/radial-basis.md (not run by default; ~1 s):
//   test_common --gtest_also_run_disabled_tests --gtest_filter='RadialBasisMeasure.*'
TEST(RadialBasisMeasure, DISABLED_PrintTable) {
    struct Worst {
        double l1 = 0, disk = 0, moment = 0;
        std::string l1Case, diskCase, momentCase;
    };
    auto measure = [](const RadialBasis& b, const std::vector<Material>& materials) {
        Worst w;
        for (const Material& m : materials) {
            for (double s : kSizes) {
                for (int c = 0; c < 3; ++c) {
                    const prt::RadialFitError e = b.fitError(scaledChannel(m, c, s));
                    const std::string name = caseName(m, c, s).substr(0, m.name.size() + 6);
                    if (e.l1 > w.l1) w.l1 = e.l1, w.l1Case = name;
                    if (e.disk > w.disk) w.disk = e.disk, w.diskCase = name;
                    const double mo = std::max(e.moment1, e.moment2);
                    if (mo > w.moment) w.moment = mo, w.momentCase = name;
                }
            }
        }
        return w;
    };
    std::printf("| construction | p | J | worst L1 | worst disk | worst moment | Marble range L1 / disk / moment |\n");
    std::printf("|---|---|---|---|---|---|---|\n");
    for (prt::RadialConstruction c : {prt::RadialConstruction::Pca, prt::RadialConstruction::Greedy,
                                      prt::RadialConstruction::ExpLadder}) {
        for (double p : {3.0, 1.0}) {
            for (int J : {6, 8, 10, 12, 16}) {
                RadialBasisOptions o;
                o.construction = c;
                o.size = J;
                o.normExponent = p;
                const Worst w = measure(prt::makeRadialBasis(fullRange(), o), measuredAbsorbing());
                const Worst wm = measure(prt::makeRadialBasis(marbleRange(), o), {prt::materialByName("Marble")});
                std::printf("| %s | %g | %d | %.2e (%s) | %.2e (%s) | %.2e (%s) | %.1e / %.1e / %.1e |\n",
                            prt::radialConstructionName(c), p, J, w.l1, w.l1Case.c_str(), w.disk,
                            w.diskCase.c_str(), w.moment, w.momentCase.c_str(), wm.l1, wm.disk, wm.moment);
            }
        }
    }
}

}  // namespace

// Balancing changes the coordinates, not the fits: the balanced basis fits every covered
// dipole as well as the original (the same span; float tables), and its weights have
// identity second moments over the dipoles it was balanced for.
TEST(RadialBasisBalance, SameFitsIdentityMoments) {
    std::vector<prt::Material> materials;
    for (const char* name : {"Marble", "Skin1", "Ketchup", "Wholemilk"}) materials.push_back(prt::materialByName(name));
    const prt::RadialBasis basis = prt::makeRadialBasis(prt::rangeCovering(materials, 0.5, 2.0, 30.0), {});
    std::vector<prt::DipoleChannel> dipoles;
    for (const prt::Material& m : materials)
        for (double s : {0.5, 1.0, 2.0})
            for (int c = 0; c < 3; ++c) {
                prt::Material scaled = m;
                scaled.sigmaA *= s;
                scaled.sigmaSPrime *= s;
                dipoles.push_back(prt::makeDipoleChannel(scaled, c));
            }
    const prt::RadialBasis balanced = prt::balancedForDipoles(basis, dipoles);
    ASSERT_EQ(balanced.size(), basis.size());
    const int J = basis.size();
    std::vector<double> moments(size_t(J * J), 0.0);
    for (const prt::DipoleChannel& d : dipoles) {
        const prt::RadialFitError a = basis.fitError(d), b = balanced.fitError(d);
        EXPECT_NEAR(b.l1, a.l1, 0.02 * a.l1 + 1e-5);
        EXPECT_LT(b.integral, 1e-9);
        const std::vector<double> w = balanced.weights(d);
        for (int i = 0; i < J; ++i)
            for (int j = 0; j < J; ++j) moments[size_t(i * J + j)] += w[size_t(i)] * w[size_t(j)] / double(dipoles.size());
    }
    for (int i = 0; i < J; ++i)
        for (int j = 0; j < J; ++j) EXPECT_NEAR(moments[size_t(i * J + j)], i == j ? 1.0 : 0.0, 1e-3) << i << " " << j;
    EXPECT_THROW(prt::balancedForDipoles(basis, {}), prt::Error);
}

// Importance weights: the weighted second moments become the identity, so a dipole
// weighted 10x counts 10x in the joint truncation's norm; bad weights are refused.
TEST(RadialBasisBalance, ImportanceWeightsTheMoments) {
    std::vector<prt::Material> materials;
    for (const char* name : {"Marble", "Ketchup"}) materials.push_back(prt::materialByName(name));
    const prt::RadialBasis basis = prt::makeRadialBasis(prt::rangeCovering(materials, 0.5, 2.0, 30.0), {});
    std::vector<prt::DipoleChannel> dipoles;
    std::vector<double> importance;
    for (const prt::Material& m : materials)
        for (double s : {0.5, 1.0, 2.0})
            for (int c = 0; c < 3; ++c) {
                dipoles.push_back(prt::makeDipoleChannel(prt::scaledMaterial(m, s), c));
                importance.push_back(m.name == "Ketchup" ? 10.0 : 1.0);
            }
    const prt::RadialBasis balanced = prt::balancedForDipoles(basis, dipoles, importance);
    const prt::RadialBasis plain = prt::balancedForDipoles(basis, dipoles);
    const int J = basis.size();
    std::vector<double> moments(size_t(J * J), 0.0), plainMoments(size_t(J * J), 0.0);
    double total = 0.0;
    for (size_t k = 0; k < dipoles.size(); ++k) total += importance[k];
    for (size_t k = 0; k < dipoles.size(); ++k) {
        const std::vector<double> w = balanced.weights(dipoles[k]);
        const std::vector<double> u = plain.weights(dipoles[k]);
        for (int i = 0; i < J; ++i)
            for (int j = 0; j < J; ++j) {
                moments[size_t(i * J + j)] += importance[k] * w[size_t(i)] * w[size_t(j)] / total;
                plainMoments[size_t(i * J + j)] += importance[k] * u[size_t(i)] * u[size_t(j)] / total;
            }
    }
    double plainOff = 0.0;
    for (int i = 0; i < J; ++i)
        for (int j = 0; j < J; ++j) {
            EXPECT_NEAR(moments[size_t(i * J + j)], i == j ? 1.0 : 0.0, 1e-3) << i << " " << j;
            plainOff = std::max(plainOff, std::abs(plainMoments[size_t(i * J + j)] - (i == j ? 1.0 : 0.0)));
        }
    EXPECT_GT(plainOff, 0.1);  // the unweighted balance is not the weighted one
    EXPECT_THROW(prt::balancedForDipoles(basis, dipoles, {1.0}), prt::Error);
    std::vector<double> negative = importance;
    negative[0] = -1.0;
    EXPECT_THROW(prt::balancedForDipoles(basis, dipoles, negative), prt::Error);
    EXPECT_THROW(prt::balancedForDipoles(basis, dipoles, std::vector<double>(dipoles.size(), 0.0)), prt::Error);
}
