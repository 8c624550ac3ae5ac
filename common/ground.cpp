#include "common/ground.h"

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <vector>
#include <filesystem>

#include "common/error.h"
#include "common/util.h"

namespace prt {

void validateGroundSettings(const GroundSettings& s) {
    if (!(s.halfExtentPerDiagonal > 0.0 && s.halfExtentPerDiagonal <= kMaxGroundHalfExtent))
        throw Error("--ground-size", "must be a number of object diagonals in (0, " +
                                         std::to_string(int(kMaxGroundHalfExtent)) + "]");
    if (s.cells < 1 || s.cells > kMaxGroundCells)
        throw Error("--ground-cells", "must be in 1.." + std::to_string(kMaxGroundCells));
    for (int c = 0; c < 3; ++c)
        if (!(s.albedo[c] >= 0.0 && s.albedo[c] <= 1.0))
            throw Error("--ground-albedo", "each channel must be in [0, 1]");
}

GroundPlane groundPlaneUnder(const Bounds& object, const GroundSettings& settings) {
    validateGroundSettings(settings);
    const double diagonal = object.diagonal();
    if (!(diagonal > 0.0)) throw Error("ground", "the object has no extent to put a plane under");
    GroundPlane plane;
    plane.height = double(object.lo.y) - kGroundGap * diagonal;
    plane.centre = {0.5 * (double(object.lo.x) + double(object.hi.x)), 0.5 * (double(object.lo.z) + double(object.hi.z))};
    plane.halfExtent = settings.halfExtentPerDiagonal * diagonal;
    plane.cells = settings.cells;
    return plane;
}

TriangleMesh groundMesh(const GroundPlane& plane) {
    const int n = plane.cells;
    TriangleMesh mesh;
    mesh.positions.reserve(size_t(n + 1) * size_t(n + 1));
    for (int j = 0; j <= n; ++j)
        for (int i = 0; i <= n; ++i) {
            // Edge vertices exactly at +-halfExtent, the rest evenly between.
            const double u = -1.0 + 2.0 * double(i) / n, v = -1.0 + 2.0 * double(j) / n;
            mesh.positions.emplace_back(plane.centre.x + u * plane.halfExtent, plane.height,
                                        plane.centre.y + v * plane.halfExtent);
        }
    mesh.normals.assign(mesh.positions.size(), glm::vec3(0.0f, 1.0f, 0.0f));
    mesh.triangles.reserve(2 * size_t(n) * size_t(n));
    const auto at = [n](int i, int j) { return unsigned(j * (n + 1) + i); };
    for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i) {
            // x to the right, z toward the viewer: (x, z) -> (x, z + 1) -> (x + 1, z)
            // turns counter-clockwise seen from +Y.
            mesh.triangles.emplace_back(at(i, j), at(i, j + 1), at(i + 1, j));
            mesh.triangles.emplace_back(at(i + 1, j), at(i, j + 1), at(i + 1, j + 1));
        }
    return mesh;
}

std::string formatGroundPlane(const GroundPlane& p) {
    char text[160];
    std::snprintf(text, sizeof text, "%.17g,%.17g,%.17g,%.17g,%d", p.height, p.centre.x, p.centre.y, p.halfExtent,
                  p.cells);
    return text;
}

GroundPlane parseGroundPlane(const std::string& text, const std::string& subject) {
    const std::vector<std::string> fields = splitText(text, ',');
    if (fields.size() != 5)
        throw Error(subject, "a ground plane is \"height,centre_x,centre_z,half_extent,cells\", got \"" + text + "\"");
    double v[4];
    for (int k = 0; k < 4; ++k) {
        char* end = nullptr;
        v[k] = std::strtod(fields[size_t(k)].c_str(), &end);
        if (end == fields[size_t(k)].c_str() || *end != '\0' || !std::isfinite(v[k]))
            throw Error(subject, "ground plane: \"" + fields[size_t(k)] + "\" is not a finite number");
    }
    char* end = nullptr;
    const long cells = std::strtol(fields[4].c_str(), &end, 10);
    if (end == fields[4].c_str() || *end != '\0' || cells < 1 || cells > kMaxGroundCells)
        throw Error(subject, "ground plane: cells must be an integer in 1.." + std::to_string(kMaxGroundCells));
    if (!(v[3] > 0.0)) throw Error(subject, "ground plane: the half extent must be positive");
    return GroundPlane{v[0], {v[1], v[2]}, v[3], int(cells)};
}

TriangleMesh withGround(const TriangleMesh& object, const TriangleMesh& ground) {
    if (object.normals.empty() != ground.normals.empty())
        throw Error("ground", "the object and the ground must both have vertex normals, or neither");
    TriangleMesh all = object;
    const unsigned offset = unsigned(object.vertexCount());
    all.positions.insert(all.positions.end(), ground.positions.begin(), ground.positions.end());
    all.normals.insert(all.normals.end(), ground.normals.begin(), ground.normals.end());
    all.triangles.reserve(object.triangleCount() + ground.triangleCount());
    for (const glm::uvec3& t : ground.triangles) all.triangles.push_back(t + glm::uvec3(offset));
    return all;
}

std::string groundObjectText(const MeshFingerprint& object) {
    char text[48];
    std::snprintf(text, sizeof text, "%llu:%016llx", static_cast<unsigned long long>(object.vertexCount),
                  static_cast<unsigned long long>(object.positionHash));
    return text;
}

GroundDescription readGroundDescription(const std::string& path, const MeshFingerprint& object,
                                        const std::string& objectGroundPlane, const std::string& objectDigest,
                                        uint32_t cubemapSize, uint32_t shTerms,
                                        const std::string& objectTransportPath) {
    const TransportFileInfo info = readTransportFileInfo(path);
    if (info.parameter("receiver") != "ground")
        throw Error(path, "not a ground transport file (prt-precompute --ground writes one beside the object's)");
    GroundDescription g;
    g.plane = parseGroundPlane(info.parameter(kGroundPlaneParameter), path);
    if (info.parameter(kGroundObjectParameter) != groundObjectText(object))
        throw Error(path, "made for another object (" + info.parameter(kGroundObjectParameter) + ") than " +
                              objectTransportPath + " (" + groundObjectText(object) + ")");
    if (objectGroundPlane != info.parameter(kGroundPlaneParameter))
        throw Error(path, objectTransportPath + " was precomputed without this ground occluding it (precompute the "
                                                "object with --ground)");
    if (info.parameter("input_digest") != objectDigest)
        throw Error(path, "made by another precompute job than " + objectTransportPath +
                              " (their input digests differ): run prt-precompute --ground again");
    if (info.cubemapSize != cubemapSize || info.shTerms != shTerms)
        throw Error(path, "its cubemap or SH part differs from " + objectTransportPath + "'s");
    const std::vector<double> albedo = parseNumberList(info.parameter("albedo"), path, "albedo");
    if (albedo.size() != 3) throw Error(path, "its albedo parameter is not R,G,B");
    g.albedo = {albedo[0], albedo[1], albedo[2]};
    return g;
}

std::string groundTransportPath(const std::string& objectTransportPath) {
    std::filesystem::path p(objectTransportPath);
    // Only ".prt" is replaced: "x.v1" and "x.v2" must not share "x.ground.prt".
    if (toLower(p.extension().string()) == ".prt") {
        p.replace_extension(".ground.prt");
        return p.string();
    }
    return objectTransportPath + ".ground.prt";
}

}  // namespace prt
