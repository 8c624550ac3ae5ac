#pragma once
// A single-scattering path inside a medium: the formulas that the precompute's
// environment single scattering (precompute/passes/single_scattering.h, Wang et al.
// 2005, Eqs. 4, 5, 10, 11; docs/single-scattering.md) and the point-light renderer's
// (relight/pointlight/point_single_scattering.h) both use, in one place:
//   * the deterministic importance samples of the depth s along the path (Wang Sec. 3)
//         s_i = -ln(1 - lambda xi_i) / sigma,
//         lambda = 1 - e^(-sigma d_m),  pdf(s) = sigma e^(-sigma s) / lambda,
//     each weighted w_i / pdf(s_i), where (xi_i, w_i) is a quadrature rule on [0, 1]
//     (PathQuadrature): Wang's midpoints xi_i = (i - 0.5) / N, w_i = 1 / N, or the
//     N-point Gauss-Legendre rule;
//   * Jensen et al. 2001's Eq. 5 estimate of the light's refracted path inside;
//   * d_m, where a ray into the medium leaves the object.
//
// Units: lengths in mm, coefficients in mm^-1.

#include <glm/glm.hpp>

#include <vector>

#include "common/raytrace.h"

namespace prt {

// One deterministic path sample: its depth s (mm) below x_o and the estimator weight
// 1 / (N pdf(s)) (mm), so that sum_i f(s_i) weight_i estimates int_0^{d_m} f(s) ds.
struct PathSample {
    double distance = 0.0;
    double weight = 0.0;
};
// lambda = 1 - e^(-sigma d_m) (computed with expm1, accurate for small sigma d_m).
double pathSampleLambda(double sigma, double dm);
// s(xi) = -ln(1 - lambda xi) / sigma (log1p), in [0, d_m] for xi in [0, 1].
double pathSampleDistance(double sigma, double dm, double xi);
// pdf(s) = sigma e^(-sigma s) / lambda on [0, d_m] (0 outside).
double pathSamplePdf(double sigma, double dm, double s);
// The rule on [0, 1] in xi = the sampled mass, in which a flat surface's integrand is
// (1 - lambda xi)^p, p = sigma_t^c (1 + 1/cos_t) / |sigma_t| - 1 in [0.7, 2.6]: smooth, so
// a few Gauss-Legendre points integrate it as well as many midpoints. Geometry (exits
// that jump to another surface as the depth grows, shadow edges) makes it non-smooth,
// where no rule has an order (docs/single-scattering.md, "Gauss path samples").
// Its names and the precompute's defaults (toString, parsePathQuadrature,
// defaultPathSamples): precompute/passes/single_scattering.h.
enum class PathQuadrature {
    Midpoint,      // xi_i = (i - 0.5) / N, w_i = 1 / N (Wang 2005)
    GaussLegendre, // the N Gauss-Legendre nodes and weights mapped to [0, 1]
};
struct QuadratureNode {
    double xi = 0.0;
    double weight = 0.0;
};
// The N-point rule on [0, 1]: nodes increasing, weights summing to 1. Gauss-Legendre
// nodes by Newton's iteration on P_N (to ~1e-15). Throws unless 1 <= count <= 4096
// (prt::Error("--path-samples", ...)).
std::vector<QuadratureNode> pathQuadratureRule(PathQuadrature rule, int count);
// The N samples of `rule`, increasing in depth: s_i = s(xi_i), weight w_i / pdf(s_i)
// (1 / (N pdf(s_i)) for the midpoint rule). Throws prt::Error unless sigma > 0, d_m > 0
// (both finite) and count >= 1.
std::vector<PathSample> makePathSamples(double sigma, double dm, int count,
                                        PathQuadrature rule = PathQuadrature::Midpoint);
// The same from a rule made once (pathQuadratureRule), without allocating the rule;
// `kind` is the rule it was made with.
void makePathSamples(double sigma, double dm, const std::vector<QuadratureNode>& rule,
                     PathQuadrature kind, std::vector<PathSample>& out);

// Eq. 5: the refracted incident path length s_i' from the observed (unrefracted)
// length s_i and cos_i = |w_j . n_i|: s_i cos_i / sqrt(1 - (1 - cos_i^2) / eta^2).
// Returns a negative value on total internal reflection (only possible for eta < 1).
double refractedPathLength(double observedLength, double cosI, double eta);

// d_m: distance from `position` along -normal to where that ray leaves the object:
// the first hit on a triangle facing along the ray (the ray starts offset inward off
// the surface). Up to 8 hits on triangles facing against the ray (the vertex is on a
// flap or sheet lying outside the body, as in scanned meshes; or the winding is
// inconsistent) are passed through first; when only such hits exist the first one
// is used. hit = false and distance = cap when the ray hits nothing (an open mesh
// seen from inside). `normal` need not be the surface normal: a path along any
// direction d into the medium (the point-light renderer's refracted view ray) passes
// normal = -d.
struct FarSide {
    double distance = 0.0;
    bool hit = false;
};
FarSide farSideDistance(const RayScene& scene, const glm::vec3& position,
                        const glm::vec3& normal, double cap);

}  // namespace prt
