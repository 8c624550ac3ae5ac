#pragma once
// The viewer's relight worker (prt-relight view, docs/viewer.md): light vector
// (relight/prt/light_vector.h) + relight kernel (relight/prt/relight_kernel.h) on a
// thread of its own (latest_request_worker.h: the latest request wins, results are
// triple-buffered, take() rethrows a failure as prt::Error("relight", ...)).
//
// Material edits (files made with prt-precompute --editable; relight/prt/
// editable_transport.h; docs/viewer.md, "Material"). A request may carry the object's
// material and size; when they differ from the ones the worker holds, the worker makes
// them the object's, by the cheapest correct path:
//   - the light changed too (or the object has no multiple scattering selected): the
//     multiple-scattering component is recombined for the new material, then the
//     frame is relit as for any file;
//   - the light stands still: the light is projected onto the profiles once per light
//     (EditableTransport::projectLight, about the cost of one recombination) and each
//     edit is relightProjected (J multiply-adds per vertex and channel), added to the
//     cached single-scattering part (which no edit changes). The recombination is
//     deferred, so a slider drag pays for one projection and then only for the weights:
//     it runs as a job once no request waits (recombineWhileIdle), giving way to the
//     next request if one comes (then the next change of light recombines first).
// Both paths give the same radiance up to the 16-bit quantization of the recombined
// component (editable_transport.h). With a material map (RelightObject::materialMap) the
// multiple scattering is blended per vertex with the map's material B, relit once per
// light; B keeps the size it was loaded at when the size is edited live. A material the basis does not cover (or an invalid
// one) is not applied: the result carries the one-line message and the previous
// material's radiance.
//
// Ownership: while the worker exists it owns `object.transport.components` and
// `object.editable` (it changes them on its thread); other threads may read only what no
// edit changes: the mesh, the bounds, eta, transport.cubemapSize and viewMaps, and
// editable->basis(), fileMaterial() and objectSizeMm(). The object and the environments
// must outlive the worker.

#include <glm/glm.hpp>

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "common/image.h"
#include "common/materials.h"
#include "relight/prt/light_vector.h"
#include "relight/prt/relight_kernel.h"
#include "relight/prt/relight_object.h"
#include "relight/viewer/latest_request_worker.h"

namespace prt {

struct LightRequest {
    int environment = 0;
    double rotation = 0.0;  // degrees about +Y
    size_t lightTerms = 0;
    bool multipleScattering = true, singleScattering = true;
    // Editable files: the object's material (eta is the file's whatever this says) and
    // size in mm; nullopt keeps the worker's current one.
    std::optional<Material> material;
    double sizeMm = 0.0;
    uint64_t id = 0;

    bool sameLight(const LightRequest& o) const {
        return environment == o.environment && rotation == o.rotation && lightTerms == o.lightTerms &&
               multipleScattering == o.multipleScattering && singleScattering == o.singleScattering;
    }
    // Coefficients (sigma_a, sigma_s', g) and size equal; the name and eta are ignored.
    bool sameMaterial(const LightRequest& o) const;
};

struct LightResult {
    LightRequest request;
    VertexRadiance radiance;
    // What the GPU gets: diffuse then each term, one RGBA (A unused) per vertex, so
    // (1 + K) V entries (K = 0 without view-dependent single scattering).
    std::vector<glm::vec4> packed;
    // The ground's per-vertex radiance under the same light (RelightObject::ground;
    // empty without a ground).
    std::vector<glm::vec3> ground;
    size_t keptTerms = 0, coefficients = 0;
    double relativeL2Error = 0.0;
    double lightMs = 0.0, relightMs = 0.0;

    // The material edit this request made (all 0 / false when none).
    enum class EditPath { None, Recombined, Projected };
    EditPath editPath = EditPath::None;
    double recombineMs = 0.0;  // EditableTransport::recombine (included in relightMs)
    double projectMs = 0.0;    // projectLight, once per light (included in relightMs)
    double editMs = 0.0;       // the edit from request to radiance (weights, recombine or
                               // projection, relight), before packing
    // Editable files: the material and size the radiance shows (the previous ones when
    // the request's were refused, with the reason in materialError).
    std::optional<Material> material;
    double sizeMm = 0.0;
    std::string materialError;
};

class RelightWorker {
public:
    RelightWorker(RelightObject& object, const std::vector<Image>& environments);

    void submit(const LightRequest& r) { worker_.submit(r); }
    // A request queued or running.
    bool busy() const { return worker_.busy(); }
    // Recombinations done while idle so far (recombineWhileIdle), from any thread.
    size_t backgroundRecombines() const { return backgroundRecombines_.load(); }
    // Swaps the newest finished result into `out`; throws the worker's error, if any.
    bool take(LightResult& out) { return worker_.take(out); }

private:
    void compute(const LightRequest& r, LightResult& out);  // on the worker's thread
    // A job posted after an edit on the projected path: recombines the transport for the
    // current material while no request waits (EditableTransport::recombineUnless), so
    // that the next light change does not; gives way to a request that arrives.
    void recombineWhileIdle();
    // Sets out.radiance from ssOnly_ and msDiffuse_ (editable files).
    void combine(LightResult& out) const;

    RelightObject& object_;
    const TransportFile& file_;
    const std::vector<Image>& environments_;
    // The environment of the latest request, prepared for turning (EnvironmentLight;
    // docs/relight.md, "Turning the environment: the fast path"); a request for another
    // environment prepares that one.
    std::unique_ptr<EnvironmentLight> prepared_;
    int preparedEnvironment_ = -1;

    // Editable files: the last light and its radiance split into the part no edit
    // changes (single scattering, view terms included) and the multiple scattering.
    bool haveLight_ = false;
    LightRequest lastLight_;
    LightVector light_;
    VertexRadiance ssOnly_;
    std::vector<glm::vec3> msDiffuse_;
    std::vector<glm::vec3> ground_;  // the ground's radiance under the last light
    std::vector<glm::vec3> mapSecond_;  // with a material map: B's multiple scattering under it
    bool recombined_ = true;   // the transport's MS component is the editable's material
    bool projected_ = false;   // editable->projectLight(light_) is current
    std::atomic<size_t> backgroundRecombines_{0};  // recombinations recombineWhileIdle completed

    LatestRequestWorker<LightRequest, LightResult> worker_;  // last: its thread uses the members above
};

}  // namespace prt
