#include "common/camera.h"

#include <cmath>
#include <string>

#include "common/error.h"

namespace prt {

namespace {
struct Basis {
    glm::dvec3 forward, right, up;
    double tanHalf;
};
Basis basis(const Camera& c) {
    Basis b;
    b.forward = glm::normalize(c.target - c.eye);
    b.right = glm::normalize(glm::cross(b.forward, c.up));
    b.up = glm::cross(b.right, b.forward);
    b.tanHalf = std::tan(glm::radians(c.fovY) * 0.5);
    return b;
}
}  // namespace

void validateCamera(const Camera& c) {
    if (c.width < 1 || c.height < 1 || c.width > kMaxCameraSide || c.height > kMaxCameraSide)
        throw Error("camera", "image size must be between 1 and " + std::to_string(kMaxCameraSide) + " pixels");
    if (!(c.fovY > 0 && c.fovY < 180)) throw Error("camera", "vertical field of view must be in (0, 180) degrees");
    const glm::dvec3 view = c.target - c.eye;
    if (!(glm::length(view) > 0)) throw Error("camera", "eye and target coincide");
    if (!(glm::length(glm::cross(glm::normalize(view), c.up)) > 1e-9))
        throw Error("camera", "up vector is parallel to the view direction (or zero)");
}

glm::dvec3 cameraRayDirection(const Camera& c, double px, double py) {
    const Basis b = basis(c);
    const double aspect = double(c.width) / c.height;
    const double sx = (2.0 * px / c.width - 1.0) * b.tanHalf * aspect;
    const double sy = (1.0 - 2.0 * py / c.height) * b.tanHalf;
    return glm::normalize(b.forward + sx * b.right + sy * b.up);
}

bool projectDirection(const Camera& c, const glm::dvec3& d, double& px, double& py) {
    const Basis b = basis(c);
    const double z = glm::dot(d, b.forward);
    if (!(z > 0)) return false;
    const double aspect = double(c.width) / c.height;
    const double sx = glm::dot(d, b.right) / z, sy = glm::dot(d, b.up) / z;
    px = (sx / (b.tanHalf * aspect) + 1.0) * 0.5 * c.width;
    py = (1.0 - sy / b.tanHalf) * 0.5 * c.height;
    return true;
}

Camera frameSphere(const glm::dvec3& centre, double radius, double azimuthDeg, double elevationDeg,
                   double fovY, int width, int height, double fill) {
    Camera c;
    c.fovY = fovY;
    c.width = width;
    c.height = height;
    c.target = centre;
    const double az = glm::radians(azimuthDeg), el = glm::radians(elevationDeg);
    const glm::dvec3 dir(std::sin(az) * std::cos(el), std::sin(el), std::cos(az) * std::cos(el));
    // Half-angle the sphere may subtend: fill x the smaller half field of view.
    const double tanHalfY = std::tan(glm::radians(fovY) * 0.5);
    const double tanHalf = fill * tanHalfY * std::min(1.0, double(width) / height);
    const double distance = radius / std::sin(std::atan(tanHalf));
    c.eye = centre + distance * dir;
    return c;
}

}  // namespace prt
