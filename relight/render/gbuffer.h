#pragma once
// The G-buffer every offline renderer shares (prt-relight render, prt-pointlight,
// prt-reference): one primary ray per pixel through its centre, traced against the
// object's RayScene; shading is then a function of the G-buffer, composited over the
// environment, so every renderer and the reference see identical pixels.
//
// Images are linear RGBA float: RGB radiance, A = 1 on object pixels, 0 on the
// background (prt-compare measures errors over A = 1 pixels only). Positions in mm,
// world frame of docs/conventions.md.

#include <glm/glm.hpp>

#include <cstdint>
#include <functional>
#include <vector>

#include "common/camera.h"
#include "common/image.h"
#include "common/mesh.h"
#include "common/raytrace.h"

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
    // The pixel of column x, row y (row 0 at the top); no bounds check.
    const GBufferPixel& at(int x, int y) const { return pixels[size_t(y) * size_t(width) + size_t(x)]; }
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

// Turntable: the object turned by `degrees` about the vertical (+Y) axis through
// `pivot`, seen by `camera` in a fixed world with a fixed environment, is rendered
// with the precomputed transport (which is tied to the object's own frame) by moving
// the world instead: the camera orbits by -degrees about the same axis (returned
// here) and the environment is rotated by rotationY(-degrees) (compose the
// environment rotation as rotationY(-degrees) * envRotation for both lighting and
// background). The image is identical to the one of the turned object, background
// included: the background stays fixed in the world.
Camera turntableCamera(const Camera& camera, const glm::dvec3& pivot, double degrees);

}  // namespace prt
