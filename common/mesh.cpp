// The in-memory mesh (common/mesh.h): geometry, topology, physical scale, centring,
// fingerprint. File reading and writing is mesh_io.cpp.
#include "common/mesh.h"

#include "common/error.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <limits>
#include <numeric>
#include <string>
#include <utility>

namespace prt {

// ---------------------------------------------------------------------------------
// Geometry
// ---------------------------------------------------------------------------------

namespace {

glm::dvec3 crossOf(const TriangleMesh& mesh, size_t f) {
    const glm::uvec3 t = mesh.triangles[f];
    const glm::dvec3 p0(mesh.positions[t.x]);
    const glm::dvec3 p1(mesh.positions[t.y]);
    const glm::dvec3 p2(mesh.positions[t.z]);
    return glm::cross(p1 - p0, p2 - p0);
}

}  // namespace

Bounds bounds(const TriangleMesh& mesh) {
    Bounds b;
    if (mesh.positions.empty()) return b;
    b.lo = b.hi = mesh.positions.front();
    for (const auto& p : mesh.positions) {
        b.lo = glm::min(b.lo, p);
        b.hi = glm::max(b.hi, p);
    }
    return b;
}

BoundingSphere boundingSphere(const TriangleMesh& mesh) {
    BoundingSphere s;
    s.centre = glm::dvec3(bounds(mesh).centre());
    double r2 = 0;
    for (const glm::vec3& p : mesh.positions) {
        const glm::dvec3 d = glm::dvec3(p) - s.centre;
        r2 = std::max(r2, glm::dot(d, d));
    }
    s.radius = std::sqrt(r2);
    return s;
}

float faceArea(const TriangleMesh& mesh, size_t f) {
    return float(0.5 * glm::length(crossOf(mesh, f)));
}

glm::vec3 faceNormal(const TriangleMesh& mesh, size_t f) {
    const glm::dvec3 c = crossOf(mesh, f);
    const double len = glm::length(c);
    if (!(len > 0.0)) return glm::vec3(0.0f);
    return glm::vec3(c / len);
}

std::vector<float> faceAreas(const TriangleMesh& mesh) {
    std::vector<float> areas(mesh.triangles.size());
    for (size_t f = 0; f < areas.size(); ++f) areas[f] = faceArea(mesh, f);
    return areas;
}

double totalArea(const TriangleMesh& mesh) {
    double sum = 0.0;
    for (size_t f = 0; f < mesh.triangles.size(); ++f) sum += 0.5 * glm::length(crossOf(mesh, f));
    return sum;
}

double signedVolume(const TriangleMesh& mesh) {
    double sum = 0.0;
    for (const auto& t : mesh.triangles) {
        const glm::dvec3 p0(mesh.positions[t.x]);
        const glm::dvec3 p1(mesh.positions[t.y]);
        const glm::dvec3 p2(mesh.positions[t.z]);
        sum += glm::dot(p0, glm::cross(p1, p2));
    }
    return sum / 6.0;
}

void computeVertexNormals(TriangleMesh& mesh) {
    // Max (1999) weights: at corner v with edge vectors e1, e2 the triangle adds
    // cross(e1, e2) / (|e1|^2 |e2|^2), i.e. its unit normal times
    // sin(angle) / (|e1| |e2|). Exact for vertices on a sphere.
    std::vector<glm::dvec3> sum(mesh.positions.size(), glm::dvec3(0.0));
    for (const auto& t : mesh.triangles) {
        const uint32_t idx[3] = {t.x, t.y, t.z};
        for (int k = 0; k < 3; ++k) {
            const glm::dvec3 p(mesh.positions[idx[k]]);
            const glm::dvec3 e1 = glm::dvec3(mesh.positions[idx[(k + 1) % 3]]) - p;
            const glm::dvec3 e2 = glm::dvec3(mesh.positions[idx[(k + 2) % 3]]) - p;
            const double w = glm::dot(e1, e1) * glm::dot(e2, e2);
            if (w > 0.0) sum[idx[k]] += glm::cross(e1, e2) / w;
        }
    }
    mesh.normals.resize(mesh.positions.size());
    for (size_t v = 0; v < sum.size(); ++v) {
        const double len = glm::length(sum[v]);
        mesh.normals[v] = len > 0.0 ? glm::vec3(sum[v] / len) : glm::vec3(0.0f, 1.0f, 0.0f);
    }
}

// ---------------------------------------------------------------------------------
// Topology
// ---------------------------------------------------------------------------------

namespace {

// Representative vertex for every vertex: the first vertex with a bit-identical
// position (-0 and +0 treated alike). Deterministic (depends only on the input order).
std::vector<uint32_t> weldMap(const std::vector<glm::vec3>& positions) {
    struct Key {
        std::array<uint32_t, 3> bits;
        uint32_t index;
    };
    std::vector<Key> keys(positions.size());
    for (size_t i = 0; i < positions.size(); ++i) {
        for (int a = 0; a < 3; ++a) {
            const float c = positions[i][a] + 0.0f;  // turns -0 into +0
            std::memcpy(&keys[i].bits[a], &c, sizeof(float));
        }
        keys[i].index = uint32_t(i);
    }
    std::sort(keys.begin(), keys.end(), [](const Key& a, const Key& b) {
        return a.bits != b.bits ? a.bits < b.bits : a.index < b.index;
    });
    std::vector<uint32_t> rep(positions.size());
    for (size_t i = 0; i < keys.size();) {
        size_t j = i;
        while (j < keys.size() && keys[j].bits == keys[i].bits) rep[keys[j++].index] = keys[i].index;
        i = j;
    }
    return rep;
}

}  // namespace

MeshTopology analyseTopology(const TriangleMesh& mesh, bool weldCoincident) {
    MeshTopology topo;
    topo.faces = mesh.triangles.size();
    std::vector<uint32_t> rep;
    if (weldCoincident) {
        rep = weldMap(mesh.positions);
    } else {
        rep.resize(mesh.positions.size());
        for (size_t i = 0; i < rep.size(); ++i) rep[i] = uint32_t(i);
    }

    std::vector<char> used(mesh.positions.size(), 0);
    // Directed edges as (undirected key << 1 | direction bit).
    std::vector<std::pair<uint64_t, uint8_t>> edges;
    edges.reserve(mesh.triangles.size() * 3);
    for (const auto& t : mesh.triangles) {
        const uint32_t v[3] = {rep[t.x], rep[t.y], rep[t.z]};
        for (int k = 0; k < 3; ++k) {
            used[v[k]] = 1;
            const uint32_t a = v[k], b = v[(k + 1) % 3];
            if (a == b) continue;
            const uint64_t key = (uint64_t(std::min(a, b)) << 32) | std::max(a, b);
            edges.emplace_back(key, uint8_t(a < b ? 0 : 1));
        }
    }
    topo.vertices = size_t(std::count(used.begin(), used.end(), char(1)));
    std::sort(edges.begin(), edges.end());
    for (size_t i = 0; i < edges.size();) {
        size_t j = i;
        while (j < edges.size() && edges[j].first == edges[i].first) ++j;
        const size_t n = j - i;
        ++topo.edges;
        if (n == 1) ++topo.boundaryEdges;
        else if (n > 2) ++topo.nonManifoldEdges;
        else if (edges[i].second == edges[i + 1].second) ++topo.inconsistentEdges;
        i = j;
    }
    return topo;
}

// ---------------------------------------------------------------------------------
// Scale, centre, fingerprint
// ---------------------------------------------------------------------------------

double scaleToPhysical(TriangleMesh& mesh, const MeshScale& scale) {
    if (scale.sizeMm.has_value() == scale.mmPerUnit.has_value())
        throw Error("mesh scale", "give exactly one of --size-mm and --mm-per-unit");
    double factor = 0.0;
    if (scale.sizeMm) {
        const double s = *scale.sizeMm;
        if (!std::isfinite(s) || !(s > 0.0))
            throw Error("--size-mm", "must be a positive finite number of millimetres");
        const double diag = glm::length(glm::dvec3(bounds(mesh).size()));
        if (!(diag > 0.0))
            throw Error("--size-mm", "the mesh's bounding box has zero diagonal; cannot scale it to a size");
        factor = s / diag;
    } else {
        factor = *scale.mmPerUnit;
        if (!std::isfinite(factor) || !(factor > 0.0))
            throw Error("--mm-per-unit", "must be a positive finite number of millimetres");
    }
    for (auto& p : mesh.positions) p = glm::vec3(glm::dvec3(p) * factor);
    return factor;
}

glm::vec3 centreAtOrigin(TriangleMesh& mesh) {
    const glm::vec3 offset = -bounds(mesh).centre();
    for (auto& p : mesh.positions) p += offset;
    return offset;
}

uint64_t meshFingerprint(const TriangleMesh& mesh) {
    uint64_t hash = 14695981039346656037ull;
    auto byte = [&](uint8_t b) {
        hash ^= b;
        hash *= 1099511628211ull;
    };
    auto u64 = [&](uint64_t v) {
        for (int i = 0; i < 8; ++i) byte(uint8_t(v >> (8 * i)));
    };
    auto u32 = [&](uint32_t v) {
        for (int i = 0; i < 4; ++i) byte(uint8_t(v >> (8 * i)));
    };
    u64(mesh.positions.size());
    u64(mesh.triangles.size());
    for (const auto& p : mesh.positions)
        for (int a = 0; a < 3; ++a) {
            uint32_t bits = 0;
            std::memcpy(&bits, &p[a], sizeof bits);
            u32(bits);
        }
    for (const auto& t : mesh.triangles)
        for (int k = 0; k < 3; ++k) u32(t[k]);
    return hash;
}
namespace {

// 30-bit Morton code of a point quantised to 1024^3 cells of the box [lo, lo + 1023 / scale].
uint32_t morton3(const glm::vec3& p, const glm::vec3& lo, const glm::vec3& scale) {
    auto spread = [](uint32_t v) {  // 10 bits -> every third bit
        v &= 0x3ffu;
        v = (v | (v << 16)) & 0x030000ffu;
        v = (v | (v << 8)) & 0x0300f00fu;
        v = (v | (v << 4)) & 0x030c30c3u;
        v = (v | (v << 2)) & 0x09249249u;
        return v;
    };
    const glm::vec3 q = glm::clamp((p - lo) * scale, glm::vec3(0.0f), glm::vec3(1023.0f));
    return (spread(uint32_t(q.x)) << 2) | (spread(uint32_t(q.y)) << 1) | spread(uint32_t(q.z));
}

}  // namespace

std::vector<uint32_t> mortonOrder(std::span<const glm::vec3> points, const std::string& subject) {
    std::vector<uint32_t> order(points.size());
    std::iota(order.begin(), order.end(), 0u);
    if (points.empty()) return order;
    glm::vec3 lo(std::numeric_limits<float>::max());
    glm::vec3 hi(std::numeric_limits<float>::lowest());
    for (const glm::vec3& v : points) {
        if (!std::isfinite(v.x) || !std::isfinite(v.y) || !std::isfinite(v.z))
            throw Error(subject, "point " + std::to_string(&v - points.data()) + " has a non-finite position");
        lo = glm::min(lo, v);
        hi = glm::max(hi, v);
    }
    const glm::vec3 extent = hi - lo;
    const float largest = std::max(extent.x, std::max(extent.y, extent.z));
    const glm::vec3 scale(largest > 0.0f ? 1023.0f / largest : 0.0f);
    std::vector<uint32_t> code(points.size());
    for (size_t v = 0; v < points.size(); ++v) code[v] = morton3(points[v], lo, scale);
    std::stable_sort(order.begin(), order.end(), [&code](uint32_t a, uint32_t b) { return code[a] < code[b]; });
    return order;
}

}  // namespace prt
