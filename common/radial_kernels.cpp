#include "common/radial_kernels.h"

#include <algorithm>
#include <cmath>

#include "common/bssrdf.h"
#include "common/error.h"

namespace prt {

RadialKernels::RadialKernels(const Material& material) : description_("dipole of " + material.name) {
    validateMaterial(material);
    double widest = 0.0, narrowest = 0.0;  // of 1 / (sigma_t' + sigma_tr)
    for (int c = 0; c < 3; ++c) {
        dipole_[c] = makeDipoleChannel(material, c);
        const double width = 1.0 / (1.0 / dipole_[c].zr + dipole_[c].sigmaTr);
        widest = std::max(widest, width);
        narrowest = c == 0 ? width : std::min(narrowest, width);
    }
    narrowestWidth_ = narrowest;
    widestWidth_ = widest;
}

RadialKernels::RadialKernels(int count, std::function<void(double, double*)> evaluate, double narrowestWidth,
                             double widestWidth, std::string description)
    : count_(count), evaluate_(std::move(evaluate)), narrowestWidth_(narrowestWidth), widestWidth_(widestWidth),
      description_(std::move(description)) {
    if (count < 1 || count > kMaxRadialKernels)
        throw Error("radial kernels", "need 1 to " + std::to_string(kMaxRadialKernels) + " kernels, got " +
                                          std::to_string(count));
    if (!evaluate_) throw Error("radial kernels", "no evaluation function");
    if (!(narrowestWidth > 0.0) || !(widestWidth >= narrowestWidth) || !std::isfinite(widestWidth))
        throw Error("radial kernels", "widths must satisfy 0 < narrowest <= widest < inf");
}

void RadialKernels::evaluate(double r, double* out) const {
    if (evaluate_) {
        evaluate_(r, out);
        return;
    }
    for (int c = 0; c < 3; ++c) out[c] = dipoleRd(dipole_[c], r);
}

double narrowestDipoleWidth(const RadialRange& range) {
    return range.zrMin / (1.0 + std::sqrt(3.0 * (1.0 - range.alphaMax)));
}

double widestDipoleWidth(const RadialRange& range) {
    return range.zrMax / (1.0 + std::sqrt(3.0 * (1.0 - range.alphaMax)));
}

RadialKernels radialBasisKernels(const RadialBasis& basis) {
    const int count = basis.size();
    return RadialKernels(
        count,
        [&basis, count](double r, double* out) {
            float values[kMaxRadialKernels];
            basis.evaluate(r, values);
            for (int j = 0; j < count; ++j) out[j] = double(values[j]);
        },
        narrowestDipoleWidth(basis.range()), widestDipoleWidth(basis.range()),
        "radial basis (" + std::to_string(count) + " profiles)");
}

}  // namespace prt
