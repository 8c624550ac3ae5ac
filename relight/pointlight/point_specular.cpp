#include "relight/pointlight/point_specular.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <cmath>
#include <cstdio>

#include "common/bssrdf.h"
#include "common/error.h"
#include "common/util.h"

namespace prt {

void validateSpecularRoughness(double alpha, const char* option) {
    if (std::isfinite(alpha) && alpha > 0.0 && alpha <= 1.0) return;
    char buf[120];
    std::snprintf(buf, sizeof buf, "the GGX roughness alpha must be in (0, 1], got %g", alpha);
    throw Error(option, buf);
}

double ggxDistribution(double alpha, double cosH) {
    if (!(cosH > 0.0)) return 0.0;
    const double a2 = alpha * alpha;
    const double d = cosH * cosH * (a2 - 1.0) + 1.0;
    return a2 / (kPi * d * d);
}

double ggxMasking(double alpha, double cosTheta) {
    if (!(cosTheta > 0.0)) return 0.0;
    const double a2 = alpha * alpha;
    return 2.0 * cosTheta / (cosTheta + std::sqrt(a2 + (1.0 - a2) * cosTheta * cosTheta));
}

double specularBrdf(double eta, double alpha, const glm::dvec3& n, const glm::dvec3& wi, const glm::dvec3& wo) {
    const double cosI = glm::dot(n, wi), cosO = glm::dot(n, wo);
    if (!(cosI > 0.0) || !(cosO > 0.0)) return 0.0;
    const glm::dvec3 sum = wi + wo;
    const double len = glm::length(sum);
    if (!(len > 0.0)) return 0.0;
    const glm::dvec3 h = sum / len;
    // The Fresnel of the microfacet the light meets, at its own angle of incidence.
    const double fr = fresnelReflectance(eta, glm::dot(wi, h));
    return fr * ggxDistribution(alpha, glm::dot(n, h)) * ggxMasking(alpha, cosI) * ggxMasking(alpha, cosO) /
           (4.0 * cosI * cosO);
}

glm::dvec3 pointSpecular(const RayScene& scene, const std::vector<Light>& lights, const SurfacePoint& x,
                         const glm::dvec3& toViewer, double eta, double alpha) {
    const glm::dvec3 p(x.position), n(x.normal), ng(x.geometricNormal);
    if (!(glm::dot(n, toViewer) > 0.0)) return glm::dvec3(0.0);
    glm::dvec3 sum(0.0);
    for (const Light& l : lights) {
        IncidentLight in;
        if (!incidentLight(l, p, in)) continue;
        const double cosI = glm::dot(n, in.toLight);
        if (cosI <= 0.0 || glm::dot(ng, in.toLight) <= 0.0) continue;
        const double f = specularBrdf(eta, alpha, n, in.toLight, toViewer);
        if (!(f > 0.0) || !(glm::dot(in.irradiance, glm::dvec3(1.0)) > 0.0)) continue;  // no ray for nothing
        if (!lightUnoccluded(scene, x.position, x.geometricNormal, in)) continue;
        sum += f * cosI * in.irradiance;
    }
    return sum;
}

SurfacePoint surfacePointOf(const TriangleMesh& mesh, const GBufferPixel& pixel) {
    return SurfacePoint{pixel.position, pixel.normal, faceNormal(mesh, pixel.triangle)};
}

Image specularImage(const GBuffer& g, const TriangleMesh& mesh, const RayScene& scene,
                    const std::vector<Light>& lights, double eta, double alpha) {
    validateSpecularRoughness(alpha);
    (void)fresnelReflectance(eta, 1.0);  // a bad eta fails here, not inside the parallel loop
    Image out(g.width, g.height, 3, 0.0f);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, g.pixels.size(), 256), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t i = r.begin(); i != r.end(); ++i) {
            const GBufferPixel& px = g.pixels[i];
            if (!px.hit) continue;
            const glm::dvec3 L =
                pointSpecular(scene, lights, surfacePointOf(mesh, px), glm::dvec3(px.toViewer), eta, alpha);
            for (int c = 0; c < 3; ++c) out.pixels[3 * i + size_t(c)] = float(L[c]);
        }
    });
    return out;
}

}  // namespace prt
