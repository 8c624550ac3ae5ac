#pragma once
// Single-scattering precomputation (Wang et al. 2005, Eqs. 4, 5, 10, 11; SPEC
// section 5; docs/single-scattering.md).
//
// For every vertex x_o with outward unit normal n_o the single-scattering transport
//
//     T_k^c(x_o, w_j) = int_0^{d_m} sigma_s^c T_p^c(x_p, w_j) e^(-sigma_t^c s) ds,
//     T_p^c(x_p, w_j) = g_k(w_i') F_t(eta, w_j . n_i) e^(-sigma_t^c s_i') V dOmega_j,
//
// is integrated along the INWARD NORMAL x_p = x_o - s n_o (Wang's view-independent
// approximation of the refracted view ray, Fig. 2b), for every texel direction w_j
// of a 6 x N x N cubemap (w_j points from the object toward the light):
//   * d_m    distance from x_o along -n_o to the far side of the object (where that
//            ray leaves it; farSideDistance); when that ray hits nothing (open mesh)
//            d_m is capped at depthCapMeanFreePaths / |sigma_t|.
//   * x_i    the first surface point of the ray x_p + t w_j, s_i its distance from
//            x_p, n_i the vertex normals interpolated with the hit's barycentrics
//            (the triangle's geometric normal where the interpolated one does not
//            face w_j).
//   * inside x_p counts only when it is inside the object: when more of its rays
//            first hit a triangle facing along the ray (a back face) than hit nothing
//            (the rays toward every texel, or toward the lattice of the adaptive
//            directions).
//            An exit through a triangle facing the other way (inconsistent winding,
//            common in scanned meshes) is used with its normals reversed. When most
//            points below a vertex are outside, its normal points inward and the
//            path is taken along +n_o instead (if that is inside more often).
//   * s_i'   = s_i |w_j . n_i| / sqrt(1 - (1/eta)^2 (1 - |w_j . n_i|^2))   (Eq. 5).
//   * w_i'   = refractDirection(w_j, n_i, eta): the light's propagation direction
//            after it entered at x_i, pointing INTO the medium; the light maps g_k of
//            precompute/passes/phase_factoring.h are indexed by it (see the conventions there).
//   * V      1 when nothing lies beyond x_i toward w_j (found by the exit ray itself, or
//            by a second ray from x_i offset outward: visibilityFromExitRay).
// The integral over s uses N deterministic importance samples (Wang Sec. 3)
//     s_i = -ln(1 - lambda xi_i) / |sigma_t|,
//     lambda = 1 - e^(-|sigma_t| d_m),  pdf(s) = |sigma_t| e^(-|sigma_t| s) / lambda,
// |sigma_t| = luminance(sigma_t), each sample weighted w_i / pdf(s_i), where (xi_i, w_i)
// is a quadrature rule on [0, 1] (PathQuadrature): Wang's midpoints xi_i = (i - 0.5) / N,
// w_i = 1 / N, or the N-point Gauss-Legendre rule.
//
// PHASE. Isotropic (no factorisation): one term with g(a) = 1 / (4 pi) folded in, so
// the outgoing radiance is F_t(eta, w_o) dot(T, L) and T adds directly to the
// multiple-scattering vector (stored as T_d / pi). Anisotropic: K terms, one per light
// map g_k of a PhaseFactorization, and the radiance is
//     F_t(eta, w_o) sum_k h_k(w_o') dot(T_k, L),  w_o' = refractDirection(w_o, n_o, eta).
//
// STORAGE. Per vertex and term the dense RGB cubemap (6 N^2 x 3, solid angle folded
// in) is Haar-transformed per face and channel (common/haar.h) and truncated to the
// largest vertexCoefficients coefficients (Euclidean norm over RGB).
//
// Units: lengths in mm, coefficients in mm^-1; T is dimensionless (sr x sr^-1).

#include <glm/glm.hpp>

#include <cstddef>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <span>
#include <utility>
#include <vector>

#include "common/bssrdf.h"
#include "common/cubemap.h"
#include "common/haar.h"
#include "precompute/passes/irradiance_transport.h"
#include "common/raytrace.h"
#include "common/scattering_path.h"
#include "precompute/passes/single_scattering_sites.h"

namespace prt {

class Progress;
struct PhaseFactorization;
struct TriangleMesh;

// ---------------------------------------------------------------------------------
// Small helpers (the formulas above, unit-tested on their own)
// ---------------------------------------------------------------------------------

// |sigma_t|: the Rec. 709 luminance of sigma_t (mm^-1), the scalar extinction of the
// importance sampling along the path.
double samplingExtinction(const Material& material);

// The path's formulas (PathSample, pathSampleLambda / Distance / Pdf, PathQuadrature,
// QuadratureNode, pathQuadratureRule, makePathSamples, refractedPathLength,
// farSideDistance): common/scattering_path.h, shared with the point-light renderer.

// PathQuadrature's names: "midpoint" / "gauss"; parsePathQuadrature throws
// prt::Error("--path-quadrature", ...) on anything else.
const char* toString(PathQuadrature q);
PathQuadrature parsePathQuadrature(const std::string& text);
// The default N of each rule: Wang's 16 midpoints, 4 Gauss-Legendre points (with the
// adaptive directions, within the 128-term truncation's error for 4x fewer rays:
// docs/single-scattering.md, "adaptive directions and 4 Gauss points").
constexpr int defaultPathSamples(PathQuadrature q) { return q == PathQuadrature::Midpoint ? 16 : 4; }
constexpr PathQuadrature kDefaultPathQuadrature = PathQuadrature::GaussLegendre;

// ---------------------------------------------------------------------------------
// Per-vertex kernel
// ---------------------------------------------------------------------------------

struct SingleScatteringOptions {
    int cubemapSize = 32;          // N; a power of two
    int supersample = 1;           // s x s sub-directions per texel (each with its solid angle)
    PathQuadrature pathQuadrature = kDefaultPathQuadrature;  // the rule of the samples in xi
    int pathSamples = defaultPathSamples(kDefaultPathQuadrature);  // samples along -n_o
    size_t vertexCoefficients = 128; // terms kept per vertex and term: shTerms SH + the largest Haar
    int shTerms = 0;               // SH part of each vector (common/sh_part.h truncateWithShPart)
    // d_m when the inward ray leaves an open mesh: this many mean free paths
    // 1 / |sigma_t| (the sampled mass beyond it is e^-16 ~ 1e-7).
    double depthCapMeanFreePaths = 16.0;
    // An exit point whose throughput F_t max_c e^(-sigma_t^c s_i') is below this
    // contributes nothing and gets no occlusion ray (relative to an unattenuated
    // normal-incidence ray, whose throughput is F_t(1) ~ 0.98). 0 traces every ray.
    // What it saves and costs: docs/single-scattering.md, "Throughput cut-off".
    double minThroughput = 1e-4;
    bool visibility = true;        // false: V = 1 (no occlusion rays; tests, ablations)
    // V from the exit ray itself (RayScene::intersectBatchWithBeyond): x_i is occluded
    // when the exit ray meets another surface more than the scene's epsilon beyond it,
    // found by the same traversal that finds x_i, so no second ray is traced. false: an
    // occlusion ray from x_i offset along its geometric normal (the reference;
    // sharedVisibility always uses it). The two differ only where a surface lies within
    // ~epsilon of x_i (docs/single-scattering.md, "visibility from the exit ray").
    bool visibilityFromExitRay = true;
    // Whether V comes from the exit rays: visibility on, visibilityFromExitRay, and not
    // shared visibility (which always traces its own rays).
    bool exitRayVisibility() const { return visibility && visibilityFromExitRay && !sharedVisibility; }
    // Shared visibility: of the exit points of one direction (one per path sample that
    // survives the cut-off), only the shallowest and the deepest sample's get an
    // occlusion ray; when both are visible (or both occluded) the samples between take
    // that V, otherwise each gets its own ray. Exact when every shadow edge that crosses
    // a direction's exits also separates its ends (wide occluders; tested); on meshes
    // the ends often lie on different sheets of the surface with occluded exits between
    // them, and light is added. Not the default; kept for measurements
    // (docs/single-scattering.md, "Gauss path samples").
    bool sharedVisibility = false;
    // Trace the exit and occlusion rays as COHERENT 16-ray packets (Embree's
    // RTC_INTERSECT_CONTEXT_FLAG_COHERENT, RayScene's batches with coherent = true); each
    // packet holds one direction from 16 neighbouring points (with 16 path samples; with
    // 4, neighbouring directions from 4 points), which is what that flag is for. The
    // hits are the same either way (tested); docs/single-scattering.md, "Speed".
    bool coherentRays = true;
    // Adaptive texel directions. With a stride S > 1 only the texels of a lattice of
    // spacing S on each cube face (and the face's last row and column) are traced
    // first. A lattice cell whose four corners AGREE has the texels inside it
    // interpolated bilinearly (per steradian) from its corners; any other cell is split
    // in four, its new corners traced, and so on down to single texels. Corners agree
    // when (refineDirections in the .cpp):
    //   * for every path sample with more than refineValueFloor x L per steradian at
    //     some corner (L: the vertex's brightest lattice texel, before occlusion), all
    //     four corners have the same kind of exit: occluded, visible, or none (escaped,
    //     culled, outside);
    //   * their visible throughputs per steradian differ by at most
    //     refineValueTolerance x the largest (+ refineValueFloor x L);
    //   * a cell wider than 2 texels has no corner with more than refineLargeCellValue x L
    //     at stake before occlusion.
    // Shadow edges, the cut-off and steep changes show as disagreeing corners; an
    // occluder or a lit gap that fits between agreeing corners is missed, which the last
    // rule confines to dim cells or cells 2 texels wide (what it costs in accuracy:
    // docs/single-scattering.md, "adaptive directions and 4 Gauss points"). 1 traces
    // every texel; used only with supersample == 1 (ignored otherwise).
    int directionStride = 1;
    double refineValueTolerance = 0.5;
    double refineValueFloor = 1e-2;
    double refineLargeCellValue = 0.3;
    // Sites (precompute/passes/single_scattering_sites.h): with a spacing h > 0 (mm) the
    // transport is computed at sites about h apart, each kept as its
    // siteCoefficientFactor x vertexCoefficients largest Haar coefficients per term, and
    // every vertex's vector is the truncation of its blend of those. 0: every vertex
    // computes its own.
    double siteSpacing = 0.0;
    int siteCoefficientFactor = 4;
};

// Everything the kernel needs that does not depend on the vertex, prepared once.
// The scene must have been built from `mesh` (the triangle indices of its hits index
// mesh.triangles) and both must outlive the context.
class SingleScatteringContext {
public:
    // phase == nullptr: isotropic (requires material.g == 0); otherwise its K light
    // maps are used and phase->g must equal material.g. Throws prt::Error on a bad
    // option, a mesh without per-vertex normals or a phase/material mismatch.
    SingleScatteringContext(const RayScene& scene, const TriangleMesh& mesh,
                            const Material& material, const PhaseFactorization* phase,
                            const SingleScatteringOptions& options);

    int terms() const { return terms_; }       // 1 when isotropic
    bool isotropic() const { return isotropic_; }
    int cubemapSize() const { return options_.cubemapSize; }
    size_t texelCount() const { return size_t(6) * options_.cubemapSize * options_.cubemapSize; }
    // Floats of the dense output of one vertex: terms() x texelCount() x 3.
    size_t denseSize() const { return size_t(terms_) * texelCount() * 3; }
    const SingleScatteringOptions& options() const { return options_; }
    const TexelDirections& directions() const { return dirs_; }
    // The sub-directions in the order they are traced, with their texel and solid angle.
    struct Directions {
        std::vector<float> x, y, z, solidAngle;
        std::vector<uint32_t> texel;
    };
    const Directions& tracedDirections() const { return traced_; }
    double samplingSigma() const { return sigma_; }
    // Adaptive directions (options().directionStride > 1 and supersample == 1): the
    // directions traced first (the lattice, face by face) and the lattice cells, in
    // texel coordinates [i0, i1] x [j0, j1] of one face (corners included).
    bool adaptiveDirections() const { return !topCells_.empty(); }
    struct DirectionCell {
        uint16_t face, i0, i1, j0, j1;
    };
    const std::vector<uint32_t>& firstDirections() const { return firstDirections_; }
    const std::vector<DirectionCell>& topCells() const { return topCells_; }
    // The path-sample rule on [0, 1] (options().pathQuadrature, options().pathSamples).
    const std::vector<QuadratureNode>& pathRule() const { return pathRule_; }
    double depthCap() const { return depthCap_; }

    // g_k(a) for every term into out[0..terms()): 1/(4 pi) when isotropic, else the
    // bilinear lookup of the light maps (a points into the medium).
    void lightMapValues(const glm::vec3& a, float* out) const;

    // F_t(eta, cosTheta) from a table (linear interpolation, error < 1e-6; exact for
    // eta < 1, where F_t has a kink at the critical angle).
    float fresnel(float cosTheta) const;

    // Where the inward path of vertex v starts: the vertex moved 1% of the way toward
    // the mean centroid of its own triangles, so that at a crease with split vertices
    // (a box edge, each face with its own vertices and flat normals) the path -n_o
    // leaves the plane of the adjacent face instead of running in it (half its rays
    // would leave through that face at t ~ 0: black edges).
    const glm::vec3& pathOrigin(size_t v) const { return pathOrigins_[v]; }
    // The vertex normals at the three corners of triangle t (mesh.normals of its
    // indices), stored per triangle: one memory access per exit instead of two
    // dependent ones (the shading's cache misses; docs/single-scattering.md).
    struct CornerNormals {
        glm::vec3 n[3];
    };
    const CornerNormals* cornerNormalsData() const { return cornerNormals_.data(); }

    const RayScene& scene() const { return *scene_; }
    const TriangleMesh& mesh() const { return *mesh_; }
    const Material& material() const { return material_; }

    // hits[i] = the closest hit of ray (org[i], dir[i]) for t in [0, inf), occluded[i] =
    // whether it hits anything: the scene's batches, coherent when coherentRays (the rays
    // of one packet should then share a direction).
    void intersectCoherent(const float* orgX, const float* orgY, const float* orgZ, const float* dirX,
                           const float* dirY, const float* dirZ, size_t count, Hit* hits) const;
    void occludedCoherent(const float* orgX, const float* orgY, const float* orgZ, const float* dirX,
                          const float* dirY, const float* dirZ, size_t count, uint8_t* occluded) const;
    // hits as intersectCoherent, and beyond[i] = whether the ray meets another surface
    // more than scene().epsilon() beyond hits[i] (options().visibilityFromExitRay).
    void intersectWithBeyond(const float* orgX, const float* orgY, const float* orgZ, const float* dirX,
                             const float* dirY, const float* dirZ, size_t count, Hit* hits,
                             uint8_t* beyond) const;
    bool visibilityFromExitRays() const { return options_.exitRayVisibility(); }

private:
    const RayScene* scene_;
    const TriangleMesh* mesh_;
    Material material_;
    SingleScatteringOptions options_;
    TexelDirections dirs_;
    Directions traced_;
    std::vector<uint32_t> firstDirections_;  // every direction, or the lattice when adaptive
    std::vector<DirectionCell> topCells_;
    std::vector<glm::vec3> pathOrigins_;
    std::vector<CornerNormals> cornerNormals_;
    bool isotropic_ = true;
    int terms_ = 1;
    Cubemap lightMaps_;  // M x M faces, K channels (channel k = g_k); empty if isotropic
    double sigma_ = 0.0;
    double depthCap_ = 0.0;
    std::vector<QuadratureNode> pathRule_;
    static constexpr int kFresnelTableSize = 4096;
    std::vector<float> fresnelTable_;
};

// Counters of one or many vertices.
struct SingleScatteringStats {
    uint64_t depthRays = 0;       // rays along -n_o (one per vertex, two if flipped)
    // Rays from x_p to the exit points: closest hit, and with visibilityFromExitRay
    // (the default) also V, from the same traversal.
    uint64_t exitRays = 0;
    uint64_t occlusionRays = 0;   // second rays from the exit points (!visibilityFromExitRay)
    uint64_t occludedExits = 0;   // exits above the cut-off with V = 0 (either rule)
    uint64_t sharedVisibility = 0; // exits whose V was taken from their direction's end samples
    uint64_t culledRays = 0;      // exits below minThroughput (no occlusion ray)
    // Texels of the vertices with an inside path: traced (all of them unless adaptive:
    // the lattice and the refined corners) or interpolated from agreeing corners.
    uint64_t tracedTexels = 0;
    uint64_t interpolatedTexels = 0;
    // Adaptive directions: lattice cells split, by the first rule their corners broke
    // (cornersAgree: light at stake in a wide cell, throughput spread, exit kind).
    uint64_t splitsByStake = 0, splitsByThroughput = 0, splitsByExitKind = 0;
    uint64_t sites = 0;           // points whose transport was computed (vertices or sites)
    uint64_t escapedRays = 0;     // exit rays of inside points that hit nothing (open mesh)
    uint64_t reversedHits = 0;    // exits through triangles wound the wrong way (used, reversed)
    uint64_t outsideSamples = 0;  // path samples x_p judged outside the object (skipped)
    uint64_t flippedNormals = 0;  // vertices integrated along +n_o (normal pointed inward)
    uint64_t cappedDepths = 0;    // vertices whose inward ray hit nothing (d_m capped)
    double depthSum = 0.0;        // sum of d_m over vertices, mm

    uint64_t rays() const { return depthRays + exitRays + occlusionRays; }
    void add(const SingleScatteringStats& o);
};

// Per-thread scratch so the hot loop never allocates after the first vertex.
struct SingleScatteringScratch {
    std::vector<float> orgX, orgY, orgZ;  // ray origins (x_p repeated; exit points)
    std::vector<float> dirX, dirY, dirZ;  // occlusion-ray directions
    std::vector<Hit> hits;
    std::vector<uint8_t> beyond;          // per exit ray: V = 0 from its own traversal
    std::vector<uint8_t> occluded;
    std::vector<uint32_t> texel;          // texel of each candidate
    std::vector<uint32_t> direction;      // traced direction of each candidate
    std::vector<uint32_t> traced;         // candidates given an occlusion ray (shared visibility)
    std::vector<float> visX, visY, visZ, visDX, visDY, visDZ;  // their rays, gathered
    std::vector<uint8_t> visOccluded;
    std::vector<PathSample> samples;      // the path samples of the current vertex
    std::vector<float> value;             // 3 per candidate: RGB weight
    std::vector<float> phase;             // terms per candidate: g_k(w_i')
    std::vector<glm::vec3> samplePoint, sampleWeight;  // x_p and RGB weight per path sample
    std::vector<int32_t> vote;            // per path sample: back-face hits minus misses
    std::vector<uint8_t> inside;          // per path sample: x_p inside the object
    // Adaptive directions: per texel and path sample what its exit was (0 nothing,
    // 1 occluded, 2 visible) and its throughput per steradian (before V); per texel the
    // throughput of its visible exits, whether it was traced and the span of the cell it
    // was interpolated from.
    std::vector<uint32_t> candidateSample;  // path sample of each candidate
    std::vector<uint8_t> exitCode;
    std::vector<float> sampleMagnitude;   // per texel and path sample, before V
    std::vector<float> magnitude;
    std::vector<float> stake;             // per texel: throughput of all its exits, before V
    std::vector<uint8_t> texelTraced;
    std::vector<uint16_t> texelSpan;
    std::vector<uint32_t> list;           // directions of the current round
    std::vector<float> cornerPerSr;       // an agreeing cell's corners per steradian
    std::vector<SingleScatteringContext::DirectionCell> cells, nextCells;
};

// Dense transport of one vertex into dense[denseSize()], layout
// dense[(k * texelCount() + texel) * 3 + c] (texel order of common/cubemap.h).
void singleScatteringVertex(const SingleScatteringContext& ctx, const glm::vec3& position,
                            const glm::vec3& normal, float* dense,
                            SingleScatteringScratch& scratch, SingleScatteringStats& stats);

// Haar transform (per face, per channel) of a dense vertex result in place, then the
// largest vertexCoefficients entries of each term: out[k] (channels = 3). Returns the
// retained energy fraction (kept / total over all terms; 1 for an all-zero vertex).
double compressSingleScattering(const SingleScatteringContext& ctx, float* dense,
                                std::vector<SparseVector>& out);
// Its two halves: the Haar transform in place, and the truncation of a transformed
// vector (with the SH part of options().shTerms), which modifies `dense`.
void haarSingleScattering(const SingleScatteringContext& ctx, float* dense);
double truncateSingleScattering(const SingleScatteringContext& ctx, float* dense, std::vector<SparseVector>& out);

// ---------------------------------------------------------------------------------
// All vertices
// ---------------------------------------------------------------------------------

struct SingleScatteringResult {
    bool isotropic = true;
    int terms = 1;
    SingleScatteringStats stats;
    double retainedEnergyFraction = 1.0;  // mean over vertices
    double seconds = 0.0;
    double raysPerSecond() const { return seconds > 0 ? double(stats.rays()) / seconds : 0.0; }
};

// Receives the K truncated vectors of each vertex, in increasing vertex order, on the
// calling thread (so it can append to a file's arrays without locking).
using SingleScatteringSink =
    std::function<void(size_t vertex, const std::vector<SparseVector>& terms)>;

// Every vertex of the context's mesh (positions and normals of mesh.positions /
// mesh.normals), or those of the ranges [first, second) when given (in their order, each
// within the mesh), in parallel (TBB) over blocks of vertices; the sink sees them in that
// order. With options().siteSpacing > 0 the sites those vertices blend are computed first,
// once for all the ranges (all of them held in memory), then the vertices. Deterministic:
// a vertex's result depends neither on the thread count nor on the ranges it was computed
// in. Throws prt::Error on a range outside the mesh.
using VertexRanges = std::vector<std::pair<size_t, size_t>>;
SingleScatteringResult computeSingleScattering(const SingleScatteringContext& ctx,
                                               const SingleScatteringSink& sink,
                                               Progress* progress = nullptr,
                                               std::optional<VertexRanges> vertices = {});

// The same computation in its two stages, for processes that share the sites between
// them (MPI ranks: each computes some of the sites, all exchange them, each blends its
// own vertices). computeSingleScattering with sites is chooseSingleScatteringSites,
// then computeSiteTransport of the sites its ranges blend, then blendSiteTransport.

// The transport of the sites `numbers` (indices into sites.site): for each,
// its K vectors (channels = 3) truncated to vertexCoefficients x siteCoefficientFactor
// entries, out[i][k] for numbers[i]. In parallel (TBB); a site's vectors depend on it
// alone. Adds the work to `stats` (sites counts the sites computed); `progress`
// advances by `progressUnits` in all, spread evenly over the sites.
std::vector<std::vector<SparseVector>> computeSiteTransport(const SingleScatteringContext& ctx,
                                                            const SingleScatteringSites& sites,
                                                            std::span<const uint32_t> numbers,
                                                            SingleScatteringStats& stats,
                                                            Progress* progress = nullptr, size_t progressUnits = 0);

// Each vertex of `ranges` (as in computeSingleScattering) as the blend of its sites'
// vectors (single_scattering_sites.h), truncated to the vertex's coefficients, to the
// sink in order. `held` (site numbers) and `vectors` (out of computeSiteTransport, one
// per held site: the context's K RGB vectors of its cubemap) must hold every site the
// ranges blend (prt::Error otherwise, and for vectors of another shape). The result's
// stats hold no rays: the sites' are the caller's.
SingleScatteringResult blendSiteTransport(const SingleScatteringContext& ctx, const SingleScatteringSites& sites,
                                          std::span<const uint32_t> held,
                                          const std::vector<std::vector<SparseVector>>& vectors,
                                          const SingleScatteringSink& sink, Progress* progress,
                                          const VertexRanges& ranges);

// Convenience: collects the vectors, out[k][vertex].
SingleScatteringResult computeSingleScattering(const SingleScatteringContext& ctx,
                                               std::vector<std::vector<SparseVector>>& out,
                                               Progress* progress = nullptr);

}  // namespace prt
