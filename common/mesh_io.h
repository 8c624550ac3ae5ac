#pragma once
// Mesh files: loadMesh reads .obj, .ply, .off and .stl (each optionally gzip-compressed)
// into a TriangleMesh (common/mesh.h, included here), reporting what it found in a
// MeshReport; saveMesh writes one. OpenMesh does the parsing and most of the writing,
// inside mesh_io.cpp only; nothing here exposes it.
//
// Contract:
// - Format: chosen by the file name's extension, case-insensitive (.obj .ply .off .stl,
//   plus .gz for loading); loadMesh also decompresses any file with gzip magic.
// - Units and frame: none are applied. Positions are the file's numbers in the file's
//   frame, unscaled and uncentred (scaleToPhysical and centreAtOrigin, common/mesh.h,
//   do that); saveMesh writes the positions as they are.
// - Result: loadMesh returns a mesh satisfying common/mesh.h's preconditions (indices in
//   range, finite positions, at least one non-degenerate triangle, normals computed).
// - Preconditions: saveMesh checks the triangle indices itself (an index out of range
//   is an error); normals are neither read nor written.
// - Errors: failures throw prt::Error (common/error.h) whose subject is the path and
//   whose reason is one line; survivable defects are prt::warn'ed (see loadMesh).
// - Threads: callable from any thread; calls into OpenMesh are serialised by a
//   process-wide mutex. Temporary files (decompression in the system temp directory,
//   saveMesh's in the target's directory) are removed again on success and on error.

#include "common/mesh.h"

#include <cstddef>
#include <string>

namespace prt {

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
    size_t removedFaces = 0;          // all input triangles not in the result (the
                                      // degenerate ones)
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

}  // namespace prt
