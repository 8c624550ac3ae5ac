#include "relight/prt/eye_path.h"

#include <algorithm>
#include <cmath>

#include "common/bssrdf.h"
#include "common/error.h"
#include "common/scattering_path.h"

namespace prt {

const char* toString(SingleScatteringView view) {
    return view == SingleScatteringView::Normal ? "normal" : "refracted";
}

SingleScatteringView parseSingleScatteringView(const std::string& text) {
    if (text == "refracted") return SingleScatteringView::Refracted;
    if (text == "normal") return SingleScatteringView::Normal;
    throw Error("--ss-path", "'" + text + "' is not a path: refracted (the eye's) or normal (Wang et al.'s)");
}

double eyePathFactor(double eta, double cosRefracted) {
    if (!(eta > 0) || !std::isfinite(eta)) throw Error("eta", "must be positive and finite");
    const double cosO = std::clamp(cosRefracted, 0.0, 1.0);
    static const std::vector<QuadratureNode> rule = pathQuadratureRule(PathQuadrature::GaussLegendre, 64);
    double eye = 0.0, normal = 0.0;
    for (const QuadratureNode& q : rule) {
        const double mu = q.xi;
        const double c2 = 1.0 - (1.0 - mu * mu) / (eta * eta);
        if (!(c2 > 0)) continue;  // total internal reflection (eta < 1): nothing enters
        const double c = std::sqrt(c2), ft = fresnelTransmittance(eta, mu);
        eye += q.weight * ft * c / (c + cosO);
        normal += q.weight * ft * c / (c + 1.0);
    }
    return normal > 0.0 ? eye / normal : 1.0;
}

EyePathTable::EyePathTable(double eta, SingleScatteringView view) {
    for (int i = 0; i < kSize; ++i)
        values_[size_t(i)] =
            view == SingleScatteringView::Normal ? 1.0f : float(eyePathFactor(eta, double(i) / (kSize - 1)));
}

double EyePathTable::operator()(double cosRefracted) const {
    const double x = std::clamp(cosRefracted, 0.0, 1.0) * (kSize - 1);
    const int i = std::min(int(x), kSize - 2);
    const double f = x - i;
    return (1.0 - f) * values_[size_t(i)] + f * values_[size_t(i + 1)];
}

}  // namespace prt
