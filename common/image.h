#pragma once
// Float images and the project's image I/O (all through OpenImageIO).
//
// An Image is width x height pixels of `channels` interleaved floats, row-major,
// top row first: the value of channel c of pixel (x, y) is
// pixels[(y * width + x) * channels + c].
//
// Reading converts any format OpenImageIO understands (EXR, HDR, PNG, TIFF, ...) to
// float with the file's own values: 8/16-bit integer formats are scaled to [0, 1]
// but NOT linearised (a PNG comes back sRGB-encoded; use srgbToLinear).
//
// Writing is atomic: the image goes to a temporary file in the target's directory,
// "<stem>.tmp<pid>-<n><ext>" (the real extension stays last), which is renamed over
// the target only once it is complete. On any failure the temporary file is removed,
// an existing target is left untouched and prt::Error(path, reason) is thrown. Parent
// directories are never created: a missing directory is an error.

#include <cstddef>
#include <string>
#include <vector>

namespace prt {

struct DisplayTransform;  // common/tonemap.h

struct Image {
    int width = 0;
    int height = 0;
    int channels = 0;
    std::vector<float> pixels;  // row-major, top row first, channels interleaved

    Image() = default;
    // Throws prt::Error for negative sizes; all pixels are set to `value`.
    Image(int width, int height, int channels, float value = 0.0f);

    bool empty() const { return width <= 0 || height <= 0 || channels <= 0; }
    // True when pixels.size() == width * height * channels (and sizes are >= 0).
    bool consistent() const;

    size_t index(int x, int y, int c) const {
        return (size_t(y) * size_t(width) + size_t(x)) * size_t(channels) + size_t(c);
    }
    float& at(int x, int y, int c) { return pixels[index(x, y, c)]; }
    const float& at(int x, int y, int c) const { return pixels[index(x, y, c)]; }
    float* pixel(int x, int y) { return &pixels[index(x, y, 0)]; }
    const float* pixel(int x, int y) const { return &pixels[index(x, y, 0)]; }
};

// Reads the first subimage (top MIP level) of any file OpenImageIO can read, all
// channels, as float: the stored pixels (data window), any display-window offset
// ignored. Unassociated alpha is kept as stored (no premultiplication).
// Throws prt::Error(path, reason) for a missing file, a directory, an unknown or
// corrupt format, deep or volume images, more than kMaxImageSide pixels a side or 64
// channels, and a header claiming more pixels than the available memory.
inline constexpr int kMaxImageSide = 65536;
Image readImage(const std::string& path);

enum class ExrPixelType { Float, Half };

// Writes a linear OpenEXR file (ZIP compression, lossless). Channel names: 1 -> Y,
// 2 -> Y A, 3 -> R G B, 4 -> R G B A, more -> R G B A channel4 ... The file is EXR
// whatever the extension of `path`. Atomic (see above).
void writeExr(const std::string& path, const Image& image,
              ExrPixelType pixelType = ExrPixelType::Float);

// Writes an 8-bit RGB PNG for display: each pixel goes through the display transform
// (common/tonemap.h: 2^exposure, the operator, display-linear [0, 1]), is encoded
// with the sRGB transfer function (linearToSrgb) and rounded to the nearest of 256
// levels. Channels 0-2 are used (alpha and extra channels dropped); 1- and 2-channel
// images are shown as gray (channel 0 replicated). The file is PNG whatever the
// extension. Atomic (see above). Throws prt::Error(path, ...) for a non-finite exposure.
void writePng(const std::string& path, const Image& image, const DisplayTransform& display);
// The clamp operator at this exposure.
void writePng(const std::string& path, const Image& image, double exposureStops = 0.0);

// Where a command's images go (runPointLightCommand, runReferenceCommand): files for
// the command-line tools (FileImageWriter: writeExr / writePng), memory for the Python
// module. `path` is the file the tool would write.
class ImageWriter {
public:
    virtual ~ImageWriter() = default;
    virtual void exr(const std::string& path, const Image& image) = 0;
    // `display` null: the clamp operator at exposure 0 (images already meant for display).
    virtual void png(const std::string& path, const Image& image, const DisplayTransform* display = nullptr) = 0;
};

class FileImageWriter : public ImageWriter {
public:
    void exr(const std::string& path, const Image& image) override { writeExr(path, image); }
    void png(const std::string& path, const Image& image, const DisplayTransform* display = nullptr) override;
};

// An output prefix as the tools take it (they write <prefix>.exr and <prefix>.png):
// `path` without a trailing ".exr" or ".png" (any case), so "-o frame.exr" writes
// frame.exr and frame.png rather than frame.exr.exr.
std::string outputPrefix(const std::string& path);

// The exact piecewise sRGB transfer functions (IEC 61966-2-1):
// encode: 12.92 x for x <= 0.0031308, else 1.055 x^(1/2.4) - 0.055;
// decode: x / 12.92 for x <= 0.04045, else ((x + 0.055) / 1.055)^2.4.
// Inputs are not clamped (negative inputs stay on the linear segment).
float linearToSrgb(float linear);
float srgbToLinear(float encoded);

}  // namespace prt
