#include "precompute/job/pipeline.h"

#include <sys/resource.h>

#include <optional>
#include <tuple>
#include <utility>

#include <cstdio>
#include <filesystem>

#include "common/atomic_file.h"
#include "common/error.h"
#include "common/mesh_io.h"
#include "common/raytrace.h"
#include "common/util.h"
#include "precompute/passes/diffuse_baseline.h"
#include "precompute/job/pipeline_stages.h"

namespace prt {

namespace {

void append(ParameterList& to, const ParameterList& more) { to.insert(to.end(), more.begin(), more.end()); }

// What the summary says before any stage runs: the job as asked.
PrecomputeSummary plannedSummary(const PrecomputeSettings& s, const Distribution& dist) {
    PrecomputeSummary summary;
    summary.outputPath = s.outputPath;
    summary.components = s.components;
    summary.blocks.coefficients = s.blockCoefficients;
    summary.blocks.sourceCoefficients = s.vertexCoefficients;
    summary.distribution.description = dist.describe();
    summary.distribution.ranks = dist.ranks();
    summary.distribution.shard = s.shard.has_value();
    return summary;
}

PrecomputeSummary finished(PrecomputeSummary summary, const Stopwatch& start) {
    summary.totalSeconds = start.seconds();
    summary.peakMemoryBytes = peakMemoryBytes();
    return summary;
}

}  // namespace

size_t precomputeDiffuseBaseline(const PrecomputeSettings& s, const glm::dvec3& albedo) {
    const Stopwatch start;
    if (s.components.singleScattering) throw Error("--baseline", "the diffuse baseline has no single scattering");
    if (s.editable.enabled) throw Error("--baseline", "the diffuse baseline has no material to edit (--editable)");
    if (s.shard || !s.pass1File.empty() || s.pass1Only)
        throw Error("--baseline", "the diffuse baseline runs in one process, without shards or pass-1 files");
    if (s.outputPath.empty()) throw Error("--output", "no output path given (see --help)");
    checkOutputPath(s.outputPath);
    TriangleMesh mesh = loadMesh(s.meshPath);
    const MeshFingerprint fingerprint{mesh.vertexCount(), meshFingerprint(mesh)};
    const double mmPerUnit = scaleToPhysical(mesh, s.scale);
    computeVertexNormals(mesh);
    const RayScene scene(mesh);
    DiffuseBaselineOptions o;
    o.albedo = albedo;
    o.cubemapSize = s.cubemapSize;
    o.shTerms = s.shTerms;
    o.coefficients = s.vertexCoefficients;
    o.supersample = s.pass1.supersample;
    o.sampling = s.pass1.sampling;
    Progress progress("diffuse baseline: vertices", mesh.vertexCount());
    char sizeMm[32];
    std::snprintf(sizeMm, sizeof sizeMm, "%.9g", double(bounds(mesh).diagonal()));
    const TransportFile file =
        diffuseBaselineTransport(mesh, scene, fingerprint, mmPerUnit, o,
                                 {{"mesh_file", std::filesystem::path(s.meshPath).filename().string()},
                                  {"size_mm", sizeMm}},
                                 &progress);
    progress.finish();
    saveTransportFile(s.outputPath, file);
    std::printf("diffuse baseline: %zu vertices, albedo (%.3g, %.3g, %.3g), cubemap 6x%dx%d, %zu terms per vertex, "
                "%s rays; wrote %s in %s\n",
                mesh.vertexCount(), albedo.r, albedo.g, albedo.b, s.cubemapSize, s.cubemapSize, s.vertexCoefficients,
                file.parameter("rays_traced").c_str(), s.outputPath.c_str(), formatDuration(start.seconds()).c_str());
    return mesh.vertexCount();
}

size_t peakMemoryBytes() {
    rusage usage{};
    getrusage(RUSAGE_SELF, &usage);
    return size_t(usage.ru_maxrss) * 1024;  // Linux reports kilobytes
}

PrecomputeSummary precomputeTransport(const PrecomputeSettings& requested, bool force,
                                      Distribution* distribution) {
    const Stopwatch start;
    const PrecomputeSettings settings = withSharedValues(requested);
    Distribution single;
    std::optional<ShardDistribution> shardOfJob;
    if (settings.shard) {
        if (distribution && distribution->partial())
            throw Error("--shard", "a shard job cannot run under MPI ranks too (use one or the other)");
        shardOfJob.emplace(*settings.shard);
    }
    Distribution& dist = shardOfJob ? *shardOfJob : distribution ? *distribution : single;
    const JobContext job{settings, dist, dist.partial() ? " [" + dist.describe() + "]" : ""};
    PrecomputeSummary summary = plannedSummary(settings, dist);
    summary.startMemoryBytes = residentMemoryBytes();

    JobInputs inputs = readInputs(job, force);
    if (dist.agree(inputs.upToDate)) {
        summary.skipped = true;
        return summary;
    }
    const PreparedJob prepared = setUp(job, std::move(inputs), start);
    summary.setup = prepared.summary;
    ParameterList derived = prepared.derived;
    std::vector<TransportComponent> components;
    std::optional<ViewMaps> viewMaps;
    std::optional<StoredRadialBasis> radialBasis;
    double busy = 0.0;  // this process's compute seconds, for the balance of the split

    if (settings.components.multipleScattering) {
        const PlacedSamples samples = placeSamples(job, prepared);
        summary.samples = samples.summary;
        append(derived, samples.derived);
        Pass1Output pass1 = runPass1(job, prepared, samples);
        summary.pass1 = pass1.summary;
        busy += pass1.busySeconds;
        if (settings.pass1Only) return finished(std::move(summary), start);
        Pass2Output pass2 = runPass2(job, prepared, samples, std::move(pass1.vectors));
        summary.pass2 = pass2.summary;
        busy += pass2.busySeconds;
        for (TransportComponent& c : pass2.components) components.push_back(std::move(c));
        radialBasis = std::move(pass2.radialBasis);
        append(derived, pass2.derived);
    }
    if (settings.components.singleScattering) {
        SingleScatteringOutput ss = runSingleScattering(job, prepared);
        summary.singleScattering = ss.summary;
        busy += ss.busySeconds;
        append(derived, ss.derived);
        for (TransportComponent& c : ss.components) components.push_back(std::move(c));
        viewMaps = std::move(ss.viewMaps);
    }
    std::tie(summary.distribution.busySecondsMin, summary.distribution.busySecondsMax) = dist.minMax(busy);

    const WriteOutput written = writeTransport(job, prepared, std::move(components), std::move(viewMaps),
                                               std::move(radialBasis), std::move(derived));
    summary.blocks.seconds = written.blockSeconds;
    summary.blocks.retainedEnergy = written.blockRetainedEnergy;
    summary.write = written.summary;
    summary.ground = writeGroundTransport(job, prepared);
    return finished(std::move(summary), start);
}

}  // namespace prt
