// Tests of common/mesh (geometry, bounding sphere, topology, scale, fingerprint) and
// common/shapes (the generated test meshes). File formats: test_mesh_io.cpp.
#include "common/error.h"
#include "common/mesh.h"
#include "common/shapes.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <numbers>
#include <string>

using prt::TriangleMesh;

namespace {

constexpr double kPi = std::numbers::pi;

// Identical vertex order, positions and triangles.
void expectIdentical(const TriangleMesh& a, const TriangleMesh& b) {
    ASSERT_EQ(a.positions.size(), b.positions.size());
    for (size_t v = 0; v < a.positions.size(); ++v) ASSERT_EQ(a.positions[v], b.positions[v]) << v;
    ASSERT_EQ(a.triangles.size(), b.triangles.size());
    for (size_t f = 0; f < a.triangles.size(); ++f) ASSERT_EQ(a.triangles[f], b.triangles[f]) << f;
}

}  // namespace

// ---------------------------------------------------------------------------------
// Generated shapes
// ---------------------------------------------------------------------------------

TEST(Icosphere, VertexAndFaceCounts) {
    size_t v = 12, f = 20;
    for (int level = 0; level <= 4; ++level) {
        const TriangleMesh m = prt::makeIcosphere(level, 1.0f);
        EXPECT_EQ(m.positions.size(), v) << level;
        EXPECT_EQ(m.normals.size(), v) << level;
        EXPECT_EQ(m.triangles.size(), f) << level;
        v = 4 * v - 6;  // 10 * 4^n + 2
        f *= 4;
    }
}

TEST(Icosphere, AllVerticesAtRadius) {
    const float radius = 2.5f;
    const TriangleMesh m = prt::makeIcosphere(3, radius);
    for (const auto& p : m.positions) EXPECT_NEAR(glm::length(p), radius, 1e-5f * radius);
}

TEST(Icosphere, AreaConvergesToSphere) {
    const double radius = 1.5, exact = 4.0 * kPi * radius * radius;
    double previous = 1e9;
    for (int level = 0; level <= 5; ++level) {
        const double area = prt::totalArea(prt::makeIcosphere(level, float(radius)));
        const double error = std::abs(area - exact) / exact;
        EXPECT_LT(area, exact);  // inscribed polyhedron
        EXPECT_LT(error, previous) << level;
        previous = error;
    }
    EXPECT_LT(previous, 2e-3);
}

TEST(Icosphere, NormalsRadialAndOutward) {
    for (int level = 0; level <= 4; ++level) {
        TriangleMesh m = prt::makeIcosphere(level, 3.0f);
        // Generator normals are exact.
        for (size_t v = 0; v < m.positions.size(); ++v) {
            const glm::vec3 radial = glm::normalize(m.positions[v]);
            EXPECT_LT(glm::length(m.normals[v] - radial), 1e-6f);
        }
        // Computed normals agree to 1e-3 and point outward (Max's weights are exact on
        // a sphere; area weighting would be off by 2e-2 at level 2).
        prt::computeVertexNormals(m);
        for (size_t v = 0; v < m.positions.size(); ++v) {
            const glm::vec3 radial = glm::normalize(m.positions[v]);
            EXPECT_NEAR(glm::length(m.normals[v]), 1.0f, 1e-6f);
            EXPECT_LT(glm::length(m.normals[v] - radial), 1e-3f) << "level " << level << " vertex " << v;
        }
        for (size_t f = 0; f < m.triangles.size(); ++f) {
            const glm::uvec3 t = m.triangles[f];
            const glm::vec3 centroid = (m.positions[t.x] + m.positions[t.y] + m.positions[t.z]) / 3.0f;
            EXPECT_GT(glm::dot(prt::faceNormal(m, f), centroid), 0.0f) << f;
        }
    }
}

TEST(Icosphere, ClosedGenusZero) {
    for (int level = 0; level <= 3; ++level) {
        const TriangleMesh m = prt::makeIcosphere(level, 1.0f);
        for (bool weld : {false, true}) {
            const prt::MeshTopology t = prt::analyseTopology(m, weld);
            EXPECT_EQ(t.eulerCharacteristic(), 2);
            EXPECT_EQ(t.boundaryEdges, 0u);
            EXPECT_EQ(t.nonManifoldEdges, 0u);
            EXPECT_EQ(t.inconsistentEdges, 0u);
            EXPECT_EQ(t.edges, m.triangles.size() * 3 / 2);
        }
        EXPECT_GT(prt::signedVolume(m), 0.0);
    }
    const TriangleMesh m = prt::makeIcosphere(5, 1.0f);
    EXPECT_NEAR(prt::signedVolume(m), 4.0 / 3.0 * kPi, 5e-3 * 4.0 / 3.0 * kPi);
}

TEST(Icosphere, RejectsBadParameters) {
    EXPECT_THROW(prt::makeIcosphere(-1, 1.0f), prt::Error);
    EXPECT_THROW(prt::makeIcosphere(11, 1.0f), prt::Error);
    EXPECT_THROW(prt::makeIcosphere(1, 0.0f), prt::Error);
    EXPECT_THROW(prt::makeIcosphere(1, std::nanf("")), prt::Error);
}

TEST(Box, ClosedAreaVolumeFlatNormals) {
    const glm::vec3 size(1.0f, 2.0f, 3.0f);
    for (glm::ivec3 seg : {glm::ivec3(1), glm::ivec3(3, 2, 5)}) {
        TriangleMesh m = prt::makeBox(size, seg);
        if (seg == glm::ivec3(1)) {
            EXPECT_EQ(m.positions.size(), 24u);
            EXPECT_EQ(m.triangles.size(), 12u);
        }
        EXPECT_NEAR(prt::totalArea(m), 2.0 * (1 * 2 + 2 * 3 + 3 * 1), 1e-5);
        EXPECT_NEAR(prt::signedVolume(m), 6.0, 1e-5);
        const prt::MeshTopology welded = prt::analyseTopology(m, true);
        EXPECT_EQ(welded.boundaryEdges, 0u);
        EXPECT_EQ(welded.nonManifoldEdges, 0u);
        EXPECT_EQ(welded.inconsistentEdges, 0u);
        EXPECT_EQ(welded.eulerCharacteristic(), 2);
        // Faces own their vertices: without welding every face is an open patch.
        EXPECT_GT(prt::analyseTopology(m, false).boundaryEdges, 0u);
        const prt::Bounds b = prt::bounds(m);
        EXPECT_EQ(b.lo, -0.5f * size);
        EXPECT_EQ(b.hi, 0.5f * size);
        // Stored normals are flat, outward, and equal to the computed ones.
        const std::vector<glm::vec3> stored = m.normals;
        prt::computeVertexNormals(m);
        for (size_t v = 0; v < m.positions.size(); ++v) {
            EXPECT_LT(glm::length(stored[v] - m.normals[v]), 1e-6f);
            EXPECT_GT(glm::dot(stored[v], m.positions[v]), 0.0f);
        }
    }
    EXPECT_THROW(prt::makeBox(glm::vec3(1, 0, 1)), prt::Error);
    EXPECT_THROW(prt::makeBox(glm::vec3(1), glm::ivec3(1, 0, 1)), prt::Error);
}

TEST(Box, SlabHasGridTop) {
    const TriangleMesh m = prt::makeSlab(10.0f, 8.0f, 1.0f, 4);
    const prt::Bounds b = prt::bounds(m);
    EXPECT_EQ(b.size(), glm::vec3(10.0f, 1.0f, 8.0f));
    size_t top = 0;
    for (size_t f = 0; f < m.triangles.size(); ++f)
        if (prt::faceNormal(m, f).y > 0.99f) ++top;
    EXPECT_EQ(top, 2u * 4 * 4);
    EXPECT_NEAR(prt::signedVolume(m), 80.0, 1e-4);
    EXPECT_TRUE(prt::analyseTopology(m, true).closed());
}

TEST(Torus, ClosedAreaAndVolumeConverge) {
    const double R = 2.0, r = 0.5;
    const double exactArea = 4.0 * kPi * kPi * R * r, exactVolume = 2.0 * kPi * kPi * R * r * r;
    double previous = 1e9, previousVolume = 1e9;
    for (int n : {8, 16, 32, 64, 128}) {
        const TriangleMesh m = prt::makeTorus(float(R), float(r), 2 * n, n);
        EXPECT_EQ(m.positions.size(), size_t(2 * n * n));
        EXPECT_EQ(m.triangles.size(), size_t(4 * n * n));
        const double error = std::abs(prt::totalArea(m) - exactArea) / exactArea;
        EXPECT_LT(error, previous) << n;
        previous = error;
        const double volumeError = std::abs(prt::signedVolume(m) - exactVolume) / exactVolume;
        EXPECT_GT(prt::signedVolume(m), 0.0);
        EXPECT_LT(volumeError, previousVolume) << n;
        previousVolume = volumeError;
        const prt::MeshTopology t = prt::analyseTopology(m, false);
        EXPECT_EQ(t.boundaryEdges, 0u);
        EXPECT_EQ(t.nonManifoldEdges, 0u);
        EXPECT_EQ(t.inconsistentEdges, 0u);
        EXPECT_EQ(t.eulerCharacteristic(), 0);
    }
    EXPECT_LT(previous, 1e-3);
    EXPECT_LT(previousVolume, 1e-3);
}

TEST(Torus, NormalsOutward) {
    const TriangleMesh m = prt::makeTorus(3.0f, 1.0f, 24, 12);
    for (size_t v = 0; v < m.positions.size(); ++v) {
        const glm::vec3 p = m.positions[v];
        const glm::vec3 ring = 3.0f * glm::normalize(glm::vec3(p.x, 0.0f, p.z));
        EXPECT_LT(glm::length(m.normals[v] - glm::normalize(p - ring)), 1e-5f);
    }
    for (size_t f = 0; f < m.triangles.size(); ++f) {
        const glm::uvec3 t = m.triangles[f];
        const glm::vec3 c = (m.positions[t.x] + m.positions[t.y] + m.positions[t.z]) / 3.0f;
        const glm::vec3 ring = 3.0f * glm::normalize(glm::vec3(c.x, 0.0f, c.z));
        EXPECT_GT(glm::dot(prt::faceNormal(m, f), c - ring), 0.0f) << f;
    }
    EXPECT_THROW(prt::makeTorus(1.0f, 1.0f, 8, 8), prt::Error);
    EXPECT_THROW(prt::makeTorus(2.0f, 1.0f, 2, 8), prt::Error);
}

// ---------------------------------------------------------------------------------
// Geometry helpers
// ---------------------------------------------------------------------------------

TEST(Geometry, FaceAreaNormalBounds) {
    TriangleMesh m;
    m.positions = {{0, 0, 0}, {2, 0, 0}, {0, 3, 0}, {1, 1, 1}};
    m.triangles = {{0, 1, 2}, {0, 2, 1}};
    EXPECT_FLOAT_EQ(prt::faceArea(m, 0), 3.0f);
    EXPECT_EQ(prt::faceNormal(m, 0), glm::vec3(0, 0, 1));
    EXPECT_EQ(prt::faceNormal(m, 1), glm::vec3(0, 0, -1));
    EXPECT_EQ(prt::faceAreas(m), (std::vector<float>{3.0f, 3.0f}));
    EXPECT_DOUBLE_EQ(prt::totalArea(m), 6.0);
    const prt::Bounds b = prt::bounds(m);
    EXPECT_EQ(b.lo, glm::vec3(0, 0, 0));
    EXPECT_EQ(b.hi, glm::vec3(2, 3, 1));
    EXPECT_FLOAT_EQ(b.diagonal(), std::sqrt(14.0f));
    EXPECT_EQ(prt::bounds(TriangleMesh{}).diagonal(), 0.0f);
    // A zero-area triangle has a zero normal; an isolated vertex gets +Y.
    m.triangles = {{0, 1, 2}};
    m.positions[2] = {1, 0, 0};
    EXPECT_EQ(prt::faceNormal(m, 0), glm::vec3(0.0f));
    prt::computeVertexNormals(m);
    EXPECT_EQ(m.normals[3], glm::vec3(0, 1, 0));
}

TEST(Geometry, NormalsUseMaxWeights) {
    // Vertex 0 is shared by a big triangle in the z = 0 plane and a small one in x = 0.
    TriangleMesh m;
    m.positions = {{0, 0, 0}, {3, 0, 0}, {0, 3, 0}, {0, 0, 1}, {0, 1, 0}};
    m.triangles = {{0, 1, 2}, {0, 4, 3}};
    prt::computeVertexNormals(m);
    // At vertex 0: cross(e1, e2) / (|e1|^2 |e2|^2) = (0, 0, 9) / 81 and (1, 0, 0) / 1.
    // (Area weighting would give normalize(1, 0, 9).)
    const glm::vec3 expected = glm::normalize(glm::vec3(1.0f, 0.0f, 1.0f / 9.0f));
    EXPECT_LT(glm::length(m.normals[0] - expected), 1e-6f);
}

TEST(Geometry, TopologyCountsOrientationAndNonManifold) {
    TriangleMesh m = prt::makeIcosphere(0, 1.0f);
    std::swap(m.triangles[0].y, m.triangles[0].z);  // flip one face
    EXPECT_EQ(prt::analyseTopology(m).inconsistentEdges, 3u);
    TriangleMesh fin;
    fin.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}};
    fin.triangles = {{0, 1, 2}, {1, 0, 3}, {0, 1, 4}};
    const prt::MeshTopology t = prt::analyseTopology(fin);
    EXPECT_EQ(t.nonManifoldEdges, 1u);
    EXPECT_EQ(t.boundaryEdges, 6u);
    EXPECT_EQ(t.edges, 7u);
}

TEST(Geometry, BoundingSphereOfUnitBox) {
    // The 8 corners of [0, 1]^3: centre 0.5, radius half the space diagonal.
    TriangleMesh m = prt::makeBox(glm::vec3(1.0f));
    for (auto& p : m.positions) p += glm::vec3(0.5f);
    const prt::BoundingSphere s = prt::boundingSphere(m);
    EXPECT_EQ(s.centre, glm::dvec3(0.5));
    EXPECT_DOUBLE_EQ(s.radius, std::sqrt(3.0) / 2.0);
}

TEST(Geometry, BoundingSphereIsBoxCentreAndFarthestVertex) {
    // Not the minimal sphere: the box centre, and the farthest vertex from it, in
    // double precision (as prt-relight and prt-reference frame the object).
    TriangleMesh m;
    m.positions = {{0, 0, 0}, {4, 0, 0}, {0, 2, 0}, {0.1f, 0.3f, 1}};
    m.triangles = {{0, 1, 2}, {0, 1, 3}};
    const prt::BoundingSphere s = prt::boundingSphere(m);
    const glm::dvec3 centre(prt::bounds(m).centre());
    EXPECT_EQ(s.centre, centre);
    EXPECT_EQ(s.centre, glm::dvec3(2.0, 1.0, 0.5));
    double r2 = 0;
    for (const glm::vec3& p : m.positions) {
        const glm::dvec3 d = glm::dvec3(p) - centre;
        r2 = std::max(r2, glm::dot(d, d));
    }
    EXPECT_EQ(s.radius, std::sqrt(r2));
    EXPECT_DOUBLE_EQ(s.radius, std::sqrt(4.0 + 1.0 + 0.25));
    // Every vertex is inside; an icosphere's sphere is its own (to float rounding).
    for (const glm::vec3& p : m.positions) EXPECT_LE(glm::length(glm::dvec3(p) - s.centre), s.radius);
    const prt::BoundingSphere ico = prt::boundingSphere(prt::makeIcosphere(3, 2.0f));
    EXPECT_LT(glm::length(ico.centre), 1e-6);
    EXPECT_NEAR(ico.radius, 2.0, 1e-6);
}

TEST(Geometry, BoundingSphereOfEmptyMesh) {
    // Documented: bounds() of an empty mesh is lo = hi = 0, so centre (0, 0, 0), radius 0.
    const prt::BoundingSphere s = prt::boundingSphere(TriangleMesh{});
    EXPECT_EQ(s.centre, glm::dvec3(0.0));
    EXPECT_EQ(s.radius, 0.0);
}

// ---------------------------------------------------------------------------------
// Physical scale, centring, fingerprint
// ---------------------------------------------------------------------------------

TEST(Scale, SizeMmSetsDiagonal) {
    TriangleMesh m = prt::makeTorus(2.0f, 0.5f, 32, 16);
    const glm::vec3 p5 = m.positions[5];
    const std::vector<glm::vec3> normals = m.normals;
    prt::MeshScale s;
    s.sizeMm = 120.0;
    const double factor = prt::scaleToPhysical(m, s);
    EXPECT_NEAR(prt::bounds(m).diagonal(), 120.0f, 120.0f * 1e-6f);
    EXPECT_LT(glm::length(m.positions[5] - p5 * float(factor)), 1e-4f);
    EXPECT_EQ(m.normals, normals);
}

TEST(Scale, MmPerUnitMultiplies) {
    TriangleMesh m = prt::makeBox(glm::vec3(1, 2, 3));
    const TriangleMesh before = m;
    prt::MeshScale s;
    s.mmPerUnit = 25.4;
    EXPECT_DOUBLE_EQ(prt::scaleToPhysical(m, s), 25.4);
    for (size_t v = 0; v < m.positions.size(); ++v)
        EXPECT_EQ(m.positions[v], glm::vec3(glm::dvec3(before.positions[v]) * 25.4));
    EXPECT_NEAR(prt::signedVolume(m), 6.0 * std::pow(25.4, 3), 1e-6 * 6.0 * std::pow(25.4, 3));
}

TEST(Scale, RejectsBadValues) {
    TriangleMesh m = prt::makeIcosphere(0, 1.0f);
    const TriangleMesh before = m;
    auto expectRejected = [&](prt::MeshScale s, const std::string& subject) {
        try {
            prt::scaleToPhysical(m, s);
            ADD_FAILURE() << "accepted";
        } catch (const prt::Error& e) {
            EXPECT_EQ(e.subject(), subject);
        }
        expectIdentical(m, before);
    };
    expectRejected({}, "mesh scale");
    expectRejected({1.0, 1.0}, "mesh scale");
    for (double bad : {0.0, -5.0, std::nan(""), HUGE_VAL}) {
        expectRejected({bad, std::nullopt}, "--size-mm");
        expectRejected({std::nullopt, bad}, "--mm-per-unit");
    }
    TriangleMesh point;
    point.positions = {{1, 1, 1}};
    prt::MeshScale s;
    s.sizeMm = 10.0;
    EXPECT_THROW(prt::scaleToPhysical(point, s), prt::Error);
}

TEST(Scale, CentreAtOrigin) {
    TriangleMesh m = prt::makeBox(glm::vec3(2, 2, 2));
    for (auto& p : m.positions) p += glm::vec3(10, -4, 3);
    const glm::vec3 offset = prt::centreAtOrigin(m);
    EXPECT_EQ(offset, glm::vec3(-10, 4, -3));
    EXPECT_EQ(prt::bounds(m).centre(), glm::vec3(0.0f));
}

TEST(Fingerprint, StableAndSensitive) {
    const TriangleMesh a = prt::makeIcosphere(3, 1.0f);
    const TriangleMesh b = prt::makeIcosphere(3, 1.0f);
    const uint64_t fa = prt::meshFingerprint(a);
    EXPECT_EQ(fa, prt::meshFingerprint(b));

    TriangleMesh moved = a;
    moved.positions[100].x += 1e-6f;
    ASSERT_NE(moved.positions[100].x, a.positions[100].x);
    EXPECT_NE(prt::meshFingerprint(moved), fa);

    TriangleMesh tiny = a;
    tiny.positions[0].z = std::nextafter(tiny.positions[0].z, 2.0f);
    EXPECT_NE(prt::meshFingerprint(tiny), fa);

    TriangleMesh rewired = a;
    std::swap(rewired.triangles[0].x, rewired.triangles[0].y);
    EXPECT_NE(prt::meshFingerprint(rewired), fa);

    TriangleMesh renormal = a;
    renormal.normals[0] = glm::vec3(1, 0, 0);
    EXPECT_EQ(prt::meshFingerprint(renormal), fa);  // normals are not hashed

    // The documented byte stream, hashed independently here: counts (uint64 LE),
    // position bits (uint32 LE), indices (uint32 LE), FNV-1a 64.
    TriangleMesh fixed;
    fixed.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
    fixed.triangles = {{0, 1, 2}};
    std::vector<uint8_t> stream;
    auto put = [&](uint64_t v, int bytes) {
        for (int i = 0; i < bytes; ++i) stream.push_back(uint8_t(v >> (8 * i)));
    };
    put(3, 8);
    put(1, 8);
    for (const auto& p : fixed.positions)
        for (int k = 0; k < 3; ++k) {
            uint32_t bits = 0;
            std::memcpy(&bits, &p[k], 4);
            put(bits, 4);
        }
    for (uint32_t i : {0u, 1u, 2u}) put(i, 4);
    uint64_t h = 0xcbf29ce484222325ull;
    for (uint8_t byte : stream) {
        h ^= byte;
        h *= 0x100000001b3ull;
    }
    EXPECT_EQ(prt::meshFingerprint(fixed), h);
    EXPECT_NE(prt::meshFingerprint(fixed), prt::meshFingerprint(TriangleMesh{}));
}

// mortonOrder: a permutation; on a 2 x 2 x 2 grid given in reverse, the order of the
// Morton codes (x, y, z bits from high to low); a NaN point is an error naming the subject.
TEST(Mesh, MortonOrderFollowsTheCurve) {
    std::vector<glm::vec3> points;
    for (int i = 7; i >= 0; --i) points.emplace_back(float((i >> 2) & 1), float((i >> 1) & 1), float(i & 1));
    const std::vector<uint32_t> order = prt::mortonOrder(points);
    ASSERT_EQ(order.size(), 8u);
    for (int k = 0; k < 8; ++k) {
        const glm::vec3 p = points[order[size_t(k)]];
        EXPECT_EQ(int(p.x) * 4 + int(p.y) * 2 + int(p.z), k);
    }
    EXPECT_TRUE(prt::mortonOrder(std::vector<glm::vec3>{}).empty());
    points[3].y = std::nanf("");
    try {
        prt::mortonOrder(points, "mesh");
        ADD_FAILURE() << "expected an error";
    } catch (const prt::Error& e) {
        EXPECT_NE(std::string(e.what()).find("mesh"), std::string::npos);
        EXPECT_NE(std::string(e.what()).find("point 3"), std::string::npos);
    }
}

