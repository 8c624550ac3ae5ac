#include "relight/prt/environment_frame.h"

#include "common/error.h"
#include "common/util.h"
#include "relight/render/specular.h"

namespace prt {

EnvironmentFrameRenderer::EnvironmentFrameRenderer(const RelightObject& object, Image environment,
                                                   const FrameSettings& look,
                                                   const ScatteringComponents& components, bool sequence, Image lighting)
    : object_(object),
      environment_(std::move(environment)),
      lighting_(std::move(lighting)),
      look_(look),
      components_(components),
      objectAndGround_(object.ground ? std::optional<TriangleMesh>(withGround(object.mesh, object.ground->mesh))
                                     : std::nullopt),
      scene_(tracedMesh()),
      shader_(object.mesh, object.eta,
              components.singleScattering && object.transport.viewMaps ? &*object.transport.viewMaps : nullptr,
              EyePathTable(object.eta, parseSingleScatteringView(look.ssPath))) {
    if (look_.specular)
        prefiltered_ = prefilterEnvironment(environment_, specularBlurFactor(look_.specularBlur, environment_));
    if (!lighting_.empty() && (lighting_.width != environment_.width || lighting_.height != environment_.height ||
                               lighting_.channels != environment_.channels))
        throw Error("environment", "the lighting environment differs in size from the background");
    if (sequence) prepared_.emplace(lightingEnvironment(), int(object_.transport.cubemapSize));
}

LightVector EnvironmentFrameRenderer::lightVector(const glm::dmat3& rotation) const {
    return prepared_ ? prepared_->lightVector(rotation, look_.lightTerms)
                     : makeLightVector(lightingEnvironment(), int(object_.transport.cubemapSize), rotation, look_.lightTerms);
}

Image EnvironmentFrameRenderer::render(const Camera& camera, const glm::dmat3& rotation,
                                       EnvironmentFrameTimes* times) {
    EnvironmentFrameTimes t;
    Stopwatch clock;
    const LightVector light = lightVector(rotation);
    t.light = clock.milliseconds();
    t.lightTerms = light.keptTerms;
    t.lightRelativeL2 = light.relativeL2Error;

    clock.restart();
    if (object_.materialMap && components_.multipleScattering) {
        // Everything but multiple scattering, then A's and B's blended per vertex.
        relightVertices(object_.transport, light, {false, components_.singleScattering}, radiance_);
        relightVertices(object_.transport, light, {true, false}, first_);
        relightVertices(object_.materialMap->secondTransport, light, {true, false}, second_);
        blendMaterialMap(*object_.materialMap, first_.diffuse, second_.diffuse, radiance_);
    } else {
        relightVertices(object_.transport, light, components_, radiance_);
    }
    if (object_.ground) relightVertices(object_.ground->transport, light, {true, false}, groundRadiance_);
    t.relight = clock.milliseconds();

    clock.restart();
    if (!tracedCamera_ || !(*tracedCamera_ == camera)) {
        gbuffer_ = traceGBuffer(scene_, tracedMesh(), camera);
        tracedCamera_ = camera;
    }
    t.rays = clock.milliseconds();

    clock.restart();
    const size_t objectTriangles = object_.mesh.triangleCount();
    Image image = compose(gbuffer_, environment_, rotation, [&](const GBufferPixel& p) {
        if (isGroundTriangle(p.triangle, objectTriangles))
            return groundRadiance(*object_.ground, p, groundRadiance_, objectTriangles);
        glm::vec3 L = object_.baseColour.at(p) * shader_.shade(p, radiance_);
        if (look_.specular) L += specularReflection(p, object_.eta, prefiltered_, rotation);
        return L;
    });
    t.shade = clock.milliseconds();
    t.objectPixels = gbuffer_.objectPixels();
    if (times) *times = t;
    return image;
}

}  // namespace prt
