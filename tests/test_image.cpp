#include "common/image.h"

#include <OpenImageIO/imageio.h>
#include <gtest/gtest.h>
#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <csignal>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <random>
#include <string>

#include "common/error.h"

namespace fs = std::filesystem;
using prt::Image;

namespace {

// A fresh, empty directory per test, removed afterwards.
class ImageIoTest : public ::testing::Test {
protected:
    void SetUp() override {
        const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
        dir_ = fs::temp_directory_path() /
               ("prt_test_image_" + std::to_string(long(::getpid())) + "_" + info->name());
        fs::remove_all(dir_);
        fs::create_directories(dir_);
    }
    void TearDown() override {
        std::error_code ec;
        fs::remove_all(dir_, ec);
    }
    std::string file(const std::string& name) const { return (dir_ / name).string(); }
    // Names of all entries in the test directory.
    std::vector<std::string> entries() const {
        std::vector<std::string> names;
        for (const auto& e : fs::directory_iterator(dir_)) names.push_back(e.path().filename());
        std::sort(names.begin(), names.end());
        return names;
    }
    fs::path dir_;
};

Image randomImage(int w, int h, int c, float lo, float hi, unsigned seed) {
    Image img(w, h, c);
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> dist(lo, hi);
    for (float& v : img.pixels) v = dist(rng);
    return img;
}

// Runs `f`, expecting a prt::Error whose message names `path`.
template <class F>
void expectErrorNaming(const std::string& path, F&& f) {
    try {
        f();
        ADD_FAILURE() << "expected prt::Error for " << path;
    } catch (const prt::Error& e) {
        EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
        EXPECT_EQ(e.subject(), path);
    }
}

}  // namespace

TEST(Image, LayoutAndAccess) {
    Image img(3, 2, 4, 0.5f);
    EXPECT_EQ(img.pixels.size(), 24u);
    EXPECT_TRUE(img.consistent());
    EXPECT_FALSE(img.empty());
    img.at(2, 1, 3) = 7.0f;
    EXPECT_EQ(img.pixels[(1 * 3 + 2) * 4 + 3], 7.0f);
    EXPECT_EQ(img.pixel(2, 1)[3], 7.0f);
    EXPECT_TRUE(Image().empty());
    EXPECT_THROW(Image(-1, 2, 3), prt::Error);
}

TEST(Image, SrgbTransferFunctions) {
    // Exact piecewise curve: linear segment, breakpoints, end points.
    EXPECT_FLOAT_EQ(prt::linearToSrgb(0.0f), 0.0f);
    EXPECT_FLOAT_EQ(prt::linearToSrgb(1.0f), 1.0f);
    EXPECT_FLOAT_EQ(prt::linearToSrgb(0.001f), 0.01292f);
    EXPECT_NEAR(prt::linearToSrgb(0.0031308f), 0.04045f, 1e-6);
    EXPECT_NEAR(prt::linearToSrgb(0.18f), 1.055 * std::pow(0.18, 1 / 2.4) - 0.055, 1e-6);
    EXPECT_NEAR(prt::srgbToLinear(0.5f), std::pow((0.5 + 0.055) / 1.055, 2.4), 1e-7);
    EXPECT_FLOAT_EQ(prt::srgbToLinear(0.02f), 0.02f / 12.92f);
    for (int i = 0; i <= 1000; ++i) {
        const float x = i / 1000.0f;
        EXPECT_NEAR(prt::srgbToLinear(prt::linearToSrgb(x)), x, 2e-6) << x;
    }
    // Continuity at the breakpoint.
    // (the curve's slope there is 12.92, the two arguments are 2e-7 apart).
    EXPECT_NEAR(prt::linearToSrgb(0.0031307f), prt::linearToSrgb(0.0031309f), 4e-6);
}

TEST_F(ImageIoTest, ExrFloatRoundTripIsBitExact) {
    for (int c : {1, 3, 4}) {
        Image img = randomImage(37, 23, c, -2.0f, 1000.0f, 7u + unsigned(c));
        img.at(0, 0, 0) = 1e-30f;  // tiny values survive in float
        img.at(1, 0, 0) = 3.0e38f;
        const std::string path = file("round" + std::to_string(c) + ".exr");
        prt::writeExr(path, img);
        const Image back = prt::readImage(path);
        ASSERT_EQ(back.width, img.width);
        ASSERT_EQ(back.height, img.height);
        ASSERT_EQ(back.channels, img.channels);
        for (size_t k = 0; k < img.pixels.size(); ++k)
            ASSERT_EQ(back.pixels[k], img.pixels[k]) << "channels " << c << " value " << k;
    }
}

TEST_F(ImageIoTest, ExrHalfRoundTripWithinHalfPrecision) {
    const Image img = randomImage(16, 8, 3, 0.0f, 100.0f, 3u);
    const std::string path = file("half.exr");
    prt::writeExr(path, img, prt::ExrPixelType::Half);
    const Image back = prt::readImage(path);
    ASSERT_EQ(back.pixels.size(), img.pixels.size());
    for (size_t k = 0; k < img.pixels.size(); ++k)
        EXPECT_NEAR(back.pixels[k], img.pixels[k], std::abs(img.pixels[k]) * 1e-3 + 1e-6);
}

TEST_F(ImageIoTest, PngRoundTripWithinOneLevel) {
    const Image img = randomImage(40, 30, 3, 0.0f, 1.0f, 11u);
    const std::string path = file("round.png");
    prt::writePng(path, img);
    const Image back = prt::readImage(path);
    ASSERT_EQ(back.width, 40);
    ASSERT_EQ(back.height, 30);
    ASSERT_EQ(back.channels, 3);
    for (size_t k = 0; k < img.pixels.size(); ++k) {
        const float encoded = prt::linearToSrgb(img.pixels[k]);
        // Stored values are the nearest of the 256 levels of the sRGB encoding...
        EXPECT_NEAR(back.pixels[k], encoded, 0.5f / 255.0f + 1e-6f);
        // ...so in sRGB space the round trip is within 1/255 after decoding and
        // re-encoding, and in linear space within one level's worth of the decode slope.
        EXPECT_NEAR(prt::linearToSrgb(prt::srgbToLinear(back.pixels[k])), encoded, 1.0f / 255.0f);
        EXPECT_NEAR(prt::srgbToLinear(back.pixels[k]), img.pixels[k], 2.5f / 255.0f);
    }
}

TEST_F(ImageIoTest, PngExposureClampAndChannels) {
    Image img(4, 1, 1);
    img.pixels = {0.25f, 2.0f, -1.0f, std::nanf("")};
    const std::string path = file("gray.png");
    prt::writePng(path, img, 1.0);  // x 2
    const Image back = prt::readImage(path);
    ASSERT_EQ(back.channels, 3);  // gray replicated to RGB
    const float expect[4] = {std::round(prt::linearToSrgb(0.5f) * 255) / 255, 1.0f, 0.0f, 0.0f};
    for (int x = 0; x < 4; ++x)
        for (int c = 0; c < 3; ++c) EXPECT_NEAR(back.at(x, 0, c), expect[x], 1e-6) << x << c;

    Image rgba(2, 1, 4);
    rgba.pixels = {1, 0, 0, 0.5f, 0, 0, 1, 0};
    prt::writePng(file("rgba.png"), rgba);
    const Image back4 = prt::readImage(file("rgba.png"));
    ASSERT_EQ(back4.channels, 3);  // alpha dropped
    EXPECT_FLOAT_EQ(back4.at(0, 0, 0), 1.0f);
    EXPECT_FLOAT_EQ(back4.at(1, 0, 2), 1.0f);
}

TEST_F(ImageIoTest, NoTemporaryFilesAfterSuccess) {
    const Image img = randomImage(8, 8, 3, 0.0f, 1.0f, 1u);
    prt::writeExr(file("a.exr"), img);
    prt::writePng(file("b.png"), img);
    prt::writeExr(file("a.exr"), img);  // overwrite
    EXPECT_EQ(entries(), (std::vector<std::string>{"a.exr", "b.png"}));
}

TEST_F(ImageIoTest, FailedWriteIntoDirectoryTargetLeavesNothingBehind) {
    // The target is a (non-empty) directory: refused, nothing written, the directory kept.
    fs::create_directories(dir_ / "target.exr");
    std::ofstream(dir_ / "target.exr" / "keep.txt") << "keep";
    const Image img = randomImage(8, 8, 3, 0.0f, 1.0f, 2u);
    expectErrorNaming(file("target.exr"), [&] { prt::writeExr(file("target.exr"), img); });
    expectErrorNaming(file("target.exr"), [&] { prt::writePng(file("target.exr"), img); });
    EXPECT_EQ(entries(), (std::vector<std::string>{"target.exr"}));
    EXPECT_TRUE(fs::exists(dir_ / "target.exr" / "keep.txt"));
}

TEST_F(ImageIoTest, FailedOverwriteKeepsOldFile) {
    const Image good = randomImage(8, 4, 3, 0.0f, 10.0f, 5u);
    const std::string path = file("good.exr");
    prt::writeExr(path, good);
    const auto oldSize = fs::file_size(path);

    // An inconsistent image is refused before anything is written.
    Image bad(8, 4, 3);
    bad.pixels.resize(5);
    expectErrorNaming(path, [&] { prt::writeExr(path, bad); });
    expectErrorNaming(path, [&] { prt::writePng(path, bad); });
    // An empty image too.
    expectErrorNaming(path, [&] { prt::writeExr(path, Image()); });

    EXPECT_EQ(entries(), (std::vector<std::string>{"good.exr"}));
    EXPECT_EQ(fs::file_size(path), oldSize);
    const Image back = prt::readImage(path);
    EXPECT_EQ(back.pixels, good.pixels);
}

// A full disk (RLIMIT_FSIZE, SIGXFSZ ignored) while writing a small EXR or PNG: the
// error names the file and the reason, the old file survives, no temporary is left.
// Before images were encoded in memory, OpenEXR's writer missed the failure of its
// final flush and a truncated 1024-byte EXR replaced the old file.
TEST_F(ImageIoTest, DiskFullKeepsTheOldImage) {
    const Image old = randomImage(8, 4, 3, 0.0f, 1.0f, 7u);
    const Image big = randomImage(64, 32, 3, 0.0f, 1.0f, 8u);  // ~25 KB as float EXR, ~6 KB as PNG
    for (const char* name : {"full.exr", "full.png"}) {
        SCOPED_TRACE(name);
        const std::string path = file(name);
        const bool exr = std::string(name).ends_with(".exr");
        exr ? prt::writeExr(path, old) : prt::writePng(path, old);
        const std::string before = [&] {
            std::ifstream in(path, std::ios::binary);
            return std::string(std::istreambuf_iterator<char>(in), {});
        }();
        struct rlimit saved {};
        ASSERT_EQ(getrlimit(RLIMIT_FSIZE, &saved), 0);
        auto oldHandler = std::signal(SIGXFSZ, SIG_IGN);
        struct rlimit small = saved;
        small.rlim_cur = 1024;
        ASSERT_EQ(setrlimit(RLIMIT_FSIZE, &small), 0);
        std::string message;
        try {
            exr ? prt::writeExr(path, big) : prt::writePng(path, big);
        } catch (const prt::Error& e) {
            message = e.what();
        }
        ASSERT_EQ(setrlimit(RLIMIT_FSIZE, &saved), 0);
        std::signal(SIGXFSZ, oldHandler);
        EXPECT_NE(message.find(path), std::string::npos) << message;
        EXPECT_NE(message.find("File too large"), std::string::npos) << message;
        std::ifstream in(path, std::ios::binary);
        EXPECT_EQ(std::string(std::istreambuf_iterator<char>(in), {}), before);
    }
    EXPECT_EQ(entries(), (std::vector<std::string>{"full.exr", "full.png"}));
}

TEST_F(ImageIoTest, MissingDirectoryIsAnErrorAndNotCreated) {
    const Image img = randomImage(4, 4, 3, 0.0f, 1.0f, 6u);
    const std::string path = file("no/such/dir/out.exr");
    expectErrorNaming(path, [&] { prt::writeExr(path, img); });
    expectErrorNaming(file("nodir/out.png"), [&] { prt::writePng(file("nodir/out.png"), img); });
    EXPECT_TRUE(entries().empty());
    // A path component that is a regular file, not a directory.
    std::ofstream(dir_ / "plain") << "x";
    expectErrorNaming(file("plain/out.exr"), [&] { prt::writeExr(file("plain/out.exr"), img); });
    EXPECT_EQ(entries(), (std::vector<std::string>{"plain"}));
}

TEST_F(ImageIoTest, ReadErrorsNameThePath) {
    expectErrorNaming(file("missing.exr"), [&] { prt::readImage(file("missing.exr")); });
    expectErrorNaming(dir_.string(), [&] { prt::readImage(dir_.string()); });

    std::ofstream(dir_ / "garbage.exr") << "this is not an OpenEXR file at all, just text";
    expectErrorNaming(file("garbage.exr"), [&] { prt::readImage(file("garbage.exr")); });
    std::ofstream(dir_ / "garbage.png") << "\x89PNG but then nonsense";
    expectErrorNaming(file("garbage.png"), [&] { prt::readImage(file("garbage.png")); });
    std::ofstream(dir_ / "unknown.xyz123") << "who knows";
    expectErrorNaming(file("unknown.xyz123"), [&] { prt::readImage(file("unknown.xyz123")); });

    // A truncated EXR.
    prt::writeExr(file("whole.exr"), randomImage(64, 64, 3, 0.0f, 1.0f, 9u));
    const auto size = fs::file_size(file("whole.exr"));
    fs::copy_file(file("whole.exr"), file("cut.exr"));
    fs::resize_file(file("cut.exr"), size / 2);
    expectErrorNaming(file("cut.exr"), [&] { prt::readImage(file("cut.exr")); });
}

// A small file whose header claims a huge image: refused up front when the claim
// exceeds the available memory, otherwise failing at its first missing rows (rows are
// read in strips, the buffer grows with them; the fuzzer found claims that made
// readImage allocate gigabytes before reading a byte).
TEST_F(ImageIoTest, HugeHeaderClaimsFailWithoutAllocatingTheClaim) {
    std::ofstream(dir_ / "absurd.hdr") << "#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 1000000 +X 2000000\n\x02\x02";
    try {
        prt::readImage(file("absurd.hdr"));
        ADD_FAILURE() << "expected an error";
    } catch (const prt::Error& e) {
        EXPECT_NE(std::string(e.what()).find("at most 65536 pixels a side"), std::string::npos) << e.what();
    }
    // 50 GB claimed within the side limit: refused against the available memory (or, on
    // a machine with more, at the first missing rows), never allocated whole.
    std::ofstream(dir_ / "big.hdr") << "#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 65000 +X 65000\n\x02\x02";
    try {
        prt::readImage(file("big.hdr"));
        ADD_FAILURE() << "expected an error";
    } catch (const prt::Error& e) {
        const std::string what = e.what();
        EXPECT_TRUE(what.find("available") != std::string::npos || what.find("cannot read pixels") != std::string::npos)
            << what;
    }
    // 1.2 GB claimed, 60 bytes present.
    std::ofstream(dir_ / "claim.hdr") << "#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 5000 +X 20000\n\x02\x02";
    try {
        prt::readImage(file("claim.hdr"));
        ADD_FAILURE() << "expected an error";
    } catch (const prt::Error& e) {
        EXPECT_NE(std::string(e.what()).find("cannot read pixels"), std::string::npos) << e.what();
    }
}

// Tiled EXRs (a size that is not a multiple of the tile, a data window off the origin)
// read as the scanline path does.
TEST_F(ImageIoTest, TiledExrReadsLikeScanlines) {
    const Image img = randomImage(37, 21, 3, 0.0f, 4.0f, 12u);
    const std::string path = file("tiled.exr");
    {
        OIIO::ImageSpec spec(img.width, img.height, img.channels, OIIO::TypeDesc::FLOAT);
        spec.tile_width = 16;
        spec.tile_height = 8;
        spec.x = 3;
        spec.y = -5;
        auto out = OIIO::ImageOutput::create(path);
        ASSERT_TRUE(out);
        ASSERT_TRUE(out->open(path, spec));
        ASSERT_TRUE(out->write_image(OIIO::TypeDesc::FLOAT, img.pixels.data()));
        ASSERT_TRUE(out->close());
    }
    const Image back = prt::readImage(path);
    EXPECT_EQ(back.width, img.width);
    EXPECT_EQ(back.height, img.height);
    EXPECT_EQ(back.pixels, img.pixels);
}

TEST_F(ImageIoTest, ReadsRadianceHdr) {
    // A Radiance .hdr written directly with OpenImageIO (RGBE, ~1% precision).
    const Image img = randomImage(6, 3, 3, 0.01f, 50.0f, 4u);
    const std::string path = file("x.hdr");
    {
        auto out = OIIO::ImageOutput::create(path);
        ASSERT_TRUE(out);
        ASSERT_TRUE(out->open(path, OIIO::ImageSpec(6, 3, 3, OIIO::TypeDesc::FLOAT)));
        ASSERT_TRUE(out->write_image(OIIO::TypeDesc::FLOAT, img.pixels.data()));
        ASSERT_TRUE(out->close());
    }
    const Image back = prt::readImage(path);
    ASSERT_EQ(back.width, 6);
    ASSERT_EQ(back.height, 3);
    ASSERT_EQ(back.channels, 3);
    for (size_t k = 0; k < img.pixels.size(); ++k) {
        // RGBE shares one exponent per pixel: error relative to the pixel's largest value.
        const size_t p = k / 3 * 3;
        const float maxc = std::max({img.pixels[p], img.pixels[p + 1], img.pixels[p + 2]});
        EXPECT_NEAR(back.pixels[k], img.pixels[k], maxc * 0.01f) << k;
    }
}

TEST(Image, OutputPrefixDropsAnImageExtension) {
    EXPECT_EQ(prt::outputPrefix("out/frame.exr"), "out/frame");
    EXPECT_EQ(prt::outputPrefix("out/frame.PNG"), "out/frame");
    EXPECT_EQ(prt::outputPrefix("out/frame"), "out/frame");
    EXPECT_EQ(prt::outputPrefix("out/frame.tif"), "out/frame.tif");
    EXPECT_EQ(prt::outputPrefix(".exr"), ".exr");  // nothing would be left of the name
    EXPECT_EQ(prt::outputPrefix("a.exr"), "a");
}
