#include "precompute/job/distribution.h"

#include <algorithm>
#include <charconv>

#include "common/error.h"

namespace prt {

IndexRange evenRange(size_t count, int part, int parts) {
    if (parts < 1 || part < 0 || part >= parts)
        throw Error("evenRange", "part " + std::to_string(part) + " of " + std::to_string(parts));
    const size_t p = size_t(part), n = size_t(parts);
    const size_t base = count / n, extra = count % n;
    const size_t begin = p * base + std::min(p, extra);
    return {begin, begin + base + (p < extra ? 1 : 0)};
}

std::vector<IndexRange> interleavedBlocks(size_t count, size_t block, int part, int parts) {
    if (parts < 1 || part < 0 || part >= parts || block < 1)
        throw Error("interleavedBlocks", "part " + std::to_string(part) + " of " + std::to_string(parts));
    std::vector<IndexRange> out;
    for (size_t begin = size_t(part) * block; begin < count; begin += size_t(parts) * block)
        out.push_back({begin, std::min(count, begin + block)});
    return out;
}

size_t totalSize(const std::vector<IndexRange>& ranges) {
    size_t n = 0;
    for (const IndexRange& r : ranges) n += r.size();
    return n;
}

namespace {

bool parseInt(std::string_view text, int& out) {
    if (text.empty()) return false;
    const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), out);
    return ec == std::errc() && end == text.data() + text.size();
}

}  // namespace

ShardSpec parseShard(const std::string& text) {
    const size_t slash = text.find('/');
    ShardSpec s;
    if (slash == std::string::npos || !parseInt(std::string_view(text).substr(0, slash), s.index) ||
        !parseInt(std::string_view(text).substr(slash + 1), s.count))
        throw Error("--shard", "expected i/n (shard i of n, 0 <= i < n), got '" + text + "'");
    if (s.count < 1 || s.count > 65536)
        throw Error("--shard", "the shard count must be between 1 and 65536, got " + std::to_string(s.count));
    if (s.index < 0 || s.index >= s.count)
        throw Error("--shard", "the shard index must be between 0 and " + std::to_string(s.count - 1) +
                                   " (0-based), got " + std::to_string(s.index));
    return s;
}

std::string toString(const ShardSpec& shard) {
    return std::to_string(shard.index) + "/" + std::to_string(shard.count);
}

std::string ShardDistribution::describe() const { return "shard " + toString(shard_); }

IndexRange ShardDistribution::vertexShare(size_t vertices) const {
    return evenRange(vertices, shard_.index, shard_.count);
}

SparseRgbVectors ShardDistribution::gatherVertices(SparseRgbVectors mine, size_t vertices) {
    const IndexRange r = vertexShare(vertices);
    SparseRgbVectors all;
    all.haarBits = mine.haarBits;
    all.shFrom = mine.shFrom;
    all.reserve(vertices, mine.coefficientCount());
    appendEmptyVertices(all, r.begin);
    appendVertices(all, mine);
    appendEmptyVertices(all, vertices - r.end);
    return all;
}

std::vector<std::pair<std::string, std::string>> ShardDistribution::outputParameters(size_t vertices) const {
    const IndexRange r = vertexShare(vertices);
    return {{kShardParameter, toString(shard_)},
            {kShardVerticesParameter, std::to_string(r.begin) + "-" + std::to_string(r.end)}};
}

void appendVertices(SparseRgbVectors& all, const SparseRgbVectors& part) {
    const uint64_t base = all.offsets.back();
    if (base + part.coefficientCount() > UINT32_MAX)
        throw Error("transport", "more than 2^32 - 1 coefficients in one component");
    if (all.vertexCount() == 0) {
        all.haarBits = part.haarBits;
        all.shFrom = part.shFrom;
    } else if (all.haarBits != part.haarBits || all.shFrom != part.shFrom) {
        throw Error("transport", "joining vectors of different encodings (8-bit and 16-bit Haar values)");
    }
    all.shScales.insert(all.shScales.end(), part.shScales.begin(), part.shScales.end());
    all.offsets.reserve(all.offsets.size() + part.vertexCount());
    for (size_t v = 1; v < part.offsets.size(); ++v) all.offsets.push_back(uint32_t(base + part.offsets[v]));
    all.indices.insert(all.indices.end(), part.indices.begin(), part.indices.end());
    all.values.insert(all.values.end(), part.values.begin(), part.values.end());
    all.scales.insert(all.scales.end(), part.scales.begin(), part.scales.end());
}

SparseRgbVectors sliceVertices(const SparseRgbVectors& all, size_t begin, size_t end) {
    if (begin > end || end > all.vertexCount()) throw Error("sliceVertices", "vertex range out of bounds");
    SparseRgbVectors part;
    part.haarBits = all.haarBits;
    part.shFrom = all.shFrom;
    if (!all.shScales.empty()) part.shScales.assign(all.shScales.begin() + 3 * begin, all.shScales.begin() + 3 * end);
    const uint32_t first = all.offsets[begin], last = all.offsets[end];
    part.offsets.reserve(end - begin + 1);
    for (size_t v = begin + 1; v <= end; ++v) part.offsets.push_back(all.offsets[v] - first);
    part.indices.assign(all.indices.begin() + first, all.indices.begin() + last);
    part.values.assign(all.values.begin() + 3 * size_t(first), all.values.begin() + 3 * size_t(last));
    part.scales.assign(all.scales.begin() + 3 * begin, all.scales.begin() + 3 * end);
    return part;
}

void appendEmptyVertices(SparseRgbVectors& all, size_t count) {
    all.offsets.insert(all.offsets.end(), count, all.offsets.back());
    all.scales.insert(all.scales.end(), 3 * count, 0.0f);
    if (all.haarBits == 8 && all.shFrom != UINT32_MAX) all.shScales.insert(all.shScales.end(), 3 * count, 0.0f);
}

}  // namespace prt
