#include "tools/reference/reference_command.h"

#include <gtest/gtest.h>

#include <CLI/CLI.hpp>

#include <filesystem>
#include <string>
#include <vector>

#include "common/mesh_io.h"
#include "common/shapes.h"
#include "tests/test_support.h"

using namespace prt;

namespace {

ReferenceCommand parse(const std::vector<std::string>& args) {
    CLI::App app;
    ReferenceCommand o;
    addReferenceOptions(app, o);
    app.parse(std::vector<std::string>(args.rbegin(), args.rend()));
    noteGivenReferenceOptions(app, o);
    return o;
}

}  // namespace

// Under a light (no transport file): the frame and its noise image reach the writer
// under the tool's paths; the object is lit where the light sees it, and only there.
TEST(ReferenceCommand, ImagesGoToTheWriter) {
    const auto dir = std::filesystem::current_path() / "test_reference_command_scratch";
    std::filesystem::create_directories(dir);
    const std::string mesh = (dir / "sphere.obj").string();
    saveMesh(makeIcosphere(3, 10.0f), mesh);
    const std::string prefix = (dir / "frame").string(), noise = (dir / "noise.exr").string();
    test::MemoryImageWriter writer;
    const ReferenceCommand o = parse({mesh, "-o", prefix, "-m", "Marble", "--size-mm", "20", "--light", "dir:0,1,0:1",
                                      "-W", "24", "-H", "24", "--noise-image", noise});
    EXPECT_TRUE(o.materialGiven);
    EXPECT_EQ(runReferenceCommand(o, writer), 0);
    ASSERT_EQ(writer.images.size(), 3u);
    ASSERT_TRUE(writer.images.count(prefix + ".exr") && writer.images.count(prefix + ".png") &&
                writer.images.count(noise));
    EXPECT_FALSE(std::filesystem::exists(prefix + ".exr"));
    const Image& image = writer.images[prefix + ".exr"];
    // Lit from +Y: the top row of the sphere's pixels is brighter than the bottom's.
    double top = 0.0, bottom = 0.0;
    for (int x = 0; x < image.width; ++x)
        for (int y = 0; y < image.height; ++y) {
            if (image.at(x, y, 3) < 0.5f) continue;
            (y < image.height / 2 ? top : bottom) += image.at(x, y, 0);
        }
    EXPECT_GT(top, 2.0 * bottom);
    EXPECT_GT(bottom, 0.0);  // light scattered through the marble reaches the lower half
}

TEST(ReferenceCommand, BadOptionsNameTheOption) {
    test::MemoryImageWriter writer;
    test::expectErrorSubject([&] { runReferenceCommand(parse({"m.obj", "-o", "x"}), writer); }, "--environment");
    EXPECT_TRUE(writer.images.empty());
}
