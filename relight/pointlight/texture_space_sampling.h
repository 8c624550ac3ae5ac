#pragma once
// Texture-space importance sampling for point and directional lights (Chang et al.
// 2008, sections 2.2-4; SPEC section 9; docs/point-lights.md), with the hybrid
// local/global split.
//
// PER LIGHTING (TextureSpaceRenderer::setLights, everything a new light position needs):
//   1. the irradiance map: at every covered texel t of the atlas (surface_atlas.h) the
//      transmitted direct irradiance E^(x_t) of all lights, shadowed (point_lights.h),
//      times the texel's surface area: the flux Phi_t = E^_t A_t (Eq. 7's E' times the
//      texel's texture area; RGB, W/m^2 mm^2);
//   2. N texels drawn with probability p_t = phi_t / sum phi (phi = mean of R, G, B of
//      Phi_t) by the mipmap-ordered inverse CDF (mipmap_sampler.h), stratified, the
//      jitter seeded by the frame's seed; each draw becomes a sample at x_t with weight
//      Phi_t / (N p_t) (per channel; equal draws of one texel are merged, which changes
//      nothing but the work);
//   3. for the local part (hybrid or local modes), one translucent shadow map per light
//      (translucent_shadow_map.h).
// PER POINT x (exitance):
//   M(x) = sum_i w_i K_s(|x - x_i|)      + sum_lights localFilter(x, K_l)
//          (the global part, Eq. 10)        (the local part, section 4.2)
// with the kernels of the mode: sampling: K_s = R_d, no local part; hybrid: K_s =
// R_d W_g, K_l = R_d W_l; global: K_s = R_d W_g only; local: K_l = R_d W_l only. Eq. 10
// is M = E'_avg / N sum R_d for white light; the per-channel weights generalise it to
// coloured lights with one sample set. Radiance: L = F_out(n . w_o) M / pi as
// jensen_buhler.h (exact Fresnel or Keng's).
//
// PER MATERIAL (the constructor and setMaterial): R_p (importanceRadius), the sample
// kernel's R_d table (R_d or R_d W_g) with, when theta > 0, its curvature tables (see
// CLUSTERS) and the local filter (its R_d W_l table, ring radii and tap weights). Nothing else depends on sigma_a or sigma_s': the atlas, the
// irradiance map, the pyramid and the draws (p_t is the irradiance's), and the shadow
// maps (they store transmitted flux, which depends on eta alone; their power
// normalisation is the atlas's power) are all REUSED by setMaterial, so a material
// change followed by a render equals a renderer built with that material and lit with
// the same lights, N and seed, bit for bit. eta is fixed at construction: the
// transmitted irradiance depends on it, so setMaterial refuses another eta
// (requireIrradianceEta, point_lights.h) rather than recomputing the irradiance; build
// a new renderer for a new eta. A size change is a material change
// (common/material_edit.h, scaledMaterial): the lights and the irradiance stay attached
// to the object.
//
// CLUSTERS. With theta = clusterAngle > 0 the samples are put in an octree after each
// draw (IrradianceOctree, jensen_buhler.h: a sample's "area" is its mean weight, so a
// node carries exactly the weight W of its samples at their weight-centred position
// c), and the global sum at a group of points (one pixel, or up to 16 Morton-ordered
// vertices inside a box B) uses a node whole when its cell's diagonal is below theta
// times the distance from B to the cell; other nodes are opened down to their samples.
// A node used whole adds its Taylor expansion about c to second order,
//     W_ch [K(r) + A(r) u^T S u + B(r) tr S]      (radialCurvature, diffusion_split.h)
// with S the weighted covariance of its samples' positions (the weights' mean over R,
// G, B; a node's colour is taken as uniform over it): the first order vanishes at c,
// and the second is the curvature a monopole would miss (it would fall short: the
// kernels are convex). What remains is third order in theta, bounded by the tests
// against theta = 0 (tests/test_texture_space_sampling.cpp). theta = 0 is the plain sum
// over every sample in draw order.
//
// EVALUATION. Per pixel of a G-buffer (render), or per mesh vertex then interpolated
// barycentrically at every pixel (renderPerVertex = shadeVertices of vertexExitance
// over the view's pixel list, VertexInterpolation: fewer sums when the mesh has fewer
// vertices than the frame has object pixels; exact at vertices, linear between).
//
// The reference is the Jensen-Buhler renderer at epsilon = 0 on the same irradiance
// definition; as N grows the sampling error falls like 1/sqrt(N) down to the floor of
// the atlas resolution (one point per texel) and the R_d table.
//
// Threads: setLights and the renders are parallel (TBB) and deterministic: the same
// seed gives the same image on any thread count.

#include <glm/glm.hpp>

#include <array>
#include <cstdint>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "common/bssrdf.h"
#include "common/image.h"
#include "common/mesh.h"
#include "common/raytrace.h"
#include "relight/pointlight/diffusion_split.h"
#include "relight/pointlight/jensen_buhler.h"
#include "relight/pointlight/mipmap_sampler.h"
#include "relight/pointlight/point_lights.h"
#include "relight/render/gbuffer.h"
#include "relight/pointlight/surface_atlas.h"
#include "relight/pointlight/translucent_shadow_map.h"

namespace prt {

// Defaults (docs/point-lights.md, "Clustered sums and the defaults"): theta of the
// clustered sums and the irradiance map's resolution (the surface atlas's).
inline constexpr double kDefaultClusterAngle = 1.2;
inline constexpr int kDefaultIrradianceMapSize = 256;

enum class TextureSpaceMode {
    Sampling,  // full R_d by the texture-space samples alone (section 3)
    Hybrid,    // local part by the filter + global part by the samples (section 4)
    Local,     // the local part alone
    Global,    // the global part alone
};
const char* toString(TextureSpaceMode mode);
// "sampling", "hybrid", "local", "global" (case-insensitive); prt::Error("--split", ...).
TextureSpaceMode parseTextureSpaceMode(const std::string& text);

struct TextureSpaceOptions {
    TextureSpaceMode mode = TextureSpaceMode::Hybrid;
    int samples = 3600;                // N, >= 1
    uint64_t seed = 1;                 // the frame's jitter seed
    bool jitter = true;                // stratified with jitter (false: centred strata)
    double importanceBound = kDefaultImportanceBound;  // c, mm^-1
    double sharpness = kDefaultSplitSharpness;         // K, mm^-1
    SplitWeights weights = SplitWeights::Paper;
    int lightMapSize = 256;            // translucent shadow map resolution (docs/point-lights.md)
    int rings = 32, ringSamples = 8;   // L, C
    FresnelModel fresnel = FresnelModel::Exact;
    // theta of the clustered global sum (see CLUSTERS above), >= 0; 0 sums every sample.
    double clusterAngle = kDefaultClusterAngle;
};

// Throws prt::Error naming the option for a bad value.
void validateTextureSpaceOptions(const TextureSpaceOptions& options);

// Weighted points the global sum runs over: positions (mm) as three arrays and weights
// as (R, G, B, 0): what the SIMD loop reads.
struct SampleTerms {
    std::vector<float> x, y, z;
    std::vector<glm::vec4> w;
    size_t size() const { return x.size(); }
    void clear();
    void push(const glm::vec3& position, const glm::vec3& weight);
};

// Clusters used whole (see CLUSTERS above): centre and weight as SampleTerms, and the
// covariance S (mm^2) as arrays: xx, yy, zz, xy, xz, yz and its trace.
struct ClusterTerms : SampleTerms {
    std::vector<float> sxx, syy, szz, sxy, sxz, syz, trace;
    void clear();
    void push(const glm::vec3& position, const glm::vec3& weight, const float covariance[6]);
};

// The terms of the global sum seen from one group of points (see CLUSTERS above): the
// samples of the opened leaves and the clusters used whole.
struct GroupTerms {
    SampleTerms samples;
    ClusterTerms clusters;
    size_t byteSize() const;
};

// The per-view half of shading per-vertex exitance (renderPerVertex), built once per
// G-buffer: every object pixel's index, its triangle's vertices, its barycentric
// weights and F_out(n . w_o) / pi (which depends on the view and eta only).
struct VertexInterpolation {
    int width = 0, height = 0;
    std::vector<uint32_t> pixel;
    std::vector<glm::uvec3> vertices;
    std::vector<glm::vec3> barycentric;
    std::vector<float> transmittanceOverPi;
};
VertexInterpolation vertexInterpolation(const GBuffer& g, const TriangleMesh& mesh, double eta, FresnelModel fresnel);

struct TextureSpaceTimings {
    double irradianceSeconds = 0.0;   // the irradiance map (shadow rays)
    double samplingSeconds = 0.0;     // pyramid + N draws + merging
    double shadowMapSeconds = 0.0;    // translucent shadow maps (local part)
    double lighting() const { return irradianceSeconds + samplingSeconds + shadowMapSeconds; }
};

class TextureSpaceRenderer {
public:
    // mesh (mm), scene and atlas must outlive the renderer. Validates the material and
    // the options; builds the R_d tables (rMax = the bounding sphere's diameter).
    TextureSpaceRenderer(const TriangleMesh& mesh, const RayScene& scene, const SurfaceAtlas& atlas,
                         const Material& material, const TextureSpaceOptions& options);

    // Everything that depends on the lights (see above). Throws prt::Error for an empty
    // light list or a light the shadow map cannot frame.
    void setLights(const std::vector<Light>& lights);
    // Rebuilds what depends on the material (see PER MATERIAL above) and keeps the
    // irradiance map, the draws and the shadow maps; may be called before or after
    // setLights. Throws prt::Error for an invalid material (validateMaterial) and
    // prt::Error("material", ...) for an eta other than the constructor's; the renderer
    // is unchanged when it throws.
    void setMaterial(const Material& material);
    // Changes only N / the seed and redraws from the current irradiance map (no new
    // shadow rays). drawNow = false only records them for the next setLights.
    void redraw(int samples, uint64_t seed, bool drawNow = true);

    glm::dvec3 exitance(const glm::dvec3& x) const;
    glm::vec3 radiance(const GBufferPixel& pixel) const;
    Image render(const GBuffer& g) const;
    // Exitance at every mesh vertex (positions of the mesh given at construction).
    std::vector<glm::vec3> vertexExitance() const;
    // The per-pixel shading of renderPerVertex: exitance m (one per mesh vertex)
    // interpolated barycentrically at every object pixel, times F_out / pi; RGBA, A = 1
    // on the object, black background with A = 0. `view` from vertexInterpolation with
    // this renderer's mesh, eta and Fresnel model.
    Image shadeVertices(const VertexInterpolation& view, const std::vector<glm::vec3>& m) const;
    // vertexInterpolation with this renderer's mesh, eta and Fresnel model (material
    // changes keep eta, so it serves every material of the renderer).
    VertexInterpolation interpolation(const GBuffer& g) const;
    Image renderPerVertex(const GBuffer& g) const;

    const Material& material() const { return material_; }
    // Wall time of the last setMaterial (s): the tables, R_p and the filter.
    double materialSeconds() const { return materialSeconds_; }
    const TextureSpaceOptions& options() const { return options_; }
    const DiffusionSplit& split() const { return split_; }
    const LocalFilter& localFilter() const { return filter_; }
    const TextureSpaceTimings& timings() const { return timings_; }
    // The current samples (after merging equal draws) and the map's total flux (mean RGB
    // is the pdf's normaliser).
    size_t uniqueSamples() const { return samples_.size(); }
    const SampleTerms& samples() const { return samples_; }
    // The table the global sum evaluates (R_d, or R_d W_g in the hybrid and global modes).
    const RadialTable& sampleKernel() const { return sampleKernel_; }
    glm::dvec3 totalFlux() const { return totalFlux_; }
    const std::vector<glm::vec3>& texelFlux() const { return texelFlux_; }
    const std::vector<TranslucentShadowMap>& shadowMaps() const { return maps_; }

private:
    bool usesSamples() const { return options_.mode != TextureSpaceMode::Local; }
    bool usesFilter() const {
        return options_.mode == TextureSpaceMode::Hybrid || options_.mode == TextureSpaceMode::Local;
    }
    void draw();
    // The material-dependent state (see PER MATERIAL above).
    void buildMaterialState(const Material& material);
    // The global (sample) sums at `count` points into out[0 .. count): over every
    // sample, or with theta > 0 over the terms of the clusters (see CLUSTERS above).
    void sampleSums(const glm::vec3* points, size_t count, glm::dvec3* out) const;
    // The terms of the global sum at `count` points (theta > 0: tree_ is set), and
    // their sums there (added to out).
    void gatherTerms(const glm::vec3* points, size_t count, SampleTerms& terms, ClusterTerms& clusters) const;
    void sumGroup(const GroupTerms& terms, const glm::vec3* points, size_t count, glm::dvec3* out) const;
    // Builds tree_ over the merged samples and puts them in its order.
    void buildClusters();

    const TriangleMesh* mesh_;
    const RayScene* scene_;
    const SurfaceAtlas* atlas_;
    Material material_;
    TextureSpaceOptions options_;
    BoundingSphere sphere_;
    DiffusionSplit split_;
    RadialTable sampleKernel_;  // R_d or R_d W_g
    RadialCurvature sampleCurvature_;  // its second-order terms (clusters)
    LocalFilter filter_;        // kernel R_d W_l

    std::vector<glm::vec3> texelFlux_;  // per atlas sample (covered texel): Phi_t
    std::optional<MipmapSampler> sampler_;
    glm::dvec3 totalFlux_{0.0};
    SampleTerms samples_;  // the merged samples (in the tree's order when there is one)
    std::optional<IrradianceOctree> tree_;  // theta > 0: the samples' clusters (samples in its order)
    std::vector<std::array<float, 6>> nodeCovariance_;  // per node of tree_: S (xx, yy, zz, xy, xz, yz)
    std::vector<TranslucentShadowMap> maps_;
    TextureSpaceTimings timings_;
    double materialSeconds_ = 0.0;
    // The mesh's vertices in Morton order of their positions (and those positions):
    // vertexExitance walks them so, so that consecutive vertices' filter taps read the
    // same shadow-map cache lines.
    std::vector<uint32_t> vertexOrder_;
    std::vector<glm::vec3> orderedPositions_;
    // With clusters, the terms of each chunk of vertexExitance's vertices: they depend
    // on the draws, theta and the vertices only, so after a material change (which
    // keeps the draws) the next vertexExitance reuses them and evaluates the new
    // kernel alone. Gathered by the first vertexExitance after each draw (into the
    // previous draw's memory); not kept when they would take more than
    // kVertexTermsBudget bytes. The mutex makes concurrent vertexExitance calls safe
    // (they take turns).
    static constexpr size_t kVertexTermsBudget = size_t(256) << 20;
    mutable std::vector<GroupTerms> vertexTerms_;
    mutable bool vertexTermsValid_ = false, vertexTermsOverBudget_ = false;
    mutable std::mutex vertexTermsMutex_;
};

}  // namespace prt
