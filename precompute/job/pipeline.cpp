#include "precompute/job/pipeline.h"

#include "precompute/passes/cell_quadrature.h"

#include <sys/resource.h>
#include <tbb/task_arena.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <optional>
#include <sstream>
#include <tuple>

#include "common/atomic_file.h"
#include "common/error.h"
#include "precompute/passes/multiple_scattering.h"
#include "precompute/passes/irradiance_transport.h"
#include "precompute/passes/phase_factoring.h"
#include "common/progress.h"
#include "common/raytrace.h"
#include "common/sampling.h"
#include "common/mesh_io.h"
#include "precompute/job/distribution.h"
#include "precompute/job/memory_estimate.h"
#include "precompute/job/pass1_file.h"
#include "precompute/passes/single_scattering.h"
#include "common/sh_part.h"
#include "common/util.h"

namespace prt {

namespace {

std::string fmt(double v) { return formatParameter(v); }

std::string megabytes(size_t bytes) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.0f MB", double(bytes) / 1e6);
    return buf;
}

uint64_t fnv1a(const std::string& text) {
    uint64_t h = 0xcbf29ce484222325ull;
    for (unsigned char c : text) {
        h ^= c;
        h *= 0x100000001b3ull;
    }
    return h;
}

std::string hex(uint64_t v) {
    char buf[17];
    std::snprintf(buf, sizeof buf, "%016llx", (unsigned long long)v);
    return buf;
}

// Digest of everything that determines the output.
std::string inputDigest(const std::vector<std::pair<std::string, std::string>>& params) {
    std::string text;
    for (const auto& [k, v] : params)
        if (k != "input_digest") text += k + "=" + v + "\n";
    return hex(fnv1a(text));
}


// Single-scattering options the pipeline does not expose (recorded in the file).
SingleScatteringOptions singleScatteringOptions(const PrecomputeSettings& s) {
    SingleScatteringOptions o;
    o.cubemapSize = s.cubemapSize;
    o.supersample = s.ssSupersample;
    o.directionStride = s.ssDirectionStride;
    o.visibilityFromExitRay = s.ssVisibilityFromExitRay;
    o.pathSamples = s.pathSamples;
    o.pathQuadrature = s.pathQuadrature;
    o.keepCoefficients = s.vertexCoefficients;
    // Single-scattering vectors stay Haar only: with the SH part the bunny's single
    // scattering alone (g = -0.25, forest) was 5.28% from the reference along -n_o
    // against 4.83% without (docs/single-scattering.md, "Storage"). A file's SH terms
    // only bound its indices, so such components simply use none.
    o.shTerms = 0;
    return o;
}

}  // namespace

size_t peakMemoryBytes() {
    rusage usage{};
    getrusage(RUSAGE_SELF, &usage);
    return size_t(usage.ru_maxrss) * 1024;  // Linux reports kilobytes
}

void validateSettings(const PrecomputeSettings& s) {
    if (s.meshPath.empty()) throw Error("mesh", "no mesh file given");
    if (s.outputPath.empty() && !s.pass1Only) throw Error("--output", "no output path given");
    validateMaterial(s.material);
    if (!isPowerOfTwo(s.cubemapSize) || s.cubemapSize > 64)
        throw Error("--cubemap-size", "must be a power of two between 1 and 64, got " +
                                          std::to_string(s.cubemapSize));
    if (s.supersample < 1 || s.supersample > 8)
        throw Error("--supersample", "must be between 1 and 8, got " + std::to_string(s.supersample));
    const size_t texels = size_t(6) * s.cubemapSize * s.cubemapSize;
    if (!validShTerms(s.shTerms))
        throw Error("--sh-terms", "must be 0, 1, 4 or 9, got " + std::to_string(s.shTerms));
    if (s.shTerms == 9 && s.cubemapSize < 2)
        throw Error("--sh-terms", "9 SH terms need a cubemap of at least 6 x 2 x 2 (use 0, 1 or 4)");
    // Every count includes the SH terms: more than them, at most all of the space.
    const size_t space = texels + size_t(s.shTerms);
    auto checkTerms = [&](const char* name, size_t k) {
        if (k <= size_t(s.shTerms) || k > space)
            throw Error(name, "must be between " + std::to_string(s.shTerms + 1) + " and 6 N^2" +
                                  (s.shTerms ? " + " + std::to_string(s.shTerms) + " SH terms" : std::string()) +
                                  " = " + std::to_string(space) + ", got " + std::to_string(k));
    };
    checkTerms("--sample-coefficients", s.sampleCoefficients);
    checkTerms("--node-coefficients", s.nodeCoefficients);
    checkTerms("--coefficients", s.vertexCoefficients);
    if (s.blockCoefficients > 0) {
        checkTerms("--block-coefficients", s.blockCoefficients);
        if (s.shard)
            throw Error("--block-coefficients", "shard files are per vertex (prt-merge does not join blocked shards yet)");
    }
    if (!(s.epsilon >= 0) || !std::isfinite(s.epsilon))
        throw Error("--epsilon", "must be a finite number >= 0, got " + fmt(s.epsilon));
    if (!(s.sampleSpacingMm >= 0) || !std::isfinite(s.sampleSpacingMm))
        throw Error("--sample-spacing", "must be a positive length in mm, got " + fmt(s.sampleSpacingMm));
    if (s.maxSamples < 1) throw Error("--max-samples", "must be at least 1");
    if (!std::isfinite(s.maxMemoryGb) || s.maxMemoryGb < 0.0)
        throw Error("--max-memory", "must be a finite number of GB >= 0 (0 = the available memory)");
    if (!s.components.multipleScattering && !s.components.singleScattering)
        throw Error("--components", "select at least one of ms, ss");
    // M <= 32: the phase table is (6 M^2)^2 doubles (precompute/passes/phase_factoring.h).
    if (!isPowerOfTwo(s.phaseMapSize) || s.phaseMapSize > 32)
        throw Error("--phase-map-size", "must be a power of two between 1 and 32, got " +
                                            std::to_string(s.phaseMapSize));
    const int phaseTexels = 6 * s.phaseMapSize * s.phaseMapSize;
    if (s.phaseTerms < 1 || s.phaseTerms > phaseTexels)
        throw Error("--phase-terms", "must be between 1 and 6 M^2 = " + std::to_string(phaseTexels) +
                                         ", got " + std::to_string(s.phaseTerms));
    if (s.pathSamples < 1 || s.pathSamples > 4096)
        throw Error("--path-samples", "must be between 1 and 4096, got " + std::to_string(s.pathSamples));
    if (s.ssSupersample < 1 || s.ssSupersample > 8)
        throw Error("--ss-supersample", "must be between 1 and 8, got " + std::to_string(s.ssSupersample));
    if (s.ssDirectionStride < 1 || s.ssDirectionStride > 16 || (s.ssDirectionStride & (s.ssDirectionStride - 1)))
        throw Error("--ss-direction-stride",
                    "must be 1, 2, 4, 8 or 16, got " + std::to_string(s.ssDirectionStride));
    if (!s.pass1File.empty() && !s.components.multipleScattering)
        throw Error("--pass1-file", "needs multiple scattering (--components ms or ms,ss): single scattering has no pass 1");
    if (s.pass1Only && s.pass1File.empty()) throw Error("--pass1-only", "needs --pass1-file");
}

std::vector<std::pair<std::string, std::string>> settingsParameters(const PrecomputeSettings& s,
                                                                    const MeshFingerprint& mesh) {
    std::vector<std::pair<std::string, std::string>> p = {
        {"tool", "prt-precompute 0.1"},
        {"mesh_file", std::filesystem::path(s.meshPath).filename().string()},
        {"mesh_vertices", std::to_string(mesh.vertexCount)},
        {"mesh_hash", hex(mesh.positionHash)},
        {"size_mm", s.scale.sizeMm ? fmt(*s.scale.sizeMm) : ""},
        {"mm_per_unit_requested", s.scale.mmPerUnit ? fmt(*s.scale.mmPerUnit) : ""},
    };
    const ParameterList material = materialParameters(s.material);
    p.insert(p.end(), material.begin(), material.end());
    const ParameterList passes = {
        {"components", toString(s.components)},
        {"cubemap_size", std::to_string(s.cubemapSize)},
        {"supersample", std::to_string(s.supersample)},
        {"pass1_visibility", toString(s.pass1Visibility)},
        {"sample_coefficients", std::to_string(s.sampleCoefficients)},
        {"node_coefficients", std::to_string(s.nodeCoefficients)},
        {"coefficients", std::to_string(s.vertexCoefficients)},
        {"sh_terms", std::to_string(s.shTerms)},
        {"epsilon", fmt(s.epsilon)},
        {"samples_requested", std::to_string(s.sampleCount)},
        {"sample_spacing_requested_mm", fmt(s.sampleSpacingMm)},
        {"max_samples", std::to_string(s.maxSamples)},
        {"seed", std::to_string(s.seed)},
        {"ms_normalisation", "T_d/pi (radiance = F_t(w_o) * dot(vector, light))"},
    };
    p.insert(p.end(), passes.begin(), passes.end());
    // Only blocked files carry it, so per-vertex files (and their digests) are unchanged.
    if (s.blockCoefficients > 0) p.push_back({"block_coefficients", std::to_string(s.blockCoefficients)});
    if (s.components.singleScattering) {
        const SingleScatteringOptions o = singleScatteringOptions(s);
        const bool isotropic = s.material.g == 0.0;
        p.push_back({"ss_phase", isotropic ? "isotropic" : "henyey-greenstein svd"});
        if (!isotropic) {
            p.push_back({"phase_terms", std::to_string(s.phaseTerms)});
            p.push_back({"phase_map_size", std::to_string(s.phaseMapSize)});
        }
        p.push_back({"path_samples", std::to_string(o.pathSamples)});
        p.push_back({"path_quadrature", toString(o.pathQuadrature)});
        p.push_back({"ss_supersample", std::to_string(o.supersample)});
        // Recorded only when it acts, so files made before it keep their digest.
        if (o.directionStride > 1 && o.supersample == 1 && o.cubemapSize >= 2) {
            p.push_back({"ss_direction_stride", std::to_string(o.directionStride)});
            p.push_back({"ss_refine_tolerances", fmt(o.refineValueTolerance) + " " + fmt(o.refineValueFloor) +
                                                     " " + fmt(o.refineLargeCellValue)});
        }
        p.push_back({"ss_path", "inward normal, deterministic importance samples (Wang 2005 Eqs. 10-11)"});
        p.push_back({"ss_depth_cap_mfp", fmt(o.depthCapMeanFreePaths)});
        p.push_back({"ss_min_throughput", fmt(o.minThroughput)});
        // How the rays are traced changes the result slightly (robust traversal), so it
        // is part of the input digest: files made with the non-robust scene are redone.
        // V from the exit ray is recorded (and digested) only where it applies, so files
        // made with the second-ray rule before it existed stay up to date.
        p.push_back({"ss_rays", std::string(o.coherentRays ? "robust scene, coherent packets" : "robust scene, incoherent packets") +
                                    (o.exitRayVisibility() ? ", V from the exit ray" : "")});
        p.push_back({"ss_normalisation",
                     isotropic ? "1/(4 pi) folded in (radiance = F_t(w_o) * dot(vector, light))"
                               : "radiance = F_t(w_o) * sum_k h_k(w_o') * dot(term_k, light), "
                                 "w_o' refracted into the medium"});
    }
    p.push_back({"input_digest", inputDigest(p)});
    return p;
}

std::string PrecomputeSummary::format() const {
    std::ostringstream o;
    char line[256];
    auto add = [&](const char* f, auto... args) {
        std::snprintf(line, sizeof line, f, args...);
        o << line << '\n';
    };
    if (skipped) {
        add("%s: up to date (same mesh and settings), skipped", outputPath.c_str());
        return o.str();
    }
    if (outputPath.empty())
        add("output            none (--pass1-only)");
    else if (ranks > 1)
        add("output            %s (%.2f MB), %d MPI ranks", outputPath.c_str(), fileBytes / 1e6, ranks);
    else if (distribution != "1 process")
        add("output            %s (%.2f MB), %s", outputPath.c_str(), fileBytes / 1e6, distribution.c_str());
    else
        add("output            %s (%.2f MB)", outputPath.c_str(), fileBytes / 1e6);
    add("mesh              %zu vertices, %zu triangles, %.1f mm^2", vertices, triangles, totalAreaMm2);
    if (components.multipleScattering) {
        add("samples           %zu (spacing %.3f mm), %s", samples, sampleSpacingMm,
            formatDuration(samplesSeconds).c_str());
        if (pass1Loaded)
            add("pass 1            loaded from %s in %s", pass1File.c_str(), formatDuration(pass1Seconds).c_str());
        else
            add("pass 1            %s, %.3g rays, %.3g rays/s, retained energy %.4f%s%s",
                formatDuration(pass1Seconds).c_str(), double(raysTraced), pass1RaysPerSecond,
                sampleRetainedEnergy, pass1File.empty() ? "" : ", saved to ", pass1File.c_str());
        if (!outputPath.empty()) {  // not with --pass1-only
            add("pass 2            %s, %.1f nodes visited per vertex, retained energy %.4f",
                formatDuration(pass2Seconds).c_str(), meanNodesVisited, vertexRetainedEnergy);
            add("  sample cells    %zu sub-points in %s", cellSubPoints, formatDuration(cellSeconds).c_str());
        }
    }
    if (blockCoefficients > 0 && !outputPath.empty())
        add("blocks            16 nearby vertices share %zu terms chosen jointly from %zu per vertex, "
            "8-bit values: %s, retained energy %.4f",
            blockCoefficients, blockSourceCoefficients, formatDuration(blockSeconds).c_str(), blockRetainedEnergy);
    if (ranks > 1) {
        add("exchange          pass-1 vectors %.3g MB in %s (%.0f bytes per sample), vertex "
            "vectors gathered in %s",
            pass1ExchangeBytes / 1e6, formatDuration(pass1ExchangeSeconds).c_str(),
            samples ? pass1ExchangeBytes / double(samples) : 0.0, formatDuration(gatherSeconds).c_str());
        add("ranks busy        %s to %s (the even split's balance: %.0f%%)",
            formatDuration(busySecondsMin).c_str(), formatDuration(busySecondsMax).c_str(),
            busySecondsMax > 0 ? 100.0 * busySecondsMin / busySecondsMax : 100.0);
    }
    if (components.singleScattering && !outputPath.empty()) {
        if (ssIsotropic)
            add("phase             isotropic (1/(4 pi) folded into one vector)");
        else
            add("phase             HG svd, %d terms, rms error %.4f, %s", ssTerms, phaseRmsError,
                formatDuration(phaseSeconds).c_str());
        add("single scattering %s, %.3g rays, %.3g rays/s, retained energy %.4f",
            formatDuration(ssSeconds).c_str(), double(ssRaysTraced), ssRaysPerSecond,
            ssRetainedEnergy);
        add("  rays            %.3g exit, %.3g occlusion, %.3g culled (throughput), %.3g escaping, "
            "%.3g exits through reversed triangles, %.3g occluded exits",
            double(ssExitRays), double(ssOcclusionRays), double(ssCulledRays), double(ssEscapedRays),
            double(ssReversedHits), double(ssOccludedExits));
        if (ssInterpolatedTexels > 0)
            add("  directions      %.3g traced, %.3g interpolated from agreeing corners (%.1f%% traced)",
                double(ssTracedTexels), double(ssInterpolatedTexels),
                100.0 * double(ssTracedTexels) / double(ssTracedTexels + ssInterpolatedTexels));
        add("  path            mean d_m %.3f mm, %llu vertices with capped d_m, %llu integrated "
            "along +n (normal pointing inward), %llu path samples outside the object",
            ssMeanDepthMm, (unsigned long long)ssCappedDepths, (unsigned long long)ssFlippedNormals,
            (unsigned long long)ssOutsideSamples);
    }
    add("total             %s, peak memory %.0f MB, estimated %.0f MB (setup %s, write %s)",
        formatDuration(totalSeconds).c_str(), peakMemoryBytes / 1e6, estimatedMemoryBytes / 1e6,
        formatDuration(setupSeconds).c_str(), formatDuration(writeSeconds).c_str());
    // ru_maxrss only grows: each figure is the process's peak up to the end of that stage.
    std::string peaks = "peak memory so far after setup " + megabytes(peakMemoryAfterSetupBytes);
    if (components.multipleScattering)
        peaks += ", samples " + megabytes(peakMemoryAfterSamplesBytes) + ", pass 1 " +
                 megabytes(peakMemoryAfterPass1Bytes) + ", pass 2 " +
                 megabytes(peakMemoryAfterPass2Bytes);
    if (components.singleScattering)
        peaks += ", single scattering " + megabytes(peakMemoryAfterSingleScatteringBytes);
    o << "  " << peaks << '\n';
    return o.str();
}

PrecomputeSummary precomputeTransport(const PrecomputeSettings& settings, bool force,
                                      Distribution* distribution) {
    const Stopwatch start;
    Distribution single;
    std::optional<ShardDistribution> shardOfJob;
    if (settings.shard) {
        if (distribution && distribution->partial())
            throw Error("--shard", "a shard job cannot run under MPI ranks too (use one or the other)");
        shardOfJob.emplace(*settings.shard);
    }
    Distribution& dist = shardOfJob ? *shardOfJob : distribution ? *distribution : single;
    PrecomputeSummary summary;
    summary.outputPath = settings.outputPath;
    summary.components = settings.components;
    summary.blockCoefficients = settings.blockCoefficients;
    summary.blockSourceCoefficients = settings.vertexCoefficients;
    summary.distribution = dist.describe();
    summary.ranks = dist.ranks();
    // A label suffix for the progress lines of a share of the work ("pass 1 [MPI rank 0
    // of 2]"): rank 0's share stands for the whole job's progress and ETA, since the
    // shares are even and run side by side.
    const std::string share = dist.partial() ? " [" + dist.describe() + "]" : "";

    TriangleMesh mesh;
    MeshFingerprint fingerprint;
    std::vector<std::pair<std::string, std::string>> params;
    bool upToDate = false;
    dist.stage([&] {
        validateSettings(settings);
        if (dist.writes() && !settings.outputPath.empty())
            checkOutputPath(settings.outputPath);  // now, not after an hour of passes
        if (dist.writes() && !settings.pass1File.empty()) checkOutputPath(settings.pass1File);
        mesh = loadMesh(settings.meshPath);
        fingerprint = MeshFingerprint{mesh.vertexCount(), meshFingerprint(mesh)};
        params = settingsParameters(settings, fingerprint);
        const std::string digest = params.back().second;
        if (force || !dist.writes() || settings.pass1Only || !std::filesystem::exists(settings.outputPath)) return;
        try {
            const TransportFileInfo info = readTransportFileInfo(settings.outputPath);
            bool same = info.parameter("input_digest") == digest && info.mesh == fingerprint;
            for (const auto& [key, value] : dist.outputParameters(mesh.vertexCount()))
                same = same && info.parameter(key) == value;
            // A whole file is not up to date for a shard job nor a shard for a whole job.
            same = same && info.hasParameter(kShardParameter) == dist.shard();
            if (same) {
                loadTransportFile(settings.outputPath);  // every checksum
                upToDate = true;
            }
        } catch (const Error&) {
            // Not valid: recompute and replace it.
        }
    });
    if (dist.agree(upToDate)) {
        summary.skipped = true;
        return summary;
    }

    TransportFile file;
    double mmPerUnit = 1.0;
    double busy = 0.0;  // this process's compute seconds (pass 1, pass 2, single scattering)
    std::vector<std::pair<std::string, std::string>> derived;
    std::optional<RayScene> scene;
    const size_t coefficientCount = size_t(6) * settings.cubemapSize * settings.cubemapSize;
    const std::vector<IndexRange> vertexShares = dist.vertexShares(mesh.vertexCount());
    const size_t myVertices = totalSize(vertexShares);
    summary.computedVertices = size_t(dist.sum(double(myVertices)));
    dist.stage([&] {
        mmPerUnit = scaleToPhysical(mesh, settings.scale);
        summary.vertices = mesh.vertexCount();
        summary.triangles = mesh.triangleCount();
        summary.totalAreaMm2 = totalArea(mesh);
        file.cubemapSize = uint32_t(settings.cubemapSize);
        file.shTerms = uint32_t(settings.shTerms);
        file.mesh = fingerprint;
        file.mmPerUnit = mmPerUnit;
        file.parameters = params;
        derived.push_back({"mm_per_unit", fmt(mmPerUnit)});
        if (settings.components.multipleScattering) scene.emplace(mesh);
        summary.setupSeconds = start.seconds();
        summary.peakMemoryAfterSetupBytes = peakMemoryBytes();
        if (!settings.components.multipleScattering) {  // single scattering alone: no samples
            const MemoryEstimate need = estimatePrecomputeMemory(settings, mesh.vertexCount(), mesh.triangleCount(),
                                                                 0, tbb::this_task_arena::max_concurrency());
            checkMemory(need, settings.maxMemoryGb);
            summary.estimatedMemoryBytes = need.bytes;
        }
    });

    if (settings.components.multipleScattering) {
        SampleSet samples;
        IndexRange sampleShare;
        IrradianceResult pass1;
        // A pass-1 file that exists is read by every process (rank 0 decides, so all agree).
        summary.pass1File = settings.pass1File;
        const bool pass1FromFile =
            dist.agree(!settings.pass1File.empty() && std::filesystem::exists(settings.pass1File));
        std::string pass1KeyText;
        dist.stage([&] {
            // Samples: spacing about the mean free path l_u = 1 / sigma_t' (Jensen-Buhler).
            const double spacing = settings.sampleSpacingMm > 0 ? settings.sampleSpacingMm
                                                                : settings.material.minMeanFreePath();
            const size_t sampleCount =
                settings.sampleCount > 0
                    ? settings.sampleCount
                    : defaultSampleCount(summary.totalAreaMm2, spacing, settings.maxSamples);
            // Before any allocation that grows with the job: refuse what cannot fit.
            const MemoryEstimate need =
                estimatePrecomputeMemory(settings, mesh.vertexCount(), mesh.triangleCount(), sampleCount,
                                         tbb::this_task_arena::max_concurrency(), summary.totalAreaMm2);
            checkMemory(need, settings.maxMemoryGb);
            summary.estimatedMemoryBytes = need.bytes;
            const Stopwatch samplesStart;
            {
                Progress p("samples", sampleCount, "samples");
                samples = poissonDiskSamples(mesh, sampleCount, settings.seed);
                p.advance(sampleCount);
            }
            summary.samplesSeconds = samplesStart.seconds();
            summary.peakMemoryAfterSamplesBytes = peakMemoryBytes();
            summary.samples = samples.samples.size();
            summary.sampleSpacingMm = std::sqrt(2.0 * samples.areaPerSample / std::sqrt(3.0));
            derived.push_back({"samples", std::to_string(summary.samples)});
            derived.push_back({"sample_area_mm2", fmt(samples.areaPerSample)});
            if (!settings.pass1File.empty())
                pass1KeyText = pass1Key(params, mmPerUnit, samples.samples.size());
            if (pass1FromFile) {
                const Stopwatch loadStart;
                pass1.vectors = loadPass1File(settings.pass1File, pass1KeyText);
                pass1.seconds = loadStart.seconds();
                summary.pass1Loaded = true;
                sampleShare = {0, samples.samples.size()};
                return;
            }

            // Pass 1: irradiance transport per sample (this process's share of them).
            sampleShare = dist.sampleShare(samples.samples.size());
            SampleSet mine;
            mine.areaPerSample = samples.areaPerSample;
            mine.samples.assign(samples.samples.begin() + ptrdiff_t(sampleShare.begin),
                                samples.samples.begin() + ptrdiff_t(sampleShare.end));
            IrradianceOptions irradiance;
            irradiance.cubemapSize = settings.cubemapSize;
            irradiance.supersample = settings.supersample;
            irradiance.sampling = settings.pass1Visibility;
            irradiance.keepCoefficients = settings.sampleCoefficients;
            irradiance.shTerms = settings.shTerms;
            irradiance.eta = settings.material.eta;
            Progress p("pass 1 (irradiance transport)" + share, mine.samples.size(), "samples");
            pass1 = computeIrradianceTransport(&*scene, mine, irradiance, &p);
            busy += pass1.seconds;
        });
        const Stopwatch exchangeStart;
        // What MpiDistribution::gatherSamples sends: two 8-byte counts + 8 bytes per coefficient.
        for (const SparseVector& v : pass1.vectors) summary.pass1ExchangeBytes += 16 + 8 * double(v.size());
        if (!pass1FromFile) pass1.vectors = dist.gatherSamples(std::move(pass1.vectors), samples.samples.size());
        summary.pass1ExchangeBytes = dist.ranks() > 1 ? dist.sum(summary.pass1ExchangeBytes) : 0.0;
        summary.pass1ExchangeSeconds = exchangeStart.seconds();
        summary.raysTraced = uint64_t(dist.sum(double(pass1.raysTraced)));
        summary.pass1Seconds = pass1.seconds + summary.pass1ExchangeSeconds;
        // All ranks' rays over this rank's time: the shares run side by side.
        summary.pass1RaysPerSecond = pass1.seconds > 0 ? double(summary.raysTraced) / pass1.seconds : 0;
        summary.sampleRetainedEnergy =
            dist.sum(pass1.retainedEnergyFraction * double(sampleShare.size())) / double(samples.samples.size());
        summary.peakMemoryAfterPass1Bytes = peakMemoryBytes();
        if (!settings.pass1File.empty() && !pass1FromFile)
            dist.stage([&] {
                if (dist.writes()) savePass1File(settings.pass1File, pass1KeyText, pass1.vectors);
            });
        if (settings.pass1Only) {
            summary.totalSeconds = start.seconds();
            summary.peakMemoryBytes = peakMemoryBytes();
            return summary;
        }

        // Pass 2: hierarchical integration per vertex (this process's share of them).
        std::vector<SparseVector> transport;
        MultipleScatteringStats stats;
        const Stopwatch pass2Start;
        dist.stage([&] {
            SampleCloud cloud;
            cloud.positions.reserve(samples.samples.size());
            std::vector<glm::vec3> normals;
            normals.reserve(samples.samples.size());
            for (const SurfaceSample& s : samples.samples) {
                cloud.positions.push_back(s.position);
                normals.push_back(s.geometricNormal);
            }
            // The converged quadrature of Eq. 7 (cell_quadrature.h): E constant over each
            // sample's Voronoi cell, R_d integrated over the cells near each vertex.
            const Stopwatch cellsStart;
            const CellQuadrature cells(mesh, cloud.positions, normals, summary.sampleSpacingMm, settings.material);
            summary.cellSeconds = cellsStart.seconds();
            summary.cellSubPoints = cells.subPointCount();
            cloud.areas.assign(cells.cellAreas().begin(), cells.cellAreas().end());
            cloud.irradiance = std::move(pass1.vectors);
            HierarchyOptions hierarchy;
            hierarchy.epsilon = settings.epsilon;
            hierarchy.nodeCoefficients = settings.nodeCoefficients;
            hierarchy.vertexCoefficients = settings.vertexCoefficients;
            hierarchy.shTerms = settings.shTerms;
            hierarchy.sampleShFrom = settings.shTerms > 0 ? uint32_t(coefficientCount) : UINT32_MAX;
            SampleTree tree(std::move(cloud), hierarchy);
            std::vector<glm::vec3> positions;
            positions.reserve(myVertices);
            for (const IndexRange& r : vertexShares)
                positions.insert(positions.end(), mesh.positions.begin() + ptrdiff_t(r.begin),
                                 mesh.positions.begin() + ptrdiff_t(r.end));
            Progress p("pass 2 (multiple scattering)" + share, myVertices, "vertices");
            transport = multipleScatteringTransport(tree, positions, settings.material, hierarchy,
                                                    coefficientCount, &stats, &p, &cells);
            busy += pass2Start.seconds();
        });
        // Means over the vertices computed (all ranks'; a shard's own range).
        const double vertexWeight =
            summary.computedVertices ? double(myVertices) / double(summary.computedVertices) : 0.0;
        summary.meanNodesVisited = dist.sum(stats.meanNodesVisited * vertexWeight);
        summary.vertexRetainedEnergy = dist.sum(stats.retainedEnergyFraction * vertexWeight);

        TransportComponent ms;
        ms.kind = ComponentKind::MultipleScattering;
        ms.vectors.reserve(transport.size(), transport.size() * settings.vertexCoefficients);
        for (const SparseVector& v : transport) ms.vectors.appendVertex(v.index, v.value);
        transport.clear();
        const Stopwatch gatherStart;
        ms.vectors = dist.gatherVertices(std::move(ms.vectors), mesh.vertexCount());
        summary.gatherSeconds += gatherStart.seconds();
        file.components.push_back(std::move(ms));
        summary.pass2Seconds = pass2Start.seconds();
        // After the copy into the file's arrays, which coexists with the per-vertex vectors.
        summary.peakMemoryAfterPass2Bytes = peakMemoryBytes();
    }

    if (settings.components.singleScattering) {
        std::optional<PhaseFactorization> phase;
        std::vector<TransportComponent> ss;
        SingleScatteringResult result;
        int terms = 0;
        bool isotropic = true;
        dist.stage([&] {
            // Phase: isotropic for g = 0, else the K-term SVD of HG(g) (precompute/passes/phase_factoring.h).
            if (settings.material.g != 0.0) {
                const Stopwatch phaseStart;
                phase = factorPhaseFunction(settings.material.g, settings.phaseTerms,
                                            settings.phaseMapSize);
                summary.phaseSeconds = phaseStart.seconds();
                summary.phaseRmsError = phaseApproximationError(*phase, settings.phaseTerms);
                derived.push_back({"phase_rms_error", fmt(summary.phaseRmsError)});
            }
            // Robust traversal, traced in coherent packets (SingleScatteringOptions::
            // coherentRays): fewer rays slip through shared edges than with the non-robust
            // scene this pass used before (escaping exit rays 28,803 -> 22,461 on
            // dragon_vrip_res4), and the coherent flag more than pays for robustness
            // (1.26x the non-robust incoherent pass; docs/single-scattering.md, "Speed").
            const RayScene ssScene(mesh, RaySceneOptions{RayBuildQuality::High, true});
            const SingleScatteringContext context(ssScene, mesh, settings.material,
                                                  phase ? &*phase : nullptr,
                                                  singleScatteringOptions(settings));
            terms = context.terms();
            isotropic = context.isotropic();
            ss.resize(static_cast<size_t>(terms));
            for (int k = 0; k < terms; ++k) {
                ss[size_t(k)].kind = context.isotropic() ? ComponentKind::SingleScatteringIsotropic
                                                         : ComponentKind::SingleScatteringTerm;
                ss[size_t(k)].term = context.isotropic() ? 0 : uint32_t(k);
                ss[size_t(k)].vectors.reserve(myVertices, myVertices * settings.vertexCoefficients);
            }
            Progress p((context.isotropic() ? "single scattering (isotropic)"
                                            : "single scattering (" + std::to_string(terms) + " terms)") +
                           share,
                       myVertices, "vertices");
            double retained = 0.0;
            for (const IndexRange& r : vertexShares) {
                const SingleScatteringResult part = computeSingleScattering(
                    context,
                    [&](size_t, const std::vector<SparseVector>& vectors) {
                        for (int k = 0; k < terms; ++k)
                            ss[size_t(k)].vectors.appendVertex(vectors[size_t(k)].index,
                                                               vectors[size_t(k)].value);
                    },
                    &p, std::pair{r.begin, r.end});
                result.stats.add(part.stats);
                result.seconds += part.seconds;
                retained += part.retainedEnergyFraction * double(r.size());
            }
            result.isotropic = context.isotropic();
            result.terms = terms;
            result.retainedEnergyFraction = myVertices ? retained / double(myVertices) : 1.0;
            busy += result.seconds;
        });
        const Stopwatch gatherStart;
        for (TransportComponent& c : ss) {
            c.vectors = dist.gatherVertices(std::move(c.vectors), mesh.vertexCount());
            file.components.push_back(std::move(c));
        }
        summary.gatherSeconds += gatherStart.seconds();
        if (phase) {
            ViewMaps maps;
            maps.size = phase->mapSize;
            maps.terms = terms;
            for (const Cubemap& h : phase->viewMaps)
                maps.data.insert(maps.data.end(), h.data().begin(), h.data().end());
            file.viewMaps = std::move(maps);
        }
        summary.ssTerms = terms;
        summary.ssIsotropic = isotropic;
        summary.ssSeconds = result.seconds;
        const SingleScatteringStats& st = result.stats;
        auto total = [&](uint64_t v) { return uint64_t(dist.sum(double(v))); };
        summary.ssRaysTraced = total(st.rays());
        summary.ssExitRays = total(st.exitRays);
        summary.ssOcclusionRays = total(st.occlusionRays);
        summary.ssOccludedExits = total(st.occludedExits);
        summary.ssCulledRays = total(st.culledRays);
        summary.ssTracedTexels = total(st.tracedTexels);
        summary.ssInterpolatedTexels = total(st.interpolatedTexels);
        summary.ssReversedHits = total(st.reversedHits);
        summary.ssOutsideSamples = total(st.outsideSamples);
        summary.ssFlippedNormals = total(st.flippedNormals);
        summary.ssEscapedRays = total(st.escapedRays);
        summary.ssCappedDepths = total(st.cappedDepths);
        summary.ssRaysPerSecond = result.seconds > 0 ? double(summary.ssRaysTraced) / result.seconds : 0.0;
        summary.ssMeanDepthMm =
            summary.computedVertices ? dist.sum(st.depthSum) / double(summary.computedVertices) : 0.0;
        summary.ssRetainedEnergy =
            summary.computedVertices
                ? dist.sum(result.retainedEnergyFraction * double(myVertices)) / double(summary.computedVertices)
                : 1.0;
        summary.peakMemoryAfterSingleScatteringBytes = peakMemoryBytes();
    }

    std::tie(summary.busySecondsMin, summary.busySecondsMax) = dist.minMax(busy);
    dist.stage([&] {
        if (!dist.writes()) return;
        // Derived values (and a shard's identity) go before the digest, which stays the
        // last parameter.
        if (settings.blockCoefficients > 0) {
            // The joint choice needs every vertex's vectors: after the gather, on the writer.
            const Stopwatch blockStart;
            const std::vector<uint32_t> order = spatialBlockOrder(mesh.positions);
            double retained = 0.0;
            for (TransportComponent& c : file.components) {
                c.blocks = jointTruncate(c.vectors, settings.blockCoefficients, order,
                                         settings.shTerms > 0 ? uint32_t(coefficientCount) : UINT32_MAX);
                retained += retainedEnergyFraction(c.vectors, c.blocks);
                c.vectors = SparseRgbVectors();  // frees the 512-term arrays
            }
            summary.blockSeconds = blockStart.seconds();
            summary.blockRetainedEnergy = file.components.empty() ? 1.0 : retained / double(file.components.size());
            derived.push_back({"block_retained_energy", fmt(summary.blockRetainedEnergy)});
        }
        const auto shard = dist.outputParameters(mesh.vertexCount());
        derived.insert(derived.end(), shard.begin(), shard.end());
        file.parameters.insert(file.parameters.end() - 1, derived.begin(), derived.end());
        const Stopwatch writeStart;
        saveTransportFile(settings.outputPath, file);
        summary.writeSeconds = writeStart.seconds();
        summary.fileBytes = std::filesystem::file_size(settings.outputPath);
    });
    summary.totalSeconds = start.seconds();
    summary.peakMemoryBytes = peakMemoryBytes();
    return summary;
}

}  // namespace prt
