// prt-relight: relighting of translucent objects from precomputed transport
// (docs/relight.md, docs/viewer.md). Subcommands:
//   render  headless frames (linear EXR + tone-mapped PNG), single, turntable or
//           environment spin;
//   view    the interactive viewer (relight/viewer/view.h), scriptable for tests;
//   info    what a transport file holds (header only, or --full: load and verify).
// render and view take the same camera options (addCameraOptions / makeCamera) and the
// same look (FrameSettings, bound once by addFrameOptions: --env-rotation, --components,
// -L, --specular, --specular-blur, --exposure, --tonemap), so a viewer screenshot and a render of
// the same arguments show the same image.

#include <CLI/CLI.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "common/camera.h"
#include "common/envmap.h"
#include "common/error.h"
#include "common/image.h"
#include "common/material_edit.h"
#include "common/options.h"
#include "common/progress.h"
#include "common/raytrace.h"
#include "common/transport_file.h"
#include "common/transport_params.h"
#include "common/util.h"
#include "relight/pointlight/point_lights.h"
#include "relight/pointlight/point_single_scattering.h"
#include "relight/pointlight/point_specular.h"
#include "relight/pointlight/surface_atlas.h"
#include "relight/pointlight/texture_space_sampling.h"
#include "relight/prt/environment_frame.h"
#include "relight/prt/eye_path.h"
#include "relight/prt/frame_settings.h"
#include "relight/prt/light_vector.h"
#include "relight/prt/relight_kernel.h"
#include "relight/prt/relight_object.h"
#include "relight/combined/sun_split_frame.h"
#include "relight/prt/translucent_shader.h"
#include "relight/render/gbuffer.h"
#include "relight/render/supersample.h"
#include "relight/render/specular.h"
#ifdef PRT_HAVE_VIEWER
#include "relight/viewer/view.h"  // the viewer's entry points: ViewerSetup, runViewer, ...
#endif

using namespace prt;

namespace {

struct RenderOptions {
    std::string mesh, transport, environment, output;
    CameraOptions camera;
    FrameSettings frame;
    int turntable = 0, envSpin = 0;
    int threads = 0;
    bool sunSplit = false;
    SunSplitOptions sun;
    std::string sunMethod = "jb";
};

// --sun-split and its settings, render's and view's; `method`: render's --sun-method
// (null: the option is not offered).
void addSunSplitOptions(CLI::App& app, bool& on, SunSplitOptions& options, std::string* method,
                        const char* what) {
    const char* sun = "Sun split (docs/relight.md, \"The sun split\")";
    auto* sunFlag = app.add_flag("--sun-split", on, what)->group(sun);
    app.add_option("--sun-threshold", options.threshold,
                   "k: texels brighter than k times the environment's mean luminance give the excess to the lights")
        ->capture_default_str()->group(sun)->needs(sunFlag);
    app.add_option("--sun-cell", options.cellDegrees, "Degrees: the excess of each cell this wide becomes one light")
        ->capture_default_str()->group(sun)->needs(sunFlag);
    if (method)
        app.add_option("--sun-method", *method,
                       "The lights' multiple scattering: jb (Jensen-Buhler), cache (the irradiance cache: faster) or "
                       "brute")
            ->capture_default_str()->group(sun)->needs(sunFlag);
}

void addRenderOptions(CLI::App& app, RenderOptions& o) {
    app.add_option("mesh", o.mesh, "Mesh file the transport file was computed for (.obj .ply .off .stl, .gz)")
        ->required();
    app.add_option("-t,--transport", o.transport, "Transport file (prt-precompute output)")->required();
    app.add_option("-e,--environment", o.environment, "Lat-long HDR environment (EXR, HDR, ...; width = 2 height)")
        ->required();
    app.add_option("-o,--output", o.output,
                   "Output prefix (a trailing .exr/.png is dropped): writes <prefix>.exr (linear RGBA float, A = 1 on the object) and "
                   "<prefix>.png (sRGB); sequences write <prefix>_0000.exr/.png, ...")
        ->required();
    addCameraOptions(app, o.camera);
    addSamplesPerPixelOption(app, o.camera);
    const FrameOptions frame = addFrameOptions(app, o.frame);
    frame.specularBlur->needs(frame.specular);
    auto* tt = app.add_option("--turntable", o.turntable,
                              "Render N frames of the object turning 360 degrees about the vertical "
                              "axis through its bounding-box centre (environment fixed in the world)")
                   ->group("Sequences");
    auto* spin = app.add_option("--env-spin", o.envSpin,
                                "Render N frames of the environment turning 360 degrees about +Y")
                     ->group("Sequences");
    tt->excludes(spin);
    addSunSplitOptions(app, o.sunSplit, o.sun, &o.sunMethod,
                       "Take the environment's brightest texels (sun, lamps) out as directional lights rendered by "
                       "Jensen-Buhler; the transport relights the rest");
    addThreadsOption(app, o.threads);
}

std::string frameName(const std::string& prefix, int frame, int frames) {
    if (frames <= 0) return prefix;
    char buf[16];
    std::snprintf(buf, sizeof buf, "_%04d", frame);
    return prefix + buf;
}

int runRender(const RenderOptions& o) {
    const FrameSettings& look = o.frame;
    const ThreadLimit limit(o.threads);
    if (o.turntable < 0 || o.envSpin < 0) throw Error("--turntable/--env-spin", "frame count must be >= 0");
    checkFrameSettings(look);
    const std::string output = outputPrefix(o.output);
    if (output.empty()) throw Error("--output", "empty prefix");

    const Stopwatch loadStart;
    RelightObject object = loadRelightObject(o.mesh, o.transport);
    const std::string materialLine = applyMaterialEdit(object, look.material, look.sizeMm, o.transport);
    if (look.baseColour) object.baseColour = BaseColour::load(o.mesh, object.mesh);
    const std::string groundLine = attachGround(object, look.ground, o.transport);
    if (!look.materialMap.empty())
        object.materialMap = loadMaterialMap(object, o.mesh, look.materialMap, look.mapMaterial, o.transport);
    const ScatteringComponents components =
        selectComponents(look.components, componentsOf(object.transport), o.transport);
    const Camera camera = makeCamera(o.camera, object.sphereCentre, object.sphereRadius);
    const int subpixels = subpixelGridSize(o.camera.spp);
    supersampledCamera(camera, subpixels);  // refuses a frame too large before the environment is read
    const int frames = o.turntable > 0 ? o.turntable : o.envSpin > 0 ? o.envSpin : 0;
    const int count = std::max(frames, 1);
    // A sequence prepares the environment once (EnvironmentLight, light_vector.h;
    // docs/relight.md, "Turning the environment: the fast path").
    const PointMethod sunMethod = parseSunSplitMethod(o.sunMethod);
    if (o.sunSplit) validateSunSplitOptions(o.sun);
    Image environment = loadEnvironment(o.environment, NonFinitePolicy::ClampNegative);
    std::optional<EnvironmentFrameRenderer> plain;
    std::optional<SunSplitFrameRenderer> split;
    if (o.sunSplit)
        split.emplace(object, std::move(environment), look, components, o.sun, o.transport, count > 1,
                      sunMethod);
    else
        plain.emplace(object, std::move(environment), look, components, count > 1);
    const double loadMs = loadStart.milliseconds();

    const std::filesystem::path parent = std::filesystem::path(output).parent_path();
    if (!parent.empty()) std::filesystem::create_directories(parent);

    std::printf("object: %zu vertices, %zu triangles, %.4g mm across, eta %.4g; cubemap 6x%ux%u\n",
                object.mesh.vertexCount(), object.mesh.triangleCount(), double(object.box.diagonal()),
                object.eta, object.transport.cubemapSize, object.transport.cubemapSize);
    if (!materialLine.empty()) std::printf("%s\n", materialLine.c_str());
    if (object.baseColour.enabled()) std::printf("%s\n", object.baseColour.describe().c_str());
    if (!groundLine.empty()) std::printf("%s\n", groundLine.c_str());
    if (object.materialMap) std::printf("%s\n", describe(*object.materialMap).c_str());
    std::printf("camera: eye (%.4g, %.4g, %.4g) target (%.4g, %.4g, %.4g) fov %.4g, %dx%d, %d spp%s\n",
                camera.eye.x, camera.eye.y, camera.eye.z, camera.target.x, camera.target.y,
                camera.target.z, camera.fovY, camera.width, camera.height, o.camera.spp,
                subpixels > 1 ? " (a regular sub-pixel grid, box filter)" : "");
    const char* ssPath = !components.singleScattering ? ""
                         : componentsOf(object.transport).folded ? " (single scattering folded: along the inward normal)"
                         : parseSingleScatteringView(look.ssPath) == SingleScatteringView::Normal
                             ? " (single scattering along the inward normal)"
                             : " (single scattering along the eye's refracted path)";
    std::printf("components: %s%s%s%s%s; light terms: %s; loaded in %.0f ms\n",
                components.multipleScattering ? "ms" : "",
                components.multipleScattering && components.singleScattering ? "," : "",
                components.singleScattering ? "ss" : "", ssPath, look.specular ? " + specular" : "",
                look.lightTerms ? std::to_string(look.lightTerms).c_str() : "all", loadMs);
    if (split) std::printf("%s\n", split->describe().c_str());
    std::fflush(stdout);

    const glm::dmat3 baseRotation = rotationY(look.envRotation);
    double totalLight = 0, totalRelight = 0, totalRays = 0, totalShade = 0, totalWrite = 0, totalSun = 0;
    std::vector<std::string> written;
    const Stopwatch runStart;

    for (int f = 0; f < count; ++f) {
        const double angle = frames > 0 ? 360.0 * f / frames : 0.0;
        // Object rotation (turntable) becomes a camera orbit plus an equal environment
        // rotation; environment spin rotates only the environment.
        Camera frameCamera = camera;
        glm::dmat3 rotation = baseRotation;
        if (o.turntable > 0) {
            frameCamera = turntableCamera(camera, glm::dvec3(object.box.centre()), angle);
            rotation = rotationY(-angle) * baseRotation;
        } else if (o.envSpin > 0) {
            rotation = rotationY(angle) * baseRotation;
        }

        EnvironmentFrameTimes t;
        SunSplitFrameTimes st;
        const Camera traced = supersampledCamera(frameCamera, subpixels);
        const Image image =
            boxDownsample(split ? split->render(traced, rotation, &st) : plain->render(traced, rotation, &t), subpixels);
        if (split) t = st.environment;

        const Stopwatch writeClock;
        const std::string base = frameName(output, f, frames);
        writeExr(base + ".exr", image);
        writePng(base + ".png", image, look.display);
        const double writeMs = writeClock.milliseconds();
        written.push_back(base);

        totalLight += t.light;
        totalRelight += t.relight;
        totalRays += t.rays;
        totalShade += t.shade;
        totalWrite += writeMs;
        std::printf("frame %d/%d", f + 1, count);
        if (o.turntable > 0) std::printf(" (object %.1f deg)", angle);
        if (o.envSpin > 0) std::printf(" (environment %.1f deg)", angle);
        std::printf(": light %.1f ms (%zu terms, L2 error %.2g), relight %.1f ms, rays %.1f ms, "
                    "shading %.1f ms, write %.1f ms; %zu object pixels -> %s.exr/.png\n",
                    t.light, t.lightTerms, t.lightRelativeL2, t.relight, t.rays, t.shade, writeMs,
                    t.objectPixels, base.c_str());
        if (split)
            std::printf("  sun split: %zu lights, irradiance %.1f ms, diffusion %.1f ms, single scattering %.1f ms, "
                        "ground %.1f ms\n",
                        st.lights, st.lightsIrradiance, st.lightsDiffusion, st.lightsSingleScattering, st.lightsGround);
        totalSun += st.lightsIrradiance + st.lightsDiffusion + st.lightsSingleScattering + st.lightsGround;
        std::fflush(stdout);
    }

    const double totalMs = runStart.milliseconds();
    char sunPart[64] = "";
    if (split) std::snprintf(sunPart, sizeof sunPart, "sun split %.1f ms, ", totalSun / count);
    std::printf("done: %d frame%s in %s (mean per frame: light %.1f ms, relight %.1f ms, rays %.1f ms, "
                "shading %.1f ms, %swrite %.1f ms)\n",
                count, count == 1 ? "" : "s", formatDuration(totalMs / 1000.0).c_str(), totalLight / count,
                totalRelight / count, totalRays / count, totalShade / count,
                sunPart, totalWrite / count);
    if (count == 1)
        std::printf("wrote %s.exr and %s.png\n", written[0].c_str(), written[0].c_str());
    else
        std::printf("wrote %s.exr/.png ... %s.exr/.png\n", written.front().c_str(), written.back().c_str());
    return 0;
}

// ---------------------------------------------------------------------------
// view
// ---------------------------------------------------------------------------

struct ViewOptions {
    std::string mesh, transport;
    std::vector<std::string> environments;
    CameraOptions camera;
    FrameSettings frame;
    int frames = 0;
    std::vector<std::string> screenshots;
    bool screenshotWithPanel = false, noVsync = false, hidePanel = false;
    double spin = 0.0, orbit = 0.0, lightOrbit = 0.0;
    // The scripted mid-run edit (makeScriptedEdit, view.h); absent = not given.
    std::optional<int> editAfter;
    std::optional<std::string> editMaterial;
    std::optional<double> editSizeMm;
    int threads = 0;
    // Point lights (texture-space importance sampling).
    std::vector<std::string> lights;
    std::string lightsFile, split = "hybrid";
    TextureSpaceOptions tsis;
    int atlasSize = kDefaultIrradianceMapSize;
    bool noEnvironmentLight = false;
    bool pointSpecular = false, pointSingleScattering = false;
    double pointSpecularRoughness = kDefaultSpecularRoughness;
    int pointSingleScatteringSamples = PointSingleScatteringOptions{}.pathSamples;
    bool sunSplit = false;
    SunSplitOptions sun;
};

void addViewOptions(CLI::App& app, ViewOptions& o) {
    app.add_option("mesh", o.mesh, "Mesh file the transport file was computed for (.obj .ply .off .stl, .gz)")
        ->required();
    app.add_option("-t,--transport", o.transport, "Transport file (prt-precompute output)")->required();
    app.add_option("-e,--environment", o.environments,
                   "Lat-long HDR environments (files, or folders of .exr/.hdr), repeatable; the first is "
                   "shown first (default: data/envmaps/, the eight fetched maps)");
    addCameraOptions(app, o.camera);
    addSamplesPerPixelOption(app, o.camera);
    addFrameOptions(app, o.frame);
    app.add_option("--frames", o.frames,
                   "Scripted run: render N frames once the first relight has landed, write the "
                   "--screenshot files and exit (0 = interactive)")
        ->capture_default_str()->group("Scripting");
    app.add_option("--screenshot", o.screenshots,
                   "Write the view at exit (with --frames) to this file: .exr = linear RGBA float as "
                   "render's EXR, otherwise an sRGB PNG as render's PNG; repeatable")
        ->group("Scripting");
    app.add_flag("--screenshot-panel", o.screenshotWithPanel,
                 "PNG screenshots show the whole window, panel included")
        ->group("Scripting");
    app.add_option("--spin", o.spin, "Rotate the environment by this many degrees every frame (relights)")
        ->capture_default_str()->group("Scripting");
    app.add_option("--orbit", o.orbit,
                   "Turn the camera by this many degrees every frame about its up axis through the target "
                   "(the environment stays)")
        ->capture_default_str()->group("Scripting");
    app.add_option("--light-orbit", o.lightOrbit,
                   "Turn the point and directional lights by this many degrees every frame about +Y through "
                   "the object's centre (a new light position every frame)")
        ->capture_default_str()->group("Scripting");
    app.add_option("--edit-after", o.editAfter,
                   "Scripted edit (editable files): after K frames with light (1 <= K < --frames), edit the "
                   "material and/or size live, as the panel does")
        ->group("Scripting");
    app.add_option("--edit-material", o.editMaterial,
                   "The scripted edit's material, as --material takes it (default: keep the current one)")
        ->group("Scripting");
    app.add_option("--edit-size-mm", o.editSizeMm,
                   "The scripted edit's object size in mm (default: keep the current one)")
        ->group("Scripting");
    app.add_flag("--no-vsync", o.noVsync, "Do not wait for vertical sync (measure frame rates)")
        ->group("Scripting");
    app.add_flag("--hide-panel", o.hidePanel, "Start with the panel hidden (H toggles it)")->group("Scripting");
    addThreadsOption(app, o.threads, "Worker threads of the relight (default: all cores)");
    const char* group = "Point lights (Chang et al. 2008; docs/point-lights.md)";
    app.add_option("--light", o.lights,
                   "A point or directional light added to the environment's light, repeatable: "
                   "point:X,Y,Z:R,G,B (mm in the object's frame, W/sr) or dir:X,Y,Z:R,G,B (toward the light, W/m^2); "
                   "add, drag and recolour more in the panel")
        ->group(group);
    app.add_option("--lights", o.lightsFile, "JSON scene file with a \"lights\" list")->group(group);
    app.add_flag("--no-environment-light", o.noEnvironmentLight,
                 "Start with the environment's light (and background) off: point lights only (E toggles)")
        ->group(group);
    app.add_option("--split", o.split, "R_d by: hybrid (local filter + global samples), sampling, local or global")
        ->capture_default_str()->group(group);
    app.add_option("--tsis-samples", o.tsis.samples, "N, importance samples per lighting")
        ->capture_default_str()->group(group);
    app.add_option("--tsis-seed", o.tsis.seed, "Seed of the draws' jitter")->capture_default_str()->group(group);
    app.add_option("--atlas-size", o.atlasSize, "Irradiance map resolution (power of two)")
        ->capture_default_str()->group(group);
    app.add_option("--light-map", o.tsis.lightMapSize, "Translucent shadow map resolution per light")
        ->capture_default_str()->group(group);
    app.add_option("--rings", o.tsis.rings, "L, rings of the local filter")->capture_default_str()->group(group);
    app.add_option("--ring-samples", o.tsis.ringSamples, "C, taps per ring")->capture_default_str()->group(group);
    app.add_option("--cluster-angle", o.tsis.clusterAngle, "theta of the clustered global sum (0: every sample)")
        ->capture_default_str()->group(group);
    app.add_option("--importance-bound", o.tsis.importanceBound, "c in mm^-1 (R_p: R_d(r) 2 pi r = c)")
        ->capture_default_str()->group(group);
    app.add_option("--split-sharpness", o.tsis.sharpness, "K in mm^-1")->capture_default_str()->group(group);
    app.add_flag("--point-specular", o.pointSpecular,
                 "Start with the point lights' specular on: prt-pointlight's GGX lobe per pixel, each light's "
                 "shadow traced at the vertices and interpolated (--specular is the environment's layer)")
        ->group(group);
    app.add_option("--point-specular-roughness", o.pointSpecularRoughness,
                   "GGX roughness alpha of the point lights' specular, in (0, 1] (used as given, not squared)")
        ->capture_default_str()->group(group);
    app.add_flag("--point-single-scattering", o.pointSingleScattering,
                 "Start with the point lights' single scattering on: Jensen et al. 2001's term along the refracted "
                 "view ray, traced at the vertices from the current eye (again when the camera moves)")
        ->group(group);
    app.add_option("--point-single-scattering-samples", o.pointSingleScatteringSamples,
                   "Gauss-Legendre samples along each vertex's refracted view ray, 1 to 256")
        ->capture_default_str()->group(group);
    addSunSplitOptions(app, o.sunSplit, o.sun, nullptr,
                       "Take the environment's brightest texels (sun, lamps) out as directional lights, Jensen-Buhler "
                       "at the vertices, shown once computed for the light on screen (the plain relight meanwhile)");
}

int runView(const ViewOptions& o) {
#ifndef PRT_HAVE_VIEWER
    throw Error("view", "this prt-relight was built without the viewer (configure with -DPRT_BUILD_VIEWER=ON)");
#else
    const ThreadLimit limit(o.threads);
    checkFrameSettings(o.frame);
    if (o.frames < 0) throw Error("--frames", "must be >= 0");
    if (!o.screenshots.empty() && o.frames == 0)
        throw Error("--screenshot", "needs --frames N (interactive screenshots: F12 or P)");
    if (!std::isfinite(o.spin)) throw Error("--spin", "must be finite");
    if (!std::isfinite(o.orbit)) throw Error("--orbit", "must be finite");
    if (!std::isfinite(o.lightOrbit)) throw Error("--light-orbit", "must be finite");
    if (o.lightOrbit != 0.0 && o.lights.empty() && o.lightsFile.empty())
        throw Error("--light-orbit", "needs point or directional lights (--light / --lights)");
    validateSpecularRoughness(o.pointSpecularRoughness, "--point-specular-roughness");
    validatePointSingleScattering({.pathSamples = o.pointSingleScatteringSamples}, "--point-single-scattering-samples");
    for (const std::string& path : o.screenshots)
        if (path.empty()) throw Error("--screenshot", "empty path");
    if (o.sunSplit) validateSunSplitOptions(o.sun);
    // Cheap checks first: the display, the environments' paths.
    checkViewerDisplay();
    ViewerSetup setup;
    setup.environments = findEnvironments(o.environments);

    const Stopwatch loadStart;
    setup.object = loadRelightObject(o.mesh, o.transport);
    const std::string materialLine = applyMaterialEdit(setup.object, o.frame.material, o.frame.sizeMm, o.transport);
    if (o.frame.baseColour) setup.object.baseColour = BaseColour::load(o.mesh, setup.object.mesh);
    const std::string groundLine = attachGround(setup.object, o.frame.ground, o.transport);
    if (!o.frame.materialMap.empty())
        setup.object.materialMap =
            loadMaterialMap(setup.object, o.mesh, o.frame.materialMap, o.frame.mapMaterial, o.transport);
    setup.meshPath = o.mesh;
    setup.transportPath = o.transport;
    setup.frame = o.frame;
    setup.components = selectComponents(o.frame.components, componentsOf(setup.object.transport), o.transport);
    setup.camera = makeCamera(o.camera, setup.object.sphereCentre, setup.object.sphereRadius);
    setup.subpixels = subpixelGridSize(o.camera.spp);
    std::printf("object: %zu vertices, %zu triangles, %.4g mm across, eta %.4g; cubemap 6x%ux%u; loaded in %.0f ms\n",
                setup.object.mesh.vertexCount(), setup.object.mesh.triangleCount(),
                double(setup.object.box.diagonal()), setup.object.eta, setup.object.transport.cubemapSize,
                setup.object.transport.cubemapSize, loadStart.milliseconds());
    if (!materialLine.empty()) std::printf("%s\n", materialLine.c_str());
    if (!groundLine.empty()) std::printf("%s\n", groundLine.c_str());
    if (setup.object.materialMap) std::printf("%s\n", describe(*setup.object.materialMap).c_str());
    std::fflush(stdout);
    setup.tsis = o.tsis;
    setup.frames = o.frames;
    setup.edit = makeScriptedEdit(setup.object, o.frames, o.editAfter, o.editMaterial, o.editSizeMm, o.transport);
    setup.screenshots = o.screenshots;
    setup.screenshotWithPanel = o.screenshotWithPanel;
    setup.spinDegreesPerFrame = o.spin;
    setup.orbitDegreesPerFrame = o.orbit;
    setup.lightOrbitDegreesPerFrame = o.lightOrbit;
    setup.vsync = !o.noVsync;
    setup.showPanel = !o.hidePanel;
    // The point lights render the object's current material (an editable file's edit).
    setup.material = shownMaterial(setup.object, o.transport);
    if (!o.lightsFile.empty()) setup.pointLights = loadLightScene(o.lightsFile);
    for (const std::string& text : o.lights) setup.pointLights.push_back(parseLight(text));
    if (!setup.pointLights.empty() && !setup.material)
        throw Error(o.transport, "names no material (sigma_s_prime, sigma_a, eta): point lights need one");
    if (!setup.pointLights.empty()) checkLightsOutside(RayScene(setup.object.mesh), setup.pointLights);
    setup.tsis.mode = parseTextureSpaceMode(o.split);
    setup.atlasSize = o.atlasSize;
    validateTextureSpaceOptions(setup.tsis);
    validateAtlasResolution(o.atlasSize);
    setup.pointSpecular = o.pointSpecular;
    setup.pointSpecularRoughness = o.pointSpecularRoughness;
    setup.pointSingleScattering = o.pointSingleScattering;
    setup.pointSingleScatteringSamples = o.pointSingleScatteringSamples;
    setup.environmentLight = !o.noEnvironmentLight;
    if (o.sunSplit) setup.sunSplit = o.sun;
    return runViewer(std::move(setup));
#endif
}

// ---------------------------------------------------------------------------
// info
// ---------------------------------------------------------------------------

struct InfoOptions {
    std::vector<std::string> transports;
    bool full = false;
};

void addInfoOptions(CLI::App& app, InfoOptions& o) {
    app.add_option("transport", o.transports, "Transport files (prt-precompute output)")
        ->required();
    app.add_flag("--full", o.full,
                 "Load every vector and verify every checksum, then print the in-memory sizes, the "
                 "largest vector or block and the load time (default: read the headers only)");
}

// Headers only by default, so it answers at once even for a multi-GB file; the byte
// counts are then the on-disk payload (delta-coded indices for version-4 blocked
// components), with --full the in-memory arrays the relight reads. The vectors are
// then not read, so say so: a header-only description is not a validation.
int runInfo(const InfoOptions& o) {
    for (size_t i = 0; i < o.transports.size(); ++i) {
        const std::string& path = o.transports[i];
        const TransportFileInfo info = readTransportFileInfo(path);
        std::string text = describe(info);
        if (o.full) {
            const Stopwatch clock;
            const TransportFile file = loadTransportFile(path);
            const double seconds = clock.seconds();
            // The header line (format version, file size) from the info, the rest from
            // the loaded file, which knows the in-memory sizes and the largest vectors.
            const std::string loaded = describe(file);
            char line[160];
            std::snprintf(line, sizeof line,
                          "loaded and verified in %.3f s (%.0f MiB/s from disk or page cache)\n",
                          seconds, seconds > 0 ? double(info.fileBytes) / seconds / 1048576.0 : 0.0);
            text = text.substr(0, text.find('\n') + 1) + loaded.substr(loaded.find('\n') + 1) + line;
        } else {
            text += "vectors: not read or verified (--full loads and verifies them)\n";
        }
        std::printf("%s%s\n%s", i ? "\n" : "", path.c_str(), text.c_str());
    }
    return 0;
}

}  // namespace

int main(int argc, char** argv) {
    return runMain("prt-relight", [&]() -> int {
        CLI::App app{
            "prt-relight: relight translucent objects from precomputed transport (Wang et al. 2005).\n"
            "Examples:\n"
            "  prt-relight render data/meshes/bunny.off -t out/bunny.prt -e sunset.exr -o out/bunny\n"
            "  prt-relight render bunny.off -t bunny.prt -e studio.exr --turntable 36 -o out/tt/bunny\n"
            "  prt-relight view data/meshes/bunny.off -t out/bunny.prt -e data/envmaps\n"
            "  prt-relight info out/bunny.prt --full\n"
            "Vector options take comma-separated values; write negative ones as --eye=-10,0,50."};
        app.require_subcommand(1);

        RenderOptions render;
        CLI::App* renderCmd = app.add_subcommand(
            "render", "Render frames offline: linear EXR + sRGB PNG, optionally a turntable or an "
                      "environment spin (docs/relight.md)");
        addRenderOptions(*renderCmd, render);

        ViewOptions view;
        CLI::App* viewCmd = app.add_subcommand(
            "view", "Interactive viewer: orbit camera, environment rotation and switching, component "
                    "toggles, light terms; scriptable with --frames/--screenshot (docs/viewer.md)");
        addViewOptions(*viewCmd, view);

        InfoOptions info;
        CLI::App* infoCmd = app.add_subcommand(
            "info", "What a transport file holds: cubemap, SH part, mesh fingerprint, parameters, "
                    "components and their sizes; --full loads and verifies it (docs/relight.md)");
        addInfoOptions(*infoCmd, info);

        if (const auto exitCode = parseCommandLine(app, argc, argv, "prt-relight")) return *exitCode;
        if (renderCmd->parsed()) return runRender(render);
        if (viewCmd->parsed()) return runView(view);
        if (infoCmd->parsed()) return runInfo(info);
        return 1;
    });
}
