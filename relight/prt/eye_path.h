#pragma once
// Single scattering along the eye's refracted path, from vectors precomputed along the
// inward normal.
//
// The precomputation integrates single scattering along -n_o (Wang et al. 2005, Fig.
// 2b: the view is unknown then). The eye sees it along its refracted ray w_o', which
// leaves the surface at cos_o' = -n_o . w_o' (>= sqrt(1 - 1/eta^2) for eta > 1). In a
// half space lit from a direction whose refracted cosine is c (Eq. 5's path of the
// light inside is depth / c), the two paths give
//
//   normal path:  sigma_s p F_t / (sigma_t (1 + 1/c))
//   eye's path:   sigma_s p F_t / (sigma_t (1 + cos_o'/c))
//
// so the eye's path is brighter by (1 + c) / (c + cos_o'): 1 at a normal view and
// 1.22-1.28 at a grazing one for eta = 1.3. That ratio hardly depends on the light
// (c lies in [sqrt(1 - 1/eta^2), 1] too), so the renderers multiply the single-scattering
// sum by one factor of the view alone, eyePathFactor(eta, cos_o'): the ratio of the two
// paths' single scattering under uniform light over the half space's hemisphere,
//
//   V(cos_o') = int_0^1 F_t(eta, mu) c(mu) / (c(mu) + cos_o') dmu
//             / int_0^1 F_t(eta, mu) c(mu) / (c(mu) + 1) dmu,
//   c(mu) = sqrt(1 - (1 - mu^2) / eta^2),
//
// (Eq. 4 has no cosine at the entry point, so the hemisphere's measure is dmu). For a
// constant environment over a thick half space the factor is exact; for one direction
// of light its error is within the spread of (1 + c) / (c + cos_o') over c (under 3%
// for eta = 1.3; tested). On curved and thin parts the eye's path differs from the
// half space's in its length and its exits too; docs/single-scattering.md ("Along the
// eye's path") measures what is left against prt-reference --ss-path refracted.
//
// The factor is the same for every phase term: the path changes the depths, not the
// directions (the view maps h_k(w_o') stay as they are). Files whose single scattering
// is folded into the multiple-scattering vectors (prt-precompute --fold-ss) cannot
// separate it and keep the inward-normal path.

#include <array>
#include <string>

namespace prt {

// Which path the renderers' single scattering stands for (--ss-path).
enum class SingleScatteringView {
    Refracted,  // the eye's refracted ray: the vectors times eyePathFactor (default)
    Normal,     // the inward normal, as precomputed (Wang et al. 2005)
};
// "refracted" / "normal"; parse throws prt::Error("--ss-path", ...) on anything else.
const char* toString(SingleScatteringView view);
SingleScatteringView parseSingleScatteringView(const std::string& text);

// V(cos_o') above by 64-point Gauss-Legendre quadrature in mu (the integrands are
// smooth for eta > 1; for eta < 1 F_t's kink at the critical angle costs ~1e-4).
// Preconditions: eta > 0 finite, cosRefracted in [0, 1] (clamped).
double eyePathFactor(double eta, double cosRefracted);

// V tabulated at cos_o' = i / (kSize - 1), i = 0..kSize-1, read with linear
// interpolation (within 1e-4 relative of eyePathFactor over the cosines a view can have,
// [sqrt(1 - 1/eta^2), 1], for eta in [1.1, 2.0]; tested). The
// Normal view's table is all ones. The viewer uploads the same table to its shader.
class EyePathTable {
public:
    static constexpr int kSize = 65;
    EyePathTable() { values_.fill(1.0f); }
    EyePathTable(double eta, SingleScatteringView view);

    // V(cosRefracted), cosRefracted clamped to [0, 1].
    double operator()(double cosRefracted) const;
    const std::array<float, kSize>& values() const { return values_; }

private:
    std::array<float, kSize> values_{};
};

}  // namespace prt
