#pragma once
// Point, spot and directional lights for the offline point-light renderers (SPEC section 9;
// Keng et al. 2006 section 3.4 pass 1; docs/point-lights.md), and pass 1 of those
// renderers: the transmitted direct irradiance at surface samples.
//
// UNITS. Lengths are millimetres, like the rest of the product. Power quantities are
// SI, per square METRE:
//   - point light:       position in mm, RGB radiant intensity I in W/sr;
//   - spot light:        a point light whose intensity falls off away from its axis:
//                        I(w) = I_0 falloff(w), see SPOT LIGHTS below;
//   - directional light: unit direction TOWARD the light, RGB irradiance E_perp in
//                        W/m^2 received by a surface facing the light;
//   - irradiance E, exitance M:  W/m^2;   radiance L:  W/(m^2 sr).
// The only conversion is in the inverse-square law: a point light at r mm gives
//   E = I cos(theta) / r^2 * 1e6      (kSquareMmPerSquareMetre = 1e6 mm^2 / m^2),
// so a point light of I W/sr at distance D mm matches a directional light of
// E_perp = 1e6 I / D^2 W/m^2. R_d (mm^-2) times a sample area (mm^2) is
// dimensionless, so M = sum A_i R_d E_i keeps the unit of E and L = F_t M / pi is in
// W/(m^2 sr).
//
// SPOT LIGHTS. Position in mm, a unit AXIS the spot shines along (from the light
// outward; NOT toward the light as a directional light's direction), RGB intensity I_0
// W/sr on the axis, and two half-angles 0 <= inner <= outer <= 90 degrees, outer > 0.
// With w the unit direction from the light to the lit point and c = axis . w:
//   falloff(w) = smoothstep(cos(outer), cos(inner), c)
//              = t^2 (3 - 2 t),  t = clamp((c - cos(outer)) / (cos(inner) - cos(outer)), 0, 1)
// so falloff = 1 within the inner cone, 0 outside the outer cone, and the Hermite
// smoothstep between (C1 at both cone edges; glTF KHR_lights_punctual's ramp is t^2
// instead). inner == outer is a hard edge: falloff = 1 for c >= cos(outer), else 0.
// Everything a point light does, a spot light does with I = I_0 falloff(w).
//
// FRESNEL (FresnelModel). Both papers transmit the light through the surface before
// the dipole sees it, and differ in how:
//   Exact  (the product, as Wang et al. / SPEC section 5): the exact dielectric
//          transmittance per light direction, E^ = F_t(eta, n . w_i) E, and
//          L = F_t(eta, n . w_o) M / pi on the way out.
//   Keng   (Keng et al. 2006 Eqs. 2-4, for comparing with the paper): the diffuse
//          transmittance F_dt(eta) = 1 - F_dr(eta) for every direction, E^ = F_dt E,
//          and no Fresnel on the way out, L = M / pi (their Eq. 3). F_dr is the
//          SPEC's polynomial fit (fresnelDiffuseReflectance), as in the paper.
//
// FRAMES. World frame, right-handed, +Y up (docs/conventions.md); directions are
// world vectors (normalised on input).
//
// ERRORS. Every bad input (a light string, a JSON scene, a light inside the object)
// is a prt::Error with a one-line reason naming the offending light.

#include <glm/glm.hpp>

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "common/mesh.h"
#include "common/raytrace.h"
#include "common/sampling.h"

namespace prt {

// mm^2 per m^2: converts I / r^2 (W/sr / mm^2) to W/m^2.
inline constexpr double kSquareMmPerSquareMetre = 1.0e6;

enum class LightType { Point, Directional, Spot };

struct Light {
    LightType type = LightType::Point;
    glm::dvec3 position{0.0};   // Point, Spot: mm, world frame
    glm::dvec3 direction{0.0};  // Directional: unit vector from the surface TOWARD the light;
                                // Spot: unit axis FROM the light along which it shines
    glm::dvec3 rgb{0.0};        // Point: intensity W/sr; Spot: on-axis intensity I_0 W/sr;
                                // Directional: irradiance W/m^2
    // Spot: the cone half-angles in degrees as given, and their cosines (the falloff's).
    double innerDegrees = 0.0, outerDegrees = 0.0;
    double cosInner = 1.0, cosOuter = 1.0;
    std::string source;         // where it came from ("--light point:..." or "scene.json: lights[2]"), for messages
};

// Point and spot lights have a position (inverse-square law, a shadow ray that stops
// short of the light, the inside test); directional lights do not.
inline bool hasPosition(const Light& l) { return l.type != LightType::Directional; }

// --- construction and parsing --------------------------------------------------------

// Validated lights. Throw prt::Error(source-or-"light", reason) for a non-finite
// coordinate, a negative or non-finite colour component, or a zero direction.
Light pointLight(const glm::dvec3& positionMm, const glm::dvec3& intensityWPerSr, std::string source = "");
Light directionalLight(const glm::dvec3& towardLight, const glm::dvec3& irradianceWPerM2,
                       std::string source = "");
// Also throws for a zero axis and for half-angles outside 0 <= inner <= outer <= 90,
// outer > 0 (degrees, finite). The axis is normalised.
Light spotLight(const glm::dvec3& positionMm, const glm::dvec3& axis, const glm::dvec3& intensityWPerSr,
                double innerDegrees, double outerDegrees, std::string source = "");

// The command-line syntax (docs/point-lights.md), fields separated by ':', numbers
// by ',' (whitespace around numbers allowed, case-insensitive type):
//   point:X,Y,Z:R,G,B       point light at (X, Y, Z) mm, intensity R, G, B W/sr
//   dir:X,Y,Z:R,G,B         directional light toward (X, Y, Z) (need not be unit),
//                           irradiance R, G, B W/m^2 (also "directional:")
//   spot:X,Y,Z:DX,DY,DZ:R,G,B:INNER,OUTER
//                           spot light at (X, Y, Z) mm shining along (DX, DY, DZ),
//                           on-axis intensity R, G, B W/sr, cone half-angles in degrees
// A single colour value V means gray (V, V, V). Throws prt::Error("--light <text>",
// reason) for anything else.
Light parseLight(const std::string& text);

// A scene file (JSON):
//   { "lights": [
//       { "type": "point", "position": [X, Y, Z], "intensity": [R, G, B] },
//       { "type": "directional", "direction": [X, Y, Z], "irradiance": [R, G, B] },
//       { "type": "spot", "position": [X, Y, Z], "direction": [DX, DY, DZ],
//         "intensity": [R, G, B], "inner": DEG, "outer": DEG } ] }
// "intensity"/"irradiance" may also be one number (gray). Unknown keys are errors
// (a misspelt key must not silently give a default). An empty list is allowed here
// (renderers refuse a scene without lights). Throws prt::Error(path, "lights[i]: reason").
std::vector<Light> parseLightScene(const std::string& jsonText, const std::string& path = "scene");
std::vector<Light> loadLightScene(const std::string& path);
// The lights as a scene file parseLightScene reads back to the same lights (numbers
// written with round-trip precision; a directional direction and a spot axis are unit
// already, so re-normalising them changes at most the last bit).
std::string lightSceneJson(const std::vector<Light>& lights);

// One-line description, e.g. "point at (0, 100, 0) mm, 1 1 1 W/sr".
std::string describe(const Light& light);

// --- what a light delivers at a point --------------------------------------------------

// The spot falloff (SPOT LIGHTS above) for the unit direction fromLight from the light
// to the lit point; 1 for point and directional lights.
double spotFalloff(const Light& light, const glm::dvec3& fromLight);

// The light arriving at point x (mm): the unit direction toward the light, the
// irradiance E_light on a surface at x facing the light (W/m^2: 1e6 I / r^2 for a point
// light, 1e6 I_0 falloff / r^2 for a spot, E_perp for a directional light) and the
// distance to the light (mm; +infinity for a directional light). Every term of the
// renderers (pass 1's irradiance, the specular and single-scattering terms) takes its
// light from here. Returns false (out untouched) for a light at x itself.
struct IncidentLight {
    glm::dvec3 toLight{0.0};
    glm::dvec3 irradiance{0.0};
    double distance = 0.0;
};
bool incidentLight(const Light& light, const glm::dvec3& x, IncidentLight& out);

// V(x, w): true when nothing blocks the segment from x (a surface point with geometric
// normal ng; the ray starts at scene.offsetRayOrigin(x, ng, w)) toward the light:
// toward a point or spot light it stops short of the light (tfar = r (1 - 1e-6)),
// toward a directional light it is unbounded.
bool lightUnoccluded(const RayScene& scene, const glm::vec3& x, const glm::vec3& ng, const IncidentLight& light);

// --- inside / outside ---------------------------------------------------------------

// Whether p lies inside the closed surface of `scene`: the parity of the number of
// surface crossings along a ray, decided by the majority of three rays in fixed,
// unrelated directions (a ray through an edge or a vertex may count a crossing twice
// or not at all; three independent rays make one such accident harmless). Meaningful
// for closed meshes; for an open mesh it answers for the parity of its pieces.
bool insideClosedSurface(const RayScene& scene, const glm::dvec3& p);

// Throws prt::Error(light.source, "point light at (...) mm is inside the object ...")
// for the first point or spot light inside the closed surface; directional lights pass.
void checkLightsOutside(const RayScene& scene, const std::vector<Light>& lights);

// --- direct irradiance ----------------------------------------------------------------

enum class FresnelModel { Exact, Keng };
const char* toString(FresnelModel model);
// "exact" or "keng" (case-insensitive); prt::Error("--fresnel", ...) otherwise.
FresnelModel parseFresnelModel(const std::string& text);

// The Fresnel factor applied to light arriving at cosine cosTheta to the normal
// (Exact: F_t(eta, cosTheta); Keng: F_dt(eta) = 1 - F_dr(eta)), and the one applied
// to light leaving toward the viewer (Exact: F_t(eta, cosTheta); Keng: 1, their Eq. 3).
double incidentTransmittance(FresnelModel model, double eta, double cosTheta);
double outgoingTransmittance(FresnelModel model, double eta, double cosTheta);

// A surface point as the irradiance computation needs it.
struct SurfacePoint {
    glm::vec3 position{0.0f};         // mm
    glm::vec3 normal{0.0f};           // shading normal, unit, outward (the cosine is taken with it)
    glm::vec3 geometricNormal{0.0f};  // unit normal of its triangle (the shadow-ray offset side)
};

// Transmitted direct irradiance E^ (W/m^2, RGB) at point x (Keng Eq. 4's E^ = F E):
//   sum over lights of  F(eta, n . w) V(x, w) max(0, n . w) E_light(x)
// with w the unit direction to the light, E_light = 1e6 I / r^2 (point light, r in mm;
// a spot's I = I_0 falloff(-w)) or E_perp (directional) as incidentLight, F =
// incidentTransmittance(model, ...), and V the shadow ray of lightUnoccluded. A light
// below the shading horizon (n . w <= 0) gives nothing, and so does one below the
// geometric normal's horizon (it would be seen through the surface itself).
glm::dvec3 directIrradiance(const RayScene& scene, const std::vector<Light>& lights, const SurfacePoint& x,
                            double eta, FresnelModel model);

// --- irradiance samples (pass 1) ---------------------------------------------------------

enum class SampleSource { FaceCentroids, PoissonDisk };
const char* toString(SampleSource source);
// "faces" or "poisson" (case-insensitive); prt::Error("--samples", ...) otherwise.
SampleSource parseSampleSource(const std::string& text);

// The sample points of Jensen and Buhler's integration (structure of arrays, sample i
// at index i everywhere). area[i] is the area sample i stands for (mm^2); the
// areas sum to the mesh area.
struct IrradianceSamples {
    std::vector<glm::vec3> positions;         // mm
    std::vector<glm::vec3> normals;           // unit shading normals
    std::vector<glm::vec3> geometricNormals;  // unit triangle normals
    std::vector<float> areas;                 // mm^2
    std::vector<uint32_t> triangles;          // the triangle each sample lies on
    std::vector<glm::vec3> irradiance;        // transmitted irradiance E^, W/m^2 (computeIrradiance)
    // How they were placed: one per face at its centroid (faceCentroidSamples; sample i
    // then stands for its whole triangle) or spread over the surface (samplesFromSampleSet).
    SampleSource source = SampleSource::PoissonDisk;

    size_t size() const { return positions.size(); }
    double totalArea() const;  // double-precision sum of areas
};

// Keng's choice (section 3.4, pass 1): one sample per face at its centroid with the
// face's area. The normal is the mesh's vertex normals interpolated at the centroid
// (normalised), falling back to the face normal when the mesh has none or the result
// points to the back of the face. Zero-area faces get no sample. Throws prt::Error
// when no face has positive area.
IrradianceSamples faceCentroidSamples(const TriangleMesh& mesh);

// The precompute's samples (sampling.h): each with A_i = set.areaPerSample.
IrradianceSamples samplesFromSampleSet(const SampleSet& set);

// Fills samples.irradiance with directIrradiance at every sample, in parallel (TBB);
// each sample is computed independently, so the result does not depend on the
// number of threads.
void computeIrradiance(IrradianceSamples& samples, const RayScene& scene, const std::vector<Light>& lights,
                       double eta, FresnelModel model);
// The same into `irradiance` (resized to samples.size()), leaving samples untouched;
// with lightPower, also each light's transmitted power over the samples, sum_i A_i E^_i
// of that light alone (W/m^2 mm^2, RGB; deterministic).
void computeIrradiance(const IrradianceSamples& samples, const RayScene& scene, const std::vector<Light>& lights,
                       double eta, FresnelModel model, std::vector<glm::vec3>& irradiance,
                       std::vector<glm::dvec3>* lightPower = nullptr);

// The check of every renderer's setMaterial (texture_space_sampling.h, jensen_buhler.h,
// irradiance_cache.h): the transmitted irradiance was computed with `irradianceEta`, so a
// material with another eta would pair new Fresnel factors on the way out with old ones
// on the way in. Throws prt::Error("material", ...) (one line) when the etas differ.
void requireIrradianceEta(double irradianceEta, double materialEta);

}  // namespace prt
