#pragma once
// The quadrature of Wang Eq. 7 that pass 2 uses (issue 13, item 2): the irradiance is
// read as constant over each sample's Voronoi cell on the mesh, and R_d is integrated
// over the cells exactly enough that the sum converges, instead of being evaluated at
// the sample positions.
//
// WHY. The point rule sum_i A R_d(|x_i - x_o|) E_i samples R_d's peak (width ~z_r) with
// samples spaced ~z_r apart at random-looking positions: against the exact plane
// integral it is 1.4-11.6% off per point (RMS over points; single points up to 28%),
// though right on average. On a perfect lattice it would be within 0.5% (the lattice's
// first reciprocal vector sees R_d's spectrum at e^(-7.3 z_r / h)); the error is the
// irregularity of a Poisson-disk set, so neither a per-sample area (Voronoi areas) nor
// a per-sample filter (R_d averaged over a disk) repairs it: both were measured and
// leave 1-9% per point (docs/fidelity.md). What converges is a finer, structured
// quadrature of R_d near x_o, while E keeps its coarse samples:
//
//     T(x_o) = int R_d(|y - x_o|) E(y) dy,   E(y) = E_{nearest sample to y}
//            = sum_i w_i(x_o) E_i,   w_i = int_{cell_i} R_d(|y - x_o|) dy.
//
// THE CELLS. Every mesh triangle is split into n^2 congruent sub-triangles (n =
// ceil(longest edge / s)); each sub-triangle's centroid is a SUB-POINT with the
// sub-triangle's area, assigned to the nearest sample whose triangle faces the same
// way (geometric normals at less than 120 degrees, as poissonDiskSamples treats thin
// plates; the plain nearest sample when none does). A sample's cell area A_i is the sum
// of its sub-points' areas (the areas of all cells add up to the mesh area exactly).
// The sub-spacing s = options.subSpacingFraction (0.25) / max_c(sigma_t' + sigma_tr)
// follows the narrowest channel's kernel (the width the reference's convergence rule
// uses). Within a cell the sub-points lie along a Morton curve in chunks of 16 with a
// bounding sphere, so that a vertex visits only the chunks that reach its near field.
//
// THE SPLIT. R_d = R_d chi + R_d (1 - chi), chi(r) = 1 for r <= r1, 0 for r >= r2,
// a C^2 quintic step between (r1 = h, r2 = 3 h, h the sample spacing; r2 at most 6
// widths of the widest channel's kernel, r1 = r2 / 3 then). The NEAR part R_d chi is
// integrated with the sub-points (the sub-point rule on a per-triangle regular grid is
// accurate for any kernel wider than s); the FAR part
// R_d (1 - chi), zero near x_o and smooth at the scale of r1, with the point rule at
// the samples and their cell areas. So
//
//     w_i(x_o) = sum_{y in cell_i} a_y R_d chi(|y - x_o|) + A_i R_d (1 - chi)(|x_i - x_o|),
//
// the first sum skipped when the cell lies beyond r2 (|x_i - x_o| - cellRadius_i >= r2)
// and, within it, every chunk that does.
// The far kernel is what the hierarchy's nodes use (they are never within r2 of x_o:
// multiple_scattering.h). Both kernels are tabulated (linear interpolation, relative
// error < 1e-4 on [0, r2]; R_d itself beyond).
//
// Units: mm, mm^2, mm^-2. Thread safety: immutable after construction.

#include "common/bssrdf.h"
#include "common/mesh.h"

#include <glm/glm.hpp>

#include <cstdint>
#include <span>
#include <vector>

namespace prt {

struct CellQuadratureOptions {
    // Sub-spacing s = fraction / max_c(sigma_t' + sigma_tr).
    double subSpacingFraction = 0.25;
    // The near/far split in units of the sample spacing h ...
    double innerRadius = 1.0;
    double outerRadius = 3.0;
    // ... with r2 at most this many widest-kernel widths max_c 1 / (sigma_t' + sigma_tr)
    // (r1 scaled with it): the near part is there to resolve R_d's peak, and a coarse
    // sample set would otherwise put most of the object's sub-points into every
    // vertex's near field (bunny, Marble, --samples 64, h = 3.9 mm: pass 2 took 3 min
    // with r2 = 3 h, 47 s at 12 widths, 16 s at 6). At the default spacing r2 = 3 h is
    // below 6 widths for every measured material.
    double maxOuterRadiusWidths = 6.0;
    // Refuse to build more sub-points than this (16 bytes each once built, 36 while
    // being built; the default is 2^26, about 2.4 GB at the peak).
    size_t maxSubPoints = size_t(1) << 26;
};

// About the sub-point count the cells of a mesh of this area and triangle count will
// need: area / (0.2 s^2) (an equilateral sub-triangle of edge s has 0.43 s^2; real
// triangles are thinner and n = ceil(edge / s) rounds up: the bunny at 30 mm has 680K
// for an estimate of 700K), and at least one per triangle. The construction holds
// kCellBytesPerSubPoint bytes per sub-point at its peak.
double estimateCellSubPoints(double totalAreaMm2, size_t triangles, const Material& material,
                             const CellQuadratureOptions& options = {});
inline constexpr double kCellBytesPerSubPoint = 36.0;

class CellQuadrature {
public:
    // mesh: positions in mm (validated by the caller). samplePositions / sampleNormals:
    // the samples (geometric normals of their triangles, unit). sampleSpacing: h (mm,
    // > 0) of the sample set. Throws prt::Error for an empty sample set, mismatched
    // arrays, a non-positive spacing, or more sub-points than options.maxSubPoints
    // (naming the count and the memory it needs).
    CellQuadrature(const TriangleMesh& mesh, std::span<const glm::vec3> samplePositions,
                   std::span<const glm::vec3> sampleNormals, double sampleSpacing, const Material& material,
                   const CellQuadratureOptions& options = {});

    size_t sampleCount() const { return cellArea_.size(); }
    size_t subPointCount() const { return subPosition_.size(); }
    double subSpacing() const { return subSpacing_; }
    double innerRadius() const { return r1_; }
    double outerRadius() const { return r2_; }
    // A_i (mm^2): the area of sample i's cell.
    float cellArea(size_t i) const { return cellArea_[i]; }
    std::span<const float> cellAreas() const { return cellArea_; }
    // Largest distance from sample i to one of its sub-points (0 for an empty cell).
    float cellRadius(size_t i) const { return cellRadius_[i]; }
    float maxCellRadius() const { return maxCellRadius_; }
    // The sub-points of sample i's cell.
    std::span<const glm::vec3> cellSubPoints(size_t i) const {
        return {subPosition_.data() + subOffset_[i], subPosition_.data() + subOffset_[i + 1]};
    }

    // The far kernel R_d (1 - chi)(r) / pi, three channels.
    void farKernelOverPi(double r, double w[3]) const;
    // w_i(x_o) / pi, three channels (see the top of this file).
    void sampleWeightOverPi(size_t i, const glm::vec3& xo, double w[3]) const;
    // Only the near part sum_{y in cell_i} a_y R_d chi(|y - x_o|) / pi (0 beyond r2).
    void nearWeightOverPi(size_t i, const glm::vec3& xo, double w[3]) const;
    // Whether sample i's cell reaches within r2 of x_o (else its near part is 0).
    bool cellIsNear(size_t i, const glm::vec3& xo) const {
        const glm::vec3 d = samplePosition_[i] - xo;
        const float reach = r2f_ + cellRadius_[i];
        return d.x * d.x + d.y * d.y + d.z * d.z < reach * reach;
    }

    size_t bytes() const;

private:
    DipoleChannel channel_[3];
    double subSpacing_ = 0.0, r1_ = 0.0, r2_ = 0.0;
    float r2f_ = 0.0f;
    float maxCellRadius_ = 0.0f;
    double inverseStep_ = 0.0;
    size_t lastInterval_ = 0;  // entries - 2: the last interval a lookup may start in
    std::vector<double> nearTable_, farTable_;  // / pi, interleaved RGB on [0, r2]
    std::vector<glm::vec3> samplePosition_;
    std::vector<float> cellArea_, cellRadius_;
    std::vector<uint32_t> subOffset_;  // sampleCount + 1
    std::vector<glm::vec3> subPosition_;  // per cell along a Morton curve
    std::vector<float> subArea_;
    // Chunks of kChunk consecutive sub-points of a cell with a bounding sphere.
    static constexpr uint32_t kChunk = 16;
    std::vector<uint32_t> chunkOffset_;  // sampleCount + 1
    std::vector<glm::vec3> chunkCentre_;
    std::vector<float> chunkRadius_;
};

}  // namespace prt
