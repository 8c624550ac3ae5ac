// prt-precompute: mesh + material in, transport file out (docs/precompute.md).
// Thin: parses options (from the command line or a JSON job file) into
// PrecomputeSettings and calls precomputeTransport().

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>
#include <tbb/global_control.h>

#include <cstdio>
#include <fstream>
#include <memory>
#include <optional>

#include "common/bssrdf.h"
#include "common/error.h"
#include "common/precompute.h"
#include "common/progress.h"

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
    s.components = parsePrecomputeComponents(raw.components);
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

int runJobFile(const std::string& path, bool force) {
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
    for (size_t i = 0; i < jobs.size(); ++i) {
        const std::string where = path + ": job " + std::to_string(i + 1);
        std::fprintf(stderr, "== job %zu/%zu ==\n", i + 1, jobs.size());
        try {
            if (!jobs[i].is_object()) throw Error(where, "a job must be an object");
            PrecomputeSummary summary = precomputeTransport(parseJob(defaults, jobs[i], where), force);
            std::printf("%s", summary.format().c_str());
            std::fflush(stdout);
            (summary.skipped ? skipped : done)++;
        } catch (const std::exception& e) {
            std::fprintf(stderr, "prt-precompute: error: %s\n", e.what());
            ++failed;
        }
    }
    std::printf("jobs: %d computed, %d up to date, %d failed (of %zu)\n", done, skipped, failed,
                jobs.size());
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
        std::string jobFile;
        bool force = false, quiet = false;
        int threads = 0;
        app.add_option("--jobs", jobFile, "JSON job file: {\"defaults\": {...}, \"jobs\": [{...}, ...]}");
        app.add_flag("-f,--force", force, "Recompute even when the output is up to date");
        app.add_option("-j,--threads", threads, "Worker threads (default: all cores)");
        app.add_flag("-q,--quiet", quiet, "No progress display");
        try {
            app.parse(argc, argv);
        } catch (const CLI::ParseError& e) {
            return app.exit(e);
        }
        if (quiet) Progress::setEnabled(false);
        if (threads < 0) throw Error("--threads", "must be >= 0");
        std::unique_ptr<tbb::global_control> limit;
        if (threads > 0)
            limit = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism,
                                                          size_t(threads));
        if (!jobFile.empty()) return runJobFile(jobFile, force);
        if (raw.mesh.empty()) throw Error("prt-precompute", "no mesh given (see --help)");
        if (raw.output.empty()) throw Error("--output", "no output path given (see --help)");
        PrecomputeSummary summary = precomputeTransport(finishSettings(raw, settings), force);
        std::printf("%s", summary.format().c_str());
        return 0;
    });
}
