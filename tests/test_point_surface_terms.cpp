// The surface terms of prt-pointlight's frames: the GGX specular (point_specular.h) and
// single scattering along the refracted view ray (point_single_scattering.h), each
// against a brute-force evaluation written out independently here (its own Fresnel,
// Snell, HG, in double precision), with their physics: shadows give nothing, the lobe's
// normal-incidence albedo is the Fresnel reflectance less masking, single scattering is
// linear in sigma_s at fixed sigma_t and in the light's intensity.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "common/bssrdf.h"
#include "common/error.h"
#include "common/materials.h"
#include "common/shapes.h"
#include "common/util.h"
#include "relight/pointlight/point_lights.h"
#include "relight/pointlight/point_single_scattering.h"
#include "relight/pointlight/point_specular.h"

using namespace prt;

namespace {

// --- independent formulas -------------------------------------------------------------

// Exact unpolarised dielectric reflectance from the outside (index 1) into eta, at the
// cosine ci of the angle of incidence.
double fresnelR(double eta, double ci) {
    const double si2 = 1.0 - ci * ci;
    const double st2 = si2 / (eta * eta);
    if (st2 >= 1.0) return 1.0;
    const double ct = std::sqrt(1.0 - st2);
    const double rs = (ci - eta * ct) / (ci + eta * ct);
    const double rp = (eta * ci - ct) / (eta * ci + ct);
    return 0.5 * (rs * rs + rp * rp);
}

// Snell: the direction light arriving along -w (w outside, pointing away) takes inside
// a surface with normal n.
glm::dvec3 refracted(const glm::dvec3& w, const glm::dvec3& n, double eta) {
    const double ci = glm::dot(w, n);
    const double ct = std::sqrt(1.0 - (1.0 - ci * ci) / (eta * eta));
    return glm::normalize(-w / eta + (ci / eta - ct) * n);
}

double hg(double g, double cosTheta) {
    return (1.0 - g * g) / (4.0 * kPi * std::pow(1.0 + g * g - 2.0 * g * cosTheta, 1.5));
}

// GGX f_s written out: F(w_i . h) D G1 G1 / (4 cos_i cos_o).
double ggxBrdf(double eta, double a, const glm::dvec3& n, const glm::dvec3& wi, const glm::dvec3& wo) {
    const glm::dvec3 h = glm::normalize(wi + wo);
    const double ci = glm::dot(n, wi), co = glm::dot(n, wo), ch = glm::dot(n, h);
    const double a2 = a * a;
    const double D = a2 / (kPi * std::pow(ch * ch * (a2 - 1.0) + 1.0, 2));
    auto g1 = [&](double c) { return 2.0 * c / (c + std::sqrt(a2 + (1.0 - a2) * c * c)); };
    return fresnelR(eta, glm::dot(wi, h)) * D * g1(ci) * g1(co) / (4.0 * ci * co);
}

// Appends b to a (indices shifted), keeping per-vertex normals.
void append(TriangleMesh& a, const TriangleMesh& b, const glm::vec3& offset) {
    const uint32_t base = uint32_t(a.positions.size());
    for (const glm::vec3& p : b.positions) a.positions.push_back(p + offset);
    for (const glm::vec3& n : b.normals) a.normals.push_back(n);
    for (const glm::uvec3& t : b.triangles) a.triangles.push_back(t + glm::uvec3(base));
}

double relError(const glm::dvec3& got, const glm::dvec3& want) {
    double e = 0.0;
    for (int c = 0; c < 3; ++c) e = std::max(e, std::abs(got[c] - want[c]) / std::abs(want[c]));
    return e;
}

}  // namespace

// ---------------------------------------------------------------------------
// Specular
// ---------------------------------------------------------------------------

// The slab's top (y = 5, n = +Y) under a point, a spot and a directional light, seen
// from several directions: pointSpecular against sum f_s E cos written out here.
TEST(PointSpecular, MatchesTheFormulaWrittenOut) {
    const RayScene scene(makeSlab(400.0f, 400.0f, 10.0f, 4));
    const std::vector<Light> lights = {parseLight("point:30,80,-20:2,1,0.5"),
                                       parseLight("spot:-40,60,10:0.5,-1,0:1,2,3:15,40"),
                                       parseLight("dir:-1,2,0.5:300,200,100")};
    const double eta = 1.4;
    size_t checked = 0;
    for (double alpha : {0.05, 0.3, 1.0})
        for (const glm::vec3 p : {glm::vec3(0, 5, 0), glm::vec3(12, 5, -7), glm::vec3(-30, 5, 25)})
            for (const glm::dvec3 wo : {glm::dvec3(0, 1, 0), glm::dvec3(-0.4, 1, 0.3), glm::dvec3(0.9, 0.5, -0.6)}) {
                const glm::dvec3 v = glm::normalize(wo);
                glm::dvec3 want(0.0);
                const glm::dvec3 x(p), n(0, 1, 0);
                for (const Light& l : lights) {
                    glm::dvec3 w, e;
                    if (l.type == LightType::Directional) {
                        w = l.direction;
                        e = l.rgb;
                    } else {
                        const glm::dvec3 d = l.position - x;
                        w = glm::normalize(d);
                        e = l.rgb * 1e6 / glm::dot(d, d);
                        if (l.type == LightType::Spot) {
                            const double c = glm::dot(-w, l.direction);
                            const double ci = std::cos(15.0 * kPi / 180), co = std::cos(40.0 * kPi / 180);
                            const double t = std::clamp((c - co) / (ci - co), 0.0, 1.0);
                            e *= t * t * (3 - 2 * t);
                        }
                    }
                    want += ggxBrdf(eta, alpha, n, w, v) * glm::dot(n, w) * e;
                }
                const glm::dvec3 got = pointSpecular(scene, lights, {p, {0, 1, 0}, {0, 1, 0}}, v, eta, alpha);
                EXPECT_LT(relError(got, want), 1e-12) << alpha << " " << p.x;
                ++checked;
            }
    EXPECT_EQ(checked, 27u);
}

TEST(PointSpecular, ShadowedPointGivesNothing) {
    TriangleMesh mesh = makeSlab(400.0f, 400.0f, 10.0f, 4);
    append(mesh, makeBox({20.0f, 2.0f, 20.0f}), {0.0f, 35.0f, 0.0f});
    const RayScene scene(mesh);
    const std::vector<Light> lights = {parseLight("point:0,100,0:1"), parseLight("spot:0,100,0:0,-1,0:1:5,30")};
    const glm::dvec3 v = glm::normalize(glm::dvec3(0.2, 1, 0));
    EXPECT_EQ(pointSpecular(scene, lights, {{2, 5, -3}, {0, 1, 0}, {0, 1, 0}}, v, 1.3, 0.3), glm::dvec3(0.0));
    EXPECT_GT(pointSpecular(scene, lights, {{30, 5, 0}, {0, 1, 0}, {0, 1, 0}}, v, 1.3, 0.3).x, 0.0);
    // Seen from below the surface, or lit from below: nothing.
    EXPECT_EQ(pointSpecular(scene, lights, {{30, 5, 0}, {0, 1, 0}, {0, 1, 0}}, {0, -1, 0}, 1.3, 0.3), glm::dvec3(0.0));
    EXPECT_EQ(pointSpecular(scene, lights, {{0, -5, 0}, {0, -1, 0}, {0, -1, 0}}, {0, -1, 0}, 1.3, 0.3),
              glm::dvec3(0.0));
}

// D is normalised (int D cos_h dw_h = 1), and at normal incidence the directional albedo
// int f_s cos_o dw_o (quadrature over theta_o: the integrand does not depend on phi) is
// F_r's weighting: with dw_o = 4 (w_o . h) dw_h it is int F_r(eta, n . h) G D (n . h) dw_h
// over the half-vectors within 45 degrees (beyond, w_o is below the horizon), whose
// D-measure is 1 / (1 + alpha^2) for GGX. So albedo / (F_r(eta, 1) / (1 + alpha^2)) is 1
// up to masking (G < 1, lowers it) and the tilted facets' larger F_r (raises it):
// measured 1.0009 (alpha 0.05), 1.0021 (0.1), 0.9977 (0.2), 0.9767 (0.3): within 2.5%
// up to alpha 0.3; at 0.6 masking takes 16% (0.837). The plain ratio albedo / F_r(eta, 1)
// is 0.998, 0.992, 0.959, 0.896, 0.616: what a rough lobe loses below the horizon.
TEST(PointSpecular, NormalIncidenceAlbedoIsTheFresnelReflectance) {
    const glm::dvec3 n(0, 0, 1);
    const int steps = 200000;
    for (double alpha : {0.05, 0.1, 0.2, 0.3, 0.6}) {
        double dNorm = 0.0, albedo = 0.0;
        const double dt = 0.5 * kPi / steps;
        for (int k = 0; k < steps; ++k) {
            const double t = (k + 0.5) * dt;
            dNorm += ggxDistribution(alpha, std::cos(t)) * std::cos(t) * std::sin(t) * dt * 2.0 * kPi;
            const glm::dvec3 wo(std::sin(t), 0.0, std::cos(t));
            albedo += specularBrdf(1.3, alpha, n, n, wo) * std::cos(t) * std::sin(t) * dt * 2.0 * kPi;
        }
        EXPECT_NEAR(dNorm, 1.0, 1e-6) << alpha;
        const double expected = fresnelR(1.3, 1.0) / (1.0 + alpha * alpha);
        std::printf("alpha %.2f: albedo / F_r(1) = %.5f, albedo / (F_r(1) / (1 + alpha^2)) = %.5f\n", alpha,
                    albedo / fresnelR(1.3, 1.0), albedo / expected);
        if (alpha <= 0.3) EXPECT_NEAR(albedo / expected, 1.0, 0.025) << alpha;
        else EXPECT_GT(albedo / expected, 0.8) << alpha;
        EXPECT_LT(albedo, fresnelR(1.3, 1.0)) << alpha;
    }
}

TEST(PointSpecular, RoughnessOutsideTheRangeIsRefused) {
    for (double a : {0.0, -0.1, 1.5, std::nan("")})
        EXPECT_THROW(validateSpecularRoughness(a), Error) << a;
    EXPECT_NO_THROW(validateSpecularRoughness(1.0));
}

// ---------------------------------------------------------------------------
// Single scattering
// ---------------------------------------------------------------------------

namespace {

// The slab of the single-scattering tests: 400 x 400 mm, 10 mm thick, top at y = 5.
struct Slab {
    TriangleMesh mesh = makeSlab(400.0f, 400.0f, 10.0f, 4);
    RayScene scene{mesh};
};

// Brute force of the same integral on that slab, written out: the refracted view ray
// from x_o down to the bottom (y = -5), `steps` midpoints in s; for each, the straight
// line to the light meets the top plane at x_i (n_i = +Y), s_i' by Snell's law on the
// observed length, the light's irradiance at x_i, Fresnel in and out, HG.
glm::dvec3 bruteForceSlab(const Light& light, const Material& m, const glm::dvec3& xo, const glm::dvec3& wo,
                          int steps) {
    const glm::dvec3 n(0, 1, 0);
    const glm::dvec3 wr = refracted(wo, n, m.eta);
    const double dm = (xo.y + 5.0) / -wr.y;
    const glm::dvec3 ss = m.sigmaSPrime / (1.0 - m.g), st = m.sigmaA + ss;
    glm::dvec3 sum(0.0);
    const double ds = dm / steps;
    for (int k = 0; k < steps; ++k) {
        const double s = (k + 0.5) * ds;
        const glm::dvec3 xp = xo + s * wr;
        glm::dvec3 w = light.type == LightType::Directional ? light.direction : glm::normalize(light.position - xp);
        const double t = (5.0 - xp.y) / w.y;  // to the top plane
        const glm::dvec3 xi = xp + t * w;
        const double ci = w.y;
        const double sinT = std::sqrt(1.0 - ci * ci) / m.eta;
        const double cosT = std::sqrt(1.0 - sinT * sinT);
        const double sPrime = t * ci / cosT;  // the refracted path to the same depth
        glm::dvec3 e = light.rgb;
        if (light.type != LightType::Directional) {
            const glm::dvec3 d = light.position - xi;
            e = light.rgb * 1e6 / glm::dot(d, d);
        }
        const glm::dvec3 wi = refracted(w, n, m.eta);
        const double p = hg(m.g, glm::dot(wi, -wr));
        for (int c = 0; c < 3; ++c)
            sum[c] += ds * ss[c] * p * (1.0 - fresnelR(m.eta, ci)) * e[c] * std::exp(-st[c] * (s + sPrime));
    }
    return (1.0 - fresnelR(m.eta, glm::dot(n, wo))) * sum;
}

}  // namespace

// Against the brute force (200,000 midpoints) on the slab, a forward-scattering medium
// (g = 0.5), a point and a directional light, three view directions. Worst relative
// error measured (any channel): 5.8e-4 with the default 8 Gauss-Legendre samples,
// 2.1e-5 with 32. The convergence is algebraic, not Gauss's exponential one: in the
// sampled mass xi a channel's integrand is (1 - lambda xi)^p with a non-integer p
// (single_scattering.h, PathQuadrature), whose derivative is singular at the far end.
TEST(PointSingleScattering, MatchesBruteForceOnASlab) {
    const Slab slab;
    const Material m = customMaterial({0.6, 0.9, 1.3}, {0.02, 0.05, 0.1}, 1.3, 0.5);
    const glm::dvec3 xo(3, 5, -2);
    const SurfacePoint x{glm::vec3(xo), {0, 1, 0}, {0, 1, 0}};
    double worst8 = 0.0, worst32 = 0.0;
    for (const Light& light : {parseLight("point:20,40,-10:0.5,1,2"), parseLight("dir:-0.5,1,0.2:100,200,300")})
        for (const glm::dvec3 v : {glm::dvec3(0, 1, 0), glm::dvec3(0.5, 1, 0.3), glm::dvec3(-1, 0.6, -0.2)}) {
            const glm::dvec3 wo = glm::normalize(v);
            const glm::dvec3 want = bruteForceSlab(light, m, xo, wo, 200000);
            const glm::dvec3 got8 = pointSingleScattering(slab.scene, slab.mesh, {light}, m, x, wo);
            const glm::dvec3 got32 = pointSingleScattering(slab.scene, slab.mesh, {light}, m, x, wo, {.pathSamples = 32});
            worst8 = std::max(worst8, relError(got8, want));
            worst32 = std::max(worst32, relError(got32, want));
            EXPECT_GT(want.x, 0.0);
        }
    RecordProperty("worst_rel_error_8", std::to_string(worst8));
    RecordProperty("worst_rel_error_32", std::to_string(worst32));
    std::printf("single scattering vs brute force: worst relative error %.3g (8 samples), %.3g (32 samples)\n",
                worst8, worst32);
    EXPECT_LT(worst8, 1.5e-3);
    EXPECT_LT(worst32, 5e-5);
}

// A mesh with triangles wound against their vertex normals (as scanned meshes have) is
// read the way the normals face, at x_o and at the light's entry x_i, as prt-reference
// reads it: a sphere with every third triangle reversed, its vertex normals kept, gives
// the consistent sphere's single scattering (to 1e-6: the rounding of the hits). Before the orientation was read from the
// normals, the reversed triangles darkened it: x_o on one returned 0, and paths whose
// light entered through one were dropped as "seen from outside".
TEST(PointSingleScattering, ReadsTrianglesWoundAgainstTheirNormalsTheWayTheNormalsFace) {
    const TriangleMesh good = makeIcosphere(4, 10.0f);
    TriangleMesh reversed = good;
    for (size_t f = 0; f < reversed.triangles.size(); f += 3) std::swap(reversed.triangles[f].y, reversed.triangles[f].z);
    const RayScene goodScene(good), reversedScene(reversed);
    const Material m = customMaterial({0.2, 0.3, 0.4}, {0.02, 0.03, 0.05}, 1.3, 0.2);
    const std::vector<Light> lights = {parseLight("dir:0.3,1,0.2:100,100,100"), parseLight("point:-20,5,30:2")};
    size_t compared = 0, onReversed = 0;
    for (size_t f = 0; f < good.triangles.size(); f += 97) {
        const glm::uvec3 t = good.triangles[f];
        const glm::vec3 centroid = (good.positions[t.x] + good.positions[t.y] + good.positions[t.z]) / 3.0f;
        const glm::vec3 n = glm::normalize(good.normals[t.x] + good.normals[t.y] + good.normals[t.z]);
        const glm::dvec3 wo = glm::normalize(glm::dvec3(n) + glm::dvec3(0.3, 0.2, -0.1));
        const glm::dvec3 want = pointSingleScattering(goodScene, good, lights, m, {centroid, n, faceNormal(good, f)}, wo);
        const glm::dvec3 got =
            pointSingleScattering(reversedScene, reversed, lights, m, {centroid, n, faceNormal(reversed, f)}, wo);
        if (!(want.x > 0.0)) continue;  // x_o turned away from both lights
        ++compared;
        onReversed += f % 3 == 0;
        EXPECT_LT(relError(got, want), 1e-6) << "triangle " << f;  // Embree's barycentrics in the other vertex order
    }
    EXPECT_GE(compared, 20u);
    EXPECT_GE(onReversed, 5u);
}

// Linear in sigma_s at a fixed sigma_t (the same path samples, the same attenuation),
// and in the light's intensity; nothing when the light is shadowed at every entry point
// or the viewer is below the horizon.
TEST(PointSingleScattering, ScalesWithAlbedoAndIntensityAndVanishesInShadow) {
    const Slab slab;
    const SurfacePoint x{{0, 5, 0}, {0, 1, 0}, {0, 1, 0}};
    const glm::dvec3 wo = glm::normalize(glm::dvec3(0.3, 1, 0.1));
    const Material a = customMaterial({1.0, 1.0, 1.0}, {0.1, 0.2, 0.3});
    const Material half = customMaterial({0.5, 0.5, 0.5}, {0.6, 0.7, 0.8});  // sigma_t kept, sigma_s halved
    const std::vector<Light> one = {parseLight("point:5,30,0:1")};
    const std::vector<Light> three = {parseLight("point:5,30,0:3")};
    const glm::dvec3 la = pointSingleScattering(slab.scene, slab.mesh, one, a, x, wo);
    const glm::dvec3 lh = pointSingleScattering(slab.scene, slab.mesh, one, half, x, wo);
    const glm::dvec3 l3 = pointSingleScattering(slab.scene, slab.mesh, three, a, x, wo);
    for (int c = 0; c < 3; ++c) {
        EXPECT_GT(la[c], 0.0);
        EXPECT_NEAR(lh[c] / la[c], 0.5, 1e-12);
        EXPECT_NEAR(l3[c] / la[c], 3.0, 1e-12);
    }
    // A wide roof between the light and the slab.
    TriangleMesh roofed = makeSlab(400.0f, 400.0f, 10.0f, 4);
    append(roofed, makeBox({200.0f, 2.0f, 200.0f}), {0.0f, 20.0f, 0.0f});
    const RayScene roofScene(roofed);
    EXPECT_EQ(pointSingleScattering(roofScene, roofed, one, a, x, wo), glm::dvec3(0.0));
    EXPECT_EQ(pointSingleScattering(slab.scene, slab.mesh, one, a, x, {0, -1, 0}), glm::dvec3(0.0));
    // A spot aimed away lights nothing; aimed at the slab with x inside its inner cone
    // and every entry point too, it is the point light.
    EXPECT_EQ(pointSingleScattering(slab.scene, slab.mesh, {parseLight("spot:5,30,0:0,1,0:1:10,20")}, a, x, wo),
              glm::dvec3(0.0));
    const glm::dvec3 spot =
        pointSingleScattering(slab.scene, slab.mesh, {parseLight("spot:5,30,0:0,-1,0:1:60,70")}, a, x, wo);
    EXPECT_LT(relError(spot, la), 1e-12);
}
