// Tests of common/asset_io (textured assets: glTF and OBJ + MTL, texture lookups, the
// glTF writer) and of loadMesh on glTF files. The glTF files are written here, by hand
// (nlohmann JSON + little-endian buffers), with known positions, texture coordinates
// and texels, so that the reader is not only checked against our own writer.
#include "common/asset_io.h"
#include "common/error.h"
#include "common/image.h"
#include "common/mesh_io.h"
#include "common/shapes.h"
#include "test_support.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <unistd.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

namespace fs = std::filesystem;
using nlohmann::json;
using prt::Asset;
using prt::TextureWrap;
using prt::TriangleMesh;

namespace {

// The 4 x 2 test texture: 8-bit sRGB codes per texel (x from the left, y from the top),
// so that the PNG holds them exactly and the decoded linear values are known.
const int kW = 4, kH = 2;
const int kCodes[kH][kW][3] = {
    {{255, 0, 0}, {0, 255, 0}, {0, 0, 255}, {255, 255, 255}},
    {{128, 64, 32}, {10, 200, 90}, {0, 0, 0}, {40, 40, 220}},
};

glm::vec3 texelLinear(int x, int y) {
    glm::vec3 c;
    for (int k = 0; k < 3; ++k) c[k] = prt::srgbToLinear(float(kCodes[y][x][k]) / 255.0f);
    return c;
}

prt::Image testTexture() {
    prt::Image image(kW, kH, 3);
    for (int y = 0; y < kH; ++y)
        for (int x = 0; x < kW; ++x) {
            const glm::vec3 c = texelLinear(x, y);
            for (int k = 0; k < 3; ++k) image.at(x, y, k) = c[k];
        }
    return image;
}

// Texture coordinate (our convention: v up) of texel (x, y)'s centre.
glm::vec2 texelCentre(double x, double y) { return glm::vec2(float((x + 0.5) / kW), float(1.0 - (y + 0.5) / kH)); }

void expectVec3Near(glm::vec3 a, glm::vec3 b, float tol, const std::string& what) {
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(a[k], b[k], tol) << what << " channel " << k;
}

std::string readBytes(const std::string& p) {
    std::ifstream in(p, std::ios::binary);
    std::ostringstream s;
    s << in.rdbuf();
    return s.str();
}

void writeBytes(const std::string& p, const std::string& bytes) { std::ofstream(p, std::ios::binary) << bytes; }

template <typename T>
void append(std::string& buffer, const std::vector<T>& values) {
    buffer.append(reinterpret_cast<const char*>(values.data()), values.size() * sizeof(T));
    while (buffer.size() % 4) buffer.push_back('\0');
}

// A quad split at a texture seam: 6 vertices in the buffer, of which 2 repeat a
// position (with other texture coordinates), 2 triangles.
struct SeamQuad {
    std::vector<float> positions = {0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0, /* dups: */ 0, 1, 0, 1, 0, 0};
    // glTF convention (v down). Vertex 0..2 carry the texture's corners so that
    // barycentric (1 - s - t, s, t) on triangle 0 is (u, v) = (s, 1 - t) in glTF terms.
    std::vector<float> uvs = {0, 1, 1, 1, 0, 0, 1, 0, /* dups: */ 0.5f, 0.5f, 0.25f, 0.75f};
    std::vector<uint32_t> indices = {0, 1, 2, 4, 5, 3};
};

struct GltfOptions {
    bool glb = false;
    bool embedImage = false;     // .glb buffer view / data URI instead of a file
    std::string imageUri = "tex.png";
    int mode = 4;
    int wrapS = 10497, wrapT = 10497;
    std::vector<float> factor = {0.5f, 1.0f, 0.25f, 1.0f};
    bool withTexture = true;
    json patch;                  // merged into the document last (corruptions)
    std::function<void(std::string&)> corruptBuffer;
};

// Writes <dir>/<name>.gltf (+ <name>.bin) or <name>.glb from the seam quad.
std::string writeGltf(const fs::path& dir, const std::string& name, const SeamQuad& q, const GltfOptions& o) {
    std::string bin;
    append(bin, q.positions);
    const size_t uvAt = bin.size();
    append(bin, q.uvs);
    const size_t idxAt = bin.size();
    append(bin, q.indices);
    const size_t geometryEnd = bin.size();
    const std::string png = readBytes((dir / "tex.png").string());
    size_t imageAt = 0;
    if (o.embedImage) {
        imageAt = bin.size();
        bin += png;
        while (bin.size() % 4) bin.push_back('\0');
    }
    if (o.corruptBuffer) o.corruptBuffer(bin);
    json doc = {
        {"asset", {{"version", "2.0"}}},
        {"scene", 0},
        {"scenes", {{{"nodes", {0}}}}},
        {"nodes", {{{"mesh", 0}}}},
        {"meshes", {{{"primitives", {{{"attributes", {{"POSITION", 0}, {"TEXCOORD_0", 1}}}, {"indices", 2},
                                      {"material", 0}, {"mode", o.mode}}}}}}},
        {"materials", {{{"name", "quad"}, {"pbrMetallicRoughness", {{"baseColorFactor", o.factor}}}}}},
        {"buffers", {{{"byteLength", bin.size()}}}},
        {"bufferViews", {{{"buffer", 0}, {"byteOffset", 0}, {"byteLength", uvAt}},
                         {{"buffer", 0}, {"byteOffset", uvAt}, {"byteLength", idxAt - uvAt}},
                         {{"buffer", 0}, {"byteOffset", idxAt}, {"byteLength", geometryEnd - idxAt}}}},
        {"accessors", {{{"bufferView", 0}, {"componentType", 5126}, {"count", q.positions.size() / 3}, {"type", "VEC3"},
                        {"min", {0, 0, 0}}, {"max", {1, 1, 0}}},
                       {{"bufferView", 1}, {"componentType", 5126}, {"count", q.uvs.size() / 2}, {"type", "VEC2"}},
                       {{"bufferView", 2}, {"componentType", 5125}, {"count", q.indices.size()}, {"type", "SCALAR"}}}},
    };
    if (o.withTexture) {
        doc["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"] = {{"index", 0}};
        doc["textures"] = {{{"source", 0}, {"sampler", 0}}};
        doc["samplers"] = {{{"wrapS", o.wrapS}, {"wrapT", o.wrapT}}};
        if (o.embedImage && o.glb) {
            doc["bufferViews"].push_back({{"buffer", 0}, {"byteOffset", imageAt}, {"byteLength", png.size()}});
            doc["images"] = {{{"bufferView", 3}, {"mimeType", "image/png"}}};
        } else {
            doc["images"] = {{{"uri", o.imageUri}}};
        }
    }
    if (!o.patch.is_null()) doc.merge_patch(o.patch);
    if (o.glb) {
        std::string text = doc.dump();
        while (text.size() % 4) text.push_back(' ');
        std::string out;
        auto u32 = [&](uint32_t v) { out.append(reinterpret_cast<const char*>(&v), 4); };
        out += "glTF";
        u32(2);
        u32(uint32_t(12 + 8 + text.size() + 8 + bin.size()));
        u32(uint32_t(text.size()));
        out += "JSON";
        out += text;
        u32(uint32_t(bin.size()));
        out.append("BIN\0", 4);
        out += bin;
        const std::string p = (dir / (name + ".glb")).string();
        writeBytes(p, out);
        return p;
    }
    writeBytes((dir / (name + ".bin")).string(), bin);
    if (!doc["buffers"][0].contains("uri")) doc["buffers"][0]["uri"] = name + ".bin";
    const std::string p = (dir / (name + ".gltf")).string();
    writeBytes(p, doc.dump(1));
    return p;
}

class AssetFiles : public ::testing::Test {
protected:
    void SetUp() override {
        const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
        dir_ = fs::temp_directory_path() / ("prt-test-asset-" + std::to_string(::getpid()) + "-" + info->name());
        fs::remove_all(dir_);
        fs::create_directories(dir_);
        prt::writePng(file("tex.png"), testTexture());
    }
    void TearDown() override { fs::remove_all(dir_); }
    std::string file(const std::string& name) const { return (dir_ / name).string(); }
    std::string writeText(const std::string& name, const std::string& text) const {
        writeBytes(file(name), text);
        return file(name);
    }
    fs::path dir_;
};

// The error of f: one line, naming `path`, containing `text`.
void expectAssetError(const std::function<void()>& f, const std::string& path, const std::string& text) {
    const std::string what = prt::test::errorOf(f);
    EXPECT_NE(what, prt::test::kNoError) << "expected an error mentioning '" << text << "'";
    EXPECT_NE(what.find(path), std::string::npos) << what;
    EXPECT_NE(what.find(text), std::string::npos) << what;
    EXPECT_EQ(what.find('\n'), std::string::npos) << what;
}

// The seam quad, loaded: welded positions, triangles and per-corner texture coordinates.
void expectSeamQuad(const Asset& a) {
    ASSERT_EQ(a.mesh.positions.size(), 4u);  // 6 buffer vertices welded to 4
    EXPECT_EQ(a.mesh.positions[0], glm::vec3(0, 0, 0));
    EXPECT_EQ(a.mesh.positions[1], glm::vec3(1, 0, 0));
    EXPECT_EQ(a.mesh.positions[2], glm::vec3(0, 1, 0));
    EXPECT_EQ(a.mesh.positions[3], glm::vec3(1, 1, 0));
    ASSERT_EQ(a.mesh.triangles.size(), 2u);
    EXPECT_EQ(a.mesh.triangles[0], glm::uvec3(0, 1, 2));
    EXPECT_EQ(a.mesh.triangles[1], glm::uvec3(2, 1, 3));
    ASSERT_EQ(a.uvs.size(), 6u);
    // glTF (u, v) -> (u, 1 - v).
    const glm::vec2 expected[6] = {{0, 0}, {1, 0}, {0, 1}, {0.5f, 0.5f}, {0.25f, 0.25f}, {1, 1}};
    for (int c = 0; c < 6; ++c) {
        EXPECT_NEAR(a.uvs[size_t(c)].x, expected[c].x, 1e-7) << "corner " << c;
        EXPECT_NEAR(a.uvs[size_t(c)].y, expected[c].y, 1e-7) << "corner " << c;
    }
    ASSERT_EQ(a.triangleMaterials.size(), 2u);
    EXPECT_EQ(a.triangleMaterials[0], a.triangleMaterials[1]);
    EXPECT_EQ(a.materials[a.triangleMaterials[0]].name, "quad");
    EXPECT_EQ(a.report.uvCorners, 6u);
}

// Barycentric weights on triangle 0 of the seam quad for texture coordinate (u, v).
glm::vec3 baryFor(glm::vec2 uv) { return glm::vec3(1.0f - uv.x - uv.y, uv.x, uv.y); }

// Texel centres, bilinear midpoints, through baseColorAt on triangle 0 (factor applied).
void expectLookups(const Asset& a) {
    const glm::vec3 factor(0.5f, 1.0f, 0.25f);
    for (int y = 0; y < kH; ++y)
        for (int x = 0; x < kW; ++x)
            expectVec3Near(prt::baseColorAt(a, 0, baryFor(texelCentre(x, y))), factor * texelLinear(x, y), 2e-6f,
                           "texel " + std::to_string(x) + "," + std::to_string(y));
    // Halfway between texels (0, 0) and (1, 0), and among the four of the left half.
    expectVec3Near(prt::baseColorAt(a, 0, baryFor(texelCentre(0.5, 0))),
                   factor * 0.5f * (texelLinear(0, 0) + texelLinear(1, 0)), 2e-6f, "midpoint x");
    expectVec3Near(prt::baseColorAt(a, 0, baryFor(texelCentre(0.5, 0.5))),
                   factor * 0.25f * (texelLinear(0, 0) + texelLinear(1, 0) + texelLinear(0, 1) + texelLinear(1, 1)),
                   2e-6f, "midpoint xy");
    // A quarter of the way from texel (2, 1) to (3, 1).
    expectVec3Near(prt::baseColorAt(a, 0, baryFor(texelCentre(2.25, 1))),
                   factor * (0.75f * texelLinear(2, 1) + 0.25f * texelLinear(3, 1)), 2e-6f, "quarter");
}

}  // namespace

// ---------------------------------------------------------------------------------
// glTF
// ---------------------------------------------------------------------------------

TEST_F(AssetFiles, GltfWithBinAndPngFile) {
    const std::string p = writeGltf(dir_, "quad", SeamQuad{}, GltfOptions{});
    const Asset a = prt::loadAsset(p);
    expectSeamQuad(a);
    const auto& m = a.materials[a.triangleMaterials[0]];
    ASSERT_TRUE(m.hasTexture());
    EXPECT_EQ(m.textureSource, file("tex.png"));
    EXPECT_EQ(m.baseColorTexture.width, kW);
    EXPECT_EQ(m.baseColorTexture.height, kH);
    EXPECT_EQ(m.baseColorFactor, glm::vec4(0.5f, 1.0f, 0.25f, 1.0f));
    EXPECT_EQ(a.report.textures, 1u);
    expectLookups(a);
    EXPECT_EQ(a.report.mesh.format, "gltf");
    EXPECT_EQ(a.report.mesh.fileVertices, 4u);
}

TEST_F(AssetFiles, GlbWithEmbeddedPng) {
    GltfOptions o;
    o.glb = true;
    o.embedImage = true;
    const std::string p = writeGltf(dir_, "quad", SeamQuad{}, o);
    fs::remove(file("tex.png"));  // the texture must come from inside the .glb
    const Asset a = prt::loadAsset(p);
    expectSeamQuad(a);
    EXPECT_EQ(a.materials[a.triangleMaterials[0]].textureSource, "embedded");
    expectLookups(a);
    EXPECT_EQ(a.report.mesh.format, "glb");
}

TEST_F(AssetFiles, GltfDataUriImage) {
    // A data URI is embedded too (Assimp decodes it into the scene's textures).
    static const char* kB64 = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    const std::string png = readBytes(file("tex.png"));
    std::string b64;
    for (size_t i = 0; i < png.size(); i += 3) {
        uint32_t n = uint32_t(uint8_t(png[i])) << 16;
        if (i + 1 < png.size()) n |= uint32_t(uint8_t(png[i + 1])) << 8;
        if (i + 2 < png.size()) n |= uint32_t(uint8_t(png[i + 2]));
        b64 += kB64[(n >> 18) & 63];
        b64 += kB64[(n >> 12) & 63];
        b64 += i + 1 < png.size() ? kB64[(n >> 6) & 63] : '=';
        b64 += i + 2 < png.size() ? kB64[n & 63] : '=';
    }
    GltfOptions o;
    o.imageUri = "data:image/png;base64," + b64;
    const std::string p = writeGltf(dir_, "quad", SeamQuad{}, o);
    fs::remove(file("tex.png"));
    const Asset a = prt::loadAsset(p);
    EXPECT_EQ(a.materials[a.triangleMaterials[0]].textureSource, "embedded");
    expectLookups(a);
}

TEST_F(AssetFiles, WrapModesFromTheSampler) {
    for (const auto& [s, t, wu, wv] : {std::tuple{10497, 10497, TextureWrap::Repeat, TextureWrap::Repeat},
                                       std::tuple{33071, 33648, TextureWrap::ClampToEdge, TextureWrap::MirroredRepeat},
                                       std::tuple{33648, 33071, TextureWrap::MirroredRepeat, TextureWrap::ClampToEdge}}) {
        GltfOptions o;
        o.wrapS = s;
        o.wrapT = t;
        const Asset a = prt::loadAsset(writeGltf(dir_, "wrap" + std::to_string(s) + std::to_string(t), SeamQuad{}, o));
        const auto& m = a.materials[a.triangleMaterials[0]];
        EXPECT_EQ(m.wrapU, wu);
        EXPECT_EQ(m.wrapV, wv);
    }
    // The lookups themselves, at u = 1.25 and v = -0.25 / 1.25.
    const prt::Image t = testTexture();
    auto rgb = [&](glm::vec2 uv, TextureWrap wu, TextureWrap wv) { return glm::vec3(prt::sampleTexture(t, uv, wu, wv)); };
    const float v0 = texelCentre(0, 0).y;  // the top row's centre
    // Repeat: u = 1.25 is u = 0.25, halfway between texels 0 and 1.
    expectVec3Near(rgb({1.25f, v0}, TextureWrap::Repeat, TextureWrap::Repeat),
                   0.5f * (texelLinear(0, 0) + texelLinear(1, 0)), 2e-6f, "repeat");
    expectVec3Near(rgb({-0.75f, v0}, TextureWrap::Repeat, TextureWrap::Repeat),
                   0.5f * (texelLinear(0, 0) + texelLinear(1, 0)), 2e-6f, "repeat negative");
    // Clamp: beyond the right edge, the last column.
    expectVec3Near(rgb({1.25f, v0}, TextureWrap::ClampToEdge, TextureWrap::Repeat), texelLinear(3, 0), 2e-6f, "clamp");
    // Mirrored repeat: u = 1.25 is u = 0.75, halfway between texels 2 and 3.
    expectVec3Near(rgb({1.25f, v0}, TextureWrap::MirroredRepeat, TextureWrap::Repeat),
                   0.5f * (texelLinear(2, 0) + texelLinear(3, 0)), 2e-6f, "mirror");
    // And the mirror of texel 0's centre (u = 0.125) is at u = 1.875 and -0.125.
    expectVec3Near(rgb({1.875f, v0}, TextureWrap::MirroredRepeat, TextureWrap::Repeat), texelLinear(0, 0), 2e-6f,
                   "mirror 1.875");
    expectVec3Near(rgb({-0.125f, v0}, TextureWrap::MirroredRepeat, TextureWrap::Repeat), texelLinear(0, 0), 2e-6f,
                   "mirror -0.125");
    // v: the top row (y = 0) is v in (0.5, 1); v = 1.25 repeats to 0.25 (bottom row),
    // clamps to the top row, mirrors to 0.75 (top row's centre).
    const float u1 = texelCentre(1, 0).x;
    expectVec3Near(rgb({u1, 1.25f}, TextureWrap::Repeat, TextureWrap::Repeat), texelLinear(1, 1), 2e-6f, "v repeat");
    expectVec3Near(rgb({u1, 1.25f}, TextureWrap::Repeat, TextureWrap::ClampToEdge), texelLinear(1, 0), 2e-6f, "v clamp");
    expectVec3Near(rgb({u1, 1.25f}, TextureWrap::Repeat, TextureWrap::MirroredRepeat), texelLinear(1, 0), 2e-6f,
                   "v mirror");
    // Repeat wraps bilinear filtering across the edge: u = 0 is halfway between the
    // last and the first column; clamp there gives the first column.
    expectVec3Near(rgb({0.0f, v0}, TextureWrap::Repeat, TextureWrap::Repeat),
                   0.5f * (texelLinear(3, 0) + texelLinear(0, 0)), 2e-6f, "repeat edge");
    expectVec3Near(rgb({0.0f, v0}, TextureWrap::ClampToEdge, TextureWrap::Repeat), texelLinear(0, 0), 2e-6f,
                   "clamp edge");
}

TEST_F(AssetFiles, NoTextureOrNoUvsGivesTheFactor) {
    GltfOptions o;
    o.withTexture = false;
    const Asset a = prt::loadAsset(writeGltf(dir_, "plain", SeamQuad{}, o));
    EXPECT_FALSE(a.materials[a.triangleMaterials[0]].hasTexture());
    EXPECT_EQ(prt::baseColorAt(a, 1, glm::vec3(1.0f / 3.0f)), glm::vec3(0.5f, 1.0f, 0.25f));
    // A mesh format without texture coordinates: one white material.
    const std::string off = writeText("tri.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n");
    const Asset b = prt::loadAsset(off);
    EXPECT_TRUE(b.uvs.empty());
    ASSERT_EQ(b.materials.size(), 1u);
    EXPECT_EQ(prt::baseColorAt(b, 0, glm::vec3(1.0f / 3.0f)), glm::vec3(1.0f));
    EXPECT_EQ(prt::meshFingerprint(b.mesh), prt::meshFingerprint(prt::loadMesh(off)));
}

TEST_F(AssetFiles, NodeTransformsAreApplied) {
    GltfOptions o;
    o.patch = {{"nodes", {{{"children", {1}}, {"translation", {10, 0, 0}}}, {{"mesh", 0}, {"scale", {2, 3, 4}}}}}};
    const Asset a = prt::loadAsset(writeGltf(dir_, "moved", SeamQuad{}, o));
    ASSERT_EQ(a.mesh.positions.size(), 4u);
    EXPECT_EQ(a.mesh.positions[0], glm::vec3(10, 0, 0));
    EXPECT_EQ(a.mesh.positions[1], glm::vec3(12, 0, 0));
    EXPECT_EQ(a.mesh.positions[2], glm::vec3(10, 3, 0));
    EXPECT_EQ(a.mesh.positions[3], glm::vec3(12, 3, 0));
}

TEST_F(AssetFiles, LoadMeshReadsGltfAndGlb) {
    for (bool glb : {false, true}) {
        GltfOptions o;
        o.glb = glb;
        o.embedImage = glb;
        const std::string p = writeGltf(dir_, "m", SeamQuad{}, o);
        prt::MeshReport report;
        const TriangleMesh m = prt::loadMesh(p, &report);
        EXPECT_EQ(report.format, glb ? "glb" : "gltf");
        EXPECT_EQ(m.positions.size(), 4u);
        EXPECT_EQ(m.triangles.size(), 2u);
        EXPECT_EQ(m.normals.size(), 4u);
        EXPECT_EQ(report.fileFaces, 2u);
        EXPECT_EQ(prt::meshFingerprint(m), prt::meshFingerprint(prt::loadAsset(p).mesh));
    }
    // saveMesh does not write glTF (prt-make-asset does).
    expectAssetError([&] { prt::saveMesh(prt::makeIcosphere(0, 1), file("x.gltf")); }, file("x.gltf"), "extension");
}

// ---------------------------------------------------------------------------------
// OBJ + MTL
// ---------------------------------------------------------------------------------

TEST_F(AssetFiles, ObjWithMtlAndMapKd) {
    writeText("quad.mtl",
              "# two materials\nnewmtl textured\nKd 0.5 1 0.25\nmap_Kd tex.png\n\nnewmtl plain\nKd 0.2 0.4 0.6\n");
    // Triangle 0: uv (0,0), (1,0), (0,1) as on the glTF quad; a quad face (triangulated)
    // with its own vt per corner; a degenerate face (dropped) between them; a face
    // before any usemtl.
    const std::string obj = writeText("quad.obj",
                                      "mtllib quad.mtl\n"
                                      "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nv 2 0 0\nv 2 1 0\nv 3 3 1\n"
                                      "vt 0 0\nvt 1 0\nvt 0 1\nvt 0.1 0.2\nvt 0.3 0.4\nvt 0.5 0.6\nvt 0.7 0.8\n"
                                      "vn 0 0 2\n"
                                      "f 1 2 7\n"
                                      "usemtl textured\n"
                                      "f 1/1/1 2/2/1 3/3/1\n"
                                      "f 1/1 2/2 2/3\n"
                                      "usemtl plain\n"
                                      "f 2/4 5/5 6/6 4/7\n");
    prt::MeshReport meshReport;
    const TriangleMesh plain = prt::loadMesh(obj, &meshReport);
    const Asset a = prt::loadAsset(obj);
    EXPECT_EQ(prt::meshFingerprint(a.mesh), prt::meshFingerprint(plain));
    ASSERT_EQ(a.mesh.triangles.size(), 4u);  // 1 + 1 + quad as 2; the degenerate one dropped
    EXPECT_EQ(a.report.mesh.degenerateFaces, 1u);
    ASSERT_EQ(a.uvs.size(), 12u);
    ASSERT_EQ(a.triangleMaterials.size(), 4u);
    // Face before any usemtl: the default material, no texture coordinates.
    EXPECT_EQ(a.materials[a.triangleMaterials[0]].name, "");
    EXPECT_TRUE(std::isnan(a.uvs[0].x));
    EXPECT_EQ(prt::baseColorAt(a, 0, glm::vec3(1.0f / 3.0f)), glm::vec3(1.0f));
    // The textured triangle: vt as written (OBJ convention = ours).
    EXPECT_EQ(a.uvs[3], glm::vec2(0, 0));
    EXPECT_EQ(a.uvs[4], glm::vec2(1, 0));
    EXPECT_EQ(a.uvs[5], glm::vec2(0, 1));
    const auto& textured = a.materials[a.triangleMaterials[1]];
    EXPECT_EQ(textured.name, "textured");
    EXPECT_EQ(textured.baseColorFactor, glm::vec4(0.5f, 1.0f, 0.25f, 1.0f));
    EXPECT_EQ(textured.textureSource, file("tex.png"));
    EXPECT_EQ(textured.wrapU, TextureWrap::Repeat);
    expectVec3Near(glm::vec3(a.fileNormals[3]), glm::vec3(0, 0, 1), 1e-7f, "file normal (normalised)");
    EXPECT_TRUE(std::isnan(a.fileNormals[0].x));
    // Texel centres through triangle 1 (same uv layout as the glTF quad's triangle 0).
    for (int y = 0; y < kH; ++y)
        for (int x = 0; x < kW; ++x)
            expectVec3Near(prt::baseColorAt(a, 1, baryFor(texelCentre(x, y))),
                           glm::vec3(0.5f, 1.0f, 0.25f) * texelLinear(x, y), 2e-6f,
                           "texel " + std::to_string(x) + "," + std::to_string(y));
    // The quad's two triangles carry its corners' vt: every corner of triangles 2 and 3
    // has the vt of its vertex (vertex 1 -> 0.1 0.2, 4 -> 0.3 0.4, 5 -> 0.5 0.6, 3 -> 0.7 0.8).
    const std::map<uint32_t, glm::vec2> vtOf = {{1, {0.1f, 0.2f}}, {4, {0.3f, 0.4f}}, {5, {0.5f, 0.6f}}, {3, {0.7f, 0.8f}}};
    for (size_t t = 2; t < 4; ++t) {
        EXPECT_EQ(a.materials[a.triangleMaterials[t]].name, "plain");
        EXPECT_FALSE(a.materials[a.triangleMaterials[t]].hasTexture());
        for (int k = 0; k < 3; ++k) EXPECT_EQ(a.uvs[t * 3 + size_t(k)], vtOf.at(a.mesh.triangles[t][k])) << t << " " << k;
        EXPECT_EQ(prt::baseColorAt(a, uint32_t(t), glm::vec3(1.0f / 3.0f)), glm::vec3(0.2f, 0.4f, 0.6f));
    }
}

TEST_F(AssetFiles, ObjNegativeIndicesAndRepeatedCorners) {
    writeText("m.mtl", "newmtl a\nKd 1 1 1\nmap_Kd -clamp on tex.png\n");
    // Relative indices, and a face repeating a vertex (OpenMesh keeps the first
    // occurrence: 1 2 3).
    const std::string obj = writeText("m.obj",
                                      "mtllib m.mtl\nusemtl a\n"
                                      "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nvt 0.9 0.9\n"
                                      "f -3/-4 -2/-3 -1/-2 -2/-1\n");
    const Asset a = prt::loadAsset(obj);
    EXPECT_EQ(prt::meshFingerprint(a.mesh), prt::meshFingerprint(prt::loadMesh(obj)));
    ASSERT_EQ(a.mesh.triangles.size(), 1u);
    EXPECT_EQ(a.uvs[0], glm::vec2(0, 0));
    EXPECT_EQ(a.uvs[1], glm::vec2(1, 0));
    EXPECT_EQ(a.uvs[2], glm::vec2(0, 1));
    EXPECT_EQ(a.materials[a.triangleMaterials[0]].wrapU, TextureWrap::ClampToEdge);
}

// ---------------------------------------------------------------------------------
// The writer (prt-make-asset's library function)
// ---------------------------------------------------------------------------------

TEST_F(AssetFiles, GeneratedAssetKeepsTheMeshAndTheUvs) {
    // The input as a user has it: a file loadMesh reads.
    const std::string input = file("sphere.ply");
    prt::saveMesh(prt::makeIcosphere(3, 1.5f), input);
    const TriangleMesh mesh = prt::loadMesh(input);
    for (const auto projection : {prt::UvProjection::Spherical, prt::UvProjection::Box}) {
        const std::vector<glm::vec2> uvs = prt::projectUvs(mesh, projection);
        ASSERT_EQ(uvs.size(), mesh.triangles.size() * 3);
        for (size_t t = 0; t < mesh.triangles.size(); ++t) {
            float lo = 1e9f, hi = -1e9f;
            for (int k = 0; k < 3; ++k) {
                lo = std::min(lo, uvs[t * 3 + size_t(k)].x);
                hi = std::max(hi, uvs[t * 3 + size_t(k)].x);
                EXPECT_GE(uvs[t * 3 + size_t(k)].y, 0.0f);
                EXPECT_LE(uvs[t * 3 + size_t(k)].y, 1.0f);
            }
            EXPECT_LE(hi - lo, 2.0f / 3.0f + 1e-6f) << "triangle " << t << " spans the texture";
        }
        for (const char* ext : {".glb", ".gltf"}) {
            SCOPED_TRACE(ext);
            const std::string out = file(std::string("sphere") + ext);
            prt::saveTexturedGltf(out, mesh, uvs, testTexture());
            const Asset a = prt::loadAsset(out);
            EXPECT_EQ(prt::meshFingerprint(a.mesh), prt::meshFingerprint(mesh));
            EXPECT_EQ(prt::meshFingerprint(prt::loadMesh(out)), prt::meshFingerprint(mesh));
            ASSERT_EQ(a.uvs.size(), uvs.size());
            float worst = 0.0f;
            for (size_t c = 0; c < uvs.size(); ++c)
                worst = std::max({worst, std::abs(a.uvs[c].x - uvs[c].x), std::abs(a.uvs[c].y - uvs[c].y)});
            EXPECT_LE(worst, 1e-7f);  // v goes through 1 - v twice
            const auto& m = a.materials[a.triangleMaterials[0]];
            ASSERT_TRUE(m.hasTexture());
            // The texture comes back as the linear texels written.
            for (int y = 0; y < kH; ++y)
                for (int x = 0; x < kW; ++x)
                    expectVec3Near(glm::vec3(prt::sampleTexture(m.baseColorTexture, texelCentre(x, y), m.wrapU, m.wrapV)),
                                   texelLinear(x, y), 2e-6f, "texel");
        }
    }
    // The .gltf's parts sit beside it.
    EXPECT_TRUE(fs::exists(file("sphere.bin")));
    EXPECT_TRUE(fs::exists(file("sphere_basecolor.png")));
    expectAssetError([&] { prt::saveTexturedGltf(file("x.obj"), mesh, {}, testTexture()); }, file("x.obj"), "extension");
    expectAssetError([&] { prt::saveTexturedGltf(file("x.glb"), mesh, {}, testTexture()); }, file("x.glb"),
                     "texture coordinates");
}

TEST_F(AssetFiles, GeneratedCheckerTextureHasDistinctCells) {
    const prt::Image t = prt::makeCheckerTexture(64, 8);
    EXPECT_EQ(t.width, 64);
    EXPECT_EQ(t.channels, 3);
    // Neighbouring cells differ; every value is a valid linear colour.
    EXPECT_NE(glm::vec3(t.at(4, 4, 0), t.at(4, 4, 1), t.at(4, 4, 2)), glm::vec3(t.at(12, 4, 0), t.at(12, 4, 1), t.at(12, 4, 2)));
    for (float v : t.pixels) {
        EXPECT_GE(v, 0.0f);
        EXPECT_LE(v, 1.0f);
    }
}

// ---------------------------------------------------------------------------------
// Bad assets: one line naming the file
// ---------------------------------------------------------------------------------

TEST_F(AssetFiles, MalformedGltfIsRefusedInOneLine) {
    auto make = [&](const std::string& name, GltfOptions o) { return writeGltf(dir_, name, SeamQuad{}, o); };
    {
        GltfOptions o;
        o.imageUri = "nothere.png";
        const std::string p = make("missing-texture", o);
        expectAssetError([&] { prt::loadAsset(p); }, p, "not found");
        expectAssetError([&] { prt::loadAsset(p); }, p, "nothere.png");
        EXPECT_EQ(prt::loadMesh(p).triangles.size(), 2u);  // the mesh alone is fine
    }
    {
        GltfOptions o;
        o.patch = {{"bufferViews", {{{"buffer", 0}, {"byteOffset", 4000}, {"byteLength", 72}}, {{"buffer", 0}, {"byteOffset", 72}, {"byteLength", 48}}, {{"buffer", 0}, {"byteOffset", 120}, {"byteLength", 24}}}}};
        const std::string p = make("view-out-of-range", o);
        expectAssetError([&] { prt::loadMesh(p); }, p, "out of range");
    }
    {
        GltfOptions o;
        o.patch = json::parse(R"({"accessors": [{"bufferView": 0, "componentType": 5126, "count": 600, "type": "VEC3"}, {"bufferView": 1, "componentType": 5126, "count": 6, "type": "VEC2"}, {"bufferView": 2, "componentType": 5125, "count": 6, "type": "SCALAR"}]})");
        const std::string p = make("accessor-count", o);
        expectAssetError([&] { prt::loadAsset(p); }, p, "out of range");
    }
    for (const auto& [mode, name] : {std::pair{1, "LINES"}, std::pair{0, "POINTS"}, std::pair{3, "LINE_STRIP"}}) {
        GltfOptions o;
        o.mode = mode;
        const std::string p = make(std::string("mode-") + name, o);
        expectAssetError([&] { prt::loadMesh(p); }, p, std::string(name) + " (mode");
        expectAssetError([&] { prt::loadAsset(p); }, p, "only triangle primitives");
    }
    {
        SeamQuad q;
        q.positions[3] = std::nanf("");
        const std::string p = writeGltf(dir_, "nan", q, GltfOptions{});
        expectAssetError([&] { prt::loadAsset(p); }, p, "non-finite");
    }
    {
        SeamQuad q;
        q.indices[4] = 17;
        const std::string p = writeGltf(dir_, "index", q, GltfOptions{});
        expectAssetError([&] { prt::loadMesh(p); }, p, "declares 2 triangles but 1 could be read");
    }
    {
        const std::string p = make("broken", GltfOptions{});
        const std::string text = readBytes(p);
        writeBytes(p, text.substr(0, text.size() / 2));
        expectAssetError([&] { prt::loadAsset(p); }, p, "invalid glTF JSON");
    }
    {
        GltfOptions o;
        o.glb = true;
        o.embedImage = true;
        const std::string p = make("truncated", o);
        const std::string bytes = readBytes(p);
        writeBytes(p, bytes.substr(0, bytes.size() - 40));
        expectAssetError([&] { prt::loadAsset(p); }, p, "truncated");
    }
    {
        const std::string p = make("no-bin", GltfOptions{});
        fs::remove(file("no-bin.bin"));
        expectAssetError([&] { prt::loadMesh(p); }, p, "cannot be read as glTF");
    }
    {
        // An embedded image that is not one.
        GltfOptions o;
        o.glb = true;
        o.embedImage = true;
        o.corruptBuffer = [](std::string& bin) {
            const size_t at = bin.find("\x89PNG");
            ASSERT_NE(at, std::string::npos);
            for (size_t i = at + 8; i < bin.size(); ++i) bin[i] = char(i * 7);
        };
        const std::string p = make("bad-image", o);
        expectAssetError([&] { prt::loadAsset(p); }, p, "cannot be decoded");
    }
    {
        GltfOptions o;
        o.imageUri = "fake.png";
        writeText("fake.png", "not a PNG at all");
        const std::string p = make("fake-texture", o);
        expectAssetError([&] { prt::loadAsset(p); }, p, "fake.png");
    }
    {
        const std::string p = writeText("empty.gltf", R"({"asset": {"version": "2.0"}})");
        expectAssetError([&] { prt::loadMesh(p); }, p, "empty mesh");
    }
    {
        const std::string p = writeText("old.gltf", R"({"asset": {"version": "1.0"}})");
        expectAssetError([&] { prt::loadMesh(p); }, p, "only 2.x");
    }
    const std::string odd = writeText("m.fbx", "whatever");
    expectAssetError([&] { prt::loadAsset(odd); }, odd, "extension");
    expectAssetError([&] { prt::loadAsset(file("none.glb")); }, file("none.glb"), "no such file");
}

TEST_F(AssetFiles, MalformedObjAssetsAreRefusedInOneLine) {
    const std::string geometry = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\n";
    {
        const std::string p = writeText("no-mtl.obj", "mtllib nowhere.mtl\nusemtl a\n" + geometry + "f 1/1 2/2 3/3\n");
        expectAssetError([&] { prt::loadAsset(p); }, p, "material library not found");
        EXPECT_EQ(prt::loadMesh(p).triangles.size(), 1u);  // loadMesh ignores materials
    }
    {
        writeText("a.mtl", "newmtl a\nKd 1 1 1\nmap_Kd gone.png\n");
        const std::string p = writeText("no-tex.obj", "mtllib a.mtl\nusemtl a\n" + geometry + "f 1/1 2/2 3/3\n");
        expectAssetError([&] { prt::loadAsset(p); }, p, "gone.png");
    }
    {
        writeText("b.mtl", "newmtl b\nKd 1 1 1\n");
        const std::string p = writeText("undefined.obj", "mtllib b.mtl\nusemtl c\n" + geometry + "f 1/1 2/2 3/3\n");
        expectAssetError([&] { prt::loadAsset(p); }, p, "usemtl 'c'");
    }
    {
        writeText("bad.mtl", "newmtl b\nKd 1 x 1\n");
        const std::string p = writeText("bad-kd.obj", "mtllib bad.mtl\nusemtl b\n" + geometry + "f 1/1 2/2 3/3\n");
        expectAssetError([&] { prt::loadAsset(p); }, p, "bad.mtl line 2");
    }
    {
        const std::string p = writeText("vt-range.obj", geometry + "f 1/1 2/2 3/9\n");
        expectAssetError([&] { prt::loadAsset(p); }, p, "line 7: texture coordinate index '9' is out of range");
        EXPECT_EQ(prt::loadMesh(p).triangles.size(), 1u);  // as before: loadMesh ignores vt
    }
    {
        const std::string p = writeText("vt-nan.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt nan 0\nf 1/1 2/1 3/1\n");
        expectAssetError([&] { prt::loadAsset(p); }, p, "non-finite texture coordinate");
    }
}
