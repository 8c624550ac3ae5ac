#pragma once
// The BSSRDF building blocks of translucent PRT (SPEC section 5), for the materials
// of common/materials.h: the dipole diffusion profile R_d of Jensen et al. 2001 (Wang et al. 2005, Eq. 3),
// the exact dielectric Fresnel terms, refraction, and the Henyey-Greenstein phase
// function used by single scattering (Wang Eq. 4).
//
// Units. Every length is in millimetres and every coefficient in mm^-1, so
// sigma * length is dimensionless. R_d(r) is a reflectance per unit area (mm^-2);
// its integral over the plane is dimensionless. A mesh given in metres but read as
// millimetres would change every result by orders of magnitude: scale the mesh
// (--size-mm / --mm-per-unit), never the coefficients.
//
// Colour. Coefficients are RGB (glm::dvec3, x = R, y = G, z = B). The dipole is
// evaluated independently per channel. Where the SPEC asks for one scalar per
// material (the |sigma_t| of the single-scattering importance sampling) it is the
// Rec. 709 luminance of the RGB value (see luminance()).
//
// Direction conventions (input vectors need not be unit length; the functions
// normalise them; returned directions are unit length):
//   n   outward surface normal.
//   w   a direction on the OUTSIDE pointing AWAY from the surface: toward the light
//       (w_i) or toward the viewer (w_o). Light arrives along -w_i and leaves along w_o.
//   w'  the refracted direction refractDirection(w, n), pointing INTO the medium.
//       For the light, w_i' is the direction the light propagates after entering.
//       For the viewer, w_o' (Wang Fig. 2a) points from x_o into the medium along
//       the single-scattering integration path; the scattered light that reaches the
//       viewer propagates along -w_o'.
//   Phase function: theta is the angle between the light's PROPAGATION directions
//   before and after scattering, so for single scattering
//       p = henyeyGreensteinDirections(g, w_i', -w_o'),
//   and g > 0 means forward scattering.

#include <glm/glm.hpp>

#include "common/materials.h"

namespace prt {

// ---------------------------------------------------------------------------
// Dipole diffusion (Jensen et al. 2001; Wang et al. 2005 Eq. 3)
// ---------------------------------------------------------------------------

// The dipole of one colour channel: everything R_d(r) needs.
struct DipoleChannel {
    double alphaPrime = 0.0;  // reduced albedo sigma_s' / sigma_t'
    double sigmaTr = 0.0;     // sqrt(3 sigma_a sigma_t'), mm^-1
    double zr = 0.0;          // real source depth 1 / sigma_t', mm (> 0)
    double zv = 0.0;          // virtual source height z_r (1 + 4A/3), mm (> z_r)
};

// Dipole of one channel from scalar coefficients (mm^-1). Preconditions:
// sigmaSPrime, sigmaA >= 0, sigmaSPrime + sigmaA > 0, eta > 0 (not checked here;
// validateMaterial checks them for materials).
DipoleChannel makeDipoleChannel(double sigmaSPrime, double sigmaA, double eta);
// Dipole of channel c (0 = R, 1 = G, 2 = B) of a material.
DipoleChannel makeDipoleChannel(const Material& m, int c);

// Diffuse reflectance profile (mm^-2) at distance r (mm) between the point of
// incidence x_i and the point of exit x_o:
//   R_d(r) = alpha'/(4 pi) [ z_r (1 + sigma_tr d_r) e^(-sigma_tr d_r) / d_r^3
//                          + z_v (1 + sigma_tr d_v) e^(-sigma_tr d_v) / d_v^3 ],
//   d_r = sqrt(r^2 + z_r^2), d_v = sqrt(r^2 + z_v^2)
// (Wang Eq. 3 with the factors rearranged). Both terms are positive: the virtual
// source is a negative source above the surface, and the minus sign of its charge
// cancels against the minus sign of its height in the flux derivative.
double dipoleRd(const DipoleChannel& d, double r);
glm::dvec3 dipoleRd(const Material& m, double r);

// Closed form of int_0^inf R_d(r) 2 pi r dr, the fraction of incident (transmitted)
// flux that diffuses back out: alpha'/2 (e^(-sigma_tr z_r) + e^(-sigma_tr z_v)).
// Equals 1 for a non-absorbing medium (alpha' = 1, sigma_tr = 0).
double dipoleTotalDiffuseReflectance(const DipoleChannel& d);
// Closed form of int_0^R R_d(r) 2 pi r dr (using d/dd[-e^(-s d)/d] =
// (1 + s d) e^(-s d)/d^2): alpha'/2 sum_{z in {z_r, z_v}} (e^(-s z) - z e^(-s D)/D),
// D = sqrt(R^2 + z^2). Tends to dipoleTotalDiffuseReflectance as R -> inf.
double dipoleDiffuseReflectanceWithin(const DipoleChannel& d, double radius);
// Smallest radius (mm) within which the fraction `fraction` in (0, 1) of the total
// diffuse reflectance is collected (bisection on dipoleDiffuseReflectanceWithin).
// Useful to bound the support of R_d for sampling. Throws prt::Error for a fraction
// outside (0, 1).
double dipoleRadiusForFraction(const DipoleChannel& d, double fraction);

// ---------------------------------------------------------------------------
// Fresnel
// ---------------------------------------------------------------------------

// Diffuse Fresnel reflectance approximation of Jensen et al. 2001 (SPEC, eta >= 1):
//   F_dr = -1.440/eta^2 + 0.710/eta + 0.668 + 0.0636 eta.
// It fits the hemispherical average 2 int_0^1 F_r(1/eta, mu) mu dmu, i.e. the
// INTERNAL diffuse reflectance seen from inside a medium of relative index eta
// (about 0.445 at eta = 1.3, dominated by total internal reflection).
// For eta < 1 that polynomial goes negative, so the companion fit (Egan and
// Hilgeman) -0.4399 + 0.7099/eta - 0.3319/eta^2 + 0.0636/eta^3 is used instead.
// Both are accurate for eta in [kMinEta, kMaxEta].
// Throws prt::Error("eta", ...) unless eta > 0 and finite.
double fresnelDiffuseReflectance(double eta);
// Boundary factor A = (1 + F_dr)/(1 - F_dr) of the dipole.
double dipoleBoundaryA(double eta);

// Exact unpolarised Fresnel reflectance (average of s and p) for light arriving at
// an interface from the side of index 1 into the side of relative index eta
// (eta = n_other / n_this). cosThetaI = |cos| of the angle of incidence (its
// absolute value is used, clamped to 1). When eta < 1 and sin_i > eta the light
// is totally internally reflected and the result is 1. Grazing incidence
// (cosThetaI = 0) gives 1; eta == 1 (no interface) gives 0.
// F_r(eta, cos_i) == F_r(1/eta, cos_t) (reciprocity), with cos_t the refracted cosine.
// Throws prt::Error("eta", ...) unless eta > 0 and finite.
double fresnelReflectance(double eta, double cosThetaI);
// F_t = 1 - F_r, the fraction of energy transmitted (Wang Eqs. 2, 8, 11: F_t(eta, w)
// with cos theta = |n . w|).
double fresnelTransmittance(double eta, double cosTheta);

// ---------------------------------------------------------------------------
// Refraction
// ---------------------------------------------------------------------------

// Refracts through a surface with outward normal n into a medium of relative index
// eta. w points AWAY from the surface on the outside (toward the light or the
// viewer); the result wt (unit) points INTO the medium: it is the direction light
// propagates after refraction when it arrives along -w. Snell: sin_t = sin_i / eta,
// wt = -w/eta + (cos_i/eta - cos_t) n, so dot(wt, n) = -cos_t < 0 and normal
// incidence gives -n. The refracted view direction w_o' of the phase view maps is
// refractDirection(w_o, n_o, eta, w_o') with the same convention (it points into
// the medium along the integration path; light reaching the viewer travels along
// -w_o').
// Returns false (wt untouched) when w is below the surface (dot(w, n) < 0), when w
// or n is zero, or on total internal reflection (possible only for eta < 1).
// Throws prt::Error("eta", ...) unless eta > 0 and finite.
bool refractDirection(const glm::dvec3& w, const glm::dvec3& n, double eta, glm::dvec3& wt);

// ---------------------------------------------------------------------------
// Henyey-Greenstein phase function
// ---------------------------------------------------------------------------

// p(theta) = (1 - g^2) / (4 pi (1 + g^2 - 2 g cos theta)^(3/2)), sr^-1, normalised
// over the sphere, mean cosine g. theta is the angle between the light's
// propagation direction before and after scattering: cosTheta = 1 is no
// deflection, so g > 0 is forward scattering. cosTheta is clamped to [-1, 1].
// Throws prt::Error("g", ...) unless -1 < g < 1.
double henyeyGreenstein(double g, double cosTheta);
// The same with the propagation directions given explicitly: wIn is the direction
// the light travels before scattering, wOut the direction it travels after (for
// single scattering: wIn = w_i', wOut = -w_o', see the top of this file).
// cosTheta = dot(wIn, wOut) after normalisation. Throws prt::Error for a zero vector.
double henyeyGreensteinDirections(double g, const glm::dvec3& wIn, const glm::dvec3& wOut);

}  // namespace prt
