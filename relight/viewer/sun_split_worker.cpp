// The viewer's sun-split worker: see sun_split_worker.h.
#include "relight/viewer/sun_split_worker.h"

#include "common/envmap.h"
#include "common/error.h"
#include "common/util.h"

namespace prt {

SunSplitWorker::SunSplitWorker(const RelightObject& object, const std::vector<Image>& environments,
                               const SunSplitOptions& options, const std::string& transportPath,
                               int firstEnvironment)
    : environments_(environments) {
    // The refusals here, on the caller's thread, before the thread starts.
    lighting_ = std::make_unique<SunSplitVertexLighting>(object, environments_.at(size_t(firstEnvironment)), options,
                                                         transportPath);
    lightingEnvironment_ = firstEnvironment;
    worker_.emplace("sun split", [this](const SunSplitRequest& r, SunSplitResult& out) { compute(r, out); });
}

void SunSplitWorker::compute(const SunSplitRequest& r, SunSplitResult& out) {
    const Stopwatch clock;
    out.request = r;
    out.times = SunSplitVertexTimes{};
    if (lightingEnvironment_ != r.environment) {
        // From the copies the constructor made: nothing the relight worker edits is read here.
        lighting_->setEnvironment(environments_.at(size_t(r.environment)));
        lightingEnvironment_ = r.environment;
        last_.reset();
    }
    const glm::dmat3 rotation = rotationY(r.rotation);
    out.materialError.clear();
    bool materialKept = !last_ || last_->sameMaterial(r.material, r.sizeMm);
    if (r.material && (!last_ || !materialKept)) {
        try {
            lighting_->setMaterial(*r.material, r.sizeMm);
        } catch (const Error& e) {  // the relight worker refuses it too: no correction for it
            out.materialError = e.what();
            out.correction = VertexRadiance{};
            last_.reset();
            out.totalMs = clock.milliseconds();
            return;
        }
        materialKept = false;
    }
    const bool lightKept = last_ && materialKept &&
                           last_->sameLight(r.environment, r.rotation, r.lightTerms, r.multipleScattering,
                                            r.singleScattering);
    if (!lightKept) {
        VertexRadiance excess = lighting_->excessRelight(rotation, {r.multipleScattering, r.singleScattering},
                                                         r.lightTerms, &out.times);
        withoutSingleScattering_ = lighting_->lights(rotation, {r.multipleScattering, false}, r.eye, &out.times);
        if (excess.diffuse.size() == withoutSingleScattering_.size())
            for (size_t v = 0; v < excess.diffuse.size(); ++v) withoutSingleScattering_[v] -= excess.diffuse[v];
        terms_ = std::move(excess.terms);
        for (std::vector<glm::vec3>& term : terms_)
            for (glm::vec3& x : term) x = -x;
    }
    // The lights' single scattering depends on the lights and the eye only (the file's material).
    const bool singleScatteringKept = last_ && last_->environment == r.environment &&
                                      last_->rotation == r.rotation && r.eye == last_->eye &&
                                      !singleScattering_.empty();
    // A folded file's excess takes its single scattering with the multiple scattering.
    const bool lightsSingleScattering =
        r.singleScattering || (lighting_->foldedSingleScattering() && r.multipleScattering);
    if (lightsSingleScattering && !singleScatteringKept)
        singleScattering_ = lighting_->lights(rotation, {false, true}, r.eye, &out.times);
    else if (!lightsSingleScattering)
        singleScattering_.clear();
    out.correction.diffuse = withoutSingleScattering_;
    if (singleScattering_.size() == out.correction.diffuse.size())
        for (size_t v = 0; v < singleScattering_.size(); ++v) out.correction.diffuse[v] += singleScattering_[v];
    out.correction.terms = terms_;
    out.lights = lighting_->split().lights.size();
    out.lightFraction = lighting_->split().lightFraction;
    last_ = r;
    out.totalMs = clock.milliseconds();
}

}  // namespace prt
