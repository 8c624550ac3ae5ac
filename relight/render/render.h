#pragma once
// Offline frame rendering shared by prt-relight render and prt-reference: primary
// rays through a Camera (camera.h) against the object's RayScene give a G-buffer;
// shading is then a function of the G-buffer (per-vertex relit radiance interpolated
// barycentrically, or a brute-force reference), composited over the environment.
//
// Images are linear RGBA float: RGB radiance, A = 1 on object pixels, 0 on
// background (prt-compare measures errors over A = 1 pixels only). One ray per pixel
// through its centre, so the renderer and the reference see identical pixels.

#include <glm/glm.hpp>

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "common/camera.h"
#include "common/cubemap.h"
#include "common/image.h"
#include "common/mesh.h"
#include "common/raytrace.h"
#include "relight/prt/relight_kernel.h"
#include "common/transport_file.h"

namespace prt {

struct GBufferPixel {
    bool hit = false;
    uint32_t triangle = kNoTriangle;
    glm::vec3 barycentric{0.0f};  // weights of the triangle's vertices 0, 1, 2
    glm::vec3 position{0.0f};     // hit point, mm
    glm::vec3 normal{0.0f};       // interpolated vertex normal, unit, facing the viewer's side as the mesh says
    glm::vec3 toViewer{0.0f};     // unit direction from the hit point to the eye (w_o)
    glm::vec3 rayDirection{0.0f}; // unit primary ray direction (for the background)
};

struct GBuffer {
    int width = 0, height = 0;
    std::vector<GBufferPixel> pixels;  // row-major, top row first
    size_t objectPixels() const;
};

// Traces one primary ray per pixel (multithreaded).
GBuffer traceGBuffer(const RayScene& scene, const TriangleMesh& mesh, const Camera& camera);

// RGBA image: object pixels from shade(pixel) (RGB), A = 1; background pixels the
// environment radiance along the ray, sampled from `background` (lat-long, rotated by
// `envRotation` as in envmap.h), A = 0. background may be empty (black).
// shade is called concurrently from several threads.
Image compose(const GBuffer& g, const Image& background, const glm::dmat3& envRotation,
              const std::function<glm::vec3(const GBufferPixel&)>& shade);

// Environment radiance along direction d of a lat-long map rotated by R (L(R^T d)),
// bilinear.
glm::vec3 environmentRadiance(const Image& latlong, const glm::dmat3& rotation, const glm::dvec3& d);

// ---------------------------------------------------------------------------
// Additions for prt-relight render (and the viewer / reference tools)
// ---------------------------------------------------------------------------

// The object as the relighting tools place it: the mesh file loaded, checked against
// the transport file's fingerprint (a mismatch is a prt::Error naming the transport
// file) and scaled by the file's mmPerUnit about the origin (as prt-precompute did),
// so positions are in mm and vertex v is the transport file's vertex v.
struct RelightObject {
    TriangleMesh mesh;        // mm
    TransportFile transport;
    double eta = 1.3;         // transport.parameter("eta"); 1.3 when the file has none
    Bounds box;               // of the scaled mesh
    glm::dvec3 sphereCentre{0.0};  // bounding sphere: the box centre and the largest
    double sphereRadius = 0.0;     // distance of a vertex from it
};
RelightObject loadRelightObject(const std::string& meshPath, const std::string& transportPath);

// View-dependent shading of relit per-vertex radiance (relight.h) at a G-buffer
// pixel (Wang et al. 2005, Eqs. 6 and 10):
//   L = F_t(eta, n . w_o) * ( sum_i b_i diffuse[v_i]
//                             + sum_k h_k(w_o') sum_i b_i terms[k][v_i] )
// with b the pixel's barycentrics, v_i the hit triangle's vertices, n the
// interpolated normal, w_o = toViewer and w_o' = refractDirection(w_o, n, eta) (unit,
// pointing INTO the medium, bssrdf.h). h_k(w_o') is the view map of term k looked up
// bilinearly (Cubemap::sampleBilinear) in the direction w_o' itself. A pixel whose
// interpolated normal faces away from the viewer (n . w_o <= 0, possible at
// silhouettes) gets F_t = F_t(eta, 0) = 0, i.e. black. Non-hit pixels give 0.
class TranslucentShader {
public:
    // `mesh` (the one traced, in mm) must outlive the shader; viewMaps may be null
    // (no K-term single scattering; terms in VertexRadiance are then ignored).
    TranslucentShader(const TriangleMesh& mesh, double eta, const ViewMaps* viewMaps = nullptr);

    glm::vec3 shade(const GBufferPixel& pixel, const VertexRadiance& radiance) const;

    int viewTermCount() const { return viewTerms_; }
    // h_k(wRefracted), bilinear; wRefracted need not be unit. 0 without view maps.
    float viewTerm(int k, const glm::dvec3& wRefracted) const;

private:
    const TriangleMesh* mesh_;
    double eta_;
    int viewTerms_ = 0;
    Cubemap viewMaps_;  // K channels, channel k = h_k
};

// Turntable: the object turned by `degrees` about the vertical (+Y) axis through
// `pivot`, seen by `camera` in a fixed world with a fixed environment, is rendered
// with the precomputed transport (which is tied to the object's own frame) by moving
// the world instead: the camera orbits by -degrees about the same axis (returned
// here) and the environment is rotated by rotationY(-degrees) (compose the
// environment rotation as rotationY(-degrees) * envRotation for both lighting and
// background). The image is identical to the one of the turned object, background
// included: the background stays fixed in the world.
Camera turntableCamera(const Camera& camera, const glm::dvec3& pivot, double degrees);

// Optional specular layer (Wang et al. 2005, "Rendering": a Fresnel-weighted
// reflection of a pre-filtered environment, no occlusion):
//   L_s = F_r(eta, n . w_o) * L_pre(R^T reflect(-w_o, n))
// with F_r = 1 - F_t the exact dielectric reflectance, n the interpolated normal and
// L_pre the pre-filtered lat-long map rotated by R like the lighting (bilinear, as
// environmentRadiance). 0 where n . w_o <= 0 or for non-hit pixels.
glm::vec3 specularReflection(const GBufferPixel& pixel, double eta, const Image& prefiltered,
                             const glm::dmat3& rotation);

// The pre-filter: a lat-long map box-filtered down by `factor` in both directions
// (factor must divide width and height; 1 returns the map), each output pixel the
// solid-angle weighted mean of the factor x factor input pixels it covers, so the
// integral over the sphere is preserved. Blurs reflections over about
// factor * 360 / width degrees. Throws prt::Error for a bad factor.
Image prefilterEnvironment(const Image& latlong, int factor);

}  // namespace prt
