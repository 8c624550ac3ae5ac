// The viewer's point-light worker: see point_light_worker.h.

#include "relight/viewer/point_light_worker.h"

#include <cstdio>
#include <utility>

#include "common/error.h"
#include "common/image_compare.h"
#include "common/util.h"
#include "relight/pointlight/jensen_buhler.h"
#include "relight/pointlight/vertex_surface_terms.h"
#include "relight/render/gbuffer.h"

namespace prt {

bool PointLightRequest::sameLighting(const PointLightRequest& o) const {
    if (lights.size() != o.lights.size()) return false;
    for (size_t i = 0; i < lights.size(); ++i) {
        const Light &a = lights[i], &b = o.lights[i];
        if (a.type != b.type || a.position != b.position || a.direction != b.direction || a.rgb != b.rgb ||
            a.innerDegrees != b.innerDegrees || a.outerDegrees != b.outerDegrees)
            return false;
    }
    return true;
}

bool PointLightRequest::sameSurfaceTerms(const PointLightRequest& o) const {
    if (specular != o.specular || singleScattering != o.singleScattering) return false;
    return !singleScattering || (singleScatteringSamples == o.singleScatteringSamples && eye == o.eye);
}

namespace {
// What renders the same: the name does not.
bool sameCoefficients(const Material& a, const Material& b) {
    return a.sigmaA == b.sigmaA && a.sigmaSPrime == b.sigmaSPrime && a.eta == b.eta && a.g == b.g;
}
}  // namespace

bool PointLightRequest::sameMaterial(const PointLightRequest& o) const {
    if (material.has_value() != o.material.has_value()) return false;
    return !material || sameCoefficients(*material, *o.material);
}

PointLightWorker::PointLightWorker(const TriangleMesh& meshMm, const Material& material,
                                   const TextureSpaceOptions& base, int atlasSize)
    : mesh_(meshMm), material_(material), base_(base), atlasSize_(atlasSize) {
    validateMaterial(material_);
    validateTextureSpaceOptions(base_);
    validateAtlasResolution(atlasSize_);
    worker_.emplace("point lights", [this](const PointLightRequest& r, PointLightResult& out) { compute(r, out); });
}

void PointLightWorker::compare(const Camera& camera, const DisplayTransform& display) {
    worker_->post([this, camera, display] {
        std::string text = runComparison(camera, display);
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
    out.materialChanged = false;
    out.materialMs = 0.0;
    out.message.clear();
    const Material material = r.material.value_or(material_);
    out.material = material;
    // No light, or lights that give nothing: black, and the next request starts afresh.
    out.lightIrradiance.clear();
    out.specularMs = out.singleScatteringMs = 0.0;
    auto nothing = [&] {
        out.radiance.assign(mesh_.vertexCount(), glm::vec3(0.0f));
        out.timings = {};
        out.evaluationMs = 0.0;
        out.uniqueSamples = 0;
        renderer_.reset();
        current_.reset();
        diffusion_.clear();
        lightIrradiance_.clear();
        singleScattering_.clear();
        singleScatteringFor_.reset();
        out.totalMs = total.milliseconds();
    };
    if (r.lights.empty()) return nothing();
    ensureAtlas();  // on the first light: a viewer without point lights never pays for it
    bool redrawn = true;  // the draws were redone (a new renderer, new lights, N or seed)
    const bool newLights = !current_ || !current_->sameLighting(r);
    try {
        validateMaterial(material);
        if (r.singleScattering) validatePointSingleScattering({.pathSamples = r.singleScatteringSamples});
        checkLightsOutside(*scene_, r.lights);
        // A new eta changes the transmitted irradiance: a new renderer, as a new mode.
        if (!renderer_ || !current_ || current_->mode != r.mode || renderer_->material().eta != material.eta) {
            out.materialChanged = renderer_ && !sameCoefficients(renderer_->material(), material);
            TextureSpaceOptions o = base_;
            o.mode = r.mode;
            o.samples = r.samples;
            o.seed = r.seed;
            renderer_.reset();  // the old one's memory first
            current_.reset();
            renderer_ = std::make_unique<TextureSpaceRenderer>(mesh_, *scene_, *atlas_, material, o);
            renderer_->setLights(r.lights);
            out.lightsRecomputed = true;
        } else {
            if (!sameCoefficients(renderer_->material(), material)) {
                renderer_->setMaterial(material);
                out.materialChanged = true;
                out.materialMs = 1e3 * renderer_->materialSeconds();
            }
            if (!current_->sameLighting(r)) {
                renderer_->redraw(r.samples, r.seed, /*drawNow=*/false);
                renderer_->setLights(r.lights);
                out.lightsRecomputed = true;
            } else if (r.samples != current_->samples || r.seed != current_->seed) {
                renderer_->redraw(r.samples, r.seed);
            } else {
                redrawn = false;  // a material change alone (or nothing): the draws stand
            }
        }
    } catch (const Error& e) {
        // A light the user dragged into the object (or too close for the shadow map),
        // or a material out of range: nothing from the point lights until it changes;
        // the viewer shows why.
        out.message = e.what();
        return nothing();
    }
    current_ = r;
    out.timings = renderer_->timings();
    if (!out.lightsRecomputed) out.timings.irradianceSeconds = out.timings.shadowMapSeconds = 0.0;
    if (!redrawn) out.timings.samplingSeconds = 0.0;
    // The sums again only when the diffusion changed (not for a camera move that only
    // single scattering sees).
    out.evaluationMs = 0.0;
    if (redrawn || out.lightsRecomputed || out.materialChanged || diffusion_.size() != mesh_.vertexCount()) {
        const Stopwatch eval;
        diffusion_ = renderer_->vertexExitance();
        const float invPi = float(1.0 / kPi);
        for (glm::vec3& v : diffusion_) v *= invPi;
        out.evaluationMs = eval.milliseconds();
    }
    out.radiance = diffusion_;
    if (r.specular) {
        if (newLights || lightIrradiance_.size() != r.lights.size() * mesh_.vertexCount()) {
            const Stopwatch t;
            lightIrradiance_ = vertexLightIrradiance(*scene_, mesh_, r.lights);
            out.specularMs = t.milliseconds();
        }
        out.lightIrradiance = lightIrradiance_;
    } else {
        lightIrradiance_.clear();  // made for lights that may change before it is asked for again
    }
    if (r.singleScattering) {
        const bool stale = !singleScatteringFor_ || !singleScatteringFor_->sameLighting(r) ||
                           !sameCoefficients(singleScatteringFor_->material.value_or(material_), material) ||
                           singleScatteringFor_->singleScatteringSamples != r.singleScatteringSamples ||
                           singleScatteringFor_->eye != r.eye;
        if (stale) {
            const Stopwatch t;
            singleScattering_ = vertexSingleScattering(*scene_, mesh_, r.lights, material, r.eye,
                                                       {.pathSamples = r.singleScatteringSamples});
            singleScatteringFor_ = r;
            out.singleScatteringMs = t.milliseconds();
        }
        for (size_t v = 0; v < out.radiance.size(); ++v) out.radiance[v] += singleScattering_[v];
    }
    out.uniqueSamples = renderer_->uniqueSamples();
    out.rp = renderer_->split().rp;
    out.totalMs = total.milliseconds();
}

std::string PointLightWorker::runComparison(const Camera& camera, const DisplayTransform& display) {
    if (!renderer_ || !current_) return "no point light to compare";
    const Stopwatch t;
    const GBuffer g = traceGBuffer(*scene_, mesh_, camera);
    const Image image = renderer_->renderPerVertex(g);
    IrradianceSamples faces = faceCentroidSamples(mesh_);
    // The current material: the renderer's (the last request's, size edits included).
    const Material& material = renderer_->material();
    computeIrradiance(faces, *scene_, current_->lights, material.eta, base_.fresnel);
    // The near field as prt-pointlight's default (--near-field auto, sample_cells.h).
    std::optional<SampleCells> cells;
    if (nearFieldNeedsCells(faces.totalArea(), faces.size(), material)) cells.emplace(mesh_, faces, material);
    const JensenBuhler jb(material, IrradianceOctree(faces), {.epsilon = 0.05, .fresnel = base_.fresnel},
                          std::move(cells));
    const Image ref = jb.render(g);
    const CompareResult c = compareImages(image, ref);
    char buf[512];
    std::snprintf(buf, sizeof buf,
                  "point lights (%s) vs Jensen-Buhler (eps 0.05, %zu faces): RMSE %.4f (displayed, exposure %.2g, %s), "
                  "relative RMSE %.3f; %.1f s",
                  material.name.c_str(), faces.size(), displayRmse(image, ref, display), display.exposureStops,
                  toneMapOperatorName(display.op), c.overall.relativeRmse, t.seconds());
    std::printf("%s\n", buf);
    std::fflush(stdout);
    return buf;
}

}  // namespace prt
