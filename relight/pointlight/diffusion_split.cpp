#include "relight/pointlight/diffusion_split.h"

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

RadialTable::RadialTable(const std::function<glm::dvec3(double r)>& kernel, double rMax, int entries) {
    if (!std::isfinite(rMax) || !(rMax > 0.0)) throw Error("diffusion table", "rMax must be finite and > 0");
    if (entries < 2) throw Error("diffusion table", "needs at least 2 entries");
    rMax_ = rMax;
    rMax2_ = float(rMax * rMax);
    invRMax_ = float(1.0 / rMax);
    scale_ = float(entries);
    last_ = entries - 1;
    values_.resize(size_t(entries) + 1);
    for (int i = 0; i <= entries; ++i) {
        const double t = double(i) / double(entries);
        values_[size_t(i)] = glm::vec4(glm::vec3(kernel(rMax * t * t)), 0.0f);
    }
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

RadialCurvature radialCurvature(const RadialKernel& kernel, double rMax, double h, int entries) {
    if (!std::isfinite(h) || !(h > 0.0)) throw Error("diffusion table", "the difference step must be finite and > 0");
    // k'(r) and k''(r) by central differences, once per node (the two tables share them).
    struct Derivatives {
        glm::dvec3 first, second;
    };
    auto at = [&](double r) {
        const glm::dvec3 below = kernel(std::abs(r - h)), centre = kernel(r), above = kernel(r + h);
        return Derivatives{(above - below) / (2.0 * h), (above - 2.0 * centre + below) / (h * h)};
    };
    const double tiny = 1e-9 * rMax;
    RadialCurvature c;
    c.along = RadialTable(
        [&](double r) {
            if (r < tiny) return glm::dvec3(0.0);
            const Derivatives d = at(r);
            return 0.5 * (d.second - d.first / r);
        },
        rMax, entries);
    c.across = RadialTable(
        [&](double r) {
            const Derivatives d = at(r);
            return r < tiny ? 0.5 * d.second : 0.5 * d.first / r;
        },
        rMax, entries);
    return c;
}

}  // namespace prt
