#include "relight/combined/sun_split_vertices.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "common/error.h"
#include "common/material_edit.h"
#include "common/transport_params.h"
#include "common/util.h"
#include "relight/combined/sun_split_frame.h"
#include "relight/pointlight/jensen_buhler.h"
#include "relight/pointlight/vertex_surface_terms.h"

namespace prt {

namespace {

const RelightObject& checkedObject(const RelightObject& object, const std::string& transportPath) {
    const char* offline = " (prt-relight render --sun-split does)";
    if (object.materialMap)
        throw Error(transportPath, std::string("with a material map: the viewer's sun split does not blend one yet") +
                                       offline);
    if (object.ground)
        throw Error(transportPath, std::string("with a ground: the viewer's sun split does not light one yet") + offline);
    return object;
}

// environment - residual, texel by texel: what the lights carry.
Image excessOf(const Image& environment, const Image& residual) {
    Image excess = environment;
    for (size_t i = 0; i < excess.pixels.size(); ++i) excess.pixels[i] -= residual.pixels[i];
    return excess;
}

}  // namespace

SunSplitVertexLighting::SunSplitVertexLighting(const RelightObject& object, const Image& environment,
                                               const SunSplitOptions& options, const std::string& transportPath)
    : object_(checkedObject(object, transportPath)),
      settings_(sunSplitLightSettings(object, transportPath, ScatteringComponents::all(), PointMethod::JensenBuhler)),
      options_(options),
      cubemapSize_(int(object.transport.cubemapSize)),
      folded_(componentsOf(object.transport).folded),
      split_(splitSun(environment, options)),
      excess_(excessOf(environment, split_.residual), int(object.transport.cubemapSize)),
      scene_(object.mesh),
      placed_(faceCentroidSamples(object.mesh)) {
    split_.residual = Image();
    // The transport's single scattering keeps the file's material under an edit; so do the lights'.
    singleScatteringMaterial_ =
        readTransportParameters(object.transport.parameters, transportPath).material.value_or(settings_.material);
    if (object.editable) {
        editable_ = *object.editable;
        unedited_ = object.transport;
        std::erase_if(unedited_->components,
                      [](const TransportComponent& c) { return c.kind == ComponentKind::MultipleScattering; });
    }
    cells_ = nearFieldCells(object.mesh, placed_, settings_);
}

void SunSplitVertexLighting::setEnvironment(const Image& environment) {
    SunSplit split = splitSun(environment, options_);
    EnvironmentLight excess(excessOf(environment, split.residual), cubemapSize_);
    split.residual = Image();
    split_ = std::move(split);
    excess_ = std::move(excess);
}

void SunSplitVertexLighting::setMaterial(const Material& material, double sizeMm) {
    if (!editable_) throw Error("sun split", "the material of a file that is not editable cannot change");
    editable_->setMaterial(material, sizeMm);  // throws for what the basis does not cover
    settings_.material = scaledMaterial(editable_->material(), sizeMm / editable_->objectSizeMm());
    cells_ = nearFieldCells(object_.mesh, placed_, settings_);
}

std::vector<glm::vec3> SunSplitVertexLighting::lights(const glm::dmat3& rotation,
                                                      const ScatteringComponents& components, const glm::dvec3& eye,
                                                      SunSplitVertexTimes* times) const {
    const TriangleMesh& mesh = object_.mesh;
    std::vector<glm::vec3> out(mesh.vertexCount(), glm::vec3(0.0f));
    if (split_.lights.empty()) return out;
    const std::vector<Light> lights = rotatedLights(split_.lights, rotation);
    if (components.multipleScattering) {
        LitSamples lit = lightSamples(placed_, scene_, lights, settings_);
        if (times) times->lightsIrradiance = 1000.0 * (lit.irradianceSeconds + lit.octreeSeconds);
        const Stopwatch clock;
        const JensenBuhler jb(settings_.material, std::move(*lit.tree),
                              JensenBuhlerOptions{.epsilon = settings_.epsilon, .fresnel = settings_.fresnel}, cells_);
        tbb::parallel_for(tbb::blocked_range<size_t>(0, out.size(), 256), [&](const tbb::blocked_range<size_t>& r) {
            for (size_t v = r.begin(); v != r.end(); ++v)
                out[v] = glm::vec3(jb.exitance(glm::dvec3(mesh.positions[v])) / kPi);
        });
        if (times) times->lightsDiffusion = clock.milliseconds();
    }
    if (components.singleScattering) {
        const Stopwatch clock;
        const std::vector<glm::vec3> t = vertexSingleScattering(scene_, mesh, lights, singleScatteringMaterial_, eye,
                                                                settings_.surface.singleScatteringOptions);
        for (size_t v = 0; v < out.size(); ++v) out[v] += t[v];
        if (times) times->lightsSingleScattering = clock.milliseconds();
    }
    return out;
}

VertexRadiance SunSplitVertexLighting::excessRelight(const glm::dmat3& rotation,
                                                     const ScatteringComponents& components, size_t lightTerms,
                                                     SunSplitVertexTimes* times) {
    Stopwatch clock;
    const LightVector light = excess_.lightVector(rotation, lightTerms);
    if (times) times->lightVector = clock.milliseconds();
    clock.restart();
    VertexRadiance excess;
    if (!editable_) {
        relightVertices(object_.transport, light, components, excess);
    } else {
        // As the viewer's relight worker splits an editable file's relight: what no edit
        // changes, then the multiple scattering of the current material.
        relightVertices(*unedited_, light, {false, components.singleScattering}, excess);
        if (components.multipleScattering) {
            editable_->projectLight(light);
            std::vector<glm::vec3> ms;
            editable_->relightProjected(ms);
            if (excess.diffuse.size() != ms.size()) excess.diffuse.assign(ms.size(), glm::vec3(0.0f));
            for (size_t v = 0; v < ms.size(); ++v) excess.diffuse[v] += ms[v];
        }
    }
    if (times) times->transport = clock.milliseconds();
    return excess;
}

VertexRadiance SunSplitVertexLighting::correction(const glm::dmat3& rotation, const ScatteringComponents& components,
                                                  size_t lightTerms, const glm::dvec3& eye,
                                                  SunSplitVertexTimes* times) {
    SunSplitVertexTimes t;
    VertexRadiance excess = excessRelight(rotation, components, lightTerms, &t);
    VertexRadiance out;
    ScatteringComponents lit = components;
    if (folded_ && lit.multipleScattering) lit.singleScattering = true;  // removed with the excess's
    out.diffuse = lights(rotation, lit, eye, &t);
    if (excess.diffuse.size() == out.diffuse.size())
        for (size_t v = 0; v < out.diffuse.size(); ++v) out.diffuse[v] -= excess.diffuse[v];
    out.terms = std::move(excess.terms);
    for (std::vector<glm::vec3>& term : out.terms)
        for (glm::vec3& x : term) x = -x;
    if (times) *times = t;
    return out;
}

}  // namespace prt
