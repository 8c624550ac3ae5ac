#pragma once
// Editable transport at relight time (docs/editable-transport.md): the material and the
// object's size of a file made with prt-precompute --editable change live, without a
// new precompute.
//
// WHAT THE FILE HOLDS. Instead of the multiple-scattering vector V_c = T_d,c / pi per
// vertex and colour channel, one vector U_j per radial profile B_j of its radial basis
// (common/radial_basis.h), computed by the same pass 2 with B_j in place of R_d,c
// (common/radial_kernels.h). Pass 2 is linear in its kernel, so with the
// basis fit R_d,c(r) ~ sum_j w_cj B_j(r) of a material,
//     V_c = sum_j w_cj U_j                                              (recombine)
// is that material's multiple-scattering vector, up to the fit error of the basis
// (stored with the file: prt-relight info).
//
// SIZE. An object s times larger is the same object with s times the coefficients
// (common/material_edit.h, SIZE AS MATERIAL): a size S mm is the material
// scaledMaterial(m, S / S_file) at the file's geometry, S_file the file's object size
// (bounding-box diagonal of the scaled mesh, mm). The lights (a distant environment)
// do not change.
//
// TWO WAYS TO RELIGHT.
//   - The material stands still, the light moves: recombine() once per edit gives an
//     ordinary RGB component (kind MultipleScattering), which relightVertices
//     (relight_kernel.h) relights at the cost of a file made without --editable.
//   - The light stands still, the material moves: projectLight() once per light gives
//     D_vjc = U_j(v) . L_c for every vertex, profile and light channel; then an edit is
//     relightProjected(): J multiply-adds per vertex and channel.
// Both give the same radiance up to float rounding (and the quantization of the
// recombined component: kQuantizationMaxRelativeError of each vertex's maximum per
// vertex, kBlockQuantizationMaxRelativeError blocked).
//
// BLOCKED FILES (prt-precompute --editable --block-coefficients K): the profile
// components share one block order; per block each keeps its own index list, nested in
// a union of at most K (jointTruncateNested; files before format version 7: one list
// for all, jointTruncateShared). recombine() gives a blocked component with the same
// blocks and each block's union as its list: it relights through the blocked kernel.
//
// WHAT IS NOT EDITED. Single scattering stays the file's material's (its components
// are not touched); the index of refraction stays the file's (pass 1 bakes the
// transmittance at eta): a material with another eta is applied with the file's
// (setMaterial replaces it and reports it).
//
// ERRORS. A material or size outside the basis's range is a one-line prt::Error naming
// the channel and the bound (RadialBasis::requireCovered), never a silent wrong image;
// a file without a radial basis is refused by the constructor.
//
// Threads: recombine() and projectLight() are parallel (TBB) and deterministic.

#include <glm/glm.hpp>

#include <array>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "common/materials.h"
#include "common/radial_basis.h"
#include "common/transport_file.h"
#include "relight/prt/light_vector.h"

namespace prt {

class EditableTransport {
public:
    // Moves the profile components (and the stored basis) out of `file`, which keeps
    // every other component. objectSizeMm: the file's object size S_file (> 0). The
    // file's material (transport_params.h) is the starting material, at S_file.
    // Throws prt::Error(path, ...) for a file without a radial basis or whose material
    // the basis does not cover.
    EditableTransport(TransportFile& file, double objectSizeMm, const std::string& path = "transport file");

    const RadialBasis& basis() const { return basis_; }
    double objectSizeMm() const { return objectSizeMm_; }
    const Material& fileMaterial() const { return fileMaterial_; }
    size_t vertexCount() const;
    int profileCount() const { return basis_.size(); }

    // The material and size of the next relight: eta is forced to the file's (the
    // return value says whether it was changed), the weights are fitted (microseconds).
    // Throws prt::Error for a size <= 0 or a material the basis does not cover (the
    // current one is kept).
    bool setMaterial(const Material& material, double sizeMm);
    const Material& material() const { return material_; }
    double sizeMm() const { return sizeMm_; }
    // Whether the current material and size are the file's own (single scattering,
    // which is not edited, then matches).
    bool isFileMaterial() const;
    // w_cj of the current material (3 x J).
    const std::array<std::vector<double>, 3>& weights() const { return weights_; }

    // V_c = sum_j w_cj U_j per vertex, quantized like any component of the profiles'
    // encoding (kind MultipleScattering, the profiles' shared index lists): per vertex,
    // or blocked (the profiles' block order, per block the union of their index lists,
    // 8-bit values with new per-lane scales, blocked_vectors.h) when the file's profiles
    // are blocked.
    TransportComponent recombine() const;
    // The same, unless stop() returns true (asked every 64 vertices, from any of the
    // threads): then nothing (a per-vertex file's recombination gives way to newer
    // work; a blocked one runs to the end).
    std::optional<TransportComponent> recombineUnless(const std::function<bool()>& stop) const;

    // D_vjc = U_j(v) . L_c for every vertex v, profile j, light channel c (the SH part
    // included, as relightVertices).
    void projectLight(const LightVector& light);
    bool hasProjectedLight() const { return !projected_.empty(); }
    // diffuse[v]_c = sum_j w_cj D_vjc: the multiple-scattering part of relightVertices'
    // `diffuse` for the current material (resized to the vertex count).
    void relightProjected(std::vector<glm::vec3>& diffuse) const;

private:
    TransportComponent recombineBlocked() const;
    // Blocked profiles: each block's union of their lists, the recombination's (once).
    void blockUnion();

    std::vector<TransportComponent> profiles_;  // P = J / 3, profiles 3p .. 3p + 2
    uint32_t cubemapSize_ = 0, shTerms_ = 0;
    RadialBasis basis_;
    double objectSizeMm_ = 0.0;
    Material fileMaterial_, material_;
    double sizeMm_ = 0.0;
    std::array<std::vector<double>, 3> weights_;
    std::vector<float> projected_;  // V x J x 3
    std::vector<uint32_t> unionOffsets_;  // blocked profiles: blocks + 1
    std::vector<uint16_t> unionIndices_;
};

}  // namespace prt
