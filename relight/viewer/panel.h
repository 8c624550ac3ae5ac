#pragma once
// The viewer's Dear ImGui panel (prt-relight view; docs/viewer.md, "Controls"): the
// settings of the ViewState as widgets (environment, rotation, components, specular,
// exposure, light terms, the material and size of an editable file, the point lights
// and their sampling), what the relights and edits cost, the camera with its
// prt-relight render command, and the point lights as markers over the image.
//
// Contract: call between ViewerWindow::beginImGuiFrame and renderImGui, on the window's
// thread. The panel edits `state` only through its widgets and buttons; everything
// else it is given it only reads.

#include <functional>
#include <string>
#include <utility>
#include <vector>

#include "common/transport_params.h"
#include "relight/viewer/point_light_worker.h"
#include "relight/viewer/relight_worker.h"
#include "relight/viewer/view.h"
#include "relight/viewer/view_state.h"

namespace prt {

// The material edits that landed (relight_worker.h): count and times, the last one's path.
struct MaterialEditStats {
    RunningStats edits;  // LightResult::editMs
    LightResult::EditPath lastPath = LightResult::EditPath::None;
    double lastMs = 0.0, lastRecombineMs = 0.0, lastProjectMs = 0.0;
};

// What the panel shows besides the ViewState it edits.
struct PanelInputs {
    const ViewerSetup& setup;
    const ViewLimits& limits;
    const std::vector<std::string>& environmentNames;  // shown in the environment list
    ScatteringComponents available;      // what the file holds (the other boxes are disabled)
    int viewTerms = 0;                   // K of the file's view maps
    const LightResult* light = nullptr;  // the relight on screen; null before the first
    double uploadMs = 0.0;               // the last upload's time
    const RunningStats& relights;        // completed relights, total times (ms)
    double relightRate = 0.0;            // relights completed per second, last half second
    bool relighting = false;             // a relight queued or running
    double fps = 0.0, frameMs = 0.0;
    const std::string& renderer;                  // GL_RENDERER
    const PointLightResult* pointLight = nullptr;  // the point-light update on screen; null before the first
    const RunningStats& pointUpdates;             // point-light updates with lights (ms)
    const MaterialEditStats& edits;               // editable files
    const std::string& status;                    // the last screenshot's outcome
    const std::string& sunSplit;                  // the sun split's line (--sun-split; empty without)
    std::function<std::string()> renderCommand;   // the prt-relight render command of the view
};

// The point lights' comparison with Jensen-Buhler ("RMSE vs Jensen-Buhler").
struct PointLightComparison {
    bool running = false;
    std::string text;  // its result, or what is being done
};

// Draws the panel (the ImGui window "prt-relight view"; its close button hides it).
// pointWorker: null when the transport file names no material (no point lights); the
// comparison button queues a comparison on it and marks `comparison` running.
void drawPanel(const PanelInputs& in, ViewState& state, PointLightWorker* pointWorker,
               PointLightComparison& comparison);

// Why `material` at `sizeMm` cannot be the object's (what EditableTransport::setMaterial
// would throw: a size that is not finite and > 0, an invalid material, a channel
// outside the basis's range), in one line; empty when it can. Reads only the basis, so
// it may run while the relight worker edits the object. eta is taken as the file's.
std::string materialProblem(const EditableTransport& editable, const Material& material, double sizeMm);

// The one way an edit reaches the ViewState (the panel's widgets and the scripted edit,
// view.h ScriptedEdit): `material` (eta taken as the file's) at `sizeMm` becomes the
// state's and materialError is cleared when materialProblem finds nothing; otherwise
// materialError says why and the state keeps its material. Returns whether it was
// applied. The relight worker picks the change up with the next request.
bool editMaterial(const EditableTransport& editable, ViewState& state, const Material& material, double sizeMm);

// The sizes (mm) at which the basis covers every channel of `material` (its z_r scales
// as 1 / size; alpha' does not change with the size): {lo, hi}, lo > hi when none.
std::pair<double, double> coveredSizesMm(const EditableTransport& editable, const Material& material);

// `material` as --material text for prt-relight render: empty for the file's own
// material, the name of a measured material whose coefficients it has, else the
// sigma:SA_R,SA_G,SA_B:SS_R,SS_G,SS_B form (%.9g).
std::string materialArgument(const EditableTransport& editable, const Material& material);

// The point lights as numbered dots in their colour where the camera sees their
// positions (ImGui's background draw list), when `shown`.
void drawLightMarkers(const ViewState& state, bool shown);

}  // namespace prt
