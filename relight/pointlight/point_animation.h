#pragma once
// prt-pointlight's frames and animations (docs/point-lights.md, "Animation").
//
// ONE FRAME is pass 1 (lightSamples: the transmitted irradiance of the placed samples
// under the lights, and their octree), the G-buffer of the camera, then passes 2-3 of
// the irradiance cache or the Jensen-Buhler / brute-force sum (renderPointFrame).
// prt-pointlight's single render is exactly these calls, so an animation frame and a
// single render with the same camera and lights are the same image.
//
// TWO ANIMATIONS (renderAnimation), frames <prefix>_0000, _0001, ...:
//
//   turntable N   the object turns 360 degrees about the vertical (+Y) axis through
//                 its bounding-box centre, lights FIXED IN THE OBJECT'S FRAME; as in
//                 prt-relight render (gbuffer.h, turntableCamera) this is rendered as
//                 the camera orbiting by -360 k / N degrees, so frame k equals a single
//                 render from the orbited camera (for automatic framing: --azimuth
//                 decreased by 360 k / N, to float rounding).
//                 REUSED: the irradiance samples (positions, areas AND irradiance) and
//                 their octree -- pass 1 depends on the lights and the surface only,
//                 and both are fixed in the object's frame. NOT reused: the G-buffer
//                 and the caches: caches live on the visible points of one frame
//                 (created in that frame's bottom-up scan order, with validity radii
//                 measured on that frame's surface points), and each frame sees other
//                 points.
//   light path    the FIRST light (a point light) moves linearly from P0 (frame 0) to
//                 P1 (frame N-1): position = (1 - t) P0 + t P1, t = k / (N - 1), so the
//                 end frames are exactly P0 and P1. Its intensity stays as given; the
//                 other lights and the camera are fixed.
//                 REUSED: only the mesh, its ray scene (Embree BVH) and the sample
//                 positions / normals / areas (they depend on the surface alone), and
//                 the G-buffer, because the camera does not move (it depends on the
//                 camera and the mesh only). NOT reused: the irradiance (it depends on
//                 the light), hence the octree (its nodes store mean irradiance), and
//                 the caches (S, grad S and V are all sums of irradiance).
//
// Every frame is computed from scratch apart from the reused items above, with the
// same code as a single render, so reuse changes times, never pixels (tested).

#include <glm/glm.hpp>

#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "common/bssrdf.h"
#include "common/camera.h"
#include "common/image.h"
#include "common/mesh.h"
#include "common/raytrace.h"
#include "relight/pointlight/irradiance_cache.h"
#include "relight/pointlight/jensen_buhler.h"
#include "relight/pointlight/point_lights.h"
#include "relight/render/gbuffer.h"

namespace prt {

// TextureSpace (Chang et al. 2008) renders through TextureSpaceRenderer
// (texture_space_sampling.h), which needs a surface atlas: prt-pointlight calls it
// directly; renderPointFrame and the animations refuse it.
enum class PointMethod { Cache, JensenBuhler, Brute, TextureSpace };
const char* toString(PointMethod method);  // "cache", "jb", "brute", "tsis"
// "cache", "jb", "brute" or "tsis" (case-insensitive); prt::Error("--method", ...) otherwise.
PointMethod parsePointMethod(const std::string& text);

struct PointRenderSettings {
    Material material;
    PointMethod method = PointMethod::Cache;
    FresnelModel fresnel = FresnelModel::Exact;
    int leafSize = 8;
    double epsilon = 0.05;  // the walk's (JB and cache); brute uses 0
    double a = IrradianceCacheOptions{}.a;
    double radius = 0.0;    // split-disk R, 0 = default
    SplitDiskModel splitDisk = SplitDiskModel::Paper;
};

// Pass 1 for one set of lights: a copy of `placed` (positions, normals, areas) with its
// irradiance computed, and the octree over it.
struct LitSamples {
    IrradianceSamples samples;
    std::optional<IrradianceOctree> tree;
    double irradianceSeconds = 0.0, octreeSeconds = 0.0;
};
LitSamples lightSamples(const IrradianceSamples& placed, const RayScene& scene, const std::vector<Light>& lights,
                        const PointRenderSettings& settings);

struct PointFrame {
    Image image;
    double renderSeconds = 0.0;  // T_cache (passes 2 + 3) or T_JB / T_brute; excludes pass 1 and the G-buffer
    IrradianceCacheStats cacheStats;     // method cache
    std::vector<CacheRecord> caches;     // method cache
    CacheVisuals visuals;                // method cache with wantVisuals
    JensenBuhlerStats jbStats;           // methods jb and brute
};
// Passes 2-3 (or the JB / brute sum) over g, with a copy of `tree` (the renderers own
// theirs, and the caller's tree stays reusable).
PointFrame renderPointFrame(const IrradianceOctree& tree, const GBuffer& g, const PointRenderSettings& settings,
                            bool wantVisuals = false);

// --- animation -----------------------------------------------------------------------

enum class AnimationKind { None, Turntable, LightPath };

struct PointAnimation {
    AnimationKind kind = AnimationKind::None;
    int frames = 0;
    glm::dvec3 from{0.0}, to{0.0};  // LightPath: the first light at frame 0 and frame N-1, mm
};

// "X0,Y0,Z0:X1,Y1,Z1" (mm) -> from, to; prt::Error("--light-path", ...) otherwise.
void parseLightPath(const std::string& text, glm::dvec3& from, glm::dvec3& to);
// frames >= 1; a light path needs a point light first in `lights`. One-line errors
// naming --turntable / --frames / --light-path.
void validateAnimation(const PointAnimation& animation, const std::vector<Light>& lights);

// The frame's camera: turntableCamera(base, pivot, 360 k / N) for a turntable, base
// otherwise.
Camera animationCamera(const PointAnimation& animation, const Camera& base, const glm::dvec3& pivot, int frame);
double turntableDegrees(const PointAnimation& animation, int frame);
// The frame's lights: the first light moved along the path, the others unchanged.
std::vector<Light> animationLights(const PointAnimation& animation, const std::vector<Light>& lights, int frame);
// <prefix>_0000 ... (as prt-relight render's sequences).
std::string animationFrameName(const std::string& prefix, int frame);

struct AnimationFrameInfo {
    int frame = 0;
    Camera camera;
    std::vector<Light> lights;
    double irradianceSeconds = 0.0, octreeSeconds = 0.0;  // 0 when reused (turntable after frame 0)
    double gbufferSeconds = 0.0;                          // 0 when reused (light path after frame 0)
    size_t hitPixels = 0;
};
using AnimationSink = std::function<void(const AnimationFrameInfo&, PointFrame&)>;

// Renders frames 0 .. N-1 in order, reusing what the header comment lists and nothing
// else, and hands each to sink (which writes it). Every frame's lights are checked to
// be outside the object (checkLightsOutside) before the first frame is rendered.
void renderAnimation(const PointAnimation& animation, const TriangleMesh& mesh, const RayScene& scene,
                     const IrradianceSamples& placed, const std::vector<Light>& lights, const Camera& baseCamera,
                     const glm::dvec3& pivot, const PointRenderSettings& settings, const AnimationSink& sink);

}  // namespace prt
