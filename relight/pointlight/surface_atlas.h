#pragma once
// An area-preserving surface atlas for texture-space importance sampling (Chang et al.
// 2008, section 2.2 and Eqs. 5-7; SPEC section 9; docs/point-lights.md).
//
// THE MAP. Every triangle is its own chart, laid out ISOMETRICALLY (its 3D shape,
// longest edge as the base) and scaled by one global factor s (texture units per mm),
// so every triangle's texture area is exactly s^2 times its surface area: the map is
// area-preserving by construction (area distortion 1 everywhere; Chang et al. used
// Yoshizawa's stretch-minimising parameterisation, whose distortion is merely small).
// Charts are shelf-packed by their bounding rectangles (sorted by height, a fixed
// order), so about half of the square holds surface.
//
// TEXELS. The unit square is cut into resolution x resolution texels (row-major,
// texel (i, j) covers [i, i+1] x [j, j+1] / resolution). Each texel stands for the
// surface it covers: every triangle is clipped against every texel it overlaps and
//     area[t] = sum over triangles of (overlap in texture space) / s^2      (mm^2),
// which is Eq. 6's per-triangle correction A_S / A_T applied exactly, per texel. The
// texel's surface point (position, normals) is the centroid of its largest overlap, so
// a texel shared by two small triangles is represented by one point and the area of
// both. Sum over texels of area = the mesh area, up to float rounding.
//
// DETERMINISM. No randomness; the same mesh and resolution give the same atlas on any
// thread count. Building costs O(texels + triangles) (SurfaceAtlas::stats.buildSeconds;
// docs/point-lights.md, "The pipeline, module by module").
//
// Threads: build is serial over the packing and parallel over triangles for the
// clipping (per-texel accumulation is done in a fixed order afterwards).

#include <glm/glm.hpp>

#include <cstddef>
#include <cstdint>
#include <vector>

#include "common/mesh.h"
#include "relight/pointlight/point_lights.h"

namespace prt {

struct SurfaceAtlasStats {
    size_t triangles = 0;          // triangles with positive area (charts)
    size_t skippedTriangles = 0;   // zero-area triangles (no chart)
    size_t coveredTexels = 0;      // texels holding surface
    double coverage = 0.0;         // coveredTexels / resolution^2
    double mappedAreaMm2 = 0.0;    // sum of texel areas (double)
    double meshAreaMm2 = 0.0;      // sum of triangle areas (double)
    double scale = 0.0;            // s: texture units per mm
    double minDistortion = 0.0;    // min / max over triangles of A_T / (s^2 A_S): 1 by construction
    double maxDistortion = 0.0;
    double meanTexelsPerTriangle = 0.0;  // texture area of a triangle in texels, mean
    size_t subTexelTriangles = 0;  // triangles smaller than one texel (represented within shared texels)
    double buildSeconds = 0.0;
};

struct SurfaceAtlas {
    int resolution = 0;
    // Per triangle: texture coordinates of its three corners (in the mesh's vertex order),
    // in [0, 1]^2. Zero-area triangles have all three at (0, 0).
    std::vector<glm::vec2> cornerUv;  // 3 per triangle
    // Per texel (resolution^2, row-major): the surface area it stands for (mm^2; 0 =
    // empty) and, for covered texels, the index of its sample in `samples`.
    std::vector<float> texelArea;
    std::vector<uint32_t> texelSample;  // kNoSample for an empty texel
    // One irradiance sample per covered texel (positions, normals, geometric normals,
    // areas = texelArea, triangles), ordered by triangle (then texel) so that
    // consecutive samples are neighbours on the surface; sampleTexel[i] is its texel.
    IrradianceSamples samples;
    std::vector<uint32_t> sampleTexel;
    SurfaceAtlasStats stats;

    static constexpr uint32_t kNoSample = 0xffffffffu;
    size_t texelCount() const { return size_t(resolution) * size_t(resolution); }
};

// Builds the atlas. resolution must be a power of two in [16, 8192] (the mipmap sampler
// needs a power of two). Throws prt::Error for a bad resolution, a mesh with no
// triangle of positive area, or a non-finite position.
SurfaceAtlas buildSurfaceAtlas(const TriangleMesh& mesh, int resolution);

// Throws prt::Error(option, ...) unless resolution is a power of two in [16, 8192].
void validateAtlasResolution(int resolution, const char* option = "--atlas-size");

// The surface area each triangle receives from the texels (mm^2), summed over the
// clipped pieces: equals faceArea(mesh, f) when the clipping is right. For tests.
std::vector<double> atlasTriangleAreas(const TriangleMesh& mesh, const SurfaceAtlas& atlas);

}  // namespace prt
