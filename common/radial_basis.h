#pragma once
// A fixed radial basis for the dipole profile R_d, so that the material and the
// object's size can be edited after the precompute (SPEC section 5; docs/radial-basis.md).
//
// Multiple scattering at a vertex is T_c(x_o) = sum_i R_d,c(|x_o - x_i|) A_i E_i per
// colour channel c. Writing R_d,c(r) ~ sum_j w_cj B_j(r) for J fixed profiles B_j lets
// the precompute store one transport vector per profile; a material edit is then a new
// weight vector w_c per channel (weights(), microseconds). A size change by a factor s
// equals the material with sigma_a and sigma_s' multiplied by s at the file's geometry
// (R_d(r; s sigma) = s^2 R_d(s r; sigma)), so the basis only ever approximates dipoles of
// materials at the FILE's scale.
//
// Units: r and z_r in mm, B_j and R_d in mm^-2, weights dimensionless.
//
// The family. With eta fixed (z_v = z_r (1 + 4A/3)), one channel's R_d is alpha' times a
// shape that depends on z_r = 1/sigma_t' and alpha' (sigma_tr z_r = sqrt(3 (1 - alpha'))).
// A RadialRange is the rectangle of (z_r, alpha') the basis is built for, and the
// interval [0, rMax] of distances it is fitted on (rMax = the object's bounding-sphere
// diameter: no two surface points are further apart).
//
// The fit norm. weights() minimises the discrete weighted least-squares error
//     || fit - R_d ||^2 = int_0^rMax (fit(r) - R_d(r))^2 r^3 dr
// (by default, normExponent p = 3: weight r^p dr), subject to the exact constraint
//     int_0^rMax fit(r) 2 pi r dr = int_0^rMax R_d(r) 2 pi r dr
// (dipoleDiffuseReflectanceWithin, held to rounding). Why r^3: int e^2 r^3 dr =
// int (r^2 e)^2 d(ln r), the L2 norm, in log r, of the reflected power per unit log r,
// r^2 e(r) (up to 2 pi). The errors that matter downstream are relative L1 errors in
// the area measure, int |e| 2 pi r dr = 2 pi int |r^2 e| d(ln r), which Cauchy-Schwarz
// bounds by this norm; and the norm is scale invariant (R_d of z_r and of 10 z_r,
// each normalised to unit integral, have the same norm), so no width of profile
// dominates the fit. Plain area L2 (p = 1) weights the narrowest profiles' peaks by
// 1/z_r and fits wide materials poorly (measured in docs/radial-basis.md).
//
// Tabulation. Each B_j is stored at nodes r_k = r0 sinh(k h), k = 0 .. N-1, with
// r0 = z_r,min / 4 and r_{N-1} = rMax: evenly spaced (r0 h) below r0, geometric
// (ratio e^h) above, so the peak of the narrowest profile gets ~ 2/h nodes within z_r
// and the tail a constant number per octave. Between nodes B_j is linear IN r (so its
// area integral is exact in closed form). Beyond rMax it is held at its value at rMax.
// With the default step h = 1/64 the linear interpolation of any dipole of the range
// errs by less than 2e-4 relative L1, falling as h^2 (the tabulated basis is what is
// fitted, so this error is part of every fit error below, not in addition to it).
//
// Constructions (RadialConstruction): PCA of normalised dipole snapshots covering the
// range (the default), a greedy reduced basis of the same snapshots (worst snapshot
// first), and a geometric ladder of exponentials. The measured accuracy of each, per J,
// is in docs/radial-basis.md.
//
// Errors: every failure a user can cause (an invalid range, a material outside it, bad
// tables) throws prt::Error with a one-line reason.

#include "common/bssrdf.h"
#include "common/materials.h"

#include <array>
#include <string>
#include <vector>

namespace prt {

// ---------------------------------------------------------------------------
// Range
// ---------------------------------------------------------------------------

// The dipoles a basis must represent: z_r in [zrMin, zrMax] (mm, at the file's scale),
// alpha' in [alphaMin, alphaMax], relative index eta, distances r in [0, rMax] (mm).
struct RadialRange {
    double zrMin = 0.0, zrMax = 0.0;
    double alphaMin = 0.0, alphaMax = 0.0;
    double eta = 1.3;
    double rMax = 0.0;
};

// Throws prt::Error("radial range", reason) unless every field is finite and
// 0 < zrMin <= zrMax, 0 < alphaMin <= alphaMax < 1 (alpha' = 1, sigma_a = 0, has no
// decay length: a sum of fixed profiles cannot follow it), kMinEta <= eta <= kMaxEta,
// rMax > 0, and rMax / zrMin <= 1e7 (the table would need too many nodes).
void validateRadialRange(const RadialRange& range);

// The smallest range that holds every channel of every material at every size factor
// s in [sMin, sMax] (s multiplies sigma_a and sigma_s', so z_r becomes z_r / s and
// alpha' is unchanged), for distances up to rMax. Throws prt::Error naming the material
// when one has sigma_a = 0 in a channel, or when the materials' eta differ; and
// ("size factor", ...) unless 0 < sMin <= sMax, finite; then validates the result.
RadialRange rangeCovering(const std::vector<Material>& materials, double sMin, double sMax,
                          double rMax);

// ---------------------------------------------------------------------------
// Basis
// ---------------------------------------------------------------------------

enum class RadialConstruction {
    Pca = 0,          // leading left singular vectors of weighted, normalised snapshots
    Greedy = 1,       // Gram-Schmidt of snapshots, each time the worst-fitted one
    ExpLadder = 2,    // e^(-r/l_j) / (2 pi l_j^2), l_j geometric over the range's widths
};
const char* radialConstructionName(RadialConstruction c);

struct RadialBasisOptions {
    RadialConstruction construction = RadialConstruction::Pca;
    int size = 12;              // J, the number of profiles: 1 .. 64
    double normExponent = 3.0;  // p of the fit norm int e^2 r^p dr: 1, 2 or 3 (see top)
    double gridStep = 1.0 / 64.0;  // h of the table nodes r0 sinh(k h): (0, 0.25]
};

// What a file stores to rebuild a basis exactly (together with the RadialRange).
// values[k * size + j] = B_j(r_k), node-major (evaluate() reads one contiguous row).
// The node radii are r0 sinh(k h) with r0 = zrMin / 4 and h = asinh(rMax / r0) /
// (nodeCount - 1); the fit's Gram matrix, quadrature and constraint are recomputed
// from these tables, range and normExponent by deterministic code, so a basis built
// from stored tables gives the same weights, bit for bit, as the one that wrote them.
struct RadialBasisTables {
    int size = 0;                 // J
    int nodeCount = 0;            // N
    RadialConstruction construction = RadialConstruction::Pca;  // informational
    double normExponent = 3.0;
    std::vector<float> values;    // N * J
};

// One channel's fit errors over [0, rMax] (all relative, >= 0). With e = fit - R_d and
// the area measure dA = 2 pi r dr:
//   l1       int |e| dA / int R_d dA
//   integral |int e dA| / int R_d dA (the constraint: rounding only)
//   moment1, moment2   |int e r^k dA| / int R_d r^k dA for k = 1, 2
//   disk     max over R in [0, rMax] of |int_0^R e dA| / int R_d dA, the error of the
//            light diffused out of a uniformly lit disk of radius R (what an image of a
//            flat lit region sees)
struct RadialFitError {
    double l1 = 0.0;
    double integral = 0.0;
    double moment1 = 0.0;
    double moment2 = 0.0;
    double disk = 0.0;
};

class RadialBasis {
public:
    // Rebuilds a stored basis. Throws prt::Error("radial basis", reason) when the range
    // is invalid, size or nodeCount out of bounds (1 .. 64, 2 .. 1e6), values has the
    // wrong length or a non-finite entry, or the profiles are linearly dependent in the
    // fit norm.
    RadialBasis(const RadialRange& range, RadialBasisTables tables);

    int size() const { return tables_.size; }
    const RadialRange& range() const { return range_; }
    const RadialBasisTables& tables() const { return tables_; }
    // Node radii r_k (mm), N of them, r_0 = 0, r_{N-1} = rMax.
    const std::vector<double>& nodes() const { return nodes_; }

    // B_j(r), mm^-2 (table interpolation). Preconditions: 0 <= j < size(), r >= 0.
    double profile(int j, double r) const;
    // All J values B_0(r) .. B_{J-1}(r) into out[0 .. J-1]: a table lookup (one asinh)
    // and 2J multiply-adds. Precondition: r >= 0 (r > rMax is clamped to rMax).
    void evaluate(double r, float* out) const;
    // sum_j weights[j] B_j(r), mm^-2 (weights.size() == size()).
    double fit(const std::vector<double>& weights, double r) const;
    // int_0^rMax B_j(r) 2 pi r dr, exact for the interpolated table.
    const std::vector<double>& profileIntegrals() const { return integrals_; }

    // True when the dipole lies in the range: z_r in [zrMin, zrMax] and alpha' in
    // [alphaMin, alphaMax] (both to 1e-9 relative, so a range computed by rangeCovering
    // covers its own materials despite rounding), and z_v / z_r is the range's eta's.
    bool covers(const DipoleChannel& d) const;
    // Throws prt::Error(material name, "channel G at size factor 2: z_r = ... mm is below
    // the basis range's z_r min ... mm") for the first channel of m scaled by sizeFactor
    // that is not covered, naming the violated bound (z_r min/max, alpha' min/max,
    // sigma_a = 0, eta).
    void requireCovered(const Material& m, double sizeFactor = 1.0) const;

    // The J weights of one channel's R_d: the constrained least-squares fit described
    // at the top of this file. A few microseconds (one dipole evaluation per quadrature
    // node, ~200, and a J x J back-substitution). Does not check coverage: outside the
    // range the fit is merely poor (use covers / requireCovered).
    std::vector<double> weights(const DipoleChannel& d) const;
    // Per channel weights of m with sigma_a and sigma_s' multiplied by sizeFactor, after
    // requireCovered(m, sizeFactor).
    std::array<std::vector<double>, 3> materialWeights(const Material& m,
                                                       double sizeFactor = 1.0) const;

    // Fit errors of weights(d) against d, or of any weights (measured with Gauss
    // quadrature on the table intervals, ~1e-9 relative).
    RadialFitError fitError(const DipoleChannel& d) const;
    RadialFitError fitError(const DipoleChannel& d, const std::vector<double>& weights) const;

    // The radius (mm) within which profile j holds half of int_0^rMax |B_j| 2 pi r dr:
    // its width, which the precompute's near-field quadrature must resolve.
    double halfWidth(int j) const;

private:
    friend RadialBasis makeRadialBasis(const RadialRange&, const RadialBasisOptions&);
    void locate(double r, int& k, double& f) const;

    RadialRange range_;
    RadialBasisTables tables_;
    double r0_ = 0.0, step_ = 0.0, invStep_ = 0.0;
    std::vector<double> nodes_;
    std::vector<double> invSpacing_;
    std::vector<double> integrals_;            // c_j
    // The fit: quadrature nodes/weights of the norm, basis at the nodes (Q x J, node-major),
    // and the factorised constrained normal equations.
    std::vector<double> quadR_, quadW_, quadB_;
    std::vector<double> gramInverse_;          // J x J, G^-1
    std::vector<double> gramInverseC_;         // G^-1 c
    double cGramInverseC_ = 0.0;               // c . G^-1 c
};

// The accuracy contract, tested in tests/test_radial_basis.cpp for the default
// construction (PCA, p = 3, h = 1/64): worst RadialFitError over every channel of the 11
// measured materials with sigma_a > 0 (materialNames() less Spectralon) at size factors
// s in {0.5, 1, 2}, on the range rangeCovering(those, 0.5, 2, 30 mm) (z_r spans 2.25
// decades, alpha' 0.02 .. 0.99997), and of Marble alone on rangeCovering({Marble},
// 0.5, 2, 30 mm). `moment` bounds both moment1 and moment2; the integral is exact to
// rounding (1e-12) in every case. The moments of strongly absorbing channels (Ketchup
// G and B: alpha' < 0.07) are the hardest: their R_d r^2 tail is tiny, so the fit's
// small absolute tail error is a large relative one.
struct RadialFitTolerance {
    double l1, disk, moment;
};
inline constexpr RadialFitTolerance kRadialToleranceMeasuredJ12{1.0e-2, 1.5e-3, 0.35};
inline constexpr RadialFitTolerance kRadialToleranceMeasuredJ16{7.0e-4, 1.0e-4, 2.5e-2};
inline constexpr RadialFitTolerance kRadialToleranceMarbleJ12{1.0e-4, 1.0e-5, 1.5e-4};

// Builds a basis of options.size profiles for the range (validated first). Throws
// prt::Error("radial basis options", ...) for options out of their bounds. Its cost
// (the snapshots and their SVD) is in docs/radial-basis.md, "Cost".
RadialBasis makeRadialBasis(const RadialRange& range, const RadialBasisOptions& options = {});

// The same fits in balanced coordinates: profiles B' = B A with A = Q Lambda^(1/2),
// Q Lambda Q^T = G = mean over `dipoles` of w w^T (their weights in `basis`), so that
// the weights in B' have identity second moments over those dipoles. A vector of
// per-profile values u (one entry of every profile's transport vector) then has
// Euclidean norm ||A^T u||^2 = u^T G u in B', the mean over the dipoles of the squared
// recombined value (sum_j w_j u_j)^2: truncating per-profile vectors jointly by their
// Euclidean norm in B' keeps what the covered materials need, where in B it would keep
// what the profiles' arbitrary scales favour. Eigenvalues below 1e-9 of the largest are
// raised to it (B' stays independent). The range and options are kept; the tables are
// B's times A. `importance` (empty: all 1, else one weight >= 0 per dipole, not all 0)
// weights the mean: G = sum_i importance_i w_i w_i^T / sum_i importance_i. Throws
// prt::Error("radial basis", ...) for an empty list or bad importance weights.
RadialBasis balancedForDipoles(const RadialBasis& basis, const std::vector<DipoleChannel>& dipoles,
                               const std::vector<double>& importance = {});

}  // namespace prt
