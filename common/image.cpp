#include "common/image.h"
#include "common/tonemap.h"

#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/imageio.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <system_error>

#include "common/atomic_file.h"
#include "common/error.h"
#include "common/util.h"

namespace prt {

namespace fs = std::filesystem;

Image::Image(int w, int h, int c, float value) : width(w), height(h), channels(c) {
    if (w < 0 || h < 0 || c < 0)
        throw Error("image", "invalid size " + std::to_string(w) + " x " + std::to_string(h) +
                                 " x " + std::to_string(c) + " channels");
    pixels.assign(size_t(w) * size_t(h) * size_t(c), value);
}

bool Image::consistent() const {
    return width >= 0 && height >= 0 && channels >= 0 &&
           pixels.size() == size_t(width) * size_t(height) * size_t(channels);
}

float linearToSrgb(float linear) {
    if (linear <= 0.0031308f) return 12.92f * linear;
    return float(1.055 * std::pow(double(linear), 1.0 / 2.4) - 0.055);
}

float srgbToLinear(float encoded) {
    if (encoded <= 0.04045f) return encoded / 12.92f;
    return float(std::pow((double(encoded) + 0.055) / 1.055, 2.4));
}

namespace {

// OpenImageIO's error text on one line.
std::string oiioMessage(const std::string& text) {
    const std::string line = oneLine(text);
    return line.empty() ? "unknown OpenImageIO error" : line;
}

void checkWritable(const std::string& path, const Image& image) {
    if (path.empty()) throw Error("image", "empty output path");
    if (!image.consistent())
        throw Error(path, "image has " + std::to_string(image.pixels.size()) +
                              " values, expected width * height * channels = " +
                              std::to_string(image.width) + " * " + std::to_string(image.height) +
                              " * " + std::to_string(image.channels));
    if (image.empty())
        throw Error(path, "cannot write an empty image (" + std::to_string(image.width) + " x " +
                              std::to_string(image.height) + " x " +
                              std::to_string(image.channels) + ")");
}

// Writes `data` (described by dataType, spec's layout) through OpenImageIO's
// `formatName` writer, all or nothing (writeAtomically).
void writeImageAtomically(const std::string& path, const char* formatName, const OIIO::ImageSpec& spec,
                          OIIO::TypeDesc dataType, const void* data) {
    // The image is encoded in memory, then written by writeFileAtomically, whose every
    // write and close is checked: OpenImageIO's file writers can miss a failure (a full
    // disk while OpenEXR flushes a small file left a truncated EXR renamed over the
    // target, tests/bad_inputs_test.sh "disk full: envcheck cubemap").
    std::vector<unsigned char> bytes;
    OIIO::Filesystem::IOVecOutput proxy(bytes);
    auto out = OIIO::ImageOutput::create(formatName);
    if (!out) throw Error(path, "no " + std::string(formatName) + " writer: " + oiioMessage(OIIO::geterror()));
    if (!out->supports("ioproxy")) throw Error(path, std::string(formatName) + " writer cannot encode to memory");
    if (!out->set_ioproxy(&proxy)) throw Error(path, "cannot encode: " + oiioMessage(out->geterror()));
    if (!out->open(path, spec)) throw Error(path, "cannot encode: " + oiioMessage(out->geterror()));
    if (!out->write_image(dataType, data)) {
        const std::string why = oiioMessage(out->geterror());
        out->close();
        throw Error(path, "cannot encode: " + why);
    }
    if (!out->close()) throw Error(path, "cannot encode: " + oiioMessage(out->geterror()));
    writeFileAtomically(path, std::string_view(reinterpret_cast<const char*>(bytes.data()), bytes.size()));
}

}  // namespace

Image readImage(const std::string& path) {
    std::error_code ec;
    const fs::file_status status = fs::status(path, ec);
    if (!fs::exists(status)) throw Error(path, "file does not exist");
    if (fs::is_directory(status)) throw Error(path, "is a directory, not an image file");

    OIIO::ImageSpec config;
    config.attribute("oiio:UnassociatedAlpha", 1);
    auto in = OIIO::ImageInput::open(path, &config);
    if (!in) throw Error(path, "cannot read image: " + oiioMessage(OIIO::geterror()));

    const OIIO::ImageSpec& spec = in->spec();
    if (spec.deep) throw Error(path, "deep images are not supported");
    if (spec.depth > 1) throw Error(path, "volume images are not supported");
    if (spec.width <= 0 || spec.height <= 0 || spec.nchannels <= 0)
        throw Error(path, "image has no pixels");

    const int w = spec.width, h = spec.height, c = spec.nchannels;
    // No environment or frame of ours comes near 65536 pixels a side, and OpenImageIO's
    // EXR reader buffers many scanlines at once: a corrupt header claiming 14 million
    // columns makes it allocate 59 GB for one strip
    // (tools/fuzz/crashes/environment/oiio-exr-huge-width-oom).
    if (w > kMaxImageSide || h > kMaxImageSide || c > 64)
        throw Error(path, "the header declares " + std::to_string(w) + " x " + std::to_string(h) + " pixels of " +
                              std::to_string(c) + " channels; at most " + std::to_string(kMaxImageSide) +
                              " pixels a side and 64 channels are supported (corrupt header?)");
    const double bytes = double(w) * double(h) * double(c) * sizeof(float);
    const uint64_t available = availableMemoryBytes();
    if (available > 0 && bytes > double(available))
        throw Error(path, "the header declares " + std::to_string(w) + " x " + std::to_string(h) + " x " +
                              std::to_string(c) + " pixels, which need " + formatBytes(uint64_t(bytes)) + ", " +
                              formatBytes(available) + " available");

    // Rows are read in strips of about 16 MB and the buffer grows with them, so a small
    // corrupt file whose header claims a huge image fails at its first missing rows
    // instead of allocating the whole claim first (docs/reliability.md, "Fuzzing").
    Image image;
    image.width = w;
    image.height = h;
    image.channels = c;
    const size_t row = size_t(w) * size_t(c);
    const int unit = spec.tile_width > 0 ? std::max(1, spec.tile_height) : 1;
    const int strip = unit * std::max<int>(1, int(std::min<size_t>(size_t(h), (size_t(1) << 22) / row) / size_t(unit)));
    for (int y0 = 0; y0 < h; y0 += strip) {
        const int y1 = std::min(h, y0 + strip);
        image.pixels.resize(row * size_t(y1));
        float* dst = image.pixels.data() + row * size_t(y0);
        const bool ok = spec.tile_width > 0
                            ? in->read_tiles(0, 0, spec.x, spec.x + w, spec.y + y0, spec.y + y1, spec.z, spec.z + 1, 0, c,
                                             OIIO::TypeDesc::FLOAT, dst)
                            : in->read_scanlines(0, 0, spec.y + y0, spec.y + y1, spec.z, 0, c, OIIO::TypeDesc::FLOAT, dst);
        if (!ok) {
            const std::string reason = oiioMessage(in->geterror());
            in->close();
            throw Error(path, "cannot read pixels: " + reason);
        }
    }
    in->close();
    return image;
}

void writeExr(const std::string& path, const Image& image, ExrPixelType pixelType) {
    checkWritable(path, image);
    OIIO::ImageSpec spec(image.width, image.height, image.channels,
                         pixelType == ExrPixelType::Half ? OIIO::TypeDesc::HALF
                                                         : OIIO::TypeDesc::FLOAT);
    if (image.channels == 1) {
        spec.channelnames = {"Y"};
    } else if (image.channels == 2) {
        spec.channelnames = {"Y", "A"};
        spec.alpha_channel = 1;
    }
    spec.attribute("compression", "zip");
    writeImageAtomically(path, "openexr", spec, OIIO::TypeDesc::FLOAT, image.pixels.data());
}

void writePng(const std::string& path, const Image& image, const DisplayTransform& display) {
    checkWritable(path, image);
    if (!std::isfinite(display.exposureStops)) throw Error(path, "exposure must be finite");
    const Image shown = displayImage(image, displayMapping(image, display));

    const size_t count = size_t(image.width) * size_t(image.height);
    std::vector<std::uint8_t> rgb(count * 3);
    for (size_t i = 0; i < count * 3; ++i)
        rgb[i] = std::uint8_t(std::clamp(std::lround(double(linearToSrgb(shown.pixels[i])) * 255.0), 0L, 255L));

    OIIO::ImageSpec spec(image.width, image.height, 3, OIIO::TypeDesc::UINT8);
    spec.attribute("oiio:ColorSpace", "sRGB");
    writeImageAtomically(path, "png", spec, OIIO::TypeDesc::UINT8, rgb.data());
}

void writePng(const std::string& path, const Image& image, double exposureStops) {
    writePng(path, image, DisplayTransform{exposureStops, ToneMapOperator::Clamp});
}

void FileImageWriter::png(const std::string& path, const Image& image, const DisplayTransform* display) {
    writePng(path, image, display ? *display : DisplayTransform{});
}

std::string outputPrefix(const std::string& path) {
    if (path.size() > 4) {
        const std::string ext = toLower(path.substr(path.size() - 4));
        if (ext == ".exr" || ext == ".png") return path.substr(0, path.size() - 4);
    }
    return path;
}

}  // namespace prt
