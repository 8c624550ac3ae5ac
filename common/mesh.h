#pragma once
// The project's triangle mesh: a plain, in-memory indexed triangle list. OpenMesh is
// used only inside mesh.cpp (file reading and writing); nothing here exposes it.
//
// Conventions (docs/conventions.md):
// - Triangles are counter-clockwise seen from outside, so the geometric normal
//   cross(p1 - p0, p2 - p0) points outward.
// - Vertex normals are unit length, weighted as in N. Max, "Weights for computing
//   vertex normals from facet normals" (1999): at a vertex with triangle edge vectors
//   e1, e2 a triangle contributes cross(e1, e2) / (|e1|^2 |e2|^2), i.e. its unit normal
//   weighted by sin(corner angle) / (|e1| |e2|). This is exact for vertices on a sphere
//   (area weighting is only first-order accurate on an irregular icosphere: 2e-2 at
//   level 2) and flat on planar regions. A vertex whose sum is zero (no incident
//   triangle, or cancelling ones) gets +Y (0, 1, 0).
// - Lengths are in whatever unit the file uses until scaleToPhysical() is applied;
//   after it they are millimetres.

#include <glm/glm.hpp>

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
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

// What loadMesh found and did. All counts refer to one call.
struct MeshReport {
    std::string format;               // "obj", "ply", "off" or "stl"
    bool compressed = false;          // the file was gzip-compressed
    size_t fileVertices = 0;          // vertices the reader produced (STL: after OpenMesh
                                      // merged identical corners, see loadMesh)
    size_t fileFaces = 0;             // face records in the file, any number of corners
    size_t polygonsTriangulated = 0;  // face records with more than 3 corners
    size_t inputTriangles = 0;        // triangles after triangulation, counting a face
                                      // record the reader itself dropped as one
    size_t degenerateFaces = 0;       // triangles dropped: < 3 distinct vertices or zero area
    size_t removedFaces = 0;          // all input triangles not in the result; today
                                      // exactly the degenerate ones
    size_t unreferencedVertices = 0;  // vertices used by no kept triangle (removed)
    // Topology of the result, analyseTopology(mesh, /*weldCoincident=*/true):
    size_t boundaryEdges = 0;
    size_t nonManifoldEdges = 0;
    size_t inconsistentEdges = 0;
    long long eulerCharacteristic = 0;
    // The result:
    size_t vertices = 0;
    size_t triangles = 0;
};

// Loads a mesh: .obj, .ply (ascii or binary), .off or .stl (ascii or binary), each
// optionally gzip-compressed (name ending in .gz; a file with gzip magic is also
// decompressed). Compressed data is decompressed into a temporary file (removed
// again) that OpenMesh reads. Polygons are triangulated (ear clipping in the
// polygon's plane; fan for polygons of more than 256 corners or when clipping fails).
//
// Vertices keep the file's order (deterministic). Exceptions: OpenMesh's STL reader
// merges corners with identical positions, numbering them in order of first
// appearance; vertices used by no kept triangle are removed, the others keeping their
// relative order. Normals are computed (computeVertexNormals); normals in the file
// are ignored.
//
// Throws prt::Error(path, reason) for: a missing or unreadable file, an unknown
// extension, corrupt gzip data, a parse failure or truncated file, a face index out of
// range, a NaN or infinite coordinate (anywhere in the file), a mesh without faces,
// and a mesh whose faces are all degenerate. Survives with a prt::warn (one line per
// kind, with counts): degenerate faces (dropped), unreferenced vertices (dropped),
// boundary edges, non-manifold edges and inconsistently oriented neighbours (kept).
// A triangle is degenerate when two of its corners are the same vertex or its area is
// at most 1e-12 * (bounding-box diagonal)^2. Topology counts weld coincident vertices.
TriangleMesh loadMesh(const std::string& path, MeshReport* report = nullptr);

// Writes .ply (binary little-endian), .off (ascii) or .stl (binary) through OpenMesh,
// and .obj directly (OpenMesh's OBJ writer uses fixed-point notation, which loses
// small coordinates). Text formats use 9 significant digits, so float positions
// survive exactly. Positions and
// triangles only; written to a temporary file in the same directory, then renamed.
// Every triangle is written as it is (non-manifold meshes included).
// Throws prt::Error(path, reason) on an unknown extension or a failed write.
void saveMesh(const TriangleMesh& mesh, const std::string& path);

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
