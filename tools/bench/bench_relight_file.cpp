// prt-bench-relight-file: times one transport file's relight (docs/tools.md):
// load time, the light vector (environment -> cubemap -> Haar; from the prepared
// environment, EnvironmentLight, beside makeLightVector from the image) and the relight kernel
// (relightVertices, every component of the file), each as the median of many runs:
// back to back ("warm": a file smaller than the last-level cache is then read from
// cache) and each after reading a 1 GiB array ("cold": from memory).
// Used by tools/scaling.sh for the relight time per frame of every precomputed file.
// Per-vertex and blocked components (common/blocked_vectors.h) alike; "coefficients"
// counts each vertex's coefficients (a blocked vertex has its block's indices).

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>
#include <tbb/blocked_range.h>
#include <tbb/global_control.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <random>
#include <string>
#include <unistd.h>
#include <vector>

#include "common/atomic_file.h"
#include "common/envmap.h"
#include "common/error.h"
#include "relight/prt/light_vector.h"
#include "relight/prt/relight_kernel.h"
#include "common/transport_file.h"
#include "common/options.h"
#include "common/util.h"

using namespace prt;

namespace {

using Clock = std::chrono::steady_clock;

double secondsSince(Clock::time_point t) {
    return std::chrono::duration<double>(Clock::now() - t).count();
}

// Reads `a` (all threads) so the transport data is evicted from the caches.
float sumAll(const std::vector<float>& a) {
    return tbb::parallel_reduce(
        tbb::blocked_range<size_t>(0, a.size(), size_t(1) << 16), 0.0f,
        [&](const tbb::blocked_range<size_t>& r, float acc) {
            for (size_t i = r.begin(); i < r.end(); ++i) acc += a[i];
            return acc;
        },
        [](float x, float y) { return x + y; });
}

volatile float gSink = 0.0f;

}  // namespace

int main(int argc, char** argv) {
    return runMain("prt-bench-relight-file", [&]() -> int {
        CLI::App app{
            "prt-bench-relight-file: load time, light-vector time and relight-kernel time per frame of "
            "one transport file (medians over many runs)"};
        std::string path, envPath, jsonPath, components = "all";
        int iterations = 50, lightIterations = 10, coldIterations = 10, threads = 0;
        double minSeconds = 1.0;
        size_t lightTerms = 0;
        app.add_option("transport", path, "Transport file (.prt)")->required();
        app.add_option("-e,--environment", envPath,
                       "Lat-long environment for the light vector (without: a synthetic full light "
                       "vector, and no light-vector time)");
        app.add_option("--components", components, "Components to relight: ms, ss, ms,ss or all")
            ->capture_default_str();
        app.add_option("--light-terms", lightTerms, "Keep the largest L light coefficients (0: all)")
            ->capture_default_str();
        app.add_option("--iterations", iterations, "Relight runs (at least; see --min-seconds)")
            ->capture_default_str();
        app.add_option("--min-seconds", minSeconds, "Keep relighting until this much time has passed")
            ->capture_default_str();
        app.add_option("--light-iterations", lightIterations, "Light-vector runs (environment rotated)")
            ->capture_default_str();
        app.add_option("--cold-iterations", coldIterations,
                       "Relight runs each after reading a 1 GiB array (caches flushed; 0: none)")
            ->capture_default_str();
        std::string isaName = "best";
        app.add_option("--isa", isaName,
                       "Relight kernel: best (the CPU's best, what prt-relight runs), baseline (SSE2), avx2 or avx512")
            ->check(CLI::IsMember({"best", "baseline", "avx2", "avx512"}))
            ->capture_default_str();
        addThreadsOption(app, threads);
        app.add_option("--json", jsonPath, "Also write the results as JSON to this file");
        if (const auto exitCode = parseCommandLine(app, argc, argv, "prt-bench-relight-file")) return *exitCode;
        if (iterations < 1) throw Error("--iterations", "must be >= 1");
        if (lightIterations < 1) throw Error("--light-iterations", "must be >= 1");
        if (coldIterations < 0) throw Error("--cold-iterations", "must be >= 0");
        const ThreadLimit limit(threads);
        RelightOptions kernel;
        kernel.isa = isaName == "baseline" ? RelightIsa::Baseline
                     : isaName == "avx2"   ? RelightIsa::Avx2Fma
                     : isaName == "avx512" ? RelightIsa::Avx512
                                           : RelightIsa::Best;
        if (!relightIsaSupported(kernel.isa)) throw Error("--isa", isaName + " is not supported on this CPU or build");

        // Load (whatever the page cache holds: a file just written is cached).
        auto t0 = Clock::now();
        const TransportFile file = loadTransportFile(path);
        const double loadSeconds = secondsSince(t0);
        const double fileBytes = double(std::filesystem::file_size(path));

        const ScatteringComponents set = parseScatteringComponents(components) & componentsOf(file);
        if (!set.any())
            throw Error(path, "has none of the requested components (--components " + components + ")");
        int terms = 0;
        for (const TransportComponent& c : file.components) terms += c.kind == ComponentKind::SingleScatteringTerm;
        const int n = int(file.cubemapSize);
        const size_t vertices = file.components.empty() ? 0 : file.components[0].vertexCount();
        // Coefficients per vertex summed over vertices: a blocked component's vertex has
        // its block's indices (each stored once per block of 16: blockIndices).
        size_t coefficients = 0, blockIndices = 0, blockedCoefficients = 0;
        int blockedComponents = 0;
        for (const TransportComponent& c : file.components) {
            if (!c.blocked()) {
                coefficients += c.vectors.coefficientCount();
                continue;
            }
            const BlockedRgbVectors& b = c.blocks;
            ++blockedComponents;
            blockIndices += b.indexCount();
            for (size_t k = 0; k + 1 < b.offsets.size(); ++k)
                blockedCoefficients += size_t(b.offsets[k + 1] - b.offsets[k]) *
                                       std::min<size_t>(kVertexBlock, b.vertexCount() - k * kVertexBlock);
        }
        coefficients += blockedCoefficients;

        // Light vector: from the environment (timed, rotated each run like an
        // environment spin), or synthetic. Timed both ways, interleaved: from the prepared
        // environment (EnvironmentLight, what the viewer and prt-relight hold) and from
        // the image each time (makeLightVector(Image, ...), the entry loop).
        LightVector light;
        std::vector<double> lightTimes, lightImageTimes;
        double prepareSeconds = 0.0;
        std::unique_ptr<EnvironmentLight> prepared;
        const Image env = envPath.empty() ? Image() : loadEnvironment(envPath, NonFinitePolicy::ClampNegative);
        if (!envPath.empty()) {
            t0 = Clock::now();
            prepared = std::make_unique<EnvironmentLight>(env, n);
            prepareSeconds = secondsSince(t0);
            for (int i = 0; i < lightIterations; ++i) {
                const glm::dmat3 r = rotationY(360.0 * i / lightIterations);
                t0 = Clock::now();
                light = prepared->lightVector(r, lightTerms);
                lightTimes.push_back(secondsSince(t0));
                t0 = Clock::now();
                light = makeLightVector(env, n, r, lightTerms);
                lightImageTimes.push_back(secondsSince(t0));
            }
            light = prepared->lightVector(glm::dmat3(1.0), lightTerms);
        } else {
            Cubemap radiance(n, 3);
            std::mt19937 rng(1);
            std::uniform_real_distribution<float> value(0.0f, 1.0f);
            for (float& x : radiance.data()) x = value(rng);
            light = makeLightVector(radiance, lightTerms);
        }

        // Relight: one warm-up (allocates the output), then timed runs.
        VertexRadiance out;
        relightVertices(file, light, set, out, kernel);
        std::vector<double> times;
        const auto start = Clock::now();
        while (int(times.size()) < iterations || secondsSince(start) < minSeconds) {
            t0 = Clock::now();
            relightVertices(file, light, set, out, kernel);
            times.push_back(secondsSince(t0));
            if (times.size() >= 100000) break;
        }
        // Cold: each run after reading 1 GiB, so the transport data comes from memory
        // even when it would fit in the last-level cache.
        std::vector<double> coldTimes;
        if (coldIterations > 0) {
            std::vector<float> flush(size_t(1) << 28, 1.0f);  // 1 GiB
            for (int i = 0; i < coldIterations; ++i) {
                gSink = gSink + sumAll(flush);
                t0 = Clock::now();
                relightVertices(file, light, set, out, kernel);
                coldTimes.push_back(secondsSince(t0));
            }
        }
        // Light changes: what a frame after the light moves needs, a new light vector (the
        // environment turned by a fresh, not whole-pixel angle each time, as in the viewer's
        // spin) and the relight kernel, back to back; from the prepared environment and,
        // alternately, from the image each time.
        std::vector<double> changeTimes, changeLightTimes, changeImageTimes, changeImageLightTimes;
        if (!envPath.empty()) {
            const auto changesStart = Clock::now();
            for (int i = 0; i < iterations || secondsSince(changesStart) < 2 * minSeconds; ++i) {
                const glm::dmat3 r = rotationY(0.37 + 1.01 * i);
                const bool fromImage = i % 2 == 1;
                t0 = Clock::now();
                const LightVector turned = fromImage ? makeLightVector(env, n, r, lightTerms)
                                                     : prepared->lightVector(r, lightTerms);
                (fromImage ? changeImageLightTimes : changeLightTimes).push_back(secondsSince(t0));
                relightVertices(file, turned, set, out, kernel);
                (fromImage ? changeImageTimes : changeTimes).push_back(secondsSince(t0));
                if (changeTimes.size() >= 100000) break;
            }
        }
        const double coldMedian = median(coldTimes);
        const double med = median(times);
        const double best = *std::min_element(times.begin(), times.end());
        double mean = 0;
        for (double t : times) mean += t;
        mean /= double(times.size());
        const size_t stream = relightStreamBytes(file, set);
        const int effectiveThreads =
            int(tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism));

        std::printf("file          %s: %zu vertices, %zu components (%d view terms), N = %d, %.1f MB\n",
                    path.c_str(), vertices, file.components.size(), terms, n, fileBytes / 1e6);
        if (blockedComponents > 0)
            std::printf("blocked       %d component(s) in blocks of %u vertices sharing their indices (%zu "
                        "indices, %.1f per vertex and component)\n",
                        blockedComponents, kVertexBlock, blockIndices,
                        vertices ? double(blockedCoefficients) / double(vertices) / blockedComponents : 0.0);
        std::printf("load          %.1f ms (%.0f MB/s; as cached: a file just written is in the page cache)\n",
                    1e3 * loadSeconds, fileBytes / 1e6 / loadSeconds);
        if (!lightTimes.empty()) {
            std::printf("environment   prepared in %.1f ms (row running sums, and the lat-long filter unless "
                        "cached; once per environment)\n",
                        1e3 * prepareSeconds);
            std::printf("light vector  %.3f ms median of %zu (%s -> 6x%dx%d -> Haar, %zu terms kept; from the "
                        "image each time: %.3f ms)\n",
                        1e3 * median(lightTimes), lightTimes.size(), envPath.c_str(), n, n, light.keptTerms,
                        1e3 * median(lightImageTimes));
        }
        std::printf("relight       %.3f ms median of %zu (best %.3f, mean %.3f), %s, %d threads\n", 1e3 * med,
                    times.size(), 1e3 * best, 1e3 * mean,
                    set.multipleScattering && set.singleScattering ? "ms,ss"
                    : set.multipleScattering                       ? "ms"
                                                                   : "ss",
                    effectiveThreads);
        std::printf("stream        %.1f MB per relight, %.2f GB/s effective (median), %.1f ns per vertex\n",
                    double(stream) / 1e6, double(stream) / med / 1e9,
                    vertices ? 1e9 * med / double(vertices) : 0.0);
        if (!changeTimes.empty()) {
            std::printf("light change  %.3f ms median of %zu (light vector %.3f + relight; %.0f light changes per second)\n",
                        1e3 * median(changeTimes), changeTimes.size(), 1e3 * median(changeLightTimes),
                        1.0 / median(changeTimes));
            std::printf("  from image  %.3f ms median of %zu (light vector %.3f + relight; %.0f light changes per "
                        "second), interleaved with the above\n",
                        1e3 * median(changeImageTimes), changeImageTimes.size(), 1e3 * median(changeImageLightTimes),
                        1.0 / median(changeImageTimes));
        }
        if (!coldTimes.empty())
            std::printf("relight cold  %.3f ms median of %zu runs each after reading 1 GiB (%.2f GB/s effective)\n",
                        1e3 * coldMedian, coldTimes.size(), double(stream) / coldMedian / 1e9);

        if (!jsonPath.empty()) {
            nlohmann::ordered_json j;
            j["tool"] = "prt-bench-relight-file";
            j["file"] = path;
            j["environment"] = envPath.empty() ? nlohmann::ordered_json(nullptr) : nlohmann::ordered_json(envPath);
            j["vertices"] = vertices;
            j["cubemap_size"] = n;
            j["components"] = file.components.size();
            j["view_terms"] = terms;
            j["coefficients"] = coefficients;
            j["blocked_components"] = blockedComponents;
            j["block_indices"] = blockIndices;
            j["file_bytes"] = fileBytes;
            j["load_ms"] = 1e3 * loadSeconds;
            j["load_MBps"] = fileBytes / 1e6 / loadSeconds;
            j["light_ms_median"] =
                lightTimes.empty() ? nlohmann::ordered_json(nullptr) : nlohmann::ordered_json(1e3 * median(lightTimes));
            j["light_ms_median_from_image"] = lightImageTimes.empty()
                                                  ? nlohmann::ordered_json(nullptr)
                                                  : nlohmann::ordered_json(1e3 * median(lightImageTimes));
            j["environment_prepare_ms"] =
                envPath.empty() ? nlohmann::ordered_json(nullptr) : nlohmann::ordered_json(1e3 * prepareSeconds);
            j["light_terms"] = light.keptTerms;
            j["relight_ms_median"] = 1e3 * med;
            j["relight_ms_best"] = 1e3 * best;
            j["relight_ms_mean"] = 1e3 * mean;
            j["relight_runs"] = times.size();
            j["relight_cold_ms_median"] = coldTimes.empty() ? nlohmann::ordered_json(nullptr)
                                                            : nlohmann::ordered_json(1e3 * coldMedian);
            j["relight_cold_runs"] = coldTimes.size();
            j["light_change_ms_median"] = changeTimes.empty() ? nlohmann::ordered_json(nullptr)
                                                              : nlohmann::ordered_json(1e3 * median(changeTimes));
            j["light_change_light_ms_median"] = changeTimes.empty()
                                                    ? nlohmann::ordered_json(nullptr)
                                                    : nlohmann::ordered_json(1e3 * median(changeLightTimes));
            j["light_changes_per_second"] = changeTimes.empty() ? nlohmann::ordered_json(nullptr)
                                                                : nlohmann::ordered_json(1.0 / median(changeTimes));
            j["light_change_ms_median_from_image"] = changeImageTimes.empty()
                                                         ? nlohmann::ordered_json(nullptr)
                                                         : nlohmann::ordered_json(1e3 * median(changeImageTimes));
            j["light_changes_per_second_from_image"] = changeImageTimes.empty()
                                                           ? nlohmann::ordered_json(nullptr)
                                                           : nlohmann::ordered_json(1.0 / median(changeImageTimes));
            j["stream_bytes"] = stream;
            j["relight_GBps_effective"] = double(stream) / med / 1e9;
            j["threads"] = effectiveThreads;
            writeFileAtomically(jsonPath, j.dump(2) + "\n");
        }
        return 0;
    });
}
