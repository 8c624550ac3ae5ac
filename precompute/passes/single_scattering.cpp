#include "precompute/passes/single_scattering.h"
#include "precompute/passes/single_scattering_sites.h"

#include <tbb/blocked_range.h>
#include <tbb/combinable.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <utility>

#include "common/error.h"
#include "common/mesh.h"
#include "common/sh_part.h"
#include "precompute/passes/phase_factoring.h"
#include "common/progress.h"
#include "common/util.h"

namespace prt {

// ---------------------------------------------------------------------------------
// Helpers
// ---------------------------------------------------------------------------------

double samplingExtinction(const Material& material) { return luminance(material.sigmaT()); }

const char* toString(PathQuadrature q) {
    return q == PathQuadrature::GaussLegendre ? "gauss" : "midpoint";
}

PathQuadrature parsePathQuadrature(const std::string& text) {
    if (text == "midpoint") return PathQuadrature::Midpoint;
    if (text == "gauss") return PathQuadrature::GaussLegendre;
    throw Error("--path-quadrature", "must be midpoint or gauss, got '" + text + "'");
}

void SingleScatteringStats::add(const SingleScatteringStats& o) {
    depthRays += o.depthRays;
    exitRays += o.exitRays;
    occlusionRays += o.occlusionRays;
    occludedExits += o.occludedExits;
    sharedVisibility += o.sharedVisibility;
    culledRays += o.culledRays;
    tracedTexels += o.tracedTexels;
    interpolatedTexels += o.interpolatedTexels;
    splitsByStake += o.splitsByStake;
    splitsByThroughput += o.splitsByThroughput;
    splitsByExitKind += o.splitsByExitKind;
    sites += o.sites;
    escapedRays += o.escapedRays;
    reversedHits += o.reversedHits;
    outsideSamples += o.outsideSamples;
    flippedNormals += o.flippedNormals;
    cappedDepths += o.cappedDepths;
    depthSum += o.depthSum;
}

// ---------------------------------------------------------------------------------
// Context
// ---------------------------------------------------------------------------------

SingleScatteringContext::SingleScatteringContext(const RayScene& scene, const TriangleMesh& mesh,
                                                 const Material& material,
                                                 const PhaseFactorization* phase,
                                                 const SingleScatteringOptions& options)
    : scene_(&scene), mesh_(&mesh), material_(material), options_(options) {
    validateMaterial(material_);
    if (!isPowerOfTwo(options.cubemapSize) || options.cubemapSize > 64)
        throw Error("--cubemap-size", "must be a power of two between 1 and 64, got " +
                                          std::to_string(options.cubemapSize));
    if (options.supersample < 1 || options.supersample > 8)
        throw Error("--ss-supersample",
                    "must be between 1 and 8, got " + std::to_string(options.supersample));
    if (options.pathSamples < 1 || options.pathSamples > 4096)
        throw Error("--path-samples",
                    "must be between 1 and 4096, got " + std::to_string(options.pathSamples));
    if (options.vertexCoefficients < 1)
        throw Error("--coefficients", "must be at least 1");
    if (!(options.depthCapMeanFreePaths > 0) || !std::isfinite(options.depthCapMeanFreePaths))
        throw Error("single scattering", "the depth cap must be a positive number of mean free paths");
    if (!(options.minThroughput >= 0) || !(options.minThroughput < 1))
        throw Error("single scattering", "the throughput threshold must be in [0, 1)");
    if (!isPowerOfTwo(options.directionStride) || options.directionStride > 16)
        throw Error("--ss-direction-stride", "must be a power of two between 1 and 16, got " +
                                                 std::to_string(options.directionStride));
    if (!(options.refineLargeCellValue >= 0) || !(options.refineValueTolerance >= 0) || !std::isfinite(options.refineValueTolerance) ||
        !(options.refineValueFloor >= 0) || !std::isfinite(options.refineValueFloor))
        throw Error("single scattering", "the refinement tolerances must be finite and non-negative");
    if (mesh.normals.size() != mesh.positions.size())
        throw Error("single scattering", "the mesh has no per-vertex normals");
    if (scene.triangleCount() != mesh.triangles.size())
        throw Error("single scattering", "the ray scene was not built from this mesh");

    {
        std::vector<glm::dvec3> centroidSum(mesh.positions.size(), glm::dvec3(0.0));
        std::vector<uint32_t> triangleCount(mesh.positions.size(), 0);
        for (const glm::uvec3& t : mesh.triangles) {
            const glm::dvec3 c = (glm::dvec3(mesh.positions[t.x]) + glm::dvec3(mesh.positions[t.y]) +
                                  glm::dvec3(mesh.positions[t.z])) / 3.0;
            for (uint32_t v : {t.x, t.y, t.z}) {
                centroidSum[v] += c;
                ++triangleCount[v];
            }
        }
        cornerNormals_.resize(mesh.triangles.size());
        for (size_t t = 0; t < mesh.triangles.size(); ++t) {
            const glm::uvec3 tri = mesh.triangles[t];
            cornerNormals_[t] = {{mesh.normals[tri.x], mesh.normals[tri.y], mesh.normals[tri.z]}};
        }
        constexpr double kTowardRing = 0.01;
        pathOrigins_.resize(mesh.positions.size());
        for (size_t v = 0; v < mesh.positions.size(); ++v) {
            const glm::dvec3 x(mesh.positions[v]);
            pathOrigins_[v] = triangleCount[v]
                                  ? glm::vec3(x + kTowardRing * (centroidSum[v] / double(triangleCount[v]) - x))
                                  : mesh.positions[v];
        }
    }

    if (phase) {
        if (std::abs(phase->g - material.g) > 1e-12)
            throw Error("--g", "the phase factorisation (g = " + std::to_string(phase->g) +
                                   ") does not match the material (g = " +
                                   std::to_string(material.g) + ")");
        if (phase->terms() < 1 || phase->lightMaps.size() != size_t(phase->terms()))
            throw Error("--phase-terms", "the phase factorisation has no terms");
        isotropic_ = false;
        terms_ = phase->terms();
        const int m = phase->lightMaps.front().size();
        lightMaps_ = Cubemap(m, terms_);
        for (int k = 0; k < terms_; ++k) {
            const Cubemap& src = phase->lightMaps[size_t(k)];
            if (src.size() != m || src.channels() != 1)
                throw Error("--phase-terms", "inconsistent light maps");
            for (size_t t = 0; t < src.texelCount(); ++t)
                lightMaps_.data()[t * size_t(terms_) + size_t(k)] = src.data()[t];
        }
    } else if (material.g != 0.0) {
        throw Error("--g", "an anisotropic phase function (g != 0) needs its factorisation");
    }

    dirs_ = makeTexelDirections(options.cubemapSize, options.supersample);
    // The directions with their texel index (no division in the hot loop).
    traced_.x = dirs_.x;
    traced_.y = dirs_.y;
    traced_.z = dirs_.z;
    traced_.solidAngle = dirs_.solidAngle;
    traced_.texel.resize(dirs_.count());
    for (size_t k = 0; k < dirs_.count(); ++k) traced_.texel[k] = uint32_t(k / dirs_.subPerTexel());
    const int n = options.cubemapSize, stride = options.directionStride;
    if (stride > 1 && options.supersample == 1 && n >= 2) {
        // The lattice per face axis: 0, S, 2S, ... and the last texel N - 1.
        std::vector<uint16_t> lattice;
        for (int i = 0; i < n - 1; i += stride) lattice.push_back(uint16_t(i));
        lattice.push_back(uint16_t(n - 1));
        for (int f = 0; f < kCubeFaces; ++f) {
            for (uint16_t j : lattice)
                for (uint16_t i : lattice) firstDirections_.push_back(uint32_t((f * n + j) * n + i));
            for (size_t b = 0; b + 1 < lattice.size(); ++b)
                for (size_t a = 0; a + 1 < lattice.size(); ++a)
                    topCells_.push_back({uint16_t(f), lattice[a], lattice[a + 1], lattice[b], lattice[b + 1]});
        }
    } else {
        firstDirections_.resize(dirs_.count());
        for (size_t k = 0; k < dirs_.count(); ++k) firstDirections_[k] = uint32_t(k);
    }
    // F_t(eta, cos) on a uniform grid of cos in [0, 1] (linear interpolation; the
    // interpolation error is below 1e-6 for eta in [1, 2.5]). For eta < 1 F_t has a
    // square-root kink at the critical angle and is evaluated exactly instead.
    fresnelTable_.resize(kFresnelTableSize + 2);
    for (int k = 0; k <= kFresnelTableSize; ++k)
        fresnelTable_[size_t(k)] = float(fresnelTransmittance(material_.eta, double(k) / kFresnelTableSize));
    fresnelTable_[kFresnelTableSize + 1] = fresnelTable_[kFresnelTableSize];
    sigma_ = samplingExtinction(material_);
    depthCap_ = options.depthCapMeanFreePaths / sigma_;
    pathRule_ = pathQuadratureRule(options.pathQuadrature, options.pathSamples);
}

void SingleScatteringContext::intersectCoherent(const float* ox, const float* oy, const float* oz,
                                                const float* dx, const float* dy, const float* dz,
                                                size_t count, Hit* out) const {
    scene_->intersectBatch(ox, oy, oz, dx, dy, dz, count, 0.0f, std::numeric_limits<float>::infinity(), out,
                           options_.coherentRays);
}

void SingleScatteringContext::occludedCoherent(const float* ox, const float* oy, const float* oz,
                                               const float* dx, const float* dy, const float* dz,
                                               size_t count, uint8_t* out) const {
    scene_->occludedBatch(ox, oy, oz, dx, dy, dz, count, 0.0f, std::numeric_limits<float>::infinity(), out,
                          options_.coherentRays);
}

void SingleScatteringContext::intersectWithBeyond(const float* ox, const float* oy, const float* oz,
                                                  const float* dx, const float* dy, const float* dz,
                                                  size_t count, Hit* hits, uint8_t* beyond) const {
    scene_->intersectBatchWithBeyond(ox, oy, oz, dx, dy, dz, count, 0.0f, scene_->epsilon(), hits, beyond,
                                     options_.coherentRays);
}

float SingleScatteringContext::fresnel(float cosTheta) const {
    if (material_.eta < 1.0) return float(fresnelTransmittance(material_.eta, cosTheta));
    const float x = std::clamp(cosTheta, 0.0f, 1.0f) * float(kFresnelTableSize);
    const int k = int(x);
    const float f = x - float(k);
    return fresnelTable_[size_t(k)] + f * (fresnelTable_[size_t(k) + 1] - fresnelTable_[size_t(k)]);
}

void SingleScatteringContext::lightMapValues(const glm::vec3& a, float* out) const {
    if (isotropic_) {
        out[0] = float(1.0 / (4.0 * kPi));
        return;
    }
    // Cubemap::sampleBilinear for all K channels at once (one face lookup).
    const BilinearTaps taps = bilinearTaps(lightMaps_.size(), glm::dvec3(a));
    const float* p[4];
    float w[4];
    for (int q = 0; q < 4; ++q) {
        p[q] = lightMaps_.data().data() + taps.texel[q] * size_t(terms_);
        w[q] = float(taps.weight[q]);
    }
    for (int k = 0; k < terms_; ++k) out[k] = w[0] * p[0][k] + w[1] * p[1][k] + w[2] * p[2][k] + w[3] * p[3][k];
}

// ---------------------------------------------------------------------------------
// Per-vertex kernel
// ---------------------------------------------------------------------------------

namespace {

// Traces the exit rays of every path sample (sc.samplePoint) toward the directions
// list[0..count) into sc.hits, direction-major: ray q = p * ns + i for list[p], sample i.
void traceExitRays(const SingleScatteringContext& ctx, const uint32_t* list, size_t count,
                   SingleScatteringScratch& sc, SingleScatteringStats& stats) {
    const SingleScatteringContext::Directions& dirs = ctx.tracedDirections();
    const size_t ns = sc.samplePoint.size(), total = ns * count;
    sc.orgX.resize(total);
    sc.orgY.resize(total);
    sc.orgZ.resize(total);
    sc.dirX.resize(total);
    sc.dirY.resize(total);
    sc.dirZ.resize(total);
    sc.hits.resize(total);
    // Direction-major order puts the ns parallel rays of one direction (origins spread
    // along the normal over a few mean free paths) into one packet: 15-20% faster than
    // packets of 16 neighbouring directions from one origin (docs/single-scattering.md).
    for (size_t p = 0, q = 0; p < count; ++p) {
        const uint32_t r = list[p];
        for (size_t i = 0; i < ns; ++i, ++q) {
            sc.orgX[q] = sc.samplePoint[i].x;
            sc.orgY[q] = sc.samplePoint[i].y;
            sc.orgZ[q] = sc.samplePoint[i].z;
            sc.dirX[q] = dirs.x[r];
            sc.dirY[q] = dirs.y[r];
            sc.dirZ[q] = dirs.z[r];
        }
    }
    if (ctx.visibilityFromExitRays()) {
        sc.beyond.resize(total);
        ctx.intersectWithBeyond(sc.orgX.data(), sc.orgY.data(), sc.orgZ.data(), sc.dirX.data(),
                                sc.dirY.data(), sc.dirZ.data(), total, sc.hits.data(), sc.beyond.data());
    } else {
        ctx.intersectCoherent(sc.orgX.data(), sc.orgY.data(), sc.orgZ.data(), sc.dirX.data(),
                              sc.dirY.data(), sc.dirZ.data(), total, sc.hits.data());
    }
    stats.exitRays += total;
}

// The path samples along `inward` from `position`, their exit rays toward the first
// directions (ctx.firstDirections(): all, or the lattice when adaptive) into sc.hits,
// and for each sample point whether it is inside the object. From an inside point of
// a closed, consistently wound mesh every ray first hits a triangle facing along it
// (a back face); from an outside point rays hit front faces or nothing, and back
// faces only through wrongly wound triangles or single-layer sheets. Front faces seen
// from inside come only from wrongly wound patches, which can cover half the sphere
// (a whole face of a box) without the point being outside, so they are not counted: a
// point is inside when more of its rays hit back faces than hit nothing.
// sc.inside[i] = 1 for inside points. Returns the number of inside points.
size_t traceExits(const SingleScatteringContext& ctx, const glm::vec3& position,
                  const glm::vec3& inward, double dm, SingleScatteringScratch& sc,
                  SingleScatteringStats& stats) {
    const Material& mat = ctx.material();
    const SingleScatteringContext::Directions& dirs = ctx.tracedDirections();
    const glm::vec3 sigmaT(mat.sigmaT());
    const glm::dvec3 sigmaS = mat.sigmaS();
    makePathSamples(ctx.samplingSigma(), dm, ctx.pathRule(), ctx.options().pathQuadrature, sc.samples);
    const std::vector<PathSample>& samples = sc.samples;
    const size_t ns = samples.size();

    // Per-sample origin x_p and estimator weight sigma_s e^(-sigma_t s) w_i / pdf(s).
    sc.samplePoint.resize(ns);
    sc.sampleWeight.resize(ns);
    for (size_t i = 0; i < ns; ++i) {
        const double d = samples[i].distance, wgt = samples[i].weight;
        sc.samplePoint[i] = position + float(d) * inward;
        sc.sampleWeight[i] = glm::vec3(float(sigmaS.x * std::exp(-double(sigmaT.x) * d) * wgt),
                                       float(sigmaS.y * std::exp(-double(sigmaT.y) * d) * wgt),
                                       float(sigmaS.z * std::exp(-double(sigmaT.z) * d) * wgt));
    }
    const std::vector<uint32_t>& list = ctx.firstDirections();
    traceExitRays(ctx, list.data(), list.size(), sc, stats);

    // Votes: back faces for, misses against.
    const size_t total = ns * list.size();
    sc.vote.assign(ns, 0);
    for (size_t q = 0; q < total; ++q) {
        const Hit& h = sc.hits[q];
        const size_t p = q / ns;
        const uint32_t r = list[p];
        if (!h.hit) {
            sc.vote[q - p * ns] -= 1;
        } else if (dirs.x[r] * h.geometricNormal.x + dirs.y[r] * h.geometricNormal.y +
                       dirs.z[r] * h.geometricNormal.z > 0.0f) {
            sc.vote[q - p * ns] += 1;
        }
    }
    size_t inside = 0;
    sc.inside.resize(ns);
    for (size_t i = 0; i < ns; ++i) {
        sc.inside[i] = sc.vote[i] > 0 ? 1 : 0;
        inside += sc.inside[i];
    }
    return inside;
}

// Traces the occlusion rays of the candidates listed in sc.traced (indices into the
// compacted candidate arrays) as one coherent batch and stores V in sc.occluded.
void traceListed(const SingleScatteringContext& ctx, SingleScatteringScratch& sc,
                 SingleScatteringStats& stats) {
    const size_t k = sc.traced.size();
    if (k == 0) return;
    sc.visX.resize(k);
    sc.visY.resize(k);
    sc.visZ.resize(k);
    sc.visDX.resize(k);
    sc.visDY.resize(k);
    sc.visDZ.resize(k);
    sc.visOccluded.resize(k);
    for (size_t j = 0; j < k; ++j) {
        const uint32_t q = sc.traced[j];
        sc.visX[j] = sc.orgX[q];
        sc.visY[j] = sc.orgY[q];
        sc.visZ[j] = sc.orgZ[q];
        sc.visDX[j] = sc.dirX[q];
        sc.visDY[j] = sc.dirY[q];
        sc.visDZ[j] = sc.dirZ[q];
    }
    ctx.occludedCoherent(sc.visX.data(), sc.visY.data(), sc.visZ.data(), sc.visDX.data(),
                         sc.visDY.data(), sc.visDZ.data(), k, sc.visOccluded.data());
    stats.occlusionRays += k;
    for (size_t j = 0; j < k; ++j) sc.occluded[sc.traced[j]] = sc.visOccluded[j];
}

// Shared visibility (SingleScatteringOptions::sharedVisibility) for the m compacted
// candidates, which are in direction-major order (the candidates of one direction are
// contiguous, shallowest sample first). Round 1 traces the two ends of every run of
// one direction; round 2 the inner candidates of the runs whose ends disagree. A run
// whose ends agree gives its inner candidates the ends' V: their exit points lie on
// parallel rays between the two ends' (a few mean free paths apart), so only a shadow
// edge that enters and leaves between them is missed.
void sharedOcclusion(const SingleScatteringContext& ctx, size_t m, SingleScatteringScratch& sc,
                     SingleScatteringStats& stats) {
    sc.traced.clear();
    for (size_t a = 0; a < m;) {
        size_t b = a + 1;
        while (b < m && sc.direction[b] == sc.direction[a]) ++b;
        sc.traced.push_back(uint32_t(a));
        if (b - a > 1) sc.traced.push_back(uint32_t(b - 1));
        a = b;
    }
    traceListed(ctx, sc, stats);
    sc.traced.clear();
    for (size_t a = 0; a < m;) {
        size_t b = a + 1;
        while (b < m && sc.direction[b] == sc.direction[a]) ++b;
        if (b - a > 2) {
            if (sc.occluded[a] == sc.occluded[b - 1]) {
                std::fill(sc.occluded.begin() + std::ptrdiff_t(a + 1),
                          sc.occluded.begin() + std::ptrdiff_t(b - 1), sc.occluded[a]);
                stats.sharedVisibility += b - a - 2;
            } else {
                for (size_t q = a + 1; q + 1 < b; ++q) sc.traced.push_back(uint32_t(q));
            }
        }
        a = b;
    }
    traceListed(ctx, sc, stats);
}

// Shades the exits in sc.hits of the rays toward list[0..count) (traceExitRays' order),
// traces the occlusion rays of those that survive the cut-off and adds them to the
// dense transport. With `record`, also fills sc.exitCode and sc.sampleMagnitude (per
// texel and path sample: the kind of exit and its RGB-luminance throughput per
// steradian before V, phase not included), sc.magnitude (per texel: the same summed
// over its visible exits) and sc.stake (summed over all its exits, occluded or not) for
// the adaptive directions.
void shadeExits(const SingleScatteringContext& ctx, const uint32_t* list, size_t count, float* dense,
                bool record, SingleScatteringScratch& sc, SingleScatteringStats& stats) {
    const RayScene& scene = ctx.scene();
    const SingleScatteringContext::CornerNormals* cornerNormals = ctx.cornerNormalsData();
    const Material& mat = ctx.material();
    const SingleScatteringContext::Directions& dirs = ctx.tracedDirections();
    const SingleScatteringOptions& opt = ctx.options();
    const size_t texels = ctx.texelCount();
    const int terms = ctx.terms();
    const float eta = float(mat.eta);
    const float invEta2 = 1.0f / (eta * eta);
    const glm::vec3 sigmaT(mat.sigmaT());
    const float minThroughput = float(opt.minThroughput);
    const size_t ns = sc.samplePoint.size();
    const size_t total = ns * count;
    const bool fromExitRays = ctx.visibilityFromExitRays();
    sc.occluded.resize(total);
    sc.texel.resize(total);
    sc.direction.resize(total);
    sc.candidateSample.resize(total);
    sc.value.resize(total * 3);
    sc.phase.resize(total * size_t(terms));
    if (record)
        for (size_t p = 0; p < count; ++p) {
            std::fill_n(sc.exitCode.begin() + std::ptrdiff_t(size_t(list[p]) * ns), ns, uint8_t(0));
            std::fill_n(sc.sampleMagnitude.begin() + std::ptrdiff_t(size_t(list[p]) * ns), ns, 0.0f);
            sc.magnitude[list[p]] = 0.0f;
            sc.stake[list[p]] = 0.0f;
        }

    // Candidates: exits of inside sample points whose light reaches x_p with
    // non-negligible throughput. They overwrite the ray arrays in place (m <= q).
    size_t m = 0;
    // Exits ahead whose corner normals are fetched now (each a cache miss, and their
    // 36 bytes may straddle two lines).
    constexpr size_t kPrefetch = 16;
    for (size_t q = 0; q < total; ++q) {
        if (q + kPrefetch < total && sc.hits[q + kPrefetch].hit) {
            const char* ahead = reinterpret_cast<const char*>(&cornerNormals[sc.hits[q + kPrefetch].triangle]);
            __builtin_prefetch(ahead);
            __builtin_prefetch(ahead + sizeof(SingleScatteringContext::CornerNormals) - 1);
        }
        const size_t p = q / ns, i = q - p * ns;
        const uint32_t r = list[p];
        if (!sc.inside[i]) continue;
        const Hit& h = sc.hits[q];
        if (!h.hit) {
            ++stats.escapedRays;
            continue;
        }
        const glm::vec3 w(dirs.x[r], dirs.y[r], dirs.z[r]);
        // From an inside point the first hit is where the ray leaves the object. A
        // triangle facing the other way there is wound the wrong way round (so are its
        // vertex normals, which are computed from the faces): reverse both.
        glm::vec3 gn = h.geometricNormal;
        float side = 1.0f;
        if (glm::dot(w, gn) < 0.0f) {
            side = -1.0f;
            gn = -gn;
            ++stats.reversedHits;
        }
        const SingleScatteringContext::CornerNormals& cn = cornerNormals[h.triangle];
        glm::vec3 ni = side * ((1.0f - h.u - h.v) * cn.n[0] + h.u * cn.n[1] + h.v * cn.n[2]);
        float cosI = glm::dot(w, ni);
        const float niLen = glm::length(ni);
        if (niLen > 0.0f && cosI > 1e-6f * niLen) {
            ni /= niLen;
            cosI = std::min(cosI / niLen, 1.0f);
        } else {  // the interpolated normal faces away from w: use the triangle's
            ni = gn;
            cosI = std::min(glm::dot(w, gn), 1.0f);
        }
        if (!(cosI > 0.0f)) continue;  // grazing a degenerate configuration
        const float cos2t = 1.0f - invEta2 * (1.0f - cosI * cosI);
        if (cos2t <= 0.0f) continue;  // total internal reflection (eta < 1 only)
        const float cosT = std::sqrt(cos2t);
        const float sPrime = h.t * cosI / cosT;  // Eq. 5 (unit directions: t is s_i)
        const float ft = ctx.fresnel(cosI);
        const glm::vec3 atten(std::exp(-sigmaT.x * sPrime), std::exp(-sigmaT.y * sPrime),
                              std::exp(-sigmaT.z * sPrime));
        const float throughput = ft * std::max(atten.x, std::max(atten.y, atten.z));
        if (throughput < minThroughput || throughput <= 0.0f) {
            ++stats.culledRays;
            continue;
        }
        const glm::vec3 value = sc.sampleWeight[i] * atten * (ft * dirs.solidAngle[r]);
        // w_i': the light's propagation direction after refraction at x_i (into the
        // medium): -w / eta + (cos_i / eta - cos_t) n_i (bssrdf.h refractDirection).
        const glm::vec3 a = -w / eta + (cosI / eta - cosT) * ni;
        ctx.lightMapValues(a, &sc.phase[m * size_t(terms)]);
        if (fromExitRays) {
            sc.occluded[m] = sc.beyond[q];  // m <= q: not yet read
        } else {  // the occlusion ray from x_i
            const glm::vec3 org = scene.offsetRayOrigin(sc.samplePoint[i] + h.t * w, gn, w);
            sc.orgX[m] = org.x;
            sc.orgY[m] = org.y;
            sc.orgZ[m] = org.z;
            sc.dirX[m] = w.x;
            sc.dirY[m] = w.y;
            sc.dirZ[m] = w.z;
        }
        sc.texel[m] = dirs.texel[r];
        sc.direction[m] = r;
        sc.candidateSample[m] = uint32_t(i);
        sc.value[3 * m] = value.x;
        sc.value[3 * m + 1] = value.y;
        sc.value[3 * m + 2] = value.z;
        if (record) sc.sampleMagnitude[size_t(r) * ns + i] = float(luminance(glm::dvec3(value))) / dirs.solidAngle[r];
        ++m;
    }
    if (m == 0) return;

    // V: does anything block the light before it reaches x_i?
    if (fromExitRays) {
        // already known from the exit rays' traversal
    } else if (opt.visibility && opt.sharedVisibility) {
        sharedOcclusion(ctx, m, sc, stats);
    } else if (opt.visibility) {
        ctx.occludedCoherent(sc.orgX.data(), sc.orgY.data(), sc.orgZ.data(), sc.dirX.data(),
                             sc.dirY.data(), sc.dirZ.data(), m, sc.occluded.data());
        stats.occlusionRays += m;
    } else {
        std::fill_n(sc.occluded.begin(), m, uint8_t(0));
    }

    for (size_t q = 0; q < m; ++q) {
        stats.occludedExits += sc.occluded[q];
        if (record) {
            const uint32_t r = sc.direction[q];
            sc.exitCode[size_t(r) * ns + sc.candidateSample[q]] = sc.occluded[q] ? 1 : 2;
            const float v = sc.sampleMagnitude[size_t(r) * ns + sc.candidateSample[q]];
            sc.stake[r] += v;
            if (!sc.occluded[q]) sc.magnitude[r] += v;
        }
        if (sc.occluded[q]) continue;
        const float* v = &sc.value[3 * q];
        const float* g = &sc.phase[q * size_t(terms)];
        for (int k = 0; k < terms; ++k) {
            float* d = dense + (size_t(k) * texels + sc.texel[q]) * 3;
            d[0] += v[0] * g[k];
            d[1] += v[1] * g[k];
            d[2] += v[2] * g[k];
        }
    }
}

// Whether the corners c[0..4) of a cell `span` texels wide agree
// (SingleScatteringOptions::directionStride): every path sample whose exit carries more
// than valueFloor per steradian at some corner (occluded or not) has the same kind of
// exit at all four (occluded, visible, or none); the corners' throughputs differ by at
// most refineValueTolerance x the largest (+ valueFloor); and a cell wider than 2
// texels has little light at stake at every corner, occluded or not (at most
// largeCellMax), so a small occluder, a small lit gap or a sheet edge that fits between
// its corners can hide only where little light is at stake.
enum class CellSplit { None, Stake, Throughput, ExitKind };

CellSplit cornersAgree(const SingleScatteringContext& ctx, const uint32_t* c, int span, float valueFloor,
                       float largeCellMax, const SingleScatteringScratch& sc) {
    const size_t ns = sc.samplePoint.size();
    if (span > 2)  // before V: an occluded corner may border a lit gap
        for (int a = 0; a < 4; ++a)
            if (sc.stake[c[a]] > largeCellMax) return CellSplit::Stake;
    float lo = sc.magnitude[c[0]], hi = lo;
    for (int a = 1; a < 4; ++a) {
        lo = std::min(lo, sc.magnitude[c[a]]);
        hi = std::max(hi, sc.magnitude[c[a]]);
    }
    if (hi - lo > float(ctx.options().refineValueTolerance) * hi + valueFloor) return CellSplit::Throughput;
    for (size_t i = 0; i < ns; ++i) {
        float atStake = 0.0f;
        for (int a = 0; a < 4; ++a) atStake = std::max(atStake, sc.sampleMagnitude[size_t(c[a]) * ns + i]);
        if (atStake <= valueFloor) continue;
        const uint8_t code = sc.exitCode[size_t(c[0]) * ns + i];
        for (int a = 1; a < 4; ++a)
            if (sc.exitCode[size_t(c[a]) * ns + i] != code) return CellSplit::ExitKind;
    }
    return CellSplit::None;
}

// The adaptive directions after the lattice has been traced and shaded (with records):
// cells are interpolated or split, round by round, until every texel is traced or
// interpolated. A texel takes the value of the smallest cell that interpolated it, and
// a traced value over any interpolation.
void refineDirections(const SingleScatteringContext& ctx, float* dense, SingleScatteringScratch& sc,
                      SingleScatteringStats& stats) {
    const int n = ctx.cubemapSize();
    const size_t texels = ctx.texelCount();
    const int terms = ctx.terms();
    const SingleScatteringContext::Directions& dirs = ctx.tracedDirections();
    float largest = 0.0f;  // the vertex's scale: its brightest lattice texel before V
    for (uint32_t r : ctx.firstDirections()) largest = std::max(largest, sc.stake[r]);
    const float valueFloor = float(ctx.options().refineValueFloor) * largest;
    const float largeCellMax = float(ctx.options().refineLargeCellValue) * largest;
    auto texelOf = [n](int f, int i, int j) { return uint32_t((f * n + j) * n + i); };

    sc.cells = ctx.topCells();
    while (!sc.cells.empty()) {
        sc.nextCells.clear();
        sc.list.clear();
        for (const SingleScatteringContext::DirectionCell& cell : sc.cells) {
            const int f = cell.face, i0 = cell.i0, i1 = cell.i1, j0 = cell.j0, j1 = cell.j1;
            if (i1 - i0 <= 1 && j1 - j0 <= 1) continue;  // no texel inside
            const uint32_t corner[4] = {texelOf(f, i0, j0), texelOf(f, i1, j0), texelOf(f, i0, j1),
                                        texelOf(f, i1, j1)};
            const uint16_t span = uint16_t(std::max(i1 - i0, j1 - j0));
            const CellSplit split = cornersAgree(ctx, corner, span, valueFloor, largeCellMax, sc);
            if (split == CellSplit::None) {
                // The corners per steradian, once per cell: perSr[(k * 3 + c) * 4 + a].
                sc.cornerPerSr.resize(size_t(terms) * 12);
                float* perSr = sc.cornerPerSr.data();
                for (int a = 0; a < 4; ++a) {
                    const float inv = 1.0f / dirs.solidAngle[corner[a]];
                    for (int k = 0; k < terms; ++k)
                        for (int c = 0; c < 3; ++c)
                            perSr[(size_t(k) * 3 + size_t(c)) * 4 + size_t(a)] =
                                dense[(size_t(k) * texels + corner[a]) * 3 + size_t(c)] * inv;
                }
                const float invDu = 1.0f / float(i1 - i0), invDv = 1.0f / float(j1 - j0);
                for (int j = j0; j <= j1; ++j)
                    for (int i = i0; i <= i1; ++i) {
                        const uint32_t t = texelOf(f, i, j);
                        if (sc.texelTraced[t] || sc.texelSpan[t] < span) continue;
                        sc.texelSpan[t] = span;
                        const float u = float(i - i0) * invDu, v = float(j - j0) * invDv;
                        const float sa = dirs.solidAngle[t];
                        const float w[4] = {(1 - u) * (1 - v) * sa, u * (1 - v) * sa, (1 - u) * v * sa, u * v * sa};
                        float* d = dense + size_t(t) * 3;
                        for (int kc = 0; kc < terms * 3; ++kc) {
                            const float* q = perSr + size_t(kc) * 4;
                            d[size_t(kc / 3) * texels * 3 + size_t(kc % 3)] =
                                w[0] * q[0] + w[1] * q[1] + w[2] * q[2] + w[3] * q[3];
                        }
                    }
                continue;
            }
            // Split: trace the new corners, then look at the four (or two) sub-cells.
            (split == CellSplit::Stake ? stats.splitsByStake
             : split == CellSplit::Throughput ? stats.splitsByThroughput : stats.splitsByExitKind) += 1;
            int xs[3], ys[3];
            int cx = 0, cy = 0;
            xs[cx++] = i0;
            if (i1 - i0 >= 2) xs[cx++] = (i0 + i1) / 2;
            xs[cx++] = i1;
            ys[cy++] = j0;
            if (j1 - j0 >= 2) ys[cy++] = (j0 + j1) / 2;
            ys[cy++] = j1;
            for (int b = 0; b < cy; ++b)
                for (int a = 0; a < cx; ++a) {
                    const uint32_t t = texelOf(f, xs[a], ys[b]);
                    if (sc.texelTraced[t]) continue;
                    sc.texelTraced[t] = 1;
                    sc.list.push_back(t);
                }
            for (int b = 0; b + 1 < cy; ++b)
                for (int a = 0; a + 1 < cx; ++a)
                    sc.nextCells.push_back({uint16_t(f), uint16_t(xs[a]), uint16_t(xs[a + 1]), uint16_t(ys[b]),
                                            uint16_t(ys[b + 1])});
        }
        if (!sc.list.empty()) {
            // Traced texels replace whatever a coarser cell interpolated there.
            for (uint32_t t : sc.list)
                for (int k = 0; k < terms; ++k) std::fill_n(dense + (size_t(k) * texels + t) * 3, 3, 0.0f);
            traceExitRays(ctx, sc.list.data(), sc.list.size(), sc, stats);
            shadeExits(ctx, sc.list.data(), sc.list.size(), dense, true, sc, stats);
        }
        std::swap(sc.cells, sc.nextCells);
    }
    uint64_t traced = 0;
    for (size_t t = 0; t < texels; ++t) traced += sc.texelTraced[t];
    stats.tracedTexels += traced;
    stats.interpolatedTexels += texels - traced;
}

}  // namespace

void singleScatteringVertex(const SingleScatteringContext& ctx, const glm::vec3& position,
                            const glm::vec3& normalIn, float* dense, SingleScatteringScratch& sc,
                            SingleScatteringStats& stats) {
    const RayScene& scene = ctx.scene();
    const SingleScatteringOptions& opt = ctx.options();

    std::fill_n(dense, ctx.denseSize(), 0.0f);
    const float nLen = glm::length(normalIn);
    if (!(nLen > 0.0f)) return;  // no normal: nothing to integrate along
    const glm::vec3 n = normalIn / nLen;

    // d_m along -n_o, then the exit rays of the path sample points.
    FarSide far = farSideDistance(scene, position, n, ctx.depthCap());
    stats.depthRays += 1;
    if (!(far.distance > 0.0)) return;
    size_t inside = traceExits(ctx, position, -n, far.distance, sc, stats);
    if (2 * inside < size_t(opt.pathSamples)) {
        // Most sample points below the vertex are outside the object: the vertex normal
        // points inward (an inconsistently oriented patch of a scanned mesh). Integrate
        // along +n_o instead if that is inside more often.
        const FarSide flippedFar = farSideDistance(scene, position, -n, ctx.depthCap());
        stats.depthRays += 1;
        const size_t original = inside;
        if (flippedFar.distance > 0.0)
            inside = traceExits(ctx, position, n, flippedFar.distance, sc, stats);
        if (flippedFar.distance > 0.0 && inside > original) {
            far = flippedFar;
            stats.flippedNormals += 1;
        } else {
            inside = traceExits(ctx, position, -n, far.distance, sc, stats);
        }
    }
    stats.depthSum += far.distance;
    if (!far.hit) stats.cappedDepths += 1;
    const size_t ns = sc.samplePoint.size();
    stats.outsideSamples += ns - inside;
    if (inside == 0) return;

    const std::vector<uint32_t>& first = ctx.firstDirections();
    const bool adaptive = ctx.adaptiveDirections();
    if (adaptive) {
        const size_t texels = ctx.texelCount();
        sc.exitCode.resize(texels * ns);
        sc.sampleMagnitude.resize(texels * ns);
        sc.magnitude.resize(texels);
        sc.stake.resize(texels);
        sc.texelTraced.assign(texels, 0);
        sc.texelSpan.assign(texels, uint16_t(0xFFFF));
        for (uint32_t t : first) sc.texelTraced[t] = 1;
    }
    shadeExits(ctx, first.data(), first.size(), dense, adaptive, sc, stats);
    if (adaptive)
        refineDirections(ctx, dense, sc, stats);
    else
        stats.tracedTexels += ctx.texelCount();
}

void haarSingleScattering(const SingleScatteringContext& ctx, float* dense) {
    const int n = ctx.cubemapSize();
    const size_t texels = ctx.texelCount();
    const size_t faceSize = size_t(n) * n;
    for (int k = 0; k < ctx.terms(); ++k) {
        float* term = dense + size_t(k) * texels * 3;
        for (int f = 0; f < kCubeFaces; ++f)
            for (int c = 0; c < 3; ++c) haarForwardFace(term + size_t(f) * faceSize * 3 + c, n, 3);
    }
}

double truncateSingleScattering(const SingleScatteringContext& ctx, float* dense, std::vector<SparseVector>& out) {
    const size_t texels = ctx.texelCount();
    out.resize(size_t(ctx.terms()));
    double total = 0.0, kept = 0.0;
    for (int k = 0; k < ctx.terms(); ++k) {
        float* term = dense + size_t(k) * texels * 3;
        const double termEnergy = energy(term, texels * 3);
        total += termEnergy;
        const int shTerms = ctx.options().shTerms;
        double retained = 1.0;
        if (shTerms == 0) {
            out[size_t(k)] = truncateWithShPart(term, texels, 3, 0, ctx.options().vertexCoefficients, &retained);
        } else {
            // The SH split needs room for the SH entries after the Haar ones.
            thread_local std::vector<float> withSh;
            withSh.assign((texels + size_t(shTerms)) * 3, 0.0f);
            std::copy(term, term + texels * 3, withSh.begin());
            out[size_t(k)] = truncateWithShPart(withSh.data(), texels, 3, shTerms,
                                                ctx.options().vertexCoefficients, &retained);
        }
        kept += retained * termEnergy;
    }
    return total > 0.0 ? kept / total : 1.0;
}

double compressSingleScattering(const SingleScatteringContext& ctx, float* dense,
                                std::vector<SparseVector>& out) {
    haarSingleScattering(ctx, dense);
    return truncateSingleScattering(ctx, dense, out);
}

// ---------------------------------------------------------------------------------
// All vertices
// ---------------------------------------------------------------------------------

namespace {

struct ThreadState {
    SingleScatteringScratch scratch;
    std::vector<float> dense;
    SingleScatteringStats stats;
};

// The vertices of `ranges` in blocks: `vertex(v, dense, stats, out)` computes one
// (returning its retained energy fraction) in parallel within a block, and the block is
// handed to the sink in order. A block is a few seconds of work, so the barrier at its
// end costs little.
template <typename VertexFunction>
SingleScatteringResult forEachVertexInOrder(const SingleScatteringContext& ctx, const VertexRanges& ranges,
                                            const SingleScatteringSink& sink, Progress* progress,
                                            VertexFunction&& vertex) {
    const TriangleMesh& mesh = ctx.mesh();
    size_t vertexCount = 0;
    for (const auto& [first, end] : ranges) {
        if (first > end || end > mesh.positions.size()) throw Error("single scattering", "vertex range out of bounds");
        vertexCount += end - first;
    }
    SingleScatteringResult result;
    result.isotropic = ctx.isotropic();
    result.terms = ctx.terms();
    tbb::combinable<ThreadState> states;
    constexpr size_t kBlock = 512;
    std::vector<std::vector<SparseVector>> block(kBlock);
    std::vector<double> retained(kBlock, 1.0);
    double retainedSum = 0.0;
    const Stopwatch start;
    VertexRanges blocks;
    for (const auto& [first, last] : ranges)
        for (size_t base = first; base < last; base += kBlock) blocks.push_back({base, std::min(last, base + kBlock)});
    for (const auto& [base, end] : blocks) {
        tbb::parallel_for(tbb::blocked_range<size_t>(base, end, 1), [&](const tbb::blocked_range<size_t>& r) {
            ThreadState& st = states.local();
            st.dense.resize(ctx.denseSize());
            for (size_t v = r.begin(); v != r.end(); ++v) retained[v - base] = vertex(v, st, block[v - base]);
            if (progress) progress->advance(r.size());
        });
        for (size_t v = base; v < end; ++v) {
            retainedSum += retained[v - base];
            sink(v, block[v - base]);
        }
    }
    result.seconds = start.seconds();
    states.combine_each([&](const ThreadState& st) { result.stats.add(st.stats); });
    result.retainedEnergyFraction = vertexCount > 0 ? retainedSum / double(vertexCount) : 1.0;
    return result;
}

}  // namespace

std::vector<std::vector<SparseVector>> computeSiteTransport(const SingleScatteringContext& ctx,
                                                            const SingleScatteringSites& sites,
                                                            std::span<const uint32_t> numbers,
                                                            SingleScatteringStats& stats, Progress* progress,
                                                            size_t progressUnits) {
    const TriangleMesh& mesh = ctx.mesh();
    std::vector<std::vector<SparseVector>> out(numbers.size());
    const size_t keep = ctx.options().vertexCoefficients * size_t(std::max(1, ctx.options().siteCoefficientFactor));
    const auto share = [&](size_t i) { return numbers.empty() ? 0 : i * progressUnits / numbers.size(); };
    tbb::combinable<ThreadState> states;
    tbb::parallel_for(tbb::blocked_range<size_t>(0, numbers.size(), 1), [&](const tbb::blocked_range<size_t>& r) {
        ThreadState& st = states.local();
        st.dense.resize(ctx.denseSize());
        for (size_t i = r.begin(); i != r.end(); ++i) {
            if (numbers[i] >= sites.site.size()) throw Error("single scattering", "site number out of range");
            const uint32_t v = sites.site[numbers[i]];
            singleScatteringVertex(ctx, ctx.pathOrigin(v), mesh.normals[v], st.dense.data(), st.scratch, st.stats);
            st.stats.sites += 1;
            haarSingleScattering(ctx, st.dense.data());
            out[i].resize(size_t(ctx.terms()));
            for (int k = 0; k < ctx.terms(); ++k)
                out[i][size_t(k)] =
                    truncateLargest(st.dense.data() + size_t(k) * ctx.texelCount() * 3, ctx.texelCount(), 3, keep);
        }
        if (progress) progress->advance(share(r.end()) - share(r.begin()));
    });
    states.combine_each([&](const ThreadState& st) { stats.add(st.stats); });
    return out;
}

SingleScatteringResult blendSiteTransport(const SingleScatteringContext& ctx, const SingleScatteringSites& sites,
                                          std::span<const uint32_t> held,
                                          const std::vector<std::vector<SparseVector>>& vectors,
                                          const SingleScatteringSink& sink, Progress* progress,
                                          const VertexRanges& ranges) {
    if (held.size() != vectors.size()) throw Error("single scattering", "one vector set per held site needed");
    if (sites.vertexCount() != ctx.mesh().positions.size())
        throw Error("single scattering", "the sites were chosen for another mesh");
    std::vector<uint32_t> slotOfSite(sites.site.size(), UINT32_MAX);
    const size_t texels = ctx.texelCount();
    for (size_t i = 0; i < held.size(); ++i) {
        if (held[i] >= sites.site.size()) throw Error("single scattering", "site number out of range");
        slotOfSite[held[i]] = uint32_t(i);
        if (vectors[i].size() != size_t(ctx.terms()))
            throw Error("single scattering", "a site's vectors do not have the context's phase terms");
        for (const SparseVector& t : vectors[i])
            if (t.channels != 3 || t.value.size() != t.index.size() * 3 ||
                (!t.index.empty() && t.index.back() >= texels))
                throw Error("single scattering", "a site's vector is not an RGB vector of the context's cubemap");
    }
    for (const auto& [first, end] : ranges)
        for (size_t v = first; v < std::min(end, sites.vertexCount()); ++v)
            for (uint32_t b = sites.offset[v]; b < sites.offset[v + 1]; ++b)
                if (slotOfSite[sites.blendSite[b]] == UINT32_MAX)
                    throw Error("single scattering", "vertex " + std::to_string(v) + " blends a site not held");
    return forEachVertexInOrder(ctx, ranges, sink, progress, [&](size_t v, ThreadState& st, std::vector<SparseVector>& out) {
        // The blend, in the Haar domain (the transform is linear).
        std::fill(st.dense.begin(), st.dense.end(), 0.0f);
        for (uint32_t b = sites.offset[v]; b < sites.offset[v + 1]; ++b) {
            const float w = sites.blendWeight[b];
            const std::vector<SparseVector>& sv = vectors[slotOfSite[sites.blendSite[b]]];
            for (int k = 0; k < ctx.terms(); ++k) {
                const SparseVector& t = sv[size_t(k)];
                float* d = st.dense.data() + size_t(k) * texels * 3;
                for (size_t e = 0; e < t.index.size(); ++e)
                    for (int c = 0; c < 3; ++c) d[size_t(t.index[e]) * 3 + size_t(c)] += w * t.value[e * 3 + size_t(c)];
            }
        }
        return truncateSingleScattering(ctx, st.dense.data(), out);
    });
}

SingleScatteringResult computeSingleScattering(const SingleScatteringContext& ctx,
                                               const SingleScatteringSink& sink,
                                               Progress* progress,
                                               std::optional<VertexRanges> given) {
    const TriangleMesh& mesh = ctx.mesh();
    const VertexRanges ranges = given ? *given : VertexRanges{{0, mesh.positions.size()}};
    size_t vertexCount = 0;
    for (const auto& [first, end] : ranges) {
        if (first > end || end > mesh.positions.size()) throw Error("single scattering", "vertex range out of bounds");
        vertexCount += end - first;
    }
    const double spacing = ctx.options().siteSpacing;
    if (!(spacing > 0.0) || vertexCount == 0)
        return forEachVertexInOrder(ctx, ranges, sink, progress, [&](size_t v, ThreadState& st, std::vector<SparseVector>& out) {
            singleScatteringVertex(ctx, ctx.pathOrigin(v), mesh.normals[v], st.dense.data(), st.scratch, st.stats);
            st.stats.sites += 1;
            return compressSingleScattering(ctx, st.dense.data(), out);
        });

    // Sites: the transport of every site the ranges blend, each truncated to its
    // largest coefficients, held until the end. Progress counts them as the vertices
    // they stand for; the blend, which is quick, does not advance it.
    const Stopwatch start;
    const SingleScatteringSites sites = chooseSingleScatteringSites(mesh.positions, mesh.normals, spacing);
    const std::vector<uint32_t> needed = sites.sitesOf(ranges);
    SingleScatteringStats siteStats;
    const std::vector<std::vector<SparseVector>> vectors =
        computeSiteTransport(ctx, sites, needed, siteStats, progress, vertexCount);
    SingleScatteringResult result = blendSiteTransport(ctx, sites, needed, vectors, sink, nullptr, ranges);
    result.stats.add(siteStats);
    result.seconds = start.seconds();
    return result;
}

SingleScatteringResult computeSingleScattering(const SingleScatteringContext& ctx,
                                               std::vector<std::vector<SparseVector>>& out,
                                               Progress* progress) {
    out.assign(size_t(ctx.terms()), std::vector<SparseVector>(ctx.mesh().positions.size()));
    return computeSingleScattering(
        ctx,
        [&](size_t v, const std::vector<SparseVector>& terms) {
            for (size_t k = 0; k < terms.size(); ++k) out[k][v] = terms[k];
        },
        progress);
}

}  // namespace prt
