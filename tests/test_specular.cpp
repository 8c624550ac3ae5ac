#include "relight/render/specular.h"

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

using namespace prt;

TEST(Specular, FresnelReflectionOfThePrefilteredEnvironment) {
    TriangleMesh sphere = makeIcosphere(3, 10.0f);
    RayScene scene(sphere);
    Camera c;
    c.eye = {0, 0, 60};
    c.target = {0, 0, 0};
    c.width = 33;
    c.height = 33;
    GBuffer g = traceGBuffer(scene, sphere, c);
    const Image cst = constantEnvironment(32, {2.0f, 3.0f, 4.0f});
    size_t hits = 0;
    for (const GBufferPixel& p : g.pixels) {
        const glm::vec3 L = specularReflection(p, 1.3, cst, rotationY(40.0));
        if (!p.hit) {
            EXPECT_EQ(L, glm::vec3(0.0f));
            continue;
        }
        ++hits;
        const double cosO = glm::dot(p.normal, p.toViewer);
        EXPECT_NEAR(L.y, 3.0 * fresnelReflectance(1.3, cosO), 1e-6);
    }
    EXPECT_GT(hits, 100u);
    // The mirror direction: at the centre pixel (normal ~ toward the eye) the
    // reflection looks back toward +Z; a sun there is seen, one at -Z is not.
    const GBufferPixel& centre = g.at(16, 16);
    const Image sunBack = sunEnvironment(64, latLongPixelDirection(0, 16, 64, 32), {1, 1, 1});
    const Image sunFront = sunEnvironment(64, latLongPixelDirection(32, 16, 64, 32), {1, 1, 1});
    EXPECT_GT(specularReflection(centre, 1.3, sunBack, glm::dmat3(1.0)).x, 0.0f);
    EXPECT_EQ(specularReflection(centre, 1.3, sunFront, glm::dmat3(1.0)).x, 0.0f);
}

TEST(Specular, PrefilterPreservesTheIntegral) {
    const Image env = sunEnvironment(64, glm::normalize(glm::dvec3(0.3, 0.8, -0.5)), {5, 6, 7});
    for (int factor : {1, 2, 4, 8}) {
        const Image f = prefilterEnvironment(env, factor);
        EXPECT_EQ(f.width, 64 / factor);
        EXPECT_EQ(f.height, 32 / factor);
        for (int ch = 0; ch < 3; ++ch)
            EXPECT_NEAR(latLongIntegral(f, ch), latLongIntegral(env, ch), 1e-6 * latLongIntegral(env, ch));
    }
    const Image cst = prefilterEnvironment(constantEnvironment(64, {1, 2, 3}), 4);
    for (int y = 0; y < cst.height; ++y)
        for (int x = 0; x < cst.width; ++x)
            for (int ch = 0; ch < 3; ++ch) EXPECT_NEAR(cst.at(x, y, ch), ch + 1.0f, 1e-6f);
    EXPECT_THROW(prefilterEnvironment(env, 3), Error);
    EXPECT_THROW(prefilterEnvironment(env, 0), Error);
}

