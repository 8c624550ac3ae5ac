#pragma once
// The point lights' specular and single-scattering terms with their rays traced at the
// mesh's VERTICES: what prt-relight view draws for its point lights, and what
// prt-pointlight --method tsis --evaluate vertex renders (docs/point-lights.md,
// "Per-vertex surface terms"). The per-pixel terms (point_specular.h,
// point_single_scattering.h) trace rays at every pixel, which an interactive frame
// cannot afford; here what needs rays is computed once per vertex and interpolated
// barycentrically, and what needs none stays per pixel.
//
// SPECULAR. At every vertex v and light l, the light's shadowed irradiance
//     S_l(v) = E_l(x_v) V(x_v, w_l(x_v))                       [W/m^2, RGB]
// (incidentLight at x_v; V the shadow ray of lightUnoccluded from x_v, offset along the
// vertex normal; no horizon test here: the pixel's cosines make it). At a pixel (its
// point x, interpolated unit normal n, triangle normal n_g, w_o toward the eye):
//     L_s(x, w_o) = sum_l f_s(w_l(x), w_o) (n . w_l(x)) sum_k b_k S_l(v_k)
// with w_l(x) toward the light from the pixel's own point (the direction of a
// directional light), b_k the pixel's barycentrics, f_s the GGX lobe of point_specular.h
// and its zero conditions (n . w_l, n_g . w_l or n . w_o <= 0). It equals pointSpecular
// wherever the triangle's three vertices share the pixel's visibility and E_l is linear
// across the triangle; shadow edges soften over one triangle.
//
// SINGLE SCATTERING. At every vertex v, seen from the eye along w_o(v) = normalize(eye - x_v):
//     T(v) = singleScatteringAlongRay(x_v, refract(w_o(v), n_v))   [W/(m^2 sr)]
// pointSingleScattering at the surface point (x_v, n_v, n_v) before its outgoing Fresnel
// factor; 0 where n_v . w_o(v) <= 0. At a pixel
//     L^(1)(x, w_o) = F_t(eta, n . w_o) sum_k b_k T(v_k)
// so it interpolates as the per-vertex diffusion does (TextureSpaceRenderer::
// renderPerVertex), and the viewer adds T to the per-vertex radiance its shader
// multiplies by F_t. It depends on the eye: the viewer recomputes it when the camera
// moves. Vertices facing away from the eye give 0, so pixels next to the silhouette
// blend toward black across one triangle.
//
// Units: mm, W/m^2, W/(m^2 sr) (point_lights.h). Everything runs in parallel and does not
// depend on the thread count.

#include <glm/glm.hpp>

#include <vector>

#include "common/image.h"
#include "common/materials.h"
#include "common/mesh.h"
#include "common/raytrace.h"
#include "relight/pointlight/point_lights.h"
#include "relight/pointlight/point_single_scattering.h"
#include "relight/render/gbuffer.h"

namespace prt {

// S_l(v) for every light l and vertex v, at index l * V + v (V = mesh.vertexCount()).
// The mesh must have vertex normals (the shadow rays' offsets); prt::Error otherwise.
std::vector<glm::vec3> vertexLightIrradiance(const RayScene& scene, const TriangleMesh& mesh,
                                             const std::vector<Light>& lights);

// L_s at a G-buffer pixel (a hit) from vertexLightIrradiance's values, which must hold
// lights.size() * mesh.vertexCount() entries (vertexSpecularImage checks it).
glm::dvec3 vertexSpecular(const TriangleMesh& mesh, const std::vector<Light>& lights,
                          const std::vector<glm::vec3>& lightIrradiance, const GBufferPixel& pixel, double eta,
                          double alpha);
// L_s at every hit pixel of g (3 channels, g's size; 0 elsewhere).
Image vertexSpecularImage(const GBuffer& g, const TriangleMesh& mesh, const std::vector<Light>& lights,
                          const std::vector<glm::vec3>& lightIrradiance, double eta, double alpha);

// T(v) for every vertex, seen from `eye` (mm). Throws as singleScatteringImage for bad
// options or material, and prt::Error when the mesh has no vertex normals.
std::vector<glm::vec3> vertexSingleScattering(const RayScene& scene, const TriangleMesh& mesh,
                                              const std::vector<Light>& lights, const Material& material,
                                              const glm::dvec3& eye, const PointSingleScatteringOptions& options = {});
// L^(1) at every hit pixel of g from T: F_t(eta, n . w_o) times T interpolated.
Image vertexSingleScatteringImage(const GBuffer& g, const TriangleMesh& mesh, const std::vector<glm::vec3>& vertexTerm,
                                  double eta);

}  // namespace prt
