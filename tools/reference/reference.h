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
// Components. The outgoing radiance of a pixel is the sum of ReferenceComponents:
// multiple scattering (above) and single scattering (SingleScatteringReference below:
// Wang Eq. 4 with Eq. 5, Monte Carlo along the refracted view ray, exact
// Henyey-Greenstein phase).

#include <glm/glm.hpp>

#include <functional>

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "common/bssrdf.h"
#include "common/image.h"
#include "common/mesh.h"
#include "common/raytrace.h"
#include "relight/render/gbuffer.h"
#include "relight/pointlight/point_lights.h"
#include "tools/reference/dipole_sum.h"
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
// Irradiance from point and directional lights
// ---------------------------------------------------------------------------

// The transmitted direct irradiance of point and directional lights (units of
// relight/pointlight/point_lights.h: I in W/sr at a position in mm, E_perp in W/m^2;
// the result in W/m^2), written here again rather than taken from the point-light
// renderers' directIrradiance, so that the reference shares only Embree, the Fresnel
// formula and the spot falloff (spotFalloff, the light's definition) with what it judges:
//
//   E = sum over lights of F_t(eta, n . w) V(x, w) (n . w) E_light,   n . w > 0,
//   E_light = 1e6 I / r^2 (point light at distance r mm), 1e6 I_0 falloff(-w) / r^2
//   (spot light) or E_perp (directional),
//
// exactly (no Monte Carlo: the variance is 0). Visibility is the environment
// reference's: one ray origin scene->offsetRayOrigin(position, geometricNormal, normal)
// for every light, tnear 0, tfar = r (1 - 1e-6) toward a point or spot light and infinity
// toward a directional one. A light at the shading horizon or below gives nothing.
// The Fresnel factor is always the exact one (the renderers' Keng model is another
// physical model, not an approximation a reference could judge). scene may be null
// when `visibility` is false (tests); rays, when given, counts the occlusion rays.
glm::dvec3 lightIrradiance(const std::vector<Light>& lights, const RayScene* scene, const glm::vec3& position,
                           const glm::vec3& normal, const glm::vec3& geometricNormal, double eta,
                           bool visibility = true, uint64_t* rays = nullptr);

// lightIrradiance at every sample, in parallel (TBB; the result does not depend on the
// thread count), as a SampleIrradiance with zero variances. Throws prt::Error for an
// empty light list.
SampleIrradiance computeLightIrradiance(const std::vector<Light>& lights, const RayScene& scene,
                                        const SampleSet& samples, double eta, Progress* progress = nullptr);

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
    // this (radiance()). Samples whose E_i and Var(E_i) are zero in every channel (in
    // shadow, or facing away from every light) add exactly nothing and are left out at
    // construction. The sum is dipoleSum (tools/reference/dipole_sum.h: the same
    // formula as dipoleRd, each term in single precision within ~1e-6 of it, far below
    // any quadrature error the reference reports; blocks added in double) on the
    // fastest instruction set of the CPU; diffuseScalar is the plain double loop over
    // dipoleRd that tests hold it to.
    RadianceEstimate diffuse(const glm::vec3& x) const;
    RadianceEstimate diffuseScalar(const glm::vec3& x) const;

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
    // Samples given at construction, and those kept in the sum (E or Var(E) non-zero).
    size_t sampleCount() const { return sampleCount_; }
    size_t contributingSamples() const { return contributing_; }

private:
    Material material_;
    DipoleChannel dipole_[3];
    size_t sampleCount_ = 0, contributing_ = 0;
    double area_ = 0.0;
    DipoleSumChannel channels_[3];
    DipoleSumIsa isa_ = DipoleSumIsa::Portable;
    DipoleSumSamples samples_;  // the contributing samples: positions (mm), E and Var(E)
    std::vector<glm::uvec3> triangles_;  // per-vertex mode: the mesh's triangles
    std::vector<glm::dvec3> vertexValue_, vertexSigma_;
};

// ---------------------------------------------------------------------------
// Single scattering
// ---------------------------------------------------------------------------

// Wang et al. 2005, Eq. 4 with Eq. 5 (their Fig. 2a / Fig. 5a, after Jensen et al.
// 2001), evaluated by Monte Carlo for an object pixel with hit point x_o, shading
// normal n_o and direction to the eye w_o:
//
//   L1(x_o, w_o) = sigma_s^c F_t(eta, n_o.w_o) int_{4 pi} int_0^d
//                  p(a, -w_o') F_t(eta, n_i.w) e^(-sigma_t^c (s_i' + s)) L^c(w) V ds dw
//
//   w_o' = refractDirection(w_o, n_o, eta)   (into the medium; none -> 0)
//   x_p  = x_o + s P,  P = w_o' (true path, default) or -n_o (Wang's precomputation
//          path, Fig. 2b: SingleScatteringPath::Normal), s in [0, d], d the distance
//          along P to where that ray leaves the object;
//   w    a world direction toward the light; the ray x_p + t w (NOT refracted: the
//        "observed" path of Eq. 5) leaves the object at x_i after s_i = t, where the
//        interpolated normal is n_i;
//   s_i' = s_i |w.n_i| / sqrt(1 - (1/eta)^2 (1 - |w.n_i|^2))   (Eq. 5; exact for a
//          flat surface and distant light, where it is the refracted path's length);
//   a    = refractDirection(w, n_i, eta), the light's propagation direction inside;
//   p    = henyeyGreensteinDirections(g, a, -w_o'): theta between the propagation
//          directions before (a) and after (-w_o', toward the eye) scattering, g > 0
//          forward (common/bssrdf.h). In Normal mode only the path changes: the phase
//          still uses the true w_o' (what the precomputation's h_k(w_o') factor stands
//          for), as do F_t(eta, n_o.w_o) and sigma_s;
//   V    = 1 when the ray from x_i toward w meets nothing more.
//
// As in Eq. 4, dw is the solid angle OUTSIDE the object and there is no
// refraction Jacobian (cos_i / cos_t) for the change of solid angle at x_i; this is
// the formula the precomputation (Eqs. 10-11) approximates, so the two stay
// comparable. sigma_s = sigma_s' / (1 - g) and sigma_t = sigma_a + sigma_s
// (Material); the material's g is used.
//
// Estimator. M path samples s_m, stratified in the inverse CDF of the truncated
// exponential pdf(s) = |sigma_t| e^(-|sigma_t| s) / (1 - e^(-|sigma_t| d)),
// s = -ln(1 - lambda xi) / |sigma_t|, xi = (m + u_m) / M (|sigma_t| = luminance of
// sigma_t, the precomputation's choice). At each x_p, L directions: round(f L) from
// the EnvironmentSampler (luminance x solid angle) and the rest uniform on the sphere,
// combined by the multi-sample balance heuristic: each contributes
// f(w) / (n_env p_env(w) + n_uni / (4 pi)). Rays: one Embree intersect per path (d),
// per direction one intersect (x_i) and, when the unoccluded contribution is not
// zero, one occlusion ray from offsetRayOrigin(x_i, geometric normal, w). A
// direction contributes nothing when its ray leaves through a triangle whose
// geometric normal faces away from w (x_p was not inside: open or broken meshes)
// or through a point with n_i.w <= 0 (no refraction with the shading normal); the
// path is empty (0) when P points out of the surface geometrically (P . n_g >= 0) or
// its ray never hits the mesh again (open meshes). Geometric normals are first
// turned to the side of the interpolated normal (triangles wound against their
// vertex normals). The path ends at the first surface it meets: on self-intersecting
// meshes (folded sheets) that can be very short, and such pixels come out dark.
//
// Noise. Y_m = (1/pdf(s_m)) sum over the L directions of their contributions, the
// estimate is the mean of the Y_m, and its variance is estimated from the differences
// of neighbouring strata, sum over pairs (Y_2j - Y_2j+1)^2 / M^2 (the usual
// estimator for one sample per stratum, slightly conservative: it treats each pair
// as one stratum of twice the width). See docs/reference.md for how it compares
// with the spread between seeds.
//
// Determinism. A pixel draws from a SplitMix64 stream seeded with (seed, a hash of
// the pixel's hit point, normal, direction to the eye and triangle): a pure
// function of the pixel's G-buffer entry, independent of threads and image layout.
enum class SingleScatteringPath {
    Refracted,  // along w_o' (Wang Eq. 4, Fig. 2a / 5a): the reference
    Normal,     // along -n_o (Wang's precomputation, Fig. 2b / 5b)
};
enum class SingleScatteringPhase {
    HenyeyGreenstein,  // HG with the material's g
    Isotropic,         // explicit 1 / (4 pi) (tests)
};

struct SingleScatteringReferenceOptions {
    size_t pathSamples = 64;            // M per pixel (>= 1), stratified
    size_t lightSamples = 16;           // L directions per path sample (>= 1)
    double environmentFraction = 0.75;  // share of the L drawn from the environment, in [0, 1]
    SingleScatteringPath path = SingleScatteringPath::Refracted;
    SingleScatteringPhase phase = SingleScatteringPhase::HenyeyGreenstein;
    uint64_t seed = 1;                  // of the Monte Carlo numbers
    bool visibility = true;             // false: V = 1 (tests)
};

const char* toString(SingleScatteringPath path);

class SingleScatteringReference : public ReferenceComponent {
public:
    // `mesh` (mm) supplies the triangles and vertex normals for n_i and the geometric
    // normals of the G-buffer's triangles; `scene` must be built from the same mesh.
    // Both, and `env`, must outlive this object. Throws prt::Error for invalid options
    // or material.
    SingleScatteringReference(const Material& material, const TriangleMesh& mesh, const RayScene& scene,
                              const EnvironmentSampler& env, const SingleScatteringReferenceOptions& options);

    std::string name() const override { return "single scattering"; }
    // estimate(p.position, p.normal, geometric normal of p.triangle, p.toViewer,
    // pixelStream(p)).
    RadianceEstimate radiance(const GBufferPixel& p) const override;

    // The estimate at x_o (mm) with unit shading normal n_o, unit geometric normal
    // ng (the ray-origin offset) and unit direction to the eye w_o, from random
    // stream `stream`.
    RadianceEstimate estimate(const glm::vec3& position, const glm::vec3& normal, const glm::vec3& geometricNormal,
                              const glm::vec3& toViewer, uint64_t stream) const;

    // The stream radiance() uses for a pixel (a hash of its G-buffer entry).
    static uint64_t pixelStream(const GBufferPixel& p);

    const SingleScatteringReferenceOptions& options() const { return options_; }
    const Material& material() const { return material_; }
    // Counters since construction (all threads): rays traced (intersections and
    // occlusion rays) and path samples taken.
    uint64_t raysTraced() const { return rays_.load(std::memory_order_relaxed); }
    uint64_t pathSamplesTaken() const { return paths_.load(std::memory_order_relaxed); }

private:
    Material material_;
    glm::dvec3 sigmaS_{0.0}, sigmaT_{0.0};
    double sigmaTLuminance_ = 0.0;
    const TriangleMesh* mesh_;
    const RayScene* scene_;
    const EnvironmentSampler* env_;
    SingleScatteringReferenceOptions options_;
    mutable std::atomic<uint64_t> rays_{0}, paths_{0};
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

// The diffuse baseline (prt-precompute --baseline diffuse-brdf) traced directly: at each
// pixel's own surface point x and interpolated normal n,
//   L_o = (albedo / pi) E(x),  E = integral of L(w) V(x, w) max(0, n . w) dw,
// E by estimateIrradiance with eta = 1 (no Fresnel) and `options` (its own directions
// and seed; the stream is a hash of the pixel's triangle and barycentrics). It shares
// with the precomputed baseline only the mesh, its vertex normals, the albedo and the
// renderers' silhouette convention (a pixel whose interpolated normal faces away from
// the viewer is black): no cubemap, no Haar truncation, no interpolation between
// vertices.
class DiffuseBrdfReference : public ReferenceComponent {
public:
    DiffuseBrdfReference(const EnvironmentSampler& env, const RayScene& scene, const glm::dvec3& albedo,
                         const IrradianceEstimatorOptions& options)
        : env_(env), scene_(scene), albedo_(albedo), options_(options) {}
    std::string name() const override { return "diffuse-brdf"; }
    RadianceEstimate radiance(const GBufferPixel& p) const override;

private:
    const EnvironmentSampler& env_;
    const RayScene& scene_;
    glm::dvec3 albedo_;
    IrradianceEstimatorOptions options_;
};

// `inner` on the hits of triangles [begin, end) of the traced mesh, nothing elsewhere: how
// the object's components and the ground's share the pixels of one G-buffer traced
// against withGround (common/ground.h). `inner` must outlive it.
class TriangleRangeComponent : public ReferenceComponent {
public:
    TriangleRangeComponent(const ReferenceComponent& inner, size_t begin, size_t end)
        : inner_(inner), begin_(begin), end_(end) {}
    std::string name() const override { return inner_.name(); }
    RadianceEstimate radiance(const GBufferPixel& p) const override {
        return p.triangle >= begin_ && p.triangle < end_ ? inner_.radiance(p) : RadianceEstimate{};
    }

private:
    const ReferenceComponent& inner_;
    size_t begin_, end_;
};

// A material map's blend at the exit point (relight/prt/material_map.h, the model the
// renderers approximate per vertex): (1 - t) first + t second with t = blend(p) in
// [0, 1] at the pixel's own surface point. The variance is bounded by
// ((1 - t) sigma_first + t sigma_second)^2 (the two share their irradiance samples, so
// they are correlated). Both components and the function must outlive it.
class MaterialBlendComponent : public ReferenceComponent {
public:
    MaterialBlendComponent(const ReferenceComponent& first, const ReferenceComponent& second,
                           std::function<float(const GBufferPixel&)> blend)
        : first_(first), second_(second), blend_(std::move(blend)) {}
    std::string name() const override { return first_.name(); }
    RadianceEstimate radiance(const GBufferPixel& p) const override {
        const double t = blend_(p);
        const RadianceEstimate a = first_.radiance(p), b = second_.radiance(p);
        RadianceEstimate r;
        r.value = (1.0 - t) * a.value + t * b.value;
        const glm::dvec3 sigma = (1.0 - t) * glm::sqrt(a.variance) + t * glm::sqrt(b.variance);
        r.variance = sigma * sigma;
        return r;
    }

private:
    const ReferenceComponent& first_;
    const ReferenceComponent& second_;
    std::function<float(const GBufferPixel&)> blend_;
};

// Shades every object pixel of `g` as the sum of `components` (in parallel, one
// progress unit per object pixel) and fills the background with the environment
// along the primary ray (environmentRadiance of gbuffer.h, `background` rotated by
// `envRotation`; empty background = black), A = 0 there.
ReferenceFrame renderReference(const GBuffer& g, const std::vector<const ReferenceComponent*>& components,
                               const Image& background, const glm::dmat3& envRotation,
                               Progress* progress = nullptr);

// The frame of the sum of independently rendered components (frames of the same
// G-buffer, e.g. multiple and single scattering rendered one after the other):
// object pixels (A = 1 in every part) add their values and variances; the
// background and A come from the first part; the statistics are recomputed and
// seconds added. Throws prt::Error for an empty list or mismatched frames.
ReferenceFrame sumReferenceFrames(const std::vector<const ReferenceFrame*>& parts);

// ---------------------------------------------------------------------------
// The reference's own sample set: independent of the precomputation
// ---------------------------------------------------------------------------
//
// The dipole sum over surface samples is a quadrature of R_d, whose peak is about
// z_r wide and whose fall-off length is 1/sigma_tr. Its per-point error (the samples
// fall differently around every x_o) shrinks with the spacing h relative to the
// width w = 1 / (sigma_t' + sigma_tr) = 1 / (1/z_r + sigma_tr) (<= min(z_r,
// 1/sigma_tr), >= half of it) of the narrowest channel, and falls as N^-q with the
// sample count N (q = kDiscretisationRate); a reference sharing the precomputation's
// samples would repeat its quadrature error and never measure it (docs/reference.md,
// "Its own sample set").
//
// The reference therefore chooses, unless told otherwise:
// - spacing h = kReferenceSpacingFraction x w (referenceSampleSpacing), count from
//   defaultSampleCount (hexagonal packing), capped at a budget;
// - its own placement seed (referenceSampleSeed), never the precomputation's;
// - directions per sample from a ray budget (referenceIrradianceDirections): the
//   pixel noise depends on the rays per unit area, not on how they are split
//   between samples and directions per sample, sum_i (A_i R_d)^2 Var(E_i) ~ 1/(N D);
// - a convergence estimate (DiscretisationEstimate): the same render with half as
//   many samples (own seed) over a subset of the pixels.

inline constexpr double kReferenceSpacingFraction = 0.2;
// Default placement seed of the reference's samples: not 1 (prt-precompute's default
// seed) nor any small number a user is likely to pick.
inline constexpr uint64_t kReferenceSampleSeed = 0x7e5f3a9d2c41b6e1ull;
// Under point and directional lights the irradiance is exact and costs one shadow ray
// per sample and light, so the rule is denser by default: h = 0.1 w, up to 4 M samples
// (what that buys: docs/reference.md, "Point and directional lights").
inline constexpr double kReferenceLightSpacingFraction = 0.1;
inline constexpr size_t kReferenceLightMaxSamples = 4000000;
// Default ray budget of the irradiance estimates (directions per sample x samples).
inline constexpr double kReferenceRayBudget = 16.0 * 1024 * 1024;
// Convergence rate q of the per-pixel quadrature error, error ~ N^-q (measured:
// docs/reference.md, "Its own sample set").
inline constexpr double kDiscretisationRate = 0.6;

// w = 1 / max over channels of (sigma_t' + sigma_tr), times `fraction` (mm). Throws
// prt::Error for an invalid material or fraction outside (0, 10].
double referenceSampleSpacing(const Material& m, double fraction = kReferenceSpacingFraction);

// The placement seed of the reference's sample set number `level` (0: the render,
// 1: the half-density convergence run, 2, ...): derived from kReferenceSampleSeed
// (or `userSeed` when given), and never equal to `precomputeSeed` (nudged when it
// would be).
uint64_t referenceSampleSeed(uint64_t precomputeSeed, int level, std::optional<uint64_t> userSeed = std::nullopt);

// Directions per sample for `samples` samples under kReferenceRayBudget, in [64, 2048].
size_t referenceIrradianceDirections(size_t samples);

struct ReferenceSamplePlan {
    double spacingMm = 0.0;        // the rule's spacing (before capping)
    size_t count = 0;              // samples to place
    bool capped = false;           // count was limited by maxSamples
    double cappedSpacingMm = 0.0;  // spacing of `count` samples (== spacingMm unless capped)
    uint64_t seed = 0;             // placement seed (level 0)
};

// The default sample set of the reference for a surface of totalAreaMm2: spacing
// referenceSampleSpacing(m, fraction), count defaultSampleCount(area, spacing,
// maxSamples), seed referenceSampleSeed(precomputeSeed, 0, userSeed).
ReferenceSamplePlan planReferenceSamples(const Material& m, double totalAreaMm2, uint64_t precomputeSeed,
                                         size_t maxSamples, double fraction = kReferenceSpacingFraction,
                                         std::optional<uint64_t> userSeed = std::nullopt);

// The estimated remaining discretisation error of a frame rendered with N samples,
// from a frame of the same pixels rendered with an independent set of N/2 samples.
// The two quadrature errors are independent (different placements), and the error
// at N/2 is 2^q times the one at N (q = kDiscretisationRate), so
//   difference^2 = e_N^2 (1 + 2^2q) + noise_N^2 + noise_N/2^2
//   e_N = sqrt(max(0, difference^2 - noise floors^2) / (1 + 2^2q)),
// all as relative RMSE over the compared pixels and channels (prt-compare's measure).
struct DiscretisationEstimate {
    size_t pixels = 0;            // compared: object pixels of `half`
    double difference = 0.0;      // rel RMSE of half against full
    double noiseFloor = 0.0;      // sqrt(noise_N^2 + noise_N/2^2) over those pixels
    double halfError = 0.0;       // sqrt(max(0, difference^2 - noiseFloor^2)): e at N/2 and N combined
    double estimatedError = 0.0;  // e_N, the number to report
};
// `full` and `half` are frames of the same size; compared where half's A > 0.5
// (which must be object pixels of full). Throws prt::Error otherwise.
DiscretisationEstimate estimateDiscretisationError(const ReferenceFrame& full, const ReferenceFrame& half);

// A copy of `g` keeping every `stride`-th object pixel (in scan order) and turning
// the others into background: the pixels of a convergence run.
GBuffer subsampleObjectPixels(const GBuffer& g, size_t stride);

// ---------------------------------------------------------------------------
// Per-vertex comparison (prt-vertex-error)
// ---------------------------------------------------------------------------

// A camera-independent check of multiple scattering: a precomputed render's vertex
// values (V_o . L) against the reference's dipole sum at the same vertices. An image
// sees only the side of the object facing the camera, and truncation shifts the mean
// of different sides in different directions (docs/fidelity.md), so a frame's error can
// hide part of what the vertices carry. Groups split the vertices by where their
// normals face (world +Y is up): up (n.y > 0.5), down (n.y < -0.5), side (between).
struct VertexComparison {
    struct Group {
        size_t vertices = 0;
        glm::dvec3 sumTest{0.0}, sumReference{0.0};
        // Mean ratio of the group, sum over channels and vertices of test / the same of
        // the reference (1 = no bias; 0 when both are 0, inf when only the reference's is).
        double ratio() const;
    };
    Group all, up, side, down;
    // sqrt(sum_{v,c} (t - r)^2 / sum_{v,c} r^2) over all compared vertices.
    double relativeL2 = 0.0;
    // sqrt(sum_{v,c} variance of r / sum_{v,c} r^2): the reference's Monte Carlo noise
    // on the same scale (0 when no variances are given).
    double referenceNoise = 0.0;
};

// test, reference, normals (and referenceVariance, when not empty) have one entry per
// compared vertex. Throws prt::Error("vertex comparison", ...) when the sizes differ
// or there is nothing to compare.
VertexComparison compareVertexValues(const std::vector<glm::dvec3>& test,
                                     const std::vector<glm::dvec3>& reference,
                                     const std::vector<glm::vec3>& normals,
                                     const std::vector<glm::dvec3>& referenceVariance = {});


}  // namespace prt
