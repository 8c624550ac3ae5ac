#include "common/options.h"

#include <CLI/CLI.hpp>

#include <tbb/global_control.h>

#include <algorithm>
#include <cmath>

#include "common/error.h"
#include "common/material_edit.h"

namespace prt {

namespace {
glm::dvec3 toVec(const std::vector<double>& v) { return {v[0], v[1], v[2]}; }
}  // namespace

void addCameraOptions(CLI::App& app, CameraOptions& o) {
    app.add_option("--eye", o.eye, "Camera position x,y,z in mm (object space after scaling); "
                                   "default: framed automatically from --azimuth/--elevation")
        ->expected(3)->delimiter(',')->allow_extra_args(false)->group("Camera");
    app.add_option("--target", o.target, "Point looked at x,y,z in mm (default: bounding-sphere centre)")
        ->expected(3)->delimiter(',')->allow_extra_args(false)->group("Camera");
    app.add_option("--up", o.up, "Up vector x,y,z (roll)")->expected(3)->delimiter(',')->allow_extra_args(false)
        ->capture_default_str()->group("Camera");
    app.add_option("--fov", o.fov, "Vertical field of view in degrees")->capture_default_str()->group("Camera");
    app.add_option("-W,--width", o.width, "Image width in pixels")->capture_default_str()->group("Camera");
    app.add_option("-H,--height", o.height, "Image height in pixels")->capture_default_str()->group("Camera");
    app.add_option("--azimuth", o.azimuth,
                   "Automatic framing: degrees about +Y, 0 = camera on +Z looking down -Z")
        ->capture_default_str()->group("Camera");
    app.add_option("--elevation", o.elevation, "Automatic framing: degrees above the horizontal")
        ->capture_default_str()->group("Camera");
    app.add_option("--fill", o.fill, "Automatic framing: fraction of the smaller image side the "
                                     "bounding sphere fills")
        ->capture_default_str()->group("Camera");
}

void addBaseColourOption(CLI::App& app, bool& on, const std::string& group) {
    app.add_flag("--base-colour", on,
                 "Tint the translucent exitance at the exit point by the mesh file's base colour (glTF "
                 "baseColorFactor x baseColorTexture, OBJ+MTL Kd x map_Kd; docs/assets.md); the specular layer "
                 "is not tinted")
        ->group(group);
}

void addSamplesPerPixelOption(CLI::App& app, CameraOptions& o) {
    app.add_option("--spp", o.spp,
                   "Anti-aliasing: samples per pixel, a square number (4 = a 2 x 2 grid of sub-pixel samples "
                   "averaged by a box filter; the alpha becomes the pixel's coverage)")
        ->capture_default_str()->group("Camera");
}

Camera makeCamera(const CameraOptions& o, const glm::dvec3& sphereCentre, double sphereRadius) {
    // The image and lens first: framing divides by them.
    constexpr int kMaxSide = 16384;
    if (o.width < 1 || o.width > kMaxSide)
        throw Error("-W", "image width must be between 1 and " + std::to_string(kMaxSide) + " pixels, got " +
                              std::to_string(o.width));
    if (o.height < 1 || o.height > kMaxSide)
        throw Error("-H", "image height must be between 1 and " + std::to_string(kMaxSide) + " pixels, got " +
                              std::to_string(o.height));
    if (!(o.fov > 0 && o.fov < 180)) throw Error("--fov", "must be in (0, 180) degrees");
    if (!(o.fill > 0 && o.fill <= 1)) throw Error("--fill", "must be in (0, 1]");
    if (!std::isfinite(o.azimuth) || !std::isfinite(o.elevation))
        throw Error("camera", "azimuth and elevation must be finite");
    const glm::dvec3 target = o.target.empty() ? sphereCentre : toVec(o.target);
    Camera c;
    if (o.eye.empty()) {
        if (!(std::abs(o.elevation) < 90)) throw Error("--elevation", "must be in (-90, 90) degrees");
        c = frameSphere(target, std::max(sphereRadius, 1e-6), o.azimuth, o.elevation, o.fov,
                        o.width, o.height, o.fill);
    } else {
        c.eye = toVec(o.eye);
        c.target = target;
        c.fovY = o.fov;
        c.width = o.width;
        c.height = o.height;
    }
    c.up = toVec(o.up);
    for (const glm::dvec3& v : {c.eye, c.target, c.up})
        if (!std::isfinite(v.x) || !std::isfinite(v.y) || !std::isfinite(v.z))
            throw Error("camera", "eye, target and up must be finite");
    validateCamera(c);
    return c;
}

void addMaterialOptions(CLI::App& app, MaterialOptions& o, bool withG, const std::string& group) {
    app.add_option("-m,--material", o.material,
                   "Measured material (Jensen et al. 2001): Apple Chicken1 Chicken2 Cream Ketchup Marble "
                   "Potato Skimmilk Skin1 Skin2 Spectralon Wholemilk")
        ->capture_default_str()->group(group);
    app.add_option("--sigma-a", o.sigmaA, "Custom absorption R,G,B in mm^-1 (with --sigma-s-prime)")
        ->expected(3)->delimiter(',')->allow_extra_args(false)->group(group);
    app.add_option("--sigma-s-prime", o.sigmaSPrime, "Custom reduced scattering R,G,B in mm^-1")
        ->expected(3)->delimiter(',')->allow_extra_args(false)->group(group);
    app.add_option("--diffuse-colour", o.diffuseColour,
                   "Artist's material: diffuse colour R,G,B in (0, 1), linear (with --mfp-mm)")
        ->expected(3)->delimiter(',')->allow_extra_args(false)->group(group);
    app.add_option("--mfp-mm", o.meanFreePathMm,
                   "Artist's material: diffuse mean free path 1/sigma_tr in mm, one value or R,G,B")
        ->expected(1, 3)->delimiter(',')->allow_extra_args(false)->group(group);
    app.add_option("--eta", o.eta, "Relative index of refraction (default 1.3)")->group(group);
    if (withG) app.add_option("--g", o.g, "Henyey-Greenstein asymmetry (> 0 forward; default 0)")->group(group);
}

Material makeMaterial(const MaterialOptions& o) {
    if (o.sigmaA.empty() != o.sigmaSPrime.empty())
        throw Error("--sigma-a", "a custom material needs both --sigma-a and --sigma-s-prime");
    if (o.diffuseColour.empty() != o.meanFreePathMm.empty())
        throw Error("--diffuse-colour", "an artist's material needs both --diffuse-colour and --mfp-mm");
    if (!o.diffuseColour.empty() && !o.sigmaA.empty())
        throw Error("--diffuse-colour", "give either --sigma-a/--sigma-s-prime or --diffuse-colour/--mfp-mm");
    if (!o.diffuseColour.empty()) {
        if (o.meanFreePathMm.size() == 2) throw Error("--mfp-mm", "needs one value or three (R, G, B)");
        const glm::dvec3 mfp = o.meanFreePathMm.size() == 1
                                   ? glm::dvec3(o.meanFreePathMm[0])
                                   : glm::dvec3(o.meanFreePathMm[0], o.meanFreePathMm[1], o.meanFreePathMm[2]);
        return materialFromAppearance({o.diffuseColour[0], o.diffuseColour[1], o.diffuseColour[2]}, mfp,
                                      o.eta.value_or(1.3), o.g.value_or(0.0));
    }
    if (!o.sigmaA.empty())
        return customMaterial({o.sigmaSPrime[0], o.sigmaSPrime[1], o.sigmaSPrime[2]},
                              {o.sigmaA[0], o.sigmaA[1], o.sigmaA[2]}, o.eta.value_or(1.3), o.g.value_or(0.0));
    Material m = materialByName(o.material);
    if (o.eta) m.eta = *o.eta;
    if (o.g) m.g = *o.g;
    validateMaterial(m);
    return m;
}

void addScaleOptions(CLI::App& app, ScaleOptions& o, const std::string& group) {
    app.add_option("--size-mm", o.sizeMm, "Scale the mesh so its bounding-box diagonal is this many mm (default 30)")
        ->group(group);
    app.add_option("--mm-per-unit", o.mmPerUnit, "Millimetres per mesh-file unit (instead of --size-mm)")
        ->group(group);
}

MeshScale makeScale(const ScaleOptions& o) {
    if (o.sizeMm && o.mmPerUnit) throw Error("--size-mm", "give either --size-mm or --mm-per-unit, not both");
    MeshScale scale;
    if (o.mmPerUnit) scale.mmPerUnit = o.mmPerUnit;
    else scale.sizeMm = o.sizeMm.value_or(30.0);
    return scale;
}

void addDisplayOptions(CLI::App& app, DisplayTransform& d, const std::string& group) {
    app.add_option("--exposure", d.exposureStops, "Exposure in stops for the PNG (the EXR stays linear)")
        ->capture_default_str()->group(group);
    app.add_option_function<std::string>(
           "--tonemap", [&d](const std::string& name) { d.op = parseToneMapOperator(name); },
           "PNG tone mapping: clamp, reinhard, filmic or chang (Chang et al. 2008; docs/conventions.md, "
           "\"Display\"); the EXR stays linear")
        ->default_str(toneMapOperatorName(d.op))->group(group);
}

std::optional<int> parseCommandLine(CLI::App& app, int argc, char** argv, const std::string& program) {
    try {
        app.parse(argc, argv);
    } catch (const CLI::CallForHelp& e) {
        return app.exit(e);
    } catch (const CLI::CallForAllHelp& e) {
        return app.exit(e);
    } catch (const CLI::ParseError& e) {
        std::string reason = e.what();
        for (char& c : reason)
            if (c == '\n' || c == '\r') c = ' ';
        while (!reason.empty() && reason.back() == ' ') reason.pop_back();
        std::string hint = program;
        for (const CLI::App* sub : app.get_subcommands())
            if (sub->parsed()) hint += " " + sub->get_name();
        throw Error("", reason + " (see " + hint + " --help)");
    }
    return std::nullopt;
}

void addThreadsOption(CLI::App& app, int& threads, const std::string& help) {
    app.add_option("-j,--threads", threads, help);
}

ThreadLimit::ThreadLimit(int threads) {
    if (threads < 0) throw Error("--threads", "must be >= 0");
    if (threads > 0)
        control_ = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, size_t(threads));
}

ThreadLimit::~ThreadLimit() = default;

}  // namespace prt
