#pragma once
// The radial kernels pass 2 integrates against (Wang et al. 2005 Eq. 7): K functions
// k_c(r) of the distance r (mm) between a sample and a vertex, in mm^-2, evaluated
// together. Two sets:
//   - a material's dipole, one kernel per colour channel (K = 3, k_c = R_d,c: bssrdf.h);
//     the per-vertex vectors are then RGB transport;
//   - the J profiles B_j of a radial basis (common/radial_basis.h, K = J), for editable
//     transport: one vector U_j per profile, from which any material the basis covers
//     is recombined at relight time.
// The cell quadrature (cell_quadrature.h) and the hierarchy (multiple_scattering.h)
// only ever see a kernel set, so both sets share every line of pass 2.
//
// Widths. The cell quadrature resolves the narrowest kernel with sub-points spaced a
// fraction of narrowestWidth() and caps its near field at a multiple of widestWidth().
// For the dipole the width of channel c is 1 / (sigma_t' + sigma_tr) (mm), the scale of
// R_d's peak; a basis states the same quantity for the narrowest and widest materials it
// covers.
//
// Thread safety: immutable after construction; evaluate() may run concurrently.

#include <functional>
#include <string>

#include "common/bssrdf.h"
#include "common/materials.h"
#include "common/radial_basis.h"

namespace prt {

// The most kernels a set may hold (fixed-size weight arrays on the hot path).
inline constexpr int kMaxRadialKernels = 32;

class RadialKernels {
public:
    // The dipole of `material`, K = 3 (validateMaterial: prt::Error otherwise).
    explicit RadialKernels(const Material& material);
    // K = count general kernels: evaluate(r, out) writes k_0(r) .. k_{K-1}(r) (mm^-2) for
    // r >= 0. Widths in mm, 0 < narrowest <= widest. prt::Error("radial kernels", ...)
    // for a count outside [1, kMaxRadialKernels] or bad widths.
    RadialKernels(int count, std::function<void(double r, double* out)> evaluate, double narrowestWidth,
                  double widestWidth, std::string description);

    int count() const { return count_; }
    // k_c(r) for every c (out has count() entries).
    void evaluate(double r, double* out) const;
    double narrowestWidth() const { return narrowestWidth_; }
    double widestWidth() const { return widestWidth_; }
    // "dipole of Marble", "radial basis (12 profiles)": for messages.
    const std::string& description() const { return description_; }
    // Whether this is a material's dipole (then dipole(c) is channel c's).
    bool isDipole() const { return !evaluate_; }
    const DipoleChannel& dipole(int c) const { return dipole_[c]; }

private:
    int count_ = 3;
    DipoleChannel dipole_[3];
    std::function<void(double, double*)> evaluate_;
    double narrowestWidth_ = 0.0, widestWidth_ = 0.0;
    std::string description_;
};

// The widths of the dipoles a radial range holds (radial_kernels.h "Widths"): the
// narrowest is z_r,min / (1 + sqrt(3 (1 - alpha'_max))), the widest z_r,max / (1 +
// sqrt(3 (1 - alpha'_max))) (1 / (sigma_t' + sigma_tr) = z_r / (1 + sigma_tr z_r) and
// sigma_tr z_r = sqrt(3 (1 - alpha'))). The basis must reproduce the narrowest, so the
// cell quadrature resolves it as it would that material's own dipole.
double narrowestDipoleWidth(const RadialRange& range);
double widestDipoleWidth(const RadialRange& range);

// The J profiles of `basis` as a kernel set (K = J), with the widths of its range. The
// basis must outlive the kernel set.
RadialKernels radialBasisKernels(const RadialBasis& basis);

}  // namespace prt
