#include "relight/prt/editable_transport.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
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

TransportComponent EditableTransport::recombine() const {
    if (profiles_.front().blocked()) return recombineBlocked();
    const size_t P = profiles_.size(), V = vertexCount();
    const SparseRgbVectors& shared = profiles_.front().vectors;
    TransportComponent out;
    out.kind = ComponentKind::MultipleScattering;
    SparseRgbVectors& v = out.vectors;
    v.offsets = shared.offsets;
    v.indices = shared.indices;
    v.values.assign(shared.values.size(), 0);
    v.scales.assign(3 * V, 0.0f);
    // w[c][j] as floats, the order of the sums fixed: deterministic on any thread count.
    tbb::parallel_for(tbb::blocked_range<size_t>(0, V, 64), [&](const tbb::blocked_range<size_t>& r) {
        std::vector<float> rgb;
        for (size_t vi = r.begin(); vi < r.end(); ++vi) {
            const uint32_t begin = shared.offsets[vi], end = shared.offsets[vi + 1];
            rgb.assign(3 * size_t(end - begin), 0.0f);
            for (size_t p = 0; p < P; ++p) {
                const SparseRgbVectors& u = profiles_[p].vectors;
                // [profile channel][colour] = scale * w, for the Haar and the SH scales
                // (the same unless the profiles hold 8-bit Haar values).
                float scaled[3][3], scaledSh[3][3];
                const std::vector<float>& shScales = u.shScales.empty() ? u.scales : u.shScales;
                for (int ch = 0; ch < 3; ++ch)
                    for (int c = 0; c < 3; ++c) {
                        const double w = weights_[size_t(c)][3 * p + size_t(ch)];
                        scaled[ch][c] = float(double(u.scales[3 * vi + size_t(ch)]) * w);
                        scaledSh[ch][c] = float(double(shScales[3 * vi + size_t(ch)]) * w);
                    }
                // The SH indices are the last ones (indices increase): two plain loops.
                uint32_t split = end;
                while (split > begin && u.indices[split - 1] >= u.shFrom) --split;
                auto accumulate = [&](uint32_t from, uint32_t to, const float(&sc)[3][3]) {
                    for (uint32_t n = from; n < to; ++n) {
                        float* dst = &rgb[3 * size_t(n - begin)];
                        const int16_t* q = &u.values[3 * size_t(n)];
                        for (int ch = 0; ch < 3; ++ch)
                            for (int c = 0; c < 3; ++c) dst[c] += float(q[ch]) * sc[ch][c];
                    }
                };
                accumulate(begin, split, scaled);
                accumulate(split, end, scaledSh);
            }
            // Quantized as SparseRgbVectors::appendVertex does.
            for (int c = 0; c < 3; ++c) {
                float maxAbs = 0.0f;
                for (uint32_t n = begin; n < end; ++n) maxAbs = std::max(maxAbs, std::fabs(rgb[3 * size_t(n - begin) + size_t(c)]));
                const float scale = double(maxAbs) < kQuantMax * double(std::numeric_limits<float>::min())
                                        ? 0.0f
                                        : float(double(maxAbs) / kQuantMax);
                v.scales[3 * vi + size_t(c)] = scale;
                for (uint32_t n = begin; n < end; ++n) {
                    int q = 0;
                    if (scale > 0.0f) {
                        const double x = std::nearbyint(double(rgb[3 * size_t(n - begin) + size_t(c)]) / double(scale));
                        q = int(std::clamp(x, -kQuantMax, kQuantMax));
                    }
                    v.values[3 * size_t(n) + size_t(c)] = int16_t(q);
                }
            }
        }
    });
    return out;
}

TransportComponent EditableTransport::recombineBlocked() const {
    const size_t P = profiles_.size();
    const BlockedRgbVectors& shared = profiles_.front().blocks;
    const size_t blocks = shared.blockCount();
    TransportComponent out;
    out.kind = ComponentKind::MultipleScattering;
    BlockedRgbVectors& b = out.blocks;
    b.vertices = shared.vertices;
    b.order = shared.order;
    b.offsets = shared.offsets;
    b.indices = shared.indices;
    b.shFrom = shared.shFrom;
    b.slotOf = shared.slotOf;
    b.values.assign(shared.values.size(), 0);
    b.scales.assign(shared.scales.size(), 0.0f);
    b.shScales.assign(shared.shScales.size(), 0.0f);
    // Per block: the recombined values in quantizeBlock's layout, (n * lanes + lane) * 3
    // + c, then quantized into the block's own slots (deterministic on any thread count).
    tbb::parallel_for(tbb::blocked_range<size_t>(0, blocks, 16), [&](const tbb::blocked_range<size_t>& r) {
        std::vector<float> rgb;
        float noShScales[kBlockValuesPerIndex];
        for (size_t k = r.begin(); k < r.end(); ++k) {
            const uint32_t begin = shared.offsets[k], end = shared.offsets[k + 1], shBegin = shared.shBegin(k);
            const uint32_t lanes = uint32_t(std::min<size_t>(kVertexBlock, shared.vertexCount() - k * kVertexBlock));
            rgb.assign(size_t(end - begin) * lanes * 3, 0.0f);
            for (size_t p = 0; p < P; ++p) {
                const BlockedRgbVectors& u = profiles_[p].blocks;
                for (size_t ch = 0; ch < 3; ++ch) {
                    const float w[3] = {float(weights_[0][3 * p + ch]), float(weights_[1][3 * p + ch]),
                                        float(weights_[2][3 * p + ch])};
                    for (uint32_t n = begin; n < end; ++n) {
                        const float* scales = &(n < shBegin ? u.scales : u.shScales)[k * kBlockValuesPerIndex + 16 * ch];
                        const int8_t* q = &u.values[n * kBlockValuesPerIndex + 16 * ch];
                        float* dst = &rgb[size_t(n - begin) * lanes * 3];
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
