// The viewer's point-light worker: see point_light_worker.h.

#include "relight/viewer/point_light_worker.h"

#include <cstdio>
#include <utility>

#include "common/error.h"
#include "common/image_compare.h"
#include "common/util.h"
#include "relight/pointlight/jensen_buhler.h"
#include "relight/render/gbuffer.h"

namespace prt {

bool PointLightRequest::sameLighting(const PointLightRequest& o) const {
    if (lights.size() != o.lights.size()) return false;
    for (size_t i = 0; i < lights.size(); ++i) {
        const Light &a = lights[i], &b = o.lights[i];
        if (a.type != b.type || a.position != b.position || a.direction != b.direction || a.rgb != b.rgb) return false;
    }
    return true;
}

PointLightWorker::PointLightWorker(const TriangleMesh& meshMm, const Material& material,
                                   const TextureSpaceOptions& base, int atlasSize)
    : mesh_(meshMm), material_(material), base_(base), atlasSize_(atlasSize) {
    validateMaterial(material_);
    validateTextureSpaceOptions(base_);
    validateAtlasResolution(atlasSize_);
    worker_.emplace("point lights", [this](const PointLightRequest& r, PointLightResult& out) { compute(r, out); });
}

void PointLightWorker::compare(const Camera& camera, double exposure) {
    worker_->post([this, camera, exposure] {
        std::string text = runComparison(camera, exposure);
        std::lock_guard<std::mutex> lock(textMutex_);
        comparison_ = std::move(text);
        haveComparison_ = true;
    });
}

bool PointLightWorker::takeComparison(std::string& text) {
    std::lock_guard<std::mutex> lock(textMutex_);
    if (!haveComparison_) return false;
    text = comparison_;
    haveComparison_ = false;
    return true;
}

std::string PointLightWorker::atlasSummary() const {
    std::lock_guard<std::mutex> lock(textMutex_);
    return atlasSummary_;
}

void PointLightWorker::ensureAtlas() {
    if (atlas_) return;
    scene_ = std::make_unique<RayScene>(mesh_);
    atlas_ = std::make_unique<SurfaceAtlas>(buildSurfaceAtlas(mesh_, atlasSize_));
    char buf[160];
    std::snprintf(buf, sizeof buf, "atlas %d^2: %.0f%% covered, %.1f texels per triangle, built in %.2f s",
                  atlas_->resolution, 100.0 * atlas_->stats.coverage, atlas_->stats.meanTexelsPerTriangle,
                  atlas_->stats.buildSeconds);
    std::lock_guard<std::mutex> lock(textMutex_);
    atlasSummary_ = buf;
}

void PointLightWorker::compute(const PointLightRequest& r, PointLightResult& out) {
    const Stopwatch total;
    out.request = r;
    out.lightsRecomputed = false;
    out.message.clear();
    // No light, or lights that give nothing: black, and the next request starts afresh.
    auto nothing = [&] {
        out.radiance.assign(mesh_.vertexCount(), glm::vec3(0.0f));
        out.timings = {};
        out.evaluationMs = 0.0;
        out.uniqueSamples = 0;
        renderer_.reset();
        current_.reset();
        out.totalMs = total.milliseconds();
    };
    if (r.lights.empty()) return nothing();
    ensureAtlas();  // on the first light: a viewer without point lights never pays for it
    try {
        checkLightsOutside(*scene_, r.lights);
        if (!renderer_ || !current_ || current_->mode != r.mode) {
            TextureSpaceOptions o = base_;
            o.mode = r.mode;
            o.samples = r.samples;
            o.seed = r.seed;
            renderer_ = std::make_unique<TextureSpaceRenderer>(mesh_, *scene_, *atlas_, material_, o);
            renderer_->setLights(r.lights);
            out.lightsRecomputed = true;
        } else if (!current_->sameLighting(r)) {
            renderer_->redraw(r.samples, r.seed, /*drawNow=*/false);
            renderer_->setLights(r.lights);
            out.lightsRecomputed = true;
        } else {
            renderer_->redraw(r.samples, r.seed);
        }
    } catch (const Error& e) {
        // A light the user dragged into the object (or too close for the shadow map):
        // nothing from the point lights until it moves; the viewer shows why.
        out.message = e.what();
        return nothing();
    }
    current_ = r;
    out.timings = renderer_->timings();
    if (!out.lightsRecomputed) out.timings.irradianceSeconds = out.timings.shadowMapSeconds = 0.0;
    const Stopwatch eval;
    std::vector<glm::vec3> m = renderer_->vertexExitance();
    const float invPi = float(1.0 / kPi);
    for (glm::vec3& v : m) v *= invPi;
    out.radiance = std::move(m);
    out.evaluationMs = eval.milliseconds();
    out.uniqueSamples = renderer_->uniqueSamples();
    out.rp = renderer_->split().rp;
    out.totalMs = total.milliseconds();
}

std::string PointLightWorker::runComparison(const Camera& camera, double exposure) {
    if (!renderer_ || !current_) return "no point light to compare";
    const Stopwatch t;
    const GBuffer g = traceGBuffer(*scene_, mesh_, camera);
    const Image image = renderer_->renderPerVertex(g);
    IrradianceSamples faces = faceCentroidSamples(mesh_);
    computeIrradiance(faces, *scene_, current_->lights, material_.eta, base_.fresnel);
    const JensenBuhler jb(material_, IrradianceOctree(faces), {.epsilon = 0.05, .fresnel = base_.fresnel});
    const Image ref = jb.render(g);
    const CompareResult c = compareImages(image, ref);
    char buf[256];
    std::snprintf(buf, sizeof buf,
                  "point lights vs Jensen-Buhler (eps 0.05, %zu faces): RMSE %.4f (displayed, exposure %.2g), "
                  "relative RMSE %.3f; %.1f s",
                  faces.size(), displayRmse(image, ref, exposure), exposure, c.overall.relativeRmse, t.seconds());
    std::printf("%s\n", buf);
    std::fflush(stdout);
    return buf;
}

}  // namespace prt
