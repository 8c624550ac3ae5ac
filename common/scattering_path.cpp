#include "common/scattering_path.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <utility>

#include "common/error.h"
#include "common/util.h"

namespace prt {

double pathSampleLambda(double sigma, double dm) { return -std::expm1(-sigma * dm); }

double pathSampleDistance(double sigma, double dm, double xi) {
    return -std::log1p(-pathSampleLambda(sigma, dm) * xi) / sigma;
}

double pathSamplePdf(double sigma, double dm, double s) {
    if (s < 0 || s > dm) return 0.0;
    return sigma * std::exp(-sigma * s) / pathSampleLambda(sigma, dm);
}

std::vector<QuadratureNode> pathQuadratureRule(PathQuadrature rule, int count) {
    if (count < 1 || count > 4096)
        throw Error("--path-samples", "must be between 1 and 4096, got " + std::to_string(count));
    const size_t n = size_t(count);
    std::vector<QuadratureNode> out(n);
    if (rule == PathQuadrature::Midpoint) {
        for (int i = 1; i <= count; ++i) out[size_t(i - 1)] = {(i - 0.5) / count, 1.0 / count};
        return out;
    }
    // Gauss-Legendre on [-1, 1]: the roots of P_N by Newton's iteration from the
    // classic initial guess cos(pi (i - 1/4) / (N + 1/2)), weights 2 / ((1 - x^2) P_N'(x)^2);
    // then x -> (1 - x) / 2 (root i = 1 is the largest x, so xi increases with i).
    auto legendre = [count](double x) {  // {P_N(x), P_N'(x)} by the three-term recurrence
        double p0 = 1.0, p1 = x;
        for (int k = 2; k <= count; ++k) {
            const double p2 = ((2 * k - 1) * x * p1 - (k - 1) * p0) / k;
            p0 = p1;
            p1 = p2;
        }
        return std::pair{p1, count * (x * p1 - p0) / (x * x - 1.0)};
    };
    for (int i = 1; i <= count; ++i) {
        double x = std::cos(kPi * (i - 0.25) / (count + 0.5));
        for (int iter = 0; iter < 100; ++iter) {
            const auto [p, dp] = legendre(x);
            const double dx = p / dp;
            x -= dx;
            if (std::abs(dx) < 1e-15) break;
        }
        const double dp = legendre(x).second;
        out[size_t(i - 1)] = {0.5 * (1.0 - x), 1.0 / ((1.0 - x * x) * dp * dp)};
    }
    return out;
}

void makePathSamples(double sigma, double dm, const std::vector<QuadratureNode>& rule,
                     PathQuadrature kind, std::vector<PathSample>& out) {
    if (!(sigma > 0) || !std::isfinite(sigma))
        throw Error("single scattering", "|sigma_t| must be a positive number");
    if (!(dm > 0) || !std::isfinite(dm))
        throw Error("single scattering", "the path length d_m must be a positive number");
    if (rule.empty()) throw Error("--path-samples", "must be at least 1");
    const double lambda = pathSampleLambda(sigma, dm);
    const size_t count = rule.size();
    out.resize(count);
    for (size_t i = 0; i < count; ++i) {
        const double xi = rule[i].xi;
        const double s = -std::log1p(-lambda * xi) / sigma;
        // w / pdf(s) = w lambda e^(sigma s) / sigma = w lambda / ((1 - lambda xi) sigma).
        // The midpoint rule keeps its historical expression (w = 1 / N folded into the
        // denominator), so its samples stay bit-identical to those of earlier files.
        const double weight = kind == PathQuadrature::Midpoint
                                  ? lambda / ((1.0 - lambda * xi) * double(count) * sigma)
                                  : rule[i].weight * lambda / ((1.0 - lambda * xi) * sigma);
        out[i] = {s, weight};
    }
}

std::vector<PathSample> makePathSamples(double sigma, double dm, int count, PathQuadrature rule) {
    if (count < 1) throw Error("--path-samples", "must be at least 1");
    std::vector<PathSample> out;
    makePathSamples(sigma, dm, pathQuadratureRule(rule, count), rule, out);
    return out;
}

double refractedPathLength(double observedLength, double cosI, double eta) {
    const double c = std::min(std::abs(cosI), 1.0);
    const double cos2t = 1.0 - (1.0 - c * c) / (eta * eta);
    if (cos2t <= 0.0) return -1.0;
    return observedLength * c / std::sqrt(cos2t);
}

FarSide farSideDistance(const RayScene& scene, const glm::vec3& position, const glm::vec3& normal,
                        double cap) {
    const glm::vec3 dir = -normal;
    glm::vec3 org = scene.offsetRayOrigin(position, normal, dir);
    double first = -1.0;
    // Walk through up to kMaxSkips triangles facing against the ray (entering the
    // object: the vertex lies on a flap or sheet outside the body, as in scanned
    // meshes) to the first triangle facing along it, where the ray leaves.
    constexpr int kMaxSkips = 8;
    for (int k = 0; k <= kMaxSkips; ++k) {
        const Hit h = scene.intersect(org, dir, 0.0f, std::numeric_limits<float>::infinity());
        if (!h.hit) break;
        const glm::vec3 p = org + h.t * dir;
        // Distance from the surface point itself (the offsets are a few ulps of the
        // coordinates; measured from x_o the samples stay inside [0, d_m]).
        const double d = std::max(double(glm::length(p - position)), 0.0);
        if (first < 0.0) first = d;
        if (glm::dot(dir, h.geometricNormal) > 0.0f) return {d, true};
        org = scene.offsetRayOrigin(p, h.geometricNormal, dir);
    }
    if (first >= 0.0) return {first, true};  // only entering hits: keep the first
    return {cap, false};
}

}  // namespace prt
