#include "relight/pointlight/pointlight_command.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <string>
#include <vector>

#include "common/asset_io.h"
#include "common/image_compare.h"
#include "common/mesh_io.h"
#include "common/shapes.h"
#include "tests/test_support.h"

using namespace prt;

namespace {

PointLightCommand parse(const std::vector<std::string>& args) {
    return test::parseCommand(&addPointLightOptions, args);
}

std::string sphere() {
    const auto dir = std::filesystem::current_path() / "test_pointlight_command_scratch";
    std::filesystem::create_directories(dir);
    const std::string path = (dir / "sphere.obj").string();
    saveMesh(makeIcosphere(3, 10.0f), path);
    return path;
}

}  // namespace

// The run hands each image to the writer under the path the tool writes, and nothing
// reaches the disk: the cache's frame, Jensen-Buhler's for --compare-jb and the error
// heat map; the cache within 10% of Jensen-Buhler.
TEST(PointLightCommand, ImagesGoToTheWriterUnderTheToolsPaths) {
    const std::string mesh = sphere();
    const std::string prefix = (std::filesystem::current_path() / "test_pointlight_command_scratch" / "frame").string();
    std::filesystem::remove(prefix + ".exr");
    test::MemoryImageWriter writer;
    const PointLightCommand o = parse({mesh, "-o", prefix, "--light", "point:0,40,20:2", "--size-mm", "20", "-W", "48",
                                       "-H", "40", "--compare-jb"});
    EXPECT_EQ(runPointLightCommand(o, writer), 0);
    std::vector<std::string> paths;
    for (const auto& [path, image] : writer.images) paths.push_back(path.substr(prefix.size()));
    EXPECT_EQ(paths, (std::vector<std::string>{".exr", ".png", "_error.png", "_jb.exr", "_jb.png"}));
    EXPECT_FALSE(std::filesystem::exists(prefix + ".exr"));
    const Image& cache = writer.images[prefix + ".exr"];
    EXPECT_EQ(cache.width, 48);
    EXPECT_EQ(cache.height, 40);
    EXPECT_EQ(cache.channels, 4);
    const CompareResult r = compareImages(cache, writer.images[prefix + "_jb.exr"]);
    EXPECT_GT(r.comparedPixels, 300u);
    // The cache interpolates between records a few pixels apart in so small a frame
    // (5.9% here; about 1% at 256 x 256 and more, docs/point-lights.md).
    EXPECT_LT(r.overall.relativeRmse, 0.1);
}

// Bad options are refused by the run with the tool's one-line messages.
TEST(PointLightCommand, BadOptionsNameTheOption) {
    const std::string mesh = sphere();
    test::MemoryImageWriter writer;
    test::expectErrorSubject([&] { runPointLightCommand(parse({mesh, "-o", "x"}), writer); }, "--light");
    test::expectErrorSubject(
        [&] { runPointLightCommand(parse({mesh, "-o", "x", "--light", "point:0,40,0:1", "--method", "magic"}), writer); },
        "--method");
    test::expectErrorSubject(
        [&] { runPointLightCommand(parse({mesh, "-o", "x", "--light", "point:0,40,0:1", "--a", "0"}), writer); }, "--a");
    EXPECT_TRUE(writer.images.empty());
}

// --base-colour: a texture constant c gives c times the untextured frame, for the cache
// (and its Jensen-Buhler comparison) and texture-space sampling alike.
TEST(PointLightCommand, BaseColourTintsEveryMethod) {
    const std::string mesh = sphere();
    const auto dir = std::filesystem::current_path() / "test_pointlight_command_scratch";
    const std::string glb = (dir / "sphere.glb").string();
    const TriangleMesh fileMesh = loadMesh(mesh);
    Image texture(2, 2, 3);
    const glm::vec3 c(0.7f, 0.4f, 0.25f);
    for (size_t p = 0; p < 4; ++p)
        for (int k = 0; k < 3; ++k) texture.pixels[3 * p + size_t(k)] = c[k];
    saveTexturedGltf(glb, fileMesh, projectUvs(fileMesh, UvProjection::Box), texture);
    glm::vec3 decoded;
    for (int k = 0; k < 3; ++k) decoded[k] = srgbToLinear(std::round(linearToSrgb(c[k]) * 255.0f) / 255.0f);
    const std::string prefix = (dir / "tinted").string();
    for (const char* method : {"cache", "tsis"}) {
        std::vector<std::string> args{glb, "-o", prefix, "--light", "point:0,40,20:2", "--size-mm", "20", "-W",
                                      "40", "-H", "32", "--method", method};
        if (std::string(method) == "cache") args.push_back("--compare-jb");
        test::MemoryImageWriter plain, tinted;
        EXPECT_EQ(runPointLightCommand(parse(args), plain), 0);
        args.push_back("--base-colour");
        EXPECT_EQ(runPointLightCommand(parse(args), tinted), 0);
        ASSERT_EQ(plain.images.size(), tinted.images.size());
        for (const std::string suffix : {".exr", "_jb.exr"}) {
            if (!plain.images.count(prefix + suffix)) continue;
            const Image& a = plain.images[prefix + suffix];
            const Image& b = tinted.images[prefix + suffix];
            size_t objectPixels = 0;
            for (int y = 0; y < a.height; ++y)
                for (int x = 0; x < a.width; ++x) {
                    if (!(a.at(x, y, 3) > 0.5f)) continue;
                    ++objectPixels;
                    for (int k = 0; k < 3; ++k)
                        EXPECT_NEAR(b.at(x, y, k), decoded[k] * a.at(x, y, k), 1e-6f + 1e-5f * a.at(x, y, k))
                            << method << suffix;
                }
            EXPECT_GT(objectPixels, 200u) << method << suffix;
        }
    }
}
