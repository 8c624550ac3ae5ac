// The viewer's relight worker: see relight_worker.h.

#include "relight/viewer/relight_worker.h"

#include <algorithm>
#include <memory>

#include "common/envmap.h"
#include "common/error.h"
#include "common/util.h"
#include "relight/prt/light_vector.h"

namespace prt {

bool LightRequest::sameMaterial(const LightRequest& o) const {
    if (material.has_value() != o.material.has_value()) return false;
    if (!material) return true;
    return material->sigmaA == o.material->sigmaA && material->sigmaSPrime == o.material->sigmaSPrime &&
           material->g == o.material->g && sizeMm == o.sizeMm;
}

RelightWorker::RelightWorker(RelightObject& object, const std::vector<Image>& environments)
    : object_(object),
      file_(object.transport),
      environments_(environments),
      worker_("relight", [this](const LightRequest& r, LightResult& out) { compute(r, out); }) {}

void RelightWorker::combine(LightResult& out) const {
    const size_t V = ssOnly_.diffuse.size();
    if (msDiffuse_.size() != V) throw Error("relight", "inconsistent vertex counts");
    out.radiance.diffuse = ssOnly_.diffuse;
    if (object_.materialMap && mapSecond_.size() == V)
        blendMaterialMap(*object_.materialMap, msDiffuse_, mapSecond_, out.radiance);
    else
        for (size_t v = 0; v < V; ++v) out.radiance.diffuse[v] += msDiffuse_[v];
    out.radiance.terms = ssOnly_.terms;
}

void RelightWorker::recombineWhileIdle() {
    if (recombined_ || !object_.editable) return;
    std::optional<TransportComponent> c = object_.editable->recombineUnless([this] { return worker_.requestPending(); });
    if (!c) return;  // a request came first; the next light change recombines
    for (TransportComponent& component : object_.transport.components)
        if (component.kind == ComponentKind::MultipleScattering) component = std::move(*c);
    recombined_ = true;
    ++backgroundRecombines_;
}

void RelightWorker::compute(const LightRequest& r, LightResult& out) {
    out.request = r;
    out.editPath = LightResult::EditPath::None;
    out.recombineMs = out.projectMs = out.editMs = 0.0;
    out.materialError.clear();
    out.material.reset();
    Stopwatch clock;
    const Stopwatch editClock;
    const bool editable = object_.editable.has_value();
    const bool lightChanged = !editable || !haveLight_ || !r.sameLight(lastLight_);

    // The material first: a refused one leaves the object as it was.
    bool materialChanged = false;
    if (editable && r.material) {
        EditableTransport& e = *object_.editable;
        const Material& m = *r.material;
        if (m.sigmaA != e.material().sigmaA || m.sigmaSPrime != e.material().sigmaSPrime || m.g != e.material().g ||
            r.sizeMm != e.sizeMm()) {
            try {
                e.setMaterial(m, r.sizeMm);
                materialChanged = true;
                recombined_ = false;
            } catch (const Error& err) {
                out.materialError = err.what();
            }
        }
    }
    const auto recombine = [&] {
        const Stopwatch t;
        for (TransportComponent& c : object_.transport.components)
            if (c.kind == ComponentKind::MultipleScattering) c = object_.editable->recombine();
        recombined_ = true;
        out.recombineMs += t.milliseconds();
    };
    const auto relightMs = [&](const LightVector& light) {
        VertexRadiance ms;
        relightVertices(file_, light, {.multipleScattering = true, .singleScattering = false}, ms);
        msDiffuse_ = std::move(ms.diffuse);
    };

    if (lightChanged) {
        if (!prepared_ || preparedEnvironment_ != r.environment) {
            prepared_.reset();  // free the old one before building the new one
            prepared_ = std::make_unique<EnvironmentLight>(environments_.at(size_t(r.environment)),
                                                           int(file_.cubemapSize));
            preparedEnvironment_ = r.environment;
        }
        LightVector light = prepared_->lightVector(rotationY(r.rotation), r.lightTerms);
        out.lightMs = clock.milliseconds();
        out.keptTerms = light.keptTerms;
        out.coefficients = light.coefficientCount();
        out.relativeL2Error = light.relativeL2Error;
        clock.restart();
        if (object_.ground) {
            VertexRadiance ground;
            relightVertices(object_.ground->transport, light, {true, false}, ground);
            ground_ = std::move(ground.diffuse);
        }
        if (!editable) {
            ScatteringComponents c;
            c.multipleScattering = r.multipleScattering;
            c.singleScattering = r.singleScattering;
            relightVertices(file_, light, c, out.radiance);
        } else {
            // Split into the part no edit changes and the multiple scattering, so that
            // the next edits under this light redo only the latter.
            if (!recombined_ && r.multipleScattering) recombine();
            relightVertices(file_, light, {.multipleScattering = false, .singleScattering = r.singleScattering},
                            ssOnly_);
            if (r.multipleScattering)
                relightMs(light);
            else
                msDiffuse_.assign(ssOnly_.diffuse.size(), glm::vec3(0.0f));
            mapSecond_.clear();
            if (object_.materialMap && r.multipleScattering) {  // B's multiple scattering under this light
                VertexRadiance second;
                relightVertices(object_.materialMap->secondTransport, light, {true, false}, second);
                mapSecond_ = std::move(second.diffuse);
            }
            combine(out);
            light_ = std::move(light);
            lastLight_ = r;
            haveLight_ = true;
            projected_ = false;
            if (materialChanged) out.editPath = LightResult::EditPath::Recombined;
        }
    } else {
        out.lightMs = 0.0;
        out.keptTerms = light_.keptTerms;
        out.coefficients = light_.coefficientCount();
        out.relativeL2Error = light_.relativeL2Error;
        if (materialChanged && r.multipleScattering) {
            EditableTransport& e = *object_.editable;
            if (!projected_) {
                const Stopwatch t;
                e.projectLight(light_);
                projected_ = true;
                out.projectMs = t.milliseconds();
            }
            e.relightProjected(msDiffuse_);
            out.editPath = LightResult::EditPath::Projected;
            // The next light change would recombine first: do it now, while no request
            // waits, giving way to the next one.
            if (!recombined_) worker_.post([this] { recombineWhileIdle(); });
        }
        combine(out);
    }
    out.ground = ground_;
    if (materialChanged) out.editMs = editClock.milliseconds();
    if (editable) {
        out.material = object_.editable->material();
        out.sizeMm = object_.editable->sizeMm();
    }

    const size_t V = out.radiance.diffuse.size();
    const int terms = file_.viewMaps ? std::min<int>(file_.viewMaps->terms, int(out.radiance.terms.size())) : 0;
    out.packed.resize((1 + size_t(terms)) * V);
    for (int k = 0; k <= terms; ++k) {
        const std::vector<glm::vec3>& src = k == 0 ? out.radiance.diffuse : out.radiance.terms[size_t(k - 1)];
        if (src.size() != V) throw Error("relight", "inconsistent vertex counts");
        glm::vec4* dst = &out.packed[size_t(k) * V];
        for (size_t v = 0; v < V; ++v) dst[v] = glm::vec4(src[v], 0.0f);
    }
    out.relightMs = clock.milliseconds();
}

}  // namespace prt
