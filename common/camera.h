#pragma once
// Pinhole look-at camera shared by the offline renderer, the reference renderer and
// the viewer, so all three see identical rays (docs/relight.md).
//
// World frame: right-handed, +Y up (docs/conventions.md). The camera looks from `eye`
// toward `target`; `up` fixes the roll. fovY is the full vertical field of view in
// degrees. Pixel (x, y) has its centre at (x + 0.5, y + 0.5); y = 0 is the top row.
// Ray directions are unit vectors.

#include <glm/glm.hpp>

namespace prt {

struct Camera {
    glm::dvec3 eye{0.0, 0.0, 100.0};
    glm::dvec3 target{0.0};
    glm::dvec3 up{0.0, 1.0, 0.0};
    double fovY = 30.0;  // degrees, (0, 180)
    int width = 512;
    int height = 512;

    bool operator==(const Camera&) const = default;
};

// The largest image side validateCamera accepts.
inline constexpr int kMaxCameraSide = 16384;

// Throws prt::Error (subject "camera") for eye == target, up parallel to the view
// direction, fovY outside (0, 180) or non-positive image sizes.
void validateCamera(const Camera& camera);

// Unit direction of the ray through the point (px, py) of the image plane, in pixel
// units (px = x + 0.5 is the centre of column x).
glm::dvec3 cameraRayDirection(const Camera& camera, double px, double py);

// The inverse: the continuous pixel position where direction d (from the eye) lands;
// returns false when d points behind the camera.
bool projectDirection(const Camera& camera, const glm::dvec3& d, double& px, double& py);

// A camera looking at the bounding sphere (centre, radius) from the direction given
// by azimuth (degrees about +Y, 0 = from +Z, i.e. looking down -Z) and elevation
// (degrees above the horizontal), at the distance where the sphere fills `fill` of
// the smaller image dimension.
Camera frameSphere(const glm::dvec3& centre, double radius, double azimuthDeg,
                   double elevationDeg, double fovY, int width, int height, double fill = 0.9);

}  // namespace prt
