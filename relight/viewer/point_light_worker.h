#pragma once
// The viewer's point-light worker (prt-relight view, docs/viewer.md): texture-space
// importance sampling (relight/pointlight/texture_space_sampling.h) on a thread of its
// own, beside the environment's relight worker (relight/viewer/relight_worker.h).
//
// What it computes: the point lights' radiance before the outgoing Fresnel factor at
// every mesh vertex, M_v / pi (W/(m^2 sr)), which the viewer ADDS to the environment's
// diffuse per-vertex radiance: the fragment shader multiplies the sum by
// F_t(eta, n . w_o), so a pixel shows exactly TextureSpaceRenderer::renderPerVertex's
// value plus the environment's (both are F_t times per-vertex radiance interpolated
// barycentrically).
// The surface terms, when asked for (vertex_surface_terms.h, prt-pointlight --evaluate
// vertex): single scattering's per-vertex term T, seen from the request's eye, is added
// to that radiance (the shader's F_t is its outgoing Fresnel factor; the base colour
// tints it with the diffusion); for the specular the worker hands over each light's
// shadowed irradiance at the vertices, and the shader evaluates the GGX lobe per pixel.
//
// Reuse: a request that changes only N or the seed redraws from the current irradiance
// map (no shadow rays); a new split mode rebuilds the renderer; new lights recompute
// the irradiance map, the draws and the shadow maps. A new material (sigma_a, sigma_s';
// a size edit is a material edit, common/material_edit.h scaledMaterial: the lights and
// the irradiance stay attached to the object) calls TextureSpaceRenderer::setMaterial
// on the existing renderer: R_p, the R_d tables and the local filter are rebuilt, the
// irradiance map, the draws and the shadow maps are kept, then the per-vertex sums run
// again. A material with another eta rebuilds the renderer (the transmitted irradiance
// depends on eta), as a new split mode does. The sums run again only when the
// diffusion changed; the lights' vertex irradiance is traced again for new lights, and
// single scattering for new lights, a new material, a new eye or sample count (a camera
// move with single scattering on costs its rays, nothing else).
//
// On demand (compare()): the error of the point lights' diffusion in the frame a camera sees,
// with the current material (the last request's), against Jensen-Buhler (face-centroid samples, epsilon 0.05; docs/viewer.md, "Controls"):
// the per-vertex TSIS frame and the reference are rendered on this thread, after any
// pending request, and the RMSE of the displayed images (exposure and tone mapping as given) and the
// linear relative RMSE come back as one line of text.
//
// Contract as RelightWorker (latest_request_worker.h): submit() replaces a request not
// yet started; take() hands over the newest result and rethrows a worker failure as
// prt::Error("point lights", ...). The constructor validates the material, the options
// and the atlas size (prt::Error naming the option). The mesh must outlive the worker.
// The atlas and the ray scene are built on the worker thread when the first light
// arrives, so a viewer without point lights never builds them.

#include <glm/glm.hpp>

#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "common/camera.h"
#include "common/materials.h"
#include "common/mesh.h"
#include "common/tonemap.h"
#include "relight/pointlight/point_lights.h"
#include "relight/pointlight/point_single_scattering.h"
#include "relight/pointlight/texture_space_sampling.h"
#include "relight/viewer/latest_request_worker.h"

namespace prt {

struct PointLightRequest {
    std::vector<Light> lights;
    TextureSpaceMode mode = TextureSpaceMode::Hybrid;
    int samples = 900;
    uint64_t seed = 1;
    // The object's material at its current size (scaledMaterial(m, S / S_mesh) for a
    // size edit); nullopt: the material the worker was constructed with. An invalid
    // material makes the result carry the message, with no point-light radiance.
    std::optional<Material> material;
    // The surface terms, with their rays at the vertices (vertex_surface_terms.h): the
    // specular's per-light vertex irradiance (the shader evaluates the lobe per pixel)
    // and single scattering seen from `eye` (mm), added to the per-vertex radiance.
    bool specular = false;
    bool singleScattering = false;
    int singleScatteringSamples = PointSingleScatteringOptions{}.pathSamples;
    glm::dvec3 eye{0.0};
    uint64_t id = 0;

    bool sameLighting(const PointLightRequest& o) const;  // lights equal (type, position, direction, colour, cone)
    // Coefficients, eta and g equal (the name is ignored); both nullopt is the same.
    bool sameMaterial(const PointLightRequest& o) const;
    // The surface terms asked for alike (the eye only matters to single scattering).
    bool sameSurfaceTerms(const PointLightRequest& o) const;
    bool sameAs(const PointLightRequest& o) const {
        return sameLighting(o) && sameMaterial(o) && sameSurfaceTerms(o) && mode == o.mode && samples == o.samples &&
               seed == o.seed;
    }
};

struct PointLightResult {
    PointLightRequest request;
    std::vector<glm::vec3> radiance;  // per vertex, M / pi, plus single scattering's T when asked for
    // With the specular: each light's shadowed irradiance at the vertices, light l's
    // vertex v at l * V + v (vertexLightIrradiance); empty without it.
    std::vector<glm::vec3> lightIrradiance;
    double specularMs = 0.0, singleScatteringMs = 0.0;  // their rays, when this request ran them
    TextureSpaceTimings timings;      // of the last setLights (or redraw)
    double evaluationMs = 0.0;        // the per-vertex sums
    double totalMs = 0.0;             // everything this request needed
    bool lightsRecomputed = false;    // false: only the draws were redone
    bool materialChanged = false;     // setMaterial ran (or the renderer was rebuilt for a new eta)
    double materialMs = 0.0;          // setMaterial's time (tables, R_p, filter); 0 when none ran (a
                                      // rebuild for a new eta is in totalMs)
    Material material;                // the material of this result
    size_t uniqueSamples = 0;
    double rp = 0.0;                  // R_p, mm
    std::string message;              // why the lights gave nothing (a light inside the object, ...)
};

class PointLightWorker {
public:
    // base: the options every request starts from (its mode, samples and seed are
    // replaced by the request's). material: the one of requests without their own.
    // atlasSize: the irradiance map's resolution.
    PointLightWorker(const TriangleMesh& meshMm, const Material& material, const TextureSpaceOptions& base,
                     int atlasSize);
    PointLightWorker(const PointLightWorker&) = delete;
    PointLightWorker& operator=(const PointLightWorker&) = delete;

    void submit(const PointLightRequest& r) { worker_->submit(r); }
    // A request or comparison queued or running.
    bool busy() const { return worker_->busy(); }
    bool take(PointLightResult& out) { return worker_->take(out); }

    // Queues a comparison of the current lighting (the last request) seen by `camera`.
    void compare(const Camera& camera, const DisplayTransform& display);
    // The comparison's line of text once done.
    bool takeComparison(std::string& text);

    // Set once the atlas is built (for the panel; empty before the first light).
    std::string atlasSummary() const;

private:
    // On the worker's thread:
    void compute(const PointLightRequest& r, PointLightResult& out);
    void ensureAtlas();  // the ray scene and the atlas, built on the first light
    std::string runComparison(const Camera& camera, const DisplayTransform& display);

    const TriangleMesh& mesh_;
    Material material_;  // the constructor's: requests without a material use it
    TextureSpaceOptions base_;
    int atlasSize_;
    std::unique_ptr<RayScene> scene_;
    std::unique_ptr<SurfaceAtlas> atlas_;
    std::unique_ptr<TextureSpaceRenderer> renderer_;
    std::optional<PointLightRequest> current_;  // what renderer_ holds
    // What the last request computed, kept while its inputs stand: the per-vertex
    // diffusion M / pi, the lights' vertex irradiance and single scattering (empty: none).
    std::vector<glm::vec3> diffusion_, lightIrradiance_, singleScattering_;
    std::optional<PointLightRequest> singleScatteringFor_;  // the request singleScattering_ was made for

    mutable std::mutex textMutex_;  // guards the two texts below (written on the worker's thread)
    bool haveComparison_ = false;
    std::string comparison_, atlasSummary_;
    // Last: its thread uses the members above; started once the inputs are validated.
    std::optional<LatestRequestWorker<PointLightRequest, PointLightResult>> worker_;
};

}  // namespace prt
