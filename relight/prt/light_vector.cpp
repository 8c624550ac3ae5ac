#include "relight/prt/light_vector.h"

#include <cmath>
#include <memory>
#include <string>
#include <utility>

#include "common/envmap.h"
#include "common/error.h"
#include "common/haar.h"
#include "common/sh_part.h"

namespace prt {

namespace {

void requireRgb(const Image& latlong) {
    if (latlong.channels != 3)
        throw Error("light vector", "the environment has " + std::to_string(latlong.channels) +
                                        " channels, expected RGB (3)");
}

// Whether the sparse filter can take this map and N; input it cannot take, and that the
// exact path rejects, goes to latLongToCubemap for its messages.
bool filterFits(const Image& latlong, int n) {
    return latlong.consistent() && !latlong.empty() && isPowerOfTwo(n) &&
           latlong.width <= LatLongCubemapFilter::kMaxLatLongSize &&
           latlong.height <= LatLongCubemapFilter::kMaxLatLongSize;
}

}  // namespace

LightVector makeLightVector(const Image& latlong, int n, const glm::dmat3& rotation,
                            size_t keepTerms) {
    requireRgb(latlong);
    // Rotations about +Y (all the viewer and prt-relight use) take the cached sparse
    // filter, far cheaper than the exact resampling (docs/relight.md, "Turning the
    // environment: the fast path").
    double degrees = 0.0;
    if (filterFits(latlong, n) && rotationAboutY(rotation, degrees)) {
        const std::shared_ptr<const LatLongCubemapFilter> filter =
            LatLongCubemapFilter::shared(latlong.width, latlong.height, n);
        return makeLightVector(filter->apply(latlong, degrees), keepTerms);
    }
    return makeLightVector(latLongToCubemap(latlong, n, rotation), keepTerms);
}

EnvironmentLight::EnvironmentLight(Image latlong, int n) : latlong_(std::move(latlong)), n_(n) {
    requireRgb(latlong_);
    if (!latlong_.consistent() || latlong_.empty())
        throw Error("light vector", "empty or inconsistent environment image (" +
                                        std::to_string(latlong_.width) + " x " + std::to_string(latlong_.height) +
                                        ", " + std::to_string(latlong_.pixels.size()) + " values)");
    if (!isPowerOfTwo(n_))
        throw Error("light vector", "cubemap size " + std::to_string(n_) + " is not a power of two");
    if (!filterFits(latlong_, n_)) return;  // beyond the filter's size limit: always exact
    sums_ = std::make_unique<const LatLongRowSums>(latlong_);
    filter_ = LatLongCubemapFilter::shared(latlong_.width, latlong_.height, n_);
}

EnvironmentLight::~EnvironmentLight() = default;
EnvironmentLight::EnvironmentLight(EnvironmentLight&&) noexcept = default;
EnvironmentLight& EnvironmentLight::operator=(EnvironmentLight&&) noexcept = default;

LightVector EnvironmentLight::lightVector(const glm::dmat3& rotation, size_t keepTerms) const {
    double degrees = 0.0;
    if (filter_ && rotationAboutY(rotation, degrees))
        return makeLightVector(filter_->apply(*sums_, degrees), keepTerms);
    return makeLightVector(latLongToCubemap(latlong_, n_, rotation), keepTerms);
}

size_t EnvironmentLight::memoryBytes() const {
    return sizeof(*this) + latlong_.pixels.capacity() * sizeof(float) + (sums_ ? sums_->memoryBytes() : 0);
}

LightVector makeLightVector(const Cubemap& radiance, size_t keepTerms) {
    if (radiance.channels() != 3)
        throw Error("light vector", "the cubemap has " + std::to_string(radiance.channels()) +
                                        " channels, expected RGB (3)");
    if (radiance.size() < 1 || radiance.data().size() != radiance.texelCount() * 3)
        throw Error("light vector", "empty or inconsistent cubemap");

    Cubemap coefficients = radiance;
    haarForward(coefficients);

    LightVector light;
    light.size = radiance.size();
    const size_t count = coefficients.texelCount();
    std::vector<float>& full = coefficients.data();
    // As many SH terms as are independent on this cubemap (minShCubemapSize): a file of
    // this N holds at most these.
    const int shTerms = light.size >= 4 ? kMaxShTerms : light.size >= 2 ? 9 : 4;
    light.sh.resize(size_t(shTerms) * 3);
    shProjectLight(full.data(), light.size, 3, shTerms, light.sh.data());

    if (keepTerms == 0 || keepTerms >= count) {
        light.rgb = std::move(full);
        light.relativeL2Error = 0.0;
    } else {
        const SparseVector kept = truncateLargest(full.data(), count, 3, keepTerms);
        light.rgb.assign(full.size(), 0.0f);
        for (size_t e = 0; e < kept.size(); ++e)
            for (int c = 0; c < 3; ++c)
                light.rgb[3 * size_t(kept.index[e]) + c] = kept.value[3 * e + c];
        // Parseval: the Haar basis is orthonormal, so ||L - L_approx|| in texel space is
        // the norm of the dropped coefficients. Summed directly (not total - kept) so a
        // tiny error is not lost to cancellation.
        double total = 0.0, dropped = 0.0;
        for (size_t t = 0; t < full.size(); ++t) {
            const double x = full[t];
            total += x * x;
            const double d = x - double(light.rgb[t]);
            dropped += d * d;
        }
        light.relativeL2Error = total > 0.0 ? std::sqrt(dropped / total) : 0.0;
    }

    light.keptTerms = 0;
    for (size_t k = 0; k < count; ++k) {
        const float* v = &light.rgb[3 * k];
        if (v[0] != 0.0f || v[1] != 0.0f || v[2] != 0.0f) ++light.keptTerms;
    }
    return light;
}

}  // namespace prt
