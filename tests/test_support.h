#pragma once
// Helpers the module tests share (header-only, tests only).

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <map>
#include <new>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "common/error.h"
#include "common/image.h"
#include "common/mesh.h"
#include "common/transport_file.h"

namespace prt::test {

inline constexpr const char* kNoError = "<no error>";

// The whole file's bytes ("" when it cannot be read).
inline std::string fileBytes(const std::filesystem::path& path) {
    std::ifstream in(path, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

// Per-vertex vectors with random supports in [0, space) (each index present with
// probability 1 / keepOneIn) and values in [-10, 10] (steps of 0.01): deterministic per seed.
inline SparseRgbVectors randomSparseVectors(size_t vertices, uint32_t seed, uint32_t space, uint32_t keepOneIn) {
    std::mt19937 rng(seed);
    SparseRgbVectors v;
    for (size_t i = 0; i < vertices; ++i) {
        std::vector<uint32_t> idx;
        std::vector<float> rgb;
        for (uint32_t k = 0; k < space; ++k) {
            if (rng() % keepOneIn) continue;
            idx.push_back(k);
            for (int c = 0; c < 3; ++c) rgb.push_back(float(int(rng() % 2001) - 1000) / 100.0f);
        }
        v.appendVertex(idx, rgb);
    }
    return v;
}

// what() of the prt::Error that f throws, or kNoError when it throws none; any other
// exception (std::bad_alloc included) is a test failure: every user error must be a
// prt::Error with a one-line message.
inline std::string errorOf(const std::function<void()>& f) {
    try {
        f();
    } catch (const Error& e) {
        return e.what();
    } catch (const std::bad_alloc&) {
        ADD_FAILURE() << "std::bad_alloc instead of prt::Error";
        return "<bad_alloc>";
    } catch (const std::exception& e) {
        ADD_FAILURE() << "non-prt exception: " << e.what();
        return "<other exception>";
    }
    return kNoError;
}

// Expects f to throw prt::Error whose subject is `subject`.
inline void expectErrorSubject(const std::function<void()>& f, const std::string& subject) {
    try {
        f();
        ADD_FAILURE() << "expected prt::Error about " << subject;
    } catch (const Error& e) {
        EXPECT_EQ(e.subject(), subject) << e.what();
    }
}

// A transport file for `mesh` whose multiple-scattering vector at vertex v holds only
// the six face scaling coefficients, with RGB values (1 + 0.1 x_v / R) * faceWeight[f]
// * rgb (x_v in file units).
inline TransportFile syntheticFaceTransport(const TriangleMesh& mesh, int n, double mmPerUnit, float R) {
    TransportFile file;
    file.cubemapSize = uint32_t(n);
    file.mesh = MeshFingerprint{mesh.vertexCount(), meshFingerprint(mesh)};
    file.mmPerUnit = mmPerUnit;
    file.parameters = {{"material", "synthetic"}, {"eta", "1.3"}};
    TransportComponent ms;
    ms.kind = ComponentKind::MultipleScattering;
    const float faceWeight[6] = {1.0f, 2.0f, 3.0f, 4.0f, 5.0f, 6.0f};
    const glm::vec3 rgb(0.01f, 0.02f, 0.03f);
    for (const glm::vec3& p : mesh.positions) {
        std::vector<uint32_t> idx;
        std::vector<float> values;
        const float s = 1.0f + 0.1f * p.x / R;
        for (int f = 0; f < 6; ++f) {
            idx.push_back(uint32_t(f * n * n));
            for (int c = 0; c < 3; ++c) values.push_back(s * faceWeight[f] * rgb[c]);
        }
        ms.vectors.appendVertex(idx, values);
    }
    file.components.push_back(std::move(ms));
    return file;
}


// The images a command writes (runPointLightCommand, runReferenceCommand), by path,
// in memory.
struct MemoryImageWriter : ImageWriter {
    std::map<std::string, Image> images;
    void exr(const std::string& path, const Image& image) override { images[path] = image; }
    void png(const std::string& path, const Image& image, const DisplayTransform*) override { images[path] = image; }
};

}  // namespace prt::test
