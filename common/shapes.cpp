#include "common/shapes.h"

#include "common/error.h"

#include <array>
#include <cmath>
#include <numbers>
#include <string>
#include <unordered_map>

namespace prt {

namespace {

glm::vec3 toFloat(const glm::dvec3& v) { return glm::vec3(v); }

// Orients a triangle of a convex, origin-centred solid so that its normal points away
// from the origin.
glm::uvec3 orientOutward(const std::vector<glm::dvec3>& p, glm::uvec3 t) {
    const glm::dvec3 n = glm::cross(p[t.y] - p[t.x], p[t.z] - p[t.x]);
    const glm::dvec3 c = p[t.x] + p[t.y] + p[t.z];
    if (glm::dot(n, c) < 0.0) std::swap(t.y, t.z);
    return t;
}

}  // namespace

TriangleMesh makeIcosphere(int subdivisions, float radius) {
    if (subdivisions < 0 || subdivisions > 10)
        throw Error("makeIcosphere", "subdivisions must be in 0..10, got " +
                                         std::to_string(subdivisions));
    if (!(radius > 0.0f) || !std::isfinite(radius))
        throw Error("makeIcosphere", "radius must be positive and finite");

    // The 12 vertices of an icosahedron: cyclic permutations of (0, +-1, +-phi).
    const double phi = (1.0 + std::sqrt(5.0)) / 2.0;
    std::vector<glm::dvec3> p;
    for (double a : {-1.0, 1.0})
        for (double b : {-phi, phi}) {
            p.emplace_back(0.0, a, b);
            p.emplace_back(a, b, 0.0);
            p.emplace_back(b, 0.0, a);
        }
    // Faces: the triples of mutually adjacent vertices (edge length 2).
    std::vector<glm::uvec3> tris;
    auto adjacent = [&](size_t i, size_t j) {
        return std::abs(glm::length(p[i] - p[j]) - 2.0) < 1e-9;
    };
    for (size_t i = 0; i < p.size(); ++i)
        for (size_t j = i + 1; j < p.size(); ++j)
            for (size_t k = j + 1; k < p.size(); ++k)
                if (adjacent(i, j) && adjacent(j, k) && adjacent(i, k))
                    tris.push_back(orientOutward(
                        p, glm::uvec3(uint32_t(i), uint32_t(j), uint32_t(k))));
    for (auto& v : p) v = glm::normalize(v);

    // Each subdivision splits every triangle into four at its edge midpoints, pushed
    // onto the unit sphere. Midpoints are shared through an edge -> vertex cache.
    for (int level = 0; level < subdivisions; ++level) {
        std::unordered_map<uint64_t, uint32_t> midpoint;
        midpoint.reserve(tris.size() * 2);
        auto mid = [&](uint32_t a, uint32_t b) {
            const uint64_t key = (uint64_t(std::min(a, b)) << 32) | std::max(a, b);
            auto it = midpoint.find(key);
            if (it != midpoint.end()) return it->second;
            const uint32_t index = uint32_t(p.size());
            p.push_back(glm::normalize(p[a] + p[b]));
            midpoint.emplace(key, index);
            return index;
        };
        std::vector<glm::uvec3> next;
        next.reserve(tris.size() * 4);
        for (const auto& t : tris) {
            const uint32_t ab = mid(t.x, t.y), bc = mid(t.y, t.z), ca = mid(t.z, t.x);
            next.emplace_back(t.x, ab, ca);
            next.emplace_back(t.y, bc, ab);
            next.emplace_back(t.z, ca, bc);
            next.emplace_back(ab, bc, ca);
        }
        tris.swap(next);
    }

    TriangleMesh mesh;
    mesh.positions.reserve(p.size());
    mesh.normals.reserve(p.size());
    for (const auto& v : p) {
        mesh.positions.push_back(toFloat(v * double(radius)));
        mesh.normals.push_back(toFloat(v));
    }
    mesh.triangles = std::move(tris);
    return mesh;
}

TriangleMesh makeBox(glm::vec3 size, glm::ivec3 segments) {
    for (int a = 0; a < 3; ++a) {
        if (!(size[a] > 0.0f) || !std::isfinite(size[a]))
            throw Error("makeBox", "size components must be positive and finite");
        if (segments[a] < 1 || segments[a] > 4096)
            throw Error("makeBox", "segments must be in 1..4096");
    }
    const glm::vec3 lo = -0.5f * size;
    // Grid coordinate i of axis a; the same expression for every face, so positions
    // on shared edges are bit-identical.
    auto coord = [&](int a, int i) {
        if (i == segments[a]) return lo[a] + size[a];
        return lo[a] + size[a] * (float(i) / float(segments[a]));
    };

    TriangleMesh mesh;
    // Per face: normal axis, side, and tangent axes (t1, t2) with t1 x t2 along the
    // outward normal, so cells counter-clockwise in (t1, t2) face outward.
    struct Face { int axis; int side; int t1; int t2; };
    const std::array<Face, 6> faces{{
        {0, +1, 1, 2}, {0, -1, 2, 1},
        {1, +1, 2, 0}, {1, -1, 0, 2},
        {2, +1, 0, 1}, {2, -1, 1, 0},
    }};
    for (const Face& f : faces) {
        const uint32_t base = uint32_t(mesh.positions.size());
        const int n1 = segments[f.t1], n2 = segments[f.t2];
        glm::vec3 normal(0.0f);
        normal[f.axis] = float(f.side);
        const float fixed = f.side > 0 ? coord(f.axis, segments[f.axis]) : coord(f.axis, 0);
        for (int j = 0; j <= n2; ++j)
            for (int i = 0; i <= n1; ++i) {
                glm::vec3 q;
                q[f.axis] = fixed;
                q[f.t1] = coord(f.t1, i);
                q[f.t2] = coord(f.t2, j);
                mesh.positions.push_back(q);
                mesh.normals.push_back(normal);
            }
        auto at = [&](int i, int j) { return base + uint32_t(j * (n1 + 1) + i); };
        for (int j = 0; j < n2; ++j)
            for (int i = 0; i < n1; ++i) {
                mesh.triangles.emplace_back(at(i, j), at(i + 1, j), at(i + 1, j + 1));
                mesh.triangles.emplace_back(at(i, j), at(i + 1, j + 1), at(i, j + 1));
            }
    }
    return mesh;
}

TriangleMesh makeSlab(float width, float depth, float thickness, int cells) {
    if (cells < 1 || cells > 4096) throw Error("makeSlab", "cells must be in 1..4096");
    return makeBox(glm::vec3(width, thickness, depth), glm::ivec3(cells, 1, cells));
}

TriangleMesh makeTorus(float R, float r, int nu, int nv) {
    if (!(r > 0.0f) || !(R > r) || !std::isfinite(R))
        throw Error("makeTorus", "radii must satisfy 0 < r < R (finite)");
    if (nu < 3 || nv < 3 || nu > 65536 || nv > 65536 || size_t(nu) * size_t(nv) > (1u << 30))
        throw Error("makeTorus", "nu and nv must be at least 3 (and not huge)");

    const double twoPi = 2.0 * std::numbers::pi;
    TriangleMesh mesh;
    mesh.positions.reserve(size_t(nu) * nv);
    mesh.normals.reserve(size_t(nu) * nv);
    // Vertex (i, j): angle u = 2 pi i / nu around the Y axis, v = 2 pi j / nv around
    // the tube. Outward normal (cos v cos u, sin v, cos v sin u).
    for (int i = 0; i < nu; ++i) {
        const double u = twoPi * i / nu;
        for (int j = 0; j < nv; ++j) {
            const double v = twoPi * j / nv;
            const glm::dvec3 n(std::cos(v) * std::cos(u), std::sin(v), std::cos(v) * std::sin(u));
            const glm::dvec3 ring(double(R) * std::cos(u), 0.0, double(R) * std::sin(u));
            mesh.positions.push_back(toFloat(ring + double(r) * n));
            mesh.normals.push_back(toFloat(n));
        }
    }
    auto at = [&](int i, int j) { return uint32_t((i % nu) * nv + (j % nv)); };
    mesh.triangles.reserve(size_t(2) * nu * nv);
    // d/du x d/dv points inward for this parameterisation, so cells are walked
    // counter-clockwise in (v, u).
    for (int i = 0; i < nu; ++i)
        for (int j = 0; j < nv; ++j) {
            const uint32_t a = at(i, j), b = at(i, j + 1), c = at(i + 1, j + 1), d = at(i + 1, j);
            mesh.triangles.emplace_back(a, b, c);
            mesh.triangles.emplace_back(a, c, d);
        }
    return mesh;
}

}  // namespace prt
