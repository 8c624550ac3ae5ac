#include "common/envmap.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#if defined(__x86_64__) && defined(__GNUC__)
#include <immintrin.h>
#endif

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <mutex>
#include <numbers>
#include <string>
#include <thread>
#include <vector>

#include "common/error.h"
#include "common/util.h"

namespace prt {

namespace {

constexpr double kTwoPi = 2.0 * std::numbers::pi;

// cos(a) - cos(b) without cancellation for nearby a, b.
double cosDifference(double a, double b) {
    return 2.0 * std::sin(0.5 * (a + b)) * std::sin(0.5 * (b - a));
}

// Runs body(index) for index in [0, count) on all hardware threads. Each index is
// handled by exactly one call; results must be written to per-index storage so they
// do not depend on the schedule.
template <class Body>
void parallelFor(int count, Body&& body) {
    const int threads =
        std::clamp(int(std::thread::hardware_concurrency()), 1, std::max(1, count));
    std::atomic<int> next{0};
    auto worker = [&] {
        for (int k = next.fetch_add(1); k < count; k = next.fetch_add(1)) body(k);
    };
    if (threads == 1) {
        worker();
        return;
    }
    std::vector<std::thread> pool;
    pool.reserve(size_t(threads - 1));
    for (int t = 1; t < threads; ++t) pool.emplace_back(worker);
    worker();
    for (auto& th : pool) th.join();
}

void requireLatLongWidth(int width, const char* what) {
    if (width < 2 || width % 2 != 0)
        throw Error(what, "lat-long width must be even and >= 2, got " + std::to_string(width));
}

void requireUsable(const Image& image, const std::string& subject) {
    if (!image.consistent())
        throw Error(subject, "inconsistent image: " + std::to_string(image.pixels.size()) +
                                 " values for " + std::to_string(image.width) + " x " +
                                 std::to_string(image.height) + " x " +
                                 std::to_string(image.channels));
    if (image.empty()) throw Error(subject, "empty image");
}

// sin and cos of an angle in degrees, exact at multiples of 90 degrees.
void sinCosDegrees(double degrees, double& s, double& c) {
    const double turns = degrees / 90.0;
    if (turns == std::floor(turns) && std::abs(turns) < 1e15) {
        static constexpr double sinQ[4] = {0, 1, 0, -1};
        static constexpr double cosQ[4] = {1, 0, -1, 0};
        const long q = ((long(turns) % 4) + 4) % 4;
        s = sinQ[q];
        c = cosQ[q];
        return;
    }
    const double r = degrees * (kPi / 180.0);
    s = std::sin(r);
    c = std::cos(r);
}

const char* channelName(int c, int channels) {
    static const char* rgba[4] = {"R", "G", "B", "A"};
    return (channels >= 3 && c < 4) ? rgba[c] : nullptr;
}

}  // namespace

// ---------------------------------------------------------------- lat-long mapping

glm::dvec3 latLongToDirection(double u, double v) {
    const double phi = kTwoPi * (u - 0.5);
    const double theta = kPi * v;
    const double st = std::sin(theta);
    return {st * std::sin(phi), std::cos(theta), -st * std::cos(phi)};
}

glm::dvec2 directionToLatLong(const glm::dvec3& d) {
    const double len = glm::length(d);
    const double y = std::clamp(d.y / len, -1.0, 1.0);
    double u = 0.5 + std::atan2(d.x, -d.z) / kTwoPi;
    if (u >= 1.0) u -= 1.0;
    if (u < 0.0) u += 1.0;
    return {u, std::acos(y) / kPi};
}

glm::dvec3 latLongPixelDirection(int x, int y, int width, int height) {
    return latLongToDirection((x + 0.5) / width, (y + 0.5) / height);
}

double latLongPixelSolidAngle(int y, int width, int height) {
    return kTwoPi / width * cosDifference(kPi * y / height, kPi * (y + 1) / height);
}

double latLongIntegral(const Image& latlong, int c) {
    requireUsable(latlong, "environment");
    if (c < 0 || c >= latlong.channels)
        throw Error("environment", "channel " + std::to_string(c) + " out of range");
    double total = 0.0;
    for (int y = 0; y < latlong.height; ++y) {
        double row = 0.0;
        for (int x = 0; x < latlong.width; ++x) row += latlong.at(x, y, c);
        total += row * latLongPixelSolidAngle(y, latlong.width, latlong.height);
    }
    return total;
}

// ---------------------------------------------------------------- loading

size_t checkEnvironmentValues(Image& image, const std::string& subject, NonFinitePolicy policy) {
    const int nc = image.channels;
    if (policy != NonFinitePolicy::Clamp) {
        const bool allowNegative = policy == NonFinitePolicy::ClampNegative;
        for (int y = 0; y < image.height; ++y)
            for (int x = 0; x < image.width; ++x)
                for (int c = 0; c < nc; ++c) {
                    const float v = image.at(x, y, c);
                    if (std::isfinite(v) && (v >= 0.0f || allowNegative)) continue;
                    std::string what = std::isnan(v)   ? "NaN"
                                       : std::isinf(v) ? (v > 0 ? "+Inf" : "-Inf")
                                                       : "negative (" + std::to_string(v) + ")";
                    const char* name = channelName(c, nc);
                    throw Error(subject, "pixel (" + std::to_string(x) + ", " + std::to_string(y) +
                                             ") is " + what + " in channel " +
                                             (name ? name : std::to_string(c)) +
                                             " (the clamp policy would repair it)");
                }
    }

    std::vector<float> largest(size_t(nc), 0.0f);
    const size_t count = size_t(image.width) * size_t(image.height);
    for (size_t p = 0; p < count; ++p)
        for (int c = 0; c < nc; ++c) {
            const float v = image.pixels[p * size_t(nc) + size_t(c)];
            if (std::isfinite(v)) largest[size_t(c)] = std::max(largest[size_t(c)], v);
        }
    size_t replaced = 0;
    for (size_t p = 0; p < count; ++p)
        for (int c = 0; c < nc; ++c) {
            float& v = image.pixels[p * size_t(nc) + size_t(c)];
            if (std::isfinite(v) && v >= 0.0f) continue;
            v = (std::isinf(v) && v > 0) ? largest[size_t(c)] : 0.0f;
            ++replaced;
        }
    if (replaced > 0)
        warn(subject + ": replaced " + std::to_string(replaced) +
             (policy == NonFinitePolicy::Clamp
                  ? " NaN, infinite or negative values (NaN, -Inf and negatives by 0, +Inf by "
                    "the channel's largest finite value)"
                  : " negative values by 0"));
    return replaced;
}

Image loadEnvironment(const std::string& path, NonFinitePolicy policy) {
    const Image raw = readImage(path);
    if (raw.width != 2 * raw.height)
        throw Error(path, "a lat-long environment must be twice as wide as high, got " +
                              std::to_string(raw.width) + " x " + std::to_string(raw.height));
    Image rgb(raw.width, raw.height, 3);
    const size_t count = size_t(raw.width) * size_t(raw.height);
    const size_t nc = size_t(raw.channels);
    for (size_t p = 0; p < count; ++p)
        for (size_t c = 0; c < 3; ++c)
            rgb.pixels[p * 3 + c] = raw.pixels[p * nc + (nc >= 3 ? c : 0)];
    checkEnvironmentValues(rgb, path, policy);
    return rgb;
}

// ---------------------------------------------------------------- rotations

glm::dmat3 rotationAxisAngle(const glm::dvec3& axis, double degrees) {
    const double len = glm::length(axis);
    if (!(len > 0.0) || !std::isfinite(len))
        throw Error("rotation", "axis must be finite and non-zero");
    const glm::dvec3 k = axis / len;
    double s, c;
    sinCosDegrees(degrees, s, c);
    const double t = 1.0 - c;
    // Rodrigues: R = c I + s [k]x + (1 - c) k k^T. glm is column-major: m[column][row].
    glm::dmat3 m;
    m[0][0] = c + t * k.x * k.x;
    m[1][0] = t * k.x * k.y - s * k.z;
    m[2][0] = t * k.x * k.z + s * k.y;
    m[0][1] = t * k.y * k.x + s * k.z;
    m[1][1] = c + t * k.y * k.y;
    m[2][1] = t * k.y * k.z - s * k.x;
    m[0][2] = t * k.z * k.x - s * k.y;
    m[1][2] = t * k.z * k.y + s * k.x;
    m[2][2] = c + t * k.z * k.z;
    return m;
}

glm::dmat3 rotationX(double degrees) { return rotationAxisAngle({1, 0, 0}, degrees); }
glm::dmat3 rotationY(double degrees) { return rotationAxisAngle({0, 1, 0}, degrees); }
glm::dmat3 rotationZ(double degrees) { return rotationAxisAngle({0, 0, 1}, degrees); }

// ---------------------------------------------------------------- lat-long -> cubemap

namespace {

// A small convex spherical polygon: vertices are direction vectors (any positive
// length); an edge between consecutive vertices is the great-circle arc between them.
// Clipping against planes through the origin is then exact on the sphere.
struct SphPoly {
    static constexpr int kMax = 32;  // ample: <= 4 + 4 pyramid + 2 x 7 texel cuts
    glm::dvec3 v[kMax];
    int count = 0;
    void push(const glm::dvec3& p) {
        if (count < kMax) v[count++] = p;
    }
};

// The part of `in` on the side dot(normal, d) >= 0 (Sutherland-Hodgman).
SphPoly clipPlane(const SphPoly& in, const glm::dvec3& normal) {
    SphPoly out;
    for (int i = 0; i < in.count; ++i) {
        const glm::dvec3& prev = in.v[(i + in.count - 1) % in.count];
        const glm::dvec3& cur = in.v[i];
        const double dp = glm::dot(normal, prev), dc = glm::dot(normal, cur);
        if (dc >= 0.0) {
            if (dp < 0.0) out.push(prev + (cur - prev) * (dp / (dp - dc)));
            out.push(cur);
        } else if (dp > 0.0) {
            out.push(prev + (cur - prev) * (dp / (dp - dc)));
        }
    }
    return out;
}

// Solid angle of a convex spherical polygon (fan of Van Oosterom-Strackee triangles).
double sphericalArea(const SphPoly& p) {
    if (p.count < 3) return 0.0;
    const glm::dvec3 a = glm::normalize(p.v[0]);
    double sum = 0.0;
    glm::dvec3 b = glm::normalize(p.v[1]);
    for (int i = 2; i < p.count; ++i) {
        const glm::dvec3 c = glm::normalize(p.v[i]);
        const double triple = glm::dot(a, glm::cross(b, c));
        const double denom = 1.0 + glm::dot(a, b) + glm::dot(b, c) + glm::dot(c, a);
        sum += 2.0 * std::atan2(triple, denom);
        b = c;
    }
    return std::abs(sum);
}

// Face frames of the cubemap contract: d = F + sc S + tc T on face f.
struct FaceFrame {
    glm::dvec3 F, S, T;
};

std::array<FaceFrame, kCubeFaces> faceFrames() {
    // Derived from faceUVToDirection so they always agree with the contract.
    std::array<FaceFrame, kCubeFaces> frames;
    for (int f = 0; f < kCubeFaces; ++f) {
        const glm::dvec3 F = glm::round(faceUVToDirection(f, 0.5, 0.5));
        const glm::dvec3 S = glm::round(faceUVToDirection(f, 1.0, 0.5) * std::sqrt(2.0) - F);
        const glm::dvec3 T = glm::round(faceUVToDirection(f, 0.5, 1.0) * std::sqrt(2.0) - F);
        frames[size_t(f)] = {F, S, T};
    }
    return frames;
}

struct Piece {
    size_t texel;
    double area;
};

// Splits a polygon lying inside face f's pyramid along the texel borders of that face
// and appends (texel, solid angle) pieces.
void splitInFace(const SphPoly& poly, const FaceFrame& fr, int n, const Cubemap& cube,
                 std::vector<Piece>& pieces) {
    // Continuous texel coordinate along S (or T) of a vertex: n (a / c + 1) / 2.
    auto coordRange = [&](const SphPoly& p, const glm::dvec3& axis, double& lo, double& hi) {
        lo = std::numeric_limits<double>::max();
        hi = std::numeric_limits<double>::lowest();
        for (int i = 0; i < p.count; ++i) {
            const double c = glm::dot(p.v[i], fr.F);
            const double x = 0.5 * n * (glm::dot(p.v[i], axis) / c + 1.0);
            lo = std::min(lo, x);
            hi = std::max(hi, x);
        }
    };
    // Cuts `p` along the texel lines of `axis`; calls emit(part) for each strip.
    auto cutAlong = [&](const SphPoly& p, const glm::dvec3& axis, auto&& emit) {
        double lo, hi;
        coordRange(p, axis, lo, hi);
        SphPoly rest = p;
        for (int k = int(std::floor(lo)) + 1; k < hi && k < n; ++k) {
            if (k <= 0) continue;
            // Plane of the line at texel coordinate k: a - sc c = 0, sc = 2k/n - 1.
            const glm::dvec3 normal = axis - (2.0 * k / n - 1.0) * fr.F;
            emit(clipPlane(rest, -normal));  // the lower side
            rest = clipPlane(rest, normal);
        }
        emit(rest);
    };
    cutAlong(poly, fr.S, [&](const SphPoly& strip) {
        if (strip.count < 3) return;
        cutAlong(strip, fr.T, [&](const SphPoly& piece) {
            const double area = sphericalArea(piece);
            if (!(area > 0.0)) return;
            glm::dvec3 centre(0.0);
            for (int i = 0; i < piece.count; ++i) centre += glm::normalize(piece.v[i]);
            const TexelCoord t = directionToTexel(n, centre);
            pieces.push_back({cube.texelIndex(t.face, t.i, t.j), area});
        });
    });
}

// The exact box-filter geometry shared by latLongToCubemap and LatLongCubemapFilter
// (one code path for both): cuts the pixels of one lat-long row, turned by
// `rotation`, into pieces that each lie in one cube texel and reports each piece's
// exact solid angle (method: see latLongToCubemap in envmap.h).
class LatLongCellSplitter {
public:
    LatLongCellSplitter(int width, int height, int n, const glm::dmat3& rotation)
        : W_(width),
          H_(height),
          n_(n),
          rotation_(rotation),
          layout_(n, 1),
          frames_(faceFrames()),
          // Lat-long pixels larger than `cell_` radians are split into sub-cells (same
          // pixel) so that each is well approximated by the geodesic quad through its
          // corners (the error is confined to how a straddling cell's area is shared,
          // and is of relative order cell^2), and crosses at most ~6 texel lines per
          // axis (the smallest texel extent is 2 / (3 n) radians), which bounds
          // polygon sizes. Sub-cell borders depend only on (width, height, n): the
          // sub-columns of a row are the W * mu meridians phi = 2 pi (k / (W mu) - 1/2).
          cell_(std::min(1.0 / 128.0, 3.0 / n)),
          mv_(std::max(1, int(std::ceil((kPi / height) / cell_)))) {}

    // Working memory of row(), one per thread.
    struct Scratch {
        std::vector<double> sinPhi, cosPhi;  // at the mu * W + 1 sub-column borders
        int mu = 0;
        std::vector<glm::dvec3> cornerDir[2];  // world directions of a sub-row's corners
        std::vector<std::int64_t> cornerTexel[2];
        std::vector<Piece> pieces;
    };

    // Calls sink(x, texel, area) for every piece of lat-long row y, in a fixed order:
    // pixel (x, y) contributes `area` steradians (exact up to rounding) to the cube
    // texel with flat index `texel`. The pieces of one pixel sum to its solid angle.
    template <class Sink>
    void row(Scratch& s, int y, Sink&& sink) const {
        const int W = W_, H = H_, n = n_;
        const double theta0 = kPi * y / H, theta1 = kPi * (y + 1) / H;
        const double maxSin = (theta0 <= kPi / 2 && theta1 >= kPi / 2)
                                  ? 1.0
                                  : std::max(std::sin(theta0), std::sin(theta1));
        const int mu = std::max(1, int(std::ceil(kTwoPi / W * maxSin / cell_)));
        const int columns = W * mu;
        if (s.mu != mu) {
            s.sinPhi.resize(size_t(columns) + 1);
            s.cosPhi.resize(size_t(columns) + 1);
            for (int k = 0; k <= columns; ++k) {
                const double phi = kTwoPi * (double(k) / columns - 0.5);
                s.sinPhi[size_t(k)] = std::sin(phi);
                s.cosPhi[size_t(k)] = std::cos(phi);
            }
            s.mu = mu;
        }
        auto cornerRow = [&](double theta, int slot) {
            const double st = std::sin(theta), ct = std::cos(theta);
            auto& dirs = s.cornerDir[slot];
            auto& ids = s.cornerTexel[slot];
            dirs.resize(size_t(columns) + 1);
            ids.resize(size_t(columns) + 1);
            for (int k = 0; k <= columns; ++k) {
                const glm::dvec3 local(st * s.sinPhi[size_t(k)], ct, -st * s.cosPhi[size_t(k)]);
                const glm::dvec3 d = rotation_ * local;
                const TexelCoord t = directionToTexel(n, d);
                dirs[size_t(k)] = d;
                ids[size_t(k)] = std::int64_t(layout_.texelIndex(t.face, t.i, t.j));
            }
        };

        const double dphi = kTwoPi / columns;
        int top = 0;
        cornerRow(theta0, top);
        for (int b = 0; b < mv_; ++b) {
            const double ta = theta0 + (theta1 - theta0) * b / mv_;
            const double tb = theta0 + (theta1 - theta0) * (b + 1) / mv_;
            const int bottom = 1 - top;
            cornerRow(tb, bottom);
            // Exact solid angle of the sub-cell (two meridians, two parallels).
            const double area = dphi * cosDifference(ta, tb);
            const auto& dTop = s.cornerDir[top];
            const auto& dBot = s.cornerDir[bottom];
            const auto& iTop = s.cornerTexel[top];
            const auto& iBot = s.cornerTexel[bottom];
            for (int k = 0; k < columns; ++k) {
                const int x = k / mu;
                const std::int64_t id = iTop[size_t(k)];
                if (iTop[size_t(k) + 1] == id && iBot[size_t(k)] == id && iBot[size_t(k) + 1] == id) {
                    // All corners in one texel: the (convex) texel contains the cell.
                    sink(x, size_t(id), area);
                    continue;
                }
                // Straddles texel borders: split the cell exactly along them.
                SphPoly poly;
                poly.push(dTop[size_t(k)]);
                poly.push(dTop[size_t(k) + 1]);
                poly.push(dBot[size_t(k) + 1]);
                poly.push(dBot[size_t(k)]);
                s.pieces.clear();
                const int f0 = int(size_t(id) / (size_t(n) * n));
                bool oneFace = true;
                for (std::int64_t other : {iTop[size_t(k) + 1], iBot[size_t(k)], iBot[size_t(k) + 1]})
                    oneFace = oneFace && int(size_t(other) / (size_t(n) * n)) == f0;
                if (oneFace) {
                    splitInFace(poly, frames_[size_t(f0)], n, layout_, s.pieces);
                } else {
                    for (int f = 0; f < kCubeFaces; ++f) {
                        const FaceFrame& fr = frames_[size_t(f)];
                        SphPoly part = clipPlane(poly, fr.F - fr.S);
                        part = clipPlane(part, fr.F + fr.S);
                        part = clipPlane(part, fr.F - fr.T);
                        part = clipPlane(part, fr.F + fr.T);
                        if (part.count >= 3) splitInFace(part, fr, n, layout_, s.pieces);
                    }
                }
                double total = 0.0;
                for (const Piece& p : s.pieces) total += p.area;
                if (total > 0.0) {
                    for (const Piece& p : s.pieces) sink(x, p.texel, area * (p.area / total));
                } else {
                    sink(x, size_t(id), area);  // degenerate (e.g. a sliver at a pole)
                }
            }
            top = bottom;
        }
    }

private:
    int W_, H_, n_;
    glm::dmat3 rotation_;
    Cubemap layout_;  // for texelIndex only
    std::array<FaceFrame, kCubeFaces> frames_;
    double cell_;
    int mv_;
};

// Runs body(scratch, y) for every y in [0, rows) on all hardware threads; rows are
// handed out dynamically and each worker owns one default-constructed Scratch. Results
// must go to per-row storage so they do not depend on the schedule.
template <class Scratch, class Body>
void forRowsInParallel(int rows, Body&& body) {
    const int used = std::clamp(int(std::thread::hardware_concurrency()), 1, std::max(1, rows));
    std::vector<Scratch> scratch(static_cast<size_t>(used));
    std::atomic<int> next{0};
    auto worker = [&](int slot) {
        Scratch& s = scratch[size_t(slot)];
        for (int y = next.fetch_add(1); y < rows; y = next.fetch_add(1)) body(s, y);
    };
    std::vector<std::thread> pool;
    for (int t = 1; t < used; ++t) pool.emplace_back(worker, t);
    worker(0);
    for (auto& th : pool) th.join();
}

}  // namespace

Cubemap latLongToCubemap(const Image& latlong, int n, const glm::dmat3& rotation) {
    requireUsable(latlong, "environment");
    if (!isPowerOfTwo(n))
        throw Error("environment", "cubemap size " + std::to_string(n) + " is not a power of two");
    const int W = latlong.width, H = latlong.height, C = latlong.channels;
    const size_t stride = size_t(C) + 1;  // radiance * area per channel, then area
    Cubemap cube(n, C);
    const size_t texels = cube.texelCount();
    const LatLongCellSplitter splitter(W, H, n, rotation);

    // Per row: the texels it reached (in first-touch order) and their sums.
    struct RowSums {
        std::vector<std::uint32_t> index;
        std::vector<double> sums;  // stride values per entry
    };
    std::vector<RowSums> rows(static_cast<size_t>(H));

    struct Scratch {
        LatLongCellSplitter::Scratch geometry;
        std::vector<double> acc;
        std::vector<char> touched;
        std::vector<std::uint32_t> list;
    };

    forRowsInParallel<Scratch>(H, [&](Scratch& s, int y) {
        if (s.acc.empty()) {
            s.acc.assign(texels * stride, 0.0);
            s.touched.assign(texels, 0);
        }
        splitter.row(s.geometry, y, [&](int x, size_t t, double area) {
            const float* L = latlong.pixel(x, y);
            if (!s.touched[t]) {
                s.touched[t] = 1;
                s.list.push_back(std::uint32_t(t));
            }
            double* a = &s.acc[t * stride];
            for (int c = 0; c < C; ++c) a[c] += double(L[c]) * area;
            a[C] += area;
        });

        RowSums& out = rows[size_t(y)];
        out.index = s.list;
        out.sums.resize(s.list.size() * stride);
        for (size_t e = 0; e < s.list.size(); ++e) {
            double* a = &s.acc[size_t(s.list[e]) * stride];
            std::copy(a, a + stride, &out.sums[e * stride]);
            std::fill(a, a + stride, 0.0);
            s.touched[s.list[e]] = 0;
        }
        s.list.clear();
    });

    // Merge in row order: the sums do not depend on the thread schedule.
    std::vector<double> total(texels * stride, 0.0);
    for (const RowSums& r : rows)
        for (size_t e = 0; e < r.index.size(); ++e) {
            double* a = &total[size_t(r.index[e]) * stride];
            const double* v = &r.sums[e * stride];
            for (size_t c = 0; c < stride; ++c) a[c] += v[c];
        }

    const glm::dmat3 inverse = glm::transpose(rotation);
    for (int f = 0; f < kCubeFaces; ++f)
        for (int j = 0; j < n; ++j)
            for (int i = 0; i < n; ++i) {
                const size_t t = cube.texelIndex(f, i, j);
                const double* a = &total[t * stride];
                float* out = cube.texel(f, i, j);
                if (a[C] > 0.0) {
                    for (int c = 0; c < C; ++c) out[c] = float(a[c] / a[C]);
                } else {
                    // Not reached by any cell (should not happen): nearest lat-long pixel.
                    const glm::dvec2 uv = directionToLatLong(inverse * texelDirection(n, f, i, j));
                    const int x = std::min(int(uv.x * W), W - 1);
                    const int y = std::min(int(uv.y * H), H - 1);
                    for (int c = 0; c < C; ++c) out[c] = latlong.at(x, y, c);
                }
            }
    return cube;
}

// ---------------------------------------------------------------- lat-long -> cubemap, as a matrix

bool rotationAboutY(const glm::dmat3& rotation, double& degrees) {
    const glm::dmat3& r = rotation;  // glm is column-major: r[column][row]
    // rotationY(a): r[0][0] = r[2][2] = cos a, r[2][0] = -r[0][2] = sin a, r[1][1] = 1.
    const double angle = std::atan2(r[2][0] - r[0][2], r[0][0] + r[2][2]);
    if (!std::isfinite(angle)) return false;
    const double c = std::cos(angle), s = std::sin(angle);
    const double expected[3][3] = {{c, 0, -s}, {0, 1, 0}, {s, 0, c}};  // [column][row]
    for (int col = 0; col < 3; ++col)
        for (int row = 0; row < 3; ++row)
            if (!(std::abs(r[col][row] - expected[col][row]) <= 1e-12)) return false;
    degrees = angle * (180.0 / kPi);
    return true;
}

LatLongCubemapFilter::LatLongCubemapFilter(int width, int height, int n)
    : width_(width), height_(height), n_(n) {
    if (width < 1 || height < 1 || width > kMaxLatLongSize || height > kMaxLatLongSize)
        throw Error("lat-long filter", "lat-long size " + std::to_string(width) + " x " +
                                           std::to_string(height) + " outside 1 .. " +
                                           std::to_string(kMaxLatLongSize));
    if (!isPowerOfTwo(n))
        throw Error("environment", "cubemap size " + std::to_string(n) + " is not a power of two");
    const size_t texels = size_t(kCubeFaces) * size_t(n) * size_t(n);
    const LatLongCellSplitter splitter(width, height, n, glm::dmat3(1.0));

    // Per row: (texel, column, area) with the pieces of one (texel, pixel) pair merged.
    struct RowPiece {
        std::uint32_t texel;
        std::uint32_t x;
        double area;
    };
    std::vector<std::vector<RowPiece>> rows(static_cast<size_t>(height));
    struct Scratch {
        LatLongCellSplitter::Scratch geometry;
        std::vector<RowPiece> pieces;
    };
    forRowsInParallel<Scratch>(height, [&](Scratch& s, int y) {
        s.pieces.clear();
        splitter.row(s.geometry, y, [&](int x, size_t t, double area) {
            s.pieces.push_back({std::uint32_t(t), std::uint32_t(x), area});
        });
        // Stable: equal pairs keep the splitter's order, so the merged areas (summed in
        // that order) do not depend on the schedule.
        std::stable_sort(s.pieces.begin(), s.pieces.end(), [](const RowPiece& a, const RowPiece& b) {
            return a.texel != b.texel ? a.texel < b.texel : a.x < b.x;
        });
        std::vector<RowPiece>& out = rows[size_t(y)];
        out.clear();
        for (const RowPiece& p : s.pieces) {
            if (!out.empty() && out.back().texel == p.texel && out.back().x == p.x)
                out.back().area += p.area;
            else
                out.push_back(p);
        }
        out.shrink_to_fit();
    });

    // Texels that received no area (should not happen) take their nearest pixel, like
    // latLongToCubemap.
    std::vector<double> received(texels, 0.0);
    for (const auto& r : rows)
        for (const RowPiece& p : r) received[p.texel] += p.area;
    std::vector<size_t> count(texels, 0);
    for (const auto& r : rows)
        for (const RowPiece& p : r)
            if (received[p.texel] > 0.0) ++count[p.texel];
    struct Fallback {
        size_t texel;
        int x, y;
    };
    std::vector<Fallback> fallbacks;
    for (int f = 0; f < kCubeFaces; ++f)
        for (int j = 0; j < n; ++j)
            for (int i = 0; i < n; ++i) {
                const size_t t = (size_t(f) * size_t(n) + size_t(j)) * size_t(n) + size_t(i);
                if (received[t] > 0.0) continue;
                const glm::dvec2 uv = directionToLatLong(texelDirection(n, f, i, j));
                fallbacks.push_back({t, std::min(int(uv.x * width), width - 1),
                                     std::min(int(uv.y * height), height - 1)});
                count[t] = 1;
            }

    // CSR by texel; within a texel, entries in (row, column) order.
    begin_.assign(texels + 1, 0);
    size_t total = 0;
    for (size_t t = 0; t < texels; ++t) {
        begin_[t] = std::uint32_t(total);
        total += count[t];
        if (total > std::numeric_limits<std::uint32_t>::max())
            throw Error("lat-long filter", "too many entries");
    }
    begin_[texels] = std::uint32_t(total);
    entries_.resize(total);
    std::vector<double> area(total, 0.0);
    std::vector<std::uint32_t> fill(begin_.begin(), begin_.end() - 1);
    for (int y = 0; y < height; ++y)
        for (const RowPiece& p : rows[size_t(y)]) {
            if (!(received[p.texel] > 0.0)) continue;
            const std::uint32_t e = fill[p.texel]++;
            entries_[e] = {std::uint16_t(p.x), std::uint16_t(y), 0.0f};
            area[e] = p.area;
        }
    for (const Fallback& fb : fallbacks) {
        const std::uint32_t e = fill[fb.texel]++;
        entries_[e] = {std::uint16_t(fb.x), std::uint16_t(fb.y), 0.0f};
        area[e] = 1.0;
    }
    std::vector<double>& weight = area;  // normalised in place
    for (size_t t = 0; t < texels; ++t) {
        double sum = 0.0;
        for (std::uint32_t e = begin_[t]; e < begin_[t + 1]; ++e) sum += area[e];
        for (std::uint32_t e = begin_[t]; e < begin_[t + 1]; ++e) {
            weight[e] = area[e] / sum;
            entries_[e].weight = float(weight[e]);
        }
    }
    buildRuns(weight);
}

namespace {

// Consecutive columns of one row of one texel, unwrapped (first + i for
// i < weights.size(); first + i >= width means column first + i - width).
struct ColumnSegment {
    int first = 0;
    std::vector<double> weights;
};

// Splits one row's entries of one texel (columns ascending, distinct) into segments of
// consecutive columns; a segment reaching the right edge continues with the one starting
// at column 0 (the row is periodic), unless the texel covers the whole row.
void columnSegments(const std::vector<int>& xs, const std::vector<double>& ws, int width,
                    std::vector<ColumnSegment>& segments) {
    segments.clear();
    for (size_t i = 0; i < xs.size(); ++i) {
        if (segments.empty() || xs[i] != segments.back().first + int(segments.back().weights.size()))
            segments.push_back({xs[i], {}});
        segments.back().weights.push_back(ws[i]);
    }
    if (segments.size() > 1 && segments.front().first == 0 &&
        segments.back().first + int(segments.back().weights.size()) == width) {
        std::vector<double>& last = segments.back().weights;
        last.insert(last.end(), segments.front().weights.begin(), segments.front().weights.end());
        segments.erase(segments.begin());
    }
}

// Cuts a segment into runs (first, equal interior, last), greedily: a run's interior
// continues while the weight stays the same (bit for bit: pixels wholly inside a texel
// get identical area sums), and the pixel that breaks it ends the run as its `last`.
void appendRuns(const ColumnSegment& segment, int y, std::vector<LatLongCubemapFilter::Run>& runs) {
    const std::vector<double>& w = segment.weights;
    const size_t m = w.size();
    for (size_t i = 0; i < m;) {
        LatLongCubemapFilter::Run run{std::uint32_t(segment.first + int(i)), std::uint16_t(y), 1,
                                      float(w[i]), 0.0f, 0.0f};
        if (i + 1 < m) {
            size_t j = i + 1;  // the interior is i + 1 .. j
            while (j + 1 < m && w[j + 1] == w[i + 1]) ++j;
            if (j + 1 < m) ++j;  // the pixel breaking the interior ends the run
            run.len = std::uint16_t(j - i + 1);
            run.interior = run.len > 2 ? float(w[i + 1]) : 0.0f;
            run.last = float(w[j]);
        }
        runs.push_back(run);
        i += run.len;
    }
}

}  // namespace

void LatLongCubemapFilter::buildRuns(const std::vector<double>& weights) {
    const size_t texels = begin_.size() - 1;
    runBegin_.assign(texels + 1, 0);
    runs_.clear();
    std::vector<int> xs;
    std::vector<double> ws;
    std::vector<ColumnSegment> segments;
    for (size_t t = 0; t < texels; ++t) {
        runBegin_[t] = std::uint32_t(runs_.size());
        // Entries are in (row, column) order: one pass per row.
        for (std::uint32_t e = begin_[t]; e < begin_[t + 1];) {
            const int y = entries_[e].y;
            xs.clear();
            ws.clear();
            for (; e < begin_[t + 1] && entries_[e].y == y; ++e) {
                xs.push_back(entries_[e].x);
                ws.push_back(weights[e]);
            }
            columnSegments(xs, ws, width_, segments);
            for (const ColumnSegment& segment : segments) appendRuns(segment, y, runs_);
        }
    }
    if (runs_.size() > std::numeric_limits<std::uint32_t>::max())
        throw Error("lat-long filter", "too many runs");
    runBegin_[texels] = std::uint32_t(runs_.size());
}

size_t LatLongCubemapFilter::memoryBytes() const {
    return sizeof(*this) + entries_.capacity() * sizeof(Entry) +
           begin_.capacity() * sizeof(std::uint32_t) + runs_.capacity() * sizeof(Run) +
           runBegin_.capacity() * sizeof(std::uint32_t);
}

LatLongRowSums::LatLongRowSums(const Image& latlong)
    : width_(latlong.width), height_(latlong.height), channels_(latlong.channels) {
    requireUsable(latlong, "environment");
    const size_t C = size_t(channels_), W = size_t(width_), entries = rowEntries(width_);
    sums_.assign(size_t(height_) * entries * C + 8, 0.0);
    std::atomic<int> badRow{-1};
    tbb::parallel_for(tbb::blocked_range<int>(0, height_, 16), [&](const tbb::blocked_range<int>& r) {
        for (int y = r.begin(); y < r.end(); ++y) {
            const float* row = latlong.pixel(0, y);
            double* s = &sums_[size_t(y) * entries * C];  // s[0 .. C) stays 0
            // Entry j + 1 adds column (j mod W): two periods, then the one more.
            for (size_t j = 0; j + 1 < entries; ++j) {
                const float* p = row + (j < W ? j : j < 2 * W ? j - W : j - 2 * W) * C;
                for (size_t c = 0; c < C; ++c) s[(j + 1) * C + c] = s[j * C + c] + double(p[c]);
            }
            for (size_t c = 0; c < C; ++c)
                if (!std::isfinite(s[W * C + c])) badRow = y;
        }
    });
    if (badRow >= 0)
        throw Error("environment", "row " + std::to_string(badRow.load()) +
                                       " of the lat-long map sums to a non-finite value (NaN, infinite "
                                       "or too large values)");
}

namespace {

// A turn about +Y as a shift of lat-long columns: whole pixels in [0, width) plus a
// fraction in [0, 1) (0 within kIntegerShiftTolerance of a whole pixel).
struct ColumnShift {
    int whole = 0;
    double frac = 0.0;
};

ColumnShift columnShift(double rotationYDegrees, int W) {
    if (!std::isfinite(rotationYDegrees))
        throw Error("lat-long filter", "rotation angle is not finite");
    // rotationY(a) moves the content of longitude u to u - a / 360 (L'(d) = L(R^T d)),
    // so the rotated map's column x holds the original's column x + a W / 360.
    double shift = std::fmod(rotationYDegrees, 360.0) / 360.0 * W;  // (-W, W); fmod is exact
    if (shift < 0.0) shift += W;                                      // [0, W]
    int k = int(std::floor(shift));
    double frac = shift - k;
    if (frac < LatLongCubemapFilter::kIntegerShiftTolerance) {
        frac = 0.0;
    } else if (frac > 1.0 - LatLongCubemapFilter::kIntegerShiftTolerance) {
        frac = 0.0;
        ++k;
    }
    return {k % W, frac};
}

// Texels per parallel task of LatLongCubemapFilter::apply (~100 entries each at N = 32
// for a 1024 x 512 map, so a task is ~50K entries).
constexpr size_t kTexelGrain = 512;

#if defined(__x86_64__) && defined(__GNUC__)
// LatLongCubemapFilter::apply's RGB sums for texels [tBegin, tEnd): per entry, the
// pixel's R, G, B (and one float beyond, multiplied into an ignored lane) widened to
// 4 doubles and multiply-added with the weight, or the blend of two pixels. Double sums
// like the scalar loop; FMA rounds once, so a texel can differ from it in the last bit
// of the double before the final rounding to float. The 16-byte read of the image's
// very last pixel would pass the end of the buffer: that one is read through a copy.
__attribute__((target("avx2,fma"))) void sumTexelsRgbAvx2(
    const LatLongCubemapFilter::Entry* entries, const std::uint32_t* begin, size_t tBegin,
    size_t tEnd, const float* pixels, size_t pixelFloats, int W, int k, double a0, double a1,
    bool blend, float* out) {
    const size_t rowStride = size_t(W) * 3;
    const float* lastPixel = pixels + pixelFloats - 3;
    alignas(16) const float lastCopy[4] = {lastPixel[0], lastPixel[1], lastPixel[2], 0.0f};
#define PRT_LOAD_PIXEL(p) _mm256_cvtps_pd(_mm_loadu_ps((p) == lastPixel ? lastCopy : (p)))
    // The pixel column an entry reads after the turn by k whole pixels.
    const auto column = [W, k](const LatLongCubemapFilter::Entry& en) {
        const int x = int(en.x) + k;
        return x >= W ? x - W : x;
    };
    for (size_t t = tBegin; t < tEnd; ++t) {
        // Two independent accumulators (the FMA latency, not the loads, would bound one).
        __m256d acc0 = _mm256_setzero_pd(), acc1 = acc0;
        std::uint32_t e = begin[t];
        const std::uint32_t eEnd = begin[t + 1];
        if (blend) {
            for (; e < eEnd; ++e) {
                const LatLongCubemapFilter::Entry en = entries[e];
                const int x = column(en), x1 = x + 1 < W ? x + 1 : 0;
                const float* row = pixels + size_t(en.y) * rowStride;
                const double w = en.weight;
                acc0 = _mm256_fmadd_pd(_mm256_set1_pd(w * a0), PRT_LOAD_PIXEL(row + size_t(x) * 3), acc0);
                acc1 = _mm256_fmadd_pd(_mm256_set1_pd(w * a1), PRT_LOAD_PIXEL(row + size_t(x1) * 3), acc1);
            }
        } else {
            const auto address = [&](const LatLongCubemapFilter::Entry& en) {
                return pixels + size_t(en.y) * rowStride + size_t(column(en)) * 3;
            };
            for (; e + 2 <= eEnd; e += 2) {
                const LatLongCubemapFilter::Entry p = entries[e], q = entries[e + 1];
                acc0 = _mm256_fmadd_pd(_mm256_set1_pd(double(p.weight)), PRT_LOAD_PIXEL(address(p)), acc0);
                acc1 = _mm256_fmadd_pd(_mm256_set1_pd(double(q.weight)), PRT_LOAD_PIXEL(address(q)), acc1);
            }
            if (e < eEnd)
                acc0 = _mm256_fmadd_pd(_mm256_set1_pd(double(entries[e].weight)),
                                       PRT_LOAD_PIXEL(address(entries[e])), acc0);
        }
        alignas(32) double sum[4];
        _mm256_store_pd(sum, _mm256_add_pd(acc0, acc1));
        for (int c = 0; c < 3; ++c) out[t * 3 + size_t(c)] = float(sum[c]);
    }
#undef PRT_LOAD_PIXEL
}
#else
void sumTexelsRgbAvx2(const LatLongCubemapFilter::Entry*, const std::uint32_t*, size_t, size_t,
                      const float*, size_t, int, int, double, double, bool, float*) {}
#endif

}  // namespace

Cubemap LatLongCubemapFilter::apply(const Image& latlong, double rotationYDegrees) const {
    requireUsable(latlong, "environment");
    if (latlong.width != width_ || latlong.height != height_)
        throw Error("lat-long filter", "environment is " + std::to_string(latlong.width) + " x " +
                                           std::to_string(latlong.height) + ", the filter was built for " +
                                           std::to_string(width_) + " x " + std::to_string(height_));
    const int W = width_, C = latlong.channels;
    const ColumnShift turn = columnShift(rotationYDegrees, W);
    const int k = turn.whole;
    const double frac = turn.frac, a0 = 1.0 - frac, a1 = frac;

    Cubemap cube(n_, C);
    float* out = cube.data().data();
    const float* pixels = latlong.pixels.data();
    const size_t rowStride = size_t(W) * size_t(C);
    const size_t texels = cube.texelCount();

    // Texel t = sum over its entries of weight * pixel (x + k, y), or of the blend of
    // pixels x + k and x + k + 1 for a fractional shift; summed in double. The channel
    // count and the blend are compile-time constants for RGB, the case that matters.
    auto sumTexels = [&]<int kC, bool kBlend>(size_t tBegin, size_t tEnd) {
        for (size_t t = tBegin; t < tEnd; ++t) {
            double acc[kC] = {};
            for (std::uint32_t e = begin_[t], end = begin_[t + 1]; e < end; ++e) {
                const Entry en = entries_[e];
                int x = int(en.x) + k;
                if (x >= W) x -= W;
                const float* row = pixels + size_t(en.y) * rowStride;
                const float* p0 = row + size_t(x) * kC;
                if constexpr (kBlend) {
                    const int x1 = x + 1 < W ? x + 1 : 0;
                    const float* p1 = row + size_t(x1) * kC;
                    const double w0 = double(en.weight) * a0, w1 = double(en.weight) * a1;
                    for (int c = 0; c < kC; ++c) acc[c] += w0 * double(p0[c]) + w1 * double(p1[c]);
                } else {
                    const double w = en.weight;
                    for (int c = 0; c < kC; ++c) acc[c] += w * double(p0[c]);
                }
            }
            for (int c = 0; c < kC; ++c) out[t * kC + size_t(c)] = float(acc[c]);
        }
    };
    if (C == 3) {
        // Texel ranges in parallel (each texel is summed by one thread in entry order, so
        // the result does not depend on the thread count); the AVX2 loop where the CPU has
        // it: the same sums, in double, one 4-wide register per entry (docs/relight.md).
        const bool avx2 = cpuHasAvx2Fma();
        const size_t pixelFloats = latlong.pixels.size();
        tbb::parallel_for(tbb::blocked_range<size_t>(0, texels, kTexelGrain),
                          [&](const tbb::blocked_range<size_t>& r) {
            if (avx2) {
                sumTexelsRgbAvx2(entries_.data(), begin_.data(), r.begin(), r.end(), pixels,
                                 pixelFloats, W, k, a0, a1, frac != 0.0, out);
            } else if (frac == 0.0) {
                sumTexels.template operator()<3, false>(r.begin(), r.end());
            } else {
                sumTexels.template operator()<3, true>(r.begin(), r.end());
            }
        });
        return cube;
    }
    // Any other channel count.
    std::vector<double> acc(static_cast<size_t>(C));
    for (size_t t = 0; t < texels; ++t) {
        std::fill(acc.begin(), acc.end(), 0.0);
        for (std::uint32_t e = begin_[t]; e < begin_[t + 1]; ++e) {
            const Entry& en = entries_[e];
            int x = int(en.x) + k;
            if (x >= W) x -= W;
            const int x1 = x + 1 < W ? x + 1 : 0;
            const float* row = pixels + size_t(en.y) * rowStride;
            const float* p0 = row + size_t(x) * size_t(C);
            const float* p1 = row + size_t(x1) * size_t(C);
            const double w0 = double(en.weight) * a0, w1 = double(en.weight) * a1;
            for (int c = 0; c < C; ++c)
                acc[size_t(c)] += frac == 0.0 ? w0 * double(p0[c]) : w0 * double(p0[c]) + w1 * double(p1[c]);
        }
        for (int c = 0; c < C; ++c) out[t * size_t(C) + size_t(c)] = float(acc[size_t(c)]);
    }
    return cube;
}

namespace {

// Texels per parallel task of the running-sum apply.
constexpr size_t kRunTexelGrain = 256;

// Where a run's running sums start at a turn by k whole pixels, as an entry index of
// LatLongRowSums: one period earlier when the run would read past the row's 2 W + 2
// sums (it reads up to x + len + k + 1; a period earlier every sum it reads is less by
// the row's total, which its differences cancel).
inline std::uint64_t runEntry(const LatLongCubemapFilter::Run& run, int k, int W, std::uint64_t rowEntries) {
    const std::int64_t x = std::int64_t(run.x) + k;
    return std::uint64_t(run.y) * rowEntries +
           std::uint64_t(x + std::int64_t(run.len) > 2 * std::int64_t(W) ? x - W : x);
}

// Texels [tBegin, tEnd) from the running sums, any channel count: each run's weighted
// differences of P at its start (acc0) and, for a fractional turn, one column further
// (acc1); the texel is (1 - f) acc0 + f acc1.
template <bool kBlend>
void sumRunsScalar(const LatLongCubemapFilter::Run* runs, const std::uint32_t* begin, size_t tBegin,
                   size_t tEnd, const double* sums, int C, int W, int k, double a0, double a1, float* out) {
    const std::uint64_t rowEntries = LatLongRowSums::rowEntries(W);
    std::vector<double> acc0(static_cast<size_t>(C)), acc1(static_cast<size_t>(C));
    // One run at the running sums from p: its first pixel ends at p + C, its interior at
    // q = p + (len - 1) C, its last pixel at q + C.
    const auto runSum = [C](const LatLongCubemapFilter::Run& run, const double* p, int c) {
        const double* q = p + size_t(run.len - 1) * size_t(C);
        return double(run.first) * (p[C + c] - p[c]) + double(run.interior) * (q[c] - p[C + c]) +
               double(run.last) * (q[C + c] - q[c]);
    };
    for (size_t t = tBegin; t < tEnd; ++t) {
        std::fill(acc0.begin(), acc0.end(), 0.0);
        std::fill(acc1.begin(), acc1.end(), 0.0);
        for (std::uint32_t e = begin[t]; e < begin[t + 1]; ++e) {
            const double* p = sums + runEntry(runs[e], k, W, rowEntries) * std::uint64_t(C);
            for (int c = 0; c < C; ++c) {
                acc0[size_t(c)] += runSum(runs[e], p, c);
                if constexpr (kBlend) acc1[size_t(c)] += runSum(runs[e], p + C, c);
            }
        }
        for (int c = 0; c < C; ++c)
            out[t * size_t(C) + size_t(c)] =
                float(kBlend ? a0 * acc0[size_t(c)] + a1 * acc1[size_t(c)] : acc0[size_t(c)]);
    }
}

#if defined(__x86_64__) && defined(__GNUC__)
// How far ahead sumRunsRgbAvx2 prefetches the running sums. A light change follows the
// relight kernel, which has streamed tens of MB through the caches, so the sums come
// from the last-level cache, scattered (two places per run, rows apart), and the
// hardware prefetchers do not foresee them (docs/performance.md, "Design measurements").
constexpr std::uint32_t kPrefetchRuns = 32;

// sumRunsScalar for RGB, one 4-wide register per running sum (the fourth lane reads the
// next entry's R or the padding and is ignored).
template <bool kBlend>
__attribute__((target("avx2,fma"))) void sumRunsRgbAvx2(const LatLongCubemapFilter::Run* runs,
                                                        const std::uint32_t* begin, size_t tBegin,
                                                        size_t tEnd, const double* sums, int W, int k,
                                                        double a0, double a1, float* out) {
    const std::uint64_t rowEntries = LatLongRowSums::rowEntries(W);
    const std::uint32_t lastRun = begin[tEnd];
    for (size_t t = tBegin; t < tEnd; ++t) {
        __m256d s0 = _mm256_setzero_pd(), s1 = s0;
        for (std::uint32_t e = begin[t]; e < begin[t + 1]; ++e) {
            if (e + kPrefetchRuns < lastRun) {
                // Both ends of a run kPrefetchRuns ahead: the first and last byte each reads.
                const LatLongCubemapFilter::Run& ahead = runs[e + kPrefetchRuns];
                const char* pa = reinterpret_cast<const char*>(sums + runEntry(ahead, k, W, rowEntries) * 3);
                const char* qa = pa + size_t(ahead.len - 1) * 3 * sizeof(double);
                _mm_prefetch(pa, _MM_HINT_T0);
                _mm_prefetch(pa + 9 * sizeof(double) - 1, _MM_HINT_T0);
                _mm_prefetch(qa, _MM_HINT_T0);
                _mm_prefetch(qa + 9 * sizeof(double) - 1, _MM_HINT_T0);
            }
            const LatLongCubemapFilter::Run& run = runs[e];
            const double* p = sums + runEntry(run, k, W, rowEntries) * 3;
            const double* q = p + size_t(run.len - 1) * 3;
            const __m256d wf = _mm256_set1_pd(run.first), wi = _mm256_set1_pd(run.interior),
                          wl = _mm256_set1_pd(run.last);
            const __m256d p0 = _mm256_loadu_pd(p), p1 = _mm256_loadu_pd(p + 3);
            const __m256d q0 = _mm256_loadu_pd(q), q1 = _mm256_loadu_pd(q + 3);
            __m256d r = _mm256_mul_pd(wf, _mm256_sub_pd(p1, p0));
            r = _mm256_fmadd_pd(wi, _mm256_sub_pd(q0, p1), r);
            r = _mm256_fmadd_pd(wl, _mm256_sub_pd(q1, q0), r);
            s0 = _mm256_add_pd(s0, r);
            if constexpr (kBlend) {
                const __m256d p2 = _mm256_loadu_pd(p + 6), q2 = _mm256_loadu_pd(q + 6);
                __m256d u = _mm256_mul_pd(wf, _mm256_sub_pd(p2, p1));
                u = _mm256_fmadd_pd(wi, _mm256_sub_pd(q1, p2), u);
                u = _mm256_fmadd_pd(wl, _mm256_sub_pd(q2, q1), u);
                s1 = _mm256_add_pd(s1, u);
            }
        }
        if constexpr (kBlend)
            s0 = _mm256_fmadd_pd(_mm256_set1_pd(a0), s0, _mm256_mul_pd(_mm256_set1_pd(a1), s1));
        alignas(32) double v[4];
        _mm256_store_pd(v, s0);
        for (int c = 0; c < 3; ++c) out[t * 3 + size_t(c)] = float(v[c]);
    }
}
#endif

}  // namespace

Cubemap LatLongCubemapFilter::apply(const LatLongRowSums& sums, double rotationYDegrees) const {
    if (sums.width() != width_ || sums.height() != height_)
        throw Error("lat-long filter", "environment is " + std::to_string(sums.width()) + " x " +
                                           std::to_string(sums.height()) + ", the filter was built for " +
                                           std::to_string(width_) + " x " + std::to_string(height_));
    const int W = width_, C = sums.channels();
    const ColumnShift turn = columnShift(rotationYDegrees, W);
    const int k = turn.whole;
    const bool blend = turn.frac != 0.0;
    const double a0 = 1.0 - turn.frac, a1 = turn.frac;

    Cubemap cube(n_, C);
    float* out = cube.data().data();
    const double* data = sums.data();
    [[maybe_unused]] const bool avx2 = C == 3 && cpuHasAvx2Fma();
    tbb::parallel_for(tbb::blocked_range<size_t>(0, cube.texelCount(), kRunTexelGrain),
                      [&](const tbb::blocked_range<size_t>& r) {
        const Run* runs = runs_.data();
        const std::uint32_t* begin = runBegin_.data();
#if defined(__x86_64__) && defined(__GNUC__)
        if (avx2) {
            if (blend) sumRunsRgbAvx2<true>(runs, begin, r.begin(), r.end(), data, W, k, a0, a1, out);
            else sumRunsRgbAvx2<false>(runs, begin, r.begin(), r.end(), data, W, k, a0, a1, out);
            return;
        }
#endif
        if (blend) sumRunsScalar<true>(runs, begin, r.begin(), r.end(), data, C, W, k, a0, a1, out);
        else sumRunsScalar<false>(runs, begin, r.begin(), r.end(), data, C, W, k, a0, a1, out);
    });
    return cube;
}

std::shared_ptr<const LatLongCubemapFilter> LatLongCubemapFilter::shared(int width, int height, int n) {
    struct Slot {
        int width, height, n;
        std::mutex build;
        std::shared_ptr<const LatLongCubemapFilter> filter;
    };
    static std::mutex mutex;
    static std::vector<std::shared_ptr<Slot>> slots;  // most recently used first
    constexpr size_t kKeep = 4;

    std::shared_ptr<Slot> slot;
    {
        std::lock_guard<std::mutex> lock(mutex);
        auto it = std::find_if(slots.begin(), slots.end(), [&](const std::shared_ptr<Slot>& s) {
            return s->width == width && s->height == height && s->n == n;
        });
        if (it != slots.end()) {
            slot = *it;
            slots.erase(it);
        } else {
            slot = std::make_shared<Slot>();
            slot->width = width;
            slot->height = height;
            slot->n = n;
        }
        slots.insert(slots.begin(), slot);
        if (slots.size() > kKeep) slots.resize(kKeep);
    }
    // Built once, outside the cache lock: callers of other sizes are not held up, callers
    // of the same size wait for it. A failed build (bad sizes) is dropped from the cache.
    std::lock_guard<std::mutex> lock(slot->build);
    if (!slot->filter) {
        try {
            slot->filter = std::make_shared<const LatLongCubemapFilter>(width, height, n);
        } catch (...) {
            std::lock_guard<std::mutex> cacheLock(mutex);  // never cache a failure
            slots.erase(std::remove(slots.begin(), slots.end(), slot), slots.end());
            throw;
        }
    }
    return slot->filter;
}

// ---------------------------------------------------------------- cubemap -> images

Image cubemapToLatLong(const Cubemap& cube, int width) {
    requireLatLongWidth(width, "cubemapToLatLong");
    if (cube.size() <= 0) throw Error("cubemapToLatLong", "empty cubemap");
    const int height = width / 2, C = cube.channels();
    Image out(width, height, C);
    parallelFor(height, [&](int y) {
        for (int x = 0; x < width; ++x) {
            const glm::dvec3 d = latLongPixelDirection(x, y, width, height);
            for (int c = 0; c < C; ++c) out.at(x, y, c) = cube.sampleBilinear(d, c);
        }
    });
    return out;
}

Image cubemapToCross(const Cubemap& cube) {
    const int n = cube.size(), C = cube.channels();
    if (n <= 0) throw Error("cubemapToCross", "empty cubemap");
    // Each cell as seen from the centre: forward, right and up on the page.
    struct Cell {
        int col, row;
        glm::dvec3 forward, right, up;
    };
    const Cell cells[6] = {
        {0, 1, {-1, 0, 0}, {0, 0, -1}, {0, 1, 0}},  // -X
        {1, 1, {0, 0, -1}, {1, 0, 0}, {0, 1, 0}},   // -Z (front)
        {2, 1, {1, 0, 0}, {0, 0, 1}, {0, 1, 0}},    // +X
        {3, 1, {0, 0, 1}, {-1, 0, 0}, {0, 1, 0}},   // +Z (back)
        {1, 0, {0, 1, 0}, {1, 0, 0}, {0, 0, 1}},    // +Y
        {1, 2, {0, -1, 0}, {1, 0, 0}, {0, 0, -1}},  // -Y
    };
    Image out(4 * n, 3 * n, C);
    for (const Cell& cell : cells)
        for (int b = 0; b < n; ++b)
            for (int a = 0; a < n; ++a) {
                const double x = 2.0 * (a + 0.5) / n - 1.0;  // right
                const double y = 1.0 - 2.0 * (b + 0.5) / n;  // up
                const glm::dvec3 d = cell.forward + x * cell.right + y * cell.up;
                // Pixel centres of a cell are texel centres of its face, so this lookup
                // is exact (no ties at texel borders).
                const TexelCoord t = directionToTexel(n, d);
                const float* v = cube.texel(t.face, t.i, t.j);
                float* o = out.pixel(cell.col * n + a, cell.row * n + b);
                std::copy(v, v + C, o);
            }
    return out;
}

// ---------------------------------------------------------------- generated maps

Image constantEnvironment(int width, const glm::vec3& rgb) {
    requireLatLongWidth(width, "constantEnvironment");
    Image img(width, width / 2, 3);
    for (size_t p = 0; p < img.pixels.size(); p += 3) {
        img.pixels[p] = rgb.r;
        img.pixels[p + 1] = rgb.g;
        img.pixels[p + 2] = rgb.b;
    }
    return img;
}

Image sunEnvironment(int width, const glm::dvec3& direction, const glm::vec3& rgb) {
    requireLatLongWidth(width, "sunEnvironment");
    if (!(glm::length(direction) > 0.0))
        throw Error("sunEnvironment", "sun direction must be non-zero");
    const int height = width / 2;
    Image img(width, height, 3);
    const glm::dvec2 uv = directionToLatLong(direction);
    const int x = std::min(int(uv.x * width), width - 1);
    const int y = std::min(int(uv.y * height), height - 1);
    img.at(x, y, 0) = rgb.r;
    img.at(x, y, 1) = rgb.g;
    img.at(x, y, 2) = rgb.b;
    return img;
}

Image twoToneEnvironment(int width, const glm::vec3& upper, const glm::vec3& lower) {
    requireLatLongWidth(width, "twoToneEnvironment");
    const int height = width / 2;
    Image img(width, height, 3);
    for (int y = 0; y < height; ++y) {
        glm::vec3 v;
        if (2 * y + 1 < height) v = upper;            // row entirely above the horizon
        else if (2 * y + 1 > height) v = lower;       // entirely below
        else v = 0.5f * (upper + lower);              // odd height: middle row straddles
        for (int x = 0; x < width; ++x) {
            img.at(x, y, 0) = v.r;
            img.at(x, y, 1) = v.g;
            img.at(x, y, 2) = v.b;
        }
    }
    return img;
}

}  // namespace prt
