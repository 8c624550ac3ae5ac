#pragma once
// The viewer's sun-split worker (prt-relight view --sun-split; docs/viewer.md, "The sun
// split"): SunSplitVertexLighting (relight/combined/sun_split_vertices.h) on a thread of
// its own, beside the relight worker. Per request (environment, rotation, light terms,
// components, eye) it computes the per-vertex correction that turns the relight
// worker's radiance under the whole environment into the split's: the lights' Jensen-
// Buhler exitance / pi and single scattering from the eye, minus the transport's relight
// of the excess. The viewer adds it to the relight worker's result only when both were
// made for the same light and material, so a frame is either the plain relight or the
// split, never one rotation's relight with another's lights. After a camera move the
// lights' single scattering of the previous eye stays on screen until the new one lands
// (as the point lights' does).
//
// Each environment is split when a request first asks for it (on the worker's thread,
// from the copies made at construction); the split of the latest environment is kept.
// The lights' single scattering depends on the lights and the eye: a camera move redoes
// it, and only it, when single scattering is shown (the lights' diffusion and the
// excess's relight are kept); toggling multiple scattering or the light terms keeps it.
//
// Contract as the other workers (latest_request_worker.h): submit() replaces a request
// not yet started; take() hands over the newest result and rethrows a failure as
// prt::Error("sun split", ...). The constructor refuses what SunSplitVertexLighting
// refuses (material maps, grounds, no material) by building the first
// environment's split, prt::Error naming the transport file. The object and the
// environments must outlive the worker; construct it before the relight worker, which
// changes an editable object's transport (SunSplitVertexLighting copies what it needs).
// An editable file's request carries the material and size; a new one redoes the
// lights' pass 1 and diffusion and the excess's relight, and keeps the lights' single
// scattering (the file's material, as the transport's under an edit).

#include <glm/glm.hpp>

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "common/image.h"
#include "common/materials.h"
#include "relight/combined/sun_split_vertices.h"
#include "relight/viewer/latest_request_worker.h"

namespace prt {

struct SunSplitRequest {
    int environment = 0;
    double rotation = 0.0;  // degrees about +Y, as LightRequest's
    size_t lightTerms = 0;
    bool multipleScattering = true, singleScattering = true;
    glm::dvec3 eye{0.0};    // mm: single scattering's viewpoint
    // Editable files: the material and size of the relight it goes with (nullopt: the
    // file's, and for other files).
    std::optional<Material> material;
    double sizeMm = 0.0;
    uint64_t id = 0;

    // Coefficients and size equal (LightRequest::sameMaterial's rule).
    bool sameMaterial(const std::optional<Material>& m, double size) const {
        if (material.has_value() != m.has_value()) return false;
        return !material || (material->sigmaA == m->sigmaA && material->sigmaSPrime == m->sigmaSPrime &&
                             material->g == m->g && sizeMm == size);
    }

    // The light alike: what must match the relight worker's result (LightRequest::sameLight).
    bool sameLight(int environment, double rotation, size_t lightTerms, bool ms, bool ss) const {
        return this->environment == environment && this->rotation == rotation && this->lightTerms == lightTerms &&
               multipleScattering == ms && singleScattering == ss;
    }
    bool sameAs(const SunSplitRequest& o) const {
        return o.sameLight(environment, rotation, lightTerms, multipleScattering, singleScattering) &&
               o.sameMaterial(material, sizeMm) && (!singleScattering || eye == o.eye);
    }
};

struct SunSplitResult {
    SunSplitRequest request;
    VertexRadiance correction;     // per vertex; terms as the file's view terms
    SunSplitVertexTimes times;     // of what this request computed
    double totalMs = 0.0;          // everything this request needed, the split included
    size_t lights = 0;
    double lightFraction = 0.0;    // the lights' share of the environment's light
    std::string materialError;     // a material the basis does not cover: no correction
};

class SunSplitWorker {
public:
    SunSplitWorker(const RelightObject& object, const std::vector<Image>& environments, const SunSplitOptions& options,
                   const std::string& transportPath, int firstEnvironment);
    SunSplitWorker(const SunSplitWorker&) = delete;
    SunSplitWorker& operator=(const SunSplitWorker&) = delete;

    void submit(const SunSplitRequest& r) { worker_->submit(r); }
    bool busy() const { return worker_->busy(); }
    bool take(SunSplitResult& out) { return worker_->take(out); }

private:
    void compute(const SunSplitRequest& r, SunSplitResult& out);  // on the worker's thread

    const std::vector<Image>& environments_;
    std::unique_ptr<SunSplitVertexLighting> lighting_;
    int lightingEnvironment_ = -1;
    // The last request's parts, kept while their inputs stand: the correction without
    // the lights' single scattering, and the lights' single scattering alone.
    std::optional<SunSplitRequest> last_;
    std::vector<glm::vec3> withoutSingleScattering_, singleScattering_;
    std::vector<std::vector<glm::vec3>> terms_;
    // Last: its thread uses the members above.
    std::optional<LatestRequestWorker<SunSplitRequest, SunSplitResult>> worker_;
};

}  // namespace prt
