// Transport file I/O. The byte layout is documented in docs/transport-format.md; the
// constants and layout functions below are the single source of truth for it.

#include "common/transport_file.h"

#include "common/atomic_file.h"

#include "common/error.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>
#include <zlib.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cerrno>
#include <cinttypes>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <numeric>
#include <set>
#include <stdexcept>

namespace prt {

// ---------------------------------------------------------------------------------
// Small helpers
// ---------------------------------------------------------------------------------

namespace {

constexpr std::array<char, 8> kMagic = {'P', 'R', 'T', 'X', 'P', 'O', 'R', 'T'};
// Version 1 holds per-vertex components (COMP) only; version 2 adds blocked
// components (BLKC). The writer writes version 2 only for a file that has a blocked
// component, so every other file stays version 1 byte for byte and older readers keep
// reading it; a reader refuses BLKC in a version-1 file and a version-2 file without
// one (so no single corrupted byte of a version field is accepted). Version 3 adds an
// SH part to every vector (common/sh_part.h): the header's former reserved field holds
// the SH term count (1, 4 or 9; 0 in versions 1 and 2), and indices run to 6 N^2 +
// terms. Any file with SH terms is version 3, with or without blocked components.
// Version 4 changes BLKC sections: their indices are delta-coded varints
// (encodeBlockIndices, common/blocked_vectors.h) and a section may hold a second array
// of scales, for the SH indices ("Two scales" there), flagged in its first reserved
// field. A file with SH terms and a blocked component is version 4; version-3 files
// (one scale per vertex and channel, 16-bit indices) load as before.
constexpr uint32_t kFormatVersion = 1;
constexpr uint32_t kBlockedFormatVersion = 2;
constexpr uint32_t kShFormatVersion = 3;
constexpr uint32_t kBlockVarintFormatVersion = 4;
constexpr uint32_t kEndianMarker = 0x01020304u;
constexpr uint64_t kAlignment = 64;
constexpr uint64_t kPreambleBytes = 16;
constexpr uint64_t kSectionHeaderBytes = 16;
constexpr uint64_t kChecksumBytes = 4;
constexpr uint64_t kHeadBytes = 40;
constexpr uint64_t kComponentFixedBytes = 64;
constexpr uint64_t kBlockedFixedBytes = 64;
constexpr uint64_t kViewFixedBytes = 64;
constexpr uint64_t kMaxParameterBytes = uint64_t(16) << 20;
constexpr uint32_t kMaxCubemapSize = 64;
constexpr uint64_t kMaxVertices = uint64_t(1) << 40;
constexpr uint32_t kMaxViewMapSize = 4096;
constexpr uint32_t kMaxViewMapTerms = 4096;
constexpr int kQuantMax = 32767;

enum class Section { Head, Parameters, Component, BlockedComponent, ViewMaps, End };

const char* tagOf(Section s) {
    switch (s) {
        case Section::Head: return "HEAD";
        case Section::Parameters: return "PARM";
        case Section::Component: return "COMP";
        case Section::BlockedComponent: return "BLKC";
        case Section::ViewMaps: return "VIEW";
        case Section::End: return "END ";
    }
    return "????";
}

std::string sectionLabel(Section s, size_t index = 0, size_t count = 0) {
    std::string label = std::string("section '") + tagOf(s) + "'";
    switch (s) {
        case Section::Head: return label + " (header)";
        case Section::Parameters: return label + " (parameters)";
        case Section::Component:
            return label + " (component " + std::to_string(index + 1) + " of " +
                   std::to_string(count) + ")";
        case Section::BlockedComponent:
            return label + " (blocked component " + std::to_string(index + 1) + " of " +
                   std::to_string(count) + ")";
        case Section::ViewMaps: return label + " (view maps)";
        case Section::End: return label + " (end marker)";
    }
    return label;
}

std::string hex64(uint64_t v) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "0x%016" PRIx64, v);
    return buf;
}

std::string hex32(uint32_t v) {
    char buf[16];
    std::snprintf(buf, sizeof buf, "0x%08" PRIx32, v);
    return buf;
}

std::string u64(uint64_t v) { return std::to_string(v); }

std::string printableTag(const uint8_t* p) {
    std::string out = "'";
    for (int i = 0; i < 4; ++i) {
        if (p[i] >= 0x20 && p[i] < 0x7f) {
            out += char(p[i]);
        } else {
            char buf[8];
            std::snprintf(buf, sizeof buf, "\\x%02x", p[i]);
            out += buf;
        }
    }
    return out + "'";
}

std::string formatBytes(uint64_t bytes) {
    char buf[32];
    if (bytes < 1024) {
        std::snprintf(buf, sizeof buf, "%" PRIu64 " B", bytes);
    } else if (bytes < (uint64_t(1) << 20)) {
        std::snprintf(buf, sizeof buf, "%.1f KiB", double(bytes) / 1024.0);
    } else if (bytes < (uint64_t(1) << 30)) {
        std::snprintf(buf, sizeof buf, "%.1f MiB", double(bytes) / 1048576.0);
    } else {
        std::snprintf(buf, sizeof buf, "%.2f GiB", double(bytes) / 1073741824.0);
    }
    return buf;
}

std::string formatDouble(double v) {
    char buf[64];
    std::snprintf(buf, sizeof buf, "%.17g", v);
    // Shortest representation that round-trips, for readability.
    for (int precision = 1; precision <= 17; ++precision) {
        char tryBuf[64];
        std::snprintf(tryBuf, sizeof tryBuf, "%.*g", precision, v);
        if (std::strtod(tryBuf, nullptr) == v) return tryBuf;
    }
    return buf;
}

uint64_t alignUp(uint64_t x) { return (x + kAlignment - 1) / kAlignment * kAlignment; }

// Zero bytes written before a section header at file offset pos so that the
// section's payload starts at a multiple of kAlignment.
uint64_t paddingBefore(uint64_t pos) {
    return (kAlignment - (pos + kSectionHeaderBytes) % kAlignment) % kAlignment;
}

// Byte offsets, relative to the payload start, of a component section's arrays.
struct ComponentLayout {
    uint64_t offsets = 0, indices = 0, values = 0, scales = 0, total = 0;
};

// Requires vertices <= kMaxVertices and coefficients <= UINT32_MAX (no overflow).
ComponentLayout componentLayout(uint64_t vertices, uint64_t coefficients) {
    ComponentLayout l;
    l.offsets = kComponentFixedBytes;
    l.indices = alignUp(l.offsets + (vertices + 1) * sizeof(uint32_t));
    l.values = alignUp(l.indices + coefficients * sizeof(uint16_t));
    l.scales = alignUp(l.values + 3 * coefficients * sizeof(int16_t));
    l.total = l.scales + 3 * vertices * sizeof(float);
    return l;
}

// Blocks of kVertexBlock vertices (the last one may be partial).
uint64_t blockCountOf(uint64_t vertices) { return (vertices + kVertexBlock - 1) / kVertexBlock; }

// Byte offsets, relative to the payload start, of a blocked component section's arrays.
struct BlockedLayout {
    uint64_t order = 0, offsets = 0, indices = 0, values = 0, scales = 0, shScales = 0, total = 0;
};

// Requires vertices <= kMaxVertices, indices <= UINT32_MAX and indexBytes <= 3 indices
// (no overflow). indexBytes: the size of the index array (2 per index before format
// version 4, the varint stream's size from it); shScales: the SH scales array is there.
BlockedLayout blockedLayout(uint64_t vertices, uint64_t indices, uint64_t indexBytes, bool shScales) {
    const uint64_t blocks = blockCountOf(vertices);
    BlockedLayout l;
    l.order = kBlockedFixedBytes;
    l.offsets = alignUp(l.order + vertices * sizeof(uint32_t));
    l.indices = alignUp(l.offsets + (blocks + 1) * sizeof(uint32_t));
    l.values = alignUp(l.indices + indexBytes);
    l.scales = alignUp(l.values + indices * kBlockValuesPerIndex * sizeof(int8_t));
    l.total = l.scales + blocks * kBlockValuesPerIndex * sizeof(float);
    if (shScales) {
        l.shScales = alignUp(l.total);
        l.total = l.shScales + blocks * kBlockValuesPerIndex * sizeof(float);
    }
    return l;
}

// Requires size <= kMaxViewMapSize and terms <= kMaxViewMapTerms.
uint64_t viewMapsPayloadBytes(uint64_t size, uint64_t terms) {
    return kViewFixedBytes + terms * 6 * size * size * sizeof(float);
}

// Little-endian scalar encoding, independent of the host byte order.
void putU32(uint8_t* p, uint32_t v) {
    for (int i = 0; i < 4; ++i) p[i] = uint8_t(v >> (8 * i));
}
void putU64(uint8_t* p, uint64_t v) {
    for (int i = 0; i < 8; ++i) p[i] = uint8_t(v >> (8 * i));
}
uint32_t getU32(const uint8_t* p) {
    uint32_t v = 0;
    for (int i = 0; i < 4; ++i) v |= uint32_t(p[i]) << (8 * i);
    return v;
}
uint64_t getU64(const uint8_t* p) {
    uint64_t v = 0;
    for (int i = 0; i < 8; ++i) v |= uint64_t(p[i]) << (8 * i);
    return v;
}

// Reverses the bytes of each of `count` elements of `size` bytes (big-endian hosts).
void byteSwapElements(uint8_t* p, size_t count, size_t size) {
    for (size_t e = 0; e < count; ++e) std::reverse(p + e * size, p + (e + 1) * size);
}

uLong crcUpdate(uLong crc, const void* data, uint64_t n) {
    const auto* p = static_cast<const Bytef*>(data);
    while (n > 0) {
        const uInt chunk = uInt(std::min<uint64_t>(n, uint64_t(1) << 30));
        crc = crc32(crc, p, chunk);
        p += chunk;
        n -= chunk;
    }
    return crc;
}

bool allZero(const uint8_t* p, size_t n) {
    return std::all_of(p, p + n, [](uint8_t b) { return b == 0; });
}

bool validKind(uint32_t kind) {
    return kind >= uint32_t(ComponentKind::MultipleScattering) &&
           kind <= uint32_t(ComponentKind::SingleScatteringTerm);
}

// ---------------------------------------------------------------------------------
// Validation shared by save and load: returns "" when fine, else the reason.
// ---------------------------------------------------------------------------------

bool validShTermCount(uint32_t terms) { return terms == 0 || terms == 1 || terms == 4 || terms == 9; }

std::string indexLimitText(uint32_t cubemapSize, uint32_t shTerms) {
    return "(6 x " + u64(cubemapSize) + " x " + u64(cubemapSize) +
           (shTerms ? " + " + u64(shTerms) + " SH terms)" : ")");
}

std::string checkVectors(const SparseRgbVectors& s, uint64_t vertices, uint32_t cubemapSize,
                         uint32_t shTerms) {
    const uint64_t indexLimit = uint64_t(6) * cubemapSize * cubemapSize + shTerms;
    if (s.offsets.size() != vertices + 1)
        return "has " + u64(s.offsets.size()) + " offsets, expected " + u64(vertices + 1) +
               " (vertex count + 1)";
    if (s.offsets[0] != 0) return "offsets[0] is " + u64(s.offsets[0]) + ", not 0";
    if (s.offsets[vertices] != s.indices.size())
        return "offsets end at " + u64(s.offsets[vertices]) + " but there are " +
               u64(s.indices.size()) + " coefficient indices";
    if (s.values.size() != 3 * s.indices.size())
        return "has " + u64(s.values.size()) + " values, expected 3 per coefficient (" +
               u64(3 * s.indices.size()) + ")";
    if (s.scales.size() != 3 * vertices)
        return "has " + u64(s.scales.size()) + " scales, expected 3 per vertex (" +
               u64(3 * vertices) + ")";
    // Monotone offsets from 0 to the coefficient count keep every range in bounds.
    for (uint64_t v = 0; v < vertices; ++v)
        if (s.offsets[v + 1] < s.offsets[v])
            return "offsets decrease at vertex " + u64(v) + " (" + u64(s.offsets[v]) +
                   " then " + u64(s.offsets[v + 1]) + ")";
    for (uint64_t v = 0; v < vertices; ++v) {
        const uint32_t begin = s.offsets[v], end = s.offsets[v + 1];
        for (uint32_t n = begin; n < end; ++n) {
            if (s.indices[n] >= indexLimit)
                return "vertex " + u64(v) + ": coefficient index " + u64(s.indices[n]) +
                       " >= " + u64(indexLimit) + " " + indexLimitText(cubemapSize, shTerms);
            if (n > begin && s.indices[n] <= s.indices[n - 1])
                return "vertex " + u64(v) + ": coefficient indices not strictly increasing (" +
                       u64(s.indices[n - 1]) + " then " + u64(s.indices[n]) + ")";
        }
        for (int c = 0; c < 3; ++c) {
            const float scale = s.scales[3 * v + c];
            if (!std::isfinite(scale) || scale < 0.0f)
                return "vertex " + u64(v) + ": scale of channel " + std::to_string(c) +
                       " is not a finite non-negative number";
        }
    }
    return {};
}

std::string checkBlocked(const BlockedRgbVectors& b, uint64_t vertices, uint32_t cubemapSize,
                         uint32_t shTerms) {
    if (b.vertices != vertices)
        return "has " + u64(b.vertices) + " blocked vertices, expected " + u64(vertices);
    if (vertices == 0) return "a blocked component has no vertices";
    // Lane numbers 16 b + lane (and slotOf's "no lane" marker UINT32_MAX) are u32.
    if (vertices > UINT32_MAX)
        return "has " + u64(vertices) + " vertices, a blocked component holds at most 2^32 - 1";
    // checkBlockedVectors walks each block's index range without bounding it first, so
    // the offsets are checked to be monotone up to the index count here.
    const uint64_t blocks = blockCountOf(vertices);
    if (b.offsets.size() != blocks + 1)
        return "has " + u64(b.offsets.size()) + " block offsets, expected " + u64(blocks + 1) +
               " (block count + 1)";
    if (b.offsets[0] != 0) return "block offsets[0] is " + u64(b.offsets[0]) + ", not 0";
    if (b.offsets[blocks] != b.indices.size())
        return "block offsets end at " + u64(b.offsets[blocks]) + " but there are " +
               u64(b.indices.size()) + " indices";
    for (uint64_t k = 0; k < blocks; ++k)
        if (b.offsets[k + 1] < b.offsets[k])
            return "block offsets decrease at block " + u64(k) + " (" + u64(b.offsets[k]) +
                   " then " + u64(b.offsets[k + 1]) + ")";
    // Also the padding lanes (zero values and scales, as appendBlock writes them, so
    // equal data has equal bytes).
    return checkBlockedVectors(b, 6 * cubemapSize * cubemapSize + shTerms);
}

std::string checkViewMaps(const ViewMaps& m) {
    if (m.size < 1 || uint32_t(m.size) > kMaxViewMapSize)
        return "view map size " + std::to_string(m.size) + " outside 1.." +
               std::to_string(kMaxViewMapSize);
    if (m.terms < 1 || uint32_t(m.terms) > kMaxViewMapTerms)
        return "view map term count " + std::to_string(m.terms) + " outside 1.." +
               std::to_string(kMaxViewMapTerms);
    const uint64_t expected = uint64_t(m.terms) * 6 * uint64_t(m.size) * uint64_t(m.size);
    if (m.data.size() != expected)
        return "view maps hold " + u64(m.data.size()) + " floats, expected " + u64(expected) +
               " (terms x 6 x size x size)";
    for (size_t i = 0; i < m.data.size(); ++i)
        if (!std::isfinite(m.data[i])) return "view map value " + u64(i) + " is not finite";
    return {};
}

// Checks everything that does not depend on the byte layout. componentIndex, when
// set, receives the index of the offending component (SIZE_MAX if none).
std::string checkFile(const TransportFile& f, size_t* componentIndex = nullptr) {
    if (componentIndex) *componentIndex = SIZE_MAX;
    if (f.cubemapSize < 1 || f.cubemapSize > kMaxCubemapSize ||
        !std::has_single_bit(f.cubemapSize))
        return "cubemap size " + u64(f.cubemapSize) + " is not a power of two in 1..64";
    if (!validShTermCount(f.shTerms)) return "SH term count " + u64(f.shTerms) + " is not 0, 1, 4 or 9";
    if (f.shTerms == 9 && f.cubemapSize < 2) return "9 SH terms on a 6 x 1 x 1 cubemap (they are not independent there)";
    if (f.mesh.vertexCount == 0) return "mesh fingerprint has zero vertices";
    if (f.mesh.vertexCount > kMaxVertices)
        return "mesh fingerprint has " + u64(f.mesh.vertexCount) + " vertices (limit 2^40)";
    if (!std::isfinite(f.mmPerUnit) || f.mmPerUnit <= 0.0)
        return "mm per unit " + formatDouble(f.mmPerUnit) + " is not a positive finite number";
    std::set<std::string> keys;
    for (const auto& [key, value] : f.parameters) {
        if (key.empty()) return "a parameter has an empty key";
        if (key.size() > UINT32_MAX || value.size() > UINT32_MAX)
            return "parameter '" + key.substr(0, 64) + "' is too long";
        if (!keys.insert(key).second) return "parameter '" + key + "' appears twice";
    }
    if (f.components.empty()) return "no components";
    if (f.components.size() > UINT32_MAX) return "too many components";
    std::set<std::pair<uint32_t, uint32_t>> seen;
    std::set<uint32_t> terms;
    for (size_t i = 0; i < f.components.size(); ++i) {
        const TransportComponent& c = f.components[i];
        const std::string name = "component " + u64(i + 1) + " (" +
                                 (validKind(uint32_t(c.kind)) ? componentName(c.kind, c.term)
                                                              : std::string("unknown kind")) +
                                 ")";
        if (componentIndex) *componentIndex = i;
        if (!validKind(uint32_t(c.kind)))
            return name + ": kind " + u64(uint32_t(c.kind)) + " is not 1, 2 or 3";
        if (c.kind != ComponentKind::SingleScatteringTerm && c.term != 0)
            return name + ": term " + u64(c.term) + " on a component that has no terms";
        if (!seen.insert({uint32_t(c.kind), c.term}).second) return name + ": appears twice";
        if (c.kind == ComponentKind::SingleScatteringTerm) terms.insert(c.term);
        if (c.vertexCount() != f.mesh.vertexCount)
            return name + ": has " + u64(c.vertexCount()) +
                   " vertices, the mesh fingerprint has " + u64(f.mesh.vertexCount);
        // Exactly one encoding holds data: the other would be dropped by the writer.
        const SparseRgbVectors& v = c.vectors;
        const BlockedRgbVectors& b = c.blocks;
        if (c.blocked() && (v.vertexCount() != 0 || !v.indices.empty() || !v.values.empty() ||
                            !v.scales.empty()))
            return name + ": a blocked component also holds per-vertex vectors";
        if (!c.blocked() && (!b.order.empty() || b.offsets.size() > 1 || !b.indices.empty() ||
                             !b.values.empty() || !b.scales.empty() || !b.shScales.empty() ||
                             b.shFrom != UINT32_MAX))
            return name + ": blocked arrays without blocked vertices";
        // SH scales start at the SH part (the file stores a flag, not the index).
        if (c.blocked() && b.shFrom != UINT32_MAX &&
            (f.shTerms == 0 || b.shFrom != 6 * f.cubemapSize * f.cubemapSize))
            return name + ": SH scales from index " + u64(b.shFrom) + " but the SH part " +
                   (f.shTerms == 0 ? std::string("is absent") : "starts at " + u64(6 * f.cubemapSize * f.cubemapSize));
        std::string reason = c.blocked() ? checkBlocked(b, f.mesh.vertexCount, f.cubemapSize, f.shTerms)
                                         : checkVectors(v, f.mesh.vertexCount, f.cubemapSize, f.shTerms);
        if (!reason.empty()) return name + ": " + reason;
    }
    if (componentIndex) *componentIndex = SIZE_MAX;
    if (terms.empty()) {
        if (f.viewMaps) return "view maps present but no single-scattering term components";
    } else {
        if (!f.viewMaps) return "single-scattering term components present but no view maps";
        std::string reason = checkViewMaps(*f.viewMaps);
        if (!reason.empty()) return reason;
        if (terms.size() != size_t(f.viewMaps->terms) || *terms.rbegin() != terms.size() - 1)
            return "single-scattering term components must be terms 0.." +
                   std::to_string(f.viewMaps->terms - 1) + " (one per view map), found " +
                   u64(terms.size()) + " with largest term " + u64(*terms.rbegin());
    }
    return {};
}

// ---------------------------------------------------------------------------------
// Writing
// ---------------------------------------------------------------------------------

class FileWriter {
public:
    FileWriter(int fd, std::string path, std::string tmpPath)
        : fd_(fd), path_(std::move(path)), tmpPath_(std::move(tmpPath)) {
        buffer_.reserve(kBufferBytes);
    }

    void write(const void* data, size_t n) {
        if (inSection_) crc_ = crcUpdate(crc_, data, n);
        const auto* p = static_cast<const uint8_t*>(data);
        pos_ += n;
        while (n > 0) {
            const size_t chunk = std::min(n, kBufferBytes - buffer_.size());
            buffer_.insert(buffer_.end(), p, p + chunk);
            p += chunk;
            n -= chunk;
            if (buffer_.size() == kBufferBytes) flush();
        }
    }

    void zeros(size_t n) {
        static const uint8_t kZeros[kAlignment] = {};
        while (n > 0) {
            const size_t chunk = std::min<size_t>(n, kAlignment);
            write(kZeros, chunk);
            n -= chunk;
        }
    }

    void u32(uint32_t v) {
        uint8_t b[4];
        putU32(b, v);
        write(b, 4);
    }
    void u64(uint64_t v) {
        uint8_t b[8];
        putU64(b, v);
        write(b, 8);
    }

    // Writes a whole array in little-endian order.
    template <class T>
    void array(const std::vector<T>& a) {
        if constexpr (std::endian::native == std::endian::little || sizeof(T) == 1) {
            write(a.data(), a.size() * sizeof(T));
        } else {
            std::vector<uint8_t> tmp;
            constexpr size_t kChunk = 1 << 16;
            for (size_t first = 0; first < a.size(); first += kChunk) {
                const size_t count = std::min(kChunk, a.size() - first);
                tmp.resize(count * sizeof(T));
                std::memcpy(tmp.data(), a.data() + first, count * sizeof(T));
                byteSwapElements(tmp.data(), count, sizeof(T));
                write(tmp.data(), tmp.size());
            }
        }
    }

    // Pads with zeros until the position relative to the payload start is `offset`.
    void padTo(uint64_t offset) {
        const uint64_t target = sectionStart_ + offset;
        if (target < pos_) throw std::logic_error("transport writer: layout overrun");
        zeros(size_t(target - pos_));
    }

    void beginSection(Section s, uint64_t payloadBytes) {
        zeros(size_t(paddingBefore(pos_)));
        crc_ = crc32(0L, Z_NULL, 0);
        inSection_ = true;
        write(tagOf(s), 4);
        u32(0);  // flags, none defined
        u64(payloadBytes);
        sectionStart_ = pos_;
        sectionBytes_ = payloadBytes;
    }

    void endSection() {
        if (pos_ - sectionStart_ != sectionBytes_)
            throw std::logic_error("transport writer: section length mismatch");
        inSection_ = false;
        u32(uint32_t(crc_));
    }

    void flush() {
        const uint8_t* p = buffer_.data();
        size_t n = buffer_.size();
        while (n > 0) {
            const ssize_t written = ::write(fd_, p, n);
            if (written < 0) {
                if (errno == EINTR) continue;
                throw Error(path_, "cannot write temporary file '" + tmpPath_ +
                                       "': " + std::strerror(errno));
            }
            p += written;
            n -= size_t(written);
        }
        buffer_.clear();
    }

private:
    static constexpr size_t kBufferBytes = size_t(1) << 20;
    int fd_;
    std::string path_, tmpPath_;
    std::vector<uint8_t> buffer_;
    uint64_t pos_ = 0;
    uLong crc_ = 0;
    bool inSection_ = false;
    uint64_t sectionStart_ = 0, sectionBytes_ = 0;
};

uint32_t formatVersionOf(const TransportFile& f) {
    const bool blocked = std::any_of(f.components.begin(), f.components.end(),
                                     [](const TransportComponent& c) { return c.blocked(); });
    if (f.shTerms > 0) return blocked ? kBlockVarintFormatVersion : kShFormatVersion;
    return blocked ? kBlockedFormatVersion : kFormatVersion;
}

void writeBlockedComponent(FileWriter& w, const TransportComponent& c, uint32_t version) {
    const BlockedRgbVectors& b = c.blocks;
    const bool varints = version >= kBlockVarintFormatVersion;
    const std::vector<uint8_t> stream = varints ? encodeBlockIndices(b) : std::vector<uint8_t>();
    const BlockedLayout l =
        blockedLayout(b.vertices, b.indexCount(), varints ? stream.size() : 2 * b.indexCount(), b.shFrom != UINT32_MAX);
    w.beginSection(Section::BlockedComponent, l.total);
    w.u32(uint32_t(c.kind));
    w.u32(c.term);
    w.u64(b.vertices);
    w.u64(b.blockCount());
    w.u64(b.indexCount());
    if (varints) {  // reserved, zero, before version 4
        w.u32(b.shFrom != UINT32_MAX ? 1 : 0);  // SH scales flag
        w.u32(0);
        w.u64(stream.size());
    }
    w.padTo(l.order);
    w.array(b.order);
    w.padTo(l.offsets);
    w.array(b.offsets);
    w.padTo(l.indices);
    if (varints)
        w.array(stream);
    else
        w.array(b.indices);
    w.padTo(l.values);
    w.array(b.values);
    w.padTo(l.scales);
    w.array(b.scales);
    if (b.shFrom != UINT32_MAX) {
        w.padTo(l.shScales);
        w.array(b.shScales);
    }
    w.endSection();
}

void writeFile(FileWriter& w, const TransportFile& f) {
    // Preamble.
    w.write(kMagic.data(), kMagic.size());
    w.u32(formatVersionOf(f));
    w.u32(kEndianMarker);

    // Header.
    w.beginSection(Section::Head, kHeadBytes);
    w.u32(f.cubemapSize);
    w.u32(uint32_t(f.components.size()));
    w.u64(f.mesh.vertexCount);
    w.u64(f.mesh.positionHash);
    w.u64(std::bit_cast<uint64_t>(f.mmPerUnit));
    w.u32(f.viewMaps ? 1u : 0u);
    w.u32(f.shTerms);  // reserved (0) before version 3
    w.endSection();

    // Parameters.
    uint64_t parameterBytes = 4;
    for (const auto& [key, value] : f.parameters) parameterBytes += 8 + key.size() + value.size();
    if (parameterBytes > kMaxParameterBytes)  // checked by saveTransportFile first
        throw std::logic_error("transport writer: parameters too large");
    w.beginSection(Section::Parameters, parameterBytes);
    w.u32(uint32_t(f.parameters.size()));
    for (const auto& [key, value] : f.parameters) {
        w.u32(uint32_t(key.size()));
        w.write(key.data(), key.size());
        w.u32(uint32_t(value.size()));
        w.write(value.data(), value.size());
    }
    w.endSection();

    // Components.
    for (const TransportComponent& c : f.components) {
        if (c.blocked()) {
            writeBlockedComponent(w, c, formatVersionOf(f));
            continue;
        }
        const uint64_t vertices = c.vectors.vertexCount();
        const uint64_t coefficients = c.vectors.coefficientCount();
        const ComponentLayout l = componentLayout(vertices, coefficients);
        w.beginSection(Section::Component, l.total);
        w.u32(uint32_t(c.kind));
        w.u32(c.term);
        w.u64(vertices);
        w.u64(coefficients);
        w.padTo(l.offsets);
        w.array(c.vectors.offsets);
        w.padTo(l.indices);
        w.array(c.vectors.indices);
        w.padTo(l.values);
        w.array(c.vectors.values);
        w.padTo(l.scales);
        w.array(c.vectors.scales);
        w.endSection();
    }

    // View maps.
    if (f.viewMaps) {
        const ViewMaps& m = *f.viewMaps;
        w.beginSection(Section::ViewMaps, viewMapsPayloadBytes(uint64_t(m.size), uint64_t(m.terms)));
        w.u32(uint32_t(m.size));
        w.u32(uint32_t(m.terms));
        w.padTo(kViewFixedBytes);
        w.array(m.data);
        w.endSection();
    }

    w.beginSection(Section::End, 0);
    w.endSection();
    w.flush();
}


// ---------------------------------------------------------------------------------
// Reading
// ---------------------------------------------------------------------------------

class FileReader {
public:
    explicit FileReader(const std::string& path) : path_(path) {
        std::error_code ec;
        const auto status = std::filesystem::status(path, ec);
        if (!std::filesystem::exists(status))
            throw Error(path, "no such file");
        if (std::filesystem::is_directory(status))
            throw Error(path, "is a directory, not a transport file");
        in_.open(path, std::ios::binary);
        if (!in_) throw Error(path, std::string("cannot open: ") + std::strerror(errno));
        in_.seekg(0, std::ios::end);
        const std::streamoff end = in_.tellg();
        if (end < 0) throw Error(path, "cannot determine the file size");
        size_ = uint64_t(end);
        in_.seekg(0, std::ios::beg);
    }

    const std::string& path() const { return path_; }
    uint64_t size() const { return size_; }
    uint64_t pos() const { return pos_; }
    uint64_t remaining() const { return size_ - pos_; }

    // Callers check n <= remaining() first; a short read here is an I/O error.
    void read(void* dst, uint64_t n) {
        if (n > remaining()) throw std::logic_error("transport reader: read past the end");
        auto* p = static_cast<char*>(dst);
        uint64_t left = n;
        while (left > 0) {
            const std::streamsize chunk =
                std::streamsize(std::min<uint64_t>(left, uint64_t(1) << 30));
            in_.read(p, chunk);
            if (in_.gcount() != chunk)
                throw Error(path_, "read error at offset " + u64(pos_ + (n - left)) +
                                       " (the file changed while reading?)");
            p += chunk;
            left -= uint64_t(chunk);
        }
        pos_ += n;
    }

    void skip(uint64_t n) {
        if (n > remaining()) throw std::logic_error("transport reader: skip past the end");
        pos_ += n;
        in_.seekg(std::streamoff(pos_), std::ios::beg);
        if (!in_) throw Error(path_, "seek error at offset " + u64(pos_));
    }

    [[noreturn]] void fail(const std::string& reason) const { throw Error(path_, reason); }

private:
    std::string path_;
    std::ifstream in_;
    uint64_t size_ = 0;
    uint64_t pos_ = 0;
};

struct OpenSection {
    Section kind = Section::Head;
    std::string label;
    uint64_t headerOffset = 0;
    uint64_t payloadOffset = 0;
    uint64_t length = 0;
    uint32_t flags = 0;
    uLong crc = 0;
    uint64_t consumed = 0;  // payload bytes read so far
};

// A section that may take the place of the expected one (a blocked component where a
// component is due), with its label. With a refusal it may not (a blocked component in
// a version-1 file): finding it fails with that reason, and messages do not offer it.
struct AlternativeSection {
    Section kind;
    std::string label;
    std::string refusal;
};

// Opens the next section, which must be `kind` or, if given, `alternative` (s.kind
// tells which was found).
OpenSection openSection(FileReader& r, Section kind, std::string label,
                        const AlternativeSection* alternative = nullptr) {
    OpenSection s;
    s.kind = kind;
    s.label = std::move(label);
    // What the messages call the section before its tag is known.
    const std::string expected = alternative && alternative->refusal.empty()
                                     ? s.label + " or " + alternative->label
                                     : s.label;
    const uint64_t pad = paddingBefore(r.pos());
    s.headerOffset = r.pos() + pad;
    if (r.remaining() < pad + kSectionHeaderBytes)
        r.fail("truncated: the file ends at byte " + u64(r.size()) + ", before the " +
               u64(kSectionHeaderBytes) + "-byte header of " + expected + " expected at offset " +
               u64(s.headerOffset));
    uint8_t buf[kAlignment + kSectionHeaderBytes];
    r.read(buf, pad + kSectionHeaderBytes);
    const uint8_t* h = buf + pad;
    const bool isKind = std::memcmp(h, tagOf(kind), 4) == 0;
    const bool isAlternative = alternative && std::memcmp(h, tagOf(alternative->kind), 4) == 0;
    if (isAlternative) {
        s.kind = alternative->kind;
        s.label = alternative->label;
    }
    if (!allZero(buf, size_t(pad)))
        r.fail("corrupt: non-zero padding bytes before " +
               (isKind || isAlternative ? s.label : expected) + " at offset " +
               u64(s.headerOffset - pad));
    if (isAlternative && !alternative->refusal.empty())
        r.fail("corrupt: " + s.label + " at offset " + u64(s.headerOffset) + ": " +
               alternative->refusal);
    if (!isKind && !isAlternative)
        r.fail("corrupt: expected " + expected + " at offset " + u64(s.headerOffset) +
               ", found tag " + printableTag(h));
    s.flags = getU32(h + 4);
    s.length = getU64(h + 8);
    s.payloadOffset = r.pos();
    if (s.length > r.remaining() || r.remaining() - s.length < kChecksumBytes) {
        const uint64_t need = s.length > UINT64_MAX - kChecksumBytes ? UINT64_MAX
                                                                     : s.length + kChecksumBytes;
        r.fail("truncated: " + s.label + " at offset " + u64(s.headerOffset) + " needs " +
               u64(need) + " bytes (payload and checksum) but only " + u64(r.remaining()) +
               " remain (or its length field is corrupt)");
    }
    s.crc = crcUpdate(crc32(0L, Z_NULL, 0), h, kSectionHeaderBytes);
    return s;
}

void readPayload(FileReader& r, OpenSection& s, void* dst, uint64_t n) {
    if (n > s.length - s.consumed) throw std::logic_error("transport reader: section overrun");
    r.read(dst, n);
    s.crc = crcUpdate(s.crc, dst, n);
    s.consumed += n;
}

// Reads the padding inside a payload up to relative offset `offset`; returns whether
// it was all zero (checked by the caller after the checksum).
bool readPaddingTo(FileReader& r, OpenSection& s, uint64_t offset) {
    if (offset < s.consumed || offset - s.consumed > kAlignment)
        throw std::logic_error("transport reader: bad padding");
    uint8_t buf[kAlignment];
    const uint64_t n = offset - s.consumed;
    readPayload(r, s, buf, n);
    return allZero(buf, size_t(n));
}

template <class T>
void readArray(FileReader& r, OpenSection& s, std::vector<T>& a, uint64_t count) {
    a.resize(size_t(count));
    readPayload(r, s, a.data(), count * sizeof(T));
    if constexpr (std::endian::native != std::endian::little && sizeof(T) > 1)
        byteSwapElements(reinterpret_cast<uint8_t*>(a.data()), a.size(), sizeof(T));
}

// Reads the stored checksum and compares it; then refuses unknown flags.
void closeSection(FileReader& r, OpenSection& s) {
    if (s.consumed != s.length) throw std::logic_error("transport reader: section underrun");
    uint8_t b[kChecksumBytes];
    r.read(b, kChecksumBytes);
    const uint32_t stored = getU32(b);
    const uint32_t computed = uint32_t(s.crc);
#ifndef FUZZING_BUILD_MODE_UNSAFE_FOR_PRODUCTION  // lets mutated files reach the checks behind it
    if (stored != computed)
        r.fail("checksum mismatch in " + s.label + " at offset " + u64(s.headerOffset) +
               " (stored " + hex32(stored) + ", computed " + hex32(computed) +
               "): the file is corrupt");
#else
    (void)stored, (void)computed;
#endif
    if (s.flags != 0)
        r.fail("unsupported: " + s.label + " has flags " + hex32(s.flags) +
               " (this build knows none)");
}

// The section's fixed part disagrees with its length or the header. If the
// checksum over the declared length also fails, that is what is reported (a flipped
// byte); otherwise the inconsistency is.
[[noreturn]] void failAfterChecksum(FileReader& r, OpenSection& s, const std::string& reason) {
    std::vector<uint8_t> buf;
    while (s.consumed < s.length) {
        const uint64_t n = std::min<uint64_t>(s.length - s.consumed, uint64_t(1) << 20);
        buf.resize(size_t(n));
        readPayload(r, s, buf.data(), n);
    }
    closeSection(r, s);
    r.fail("inconsistent: " + s.label + ": " + reason);
}

// Skips the rest of the payload and the checksum without verifying it (info mode).
void skipSection(FileReader& r, OpenSection& s) {
    r.skip(s.length - s.consumed + kChecksumBytes);
    s.consumed = s.length;
}

struct HeadFields {
    uint32_t version = 0;  // from the preamble
    uint32_t cubemapSize = 0;
    uint32_t shTerms = 0;
    uint32_t componentCount = 0;
    MeshFingerprint mesh;
    double mmPerUnit = 1.0;
    bool hasViewMaps = false;
};

// Returns the format version (1 to 4).
uint32_t readPreamble(FileReader& r) {
    const uint64_t size = r.size();
    if (size == 0) r.fail("truncated: the file is empty (not a transport file)");
    uint8_t b[kPreambleBytes];
    const uint64_t n = std::min(size, kPreambleBytes);
    r.read(b, n);
    if (std::memcmp(b, kMagic.data(), size_t(std::min<uint64_t>(n, 8))) != 0)
        r.fail("not a transport file (bad magic: expected \"PRTXPORT\")");
    if (n < kPreambleBytes)
        r.fail("truncated: the file is " + u64(size) + " bytes, the preamble alone needs " +
               u64(kPreambleBytes));
    const uint32_t version = getU32(b + 8);
    const uint32_t marker = getU32(b + 12);
    if (marker == 0x04030201u)
        r.fail("wrong byte order: the endianness marker reads 0x04030201, the file is "
               "big-endian; transport files are little-endian");
    if (marker != kEndianMarker)
        r.fail("bad endianness marker " + hex32(marker) + " (expected 0x01020304): corrupt file");
    if (version < kFormatVersion || version > kBlockVarintFormatVersion)
        r.fail("unsupported transport file format version " + u64(version) +
               " (this build reads versions " + u64(kFormatVersion) + " to " +
               u64(kBlockVarintFormatVersion) + ")");
    return version;
}

HeadFields readHead(FileReader& r, uint32_t version) {
    OpenSection s = openSection(r, Section::Head, sectionLabel(Section::Head));
    if (s.length != kHeadBytes)
        failAfterChecksum(r, s, "payload is " + u64(s.length) + " bytes, expected " +
                                    u64(kHeadBytes));
    uint8_t b[kHeadBytes];
    readPayload(r, s, b, kHeadBytes);
    closeSection(r, s);
    HeadFields h;
    h.version = version;
    h.cubemapSize = getU32(b);
    h.componentCount = getU32(b + 4);
    h.mesh.vertexCount = getU64(b + 8);
    h.mesh.positionHash = getU64(b + 16);
    h.mmPerUnit = std::bit_cast<double>(getU64(b + 24));
    const uint32_t viewFlag = getU32(b + 32);
    const uint32_t reserved = getU32(b + 36);
    const std::string where = "inconsistent: " + s.label + ": ";
    if (h.cubemapSize < 1 || h.cubemapSize > kMaxCubemapSize || !std::has_single_bit(h.cubemapSize))
        r.fail(where + "cubemap size " + u64(h.cubemapSize) + " is not a power of two in 1..64");
    if (h.mesh.vertexCount == 0 || h.mesh.vertexCount > kMaxVertices)
        r.fail(where + "vertex count " + u64(h.mesh.vertexCount) + " outside 1..2^40");
    if (!std::isfinite(h.mmPerUnit) || h.mmPerUnit <= 0.0)
        r.fail(where + "mm per unit is not a positive finite number");
    if (viewFlag > 1) r.fail(where + "view-map flag " + u64(viewFlag) + " is not 0 or 1");
    if (version >= kShFormatVersion) {
        if (reserved == 0 || !validShTermCount(reserved))
            r.fail(where + "SH term count " + u64(reserved) + " is not 1, 4 or 9 (format version " +
                   u64(version) + ")");
        h.shTerms = reserved;
        if (h.shTerms == 9 && h.cubemapSize < 2)
            r.fail(where + "9 SH terms on a 6 x 1 x 1 cubemap (they are not independent there)");
    } else if (reserved != 0) {
        r.fail(where + "reserved field is " + hex32(reserved) + ", not 0");
    }
    if (h.componentCount == 0) r.fail(where + "the file has no components");
    // (The component count is not used to reserve memory: components are read one
    // section at a time, so a wrong count fails at the first missing section.)
    h.hasViewMaps = viewFlag == 1;
    return h;
}

std::vector<std::pair<std::string, std::string>> readParameters(FileReader& r) {
    OpenSection s = openSection(r, Section::Parameters, sectionLabel(Section::Parameters));
    if (s.length > kMaxParameterBytes || s.length < 4)
        failAfterChecksum(r, s, "payload is " + u64(s.length) + " bytes, outside 4.." +
                                    u64(kMaxParameterBytes));
    std::vector<uint8_t> b(size_t(s.length));
    readPayload(r, s, b.data(), s.length);
    closeSection(r, s);
    const std::string where = "inconsistent: " + s.label + ": ";
    const uint64_t count = getU32(b.data());
    if (count > (s.length - 4) / 8)
        r.fail(where + u64(count) + " entries cannot fit in " + u64(s.length) + " bytes");
    std::vector<std::pair<std::string, std::string>> out;
    out.reserve(size_t(count));
    std::set<std::string> keys;
    uint64_t pos = 4;
    auto readString = [&](uint64_t entry) {
        if (s.length - pos < 4) r.fail(where + "entry " + u64(entry) + " runs past the end");
        const uint64_t len = getU32(b.data() + pos);
        pos += 4;
        if (len > s.length - pos) r.fail(where + "entry " + u64(entry) + " runs past the end");
        std::string str(reinterpret_cast<const char*>(b.data() + pos), size_t(len));
        pos += len;
        return str;
    };
    for (uint64_t i = 0; i < count; ++i) {
        std::string key = readString(i);
        std::string value = readString(i);
        if (key.empty()) r.fail(where + "entry " + u64(i) + " has an empty key");
        if (!keys.insert(key).second) r.fail(where + "parameter '" + key + "' appears twice");
        out.emplace_back(std::move(key), std::move(value));
    }
    if (pos != s.length)
        r.fail(where + u64(s.length - pos) + " unexpected bytes after the last entry");
    return out;
}

// The checks of a component's kind, term and reserved bytes (COMP and BLKC alike),
// made after the section's checksum.
void checkComponentHeader(FileReader& r, const OpenSection& s, uint32_t kind, uint32_t term,
                          bool reservedZero) {
    const std::string where = "inconsistent: " + s.label + ": ";
    if (!validKind(kind)) r.fail(where + "unknown component kind " + u64(kind));
    if (ComponentKind(kind) != ComponentKind::SingleScatteringTerm && term != 0)
        r.fail(where + "term " + u64(term) + " on a component that has no terms");
    if (!reservedZero) r.fail(where + "reserved header bytes are not zero");
}

// Reads the rest of a BLKC section opened by readComponent.
TransportComponent readBlockedComponent(FileReader& r, OpenSection& s, const HeadFields& h,
                                        bool infoOnly, TransportFileInfo::Component* info) {
    if (s.length < kBlockedFixedBytes)
        failAfterChecksum(r, s, "payload is " + u64(s.length) + " bytes, less than the " +
                                    u64(kBlockedFixedBytes) + "-byte blocked component header");
    uint8_t b[kBlockedFixedBytes];
    readPayload(r, s, b, kBlockedFixedBytes);
    const uint32_t kind = getU32(b);
    const uint32_t term = getU32(b + 4);
    const uint64_t vertices = getU64(b + 8);
    const uint64_t blocks = getU64(b + 16);
    const uint64_t indices = getU64(b + 24);
    // Version 4 flags SH scales at 32 (0 or 1) and gives the index stream's bytes at 40;
    // versions 2 and 3 reserve both (16-bit indices).
    const bool varints = h.version >= kBlockVarintFormatVersion;
    const uint32_t shScalesFlag = varints ? getU32(b + 32) : 0;
    const uint64_t streamBytes = varints ? getU64(b + 40) : 0;
    const bool reservedZero = varints ? allZero(b + 36, 4) && allZero(b + 48, size_t(kBlockedFixedBytes - 48))
                                      : allZero(b + 32, size_t(kBlockedFixedBytes - 32));

    auto fail = [&](const std::string& reason) {
        if (infoOnly) r.fail("inconsistent: " + s.label + ": " + reason);
        failAfterChecksum(r, s, reason);
    };
    if (shScalesFlag > 1) fail("SH scales flag " + u64(shScalesFlag) + " is not 0 or 1");
    const bool shScales = shScalesFlag == 1;
    // The vertex count is bounded by the header's (<= 2^40), the index count by 2^32,
    // so the layout cannot overflow and its total is checked against the section
    // length (itself within the file) before anything is allocated.
    if (vertices != h.mesh.vertexCount)
        fail("has " + u64(vertices) + " vertices, the header says " + u64(h.mesh.vertexCount));
    if (vertices > UINT32_MAX)
        fail(u64(vertices) + " vertices exceed the 32-bit block order");
    if (blocks != blockCountOf(vertices))
        fail(u64(blocks) + " blocks for " + u64(vertices) + " vertices, expected " +
             u64(blockCountOf(vertices)) + " (16 per block)");
    if (indices > UINT32_MAX) fail(u64(indices) + " indices exceed the 32-bit offsets");
    // A varint takes 1 to 3 bytes per index (bounds the stream before the layout).
    if (varints && (streamBytes < indices || streamBytes > 3 * indices))
        fail("index stream of " + u64(streamBytes) + " bytes for " + u64(indices) +
             " indices (1 to 3 bytes each)");
    const BlockedLayout l = blockedLayout(vertices, indices, varints ? streamBytes : 2 * indices, shScales);
    if (l.total != s.length)
        fail(u64(vertices) + " vertices and " + u64(indices) + " block indices need a " +
             u64(l.total) + "-byte payload, the section has " + u64(s.length));

    TransportComponent c;
    c.kind = ComponentKind(kind);
    c.term = term;
    std::vector<uint8_t> stream;  // version 4: the varint-coded indices
    if (info) *info = {ComponentKind(kind), term, vertices, indices, s.length, true, blocks, shScales};
    if (infoOnly) {
        skipSection(r, s);
    } else {
        BlockedRgbVectors& v = c.blocks;
        v.vertices = vertices;
        bool paddingZero = readPaddingTo(r, s, l.order);
        readArray(r, s, v.order, vertices);
        paddingZero &= readPaddingTo(r, s, l.offsets);
        readArray(r, s, v.offsets, blocks + 1);
        paddingZero &= readPaddingTo(r, s, l.indices);
        if (varints)
            readArray(r, s, stream, streamBytes);
        else
            readArray(r, s, v.indices, indices);
        paddingZero &= readPaddingTo(r, s, l.values);
        readArray(r, s, v.values, indices * kBlockValuesPerIndex);
        paddingZero &= readPaddingTo(r, s, l.scales);
        readArray(r, s, v.scales, blocks * kBlockValuesPerIndex);
        if (shScales) {
            v.shFrom = 6 * h.cubemapSize * h.cubemapSize;
            paddingZero &= readPaddingTo(r, s, l.shScales);
            readArray(r, s, v.shScales, blocks * kBlockValuesPerIndex);
        }
        closeSection(r, s);
        if (!paddingZero) r.fail("inconsistent: " + s.label + ": non-zero padding between arrays");
    }
    checkComponentHeader(r, s, kind, term, reservedZero);
    if (!infoOnly) {
        BlockedRgbVectors& v = c.blocks;
        if (varints) {
            // Decoding walks the blocks by their offsets: with bad offsets, leave M zero
            // indices for checkBlocked to name the offsets' fault.
            const bool offsetsGood = v.offsets.front() == 0 && v.offsets.back() == indices &&
                                     std::is_sorted(v.offsets.begin(), v.offsets.end());
            if (offsetsGood) {
                const std::string reason = decodeBlockIndices(stream.data(), stream.size(), v.offsets, v.indices);
                if (!reason.empty()) r.fail("inconsistent: " + s.label + ": " + reason);
            } else {
                v.indices.assign(indices, 0);
            }
        }
        const std::string reason = checkBlocked(c.blocks, vertices, h.cubemapSize, h.shTerms);
        if (!reason.empty()) r.fail("inconsistent: " + s.label + ": " + reason);
        c.blocks.indexSlots();
    }
    return c;
}

// Reads one component section: COMP, or from version 2 on also BLKC. In info mode
// only the fixed part is read and the arrays are skipped (the returned vectors are
// left empty).
TransportComponent readComponent(FileReader& r, const HeadFields& h, size_t index, bool infoOnly,
                                 TransportFileInfo::Component* info) {
    const AlternativeSection blocked{
        Section::BlockedComponent,
        sectionLabel(Section::BlockedComponent, index, h.componentCount),
        h.version >= kBlockedFormatVersion
            ? std::string()
            : "a blocked component in a format version " + u64(h.version) +
                  " file (blocked components need version " + u64(kBlockedFormatVersion) + ")"};
    OpenSection s = openSection(r, Section::Component,
                                sectionLabel(Section::Component, index, h.componentCount), &blocked);
    if (s.kind == Section::BlockedComponent) return readBlockedComponent(r, s, h, infoOnly, info);
    if (s.length < kComponentFixedBytes)
        failAfterChecksum(r, s, "payload is " + u64(s.length) + " bytes, less than the " +
                                    u64(kComponentFixedBytes) + "-byte component header");
    uint8_t b[kComponentFixedBytes];
    readPayload(r, s, b, kComponentFixedBytes);
    const uint32_t kind = getU32(b);
    const uint32_t term = getU32(b + 4);
    const uint64_t vertices = getU64(b + 8);
    const uint64_t coefficients = getU64(b + 16);
    const bool reservedZero = allZero(b + 24, size_t(kComponentFixedBytes - 24));

    auto fail = [&](const std::string& reason) {
        if (infoOnly) r.fail("inconsistent: " + s.label + ": " + reason);
        failAfterChecksum(r, s, reason);
    };
    if (vertices != h.mesh.vertexCount)
        fail("has " + u64(vertices) + " vertices, the header says " + u64(h.mesh.vertexCount));
    if (coefficients > UINT32_MAX)
        fail(u64(coefficients) + " coefficients exceed the 32-bit offsets");
    const ComponentLayout l = componentLayout(vertices, coefficients);
    if (l.total != s.length)
        fail(u64(vertices) + " vertices and " + u64(coefficients) + " coefficients need a " +
             u64(l.total) + "-byte payload, the section has " + u64(s.length));

    TransportComponent c;
    c.kind = ComponentKind(kind);
    c.term = term;
    if (info) *info = {ComponentKind(kind), term, vertices, coefficients, s.length};
    if (infoOnly) {
        skipSection(r, s);
    } else {
        bool paddingZero = readPaddingTo(r, s, l.offsets);
        readArray(r, s, c.vectors.offsets, vertices + 1);
        paddingZero &= readPaddingTo(r, s, l.indices);
        readArray(r, s, c.vectors.indices, coefficients);
        paddingZero &= readPaddingTo(r, s, l.values);
        readArray(r, s, c.vectors.values, 3 * coefficients);
        paddingZero &= readPaddingTo(r, s, l.scales);
        readArray(r, s, c.vectors.scales, 3 * vertices);
        closeSection(r, s);
        if (!paddingZero) r.fail("inconsistent: " + s.label + ": non-zero padding between arrays");
    }
    checkComponentHeader(r, s, kind, term, reservedZero);
    if (!infoOnly) {
        const std::string reason = checkVectors(c.vectors, vertices, h.cubemapSize, h.shTerms);
        if (!reason.empty()) r.fail("inconsistent: " + s.label + ": " + reason);
    }
    return c;
}

// A version-2 or -4 file without a blocked component is refused: the writer writes such
// a file as version 1 or 3, so this is a corrupted version field. (A version-3 file with
// one is what the writer wrote before version 4, and is read as such.)
void checkVersionMatchesComponents(FileReader& r, const HeadFields& h, bool anyBlocked) {
    if ((h.version == kBlockedFormatVersion || h.version == kBlockVarintFormatVersion) && !anyBlocked)
        r.fail("inconsistent: format version " + u64(h.version) +
               " but no blocked component (a file without one is version " +
               u64(h.version == kBlockedFormatVersion ? kFormatVersion : kShFormatVersion) + ")");
}

ViewMaps readViewMaps(FileReader& r, bool infoOnly) {
    OpenSection s = openSection(r, Section::ViewMaps, sectionLabel(Section::ViewMaps));
    if (s.length < kViewFixedBytes)
        failAfterChecksum(r, s, "payload is " + u64(s.length) + " bytes, less than the " +
                                    u64(kViewFixedBytes) + "-byte view-map header");
    uint8_t b[kViewFixedBytes];
    readPayload(r, s, b, kViewFixedBytes);
    const uint32_t size = getU32(b);
    const uint32_t terms = getU32(b + 4);
    const bool reservedZero = allZero(b + 8, size_t(kViewFixedBytes - 8));
    auto fail = [&](const std::string& reason) {
        if (infoOnly) r.fail("inconsistent: " + s.label + ": " + reason);
        failAfterChecksum(r, s, reason);
    };
    if (size < 1 || size > kMaxViewMapSize)
        fail("map size " + u64(size) + " outside 1.." + u64(kMaxViewMapSize));
    if (terms < 1 || terms > kMaxViewMapTerms)
        fail("term count " + u64(terms) + " outside 1.." + u64(kMaxViewMapTerms));
    const uint64_t expected = viewMapsPayloadBytes(size, terms);
    if (expected != s.length)
        fail(u64(terms) + " maps of 6 x " + u64(size) + " x " + u64(size) + " need a " +
             u64(expected) + "-byte payload, the section has " + u64(s.length));
    ViewMaps m;
    m.size = int(size);
    m.terms = int(terms);
    if (infoOnly) {
        skipSection(r, s);
    } else {
        readArray(r, s, m.data, uint64_t(terms) * 6 * size * size);
        closeSection(r, s);
    }
    if (!reservedZero) r.fail("inconsistent: " + s.label + ": reserved header bytes are not zero");
    return m;
}

void readEnd(FileReader& r) {
    OpenSection s = openSection(r, Section::End, sectionLabel(Section::End));
    if (s.length != 0)
        failAfterChecksum(r, s, "payload is " + u64(s.length) + " bytes, expected 0");
    closeSection(r, s);
    if (r.remaining() != 0)
        r.fail("corrupt: " + u64(r.remaining()) + " unexpected bytes after the end marker at offset " +
               u64(r.pos()));
}

void checkFingerprint(FileReader& r, const MeshFingerprint& stored,
                      const MeshFingerprint& expected) {
    if (stored == expected) return;
    r.fail("transport file was made for a mesh with " + u64(stored.vertexCount) +
           " vertices (position hash " + hex64(stored.positionHash) + "), this mesh has " +
           u64(expected.vertexCount) + " vertices (position hash " +
           hex64(expected.positionHash) + ")");
}

std::string findParameter(const std::vector<std::pair<std::string, std::string>>& parameters,
                          const std::string& key);
bool containsParameter(const std::vector<std::pair<std::string, std::string>>& parameters,
                       const std::string& key);

TransportFile loadImpl(const std::string& path, const MeshFingerprint* expected) {
    FileReader r(path);
    const uint32_t version = readPreamble(r);
    const HeadFields h = readHead(r, version);
    if (expected) checkFingerprint(r, h.mesh, *expected);
    TransportFile f;
    f.cubemapSize = h.cubemapSize;
    f.shTerms = h.shTerms;
    f.mesh = h.mesh;
    f.mmPerUnit = h.mmPerUnit;
    f.parameters = readParameters(r);
    if (expected && containsParameter(f.parameters, kShardParameter))
        throw Error(path, "is shard " + findParameter(f.parameters, kShardParameter) + " (vertices " +
                              findParameter(f.parameters, kShardVerticesParameter) +
                              ") of a sharded precompute, not a whole transport file: join the shards with "
                              "prt-merge");
    for (size_t i = 0; i < h.componentCount; ++i)
        f.components.push_back(readComponent(r, h, i, false, nullptr));
    checkVersionMatchesComponents(
        r, h, std::any_of(f.components.begin(), f.components.end(), [](const auto& c) { return c.blocked(); }));
    if (h.hasViewMaps) f.viewMaps = readViewMaps(r, false);
    readEnd(r);
    size_t bad = SIZE_MAX;
    const std::string reason = checkFile(f, &bad);
    if (!reason.empty()) r.fail("inconsistent: " + reason);
    return f;
}

std::string findParameter(const std::vector<std::pair<std::string, std::string>>& parameters,
                          const std::string& key) {
    for (const auto& [k, v] : parameters)
        if (k == key) return v;
    return {};
}

bool containsParameter(const std::vector<std::pair<std::string, std::string>>& parameters,
                       const std::string& key) {
    return std::any_of(parameters.begin(), parameters.end(),
                       [&](const auto& p) { return p.first == key; });
}

std::string bytesPerVertex(uint64_t bytes, uint64_t vertices) {
    char buf[48];
    std::snprintf(buf, sizeof buf, "%.1f B per vertex",
                  vertices ? double(bytes) / double(vertices) : 0.0);
    return buf;
}

// "100000 vertices, blocked: 6250 blocks of 16 sharing 1200000 indices (192.0 mean,
// 192 max per block), 55.0 MiB (576.2 B per vertex)"; the max only when known; ", SH
// part scaled apart" when the block has SH scales.
// `where` says which bytes: a loaded file counts its in-memory arrays (u16 indices), the
// header-only describe its on-disk payload (varint deltas in version 4, so smaller).
std::string describeBlocked(uint64_t vertices, uint64_t blocks, uint64_t indices,
                            const uint64_t* maxPerBlock, uint64_t bytes, bool shScales,
                            const char* where) {
    const double mean = blocks ? double(indices) / double(blocks) : 0.0;
    char stats[96];
    if (maxPerBlock)
        std::snprintf(stats, sizeof stats, "%.1f mean, %" PRIu64 " max per block", mean,
                      *maxPerBlock);
    else
        std::snprintf(stats, sizeof stats, "%.1f mean per block", mean);
    return u64(vertices) + " vertices, blocked: " + u64(blocks) + " blocks of " +
           u64(kVertexBlock) + " sharing " + u64(indices) + " indices (" + stats + ")" +
           (shScales ? ", SH part scaled apart" : "") + ", " + formatBytes(bytes) + " " + where +
           " (" + bytesPerVertex(bytes, vertices) + ")";
}

void describeCommon(std::string& out, uint32_t n, uint32_t shTerms, const MeshFingerprint& mesh,
                    double mmPerUnit, const std::vector<std::pair<std::string, std::string>>& parameters) {
    out += "cubemap: 6 x " + u64(n) + " x " + u64(n) + " (" + u64(uint64_t(6) * n * n) +
           " Haar coefficients)\n";
    out += shTerms ? "SH part: " + u64(shTerms) + " terms per vector (indices " + u64(uint64_t(6) * n * n) +
                         ".." + u64(uint64_t(6) * n * n + shTerms - 1) + ")\n"
                   : "SH part: none\n";
    out += "mesh: " + u64(mesh.vertexCount) + " vertices, position hash " +
           hex64(mesh.positionHash) + ", " + formatDouble(mmPerUnit) + " mm per unit\n";
    out += "parameters (" + u64(parameters.size()) + "):\n";
    for (const auto& [k, v] : parameters) out += "  " + k + " = " + v + "\n";
}

}  // namespace

// ---------------------------------------------------------------------------------
// Public API
// ---------------------------------------------------------------------------------

std::string componentName(ComponentKind kind, uint32_t term) {
    switch (kind) {
        case ComponentKind::MultipleScattering: return "multiple scattering";
        case ComponentKind::SingleScatteringIsotropic: return "single scattering (isotropic)";
        case ComponentKind::SingleScatteringTerm:
            return "single scattering term " + std::to_string(term);
    }
    return "unknown component kind " + std::to_string(uint32_t(kind));
}

void SparseRgbVectors::appendVertex(std::span<const uint32_t> idx, std::span<const float> rgb) {
    const std::string subject = "transport vectors";
    if (rgb.size() != 3 * idx.size())
        throw Error(subject, "appendVertex got " + u64(idx.size()) + " indices but " +
                                 u64(rgb.size()) + " values (expected 3 per index)");
    if (offsets.empty()) offsets.push_back(0);
    if (uint64_t(indices.size()) + idx.size() > UINT32_MAX)
        throw Error(subject, "more than 2^32 - 1 coefficients in one component");
    for (uint32_t i : idx)
        if (i > UINT16_MAX)
            throw Error(subject, "coefficient index " + u64(i) + " does not fit 16 bits");
    for (float x : rgb)
        if (!std::isfinite(x)) throw Error(subject, "appendVertex got a non-finite value");

    // Sort by index (only when needed), refusing duplicates.
    std::vector<uint32_t> order(idx.size());
    std::iota(order.begin(), order.end(), 0u);
    if (!std::is_sorted(idx.begin(), idx.end()))
        std::sort(order.begin(), order.end(), [&](uint32_t a, uint32_t b) { return idx[a] < idx[b]; });
    for (size_t k = 1; k < order.size(); ++k)
        if (idx[order[k]] == idx[order[k - 1]])
            throw Error(subject, "coefficient index " + u64(idx[order[k]]) + " appears twice");

    float scale[3];
    for (int c = 0; c < 3; ++c) {
        float maxAbs = 0.0f;
        for (size_t k = 0; k < idx.size(); ++k) maxAbs = std::max(maxAbs, std::fabs(rgb[3 * k + c]));
        // A channel whose maximum is below 32767 * FLT_MIN (its scale would be
        // subnormal) is flushed to zero: scale 0, absolute error < 4e-34.
        scale[c] = double(maxAbs) < kQuantMax * double(std::numeric_limits<float>::min())
                       ? 0.0f
                       : float(double(maxAbs) / kQuantMax);
    }
    const size_t base = indices.size();
    indices.resize(base + idx.size());
    values.resize(3 * (base + idx.size()));
    for (size_t k = 0; k < order.size(); ++k) {
        const uint32_t src = order[k];
        indices[base + k] = uint16_t(idx[src]);
        for (int c = 0; c < 3; ++c) {
            int q = 0;
            if (scale[c] > 0.0f) {
                const double r = std::nearbyint(double(rgb[3 * src + c]) / double(scale[c]));
                q = int(std::clamp(r, double(-kQuantMax), double(kQuantMax)));
            }
            values[3 * (base + k) + c] = int16_t(q);
        }
    }
    scales.insert(scales.end(), scale, scale + 3);
    offsets.push_back(uint32_t(indices.size()));
}

void SparseRgbVectors::dequantizeVertex(size_t v, std::vector<uint32_t>& idx,
                                        std::vector<float>& rgb) const {
    if (v >= vertexCount())
        throw std::out_of_range("SparseRgbVectors::dequantizeVertex: vertex " + u64(v) +
                                " of " + u64(vertexCount()));
    const uint32_t begin = offsets[v], end = offsets[v + 1];
    idx.assign(indices.begin() + begin, indices.begin() + end);
    rgb.resize(3 * size_t(end - begin));
    for (uint32_t n = begin; n < end; ++n)
        for (int c = 0; c < 3; ++c)
            rgb[3 * size_t(n - begin) + c] = float(values[3 * size_t(n) + c]) * scales[3 * v + c];
}

void SparseRgbVectors::reserve(size_t vertices, size_t coefficients) {
    offsets.reserve(vertices + 1);
    scales.reserve(3 * vertices);
    indices.reserve(coefficients);
    values.reserve(3 * coefficients);
}

void SparseRgbVectors::clear() {
    offsets.assign(1, 0);
    indices.clear();
    values.clear();
    scales.clear();
}

size_t SparseRgbVectors::byteSize() const {
    return offsets.size() * sizeof(uint32_t) + indices.size() * sizeof(uint16_t) +
           values.size() * sizeof(int16_t) + scales.size() * sizeof(float);
}

const TransportComponent* TransportFile::find(ComponentKind kind, uint32_t term) const {
    for (const TransportComponent& c : components)
        if (c.kind == kind && c.term == term) return &c;
    return nullptr;
}

std::string TransportFile::parameter(const std::string& key) const {
    return findParameter(parameters, key);
}
bool TransportFile::hasParameter(const std::string& key) const {
    return containsParameter(parameters, key);
}
std::string TransportFileInfo::parameter(const std::string& key) const {
    return findParameter(parameters, key);
}
bool TransportFileInfo::hasParameter(const std::string& key) const {
    return containsParameter(parameters, key);
}

void saveTransportFile(const std::string& path, const TransportFile& file) {
    const std::string reason = checkFile(file);
    if (!reason.empty()) throw Error(path, "invalid transport data: " + reason);
    uint64_t parameterBytes = 4;
    for (const auto& [key, value] : file.parameters) parameterBytes += 8 + key.size() + value.size();
    if (parameterBytes > kMaxParameterBytes)
        throw Error(path, "invalid transport data: parameters take " + u64(parameterBytes) +
                              " bytes (limit " + u64(kMaxParameterBytes) + ")");

    std::error_code ec;
    if (std::filesystem::is_directory(path, ec))
        throw Error(path, "is a directory; cannot write a transport file there");

    writeAtomically(path, [&](const std::string& tmpPath) {
        const int fd = ::open(tmpPath.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0666);
        if (fd < 0)
            throw Error(path, "cannot create temporary file '" + tmpPath + "': " + std::strerror(errno));
        try {
            FileWriter writer(fd, path, tmpPath);
            writeFile(writer, file);
        } catch (...) {
            ::close(fd);
            throw;
        }
        if (::close(fd) != 0)
            throw Error(path, "cannot close temporary file '" + tmpPath + "': " + std::strerror(errno));
    });
}

TransportFile loadTransportFile(const std::string& path) { return loadImpl(path, nullptr); }

TransportFile loadTransportFile(const std::string& path, const MeshFingerprint& expected) {
    return loadImpl(path, &expected);
}

TransportFileInfo readTransportFileInfo(const std::string& path) {
    FileReader r(path);
    const uint32_t version = readPreamble(r);
    const HeadFields h = readHead(r, version);
    TransportFileInfo info;
    info.version = version;
    info.cubemapSize = h.cubemapSize;
    info.shTerms = h.shTerms;
    info.mesh = h.mesh;
    info.mmPerUnit = h.mmPerUnit;
    info.fileBytes = r.size();
    info.parameters = readParameters(r);
    for (size_t i = 0; i < h.componentCount; ++i) {
        TransportFileInfo::Component c;
        readComponent(r, h, i, true, &c);
        info.components.push_back(c);
    }
    checkVersionMatchesComponents(
        r, h, std::any_of(info.components.begin(), info.components.end(), [](const auto& c) { return c.blocked; }));
    if (h.hasViewMaps) {
        const ViewMaps m = readViewMaps(r, true);
        info.viewMapSize = m.size;
        info.viewMapTerms = m.terms;
    }
    readEnd(r);
    return info;
}

std::string describe(const TransportFile& file) {
    std::string out = "transport file\n";
    describeCommon(out, file.cubemapSize, file.shTerms, file.mesh, file.mmPerUnit, file.parameters);
    out += "components (" + u64(file.components.size()) + "):\n";
    uint64_t total = 0;
    for (const TransportComponent& c : file.components) {
        if (c.blocked()) {
            const BlockedRgbVectors& b = c.blocks;
            uint64_t maxPerBlock = 0;
            for (size_t k = 0; k < b.blockCount(); ++k)
                maxPerBlock = std::max<uint64_t>(maxPerBlock, b.offsets[k + 1] - b.offsets[k]);
            out += "  " + componentName(c.kind, c.term) + ": " +
                   describeBlocked(b.vertexCount(), b.blockCount(), b.indexCount(), &maxPerBlock,
                                   b.byteSize(), b.shFrom != UINT32_MAX, "in memory") +
                   "\n";
            total += b.byteSize();
            continue;
        }
        const SparseRgbVectors& v = c.vectors;
        uint64_t maxPerVertex = 0;
        for (size_t i = 0; i < v.vertexCount(); ++i)
            maxPerVertex = std::max<uint64_t>(maxPerVertex, v.offsets[i + 1] - v.offsets[i]);
        const double mean =
            v.vertexCount() ? double(v.coefficientCount()) / double(v.vertexCount()) : 0.0;
        char stats[96];
        std::snprintf(stats, sizeof stats, "%.1f mean, %" PRIu64 " max per vertex", mean,
                      maxPerVertex);
        out += "  " + componentName(c.kind, c.term) + ": " + u64(v.vertexCount()) +
               " vertices, " + u64(v.coefficientCount()) + " coefficients (" + stats + "), " +
               formatBytes(v.byteSize()) + " in memory (" + bytesPerVertex(v.byteSize(), v.vertexCount()) +
               ")\n";
        total += v.byteSize();
    }
    if (file.viewMaps)
        out += "view maps: " + std::to_string(file.viewMaps->terms) + " terms of 6 x " +
               std::to_string(file.viewMaps->size) + " x " + std::to_string(file.viewMaps->size) +
               "\n";
    else
        out += "view maps: none\n";
    out += "total: " + formatBytes(total) + " of vectors in memory\n";
    return out;
}

std::string describe(const TransportFileInfo& info) {
    std::string out = "transport file, format version " + u64(info.version) + ", " +
                      formatBytes(info.fileBytes) + "\n";
    describeCommon(out, info.cubemapSize, info.shTerms, info.mesh, info.mmPerUnit, info.parameters);
    out += "components (" + u64(info.components.size()) + "):\n";
    for (const TransportFileInfo::Component& c : info.components) {
        if (c.blocked) {
            out += "  " + componentName(c.kind, c.term) + ": " +
                   describeBlocked(c.vertexCount, c.blockCount, c.coefficientCount, nullptr,
                                   c.payloadBytes, c.shScales, "on disk") +
                   "\n";
            continue;
        }
        const double mean =
            c.vertexCount ? double(c.coefficientCount) / double(c.vertexCount) : 0.0;
        char stats[64];
        std::snprintf(stats, sizeof stats, "%.1f mean per vertex", mean);
        out += "  " + componentName(c.kind, c.term) + ": " + u64(c.vertexCount) + " vertices, " +
               u64(c.coefficientCount) + " coefficients (" + stats + "), " +
               formatBytes(c.payloadBytes) + " on disk (" + bytesPerVertex(c.payloadBytes, c.vertexCount) +
               ")\n";
    }
    if (info.viewMapTerms > 0)
        out += "view maps: " + std::to_string(info.viewMapTerms) + " terms of 6 x " +
               std::to_string(info.viewMapSize) + " x " + std::to_string(info.viewMapSize) + "\n";
    else
        out += "view maps: none\n";
    return out;
}

}  // namespace prt
