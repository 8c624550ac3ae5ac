#include "relight/prt/relight_kernel.h"

#include "common/sh_part.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <cstdint>
#include <cstring>
#include <limits>
#include <stdexcept>
#include <string>

#include "common/error.h"
#include "common/util.h"

#if defined(__SSE2__)
#include <emmintrin.h>
#include <xmmintrin.h>
#define PRT_RELIGHT_SSE2 1
#else
#define PRT_RELIGHT_SSE2 0
#endif
// The AVX2 + FMA kernel is compiled with a target attribute and chosen at run time.
#if PRT_RELIGHT_SSE2 && defined(__x86_64__) && defined(__GNUC__)
#include <immintrin.h>
#define PRT_RELIGHT_AVX2 1
#else
#define PRT_RELIGHT_AVX2 0
#endif
// So is the AVX-512 kernel of blocked components (same conditions).
#define PRT_RELIGHT_AVX512 PRT_RELIGHT_AVX2

namespace prt {

namespace {

// Vertices per TBB task. A 128-coefficient vertex streams ~1 KB, so a block is
// ~0.5 MB of transport data: large enough to amortise task overhead, small enough
// to balance two to a few dozen cores on 10^4..10^6 vertices.
constexpr size_t kVertexGrain = 512;

// Software prefetch distance, in coefficients, for the index and value streams (the
// arrays are contiguous across vertices, so the prefetches run ahead into the next
// vertices). 256 coefficients = 1.5 KB of values, 512 B of indices ahead: the hardware
// prefetchers alone leave a single core well short of its streaming rate, and 256 beat
// 128 and 512 (docs/performance.md, "Design measurements"). Prefetches never fault, so
// running past the end of an array is harmless; the address is formed as an integer so
// no out-of-range pointer is ever created.
constexpr size_t kPrefetchAhead = 256;

#if PRT_RELIGHT_SSE2
inline void prefetchAhead(const void* p, size_t bytes) {
    _mm_prefetch(reinterpret_cast<const char*>(reinterpret_cast<uintptr_t>(p) + bytes), _MM_HINT_T0);
}
#endif

// One selected component and where its result goes.
struct Job {
    const TransportComponent* component = nullptr;
    int slot = -1;  // -1: summed into diffuse; k >= 0: terms[k]
};

// The components the set selects, diffuse ones first, term components ordered by
// term index. Also checks that they agree on the vertex count.
struct Plan {
    size_t vertexCount = 0;
    std::vector<Job> diffuse;
    std::vector<Job> terms;
};

Plan makePlan(const TransportFile& file, const ScatteringComponents& set) {
    Plan plan;
    plan.vertexCount = file.components.empty() ? size_t(file.mesh.vertexCount)
                                               : file.components.front().vertexCount();
    for (const TransportComponent& c : file.components) {
        if (c.vertexCount() != plan.vertexCount)
            throw Error("transport file", componentName(c.kind, c.term) + " has " +
                                              std::to_string(c.vertexCount()) +
                                              " vertices, another component has " +
                                              std::to_string(plan.vertexCount));
        switch (c.kind) {
            case ComponentKind::MultipleScattering:
                if (set.multipleScattering) plan.diffuse.push_back({&c, -1});
                break;
            case ComponentKind::SingleScatteringIsotropic:
                if (set.singleScattering) plan.diffuse.push_back({&c, -1});
                break;
            case ComponentKind::SingleScatteringTerm:
                if (set.singleScattering) plan.terms.push_back({&c, 0});
                break;
            case ComponentKind::MultipleScatteringProfiles:
                throw Error("transport file", componentName(c.kind, c.term) +
                                                  ": an editable file's profiles relight through their recombination "
                                                  "(loadRelightObject, relight/prt/editable_transport.h)");
            default:
                throw Error("transport file", componentName(c.kind, c.term));
        }
    }
    std::sort(plan.terms.begin(), plan.terms.end(), [](const Job& a, const Job& b) {
        return a.component->term < b.component->term;
    });
    for (size_t k = 0; k < plan.terms.size(); ++k) {
        if (k > 0 && plan.terms[k].component->term == plan.terms[k - 1].component->term)
            throw Error("transport file",
                        componentName(ComponentKind::SingleScatteringTerm,
                                      plan.terms[k].component->term) +
                            " appears twice");
        plan.terms[k].slot = int(k);
    }
    return plan;
}

// Whole-array consistency of one component's arrays (O(1)): CSR or blocked. Per-vertex
// (per-block) offsets, the largest index of each vertex (block) and a block's vertex
// numbers are checked inside the kernel.
void checkArrays(const TransportComponent& c) {
    if (c.blocked()) {
        const BlockedRgbVectors& b = c.blocks;
        const uint64_t blocks = (b.vertices + kVertexBlock - 1) / kVertexBlock;
        if (b.order.size() != b.vertices || b.offsets.size() != blocks + 1 || b.offsets.front() != 0 ||
            b.offsets.back() != b.indices.size() || b.values.size() != kBlockValuesPerIndex * b.indices.size() ||
            b.scales.size() != kBlockValuesPerIndex * blocks ||
            b.shScales.size() != (b.shFrom == UINT32_MAX ? 0 : kBlockValuesPerIndex * blocks) ||
            b.indices.size() > UINT32_MAX)
            throw Error("transport file", componentName(c.kind, c.term) +
                                              ": inconsistent blocked array sizes (vertices " +
                                              std::to_string(b.vertices) + ", order " +
                                              std::to_string(b.order.size()) + ", offsets " +
                                              std::to_string(b.offsets.size()) + ", indices " +
                                              std::to_string(b.indices.size()) + ", values " +
                                              std::to_string(b.values.size()) + ", scales " +
                                              std::to_string(b.scales.size()) + ", SH scales " +
                                              std::to_string(b.shScales.size()) + ")");
        return;
    }
    const SparseRgbVectors& s = c.vectors;
    const size_t v = s.vertexCount();
    if (s.offsets.empty() || s.offsets.front() != 0 || s.offsets.back() != s.indices.size() ||
        s.values.size() != 3 * s.indices.size() || s.scales.size() != 3 * v ||
        (!s.shScales.empty() && s.shScales.size() != 3 * v))
        throw Error("transport file", componentName(c.kind, c.term) +
                                          ": inconsistent array sizes (offsets " +
                                          std::to_string(s.offsets.size()) + ", indices " +
                                          std::to_string(s.indices.size()) + ", values " +
                                          std::to_string(s.values.size()) + ", scales " +
                                          std::to_string(s.scales.size()) + ")");
}

void checkLight(const TransportFile& file, const LightVector& light) {
    if (light.size <= 0) throw Error("light vector", "empty (cubemap size " + std::to_string(light.size) + ")");
    if (uint32_t(light.size) != file.cubemapSize)
        throw Error("light vector", "cubemap size " + std::to_string(light.size) +
                                        " does not match the transport file's " +
                                        std::to_string(file.cubemapSize));
    const size_t count = size_t(6) * size_t(light.size) * size_t(light.size);
    if (light.rgb.size() != 3 * count)
        throw Error("light vector", "holds " + std::to_string(light.rgb.size()) +
                                        " floats, expected 3 x 6 x " + std::to_string(light.size) +
                                        "^2 = " + std::to_string(3 * count));
}

// The light's SH projections for a file with `terms` SH terms (terms x 3 floats): the
// light vector's own, or derived from its Haar coefficients for a hand-built vector.
std::vector<float> lightShPart(const LightVector& light, uint32_t terms) {
    if (terms == 0) return {};
    if (light.sh.size() >= 3 * size_t(terms)) return {light.sh.begin(), light.sh.begin() + 3 * ptrdiff_t(terms)};
    std::vector<float> sh(3 * size_t(terms));
    shProjectLight(light.rgb.data(), light.size, 3, int(terms), sh.data());
    return sh;
}

// The light vector converted for gathering: `Stride` floats per coefficient, RGB
// first, the file's SH terms after the 6 N^2 Haar coefficients (common/sh_part.h).
// Stride 4 pads each coefficient to 16 bytes (one aligned SSE load, never straddling a
// cache line); stride 3 is the plain interleaved layout (25% smaller, an
// unaligned 16-byte load that reads the next coefficient's R, which is ignored). The
// buffer has one extra coefficient of zeros so the stride-3 over-read stays inside.
template <int Stride>
std::vector<float> gatherLayout(const LightVector& light, uint32_t shTerms) {
    const size_t haar = light.coefficientCount();
    const size_t count = haar + shTerms;
    std::vector<float> out((count + 1) * Stride, 0.0f);
    for (size_t k = 0; k < haar; ++k)
        for (int c = 0; c < 3; ++c) out[k * Stride + c] = light.rgb[3 * k + c];
    const std::vector<float> sh = lightShPart(light, shTerms);
    for (size_t k = 0; k < shTerms; ++k)
        for (int c = 0; c < 3; ++c) out[(haar + k) * Stride + c] = sh[3 * k + c];
    return out;
}

// Per-component view of the arrays the kernel streams.
struct Stream {
    const uint32_t* offsets;
    const uint16_t* indices;
    const int16_t* values;
    const float* scales;
    uint32_t total;                      // coefficients in the component
    const float* shScales = nullptr;     // 8-bit Haar vectors with an SH part: its scales
    uint32_t shFrom = UINT32_MAX;        // ... from this index on
};

Stream streamOf(const SparseRgbVectors& s) {
    return {s.offsets.data(), s.indices.data(), s.values.data(), s.scales.data(), uint32_t(s.indices.size()),
            s.shScales.empty() ? nullptr : s.shScales.data(), s.shFrom};
}

// Vertex v's coefficients, validated. `safe` is how many of the first ones may be read
// with an 8-byte load of their three int16 values (over-reading the next coefficient's
// R): all but the component's very last coefficient.
struct VertexSpan {
    const uint16_t* idx;
    const int16_t* q;
    size_t count;
    size_t safe;
};

// False when v's offsets are out of order or its largest index is >= lightCount.
// Indices increase within a vertex (SparseRgbVectors invariant), so the last index is
// the largest: one comparison per vertex keeps every gather in bounds.
inline bool vertexSpan(const Stream& s, size_t v, uint32_t lightCount, VertexSpan& span) {
    const uint32_t begin = s.offsets[v], end = s.offsets[v + 1];
    if (begin > end || end > s.total || (end > begin && s.indices[end - 1] >= lightCount))
        return false;
    span.idx = s.indices + begin;
    span.q = s.values + 3 * size_t(begin);
    span.count = end - begin;
    span.safe = (end == s.total && end > begin) ? span.count - 1 : span.count;
    return true;
}

template <bool Add>
inline void store(const Stream& s, size_t v, const float sum[3], glm::vec3* out) {
    const glm::vec3 r(sum[0] * s.scales[3 * v], sum[1] * s.scales[3 * v + 1],
                      sum[2] * s.scales[3 * v + 2]);
    if constexpr (Add)
        out[v] += r;
    else
        out[v] = r;
}

// With SH scales (Stream::shScales): cuts the SH indices (the last ones: indices
// increase) off `span` and returns them as a span of their own. An 8-byte load of the
// Haar part's last coefficient reads the first SH coefficient's R, which exists.
inline VertexSpan splitShSpan(VertexSpan& span, uint32_t shFrom) {
    size_t k = span.count;
    while (k > 0 && span.idx[k - 1] >= shFrom) --k;
    const VertexSpan sh{span.idx + k, span.q + 3 * k, span.count - k, span.safe > k ? span.safe - k : 0};
    span.count = k;
    span.safe = std::min(span.safe, k);
    return sh;
}

// The SH part's sum, times its scales, added to out[v] (after store).
inline void addSh(const Stream& s, size_t v, const float sum[3], glm::vec3* out) {
    out[v] += glm::vec3(sum[0] * s.shScales[3 * v], sum[1] * s.shScales[3 * v + 1], sum[2] * s.shScales[3 * v + 2]);
}

// sum_n q[3n + c] * light[idx[n] * Stride + c] for c = 0..2, in float. Two variants
// with the same structure: four independent accumulators (the add latency, not the
// memory, would otherwise bound the loop), summed pairwise at the end.
//
// Baseline (SSE2, any x86-64): a coefficient is one 8-byte load of its three int16
// values (lane 3 is the next coefficient's R, or 0 from a safe copy for the very last
// coefficient of a component), sign-extended (unpack + shift) and converted to float,
// times one 16-byte load of the light coefficient, then added. Lane 3 of the stride-4
// light is 0; with stride 3 it is a neighbour's value and lane 3 is never read.
// Without SSE2 (other architectures) a scalar loop of the same shape.
template <int Stride>
inline void dotBaseline(const VertexSpan& span, const float* light, float out[3]) {
    const uint16_t* idx = span.idx;
    const int16_t* q = span.q;
#if PRT_RELIGHT_SSE2
    const auto loadQ = [](const int16_t* p) {
        const __m128i w = _mm_loadl_epi64(reinterpret_cast<const __m128i*>(p));
        return _mm_cvtepi32_ps(_mm_srai_epi32(_mm_unpacklo_epi16(w, w), 16));
    };
    const auto loadL = [light](uint16_t k) { return _mm_loadu_ps(light + size_t(k) * Stride); };
    __m128 a0 = _mm_setzero_ps(), a1 = a0, a2 = a0, a3 = a0;
    size_t n = 0;
    for (; n + 4 <= span.safe; n += 4) {
        prefetchAhead(q + 3 * n, 3 * sizeof(int16_t) * kPrefetchAhead);
        prefetchAhead(idx + n, sizeof(uint16_t) * kPrefetchAhead);
        a0 = _mm_add_ps(a0, _mm_mul_ps(loadQ(q + 3 * n), loadL(idx[n])));
        a1 = _mm_add_ps(a1, _mm_mul_ps(loadQ(q + 3 * n + 3), loadL(idx[n + 1])));
        a2 = _mm_add_ps(a2, _mm_mul_ps(loadQ(q + 3 * n + 6), loadL(idx[n + 2])));
        a3 = _mm_add_ps(a3, _mm_mul_ps(loadQ(q + 3 * n + 9), loadL(idx[n + 3])));
    }
    for (; n < span.safe; ++n) a0 = _mm_add_ps(a0, _mm_mul_ps(loadQ(q + 3 * n), loadL(idx[n])));
    for (; n < span.count; ++n) {  // the component's last coefficient: no over-read
        int16_t tmp[4] = {0, 0, 0, 0};
        std::memcpy(tmp, q + 3 * n, 3 * sizeof(int16_t));
        a0 = _mm_add_ps(a0, _mm_mul_ps(loadQ(tmp), loadL(idx[n])));
    }
    alignas(16) float sum[4];
    _mm_store_ps(sum, _mm_add_ps(_mm_add_ps(a0, a1), _mm_add_ps(a2, a3)));
    for (int c = 0; c < 3; ++c) out[c] = sum[c];
#else
    float acc[4][3] = {};
    size_t n = 0;
    for (; n + 4 <= span.count; n += 4)
        for (int u = 0; u < 4; ++u) {
            const float* l = light + size_t(idx[n + u]) * Stride;
            for (int c = 0; c < 3; ++c) acc[u][c] += float(q[3 * (n + u) + c]) * l[c];
        }
    for (; n < span.count; ++n) {
        const float* l = light + size_t(idx[n]) * Stride;
        for (int c = 0; c < 3; ++c) acc[0][c] += float(q[3 * n + c]) * l[c];
    }
    for (int c = 0; c < 3; ++c) out[c] = (acc[0][c] + acc[1][c]) + (acc[2][c] + acc[3][c]);
#endif
}

template <int Stride, bool Add>
bool relightRangeBaseline(const Stream& s, size_t first, size_t last, const float* light,
                          uint32_t lightCount, glm::vec3* out, size_t& badVertex) {
    for (size_t v = first; v < last; ++v) {
        VertexSpan span;
        if (!vertexSpan(s, v, lightCount, span)) {
            badVertex = v;
            return false;
        }
        float sum[3];
        const VertexSpan sh = s.shScales ? splitShSpan(span, s.shFrom) : VertexSpan{};
        dotBaseline<Stride>(span, light, sum);
        store<Add>(s, v, sum, out);
        if (s.shScales) {
            dotBaseline<Stride>(sh, light, sum);
            addSh(s, v, sum, out);
        }
    }
    return true;
}

#if PRT_RELIGHT_AVX2
// AVX2 + FMA (x86-64-v3, chosen at run time): the same loop, but the sign extension is
// one vpmovsxwd straight from memory and multiply-add one FMA with the light load
// folded in: about 5 instructions per coefficient instead of 10. (FMA rounds once,
// so results differ from the baseline's in the last bits.)
template <int Stride>
__attribute__((target("avx2,fma"))) inline void dotAvx2(const VertexSpan& span,
                                                          const float* light, float out[3]) {
    const uint16_t* idx = span.idx;
    const int16_t* q = span.q;
#define PRT_Q(p) _mm_cvtepi32_ps(_mm_cvtepi16_epi32(_mm_loadl_epi64(reinterpret_cast<const __m128i*>(p))))
#define PRT_L(k) _mm_loadu_ps(light + size_t(k) * Stride)
    __m128 a0 = _mm_setzero_ps(), a1 = a0, a2 = a0, a3 = a0;
    size_t n = 0;
    for (; n + 4 <= span.safe; n += 4) {
        prefetchAhead(q + 3 * n, 3 * sizeof(int16_t) * kPrefetchAhead);
        prefetchAhead(idx + n, sizeof(uint16_t) * kPrefetchAhead);
        a0 = _mm_fmadd_ps(PRT_Q(q + 3 * n), PRT_L(idx[n]), a0);
        a1 = _mm_fmadd_ps(PRT_Q(q + 3 * n + 3), PRT_L(idx[n + 1]), a1);
        a2 = _mm_fmadd_ps(PRT_Q(q + 3 * n + 6), PRT_L(idx[n + 2]), a2);
        a3 = _mm_fmadd_ps(PRT_Q(q + 3 * n + 9), PRT_L(idx[n + 3]), a3);
    }
    for (; n < span.safe; ++n) a0 = _mm_fmadd_ps(PRT_Q(q + 3 * n), PRT_L(idx[n]), a0);
    for (; n < span.count; ++n) {
        int16_t tmp[4] = {0, 0, 0, 0};
        std::memcpy(tmp, q + 3 * n, 3 * sizeof(int16_t));
        a0 = _mm_fmadd_ps(PRT_Q(tmp), PRT_L(idx[n]), a0);
    }
#undef PRT_Q
#undef PRT_L
    alignas(16) float sum[4];
    _mm_store_ps(sum, _mm_add_ps(_mm_add_ps(a0, a1), _mm_add_ps(a2, a3)));
    for (int c = 0; c < 3; ++c) out[c] = sum[c];
}

// A copy of relightRangeBaseline compiled for AVX2 (a function of another target
// cannot be inlined into a baseline one, so the vertex loop is duplicated).
template <int Stride, bool Add>
__attribute__((target("avx2,fma"))) bool relightRangeAvx2(const Stream& s, size_t first,
                                                           size_t last, const float* light,
                                                           uint32_t lightCount, glm::vec3* out,
                                                           size_t& badVertex) {
    for (size_t v = first; v < last; ++v) {
        VertexSpan span;
        if (!vertexSpan(s, v, lightCount, span)) {
            badVertex = v;
            return false;
        }
        float sum[3];
        const VertexSpan sh = s.shScales ? splitShSpan(span, s.shFrom) : VertexSpan{};
        dotAvx2<Stride>(span, light, sum);
        store<Add>(s, v, sum, out);
        if (s.shScales) {
            dotAvx2<Stride>(sh, light, sum);
            addSh(s, v, sum, out);
        }
    }
    return true;
}

#endif

// ---------------------------------------------------------------------------------
// Blocked components (common/blocked_vectors.h): 16 vertices (lanes) share one index
// list, 48 int8 values per index laid out [16 c + lane]. Per index the kernel loads the
// light's RGB once (three broadcasts) and does three 16-wide multiply-adds, one per
// channel, in 48 float accumulators (one per lane and channel), then multiplies by the
// block's 48 scales and scatters the 16 results to their vertices order[16 b + lane].
// With SH scales (BlockedRgbVectors::shFrom) the block's indices are two parts, the Haar
// indices then the SH ones (the last, indices increasing): each variant runs its loop
// over both parts in turn, scaling and resetting the accumulators between them.

// Blocks per TBB task: 32 blocks = 512 vertices, as kVertexGrain; at 160 indices per
// block a task streams ~256 KB.
constexpr size_t kBlockGrain = 32;

// Software prefetch distance for the values stream, in bytes (~85 indices of 48 bytes
// ahead, half a block of 160; the arrays are contiguous across blocks, so it runs into
// the task's next block). One prefetch per index covers every 64-byte line, the stride
// being 48. Without it the kernel takes longer than streaming its bytes
// (docs/performance.md, "Design measurements").
constexpr size_t kBlockPrefetchBytes = 4096;

// Per-component view of a blocked component's arrays.
struct BlockStream {
    const uint32_t* order;
    const uint32_t* offsets;
    const uint16_t* indices;
    const int8_t* values;
    const float* scales;
    const float* shScales;  // nullptr without SH scales
    uint32_t shFrom;
    size_t vertices;  // V
    size_t blocks;    // ceil(V / 16)
    uint32_t total;   // indices in the component
};

BlockStream blockStreamOf(const BlockedRgbVectors& b) {
    return {b.order.data(),
            b.offsets.data(),
            b.indices.data(),
            b.values.data(),
            b.scales.data(),
            b.shFrom == UINT32_MAX ? nullptr : b.shScales.data(),
            b.shFrom,
            size_t(b.vertices),
            b.blockCount(),
            uint32_t(b.indices.size())};
}

// Block b's indices and values, validated.
struct BlockSpan {
    const uint16_t* idx;
    const int8_t* q;      // 48 per index
    const float* scales;  // the block's 48
    const float* shScales;  // the block's 48 for indices >= split (== scales without SH scales)
    const uint32_t* order;  // the block's 16 lanes (the first `lanes` are vertices)
    size_t split;  // indices [0, split) use scales, [split, count) shScales
    size_t count;
    unsigned lanes;  // 16, fewer in a partial last block
};

// The two parts of a block's indices, in turn: [0, split) with `scales`, then
// [split, count) with `shScales` (often empty).
inline size_t partEnd(const BlockSpan& span, int part) { return part == 0 ? span.split : span.count; }
inline const float* partScales(const BlockSpan& span, int part) { return part == 0 ? span.scales : span.shScales; }

// False when b's offsets are out of order, its largest index (the last: indices increase
// within a block, a BlockedRgbVectors invariant) is >= lightCount, or one of its lanes'
// vertices is >= V. That keeps every light load and every output store in bounds with
// one comparison per block and one per lane. (A duplicated vertex in `order` would
// still be in bounds: its lanes overwrite each other and another vertex keeps its old
// value; checkBlockedVectors and the file reader check the permutation.)
inline bool blockSpan(const BlockStream& s, size_t b, uint32_t lightCount, BlockSpan& span) {
    const uint32_t begin = s.offsets[b], end = s.offsets[b + 1];
    if (begin > end || end > s.total || (end > begin && s.indices[end - 1] >= lightCount)) return false;
    const size_t first = b * kVertexBlock;
    span.lanes = unsigned(std::min<size_t>(kVertexBlock, s.vertices - first));
    span.order = s.order + first;
    for (unsigned lane = 0; lane < span.lanes; ++lane)
        if (span.order[lane] >= s.vertices) return false;
    span.idx = s.indices + begin;
    span.q = s.values + kBlockValuesPerIndex * size_t(begin);
    span.scales = s.scales + kBlockValuesPerIndex * b;
    span.count = end - begin;
    span.split = span.count;
    span.shScales = span.scales;
    if (s.shScales) {
        span.shScales = s.shScales + kBlockValuesPerIndex * b;
        while (span.split > 0 && span.idx[span.split - 1] >= s.shFrom) --span.split;
    }
    return true;
}

// Scatters a block's scaled results r[16 c + lane] to its vertices (padding lanes skipped).
template <bool Add>
inline void scatterBlock(const BlockSpan& span, const float r[kBlockValuesPerIndex], glm::vec3* out) {
    for (unsigned lane = 0; lane < span.lanes; ++lane) {
        const glm::vec3 x(r[lane], r[kVertexBlock + lane], r[2 * kVertexBlock + lane]);
        if constexpr (Add)
            out[span.order[lane]] += x;
        else
            out[span.order[lane]] = x;
    }
}

// Baseline: sum_n q[48 n + 16 c + lane] * light[idx[n] * Stride + c] in one float
// accumulator per lane and channel, in index order, then times the scale.
// SSE2 (any x86-64): a channel's 16 lanes are four xmm; the int8 values are
// sign-extended by unpacking each byte into the top of a 32-bit lane and shifting it
// down arithmetically (GCC leaves the plain loop below scalar, several times slower).
// Without SSE2 (other architectures) the plain loop, the same sums in the same order.
template <int Stride>
inline void dotBlockBaseline(const BlockSpan& span, const float* light, float r[kBlockValuesPerIndex]) {
    const int8_t* q = span.q;
#if PRT_RELIGHT_SSE2
    __m128 a[12];
    const auto widen = [](__m128i w) { return _mm_cvtepi32_ps(_mm_srai_epi32(w, 24)); };
    size_t n = 0;
    for (int part = 0; part < 2; ++part) {
        for (__m128& x : a) x = _mm_setzero_ps();
        for (; n < partEnd(span, part); ++n, q += kBlockValuesPerIndex) {
            prefetchAhead(q, kBlockPrefetchBytes);
            const float* l = light + size_t(span.idx[n]) * Stride;
            for (int c = 0; c < 3; ++c) {
                const __m128 lc = _mm_set1_ps(l[c]);
                const __m128i x = _mm_loadu_si128(reinterpret_cast<const __m128i*>(q + 16 * c));
                const __m128i lo = _mm_unpacklo_epi8(x, x), hi = _mm_unpackhi_epi8(x, x);
                a[4 * c] = _mm_add_ps(a[4 * c], _mm_mul_ps(widen(_mm_unpacklo_epi16(lo, lo)), lc));
                a[4 * c + 1] = _mm_add_ps(a[4 * c + 1], _mm_mul_ps(widen(_mm_unpackhi_epi16(lo, lo)), lc));
                a[4 * c + 2] = _mm_add_ps(a[4 * c + 2], _mm_mul_ps(widen(_mm_unpacklo_epi16(hi, hi)), lc));
                a[4 * c + 3] = _mm_add_ps(a[4 * c + 3], _mm_mul_ps(widen(_mm_unpackhi_epi16(hi, hi)), lc));
            }
        }
        const float* sc = partScales(span, part);
        for (int i = 0; i < 12; ++i) {
            const __m128 x = _mm_mul_ps(a[i], _mm_loadu_ps(sc + 4 * i));
            _mm_storeu_ps(r + 4 * i, part == 0 ? x : _mm_add_ps(_mm_loadu_ps(r + 4 * i), x));
        }
    }
#else
    size_t n = 0;
    for (int part = 0; part < 2; ++part) {
        float acc[kBlockValuesPerIndex] = {};
        for (; n < partEnd(span, part); ++n, q += kBlockValuesPerIndex) {
            const float* l = light + size_t(span.idx[n]) * Stride;
            for (size_t c = 0; c < 3; ++c) {
                const float lc = l[c];
                for (size_t lane = 0; lane < kVertexBlock; ++lane)
                    acc[kVertexBlock * c + lane] += float(q[kVertexBlock * c + lane]) * lc;
            }
        }
        const float* sc = partScales(span, part);
        for (size_t i = 0; i < kBlockValuesPerIndex; ++i) r[i] = (part == 0 ? 0.0f : r[i]) + acc[i] * sc[i];
    }
#endif
}

template <int Stride, bool Add>
bool relightBlocksBaseline(const BlockStream& s, size_t first, size_t last, const float* light,
                           uint32_t lightCount, glm::vec3* out, size_t& badBlock) {
    for (size_t b = first; b < last; ++b) {
        BlockSpan span;
        if (!blockSpan(s, b, lightCount, span)) {
            badBlock = b;
            return false;
        }
        alignas(16) float r[kBlockValuesPerIndex];
        dotBlockBaseline<Stride>(span, light, r);
        scatterBlock<Add>(span, r, out);
    }
    return true;
}

#if PRT_RELIGHT_AVX2
// AVX2 + FMA: a channel's 16 lanes are two ymm; per index six 8-byte loads sign-extended
// (vpmovsxbd) and converted, three light broadcasts, six FMAs into six accumulators.
template <int Stride>
__attribute__((target("avx2,fma"))) inline void dotBlockAvx2(const BlockSpan& span, const float* light,
                                                             float r[kBlockValuesPerIndex]) {
#define PRT_Q8(p) _mm256_cvtepi32_ps(_mm256_cvtepi8_epi32(_mm_loadl_epi64(reinterpret_cast<const __m128i*>(p))))
    __m256 a[6];
    const int8_t* q = span.q;
    size_t n = 0;
    for (int part = 0; part < 2; ++part) {
        for (__m256& x : a) x = _mm256_setzero_ps();
        for (; n < partEnd(span, part); ++n, q += kBlockValuesPerIndex) {
            prefetchAhead(q, kBlockPrefetchBytes);
            const float* l = light + size_t(span.idx[n]) * Stride;
            for (int c = 0; c < 3; ++c) {
                const __m256 lc = _mm256_broadcast_ss(l + c);
                a[2 * c] = _mm256_fmadd_ps(PRT_Q8(q + 16 * c), lc, a[2 * c]);
                a[2 * c + 1] = _mm256_fmadd_ps(PRT_Q8(q + 16 * c + 8), lc, a[2 * c + 1]);
            }
        }
        const float* sc = partScales(span, part);
        for (int i = 0; i < 6; ++i) {
            const __m256 x = _mm256_mul_ps(a[i], _mm256_loadu_ps(sc + 8 * i));
            _mm256_storeu_ps(r + 8 * i, part == 0 ? x : _mm256_add_ps(_mm256_loadu_ps(r + 8 * i), x));
        }
    }
#undef PRT_Q8
}

template <int Stride, bool Add>
__attribute__((target("avx2,fma"))) bool relightBlocksAvx2(const BlockStream& s, size_t first, size_t last,
                                                            const float* light, uint32_t lightCount,
                                                            glm::vec3* out, size_t& badBlock) {
    for (size_t b = first; b < last; ++b) {
        BlockSpan span;
        if (!blockSpan(s, b, lightCount, span)) {
            badBlock = b;
            return false;
        }
        alignas(32) float r[kBlockValuesPerIndex];
        dotBlockAvx2<Stride>(span, light, r);
        scatterBlock<Add>(span, r, out);
    }
    return true;
}
#endif

#if PRT_RELIGHT_AVX512
// AVX-512: a channel's 16 lanes are one zmm; per index three 16-byte loads sign-extended
// straight to 16 int32 (vpmovsxbd) and converted, three broadcasts, three FMAs.
template <int Stride>
__attribute__((target("avx512f,avx512bw,avx512vl,avx2,fma"))) inline void dotBlockAvx512(
    const BlockSpan& span, const float* light, float r[kBlockValuesPerIndex]) {
// (The maskz forms with an all-ones mask compile to the plain instructions; GCC 12's
// unmasked intrinsics warn about their deliberately undefined pass-through operand.)
#define PRT_Q16(p)                                                                      \
    _mm512_maskz_cvtepi32_ps(__mmask16(0xFFFF),                                        \
                             _mm512_maskz_cvtepi8_epi32(__mmask16(0xFFFF),             \
                                                        _mm_loadu_si128(reinterpret_cast<const __m128i*>(p))))
    const int8_t* q = span.q;
    __m512 rr = _mm512_setzero_ps(), rg = rr, rb = rr;
    size_t n = 0;
    for (int part = 0; part < 2; ++part) {
        __m512 ar = _mm512_setzero_ps(), ag = ar, ab = ar;
        for (; n < partEnd(span, part); ++n, q += kBlockValuesPerIndex) {
            prefetchAhead(q, kBlockPrefetchBytes);
            const float* l = light + size_t(span.idx[n]) * Stride;
            ar = _mm512_fmadd_ps(PRT_Q16(q), _mm512_set1_ps(l[0]), ar);
            ag = _mm512_fmadd_ps(PRT_Q16(q + 16), _mm512_set1_ps(l[1]), ag);
            ab = _mm512_fmadd_ps(PRT_Q16(q + 32), _mm512_set1_ps(l[2]), ab);
        }
        const float* sc = partScales(span, part);
        rr = _mm512_fmadd_ps(ar, _mm512_loadu_ps(sc), rr);
        rg = _mm512_fmadd_ps(ag, _mm512_loadu_ps(sc + 16), rg);
        rb = _mm512_fmadd_ps(ab, _mm512_loadu_ps(sc + 32), rb);
    }
#undef PRT_Q16
    _mm512_storeu_ps(r, rr);
    _mm512_storeu_ps(r + 16, rg);
    _mm512_storeu_ps(r + 32, rb);
}

template <int Stride, bool Add>
__attribute__((target("avx512f,avx512bw,avx512vl,avx2,fma"))) bool relightBlocksAvx512(
    const BlockStream& s, size_t first, size_t last, const float* light, uint32_t lightCount, glm::vec3* out,
    size_t& badBlock) {
    for (size_t b = first; b < last; ++b) {
        BlockSpan span;
        if (!blockSpan(s, b, lightCount, span)) {
            badBlock = b;
            return false;
        }
        alignas(64) float r[kBlockValuesPerIndex];
        dotBlockAvx512<Stride>(span, light, r);
        scatterBlock<Add>(span, r, out);
    }
    return true;
}
#endif

#if PRT_RELIGHT_AVX512
// AVX-512 per-vertex components: four coefficients per zmm, one coefficient per 128-bit
// lane (R, G, B, 0). The AVX2 loop spends three FP-unit operations on every coefficient
// (widen, convert, multiply-add); here the four coefficients' twelve int16 values are one
// masked load widened to int32, one permutation into the four lanes (the fourth value of
// each zeroed by the mask) and one conversion, and the four light coefficients are one
// load and three 128-bit inserts, then one multiply-add: seven operations for four.
// Masked loads do not fault on masked-off elements, so nothing is read past the
// component's last coefficient and VertexSpan::safe is not needed. Two accumulators (8
// partial sums per channel), summed pairwise at the end.
#define PRT_AVX512 __attribute__((target("avx512f,avx512bw,avx512vl,avx2,fma")))
// Four coefficients' values in their lanes: (q0, q1, q2, 0, q3, q4, q5, 0, ...).
PRT_AVX512 inline __m512 values4Avx512(const int16_t* p) {
    const __m512i perm = _mm512_setr_epi32(0, 1, 2, 0, 3, 4, 5, 0, 6, 7, 8, 0, 9, 10, 11, 0);
    const __m256i w = _mm256_maskz_loadu_epi16(__mmask16(0x0FFF), p);
    return _mm512_maskz_cvtepi32_ps(
        __mmask16(0xFFFF), _mm512_maskz_permutexvar_epi32(__mmask16(0x7777), perm,
                                                          _mm512_maskz_cvtepi16_epi32(__mmask16(0xFFFF), w)));
}

// The four coefficients' light, one per 128-bit lane. Lane 3 of each (0 with stride 4,
// the next coefficient's R with stride 3) meets a zeroed value.
template <int Stride>
PRT_AVX512 inline __m512 light4Avx512(const float* light, const uint16_t* k) {
    const __m512 l = _mm512_castps128_ps512(_mm_loadu_ps(light + size_t(k[0]) * Stride));
    const __m512 l1 = _mm512_insertf32x4(l, _mm_loadu_ps(light + size_t(k[1]) * Stride), 1);
    const __m512 l2 = _mm512_insertf32x4(l1, _mm_loadu_ps(light + size_t(k[2]) * Stride), 2);
    return _mm512_insertf32x4(l2, _mm_loadu_ps(light + size_t(k[3]) * Stride), 3);
}

template <int Stride>
PRT_AVX512 __attribute__((always_inline)) inline void dotAvx512(const VertexSpan& span, const float* light, float out[3]) {
    const uint16_t* idx = span.idx;
    const int16_t* q = span.q;
    __m512 a0 = _mm512_setzero_ps(), a1 = a0;
    size_t n = 0;
    for (; n + 8 <= span.count; n += 8) {
        // _mm_prefetch directly: GCC 12 drops prefetchAhead's prefetches once this
        // function is inlined into its caller of another target, which halves the speed.
        _mm_prefetch(reinterpret_cast<const char*>(reinterpret_cast<uintptr_t>(q + 3 * n) + 3 * sizeof(int16_t) * kPrefetchAhead), _MM_HINT_T0);
        _mm_prefetch(reinterpret_cast<const char*>(reinterpret_cast<uintptr_t>(idx + n) + sizeof(uint16_t) * kPrefetchAhead), _MM_HINT_T0);
        a0 = _mm512_fmadd_ps(values4Avx512(q + 3 * n), light4Avx512<Stride>(light, idx + n), a0);
        a1 = _mm512_fmadd_ps(values4Avx512(q + 3 * n + 12), light4Avx512<Stride>(light, idx + n + 4), a1);
    }
    if (n + 4 <= span.count) {
        a0 = _mm512_fmadd_ps(values4Avx512(q + 3 * n), light4Avx512<Stride>(light, idx + n), a0);
        n += 4;
    }
    __m128 t = _mm_setzero_ps();
    for (; n < span.count; ++n)
        t = _mm_fmadd_ps(_mm_cvtepi32_ps(_mm_cvtepi16_epi32(_mm_maskz_loadu_epi16(__mmask8(0x7), q + 3 * n))),
                         _mm_loadu_ps(light + size_t(idx[n]) * Stride), t);
    // (maskz extracts with an all-ones mask, as in dotBlockAvx512: the plain ones warn.)
    const __m512 a = _mm512_add_ps(a0, a1);
    const __m256 h = _mm256_add_ps(_mm256_castpd_ps(_mm512_maskz_extractf64x4_pd(__mmask8(0xF), _mm512_castps_pd(a), 0)),
                                    _mm256_castpd_ps(_mm512_maskz_extractf64x4_pd(__mmask8(0xF), _mm512_castps_pd(a), 1)));
    const __m128 s = _mm_add_ps(_mm_add_ps(_mm256_castps256_ps128(h), _mm256_extractf128_ps(h, 1)), t);
    alignas(16) float sum[4];
    _mm_store_ps(sum, s);
    for (int c = 0; c < 3; ++c) out[c] = sum[c];
}

// relightRangeAvx2's vertex loop compiled for AVX-512 (copied for the same reason).
template <int Stride, bool Add>
PRT_AVX512 bool relightRangeAvx512(
    const Stream& s, size_t first, size_t last, const float* light, uint32_t lightCount, glm::vec3* out,
    size_t& badVertex) {
    for (size_t v = first; v < last; ++v) {
        VertexSpan span;
        if (!vertexSpan(s, v, lightCount, span)) {
            badVertex = v;
            return false;
        }
        float sum[3];
        const VertexSpan sh = s.shScales ? splitShSpan(span, s.shFrom) : VertexSpan{};
        dotAvx512<Stride>(span, light, sum);
        store<Add>(s, v, sum, out);
        if (s.shScales) {
            dotAvx512<Stride>(sh, light, sum);
            addSh(s, v, sum, out);
        }
    }
    return true;
}
#undef PRT_AVX512
#endif

using RangeFn = bool (*)(const Stream&, size_t, size_t, const float*, uint32_t, glm::vec3*,
                         size_t&);
using BlockRangeFn = bool (*)(const BlockStream&, size_t, size_t, const float*, uint32_t, glm::vec3*,
                              size_t&);

struct Kernels {
    RangeFn assign, add;                  // per-vertex components
    BlockRangeFn blockAssign, blockAdd;  // blocked components
};

// The kernels an isa resolves to.
enum class Chosen { Baseline, Avx2, Avx512 };

Chosen chooseIsa(RelightIsa isa) {
    switch (isa) {
        case RelightIsa::Baseline: return Chosen::Baseline;
        case RelightIsa::Avx2Fma:
            if (!relightIsaSupported(isa))
                throw Error("relight", "the AVX2 + FMA kernel is not supported on this CPU or build");
            return Chosen::Avx2;
        case RelightIsa::Avx512:
            if (!relightIsaSupported(isa))
                throw Error("relight", "the AVX-512 kernel is not supported on this CPU or build");
            return Chosen::Avx512;
        case RelightIsa::Best:
            return relightIsaSupported(RelightIsa::Avx512)    ? Chosen::Avx512
                   : relightIsaSupported(RelightIsa::Avx2Fma) ? Chosen::Avx2
                                                              : Chosen::Baseline;
    }
    return Chosen::Baseline;
}

template <int Stride>
Kernels kernelsFor(Chosen isa) {
    Kernels k{relightRangeBaseline<Stride, false>, relightRangeBaseline<Stride, true>,
              relightBlocksBaseline<Stride, false>, relightBlocksBaseline<Stride, true>};
#if PRT_RELIGHT_AVX2
    if (isa != Chosen::Baseline) {
        k.assign = relightRangeAvx2<Stride, false>;
        k.add = relightRangeAvx2<Stride, true>;
        k.blockAssign = relightBlocksAvx2<Stride, false>;
        k.blockAdd = relightBlocksAvx2<Stride, true>;
    }
#endif
#if PRT_RELIGHT_AVX512
    if (isa == Chosen::Avx512) {
        k.assign = relightRangeAvx512<Stride, false>;
        k.add = relightRangeAvx512<Stride, true>;
        k.blockAssign = relightBlocksAvx512<Stride, false>;
        k.blockAdd = relightBlocksAvx512<Stride, true>;
    }
#endif
    return k;
}

template <int Stride>
void relightFast(const TransportFile& file, const LightVector& light,
                 const ScatteringComponents& components, VertexRadiance& out, RelightIsa isa) {
    checkLight(file, light);
    const Plan plan = makePlan(file, components);
    for (const Job& j : plan.diffuse) checkArrays(*j.component);
    for (const Job& j : plan.terms) checkArrays(*j.component);
    const Kernels kernels = kernelsFor<Stride>(chooseIsa(isa));

    const size_t vertices = plan.vertexCount;
    out.diffuse.resize(vertices);
    out.terms.resize(plan.terms.size());
    for (std::vector<glm::vec3>& t : out.terms) t.resize(vertices);

    const std::vector<float> gather = gatherLayout<Stride>(light, file.shTerms);
    const float* lightData = gather.data();
    const uint32_t count = uint32_t(light.coefficientCount() + file.shTerms);

    // Every selected component, diffuse ones first, then terms; each one either
    // per-vertex (a Stream, relit over ranges of vertices) or blocked (a BlockStream,
    // relit over ranges of blocks, scattering to its vertices).
    std::vector<const TransportComponent*> jobs;
    for (const Job& j : plan.diffuse) jobs.push_back(j.component);
    for (const Job& j : plan.terms) jobs.push_back(j.component);
    const size_t diffuseCount = plan.diffuse.size();
    std::vector<Stream> streams(jobs.size());
    std::vector<BlockStream> blockStreams(jobs.size());
    std::vector<size_t> perVertex, blocked;  // indices into jobs, in plan order
    for (size_t i = 0; i < jobs.size(); ++i) {
        if (jobs[i]->blocked()) {
            blockStreams[i] = blockStreamOf(jobs[i]->blocks);
            blocked.push_back(i);
        } else {
            streams[i] = streamOf(jobs[i]->vectors);
            perVertex.push_back(i);
        }
    }
    // The diffuse sum runs over the per-vertex diffuse components, then the blocked ones
    // (each in plan order): the first stores, the others add. A fixed order, so the
    // result does not depend on the threads. No diffuse component: zeros.
    size_t firstDiffuse = jobs.size();
    if (!perVertex.empty() && perVertex.front() < diffuseCount)
        firstDiffuse = perVertex.front();
    else if (!blocked.empty() && blocked.front() < diffuseCount)
        firstDiffuse = blocked.front();
    const auto destination = [&](size_t i) {
        return i < diffuseCount ? out.diffuse.data() : out.terms[i - diffuseCount].data();
    };
    const auto adds = [&](size_t i) { return i < diffuseCount && i != firstDiffuse; };

    // Smallest bad vertex (per-vertex) or block (blocked) per component (kNone: none),
    // reported after the loops.
    constexpr size_t kNone = std::numeric_limits<size_t>::max();
    std::vector<std::atomic<size_t>> bad(jobs.size());
    for (std::atomic<size_t>& b : bad) b.store(kNone, std::memory_order_relaxed);
    const auto report = [&](size_t which, size_t v) {
        size_t prev = bad[which].load(std::memory_order_relaxed);
        while (v < prev && !bad[which].compare_exchange_weak(prev, v)) {
        }
    };

    // Per-vertex components, all in one pass over ranges of vertices.
    glm::vec3* diffuseOut = out.diffuse.data();
    if (!perVertex.empty() || diffuseCount == 0)
        tbb::parallel_for(tbb::blocked_range<size_t>(0, vertices, kVertexGrain),
                          [&](const tbb::blocked_range<size_t>& r) {
                              size_t badVertex = 0;
                              if (diffuseCount == 0)
                                  std::fill(diffuseOut + r.begin(), diffuseOut + r.end(), glm::vec3(0.0f));
                              for (size_t i : perVertex) {
                                  const RangeFn fn = adds(i) ? kernels.add : kernels.assign;
                                  if (!fn(streams[i], r.begin(), r.end(), lightData, count, destination(i),
                                          badVertex))
                                      report(i, badVertex);
                              }
                          });
    // Blocked components, in passes over ranges of blocks. A block's vertices are anywhere
    // in the output, so components can share a pass only when they write different
    // outputs (terms) or the same vertices block by block (diffuse components with the
    // same order, e.g. all of one precompute's): the first pass takes every blocked term
    // component and the blocked diffuse ones up to the first whose order differs from
    // the first one's; each diffuse one from there on gets a pass of its own, in plan
    // order. (Comparing orders costs O(V), only with two or more blocked diffuse
    // components.) One pass for all keeps the threads busy to the end once, not once
    // per component.
    std::vector<std::vector<size_t>> passes(1);
    for (size_t i : blocked) {
        const bool diffuse = i < diffuseCount;
        if (diffuse && passes.size() > 1)
            passes.push_back({i});
        else if (diffuse && !passes[0].empty() && jobs[i]->blocks.order != jobs[passes[0][0]]->blocks.order)
            passes.push_back({i});
        else
            passes[0].push_back(i);
    }
    for (const std::vector<size_t>& pass : passes) {
        if (pass.empty()) continue;
        tbb::parallel_for(tbb::blocked_range<size_t>(0, blockStreams[pass[0]].blocks, kBlockGrain),
                          [&](const tbb::blocked_range<size_t>& r) {
                              size_t badBlock = 0;
                              for (size_t i : pass) {
                                  const BlockRangeFn fn = adds(i) ? kernels.blockAdd : kernels.blockAssign;
                                  if (!fn(blockStreams[i], r.begin(), r.end(), lightData, count, destination(i),
                                          badBlock))
                                      report(i, badBlock);
                              }
                          });
    }

    for (size_t i = 0; i < bad.size(); ++i) {
        const size_t v = bad[i].load();
        if (v == kNone) continue;
        const TransportComponent& c = *jobs[i];
        const std::string limit = "6 x " + std::to_string(light.size) + "^2" +
                                  (file.shTerms ? " + " + std::to_string(file.shTerms) + " SH terms" : "") +
                                  " = " + std::to_string(count);
        if (c.blocked())
            throw Error("transport file", componentName(c.kind, c.term) + ": block " + std::to_string(v) +
                                              " has invalid offsets, a coefficient index >= " + limit +
                                              " or a vertex >= " + std::to_string(vertices));
        throw Error("transport file", componentName(c.kind, c.term) + ": vertex " + std::to_string(v) +
                                          " has invalid offsets or a coefficient index >= " + limit);
    }
}

}  // namespace

bool relightIsaSupported(RelightIsa isa) {
    switch (isa) {
        case RelightIsa::Best:
        case RelightIsa::Baseline: return true;
        case RelightIsa::Avx2Fma:
#if PRT_RELIGHT_AVX2
            return cpuHasAvx2Fma();
#else
            return false;
#endif
        case RelightIsa::Avx512: return PRT_RELIGHT_AVX512 && cpuHasAvx512();
    }
    return false;
}

void relightVertices(const TransportFile& file, const LightVector& light,
                     const ScatteringComponents& components, VertexRadiance& out) {
    relightVertices(file, light, components, out, RelightOptions{});
}

void relightVertices(const TransportFile& file, const LightVector& light,
                     const ScatteringComponents& components, VertexRadiance& out,
                     const RelightOptions& options) {
    if (options.layout == RelightLayout::Rgb3)
        relightFast<3>(file, light, components, out, options.isa);
    else
        relightFast<4>(file, light, components, out, options.isa);
}

namespace {

// The reference validates a blocked component whole (checkBlockedVectors: sizes, offsets,
// every index, the permutation, padding), then reads it vertex by vertex.
void checkBlockedReference(const TransportComponent& c, size_t lightCount) {
    if (!c.blocked()) return;
    const std::string why = checkBlockedVectors(c.blocks, uint32_t(lightCount));
    if (!why.empty()) throw Error("transport file", componentName(c.kind, c.term) + ": " + why);
}

}  // namespace

void relightVerticesReference(const TransportFile& file, const LightVector& light,
                              const ScatteringComponents& components, VertexRadiance& out) {
    checkLight(file, light);
    const Plan plan = makePlan(file, components);
    const size_t vertices = plan.vertexCount;
    const size_t haar = light.coefficientCount();
    const size_t count = haar + file.shTerms;
    const std::vector<float> sh = lightShPart(light, file.shTerms);

    std::vector<glm::dvec3> diffuse(vertices, glm::dvec3(0.0));
    out.terms.assign(plan.terms.size(), std::vector<glm::vec3>(vertices));
    std::vector<uint32_t> idx;
    std::vector<float> rgb;
    for (const Job& j : plan.diffuse) checkBlockedReference(*j.component, count);
    for (const Job& j : plan.terms) checkBlockedReference(*j.component, count);
    const auto dotVertex = [&](const TransportComponent& c, size_t v) {
        try {
            c.dequantizeVertex(v, idx, rgb);
        } catch (const std::out_of_range& e) {  // a blocked component without slotOf
            throw Error("transport file", componentName(c.kind, c.term) + ": " + e.what());
        }
        glm::dvec3 sum(0.0);
        for (size_t n = 0; n < idx.size(); ++n) {
            if (idx[n] >= count)
                throw Error("transport file", componentName(c.kind, c.term) + ": vertex " +
                                                  std::to_string(v) + " has coefficient index " +
                                                  std::to_string(idx[n]) + " >= " +
                                                  std::to_string(count));
            const float* l = idx[n] < haar ? &light.rgb[3 * size_t(idx[n])] : &sh[3 * (idx[n] - haar)];
            for (int ch = 0; ch < 3; ++ch) sum[ch] += double(rgb[3 * n + ch]) * double(l[ch]);
        }
        return sum;
    };
    for (const Job& j : plan.diffuse)
        for (size_t v = 0; v < vertices; ++v) diffuse[v] += dotVertex(*j.component, v);
    for (const Job& j : plan.terms)
        for (size_t v = 0; v < vertices; ++v)
            out.terms[size_t(j.slot)][v] = glm::vec3(dotVertex(*j.component, v));
    out.diffuse.resize(vertices);
    for (size_t v = 0; v < vertices; ++v) out.diffuse[v] = glm::vec3(diffuse[v]);
}

size_t relightStreamBytes(const TransportFile& file, const ScatteringComponents& components) {
    size_t bytes = 0;
    for (const TransportComponent& c : file.components) {
        const bool selected = c.kind == ComponentKind::MultipleScattering
                                  ? components.multipleScattering
                                  : components.singleScattering;
        if (selected) bytes += c.blocked() ? c.blocks.byteSize() : c.vectors.byteSize();
    }
    return bytes;
}

}  // namespace prt
