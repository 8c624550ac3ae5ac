// Relight kernel against the machine's memory bandwidth (SPEC section 8):
//   ratio = time per relight / (bytes the relight streams / measured read bandwidth),
// goal <= 1.5. Everything is measured in one run of this program, so the ratio holds
// on a noisy machine; it is printed after the Google Benchmark table.
//
// Workload: a synthetic multiple-scattering component of 100,000 vertices x 128
// coefficients (random distinct indices, sorted, over 6 x 32 x 32 = 6144 Haar
// coefficients; random values), relit against a full (unapproximated) light vector.
// Baselines: a multithreaded (TBB, all cores, like the relight) and a single-threaded
// sum of a float array, once for a 1 GiB array (larger than any cache: the bandwidth
// used for the ratio) and once for an array as large as the relight's stream; memcpy.
// BM_RelightVsStream interleaves a 1 GiB sum and relights in every iteration, so its
// ratios are the least sensitive to other load on the machine (see there).
//
// Usage: bench_relight [--vertices=V] [--coefficients=M] [--n=N] [google benchmark flags]
// (defaults 100000, 128, 32).

#include <benchmark/benchmark.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_reduce.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
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

#include "common/light.h"
#include "common/relight.h"
#include "common/transport_file.h"

namespace {

size_t gVertices = 100000;
size_t gCoefficients = 128;
int gCubemapSize = 32;

struct Workload {
    prt::TransportFile file;
    prt::LightVector light;
    size_t streamBytes = 0;
};

const Workload& workload() {
    static const Workload w = [] {
        Workload w;
        w.file.cubemapSize = gCubemapSize;
        w.file.mesh.vertexCount = gVertices;
        prt::TransportComponent ms;
        ms.kind = prt::ComponentKind::MultipleScattering;
        const uint32_t count = 6 * gCubemapSize * gCubemapSize;
        const size_t m = std::min<size_t>(gCoefficients, count);
        ms.vectors.reserve(gVertices, gVertices * m);
        std::mt19937 rng(1234);
        std::uniform_real_distribution<float> value(-1.0f, 1.0f);
        std::vector<uint32_t> all(count);
        std::iota(all.begin(), all.end(), 0u);
        std::vector<float> rgb(3 * m);
        for (size_t v = 0; v < gVertices; ++v) {
            // Partial Fisher-Yates: m distinct random indices (appendVertex sorts them).
            for (size_t k = 0; k < m; ++k)
                std::swap(all[k], all[k + std::uniform_int_distribution<size_t>(0, count - 1 - k)(rng)]);
            for (float& x : rgb) x = value(rng);
            ms.vectors.appendVertex(std::span<const uint32_t>(all.data(), m), rgb);
        }
        w.file.components.push_back(std::move(ms));
        prt::Cubemap radiance(gCubemapSize, 3);
        for (float& x : radiance.data()) x = std::abs(value(rng));
        w.light = prt::makeLightVector(radiance);
        w.streamBytes = prt::relightStreamBytes(w.file, {true, true});
        return w;
    }();
    return w;
}

// range(0): layout (3 or 4 floats per light coefficient); range(1): kernel (0 baseline
// SSE2, 1 AVX2 + FMA); range(2): threads (0 = all, TBB's default).
void BM_Relight(benchmark::State& state) {
    const Workload& w = workload();
    prt::RelightOptions options;
    options.layout = state.range(0) == 3 ? prt::RelightLayout::Rgb3 : prt::RelightLayout::Rgb4;
    options.isa = state.range(1) == 1 ? prt::RelightIsa::Avx2Fma : prt::RelightIsa::Baseline;
    if (!prt::relightIsaSupported(options.isa)) {
        state.SkipWithError("AVX2 + FMA not supported on this CPU");
        return;
    }
    const int threads = int(state.range(2));
    prt::VertexRadiance out;
    const auto run = [&] { prt::relightVertices(w.file, w.light, {true, true}, out, options); };
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
    state.SetBytesProcessed(int64_t(state.iterations()) * int64_t(w.streamBytes));
    state.counters["stream_MB"] = double(w.streamBytes) / 1e6;
    state.SetLabel(std::string(state.range(1) == 1 ? "avx2+fma, " : "sse2, ") +
                   (options.layout == prt::RelightLayout::Rgb3 ? "rgb3" : "rgb4") +
                   (threads > 0 ? ", " + std::to_string(threads) + " thread(s)" : ", all threads"));
}
BENCHMARK(BM_Relight)
    ->ArgNames({"layout", "avx2", "threads"})
    ->ArgsProduct({{4, 3}, {1, 0}, {0, 1}})
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

double median(std::vector<double> v) {
    if (v.empty()) return 0.0;
    std::nth_element(v.begin(), v.begin() + std::ptrdiff_t(v.size() / 2), v.end());
    return v[v.size() / 2];
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
//   ratio_warm_median    the same for the warm relight (against DRAM bandwidth).
void BM_RelightVsStream(benchmark::State& state) {
    const Workload& w = workload();
    const std::vector<float>& big = bandwidthArray(size_t(1) << 30);
    const double bigBytes = double(big.size() * sizeof(float));
    const double stream = double(w.streamBytes);
    prt::VertexRadiance out;
    prt::relightVertices(w.file, w.light, {true, true}, out);  // allocate the output once
    using Clock = std::chrono::steady_clock;
    const auto seconds = [](Clock::time_point a, Clock::time_point b) {
        return std::chrono::duration<double>(b - a).count();
    };
    double sumBig = 0, sumCold = 0;
    std::vector<double> coldRatios, warmRatios;
    coldRatios.reserve(100000);
    warmRatios.reserve(100000);
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
        const double b = seconds(t0, t1), c = seconds(t1, t2), wm = seconds(t2, t3);
        const double streamSeconds = stream / (bigBytes / b);  // at this iteration's bandwidth
        sumBig += b;
        sumCold += c;
        coldRatios.push_back(c / streamSeconds);
        warmRatios.push_back(wm / streamSeconds);
        state.SetIterationTime(c);
    }
    const double n = double(state.iterations());
    state.counters["dram_GBps"] = bigBytes * n / sumBig / 1e9;
    state.counters["ratio_cold"] = (sumCold / n) / (stream / (bigBytes * n / sumBig));
    state.counters["ratio_cold_median"] = median(coldRatios);
    state.counters["ratio_warm_median"] = median(warmRatios);
    state.SetBytesProcessed(int64_t(state.iterations()) * int64_t(w.streamBytes));
}
BENCHMARK(BM_RelightVsStream)->UseManualTime()->Unit(benchmark::kMillisecond)->MinTime(3.0);

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

// Console output plus the seconds per iteration of every run, for the ratio.
class RatioReporter : public benchmark::ConsoleReporter {
public:
    std::map<std::string, double> seconds;  // best (smallest) real time per iteration
    std::map<std::string, std::vector<double>> interleaved;  // BM_RelightVsStream's ratios, per run

    void ReportRuns(const std::vector<Run>& runs) override {
        for (const Run& r : runs) {
            if (r.run_type != Run::RT_Iteration || r.iterations == 0) continue;
            const double s = r.real_accumulated_time / double(r.iterations);
            auto [it, inserted] = seconds.emplace(r.benchmark_name(), s);
            if (!inserted) it->second = std::min(it->second, s);
            for (const char* key : {"ratio_cold", "ratio_cold_median", "ratio_warm_median"}) {
                const auto it2 = r.counters.find(key);
                if (it2 != r.counters.end()) interleaved[key].push_back(it2->second.value);
            }
        }
        ConsoleReporter::ReportRuns(runs);
    }
};

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
    for (int i = 0; i < argc; ++i)
        if (i == 0 || !(parseSize(argv[i], "--vertices", gVertices) ||
                        parseSize(argv[i], "--coefficients", gCoefficients) ||
                        parseSize(argv[i], "--n", cubemapSize)))
            rest.push_back(argv[i]);
    gCubemapSize = int(cubemapSize);
    if (gCubemapSize < 1 || gCubemapSize > 64 || (gCubemapSize & (gCubemapSize - 1)) != 0) {
        std::fprintf(stderr, "bench_relight: --n must be a power of two in 1..64\n");
        return 1;
    }
    int restCount = int(rest.size());
    benchmark::Initialize(&restCount, rest.data());
    if (benchmark::ReportUnrecognizedArguments(restCount, rest.data())) return 1;

    const Workload& w = workload();
    std::printf("relight workload: %zu vertices x %zu coefficients, N = %d, %.1f MB streamed per relight\n",
                gVertices, gCoefficients, gCubemapSize, double(w.streamBytes) / 1e6);

    RatioReporter reporter;
    benchmark::RunSpecifiedBenchmarks(&reporter);

    const auto get = [&](const std::string& prefix) -> double {
        for (const auto& [name, s] : reporter.seconds)
            if (name.rfind(prefix, 0) == 0) return s;
        return 0.0;
    };
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
             {"BM_Relight/layout:4/avx2:1/threads:0", "BM_Relight/layout:3/avx2:1/threads:0",
              "BM_Relight/layout:4/avx2:0/threads:0", "BM_Relight/layout:3/avx2:0/threads:0"}) {
            const double t = get(variant);
            if (t <= 0) continue;
            std::printf("%s: %.3f ms per relight (best run), ratio %.2f (warm vs same-size array: %.2f)\n",
                        variant, 1e3 * t, t / (double(w.streamBytes) / bw),
                        bwSame > 0 ? t / (double(w.streamBytes) / bwSame) : 0.0);
        }
    }
    for (const auto& [key, values] : reporter.interleaved)
        for (double r : values)
            std::printf("BM_RelightVsStream (interleaved with 1 GiB sums): %s %.2f (goal <= 1.5)\n",
                        key.c_str(), r);
    benchmark::Shutdown();
    return 0;
}
