#include "common/precompute.h"

#include <sys/resource.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <sstream>

#include "common/error.h"
#include "common/hierarchy.h"
#include "common/irradiance.h"
#include "common/progress.h"
#include "common/raytrace.h"
#include "common/sampling.h"

namespace prt {

namespace {

std::string fmt(double v) {
    char buf[64];
    std::snprintf(buf, sizeof buf, "%.9g", v);
    return buf;
}
std::string fmt(const glm::dvec3& v) { return fmt(v.x) + "," + fmt(v.y) + "," + fmt(v.z); }

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

double seconds(std::chrono::steady_clock::time_point since) {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - since).count();
}

}  // namespace

size_t peakMemoryBytes() {
    rusage usage{};
    getrusage(RUSAGE_SELF, &usage);
    return size_t(usage.ru_maxrss) * 1024;  // Linux reports kilobytes
}

void validateSettings(const PrecomputeSettings& s) {
    if (s.meshPath.empty()) throw Error("mesh", "no mesh file given");
    if (s.outputPath.empty()) throw Error("--output", "no output path given");
    validateMaterial(s.material);
    if (!isPowerOfTwo(s.cubemapSize) || s.cubemapSize > 64)
        throw Error("--cubemap-size", "must be a power of two between 1 and 64, got " +
                                          std::to_string(s.cubemapSize));
    if (s.supersample < 1 || s.supersample > 8)
        throw Error("--supersample", "must be between 1 and 8, got " + std::to_string(s.supersample));
    const size_t texels = size_t(6) * s.cubemapSize * s.cubemapSize;
    auto checkTerms = [&](const char* name, size_t k) {
        if (k < 1 || k > texels)
            throw Error(name, "must be between 1 and 6 N^2 = " + std::to_string(texels) + ", got " +
                                  std::to_string(k));
    };
    checkTerms("--sample-coefficients", s.sampleCoefficients);
    checkTerms("--node-coefficients", s.nodeCoefficients);
    checkTerms("--coefficients", s.vertexCoefficients);
    if (!(s.epsilon >= 0) || !std::isfinite(s.epsilon))
        throw Error("--epsilon", "must be a finite number >= 0, got " + fmt(s.epsilon));
    if (!(s.sampleSpacingMm >= 0) || !std::isfinite(s.sampleSpacingMm))
        throw Error("--sample-spacing", "must be a positive length in mm, got " + fmt(s.sampleSpacingMm));
    if (s.maxSamples < 1) throw Error("--max-samples", "must be at least 1");
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
        {"material", s.material.name},
        {"sigma_s_prime", fmt(s.material.sigmaSPrime)},
        {"sigma_a", fmt(s.material.sigmaA)},
        {"eta", fmt(s.material.eta)},
        {"g", fmt(s.material.g)},
        {"components", "ms"},
        {"cubemap_size", std::to_string(s.cubemapSize)},
        {"supersample", std::to_string(s.supersample)},
        {"sample_coefficients", std::to_string(s.sampleCoefficients)},
        {"node_coefficients", std::to_string(s.nodeCoefficients)},
        {"coefficients", std::to_string(s.vertexCoefficients)},
        {"epsilon", fmt(s.epsilon)},
        {"samples_requested", std::to_string(s.sampleCount)},
        {"sample_spacing_requested_mm", fmt(s.sampleSpacingMm)},
        {"max_samples", std::to_string(s.maxSamples)},
        {"seed", std::to_string(s.seed)},
        {"ms_normalisation", "T_d/pi (radiance = F_t(w_o) * dot(vector, light))"},
    };
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
    add("output            %s (%.2f MB)", outputPath.c_str(), fileBytes / 1e6);
    add("mesh              %zu vertices, %zu triangles, %.1f mm^2", vertices, triangles, totalAreaMm2);
    add("samples           %zu (spacing %.3f mm)", samples, sampleSpacingMm);
    add("pass 1            %s, %.3g rays, %.3g rays/s, retained energy %.4f",
        formatDuration(pass1Seconds).c_str(), double(raysTraced), pass1RaysPerSecond,
        sampleRetainedEnergy);
    add("pass 2            %s, %.1f nodes visited per vertex, retained energy %.4f",
        formatDuration(pass2Seconds).c_str(), meanNodesVisited, vertexRetainedEnergy);
    add("total             %s, peak memory %.0f MB", formatDuration(totalSeconds).c_str(),
        peakMemoryBytes / 1e6);
    return o.str();
}

PrecomputeSummary precomputeTransport(const PrecomputeSettings& settings, bool force) {
    const auto start = std::chrono::steady_clock::now();
    validateSettings(settings);
    PrecomputeSummary summary;
    summary.outputPath = settings.outputPath;

    TriangleMesh mesh = loadMesh(settings.meshPath);
    const MeshFingerprint fingerprint{mesh.vertexCount(), meshFingerprint(mesh)};
    const auto params = settingsParameters(settings, fingerprint);
    const std::string digest = params.back().second;

    if (!force && std::filesystem::exists(settings.outputPath)) {
        try {
            TransportFileInfo info = readTransportFileInfo(settings.outputPath);
            if (info.parameter("input_digest") == digest && info.mesh == fingerprint) {
                loadTransportFile(settings.outputPath, fingerprint);  // every checksum
                summary.skipped = true;
                return summary;
            }
        } catch (const Error&) {
            // Not valid: recompute and replace it.
        }
    }

    const double mmPerUnit = scaleToPhysical(mesh, settings.scale);
    summary.vertices = mesh.vertexCount();
    summary.triangles = mesh.triangleCount();
    summary.totalAreaMm2 = totalArea(mesh);

    // Samples: spacing about the mean free path l_u = 1 / sigma_t' (Jensen-Buhler).
    const double spacing = settings.sampleSpacingMm > 0 ? settings.sampleSpacingMm
                                                        : settings.material.minMeanFreePath();
    const size_t sampleCount =
        settings.sampleCount > 0 ? settings.sampleCount
                                 : defaultSampleCount(summary.totalAreaMm2, spacing, settings.maxSamples);
    SampleSet samples;
    {
        Progress p("samples", sampleCount, "samples");
        samples = poissonDiskSamples(mesh, sampleCount, settings.seed);
        p.advance(sampleCount);
    }
    summary.samples = samples.samples.size();
    summary.sampleSpacingMm = std::sqrt(2.0 * samples.areaPerSample / std::sqrt(3.0));

    // Pass 1: irradiance transport per sample.
    RayScene scene(mesh);
    IrradianceOptions irradiance;
    irradiance.cubemapSize = settings.cubemapSize;
    irradiance.supersample = settings.supersample;
    irradiance.keepCoefficients = settings.sampleCoefficients;
    irradiance.eta = settings.material.eta;
    IrradianceResult pass1;
    {
        Progress p("pass 1 (irradiance transport)", samples.samples.size(), "samples");
        pass1 = computeIrradianceTransport(&scene, samples, irradiance, &p);
    }
    summary.raysTraced = pass1.raysTraced;
    summary.pass1Seconds = pass1.seconds;
    summary.pass1RaysPerSecond = pass1.seconds > 0 ? pass1.raysTraced / pass1.seconds : 0;
    summary.sampleRetainedEnergy = pass1.retainedEnergyFraction;

    // Pass 2: hierarchical integration per vertex.
    SampleCloud cloud;
    cloud.positions.reserve(samples.samples.size());
    for (const SurfaceSample& s : samples.samples) cloud.positions.push_back(s.position);
    cloud.areas.assign(samples.samples.size(), float(samples.areaPerSample));
    cloud.irradiance = std::move(pass1.vectors);
    HierarchyOptions hierarchy;
    hierarchy.epsilon = settings.epsilon;
    hierarchy.nodeCoefficients = settings.nodeCoefficients;
    hierarchy.vertexCoefficients = settings.vertexCoefficients;
    const size_t coefficientCount = size_t(6) * settings.cubemapSize * settings.cubemapSize;
    std::vector<SparseVector> transport;
    MultipleScatteringStats stats;
    const auto pass2Start = std::chrono::steady_clock::now();
    {
        SampleTree tree(std::move(cloud), hierarchy);
        Progress p("pass 2 (multiple scattering)", mesh.vertexCount(), "vertices");
        transport = multipleScatteringTransport(tree, mesh.positions, settings.material, hierarchy,
                                                coefficientCount, &stats, &p);
    }
    summary.pass2Seconds = seconds(pass2Start);
    summary.meanNodesVisited = stats.meanNodesVisited;
    summary.vertexRetainedEnergy = stats.retainedEnergyFraction;

    // Output.
    TransportFile file;
    file.cubemapSize = uint32_t(settings.cubemapSize);
    file.mesh = fingerprint;
    file.mmPerUnit = mmPerUnit;
    file.parameters = params;
    file.parameters.insert(file.parameters.end() - 1,
                           {{"mm_per_unit", fmt(mmPerUnit)},
                            {"samples", std::to_string(summary.samples)},
                            {"sample_area_mm2", fmt(samples.areaPerSample)}});
    TransportComponent ms;
    ms.kind = ComponentKind::MultipleScattering;
    ms.vectors.reserve(transport.size(), transport.size() * settings.vertexCoefficients);
    for (const SparseVector& v : transport) ms.vectors.appendVertex(v.index, v.value);
    transport.clear();
    file.components.push_back(std::move(ms));
    saveTransportFile(settings.outputPath, file);

    summary.fileBytes = std::filesystem::file_size(settings.outputPath);
    summary.totalSeconds = seconds(start);
    summary.peakMemoryBytes = peakMemoryBytes();
    return summary;
}

}  // namespace prt
