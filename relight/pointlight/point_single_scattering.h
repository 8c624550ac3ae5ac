#pragma once
// Single scattering of point, spot and directional lights (--single-scattering;
// docs/point-lights.md, "Single scattering"): Jensen et al. 2001's single-scattering term
// evaluated per pixel at the visible point x_o, along the REFRACTED view ray.
//
//   L^(1)(x_o, w_o) = F_t(eta, n_o . w_o) sum_lights int_0^{d_m} sigma_s p(w_i', -w_o')
//                     F_t(eta, n_i . w) E_light(x_i) V(x_i, w) e^(-sigma_t (s + s_i')) ds
//
//   w_o'    refractDirection(w_o, n_o, eta) (common/bssrdf.h): the refracted view ray
//           x_p = x_o + s w_o' into the medium (Jensen 2001; NOT the precompute's inward
//           normal, which is Wang's view-independent approximation);
//   d_m     where that ray leaves the object (farSideDistance, common/scattering_path.h),
//           or depthCapMeanFreePaths / |sigma_t| when it leaves nothing;
//   x_i     the light's entry point, approximated as the precompute does for environment
//           light (precompute/passes/single_scattering.h): the first surface point on
//           the STRAIGHT line from x_p toward the light (direction w, as incidentLight
//           at x_p), s_i = |x_i - x_p| the observed length, n_i the vertex normals
//           interpolated there (the triangle normal on a mesh without them); the
//           light's refracted path inside is taken as Jensen's Eq. 5 estimate
//           s_i' = s_i |w . n_i| / sqrt(1 - (1/eta)^2 (1 - |w . n_i|^2))
//           (refractedPathLength, common/scattering_path.h). A first hit on a
//           triangle facing against w means x_p lies outside the object (a
//           concavity), and n_i . w <= 0 a surface turned away from the light:
//           either sample adds nothing;
//   w_i'    refractDirection(w, n_i, eta), the light's propagation direction inside;
//   p       the Henyey-Greenstein phase function with the material's g,
//           henyeyGreensteinDirections(g, w_i', -w_o') (the product's convention);
//   E_light the light's irradiance at x_i at normal incidence (incidentLight at x_i:
//           1e6 I / r^2 with r = |light - x_i|, a spot's with its falloff, or E_perp);
//   V       the shadow ray of lightUnoccluded from x_i (offset along its triangle
//           normal) toward the light: the light shadowed at its entry point;
//   sigma_s = sigma_s' / (1 - g), sigma_t = sigma_a + sigma_s per channel (materials.h).
// The integral over s uses the precompute's path sampling (makePathSamples with
// PathQuadrature::GaussLegendre, common/scattering_path.h): N Gauss-Legendre nodes in
// the sampled mass of the exponential pdf of |sigma_t| (luminance),
// s = -ln(1 - lambda xi) / |sigma_t|, lambda = 1 - e^(-|sigma_t| d_m).
//
// Triangles wound against their vertex normals (scanned meshes; dragon_vrip_res4 has
// 458 of 11,102) face the way the interpolated normal does, at x_o and at x_i: the
// reading of the mesh prt-reference's single scattering makes. Nothing where
// n_o . w_o <= 0 or n_g . w_o <= 0. Like the diffusion, it is light that
// left the medium at x_o, so the frame's --base-colour tints it (base_colour.h: the
// translucent exitance at the exit point; prt-relight render tints its single scattering
// the same way); the specular term is not tinted.
//
// Units: sigma mm^-1 x ds mm x p sr^-1 x E W/m^2 = W/(m^2 sr).

#include <glm/glm.hpp>

#include <vector>

#include "common/image.h"
#include "common/materials.h"
#include "common/mesh.h"
#include "common/raytrace.h"
#include "relight/pointlight/point_lights.h"
#include "relight/render/gbuffer.h"

namespace prt {

struct PointSingleScatteringOptions {
    int pathSamples = 8;                // N Gauss-Legendre nodes along the refracted view ray
    double depthCapMeanFreePaths = 16.0;  // d_m when the ray leaves nothing (open mesh), in 1 / |sigma_t|
};
// Throws prt::Error(samplesOption, ...) unless 1 <= pathSamples <= 256 (samplesOption
// names the setting: prt-relight view's is --point-single-scattering-samples),
// and prt::Error("single scattering", ...) for a cap that is not finite and > 0.
void validatePointSingleScattering(const PointSingleScatteringOptions& options,
                                   const char* samplesOption = "--single-scattering-samples");

// The sum of the formula above (everything after F_t(eta, n_o . w_o)) along the refracted
// view ray from x_o in the unit direction woRefracted (into the medium). No test on
// the normals: the caller has made them.
glm::dvec3 singleScatteringAlongRay(const RayScene& scene, const TriangleMesh& mesh, const std::vector<Light>& lights,
                                    const Material& material, const glm::vec3& xo, const glm::dvec3& woRefracted,
                                    const PointSingleScatteringOptions& options = {});

// L^(1) at x_o seen from toViewer (unit, outside), W/(m^2 sr), RGB. The mesh is the
// scene's (its vertex normals give n_i; the triangle normal without them).
glm::dvec3 pointSingleScattering(const RayScene& scene, const TriangleMesh& mesh, const std::vector<Light>& lights,
                                 const Material& material, const SurfacePoint& xo, const glm::dvec3& toViewer,
                                 const PointSingleScatteringOptions& options = {});

// L^(1) at every hit pixel of g (3 channels, g's size; 0 elsewhere), in parallel; each
// pixel independent of the others and of the thread count.
Image singleScatteringImage(const GBuffer& g, const TriangleMesh& mesh, const RayScene& scene,
                            const std::vector<Light>& lights, const Material& material,
                            const PointSingleScatteringOptions& options = {});

}  // namespace prt
