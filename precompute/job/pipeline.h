#pragma once
// The precomputation pipeline of prt-precompute as one function from settings to a
// transport file (Wang et al. 2005, section 3):
//
//   mesh --scale--> samples (Poisson disk) --pass 1--> sparse Haar irradiance
//   transport per sample --pass 2 (kd-tree, Jensen-Buhler)--> sparse RGB multiple
//   scattering transport per vertex (component "ms")
//   mesh --single scattering along -n_o (Eqs. 10-11)--> one isotropic sparse RGB
//   vector per vertex (g = 0) or K term vectors + the h_k view maps (g != 0)
//   (component "ss")
//   --> transport file (atomic write).
//
// Each stage is its own library function (sampling.h, irradiance.h, hierarchy.h,
// single_scattering.h, phase.h, transport_file.h) so it can be tested and timed
// alone; this module only wires them, reports progress and collects the summary.

#include <cstdint>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "common/bssrdf.h"
#include "common/mesh.h"
#include "common/transport_file.h"
#include "common/transport_params.h"
#include "precompute/job/distribution.h"
#include "precompute/passes/irradiance_transport.h"
#include "precompute/passes/single_scattering.h"

namespace prt {

struct PrecomputeSettings {
    std::string meshPath;
    std::string outputPath;
    MeshScale scale;              // exactly one of sizeMm / mmPerUnit
    Material material;            // with eta and g
    int cubemapSize = 32;         // N of the 6 x N x N lighting cubemap (<= 64)
    int supersample = 2;          // s x s stratified sub-directions per texel
    VisibilitySampling pass1Visibility = VisibilitySampling::Every;  // how pass 1 traces them
    size_t sampleCoefficients = 128;  // Haar terms kept per sample (pass 1)
    size_t nodeCoefficients = 256;    // per kd-tree node (pass 2)
    size_t vertexCoefficients = 128;  // per vertex (in the file, or before the joint choice)
    // Of those, the SH part of every vector (common/sh_part.h): 0, 1, 4 or 9 terms; the
    // rest are the largest Haar coefficients of the residual.
    int shTerms = 9;
    // > 0: the file stores blocks of 16 nearby vertices sharing this many jointly chosen
    // terms, picked from each vertex's vertexCoefficients (common/blocked_vectors.h).
    size_t blockCoefficients = 0;
    double epsilon = 0.05;        // kd-tree solid-angle threshold A / r^2 (0: exact sum)
    size_t sampleCount = 0;       // 0: from sampleSpacingMm
    double sampleSpacingMm = 0;   // 0: the material's smallest mean free path l_u
    size_t maxSamples = 300000;   // cap on the automatic count
    uint64_t seed = 1;
    // Single scattering (used when components.singleScattering).
    ScatteringComponents components;  // default: multiple scattering only
    int phaseTerms = 4;           // K of the SVD-factored HG phase when g != 0 (g = 0: isotropic)
    int phaseMapSize = 16;        // M of the 6 x M x M light / view maps
    // Deterministic samples along -n_o and their rule in xi (single_scattering.h); the
    // command line's default N depends on the rule (defaultPathSamples).
    PathQuadrature pathQuadrature = kDefaultPathQuadrature;
    int pathSamples = defaultPathSamples(kDefaultPathQuadrature);
    int ssSupersample = 1;        // s x s sub-directions per texel in single scattering
    // Adaptive texel directions of single scattering: lattice stride (1 = every texel;
    // SingleScatteringOptions::directionStride). Used only with ssSupersample == 1.
    // Default 4 since issue 16: the per-vertex error against 64 midpoints as with every
    // texel traced, with 2.5x fewer rays (docs/single-scattering.md).
    int ssDirectionStride = 4;
    // V of single scattering from the exit ray's own traversal (true, the default since
    // issue 16) or from a second ray from each exit point (the rule before, the
    // reference; SingleScatteringOptions::visibilityFromExitRay).
    bool ssVisibilityFromExitRay = true;
    // Refuse the job up front when its estimated memory (memory_estimate.h) exceeds this
    // many GB; 0 = the machine's available memory. Not a physics setting: not stored in
    // the file and not part of the input digest.
    double maxMemoryGb = 0.0;
    // --shard i/n: compute only the vertices of shard i of n into a shard file that
    // prt-merge joins (precompute/job/distribution.h). Not a physics setting either: the
    // shards of one job share its input_digest.
    std::optional<ShardSpec> shard;
    // --pass1-file: the samples' pass-1 vectors are loaded from this file when it
    // exists (and was made for this job's pass-1 inputs, precompute/job/pass1_file.h), else
    // computed and saved there, so the shards of a job compute pass 1 once. With
    // pass1Only the job stops after writing it (no transport file).
    std::string pass1File;
    bool pass1Only = false;
};

// Throws prt::Error naming the bad option.
void validateSettings(const PrecomputeSettings& s);

// Every setting as text, in a fixed order: stored in the transport file and hashed
// into `input_digest` so that a batch run can tell whether an output is up to date.
// The single-scattering settings (phase_terms, phase_map_size, path_samples, ...) are
// listed only when single scattering is selected, so a multiple-scattering-only job
// keeps the parameters (and digest) it had before single scattering existed.
std::vector<std::pair<std::string, std::string>> settingsParameters(const PrecomputeSettings& s,
                                                                    const MeshFingerprint& mesh);

struct PrecomputeSummary {
    std::string outputPath;
    bool skipped = false;  // output already up to date
    std::string pass1File;       // --pass1-file, when given
    bool pass1Loaded = false;    // pass 1 read from it instead of computed
    std::string distribution = "1 process";  // Distribution::describe() of this process
    int ranks = 1;
    // Work split over processes (precompute/job/distribution.h): bytes of pass-1 vectors all
    // ranks exchanged (0 in one process), the time of that exchange, and the time spent
    // gathering the per-vertex vectors at the writing process.
    double pass1ExchangeBytes = 0, pass1ExchangeSeconds = 0, gatherSeconds = 0;
    // Seconds each process spent computing its shares (pass 1 + pass 2 + single
    // scattering, without the exchanges), smallest and largest over the processes: their
    // ratio is the balance of the even split.
    double busySecondsMin = 0, busySecondsMax = 0;
    ScatteringComponents components;
    size_t vertices = 0, triangles = 0, samples = 0;
    // Vertices this job computed: a shard's range under --shard, all of them otherwise
    // (MPI ranks together). The per-vertex rates of the summary divide by it.
    size_t computedVertices = 0;
    double totalAreaMm2 = 0, sampleSpacingMm = 0;
    uint64_t raysTraced = 0;          // pass 1
    // Wall-clock seconds per stage: setup (mesh load, up-to-date check, scaling, the
    // pass-1 ray scene), sample placement, pass 1, pass 2 (kd-tree build + per-vertex
    // integration), phase SVD and single scattering (below), write (the transport
    // file), total (everything).
    double setupSeconds = 0, samplesSeconds = 0, writeSeconds = 0;
    double pass1Seconds = 0, pass2Seconds = 0, totalSeconds = 0;
    double pass1RaysPerSecond = 0;
    double sampleRetainedEnergy = 0;  // mean kept/total energy of pass-1 truncations
    double vertexRetainedEnergy = 0;  // mean kept/total energy of the per-vertex truncations
    // With blockCoefficients: the joint choice of every component (after the per-vertex
    // truncations), its time and its mean kept/total energy against the per-vertex vectors.
    size_t blockCoefficients = 0, blockSourceCoefficients = 0;
    double blockSeconds = 0, blockRetainedEnergy = 0;
    double meanNodesVisited = 0;
    // Pass 2's cell quadrature (cell_quadrature.h): the time to build the sample cells
    // (part of pass2Seconds) and their sub-points.
    double cellSeconds = 0;
    size_t cellSubPoints = 0;
    // Single scattering.
    int ssTerms = 0;                  // 0: not computed; 1 and ssIsotropic; or K
    bool ssIsotropic = true;
    double phaseSeconds = 0;          // SVD of the phase function
    double phaseRmsError = 0;         // relative RMS error of the K-term phase (0 if isotropic)
    double ssSeconds = 0;
    uint64_t ssRaysTraced = 0;        // depth + exit + occlusion rays
    uint64_t ssExitRays = 0, ssOcclusionRays = 0, ssCulledRays = 0, ssOccludedExits = 0;
    uint64_t ssTracedTexels = 0, ssInterpolatedTexels = 0;
    uint64_t ssEscapedRays = 0, ssReversedHits = 0, ssOutsideSamples = 0;
    uint64_t ssFlippedNormals = 0, ssCappedDepths = 0;
    double ssRaysPerSecond = 0;
    double ssMeanDepthMm = 0;         // mean d_m
    double ssRetainedEnergy = 0;      // mean kept/total energy of the per-vertex truncations
    size_t peakMemoryBytes = 0;       // of the process, at the end
    uint64_t estimatedMemoryBytes = 0;  // memory_estimate.h, checked before the passes
    // Peak resident set size of the process read at the end of each stage (getrusage
    // ru_maxrss). It only ever grows, so each is the peak SO FAR (that stage and every
    // earlier one, and earlier jobs of the same process), not the stage's own use; a
    // stage that did not run has 0.
    size_t peakMemoryAfterSetupBytes = 0, peakMemoryAfterSamplesBytes = 0;
    size_t peakMemoryAfterPass1Bytes = 0, peakMemoryAfterPass2Bytes = 0;
    size_t peakMemoryAfterSingleScatteringBytes = 0;
    size_t fileBytes = 0;

    std::string format() const;  // multi-line human-readable summary
};

// Runs the pipeline. When the output exists, is valid and was made from the same
// settings and mesh, returns a summary with skipped = true unless force is set.
// `distribution` divides the work between processes (precompute/job/distribution.h: a
// shard of the vertices, MPI ranks); null = all of it in this process. The file
// written is the same, byte for byte, however the work was divided (a shard writes
// its part, which prt-merge joins into that file).
PrecomputeSummary precomputeTransport(const PrecomputeSettings& settings, bool force = false,
                                      Distribution* distribution = nullptr);

// Peak resident set size of this process in bytes (getrusage).
size_t peakMemoryBytes();

}  // namespace prt
