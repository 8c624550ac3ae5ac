#include "precompute/irradiance_transport.h"

#include <tbb/blocked_range.h>
#include <tbb/combinable.h>
#include <tbb/parallel_for.h>

#include <chrono>
#include <cmath>

#include "common/bssrdf.h"
#include "common/cubemap.h"
#include "common/error.h"
#include "common/progress.h"
#include "common/util.h"

namespace prt {

TexelDirections makeTexelDirections(int n, int s) {
    if (!isPowerOfTwo(n)) throw Error("--cubemap-size", "must be a power of two, got " + std::to_string(n));
    if (s < 1 || s > 16) throw Error("--supersample", "must be in [1, 16], got " + std::to_string(s));
    TexelDirections d;
    d.size = n;
    d.supersample = s;
    const size_t total = size_t(kCubeFaces) * n * n * s * s;
    d.x.reserve(total);
    d.y.reserve(total);
    d.z.reserve(total);
    d.solidAngle.reserve(total);
    const double h = 1.0 / (double(n) * s);  // sub-texel size in face coordinates
    for (int f = 0; f < kCubeFaces; ++f)
        for (int j = 0; j < n; ++j)
            for (int i = 0; i < n; ++i)
                for (int b = 0; b < s; ++b)
                    for (int a = 0; a < s; ++a) {
                        const double s0 = (double(i) * s + a) * h, t0 = (double(j) * s + b) * h;
                        const glm::dvec3 w = faceUVToDirection(f, s0 + 0.5 * h, t0 + 0.5 * h);
                        d.x.push_back(float(w.x));
                        d.y.push_back(float(w.y));
                        d.z.push_back(float(w.z));
                        d.solidAngle.push_back(float(faceRegionSolidAngle(s0, t0, s0 + h, t0 + h)));
                    }
    return d;
}

uint64_t irradianceTransport(const RayScene* scene, const SurfaceSample& sample,
                             const TexelDirections& dirs, double eta, float* out,
                             IrradianceScratch& sc) {
    const size_t texels = size_t(kCubeFaces) * dirs.size * dirs.size;
    const size_t sub = dirs.subPerTexel();
    const glm::vec3 n = sample.normal;
    sc.dirX.resize(dirs.count());
    sc.dirY.resize(dirs.count());
    sc.dirZ.resize(dirs.count());
    sc.weight.resize(dirs.count());
    sc.texel.resize(dirs.count());
    sc.occluded.resize(dirs.count());

    // Gather the sub-directions above the shading horizon; the rest contribute 0.
    size_t m = 0;
    for (size_t k = 0; k < dirs.count(); ++k) {
        const float cosTheta = n.x * dirs.x[k] + n.y * dirs.y[k] + n.z * dirs.z[k];
        if (cosTheta <= 0.0f) continue;
        sc.dirX[m] = dirs.x[k];
        sc.dirY[m] = dirs.y[k];
        sc.dirZ[m] = dirs.z[k];
        sc.weight[m] = float(fresnelTransmittance(eta, cosTheta)) * cosTheta * dirs.solidAngle[k];
        sc.texel[m] = uint32_t(k / sub);
        ++m;
    }

    if (scene && m > 0) {
        // All rays share one origin: offset it off the surface to the front side of
        // the triangle (the side the shading normal faces).
        const glm::vec3 org = scene->offsetRayOrigin(sample.position, sample.geometricNormal, n);
        scene->occludedFromPoint(org, sc.dirX.data(), sc.dirY.data(), sc.dirZ.data(), m, 0.0f,
                                 std::numeric_limits<float>::infinity(), sc.occluded.data());
    } else {
        std::fill_n(sc.occluded.begin(), m, uint8_t(0));
    }

    std::fill_n(out, texels, 0.0f);
    for (size_t r = 0; r < m; ++r)
        if (!sc.occluded[r]) out[sc.texel[r]] += sc.weight[r];
    return scene ? m : 0;
}

IrradianceResult computeIrradianceTransport(const RayScene* scene, const SampleSet& samples,
                                            const IrradianceOptions& options,
                                            Progress* progress) {
    if (!scene && options.visibility)
        throw Error("pass 1", "visibility requested without a ray scene");
    if (options.keepCoefficients == 0)
        throw Error("--sample-coefficients", "must be at least 1");
    const TexelDirections dirs = makeTexelDirections(options.cubemapSize, options.supersample);
    const int n = options.cubemapSize;
    const size_t texels = size_t(kCubeFaces) * n * n;
    const size_t count = samples.samples.size();

    IrradianceResult result;
    result.vectors.resize(count);
    std::vector<double> retained(count, 1.0);
    struct ThreadState {
        IrradianceScratch scratch;
        uint64_t rays = 0;
    };
    tbb::combinable<ThreadState> states;
    const RayScene* visScene = options.visibility ? scene : nullptr;

    const Stopwatch start;
    tbb::parallel_for(tbb::blocked_range<size_t>(0, count, 16), [&](const tbb::blocked_range<size_t>& r) {
        ThreadState& st = states.local();
        st.scratch.dense.resize(texels);
        float* dense = st.scratch.dense.data();
        for (size_t i = r.begin(); i != r.end(); ++i) {
            st.rays += irradianceTransport(visScene, samples.samples[i], dirs, options.eta, dense,
                                           st.scratch);
            for (int f = 0; f < kCubeFaces; ++f) haarForwardFace(dense + size_t(f) * n * n, n);
            const double total = energy(dense, texels);
            result.vectors[i] = truncateLargest(dense, texels, 1, options.keepCoefficients);
            if (total > 0) retained[i] = energy(result.vectors[i]) / total;
        }
        if (progress) progress->advance(r.size());
    });
    result.seconds =
        start.seconds();
    states.combine_each([&](const ThreadState& st) { result.raysTraced += st.rays; });
    double sum = 0;
    for (double v : retained) sum += v;
    result.retainedEnergyFraction = count ? sum / double(count) : 1.0;
    return result;
}

}  // namespace prt
