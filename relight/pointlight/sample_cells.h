#pragma once
// The near field of the point-light renderers' sample sums on the cell quadrature
// (common/cell_quadrature.h; docs/point-lights.md, "The near field").
//
// WHAT IS COMPUTED. Jensen-Buhler, the irradiance cache and the brute-force sum
// (jensen_buhler.h, irradiance_cache.h) read Keng Eq. 4 by cubature, one term
// A_i R_d(|x - x_i|) E^_i per sample. Near x that point rule does not converge at the
// samples' spacing: R_d peaks over about w = 1 / (sigma_t' + sigma_tr), and face
// centroids of a coarse mesh lie a kernel width apart or more. SampleCells gives each
// sample a cell of the surface (E^ read as constant over it, as pass 2 of the
// precompute does) and the term of a sample near x becomes
//
//     w_i(x) E^_i,    w_i(x) = int_{cell_i} R_d(|y - x|) dy      (dimensionless, per channel)
//
// integrated with the cell quadrature's sub-points (its near part) plus its point rule
// for the smooth remainder (its far part). Samples whose cell lies beyond the near
// radius keep the point rule, which equals w_i there.
//
// THE CELLS. Face-centroid samples (SampleSource::FaceCentroids, Keng's choice) own
// their whole face: the cells are the faces and A_i the face areas, so the cells agree
// with the areas the octree aggregates. Poisson-disk samples own the surface nearest
// them (the quadrature's cells); their cell areas differ from the octree's A / N by
// the set's irregularity, which the far point rule then carries unchanged.
// The sample spacing h of the quadrature's near/far split is sqrt(mesh area / N), and
// the split is at r1 = h, r2 = 3 h without the precompute's cap of a few kernel widths:
// the far part's point rule needs cells small against r1, and faces may be far coarser
// than the kernel.
//
// SUB-POINTS. Graded (cell_quadrature.h, "Graded sub-points", g = 8 as the editable
// precompute): coarse sub-triangles everywhere, split finely only near the point
// evaluated, so a large object with a narrow kernel does not need the fine spacing over
// its whole surface.
//
// MATERIAL. The sub-spacing, the split radii and the kernel tables depend on the
// material: setMaterial rebuilds the quadrature (docs/point-lights.md, "The near
// field", gives its cost). The cells' areas depend on the samples only
// for face cells, on the sub-spacing too (within a sub-triangle) for Poisson cells.
//
// Units: mm, mm^2; weights dimensionless (R_d in mm^-2 times mm^2). Indices are the
// samples' input order (IrradianceSamples; IrradianceOctree::order() maps tree order
// to it). Thread safety: const members may run concurrently; copies share the
// quadrature (setMaterial on one copy gives it a new one and leaves the others).

#include <glm/glm.hpp>

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "common/bssrdf.h"
#include "common/cell_quadrature.h"
#include "common/mesh.h"
#include "relight/pointlight/point_lights.h"

namespace prt {

// The rule of the renderers' near field: the cells, the point rule (Keng's and
// Jensen-Buhler's cubature, kept for comparison with the papers), or Auto (the
// default): the cells where the samples' spacing sqrt(area / N) exceeds the narrowest
// kernel width, the point rule below it, where the two were measured to agree and the
// cells only cost time (docs/point-lights.md, "The near field").
enum class NearFieldRule { Auto, Cells, Points };
const char* toString(NearFieldRule rule);  // "auto", "cells", "points"
// "auto", "cells" or "points" (case-insensitive); prt::Error("--near-field", ...) otherwise.
NearFieldRule parseNearFieldRule(const std::string& text);
// Auto resolved for samples of this count over this area (mm^2) and this material.
bool nearFieldNeedsCells(double areaMm2, size_t samples, const Material& material);

// g of the graded sub-points (see SUB-POINTS above).
inline constexpr double kGradedPiecesPerDistance = 8.0;

class SampleCells {
public:
    // mesh in mm (the one the samples lie on), samples with positions, geometric normals,
    // triangles and source. Throws prt::Error for an empty sample set, a sample naming
    // no triangle of the mesh, an invalid material, or a quadrature too large
    // (cell_quadrature.h).
    SampleCells(const TriangleMesh& mesh, const IrradianceSamples& samples, const Material& material);

    // Rebuilds the quadrature for `material` (see MATERIAL above); unchanged on error.
    void setMaterial(const Material& material);
    const Material& material() const { return material_; }

    // A sample whose position lies farther than this from x has no near part at x; an
    // octree node whose cell lies farther is used whole (mm).
    double nearRadius() const { return nearRadius_; }
    // Whether sample i's cell has a near part at x (else w_i(x) = A_i R_d(|x - x_i|)).
    bool isNear(uint32_t i, const glm::vec3& x) const { return quadrature_->cellIsNear(i, x); }
    // w_i(x) per colour channel (see the top of this file).
    glm::dvec3 weight(uint32_t i, const glm::vec3& x) const;
    // The cell's area A_i (mm^2).
    double cellArea(uint32_t i) const { return quadrature_->cellArea(i); }

    const CellQuadrature& quadrature() const { return *quadrature_; }
    size_t sampleCount() const { return positions_->size(); }
    double sampleSpacing() const { return spacing_; }
    bool faceCells() const { return !triangleOwner_->empty(); }
    double buildSeconds() const { return buildSeconds_; }  // the last (re)build, wall

private:
    void build(const Material& material);

    std::shared_ptr<const TriangleMesh> mesh_;
    std::shared_ptr<const std::vector<glm::vec3>> positions_, normals_;
    std::shared_ptr<const std::vector<uint32_t>> triangleOwner_;  // face cells; empty for nearest-sample cells
    double spacing_ = 0.0;
    Material material_;
    std::shared_ptr<const CellQuadrature> quadrature_;
    double nearRadius_ = 0.0;
    double buildSeconds_ = 0.0;
};

}  // namespace prt
