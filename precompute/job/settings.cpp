#include "precompute/job/settings.h"

#include <cmath>
#include <cstdio>
#include <filesystem>

#include "common/error.h"
#include "common/material_edit.h"
#include "common/sh_part.h"
#include "common/util.h"

namespace prt {

namespace {

std::string fmt(double v) { return formatParameter(v); }

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
std::string inputDigest(const ParameterList& params) {
    std::string text;
    for (const auto& [k, v] : params)
        if (k != "input_digest") text += k + "=" + v + "\n";
    return hex(fnv1a(text));
}

}  // namespace

PrecomputeSettings withSharedValues(PrecomputeSettings s) {
    const size_t texels = size_t(6) * s.cubemapSize * s.cubemapSize;
    s.pass1.cubemapSize = s.cubemapSize;
    s.pass1.shTerms = s.shTerms;
    s.pass1.eta = s.material.eta;
    s.pass2.vertexCoefficients = s.vertexCoefficients;
    s.pass2.shTerms = s.shTerms;
    s.pass2.sampleShFrom = s.shTerms > 0 ? uint32_t(texels) : UINT32_MAX;
    s.singleScattering.cubemapSize = s.cubemapSize;
    s.singleScattering.vertexCoefficients = s.vertexCoefficients;
    s.singleScattering.shTerms = 0;
    s.singleScattering.siteSpacing = resolvedSiteSpacing(s);
    return s;
}

double resolvedSiteSpacing(const PrecomputeSettings& s) {
    if (s.ssSiteSpacing) return *s.ssSiteSpacing;
    const double extinction = samplingExtinction(s.material);
    return extinction > 0.0 && std::isfinite(extinction) ? kSiteSpacingMeanFreePaths / extinction : 0.0;
}

void validateSettings(const PrecomputeSettings& s) {
    if (s.meshPath.empty()) throw Error("mesh", "no mesh file given");
    if (s.outputPath.empty() && !s.pass1Only) throw Error("--output", "no output path given");
    validateMaterial(s.material);
    if (!isPowerOfTwo(s.cubemapSize) || s.cubemapSize > 64)
        throw Error("--cubemap-size", "must be a power of two between 1 and 64, got " +
                                          std::to_string(s.cubemapSize));
    if (s.pass1.supersample < 1 || s.pass1.supersample > 8)
        throw Error("--supersample", "must be between 1 and 8, got " + std::to_string(s.pass1.supersample));
    const size_t texels = size_t(6) * s.cubemapSize * s.cubemapSize;
    if (!validShTerms(s.shTerms))
        throw Error("--sh-terms", std::string("must be ") + kShTermCounts + ", got " + std::to_string(s.shTerms));
    if (s.cubemapSize < minShCubemapSize(s.shTerms))
        throw Error("--sh-terms", std::to_string(s.shTerms) + " SH terms need a cubemap of at least 6 x " +
                                      std::to_string(minShCubemapSize(s.shTerms)) + " x " +
                                      std::to_string(minShCubemapSize(s.shTerms)));
    // Every count includes the SH terms: more than them, at most all of the space.
    const size_t space = texels + size_t(s.shTerms);
    auto checkTerms = [&](const char* name, size_t k) {
        if (k <= size_t(s.shTerms) || k > space)
            throw Error(name, "must be between " + std::to_string(s.shTerms + 1) + " and 6 N^2" +
                                  (s.shTerms ? " + " + std::to_string(s.shTerms) + " SH terms" : std::string()) +
                                  " = " + std::to_string(space) + ", got " + std::to_string(k));
    };
    checkTerms("--sample-coefficients", s.pass1.sampleCoefficients);
    checkTerms("--node-coefficients", s.pass2.nodeCoefficients);
    checkTerms("--coefficients", s.vertexCoefficients);
    if (s.blockCoefficients > 0) {
        checkTerms("--block-coefficients", s.blockCoefficients);
    }
    if (!(s.pass2.epsilon >= 0) || !std::isfinite(s.pass2.epsilon))
        throw Error("--epsilon", "must be a finite number >= 0, got " + fmt(s.pass2.epsilon));
    if (!(s.samples.spacingMm >= 0) || !std::isfinite(s.samples.spacingMm))
        throw Error("--sample-spacing", "must be a positive length in mm, got " + fmt(s.samples.spacingMm));
    if (s.samples.maxCount < 1) throw Error("--max-samples", "must be at least 1");
    if (!std::isfinite(s.maxMemoryGb) || s.maxMemoryGb < 0.0)
        throw Error("--max-memory", "must be a finite number of GB >= 0 (0 = the available memory)");
    if (!s.components.multipleScattering && !s.components.singleScattering)
        throw Error("--components", "select at least one of ms, ss");
    // M <= 32: the phase table is (6 M^2)^2 doubles (precompute/passes/phase_factoring.h).
    if (!isPowerOfTwo(s.phase.mapSize) || s.phase.mapSize > 32)
        throw Error("--phase-map-size", "must be a power of two between 1 and 32, got " +
                                            std::to_string(s.phase.mapSize));
    const int phaseTexels = 6 * s.phase.mapSize * s.phase.mapSize;
    if (s.phase.terms < 1 || s.phase.terms > phaseTexels)
        throw Error("--phase-terms", "must be between 1 and 6 M^2 = " + std::to_string(phaseTexels) +
                                         ", got " + std::to_string(s.phase.terms));
    const SingleScatteringOptions& ss = s.singleScattering;
    if (ss.pathSamples < 1 || ss.pathSamples > 4096)
        throw Error("--path-samples", "must be between 1 and 4096, got " + std::to_string(ss.pathSamples));
    if (ss.supersample < 1 || ss.supersample > 8)
        throw Error("--ss-supersample", "must be between 1 and 8, got " + std::to_string(ss.supersample));
    if (ss.directionStride < 1 || ss.directionStride > 16 || (ss.directionStride & (ss.directionStride - 1)))
        throw Error("--ss-direction-stride",
                    "must be 1, 2, 4, 8 or 16, got " + std::to_string(ss.directionStride));
    if (s.ssSiteSpacing && (!(*s.ssSiteSpacing >= 0.0) || !std::isfinite(*s.ssSiteSpacing)))
        throw Error("--ss-site-spacing", "must be auto or a non-negative number of mm, got " + fmt(*s.ssSiteSpacing));
    if (!s.pass1File.empty() && !s.components.multipleScattering)
        throw Error("--pass1-file", "needs multiple scattering (--components ms or ms,ss): single scattering has no pass 1");
    if (s.pass1Only && s.pass1File.empty()) throw Error("--pass1-only", "needs --pass1-file");
    if (s.ground) {
        validateGroundSettings(*s.ground);
        if (!s.components.multipleScattering)
            throw Error("--ground", "occludes pass 1 of multiple scattering: select it (--components ms or ms,ss)");
        if (s.shard) throw Error("--ground", "not with --shard (the ground's file is written by one process)");
    }
    if (s.foldSingleScattering) {
        if (!s.components.multipleScattering || !s.components.singleScattering)
            throw Error("--fold-ss", "folds single scattering into multiple scattering: select both (--components ms,ss)");
        if (s.material.g != 0.0)
            throw Error("--fold-ss", "needs isotropic single scattering (g = 0): an anisotropic phase has view maps");
        if (s.editable.enabled) throw Error("--fold-ss", "not with --editable (its multiple scattering is recombined)");
    }
    if (s.editable.enabled) {
        if (!s.components.multipleScattering)
            throw Error("--editable", "edits multiple scattering: select it (--components ms or ms,ss)");
        const int J = s.editable.basis.size;
        if (J < 3 || J > 30 || J % 3 != 0)
            throw Error("--editable-profiles", "must be a multiple of 3 between 3 and 30 (three profiles per stored "
                                               "component), got " + std::to_string(J));
        if (s.editable.haarBits != 8 && s.editable.haarBits != 16)
            throw Error("--editable-bits", "must be 8 or 16, got " + std::to_string(s.editable.haarBits));
        const double g = s.editable.cellGrading;
        if (!(g == 0.0 || (g >= 2.0 && g <= 64.0)))
            throw Error("--editable-grading", "must be 0 (off) or between 2 and 64, got " + fmt(g));
        const double lo = s.editable.sizeMinMm, hi = s.editable.sizeMaxMm;
        if (!(lo == 0.0 && hi == 0.0) && !(lo > 0.0 && hi >= lo && std::isfinite(hi)))
            throw Error("--editable-sizes", "needs 0 < S0 <= S1 mm, got " + fmt(lo) + ":" + fmt(hi));
        editableMaterials(s);  // every text parses
    }
}

std::vector<Material> editableMaterials(const PrecomputeSettings& s) {
    std::vector<Material> materials;
    if (s.editable.materials.empty()) {
        for (const std::string& name : materialNames()) {
            Material m = materialByName(name);
            if (m.sigmaA.x > 0.0 && m.sigmaA.y > 0.0 && m.sigmaA.z > 0.0) {
                m.eta = s.material.eta;
                materials.push_back(m);
            }
        }
    } else {
        for (const std::string& text : s.editable.materials)
            materials.push_back(parseMaterial(text, s.material.eta, s.material.g, "--editable-materials"));
    }
    materials.push_back(s.material);
    return materials;
}

RadialRange editableRange(const PrecomputeSettings& s, double objectSizeMm) {
    const bool sized = s.editable.sizeMinMm > 0.0;
    const double sMin = sized ? s.editable.sizeMinMm / objectSizeMm : 0.5;
    const double sMax = sized ? s.editable.sizeMaxMm / objectSizeMm : 2.0;
    try {
        return rangeCovering(editableMaterials(s), sMin, sMax, objectSizeMm);
    } catch (const Error& e) {
        throw Error("--editable-materials", e.subject() + ": " + e.reason());
    }
}

ParameterList settingsParameters(const PrecomputeSettings& settings, const MeshFingerprint& mesh) {
    const PrecomputeSettings s = withSharedValues(settings);
    ParameterList p = {
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
        {"supersample", std::to_string(s.pass1.supersample)},
        {"pass1_visibility", toString(s.pass1.sampling)},
        {"sample_coefficients", std::to_string(s.pass1.sampleCoefficients)},
        {"node_coefficients", std::to_string(s.pass2.nodeCoefficients)},
        {"coefficients", std::to_string(s.vertexCoefficients)},
        {"sh_terms", std::to_string(s.shTerms)},
        {"epsilon", fmt(s.pass2.epsilon)},
        {"samples_requested", std::to_string(s.samples.count)},
        {"sample_spacing_requested_mm", fmt(s.samples.spacingMm)},
        {"max_samples", std::to_string(s.samples.maxCount)},
        {"seed", std::to_string(s.samples.seed)},
        {"ms_normalisation", "T_d/pi (radiance = F_t(w_o) * dot(vector, light))"},
    };
    p.insert(p.end(), passes.begin(), passes.end());
    if (s.blockCoefficients > 0) p.push_back({"block_coefficients", std::to_string(s.blockCoefficients)});
    // Recorded only when folded, so other files keep their parameters and digest.
    if (s.foldSingleScattering) p.push_back({kFoldedSingleScatteringParameter, "1"});
    // Recorded only with a ground, so files without one keep their parameters and digest.
    if (s.ground) {
        p.push_back({"ground_size_diagonals", fmt(s.ground->halfExtentPerDiagonal)});
        p.push_back({"ground_cells", std::to_string(s.ground->cells)});
        p.push_back({"ground_albedo", fmt(s.ground->albedo.r) + "," + fmt(s.ground->albedo.g) + "," +
                                          fmt(s.ground->albedo.b)});
    }
    // Recorded only for editable jobs, so other files keep their parameters and digest.
    if (s.editable.enabled) {
        std::string materials;
        for (const std::string& m : s.editable.materials) materials += (materials.empty() ? "" : " ") + m;
        p.push_back({"editable", "radial basis (docs/editable-transport.md)"});
        p.push_back({"editable_materials", materials.empty() ? "measured with absorption" : materials});
        p.push_back({"editable_sizes_requested_mm",
                     s.editable.sizeMinMm > 0.0 ? fmt(s.editable.sizeMinMm) + ":" + fmt(s.editable.sizeMaxMm)
                                                : "0.5x:2x"});
        p.push_back({"radial_profiles", std::to_string(s.editable.basis.size)});
        p.push_back({"radial_construction", radialConstructionName(s.editable.basis.construction)});
        p.push_back({"cell_grading", fmt(s.editable.cellGrading)});
        if (!s.blockCoefficients) p.push_back({"profile_haar_bits", std::to_string(s.editable.haarBits)});
    }
    if (s.components.singleScattering) {
        const SingleScatteringOptions& o = s.singleScattering;
        const bool isotropic = s.material.g == 0.0;
        p.push_back({"ss_phase", isotropic ? "isotropic" : "henyey-greenstein svd"});
        if (!isotropic) {
            p.push_back({"phase_terms", std::to_string(s.phase.terms)});
            p.push_back({"phase_map_size", std::to_string(s.phase.mapSize)});
        }
        p.push_back({"path_samples", std::to_string(o.pathSamples)});
        p.push_back({"path_quadrature", toString(o.pathQuadrature)});
        p.push_back({"ss_supersample", std::to_string(o.supersample)});
        // Recorded only when it acts, so files made without it keep their digest.
        if (o.directionStride > 1 && o.supersample == 1 && o.cubemapSize >= 2) {
            p.push_back({"ss_direction_stride", std::to_string(o.directionStride)});
            p.push_back({"ss_refine_tolerances", fmt(o.refineValueTolerance) + " " + fmt(o.refineValueFloor) +
                                                     " " + fmt(o.refineLargeCellValue)});
        }
        // Recorded only when it acts, so files made without it keep their digest.
        if (o.siteSpacing > 0.0)
            p.push_back({"ss_sites", fmt(o.siteSpacing) + " mm, " + std::to_string(o.siteCoefficientFactor) +
                                         "x coefficients per site"});
        p.push_back({"ss_path", "inward normal, deterministic importance samples (Wang 2005 Eqs. 10-11)"});
        p.push_back({"ss_depth_cap_mfp", fmt(o.depthCapMeanFreePaths)});
        p.push_back({"ss_min_throughput", fmt(o.minThroughput)});
        // How the rays are traced changes the result slightly (robust traversal), so it
        // is part of the digest. V from the exit ray is recorded only where it applies,
        // so files made with the second-ray rule keep their digest.
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

}  // namespace prt
