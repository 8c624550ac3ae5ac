// The viewer's relight worker: see relight_worker.h.

#include "relight/viewer/relight_worker.h"

#include <algorithm>
#include <memory>

#include "common/envmap.h"
#include "common/error.h"
#include "common/util.h"
#include "relight/prt/light_vector.h"

namespace prt {

RelightWorker::RelightWorker(const TransportFile& file, const std::vector<Image>& environments)
    : file_(file),
      environments_(environments),
      worker_("relight", [this](const LightRequest& r, LightResult& out) { compute(r, out); }) {}

void RelightWorker::compute(const LightRequest& r, LightResult& out) {
    out.request = r;
    Stopwatch clock;
    if (!prepared_ || preparedEnvironment_ != r.environment) {
        prepared_.reset();  // free the old one before building the new one
        prepared_ = std::make_unique<EnvironmentLight>(environments_.at(size_t(r.environment)),
                                                       int(file_.cubemapSize));
        preparedEnvironment_ = r.environment;
    }
    const LightVector light = prepared_->lightVector(rotationY(r.rotation), r.lightTerms);
    out.lightMs = clock.milliseconds();
    out.keptTerms = light.keptTerms;
    out.coefficients = light.coefficientCount();
    out.relativeL2Error = light.relativeL2Error;
    clock.restart();
    ScatteringComponents c;
    c.multipleScattering = r.multipleScattering;
    c.singleScattering = r.singleScattering;
    relightVertices(file_, light, c, out.radiance);
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
