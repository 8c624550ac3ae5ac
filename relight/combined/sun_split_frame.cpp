#include "relight/combined/sun_split_frame.h"

#include <cstdio>

#include "common/error.h"
#include "common/util.h"

namespace prt {

Material sunSplitMaterial(const RelightObject& object, const std::string& transportPath) {
    if (object.ground)
        throw Error(transportPath,
                    "the sun split does not support a ground yet (the ground's transport still needs the sun)");
    if (object.materialMap)
        throw Error(transportPath, "the sun split does not support a material map yet");
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

SunSplitFrameRenderer::SunSplitFrameRenderer(const RelightObject& object, Image environment,
                                             const FrameSettings& look, const ScatteringComponents& components,
                                             const SunSplitOptions& options, const std::string& transportPath,
                                             bool sequence, PointMethod method)
    : object_(object),
      components_(components),
      material_(sunSplitMaterial(object, transportPath)),
      split_(splitSun(environment, options)),
      environment_(object, std::move(environment), look, components, sequence, std::move(split_.residual)),
      scene_(object.mesh),
      placed_(faceCentroidSamples(object.mesh)) {
    split_.residual = Image();
    if (method == PointMethod::TextureSpace)
        throw Error("--sun-method", "must be jb, cache or brute (texture-space sampling is the viewer's)");
    settings_.material = material_;
    settings_.method = method;
    settings_.baseColour = object.baseColour.enabled() ? &object.baseColour : nullptr;
    settings_.surface.singleScattering = components.singleScattering;
    if (components_.multipleScattering) cells_ = nearFieldCells(object.mesh, placed_, settings_);
}

std::string SunSplitFrameRenderer::describe() const {
    char line[256];
    std::snprintf(line, sizeof line,
                  "sun split: %zu directional lights (%zu texels above %.4g = %g x the mean luminance, cells of %d "
                  "texels) carry %.1f%% of the light; %s over %zu face centroids",
                  split_.lights.size(), split_.texelsAbove, split_.thresholdLuminance,
                  split_.meanLuminance > 0 ? split_.thresholdLuminance / split_.meanLuminance : 0.0,
                  split_.cellTexels, 100.0 * split_.lightFraction,
                  settings_.method == PointMethod::Cache   ? "the irradiance cache"
                  : settings_.method == PointMethod::Brute ? "the brute-force sum"
                                                           : "Jensen-Buhler",
                  placed_.size());
    return line;
}

Image SunSplitFrameRenderer::render(const Camera& camera, const glm::dmat3& rotation, SunSplitFrameTimes* times) {
    SunSplitFrameTimes t;
    Image image = environment_.render(camera, rotation, &t.environment);
    t.lights = split_.lights.size();
    if (!split_.lights.empty()) {
        const std::vector<Light> lights = rotatedLights(split_.lights, rotation);
        const GBuffer& g = environment_.gbuffer();
        if (components_.multipleScattering) {
            const LitSamples lit = lightSamples(placed_, scene_, lights, settings_);
            t.lightsIrradiance = 1000.0 * (lit.irradianceSeconds + lit.octreeSeconds);
            const PointFrame frame = renderPointFrame(*lit.tree, g, settings_, false, cells_);
            t.lightsDiffusion = 1000.0 * frame.renderSeconds;
            if (frame.image.width != image.width || frame.image.height != image.height || frame.image.channels < 3)
                throw Error("sun split", "the lights' frame differs in size from the environment's");
            const size_t n = size_t(image.width) * size_t(image.height);
            const size_t a = size_t(image.channels), b = size_t(frame.image.channels);
            for (size_t i = 0; i < n; ++i)
                for (size_t c = 0; c < 3; ++c) image.pixels[i * a + c] += frame.image.pixels[i * b + c];
        }
        if (components_.singleScattering) {
            const SurfaceTerms terms = renderSurfaceTerms(g, object_.mesh, scene_, lights, settings_.material,
                                                          settings_.surface, settings_.baseColour);
            t.lightsSingleScattering = 1000.0 * terms.seconds();
            addSurfaceTerms(image, terms);
        }
    }
    if (times) *times = t;
    return image;
}

}  // namespace prt
