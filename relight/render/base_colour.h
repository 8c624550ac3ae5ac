#pragma once
// A colour texture on a translucent object (--base-colour of prt-relight render,
// prt-pointlight and prt-reference; docs/assets.md, "Colour on a translucent object").
//
// Our reading of Wang et al. 2005, Fig. 8 (the texture "applied during the final
// rendering"): the mesh file's base colour (glTF baseColorFactor x baseColorTexture, MTL
// Kd x map_Kd; common/asset_io.h) multiplies the translucent exitance at the EXIT point
// x_o, the pixel's surface point:
//   L_o(x_o, w_o) = baseColour(x_o) * L_translucent(x_o, w_o).
// The light is scattered as by the untextured material (the transport is unchanged);
// only what leaves at x_o is tinted, like a thin coloured layer at the surface that
// absorbs on the way out. The specular layer is reflection at the surface and is not
// tinted. Every renderer applies it to its G-buffer pixels the same way, so textured
// renders and references compare as untextured ones do.
//
// A texture that is constant c over a region therefore gives c times the untextured
// image there, exactly.

#include <memory>
#include <string>

#include <glm/glm.hpp>

#include "common/asset_io.h"
#include "common/image.h"
#include "relight/render/gbuffer.h"

namespace prt {

class BaseColour {
public:
    // None: white everywhere (at() returns 1).
    BaseColour() = default;
    // The base colour of the asset at `meshPath` (loadAsset), for the object whose mesh is
    // `objectMesh` (the same file loaded and placed by a renderer: the same vertex and
    // triangle counts and triangles). Throws prt::Error(meshPath, ...) as loadAsset, and
    // when the asset's mesh is not the object's.
    static BaseColour load(const std::string& meshPath, const TriangleMesh& objectMesh);

    bool enabled() const { return asset_ != nullptr; }
    // Linear RGB at a G-buffer pixel: baseColorAt at its triangle and barycentrics on an
    // object pixel; 1 on background pixels, on triangles past the object's (a mesh traced
    // with it, common/ground.h's withGround) and when disabled.
    glm::vec3 at(const GBufferPixel& p) const;
    // One line for the tools' output: materials, textures and their sizes.
    std::string describe() const;
    const Asset* asset() const { return asset_.get(); }

private:
    std::shared_ptr<const Asset> asset_;
    std::string path_;
};

// Multiplies every object pixel (a hit of g) of `image` (3 or more channels, of g's size) by the base colour at that pixel, for renderers whose frame is translucent
// exitance only (the point-light renderers, the reference). Throws prt::Error when the
// sizes differ.
void applyBaseColour(Image& image, const GBuffer& g, const BaseColour& colour);

}  // namespace prt
