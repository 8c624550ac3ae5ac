#pragma once
// prt-relight view: the interactive viewer (docs/viewer.md).
//
// A GLFW window with an OpenGL 3.3+ core context and a Dear ImGui panel. The object
// is the one prt-relight render draws (loadRelightObject, relight/prt/relight_object.h), seen
// through the same Camera (common/camera.h), lit the same way:
//   - on the CPU, when the light changes (environment, rotation, light terms,
//     components): light vector (relight/prt/light_vector.h) + relight kernel (relight/prt/relight_kernel.h)
//     on a worker thread, so frames keep coming while a relight is in flight; the
//     per-vertex results are double-buffered and uploaded when complete;
//   - per pixel, every frame, in the fragment shader: F_t(eta, n . w_o), the view maps
//     h_k(w_o') and the optional specular layer, ports of TranslucentShader::shade and
//     specularReflection; the background is the lat-long environment along the pixel's
//     ray (environmentRadiance: L(R^T d), bilinear, u wraps, v clamps).
//   - point lights (texture-space importance sampling, Chang et al. 2008) on a second
//     worker (relight/viewer/point_light_worker.h): per-vertex M / pi added to the
//     environment's diffuse radiance before upload; each source toggles on its own.
// The projection reproduces cameraRayDirection exactly (same vertical fov, aspect and
// pixel centres), and tone mapping is writePng's (2^exposure, clamp to [0, 1], exact
// sRGB encoding), so a screenshot matches prt-relight render's PNG and EXR.

#include <glm/glm.hpp>

#include <cstddef>
#include <optional>
#include <string>
#include <vector>

#include "common/camera.h"
#include "common/error.h"
#include "common/image.h"
#include "relight/pointlight/point_lights.h"
#include "relight/prt/relight_kernel.h"
#include "relight/render/gbuffer.h"
#include "relight/render/specular.h"
#include "relight/prt/relight_object.h"
#include "relight/pointlight/texture_space_sampling.h"

namespace prt {

struct ViewerSetup {
    RelightObject object;              // loaded and checked (loadRelightObject)
    std::string meshPath, transportPath;
    Camera camera;                     // initial camera (also the "reset" camera)
    ScatteringComponents components;   // initially enabled (what the file has, as asked)
    std::vector<std::string> environments;  // lat-long maps, shown in this order
    double envRotation = 0.0;          // degrees about +Y (rotationY), like --env-rotation
    double exposure = 0.0;             // stops
    size_t lightTerms = 0;             // 0 = all
    bool specular = false;
    int specularBlur = 0;              // 0 = automatic (specularBlurFactor)

    // Point lights by texture-space importance sampling (relight/viewer/point_light_worker.h),
    // added to the environment's light. Unavailable when the transport file names no
    // material.
    std::optional<Material> material;  // the transport file's
    std::vector<Light> pointLights;    // initial lights (mm, the object's frame)
    TextureSpaceOptions tsis;          // split mode, N, seed, shadow map, filter
    int atlasSize = 1024;              // irradiance map resolution
    bool environmentLight = true;      // the environment's light (and background) on at start

    // Scripting. frames > 0: render this many frames once the first relight has landed
    // (and, after them, until no relight is in flight), write the screenshots, exit.
    // Spin and orbit take one step per frame from the first light on, exactly `frames`
    // steps in a scripted run.
    int frames = 0;
    std::vector<std::string> screenshots;  // .exr: linear RGBA (A = 1 on the object);
                                           // anything else: 8-bit sRGB PNG
    bool screenshotWithPanel = false;      // PNGs of the whole window, panel included
    double spinDegreesPerFrame = 0.0;      // rotate the environment every frame
    double orbitDegreesPerFrame = 0.0;     // turn the camera about its up axis through the
                                           // target every frame (+ = toward +X from +Z)
    bool vsync = true;
    bool showPanel = true;
};

// The lat-long maps named by `args`: files as given, directories expanded to their
// .exr and .hdr files in name order. With no args: data/envmaps/ under the current
// directory, else under the source tree. Throws prt::Error when nothing is found.
std::vector<std::string> findEnvironments(const std::vector<std::string>& args);

// Fails early and clearly (prt::Error "display: ...") when no window can be opened
// (no X display / Wayland compositor). Leaves GLFW initialised for runViewer.
void checkViewerDisplay();

// Runs the viewer until the window is closed (or the scripted frames are done).
// Throws prt::Error for unreadable environments, no OpenGL 3.3 core context, shader or
// framebuffer failures, and screenshot write errors. Returns the exit code.
int runViewer(ViewerSetup setup);

}  // namespace prt
