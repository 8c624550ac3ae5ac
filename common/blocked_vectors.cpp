#include "common/blocked_vectors.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <glm/common.hpp>
#include <glm/vec3.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <stdexcept>
#include <string>
#include <utility>

#include "common/error.h"
#include "common/transport_file.h"

namespace prt {

namespace {

constexpr double kInt8Max = 127.0;
const char* kSubject = "blocked transport vectors";

}  // namespace

void quantizeBlock(const float* rgb, size_t count, size_t split, uint32_t lanes, int8_t* values, float* scales,
                   float* shScales) {
    const auto scaleOf = [&](uint32_t lane, int c, size_t begin, size_t end) {
        float maxAbs = 0.0f;
        for (size_t n = begin; n < end; ++n) maxAbs = std::max(maxAbs, std::fabs(rgb[(n * lanes + lane) * 3 + c]));
        // A maximum below 127 * FLT_MIN (subnormal scale) is stored as zero.
        return double(maxAbs) < kInt8Max * double(std::numeric_limits<float>::min())
                   ? 0.0f
                   : float(double(maxAbs) / kInt8Max);
    };
    for (int c = 0; c < 3; ++c)
        for (uint32_t lane = 0; lane < kVertexBlock; ++lane) {
            const bool used = lane < lanes;
            scales[16 * c + lane] = used ? scaleOf(lane, c, 0, split) : 0.0f;
            shScales[16 * c + lane] = used ? scaleOf(lane, c, split, count) : 0.0f;
        }
    for (size_t n = 0; n < count; ++n)
        for (uint32_t lane = 0; lane < kVertexBlock; ++lane)
            for (int c = 0; c < 3; ++c) {
                int q = 0;
                const float s = n < split ? scales[16 * c + lane] : shScales[16 * c + lane];
                if (lane < lanes && s > 0.0f) {
                    const double r = std::nearbyint(double(rgb[(n * lanes + lane) * 3 + c]) / double(s));
                    q = int(std::clamp(r, -kInt8Max, kInt8Max));
                }
                values[n * kBlockValuesPerIndex + 16 * size_t(c) + lane] = int8_t(q);
            }
}

void BlockedRgbVectors::appendBlock(const std::vector<uint32_t>& idx, const std::vector<float>& rgb,
                                    const std::vector<uint32_t>& laneVertices) {
    const uint32_t lanes = uint32_t(laneVertices.size());
    if (lanes < 1 || lanes > kVertexBlock)
        throw Error(kSubject, "a block holds 1 to 16 vertices, got " + std::to_string(lanes));
    if (vertices % kVertexBlock != 0)
        throw Error(kSubject, "a block after a partial block (vertex " + std::to_string(vertices) + ")");
    if (shScales.size() != (shFrom == UINT32_MAX ? 0 : scales.size()))
        throw Error(kSubject, "shFrom set after the first block");
    if (rgb.size() != size_t(3) * lanes * idx.size())
        throw Error(kSubject, "appendBlock got " + std::to_string(idx.size()) + " indices and " +
                                  std::to_string(rgb.size()) + " values for " + std::to_string(lanes) +
                                  " vertices (expected 3 per index and vertex)");
    if (uint64_t(indices.size()) + idx.size() > UINT32_MAX)
        throw Error(kSubject, "more than 2^32 - 1 indices in one component");
    for (size_t n = 0; n < idx.size(); ++n) {
        if (idx[n] > UINT16_MAX)
            throw Error(kSubject, "coefficient index " + std::to_string(idx[n]) + " does not fit 16 bits");
        if (n > 0 && idx[n] <= idx[n - 1])
            throw Error(kSubject, "block indices are not strictly increasing at " + std::to_string(idx[n]));
    }
    for (float x : rgb)
        if (!std::isfinite(x)) throw Error(kSubject, "appendBlock got a non-finite value");

    // The SH indices (>= shFrom) are the last ones: [split, idx.size()).
    const size_t split = size_t(std::lower_bound(idx.begin(), idx.end(), shFrom) - idx.begin());
    float scale[kBlockValuesPerIndex], shScale[kBlockValuesPerIndex];
    const size_t base = indices.size();
    indices.insert(indices.end(), idx.begin(), idx.end());
    values.resize((base + idx.size()) * kBlockValuesPerIndex, 0);
    quantizeBlock(rgb.data(), idx.size(), split, lanes, &values[base * kBlockValuesPerIndex], scale, shScale);
    if (offsets.empty()) offsets.push_back(0);
    offsets.push_back(uint32_t(indices.size()));
    scales.insert(scales.end(), scale, scale + kBlockValuesPerIndex);
    if (shFrom != UINT32_MAX) shScales.insert(shScales.end(), shScale, shScale + kBlockValuesPerIndex);
    for (uint32_t lane = 0; lane < lanes; ++lane) {
        const uint32_t v = laneVertices[lane];
        if (v >= slotOf.size()) slotOf.resize(size_t(v) + 1, UINT32_MAX);
        slotOf[v] = uint32_t(vertices + lane);
        order.push_back(v);
    }
    vertices += lanes;
}

void BlockedRgbVectors::indexSlots() {
    slotOf.assign(order.size(), UINT32_MAX);
    for (size_t s = 0; s < order.size(); ++s)
        if (order[s] < slotOf.size()) slotOf[order[s]] = uint32_t(s);
}

void BlockedRgbVectors::dequantizeVertex(size_t v, std::vector<uint32_t>& idx, std::vector<float>& rgb) const {
    if (v >= vertexCount())
        throw std::out_of_range("BlockedRgbVectors::dequantizeVertex: vertex " + std::to_string(v) + " of " +
                                std::to_string(vertexCount()));
    if (v >= slotOf.size() || slotOf[v] == UINT32_MAX)
        throw std::out_of_range("BlockedRgbVectors::dequantizeVertex: vertex " + std::to_string(v) + " has no lane");
    const size_t b = slotOf[v] / kVertexBlock, lane = slotOf[v] % kVertexBlock;
    const uint32_t begin = offsets[b], end = offsets[b + 1], split = shBegin(b);
    idx.assign(indices.begin() + begin, indices.begin() + end);
    rgb.resize(3 * size_t(end - begin));
    for (uint32_t n = begin; n < end; ++n)
        for (size_t c = 0; c < 3; ++c)
            rgb[3 * size_t(n - begin) + c] = float(values[n * kBlockValuesPerIndex + 16 * c + lane]) *
                                             (n < split ? scales : shScales)[b * kBlockValuesPerIndex + 16 * c + lane];
}

uint32_t BlockedRgbVectors::shBegin(size_t b) const {
    if (shFrom == UINT32_MAX) return offsets[b + 1];
    return uint32_t(std::lower_bound(indices.begin() + offsets[b], indices.begin() + offsets[b + 1], shFrom) -
                    indices.begin());
}

void BlockedRgbVectors::clear() { *this = BlockedRgbVectors(); }

size_t BlockedRgbVectors::byteSize() const {
    return (order.size() + offsets.size()) * sizeof(uint32_t) + indices.size() * sizeof(uint16_t) +
           values.size() + (scales.size() + shScales.size()) * sizeof(float);
}

namespace {

// One block of the joint truncation: per component, its chosen indices and the lanes'
// values there.
struct Block {
    std::vector<std::vector<uint32_t>> idx;  // per component
    std::vector<std::vector<float>> rgb;     // per component: (n * lanes + lane) * 3 + c
    std::vector<uint32_t> lanes;             // the block's vertices
};

// How the components of a block share its indices (jointTruncateShared, jointTruncateNested).
enum class Sharing { OneList, NestedLists };

Block chooseBlock(const std::vector<const SparseRgbVectors*>& src, const uint32_t* laneVertices, uint32_t lanes,
                  size_t keep, uint32_t forcedFrom, Sharing sharing) {
    const size_t C = src.size();
    Block out;
    out.lanes.assign(laneVertices, laneVertices + lanes);
    // [component * 16 + lane]
    std::vector<std::vector<uint32_t>> idx(C * kVertexBlock);
    std::vector<std::vector<float>> rgb(C * kVertexBlock);
    // Union of the supports, each vertex's energy-normalised contribution per index.
    std::vector<uint32_t> all;
    for (size_t k = 0; k < C; ++k)
        for (uint32_t lane = 0; lane < lanes; ++lane) {
            src[k]->dequantizeVertex(laneVertices[lane], idx[k * kVertexBlock + lane], rgb[k * kVertexBlock + lane]);
            all.insert(all.end(), idx[k * kVertexBlock + lane].begin(), idx[k * kVertexBlock + lane].end());
        }
    std::sort(all.begin(), all.end());
    all.erase(std::unique(all.begin(), all.end()), all.end());
    // componentScore[k * all.size() + at]: component k's part of the score of all[at].
    std::vector<double> componentScore(C * all.size(), 0.0);
    for (uint32_t lane = 0; lane < lanes; ++lane) {
        double energy = 0.0;
        for (size_t k = 0; k < C; ++k)
            for (float x : rgb[k * kVertexBlock + lane]) energy += double(x) * x;
        if (energy <= 0.0) continue;
        for (size_t k = 0; k < C; ++k) {
            const std::vector<uint32_t>& li = idx[k * kVertexBlock + lane];
            const std::vector<float>& lv = rgb[k * kVertexBlock + lane];
            for (size_t n = 0; n < li.size(); ++n) {
                const size_t at = size_t(std::lower_bound(all.begin(), all.end(), li[n]) - all.begin());
                double e = 0.0;
                for (int c = 0; c < 3; ++c) e += double(lv[3 * n + c]) * lv[3 * n + c];
                componentScore[k * all.size() + at] += e / energy;
            }
        }
    }
    // Indices >= forcedFrom (SH terms) come first whatever their score.
    const double inf = std::numeric_limits<double>::infinity();
    for (size_t k = 0; k < C; ++k)
        for (size_t at = 0; at < all.size(); ++at)
            if (all[at] >= forcedFrom && componentScore[k * all.size() + at] > 0.0) componentScore[k * all.size() + at] = inf;
    // The union's ranking: the sum over the components (one list), or the largest
    // component's part (nested lists: the union is then exactly the indices some
    // component keeps at the block's threshold).
    std::vector<double> score(all.size(), 0.0);
    for (size_t k = 0; k < C; ++k)
        for (size_t at = 0; at < all.size(); ++at) {
            const double x = componentScore[k * all.size() + at];
            score[at] = sharing == Sharing::OneList ? score[at] + x : std::max(score[at], x);
        }
    std::vector<uint32_t> order(all.size());
    std::iota(order.begin(), order.end(), 0u);
    const size_t kept = std::min(keep, order.size());
    // Highest score first, ties by lower index; indices with zero score are never kept.
    std::partial_sort(order.begin(), order.begin() + ptrdiff_t(kept), order.end(),
                      [&](uint32_t a, uint32_t b) { return score[a] != score[b] ? score[a] > score[b] : a < b; });
    order.resize(kept);
    order.erase(std::remove_if(order.begin(), order.end(), [&](uint32_t a) { return score[a] <= 0.0; }),
                order.end());
    std::sort(order.begin(), order.end());
    // The threshold of nested lists: the lowest union score kept (also when the union
    // is every index that scores: a pair below it is worth less than any index kept).
    double threshold = inf;
    for (uint32_t at : order) threshold = std::min(threshold, score[at]);
    out.idx.assign(C, {});
    out.rgb.resize(C);
    for (size_t k = 0; k < C; ++k) {
        std::vector<uint32_t>& list = out.idx[k];
        for (uint32_t at : order)
            if (sharing == Sharing::OneList || componentScore[k * all.size() + at] >= threshold) list.push_back(all[at]);
        out.rgb[k].assign(list.size() * lanes * 3, 0.0f);
        for (uint32_t lane = 0; lane < lanes; ++lane) {
            const std::vector<uint32_t>& li = idx[k * kVertexBlock + lane];
            const std::vector<float>& lv = rgb[k * kVertexBlock + lane];
            // Both lists are sorted: one merge.
            size_t n = 0;
            for (size_t m = 0; m < li.size() && n < list.size(); ++m) {
                while (n < list.size() && list[n] < li[m]) ++n;
                if (n < list.size() && list[n] == li[m])
                    for (int c = 0; c < 3; ++c) out.rgb[k][(n * lanes + lane) * 3 + c] = lv[3 * m + c];
            }
        }
    }
    return out;
}

}  // namespace

BlockedRgbVectors jointTruncate(const SparseRgbVectors& perVertex, size_t keep,
                                const std::vector<uint32_t>& order, uint32_t forcedFrom) {
    return std::move(jointTruncateShared({&perVertex}, keep, order, forcedFrom).front());
}

namespace {

std::vector<BlockedRgbVectors> truncateComponents(const std::vector<const SparseRgbVectors*>& components,
                                                  size_t keep, const std::vector<uint32_t>& order,
                                                  uint32_t forcedFrom, Sharing sharing) {
    if (keep < 1) throw Error(kSubject, "a block must keep at least one coefficient");
    if (components.empty()) throw Error(kSubject, "no components to truncate jointly");
    const size_t vertices = components.front()->vertexCount();
    for (const SparseRgbVectors* c : components)
        if (c->vertexCount() != vertices)
            throw Error(kSubject, "components of " + std::to_string(c->vertexCount()) + " and " +
                                      std::to_string(vertices) + " vertices cannot share blocks");
    if (order.size() != vertices) throw Error(kSubject, "block order of " + std::to_string(order.size()) +
                                                            " vertices for " + std::to_string(vertices));
    {
        std::vector<bool> seen(vertices, false);
        for (uint32_t v : order) {
            if (v >= vertices || seen[v]) throw Error(kSubject, "block order is not a permutation of the vertices");
            seen[v] = true;
        }
    }
    const size_t blocks = (vertices + kVertexBlock - 1) / kVertexBlock;
    // The SH scales are kept when some block keeps an SH index, which is known only after
    // the choice: every block is quantized with them (an SH-free block gives the same
    // values either way) and they are dropped at the end if no block kept one.
    // A block keeps at most `keep` indices, and at most its 16 vertices' indices.
    size_t widest = 0;
    for (const SparseRgbVectors* c : components)
        for (size_t v = 0; v < vertices; ++v) widest = std::max<size_t>(widest, c->offsets[v + 1] - c->offsets[v]);
    const size_t perBlock = std::min(keep, kVertexBlock * widest);
    std::vector<BlockedRgbVectors> out(components.size());
    for (BlockedRgbVectors& o : out) {
        o.shFrom = forcedFrom;
        o.offsets.reserve(blocks + 1);
        o.indices.reserve(blocks * perBlock);
        o.values.reserve(blocks * perBlock * kBlockValuesPerIndex);
        o.scales.reserve(blocks * kBlockValuesPerIndex);
        if (forcedFrom != UINT32_MAX) o.shScales.reserve(blocks * kBlockValuesPerIndex);
    }
    // Chosen in parallel a batch at a time: a chosen block holds its values in float,
    // 4x the bytes of the quantized block it becomes.
    constexpr size_t kBatchBlocks = 4096;
    bool keptSh = false;
    std::vector<Block> chosen;
    for (size_t begin = 0; begin < blocks; begin += kBatchBlocks) {
        const size_t end = std::min(blocks, begin + kBatchBlocks);
        chosen.assign(end - begin, Block());
        tbb::parallel_for(tbb::blocked_range<size_t>(begin, end, 64), [&](const tbb::blocked_range<size_t>& r) {
            for (size_t b = r.begin(); b != r.end(); ++b) {
                const size_t first = b * kVertexBlock;
                const uint32_t lanes = uint32_t(std::min<size_t>(kVertexBlock, vertices - first));
                chosen[b - begin] = chooseBlock(components, order.data() + first, lanes, keep, forcedFrom, sharing);
            }
        });
        for (Block& b : chosen) {
            for (size_t k = 0; k < out.size(); ++k) {
                if (!b.idx[k].empty() && b.idx[k].back() >= forcedFrom) keptSh = true;
                out[k].appendBlock(b.idx[k], b.rgb[k], b.lanes);
            }
            b = Block();
        }
    }
    if (!keptSh)
        for (BlockedRgbVectors& o : out) {
            o.shFrom = UINT32_MAX;
            o.shScales = {};
        }
    return out;
}

}  // namespace

std::vector<BlockedRgbVectors> jointTruncateShared(const std::vector<const SparseRgbVectors*>& components,
                                                   size_t keep, const std::vector<uint32_t>& order,
                                                   uint32_t forcedFrom) {
    return truncateComponents(components, keep, order, forcedFrom, Sharing::OneList);
}

std::vector<BlockedRgbVectors> jointTruncateNested(const std::vector<const SparseRgbVectors*>& components,
                                                   size_t keep, const std::vector<uint32_t>& order,
                                                   uint32_t forcedFrom) {
    return truncateComponents(components, keep, order, forcedFrom, Sharing::NestedLists);
}

std::string checkBlockedVectors(const BlockedRgbVectors& b, uint32_t lightCount) {
    const uint64_t blocks = (b.vertices + kVertexBlock - 1) / kVertexBlock;
    if (b.order.size() != b.vertices) return "block order has " + std::to_string(b.order.size()) +
                                              " entries for " + std::to_string(b.vertices) + " vertices";
    if (b.offsets.size() != blocks + 1 || b.offsets.front() != 0 || b.offsets.back() != b.indices.size())
        return "block offsets inconsistent with " + std::to_string(blocks) + " blocks and " +
               std::to_string(b.indices.size()) + " indices";
    if (b.values.size() != b.indices.size() * kBlockValuesPerIndex)
        return "blocked values hold " + std::to_string(b.values.size()) + " bytes, expected 48 per index";
    if (b.scales.size() != blocks * kBlockValuesPerIndex)
        return "blocked scales hold " + std::to_string(b.scales.size()) + " floats, expected 48 per block";
    if (b.shFrom != UINT32_MAX && b.shFrom >= lightCount)
        return "SH scales start at index " + std::to_string(b.shFrom) + " >= " + std::to_string(lightCount);
    if (b.shScales.size() != (b.shFrom == UINT32_MAX ? 0 : blocks * kBlockValuesPerIndex))
        return "blocked SH scales hold " + std::to_string(b.shScales.size()) + " floats, expected " +
               (b.shFrom == UINT32_MAX ? std::string("none without an SH part") : std::string("48 per block"));
    // Offsets first: every later loop indexes through them.
    for (uint64_t k = 0; k < blocks; ++k)
        if (b.offsets[k] > b.offsets[k + 1]) return "block offsets decrease at block " + std::to_string(k);
    std::vector<bool> seen(b.vertices, false);
    for (uint32_t v : b.order) {
        if (v >= b.vertices || seen[v]) return "block order is not a permutation of the vertices";
        seen[v] = true;
    }
    for (uint64_t k = 0; k < blocks; ++k) {
        const uint32_t begin = b.offsets[k], end = b.offsets[k + 1];
        const uint64_t lanes = std::min<uint64_t>(kVertexBlock, b.vertices - k * kVertexBlock);
        for (uint32_t n = begin; n < end; ++n) {
            for (uint64_t lane = lanes; lane < kVertexBlock; ++lane)
                for (size_t c = 0; c < 3; ++c)
                    if (b.values[n * kBlockValuesPerIndex + 16 * c + lane] != 0)
                        return "padding lane with a non-zero value in block " + std::to_string(k);
            if (b.indices[n] >= lightCount)
                return "coefficient index " + std::to_string(b.indices[n]) + " >= " + std::to_string(lightCount) + " (6 N^2 + SH terms)";
            if (n > begin && b.indices[n] <= b.indices[n - 1])
                return "block " + std::to_string(k) + " indices not strictly increasing";
        }
        for (const std::vector<float>* scales : {&b.scales, &b.shScales}) {
            if (scales->empty()) continue;
            for (int c = 0; c < 3; ++c)
                for (uint32_t lane = 0; lane < kVertexBlock; ++lane) {
                    const float s = (*scales)[k * kBlockValuesPerIndex + 16 * size_t(c) + lane];
                    if (!std::isfinite(s) || s < 0.0f) return "block scale not finite and >= 0";
                    if (k * kVertexBlock + lane >= b.vertices && s != 0.0f) return "padding lane with a non-zero scale";
                }
        }
    }
    return {};
}

std::vector<uint8_t> encodeIndexLists(const std::vector<uint32_t>& offsets, const std::vector<uint16_t>& indices) {
    std::vector<uint8_t> out;
    out.reserve(indices.size() + indices.size() / 8);
    for (size_t k = 0; k + 1 < offsets.size(); ++k)
        for (uint32_t n = offsets[k]; n < offsets[k + 1]; ++n) {
            uint32_t d = n == offsets[k] ? indices[n] : uint32_t(indices[n] - indices[n - 1] - 1);
            while (d >= 0x80) {
                out.push_back(uint8_t(0x80 | (d & 0x7F)));
                d >>= 7;
            }
            out.push_back(uint8_t(d));
        }
    return out;
}

std::vector<uint8_t> encodeBlockIndices(const BlockedRgbVectors& b) { return encodeIndexLists(b.offsets, b.indices); }

std::string decodeBlockIndices(const uint8_t* bytes, size_t size, const std::vector<uint32_t>& offsets,
                               std::vector<uint16_t>& indices) {
    return decodeIndexLists(bytes, size, offsets, indices, "block");
}

std::string decodeIndexLists(const uint8_t* bytes, size_t size, const std::vector<uint32_t>& offsets,
                             std::vector<uint16_t>& indices, const std::string& unit) {
    if (offsets.empty() || offsets.front() != 0 || !std::is_sorted(offsets.begin(), offsets.end()))
        return unit + " offsets do not rise from 0";
    const size_t total = offsets.back();
    indices.resize(total);
    size_t at = 0;
    for (size_t k = 0; k + 1 < offsets.size(); ++k)
        for (uint32_t n = offsets[k]; n < offsets[k + 1]; ++n) {
            uint32_t d = 0;
            for (int shift = 0;; shift += 7) {
                if (at == size)
                    return "index stream ends inside " + unit + " " + std::to_string(k) + " (" + std::to_string(size) +
                           " bytes)";
                const uint8_t byte = bytes[at++];
                if (shift == 14 && byte >= 0x04)
                    return "index stream: a varint at byte " + std::to_string(at - 1) + " exceeds 16 bits";
                d |= uint32_t(byte & 0x7F) << shift;
                if (!(byte & 0x80)) {
                    if (byte == 0 && shift > 0)
                        return "index stream: overlong varint at byte " + std::to_string(at - 1);
                    break;
                }
            }
            const uint32_t index = n == offsets[k] ? d : uint32_t(indices[n - 1]) + 1 + d;
            if (index > UINT16_MAX)
                return "index stream: " + unit + " " + std::to_string(k) + " decodes index " + std::to_string(index) +
                       " > 65535";
            indices[n] = uint16_t(index);
        }
    if (at != size) return "index stream has " + std::to_string(size - at) + " bytes after its last index";
    return {};
}

std::vector<uint32_t> spatialBlockOrder(const std::vector<glm::vec3>& positions) {
    std::vector<uint32_t> order(positions.size());
    std::iota(order.begin(), order.end(), 0u);
    // Explicit stack of [begin, end) ranges; the lower part of each split is a multiple
    // of 16, so only the range holding the last vertex can end in a partial block.
    std::vector<std::pair<size_t, size_t>> todo{{0, order.size()}};
    while (!todo.empty()) {
        const auto [begin, end] = todo.back();
        todo.pop_back();
        if (end - begin <= kVertexBlock) continue;
        glm::vec3 lo(std::numeric_limits<float>::max()), hi(-std::numeric_limits<float>::max());
        for (size_t i = begin; i < end; ++i) {
            lo = glm::min(lo, positions[order[i]]);
            hi = glm::max(hi, positions[order[i]]);
        }
        const glm::vec3 d = hi - lo;
        const int axis = d.x >= d.y ? (d.x >= d.z ? 0 : 2) : (d.y >= d.z ? 1 : 2);
        const size_t half = (end - begin) / 2;
        const size_t mid = begin + std::max<size_t>(kVertexBlock, (half + kVertexBlock - 1) / kVertexBlock * kVertexBlock);
        std::nth_element(order.begin() + ptrdiff_t(begin), order.begin() + ptrdiff_t(mid), order.begin() + ptrdiff_t(end),
                         [&](uint32_t a, uint32_t b) {
                             const float pa = positions[a][axis], pb = positions[b][axis];
                             return pa != pb ? pa < pb : a < b;
                         });
        todo.push_back({mid, end});
        todo.push_back({begin, mid});
    }
    return order;
}

double retainedEnergyFraction(const SparseRgbVectors& perVertex, const BlockedRgbVectors& blocks) {
    return retainedEnergyFraction(std::vector<const SparseRgbVectors*>{&perVertex},
                                  std::vector<const BlockedRgbVectors*>{&blocks});
}

double retainedEnergyFraction(const std::vector<const SparseRgbVectors*>& perVertex,
                              const std::vector<const BlockedRgbVectors*>& blocks) {
    if (perVertex.empty() || perVertex.size() != blocks.size())
        throw Error(kSubject, "retained energy of " + std::to_string(blocks.size()) + " blocked components against " +
                                  std::to_string(perVertex.size()));
    const size_t vertices = perVertex.front()->vertexCount();
    for (size_t k = 0; k < perVertex.size(); ++k)
        if (perVertex[k]->vertexCount() != vertices || blocks[k]->vertexCount() != vertices)
            throw Error(kSubject, "retained energy of " + std::to_string(blocks[k]->vertexCount()) +
                                      " blocked vertices against " + std::to_string(perVertex[k]->vertexCount()));
    std::vector<uint32_t> idx;
    std::vector<float> rgb;
    double sum = 0.0;
    for (size_t v = 0; v < vertices; ++v) {
        double total = 0.0, kept = 0.0;
        for (size_t k = 0; k < perVertex.size(); ++k) {
            perVertex[k]->dequantizeVertex(v, idx, rgb);
            for (float x : rgb) total += double(x) * x;
            blocks[k]->dequantizeVertex(v, idx, rgb);
            for (float x : rgb) kept += double(x) * x;
        }
        sum += total > 0.0 ? std::min(1.0, kept / total) : 1.0;
    }
    return vertices ? sum / double(vertices) : 1.0;
}

}  // namespace prt
