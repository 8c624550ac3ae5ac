#pragma once
// A material map: spatially varying scattering on a file made with prt-precompute
// --editable (relight/prt/editable_transport.h; docs/editable-transport.md, "Material
// maps"). A texture in the asset's texture coordinates says, at every surface point,
// how much of a second material B replaces the object's material A:
//
//     t(x) = the map's first channel at x's texture coordinate, in [0, 1]
//     (a PNG's 8-bit value / 255 as stored, not linearised; an EXR's value), and
//     R_d(x_o, r) = (1 - t(x_o)) R_d,A(r) + t(x_o) R_d,B(r)
//
// THE APPROXIMATION. The profile between an entry point x_i and the exit point x_o is
// the blend at the EXIT point x_o alone, as if the whole object were of x_o's material:
// light that enters a marble region and leaves through a jade one is scattered as by
// jade all the way. Exact where the material is constant over the profile's reach (a
// few mean free paths); a blurred boundary where it is not.
//
// THE PRT FORM. Pass 2 is linear in its kernel and the basis weights are linear in the
// profile, so the blended profile's multiple scattering at vertex v is
//     M_v = (1 - t_v) M_A,v + t_v M_B,v,
// t_v the mean of t over v's corners (per-vertex weights at the exit point): two
// relights of the editable file, one per material, blended per vertex. A pixel then
// interpolates its vertices as always, so t varies over a triangle only linearly (the
// reference evaluates t at the pixel's own texture coordinate: the difference is the
// map's resolution on the mesh). Single scattering, eta and g stay the file's.
//
// Errors are prt::Error(path or option, one line): a file that is not editable, an asset
// without texture coordinates, an unreadable map, a map value outside [0, 1] or not
// finite, a material B the basis does not cover.

#include <glm/glm.hpp>

#include <memory>
#include <string>
#include <vector>

#include "common/asset_io.h"
#include "common/image.h"
#include "common/materials.h"
#include "common/transport_file.h"
#include "relight/prt/relight_kernel.h"

namespace prt {

struct RelightObject;

struct MaterialMap {
    std::string path;                    // the map's file
    Image map;                           // its pixels (first channel: t)
    std::shared_ptr<const Asset> asset;  // the object's asset: its texture coordinates
    Material second;                     // B, at the object's current size
    std::vector<float> vertexT;          // t_v per object vertex
    TransportFile secondTransport;       // B's recombined multiple scattering only

    // t at a point of `triangle` with barycentrics b: the map at the interpolated texture
    // coordinate (bilinear, repeating), clamped to [0, 1]; 0 where a corner has none.
    float at(uint32_t triangle, glm::vec3 b) const;
};

// The map `mapPath` of the asset `meshPath` for `object` (loaded from it, editable; its
// current material is A), with `secondMaterial` (parseMaterial text at the file's eta
// and g) as B at the object's current size. Throws as the header says.
MaterialMap loadMaterialMap(RelightObject& object, const std::string& meshPath, const std::string& mapPath,
                            const std::string& secondMaterial, const std::string& transportPath);

// radiance.diffuse[v] += (1 - t_v) first[v] + t_v second[v]: `radiance` the relight of
// everything but multiple scattering (single scattering, not blended, or zeros), `first`
// and `second` A's and B's multiple scattering per vertex.
void blendMaterialMap(const MaterialMap& map, const std::vector<glm::vec3>& first,
                      const std::vector<glm::vec3>& second, VertexRadiance& radiance);

// One line for the tools: the map, its size, B, the mean of t over the vertices.
std::string describe(const MaterialMap& map);

}  // namespace prt
