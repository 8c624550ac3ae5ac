#include "precompute/passes/irradiance_transport.h"

#include <tbb/blocked_range.h>
#include <tbb/combinable.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstddef>
#include <limits>
#include <string>

#include "common/bssrdf.h"
#include "common/cubemap.h"
#include "common/error.h"
#include "common/sh_part.h"
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

VisibilitySampling parseVisibilitySampling(const std::string& text) {
    if (text == "every") return VisibilitySampling::Every;
    if (text == "coherent") return VisibilitySampling::Coherent;
    throw Error("--pass1-visibility", "expected every or coherent, got '" + text + "'");
}

const char* toString(VisibilitySampling mode) {
    return mode == VisibilitySampling::Every ? "every" : "coherent";
}

namespace {

// VisibilitySampling::Coherent for the m gathered rays of one sample (texel order, as
// irradianceTransport gathers them): probes, then the texels that need all their rays.
// Returns the rays traced; fills sc.occluded[0, m).
uint64_t traceCoherent(const RayScene& scene, const glm::vec3& org, const TexelDirections& dirs,
                       size_t m, IrradianceTransportScratch& sc) {
    const int n = dirs.size;
    const size_t texels = size_t(kCubeFaces) * size_t(n) * size_t(n);
    const uint32_t sub = uint32_t(dirs.subPerTexel());
    sc.firstRay.assign(texels, 0);
    sc.rayCount.assign(texels, 0);
    for (size_t r = m; r-- > 0;) {
        sc.firstRay[sc.texel[r]] = uint32_t(r);
        ++sc.rayCount[sc.texel[r]];
    }
    const auto trace = [&](size_t count) {
        sc.batchX.resize(count);
        sc.batchY.resize(count);
        sc.batchZ.resize(count);
        sc.batchOccluded.resize(count);
        for (size_t b = 0; b < count; ++b) {
            sc.batchX[b] = sc.dirX[sc.batch[b]];
            sc.batchY[b] = sc.dirY[sc.batch[b]];
            sc.batchZ[b] = sc.dirZ[sc.batch[b]];
        }
        scene.occludedFromPoint(org, sc.batchX.data(), sc.batchY.data(), sc.batchZ.data(), count, 0.0f,
                                std::numeric_limits<float>::infinity(), sc.batchOccluded.data());
        for (size_t b = 0; b < count; ++b) sc.occluded[sc.batch[b]] = sc.batchOccluded[b];
    };

    // Texels in 4 x 4 tiles per face, so a 16-ray packet of probes spans a compact cone
    // (rows of 16 texels made packets 4x wider than Every's, and Embree slower per ray).
    thread_local std::vector<uint32_t> tileOrder;
    if (tileOrder.size() != texels) {
        tileOrder.clear();
        const int tile = std::min(n, 4);
        for (int f = 0; f < kCubeFaces; ++f)
            for (int tj = 0; tj < n; tj += tile)
                for (int ti = 0; ti < n; ti += tile)
                    for (int j = tj; j < tj + tile; ++j)
                        for (int i = ti; i < ti + tile; ++i)
                            tileOrder.push_back(uint32_t((f * n + j) * n + i));
    }

    // Probes: the first ray of every texel that has one.
    sc.batch.clear();
    for (const uint32_t t : tileOrder)
        if (sc.rayCount[t] > 0) sc.batch.push_back(sc.firstRay[t]);
    const size_t probes = sc.batch.size();
    trace(probes);
    sc.probe.assign(texels, 0);
    for (size_t t = 0; t < texels; ++t)
        if (sc.rayCount[t] > 0) sc.probe[t] = sc.occluded[sc.firstRay[t]] ? 2 : 1;

    // A texel is coherent when it is whole above the horizon and its 8 neighbours on the
    // face exist (no face border) and carry the same probe value.
    sc.batch.clear();
    for (const uint32_t t : tileOrder) {
        if (sc.rayCount[t] == 0) continue;
        const int i = int(t % uint32_t(n)), j = int(t / uint32_t(n) % uint32_t(n));
        bool coherent = sc.rayCount[t] == sub && i > 0 && j > 0 && i + 1 < n && j + 1 < n;
        for (int dj = -1; coherent && dj <= 1; ++dj)
            for (int di = -1; coherent && di <= 1; ++di)
                coherent = sc.probe[size_t(std::ptrdiff_t(t) + std::ptrdiff_t(dj) * n + di)] == sc.probe[t];
        const uint32_t first = sc.firstRay[t], end = first + sc.rayCount[t];
        for (uint32_t r = first + 1; r < end; ++r) {
            if (coherent) sc.occluded[r] = sc.occluded[first];
            else sc.batch.push_back(r);
        }
    }
    const size_t refined = sc.batch.size();
    trace(refined);
    return probes + refined;
}

}  // namespace

uint64_t irradianceTransport(const RayScene* scene, const SurfaceSample& sample,
                             const TexelDirections& dirs, double eta, float* out,
                             IrradianceTransportScratch& sc, VisibilitySampling sampling) {
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

    uint64_t traced = 0;
    if (scene && m > 0) {
        // All rays share one origin: offset it off the surface to the front side of
        // the triangle (the side the shading normal faces).
        const glm::vec3 org = scene->offsetRayOrigin(sample.position, sample.geometricNormal, n);
        if (sampling == VisibilitySampling::Coherent && sub > 1) {
            traced = traceCoherent(*scene, org, dirs, m, sc);
        } else {
            scene->occludedFromPoint(org, sc.dirX.data(), sc.dirY.data(), sc.dirZ.data(), m, 0.0f,
                                     std::numeric_limits<float>::infinity(), sc.occluded.data());
            traced = m;
        }
    } else {
        std::fill_n(sc.occluded.begin(), m, uint8_t(0));
    }

    std::fill_n(out, texels, 0.0f);
    for (size_t r = 0; r < m; ++r)
        if (!sc.occluded[r]) out[sc.texel[r]] += sc.weight[r];
    return traced;
}

IrradianceTransportResult computeIrradianceTransport(const RayScene* scene, const SampleSet& samples,
                                                     const IrradianceTransportOptions& options,
                                                     Progress* progress) {
    if (!scene && options.visibility)
        throw Error("pass 1", "visibility requested without a ray scene");
    if (options.sampleCoefficients == 0)
        throw Error("--sample-coefficients", "must be at least 1");
    const TexelDirections dirs = makeTexelDirections(options.cubemapSize, options.supersample);
    const int n = options.cubemapSize;
    const size_t texels = size_t(kCubeFaces) * n * n;
    const size_t count = samples.samples.size();

    IrradianceTransportResult result;
    result.vectors.resize(count);
    std::vector<double> retained(count, 1.0);
    struct ThreadState {
        IrradianceTransportScratch scratch;
        uint64_t rays = 0;
    };
    tbb::combinable<ThreadState> states;
    const RayScene* visScene = options.visibility ? scene : nullptr;

    const Stopwatch start;
    tbb::parallel_for(tbb::blocked_range<size_t>(0, count, 16), [&](const tbb::blocked_range<size_t>& r) {
        ThreadState& st = states.local();
        // Room for the SH entries, which truncateWithShPart leaves zero.
        st.scratch.dense.resize(texels + size_t(options.shTerms));
        float* dense = st.scratch.dense.data();
        for (size_t i = r.begin(); i != r.end(); ++i) {
            st.rays += irradianceTransport(visScene, samples.samples[i], dirs, options.eta, dense,
                                           st.scratch, options.sampling);
            for (int f = 0; f < kCubeFaces; ++f) haarForwardFace(dense + size_t(f) * n * n, n);
            result.vectors[i] = truncateWithShPart(dense, texels, 1, options.shTerms, options.sampleCoefficients,
                                                   &retained[i]);
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
