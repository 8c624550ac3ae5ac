#pragma once
// The quadrature of Wang Eq. 7 that pass 2 uses: E (the samples' irradiance transport)
// is read as constant over each sample's Voronoi cell on the mesh and R_d is integrated
// over the cells,
//
//     T(x_o) = int R_d(|y - x_o|) E(y) dy = sum_i w_i(x_o) E_i,   w_i = int_{cell_i} R_d(|y - x_o|) dy,
//
// which converges at the default sample spacing where the point rule
// A_i R_d(|x_i - x_o|) does not (docs/fidelity.md, "The sample sum").
//
// The cells: every mesh triangle is split into n^2 congruent sub-triangles (n =
// ceil(longest edge / s)); each sub-triangle's centroid is a sub-point with the
// sub-triangle's area, assigned to the nearest sample whose triangle faces the same
// way (geometric normals less than 120 degrees apart, as poissonDiskSamples treats thin
// plates; the plain nearest sample when none does), or to its triangle's given owner
// (options.triangleOwner). A sample's cell area A_i is the sum
// of its sub-points' areas (all cells add up to the mesh area). The sub-spacing s =
// subSpacingFraction x the narrowest kernel's width (radial_kernels.h; for the dipole
// 1 / max_c(sigma_t' + sigma_tr)). Within a cell the sub-points lie along a Morton
// curve in chunks of 16 with a bounding sphere, so that a vertex visits only the chunks that reach its near field.
//
// The split: R_d = R_d chi + R_d (1 - chi), chi(r) = 1 for r <= r1, 0 for r >= r2, a C^2
// quintic step between (r1 = innerRadius h, r2 = outerRadius h, h the sample spacing;
// r2 capped at maxOuterRadiusWidths widths of the widest kernel, r1 scaled
// with it). The near part is integrated with the sub-points, the far part (smooth at
// the scale of r1) with the point rule:
//
//     w_i(x_o) = sum_{y in cell_i} a_y R_d chi(|y - x_o|) + A_i R_d (1 - chi)(|x_i - x_o|),
//
// the first sum skipped when the cell lies beyond r2 (|x_i - x_o| - cellRadius_i >= r2)
// and, within it, every chunk that does.
//
// Graded sub-points (options.gradedPiecesPerDistance g > 0). A kernel set far narrower
// than the sample spacing (the profiles of a radial basis, whose narrowest member is the
// most opaque material of the range at its largest size) needs the fine spacing s only
// at its peak: beyond it the kernels vary on the scale of the distance itself. The cells
// are then built from coarse sub-triangles (spacing s_c = min(r2 / g, h / 4), never below
// s), and a vertex splits each sub-triangle it integrates into m^2 congruent pieces no
// wider than max(s, d / g), d the least distance from the vertex to the sub-triangle; the
// midpoint rule on each piece (the near sum above, over pieces instead of sub-points).
// The cells (their areas and the far part) are the coarse sub-triangles'. A vertex then
// visits about pi g^2 / 0.43 (2 + 2 ln(s_c / s)) pieces instead of pi r2^2 / (0.43 s^2)
// sub-points. The far kernel is what the hierarchy's nodes
// use (never within r2 of x_o: multiple_scattering.h). Both kernels are tabulated
// (linear interpolation, relative error < 1e-4 on [0, r2]; R_d itself beyond).
//
// R_d stands for every kernel of the set integrated (radial_kernels.h): the material's
// dipole per colour channel, or the profiles of a radial basis.
//
// Units: mm, mm^2, mm^-2. Thread safety: immutable after construction.

#include "common/bssrdf.h"
#include "common/mesh.h"
#include "common/radial_kernels.h"

#include <glm/glm.hpp>

#include <cstdint>
#include <span>
#include <vector>

namespace prt {

inline constexpr uint32_t kNoTriangleOwner = 0xffffffffu;

struct CellQuadratureOptions {
    // Sub-spacing s = fraction x the narrowest kernel width.
    double subSpacingFraction = 0.25;
    // The near/far split in units of the sample spacing h ...
    double innerRadius = 1.0;
    double outerRadius = 3.0;
    // ... with r2 at most this many widest-kernel widths (radial_kernels.h)
    // (r1 scaled with it): the near part only resolves R_d's peak, and a coarse sample
    // set would otherwise put most of the object's sub-points in every vertex's near
    // field (docs/precompute.md, "Pipeline").
    double maxOuterRadiusWidths = 6.0;
    // Graded sub-points (see the top of this file): pieces no wider than d / g at
    // distance d from the vertex. 0 turns grading off (one level of sub-points at s).
    double gradedPiecesPerDistance = 0.0;
    // Cells that are whole triangles: when not empty (one entry per mesh triangle), the
    // sub-points of triangle t belong to sample triangleOwner[t] instead of the nearest
    // sample (a triangle marked kNoTriangleOwner still goes to the nearest). For one
    // sample per face (the point-light renderers' face centroids) the cells are then the
    // faces and A_i the face areas, whatever the sub-spacing.
    std::span<const uint32_t> triangleOwner{};
    // Refuse to build more sub-points than this (16 bytes each once built, 36 while
    // being built; the default is 2^26, about 2.4 GB at the peak).
    size_t maxSubPoints = size_t(1) << 26;
};

// About the sub-point count the cells of a mesh of this area and triangle count will
// need: area / (0.2 s^2) (an equilateral sub-triangle of edge s has 0.43 s^2; real
// triangles are thinner and n = ceil(edge / s) rounds up), and at least one per
// triangle. The construction holds kCellBytesPerSubPoint bytes per sub-point at its peak.
double estimateCellSubPoints(double totalAreaMm2, size_t triangles, double narrowestKernelWidthMm,
                             const CellQuadratureOptions& options = {});
// The same for kernels of these widths (radial_kernels.h) and sample spacing h: graded
// sub-points are spaced s_c.
double estimateCellSubPoints(double totalAreaMm2, size_t triangles, double narrowestWidthMm, double widestWidthMm,
                             double sampleSpacingMm, const CellQuadratureOptions& options);
double estimateCellSubPoints(double totalAreaMm2, size_t triangles, const Material& material,
                             const CellQuadratureOptions& options = {});
inline constexpr double kCellBytesPerSubPoint = 36.0;
// Graded sub-points also keep their sub-triangle's shape.
inline constexpr double kCellBytesPerGradedSubPoint = 68.0;

class CellQuadrature {
public:
    // mesh: positions in mm (validated by the caller). samplePositions / sampleNormals:
    // the samples (geometric normals of their triangles, unit). sampleSpacing: h (mm,
    // > 0) of the sample set. Throws prt::Error for an empty sample set, mismatched
    // arrays, a non-positive spacing, a triangleOwner of another length than the
    // triangles or naming no sample, or more sub-points than options.maxSubPoints
    // (naming the count and the memory it needs).
    CellQuadrature(const TriangleMesh& mesh, std::span<const glm::vec3> samplePositions,
                   std::span<const glm::vec3> sampleNormals, double sampleSpacing, const RadialKernels& kernels,
                   const CellQuadratureOptions& options = {});
    // The material's dipole (RadialKernels(material)): one kernel per colour channel.
    CellQuadrature(const TriangleMesh& mesh, std::span<const glm::vec3> samplePositions,
                   std::span<const glm::vec3> sampleNormals, double sampleSpacing, const Material& material,
                   const CellQuadratureOptions& options = {});

    size_t sampleCount() const { return cellArea_.size(); }
    size_t subPointCount() const { return subPosition_.size(); }
    // s: the finest spacing integrated (the sub-points' spacing unless graded).
    double subSpacing() const { return subSpacing_; }
    // The sub-triangles' spacing: s, or s_c when graded.
    double coarseSpacing() const { return coarseSpacing_; }
    bool graded() const { return !subShape_.empty(); }
    double innerRadius() const { return r1_; }
    double outerRadius() const { return r2_; }
    // A_i (mm^2): the area of sample i's cell.
    float cellArea(size_t i) const { return cellArea_[i]; }
    std::span<const float> cellAreas() const { return cellArea_; }
    // Largest distance from sample i to a point its near part is evaluated at: its
    // sub-points, or with graded sub-points every point of their sub-triangles (0 for an
    // empty cell).
    float cellRadius(size_t i) const { return cellRadius_[i]; }
    float maxCellRadius() const { return maxCellRadius_; }
    // The sub-points of sample i's cell.
    std::span<const glm::vec3> cellSubPoints(size_t i) const {
        return {subPosition_.data() + subOffset_[i], subPosition_.data() + subOffset_[i + 1]};
    }

    // The kernels integrated (R_d in the text above stands for each of them).
    const RadialKernels& kernels() const { return kernels_; }
    // The far kernel R_d (1 - chi)(r) / pi, kernels().count() values.
    void farKernelOverPi(double r, double* w) const;
    // w_i(x_o) / pi, kernels().count() values (see the top of this file).
    void sampleWeightOverPi(size_t i, const glm::vec3& xo, double* w) const;
    // Only the near part sum_{y in cell_i} a_y R_d chi(|y - x_o|) / pi (0 beyond r2).
    void nearWeightOverPi(size_t i, const glm::vec3& xo, double* w) const;
    // Whether sample i's cell reaches within r2 of x_o (else its near part is 0).
    bool cellIsNear(size_t i, const glm::vec3& xo) const {
        const glm::vec3 d = samplePosition_[i] - xo;
        const float reach = r2f_ + cellRadius_[i];
        return d.x * d.x + d.y * d.y + d.z * d.z < reach * reach;
    }

    size_t bytes() const;

    // A graded sub-point's sub-triangle: two edges from the corner centroid - (e1 + e2)
    // / 3, its longest edge and the largest distance from the centroid to a corner.
    struct SubTriangle {
        glm::vec3 e1, e2;
        float longestEdge, reach;
    };

private:
    RadialKernels kernels_;
    int k_ = 3;  // kernels_.count(): the tables' interleave
    double subSpacing_ = 0.0, coarseSpacing_ = 0.0, r1_ = 0.0, r2_ = 0.0;
    double gradedRatio_ = 0.0;  // g
    float r2f_ = 0.0f;
    float maxCellRadius_ = 0.0f;
    double inverseStep_ = 0.0;
    size_t lastInterval_ = 0;  // entries - 2: the last interval a lookup may start in
    std::vector<double> nearTable_, farTable_;  // / pi, k_ kernels interleaved, on [0, r2]
    std::vector<glm::vec3> samplePosition_;
    std::vector<float> cellArea_, cellRadius_;
    std::vector<uint32_t> subOffset_;  // sampleCount + 1
    std::vector<glm::vec3> subPosition_;  // per cell along a Morton curve
    std::vector<float> subArea_;
    std::vector<SubTriangle> subShape_;  // graded only, per sub-point
    // Chunks of kChunk consecutive sub-points of a cell with a bounding sphere.
    static constexpr uint32_t kChunk = 16;
    std::vector<uint32_t> chunkOffset_;  // sampleCount + 1
    std::vector<glm::vec3> chunkCentre_;
    std::vector<float> chunkRadius_;
};

}  // namespace prt
