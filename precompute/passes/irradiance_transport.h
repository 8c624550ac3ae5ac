#pragma once
// Pass 1 of multiple scattering (Wang et al. 2005, Eq. 8): the irradiance transport of
// each surface sample x_i over the texels w_j of a 6 x N x N cubemap (docs/conventions.md),
//
//     E(x_i, w_j) = F_t(eta, w_j) V(x_i, w_j) max(0, n_i . w_j) dOmega_j,
//
// a function of direction (not an irradiance) with the texel's solid angle folded in,
// so that relighting is a dot product with radiance. Each texel is integrated with
// s x s stratified sub-directions weighted by their exact sub-solid-angles; V comes
// from occlusion rays from one offset origin per sample. The dense cubemap is
// Haar-transformed per face and truncated to its largest coefficients.
//
// Units: positions in mm (only ratios matter); E is dimensionless (sr).

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "common/haar.h"
#include "common/raytrace.h"
#include "common/sampling.h"

namespace prt {

class Progress;

// The sub-directions of every texel of a 6 x N x N cubemap, s x s per texel,
// stored texel by texel in flat texel order (SoA), with their exact solid angles.
struct TexelDirections {
    int size = 0;         // N
    int supersample = 0;  // s
    std::vector<float> x, y, z;      // unit sub-directions, 6 N^2 s^2 of them
    std::vector<float> solidAngle;   // exact solid angle of each sub-texel (sums to 4 pi)

    size_t subPerTexel() const { return size_t(supersample) * supersample; }
    size_t count() const { return x.size(); }
};
TexelDirections makeTexelDirections(int cubemapSize, int supersample);

// How pass 1 finds V for the s x s sub-directions of each texel.
//   Every:    one occlusion ray per sub-direction above the horizon (the reference).
//   Coherent: one probe ray per texel first (its first sub-direction above the
//             horizon); a texel wholly above the horizon whose probe agrees with the
//             probes of all 8 neighbours on its face gives every sub-direction the
//             probe's V, every other texel (at a visibility or horizon edge, on a face
//             border) traces all its sub-directions. Exact wherever visibility changes
//             over at least a texel; an occluder or hole narrower than a texel that
//             falls between probes is missed. With s = 1 it is Every. Not the default
//             (docs/precompute.md, "Pass 1 visibility").
enum class VisibilitySampling { Every, Coherent };
// "every" / "coherent"; throws prt::Error("--pass1-visibility", ...) for anything else.
VisibilitySampling parseVisibilitySampling(const std::string& text);
const char* toString(VisibilitySampling mode);

struct IrradianceTransportOptions {
    int cubemapSize = 32;            // N; a power of two
    int supersample = 2;             // s: s x s sub-directions per texel
    size_t sampleCoefficients = 128; // terms kept per sample, shTerms of them the SH part
    // SH part of each sample's vector (common/sh_part.h truncateWithShPart; indices
    // 6 N^2 + i): 0, 1, 4 or 9, fewer than sampleCoefficients.
    int shTerms = 0;
    double eta = 1.3;                // relative index of refraction for F_t
    bool visibility = true;          // false: V = 1 everywhere (tests, ablations)
    VisibilitySampling sampling = VisibilitySampling::Every;
};

// Per-thread scratch so the hot loop never allocates.
struct IrradianceTransportScratch {
    std::vector<float> dirX, dirY, dirZ, weight;  // rays that face the sample's normal
    std::vector<uint32_t> texel;                  // their texel
    std::vector<uint8_t> occluded;
    std::vector<float> dense;                     // 6 N^2 (+ room for the SH entries)
    // Coherent sampling: per texel its first ray and ray count, the probes' V, the rays
    // still to trace (as indices into the arrays above) and their directions.
    std::vector<uint32_t> firstRay, rayCount;
    std::vector<uint8_t> probe;  // 0: no ray above the horizon, 1: visible, 2: occluded
    std::vector<uint32_t> batch;
    std::vector<float> batchX, batchY, batchZ;
    std::vector<uint8_t> batchOccluded;
};

// Dense E of one sample (Eq. 8) into `out` (6 N^2 floats, texel order). Returns the
// number of occlusion rays traced (only sub-directions with n_i . w > 0 are candidates;
// Coherent traces fewer, see VisibilitySampling).
uint64_t irradianceTransport(const RayScene* scene, const SurfaceSample& sample,
                             const TexelDirections& dirs, double eta, float* out,
                             IrradianceTransportScratch& scratch,
                             VisibilitySampling sampling = VisibilitySampling::Every);

struct IrradianceTransportResult {
    std::vector<SparseVector> vectors;  // one per sample, channels = 1: Haar, then the SH part
    uint64_t raysTraced = 0;
    double retainedEnergyFraction = 1.0;  // mean over samples of kept / total energy
    double seconds = 0.0;
};

// Pass 1 over all samples, in parallel (TBB). Deterministic: the result does not
// depend on the thread count. scene may be null only when options.visibility is false.
IrradianceTransportResult computeIrradianceTransport(const RayScene* scene, const SampleSet& samples,
                                                     const IrradianceTransportOptions& options,
                                                     Progress* progress = nullptr);

}  // namespace prt
