// bench_precompute: the cost of two precomputation stages at production sizes, timed
// by Google Benchmark rather than printed by a test (docs/performance.md):
//   PoissonDiskSamples / UniformRandomSamples   300,000 samples (the default sample cap)
//       on an 81,920-triangle sphere; counters: samples/s and the achieved minimum
//       spacing as a fraction of the hexagonal-packing spacing 2 r_max;
//   HierarchyBuild / HierarchyTransport   pass 2's kd-tree over 100,000 samples x 128
//       coefficients of a 6 x 32 x 32 cubemap, and the traversal for 20,000 vertices at
//       the default epsilon (point rule, as the hierarchy's own tests); counters: nodes
//       visited / used and samples used per vertex, CPU microseconds per vertex.
//   SiteBlend   single scattering's blend of sites (single_scattering_sites.h) into
//       the vertices of a 40,962-vertex sphere of radius 5 mm at Marble's default spacing
//       (about the bunny's vertices per site), from synthetic 512-entry site vectors;
//       counter: CPU microseconds per vertex.
// The clouds are synthetic but spatially coherent (each coefficient a smooth lobe of
// the sample's normal), so node sums truncate as real irradiance transport does.

#include <benchmark/benchmark.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <ctime>
#include <random>
#include <vector>

#include "common/haar.h"
#include "common/materials.h"
#include "common/sampling.h"
#include "common/shapes.h"
#include "common/raytrace.h"
#include "precompute/passes/multiple_scattering.h"
#include "precompute/passes/single_scattering.h"

using namespace prt;

namespace {

constexpr size_t kTexels = 6 * 32 * 32;
constexpr size_t kCloudSamples = 100000;
constexpr size_t kCoefficients = 128;
constexpr size_t kVertices = 20000;
constexpr float kRadiusMm = 30.0f;

struct Rng {
    std::mt19937_64 engine;
    explicit Rng(uint64_t seed) : engine(seed) {}
    double uniform() { return double(engine() >> 11) * 0x1.0p-53; }
    glm::vec3 direction() {
        for (;;) {
            const glm::dvec3 v(2.0 * uniform() - 1.0, 2.0 * uniform() - 1.0, 2.0 * uniform() - 1.0);
            const double l = glm::length(v);
            if (l > 1e-3 && l <= 1.0) return glm::vec3(v / l);
        }
    }
};

// Coefficient index[j] of a sample with normal n is amp[j] max(0, n . dir[j])^2; the
// `keep` largest entries are kept.
struct Lobes {
    std::vector<uint32_t> index;
    std::vector<glm::vec3> dir;
    std::vector<float> amp;
    Lobes(Rng& rng, size_t count) {
        for (size_t j = 0; j < count; ++j) {
            index.push_back(j == 0 ? 0u : uint32_t(1 + rng.uniform() * double(kTexels - 1)));
            dir.push_back(rng.direction());
            amp.push_back(j == 0 ? 2.0f : float((2.0 * rng.uniform() - 1.0) / (1.0 + 0.05 * double(j))));
        }
    }
    SparseVector vectorFor(const glm::vec3& n, size_t keep) const {
        std::vector<float> dense(kTexels, 0.0f);
        for (size_t j = 0; j < index.size(); ++j) {
            const float c = std::max(0.0f, glm::dot(n, dir[j]));
            dense[index[j]] += amp[j] * (j == 0 ? 1.0f : c * c);
        }
        return truncateLargest(dense.data(), kTexels, 1, keep);
    }
};

// kCloudSamples samples uniformly on the sphere, A_i = 4 pi R^2 / n.
const SampleCloud& cloud() {
    static const SampleCloud c = [] {
        Rng rng(91);
        const Lobes lobes(rng, 400);
        SampleCloud out;
        const float area = float(4.0 * 3.14159265358979323846 * kRadiusMm * kRadiusMm / double(kCloudSamples));
        std::vector<glm::vec3> normals;
        for (size_t i = 0; i < kCloudSamples; ++i) {
            normals.push_back(rng.direction());
            out.positions.push_back(kRadiusMm * normals.back());
            out.areas.push_back(area);
        }
        out.irradianceTransport.resize(kCloudSamples);
        tbb::parallel_for(size_t(0), kCloudSamples,
                          [&](size_t i) { out.irradianceTransport[i] = lobes.vectorFor(normals[i], kCoefficients); });
        return out;
    }();
    return c;
}

std::vector<glm::vec3> sphereVertices(size_t n) {
    Rng rng(93);
    std::vector<glm::vec3> v;
    for (size_t i = 0; i < n; ++i) v.push_back(kRadiusMm * rng.direction());
    return v;
}

const TriangleMesh& bigSphere() {
    static const TriangleMesh m = makeIcosphere(6, 50.0f);  // 81,920 triangles
    return m;
}

void PoissonDiskSamples(benchmark::State& state) {
    const size_t n = size_t(state.range(0));
    SampleSet s;
    for (auto _ : state) {
        s = poissonDiskSamples(bigSphere(), n, 1);
        benchmark::DoNotOptimize(s.samples.data());
    }
    state.counters["samples/s"] = benchmark::Counter(double(n), benchmark::Counter::kIsIterationInvariantRate);
    state.counters["min_spacing/2r_max"] = s.minSpacing / (2.0 * hexagonalPackingRadius(s.totalArea, n));
    state.counters["triangles"] = double(bigSphere().triangles.size());
}
BENCHMARK(PoissonDiskSamples)->Arg(300000)->Unit(benchmark::kMillisecond)->UseRealTime();

void UniformRandomSamples(benchmark::State& state) {
    const size_t n = size_t(state.range(0));
    for (auto _ : state) {
        const SampleSet s = uniformRandomSamples(bigSphere(), n, 1);
        benchmark::DoNotOptimize(s.samples.data());
    }
    state.counters["samples/s"] = benchmark::Counter(double(n), benchmark::Counter::kIsIterationInvariantRate);
}
BENCHMARK(UniformRandomSamples)->Arg(300000)->Unit(benchmark::kMillisecond)->UseRealTime();

void HierarchyBuild(benchmark::State& state) {
    const HierarchyOptions o;
    size_t nodes = 0, bytes = 0;
    for (auto _ : state) {
        state.PauseTiming();
        SampleCloud copy = cloud();
        state.ResumeTiming();
        const SampleTree tree(std::move(copy), o);
        nodes = tree.nodes().size();
        bytes = tree.bytes();
    }
    state.counters["nodes"] = double(nodes);
    state.counters["tree_MB"] = double(bytes) / 1e6;
}
BENCHMARK(HierarchyBuild)->Unit(benchmark::kMillisecond)->UseRealTime();

void HierarchyTransport(benchmark::State& state) {
    const HierarchyOptions o;
    const SampleTree tree(SampleCloud(cloud()), o);
    const std::vector<glm::vec3> vertices = sphereVertices(kVertices);
    const Material m = materialByName("Marble");
    MultipleScatteringStats stats;
    double cpuSeconds = 0.0;
    for (auto _ : state) {
        const std::clock_t c0 = std::clock();
        const std::vector<SparseVector> r = multipleScatteringTransport(tree, vertices, m, o, kTexels, &stats);
        cpuSeconds += double(std::clock() - c0) / CLOCKS_PER_SEC;
        benchmark::DoNotOptimize(r.data());
    }
    state.counters["epsilon"] = o.epsilon;
    state.counters["nodes_visited"] = stats.meanNodesVisited;
    state.counters["nodes_used"] = stats.meanNodesUsed;
    state.counters["samples_used"] = stats.meanSamplesUsed;
    state.counters["retained_energy"] = stats.retainedEnergyFraction;
    state.counters["cpu_us/vertex"] = 1e6 * cpuSeconds / double(state.iterations()) / double(kVertices);
}
BENCHMARK(HierarchyTransport)->Unit(benchmark::kMillisecond)->UseRealTime();

void SiteBlend(benchmark::State& state) {
    const TriangleMesh sphere = makeIcosphere(6, 5.0f);
    const RayScene scene(sphere);
    SingleScatteringOptions o;
    o.siteSpacing = 0.29;
    const SingleScatteringContext ctx(scene, sphere, materialByName("Marble"), nullptr, o);
    const SingleScatteringSites sites = chooseSingleScatteringSites(sphere.positions, sphere.normals, o.siteSpacing);
    // Each site 512 entries of the 6 N^2 Haar coefficients, decaying with the index as
    // real transport does (coarse levels first).
    Rng rng(7);
    std::vector<std::vector<SparseVector>> vectors(sites.site.size());
    std::vector<uint32_t> held(sites.site.size());
    const size_t texels = ctx.texelCount(), keep = 512;
    for (size_t i = 0; i < vectors.size(); ++i) {
        held[i] = uint32_t(i);
        SparseVector v;
        v.channels = 3;
        std::vector<uint32_t> all(texels);
        for (uint32_t t = 0; t < texels; ++t) all[t] = t;
        std::shuffle(all.begin(), all.end(), rng.engine);
        all.resize(keep);
        std::sort(all.begin(), all.end());
        for (uint32_t t : all) {
            v.index.push_back(t);
            for (int c = 0; c < 3; ++c) v.value.push_back(float(rng.uniform() - 0.5) / (1.0f + float(t % 1024)));
        }
        vectors[i] = {std::move(v)};
    }
    const VertexRanges ranges = {{0, sphere.positions.size()}};
    double cpuSeconds = 0.0;
    for (auto _ : state) {
        size_t entries = 0;
        const std::clock_t c0 = std::clock();
        blendSiteTransport(ctx, sites, held, vectors,
                           [&](size_t, const std::vector<SparseVector>& t) { entries += t[0].size(); }, nullptr, ranges);
        cpuSeconds += double(std::clock() - c0) / CLOCKS_PER_SEC;
        benchmark::DoNotOptimize(entries);
    }
    state.counters["sites"] = double(sites.site.size());
    state.counters["sites/vertex"] = double(sites.blendSite.size()) / double(sphere.positions.size());
    state.counters["cpu_us/vertex"] = 1e6 * cpuSeconds / double(state.iterations()) / double(sphere.positions.size());
}
BENCHMARK(SiteBlend)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
