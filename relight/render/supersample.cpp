// Anti-aliased offline frames: see supersample.h.

#include "relight/render/supersample.h"

#include <algorithm>
#include <cmath>

#include "common/error.h"

namespace prt {

int subpixelGridSize(int samplesPerPixel) {
    const int n = int(std::lround(std::sqrt(double(std::max(samplesPerPixel, 0)))));
    if (samplesPerPixel < 1 || samplesPerPixel > kMaxSamplesPerPixel || n * n != samplesPerPixel)
        throw Error("--spp", "must be a square number of samples per pixel from 1 to " +
                                 std::to_string(kMaxSamplesPerPixel) + " (1, 4, 9, 16, ...), not " +
                                 std::to_string(samplesPerPixel));
    return n;
}

Camera supersampledCamera(const Camera& camera, int n) {
    if (n < 1) throw Error("--spp", "the sub-pixel grid must be at least 1 x 1");
    if (double(camera.width) * n > kMaxCameraSide || double(camera.height) * n > kMaxCameraSide)
        throw Error("--spp", "the supersampled frame (" + std::to_string(camera.width) + " x " +
                                 std::to_string(camera.height) + " times " + std::to_string(n) +
                                 ") exceeds " + std::to_string(kMaxCameraSide) + " pixels a side");
    Camera c = camera;
    c.width = camera.width * n;
    c.height = camera.height * n;
    return c;
}

Image boxDownsample(const Image& image, int n) {
    if (n < 1) throw Error("boxDownsample", "the factor must be at least 1");
    if (n == 1) return image;
    if (image.width % n != 0 || image.height % n != 0)
        throw Error("boxDownsample", std::to_string(image.width) + " x " + std::to_string(image.height) +
                                         " is not a multiple of " + std::to_string(n));
    Image out(image.width / n, image.height / n, image.channels);
    const double weight = 1.0 / double(n * n);
    for (int y = 0; y < out.height; ++y)
        for (int x = 0; x < out.width; ++x)
            for (int c = 0; c < image.channels; ++c) {
                double sum = 0.0;
                for (int j = 0; j < n; ++j)
                    for (int i = 0; i < n; ++i) sum += double(image.at(x * n + i, y * n + j, c));
                out.at(x, y, c) = float(sum * weight);
            }
    return out;
}

void DownsamplingImageWriter::exr(const std::string& path, const Image& image) {
    target_.exr(path, boxDownsample(image, n_));
}

void DownsamplingImageWriter::png(const std::string& path, const Image& image, const DisplayTransform* display) {
    target_.png(path, boxDownsample(image, n_), display);
}

}  // namespace prt
