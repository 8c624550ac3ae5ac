#include "common/bssrdf.h"

#include "common/error.h"

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <numbers>
#include <sstream>

namespace prt {

namespace {

constexpr double kPi = std::numbers::pi;

std::string formatRgb(const glm::dvec3& v) {
    std::ostringstream os;
    os << "(" << v.x << ", " << v.y << ", " << v.z << ")";
    return os.str();
}

bool allFiniteNonNegative(const glm::dvec3& v) {
    for (int c = 0; c < 3; ++c) {
        if (!std::isfinite(v[c]) || v[c] < 0.0) return false;
    }
    return true;
}

void requireEta(double eta) {
    if (!std::isfinite(eta) || !(eta > 0.0)) {
        throw Error("eta", "relative index of refraction must be finite and > 0, got " +
                               std::to_string(eta));
    }
}

std::string lowercase(std::string s) {
    for (char& ch : s) ch = static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
    return s;
}

struct TableEntry {
    const char* name;
    glm::dvec3 sigmaSPrime;
    glm::dvec3 sigmaA;
};

// Jensen et al. 2001, Fig. 5 (SPEC section 5), mm^-1, eta = 1.3.
const std::array<TableEntry, 12>& measuredTable() {
    static const std::array<TableEntry, 12> table = {{
        {"Apple", {2.29, 2.39, 1.97}, {0.0030, 0.0034, 0.046}},
        {"Chicken1", {0.15, 0.21, 0.38}, {0.015, 0.077, 0.19}},
        {"Chicken2", {0.19, 0.25, 0.32}, {0.018, 0.088, 0.20}},
        {"Cream", {7.38, 5.47, 3.15}, {0.0002, 0.0028, 0.0163}},
        {"Ketchup", {0.18, 0.07, 0.03}, {0.061, 0.97, 1.45}},
        {"Marble", {2.19, 2.62, 3.00}, {0.0021, 0.0041, 0.0071}},
        {"Potato", {0.68, 0.70, 0.55}, {0.0024, 0.0090, 0.12}},
        {"Skimmilk", {0.70, 1.22, 1.90}, {0.0014, 0.0025, 0.0142}},
        {"Skin1", {0.74, 0.88, 1.01}, {0.032, 0.17, 0.48}},
        {"Skin2", {1.09, 1.59, 1.79}, {0.013, 0.070, 0.145}},
        {"Spectralon", {11.6, 20.4, 14.9}, {0.00, 0.00, 0.00}},
        {"Wholemilk", {2.55, 3.21, 3.77}, {0.0011, 0.0024, 0.014}},
    }};
    return table;
}

}  // namespace

double luminance(const glm::dvec3& rgb) {
    return 0.2126 * rgb.x + 0.7152 * rgb.y + 0.0722 * rgb.z;
}

// ---------------------------------------------------------------------------
// Material
// ---------------------------------------------------------------------------

glm::dvec3 Material::sigmaS() const { return sigmaSPrime / (1.0 - g); }
glm::dvec3 Material::sigmaT() const { return sigmaA + sigmaS(); }
glm::dvec3 Material::sigmaTPrime() const { return sigmaA + sigmaSPrime; }
glm::dvec3 Material::alphaPrime() const { return sigmaSPrime / sigmaTPrime(); }
glm::dvec3 Material::albedo() const { return sigmaS() / sigmaT(); }
glm::dvec3 Material::sigmaTr() const { return glm::sqrt(3.0 * sigmaA * sigmaTPrime()); }
glm::dvec3 Material::zr() const { return 1.0 / sigmaTPrime(); }
glm::dvec3 Material::zv() const { return zr() * (1.0 + 4.0 * boundaryA() / 3.0); }
double Material::fresnelDiffuse() const { return fresnelDiffuseReflectance(eta); }
double Material::boundaryA() const { return dipoleBoundaryA(eta); }
glm::dvec3 Material::meanFreePath() const { return 1.0 / sigmaTPrime(); }
double Material::minMeanFreePath() const {
    const glm::dvec3 l = meanFreePath();
    return std::min({l.x, l.y, l.z});
}
glm::dvec3 Material::totalDiffuseReflectance() const {
    glm::dvec3 r;
    for (int c = 0; c < 3; ++c) r[c] = dipoleTotalDiffuseReflectance(makeDipoleChannel(*this, c));
    return r;
}

void validateMaterial(const Material& m) {
    if (!allFiniteNonNegative(m.sigmaSPrime)) {
        throw Error("sigma_s'", "reduced scattering coefficient must be finite and >= 0 in every "
                                "channel (mm^-1), got " + formatRgb(m.sigmaSPrime));
    }
    if (!allFiniteNonNegative(m.sigmaA)) {
        throw Error("sigma_a", "absorption coefficient must be finite and >= 0 in every channel "
                               "(mm^-1), got " + formatRgb(m.sigmaA));
    }
    const glm::dvec3 st = m.sigmaTPrime();
    if (!(st.x > 0.0 && st.y > 0.0 && st.z > 0.0)) {
        throw Error("sigma_t'", "sigma_s' + sigma_a must be > 0 in every channel (a medium that "
                                "neither scatters nor absorbs has no dipole), got " +
                                    formatRgb(st));
    }
    if (!std::isfinite(m.eta) || m.eta < kMinEta || m.eta > kMaxEta) {
        std::ostringstream os;
        os << "relative index of refraction must be in [" << kMinEta << ", " << kMaxEta
           << "] (the range where the diffuse Fresnel fits hold), got " << m.eta;
        throw Error("eta", os.str());
    }
    if (!std::isfinite(m.g) || !(m.g > -1.0 && m.g < 1.0)) {
        throw Error("g", "Henyey-Greenstein asymmetry must satisfy -1 < g < 1, got " +
                             std::to_string(m.g));
    }
}

std::vector<std::string> materialNames() {
    std::vector<std::string> names;
    for (const TableEntry& e : measuredTable()) names.emplace_back(e.name);
    return names;
}

Material materialByName(const std::string& name) {
    const std::string key = lowercase(name);
    for (const TableEntry& e : measuredTable()) {
        if (lowercase(e.name) == key) {
            Material m;
            m.name = e.name;
            m.sigmaSPrime = e.sigmaSPrime;
            m.sigmaA = e.sigmaA;
            m.eta = 1.3;
            m.g = 0.0;
            return m;
        }
    }
    std::string valid;
    for (const TableEntry& e : measuredTable()) {
        if (!valid.empty()) valid += ", ";
        valid += e.name;
    }
    throw Error(name, "unknown material; valid names: " + valid);
}

Material customMaterial(const glm::dvec3& sigmaSPrime, const glm::dvec3& sigmaA, double eta,
                        double g) {
    Material m;
    m.name = "custom";
    m.sigmaSPrime = sigmaSPrime;
    m.sigmaA = sigmaA;
    m.eta = eta;
    m.g = g;
    validateMaterial(m);
    return m;
}

// ---------------------------------------------------------------------------
// Dipole
// ---------------------------------------------------------------------------

DipoleChannel makeDipoleChannel(double sigmaSPrime, double sigmaA, double eta) {
    const double sigmaTPrime = sigmaSPrime + sigmaA;
    DipoleChannel d;
    d.alphaPrime = sigmaSPrime / sigmaTPrime;
    d.sigmaTr = std::sqrt(3.0 * sigmaA * sigmaTPrime);
    d.zr = 1.0 / sigmaTPrime;
    d.zv = d.zr * (1.0 + 4.0 * dipoleBoundaryA(eta) / 3.0);
    return d;
}

DipoleChannel makeDipoleChannel(const Material& m, int c) {
    if (c < 0 || c > 2) throw Error("channel", "must be 0, 1 or 2, got " + std::to_string(c));
    return makeDipoleChannel(m.sigmaSPrime[c], m.sigmaA[c], m.eta);
}

double dipoleRd(const DipoleChannel& d, double r) {
    const double r2 = r * r;
    const double dr = std::sqrt(r2 + d.zr * d.zr);
    const double dv = std::sqrt(r2 + d.zv * d.zv);
    // Each term is z (1 + sigma_tr d) e^(-sigma_tr d) / d^3: the normal flux at the
    // surface of a point source at distance d and depth (or height) z.
    const double real = d.zr * (1.0 + d.sigmaTr * dr) * std::exp(-d.sigmaTr * dr) / (dr * dr * dr);
    const double virt = d.zv * (1.0 + d.sigmaTr * dv) * std::exp(-d.sigmaTr * dv) / (dv * dv * dv);
    return d.alphaPrime / (4.0 * kPi) * (real + virt);
}

glm::dvec3 dipoleRd(const Material& m, double r) {
    glm::dvec3 out;
    for (int c = 0; c < 3; ++c) out[c] = dipoleRd(makeDipoleChannel(m, c), r);
    return out;
}

double dipoleTotalDiffuseReflectance(const DipoleChannel& d) {
    return 0.5 * d.alphaPrime * (std::exp(-d.sigmaTr * d.zr) + std::exp(-d.sigmaTr * d.zv));
}

double dipoleDiffuseReflectanceWithin(const DipoleChannel& d, double radius) {
    if (!(radius > 0.0)) return 0.0;
    auto term = [&](double z) {
        const double big = std::sqrt(radius * radius + z * z);
        return std::exp(-d.sigmaTr * z) - z * std::exp(-d.sigmaTr * big) / big;
    };
    return 0.5 * d.alphaPrime * (term(d.zr) + term(d.zv));
}

double dipoleRadiusForFraction(const DipoleChannel& d, double fraction) {
    if (!(fraction > 0.0 && fraction < 1.0)) {
        throw Error("fraction", "must be in (0, 1), got " + std::to_string(fraction));
    }
    const double total = dipoleTotalDiffuseReflectance(d);
    if (!(total > 0.0)) return 0.0;
    const double target = fraction * total;
    double lo = 0.0;
    double hi = std::max(d.zv, 1e-12);
    // Within(R) is increasing in R; grow the bracket until it holds the target. The
    // slowest tail (sigma_tr = 0) decays like (z_r + z_v) / (2 R), so this terminates.
    for (int i = 0; i < 2000 && dipoleDiffuseReflectanceWithin(d, hi) < target; ++i) hi *= 2.0;
    for (int i = 0; i < 200 && hi - lo > 1e-12 * hi; ++i) {
        const double mid = 0.5 * (lo + hi);
        if (dipoleDiffuseReflectanceWithin(d, mid) < target) lo = mid;
        else hi = mid;
    }
    return hi;
}

// ---------------------------------------------------------------------------
// Fresnel
// ---------------------------------------------------------------------------

double fresnelDiffuseReflectance(double eta) {
    requireEta(eta);
    if (eta >= 1.0) {
        // Jensen et al. 2001 / Wang Sec. 2, each term divided separately.
        return -1.440 / (eta * eta) + 0.710 / eta + 0.668 + 0.0636 * eta;
    }
    // Below 1 the formula above turns negative (-0.26 at eta = 0.9); the companion fit
    // of Egan and Hilgeman for eta < 1 follows the exact hemispherical average.
    return -0.4399 + 0.7099 / eta - 0.3319 / (eta * eta) + 0.0636 / (eta * eta * eta);
}

double dipoleBoundaryA(double eta) {
    const double fdr = fresnelDiffuseReflectance(eta);
    return (1.0 + fdr) / (1.0 - fdr);
}

double fresnelReflectance(double eta, double cosThetaI) {
    requireEta(eta);
    if (eta == 1.0) return 0.0;  // index matched: no interface
    const double ci = std::min(std::fabs(cosThetaI), 1.0);
    const double sin2t = (1.0 - ci * ci) / (eta * eta);
    if (sin2t >= 1.0) return 1.0;  // total internal reflection (or grazing at the critical angle)
    const double ct = std::sqrt(1.0 - sin2t);
    const double rs = (ci - eta * ct) / (ci + eta * ct);
    const double rp = (eta * ci - ct) / (eta * ci + ct);
    return 0.5 * (rs * rs + rp * rp);
}

double fresnelTransmittance(double eta, double cosTheta) {
    return 1.0 - fresnelReflectance(eta, cosTheta);
}

// ---------------------------------------------------------------------------
// Refraction
// ---------------------------------------------------------------------------

bool refractDirection(const glm::dvec3& w, const glm::dvec3& n, double eta, glm::dvec3& wt) {
    requireEta(eta);
    const double lw = glm::length(w);
    const double ln = glm::length(n);
    if (!(lw > 0.0) || !(ln > 0.0)) return false;
    const glm::dvec3 wi = w / lw;
    const glm::dvec3 nn = n / ln;
    const double ci = glm::dot(wi, nn);
    if (ci < 0.0) return false;  // w is inside: not a direction on the outside
    const double c = std::min(ci, 1.0);
    const double sin2t = (1.0 - c * c) / (eta * eta);
    if (sin2t >= 1.0) return false;  // total internal reflection
    const double ct = std::sqrt(1.0 - sin2t);
    // Tangential part of -w shrinks by 1/eta (Snell); normal part is -cos_t.
    wt = glm::normalize(-wi / eta + (c / eta - ct) * nn);
    return true;
}

// ---------------------------------------------------------------------------
// Henyey-Greenstein
// ---------------------------------------------------------------------------

double henyeyGreenstein(double g, double cosTheta) {
    if (!(g > -1.0 && g < 1.0)) {
        throw Error("g", "Henyey-Greenstein asymmetry must satisfy -1 < g < 1, got " +
                             std::to_string(g));
    }
    const double c = std::clamp(cosTheta, -1.0, 1.0);
    const double denom = 1.0 + g * g - 2.0 * g * c;
    return (1.0 - g * g) / (4.0 * kPi * denom * std::sqrt(denom));
}

double henyeyGreensteinDirections(double g, const glm::dvec3& wIn, const glm::dvec3& wOut) {
    const double li = glm::length(wIn);
    const double lo = glm::length(wOut);
    if (!(li > 0.0) || !(lo > 0.0)) {
        throw Error("henyeyGreensteinDirections", "propagation directions must be non-zero");
    }
    return henyeyGreenstein(g, glm::dot(wIn, wOut) / (li * lo));
}

}  // namespace prt
