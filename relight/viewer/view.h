#pragma once
// prt-relight view: the interactive viewer (docs/viewer.md), its entry points.
//
// The object is the one prt-relight render draws (loadRelightObject,
// relight/prt/relight_object.h), seen through the same Camera (common/camera.h), with
// the same look (FrameSettings, relight/prt/frame_settings.h), so a screenshot matches
// prt-relight render's PNG and EXR of the same arguments. The light is relit on the CPU
// on worker threads whenever it changes (relight_worker.h; point lights:
// point_light_worker.h) while frames keep coming; the view-dependent shading runs per
// pixel on the GPU every frame (scene_gl.h). The window and input are window.h, the
// panel panel.h.

#include <cstddef>
#include <optional>
#include <string>
#include <vector>

#include "common/camera.h"
#include "common/materials.h"
#include "common/transport_params.h"
#include "relight/pointlight/environment_lights.h"
#include "relight/pointlight/point_lights.h"
#include "relight/pointlight/texture_space_sampling.h"
#include "relight/prt/frame_settings.h"
#include "relight/prt/relight_object.h"

namespace prt {

// A material edit made in the middle of a scripted run (--edit-after, --edit-material,
// --edit-size-mm; docs/viewer.md, "Scripting"), so a scripted run exercises the live
// edit path: once `afterFrames` frames have been shown with light, the ViewState takes
// the material and size through the panel's own edit (editMaterial, panel.h) and the
// relight worker applies it like any panel edit (projected while the light stands
// still, recombined when the light changes in the same frame; relight_worker.h).
struct ScriptedEdit {
    int afterFrames = 0;  // K, 1 <= K < frames: the first K frames show the material before the edit
    Material material;    // eta and g are the file's
    double sizeMm = 0.0;  // > 0, covered by the basis together with `material`
};

struct ViewerSetup {
    RelightObject object;              // loaded and checked (loadRelightObject)
    std::string meshPath, transportPath;
    Camera camera;                     // initial camera (also the "reset" camera)
    int subpixels = 1;                 // --spp n^2: n x n sub-pixels per pixel, box-filtered (SceneGl)
    FrameSettings frame;               // the initial look, as prt-relight render takes it
    ScatteringComponents components;   // frame.components resolved against the file (selectComponents)
    std::vector<std::string> environments;  // lat-long maps, shown in this order

    // Point lights by texture-space importance sampling (relight/viewer/point_light_worker.h),
    // added to the environment's light. Unavailable when the transport file names no
    // material.
    std::optional<Material> material;  // the transport file's
    std::vector<Light> pointLights;    // initial lights (mm, the object's frame)
    TextureSpaceOptions tsis;          // split mode, N, seed, shadow map, filter
    int atlasSize = kDefaultIrradianceMapSize;              // irradiance map resolution
    // Their surface terms at start (vertex_surface_terms.h; prt-pointlight --specular,
    // --specular-roughness, --single-scattering, --single-scattering-samples).
    bool pointSpecular = false;
    double pointSpecularRoughness = 0.3;
    bool pointSingleScattering = false;
    int pointSingleScatteringSamples = 8;
    bool environmentLight = true;      // the environment's light (and background) on at start
    // --sun-split: the environment's brightest texels as directional lights at the
    // vertices (sun_split_worker.h), refining the relight once they land; nullopt: off.
    std::optional<SunSplitOptions> sunSplit;

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
    double lightOrbitDegreesPerFrame = 0.0;  // turn the lights about +Y through the object's
                                             // bounding-box centre every frame
    std::optional<ScriptedEdit> edit;      // editable files with frames > 0 (makeScriptedEdit)
    bool vsync = true;
    bool showPanel = true;
};

// The scripted edit of --edit-after K, --edit-material TEXT, --edit-size-mm S for
// `object` (the startup edit, --material / --size-mm, already applied) in a run of
// `frames` frames. TEXT is read by parseMaterial with the file's eta and g; an absent
// TEXT keeps the object's current material, an absent S its current size. Throws
// prt::Error naming the option: --edit-* on a file that is not editable, --edit-after
// missing or without --edit-material / --edit-size-mm, K outside [1, frames), bad
// material text, S not finite and > 0, a material and size the basis does not cover
// (materialProblem, panel.h). Nothing given: nullopt. Call before runViewer: it reads
// the object's current material and size, which the relight worker owns from then on.
std::optional<ScriptedEdit> makeScriptedEdit(const RelightObject& object, int frames,
                                             const std::optional<int>& afterFrames,
                                             const std::optional<std::string>& materialText,
                                             const std::optional<double>& sizeMm,
                                             const std::string& transportPath);

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
