#include "relight/pointlight/point_single_scattering.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <cmath>
#include <limits>
#include <string>

#include "common/bssrdf.h"
#include "common/error.h"
#include "common/scattering_path.h"
#include "relight/pointlight/point_specular.h"

namespace prt {

namespace {

// The light's entry point as the reference reads the mesh (tools/reference/reference.h,
// SingleScatteringReference): the hit triangle's normal turned to the side of the
// vertex normals interpolated there (a triangle wound against its neighbours is read
// the way they face), and n_i the interpolated normal. Without vertex normals both are
// the triangle's own.
struct EntryPoint {
    glm::dvec3 geometricNormal;  // unit, oriented
    glm::dvec3 normal;           // n_i, unit; may face away from the light
};
EntryPoint entryPoint(const TriangleMesh& mesh, const Hit& h) {
    const glm::dvec3 ng(h.geometricNormal);
    if (mesh.normals.size() != mesh.positions.size()) return {ng, ng};
    const glm::uvec3 t = mesh.triangles[h.triangle];
    const double u = h.u, v = h.v;
    const glm::dvec3 s = (1.0 - u - v) * glm::dvec3(mesh.normals[t.x]) + u * glm::dvec3(mesh.normals[t.y]) +
                         v * glm::dvec3(mesh.normals[t.z]);
    const double len = glm::length(s);
    if (!(len > 1e-12)) return {ng, ng};
    return {glm::dot(ng, s) < 0.0 ? -ng : ng, s / len};
}

}  // namespace

void validatePointSingleScattering(const PointSingleScatteringOptions& o, const char* samplesOption) {
    if (o.pathSamples < 1 || o.pathSamples > 256)
        throw Error(samplesOption, "must be from 1 to 256, got " + std::to_string(o.pathSamples));
    if (!std::isfinite(o.depthCapMeanFreePaths) || !(o.depthCapMeanFreePaths > 0.0))
        throw Error("single scattering", "the depth cap must be finite and > 0 mean free paths");
}

glm::dvec3 singleScatteringAlongRay(const RayScene& scene, const TriangleMesh& mesh, const std::vector<Light>& lights,
                                    const Material& material, const glm::vec3& xo, const glm::dvec3& woRefracted,
                                    const PointSingleScatteringOptions& options) {
    const double eta = material.eta;
    const glm::dvec3 sigmaS = material.sigmaS(), sigmaT = material.sigmaT();
    const double sigma = luminance(sigmaT);  // |sigma_t|, the sampling's extinction
    // The path runs along w_o' into the medium: farSideDistance's "normal" is -w_o'.
    const FarSide far = farSideDistance(scene, xo, -glm::vec3(woRefracted), options.depthCapMeanFreePaths / sigma);
    if (!(far.distance > 0.0)) return glm::dvec3(0.0);
    // The rule once per thread and count (its Gauss-Legendre nodes come from Newton's
    // iteration), the samples per point.
    thread_local std::vector<QuadratureNode> rule;
    thread_local std::vector<PathSample> samples;
    if (rule.size() != size_t(options.pathSamples))
        rule = pathQuadratureRule(PathQuadrature::GaussLegendre, options.pathSamples);
    makePathSamples(sigma, far.distance, rule, PathQuadrature::GaussLegendre, samples);

    glm::dvec3 sum(0.0);
    for (const PathSample& ps : samples) {
        const glm::dvec3 xp = glm::dvec3(xo) + ps.distance * woRefracted;
        for (const Light& l : lights) {
            IncidentLight atP;
            if (!incidentLight(l, xp, atP)) continue;
            const glm::vec3 w(atP.toLight);
            const float tfar = std::isfinite(atP.distance) ? float(atP.distance)
                                                           : std::numeric_limits<float>::infinity();
            const Hit h = scene.intersect(glm::vec3(xp), w, 0.0f, tfar);
            if (!h.hit) continue;  // no surface toward the light (an open mesh)
            // x_p seen from outside (the first surface faces the other way), or a
            // smooth surface that faces away from the light there: no light enters.
            const EntryPoint entry = entryPoint(mesh, h);
            if (!(glm::dot(entry.geometricNormal, atP.toLight) > 0.0)) continue;
            const glm::dvec3& ni = entry.normal;
            const double cosI = glm::dot(ni, atP.toLight);
            if (!(cosI > 0.0)) continue;
            const glm::dvec3 xi = xp + double(h.t) * atP.toLight;
            const double sPrime = refractedPathLength(double(h.t), cosI, eta);  // Jensen 2001 Eq. 5
            if (sPrime < 0.0) continue;
            IncidentLight atI;
            if (!incidentLight(l, xi, atI) || !(glm::dot(atI.irradiance, glm::dvec3(1.0)) > 0.0)) continue;
            glm::dvec3 wiRefracted;
            if (!refractDirection(atP.toLight, ni, eta, wiRefracted)) continue;
            if (!lightUnoccluded(scene, glm::vec3(xi), glm::vec3(entry.geometricNormal), atI)) continue;
            const double phase = henyeyGreensteinDirections(material.g, wiRefracted, -woRefracted);
            const double ftIn = fresnelTransmittance(eta, cosI);
            for (int c = 0; c < 3; ++c)
                sum[c] += ps.weight * sigmaS[c] * phase * ftIn * atI.irradiance[c] *
                          std::exp(-sigmaT[c] * (ps.distance + sPrime));
        }
    }
    return sum;
}

glm::dvec3 pointSingleScattering(const RayScene& scene, const TriangleMesh& mesh, const std::vector<Light>& lights,
                                 const Material& material, const SurfacePoint& xo, const glm::dvec3& toViewer,
                                 const PointSingleScatteringOptions& options) {
    const double eta = material.eta;
    const glm::dvec3 n(xo.normal);
    // A triangle wound against its vertex normals is read the way they face (as at x_i).
    const glm::dvec3 ng = glm::dot(glm::dvec3(xo.geometricNormal), n) < 0.0 ? -glm::dvec3(xo.geometricNormal)
                                                                           : glm::dvec3(xo.geometricNormal);
    const double cosO = glm::dot(n, toViewer);
    if (!(cosO > 0.0) || !(glm::dot(ng, toViewer) > 0.0)) return glm::dvec3(0.0);
    glm::dvec3 woRefracted;
    if (!refractDirection(toViewer, n, eta, woRefracted)) return glm::dvec3(0.0);
    return fresnelTransmittance(eta, cosO) *
           singleScatteringAlongRay(scene, mesh, lights, material, xo.position, woRefracted, options);
}

Image singleScatteringImage(const GBuffer& g, const TriangleMesh& mesh, const RayScene& scene,
                            const std::vector<Light>& lights, const Material& material,
                            const PointSingleScatteringOptions& options) {
    validatePointSingleScattering(options);
    validateMaterial(material);
    Image out(g.width, g.height, 3, 0.0f);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, g.pixels.size(), 64), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t i = r.begin(); i != r.end(); ++i) {
            const GBufferPixel& px = g.pixels[i];
            if (!px.hit) continue;
            const glm::dvec3 L = pointSingleScattering(scene, mesh, lights, material, surfacePointOf(mesh, px),
                                                       glm::dvec3(px.toViewer), options);
            for (int c = 0; c < 3; ++c) out.pixels[3 * i + size_t(c)] = float(L[c]);
        }
    });
    return out;
}

}  // namespace prt
