#include "common/bssrdf.h"

#include "common/error.h"
#include "common/util.h"

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <numbers>
#include <sstream>

namespace prt {

namespace {

void requireEta(double eta) {
    if (!std::isfinite(eta) || !(eta > 0.0)) {
        throw Error("eta", "relative index of refraction must be finite and > 0, got " +
                               std::to_string(eta));
    }
}

}  // namespace

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
