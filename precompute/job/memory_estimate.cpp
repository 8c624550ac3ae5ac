#include "precompute/job/memory_estimate.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <utility>
#include <vector>

#include "common/error.h"
#include "common/cell_quadrature.h"
#include "common/radial_kernels.h"

namespace prt {

namespace {
constexpr double kSafety = 1.5;
}

MemoryEstimate estimatePrecomputeMemory(const PrecomputeSettings& s, size_t vertices, size_t triangles,
                                        size_t samples, int threads, double totalAreaMm2, double objectSizeMm) {
    const double texels = 6.0 * double(s.cubemapSize) * double(s.cubemapSize);
    const bool ms = s.components.multipleScattering;
    // Single scattering keeps K vectors (one when isotropic) of one float per entry.
    const double terms =
        s.components.singleScattering ? (s.material.g != 0.0 ? double(s.phase.terms) : 1.0) : 0.0;
    const double n = ms ? double(samples) : 0.0;
    // An editable job: J profiles per vertex instead of three channels, a narrower kernel.
    const bool editable = ms && s.editable.enabled && objectSizeMm > 0.0;
    const double channels = editable ? double(s.editable.basis.size) : 3.0;
    const RadialRange range = editable ? editableRange(s, objectSizeMm) : RadialRange{};
    const RadialKernels dipole(s.material);
    const double narrowest = editable ? narrowestDipoleWidth(range) : dipole.narrowestWidth();
    const double widest = editable ? widestDipoleWidth(range) : dipole.widestWidth();
    CellQuadratureOptions cellOptions;
    if (editable) cellOptions.gradedPiecesPerDistance = s.editable.cellGrading;
    // The sample spacing of n samples over the area (sampling.h: a triangular lattice).
    const double spacing = n > 0.0 ? std::sqrt(2.0 * totalAreaMm2 / n / std::sqrt(3.0)) : 0.0;
    const double subPoints =
        ms && totalAreaMm2 > 0.0 && spacing > 0.0
            ? estimateCellSubPoints(totalAreaMm2, triangles, narrowest, widest, spacing, cellOptions)
            : 0.0;
    const bool graded = editable && cellOptions.gradedPiecesPerDistance > 0.0;
    // The ground (--ground): its (cells + 1)^2 vertices' RGB vectors, its 2 cells^2
    // triangles in the scene, and the object + plane mesh copy the scene is built from.
    const double groundCells = s.ground ? double(s.ground->cells) : 0.0;
    const double groundVertices = s.ground ? (groundCells + 1.0) * (groundCells + 1.0) : 0.0;
    const double groundTriangles = 2.0 * groundCells * groundCells;
    // Single-scattering sites (--ss-site-spacing h): at most a hexagonal packing of the
    // area at spacing h, each holding its terms' larger vectors (an index and three
    // floats per entry), and about 12 blend entries per vertex.
    // Without the area (single scattering alone), every vertex.
    const double h = s.components.singleScattering ? resolvedSiteSpacing(s) : 0.0;
    const double sites = h <= 0.0            ? 0.0
                         : totalAreaMm2 > 0.0 ? std::min(double(vertices), 2.0 * totalAreaMm2 / (std::sqrt(3.0) * h * h))
                                              : double(vertices);
    const double siteBytes =
        h > 0.0 ? sites * terms *
                          std::min(texels, double(s.vertexCoefficients) * double(std::max(1, s.singleScattering.siteCoefficientFactor))) *
                          16.0 +
                      double(vertices) * (12.0 * 8.0 + 16.0)
                : 0.0;
    const std::vector<std::pair<const char*, double>> parts = {
        // + 36 bytes per triangle of single scattering's corner normals
        {"mesh and ray scene", (s.components.singleScattering ? 286.0 : 250.0) * double(triangles)},
        {"samples", 200.0 * n},
        {"pass 1 vectors", n * (double(s.pass1.sampleCoefficients) * 8.0 + 64.0)},
        {"pass 2 kd-tree sums", n / 4.0 * (double(s.pass2.nodeCoefficients) * 8.0 + 64.0)},
        {"pass 2 cell sub-points", subPoints * (graded ? kCellBytesPerGradedSubPoint : kCellBytesPerSubPoint)},
        // The file's arrays: 8 bytes per term (a 16-bit index and three 16-bit values) for
        // each multiple-scattering component of three channels and each single-scattering term.
        {"per-vertex results", double(vertices) * double(s.vertexCoefficients) * 8.0 * ((ms ? channels / 3.0 : 0.0) + terms)},
        // Pass 2's float vectors of one chunk of vertices (an index and K floats per term).
        {"pass 2 vectors of a chunk", ms ? double(std::min(vertices, std::max<size_t>(s.pass2ChunkVertices, 1))) *
                                               double(s.vertexCoefficients) * (4.0 + 4.0 * channels)
                                         : 0.0},
        // Blocks (per component: 16 vertices share an index and 48 one-byte values per term).
        {"blocks", s.blockCoefficients > 0 ? double(vertices) / 16.0 * double(s.blockCoefficients) * 50.0 *
                                                 ((ms ? channels / 3.0 : 0.0) + terms)
                                           : 0.0},
        {"single-scattering sites", siteBytes},
        {"per-thread workspaces", double(std::max(threads, 1)) * texels * 64.0 * std::max(1.0, channels / 3.0)},
        {"ground", groundTriangles * 250.0 + groundVertices * (double(s.vertexCoefficients) * 16.0 + 64.0) +
                       (s.ground ? 40.0 * double(vertices) + 12.0 * double(triangles) : 0.0)},
    };
    MemoryEstimate e;
    double total = 0.0, largest = -1.0;
    for (const auto& [name, bytes] : parts) {
        total += bytes;
        if (bytes > largest) {
            largest = bytes;
            e.largest = std::string(name) + " " + formatBytes(uint64_t(bytes));
        }
    }
    e.bytes = uint64_t(std::min(total * kSafety, 1.8e19));
    return e;
}

void checkMemory(const MemoryEstimate& estimate, double maxMemoryGb) {
    if (!std::isfinite(maxMemoryGb) || maxMemoryGb < 0.0)
        throw Error("--max-memory", "must be a finite number of GB >= 0 (0 = the available memory)");
    const uint64_t limit = maxMemoryGb > 0.0 ? uint64_t(maxMemoryGb * 1e9) : availableMemoryBytes();
    if (limit == 0 || estimate.bytes <= limit) return;
    throw Error("memory", "the job needs about " + formatBytes(estimate.bytes) + " (largest: " + estimate.largest +
                              "), " + formatBytes(limit) + (maxMemoryGb > 0.0 ? " allowed by --max-memory" : " available") +
                              "; use --max-memory GB to allow more, or fewer samples (--samples, --sample-spacing) "
                              "or coefficients");
}

}  // namespace prt
