#pragma once
// The low-order spherical-harmonic part of transport vectors (docs/transport-format.md,
// "SH part"; docs/fidelity.md, "The SH part").
//
// WHY. Truncating a transport vector to its largest Haar coefficients drops the fine
// details of its smooth shape (the cosine-like lobe around the normal, the fall-off
// to the horizon) as well as those of its shadows. Against a light with fine-scale
// energy (a sun, bright windows) those dropped details do not average out: the
// truncated vertex is systematically too bright or too dark (docs/fidelity.md, "What
// the city error was"). Splitting each vector into a fit by the first 1, 4 or 9 real
// spherical harmonics (bands 0..2) plus a Haar residual, and truncating only the
// residual, keeps the smooth shape exact and spends the budget on what the harmonics
// cannot carry (shadows, edges) (docs/fidelity.md, "The SH part").
//
// SPACES. A transport vector T lives in the 6 N^2-dimensional Haar space of the
// N x N cubemap (common/haar.h); relighting is sum_t T_t L_t over texels t, with L_t
// the mean radiance of texel t and T_t already holding the texel's solid angle
// (relight/prt/light_vector.h). With w_t the texel centre's direction, the SH part of T
// is a combination of the transport-like vectors
//     W_i(t) = dOmega_t Y_i(w_t)          (scaled to unit texel norm, below)
// and it is fitted so that the residual R = T - sum_i c_i W_i is invisible to every
// light of bands 0..2, i.e. orthogonal to the light-like vectors V_i(t) = Y_i(w_t):
//     c = G^-1 (<V^_i, T^>)_i,   G_ij = <V_i, W_j>,   so <V_i, R> = 0.
// Hence a light whose texel values are a combination of the Y_i (a constant sky, a
// sky-ground gradient) sees only the SH part, which is kept whole: of the residual's
// truncation it sees only the dropped entries' share of <R, L> = 0, which is small.
// (A least-squares fit, R orthogonal to the W_i instead, leaves R with a plain sum
// that a constant light sees whole, worse than no fit at all under a constant light:
// docs/fidelity.md, "The SH part".) Relighting the SH part needs only the light's
// projections
//     l_i = sum_t W_i(t) L_t = <W^_i, L^>        (Haar domain, by Parseval)
// and T . L = sum_i c_i l_i + <R^, L^> exactly, whatever is later done to R.
//
// INDICES. In a sparse transport vector the SH coefficients take the indices
// 6 N^2 + i, after every Haar index: the relight kernel appends the light's l_i to
// its Haar coefficients and needs nothing else (transport_file.h: shTerms).
//
// Y_i are the real spherical harmonics of bands 0..4 in the usual order
// (l, m) = (0,0), (1,-1), (1,0), (1,1), (2,-2), ..., (2,2), (3,-3), ..., (4,4) with
// Y_1,-1 ~ y, Y_10 ~ z, Y_11 ~ x (docs/conventions.md frame), orthonormal on the
// sphere. W_i is dOmega_t Y_i(w_t) scaled to unit texel norm (||W^_i|| = 1), so SH
// coefficients are on the scale of the Haar coefficients beside them and one
// quantization scale per vertex serves both (transport_file.h); V_i is unscaled.

#include "common/haar.h"

#include <glm/glm.hpp>

#include <cstddef>
#include <vector>

namespace prt {

inline constexpr int kMaxShTerms = 25;

// Whether `terms` is an SH term count this module supports: 0, 1, 4, 9, 16 or 25
// (bands 0..b for b = -1..4).
inline bool validShTerms(int terms) {
    return terms == 0 || terms == 1 || terms == 4 || terms == 9 || terms == 16 || terms == 25;
}
inline constexpr const char* kShTermCounts = "0, 1, 4, 9, 16 or 25";
// The smallest cubemap size N on which `terms` SH terms are independent (sampled at the
// texel centres of 6 x N x N): 9 need 2, 16 and 25 need 4.
inline int minShCubemapSize(int terms) { return terms > 9 ? 4 : terms > 4 ? 2 : 1; }

// Y_0..Y_{terms-1} at the unit direction d (terms <= 25).
void shBasis(const glm::dvec3& d, int terms, double* y);

// The tables of one (N, terms): Haar transforms of W_i (unit norm) and the projection rows
// P_i = sum_j (G^-1)_ij V^_j (so <P_i, W^_j> = delta_ij), each 6 N^2 floats, row i
// at [i * 6 N^2].
struct ShTables {
    int size = 0;   // N
    int terms = 0;
    std::vector<float> weightedHaar;  // W^_i
    std::vector<float> projection;    // P_i
    std::vector<double> weightedGram; // <W^_i, W^_j>, terms x terms
    size_t coefficientCount() const { return size_t(6) * size * size; }
};

// Built on first use per (N, terms) and kept for the process (thread-safe). Throws
// prt::Error("sh part", ...) for invalid terms, an N that is not a power of two in
// 1..64, or an (N, terms) whose W_i are not independent (N = 1 with 9 terms).
const ShTables& shTables(int n, int terms);

// The SH split of one dense Haar-domain vector, then the truncation of its residual.
// `dense` holds count = 6 N^2 Haar entries + terms entries of `channels` floats
// (1 .. kMaxShChannels: RGB, or the profiles of editable transport),
// channel-interleaved (with terms = 0 any count is accepted):
// the Haar coefficients, then SH coefficients s_i the vector already carries (zeros
// for a plain vector; a sum of vectors that were split already carries one). The
// whole vector is T^ + sum_i s_i W^_i. On return the Haar entries hold its residual R
// and the SH entries are zero (both modified in place). The result keeps the
// `keep - terms` residual entries of largest magnitude (haar.h truncateLargest) and
// all `terms` SH entries (indices 6 N^2 + i, the whole vector's fit c_i), so it has
// at most `keep` entries. terms = 0 is truncateLargest of the 6 N^2 Haar entries.
// keep must be > terms (else prt::Error). `retained`, when given, receives
// 1 - ||dropped residual entries||^2 / (||R||^2 + ||sum_i c_i W^_i||^2) in the texel
// norm (1 for a zero vector; for terms = 0 the kept fraction of the energy). (R and
// the SH part are not orthogonal, so the denominator is not exactly ||T||^2.)
// Float arithmetic in 16 partial sums per product (relative error ~1e-6, below the
// files' 16-bit quantization): about 0.3 M multiply-adds per RGB vector at N = 32.
inline constexpr int kMaxShChannels = 32;
SparseVector truncateWithShPart(float* dense, size_t count, int channels, int terms, size_t keep,
                                double* retained = nullptr);

// The light's projections l_i = <W^_i, L^> for i < terms from its 6 N^2 Haar
// coefficients `haar` of `channels` (<= 4) interleaved floats each; out receives
// terms x channels floats (appended after the Haar coefficients, they make the light
// vector a file with SH terms relights against).
void shProjectLight(const float* haar, int n, int channels, int terms, float* out);

}  // namespace prt
