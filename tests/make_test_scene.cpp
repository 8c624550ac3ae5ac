// prt-make-test-scene: helper of the viewer test (tests/viewer_test.sh, registered in
// relight/CMakeLists.txt). Two subcommands.
//
// `scene DIR` writes the small generated scene:
//   DIR/torus.ply      a torus (1152 vertices), for prt-precompute;
//   DIR/sphere.ply     an icosphere, the "wrong mesh" of the mismatch test;
//   DIR/sky.exr        128 x 64: a two-tone sky plus a small bright sun;
//   DIR/dusk.exr       128 x 64: a dimmer constant sky plus a low sun elsewhere;
//   DIR/synthetic.prt  a transport file for torus.ply made up here, not precomputed:
//                      multiple scattering plus K = 3 single-scattering terms with
//                      smooth view maps, so the viewer's view-map path (refraction,
//                      cube-face lookup, bilinear) is compared with the offline renderer
//                      although prt-precompute does not write terms yet.
// Everything is deterministic.
//
// `agree VIEW RENDER MASKED` compares a viewer screenshot pair VIEW.exr/.png with a
// render RENDER.exr/.png of the same view, for what rasterisation and ray casting can
// legitimately disagree on: pixels whose centre lies within a rounding error of a
// silhouette edge (OpenGL snaps vertices to a sub-pixel grid, 1/256 pixel in Mesa) may
// be covered in one image and not in the other. It
//   - counts those coverage mismatches (alpha > 0.5 in exactly one EXR) and fails when
//     there are more than --max-mismatch (default 0.1% of the object pixels + 2);
//   - writes MASKED.exr: RENDER's RGB with alpha = object in both, the reference that
//     prt-compare then uses to measure the shading error over the common object pixels;
//   - checks the PNGs over the pixels with equal coverage (object and background): the
//     largest difference must be at most --max-levels of 255 (default 1: the float
//     shaders round differently once in a while).
// Exit code 0 when all hold, 2 otherwise, 1 on errors.

#include <CLI/CLI.hpp>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include "common/cubemap.h"
#include "common/envmap.h"
#include "common/error.h"
#include "common/image.h"
#include "common/mesh.h"
#include "common/shapes.h"
#include "common/transport_file.h"
#include "common/mesh_io.h"
#include "common/options.h"

#include <algorithm>

using namespace prt;

namespace {

// Deterministic value in [-1, 1) from a counter (splitmix64).
double hashUnit(uint64_t x) {
    x += 0x9e3779b97f4a7c15ULL;
    x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ULL;
    x = (x ^ (x >> 27)) * 0x94d049bb133111ebULL;
    x ^= x >> 31;
    return double(x >> 11) / double(1ULL << 52) - 1.0;
}

Image addImages(const Image& a, const Image& b) {
    Image out = a;
    for (size_t i = 0; i < out.pixels.size(); ++i) out.pixels[i] += b.pixels[i];
    return out;
}

// Face directions in the cubemap order +X, -X, +Y, -Y, +Z, -Z.
const glm::dvec3 kFaceAxis[6] = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};

// One sparse RGB vector: the six face scaling coefficients weighted by how much the
// vertex faces each cube face (a smooth, mostly positive response), plus a few small
// detail coefficients.
void appendVector(SparseRgbVectors& vectors, const glm::dvec3& normal, int n, const glm::dvec3& rgb,
                  uint64_t seed) {
    std::vector<uint32_t> idx;
    std::vector<float> values;
    for (int f = 0; f < 6; ++f) {
        const double w = std::max(0.0, glm::dot(normal, kFaceAxis[f])) + 0.05;
        idx.push_back(uint32_t(f * n * n));
        for (int c = 0; c < 3; ++c) values.push_back(float(w * rgb[c]));
        for (int d = 1; d <= 3; ++d) {  // detail coefficients at distinct indices of the face
            idx.push_back(uint32_t(f * n * n + d * 5));
            for (int c = 0; c < 3; ++c)
                values.push_back(float(0.3 * w * rgb[c] * hashUnit(seed * 977 + uint64_t(f * 16 + d * 3 + c))));
        }
    }
    vectors.appendVertex(idx, values);
}

TransportFile syntheticTransport(const TriangleMesh& mesh, int n, int terms, int viewSize) {
    TransportFile file;
    file.cubemapSize = uint32_t(n);
    file.mesh = MeshFingerprint{mesh.vertexCount(), meshFingerprint(mesh)};
    file.mmPerUnit = 10.0;
    file.parameters = {{"material", "synthetic (prt-make-test-scene)"}, {"eta", "1.4"}, {"terms", std::to_string(terms)}};
    TransportComponent ms;
    ms.kind = ComponentKind::MultipleScattering;
    for (size_t v = 0; v < mesh.vertexCount(); ++v)
        appendVector(ms.vectors, glm::dvec3(mesh.normals[v]), n, {0.020, 0.012, 0.008}, v);
    file.components.push_back(std::move(ms));
    for (int k = 0; k < terms; ++k) {
        TransportComponent t;
        t.kind = ComponentKind::SingleScatteringTerm;
        t.term = uint32_t(k);
        const glm::dvec3 rgb = glm::dvec3(0.006, 0.008, 0.010) / double(k + 1);
        for (size_t v = 0; v < mesh.vertexCount(); ++v)
            appendVector(t.vectors, -glm::dvec3(mesh.normals[v]), n, rgb, 1000003ULL * (k + 1) + v);
        file.components.push_back(std::move(t));
    }
    ViewMaps maps;
    maps.size = viewSize;
    maps.terms = terms;
    maps.data.resize(size_t(terms) * 6 * viewSize * viewSize);
    for (int k = 0; k < terms; ++k)
        for (int f = 0; f < 6; ++f)
            for (int j = 0; j < viewSize; ++j)
                for (int i = 0; i < viewSize; ++i) {
                    const glm::dvec3 d = texelDirection(viewSize, f, i, j);
                    // Smooth functions of the refracted view direction (which points into
                    // the medium): term 0 positive, terms 1 and 2 signed.
                    const double h = k == 0 ? 1.0 + 0.5 * d.z : k == 1 ? 0.8 * d.x : 0.6 * d.y + 0.2;
                    maps.data[((size_t(k) * 6 + f) * viewSize + j) * viewSize + i] = float(h);
                }
    file.viewMaps = std::move(maps);
    return file;
}

}  // namespace

int makeScene(const std::string& dir) {
    std::filesystem::create_directories(dir);

    saveMesh(makeTorus(1.0f, 0.4f, 48, 24), dir + "/torus.ply");
    const TriangleMesh torus = loadMesh(dir + "/torus.ply");
    saveMesh(makeIcosphere(2, 1.0f), dir + "/sphere.ply");

    const Image sky = addImages(twoToneEnvironment(128, {0.55f, 0.65f, 0.9f}, {0.25f, 0.2f, 0.15f}),
                                sunEnvironment(128, glm::normalize(glm::dvec3(0.5, 0.7, 0.4)), {400.0f, 380.0f, 330.0f}));
    writeExr(dir + "/sky.exr", sky);
    const Image dusk = addImages(constantEnvironment(128, {0.15f, 0.12f, 0.2f}),
                                 sunEnvironment(128, glm::normalize(glm::dvec3(-0.8, 0.15, -0.3)), {500.0f, 250.0f, 100.0f}));
    writeExr(dir + "/dusk.exr", dusk);

    saveTransportFile(dir + "/synthetic.prt", syntheticTransport(torus, 8, 3, 8));
    std::printf("wrote %s/torus.ply (%zu vertices), sphere.ply, sky.exr, dusk.exr, synthetic.prt\n", dir.c_str(),
                torus.vertexCount());
    return 0;
}

int agree(const std::string& view, const std::string& render, const std::string& masked, long maxMismatch,
          int maxLevels) {
    const Image ve = readImage(view + ".exr"), re = readImage(render + ".exr");
    const Image vp = readImage(view + ".png"), rp = readImage(render + ".png");
    for (const Image* im : {&ve, &re})
        if (im->channels != 4) throw Error(im == &ve ? view + ".exr" : render + ".exr", "expected RGBA");
    for (const Image* im : {&re, &vp, &rp})
        if (im->width != ve.width || im->height != ve.height)
            throw Error(render, "image sizes differ from " + view + "'s");
    Image out(re.width, re.height, 4);
    long objectBoth = 0, onlyRender = 0, onlyView = 0, compared = 0, offByOne = 0;
    int worst = 0, worstX = -1, worstY = -1;
    for (int y = 0; y < re.height; ++y)
        for (int x = 0; x < re.width; ++x) {
            const bool v = ve.at(x, y, 3) > 0.5f, r = re.at(x, y, 3) > 0.5f;
            objectBoth += v && r;
            onlyRender += r && !v;
            onlyView += v && !r;
            for (int c = 0; c < 3; ++c) out.at(x, y, c) = re.at(x, y, c);
            out.at(x, y, 3) = v && r ? 1.0f : 0.0f;
            if (v != r) continue;
            ++compared;
            int d = 0;
            for (int c = 0; c < 3; ++c)
                d = std::max(d, int(std::lround(std::abs(vp.at(x, y, c) - rp.at(x, y, c)) * 255.0f)));
            offByOne += d > 0;
            if (d > worst) {
                worst = d;
                worstX = x;
                worstY = y;
            }
        }
    writeExr(masked, out);
    if (maxMismatch < 0) maxMismatch = (objectBoth + onlyRender + onlyView) / 1000 + 2;
    const long mismatch = onlyRender + onlyView;
    std::printf("coverage: %ld object pixels in both, %ld only in the render, %ld only in the view "
                "(at most %ld allowed)\n",
                objectBoth, onlyRender, onlyView, maxMismatch);
    std::printf("png: %ld pixels with equal coverage, %ld differ, largest difference %d/255 at (%d, %d) "
                "(at most %d allowed)\n",
                compared, offByOne, worst, worstX, worstY, maxLevels);
    return mismatch <= maxMismatch && worst <= maxLevels ? 0 : 2;
}

int main(int argc, char** argv) {
    return runMain("prt-make-test-scene", [&]() -> int {
        CLI::App app{"prt-make-test-scene: helper of tests/viewer_test.sh"};
        app.require_subcommand(1);
        std::string dir, view, render, masked;
        long maxMismatch = -1;
        int maxLevels = 1;
        CLI::App* scene = app.add_subcommand("scene", "Write the viewer test's generated scene into DIR");
        scene->add_option("dir", dir, "Output folder (created)")->required();
        CLI::App* agreeCmd = app.add_subcommand(
            "agree", "Coverage mismatches and PNG agreement of VIEW.exr/.png and RENDER.exr/.png; writes "
                     "MASKED (RENDER.exr with alpha = object in both)");
        agreeCmd->add_option("view", view, "Viewer screenshot prefix")->required();
        agreeCmd->add_option("render", render, "prt-relight render output prefix")->required();
        agreeCmd->add_option("masked", masked, "Masked reference EXR to write")->required();
        agreeCmd->add_option("--max-mismatch", maxMismatch,
                             "Allowed coverage mismatches (default: 0.1% of the object pixels + 2)");
        agreeCmd->add_option("--max-levels", maxLevels, "Allowed PNG difference in levels of 255")
            ->capture_default_str();
        if (const auto exitCode = parseCommandLine(app, argc, argv, "prt-make-test-scene")) return *exitCode;
        if (scene->parsed()) return makeScene(dir);
        return agree(view, render, masked, maxMismatch, maxLevels);
    });
}
