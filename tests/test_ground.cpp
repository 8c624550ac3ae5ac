// The ground plane's geometry (common/ground.h).

#include <gtest/gtest.h>

#include "common/error.h"
#include "common/ground.h"
#include "common/mesh.h"
#include "common/raytrace.h"
#include "common/shapes.h"

namespace prt {
namespace {

TEST(Ground, PlaneUnderTheObjectIsBelowItsLowestPointAndCentredUnderIt) {
    TriangleMesh sphere = makeIcosphere(2, 10.0f);
    for (glm::vec3& p : sphere.positions) p += glm::vec3(3.0f, 7.0f, -2.0f);
    const Bounds box = bounds(sphere);
    GroundSettings s;
    s.halfExtentPerDiagonal = 2.0;
    s.cells = 8;
    const GroundPlane plane = groundPlaneUnder(box, s);
    EXPECT_NEAR(plane.height, box.lo.y - kGroundGap * box.diagonal(), 1e-9);
    EXPECT_LT(plane.height, box.lo.y);
    EXPECT_NEAR(plane.centre.x, 3.0, 1e-5);
    EXPECT_NEAR(plane.centre.y, -2.0, 1e-5);
    EXPECT_NEAR(plane.halfExtent, 2.0 * box.diagonal(), 1e-9);
}

TEST(Ground, MeshCoversTheSquareFacingUp) {
    const GroundPlane plane{-1.5, {2.0, -3.0}, 4.0, 5};
    const TriangleMesh mesh = groundMesh(plane);
    ASSERT_EQ(mesh.vertexCount(), 36u);
    ASSERT_EQ(mesh.triangleCount(), 50u);
    double area = 0.0;
    for (const glm::uvec3& t : mesh.triangles) {
        const glm::dvec3 a = mesh.positions[t.x], b = mesh.positions[t.y], c = mesh.positions[t.z];
        const glm::dvec3 n = glm::cross(b - a, c - a);
        EXPECT_GT(n.y, 0.0) << "every triangle faces +Y";
        area += 0.5 * glm::length(n);
    }
    EXPECT_NEAR(area, 64.0, 1e-9);  // (2 x 4)^2
    const Bounds box = bounds(mesh);
    EXPECT_FLOAT_EQ(box.lo.x, -2.0f);
    EXPECT_FLOAT_EQ(box.hi.x, 6.0f);
    EXPECT_FLOAT_EQ(box.lo.z, -7.0f);
    EXPECT_FLOAT_EQ(box.hi.z, 1.0f);
    EXPECT_FLOAT_EQ(box.lo.y, -1.5f);
    EXPECT_FLOAT_EQ(box.hi.y, -1.5f);
    for (const glm::vec3& n : mesh.normals) EXPECT_EQ(n, glm::vec3(0, 1, 0));
}

TEST(Ground, TextRoundTripIsExact) {
    const GroundPlane plane{-0.123456789012345678, {1.0 / 3.0, -2.0 / 7.0}, 45.000000000000007, 128};
    EXPECT_EQ(parseGroundPlane(formatGroundPlane(plane), "test"), plane);
    EXPECT_EQ(groundMesh(parseGroundPlane(formatGroundPlane(plane), "test")).positions, groundMesh(plane).positions);
}

TEST(Ground, BadTextAndSettingsAreRefused) {
    EXPECT_THROW(parseGroundPlane("1,2,3,4", "f"), Error);
    EXPECT_THROW(parseGroundPlane("1,2,3,4,5,6", "f"), Error);
    EXPECT_THROW(parseGroundPlane("1,2,x,4,5", "f"), Error);
    EXPECT_THROW(parseGroundPlane("1,2,3,-4,5", "f"), Error);
    EXPECT_THROW(parseGroundPlane("1,2,3,4,0", "f"), Error);
    EXPECT_THROW(parseGroundPlane("1,2,3,4,2.5", "f"), Error);
    EXPECT_THROW(parseGroundPlane("1,2,inf,4,5", "f"), Error);
    GroundSettings s;
    s.cells = 0;
    EXPECT_THROW(validateGroundSettings(s), Error);
    s = {};
    s.halfExtentPerDiagonal = 0.0;
    EXPECT_THROW(validateGroundSettings(s), Error);
    s = {};
    s.albedo = {0.5, 1.1, 0.5};
    EXPECT_THROW(validateGroundSettings(s), Error);
    EXPECT_NO_THROW(validateGroundSettings(GroundSettings{}));
}

TEST(Ground, CombinedMeshKeepsTheObjectFirstAndTellsTheGroundsTriangles) {
    TriangleMesh object = makeIcosphere(1, 1.0f);
    GroundSettings s;
    s.cells = 3;
    const GroundPlane plane = groundPlaneUnder(bounds(object), s);
    const TriangleMesh ground = groundMesh(plane);
    const TriangleMesh all = withGround(object, ground);
    ASSERT_EQ(all.vertexCount(), object.vertexCount() + ground.vertexCount());
    ASSERT_EQ(all.triangleCount(), object.triangleCount() + ground.triangleCount());
    for (size_t t = 0; t < object.triangleCount(); ++t) EXPECT_EQ(all.triangles[t], object.triangles[t]);
    // A ray straight down from above the sphere hits the sphere; one beside it, the ground.
    const RayScene scene(all);
    const Hit top = scene.intersect({0, 5, 0}, {0, -1, 0}, 0.0f, 100.0f);
    ASSERT_TRUE(top.hit);
    EXPECT_FALSE(isGroundTriangle(top.triangle, object.triangleCount()));
    const Hit beside = scene.intersect({2.5f, 5, 0.3f}, {0, -1, 0}, 0.0f, 100.0f);
    ASSERT_TRUE(beside.hit);
    EXPECT_TRUE(isGroundTriangle(beside.triangle, object.triangleCount()));
    EXPECT_NEAR(5.0 - beside.t, plane.height, 1e-5);
    EXPECT_EQ(groundTransportPath("out/bunny.prt"), "out/bunny.ground.prt");
    EXPECT_EQ(groundTransportPath("x"), "x.ground.prt");
    EXPECT_EQ(groundTransportPath("out/Bunny.PRT"), "out/Bunny.ground.prt");
    EXPECT_EQ(groundTransportPath("out/bunny.v1"), "out/bunny.v1.ground.prt");
    EXPECT_NE(groundTransportPath("out/bunny.v1"), groundTransportPath("out/bunny.v2"));
}

}  // namespace
}  // namespace prt
