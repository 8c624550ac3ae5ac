#pragma once
// Display transforms: how linear radiance becomes the values an 8-bit PNG or the viewer
// shows (docs/conventions.md, "Display"). Every PNG writer and the viewer go through
// here; EXR files and every error figure stay linear.
//
// A pixel's linear RGB L (W / (m^2 sr), any scale) is first multiplied by
// s = 2^exposureStops, then mapped by the operator to display-linear values in [0, 1],
// then sRGB-encoded (linearToSrgb, common/image.h) and rounded to 8 bits by the writer:
//
//   clamp     min(max(sL, 0), 1) per channel (the project's historical display).
//   reinhard  Reinhard et al. 2002, "Photographic tone reproduction", eq. 3 (global, no
//             white point): on the luminance Y = 0.2126 R + 0.7152 G + 0.0722 B of sL,
//             Y_d = Y / (1 + Y); the colour is scaled by Y_d / Y (hue kept), then clamped.
//             Exposure plays the role of the key; no automatic log-average.
//   filmic    the ACES filmic curve as fitted by K. Narkowicz (2015), per channel:
//             f(x) = x (2.51 x + 0.03) / (x (2.43 x + 0.59) + 0.14), clamped to [0, 1],
//             applied to x = sL without Narkowicz's extra 0.6 pre-scale.
//   chang     Chang et al. 2008, Sec. 3, "Evaluating Translucency" (DirectX's HDR
//             Lighting): R_scale = sL / Radiance_avg, Color = R_scale / (1 + R_scale) per
//             channel. The paper prints Color = (1 + R_scale) / R_scale, a typo: it is
//             not in [0, 1] and decreases with radiance; we implement R / (1 + R).
//             Radiance_avg is the mean luminance of the object's pixels (alpha > 0.5 when
//             the image has 4 channels, else every pixel) of the image being shown; the
//             paper approximates it by the mean irradiance of its samples. Exposure acts
//             as a key on top.
//
// Negative and NaN inputs display as 0 under every operator; +Inf as 1.

#include <glm/glm.hpp>

#include <string>

#include "common/image.h"

namespace prt {

enum class ToneMapOperator { Clamp, Reinhard, Filmic, Chang };

// "clamp", "reinhard", "filmic" or "chang" (case-insensitive). Throws
// prt::Error("--tonemap", "unknown operator 'X' (clamp, reinhard, filmic, chang)").
ToneMapOperator parseToneMapOperator(const std::string& name);
const char* toneMapOperatorName(ToneMapOperator op);

// What the user asked for (--exposure, --tonemap).
struct DisplayTransform {
    double exposureStops = 0.0;
    ToneMapOperator op = ToneMapOperator::Clamp;
};

// One image's mapping: the transform with its image-dependent scale resolved (Chang's
// Radiance_avg), so test and reference images can be shown through the same mapping.
struct DisplayMapping {
    ToneMapOperator op = ToneMapOperator::Clamp;
    float scale = 1.0f;  // 2^exposure, divided by Radiance_avg for chang
    // Display-linear values in [0, 1] of a linear colour.
    glm::vec3 apply(const glm::vec3& linear) const;
};

// Rec. 709 / sRGB luminance.
inline float luminance(const glm::vec3& c) { return 0.2126f * c.r + 0.7152f * c.g + 0.0722f * c.b; }

// Chang's Radiance_avg of an image: the mean luminance of its object pixels (channels 0-2,
// or channel 0 replicated for 1-2 channels; object = alpha > 0.5 for 4+ channels, every
// pixel otherwise), non-finite and negative values counted as 0. 0 when there is no
// object pixel.
double meanObjectLuminance(const Image& image);

// The mapping of `image` under `t`. For chang, an image whose Radiance_avg is 0 (black
// or no object pixel) maps with Radiance_avg = 1. Throws prt::Error("--exposure", ...)
// for a non-finite exposure.
DisplayMapping displayMapping(const Image& image, const DisplayTransform& t);
// The mapping with a given Radiance_avg (chang; ignored by the other operators), for
// displays that know it without an image (the viewer).
DisplayMapping displayMapping(const DisplayTransform& t, double radianceAverage);

// The image as display values: 3 channels, display-linear in [0, 1], not sRGB-encoded.
Image displayImage(const Image& image, const DisplayMapping& mapping);

}  // namespace prt
