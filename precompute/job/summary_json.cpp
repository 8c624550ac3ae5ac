#include "precompute/job/summary_json.h"

#include <tbb/global_control.h>

#include <cstdlib>
#include <ctime>
#include <thread>

#include "common/atomic_file.h"
#include "common/error.h"

namespace prt {

namespace {

Json vec3(const glm::dvec3& v) { return Json::array({v.x, v.y, v.z}); }

std::string utcNow() {
    const std::time_t t = std::time(nullptr);
    std::tm tm{};
    gmtime_r(&t, &tm);
    char buf[32];
    std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%SZ", &tm);
    return buf;
}

}  // namespace


Json settingsJson(const PrecomputeSettings& s) {
    Json j;
    j["mesh"] = s.meshPath;
    j["output"] = s.outputPath;
    j["size_mm"] = s.scale.sizeMm ? Json(*s.scale.sizeMm) : Json(nullptr);
    j["mm_per_unit"] = s.scale.mmPerUnit ? Json(*s.scale.mmPerUnit) : Json(nullptr);
    j["material"] = s.material.name;
    j["sigma_s_prime"] = vec3(s.material.sigmaSPrime);
    j["sigma_a"] = vec3(s.material.sigmaA);
    j["eta"] = s.material.eta;
    j["g"] = s.material.g;
    j["components"] = toString(s.components);
    j["cubemap_size"] = s.cubemapSize;
    j["supersample"] = s.supersample;
    j["pass1_visibility"] = toString(s.pass1Visibility);
    j["sample_coefficients"] = s.sampleCoefficients;
    j["node_coefficients"] = s.nodeCoefficients;
    j["coefficients"] = s.vertexCoefficients;
    j["sh_terms"] = s.shTerms;
    j["epsilon"] = s.epsilon;
    j["samples_requested"] = s.sampleCount;            // 0: from the spacing
    j["sample_spacing_mm_requested"] = s.sampleSpacingMm;  // 0: the mean free path
    j["max_samples"] = s.maxSamples;
    j["seed"] = s.seed;
    j["phase_terms"] = s.phaseTerms;
    j["phase_map_size"] = s.phaseMapSize;
    j["path_quadrature"] = toString(s.pathQuadrature);
    j["path_samples"] = s.pathSamples;
    j["ss_supersample"] = s.ssSupersample;
    j["ss_direction_stride"] = s.ssDirectionStride;
    j["shard"] = s.shard ? Json(toString(*s.shard)) : Json(nullptr);
    j["pass1_file"] = s.pass1File.empty() ? Json(nullptr) : Json(s.pass1File);
    j["pass1_only"] = s.pass1Only;
    return j;
}

// Every field of the summary; fields of a stage that did not run are null. The
// peak_memory_after_* values are ru_maxrss read at the end of each stage: the
// process's peak so far (it only grows), not the stage's own use.
Json summaryJson(const PrecomputeSummary& r) {
    Json j;
    j["output"] = r.outputPath;
    j["skipped"] = r.skipped;
    j["components"] = toString(r.components);
    if (r.skipped) return j;  // nothing was computed
    j["distribution"] = r.distribution;
    j["pass1_loaded"] = r.pass1Loaded;
    j["ranks"] = r.ranks;
    j["pass1_exchange_bytes"] = r.pass1ExchangeBytes;
    j["pass1_exchange_seconds"] = r.pass1ExchangeSeconds;
    j["gather_seconds"] = r.gatherSeconds;
    j["busy_seconds_min"] = r.busySecondsMin;
    j["busy_seconds_max"] = r.busySecondsMax;
    const bool ms = r.components.multipleScattering, ss = r.components.singleScattering;
    const auto msOnly = [&](const Json& v) { return ms ? v : Json(nullptr); };
    const auto ssOnly = [&](const Json& v) { return ss ? v : Json(nullptr); };
    const double vertices = double(r.vertices);
    const auto perVertex = [&](double v) { return vertices > 0 ? Json(v / vertices) : Json(nullptr); };
    j["vertices"] = r.vertices;
    j["computed_vertices"] = r.computedVertices;
    j["triangles"] = r.triangles;
    j["total_area_mm2"] = r.totalAreaMm2;
    j["samples"] = msOnly(r.samples);
    j["sample_spacing_mm"] = msOnly(r.sampleSpacingMm);
    // Wall-clock seconds per stage.
    j["setup_seconds"] = r.setupSeconds;
    j["samples_seconds"] = msOnly(r.samplesSeconds);
    j["pass1_seconds"] = msOnly(r.pass1Seconds);
    j["pass2_seconds"] = msOnly(r.pass2Seconds);
    j["phase_seconds"] = ssOnly(r.phaseSeconds);
    j["ss_seconds"] = ssOnly(r.ssSeconds);
    j["write_seconds"] = r.writeSeconds;
    j["total_seconds"] = r.totalSeconds;
    // Pass 1 and pass 2.
    j["pass1_rays"] = msOnly(r.raysTraced);
    j["pass1_rays_per_second"] = msOnly(r.pass1RaysPerSecond);
    j["sample_retained_energy"] = msOnly(r.sampleRetainedEnergy);
    j["mean_nodes_visited"] = msOnly(r.meanNodesVisited);
    j["cell_sub_points"] = msOnly(double(r.cellSubPoints));
    j["cell_seconds"] = msOnly(r.cellSeconds);
    j["vertex_retained_energy"] = msOnly(r.vertexRetainedEnergy);
    // Blocks (null for per-vertex files).
    const bool blocked = r.blockCoefficients > 0;
    j["block_coefficients"] = blocked ? Json(r.blockCoefficients) : Json(nullptr);
    j["block_seconds"] = blocked ? Json(r.blockSeconds) : Json(nullptr);
    j["block_retained_energy"] = blocked ? Json(r.blockRetainedEnergy) : Json(nullptr);
    // Single scattering.
    j["ss_terms"] = ssOnly(r.ssTerms);
    j["ss_isotropic"] = ssOnly(r.ssIsotropic);
    j["phase_rms_error"] = ssOnly(r.phaseRmsError);
    j["ss_rays"] = ssOnly(r.ssRaysTraced);
    j["ss_exit_rays"] = ssOnly(r.ssExitRays);
    j["ss_occlusion_rays"] = ssOnly(r.ssOcclusionRays);
    j["ss_culled_rays"] = ssOnly(r.ssCulledRays);
    j["ss_occluded_exits"] = ssOnly(r.ssOccludedExits);
    j["ss_traced_texels"] = ssOnly(r.ssTracedTexels);
    j["ss_interpolated_texels"] = ssOnly(r.ssInterpolatedTexels);
    j["ss_escaped_rays"] = ssOnly(r.ssEscapedRays);
    j["ss_reversed_hits"] = ssOnly(r.ssReversedHits);
    j["ss_outside_samples"] = ssOnly(r.ssOutsideSamples);
    j["ss_flipped_normals"] = ssOnly(r.ssFlippedNormals);
    j["ss_capped_depths"] = ssOnly(r.ssCappedDepths);
    j["ss_rays_per_second"] = ssOnly(r.ssRaysPerSecond);
    j["ss_mean_depth_mm"] = ssOnly(r.ssMeanDepthMm);
    j["ss_retained_energy"] = ssOnly(r.ssRetainedEnergy);
    // Output and memory.
    j["file_bytes"] = r.fileBytes;
    j["peak_memory_bytes"] = r.peakMemoryBytes;
    j["peak_memory_after_setup_bytes"] = r.peakMemoryAfterSetupBytes;
    j["peak_memory_after_samples_bytes"] = msOnly(r.peakMemoryAfterSamplesBytes);
    j["peak_memory_after_pass1_bytes"] = msOnly(r.peakMemoryAfterPass1Bytes);
    j["peak_memory_after_pass2_bytes"] = msOnly(r.peakMemoryAfterPass2Bytes);
    j["peak_memory_after_ss_bytes"] = ssOnly(r.peakMemoryAfterSingleScatteringBytes);
    // Derived per-item figures (for tables and scaling plots).
    j["pass1_seconds_per_sample"] =
        ms && r.samples > 0 ? Json(r.pass1Seconds / double(r.samples)) : Json(nullptr);
    // Per computed vertex (a shard's own range; all vertices otherwise).
    const double computed = double(r.computedVertices);
    const auto perComputed = [&](double v) { return computed > 0 ? Json(v / computed) : Json(nullptr); };
    j["pass2_seconds_per_vertex"] = ms ? perComputed(r.pass2Seconds) : Json(nullptr);
    j["ss_seconds_per_vertex"] = ss ? perComputed(r.ssSeconds) : Json(nullptr);
    j["ss_rays_per_vertex"] = ss ? perComputed(double(r.ssRaysTraced)) : Json(nullptr);
    j["file_bytes_per_vertex"] = perVertex(double(r.fileBytes));
    return j;
}

Json loadAverage() {
    double l[3] = {0, 0, 0};
    if (getloadavg(l, 3) != 3) return nullptr;
    return Json::array({l[0], l[1], l[2]});
}


// The command line as one string, arguments with shell-special characters quoted.
std::string commandLine(int argc, char** argv) {
    std::string out;
    for (int i = 0; i < argc; ++i) {
        std::string a = argv[i];
        if (a.empty() || a.find_first_of(" \t\n'\"\\$`*?[]{}()<>|&;#~!") != std::string::npos) {
            std::string q = "'";
            for (char c : a) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
            a = q + "'";
        }
        out += (i ? " " : "") + a;
    }
    return out;
}

// Fails early (before a long job) when the JSON could not be written at the end.
void checkJsonPath(const std::string& path) {
    try {
        checkOutputPath(path);
    } catch (const Error& e) {
        throw Error(path, e.reason() + " (--summary-json)");
    }
}

void writeJsonAtomically(const std::string& path, const Json& doc) { writeFileAtomically(path, doc.dump(2) + "\n"); }

// The document's common head: tool, command, time, machine.
Json runJson(const std::string& command) {
    Json j;
    j["tool"] = "prt-precompute";
    j["command"] = command;
    j["time_utc"] = utcNow();
    Json m;
    m["hardware_threads"] = std::thread::hardware_concurrency();
    m["threads"] = tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism);
    m["load_average_start"] = loadAverage();  // 1, 5, 15 minutes
    j["machine"] = m;
    return j;
}

Json jobJson(const PrecomputeSettings& settings, const PrecomputeSummary& summary) {
    Json j;
    j["settings"] = settingsJson(settings);
    j["summary"] = summaryJson(summary);
    return j;
}

}  // namespace prt
