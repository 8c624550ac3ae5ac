#include "relight/prt/editable_transport.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <emmintrin.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>

#include "common/blocked_vectors.h"
#include "common/error.h"
#include "common/material_edit.h"
#include "common/transport_params.h"
#include "relight/prt/relight_kernel.h"

namespace prt {

namespace {

constexpr double kQuantMax = 32767.0;
constexpr double kRoundToInteger = 6755399441055744.0;  // 1.5 2^52

RadialBasis storedBasis(const TransportFile& file, const std::string& path) {
    if (!file.radialBasis)
        throw Error(path, "has no radial basis: it was not made with prt-precompute --editable, so its material "
                          "and size are fixed");
    return RadialBasis(file.radialBasis->range, file.radialBasis->tables);
}

// A profile component's vectors lent, without a copy, to a one-component file as kind
// MultipleScattering (what the relight kernel takes), and given back when this goes out
// of scope, also on a throw.
class LentComponent {
public:
    LentComponent(TransportComponent& profiles, uint32_t cubemapSize, uint32_t shTerms) : owner_(profiles) {
        file.cubemapSize = cubemapSize;
        file.shTerms = shTerms;
        TransportComponent& c = file.components.emplace_back();
        c.kind = ComponentKind::MultipleScattering;
        c.vectors = std::move(profiles.vectors);
        c.blocks = std::move(profiles.blocks);
    }
    ~LentComponent() {
        owner_.vectors = std::move(file.components.front().vectors);
        owner_.blocks = std::move(file.components.front().blocks);
    }
    LentComponent(const LentComponent&) = delete;
    LentComponent& operator=(const LentComponent&) = delete;

    TransportFile file;

private:
    TransportComponent& owner_;
};

}  // namespace

EditableTransport::EditableTransport(TransportFile& file, double objectSizeMm, const std::string& path)
    : cubemapSize_(file.cubemapSize), shTerms_(file.shTerms), basis_(storedBasis(file, path)),
      objectSizeMm_(objectSizeMm) {
    if (!(objectSizeMm > 0.0) || !std::isfinite(objectSizeMm))
        throw Error(path, "the object size must be > 0 mm to edit its material");
    std::vector<TransportComponent> others;
    for (TransportComponent& c : file.components)
        (c.kind == ComponentKind::MultipleScatteringProfiles ? profiles_ : others).push_back(std::move(c));
    file.components = std::move(others);
    file.radialBasis.reset();
    std::sort(profiles_.begin(), profiles_.end(),
              [](const TransportComponent& a, const TransportComponent& b) { return a.term < b.term; });
    if (profiles_.empty() || 3 * profiles_.size() != size_t(basis_.size()))
        throw Error(path, "has " + std::to_string(profiles_.size()) + " profile components for a basis of " +
                              std::to_string(basis_.size()) + " profiles");
    if (profiles_.front().blocked()) blockUnion();
    const TransportParameters parameters = readTransportParameters(file.parameters, path);
    if (!parameters.material) throw Error(path, "names no material: the starting point of an edit is unknown");
    fileMaterial_ = *parameters.material;
    material_ = fileMaterial_;
    sizeMm_ = objectSizeMm_;
    try {
        setMaterial(fileMaterial_, objectSizeMm_);
    } catch (const Error& e) {
        throw Error(path, "its own material is outside its basis: " + std::string(e.what()));
    }
}

size_t EditableTransport::vertexCount() const { return profiles_.front().vertexCount(); }

void EditableTransport::blockUnion() {
    const size_t blocks = profiles_.front().blocks.blockCount();
    std::vector<std::vector<uint16_t>> lists(blocks);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, blocks, 256), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t k = r.begin(); k < r.end(); ++k) {
            std::vector<uint16_t>& merged = lists[k];
            for (const TransportComponent& c : profiles_)
                merged.insert(merged.end(), c.blocks.indices.begin() + c.blocks.offsets[k],
                              c.blocks.indices.begin() + c.blocks.offsets[k + 1]);
            std::sort(merged.begin(), merged.end());
            merged.erase(std::unique(merged.begin(), merged.end()), merged.end());
        }
    });
    unionOffsets_.assign(blocks + 1, 0);
    for (size_t k = 0; k < blocks; ++k) unionOffsets_[k + 1] = unionOffsets_[k] + uint32_t(lists[k].size());
    unionIndices_.resize(unionOffsets_.back());
    for (size_t k = 0; k < blocks; ++k) std::copy(lists[k].begin(), lists[k].end(), unionIndices_.begin() + unionOffsets_[k]);
}

bool EditableTransport::setMaterial(const Material& material, double sizeMm) {
    if (!(sizeMm > 0.0) || !std::isfinite(sizeMm))
        throw Error("size", "must be finite and > 0 mm, got " + formatParameter(sizeMm));
    Material m = material;
    const bool etaChanged = m.eta != fileMaterial_.eta;
    m.eta = fileMaterial_.eta;
    validateMaterial(m);
    const double factor = sizeMm / objectSizeMm_;
    weights_ = basis_.materialWeights(m, factor);  // throws outside the range
    material_ = m;
    sizeMm_ = sizeMm;
    return etaChanged;
}

bool EditableTransport::isFileMaterial() const {
    return material_.sigmaA == fileMaterial_.sigmaA && material_.sigmaSPrime == fileMaterial_.sigmaSPrime &&
           sizeMm_ == objectSizeMm_;
}

TransportComponent EditableTransport::recombine() const { return *recombineUnless({}); }

std::optional<TransportComponent> EditableTransport::recombineUnless(const std::function<bool()>& stop) const {
    if (profiles_.front().blocked()) return recombineBlocked();
    std::atomic<bool> stopped{false};
    const size_t P = profiles_.size(), V = vertexCount();
    const SparseRgbVectors& shared = profiles_.front().vectors;
    TransportComponent out;
    out.kind = ComponentKind::MultipleScattering;
    SparseRgbVectors& v = out.vectors;
    v.offsets = shared.offsets;
    v.indices = shared.indices;
    v.values.assign(shared.values.size(), 0);
    v.scales.assign(3 * V, 0.0f);
    // Per vertex, in loops the compiler vectorises: the P x 3 profile channels as
    // floats, one array each (k = 3p + profile channel); then each colour's sum over k of
    // scale x w_ck times them (k in order: deterministic on any thread count), with the
    // SH scales from the first SH index on; then the quantization.
    tbb::parallel_for(tbb::blocked_range<size_t>(0, V, 64), [&](const tbb::blocked_range<size_t>& r) {
        std::vector<float> f, rgb, converted;
        std::vector<float> haarColumn(9 * P), shColumn(9 * P);  // [k][colour]
        for (size_t vi = r.begin(); vi < r.end(); ++vi) {
            if ((vi - r.begin()) % 64 == 0 && (stopped.load(std::memory_order_relaxed) || (stop && stop()))) {
                stopped.store(true, std::memory_order_relaxed);
                return;
            }
            const uint32_t begin = shared.offsets[vi], end = shared.offsets[vi + 1];
            const size_t count = end - begin;
            f.resize(3 * P * count);
            converted.resize(3 * count);
            rgb.assign(3 * count, 0.0f);
            for (size_t p = 0; p < P; ++p) {
                const SparseRgbVectors& u = profiles_[p].vectors;
                // The Haar and the SH scales are the same unless the profiles hold 8-bit
                // Haar values.
                const std::vector<float>& shScales = u.shScales.empty() ? u.scales : u.shScales;
                for (size_t ch = 0; ch < 3; ++ch)
                    for (size_t c = 0; c < 3; ++c) {
                        const double w = weights_[c][3 * p + ch];
                        haarColumn[3 * (3 * p + ch) + c] = float(double(u.scales[3 * vi + ch]) * w);
                        shColumn[3 * (3 * p + ch) + c] = float(double(shScales[3 * vi + ch]) * w);
                    }
                // Converted in one contiguous pass, then split into the three channels.
                const int16_t* q = &u.values[3 * size_t(begin)];
                float* flat = converted.data();
                for (size_t j = 0; j < 3 * count; ++j) flat[j] = float(q[j]);
                float* f0 = &f[(3 * p) * count];
                float* f1 = f0 + count;
                float* f2 = f1 + count;
                for (size_t n = 0; n < count; ++n) {
                    f0[n] = flat[3 * n];
                    f1[n] = flat[3 * n + 1];
                    f2[n] = flat[3 * n + 2];
                }
            }
            // The SH indices are the last ones (indices increase).
            const SparseRgbVectors& u0 = profiles_.front().vectors;
            size_t split = count;
            while (split > 0 && u0.indices[begin + split - 1] >= u0.shFrom) --split;
            for (size_t c = 0; c < 3; ++c) {
                float* o = &rgb[c * count];
                for (size_t p = 0; p < P; ++p) {  // one profile component's three channels a pass
                    const float* f0 = &f[(3 * p) * count];
                    const float *f1 = f0 + count, *f2 = f1 + count;
                    const float* h = &haarColumn[9 * p + c];
                    const float* sh = &shColumn[9 * p + c];
                    for (size_t n = 0; n < split; ++n) o[n] += h[0] * f0[n] + h[3] * f1[n] + h[6] * f2[n];
                    for (size_t n = split; n < count; ++n) o[n] += sh[0] * f0[n] + sh[3] * f1[n] + sh[6] * f2[n];
                }
            }
            // Quantized as SparseRgbVectors::appendVertex does: nearbyint(x / scale) in the
            // default rounding mode, written as the addition and subtraction of 1.5 2^52
            // (exact for |x| < 2^51, here |x| <= 32767), which the compiler inlines where
            // nearbyint is a library call.
            for (size_t c = 0; c < 3; ++c) {
                const float* o = &rgb[c * count];
                // Four lanes of maxima (a scalar max waits on the previous one).
                const __m128 absMask = _mm_castsi128_ps(_mm_set1_epi32(0x7fffffff));
                __m128 m4 = _mm_setzero_ps();
                size_t n4 = 0;
                for (; n4 + 4 <= count; n4 += 4) m4 = _mm_max_ps(m4, _mm_and_ps(_mm_loadu_ps(o + n4), absMask));
                alignas(16) float lanes[4];
                _mm_store_ps(lanes, m4);
                float maxAbs = std::max(std::max(lanes[0], lanes[1]), std::max(lanes[2], lanes[3]));
                for (; n4 < count; ++n4) maxAbs = std::max(maxAbs, std::fabs(o[n4]));
                const float scale = double(maxAbs) < kQuantMax * double(std::numeric_limits<float>::min())
                                        ? 0.0f
                                        : float(double(maxAbs) / kQuantMax);
                v.scales[3 * vi + c] = scale;
                int16_t* dst = &v.values[3 * size_t(begin) + c];
                if (!(scale > 0.0f)) continue;  // the values stay 0
                const double d = double(scale);
                for (size_t n = 0; n < count; ++n) {
                    const double x = (double(o[n]) / d + kRoundToInteger) - kRoundToInteger;
                    dst[3 * n] = int16_t(std::clamp(x, -kQuantMax, kQuantMax));
                }
            }
        }
    });
    if (stopped.load()) return std::nullopt;
    return out;
}

TransportComponent EditableTransport::recombineBlocked() const {
    const size_t P = profiles_.size();
    const BlockedRgbVectors& first = profiles_.front().blocks;
    const size_t blocks = first.blockCount();
    TransportComponent out;
    out.kind = ComponentKind::MultipleScattering;
    BlockedRgbVectors& b = out.blocks;
    b.vertices = first.vertices;
    b.order = first.order;
    b.shFrom = first.shFrom;
    b.slotOf = first.slotOf;
    b.offsets = unionOffsets_;
    b.indices = unionIndices_;
    b.values.assign(b.indices.size() * kBlockValuesPerIndex, 0);
    b.scales.assign(first.scales.size(), 0.0f);
    b.shScales.assign(first.shScales.size(), 0.0f);
    // Per block: the recombined values in quantizeBlock's layout, (n * lanes + lane) * 3
    // + c, then quantized into the block's own slots (deterministic on any thread count).
    tbb::parallel_for(tbb::blocked_range<size_t>(0, blocks, 16), [&](const tbb::blocked_range<size_t>& r) {
        std::vector<float> rgb;
        float noShScales[kBlockValuesPerIndex];
        for (size_t k = r.begin(); k < r.end(); ++k) {
            const uint32_t begin = b.offsets[k], end = b.offsets[k + 1], shBegin = b.shBegin(k);
            const uint32_t lanes = uint32_t(std::min<size_t>(kVertexBlock, b.vertexCount() - k * kVertexBlock));
            rgb.assign(size_t(end - begin) * lanes * 3, 0.0f);
            for (size_t p = 0; p < P; ++p) {
                const BlockedRgbVectors& u = profiles_[p].blocks;
                const uint32_t uBegin = u.offsets[k], uEnd = u.offsets[k + 1], uShBegin = u.shBegin(k);
                for (size_t ch = 0; ch < 3; ++ch) {
                    const float w[3] = {float(weights_[0][3 * p + ch]), float(weights_[1][3 * p + ch]),
                                        float(weights_[2][3 * p + ch])};
                    // The profile's list is a subset of the union: one merge.
                    uint32_t at = begin;
                    for (uint32_t n = uBegin; n < uEnd; ++n) {
                        while (b.indices[at] < u.indices[n]) ++at;
                        const float* scales = &(n < uShBegin ? u.scales : u.shScales)[k * kBlockValuesPerIndex + 16 * ch];
                        const int8_t* q = &u.values[n * kBlockValuesPerIndex + 16 * ch];
                        float* dst = &rgb[size_t(at - begin) * lanes * 3];
                        for (uint32_t lane = 0; lane < lanes; ++lane) {
                            const float x = float(q[lane]) * scales[lane];
                            for (size_t c = 0; c < 3; ++c) dst[3 * lane + c] += x * w[c];
                        }
                    }
                }
            }
            quantizeBlock(rgb.data(), end - begin, shBegin - begin, lanes, &b.values[begin * kBlockValuesPerIndex],
                          &b.scales[k * kBlockValuesPerIndex],
                          b.shScales.empty() ? noShScales : &b.shScales[k * kBlockValuesPerIndex]);
        }
    });
    return out;
}

void EditableTransport::projectLight(const LightVector& light) {
    const size_t V = vertexCount(), J = size_t(basis_.size());
    // Built apart and swapped in at the end: a light the kernel refuses leaves the
    // previous projection as it was.
    std::vector<float> projected(V * J * 3, 0.0f);
    // Per light channel c a grey light (L_c in all three channels): the relight kernel
    // then gives U_{3p+ch} . L_c in channel ch of component p.
    LightVector grey = light;
    VertexRadiance out;
    const ScatteringComponents ms{.multipleScattering = true, .singleScattering = false};
    for (size_t p = 0; p < profiles_.size(); ++p) {
        const LentComponent lent(profiles_[p], cubemapSize_, shTerms_);
        const TransportFile& file = lent.file;
        for (int c = 0; c < 3; ++c) {
            for (size_t k = 0; k < light.rgb.size() / 3; ++k)
                grey.rgb[3 * k] = grey.rgb[3 * k + 1] = grey.rgb[3 * k + 2] = light.rgb[3 * k + size_t(c)];
            for (size_t k = 0; k < light.sh.size() / 3; ++k)
                grey.sh[3 * k] = grey.sh[3 * k + 1] = grey.sh[3 * k + 2] = light.sh[3 * k + size_t(c)];
            relightVertices(file, grey, ms, out);
            for (size_t v = 0; v < V; ++v)
                for (int ch = 0; ch < 3; ++ch) projected[(v * J + 3 * p + size_t(ch)) * 3 + size_t(c)] = out.diffuse[v][ch];
        }
    }
    projected_.swap(projected);
}

void EditableTransport::relightProjected(std::vector<glm::vec3>& diffuse) const {
    if (projected_.empty()) throw Error("editable transport", "no light projected (projectLight first)");
    const size_t V = vertexCount(), J = size_t(basis_.size());
    diffuse.resize(V);
    float w[3][64];
    for (int c = 0; c < 3; ++c)
        for (size_t j = 0; j < J; ++j) w[c][j] = float(weights_[size_t(c)][j]);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, V, 1024), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t v = r.begin(); v < r.end(); ++v) {
            const float* d = &projected_[v * J * 3];
            float s[3] = {0.0f, 0.0f, 0.0f};
            for (size_t j = 0; j < J; ++j)
                for (int c = 0; c < 3; ++c) s[c] += w[c][j] * d[3 * j + size_t(c)];
            diffuse[v] = glm::vec3(s[0], s[1], s[2]);
        }
    });
}

}  // namespace prt
