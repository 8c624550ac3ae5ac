#include "common/sampling.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>
#include <tbb/parallel_sort.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <string>
#include <utility>

#include "common/error.h"

namespace prt {
namespace {

// ---------------------------------------------------------------------------------
// Deterministic counter-based random numbers: value i of the stream for `seed` is
// the splitmix64 finaliser applied to base + i * golden, so any value can be drawn
// independently of the others (parallel generation gives the same numbers as a
// serial loop, on every standard library).

constexpr uint64_t kGolden = 0x9E3779B97F4A7C15ull;

uint64_t mix64(uint64_t z) {
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
}

class CounterRng {
public:
    explicit CounterRng(uint64_t seed) : base_(mix64(seed ^ 0x5A3F1C2B9D8E7061ull)) {}
    uint64_t bits(uint64_t i) const { return mix64(base_ + (i + 1) * kGolden); }
    // Uniform double in [0, 1) with 53 random bits.
    double uniform(uint64_t i) const { return double(bits(i) >> 11) * 0x1.0p-53; }

private:
    uint64_t base_;
};

// ---------------------------------------------------------------------------------
// Mesh preparation: triangle areas, geometric normals and the area CDF over the
// triangles of positive area (degenerate triangles are left out of the CDF, so they
// can never be chosen).

struct PreparedMesh {
    std::vector<glm::dvec3> faceNormal;  // unit, per triangle (zero when degenerate)
    std::vector<uint32_t> positiveTriangles;
    std::vector<double> cdf;  // cdf[k] = sum of areas of positiveTriangles[0..k]
    double totalArea = 0.0;
    bool useVertexNormals = false;
};

PreparedMesh prepareMesh(const TriangleMesh& mesh) {
    const size_t nt = mesh.triangles.size();
    const size_t nv = mesh.positions.size();
    if (nt == 0) throw Error("mesh", "has no triangles to sample");
    if (nt > size_t(std::numeric_limits<uint32_t>::max()))
        throw Error("mesh", "too many triangles to sample (" + std::to_string(nt) + ")");
    PreparedMesh pm;
    pm.faceNormal.assign(nt, glm::dvec3(0.0));
    std::vector<double> area(nt, 0.0);
    for (size_t t = 0; t < nt; ++t) {
        const glm::uvec3 tri = mesh.triangles[t];
        for (int c = 0; c < 3; ++c)
            if (tri[c] >= nv)
                throw Error("mesh", "triangle " + std::to_string(t) + " references vertex " +
                                        std::to_string(tri[c]) + " of " + std::to_string(nv));
        const glm::dvec3 p0(mesh.positions[tri.x]);
        const glm::dvec3 cr = glm::cross(glm::dvec3(mesh.positions[tri.y]) - p0,
                                         glm::dvec3(mesh.positions[tri.z]) - p0);
        const double len = glm::length(cr);
        if (!std::isfinite(len))
            throw Error("mesh", "triangle " + std::to_string(t) + " has non-finite coordinates");
        area[t] = 0.5 * len;
        if (len > 0.0) pm.faceNormal[t] = cr / len;
    }
    pm.positiveTriangles.reserve(nt);
    pm.cdf.reserve(nt);
    double sum = 0.0;
    for (size_t t = 0; t < nt; ++t) {
        if (!(area[t] > 0.0) || glm::length(pm.faceNormal[t]) == 0.0) continue;
        sum += area[t];
        pm.positiveTriangles.push_back(uint32_t(t));
        pm.cdf.push_back(sum);
    }
    if (!(sum > 0.0) || !std::isfinite(sum))
        throw Error("mesh", "total surface area is zero; nothing to sample");
    pm.totalArea = sum;
    pm.useVertexNormals = mesh.normals.size() == nv;
    return pm;
}

// Candidate number k uses stream values 3k, 3k + 1, 3k + 2: triangle choice by area,
// then uniform barycentrics with the square-root warp (b1 = sqrt(u1) u2,
// b2 = sqrt(u1) (1 - u2)).
struct Draw {
    uint32_t triangle;
    glm::vec2 bary;
};

Draw drawSample(const PreparedMesh& pm, const CounterRng& rng, uint64_t k) {
    const double x = rng.uniform(3 * k) * pm.totalArea;
    size_t idx = size_t(std::upper_bound(pm.cdf.begin(), pm.cdf.end(), x) - pm.cdf.begin());
    if (idx >= pm.cdf.size()) idx = pm.cdf.size() - 1;
    const double su = std::sqrt(rng.uniform(3 * k + 1));
    const double u2 = rng.uniform(3 * k + 2);
    float b1 = float(su * u2);
    float b2 = float(su * (1.0 - u2));
    if (b1 + b2 > 1.0f) b2 = 1.0f - b1;
    return {pm.positiveTriangles[idx], glm::vec2(b1, b2)};
}

glm::vec3 samplePosition(const TriangleMesh& mesh, uint32_t t, glm::vec2 b) {
    const glm::uvec3 tri = mesh.triangles[t];
    const double b1 = b.x, b2 = b.y, b0 = 1.0 - b1 - b2;
    return glm::vec3(b0 * glm::dvec3(mesh.positions[tri.x]) + b1 * glm::dvec3(mesh.positions[tri.y]) +
                     b2 * glm::dvec3(mesh.positions[tri.z]));
}

SurfaceSample makeSample(const TriangleMesh& mesh, const PreparedMesh& pm, uint32_t t, glm::vec2 b,
                         const glm::vec3& position) {
    SurfaceSample s;
    s.position = position;
    s.triangle = t;
    s.barycentric = b;
    const glm::dvec3 ng = pm.faceNormal[t];
    s.geometricNormal = glm::vec3(ng);
    glm::dvec3 n = ng;
    if (pm.useVertexNormals) {
        const glm::uvec3 tri = mesh.triangles[t];
        const double b1 = b.x, b2 = b.y, b0 = 1.0 - b1 - b2;
        const glm::dvec3 ni = b0 * glm::dvec3(mesh.normals[tri.x]) + b1 * glm::dvec3(mesh.normals[tri.y]) +
                              b2 * glm::dvec3(mesh.normals[tri.z]);
        const double len = glm::length(ni);
        // Keep the interpolated normal only when it is usable and on the front side.
        if (std::isfinite(len) && len > 1e-12 && glm::dot(ni, ng) > 0.0) n = ni / len;
    }
    s.normal = glm::vec3(n);
    return s;
}

// ---------------------------------------------------------------------------------
// Uniform grid over 3D points, stored sparsely: points sorted by the Morton (Z-order)
// code of their cell, so that cells close in space are mostly close in memory; a hash
// table from cell code to cell, used once per cell to list the non-empty cells of its
// 3 x 3 x 3 block as ranges of the sorted order.

// Spreads the low 21 bits of v so that bit k moves to bit 3k.
uint64_t spreadBits3(uint64_t v) {
    v &= 0x1FFFFFull;
    v = (v | (v << 32)) & 0x1F00000000FFFFull;
    v = (v | (v << 16)) & 0x1F0000FF0000FFull;
    v = (v | (v << 8)) & 0x100F00F00F00F00Full;
    v = (v | (v << 4)) & 0x10C30C30C30C30C3ull;
    v = (v | (v << 2)) & 0x1249249249249249ull;
    return v;
}

uint64_t compactBits3(uint64_t v) {
    v &= 0x1249249249249249ull;
    v = (v | (v >> 2)) & 0x10C30C30C30C30C3ull;
    v = (v | (v >> 4)) & 0x100F00F00F00F00Full;
    v = (v | (v >> 8)) & 0x1F0000FF0000FFull;
    v = (v | (v >> 16)) & 0x1F00000000FFFFull;
    v = (v | (v >> 32)) & 0x1FFFFFull;
    return v;
}

struct Range {
    uint32_t begin;
    uint32_t end;
};

class CellGrid {
public:
    static constexpr int64_t kMaxDim = (int64_t(1) << 21) - 1;
    static constexpr uint32_t kEmpty = std::numeric_limits<uint32_t>::max();

    // cellSize is a lower bound: it grows when the bounding box would need more than
    // kMaxDim cells along an axis.
    CellGrid(const std::vector<glm::vec3>& points, double cellSize) {
        const size_t n = points.size();
        glm::dvec3 lo(std::numeric_limits<double>::max()), hi(-std::numeric_limits<double>::max());
        for (const glm::vec3& p : points) {
            lo = glm::min(lo, glm::dvec3(p));
            hi = glm::max(hi, glm::dvec3(p));
        }
        if (n == 0) lo = hi = glm::dvec3(0.0);
        origin_ = lo;
        const double extent = std::max({hi.x - lo.x, hi.y - lo.y, hi.z - lo.z});
        cell_ = std::max(cellSize, extent / double(kMaxDim - 2));
        if (!(cell_ > 0.0)) cell_ = 1.0;
        for (int a = 0; a < 3; ++a) dims_[a] = std::min<int64_t>(int64_t((hi[a] - lo[a]) / cell_) + 1, kMaxDim);

        std::vector<std::pair<uint64_t, uint32_t>> keyed(n);
        tbb::parallel_for(tbb::blocked_range<size_t>(0, n), [&](const tbb::blocked_range<size_t>& r) {
            for (size_t i = r.begin(); i != r.end(); ++i) keyed[i] = {keyOf(coordsOf(points[i])), uint32_t(i)};
        });
        tbb::parallel_sort(keyed.begin(), keyed.end());  // total order: the result is unique

        order_.resize(n);
        for (size_t i = 0; i < n; ++i) {
            order_[i] = keyed[i].second;
            if (i == 0 || keyed[i].first != keyed[i - 1].first) {
                cellKeys_.push_back(keyed[i].first);
                cellBegin_.push_back(uint32_t(i));
            }
        }
        cellBegin_.push_back(uint32_t(n));
        const size_t nc = cellKeys_.size();

        size_t capacity = 16;
        while (capacity < 2 * nc) capacity *= 2;
        const size_t mask = capacity - 1;
        std::vector<uint32_t> table(capacity, kEmpty);
        for (size_t c = 0; c < nc; ++c) {
            size_t slot = mix64(cellKeys_[c]) & mask;
            while (table[slot] != kEmpty) slot = (slot + 1) & mask;
            table[slot] = uint32_t(c);
        }
        const auto find = [&](uint64_t key) {
            size_t slot = mix64(key) & mask;
            while (true) {
                const uint32_t c = table[slot];
                if (c == kEmpty || cellKeys_[c] == key) return c;
                slot = (slot + 1) & mask;
            }
        };

        std::vector<std::array<Range, 27>> found(nc);
        std::vector<uint8_t> foundCount(nc, 0);
        tbb::parallel_for(tbb::blocked_range<size_t>(0, nc), [&](const tbb::blocked_range<size_t>& r) {
            for (size_t c = r.begin(); c != r.end(); ++c) {
                const glm::i64vec3 cc = coordsOfKey(cellKeys_[c]);
                uint8_t k = 0;
                for (int64_t z = cc.z - 1; z <= cc.z + 1; ++z) {
                    if (z < 0 || z >= dims_[2]) continue;
                    for (int64_t y = cc.y - 1; y <= cc.y + 1; ++y) {
                        if (y < 0 || y >= dims_[1]) continue;
                        for (int64_t x = cc.x - 1; x <= cc.x + 1; ++x) {
                            if (x < 0 || x >= dims_[0]) continue;
                            const uint32_t other = find(keyOf({x, y, z}));
                            if (other != kEmpty) found[c][k++] = {cellBegin_[other], cellBegin_[other + 1]};
                        }
                    }
                }
                foundCount[c] = k;
            }
        });
        neighbourBegin_.resize(nc + 1);
        neighbourBegin_[0] = 0;
        for (size_t c = 0; c < nc; ++c) neighbourBegin_[c + 1] = neighbourBegin_[c] + foundCount[c];
        neighbours_.resize(neighbourBegin_[nc]);
        for (size_t c = 0; c < nc; ++c)
            std::copy_n(found[c].begin(), foundCount[c], neighbours_.begin() + neighbourBegin_[c]);
    }

    double cellSize() const { return cell_; }
    size_t cellCount() const { return cellKeys_.size(); }
    // Sorted-order range of the points in cell c.
    Range cell(size_t c) const { return {cellBegin_[c], cellBegin_[c + 1]}; }
    // Point indices in cell order; the ranges index this order.
    const std::vector<uint32_t>& order() const { return order_; }

    // Calls fn(range) for every non-empty cell of the 3 x 3 x 3 block around cell c
    // (c included), in a fixed order. Any two points closer than cellSize() lie in
    // such a block.
    template <class Fn>
    void forEachNeighbourCell(size_t c, Fn&& fn) const {
        for (uint32_t q = neighbourBegin_[c]; q < neighbourBegin_[c + 1]; ++q) fn(neighbours_[q]);
    }

private:
    glm::i64vec3 coordsOf(const glm::vec3& p) const {
        glm::i64vec3 c;
        for (int a = 0; a < 3; ++a)
            c[a] = std::clamp<int64_t>(int64_t(std::floor((double(p[a]) - origin_[a]) / cell_)), 0, dims_[a] - 1);
        return c;
    }

    static uint64_t keyOf(const glm::i64vec3& c) {
        return spreadBits3(uint64_t(c.x)) | (spreadBits3(uint64_t(c.y)) << 1) | (spreadBits3(uint64_t(c.z)) << 2);
    }
    static glm::i64vec3 coordsOfKey(uint64_t key) {
        return {int64_t(compactBits3(key)), int64_t(compactBits3(key >> 1)), int64_t(compactBits3(key >> 2))};
    }

    glm::dvec3 origin_{0.0};
    double cell_ = 1.0;
    int64_t dims_[3] = {1, 1, 1};
    std::vector<uint32_t> order_;
    std::vector<uint64_t> cellKeys_;
    std::vector<uint32_t> cellBegin_;
    std::vector<uint32_t> neighbourBegin_;  // per cell, into neighbours_
    std::vector<Range> neighbours_;
};

// Asks the cache for the records of range r (a hint; no effect on results).
template <class T>
void prefetch(const std::vector<T>& v, Range r) {
#if defined(__GNUC__)
    if (r.begin == r.end) return;
    const uintptr_t first = reinterpret_cast<uintptr_t>(v.data() + r.begin) & ~uintptr_t(63);
    const uintptr_t last = reinterpret_cast<uintptr_t>(v.data() + r.end) - 1;
    for (uintptr_t q = first; q <= last; q += 64) __builtin_prefetch(reinterpret_cast<const void*>(q));
#else
    (void)v;
    (void)r;
#endif
}

double distance2(const glm::vec3& a, const glm::vec3& b) {
    const glm::dvec3 d = glm::dvec3(a) - glm::dvec3(b);
    return glm::dot(d, d);
}

void checkCount(size_t count, size_t limit) {
    if (count == 0) throw Error("sample count", "must be at least 1");
    if (count > limit)
        throw Error("sample count", std::to_string(count) + " exceeds the supported maximum " + std::to_string(limit));
}

SampleSet finish(std::vector<SurfaceSample> samples, double totalArea) {
    SampleSet set;
    set.samples = std::move(samples);
    set.totalArea = totalArea;
    set.areaPerSample = totalArea / double(set.samples.size());
    set.minSpacing = minimumPairwiseDistance(set.samples);
    return set;
}

}  // namespace

double hexagonalPackingRadius(double area, size_t count) {
    if (count == 0 || !(area >= 0.0)) return 0.0;
    return std::sqrt(area / (2.0 * std::sqrt(3.0) * double(count)));
}

size_t defaultSampleCount(double totalAreaMm2, double spacingMm, size_t cap) {
    if (!(totalAreaMm2 > 0.0) || !std::isfinite(totalAreaMm2))
        throw Error("surface area", "must be positive and finite (got " + std::to_string(totalAreaMm2) + ")");
    if (!(spacingMm > 0.0) || !std::isfinite(spacingMm))
        throw Error("sample spacing", "must be positive and finite (got " + std::to_string(spacingMm) + ")");
    if (cap == 0) throw Error("sample cap", "must be at least 1");
    // Hexagonal packing with neighbour distance `spacing`: (sqrt(3) / 2) spacing^2 per sample.
    const double n = std::ceil(2.0 * totalAreaMm2 / (std::sqrt(3.0) * spacingMm * spacingMm));
    const size_t lower = std::min(kMinSampleCount, cap);
    if (!(n < double(cap))) return cap;  // also catches overflow to infinity
    return std::max(size_t(n), lower);
}

SampleSet uniformRandomSamples(const TriangleMesh& mesh, size_t count, uint64_t seed) {
    checkCount(count, size_t(std::numeric_limits<uint32_t>::max()) - 1);
    const PreparedMesh pm = prepareMesh(mesh);
    const CounterRng rng(seed);
    std::vector<SurfaceSample> samples(count);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, count), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t k = r.begin(); k != r.end(); ++k) {
            const Draw d = drawSample(pm, rng, k);
            samples[k] = makeSample(mesh, pm, d.triangle, d.bary, samplePosition(mesh, d.triangle, d.bary));
        }
    });
    return finish(std::move(samples), pm.totalArea);
}

SampleSet poissonDiskSamples(const TriangleMesh& mesh, size_t count, uint64_t seed,
                             const PoissonDiskOptions& options) {
    if (!(options.candidateFactor >= 1.0) || !(options.candidateFactor <= 1000.0))
        throw Error("candidate factor", "must be in [1, 1000] (got " + std::to_string(options.candidateFactor) + ")");
    const size_t limit = size_t(std::numeric_limits<uint32_t>::max()) - 1;
    checkCount(count, size_t(double(limit) / options.candidateFactor));
    const PreparedMesh pm = prepareMesh(mesh);
    const CounterRng rng(seed);

    // 1. Candidates, uniform by area.
    const size_t m = std::max(count, size_t(std::ceil(options.candidateFactor * double(count))));
    std::vector<Draw> draws(m);
    std::vector<glm::vec3> points(m);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, m), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t k = r.begin(); k != r.end(); ++k) {
            draws[k] = drawSample(pm, rng, k);
            points[k] = samplePosition(mesh, draws[k].triangle, draws[k].bary);
        }
    });

    // 2. Grid with cells of at least 2 r_max. From here on candidates live in cell
    //    order, in one 32-byte record each (position, sheet normal, weight) so that
    //    the random-access elimination touches few cache lines.
    const double rMax = hexagonalPackingRadius(pm.totalArea, count);
    const double reach = 2.0 * rMax;
    const CellGrid grid(points, reach);
    struct Candidate {
        glm::vec3 p;
        glm::vec3 n;  // geometric normal of its triangle, for the sheet test
        double w;     // weight; -infinity once eliminated
    };
    constexpr double kGone = -std::numeric_limits<double>::infinity();
    std::vector<Candidate> cand(m);
    std::vector<Draw> sortedDraws(m);
    for (size_t k = 0; k < m; ++k) {
        const uint32_t src = grid.order()[k];
        sortedDraws[k] = draws[src];
        cand[k] = {points[src], glm::vec3(pm.faceNormal[draws[src].triangle]), 0.0};
    }
    draws = std::vector<Draw>();
    points = std::vector<glm::vec3>();

    // 3. Weights. Yuksel's weight limiting: distances below 2 r_min count as 2 r_min.
    //    (gamma = 1.5 written as ratio * sqrt(ratio): correctly rounded everywhere).
    const double ratio = double(count) / double(m);
    const double rMin = options.weightLimiting ? rMax * 0.65 * (1.0 - ratio * std::sqrt(ratio)) : 0.0;
    const double reach2 = reach * reach;
    const float sheetCos = float(options.sheetCosine);
    const bool sheetTest = options.sheetCosine > -1.0;
    // Weight of the pair (a, b) in w; false when they do not interact.
    auto pairWeight = [&](const Candidate& a, const Candidate& b, double& w) -> bool {
        const double d2 = distance2(a.p, b.p);
        if (d2 >= reach2) return false;
        if (sheetTest && glm::dot(a.n, b.n) < sheetCos) return false;
        const double d = std::max(std::sqrt(d2), 2.0 * rMin);
        const double x = 1.0 - d / reach;
        const double x2 = x * x, x4 = x2 * x2;
        w = x4 * x4;  // alpha = 8
        return true;
    };
    tbb::parallel_for(tbb::blocked_range<size_t>(0, grid.cellCount()), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t c = r.begin(); c != r.end(); ++c) {
            const Range own = grid.cell(c);
            for (uint32_t i = own.begin; i < own.end; ++i) {
                double sum = 0.0;
                grid.forEachNeighbourCell(c, [&](Range nb) {
                    for (uint32_t j = nb.begin; j < nb.end; ++j) {
                        double w;
                        if (j != i && pairWeight(cand[i], cand[j], w)) sum += w;
                    }
                });
                cand[i].w = sum;
            }
        }
    });

    // 4. Elimination (serial: the order of removals defines the result). Always the
    //    alive candidate of largest weight goes (ties: smaller index). A lazy max-heap
    //    holds one (weight, index) snapshot per non-empty cell, its best candidate when
    //    the snapshot was taken. Weights only decrease, so a snapshot bounds its
    //    cell's current best from above; an out-of-date top is replaced by the cell's
    //    current best, and an up-to-date top is the global maximum. Keys are distinct,
    //    so the order is total and the result does not depend on the heap
    //    implementation. One entry per cell (not per candidate) keeps the heap small.
    {
        constexpr uint32_t kNone = std::numeric_limits<uint32_t>::max();
        struct Entry {
            double w;
            uint32_t i;
            uint32_t cell;
        };
        const auto below = [](const Entry& a, const Entry& b) { return a.w < b.w || (a.w == b.w && a.i > b.i); };
        const auto cellBest = [&](uint32_t c) {
            Entry best{kGone, kNone, c};
            const Range r = grid.cell(c);
            for (uint32_t j = r.begin; j < r.end; ++j)
                if (cand[j].w != kGone && (best.i == kNone || cand[j].w > best.w)) best = {cand[j].w, j, c};
            return best;
        };
        std::vector<Entry> heap(grid.cellCount());
        for (size_t c = 0; c < heap.size(); ++c) heap[c] = cellBest(uint32_t(c));
        std::make_heap(heap.begin(), heap.end(), below);
        for (size_t alive = m; alive > count;) {
            prefetch(cand, grid.cell(heap.front().cell));  // overlaps with pop_heap
            std::pop_heap(heap.begin(), heap.end(), below);
            Entry& top = heap.back();
            const Entry now = cellBest(top.cell);
            if (now.i == kNone) {  // cannot happen (a cell's last candidate leaves below); defensive
                heap.pop_back();
                continue;
            }
            if (now.i != top.i || now.w != top.w) {  // out of date
                top = now;
                std::push_heap(heap.begin(), heap.end(), below);
                continue;
            }
            Candidate& gone = cand[top.i];
            gone.w = kGone;
            --alive;
            // The neighbour cells are scattered in memory: request them all at once
            // so that their cache misses overlap instead of following one another.
            grid.forEachNeighbourCell(top.cell, [&](Range nb) { prefetch(cand, nb); });
            grid.forEachNeighbourCell(top.cell, [&](Range nb) {
                for (uint32_t j = nb.begin; j < nb.end; ++j) {
                    double w;
                    if (cand[j].w != kGone && pairWeight(gone, cand[j], w)) cand[j].w -= w;
                }
            });
            const Entry next = cellBest(top.cell);
            if (next.i == kNone) {
                heap.pop_back();
            } else {
                top = next;
                std::push_heap(heap.begin(), heap.end(), below);
            }
        }
    }

    // 5. Survivors, in cell (Morton) order.
    std::vector<SurfaceSample> samples;
    samples.reserve(count);
    for (size_t i = 0; i < m; ++i)
        if (cand[i].w != kGone)
            samples.push_back(makeSample(mesh, pm, sortedDraws[i].triangle, sortedDraws[i].bary, cand[i].p));
    return finish(std::move(samples), pm.totalArea);
}

double minimumPairwiseDistance(const std::vector<SurfaceSample>& samples) {
    const size_t n = samples.size();
    if (n < 2) return 0.0;
    std::vector<glm::vec3> points(n);
    glm::dvec3 lo(std::numeric_limits<double>::max()), hi(-std::numeric_limits<double>::max());
    for (size_t i = 0; i < n; ++i) {
        points[i] = samples[i].position;
        lo = glm::min(lo, glm::dvec3(points[i]));
        hi = glm::max(hi, glm::dvec3(points[i]));
    }
    const double diagonal = glm::length(hi - lo);
    if (!(diagonal > 0.0)) return 0.0;
    // Any pair closer than the cell size lies in one 3 x 3 x 3 block, so a minimum
    // found below the cell size is exact; otherwise retry with larger cells.
    double cell = diagonal / std::sqrt(double(n));
    while (true) {
        const CellGrid grid(points, cell);
        std::vector<glm::vec3> sorted(n);
        for (size_t k = 0; k < n; ++k) sorted[k] = points[grid.order()[k]];
        const double best2 = tbb::parallel_reduce(
            tbb::blocked_range<size_t>(0, grid.cellCount()), std::numeric_limits<double>::infinity(),
            [&](const tbb::blocked_range<size_t>& r, double best) {
                for (size_t c = r.begin(); c != r.end(); ++c) {
                    const Range own = grid.cell(c);
                    grid.forEachNeighbourCell(c, [&](Range nb) {
                        for (uint32_t i = own.begin; i < own.end; ++i)
                            for (uint32_t j = nb.begin; j < nb.end; ++j)
                                if (j != i) best = std::min(best, distance2(sorted[i], sorted[j]));
                    });
                }
                return best;
            },
            [](double x, double y) { return std::min(x, y); });
        const double best = std::sqrt(best2);
        if (best <= grid.cellSize() || grid.cellSize() >= diagonal) return best;
        cell = grid.cellSize() * 4.0;
    }
}

}  // namespace prt
