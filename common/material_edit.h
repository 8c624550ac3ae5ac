#pragma once
// Live material edits (docs/materials.md, "Editing a material"): the object's size as a
// change of material, the artist's pair (diffuse colour + mean free path) and its
// inversion, interpolation between two materials, and one text form for all of them.
//
// SIZE AS MATERIAL. Scaling an object by s (every length times s) with coefficients sigma
// gives the same dipole transport as the unscaled object with coefficients s sigma:
//   R_d(r; s sigma) = s^2 R_d(s r; sigma),
// so with areas s^2 A and distances s r, sum A_i R_d(r_i; s sigma) E_i is the scaled
// object's sum. A size edit is therefore scaledMaterial(m, S / S_file) rendered at the
// geometry's own scale: the lights, the camera and the irradiance each surface point
// receives stay attached to the object (a look-development size change: how would this
// object look if it were s times larger, lit the same way). Single scattering obeys the
// same identity (its attenuation e^(-sigma_t s) along a path of length s).
//
// THE ARTIST'S PAIR (Jensen and Buhler 2002, section 4.1 "intuitive parameters"). Per
// channel, the diffuse colour is the total diffuse reflectance of the dipole,
//   R_total(alpha') = alpha'/2 (e^(-sqrt(3 (1 - alpha'))) + e^(-(1 + 4A/3) sqrt(3 (1 - alpha')))),
// (bssrdf.h dipoleTotalDiffuseReflectance, written in alpha' alone since sigma_tr z_r =
// sqrt(3 (1 - alpha')) and z_v = z_r (1 + 4A/3)), strictly increasing from 0 at
// alpha' = 0 to 1 at alpha' = 1; the mean free path is the diffuse mean free path
// l_d = 1 / sigma_tr (mm), the distance over which the diffusion decays by e. The
// inversion: alpha' from the colour by bisection, then
//   sigma_tr = 1 / l_d,  sigma_t' = sigma_tr / sqrt(3 (1 - alpha')),
//   sigma_s' = alpha' sigma_t',  sigma_a = sigma_t' - sigma_s'.
// Colours must lie in (0, 1): 1 needs sigma_a = 0 (an infinite l_d), 0 no scattering.
//
// Units: mm and mm^-1 throughout; colours linear (not sRGB-encoded).

#include <glm/glm.hpp>

#include <string>
#include <utility>

#include "common/materials.h"

namespace prt {

// m with sigma_a and sigma_s' multiplied by s (> 0, finite; else prt::Error("size", ...)):
// the material that renders the object at s times its size (see the top of this file).
// eta, g and the name are kept.
Material scaledMaterial(const Material& m, double s);

// The artist's pair of a material: its total diffuse reflectance per channel and its
// diffuse mean free path 1 / sigma_tr per channel (mm; infinite where sigma_a = 0).
struct MaterialAppearance {
    glm::dvec3 diffuseColour{0.0};
    glm::dvec3 meanFreePathMm{0.0};
};
MaterialAppearance appearanceOf(const Material& m);

// The inversion above. Throws prt::Error("--diffuse-colour", ...) for a colour outside
// (0, 1) and prt::Error("--mfp-mm", ...) for a mean free path that is not finite and > 0;
// eta and g as customMaterial. The result's name is "appearance".
Material materialFromAppearance(const glm::dvec3& diffuseColour, const glm::dvec3& meanFreePathMm,
                                double eta = 1.3, double g = 0.0);

// (1 - t) a + t b for sigma_a, sigma_s' (and eta, g), t in [0, 1]: the linear
// interpolation of the coefficients of Chang et al. 2008's material animation (Fig. 11).
// The name is "a.name -> b.name" (a's at t = 0, b's at t = 1).
Material lerpMaterial(const Material& a, const Material& b, double t);

// One material as text (the --material-path ends, the viewer's presets):
//   NAME                          a measured material (materialByName), the given eta
//   sigma:SA_R,SA_G,SA_B:SS_R,SS_G,SS_B    sigma_a and sigma_s' in mm^-1
//   colour:R,G,B:L_R,L_G,L_B      the artist's pair (also "color:"); one value for L
//                                 means the same mean free path in every channel
// with eta (and g) applied to all three forms. Throws prt::Error(subject, reason) with
// subject = `subject` and the text for anything else.
Material parseMaterial(const std::string& text, double eta = 1.3, double g = 0.0,
                       const std::string& subject = "--material");

// Two materials "A:B" where each end is one of the forms above (the ':' inside a sigma:
// or colour: form belongs to it): "Marble:Ketchup", "Marble:colour:0.8,0.5,0.2:2".
// Throws prt::Error(subject, ...) unless the text is exactly two materials.
std::pair<Material, Material> parseMaterialPath(const std::string& text, double eta = 1.3, double g = 0.0,
                                                const std::string& subject = "--material-path");

// Short description: "Marble (sigma_a 0.0021, 0.0041, 0.0071 mm^-1; sigma_s' 2.19, 2.62,
// 3 mm^-1; eta 1.3)".
std::string describeMaterial(const Material& m);

}  // namespace prt
