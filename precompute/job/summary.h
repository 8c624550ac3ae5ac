#pragma once
// What one precompute job did (precomputeTransport, pipeline.h), one part per stage,
// each filled by that stage: times in wall-clock seconds, energies as mean kept / total
// energy of a truncation, memory in bytes. A stage that did not run leaves its part 0.
// format() is the printed summary (docs/precompute.md, "Output summary"); summary_json.h
// writes every field.

#include <cstddef>
#include <cstdint>
#include <string>

#include "common/transport_params.h"

namespace prt {

// How the work was divided between processes (distribution.h).
struct DistributionSummary {
    std::string description = "1 process";  // Distribution::describe() of this process
    int ranks = 1;
    bool shard = false;  // --shard i/n: a per-vertex shard file (prt-merge blocks the whole)
    // Seconds each process spent computing its shares (pass 1 + pass 2 + single
    // scattering, without the exchanges), smallest and largest over the processes: their
    // ratio is the balance of the even split.
    double busySecondsMin = 0, busySecondsMax = 0;
};

// Mesh load, up-to-date check, scaling, the memory check, pass 1's ray scene.
struct SetupSummary {
    size_t vertices = 0, triangles = 0;
    // Vertices this job computed: a shard's range under --shard, all of them otherwise
    // (MPI ranks together). The per-vertex rates divide by it.
    size_t computedVertices = 0;
    double totalAreaMm2 = 0;
    double seconds = 0;                 // from the start of the job
    uint64_t estimatedMemoryBytes = 0;  // memory_estimate.h, checked here
    // Peak resident set size of the process so far (getrusage ru_maxrss: it only grows,
    // so each stage's figure is that stage's and every earlier one's, and earlier jobs'
    // of the same process), read at the end of the stage. The same in every part below.
    size_t peakMemoryBytes = 0;
};

struct SamplesSummary {
    size_t count = 0;
    double spacingMm = 0;  // of the placed samples
    double seconds = 0;
    size_t peakMemoryBytes = 0;
};

struct Pass1Summary {
    std::string file;         // --pass1-file, when given
    bool loaded = false;      // read from it instead of computed
    uint64_t rays = 0;        // all processes'
    double seconds = 0;       // computing (or loading) and the exchange
    double raysPerSecond = 0; // all processes' rays over this process's time
    double retainedEnergy = 0;
    // The pass-1 vectors all ranks exchanged (0 in one process) and its time.
    double exchangeBytes = 0, exchangeSeconds = 0;
    size_t peakMemoryBytes = 0;
};

struct Pass2Summary {
    double seconds = 0;        // kd-tree build, per-vertex integration, gather
    double meanNodesVisited = 0;
    double retainedEnergy = 0; // of the per-vertex truncations
    // The cell quadrature (cell_quadrature.h): the time to build the sample cells (part
    // of seconds) and their sub-points.
    double cellSeconds = 0;
    size_t cellSubPoints = 0;
    double gatherSeconds = 0;  // the per-vertex vectors gathered at the writing process
    size_t peakMemoryBytes = 0;  // after the copy into the file's arrays
};

struct SingleScatteringSummary {
    int terms = 0;               // 0: not computed; 1 and isotropic; or K
    bool isotropic = true;
    double phaseSeconds = 0;     // SVD of the phase function
    double phaseRmsError = 0;    // relative RMS error of the K-term phase (0 if isotropic)
    double seconds = 0;
    uint64_t rays = 0;           // depth + exit + occlusion rays
    uint64_t exitRays = 0, occlusionRays = 0, culledRays = 0, occludedExits = 0;
    uint64_t tracedTexels = 0, interpolatedTexels = 0;
    uint64_t sites = 0;          // points whose transport was computed (the vertices unless --ss-site-spacing)
    double siteSpacing = 0;      // mm, 0: every vertex
    // MPI ranks sharing the sites: the bytes all ranks sent and the exchange's time.
    double siteExchangeBytes = 0, siteExchangeSeconds = 0;
    uint64_t splitsByStake = 0, splitsByThroughput = 0, splitsByExitKind = 0;  // adaptive cells split, per rule
    uint64_t escapedRays = 0, reversedHits = 0, outsideSamples = 0;
    uint64_t flippedNormals = 0, cappedDepths = 0;
    double raysPerSecond = 0;
    // Path statistics count the points whose transport was computed (the sites, or
    // every vertex without sites): meanDepthMm is the mean d_m over them.
    double meanDepthMm = 0;
    double retainedEnergy = 0;   // of the per-vertex truncations
    double gatherSeconds = 0;
    size_t peakMemoryBytes = 0;
};

// With blockCoefficients: the joint choice of every component (after the per-vertex
// truncations), its time and its retained energy against the per-vertex vectors.
struct BlocksSummary {
    size_t coefficients = 0, sourceCoefficients = 0;  // as the settings ask
    double seconds = 0, retainedEnergy = 0;
};

struct WriteSummary {
    double seconds = 0;
    size_t fileBytes = 0;
};

// The ground's transport file (written only by jobs with --ground).
struct GroundSummary {
    std::string path;  // empty: no ground
    size_t vertices = 0;
    uint64_t rays = 0;
    double seconds = 0;
};

struct PrecomputeSummary {
    std::string outputPath;
    bool skipped = false;  // output already up to date
    ScatteringComponents components;
    DistributionSummary distribution;
    SetupSummary setup;
    SamplesSummary samples;
    Pass1Summary pass1;
    Pass2Summary pass2;
    SingleScatteringSummary singleScattering;
    BlocksSummary blocks;
    WriteSummary write;
    GroundSummary ground;
    double totalSeconds = 0;
    size_t peakMemoryBytes = 0;  // of the process, at the end
    // Resident before the job read its mesh: the libraries and the caller's own data,
    // which the memory estimate (the job's data) leaves out.
    size_t startMemoryBytes = 0;

    // Pass 2's and single scattering's gathers.
    double gatherSeconds() const { return pass2.gatherSeconds + singleScattering.gatherSeconds; }
    std::string format() const;  // multi-line human-readable summary
};

}  // namespace prt
