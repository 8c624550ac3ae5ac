// prt-bench-pass1: pass-1 occlusion throughput against raw Embree on the same rays,
// measured in one run (SPEC section 8): ratio = achieved rays/s inside
// computeIrradianceTransport / rays/s of the bare occlusion queries.

#include <CLI/CLI.hpp>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <vector>
#include <cstdio>

#include "common/bssrdf.h"
#include "common/error.h"
#include "precompute/passes/irradiance_transport.h"
#include "common/mesh.h"
#include "common/progress.h"
#include "common/raytrace.h"
#include "common/sampling.h"
#include "common/mesh_io.h"
#include "common/options.h"

using namespace prt;

namespace {

double now() {
    return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

// The rays pass 1 traces for one sample: its offset origin and the sub-directions
// above its shading horizon (the same gather as irradianceTransport).
struct SampleRays {
    glm::vec3 origin;
    std::vector<float> x, y, z;
};

SampleRays gatherRays(const RayScene& scene, const SurfaceSample& s, const TexelDirections& dirs) {
    SampleRays r;
    r.origin = scene.offsetRayOrigin(s.position, s.geometricNormal, s.normal);
    for (size_t k = 0; k < dirs.count(); ++k) {
        if (s.normal.x * dirs.x[k] + s.normal.y * dirs.y[k] + s.normal.z * dirs.z[k] <= 0.0f) continue;
        r.x.push_back(dirs.x[k]);
        r.y.push_back(dirs.y[k]);
        r.z.push_back(dirs.z[k]);
    }
    return r;
}

// Rays/s of one kernel over all rays, in blocks of pre-gathered samples.
double rawRate(const RayScene& scene, const SampleSet& samples, const TexelDirections& dirs,
               OcclusionKernel kernel, uint64_t& rays) {
    const size_t block = 128;
    double seconds = 0;
    rays = 0;
    for (size_t b = 0; b < samples.samples.size(); b += block) {
        const size_t e = std::min(samples.samples.size(), b + block);
        std::vector<SampleRays> gathered(e - b);
        tbb::parallel_for(b, e, [&](size_t i) { gathered[i - b] = gatherRays(scene, samples.samples[i], dirs); });
        const double t0 = now();
        tbb::parallel_for(size_t(0), gathered.size(), [&](size_t i) {
            const SampleRays& r = gathered[i];
            std::vector<uint8_t> out(r.x.size());
            scene.occludedFromPointWith(kernel, true, r.origin, r.x.data(), r.y.data(), r.z.data(),
                                        r.x.size(), 0.0f, std::numeric_limits<float>::infinity(), out.data());
        });
        seconds += now() - t0;
        for (const SampleRays& r : gathered) rays += r.x.size();
    }
    return rays / seconds;
}

}  // namespace

int main(int argc, char** argv) {
    return runMain("prt-bench-pass1", [&]() -> int {
        CLI::App app{"prt-bench-pass1: pass-1 occlusion rays/s against raw Embree on the same rays"};
        std::string meshPath;
        double sizeMm = 30;
        std::string material = "Marble";
        size_t count = 2000;
        int cubemapSize = 32, supersample = 2;
        app.add_option("mesh", meshPath, "Mesh file")->required();
        app.add_option("--size-mm", sizeMm, "Bounding-box diagonal in mm")->capture_default_str();
        app.add_option("-m,--material", material, "Material (sets the sample spacing)")->capture_default_str();
        app.add_option("--samples", count, "Samples to trace (a Poisson subset of the mesh)")->capture_default_str();
        app.add_option("--cubemap-size", cubemapSize, "Cubemap face size")->capture_default_str();
        app.add_option("--supersample", supersample, "Sub-directions per texel side")->capture_default_str();
        if (const auto exitCode = parseCommandLine(app, argc, argv, "prt-bench-pass1")) return *exitCode;
        Progress::setEnabled(false);
        TriangleMesh mesh = loadMesh(meshPath);
        scaleToPhysical(mesh, MeshScale{.sizeMm = sizeMm, .mmPerUnit = std::nullopt});
        RayScene scene(mesh);
        SampleSet samples = poissonDiskSamples(mesh, count, 1);
        const TexelDirections dirs = makeTexelDirections(cubemapSize, supersample);

        IrradianceTransportOptions options;
        options.cubemapSize = cubemapSize;
        options.supersample = supersample;
        options.eta = materialByName(material).eta;
        // Warm-up, then the measured pass 1 (everything: rays, Fresnel, Haar, truncation),
        // once tracing every sub-direction and once with coherent visibility.
        const auto runPass1 = [&](VisibilitySampling sampling) {
            options.sampling = sampling;
            computeIrradianceTransport(&scene, SampleSet{{samples.samples.begin(), samples.samples.begin() + std::min<size_t>(64, count)}, 0, 0, 0}, options);
            return computeIrradianceTransport(&scene, samples, options);
        };
        const IrradianceTransportResult pass1 = runPass1(VisibilitySampling::Every);
        const IrradianceTransportResult coherent = runPass1(VisibilitySampling::Coherent);
        const double achieved = pass1.raysTraced / pass1.seconds;
        // What coherent visibility delivers, counted as the rays it stands for (every
        // sub-direction above the horizon) per second.
        const double effective = pass1.raysTraced / coherent.seconds;
        double change2 = 0.0, total2 = 0.0, worst = 0.0;
        {
            const size_t texels = size_t(6) * cubemapSize * cubemapSize;
            std::vector<float> a(texels), b(texels);
            for (size_t i = 0; i < count; ++i) {
                std::fill(a.begin(), a.end(), 0.0f);
                std::fill(b.begin(), b.end(), 0.0f);
                addTo(pass1.vectors[i], 1.0f, a.data());
                addTo(coherent.vectors[i], 1.0f, b.data());
                double d2 = 0.0, n2 = 0.0;
                for (size_t t = 0; t < texels; ++t) {
                    d2 += double(a[t] - b[t]) * (a[t] - b[t]);
                    n2 += double(a[t]) * a[t];
                }
                change2 += d2;
                total2 += n2;
                if (n2 > 0) worst = std::max(worst, std::sqrt(d2 / n2));
            }
        }

        uint64_t rays16 = 0, rays1 = 0;
        const double packet = rawRate(scene, samples, dirs, OcclusionKernel::Auto, rays16);
        const double single = rawRate(scene, samples, dirs, OcclusionKernel::Single, rays1);

        std::printf("mesh               %s (%zu triangles, %.0f mm)\n", meshPath.c_str(), mesh.triangleCount(), sizeMm);
        std::printf("samples            %zu, cubemap 6x%dx%d, %dx%d sub-directions\n", count, cubemapSize,
                    cubemapSize, supersample, supersample);
        std::printf("rays               %llu (pass 1, every) / %llu (raw) / %llu (pass 1, coherent: %.1f%%)\n",
                    (unsigned long long)pass1.raysTraced, (unsigned long long)rays16,
                    (unsigned long long)coherent.raysTraced, 100.0 * double(coherent.raysTraced) / double(pass1.raysTraced));
        std::printf("pass 1, every      %.3g rays/s (%.2f s)\n", achieved, pass1.seconds);
        std::printf("pass 1, coherent   %.2f s: %.3g rays/s traced, %.3g effective (every's rays / its time)\n",
                    coherent.seconds, coherent.raysTraced / coherent.seconds, effective);
        std::printf("raw Embree packet  %.3g rays/s (%s, coherent)\n", packet, toString(defaultOcclusionKernel()));
        std::printf("raw Embree single  %.3g rays/s (rtcOccluded1)\n", single);
        std::printf("ratio              %.3f pass 1 / raw packet, %.3f pass 1 / raw single\n", achieved / packet,
                    achieved / single);
        std::printf("ratio, coherent    %.3f effective / raw packet (%.2fx every's time)\n", effective / packet,
                    pass1.seconds / coherent.seconds);
        std::printf("coherent vs every  truncated sample vectors: relative L2 change %.2e over all samples, "
                    "worst sample %.2e\n", std::sqrt(change2 / std::max(total2, 1e-300)), worst);
        return 0;
    });
}
