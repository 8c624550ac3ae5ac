#pragma once
// One frame of a relit object under an environment, exactly as `prt-relight render`
// writes it (docs/relight.md): light vector -> per-vertex relight -> primary rays ->
// per-pixel shading (+ the optional specular layer) composed over the environment.
// The command line and the Python module both render through this class, so their
// images are the same bit for bit for the same arguments.
//
// Frames: the object in mm (RelightObject), the environment rotated by `rotation`
// (envmap.h's convention: the world sees L(R^T d)). The image is RGBA float, linear;
// object pixels have A = 1, background pixels the environment and A = 0. With a ground
// (RelightObject::ground) its pixels are shaded by ground_receiver.h and have A = 1 too.

#include <glm/glm.hpp>

#include <memory>
#include <optional>

#include "common/camera.h"
#include "common/image.h"
#include "common/raytrace.h"
#include "common/transport_params.h"
#include "relight/prt/frame_settings.h"
#include "relight/prt/light_vector.h"
#include "relight/prt/relight_kernel.h"
#include "relight/prt/relight_object.h"
#include "relight/prt/translucent_shader.h"
#include "relight/render/gbuffer.h"

namespace prt {

// Milliseconds of each stage of the last frame.
struct EnvironmentFrameTimes {
    double light = 0, relight = 0, rays = 0, shade = 0;
    size_t lightTerms = 0;          // the light vector's kept terms
    double lightRelativeL2 = 0;     // its approximation error (Parseval)
    size_t objectPixels = 0;
};

class EnvironmentFrameRenderer {
public:
    // `object` must outlive the renderer (the ray scene and the shader refer to its
    // mesh). `look` gives the light terms, the single-scattering path, the specular
    // layer and its blur; its material and rotation are not read here (the caller
    // applies the edit and passes the rotation per frame). `sequence` prepares the environment once for many
    // rotations (EnvironmentLight, the fast path of a turntable or a spin); a single
    // frame builds its light vector directly, as `render` does without a sequence.
    // `lighting`, when not empty, is what the light vector is made of instead of
    // `environment`, which stays the background and the specular layer's light (the sun
    // split's residual, relight/combined/sun_split_frame.h); the same size as `environment`.
    EnvironmentFrameRenderer(const RelightObject& object, Image environment, const FrameSettings& look,
                             const ScatteringComponents& components, bool sequence = false, Image lighting = {});

    // The frame seen by `camera` with the environment rotated by `rotation`. Primary
    // rays are traced again only when the camera changed since the last frame.
    Image render(const Camera& camera, const glm::dmat3& rotation, EnvironmentFrameTimes* times = nullptr);

    // The light vector this renderer would use for `rotation`.
    LightVector lightVector(const glm::dmat3& rotation) const;
    // The per-vertex radiance of the last frame.
    const VertexRadiance& vertexRadiance() const { return radiance_; }
    // The ground's per-vertex radiance of the last frame (empty without a ground).
    const VertexRadiance& groundVertexRadiance() const { return groundRadiance_; }
    const GBuffer& gbuffer() const { return gbuffer_; }

private:
    const RelightObject& object_;
    Image environment_;
    Image lighting_;  // empty: environment_
    const Image& lightingEnvironment() const { return lighting_.empty() ? environment_ : lighting_; }
    FrameSettings look_;
    ScatteringComponents components_;
    // What primary rays see: the object's mesh, or withGround(object, ground) when the
    // object has a ground (object triangles first, so the shader's indices hold).
    std::optional<TriangleMesh> objectAndGround_;
    const TriangleMesh& tracedMesh() const { return objectAndGround_ ? *objectAndGround_ : object_.mesh; }
    RayScene scene_;
    TranslucentShader shader_;
    Image prefiltered_;
    std::optional<EnvironmentLight> prepared_;
    GBuffer gbuffer_;
    std::optional<Camera> tracedCamera_;
    VertexRadiance radiance_;
    VertexRadiance groundRadiance_;
    VertexRadiance first_, second_;  // with a material map: A's and B's multiple scattering
};

}  // namespace prt
