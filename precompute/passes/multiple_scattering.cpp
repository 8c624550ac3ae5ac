#include "precompute/passes/multiple_scattering.h"

#include "common/cell_quadrature.h"

#include "common/error.h"
#include "common/mesh.h"
#include "common/sh_part.h"
#include "common/util.h"

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_invoke.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <limits>
#include <numeric>
#include <string>

namespace prt {

namespace {


// Subtrees with at most this many samples are built sequentially.
constexpr uint32_t kParallelCutoff = 2048;

using Entry = SampleTree::Entry;


bool isLeafNode(uint32_t count, int depth, const HierarchyOptions& o) {
    return count <= uint32_t(o.leafSize) || depth >= o.maxDepth;
}

// Number of nodes of the subtree over `count` samples at `depth`. The shape depends
// only on the counts (split by count, left = floor(n/2)), so node indices can be
// assigned before and independently of the parallel build.
uint32_t subtreeSize(uint32_t count, int depth, const HierarchyOptions& o) {
    if (isLeafNode(count, depth, o)) return 1;
    const uint32_t left = count / 2;
    return 1 + subtreeSize(left, depth + 1, o) + subtreeSize(count - left, depth + 1, o);
}

// Keeps the keep entries of largest |value| (ties: lower index), drops zeros, writes
// them in increasing index order to out; returns how many were written. Non-zero
// entries with index >= forcedFrom (SH coefficients) count as larger than any other.
// `in` must be sorted by index.
uint32_t truncateEntries(const std::vector<Entry>& in, size_t keep, Entry* out, uint32_t forcedFrom) {
    // Drop exact zeros first (they are never kept, as in haar.h truncateLargest).
    size_t nonZero = 0;
    for (const Entry& e : in) nonZero += e.value != 0.0f;
    if (nonZero <= keep) {
        uint32_t n = 0;
        for (const Entry& e : in) {
            if (e.value != 0.0f) out[n++] = e;
        }
        return n;
    }
    thread_local std::vector<Entry> scratch;
    scratch.clear();
    for (const Entry& e : in) {
        if (e.value != 0.0f) scratch.push_back(e);
    }
    const auto larger = [forcedFrom](const Entry& a, const Entry& b) {
        const bool fa = a.index >= forcedFrom, fb = b.index >= forcedFrom;
        if (fa != fb) return fa;
        const float ma = std::fabs(a.value);
        const float mb = std::fabs(b.value);
        return ma > mb || (ma == mb && a.index < b.index);
    };
    std::nth_element(scratch.begin(), scratch.begin() + std::ptrdiff_t(keep), scratch.end(), larger);
    std::sort(scratch.begin(), scratch.begin() + std::ptrdiff_t(keep),
              [](const Entry& a, const Entry& b) { return a.index < b.index; });
    std::copy_n(scratch.begin(), keep, out);
    return uint32_t(keep);
}

// Sum of two index-sorted sparse vectors (a first, then b: a fixed summation order).
std::vector<Entry> mergeSum(const std::vector<Entry>& a, const std::vector<Entry>& b) {
    std::vector<Entry> out;
    out.reserve(a.size() + b.size());
    size_t i = 0;
    size_t j = 0;
    while (i < a.size() && j < b.size()) {
        if (a[i].index < b[j].index) {
            out.push_back(a[i++]);
        } else if (b[j].index < a[i].index) {
            out.push_back(b[j++]);
        } else {
            out.push_back({a[i].index, a[i].value + b[j].value});
            ++i;
            ++j;
        }
    }
    out.insert(out.end(), a.begin() + std::ptrdiff_t(i), a.end());
    out.insert(out.end(), b.begin() + std::ptrdiff_t(j), b.end());
    return out;
}

void validateCloud(const SampleCloud& cloud, const HierarchyOptions& o) {
    const size_t n = cloud.positions.size();
    if (n == 0) throw Error("hierarchy", "the sample cloud is empty");
    if (cloud.areas.size() != n || cloud.irradianceTransport.size() != n) {
        throw Error("hierarchy", "sample cloud arrays differ in length (" + std::to_string(n) +
                                     " positions, " + std::to_string(cloud.areas.size()) + " areas, " +
                                     std::to_string(cloud.irradianceTransport.size()) + " vectors)");
    }
    if (n >= (size_t(1) << 31)) {  // node indices (< 2n) must fit in 32 bits
        throw Error("hierarchy", "too many samples (" + std::to_string(n) + ")");
    }
    if (o.leafSize < 1) throw Error("leafSize", "must be >= 1");
    if (o.maxDepth < 0) throw Error("maxDepth", "must be >= 0");
    if (o.nodeCoefficients == 0) throw Error("nodeCoefficients", "must be >= 1");
    if (o.sampleShFrom != UINT32_MAX && o.nodeCoefficients <= size_t(o.shTerms))
        throw Error("nodeCoefficients", "must be more than the " + std::to_string(o.shTerms) +
                                            " SH terms the samples carry");
    for (size_t i = 0; i < n; ++i) {
        const glm::vec3& p = cloud.positions[i];
        if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) {
            throw Error("hierarchy", "sample " + std::to_string(i) + " has a non-finite position");
        }
        const float a = cloud.areas[i];
        if (!std::isfinite(a) || a < 0.0f) {
            throw Error("hierarchy", "sample " + std::to_string(i) + " has an invalid area (" +
                                         std::to_string(a) + ")");
        }
        const SparseVector& v = cloud.irradianceTransport[i];
        if (v.channels != 1) {
            throw Error("hierarchy", "sample " + std::to_string(i) + " irradiance vector has " +
                                         std::to_string(v.channels) + " channels, expected 1");
        }
        if (v.value.size() != v.index.size()) {
            throw Error("hierarchy", "sample " + std::to_string(i) +
                                         " irradiance vector has inconsistent index/value sizes");
        }
        for (size_t e = 1; e < v.index.size(); ++e) {
            if (v.index[e] <= v.index[e - 1]) {
                throw Error("hierarchy", "sample " + std::to_string(i) +
                                             " irradiance vector indices are not strictly increasing");
            }
        }
    }
}

// Builds the geometry of the tree: partitions `order` in place and fills the nodes'
// bounds, area, centroid, sample range, right child and depth.
struct GeometryBuilder {
    const std::vector<glm::vec3>& positions;
    const std::vector<float>& areas;
    const HierarchyOptions& options;
    std::vector<uint32_t>& order;
    std::vector<SampleTree::Node>& nodes;

    void build(uint32_t nodeIndex, uint32_t first, uint32_t count, int depth) {
        SampleTree::Node& node = nodes[nodeIndex];
        glm::vec3 lo(std::numeric_limits<float>::max());
        glm::vec3 hi(std::numeric_limits<float>::lowest());
        double area = 0.0;
        double wx = 0.0, wy = 0.0, wz = 0.0;  // area-weighted position sums
        double mx = 0.0, my = 0.0, mz = 0.0;  // plain sums (fallback for zero area)
        for (uint32_t k = first; k < first + count; ++k) {
            const uint32_t s = order[k];
            const glm::vec3& p = positions[s];
            const double a = areas[s];
            lo = glm::min(lo, p);
            hi = glm::max(hi, p);
            area += a;
            wx += a * p.x;
            wy += a * p.y;
            wz += a * p.z;
            mx += p.x;
            my += p.y;
            mz += p.z;
        }
        glm::dvec3 centroid = area > 0.0 ? glm::dvec3(wx, wy, wz) / area
                                         : glm::dvec3(mx, my, mz) / double(count);
        node.boundsMin = lo;
        node.boundsMax = hi;
        // Rounding can put the centroid a hair outside the box; clamp it in.
        node.centroid = glm::clamp(glm::vec3(centroid), lo, hi);
        node.area = float(area);
        node.first = first;
        node.count = count;
        node.depth = uint32_t(depth);
        node.right = 0;
        node.sumOffset = 0;
        node.sumCount = 0;
        node.padding = 0;
        if (isLeafNode(count, depth, options)) return;

        const glm::vec3 extent = hi - lo;
        int axis = 0;
        if (extent.y > extent[axis]) axis = 1;
        if (extent.z > extent[axis]) axis = 2;
        const uint32_t leftCount = count / 2;
        auto begin = order.begin() + std::ptrdiff_t(first);
        const auto& pos = positions;
        std::nth_element(begin, begin + std::ptrdiff_t(leftCount), begin + std::ptrdiff_t(count),
                         [&pos, axis](uint32_t a, uint32_t b) {
                             const float pa = pos[a][axis];
                             const float pb = pos[b][axis];
                             return pa < pb || (pa == pb && a < b);
                         });
        const uint32_t leftIndex = nodeIndex + 1;
        const uint32_t rightIndex = leftIndex + subtreeSize(leftCount, depth + 1, options);
        node.right = rightIndex;
        const uint32_t rightCount = count - leftCount;
        if (count > kParallelCutoff) {
            tbb::parallel_invoke(
                [&] { build(leftIndex, first, leftCount, depth + 1); },
                [&] { build(rightIndex, first + leftCount, rightCount, depth + 1); });
        } else {
            build(leftIndex, first, leftCount, depth + 1);
            build(rightIndex, first + leftCount, rightCount, depth + 1);
        }
    }
};

// Computes the node sums bottom-up into the (capacity-sized) node pool.
struct SumBuilder {
    const std::vector<uint64_t>& sampleOffsets;
    const std::vector<Entry>& sampleEntries;
    const HierarchyOptions& options;
    std::vector<SampleTree::Node>& nodes;
    std::vector<Entry>& pool;

    // Returns the node's exact sum (exactNodeSums) or its truncated sum.
    std::vector<Entry> build(uint32_t nodeIndex) {
        SampleTree::Node& node = nodes[nodeIndex];
        std::vector<Entry> sum;
        if (node.isLeaf()) {
            // Concatenate the samples' entries in sample order; a stable sort by index
            // then sums duplicates in sample order (deterministic).
            const uint64_t b = sampleOffsets[node.first];
            const uint64_t e = sampleOffsets[node.first + node.count];
            std::vector<Entry> all(sampleEntries.begin() + std::ptrdiff_t(b),
                                   sampleEntries.begin() + std::ptrdiff_t(e));
            std::stable_sort(all.begin(), all.end(),
                             [](const Entry& x, const Entry& y) { return x.index < y.index; });
            for (const Entry& x : all) {
                if (!sum.empty() && sum.back().index == x.index) {
                    sum.back().value += x.value;
                } else {
                    sum.push_back(x);
                }
            }
        } else {
            std::vector<Entry> left;
            std::vector<Entry> right;
            if (node.count > kParallelCutoff) {
                tbb::parallel_invoke([&] { left = build(nodeIndex + 1); },
                                     [&] { right = build(node.right); });
            } else {
                left = build(nodeIndex + 1);
                right = build(node.right);
            }
            sum = mergeSum(left, right);
        }
        node.sumCount = truncateEntries(sum, options.nodeCoefficients, pool.data() + node.sumOffset,
                                        options.sampleShFrom);
        if (options.exactNodeSums) return sum;
        std::vector<Entry> truncated(pool.begin() + std::ptrdiff_t(node.sumOffset),
                                     pool.begin() + std::ptrdiff_t(node.sumOffset + node.sumCount));
        return truncated;
    }
};

}  // namespace

SampleTree::SampleTree(SampleCloud cloud, const HierarchyOptions& options) {
    const Stopwatch start;
    validateCloud(cloud, options);
    const uint32_t n = uint32_t(cloud.positions.size());

    // 1. Geometry: partition a permutation of the samples, fill the nodes.
    const uint32_t nodeCount = subtreeSize(n, 0, options);
    nodes_.resize(nodeCount);
    originalIndex_.resize(n);
    std::iota(originalIndex_.begin(), originalIndex_.end(), 0u);
    GeometryBuilder geometry{cloud.positions, cloud.areas, options, originalIndex_, nodes_};
    geometry.build(0, 0, n, 0);
    for (const Node& node : nodes_) {
        maxDepthReached_ = std::max(maxDepthReached_, int(node.depth));
        leafCount_ += node.isLeaf();
    }

    // 2. Repack the samples in tree order; vectors premultiplied by their area.
    samplePositions_.resize(n);
    sampleAreas_.resize(n);
    sampleOffsets_.assign(size_t(n) + 1, 0);
    for (uint32_t k = 0; k < n; ++k) {
        sampleOffsets_[k + 1] = sampleOffsets_[k] + cloud.irradianceTransport[originalIndex_[k]].index.size();
    }
    sampleEntries_.resize(sampleOffsets_[n]);
    tbb::enumerable_thread_specific<uint32_t> maxIndex(0u);
    tbb::parallel_for(tbb::blocked_range<uint32_t>(0, n, 256), [&](const tbb::blocked_range<uint32_t>& r) {
        uint32_t& localMax = maxIndex.local();
        for (uint32_t k = r.begin(); k < r.end(); ++k) {
            const uint32_t s = originalIndex_[k];
            samplePositions_[k] = cloud.positions[s];
            const float a = cloud.areas[s];
            sampleAreas_[k] = a;
            SparseVector& v = cloud.irradianceTransport[s];
            Entry* out = sampleEntries_.data() + sampleOffsets_[k];
            for (size_t e = 0; e < v.index.size(); ++e) out[e] = {v.index[e], a * v.value[e]};
            if (!v.index.empty()) localMax = std::max(localMax, v.index.back() + 1);
            // Release the input as we go to keep the peak memory near one copy.
            std::vector<uint32_t>().swap(v.index);
            std::vector<float>().swap(v.value);
        }
    });
    for (uint32_t m : maxIndex) coefficientBound_ = std::max(coefficientBound_, size_t(m));

    // 3. Node sums: capacity min(nodeCoefficients, entries of the node's samples) per node, filled in
    //    parallel, then compacted in place (offsets only move down in pre-order).
    uint64_t capacity = 0;
    for (Node& node : nodes_) {
        node.sumOffset = capacity;
        const uint64_t entries = sampleOffsets_[node.first + node.count] - sampleOffsets_[node.first];
        capacity += std::min<uint64_t>(entries, options.nodeCoefficients);
    }
    nodeEntries_.resize(capacity);
    SumBuilder sums{sampleOffsets_, sampleEntries_, options, nodes_, nodeEntries_};
    sums.build(0);
    uint64_t used = 0;
    for (Node& node : nodes_) {
        if (node.sumOffset != used) {
            std::memmove(nodeEntries_.data() + used, nodeEntries_.data() + node.sumOffset,
                         size_t(node.sumCount) * sizeof(Entry));
            node.sumOffset = used;
        }
        used += node.sumCount;
    }
    nodeEntries_.resize(used);
    nodeEntries_.shrink_to_fit();
    buildSeconds_ = start.seconds();
}

SparseVector SampleTree::nodeSumVector(size_t node) const {
    SparseVector v;
    v.channels = 1;
    for (const Entry& e : nodeSum(node)) {
        v.index.push_back(e.index);
        v.value.push_back(e.value);
    }
    return v;
}

size_t SampleTree::nodeBytes() const {
    return nodes_.capacity() * sizeof(Node) + nodeEntries_.capacity() * sizeof(Entry);
}

size_t SampleTree::sampleBytes() const {
    return samplePositions_.capacity() * sizeof(glm::vec3) + sampleAreas_.capacity() * sizeof(float) +
           originalIndex_.capacity() * sizeof(uint32_t) + sampleOffsets_.capacity() * sizeof(uint64_t) +
           sampleEntries_.capacity() * sizeof(Entry);
}

namespace {

// k_c(r) / pi for every kernel.
inline void kernelWeights(const RadialKernels& kernels, double r, double* w) {
    kernels.evaluate(r, w);
    for (int c = 0; c < kernels.count(); ++c) w[c] /= kPi;
}

// acc[index][c] += w[c] value over the entries, K a compile-time constant for the
// kernel counts pass 2 runs with (the channel loop then unrolls and vectorises).
template <int K>
inline void accumulateFixed(std::span<const Entry> entries, const double* w, double* acc) {
    double wk[K];
    for (int c = 0; c < K; ++c) wk[c] = w[c];
    for (const Entry& e : entries) {
        double* d = acc + size_t(e.index) * K;
        const double v = e.value;
        for (int c = 0; c < K; ++c) d[c] += wk[c] * v;
    }
}

// K a multiple of four, into a float accumulator, four channels at a time: half the
// bytes of the double rows, which for the 12 profiles of editable transport is what the
// scattered additions wait on (docs/performance.md, "Pass 2 design measurements").
template <int K>
inline void accumulateQuads(std::span<const Entry> entries, const double* w, float* acc) {
    static_assert(K % 4 == 0);
    using Quad = float __attribute__((vector_size(16)));
    Quad wk[K / 4];
    for (int c = 0; c < K / 4; ++c) wk[c] = Quad{float(w[4 * c]), float(w[4 * c + 1]), float(w[4 * c + 2]), float(w[4 * c + 3])};
    for (const Entry& e : entries) {
        float* d = acc + size_t(e.index) * K;
        const float v = e.value;
        for (int c = 0; c < K / 4; ++c) {
            Quad x;
            std::memcpy(&x, d + 4 * c, sizeof(x));
            x += wk[c] * v;
            std::memcpy(d + 4 * c, &x, sizeof(x));
        }
    }
}

inline void accumulate(std::span<const Entry> entries, const double* w, int count, double* acc) {
    switch (count) {
        case 3: {
            // Written out: GCC compiles the template at K = 3 into slower code
            // (docs/performance.md, "Pass 2 design measurements").
            const double w0 = w[0], w1 = w[1], w2 = w[2];
            for (const Entry& e : entries) {
                double* d = acc + size_t(e.index) * 3;
                const double v = e.value;
                d[0] += w0 * v;
                d[1] += w1 * v;
                d[2] += w2 * v;
            }
            return;
        }
        case 6: return accumulateFixed<6>(entries, w, acc);
        case 9: return accumulateFixed<9>(entries, w, acc);
        case 15: return accumulateFixed<15>(entries, w, acc);
        default: break;
    }
    for (const Entry& e : entries) {
        double* d = acc + size_t(e.index) * size_t(count);
        const double v = e.value;
        for (int c = 0; c < count; ++c) d[c] += w[c] * v;
    }
}

inline double distance(const glm::vec3& a, const glm::vec3& b) {
    const double dx = double(a.x) - double(b.x);
    const double dy = double(a.y) - double(b.y);
    const double dz = double(a.z) - double(b.z);
    return std::sqrt(dx * dx + dy * dy + dz * dz);
}

inline bool insideWithMargin(const SampleTree::Node& node, const glm::vec3& x) {
    const glm::vec3 extent = node.boundsMax - node.boundsMin;
    const float margin = kBoundsMargin * std::max(extent.x, std::max(extent.y, extent.z));
    return x.x >= node.boundsMin.x - margin && x.x <= node.boundsMax.x + margin &&
           x.y >= node.boundsMin.y - margin && x.y <= node.boundsMax.y + margin &&
           x.z >= node.boundsMin.z - margin && x.z <= node.boundsMax.z + margin;
}

// Squared distance from x to the node's bounding box (0 inside).
inline float boxDistanceSquared(const SampleTree::Node& node, const glm::vec3& x) {
    const glm::vec3 d = glm::max(glm::max(node.boundsMin - x, x - node.boundsMax), glm::vec3(0.0f));
    return glm::dot(d, d);
}

// Checks that the tree's samples are the quadrature's (count and cell areas).
void checkCells(const SampleTree& tree, const CellQuadrature& cells) {
    if (cells.sampleCount() != tree.sampleCount()) {
        throw Error("hierarchy", "the cell quadrature has " + std::to_string(cells.sampleCount()) +
                                     " samples, the tree " + std::to_string(tree.sampleCount()));
    }
    for (size_t k = 0; k < tree.sampleCount(); ++k) {
        if (tree.sampleAreas()[k] != cells.cellArea(tree.originalIndex()[k])) {
            throw Error("hierarchy", "the tree's sample areas are not the cell quadrature's cell areas");
        }
    }
}

struct VertexCounters {
    uint32_t visited = 0;
    uint32_t used = 0;
    uint32_t samples = 0;
    double retained = 1.0;
};

}  // namespace

std::vector<SparseVector> multipleScatteringTransport(const SampleTree& tree,
                                                      std::span<const glm::vec3> vertices,
                                                      const Material& material,
                                                      const HierarchyOptions& options,
                                                      size_t texelCount,
                                                      MultipleScatteringStats* stats,
                                                      Progress* progress,
                                                      const CellQuadrature* cells) {
    return multipleScatteringTransport(tree, vertices, RadialKernels(material), options, texelCount, stats, progress,
                                       cells);
}

std::vector<SparseVector> multipleScatteringTransport(const SampleTree& tree,
                                                      std::span<const glm::vec3> vertices,
                                                      const RadialKernels& kernels,
                                                      const HierarchyOptions& options,
                                                      size_t texelCount,
                                                      MultipleScatteringStats* stats,
                                                      Progress* progress,
                                                      const CellQuadrature* cells) {
    const Stopwatch start;
    const int K = kernels.count();
    if (cells) {
        checkCells(tree, *cells);
        if (cells->kernels().count() != K)
            throw Error("hierarchy", "the cell quadrature integrates " + std::to_string(cells->kernels().count()) +
                                         " kernels, pass 2 " + std::to_string(K));
    }
    // With cells, a node is used whole only when no sample's cell reaches into the near
    // field (cell_quadrature.h), where the far kernel is not R_d.
    const float nearReach = cells ? float(cells->outerRadius()) + cells->maxCellRadius() : 0.0f;
    const float nearReach2 = nearReach * nearReach;
    const auto& originalIndex = tree.originalIndex();
    const auto& sampleAreas = tree.sampleAreas();
    if (!(options.epsilon >= 0.0) || !std::isfinite(options.epsilon)) {
        throw Error("epsilon", "must be finite and >= 0");
    }
    // Sample vectors may carry SH entries (indices texelCount + i, i < shTerms).
    const size_t spaceCount = texelCount + size_t(options.shTerms);
    if (options.sampleShFrom != UINT32_MAX && options.sampleShFrom != texelCount)
        throw Error("hierarchy", "the samples' SH part starts at index " + std::to_string(options.sampleShFrom) +
                                     ", not at coefficientCount " + std::to_string(texelCount));
    if (spaceCount < tree.coefficientBound()) {
        throw Error("hierarchy", "coefficientCount " + std::to_string(texelCount) + " + " +
                                     std::to_string(options.shTerms) + " SH terms is too small for coefficient index " +
                                     std::to_string(tree.coefficientBound() - 1));
    }
    if (texelCount > size_t(std::numeric_limits<uint32_t>::max()) + 1) {
        throw Error("hierarchy", "coefficientCount too large");
    }
    const double epsilon = options.epsilon;
    const auto& nodes = tree.nodes();
    const auto& positions = tree.samplePositions();

    if (vertices.size() > size_t(std::numeric_limits<uint32_t>::max())) {
        throw Error("hierarchy", "too many vertices");
    }
    // Along a Morton curve, consecutive vertices of a thread reuse the node sums in cache.
    const std::vector<uint32_t> order = mortonOrder(vertices, "hierarchy");
    std::vector<SparseVector> result(vertices.size());
    std::vector<VertexCounters> counters(vertices.size());

    // A dense accumulator of doubles per thread, (6 N^2 + shTerms) x K: as fast as
    // floats (the scattered additions are bound by reading the node sums) and closer to
    // the brute force (docs/performance.md, "Pass 2 design measurements"). It is cleared
    // with one fill: tracking the touched entries would test every scattered addition,
    // and the truncation reads the whole block anyway.
    struct Scratch {
        std::vector<double> acc;     // the accumulator
        std::vector<float> rounded;  // its float copy for the truncation
        std::vector<uint32_t> stack;
    };
    tbb::enumerable_thread_specific<Scratch> scratch;

    // Twelve kernels (editable transport's profiles) accumulate in float (see
    // accumulateQuads); the sums are then ~1e-6 relative, below the files' 16-bit
    // quantization.
    const bool floatSums = K == 12;
    const auto add = [&](std::span<const Entry> entries, const double* w, double* acc, float* accFloat) {
        if (floatSums)
            accumulateQuads<12>(entries, w, accFloat);
        else
            accumulate(entries, w, K, acc);
    };

    tbb::parallel_for(tbb::blocked_range<size_t>(0, vertices.size(), 8), [&](const tbb::blocked_range<size_t>& r) {
        Scratch& s = scratch.local();
        if (s.rounded.size() != spaceCount * size_t(K)) {
            if (!floatSums) s.acc.assign(spaceCount * size_t(K), 0.0);
            s.rounded.assign(spaceCount * size_t(K), 0.0f);
        }
        double* acc = s.acc.data();
        float* accFloat = s.rounded.data();
        for (size_t o = r.begin(); o < r.end(); ++o) {
            const uint32_t v = order[o];
            const glm::vec3 x = vertices[v];
            VertexCounters& count = counters[v];
            s.stack.clear();
            s.stack.push_back(0);
            double w[kMaxRadialKernels];
            while (!s.stack.empty()) {
                const uint32_t ni = s.stack.back();
                s.stack.pop_back();
                const SampleTree::Node& node = nodes[ni];
                ++count.visited;
                const double d = distance(x, node.centroid);
                if (!insideWithMargin(node, x) && double(node.area) < epsilon * d * d &&
                    (!cells || boxDistanceSquared(node, x) >= nearReach2)) {
                    kernelWeights(kernels, d, w);
                    add(tree.nodeSum(ni), w, acc, accFloat);
                    ++count.used;
                } else if (node.isLeaf()) {
                    for (uint32_t k = node.first; k < node.first + node.count; ++k) {
                        if (cells) {
                            // The entries hold A_k E_k; the cell rule's weight w_k replaces A_k R_d.
                            const double area = sampleAreas[k];
                            if (area <= 0.0) continue;
                            cells->sampleWeightOverPi(originalIndex[k], x, w);
                            for (int c = 0; c < K; ++c) w[c] /= area;
                        } else {
                            kernelWeights(kernels, distance(x, positions[k]), w);
                        }
                        add(tree.sampleEntries(k), w, acc, accFloat);
                    }
                    count.samples += node.count;
                } else {
                    s.stack.push_back(node.right);
                    s.stack.push_back(ni + 1);  // left child first
                }
            }
            if (!floatSums) {
                std::copy(s.acc.begin(), s.acc.end(), s.rounded.begin());
                std::fill(s.acc.begin(), s.acc.end(), 0.0);
            }
            result[v] = truncateWithShPart(s.rounded.data(), texelCount, K, options.shTerms,
                                           options.vertexCoefficients, &count.retained);
            if (floatSums) std::fill(s.rounded.begin(), s.rounded.end(), 0.0f);
        }
        if (progress) progress->advance(r.size());
    });

    if (stats) {
        double visited = 0.0, used = 0.0, samples = 0.0, retained = 0.0;
        for (const VertexCounters& c : counters) {
            visited += c.visited;
            used += c.used;
            samples += c.samples;
            retained += c.retained;
        }
        const double nv = vertices.empty() ? 1.0 : double(vertices.size());
        stats->meanNodesVisited = visited / nv;
        stats->meanNodesUsed = used / nv;
        stats->meanSamplesUsed = samples / nv;
        stats->retainedEnergyFraction = vertices.empty() ? 1.0 : retained / nv;
        stats->seconds = start.seconds();
        stats->treeBytes = tree.bytes();
    }
    return result;
}

std::vector<SparseVector> multipleScatteringBruteForce(const SampleCloud& cloud,
                                                       std::span<const glm::vec3> vertices,
                                                       const Material& material,
                                                       size_t texelCount,
                                                       size_t vertexCoefficients,
                                                       const CellQuadrature* cells, int shTerms) {
    return multipleScatteringBruteForce(cloud, vertices, RadialKernels(material), texelCount, vertexCoefficients, cells,
                                        shTerms);
}

std::vector<SparseVector> multipleScatteringBruteForce(const SampleCloud& cloud,
                                                       std::span<const glm::vec3> vertices,
                                                       const RadialKernels& kernels,
                                                       size_t texelCount,
                                                       size_t vertexCoefficients,
                                                       const CellQuadrature* cells, int shTerms) {
    const int K = kernels.count();
    if (cells && cells->kernels().count() != K) throw Error("hierarchy", "the cell quadrature's kernels are not pass 2's");
    if (cells && cells->sampleCount() != cloud.positions.size()) {
        throw Error("hierarchy", "the cell quadrature's samples are not the cloud's");
    }
    const size_t n = cloud.positions.size();
    if (cloud.areas.size() != n || cloud.irradianceTransport.size() != n) {
        throw Error("hierarchy", "sample cloud arrays differ in length");
    }
    for (const SparseVector& e : cloud.irradianceTransport) {
        if (e.channels != 1 || e.value.size() != e.index.size()) {
            throw Error("hierarchy", "irradiance vectors must have one channel and consistent sizes");
        }
        for (uint32_t idx : e.index) {
            if (idx >= texelCount + size_t(shTerms)) {
                throw Error("hierarchy", "coefficient index " + std::to_string(idx) + " >= coefficientCount " +
                                             std::to_string(texelCount) + " + " + std::to_string(shTerms) +
                                             " SH terms");
            }
        }
    }
    std::vector<SparseVector> result(vertices.size());
    tbb::parallel_for(size_t(0), vertices.size(), [&](size_t v) {
        std::vector<double> acc((texelCount + size_t(shTerms)) * size_t(K), 0.0);
        for (size_t i = 0; i < n; ++i) {
            const double r = distance(vertices[v], cloud.positions[i]);
            const SparseVector& e = cloud.irradianceTransport[i];
            double weight[kMaxRadialKernels];
            if (cells) {
                cells->sampleWeightOverPi(i, vertices[v], weight);
            } else {
                kernels.evaluate(r, weight);
                for (int c = 0; c < K; ++c) weight[c] = double(cloud.areas[i]) * weight[c] / kPi;
            }
            for (int c = 0; c < K; ++c) {
                for (size_t k = 0; k < e.index.size(); ++k) {
                    acc[size_t(e.index[k]) * size_t(K) + size_t(c)] += weight[c] * double(e.value[k]);
                }
            }
        }
        std::vector<float> dense(acc.begin(), acc.end());
        result[v] = truncateWithShPart(dense.data(), texelCount, K, shTerms, vertexCoefficients);
    });
    return result;
}

}  // namespace prt
