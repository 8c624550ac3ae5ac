#include "precompute/job/fold_single_scattering.h"

#include <algorithm>
#include <numeric>

#include "common/error.h"
#include "common/transport_file.h"

namespace prt {

SparseRgbVectors foldVectors(const SparseRgbVectors& a, const SparseRgbVectors& b, size_t keep, uint32_t forcedFrom) {
    if (keep < 1) throw Error("fold", "keep at least one term per vertex");
    if (a.vertexCount() != b.vertexCount())
        throw Error("fold", "the components have " + std::to_string(a.vertexCount()) + " and " +
                                std::to_string(b.vertexCount()) + " vertices");
    SparseRgbVectors out;
    out.reserve(a.vertexCount(), std::min(a.coefficientCount() + b.coefficientCount(), a.vertexCount() * keep));
    std::vector<uint32_t> ia, ib, idx, order;
    std::vector<float> va, vb, sum, kept;
    std::vector<uint32_t> keptIdx;
    for (size_t v = 0; v < a.vertexCount(); ++v) {
        a.dequantizeVertex(v, ia, va);
        b.dequantizeVertex(v, ib, vb);
        // The sum on the union of the two (sorted) index lists.
        idx.clear();
        sum.clear();
        size_t p = 0, q = 0;
        while (p < ia.size() || q < ib.size()) {
            const bool takeA = q == ib.size() || (p < ia.size() && ia[p] <= ib[q]);
            const bool takeB = p == ia.size() || (q < ib.size() && ib[q] <= ia[p]);
            idx.push_back(takeA ? ia[p] : ib[q]);
            for (int c = 0; c < 3; ++c)
                sum.push_back((takeA ? va[3 * p + size_t(c)] : 0.0f) + (takeB ? vb[3 * q + size_t(c)] : 0.0f));
            p += takeA;
            q += takeB;
        }
        // The SH part first, then the largest Haar terms.
        order.resize(idx.size());
        std::iota(order.begin(), order.end(), 0u);
        auto norm2 = [&](uint32_t k) {
            return double(sum[3 * k]) * sum[3 * k] + double(sum[3 * k + 1]) * sum[3 * k + 1] +
                   double(sum[3 * k + 2]) * sum[3 * k + 2];
        };
        const size_t n = std::min(keep, idx.size());
        std::partial_sort(order.begin(), order.begin() + std::ptrdiff_t(n), order.end(), [&](uint32_t x, uint32_t y) {
            const bool shX = idx[x] >= forcedFrom, shY = idx[y] >= forcedFrom;
            if (shX != shY) return shX;
            const double nx = norm2(x), ny = norm2(y);
            return nx != ny ? nx > ny : idx[x] < idx[y];
        });
        order.resize(n);
        std::sort(order.begin(), order.end());  // positions in idx: increasing indices
        keptIdx.clear();
        kept.clear();
        for (uint32_t k : order) {
            keptIdx.push_back(idx[k]);
            kept.insert(kept.end(), sum.begin() + std::ptrdiff_t(3 * k), sum.begin() + std::ptrdiff_t(3 * k + 3));
        }
        out.appendVertex(keptIdx, kept);
    }
    return out;
}

void foldSingleScattering(std::vector<TransportComponent>& components, size_t keep, uint32_t forcedFrom) {
    auto find = [&](ComponentKind kind) {
        const auto it = std::find_if(components.begin(), components.end(),
                                     [&](const TransportComponent& c) { return c.kind == kind; });
        if (it == components.end() ||
            std::count_if(components.begin(), components.end(), [&](const TransportComponent& c) { return c.kind == kind; }) != 1)
            throw Error("--fold-ss", "needs exactly one " + componentName(kind, 0) + " component");
        if (it->blocked()) throw Error("--fold-ss", "folds per-vertex vectors, before any blocks");
        return it;
    };
    const auto ms = find(ComponentKind::MultipleScattering);
    const auto ss = find(ComponentKind::SingleScatteringIsotropic);
    ms->vectors = foldVectors(ms->vectors, ss->vectors, keep, forcedFrom);
    components.erase(ss);
}

}  // namespace prt
