#pragma once
// Separable approximation of the Henyey-Greenstein phase function (Wang et al. 2005,
// Eq. 9, after Kautz and McCool 1999):  p(a, b) ~= sum_k g_k(a) h_k(b).
//
// DIRECTION CONVENTIONS (the whole pipeline relies on them):
//   a = the light's propagation direction inside the medium after refraction at the
//       entry point x_i: a = refractDirection(w_j, n_i, eta) for light arriving from
//       direction w_j (w_j points from the surface toward the light), so a points INTO
//       the medium. The light maps g_k are indexed by a.
//   b = the refracted VIEW direction w_o' = refractDirection(w_o, n_o, eta), w_o
//       pointing from x_o toward the eye, so b also points into the medium. The view
//       maps h_k are indexed by b (this is what relight/prt/translucent_shader.h looks up).
//   The light leaves x_p toward the eye, i.e. propagates along -b, so
//       p(a, b) = henyeyGreenstein(g, dot(a, -b))   (bssrdf.h: cos between
//   propagation directions before and after scattering; g > 0 = forward).
//   Forward scattering (g > 0) therefore favours a ~ -b: light travelling toward the
//   viewer, i.e. backlit views.
//
// TABULATION: a and b both range over the texel-centre directions of a 6 x M x M
// cubemap (M = 16 by default, so a 1536 x 1536 matrix P[a][b] = p(a, b)). With the
// solid angles dOmega the matrix is weighted so that the SVD minimises the error in
// the L2 norm over the sphere: Q[a][b] = sqrt(dOmega_a) P[a][b] sqrt(dOmega_b), Q =
// U S V^T (Eigen), and g_k(a) = sqrt(s_k) U[a][k] / sqrt(dOmega_a), h_k(b) = sqrt(s_k)
// V[b][k] / sqrt(dOmega_b). Both are stored as scalar 6 x M x M cubemaps (texel
// order of cubemap.h) and looked up bilinearly (Cubemap::sampleBilinear).

#include <glm/glm.hpp>

#include <cstddef>
#include <vector>

#include "common/cubemap.h"

namespace prt {

struct PhaseFactorization {
    double g = 0.0;                   // HG asymmetry
    int mapSize = 16;                 // M
    std::vector<double> singularValues;  // all of them, descending
    std::vector<Cubemap> lightMaps;   // g_k, K of them, 1 channel each
    std::vector<Cubemap> viewMaps;    // h_k, K of them, 1 channel each

    // The same K factors at the texel centres in double precision (the cubemaps above
    // are float copies): lightTable[k * 6M^2 + t] = g_k(texel t), viewTable likewise
    // h_k, t the flat texel index of cubemap.h (face * M^2 + j * M + i).
    std::vector<double> lightTable;
    std::vector<double> viewTable;

    int terms() const { return int(lightMaps.size()); }
    size_t texelCount() const { return size_t(6) * size_t(mapSize) * size_t(mapSize); }
    // sum_k g_k(a) h_k(b) with bilinear lookups (a, b unit, both pointing into the medium).
    double evaluate(const glm::dvec3& a, const glm::dvec3& b) const;
    // sum_k g_k(a) h_k(b) for a, b texel centres (flat texel indices), double precision:
    // the K-term reconstruction of the table P[a][b] without interpolation or float
    // rounding. Throws prt::Error for an index out of range.
    double evaluateTexels(size_t a, size_t b) const;
};

// How the factorisation is computed (all give the same singular values; the factors
// agree up to the sign and rotation freedom within equal singular values).
//   SymmetricEigen (default): P[a][b] = S[a][R b] with S[a][c] = p_HG(dot(a, c))
//     symmetric and R the antipodal permutation (R b = texel of -b: the cubemap's
//     texel centres and solid angles are symmetric under d -> -d). Eigen's
//     SelfAdjointEigenSolver on W^1/2 S W^1/2 = E L E^T gives the SVD of Q directly:
//     U = E, s_k = |l_k|, V = R E sign(L); hence h_k(b) = sign(l_k) g_k(-b).
//     l_k < 0 occurs for g < 0 (the HG Legendre coefficients g^l alternate in sign).
//     Qs commutes with R, so it is solved as two 3 M^2 blocks (even / odd functions
//     under d -> -d; docs/phase.md, "How it is computed, and why").
//   BdcSvd: Eigen::BDCSVD of Q (thin U, V).
//   JacobiSvd: Eigen::JacobiSVD of Q (thin U, V); slow, for checks.
enum class PhaseSolver { SymmetricEigen, BdcSvd, JacobiSvd };
const char* phaseSolverName(PhaseSolver solver);

// Largest accepted M: the dense table is (6 M^2)^2 doubles (302 MB at M = 32).
inline constexpr int kMaxPhaseMapSize = 32;

// K and M as a job asks for them (prt-precompute --phase-terms, --phase-map-size).
struct PhaseFactoringOptions {
    int terms = 4;     // K
    int mapSize = 16;  // M
};

// Tabulates HG(g) on 6 x M x M directions, SVD, keeps K terms (1 <= K <= 6 M^2).
// Throws prt::Error for |g| >= 1 (or NaN), M not a power of two in [1, kMaxPhaseMapSize],
// K out of range. Nothing is cached between calls.
PhaseFactorization factorPhaseFunction(double g, int terms, int mapSize = 16);
// The same with an explicit solver.
PhaseFactorization factorPhaseFunction(double g, int terms, int mapSize, PhaseSolver solver);
// The same with K and M from the options.
inline PhaseFactorization factorPhaseFunction(double g, const PhaseFactoringOptions& options) {
    return factorPhaseFunction(g, options.terms, options.mapSize);
}

// Relative RMS error of the K-term approximation over the tabulated directions,
// solid-angle weighted: ||Q - Q_K||_F / ||Q||_F = sqrt(sum_{k>K} s_k^2 / sum s_k^2).
// terms may be 0 .. 6 M^2 (0 gives 1, 6 M^2 gives 0); throws prt::Error otherwise.
double phaseApproximationError(const PhaseFactorization& f, int terms);

}  // namespace prt
