// prt-precompute: mesh + material in, transport file out (docs/precompute.md).
// Thin: parses options (from the command line or a JSON job file) into
// PrecomputeSettings and calls precomputeTransport().

#include <CLI/CLI.hpp>
#include <fcntl.h>
#include <nlohmann/json.hpp>
#include <tbb/global_control.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <memory>
#include <optional>
#include <thread>

#include "common/atomic_file.h"
#include "common/bssrdf.h"
#include "common/error.h"
#include "precompute/pipeline.h"
#include "common/progress.h"
#include "common/options.h"

using namespace prt;

namespace {

struct RawOptions {
    std::string mesh, output, material = "Marble";
    std::optional<double> sizeMm, mmPerUnit;
    std::vector<double> sigmaA, sigmaSPrime;
    double eta = 1.3, g = 0.0;
    bool etaSet = false;
    std::string components = "ms";
};

// Declares every per-job option on `app`, bound to `raw` and `s`.
void addJobOptions(CLI::App& app, RawOptions& raw, PrecomputeSettings& s) {
    app.add_option("mesh", raw.mesh, "Mesh file (.obj .ply .off .stl, optionally .gz)");
    app.add_option("-o,--output", raw.output, "Transport file to write (written atomically)");
    app.add_option("--size-mm", raw.sizeMm, "Scale the mesh so its bounding-box diagonal is this many mm");
    app.add_option("--mm-per-unit", raw.mmPerUnit, "Millimetres per mesh-file unit (instead of --size-mm)");
    app.add_option("-m,--material", raw.material,
                   "Measured material (Jensen et al. 2001): Apple Chicken1 Chicken2 Cream Ketchup Marble "
                   "Potato Skimmilk Skin1 Skin2 Spectralon Wholemilk")
        ->capture_default_str();
    app.add_option("--sigma-a", raw.sigmaA, "Custom absorption R G B in mm^-1 (with --sigma-s-prime)")
        ->expected(3)->delimiter(',');
    app.add_option("--sigma-s-prime", raw.sigmaSPrime, "Custom reduced scattering R G B in mm^-1")
        ->expected(3)->delimiter(',');
    app.add_option_function<double>("--eta", [&](double v) { raw.eta = v; raw.etaSet = true; },
                                    "Relative index of refraction (default 1.3)");
    app.add_option("--g", raw.g, "Henyey-Greenstein asymmetry (> 0 forward)")->capture_default_str();
    app.add_option("--cubemap-size", s.cubemapSize, "Lighting cubemap face size N (power of two, <= 64)")
        ->capture_default_str();
    app.add_option("--supersample", s.supersample, "s x s stratified directions per texel in pass 1")
        ->capture_default_str();
    app.add_option("--sample-coefficients", s.sampleCoefficients, "Haar terms kept per sample (pass 1)")
        ->capture_default_str();
    app.add_option("--node-coefficients", s.nodeCoefficients, "Haar terms kept per kd-tree node (pass 2)")
        ->capture_default_str();
    app.add_option("-k,--coefficients", s.vertexCoefficients, "Haar terms kept per vertex")
        ->capture_default_str();
    app.add_option("--epsilon", s.epsilon, "kd-tree threshold on A_node / r^2 (0 = exact sum)")
        ->capture_default_str();
    app.add_option("--samples", s.sampleCount, "Number of surface samples (default: from the spacing)");
    app.add_option("--sample-spacing", s.sampleSpacingMm,
                   "Sample spacing in mm (default: the material's mean free path 1/sigma_t')");
    app.add_option("--max-samples", s.maxSamples, "Cap on the automatic sample count")->capture_default_str();
    app.add_option("--seed", s.seed, "Seed of the sample placement")->capture_default_str();
    app.add_option("--components", raw.components,
                   "Components to compute: ms (multiple scattering), ss (single scattering) or ms,ss")
        ->capture_default_str();
    app.add_option("--phase-terms", s.phaseTerms,
                   "Single scattering with g != 0: K terms of the SVD-factored HG phase function")
        ->capture_default_str();
    app.add_option("--phase-map-size", s.phaseMapSize,
                   "Face size M of the 6 x M x M phase light/view maps")
        ->capture_default_str();
    app.add_option("--path-samples", s.pathSamples,
                   "Single scattering: deterministic importance samples along the inward normal")
        ->capture_default_str();
    app.add_option("--ss-supersample", s.ssSupersample,
                   "Single scattering: s x s sub-directions per texel")
        ->capture_default_str();
}

PrecomputeSettings finishSettings(const RawOptions& raw, PrecomputeSettings s) {
    s.meshPath = raw.mesh;
    s.outputPath = raw.output;
    s.components = parseScatteringComponents(raw.components);
    if (raw.sizeMm && raw.mmPerUnit)
        throw Error("--size-mm", "give either --size-mm or --mm-per-unit, not both");
    if (raw.mmPerUnit) s.scale.mmPerUnit = raw.mmPerUnit;
    else s.scale.sizeMm = raw.sizeMm.value_or(30.0);
    if (raw.sigmaA.empty() != raw.sigmaSPrime.empty())
        throw Error("--sigma-a", "a custom material needs both --sigma-a and --sigma-s-prime");
    if (!raw.sigmaA.empty()) {
        s.material = customMaterial({raw.sigmaSPrime[0], raw.sigmaSPrime[1], raw.sigmaSPrime[2]},
                                    {raw.sigmaA[0], raw.sigmaA[1], raw.sigmaA[2]}, raw.eta, raw.g);
    } else {
        s.material = materialByName(raw.material);
        if (raw.etaSet) s.material.eta = raw.eta;
        s.material.g = raw.g;
        validateMaterial(s.material);
    }
    return s;
}

// A JSON value as the text of a command-line argument.
std::string argumentText(const nlohmann::json& v, const std::string& where) {
    if (v.is_string()) return v.get<std::string>();
    if (v.is_number() || v.is_boolean()) return v.dump();
    if (v.is_array()) {
        std::string out;
        for (const auto& e : v) out += (out.empty() ? "" : ",") + argumentText(e, where);
        return out;
    }
    throw Error(where, "values must be strings, numbers or arrays of numbers");
}

// Parses one job (defaults merged with the job's own keys) with the same options
// as the command line: key "size-mm" (or "size_mm") is the option --size-mm.
PrecomputeSettings parseJob(const nlohmann::json& defaults, const nlohmann::json& job,
                            const std::string& where) {
    std::vector<std::string> args;
    nlohmann::json merged = defaults;
    for (auto it = job.begin(); it != job.end(); ++it) merged[it.key()] = it.value();
    for (auto it = merged.begin(); it != merged.end(); ++it) {
        std::string key = it.key();
        std::replace(key.begin(), key.end(), '_', '-');
        if (key == "mesh") continue;
        args.push_back("--" + key);
        args.push_back(argumentText(it.value(), where + ": " + it.key()));
    }
    if (merged.contains("mesh")) args.push_back(argumentText(merged["mesh"], where + ": mesh"));
    CLI::App app;
    RawOptions raw;
    PrecomputeSettings s;
    addJobOptions(app, raw, s);
    std::vector<std::string> reversed(args.rbegin(), args.rend());
    try {
        app.parse(reversed);
    } catch (const CLI::ParseError& e) {
        throw Error(where, e.what());
    }
    return finishSettings(raw, s);
}

// ---------------------------------------------------------------------------
// --summary-json: the job's PrecomputeSummary (every field), its settings, the
// command and the machine's state, as JSON (docs/precompute.md, "Summary as JSON").
// ---------------------------------------------------------------------------

using Json = nlohmann::ordered_json;

Json vec3(const glm::dvec3& v) { return Json::array({v.x, v.y, v.z}); }

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
    j["sample_coefficients"] = s.sampleCoefficients;
    j["node_coefficients"] = s.nodeCoefficients;
    j["coefficients"] = s.vertexCoefficients;
    j["epsilon"] = s.epsilon;
    j["samples_requested"] = s.sampleCount;            // 0: from the spacing
    j["sample_spacing_mm_requested"] = s.sampleSpacingMm;  // 0: the mean free path
    j["max_samples"] = s.maxSamples;
    j["seed"] = s.seed;
    j["phase_terms"] = s.phaseTerms;
    j["phase_map_size"] = s.phaseMapSize;
    j["path_samples"] = s.pathSamples;
    j["ss_supersample"] = s.ssSupersample;
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
    const bool ms = r.components.multipleScattering, ss = r.components.singleScattering;
    const auto msOnly = [&](const Json& v) { return ms ? v : Json(nullptr); };
    const auto ssOnly = [&](const Json& v) { return ss ? v : Json(nullptr); };
    const double vertices = double(r.vertices);
    const auto perVertex = [&](double v) { return vertices > 0 ? Json(v / vertices) : Json(nullptr); };
    j["vertices"] = r.vertices;
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
    j["vertex_retained_energy"] = msOnly(r.vertexRetainedEnergy);
    // Single scattering.
    j["ss_terms"] = ssOnly(r.ssTerms);
    j["ss_isotropic"] = ssOnly(r.ssIsotropic);
    j["phase_rms_error"] = ssOnly(r.phaseRmsError);
    j["ss_rays"] = ssOnly(r.ssRaysTraced);
    j["ss_exit_rays"] = ssOnly(r.ssExitRays);
    j["ss_occlusion_rays"] = ssOnly(r.ssOcclusionRays);
    j["ss_culled_rays"] = ssOnly(r.ssCulledRays);
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
    j["pass2_seconds_per_vertex"] = ms ? perVertex(r.pass2Seconds) : Json(nullptr);
    j["ss_seconds_per_vertex"] = ss ? perVertex(r.ssSeconds) : Json(nullptr);
    j["ss_rays_per_vertex"] = ss ? perVertex(double(r.ssRaysTraced)) : Json(nullptr);
    j["file_bytes_per_vertex"] = perVertex(double(r.fileBytes));
    return j;
}

Json loadAverage() {
    double l[3] = {0, 0, 0};
    if (getloadavg(l, 3) != 3) return nullptr;
    return Json::array({l[0], l[1], l[2]});
}

std::string utcNow() {
    const std::time_t t = std::time(nullptr);
    std::tm tm{};
    gmtime_r(&t, &tm);
    char buf[32];
    std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%SZ", &tm);
    return buf;
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

int runJobFile(const std::string& path, bool force, const std::string& summaryJsonPath,
               const std::string& command) {
    std::ifstream in(path);
    if (!in) throw Error(path, "cannot open job file");
    nlohmann::json doc;
    try {
        doc = nlohmann::json::parse(in);
    } catch (const nlohmann::json::exception& e) {
        throw Error(path, std::string("not valid JSON: ") + e.what());
    }
    if (!doc.is_object() || !doc.contains("jobs") || !doc["jobs"].is_array())
        throw Error(path, "expected an object with a \"jobs\" array");
    const nlohmann::json defaults = doc.value("defaults", nlohmann::json::object());
    const auto& jobs = doc["jobs"];
    int failed = 0, skipped = 0, done = 0;
    Json report = runJson(command);
    report["job_file"] = path;
    Json results = Json::array();
    for (size_t i = 0; i < jobs.size(); ++i) {
        const std::string where = path + ": job " + std::to_string(i + 1);
        std::fprintf(stderr, "== job %zu/%zu ==\n", i + 1, jobs.size());
        Json result;
        result["job"] = i + 1;
        result["load_average_start"] = loadAverage();
        try {
            if (!jobs[i].is_object()) throw Error(where, "a job must be an object");
            const PrecomputeSettings settings = parseJob(defaults, jobs[i], where);
            result["settings"] = settingsJson(settings);
            PrecomputeSummary summary = precomputeTransport(settings, force);
            std::printf("%s", summary.format().c_str());
            std::fflush(stdout);
            result["summary"] = summaryJson(summary);
            (summary.skipped ? skipped : done)++;
        } catch (const std::exception& e) {
            std::fprintf(stderr, "prt-precompute: error: %s\n", e.what());
            result["error"] = e.what();
            ++failed;
        }
        result["load_average_end"] = loadAverage();
        results.push_back(std::move(result));
    }
    std::printf("jobs: %d computed, %d up to date, %d failed (of %zu)\n", done, skipped, failed,
                jobs.size());
    if (!summaryJsonPath.empty()) {
        report["machine"]["load_average_end"] = loadAverage();
        report["computed"] = done;
        report["up_to_date"] = skipped;
        report["failed"] = failed;
        report["jobs"] = std::move(results);
        writeJsonAtomically(summaryJsonPath, report);
        std::printf("summary: %s\n", summaryJsonPath.c_str());
    }
    return failed ? 1 : 0;
}

}  // namespace

int main(int argc, char** argv) {
    return runMain("prt-precompute", [&]() -> int {
        CLI::App app{
            "prt-precompute: precompute translucent light transport (dipole multiple scattering,\n"
            "single scattering) into per-vertex Haar wavelet vectors. Examples:\n"
            "  prt-precompute data/meshes/bunny.off --size-mm 30 --material Marble -o out/bunny.prt\n"
            "  prt-precompute data/meshes/bunny.off --components ms,ss --g 0.25 --phase-terms 4 -o b.prt\n"
            "  prt-precompute --jobs jobs.json"};
        RawOptions raw;
        PrecomputeSettings settings;
        addJobOptions(app, raw, settings);
        std::string jobFile, summaryJsonPath;
        bool force = false, quiet = false;
        int threads = 0;
        app.add_option("--jobs", jobFile, "JSON job file: {\"defaults\": {...}, \"jobs\": [{...}, ...]}");
        app.add_option("--summary-json", summaryJsonPath,
                       "Also write the summary (every field, settings, per-stage times and peak "
                       "memory) as JSON to this file (atomically); with --jobs one document for all jobs");
        app.add_flag("-f,--force", force, "Recompute even when the output is up to date");
        addThreadsOption(app, threads);
        app.add_flag("-q,--quiet", quiet, "No progress display");
        try {
            app.parse(argc, argv);
        } catch (const CLI::ParseError& e) {
            return app.exit(e);
        }
        if (quiet) Progress::setEnabled(false);
        const ThreadLimit limit(threads);
        if (!summaryJsonPath.empty()) checkJsonPath(summaryJsonPath);
        const std::string command = commandLine(argc, argv);
        if (!jobFile.empty()) return runJobFile(jobFile, force, summaryJsonPath, command);
        if (raw.mesh.empty()) throw Error("prt-precompute", "no mesh given (see --help)");
        if (raw.output.empty()) throw Error("--output", "no output path given (see --help)");
        const PrecomputeSettings job = finishSettings(raw, settings);
        Json report = runJson(command);
        PrecomputeSummary summary = precomputeTransport(job, force);
        std::printf("%s", summary.format().c_str());
        if (!summaryJsonPath.empty()) {
            report["machine"]["load_average_end"] = loadAverage();
            const Json j = jobJson(job, summary);
            for (auto it = j.begin(); it != j.end(); ++it) report[it.key()] = it.value();
            writeJsonAtomically(summaryJsonPath, report);
            std::printf("summary: %s\n", summaryJsonPath.c_str());
        }
        return 0;
    });
}
