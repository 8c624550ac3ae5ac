#pragma once
// The specular layer of the offline renderers and the viewer (Wang et al. 2005,
// "Rendering"): a Fresnel-weighted reflection of a pre-filtered environment, no
// occlusion. Radiance in the environment's units; frames as in gbuffer.h.

#include <glm/glm.hpp>

#include "common/error.h"
#include "common/image.h"
#include "relight/render/gbuffer.h"

namespace prt {

// The specular radiance:
//   L_s = F_r(eta, n . w_o) * L_pre(R^T reflect(-w_o, n))
// with F_r = 1 - F_t the exact dielectric reflectance, n the interpolated normal and
// L_pre the pre-filtered lat-long map rotated by R like the lighting (bilinear, as
// environmentRadiance). 0 where n . w_o <= 0 or for non-hit pixels.
glm::vec3 specularReflection(const GBufferPixel& pixel, double eta, const Image& prefiltered,
                             const glm::dmat3& rotation);

// The pre-filter: a lat-long map box-filtered down by `factor` in both directions
// (factor must divide width and height; 1 returns the map), each output pixel the
// solid-angle weighted mean of the factor x factor input pixels it covers, so the
// integral over the sphere is preserved. Blurs reflections over about
// factor * 360 / width degrees. Throws prt::Error for a bad factor.
Image prefilterEnvironment(const Image& latlong, int factor);

// Box pre-filter factor of the specular layer (prefilterEnvironment): `requested`
// when > 0, else the largest of 8, 4, 2, 1 that divides the map's width and height
// (what prt-relight render --specular uses by default). Throws for requested < 0.
inline int specularBlurFactor(int requested, const Image& latlong) {
    if (requested < 0) throw Error("--specular-blur", "must be >= 1");
    if (requested > 0) return requested;
    int factor = 8;
    while (factor > 1 && (latlong.width % factor || latlong.height % factor)) factor /= 2;
    return factor;
}

}  // namespace prt
