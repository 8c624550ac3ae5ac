#pragma once
// The project's triangle mesh: a plain, in-memory indexed triangle list, and what works
// on it (bounds, bounding sphere, areas, normals, volume, topology, physical scale,
// centring, fingerprint). No file I/O here: reading and writing files (loadMesh,
// saveMesh, MeshReport) is common/mesh_io.h, which includes this header. Nothing here
// exposes OpenMesh.
//
// Contract:
// - Frame: positions are in the mesh's own (object) frame; nothing here moves it
//   except centreAtOrigin (translation) and scaleToPhysical (scaling about the origin).
// - Units: whatever unit the file uses until scaleToPhysical() is applied; after it,
//   millimetres. Areas and volumes are in those units squared / cubed.
// - Preconditions: every triangle index is < positions.size() (loadMesh guarantees
//   it; the functions here do not check it). normals, when present, has one entry per
//   position. Areas, normals, volume and the sphere radius are computed in double
//   precision and returned in the declared type; bounds are float.
// - Errors: only scaleToPhysical throws (prt::Error, common/error.h, on bad scale
//   input); everything else never throws and accepts an empty mesh (see each function).
//
// Conventions (docs/conventions.md):
// - Triangles are counter-clockwise seen from outside, so the geometric normal
//   cross(p1 - p0, p2 - p0) points outward.
// - Vertex normals are unit length, weighted as in N. Max, "Weights for computing
//   vertex normals from facet normals" (1999): at a vertex with triangle edge vectors
//   e1, e2 a triangle contributes cross(e1, e2) / (|e1|^2 |e2|^2), i.e. its unit normal
//   weighted by sin(corner angle) / (|e1| |e2|). This is exact for vertices on a sphere
//   (area weighting is not: docs/conventions.md, "World frame") and flat on planar
//   regions. A vertex whose sum is zero (no incident triangle, or cancelling ones) gets
//   +Y (0, 1, 0).

#include <glm/glm.hpp>

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <span>
#include <vector>

namespace prt {

struct TriangleMesh {
    std::vector<glm::vec3> positions;
    std::vector<glm::vec3> normals;     // per vertex, unit, Max-weighted (see above)
    std::vector<glm::uvec3> triangles;  // indices into positions, CCW seen from outside

    size_t vertexCount() const { return positions.size(); }
    size_t triangleCount() const { return triangles.size(); }
};

// Axis-aligned bounding box. An empty mesh has lo = hi = (0, 0, 0).
struct Bounds {
    glm::vec3 lo{0.0f};
    glm::vec3 hi{0.0f};

    glm::vec3 size() const { return hi - lo; }
    glm::vec3 centre() const { return 0.5f * (lo + hi); }
    float diagonal() const { return glm::length(hi - lo); }
};

// Bounding box of all positions.
Bounds bounds(const TriangleMesh& mesh);

// Indices 0 .. points.size() - 1 sorted along a Morton curve through the points'
// bounding box (1024 cells per side of its largest extent, stable for equal codes):
// consecutive indices are close in space, so per-point work done in this order (pass 2's
// vertices, the point-light sums) reuses what is already in cache. Throws
// prt::Error(subject, "point i has a non-finite position").
std::vector<uint32_t> mortonOrder(std::span<const glm::vec3> points, const std::string& subject = "points");

// Bounding sphere as the renderers frame the object: centre = the bounding-box centre
// (bounds(mesh).centre(), computed in float, then widened to double), radius = the
// largest distance of a vertex from that centre (double precision). Not the minimal
// enclosing sphere. An empty mesh gives centre (0, 0, 0) and radius 0 (bounds() of an
// empty mesh is lo = hi = 0 and there is no vertex to measure).
struct BoundingSphere {
    glm::dvec3 centre;
    double radius;
};
BoundingSphere boundingSphere(const TriangleMesh& mesh);

// Area of triangle f (computed in double precision).
float faceArea(const TriangleMesh& mesh, size_t f);
// Unit geometric normal of triangle f (outward for a correctly oriented mesh);
// (0, 0, 0) for a zero-area triangle.
glm::vec3 faceNormal(const TriangleMesh& mesh, size_t f);
// Areas of all triangles, in triangle order.
std::vector<float> faceAreas(const TriangleMesh& mesh);
// Sum of all triangle areas (double accumulation).
double totalArea(const TriangleMesh& mesh);
// Signed enclosed volume by the divergence theorem: sum over triangles of
// dot(p0, cross(p1, p2)) / 6. Positive for a closed mesh oriented outward.
double signedVolume(const TriangleMesh& mesh);

// Recomputes mesh.normals (unit, Max weights; see the header comment).
void computeVertexNormals(TriangleMesh& mesh);

// Edge-based topology of the triangle list. With weldCoincident, vertices with
// bit-identical positions (-0 and +0 are the same) count as one vertex, so a mesh
// that splits vertices for sharp normals (makeBox) is still seen as closed.
// Triangles with a repeated (welded) vertex contribute no edge of length zero.
struct MeshTopology {
    size_t vertices = 0;           // distinct vertices referenced by triangles
    size_t edges = 0;              // distinct undirected edges
    size_t faces = 0;              // triangles
    size_t boundaryEdges = 0;      // edges with exactly one incident triangle
    size_t nonManifoldEdges = 0;   // edges with three or more incident triangles
    size_t inconsistentEdges = 0;  // two-triangle edges traversed in the same direction
                                   // by both (neighbours with opposite orientation)

    long long eulerCharacteristic() const {
        return static_cast<long long>(vertices) - static_cast<long long>(edges) +
               static_cast<long long>(faces);
    }
    bool closed() const { return boundaryEdges == 0 && nonManifoldEdges == 0; }
};
MeshTopology analyseTopology(const TriangleMesh& mesh, bool weldCoincident = true);

// Physical size. Exactly one of the two must be set, finite and positive:
//   sizeMm:    the bounding-box diagonal becomes this many millimetres;
//   mmPerUnit: one file unit is this many millimetres.
// Positions are multiplied by the factor about the origin (no recentring; see
// centreAtOrigin); normals are unchanged. Units afterwards are millimetres.
struct MeshScale {
    std::optional<double> sizeMm;
    std::optional<double> mmPerUnit;
};
// Returns the factor applied. Throws prt::Error (subject "--size-mm" or
// "--mm-per-unit", or "mesh scale" when both or neither are given) on bad input, and
// when sizeMm is asked of a mesh whose bounding box has zero diagonal.
double scaleToPhysical(TriangleMesh& mesh, const MeshScale& scale);

// Translates the mesh so that its bounding-box centre is the origin. Returns the
// translation added to every position.
glm::vec3 centreAtOrigin(TriangleMesh& mesh);

// 64-bit FNV-1a hash of, in this order: the vertex count and the triangle count (each
// as a little-endian uint64), the IEEE-754 bit pattern of every position coordinate
// (x, y, z per vertex, each a little-endian uint32), and every triangle index
// (little-endian uint32). Normals are not hashed. Any change of a position bit (even
// -0 versus +0) or of the connectivity changes the value (with overwhelming
// probability); identical meshes give identical values on every platform.
uint64_t meshFingerprint(const TriangleMesh& mesh);

}  // namespace prt
