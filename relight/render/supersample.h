#pragma once
// Anti-aliased offline frames (--spp N of prt-relight render, prt-pointlight and
// prt-reference; docs/relight.md, "Anti-aliasing"). N = n^2 sub-pixel samples per
// pixel on the regular n x n grid of strata of the pixel, each at its stratum's centre
// (stratified, without jitter, so frames are deterministic and an N-sample frame
// refines the same strata at every resolution), reconstructed with a box filter over
// the pixel: a pixel is the mean of its n^2 samples.
//
// It works on whole frames: a renderer draws the frame seen by supersampledCamera (n
// times the width and height, the same eye, target and field of view, so its pixel
// centres are exactly the sub-pixel samples), and boxDownsample averages each n x n
// block. Every renderer therefore anti-aliases without change, at n^2 times the
// per-pixel cost; light-dependent work done once per frame (light vectors, irradiance,
// caches of the object) is not repeated.
//
// Channels are averaged alike: RGB radiance (linear) and alpha, which becomes the
// pixel's coverage (the fraction of its samples on the object). prt-compare's object
// pixels (A > 0.5) are then the pixels more than half covered: compare a test and a
// reference rendered at the same N (docs/relight.md says which figures do).

#include <string>

#include "common/camera.h"
#include "common/image.h"

namespace prt {

inline constexpr int kMaxSamplesPerPixel = 256;

// n for N samples per pixel. Throws prt::Error("--spp", ...) unless N is a square
// number in [1, kMaxSamplesPerPixel].
int subpixelGridSize(int samplesPerPixel);

// `camera` with n times the width and height. Throws prt::Error("--spp", ...) when the
// result would exceed kMaxCameraSide pixels a side (common/camera.h).
Camera supersampledCamera(const Camera& camera, int n);

// The mean of every n x n block: a (width / n) x (height / n) image with the same
// channels. n = 1 returns the image unchanged. Throws prt::Error("boxDownsample", ...)
// when n < 1 or the size is not a multiple of n. Non-finite samples make the pixel
// non-finite (nothing is hidden).
Image boxDownsample(const Image& image, int n);

// An ImageWriter that box-downsamples every image by n before passing it to `target`
// (what prt-pointlight and prt-reference write through at --spp N).
class DownsamplingImageWriter : public ImageWriter {
public:
    DownsamplingImageWriter(ImageWriter& target, int n) : target_(target), n_(n) {}
    void exr(const std::string& path, const Image& image) override;
    void png(const std::string& path, const Image& image, const DisplayTransform* display = nullptr) override;

private:
    ImageWriter& target_;
    int n_;
};

}  // namespace prt
