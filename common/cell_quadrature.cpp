#include "common/cell_quadrature.h"

#include "common/error.h"
#include "common/mesh.h"
#include "common/point_grid.h"
#include "common/util.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

namespace prt {

namespace {

// Samples bucketed in a hashed grid of cell size `cell` for nearest-sample queries.
class SampleGrid {
public:
    SampleGrid(std::span<const glm::vec3> positions, double cell) : positions_(positions), grid_(positions, cell) {}

    // The nearest sample whose normal is within 120 degrees of `normal` (or the nearest
    // of all when none is within `maxRings` cells).
    uint32_t nearest(const glm::vec3& p, const glm::vec3& normal, std::span<const glm::vec3> normals) const {
        const glm::ivec3 c = grid_.coords(p);
        float bestFacing = std::numeric_limits<float>::max(), bestAny = bestFacing;
        uint32_t facing = UINT32_MAX, any = UINT32_MAX;
        const float cell = float(grid_.cell());
        for (int ring = 0; ring <= kMaxRings; ++ring) {
            for (int dx = -ring; dx <= ring; ++dx)
                for (int dy = -ring; dy <= ring; ++dy)
                    for (int dz = -ring; dz <= ring; ++dz) {
                        if (std::max({std::abs(dx), std::abs(dy), std::abs(dz)}) != ring) continue;
                        grid_.forEachInCell(c + glm::ivec3(dx, dy, dz), [&](uint32_t s) {
                            const glm::vec3 d = positions_[s] - p;
                            const float d2 = glm::dot(d, d);
                            if (d2 < bestAny || (d2 == bestAny && s < any)) bestAny = d2, any = s;
                            if (glm::dot(normals[s], normal) > -0.5f &&
                                (d2 < bestFacing || (d2 == bestFacing && s < facing)))
                                bestFacing = d2, facing = s;
                        });
                    }
            // Every sample within `ring` cells' distance has been seen.
            const float seen = float(ring) * cell;
            if (facing != UINT32_MAX && bestFacing <= seen * seen) return facing;
        }
        if (facing != UINT32_MAX) return facing;
        if (any != UINT32_MAX) return any;
        // Nothing within kMaxRings cells: a part of the mesh too small to have received a
        // sample of its own (a detached speck). Its area goes to the nearest sample.
        for (uint32_t s = 0; s < positions_.size(); ++s) {
            const glm::vec3 d = positions_[s] - p;
            const float d2 = glm::dot(d, d);
            if (d2 < bestAny) bestAny = d2, any = s;
        }
        return any;
    }

    static constexpr int kMaxRings = 4;

private:
    std::span<const glm::vec3> positions_;
    PointGrid grid_;
};

double quinticStep(double t) {
    t = std::clamp(t, 0.0, 1.0);
    return t * t * t * (t * (6.0 * t - 15.0) + 10.0);
}

}  // namespace

double estimateCellSubPoints(double totalAreaMm2, size_t triangles, double narrowestKernelWidthMm,
                             const CellQuadratureOptions& options) {
    const double s = options.subSpacingFraction * narrowestKernelWidthMm;
    return std::max(totalAreaMm2 / (0.2 * s * s), double(triangles));
}

double estimateCellSubPoints(double totalAreaMm2, size_t triangles, const Material& material,
                             const CellQuadratureOptions& options) {
    return estimateCellSubPoints(totalAreaMm2, triangles, RadialKernels(material).narrowestWidth(), options);
}

namespace {

// r2 and the sub-triangles' spacing (cell_quadrature.h).
double outerRadiusOf(double widestWidth, double sampleSpacing, const CellQuadratureOptions& options) {
    return std::min(options.outerRadius * sampleSpacing, options.maxOuterRadiusWidths * widestWidth);
}

double coarseSpacingOf(double narrowestWidth, double widestWidth, double sampleSpacing,
                       const CellQuadratureOptions& options) {
    const double fine = options.subSpacingFraction * narrowestWidth;
    if (!(options.gradedPiecesPerDistance > 0.0)) return fine;
    const double r2 = outerRadiusOf(widestWidth, sampleSpacing, options);
    return std::max(fine, std::min(r2 / options.gradedPiecesPerDistance, 0.25 * sampleSpacing));
}

}  // namespace

double estimateCellSubPoints(double totalAreaMm2, size_t triangles, double narrowestWidthMm, double widestWidthMm,
                             double sampleSpacingMm, const CellQuadratureOptions& options) {
    const double s = coarseSpacingOf(narrowestWidthMm, widestWidthMm, sampleSpacingMm, options);
    return std::max(totalAreaMm2 / (0.2 * s * s), double(triangles));
}

CellQuadrature::CellQuadrature(const TriangleMesh& mesh, std::span<const glm::vec3> samplePositions,
                               std::span<const glm::vec3> sampleNormals, double sampleSpacing,
                               const Material& material, const CellQuadratureOptions& options)
    : CellQuadrature(mesh, samplePositions, sampleNormals, sampleSpacing, RadialKernels(material), options) {}

CellQuadrature::CellQuadrature(const TriangleMesh& mesh, std::span<const glm::vec3> samplePositions,
                               std::span<const glm::vec3> sampleNormals, double sampleSpacing,
                               const RadialKernels& kernels, const CellQuadratureOptions& options)
    : kernels_(kernels), k_(kernels.count()) {
    const size_t n = samplePositions.size();
    if (n == 0) throw Error("cell quadrature", "no samples");
    if (sampleNormals.size() != n) throw Error("cell quadrature", "sample positions and normals differ in length");
    if (n >= size_t(UINT32_MAX)) throw Error("cell quadrature", "too many samples");
    if (!(sampleSpacing > 0.0) || !std::isfinite(sampleSpacing))
        throw Error("cell quadrature", "sample spacing must be positive and finite");
    if (!(options.subSpacingFraction > 0.0) || !(options.innerRadius >= 0.0) ||
        !(options.outerRadius > options.innerRadius) || !std::isfinite(options.outerRadius) ||
        !(options.maxOuterRadiusWidths > 0.0) || !(options.gradedPiecesPerDistance >= 0.0) ||
        !std::isfinite(options.gradedPiecesPerDistance))
        throw Error("cell quadrature",
                    "invalid options (need fraction > 0, 0 <= inner < outer, max widths > 0, graded ratio >= 0)");

    if (!options.triangleOwner.empty()) {
        if (options.triangleOwner.size() != mesh.triangles.size())
            throw Error("cell quadrature", "triangleOwner has " + std::to_string(options.triangleOwner.size()) +
                                               " entries for " + std::to_string(mesh.triangles.size()) + " triangles");
        for (uint32_t o : options.triangleOwner)
            if (o != kNoTriangleOwner && o >= n)
                throw Error("cell quadrature", "triangleOwner names sample " + std::to_string(o) + " of " +
                                                   std::to_string(n));
    }

    const double widest = 1.0 / kernels_.narrowestWidth();
    subSpacing_ = options.subSpacingFraction / widest;
    r2_ = outerRadiusOf(kernels_.widestWidth(), sampleSpacing, options);
    r1_ = r2_ * options.innerRadius / options.outerRadius;
    coarseSpacing_ = coarseSpacingOf(kernels_.narrowestWidth(), kernels_.widestWidth(), sampleSpacing, options);
    const bool graded = coarseSpacing_ > subSpacing_;
    gradedRatio_ = graded ? options.gradedPiecesPerDistance : 0.0;
    r2f_ = float(r2_);

    // Kernel tables on [0, r2].
    const double step = std::min(sampleSpacing, 1.0 / widest) / 32.0;
    const size_t entries = std::clamp<size_t>(size_t(std::ceil(r2_ / step)) + 1, 2, size_t(1) << 20);
    inverseStep_ = double(entries - 1) / r2_;
    lastInterval_ = entries - 2;
    const size_t kc = size_t(k_);
    nearTable_.resize(kc * entries);
    farTable_.resize(kc * entries);
    double value[kMaxRadialKernels];
    for (size_t k = 0; k < entries; ++k) {
        const double r = double(k) / inverseStep_;
        const double chi = 1.0 - quinticStep((r - r1_) / (r2_ - r1_));
        kernels_.evaluate(r, value);
        for (size_t c = 0; c < kc; ++c) {
            const double rd = value[c] / kPi;
            nearTable_[kc * k + c] = rd * chi;
            farTable_[kc * k + c] = rd * (1.0 - chi);
        }
    }

    // Sub-points: n_t^2 congruent sub-triangles per triangle.
    const size_t triangles = mesh.triangles.size();
    std::vector<uint64_t> first(triangles + 1, 0);
    for (size_t t = 0; t < triangles; ++t) {
        const glm::uvec3 tri = mesh.triangles[t];
        const glm::vec3 a = mesh.positions[tri.x], b = mesh.positions[tri.y], c = mesh.positions[tri.z];
        const double edge = std::max({glm::length(b - a), glm::length(c - b), glm::length(a - c)});
        const double area = 0.5 * glm::length(glm::cross(b - a, c - a));
        const uint64_t div = area > 0.0 ? std::max<uint64_t>(1, uint64_t(std::ceil(edge / coarseSpacing_))) : 0;
        first[t + 1] = first[t] + div * div;
        if (first[t + 1] > options.maxSubPoints) {
            throw Error("cell quadrature",
                        "needs more than " + std::to_string(options.maxSubPoints) + " sub-points (" +
                            std::to_string(options.maxSubPoints * 16 >> 20) +
                            " MB) at sub-spacing " + std::to_string(coarseSpacing_) +
                            " mm (set by the narrowest kernel, " + kernels_.description() + "): use a smaller --size-mm");
        }
    }
    const size_t total = first[triangles];
    std::vector<glm::vec3> position(total);
    std::vector<float> area(total);
    std::vector<uint32_t> owner(total);
    std::vector<SubTriangle> shape(graded ? total : 0);
    const SampleGrid grid(samplePositions, sampleSpacing);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, triangles, 64), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t t = r.begin(); t < r.end(); ++t) {
            const uint64_t count = first[t + 1] - first[t];
            if (count == 0) continue;
            const int div = int(std::lround(std::sqrt(double(count))));
            const glm::uvec3 tri = mesh.triangles[t];
            const glm::dvec3 a = mesh.positions[tri.x], b = mesh.positions[tri.y], c = mesh.positions[tri.z];
            const glm::dvec3 cr = glm::cross(b - a, c - a);
            const glm::vec3 normal = glm::vec3(glm::normalize(cr));
            const uint32_t given = options.triangleOwner.empty() ? kNoTriangleOwner : options.triangleOwner[t];
            const float subArea = float(0.5 * glm::length(cr) / double(count));
            // The sub-triangles' edges: (b - a) / div and (c - a) / div, negated for the
            // "downward" ones (their corner is the far one).
            const glm::dvec3 e1 = (b - a) / double(div), e2 = (c - a) / double(div);
            const float longest = float(std::max({glm::length(e1), glm::length(e2), glm::length(e2 - e1)}));
            const float reach = float(std::max({glm::length(e1 + e2), glm::length(2.0 * e1 - e2),
                                                glm::length(2.0 * e2 - e1)}) / 3.0);
            uint64_t k = first[t];
            // Centroids of the "upward" (i + j <= div - 1) and "downward" (i + j <= div - 2)
            // sub-triangles of the barycentric grid.
            const auto emit = [&](double u, double v, double sign) {
                position[k] = glm::vec3(a + u * (b - a) + v * (c - a));
                area[k] = subArea;
                owner[k] = given != kNoTriangleOwner ? given : grid.nearest(position[k], normal, sampleNormals);
                if (graded) shape[k] = {glm::vec3(sign * e1), glm::vec3(sign * e2), longest, reach};
                ++k;
            };
            for (int i = 0; i < div; ++i)
                for (int j = 0; i + j < div; ++j) {
                    emit((i + 1.0 / 3.0) / div, (j + 1.0 / 3.0) / div, 1.0);
                    if (i + j <= div - 2) emit((i + 2.0 / 3.0) / div, (j + 2.0 / 3.0) / div, -1.0);
                }
        }
    });

    // Group by owner (counting sort, stable: deterministic).
    samplePosition_.assign(samplePositions.begin(), samplePositions.end());
    subOffset_.assign(n + 1, 0);
    for (uint32_t o : owner) ++subOffset_[o + 1];
    for (size_t i = 0; i < n; ++i) subOffset_[i + 1] += subOffset_[i];
    subPosition_.resize(total);
    subArea_.resize(total);
    subShape_.resize(shape.size());
    std::vector<uint32_t> cursor(subOffset_.begin(), subOffset_.end() - 1);
    for (size_t k = 0; k < total; ++k) {
        const uint32_t dst = cursor[owner[k]]++;
        subPosition_[dst] = position[k];
        subArea_[dst] = area[k];
        if (graded) subShape_[dst] = shape[k];
    }
    std::vector<SubTriangle>().swap(shape);
    // Within each cell: sub-points along a Morton curve, in chunks of kChunk with a
    // bounding sphere, so that a vertex skips the chunks beyond r2 (large cells of a
    // coarse sample set reach far past the near field).
    chunkOffset_.assign(n + 1, 0);
    for (size_t i = 0; i < n; ++i) {
        const uint32_t count = subOffset_[i + 1] - subOffset_[i];
        chunkOffset_[i + 1] = chunkOffset_[i] + (count + kChunk - 1) / kChunk;
    }
    chunkCentre_.resize(chunkOffset_[n]);
    chunkRadius_.resize(chunkOffset_[n]);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, n, 256), [&](const tbb::blocked_range<size_t>& r) {
        std::vector<glm::vec3> pos;
        std::vector<float> area;
        std::vector<SubTriangle> shapes;
        for (size_t i = r.begin(); i < r.end(); ++i) {
            const uint32_t b = subOffset_[i], e = subOffset_[i + 1];
            if (e - b > 1) {
                const std::vector<uint32_t> order =
                    mortonOrder(std::span(subPosition_.data() + b, e - b), "cell sub-points");
                pos.assign(subPosition_.begin() + b, subPosition_.begin() + e);
                area.assign(subArea_.begin() + b, subArea_.begin() + e);
                if (graded) shapes.assign(subShape_.begin() + b, subShape_.begin() + e);
                for (uint32_t k = 0; k < e - b; ++k) {
                    subPosition_[b + k] = pos[order[k]];
                    subArea_[b + k] = area[order[k]];
                    if (graded) subShape_[b + k] = shapes[order[k]];
                }
            }
            for (uint32_t c = chunkOffset_[i]; c < chunkOffset_[i + 1]; ++c) {
                const uint32_t first = b + (c - chunkOffset_[i]) * kChunk;
                const uint32_t last = std::min(first + kChunk, e);
                glm::vec3 lo(std::numeric_limits<float>::max()), hi(std::numeric_limits<float>::lowest());
                for (uint32_t k = first; k < last; ++k) {
                    lo = glm::min(lo, subPosition_[k]);
                    hi = glm::max(hi, subPosition_[k]);
                }
                chunkCentre_[c] = 0.5f * (lo + hi);
                float radius = 0.0f;
                for (uint32_t k = first; k < last; ++k)
                    radius = std::max(radius, glm::length(subPosition_[k] - chunkCentre_[c]) +
                                                  (graded ? subShape_[k].reach : 0.0f));
                chunkRadius_[c] = radius * (1.0f + 1e-5f) + 1e-6f;  // rounding margin
            }
        }
    });

    cellArea_.assign(n, 0.0f);
    cellRadius_.assign(n, 0.0f);
    for (size_t i = 0; i < n; ++i) {
        double sum = 0.0;
        float radius = 0.0f;
        for (uint32_t k = subOffset_[i]; k < subOffset_[i + 1]; ++k) {
            sum += subArea_[k];
            radius = std::max(radius, glm::length(subPosition_[k] - samplePosition_[i]) +
                                          (graded ? subShape_[k].reach : 0.0f));
        }
        cellArea_[i] = float(sum);
        cellRadius_[i] = radius;
        maxCellRadius_ = std::max(maxCellRadius_, radius);
    }
}

void CellQuadrature::farKernelOverPi(double r, double* w) const {
    if (r >= r2_) {
        kernels_.evaluate(r, w);
        for (int c = 0; c < k_; ++c) w[c] /= kPi;
        return;
    }
    const double x = r * inverseStep_;
    const size_t k = std::min(size_t(x), lastInterval_);
    const double f = x - double(k);
    const double* p = farTable_.data() + size_t(k_) * k;
    for (int c = 0; c < k_; ++c) w[c] = p[c] + f * (p[c + k_] - p[c]);
}

namespace {

// The near sum of one cell for K kernels, K a compile-time constant for the dipole
// (the hot case) or the run-time count.
template <int Fixed>
void nearSum(int count, const double* table, double inverseStep, size_t lastInterval, double limit,
             std::span<const glm::vec3> position, std::span<const float> area, const glm::vec3& xo, double* s) {
    const int K = Fixed > 0 ? Fixed : count;
    for (size_t k = 0; k < position.size(); ++k) {
        const glm::vec3 d = position[k] - xo;
        const double d2 = double(d.x) * d.x + double(d.y) * d.y + double(d.z) * d.z;
        if (d2 >= limit) continue;
        const double x = std::sqrt(d2) * inverseStep;
        const size_t e = std::min(size_t(x), lastInterval);
        const double f = x - double(e);
        const double* p = table + size_t(K) * e;
        const double a = area[k];
        for (int c = 0; c < K; ++c) s[c] += a * (p[c] + f * (p[c + K] - p[c]));
    }
}

// The graded near sum of one chunk (cell_quadrature.h, "Graded sub-points"): each
// sub-triangle split into m^2 pieces no wider than max(fine, d / g).
template <int Fixed>
void gradedNearSum(int count, const double* table, double inverseStep, size_t lastInterval, double r2, double fine,
                   double g, std::span<const glm::vec3> position, std::span<const float> area,
                   const CellQuadrature::SubTriangle* shape, const glm::vec3& xo, double* s) {
    const int K = Fixed > 0 ? Fixed : count;
    const double limit = r2 * r2;
    const auto add = [&](double r, double a) {
        const double x = r * inverseStep;
        const size_t e = std::min(size_t(x), lastInterval);
        const double f = x - double(e);
        const double* p = table + size_t(K) * e;
        const double lo = a * (1.0 - f), hi = a * f;
        for (int c = 0; c < K; ++c) s[c] += lo * p[c] + hi * p[c + K];
    };
    for (size_t k = 0; k < position.size(); ++k) {
        const glm::vec3 d = position[k] - xo;
        const double d2 = double(d.x) * d.x + double(d.y) * d.y + double(d.z) * d.z;
        const CellQuadrature::SubTriangle& t = shape[k];
        const double reach = t.reach;
        const double dist = std::sqrt(d2);
        if (dist >= r2 + reach) continue;
        const double piece = std::max(fine, (dist - reach) / g);
        const int m = std::min(64, std::max(1, int(std::ceil(double(t.longestEdge) / piece))));
        if (m == 1) {
            if (d2 < limit) add(dist, area[k]);
            continue;
        }
        // Piece centroids on the barycentric grid of the sub-triangle, relative to x_o.
        const glm::dvec3 corner = glm::dvec3(d) - (glm::dvec3(t.e1) + glm::dvec3(t.e2)) / 3.0;
        const glm::dvec3 u = glm::dvec3(t.e1) / double(m), v = glm::dvec3(t.e2) / double(m);
        const double a = double(area[k]) / double(m * m);
        for (int i = 0; i < m; ++i) {
            for (int j = 0; i + j < m; ++j) {
                const glm::dvec3 base = corner + double(i) * u + double(j) * v;
                const glm::dvec3 up = base + (u + v) / 3.0;
                const double u2 = glm::dot(up, up);
                if (u2 < limit) add(std::sqrt(u2), a);
                if (i + j <= m - 2) {
                    const glm::dvec3 down = base + 2.0 * (u + v) / 3.0;
                    const double w2 = glm::dot(down, down);
                    if (w2 < limit) add(std::sqrt(w2), a);
                }
            }
        }
    }
}

}  // namespace

void CellQuadrature::nearWeightOverPi(size_t i, const glm::vec3& xo, double* w) const {
    for (int c = 0; c < k_; ++c) w[c] = 0.0;
    const double limit = r2_ * r2_;
    for (uint32_t c = chunkOffset_[i]; c < chunkOffset_[i + 1]; ++c) {
        const float reach = r2f_ + chunkRadius_[c];
        const glm::vec3 dc = chunkCentre_[c] - xo;
        if (glm::dot(dc, dc) >= reach * reach) continue;
        const uint32_t first = subOffset_[i] + (c - chunkOffset_[i]) * kChunk;
        const uint32_t last = std::min(first + kChunk, subOffset_[i + 1]);
        const std::span<const glm::vec3> position(subPosition_.data() + first, last - first);
        const std::span<const float> area(subArea_.data() + first, last - first);
        if (graded()) {
            const SubTriangle* shape = subShape_.data() + first;
            if (k_ == 12)
                gradedNearSum<12>(12, nearTable_.data(), inverseStep_, lastInterval_, r2_, subSpacing_, gradedRatio_,
                                  position, area, shape, xo, w);
            else
                gradedNearSum<0>(k_, nearTable_.data(), inverseStep_, lastInterval_, r2_, subSpacing_, gradedRatio_,
                                 position, area, shape, xo, w);
            continue;
        }
        if (k_ == 3)
            nearSum<3>(3, nearTable_.data(), inverseStep_, lastInterval_, limit, position, area, xo, w);
        else
            nearSum<0>(k_, nearTable_.data(), inverseStep_, lastInterval_, limit, position, area, xo, w);
    }
}

void CellQuadrature::sampleWeightOverPi(size_t i, const glm::vec3& xo, double* w) const {
    double far[kMaxRadialKernels];
    farKernelOverPi(glm::length(samplePosition_[i] - xo), far);
    double near[kMaxRadialKernels] = {};
    if (cellIsNear(i, xo)) nearWeightOverPi(i, xo, near);
    for (int c = 0; c < k_; ++c) w[c] = near[c] + double(cellArea_[i]) * far[c];
}

size_t CellQuadrature::bytes() const {
    return (nearTable_.capacity() + farTable_.capacity()) * sizeof(double) +
           samplePosition_.capacity() * sizeof(glm::vec3) +
           (cellArea_.capacity() + cellRadius_.capacity() + subArea_.capacity()) * sizeof(float) +
           subOffset_.capacity() * sizeof(uint32_t) + subPosition_.capacity() * sizeof(glm::vec3) +
           subShape_.capacity() * sizeof(SubTriangle) +
           chunkOffset_.capacity() * sizeof(uint32_t) + chunkCentre_.capacity() * sizeof(glm::vec3) +
           chunkRadius_.capacity() * sizeof(float);
}

}  // namespace prt
