// A colour texture on a translucent object: see base_colour.h.

#include "relight/render/base_colour.h"

#include <cstdio>

#include "common/error.h"

namespace prt {

BaseColour BaseColour::load(const std::string& meshPath, const TriangleMesh& objectMesh) {
    auto asset = std::make_shared<Asset>(loadAsset(meshPath));
    if (asset->mesh.vertexCount() != objectMesh.vertexCount() || asset->mesh.triangles != objectMesh.triangles)
        throw Error(meshPath, "the asset's mesh (" + std::to_string(asset->mesh.vertexCount()) + " vertices) is not "
                              "the object's (" + std::to_string(objectMesh.vertexCount()) + " vertices)");
    BaseColour c;
    c.asset_ = std::move(asset);
    c.path_ = meshPath;
    return c;
}

glm::vec3 BaseColour::at(const GBufferPixel& p) const {
    // Triangles past the object's belong to another mesh traced with it (the ground).
    if (!asset_ || !p.hit || p.triangle >= asset_->mesh.triangleCount()) return glm::vec3(1.0f);
    return baseColorAt(*asset_, p.triangle, p.barycentric);
}

std::string BaseColour::describe() const {
    if (!asset_) return "base colour: none (white)";
    std::string text = "base colour: " + path_ + ", " + std::to_string(asset_->materials.size()) + " material" +
                       (asset_->materials.size() == 1 ? "" : "s");
    for (const AssetMaterial& m : asset_->materials) {
        char buf[160];
        std::snprintf(buf, sizeof buf, "; '%s' factor (%.3g, %.3g, %.3g)", m.name.c_str(), m.baseColorFactor.r,
                      m.baseColorFactor.g, m.baseColorFactor.b);
        text += buf;
        if (m.hasTexture())
            text += " x texture " + m.textureSource + " (" + std::to_string(m.baseColorTexture.width) + " x " +
                    std::to_string(m.baseColorTexture.height) + ")";
    }
    if (asset_->uvs.empty()) text += "; no texture coordinates (factors only)";
    return text;
}

void applyBaseColour(Image& image, const GBuffer& g, const BaseColour& colour) {
    if (!colour.enabled()) return;
    if (image.width != g.width || image.height != g.height || image.channels < 3)
        throw Error("base colour", "the image is not the G-buffer's size");
    for (int y = 0; y < g.height; ++y)
        for (int x = 0; x < g.width; ++x) {
            const GBufferPixel& p = g.at(x, y);
            if (!p.hit) continue;
            const glm::vec3 c = colour.at(p);
            for (int k = 0; k < 3; ++k) image.at(x, y, k) *= c[k];
        }
}

}  // namespace prt
