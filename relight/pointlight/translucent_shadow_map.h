#pragma once
// The local part of the hybrid (Chang et al. 2008, section 4.2, after Dachsbacher and
// Stamminger 2003 and Mertens et al. 2003; docs/point-lights.md): a translucent
// shadow map per light and the circular L x C + 1 filter over it.
//
// THE MAP. One image per light, seen FROM the light: a perspective map for a point
// light (looking at the object's bounding sphere), an orthographic one along the
// light's direction for a directional light. Every pixel's ray from the light finds the
// first surface point x_p, which is lit by this light by construction (no shadow ray),
// and stores
//     x_p (mm)  and  the transmitted flux per unit MEASURE of the map,
//     point light:       flux per steradian   = E^(x_p) r^2 / cos_g    (W/m^2 mm^2 sr^-1)
//                        (a spot light likewise, E^ with its falloff along the pixel's ray)
//     directional light: flux per mm^2 of beam = E^(x_p) / cos_g        (W/m^2)
// with E^ the transmitted irradiance of point_lights.h (the same Fresnel model), r the
// distance to the light and cos_g the geometric cosine (the surface a pixel sees is
// its measure / cos_g wide, times r^2 for a point light). E^ uses the interpolated
// normal's cosine cos_s, so a face seen edge-on whose interpolated normals face the
// light would give one pixel the flux of a wide strip (cos_s / cos_g unbounded): one
// tap of the filter, which stands for far more area than a pixel, then sparkles. The
// ratio is capped at 2; that and the pixels that see no grazing surface at all leave
// the map short of the light's power, which normalisePower gives back (spread over the
// map in proportion to its flux; docs/point-lights.md, "The pipeline, module by
// module"). The sum over all pixels of
// flux x measure x K(|x_o - x_p|) is the local exitance at x_o (a cubature of the lit
// surface); the filter evaluates a sparse version of it.
//
// THE FILTER (LocalFilter). Taps around x_o in the plane perpendicular to the light's
// ray through x_o: one at x_o itself and L rings of C taps. The ring radii split the
// kernel's planar importance mean_c(K_c(r)) 2 pi r over [0, rho_max] into L + 1 parts of
// equal weight (Mertens et al.'s importance sampling of the radius, done once): the
// centre tap stands for the disk [0, e_1], ring l for the annulus [e_l, e_l+1], its taps
// at the importance median of the annulus and angles 2 pi (c + 1/2 (l odd)) / C. rho_max
// holds 99.9% of the importance. A tap contributes
//     flux(p) x tap measure x K(|x_o - x_p|)
// with p the map pixel the tap projects to (nearest), tap measure = the annulus's
// integral of K divided by C K(rho_tap), per channel (Mertens et al.'s importance
// weight: the filter is exact for a lit plane facing the light), in mm^2, divided by
// |x_o - light|^2 for a point light, and the TRUE 3D distance to
// the stored x_p, so a tap that lands on a far surface (x_o in shadow, a silhouette)
// adds almost nothing. x_o need not be lit or visible from the light.
//
// Limits. A point light must see the whole bounding sphere within a 140-degree cone
// (otherwise prt::Error: the planar map would need a cube map); lit surface outside
// the map's pixels is lost (the map frames the bounding sphere, so there is none).

#include <glm/glm.hpp>

#include <cstddef>
#include <vector>

#include "common/mesh.h"
#include "common/raytrace.h"
#include "relight/pointlight/diffusion_split.h"
#include "relight/pointlight/point_lights.h"

namespace prt {

struct LocalFilter {
    RadialTable kernel;          // K(r), RGB, mm^-2
    int rings = 20;              // L
    int ringSamples = 20;        // C
    double rhoMax = 0.0;         // mm
    glm::dvec3 centreArea{0.0};  // mm^2 per channel: int_0^e_1 K 2 pi r dr / K(0)
    std::vector<double> radius;  // per ring, mm (the tap radius)
    std::vector<glm::dvec3> area;  // per ring, mm^2 per tap and channel: int_e_l^e_l+1 K 2 pi r dr / (C K(radius))
    // Every tap as (offset along e1, offset along e2) in mm and its measure per channel
    // (mm^2), centre first: the unrolled pattern localExitance walks.
    std::vector<glm::vec2> tapOffset;
    std::vector<float> tapOffset1, tapOffset2;  // the same, as two arrays (SIMD-friendly)
    std::vector<glm::vec4> tapArea;  // (R, G, B, 0)
    size_t taps() const { return size_t(rings) * size_t(ringSamples) + 1; }
};

// Builds the ring radii for a kernel. rings >= 1, ringSamples >= 1 (prt::Error
// "--rings" / "--ring-samples" otherwise). A kernel that is 0 everywhere gives a
// filter with rhoMax = 0 (every tap adds 0).
LocalFilter makeLocalFilter(RadialTable kernel, int rings, int ringSamples);

// One pixel of a translucent shadow map, together in 16 bytes (the filter's taps are
// random reads: memory bound): the surface point (only meaningful where lit) and the
// flux per unit measure divided by the light's colour (0 = nothing).
struct ShadowMapTexel {
    glm::vec3 position{0.0f};
    float flux = 0.0f;
};

class TranslucentShadowMap {
public:
    // Renders the map of one light. resolution in [16, 8192]. Throws prt::Error for a
    // point light inside the 140-degree limit (see above) or a bad resolution.
    TranslucentShadowMap(const RayScene& scene, const TriangleMesh& mesh, const Light& light,
                         const BoundingSphere& sphere, double eta, FresnelModel fresnel, int resolution);

    // The filtered local exitance at x (W/m^2, RGB).
    glm::dvec3 localExitance(const glm::dvec3& x, const LocalFilter& filter) const;
    // The same taps summed one by one in double precision, projected by project(): the
    // plain form localExitance's SIMD paths are tested against (slow).
    glm::dvec3 localExitanceReference(const glm::dvec3& x, const LocalFilter& filter) const;
    // The full cubature over every pixel of the map with kernel k (slow: the reference
    // of the filter in tests).
    glm::dvec3 exitanceAllPixels(const glm::dvec3& x, const RadialTable& kernel) const;

    int resolution() const { return resolution_; }
    size_t litPixels() const { return litPixels_; }
    // Sum over pixels of flux x pixel measure: the transmitted power the map holds
    // (W/m^2 mm^2), for tests against the irradiance samples.
    glm::dvec3 totalFlux() const;
    // Rescales the map's flux per channel so that totalFlux() equals `power`, the light's
    // transmitted power over the whole surface (the atlas's, computeIrradiance's
    // lightPower): the map misses what it cannot see (surfaces grazing the light's rays,
    // the cosine cap above) and would bias the local part low by as much. Channels where
    // either is 0 are left alone. Returns the factors.
    glm::dvec3 normalisePower(const glm::dvec3& power);

private:
    // Continuous pixel coordinates of world point q; false outside the image plane.
    bool project(const glm::dvec3& q, double& px, double& py) const;
    double pixelMeasure(int x, int y) const;  // sr (point) or mm^2 (directional)
    // The plane of the filter's taps at x (e1, e2 perpendicular to the light's ray) and
    // the measure's scale (1 / d^2 for a light with a position, else 1); false at the
    // light's own position.
    bool tapPlane(const glm::dvec3& x, glm::dvec3& e1, glm::dvec3& e2, double& measureScale) const;

    Light light_;
    int resolution_ = 0;
    glm::dvec3 origin_{0.0};   // point: the light position; directional: the centre of the map plane
    glm::dvec3 forward_{0.0}, right_{0.0}, up_{0.0};
    double halfExtent_ = 0.0;  // point: tan(half angle); directional: half width in mm
    using Texel = ShadowMapTexel;
    glm::vec3 fluxScale_{0.0f};
    std::vector<Texel> texels_;
    size_t litPixels_ = 0;
};

}  // namespace prt
