#pragma once
// The camera options every rendering tool takes (prt-relight render and view,
// prt-reference): the same names, defaults and meaning everywhere (docs/relight.md,
// "Camera"). Lengths in mm, in the object's space after scaling; angles in degrees.

#include <CLI/CLI.hpp>
#include <glm/glm.hpp>

#include <vector>

#include "common/camera.h"

namespace prt {

struct CameraOptions {
    std::vector<double> eye, target, up{0.0, 1.0, 0.0};  // empty eye/target: automatic
    double fov = 30.0;                                    // vertical, degrees
    int width = 512, height = 512;
    double azimuth = 0.0, elevation = 15.0, fill = 0.9;  // automatic framing
};

// Declares --eye --target --up --fov -W -H --azimuth --elevation --fill (group "Camera").
void addCameraOptions(CLI::App& app, CameraOptions& o);

// The camera of `o` for an object with this bounding sphere: --eye given -> that
// camera looking at --target (default: the sphere centre); otherwise the sphere framed
// from --azimuth/--elevation so it fills --fill of the smaller image side. Throws
// prt::Error naming the option for non-finite or out-of-range values.
Camera makeCamera(const CameraOptions& o, const glm::dvec3& sphereCentre, double sphereRadius);

}  // namespace prt
