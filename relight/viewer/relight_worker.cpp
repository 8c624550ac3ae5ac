// The viewer's relight worker: see relight_worker.h.

#include "relight/viewer/relight_worker.h"

#include <algorithm>
#include <chrono>
#include <exception>
#include <memory>
#include <utility>

#include "common/envmap.h"
#include "common/error.h"
#include "relight/prt/light_vector.h"

namespace prt {

namespace {

using Clock = std::chrono::steady_clock;

double msSince(Clock::time_point t0) {
    return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

}  // namespace

bool RelightWorker::take(LightResult& out) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (!error_.empty()) throw Error("relight", error_);
    if (!haveReady_) return false;
    std::swap(out, ready_);
    haveReady_ = false;
    return true;
}

void RelightWorker::run() {
    for (;;) {
        LightRequest r;
        {
            std::unique_lock<std::mutex> lock(mutex_);
            cv_.wait(lock, [&] { return stop_ || pending_.has_value(); });
            if (stop_) return;
            r = *pending_;
            pending_.reset();
            running_ = true;
        }
        try {
            compute(r, work_);
            std::lock_guard<std::mutex> lock(mutex_);
            std::swap(work_, ready_);
            haveReady_ = true;
            running_ = false;
        } catch (const std::exception& e) {
            std::lock_guard<std::mutex> lock(mutex_);
            error_ = e.what();
            running_ = false;
            return;
        }
    }
}

void RelightWorker::compute(const LightRequest& r, LightResult& out) {
    out.request = r;
    auto t0 = Clock::now();
    if (!prepared_ || preparedEnvironment_ != r.environment) {
        prepared_.reset();  // free the old one before building the new one
        prepared_ = std::make_unique<EnvironmentLight>(environments_.at(size_t(r.environment)),
                                                       int(file_.cubemapSize));
        preparedEnvironment_ = r.environment;
    }
    const LightVector light = prepared_->lightVector(rotationY(r.rotation), r.lightTerms);
    out.lightMs = msSince(t0);
    out.keptTerms = light.keptTerms;
    out.coefficients = light.coefficientCount();
    out.relativeL2Error = light.relativeL2Error;
    t0 = Clock::now();
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
    out.relightMs = msSince(t0);
}

}  // namespace prt
