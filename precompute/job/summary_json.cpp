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
    j["supersample"] = s.pass1.supersample;
    j["pass1_visibility"] = toString(s.pass1.sampling);
    j["sample_coefficients"] = s.pass1.sampleCoefficients;
    j["node_coefficients"] = s.pass2.nodeCoefficients;
    j["coefficients"] = s.vertexCoefficients;
    j["block_coefficients"] = s.blockCoefficients;  // 0: per-vertex vectors
    j["fold_ss"] = s.foldSingleScattering;
    j["sh_terms"] = s.shTerms;
    j["epsilon"] = s.pass2.epsilon;
    j["samples_requested"] = s.samples.count;               // 0: from the spacing
    j["sample_spacing_mm_requested"] = s.samples.spacingMm;  // 0: the mean free path
    j["max_samples"] = s.samples.maxCount;
    j["seed"] = s.samples.seed;
    j["phase_terms"] = s.phase.terms;
    j["phase_map_size"] = s.phase.mapSize;
    j["path_quadrature"] = toString(s.singleScattering.pathQuadrature);
    j["path_samples"] = s.singleScattering.pathSamples;
    j["ss_supersample"] = s.singleScattering.supersample;
    j["ss_direction_stride"] = s.singleScattering.directionStride;
    j["ss_site_spacing_mm"] = resolvedSiteSpacing(s);
    j["shard"] = s.shard ? Json(toString(*s.shard)) : Json(nullptr);
    j["pass1_file"] = s.pass1File.empty() ? Json(nullptr) : Json(s.pass1File);
    j["pass1_only"] = s.pass1Only;
    j["ground"] = s.ground ? Json({{"size_diagonals", s.ground->halfExtentPerDiagonal},
                                   {"cells", s.ground->cells},
                                   {"albedo", vec3(s.ground->albedo)}})
                           : Json(nullptr);
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
    const SetupSummary& setup = r.setup;
    const Pass1Summary& pass1 = r.pass1;
    const Pass2Summary& pass2 = r.pass2;
    const SingleScatteringSummary& ss = r.singleScattering;
    j["distribution"] = r.distribution.description;
    j["pass1_loaded"] = pass1.loaded;
    j["ranks"] = r.distribution.ranks;
    j["pass1_exchange_bytes"] = pass1.exchangeBytes;
    j["pass1_exchange_seconds"] = pass1.exchangeSeconds;
    j["gather_seconds"] = r.gatherSeconds();
    j["busy_seconds_min"] = r.distribution.busySecondsMin;
    j["busy_seconds_max"] = r.distribution.busySecondsMax;
    j["ground_file"] = r.ground.path.empty() ? Json(nullptr) : Json(r.ground.path);
    j["ground_vertices"] = r.ground.path.empty() ? Json(nullptr) : Json(r.ground.vertices);
    j["ground_seconds"] = r.ground.path.empty() ? Json(nullptr) : Json(r.ground.seconds);
    const bool ms = r.components.multipleScattering, ssOn = r.components.singleScattering;
    const auto msOnly = [&](const Json& v) { return ms ? v : Json(nullptr); };
    const auto ssOnly = [&](const Json& v) { return ssOn ? v : Json(nullptr); };
    const double vertices = double(setup.vertices);
    const auto perVertex = [&](double v) { return vertices > 0 ? Json(v / vertices) : Json(nullptr); };
    j["vertices"] = setup.vertices;
    j["computed_vertices"] = setup.computedVertices;
    j["triangles"] = setup.triangles;
    j["total_area_mm2"] = setup.totalAreaMm2;
    j["samples"] = msOnly(r.samples.count);
    j["sample_spacing_mm"] = msOnly(r.samples.spacingMm);
    // Wall-clock seconds per stage.
    j["setup_seconds"] = setup.seconds;
    j["samples_seconds"] = msOnly(r.samples.seconds);
    j["pass1_seconds"] = msOnly(pass1.seconds);
    j["pass2_seconds"] = msOnly(pass2.seconds);
    j["phase_seconds"] = ssOnly(ss.phaseSeconds);
    j["ss_seconds"] = ssOnly(ss.seconds);
    j["write_seconds"] = r.write.seconds;
    j["total_seconds"] = r.totalSeconds;
    // Pass 1 and pass 2.
    j["pass1_rays"] = msOnly(pass1.rays);
    j["pass1_rays_per_second"] = msOnly(pass1.raysPerSecond);
    j["sample_retained_energy"] = msOnly(pass1.retainedEnergy);
    j["mean_nodes_visited"] = msOnly(pass2.meanNodesVisited);
    j["cell_sub_points"] = msOnly(double(pass2.cellSubPoints));
    j["cell_seconds"] = msOnly(pass2.cellSeconds);
    j["vertex_retained_energy"] = msOnly(pass2.retainedEnergy);
    // Blocks (null for per-vertex files).
    const bool blocked = r.blocks.coefficients > 0;
    j["block_coefficients"] = blocked ? Json(r.blocks.coefficients) : Json(nullptr);
    j["block_seconds"] = blocked ? Json(r.blocks.seconds) : Json(nullptr);
    j["block_retained_energy"] = blocked ? Json(r.blocks.retainedEnergy) : Json(nullptr);
    // Single scattering.
    j["ss_terms"] = ssOnly(ss.terms);
    j["ss_isotropic"] = ssOnly(ss.isotropic);
    j["phase_rms_error"] = ssOnly(ss.phaseRmsError);
    j["ss_rays"] = ssOnly(ss.rays);
    j["ss_exit_rays"] = ssOnly(ss.exitRays);
    j["ss_occlusion_rays"] = ssOnly(ss.occlusionRays);
    j["ss_culled_rays"] = ssOnly(ss.culledRays);
    j["ss_occluded_exits"] = ssOnly(ss.occludedExits);
    j["ss_traced_texels"] = ssOnly(ss.tracedTexels);
    j["ss_interpolated_texels"] = ssOnly(ss.interpolatedTexels);
    j["ss_sites"] = ssOnly(ss.sites);
    j["ss_site_exchange_bytes"] = ssOnly(ss.siteExchangeBytes);
    j["ss_site_exchange_seconds"] = ssOnly(ss.siteExchangeSeconds);
    j["ss_splits_by_stake"] = ssOnly(ss.splitsByStake);
    j["ss_splits_by_throughput"] = ssOnly(ss.splitsByThroughput);
    j["ss_splits_by_exit_kind"] = ssOnly(ss.splitsByExitKind);
    j["ss_escaped_rays"] = ssOnly(ss.escapedRays);
    j["ss_reversed_hits"] = ssOnly(ss.reversedHits);
    j["ss_outside_samples"] = ssOnly(ss.outsideSamples);
    j["ss_flipped_normals"] = ssOnly(ss.flippedNormals);
    j["ss_capped_depths"] = ssOnly(ss.cappedDepths);
    j["ss_rays_per_second"] = ssOnly(ss.raysPerSecond);
    j["ss_mean_depth_mm"] = ssOnly(ss.meanDepthMm);
    j["ss_retained_energy"] = ssOnly(ss.retainedEnergy);
    // Output and memory.
    j["file_bytes"] = r.write.fileBytes;
    j["peak_memory_bytes"] = r.peakMemoryBytes;
    j["start_resident_bytes"] = r.startMemoryBytes;
    j["peak_memory_after_setup_bytes"] = setup.peakMemoryBytes;
    j["peak_memory_after_samples_bytes"] = msOnly(r.samples.peakMemoryBytes);
    j["peak_memory_after_pass1_bytes"] = msOnly(pass1.peakMemoryBytes);
    j["peak_memory_after_pass2_bytes"] = msOnly(pass2.peakMemoryBytes);
    j["peak_memory_after_ss_bytes"] = ssOnly(ss.peakMemoryBytes);
    // Derived per-item figures (for tables and scaling plots).
    j["pass1_seconds_per_sample"] =
        ms && r.samples.count > 0 ? Json(pass1.seconds / double(r.samples.count)) : Json(nullptr);
    // Per computed vertex (a shard's own range; all vertices otherwise).
    const double computed = double(setup.computedVertices);
    const auto perComputed = [&](double v) { return computed > 0 ? Json(v / computed) : Json(nullptr); };
    j["pass2_seconds_per_vertex"] = ms ? perComputed(pass2.seconds) : Json(nullptr);
    j["ss_seconds_per_vertex"] = ssOn ? perComputed(ss.seconds) : Json(nullptr);
    j["ss_rays_per_vertex"] = ssOn ? perComputed(double(ss.rays)) : Json(nullptr);
    j["file_bytes_per_vertex"] = perVertex(double(r.write.fileBytes));
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
