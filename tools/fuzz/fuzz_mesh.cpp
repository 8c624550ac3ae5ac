// Fuzz target: the mesh loading path (common/mesh_io.h loadMesh: OpenMesh's readers,
// gzip, triangulation, our validation of indices, NaN/Inf, degenerate faces, topology).
// The first input byte picks the file name's extension (.obj .ply .off .stl and the
// same gzip-named), the rest is the file.
//
// Oracle: an accepted mesh satisfies loadMesh's contract (common/mesh.h
// preconditions: indices in range, finite positions, one unit normal per vertex, at
// least one triangle, and the report's counts agree with the result).

#include <cmath>
#include <cstdint>

#include "common/mesh_io.h"
#include "tools/fuzz/fuzz_support.h"

using namespace prt;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    if (size < 1) return 0;
    static const char* const kExtensions[] = {".obj", ".ply", ".off", ".stl",
                                              ".obj.gz", ".ply.gz", ".off.gz", ".stl.gz"};
    const std::string path = fuzz::writeInput(data + 1, size - 1, kExtensions[data[0] % 8]);
    fuzz::expectErrors([&] {
        MeshReport report;
        const TriangleMesh mesh = loadMesh(path, &report);
        fuzz::require(mesh.triangleCount() > 0, "an accepted mesh has triangles");
        fuzz::require(mesh.normals.size() == mesh.positions.size(), "one normal per vertex");
        fuzz::require(report.vertices == mesh.vertexCount() && report.triangles == mesh.triangleCount(),
                      "the report counts the result");
        for (const glm::uvec3& t : mesh.triangles)
            for (int k = 0; k < 3; ++k) fuzz::require(t[k] < mesh.vertexCount(), "indices in range");
        for (size_t v = 0; v < mesh.vertexCount(); ++v) {
            for (int k = 0; k < 3; ++k) fuzz::require(std::isfinite(mesh.positions[v][k]), "finite positions");
            fuzz::require(std::abs(glm::length(mesh.normals[v]) - 1.0f) < 1e-3f, "unit normals");
        }
        fuzz::require(std::isfinite(totalArea(mesh)) && totalArea(mesh) > 0.0, "positive finite area");
        (void)analyseTopology(mesh);
        (void)boundingSphere(mesh);
    });
    return 0;
}
