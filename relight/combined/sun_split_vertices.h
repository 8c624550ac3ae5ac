#pragma once
// The sun split at the mesh's vertices (prt-relight view --sun-split; docs/viewer.md,
// "The sun split"): what turns the transport's per-vertex radiance under the WHOLE
// environment into the split's,
//
//   correction(v) = lights(v) - transport(excess)(v)
//   lights(v)     = M(x_v) / pi                      (Jensen-Buhler over face centroids
//                                                     lit by the lights, as
//                                                     sun_split_frame.h's; with
//                                                     multiple scattering)
//                 + T(v)                             (the lights' single scattering seen
//                                                     from the eye, vertex_surface_terms.h;
//                                                     with single scattering)
//   transport(excess) = relightVertices of the excess environment (the texels above the
//                   threshold, environment - residual), diffuse and view terms
//
// so that transport(environment) + correction = transport(residual) + lights, since the
// relight is linear in the light (exactly so when the light vector keeps every term:
// lightTerms 0; a largest-L cut of each light is not linear). The viewer adds it to the
// relight worker's result for the same environment and rotation, and its shader
// multiplies the sum by F_t(eta, n . w_o) and the base colour, as it does the
// transport's; the view terms' slots carry -transport(excess)'s terms.
//
// Editable files (prt-precompute --editable): setMaterial makes a material and size the
// lights' (scaled for the size, material_edit.h, as the point lights' in the viewer) and
// the excess's multiple scattering (its own copy of the profiles, relit on the projected
// path: EditableTransport::projectLight + relightProjected, equal to the recombined
// relight up to its 16-bit quantization). The lights' single scattering keeps the file's
// material, as the transport's does under an edit.
//
// What it does not do: the ground (its transport keeps the whole environment) and a
// material map (refused at construction with prt::Error(transportPath, ...)).
//
// A file with folded single scattering (prt-precompute --fold-ss): the excess's relight
// removes its single scattering with its multiple scattering, so the lights' single
// scattering goes with the multiple scattering (as render's split adds it).
//
// Threads: the calls run in parallel inside (TBB); one call at a time. The constructor
// reads the object's transport and editable state and copies what an edit changes (an
// editable file's profiles) and the components it relights, so for an editable file it
// must run before anything edits the object (the viewer's relight worker), and the
// object's transport may change afterwards; setEnvironment and the rest read only the
// copies and what no edit changes (the mesh). For other files the object's transport is
// read by every relight and must not change.

#include <glm/glm.hpp>

#include <optional>
#include <string>
#include <vector>

#include "common/image.h"
#include "common/raytrace.h"
#include "common/transport_params.h"
#include "relight/pointlight/environment_lights.h"
#include "relight/pointlight/point_animation.h"
#include "relight/prt/light_vector.h"
#include "relight/prt/relight_kernel.h"
#include "relight/prt/relight_object.h"

namespace prt {

struct SunSplitVertexTimes {
    double lightVector = 0;        // the excess's light vector (ms)
    double transport = 0;          // its relight (ms)
    double lightsIrradiance = 0;   // pass 1: the lights at the face centroids (ms)
    double lightsDiffusion = 0;    // the Jensen-Buhler sum at the vertices (ms)
    double lightsSingleScattering = 0;  // ms
    double total() const { return lightVector + transport + lightsIrradiance + lightsDiffusion + lightsSingleScattering; }
};

class SunSplitVertexLighting {
public:
    // `object` must outlive this and hold no material map or ground (prt::Error(
    // transportPath, ...)); it must name a material (sunSplitMaterial). Splits
    // `environment` (splitSun's errors for bad options).
    SunSplitVertexLighting(const RelightObject& object, const Image& environment, const SunSplitOptions& options,
                           const std::string& transportPath);

    // Splits another environment with the same options (the material is kept).
    void setEnvironment(const Image& environment);
    const SunSplit& split() const { return split_; }
    // The file's single scattering is folded into its multiple scattering.
    bool foldedSingleScattering() const { return folded_; }

    // Editable files: the material and size of the next corrections (their eta is the
    // file's). prt::Error for a file that is not editable, and EditableTransport's for a
    // material or size the basis does not cover (the current one is then kept).
    void setMaterial(const Material& material, double sizeMm);

    // The correction above for the environment turned by `rotation`, the components
    // shown and the light vector's kept terms (0: all), single scattering seen from `eye`
    // (mm). diffuse has one entry per vertex; terms as relightVertices gives the file's
    // view terms (empty without them or without single scattering). Not const for
    // editable files (the projected light is kept).
    VertexRadiance correction(const glm::dmat3& rotation, const ScatteringComponents& components, size_t lightTerms,
                              const glm::dvec3& eye, SunSplitVertexTimes* times = nullptr);

    // The correction's two parts, for callers that keep one while the other changes (the
    // viewer's worker redoes only the lights' single scattering when the eye moves):
    // transport(excess), diffuse and view terms (times: lightVector and transport) ...
    VertexRadiance excessRelight(const glm::dmat3& rotation, const ScatteringComponents& components,
                                 size_t lightTerms, SunSplitVertexTimes* times = nullptr);
    // ... and lights(v) (times: the lights' fields): the parts `components` names (a
    // caller of a folded file asks for single scattering with multiple scattering, as
    // correction() does).
    std::vector<glm::vec3> lights(const glm::dmat3& rotation, const ScatteringComponents& components,
                                  const glm::dvec3& eye, SunSplitVertexTimes* times = nullptr) const;

private:
    const RelightObject& object_;
    PointRenderSettings settings_;      // the lights' multiple scattering: the current material
    Material singleScatteringMaterial_;  // the file's
    SunSplitOptions options_;
    int cubemapSize_ = 0;
    bool folded_ = false;
    SunSplit split_;               // its residual dropped after the excess is made
    EnvironmentLight excess_;      // environment - residual, prepared for turning
    // Editable files: the profiles (a copy) and the components no edit changes (single
    // scattering), relit in place of the object's transport.
    std::optional<EditableTransport> editable_;
    std::optional<TransportFile> unedited_;
    RayScene scene_;
    IrradianceSamples placed_;
    std::optional<SampleCells> cells_;
};

}  // namespace prt
