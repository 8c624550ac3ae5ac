#pragma once
// prt-pointlight's frames and animations (docs/point-lights.md, "Animation").
//
// ONE FRAME is pass 1 (lightSamples: the transmitted irradiance of the placed samples
// under the lights, and their octree), the G-buffer of the camera, then passes 2-3 of
// the irradiance cache or the Jensen-Buhler / brute-force sum (renderPointFrame).
// prt-pointlight's single render is exactly these calls, so an animation frame and a
// single render with the same camera and lights are the same image.
//
// THREE ANIMATIONS (renderAnimation), frames <prefix>_0000, _0001, ...:
//
//   turntable N   the object turns 360 degrees about the vertical (+Y) axis through
//                 its bounding-box centre, lights FIXED IN THE OBJECT'S FRAME; as in
//                 prt-relight render (gbuffer.h, turntableCamera) this is rendered as
//                 the camera orbiting by -360 k / N degrees, so frame k equals a single
//                 render from the orbited camera (for automatic framing: --azimuth
//                 decreased by 360 k / N, to float rounding).
//                 REUSED: the irradiance samples (positions, areas AND irradiance),
//                 their near-field cells (nearFieldCells) and their octree -- pass 1 depends on the lights and the surface only,
//                 and both are fixed in the object's frame. NOT reused: the G-buffer
//                 and the caches: caches live on the visible points of one frame
//                 (created in that frame's bottom-up scan order, with validity radii
//                 measured on that frame's surface points), and each frame sees other
//                 points.
//   light path    the FIRST light (a point or spot light; a spot keeps its axis) moves linearly from P0 (frame 0) to
//                 P1 (frame N-1): position = (1 - t) P0 + t P1, t = k / (N - 1), so the
//                 end frames are exactly P0 and P1. Its intensity stays as given; the
//                 other lights and the camera are fixed.
//                 REUSED: only the mesh, its ray scene (Embree BVH) and the sample
//                 positions / normals / areas and their near-field cells (they depend
//                 on the surface and the material alone), and
//                 the G-buffer, because the camera does not move (it depends on the
//                 camera and the mesh only). NOT reused: the irradiance (it depends on
//                 the light), hence the octree (its nodes store mean irradiance), and
//                 the caches (S, grad S and V are all sums of irradiance).
//   material path (Chang et al. 2008, Fig. 11 and "dynamic light and material
//                 properties"): the material and/or the object's size move linearly,
//                 t = k / (N - 1), N >= 2: the coefficients by lerpMaterial(A, B, t)
//                 and the size S_k = (1 - t) S_0 + t S_1 (mm) as a material,
//                 scaledMaterial(m_k, S_k / S_geometry) (common/material_edit.h, SIZE
//                 AS MATERIAL): the mesh stays at its placed size S_geometry, and the
//                 lights, the camera and the irradiance stay attached to the object.
//                 Frame 0 is exactly A at S_0, frame N-1 exactly B at S_1. Lights and
//                 camera are fixed.
//                 REUSED: everything that does not depend on sigma_a / sigma_s': the
//                 irradiance samples with their irradiance (eta is the same at every
//                 frame: the two ends must share it) and their octree, the G-buffer,
//                 and the renderer itself (PointFrameRenderer::setMaterial, or for
//                 tsis TextureSpaceRenderer::setMaterial, which keeps the atlas, the
//                 irradiance map, the draws and the shadow maps). NOT reused: the
//                 caches (S, grad S and the validity radii depend on the material), the
//                 near-field cells' quadrature (sample_cells.h), the R_d tables, R_p and
//                 the local filter (tsis).
//
// Every frame is computed from scratch apart from the reused items above, with the
// same code as a single render, so reuse changes times, never pixels (tested).

#include <glm/glm.hpp>

#include <functional>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "common/bssrdf.h"
#include "common/camera.h"
#include "common/image.h"
#include "common/mesh.h"
#include "relight/render/base_colour.h"
#include "common/raytrace.h"
#include "relight/pointlight/irradiance_cache.h"
#include "relight/pointlight/jensen_buhler.h"
#include "relight/pointlight/point_lights.h"
#include "relight/pointlight/point_single_scattering.h"
#include "relight/pointlight/point_specular.h"
#include "relight/pointlight/sample_cells.h"
#include "relight/pointlight/texture_space_sampling.h"
#include "relight/render/gbuffer.h"

namespace prt {

// TextureSpace (Chang et al. 2008) renders through TextureSpaceRenderer
// (texture_space_sampling.h), which needs a surface atlas: prt-pointlight calls it
// directly; renderPointFrame and renderAnimation refuse it, and its material path is
// renderTextureSpaceAnimation.
enum class PointMethod { Cache, JensenBuhler, Brute, TextureSpace };
const char* toString(PointMethod method);  // "cache", "jb", "brute", "tsis"
// "cache", "jb", "brute" or "tsis" (case-insensitive); prt::Error("--method", ...) otherwise.
PointMethod parsePointMethod(const std::string& text);

// The terms at the surface beside the translucent (diffusion) radiance, both off by
// default: the specular reflection (point_specular.h) and single scattering
// (point_single_scattering.h).
struct SurfaceTermSettings {
    bool specular = false;
    double specularRoughness = kDefaultSpecularRoughness;  // GGX alpha
    bool singleScattering = false;
    PointSingleScatteringOptions singleScatteringOptions{};
    // Rays at the vertices, interpolated (vertex_surface_terms.h): what the viewer draws,
    // for prt-pointlight --evaluate vertex; single scattering then is seen from `eye` (mm).
    bool perVertex = false;
    glm::dvec3 eye{0.0};
    bool any() const { return specular || singleScattering; }
};

struct PointRenderSettings {
    Material material;
    PointMethod method = PointMethod::Cache;
    FresnelModel fresnel = FresnelModel::Exact;
    int leafSize = 8;
    double epsilon = 0.05;  // the walk's (JB and cache); brute uses 0
    double a = IrradianceCacheOptions{}.a;
    double radius = 0.0;    // split-disk R, 0 = default
    SplitDiskModel splitDisk = SplitDiskModel::Paper;
    NearFieldRule nearField = NearFieldRule::Auto;  // sample_cells.h (JB, brute and the cache's S)
    const BaseColour* baseColour = nullptr;  // tints every frame's object pixels (base_colour.h); null: none
    SurfaceTermSettings surface{};           // added to every frame (addSurfaceTerms)
};

// The near field's cells of `placed` on `mesh` for settings.material, or none for the
// point rule (settings.nearField; Auto resolved by nearFieldNeedsCells). They depend on the samples' places and the
// material, never on the lights: one set serves every frame of a light path or turntable.
std::optional<SampleCells> nearFieldCells(const TriangleMesh& mesh, const IrradianceSamples& placed,
                                          const PointRenderSettings& settings);

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
// Passes 2-3 (or the JB / brute sum) for one lit tree, kept between frames whose
// material changes: the renderer (IrradianceCache or JensenBuhler) owns the tree, and
// setMaterial rebuilds only what depends on the material (irradiance_cache.h,
// jensen_buhler.h). Throws prt::Error("--method", ...) for tsis.
class PointFrameRenderer {
public:
    // cells: nearFieldCells over the tree's samples (none: the point rule).
    PointFrameRenderer(IrradianceOctree tree, const PointRenderSettings& settings,
                       std::optional<SampleCells> cells = std::nullopt);
    // Throws prt::Error for an invalid material or another eta than settings.material's.
    void setMaterial(const Material& material);
    const Material& material() const { return settings_.material; }
    PointFrame render(const GBuffer& g, bool wantVisuals = false);

private:
    PointRenderSettings settings_;
    std::optional<IrradianceCache> cache_;
    std::optional<JensenBuhler> jb_;
};

// Passes 2-3 (or the JB / brute sum) over g, with a copy of `tree` (the renderers own
// theirs, and the caller's tree stays reusable): PointFrameRenderer(tree, settings).render.
PointFrame renderPointFrame(const IrradianceOctree& tree, const GBuffer& g, const PointRenderSettings& settings,
                            bool wantVisuals = false, const std::optional<SampleCells>& cells = std::nullopt);

// --- the surface terms -----------------------------------------------------------------

// A frame's specular and single-scattering radiance at g's pixels (RGB, W/(m^2 sr)):
//   radiance = baseColour(x_o) L^(1)(x_o, w_o) + L_s(x_o, w_o)
// the single scattering tinted by `colour` like the diffusion (when not null), the
// specular not (point_specular.h, point_single_scattering.h). `material` is the frame's
// (a material path's frame k: animationMaterial). Empty radiance when `settings` asks
// for neither; the seconds are each term's time.
struct SurfaceTerms {
    Image radiance;
    double specularSeconds = 0.0, singleScatteringSeconds = 0.0;
    double seconds() const { return specularSeconds + singleScatteringSeconds; }
};
SurfaceTerms renderSurfaceTerms(const GBuffer& g, const TriangleMesh& mesh, const RayScene& scene,
                                const std::vector<Light>& lights, const Material& material,
                                const SurfaceTermSettings& settings, const BaseColour* colour);
// Adds terms.radiance to the RGB of every pixel of `frame` (the translucent frame, its
// base colour already applied, of the same size): after the translucent radiance and its
// tint, so the specular stays untinted. Nothing when the radiance is empty, so a frame
// without the terms is exactly the translucent frame.
void addSurfaceTerms(Image& frame, const SurfaceTerms& terms);

// --- animation -----------------------------------------------------------------------

enum class AnimationKind { None, Turntable, LightPath, MaterialPath };

struct PointAnimation {
    AnimationKind kind = AnimationKind::None;
    int frames = 0;
    glm::dvec3 from{0.0}, to{0.0};  // LightPath: the first light at frame 0 and frame N-1, mm
    // MaterialPath: the materials at frame 0 and N-1 (none: the settings' material at
    // every frame) and the sizes S_0, S_1 in mm (none: the geometry's size at every
    // frame); at least one of the two. geometrySizeMm: the size the mesh is placed at
    // (prt-pointlight's --size-mm, or its bounding-box diagonal with --mm-per-unit).
    std::optional<std::pair<Material, Material>> materials{};
    std::optional<std::pair<double, double>> sizesMm{};
    double geometrySizeMm = 0.0;
};

// "X0,Y0,Z0:X1,Y1,Z1" (mm) -> from, to; prt::Error("--light-path", ...) otherwise.
void parseLightPath(const std::string& text, glm::dvec3& from, glm::dvec3& to);
// "S0:S1" (mm, finite and > 0) -> s0, s1; prt::Error("--size-path", ...) otherwise.
void parseSizePath(const std::string& text, double& s0, double& s1);
// frames >= 1 (>= 2 for a material path); a light path needs a point or spot light
// first in `lights` (a spot moves keeping its axis); a material path needs a material
// or a size path, sizes and the geometry's size finite and > 0, and the same eta at
// both ends. One-line errors naming
// --turntable / --frames / --light-path / --material-path / --size-path.
void validateAnimation(const PointAnimation& animation, const std::vector<Light>& lights);

// The frame's camera: turntableCamera(base, pivot, 360 k / N) for a turntable, base
// otherwise.
Camera animationCamera(const PointAnimation& animation, const Camera& base, const glm::dvec3& pivot, int frame);
double turntableDegrees(const PointAnimation& animation, int frame);
// The frame's lights: the first light moved along the path, the others unchanged.
std::vector<Light> animationLights(const PointAnimation& animation, const std::vector<Light>& lights, int frame);
// The frame's material: for a material path lerpMaterial(A, B, t) (or `base`), then
// with a size path scaledMaterial(., S_k / geometrySizeMm); `base` otherwise.
Material animationMaterial(const PointAnimation& animation, const Material& base, int frame);
// The frame's object size in mm: S_k with a size path, geometrySizeMm otherwise.
double animationSizeMm(const PointAnimation& animation, int frame);
// <prefix>_0000 ... (as prt-relight render's sequences).
std::string animationFrameName(const std::string& prefix, int frame);

struct AnimationFrameInfo {
    int frame = 0;
    Camera camera;
    std::vector<Light> lights;
    double irradianceSeconds = 0.0, octreeSeconds = 0.0;  // 0 when reused (turntable after frame 0)
    double gbufferSeconds = 0.0;                          // 0 when reused (light and material paths after frame 0)
    size_t hitPixels = 0;
    Material material;           // the frame's (animationMaterial)
    double sizeMm = 0.0;         // the frame's object size (animationSizeMm)
    double materialSeconds = 0.0;  // the renderer's setMaterial (material path; includes the cells' rebuild)
    double cellsSeconds = 0.0;     // nearFieldCells (frame 0 only)
    double surfaceSeconds = 0.0;   // renderSurfaceTerms (0 without --specular / --single-scattering)
};
using AnimationSink = std::function<void(const AnimationFrameInfo&, PointFrame&)>;

// Renders frames 0 .. N-1 in order, reusing what the header comment lists and nothing
// else (the surface terms of settings.surface are computed for every frame with its
// camera, lights and material), and hands each to sink (which writes it). Every frame's lights are checked to
// be outside the object (checkLightsOutside) before the first frame is rendered.
void renderAnimation(const PointAnimation& animation, const TriangleMesh& mesh, const RayScene& scene,
                     const IrradianceSamples& placed, const std::vector<Light>& lights, const Camera& baseCamera,
                     const glm::dvec3& pivot, const PointRenderSettings& settings, const AnimationSink& sink);

// --method tsis with a material path: `renderer` already lit (setLights: its irradiance
// map, draws and shadow maps are reused by every frame) and the G-buffer g of the fixed
// camera. Per frame: renderer.setMaterial(animationMaterial(animation, base, k)), then
// render (per pixel) or renderPerVertex; info.camera and info.lights are left empty
// (they are the caller's). Throws prt::Error("--method", ...) for any other kind.
void renderTextureSpaceAnimation(const PointAnimation& animation, TextureSpaceRenderer& renderer, const GBuffer& g,
                                 bool perVertex, const Material& base, const AnimationSink& sink);

}  // namespace prt
