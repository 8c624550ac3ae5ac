#include "common/radial_basis.h"

#include "common/error.h"
#include "common/util.h"

#include <Eigen/Dense>
#include <Eigen/SVD>

#include <algorithm>
#include <cmath>
#include <sstream>

namespace prt {

namespace {

// Table nodes start at r0 = zrMin * kGridScale: evenly spaced below r0, geometric above.
constexpr double kGridScale = 0.25;
// Quadrature of the fit norm: Gauss-Legendre panels of this width in u = asinh(r / r0)
// (a factor e^0.25 = 1.28 in r per panel), kNormPoints points each.
constexpr double kNormPanel = 0.25;
constexpr int kNormPoints = 4;
// Snapshots (PCA, greedy): z_r log-spaced at this many per decade; sqrt(1 - alpha')
// evenly spaced with this many values over the range.
constexpr double kSnapshotsPerDecade = 16.0;
constexpr int kSnapshotAlphas = 24;
// Relative slack of covers() (rounding of z_r / s and alpha').
constexpr double kCoverSlack = 1e-9;

// Gauss-Legendre nodes/weights on [-1, 1].
constexpr double kGl3x[3] = {-0.7745966692414834, 0.0, 0.7745966692414834};
constexpr double kGl3w[3] = {0.5555555555555556, 0.8888888888888888, 0.5555555555555556};
constexpr double kGl4x[4] = {-0.8611363115940526, -0.3399810435848563, 0.3399810435848563,
                             0.8611363115940526};
constexpr double kGl4w[4] = {0.3478548451374538, 0.6521451548625461, 0.6521451548625461,
                             0.3478548451374538};

std::string num(double v) {
    std::ostringstream os;
    os.precision(6);
    os << v;
    return os.str();
}

void rangeError(const std::string& reason) { throw Error("radial range", reason); }

const char* channelName(int c) { return c == 0 ? "R" : c == 1 ? "G" : "B"; }

// z_v / z_r for a relative index.
double virtualRatio(double eta) { return 1.0 + 4.0 * dipoleBoundaryA(eta) / 3.0; }

// The dipole of shape (z_r, alpha') at the range's eta.
DipoleChannel dipoleOf(double zr, double alphaPrime, double eta) {
    DipoleChannel d;
    d.alphaPrime = alphaPrime;
    d.zr = zr;
    d.zv = zr * virtualRatio(eta);
    d.sigmaTr = std::sqrt(3.0 * (1.0 - alphaPrime)) / zr;
    return d;
}

double gridOrigin(const RadialRange& range) { return range.zrMin * kGridScale; }

int nodeCountFor(const RadialRange& range, double step) {
    const double span = std::asinh(range.rMax / gridOrigin(range));
    return std::max(2, static_cast<int>(std::ceil(span / step)) + 1);
}

// The snapshot dipoles: z_r log-spaced, sqrt(1 - alpha') evenly spaced.
std::vector<DipoleChannel> snapshots(const RadialRange& range) {
    const double decades = std::log10(range.zrMax / range.zrMin);
    const int nz = range.zrMax > range.zrMin
                       ? std::max(2, static_cast<int>(std::ceil(decades * kSnapshotsPerDecade)) + 1)
                       : 1;
    const double tLo = std::sqrt(1.0 - range.alphaMax);
    const double tHi = std::sqrt(1.0 - range.alphaMin);
    const int na = range.alphaMax > range.alphaMin ? kSnapshotAlphas : 1;
    std::vector<DipoleChannel> out;
    for (int i = 0; i < nz; ++i) {
        const double zr = nz == 1 ? range.zrMin
                                  : range.zrMin * std::pow(range.zrMax / range.zrMin,
                                                           static_cast<double>(i) / (nz - 1));
        for (int a = 0; a < na; ++a) {
            const double t = na == 1 ? tLo : tLo + (tHi - tLo) * a / (na - 1);
            out.push_back(dipoleOf(zr, 1.0 - t * t, range.eta));
        }
    }
    return out;
}

}  // namespace

const char* radialConstructionName(RadialConstruction c) {
    switch (c) {
        case RadialConstruction::Pca: return "pca";
        case RadialConstruction::Greedy: return "greedy";
        case RadialConstruction::ExpLadder: return "exp-ladder";
    }
    return "unknown";
}

// ---------------------------------------------------------------------------
// Range
// ---------------------------------------------------------------------------

void validateRadialRange(const RadialRange& r) {
    for (double v : {r.zrMin, r.zrMax, r.alphaMin, r.alphaMax, r.eta, r.rMax}) {
        if (!std::isfinite(v)) rangeError("every bound must be finite");
    }
    if (!(r.zrMin > 0.0)) rangeError("z_r min must be > 0 mm, got " + num(r.zrMin));
    if (!(r.zrMax >= r.zrMin)) {
        rangeError("z_r max " + num(r.zrMax) + " mm is below z_r min " + num(r.zrMin) + " mm");
    }
    if (!(r.alphaMin > 0.0)) rangeError("alpha' min must be > 0, got " + num(r.alphaMin));
    if (!(r.alphaMax >= r.alphaMin)) {
        rangeError("alpha' max " + num(r.alphaMax) + " is below alpha' min " + num(r.alphaMin));
    }
    if (!(r.alphaMax < 1.0)) {
        rangeError("alpha' max must be < 1 (sigma_a = 0 has no decay length), got " +
                   num(r.alphaMax));
    }
    if (r.eta < kMinEta || r.eta > kMaxEta) {
        rangeError("eta must be in [" + num(kMinEta) + ", " + num(kMaxEta) + "], got " +
                   num(r.eta));
    }
    if (!(r.rMax > 0.0)) rangeError("r max must be > 0 mm, got " + num(r.rMax));
    if (r.rMax / r.zrMin > 1e7) {
        rangeError("r max / z_r min = " + num(r.rMax / r.zrMin) + " exceeds 1e7");
    }
}

RadialRange rangeCovering(const std::vector<Material>& materials, double sMin, double sMax,
                          double rMax) {
    if (materials.empty()) throw Error("radial range", "no materials to cover");
    if (!std::isfinite(sMin) || !std::isfinite(sMax) || !(sMin > 0.0) || !(sMax >= sMin)) {
        throw Error("size factor", "need 0 < s min <= s max, got [" + num(sMin) + ", " +
                                       num(sMax) + "]");
    }
    RadialRange range;
    range.eta = materials.front().eta;
    range.rMax = rMax;
    range.zrMin = INFINITY;
    range.zrMax = 0.0;
    range.alphaMin = INFINITY;
    range.alphaMax = 0.0;
    for (const Material& m : materials) {
        validateMaterial(m);
        if (m.eta != range.eta) {
            throw Error(m.name, "eta " + num(m.eta) + " differs from " + num(range.eta) +
                                    " of " + materials.front().name +
                                    " (one basis serves one eta)");
        }
        for (int c = 0; c < 3; ++c) {
            if (!(m.sigmaA[c] > 0.0)) {
                throw Error(m.name, std::string("channel ") + channelName(c) +
                                        ": sigma_a = 0 (alpha' = 1) cannot be in a radial "
                                        "basis range");
            }
            const double zr = 1.0 / m.sigmaTPrime()[c];
            const double a = m.alphaPrime()[c];
            range.zrMin = std::min(range.zrMin, zr / sMax);
            range.zrMax = std::max(range.zrMax, zr / sMin);
            range.alphaMin = std::min(range.alphaMin, a);
            range.alphaMax = std::max(range.alphaMax, a);
        }
    }
    validateRadialRange(range);
    return range;
}

// ---------------------------------------------------------------------------
// Basis
// ---------------------------------------------------------------------------

RadialBasis::RadialBasis(const RadialRange& range, RadialBasisTables tables)
    : range_(range), tables_(std::move(tables)) {
    validateRadialRange(range_);
    const int J = tables_.size;
    const int N = tables_.nodeCount;
    if (J < 1 || J > 64) throw Error("radial basis", "size must be 1 .. 64, got " + num(J));
    if (N < 2 || N > 1000000) {
        throw Error("radial basis", "node count must be 2 .. 1e6, got " + num(N));
    }
    if (tables_.values.size() != static_cast<size_t>(N) * J) {
        throw Error("radial basis", "table holds " + num(double(tables_.values.size())) +
                                        " values, expected nodes x size = " + num(double(N) * J));
    }
    for (float v : tables_.values) {
        if (!std::isfinite(v)) throw Error("radial basis", "table holds a non-finite value");
    }
    const double p = tables_.normExponent;
    if (!std::isfinite(p) || p < 1.0 || p > 3.0) {
        throw Error("radial basis", "norm exponent must be in [1, 3], got " + num(p));
    }

    // Nodes r_k = r0 sinh(k h), r_{N-1} = rMax.
    r0_ = gridOrigin(range_);
    const double span = std::asinh(range_.rMax / r0_);
    step_ = span / (N - 1);
    invStep_ = 1.0 / step_;
    nodes_.resize(N);
    for (int k = 0; k < N; ++k) nodes_[k] = r0_ * std::sinh(k * step_);
    nodes_[0] = 0.0;
    nodes_[N - 1] = range_.rMax;
    invSpacing_.resize(N - 1);
    for (int k = 0; k + 1 < N; ++k) {
        if (!(nodes_[k + 1] > nodes_[k])) {
            throw Error("radial basis", "node count too large for the range (nodes coincide)");
        }
        invSpacing_[k] = 1.0 / (nodes_[k + 1] - nodes_[k]);
    }

    // c_j = int B_j 2 pi r dr, exact for B_j linear in r on each interval:
    // int_a^b (B_a (b - r) + B_b (r - a)) / (b - a) r dr = (b - a)/6 (B_a (2a + b) + B_b (a + 2b)).
    integrals_.assign(J, 0.0);
    for (int k = 0; k + 1 < N; ++k) {
        const double a = nodes_[k], b = nodes_[k + 1];
        for (int j = 0; j < J; ++j) {
            const double ba = tables_.values[size_t(k) * J + j];
            const double bb = tables_.values[size_t(k + 1) * J + j];
            integrals_[j] += (b - a) / 6.0 * (ba * (2.0 * a + b) + bb * (a + 2.0 * b));
        }
    }
    for (double& c : integrals_) c *= 2.0 * kPi;

    // Quadrature of the norm int e^2 r^p dr in u = asinh(r / r0).
    const int panels = std::max(4, static_cast<int>(std::ceil(span / kNormPanel)));
    const double du = span / panels;
    for (int pi = 0; pi < panels; ++pi) {
        for (int g = 0; g < kNormPoints; ++g) {
            const double u = (pi + 0.5 + 0.5 * kGl4x[g]) * du;
            const double r = r0_ * std::sinh(u);
            quadR_.push_back(r);
            quadW_.push_back(0.5 * du * kGl4w[g] * r0_ * std::cosh(u) * std::pow(r, p));
        }
    }
    const int Q = static_cast<int>(quadR_.size());
    quadB_.resize(size_t(Q) * J);
    for (int q = 0; q < Q; ++q) {
        int k;
        double f;
        locate(quadR_[q], k, f);
        for (int j = 0; j < J; ++j) {
            quadB_[size_t(q) * J + j] = (1.0 - f) * tables_.values[size_t(k) * J + j] +
                                        f * tables_.values[size_t(k + 1) * J + j];
        }
    }
    Eigen::MatrixXd gram = Eigen::MatrixXd::Zero(J, J);
    for (int q = 0; q < Q; ++q) {
        const Eigen::Map<const Eigen::VectorXd> b(&quadB_[size_t(q) * J], J);
        gram.noalias() += quadW_[q] * b * b.transpose();
    }
    // Equilibrate so that the dependence test does not depend on the profiles' scale.
    Eigen::VectorXd scale(J);
    for (int j = 0; j < J; ++j) {
        if (!(gram(j, j) > 0.0)) throw Error("radial basis", "profile " + num(j) + " is zero");
        scale(j) = 1.0 / std::sqrt(gram(j, j));
    }
    const Eigen::MatrixXd unit = scale.asDiagonal() * gram * scale.asDiagonal();
    const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(unit);
    if (eig.info() != Eigen::Success || !(eig.eigenvalues()(0) > 1e-13 * eig.eigenvalues()(J - 1))) {
        throw Error("radial basis", "profiles are linearly dependent in the fit norm");
    }
    const Eigen::MatrixXd unitInverse = eig.eigenvectors() *
                                        eig.eigenvalues().cwiseInverse().asDiagonal() *
                                        eig.eigenvectors().transpose();
    const Eigen::MatrixXd inverse = scale.asDiagonal() * unitInverse * scale.asDiagonal();
    gramInverse_.resize(size_t(J) * J);
    for (int i = 0; i < J; ++i) {
        for (int j = 0; j < J; ++j) gramInverse_[size_t(i) * J + j] = inverse(i, j);
    }
    gramInverseC_.assign(J, 0.0);
    for (int i = 0; i < J; ++i) {
        for (int j = 0; j < J; ++j) gramInverseC_[i] += inverse(i, j) * integrals_[j];
    }
    cGramInverseC_ = 0.0;
    for (int j = 0; j < J; ++j) cGramInverseC_ += integrals_[j] * gramInverseC_[j];
    if (!(cGramInverseC_ > 0.0)) {
        throw Error("radial basis", "profiles have no integral: the constraint cannot hold");
    }
}

void RadialBasis::locate(double r, int& k, double& f) const {
    const int N = tables_.nodeCount;
    if (!(r < range_.rMax)) {
        k = N - 2;
        f = 1.0;
        return;
    }
    if (!(r > 0.0)) {
        k = 0;
        f = 0.0;
        return;
    }
    k = std::min(N - 2, static_cast<int>(std::asinh(r / r0_) * invStep_));
    // asinh / sinh rounding can put r just outside [r_k, r_k+1].
    if (k > 0 && r < nodes_[k]) --k;
    else if (k < N - 2 && r > nodes_[k + 1]) ++k;
    f = std::clamp((r - nodes_[k]) * invSpacing_[k], 0.0, 1.0);
}

double RadialBasis::profile(int j, double r) const {
    int k;
    double f;
    locate(r, k, f);
    const int J = tables_.size;
    return (1.0 - f) * tables_.values[size_t(k) * J + j] + f * tables_.values[size_t(k + 1) * J + j];
}

void RadialBasis::evaluate(double r, float* out) const {
    int k;
    double f;
    locate(r, k, f);
    const int J = tables_.size;
    const float* a = &tables_.values[size_t(k) * J];
    const float* b = a + J;
    const float ff = static_cast<float>(f);
    for (int j = 0; j < J; ++j) out[j] = a[j] + ff * (b[j] - a[j]);
}

double RadialBasis::fit(const std::vector<double>& weights, double r) const {
    int k;
    double f;
    locate(r, k, f);
    const int J = tables_.size;
    double s = 0.0;
    for (int j = 0; j < J; ++j) {
        s += weights[j] * ((1.0 - f) * tables_.values[size_t(k) * J + j] +
                           f * tables_.values[size_t(k + 1) * J + j]);
    }
    return s;
}

bool RadialBasis::covers(const DipoleChannel& d) const {
    if (!(d.sigmaTr > 0.0) || !(d.alphaPrime < 1.0)) return false;
    if (!(d.zr >= range_.zrMin * (1.0 - kCoverSlack)) || !(d.zr <= range_.zrMax * (1.0 + kCoverSlack))) {
        return false;
    }
    if (!(d.alphaPrime >= range_.alphaMin * (1.0 - kCoverSlack))) return false;
    if (!(1.0 - d.alphaPrime >= (1.0 - range_.alphaMax) * (1.0 - kCoverSlack))) return false;
    const double ratio = d.zv / d.zr;
    return std::fabs(ratio - virtualRatio(range_.eta)) <= kCoverSlack * ratio;
}

void RadialBasis::requireCovered(const Material& m, double sizeFactor) const {
    if (!std::isfinite(sizeFactor) || !(sizeFactor > 0.0)) {
        throw Error("size factor", "must be finite and > 0, got " + num(sizeFactor));
    }
    const std::string name = m.name.empty() ? "material" : m.name;
    if (m.eta != range_.eta) {
        throw Error(name, "eta = " + num(m.eta) + " differs from the basis range's eta " +
                              num(range_.eta));
    }
    for (int c = 0; c < 3; ++c) {
        const DipoleChannel d =
            makeDipoleChannel(sizeFactor * m.sigmaSPrime[c], sizeFactor * m.sigmaA[c], m.eta);
        if (covers(d)) continue;
        const std::string where = std::string("channel ") + channelName(c) + " at size factor " +
                                  num(sizeFactor) + ": ";
        std::string reason;
        if (!(m.sigmaA[c] > 0.0)) {
            reason = "sigma_a = 0 (alpha' = 1) is outside every radial basis range";
        } else if (d.zr < range_.zrMin) {
            reason = "z_r = " + num(d.zr) + " mm is below the basis range's z_r min " +
                     num(range_.zrMin) + " mm";
        } else if (d.zr > range_.zrMax) {
            reason = "z_r = " + num(d.zr) + " mm is above the basis range's z_r max " +
                     num(range_.zrMax) + " mm";
        } else if (d.alphaPrime < range_.alphaMin) {
            reason = "alpha' = " + num(d.alphaPrime) + " is below the basis range's alpha' min " +
                     num(range_.alphaMin);
        } else {
            reason = "alpha' = " + num(d.alphaPrime) + " is above the basis range's alpha' max " +
                     num(range_.alphaMax);
        }
        throw Error(name, where + reason);
    }
}

std::vector<double> RadialBasis::weights(const DipoleChannel& d) const {
    const int J = tables_.size;
    const int Q = static_cast<int>(quadR_.size());
    double b[64] = {};
    for (int q = 0; q < Q; ++q) {
        const double v = quadW_[q] * dipoleRd(d, quadR_[q]);
        const double* row = &quadB_[size_t(q) * J];
        for (int j = 0; j < J; ++j) b[j] += v * row[j];
    }
    // Unconstrained normal equations w0 = G^-1 b, then the Lagrange correction along
    // G^-1 c that puts the integral on its exact value.
    std::vector<double> w(J, 0.0);
    for (int i = 0; i < J; ++i) {
        const double* row = &gramInverse_[size_t(i) * J];
        double s = 0.0;
        for (int j = 0; j < J; ++j) s += row[j] * b[j];
        w[i] = s;
    }
    double cw = 0.0;
    for (int j = 0; j < J; ++j) cw += integrals_[j] * w[j];
    const double lambda = (dipoleDiffuseReflectanceWithin(d, range_.rMax) - cw) / cGramInverseC_;
    for (int j = 0; j < J; ++j) w[j] += lambda * gramInverseC_[j];
    return w;
}

std::array<std::vector<double>, 3> RadialBasis::materialWeights(const Material& m,
                                                                double sizeFactor) const {
    requireCovered(m, sizeFactor);
    std::array<std::vector<double>, 3> out;
    for (int c = 0; c < 3; ++c) {
        out[c] = weights(
            makeDipoleChannel(sizeFactor * m.sigmaSPrime[c], sizeFactor * m.sigmaA[c], m.eta));
    }
    return out;
}

RadialFitError RadialBasis::fitError(const DipoleChannel& d) const {
    return fitError(d, weights(d));
}

RadialFitError RadialBasis::fitError(const DipoleChannel& d,
                                     const std::vector<double>& weights) const {
    const int N = tables_.nodeCount;
    const int J = tables_.size;
    std::vector<double> atNode(N, 0.0);
    for (int k = 0; k < N; ++k) {
        double s = 0.0;
        for (int j = 0; j < J; ++j) s += weights[j] * tables_.values[size_t(k) * J + j];
        atNode[k] = s;
    }
    const double total = dipoleDiffuseReflectanceWithin(d, range_.rMax);
    double l1 = 0.0, cumulative = 0.0, disk = 0.0;
    double e1 = 0.0, e2 = 0.0, m1 = 0.0, m2 = 0.0, fitIntegral = 0.0;
    for (int k = 0; k + 1 < N; ++k) {
        const double a = nodes_[k], h = nodes_[k + 1] - nodes_[k];
        double piece = 0.0;
        for (int g = 0; g < 3; ++g) {
            const double t = 0.5 + 0.5 * kGl3x[g];
            const double r = a + t * h;
            const double fitValue = (1.0 - t) * atNode[k] + t * atNode[k + 1];
            const double rd = dipoleRd(d, r);
            const double dA = 0.5 * h * kGl3w[g] * 2.0 * kPi * r;
            const double e = fitValue - rd;
            piece += e * dA;
            l1 += std::fabs(e) * dA;
            fitIntegral += fitValue * dA;
            e1 += e * r * dA;
            e2 += e * r * r * dA;
            m1 += rd * r * dA;
            m2 += rd * r * r * dA;
        }
        cumulative += piece;
        disk = std::max(disk, std::fabs(cumulative));
    }
    double exactIntegral = 0.0;
    for (int j = 0; j < J; ++j) exactIntegral += weights[j] * integrals_[j];
    RadialFitError out;
    out.l1 = l1 / total;
    out.integral = std::fabs(exactIntegral - total) / total;
    out.moment1 = std::fabs(e1) / m1;
    out.moment2 = std::fabs(e2) / m2;
    out.disk = disk / total;
    return out;
}

double RadialBasis::halfWidth(int j) const {
    const int N = tables_.nodeCount;
    const int J = tables_.size;
    // |B_j| 2 pi r integrated per interval (3-point Gauss of the linear interpolant).
    std::vector<double> cumulative(N, 0.0);
    for (int k = 0; k + 1 < N; ++k) {
        const double a = nodes_[k], h = nodes_[k + 1] - nodes_[k];
        const double ba = tables_.values[size_t(k) * J + j];
        const double bb = tables_.values[size_t(k + 1) * J + j];
        double s = 0.0;
        for (int g = 0; g < 3; ++g) {
            const double t = 0.5 + 0.5 * kGl3x[g];
            s += 0.5 * h * kGl3w[g] * std::fabs((1.0 - t) * ba + t * bb) * 2.0 * kPi * (a + t * h);
        }
        cumulative[k + 1] = cumulative[k] + s;
    }
    const double half = 0.5 * cumulative[N - 1];
    for (int k = 0; k + 1 < N; ++k) {
        if (cumulative[k + 1] >= half) {
            const double t = (half - cumulative[k]) / std::max(cumulative[k + 1] - cumulative[k], 1e-300);
            return nodes_[k] + t * (nodes_[k + 1] - nodes_[k]);
        }
    }
    return range_.rMax;
}

// ---------------------------------------------------------------------------
// Constructions
// ---------------------------------------------------------------------------

RadialBasis makeRadialBasis(const RadialRange& range, const RadialBasisOptions& options) {
    validateRadialRange(range);
    const int J = options.size;
    if (J < 1 || J > 64) {
        throw Error("radial basis options", "size must be 1 .. 64, got " + num(J));
    }
    const double p = options.normExponent;
    if (!std::isfinite(p) || p < 1.0 || p > 3.0) {
        throw Error("radial basis options", "norm exponent must be in [1, 3], got " + num(p));
    }
    if (!std::isfinite(options.gridStep) || !(options.gridStep > 0.0) || options.gridStep > 0.25) {
        throw Error("radial basis options", "grid step must be in (0, 0.25], got " +
                                                num(options.gridStep));
    }
    RadialBasisTables tables;
    tables.size = J;
    tables.nodeCount = nodeCountFor(range, options.gridStep);
    tables.construction = options.construction;
    tables.normExponent = p;
    const int N = tables.nodeCount;
    // A provisional basis gives the node radii and the norm's quadrature.
    RadialBasisTables probe = tables;
    probe.size = 1;
    probe.values.assign(N, 1.0f);
    const RadialBasis grid(range, probe);
    const std::vector<double>& nodes = grid.nodes();
    const std::vector<double>& quadR = grid.quadR_;
    const std::vector<double>& quadW = grid.quadW_;
    const int Q = static_cast<int>(quadR.size());

    Eigen::MatrixXd atNodes(N, J);  // the profiles before rounding to float
    if (options.construction == RadialConstruction::ExpLadder) {
        // e^(-r/l) / (2 pi l^2) has unit integral over the plane; l from half the
        // narrowest z_r (the peak) to rMax (the slowest tails are ~1/r^3 out to rMax).
        const double lo = 0.5 * range.zrMin, hi = range.rMax;
        for (int j = 0; j < J; ++j) {
            const double l = J == 1 ? lo : lo * std::pow(hi / lo, static_cast<double>(j) / (J - 1));
            for (int k = 0; k < N; ++k) atNodes(k, j) = std::exp(-nodes[k] / l) / (2.0 * kPi * l * l);
        }
    } else {
        // Snapshots normalised to unit integral over [0, rMax] (a material's weights are
        // then proportional to its total reflectance), rows weighted by the norm.
        const std::vector<DipoleChannel> snaps = snapshots(range);
        const int S = static_cast<int>(snaps.size());
        if (S < J) {
            throw Error("radial basis options", "size " + num(J) + " exceeds the " + num(S) +
                                                    " snapshots of this range");
        }
        Eigen::MatrixXd weighted(Q, S);
        std::vector<double> norm(S);
        for (int n = 0; n < S; ++n) {
            norm[n] = 1.0 / dipoleDiffuseReflectanceWithin(snaps[n], range.rMax);
            for (int q = 0; q < Q; ++q) {
                weighted(q, n) = std::sqrt(quadW[q]) * dipoleRd(snaps[n], quadR[q]) * norm[n];
            }
        }
        // Each basis profile is a combination of snapshots: coefficients (S x J).
        Eigen::MatrixXd coeff = Eigen::MatrixXd::Zero(S, J);
        if (options.construction == RadialConstruction::Pca) {
            const Eigen::BDCSVD<Eigen::MatrixXd> svd(weighted, Eigen::ComputeThinV);
            const Eigen::VectorXd& sv = svd.singularValues();
            if (!(sv(J - 1) > 1e-14 * sv(0))) {
                throw Error("radial basis options", "range too narrow for " + num(J) + " profiles");
            }
            // u_j = M v_j / s_j: orthonormal in the discrete norm.
            for (int j = 0; j < J; ++j) coeff.col(j) = svd.matrixV().col(j) / sv(j);
        } else {
            // Greedy: add the snapshot worst represented by the profiles so far
            // (largest residual in the norm), orthonormalised (Gram-Schmidt, twice).
            Eigen::MatrixXd basisQ(Q, J);
            Eigen::VectorXd residual2 = weighted.colwise().squaredNorm().transpose();
            for (int j = 0; j < J; ++j) {
                int pick = 0;
                residual2.maxCoeff(&pick);
                Eigen::VectorXd v = weighted.col(pick);
                Eigen::VectorXd a = Eigen::VectorXd::Zero(S);
                a(pick) = 1.0;
                for (int pass = 0; pass < 2; ++pass) {
                    for (int i = 0; i < j; ++i) {
                        const double dot = basisQ.col(i).dot(v);
                        v -= dot * basisQ.col(i);
                        a -= dot * coeff.col(i);
                    }
                }
                const double len = v.norm();
                if (!(len > 1e-14)) {
                    throw Error("radial basis options",
                                "range too narrow for " + num(J) + " profiles");
                }
                basisQ.col(j) = v / len;
                coeff.col(j) = a / len;
                const Eigen::VectorXd proj = weighted.transpose() * basisQ.col(j);
                residual2 -= proj.cwiseAbs2();
            }
        }
        Eigen::MatrixXd snapAtNodes(N, S);
        for (int n = 0; n < S; ++n) {
            for (int k = 0; k < N; ++k) snapAtNodes(k, n) = dipoleRd(snaps[n], nodes[k]) * norm[n];
        }
        atNodes = snapAtNodes * coeff;
    }
    // Sign convention: every profile has a positive integral (else a positive value at 0).
    for (int j = 0; j < J; ++j) {
        double integral = 0.0;
        for (int k = 0; k + 1 < N; ++k) {
            integral += (atNodes(k, j) + atNodes(k + 1, j)) * (nodes[k + 1] * nodes[k + 1] - nodes[k] * nodes[k]);
        }
        if (integral < 0.0 || (integral == 0.0 && atNodes(0, j) < 0.0)) atNodes.col(j) *= -1.0;
    }
    tables.values.resize(size_t(N) * J);
    for (int k = 0; k < N; ++k) {
        for (int j = 0; j < J; ++j) tables.values[size_t(k) * J + j] = static_cast<float>(atNodes(k, j));
    }
    return RadialBasis(range, std::move(tables));
}

RadialBasis balancedForDipoles(const RadialBasis& basis, const std::vector<DipoleChannel>& dipoles,
                               const std::vector<double>& importance) {
    if (dipoles.empty()) throw Error("radial basis", "no dipoles to balance the basis for");
    if (!importance.empty() && importance.size() != dipoles.size())
        throw Error("radial basis", "one importance weight per dipole needed");
    const int J = basis.size();
    Eigen::MatrixXd G = Eigen::MatrixXd::Zero(J, J);
    double total = 0.0;
    for (size_t i = 0; i < dipoles.size(); ++i) {
        const double weight = importance.empty() ? 1.0 : importance[i];
        if (!(weight >= 0.0) || !std::isfinite(weight))
            throw Error("radial basis", "importance weights must be finite and >= 0");
        const std::vector<double> w = basis.weights(dipoles[i]);
        const Eigen::Map<const Eigen::VectorXd> v(w.data(), J);
        G += weight * v * v.transpose();
        total += weight;
    }
    if (!(total > 0.0)) throw Error("radial basis", "importance weights are all 0");
    G /= total;
    const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eigen(G);
    if (eigen.info() != Eigen::Success) throw Error("radial basis", "the weights' second moments have no eigenbasis");
    const double largest = std::max(eigen.eigenvalues().maxCoeff(), 0.0);
    if (!(largest > 0.0)) throw Error("radial basis", "the dipoles' weights are all zero");
    Eigen::VectorXd root(J);
    for (int j = 0; j < J; ++j) root[j] = std::sqrt(std::max(eigen.eigenvalues()[j], 1e-9 * largest));
    const Eigen::MatrixXd A = eigen.eigenvectors() * root.asDiagonal();
    RadialBasisTables tables = basis.tables();
    const int N = tables.nodeCount;
    for (int k = 0; k < N; ++k) {
        Eigen::VectorXd row(J);
        for (int j = 0; j < J; ++j) row[j] = tables.values[size_t(k) * size_t(J) + size_t(j)];
        const Eigen::VectorXd balanced = A.transpose() * row;
        for (int j = 0; j < J; ++j) tables.values[size_t(k) * size_t(J) + size_t(j)] = float(balanced[j]);
    }
    return RadialBasis(basis.range(), std::move(tables));
}

}  // namespace prt
