#pragma once
// Cubemap parameterisation of the sphere of directions (docs/conventions.md).
//
// Faces in OpenGL order and orientation: 0 +X, 1 -X, 2 +Y, 3 -Y, 4 +Z, 5 -Z. A face
// is N x N texels (N a power of two). Texel (i, j) is column i (the face's s axis)
// and row j (its t axis); its centre is at s = (i + 0.5) / N, t = (j + 0.5) / N.
// Face coordinates follow the OpenGL cube-map selection table, with sc = 2 s - 1 and
// tc = 2 t - 1:
//   +X: d = ( 1, -tc, -sc)    -X: d = (-1, -tc,  sc)
//   +Y: d = ( sc,  1,  tc)    -Y: d = ( sc, -1, -tc)
//   +Z: d = ( sc, -tc,  1)    -Z: d = (-sc, -tc, -1)
// (each then normalised). World frame: right-handed, +Y up.
//
// Texel solid angles are exact (closed form of the projected-area integral); over
// all 6 N^2 texels they sum to 4 pi.

#include <glm/glm.hpp>

#include <array>

#include <cstddef>
#include <vector>

namespace prt {

inline constexpr int kCubeFaces = 6;

struct TexelCoord {
    int face = 0;
    int i = 0;  // column, along s
    int j = 0;  // row, along t
};

// Unit direction through face coordinates (s, t) in [0, 1]^2 of a face.
glm::dvec3 faceUVToDirection(int face, double s, double t);
// Face and (s, t) in [0, 1]^2 hit by direction d (need not be normalised, must be non-zero).
void directionToFaceUV(const glm::dvec3& d, int& face, double& s, double& t);

// Unit direction through the centre of texel (face, i, j) of an N x N face.
glm::dvec3 texelDirection(int n, int face, int i, int j);
// The texel whose footprint contains direction d (inverse of texelDirection).
TexelCoord directionToTexel(int n, const glm::dvec3& d);

// Exact solid angle of texel (i, j) on any face (all faces are congruent).
double texelSolidAngle(int n, int i, int j);
// Solid angle of the region s in [s0, s1], t in [t0, t1] of a face (exact).
double faceRegionSolidAngle(double s0, double t0, double s1, double t1);

bool isPowerOfTwo(int n);

// The four texels of an n x n-face cubemap around direction d, for bilinear
// interpolation between texel centres ((i + 0.5) / n) on the face d falls on, clamped
// at the face border (no filtering across faces): flat texel indices
// (face * n + j) * n + i and weights (>= 0, summing to 1), in the order
// (i0, j0), (i1, j0), (i0, j1), (i1, j1).
struct BilinearTaps {
    std::array<size_t, 4> texel;
    std::array<double, 4> weight;
};
BilinearTaps bilinearTaps(int n, const glm::dvec3& d);

// Dense cubemap with `channels` floats per texel, stored [face][j][i][channel].
class Cubemap {
public:
    Cubemap() = default;
    // Throws prt::Error unless size is a power of two >= 1 and channels >= 1.
    Cubemap(int size, int channels);

    int size() const { return size_; }
    int channels() const { return channels_; }
    size_t texelCount() const { return size_t(kCubeFaces) * size_ * size_; }

    // Flat texel index face * N^2 + j * N + i (the same index the Haar basis uses).
    size_t texelIndex(int face, int i, int j) const {
        return (size_t(face) * size_ + j) * size_ + i;
    }
    float* texel(int face, int i, int j) { return &data_[texelIndex(face, i, j) * channels_]; }
    const float* texel(int face, int i, int j) const {
        return &data_[texelIndex(face, i, j) * channels_];
    }

    std::vector<float>& data() { return data_; }
    const std::vector<float>& data() const { return data_; }

    // Bilinear interpolation of channel c in direction d between texel centres of
    // the face d falls on (clamped at the face border; no filtering across faces).
    float sampleBilinear(const glm::dvec3& d, int c) const;

    // Sum over texels of value * texel solid angle, per channel (the integral over the sphere).
    std::vector<double> integrate() const;

private:
    int size_ = 0;
    int channels_ = 0;
    std::vector<float> data_;
};

// Table of the N x N texel solid angles of one face, [j][i].
std::vector<double> faceSolidAngles(int n);

}  // namespace prt
