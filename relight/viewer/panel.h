#pragma once
// The viewer's Dear ImGui panel (prt-relight view; docs/viewer.md, "Controls"): the
// settings of the ViewState as widgets (environment, rotation, components, specular,
// exposure, light terms, the point lights and their sampling), what the relights cost,
// the camera with its prt-relight render command, and the point lights as markers over
// the image.
//
// Contract: call between ViewerWindow::beginImGuiFrame and renderImGui, on the window's
// thread. The panel edits `state` only through its widgets and buttons; everything
// else it is given it only reads.

#include <functional>
#include <string>
#include <vector>

#include "common/transport_params.h"
#include "relight/viewer/point_light_worker.h"
#include "relight/viewer/relight_worker.h"
#include "relight/viewer/view.h"
#include "relight/viewer/view_state.h"

namespace prt {

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
    const std::string& status;                    // the last screenshot's outcome
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

// The point lights as numbered dots in their colour where the camera sees their
// positions (ImGui's background draw list), when `shown`.
void drawLightMarkers(const ViewState& state, bool shown);

}  // namespace prt
