#pragma once
// Importance sampling of a square map by the mipmap-ordered inverse CDF (Chang et al.
// 2008, section 3 "Importance Sampling" and Fig. 2b; docs/point-lights.md).
//
// The map is resolution x resolution non-negative weights (row-major, resolution a
// power of two). Level 0 is the map; level k+1 holds the sums of 2 x 2 blocks of level
// k, up to one texel holding the total. The CDF runs over the texels in MIPMAP order:
// the four children of a block are ordered (x, y) = (0, 0), (1, 0), (0, 1), (1, 1), and
// recursively inside each (a Morton / Z order). Inverting the CDF at u in [0, 1) walks
// from the top level down, choosing at each level the child whose cumulative range
// holds u: log2(resolution) steps, no search table, each sample independent of the
// others (what lets the GPU do it per pixel; here per sample, in parallel).
//
// Because neighbouring u land in neighbouring blocks, stratified u (one per interval
// [i, i + 1) / N) also stratifies the samples over the map's quadtree.
//
// p(texel) = weight(texel) / total: the probability of drawing that texel.

#include <cstddef>
#include <cstdint>
#include <vector>

namespace prt {

class MipmapSampler {
public:
    MipmapSampler() = default;
    // Builds the pyramid. weights.size() must be resolution^2 with resolution a power of
    // two >= 1; weights must be finite and >= 0. Throws prt::Error otherwise.
    MipmapSampler(const std::vector<float>& weights, int resolution);

    int resolution() const { return resolution_; }
    int levels() const { return int(levels_.size()); }
    double total() const { return levels_.empty() ? 0.0 : levels_.back()[0]; }
    // Sum of the 2^level x 2^level block at (x, y) of that level (0 = the map).
    double blockSum(int level, int x, int y) const;

    // The texel (row-major index) at CDF value u * total(), u in [0, 1) (clamped).
    // Texels of weight 0 are never returned while total() > 0. Precondition: total() > 0.
    uint32_t sample(double u) const;
    // p(texel) = weight / total.
    double probability(uint32_t texel) const;

    // N stratified draws: u_i = (i + xi_i) / N with xi_i from a generator seeded by
    // `seed` (deterministic: the same seed gives the same texels on any thread count).
    // xi_i = 0.5 for every i when jitter is false.
    std::vector<uint32_t> stratifiedSamples(size_t n, uint64_t seed, bool jitter = true) const;

    // The reference the mipmap order is tested against: the texel at CDF value u in
    // ROW-MAJOR order (Fig. 2a), by a linear scan. Same preconditions.
    static uint32_t rowMajorInverse(const std::vector<float>& weights, double u);

private:
    int resolution_ = 0;
    std::vector<std::vector<double>> levels_;  // levels_[k]: (resolution >> k)^2 sums
};

}  // namespace prt
