#include "precompute/job/pass1_file.h"

#include <zlib.h>

#include <cstring>
#include <fstream>
#include <iterator>
#include <sstream>

#include "common/atomic_file.h"
#include "common/error.h"
#include "common/transport_params.h"

namespace prt {

namespace {

constexpr char kMagic[8] = {'P', 'R', 'T', 'P', 'A', 'S', 'S', '1'};
constexpr uint32_t kVersion = 1;
constexpr uint32_t kEndianMarker = 0x01020304;

template <class T>
void put(std::string& out, const T& v) {
    out.append(reinterpret_cast<const char*>(&v), sizeof(T));
}

uint32_t crcOf(const char* data, size_t size) {
    uLong crc = crc32(0L, Z_NULL, 0);
    while (size > 0) {
        const uInt chunk = uInt(std::min<size_t>(size, 1u << 30));
        crc = crc32(crc, reinterpret_cast<const Bytef*>(data), chunk);
        data += chunk;
        size -= chunk;
    }
    return uint32_t(crc);
}

// The first line where two keys differ, for the message.
std::string firstDifference(const std::string& a, const std::string& b) {
    std::istringstream ia(a), ib(b);
    std::string la, lb;
    while (true) {
        const bool ga = bool(std::getline(ia, la)), gb = bool(std::getline(ib, lb));
        if (!ga && !gb) return "";
        if (la != lb || ga != gb) return "file has '" + (ga ? la : "") + "', this job '" + (gb ? lb : "") + "'";
    }
}

}  // namespace

std::string pass1Key(const std::vector<std::pair<std::string, std::string>>& parameters, double mmPerUnit,
                     size_t samples) {
    std::string key;
    for (const auto& [k, v] : parameters)
        if (k == "mesh_vertices" || k == "mesh_hash" || k == "seed" || k == "cubemap_size" || k == "supersample" || k == "pass1_visibility" ||
            k == "sample_coefficients" || (k == "sh_terms" && v != "0") || k == "eta" ||
            k == "ground_size_diagonals" || k == "ground_cells")  // the plane occludes pass 1
            key += k + "=" + v + "\n";
    key += "mm_per_unit=" + formatParameter(mmPerUnit) + "\n";
    key += "samples=" + std::to_string(samples) + "\n";
    return key;
}

void savePass1File(const std::string& path, const std::string& key, const std::vector<SparseVector>& vectors) {
    std::string out;
    size_t coefficients = 0;
    for (const SparseVector& v : vectors) coefficients += v.size();
    out.reserve(64 + key.size() + vectors.size() * 4 + coefficients * 8);
    out.append(kMagic, sizeof kMagic);
    put(out, kVersion);
    put(out, kEndianMarker);
    put(out, uint64_t(key.size()));
    out += key;
    put(out, uint64_t(vectors.size()));
    for (const SparseVector& v : vectors) {
        if (v.channels != 1 || v.value.size() != v.index.size())
            throw Error(path, "pass-1 vectors must have one channel");
        put(out, uint32_t(v.size()));
        if (v.empty()) continue;
        out.append(reinterpret_cast<const char*>(v.index.data()), v.index.size() * sizeof(uint32_t));
        out.append(reinterpret_cast<const char*>(v.value.data()), v.value.size() * sizeof(float));
    }
    put(out, crcOf(out.data(), out.size()));
    writeFileAtomically(path, out);
}

std::vector<SparseVector> loadPass1File(const std::string& path, const std::string& key) {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw Error(path, "cannot open the pass-1 file");
    const std::string data((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    if (data.size() < sizeof kMagic + 16 || std::memcmp(data.data(), kMagic, sizeof kMagic) != 0)
        throw Error(path, "not a pass-1 file (no PRTPASS1 magic)");
    size_t at = sizeof kMagic;
    auto get = [&](auto& v) {
        if (data.size() - at < sizeof v + 4) throw Error(path, "truncated pass-1 file");
        std::memcpy(&v, data.data() + at, sizeof v);
        at += sizeof v;
    };
    uint32_t version = 0, marker = 0;
    get(version);
    get(marker);
    if (marker != kEndianMarker) throw Error(path, "pass-1 file of the other byte order");
    if (version != kVersion)
        throw Error(path, "unsupported pass-1 file version " + std::to_string(version) + " (this build reads 1)");
    uint32_t stored = 0;
    std::memcpy(&stored, data.data() + data.size() - 4, 4);
    if (stored != crcOf(data.data(), data.size() - 4)) throw Error(path, "pass-1 file is corrupt (checksum mismatch)");
    uint64_t keyLength = 0, count = 0;
    get(keyLength);
    if (keyLength > data.size() - at - 4) throw Error(path, "truncated pass-1 file");
    const std::string stored_key = data.substr(at, keyLength);
    at += keyLength;
    if (stored_key != key)
        throw Error(path, "was made for other pass-1 inputs (" + firstDifference(stored_key, key) + ")");
    get(count);
    if (count > (data.size() - at) / 4) throw Error(path, "truncated pass-1 file");
    std::vector<SparseVector> vectors(count);
    for (SparseVector& v : vectors) {
        uint32_t n = 0;
        get(n);
        if (uint64_t(n) * 8 > data.size() - at - 4) throw Error(path, "truncated pass-1 file");
        if (n == 0) continue;  // (memcpy into an empty vector's null data() is undefined)
        v.index.resize(n);
        v.value.resize(n);
        std::memcpy(v.index.data(), data.data() + at, n * sizeof(uint32_t));
        at += n * sizeof(uint32_t);
        std::memcpy(v.value.data(), data.data() + at, n * sizeof(float));
        at += n * sizeof(float);
    }
    if (at != data.size() - 4) throw Error(path, "pass-1 file has trailing bytes");
    return vectors;
}

}  // namespace prt
