// Relight kernel against the machine's memory bandwidth (SPEC section 8):
//   ratio = time per relight / (bytes the relight streams / measured read bandwidth),
// goal <= 1.5. Everything is measured in one run of this program, so the ratio holds
// on a noisy machine; it is printed after the Google Benchmark table.
//
// Workloads (synthetic, random distinct indices, sorted, over 6 x 32 x 32 = 6144 Haar
// coefficients; random values; relit against a full, unapproximated light vector):
//   diffuse  one multiple-scattering component, 100,000 vertices x 128 coefficients
//            (what an ms file or an isotropic ms,ss file sums into one diffuse vector);
//   K = 4    the same diffuse component + 4 single-scattering term components (what
//            prt-precompute --components ms,ss --g G --phase-terms 4 writes): the
//            kernel with view terms, out.terms[0..3] besides out.diffuse.
// Baselines: a multithreaded (TBB, all cores, like the relight) and a single-threaded
// sum of a float array, once for a 1 GiB array (larger than any cache: the bandwidth
// used for the ratio) and once for an array as large as the relight's stream; memcpy.
// BM_RelightVsStream/terms:0 and /terms:4 interleave a 1 GiB sum and relights in every
// iteration, so their ratios are the least sensitive to other load on the machine (see
// there). BM_LoadTransportFile times loadTransportFile of the diffuse workload saved
// with saveTransportFile (every checksum verified), from the page cache and after
// dropping the file from it.
//
// Blocked workloads (common/blocked_vectors.h): the same per-vertex vectors converted
// with jointTruncate to blocks of 16 vertices sharing 160 indices
// (--block-coefficients), for the diffuse and the K = 4 workloads. BM_BlockedRelight
// times each kernel (baseline, AVX2, AVX-512); BM_BlockedRelightVsStream interleaves
// 1 GiB sums, the blocked relight and the per-vertex relight of the same vectors, and
// reports the blocked kernel's time against the time to stream the per-vertex file's
// 8-byte coefficients (goal <= 0.5, i.e. >= 2x faster; docs/performance.md) and its
// own bytes.
//
// Usage: bench_relight [--vertices=V] [--coefficients=M] [--n=N] [--block-coefficients=B]
//                      [--block-order=surface|random|identity] [--tmp-dir=DIR] [--summary-json=FILE]
//                      [google benchmark flags]
// (defaults 100000, 128, 32, 160, surface, the system's temporary directory;
// --summary-json writes the ratios, times per frame and load times as JSON for
// tools/bench.sh).

#include <benchmark/benchmark.h>
#include <fcntl.h>
#include <nlohmann/json.hpp>
#include <sys/mman.h>
#include <sys/stat.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_reduce.h>
#include <tbb/task_arena.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <numeric>
#include <random>
#include <span>
#include <string>
#include <vector>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include "common/atomic_file.h"
#include "common/envmap.h"
#include "common/error.h"
#include "common/image.h"
#include "relight/prt/light_vector.h"
#include "relight/prt/relight_kernel.h"
#include "common/transport_file.h"
#include "common/util.h"

namespace {

using prt::median;

size_t gVertices = 100000;
size_t gCoefficients = 128;
size_t gBlockCoefficients = 160;  // indices per block of 16 in the blocked workloads
std::string gBlockOrder = "surface";  // --block-order: surface, random or identity (see blockedWorkload)
int gCubemapSize = 32;
std::string gTmpDir;  // --tmp-dir; empty: the system's temporary directory

struct Workload {
    prt::TransportFile file;
    prt::LightVector light;
    size_t streamBytes = 0;
    int terms = 0;  // single-scattering term components besides the diffuse one
};

// gVertices x gCoefficients random coefficients (distinct indices) of one component.
prt::TransportComponent randomComponent(prt::ComponentKind kind, uint32_t term, uint32_t seed) {
    prt::TransportComponent c;
    c.kind = kind;
    c.term = term;
    const uint32_t count = 6 * gCubemapSize * gCubemapSize;
    const size_t m = std::min<size_t>(gCoefficients, count);
    c.vectors.reserve(gVertices, gVertices * m);
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> value(-1.0f, 1.0f);
    std::vector<uint32_t> all(count);
    std::iota(all.begin(), all.end(), 0u);
    std::vector<float> rgb(3 * m);
    for (size_t v = 0; v < gVertices; ++v) {
        // Partial Fisher-Yates: m distinct random indices (appendVertex sorts them).
        for (size_t k = 0; k < m; ++k)
            std::swap(all[k], all[k + std::uniform_int_distribution<size_t>(0, count - 1 - k)(rng)]);
        for (float& x : rgb) x = value(rng);
        c.vectors.appendVertex(std::span<const uint32_t>(all.data(), m), rgb);
    }
    return c;
}

Workload makeWorkload(int terms) {
    Workload w;
    w.terms = terms;
    w.file.cubemapSize = gCubemapSize;
    w.file.mesh.vertexCount = gVertices;
    // Seed 1234 for the diffuse component, whatever the term count: the diffuse data of
    // every workload are the same.
    w.file.components.push_back(randomComponent(prt::ComponentKind::MultipleScattering, 0, 1234));
    for (int k = 0; k < terms; ++k)
        w.file.components.push_back(
            randomComponent(prt::ComponentKind::SingleScatteringTerm, uint32_t(k), 5678 + uint32_t(k)));
    std::mt19937 rng(1234);
    std::uniform_real_distribution<float> value(-1.0f, 1.0f);
    if (terms > 0) {  // a valid file has the h_k view maps (unused by the kernel)
        prt::ViewMaps maps;
        maps.size = 16;
        maps.terms = terms;
        maps.data.resize(size_t(terms) * 6 * 16 * 16);
        for (float& x : maps.data) x = value(rng);
        w.file.viewMaps = std::move(maps);
    }
    prt::Cubemap radiance(gCubemapSize, 3);
    for (float& x : radiance.data()) x = std::abs(value(rng));
    w.light = prt::makeLightVector(radiance);
    w.streamBytes = prt::relightStreamBytes(w.file, {true, true});
    return w;
}

// terms = 0: the diffuse workload; 4: diffuse + K = 4 terms. Built on first use.
const Workload& workload(int terms = 0) {
    static std::map<int, Workload> built;
    auto it = built.find(terms);
    if (it == built.end()) it = built.emplace(terms, makeWorkload(terms)).first;
    return it->second;
}

// The workload's vectors in blocks (jointTruncate, gBlockCoefficients per block of 16;
// the synthetic vectors have no spatial structure, so the order changes only where the
// kernel scatters its results, order[16 b + lane]). --block-order:
//   surface   (default) spatialBlockOrder of points on a sphere numbered ring after ring
//             (latitude bands, like a scanned mesh's file order): blocks hold vertices
//             of a few neighbouring rings, as on a real mesh;
//   random    spatialBlockOrder of random points in a cube: vertex numbers unrelated to
//             position, every store of the scatter a cache miss (the worst case);
//   identity  blocks of consecutive vertices (sequential stores, the best case).
// How far apart they are: docs/performance.md, "Design measurements".
struct BlockedWorkload {
    prt::TransportFile file;  // every component blocked
    size_t streamBytes = 0;   // relightStreamBytes of the blocked file
    size_t perVertexBytes = 0;  // relightStreamBytes of the per-vertex workload (8-byte coefficients)
};

const BlockedWorkload& blockedWorkload(int terms = 0) {
    static std::map<int, BlockedWorkload> built;
    auto it = built.find(terms);
    if (it != built.end()) return it->second;
    const Workload& w = workload(terms);
    std::vector<glm::vec3> positions(gVertices);
    if (gBlockOrder == "random") {
        std::mt19937 rng(99);
        std::uniform_real_distribution<float> unit(0.0f, 1.0f);
        for (glm::vec3& p : positions) p = glm::vec3(unit(rng), unit(rng), unit(rng));
    } else {  // ~sqrt(V / 2) rings of ~2 sqrt(V / 2) points
        const size_t rings = std::max<size_t>(1, size_t(std::lround(std::sqrt(double(gVertices) / 2.0))));
        const size_t perRing = (gVertices + rings - 1) / rings;
        for (size_t i = 0; i < gVertices; ++i) {
            const double theta = prt::kPi * (double(i / perRing) + 0.5) / double(rings);
            const double phi = 2.0 * prt::kPi * double(i % perRing) / double(perRing);
            positions[i] = glm::vec3(float(std::sin(theta) * std::cos(phi)), float(std::cos(theta)),
                                     float(std::sin(theta) * std::sin(phi)));
        }
    }
    std::vector<uint32_t> order = prt::spatialBlockOrder(positions);
    if (gBlockOrder == "identity") std::iota(order.begin(), order.end(), 0u);
    BlockedWorkload b;
    b.file.cubemapSize = w.file.cubemapSize;
    b.file.mesh = w.file.mesh;
    b.file.viewMaps = w.file.viewMaps;
    for (const prt::TransportComponent& c : w.file.components) {
        prt::TransportComponent blocked;
        blocked.kind = c.kind;
        blocked.term = c.term;
        blocked.blocks = prt::jointTruncate(c.vectors, gBlockCoefficients, order);
        b.file.components.push_back(std::move(blocked));
    }
    b.streamBytes = prt::relightStreamBytes(b.file, {true, true});
    b.perVertexBytes = w.streamBytes;
    return built.emplace(terms, std::move(b)).first->second;
}

// The kernels BM_Relight and BM_BlockedRelight take by number (0, 1, 2).
const prt::RelightIsa kIsas[] = {prt::RelightIsa::Baseline, prt::RelightIsa::Avx2Fma, prt::RelightIsa::Avx512};

// The timed loop of BM_Relight and BM_BlockedRelight: relight `file` (all components)
// on `threads` threads (0 = all, TBB's default), bytes per iteration = streamBytes.
void relightLoop(benchmark::State& state, const prt::TransportFile& file, const prt::LightVector& light,
                 const prt::RelightOptions& options, int threads, size_t streamBytes) {
    prt::VertexRadiance out;
    const auto run = [&] { prt::relightVertices(file, light, {true, true}, out, options); };
    std::unique_ptr<tbb::task_arena> arena;
    if (threads > 0) arena = std::make_unique<tbb::task_arena>(threads);
    for (auto _ : state) {
        if (arena)
            arena->execute(run);
        else
            run();
        benchmark::DoNotOptimize(out.diffuse.data());
        benchmark::ClobberMemory();
    }
    state.SetBytesProcessed(int64_t(state.iterations()) * int64_t(streamBytes));
    state.counters["stream_MB"] = double(streamBytes) / 1e6;
}

// range(0): layout (3 or 4 floats per light coefficient); range(1): kernel (0 baseline
// SSE2, 1 AVX2 + FMA, 2 AVX-512); range(2): threads (0 = all, TBB's default).
void BM_Relight(benchmark::State& state) {
    const Workload& w = workload();
    prt::RelightOptions options;
    options.layout = state.range(0) == 3 ? prt::RelightLayout::Rgb3 : prt::RelightLayout::Rgb4;
    const char* names[] = {"sse2", "avx2+fma", "avx512"};
    options.isa = kIsas[state.range(1)];
    if (!prt::relightIsaSupported(options.isa)) {
        state.SkipWithError("kernel not supported on this CPU");
        return;
    }
    const int threads = int(state.range(2));
    relightLoop(state, w.file, w.light, options, threads, w.streamBytes);
    state.SetLabel(std::string(names[state.range(1)]) + ", " +
                   (options.layout == prt::RelightLayout::Rgb3 ? "rgb3" : "rgb4") +
                   (threads > 0 ? ", " + std::to_string(threads) + " thread(s)" : ", all threads"));
}
BENCHMARK(BM_Relight)
    ->ArgNames({"layout", "isa", "threads"})
    ->ArgsProduct({{4, 3}, {2, 1, 0}, {0, 1}})
    ->UseRealTime()
    ->Unit(benchmark::kMillisecond);

// The blocked diffuse workload. range(0): kernel (0 baseline: SSE2 on x86-64, 1 AVX2 + FMA,
// 2 AVX-512);
// range(1): threads (0 = all, TBB's default).
void BM_BlockedRelight(benchmark::State& state) {
    const BlockedWorkload& b = blockedWorkload();
    const Workload& w = workload();
    prt::RelightOptions options;
    const char* names[] = {"baseline (sse2)", "avx2+fma", "avx512"};
    options.isa = kIsas[state.range(0)];
    if (!prt::relightIsaSupported(options.isa)) {
        state.SkipWithError("kernel not supported on this CPU");
        return;
    }
    const int threads = int(state.range(1));
    relightLoop(state, b.file, w.light, options, threads, b.streamBytes);
    state.SetLabel(std::string(names[state.range(0)]) + ", " + std::to_string(gBlockCoefficients) +
                   " per block" + (threads > 0 ? ", " + std::to_string(threads) + " thread(s)" : ", all threads"));
}
BENCHMARK(BM_BlockedRelight)
    ->ArgNames({"isa", "threads"})
    ->ArgsProduct({{2, 1, 0}, {0, 1}})
    ->UseRealTime()
    ->Unit(benchmark::kMillisecond);

// Sum of n floats with 16 independent accumulators (so the loop is bound by loads,
// not by the add latency).
float sumFloats(const float* p, size_t n) {
#if defined(__SSE2__)
    __m128 a0 = _mm_setzero_ps(), a1 = a0, a2 = a0, a3 = a0;
    size_t i = 0;
    for (; i + 16 <= n; i += 16) {
        a0 = _mm_add_ps(a0, _mm_loadu_ps(p + i));
        a1 = _mm_add_ps(a1, _mm_loadu_ps(p + i + 4));
        a2 = _mm_add_ps(a2, _mm_loadu_ps(p + i + 8));
        a3 = _mm_add_ps(a3, _mm_loadu_ps(p + i + 12));
    }
    alignas(16) float lanes[4];
    _mm_store_ps(lanes, _mm_add_ps(_mm_add_ps(a0, a1), _mm_add_ps(a2, a3)));
    float s = (lanes[0] + lanes[1]) + (lanes[2] + lanes[3]);
#else
    float acc[16] = {};
    size_t i = 0;
    for (; i + 16 <= n; i += 16)
        for (int j = 0; j < 16; ++j) acc[j] += p[i + j];
    float s = 0.0f;
    for (float a : acc) s += a;
#endif
    for (; i < n; ++i) s += p[i];
    return s;
}

// A float array touched once (first-touch page allocation happens here, not in the loop).
std::vector<float>& bandwidthArray(size_t bytes) {
    static std::map<size_t, std::vector<float>> arrays;
    std::vector<float>& a = arrays[bytes];
    if (a.empty()) {
        a.resize(bytes / sizeof(float));
        for (size_t i = 0; i < a.size(); ++i) a[i] = float(i & 1023) * 1e-3f;
    }
    return a;
}

// range(0): bytes (0 = as large as the relight stream); range(1): 1 = all threads.
void BM_StreamSum(benchmark::State& state) {
    const size_t bytes = state.range(0) > 0 ? size_t(state.range(0)) : workload().streamBytes;
    const bool parallel = state.range(1) != 0;
    const std::vector<float>& a = bandwidthArray(bytes);
    for (auto _ : state) {
        float s;
        if (parallel) {
            s = tbb::parallel_reduce(
                tbb::blocked_range<size_t>(0, a.size(), size_t(1) << 16), 0.0f,
                [&](const tbb::blocked_range<size_t>& r, float acc) {
                    return acc + sumFloats(a.data() + r.begin(), r.size());
                },
                [](float x, float y) { return x + y; });
        } else {
            s = sumFloats(a.data(), a.size());
        }
        benchmark::DoNotOptimize(s);
    }
    state.SetBytesProcessed(int64_t(state.iterations()) * int64_t(a.size() * sizeof(float)));
    state.SetLabel(std::to_string(bytes >> 20) + " MiB, " + (parallel ? "all threads" : "1 thread"));
}
BENCHMARK(BM_StreamSum)
    ->ArgNames({"bytes", "parallel"})
    ->Args({int64_t(1) << 30, 1})
    ->Args({0, 1})
    ->Args({int64_t(1) << 30, 0})
    ->Args({0, 0})
    ->UseRealTime()
    ->Unit(benchmark::kMillisecond);

float parallelSum(const std::vector<float>& a) {
    return tbb::parallel_reduce(
        tbb::blocked_range<size_t>(0, a.size(), size_t(1) << 16), 0.0f,
        [&](const tbb::blocked_range<size_t>& r, float acc) {
            return acc + sumFloats(a.data() + r.begin(), r.size());
        },
        [](float x, float y) { return x + y; });
}

// A 1024 x 512 lat-long environment of random radiance (fixed seed), built once.
const prt::Image& syntheticEnvironment() {
    static const prt::Image env = [] {
        prt::Image e(1024, 512, 3);
        std::mt19937 rng(7);
        std::uniform_real_distribution<float> value(0.0f, 2.0f);
        for (float& x : e.pixels) x = value(rng);
        return e;
    }();
    return env;
}

// The SPEC ratio with the workloads interleaved, so both see the same machine load:
// every iteration sums a 1 GiB array (all threads; DRAM bandwidth, and it evicts the
// transport data from the caches), then relights once from memory ("cold", the time
// reported) and once more right away ("warm": on a machine whose last-level cache
// holds the ~100 MB stream this one reads it from cache). Counters:
//   dram_GBps            mean bandwidth of the 1 GiB sums;
//   ratio_cold           mean cold relight time / (stream bytes / mean bandwidth);
//   ratio_cold_median    median over iterations of the same ratio within one iteration
//                        (matched pairs: the most robust to bursts of other load);
//   ratio_warm_median    the same for the warm relight (against DRAM bandwidth);
//   cold_ms_median, warm_ms_median   median time per relight (= per frame);
//   change_ms_median     median time of a light change right after: a new light vector
//                        (a 1024 x 512 environment turned by a fresh angle) + the relight;
//   light_ms_median      its light-vector part (from the prepared environment);
//   light_from_image_ms_median   the same light vector from the image each time
//                        (makeLightVector(Image, ...)), timed after the change;
//   ratio_change_median  change time / the same stream time (SPEC section 8: the ratio
//                        per light change, beside the kernel-only ratios above);
//   stream_MB            bytes one relight streams.
// range(0): single-scattering terms besides the diffuse vector (0 or 4). With K = 4 the
// stream is five times larger (~520 MB), more than any cache, so warm ~ cold.
void BM_RelightVsStream(benchmark::State& state) {
    const Workload& w = workload(int(state.range(0)));
    const std::vector<float>& big = bandwidthArray(size_t(1) << 30);
    const double bigBytes = double(big.size() * sizeof(float));
    const double stream = double(w.streamBytes);
    prt::VertexRadiance out;
    prt::relightVertices(w.file, w.light, {true, true}, out);  // allocate the output once
    using Clock = std::chrono::steady_clock;
    const auto seconds = [](Clock::time_point a, Clock::time_point b) {
        return std::chrono::duration<double>(b - a).count();
    };
    // A light change also builds the light vector: from a 1024 x 512 environment turned
    // by a fresh, not whole-pixel angle each iteration (the viewer's spin), prepared once
    // like the viewer's (EnvironmentLight: the row running sums and the shared filter).
    const prt::Image& env = syntheticEnvironment();
    const prt::EnvironmentLight prepared(env, gCubemapSize);
    double sumBig = 0, sumCold = 0, angle = 0.37;
    std::vector<double> coldRatios, warmRatios, coldTimes, warmTimes, changeRatios, changeTimes, lightTimes,
        lightImageTimes;
    coldRatios.reserve(100000);
    warmRatios.reserve(100000);
    coldTimes.reserve(100000);
    warmTimes.reserve(100000);
    for (auto _ : state) {
        const auto t0 = Clock::now();
        benchmark::DoNotOptimize(parallelSum(big));
        const auto t1 = Clock::now();
        prt::relightVertices(w.file, w.light, {true, true}, out);
        benchmark::DoNotOptimize(out.diffuse.data());
        benchmark::ClobberMemory();
        const auto t2 = Clock::now();
        prt::relightVertices(w.file, w.light, {true, true}, out);
        benchmark::DoNotOptimize(out.diffuse.data());
        benchmark::ClobberMemory();
        const auto t3 = Clock::now();
        const prt::LightVector turned = prepared.lightVector(prt::rotationY(angle += 1.01));
        const auto t4 = Clock::now();
        prt::relightVertices(w.file, turned, {true, true}, out);
        benchmark::DoNotOptimize(out.diffuse.data());
        benchmark::ClobberMemory();
        const auto t5 = Clock::now();
        // The same light vector from the image (the entry loop), for comparison only.
        benchmark::DoNotOptimize(prt::makeLightVector(env, gCubemapSize, prt::rotationY(angle)).rgb.data());
        lightImageTimes.push_back(seconds(t5, Clock::now()));
        const double b = seconds(t0, t1), c = seconds(t1, t2), wm = seconds(t2, t3);
        const double streamSeconds = stream / (bigBytes / b);  // at this iteration's bandwidth
        changeTimes.push_back(seconds(t3, t5));
        lightTimes.push_back(seconds(t3, t4));
        changeRatios.push_back(seconds(t3, t5) / streamSeconds);
        sumBig += b;
        sumCold += c;
        coldRatios.push_back(c / streamSeconds);
        warmRatios.push_back(wm / streamSeconds);
        coldTimes.push_back(c);
        warmTimes.push_back(wm);
        state.SetIterationTime(c);
    }
    const double n = double(state.iterations());
    state.counters["dram_GBps"] = bigBytes * n / sumBig / 1e9;
    state.counters["ratio_cold"] = (sumCold / n) / (stream / (bigBytes * n / sumBig));
    state.counters["ratio_cold_median"] = median(coldRatios);
    state.counters["ratio_warm_median"] = median(warmRatios);
    state.counters["cold_ms_median"] = 1e3 * median(coldTimes);
    state.counters["warm_ms_median"] = 1e3 * median(warmTimes);
    state.counters["change_ms_median"] = 1e3 * median(changeTimes);  // light vector + kernel
    state.counters["light_ms_median"] = 1e3 * median(lightTimes);
    state.counters["light_from_image_ms_median"] = 1e3 * median(lightImageTimes);
    state.counters["ratio_change_median"] = median(changeRatios);
    state.counters["stream_MB"] = stream / 1e6;
    state.SetBytesProcessed(int64_t(state.iterations()) * int64_t(w.streamBytes));
    state.SetLabel(w.terms == 0 ? "diffuse: 1 vector per vertex"
                                : "1 diffuse + " + std::to_string(w.terms) + " term vectors per vertex");
}
BENCHMARK(BM_RelightVsStream)
    ->ArgName("terms")
    ->Arg(0)
    ->Arg(4)
    ->UseManualTime()
    ->Unit(benchmark::kMillisecond)
    ->MinTime(3.0);

// The blocked workload against the per-vertex file's bytes, interleaved like
// BM_RelightVsStream: every iteration sums the 1 GiB array, relights the blocked file
// from memory ("cold", the time reported) and again right away ("warm"), sums the 1 GiB
// array again and relights the per-vertex file of the same vectors (the per-vertex
// kernel, cold; "today" in the counter names). Counters (medians over iterations of
// per-iteration ratios, at that iteration's bandwidth):
//   ratio_vs_8byte_cold_median   blocked cold time / time to stream the per-vertex
//                                file's 8-byte coefficients (goal: <= 0.5);
//   ratio_vs_8byte_warm_median   the same for the warm relight;
//   ratio_own_cold_median        blocked cold time / time to stream its own bytes;
//   ratio_today_cold_median      the per-vertex kernel / its bytes (BM_RelightVsStream's
//                                ratio);
//   speedup_median               per-vertex cold time / the blocked cold time;
//   cold_ms_median, warm_ms_median, today_cold_ms_median (per-vertex); dram_GBps (mean
//   of the sums); stream_MB (blocked), stream_8byte_MB (per-vertex).
// range(0): single-scattering terms besides the diffuse vector (0 or 4).
void BM_BlockedRelightVsStream(benchmark::State& state) {
    const int terms = int(state.range(0));
    const BlockedWorkload& bw = blockedWorkload(terms);
    const Workload& w = workload(terms);
    const std::vector<float>& big = bandwidthArray(size_t(1) << 30);
    const double bigBytes = double(big.size() * sizeof(float));
    prt::VertexRadiance out, today;
    prt::relightVertices(bw.file, w.light, {true, true}, out);  // allocate the outputs once
    prt::relightVertices(w.file, w.light, {true, true}, today);
    using Clock = std::chrono::steady_clock;
    const auto seconds = [](Clock::time_point a, Clock::time_point b) {
        return std::chrono::duration<double>(b - a).count();
    };
    double sumBig = 0;
    std::vector<double> cold, warm, todayCold, vs8Cold, vs8Warm, own, todayRatio, speedup;
    for (auto _ : state) {
        const auto t0 = Clock::now();
        benchmark::DoNotOptimize(parallelSum(big));
        const auto t1 = Clock::now();
        prt::relightVertices(bw.file, w.light, {true, true}, out);
        benchmark::DoNotOptimize(out.diffuse.data());
        benchmark::ClobberMemory();
        const auto t2 = Clock::now();
        prt::relightVertices(bw.file, w.light, {true, true}, out);
        benchmark::DoNotOptimize(out.diffuse.data());
        benchmark::ClobberMemory();
        const auto t3 = Clock::now();
        benchmark::DoNotOptimize(parallelSum(big));
        const auto t4 = Clock::now();
        prt::relightVertices(w.file, w.light, {true, true}, today);
        benchmark::DoNotOptimize(today.diffuse.data());
        benchmark::ClobberMemory();
        const auto t5 = Clock::now();
        const double b = 0.5 * (seconds(t0, t1) + seconds(t3, t4));  // this iteration's 1 GiB sum
        const double bandwidth = bigBytes / b;
        const double c = seconds(t1, t2), wm = seconds(t2, t3), t = seconds(t4, t5);
        sumBig += b;
        cold.push_back(c);
        warm.push_back(wm);
        todayCold.push_back(t);
        vs8Cold.push_back(c / (double(bw.perVertexBytes) / bandwidth));
        vs8Warm.push_back(wm / (double(bw.perVertexBytes) / bandwidth));
        own.push_back(c / (double(bw.streamBytes) / bandwidth));
        todayRatio.push_back(t / (double(bw.perVertexBytes) / bandwidth));
        speedup.push_back(t / c);
        state.SetIterationTime(c);
    }
    const double n = double(state.iterations());
    state.counters["dram_GBps"] = bigBytes * n / sumBig / 1e9;
    state.counters["ratio_vs_8byte_cold_median"] = median(vs8Cold);
    state.counters["ratio_vs_8byte_warm_median"] = median(vs8Warm);
    state.counters["ratio_own_cold_median"] = median(own);
    state.counters["ratio_today_cold_median"] = median(todayRatio);
    state.counters["speedup_median"] = median(speedup);
    state.counters["cold_ms_median"] = 1e3 * median(cold);
    state.counters["warm_ms_median"] = 1e3 * median(warm);
    state.counters["today_cold_ms_median"] = 1e3 * median(todayCold);
    state.counters["stream_MB"] = double(bw.streamBytes) / 1e6;
    state.counters["stream_8byte_MB"] = double(bw.perVertexBytes) / 1e6;
    state.SetBytesProcessed(int64_t(state.iterations()) * int64_t(bw.streamBytes));
    state.SetLabel((terms == 0 ? std::string("diffuse") : "1 diffuse + " + std::to_string(terms) + " terms") +
                   ", blocks of 16 sharing " + std::to_string(gBlockCoefficients));
}
// A fixed 100 iterations (docs/tools.md, "bench_relight"): with the manual time being
// the cold relight alone, a minimum time would take thousands of 1 GiB sums.
BENCHMARK(BM_BlockedRelightVsStream)
    ->ArgName("terms")
    ->Arg(0)
    ->Arg(4)
    ->UseManualTime()
    ->Unit(benchmark::kMillisecond)
    ->Iterations(100);

// ---------------------------------------------------------------------------
// Transport-file load time: loadTransportFile (read + every checksum + every index
// check) of the diffuse workload, saved once with saveTransportFile into --tmp-dir.
// range(0) = 0: from the page cache (the file was just written or read); 1: "cold",
// the file's pages dropped from the page cache before every load with
// posix_fadvise(POSIX_FADV_DONTNEED) (no root needed; the pages are clean after the
// save's fsync). Counter cached_fraction = fraction of the file's pages still in the
// page cache right after the drop (mincore): 0 means the drop worked; on tmpfs it
// cannot work (1). On a VM a "cold" read may still come from the host's cache.
// ---------------------------------------------------------------------------

// The diffuse workload saved once into --tmp-dir; removed at exit.
struct LoadFile {
    std::string path;
    size_t bytes = 0;
    LoadFile() {
        namespace fs = std::filesystem;
        const fs::path dir = gTmpDir.empty() ? fs::temp_directory_path() : fs::path(gTmpDir);
        path = (dir / ("bench_relight_load." + std::to_string(long(::getpid())) + ".prt")).string();
        prt::saveTransportFile(path, workload(0).file);
        bytes = size_t(fs::file_size(path));
    }
    LoadFile(const LoadFile&) = delete;
    LoadFile& operator=(const LoadFile&) = delete;
    ~LoadFile() { std::remove(path.c_str()); }
};

const LoadFile& loadFile() {
    static const LoadFile f;
    return f;
}

// Fraction of the file's pages resident in the page cache (mincore), or -1.
double residentFraction(const std::string& path) {
    const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
    if (fd < 0) return -1;
    struct stat st {};
    double fraction = -1;
    if (::fstat(fd, &st) == 0 && st.st_size > 0) {
        void* p = ::mmap(nullptr, size_t(st.st_size), PROT_READ, MAP_SHARED, fd, 0);
        if (p != MAP_FAILED) {
            const size_t page = size_t(::sysconf(_SC_PAGESIZE));
            std::vector<unsigned char> vec((size_t(st.st_size) + page - 1) / page);
            if (::mincore(p, size_t(st.st_size), vec.data()) == 0) {
                size_t resident = 0;
                for (unsigned char c : vec) resident += c & 1;
                fraction = double(resident) / double(vec.size());
            }
            ::munmap(p, size_t(st.st_size));
        }
    }
    ::close(fd);
    return fraction;
}

// Asks the kernel to drop the file's (clean) pages from the page cache.
void dropFromPageCache(const std::string& path) {
    const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
    if (fd < 0) return;
    (void)::fdatasync(fd);
    (void)::posix_fadvise(fd, 0, 0, POSIX_FADV_DONTNEED);
    ::close(fd);
}

void BM_LoadTransportFile(benchmark::State& state) {
    const bool cold = state.range(0) != 0;
    const LoadFile& f = loadFile();
    double cachedSum = 0;
    if (!cold) {  // make sure it is in the page cache
        benchmark::DoNotOptimize(prt::loadTransportFile(f.path).components.size());
    }
    for (auto _ : state) {
        if (cold) {
            state.PauseTiming();
            dropFromPageCache(f.path);
            cachedSum += residentFraction(f.path);
            state.ResumeTiming();
        }
        auto file = std::make_unique<prt::TransportFile>(prt::loadTransportFile(f.path));
        benchmark::DoNotOptimize(file->components.data());
        state.PauseTiming();
        file.reset();  // freeing the arrays is not part of the load
        state.ResumeTiming();
    }
    state.SetBytesProcessed(int64_t(state.iterations()) * int64_t(f.bytes));
    state.counters["file_MB"] = double(f.bytes) / 1e6;
    if (cold) state.counters["cached_fraction"] = cachedSum / double(state.iterations());
    state.SetLabel(cold ? "dropped from the page cache before each load" : "from the page cache");
}
BENCHMARK(BM_LoadTransportFile)
    ->ArgName("cold")
    ->Arg(0)
    ->Arg(1)
    ->UseRealTime()
    ->Unit(benchmark::kMillisecond)
    ->MinTime(2.0);

// memcpy of 256 MiB; bytes processed counts the bytes copied (the memory traffic is
// twice that, read + write, plus write-allocate reads).
void BM_Memcpy(benchmark::State& state) {
    const size_t bytes = size_t(256) << 20;
    std::vector<char> src(bytes, 1), dst(bytes, 0);
    for (auto _ : state) {
        std::memcpy(dst.data(), src.data(), bytes);
        benchmark::DoNotOptimize(dst.data());
        benchmark::ClobberMemory();
    }
    state.SetBytesProcessed(int64_t(state.iterations()) * int64_t(bytes));
}
BENCHMARK(BM_Memcpy)->UseRealTime()->Unit(benchmark::kMillisecond);

// Console output plus the seconds per iteration and the counters of every run, for
// the ratios and the summary.
class RatioReporter : public benchmark::ConsoleReporter {
public:
    std::map<std::string, double> seconds;  // best (smallest) real time per iteration
    // Counters of the last run of each benchmark.
    std::map<std::string, std::map<std::string, double>> counters;

    void ReportRuns(const std::vector<Run>& runs) override {
        for (const Run& r : runs) {
            if (r.run_type != Run::RT_Iteration || r.iterations == 0) continue;
            const double s = r.real_accumulated_time / double(r.iterations);
            auto [it, inserted] = seconds.emplace(r.benchmark_name(), s);
            if (!inserted) it->second = std::min(it->second, s);
            auto& c = counters[r.benchmark_name()];
            for (const auto& [key, counter] : r.counters) c[key] = counter.value;
        }
        ConsoleReporter::ReportRuns(runs);
    }

    // The first benchmark whose name starts with prefix (nullptr if none ran).
    const std::map<std::string, double>* countersOf(const std::string& prefix) const {
        for (const auto& [name, c] : counters)
            if (name.rfind(prefix, 0) == 0) return &c;
        return nullptr;
    }
    double secondsOf(const std::string& prefix) const {
        for (const auto& [name, s] : seconds)
            if (name.rfind(prefix, 0) == 0) return s;
        return 0.0;
    }
};

double counter(const std::map<std::string, double>* c, const char* key) {
    if (!c) return 0.0;
    const auto it = c->find(key);
    return it == c->end() ? 0.0 : it->second;
}

bool parseString(const char* arg, const char* name, std::string& out) {
    const size_t len = std::strlen(name);
    if (std::strncmp(arg, name, len) != 0 || arg[len] != '=') return false;
    out = arg + len + 1;
    return true;
}

bool parseSize(const char* arg, const char* name, size_t& out) {
    const size_t len = std::strlen(name);
    if (std::strncmp(arg, name, len) != 0 || arg[len] != '=') return false;
    out = size_t(std::strtoull(arg + len + 1, nullptr, 10));
    return true;
}

}  // namespace

int main(int argc, char** argv) {
    std::vector<char*> rest;
    size_t cubemapSize = size_t(gCubemapSize);
    std::string summaryJson;
    for (int i = 0; i < argc; ++i)
        if (i == 0 || !(parseSize(argv[i], "--vertices", gVertices) ||
                        parseSize(argv[i], "--coefficients", gCoefficients) ||
                        parseSize(argv[i], "--block-coefficients", gBlockCoefficients) ||
                        parseSize(argv[i], "--n", cubemapSize) ||
                        parseString(argv[i], "--tmp-dir", gTmpDir) ||
                        parseString(argv[i], "--block-order", gBlockOrder) ||
                        parseString(argv[i], "--summary-json", summaryJson)))
            rest.push_back(argv[i]);
    gCubemapSize = int(cubemapSize);
    if (gCubemapSize < 1 || gCubemapSize > 64 || (gCubemapSize & (gCubemapSize - 1)) != 0) {
        std::fprintf(stderr, "bench_relight: --n must be a power of two in 1..64\n");
        return 1;
    }
    if (gBlockCoefficients < 1) {
        std::fprintf(stderr, "bench_relight: --block-coefficients must be >= 1\n");
        return 1;
    }
    if (gBlockOrder != "surface" && gBlockOrder != "random" && gBlockOrder != "identity") {
        std::fprintf(stderr, "bench_relight: --block-order must be surface, random or identity\n");
        return 1;
    }
    if (!gTmpDir.empty() && !std::filesystem::is_directory(gTmpDir)) {
        std::fprintf(stderr, "bench_relight: --tmp-dir %s: not a directory\n", gTmpDir.c_str());
        return 1;
    }
    int restCount = int(rest.size());
    benchmark::Initialize(&restCount, rest.data());
    if (benchmark::ReportUnrecognizedArguments(restCount, rest.data())) return 1;

    const Workload& w = workload();
    std::printf("relight workload: %zu vertices x %zu coefficients, N = %d, %.1f MB streamed per relight "
                "(diffuse); K = 4 terms: 5 such vectors per vertex\n",
                gVertices, gCoefficients, gCubemapSize, double(w.streamBytes) / 1e6);

    RatioReporter reporter;
    try {
        benchmark::RunSpecifiedBenchmarks(&reporter);
    } catch (const std::exception& e) {  // e.g. the load benchmark cannot write its file
        std::fprintf(stderr, "bench_relight: error: %s\n", e.what());
        return 1;
    }

    const auto get = [&](const std::string& prefix) { return reporter.secondsOf(prefix); };
    const double bigParallel = get("BM_StreamSum/bytes:1073741824/parallel:1");
    const double sameParallel = get("BM_StreamSum/bytes:0/parallel:1");
    const double bw = bigParallel > 0 ? double(size_t(1) << 30) / bigParallel : 0.0;
    const double bwSame = sameParallel > 0 ? double(w.streamBytes) / sameParallel : 0.0;
    std::printf("\n");
    if (bw > 0) {
        std::printf("read bandwidth (1 GiB, all threads): %.2f GB/s; same-size array: %.2f GB/s\n",
                    bw / 1e9, bwSame / 1e9);
        std::printf("time to stream %.1f MB at that bandwidth: %.3f ms\n",
                    double(w.streamBytes) / 1e6, 1e3 * double(w.streamBytes) / bw);
        for (const char* variant :
             {"BM_Relight/layout:4/isa:2/threads:0", "BM_Relight/layout:3/isa:2/threads:0",
              "BM_Relight/layout:4/isa:1/threads:0", "BM_Relight/layout:3/isa:1/threads:0",
              "BM_Relight/layout:4/isa:0/threads:0", "BM_Relight/layout:3/isa:0/threads:0"}) {
            const double t = get(variant);
            if (t <= 0) continue;
            std::printf("%s: %.3f ms per relight (best run), ratio %.2f (warm vs same-size array: %.2f)\n",
                        variant, 1e3 * t, t / (double(w.streamBytes) / bw),
                        bwSame > 0 ? t / (double(w.streamBytes) / bwSame) : 0.0);
        }
        for (const char* variant : {"BM_BlockedRelight/isa:2/threads:0", "BM_BlockedRelight/isa:1/threads:0",
                                    "BM_BlockedRelight/isa:0/threads:0"}) {
            const double t = get(variant);
            if (t <= 0) continue;
            const BlockedWorkload& b = blockedWorkload();  // built by the benchmark
            std::printf("%s: %.3f ms per relight (best run), ratio to streaming today's 8-byte %.1f MB %.2f, "
                        "to streaming its own %.1f MB %.2f\n",
                        variant, 1e3 * t, double(w.streamBytes) / 1e6, t / (double(w.streamBytes) / bw),
                        double(b.streamBytes) / 1e6, t / (double(b.streamBytes) / bw));
        }
    }

    nlohmann::ordered_json summary;
    summary["workload"] = {{"vertices", gVertices}, {"coefficients", gCoefficients}, {"cubemap_size", gCubemapSize}};
    if (bw > 0) summary["stream_sum_GBps"] = bw / 1e9;
    for (int terms : {0, 4}) {
        const auto* c = reporter.countersOf("BM_RelightVsStream/terms:" + std::to_string(terms) + "/");
        if (!c) continue;
        const char* name = terms == 0 ? "diffuse" : "k4";
        std::printf("BM_RelightVsStream (interleaved with 1 GiB sums), %s (%.1f MB per frame): "
                    "%.2f ms per frame cold (median), %.2f warm; ratio_cold %.2f, ratio_cold_median "
                    "%.2f, ratio_warm_median %.2f (goal <= 1.5); %.2f GB/s DRAM; light change %.2f ms "
                    "(light vector %.2f + kernel), ratio_change_median %.2f\n",
                    terms == 0 ? "diffuse only" : "1 diffuse + K = 4 terms", counter(c, "stream_MB"),
                    counter(c, "cold_ms_median"), counter(c, "warm_ms_median"), counter(c, "ratio_cold"),
                    counter(c, "ratio_cold_median"), counter(c, "ratio_warm_median"),
                    counter(c, "dram_GBps"), counter(c, "change_ms_median"), counter(c, "light_ms_median"),
                    counter(c, "ratio_change_median"));
        nlohmann::ordered_json r;
        r["components"] = terms == 0 ? "1 diffuse vector" : "1 diffuse + 4 term vectors";
        for (const char* key : {"stream_MB", "cold_ms_median", "warm_ms_median", "ratio_cold",
                                "ratio_cold_median", "ratio_warm_median", "dram_GBps", "change_ms_median",
                                "light_ms_median", "ratio_change_median"})
            r[key] = counter(c, key);
        summary["relight"][name] = r;
    }
    for (int terms : {0, 4}) {
        const auto* c = reporter.countersOf("BM_BlockedRelightVsStream/terms:" + std::to_string(terms) + "/");
        if (!c) continue;
        const char* name = terms == 0 ? "diffuse" : "k4";
        std::printf("BM_BlockedRelightVsStream, %s, blocks of 16 sharing %zu, %s order (%.1f MB per frame; today's "
                    "8-byte per-vertex file %.1f MB): %.2f ms per frame cold (median), %.2f warm; today's "
                    "kernel %.2f ms cold; ratio to streaming the 8-byte bytes %.2f cold, %.2f warm (goal <= "
                    "0.5); ratio to streaming its own bytes %.2f; today's kernel ratio %.2f; speedup %.2fx; "
                    "%.2f GB/s DRAM\n",
                    terms == 0 ? "diffuse only" : "1 diffuse + K = 4 terms", gBlockCoefficients,
                    gBlockOrder.c_str(), counter(c, "stream_MB"), counter(c, "stream_8byte_MB"), counter(c, "cold_ms_median"),
                    counter(c, "warm_ms_median"), counter(c, "today_cold_ms_median"),
                    counter(c, "ratio_vs_8byte_cold_median"), counter(c, "ratio_vs_8byte_warm_median"),
                    counter(c, "ratio_own_cold_median"), counter(c, "ratio_today_cold_median"),
                    counter(c, "speedup_median"), counter(c, "dram_GBps"));
        nlohmann::ordered_json r;
        r["components"] = terms == 0 ? "1 diffuse vector" : "1 diffuse + 4 term vectors";
        r["block_coefficients"] = gBlockCoefficients;
        r["block_order"] = gBlockOrder;
        for (const char* key : {"stream_MB", "stream_8byte_MB", "cold_ms_median", "warm_ms_median",
                                "today_cold_ms_median", "ratio_vs_8byte_cold_median", "ratio_vs_8byte_warm_median",
                                "ratio_own_cold_median", "ratio_today_cold_median", "speedup_median", "dram_GBps"})
            r[key] = counter(c, key);
        summary["blocked"][name] = r;
    }
    for (int cold : {0, 1}) {
        const std::string prefix = "BM_LoadTransportFile/cold:" + std::to_string(cold) + "/";
        const auto* c = reporter.countersOf(prefix);
        const double t = get(prefix);
        if (!c || t <= 0) continue;
        const double mb = counter(c, "file_MB");
        std::printf("load %.1f MB transport file (%s): %.1f ms, %.0f MB/s", mb,
                    cold ? "dropped from the page cache" : "page cache", 1e3 * t, mb / t);
        if (cold)
            std::printf(" (%.0f%% of its pages were still cached after the drop)",
                        100.0 * counter(c, "cached_fraction"));
        std::printf("\n");
        nlohmann::ordered_json r;
        r["file_MB"] = mb;
        r["ms"] = 1e3 * t;  // best run
        r["MBps"] = mb / t;
        if (cold) r["cached_fraction"] = counter(c, "cached_fraction");
        summary["load"][cold ? "cold" : "page_cache"] = r;
    }
    if (!summaryJson.empty()) {
        try {
            prt::writeFileAtomically(summaryJson, summary.dump(2) + "\n");
        } catch (const prt::Error& e) {
            std::fprintf(stderr, "bench_relight: error: %s\n", e.what());
            return 1;
        }
        std::printf("summary: %s\n", summaryJson.c_str());
    }
    benchmark::Shutdown();
    return 0;
}
