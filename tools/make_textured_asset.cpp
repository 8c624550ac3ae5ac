// prt-make-asset: mesh -> textured glTF (.gltf + .bin + PNG, or .glb) with generated
// texture coordinates and a generated or given base-colour texture, so that tests and
// examples have a textured asset (common/asset_io.h, docs/assets.md).

#include <CLI/CLI.hpp>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>
#include <tuple>

#include "common/asset_io.h"
#include "common/atomic_file.h"
#include "common/error.h"
#include "common/image.h"
#include "common/mesh_io.h"
#include "common/options.h"
#include "common/util.h"

using namespace prt;

int main(int argc, char** argv) {
    return runMain("prt-make-asset", [&]() -> int {
        CLI::App app{"prt-make-asset: write a mesh as a textured glTF asset with generated texture\n"
                     "coordinates and a base-colour texture (a generated checkerboard, or --texture)."};
        std::string input, output, texturePath, projectionName = "spherical", wrapName = "repeat";
        int textureSize = 256, cells = 8;
        app.add_option("mesh", input, "Input mesh (.obj .ply .off .stl, optionally .gz; .gltf .glb)")->required();
        app.add_option("-o,--output", output, "Output: .glb (one file) or .gltf (+ <stem>.bin, <stem>_basecolor.png)")
            ->required();
        app.add_option("--projection", projectionName,
                       "Texture coordinates: spherical (about the bounding-box centre) or box (per triangle,\n"
                       "along the axis nearest its normal); docs/assets.md")
            ->capture_default_str();
        app.add_option("--texture", texturePath, "Base-colour texture: a PNG file embedded or copied as it is\n"
                                                 "(default: a generated checkerboard)");
        app.add_option("--texture-size", textureSize, "Generated texture: pixels a side")->capture_default_str();
        app.add_option("--cells", cells, "Generated texture: checker squares a side")->capture_default_str();
        app.add_option("--wrap", wrapName, "Sampler wrap mode: repeat, clamp or mirror")->capture_default_str();
        if (const auto exitCode = parseCommandLine(app, argc, argv, "prt-make-asset")) return *exitCode;

        UvProjection projection;
        if (projectionName == "spherical") projection = UvProjection::Spherical;
        else if (projectionName == "box") projection = UvProjection::Box;
        else throw Error("--projection", "unknown projection '" + projectionName + "' (spherical or box)");
        TextureWrap wrap;
        if (wrapName == "repeat") wrap = TextureWrap::Repeat;
        else if (wrapName == "clamp") wrap = TextureWrap::ClampToEdge;
        else if (wrapName == "mirror") wrap = TextureWrap::MirroredRepeat;
        else throw Error("--wrap", "unknown wrap mode '" + wrapName + "' (repeat, clamp or mirror)");
        if (textureSize < 1 || textureSize > 8192) throw Error("--texture-size", "must be between 1 and 8192");
        if (cells < 1 || cells > textureSize) throw Error("--cells", "must be between 1 and --texture-size");
        const std::string ext = toLower(std::filesystem::path(output).extension().string());
        if (ext != ".gltf" && ext != ".glb")
            throw Error(output, "cannot write a textured asset with extension '" + ext + "' (supported: .gltf .glb)");
        checkOutputPath(output);

        const TriangleMesh mesh = loadMesh(input);
        // loadAsset welds vertices with equal positions: a mesh with such vertices does
        // not come back with the same vertices (nor fingerprint).
        std::set<std::tuple<float, float, float>> distinct;
        for (const glm::vec3& p : mesh.positions) distinct.emplace(p.x + 0.0f, p.y + 0.0f, p.z + 0.0f);
        if (distinct.size() != mesh.positions.size())
            warn(input + ": " + std::to_string(mesh.positions.size() - distinct.size()) +
                 " vertices share a position with another; the asset's vertices are welded, so its mesh "
                 "(and fingerprint) differs from this file's");

        std::string pngBytes;
        Image texture;
        if (!texturePath.empty()) {
            std::ifstream in(texturePath, std::ios::binary);
            if (!in || std::filesystem::is_directory(texturePath)) throw Error(texturePath, "no such file");
            std::ostringstream bytes;
            bytes << in.rdbuf();
            pngBytes = bytes.str();
            if (pngBytes.size() < 8 || pngBytes.compare(0, 4, "\x89PNG") != 0)
                throw Error(texturePath, "not a PNG file (the texture is embedded as it is; glTF takes PNG or JPEG)");
        } else {
            texture = makeCheckerTexture(textureSize, cells);
        }
        const std::vector<glm::vec2> uvs = projectUvs(mesh, projection);
        saveTexturedGltf(output, mesh, uvs, texture, pngBytes, wrap);
        std::printf("%s: %zu vertices, %zu triangles, %s texture coordinates, %s texture\n", output.c_str(),
                    mesh.positions.size(), mesh.triangles.size(), projectionName.c_str(),
                    texturePath.empty() ? "generated" : texturePath.c_str());
        return 0;
    });
}
