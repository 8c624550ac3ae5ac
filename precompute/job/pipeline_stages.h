#pragma once
// The stages of precomputeTransport (pipeline.h), in the order it runs them. Each runs
// on every process of the job's Distribution, its work inside Distribution::stage (a
// failure on one process fails every process at the end of that stage), takes what the
// earlier stages returned and returns its results with its own part of the summary.
// Internal to prt_job.

#include <optional>
#include <string>
#include <vector>

#include "common/ground.h"
#include "common/haar.h"
#include "common/mesh.h"
#include "common/raytrace.h"
#include "common/sampling.h"
#include "common/transport_file.h"
#include "common/transport_params.h"
#include "common/util.h"
#include "precompute/job/distribution.h"
#include "precompute/job/settings.h"
#include "precompute/job/summary.h"

namespace prt {

// What every stage reads.
struct JobContext {
    const PrecomputeSettings& settings;  // withSharedValues applied
    Distribution& distribution;
    // Suffix of the progress labels of a share of the work ("pass 1 [MPI rank 0 of 2]"):
    // rank 0's share stands for the whole job's progress, the shares being even.
    std::string share;
};

// 1. Validation, the output paths (checked now, not after the passes), the mesh, the
// parameters and whether the output is up to date (never with force, pass1Only, or on a
// process that does not write).
struct JobInputs {
    TriangleMesh mesh;  // in file units
    MeshFingerprint fingerprint;
    ParameterList parameters;  // settingsParameters
    bool upToDate = false;
};
JobInputs readInputs(const JobContext& job, bool force);

// 2. The mesh scaled to mm, this process's vertices, the sample count, the memory check
// (before any allocation that grows with the job) and pass 1's ray scene.
struct PreparedJob {
    TriangleMesh mesh;  // in mm
    MeshFingerprint fingerprint;
    ParameterList parameters;
    double mmPerUnit = 1.0;
    ParameterList derived;  // derived file parameters of this stage: mm_per_unit
    std::vector<IndexRange> vertexShares;  // this process's vertices
    size_t myVertices = 0;
    size_t sampleCount = 0;           // 0 without multiple scattering
    // With multiple scattering: the object's, and the ground's after it (withGround) when
    // the job has one.
    std::optional<RayScene> scene;
    std::optional<GroundPlane> ground;  // settings.ground placed under the scaled mesh
    SetupSummary summary;
};
PreparedJob setUp(const JobContext& job, JobInputs inputs, const Stopwatch& jobStart);

// 3. The Poisson-disk samples (every process places all of them, from the seed).
struct PlacedSamples {
    SampleSet samples;
    ParameterList derived;  // samples, sample_area_mm2
    SamplesSummary summary;
};
PlacedSamples placeSamples(const JobContext& job, const PreparedJob& prepared);

// 4. Pass 1: this process's share of the samples' irradiance transport vectors, or all
// of them from settings.pass1File; then every vector on every process, and saved to
// pass1File when it was computed.
struct Pass1Output {
    std::vector<SparseVector> vectors;  // all samples, in sample order
    double busySeconds = 0;             // computing this process's share
    Pass1Summary summary;
};
Pass1Output runPass1(const JobContext& job, const PreparedJob& prepared, const PlacedSamples& samples);

// 5. Pass 2: the multiple-scattering vectors of this process's vertices, gathered at the
// writing process into the file's component (empty elsewhere).
struct Pass2Output {
    // The multiple-scattering component; or, for an editable job, the profile components
    // (three radial profiles per component, one shared index list per vertex) and the
    // basis they were computed against.
    std::vector<TransportComponent> components;
    std::optional<StoredRadialBasis> radialBasis;
    ParameterList derived;  // an editable job's basis range and fit errors
    double busySeconds = 0;
    Pass2Summary summary;
};
Pass2Output runPass2(const JobContext& job, const PreparedJob& prepared, const PlacedSamples& samples,
                     std::vector<SparseVector> pass1Vectors);

// 6. Single scattering: the phase factorisation (g != 0), the vectors of this process's
// vertices gathered like pass 2's, one component per term, and the view maps.
struct SingleScatteringOutput {
    std::vector<TransportComponent> components;
    std::optional<ViewMaps> viewMaps;  // g != 0
    ParameterList derived;             // phase_rms_error (g != 0)
    double busySeconds = 0;
    SingleScatteringSummary summary;
};
SingleScatteringOutput runSingleScattering(const JobContext& job, const PreparedJob& prepared);

// 7. On the writing process: the blocks (blockCoefficients > 0), the derived and shard
// parameters (before input_digest, which stays last) and the atomic write.
struct WriteOutput {
    double blockSeconds = 0, blockRetainedEnergy = 0;
    WriteSummary summary;
};
WriteOutput writeTransport(const JobContext& job, const PreparedJob& prepared,
                           std::vector<TransportComponent> components, std::optional<ViewMaps> viewMaps,
                           std::optional<StoredRadialBasis> radialBasis, ParameterList derived);

// 8. On the writing process, with a ground: the ground's transport file
// (groundTransportPath of the output; diffuse_baseline.h's groundTransport) in the
// prepared scene, its input_digest the object file's, written atomically.
GroundSummary writeGroundTransport(const JobContext& job, const PreparedJob& prepared);

}  // namespace prt
