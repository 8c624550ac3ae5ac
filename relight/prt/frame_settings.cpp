// The look shared by prt-relight render and view: see frame_settings.h.

#include "relight/prt/frame_settings.h"

#include <cmath>
#include <cstdio>

#include "common/error.h"

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
    o.specular = app.add_flag("--specular", s.specular,
                              "Add a Fresnel-weighted specular reflection of the pre-filtered environment "
                              "(off by default; the reference renderer has none)")
                     ->group("Lighting");
    o.specularBlur = app.add_option("--specular-blur", s.specularBlur,
                                    "Pre-filter of the specular layer: box-filter the lat-long map down by this "
                                    "factor (must divide its size; default: the largest of 8, 4, 2, 1 that does)")
                         ->group("Lighting");
    app.add_option("--exposure", s.exposure, "Exposure in stops for the PNG (the EXR stays linear)")
        ->capture_default_str()->group("Output");
    return o;
}

void checkFrameSettings(const FrameSettings& s) {
    if (!std::isfinite(s.envRotation)) throw Error("--env-rotation", "must be finite");
    if (!std::isfinite(s.exposure)) throw Error("--exposure", "must be finite");
    if (s.specularBlur < 0) throw Error("--specular-blur", "must be >= 1");
}

std::string renderArguments(const FrameSettings& s) {
    char buf[128];
    std::snprintf(buf, sizeof buf, " --env-rotation=%.9g --exposure=%.9g", s.envRotation, s.exposure);
    std::string args = buf;
    if (s.lightTerms > 0) args += " -L " + std::to_string(s.lightTerms);
    if (s.components != "all") args += " --components " + s.components;
    if (s.specular) {
        args += " --specular";
        if (s.specularBlur > 0) args += " --specular-blur " + std::to_string(s.specularBlur);
    }
    return args;
}

}  // namespace prt
