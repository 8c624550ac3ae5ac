#pragma once
// Private to the transport-file implementation (transport_file*.cpp): the on-disk
// layout that the writer and the readers share, and the validation of the in-memory
// model that both apply. These constants and layout functions are the single source
// of truth for the byte layout of docs/transport-format.md ("Byte layout"); callers
// use common/transport_file.h.

#include <zlib.h>

#include <algorithm>
#include <array>
#include <cinttypes>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "common/sh_part.h"
#include "common/transport_file.h"

namespace prt::transport_format {

inline constexpr std::array<char, 8> kMagic = {'P', 'R', 'T', 'X', 'P', 'O', 'R', 'T'};

// The preamble's version field. The writer picks the lowest version that can hold the
// file (formatVersionOf), so a file without blocked components or SH terms stays
// version 1 byte for byte; a reader accepts 1..5 and refuses a version that disagrees
// with the sections (docs/transport-format.md, "Compatibility").
inline constexpr uint32_t kFormatVersion = 1;             // per-vertex components (COMP) only
inline constexpr uint32_t kBlockedFormatVersion = 2;      // + blocked components (BLKC)
inline constexpr uint32_t kShFormatVersion = 3;           // + SH term count in HEAD (indices < 6 N^2 + S)
inline constexpr uint32_t kBlockVarintFormatVersion = 4;  // + varint BLKC indices and SH scales
// + the radial basis (RBAS) and profile components (kind 4); the SH term count may be 0.
inline constexpr uint32_t kRadialFormatVersion = 5;
// + COMP flags: 8-bit Haar values with SH scales, offsets and indices shared with the
// component before (the profile components of an editable file).
inline constexpr uint32_t kEightBitFormatVersion = 6;
// + blocked profile components with index lists of their own per block (nested lists,
// common/blocked_vectors.h jointTruncateNested); nothing else in the layout changes.
inline constexpr uint32_t kNestedListsFormatVersion = 7;
inline constexpr uint32_t kNewestFormatVersion = kNestedListsFormatVersion;
inline constexpr int kEightBitLevels = 127;  // 8-bit values: [-127, 127]
// COMP flags (format version 6; reserved zero before).
inline constexpr uint32_t kCompEightBitHaar = 1;      // values: int8 Haar, int16 SH; SH scales
inline constexpr uint32_t kCompSharedIndices = 2;     // no offsets or indices: the previous COMP's

inline constexpr uint32_t kEndianMarker = 0x01020304u;
inline constexpr uint64_t kAlignment = 64;  // every section payload and array starts at a multiple
inline constexpr uint64_t kPreambleBytes = 16;
inline constexpr uint64_t kSectionHeaderBytes = 16;  // tag, flags, payload length
inline constexpr uint64_t kChecksumBytes = 4;
inline constexpr uint64_t kHeadBytes = 40;
inline constexpr uint64_t kComponentFixedBytes = 64;
inline constexpr uint64_t kBlockedFixedBytes = 64;
inline constexpr uint64_t kViewFixedBytes = 64;
// RBAS: 72 bytes of fields (range, J, N, construction, reserved, norm exponent), then
// reserved zeros so that the table starts 64-byte aligned like every other array.
inline constexpr uint64_t kRadialFieldBytes = 72;
inline constexpr uint64_t kRadialFixedBytes = 128;
// The bounds RadialBasis's constructor accepts (common/radial_basis.h), checked on the
// fixed part before the table is sized from it.
inline constexpr uint32_t kMaxRadialProfiles = 64;
inline constexpr uint32_t kMinRadialNodes = 2;
inline constexpr uint32_t kMaxRadialNodes = 1000000;
inline constexpr uint64_t kMaxParameterBytes = uint64_t(16) << 20;
inline constexpr uint32_t kMaxCubemapSize = 64;
inline constexpr uint64_t kMaxVertices = uint64_t(1) << 40;
inline constexpr uint32_t kMaxViewMapSize = 4096;
inline constexpr uint32_t kMaxViewMapTerms = 4096;

// The sections, in file order.
enum class Section { Head, Parameters, Component, BlockedComponent, ViewMaps, RadialBasis, End };

inline const char* tagOf(Section s) {
    switch (s) {
        case Section::Head: return "HEAD";
        case Section::Parameters: return "PARM";
        case Section::Component: return "COMP";
        case Section::BlockedComponent: return "BLKC";
        case Section::ViewMaps: return "VIEW";
        case Section::RadialBasis: return "RBAS";
        case Section::End: return "END ";
    }
    return "????";
}

// ---- layout ---------------------------------------------------------------------

inline uint64_t alignUp(uint64_t x) { return (x + kAlignment - 1) / kAlignment * kAlignment; }

// Zero bytes before a section header at file offset pos so that the section's payload
// starts at a multiple of kAlignment.
inline uint64_t paddingBefore(uint64_t pos) {
    return (kAlignment - (pos + kSectionHeaderBytes) % kAlignment) % kAlignment;
}

// Byte offsets, relative to the payload start, of a COMP section's arrays. With
// kCompSharedIndices there are no offsets or indices (offsets = indices = 0); with
// kCompEightBitHaar the indices are a varint stream of indexBytes bytes (the coding of
// blocked_vectors.h's encodeIndexLists, per vertex), the values are the Haar values as
// int8 (3 per Haar coefficient), then at shValues the SH values as int16 (3 per SH
// coefficient), and after the scales the SH scales when the file has SH terms
// (shScales > 0).
struct ComponentLayout {
    uint64_t offsets = 0, indices = 0, values = 0, shValues = 0, scales = 0, shScales = 0, total = 0;
};

// Requires vertices <= kMaxVertices, shCoefficients <= coefficients <= UINT32_MAX and
// indexBytes <= 3 coefficients (no overflow). shCoefficients, withShScales and
// indexBytes only count with kCompEightBitHaar.
inline ComponentLayout componentLayout(uint64_t vertices, uint64_t coefficients, uint32_t flags = 0,
                                       uint64_t shCoefficients = 0, bool withShScales = false,
                                       uint64_t indexBytes = 0) {
    ComponentLayout l;
    uint64_t pos = kComponentFixedBytes;
    if (!(flags & kCompSharedIndices)) {
        l.offsets = pos;
        l.indices = alignUp(l.offsets + (vertices + 1) * sizeof(uint32_t));
        pos = l.indices + ((flags & kCompEightBitHaar) ? indexBytes : coefficients * sizeof(uint16_t));
    }
    l.values = alignUp(pos);
    if (flags & kCompEightBitHaar) {
        l.shValues = alignUp(l.values + 3 * (coefficients - shCoefficients) * sizeof(int8_t));
        l.scales = alignUp(l.shValues + 3 * shCoefficients * sizeof(int16_t));
    } else {
        l.scales = alignUp(l.values + 3 * coefficients * sizeof(int16_t));
    }
    l.total = l.scales + 3 * vertices * sizeof(float);
    if ((flags & kCompEightBitHaar) && withShScales) {
        l.shScales = alignUp(l.total);
        l.total = l.shScales + 3 * vertices * sizeof(float);
    }
    return l;
}

// Blocks of kVertexBlock vertices (the last one may be partial).
inline uint64_t blockCountOf(uint64_t vertices) { return (vertices + kVertexBlock - 1) / kVertexBlock; }

// Byte offsets, relative to the payload start, of a BLKC section's arrays.
struct BlockedLayout {
    uint64_t order = 0, offsets = 0, indices = 0, values = 0, scales = 0, shScales = 0, total = 0;
};

// Requires vertices <= kMaxVertices, indices <= UINT32_MAX and indexBytes <= 3 indices
// (no overflow). indexBytes: the size of the index array (2 per index before format
// version 4, the varint stream's size from it); shScales: the SH scales array is there.
inline BlockedLayout blockedLayout(uint64_t vertices, uint64_t indices, uint64_t indexBytes, bool shScales) {
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
inline uint64_t viewMapsPayloadBytes(uint64_t size, uint64_t terms) {
    return kViewFixedBytes + terms * 6 * size * size * sizeof(float);
}

// Requires size <= kMaxRadialProfiles and nodeCount <= kMaxRadialNodes.
inline uint64_t radialBasisPayloadBytes(uint64_t size, uint64_t nodeCount) {
    return kRadialFixedBytes + nodeCount * size * sizeof(float);
}

// ---- encoding -------------------------------------------------------------------

// Little-endian scalars, independent of the host byte order.
inline void putU32(uint8_t* p, uint32_t v) {
    for (int i = 0; i < 4; ++i) p[i] = uint8_t(v >> (8 * i));
}
inline void putU64(uint8_t* p, uint64_t v) {
    for (int i = 0; i < 8; ++i) p[i] = uint8_t(v >> (8 * i));
}
inline uint32_t getU32(const uint8_t* p) {
    uint32_t v = 0;
    for (int i = 0; i < 4; ++i) v |= uint32_t(p[i]) << (8 * i);
    return v;
}
inline uint64_t getU64(const uint8_t* p) {
    uint64_t v = 0;
    for (int i = 0; i < 8; ++i) v |= uint64_t(p[i]) << (8 * i);
    return v;
}

// Reverses the bytes of each of `count` elements of `size` bytes (big-endian hosts).
inline void byteSwapElements(uint8_t* p, size_t count, size_t size) {
    for (size_t e = 0; e < count; ++e) std::reverse(p + e * size, p + (e + 1) * size);
}

// zlib crc32 over any length (crc32 takes at most 4 GiB - 1 at a time).
inline uLong crcUpdate(uLong crc, const void* data, uint64_t n) {
    const auto* p = static_cast<const Bytef*>(data);
    while (n > 0) {
        const uInt chunk = uInt(std::min<uint64_t>(n, uint64_t(1) << 30));
        crc = crc32(crc, p, chunk);
        p += chunk;
        n -= chunk;
    }
    return crc;
}

// ---- text for messages ----------------------------------------------------------

inline std::string u64(uint64_t v) { return std::to_string(v); }

inline std::string hex32(uint32_t v) {
    char buf[16];
    std::snprintf(buf, sizeof buf, "0x%08" PRIx32, v);
    return buf;
}

inline std::string hex64(uint64_t v) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "0x%016" PRIx64, v);
    return buf;
}

// The shortest %g form that reads back as v (%.17g if none does).
inline std::string formatDouble(double v) {
    for (int precision = 1; precision <= 17; ++precision) {
        char buf[64];
        std::snprintf(buf, sizeof buf, "%.*g", precision, v);
        if (std::strtod(buf, nullptr) == v) return buf;
    }
    char buf[64];
    std::snprintf(buf, sizeof buf, "%.17g", v);
    return buf;
}

// ---- validation (transport_file.cpp), shared by save and load ------------------
// Each returns "" when fine, else a one-line reason.

inline bool validKind(uint32_t kind) {
    return kind >= uint32_t(ComponentKind::MultipleScattering) &&
           kind <= uint32_t(ComponentKind::MultipleScatteringProfiles);
}

// Kinds whose components carry a term index (0 for the others).
inline bool hasTerms(ComponentKind kind) {
    return kind == ComponentKind::SingleScatteringTerm || kind == ComponentKind::MultipleScatteringProfiles;
}

// The construction field of RBAS: a RadialConstruction value.
inline bool validRadialConstruction(uint32_t c) {
    return c <= uint32_t(RadialConstruction::ExpLadder);
}

inline bool validShTermCount(uint32_t terms) { return terms <= uint32_t(kMaxShTerms) && validShTerms(int(terms)); }

// Per-vertex vectors of `vertices` vertices with indices < 6 N^2 + shTerms.
std::string checkVectors(const SparseRgbVectors& s, uint64_t vertices, uint32_t cubemapSize, uint32_t shTerms);
// Blocked vectors of `vertices` vertices (offsets checked monotone before
// checkBlockedVectors walks them).
std::string checkBlocked(const BlockedRgbVectors& b, uint64_t vertices, uint32_t cubemapSize, uint32_t shTerms);
// The profile components' terms (the term of every kind-4 component, in file order)
// against the basis: none without a basis (basisSize < 0), else terms exactly
// 0..P-1 with basisSize == 3P. Shared by checkFile and readTransportFileInfo.
std::string checkProfileTerms(const std::vector<uint32_t>& terms, int basisSize);
// Whether f's blocked profile components hold index lists that are not all equal (what
// format version 7 adds).
bool blockedProfileListsDiffer(const TransportFile& f);
// A stored basis: RadialBasis(range, tables) accepts it (a valid range, bounds, table
// size, finite values, independent profiles) and the construction is a known one.
std::string checkRadialBasis(const StoredRadialBasis& b);
// Everything saveTransportFile promises (transport_file.h) that does not depend on the
// byte layout.
std::string checkFile(const TransportFile& f);

}  // namespace prt::transport_format
