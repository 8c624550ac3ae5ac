// Display transforms (common/tonemap.h): each operator against its published formula,
// written out again here in double precision, and the PNG writer and the displayed RMSE
// through them.

#include <gtest/gtest.h>

#include <CLI/CLI.hpp>

#include <cmath>
#include <filesystem>
#include <limits>
#include <string>

#include "common/error.h"
#include "common/image.h"
#include "common/image_compare.h"
#include "common/options.h"
#include "common/tonemap.h"

using namespace prt;

namespace {

// The formulas as the papers print them (tonemap.h cites them).
double reinhardLuminanceScale(double y) { return 1.0 / (1.0 + y); }  // Y_d / Y, Reinhard 2002 eq. 3
double narkowicz(double x) {
    return std::clamp(x * (2.51 * x + 0.03) / (x * (2.43 * x + 0.59) + 0.14), 0.0, 1.0);
}
double changCorrected(double r) { return r / (1.0 + r); }

const double kInputs[] = {0.0, 1e-4, 0.01, 0.18, 0.5, 1.0, 2.0, 7.5, 100.0, 1e6};

}  // namespace

TEST(ToneMap, OperatorNamesRoundTrip) {
    for (ToneMapOperator op :
         {ToneMapOperator::Clamp, ToneMapOperator::Reinhard, ToneMapOperator::Filmic, ToneMapOperator::Chang})
        EXPECT_EQ(parseToneMapOperator(toneMapOperatorName(op)), op);
    EXPECT_EQ(parseToneMapOperator("ReInHaRd"), ToneMapOperator::Reinhard);
    try {
        parseToneMapOperator("aces");
        FAIL() << "an unknown operator was accepted";
    } catch (const Error& e) {
        EXPECT_EQ(e.subject(), "--tonemap");
        EXPECT_NE(std::string(e.what()).find("clamp, reinhard, filmic, chang"), std::string::npos) << e.what();
    }
}

TEST(ToneMap, ClampScalesByTheExposure) {
    const DisplayMapping m = displayMapping(DisplayTransform{2.0, ToneMapOperator::Clamp}, 1.0);
    EXPECT_FLOAT_EQ(m.scale, 4.0f);
    for (double x : kInputs) {
        const glm::vec3 d = m.apply(glm::vec3(float(x)));
        EXPECT_FLOAT_EQ(d.r, float(std::min(4.0 * x, 1.0))) << x;
    }
}

TEST(ToneMap, FilmicIsNarkowiczsFit) {
    const DisplayMapping m = displayMapping(DisplayTransform{-1.0, ToneMapOperator::Filmic}, 1.0);
    for (double x : kInputs) {
        const glm::vec3 d = m.apply(glm::vec3(float(x), float(2.0 * x), float(0.5 * x)));
        EXPECT_NEAR(d.r, narkowicz(0.5 * x), 2e-6) << x;
        EXPECT_NEAR(d.g, narkowicz(x), 2e-6) << x;
        EXPECT_NEAR(d.b, narkowicz(0.25 * x), 2e-6) << x;
    }
    // The fit's asymptote is 2.51 / 2.43 > 1: the clamp is what keeps it in [0, 1].
    EXPECT_EQ(m.apply(glm::vec3(1e9f)).r, 1.0f);
}

TEST(ToneMap, ReinhardMapsTheLuminanceAndKeepsTheHue) {
    const DisplayMapping m = displayMapping(DisplayTransform{0.0, ToneMapOperator::Reinhard}, 1.0);
    const glm::dvec3 colour(0.9, 0.5, 0.2);
    for (double x : kInputs) {
        const glm::dvec3 c = colour * x;
        const double y = 0.2126 * c.r + 0.7152 * c.g + 0.0722 * c.b;
        const glm::vec3 d = m.apply(glm::vec3(c));
        for (int k = 0; k < 3; ++k)
            EXPECT_NEAR(d[k], std::min(c[k] * reinhardLuminanceScale(y), 1.0), 1e-6 * std::max(1.0, c[k])) << x;
        // Displayed luminance is Y / (1 + Y) while no channel clips.
        if (d.r < 1.0f) {
            EXPECT_NEAR(luminance(d), y / (1.0 + y), 1e-6) << x;
        }
    }
}

TEST(ToneMap, ChangIsRadianceOverOnePlusRadianceOfTheAverage) {
    // Object pixels of luminance 1 and 3 (mean 2) and a bright background that must not
    // count towards Radiance_avg.
    Image image(3, 1, 4, 0.0f);
    for (int c = 0; c < 3; ++c) {
        image.at(0, 0, c) = 1.0f;
        image.at(1, 0, c) = 3.0f;
        image.at(2, 0, c) = 1000.0f;
    }
    image.at(0, 0, 3) = image.at(1, 0, 3) = 1.0f;
    EXPECT_NEAR(meanObjectLuminance(image), 2.0, 1e-6);
    const DisplayMapping m = displayMapping(image, DisplayTransform{1.0, ToneMapOperator::Chang});
    EXPECT_NEAR(m.scale, 2.0 / 2.0, 1e-7);  // 2^1 / Radiance_avg
    const Image shown = displayImage(image, m);
    EXPECT_NEAR(shown.at(0, 0, 0), changCorrected(1.0), 1e-6);
    EXPECT_NEAR(shown.at(1, 0, 0), changCorrected(3.0), 1e-6);
    // The paper's printed (1 + R) / R would exceed 1 and fall as radiance rises.
    for (double r : kInputs) {
        const double d = m.apply(glm::vec3(float(r))).r;
        EXPECT_GE(d, 0.0);
        EXPECT_LE(d, 1.0);
    }
    // A black image maps with Radiance_avg = 1 instead of dividing by zero.
    EXPECT_FLOAT_EQ(displayMapping(Image(2, 2, 4, 0.0f), DisplayTransform{0.0, ToneMapOperator::Chang}).scale, 1.0f);
}

TEST(ToneMap, NonFiniteAndNegativeInputs) {
    for (ToneMapOperator op :
         {ToneMapOperator::Clamp, ToneMapOperator::Reinhard, ToneMapOperator::Filmic, ToneMapOperator::Chang}) {
        const DisplayMapping m = displayMapping(DisplayTransform{0.0, op}, 1.0);
        const glm::vec3 d = m.apply({std::numeric_limits<float>::quiet_NaN(), -5.0f, 0.0f});
        EXPECT_EQ(d.r, 0.0f) << toneMapOperatorName(op);
        EXPECT_EQ(d.g, 0.0f) << toneMapOperatorName(op);
        const glm::vec3 inf = m.apply({std::numeric_limits<float>::infinity(), 0.0f, 0.0f});
        EXPECT_EQ(inf.r, 1.0f) << toneMapOperatorName(op);
        EXPECT_FALSE(std::isnan(inf.g)) << toneMapOperatorName(op);
    }
    EXPECT_THROW(displayMapping(DisplayTransform{NAN, ToneMapOperator::Clamp}, 1.0), Error);
}

TEST(ToneMap, PngHoldsTheDisplayValues) {
    // A ramp over four decades, written through each operator and read back: every byte
    // is the sRGB encoding of displayImage's value, to the 8-bit rounding.
    Image ramp(64, 2, 4, 1.0f);
    for (int x = 0; x < 64; ++x)
        for (int c = 0; c < 3; ++c) {
            ramp.at(x, 0, c) = float(std::pow(10.0, -2.0 + 4.0 * x / 63.0)) * (c == 0 ? 1.0f : 0.6f);
            ramp.at(x, 1, c) = 0.3f;
        }
    const std::string path = ::testing::TempDir() + "tonemap_ramp.png";
    for (ToneMapOperator op :
         {ToneMapOperator::Clamp, ToneMapOperator::Reinhard, ToneMapOperator::Filmic, ToneMapOperator::Chang}) {
        const DisplayTransform t{0.5, op};
        writePng(path, ramp, t);
        const Image back = readImage(path);
        const Image shown = displayImage(ramp, displayMapping(ramp, t));
        ASSERT_EQ(back.channels, 3);
        double worst = 0.0;
        for (size_t i = 0; i < shown.pixels.size(); ++i)
            worst = std::max(worst, std::abs(double(back.pixels[i]) - double(linearToSrgb(shown.pixels[i]))));
        EXPECT_LE(worst, 0.5 / 255.0 + 1e-6) << toneMapOperatorName(op);
    }
    std::filesystem::remove(path);
}

TEST(ToneMap, DisplayRmseShowsBothImagesThroughTheReferencesMapping) {
    Image reference(8, 8, 4, 1.0f), doubled(8, 8, 4, 1.0f);
    for (size_t p = 0; p < 64; ++p)
        for (int c = 0; c < 3; ++c) {
            reference.pixels[4 * p + size_t(c)] = 0.2f + 0.01f * float(p);
            doubled.pixels[4 * p + size_t(c)] = 2.0f * reference.pixels[4 * p + size_t(c)];
        }
    const DisplayTransform chang{0.0, ToneMapOperator::Chang};
    // Each image through its own Radiance_avg would show the doubled one unchanged.
    const Image ownR = displayImage(reference, displayMapping(reference, chang));
    const Image ownD = displayImage(doubled, displayMapping(doubled, chang));
    EXPECT_NEAR(ownR.pixels[0], ownD.pixels[0], 1e-6);
    // Through the reference's, the factor of two shows.
    EXPECT_GT(displayRmse(doubled, reference, chang), 0.05);
    EXPECT_NEAR(displayRmse(reference, reference, chang), 0.0, 1e-12);
    // The exposure-only form is the clamp operator.
    EXPECT_DOUBLE_EQ(displayRmse(doubled, reference, 1.0),
                     displayRmse(doubled, reference, DisplayTransform{1.0, ToneMapOperator::Clamp}));
}

TEST(ToneMap, CommandLineOptions) {
    CLI::App app;
    DisplayTransform d;
    addDisplayOptions(app, d);
    const char* argv[] = {"tool", "--tonemap", "chang", "--exposure=-1.5"};
    app.parse(4, const_cast<char**>(argv));
    EXPECT_EQ(d.op, ToneMapOperator::Chang);
    EXPECT_EQ(d.exposureStops, -1.5);
    CLI::App bad;
    DisplayTransform e;
    addDisplayOptions(bad, e);
    const char* wrong[] = {"tool", "--tonemap", "gamma"};
    EXPECT_THROW(bad.parse(3, const_cast<char**>(wrong)), Error);
}
