#include "common/cubemap.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "common/error.h"

namespace prt {

namespace {

// Antiderivative of the solid-angle density 1 / (1 + x^2 + y^2)^(3/2) over a face
// of the unit cube, in face coordinates x, y in [-1, 1].
double solidAngleAntiderivative(double x, double y) {
    return std::atan2(x * y, std::sqrt(x * x + y * y + 1.0));
}

}  // namespace

bool isPowerOfTwo(int n) { return n > 0 && (n & (n - 1)) == 0; }

glm::dvec3 faceUVToDirection(int face, double s, double t) {
    const double sc = 2.0 * s - 1.0;
    const double tc = 2.0 * t - 1.0;
    glm::dvec3 d;
    switch (face) {
        case 0: d = {1.0, -tc, -sc}; break;
        case 1: d = {-1.0, -tc, sc}; break;
        case 2: d = {sc, 1.0, tc}; break;
        case 3: d = {sc, -1.0, -tc}; break;
        case 4: d = {sc, -tc, 1.0}; break;
        default: d = {-sc, -tc, -1.0}; break;
    }
    return glm::normalize(d);
}

void directionToFaceUV(const glm::dvec3& d, int& face, double& s, double& t) {
    const double ax = std::abs(d.x), ay = std::abs(d.y), az = std::abs(d.z);
    double sc, tc, ma;
    // Ties go to X before Y before Z, matching the order of the OpenGL selection rule.
    if (ax >= ay && ax >= az) {
        ma = ax;
        if (d.x >= 0) { face = 0; sc = -d.z; tc = -d.y; }
        else          { face = 1; sc = d.z;  tc = -d.y; }
    } else if (ay >= az) {
        ma = ay;
        if (d.y >= 0) { face = 2; sc = d.x; tc = d.z; }
        else          { face = 3; sc = d.x; tc = -d.z; }
    } else {
        ma = az;
        if (d.z >= 0) { face = 4; sc = d.x;  tc = -d.y; }
        else          { face = 5; sc = -d.x; tc = -d.y; }
    }
    s = 0.5 * (sc / ma + 1.0);
    t = 0.5 * (tc / ma + 1.0);
}

glm::dvec3 texelDirection(int n, int face, int i, int j) {
    return faceUVToDirection(face, (i + 0.5) / n, (j + 0.5) / n);
}

TexelCoord directionToTexel(int n, const glm::dvec3& d) {
    TexelCoord tc;
    double s, t;
    directionToFaceUV(d, tc.face, s, t);
    tc.i = std::clamp(int(std::floor(s * n)), 0, n - 1);
    tc.j = std::clamp(int(std::floor(t * n)), 0, n - 1);
    return tc;
}

double faceRegionSolidAngle(double s0, double t0, double s1, double t1) {
    const double x0 = 2 * s0 - 1, x1 = 2 * s1 - 1, y0 = 2 * t0 - 1, y1 = 2 * t1 - 1;
    return solidAngleAntiderivative(x1, y1) - solidAngleAntiderivative(x0, y1) -
           solidAngleAntiderivative(x1, y0) + solidAngleAntiderivative(x0, y0);
}

double texelSolidAngle(int n, int i, int j) {
    return faceRegionSolidAngle(double(i) / n, double(j) / n, double(i + 1) / n,
                                double(j + 1) / n);
}

std::vector<double> faceSolidAngles(int n) {
    std::vector<double> table(size_t(n) * n);
    for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i) table[size_t(j) * n + i] = texelSolidAngle(n, i, j);
    return table;
}

Cubemap::Cubemap(int size, int channels) : size_(size), channels_(channels) {
    if (!isPowerOfTwo(size))
        throw Error("cubemap", "face size " + std::to_string(size) + " is not a power of two");
    if (channels < 1)
        throw Error("cubemap", "channel count " + std::to_string(channels) + " must be >= 1");
    data_.assign(texelCount() * size_t(channels), 0.0f);
}

BilinearTaps bilinearTaps(int n, const glm::dvec3& d) {
    int face;
    double s, t;
    directionToFaceUV(d, face, s, t);
    // Continuous texel coordinates whose integers are texel centres.
    const double x = std::clamp(s * n - 0.5, 0.0, double(n - 1));
    const double y = std::clamp(t * n - 0.5, 0.0, double(n - 1));
    const int i0 = int(x), j0 = int(y);
    const int i1 = std::min(i0 + 1, n - 1), j1 = std::min(j0 + 1, n - 1);
    const double fx = x - i0, fy = y - j0;
    auto index = [&](int i, int j) { return (size_t(face) * n + j) * n + i; };
    return {{index(i0, j0), index(i1, j0), index(i0, j1), index(i1, j1)},
            {(1 - fx) * (1 - fy), fx * (1 - fy), (1 - fx) * fy, fx * fy}};
}

float Cubemap::sampleBilinear(const glm::dvec3& d, int c) const {
    const BilinearTaps taps = bilinearTaps(size_, d);
    double v = 0.0;
    for (int k = 0; k < 4; ++k) v += taps.weight[k] * data_[taps.texel[k] * channels_ + c];
    return float(v);
}

std::vector<double> Cubemap::integrate() const {
    std::vector<double> sum(channels_, 0.0);
    const std::vector<double> omega = faceSolidAngles(size_);
    for (int f = 0; f < kCubeFaces; ++f)
        for (int j = 0; j < size_; ++j)
            for (int i = 0; i < size_; ++i) {
                const float* v = texel(f, i, j);
                for (int c = 0; c < channels_; ++c) sum[c] += v[c] * omega[size_t(j) * size_ + i];
            }
    return sum;
}

}  // namespace prt
