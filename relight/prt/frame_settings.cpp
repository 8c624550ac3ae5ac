// The look shared by prt-relight render and view: see frame_settings.h.

#include "relight/prt/frame_settings.h"

#include <CLI/CLI.hpp>

#include <cmath>
#include <cstdio>

#include "common/error.h"
#include "common/util.h"
#include "common/options.h"
#include "relight/prt/eye_path.h"

namespace prt {

FrameOptions addFrameOptions(CLI::App& app, FrameSettings& s) {
    FrameOptions o;
    app.add_option("--env-rotation", s.envRotation, "Rotate the environment by this many degrees about +Y")
        ->capture_default_str()->group("Lighting");
    app.add_option("--components", s.components,
                   "Components to render: ms, ss, ms,ss or all (default: all the file has)")
        ->capture_default_str()->group("Lighting");
    app.add_option("-L,--light-terms", s.lightTerms, "Keep the largest L Haar terms of the light (0 = all)")
        ->capture_default_str()->group("Lighting");
    app.add_option("--ss-path", s.ssPath,
                   "Single scattering along the eye's refracted ray (refracted: the precomputed vectors "
                   "times a factor of the view, exact for a half space) or along the inward normal as "
                   "precomputed (normal: Wang et al. 2005)")
        ->capture_default_str()->group("Lighting");
    o.specular = app.add_flag("--specular", s.specular,
                              "Add a Fresnel-weighted specular reflection of the pre-filtered environment "
                              "(off by default; the reference renderer has none)")
                     ->group("Lighting");
    o.specularBlur = app.add_option("--specular-blur", s.specularBlur,
                                    "Pre-filter of the specular layer: box-filter the lat-long map down by this "
                                    "factor (must divide its size; default: the largest of 8, 4, 2, 1 that does)")
                         ->group("Lighting");
    app.add_option("--material", s.material,
                   "Editable files only: the object's material, a measured one (Marble), sigma:SA_R,SA_G,SA_B:"
                   "SS_R,SS_G,SS_B (mm^-1) or colour:R,G,B:MFP (diffuse colour + mean free path in mm); "
                   "default: the file's")
        ->group("Material");
    app.add_option("--size-mm", s.sizeMm,
                   "Editable files only: the object's size (bounding-box diagonal, mm); default: the file's")
        ->group("Material");
    addBaseColourOption(app, s.baseColour, "Material");
    app.add_option("--ground", s.ground,
                   "The ground's transport file (prt-precompute --ground writes <output>.ground.prt): draws the "
                   "diffuse plane under the object with the object's shadow (docs/ground.md)")
        ->group("Scene");
    CLI::Option* map =
        app.add_option("--material-map", s.materialMap,
                       "Editable files only: a texture (PNG or EXR, first channel in [0, 1]) in the asset's texture "
                       "coordinates; where it is t, --map-material replaces the object's material by t, blended "
                       "per vertex at the exit point (docs/editable-transport.md, \"Material maps\")")
            ->group("Material");
    app.add_option("--map-material", s.mapMaterial, "The material where --material-map is 1 (as --material reads it)")
        ->group("Material")
        ->needs(map);
    map->needs("--map-material");
    addDisplayOptions(app, s.display);
    return o;
}

void checkFrameSettings(const FrameSettings& s) {
    if (!std::isfinite(s.envRotation)) throw Error("--env-rotation", "must be finite");
    if (!std::isfinite(s.display.exposureStops)) throw Error("--exposure", "must be finite");
    if (s.specularBlur < 0) throw Error("--specular-blur", "must be >= 1");
    parseSingleScatteringView(s.ssPath);
    if (!(s.sizeMm >= 0.0) || !std::isfinite(s.sizeMm)) throw Error("--size-mm", "must be a size in mm > 0");
}

std::string renderArguments(const FrameSettings& s) {
    char buf[128];
    std::snprintf(buf, sizeof buf, " --env-rotation=%.9g --exposure=%.9g", s.envRotation, s.display.exposureStops);
    std::string args = buf;
    if (s.display.op != ToneMapOperator::Clamp) args += std::string(" --tonemap ") + toneMapOperatorName(s.display.op);
    if (s.lightTerms > 0) args += " -L " + std::to_string(s.lightTerms);
    if (s.components != "all") args += " --components " + s.components;
    if (parseSingleScatteringView(s.ssPath) == SingleScatteringView::Normal) args += " --ss-path normal";
    if (s.specular) {
        args += " --specular";
        if (s.specularBlur > 0) args += " --specular-blur " + std::to_string(s.specularBlur);
    }
    if (!s.material.empty()) args += " --material " + shellQuote(s.material);
    if (s.sizeMm > 0.0) {
        std::snprintf(buf, sizeof buf, " --size-mm=%.9g", s.sizeMm);
        args += buf;
    }
    if (s.baseColour) args += " --base-colour";
    if (!s.ground.empty()) args += " --ground " + shellQuote(s.ground);
    if (!s.materialMap.empty())
        args += " --material-map " + shellQuote(s.materialMap) + " --map-material " + shellQuote(s.mapMaterial);
    return args;
}

}  // namespace prt
