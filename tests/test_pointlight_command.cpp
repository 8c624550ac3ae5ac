#include "relight/pointlight/pointlight_command.h"

#include <gtest/gtest.h>

#include <cmath>
#include <algorithm>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include "common/asset_io.h"
#include "common/image_compare.h"
#include "common/mesh_io.h"
#include "common/shapes.h"
#include "tests/command_line_support.h"
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

namespace {

// Runs the command and returns the images it wrote, by path.
std::map<std::string, Image> run(const std::vector<std::string>& args) {
    test::MemoryImageWriter writer;
    EXPECT_EQ(runPointLightCommand(parse(args), writer), 0);
    return writer.images;
}

// The rows of the lower 40% of the object in a frame (alpha = 1 marks the object).
std::pair<int, int> lowerObjectRows(const Image& a) {
    int top = a.height, bottom = -1;
    for (int y = 0; y < a.height; ++y)
        for (int x = 0; x < a.width; ++x)
            if (a.at(x, y, 3) > 0.5f) {
                top = std::min(top, y);
                bottom = std::max(bottom, y);
            }
    return {bottom - int(0.4 * (bottom - top)), bottom};
}

}  // namespace

// --specular and --single-scattering are off by default and toggle alone (their other
// options change nothing while they are off); on, they add to the object only: the
// background and alpha stay, no pixel darkens, and the specular leaves the lower part
// of the sphere (facing away from the light above) exactly as it was. The references
// of --compare-jb get the same terms.
TEST(PointLightCommand, SurfaceTermsToggleAndAddOnlyWhereTheyShould) {
    const std::string mesh = sphere();
    const std::string prefix = (std::filesystem::current_path() / "test_pointlight_command_scratch" / "terms").string();
    for (const char* method : {"cache", "tsis"}) {
        SCOPED_TRACE(method);
        const std::vector<std::string> base{mesh,  "-o", prefix, "--light", "point:0,40,0:0.01", "--size-mm", "20",
                                            "-W", "40", "-H", "40", "--method", method, "--compare-jb"};
        auto with = [&](std::vector<std::string> extra) {
            std::vector<std::string> a = base;
            a.insert(a.end(), extra.begin(), extra.end());
            return run(a);
        };
        const auto plain = with({});
        const auto off = with({"--specular-roughness", "0.7", "--single-scattering-samples", "3", "--g", "0"});
        ASSERT_EQ(plain.size(), off.size());
        for (const auto& [path, image] : plain) EXPECT_EQ(image.pixels, off.at(path).pixels) << path;
        const Image& a = plain.at(prefix + ".exr");
        const auto [lowTop, lowBottom] = lowerObjectRows(a);
        ASSERT_GT(lowBottom - lowTop, 4);

        for (const char* flag : {"--specular", "--single-scattering"}) {
            SCOPED_TRACE(flag);
            const bool specular = std::string(flag) == "--specular";
            const auto on = with({flag});
            for (const char* suffix : {".exr", "_jb.exr"}) {
                const Image& before = plain.at(prefix + suffix);
                const Image& after = on.at(prefix + suffix);
                size_t brighter = 0, lowerChanged = 0;
                for (int y = 0; y < a.height; ++y)
                    for (int x = 0; x < a.width; ++x) {
                        EXPECT_EQ(after.at(x, y, 3), before.at(x, y, 3));
                        const bool object = before.at(x, y, 3) > 0.5f;
                        for (int c = 0; c < 3; ++c) {
                            if (!object) {
                                EXPECT_EQ(after.at(x, y, c), before.at(x, y, c));
                                continue;
                            }
                            EXPECT_GE(after.at(x, y, c), before.at(x, y, c));
                            if (c == 0 && after.at(x, y, c) > before.at(x, y, c)) ++brighter;
                            if (y >= lowTop && after.at(x, y, c) != before.at(x, y, c)) ++lowerChanged;
                        }
                    }
                EXPECT_GT(brighter, 100u) << suffix;
                if (specular) {
                    EXPECT_EQ(lowerChanged, 0u) << suffix;
                }
            }
            // The same terms on the frame and on its reference.
            const Image& f0 = plain.at(prefix + ".exr");
            const Image& f1 = on.at(prefix + ".exr");
            const Image& j0 = plain.at(prefix + "_jb.exr");
            const Image& j1 = on.at(prefix + "_jb.exr");
            for (size_t i = 0; i < f0.pixels.size(); ++i)
                EXPECT_NEAR(f1.pixels[i] - f0.pixels[i], j1.pixels[i] - j0.pixels[i],
                            1e-6f * (1.0f + std::abs(f1.pixels[i]) + std::abs(j1.pixels[i])));
        }
    }
}

// Every frame of an animation has the terms: a light path's first frame (a spot light
// moving) equals the single frame with that light, terms and all.
TEST(PointLightCommand, SurfaceTermsInAnimationFrames) {
    const std::string mesh = sphere();
    const std::string prefix = (std::filesystem::current_path() / "test_pointlight_command_scratch" / "pathterms").string();
    const std::vector<std::string> common{mesh, "-o", prefix, "--size-mm", "20", "-W", "32", "-H", "32",
                                          "--method", "jb", "--specular", "--single-scattering"};
    std::vector<std::string> single = common;
    for (const char* a : {"--light", "spot:-20,30,10:0.5,-1,-0.2:0.01:20,40"}) single.push_back(a);
    std::vector<std::string> path = common;
    for (const char* a : {"--light", "spot:0,0,90:0.5,-1,-0.2:0.01:20,40", "--light-path=-20,30,10:20,30,10",
                          "--frames", "2"})
        path.push_back(a);
    const auto one = run(single);
    const auto frames = run(path);
    ASSERT_TRUE(frames.count(prefix + "_0000.exr"));
    EXPECT_EQ(frames.at(prefix + "_0000.exr").pixels, one.at(prefix + ".exr").pixels);
    // Without the terms the frame differs.
    std::vector<std::string> bare(single.begin(), single.end());
    bare.erase(std::find(bare.begin(), bare.end(), "--specular"));
    bare.erase(std::find(bare.begin(), bare.end(), "--single-scattering"));
    EXPECT_NE(run(bare).at(prefix + ".exr").pixels, one.at(prefix + ".exr").pixels);
}

// A spot whose inner cone holds the whole object is the point light of the same
// intensity, for every method (pass 1's irradiance, tsis's shadow maps, the terms).
TEST(PointLightCommand, WideSpotEqualsPointLightInEveryMethod) {
    const std::string mesh = sphere();
    const std::string prefix = (std::filesystem::current_path() / "test_pointlight_command_scratch" / "spot").string();
    for (const char* method : {"cache", "jb", "tsis"}) {
        const std::vector<std::string> base{mesh, "-o", prefix, "--size-mm", "20", "-W", "32", "-H", "32", "--method",
                                            method, "--specular", "--single-scattering", "--light"};
        std::vector<std::string> point = base, spot = base;
        point.push_back("point:10,40,20:0.01");
        spot.push_back("spot:10,40,20:-0.25,-1,-0.5:0.01:45,60");
        EXPECT_EQ(run(point).at(prefix + ".exr").pixels, run(spot).at(prefix + ".exr").pixels) << method;
        // Aimed away, it lights nothing.
        std::vector<std::string> away = base;
        away.push_back("spot:10,40,20:0,1,0:0.01:10,20");
        const Image dark = run(away).at(prefix + ".exr");
        float most = 0.0f;
        for (int y = 0; y < dark.height; ++y)
            for (int x = 0; x < dark.width; ++x) most = std::max(most, dark.at(x, y, 0));
        EXPECT_EQ(most, 0.0f) << method;
    }
}
