#include "relight/pointlight/texture_space_sampling.h"

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
    switch (options_.mode) {
        case TextureSpaceMode::Sampling: sampleKernel_ = diffusionTable(material_, rMax); break;
        case TextureSpaceMode::Hybrid:
        case TextureSpaceMode::Global: sampleKernel_ = globalDiffusionTable(material_, split_, rMax); break;
        case TextureSpaceMode::Local: break;
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
    px_.clear(); py_.clear(); pz_.clear(); w_.clear();
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
        const glm::vec3 p = atlas_->samples.positions[s];
        px_.push_back(p.x);
        py_.push_back(p.y);
        pz_.push_back(p.z);
        w_.push_back(glm::vec4(glm::vec3(glm::dvec3(f) * scale), 0.0f));
        k = e;
    }
}

void TextureSpaceRenderer::sampleSums(const glm::vec3* points, size_t count, glm::dvec3* out) const {
    // Tiled: one block of samples (kBlock x 24 bytes, in L1) for all the points, then
    // the next block. Per point and block: distances and table positions in loops the
    // compiler vectorises, then the table reads and the weighted sums (float within a
    // block, double across blocks: the same order for one point or many).
    constexpr size_t kBlock = 64;
    float r2[kBlock], t[kBlock];
    for (size_t p = 0; p < count; ++p) out[p] = glm::dvec3(0.0);
    const size_t n = px_.size();
    for (size_t begin = 0; begin < n; begin += kBlock) {
        const size_t block = std::min(kBlock, n - begin);
        const float *px = &px_[begin], *py = &py_[begin], *pz = &pz_[begin];
        const glm::vec4* w = &w_[begin];
        const float rMax2 = sampleKernel_.rMax2();
        for (size_t p = 0; p < count; ++p) {
            const float x0 = points[p].x, y0 = points[p].y, z0 = points[p].z;
            for (size_t j = 0; j < block; ++j) {
                const float dx = x0 - px[j], dy = y0 - py[j], dz = z0 - pz[j];
                r2[j] = dx * dx + dy * dy + dz * dz;
            }
            for (size_t j = 0; j < block; ++j) t[j] = sampleKernel_.position(r2[j]);
            __m128 acc = _mm_setzero_ps();  // RGB in one SSE register
            for (size_t j = 0; j < block; ++j)
                if (r2[j] < rMax2) acc = _mm_add_ps(acc, _mm_mul_ps(_mm_loadu_ps(&w[j].x), sampleKernel_.atSse(t[j])));
            alignas(16) float sum[4];
            _mm_store_ps(sum, acc);
            out[p] += glm::dvec3(sum[0], sum[1], sum[2]);
        }
    }
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
    constexpr size_t kChunk = 64;  // vertices sharing each block of samples
    tbb::parallel_for(size_t(0), (nv + kChunk - 1) / kChunk, [&](size_t c) {
        const size_t begin = c * kChunk, count = std::min(kChunk, nv - begin);
        glm::dvec3 m[kChunk];
        const glm::vec3* points = &orderedPositions_[begin];
        if (usesSamples()) {
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
    return out;
}

Image TextureSpaceRenderer::renderPerVertex(const GBuffer& g) const {
    const std::vector<glm::vec3> m = vertexExitance();
    return compose(g, Image(), glm::dmat3(1.0), [&](const GBufferPixel& p) -> glm::vec3 {
        if (!p.hit) return glm::vec3(0.0f);
        const double cosO = glm::dot(glm::dvec3(p.normal), glm::dvec3(p.toViewer));
        const double fo = outgoingTransmittance(options_.fresnel, material_.eta, std::max(0.0, cosO));
        if (fo == 0.0) return glm::vec3(0.0f);
        const glm::uvec3 t = mesh_->triangles[p.triangle];
        const glm::vec3 e = p.barycentric.x * m[t.x] + p.barycentric.y * m[t.y] + p.barycentric.z * m[t.z];
        return float(fo / std::numbers::pi) * e;
    });
}

}  // namespace prt
