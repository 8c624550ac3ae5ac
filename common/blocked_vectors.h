#pragma once
// Blocked transport vectors: blocks of 16 vertices close on the surface share one list
// of Haar coefficient indices, chosen jointly for the block, with 8-bit values. WHY:
// the relight kernel (relight/prt/relight_kernel.h) then loads the light once per
// index for 16 vertices and does their multiply-adds as one vector operation
// (docs/transport-format.md, "Blocked files: why and measurements").
//
// BLOCKS. `order` lists the vertices block after block; spatialBlockOrder makes blocks
// of close vertices (median splits of the positions into leaves of 16), jointTruncate
// chooses each block's indices.
//
// LAYOUT. Block b holds the vertices order[16 b + lane], lane 0..15 (only the last block
// may be partial: lanes past the vertex count are padding with zero values and zero
// scales, and order has exactly V entries, a permutation of 0..V-1) and the indices
// [offsets[b], offsets[b+1]), strictly increasing, each < 6 N^2 (+ the file's SH terms,
// transport_file.h). For the n-th index of the whole array, values[48 n + 16 c + lane]
// is the int8 value of channel c for that lane; scales[48 b + 16 c + lane] is the
// lane's per-channel scale. The value of channel c of vertex order[16 b + lane] at
// index indices[n] is
//     values[48 n + 16 c + lane] * scales[48 b + 16 c + lane].
// So relighting a block is, per index, one light load and three 16-wide multiply-adds.
//
// QUANTIZATION. Per vertex and channel, scale = max |v_nc| / 127 over the block's
// indices (float), q = round(v / scale) in [-127, 127] (-128 is never written). The
// error of a value is at most half a step, max |v_nc| / 254 of the vertex's channel
// maximum, plus float rounding (kBlockQuantizationMaxRelativeError). A channel that is
// zero at every kept index has scale 0.
//
// TWO SCALES WITH AN SH PART. When shFrom is set (the file's SH terms start there,
// 6 N^2; transport_file.h) the indices >= shFrom have scales of their own, shScales
// (48 per block, laid out as scales), each max |v_nc| / 127 over those indices only;
// the maxima above then run over the Haar indices only. WHY: the SH band-0 coefficient
// dwarfs the Haar ones, and a scale set by it would leave the Haar values a few of the
// 255 levels (docs/transport-format.md, "Blocked files: why and measurements"). The
// SH indices are the last of each block (indices increase), so the kernel sums the
// Haar range and the SH range separately and scales each once. Without shFrom
// (UINT32_MAX: no SH terms, or a format version 2-3 file) shScales is empty and
// `scales` serves every index.

#include <glm/vec3.hpp>

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace prt {

struct SparseRgbVectors;

inline constexpr uint32_t kVertexBlock = 16;  // vertices per block (lanes)
inline constexpr size_t kBlockValuesPerIndex = 3 * kVertexBlock;  // 48 int8 per index

// The quantization of one block (QUANTIZATION above; appendBlock's): its `count`
// indices' values rgb[(n * lanes + lane) * 3 + c] for `lanes` (1..16) vertices, the
// indices from `split` on being the SH part (split = count without one), into
// values[48 n + 16 c + lane] (48 per index), scales and shScales (48 each: [16 c +
// lane]); padding lanes get zero values and scales. For writers that fill the arrays of
// many blocks in parallel; the values must be finite (appendBlock checks).
void quantizeBlock(const float* rgb, size_t count, size_t split, uint32_t lanes, int8_t* values, float* scales,
                   float* shScales);

// Bound of |v - dequantized v| / max_n |v_nc| for blocked values.
inline constexpr double kBlockQuantizationMaxRelativeError = 0.5 / 127.0 + 1.0 / 8388608.0;

struct BlockedRgbVectors {
    uint64_t vertices = 0;               // V; blocks = ceil(V / 16)
    std::vector<uint32_t> order;         // V: the vertex in each lane, block after block
    std::vector<uint32_t> offsets{0};    // blocks + 1
    std::vector<uint16_t> indices;       // shared by the block's vertices
    std::vector<int8_t> values;          // 48 per index: [16 c + lane]
    std::vector<float> scales;           // 48 per block: [16 c + lane] (indices < shFrom)
    uint32_t shFrom = UINT32_MAX;        // first index with its own scale (the SH part); none if UINT32_MAX
    std::vector<float> shScales;         // 48 per block if shFrom is set, else empty

    size_t vertexCount() const { return size_t(vertices); }
    size_t blockCount() const { return offsets.empty() ? 0 : offsets.size() - 1; }
    size_t indexCount() const { return indices.size(); }
    bool empty() const { return vertices == 0; }

    // Appends the next block: the vertices `lanes` (1..16 of them) that share the indices idx
    // (strictly increasing, each < 65536) with their values rgb[(n * lanes + lane) * 3 + c]
    // (finite). Quantizes per vertex and channel as described above (two scales when
    // shFrom is set: set it before the first block, or this throws). Throws prt::Error
    // on a size mismatch, unsorted or duplicate index, non-finite value, a block after a
    // partial one, or more than 2^32 - 1 indices in total.
    // (Vertex numbers are not checked here; checkBlockedVectors checks the permutation.)
    void appendBlock(const std::vector<uint32_t>& idx, const std::vector<float>& rgb,
                     const std::vector<uint32_t>& lanes);

    // Vertex v's indices (its block's) and dequantized RGB values (3 per index),
    // replacing idx and rgb. Throws std::out_of_range if v >= vertexCount() or has no
    // slot (an incomplete permutation).
    void dequantizeVertex(size_t v, std::vector<uint32_t>& idx, std::vector<float>& rgb) const;
    // Rebuilds slotOf from order (after filling the arrays directly, e.g. a file reader).
    void indexSlots();

    void clear();  // back to zero vertices
    // Bytes of the six arrays in memory (what a relight pass streams; slotOf is not read).
    size_t byteSize() const;
    // Where block b's SH indices start within the index array (offsets[b] + the count
    // of its indices < shFrom); offsets[b + 1] when shFrom is not set.
    uint32_t shBegin(size_t b) const;

    bool operator==(const BlockedRgbVectors& o) const {
        return vertices == o.vertices && order == o.order && offsets == o.offsets &&
               indices == o.indices && values == o.values && scales == o.scales &&
               shFrom == o.shFrom && shScales == o.shScales;
    }

    // Derived, not compared: the inverse of order, slotOf[vertex] = 16 b + lane
    // (UINT32_MAX where no lane holds the vertex). appendBlock and indexSlots keep it.
    std::vector<uint32_t> slotOf;
};

// Empty when the arrays are consistent (sizes; offsets monotone from 0 to the index
// count; indices strictly increasing per block and < lightCount; order a permutation of
// 0..V-1; padding lanes zero; shScales 48 per block iff shFrom is set, shFrom <
// lightCount); otherwise a one-line reason.
std::string checkBlockedVectors(const BlockedRgbVectors& b, uint32_t lightCount);

// The vertices in blocks of 16 close together: recursive median splits along the
// longest axis of the bounding box, the lower part a multiple of 16 vertices, down to
// leaves of 16 (deterministic). Returns a permutation of 0..positions.size()-1.
std::vector<uint32_t> spatialBlockOrder(const std::vector<glm::vec3>& positions);

// The joint choice of a block's indices (the blocked layout's truncation): for the
// block's vertices with per-vertex vectors T_v (any sparse support), each index i
// scores
//     score(i) = sum_v ||T_v(i)||^2 / sum_j ||T_v(j)||^2      (||.|| over RGB)
// so every vertex has the same say whatever its brightness; the `keep` indices of
// highest score are kept (ties: lower index), fewer when the union of the supports is
// smaller. For `keep` >= the union it is lossless up to quantization.
//
// Converts whole per-vertex vectors (e.g. a precompute's 512-term vectors) to blocks of
// the vertices in `order` (a permutation of the vertices, e.g. spatialBlockOrder), each
// keeping `keep` indices (>= 1). Indices >= forcedFrom (a file's SH terms, 6 N^2 and
// up; transport_file.h) are kept first whatever their score, when any lane has them,
// and get scales of their own (the result's shFrom = forcedFrom when a block has one).
// Deterministic, independent of the number of threads.
BlockedRgbVectors jointTruncate(const SparseRgbVectors& perVertex, size_t keep,
                                const std::vector<uint32_t>& order,
                                uint32_t forcedFrom = UINT32_MAX);

// jointTruncate of several components of the same vertices with ONE index list per
// block for all of them (an editable file's radial profiles: transport_file.h): the
// scores add over the components, a lane's energy is its sum over the components, and
// each result holds that block's indices with its own values and scales (the results'
// order, offsets, indices and shFrom are equal). jointTruncate(v, ...) is
// jointTruncateShared({&v}, ...)[0]. Throws prt::Error when the components' vertex
// counts differ or the list is empty, besides jointTruncate's errors.
std::vector<BlockedRgbVectors> jointTruncateShared(const std::vector<const SparseRgbVectors*>& components,
                                                   size_t keep, const std::vector<uint32_t>& order,
                                                   uint32_t forcedFrom = UINT32_MAX);

// The same components with NESTED LISTS: per block, each component's part of the score
// (score_k(i), the sum over the block's lanes of ||T_kv(i)||^2 over the lane's energy
// summed over all components, as above) decides alone. The block's union is the `keep`
// indices of highest max_k score_k(i) (ties: lower index); its threshold t is the
// lowest such max kept; component k keeps the union's indices with score_k(i) >= t.
// So every kept (component, index) pair scores at least t, the union is exactly the
// indices some component keeps (at most `keep`), and a component that matters little
// keeps few. Even when the union is every index that scores (`keep` >= their count), a
// component drops its pairs below t, each worth less than the least index kept: so,
// unlike jointTruncateShared's, the result is not lossless there (the bytes a weak
// profile's tiny values would take are saved; docs/editable-transport.md). WHY: for an editable file's balanced profiles (common/radial_basis.h,
// balancedForDipoles) a pair's score is its share of the mean squared recombined value
// over the covered materials, so one threshold for all pairs spends the bytes where the
// materials need them; one shared list gives every profile every index, also the
// profiles whose values there are far below the threshold. The results' order and
// shFrom are equal; their offsets and indices are their own. Errors as jointTruncateShared.
std::vector<BlockedRgbVectors> jointTruncateNested(const std::vector<const SparseRgbVectors*>& components,
                                                   size_t keep, const std::vector<uint32_t>& order,
                                                   uint32_t forcedFrom = UINT32_MAX);

// The on-disk form of a blocked component's indices (format version 4,
// docs/transport-format.md, "BLKC payload"): per block, the first index and then each
// index minus its predecessor minus 1, as LEB128 varints (7 bits per byte, low bits
// first, the high bit set on every byte but the last; at most 3 bytes for a 16-bit
// index, never an overlong encoding). encodeBlockIndices writes b's indices block after
// block; decodeBlockIndices reads `bytes` back into `indices` for the blocks that
// `offsets` describes and returns an empty string, or a one-line reason when the
// offsets do not rise from 0 or the stream is truncated, overlong, has bytes left over
// or decodes an index above 65535. They are inverses: decode(encode(b)) == b.indices.
std::vector<uint8_t> encodeBlockIndices(const BlockedRgbVectors& b);
std::string decodeBlockIndices(const uint8_t* bytes, size_t size, const std::vector<uint32_t>& offsets,
                               std::vector<uint16_t>& indices);
// The same coding for any lists of increasing indices, list k being
// indices[offsets[k] .. offsets[k + 1]) (the per-vertex lists of an 8-bit component,
// format version 6); `unit` names a list in the messages ("block", "vertex").
std::vector<uint8_t> encodeIndexLists(const std::vector<uint32_t>& offsets, const std::vector<uint16_t>& indices);
std::string decodeIndexLists(const uint8_t* bytes, size_t size, const std::vector<uint32_t>& offsets,
                             std::vector<uint16_t>& indices, const std::string& unit);

// Mean over vertices of kept / total energy (sum of squares over RGB, per vertex,
// vertices with zero energy count as 1) of a jointTruncate result against its source.
double retainedEnergyFraction(const SparseRgbVectors& perVertex, const BlockedRgbVectors& blocks);
// The same for components truncated together (jointTruncateShared or -Nested results
// against their sources, in the same order): a vertex's energy is summed over them.
double retainedEnergyFraction(const std::vector<const SparseRgbVectors*>& perVertex,
                              const std::vector<const BlockedRgbVectors*>& blocks);

}  // namespace prt
