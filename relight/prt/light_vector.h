#pragma once
// Light vectors (Ng et al. 2003; Wang et al. 2005, "Rendering"): an environment,
// rotated, resampled onto the 6 x N x N cubemap with area-correct filtering and
// Haar-transformed per face, optionally non-linearly approximated by its largest L
// terms. Relighting is then a dot product of a transport vector with this vector.
//
// Units: the cubemap holds mean radiance per texel (the transport vectors already
// fold in each texel's solid angle). Rotation convention: L'(d) = L(R^T d)
// (docs/conventions.md).

#include <glm/glm.hpp>

#include <cstddef>
#include <memory>
#include <vector>

#include "common/cubemap.h"
#include "common/image.h"

namespace prt {

class LatLongCubemapFilter;
class LatLongRowSums;

struct LightVector {
    int size = 0;                 // N
    std::vector<float> rgb;       // 6 N^2 Haar coefficients x 3, RGB interleaved
    size_t keptTerms = 0;         // non-zero coefficients after approximation
    double relativeL2Error = 0;   // of the approximation, ||L - L_approx|| / ||L|| (Parseval)
    // The light's SH projections l_i = <W^_i, L^> (common/sh_part.h), kMaxShTerms x 3
    // (RGB per term; 9 x 3 for N = 2, 4 x 3 for N = 1), of the whole light even when it is approximated:
    // what the SH part of a transport file relights against. makeLightVector fills it;
    // the relight kernel derives it from `rgb` when it is empty (a hand-built vector).
    std::vector<float> sh;

    size_t coefficientCount() const { return rgb.size() / 3; }
};

// From a lat-long environment (see envmap.h). keepTerms = 0 keeps every coefficient;
// otherwise the largest keepTerms by RGB magnitude (Euclidean norm over channels).
//
// Resampling: when `rotation` is a rotation about +Y (rotationAboutY, which includes
// the identity and any product of rotationY matrices) the cubemap comes from the
// process-wide LatLongCubemapFilter::shared(width, height, n), which the first call for
// a (width, height, n) builds (docs/performance.md, "Design measurements"). For angles
// that are whole lat-long pixels (360 k / width degrees) the result equals the exact
// latLongToCubemap to ~1e-7 relative; between them it is the exact filter of the map
// linearly interpolated in longitude (common/envmap.h; docs/relight.md, "Turning the
// environment: the fast path"). Any other rotation uses latLongToCubemap. For the exact
// filter at any angle, use makeLightVector(latLongToCubemap(latlong, n, rotation),
// keepTerms).
LightVector makeLightVector(const Image& latlong, int n, const glm::dmat3& rotation = glm::dmat3(1.0),
                            size_t keepTerms = 0);
// From an RGB radiance cubemap (3 channels).
LightVector makeLightVector(const Cubemap& radiance, size_t keepTerms = 0);
//
// An environment prepared for many light vectors under turns about +Y (the viewer's
// slider, prt-relight's spin and turntable frames, benchmarks): it keeps the map, the
// shared LatLongCubemapFilter for its size and N, and the map's row running sums
// (LatLongRowSums), so each light vector costs the filter's running-sum apply (cheaper
// than makeLightVector(latlong, ...)'s) and the Haar transform.
//
// lightVector(rotation, keepTerms) equals makeLightVector(image(), n, rotation, keepTerms)
// up to float rounding for every rotation: about +Y through the running sums, anything
// else through latLongToCubemap like makeLightVector. Building costs one pass over the
// map for the running sums plus, for the first (width, height, N) in the process, the
// filter. Memory: the image, the running sums (8 (2 width + 2) height x 3 bytes, 25 MB
// for 1024 x 512) and a share of the filter.
//
// Thread-safe: lightVector may be called concurrently (everything is immutable after
// construction). The constructor throws prt::Error("light vector", ...) for an image
// that is not RGB, empty or inconsistent, or an n that is not a power of two, and
// LatLongRowSums' error for a row with a non-finite sum.
class EnvironmentLight {
public:
    EnvironmentLight(Image latlong, int n);
    ~EnvironmentLight();
    EnvironmentLight(EnvironmentLight&&) noexcept;
    EnvironmentLight& operator=(EnvironmentLight&&) noexcept;

    LightVector lightVector(const glm::dmat3& rotation = glm::dmat3(1.0), size_t keepTerms = 0) const;

    const Image& image() const { return latlong_; }
    int size() const { return n_; }
    size_t memoryBytes() const;  // the image and the running sums (not the shared filter)

private:
    Image latlong_;
    int n_ = 0;
    std::shared_ptr<const LatLongCubemapFilter> filter_;  // null beyond the filter's size limit
    std::unique_ptr<const LatLongRowSums> sums_;          // with filter_
};

// All three: keepTerms >= 6 N^2 is the same as 0. Zero coefficients are never "kept", so
// keptTerms can be below keepTerms (a constant environment has 6 non-zero terms).
// Ties in magnitude go to the lower index (truncateLargest). relativeL2Error is 0 for
// an all-zero environment. Throws prt::Error("light vector", ...) for input that is
// not RGB, and latLongToCubemap's errors (n not a power of two, bad image).

}  // namespace prt
