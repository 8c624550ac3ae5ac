#pragma once
// Pass 2 of the multiple-scattering precomputation (SPEC section 6, Wang et al. 2005
// section 3 "Diffuse Multiple Scattering"): the hierarchical integration of Jensen and
// Buhler 2002, performed on sparse Haar coefficient vectors instead of scalars.
//
// WHAT IS COMPUTED. Pass 1 gives, for each surface sample i, its position x_i (mm),
// its area A_i (mm^2; total area / N) and its irradiance transport vector E_i (Wang
// Eq. 8 with the texel solid angle folded in, one scalar Haar vector, already
// truncated). For each mesh vertex x_o this module evaluates Wang Eq. 7 by cubature,
// per colour channel c (R_d^c is the dipole profile of channel c of the material):
//
//     T_d^c(x_o) = sum_i A_i R_d^c(|x_i - x_o|) E_i
//
// (the point rule; prt-precompute passes a CellQuadrature, which replaces A_i R_d by the
// integral of R_d over sample i's Voronoi cell near x_o so that the sum converges at the
// default spacing: cell_quadrature.h and QUADRATURE below)
//
// and STORES T_d / pi, i.e. the returned RGB vector of vertex o is
//
//     V_o = T_d(x_o) / pi,
//
// so that the renderer evaluates Wang's relighting equation
//     L_d(x_o, w_o) = F_t(eta, w_o) * (V_o . L)
// with only the Fresnel transmittance of the view direction left to apply. The
// vector is truncated to its vertexCoefficients largest coefficients, the magnitude
// of an entry being the Euclidean norm of its three channels (haar.h
// truncateLargest), and has channels = 3.
//
// THE TREE (SampleTree). A kd-tree over the samples: a node is split at the median
// (std::nth_element) along the longest axis of its bounding box, until it holds at
// most leafSize samples or reaches maxDepth (the depth guard; a node at maxDepth
// becomes a leaf whatever its size). Splitting is by COUNT (left half gets
// floor(n/2) samples), so even coincident samples halve the node at each level and
// the depth is at most ceil(log2(n / leafSize)) regardless of geometry (maxDepth
// matters only when it is smaller than that).
// Each node stores
//   - its bounding box and total area A_node = sum A_i (summed in double),
//   - its AREA-WEIGHTED centroid p_node = sum A_i x_i / sum A_i (the plain mean of
//     the positions only when every sample of the node has zero area), and
//   - its AREA-WEIGHTED SUM vector S_node = sum A_i E_i, truncated to the
//     nodeCoefficients entries of largest magnitude.
// It is a sum, not a mean: the node contributes R_d(|x_o - p_node|) S_node, the
// cubature of its samples with R_d frozen at the centroid. (Averaging E without area
// weights is a known trap: see SPEC section 5.)
//
// Node sums are the truncation of the EXACT sum of the node's samples' vectors by
// default (HierarchyOptions::exactNodeSums): the exact sums are merged bottom-up as
// sparse vectors (each parent merges its children's exact sums, so the cost is that
// of a merge sort, not of re-adding every sample at every level) and only the stored
// copy is truncated. With exactNodeSums = false the parent merges its children's
// TRUNCATED sums instead (Wang's "clustering" read literally; the truncation error
// compounds up the tree, and it is hardly faster). Both are built in parallel with
// TBB and give results independent of the number of threads (build times and
// memory: docs/performance.md, "Pass 2 design measurements").
//
// Storage is compact: nodes are one contiguous array in depth-first (pre-order)
// layout (left child = node + 1), node sums and sample vectors live in two pools of
// (index, value) pairs addressed by offsets; there is no per-node allocation. The
// tree takes the SampleCloud by value (std::move it in to avoid a copy) and repacks
// the sample vectors, premultiplied by A_i, into its pool in leaf order.
//
// TRAVERSAL. For a vertex x_o, starting at the root: a node is used whole when
//   (a) x_o is not inside the node's bounding box enlarged by a margin of
//       kBoundsMargin times the box's longest extent on every side (a mesh vertex can
//       sit a hair off the sampled surface and flat nodes have zero thickness; the
//       margin keeps a node that really contains x_o from being approximated), and
//   (b) A_node / |x_o - p_node|^2 < epsilon (Jensen and Buhler's solid-angle
//       criterion; evaluated as A_node < epsilon |x_o - p_node|^2, so epsilon = 0
//       never uses a node whole);
// otherwise its children are visited; a leaf that is not used whole contributes its
// samples individually with their exact A_i E_i and positions. With epsilon = 0 the
// result is the brute-force sum up to rounding (measured: 1e-7 of the sum of the
// absolute values of the terms).
//
// Vertices are processed along a Morton curve of their positions (consecutive
// vertices of a thread reuse the node sums in cache: 1.4x faster than random order
// in TimingReport); results are returned in the caller's order. Contributions are
// accumulated into a dense per-thread RGB accumulator of coefficientCount x 3
// DOUBLES (147 KB for a 6x32x32 cubemap, well inside L2): as fast as floats, and the
// epsilon = 0 result matches the brute force ~70x closer (docs/performance.md). Per vertex the accumulator is rounded
// to float, split and truncated to vertexCoefficients entries (sh_part.h
// truncateWithShPart; haar.h truncateLargest without an SH part), and
// cleared with one fill of the whole block (a few us, ~2% of a vertex's time);
// tracking touched entries would put a test on every one of the ~10^5 scattered
// additions instead, and the truncation reads the whole block anyway.
//
// DEFAULT EPSILON = 0.05. Freezing R_d at the centroid is exact to first order in
// the node's angular size s / d ~ sqrt(A_node) / d <= sqrt(epsilon) (the
// area-weighted centroid cancels the linear term for the area-weighted part of E);
// the remainder is of order epsilon times the relative curvature of R_d and, R_d
// being convex in the distance, it is mostly a systematic UNDERestimate. The error
// and cost against epsilon (tests/test_multiple_scattering.cpp ErrorShrinksAsEpsilonShrinks,
// FlatDiskMatchesTotalDiffuseReflectance, TimingReport) are tabulated in
// docs/performance.md, "Pass 2 design measurements": 0.05 keeps the hierarchy's
// error, bias included, below 0.5% (under the 8-bit display step) for about 1.7x
// the work of 0.1.
//
// Thread safety: a built SampleTree is immutable; any number of threads may traverse
// it. Results are deterministic: every vertex is computed independently by the same
// sequential code, and the tree build does not depend on the thread count.

#include "common/bssrdf.h"
#include "common/haar.h"
#include "common/progress.h"

#include <glm/glm.hpp>

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

namespace prt {

class CellQuadrature;

// The input of pass 2: one entry per surface sample, all vectors of the same length.
struct SampleCloud {
    std::vector<glm::vec3> positions;      // mm
    std::vector<float> areas;              // mm^2, >= 0 and finite
    std::vector<SparseVector> irradiance;  // channels = 1, strictly increasing indices
};

struct HierarchyOptions {
    // Solid-angle criterion A_node / |x_o - p_node|^2 < epsilon for using a node whole
    // (see the top of this file for why 0.05). 0 = exact (no node used whole).
    double epsilon = 0.05;
    // Entries kept in each node's area-weighted sum vector.
    size_t nodeCoefficients = 256;
    // Largest leaf (samples), and the depth guard (the root has depth 0).
    int leafSize = 8;
    int maxDepth = 48;
    // Entries kept in each vertex's RGB transport vector (Wang: 128), of which shTerms
    // (0, 1, 4 or 9) are its SH part (common/sh_part.h truncateWithShPart; indices
    // 6 N^2 + i) and the rest the largest Haar coefficients of the residual.
    size_t vertexCoefficients = 128;
    int shTerms = 0;
    // Sample vectors that carry an SH part (pass 1 with IrradianceOptions::shTerms) hold
    // it at indices >= sampleShFrom (= 6 N^2, with the same shTerms as the vertices):
    // node truncations keep those entries whatever their size, and each vertex folds
    // the summed SH part into its own split. UINT32_MAX: the samples carry none.
    uint32_t sampleShFrom = UINT32_MAX;
    // true: node sums are truncations of the exact sums; false: truncated children's
    // sums are merged (see the top of this file).
    bool exactNodeSums = true;
};

// Relative margin of the "x_o inside the node" test (fraction of the node box's
// longest extent added on every side).
inline constexpr float kBoundsMargin = 0.01f;

class SampleTree {
public:
    // One sparse entry of a pool.
    struct Entry {
        uint32_t index;
        float value;
    };
    // A node; 72 bytes. Children: left = this + 1 (pre-order), right = `right`.
    struct Node {
        glm::vec3 boundsMin;
        glm::vec3 boundsMax;
        glm::vec3 centroid;    // area-weighted
        float area;            // sum of the samples' areas (summed in double)
        uint32_t first;        // first sample (tree order) of the node's range
        uint32_t count;        // number of samples in the range
        uint32_t right;        // index of the right child; 0 for a leaf
        uint32_t depth;        // root = 0
        uint64_t sumOffset;    // node sum entries [sumOffset, sumOffset + sumCount)
        uint32_t sumCount;
        uint32_t padding = 0;
        bool isLeaf() const { return right == 0; }
    };
    static_assert(sizeof(Node) == 72);

    // Builds the tree (parallel, TBB). Only options.nodeCoefficients, leafSize,
    // maxDepth and exactNodeSums are used here. Throws prt::Error when the cloud is
    // empty, its arrays differ in length, a vector has channels != 1 or inconsistent
    // sizes or unsorted indices, an area is negative or not finite, a position is not
    // finite, leafSize < 1, maxDepth < 0, nodeCoefficients == 0, or there are more
    // than 2^31 - 1 samples.
    SampleTree(SampleCloud cloud, const HierarchyOptions& options = {});

    size_t sampleCount() const { return samplePositions_.size(); }
    const std::vector<Node>& nodes() const { return nodes_; }
    const Node& root() const { return nodes_.front(); }

    // Samples in tree order (each node's samples are a contiguous range).
    const std::vector<glm::vec3>& samplePositions() const { return samplePositions_; }
    const std::vector<float>& sampleAreas() const { return sampleAreas_; }
    // original[k] = index in the input cloud of tree sample k.
    const std::vector<uint32_t>& originalIndex() const { return originalIndex_; }
    // Entries of tree sample k: A_k E_k (area premultiplied).
    std::span<const Entry> sampleEntries(size_t k) const {
        return {sampleEntries_.data() + sampleOffsets_[k],
                sampleEntries_.data() + sampleOffsets_[k + 1]};
    }
    // The truncated area-weighted sum sum A_i E_i of a node.
    std::span<const Entry> nodeSum(size_t node) const {
        const Node& n = nodes_[node];
        return {nodeEntries_.data() + n.sumOffset, n.sumCount};
    }
    // The node sum as a SparseVector (channels = 1), for tests and tools.
    SparseVector nodeSumVector(size_t node) const;

    // Largest coefficient index in any sample vector + 1 (0 when all are empty).
    size_t coefficientBound() const { return coefficientBound_; }
    int maxDepthReached() const { return maxDepthReached_; }
    size_t leafCount() const { return leafCount_; }
    double buildSeconds() const { return buildSeconds_; }

    // Memory held: nodes, node-sum pool, sample pool (+ offsets, positions, areas,
    // original indices).
    size_t nodeBytes() const;
    size_t sampleBytes() const;
    size_t bytes() const { return nodeBytes() + sampleBytes(); }

private:
    std::vector<Node> nodes_;
    std::vector<Entry> nodeEntries_;
    std::vector<glm::vec3> samplePositions_;
    std::vector<float> sampleAreas_;
    std::vector<uint32_t> originalIndex_;
    std::vector<uint64_t> sampleOffsets_;  // sampleCount + 1
    std::vector<Entry> sampleEntries_;
    size_t coefficientBound_ = 0;
    int maxDepthReached_ = 0;
    size_t leafCount_ = 0;
    double buildSeconds_ = 0.0;
};

struct MultipleScatteringStats {
    double meanNodesVisited = 0.0;  // nodes whose criterion was evaluated, per vertex
    double meanNodesUsed = 0.0;     // nodes used whole (their sum vector), per vertex
    double meanSamplesUsed = 0.0;   // samples used individually (in leaves), per vertex
    // Mean over vertices of (energy kept by the final truncation) / (energy of the
    // full accumulated vector), energy = sum of squares over all channels; a vertex
    // whose accumulated vector is zero counts as 1.
    double retainedEnergyFraction = 1.0;
    double seconds = 0.0;           // wall time of the traversal
    size_t treeBytes = 0;           // SampleTree::bytes()
};

// Pass 2: the RGB multiple-scattering transport T_d / pi of every vertex (see the top
// of this file), truncated to options.vertexCoefficients entries, channels = 3.
// Only options.epsilon, vertexCoefficients, shTerms and sampleShFrom are used here (the
// tree was built with the rest). coefficientCount = 6 N^2 of the cubemap; with the
// samples' SH entries, coefficientCount + shTerms must exceed every index in the tree
// (else prt::Error). Parallel over vertices (TBB); deterministic. The
// material must be valid (validateMaterial). progress, when given, advances once per
// vertex.
// QUADRATURE. With cells (what prt-precompute uses), a sample in a leaf contributes
// w_k(x_o) E_k with the cell rule's weight (cell_quadrature.h: R_d integrated over its
// Voronoi cell near x_o, A_k R_d far away); the tree must have been built with
// cloud.areas = cells->cellAreas() (else prt::Error), and a node is used whole only
// when, besides (a) and (b) above, no sample's cell can reach within the near radius
// r2 of x_o (distance to its box >= r2 + the largest cell radius). Without cells, the
// point rule A_k R_d(|x_k - x_o|) of Jensen and Buhler (not converged at the default
// spacing: 1.4-11.6% per point; kept for the hierarchy's tests on synthetic clouds).
std::vector<SparseVector> multipleScatteringTransport(const SampleTree& tree,
                                                      std::span<const glm::vec3> vertices,
                                                      const Material& material,
                                                      const HierarchyOptions& options,
                                                      size_t coefficientCount,
                                                      MultipleScatteringStats* stats = nullptr,
                                                      Progress* progress = nullptr,
                                                      const CellQuadrature* cells = nullptr);

// The slow, obvious reference: for each vertex, sum over ALL samples of
// A_i R_d^c(|x_i - x_o|) / pi E_i (with cells: w_i^c(x_o) / pi E_i, the cell rule)
// accumulated in double, then rounded to float and truncated to vertexCoefficients
// entries (channels = 3). No tree. For tests.
std::vector<SparseVector> multipleScatteringBruteForce(const SampleCloud& cloud,
                                                       std::span<const glm::vec3> vertices,
                                                       const Material& material,
                                                       size_t coefficientCount,
                                                       size_t vertexCoefficients,
                                                       const CellQuadrature* cells = nullptr,
                                                       int shTerms = 0);

}  // namespace prt
