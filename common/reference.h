#pragma once
// The brute-force reference renderer (SPEC section 6, "Reference renderer"): the
// ground truth that the precomputed transport (wavelets, kd-tree hierarchy,
// truncation, quantization) is measured against. Nothing here is clever on purpose.
//
// Multiple scattering (Wang et al. 2005, Eqs. 6-8, evaluated directly):
//
//   E_i = int_{hemisphere of n_i} F_t(eta, n_i . w) V(x_i, w) L(w) (n_i . w) dw
//         per surface sample x_i, RGB, from the FULL-RESOLUTION lat-long map (no
//         cubemap, no wavelets), by Monte Carlo (see IrradianceEstimatorOptions);
//   L_d(x_o, w_o) = F_t(eta, n_o . w_o) / pi * sum over ALL samples i of
//                   A_i R_d^c(|x_i - x_o|) E_i^c     (no hierarchy, no truncation),
//   A_i = total area / N.
//
// The lat-long map is treated as piecewise constant over its pixels (box
// reconstruction), as latLongIntegral and latLongToCubemap in envmap.h do, so the
// reference and the precomputation integrate the same radiance function. Rotating
// the environment by R means L'(d) = L(R^T d) (envmap.h).
//
// Noise. Every estimate carries its estimated variance: the sample variance of the
// irradiance estimator per point, propagated through the (linear) sum over samples
// (the E_i of different samples are independent: each point has its own random
// stream). renderReference reports the expected relative RMSE that this noise alone
// causes, the number to compare with prt-compare's relative RMSE.
//
// Determinism. Point i draws its directions from a counter-based generator seeded
// with (seed, i); the sum over samples runs serially per pixel. Results do not
// depend on the number of threads.
//
// Components. The outgoing radiance of a pixel is the sum of ReferenceComponents;
// multiple scattering is the only one today. Single scattering (Wang Eqs. 10-11,
// Monte Carlo along the refracted view ray) will be another ReferenceComponent.

#include <glm/glm.hpp>

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "common/bssrdf.h"
#include "common/image.h"
#include "common/mesh.h"
#include "common/raytrace.h"
#include "common/render.h"
#include "common/sampling.h"

namespace prt {

class Progress;

// ---------------------------------------------------------------------------
// Environment importance sampling
// ---------------------------------------------------------------------------

// Samples directions from a (rotated) lat-long environment with probability
// proportional to luminance x pixel solid angle: a 2D piecewise-constant
// distribution (marginal over rows, conditional over the pixels of a row), then a
// direction uniform in solid angle within the chosen pixel (uniform in longitude and
// in cos(polar angle)). The pdf with respect to solid angle is therefore constant
// over a pixel: pdf(d) = luminance(pixel(d)) / sum over pixels of luminance x solid
// angle. Luminance is Rec. 709 (bssrdf.h), positive wherever any channel is, so
// every direction with non-zero radiance can be drawn (channels must be >= 0, as
// loadEnvironment guarantees).
class EnvironmentSampler {
public:
    // `latlong`: RGB (at least 3 channels; the first 3 are used), width == 2 height,
    // values finite and >= 0 (throws prt::Error otherwise). The image is copied.
    explicit EnvironmentSampler(const Image& latlong, const glm::dmat3& rotation = glm::dmat3(1.0));

    struct Sample {
        glm::dvec3 direction{0.0};  // unit, world frame (rotation applied)
        glm::dvec3 radiance{0.0};   // L of the pixel it lies in
        double pdf = 0.0;           // per unit solid angle
    };
    // Maps four uniform numbers in [0, 1) to a sample. Requires !black().
    Sample sample(double u1, double u2, double u3, double u4) const;

    // Radiance along world direction d (need not be unit; non-zero): the value of the
    // lat-long pixel containing R^T d (piecewise constant, no filtering).
    glm::dvec3 radiance(const glm::dvec3& d) const;
    // The sampling density at d per unit solid angle (0 where the map is black).
    double pdf(const glm::dvec3& d) const;

    // True when the map is zero everywhere (nothing to sample).
    bool black() const { return totalWeight_ <= 0.0; }
    // sum over pixels of luminance x solid angle (the pdf's normalisation).
    double totalWeight() const { return totalWeight_; }
    // Integral of the radiance over the sphere per channel (sum of L x solid angle).
    glm::dvec3 integral() const { return integral_; }
    const glm::dmat3& rotation() const { return rotation_; }
    int width() const { return width_; }
    int height() const { return height_; }

private:
    size_t pixelOf(const glm::dvec3& worldDirection) const;

    int width_ = 0, height_ = 0;
    glm::dmat3 rotation_{1.0};
    std::vector<glm::vec3> rgb_;        // width x height, row-major, top row first
    std::vector<double> luminance_;     // per pixel
    std::vector<double> rowCdf_;        // height, inclusive running sums of row weights
    std::vector<double> columnCdf_;     // width per row, inclusive running sums within the row
    double totalWeight_ = 0.0;
    glm::dvec3 integral_{0.0};
};

// ---------------------------------------------------------------------------
// Irradiance at one surface point
// ---------------------------------------------------------------------------

// Monte Carlo estimation of E = int F_t(eta, n.w) V(w) L(w) max(0, n.w) dw with two
// strategies combined by the multi-sample balance heuristic (Veach 1997, sec. 9.2):
// a fixed number n_env of directions from EnvironmentSampler and n_cos from the
// cosine-weighted hemisphere about the shading normal; every direction d, whichever
// strategy drew it, contributes f(d) / (n_env p_env(d) + n_cos p_cos(d)). The sum of
// all contributions is an unbiased estimate of E (each strategy alone covers every
// direction where f > 0, as long as n_cos > 0 or the map is sampled where it is
// non-zero). Bright small sources are found by the environment strategy, dim wide
// regions and the horizon by the cosine strategy; neither is ever starved.
struct IrradianceEstimatorOptions {
    size_t directions = 2048;           // n_env + n_cos per point (>= 2)
    double environmentFraction = 0.5;   // n_env = round(fraction x directions), in [0, 1]
    uint64_t seed = 1;                  // of the Monte Carlo directions (not the sample placement)
    bool visibility = true;             // false: V = 1 (tests)
};

struct IrradianceEstimate {
    glm::dvec3 value{0.0};     // E per channel
    glm::dvec3 variance{0.0};  // estimated variance of `value` per channel
    uint64_t rays = 0;         // occlusion rays traced
};

// E at `position` with shading normal `normal` (unit; the hemisphere and cosine) and
// geometric normal `geometricNormal` (unit; the ray-origin offset). Visibility rays
// start at scene->offsetRayOrigin(position, geometricNormal, normal) (one origin
// for all rays, offset to the side the shading normal faces, as pass 1 does) with
// tnear = 0, tfar = infinity; scene may be null when options.visibility is false.
// `stream` selects the random stream (the sample index): the result is a pure
// function of (inputs, options.seed, stream).
IrradianceEstimate estimateIrradiance(const EnvironmentSampler& env, const RayScene* scene,
                                      const glm::vec3& position, const glm::vec3& normal,
                                      const glm::vec3& geometricNormal, double eta,
                                      const IrradianceEstimatorOptions& options, uint64_t stream);

struct SampleIrradiance {
    std::vector<glm::dvec3> value;     // E_i, one per sample
    std::vector<glm::dvec3> variance;  // its estimated variance
    uint64_t rays = 0;
    double seconds = 0.0;
    // Median over samples with E > 0 of the relative standard error of E's channel
    // sum (sqrt of the summed channel variances / the summed channels).
    double medianRelativeStandardError = 0.0;
};

// estimateIrradiance for every sample (stream = sample index), in parallel (TBB).
SampleIrradiance computeSampleIrradiance(const EnvironmentSampler& env, const RayScene* scene,
                                         const SampleSet& samples, double eta,
                                         const IrradianceEstimatorOptions& options,
                                         Progress* progress = nullptr);

// ---------------------------------------------------------------------------
// Components of the outgoing radiance
// ---------------------------------------------------------------------------

struct RadianceEstimate {
    glm::dvec3 value{0.0};
    glm::dvec3 variance{0.0};
};

// One term of the outgoing radiance at an object pixel. radiance() is called
// concurrently from several threads.
class ReferenceComponent {
public:
    virtual ~ReferenceComponent() = default;
    virtual std::string name() const = 0;
    // Outgoing radiance toward the viewer at a G-buffer hit (p.hit is true).
    virtual RadianceEstimate radiance(const GBufferPixel& p) const = 0;
};

// Multiple scattering by the brute-force dipole sum (top of file).
class MultipleScatteringReference : public ReferenceComponent {
public:
    // positions: the sample points x_i (mm); area: A_i = total area / N (mm^2);
    // irradiance: E_i (same count as positions).
    MultipleScatteringReference(const Material& material, std::vector<glm::vec3> positions,
                                double areaPerSample, SampleIrradiance irradiance);

    // (1/pi) sum_i A_i R_d(|x_i - x|) E_i per channel, with its variance
    // sum_i (A_i R_d / pi)^2 Var(E_i). The outgoing radiance is F_t(eta, n . w_o) times
    // this (radiance()).
    RadianceEstimate diffuse(const glm::vec3& x) const;

    // Per-vertex mode: evaluates diffuse() at every vertex of `mesh` (in parallel);
    // radiance() then interpolates the vertex values with the pixel's barycentric
    // weights, as the precomputed renderer does, instead of summing at the hit point.
    // The interpolated standard error is bounded by sum_k b_k sigma_k (the vertices'
    // errors are correlated: they share samples), which is what is reported.
    void evaluateAtVertices(const TriangleMesh& mesh, Progress* progress = nullptr);
    bool perVertex() const { return !vertexValue_.empty(); }

    std::string name() const override { return "multiple scattering"; }
    // F_t(eta, max(0, n . w_o)) x (diffuse(hit point), or the interpolated vertex values).
    RadianceEstimate radiance(const GBufferPixel& p) const override;

    const Material& material() const { return material_; }
    size_t sampleCount() const { return positions_.size(); }

private:
    Material material_;
    DipoleChannel dipole_[3];
    std::vector<glm::vec3> positions_;
    double area_ = 0.0;
    SampleIrradiance irradiance_;
    std::vector<glm::uvec3> triangles_;  // per-vertex mode: the mesh's triangles
    std::vector<glm::dvec3> vertexValue_, vertexSigma_;
};

// ---------------------------------------------------------------------------
// Frames
// ---------------------------------------------------------------------------

struct ReferenceFrame {
    Image image;          // RGBA: object pixels the summed components, A = 1; background A = 0
    Image standardError;  // RGB: estimated standard error of each object pixel (0 elsewhere)
    size_t objectPixels = 0;
    // The noise floor: sqrt(sum over object pixels and channels of the variance /
    // sum of value^2), i.e. the relative RMSE (as prt-compare measures it) expected
    // between this frame and the exact answer from Monte Carlo noise alone.
    double expectedRelativeRmse = 0.0;
    double medianRelativeStandardError = 0.0;  // per pixel: sqrt(sum_c var) / sum_c value
    double maxRelativeStandardError = 0.0;
    double seconds = 0.0;
};

// Shades every object pixel of `g` as the sum of `components` (in parallel, one
// progress unit per object pixel) and fills the background with the environment
// along the primary ray (environmentRadiance of render.h, `background` rotated by
// `envRotation`; empty background = black), A = 0 there.
ReferenceFrame renderReference(const GBuffer& g, const std::vector<const ReferenceComponent*>& components,
                               const Image& background, const glm::dmat3& envRotation,
                               Progress* progress = nullptr);

}  // namespace prt
