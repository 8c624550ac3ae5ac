#pragma once
// The settings of one precompute job: what prt-precompute's options and JSON job keys
// set (job_options.h), with the options of each pass held as the very struct that pass
// takes (settings.pass1 is what computeIrradianceTransport runs with, and so on), and
// their text as stored in the transport file and hashed into its input digest.

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "common/bssrdf.h"
#include "common/ground.h"
#include "common/mesh.h"
#include "common/radial_basis.h"
#include "common/transport_file.h"
#include "common/transport_params.h"
#include "precompute/job/distribution.h"
#include "precompute/passes/irradiance_transport.h"
#include "precompute/passes/multiple_scattering.h"
#include "precompute/passes/phase_factoring.h"
#include "precompute/passes/single_scattering.h"

namespace prt {

// Where the surface samples x_i of pass 1 go (Poisson disk, common/sampling.h).
struct SamplePlacement {
    size_t count = 0;          // 0: from spacingMm
    double spacingMm = 0;      // 0: the material's smallest mean free path l_u
    size_t maxCount = 300000;  // cap on the automatic count
    uint64_t seed = 1;
};

// --editable: pass 2 against a radial basis instead of the material's dipole, so that
// the material and the object's size can change at relight time without a new
// precompute (docs/editable-transport.md). The basis covers every channel of
// `materials` (and the job's own material) at every size in [sizeMinMm, sizeMaxMm]
// (object sizes as --size-mm measures them, the bounding-box diagonal, in mm).
struct EditableSettings {
    bool enabled = false;
    // Materials as parseMaterial text; empty: every measured material with absorption
    // (all but Spectralon, whose sigma_a = 0 no fixed basis can follow).
    std::vector<std::string> materials;
    // 0, 0: half and twice the job's own size.
    double sizeMinMm = 0.0, sizeMaxMm = 0.0;
    // J (a multiple of 3: the file packs three profiles per component) and the
    // construction (radial_basis.h).
    RadialBasisOptions basis;
    // g of the cell quadrature's graded sub-points (cell_quadrature.h): the profiles
    // reach down to the narrowest material of the range, whose peak alone needs the
    // fine spacing. 0: one level of sub-points at the fine spacing.
    double cellGrading = 8.0;
    // Bits of the profiles' Haar values in a per-vertex file (SparseRgbVectors::haarBits):
    // 8 keeps kDefaultEditableCoefficients terms in fewer bytes than 128 at 16 bits
    // (the files, version 6, also store the shared index list once, varint-coded); 16
    // for comparisons that must not see the 8-bit rounding.
    int haarBits = 8;
};

// prt-precompute's shared terms per block of 16 vertices when a job does not choose
// (JobOptions::blockCoefficients).
inline constexpr size_t kDefaultBlockCoefficients = 160;
// The terms per vertex the joint choice picks from when a blocked job does not set -k.
inline constexpr size_t kDefaultPreBlockCoefficients = 192;
// The terms per vertex of an editable per-vertex job that does not set -k (shared by its
// profiles, 8-bit Haar values).
inline constexpr size_t kDefaultEditableCoefficients = 296;

struct PrecomputeSettings {
    std::string meshPath;
    std::string outputPath;           // empty only with pass1Only
    MeshScale scale;                  // exactly one of sizeMm / mmPerUnit
    Material material;                // with eta and g
    ScatteringComponents components;  // default: multiple scattering only

    // What every pass and the file share; withSharedValues() sets them (and the
    // material's eta) on the pass options below, whose own copies are not read.
    int cubemapSize = 32;             // N of the 6 x N x N lighting cubemap (<= 64)
    int shTerms = 9;                  // SH part of every multiple-scattering vector: 0, 1, 4 or 9
    size_t vertexCoefficients = 128;  // terms kept per vertex and component, the SH terms included
    // > 0: the file stores blocks of 16 nearby vertices sharing this many jointly chosen
    // terms, picked from each vertex's vertexCoefficients (common/blocked_vectors.h).
    // 0: per-vertex vectors. The command line's default is kDefaultBlockCoefficients
    // (JobOptions); a PrecomputeSettings made in code is per vertex unless it says so.
    size_t blockCoefficients = 0;
    // Isotropic single scattering added into the multiple-scattering vectors (both are
    // dotted with the same light and scaled by F_t(w_o); Wang et al. 2005 Sec. 5), each
    // vertex's sum truncated to vertexCoefficients: one vector per vertex to relight, the
    // two components no longer shown apart (precompute/job/fold_single_scattering.h).
    bool foldSingleScattering = false;

    SamplePlacement samples;
    IrradianceTransportOptions pass1;  // its supersample, sampleCoefficients, sampling
    HierarchyOptions pass2;            // its epsilon, nodeCoefficients
    PhaseFactoringOptions phase;       // single scattering with g != 0
    // Used when components.singleScattering: its supersample, pathQuadrature,
    // pathSamples, directionStride, visibilityFromExitRay. Adaptive directions by
    // default (docs/single-scattering.md, "adaptive directions and 4 Gauss points").
    SingleScatteringOptions singleScattering{.directionStride = 4};
    // --ss-site-spacing: single scattering at sites this far apart (mm; 0 = at every
    // vertex); unset = kSiteSpacingMeanFreePaths mean free paths of the material
    // (resolvedSiteSpacing; docs/single-scattering.md, "Sites"). withSharedValues
    // copies the resolved spacing into singleScattering.siteSpacing.
    std::optional<double> ssSiteSpacing;
    EditableSettings editable;

    // Not physics settings: neither stored in the file nor part of the input digest.
    // Refuse the job up front when its estimated memory (memory_estimate.h) exceeds
    // this many GB; 0 = the machine's available memory.
    double maxMemoryGb = 0.0;
    // Pass 2 runs over this many vertices at a time, each chunk's float vectors moved
    // into the file's quantized arrays before the next (the memory of one chunk, not of
    // the whole mesh, beside them). The results do not depend on it.
    size_t pass2ChunkVertices = 32768;
    // --shard i/n: only the vertices of shard i of n, into a shard file that prt-merge
    // joins (distribution.h); the shards of a job share its input_digest.
    std::optional<ShardSpec> shard;
    // --pass1-file: the samples' pass-1 vectors are loaded from this file when it exists
    // (made for this job's pass-1 inputs, pass1_file.h), else computed and saved there,
    // so the shards of a job compute pass 1 once. pass1Only: stop after writing it.
    std::string pass1File;
    bool pass1Only = false;
    // A diffuse plane under the object (common/ground.h): it occludes pass 1, and a
    // second transport file holds its own vertices' vectors (groundTransportPath).
    std::optional<GroundSettings> ground;
};

// The settings as the passes take them: cubemapSize, shTerms, vertexCoefficients and
// the material's eta set on pass1, pass2 and singleScattering, and pass2's sampleShFrom.
// Single-scattering vectors get no SH part (docs/single-scattering.md, "Storage").
PrecomputeSettings withSharedValues(PrecomputeSettings s);

// Throws prt::Error naming the bad option.
void validateSettings(const PrecomputeSettings& s);

// The single-scattering site spacing a job uses, mm: ssSiteSpacing, or when unset
// kSiteSpacingMeanFreePaths / luminance(sigma_t) of its material.
inline constexpr double kSiteSpacingMeanFreePaths = 0.75;
double resolvedSiteSpacing(const PrecomputeSettings& s);

// The materials an editable job's basis covers: s.editable.materials parsed with the
// job's eta (or the measured ones with absorption), then the job's own material.
std::vector<Material> editableMaterials(const PrecomputeSettings& s);
// The basis range of an editable job whose scaled mesh has bounding-box diagonal
// `objectSizeMm`: editableMaterials at size factors sizeMin / objectSize .. sizeMax /
// objectSize (defaults 0.5 .. 2), distances up to objectSizeMm. One-line prt::Error
// naming --editable-materials or --editable-sizes when that is impossible (a material
// with sigma_a = 0, ...).
RadialRange editableRange(const PrecomputeSettings& s, double objectSizeMm);

// Every setting as text, in a fixed order, with the input digest (a hash of the rest)
// last: stored in the transport file, so that a batch run can tell whether an output
// is up to date. The single-scattering settings are listed only when single scattering
// is selected, and block_coefficients only when > 0, so files without them keep their
// parameters and digest.
ParameterList settingsParameters(const PrecomputeSettings& s, const MeshFingerprint& mesh);

}  // namespace prt
