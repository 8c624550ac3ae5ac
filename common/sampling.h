#pragma once
// Pass 1 surface samples (SPEC section 6): well-distributed points on a triangle mesh,
// each standing for the same area A_i = total area / N (never pi (d/2)^2).
//
// Method: weighted sample elimination (Yuksel 2015, "Sample Elimination for
// Generating Poisson Disk Sample Sets"). We draw candidateFactor * N candidates
// uniformly by area, give each the weight sum_j w(d_ij) over its neighbours within
// 2 r_max, with w(d) = (1 - d / (2 r_max))^8 and r_max = sqrt(A / (2 sqrt(3) N)) (the
// disk radius of a hexagonal packing of N disks on area A), then repeatedly remove the
// candidate with the largest weight (subtracting its contribution from its
// neighbours) until exactly N remain.
//
// Limitations and choices:
// - Distances are 3D Euclidean, a proxy for geodesic distance. Where two sheets of
//   the surface are closer than about 2 r_max (thin plates, folds), Euclidean
//   neighbours on the other sheet would repel, leaving such parts under-sampled
//   relative to their area. To avoid that, two candidates only interact when the
//   angle between their triangles' geometric normals is below 120 degrees
//   (cos > -0.5), so opposite faces of a thin plate are sampled independently.
//   Consequence: inside very sharp creases (dihedral angle below 60 degrees) the two
//   sides do not repel, and samples can come closer than elsewhere.
//   On strongly curved parts whose radius is comparable to r_max the Euclidean
//   proxy is also coarse; pick N so that r_max is well below feature size.
// - Output is deterministic for a given mesh, count and seed: the same on every run
//   and for every TBB thread count (a counter-based PRNG written here, no std::
//   distributions; parallel steps only compute independent per-candidate values).
// - Degenerate (zero-area) triangles never receive samples. A mesh whose total
//   area is zero (or not finite) is rejected with prt::Error.
//
// Barycentric convention: position = (1 - b.x - b.y) p0 + b.x p1 + b.y p2 for the
// triangle's vertices (p0, p1, p2) in index order.

#include <glm/glm.hpp>

#include <cstddef>
#include <cstdint>
#include <vector>

#include "common/mesh.h"

namespace prt {

struct SurfaceSample {
    glm::vec3 position{0.0f};
    // Interpolated vertex normal, unit: the shading normal n_i of Wang Eq. 8. Falls
    // back to the geometric normal when the mesh has no (valid) vertex normals or the
    // interpolated normal does not point to the triangle's front side.
    glm::vec3 normal{0.0f};
    glm::vec3 geometricNormal{0.0f};  // unit normal of its triangle (CCW front side)
    uint32_t triangle = 0;
    glm::vec2 barycentric{0.0f};  // weights of vertices 1 and 2 (see top of file)
};

struct SampleSet {
    std::vector<SurfaceSample> samples;
    double totalArea = 0.0;      // of the whole mesh, in mesh units^2 (mm^2)
    double areaPerSample = 0.0;  // totalArea / N: the A_i of every sample
    double minSpacing = 0.0;     // achieved minimum pairwise distance (0 when N < 2)
};

// Lower clamp of defaultSampleCount and the cap the tools use by default.
inline constexpr size_t kMinSampleCount = 64;
inline constexpr size_t kDefaultSampleCap = 300000;

// Number of samples for a surface of area totalAreaMm2 with typical spacing
// spacingMm between neighbouring samples (callers pass l_u = 1 / sigma_t').
// Hexagonal packing: a sample whose six neighbours are `spacing` away covers
// (sqrt(3) / 2) spacing^2, so N = ceil(2 A / (sqrt(3) spacing^2)) (about 1.155 A /
// spacing^2). Equivalently the elimination radius r_max of poissonDiskSamples is
// spacing / 2. Clamped to [kMinSampleCount, cap] (to cap alone when cap is smaller).
// Throws prt::Error for non-positive or non-finite area or spacing, or cap == 0.
size_t defaultSampleCount(double totalAreaMm2, double spacingMm, size_t cap = kDefaultSampleCap);

// Radius r_max = sqrt(A / (2 sqrt(3) N)) of the densest (hexagonal) packing of N
// disks on area A; 2 r_max is the neighbour distance of that packing.
double hexagonalPackingRadius(double area, size_t count);

struct PoissonDiskOptions {
    double candidateFactor = 5.0;  // candidates drawn per output sample (>= 1)
    // Yuksel's weight limiting: distances below 2 r_min, r_min = r_max * beta *
    // (1 - (N / M)^gamma), beta = 0.65, gamma = 1.5, count as 2 r_min.
    bool weightLimiting = true;
    // Candidates whose geometric normals have a cosine below this do not interact
    // (treated as different sheets). -1 disables the test (pure Euclidean).
    double sheetCosine = -0.5;
};

// Exactly `count` well-distributed samples (see top of file). The samples are in
// spatially coherent order (Z-order of the cells of a uniform grid), not in
// elimination order. Throws prt::Error when count == 0, when the mesh is malformed (vertex
// index out of range) or its total area is zero.
SampleSet poissonDiskSamples(const TriangleMesh& mesh, size_t count, uint64_t seed,
                             const PoissonDiskOptions& options = {});

// `count` independent samples uniform by area (area-weighted triangle choice,
// uniform barycentrics), in generation order. Same validation as above.
SampleSet uniformRandomSamples(const TriangleMesh& mesh, size_t count, uint64_t seed);

// Exact minimum pairwise Euclidean distance between the sample positions (0 when
// fewer than two samples).
double minimumPairwiseDistance(const std::vector<SurfaceSample>& samples);

}  // namespace prt
