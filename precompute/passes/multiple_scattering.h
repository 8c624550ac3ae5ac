#pragma once
// Pass 2 of multiple scattering (Wang et al. 2005, section 3): the hierarchical
// integration of Jensen and Buhler 2002 on sparse Haar vectors. For each vertex x_o,
// per colour channel c, Wang Eq. 7 as a sum over the pass-1 samples i (position x_i in
// mm, area A_i in mm^2, irradiance transport vector E_i: irradiance_transport.h):
//
//     T_d^c(x_o) = sum_i w_i^c(x_o) E_i,
//
// with the point rule w_i^c = A_i R_d^c(|x_i - x_o|) (R_d: the material's dipole) or,
// given a CellQuadrature, R_d integrated over sample i's cell (cell_quadrature.h; what
// prt-precompute uses). Each vertex gets V_o = T_d(x_o) / pi (channels = 3), so the
// renderer's radiance is F_t(eta, w_o) (V_o . L), truncated to vertexCoefficients
// entries by the Euclidean norm of their three channels (with an SH part:
// common/sh_part.h truncateWithShPart).
//
// The tree (SampleTree): a kd-tree split by count (left = floor(n/2)) at the median of
// the longest axis of the node's box, down to leafSize samples or maxDepth. A node
// stores its box, its area A_node = sum A_i, its area-weighted centroid p_node (the
// plain mean when every area is 0) and the area-weighted SUM S_node = sum A_i E_i
// truncated to nodeCoefficients entries, so that it contributes R_d(|x_o - p_node|)
// S_node (averaging E without area weights is a known trap: SPEC section 5).
//
// Traversal: a node is used whole when (a) x_o lies outside its box enlarged by
// kBoundsMargin of its longest extent on every side (a vertex can sit a hair off the
// sampled surface, and flat nodes have no thickness) and (b) A_node / |x_o - p_node|^2
// < epsilon (Jensen and Buhler's solid-angle criterion); otherwise its children are
// visited, and a leaf adds its samples one by one. epsilon = 0 is the brute-force sum
// up to rounding. Freezing R_d at the area-weighted centroid is exact to first order in
// the node's angular size, so the error is of order epsilon and, R_d being convex,
// mostly an underestimate (why 0.05: docs/performance.md, "Pass 2 design measurements").
//
// Thread safety: a built SampleTree is immutable. Results do not depend on the thread
// count.

#include "common/bssrdf.h"
#include "common/haar.h"
#include "common/progress.h"
#include "common/radial_kernels.h"

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
    std::vector<SparseVector> irradianceTransport;  // E_i: channels = 1, strictly increasing indices
};

// The options of pass 2 (its tree and its per-vertex vectors).
struct HierarchyOptions {
    // Solid-angle criterion A_node / |x_o - p_node|^2 < epsilon for using a node whole;
    // 0 = exact (no node used whole).
    double epsilon = 0.05;
    size_t nodeCoefficients = 256;  // entries kept in each node's sum S_node
    int leafSize = 8;               // largest leaf (samples)
    int maxDepth = 48;              // depth guard (the root has depth 0)
    // Entries kept in each vertex's RGB vector, of which shTerms (0, 1, 4 or 9) are its
    // SH part (indices 6 N^2 + i) and the rest the largest Haar coefficients.
    size_t vertexCoefficients = 128;
    int shTerms = 0;
    // Where the samples' SH part starts (= 6 N^2, with the vertices' shTerms; pass 1 with
    // IrradianceTransportOptions::shTerms): node truncations keep those entries whatever
    // their size and each vertex folds the summed SH part into its own split.
    // UINT32_MAX: the samples carry none.
    uint32_t sampleShFrom = UINT32_MAX;
    // true: node sums are truncations of the exact sums, merged bottom-up; false: the
    // children's truncated sums are merged (Wang's clustering read literally; the
    // truncation error compounds up the tree).
    bool exactNodeSums = true;
};

// Relative margin of the "x_o inside the node" test (fraction of the node box's
// longest extent added on every side).
inline constexpr float kBoundsMargin = 0.01f;

// Nodes in one array in pre-order (left child = node + 1), node sums and sample vectors
// in two pools of (index, value) entries: no per-node allocation. The tree takes the
// cloud by value (std::move it in) and repacks the vectors, premultiplied by A_i, in
// leaf order.
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

// Pass 2: V_o = T_d(x_o) / pi of every vertex (see the top of this file), channels = 3,
// in the caller's order. Uses options.epsilon, vertexCoefficients, shTerms and
// sampleShFrom (the tree was built with the rest). texelCount = 6 N^2 of the cubemap:
// with the samples' SH entries, texelCount + shTerms must exceed every index in the
// tree (else prt::Error). The material must be valid (validateMaterial). Parallel over
// vertices (TBB), deterministic; progress, when given, advances once per vertex.
// With cells, a sample in a leaf contributes w_k(x_o) E_k with the cell rule's weight;
// the tree must have been built with cloud.areas = cells->cellAreas() (else
// prt::Error), and a node is used whole only when, besides (a) and (b) above, no
// sample's cell can reach within the near radius r2 of x_o (distance to its box >= r2
// + the largest cell radius). Without cells, the point rule (the hierarchy's tests on
// synthetic clouds; not converged at the default spacing: docs/fidelity.md, "The
// sample sum").
std::vector<SparseVector> multipleScatteringTransport(const SampleTree& tree,
                                                      std::span<const glm::vec3> vertices,
                                                      const Material& material,
                                                      const HierarchyOptions& options,
                                                      size_t texelCount,
                                                      MultipleScatteringStats* stats = nullptr,
                                                      Progress* progress = nullptr,
                                                      const CellQuadrature* cells = nullptr);
// The same against any kernel set (radial_kernels.h): K = kernels.count() channels per
// vertex vector, V_o^c = sum_i w_i^c(x_o) E_i / pi with kernel c in place of R_d^c
// (the material overload is RadialKernels(material)). With cells, they must integrate
// the same number of kernels (prt::Error otherwise).
std::vector<SparseVector> multipleScatteringTransport(const SampleTree& tree,
                                                      std::span<const glm::vec3> vertices,
                                                      const RadialKernels& kernels,
                                                      const HierarchyOptions& options,
                                                      size_t texelCount,
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
                                                       size_t texelCount,
                                                       size_t vertexCoefficients,
                                                       const CellQuadrature* cells = nullptr,
                                                       int shTerms = 0);
std::vector<SparseVector> multipleScatteringBruteForce(const SampleCloud& cloud,
                                                       std::span<const glm::vec3> vertices,
                                                       const RadialKernels& kernels,
                                                       size_t texelCount,
                                                       size_t vertexCoefficients,
                                                       const CellQuadrature* cells = nullptr,
                                                       int shTerms = 0);

}  // namespace prt
