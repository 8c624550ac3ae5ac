#pragma once
// What the viewer's parts share (prt-relight view, docs/viewer.md): the state the user
// changes with keys, drags and the panel (ViewState), what bounds those changes
// (ViewLimits), and the running statistics the panel and the exit summary print.

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <string>
#include <vector>

#include "common/camera.h"
#include "common/materials.h"
#include "relight/pointlight/point_lights.h"
#include "relight/pointlight/texture_space_sampling.h"

namespace prt {

// What the user asks for. The light on screen lags behind it while a relight is in
// flight (the viewer draws the light of the result it shows).
struct ViewState {
    Camera camera;                      // its width x height is the image's (the window's framebuffer)
    int environment = 0;                // index into the environments
    double rotation = 0.0;              // environment rotation, degrees about +Y, in (-180, 180]
    float exposure = 0.0f;              // stops
    int toneMap = 0;                    // ToneMapOperator (common/tonemap.h)
    int lightTerms = 0;                 // the light's largest Haar terms kept; 0 = all
    bool multipleScattering = true, singleScattering = true;  // asked for (the file may lack one)
    bool specular = false;              // the specular layer
    bool environmentLight = true;       // the environment's light and background
    bool pointLights = true;            // the point lights' light
    std::vector<Light> lights;          // point lights, mm in the object's frame
    int splitMode = int(TextureSpaceMode::Hybrid);  // TextureSpaceMode
    int pointSamples = 900;             // N of texture-space importance sampling
    // The point lights' surface terms (vertex_surface_terms.h): the GGX specular with
    // its roughness alpha, and single scattering (recomputed when the camera moves).
    bool pointSpecular = false;
    float pointSpecularRoughness = 0.3f;
    bool pointSingleScattering = false;
    // The object's material and size (files made with prt-precompute --editable; the
    // panel's "material" section). Only edits the basis covers get here: eta is the
    // file's, sizeMm > 0. Both the environment's relight and the point lights use them.
    Material material;
    double sizeMm = 0.0;
    std::string materialError;          // the last refused edit (shown until one is applied)
    bool materialByAppearance = false;  // the panel edits diffuse colour + mean free path
    bool showPanel = true;
    bool screenshotRequested = false;   // F12, P or the panel's button; taken by the next frame
};

// Bounds of what the keys and drags change.
struct ViewLimits {
    int environments = 1;       // how many maps N and B cycle through
    int maxLightTerms = 0;      // 6 N^2 of the transport file's cubemap
    Camera home;                // what R returns to (keeping the current image size)
    double objectRadius = 0.0;  // the bounding sphere's, mm: zooming in stops at 1e-3 of it
};

// `degrees` in (-180, 180].
inline double wrapDegrees(double degrees) {
    degrees = std::fmod(degrees, 360.0);
    if (degrees > 180.0) degrees -= 360.0;
    if (degrees <= -180.0) degrees += 360.0;
    return degrees;
}

// Count, sum, minimum and maximum of a series of times (ms).
struct RunningStats {
    size_t count = 0;
    double sum = 0.0, min = 0.0, max = 0.0;
    void add(double v) {
        min = count ? std::min(min, v) : v;
        max = count ? std::max(max, v) : v;
        sum += v;
        ++count;
    }
    double mean() const { return count ? sum / double(count) : 0.0; }
};

}  // namespace prt
