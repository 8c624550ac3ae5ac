// Textured assets (common/asset_io.h): loadAsset (mesh_io's surface data + the MTL
// reader + texture decoding), the texture lookup, generated texture coordinates and the
// glTF writer.
#include "common/asset_io.h"

#include "common/atomic_file.h"
#include "common/error.h"
#include "common/util.h"

#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/imageio.h>

#include <zlib.h>

#include <nlohmann/json.hpp>

#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <sstream>
#include <unordered_map>

namespace prt {

namespace {

namespace fs = std::filesystem;

std::string readWholeFile(const std::string& subject, const std::string& file) {
    std::ifstream in(file, std::ios::binary);
    if (!in) throw Error(subject, "cannot open " + file);
    std::ostringstream s;
    s << in.rdbuf();
    return s.str();
}

// Integer pixels are sRGB-encoded (PNG, JPEG); float pixels are linear.
void linearise(Image& image, bool srgb) {
    if (!srgb) return;
    const int colourChannels = image.channels == 2 || image.channels == 4 ? image.channels - 1 : image.channels;
    for (size_t p = 0; p < size_t(image.width) * size_t(image.height); ++p)
        for (int c = 0; c < std::min(colourChannels, 3); ++c) {
            float& v = image.pixels[p * size_t(image.channels) + size_t(c)];
            v = srgbToLinear(v);
        }
}

bool isFloatFormat(const OIIO::TypeDesc& t) {
    return t.basetype == OIIO::TypeDesc::FLOAT || t.basetype == OIIO::TypeDesc::HALF ||
           t.basetype == OIIO::TypeDesc::DOUBLE;
}

bool isPng(const std::string& bytes) { return bytes.size() >= 8 && std::memcmp(bytes.data(), "\x89PNG\r\n\x1a\n", 8) == 0; }

uint32_t readBe32(const std::string& bytes, size_t at) {
    const auto* b = reinterpret_cast<const unsigned char*>(bytes.data()) + at;
    return uint32_t(b[0]) << 24 | uint32_t(b[1]) << 16 | uint32_t(b[2]) << 8 | uint32_t(b[3]);
}

// The signature, chunk structure and CRCs of PNG bytes: "" when sound, else the
// problem. libpng, under OpenImageIO, prints its own message on stderr for a corrupt or
// truncated file; this check refuses such files first, in one line.
std::string pngProblem(const std::string& bytes) {
    if (!isPng(bytes)) return "corrupt PNG signature";
    size_t at = 8;
    while (at + 12 <= bytes.size()) {
        const uint32_t length = readBe32(bytes, at);
        if (uint64_t(length) + 12 > bytes.size() - at) return "truncated PNG (a chunk runs past the end)";
        const uint32_t stored = readBe32(bytes, at + 8 + length);
        const uint32_t crc = uint32_t(crc32(0L, reinterpret_cast<const Bytef*>(bytes.data() + at + 4), uInt(length + 4)));
        if (crc != stored) return "corrupt PNG (chunk " + bytes.substr(at + 4, 4) + " fails its CRC)";
        if (bytes.compare(at + 4, 4, "IEND") == 0) return "";
        at += 12 + length;
    }
    return "truncated PNG (no IEND chunk)";
}

// Decodes an image held in memory (an embedded glTF texture). `what` names it in errors.
Image decodeImageBytes(const std::string& subject, const std::string& what, const std::string& bytes,
                       std::string formatHint) {
    if (bytes.empty()) throw Error(subject, what + " is empty");
    if (bytes.size() >= 4 && std::memcmp(bytes.data(), "\x89PNG", 4) == 0)
        if (const std::string problem = pngProblem(bytes); !problem.empty())
            throw Error(subject, what + " cannot be decoded: " + problem);
    const auto* b = reinterpret_cast<const unsigned char*>(bytes.data());
    if (bytes.size() >= 8 && std::memcmp(b, "\x89PNG", 4) == 0) formatHint = "png";
    else if (bytes.size() >= 3 && b[0] == 0xff && b[1] == 0xd8 && b[2] == 0xff) formatHint = "jpg";
    if (formatHint.empty()) throw Error(subject, what + " is neither PNG nor JPEG and has no format hint");
    OIIO::Filesystem::IOMemReader proxy(bytes.data(), bytes.size());
    auto in = OIIO::ImageInput::open("embedded." + formatHint, nullptr, &proxy);
    if (!in) throw Error(subject, what + " cannot be decoded: " + oneLine(OIIO::geterror()));
    const OIIO::ImageSpec spec = in->spec();
    if (spec.width <= 0 || spec.height <= 0 || spec.nchannels <= 0 || spec.width > kMaxImageSide ||
        spec.height > kMaxImageSide || spec.nchannels > 64 || spec.depth > 1 || spec.deep)
        throw Error(subject, what + " has an unsupported size (" + std::to_string(spec.width) + " x " +
                                 std::to_string(spec.height) + " x " + std::to_string(spec.nchannels) + ")");
    Image image(spec.width, spec.height, spec.nchannels);
    if (!in->read_image(0, 0, 0, spec.nchannels, OIIO::TypeDesc::FLOAT, image.pixels.data()))
        throw Error(subject, what + " cannot be decoded: " + oneLine(in->geterror()));
    in->close();
    linearise(image, !isFloatFormat(spec.format));
    return image;
}

// Reads a texture file (readImage) and linearises it by its stored pixel type.
Image decodeImageFile(const std::string& subject, const std::string& what, const std::string& file) {
    std::error_code ec;
    if (!fs::exists(file, ec)) throw Error(subject, what + " not found: " + file);
    if (fs::is_regular_file(file, ec)) {
        const std::string bytes = readWholeFile(subject, file);
        if (bytes.size() >= 4 && std::memcmp(bytes.data(), "\x89PNG", 4) == 0)
            if (const std::string problem = pngProblem(bytes); !problem.empty())
                throw Error(subject, what + " (" + file + ") cannot be decoded: " + problem);
    }
    Image image;
    try {
        image = readImage(file);
    } catch (const Error& e) {
        throw Error(subject, what + " (" + file + ") cannot be read: " + e.reason());
    }
    bool srgb = true;
    if (auto in = OIIO::ImageInput::open(file)) {
        srgb = !isFloatFormat(in->spec().format);
        in->close();
    }
    linearise(image, srgb);
    return image;
}

// ---- MTL ----------------------------------------------------------------------------

struct MtlEntry {
    glm::vec3 kd{1.0f};
    std::string mapKd;  // as written (relative to the .mtl)
    bool clamp = false;
    fs::path dir;       // the .mtl's directory
};

// newmtl / Kd / map_Kd only (asset_io.h says why).
void readMtl(const std::string& subject, const fs::path& file, std::map<std::string, MtlEntry>& out) {
    std::error_code ec;
    if (!fs::is_regular_file(file, ec)) throw Error(subject, "material library not found: " + file.string());
    const std::string text = readWholeFile(subject, file.string());
    std::istringstream lines(text);
    std::string line;
    size_t number = 0;
    MtlEntry* current = nullptr;
    while (std::getline(lines, line)) {
        ++number;
        const std::string t = trim(line);
        if (t.empty() || t[0] == '#') continue;
        std::istringstream words(t);
        std::string keyword;
        words >> keyword;
        const std::string where = file.filename().string() + " line " + std::to_string(number) + ": ";
        if (keyword == "newmtl") {
            const std::string name = trim(t.substr(6));
            current = &out[name];
            *current = MtlEntry{};
            current->dir = file.parent_path();
        } else if (keyword == "Kd" || keyword == "map_Kd") {
            if (!current) throw Error(subject, where + keyword + " before any newmtl");
            std::vector<std::string> args;
            for (std::string w; words >> w;) args.push_back(w);
            if (keyword == "Kd") {
                if (args.size() != 3) throw Error(subject, where + "Kd needs three values (r g b)");
                for (int c = 0; c < 3; ++c) {
                    char* end = nullptr;
                    const double v = std::strtod(args[size_t(c)].c_str(), &end);
                    if (end == args[size_t(c)].c_str() || *end != '\0' || !std::isfinite(v))
                        throw Error(subject, where + "cannot parse Kd value '" + args[size_t(c)] + "'");
                    current->kd[c] = float(v);
                }
            } else {
                if (args.empty()) throw Error(subject, where + "map_Kd without a file name");
                current->mapKd = args.back();
                for (size_t i = 0; i + 1 < args.size(); ++i)
                    if (args[i] == "-clamp") current->clamp = toLower(args[i + 1]) == "on";
            }
        }
    }
}

size_t wrapIndex(long long i, int n, TextureWrap wrap) {
    switch (wrap) {
        case TextureWrap::ClampToEdge: return size_t(std::clamp<long long>(i, 0, n - 1));
        case TextureWrap::MirroredRepeat: {
            const long long period = 2LL * n;
            long long m = i % period;
            if (m < 0) m += period;
            return size_t(m < n ? m : period - 1 - m);
        }
        case TextureWrap::Repeat:
        default: {
            long long m = i % n;
            if (m < 0) m += n;
            return size_t(m);
        }
    }
}

glm::vec4 texel(const Image& t, size_t x, size_t y) {
    const float* p = t.pixel(int(x), int(y));
    switch (t.channels) {
        case 1: return glm::vec4(p[0], p[0], p[0], 1.0f);
        case 2: return glm::vec4(p[0], p[0], p[0], p[1]);
        case 3: return glm::vec4(p[0], p[1], p[2], 1.0f);
        default: return glm::vec4(p[0], p[1], p[2], p[3]);
    }
}

}  // namespace

// ---------------------------------------------------------------------------------
// loadAsset
// ---------------------------------------------------------------------------------

Asset loadAsset(const std::string& path) {
    Asset asset;
    MeshSurface surface;
    asset.mesh = loadMeshSurface(path, surface, &asset.report.mesh);
    asset.uvs = std::move(surface.uvs);
    asset.fileNormals = std::move(surface.normals);
    asset.triangleMaterials = std::move(surface.triangleMaterials);
    const fs::path dir = fs::path(path).parent_path();

    // OBJ: factors and textures from the material libraries.
    std::map<std::string, MtlEntry> mtl;
    for (const std::string& lib : surface.materialLibraries) readMtl(path, dir / lib, mtl);
    const bool obj = asset.report.mesh.format == "obj";
    std::vector<std::string> texturePaths(surface.materials.size());  // resolved, "" for none
    if (obj) {
        for (size_t i = 0; i < surface.materials.size(); ++i) {
            FileMaterial& m = surface.materials[i];
            if (m.name.empty() && i + 1 == surface.materials.size()) continue;  // the default
            const auto it = mtl.find(m.name);
            if (it == mtl.end())
                throw Error(path, "usemtl '" + m.name + "' names a material that no material library defines" +
                                      (surface.materialLibraries.empty() ? std::string(" (the file has no mtllib)")
                                                                         : std::string()));
            m.baseColorFactor = glm::vec4(it->second.kd, 1.0f);
            if (!it->second.mapKd.empty()) texturePaths[i] = (it->second.dir / it->second.mapKd).string();
            if (it->second.clamp) m.wrapU = m.wrapV = TextureWrap::ClampToEdge;
        }
    } else {
        for (size_t i = 0; i < surface.materials.size(); ++i)
            if (!surface.materials[i].texture.empty())
                texturePaths[i] = (dir / surface.materials[i].texture).string();
    }

    // Textures, each decoded once: files by path, embedded images by their bytes.
    std::map<std::string, Image> decoded, decodedEmbedded;
    for (size_t i = 0; i < surface.materials.size(); ++i) {
        const FileMaterial& fm = surface.materials[i];
        AssetMaterial m;
        m.name = fm.name;
        m.baseColorFactor = fm.baseColorFactor;
        m.wrapU = fm.wrapU;
        m.wrapV = fm.wrapV;
        const std::string what = "the base-colour texture of material '" + fm.name + "'";
        if (!fm.embeddedTexture.empty()) {
            auto it = decodedEmbedded.find(fm.embeddedTexture);
            if (it == decodedEmbedded.end())
                it = decodedEmbedded.emplace(fm.embeddedTexture, decodeImageBytes(path, what + " (embedded)",
                                                                                  fm.embeddedTexture, fm.embeddedFormat))
                         .first;
            m.baseColorTexture = it->second;
            m.textureSource = "embedded";
        } else if (!texturePaths[i].empty()) {
            auto it = decoded.find(texturePaths[i]);
            if (it == decoded.end())
                it = decoded.emplace(texturePaths[i], decodeImageFile(path, what, texturePaths[i])).first;
            m.baseColorTexture = it->second;
            m.textureSource = texturePaths[i];
        }
        asset.materials.push_back(std::move(m));
    }
    if (asset.materials.empty()) asset.materials.emplace_back();

    for (const glm::vec2& uv : asset.uvs) asset.report.uvCorners += std::isnan(uv.x) ? 0 : 1;
    for (const glm::vec3& n : asset.fileNormals) asset.report.normalCorners += std::isnan(n.x) ? 0 : 1;
    asset.report.materials = asset.materials.size();
    asset.report.textures = decoded.size() + decodedEmbedded.size();
    return asset;
}

// ---------------------------------------------------------------------------------
// Lookup
// ---------------------------------------------------------------------------------

glm::vec4 sampleTexture(const Image& texture, glm::vec2 uv, TextureWrap wrapU, TextureWrap wrapV) {
    if (std::isnan(uv.x) || std::isnan(uv.y)) return glm::vec4(std::numeric_limits<float>::quiet_NaN());
    // Texel centres at integer coordinates; row 0 is the top (v = 1).
    const double s = double(uv.x) * texture.width - 0.5;
    const double t = (1.0 - double(uv.y)) * texture.height - 0.5;
    const double fs0 = std::floor(s), ft0 = std::floor(t);
    const float fx = float(s - fs0), fy = float(t - ft0);
    const auto x0 = (long long)fs0, y0 = (long long)ft0;
    const size_t xa = wrapIndex(x0, texture.width, wrapU), xb = wrapIndex(x0 + 1, texture.width, wrapU);
    const size_t ya = wrapIndex(y0, texture.height, wrapV), yb = wrapIndex(y0 + 1, texture.height, wrapV);
    const glm::vec4 top = glm::mix(texel(texture, xa, ya), texel(texture, xb, ya), fx);
    const glm::vec4 bottom = glm::mix(texel(texture, xa, yb), texel(texture, xb, yb), fx);
    return glm::mix(top, bottom, fy);
}

glm::vec3 baseColorAt(const Asset& asset, uint32_t triangle, glm::vec3 barycentric) {
    const AssetMaterial& m = asset.materials[asset.triangleMaterials.empty() ? 0 : asset.triangleMaterials[triangle]];
    const glm::vec3 factor(m.baseColorFactor);
    if (!m.hasTexture() || asset.uvs.empty()) return factor;
    const size_t at = size_t(triangle) * 3;
    const glm::vec2 uv = barycentric.x * asset.uvs[at] + barycentric.y * asset.uvs[at + 1] +
                         barycentric.z * asset.uvs[at + 2];
    if (std::isnan(uv.x) || std::isnan(uv.y)) return factor;
    return factor * glm::vec3(sampleTexture(m.baseColorTexture, uv, m.wrapU, m.wrapV));
}

// ---------------------------------------------------------------------------------
// Generated texture coordinates and textures
// ---------------------------------------------------------------------------------

std::vector<glm::vec2> projectUvs(const TriangleMesh& mesh, UvProjection projection) {
    std::vector<glm::vec2> uvs;
    uvs.reserve(mesh.triangles.size() * 3);
    const Bounds box = bounds(mesh);
    const glm::dvec3 centre(box.centre());
    const glm::dvec3 lo(box.lo), size(box.size());
    for (size_t f = 0; f < mesh.triangles.size(); ++f) {
        const glm::uvec3 t = mesh.triangles[f];
        glm::vec2 c[3];
        if (projection == UvProjection::Spherical) {
            for (int k = 0; k < 3; ++k) {
                const glm::dvec3 d = glm::dvec3(mesh.positions[t[k]]) - centre;
                const double r = glm::length(d);
                const double u = 0.5 + std::atan2(d.x, d.z) / (2.0 * kPi);
                const double v = r > 0.0 ? 0.5 + std::asin(std::clamp(d.y / r, -1.0, 1.0)) / kPi : 0.5;
                c[k] = glm::vec2(float(u), float(v));
            }
            // Shortest arc holding the three u values on the circle: start it after the
            // largest gap, shifting the corners before the gap by 1.
            int order[3] = {0, 1, 2};
            std::sort(order, order + 3, [&](int a, int b) { return c[a].x < c[b].x; });
            const float gaps[3] = {c[order[1]].x - c[order[0]].x, c[order[2]].x - c[order[1]].x,
                                   c[order[0]].x + 1.0f - c[order[2]].x};
            const int largest = int(std::max_element(gaps, gaps + 3) - gaps);
            if (largest == 0) c[order[0]].x += 1.0f;
            if (largest == 1) {
                c[order[0]].x += 1.0f;
                c[order[1]].x += 1.0f;
            }
        } else {
            const glm::dvec3 n = glm::cross(glm::dvec3(mesh.positions[t.y]) - glm::dvec3(mesh.positions[t.x]),
                                            glm::dvec3(mesh.positions[t.z]) - glm::dvec3(mesh.positions[t.x]));
            int axis = 0;
            for (int a = 1; a < 3; ++a)
                if (std::abs(n[a]) > std::abs(n[axis])) axis = a;
            const int a = (axis + 1) % 3, b = (axis + 2) % 3;
            for (int k = 0; k < 3; ++k) {
                const glm::dvec3 p(mesh.positions[t[k]]);
                const double u = size[a] > 0.0 ? (p[a] - lo[a]) / size[a] : 0.5;
                const double v = size[b] > 0.0 ? (p[b] - lo[b]) / size[b] : 0.5;
                c[k] = glm::vec2(float(u), float(v));
            }
        }
        for (const auto& k : c) uvs.push_back(k);
    }
    return uvs;
}

Image makeCheckerTexture(int size, int cells) {
    if (size < 1 || cells < 1) throw Error("texture", "size and cell count must be at least 1");
    Image image(size, size, 3);
    for (int y = 0; y < size; ++y)
        for (int x = 0; x < size; ++x) {
            const int cx = x * cells / size, cy = y * cells / size;
            const float hue = (float(cx) + 0.5f) / float(cells);  // 0..1 across u
            const float level = 0.25f + 0.75f * (1.0f - (float(cy) + 0.5f) / float(cells));  // brighter at the top
            const float dark = ((cx + cy) % 2 == 0) ? 1.0f : 0.35f;
            glm::vec3 rgb;
            for (int c = 0; c < 3; ++c) {
                const float phase = hue * 6.0f + float(c) * 2.0f;
                const float k = std::fmod(phase, 6.0f);
                rgb[c] = std::clamp(std::abs(k - 3.0f) - 1.0f, 0.0f, 1.0f);
            }
            const glm::vec3 colour = dark * level * (0.2f + 0.8f * rgb);
            for (int c = 0; c < 3; ++c) image.at(x, y, c) = colour[c];
        }
    return image;
}

// ---------------------------------------------------------------------------------
// saveTexturedGltf
// ---------------------------------------------------------------------------------

namespace {

int wrapCode(TextureWrap w) {
    switch (w) {
        case TextureWrap::ClampToEdge: return 33071;
        case TextureWrap::MirroredRepeat: return 33648;
        case TextureWrap::Repeat:
        default: return 10497;
    }
}

void appendBytes(std::string& buffer, const void* data, size_t n) {
    buffer.append(static_cast<const char*>(data), n);
}

void padTo4(std::string& buffer, char pad) {
    while (buffer.size() % 4 != 0) buffer.push_back(pad);
}

// PNG bytes of a linear image, through writePng and a temporary file.
std::string encodePng(const std::string& subject, const Image& texture) {
    static std::atomic<unsigned> counter{0};
    const fs::path temp = fs::temp_directory_path() /
                          ("prt-asset-" + std::to_string(long(::getpid())) + "-" + std::to_string(counter++) + ".png");
    struct Remove {
        fs::path p;
        ~Remove() {
            std::error_code ec;
            fs::remove(p, ec);
        }
    } remove{temp};
    try {
        writePng(temp.string(), texture);
    } catch (const Error& e) {
        throw Error(subject, "cannot encode the texture as PNG: " + e.reason());
    }
    return readWholeFile(subject, temp.string());
}

}  // namespace

void saveTexturedGltf(const std::string& path, const TriangleMesh& mesh, const std::vector<glm::vec2>& uvs,
                      const Image& texture, const std::string& pngBytes, TextureWrap wrap, glm::vec4 baseColorFactor) {
    const std::string ext = toLower(fs::path(path).extension().string());
    if (ext != ".gltf" && ext != ".glb")
        throw Error(path, "cannot write a textured asset with extension '" + ext + "' (supported: .gltf .glb)");
    if (uvs.size() != mesh.triangles.size() * 3)
        throw Error(path, "expected " + std::to_string(mesh.triangles.size() * 3) + " texture coordinates (3 per triangle), got " +
                              std::to_string(uvs.size()));
    for (const glm::vec2& uv : uvs)
        if (!std::isfinite(uv.x) || !std::isfinite(uv.y)) throw Error(path, "a texture coordinate is not finite");
    for (const glm::uvec3& t : mesh.triangles)
        if (t.x >= mesh.positions.size() || t.y >= mesh.positions.size() || t.z >= mesh.positions.size())
            throw Error(path, "a triangle refers to a vertex that does not exist");
    if (mesh.triangles.empty()) throw Error(path, "the mesh has no triangles");
    if (pngBytes.empty() && (texture.empty() || !texture.consistent())) throw Error(path, "the texture is empty");
    checkOutputPath(path);

    // Vertices: the mesh's own, in order (each with the texture coordinate of its first
    // corner), then one more per further (vertex, texture coordinate) pair. loadAsset
    // welds by position in this order, giving back the mesh's vertex order.
    const size_t nv = mesh.positions.size();
    std::vector<glm::vec3> positions(mesh.positions.begin(), mesh.positions.end());
    std::vector<glm::vec2> vertexUv(nv, glm::vec2(0.0f));
    std::vector<bool> assigned(nv, false);
    std::map<std::tuple<uint32_t, uint32_t, uint32_t>, uint32_t> extra;
    std::vector<uint32_t> indices(mesh.triangles.size() * 3);
    auto bitsOf = [](float v) {
        uint32_t b;
        std::memcpy(&b, &v, 4);
        return b;
    };
    for (size_t f = 0; f < mesh.triangles.size(); ++f)
        for (int k = 0; k < 3; ++k) {
            const uint32_t v = mesh.triangles[f][k];
            const glm::vec2 uv = uvs[f * 3 + size_t(k)];
            uint32_t out = v;
            if (!assigned[v]) {
                assigned[v] = true;
                vertexUv[v] = uv;
            } else if (bitsOf(vertexUv[v].x) != bitsOf(uv.x) || bitsOf(vertexUv[v].y) != bitsOf(uv.y)) {
                const auto key = std::make_tuple(v, bitsOf(uv.x), bitsOf(uv.y));
                const auto [it, inserted] = extra.try_emplace(key, uint32_t(positions.size()));
                if (inserted) {
                    positions.push_back(mesh.positions[v]);
                    vertexUv.push_back(uv);
                }
                out = it->second;
            }
            indices[f * 3 + size_t(k)] = out;
        }

    std::string bin;
    glm::vec3 lo(std::numeric_limits<float>::max()), hi(std::numeric_limits<float>::lowest());
    for (const glm::vec3& p : positions) {
        appendBytes(bin, &p, sizeof p);
        lo = glm::min(lo, p);
        hi = glm::max(hi, p);
    }
    const size_t uvOffset = bin.size();
    for (const glm::vec2& uv : vertexUv) {
        const glm::vec2 gltfUv(uv.x, 1.0f - uv.y);  // glTF: v down from the top-left corner
        appendBytes(bin, &gltfUv, sizeof gltfUv);
    }
    const size_t indexOffset = bin.size();
    appendBytes(bin, indices.data(), indices.size() * sizeof(uint32_t));
    const size_t geometryEnd = bin.size();

    if (!pngBytes.empty()) {
        if (!isPng(pngBytes)) throw Error(path, "the texture given is not a PNG");
        (void)decodeImageBytes(path, "the texture given", pngBytes, "png");  // refuses a broken one
    }
    const std::string png = pngBytes.empty() ? encodePng(path, texture) : pngBytes;
    const bool glb = ext == ".glb";
    size_t imageOffset = 0;
    if (glb) {
        padTo4(bin, '\0');
        imageOffset = bin.size();
        bin += png;
    }
    padTo4(bin, '\0');

    using nlohmann::json;
    const std::string stem = fs::path(path).stem().string();
    const fs::path dir = fs::path(path).parent_path();
    const std::string binName = stem + ".bin", pngName = stem + "_basecolor.png";
    json bufferViews = json::array({
        {{"buffer", 0}, {"byteOffset", 0}, {"byteLength", uvOffset}, {"target", 34962}},
        {{"buffer", 0}, {"byteOffset", uvOffset}, {"byteLength", indexOffset - uvOffset}, {"target", 34962}},
        {{"buffer", 0}, {"byteOffset", indexOffset}, {"byteLength", geometryEnd - indexOffset}, {"target", 34963}},
    });
    json image;
    if (glb) {
        bufferViews.push_back({{"buffer", 0}, {"byteOffset", imageOffset}, {"byteLength", png.size()}});
        image = {{"bufferView", 3}, {"mimeType", "image/png"}};
    } else {
        image = {{"uri", pngName}};
    }
    json buffer = {{"byteLength", bin.size()}};
    if (!glb) buffer["uri"] = binName;
    const json doc = {
        {"asset", {{"version", "2.0"}, {"generator", "prt-make-asset"}}},
        {"scene", 0},
        {"scenes", json::array({{{"nodes", json::array({0})}}})},
        {"nodes", json::array({{{"mesh", 0}}})},
        {"meshes", json::array({{{"primitives", json::array({{{"attributes", {{"POSITION", 0}, {"TEXCOORD_0", 1}}},
                                                              {"indices", 2},
                                                              {"material", 0},
                                                              {"mode", 4}}})}}})},
        {"materials", json::array({{{"name", "basecolor"},
                                    {"pbrMetallicRoughness",
                                     {{"baseColorFactor",
                                       {baseColorFactor.r, baseColorFactor.g, baseColorFactor.b, baseColorFactor.a}},
                                      {"baseColorTexture", {{"index", 0}}},
                                      {"metallicFactor", 0.0},
                                      {"roughnessFactor", 1.0}}}}})},
        {"textures", json::array({{{"source", 0}, {"sampler", 0}}})},
        {"samplers", json::array({{{"magFilter", 9729}, {"minFilter", 9729}, {"wrapS", wrapCode(wrap)},
                                   {"wrapT", wrapCode(wrap)}}})},
        {"images", json::array({image})},
        {"buffers", json::array({buffer})},
        {"bufferViews", bufferViews},
        {"accessors", json::array({
                          {{"bufferView", 0}, {"componentType", 5126}, {"count", positions.size()}, {"type", "VEC3"},
                           {"min", {lo.x, lo.y, lo.z}}, {"max", {hi.x, hi.y, hi.z}}},
                          {{"bufferView", 1}, {"componentType", 5126}, {"count", vertexUv.size()}, {"type", "VEC2"}},
                          {{"bufferView", 2}, {"componentType", 5125}, {"count", indices.size()}, {"type", "SCALAR"}},
                      })},
    };
    std::string text = doc.dump();

    if (glb) {
        padTo4(text, ' ');
        std::string out;
        const uint32_t total = uint32_t(12 + 8 + text.size() + 8 + bin.size());
        const uint32_t header[3] = {0x46546C67u /* "glTF" */, 2u, total};
        appendBytes(out, header, sizeof header);
        const uint32_t jsonChunk[2] = {uint32_t(text.size()), 0x4E4F534Au /* "JSON" */};
        appendBytes(out, jsonChunk, sizeof jsonChunk);
        out += text;
        const uint32_t binChunk[2] = {uint32_t(bin.size()), 0x004E4942u /* "BIN\0" */};
        appendBytes(out, binChunk, sizeof binChunk);
        out += bin;
        writeFileAtomically(path, out);
    } else {
        writeFileAtomically((dir / binName).string(), bin);
        writeFileAtomically((dir / pngName).string(), png);
        writeFileAtomically(path, text + "\n");
    }
}

}  // namespace prt
