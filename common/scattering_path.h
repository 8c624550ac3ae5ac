#pragma once
// A single-scattering path inside a medium, for the renderers outside the precompute
// (relight/pointlight/point_single_scattering.h): Jensen et al. 2001's Eq. 5 estimate of
// the light's refracted path, depth samples along a ray by the importance sampling of
// Wang et al. 2005 Sec. 3 with Gauss-Legendre nodes, and where a ray leaves the object.
// The same formulas as precompute/passes/single_scattering.h's helpers
// (refractedPathLength, pathQuadratureRule, makePathSamples, farSideDistance), which
// the rooms above the precompute cannot include; header-only (inline).
//
// Units: lengths in mm, coefficients in mm^-1.

#include <glm/glm.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "common/error.h"
#include "common/raytrace.h"
#include "common/util.h"

namespace prt {

// Eq. 5 (Jensen et al. 2001): the refracted length s_i' of the light's path inside,
// from its observed (straight, unrefracted) length s_i to the entry point and
// cos_i = |w . n_i| there: s_i cos_i / sqrt(1 - (1 - cos_i^2) / eta^2). Negative on
// total internal reflection (eta < 1 only).
inline double refractedEntryLength(double observedLength, double cosI, double eta) {
    const double c = std::min(std::abs(cosI), 1.0);
    const double cos2t = 1.0 - (1.0 - c * c) / (eta * eta);
    if (cos2t <= 0.0) return -1.0;
    return observedLength * c / std::sqrt(cos2t);
}

// The N-point Gauss-Legendre rule on [0, 1] (nodes increasing, weights summing to 1),
// by Newton's iteration on P_N from cos(pi (i - 1/4) / (N + 1/2)). Throws prt::Error
// unless 1 <= count <= 4096.
struct DepthNode {
    double xi = 0.0;
    double weight = 0.0;
};
inline std::vector<DepthNode> gaussLegendreDepthRule(int count) {
    if (count < 1 || count > 4096)
        throw Error("path samples", "must be between 1 and 4096, got " + std::to_string(count));
    auto legendre = [count](double x) {  // {P_N(x), P_N'(x)} by the three-term recurrence
        double p0 = 1.0, p1 = x;
        for (int k = 2; k <= count; ++k) {
            const double p2 = ((2 * k - 1) * x * p1 - (k - 1) * p0) / k;
            p0 = p1;
            p1 = p2;
        }
        return std::pair{p1, count * (x * p1 - p0) / (x * x - 1.0)};
    };
    std::vector<DepthNode> out(static_cast<size_t>(count));
    for (int i = 1; i <= count; ++i) {
        double x = std::cos(kPi * (i - 0.25) / (count + 0.5));
        for (int iter = 0; iter < 100; ++iter) {
            const double dx = legendre(x).first / legendre(x).second;
            x -= dx;
            if (std::abs(dx) < 1e-15) break;
        }
        const double dp = legendre(x).second;
        out[size_t(i - 1)] = {0.5 * (1.0 - x), 1.0 / ((1.0 - x * x) * dp * dp)};
    }
    return out;
}

// Depth samples on [0, d_m] for an integrand that decays as e^(-sigma s): the rule's
// nodes mapped through the exponential pdf's inverse CDF,
//   s = -ln(1 - lambda xi) / sigma,  lambda = 1 - e^(-sigma d_m),
//   weight = w / pdf(s),  pdf(s) = sigma e^(-sigma s) / lambda,
// so that sum f(s_k) weight_k estimates int_0^{d_m} f(s) ds. Throws prt::Error unless
// sigma > 0 and d_m > 0 (finite).
struct DepthSample {
    double distance = 0.0;  // mm
    double weight = 0.0;    // mm
};
inline void exponentialDepthSamples(double sigma, double dm, const std::vector<DepthNode>& rule,
                                    std::vector<DepthSample>& out) {
    if (!(sigma > 0.0) || !std::isfinite(sigma)) throw Error("single scattering", "|sigma_t| must be a positive number");
    if (!(dm > 0.0) || !std::isfinite(dm)) throw Error("single scattering", "the path depth must be a positive number");
    const double lambda = -std::expm1(-sigma * dm);
    out.resize(rule.size());
    for (size_t i = 0; i < rule.size(); ++i) {
        const double s = std::min(-std::log1p(-lambda * rule[i].xi) / sigma, dm);
        out[i] = {s, rule[i].weight * lambda / (sigma * std::exp(-sigma * s))};
    }
}

// Where the ray from a surface point along `direction` (into the medium) leaves the
// object: the distance to the first hit on a triangle facing along the ray, passing
// through up to 8 facing against it (a flap or sheet outside the body, inconsistent
// winding); the first hit when there are only such; hit = false and `cap` when it
// hits nothing (an open mesh). The ray starts offset off the surface along `direction`.
struct ExitDistance {
    double distance = 0.0;
    bool hit = false;
};
inline ExitDistance exitDistance(const RayScene& scene, const glm::vec3& position, const glm::vec3& direction,
                                 double cap) {
    glm::vec3 org = scene.offsetRayOrigin(position, -direction, direction);
    double first = -1.0;
    for (int k = 0; k <= 8; ++k) {
        const Hit h = scene.intersect(org, direction, 0.0f, std::numeric_limits<float>::infinity());
        if (!h.hit) break;
        const glm::vec3 p = org + h.t * direction;
        const double d = std::max(double(glm::length(p - position)), 0.0);
        if (first < 0.0) first = d;
        if (glm::dot(direction, h.geometricNormal) > 0.0f) return {d, true};
        org = scene.offsetRayOrigin(p, h.geometricNormal, direction);
    }
    if (first >= 0.0) return {first, true};
    return {cap, false};
}

}  // namespace prt
