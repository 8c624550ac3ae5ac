#pragma once
// One frame under an environment with the sun split (environment_lights.h; docs/relight.md,
// "The sun split"): the precomputed transport relights the residual environment, and
// the lights taken out of it (the sun, lamps) are rendered by the point-light path,
// exactly as prt-pointlight --method jb renders directional lights:
//
//   frame = EnvironmentFrameRenderer(background and specular: the environment;
//                                    light vector: the residual)
//         + Jensen-Buhler (or the irradiance cache) over face-centroid samples lit by
//           the lights turned with the environment (multiple scattering, when the
//           frame shows it)
//         + the lights' single scattering along the refracted view ray
//           (point_single_scattering.h, when the frame shows single scattering; with
//           the file's material, as the transport's single scattering under an edit)
//         + on a ground (RelightObject::ground), the lights' direct light on it:
//           albedo / pi sum_l E_l max(0, n . w_l) V_l per pixel, V_l a shadow ray
//           against the object (the ground's transport is direct light only too)
//
// the object's parts tinted by its base colour. Pass 1's shadow rays see the ground
// when there is one, as the object's precompute did. The three parts are linear in the light, so
// the sum is the frame of the whole environment up to each part's own error; the
// transport's truncation then only sees the residual, whose luminance is bounded.
//
// Frames, units and the image: as EnvironmentFrameRenderer (RGBA float, A = 1 on the
// object; the background is the whole environment). The material of the point-light
// parts is the object's shown material (shownMaterial: an editable file's edit
// included); the index of refraction the object's.
//
// A material map (material_map.h): the lights' sum is made for A and for B and blended
// per pixel with t interpolated from the vertices' t_v, as the transport's per-vertex
// blend is. Not supported (prt::Error naming the transport file): a file that names no
// material.

#include <glm/glm.hpp>

#include <optional>
#include <string>

#include "common/camera.h"
#include "common/image.h"
#include "common/raytrace.h"
#include "relight/pointlight/environment_lights.h"
#include "relight/pointlight/point_animation.h"
#include "relight/prt/environment_frame.h"

namespace prt {

struct SunSplitFrameTimes {
    EnvironmentFrameTimes environment;  // the residual's frame
    double lightsIrradiance = 0;        // pass 1: the lights at the samples (ms)
    double lightsDiffusion = 0;         // the Jensen-Buhler sum (ms)
    double lightsSingleScattering = 0;  // ms
    double lightsGround = 0;            // the ground's direct light (ms)
    size_t lights = 0;
};

// --sun-method: "jb", "cache" or "brute"; prt::Error("--sun-method", ...) otherwise.
PointMethod parseSunSplitMethod(const std::string& text);

// The object's shown material (shownMaterial), or prt::Error naming transportPath when
// the sun split cannot render the object (no material): the renderer's own check, for
// callers that must refuse before changing anything.
Material sunSplitMaterial(const RelightObject& object, const std::string& transportPath);

// The point-light path's settings for the lights, checked before anything is built: the
// shown material (sunSplitMaterial), `method` (prt::Error("--sun-method", ...) for
// TextureSpace), the object's base colour, single scattering when `components` shows it.
PointRenderSettings sunSplitLightSettings(const RelightObject& object, const std::string& transportPath,
                                          const ScatteringComponents& components, PointMethod method);

class SunSplitFrameRenderer {
public:
    // `object` must outlive the renderer. `look`, `components` and `sequence` as
    // EnvironmentFrameRenderer's; `transportPath` names the object's file in errors.
    // `method`: how the lights' multiple scattering is summed, JensenBuhler (the
    // default), Cache (Keng et al.'s irradiance cache over the same samples: faster, a
    // little less accurate) or Brute; TextureSpace is refused (prt::Error("--sun-method")).
    SunSplitFrameRenderer(const RelightObject& object, Image environment, const FrameSettings& look,
                          const ScatteringComponents& components, const SunSplitOptions& options,
                          const std::string& transportPath, bool sequence = false,
                          PointMethod method = PointMethod::JensenBuhler);

    // The frame seen by `camera` with the environment turned by `rotation`.
    Image render(const Camera& camera, const glm::dmat3& rotation, SunSplitFrameTimes* times = nullptr);

    // The split; its residual is moved into the renderer (empty here).
    const SunSplit& split() const { return split_; }
    // One line for the tools: the lights, their share of the light, the threshold.
    std::string describe() const;

private:
    const RelightObject& object_;
    ScatteringComponents components_;
    PointRenderSettings settings_;       // the lights': checked first, nothing is built for what is refused
    Material singleScatteringMaterial_;  // the file's: single scattering is not edited
    SunSplit split_;
    EnvironmentFrameRenderer environment_;
    std::optional<TriangleMesh> objectAndGround_;  // withGround(object, ground) when there is a ground
    RayScene scene_;                               // over objectAndGround_ or the object's mesh
    std::optional<RayScene> objectScene_;          // the object alone, for single scattering beside a ground
    IrradianceSamples placed_;
    std::optional<SampleCells> cells_;
    std::optional<PointRenderSettings> secondSettings_;  // a material map's B
    std::optional<SampleCells> secondCells_;

    // first = (1 - t) first + t second at g's object pixels, t interpolated from the map's t_v.
    void blendMaterialMapPixels(const GBuffer& g, const Image& second, Image& first) const;
    // The lights' direct light on the ground's pixels of g, added to image.
    void addGroundLight(const GBuffer& g, const std::vector<Light>& lights, Image& image) const;
};

}  // namespace prt
