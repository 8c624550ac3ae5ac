#include "common/image_compare.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <sstream>
#include <vector>

#include "common/error.h"

namespace prt {

namespace {

int colourChannelsOf(const Image& image) { return image.channels >= 3 ? 3 : 1; }

// Index of the alpha channel, or -1.
int alphaChannelOf(const Image& image) {
    if (image.channels >= 4) return 3;
    if (image.channels == 2) return 1;
    return -1;
}

void checkImage(const Image& image, const char* which) {
    if (image.empty()) throw Error(which, "image is empty");
    if (!image.consistent()) throw Error(which, "image is inconsistent (pixel count does not match its size)");
}

// Which pixels are compared (see image_compare.h), and a description of the rule.
std::vector<uint8_t> maskOf(const Image& test, const Image& reference, const CompareOptions& options,
                            std::string& description) {
    const size_t count = size_t(reference.width) * reference.height;
    std::vector<uint8_t> mask(count, 1);
    const Image* source = nullptr;
    if (alphaChannelOf(reference) >= 0) {
        source = &reference;
        description = "reference alpha";
    } else if (alphaChannelOf(test) >= 0) {
        source = &test;
        description = "test alpha";
    } else {
        description = "all pixels";
        return mask;
    }
    const int a = alphaChannelOf(*source);
    for (int y = 0; y < source->height; ++y)
        for (int x = 0; x < source->width; ++x)
            mask[size_t(y) * source->width + x] = source->at(x, y, a) > options.alphaThreshold ? 1 : 0;
    return mask;
}

std::string formatNumber(double v, const char* format) {
    if (std::isinf(v)) return v > 0 ? "inf" : "-inf";
    if (std::isnan(v)) return "nan";
    char buf[64];
    std::snprintf(buf, sizeof buf, format, v);
    return buf;
}

}  // namespace

CompareResult compareImages(const Image& test, const Image& reference, const CompareOptions& options) {
    checkImage(test, "test image");
    checkImage(reference, "reference image");
    if (test.width != reference.width || test.height != reference.height)
        throw Error("compare", "image sizes differ: test " + std::to_string(test.width) + " x " +
                                   std::to_string(test.height) + ", reference " + std::to_string(reference.width) +
                                   " x " + std::to_string(reference.height));
    const int channels = colourChannelsOf(reference);
    if (colourChannelsOf(test) != channels)
        throw Error("compare", "colour channel counts differ: test " + std::to_string(colourChannelsOf(test)) +
                                   ", reference " + std::to_string(channels));
    if (!(options.relativeFloor >= 0.0)) throw Error("compare", "the relative-error floor must be >= 0");

    CompareResult r;
    r.width = reference.width;
    r.height = reference.height;
    r.colourChannels = channels;
    const std::vector<uint8_t> mask = maskOf(test, reference, options, r.mask);
    const int testAlpha = alphaChannelOf(test);

    // Pass 1: count, peak, finiteness.
    double peak = -std::numeric_limits<double>::infinity();
    for (int y = 0; y < r.height; ++y)
        for (int x = 0; x < r.width; ++x) {
            if (!mask[size_t(y) * r.width + x]) continue;
            ++r.comparedPixels;
            if (testAlpha >= 0 && !(test.at(x, y, testAlpha) > options.alphaThreshold)) ++r.coverageMismatch;
            for (int c = 0; c < channels; ++c) {
                const double a = test.at(x, y, c), b = reference.at(x, y, c);
                if (!std::isfinite(a) || !std::isfinite(b))
                    throw Error(std::isfinite(a) ? "reference image" : "test image",
                                "pixel (" + std::to_string(x) + ", " + std::to_string(y) + ") channel " +
                                    std::to_string(c) + " is not finite");
                peak = std::max(peak, b);
            }
        }
    if (r.comparedPixels == 0) throw Error("compare", "no pixel to compare (" + r.mask + " selects none)");
    r.peak = peak;

    // Pass 2: the sums.
    const double floor = options.relativeFloor * std::abs(peak);
    double sqErr[3] = {0, 0, 0}, sqRef[3] = {0, 0, 0}, sumA[3] = {0, 0, 0}, sumB[3] = {0, 0, 0};
    for (int y = 0; y < r.height; ++y)
        for (int x = 0; x < r.width; ++x) {
            if (!mask[size_t(y) * r.width + x]) continue;
            for (int c = 0; c < channels; ++c) {
                const double a = test.at(x, y, c), b = reference.at(x, y, c);
                const double e = std::abs(a - b);
                sqErr[c] += e * e;
                sqRef[c] += b * b;
                sumA[c] += a;
                sumB[c] += b;
                ChannelErrors& ch = r.channel[c];
                ch.maxAbsolute = std::max(ch.maxAbsolute, e);
                const double denominator = std::max(std::abs(b), floor);
                const double rel = e == 0.0 ? 0.0 : (denominator > 0.0 ? e / denominator
                                                                        : std::numeric_limits<double>::infinity());
                if (rel > ch.maxRelative || ch.maxRelativeX < 0) {
                    ch.maxRelative = rel;
                    ch.maxRelativeX = x;
                    ch.maxRelativeY = y;
                }
            }
        }

    auto relativeRmse = [](double err, double ref) {
        if (ref > 0.0) return std::sqrt(err / ref);
        return err == 0.0 ? 0.0 : std::numeric_limits<double>::infinity();
    };
    auto psnr = [&](double err, double n) {
        if (err == 0.0) return std::numeric_limits<double>::infinity();
        return 10.0 * std::log10(peak * peak / (err / n));
    };
    auto ratio = [](double a, double b) {
        if (b != 0.0) return a / b;
        return a == 0.0 ? 1.0 : std::numeric_limits<double>::infinity();
    };
    const double n = double(r.comparedPixels);
    double totalErr = 0, totalRef = 0, totalA = 0, totalB = 0;
    for (int c = 0; c < channels; ++c) {
        ChannelErrors& ch = r.channel[c];
        ch.relativeRmse = relativeRmse(sqErr[c], sqRef[c]);
        ch.psnr = psnr(sqErr[c], n);
        ch.meanRatio = ratio(sumA[c], sumB[c]);
        totalErr += sqErr[c];
        totalRef += sqRef[c];
        totalA += sumA[c];
        totalB += sumB[c];
        if (c == 0 || ch.maxAbsolute > r.overall.maxAbsolute) r.overall.maxAbsolute = ch.maxAbsolute;
        if (c == 0 || ch.maxRelative > r.overall.maxRelative) {
            r.overall.maxRelative = ch.maxRelative;
            r.overall.maxRelativeX = ch.maxRelativeX;
            r.overall.maxRelativeY = ch.maxRelativeY;
        }
    }
    r.overall.relativeRmse = relativeRmse(totalErr, totalRef);
    r.overall.psnr = psnr(totalErr, n * channels);
    r.overall.meanRatio = ratio(totalA, totalB);
    return r;
}

Image relativeErrorImage(const Image& test, const Image& reference, const CompareResult& result,
                         const CompareOptions& options) {
    std::string description;
    const std::vector<uint8_t> mask = maskOf(test, reference, options, description);
    const int channels = result.colourChannels;
    const double floor = options.relativeFloor * std::abs(result.peak) * channels;
    Image out(reference.width, reference.height, 1, -1.0f);
    for (int y = 0; y < out.height; ++y)
        for (int x = 0; x < out.width; ++x) {
            if (!mask[size_t(y) * out.width + x]) continue;
            double err = 0.0, ref = 0.0;
            for (int c = 0; c < channels; ++c) {
                err += std::abs(double(test.at(x, y, c)) - double(reference.at(x, y, c)));
                ref += reference.at(x, y, c);
            }
            const double denominator = std::max(ref, floor);
            out.at(x, y, 0) = float(err == 0.0 ? 0.0 : (denominator > 0.0 ? err / denominator : 1e30));
        }
    return out;
}

double heatmapScale(const Image& relativeError) {
    std::vector<float> values;
    for (float v : relativeError.pixels)
        if (v >= 0.0f) values.push_back(v);
    double p99 = 0.0;
    if (!values.empty()) {
        const size_t k = size_t(0.99 * double(values.size() - 1));
        std::nth_element(values.begin(), values.begin() + k, values.end());
        p99 = values[k];
    }
    if (!(p99 > 1e-6)) return 1e-6;
    const double decade = std::pow(10.0, std::floor(std::log10(p99)));
    for (double m : {1.0, 2.0, 5.0, 10.0})
        if (m * decade >= p99 * (1.0 - 1e-6)) return m * decade;  // float p99 of 0.1 -> 0.1
    return 10.0 * decade;
}

void viridis(double t, float rgb[3]) {
    // matplotlib's viridis (van der Walt and Smith, CC0) at t = 0, 0.1, ..., 1.
    static const float stops[11][3] = {
        {0.267004f, 0.004874f, 0.329415f}, {0.282623f, 0.140926f, 0.457517f},
        {0.253935f, 0.265254f, 0.529983f}, {0.206756f, 0.371758f, 0.553117f},
        {0.163625f, 0.471133f, 0.558148f}, {0.127568f, 0.566949f, 0.550556f},
        {0.134692f, 0.658636f, 0.517649f}, {0.266941f, 0.748751f, 0.440573f},
        {0.477504f, 0.821444f, 0.318195f}, {0.741388f, 0.873449f, 0.149561f},
        {0.993248f, 0.906157f, 0.143936f}};
    if (!(t > 0.0)) t = 0.0;  // NaN -> 0
    t = std::min(t, 1.0);
    const double pos = t * 10.0;
    const int i = std::min(9, int(pos));
    const double f = pos - i;
    for (int c = 0; c < 3; ++c) rgb[c] = float(stops[i][c] + f * (stops[i + 1][c] - stops[i][c]));
}

Image heatmapImage(const Image& relativeError, double scale) {
    if (!(scale > 0.0)) throw Error("--heatmap-scale", "must be positive");
    Image out(relativeError.width, relativeError.height, 3, 0.0f);
    for (int y = 0; y < out.height; ++y)
        for (int x = 0; x < out.width; ++x) {
            const float e = relativeError.at(x, y, 0);
            if (e < 0.0f) continue;  // not compared: black
            float rgb[3];
            viridis(e / scale, rgb);
            // writePng encodes linear values with sRGB; the ramp is given encoded.
            for (int c = 0; c < 3; ++c) out.at(x, y, c) = srgbToLinear(rgb[c]);
        }
    return out;
}

int thresholdExitCode(const CompareResult& result, double maxRelativeRmse) {
    return result.overall.relativeRmse <= maxRelativeRmse ? 0 : 2;
}

std::string formatCompareResult(const CompareResult& r) {
    std::ostringstream o;
    char line[256];
    std::snprintf(line, sizeof line, "compared %zu of %d x %d pixels (%s > 0.5), reference peak %.6g\n",
                  r.comparedPixels, r.width, r.height, r.mask.c_str(), r.peak);
    o << line;
    std::snprintf(line, sizeof line, "%-8s %11s %9s %11s %11s %-13s %11s\n", "channel", "rel RMSE", "PSNR dB",
                  "max abs", "max rel", " at (x, y)", "mean ratio");
    o << line;
    auto row = [&](const char* name, const ChannelErrors& e) {
        const std::string at = "(" + std::to_string(e.maxRelativeX) + ", " + std::to_string(e.maxRelativeY) + ")";
        std::snprintf(line, sizeof line, "%-8s %11s %9s %11s %11s %-13s %11s\n", name,
                      formatNumber(e.relativeRmse, "%.6f").c_str(), formatNumber(e.psnr, "%.2f").c_str(),
                      formatNumber(e.maxAbsolute, "%.4g").c_str(), formatNumber(e.maxRelative, "%.4g").c_str(),
                      (" " + at).c_str(), formatNumber(e.meanRatio, "%.6f").c_str());
        o << line;
    };
    static const char* names[3] = {"R", "G", "B"};
    if (r.colourChannels == 1) {
        row("Y", r.channel[0]);
    } else {
        for (int c = 0; c < r.colourChannels; ++c) row(names[c], r.channel[c]);
    }
    row("overall", r.overall);
    if (r.coverageMismatch > 0) {
        std::snprintf(line, sizeof line,
                      "warning: %zu compared pixels are background in the test image (different camera or mesh?)\n",
                      r.coverageMismatch);
        o << line;
    }
    return o.str();
}

double displayRmse(const Image& test, const Image& reference, const DisplayTransform& display) {
    const DisplayMapping mapping = displayMapping(reference, display);
    auto shown = [&](const Image& image, int x, int y) {
        const glm::vec3 d = mapping.apply({image.at(x, y, 0), image.at(x, y, 1), image.at(x, y, 2)});
        return glm::vec3(linearToSrgb(d.r), linearToSrgb(d.g), linearToSrgb(d.b));
    };
    double sum = 0.0;
    size_t n = 0;
    for (int y = 0; y < reference.height; ++y)
        for (int x = 0; x < reference.width; ++x) {
            if (!(reference.at(x, y, 3) > 0.5f)) continue;
            const glm::vec3 d = shown(test, x, y) - shown(reference, x, y);
            const double mean = (double(d.r) + double(d.g) + double(d.b)) / 3.0;
            sum += mean * mean;
            ++n;
        }
    return n ? std::sqrt(sum / double(n)) : 0.0;
}

double displayRmse(const Image& test, const Image& reference, double exposure) {
    return displayRmse(test, reference, DisplayTransform{exposure, ToneMapOperator::Clamp});
}

}  // namespace prt
