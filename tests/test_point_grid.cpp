// Tests of common/point_grid: radius queries against brute force.

#include "common/point_grid.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <random>
#include <vector>

#include "common/error.h"

using namespace prt;

TEST(PointGrid, RadiusQueriesMatchBruteForce) {
    std::mt19937 rng(7);
    std::uniform_real_distribution<float> u(-3.0f, 2.0f);  // negative coordinates too
    std::vector<glm::vec3> points(2000);
    for (glm::vec3& p : points) p = {u(rng), u(rng), u(rng)};
    for (double cell : {0.05, 0.3, 1.0, 10.0}) {
        const PointGrid grid(points, cell);
        for (int q = 0; q < 50; ++q) {
            const glm::vec3 p(u(rng), u(rng), u(rng));
            for (double radius : {0.0, 0.1, 0.45, 2.0}) {
                std::vector<uint32_t> found;
                grid.forEachWithin(p, radius, [&](uint32_t i, float d2) {
                    EXPECT_FLOAT_EQ(d2, glm::dot(points[i] - p, points[i] - p));
                    found.push_back(i);
                });
                std::vector<uint32_t> expected;
                for (uint32_t i = 0; i < points.size(); ++i)
                    if (glm::dot(points[i] - p, points[i] - p) <= float(radius * radius)) expected.push_back(i);
                std::sort(found.begin(), found.end());
                EXPECT_EQ(found, expected) << "cell " << cell << " radius " << radius;
            }
        }
    }
}

TEST(PointGrid, CellsHoldTheirPointsInIndexOrder) {
    const std::vector<glm::vec3> points = {{0.5f, 0.5f, 0.5f}, {-0.5f, 0.2f, 0.1f}, {0.9f, 0.1f, 0.2f}, {0.1f, 0.9f, 0.99f}};
    const PointGrid grid(points, 1.0);
    EXPECT_EQ(grid.coords(points[1]), glm::ivec3(-1, 0, 0));
    std::vector<uint32_t> cell;
    grid.forEachInCell({0, 0, 0}, [&](uint32_t i) { cell.push_back(i); });
    EXPECT_EQ(cell, (std::vector<uint32_t>{0, 2, 3}));
    cell.clear();
    grid.forEachInCell({5, 5, 5}, [&](uint32_t i) { cell.push_back(i); });
    EXPECT_TRUE(cell.empty());
}

TEST(PointGrid, RefusesABadCellSize) {
    const std::vector<glm::vec3> points = {{0, 0, 0}};
    EXPECT_THROW(PointGrid(points, 0.0), Error);
    EXPECT_THROW(PointGrid(points, -1.0), Error);
    EXPECT_THROW(PointGrid(points, std::numeric_limits<double>::infinity()), Error);
}
