#include "relight/pointlight/translucent_shadow_map.h"

#include <tbb/parallel_for.h>
#include <xmmintrin.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include "common/error.h"
#include "common/util.h"

namespace prt {

namespace {

constexpr double kMaxConeDegrees = 140.0;
// Bound of cos_s / cos_g in a pixel's flux (see the header: interpolated normals facing
// the light on a face seen edge-on would give one pixel the flux of a wide strip).
constexpr double kMaxCosineRatio = 2.0;

// Two unit vectors completing w to a right-handed orthonormal frame.
void orthonormalBasis(const glm::dvec3& w, glm::dvec3& a, glm::dvec3& b) {
    const glm::dvec3 helper = std::abs(w.y) < 0.9 ? glm::dvec3(0, 1, 0) : glm::dvec3(1, 0, 0);
    a = glm::normalize(glm::cross(helper, w));
    b = glm::cross(w, a);
}

// The map-frame projection of one point's filter taps: tap q = x + o1 e1 + o2 e2 has
// map-frame coordinates X + o1 E1 + o2 E2 (linear in the offsets).
struct TapFrame {
    glm::vec3 X, E1, E2, x;
    float toPixel;  // pixels per unit of the image plane
    int resolution;
    bool perspective;
};

// Sum over the filter's taps of flux x K(r) x measure, RGB in the first three lanes. In
// blocks of taps: projections and distances in loops the compiler vectorises, the map
// and table reads apart, summed in pairs (sumInPairs). Compiled twice, for x86-64 and
// for AVX2 + FMA, and chosen once per process (cpuHasAvx2Fma), as
// texture_space_sampling.cpp's sums.
[[gnu::always_inline]] inline __m128 filterTapsBody(const TapFrame& fr, const ShadowMapTexel* texels,
                                                    const LocalFilter& filter) {
    const glm::vec3 X = fr.X, E1 = fr.E1, E2 = fr.E2, xf = fr.x;
    const bool perspective = fr.perspective;
    const int resolution = fr.resolution;
    const float toPixel = fr.toPixel, half = 0.5f * float(resolution);
    const float res = float(resolution);
    constexpr size_t kBlock = 128;
    int index[kBlock];
    float r2[kBlock], flux[kBlock], t[kBlock];
    __m128 sum = _mm_setzero_ps();
    const float rMax2 = filter.kernel.rMax2();
    const size_t taps = filter.tapOffset.size();
    const int last = resolution - 1;
    for (size_t begin = 0; begin < taps; begin += kBlock) {
        const size_t count = std::min(kBlock, taps - begin);
        const float* o1 = &filter.tapOffset1[begin];
        const float* o2 = &filter.tapOffset2[begin];
        // Plain floats, selects and non-short-circuit tests so that GCC vectorises it:
        // the perspective divide is by qz or by 1.
        const float zMin = perspective ? 0.0f : -std::numeric_limits<float>::infinity();
        const float zScale = perspective ? 1.0f : 0.0f, zBias = perspective ? 0.0f : 1.0f;
        const float lastF = float(last);
        for (size_t k = 0; k < count; ++k) {
            const float qx = X.x + o1[k] * E1.x + o2[k] * E2.x;
            const float qy = X.y + o1[k] * E1.y + o2[k] * E2.y;
            const float qz = X.z + o1[k] * E1.z + o2[k] * E2.z;
            const float inv = toPixel / (qz * zScale + zBias);
            const float px = qx * inv + half, py = qy * inv + half;
            const bool inside = (qz > zMin) & (px >= 0.0f) & (py >= 0.0f) & (px < res) & (py < res);
            const int ix = int(std::min(std::max(px, 0.0f), lastF)), iy = int(std::min(std::max(py, 0.0f), lastF));
            index[k] = inside ? iy * resolution + ix : -1;
        }
        // Without branches (a tap off the map or beyond the table reads pixel 0 and
        // gets flux 0): which taps land on lit pixels does not follow a pattern.
        for (size_t k = 0; k < count; ++k) {
            const ShadowMapTexel& tx = texels[size_t(std::max(index[k], 0))];
            const glm::vec3 d = xf - tx.position;
            r2[k] = glm::dot(d, d);
            flux[k] = index[k] >= 0 ? tx.flux : 0.0f;
        }
        for (size_t k = 0; k < count; ++k) {
            t[k] = filter.kernel.position(r2[k]);
            flux[k] = r2[k] < rMax2 ? flux[k] : 0.0f;
        }
        const glm::vec4* area = &filter.tapArea[begin];
        const auto term = [&](size_t k) {
            return _mm_mul_ps(_mm_mul_ps(_mm_set1_ps(flux[k]), filter.kernel.atSse(t[k])), _mm_loadu_ps(&area[k].x));
        };
        sum = _mm_add_ps(sum, sumInPairs(count, term));
    }
    return sum;
}

__m128 filterTapsBaseline(const TapFrame& fr, const ShadowMapTexel* texels, const LocalFilter& filter) {
    return filterTapsBody(fr, texels, filter);
}

#if defined(__x86_64__) && defined(__GNUC__)
__attribute__((target("avx2,fma"))) __m128 filterTapsAvx2(const TapFrame& fr, const ShadowMapTexel* texels,
                                                          const LocalFilter& filter) {
    return filterTapsBody(fr, texels, filter);
}
#endif

__m128 filterTaps(const TapFrame& fr, const ShadowMapTexel* texels, const LocalFilter& filter) {
#if defined(__x86_64__) && defined(__GNUC__)
    if (cpuHasAvx2Fma()) return filterTapsAvx2(fr, texels, filter);
#endif
    return filterTapsBaseline(fr, texels, filter);
}

}  // namespace

LocalFilter makeLocalFilter(RadialTable kernel, int rings, int ringSamples) {
    if (rings < 1) throw Error("--rings", "must be at least 1, got " + std::to_string(rings));
    if (ringSamples < 1) throw Error("--ring-samples", "must be at least 1, got " + std::to_string(ringSamples));
    LocalFilter f;
    f.rings = rings;
    f.ringSamples = ringSamples;
    // Cumulative planar importance of the kernel (mean of R, G, B) and of each channel
    // on a fine grid in t = sqrt(r / rMax) (trapezoids in r).
    const double rMax = kernel.rMax();
    const int steps = 20000;
    std::vector<double> r(steps + 1), cum(steps + 1, 0.0);
    std::vector<glm::dvec3> cumC(steps + 1, glm::dvec3(0.0));
    glm::dvec3 prev(0.0);
    for (int i = 0; i <= steps; ++i) {
        const double t = double(i) / steps;
        r[i] = std::min(rMax * t * t, rMax * (1.0 - 1e-9));
        const glm::dvec3 g = glm::dvec3(kernel(float(r[i] * r[i]))) * (2.0 * kPi * r[i]);
        if (i > 0) {
            cumC[i] = cumC[i - 1] + 0.5 * (g + prev) * (r[i] - r[i - 1]);
            cum[i] = (cumC[i].x + cumC[i].y + cumC[i].z) / 3.0;
        }
        prev = g;
    }
    f.kernel = std::move(kernel);
    f.radius.assign(size_t(rings), 0.0);
    f.area.assign(size_t(rings), glm::dvec3(0.0));
    const double total = cum.back();
    if (!(total > 0.0)) return f;
    auto inverse = [&](double value) {  // smallest r with cum(r) >= value, linear between nodes
        const auto it = std::lower_bound(cum.begin(), cum.end(), value);
        if (it == cum.begin()) return 0.0;
        if (it == cum.end()) return r.back();
        const size_t i = size_t(it - cum.begin());
        const double span = cum[i] - cum[i - 1];
        const double w = span > 0.0 ? (value - cum[i - 1]) / span : 0.0;
        return r[i - 1] + w * (r[i] - r[i - 1]);
    };
    auto channelIntegral = [&](double value) {  // per-channel int_0^r K 2 pi r dr at r = inverse(value)
        const auto it = std::lower_bound(cum.begin(), cum.end(), value);
        if (it == cum.begin()) return glm::dvec3(0.0);
        if (it == cum.end()) return cumC.back();
        const size_t i = size_t(it - cum.begin());
        const double span = cum[i] - cum[i - 1];
        const double w = span > 0.0 ? (value - cum[i - 1]) / span : 0.0;
        return cumC[i - 1] + w * (cumC[i] - cumC[i - 1]);
    };
    // Importance weights (Mertens et al.): a tap at radius rho stands for its share of
    // the annulus integral of K divided by K(rho), per channel, so that a lit plane
    // facing the light is filtered exactly whatever L and C.
    auto effectiveArea = [&](const glm::dvec3& integral, double rho, int taps) {
        const glm::dvec3 k(f.kernel(float(rho * rho)));
        glm::dvec3 a(0.0);
        for (int c = 0; c < 3; ++c) a[c] = k[c] > 0.0 ? integral[c] / (double(taps) * k[c]) : 0.0;
        return a;
    };
    const double held = 0.999 * total;
    f.rhoMax = inverse(held);
    const int parts = rings + 1;
    auto edgeValue = [&](int k) { return held * double(k) / parts; };
    f.centreArea = effectiveArea(channelIntegral(edgeValue(1)), 0.0, 1);
    for (int l = 0; l < rings; ++l) {
        const glm::dvec3 integral = channelIntegral(edgeValue(l + 2)) - channelIntegral(edgeValue(l + 1));
        f.radius[size_t(l)] = inverse(held * (double(l + 1) + 0.5) / parts);
        f.area[size_t(l)] = effectiveArea(integral, f.radius[size_t(l)], ringSamples);
    }
    f.tapOffset.push_back(glm::vec2(0.0f));
    f.tapOffset1.push_back(0.0f);
    f.tapOffset2.push_back(0.0f);
    f.tapArea.push_back(glm::vec4(glm::vec3(f.centreArea), 0.0f));
    const double step = 2.0 * kPi / ringSamples;
    for (int l = 0; l < rings; ++l) {
        const double offset = (l & 1) ? 0.5 : 0.0;
        for (int c = 0; c < ringSamples; ++c) {
            const double phi = (c + offset) * step;
            f.tapOffset.push_back(glm::vec2(glm::dvec2(std::cos(phi), std::sin(phi)) * f.radius[size_t(l)]));
            f.tapOffset1.push_back(f.tapOffset.back().x);
            f.tapOffset2.push_back(f.tapOffset.back().y);
            f.tapArea.push_back(glm::vec4(glm::vec3(f.area[size_t(l)]), 0.0f));
        }
    }
    return f;
}

TranslucentShadowMap::TranslucentShadowMap(const RayScene& scene, const TriangleMesh& mesh, const Light& light,
                                           const BoundingSphere& sphere, double eta, FresnelModel fresnel,
                                           int resolution)
    : light_(light), resolution_(resolution) {
    if (resolution < 16 || resolution > 8192)
        throw Error("--light-map", "resolution must be from 16 to 8192, got " + std::to_string(resolution));
    const double radius = std::max(sphere.radius, 1e-9) * 1.02;
    if (hasPosition(light)) {
        const glm::dvec3 toCentre = sphere.centre - light.position;
        const double d = glm::length(toCentre);
        const double half = d > radius ? std::asin(radius / d) : kPi;
        if (2.0 * half * 180.0 / kPi > kMaxConeDegrees)
            throw Error(light.source.empty() ? "light" : light.source,
                        "the point light is too close to the object for a translucent shadow map (the bounding "
                        "sphere spans " + (d > radius ? std::to_string(int(2.0 * half * 180.0 / kPi)) : std::string(">180")) +
                        " degrees from it, at most 140): move it farther or render without the local filter "
                        "(--split sampling)");
        origin_ = light.position;
        forward_ = toCentre / d;
        halfExtent_ = std::tan(half);
    } else {
        forward_ = -glm::normalize(light.direction);  // the direction light travels
        origin_ = sphere.centre - forward_ * (2.0 * radius);
        halfExtent_ = radius;
    }
    orthonormalBasis(forward_, right_, up_);

    const size_t n = size_t(resolution) * size_t(resolution);
    texels_.assign(n, Texel{});
    fluxScale_ = glm::vec3(light.rgb);
    const bool haveNormals = mesh.normals.size() == mesh.positions.size();
    std::vector<uint8_t> lit(n, 0);
    // 8 x 8 tiles, traced as four coherent 4 x 4 packets (intersectBatch).
    constexpr int kTile = 8;
    const int tiles = (resolution + kTile - 1) / kTile;
    tbb::parallel_for(0, tiles * tiles, [&](int tile) {
        const int tx = (tile % tiles) * kTile, ty = (tile / tiles) * kTile;
        float ox[64], oy[64], oz[64], dx[64], dy[64], dz[64];
        int px[64], py[64];
        Hit hits[64];
        int count = 0;
        for (int q = 0; q < 4; ++q)  // 4 x 4 quadrants of the tile
            for (int j = 0; j < 4; ++j)
                for (int i = 0; i < 4; ++i) {
                    const int x = tx + (q & 1) * 4 + i, y = ty + (q >> 1) * 4 + j;
                    if (x >= resolution || y >= resolution) continue;
                    const double a = ((x + 0.5) / resolution * 2.0 - 1.0) * halfExtent_;
                    const double b = ((y + 0.5) / resolution * 2.0 - 1.0) * halfExtent_;
                    glm::dvec3 org, dir;
                    if (hasPosition(light_)) {
                        org = origin_;
                        dir = glm::normalize(forward_ + a * right_ + b * up_);
                    } else {
                        org = origin_ + a * right_ + b * up_;
                        dir = forward_;
                    }
                    ox[count] = float(org.x); oy[count] = float(org.y); oz[count] = float(org.z);
                    dx[count] = float(dir.x); dy[count] = float(dir.y); dz[count] = float(dir.z);
                    px[count] = x;
                    py[count] = y;
                    ++count;
                }
        scene.intersectBatch(ox, oy, oz, dx, dy, dz, size_t(count), 0.0f, std::numeric_limits<float>::infinity(), hits);
        for (int k = 0; k < count; ++k) {
            const Hit& h = hits[k];
            if (!h.hit) continue;
            const glm::dvec3 dir(dx[k], dy[k], dz[k]);
            const glm::uvec3 t = mesh.triangles[h.triangle];
            const double u = h.u, v = h.v, w0 = 1.0 - u - v;
            const glm::dvec3 p = w0 * glm::dvec3(mesh.positions[t.x]) + u * glm::dvec3(mesh.positions[t.y]) +
                                 v * glm::dvec3(mesh.positions[t.z]);
            const glm::dvec3 ng(h.geometricNormal);
            glm::dvec3 ns = ng;
            if (haveNormals) {
                const glm::dvec3 s = w0 * glm::dvec3(mesh.normals[t.x]) + u * glm::dvec3(mesh.normals[t.y]) +
                                     v * glm::dvec3(mesh.normals[t.z]);
                const double len = glm::length(s);
                if (len > 1e-12 && glm::dot(s, ng) > 0.0) ns = s / len;
            }
            const glm::dvec3 toLight = -glm::normalize(dir);
            const double cosS = glm::dot(ns, toLight), cosG = glm::dot(ng, toLight);
            if (cosS <= 0.0 || cosG <= 1e-6) continue;
            // Point: E^ r^2 / cos_g = F I cos_s 1e6 / cos_g, flux per steradian;
            // directional: E^ / cos_g = F E_perp cos_s / cos_g, flux per mm^2 of beam;
            // both per unit of the light's colour (fluxScale_).
            double perMeasure = std::min(cosS / cosG, kMaxCosineRatio) * incidentTransmittance(fresnel, eta, cosS);
            if (hasPosition(light_)) perMeasure *= kSquareMmPerSquareMetre;
            // A spot's flux per steradian along this pixel's ray: I_0 falloff (the map's
            // rays leave the light, as spotFalloff's direction).
            if (light_.type == LightType::Spot) {
                perMeasure *= spotFalloff(light_, glm::normalize(dir));
                if (!(perMeasure > 0.0)) continue;  // outside the outer cone: not lit
            }
            const size_t i = size_t(py[k]) * size_t(resolution) + size_t(px[k]);
            texels_[i] = Texel{glm::vec3(p), float(perMeasure)};
            lit[i] = 1;
        }
    });
    for (uint8_t l : lit) litPixels_ += l;
}

bool TranslucentShadowMap::project(const glm::dvec3& q, double& px, double& py) const {
    double a, b;
    if (hasPosition(light_)) {
        const glm::dvec3 d = q - origin_;
        const double z = glm::dot(d, forward_);
        if (!(z > 0.0)) return false;
        a = glm::dot(d, right_) / z;
        b = glm::dot(d, up_) / z;
    } else {
        const glm::dvec3 d = q - origin_;
        a = glm::dot(d, right_);
        b = glm::dot(d, up_);
    }
    px = (a / halfExtent_ + 1.0) * 0.5 * resolution_;
    py = (b / halfExtent_ + 1.0) * 0.5 * resolution_;
    return px >= 0.0 && py >= 0.0 && px < resolution_ && py < resolution_;
}

double TranslucentShadowMap::pixelMeasure(int x, int y) const {
    const double step = 2.0 * halfExtent_ / resolution_;
    if (light_.type == LightType::Directional) return step * step;
    // Solid angle of a pixel of the image plane at unit distance: step^2 cos^3 of its
    // angle off the axis (at its centre).
    const double a = ((x + 0.5) / resolution_ * 2.0 - 1.0) * halfExtent_;
    const double b = ((y + 0.5) / resolution_ * 2.0 - 1.0) * halfExtent_;
    const double c = 1.0 / std::sqrt(1.0 + a * a + b * b);
    return step * step * c * c * c;
}

bool TranslucentShadowMap::tapPlane(const glm::dvec3& x, glm::dvec3& e1, glm::dvec3& e2,
                                   double& measureScale) const {
    glm::dvec3 w = forward_;  // the light's ray direction at x
    measureScale = 1.0;
    if (hasPosition(light_)) {
        const glm::dvec3 d = x - origin_;
        const double d2 = glm::dot(d, d);
        if (!(d2 > 0.0)) return false;
        w = d / std::sqrt(d2);
        measureScale = 1.0 / d2;
    }
    orthonormalBasis(w, e1, e2);
    return true;
}

glm::dvec3 TranslucentShadowMap::localExitance(const glm::dvec3& x, const LocalFilter& filter) const {
    glm::dvec3 e1, e2;
    double measureScale = 1.0;
    if (!(filter.rhoMax > 0.0) || !tapPlane(x, e1, e2, measureScale)) return glm::dvec3(0.0);
    // The projection in float, relative to the map's origin: tap q = x + o1 e1 + o2 e2
    // has map-frame coordinates (a, b, z) = X + o1 E1 + o2 E2 (linear in the offsets).
    const glm::dvec3 rel = x - origin_;
    const glm::vec3 X(glm::dot(rel, right_), glm::dot(rel, up_), glm::dot(rel, forward_));
    const glm::vec3 E1(glm::dot(e1, right_), glm::dot(e1, up_), glm::dot(e1, forward_));
    const glm::vec3 E2(glm::dot(e2, right_), glm::dot(e2, up_), glm::dot(e2, forward_));
    const TapFrame frame{X, E1, E2, glm::vec3(x), float(0.5 * resolution_ / halfExtent_), resolution_,
                         hasPosition(light_)};
    const __m128 sum = filterTaps(frame, texels_.data(), filter);
    alignas(16) float total[4];
    _mm_store_ps(total, sum);
    return glm::dvec3(glm::vec3(total[0], total[1], total[2]) * fluxScale_) * measureScale;
}

glm::dvec3 TranslucentShadowMap::localExitanceReference(const glm::dvec3& x, const LocalFilter& filter) const {
    glm::dvec3 e1, e2;
    double measureScale = 1.0;
    if (!(filter.rhoMax > 0.0) || !tapPlane(x, e1, e2, measureScale)) return glm::dvec3(0.0);
    glm::dvec3 sum(0.0);
    for (size_t k = 0; k < filter.tapOffset.size(); ++k) {
        const glm::dvec3 q = x + double(filter.tapOffset[k].x) * e1 + double(filter.tapOffset[k].y) * e2;
        double px = 0.0, py = 0.0;
        if (!project(q, px, py)) continue;
        const Texel& t = texels_[size_t(py) * size_t(resolution_) + size_t(px)];
        if (t.flux == 0.0f) continue;
        const glm::dvec3 d = x - glm::dvec3(t.position);
        const double r2 = glm::dot(d, d);
        if (!(r2 < double(filter.kernel.rMax2()))) continue;
        sum += double(t.flux) * glm::dvec3(filter.kernel(float(r2))) * glm::dvec3(glm::vec3(filter.tapArea[k]));
    }
    return sum * glm::dvec3(fluxScale_) * measureScale;
}

glm::dvec3 TranslucentShadowMap::exitanceAllPixels(const glm::dvec3& x, const RadialTable& kernel) const {
    glm::dvec3 sum(0.0);
    const glm::vec3 xf(x);
    for (int y = 0; y < resolution_; ++y)
        for (int px = 0; px < resolution_; ++px) {
            const size_t i = size_t(y) * size_t(resolution_) + size_t(px);
            const float f = texels_[i].flux;
            if (f == 0.0f) continue;
            const glm::vec3 d = xf - texels_[i].position;
            sum += glm::dvec3(f * fluxScale_ * kernel(glm::dot(d, d))) * pixelMeasure(px, y);
        }
    return sum;
}

glm::dvec3 TranslucentShadowMap::totalFlux() const {
    glm::dvec3 sum(0.0);
    for (int y = 0; y < resolution_; ++y)
        for (int x = 0; x < resolution_; ++x)
            sum += double(texels_[size_t(y) * size_t(resolution_) + size_t(x)].flux) * glm::dvec3(fluxScale_) *
                   pixelMeasure(x, y);
    return sum;
}

glm::dvec3 TranslucentShadowMap::normalisePower(const glm::dvec3& power) {
    const glm::dvec3 held = totalFlux();
    glm::dvec3 factor(1.0);
    for (int c = 0; c < 3; ++c)
        if (held[c] > 0.0 && power[c] > 0.0 && std::isfinite(power[c])) factor[c] = power[c] / held[c];
    fluxScale_ *= glm::vec3(factor);
    return factor;
}

}  // namespace prt
