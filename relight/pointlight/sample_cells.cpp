#include "relight/pointlight/sample_cells.h"

#include <cmath>
#include <limits>

#include "common/error.h"
#include "common/util.h"

namespace prt {

const char* toString(NearFieldRule rule) {
    switch (rule) {
        case NearFieldRule::Auto: return "auto";
        case NearFieldRule::Cells: return "cells";
        case NearFieldRule::Points: return "points";
    }
    return "?";
}

NearFieldRule parseNearFieldRule(const std::string& text) {
    const std::string t = toLower(text);
    if (t == "auto") return NearFieldRule::Auto;
    if (t == "cells") return NearFieldRule::Cells;
    if (t == "points") return NearFieldRule::Points;
    throw Error("--near-field", "expected 'auto', 'cells' or 'points', got '" + text + "'");
}

bool nearFieldNeedsCells(double areaMm2, size_t samples, const Material& material) {
    if (samples == 0 || !(areaMm2 > 0.0)) return false;
    const double spacing = std::sqrt(areaMm2 / double(samples));
    return spacing > RadialKernels(material).narrowestWidth();
}

SampleCells::SampleCells(const TriangleMesh& mesh, const IrradianceSamples& samples, const Material& material) {
    const size_t n = samples.size();
    if (n == 0) throw Error("sample cells", "no samples");
    if (samples.geometricNormals.size() != n || samples.triangles.size() != n)
        throw Error("sample cells", "inconsistent sample arrays");
    std::vector<uint32_t> owner;
    if (samples.source == SampleSource::FaceCentroids) {
        owner.assign(mesh.triangles.size(), kNoTriangleOwner);
        for (size_t i = 0; i < n; ++i) {
            const uint32_t t = samples.triangles[i];
            if (t >= owner.size())
                throw Error("sample cells", "sample " + std::to_string(i) + " names triangle " + std::to_string(t) +
                                                " of a mesh with " + std::to_string(owner.size()));
            if (owner[t] != kNoTriangleOwner)
                throw Error("sample cells", "two face samples on triangle " + std::to_string(t));
            owner[t] = uint32_t(i);
        }
    }
    mesh_ = std::make_shared<const TriangleMesh>(mesh);
    positions_ = std::make_shared<const std::vector<glm::vec3>>(samples.positions);
    normals_ = std::make_shared<const std::vector<glm::vec3>>(samples.geometricNormals);
    triangleOwner_ = std::make_shared<const std::vector<uint32_t>>(std::move(owner));
    spacing_ = std::sqrt(totalArea(mesh) / double(n));
    if (!(spacing_ > 0.0) || !std::isfinite(spacing_)) throw Error("sample cells", "the mesh has no area");
    build(material);
}

void SampleCells::setMaterial(const Material& material) { build(material); }

void SampleCells::build(const Material& material) {
    const Stopwatch t;
    validateMaterial(material);
    CellQuadratureOptions options;
    options.triangleOwner = *triangleOwner_;
    options.gradedPiecesPerDistance = kGradedPiecesPerDistance;
    // r2 = 3 h whatever the kernel: the far part's point rule needs cells small against
    // r1 = h, which the precompute's cap (a few kernel widths) breaks for faces coarser
    // than the kernel.
    options.maxOuterRadiusWidths = std::numeric_limits<double>::infinity();
    auto quadrature = std::make_shared<const CellQuadrature>(*mesh_, *positions_, *normals_, spacing_, material, options);
    material_ = material;
    nearRadius_ = quadrature->outerRadius() + double(quadrature->maxCellRadius());
    quadrature_ = std::move(quadrature);
    buildSeconds_ = t.seconds();
}

glm::dvec3 SampleCells::weight(uint32_t i, const glm::vec3& x) const {
    double w[3];
    quadrature_->sampleWeightOverPi(i, x, w);
    return kPi * glm::dvec3(w[0], w[1], w[2]);
}

}  // namespace prt
