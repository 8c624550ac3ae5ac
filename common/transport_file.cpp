// The in-memory transport file: SparseRgbVectors' quantization, the lookups of
// TransportFile and TransportFileInfo, and the validation of a TransportFile that the
// writer applies before saving and the reader after loading. The readers, the writer
// and describe() live in transport_file_{read,write,describe}.cpp.

#include "common/transport_file.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <limits>
#include <numeric>
#include <set>
#include <stdexcept>

#include "common/error.h"
#include "common/transport_file_format.h"

namespace prt {

namespace transport_format {

namespace {

std::string indexLimitText(uint32_t cubemapSize, uint32_t shTerms) {
    return "(6 x " + u64(cubemapSize) + " x " + u64(cubemapSize) +
           (shTerms ? " + " + u64(shTerms) + " SH terms)" : ")");
}

std::string checkViewMaps(const ViewMaps& m) {
    if (m.size < 1 || uint32_t(m.size) > kMaxViewMapSize)
        return "view map size " + std::to_string(m.size) + " outside 1.." +
               std::to_string(kMaxViewMapSize);
    if (m.terms < 1 || uint32_t(m.terms) > kMaxViewMapTerms)
        return "view map term count " + std::to_string(m.terms) + " outside 1.." +
               std::to_string(kMaxViewMapTerms);
    const uint64_t expected = uint64_t(m.terms) * 6 * uint64_t(m.size) * uint64_t(m.size);
    if (m.data.size() != expected)
        return "view maps hold " + u64(m.data.size()) + " floats, expected " + u64(expected) +
               " (terms x 6 x size x size)";
    for (size_t i = 0; i < m.data.size(); ++i)
        if (!std::isfinite(m.data[i])) return "view map value " + u64(i) + " is not finite";
    return {};
}

// The profile components (each already checked alone) hold one index list: equal
// offsets and indices (per vertex), or one block order and SH split with index lists
// that may differ per block (blocked: nested lists, format version 7). Names the
// first vertex where a per-vertex list differs from the first.
std::string checkSharedIndices(const std::vector<const TransportComponent*>& profiles) {
    if (profiles.empty()) return {};
    const TransportComponent& first = *profiles.front();
    const SparseRgbVectors& a = first.vectors;
    for (size_t i = 1; i < profiles.size(); ++i) {
        const std::string names = "'" + componentName(profiles[i]->kind, profiles[i]->term) + "' and '" +
                                  componentName(first.kind, first.term) + "'";
        const std::string why = " (the profile components share one index list)";
        if (profiles[i]->blocked() != first.blocked())
            return names + " are not both blocked (the profile components are all per vertex or all blocked)";
        if (first.blocked()) {
            // Blocks: one lane order for all of them; the lists are each its own.
            const BlockedRgbVectors &x = first.blocks, &y = profiles[i]->blocks;
            const std::string blockWhy = " (the profile components share one block order)";
            if (x.order != y.order) return names + " have different block orders" + blockWhy;
            if (x.shFrom != y.shFrom) return names + " differ in SH scales" + blockWhy;
            continue;
        }
        const SparseRgbVectors& b = profiles[i]->vectors;
        if (a.offsets == b.offsets && a.indices == b.indices) continue;
        // Both passed checkVectors for the same vertex count: offsets are monotone.
        for (size_t v = 0; v + 1 < a.offsets.size(); ++v) {
            const uint32_t countA = a.offsets[v + 1] - a.offsets[v], countB = b.offsets[v + 1] - b.offsets[v];
            if (countA != countB)
                return names + " differ at vertex " + u64(v) + ": " + u64(countB) + " and " + u64(countA) +
                       " coefficients" + why;
            if (!std::equal(a.indices.begin() + a.offsets[v], a.indices.begin() + a.offsets[v + 1],
                            b.indices.begin() + b.offsets[v]))
                return names + " differ at vertex " + u64(v) + ": different coefficient indices" + why;
        }
        return names + " have different index lists" + why;
    }
    return {};
}

}  // namespace

bool blockedProfileListsDiffer(const TransportFile& f) {
    const BlockedRgbVectors* first = nullptr;
    for (const TransportComponent& c : f.components) {
        if (c.kind != ComponentKind::MultipleScatteringProfiles || !c.blocked()) continue;
        if (!first) {
            first = &c.blocks;
        } else if (c.blocks.offsets != first->offsets || c.blocks.indices != first->indices) {
            return true;
        }
    }
    return false;
}

std::string checkProfileTerms(const std::vector<uint32_t>& terms, int basisSize) {
    if (basisSize < 0) {
        if (terms.empty()) return {};
        return "multiple-scattering profile components present but no radial basis";
    }
    if (terms.empty()) return "radial basis present but no multiple-scattering profile components";
    const std::set<uint32_t> sorted(terms.begin(), terms.end());
    const uint64_t count = terms.size();
    if (uint64_t(basisSize) != kProfilesPerComponent * count)
        return "the radial basis has " + std::to_string(basisSize) + " profiles but there are " + u64(count) +
               " profile components of 3 (J must be 3 x their count)";
    if (sorted.size() != count || *sorted.rbegin() != count - 1)
        return "multiple-scattering profile components must be terms 0.." + u64(count - 1) + ", found " +
               u64(sorted.size()) + " distinct with largest term " + u64(*sorted.rbegin());
    return {};
}

std::string checkRadialBasis(const StoredRadialBasis& b) {
    if (!validRadialConstruction(uint32_t(b.tables.construction)))
        return "radial basis: construction " + u64(uint32_t(b.tables.construction)) + " is not 0, 1 or 2";
    try {
        RadialBasis basis(b.range, b.tables);
    } catch (const Error& e) {
        return e.what();
    }
    return {};
}

std::string checkVectors(const SparseRgbVectors& s, uint64_t vertices, uint32_t cubemapSize,
                         uint32_t shTerms) {
    const uint64_t indexLimit = uint64_t(6) * cubemapSize * cubemapSize + shTerms;
    if (s.offsets.size() != vertices + 1)
        return "has " + u64(s.offsets.size()) + " offsets, expected " + u64(vertices + 1) +
               " (vertex count + 1)";
    if (s.offsets[0] != 0) return "offsets[0] is " + u64(s.offsets[0]) + ", not 0";
    if (s.offsets[vertices] != s.indices.size())
        return "offsets end at " + u64(s.offsets[vertices]) + " but there are " +
               u64(s.indices.size()) + " coefficient indices";
    if (s.values.size() != 3 * s.indices.size())
        return "has " + u64(s.values.size()) + " values, expected 3 per coefficient (" +
               u64(3 * s.indices.size()) + ")";
    if (s.scales.size() != 3 * vertices)
        return "has " + u64(s.scales.size()) + " scales, expected 3 per vertex (" +
               u64(3 * vertices) + ")";
    const bool eightBit = s.haarBits == 8;
    if (s.haarBits != 16 && !eightBit) return "Haar values of " + u64(s.haarBits) + " bits (16 or 8)";
    if (!eightBit && (s.shFrom != UINT32_MAX || !s.shScales.empty()))
        return "SH scales on 16-bit vectors (only 8-bit Haar values have them)";
    const bool shScales = eightBit && s.shFrom != UINT32_MAX;
    if (shScales && (shTerms == 0 || s.shFrom != 6 * cubemapSize * cubemapSize))
        return "SH scales from index " + u64(s.shFrom) + " but the SH part " +
               (shTerms == 0 ? std::string("is absent") : "starts at " + u64(6 * cubemapSize * cubemapSize));
    if (s.shScales.size() != (shScales ? 3 * vertices : 0))
        return "has " + u64(s.shScales.size()) + " SH scales, expected " + u64(shScales ? 3 * vertices : 0);
    // Monotone offsets from 0 to the coefficient count keep every range in bounds.
    for (uint64_t v = 0; v < vertices; ++v)
        if (s.offsets[v + 1] < s.offsets[v])
            return "offsets decrease at vertex " + u64(v) + " (" + u64(s.offsets[v]) +
                   " then " + u64(s.offsets[v + 1]) + ")";
    for (uint64_t v = 0; v < vertices; ++v) {
        const uint32_t begin = s.offsets[v], end = s.offsets[v + 1];
        for (uint32_t n = begin; n < end; ++n) {
            if (s.indices[n] >= indexLimit)
                return "vertex " + u64(v) + ": coefficient index " + u64(s.indices[n]) +
                       " >= " + u64(indexLimit) + " " + indexLimitText(cubemapSize, shTerms);
            if (n > begin && s.indices[n] <= s.indices[n - 1])
                return "vertex " + u64(v) + ": coefficient indices not strictly increasing (" +
                       u64(s.indices[n - 1]) + " then " + u64(s.indices[n]) + ")";
        }
        for (int c = 0; c < 3; ++c) {
            const float scale = s.scales[3 * v + c];
            if (!std::isfinite(scale) || scale < 0.0f)
                return "vertex " + u64(v) + ": scale of channel " + std::to_string(c) +
                       " is not a finite non-negative number";
            if (shScales && (!std::isfinite(s.shScales[3 * v + c]) || s.shScales[3 * v + c] < 0.0f))
                return "vertex " + u64(v) + ": SH scale of channel " + std::to_string(c) +
                       " is not a finite non-negative number";
        }
        if (eightBit)
            for (uint32_t n = begin; n < end; ++n)
                for (int c = 0; c < 3; ++c)
                    if (s.indices[n] < s.shFrom && std::abs(int(s.values[3 * size_t(n) + c])) > kEightBitLevels)
                        return "vertex " + u64(v) + ": 8-bit Haar value " + std::to_string(s.values[3 * size_t(n) + c]) +
                               " outside -127..127";
    }
    return {};
}

std::string checkBlocked(const BlockedRgbVectors& b, uint64_t vertices, uint32_t cubemapSize,
                         uint32_t shTerms) {
    if (b.vertices != vertices)
        return "has " + u64(b.vertices) + " blocked vertices, expected " + u64(vertices);
    if (vertices == 0) return "a blocked component has no vertices";
    // Lane numbers 16 b + lane (and slotOf's "no lane" marker UINT32_MAX) are u32.
    if (vertices > UINT32_MAX)
        return "has " + u64(vertices) + " vertices, a blocked component holds at most 2^32 - 1";
    // checkBlockedVectors walks each block's index range without bounding it first, so
    // the offsets are checked to be monotone up to the index count here.
    const uint64_t blocks = blockCountOf(vertices);
    if (b.offsets.size() != blocks + 1)
        return "has " + u64(b.offsets.size()) + " block offsets, expected " + u64(blocks + 1) +
               " (block count + 1)";
    if (b.offsets[0] != 0) return "block offsets[0] is " + u64(b.offsets[0]) + ", not 0";
    if (b.offsets[blocks] != b.indices.size())
        return "block offsets end at " + u64(b.offsets[blocks]) + " but there are " +
               u64(b.indices.size()) + " indices";
    for (uint64_t k = 0; k < blocks; ++k)
        if (b.offsets[k + 1] < b.offsets[k])
            return "block offsets decrease at block " + u64(k) + " (" + u64(b.offsets[k]) +
                   " then " + u64(b.offsets[k + 1]) + ")";
    // Also the padding lanes (zero values and scales, as appendBlock writes them, so
    // equal data has equal bytes).
    return checkBlockedVectors(b, 6 * cubemapSize * cubemapSize + shTerms);
}

std::string checkFile(const TransportFile& f) {
    if (f.cubemapSize < 1 || f.cubemapSize > kMaxCubemapSize ||
        !std::has_single_bit(f.cubemapSize))
        return "cubemap size " + u64(f.cubemapSize) + " is not a power of two in 1..64";
    if (!validShTermCount(f.shTerms)) return "SH term count " + u64(f.shTerms) + " is not " + kShTermCounts;
    if (f.cubemapSize < uint32_t(minShCubemapSize(int(f.shTerms))))
        return u64(f.shTerms) + " SH terms on a 6 x " + u64(f.cubemapSize) + " x " + u64(f.cubemapSize) +
               " cubemap (they are not independent there)";
    if (f.mesh.vertexCount == 0) return "mesh fingerprint has zero vertices";
    if (f.mesh.vertexCount > kMaxVertices)
        return "mesh fingerprint has " + u64(f.mesh.vertexCount) + " vertices (limit 2^40)";
    if (!std::isfinite(f.mmPerUnit) || f.mmPerUnit <= 0.0)
        return "mm per unit " + formatDouble(f.mmPerUnit) + " is not a positive finite number";
    std::set<std::string> keys;
    for (const auto& [key, value] : f.parameters) {
        if (key.empty()) return "a parameter has an empty key";
        if (key.size() > UINT32_MAX || value.size() > UINT32_MAX)
            return "parameter '" + key.substr(0, 64) + "' is too long";
        if (!keys.insert(key).second) return "parameter '" + key + "' appears twice";
    }
    if (f.components.empty()) return "no components";
    if (f.components.size() > UINT32_MAX) return "too many components";
    std::set<std::pair<uint32_t, uint32_t>> seen;
    std::set<uint32_t> terms;
    std::vector<uint32_t> profileTerms;
    std::vector<const TransportComponent*> profiles;
    for (size_t i = 0; i < f.components.size(); ++i) {
        const TransportComponent& c = f.components[i];
        const std::string name = "component " + u64(i + 1) + " (" +
                                 (validKind(uint32_t(c.kind)) ? componentName(c.kind, c.term)
                                                              : std::string("unknown kind")) +
                                 ")";
        if (!validKind(uint32_t(c.kind)))
            return name + ": kind " + u64(uint32_t(c.kind)) + " is not 1, 2, 3 or 4";
        if (!hasTerms(c.kind) && c.term != 0)
            return name + ": term " + u64(c.term) + " on a component that has no terms";
        if (!seen.insert({uint32_t(c.kind), c.term}).second) return name + ": appears twice";
        if (c.kind == ComponentKind::SingleScatteringTerm) terms.insert(c.term);
        if (c.kind == ComponentKind::MultipleScatteringProfiles) {
            profileTerms.push_back(c.term);
            profiles.push_back(&c);
        }
        if (c.vertexCount() != f.mesh.vertexCount)
            return name + ": has " + u64(c.vertexCount()) +
                   " vertices, the mesh fingerprint has " + u64(f.mesh.vertexCount);
        // Exactly one encoding holds data: the other would be dropped by the writer.
        const SparseRgbVectors& v = c.vectors;
        const BlockedRgbVectors& b = c.blocks;
        if (c.blocked() && (v.vertexCount() != 0 || !v.indices.empty() || !v.values.empty() ||
                            !v.scales.empty()))
            return name + ": a blocked component also holds per-vertex vectors";
        if (!c.blocked() && (!b.order.empty() || b.offsets.size() > 1 || !b.indices.empty() ||
                             !b.values.empty() || !b.scales.empty() || !b.shScales.empty() ||
                             b.shFrom != UINT32_MAX))
            return name + ": blocked arrays without blocked vertices";
        // SH scales start at the SH part (the file stores a flag, not the index).
        if (c.blocked() && b.shFrom != UINT32_MAX &&
            (f.shTerms == 0 || b.shFrom != 6 * f.cubemapSize * f.cubemapSize))
            return name + ": SH scales from index " + u64(b.shFrom) + " but the SH part " +
                   (f.shTerms == 0 ? std::string("is absent") : "starts at " + u64(6 * f.cubemapSize * f.cubemapSize));
        // 8-bit Haar values are the profile components' encoding (version 6 builds on 5).
        if (!c.blocked() && v.haarBits == 8 && c.kind != ComponentKind::MultipleScatteringProfiles)
            return name + ": 8-bit Haar values on a component that is not a radial profile";
        std::string reason = c.blocked() ? checkBlocked(b, f.mesh.vertexCount, f.cubemapSize, f.shTerms)
                                         : checkVectors(v, f.mesh.vertexCount, f.cubemapSize, f.shTerms);
        if (!reason.empty()) return name + ": " + reason;
    }
    if (terms.empty()) {
        if (f.viewMaps) return "view maps present but no single-scattering term components";
    } else {
        if (!f.viewMaps) return "single-scattering term components present but no view maps";
        std::string reason = checkViewMaps(*f.viewMaps);
        if (!reason.empty()) return reason;
        if (terms.size() != size_t(f.viewMaps->terms) || *terms.rbegin() != terms.size() - 1)
            return "single-scattering term components must be terms 0.." +
                   std::to_string(f.viewMaps->terms - 1) + " (one per view map), found " +
                   u64(terms.size()) + " with largest term " + u64(*terms.rbegin());
    }
    std::string reason = checkProfileTerms(profileTerms, f.radialBasis ? f.radialBasis->tables.size : -1);
    if (!reason.empty()) return reason;
    reason = checkSharedIndices(profiles);
    if (!reason.empty()) return reason;
    if (f.radialBasis) return checkRadialBasis(*f.radialBasis);
    return {};
}

}  // namespace transport_format

using namespace transport_format;

namespace {

constexpr int kQuantMax = 32767;  // SparseRgbVectors: int16 values in [-32767, 32767]

std::string findParameter(const std::vector<std::pair<std::string, std::string>>& parameters,
                          const std::string& key) {
    for (const auto& [k, v] : parameters)
        if (k == key) return v;
    return {};
}

bool containsParameter(const std::vector<std::pair<std::string, std::string>>& parameters,
                       const std::string& key) {
    return std::any_of(parameters.begin(), parameters.end(),
                       [&](const auto& p) { return p.first == key; });
}

}  // namespace

std::string componentName(ComponentKind kind, uint32_t term) {
    switch (kind) {
        case ComponentKind::MultipleScattering: return "multiple scattering";
        case ComponentKind::SingleScatteringIsotropic: return "single scattering (isotropic)";
        case ComponentKind::SingleScatteringTerm:
            return "single scattering term " + std::to_string(term);
        case ComponentKind::MultipleScatteringProfiles:
            return "multiple scattering profiles " + std::to_string(uint64_t(term) * kProfilesPerComponent) + "-" +
                   std::to_string(uint64_t(term) * kProfilesPerComponent + kProfilesPerComponent - 1);
    }
    return "unknown component kind " + std::to_string(uint32_t(kind));
}

void SparseRgbVectors::appendVertex(std::span<const uint32_t> idx, std::span<const float> rgb) {
    const std::string subject = "transport vectors";
    if (rgb.size() != 3 * idx.size())
        throw Error(subject, "appendVertex got " + u64(idx.size()) + " indices but " +
                                 u64(rgb.size()) + " values (expected 3 per index)");
    if (offsets.empty()) offsets.push_back(0);
    if (uint64_t(indices.size()) + idx.size() > UINT32_MAX)
        throw Error(subject, "more than 2^32 - 1 coefficients in one component");
    for (uint32_t i : idx)
        if (i > UINT16_MAX)
            throw Error(subject, "coefficient index " + u64(i) + " does not fit 16 bits");
    for (float x : rgb)
        if (!std::isfinite(x)) throw Error(subject, "appendVertex got a non-finite value");

    // Sort by index (only when needed), refusing duplicates.
    std::vector<uint32_t> order(idx.size());
    std::iota(order.begin(), order.end(), 0u);
    if (!std::is_sorted(idx.begin(), idx.end()))
        std::sort(order.begin(), order.end(), [&](uint32_t a, uint32_t b) { return idx[a] < idx[b]; });
    for (size_t k = 1; k < order.size(); ++k)
        if (idx[order[k]] == idx[order[k - 1]])
            throw Error(subject, "coefficient index " + u64(idx[order[k]]) + " appears twice");

    // Per channel the scale of the Haar part (k < split in sorted order: every index
    // unless haarBits is 8 with an SH part) and of the SH part.
    const bool eightBit = haarBits == 8;
    size_t split = order.size();
    if (eightBit)
        while (split > 0 && idx[order[split - 1]] >= shFrom) --split;
    auto scaleOver = [&](size_t from, size_t to, int c, int levels) {
        float maxAbs = 0.0f;
        for (size_t k = from; k < to; ++k) maxAbs = std::max(maxAbs, std::fabs(rgb[3 * order[k] + c]));
        // A channel whose maximum is below levels * FLT_MIN (its scale would be
        // subnormal) is flushed to zero: scale 0, absolute error < 4e-34.
        return double(maxAbs) < levels * double(std::numeric_limits<float>::min()) ? 0.0f
                                                                                   : float(double(maxAbs) / levels);
    };
    const int haarLevels = eightBit ? kEightBitLevels : kQuantMax;
    float scale[3], shScale[3];
    for (int c = 0; c < 3; ++c) {
        scale[c] = scaleOver(0, split, c, haarLevels);
        shScale[c] = scaleOver(split, order.size(), c, kQuantMax);
    }
    const size_t base = indices.size();
    indices.resize(base + idx.size());
    values.resize(3 * (base + idx.size()));
    for (size_t k = 0; k < order.size(); ++k) {
        const uint32_t src = order[k];
        indices[base + k] = uint16_t(idx[src]);
        const float* sc = k < split ? scale : shScale;
        const int levels = k < split ? haarLevels : kQuantMax;
        for (int c = 0; c < 3; ++c) {
            int q = 0;
            if (sc[c] > 0.0f) {
                const double r = std::nearbyint(double(rgb[3 * src + c]) / double(sc[c]));
                q = int(std::clamp(r, double(-levels), double(levels)));
            }
            values[3 * (base + k) + c] = int16_t(q);
        }
    }
    scales.insert(scales.end(), scale, scale + 3);
    if (eightBit && shFrom != UINT32_MAX) shScales.insert(shScales.end(), shScale, shScale + 3);
    offsets.push_back(uint32_t(indices.size()));
}

void SparseRgbVectors::useEightBitHaar(uint32_t shIndex) {
    if (!indices.empty() || vertexCount() != 0)
        throw Error("transport vectors", "8-bit Haar values must be chosen before the first vertex");
    haarBits = 8;
    shFrom = shIndex;
    shScales.clear();
}

void SparseRgbVectors::dequantizeVertex(size_t v, std::vector<uint32_t>& idx,
                                        std::vector<float>& rgb) const {
    if (v >= vertexCount())
        throw std::out_of_range("SparseRgbVectors::dequantizeVertex: vertex " + u64(v) +
                                " of " + u64(vertexCount()));
    const uint32_t begin = offsets[v], end = offsets[v + 1];
    idx.assign(indices.begin() + begin, indices.begin() + end);
    rgb.resize(3 * size_t(end - begin));
    for (uint32_t n = begin; n < end; ++n)
        for (int c = 0; c < 3; ++c)
            rgb[3 * size_t(n - begin) + c] = float(values[3 * size_t(n) + c]) * scaleOf(v, n, c);
}

void SparseRgbVectors::reserve(size_t vertices, size_t coefficients) {
    offsets.reserve(vertices + 1);
    scales.reserve(3 * vertices);
    if (haarBits == 8 && shFrom != UINT32_MAX) shScales.reserve(3 * vertices);
    indices.reserve(coefficients);
    values.reserve(3 * coefficients);
}

void SparseRgbVectors::clear() {
    offsets.assign(1, 0);
    indices.clear();
    values.clear();
    scales.clear();
    shScales.clear();
}

size_t SparseRgbVectors::byteSize() const {
    return offsets.size() * sizeof(uint32_t) + indices.size() * sizeof(uint16_t) +
           values.size() * sizeof(int16_t) + (scales.size() + shScales.size()) * sizeof(float);
}

bool StoredRadialBasis::operator==(const StoredRadialBasis& o) const {
    const RadialRange& a = range;
    const RadialRange& b = o.range;
    return a.zrMin == b.zrMin && a.zrMax == b.zrMax && a.alphaMin == b.alphaMin && a.alphaMax == b.alphaMax &&
           a.eta == b.eta && a.rMax == b.rMax && tables.size == o.tables.size &&
           tables.nodeCount == o.tables.nodeCount && tables.construction == o.tables.construction &&
           tables.normExponent == o.tables.normExponent && tables.values == o.tables.values;
}

const TransportComponent* TransportFile::find(ComponentKind kind, uint32_t term) const {
    for (const TransportComponent& c : components)
        if (c.kind == kind && c.term == term) return &c;
    return nullptr;
}

std::string TransportFile::parameter(const std::string& key) const {
    return findParameter(parameters, key);
}
bool TransportFile::hasParameter(const std::string& key) const {
    return containsParameter(parameters, key);
}
std::string TransportFileInfo::parameter(const std::string& key) const {
    return findParameter(parameters, key);
}
bool TransportFileInfo::hasParameter(const std::string& key) const {
    return containsParameter(parameters, key);
}

}  // namespace prt
