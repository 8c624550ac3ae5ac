#pragma once
// The ground: an optional diffuse plane under the object that receives its shadow and
// hides the environment below it (Wang et al. 2005, Fig. 1; docs/ground.md).
//
// GEOMETRY. A square in the world's XZ plane (+Y up, docs/conventions.md), facing +Y,
// at height `height` mm, centred on (centre.x, centre.y) = (x, z) with half side
// `halfExtent` mm, split into cells x cells squares of two triangles each. The plane
// under an object (groundPlaneUnder) lies kGroundGap object diagonals below the lowest
// vertex: touching would make the object's flat bottoms coplanar with the plane (a
// primary ray could hit either), and the gap is far larger than the rays' self-
// intersection offset, so a sample on a bottom facing the plane sees the plane, not
// the environment below it.
//
// THE TWO FILES. A precompute with a ground writes the object's transport file with the
// plane among its occluders (parameter kGroundPlaneParameter = formatGroundPlane) and a
// second transport file for the ground's vertices (groundTransportPath; its
// parameters: kGroundPlaneParameter again, and the object's fingerprint as
// kGroundObjectParameter). Renderers rebuild the ground's mesh from the parameter with
// groundMesh, so the two agree bit for bit.
//
// COMBINED MESH. Rays see the object and the ground as one mesh (withGround): the
// object's vertices and triangles first, unchanged, then the ground's, so a hit's
// triangle index tells which was hit (isGroundTriangle).

#include <glm/glm.hpp>

#include <cstddef>
#include <string>

#include "common/mesh.h"
#include "common/transport_file.h"

namespace prt {

struct GroundPlane {
    double height = 0.0;        // y of the plane, mm
    glm::dvec2 centre{0.0};     // (x, z) of its centre, mm
    double halfExtent = 0.0;    // half the side of the square, mm, > 0
    int cells = 1;              // per side, 1 .. kMaxGroundCells
    bool operator==(const GroundPlane&) const = default;
};

inline constexpr int kMaxGroundCells = 1024;
// The largest half side, in object diagonals: rays leave surfaces offset by a distance
// that grows with the scene's largest coordinate (raytrace.h, RayScene::epsilon), and
// up to this size it stays well below kGroundGap, so a bottom facing the plane still
// sees it.
inline constexpr double kMaxGroundHalfExtent = 100.0;
// The gap between the object's lowest vertex and the plane, in object diagonals.
inline constexpr double kGroundGap = 1.0e-3;
// Parameters of the transport files (see above).
inline constexpr const char* kGroundPlaneParameter = "ground_plane";
inline constexpr const char* kGroundObjectParameter = "ground_object";

// What a user asks for: the plane's half side in object diagonals, its cells per side
// and the Lambertian albedo of its surface (R, G, B in [0, 1]).
struct GroundSettings {
    double halfExtentPerDiagonal = 1.5;
    int cells = 128;
    glm::dvec3 albedo{0.5};
};
// Throws prt::Error("--ground-size" / "--ground-cells" / "--ground-albedo", ...) for a
// size outside (0, kMaxGroundHalfExtent], cells outside 1 .. kMaxGroundCells, an albedo
// outside [0, 1].
void validateGroundSettings(const GroundSettings& settings);

// The plane under an object of bounding box `object` (mm): centred under the box's
// centre, kGroundGap diagonals below its lowest point, half side
// settings.halfExtentPerDiagonal diagonals.
GroundPlane groundPlaneUnder(const Bounds& object, const GroundSettings& settings);

// The plane's mesh (mm): (cells + 1)^2 vertices in row-major order (x fastest), normals
// +Y, 2 cells^2 triangles counter-clockwise seen from above.
TriangleMesh groundMesh(const GroundPlane& plane);

// "height,centre_x,centre_z,half_extent,cells" with round-trip precision, and back.
// parseGroundPlane throws prt::Error(subject, ...) for anything else (a count of
// numbers other than five, non-finite numbers, a non-positive extent, bad cells).
std::string formatGroundPlane(const GroundPlane& plane);
GroundPlane parseGroundPlane(const std::string& text, const std::string& subject);

// The object followed by the ground: vertices, normals and triangles appended, the
// ground's indices shifted by object.vertexCount(). Both need normals or neither.
TriangleMesh withGround(const TriangleMesh& object, const TriangleMesh& ground);
// Whether triangle t of withGround(object, ...) is the ground's.
inline bool isGroundTriangle(size_t t, size_t objectTriangles) { return t >= objectTriangles; }

// kGroundObjectParameter's value: the object file's fingerprint as "vertices:hash".
std::string groundObjectText(const MeshFingerprint& object);

// What a ground transport file describes, read from its header (no vectors): the plane
// and the albedo, after the checks that tie it to the object's file, whose fingerprint,
// "ground_plane" and "input_digest" parameters (empty when absent), cubemap size and SH
// terms are given. Throws prt::Error(path, one line) for a file that is not a ground
// file, one made for another object, by another job (another input digest: a stale
// file, or one of other settings), with another cubemap or SH part, or when the
// object's file was precomputed without this plane occluding it; and
// readTransportFileInfo's errors.
struct GroundDescription {
    GroundPlane plane;
    glm::dvec3 albedo{0.0};
};
GroundDescription readGroundDescription(const std::string& path, const MeshFingerprint& object,
                                        const std::string& objectGroundPlane, const std::string& objectDigest,
                                        uint32_t cubemapSize, uint32_t shTerms,
                                        const std::string& objectTransportPath);

// Where a precompute writes the ground's transport file: the object's output path with
// its ".prt" extension replaced by ".ground.prt" ("out/bunny.prt" -> "out/bunny.ground.prt"),
// or ".ground.prt" appended to any other ("out/bunny.v2" -> "out/bunny.v2.ground.prt"), so
// outputs that differ only in another extension get different ground files.
std::string groundTransportPath(const std::string& objectTransportPath);

}  // namespace prt
