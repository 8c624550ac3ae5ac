// Display transforms: see tonemap.h.

#include "common/tonemap.h"

#include <algorithm>
#include <cmath>

#include "common/error.h"
#include "common/util.h"

namespace prt {

ToneMapOperator parseToneMapOperator(const std::string& name) {
    const std::string n = toLower(name);
    if (n == "clamp") return ToneMapOperator::Clamp;
    if (n == "reinhard") return ToneMapOperator::Reinhard;
    if (n == "filmic") return ToneMapOperator::Filmic;
    if (n == "chang") return ToneMapOperator::Chang;
    throw Error("--tonemap", "unknown operator '" + name + "' (clamp, reinhard, filmic, chang)");
}

const char* toneMapOperatorName(ToneMapOperator op) {
    switch (op) {
        case ToneMapOperator::Clamp: return "clamp";
        case ToneMapOperator::Reinhard: return "reinhard";
        case ToneMapOperator::Filmic: return "filmic";
        case ToneMapOperator::Chang: return "chang";
    }
    return "?";
}

namespace {

// Negatives and NaN -> 0, +Inf stays +Inf (the operators take it to 1).
float sanitized(float v) { return v > 0.0f ? v : 0.0f; }

float unit(float v) { return std::min(std::max(v, 0.0f), 1.0f); }

float acesFilmic(float x) {
    if (std::isinf(x)) return 1.0f;
    return unit(x * (2.51f * x + 0.03f) / (x * (2.43f * x + 0.59f) + 0.14f));
}

float rational(float x) { return std::isinf(x) ? 1.0f : x / (1.0f + x); }

glm::vec3 pixelColour(const Image& image, size_t p) {
    const float* v = &image.pixels[p * size_t(image.channels)];
    return image.channels >= 3 ? glm::vec3(v[0], v[1], v[2]) : glm::vec3(v[0]);
}

}  // namespace

glm::vec3 DisplayMapping::apply(const glm::vec3& linear) const {
    const glm::vec3 c(sanitized(linear.r) * scale, sanitized(linear.g) * scale, sanitized(linear.b) * scale);
    switch (op) {
        case ToneMapOperator::Clamp: return {unit(c.r), unit(c.g), unit(c.b)};
        case ToneMapOperator::Reinhard: {
            const float y = luminance(c);
            if (!(y > 0.0f)) return glm::vec3(0.0f);
            if (std::isinf(y)) return glm::vec3(std::isinf(c.r) ? 1.0f : 0.0f, std::isinf(c.g) ? 1.0f : 0.0f,
                                                std::isinf(c.b) ? 1.0f : 0.0f);
            const float k = 1.0f / (1.0f + y);  // Y_d / Y
            return {unit(c.r * k), unit(c.g * k), unit(c.b * k)};
        }
        case ToneMapOperator::Filmic: return {acesFilmic(c.r), acesFilmic(c.g), acesFilmic(c.b)};
        case ToneMapOperator::Chang: return {rational(c.r), rational(c.g), rational(c.b)};
    }
    return glm::vec3(0.0f);
}

double meanObjectLuminance(const Image& image) {
    const size_t count = size_t(std::max(image.width, 0)) * size_t(std::max(image.height, 0));
    double sum = 0.0;
    size_t n = 0;
    for (size_t p = 0; p < count; ++p) {
        if (image.channels >= 4 && !(image.pixels[p * size_t(image.channels) + 3] > 0.5f)) continue;
        const glm::vec3 c = pixelColour(image, p);
        const float y = luminance(glm::vec3(sanitized(c.r), sanitized(c.g), sanitized(c.b)));
        if (std::isfinite(y)) sum += double(y);
        ++n;
    }
    return n ? sum / double(n) : 0.0;
}

DisplayMapping displayMapping(const DisplayTransform& t, double radianceAverage) {
    if (!std::isfinite(t.exposureStops)) throw Error("--exposure", "must be finite");
    DisplayMapping m;
    m.op = t.op;
    double scale = std::exp2(t.exposureStops);
    if (t.op == ToneMapOperator::Chang && radianceAverage > 0.0 && std::isfinite(radianceAverage))
        scale /= radianceAverage;
    m.scale = float(scale);
    if (!std::isfinite(m.scale) || !(m.scale > 0.0f))
        throw Error("--exposure", "2^exposure (over the image's average for chang) is out of range");
    return m;
}

DisplayMapping displayMapping(const Image& image, const DisplayTransform& t) {
    return displayMapping(t, t.op == ToneMapOperator::Chang ? meanObjectLuminance(image) : 1.0);
}

Image displayImage(const Image& image, const DisplayMapping& mapping) {
    Image out(image.width, image.height, 3);
    const size_t count = size_t(image.width) * size_t(image.height);
    for (size_t p = 0; p < count; ++p) {
        const glm::vec3 d = mapping.apply(pixelColour(image, p));
        out.pixels[3 * p + 0] = d.r;
        out.pixels[3 * p + 1] = d.g;
        out.pixels[3 * p + 2] = d.b;
    }
    return out;
}

}  // namespace prt
