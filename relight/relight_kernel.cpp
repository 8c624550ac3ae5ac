#include "relight/relight_kernel.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <cstdint>
#include <cstring>
#include <limits>
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

namespace prt {

namespace {

// Vertices per TBB task. A 128-coefficient vertex streams ~1 KB, so a block is
// ~0.5 MB of transport data: large enough to amortise task overhead, small enough
// to balance two to a few dozen cores on 10^4..10^6 vertices.
constexpr size_t kVertexGrain = 512;

// Software prefetch distance, in coefficients, for the index and value streams (the
// arrays are contiguous across vertices, so the prefetches run ahead into the next
// vertices). 256 coefficients = 1.5 KB of values, 512 B of indices ahead. The hardware
// prefetchers alone left a single core at ~2/3 of its streaming rate (measured with
// tools/bench_relight, one thread: 14.3 -> 9.9 ms per 104 MB relight, i.e. the rate
// of a plain single-core sum over a float array). 128 and 512 measured slightly worse.
// Prefetches never fault, so running past the end of an array is harmless; the
// address is formed as an integer so no out-of-range pointer is ever created.
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
                                               : file.components.front().vectors.vertexCount();
    for (const TransportComponent& c : file.components) {
        if (c.vectors.vertexCount() != plan.vertexCount)
            throw Error("transport file", componentName(c.kind, c.term) + " has " +
                                              std::to_string(c.vectors.vertexCount()) +
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

// Whole-array consistency of one component's CSR arrays (O(1)); per-vertex offsets and
// the largest index of each vertex are checked inside the kernel.
void checkArrays(const TransportComponent& c) {
    const SparseRgbVectors& s = c.vectors;
    const size_t v = s.vertexCount();
    if (s.offsets.empty() || s.offsets.front() != 0 || s.offsets.back() != s.indices.size() ||
        s.values.size() != 3 * s.indices.size() || s.scales.size() != 3 * v)
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

// The light vector converted for gathering: `Stride` floats per coefficient, RGB
// first. Stride 4 pads each coefficient to 16 bytes (one aligned SSE load, never
// straddling a cache line); stride 3 is the plain interleaved layout (25% smaller, an
// unaligned 16-byte load that reads the next coefficient's R, which is ignored). The
// buffer has one extra coefficient of zeros so the stride-3 over-read stays inside.
template <int Stride>
std::vector<float> gatherLayout(const LightVector& light) {
    const size_t count = light.coefficientCount();
    std::vector<float> out((count + 1) * Stride, 0.0f);
    for (size_t k = 0; k < count; ++k)
        for (int c = 0; c < 3; ++c) out[k * Stride + c] = light.rgb[3 * k + c];
    return out;
}

// Per-component view of the arrays the kernel streams.
struct Stream {
    const uint32_t* offsets;
    const uint16_t* indices;
    const int16_t* values;
    const float* scales;
    uint32_t total;  // coefficients in the component
};

Stream streamOf(const SparseRgbVectors& s) {
    return {s.offsets.data(), s.indices.data(), s.values.data(), s.scales.data(),
            uint32_t(s.indices.size())};
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
        dotBaseline<Stride>(span, light, sum);
        store<Add>(s, v, sum, out);
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
        dotAvx2<Stride>(span, light, sum);
        store<Add>(s, v, sum, out);
    }
    return true;
}

#endif

using RangeFn = bool (*)(const Stream&, size_t, size_t, const float*, uint32_t, glm::vec3*,
                         size_t&);

struct Kernels {
    RangeFn assign, add;
};

template <int Stride>
Kernels kernelsFor(bool avx2) {
#if PRT_RELIGHT_AVX2
    if (avx2) return {relightRangeAvx2<Stride, false>, relightRangeAvx2<Stride, true>};
#endif
    return {relightRangeBaseline<Stride, false>, relightRangeBaseline<Stride, true>};
}

bool useAvx2(RelightIsa isa) {
    switch (isa) {
        case RelightIsa::Baseline: return false;
        case RelightIsa::Avx2Fma:
            if (!relightIsaSupported(isa))
                throw Error("relight", "the AVX2 + FMA kernel is not supported on this CPU or build");
            return true;
        case RelightIsa::Best: return relightIsaSupported(RelightIsa::Avx2Fma);
    }
    return false;
}

template <int Stride>
void relightFast(const TransportFile& file, const LightVector& light,
                 const ScatteringComponents& components, VertexRadiance& out, RelightIsa isa) {
    checkLight(file, light);
    const Plan plan = makePlan(file, components);
    for (const Job& j : plan.diffuse) checkArrays(*j.component);
    for (const Job& j : plan.terms) checkArrays(*j.component);
    const Kernels kernels = kernelsFor<Stride>(useAvx2(isa));

    const size_t vertices = plan.vertexCount;
    out.diffuse.resize(vertices);
    out.terms.resize(plan.terms.size());
    for (std::vector<glm::vec3>& t : out.terms) t.resize(vertices);

    const std::vector<float> gather = gatherLayout<Stride>(light);
    const float* lightData = gather.data();
    const uint32_t count = uint32_t(light.coefficientCount());

    std::vector<Stream> streams;  // diffuse components first, then terms
    for (const Job& j : plan.diffuse) streams.push_back(streamOf(j.component->vectors));
    for (const Job& j : plan.terms) streams.push_back(streamOf(j.component->vectors));
    const size_t diffuseCount = plan.diffuse.size();

    // Smallest bad vertex per component (kNone: none), reported after the loop.
    constexpr size_t kNone = std::numeric_limits<size_t>::max();
    std::vector<std::atomic<size_t>> bad(streams.size());
    for (std::atomic<size_t>& b : bad) b.store(kNone, std::memory_order_relaxed);
    const auto report = [&](size_t which, size_t v) {
        size_t prev = bad[which].load(std::memory_order_relaxed);
        while (v < prev && !bad[which].compare_exchange_weak(prev, v)) {
        }
    };

    glm::vec3* diffuseOut = out.diffuse.data();
    tbb::parallel_for(tbb::blocked_range<size_t>(0, vertices, kVertexGrain),
                      [&](const tbb::blocked_range<size_t>& r) {
                          size_t badVertex = 0;
                          if (diffuseCount == 0)
                              std::fill(diffuseOut + r.begin(), diffuseOut + r.end(), glm::vec3(0.0f));
                          for (size_t i = 0; i < streams.size(); ++i) {
                              const bool term = i >= diffuseCount;
                              const RangeFn fn = (term || i == 0) ? kernels.assign : kernels.add;
                              glm::vec3* dst = term ? out.terms[i - diffuseCount].data() : diffuseOut;
                              if (!fn(streams[i], r.begin(), r.end(), lightData, count, dst, badVertex))
                                  report(i, badVertex);
                          }
                      });

    for (size_t i = 0; i < bad.size(); ++i) {
        const size_t v = bad[i].load();
        if (v == kNone) continue;
        const TransportComponent& c =
            *(i < diffuseCount ? plan.diffuse[i] : plan.terms[i - diffuseCount]).component;
        throw Error("transport file",
                    componentName(c.kind, c.term) + ": vertex " + std::to_string(v) +
                        " has invalid offsets or a coefficient index >= 6 x " +
                        std::to_string(light.size) + "^2 = " + std::to_string(count));
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

void relightVerticesReference(const TransportFile& file, const LightVector& light,
                              const ScatteringComponents& components, VertexRadiance& out) {
    checkLight(file, light);
    const Plan plan = makePlan(file, components);
    const size_t vertices = plan.vertexCount;
    const size_t count = light.coefficientCount();

    std::vector<glm::dvec3> diffuse(vertices, glm::dvec3(0.0));
    out.terms.assign(plan.terms.size(), std::vector<glm::vec3>(vertices));
    std::vector<uint32_t> idx;
    std::vector<float> rgb;
    const auto dotVertex = [&](const TransportComponent& c, size_t v) {
        c.vectors.dequantizeVertex(v, idx, rgb);
        glm::dvec3 sum(0.0);
        for (size_t n = 0; n < idx.size(); ++n) {
            if (idx[n] >= count)
                throw Error("transport file", componentName(c.kind, c.term) + ": vertex " +
                                                  std::to_string(v) + " has coefficient index " +
                                                  std::to_string(idx[n]) + " >= " +
                                                  std::to_string(count));
            for (int ch = 0; ch < 3; ++ch)
                sum[ch] += double(rgb[3 * n + ch]) * double(light.rgb[3 * size_t(idx[n]) + ch]);
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
        if (selected) bytes += c.vectors.byteSize();
    }
    return bytes;
}

}  // namespace prt
