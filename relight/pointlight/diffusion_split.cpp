#include "relight/pointlight/diffusion_split.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <cmath>
#include <string>

#include "common/bssrdf.h"
#include "common/error.h"
#include "common/util.h"

namespace prt {

double importanceRadius(const Material& material, double lowerBound, double rMax) {
    if (!std::isfinite(lowerBound) || !(lowerBound > 0.0))
        throw Error("--importance-bound", "must be finite and > 0 (mm^-1), got " + std::to_string(lowerBound));
    double best = 0.0;
    for (int c = 0; c < 3; ++c) {
        const DipoleChannel d = makeDipoleChannel(material, c);
        auto excess = [&](double r) { return dipoleRd(d, r) * 2.0 * kPi * r - lowerBound; };
        // Scan down from rMax on a geometric grid for the last point above c, then
        // bisect between it and the next grid point (where the importance is below c).
        const int steps = 4000;
        const double ratio = std::pow(1e-6, 1.0 / steps);  // rMax .. rMax * 1e-6
        double outer = rMax;
        if (excess(outer) >= 0.0) {
            best = std::max(best, rMax);
            continue;
        }
        for (int i = 1; i <= steps; ++i) {
            const double r = outer * ratio;
            if (excess(r) >= 0.0) {
                double lo = r, hi = outer;
                for (int it = 0; it < 100; ++it) {
                    const double mid = 0.5 * (lo + hi);
                    (excess(mid) >= 0.0 ? lo : hi) = mid;
                }
                best = std::max(best, 0.5 * (lo + hi));
                break;
            }
            outer = r;
        }
    }
    return best;
}

double DiffusionSplit::localWeight(double r) const {
    switch (weights) {
        case SplitWeights::AllLocal: return 1.0;
        case SplitWeights::AllGlobal: return 0.0;
        case SplitWeights::Paper: break;
    }
    return r <= rp ? 1.0 - 0.5 * std::exp((r - rp) * sharpness) : 0.5 * std::exp(-(r - rp) * sharpness);
}

std::vector<glm::dvec3> radialNodes(const RadialKernel& kernel, double rMax, int entries) {
    if (!std::isfinite(rMax) || !(rMax > 0.0)) throw Error("diffusion table", "rMax must be finite and > 0");
    if (entries < 2) throw Error("diffusion table", "needs at least 2 entries");
    std::vector<glm::dvec3> nodes(size_t(entries) + 1);
    // Each node on its own (a live material change waits for these): the same values on
    // any thread count.
    tbb::parallel_for(tbb::blocked_range<size_t>(0, nodes.size(), 256), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t i = r.begin(); i < r.end(); ++i) {
            const double t = double(i) / double(entries);
            nodes[i] = kernel(rMax * t * t);
        }
    });
    return nodes;
}

RadialTable::RadialTable(const std::function<glm::dvec3(double r)>& kernel, double rMax, int entries)
    : RadialTable(radialNodes(kernel, rMax, entries), rMax) {}

RadialTable::RadialTable(const std::vector<glm::dvec3>& nodes, double rMax) {
    if (!std::isfinite(rMax) || !(rMax > 0.0)) throw Error("diffusion table", "rMax must be finite and > 0");
    if (nodes.size() < 3) throw Error("diffusion table", "needs at least 2 entries");
    const int entries = int(nodes.size()) - 1;
    rMax_ = rMax;
    rMax2_ = float(rMax * rMax);
    invRMax_ = float(1.0 / rMax);
    scale_ = float(entries);
    last_ = entries - 1;
    values_.resize(nodes.size());
    for (size_t i = 0; i < nodes.size(); ++i) values_[i] = glm::vec4(glm::vec3(nodes[i]), 0.0f);
}

RadialKernel diffusionKernel(const Material& material) {
    return [material](double r) { return dipoleRd(material, r); };
}

RadialKernel localDiffusionKernel(const Material& material, const DiffusionSplit& split) {
    return [material, split](double r) { return dipoleRd(material, r) * split.localWeight(r); };
}

RadialKernel globalDiffusionKernel(const Material& material, const DiffusionSplit& split) {
    return [material, split](double r) { return dipoleRd(material, r) * split.globalWeight(r); };
}

RadialTable diffusionTable(const Material& material, double rMax) {
    return RadialTable(diffusionKernel(material), rMax);
}

RadialTable localDiffusionTable(const Material& material, const DiffusionSplit& split, double rMax) {
    return RadialTable(localDiffusionKernel(material, split), rMax);
}

RadialTable globalDiffusionTable(const Material& material, const DiffusionSplit& split, double rMax) {
    return RadialTable(globalDiffusionKernel(material, split), rMax);
}

RadialCurvature radialCurvature(const std::vector<glm::dvec3>& k, double rMax) {
    if (k.size() < 3) throw Error("diffusion table", "needs at least 2 entries");
    const size_t last = k.size() - 1;
    const double entries = double(last);
    auto radius = [&](size_t i) { return rMax * (double(i) / entries) * (double(i) / entries); };
    std::vector<glm::dvec3> along(k.size()), across(k.size());
    // r = 0: k = k(0) + k''(0) r^2 / 2 + O(r^4), k being even.
    along[0] = glm::dvec3(0.0);
    across[0] = (k[1] - k[0]) / (radius(1) * radius(1));
    for (size_t i = 1; i < last; ++i) {
        // Second-order differences on the uneven spacing h1 = r_i - r_i-1, h2 = r_i+1 - r_i.
        const double r = radius(i), h1 = r - radius(i - 1), h2 = radius(i + 1) - r;
        const glm::dvec3 first = (-h2 / (h1 * (h1 + h2))) * k[i - 1] + ((h2 - h1) / (h1 * h2)) * k[i] +
                                 (h1 / (h2 * (h1 + h2))) * k[i + 1];
        const glm::dvec3 second =
            2.0 * (k[i - 1] / (h1 * (h1 + h2)) - k[i] / (h1 * h2) + k[i + 1] / (h2 * (h1 + h2)));
        along[i] = 0.5 * (second - first / r);
        across[i] = 0.5 * first / r;
    }
    along[last] = along[last - 1];
    across[last] = across[last - 1];
    return RadialCurvature{RadialTable(along, rMax), RadialTable(across, rMax)};
}

}  // namespace prt
