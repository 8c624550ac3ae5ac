#include "relight/prt/translucent_shader.h"

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
#include "relight/prt/relight_kernel.h"

using namespace prt;

// ---------------------------------------------------------------------------
// Shading
// ---------------------------------------------------------------------------

TEST(TranslucentShader, FresnelTimesInterpolatedDiffuse) {
    const float r = 10.0f;
    TriangleMesh sphere = makeIcosphere(3, r);
    RayScene scene(sphere);
    Camera c;
    c.eye = {0, 0, 60};
    c.target = {0, 0, 0};
    c.width = 64;
    c.height = 64;
    GBuffer g = traceGBuffer(scene, sphere, c);
    // Per-vertex radiance linear in position: its barycentric interpolation is the same
    // linear function at the hit point.
    VertexRadiance rad;
    for (const glm::vec3& p : sphere.positions) rad.diffuse.push_back(glm::vec3(1.0f) + 0.05f * p);
    const double eta = 1.3;
    TranslucentShader shader(sphere, eta);
    EXPECT_EQ(shader.viewTermCount(), 0);
    size_t checked = 0;
    for (const GBufferPixel& p : g.pixels) {
        const glm::vec3 L = shader.shade(p, rad);
        if (!p.hit) {
            EXPECT_EQ(L, glm::vec3(0.0f));
            continue;
        }
        const double cosO = glm::dot(glm::dvec3(p.normal), glm::dvec3(p.toViewer));
        const double ft = cosO > 0 ? fresnelTransmittance(eta, cosO) : 0.0;
        const glm::dvec3 expected = ft * (glm::dvec3(1.0) + 0.05 * glm::dvec3(p.position));
        EXPECT_NEAR(L.x, expected.x, 1e-5);
        EXPECT_NEAR(L.y, expected.y, 1e-5);
        EXPECT_NEAR(L.z, expected.z, 1e-5);
        ++checked;
    }
    EXPECT_GT(checked, 100u);
    // Back-facing interpolated normal: black.
    GBufferPixel back = g.pixels[size_t(32) * 64 + 32];
    ASSERT_TRUE(back.hit);
    back.normal = -back.normal;
    EXPECT_EQ(shader.shade(back, rad), glm::vec3(0.0f));
}

TEST(TranslucentShader, ViewMapsAreLookedUpAtTheRefractedViewDirection) {
    TriangleMesh sphere = makeIcosphere(3, 10.0f);
    RayScene scene(sphere);
    Camera c;
    c.eye = {0, 0, 60};
    c.target = {0, 0, 0};
    c.width = 33;
    c.height = 33;
    GBuffer g = traceGBuffer(scene, sphere, c);
    const GBufferPixel& centre = g.at(16, 16);
    ASSERT_TRUE(centre.hit);

    // Two terms: h_0 = 1 on the -Z face (where w_o' points at the centre pixel: into
    // the medium, opposite to the viewer on +Z), 0 elsewhere; h_1 = 0.5 everywhere.
    ViewMaps maps;
    maps.size = 4;
    maps.terms = 2;
    const size_t texels = size_t(6) * 16;
    maps.data.assign(2 * texels, 0.0f);
    for (size_t i = 0; i < 16; ++i) maps.data[5 * 16 + i] = 1.0f;
    for (size_t i = 0; i < texels; ++i) maps.data[texels + i] = 0.5f;

    const double eta = 1.4;
    TranslucentShader shader(sphere, eta, &maps);
    ASSERT_EQ(shader.viewTermCount(), 2);
    EXPECT_FLOAT_EQ(shader.viewTerm(0, {0, 0, -1}), 1.0f);
    EXPECT_FLOAT_EQ(shader.viewTerm(0, {0, 0, 1}), 0.0f);
    EXPECT_FLOAT_EQ(shader.viewTerm(1, {0.3, -0.2, 0.5}), 0.5f);

    VertexRadiance rad;
    rad.diffuse.assign(sphere.vertexCount(), glm::vec3(0.25f));
    rad.terms.assign(2, std::vector<glm::vec3>(sphere.vertexCount(), glm::vec3(1.0f, 2.0f, 3.0f)));
    const glm::vec3 L = shader.shade(centre, rad);
    const double ft = fresnelTransmittance(eta, glm::dot(centre.normal, centre.toViewer));
    // 0.25 + h_0 * (1, 2, 3) + h_1 * (1, 2, 3) with h_0 = 1, h_1 = 0.5.
    EXPECT_NEAR(L.x, ft * (0.25 + 1.5 * 1), 1e-5);
    EXPECT_NEAR(L.y, ft * (0.25 + 1.5 * 2), 1e-5);
    EXPECT_NEAR(L.z, ft * (0.25 + 1.5 * 3), 1e-5);
    // Without view maps the terms are ignored.
    TranslucentShader plain(sphere, eta);
    EXPECT_NEAR(plain.shade(centre, rad).x, ft * 0.25, 1e-6);
    // A negative K-term sum (the factored phase's negative lobes) adds nothing: single
    // scattering is clamped at 0 per channel before it joins the diffuse part, and the
    // whole radiance is never negative.
    rad.terms.assign(2, std::vector<glm::vec3>(sphere.vertexCount(), glm::vec3(-1.0f, 0.1f, -3.0f)));
    const glm::vec3 clamped = shader.shade(centre, rad);
    EXPECT_NEAR(clamped.x, ft * 0.25, 1e-6);
    EXPECT_NEAR(clamped.y, ft * (0.25 + 1.5 * 0.1), 1e-6);
    EXPECT_NEAR(clamped.z, ft * 0.25, 1e-6);
    rad.diffuse.assign(sphere.vertexCount(), glm::vec3(-0.25f));
    EXPECT_EQ(shader.shade(centre, rad).x, 0.0f);
}
