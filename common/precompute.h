#pragma once
// The precomputation pipeline of prt-precompute as one function from settings to a
// transport file (Wang et al. 2005, section 3):
//
//   mesh --scale--> samples (Poisson disk) --pass 1--> sparse Haar irradiance
//   transport per sample --pass 2 (kd-tree, Jensen-Buhler)--> sparse RGB multiple
//   scattering transport per vertex --> transport file (atomic write).
//
// Each stage is its own library function (sampling.h, irradiance.h, hierarchy.h,
// transport_file.h) so it can be tested and timed alone; this module only wires
// them, reports progress and collects the summary.

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "common/bssrdf.h"
#include "common/mesh.h"
#include "common/transport_file.h"

namespace prt {

struct PrecomputeSettings {
    std::string meshPath;
    std::string outputPath;
    MeshScale scale;              // exactly one of sizeMm / mmPerUnit
    Material material;            // with eta and g
    int cubemapSize = 32;         // N of the 6 x N x N lighting cubemap (<= 64)
    int supersample = 2;          // s x s stratified sub-directions per texel
    size_t sampleCoefficients = 128;  // Haar terms kept per sample (pass 1)
    size_t nodeCoefficients = 256;    // per kd-tree node (pass 2)
    size_t vertexCoefficients = 128;  // per vertex in the file
    double epsilon = 0.05;        // kd-tree solid-angle threshold A / r^2 (0: exact sum)
    size_t sampleCount = 0;       // 0: from sampleSpacingMm
    double sampleSpacingMm = 0;   // 0: the material's smallest mean free path l_u
    size_t maxSamples = 300000;   // cap on the automatic count
    uint64_t seed = 1;
};

// Throws prt::Error naming the bad option.
void validateSettings(const PrecomputeSettings& s);

// Every setting as text, in a fixed order: stored in the transport file and hashed
// into `input_digest` so that a batch run can tell whether an output is up to date.
std::vector<std::pair<std::string, std::string>> settingsParameters(const PrecomputeSettings& s,
                                                                    const MeshFingerprint& mesh);

struct PrecomputeSummary {
    std::string outputPath;
    bool skipped = false;  // output already up to date
    size_t vertices = 0, triangles = 0, samples = 0;
    double totalAreaMm2 = 0, sampleSpacingMm = 0;
    uint64_t raysTraced = 0;
    double pass1Seconds = 0, pass2Seconds = 0, totalSeconds = 0;
    double pass1RaysPerSecond = 0;
    double sampleRetainedEnergy = 0;  // mean kept/total energy of pass-1 truncations
    double vertexRetainedEnergy = 0;  // mean kept/total energy of the per-vertex truncations
    double meanNodesVisited = 0;
    size_t peakMemoryBytes = 0;       // of the process, at the end
    size_t fileBytes = 0;

    std::string format() const;  // multi-line human-readable summary
};

// Runs the pipeline. When the output exists, is valid and was made from the same
// settings and mesh, returns a summary with skipped = true unless force is set.
PrecomputeSummary precomputeTransport(const PrecomputeSettings& settings, bool force = false);

// Peak resident set size of this process in bytes (getrusage).
size_t peakMemoryBytes();

}  // namespace prt
