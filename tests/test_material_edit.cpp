// Material edits: the size identity, the artist's pair and its inversion, interpolation
// and the text form (common/material_edit.h).
#include <gtest/gtest.h>

#include <cmath>

#include "common/bssrdf.h"
#include "common/error.h"
#include "common/material_edit.h"

namespace prt {
namespace {

// R_d(r; s sigma) = s^2 R_d(s r; sigma): an object s times larger renders as the
// original with s times the coefficients.
TEST(MaterialEdit, SizeIsMaterialScaling) {
    for (const std::string& name : materialNames()) {
        const Material m = materialByName(name);
        for (double s : {0.5, 2.0, 3.7}) {
            const Material scaled = scaledMaterial(m, s);
            for (double r : {0.0, 0.01, 0.3, 1.0, 4.0, 20.0}) {
                const glm::dvec3 lhs = dipoleRd(scaled, r), rhs = s * s * dipoleRd(m, s * r);
                for (int c = 0; c < 3; ++c) EXPECT_NEAR(lhs[c], rhs[c], 1e-12 * std::abs(rhs[c]) + 1e-300) << name;
            }
            // The plane integral is scale free.
            const glm::dvec3 a = scaled.totalDiffuseReflectance(), b = m.totalDiffuseReflectance();
            for (int c = 0; c < 3; ++c) EXPECT_NEAR(a[c], b[c], 1e-13);
        }
    }
    EXPECT_THROW(scaledMaterial(materialByName("Marble"), 0.0), Error);
    EXPECT_THROW(scaledMaterial(materialByName("Marble"), std::nan("")), Error);
}

// appearanceOf and materialFromAppearance are inverse pairs on every measured material
// with absorption (Spectralon has sigma_a = 0: an infinite mean free path).
TEST(MaterialEdit, AppearanceRoundTrip) {
    for (const std::string& name : materialNames()) {
        const Material m = materialByName(name);
        if (name == "Spectralon") {
            EXPECT_TRUE(std::isinf(appearanceOf(m).meanFreePathMm.x));
            continue;
        }
        const MaterialAppearance a = appearanceOf(m);
        const Material back = materialFromAppearance(a.diffuseColour, a.meanFreePathMm, m.eta);
        for (int c = 0; c < 3; ++c) {
            EXPECT_NEAR(back.sigmaA[c], m.sigmaA[c], 1e-9 * m.sigmaTPrime()[c]) << name << " channel " << c;
            EXPECT_NEAR(back.sigmaSPrime[c], m.sigmaSPrime[c], 1e-9 * m.sigmaTPrime()[c]) << name << " channel " << c;
        }
        // The forward direction: the colour is the dipole's closed-form total reflectance.
        const glm::dvec3 colour = back.totalDiffuseReflectance();
        for (int c = 0; c < 3; ++c) EXPECT_NEAR(colour[c], a.diffuseColour[c], 1e-12);
    }
}

// The inverted material reproduces the requested colour by integrating R_d numerically
// (independent of the closed form used by the inversion) and the requested 1 / sigma_tr.
TEST(MaterialEdit, AppearanceMeaning) {
    const glm::dvec3 colour(0.8, 0.5, 0.2), mfp(2.0, 1.0, 0.5);
    const Material m = materialFromAppearance(colour, mfp, 1.4);
    EXPECT_EQ(m.name, "appearance");
    EXPECT_DOUBLE_EQ(m.eta, 1.4);
    for (int c = 0; c < 3; ++c) {
        EXPECT_NEAR(1.0 / m.sigmaTr()[c], mfp[c], 1e-12 * mfp[c]);
        // int_0^inf R_d 2 pi r dr by the midpoint rule in u = log r.
        const DipoleChannel d = makeDipoleChannel(m, c);
        double sum = 0.0;
        const double lo = std::log(1e-6), hi = std::log(400.0 * mfp[c]);
        const int n = 200000;
        for (int i = 0; i < n; ++i) {
            const double r = std::exp(lo + (i + 0.5) * (hi - lo) / n);
            sum += dipoleRd(d, r) * 2.0 * M_PI * r * r * (hi - lo) / n;
        }
        EXPECT_NEAR(sum, colour[c], 2e-5) << "channel " << c;
    }
    EXPECT_THROW(materialFromAppearance(glm::dvec3(1.0, 0.5, 0.5), mfp), Error);
    EXPECT_THROW(materialFromAppearance(glm::dvec3(0.0, 0.5, 0.5), mfp), Error);
    EXPECT_THROW(materialFromAppearance(colour, glm::dvec3(1.0, -1.0, 1.0)), Error);
    EXPECT_THROW(materialFromAppearance(colour, mfp, 9.0), Error);
}

TEST(MaterialEdit, Lerp) {
    const Material a = materialByName("Marble"), b = materialByName("Ketchup");
    const Material m0 = lerpMaterial(a, b, 0.0), m1 = lerpMaterial(a, b, 1.0), mh = lerpMaterial(a, b, 0.25);
    EXPECT_EQ(m0.sigmaA, a.sigmaA);
    EXPECT_EQ(m1.sigmaSPrime, b.sigmaSPrime);
    EXPECT_NEAR(mh.sigmaA.y, 0.75 * a.sigmaA.y + 0.25 * b.sigmaA.y, 1e-15);
    EXPECT_EQ(mh.name, "Marble -> Ketchup");
    for (double t = 0.0; t <= 1.0; t += 1.0 / 7.0) EXPECT_EQ(lerpMaterial(a, b, t).eta, a.eta);
    EXPECT_THROW(lerpMaterial(a, b, 1.5), Error);
}

TEST(MaterialEdit, ParseForms) {
    const Material preset = parseMaterial("skin1", 1.4);
    EXPECT_EQ(preset.name, "Skin1");
    EXPECT_DOUBLE_EQ(preset.eta, 1.4);
    const Material sigma = parseMaterial("sigma:0.01,0.02,0.03:1,2,3");
    EXPECT_EQ(sigma.sigmaA, glm::dvec3(0.01, 0.02, 0.03));
    EXPECT_EQ(sigma.sigmaSPrime, glm::dvec3(1, 2, 3));
    const Material colour = parseMaterial("colour: 0.8,0.5,0.2 : 1.5");
    EXPECT_NEAR(1.0 / colour.sigmaTr().z, 1.5, 1e-12);
    EXPECT_EQ(parseMaterial("color:0.8,0.5,0.2:1.5").sigmaA, colour.sigmaA);
    for (const char* bad : {"Jade", "sigma:1,2:1,2,3", "sigma:-1,0,0:1,1,1", "colour:1.2,0.5,0.5:1", "colour:0.5,0.5,0.5",
                            "sigma:a,b,c:1,2,3", ""}) {
        try {
            parseMaterial(bad);
            ADD_FAILURE() << "accepted '" << bad << "'";
        } catch (const Error& e) {
            EXPECT_EQ(std::string(e.what()).find('\n'), std::string::npos);
            EXPECT_NE(std::string(e.what()).find("--material"), std::string::npos) << e.what();
        }
    }
}

TEST(MaterialEdit, ParsePath) {
    auto [a, b] = parseMaterialPath("Marble:Ketchup");
    EXPECT_EQ(a.name, "Marble");
    EXPECT_EQ(b.name, "Ketchup");
    auto [c, d] = parseMaterialPath("sigma:0.01,0.02,0.03:1,2,3:colour:0.8,0.5,0.2:2", 1.2);
    EXPECT_EQ(c.sigmaA, glm::dvec3(0.01, 0.02, 0.03));
    EXPECT_EQ(d.name, "appearance");
    EXPECT_DOUBLE_EQ(d.eta, 1.2);
    for (const char* bad : {"Marble", "Marble:Ketchup:Apple", "sigma:1,1,1:Marble", "Marble:", ":Marble", "Marble:Jade"})
        EXPECT_THROW(parseMaterialPath(bad), Error) << bad;
}

}  // namespace
}  // namespace prt
