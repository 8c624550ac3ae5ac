#pragma once
// Fixtures of the sun split's tests (test_sun_split_frame.cpp, test_sun_split_vertices.cpp):
// a synthetic sphere object and a sky with a sun.

#include <glm/glm.hpp>

#include <filesystem>
#include <string>

#include "common/envmap.h"
#include "common/mesh_io.h"
#include "common/shapes.h"
#include "relight/prt/relight_object.h"
#include "tests/test_support.h"

namespace prt::test {

// test_environment_frame's synthetic sphere (radius 2, syntheticFaceTransport over a
// 6 x 8 x 8 cubemap), written under `folder`/`name` of the current directory and loaded;
// withMaterial: its file names Marble-like coefficients (the split needs a material).
inline RelightObject sunSplitSphere(const std::string& folder, const std::string& name, bool withMaterial,
                                    int subdivisions = 3) {
    const std::filesystem::path dir = std::filesystem::current_path() / folder / name;
    std::filesystem::remove_all(dir);
    std::filesystem::create_directories(dir);
    saveMesh(makeIcosphere(subdivisions, 2.0f), (dir / "sphere.obj").string());
    const TriangleMesh fileMesh = loadMesh((dir / "sphere.obj").string());
    TransportFile file = syntheticFaceTransport(fileMesh, 8, 5.0, 2.0f);
    if (withMaterial) {
        file.parameters.push_back({"sigma_s_prime", "2.19,2.62,3.00"});
        file.parameters.push_back({"sigma_a", "0.0021,0.0041,0.0071"});
    }
    saveTransportFile((dir / "sphere.prt").string(), file);
    return loadRelightObject((dir / "sphere.obj").string(), (dir / "sphere.prt").string());
}

// A two-tone sky (64 x 32) with a one-texel sun toward (1, 1, 0.3).
inline Image skyWithSun() {
    Image env = twoToneEnvironment(64, {1.2f, 1.0f, 0.8f}, {0.1f, 0.2f, 0.3f});
    const Image sun = sunEnvironment(64, glm::normalize(glm::dvec3(1, 1, 0.3)), {300.0f, 280.0f, 250.0f});
    for (size_t i = 0; i < env.pixels.size(); ++i) env.pixels[i] += sun.pixels[i];
    return env;
}

}  // namespace prt::test
