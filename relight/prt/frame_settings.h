#pragma once
// The look of a frame lit by an environment, one struct for `prt-relight render` and
// `prt-relight view`, so a viewer screenshot and a render of the same arguments agree
// by construction: which scattering components, how many Haar terms of the light, the
// environment's rotation, the specular layer and the exposure (docs/relight.md,
// "Shading"; docs/viewer.md, "Inputs and options").
//
// Both subcommands bind it with addFrameOptions (one name, default and help text per
// option), validate it with checkFrameSettings, and the viewer writes its state back as
// render options with renderArguments.

#include "common/cli_fwd.h"

#include <cstddef>
#include <string>

#include "common/tonemap.h"

namespace prt {

struct FrameSettings {
    double envRotation = 0.0;         // --env-rotation: degrees about +Y (rotationY), light and background
    std::string components = "all";   // --components: ms, ss, ms,ss or all (selectComponents against the file)
    size_t lightTerms = 0;            // -L: keep the light's largest Haar terms; 0 = all
    // --ss-path: the path single scattering is shown along, refracted (the eye's) or
    // normal (as precomputed); parseSingleScatteringView, relight/prt/eye_path.h.
    std::string ssPath = "refracted";
    bool specular = false;            // --specular: the Fresnel-weighted pre-filtered reflection
    int specularBlur = 0;             // --specular-blur: pre-filter factor; 0 = automatic (specularBlurFactor)
    DisplayTransform display;         // --exposure, --tonemap: the displayed / PNG image only
    // The object's material and size, for files made with prt-precompute --editable
    // (relight/prt/editable_transport.h): --material as parseMaterial reads it
    // (common/material_edit.h), --size-mm the object's size in mm; empty / 0 = the
    // file's own.
    std::string material;
    double sizeMm = 0.0;
    // --base-colour: the mesh file's base colour tints the translucent exitance at the
    // exit point (relight/render/base_colour.h); loaded into RelightObject::baseColour.
    bool baseColour = false;
    // --ground: the ground's transport file (prt-precompute --ground; relight/prt/
    // ground_receiver.h), loaded into RelightObject::ground; empty: no ground drawn.
    std::string ground;
    // --material-map / --map-material: a texture in the asset's texture coordinates and
    // the material where it is 1 (relight/prt/material_map.h); editable files only.
    std::string materialMap, mapMaterial;
};

// The options addFrameOptions declared that a subcommand may tie together
// (render makes --specular-blur need --specular).
struct FrameOptions {
    CLI::Option* specular = nullptr;
    CLI::Option* specularBlur = nullptr;
};

// Declares --env-rotation, --components, -L/--light-terms, --ss-path, --specular, --specular-blur
// (group "Lighting"), --material and --size-mm (group "Material") and --exposure,
// --tonemap (group "Output", addDisplayOptions), bound to `s`; the defaults are FrameSettings'.
FrameOptions addFrameOptions(CLI::App& app, FrameSettings& s);

// Throws prt::Error naming the option: a non-finite --env-rotation or --exposure, a
// negative --specular-blur, an --ss-path that is neither refracted nor normal, a --size-mm that is not finite and >= 0. --components is checked against the transport file by
// selectComponents (common/transport_params.h).
void checkFrameSettings(const FrameSettings& s);

// The options that give `s` back through addFrameOptions:
// " --env-rotation=R --exposure=E" (%.9g; '=' so negative values parse), then
// " --tonemap T" unless T is clamp, " -L N"
// when N > 0, " --components C" unless C is "all", " --ss-path normal" when set,
// " --specular" followed by
// " --specular-blur F" (F > 0) when the layer is on, and " --material M" /
// " --size-mm=S" when set, " --base-colour" when on, " --ground G" and
// " --material-map MAP --map-material B" when set; M, G, MAP and B as shellQuote
// writes them (common/util.h), so the text pastes into a shell as it is.
std::string renderArguments(const FrameSettings& s);

}  // namespace prt
