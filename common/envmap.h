#pragma once
// HDR environment maps: lat-long (equirectangular) images, their conversion to
// cubemaps with area-correct filtering, rotation, and generated test environments.
//
// Lat-long convention (SPEC section 4, docs/conventions.md). World frame right-handed,
// +Y up. For a unit direction d:
//   u = 0.5 + atan2(d.x, -d.z) / (2 pi)   in [0, 1)
//   v = acos(d.y) / pi                    in [0, 1]
// v = 0 is the top row (+Y), v = 1 the bottom row (-Y). The image centre
// (u, v) = (0.5, 0.5) is -Z, u = 0.75 is +X, u = 0.25 is -X, u = 0 (= 1, the left and
// right edges) is +Z. Pixel (x, y) of a W x H map has its centre at
// u = (x + 0.5) / W, v = (y + 0.5) / H and covers u in [x/W, (x+1)/W],
// v in [y/H, (y+1)/H], i.e. the exact solid angle (2 pi / W) (cos(pi y/H) - cos(pi (y+1)/H)).
//
// A lat-long map is treated as piecewise constant over its pixels (box
// reconstruction): that is what latLongIntegral integrates and what latLongToCubemap
// averages over each cube texel.
//
// Rotation convention: rotating the environment by R gives the environment
// L'(d) = L(R^T d), i.e. the environment turns with R: whatever was seen in direction
// d0 is afterwards seen in direction R d0. rotationY(90) turns -Z into -X (a sun at
// -Z ends up at -X) and +X into -Z (right-handed rotation about +Y).

#include <glm/glm.hpp>

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "common/cubemap.h"
#include "common/image.h"

namespace prt {

// Direction (unit) for lat-long coordinates (u, v); u may be any real (periodic).
glm::dvec3 latLongToDirection(double u, double v);
// Lat-long coordinates of direction d (need not be normalised, must be non-zero);
// u in [0, 1), v in [0, 1].
glm::dvec2 directionToLatLong(const glm::dvec3& d);
// Unit direction through the centre of pixel (x, y) of a width x height lat-long map.
glm::dvec3 latLongPixelDirection(int x, int y, int width, int height);
// Exact solid angle of any pixel in row y of a width x height lat-long map.
double latLongPixelSolidAngle(int y, int width, int height);

// Integral over the sphere of channel c, sum over pixels of L * exact pixel solid angle.
double latLongIntegral(const Image& latlong, int c);

enum class NonFinitePolicy {
    Reject,         // throw prt::Error(path, "pixel (x, y) is NaN in channel R ...")
    ClampNegative,  // reject NaN and Inf as above, but replace negative values by 0 and
                    // prt::warn their count: real maps often hold small negatives from
                    // resampling (docs/conventions.md, "Lat-long").
    Clamp,          // NaN, -Inf, negatives -> 0; +Inf -> largest finite value of that
                    // channel (0 if none); prt::warn with the number of values replaced
};

// Reads a lat-long environment (any format readImage supports) as 3-channel RGB float:
// channels beyond the third (alpha, ...) are dropped, gray (1 channel, or gray +
// alpha) is replicated to RGB. Requires width == 2 * height. Rejects (or, as the
// policy says, repairs) NaN, infinite and negative values. Errors are
// prt::Error(path, ...).
Image loadEnvironment(const std::string& path,
                      NonFinitePolicy policy = NonFinitePolicy::Reject);

// The NaN / Inf / negative check of loadEnvironment, for images from elsewhere;
// `subject` names the image in messages. Returns the number of values replaced.
size_t checkEnvironmentValues(Image& image, const std::string& subject, NonFinitePolicy policy);

// Right-handed rotations by `degrees` about +X, +Y, +Z, and about an arbitrary axis
// (need not be normalised, must be non-zero). Use them as the `rotation` below.
glm::dmat3 rotationX(double degrees);
glm::dmat3 rotationY(double degrees);
glm::dmat3 rotationZ(double degrees);
glm::dmat3 rotationAxisAngle(const glm::dvec3& axis, double degrees);

// True when `rotation` is a rotation about +Y, i.e. equals rotationY(degrees) entry by
// entry within 1e-12 for the degrees it then stores (in [-180, 180]). Products of
// rotationY matrices qualify; anything else leaves `degrees` untouched.
bool rotationAboutY(const glm::dmat3& rotation, double& degrees);

// Cubemap of face size n (power of two) with one channel per lat-long channel (RGB
// for loadEnvironment's maps), of the environment rotated by `rotation`
// (L'(d) = L(R^T d)). Area-correct: each texel holds the average of the
// (piecewise-constant) lat-long radiance over the texel's exact solid angle.
//
// Method (exact box filtering up to rounding): each lat-long pixel, split into
// sub-cells of at most 1/128 radian when it is larger, carries its exact solid
// angle dphi (cos theta0 - cos theta1). A cell whose four corners fall in one texel
// goes to that texel whole (texels are convex). A cell straddling texel or face
// borders is clipped, as the geodesic quad through its corners, against the
// great-circle planes of the face and texel borders, and its area is shared in
// proportion to the exact spherical areas of the pieces. A texel's value is the sum of
// radiance * area over what it received divided by the total area it received. So a
// constant map gives an exactly constant cubemap, and the integral over the sphere is
// preserved to ~1e-6 relative; the only approximation is the geodesic-vs-parallel shape
// of a straddling cell, of relative order cell^2. Multithreaded over lat-long rows; the
// result does not depend on the number of threads. Throws prt::Error for an empty or
// inconsistent image or an n that is not a power of two.
//
// This is the reference implementation. For rotations about +Y, LatLongCubemapFilter
// below gives the same cubemap at whole-pixel angles, and a close one between them, far
// faster (docs/relight.md, "Turning the environment: the fast path").
Cubemap latLongToCubemap(const Image& latlong, int n,
                         const glm::dmat3& rotation = glm::dmat3(1.0));

// latLongToCubemap's exact box filter for width x height lat-long maps and n x n faces,
// stored as a sparse matrix (weights depend only on width, height and n, never on the
// image), applied to environments turned by rotationY(degrees).
//
// A rotation about +Y by a whole number k of pixel widths (360 k / width degrees) is a
// cyclic shift of the lat-long columns, and latLongToCubemap's sub-cells are aligned
// with pixel columns, so apply(latlong, 360 k / width) equals
// latLongToCubemap(latlong, n, rotationY(360 k / width)) up to rounding: the weights are
// stored as float (~6e-8 relative each), so each texel agrees to ~1e-7 relative for a
// non-negative map. The one other difference: the rotated exact path's corner
// directions carry ~1e-16 of rounding, so where a column border lies exactly on a texel
// border it leaves slivers of ~1e-14 of a pixel's solid angle in the neighbouring
// texel, which this filter (built at identity) does not; that shows only next to
// pixels ~1e9 times brighter (an absolute difference of ~2e-14 of the brightest texel).
// For a fractional shift k + f (0 < f < 1) apply returns (1 - f) apply(k) + f
// apply(k + 1): the exact box filter of the map linearly interpolated in longitude
// between pixel centres. That keeps the integral over the sphere exactly as
// latLongToCubemap does (~1e-6) but differs from the exact rotated filter by a
// sub-pixel blur (docs/relight.md gives the size on the real maps). Shifts within 1e-9
// pixel of a whole number are taken as whole.
//
// Two ways to apply it, with the same result up to rounding:
// - apply(const Image&, degrees) reads every stored entry (the lat-long pixels a texel
//   receives area from, with float weights). It needs nothing but the image and is the
//   reference for the faster one.
// - apply(const LatLongRowSums&, degrees) reads the environment's row running sums
//   (built once per environment, below). Within one texel and one lat-long row the
//   pixels form runs of consecutive columns whose weights are all equal but perhaps the
//   first and the last (every pixel wholly inside the texel gets the same one), so a run
//   costs the running sums at its two ends instead of one read per pixel, and the blend
//   of a fractional shift is linear in the running sums too. Same float weights, double
//   sums (tests: LatLongFilter.RowSums*); its own rounding: see LatLongRowSums.
//
// Storage: per texel (CSR), the lat-long pixels it receives area from with their
// normalised weights (area received / the texel's total), 8 bytes per entry
// (entryCount()); and the same weights as runs along rows, 20 bytes per run
// (runCount(); all of it in memoryBytes()).
class LatLongRowSums;

class LatLongCubemapFilter {
public:
    static constexpr int kMaxLatLongSize = 65535;          // pixel coordinates are 16-bit
    static constexpr double kIntegerShiftTolerance = 1e-9;  // pixels

    // Builds the filter (multithreaded over rows; deterministic). Throws prt::Error for
    // sizes outside 1 .. kMaxLatLongSize or an n that is not a power of two.
    LatLongCubemapFilter(int width, int height, int n);

    // Cubemap of face size n, one channel per lat-long channel, of `latlong` (width x
    // height, any channel count) turned by rotationY(rotationYDegrees): see above.
    // Multithreaded over texels (the result does not depend on the thread count); for
    // RGB the loop is AVX2 where the CPU has it (the same double sums, so the same
    // cubemap up to the order of the final rounding). Throws prt::Error for an
    // inconsistent or empty image, a size other than the filter's, or a non-finite angle.
    Cubemap apply(const Image& latlong, double rotationYDegrees = 0.0) const;
    // The same cubemap (up to rounding) from the environment's row running sums, in less
    // time (runCount() against entryCount() says how much less). Multithreaded over
    // texels, the result does not depend on the thread count; RGB uses AVX2 where the
    // CPU has it. Throws prt::Error for sums of a size other than the filter's or a
    // non-finite angle.
    Cubemap apply(const LatLongRowSums& sums, double rotationYDegrees = 0.0) const;

    int width() const { return width_; }
    int height() const { return height_; }
    int size() const { return n_; }
    size_t entryCount() const { return entries_.size(); }
    size_t runCount() const { return runs_.size(); }
    size_t memoryBytes() const;

    // The filter for (width, height, n) from a process-wide cache, built on first use.
    // Thread-safe: concurrent callers for the same sizes wait for one build. The cache
    // keeps the 4 most recently used filters (holders keep theirs alive).
    static std::shared_ptr<const LatLongCubemapFilter> shared(int width, int height, int n);

    // One stored weight (public for apply's SIMD loop in envmap.cpp).
    struct Entry {
        std::uint16_t x, y;  // lat-long pixel at rotation identity
        float weight;        // its share of the texel's area (a texel's weights sum to 1)
    };
    // A run of pixels of one row received by one texel (public for the SIMD loop):
    // columns x .. x + len - 1 of row y, x unwrapped (a run crossing the right edge
    // continues past width, column x + width being column x), weights first, then
    // interior for every pixel but the first and the last, then last (a one-pixel run
    // has interior = last = 0, a two-pixel run interior = 0). Its sum is first L(x) +
    // interior (P(x + len - 1) - P(x + 1)) + last L(x + len - 1), each pixel L(x) read as
    // P(x + 1) - P(x), with P the row's running sum: every difference a local sum, so
    // the float weights cost ~6e-8 relative like the entries' own.
    struct Run {
        std::uint32_t x;
        std::uint16_t y, len;
        float first, interior, last;
    };

private:
    // The runs, from the entries and their weights.
    void buildRuns(const std::vector<double>& weights);

    int width_ = 0, height_ = 0, n_ = 0;
    std::vector<std::uint32_t> begin_;  // 6 n^2 + 1 offsets into entries_
    std::vector<Entry> entries_;
    std::vector<std::uint32_t> runBegin_;  // 6 n^2 + 1 offsets into runs_
    std::vector<Run> runs_;
};

// Running sums along the rows of a lat-long map, in double: the per-environment half of
// LatLongCubemapFilter::apply(const LatLongRowSums&, ...). Build it once per environment
// image (one pass over the map) and keep it for as long as the environment is turned;
// it does not refer to the image afterwards.
//
// at(y, j, c) is the sum of channel c over columns 0 .. j - 1 of row y, the row repeated
// periodically (column x + width is column x), for j in [0, 2 width + 1]: two periods, so
// a run of up to width pixels turned by up to width - 1 pixels, plus the fractional
// blend's one more column, reads one contiguous stretch. Memory:
// 8 (2 width + 2) height channels bytes, 25 MB for a 1024 x 512 RGB map (the image:
// 6.3 MB).
//
// Rounding: each sum is exact to ~1e-16 of the row's total, and a texel is a weighted
// sum of differences of them, so it carries an absolute error of ~1e-16 of the totals of
// the rows it covers: relative to the texel, ~1e-16 x row total / texel value, below
// float rounding unless a row holds a sun ~1e8 times brighter than the texel's pixels.
//
// Thread-safe for concurrent readers (immutable after construction). Throws prt::Error
// for an empty or inconsistent image, or a row whose sum is not finite (NaN or infinite
// values, which would spread to every texel reading the row).
class LatLongRowSums {
public:
    explicit LatLongRowSums(const Image& latlong);

    int width() const { return width_; }
    int height() const { return height_; }
    int channels() const { return channels_; }
    double at(int y, int j, int c) const {
        return sums_[(size_t(y) * rowEntries(width_) + size_t(j)) * size_t(channels_) + size_t(c)];
    }
    static size_t rowEntries(int width) { return 2 * size_t(width) + 2; }
    // Row-major: entry j of row y at data() + (y rowEntries + j) channels; followed by
    // 8 zeros of padding (a 4-wide load of the last RGB entry stays inside).
    const double* data() const { return sums_.data(); }
    size_t memoryBytes() const { return sizeof(*this) + sums_.capacity() * sizeof(double); }

private:
    int width_ = 0, height_ = 0, channels_ = 0;
    std::vector<double> sums_;
};

// Lat-long image width x width/2 (width even, >= 2) of the cubemap, bilinearly
// sampled at pixel centres (Cubemap::sampleBilinear). For viewing and debugging.
Image cubemapToLatLong(const Cubemap& cube, int width);

// Horizontal cross, 4N x 3N pixels, unused cells black (0). Each face is drawn as seen
// from the centre of the cube looking out, in our right-handed world with +Y up, so
// the cross folds into a seamless cube and reads like the lat-long map (the middle row
// is the panorama's left-to-right order -X, -Z, +X, +Z):
//
//            +--------+
//            |   +Y   |        up on the page = +Z, right = +X
//            |        |
//   +--------+--------+--------+--------+
//   |   -X   |   -Z   |   +X   |   +Z   |   up = +Y for all four;
//   |        | (front)|        | (back) |   right = -Z, +X, +Z, -X respectively
//   +--------+--------+--------+--------+
//            |   -Y   |        up on the page = -Z, right = +X
//            |        |
//            +--------+
//
// Cell (column, row) in units of N: -X (0,1), -Z (1,1), +X (2,1), +Z (3,1),
// +Y (1,0), -Y (1,2). The +Y cell's bottom edge meets -Z's top edge; the -Y cell's top
// edge meets -Z's bottom edge; +Z's right edge wraps around to -X's left edge.
//
// Relation to OpenGL's face images: a face of an OpenGL cube map drawn with s to the
// right and t downwards is the MIRROR image of what a viewer at the centre of a
// right-handed world sees (OpenGL inherited RenderMan's left-handed cube-map
// convention). Each cell here is therefore the OpenGL face image flipped: left-right
// for the four side faces, top-bottom for +Y and -Y. Cross files from tools working in
// a left-handed frame label the centre cell "+Z"; it is our -Z (front).
Image cubemapToCross(const Cubemap& cube);

// Generated environments (width x width/2, width even and >= 2, RGB).
// Constant radiance everywhere.
Image constantEnvironment(int width, const glm::vec3& rgb);
// Zero everywhere except the one pixel containing `direction`, whose radiance is rgb
// (its energy is rgb * latLongPixelSolidAngle of its row).
Image sunEnvironment(int width, const glm::dvec3& direction, const glm::vec3& rgb);
// `upper` for the hemisphere y > 0, `lower` for y < 0. With an even height the horizon
// lies on a row boundary; with an odd height the middle row (straddling the horizon
// symmetrically) gets the mean of the two, so each hemisphere integral stays exact.
Image twoToneEnvironment(int width, const glm::vec3& upper, const glm::vec3& lower);

}  // namespace prt
