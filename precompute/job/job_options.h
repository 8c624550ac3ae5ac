#pragma once
// The options of one precompute job, shared by the command line and JSON job files
// (docs/precompute.md): the same names, defaults and checks either way. A job file is
// {"defaults": {...}, "jobs": [{...}, ...]}; a job's keys are the long option names
// ("size-mm" or "size_mm" for --size-mm; "mesh" is the positional mesh file), its
// values strings, numbers, arrays of numbers, or true / false for a flag ("editable": true);
// job keys override the defaults.

#include "common/cli_fwd.h"
#include <nlohmann/json.hpp>

#include <optional>
#include <string>
#include <vector>

#include "common/options.h"
#include "precompute/job/settings.h"

namespace prt {

// What the options give before they become PrecomputeSettings (material by name or
// custom coefficients, one of two scales, components as text).
struct JobOptions {
    std::string mesh, output;
    ScaleOptions scale;
    MaterialOptions material;
    std::string components = "ms";
    std::string shard;  // "i/n" or empty
    std::optional<size_t> coefficients;  // -k; absent: 128 per vertex, or kDefaultPreBlockCoefficients before blocking
    // --block-coefficients; absent: kDefaultBlockCoefficients, or 0 (per-vertex vectors)
    // with -k or --editable (and --baseline, which prt-precompute's main sets).
    std::optional<size_t> blockCoefficients;
    std::optional<int> pathSamples;      // --path-samples; absent: defaultPathSamples(--path-quadrature)
    std::string editableMaterials;       // --editable-materials "A;B;...": parseMaterial texts
    std::string editableSizes;           // --editable-sizes S0:S1 (mm)
    bool ground = false;                 // --ground, with --ground-size / -cells / -albedo
    GroundSettings groundSettings;
    std::vector<double> groundAlbedo;
};

// Declares every per-job option on `app`, bound to `raw` and to the fields of `s` (and of
// its pass options) that they set, with `s`'s values as the defaults shown.
void addJobOptions(CLI::App& app, JobOptions& raw, PrecomputeSettings& s);

// The settings of a parsed job: the material (named or custom, with --eta / --g),
// the scale (--size-mm, default 30, or --mm-per-unit) and the components. Throws
// prt::Error naming the option for contradictory or invalid values.
PrecomputeSettings settingsFromOptions(const JobOptions& raw, PrecomputeSettings s);

// One job of a job file: defaults merged with the job's own keys, parsed with the
// command line's options. Errors are prt::Error(where, reason).
PrecomputeSettings parseJob(const nlohmann::json& defaults, const nlohmann::json& job, const std::string& where);

// A job file read and checked for its shape ({"jobs": [...]} with optional
// "defaults"); the jobs themselves are parsed one by one with parseJob so that one
// bad job does not stop the others.
struct JobFile {
    nlohmann::json defaults = nlohmann::json::object();
    nlohmann::json jobs = nlohmann::json::array();
};
JobFile loadJobFile(const std::string& path);

}  // namespace prt
