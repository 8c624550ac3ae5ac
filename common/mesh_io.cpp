// Mesh files (common/mesh_io.h): loadMesh (pre-scan, OpenMesh reader into a polygon
// soup, triangulation, clean-up, report) and saveMesh (OpenMesh writers, own OBJ
// writer). The in-memory mesh and its geometry are mesh.cpp.
#include "common/mesh_io.h"

#include "common/error.h"
#include "common/atomic_file.h"
#include "common/util.h"

#include <OpenMesh/Core/IO/IOManager.hh>
#include <OpenMesh/Core/IO/Options.hh>
#include <OpenMesh/Core/IO/exporter/BaseExporter.hh>
#include <OpenMesh/Core/IO/importer/BaseImporter.hh>
#include <OpenMesh/Core/Mesh/BaseKernel.hh>
#include <OpenMesh/Core/System/omstream.hh>

#include <assimp/Importer.hpp>
#include <assimp/material.h>
#include <assimp/scene.h>

#include <nlohmann/json.hpp>

#include <zlib.h>

#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <limits>
#include <mutex>
#include <string_view>
#include <system_error>
#include <unordered_map>

namespace prt {

// ---------------------------------------------------------------------------------
// Loading: helpers
// ---------------------------------------------------------------------------------

namespace {

enum class Format { Obj, Ply, Off, Stl, Gltf, Glb };


std::string formatName(Format f) {
    switch (f) {
        case Format::Obj: return "obj";
        case Format::Ply: return "ply";
        case Format::Off: return "off";
        case Format::Stl: return "stl";
        case Format::Gltf: return "gltf";
        case Format::Glb: return "glb";
    }
    return "?";
}

// Format from the file name; `gz` is set when the name ends in .gz.
Format formatOf(const std::string& path, bool& gz, const char* verb) {
    std::string name = toLower(std::filesystem::path(path).filename().string());
    gz = false;
    if (name.size() > 3 && name.ends_with(".gz")) {
        gz = true;
        name.resize(name.size() - 3);
    }
    const auto dot = name.rfind('.');
    const std::string ext = dot == std::string::npos ? std::string() : name.substr(dot + 1);
    if (ext == "obj") return Format::Obj;
    if (ext == "ply") return Format::Ply;
    if (ext == "off") return Format::Off;
    if (ext == "stl") return Format::Stl;
    const bool load = std::string(verb) == "load";
    if (load && (ext == "gltf" || ext == "glb")) {
        if (gz) throw Error(path, "compressed glTF (." + ext + ".gz) is not supported");
        return ext == "gltf" ? Format::Gltf : Format::Glb;
    }
    throw Error(path, std::string("cannot ") + verb + " a mesh with extension '" +
                          (ext.empty() ? std::string() : "." + ext) +
                          "' (supported: .obj .ply .off .stl" +
                          (load ? ", each optionally .gz, and .gltf .glb" : "") + ")");
}

// Whole file, decompressed if it is gzip data (zlib reads plain files unchanged).
std::string readFileBytes(const std::string& path, bool& wasCompressed) {
    gzFile file = gzopen(path.c_str(), "rb");
    if (!file) throw Error(path, std::string("cannot open: ") + std::strerror(errno));
    std::string data;
    std::array<char, 1 << 16> chunk;
    for (;;) {
        const int n = gzread(file, chunk.data(), unsigned(chunk.size()));
        if (n < 0) {
            int code = 0;
            const std::string msg = gzerror(file, &code);
            gzclose(file);
            throw Error(path, "corrupt compressed data: " + msg);
        }
        if (n == 0) break;
        data.append(chunk.data(), size_t(n));
    }
    wasCompressed = gzdirect(file) == 0;
    const int rc = gzclose(file);
    if (rc == Z_BUF_ERROR) throw Error(path, "compressed data ends unexpectedly (truncated .gz)");
    if (rc != Z_OK) throw Error(path, "error while reading the file");
    return data;
}

// A file created with mkstemps, removed on destruction.
class TempFile {
public:
    // Errors name `subject` (the file the caller is loading or saving).
    TempFile(const std::string& subject, const std::filesystem::path& dir, const std::string& stem,
             const std::string& suffix) {
        std::string templ = (dir / (stem + "XXXXXX" + suffix)).string();
        std::vector<char> buf(templ.begin(), templ.end());
        buf.push_back('\0');
        const int fd = mkstemps(buf.data(), int(suffix.size()));
        if (fd < 0)
            throw Error(subject, "cannot create temporary file " + templ + ": " + std::strerror(errno));
        ::close(fd);
        path_ = buf.data();
    }
    ~TempFile() {
        if (!path_.empty()) {
            std::error_code ec;
            std::filesystem::remove(path_, ec);
        }
    }
    TempFile(const TempFile&) = delete;
    TempFile& operator=(const TempFile&) = delete;
    const std::string& path() const { return path_; }
    void release() { path_.clear(); }

private:
    std::string path_;
};

// OpenMesh's I/O is a process-wide singleton with global message streams; all our
// calls into it are serialised.
std::mutex& openMeshMutex() {
    static std::mutex m;
    return m;
}

// Silences OpenMesh's omerr/omlog message streams for the lifetime of the object
// (restoring their previous state), so a failed read does not spill reader messages
// onto stderr next to our own one-line error. (Capturing the text instead would need
// mostream::disconnect(), which leaks the target it removes.) Hold openMeshMutex().
class OpenMeshQuiet {
public:
    OpenMeshQuiet() : errWasEnabled_(::omerr().is_enabled()), logWasEnabled_(::omlog().is_enabled()) {
        ::omerr().disable();
        ::omlog().disable();
    }
    ~OpenMeshQuiet() {
        ::omerr().flush();
        ::omlog().flush();
        if (errWasEnabled_) ::omerr().enable();
        if (logWasEnabled_) ::omlog().enable();
    }
    OpenMeshQuiet(const OpenMeshQuiet&) = delete;
    OpenMeshQuiet& operator=(const OpenMeshQuiet&) = delete;

private:
    bool errWasEnabled_;
    bool logWasEnabled_;
};

// ---- pre-scan of the file bytes -----------------------------------------------------
// OpenMesh's text readers parse numbers with iostreams, which stop at "nan"/"inf" and
// then silently skip the vertex (OBJ) or read zeros for the rest of the file (PLY,
// OFF). The pre-scan checks every vertex coordinate of the text formats itself (with a
// line number in the message) and learns the record counts the file declares, so that
// truncation and faces the reader drops on its own can be detected.

struct ScanResult {
    std::optional<size_t> vertices;  // vertex records the reader must produce
    std::optional<size_t> faces;     // face records in the file
    bool readerDropsDegenerate = false;  // reader silently skips faces with < 3 distinct corners
};

bool isSpace(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\n' || c == '\f' || c == '\v'; }

// Walks whitespace-separated tokens, tracking line numbers.
class Tokens {
public:
    Tokens(std::string_view data, size_t offset, size_t firstLine)
        : data_(data), pos_(offset), line_(firstLine) {}

    bool next(std::string_view& token) {
        while (pos_ < data_.size() && isSpace(data_[pos_])) {
            if (data_[pos_] == '\n') ++line_;
            ++pos_;
        }
        if (pos_ >= data_.size()) return false;
        const size_t b = pos_;
        while (pos_ < data_.size() && !isSpace(data_[pos_])) ++pos_;
        token = data_.substr(b, pos_ - b);
        return true;
    }
    void skipLine() {
        while (pos_ < data_.size() && data_[pos_] != '\n') ++pos_;
    }
    size_t line() const { return line_; }
    size_t offset() const { return pos_; }

private:
    std::string_view data_;
    size_t pos_;
    size_t line_;
};

// Splits a buffer into lines (without the newline), numbering them from 1.
class Lines {
public:
    explicit Lines(std::string_view data) : data_(data) {}
    bool next(std::string_view& line) {
        if (pos_ >= data_.size()) return false;
        size_t e = data_.find('\n', pos_);
        if (e == std::string_view::npos) e = data_.size();
        line = data_.substr(pos_, e - pos_);
        pos_ = e + 1;
        ++number_;
        return true;
    }
    size_t number() const { return number_; }
    size_t offset() const { return pos_; }

private:
    std::string_view data_;
    size_t pos_ = 0;
    size_t number_ = 0;
};

std::vector<std::string_view> split(std::string_view line) {
    std::vector<std::string_view> out;
    size_t i = 0;
    while (i < line.size()) {
        while (i < line.size() && isSpace(line[i])) ++i;
        const size_t b = i;
        while (i < line.size() && !isSpace(line[i])) ++i;
        if (i > b) out.push_back(line.substr(b, i - b));
    }
    return out;
}

std::string shown(std::string_view token) {
    std::string s(token.substr(0, 40));
    return "'" + s + (token.size() > 40 ? "...'" : "'");
}

// The number `token` as a double, or throws naming the line and `what` (`hint` appended
// to the overflow and non-finite messages) unless it parses and is finite. Underflow (a
// tiny number) is fine.
double parseFiniteToken(const std::string& path, size_t line, std::string_view token, const char* what,
                        const char* hint = "") {
    std::string_view t = token;
    if (!t.empty() && t.front() == '+') t.remove_prefix(1);
    double value = 0.0;
    const auto [end, ec] = std::from_chars(t.data(), t.data() + t.size(), value);
    const std::string where = "line " + std::to_string(line) + ": ";
    if (ec == std::errc::invalid_argument || end != t.data() + t.size())
        throw Error(path, where + "cannot parse " + what + " " + shown(token));
    if (ec == std::errc::result_out_of_range) {
        const double v = std::strtod(std::string(t).c_str(), nullptr);
        if (std::isinf(v)) throw Error(path, where + what + " " + shown(token) + " overflows" + hint);
        return v;
    }
    if (!std::isfinite(value)) throw Error(path, where + "non-finite " + what + " " + shown(token) + hint);
    return value;
}

// Throws unless token is a finite number.
void checkCoordinate(const std::string& path, size_t line, std::string_view token) {
    parseFiniteToken(path, line, token, "vertex coordinate", " (NaN/Inf coordinates are not allowed)");
}

bool parseCount(std::string_view token, size_t& out) {
    const auto [end, ec] = std::from_chars(token.data(), token.data() + token.size(), out);
    return ec == std::errc() && end == token.data() + token.size();
}

// An optionally signed, non-zero integer: an OBJ index (1-based, or negative = relative).
bool objIndexIsValid(std::string_view t) {
    if (!t.empty() && (t.front() == '-' || t.front() == '+')) t.remove_prefix(1);
    if (t.empty() || t.size() > 10) return false;
    bool nonZero = false;
    for (char c : t) {
        if (c < '0' || c > '9') return false;
        nonZero = nonZero || c != '0';
    }
    return nonZero;
}

// V, V/, V/T, V//N, V/T/N (V/ is not in the specification but common and harmless).
bool objCornerIsValid(std::string_view corner) {
    const size_t a = corner.find('/');
    if (!objIndexIsValid(corner.substr(0, a))) return false;
    if (a == std::string_view::npos) return true;
    const std::string_view rest = corner.substr(a + 1);
    const size_t b = rest.find('/');
    const std::string_view t = rest.substr(0, b);
    if (!t.empty() && !objIndexIsValid(t)) return false;
    if (b == std::string_view::npos) return true;
    const std::string_view n = rest.substr(b + 1);
    return !n.empty() && objIndexIsValid(n) && n.find('/') == std::string_view::npos;
}

// What the OBJ pre-scan collects for loadMeshSurface: per face record that OpenMesh
// keeps (three or more distinct vertices), its corners after OpenMesh's removal of
// repeated vertices (the first occurrence stays), each with its vertex, texture
// coordinate and normal (0-based; -1 for none), and the material named by the last
// usemtl before it.
struct ObjSurfaceScan {
    std::vector<glm::vec2> texcoords;  // vt records, (u, v)
    std::vector<glm::vec3> normals;    // vn records
    std::vector<int> cornerVertex, cornerTexcoord, cornerNormal;
    std::vector<size_t> faceStart{0};  // record r: corners [faceStart[r], faceStart[r + 1])
    std::vector<uint32_t> faceMaterial;     // index into materialNames, or kNoMaterial
    std::vector<std::string> materialNames; // usemtl names in order of first use
    std::vector<std::string> libraries;     // mtllib file names, as written
    static constexpr uint32_t kNoMaterial = 0xffffffffu;
};

// A finite float, or throws naming the line and what it is.
float parseFiniteValue(const std::string& path, size_t line, std::string_view token, const char* what) {
    const double value = parseFiniteToken(path, line, token, what);
    if (!std::isfinite(float(value)))
        throw Error(path, "line " + std::to_string(line) + ": non-finite " + what + " " + shown(token));
    return float(value);
}

// An OBJ index (1-based or negative = relative to the `count` records so far) as a
// 0-based index; throws when it falls outside [0, count).
int resolveObjIndex(const std::string& path, size_t line, std::string_view token, size_t count, const char* what) {
    long long value = 0;
    std::string_view t = token;
    if (!t.empty() && t.front() == '+') t.remove_prefix(1);
    std::from_chars(t.data(), t.data() + t.size(), value);  // objCornerIsValid checked the syntax
    const long long resolved = value < 0 ? (long long)count + value : value - 1;
    if (resolved < 0 || resolved >= (long long)count)
        throw Error(path, "line " + std::to_string(line) + ": " + what + " index " + shown(token) +
                              " is out of range (" + std::to_string(count) + " " + what + "s so far)");
    return int(resolved);
}

ScanResult scanObj(const std::string& path, std::string_view data, ObjSurfaceScan* surface) {
    ScanResult r;
    r.readerDropsDegenerate = true;
    size_t v = 0, f = 0;
    uint32_t material = ObjSurfaceScan::kNoMaterial;
    Lines lines(data);
    std::string_view line;
    while (lines.next(line)) {
        const auto tok = split(line);
        if (tok.empty() || tok[0].front() == '#') continue;
        if (tok[0] == "v") {
            if (tok.size() < 4)
                throw Error(path, "line " + std::to_string(lines.number()) +
                                      ": vertex needs three coordinates");
            for (int k = 1; k <= 3; ++k) checkCoordinate(path, lines.number(), tok[size_t(k)]);
            ++v;
        } else if (tok[0] == "f") {
            // OpenMesh 9.0 aborts (an assertion) on a face whose corners all lack a
            // vertex index ("f /1 /2 /3"; tools/fuzz/crashes/mesh/): each corner must be
            // V, V/T, V//N or V/T/N with non-zero integers, V required.
            if (tok.size() < 2)
                throw Error(path, "line " + std::to_string(lines.number()) + ": face without corners");
            for (size_t k = 1; k < tok.size(); ++k)
                if (!objCornerIsValid(tok[k]))
                    throw Error(path, "line " + std::to_string(lines.number()) + ": malformed face corner " +
                                          shown(tok[k]) + " (expected V, V/T, V//N or V/T/N, indices from 1 or negative)");
            ++f;
            if (surface) {
                // The corners OpenMesh keeps: repeated vertices removed, first occurrence
                // stays; a record of fewer than three distinct vertices is not a face.
                const size_t begin = surface->cornerVertex.size();
                for (size_t k = 1; k < tok.size(); ++k) {
                    const std::string_view c = tok[k];
                    const size_t a = c.find('/');
                    const int vi = resolveObjIndex(path, lines.number(), c.substr(0, a), v, "vertex");
                    int ti = -1, ni = -1;
                    if (a != std::string_view::npos) {
                        const std::string_view rest = c.substr(a + 1);
                        const size_t b = rest.find('/');
                        if (!rest.substr(0, b).empty())
                            ti = resolveObjIndex(path, lines.number(), rest.substr(0, b), surface->texcoords.size(),
                                                 "texture coordinate");
                        if (b != std::string_view::npos)
                            ni = resolveObjIndex(path, lines.number(), rest.substr(b + 1), surface->normals.size(),
                                                 "normal");
                    }
                    bool repeated = false;
                    for (size_t j = begin; j < surface->cornerVertex.size() && !repeated; ++j)
                        repeated = surface->cornerVertex[j] == vi;
                    if (repeated) continue;
                    surface->cornerVertex.push_back(vi);
                    surface->cornerTexcoord.push_back(ti);
                    surface->cornerNormal.push_back(ni);
                }
                if (surface->cornerVertex.size() - begin < 3) {
                    surface->cornerVertex.resize(begin);
                    surface->cornerTexcoord.resize(begin);
                    surface->cornerNormal.resize(begin);
                } else {
                    surface->faceStart.push_back(surface->cornerVertex.size());
                    surface->faceMaterial.push_back(material);
                }
            }
        } else if (surface && tok[0] == "vt") {
            if (tok.size() < 2)
                throw Error(path, "line " + std::to_string(lines.number()) + ": texture coordinate needs u (and v)");
            glm::vec2 uv(0.0f);
            for (size_t k = 1; k <= std::min<size_t>(2, tok.size() - 1); ++k)
                uv[int(k - 1)] = parseFiniteValue(path, lines.number(), tok[k], "texture coordinate");
            surface->texcoords.push_back(uv);
        } else if (surface && tok[0] == "vn") {
            if (tok.size() < 4)
                throw Error(path, "line " + std::to_string(lines.number()) + ": normal needs three components");
            glm::vec3 n;
            for (int k = 0; k < 3; ++k) n[k] = parseFiniteValue(path, lines.number(), tok[size_t(k + 1)], "normal");
            surface->normals.push_back(n);
        } else if (surface && tok[0] == "usemtl") {
            // The name is the rest of the line (names may hold spaces).
            const std::string name(trim(std::string(line.substr(line.find("usemtl") + 6))));
            auto it = std::find(surface->materialNames.begin(), surface->materialNames.end(), name);
            material = uint32_t(it - surface->materialNames.begin());
            if (it == surface->materialNames.end()) surface->materialNames.push_back(name);
        } else if (surface && tok[0] == "mtllib") {
            for (size_t k = 1; k < tok.size(); ++k) surface->libraries.emplace_back(tok[k]);
        }
    }
    r.vertices = v;
    r.faces = f;
    return r;
}

struct PlyProperty {
    std::string name;
    bool list = false;
};
struct PlyElement {
    std::string name;
    size_t count = 0;
    std::vector<PlyProperty> properties;
};

// Bytes of a PLY scalar type, 0 for an unknown name.
size_t plyTypeBytes(std::string_view type) {
    static const std::pair<std::string_view, size_t> kTypes[] = {
        {"char", 1},  {"uchar", 1},  {"int8", 1},   {"uint8", 1},   {"short", 2},  {"ushort", 2},
        {"int16", 2}, {"uint16", 2}, {"int", 4},    {"uint", 4},    {"int32", 4},  {"uint32", 4},
        {"float", 4}, {"float32", 4}, {"double", 8}, {"float64", 8}};
    for (const auto& [name, bytes] : kTypes)
        if (type == name) return bytes;
    return 0;
}

// The header is checked strictly, line by line, before OpenMesh sees the file: OpenMesh
// 9.0's reader loops forever on some malformed headers (tools/fuzz/crashes/mesh/), and
// reserves memory for whatever counts the header claims.
ScanResult scanPly(const std::string& path, std::string_view data) {
    Lines lines(data);
    std::string_view line;
    if (!lines.next(line) || split(line).size() != 1 || split(line)[0] != "ply")
        throw Error(path, "not a PLY file (it does not start with 'ply')");
    bool ascii = false, sawFormat = false, sawEnd = false;
    std::vector<PlyElement> elements;
    std::vector<size_t> minRecordBytes;  // per element: the fewest bytes one record can take
    while (lines.next(line)) {
        const auto tok = split(line);
        if (tok.empty()) continue;
        const std::string where = "PLY header line " + std::to_string(lines.number()) + ": ";
        if (tok[0] == "end_header") {
            if (tok.size() != 1) throw Error(path, where + "malformed end_header line");
            sawEnd = true;
            break;
        }
        if (tok[0] == "comment" || tok[0] == "obj_info") continue;
        if (tok[0] == "format") {
            if (tok.size() != 3 || tok[2] != "1.0")
                throw Error(path, where + "malformed format line (expected 'format <ascii|binary_little_endian|"
                                          "binary_big_endian> 1.0')");
            if (sawFormat) throw Error(path, where + "a second format line");
            sawFormat = true;
            ascii = tok[1] == "ascii";
            if (!ascii && tok[1] != "binary_little_endian" && tok[1] != "binary_big_endian")
                throw Error(path, where + "unknown format " + shown(tok[1]));
        } else if (tok[0] == "element") {
            PlyElement e;
            if (tok.size() != 3 || !parseCount(tok[2], e.count))
                throw Error(path, where + "malformed element line (expected 'element <name> <count>')");
            e.name = std::string(tok[1]);
            elements.push_back(std::move(e));
            minRecordBytes.push_back(0);
        } else if (tok[0] == "property") {
            if (elements.empty()) throw Error(path, where + "property before any element");
            PlyProperty p;
            p.list = tok.size() > 1 && tok[1] == "list";
            if (tok.size() != (p.list ? 5u : 3u))
                throw Error(path, where + "malformed property line (expected 'property <type> <name>' or "
                                          "'property list <count type> <index type> <name>')");
            const size_t bytes = plyTypeBytes(tok[p.list ? 2 : 1]);
            if (bytes == 0 || (p.list && plyTypeBytes(tok[3]) == 0))
                throw Error(path, where + "unknown property type " + shown(p.list && bytes ? tok[3] : tok[p.list ? 2 : 1]));
            minRecordBytes.back() += bytes;
            p.name = std::string(tok.back());
            elements.back().properties.push_back(std::move(p));
        } else {
            throw Error(path, where + "unknown header keyword " + shown(tok[0]));
        }
    }
    if (!sawFormat || !sawEnd) throw Error(path, "malformed PLY header (no format or end_header)");

    // Every record of an element takes at least a byte per property (ascii: a digit
    // and a separator), so the counts cannot exceed what the body could hold.
    const size_t body = data.size() - std::min(data.size(), lines.offset());
    for (size_t i = 0; i < elements.size(); ++i) {
        const size_t perRecord = ascii ? 2 * elements[i].properties.size() : minRecordBytes[i];
        if (perRecord > 0 && elements[i].count > (body + 1) / perRecord)
            throw Error(path, "the header declares " + std::to_string(elements[i].count) + " " + elements[i].name +
                                  " records, more than the " + std::to_string(body) +
                                  " bytes after the header can hold (truncated or corrupt)");
    }

    ScanResult r;
    size_t vertexCount = 0, faceCount = 0;
    for (const auto& e : elements) {
        if (e.name == "vertex") vertexCount = e.count;
        if (e.name == "face") faceCount = e.count;
    }
    r.vertices = vertexCount;
    r.faces = faceCount;
    if (!ascii) return r;

    // ASCII body: walk every element, so that a list never claims more entries than
    // the file holds (OpenMesh would keep appending).
    Tokens tokens(data, lines.offset(), lines.number() + 1);
    std::string_view token;
    for (const auto& e : elements) {
        const bool isVertex = e.name == "vertex";
        for (size_t i = 0; i < e.count; ++i)
            for (const auto& p : e.properties) {
                auto need = [&]() {
                    if (!tokens.next(token))
                        throw Error(path, "file ends inside " + e.name + " " + std::to_string(i) +
                                              " of " + std::to_string(e.count) + " (truncated)");
                };
                need();
                if (p.list) {
                    size_t n = 0;
                    if (!parseCount(token, n))
                        throw Error(path, "line " + std::to_string(tokens.line()) +
                                              ": cannot parse list length " + shown(token));
                    for (size_t k = 0; k < n; ++k) need();
                } else if (isVertex && (p.name == "x" || p.name == "y" || p.name == "z")) {
                    checkCoordinate(path, tokens.line(), token);
                }
            }
    }
    return r;
}

ScanResult scanOff(const std::string& path, std::string_view data) {
    ScanResult r;
    Lines lines(data);
    std::string_view header;
    lines.next(header);
    const auto head = split(header);
    if (head.empty() || head[0].find("OFF") == std::string_view::npos)
        throw Error(path, "not an OFF file (the first line has no 'OFF' keyword)");
    // OpenMesh reads the letters around OFF as options (C colours, N normals, ST texture
    // coordinates, 4 homogeneous, n dimension) and then reads the records differently
    // from the pre-scan below (a header 'OFF\x0414M' makes it loop: tools/fuzz/crashes/mesh/).
    if (head[0] != "OFF")
        throw Error(path, "unsupported OFF header " + shown(head[0]) +
                              " (plain OFF only: no colour, normal, texture, 4D or nOFF variants)");
    const bool binary = head.size() > 1 && head[1] == "BINARY";
    if (!binary && head.size() > 1)
        throw Error(path, "counts on the OFF header line are not supported; put them on the next line");
    if (binary) {
        const size_t at = lines.offset();
        if (data.size() < at + 12) throw Error(path, "binary OFF file ends inside its counts");
        uint32_t counts[2];
        std::memcpy(counts, data.data() + at, sizeof counts);
        // A vertex takes 12 bytes, a face at least its 4-byte corner count.
        if (12 * uint64_t(counts[0]) + 4 * uint64_t(counts[1]) > data.size() - at - 12)
            throw Error(path, "the header declares " + std::to_string(counts[0]) + " vertices and " +
                                  std::to_string(counts[1]) + " faces, more than the file can hold (truncated or corrupt)");
        r.vertices = counts[0];
        r.faces = counts[1];
        return r;
    }
    Tokens tokens(data, lines.offset(), 2);
    std::string_view token;
    size_t counts[3] = {0, 0, 0};
    size_t countsLine = 0;
    for (size_t& c : counts) {
        if (!tokens.next(token) || !parseCount(token, c))
            throw Error(path, "line " + std::to_string(tokens.line()) +
                                  ": expected the vertex, face and edge counts (comments "
                                  "before the counts are not supported)");
        if (countsLine == 0) countsLine = tokens.line();
        if (tokens.line() != countsLine)
            throw Error(path, "line " + std::to_string(countsLine) +
                                  ": the vertex, face and edge counts must be on one line");
    }
    // OpenMesh reads on from the third count: anything after it on the line would be
    // read as the first vertex's x, every record after out of step (a face of
    // -8 = 2^32 - 8 corners exhausts memory: tools/fuzz/crashes/mesh/).
    const size_t afterCounts = tokens.offset();
    tokens.skipLine();
    for (size_t i = afterCounts; i < tokens.offset(); ++i)
        if (!isSpace(data[i]))
            throw Error(path, "line " + std::to_string(countsLine) +
                                  ": more than the vertex, face and edge counts on the counts line");
    // The body line by line: one vertex per line (x y z, nothing else), one face per
    // line (its corner count, then that many indices, then optional colours, which
    // OpenMesh 9.0 reads with the rest of the line). Anything else reaches OpenMesh's
    // stream reader out of step and it loops forever (a face index '1p':
    // tools/fuzz/crashes/mesh/).
    Lines body(data.substr(std::min(data.size(), tokens.offset())));
    const size_t firstBodyLine = tokens.line();
    std::string_view line;
    auto nextRecord = [&](std::vector<std::string_view>& fields) {
        while (body.next(line)) {
            fields = split(line);
            if (!fields.empty()) return true;  // blank lines are skipped; OpenMesh misreads comments
        }
        return false;
    };
    auto at = [&] { return "line " + std::to_string(firstBodyLine + body.number() - 1) + ": "; };
    std::vector<std::string_view> fields;
    for (size_t i = 0; i < counts[0]; ++i) {
        if (!nextRecord(fields))
            throw Error(path, "file ends before vertex " + std::to_string(i) + " of " + std::to_string(counts[0]) +
                                  " (truncated)");
        if (fields.size() < 3)
            throw Error(path, at() + "vertex " + std::to_string(i) + " has " + std::to_string(fields.size()) +
                                  " coordinates, expected x y z on one line");
        // Plain OFF: OpenMesh reads x y z and goes on with the next number, so a fourth
        // one on the line would start the next record and put every later one out of
        // step (a coordinate read as a face's corner count exhausts memory:
        // tools/fuzz/crashes/mesh/openmesh-off-vertex-extra-value-oom).
        if (fields.size() > 3)
            throw Error(path, at() + "vertex " + std::to_string(i) + " has " + std::to_string(fields.size()) +
                                  " values, expected x y z only (plain OFF: no colours or normals)");
        for (int k = 0; k < 3; ++k) checkCoordinate(path, firstBodyLine + body.number() - 1, fields[size_t(k)]);
    }
    for (size_t i = 0; i < counts[1]; ++i) {
        if (!nextRecord(fields))
            throw Error(path, "file ends before face " + std::to_string(i) + " of " + std::to_string(counts[1]) +
                                  " (truncated)");
        size_t corners = 0;
        if (!parseCount(fields[0], corners))
            throw Error(path, at() + "cannot parse the corner count " + shown(fields[0]) + " of face " +
                                  std::to_string(i));
        // OpenMesh reads the numbers after a face of no corners as the next face
        // (tools/fuzz/crashes/mesh/); faces of one or two corners are not surfaces either.
        if (corners < 3)
            throw Error(path, at() + "face " + std::to_string(i) + " has " + std::to_string(corners) +
                                  " corners (a face needs at least 3)");
        if (fields.size() < corners + 1)
            throw Error(path, at() + "face " + std::to_string(i) + " declares " + std::to_string(corners) +
                                  " corners but lists " + std::to_string(fields.size() - 1) +
                                  " indices on its line (truncated or corrupt)");
        for (size_t k = 1; k <= corners; ++k) {
            size_t index = 0;
            if (!parseCount(fields[k], index))
                throw Error(path, at() + "cannot parse vertex index " + shown(fields[k]) + " of face " +
                                      std::to_string(i));
            if (index >= counts[0])
                throw Error(path, at() + "face " + std::to_string(i) + " refers to vertex " + std::to_string(index) +
                                      " but the file has " + std::to_string(counts[0]) + " vertices");
        }
    }
    r.vertices = counts[0];
    r.faces = counts[1];
    return r;
}

bool stlIsBinary(std::string_view data) {
    if (data.size() < 84) return false;
    uint32_t n = 0;
    std::memcpy(&n, data.data() + 80, 4);
    return 84 + uint64_t(n) * 50 == data.size();
}

ScanResult scanStl(const std::string& path, std::string_view data) {
    ScanResult r;
    r.readerDropsDegenerate = true;  // and it merges identical corners
    if (stlIsBinary(data)) {
        uint32_t n = 0;
        std::memcpy(&n, data.data() + 80, 4);
        r.faces = n;
        return r;
    }
    // ASCII: like OpenMesh, a line containing "outer" starts a triangle whose three
    // vertices are the next three lines.
    size_t faces = 0;
    Lines lines(data);
    std::string_view line;
    while (lines.next(line)) {
        if (line.find("outer") == std::string_view::npos && line.find("OUTER") == std::string_view::npos)
            continue;
        ++faces;
        for (int k = 0; k < 3; ++k) {
            if (!lines.next(line))
                throw Error(path, "file ends inside facet " + std::to_string(faces) + " (truncated)");
            const auto tok = split(line);
            if (tok.size() < 4)
                throw Error(path, "line " + std::to_string(lines.number()) +
                                      ": expected 'vertex x y z'");
            for (int c = 1; c <= 3; ++c) checkCoordinate(path, lines.number(), tok[size_t(c)]);
        }
    }
    r.faces = faces;
    return r;
}

ScanResult scan(Format format, const std::string& path, std::string_view data, ObjSurfaceScan* objSurface) {
    switch (format) {
        case Format::Obj: return scanObj(path, data, objSurface);
        case Format::Ply: return scanPly(path, data);
        case Format::Off: return scanOff(path, data);
        case Format::Stl: return scanStl(path, data);
        case Format::Gltf:
        case Format::Glb: return {};  // checked by readGltf
    }
    return {};
}

// ---- OpenMesh importer collecting a polygon soup ------------------------------------

struct Soup {
    std::vector<glm::vec3> positions;
    std::vector<int> corners;          // vertex indices as the reader gave them
    std::vector<size_t> faceStart{0};  // face f is corners[faceStart[f], faceStart[f + 1])
    size_t faceCount() const { return faceStart.size() - 1; }
    // For loadMeshSurface only: per corner (parallel to corners; empty when the file has
    // none) and per face.
    std::vector<glm::vec2> cornerUv;
    std::vector<glm::vec3> cornerNormal;
    std::vector<uint32_t> faceMaterial;
};

// Receives vertices and faces from any OpenMesh reader without building a halfedge
// structure, so nothing the file contains is refused (non-manifold edges, repeated
// corners) and the vertex order is exactly the reader's.
class SoupImporter : public OpenMesh::IO::BaseImporter {
public:
    SoupImporter(Soup& soup, size_t reserveLimit) : soup_(soup), reserveLimit_(reserveLimit) {}

    OpenMesh::VertexHandle add_vertex(const OpenMesh::Vec3f& p) override {
        soup_.positions.emplace_back(p[0], p[1], p[2]);
        return OpenMesh::VertexHandle(int(soup_.positions.size() - 1));
    }
    OpenMesh::VertexHandle add_vertex(const OpenMesh::Vec3d& p) override {
        soup_.positions.emplace_back(float(p[0]), float(p[1]), float(p[2]));
        return OpenMesh::VertexHandle(int(soup_.positions.size() - 1));
    }
    OpenMesh::VertexHandle add_vertex() override {
        soup_.positions.emplace_back(0.0f);
        return OpenMesh::VertexHandle(int(soup_.positions.size() - 1));
    }
    void set_point(OpenMesh::VertexHandle vh, const OpenMesh::Vec3f& p) override {
        if (vh.is_valid() && size_t(vh.idx()) < soup_.positions.size())
            soup_.positions[size_t(vh.idx())] = glm::vec3(p[0], p[1], p[2]);
    }
    OpenMesh::FaceHandle add_face(const VHandles& corners) override {
        for (const auto& vh : corners) soup_.corners.push_back(vh.idx());
        soup_.faceStart.push_back(soup_.corners.size());
        return OpenMesh::FaceHandle(int(soup_.faceCount() - 1));
    }
    size_t n_vertices() const override { return soup_.positions.size(); }
    size_t n_faces() const override { return soup_.faceCount(); }
    size_t n_edges() const override { return 0; }
    void reserve(unsigned int nV, unsigned int, unsigned int nF) override {
        soup_.positions.reserve(std::min<size_t>(nV, reserveLimit_));
        soup_.faceStart.reserve(std::min<size_t>(size_t(nF) + 1, reserveLimit_));
        soup_.corners.reserve(std::min<size_t>(size_t(nF) * 3, reserveLimit_));
    }

    // Everything else a reader may hand over is ignored.
    OpenMesh::HalfedgeHandle add_edge(OpenMesh::VertexHandle, OpenMesh::VertexHandle) override {
        return OpenMesh::HalfedgeHandle();
    }
    OpenMesh::FaceHandle add_face(OpenMesh::HalfedgeHandle) override { return OpenMesh::FaceHandle(); }
    void add_face_texcoords(OpenMesh::FaceHandle, OpenMesh::VertexHandle,
                            const std::vector<OpenMesh::Vec2f>&) override {}
    void add_face_texcoords(OpenMesh::FaceHandle, OpenMesh::VertexHandle,
                            const std::vector<OpenMesh::Vec3f>&) override {}
    void set_face_texindex(OpenMesh::FaceHandle, int) override {}
    void set_halfedge(OpenMesh::VertexHandle, OpenMesh::HalfedgeHandle) override {}
    void set_normal(OpenMesh::VertexHandle, const OpenMesh::Vec3f&) override {}
    void set_normal(OpenMesh::VertexHandle, const OpenMesh::Vec3d&) override {}
    void set_color(OpenMesh::VertexHandle, const OpenMesh::Vec3uc&) override {}
    void set_color(OpenMesh::VertexHandle, const OpenMesh::Vec4uc&) override {}
    void set_color(OpenMesh::VertexHandle, const OpenMesh::Vec3f&) override {}
    void set_color(OpenMesh::VertexHandle, const OpenMesh::Vec4f&) override {}
    void set_texcoord(OpenMesh::VertexHandle, const OpenMesh::Vec2f&) override {}
    void set_status(OpenMesh::VertexHandle, const OpenMesh::Attributes::StatusInfo&) override {}
    void set_next(OpenMesh::HalfedgeHandle, OpenMesh::HalfedgeHandle) override {}
    void set_face(OpenMesh::HalfedgeHandle, OpenMesh::FaceHandle) override {}
    void request_face_texcoords2D() override {}
    void set_texcoord(OpenMesh::HalfedgeHandle, const OpenMesh::Vec2f&) override {}
    void set_texcoord(OpenMesh::VertexHandle, const OpenMesh::Vec3f&) override {}
    void set_texcoord(OpenMesh::HalfedgeHandle, const OpenMesh::Vec3f&) override {}
    void set_status(OpenMesh::HalfedgeHandle, const OpenMesh::Attributes::StatusInfo&) override {}
    void set_color(OpenMesh::EdgeHandle, const OpenMesh::Vec3uc&) override {}
    void set_color(OpenMesh::EdgeHandle, const OpenMesh::Vec4uc&) override {}
    void set_color(OpenMesh::EdgeHandle, const OpenMesh::Vec3f&) override {}
    void set_color(OpenMesh::EdgeHandle, const OpenMesh::Vec4f&) override {}
    void set_status(OpenMesh::EdgeHandle, const OpenMesh::Attributes::StatusInfo&) override {}
    void set_normal(OpenMesh::FaceHandle, const OpenMesh::Vec3f&) override {}
    void set_normal(OpenMesh::FaceHandle, const OpenMesh::Vec3d&) override {}
    void set_color(OpenMesh::FaceHandle, const OpenMesh::Vec3uc&) override {}
    void set_color(OpenMesh::FaceHandle, const OpenMesh::Vec4uc&) override {}
    void set_color(OpenMesh::FaceHandle, const OpenMesh::Vec3f&) override {}
    void set_color(OpenMesh::FaceHandle, const OpenMesh::Vec4f&) override {}
    void set_status(OpenMesh::FaceHandle, const OpenMesh::Attributes::StatusInfo&) override {}
    void add_texture_information(int, std::string) override {}

private:
    Soup& soup_;
    size_t reserveLimit_;
};

// ---- triangulation ------------------------------------------------------------------

// Splits polygon `poly` (vertex indices, >= 4 distinct consecutive corners) into
// triangles with the same orientation: ear clipping in the plane of the polygon's
// Newell normal; a fan when the polygon is huge, has no area, or clipping gets stuck.
// `out` receives each triangle as three positions in `poly` (0 .. poly.size() - 1), so
// that the caller can carry per-corner data along.
void triangulatePolygon(const std::vector<glm::vec3>& positions, const std::vector<uint32_t>& poly,
                        std::vector<glm::uvec3>& out) {
    const size_t n = poly.size();
    auto fan = [&](const std::vector<uint32_t>& p) {
        for (size_t i = 1; i + 1 < p.size(); ++i) out.emplace_back(p[0], p[i], p[i + 1]);
    };
    glm::dvec3 normal(0.0);
    for (size_t i = 0; i < n; ++i) {
        const glm::dvec3 a(positions[poly[i]]), b(positions[poly[(i + 1) % n]]);
        normal += glm::dvec3((a.y - b.y) * (a.z + b.z), (a.z - b.z) * (a.x + b.x), (a.x - b.x) * (a.y + b.y));
    }
    if (n > 256 || !(glm::length(normal) > 0.0)) {
        std::vector<uint32_t> all(n);
        for (size_t i = 0; i < n; ++i) all[i] = uint32_t(i);
        fan(all);
        return;
    }
    // Project onto the coordinate plane most perpendicular to the normal, flipping one
    // axis if needed so that the polygon runs counter-clockwise in 2D.
    int axis = 0;
    for (int a = 1; a < 3; ++a)
        if (std::abs(normal[a]) > std::abs(normal[axis])) axis = a;
    const int u = (axis + 1) % 3, v = (axis + 2) % 3;
    const double flip = normal[axis] > 0.0 ? 1.0 : -1.0;
    std::vector<glm::dvec2> q(n);
    for (size_t i = 0; i < n; ++i) q[i] = glm::dvec2(positions[poly[i]][u], flip * positions[poly[i]][v]);

    auto cross2 = [](glm::dvec2 a, glm::dvec2 b, glm::dvec2 c) {
        return (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x);
    };
    std::vector<size_t> ring(n);
    for (size_t i = 0; i < n; ++i) ring[i] = i;
    while (ring.size() > 3) {
        const size_t m = ring.size();
        bool clipped = false;
        for (size_t k = 0; k < m && !clipped; ++k) {
            const size_t ia = ring[(k + m - 1) % m], ib = ring[k], ic = ring[(k + 1) % m];
            if (!(cross2(q[ia], q[ib], q[ic]) > 0.0)) continue;  // reflex or flat corner
            bool inside = false;
            for (size_t j = 0; j < m && !inside; ++j) {
                const size_t ip = ring[j];
                if (ip == ia || ip == ib || ip == ic) continue;
                inside = cross2(q[ia], q[ib], q[ip]) >= 0.0 && cross2(q[ib], q[ic], q[ip]) >= 0.0 &&
                         cross2(q[ic], q[ia], q[ip]) >= 0.0;
            }
            if (inside) continue;
            out.emplace_back(uint32_t(ia), uint32_t(ib), uint32_t(ic));
            ring.erase(ring.begin() + std::ptrdiff_t(k));
            clipped = true;
        }
        if (!clipped) {
            std::vector<uint32_t> rest;
            for (size_t i : ring) rest.push_back(uint32_t(i));
            fan(rest);
            return;
        }
    }
    out.emplace_back(uint32_t(ring[0]), uint32_t(ring[1]), uint32_t(ring[2]));
}

std::string plural(size_t n, const char* one, const char* many) {
    return std::to_string(n) + " " + (n == 1 ? one : many);
}

// ---- glTF through Assimp -------------------------------------------------------------
// Assimp's glTF 2.0 importer silently drops triangles with an index out of range and
// reports broken JSON as "no suitable reader", so the JSON is checked first: the .glb
// container, the primitives' modes and the number of triangles they declare, which the
// triangles Assimp delivers must match.

const char* gltfModeName(int mode) {
    switch (mode) {
        case 0: return "POINTS";
        case 1: return "LINES";
        case 2: return "LINE_LOOP";
        case 3: return "LINE_STRIP";
        case 4: return "TRIANGLES";
        case 5: return "TRIANGLE_STRIP";
        case 6: return "TRIANGLE_FAN";
    }
    return "unknown";
}

uint32_t readLe32(std::string_view data, size_t at) {
    uint32_t v = 0;
    std::memcpy(&v, data.data() + at, 4);
    return v;
}

// The glTF JSON (a .glb's JSON chunk) checked for what Assimp would get wrong; returns
// the number of triangles the primitives declare.
size_t gltfPrecheck(const std::string& path, Format format, std::string_view data) {
    std::string_view jsonText = data;
    if (format == Format::Glb) {
        if (data.size() < 12 || data.substr(0, 4) != "glTF")
            throw Error(path, "not a binary glTF file (no 'glTF' magic)");
        const uint32_t version = readLe32(data, 4), length = readLe32(data, 8);
        if (version != 2) throw Error(path, "binary glTF version " + std::to_string(version) + " (only 2 is read)");
        if (length > data.size())
            throw Error(path, "truncated: the .glb header declares " + std::to_string(length) + " bytes but the file has " +
                                  std::to_string(data.size()));
        if (length < data.size())
            throw Error(path, "the .glb header declares " + std::to_string(length) + " bytes but the file has " +
                                  std::to_string(data.size()) + " (corrupt)");
        if (data.size() < 20) throw Error(path, "truncated: the .glb file ends before its JSON chunk");
        const uint32_t chunkLength = readLe32(data, 12);
        if (data.substr(16, 4) != "JSON") throw Error(path, "the first chunk of the .glb file is not JSON (corrupt)");
        if (uint64_t(chunkLength) > data.size() - 20)
            throw Error(path, "truncated: the .glb JSON chunk declares " + std::to_string(chunkLength) +
                                  " bytes, more than the file holds");
        jsonText = data.substr(20, chunkLength);
    }
    nlohmann::json doc;
    try {
        doc = nlohmann::json::parse(jsonText.begin(), jsonText.end());
    } catch (const nlohmann::json::exception& e) {
        std::string what = e.what();
        const size_t bracket = what.find("] ");
        if (what.rfind("[json.exception", 0) == 0 && bracket != std::string::npos) what = what.substr(bracket + 2);
        throw Error(path, "invalid glTF JSON: " + oneLine(what));
    }
    if (!doc.is_object()) throw Error(path, "invalid glTF: the JSON is not an object");
    const auto asset = doc.find("asset");
    if (asset == doc.end() || !asset->is_object() || !asset->contains("version") || !(*asset)["version"].is_string())
        throw Error(path, "invalid glTF: no asset.version");
    const std::string version = (*asset)["version"].get<std::string>();
    if (version.rfind("2.", 0) != 0) throw Error(path, "glTF version " + version + " (only 2.x is read)");

    const nlohmann::json accessors = doc.value("accessors", nlohmann::json::array());
    auto accessorCount = [&](const nlohmann::json& ref, const std::string& where) -> size_t {
        if (!ref.is_number_unsigned() || ref.get<size_t>() >= accessors.size())
            throw Error(path, where + " refers to accessor " + ref.dump() + " but the file has " +
                                  std::to_string(accessors.size()));
        const auto& a = accessors[ref.get<size_t>()];
        if (!a.is_object() || !a.contains("count") || !a["count"].is_number_unsigned())
            throw Error(path, "accessor " + ref.dump() + " has no valid count");
        return a["count"].get<size_t>();
    };
    size_t triangles = 0;
    const nlohmann::json meshes = doc.value("meshes", nlohmann::json::array());
    if (!meshes.is_array()) throw Error(path, "invalid glTF: meshes is not an array");
    for (size_t m = 0; m < meshes.size(); ++m) {
        const auto& prims = meshes[m].is_object() ? meshes[m].value("primitives", nlohmann::json::array())
                                                  : nlohmann::json::array();
        for (size_t p = 0; p < prims.size(); ++p) {
            const std::string where = "mesh " + std::to_string(m) + " primitive " + std::to_string(p);
            const auto& prim = prims[p];
            if (!prim.is_object()) throw Error(path, where + " is not an object");
            const nlohmann::json modeValue = prim.value("mode", nlohmann::json(4));
            const int mode = modeValue.is_number_integer() ? modeValue.get<int>() : -1;
            if (mode < 0 || mode > 6) throw Error(path, where + " has unknown mode " + modeValue.dump());
            if (mode < 4)
                throw Error(path, where + " is " + gltfModeName(mode) + " (mode " + std::to_string(mode) +
                                      "): only triangle primitives are read");
            const auto attributes = prim.find("attributes");
            if (attributes == prim.end() || !attributes->is_object() || !attributes->contains("POSITION"))
                throw Error(path, where + " has no POSITION attribute");
            const size_t count = prim.contains("indices") ? accessorCount(prim["indices"], where + "'s indices")
                                                          : accessorCount((*attributes)["POSITION"], where);
            if (mode == 4) {
                if (count % 3 != 0)
                    throw Error(path, where + " has " + std::to_string(count) +
                                          " indices, not a multiple of 3 (TRIANGLES)");
                triangles += count / 3;
            } else {
                triangles += count >= 3 ? count - 2 : 0;
            }
        }
    }
    // Assimp 5.2 reads past a media type without '/' (a crash): an image's mimeType, and
    // the media type of a data URI (images and buffers).
    auto mediaTypeIsValid = [](const std::string& text) {
        const size_t slash = text.find('/');
        return slash != std::string::npos && slash > 0 && slash + 1 < text.size();
    };
    for (const char* kind : {"images", "buffers"}) {
        const nlohmann::json items = doc.value(kind, nlohmann::json::array());
        for (size_t i = 0; items.is_array() && i < items.size(); ++i) {
            if (!items[i].is_object()) continue;
            const std::string what = std::string(kind).substr(0, std::strlen(kind) - 1) + " " + std::to_string(i);
            if (items[i].contains("mimeType")) {
                const auto& mime = items[i]["mimeType"];
                if (!mime.is_string() || !mediaTypeIsValid(mime.get<std::string>()))
                    throw Error(path, what + " has an invalid mimeType " + mime.dump().substr(0, 40));
            }
            if (items[i].contains("uri")) {
                const auto& uri = items[i]["uri"];
                if (!uri.is_string()) throw Error(path, what + " has a uri that is not a string");
                const std::string text = uri.get<std::string>();
                if (text.rfind("data:", 0) == 0) {
                    const std::string media = text.substr(5, text.find_first_of(";,") - 5);
                    if (!mediaTypeIsValid(media) || text.find(',') == std::string::npos)
                        throw Error(path, what + " has a malformed data URI");
                }
            }
        }
    }
    if (triangles == 0)
        throw Error(path, meshes.empty() ? "contains no meshes (empty mesh)"
                                         : "its primitives hold no triangles (empty mesh)");
    return triangles;
}

TextureWrap wrapOf(int mode) {
    switch (mode) {
        case aiTextureMapMode_Clamp: return TextureWrap::ClampToEdge;
        case aiTextureMapMode_Mirror: return TextureWrap::MirroredRepeat;
        default: return TextureWrap::Repeat;
    }
}

// The materials of an Assimp scene as written: name, base-colour factor, base-colour
// texture (a path, or the bytes of an embedded image) and its wrap modes.
std::vector<FileMaterial> gltfMaterials(const std::string& path, const aiScene& scene) {
    std::vector<FileMaterial> out;
    for (unsigned i = 0; i < scene.mNumMaterials; ++i) {
        const aiMaterial& mat = *scene.mMaterials[i];
        FileMaterial fm;
        aiString name;
        if (mat.Get(AI_MATKEY_NAME, name) == AI_SUCCESS) fm.name = name.C_Str();
        aiColor4D colour(1.0f, 1.0f, 1.0f, 1.0f);
        if (mat.Get(AI_MATKEY_BASE_COLOR, colour) != AI_SUCCESS) mat.Get(AI_MATKEY_COLOR_DIFFUSE, colour);
        fm.baseColorFactor = glm::vec4(colour.r, colour.g, colour.b, colour.a);
        aiTextureType type = aiTextureType_BASE_COLOR;
        if (mat.GetTextureCount(type) == 0) type = aiTextureType_DIFFUSE;
        if (mat.GetTextureCount(type) > 0) {
            aiString texPath;
            unsigned uvIndex = 0;
            aiTextureMapMode modes[2] = {aiTextureMapMode_Wrap, aiTextureMapMode_Wrap};
            mat.GetTexture(type, 0, &texPath, nullptr, &uvIndex, nullptr, nullptr, modes);
            if (uvIndex != 0)
                throw Error(path, "material '" + fm.name + "': its base-colour texture uses TEXCOORD_" +
                                      std::to_string(uvIndex) + "; only TEXCOORD_0 is read");
            fm.wrapU = wrapOf(modes[0]);
            fm.wrapV = wrapOf(modes[1]);
            if (const aiTexture* embedded = scene.GetEmbeddedTexture(texPath.C_Str())) {
                if (embedded->mHeight != 0)
                    throw Error(path, "material '" + fm.name + "': uncompressed embedded textures are not supported");
                fm.embeddedTexture.assign(reinterpret_cast<const char*>(embedded->pcData), embedded->mWidth);
                fm.embeddedFormat = embedded->achFormatHint;
            } else if (texPath.length > 0 && texPath.C_Str()[0] == '*') {
                throw Error(path, "material '" + fm.name + "' refers to embedded texture " + texPath.C_Str() +
                                      ", which the file does not hold");
            } else {
                fm.texture = texPath.C_Str();
            }
        }
        out.push_back(std::move(fm));
    }
    if (out.empty()) out.emplace_back();
    return out;
}

// Reads a glTF file into `soup` (welded vertices, triangles, and with `surface` the
// per-corner texture coordinates and normals and the per-face material). Returns the
// number of triangles read (over all instances).
size_t readGltf(const std::string& path, Format format, std::string_view data, Soup& soup,
                std::vector<FileMaterial>* materials) {
    const size_t declared = gltfPrecheck(path, format, data);

    // From the file, not from `data`: Assimp opens a .gltf's buffers relative to it.
    Assimp::Importer importer;
    const aiScene* scene = importer.ReadFile(path, 0);
    if (!scene) {
        std::string why = oneLine(importer.GetErrorString());
        if (why.rfind("GLTF: ", 0) == 0) why = why.substr(6);
        throw Error(path, "cannot be read as glTF: " + (why.empty() ? std::string("unknown error") : why));
    }
    size_t read = 0;
    for (unsigned m = 0; m < scene->mNumMeshes; ++m) {
        const aiMesh& mesh = *scene->mMeshes[m];
        if (mesh.mPrimitiveTypes & (aiPrimitiveType_POINT | aiPrimitiveType_LINE))
            throw Error(path, "mesh '" + std::string(mesh.mName.C_Str()) +
                                  "' holds points or lines: only triangle primitives are read");
        for (unsigned f = 0; f < mesh.mNumFaces; ++f)
            if (mesh.mFaces[f].mNumIndices == 3) ++read;
    }
    if (read != declared)
        throw Error(path, "the file declares " + std::to_string(declared) + " triangles but " + std::to_string(read) +
                              " could be read (an index out of range, or a corrupt buffer)");
    if (!scene->mRootNode) throw Error(path, "cannot be read as glTF: no scene");

    const bool wantSurface = materials != nullptr;
    if (wantSurface) *materials = gltfMaterials(path, *scene);

    // Welding by position; -0 and +0 are one key.
    struct Key {
        uint32_t x, y, z;
        bool operator==(const Key&) const = default;
    };
    struct KeyHash {
        size_t operator()(const Key& k) const {
            uint64_t h = 1469598103934665603ull;
            for (uint32_t v : {k.x, k.y, k.z}) h = (h ^ v) * 1099511628211ull;
            return size_t(h);
        }
    };
    auto bits = [](float v) {
        if (v == 0.0f) v = 0.0f;
        uint32_t b;
        std::memcpy(&b, &v, 4);
        return b;
    };
    std::unordered_map<Key, uint32_t, KeyHash> welded;
    bool anyUv = false, anyNormal = false;
    size_t triangles = 0;
    const glm::vec2 noUv(std::numeric_limits<float>::quiet_NaN());
    const glm::vec3 noNormal(std::numeric_limits<float>::quiet_NaN());

    std::vector<std::pair<const aiNode*, aiMatrix4x4>> stack{{scene->mRootNode, scene->mRootNode->mTransformation}};
    std::vector<uint32_t> vertexOf;
    while (!stack.empty()) {
        const auto [node, transform] = stack.back();
        stack.pop_back();
        const bool identity = transform == aiMatrix4x4();
        aiMatrix3x3 normalMatrix(transform);
        normalMatrix.Inverse().Transpose();
        for (unsigned k = 0; k < node->mNumMeshes; ++k) {
            const unsigned mi = node->mMeshes[k];
            if (mi >= scene->mNumMeshes) throw Error(path, "a node refers to mesh " + std::to_string(mi) + " that does not exist");
            const aiMesh& mesh = *scene->mMeshes[mi];
            vertexOf.assign(mesh.mNumVertices, 0);
            for (unsigned v = 0; v < mesh.mNumVertices; ++v) {
                aiVector3D p = mesh.mVertices[v];
                if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
                    throw Error(path, "vertex " + std::to_string(v) + " of Assimp mesh " + std::to_string(mi) +
                                          " (a glTF primitive) has a non-finite coordinate (NaN/Inf coordinates "
                                          "are not allowed)");
                if (!identity) {
                    const glm::dvec4 q = glm::dvec4(p.x, p.y, p.z, 1.0);
                    glm::dvec3 r(0.0);
                    for (int row = 0; row < 3; ++row)
                        r[row] = transform[row][0] * q.x + transform[row][1] * q.y + transform[row][2] * q.z +
                                 transform[row][3];
                    p = aiVector3D(float(r.x), float(r.y), float(r.z));
                    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
                        throw Error(path, "a node transform takes a vertex to a non-finite position");
                }
                const Key key{bits(p.x), bits(p.y), bits(p.z)};
                const auto [it, inserted] = welded.try_emplace(key, uint32_t(soup.positions.size()));
                if (inserted) soup.positions.emplace_back(p.x, p.y, p.z);
                vertexOf[v] = it->second;
            }
            const bool hasUv = mesh.HasTextureCoords(0), hasNormal = mesh.HasNormals();
            anyUv = anyUv || hasUv;
            anyNormal = anyNormal || hasNormal;
            for (unsigned f = 0; f < mesh.mNumFaces; ++f) {
                const aiFace& face = mesh.mFaces[f];
                if (face.mNumIndices != 3) continue;
                for (int c = 0; c < 3; ++c) {
                    const unsigned idx = face.mIndices[c];
                    if (idx >= mesh.mNumVertices)
                        throw Error(path, "mesh '" + std::string(mesh.mName.C_Str()) + "' triangle " +
                                              std::to_string(f) + " refers to vertex " + std::to_string(idx) +
                                              " but the mesh has " + std::to_string(mesh.mNumVertices));
                    soup.corners.push_back(int(vertexOf[idx]));
                    if (!wantSurface) continue;
                    soup.cornerUv.push_back(hasUv ? glm::vec2(mesh.mTextureCoords[0][idx].x, mesh.mTextureCoords[0][idx].y)
                                                  : noUv);
                    if (hasNormal) {
                        aiVector3D n = mesh.mNormals[idx];
                        if (!identity) n = normalMatrix * n;
                        const float len = n.Length();
                        soup.cornerNormal.push_back(len > 0.0f ? glm::vec3(n.x, n.y, n.z) / len : noNormal);
                    } else {
                        soup.cornerNormal.push_back(noNormal);
                    }
                }
                soup.faceStart.push_back(soup.corners.size());
                if (wantSurface) soup.faceMaterial.push_back(mesh.mMaterialIndex);
                ++triangles;
            }
        }
        for (unsigned c = node->mNumChildren; c-- > 0;)
            stack.emplace_back(node->mChildren[c], transform * node->mChildren[c]->mTransformation);
    }
    if (wantSurface) {
        if (!anyUv) soup.cornerUv.clear();
        if (!anyNormal) soup.cornerNormal.clear();
        for (uint32_t& m : soup.faceMaterial)
            if (m >= materials->size()) m = uint32_t(materials->size() - 1);
    }
    return triangles;
}

}  // namespace

// ---------------------------------------------------------------------------------
// loadMesh
// ---------------------------------------------------------------------------------

namespace {

TriangleMesh loadMeshImpl(const std::string& path, MeshReport* report, MeshSurface* surface) {
    namespace fs = std::filesystem;
    std::error_code ec;
    if (!fs::exists(path, ec)) throw Error(path, "no such file");
    if (!fs::is_regular_file(path, ec)) throw Error(path, "not a regular file");

    bool gzName = false;
    const Format format = formatOf(path, gzName, "load");
    const bool gltf = format == Format::Gltf || format == Format::Glb;
    bool compressed = false;
    const std::string data = readFileBytes(path, compressed);
    if (data.empty()) throw Error(path, compressed ? "decompresses to nothing" : "file is empty");
    if (gltf && compressed) throw Error(path, "compressed glTF is not supported");

    MeshReport rep;
    rep.format = formatName(format);
    rep.compressed = compressed;

    std::optional<ObjSurfaceScan> objSurface;
    if (surface && format == Format::Obj) objSurface.emplace();
    const ScanResult expected = scan(format, path, data, objSurface ? &*objSurface : nullptr);

    Soup soup;
    std::vector<FileMaterial> materials;
    if (gltf) {
        readGltf(path, format, data, soup, surface ? &materials : nullptr);
    } else {
        std::lock_guard lock(openMeshMutex());
        std::optional<TempFile> temp;
        std::string readPath = path;
        if (compressed) {
            temp.emplace(path, fs::temp_directory_path(), "prt-mesh-" + std::to_string(long(::getpid())) + "-",
                         "." + formatName(format));
            std::FILE* out = std::fopen(temp->path().c_str(), "wb");
            bool written = out != nullptr;
            if (out) {
                written = std::fwrite(data.data(), 1, data.size(), out) == data.size();
                written = (std::fclose(out) == 0) && written;
            }
            if (!written) throw Error(path, "cannot write the decompressed data to " + temp->path());
            readPath = temp->path();
        }
        OpenMeshQuiet quiet;
        SoupImporter importer(soup, data.size() / 4 + 16);
        OpenMesh::IO::Options options;  // positions and faces only
        bool ok = false;
        try {
            ok = OpenMesh::IO::IOManager().read(readPath, importer, options);
        } catch (const std::exception& e) {
            throw Error(path, std::string("OpenMesh failed while reading: ") + e.what());
        }
        if (!ok)
            throw Error(path, "cannot be parsed as " + formatName(format) +
                                  " (corrupt, truncated or unsupported file)");
    }

    // Record counts against what the file declares.
    if (expected.vertices && soup.positions.size() != *expected.vertices)
        throw Error(path, "the file declares " + std::to_string(*expected.vertices) +
                              " vertices but " + std::to_string(soup.positions.size()) +
                              " could be read (truncated or malformed)");
    size_t droppedByReader = 0;
    if (expected.faces && soup.faceCount() != *expected.faces) {
        if (soup.faceCount() < *expected.faces && expected.readerDropsDegenerate)
            droppedByReader = *expected.faces - soup.faceCount();
        else
            throw Error(path, "the file declares " + std::to_string(*expected.faces) + " faces but " +
                                  std::to_string(soup.faceCount()) + " could be read (truncated or malformed)");
    }
    rep.fileVertices = soup.positions.size();
    rep.fileFaces = soup.faceCount() + droppedByReader;

    for (size_t v = 0; v < soup.positions.size(); ++v) {
        const glm::vec3 p = soup.positions[v];
        if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
            throw Error(path, "vertex " + std::to_string(v) +
                                  " has a non-finite coordinate (NaN/Inf coordinates are not allowed)");
    }
    const size_t nv = soup.positions.size();
    for (size_t f = 0; f < soup.faceCount(); ++f)
        for (size_t c = soup.faceStart[f]; c < soup.faceStart[f + 1]; ++c)
            if (soup.corners[c] < 0 || size_t(soup.corners[c]) >= nv)
                throw Error(path, "face " + std::to_string(f) + " refers to vertex " +
                                      std::to_string(soup.corners[c]) + " but the file has " +
                                      plural(nv, "vertex", "vertices"));
    if (rep.fileFaces == 0)
        throw Error(path, nv == 0 ? "contains no vertices and no faces (empty mesh)"
                                  : "contains " + plural(nv, "vertex", "vertices") +
                                        " but no faces (empty mesh)");

    // OBJ surface data from the pre-scan, face by face against what OpenMesh read.
    if (objSurface) {
        const ObjSurfaceScan& o = *objSurface;
        const size_t records = o.faceStart.size() - 1;
        bool same = records == soup.faceCount() && o.cornerVertex.size() == soup.corners.size();
        for (size_t c = 0; same && c < soup.corners.size(); ++c) same = o.cornerVertex[c] == soup.corners[c];
        for (size_t f = 0; same && f < records; ++f) same = o.faceStart[f + 1] == soup.faceStart[f + 1];
        if (!same)
            throw Error(path, "the faces' texture coordinates and normals cannot be matched to the faces read "
                              "(unsupported OBJ layout)");
        const glm::vec2 noUv(std::numeric_limits<float>::quiet_NaN());
        const glm::vec3 noNormal(std::numeric_limits<float>::quiet_NaN());
        const bool anyUv = std::any_of(o.cornerTexcoord.begin(), o.cornerTexcoord.end(), [](int t) { return t >= 0; });
        const bool anyNormal = std::any_of(o.cornerNormal.begin(), o.cornerNormal.end(), [](int n) { return n >= 0; });
        for (size_t c = 0; c < soup.corners.size(); ++c) {
            if (anyUv) soup.cornerUv.push_back(o.cornerTexcoord[c] >= 0 ? o.texcoords[size_t(o.cornerTexcoord[c])] : noUv);
            if (anyNormal) {
                const int n = o.cornerNormal[c];
                const float len = n >= 0 ? glm::length(o.normals[size_t(n)]) : 0.0f;
                soup.cornerNormal.push_back(len > 0.0f ? o.normals[size_t(n)] / len : noNormal);
            }
        }
        for (const std::string& name : o.materialNames) {
            materials.emplace_back();
            materials.back().name = name;
        }
        materials.push_back(FileMaterial{});  // faces before any usemtl
        for (uint32_t m : o.faceMaterial)
            soup.faceMaterial.push_back(m == ObjSurfaceScan::kNoMaterial ? uint32_t(materials.size() - 1) : m);
    }
    if (surface && !gltf && format != Format::Obj) {
        materials.assign(1, FileMaterial{});
        soup.faceMaterial.assign(soup.faceCount(), 0);
    }

    // Triangulate; a record with fewer than three distinct consecutive corners is one
    // degenerate input triangle. With a surface, each triangle's corners remember the
    // soup corners they came from and its face.
    const bool track = surface != nullptr;
    std::vector<glm::uvec3> tris;
    tris.reserve(soup.corners.size() / 3 + 1);
    std::vector<std::array<size_t, 3>> triCorners;
    std::vector<size_t> triFace;
    size_t degenerate = droppedByReader;
    std::vector<uint32_t> poly;
    std::vector<size_t> polyCorner;
    std::vector<glm::uvec3> local;
    for (size_t f = 0; f < soup.faceCount(); ++f) {
        poly.clear();
        polyCorner.clear();
        for (size_t c = soup.faceStart[f]; c < soup.faceStart[f + 1]; ++c) {
            const auto idx = uint32_t(soup.corners[c]);
            if (poly.empty() || poly.back() != idx) {
                poly.push_back(idx);
                polyCorner.push_back(c);
            }
        }
        while (poly.size() > 1 && poly.front() == poly.back()) {
            poly.pop_back();
            polyCorner.pop_back();
        }
        local.clear();
        if (poly.size() == 3) {
            local.emplace_back(0, 1, 2);
        } else if (poly.size() > 3) {
            ++rep.polygonsTriangulated;
            triangulatePolygon(soup.positions, poly, local);
        } else {
            ++degenerate;
        }
        for (const glm::uvec3& l : local) {
            tris.emplace_back(poly[l.x], poly[l.y], poly[l.z]);
            if (track) {
                triCorners.push_back({polyCorner[l.x], polyCorner[l.y], polyCorner[l.z]});
                triFace.push_back(f);
            }
        }
    }
    rep.inputTriangles = tris.size() + degenerate;

    // Drop degenerate triangles.
    TriangleMesh mesh;
    mesh.positions = std::move(soup.positions);
    {
        const double diag = double(bounds(mesh).diagonal());
        const double limit = 2.0 * 1e-12 * diag * diag;  // on |cross| = 2 * area
        std::vector<glm::uvec3> kept;
        kept.reserve(tris.size());
        for (size_t i = 0; i < tris.size(); ++i) {
            const glm::uvec3& t = tris[i];
            if (t.x == t.y || t.y == t.z || t.x == t.z) {
                ++degenerate;
                continue;
            }
            const glm::dvec3 p0(mesh.positions[t.x]), p1(mesh.positions[t.y]), p2(mesh.positions[t.z]);
            if (glm::length(glm::cross(p1 - p0, p2 - p0)) <= limit) {
                ++degenerate;
                continue;
            }
            kept.push_back(t);
            if (track) {
                for (size_t corner : triCorners[i]) {
                    if (!soup.cornerUv.empty()) surface->uvs.push_back(soup.cornerUv[corner]);
                    if (!soup.cornerNormal.empty()) surface->normals.push_back(soup.cornerNormal[corner]);
                }
                surface->triangleMaterials.push_back(soup.faceMaterial[triFace[i]]);
            }
        }
        mesh.triangles = std::move(kept);
    }
    rep.degenerateFaces = degenerate;
    rep.removedFaces = degenerate;
    if (mesh.triangles.empty())
        throw Error(path, "all " + plural(rep.inputTriangles, "face is", "faces are") +
                              " degenerate (zero area); nothing is left");

    // Remove vertices no kept triangle uses, keeping the others' relative order.
    {
        std::vector<uint32_t> remap(mesh.positions.size(), std::numeric_limits<uint32_t>::max());
        for (const auto& t : mesh.triangles)
            for (int k = 0; k < 3; ++k) remap[t[k]] = 0;
        uint32_t next = 0;
        std::vector<glm::vec3> kept;
        kept.reserve(mesh.positions.size());
        for (size_t v = 0; v < remap.size(); ++v)
            if (remap[v] == 0) {
                remap[v] = next++;
                kept.push_back(mesh.positions[v]);
            }
        rep.unreferencedVertices = mesh.positions.size() - kept.size();
        if (rep.unreferencedVertices > 0) {
            mesh.positions = std::move(kept);
            for (auto& t : mesh.triangles) t = glm::uvec3(remap[t.x], remap[t.y], remap[t.z]);
        }
    }
    computeVertexNormals(mesh);

    const MeshTopology topo = analyseTopology(mesh, true);
    rep.boundaryEdges = topo.boundaryEdges;
    rep.nonManifoldEdges = topo.nonManifoldEdges;
    rep.inconsistentEdges = topo.inconsistentEdges;
    rep.eulerCharacteristic = topo.eulerCharacteristic();
    rep.vertices = mesh.positions.size();
    rep.triangles = mesh.triangles.size();

    if (rep.degenerateFaces > 0)
        warn(path + ": dropped " + plural(rep.degenerateFaces, "degenerate face", "degenerate faces") +
             " (zero area or repeated vertex) of " + std::to_string(rep.inputTriangles));
    if (rep.unreferencedVertices > 0)
        warn(path + ": removed " + plural(rep.unreferencedVertices, "vertex", "vertices") +
             " not used by any face");
    if (rep.nonManifoldEdges > 0)
        warn(path + ": " + plural(rep.nonManifoldEdges, "non-manifold edge", "non-manifold edges") +
             " (shared by three or more faces); kept");
    if (rep.boundaryEdges > 0)
        warn(path + ": " + plural(rep.boundaryEdges, "boundary edge", "boundary edges") +
             " (the surface is not closed); kept");
    if (rep.inconsistentEdges > 0)
        warn(path + ": " + plural(rep.inconsistentEdges, "edge joins", "edges join") +
             " faces of opposite orientation; kept");

    if (report) *report = rep;
    if (surface) {
        surface->materials = std::move(materials);
        if (objSurface) surface->materialLibraries = objSurface->libraries;
    }
    return mesh;
}

}  // namespace

TriangleMesh loadMesh(const std::string& path, MeshReport* report) {
    return loadMeshImpl(path, report, nullptr);
}

TriangleMesh loadMeshSurface(const std::string& path, MeshSurface& surface, MeshReport* report) {
    surface = MeshSurface{};
    return loadMeshImpl(path, report, &surface);
}

// ---------------------------------------------------------------------------------
// saveMesh
// ---------------------------------------------------------------------------------

namespace {

// Hands a TriangleMesh to OpenMesh's writers: positions and triangles, nothing else.
// The (empty) kernel is there because the PLY writer asks it for custom properties.
class MeshExporter : public OpenMesh::IO::BaseExporter {
public:
    explicit MeshExporter(const TriangleMesh& mesh) : mesh_(mesh) {}

    OpenMesh::Vec3f point(OpenMesh::VertexHandle vh) const override {
        const glm::vec3& p = mesh_.positions[size_t(vh.idx())];
        return OpenMesh::Vec3f(p.x, p.y, p.z);
    }
    OpenMesh::Vec3d pointd(OpenMesh::VertexHandle vh) const override {
        const glm::vec3& p = mesh_.positions[size_t(vh.idx())];
        return OpenMesh::Vec3d(p.x, p.y, p.z);
    }
    bool is_point_double() const override { return false; }
    unsigned int get_vhandles(OpenMesh::FaceHandle fh, std::vector<OpenMesh::VertexHandle>& out) const override {
        const glm::uvec3& t = mesh_.triangles[size_t(fh.idx())];
        out.assign({OpenMesh::VertexHandle(int(t.x)), OpenMesh::VertexHandle(int(t.y)),
                    OpenMesh::VertexHandle(int(t.z))});
        return 3;
    }
    OpenMesh::Vec3f normal(OpenMesh::FaceHandle fh) const override {
        const glm::vec3 n = faceNormal(mesh_, size_t(fh.idx()));
        return OpenMesh::Vec3f(n.x, n.y, n.z);
    }
    OpenMesh::Vec3d normald(OpenMesh::FaceHandle fh) const override {
        const glm::vec3 n = faceNormal(mesh_, size_t(fh.idx()));
        return OpenMesh::Vec3d(n.x, n.y, n.z);
    }
    const OpenMesh::BaseKernel* kernel() override { return &kernel_; }
    size_t n_vertices() const override { return mesh_.positions.size(); }
    size_t n_faces() const override { return mesh_.triangles.size(); }
    size_t n_edges() const override { return 0; }
    bool is_triangle_mesh() const override { return true; }

    // Attributes we do not write.
    OpenMesh::Vec3f normal(OpenMesh::VertexHandle) const override { return OpenMesh::Vec3f(0, 0, 0); }
    OpenMesh::Vec3d normald(OpenMesh::VertexHandle) const override { return OpenMesh::Vec3d(0, 0, 0); }
    bool is_normal_double() const override { return false; }
    OpenMesh::Vec3uc color(OpenMesh::VertexHandle) const override { return OpenMesh::Vec3uc(0, 0, 0); }
    OpenMesh::Vec4uc colorA(OpenMesh::VertexHandle) const override { return OpenMesh::Vec4uc(0, 0, 0, 0); }
    OpenMesh::Vec3ui colori(OpenMesh::VertexHandle) const override { return OpenMesh::Vec3ui(0, 0, 0); }
    OpenMesh::Vec4ui colorAi(OpenMesh::VertexHandle) const override { return OpenMesh::Vec4ui(0, 0, 0, 0); }
    OpenMesh::Vec3f colorf(OpenMesh::VertexHandle) const override { return OpenMesh::Vec3f(0, 0, 0); }
    OpenMesh::Vec4f colorAf(OpenMesh::VertexHandle) const override { return OpenMesh::Vec4f(0, 0, 0, 0); }
    OpenMesh::Vec2f texcoord(OpenMesh::VertexHandle) const override { return OpenMesh::Vec2f(0, 0); }
    OpenMesh::Vec2f texcoord(OpenMesh::HalfedgeHandle) const override { return OpenMesh::Vec2f(0, 0); }
    OpenMesh::Attributes::StatusInfo status(OpenMesh::VertexHandle) const override { return {}; }
    OpenMesh::HalfedgeHandle getHeh(OpenMesh::FaceHandle, OpenMesh::VertexHandle) const override {
        return OpenMesh::HalfedgeHandle();
    }
    unsigned int get_face_texcoords(std::vector<OpenMesh::Vec2f>& out) const override {
        out.clear();
        return 0;
    }
    OpenMesh::Vec3uc color(OpenMesh::FaceHandle) const override { return OpenMesh::Vec3uc(0, 0, 0); }
    OpenMesh::Vec4uc colorA(OpenMesh::FaceHandle) const override { return OpenMesh::Vec4uc(0, 0, 0, 0); }
    OpenMesh::Vec3ui colori(OpenMesh::FaceHandle) const override { return OpenMesh::Vec3ui(0, 0, 0); }
    OpenMesh::Vec4ui colorAi(OpenMesh::FaceHandle) const override { return OpenMesh::Vec4ui(0, 0, 0, 0); }
    OpenMesh::Vec3f colorf(OpenMesh::FaceHandle) const override { return OpenMesh::Vec3f(0, 0, 0); }
    OpenMesh::Vec4f colorAf(OpenMesh::FaceHandle) const override { return OpenMesh::Vec4f(0, 0, 0, 0); }
    OpenMesh::Attributes::StatusInfo status(OpenMesh::FaceHandle) const override { return {}; }
    OpenMesh::Vec3uc color(OpenMesh::EdgeHandle) const override { return OpenMesh::Vec3uc(0, 0, 0); }
    OpenMesh::Vec4uc colorA(OpenMesh::EdgeHandle) const override { return OpenMesh::Vec4uc(0, 0, 0, 0); }
    OpenMesh::Vec3ui colori(OpenMesh::EdgeHandle) const override { return OpenMesh::Vec3ui(0, 0, 0); }
    OpenMesh::Vec4ui colorAi(OpenMesh::EdgeHandle) const override { return OpenMesh::Vec4ui(0, 0, 0, 0); }
    OpenMesh::Vec3f colorf(OpenMesh::EdgeHandle) const override { return OpenMesh::Vec3f(0, 0, 0); }
    OpenMesh::Vec4f colorAf(OpenMesh::EdgeHandle) const override { return OpenMesh::Vec4f(0, 0, 0, 0); }
    OpenMesh::Attributes::StatusInfo status(OpenMesh::EdgeHandle) const override { return {}; }
    int get_halfedge_id(OpenMesh::VertexHandle) override { return -1; }
    int get_halfedge_id(OpenMesh::FaceHandle) override { return -1; }
    int get_next_halfedge_id(OpenMesh::HalfedgeHandle) override { return -1; }
    int get_to_vertex_id(OpenMesh::HalfedgeHandle) override { return -1; }
    int get_face_id(OpenMesh::HalfedgeHandle) override { return -1; }
    OpenMesh::Attributes::StatusInfo status(OpenMesh::HalfedgeHandle) const override { return {}; }

private:
    const TriangleMesh& mesh_;
    OpenMesh::BaseKernel kernel_;
};

}  // namespace

void saveMesh(const TriangleMesh& mesh, const std::string& path) {
    bool gz = false;
    const Format format = formatOf(path, gz, "save");
    if (gz) throw Error(path, "saving compressed (.gz) meshes is not supported");
    for (const auto& t : mesh.triangles)
        if (t.x >= mesh.positions.size() || t.y >= mesh.positions.size() || t.z >= mesh.positions.size())
            throw Error(path, "cannot save: a triangle refers to a vertex that does not exist");

    OpenMesh::IO::Options options;
    if (format == Format::Ply) options = OpenMesh::IO::Options(OpenMesh::IO::Options::Binary | OpenMesh::IO::Options::LSB);
    if (format == Format::Stl) options = OpenMesh::IO::Options(OpenMesh::IO::Options::Binary);

    std::lock_guard lock(openMeshMutex());
    writeAtomically(path, [&](const std::string& temp) {
        if (format == Format::Obj) {
            // Written directly: OpenMesh's OBJ writer prints coordinates in fixed-point
            // notation, which loses small values (1e-17 becomes 0).
            std::FILE* out = std::fopen(temp.c_str(), "w");
            if (!out) throw Error(path, std::string("cannot write: ") + std::strerror(errno));
            bool ok = std::fprintf(out, "# %zu vertices, %zu triangles\n", mesh.positions.size(),
                                   mesh.triangles.size()) > 0;
            for (const auto& p : mesh.positions)
                ok = ok && std::fprintf(out, "v %.9g %.9g %.9g\n", double(p.x), double(p.y), double(p.z)) > 0;
            for (const auto& t : mesh.triangles)
                ok = ok && std::fprintf(out, "f %u %u %u\n", t.x + 1, t.y + 1, t.z + 1) > 0;
            ok = (std::fclose(out) == 0) && ok;
            if (!ok) throw Error(path, "error while writing the mesh");
        } else {
            OpenMeshQuiet quiet;
            MeshExporter exporter(mesh);
            bool ok = false;
            try {
                ok = OpenMesh::IO::IOManager().write(temp, exporter, options, 9);
            } catch (const std::exception& e) {
                throw Error(path, std::string("OpenMesh failed while writing: ") + e.what());
            }
            if (!ok) throw Error(path, "cannot write the mesh (OpenMesh's writer failed)");
        }
    });
}

}  // namespace prt
