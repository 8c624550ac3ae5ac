#pragma once
// Homogeneous scattering media: the measured coefficients of Jensen et al. 2001 (the
// SPEC table) or custom ones, validated, with every derived constant the dipole and
// single scattering need (SPEC section 5). Units: coefficients in mm^-1, lengths in mm.
// Colour: RGB as glm::dvec3 (x = R, y = G, z = B); where one scalar per material is
// needed it is the Rec. 709 luminance (luminance()).

#include <glm/glm.hpp>

#include <string>
#include <vector>

namespace prt {

// Rec. 709 / sRGB luminance weights: 0.2126 R + 0.7152 G + 0.0722 B.
double luminance(const glm::dvec3& rgb);

// ---------------------------------------------------------------------------
// Material
// ---------------------------------------------------------------------------

// Accepted range of the relative index eta. The diffuse Fresnel fits (see
// fresnelDiffuseReflectance) stay within 0.005 of the exact hemispherical average
// here; outside it they drift and eventually leave [0, 1), which would put the
// virtual source at a wrong (even negative) height.
inline constexpr double kMinEta = 0.5;
inline constexpr double kMaxEta = 2.5;

// A homogeneous scattering medium. The stored parameters are the ones that are
// measured (Jensen et al. 2001 give the reduced coefficients sigma_s' and sigma_a);
// everything else is derived. Changing g keeps the reduced coefficients, hence the
// whole diffusion (dipole) term, unchanged and changes only single scattering
// through sigma_s = sigma_s' / (1 - g).
//
// Invariants (checked by validateMaterial / customMaterial, assumed elsewhere):
// sigmaSPrime and sigmaA finite and >= 0 per channel, sigmaT' > 0 per channel,
// kMinEta <= eta <= kMaxEta, -1 < g < 1.
struct Material {
    std::string name;
    glm::dvec3 sigmaSPrime{0.0};  // reduced scattering coefficient sigma_s', mm^-1
    glm::dvec3 sigmaA{0.0};       // absorption coefficient sigma_a, mm^-1
    double eta = 1.3;             // relative index of refraction (medium / outside)
    double g = 0.0;               // Henyey-Greenstein mean cosine (asymmetry)

    // Scattering coefficient sigma_s = sigma_s' / (1 - g) (Wang Sec. 2: sigma_s' = (1-g) sigma_s).
    glm::dvec3 sigmaS() const;
    // Extinction coefficient sigma_t = sigma_a + sigma_s (single scattering).
    glm::dvec3 sigmaT() const;
    // Reduced extinction sigma_t' = sigma_a + sigma_s' (diffusion).
    glm::dvec3 sigmaTPrime() const;
    // Reduced albedo alpha' = sigma_s' / sigma_t'.
    glm::dvec3 alphaPrime() const;
    // Single-scattering albedo sigma_s / sigma_t.
    glm::dvec3 albedo() const;
    // Effective transport coefficient sigma_tr = sqrt(3 sigma_a sigma_t'), mm^-1.
    glm::dvec3 sigmaTr() const;
    // Depth of the real dipole source z_r = 1 / sigma_t' (one reduced mean free path), mm.
    glm::dvec3 zr() const;
    // Height of the virtual (negative) source above the surface, a POSITIVE distance:
    // z_v = z_r (1 + 4A/3), mm. (The boundary sits at z_r 2A/3 above the surface.)
    glm::dvec3 zv() const;
    // Diffuse Fresnel reflectance F_dr(eta) and boundary factor A = (1+F_dr)/(1-F_dr).
    double fresnelDiffuse() const;
    double boundaryA() const;
    // Reduced mean free path l_u = 1 / sigma_t' per channel (= z_r), mm.
    glm::dvec3 meanFreePath() const;
    // The smallest channel of meanFreePath(): the conservative length scale that the
    // surface sampling density must resolve (Jensen et al. 2002 sample at a spacing
    // tied to l_u; using the minimum keeps every channel resolved).
    double minMeanFreePath() const;
    // Closed-form total diffuse reflectance int R_d dA per channel (see
    // dipoleTotalDiffuseReflectance).
    glm::dvec3 totalDiffuseReflectance() const;
};

// Throws prt::Error(parameter, reason) unless m satisfies the invariants above.
// The subject names the offending parameter: "sigma_s'", "sigma_a", "sigma_t'",
// "eta" or "g".
void validateMaterial(const Material& m);

// The 12 measured materials of Jensen et al. 2001 (SPEC table; eta = 1.3, g = 0).
// Names in table spelling: Apple, Chicken1, Chicken2, Cream, Ketchup, Marble,
// Potato, Skimmilk, Skin1, Skin2, Spectralon, Wholemilk.
std::vector<std::string> materialNames();
// Case-insensitive lookup; the returned name uses the table spelling. Throws
// prt::Error(name, "unknown material; valid names: ...") for any other name.
Material materialByName(const std::string& name);
// A validated material (name "custom") with the given coefficients (mm^-1). Throws
// prt::Error naming the parameter when a coefficient is negative or not finite,
// sigma_t' is not > 0 in some channel, eta is outside [kMinEta, kMaxEta], or g is
// outside (-1, 1).
Material customMaterial(const glm::dvec3& sigmaSPrime, const glm::dvec3& sigmaA,
                        double eta = 1.3, double g = 0.0);

}  // namespace prt
