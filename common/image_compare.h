#pragma once
// Image comparison for validation (SPEC section 6): a test image (e.g. prt-relight
// render) against a reference (prt-reference), over the object's pixels.
//
// Channels. Images with 3 or more channels are compared on R, G, B (channels 0-2);
// 1-channel (Y) and 2-channel (Y A) images on channel 0. Alpha is channel 3 of a
// 4+-channel image and channel 1 of a 2-channel one. Both images must have the same
// width, height and number of colour channels.
//
// Mask. A pixel is compared when the reference's alpha is > 0.5; when the reference
// has no alpha the test image's alpha is used; when neither has one, every pixel is.
//
// Measures, per colour channel and over all colour channels together ("overall"),
// with a = test, b = reference, sums over the compared pixels:
//   relative RMSE  sqrt(sum (a - b)^2 / sum b^2)          (0 when both sums are 0,
//                                                          infinite when only sum b^2 is)
//   PSNR           10 log10(peak^2 / mean (a - b)^2) dB,   peak = the largest reference
//                  value over the compared pixels and colour channels (one peak for all
//                  channels, so channel PSNRs are comparable); infinite when a == b
//   max abs error  max |a - b|
//   max rel error  max |a - b| / max(|b|, relativeFloor x peak): the floor keeps
//                  near-black reference values from dominating; default 1e-3
//   mean ratio     sum a / sum b (the ratio of the mean values; 1 = no global bias)
// Any NaN or infinite value in a compared pixel of either image is an error.

#include <cstddef>
#include <string>

#include "common/image.h"
#include "common/tonemap.h"

namespace prt {

struct CompareOptions {
    double alphaThreshold = 0.5;
    double relativeFloor = 1e-3;  // of the peak, for the max relative error
};

struct ChannelErrors {
    double relativeRmse = 0.0;
    double psnr = 0.0;  // dB, +infinity for identical values
    double maxAbsolute = 0.0;
    double maxRelative = 0.0;
    double meanRatio = 1.0;  // sum test / sum reference (1 when both are 0, inf when only the reference's is)
    int maxRelativeX = -1, maxRelativeY = -1;  // where maxRelative occurs
};

struct CompareResult {
    int width = 0, height = 0;
    int colourChannels = 0;  // 3 (RGB) or 1 (gray)
    std::string mask;        // "reference alpha", "test alpha" or "all pixels"
    size_t comparedPixels = 0;
    // Compared pixels that the test image marks as background (its alpha <= threshold):
    // a coverage mismatch (different camera or mesh placement) when non-zero.
    size_t coverageMismatch = 0;
    double peak = 0.0;
    ChannelErrors channel[3];  // the first colourChannels entries are used
    ChannelErrors overall;
};

// Compares test against reference (see the top of the file). Throws prt::Error for
// empty or inconsistent images, different sizes or colour channel counts, no pixel to
// compare, or non-finite values in a compared pixel.
CompareResult compareImages(const Image& test, const Image& reference, const CompareOptions& options = {});

// Per-pixel relative error (1 channel) of a compared pixel: sum_c |a_c - b_c| /
// max(sum_c b_c, options.relativeFloor x peak x channels); -1 for pixels outside the
// mask. `result` is compareImages(test, reference, options).
Image relativeErrorImage(const Image& test, const Image& reference, const CompareResult& result,
                         const CompareOptions& options = {});

// A scale for the heat map: the 99th percentile of the relative error over the
// compared pixels, rounded up to 1, 2 or 5 times a power of ten (at least 1e-6).
double heatmapScale(const Image& relativeError);

// RGB heat map (linear values, for writePng): compared pixels coloured by
// min(error / scale, 1) on the viridis ramp (dark blue 0 -> yellow at scale and
// above); other pixels black.
Image heatmapImage(const Image& relativeError, double scale);

// One colour of the viridis ramp, t in [0, 1] (clamped), as display (sRGB-encoded)
// values.
void viridis(double t, float rgb[3]);

// prt-compare's exit code for a threshold on the overall relative RMSE: 0 when
// result.overall.relativeRmse <= maxRelativeRmse, 2 when above (or NaN).
int thresholdExitCode(const CompareResult& result, double maxRelativeRmse);

// Multi-line table of the result (for prt-compare and logs).
std::string formatCompareResult(const CompareResult& r);

// The papers' RMS (Keng et al. 2006 Table 1, Chang et al. 2008 Figs. 7-14): over the
// reference's object pixels (A > 0.5), the RMS of the mean of R, G, B of the DISPLAYED
// images, i.e. writePng's display transform without its 8-bit rounding: both images
// through the REFERENCE's mapping (common/tonemap.h; for chang the reference's
// Radiance_avg, so an overall scale error is not normalised away), then sRGB-encoded.
// It depends on the transform; non-finite values count as 0. The exposure-only form
// is the clamp operator.
double displayRmse(const Image& test, const Image& reference, const DisplayTransform& display);
double displayRmse(const Image& test, const Image& reference, double exposure);

}  // namespace prt
