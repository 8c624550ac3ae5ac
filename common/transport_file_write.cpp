// The transport file writer: saveTransportFile (docs/transport-format.md, "Writing
// rules"). Layout constants and helpers: common/transport_file_format.h.

#include <fcntl.h>
#include <unistd.h>
#include <zlib.h>

#include <algorithm>
#include <bit>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <stdexcept>

#include "common/atomic_file.h"
#include "common/blocked_vectors.h"
#include "common/error.h"
#include "common/transport_file.h"
#include "common/transport_file_format.h"

namespace prt {

using namespace transport_format;

namespace {

// Buffered writes to an open file descriptor, with the position and the running
// checksum of the open section.
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

// The lowest version that holds f (docs/transport-format.md, "Preamble").
uint32_t formatVersionOf(const TransportFile& f) {
    if (blockedProfileListsDiffer(f)) return kNestedListsFormatVersion;
    if (std::any_of(f.components.begin(), f.components.end(),
                    [](const TransportComponent& c) { return !c.blocked() && c.vectors.haarBits == 8; }))
        return kEightBitFormatVersion;
    if (f.radialBasis) return kRadialFormatVersion;
    const bool blocked = std::any_of(f.components.begin(), f.components.end(),
                                     [](const TransportComponent& c) { return c.blocked(); });
    if (f.shTerms > 0) return blocked ? kBlockVarintFormatVersion : kShFormatVersion;
    return blocked ? kBlockedFormatVersion : kFormatVersion;
}

uint64_t parameterPayloadBytes(const TransportFile& f) {
    uint64_t bytes = 4;
    for (const auto& [key, value] : f.parameters) bytes += 8 + key.size() + value.size();
    return bytes;
}

// A per-vertex component; `previous` is the COMP written just before it (or nullptr):
// an 8-bit component with its offsets and indices stores none of its own.
void writeComponent(FileWriter& w, const TransportComponent& c, const TransportComponent* previous) {
    const SparseRgbVectors& v = c.vectors;
    const uint64_t vertices = v.vertexCount();
    const uint64_t coefficients = v.coefficientCount();
    const bool eightBit = v.haarBits == 8;
    uint32_t flags = eightBit ? kCompEightBitHaar : 0;
    if (eightBit && previous && previous->vectors.haarBits == 8 && previous->vectors.offsets == v.offsets &&
        previous->vectors.indices == v.indices)
        flags |= kCompSharedIndices;
    uint64_t shCoefficients = 0;
    if (eightBit)
        shCoefficients = uint64_t(std::count_if(v.indices.begin(), v.indices.end(),
                                                [&](uint16_t i) { return i >= v.shFrom; }));
    const bool ownIndices = !(flags & kCompSharedIndices);
    const std::vector<uint8_t> stream =
        eightBit && ownIndices ? encodeIndexLists(v.offsets, v.indices) : std::vector<uint8_t>();
    const ComponentLayout l =
        componentLayout(vertices, coefficients, flags, shCoefficients, !v.shScales.empty(), stream.size());
    w.beginSection(Section::Component, l.total);
    w.u32(uint32_t(c.kind));
    w.u32(c.term);
    w.u64(vertices);
    w.u64(coefficients);
    w.u32(flags);  // reserved (0) before version 6
    w.u32(0);
    w.u64(shCoefficients);
    w.u64(stream.size());
    if (ownIndices) {
        w.padTo(l.offsets);
        w.array(v.offsets);
        w.padTo(l.indices);
        if (eightBit)
            w.array(stream);
        else
            w.array(v.indices);
    }
    w.padTo(l.values);
    if (eightBit) {
        std::vector<int8_t> haar;
        std::vector<int16_t> sh;
        haar.reserve(3 * (coefficients - shCoefficients));
        sh.reserve(3 * shCoefficients);
        for (size_t n = 0; n < v.indices.size(); ++n)
            for (int ch = 0; ch < 3; ++ch) {
                const int16_t q = v.values[3 * n + size_t(ch)];
                if (v.indices[n] < v.shFrom)
                    haar.push_back(int8_t(q));  // checkVectors: within -127..127
                else
                    sh.push_back(q);
            }
        w.array(haar);
        w.padTo(l.shValues);
        w.array(sh);
    } else {
        w.array(v.values);
    }
    w.padTo(l.scales);
    w.array(v.scales);
    if (l.shScales) {
        w.padTo(l.shScales);
        w.array(v.shScales);
    }
    w.endSection();
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
    const uint32_t version = formatVersionOf(f);
    w.write(kMagic.data(), kMagic.size());
    w.u32(version);
    w.u32(kEndianMarker);

    w.beginSection(Section::Head, kHeadBytes);
    w.u32(f.cubemapSize);
    w.u32(uint32_t(f.components.size()));
    w.u64(f.mesh.vertexCount);
    w.u64(f.mesh.positionHash);
    w.u64(std::bit_cast<uint64_t>(f.mmPerUnit));
    w.u32(f.viewMaps ? 1u : 0u);
    w.u32(f.shTerms);  // reserved (0) before version 3
    w.endSection();

    const uint64_t parameterBytes = parameterPayloadBytes(f);
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

    const TransportComponent* previous = nullptr;
    for (const TransportComponent& c : f.components) {
        if (c.blocked()) {
            writeBlockedComponent(w, c, version);
            previous = nullptr;
        } else {
            writeComponent(w, c, previous);
            previous = &c;
        }
    }

    if (f.viewMaps) {
        const ViewMaps& m = *f.viewMaps;
        w.beginSection(Section::ViewMaps, viewMapsPayloadBytes(uint64_t(m.size), uint64_t(m.terms)));
        w.u32(uint32_t(m.size));
        w.u32(uint32_t(m.terms));
        w.padTo(kViewFixedBytes);
        w.array(m.data);
        w.endSection();
    }

    if (f.radialBasis) {
        const RadialRange& r = f.radialBasis->range;
        const RadialBasisTables& t = f.radialBasis->tables;
        w.beginSection(Section::RadialBasis,
                       radialBasisPayloadBytes(uint64_t(t.size), uint64_t(t.nodeCount)));
        for (double x : {r.zrMin, r.zrMax, r.alphaMin, r.alphaMax, r.eta, r.rMax})
            w.u64(std::bit_cast<uint64_t>(x));
        w.u32(uint32_t(t.size));
        w.u32(uint32_t(t.nodeCount));
        w.u32(uint32_t(t.construction));
        w.u32(0);  // reserved
        w.u64(std::bit_cast<uint64_t>(t.normExponent));
        w.padTo(kRadialFixedBytes);
        w.array(t.values);
        w.endSection();
    }

    w.beginSection(Section::End, 0);
    w.endSection();
    w.flush();
}

}  // namespace

void saveTransportFile(const std::string& path, const TransportFile& file) {
    const std::string reason = checkFile(file);
    if (!reason.empty()) throw Error(path, "invalid transport data: " + reason);
    const uint64_t parameterBytes = parameterPayloadBytes(file);
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

}  // namespace prt
