#include "common/camera.h"

#include <gtest/gtest.h>

#include <cmath>

#include "common/error.h"

using namespace prt;

TEST(Camera, DefaultLooksDownMinusZWithYUp) {
    Camera c;
    c.eye = {0, 0, 10};
    c.target = {0, 0, 0};
    glm::dvec3 centre = cameraRayDirection(c, c.width / 2.0, c.height / 2.0);
    EXPECT_NEAR(glm::length(centre - glm::dvec3(0, 0, -1)), 0, 1e-12);
    // The top row looks up, the right column looks toward +X.
    EXPECT_GT(cameraRayDirection(c, c.width / 2.0, 0).y, 0);
    EXPECT_GT(cameraRayDirection(c, c.width, c.height / 2.0).x, 0);
}

TEST(Camera, FieldOfViewIsTheVerticalAngle) {
    Camera c;
    c.fovY = 60;
    c.width = 300;
    c.height = 200;
    glm::dvec3 top = cameraRayDirection(c, 150, 0), bottom = cameraRayDirection(c, 150, 200);
    EXPECT_NEAR(glm::degrees(std::acos(glm::dot(top, bottom))), 60, 1e-9);
}

TEST(Camera, ProjectIsTheInverseOfRayDirection) {
    Camera c;
    c.eye = {3, 4, 5};
    c.target = {-1, 0.5, 2};
    c.width = 320;
    c.height = 240;
    for (double px : {0.5, 17.25, 160.0, 319.5})
        for (double py : {0.5, 100.0, 239.5}) {
            double x, y;
            ASSERT_TRUE(projectDirection(c, cameraRayDirection(c, px, py), x, y));
            EXPECT_NEAR(x, px, 1e-9);
            EXPECT_NEAR(y, py, 1e-9);
        }
    double x, y;
    EXPECT_FALSE(projectDirection(c, glm::normalize(c.eye - c.target), x, y));
}

TEST(Camera, FrameSphereFitsTheSphere) {
    Camera c = frameSphere({1, 2, 3}, 5, 0, 0, 40, 400, 300, 0.9);
    EXPECT_NEAR(c.eye.x, 1, 1e-12);
    EXPECT_GT(c.eye.z, 3);  // azimuth 0 looks down -Z
    // The sphere's angular radius is 0.9 of the half field of view.
    double angular = std::asin(5 / glm::length(c.eye - c.target));
    EXPECT_NEAR(std::tan(angular), 0.9 * std::tan(glm::radians(20.0)), 1e-9);
}

TEST(Camera, RejectsDegenerateCameras) {
    Camera c;
    EXPECT_NO_THROW(validateCamera(c));
    Camera same = c;
    same.target = same.eye;
    EXPECT_THROW(validateCamera(same), Error);
    Camera parallel = c;
    parallel.up = {0, 0, 1};
    EXPECT_THROW(validateCamera(parallel), Error);
    Camera fov = c;
    fov.fovY = 180;
    EXPECT_THROW(validateCamera(fov), Error);
    Camera size = c;
    size.width = 0;
    EXPECT_THROW(validateCamera(size), Error);
}
