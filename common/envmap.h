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

#include <string>

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
                    // prt::warn their count. Real maps often hold small negatives from
                    // resampling (all eight Blender studio-light maps do, down to -0.004).
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
// preserved to ~1e-6 relative or better (measured: ~1e-7 on real maps at N = 32,
// ~2e-6 for one-pixel suns); the only approximation is the geodesic-vs-parallel shape of a
// straddling cell, of relative order cell^2. Multithreaded over lat-long rows; the
// result does not depend on the number of threads. Throws prt::Error for an empty or
// inconsistent image or an n that is not a power of two.
Cubemap latLongToCubemap(const Image& latlong, int n,
                         const glm::dmat3& rotation = glm::dmat3(1.0));

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
