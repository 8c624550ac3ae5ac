#include "relight/pointlight/vertex_surface_terms.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "common/bssrdf.h"
#include "common/error.h"
#include "relight/pointlight/point_specular.h"

namespace prt {

namespace {

void requireVertexNormals(const TriangleMesh& mesh) {
    if (mesh.normals.size() != mesh.positions.size())
        throw Error("per-vertex surface terms", "the mesh has no vertex normals");
}

}  // namespace

std::vector<glm::vec3> vertexLightIrradiance(const RayScene& scene, const TriangleMesh& mesh,
                                             const std::vector<Light>& lights) {
    requireVertexNormals(mesh);
    const size_t V = mesh.vertexCount();
    std::vector<glm::vec3> out(lights.size() * V, glm::vec3(0.0f));
    tbb::parallel_for(tbb::blocked_range<size_t>(0, V, 256), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t v = r.begin(); v != r.end(); ++v)
            for (size_t l = 0; l < lights.size(); ++l) {
                IncidentLight in;
                if (!incidentLight(lights[l], glm::dvec3(mesh.positions[v]), in)) continue;
                if (!(glm::dot(in.irradiance, glm::dvec3(1.0)) > 0.0)) continue;  // no ray for nothing
                if (!lightUnoccluded(scene, mesh.positions[v], mesh.normals[v], in)) continue;
                out[l * V + v] = glm::vec3(in.irradiance);
            }
    });
    return out;
}

glm::dvec3 vertexSpecular(const TriangleMesh& mesh, const std::vector<Light>& lights,
                          const std::vector<glm::vec3>& lightIrradiance, const GBufferPixel& px, double eta,
                          double alpha) {
    const size_t V = mesh.vertexCount();
    const glm::dvec3 x(px.position), n(px.normal), wo(px.toViewer);
    const glm::dvec3 ng(faceNormal(mesh, px.triangle));
    if (!(glm::dot(n, wo) > 0.0)) return glm::dvec3(0.0);
    const glm::uvec3 t = mesh.triangles[px.triangle];
    const glm::dvec3 b(px.barycentric);
    glm::dvec3 sum(0.0);
    for (size_t l = 0; l < lights.size(); ++l) {
        IncidentLight in;  // its direction from the pixel; the irradiance is the vertices'
        if (!incidentLight(lights[l], x, in)) continue;
        const glm::dvec3& wi = in.toLight;
        const double cosI = glm::dot(n, wi);
        if (!(cosI > 0.0) || !(glm::dot(ng, wi) > 0.0)) continue;
        const glm::vec3* s = &lightIrradiance[l * V];
        const glm::dvec3 e = b.x * glm::dvec3(s[t.x]) + b.y * glm::dvec3(s[t.y]) + b.z * glm::dvec3(s[t.z]);
        sum += specularBrdf(eta, alpha, n, wi, wo) * cosI * e;
    }
    return sum;
}

Image vertexSpecularImage(const GBuffer& g, const TriangleMesh& mesh, const std::vector<Light>& lights,
                          const std::vector<glm::vec3>& lightIrradiance, double eta, double alpha) {
    validateSpecularRoughness(alpha);
    (void)fresnelReflectance(eta, 1.0);  // a bad eta fails here, not inside the parallel loop
    if (lightIrradiance.size() != lights.size() * mesh.vertexCount())
        throw Error("per-vertex specular", "the lights' vertex irradiance is of another mesh or light count");
    Image out(g.width, g.height, 3, 0.0f);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, g.pixels.size(), 256), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t i = r.begin(); i != r.end(); ++i) {
            const GBufferPixel& px = g.pixels[i];
            if (!px.hit) continue;
            const glm::dvec3 L = vertexSpecular(mesh, lights, lightIrradiance, px, eta, alpha);
            for (int c = 0; c < 3; ++c) out.pixels[3 * i + size_t(c)] = float(L[c]);
        }
    });
    return out;
}

std::vector<glm::vec3> vertexSingleScattering(const RayScene& scene, const TriangleMesh& mesh,
                                              const std::vector<Light>& lights, const Material& material,
                                              const glm::dvec3& eye, const PointSingleScatteringOptions& options) {
    validatePointSingleScattering(options);
    validateMaterial(material);
    requireVertexNormals(mesh);
    const size_t V = mesh.vertexCount();
    std::vector<glm::vec3> out(V, glm::vec3(0.0f));
    tbb::parallel_for(tbb::blocked_range<size_t>(0, V, 64), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t v = r.begin(); v != r.end(); ++v) {
            const glm::dvec3 x(mesh.positions[v]), n(mesh.normals[v]);
            const glm::dvec3 d = eye - x;
            const double len = glm::length(d);
            if (!(len > 0.0)) continue;
            const glm::dvec3 wo = d / len;
            if (!(glm::dot(n, wo) > 0.0)) continue;
            glm::dvec3 woRefracted;
            if (!refractDirection(wo, n, material.eta, woRefracted)) continue;
            out[v] = glm::vec3(
                singleScatteringAlongRay(scene, mesh, lights, material, mesh.positions[v], woRefracted, options));
        }
    });
    return out;
}

Image vertexSingleScatteringImage(const GBuffer& g, const TriangleMesh& mesh, const std::vector<glm::vec3>& vertexTerm,
                                  double eta) {
    if (vertexTerm.size() != mesh.vertexCount())
        throw Error("per-vertex single scattering", "the vertex values are of another mesh");
    (void)fresnelTransmittance(eta, 1.0);
    Image out(g.width, g.height, 3, 0.0f);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, g.pixels.size(), 256), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t i = r.begin(); i != r.end(); ++i) {
            const GBufferPixel& px = g.pixels[i];
            if (!px.hit) continue;
            const double cosO = glm::dot(glm::dvec3(px.normal), glm::dvec3(px.toViewer));
            if (!(cosO > 0.0)) continue;
            const glm::uvec3 t = mesh.triangles[px.triangle];
            const glm::vec3 b = px.barycentric;
            const glm::vec3 s = b.x * vertexTerm[t.x] + b.y * vertexTerm[t.y] + b.z * vertexTerm[t.z];
            const float ft = float(fresnelTransmittance(eta, cosO));
            for (int c = 0; c < 3; ++c) out.pixels[3 * i + size_t(c)] = ft * s[c];
        }
    });
    return out;
}

}  // namespace prt
