#include "common/materials.h"

#include <array>
#include <cmath>
#include <sstream>

#include "common/bssrdf.h"
#include "common/error.h"
#include "common/util.h"

namespace prt {

namespace {

// "(r, g, b)" in iostream's default notation (%.6g) for the messages below.
std::string bracketedRgb(const glm::dvec3& v) { return "(" + formatRgb(v, 6) + ")"; }

bool allFiniteNonNegative(const glm::dvec3& v) {
    for (int c = 0; c < 3; ++c) {
        if (!std::isfinite(v[c]) || v[c] < 0.0) return false;
    }
    return true;
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
                                "channel (mm^-1), got " + bracketedRgb(m.sigmaSPrime));
    }
    if (!allFiniteNonNegative(m.sigmaA)) {
        throw Error("sigma_a", "absorption coefficient must be finite and >= 0 in every channel "
                               "(mm^-1), got " + bracketedRgb(m.sigmaA));
    }
    const glm::dvec3 st = m.sigmaTPrime();
    if (!(st.x > 0.0 && st.y > 0.0 && st.z > 0.0)) {
        throw Error("sigma_t'", "sigma_s' + sigma_a must be > 0 in every channel (a medium that "
                                "neither scatters nor absorbs has no dipole), got " +
                                    bracketedRgb(st));
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
    const std::string key = toLower(name);
    for (const TableEntry& e : measuredTable()) {
        if (toLower(e.name) == key) {
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

}  // namespace prt
