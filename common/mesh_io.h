#pragma once
// Mesh files: loadMesh reads .obj, .ply, .off and .stl (each optionally gzip-compressed)
// and glTF 2.0 (.gltf, .glb) into a TriangleMesh (common/mesh.h, included here),
// reporting what it found in a MeshReport; saveMesh writes one (not glTF:
// common/asset_io.h writes that). OpenMesh (the first four formats, and most of the
// writing) and Assimp (glTF) work inside mesh_io.cpp only; nothing here exposes them.
// loadMeshSurface also hands over what a file says about the surface (per-corner
// texture coordinates and normals, materials as written) for loadAsset
// (common/asset_io.h), which turns it into materials and textures.
//
// Contract:
// - Format: chosen by the file name's extension, case-insensitive (.obj .ply .off .stl,
//   plus .gz for loading; .gltf .glb for loading, never compressed); loadMesh also
//   decompresses any file with gzip magic (not glTF).
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
//   process-wide mutex (Assimp importers are made per call). Temporary files (decompression in the system temp directory,
//   saveMesh's in the target's directory) are removed again on success and on error.

#include "common/mesh.h"

#include <cstddef>
#include <string>

namespace prt {

// What loadMesh found and did. All counts refer to one call.
struct MeshReport {
    std::string format;               // "obj", "ply", "off", "stl", "gltf" or "glb"
    bool compressed = false;          // the file was gzip-compressed
    size_t fileVertices = 0;          // vertices the reader produced (STL: after OpenMesh
                                      // merged identical corners; glTF: after welding,
                                      // see loadMesh)
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
// decompressed), or glTF 2.0 (.gltf with its buffers, or .glb). Compressed data is
// decompressed into a temporary file (removed again) that OpenMesh reads. Polygons are
// triangulated (ear clipping in the polygon's plane; fan for polygons of more than 256
// corners or when clipping fails).
//
// Vertices keep the file's order (deterministic). Exceptions: OpenMesh's STL reader
// merges corners with identical positions, numbering them in order of first
// appearance; vertices used by no kept triangle are removed, the others keeping their
// relative order. Normals are computed (computeVertexNormals); normals in the file
// are ignored.
//
// glTF: the default scene's node tree is flattened, depth first (a node, then its
// children in order), each node's meshes in order, each mesh's primitives in order;
// positions are transformed by the node's global matrix (not touched when it is the
// identity, so their bits are the file's). Vertices with equal positions (compared as
// floats, so -0 and +0 are one) are welded into one, numbered in order of first
// appearance in the vertex buffers (each primitive's vertices in order, primitives in
// the order visited): glTF splits vertices at texture seams and hard normals, the
// project needs one vertex per surface point. TRIANGLES, TRIANGLE_STRIP and
// TRIANGLE_FAN primitives are read; POINTS and LINES* are refused. Meshes of nodes
// outside the scene and animations, skins and morph targets are ignored.
//
// Throws prt::Error(path, reason) for: a missing or unreadable file, an unknown
// extension, corrupt gzip data, a parse failure or truncated file, a face index out of
// range, a NaN or infinite coordinate (anywhere in the file), a mesh without faces,
// and a mesh whose faces are all degenerate; for glTF also invalid JSON, a broken .glb
// container, a version other than 2.x, a buffer, buffer view or accessor out of range,
// a missing buffer file, an index out of range, a POINTS or LINES primitive and a
// malformed media type or data URI. Survives with a prt::warn (one line per kind, with
// counts): degenerate faces (dropped), unreferenced vertices (dropped),
// boundary edges, non-manifold edges and inconsistently oriented neighbours (kept).
// A triangle is degenerate when two of its corners are the same vertex or its area is
// at most 1e-12 * (bounding-box diagonal)^2. Topology counts weld coincident vertices.
TriangleMesh loadMesh(const std::string& path, MeshReport* report = nullptr);

// Texture wrap modes as glTF names them (the sampler's wrapS / wrapT).
enum class TextureWrap { Repeat, ClampToEdge, MirroredRepeat };

// A material as the file writes it, before any texture is read (loadAsset does that).
struct FileMaterial {
    std::string name;
    glm::vec4 baseColorFactor{1.0f};  // linear RGBA (glTF baseColorFactor; OBJ: set by
                                      // loadAsset from the MTL's Kd)
    std::string texture;              // base-colour texture: a path as written in the
                                      // file (relative to it), or "" for none
    std::string embeddedTexture;      // or the bytes of an image embedded in the file
                                      // (.glb buffer view, data URI): PNG, JPEG, ...
    std::string embeddedFormat;       // its format hint ("png", "jpg"), may be empty
    TextureWrap wrapU = TextureWrap::Repeat;
    TextureWrap wrapV = TextureWrap::Repeat;
};

// What a file says about the surface besides positions and triangles, aligned with the
// mesh loadMeshSurface returns (after triangulation and the removal of degenerate
// triangles): corner k of triangle t is entry 3 t + k.
struct MeshSurface {
    // Texture coordinates per corner, empty when the file has none. Convention: u to the
    // right, v up, (0, 0) the bottom-left corner of the image (OBJ's; glTF's
    // TEXCOORD_0, whose v runs down from the top-left corner, is stored as (u, 1 - v)).
    // A corner without one (an OBJ face without vt beside faces with it, a glTF
    // primitive without TEXCOORD_0 beside others) holds (NaN, NaN).
    std::vector<glm::vec2> uvs;
    // Normals per corner as written in the file (OBJ vn, glTF NORMAL, rotated by the
    // node's matrix and normalised), empty when the file has none, (NaN, NaN, NaN) for a
    // corner without one. Not used by loadMesh, which computes its normals.
    std::vector<glm::vec3> normals;
    // Per triangle: index into `materials`.
    std::vector<uint32_t> triangleMaterials;
    // glTF: the file's materials (textures named or embedded) as Assimp lists them
    // (with the default material it appends for primitives without one). OBJ: one entry per name given to usemtl (in
    // order of first use; factor and texture are left to loadAsset's MTL reader), plus a
    // last entry named "" for faces before any usemtl. Other formats: one default entry.
    std::vector<FileMaterial> materials;
    // OBJ: the files named by mtllib, as written (relative to the OBJ), in order.
    std::vector<std::string> materialLibraries;
};

// loadMesh, returning the same mesh (same vertices, triangles and fingerprint) and
// filling `surface` as described above. OBJ texture coordinates and normals are
// read by the pre-scan, which also refuses a vt/vn index out of range and a NaN/Inf
// texture coordinate or normal (prt::Error naming the line).
TriangleMesh loadMeshSurface(const std::string& path, MeshSurface& surface, MeshReport* report = nullptr);

// Writes .ply (binary little-endian), .off (ascii) or .stl (binary) through OpenMesh,
// and .obj directly (OpenMesh's OBJ writer uses fixed-point notation, which loses
// small coordinates). Text formats use 9 significant digits, so float positions
// survive exactly. Positions and
// triangles only; written to a temporary file in the same directory, then renamed.
// Every triangle is written as it is (non-manifold meshes included).
// Throws prt::Error(path, reason) on an unknown extension or a failed write.
void saveMesh(const TriangleMesh& mesh, const std::string& path);

}  // namespace prt
