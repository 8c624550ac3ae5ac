// Tests of common/materials: the measured table transcribed independently from the
// SPEC, name look-up, validation of custom media and the derived constants.

#include "common/materials.h"
#include "common/bssrdf.h"
#include "common/error.h"
#include "tests/test_support.h"

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <string>
#include <vector>

namespace {

using prt::test::expectErrorSubject;

using prt::DipoleChannel;
using prt::Material;


// ---------------------------------------------------------------------------
// Material table
// ---------------------------------------------------------------------------

struct Row {
    const char* name;
    double ss[3];
    double sa[3];
};

// Transcribed separately from the SPEC table (Jensen et al. 2001), to compare with
// the library's own transcription.
const Row kSpecTable[] = {
    {"Apple", {2.29, 2.39, 1.97}, {0.0030, 0.0034, 0.046}},
    {"Chicken1", {0.15, 0.21, 0.38}, {0.015, 0.077, 0.19}},
    {"Chicken2", {0.19, 0.25, 0.32}, {0.018, 0.088, 0.20}},
    {"Cream", {7.38, 5.47, 3.15}, {0.0002, 0.0028, 0.0163}},
    {"Ketchup", {0.18, 0.07, 0.03}, {0.061, 0.97, 1.45}},
    {"Marble", {2.19, 2.62, 3.00}, {0.0021, 0.0041, 0.0071}},
    {"Potato", {0.68, 0.70, 0.55}, {0.0024, 0.0090, 0.12}},
    {"Skimmilk", {0.70, 1.22, 1.90}, {0.0014, 0.0025, 0.0142}},
    {"Skin1", {0.74, 0.88, 1.01}, {0.032, 0.17, 0.48}},
    {"Skin2", {1.09, 1.59, 1.79}, {0.013, 0.070, 0.145}},
    {"Spectralon", {11.6, 20.4, 14.9}, {0.00, 0.00, 0.00}},
    {"Wholemilk", {2.55, 3.21, 3.77}, {0.0011, 0.0024, 0.014}},
};

TEST(MaterialTable, NamesAreTheTwelveSpecMaterials) {
    const std::vector<std::string> names = prt::materialNames();
    ASSERT_EQ(names.size(), 12u);
    for (size_t i = 0; i < names.size(); ++i) EXPECT_EQ(names[i], kSpecTable[i].name);
}

TEST(MaterialTable, SpotCheckedNumbersAreExact) {
    const Material marble = prt::materialByName("Marble");
    EXPECT_EQ(marble.sigmaSPrime, glm::dvec3(2.19, 2.62, 3.00));
    EXPECT_EQ(marble.sigmaA, glm::dvec3(0.0021, 0.0041, 0.0071));
    const Material ketchup = prt::materialByName("Ketchup");
    EXPECT_EQ(ketchup.sigmaSPrime, glm::dvec3(0.18, 0.07, 0.03));
    EXPECT_EQ(ketchup.sigmaA, glm::dvec3(0.061, 0.97, 1.45));
    const Material skin1 = prt::materialByName("Skin1");
    EXPECT_EQ(skin1.sigmaSPrime, glm::dvec3(0.74, 0.88, 1.01));
    EXPECT_EQ(skin1.sigmaA, glm::dvec3(0.032, 0.17, 0.48));
    const Material spectralon = prt::materialByName("Spectralon");
    EXPECT_EQ(spectralon.sigmaA, glm::dvec3(0.0));
}

TEST(MaterialTable, EveryRowMatchesTheSpec) {
    for (const Row& row : kSpecTable) {
        const Material m = prt::materialByName(row.name);
        EXPECT_EQ(m.name, row.name);
        EXPECT_EQ(m.eta, 1.3) << row.name;
        EXPECT_EQ(m.g, 0.0) << row.name;
        for (int c = 0; c < 3; ++c) {
            EXPECT_EQ(m.sigmaSPrime[c], row.ss[c]) << row.name << " channel " << c;
            EXPECT_EQ(m.sigmaA[c], row.sa[c]) << row.name << " channel " << c;
        }
        EXPECT_NO_THROW(prt::validateMaterial(m)) << row.name;
    }
}

TEST(MaterialByName, IsCaseInsensitive) {
    for (const char* spelling : {"marble", "MARBLE", "mArBlE", "Marble"}) {
        EXPECT_EQ(prt::materialByName(spelling).name, "Marble") << spelling;
    }
    EXPECT_EQ(prt::materialByName("wholemilk").sigmaSPrime, glm::dvec3(2.55, 3.21, 3.77));
}

TEST(MaterialByName, UnknownNameThrowsListingValidNames) {
    for (const char* bad : {"jade", "", "Marble ", "Skin3"}) {
        try {
            prt::materialByName(bad);
            ADD_FAILURE() << "no error for '" << bad << "'";
        } catch (const prt::Error& e) {
            EXPECT_EQ(e.subject(), bad);
            const std::string what = e.what();
            for (const Row& row : kSpecTable) {
                EXPECT_NE(what.find(row.name), std::string::npos) << what;
            }
        }
    }
}

TEST(CustomMaterial, KeepsValidParameters) {
    const Material m = prt::customMaterial({1.0, 2.0, 3.0}, {0.1, 0.0, 0.3}, 1.5, -0.3);
    EXPECT_EQ(m.sigmaSPrime, glm::dvec3(1.0, 2.0, 3.0));
    EXPECT_EQ(m.sigmaA, glm::dvec3(0.1, 0.0, 0.3));
    EXPECT_EQ(m.eta, 1.5);
    EXPECT_EQ(m.g, -0.3);
    // Defaults: eta = 1.3, g = 0.
    const Material d = prt::customMaterial({1.0, 1.0, 1.0}, {0.01, 0.01, 0.01});
    EXPECT_EQ(d.eta, 1.3);
    EXPECT_EQ(d.g, 0.0);
    // Pure absorber and pure scatterer are both valid media.
    EXPECT_NO_THROW(prt::customMaterial({0.0, 0.0, 0.0}, {1.0, 1.0, 1.0}));
    EXPECT_NO_THROW(prt::customMaterial({1.0, 1.0, 1.0}, {0.0, 0.0, 0.0}));
}

TEST(CustomMaterial, RejectsBadParametersNamingThem) {
    const glm::dvec3 ok(1.0, 1.0, 1.0);
    const double nan = std::nan("");
    const double inf = INFINITY;
    auto make = [](glm::dvec3 s, glm::dvec3 a, double eta, double g) {
        return [=] { prt::customMaterial(s, a, eta, g); };
    };
    expectErrorSubject(make({-0.1, 1, 1}, ok, 1.3, 0), "sigma_s'");
    expectErrorSubject(make({1, nan, 1}, ok, 1.3, 0), "sigma_s'");
    expectErrorSubject(make({1, 1, inf}, ok, 1.3, 0), "sigma_s'");
    expectErrorSubject(make(ok, {1, -1e-9, 1}, 1.3, 0), "sigma_a");
    expectErrorSubject(make(ok, {nan, 1, 1}, 1.3, 0), "sigma_a");
    expectErrorSubject(make(ok, {1, 1, inf}, 1.3, 0), "sigma_a");
    expectErrorSubject(make({1, 0, 1}, {1, 0, 1}, 1.3, 0), "sigma_t'");
    for (double eta : {0.0, -1.3, nan, inf, 0.2, 4.0}) {
        expectErrorSubject(make(ok, ok, eta, 0), "eta");
    }
    for (double g : {1.0, -1.0, 1.5, -2.0, nan}) {
        expectErrorSubject(make(ok, ok, 1.3, g), "g");
    }
}

// ---------------------------------------------------------------------------
// Derived quantities
// ---------------------------------------------------------------------------

TEST(Material, DerivedQuantitiesFollowTheirDefinitions) {
    Material m = prt::materialByName("Skin2");
    m.g = 0.4;
    const glm::dvec3 ss = m.sigmaSPrime / 0.6;
    for (int c = 0; c < 3; ++c) {
        const double sp = m.sigmaSPrime[c];
        const double sa = m.sigmaA[c];
        EXPECT_DOUBLE_EQ(m.sigmaS()[c], ss[c]);
        EXPECT_DOUBLE_EQ(m.sigmaT()[c], sa + ss[c]);
        EXPECT_DOUBLE_EQ(m.sigmaTPrime()[c], sa + sp);
        EXPECT_DOUBLE_EQ(m.alphaPrime()[c], sp / (sa + sp));
        EXPECT_DOUBLE_EQ(m.albedo()[c], ss[c] / (sa + ss[c]));
        EXPECT_DOUBLE_EQ(m.sigmaTr()[c], std::sqrt(3.0 * sa * (sa + sp)));
        EXPECT_DOUBLE_EQ(m.zr()[c], 1.0 / (sa + sp));
        EXPECT_DOUBLE_EQ(m.zv()[c], m.zr()[c] * (1.0 + 4.0 * m.boundaryA() / 3.0));
        EXPECT_DOUBLE_EQ(m.meanFreePath()[c], 1.0 / (sa + sp));
        // The per-channel dipole agrees with the material's vectors.
        const DipoleChannel d = prt::makeDipoleChannel(m, c);
        EXPECT_DOUBLE_EQ(d.alphaPrime, m.alphaPrime()[c]);
        EXPECT_DOUBLE_EQ(d.sigmaTr, m.sigmaTr()[c]);
        EXPECT_DOUBLE_EQ(d.zr, m.zr()[c]);
        EXPECT_DOUBLE_EQ(d.zv, m.zv()[c]);
    }
    // sigma_s' is (1 - g) sigma_s: changing g leaves the reduced coefficients alone.
    EXPECT_LT(m.sigmaS().x * 0.6 - m.sigmaSPrime.x, 1e-15);
    EXPECT_DOUBLE_EQ(m.minMeanFreePath(), 1.0 / (1.79 + 0.145));  // blue is densest
}

TEST(Material, LuminanceUsesRec709Weights) {
    EXPECT_DOUBLE_EQ(prt::luminance({1, 0, 0}), 0.2126);
    EXPECT_DOUBLE_EQ(prt::luminance({0, 1, 0}), 0.7152);
    EXPECT_DOUBLE_EQ(prt::luminance({0, 0, 1}), 0.0722);
    EXPECT_NEAR(prt::luminance({1, 1, 1}), 1.0, 1e-15);
}

TEST(Material, VirtualSourceIsAboveRealSourceForEveryMaterial) {
    for (const std::string& name : prt::materialNames()) {
        const Material m = prt::materialByName(name);
        for (int c = 0; c < 3; ++c) {
            EXPECT_GT(m.zr()[c], 0.0) << name;
            EXPECT_GT(m.zv()[c], m.zr()[c]) << name;
            EXPECT_GE(m.sigmaTr()[c], 0.0) << name;
            EXPECT_GT(m.alphaPrime()[c], 0.0) << name;
            EXPECT_LE(m.alphaPrime()[c], 1.0) << name;
        }
    }
}


}  // namespace
