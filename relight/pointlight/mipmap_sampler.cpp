#include "relight/pointlight/mipmap_sampler.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <string>

#include "common/error.h"

namespace prt {

MipmapSampler::MipmapSampler(const std::vector<float>& weights, int resolution) : resolution_(resolution) {
    if (resolution < 1 || (resolution & (resolution - 1)) != 0)
        throw Error("importance map", "resolution must be a power of two, got " + std::to_string(resolution));
    const size_t n = size_t(resolution) * size_t(resolution);
    if (weights.size() != n)
        throw Error("importance map", "expected " + std::to_string(n) + " weights, got " + std::to_string(weights.size()));
    std::vector<double> level0(n);
    for (size_t i = 0; i < n; ++i) {
        const float w = weights[i];
        if (!std::isfinite(w) || w < 0.0f)
            throw Error("importance map", "weight " + std::to_string(i) + " is negative or not finite");
        level0[i] = double(w);
    }
    levels_.push_back(std::move(level0));
    for (int size = resolution / 2; size >= 1; size /= 2) {
        const std::vector<double>& below = levels_.back();
        std::vector<double> level(size_t(size) * size_t(size));
        const int bs = size * 2;
        tbb::parallel_for(0, size, [&](int y) {
            for (int x = 0; x < size; ++x) {
                const size_t i = size_t(2 * y) * size_t(bs) + size_t(2 * x);
                level[size_t(y) * size_t(size) + size_t(x)] =
                    (below[i] + below[i + 1]) + (below[i + size_t(bs)] + below[i + size_t(bs) + 1]);
            }
        });
        levels_.push_back(std::move(level));
    }
}

double MipmapSampler::blockSum(int level, int x, int y) const {
    const int size = resolution_ >> level;
    return levels_[size_t(level)][size_t(y) * size_t(size) + size_t(x)];
}

uint32_t MipmapSampler::sample(double u) const {
    u = std::clamp(u, 0.0, 1.0);
    double target = u * total();
    int x = 0, y = 0;
    for (int level = levels() - 2; level >= 0; --level) {
        const int size = resolution_ >> level;
        const std::vector<double>& lv = levels_[size_t(level)];
        const int cx = 2 * x, cy = 2 * y;
        const double w[4] = {lv[size_t(cy) * size_t(size) + size_t(cx)], lv[size_t(cy) * size_t(size) + size_t(cx + 1)],
                             lv[size_t(cy + 1) * size_t(size) + size_t(cx)],
                             lv[size_t(cy + 1) * size_t(size) + size_t(cx + 1)]};
        // The child whose cumulative range holds the target; never a zero-weight one
        // (rounding may leave the target just past the last non-zero child).
        int chosen = -1;
        for (int k = 0; k < 4; ++k) {
            if (w[k] <= 0.0) continue;
            chosen = k;
            if (target < w[k]) break;
            target -= w[k];
        }
        if (chosen < 0) chosen = 0;  // an empty block (only when total() == 0)
        target = std::clamp(target, 0.0, w[chosen]);
        x = cx + (chosen & 1);
        y = cy + (chosen >> 1);
    }
    return uint32_t(y) * uint32_t(resolution_) + uint32_t(x);
}

double MipmapSampler::probability(uint32_t texel) const {
    const double t = total();
    return t > 0.0 ? levels_[0][texel] / t : 0.0;
}

std::vector<uint32_t> MipmapSampler::stratifiedSamples(size_t n, uint64_t seed, bool jitter) const {
    std::vector<double> xi(n, 0.5);
    if (jitter) {
        std::mt19937_64 rng(seed);
        std::uniform_real_distribution<double> uni(0.0, 1.0);
        for (double& v : xi) v = uni(rng);
    }
    std::vector<uint32_t> out(n);
    tbb::parallel_for(size_t(0), n, [&](size_t i) { out[i] = sample((double(i) + xi[i]) / double(n)); });
    return out;
}

uint32_t MipmapSampler::rowMajorInverse(const std::vector<float>& weights, double u) {
    double total = 0.0;
    for (float w : weights) total += double(w);
    double target = std::clamp(u, 0.0, 1.0) * total;
    uint32_t last = 0;
    for (size_t i = 0; i < weights.size(); ++i) {
        if (weights[i] <= 0.0f) continue;
        last = uint32_t(i);
        if (target < double(weights[i])) return last;
        target -= double(weights[i]);
    }
    return last;
}

}  // namespace prt
