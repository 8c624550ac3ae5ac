// prt-relight view: see view.h and docs/viewer.md.
//
// One frame: events and input change the ViewState (window.h); the scripted motion
// takes its step and, at its frame, the scripted edit is made; a light the state asks
// for and the workers do not have yet is submitted, and finished results are taken and
// uploaded (environment + point lights, summed per vertex); the scene is drawn (scene_gl.h) with the light of the result on
// screen, so the background, the specular layer and the object never mix two lights;
// then screenshots, the panel (panel.h) and the swap.

#include "relight/viewer/view.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <exception>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "common/envmap.h"
#include "common/error.h"
#include "common/image.h"
#include "common/material_edit.h"
#include "common/transport_params.h"
#include "common/util.h"
#include "relight/viewer/gl_util.h"
#include "relight/viewer/panel.h"
#include "relight/viewer/point_light_worker.h"
#include "relight/viewer/relight_worker.h"
#include "relight/viewer/scene_gl.h"
#include "relight/viewer/sun_split_worker.h"
#include "relight/viewer/view_state.h"
#include "relight/viewer/window.h"

#ifndef PRT_SOURCE_DIR
#define PRT_SOURCE_DIR "."
#endif

namespace prt {

namespace fs = std::filesystem;

namespace {

std::string lowerExtension(const fs::path& p) { return toLower(p.extension().string()); }

// Frame times (still light or a relight in flight) and the rates the panel shows,
// over windows of half a second.
class FrameClock {
public:
    // After a frame was shown; `relights`: relights completed so far.
    void frameShown(bool lightShown, bool busy, size_t relights) {
        const double ms = frame_.milliseconds();
        frame_.restart();
        if (lightShown) (busy ? busyFrames : stillFrames).add(ms);
        ++windowFrames_;
        const double t = session_.seconds();
        if (t - windowStart_ >= 0.5) {
            fps = windowFrames_ / (t - windowStart_);
            frameMs = 1000.0 * (t - windowStart_) / windowFrames_;
            relightRate = double(relights - windowRelights_) / (t - windowStart_);
            windowRelights_ = relights;
            windowStart_ = t;
            windowFrames_ = 0;
        }
    }
    double seconds() const { return session_.seconds(); }

    // Over the last window: frames per second, ms per frame, relights completed per second.
    double fps = 0.0, frameMs = 0.0, relightRate = 0.0;
    RunningStats stillFrames, busyFrames;  // frames with light on screen, ms

private:
    Stopwatch session_, frame_;
    double windowStart_ = 0.0;
    int windowFrames_ = 0;
    size_t windowRelights_ = 0;
};

class Viewer {
public:
    explicit Viewer(ViewerSetup setup) : s_(std::move(setup)) {}
    ~Viewer();
    int run();

private:
    void start();
    void loadEnvironments();
    // Events, a resize, ImGui's frame and the input; false while minimised.
    bool beginFrame(int& fbWidth, int& fbHeight);
    // Submits the lights the state asks for, takes what the workers finished and
    // uploads it; returns whether a result landed.
    bool exchangeLight();
    // Uploads the environment's per-vertex radiance (if on) plus the point lights' (if
    // on) and makes it the one drawn.
    void uploadCombined();
    // Draws the scene, the screenshots and the panel; lastFrame: the scripted end.
    void drawFrame(int fbWidth, int fbHeight, bool lastFrame);
    SceneFrame sceneFrame() const;
    void writeKeyScreenshot();
    std::string renderCommand() const;
    LightRequest currentRequest() const;
    SunSplitRequest currentSunRequest() const;
    // The sun split's correction is for the relight on screen (its light).
    bool sunMatchesFront() const;
    std::string sunSplitLine() const;
    PointLightRequest currentPointRequest() const;
    void printSummary(double seconds) const;
    // The scripted edit, once its frame has come: through the panel's edit (editMaterial),
    // so the next exchangeLight submits it as it would a panel edit.
    void applyScriptedEdit();

    ViewerSetup s_;
    ViewLimits limits_;
    ScatteringComponents available_;  // what the file holds
    int fileTerms_ = 0;               // K of the file's view maps
    std::vector<Image> environments_;
    std::vector<std::string> environmentNames_;
    ViewState state_;
    ScriptedMotion script_{0, 0.0, 0.0};

    // The environment's light: on screen (the last result uploaded) and asked for.
    std::unique_ptr<RelightWorker> worker_;
    LightResult front_;
    bool haveLight_ = false;
    LightRequest displayed_, submitted_;
    uint64_t nextId_ = 1;
    int displayedTerms_ = 0;
    EyePathTable eyePath_;  // --ss-path's factor for the object's eta
    double lastUploadMs_ = 0.0;
    RunningStats relightStats_, lightStats_, kernelStats_, uploadStats_;
    MaterialEditStats editStats_;
    size_t recombinedEdits_ = 0, projectedEdits_ = 0;
    bool scriptedEditDone_ = false;

    // The point lights (texture-space importance sampling).
    std::unique_ptr<PointLightWorker> pointWorker_;
    PointLightResult pointFront_;
    bool havePoint_ = false;
    PointLightRequest pointSubmitted_, pointDisplayed_;
    uint64_t nextPointId_ = 1;
    PointLightComparison comparison_;
    RunningStats pointStats_;
    Stopwatch lastDrawn_;  // since the last frame drawn
    size_t backgroundRecombines_ = 0;  // the relight worker's, read before it stops
    static constexpr double kIdleRedrawMs = 250.0;
    // Point-light updates that were a material change alone (the lights standing still):
    // the worker's time (setMaterial and the per-vertex sums) plus the upload after it,
    // what the change costs before the frame that shows it.
    RunningStats pointEditStats_, pointEditMaterialStats_, pointEditSumsStats_;
    bool uploadDirty_ = false, uploadedEnvOn_ = true, uploadedPointOn_ = true;
    uint64_t uploadedSpecularId_ = 0;  // the point-light result whose specular is uploaded (0: none)
    std::vector<glm::vec4> combined_;

    // The sun split (--sun-split): the correction at the vertices, added to the relight
    // on screen when made for its light.
    std::unique_ptr<SunSplitWorker> sunWorker_;
    SunSplitResult sunFront_;
    bool haveSun_ = false, sunShown_ = false;
    SunSplitRequest sunSubmitted_;
    uint64_t nextSunId_ = 1;
    RunningStats sunStats_;

    // The window first: the scene's GL objects go before its context.
    std::unique_ptr<ViewerWindow> window_;
    std::unique_ptr<SceneGl> scene_;
    int screenshotCounter_ = 0;
    std::string status_;
    FrameClock clock_;
};

Viewer::~Viewer() {
    sunWorker_.reset();
    worker_.reset();
    pointWorker_.reset();
    if (window_) window_->makeCurrent();
    scene_.reset();
    window_.reset();
}

void Viewer::loadEnvironments() {
    const Stopwatch clock;
    environments_.resize(s_.environments.size());
    // OpenImageIO reads are thread-safe; the maps are independent.
    tbb::parallel_for(size_t(0), s_.environments.size(), [&](size_t i) {
        environments_[i] = loadEnvironment(s_.environments[i], NonFinitePolicy::ClampNegative);
    });
    for (const std::string& p : s_.environments) environmentNames_.push_back(fs::path(p).stem().string());
    std::printf("environments: %zu loaded in %.0f ms (", environments_.size(), clock.milliseconds());
    for (size_t i = 0; i < environments_.size(); ++i)
        std::printf("%s%s %dx%d", i ? ", " : "", environmentNames_[i].c_str(), environments_[i].width,
                    environments_[i].height);
    std::printf(")\n");
    std::fflush(stdout);
}

void Viewer::start() {
    const TransportFile& file = s_.object.transport;
    available_.multipleScattering = file.find(ComponentKind::MultipleScattering) != nullptr;
    available_.singleScattering = file.find(ComponentKind::SingleScatteringIsotropic) != nullptr;
    for (const TransportComponent& c : file.components)
        available_.singleScattering = available_.singleScattering || c.kind == ComponentKind::SingleScatteringTerm;
    fileTerms_ = file.viewMaps ? file.viewMaps->terms : 0;
    eyePath_ = EyePathTable(s_.object.eta, parseSingleScatteringView(s_.frame.ssPath));
    limits_.environments = int(s_.environments.size());
    limits_.maxLightTerms = 6 * int(file.cubemapSize * file.cubemapSize);
    limits_.home = s_.camera;
    limits_.objectRadius = s_.object.sphereRadius;

    state_.camera = s_.camera;
    state_.rotation = wrapDegrees(s_.frame.envRotation);
    state_.exposure = float(s_.frame.display.exposureStops);
    state_.toneMap = int(s_.frame.display.op);
    state_.lightTerms = int(std::min<size_t>(s_.frame.lightTerms, size_t(6) * file.cubemapSize * file.cubemapSize));
    state_.multipleScattering = s_.components.multipleScattering;
    state_.singleScattering = s_.components.singleScattering;
    if (componentsOf(file).folded) {
        // No toggle of its own: the multiple-scattering vectors carry it.
        std::printf("single scattering: folded into the multiple-scattering vectors (prt-precompute --fold-ss); "
                    "the ms toggle shows both\n");
        std::fflush(stdout);
    }
    state_.specular = s_.frame.specular;
    state_.showPanel = s_.showPanel;
    script_ = ScriptedMotion(s_.frames, s_.spinDegreesPerFrame, s_.orbitDegreesPerFrame,
                             s_.lightOrbitDegreesPerFrame, glm::dvec3(bounds(s_.object.mesh).centre()));

    loadEnvironments();
    // Before the window, so its refusals (grounds, material maps, no material) come first,
    // and before the relight worker, which edits an editable object (the split copies
    // what it needs here).
    if (s_.sunSplit) {
        sunWorker_ = std::make_unique<SunSplitWorker>(s_.object, environments_, *s_.sunSplit, s_.transportPath,
                                                      state_.environment);
        std::printf("sun split: the brightest texels (above %g x the mean luminance, cells of %g degrees) as "
                    "directional lights at the vertices, shown once they land for the light on screen\n",
                    s_.sunSplit->threshold, s_.sunSplit->cellDegrees);
        std::fflush(stdout);
    }
    window_ = std::make_unique<ViewerWindow>(s_.camera.width, s_.camera.height,
                                             "prt-relight view - " + fs::path(s_.meshPath).filename().string(),
                                             s_.vsync);
    scene_ = std::make_unique<SceneGl>(s_.object, environments_, s_.frame.specularBlur, s_.camera.width,
                                       s_.camera.height, s_.subpixels);
    if (s_.object.editable) {
        state_.material = s_.object.editable->material();
        state_.sizeMm = s_.object.editable->sizeMm();
    }
    // From here on the worker owns the object's transport components and its editable
    // transport (relight_worker.h): this thread reads only what no edit changes.
    worker_ = std::make_unique<RelightWorker>(s_.object, environments_);
    state_.environmentLight = s_.environmentLight;
    state_.lights = s_.pointLights;
    state_.splitMode = int(s_.tsis.mode);
    state_.pointSamples = s_.tsis.samples;
    state_.pointSpecular = s_.pointSpecular;
    state_.pointSpecularRoughness = float(s_.pointSpecularRoughness);
    state_.pointSingleScattering = s_.pointSingleScattering;
    if (s_.material)
        pointWorker_ = std::make_unique<PointLightWorker>(s_.object.mesh, *s_.material, s_.tsis, s_.atlasSize);
}

bool Viewer::beginFrame(int& fbWidth, int& fbHeight) {
    if (const auto resized = window_->pollEvents()) {
        const auto [width, height] = *resized;
        if (width > 0 && height > 0 && (width != state_.camera.width || height != state_.camera.height)) {
            state_.camera.width = width;
            state_.camera.height = height;
            scene_->resize(width, height);
        }
    }
    std::tie(fbWidth, fbHeight) = window_->framebufferSize();
    if (fbWidth <= 0 || fbHeight <= 0) {  // minimised
        window_->waitEvents(0.1);
        return false;
    }
    window_->beginImGuiFrame();
    window_->applyInput(state_, limits_);
    return true;
}

LightRequest Viewer::currentRequest() const {
    LightRequest r;
    r.environment = state_.environment;
    r.rotation = state_.rotation;
    r.lightTerms = size_t(std::max(state_.lightTerms, 0));
    r.multipleScattering = state_.multipleScattering && available_.multipleScattering;
    r.singleScattering = state_.singleScattering && available_.singleScattering;
    if (s_.object.editable) {
        r.material = state_.material;
        r.sizeMm = state_.sizeMm;
    }
    return r;
}

SunSplitRequest Viewer::currentSunRequest() const {
    const LightRequest l = currentRequest();
    SunSplitRequest r;
    r.environment = l.environment;
    r.rotation = l.rotation;
    r.lightTerms = l.lightTerms;
    r.multipleScattering = l.multipleScattering;
    r.singleScattering = l.singleScattering;
    r.eye = state_.camera.eye;
    r.material = l.material;
    r.sizeMm = l.sizeMm;
    return r;
}

bool Viewer::sunMatchesFront() const {
    const LightRequest& l = front_.request;
    return haveSun_ && haveLight_ &&
           sunFront_.request.sameLight(l.environment, l.rotation, l.lightTerms, l.multipleScattering,
                                       l.singleScattering) &&
           // An editable file's: the material the relight shows (the previous one when it refused an edit).
           sunFront_.request.sameMaterial(front_.material, front_.sizeMm) &&
           sunFront_.correction.diffuse.size() == s_.object.mesh.vertexCount();
}

std::string Viewer::sunSplitLine() const {
    if (!sunWorker_) return "";
    char line[256];
    if (!haveSun_) return "sun split: splitting ...";
    if (!sunFront_.materialError.empty()) return "sun split: not for this material: " + sunFront_.materialError;
    std::snprintf(line, sizeof line, "sun split: %zu lights carry %.1f%% of the light; %s (last update %.0f ms)",
                  sunFront_.lights, 100.0 * sunFront_.lightFraction,
                  sunShown_ ? "shown" : "refining (the plain relight meanwhile)", sunFront_.totalMs);
    return line;
}

PointLightRequest Viewer::currentPointRequest() const {
    PointLightRequest r;
    if (state_.pointLights) r.lights = state_.lights;
    r.mode = TextureSpaceMode(state_.splitMode);
    r.samples = state_.pointSamples;
    r.seed = s_.tsis.seed;
    r.specular = state_.pointSpecular;
    r.singleScattering = state_.pointSingleScattering;
    r.singleScatteringSamples = s_.pointSingleScatteringSamples;
    r.eye = state_.camera.eye;
    // A size edit is a material edit at the file's geometry (material_edit.h), as the
    // relight worker applies it.
    if (s_.object.editable)
        r.material = scaledMaterial(state_.material, state_.sizeMm / s_.object.editable->objectSizeMm());
    return r;
}

bool Viewer::exchangeLight() {
    const LightRequest wanted = currentRequest();
    if (nextId_ == 1 || !wanted.sameLight(submitted_) || !wanted.sameMaterial(submitted_)) {
        submitted_ = wanted;
        submitted_.id = nextId_++;
        worker_->submit(submitted_);
    }
    const bool envLanded = worker_->take(front_);
    bool pointLanded = false, pointEdit = false;
    if (envLanded) {
        displayed_ = front_.request;
        haveLight_ = true;
        uploadDirty_ = true;
    }
    bool sunLanded = false;
    if (sunWorker_) {
        const SunSplitRequest sw = currentSunRequest();
        if (nextSunId_ == 1 || !sw.sameAs(sunSubmitted_)) {
            sunSubmitted_ = sw;
            sunSubmitted_.id = nextSunId_++;
            sunWorker_->submit(sunSubmitted_);
        }
        if (sunWorker_->take(sunFront_)) {
            haveSun_ = true;
            sunLanded = true;
            uploadDirty_ = true;
            sunStats_.add(sunFront_.totalMs);
        }
    }
    if (pointWorker_) {
        const PointLightRequest pw = currentPointRequest();
        if (nextPointId_ == 1 || !pw.sameAs(pointSubmitted_)) {
            pointSubmitted_ = pw;
            pointSubmitted_.id = nextPointId_++;
            pointWorker_->submit(pointSubmitted_);
        }
        if (pointWorker_->take(pointFront_)) {
            pointLanded = true;
            pointDisplayed_ = pointFront_.request;
            havePoint_ = true;
            uploadDirty_ = true;
            if (!pointFront_.request.lights.empty()) pointStats_.add(pointFront_.totalMs);
            pointEdit = pointFront_.materialChanged && !pointFront_.lightsRecomputed;
        }
        std::string text;
        if (pointWorker_->takeComparison(text)) {
            comparison_.text = text;
            comparison_.running = false;
        }
    }
    if (state_.environmentLight != uploadedEnvOn_ || state_.pointLights != uploadedPointOn_) uploadDirty_ = true;
    if (uploadDirty_ && (haveLight_ || havePoint_)) {
        uploadCombined();
        uploadDirty_ = false;
        uploadedEnvOn_ = state_.environmentLight;
        uploadedPointOn_ = state_.pointLights;
    }
    if (pointEdit) {  // after the upload, which it includes
        pointEditStats_.add(pointFront_.totalMs + lastUploadMs_);
        pointEditMaterialStats_.add(pointFront_.materialMs);
        pointEditSumsStats_.add(pointFront_.evaluationMs);
    }
    if (envLanded) {
        relightStats_.add(front_.lightMs + front_.relightMs + lastUploadMs_);
        lightStats_.add(front_.lightMs);
        kernelStats_.add(front_.relightMs);
        uploadStats_.add(lastUploadMs_);
        if (front_.editPath != LightResult::EditPath::None) {
            editStats_.edits.add(front_.editMs);
            editStats_.lastPath = front_.editPath;
            editStats_.lastMs = front_.editMs;
            editStats_.lastRecombineMs = front_.recombineMs;
            editStats_.lastProjectMs = front_.projectMs;
            ++(front_.editPath == LightResult::EditPath::Projected ? projectedEdits_ : recombinedEdits_);
        }
    }
    return envLanded || pointLanded || sunLanded;
}

void Viewer::uploadCombined() {
    const Stopwatch clock;
    const size_t V = s_.object.mesh.vertexCount();
    const bool env = state_.environmentLight && haveLight_;
    const bool point = state_.pointLights && havePoint_ && pointFront_.radiance.size() == V;
    const int envSlots = haveLight_ ? std::min(1 + fileTerms_, int(front_.packed.size() / std::max<size_t>(V, 1))) : 1;
    const int slots = std::max(envSlots, 1);
    combined_.assign(size_t(slots) * V, glm::vec4(0.0f));
    if (env) std::copy(front_.packed.begin(), front_.packed.begin() + ptrdiff_t(size_t(slots) * V), combined_.begin());
    // The split's correction only with the relight it was made for: the screen shows the
    // plain relight or the split, never one rotation's relight with another's lights.
    sunShown_ = env && sunMatchesFront();
    if (sunShown_) {
        const VertexRadiance& c = sunFront_.correction;
        for (size_t v = 0; v < V; ++v) combined_[v] += glm::vec4(c.diffuse[v], 0.0f);
        for (size_t k = 0; k + 1 < size_t(slots) && k < c.terms.size(); ++k)
            if (c.terms[k].size() == V)
                for (size_t v = 0; v < V; ++v) combined_[(k + 1) * V + v] += glm::vec4(c.terms[k][v], 0.0f);
    }
    if (point)
        for (size_t v = 0; v < V; ++v) combined_[v] += glm::vec4(pointFront_.radiance[v], 0.0f);
    scene_->uploadRadiance(combined_, slots, env ? front_.ground : std::vector<glm::vec3>());
    // The specular's lights with the radiance they go with (the screen never mixes two),
    // uploaded once per point-light result.
    const uint64_t specularId = point && !pointFront_.lightIrradiance.empty() ? pointFront_.request.id : 0;
    if (specularId != uploadedSpecularId_) {
        uploadedSpecularId_ = specularId;
        try {
            if (specularId)
                scene_->uploadPointSpecular(pointFront_.request.lights, pointFront_.lightIrradiance);
            else
                scene_->uploadPointSpecular({}, {});
        } catch (const Error& e) {  // more lights than this OpenGL's textures hold: the specular goes off
            scene_->uploadPointSpecular({}, {});
            state_.pointSpecular = false;
            status_ = std::string("point-light specular off: ") + e.what();
            warn(status_);
        }
    }
    displayedTerms_ = env ? std::max(slots - 1, 0) : 0;
    lastUploadMs_ = clock.milliseconds();
    checkGl("uploading relit radiance");
}

SceneFrame Viewer::sceneFrame() const {
    SceneFrame f;
    f.camera = state_.camera;
    f.environment = haveLight_ ? displayed_.environment : state_.environment;
    f.rotation = haveLight_ ? displayed_.rotation : state_.rotation;
    f.display = {double(state_.exposure), ToneMapOperator(state_.toneMap)};
    f.viewTerms = haveLight_ ? displayedTerms_ : 0;
    f.eyePath = eyePath_;
    f.specular = state_.specular;
    f.environmentLight = state_.environmentLight;
    f.pointSpecular = state_.pointLights && havePoint_ && pointFront_.request.specular;
    f.pointSpecularRoughness = state_.pointSpecularRoughness;
    f.pointEta = pointFront_.material.eta;
    return f;
}

void Viewer::drawFrame(int fbWidth, int fbHeight, bool lastFrame) {
    const bool keyShot = state_.screenshotRequested;
    state_.screenshotRequested = false;
    const bool direct = fbWidth == state_.camera.width && fbHeight == state_.camera.height;
    const bool offscreen = !direct || keyShot || (lastFrame && !s_.screenshots.empty());
    scene_->draw(sceneFrame(), offscreen);
    if (offscreen) scene_->blitToWindow(fbWidth, fbHeight);
    if (keyShot) writeKeyScreenshot();
    if (lastFrame)
        for (const std::string& path : s_.screenshots)
            if (!s_.screenshotWithPanel || lowerExtension(path) == ".exr") {
                scene_->writeScreenshot(path);
                std::printf("screenshot: %s\n", path.c_str());
            }

    glViewport(0, 0, fbWidth, fbHeight);
    if (state_.showPanel) {
        drawLightMarkers(state_, pointWorker_ && state_.pointLights);
        const PanelInputs in{.setup = s_,
                             .limits = limits_,
                             .environmentNames = environmentNames_,
                             .available = available_,
                             .viewTerms = fileTerms_,
                             .light = haveLight_ ? &front_ : nullptr,
                             .uploadMs = lastUploadMs_,
                             .relights = relightStats_,
                             .relightRate = clock_.relightRate,
                             .relighting = worker_->busy(),
                             .fps = clock_.fps,
                             .frameMs = clock_.frameMs,
                             .renderer = window_->glRenderer(),
                             .pointLight = havePoint_ ? &pointFront_ : nullptr,
                             .pointUpdates = pointStats_,
                             .edits = editStats_,
                             .status = status_,
                             .sunSplit = sunSplitLine(),
                             .renderCommand = [this] { return renderCommand(); }};
        drawPanel(in, state_, pointWorker_.get(), comparison_);
    }
    window_->renderImGui();

    if (lastFrame) {
        for (const std::string& path : s_.screenshots)
            if (s_.screenshotWithPanel && lowerExtension(path) != ".exr") {
                scene_->writeWindowScreenshot(path, fbWidth, fbHeight);
                std::printf("screenshot: %s (with the panel)\n", path.c_str());
            }
        // What reproduces the screenshots offline (the state the script ended in).
        std::printf("render command: %s\n", renderCommand().c_str());
        std::fflush(stdout);
    }
}

std::string Viewer::renderCommand() const {
    const Camera& c = state_.camera;
    const auto vec = [](const glm::dvec3& v) {
        char buf[128];
        std::snprintf(buf, sizeof buf, "%.9g,%.9g,%.9g", v.x, v.y, v.z);
        return std::string(buf);
    };
    char buf[128];
    std::string cmd = "prt-relight render " + shellQuote(s_.meshPath) + " -t " + shellQuote(s_.transportPath) +
                      " -e " + shellQuote(s_.environments[size_t(state_.environment)]) + " --eye=" + vec(c.eye) +
                      " --target=" + vec(c.target) + " --up=" + vec(c.up);
    std::snprintf(buf, sizeof buf, " --fov %.9g -W %d -H %d", c.fovY, c.width, c.height);
    cmd += buf;
    if (s_.subpixels > 1) cmd += " --spp " + std::to_string(s_.subpixels * s_.subpixels);
    FrameSettings frame;
    frame.envRotation = state_.rotation;
    frame.display = {double(state_.exposure), ToneMapOperator(state_.toneMap)};
    frame.baseColour = s_.frame.baseColour;
    frame.ground = s_.frame.ground;
    frame.materialMap = s_.frame.materialMap;
    frame.mapMaterial = s_.frame.mapMaterial;
    frame.lightTerms = size_t(std::max(state_.lightTerms, 0));
    const LightRequest r = currentRequest();
    if (s_.sunSplit) {
        char sun[96];
        std::snprintf(sun, sizeof sun, " --sun-split --sun-threshold %.9g --sun-cell %.9g", s_.sunSplit->threshold,
                      s_.sunSplit->cellDegrees);
        cmd += sun;
    }
    if (r.multipleScattering != available_.multipleScattering || r.singleScattering != available_.singleScattering)
        frame.components = r.multipleScattering && r.singleScattering ? "ms,ss"
                           : r.multipleScattering                      ? "ms"
                                                                       : "ss";
    frame.specular = state_.specular;
    frame.specularBlur = s_.frame.specularBlur;
    if (s_.object.editable) {
        const EditableTransport& e = *s_.object.editable;  // only what no edit changes
        frame.material = materialArgument(e, state_.material);
        if (state_.sizeMm != e.objectSizeMm()) frame.sizeMm = state_.sizeMm;
    }
    return cmd + renderArguments(frame) + " -o OUT";
}

void Viewer::writeKeyScreenshot() {
    std::string base;
    do {
        char buf[64];
        std::snprintf(buf, sizeof buf, "prt-view-%03d", screenshotCounter_++);
        base = buf;
    } while (fs::exists(base + ".png") || fs::exists(base + ".exr"));
    try {
        scene_->writeScreenshot(base + ".png");
        scene_->writeScreenshot(base + ".exr");
        status_ = "wrote " + base + ".png and .exr";
        std::printf("screenshot: %s.png/.exr; same view offline:\n  %s\n", base.c_str(), renderCommand().c_str());
        std::fflush(stdout);
    } catch (const std::exception& e) {
        status_ = std::string("screenshot failed: ") + e.what();
        warn(status_);
    }
}

void Viewer::printSummary(double seconds) const {
    const RunningStats &still = clock_.stillFrames, &busy = clock_.busyFrames;
    const size_t frames = still.count + busy.count;
    std::printf("viewer: %zu frames in %.2f s at %d x %d", frames, seconds, state_.camera.width,
                state_.camera.height);
    if (still.count)
        std::printf("; still light: %zu frames, %.1f fps (%.2f ms per frame)", still.count, 1000.0 / still.mean(),
                    still.mean());
    if (busy.count) std::printf("; while relighting: %zu frames, %.1f fps", busy.count, 1000.0 / busy.mean());
    std::printf("\n");
    if (relightStats_.count)
        std::printf("relights: %zu completed (%.1f per second), mean %.1f ms (light vector %.1f + kernel %.1f + "
                    "upload %.1f), min %.1f, max %.1f ms\n",
                    relightStats_.count, seconds > 0.0 ? double(relightStats_.count) / seconds : 0.0,
                    relightStats_.mean(), lightStats_.mean(), kernelStats_.mean(), uploadStats_.mean(),
                    relightStats_.min, relightStats_.max);
    if (editStats_.edits.count)
        std::printf("material edits: %zu (%zu recombined, %zu projected), %zu recombinations while idle, mean %.1f ms, "
                    "min %.1f, max %.1f ms\n",
                    editStats_.edits.count, recombinedEdits_, projectedEdits_, backgroundRecombines_,
                    editStats_.edits.mean(), editStats_.edits.min, editStats_.edits.max);
    if (pointStats_.count)
        std::printf("point-light updates: %zu, mean %.1f ms (irradiance map, shadow maps, draws and per-vertex sums; "
                    "last: %.1f ms, N = %d, %s), min %.1f, max %.1f ms\n",
                    pointStats_.count, pointStats_.mean(), pointFront_.totalMs, pointFront_.request.samples,
                    toString(pointFront_.request.mode), pointStats_.min, pointStats_.max);
    if (sunStats_.count)
        std::printf("sun split: %zu lights carry %.1f%% of the light; %zu updates, mean %.1f ms (last: light vector "
                    "%.1f + relight %.1f of the excess, pass 1 %.1f, Jensen-Buhler at the vertices %.1f, single "
                    "scattering %.1f ms), min %.1f, max %.1f ms; the last frame %s\n",
                    sunFront_.lights, 100.0 * sunFront_.lightFraction, sunStats_.count, sunStats_.mean(),
                    sunFront_.times.lightVector, sunFront_.times.transport, sunFront_.times.lightsIrradiance,
                    sunFront_.times.lightsDiffusion, sunFront_.times.lightsSingleScattering, sunStats_.min,
                    sunStats_.max, sunShown_ ? "showed the split" : "showed the plain relight");
    if (pointEditStats_.count)
        std::printf("point-light material changes: %zu, mean %.1f ms before the frame (setMaterial %.1f + "
                    "per-vertex sums %.1f, the rest the worker's other steps and the upload), min %.1f, max %.1f ms\n",
                    pointEditStats_.count, pointEditStats_.mean(), pointEditMaterialStats_.mean(),
                    pointEditSumsStats_.mean(), pointEditStats_.min, pointEditStats_.max);
    const PointLightRequest& shown = pointFront_.request;
    if (pointStats_.count && (shown.specular || shown.singleScattering))
        std::printf("point-light surface terms (rays at the vertices): specular %s (GGX alpha %.3g), single "
                    "scattering %s (%d samples, seen from the eye of the last update); last update's rays: "
                    "specular %.1f ms, single scattering %.1f ms (0: kept)\n",
                    shown.specular ? "on" : "off", double(state_.pointSpecularRoughness),
                    shown.singleScattering ? "on" : "off", shown.singleScatteringSamples,
                    pointFront_.specularMs, pointFront_.singleScatteringMs);
    std::fflush(stdout);
}

void Viewer::applyScriptedEdit() {
    if (!s_.edit || scriptedEditDone_ || script_.framesWithLight() < s_.edit->afterFrames) return;
    scriptedEditDone_ = true;
    // makeScriptedEdit checked it against the basis, so a refusal here is a bug, not input.
    if (!editMaterial(*s_.object.editable, state_, s_.edit->material, s_.edit->sizeMm))
        throw Error("--edit-material", state_.materialError);
    std::printf("scripted edit: after frame %d, %s at %s mm\n", s_.edit->afterFrames,
                describeMaterial(state_.material).c_str(), formatParameter(state_.sizeMm).c_str());
    std::fflush(stdout);
}

int Viewer::run() {
    start();
    clock_ = FrameClock();
    bool screenshotsDone = false;
    while (!window_->shouldClose()) {
        int fbWidth = 0, fbHeight = 0;
        if (!beginFrame(fbWidth, fbHeight)) continue;
        const bool input = window_->takeInputSeen();
        script_.step(state_, haveLight_);
        applyScriptedEdit();
        const bool landed = exchangeLight();
        const bool pointBusy = pointWorker_ && !comparison_.running && pointWorker_->busy();
        const bool busy = worker_->busy() || pointBusy || (sunWorker_ && sunWorker_->busy());
        // The scripted end: the frames are done and the light on screen is the last asked for.
        // The scripted edit goes out before the frames are done (K < frames), so waiting
        // for the last request's result waits for the edit's.
        const bool lastFrame = script_.finishing() && !busy && displayed_.id == submitted_.id &&
                               (!pointWorker_ || (havePoint_ && pointDisplayed_.id == pointSubmitted_.id)) &&
                               (!sunWorker_ || (haveSun_ && sunFront_.request.id == sunSubmitted_.id &&
                                                (sunShown_ || !state_.environmentLight ||
                                                 !sunFront_.materialError.empty())));
        if (lastFrame && s_.edit && !front_.materialError.empty())
            throw Error("--edit-material", "the relight refused the edit: " + front_.materialError);
        // While a worker computes and nothing on screen would change (no input, no
        // result, no scripted motion), the frame would be the last one again: skip it and
        // wait for input, so that a software rasteriser does not take the workers' cores.
        // The panel is still redrawn every kIdleRedrawMs.
        if (busy && !input && !landed && !lastFrame && !script_.moving() &&
            lastDrawn_.milliseconds() < kIdleRedrawMs) {
            window_->skipImGuiFrame();
            window_->waitEvents(0.002);
            continue;
        }
        lastDrawn_.restart();
        drawFrame(fbWidth, fbHeight, lastFrame);
        if (lastFrame) {
            screenshotsDone = true;
            window_->close();
        }
        window_->swapBuffers();
        script_.frameShown(haveLight_);
        clock_.frameShown(haveLight_, busy, relightStats_.count);
    }
    backgroundRecombines_ = worker_->backgroundRecombines();
    sunWorker_.reset();
    worker_.reset();
    pointWorker_.reset();
    printSummary(clock_.seconds());
    if (script_.scripted() && !screenshotsDone && !s_.screenshots.empty())
        throw Error("view", "the window was closed before the scripted frames were done; no screenshot written");
    return 0;
}

}  // namespace

// ---------------------------------------------------------------------------
// Entry points
// ---------------------------------------------------------------------------

std::vector<std::string> findEnvironments(const std::vector<std::string>& args) {
    std::vector<std::string> paths;
    const auto expand = [&](const fs::path& dir) {
        std::vector<std::string> found;
        for (const fs::directory_entry& e : fs::directory_iterator(dir)) {
            const std::string ext = lowerExtension(e.path());
            if (e.is_regular_file() && (ext == ".exr" || ext == ".hdr")) found.push_back(e.path().string());
        }
        std::sort(found.begin(), found.end());
        return found;
    };
    if (args.empty()) {
        for (const fs::path& dir : {fs::path("data/envmaps"), fs::path(PRT_SOURCE_DIR) / "data/envmaps"}) {
            std::error_code ec;
            if (!fs::is_directory(dir, ec)) continue;
            paths = expand(dir);
            if (!paths.empty()) return paths;
        }
        throw Error("--environment", "none given and no data/envmaps/ folder with .exr/.hdr maps found "
                                     "(run tools/fetch-data.sh, or pass -e FILE_OR_FOLDER)");
    }
    for (const std::string& a : args) {
        std::error_code ec;
        if (fs::is_directory(a, ec)) {
            const std::vector<std::string> found = expand(a);
            if (found.empty()) throw Error(a, "folder holds no .exr or .hdr file");
            paths.insert(paths.end(), found.begin(), found.end());
        } else if (fs::exists(a, ec)) {
            paths.push_back(a);
        } else {
            throw Error(a, "no such file or folder");
        }
    }
    return paths;
}

std::optional<ScriptedEdit> makeScriptedEdit(const RelightObject& object, int frames,
                                             const std::optional<int>& afterFrames,
                                             const std::optional<std::string>& materialText,
                                             const std::optional<double>& sizeMm,
                                             const std::string& transportPath) {
    if (!afterFrames && !materialText && !sizeMm) return std::nullopt;
    const std::string first = afterFrames ? "--edit-after" : materialText ? "--edit-material" : "--edit-size-mm";
    if (!object.editable)
        throw Error(first, transportPath + " is not editable (made without prt-precompute --editable)");
    if (!afterFrames) throw Error(first, "needs --edit-after K (the frame of the edit)");
    if (!materialText && !sizeMm) throw Error("--edit-after", "needs --edit-material and/or --edit-size-mm");
    if (frames <= 0) throw Error("--edit-after", "needs a scripted run, --frames N with N > K");
    if (*afterFrames < 1 || *afterFrames >= frames)
        throw Error("--edit-after", "must be >= 1 and < --frames (" + std::to_string(frames) + "), got " +
                                        std::to_string(*afterFrames));
    const EditableTransport& e = *object.editable;
    ScriptedEdit edit;
    edit.afterFrames = *afterFrames;
    edit.material = materialText ? parseMaterial(*materialText, e.fileMaterial().eta, e.fileMaterial().g,
                                                 "--edit-material")
                                 : e.material();
    edit.material.eta = e.fileMaterial().eta;
    edit.sizeMm = sizeMm ? *sizeMm : e.sizeMm();
    if (sizeMm && (!std::isfinite(*sizeMm) || !(*sizeMm > 0.0)))
        throw Error("--edit-size-mm", "must be finite and > 0 mm, got " + formatParameter(*sizeMm));
    const std::string problem = materialProblem(e, edit.material, edit.sizeMm);
    if (!problem.empty()) throw Error(materialText ? "--edit-material" : "--edit-size-mm", problem);
    return edit;
}

void checkViewerDisplay() { initDisplay(); }

int runViewer(ViewerSetup setup) {
    if (setup.environments.empty()) throw Error("view", "no environment");
    Viewer viewer(std::move(setup));
    return viewer.run();
}

}  // namespace prt
