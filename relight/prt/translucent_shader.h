#pragma once
// View-dependent shading of relit per-vertex radiance at the pixels of a G-buffer:
// Fresnel transmittance at the view direction and the phase terms' view maps at the
// refracted view direction (Wang et al. 2005, Eqs. 6 and 10). Radiance in the
// environment's units; directions unit, world frame.

#include <glm/glm.hpp>

#include "common/cubemap.h"
#include "common/mesh.h"
#include "common/transport_file.h"
#include "relight/prt/eye_path.h"
#include "relight/prt/relight_kernel.h"
#include "relight/render/gbuffer.h"

namespace prt {

// View-dependent shading of relit per-vertex radiance (relight_kernel.h) at a G-buffer
// pixel (Wang et al. 2005, Eqs. 6 and 10):
//   L = F_t(eta, n . w_o) * ( sum_i b_i diffuse[v_i]
//                             + V(cos_o') sum_k h_k(w_o') sum_i b_i terms[k][v_i] )
// with b the pixel's barycentrics, v_i the hit triangle's vertices, n the
// interpolated normal, w_o = toViewer and w_o' = refractDirection(w_o, n, eta) (unit,
// pointing INTO the medium, bssrdf.h). h_k(w_o') is the view map of term k looked up
// bilinearly (Cubemap::sampleBilinear) in the direction w_o' itself; V(cos_o') is the
// eye's-path factor at cos_o' = -n . w_o' (eye_path.h; all ones for the inward normal).
// A file's isotropic single scattering reaches the shader as a term with h_0 = 1
// (loadRelightObject), so the factor applies to it too. A pixel whose
// interpolated normal faces away from the viewer (n . w_o <= 0, possible at
// silhouettes) gets F_t = F_t(eta, 0) = 0, i.e. black. Non-hit pixels give 0.
class TranslucentShader {
public:
    // `mesh` (the one traced, in mm) must outlive the shader; viewMaps may be null
    // (no K-term single scattering; terms in VertexRadiance are then ignored).
    TranslucentShader(const TriangleMesh& mesh, double eta, const ViewMaps* viewMaps = nullptr,
                      const EyePathTable& eyePath = {});

    glm::vec3 shade(const GBufferPixel& pixel, const VertexRadiance& radiance) const;

    int viewTermCount() const { return viewTerms_; }
    // h_k(wRefracted), bilinear; wRefracted need not be unit. 0 without view maps.
    float viewTerm(int k, const glm::dvec3& wRefracted) const;

private:
    const TriangleMesh* mesh_;
    double eta_;
    int viewTerms_ = 0;
    Cubemap viewMaps_;  // K channels, channel k = h_k
    EyePathTable eyePath_;
};

}  // namespace prt
