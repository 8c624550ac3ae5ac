#pragma once
// The specular term of prt-pointlight's frames (--specular; docs/point-lights.md,
// "Specular"): light reflected at the object's surface, shadowed, Fresnel-weighted, by a
// GGX (Trowbridge-Reitz) microfacet lobe. The environment renderers' specular layer is
// relight/render/specular.h; this is its counterpart for point, spot and directional
// lights, which a mirror would reflect into a single pixel, hence a rough lobe.
//
// THE LOBE. With n the shading normal, w_i toward the light, w_o toward the viewer (both
// unit, outside), h = normalize(w_i + w_o) and alpha the GGX roughness (the slope-space
// width, --specular-roughness, used as given: NOT squared):
//   f_s(w_i, w_o) = F_r(eta, w_i . h) D(h) G(w_i, w_o) / (4 (n . w_i)(n . w_o))      [sr^-1]
//   D(h)          = alpha^2 / (pi ((n . h)^2 (alpha^2 - 1) + 1)^2)
//   G             = G_1(w_i) G_1(w_o),  G_1(w) = 2 (n . w) / ((n . w) + sqrt(alpha^2 + (1 - alpha^2)(n . w)^2))
//   F_r           = 1 - F_t: the exact unpolarised dielectric reflectance of common/bssrdf.h
//                   at the material's eta (the share of the light that does NOT enter
//                   the medium and feed the translucent terms)
// D is normalised (int D(h) (n . h) dw_h = 1), so at normal incidence the directional
// albedo int f_s (n . w_o) dw_o is F_r(eta, 1) less what masking (G) and the horizon
// take (measured in docs/point-lights.md; tested).
//
// THE TERM. Per pixel (its surface point x, shading normal n, triangle normal n_g) and
// summed over the lights:
//   L_s(x, w_o) = sum_lights f_s(w_i, w_o) E_light(x) (n . w_i) V(x, w_i)      [W/(m^2 sr)]
// with w_i, E_light (W/m^2 at normal incidence: 1e6 I / r^2, a spot's with its falloff,
// or E_perp) and V exactly as pass 1 (point_lights.h: incidentLight, lightUnoccluded);
// nothing where n . w_i <= 0, n_g . w_i <= 0 or n . w_o <= 0.
// The frame adds L_s to the translucent radiance UNTINTED by --base-colour (reflection
// at the surface, as base_colour.h states for the environment's specular layer).
//
// Units: mm for positions, W/m^2 irradiance, W/(m^2 sr) radiance (point_lights.h).

#include <glm/glm.hpp>

#include <vector>

#include "common/image.h"
#include "common/mesh.h"
#include "common/raytrace.h"
#include "relight/pointlight/point_lights.h"
#include "relight/render/gbuffer.h"

namespace prt {

// --specular-roughness's default (a satin-like highlight).
inline constexpr double kDefaultSpecularRoughness = 0.3;

// Throws prt::Error(option, ...) unless 0 < alpha <= 1 (finite); option names the
// setting in the message (prt-relight view's is --point-specular-roughness). Below
// ~0.01 the lobe is a near-mirror that a point light turns into a sub-pixel highlight.
void validateSpecularRoughness(double alpha, const char* option = "--specular-roughness");

// The lobe's factors (cosines as above; 0 for a non-positive cosine).
double ggxDistribution(double alpha, double cosH);
double ggxMasking(double alpha, double cosTheta);  // G_1
// f_s(w_i, w_o) in sr^-1 for unit n, w_i, w_o; 0 when either is below the horizon.
double specularBrdf(double eta, double alpha, const glm::dvec3& n, const glm::dvec3& wi, const glm::dvec3& wo);

// L_s at a surface point seen from toViewer (unit, outside), W/(m^2 sr), RGB.
glm::dvec3 pointSpecular(const RayScene& scene, const std::vector<Light>& lights, const SurfacePoint& x,
                         const glm::dvec3& toViewer, double eta, double alpha);

// The surface point of a G-buffer pixel: its position and interpolated normal, and its
// triangle's normal (faceNormal) for the shadow rays' offsets.
SurfacePoint surfacePointOf(const TriangleMesh& mesh, const GBufferPixel& pixel);

// L_s at every hit pixel of g (3 channels, g's size; 0 elsewhere), in parallel; each
// pixel independent of the others and of the thread count.
Image specularImage(const GBuffer& g, const TriangleMesh& mesh, const RayScene& scene,
                    const std::vector<Light>& lights, double eta, double alpha);

}  // namespace prt
