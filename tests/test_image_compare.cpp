#include "common/image_compare.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <limits>

#include "common/error.h"
#include "common/image.h"

using namespace prt;

namespace {

// A smooth RGBA test image: a disc of object pixels (A = 1) with varying colour,
// background (A = 0) a bright constant that must never enter the measures.
Image discImage(int w, int h) {
    Image im(w, h, 4, 0.0f);
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            const double dx = (x + 0.5) / w - 0.5, dy = (y + 0.5) / h - 0.5;
            float* p = im.pixel(x, y);
            if (dx * dx + dy * dy < 0.16) {
                p[0] = float(0.2 + 0.5 * (x + 1.0) / w);
                p[1] = float(0.1 + 0.3 * (y + 1.0) / h);
                p[2] = float(0.05 + 0.01 * ((x * 7 + y * 3) % 11));
                p[3] = 1.0f;
            } else {
                p[0] = p[1] = p[2] = 100.0f;
                p[3] = 0.0f;
            }
        }
    return im;
}

Image scaled(Image im, float s) {
    for (int y = 0; y < im.height; ++y)
        for (int x = 0; x < im.width; ++x)
            for (int c = 0; c < 3; ++c) im.at(x, y, c) *= s;
    return im;
}

size_t objectPixels(const Image& im) {
    size_t n = 0;
    for (int y = 0; y < im.height; ++y)
        for (int x = 0; x < im.width; ++x) n += im.at(x, y, 3) > 0.5f;
    return n;
}

}  // namespace

TEST(Compare, IdenticalImagesHaveZeroErrorAndInfinitePsnr) {
    const Image ref = discImage(64, 48);
    const CompareResult r = compareImages(ref, ref);
    EXPECT_EQ(r.comparedPixels, objectPixels(ref));
    EXPECT_EQ(r.mask, "reference alpha");
    EXPECT_EQ(r.colourChannels, 3);
    EXPECT_EQ(r.overall.relativeRmse, 0.0);
    EXPECT_TRUE(std::isinf(r.overall.psnr) && r.overall.psnr > 0);
    EXPECT_EQ(r.overall.maxAbsolute, 0.0);
    EXPECT_EQ(r.overall.maxRelative, 0.0);
    EXPECT_EQ(r.overall.meanRatio, 1.0);
    for (int c = 0; c < 3; ++c) {
        EXPECT_EQ(r.channel[c].relativeRmse, 0.0);
        EXPECT_TRUE(std::isinf(r.channel[c].psnr));
    }
    EXPECT_EQ(r.coverageMismatch, 0u);
}

TEST(Compare, ScaledImageHasRelativeRmseOfTheScale) {
    const Image ref = discImage(64, 48);
    const Image test = scaled(ref, 1.1f);
    const CompareResult r = compareImages(test, ref);
    // (1.1 b - b)^2 / b^2 = 0.01 for every value, whatever b; float rounding of 1.1 x b
    // (relative 6e-8) is the only deviation.
    EXPECT_NEAR(r.overall.relativeRmse, 0.1, 1e-6);
    for (int c = 0; c < 3; ++c) {
        EXPECT_NEAR(r.channel[c].relativeRmse, 0.1, 1e-6);
        EXPECT_NEAR(r.channel[c].meanRatio, 1.1, 1e-6);
        EXPECT_NEAR(r.channel[c].maxRelative, 0.1, 1e-6);
    }
    EXPECT_NEAR(r.overall.meanRatio, 1.1, 1e-6);
    // Max absolute error: 0.1 x the largest reference value; PSNR = 10 log10(peak^2 / MSE).
    EXPECT_NEAR(r.overall.maxAbsolute, 0.1 * r.peak, 1e-6);
    double sq = 0, peak = 0;
    size_t n = 0;
    for (int y = 0; y < ref.height; ++y)
        for (int x = 0; x < ref.width; ++x) {
            if (ref.at(x, y, 3) <= 0.5f) continue;
            for (int c = 0; c < 3; ++c) {
                const double d = double(test.at(x, y, c)) - ref.at(x, y, c);
                peak = std::max(peak, double(ref.at(x, y, c)));
                sq += d * d;
                ++n;
            }
        }
    EXPECT_EQ(r.peak, peak);  // the brightest reference value inside the disc, not the background's 100
    EXPECT_NEAR(r.overall.psnr, 10 * std::log10(peak * peak / (sq / n)), 1e-9);
}

TEST(Compare, AlphaMaskExcludesBackground) {
    const Image ref = discImage(64, 48);
    Image test = ref;
    // Wreck the background of the test image (and its alpha stays 0): no effect.
    for (int y = 0; y < test.height; ++y)
        for (int x = 0; x < test.width; ++x)
            if (test.at(x, y, 3) <= 0.5f)
                for (int c = 0; c < 3; ++c) test.at(x, y, c) = -1000.0f;
    CompareResult r = compareImages(test, ref);
    EXPECT_EQ(r.overall.relativeRmse, 0.0);
    EXPECT_EQ(r.comparedPixels, objectPixels(ref));

    // Without alpha every pixel counts, and the wrecked background shows.
    Image refRgb(ref.width, ref.height, 3), testRgb(ref.width, ref.height, 3);
    for (int y = 0; y < ref.height; ++y)
        for (int x = 0; x < ref.width; ++x)
            for (int c = 0; c < 3; ++c) {
                refRgb.at(x, y, c) = ref.at(x, y, c);
                testRgb.at(x, y, c) = test.at(x, y, c);
            }
    r = compareImages(testRgb, refRgb);
    EXPECT_EQ(r.mask, "all pixels");
    EXPECT_EQ(r.comparedPixels, size_t(ref.width) * ref.height);
    EXPECT_GT(r.overall.relativeRmse, 1.0);

    // A reference without alpha uses the test image's alpha.
    r = compareImages(test, refRgb);
    EXPECT_EQ(r.mask, "test alpha");
    EXPECT_EQ(r.comparedPixels, objectPixels(ref));
    EXPECT_EQ(r.overall.relativeRmse, 0.0);
}

TEST(Compare, CoverageMismatchIsCounted) {
    const Image ref = discImage(32, 32);
    Image test = ref;
    int cleared = 0;
    for (int x = 0; x < test.width && cleared < 3; ++x)
        if (test.at(x, 16, 3) > 0.5f) {
            test.at(x, 16, 3) = 0.0f;
            ++cleared;
        }
    ASSERT_EQ(cleared, 3);
    const CompareResult r = compareImages(test, ref);
    EXPECT_EQ(r.coverageMismatch, 3u);
    EXPECT_NE(formatCompareResult(r).find("warning"), std::string::npos);
}

TEST(Compare, SizeAndChannelMismatchesAreErrors) {
    const Image ref = discImage(32, 32);
    EXPECT_THROW(compareImages(discImage(32, 31), ref), Error);
    EXPECT_THROW(compareImages(discImage(31, 32), ref), Error);
    EXPECT_THROW(compareImages(Image(32, 32, 1, 0.5f), ref), Error);
    EXPECT_THROW(compareImages(Image(), ref), Error);
    try {
        compareImages(discImage(16, 32), ref);
        FAIL() << "no error for a size mismatch";
    } catch (const Error& e) {
        EXPECT_NE(std::string(e.what()).find("16 x 32"), std::string::npos) << e.what();
    }
    // Nothing to compare: a reference with alpha 0 everywhere.
    EXPECT_THROW(compareImages(Image(8, 8, 4, 0.0f), Image(8, 8, 4, 0.0f)), Error);
}

TEST(Compare, NonFiniteValuesInComparedPixelsAreErrors) {
    const Image ref = discImage(32, 32);
    Image test = ref;
    test.at(16, 16, 1) = std::numeric_limits<float>::quiet_NaN();
    EXPECT_THROW(compareImages(test, ref), Error);
    // ... but not in the background.
    test = ref;
    test.at(0, 0, 1) = std::numeric_limits<float>::infinity();
    EXPECT_NO_THROW(compareImages(test, ref));
}

TEST(Compare, GrayImages) {
    Image ref(10, 10, 1, 2.0f), test(10, 10, 1, 2.0f);
    test.at(3, 3, 0) = 2.2f;
    const CompareResult r = compareImages(test, ref);
    EXPECT_EQ(r.colourChannels, 1);
    EXPECT_EQ(r.comparedPixels, 100u);
    EXPECT_NEAR(r.overall.relativeRmse, std::sqrt(0.04 / 400.0), 1e-6);
    EXPECT_NEAR(r.overall.maxRelative, 0.1, 1e-6);
    EXPECT_EQ(r.overall.maxRelativeX, 3);
    EXPECT_EQ(r.overall.maxRelativeY, 3);
}

TEST(Compare, RelativeFloorBoundsTheMaxRelativeError) {
    Image ref(4, 1, 1, 1.0f), test(4, 1, 1, 1.0f);
    ref.at(0, 0, 0) = 0.0f;  // black reference value
    test.at(0, 0, 0) = 0.01f;
    CompareOptions o;
    o.relativeFloor = 1e-3;
    CompareResult r = compareImages(test, ref, o);
    EXPECT_NEAR(r.overall.maxRelative, 0.01 / 1e-3, 1e-3);  // divided by 1e-3 x peak (1)
    o.relativeFloor = 0.0;
    r = compareImages(test, ref, o);
    EXPECT_TRUE(std::isinf(r.overall.maxRelative));
}

TEST(Compare, ThresholdExitCodes) {
    const Image ref = discImage(32, 32);
    const CompareResult r = compareImages(scaled(ref, 1.1f), ref);
    EXPECT_EQ(thresholdExitCode(r, 0.2), 0);
    EXPECT_EQ(thresholdExitCode(r, 0.1 + 1e-5), 0);
    EXPECT_EQ(thresholdExitCode(r, 0.1 - 1e-5), 2);
    EXPECT_EQ(thresholdExitCode(r, 0.0), 2);
    const CompareResult same = compareImages(ref, ref);
    EXPECT_EQ(thresholdExitCode(same, 0.0), 0);
}

TEST(Compare, HeatMap) {
    const Image ref = discImage(40, 40);
    Image test = scaled(ref, 1.1f);
    test.at(20, 20, 0) *= 2.0f;  // one hot pixel
    const CompareResult r = compareImages(test, ref);
    const Image rel = relativeErrorImage(test, ref, r);
    ASSERT_EQ(rel.channels, 1);
    EXPECT_FLOAT_EQ(rel.at(0, 0, 0), -1.0f);  // background
    EXPECT_NEAR(rel.at(10, 20, 0), 0.1, 1e-5);
    EXPECT_GT(rel.at(20, 20, 0), 0.3f);
    const double scale = heatmapScale(rel);
    EXPECT_NEAR(scale, 0.1, 1e-12);  // 99th percentile 0.1 -> 0.1
    const Image heat = heatmapImage(rel, scale);
    ASSERT_EQ(heat.channels, 3);
    EXPECT_EQ(heat.at(0, 0, 0), 0.0f);  // background black
    // The hot pixel saturates at the top of the ramp (yellow), an ordinary pixel too
    // (error == scale); a zero-error pixel would be the dark-blue bottom.
    float top[3], bottom[3];
    viridis(1.0, top);
    viridis(0.0, bottom);
    EXPECT_NEAR(linearToSrgb(heat.at(20, 20, 0)), top[0], 1e-5);
    EXPECT_NEAR(linearToSrgb(heat.at(20, 20, 2)), top[2], 1e-5);
    const Image zero = heatmapImage(relativeErrorImage(ref, ref, compareImages(ref, ref)), 1.0);
    EXPECT_NEAR(linearToSrgb(zero.at(20, 20, 2)), bottom[2], 1e-5);

    // It writes as a PNG.
    const std::string path = (std::filesystem::current_path() / "prt_test_compare_heat.png").string();
    writePng(path, heat);
    EXPECT_TRUE(std::filesystem::exists(path));
    std::filesystem::remove(path);
}

TEST(Compare, HeatmapScaleRoundsUp) {
    Image rel(100, 1, 1, 0.0f);
    for (int x = 0; x < 100; ++x) rel.at(x, 0, 0) = 0.003f * (x + 1) / 100.0f;  // up to 0.003
    EXPECT_NEAR(heatmapScale(rel), 0.005, 1e-12);
    for (int x = 0; x < 100; ++x) rel.at(x, 0, 0) = 0.0f;
    EXPECT_NEAR(heatmapScale(rel), 1e-6, 1e-18);
}

// The papers' displayed-image RMS: identical images give 0; a constant offset of the
// displayed value gives that offset; background pixels (A = 0) are not counted; the
// exposure scales before the clamp.
TEST(ImageCompare, DisplayRmseMeasuresTheToneMappedImage) {
    Image a(4, 2, 4, 0.0f), b(4, 2, 4, 0.0f);
    for (int y = 0; y < 2; ++y)
        for (int x = 0; x < 4; ++x) {
            const bool object = x < 3;
            for (int c = 0; c < 3; ++c) {
                a.at(x, y, c) = 0.2f;
                b.at(x, y, c) = object ? srgbToLinear(linearToSrgb(0.2f) + 0.1f) : 5.0f;
            }
            a.at(x, y, 3) = b.at(x, y, 3) = object ? 1.0f : 0.0f;
        }
    EXPECT_NEAR(displayRmse(a, a, 0.0), 0.0, 1e-12);
    EXPECT_NEAR(displayRmse(b, a, 0.0), 0.1, 1e-5);
    // +3 stops: 0.2 x 8 clamps to 1 in both images.
    EXPECT_NEAR(displayRmse(b, a, 3.0), 0.0, 1e-6);
}
