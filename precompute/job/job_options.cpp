#include "precompute/job/job_options.h"

#include <CLI/CLI.hpp>

#include <algorithm>
#include <fstream>

#include "common/error.h"
#include "common/util.h"

namespace prt {

namespace {

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

}  // namespace


void addJobOptions(CLI::App& app, JobOptions& raw, PrecomputeSettings& s) {
    app.add_option("mesh", raw.mesh, "Mesh file (.obj .ply .off .stl, optionally .gz)");
    app.add_option("-o,--output", raw.output, "Transport file to write (written atomically)");
    addScaleOptions(app, raw.scale, "Object");
    addMaterialOptions(app, raw.material, /*withG=*/true, "Object");
    app.add_option("--cubemap-size", s.cubemapSize, "Lighting cubemap face size N (power of two, <= 64)")
        ->capture_default_str();
    app.add_option("--supersample", s.pass1.supersample, "s x s stratified directions per texel in pass 1")
        ->capture_default_str();
    app.add_option_function<std::string>(
           "--pass1-visibility",
           [&s](const std::string& v) { s.pass1.sampling = parseVisibilitySampling(v); },
           "Pass 1 occlusion rays: every (one per sub-direction) or coherent (a probe per texel, "
           "every sub-direction only next to a change: fewer rays, misses occluders narrower than a "
           "texel; docs/precompute.md)")
        ->default_str("every");
    app.add_option("--sample-coefficients", s.pass1.sampleCoefficients, "Terms kept per sample (pass 1), the SH terms included")
        ->capture_default_str();
    app.add_option("--node-coefficients", s.pass2.nodeCoefficients, "Terms kept per kd-tree node (pass 2), the SH terms included")
        ->capture_default_str();
    app.add_option("-k,--coefficients", raw.coefficients,
                   "Terms kept per vertex, the SH terms included (in a blocked file: before the joint choice); "
                   "given alone, it makes a per-vertex file")
        ->default_str(std::to_string(kDefaultPreBlockCoefficients) + " before blocking; 128 per vertex, " +
                      std::to_string(kDefaultEditableCoefficients) + " editable");
    app.add_option("--sh-terms", s.shTerms,
                   "Of the terms kept per sample, node and vertex, this many (0, 1, 4, 9, 16 or 25) are a fit by "
                   "spherical harmonics of bands 0..2 (up to 4) whose residual no light of those bands sees, the rest the "
                   "largest Haar terms of that residual (9: the smooth shape kept whole; 0: Haar only; "
                   "docs/precompute.md)")
        ->capture_default_str();
    app.add_option("--block-coefficients", raw.blockCoefficients,
                   "M > 0: blocks of 16 nearby vertices share M terms chosen jointly, 8-bit values (a smaller "
                   "file that relights faster; docs/precompute.md). 0: each vertex keeps its own terms")
        ->default_str(std::to_string(kDefaultBlockCoefficients) + "; 0 with -k, --editable or --baseline");
    app.add_option("--epsilon", s.pass2.epsilon, "kd-tree threshold on A_node / r^2 (0 = exact sum)")
        ->capture_default_str();
    app.add_option("--samples", s.samples.count, "Number of surface samples (default: from the spacing)");
    app.add_option("--sample-spacing", s.samples.spacingMm,
                   "Sample spacing in mm (default: the material's mean free path 1/sigma_t')");
    app.add_option("--max-samples", s.samples.maxCount, "Cap on the automatic sample count")->capture_default_str();
    app.add_option("--seed", s.samples.seed, "Seed of the sample placement")->capture_default_str();
    app.add_option("--max-memory", s.maxMemoryGb,
                   "Refuse the job up front when its estimated memory exceeds this many GB (0 = the available "
                   "memory)")
        ->capture_default_str();
    app.add_option("--components", raw.components,
                   "Components to compute: ms (multiple scattering), ss (single scattering) or ms,ss")
        ->capture_default_str();
    app.add_option("--phase-terms", s.phase.terms,
                   "Single scattering with g != 0: K terms of the SVD-factored HG phase function")
        ->capture_default_str();
    app.add_option("--phase-map-size", s.phase.mapSize,
                   "Face size M of the 6 x M x M phase light/view maps")
        ->capture_default_str();
    app.add_option("--path-samples", raw.pathSamples,
                   "Single scattering: deterministic importance samples along the inward normal")
        ->default_str(std::to_string(defaultPathSamples(PathQuadrature::GaussLegendre)) + " with gauss, " +
                      std::to_string(defaultPathSamples(PathQuadrature::Midpoint)) + " with midpoint");
    app.add_option_function<std::string>(
           "--path-quadrature",
           [&s](const std::string& v) { s.singleScattering.pathQuadrature = parsePathQuadrature(v); },
           "Single scattering: rule of the path samples in the sampled mass xi: gauss (Gauss-Legendre) "
           "or midpoint (Wang 2005)")
        ->default_str(toString(kDefaultPathQuadrature));
    app.add_option("--ss-supersample", s.singleScattering.supersample,
                   "Single scattering: s x s sub-directions per texel")
        ->capture_default_str();
    app.add_option("--ss-direction-stride", s.singleScattering.directionStride,
                   "Single scattering: trace the texels of a lattice of this stride per cube face "
                   "(1, 2, 4, 8 or 16), split the cells whose corners disagree (shadow or sheet edges, "
                   "the cut-off, bright cells) down to single texels and interpolate the others; 1 "
                   "traces every texel. Ignored when --ss-supersample > 1 (docs/single-scattering.md)")
        ->capture_default_str();
    app.add_option_function<std::string>(
           "--ss-site-spacing",
           [&s](const std::string& v) {
               if (v == "auto") {
                   s.ssSiteSpacing.reset();
                   return;
               }
               const std::vector<double> h = parseNumberList(v, "--ss-site-spacing", "spacing (auto or mm)");
               if (h.size() != 1) throw Error("--ss-site-spacing", "must be auto or one number of mm, got '" + v + "'");
               s.ssSiteSpacing = h[0];
           },
           "Single scattering: compute it at sites about this far apart (mm) and give every vertex "
           "the blend of the sites within twice that distance whose normals are within 60 degrees "
           "of its own (fewer rays, a blur of about one spacing); 0 computes it at every vertex; auto: "
           "0.75 mean free paths of the material, 1 / luminance(sigma_t) (docs/single-scattering.md, \"Sites\")")
        ->default_str("auto");
    app.add_option_function<std::string>(
           "--ss-visibility",
           [&s](const std::string& v) {
               if (v != "exit" && v != "ray")
                   throw Error("--ss-visibility", "must be exit or ray, got '" + v + "'");
               s.singleScattering.visibilityFromExitRay = v == "exit";
           },
           "Single scattering: V from the exit ray's own traversal (exit: a surface beyond the exit "
           "point shadows it) or from a second ray from each exit point (ray: slower; the two agree "
           "exit by exit on clean meshes; docs/single-scattering.md)")
        ->default_str("exit");
    app.add_option("--pass1-file", s.pass1File,
                   "Load the samples' pass-1 vectors from this file when it exists (made for the same "
                   "pass-1 inputs), else compute and save them there: the shards of a job then compute "
                   "pass 1 once (docs/cluster.md)");
    app.add_flag("--pass1-only", s.pass1Only, "Stop after writing --pass1-file (no transport file)");
    app.add_flag("--fold-ss", s.foldSingleScattering,
                 "Add isotropic single scattering into the multiple-scattering vectors (one vector per vertex: "
                 "relit at the cost of multiple scattering alone; the renderers then show the two only "
                 "together; docs/precompute.md)");
    app.add_flag("--editable", s.editable.enabled,
                 "Editable transport: pass 2 against a radial basis, so prt-relight can change the material "
                 "and the size without a new precompute (docs/editable-transport.md)")
        ->group("Editable transport");
    app.add_option("--editable-materials", raw.editableMaterials,
                   "Materials the basis must cover, separated by ';' (names, sigma:SA:SS or colour:C:L forms; "
                   "default: the measured ones with absorption), besides the job's own")
        ->group("Editable transport");
    app.add_option("--editable-sizes", raw.editableSizes,
                   "S0:S1, the object sizes (mm, bounding-box diagonal) the basis must cover (default: half "
                   "to twice the job's size)")
        ->group("Editable transport");
    app.add_option("--editable-profiles", s.editable.basis.size,
                   "J, the number of radial profiles (a multiple of 3; more: a closer fit, a larger file)")
        ->capture_default_str()->group("Editable transport");
    app.add_option("--editable-grading", s.editable.cellGrading,
                   "g: pass 2 integrates the profiles over pieces no wider than 1/g of their distance from "
                   "the vertex (fine only at the narrowest profile's peak); 0: fine everywhere (slower)")
        ->capture_default_str()->group("Editable transport");
    app.add_option("--editable-bits", s.editable.haarBits,
                   "Bits of the profiles' Haar values in a per-vertex file: 8 (with -k " +
                       std::to_string(kDefaultEditableCoefficients) +
                       " by default: more terms in fewer bytes than 16 bits) or 16 (-k 128 by default)")
        ->capture_default_str()->group("Editable transport");
    CLI::Option* ground =
        app.add_flag("--ground", raw.ground,
                     "A diffuse plane under the object that receives its shadow and hides the environment below "
                     "it in pass 1; writes a second transport file, <output>.ground.prt, for the renderers' "
                     "--ground (docs/ground.md)")
            ->group("Ground");
    app.add_option("--ground-size", raw.groundSettings.halfExtentPerDiagonal,
                   "Half the side of the square plane, in object diagonals")
        ->capture_default_str()->needs(ground)->group("Ground");
    app.add_option("--ground-cells", raw.groundSettings.cells,
                   "Cells per side of the plane's grid (its vertices carry the shadow: (cells + 1)^2 of them)")
        ->capture_default_str()->needs(ground)->group("Ground");
    app.add_option("--ground-albedo", raw.groundAlbedo, "Lambertian reflectance of the plane, one value or R,G,B in [0, 1]")
        ->delimiter(',')->expected(1, 3)->default_str("0.5")->needs(ground)->group("Ground");
    app.add_option("--shard", raw.shard,
                   "i/n: compute only shard i (0-based) of n of the vertices into a shard file; "
                   "prt-merge joins the n shard files (docs/cluster.md)");
}

PrecomputeSettings settingsFromOptions(const JobOptions& raw, PrecomputeSettings s) {
    s.meshPath = raw.mesh;
    s.outputPath = raw.output;
    s.components = parseScatteringComponents(raw.components);
    s.scale = makeScale(raw.scale);
    s.material = makeMaterial(raw.material);
    if (!raw.editableMaterials.empty()) {
        s.editable.materials.clear();
        for (const std::string& m : splitText(raw.editableMaterials, ';'))
            if (!trim(m).empty()) s.editable.materials.push_back(trim(m));
    }
    if (!raw.editableSizes.empty()) {
        const std::vector<std::string> ends = splitText(raw.editableSizes, ':');
        if (ends.size() != 2) throw Error("--editable-sizes", "expected S0:S1 in mm, got '" + raw.editableSizes + "'");
        const std::vector<double> lo = parseNumberList(ends[0], "--editable-sizes", "sizes");
        const std::vector<double> hi = parseNumberList(ends[1], "--editable-sizes", "sizes");
        if (lo.size() != 1 || hi.size() != 1)
            throw Error("--editable-sizes", "expected S0:S1 in mm, got '" + raw.editableSizes + "'");
        s.editable.sizeMinMm = lo[0];
        s.editable.sizeMaxMm = hi[0];
        if (!(lo[0] > 0.0)) throw Error("--editable-sizes", "sizes must be > 0 mm, got '" + raw.editableSizes + "'");
    }
    if (!raw.shard.empty()) s.shard = parseShard(raw.shard);
    if (raw.ground) {
        s.ground = raw.groundSettings;
        if (raw.groundAlbedo.size() == 1) s.ground->albedo = glm::dvec3(raw.groundAlbedo[0]);
        else if (raw.groundAlbedo.size() == 3)
            s.ground->albedo = {raw.groundAlbedo[0], raw.groundAlbedo[1], raw.groundAlbedo[2]};
        else if (!raw.groundAlbedo.empty()) throw Error("--ground-albedo", "one value or R,G,B");
        validateGroundSettings(*s.ground);
    }
    // Blocked by default; per vertex when the job asks for a per-vertex count (-k) or is
    // editable (its recombination is faster per vertex: docs/editable-transport.md).
    // The defaults never ask for more terms than a small cubemap has.
    const size_t space = size_t(6) * size_t(std::max(s.cubemapSize, 0)) * size_t(std::max(s.cubemapSize, 0)) +
                         size_t(std::max(s.shTerms, 0));
    s.blockCoefficients = raw.blockCoefficients ? *raw.blockCoefficients
                          : raw.coefficients || s.editable.enabled
                              ? 0
                              : std::min(kDefaultBlockCoefficients, space);
    const bool eightBitProfiles = s.editable.enabled && s.editable.haarBits == 8 && !s.blockCoefficients;
    s.vertexCoefficients = raw.coefficients      ? *raw.coefficients
                           : s.blockCoefficients ? std::min(kDefaultPreBlockCoefficients, space)
                           : eightBitProfiles    ? std::min(kDefaultEditableCoefficients, space)
                                                 : size_t(128);
    s.singleScattering.pathSamples =
        raw.pathSamples ? *raw.pathSamples : defaultPathSamples(s.singleScattering.pathQuadrature);
    return s;
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
        // A flag takes its value attached (CLI11: --editable=true / =false); a
        // separate "true" would be read as a positional.
        if (it.value().is_boolean()) {
            args.push_back("--" + key + "=" + it.value().dump());
            continue;
        }
        args.push_back("--" + key);
        args.push_back(argumentText(it.value(), where + ": " + it.key()));
    }
    // The positional mesh goes first: after a 3-value option (--sigma-a) CLI11 would
    // take it as a fourth value.
    if (merged.contains("mesh")) args.insert(args.begin(), argumentText(merged["mesh"], where + ": mesh"));
    CLI::App app;
    JobOptions raw;
    PrecomputeSettings s;
    addJobOptions(app, raw, s);
    std::vector<std::string> reversed(args.rbegin(), args.rend());
    try {
        app.parse(reversed);
    } catch (const CLI::ParseError& e) {
        throw Error(where, e.what());
    }
    return settingsFromOptions(raw, s);
}

JobFile loadJobFile(const std::string& path) {
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
    JobFile f;
    if (doc.contains("defaults")) {
        if (!doc["defaults"].is_object()) throw Error(path, "\"defaults\" must be an object");
        f.defaults = doc["defaults"];
    }
    f.jobs = doc["jobs"];
    return f;
}

}  // namespace prt
