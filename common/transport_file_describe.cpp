// describe(): the human-readable summary of a transport file (prt-relight info).

#include <algorithm>
#include <cinttypes>
#include <cstdio>
#include <cstdlib>

#include "common/transport_file.h"
#include "common/transport_file_format.h"

namespace prt {

using namespace transport_format;

namespace {

// Binary units ("1.5 KiB", "55.0 MiB"), unlike util.h's decimal formatBytes.
std::string formatBinaryBytes(uint64_t bytes) {
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
           (shScales ? ", SH part scaled apart" : "") + ", " + formatBinaryBytes(bytes) + " " + where +
           " (" + bytesPerVertex(bytes, vertices) + ")";
}

// The lines both describe()s share: cubemap, SH part, mesh, parameters.
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

// The shortest of %.6g .. %.17g that reads back as v: plain decimals for the ranges a
// basis has ("20", "0.4"), where formatDouble's shortest form may be "2e+01".
std::string numberText(double v) {
    for (int precision = 6; precision <= 17; ++precision) {
        char buf[64];
        std::snprintf(buf, sizeof buf, "%.*g", precision, v);
        if (std::strtod(buf, nullptr) == v) return buf;
    }
    return formatDouble(v);
}

// "radial basis: 12 profiles (pca, norm r^3), z_r 0.25..12 mm, alpha' 0.5..0.999, eta
// 1.3, rMax 30 mm, 1200 nodes; in multiple scattering profiles 0-2, ..., 9-11", plus
// the bytes where given.
std::string describeRadialBasis(const RadialRange& r, int size, int nodeCount, RadialConstruction construction,
                                double normExponent, const std::vector<std::pair<ComponentKind, uint32_t>>& components,
                                const std::string& bytes) {
    std::string out = "radial basis: " + std::to_string(size) + " profiles (" +
                      radialConstructionName(construction) + ", norm r^" + numberText(normExponent) + "), z_r " +
                      numberText(r.zrMin) + ".." + numberText(r.zrMax) + " mm, alpha' " +
                      numberText(r.alphaMin) + ".." + numberText(r.alphaMax) + ", eta " + numberText(r.eta) +
                      ", rMax " + numberText(r.rMax) + " mm, " + std::to_string(nodeCount) + " nodes";
    std::string names;
    for (const auto& [kind, term] : components) {
        if (kind != ComponentKind::MultipleScatteringProfiles) continue;
        names += (names.empty() ? "" : ", ") + componentName(kind, term);
    }
    out += "; in " + (names.empty() ? std::string("no component") : names);
    if (!bytes.empty()) out += "; " + bytes;
    return out + "\n";
}

}  // namespace

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
               formatBinaryBytes(v.byteSize()) + " in memory (" + bytesPerVertex(v.byteSize(), v.vertexCount()) +
               ")\n";
        total += v.byteSize();
    }
    if (file.viewMaps)
        out += "view maps: " + std::to_string(file.viewMaps->terms) + " terms of 6 x " +
               std::to_string(file.viewMaps->size) + " x " + std::to_string(file.viewMaps->size) +
               "\n";
    else
        out += "view maps: none\n";
    if (file.radialBasis) {
        const StoredRadialBasis& b = *file.radialBasis;
        std::vector<std::pair<ComponentKind, uint32_t>> kinds;
        for (const TransportComponent& c : file.components) kinds.emplace_back(c.kind, c.term);
        out += describeRadialBasis(b.range, b.tables.size, b.tables.nodeCount, b.tables.construction,
                                   b.tables.normExponent, kinds,
                                   formatBinaryBytes(b.tables.values.size() * sizeof(float)) + " of tables in memory");
    }
    out += "total: " + formatBinaryBytes(total) + " of vectors in memory\n";
    return out;
}

std::string describe(const TransportFileInfo& info) {
    std::string out = "transport file, format version " + u64(info.version) + ", " +
                      formatBinaryBytes(info.fileBytes) + "\n";
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
        const std::string encoding =
            c.eightBitHaar ? std::string(info.shTerms ? "8-bit Haar values, 16-bit SH part, " : "8-bit values, ") +
                                 (c.sharedIndices ? "the indices of the component before, " : "")
                           : "";
        out += "  " + componentName(c.kind, c.term) + ": " + u64(c.vertexCount) + " vertices, " +
               u64(c.coefficientCount) + " coefficients (" + stats + "), " + encoding +
               formatBinaryBytes(c.payloadBytes) + " on disk (" + bytesPerVertex(c.payloadBytes, c.vertexCount) +
               ")\n";
    }
    if (info.viewMapTerms > 0)
        out += "view maps: " + std::to_string(info.viewMapTerms) + " terms of 6 x " +
               std::to_string(info.viewMapSize) + " x " + std::to_string(info.viewMapSize) + "\n";
    else
        out += "view maps: none\n";
    if (info.radialRange) {
        std::vector<std::pair<ComponentKind, uint32_t>> kinds;
        for (const TransportFileInfo::Component& c : info.components) kinds.emplace_back(c.kind, c.term);
        out += describeRadialBasis(*info.radialRange, info.radialProfiles, info.radialNodeCount,
                                   info.radialConstruction, info.radialNormExponent, kinds,
                                   formatBinaryBytes(info.radialBasisBytes) + " on disk");
    }
    return out;
}

}  // namespace prt
