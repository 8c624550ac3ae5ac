#include "relight/prt/relight_object.h"

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
#include "relight/prt/light_vector.h"
#include "relight/prt/relight_kernel.h"
#include "relight/prt/translucent_shader.h"
#include "relight/render/gbuffer.h"
#include "tests/test_support.h"

using namespace prt;

namespace {

std::string scratchDir(const std::string& name) {
    const std::filesystem::path p = std::filesystem::current_path() / "test_relight_object_scratch" / name;
    std::filesystem::remove_all(p);
    std::filesystem::create_directories(p);
    return p.string();
}

}  // namespace

// ---------------------------------------------------------------------------
// End to end: files on disk -> placed object -> light vector -> relight -> frame
// ---------------------------------------------------------------------------

TEST(RenderEndToEnd, ConstantEnvironmentGivesFresnelTimesClosedFormDot) {
    const std::string dir = scratchDir("end_to_end");
    const float R = 2.0f;  // file units
    const double mmPerUnit = 5.0;
    const int n = 8;
    saveMesh(makeIcosphere(4, R), dir + "/sphere.obj");
    const TriangleMesh fileMesh = loadMesh(dir + "/sphere.obj");
    saveTransportFile(dir + "/sphere.prt", test::syntheticFaceTransport(fileMesh, n, mmPerUnit, R));

    const RelightObject object = loadRelightObject(dir + "/sphere.obj", dir + "/sphere.prt");
    EXPECT_DOUBLE_EQ(object.eta, 1.3);
    ASSERT_EQ(object.mesh.vertexCount(), fileMesh.vertexCount());
    EXPECT_NEAR(object.sphereRadius, R * mmPerUnit, 1e-4);
    EXPECT_NEAR(glm::length(object.sphereCentre), 0.0, 1e-4);
    EXPECT_NEAR(object.mesh.positions[7].x, fileMesh.positions[7].x * mmPerUnit, 1e-5);

    // Constant environment c: each face's Haar scaling coefficient is N * c (N times
    // the face mean), every other coefficient 0. So at vertex v
    //   diffuse[v] = sum_f s_v w_f rgb N c = s_v N c rgb * 21.
    const glm::vec3 cst(0.7f, 1.1f, 1.9f);
    const Image env = constantEnvironment(64, cst);
    const LightVector light = makeLightVector(env, n, rotationY(33.0));
    VertexRadiance rad;
    relightVertices(object.transport, light, ScatteringComponents::all(), rad);
    ASSERT_EQ(rad.diffuse.size(), object.mesh.vertexCount());

    const RayScene scene(object.mesh);
    const Camera camera = frameSphere(object.sphereCentre, object.sphereRadius, 0, 0, 30, 65, 65);
    const GBuffer g = traceGBuffer(scene, object.mesh, camera);
    const TranslucentShader shader(object.mesh, object.eta);
    const Image img = compose(g, env, glm::dmat3(1.0), [&](const GBufferPixel& p) { return shader.shade(p, rad); });

    const GBufferPixel& centre = g.at(32, 32);
    ASSERT_TRUE(centre.hit);
    const double cosO = glm::dot(centre.normal, centre.toViewer);
    EXPECT_GT(cosO, 0.999);
    const glm::dvec3 rgb(0.01, 0.02, 0.03);
    // s at the hit point (file units: position / mmPerUnit).
    const double s = 1.0 + 0.1 * (centre.position.x / mmPerUnit) / R;
    for (int ch = 0; ch < 3; ++ch) {
        const double closedForm = s * 21.0 * rgb[ch] * n * cst[ch];
        EXPECT_NEAR(img.at(32, 32, ch), fresnelTransmittance(1.3, cosO) * closedForm, 2e-4 * closedForm);
        // ~ F_t(eta, 1) at normal incidence.
        EXPECT_NEAR(img.at(32, 32, ch), fresnelTransmittance(1.3, 1.0) * closedForm, 2e-3 * closedForm);
    }
    EXPECT_EQ(img.at(32, 32, 3), 1.0f);
    // Every object pixel: the same law with its own normal and position.
    for (int y = 0; y < g.height; ++y)
        for (int x = 0; x < g.width; ++x) {
            const GBufferPixel& p = g.at(x, y);
            if (!p.hit) {
                EXPECT_FLOAT_EQ(img.at(x, y, 1), cst.y);
                continue;
            }
            const double co = glm::dot(p.normal, p.toViewer);
            const double ft = co > 0 ? fresnelTransmittance(1.3, co) : 0.0;
            const double sp = 1.0 + 0.1 * (p.position.x / mmPerUnit) / R;
            const double expected = ft * sp * 21.0 * rgb[1] * n * cst[1];
            EXPECT_NEAR(img.at(x, y, 1), expected, 2e-4 * (1e-3 + expected));
        }
}

TEST(RenderEndToEnd, MismatchedMeshIsRefused) {
    const std::string dir = scratchDir("mismatch");
    saveMesh(makeIcosphere(2, 1.0f), dir + "/a.obj");
    saveMesh(makeIcosphere(2, 1.5f), dir + "/b.obj");
    saveTransportFile(dir + "/a.prt", test::syntheticFaceTransport(loadMesh(dir + "/a.obj"), 4, 1.0, 1.0f));
    EXPECT_NO_THROW(loadRelightObject(dir + "/a.obj", dir + "/a.prt"));
    try {
        loadRelightObject(dir + "/b.obj", dir + "/a.prt");
        FAIL() << "a transport file for another mesh was accepted";
    } catch (const Error& e) {
        EXPECT_NE(std::string(e.what()).find("a.prt"), std::string::npos) << e.what();
    }
    EXPECT_THROW(loadRelightObject(dir + "/missing.obj", dir + "/a.prt"), Error);
    EXPECT_THROW(loadRelightObject(dir + "/a.obj", dir + "/missing.prt"), Error);
}
