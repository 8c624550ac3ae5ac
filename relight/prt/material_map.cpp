#include "relight/prt/material_map.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "common/error.h"
#include "common/material_edit.h"
#include "relight/prt/relight_object.h"

namespace prt {

float MaterialMap::at(uint32_t triangle, glm::vec3 b) const {
    const glm::vec2 uv = b.x * asset->uvs[3 * size_t(triangle)] + b.y * asset->uvs[3 * size_t(triangle) + 1] +
                         b.z * asset->uvs[3 * size_t(triangle) + 2];
    if (std::isnan(uv.x) || std::isnan(uv.y)) return 0.0f;
    return std::clamp(sampleTexture(map, uv, TextureWrap::Repeat, TextureWrap::Repeat).r, 0.0f, 1.0f);
}

MaterialMap loadMaterialMap(RelightObject& object, const std::string& meshPath, const std::string& mapPath,
                            const std::string& secondMaterial, const std::string& transportPath) {
    if (!object.editable)
        throw Error(transportPath, "a material map needs a file made with prt-precompute --editable");
    MaterialMap m;
    m.path = mapPath;
    m.asset = std::make_shared<const Asset>(loadAsset(meshPath));
    if (m.asset->mesh.triangleCount() != object.mesh.triangleCount() ||
        m.asset->mesh.vertexCount() != object.mesh.vertexCount())
        throw Error(meshPath, "its asset is not the object's mesh");
    if (m.asset->uvs.empty()) throw Error(meshPath, "has no texture coordinates for --material-map");
    m.map = readImage(mapPath);
    if (m.map.width < 1 || m.map.height < 1) throw Error(mapPath, "empty image");
    for (int y = 0; y < m.map.height; ++y)
        for (int x = 0; x < m.map.width; ++x) {
            const float t = m.map.pixel(x, y)[0];
            if (!(t >= 0.0f && t <= 1.0f))
                throw Error(mapPath, "material map values must lie in [0, 1] (pixel " + std::to_string(x) + ", " +
                                         std::to_string(y) + " holds " + std::to_string(t) + ")");
        }
    // t_v: the mean over the vertex's corners (a seam gives a vertex several).
    std::vector<double> sum(object.mesh.vertexCount(), 0.0);
    std::vector<int> count(object.mesh.vertexCount(), 0);
    for (size_t f = 0; f < object.mesh.triangleCount(); ++f)
        for (int k = 0; k < 3; ++k) {
            glm::vec3 corner(0.0f);
            corner[k] = 1.0f;
            sum[object.mesh.triangles[f][k]] += m.at(uint32_t(f), corner);
            ++count[object.mesh.triangles[f][k]];
        }
    m.vertexT.resize(sum.size());
    for (size_t v = 0; v < sum.size(); ++v) m.vertexT[v] = count[v] ? float(sum[v] / count[v]) : 0.0f;

    // B's multiple scattering: the editable transport recombined for B, then A restored.
    EditableTransport& e = *object.editable;
    const Material a = e.material();
    const double size = e.sizeMm();
    m.second = parseMaterial(secondMaterial, e.fileMaterial().eta, e.fileMaterial().g);
    try {
        e.setMaterial(m.second, size);
    } catch (const Error& err) {
        throw Error("--map-material", err.what());
    }
    m.second = e.material();
    m.secondTransport.cubemapSize = object.transport.cubemapSize;
    m.secondTransport.shTerms = object.transport.shTerms;
    m.secondTransport.mesh = object.transport.mesh;
    m.secondTransport.components.push_back(e.recombine());
    e.setMaterial(a, size);
    return m;
}

void blendMaterialMap(const MaterialMap& map, const std::vector<glm::vec3>& first,
                      const std::vector<glm::vec3>& second, VertexRadiance& radiance) {
    if (first.size() != second.size() || second.size() != radiance.diffuse.size() ||
        map.vertexT.size() != second.size())
        throw Error("material map", "inconsistent vertex counts");
    for (size_t v = 0; v < second.size(); ++v) {
        const float t = map.vertexT[v];
        radiance.diffuse[v] += (1.0f - t) * first[v] + t * second[v];
    }
}

std::string describe(const MaterialMap& map) {
    double mean = 0.0;
    for (float t : map.vertexT) mean += t;
    mean /= double(std::max<size_t>(map.vertexT.size(), 1));
    char line[512];
    std::snprintf(line, sizeof line,
                  "material map: %s (%d x %d), %s where it is 1, blended per vertex at the exit point (mean t %.3g)",
                  map.path.c_str(), map.map.width, map.map.height, describeMaterial(map.second).c_str(), mean);
    return line;
}

}  // namespace prt
