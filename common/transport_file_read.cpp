// The transport file readers: loadTransportFile (whole file, every checksum and
// index) and readTransportFileInfo (preamble, header, parameters and the fixed part of
// every section); docs/transport-format.md, "Reading rules". Layout constants and
// helpers: common/transport_file_format.h.

#include <zlib.h>

#include <algorithm>
#include <bit>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <set>
#include <stdexcept>

#include "common/error.h"
#include "common/transport_file.h"
#include "common/transport_file_format.h"

namespace prt {

using namespace transport_format;

namespace {

// What messages call a section: "section 'COMP' (component 2 of 6)".
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
        case Section::RadialBasis: return label + " (radial basis)";
        case Section::End: return label + " (end marker)";
    }
    return label;
}

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

bool allZero(const uint8_t* p, size_t n) {
    return std::all_of(p, p + n, [](uint8_t b) { return b == 0; });
}

// Sequential reads of a file whose size is known up front, so that every declared
// length is compared with the bytes left before anything is allocated.
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

// Returns the format version (1 to kNewestFormatVersion).
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
    if (version < kFormatVersion || version > kNewestFormatVersion)
        r.fail("unsupported transport file format version " + u64(version) +
               " (this build reads versions " + u64(kFormatVersion) + " to " +
               u64(kNewestFormatVersion) + ")");
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
    if (version >= kRadialFormatVersion) {
        // Version 5 is chosen by the radial basis alone, with or without an SH part.
        if (!validShTermCount(reserved))
            r.fail(where + "SH term count " + u64(reserved) + " is not " + kShTermCounts + " (format version " +
                   u64(version) + ")");
        h.shTerms = reserved;
        if (h.cubemapSize < uint32_t(minShCubemapSize(int(h.shTerms))))
            r.fail(where + u64(h.shTerms) + " SH terms on a 6 x " + u64(h.cubemapSize) + " x " + u64(h.cubemapSize) +
                   " cubemap (they are not independent there)");
    } else if (version >= kShFormatVersion) {
        if (reserved == 0 || !validShTermCount(reserved))
            r.fail(where + "SH term count " + u64(reserved) + " is not 1, 4, 9, 16 or 25 (format version " +
                   u64(version) + ")");
        h.shTerms = reserved;
        if (h.cubemapSize < uint32_t(minShCubemapSize(int(h.shTerms))))
            r.fail(where + u64(h.shTerms) + " SH terms on a 6 x " + u64(h.cubemapSize) + " x " + u64(h.cubemapSize) +
                   " cubemap (they are not independent there)");
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
void checkComponentHeader(FileReader& r, const OpenSection& s, const HeadFields& h, uint32_t kind,
                          uint32_t term, bool reservedZero) {
    const std::string where = "inconsistent: " + s.label + ": ";
    if (!validKind(kind)) r.fail(where + "unknown component kind " + u64(kind));
    if (ComponentKind(kind) == ComponentKind::MultipleScatteringProfiles) {
        if (h.version < kRadialFormatVersion)
            r.fail(where + "component kind 4 (multiple scattering profiles) in a format version " +
                   u64(h.version) + " file (it needs version " + u64(kRadialFormatVersion) + ")");
    }
    if (!hasTerms(ComponentKind(kind)) && term != 0)
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
    checkComponentHeader(r, s, h, kind, term, reservedZero);
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
// `previous`: the component read just before (nullptr for the first or after a blocked
// one): an 8-bit component with kCompSharedIndices takes its offsets and indices. In
// info mode `previousInfo` plays that part for the counts.
TransportComponent readComponent(FileReader& r, const HeadFields& h, size_t index, bool infoOnly,
                                 TransportFileInfo::Component* info, const TransportComponent* previous,
                                 const TransportFileInfo::Component* previousInfo) {
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
    // Version 6: flags at 24, zero at 28, the SH coefficient count at 32; reserved zero before.
    const bool flagged = h.version >= kEightBitFormatVersion;
    const uint32_t flags = flagged ? getU32(b + 24) : 0;
    const uint64_t shCoefficients = flagged ? getU64(b + 32) : 0;
    const uint64_t indexBytes = flagged ? getU64(b + 40) : 0;
    const bool reservedZero = flagged ? allZero(b + 28, 4) && allZero(b + 48, size_t(kComponentFixedBytes - 48))
                                      : allZero(b + 24, size_t(kComponentFixedBytes - 24));

    auto fail = [&](const std::string& reason) {
        if (infoOnly) r.fail("inconsistent: " + s.label + ": " + reason);
        failAfterChecksum(r, s, reason);
    };
    if (vertices != h.mesh.vertexCount)
        fail("has " + u64(vertices) + " vertices, the header says " + u64(h.mesh.vertexCount));
    if (coefficients > UINT32_MAX)
        fail(u64(coefficients) + " coefficients exceed the 32-bit offsets");
    if (flags & ~(kCompEightBitHaar | kCompSharedIndices)) fail("unknown component flags " + hex32(flags));
    const bool eightBit = flags & kCompEightBitHaar;
    const bool shared = flags & kCompSharedIndices;
    if (shared && !eightBit) fail("shares the previous component's indices without 8-bit values");
    if (!eightBit && shCoefficients != 0) fail("an SH coefficient count without 8-bit values");
    if (shCoefficients > coefficients)
        fail(u64(shCoefficients) + " SH coefficients of " + u64(coefficients) + " coefficients");
    if (shared) {
        const bool previousFits = infoOnly ? previousInfo && !previousInfo->blocked && previousInfo->eightBitHaar &&
                                                 previousInfo->coefficientCount == coefficients
                                           : previous && previous->vectors.haarBits == 8 &&
                                                 previous->vectors.coefficientCount() == coefficients;
        if (!previousFits)
            fail("shares the indices of the component before it, which is not an 8-bit component of " +
                 u64(coefficients) + " coefficients");
    }
    // A varint takes 1 to 3 bytes per index (bounds the stream before the layout).
    if (eightBit && !shared ? (indexBytes < coefficients || indexBytes > 3 * coefficients) : indexBytes != 0)
        fail("an index stream of " + u64(indexBytes) + " bytes for " + u64(coefficients) + " coefficients");
    const bool withShScales = eightBit && h.shTerms > 0;
    const ComponentLayout l =
        componentLayout(vertices, coefficients, flags, shCoefficients, withShScales, indexBytes);
    if (l.total != s.length)
        fail(u64(vertices) + " vertices and " + u64(coefficients) + " coefficients need a " +
             u64(l.total) + "-byte payload, the section has " + u64(s.length));

    TransportComponent c;
    c.kind = ComponentKind(kind);
    c.term = term;
    if (info) {
        *info = {ComponentKind(kind), term, vertices, coefficients, s.length};
        info->eightBitHaar = eightBit;
        info->sharedIndices = shared;
    }
    if (infoOnly) {
        skipSection(r, s);
    } else {
        SparseRgbVectors& v = c.vectors;
        bool paddingZero = true, shCountMismatch = false;
        std::vector<uint8_t> stream;  // version 6: the varint-coded indices
        if (shared) {
            v.offsets = previous->vectors.offsets;
            v.indices = previous->vectors.indices;
        } else {
            paddingZero &= readPaddingTo(r, s, l.offsets);
            readArray(r, s, v.offsets, vertices + 1);
            paddingZero &= readPaddingTo(r, s, l.indices);
            if (eightBit)
                readArray(r, s, stream, indexBytes);
            else
                readArray(r, s, v.indices, coefficients);
        }
        std::string indexReason;
        if (eightBit && !shared) {
            // A bad stream is reported after the checksum (below), like every content
            // error; the values are read against zero indices meanwhile.
            if (v.offsets.empty() || v.offsets.back() != coefficients)
                indexReason = "offsets end at " + u64(v.offsets.empty() ? 0 : v.offsets.back()) + " but there are " +
                              u64(coefficients) + " coefficients";
            else
                indexReason = decodeIndexLists(stream.data(), stream.size(), v.offsets, v.indices, "vertex");
            if (!indexReason.empty()) v.indices.assign(coefficients, 0);
        }
        paddingZero &= readPaddingTo(r, s, l.values);
        if (eightBit) {
            v.haarBits = 8;
            v.shFrom = withShScales ? 6 * h.cubemapSize * h.cubemapSize : UINT32_MAX;
            std::vector<int8_t> haar;
            std::vector<int16_t> sh;
            readArray(r, s, haar, 3 * (coefficients - shCoefficients));
            paddingZero &= readPaddingTo(r, s, l.shValues);
            readArray(r, s, sh, 3 * shCoefficients);
            // Back into one int16 array in coefficient order; the counts must match.
            v.values.resize(3 * coefficients);
            size_t nh = 0, ns = 0;
            bool countsMatch = true;
            for (size_t n = 0; n < v.indices.size() && countsMatch; ++n) {
                const bool isSh = v.indices[n] >= v.shFrom;
                if ((isSh ? ns : nh) + 3 > (isSh ? sh.size() : haar.size())) {
                    countsMatch = false;
                    break;
                }
                for (int ch = 0; ch < 3; ++ch)
                    v.values[3 * n + size_t(ch)] = isSh ? sh[ns++] : int16_t(haar[nh++]);
            }
            shCountMismatch = !countsMatch || nh != haar.size() || ns != sh.size();
        } else {
            readArray(r, s, v.values, 3 * coefficients);
        }
        paddingZero &= readPaddingTo(r, s, l.scales);
        readArray(r, s, v.scales, 3 * vertices);
        if (l.shScales) {
            paddingZero &= readPaddingTo(r, s, l.shScales);
            readArray(r, s, v.shScales, 3 * vertices);
        }
        closeSection(r, s);
        if (!paddingZero) r.fail("inconsistent: " + s.label + ": non-zero padding between arrays");
        if (!indexReason.empty()) r.fail("inconsistent: " + s.label + ": " + indexReason);
        if (shCountMismatch)
            r.fail("inconsistent: " + s.label + ": the SH coefficient count " + u64(shCoefficients) +
                   " does not match the indices");
    }
    checkComponentHeader(r, s, h, kind, term, reservedZero);
    if (!infoOnly) {
        const std::string reason = checkVectors(c.vectors, vertices, h.cubemapSize, h.shTerms);
        if (!reason.empty()) r.fail("inconsistent: " + s.label + ": " + reason);
    }
    return c;
}

// A version-2 or -4 file without a blocked component is refused: the writer writes such
// a file as version 1 or 3, so this is a corrupted version field. (A version-3 file with
// one is what the writer wrote before version 4, and is read as such.)
void checkVersionMatchesComponents(FileReader& r, const HeadFields& h, bool anyBlocked, bool anyEightBit) {
    if (h.version == kEightBitFormatVersion && !anyEightBit)
        r.fail("inconsistent: format version 6 but no component with 8-bit Haar values (a file without one is "
               "version 5 or lower)");
    if ((h.version == kBlockedFormatVersion || h.version == kBlockVarintFormatVersion) && !anyBlocked)
        r.fail("inconsistent: format version " + u64(h.version) +
               " but no blocked component (a file without one is version " +
               u64(h.version == kBlockedFormatVersion ? kFormatVersion : kShFormatVersion) + ")");
}

// Version 7's rule (blocked profile components with index lists of their own): refused
// below it when the lists surely differ, and a version-7 file where they cannot.
void checkNestedListsVersion(FileReader& r, uint32_t version, bool listsDiffer, bool listsMayDiffer) {
    if (listsDiffer && version < kNestedListsFormatVersion)
        r.fail("inconsistent: blocked profile components with index lists of their own in a format version " +
               u64(version) + " file (they need version " + u64(kNestedListsFormatVersion) + ")");
    if (!listsMayDiffer && version == kNestedListsFormatVersion)
        r.fail("inconsistent: format version " + u64(version) +
               " but no blocked profile components with index lists of their own (such a file is version " +
               u64(kEightBitFormatVersion) + " or lower)");
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

// Reads an RBAS section (version 5). In info mode only the fixed part is read: `out`
// gets the range and the table's shape, with empty values.
StoredRadialBasis readRadialBasis(FileReader& r, bool infoOnly, uint32_t version) {
    // A version-5 or -6 file always has one (the writer picks those versions for it alone).
    const AlternativeSection end{Section::End, sectionLabel(Section::End),
                                 "format version " + u64(version) +
                                     " but no radial basis (a file without one is version 1 to 4)"};
    OpenSection s = openSection(r, Section::RadialBasis, sectionLabel(Section::RadialBasis), &end);
    if (s.length < kRadialFixedBytes)
        failAfterChecksum(r, s, "payload is " + u64(s.length) + " bytes, less than the " +
                                    u64(kRadialFixedBytes) + "-byte radial basis header");
    uint8_t b[kRadialFixedBytes];
    readPayload(r, s, b, kRadialFixedBytes);
    StoredRadialBasis basis;
    RadialRange& range = basis.range;
    double* fields[] = {&range.zrMin, &range.zrMax, &range.alphaMin, &range.alphaMax, &range.eta, &range.rMax};
    for (int i = 0; i < 6; ++i) *fields[i] = std::bit_cast<double>(getU64(b + 8 * i));
    const uint32_t size = getU32(b + 48);
    const uint32_t nodeCount = getU32(b + 52);
    const uint32_t construction = getU32(b + 56);
    const bool reservedZero = getU32(b + 60) == 0 && allZero(b + kRadialFieldBytes, size_t(kRadialFixedBytes - kRadialFieldBytes));
    basis.tables.normExponent = std::bit_cast<double>(getU64(b + 64));
    auto fail = [&](const std::string& reason) {
        if (infoOnly) r.fail("inconsistent: " + s.label + ": " + reason);
        failAfterChecksum(r, s, reason);
    };
    // The shape bounds the table (at most 256 MB), whose size is then checked against
    // the section length (itself within the file) before anything is allocated.
    if (size < 1 || size > kMaxRadialProfiles)
        fail("profile count " + u64(size) + " outside 1.." + u64(kMaxRadialProfiles));
    if (nodeCount < kMinRadialNodes || nodeCount > kMaxRadialNodes)
        fail("node count " + u64(nodeCount) + " outside " + u64(kMinRadialNodes) + ".." + u64(kMaxRadialNodes));
    const uint64_t expected = radialBasisPayloadBytes(size, nodeCount);
    if (expected != s.length)
        fail(u64(nodeCount) + " nodes of " + u64(size) + " profiles need a " + u64(expected) +
             "-byte payload, the section has " + u64(s.length));
    basis.tables.size = int(size);
    basis.tables.nodeCount = int(nodeCount);
    basis.tables.construction = RadialConstruction(construction);
    if (infoOnly) {
        skipSection(r, s);
    } else {
        readArray(r, s, basis.tables.values, uint64_t(size) * nodeCount);
        closeSection(r, s);
    }
    const std::string where = "inconsistent: " + s.label + ": ";
    if (!reservedZero) r.fail(where + "reserved header bytes are not zero");
    if (!validRadialConstruction(construction))
        r.fail(where + "construction " + u64(construction) + " is not 0, 1 or 2");
    try {
        validateRadialRange(range);
    } catch (const Error& e) {
        r.fail(where + e.what());
    }
    return basis;
}

void readEnd(FileReader& r, uint32_t version) {
    const AlternativeSection radial{
        Section::RadialBasis, sectionLabel(Section::RadialBasis),
        "a radial basis in a format version " + u64(version) + " file (it needs version " +
            u64(kRadialFormatVersion) + ")"};
    OpenSection s = openSection(r, Section::End, sectionLabel(Section::End),
                                version < kRadialFormatVersion ? &radial : nullptr);
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
    if (expected && f.hasParameter(kShardParameter))
        throw Error(path, "is shard " + f.parameter(kShardParameter) + " (vertices " +
                              f.parameter(kShardVerticesParameter) +
                              ") of a sharded precompute, not a whole transport file: join the shards with "
                              "prt-merge");
    for (size_t i = 0; i < h.componentCount; ++i) {
        const TransportComponent* previous = i > 0 && !f.components.back().blocked() ? &f.components.back() : nullptr;
        TransportComponent c = readComponent(r, h, i, false, nullptr, previous, nullptr);
        f.components.push_back(std::move(c));
    }
    checkVersionMatchesComponents(
        r, h, std::any_of(f.components.begin(), f.components.end(), [](const auto& c) { return c.blocked(); }),
        std::any_of(f.components.begin(), f.components.end(),
                    [](const auto& c) { return !c.blocked() && c.vectors.haarBits == 8; }));
    if (h.hasViewMaps) f.viewMaps = readViewMaps(r, false);
    if (version >= kRadialFormatVersion) f.radialBasis = readRadialBasis(r, false, version);
    readEnd(r, version);
    const std::string reason = checkFile(f);
    if (!reason.empty()) r.fail("inconsistent: " + reason);
    const bool ownLists = blockedProfileListsDiffer(f);
    checkNestedListsVersion(r, version, ownLists, ownLists);
    return f;
}

}  // namespace

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
        readComponent(r, h, i, true, &c, nullptr, info.components.empty() ? nullptr : &info.components.back());
        info.components.push_back(c);
    }
    checkVersionMatchesComponents(
        r, h, std::any_of(info.components.begin(), info.components.end(), [](const auto& c) { return c.blocked; }),
        std::any_of(info.components.begin(), info.components.end(), [](const auto& c) { return c.eightBitHaar; }));
    if (h.hasViewMaps) {
        const ViewMaps m = readViewMaps(r, true);
        info.viewMapSize = m.size;
        info.viewMapTerms = m.terms;
    }
    int basisSize = -1;
    if (version >= kRadialFormatVersion) {
        const StoredRadialBasis b = readRadialBasis(r, true, version);
        info.radialRange = b.range;
        info.radialProfiles = basisSize = b.tables.size;
        info.radialNodeCount = b.tables.nodeCount;
        info.radialConstruction = b.tables.construction;
        info.radialNormExponent = b.tables.normExponent;
        info.radialBasisBytes = radialBasisPayloadBytes(uint64_t(b.tables.size), uint64_t(b.tables.nodeCount));
    }
    readEnd(r, version);
    std::vector<uint32_t> profileTerms;
    std::vector<uint64_t> blockedProfileCounts;
    for (const TransportFileInfo::Component& c : info.components)
        if (c.kind == ComponentKind::MultipleScatteringProfiles) {
            profileTerms.push_back(c.term);
            if (c.blocked) blockedProfileCounts.push_back(c.coefficientCount);
        }
    // Version 7's rule as far as the counts tell (loadTransportFile compares the lists).
    const bool countsDiffer =
        std::adjacent_find(blockedProfileCounts.begin(), blockedProfileCounts.end(), std::not_equal_to<>()) !=
        blockedProfileCounts.end();
    checkNestedListsVersion(r, version, countsDiffer, blockedProfileCounts.size() >= 2);
    const std::string reason = checkProfileTerms(profileTerms, basisSize);
    if (!reason.empty()) r.fail("inconsistent: " + reason);
    return info;
}

}  // namespace prt
