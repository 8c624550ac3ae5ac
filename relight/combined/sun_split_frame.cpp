#include "relight/combined/sun_split_frame.h"

#include <cstdio>

#include <tbb/parallel_for.h>

#include "common/error.h"
#include "common/ground.h"
#include "common/material_edit.h"
#include "common/transport_params.h"
#include "common/util.h"

namespace prt {

Material sunSplitMaterial(const RelightObject& object, const std::string& transportPath) {
    const std::optional<Material> material = shownMaterial(object, transportPath);
    if (!material)
        throw Error(transportPath, "names no material (sigma_s_prime, sigma_a, eta): the sun split needs one");
    return *material;
}

PointMethod parseSunSplitMethod(const std::string& text) {
    if (text == "jb") return PointMethod::JensenBuhler;
    if (text == "cache") return PointMethod::Cache;
    if (text == "brute") return PointMethod::Brute;
    throw Error("--sun-method", "must be jb, cache or brute, got '" + text + "'");
}

PointRenderSettings sunSplitLightSettings(const RelightObject& object, const std::string& transportPath,
                                          const ScatteringComponents& components, PointMethod method) {
    if (method == PointMethod::TextureSpace)
        throw Error("--sun-method", "must be jb, cache or brute (texture-space sampling is the viewer's)");
    PointRenderSettings settings;
    settings.material = sunSplitMaterial(object, transportPath);
    settings.method = method;
    settings.baseColour = object.baseColour.enabled() ? &object.baseColour : nullptr;
    settings.surface.singleScattering = components.singleScattering;
    return settings;
}

SunSplitFrameRenderer::SunSplitFrameRenderer(const RelightObject& object, Image environment,
                                             const FrameSettings& look, const ScatteringComponents& components,
                                             const SunSplitOptions& options, const std::string& transportPath,
                                             bool sequence, PointMethod method)
    : object_(object),
      components_(components),
      settings_(sunSplitLightSettings(object, transportPath, components, method)),
      // The transport's single scattering keeps the file's material under an edit; so do the lights'.
      singleScatteringMaterial_(
          readTransportParameters(object.transport.parameters, transportPath).material.value_or(settings_.material)),
      split_(splitSun(environment, options)),
      environment_(object, std::move(environment), look, components, sequence, std::move(split_.residual)),
      objectAndGround_(object.ground ? std::optional<TriangleMesh>(withGround(object.mesh, object.ground->mesh))
                                     : std::nullopt),
      scene_(objectAndGround_ ? *objectAndGround_ : object.mesh),
      placed_(faceCentroidSamples(object.mesh)) {
    split_.residual = Image();
    if (components_.multipleScattering) cells_ = nearFieldCells(object.mesh, placed_, settings_);
    if (object.materialMap && components_.multipleScattering) {
        // B at the object's current size, as A (shownMaterial): a size edit is a material
        // edit at the placed mesh (material_edit.h).
        const EditableTransport& e = *object.editable;
        secondSettings_ = settings_;
        secondSettings_->material = scaledMaterial(object.materialMap->second, e.sizeMm() / e.objectSizeMm());
        secondCells_ = nearFieldCells(object.mesh, placed_, *secondSettings_);
    }
    if (object.ground && components_.singleScattering) objectScene_.emplace(object.mesh);
}

void SunSplitFrameRenderer::blendMaterialMapPixels(const GBuffer& g, const Image& second, Image& first) const {
    const MaterialMap& map = *object_.materialMap;
    const size_t a = size_t(first.channels), b = size_t(second.channels);
    for (size_t i = 0; i < g.pixels.size(); ++i) {
        const GBufferPixel& p = g.pixels[i];
        if (!p.hit) continue;
        const glm::uvec3 tri = object_.mesh.triangles[p.triangle];
        const float t = p.barycentric[0] * map.vertexT[tri[0]] + p.barycentric[1] * map.vertexT[tri[1]] +
                        p.barycentric[2] * map.vertexT[tri[2]];
        for (size_t c = 0; c < 3; ++c)
            first.pixels[i * a + c] = (1.0f - t) * first.pixels[i * a + c] + t * second.pixels[i * b + c];
    }
}

void SunSplitFrameRenderer::addGroundLight(const GBuffer& g, const std::vector<Light>& lights, Image& image) const {
    const GroundReceiver& ground = *object_.ground;
    const size_t objectTriangles = object_.mesh.triangleCount();
    const glm::vec3 up(0.0f, 1.0f, 0.0f);
    const size_t channels = size_t(image.channels);
    tbb::parallel_for(size_t(0), g.pixels.size(), [&](size_t i) {
        const GBufferPixel& p = g.pixels[i];
        // Seen from below, the plane's back receives nothing (groundRadiance).
        if (!p.hit || !isGroundTriangle(p.triangle, objectTriangles) || p.toViewer.y <= 0.0f) return;
        // eta 1: no interface, so the transmittance is 1 and this is the plain shadowed irradiance.
        const glm::dvec3 E = directIrradiance(scene_, lights, {p.position, up, up}, 1.0, FresnelModel::Exact);
        for (size_t c = 0; c < 3; ++c) image.pixels[i * channels + c] += float(ground.albedo[c] * E[c] / kPi);
    });
}

std::string SunSplitFrameRenderer::describe() const {
    char line[256];
    std::snprintf(line, sizeof line,
                  "sun split: %zu directional lights (%zu texels above %.4g = %g x the mean luminance, cells of %d "
                  "texels) carry %.1f%% of the light; --sun-method %s over %zu face centroids",
                  split_.lights.size(), split_.texelsAbove, split_.thresholdLuminance,
                  split_.meanLuminance > 0 ? split_.thresholdLuminance / split_.meanLuminance : 0.0,
                  split_.cellTexels, 100.0 * split_.lightFraction, toString(settings_.method), placed_.size());
    return line;
}

Image SunSplitFrameRenderer::render(const Camera& camera, const glm::dmat3& rotation, SunSplitFrameTimes* times) {
    SunSplitFrameTimes t;
    Image image = environment_.render(camera, rotation, &t.environment);
    t.lights = split_.lights.size();
    if (!split_.lights.empty()) {
        const std::vector<Light> lights = rotatedLights(split_.lights, rotation);
        const GBuffer& traced = environment_.gbuffer();
        // The point-light parts see the object's pixels only: ground pixels become misses.
        std::optional<GBuffer> objectOnly;
        if (object_.ground) {
            objectOnly = traced;
            for (GBufferPixel& p : objectOnly->pixels)
                if (p.hit && isGroundTriangle(p.triangle, object_.mesh.triangleCount())) p = GBufferPixel{};
        }
        const GBuffer& g = objectOnly ? *objectOnly : traced;
        if (components_.multipleScattering) {
            const LitSamples lit = lightSamples(placed_, scene_, lights, settings_);
            t.lightsIrradiance = 1000.0 * (lit.irradianceSeconds + lit.octreeSeconds);
            PointFrame frame = renderPointFrame(*lit.tree, g, settings_, false, cells_);
            if (secondSettings_) {
                // A material map: B's sum too, blended per pixel with t interpolated from
                // the vertices' t_v, as the transport's M_v = (1 - t_v) M_A + t_v M_B is.
                const PointFrame second = renderPointFrame(*lit.tree, g, *secondSettings_, false, secondCells_);
                frame.renderSeconds += second.renderSeconds;
                blendMaterialMapPixels(g, second.image, frame.image);
            }
            t.lightsDiffusion = 1000.0 * frame.renderSeconds;
            if (frame.image.width != image.width || frame.image.height != image.height || frame.image.channels < 3)
                throw Error("sun split", "the lights' frame differs in size from the environment's");
            const size_t n = size_t(image.width) * size_t(image.height);
            const size_t a = size_t(image.channels), b = size_t(frame.image.channels);
            for (size_t i = 0; i < n; ++i)
                for (size_t c = 0; c < 3; ++c) image.pixels[i * a + c] += frame.image.pixels[i * b + c];
        }
        if (components_.singleScattering) {
            // Its paths run inside the object and index the object's triangles: the object's scene.
            const SurfaceTerms terms = renderSurfaceTerms(g, object_.mesh, objectScene_ ? *objectScene_ : scene_,
                                                          lights, singleScatteringMaterial_,
                                                          settings_.surface, settings_.baseColour);
            t.lightsSingleScattering = 1000.0 * terms.seconds();
            addSurfaceTerms(image, terms);
        }
        if (object_.ground) {
            const Stopwatch clock;
            addGroundLight(traced, lights, image);
            t.lightsGround = clock.milliseconds();
        }
    }
    if (times) *times = t;
    return image;
}

}  // namespace prt
