#include "relight/pointlight/texture_space_sampling.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <xmmintrin.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <string>

#include "common/error.h"
#include "common/util.h"

namespace prt {

const char* toString(TextureSpaceMode mode) {
    switch (mode) {
        case TextureSpaceMode::Sampling: return "sampling";
        case TextureSpaceMode::Hybrid: return "hybrid";
        case TextureSpaceMode::Local: return "local";
        case TextureSpaceMode::Global: return "global";
    }
    return "?";
}

TextureSpaceMode parseTextureSpaceMode(const std::string& text) {
    const std::string t = toLower(text);
    if (t == "sampling") return TextureSpaceMode::Sampling;
    if (t == "hybrid") return TextureSpaceMode::Hybrid;
    if (t == "local") return TextureSpaceMode::Local;
    if (t == "global") return TextureSpaceMode::Global;
    throw Error("--split", "expected sampling, hybrid, local or global, got '" + text + "'");
}

void validateTextureSpaceOptions(const TextureSpaceOptions& o) {
    if (o.samples < 1 || o.samples > 10'000'000)
        throw Error("--tsis-samples", "must be from 1 to 10000000, got " + std::to_string(o.samples));
    if (!std::isfinite(o.importanceBound) || !(o.importanceBound > 0.0))
        throw Error("--importance-bound", "must be finite and > 0 (mm^-1)");
    if (!std::isfinite(o.sharpness) || !(o.sharpness > 0.0))
        throw Error("--split-sharpness", "must be finite and > 0 (mm^-1)");
    if (o.lightMapSize < 16 || o.lightMapSize > 8192)
        throw Error("--light-map", "must be from 16 to 8192, got " + std::to_string(o.lightMapSize));
    if (o.rings < 1 || o.rings > 1000) throw Error("--rings", "must be from 1 to 1000");
    if (o.ringSamples < 1 || o.ringSamples > 1000) throw Error("--ring-samples", "must be from 1 to 1000");
    if (!std::isfinite(o.clusterAngle) || o.clusterAngle < 0.0 || o.clusterAngle > 2.0)
        throw Error("--cluster-angle", "must be from 0 to 2 (0 sums every sample)");
}

TextureSpaceRenderer::TextureSpaceRenderer(const TriangleMesh& mesh, const RayScene& scene, const SurfaceAtlas& atlas,
                                           const Material& material, const TextureSpaceOptions& options)
    : mesh_(&mesh), scene_(&scene), atlas_(&atlas), options_(options) {
    validateMaterial(material);
    validateTextureSpaceOptions(options_);
    if (atlas.samples.size() == 0) throw Error("atlas", "the atlas holds no surface");
    sphere_ = boundingSphere(mesh);
    buildMaterialState(material);

    vertexOrder_ = mortonOrder(mesh.positions, "mesh");
    orderedPositions_.resize(vertexOrder_.size());
    for (size_t k = 0; k < vertexOrder_.size(); ++k) orderedPositions_[k] = mesh.positions[vertexOrder_[k]];
}

void TextureSpaceRenderer::buildMaterialState(const Material& material) {
    material_ = material;
    const double rMax = std::max(2.0 * sphere_.radius, 1e-6) * 1.001;
    split_ = DiffusionSplit{};
    split_.rp = importanceRadius(material_, options_.importanceBound);
    split_.sharpness = options_.sharpness;
    split_.weights = options_.weights;
    sampleKernel_ = RadialTable();
    sampleCurvature_ = RadialCurvature();
    if (usesSamples()) {
        const RadialKernel kernel = options_.mode == TextureSpaceMode::Sampling ? diffusionKernel(material_)
                                                                                : globalDiffusionKernel(material_, split_);
        const std::vector<glm::dvec3> nodes = radialNodes(kernel, rMax);
        sampleKernel_ = RadialTable(nodes, rMax);
        if (options_.clusterAngle > 0.0) sampleCurvature_ = radialCurvature(nodes, rMax);
    }
    filter_ = LocalFilter();
    if (usesFilter())
        filter_ = makeLocalFilter(localDiffusionTable(material_, split_, rMax), options_.rings, options_.ringSamples);
}

void TextureSpaceRenderer::setMaterial(const Material& material) {
    validateMaterial(material);
    requireIrradianceEta(material_.eta, material.eta);
    const Stopwatch t;
    buildMaterialState(material);
    materialSeconds_ = t.seconds();
}

void TextureSpaceRenderer::setLights(const std::vector<Light>& lights) {
    if (lights.empty()) throw Error("--light", "no light");
    Stopwatch t;
    // The irradiance map: E^ at every texel's surface point, times its area.
    const IrradianceSamples& samples = atlas_->samples;
    std::vector<glm::dvec3> lightPower;
    computeIrradiance(samples, *scene_, lights, material_.eta, options_.fresnel, texelFlux_,
                      usesFilter() ? &lightPower : nullptr);
    for (size_t i = 0; i < samples.size(); ++i) texelFlux_[i] *= samples.areas[i];
    timings_.irradianceSeconds = t.seconds();

    // The shadow maps (local part), each holding its light's power over the atlas.
    t.restart();
    maps_.clear();
    if (usesFilter())
        for (size_t l = 0; l < lights.size(); ++l) {
            maps_.emplace_back(*scene_, *mesh_, lights[l], sphere_, material_.eta, options_.fresnel,
                               options_.lightMapSize);
            maps_.back().normalisePower(lightPower[l]);
        }
    timings_.shadowMapSeconds = t.seconds();

    // The pyramid and the draws.
    t.restart();
    const int res = atlas_->resolution;
    std::vector<float> importance(size_t(res) * size_t(res), 0.0f);
    totalFlux_ = glm::dvec3(0.0);
    for (size_t i = 0; i < texelFlux_.size(); ++i) {
        const glm::vec3 f = texelFlux_[i];
        importance[atlas_->sampleTexel[i]] = (f.x + f.y + f.z) / 3.0f;
        totalFlux_ += glm::dvec3(f);
    }
    sampler_.emplace(importance, res);
    draw();
    timings_.samplingSeconds = t.seconds();
}

void TextureSpaceRenderer::redraw(int samples, uint64_t seed, bool drawNow) {
    TextureSpaceOptions o = options_;
    o.samples = samples;
    o.seed = seed;
    validateTextureSpaceOptions(o);
    options_ = o;
    if (!sampler_ || !drawNow) return;
    const Stopwatch t;
    draw();
    timings_.samplingSeconds = t.seconds();
}

void TextureSpaceRenderer::draw() {
    samples_.clear();
    tree_.reset();
    {
        const std::lock_guard<std::mutex> lock(vertexTermsMutex_);
        vertexTermsValid_ = false;  // the next vertexExitance gathers them anew, in the same memory
        vertexTermsOverBudget_ = false;
    }
    if (!usesSamples() || !(sampler_->total() > 0.0)) return;
    std::vector<uint32_t> texels = sampler_->stratifiedSamples(size_t(options_.samples), options_.seed, options_.jitter);
    std::sort(texels.begin(), texels.end());
    const double n = double(options_.samples), total = sampler_->total();
    for (size_t k = 0; k < texels.size();) {
        size_t e = k;
        while (e < texels.size() && texels[e] == texels[k]) ++e;
        const uint32_t texel = texels[k];
        const uint32_t s = atlas_->texelSample[texel];
        const glm::vec3 f = texelFlux_[s];
        const double phi = double(f.x + f.y + f.z) / 3.0;
        // Phi_t / (N p_t) per draw, times the number of equal draws.
        const double scale = double(e - k) * total / (n * phi);
        samples_.push(atlas_->samples.positions[s], glm::vec3(glm::dvec3(f) * scale));
        k = e;
    }
    buildClusters();
}

void SampleTerms::clear() {
    x.clear(); y.clear(); z.clear(); w.clear();
}

void SampleTerms::push(const glm::vec3& position, const glm::vec3& weight) {
    x.push_back(position.x); y.push_back(position.y); z.push_back(position.z);
    w.push_back(glm::vec4(weight, 0.0f));
}

void ClusterTerms::clear() {
    SampleTerms::clear();
    sxx.clear(); syy.clear(); szz.clear(); sxy.clear(); sxz.clear(); syz.clear(); trace.clear();
}

void ClusterTerms::push(const glm::vec3& position, const glm::vec3& weight, const float s[6]) {
    SampleTerms::push(position, weight);
    sxx.push_back(s[0]); syy.push_back(s[1]); szz.push_back(s[2]);
    sxy.push_back(s[3]); sxz.push_back(s[4]); syz.push_back(s[5]);
    trace.push_back(s[0] + s[1] + s[2]);
}

namespace {

// out[p] = sum_j w_j K(|points[p] - x_j|) over the terms. Tiled: one block of terms
// (kBlock x 28 bytes, in L1) for all the points, then the next block. Per point and
// block: distances and table positions in loops the compiler vectorises, then the
// table reads and the weighted sums (RGB in one SSE register, two accumulators for the
// even and the odd terms so that consecutive additions do not wait on each other;
// float within a block, double across blocks: the same order for one point or many).
// The table reads stay scalar (docs/point-lights.md, "Clustered sums and the
// defaults", on gathers). The bodies are compiled twice, for x86-64 and for AVX2 + FMA
// (8 lanes in the vectorised loops), and chosen once per process (cpuHasAvx2Fma): one
// machine always takes the same path, so its sums are deterministic.
[[gnu::always_inline]] inline void kernelSumsBody(const RadialTable& kernel, const SampleTerms& s,
                                                  const glm::vec3* points, size_t count, glm::dvec3* out) {
    constexpr size_t kBlock = 64;
    float r2[kBlock], t[kBlock];
    for (size_t p = 0; p < count; ++p) out[p] = glm::dvec3(0.0);
    const float rMax2 = kernel.rMax2();
    const size_t n = s.size();
    for (size_t begin = 0; begin < n; begin += kBlock) {
        const size_t block = std::min(kBlock, n - begin);
        const float *px = &s.x[begin], *py = &s.y[begin], *pz = &s.z[begin];
        const glm::vec4* w = &s.w[begin];
        for (size_t p = 0; p < count; ++p) {
            const float x0 = points[p].x, y0 = points[p].y, z0 = points[p].z;
            for (size_t j = 0; j < block; ++j) {
                const float dx = x0 - px[j], dy = y0 - py[j], dz = z0 - pz[j];
                r2[j] = dx * dx + dy * dy + dz * dz;
            }
            for (size_t j = 0; j < block; ++j) t[j] = kernel.position(r2[j]);
            const auto term = [&](size_t j) {
                return r2[j] < rMax2 ? _mm_mul_ps(_mm_loadu_ps(&w[j].x), kernel.atSse(t[j])) : _mm_setzero_ps();
            };
            alignas(16) float sum[4];
            _mm_store_ps(sum, sumInPairs(block, term));
            out[p] += glm::dvec3(sum[0], sum[1], sum[2]);
        }
    }
}

// out[p] += sum_j W_j [K(r) + A(r) u^T S_j u + B(r) tr S_j] over the clusters (see
// CLUSTERS in the header), blocked and compiled as kernelSums. A cluster's distance is
// never 0 (it is used whole only at a positive distance from every point).
[[gnu::always_inline]] inline void clusterSumsBody(const RadialTable& kernel, const RadialCurvature& curvature,
                                                   const ClusterTerms& s, const glm::vec3* points, size_t count,
                                                   glm::dvec3* out) {
    constexpr size_t kBlock = 64;
    float r2[kBlock], t[kBlock], q[kBlock];
    const float rMax2 = kernel.rMax2();
    const size_t n = s.size();
    for (size_t begin = 0; begin < n; begin += kBlock) {
        const size_t block = std::min(kBlock, n - begin);
        const float *px = &s.x[begin], *py = &s.y[begin], *pz = &s.z[begin];
        const float *sxx = &s.sxx[begin], *syy = &s.syy[begin], *szz = &s.szz[begin];
        const float *sxy = &s.sxy[begin], *sxz = &s.sxz[begin], *syz = &s.syz[begin], *tr = &s.trace[begin];
        const glm::vec4* w = &s.w[begin];
        for (size_t p = 0; p < count; ++p) {
            const float x0 = points[p].x, y0 = points[p].y, z0 = points[p].z;
            for (size_t j = 0; j < block; ++j) {
                const float dx = x0 - px[j], dy = y0 - py[j], dz = z0 - pz[j];
                r2[j] = dx * dx + dy * dy + dz * dz;
                const float vsv = sxx[j] * dx * dx + syy[j] * dy * dy + szz[j] * dz * dz +
                                  2.0f * (sxy[j] * dx * dy + sxz[j] * dx * dz + syz[j] * dy * dz);
                q[j] = vsv / std::max(r2[j], 1e-30f);  // u^T S u
            }
            for (size_t j = 0; j < block; ++j) t[j] = kernel.position(r2[j]);
            const auto term = [&](size_t j) {
                if (!(r2[j] < rMax2)) return _mm_setzero_ps();
                // The three tables share the grid: one node and fraction for all.
                const int i = kernel.node(t[j]);
                const __m128 f = _mm_set1_ps(t[j] - float(i));
                const __m128 k = _mm_add_ps(kernel.lerpSse(i, f),
                                            _mm_add_ps(_mm_mul_ps(_mm_set1_ps(q[j]), curvature.along.lerpSse(i, f)),
                                                       _mm_mul_ps(_mm_set1_ps(tr[j]), curvature.across.lerpSse(i, f))));
                return _mm_mul_ps(_mm_loadu_ps(&w[j].x), k);
            };
            alignas(16) float sum[4];
            _mm_store_ps(sum, sumInPairs(block, term));
            out[p] += glm::dvec3(sum[0], sum[1], sum[2]);
        }
    }
}

void kernelSumsBaseline(const RadialTable& kernel, const SampleTerms& s, const glm::vec3* points, size_t count,
                        glm::dvec3* out) {
    kernelSumsBody(kernel, s, points, count, out);
}

void clusterSumsBaseline(const RadialTable& kernel, const RadialCurvature& curvature, const ClusterTerms& s,
                         const glm::vec3* points, size_t count, glm::dvec3* out) {
    clusterSumsBody(kernel, curvature, s, points, count, out);
}

#if defined(__x86_64__) && defined(__GNUC__)
__attribute__((target("avx2,fma"))) void kernelSumsAvx2(const RadialTable& kernel, const SampleTerms& s,
                                                        const glm::vec3* points, size_t count, glm::dvec3* out) {
    kernelSumsBody(kernel, s, points, count, out);
}

__attribute__((target("avx2,fma"))) void clusterSumsAvx2(const RadialTable& kernel, const RadialCurvature& curvature,
                                                         const ClusterTerms& s, const glm::vec3* points, size_t count,
                                                         glm::dvec3* out) {
    clusterSumsBody(kernel, curvature, s, points, count, out);
}
#endif

void kernelSums(const RadialTable& kernel, const SampleTerms& s, const glm::vec3* points, size_t count,
                glm::dvec3* out) {
#if defined(__x86_64__) && defined(__GNUC__)
    if (cpuHasAvx2Fma()) return kernelSumsAvx2(kernel, s, points, count, out);
#endif
    kernelSumsBaseline(kernel, s, points, count, out);
}

void clusterSums(const RadialTable& kernel, const RadialCurvature& curvature, const ClusterTerms& s,
                 const glm::vec3* points, size_t count, glm::dvec3* out) {
#if defined(__x86_64__) && defined(__GNUC__)
    if (cpuHasAvx2Fma()) return clusterSumsAvx2(kernel, curvature, s, points, count, out);
#endif
    clusterSumsBaseline(kernel, curvature, s, points, count, out);
}

// Squared distance between the box [lo, hi] and the cubic cell of a node, mm^2.
double boxCellDistance2(const glm::dvec3& lo, const glm::dvec3& hi, const IrradianceOctree::Node& node) {
    const glm::dvec3 cellHi = node.cellLo + glm::dvec3(node.cellSize);
    const glm::dvec3 d = glm::max(glm::max(node.cellLo - hi, lo - cellHi), glm::dvec3(0.0));
    return glm::dot(d, d);
}

}  // namespace

void TextureSpaceRenderer::buildClusters() {
    tree_.reset();
    if (!(options_.clusterAngle > 0.0) || samples_.size() == 0) return;
    // A sample's "area" is its mean weight and its "irradiance" weight / area, so that a
    // node's area x irradiance is the sum of its samples' weights and its position their
    // weight-centred mean (jensen_buhler.h, THE OCTREE).
    IrradianceSamples in;
    const size_t n = samples_.size();
    in.positions.resize(n);
    in.areas.resize(n);
    in.irradiance.resize(n);
    for (size_t i = 0; i < n; ++i) {
        const glm::vec3 w(samples_.w[i]);
        const float a = (w.x + w.y + w.z) / 3.0f;
        in.positions[i] = glm::vec3(samples_.x[i], samples_.y[i], samples_.z[i]);
        in.areas[i] = a;
        in.irradiance[i] = a > 0.0f ? w / a : glm::vec3(0.0f);
    }
    tree_.emplace(in, OctreeOptions{8, 24});
    // The samples in tree order, so that every node's samples are one contiguous range.
    SampleTerms sorted;
    for (const uint32_t i : tree_->order())
        sorted.push(in.positions[i], glm::vec3(samples_.w[i]));
    samples_ = std::move(sorted);
    // Each node's weighted covariance about its centre (mean-weight weights, as the
    // centre's).
    const std::vector<IrradianceOctree::Node>& nodes = tree_->nodes();
    nodeCovariance_.assign(nodes.size(), {});
    tbb::parallel_for(size_t(0), nodes.size(), [&](size_t k) {
        const IrradianceOctree::Node& node = nodes[k];
        if (!(node.area > 0.0)) return;
        double s[6] = {0, 0, 0, 0, 0, 0};
        for (uint32_t i = node.firstSample; i < node.firstSample + node.sampleCount; ++i) {
            const glm::vec4 w = samples_.w[i];
            const double a = (double(w.x) + double(w.y) + double(w.z)) / 3.0;
            const glm::dvec3 d = glm::dvec3(samples_.x[i], samples_.y[i], samples_.z[i]) - node.position;
            s[0] += a * d.x * d.x; s[1] += a * d.y * d.y; s[2] += a * d.z * d.z;
            s[3] += a * d.x * d.y; s[4] += a * d.x * d.z; s[5] += a * d.y * d.z;
        }
        for (int c = 0; c < 6; ++c) nodeCovariance_[k][size_t(c)] = float(s[c] / node.area);
    });
}

void TextureSpaceRenderer::gatherTerms(const glm::vec3* points, size_t count, SampleTerms& terms,
                                       ClusterTerms& clusters) const {
    // The clusters seen from the points' box (see CLUSTERS in the header): whole nodes
    // as one term each, the samples of the opened leaves as they are.
    glm::dvec3 lo(points[0]), hi(points[0]);
    for (size_t p = 1; p < count; ++p) {
        lo = glm::min(lo, glm::dvec3(points[p]));
        hi = glm::max(hi, glm::dvec3(points[p]));
    }
    const double theta2 = options_.clusterAngle * options_.clusterAngle;
    thread_local std::vector<uint32_t> stack;
    terms.clear();
    clusters.clear();
    stack.assign(1, 0u);
    const std::vector<IrradianceOctree::Node>& nodes = tree_->nodes();
    while (!stack.empty()) {
        const uint32_t index = stack.back();
        const IrradianceOctree::Node& node = nodes[index];
        stack.pop_back();
        const double diagonal2 = 3.0 * node.cellSize * node.cellSize;
        if (diagonal2 < theta2 * boxCellDistance2(lo, hi, node)) {
            clusters.push(glm::vec3(node.position), glm::vec3(node.area * node.irradiance), nodeCovariance_[index].data());
        } else if (node.leaf()) {
            for (uint32_t k = node.firstSample; k < node.firstSample + node.sampleCount; ++k)
                terms.push(glm::vec3(samples_.x[k], samples_.y[k], samples_.z[k]),
                           glm::vec3(samples_.w[k]));
        } else {
            for (uint32_t c = node.childCount; c-- > 0;) stack.push_back(node.firstChild + c);
        }
    }
}

void TextureSpaceRenderer::sampleSums(const glm::vec3* points, size_t count, glm::dvec3* out) const {
    if (!tree_) {
        kernelSums(sampleKernel_, samples_, points, count, out);
        return;
    }
    thread_local GroupTerms group;
    gatherTerms(points, count, group.samples, group.clusters);
    sumGroup(group, points, count, out);
}

void TextureSpaceRenderer::sumGroup(const GroupTerms& terms, const glm::vec3* points, size_t count,
                                    glm::dvec3* out) const {
    kernelSums(sampleKernel_, terms.samples, points, count, out);
    clusterSums(sampleKernel_, sampleCurvature_, terms.clusters, points, count, out);
}

size_t GroupTerms::byteSize() const {
    return samples.size() * (3 * sizeof(float) + sizeof(glm::vec4)) +
           clusters.size() * (10 * sizeof(float) + sizeof(glm::vec4));
}

glm::dvec3 TextureSpaceRenderer::exitance(const glm::dvec3& x) const {
    glm::dvec3 m(0.0);
    if (usesSamples()) {
        const glm::vec3 p(x);
        sampleSums(&p, 1, &m);
    }
    if (usesFilter())
        for (const TranslucentShadowMap& map : maps_) m += map.localExitance(x, filter_);
    return m;
}

glm::vec3 TextureSpaceRenderer::radiance(const GBufferPixel& pixel) const {
    if (!pixel.hit) return glm::vec3(0.0f);
    const double cosO = glm::dot(glm::dvec3(pixel.normal), glm::dvec3(pixel.toViewer));
    const double fo = outgoingTransmittance(options_.fresnel, material_.eta, std::max(0.0, cosO));
    if (fo == 0.0) return glm::vec3(0.0f);
    return glm::vec3(fo / std::numbers::pi * exitance(glm::dvec3(pixel.position)));
}

Image TextureSpaceRenderer::render(const GBuffer& g) const {
    return compose(g, Image(), glm::dmat3(1.0), [&](const GBufferPixel& p) { return radiance(p); });
}

std::vector<glm::vec3> TextureSpaceRenderer::vertexExitance() const {
    const size_t nv = mesh_->vertexCount();
    std::vector<glm::vec3> out(nv);
    // Vertices sharing each block of samples (and, with clusters, one box: fewer for a
    // tighter box).
    const size_t kChunk = tree_ ? 16 : 64;
    const size_t chunks = (nv + kChunk - 1) / kChunk;
    // With clusters, each chunk's terms are gathered once per draw and kept (see
    // vertexTerms_ in the header), unless they would take more than the budget.
    std::unique_lock<std::mutex> lock(vertexTermsMutex_, std::defer_lock);
    bool cached = false, gather = false;
    if (tree_ && usesSamples()) {
        lock.lock();
        cached = !vertexTermsOverBudget_;
        gather = cached && !vertexTermsValid_;
        if (gather) vertexTerms_.resize(chunks);
    }
    tbb::parallel_for(size_t(0), chunks, [&](size_t c) {
        const size_t begin = c * kChunk, count = std::min(kChunk, nv - begin);
        glm::dvec3 m[64];
        const glm::vec3* points = &orderedPositions_[begin];
        if (cached) {
            GroupTerms& t = vertexTerms_[c];
            if (gather) gatherTerms(points, count, t.samples, t.clusters);
            sumGroup(t, points, count, m);
        } else if (usesSamples()) {
            sampleSums(points, count, m);
        } else {
            for (size_t k = 0; k < count; ++k) m[k] = glm::dvec3(0.0);
        }
        for (size_t k = 0; k < count; ++k) {
            if (usesFilter())
                for (const TranslucentShadowMap& map : maps_) m[k] += map.localExitance(glm::dvec3(points[k]), filter_);
            out[vertexOrder_[begin + k]] = glm::vec3(m[k]);
        }
    });
    if (gather) {
        size_t bytes = 0;
        for (const GroupTerms& t : vertexTerms_) bytes += t.byteSize();
        if (bytes > kVertexTermsBudget) {
            vertexTerms_ = std::vector<GroupTerms>();
            vertexTermsOverBudget_ = true;
        } else {
            vertexTermsValid_ = true;
        }
    }
    return out;
}

VertexInterpolation vertexInterpolation(const GBuffer& g, const TriangleMesh& mesh, double eta,
                                        FresnelModel fresnel) {
    VertexInterpolation v;
    v.width = g.width;
    v.height = g.height;
    for (size_t i = 0; i < g.pixels.size(); ++i) {
        const GBufferPixel& p = g.pixels[i];
        if (!p.hit) continue;
        const double cosO = glm::dot(glm::dvec3(p.normal), glm::dvec3(p.toViewer));
        v.pixel.push_back(uint32_t(i));
        v.vertices.push_back(mesh.triangles[p.triangle]);
        v.barycentric.push_back(p.barycentric);
        v.transmittanceOverPi.push_back(
            float(outgoingTransmittance(fresnel, eta, std::max(0.0, cosO)) / std::numbers::pi));
    }
    return v;
}

Image TextureSpaceRenderer::shadeVertices(const VertexInterpolation& view, const std::vector<glm::vec3>& m) const {
    if (m.size() != mesh_->vertexCount()) throw Error("shadeVertices", "one exitance per mesh vertex expected");
    Image out(view.width, view.height, 4, 0.0f);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, view.pixel.size(), 4096), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t k = r.begin(); k != r.end(); ++k) {
            const glm::uvec3 t = view.vertices[k];
            const glm::vec3 b = view.barycentric[k];
            const glm::vec3 e = view.transmittanceOverPi[k] * (b.x * m[t.x] + b.y * m[t.y] + b.z * m[t.z]);
            float* o = &out.pixels[size_t(view.pixel[k]) * 4];
            o[0] = e.x;
            o[1] = e.y;
            o[2] = e.z;
            o[3] = 1.0f;
        }
    });
    return out;
}

VertexInterpolation TextureSpaceRenderer::interpolation(const GBuffer& g) const {
    return vertexInterpolation(g, *mesh_, material_.eta, options_.fresnel);
}

Image TextureSpaceRenderer::renderPerVertex(const GBuffer& g) const {
    return shadeVertices(interpolation(g), vertexExitance());
}

}  // namespace prt
