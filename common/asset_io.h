#pragma once
// Textured assets: a mesh file with what it says about the surface (texture
// coordinates, file normals, materials with a base colour and an optional base-colour
// texture), the texture lookup the renderers use at a surface point, and a writer of
// textured glTF files (prt-make-asset, tests). Formats: glTF 2.0 (.gltf + buffers and
// images, .glb) and OBJ + MTL; the other mesh formats load as an asset without texture
// coordinates and with one white material (docs/assets.md).
//
// Contract:
// - Mesh: Asset::mesh is exactly loadMesh(path) (common/mesh_io.h): same vertices in the
//   same order, same triangles, same meshFingerprint, so transport files made from
//   loadMesh's mesh pair with the asset. Units and frame as loadMesh: none applied.
// - Normals: the renderers use mesh.normals (computed, Max-weighted, common/mesh.h);
//   the file's own normals are kept per corner in fileNormals, unused for now.
// - Texture coordinates (uvs): per triangle corner (corner k of triangle t is entry
//   3 t + k), u to the right, v up, (0, 0) the bottom-left corner of the image and
//   (1, 1) its top-right corner (OBJ's convention; glTF's TEXCOORD_0, whose v runs down
//   from the top-left corner, is stored as (u, 1 - v)). So texel (x, y) of an image of
//   W x H (x from the left, y from the top row, Image's layout) has its centre at
//   u = (x + 0.5) / W, v = 1 - (y + 0.5) / H.
// - Colour: base-colour factors and textures are linear RGB(A). Textures stored with
//   integer pixels (PNG, JPEG: glTF and MTL's map_Kd define them as sRGB) are decoded
//   with the sRGB transfer function (common/image.h srgbToLinear; alpha stays linear);
//   float images (EXR, HDR) are taken as linear.
// - Errors: every bad asset throws prt::Error(path of the asset, one-line reason): those
//   of loadMesh and loadMeshSurface, a missing .mtl, a usemtl of a material no .mtl
//   defines, a missing or undecodable texture (the reason names the texture), an
//   embedded image that cannot be decoded.
// - Threads: loadAsset and saveTexturedGltf may run on any thread; baseColorAt and
//   sampleTexture only read.

#include "common/image.h"
#include "common/mesh_io.h"

#include <cstdint>
#include <string>
#include <vector>

namespace prt {

struct AssetMaterial {
    std::string name;
    glm::vec4 baseColorFactor{1.0f};  // linear RGBA (glTF baseColorFactor; MTL Kd, alpha 1)
    Image baseColorTexture;           // linear float, 1-4 channels; empty when none
    std::string textureSource;        // the texture file's path, "embedded", or "" for none
    TextureWrap wrapU = TextureWrap::Repeat;
    TextureWrap wrapV = TextureWrap::Repeat;

    bool hasTexture() const { return !baseColorTexture.empty(); }
};

struct AssetReport {
    MeshReport mesh;           // loadMesh's report of the same file
    size_t uvCorners = 0;      // corners with a texture coordinate
    size_t normalCorners = 0;  // corners with a file normal
    size_t materials = 0;
    size_t textures = 0;       // distinct textures decoded
};

struct Asset {
    TriangleMesh mesh;                       // == loadMesh(path)
    std::vector<glm::vec2> uvs;              // 3 per triangle, or empty; NaN where a
                                             // corner has none (see MeshSurface)
    std::vector<glm::vec3> fileNormals;      // 3 per triangle, or empty; unit, NaN where
                                             // a corner has none
    std::vector<uint32_t> triangleMaterials; // per triangle, index into materials
    std::vector<AssetMaterial> materials;    // at least one
    AssetReport report;
};

// Loads a mesh file with its surface: materials (glTF: the file's, plus a default;
// OBJ: one per usemtl name, Kd and map_Kd from the files mtllib names, plus a default
// for faces before any usemtl) and their decoded base-colour textures (paths relative
// to the asset; a texture used by several materials is decoded once). The MTL reader
// takes newmtl, Kd, map_Kd (its last token is the file; "-clamp on" clamps both axes)
// and ignores every other keyword: an MTL describes looks, not geometry, and these three
// are all the renderers use. Warnings (prt::warn) are loadMesh's. Throws as above.
Asset loadAsset(const std::string& path);

// Bilinear lookup of `texture` at (u, v) (the convention above) with the wrap modes
// applied to texel indices as glTF samplers do: Repeat (period 1), ClampToEdge (the
// edge texels continue), MirroredRepeat (period 2, mirrored every other period).
// Returns RGBA: a 1- or 2-channel image is grey (+ alpha), alpha is 1 when absent.
// Precondition: texture is not empty; a NaN coordinate gives NaN.
glm::vec4 sampleTexture(const Image& texture, glm::vec2 uv, TextureWrap wrapU, TextureWrap wrapV);

// Linear RGB base colour at a point of `triangle` given by barycentric weights of its
// corners 0, 1, 2 (summing to 1): the material's factor times the texture at the
// interpolated texture coordinate, or the factor alone when the asset has no texture
// coordinates, the material no texture, or a corner no coordinate.
// Precondition: triangle < asset.mesh.triangles.size().
glm::vec3 baseColorAt(const Asset& asset, uint32_t triangle, glm::vec3 barycentric);

// ---- writing textured glTF (prt-make-asset) ------------------------------------------

// Generated texture coordinates, per corner (3 per triangle), in the convention above.
//   Spherical: about the bounding-box centre c, for a corner at p with d = p - c:
//     u = 0.5 + atan2(d.x, d.z) / (2 pi), v = 0.5 + asin(d.y / |d|) / pi
//     (v up with +Y; a point at c gets (0.5, 0.5)). u is made continuous within each
//     triangle: its corners take the shortest arc around the circle of u, those before
//     the arc's start shifted by 1 (so u may exceed 1 near the seam behind the object;
//     Repeat wraps it back). No triangle spans more than 2/3 of the texture in u, and
//     only triangles around the poles come near that.
//   Box: each triangle projected along the axis its geometric normal is closest to,
//     onto the bounding box's face, (u, v) in [0, 1]^2 across that face.
enum class UvProjection { Spherical, Box };
std::vector<glm::vec2> projectUvs(const TriangleMesh& mesh, UvProjection projection);

// A linear RGB checkerboard of size x size pixels with `cells` x `cells` squares, each
// square's colour distinct (a hue ramp across u, brightness across v), for seeing
// texture coordinates. Throws prt::Error("texture") for size < 1 or cells < 1.
Image makeCheckerTexture(int size, int cells);

// Writes `mesh` (positions and triangles, one glTF primitive, 32-bit indices; no
// normals) with per-corner `uvs` (3 per triangle, the convention above) and a
// base-colour texture as glTF 2.0: .glb (one file, the PNG embedded) or .gltf (beside
// it <stem>.bin and <stem>_basecolor.png, written first). The texture is `pngBytes`
// as given when not empty, else `texture` (linear) encoded by writePng (sRGB, 8 bits).
// Vertices are split where corners of one vertex have different uvs (glTF has one
// texture coordinate per vertex); loadAsset welds them back, so it returns `mesh`'s
// positions and triangles (same fingerprint when `mesh` came from loadMesh) and `uvs`.
// Every file is written atomically (common/atomic_file.h). Throws prt::Error(path, ...)
// for another extension, uvs of the wrong size or non-finite, an empty texture,
// pngBytes that are not a decodable PNG, a failed write.
void saveTexturedGltf(const std::string& path, const TriangleMesh& mesh, const std::vector<glm::vec2>& uvs,
                      const Image& texture, const std::string& pngBytes = {},
                      TextureWrap wrap = TextureWrap::Repeat, glm::vec4 baseColorFactor = glm::vec4(1.0f));

}  // namespace prt
