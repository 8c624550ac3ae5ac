#include "relight/render/gbuffer.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <numbers>
#include <string>

#include "common/bssrdf.h"
#include "common/envmap.h"
#include "common/error.h"
#include "common/mesh_io.h"
#include "common/shapes.h"
#include "common/util.h"

using namespace prt;

namespace {

// Radius in pixels of the image of a sphere of radius r whose centre lies on the
// optical axis at distance d: the silhouette cone has half-angle asin(r / d), and the
// image plane at unit distance spans tan(fovY / 2) over height / 2 pixels.
double projectedRadiusPx(double r, double d, const Camera& c) {
    return std::tan(std::asin(r / d)) / std::tan(glm::radians(c.fovY) * 0.5) * c.height * 0.5;
}

}  // namespace

// ---------------------------------------------------------------------------
// G-buffer geometry
// ---------------------------------------------------------------------------

TEST(GBuffer, CoverageIsTheProjectedDiscExplicitCamera) {
    const float r = 10.0f;
    const double d = 60.0;
    TriangleMesh sphere = makeIcosphere(5, r);
    RayScene scene(sphere);
    Camera c;
    c.eye = {0, 0, d};
    c.target = {0, 0, 0};
    c.fovY = 30;
    c.width = 400;
    c.height = 300;
    GBuffer g = traceGBuffer(scene, sphere, c);
    ASSERT_EQ(g.width, 400);
    ASSERT_EQ(g.height, 300);
    ASSERT_EQ(g.pixels.size(), size_t(400 * 300));
    const double rpx = projectedRadiusPx(r, d, c);
    const double expected = kPi * rpx * rpx;
    EXPECT_NEAR(double(g.objectPixels()) / expected, 1.0, 0.02) << "r_px = " << rpx;

    // Silhouette: the image centre is hit, the corners are not; along the horizontal
    // and vertical axes the edge is at r_px.
    const double cx = c.width / 2.0, cy = c.height / 2.0;
    EXPECT_TRUE(g.at(int(cx), int(cy)).hit);
    EXPECT_FALSE(g.at(0, 0).hit);
    EXPECT_FALSE(g.at(c.width - 1, 0).hit);
    EXPECT_FALSE(g.at(0, c.height - 1).hit);
    EXPECT_FALSE(g.at(c.width - 1, c.height - 1).hit);
    EXPECT_TRUE(g.at(int(cx + 0.95 * rpx), int(cy)).hit);
    EXPECT_FALSE(g.at(int(cx + 1.05 * rpx), int(cy)).hit);
    EXPECT_TRUE(g.at(int(cx - 0.95 * rpx), int(cy)).hit);
    EXPECT_FALSE(g.at(int(cx - 1.05 * rpx), int(cy)).hit);
    EXPECT_TRUE(g.at(int(cx), int(cy - 0.95 * rpx)).hit);
    EXPECT_FALSE(g.at(int(cx), int(cy - 1.05 * rpx)).hit);
}

TEST(GBuffer, CoverageIsTheProjectedDiscFrameSphere) {
    const float r = 3.0f;
    const glm::dvec3 centre(1.0, -2.0, 0.5);
    TriangleMesh sphere = makeIcosphere(5, r);
    for (glm::vec3& p : sphere.positions) p += glm::vec3(centre);
    RayScene scene(sphere);
    const double fill = 0.8;
    for (double azimuth : {0.0, 70.0, 200.0}) {
        Camera c = frameSphere(centre, r, azimuth, 20.0, 40.0, 256, 256, fill);
        GBuffer g = traceGBuffer(scene, sphere, c);
        // frameSphere puts the silhouette at fill x the half image height.
        const double rpx = fill * c.height * 0.5;
        EXPECT_NEAR(projectedRadiusPx(r, glm::length(c.eye - centre), c), rpx, 1e-9 * rpx);
        EXPECT_NEAR(double(g.objectPixels()) / (kPi * rpx * rpx), 1.0, 0.02) << "azimuth " << azimuth;
        EXPECT_TRUE(g.at(128, 128).hit);
        EXPECT_FALSE(g.at(0, 0).hit);
        EXPECT_FALSE(g.at(255, 255).hit);
    }
}

TEST(GBuffer, PixelAttributes) {
    const float r = 10.0f;
    TriangleMesh sphere = makeIcosphere(4, r);
    RayScene scene(sphere);
    Camera c;
    c.eye = {0, 0, 50};
    c.target = {0, 0, 0};
    c.width = 101;  // odd: the centre pixel's ray is the optical axis
    c.height = 101;
    GBuffer g = traceGBuffer(scene, sphere, c);

    // Centre pixel: on the axis, at z ~ r, normal facing the camera.
    const GBufferPixel& centre = g.at(50, 50);
    ASSERT_TRUE(centre.hit);
    EXPECT_NEAR(glm::length(centre.rayDirection - glm::vec3(0, 0, -1)), 0.0f, 1e-6f);
    EXPECT_NEAR(glm::length(centre.toViewer - glm::vec3(0, 0, 1)), 0.0f, 1e-6f);
    EXPECT_NEAR(centre.position.x, 0.0f, 1e-4f);
    EXPECT_NEAR(centre.position.y, 0.0f, 1e-4f);
    EXPECT_NEAR(centre.position.z, r, 0.02f * r);  // the inscribed polyhedron is a bit inside
    EXPECT_GT(glm::dot(centre.normal, centre.toViewer), 0.999f);

    size_t hits = 0;
    for (int y = 0; y < g.height; ++y)
        for (int x = 0; x < g.width; ++x) {
            const GBufferPixel& p = g.at(x, y);
            const glm::dvec3 expectedDir = cameraRayDirection(c, x + 0.5, y + 0.5);
            ASSERT_NEAR(glm::length(glm::dvec3(p.rayDirection) - expectedDir), 0.0, 1e-6);
            ASSERT_NEAR(glm::length(p.toViewer + p.rayDirection), 0.0f, 1e-7f);
            if (!p.hit) {
                EXPECT_EQ(p.triangle, kNoTriangle);
                continue;
            }
            ++hits;
            ASSERT_LT(p.triangle, sphere.triangleCount());
            const glm::vec3 b = p.barycentric;
            EXPECT_NEAR(b.x + b.y + b.z, 1.0f, 1e-6f);
            EXPECT_GE(std::min({b.x, b.y, b.z}), -1e-5f);
            // The hit point lies on the ray and on the sphere's polyhedron.
            const glm::dvec3 toHit = glm::dvec3(p.position) - c.eye;
            EXPECT_NEAR(glm::length(glm::cross(toHit, glm::dvec3(p.rayDirection))), 0.0, 1e-4);
            EXPECT_LE(glm::length(p.position), r * 1.0001f);
            EXPECT_GE(glm::length(p.position), r * 0.995f);
            EXPECT_NEAR(glm::length(p.normal), 1.0f, 1e-5f);
            // Interpolated normals of a sphere: close to the radial direction, front-facing here.
            EXPECT_GT(glm::dot(p.normal, glm::normalize(p.position)), 0.999f);
            // Visible points of a convex object face the viewer (geometrically).
            EXPECT_GT(glm::dot(glm::normalize(p.position), p.toViewer), -1e-3f);
        }
    EXPECT_GT(hits, 100u);
}

TEST(GBuffer, RejectsBadCamera) {
    TriangleMesh sphere = makeIcosphere(1, 1.0f);
    RayScene scene(sphere);
    Camera c;
    c.target = c.eye;
    EXPECT_THROW(traceGBuffer(scene, sphere, c), Error);
    Camera d;
    d.fovY = 180;
    EXPECT_THROW(traceGBuffer(scene, sphere, d), Error);
}

// ---------------------------------------------------------------------------
// Environment lookup
// ---------------------------------------------------------------------------

TEST(EnvironmentRadiance, ConstantIsConstant) {
    const Image env = constantEnvironment(64, {0.5f, 1.25f, 3.0f});
    for (const glm::dmat3& R : {glm::dmat3(1.0), rotationY(37.0), rotationX(-80.0)})
        for (const glm::dvec3& d : {glm::dvec3(0, 1, 0), glm::dvec3(0, -1, 0), glm::dvec3(0, 0, 1),
                                    glm::dvec3(1, 2, -3), glm::dvec3(-0.3, 0.1, 0.9)}) {
            const glm::vec3 L = environmentRadiance(env, R, d);
            EXPECT_FLOAT_EQ(L.x, 0.5f);
            EXPECT_FLOAT_EQ(L.y, 1.25f);
            EXPECT_FLOAT_EQ(L.z, 3.0f);
        }
    EXPECT_EQ(environmentRadiance(Image(), glm::dmat3(1.0), {0, 0, -1}), glm::vec3(0.0f));
}

TEST(EnvironmentRadiance, SunFollowsTheRotationConvention) {
    const int W = 64, H = 32;
    // A sun in the pixel next to the image centre (-Z), at its pixel centre.
    const glm::dvec3 sun = latLongPixelDirection(W / 2, H / 2, W, H);
    ASSERT_LT(sun.z, -0.99);
    const Image env = sunEnvironment(W, sun, {2.0f, 3.0f, 4.0f});
    // Unrotated: full value exactly at the pixel centre.
    EXPECT_FLOAT_EQ(environmentRadiance(env, glm::dmat3(1.0), sun).y, 3.0f);
    // rotationY(90) turns -Z into -X: the sun is now seen near -X, not near -Z.
    const glm::dmat3 R = rotationY(90.0);
    const glm::dvec3 turned = R * sun;
    EXPECT_LT(turned.x, -0.99);
    const glm::vec3 peak = environmentRadiance(env, R, turned);
    EXPECT_FLOAT_EQ(peak.x, 2.0f);
    EXPECT_FLOAT_EQ(peak.z, 4.0f);
    EXPECT_EQ(environmentRadiance(env, R, sun), glm::vec3(0.0f));
    EXPECT_EQ(environmentRadiance(env, R, {1, 0, 0}), glm::vec3(0.0f));
    // Brightest of a dense set of directions is next to -X.
    double best = -1;
    glm::dvec3 bestDir(0.0);
    for (int i = 0; i < 720; ++i)
        for (int j = 1; j < 360; ++j) {
            const glm::dvec3 d = latLongToDirection(i / 720.0, j / 360.0);
            const double v = environmentRadiance(env, R, d).y;
            if (v > best) best = v, bestDir = d;
        }
    EXPECT_GT(glm::dot(bestDir, glm::dvec3(-1, 0, 0)), 0.99);
}

TEST(EnvironmentRadiance, BilinearWrapsInUAndClampsInV) {
    const int W = 8, H = 4;
    Image env(W, H, 3, 0.0f);
    for (int y = 0; y < H; ++y) {
        env.at(0, y, 0) = 1.0f;       // left column red
        env.at(W - 1, y, 1) = 1.0f;   // right column green
    }
    env.at(3, 0, 2) = 8.0f;  // blue in the top row
    // u = 0 (the +Z seam) lies halfway between the two edge columns' centres.
    const glm::vec3 seam = environmentRadiance(env, glm::dmat3(1.0), latLongToDirection(0.0, 0.5));
    EXPECT_NEAR(seam.x, 0.5f, 1e-6f);
    EXPECT_NEAR(seam.y, 0.5f, 1e-6f);
    // Between two pixel centres of a row: the mean.
    const glm::vec3 mid = environmentRadiance(env, glm::dmat3(1.0), latLongToDirection(1.0 / W, 0.5));
    EXPECT_NEAR(mid.x, 0.5f, 1e-6f);
    EXPECT_NEAR(mid.y, 0.0f, 1e-6f);
    // Above the top row's centres: clamped to the top row (straight up is the row itself).
    const glm::vec3 top = environmentRadiance(env, glm::dmat3(1.0), latLongToDirection(3.5 / W, 0.01));
    EXPECT_NEAR(top.z, 8.0f, 1e-5f);
    // A direction need not be unit length.
    const glm::vec3 a = environmentRadiance(env, glm::dmat3(1.0), {0.3, 0.2, -0.5});
    const glm::vec3 b = environmentRadiance(env, glm::dmat3(1.0), {3.0, 2.0, -5.0});
    EXPECT_EQ(a, b);
}

// ---------------------------------------------------------------------------
// Compositing
// ---------------------------------------------------------------------------

TEST(Compose, AlphaIsOneExactlyOnHitPixelsAndBackgroundIsTheEnvironment) {
    TriangleMesh sphere = makeIcosphere(3, 5.0f);
    RayScene scene(sphere);
    Camera c;
    c.eye = {0, 0, 30};
    c.target = {0, 0, 0};
    c.width = 64;
    c.height = 48;
    GBuffer g = traceGBuffer(scene, sphere, c);
    const Image env = twoToneEnvironment(32, {1.0f, 2.0f, 3.0f}, {0.1f, 0.2f, 0.3f});
    const glm::dmat3 R = rotationX(20.0);
    const Image img = compose(g, env, R, [](const GBufferPixel& p) { return p.normal * 7.0f; });
    ASSERT_EQ(img.width, 64);
    ASSERT_EQ(img.height, 48);
    ASSERT_EQ(img.channels, 4);
    size_t hits = 0;
    for (int y = 0; y < img.height; ++y)
        for (int x = 0; x < img.width; ++x) {
            const GBufferPixel& p = g.at(x, y);
            const float* o = img.pixel(x, y);
            if (p.hit) {
                ++hits;
                EXPECT_EQ(o[3], 1.0f);
                EXPECT_EQ(o[0], p.normal.x * 7.0f);
                EXPECT_EQ(o[2], p.normal.z * 7.0f);
            } else {
                EXPECT_EQ(o[3], 0.0f);
                const glm::vec3 L = environmentRadiance(env, R, glm::dvec3(p.rayDirection));
                EXPECT_EQ(o[0], L.x);
                EXPECT_EQ(o[1], L.y);
                EXPECT_EQ(o[2], L.z);
            }
        }
    EXPECT_EQ(hits, g.objectPixels());
    // Without a background the background is black.
    const Image black = compose(g, Image(), R, [](const GBufferPixel&) { return glm::vec3(1.0f); });
    EXPECT_EQ(black.at(0, 0, 0), 0.0f);
    EXPECT_EQ(black.at(0, 0, 3), 0.0f);
}

// ---------------------------------------------------------------------------
// Turntable: camera orbit + environment rotation == turned object in a fixed world
// ---------------------------------------------------------------------------

TEST(Turntable, CameraOrbitEqualsTurnedObject) {
    // An asymmetric object away from the origin, so both the pivot and the direction
    // of the turn matter.
    TriangleMesh box = makeBox({6.0f, 2.0f, 1.0f});
    for (glm::vec3& p : box.positions) p += glm::vec3(5.0f, 1.0f, -2.0f);
    const glm::dvec3 pivot(bounds(box).centre());
    RayScene scene(box);
    Camera c;
    c.eye = {5, 8, 30};
    c.target = pivot;
    c.fovY = 15;
    c.width = 96;
    c.height = 64;
    const Image env = sunEnvironment(64, glm::normalize(glm::dvec3(1, 0.2, -1)), {1, 1, 1});
    const Image sky = twoToneEnvironment(64, {1, 1, 1}, {0, 0, 0});
    for (double degrees : {30.0, 90.0, 200.0}) {
        // The object actually turned about the vertical axis through the pivot.
        TriangleMesh turned = box;
        const glm::dmat3 Ry = rotationY(degrees);
        for (glm::vec3& p : turned.positions) p = glm::vec3(pivot + Ry * (glm::dvec3(p) - pivot));
        for (glm::vec3& n : turned.normals) n = glm::vec3(Ry * glm::dvec3(n));
        RayScene turnedScene(turned);
        const GBuffer world = traceGBuffer(turnedScene, turned, c);
        const Camera orbit = turntableCamera(c, pivot, degrees);
        const GBuffer local = traceGBuffer(scene, box, orbit);
        size_t differ = 0, hits = 0;
        for (size_t i = 0; i < world.pixels.size(); ++i) {
            const GBufferPixel &a = world.pixels[i], &b = local.pixels[i];
            if (a.hit != b.hit) ++differ;
            if (!a.hit || !b.hit) {
                // Background: the environment rotated by Ry(-degrees) in the object's
                // frame is the fixed world environment.
                const glm::vec3 Lw = environmentRadiance(sky, glm::dmat3(1.0), glm::dvec3(a.rayDirection));
                const glm::vec3 Ll =
                    environmentRadiance(sky, rotationY(-degrees), glm::dvec3(b.rayDirection));
                EXPECT_NEAR(Lw.x, Ll.x, 1e-4);
                continue;
            }
            ++hits;
            EXPECT_EQ(a.triangle, b.triangle);
            // The same surface point, normal and view direction, up to the rotation.
            EXPECT_NEAR(glm::length(glm::dvec3(a.position) - (pivot + Ry * (glm::dvec3(b.position) - pivot))),
                        0.0, 1e-3);
            EXPECT_NEAR(glm::length(glm::dvec3(a.normal) - Ry * glm::dvec3(b.normal)), 0.0, 1e-5);
            EXPECT_NEAR(glm::length(glm::dvec3(a.toViewer) - Ry * glm::dvec3(b.toViewer)), 0.0, 1e-5);
            // Lighting from direction w in the world is lighting from Ry^T w on the
            // object: the rotated environment gives the same radiance.
            const glm::dvec3 w = glm::normalize(glm::dvec3(0.3, 0.5, -0.8));
            EXPECT_NEAR(environmentRadiance(env, glm::dmat3(1.0), w).x,
                        environmentRadiance(env, rotationY(-degrees), glm::transpose(Ry) * w).x, 1e-5);
        }
        EXPECT_GT(hits, 100u) << degrees;
        EXPECT_LE(differ, world.pixels.size() / 500) << degrees;  // edge pixels only
    }
}

