#include "common/material_edit.h"

#include <cmath>
#include <cstdio>
#include <limits>

#include "common/bssrdf.h"
#include "common/error.h"
#include "common/util.h"

namespace prt {

Material scaledMaterial(const Material& m, double s) {
    if (!(s > 0.0) || !std::isfinite(s))
        throw Error("size", "the size factor must be finite and > 0, got " + std::to_string(s));
    Material out = m;
    out.sigmaA *= s;
    out.sigmaSPrime *= s;
    return out;
}

namespace {

// The total diffuse reflectance as a function of alpha' alone (see the header).
double totalReflectanceOfAlbedo(double alphaPrime, double boundaryA) {
    const double q = std::sqrt(3.0 * (1.0 - alphaPrime));
    return 0.5 * alphaPrime * (std::exp(-q) + std::exp(-(1.0 + 4.0 * boundaryA / 3.0) * q));
}

}  // namespace

MaterialAppearance appearanceOf(const Material& m) {
    MaterialAppearance a;
    a.diffuseColour = m.totalDiffuseReflectance();
    const glm::dvec3 sigmaTr = m.sigmaTr();
    for (int c = 0; c < 3; ++c)
        a.meanFreePathMm[c] = sigmaTr[c] > 0.0 ? 1.0 / sigmaTr[c] : std::numeric_limits<double>::infinity();
    return a;
}

Material materialFromAppearance(const glm::dvec3& diffuseColour, const glm::dvec3& meanFreePathMm, double eta,
                                double g) {
    for (int c = 0; c < 3; ++c) {
        if (!(diffuseColour[c] > 0.0 && diffuseColour[c] < 1.0))
            throw Error("--diffuse-colour", "every channel must lie in (0, 1) (linear), got " +
                                                formatRgb(diffuseColour, 6));
        if (!(meanFreePathMm[c] > 0.0) || !std::isfinite(meanFreePathMm[c]))
            throw Error("--mfp-mm", "every channel must be finite and > 0 mm, got " + formatRgb(meanFreePathMm, 6));
    }
    // eta is checked before it is used for A.
    const double boundaryA = customMaterial(glm::dvec3(1.0), glm::dvec3(0.0), eta, g).boundaryA();
    glm::dvec3 sigmaSPrime, sigmaA;
    for (int c = 0; c < 3; ++c) {
        // R_total(alpha') increases strictly on [0, 1]: bisection to double precision.
        double lo = 0.0, hi = 1.0;
        for (int i = 0; i < 200 && hi - lo > 1e-16; ++i) {
            const double mid = 0.5 * (lo + hi);
            (totalReflectanceOfAlbedo(mid, boundaryA) < diffuseColour[c] ? lo : hi) = mid;
        }
        const double alphaPrime = 0.5 * (lo + hi);
        const double sigmaTr = 1.0 / meanFreePathMm[c];
        const double sigmaTPrime = sigmaTr / std::sqrt(3.0 * (1.0 - alphaPrime));
        sigmaSPrime[c] = alphaPrime * sigmaTPrime;
        sigmaA[c] = sigmaTPrime - sigmaSPrime[c];
    }
    Material m = customMaterial(sigmaSPrime, sigmaA, eta, g);
    m.name = "appearance";
    return m;
}

Material lerpMaterial(const Material& a, const Material& b, double t) {
    if (!(t >= 0.0 && t <= 1.0)) throw Error("material path", "t must lie in [0, 1], got " + std::to_string(t));
    // Equal ends stay exact (the blend of two equal values may differ from them in the last bit).
    auto blend = [t](double x, double y) { return x == y ? x : (1.0 - t) * x + t * y; };
    Material m = customMaterial((1.0 - t) * a.sigmaSPrime + t * b.sigmaSPrime, (1.0 - t) * a.sigmaA + t * b.sigmaA,
                                blend(a.eta, b.eta), blend(a.g, b.g));
    m.name = a.name + " -> " + b.name;
    return m;
}

Material parseMaterial(const std::string& text, double eta, double g, const std::string& subject) {
    const std::vector<std::string> fields = splitText(text, ':');
    const std::string kind = toLower(trim(fields[0]));
    const std::string where = subject + " " + text;
    auto rgb = [&](const std::string& field, const char* what, bool allowGray) {
        const std::vector<double> v = parseNumberList(field, where, what);
        if (v.size() == 3) return glm::dvec3(v[0], v[1], v[2]);
        if (allowGray && v.size() == 1) return glm::dvec3(v[0]);
        throw Error(where, std::string("the ") + what + " needs " + (allowGray ? "1 or 3" : "3") +
                               " values (R, G, B), got " + std::to_string(v.size()));
    };
    try {
        if (fields.size() == 1) {
            Material m = materialByName(trim(fields[0]));
            m.eta = eta;
            m.g = g;
            validateMaterial(m);
            return m;
        }
        if (fields.size() == 3 && kind == "sigma")
            return customMaterial(rgb(fields[2], "sigma_s'", false), rgb(fields[1], "sigma_a", false), eta, g);
        if (fields.size() == 3 && (kind == "colour" || kind == "color"))
            return materialFromAppearance(rgb(fields[1], "diffuse colour", false),
                                          rgb(fields[2], "mean free path", true), eta, g);
    } catch (const Error& e) {
        if (e.subject() == where) throw;
        throw Error(where, e.subject() + ": " + e.reason());
    }
    throw Error(where, "expected a material name, sigma:SA_R,SA_G,SA_B:SS_R,SS_G,SS_B or colour:R,G,B:L_R,L_G,L_B");
}

std::pair<Material, Material> parseMaterialPath(const std::string& text, double eta, double g,
                                                const std::string& subject) {
    const std::vector<std::string> fields = splitText(text, ':');
    std::vector<std::string> ends;
    for (size_t i = 0; i < fields.size();) {
        const std::string kind = toLower(trim(fields[i]));
        const size_t take = (kind == "sigma" || kind == "colour" || kind == "color") ? 3 : 1;
        if (i + take > fields.size()) break;
        std::string end = fields[i];
        for (size_t k = 1; k < take; ++k) end += ":" + fields[i + k];
        ends.push_back(end);
        i += take;
    }
    size_t joined = 0;
    for (const std::string& e : ends) joined += e.size() + 1;
    if (ends.size() != 2 || joined != text.size() + 1)
        throw Error(subject + " " + text, "expected two materials A:B (names, sigma:... or colour:... forms)");
    return {parseMaterial(ends[0], eta, g, subject), parseMaterial(ends[1], eta, g, subject)};
}

std::string describeMaterial(const Material& m) {
    char eta[32];
    std::snprintf(eta, sizeof eta, "%g", m.eta);
    return m.name + " (sigma_a " + formatRgb(m.sigmaA) + " mm^-1; sigma_s' " + formatRgb(m.sigmaSPrime) +
           " mm^-1; eta " + eta + ")";
}

}  // namespace prt
