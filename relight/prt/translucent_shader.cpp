#include "relight/prt/translucent_shader.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include "common/bssrdf.h"
#include "common/error.h"

namespace prt {

TranslucentShader::TranslucentShader(const TriangleMesh& mesh, double eta, const ViewMaps* viewMaps,
                                     const EyePathTable& eyePath)
    : mesh_(&mesh), eta_(eta), eyePath_(eyePath) {
    if (!(eta > 0) || !std::isfinite(eta)) throw Error("eta", "must be positive and finite");
    if (viewMaps && viewMaps->terms > 0) {
        const int n = viewMaps->size, k = viewMaps->terms;
        const size_t texels = size_t(6) * n * n;
        if (n < 1 || viewMaps->data.size() != texels * size_t(k))
            throw Error("view maps", "inconsistent size");
        viewTerms_ = k;
        viewMaps_ = Cubemap(n, k);
        std::vector<float>& dst = viewMaps_.data();
        for (int t = 0; t < k; ++t) {
            const float* src = viewMaps->term(t);
            for (size_t i = 0; i < texels; ++i) dst[i * k + t] = src[i];
        }
    }
}

float TranslucentShader::viewTerm(int k, const glm::dvec3& wRefracted) const {
    if (k < 0 || k >= viewTerms_) return 0.0f;
    return viewMaps_.sampleBilinear(wRefracted, k);
}

glm::vec3 TranslucentShader::shade(const GBufferPixel& p, const VertexRadiance& radiance) const {
    if (!p.hit || p.triangle >= mesh_->triangles.size()) return glm::vec3(0.0f);
    const glm::uvec3 tri = mesh_->triangles[p.triangle];
    if (std::max({tri.x, tri.y, tri.z}) >= radiance.diffuse.size()) return glm::vec3(0.0f);
    const glm::dvec3 n(p.normal), wo(p.toViewer);
    const double cosO = glm::dot(n, wo);
    if (!(cosO > 0)) return glm::vec3(0.0f);  // F_t(eta, 0) = 0
    const double ft = fresnelTransmittance(eta_, cosO);
    const glm::vec3 b = p.barycentric;
    glm::dvec3 sum = glm::dvec3(b.x * radiance.diffuse[tri.x] + b.y * radiance.diffuse[tri.y] +
                                b.z * radiance.diffuse[tri.z]);
    const int terms = std::min<int>(viewTerms_, int(radiance.terms.size()));
    if (terms > 0) {
        glm::dvec3 woRefracted;
        if (refractDirection(wo, n, eta_, woRefracted)) {
            glm::dvec3 ss(0.0);
            for (int k = 0; k < terms; ++k) {
                const std::vector<glm::vec3>& t = radiance.terms[k];
                if (std::max({tri.x, tri.y, tri.z}) >= t.size()) continue;
                const double h = viewTerm(k, woRefracted);
                ss += h * glm::dvec3(b.x * t[tri.x] + b.y * t[tri.y] + b.z * t[tri.z]);
            }
            // The K-term phase (phase_factoring.h) has negative lobes where HG is small
            // (g = 0.4, cos = -1: -0.015 for 0.024); single scattering is never negative.
            sum += eyePath_(-glm::dot(woRefracted, n)) * glm::max(ss, glm::dvec3(0.0));
        }
    }
    // Truncated wavelets can undershoot too; radiance is never negative.
    return glm::vec3(ft * glm::max(sum, glm::dvec3(0.0)));
}

}  // namespace prt
