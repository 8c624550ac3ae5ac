#include "precompute/passes/phase_factoring.h"

#include <Eigen/Dense>
#include <Eigen/Eigenvalues>
#include <Eigen/SVD>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <string>

#include "common/bssrdf.h"
#include "common/error.h"

namespace prt {

namespace {

void checkArguments(double g, int terms, int mapSize) {
    if (!(g > -1.0 && g < 1.0)) {
        throw Error("g", "Henyey-Greenstein asymmetry must satisfy -1 < g < 1, got " + std::to_string(g));
    }
    if (!isPowerOfTwo(mapSize) || mapSize > kMaxPhaseMapSize) {
        throw Error("phase map size", "must be a power of two in [1, " + std::to_string(kMaxPhaseMapSize) +
                                          "], got " + std::to_string(mapSize));
    }
    const int count = kCubeFaces * mapSize * mapSize;
    if (terms < 1 || terms > count) {
        throw Error("phase terms", "must be in [1, 6 M^2 = " + std::to_string(count) + "], got " +
                                       std::to_string(terms));
    }
}

// Texel-centre directions, square roots of the solid angles and the antipodal
// permutation, all in the flat texel order of cubemap.h.
struct Tabulation {
    std::vector<glm::dvec3> direction;
    std::vector<double> sqrtOmega;
    std::vector<int> antipode;  // texel index of -direction[t]
};

Tabulation tabulate(int n) {
    Tabulation tab;
    const size_t count = size_t(kCubeFaces) * n * n;
    tab.direction.resize(count);
    tab.sqrtOmega.resize(count);
    tab.antipode.resize(count);
    const std::vector<double> omega = faceSolidAngles(n);
    for (int f = 0; f < kCubeFaces; ++f)
        for (int j = 0; j < n; ++j)
            for (int i = 0; i < n; ++i) {
                const size_t t = (size_t(f) * n + j) * n + i;
                tab.direction[t] = texelDirection(n, f, i, j);
                tab.sqrtOmega[t] = std::sqrt(omega[size_t(j) * n + i]);
            }
    for (size_t t = 0; t < count; ++t) {
        const TexelCoord c = directionToTexel(n, -tab.direction[t]);
        const size_t r = (size_t(c.face) * n + c.j) * n + c.i;
        // The texel centres of a cubemap are symmetric under d -> -d (+X texel (i, j) is
        // the antipode of -X texel (i, N-1-j), and so on), exactly in floating point
        // for power-of-two N. The symmetric-eigen route relies on it.
        if (glm::length(tab.direction[r] + tab.direction[t]) > 1e-14) {
            throw Error("factorPhaseFunction", "internal: cubemap texel centres are not antipodally symmetric");
        }
        tab.antipode[t] = int(r);
    }
    // Antipodal texels have the same solid angle (the faces are congruent); make the
    // two stored values bit-identical so the weighted matrices are exactly symmetric.
    for (size_t t = 0; t < count; ++t) {
        const size_t r = size_t(tab.antipode[t]);
        if (std::abs(tab.sqrtOmega[r] - tab.sqrtOmega[t]) > 1e-12 * tab.sqrtOmega[t]) {
            throw Error("factorPhaseFunction", "internal: antipodal texels differ in solid angle");
        }
        if (r > t) tab.sqrtOmega[r] = tab.sqrtOmega[t];
    }
    return tab;
}

// Writes the K factors: lightTable/viewTable in double and the float cubemaps.
// u(t, k) and v(t, k) are the k-th columns of U and V of Q = U S V^T.
template <typename UFn, typename VFn>
void storeFactors(PhaseFactorization& f, const Tabulation& tab, int terms, UFn u, VFn v) {
    const int n = f.mapSize;
    const size_t count = tab.direction.size();
    f.lightTable.assign(size_t(terms) * count, 0.0);
    f.viewTable.assign(size_t(terms) * count, 0.0);
    f.lightMaps.clear();
    f.viewMaps.clear();
    for (int k = 0; k < terms; ++k) {
        const double root = std::sqrt(f.singularValues[size_t(k)]);
        Cubemap light(n, 1), view(n, 1);
        for (size_t t = 0; t < count; ++t) {
            const double gk = root * u(t, k) / tab.sqrtOmega[t];
            const double hk = root * v(t, k) / tab.sqrtOmega[t];
            f.lightTable[size_t(k) * count + t] = gk;
            f.viewTable[size_t(k) * count + t] = hk;
            light.data()[t] = float(gk);
            view.data()[t] = float(hk);
        }
        f.lightMaps.push_back(std::move(light));
        f.viewMaps.push_back(std::move(view));
    }
}

// The symmetric-eigen route (see PhaseSolver::SymmetricEigen in phase_factoring.h).
//
// Qs[a][c] = sqrt(dOmega_a) p_HG(dot(a, c)) sqrt(dOmega_c) is symmetric, and the phase
// of the pair (a, b) is p_HG(dot(a, -b)) = p_HG(dot(a, direction[R b])), so
// Q[a][b] = Qs[a][R b], Q = Qs R. Qs also commutes with R (p_HG(dot(-a, -c)) =
// p_HG(dot(a, c)), equal solid angles), so it splits into the functions that are
// even and odd under d -> -d. With H the texels of the faces +X, +Y, +Z (their
// antipodes are the texels of -X, -Y, -Z) and, for x, y in H,
//     A[x][y] = Qs[x][y],  B[x][y] = Qs[x][R y],
// the even eigenvectors are (v on H, v on R H) / sqrt 2 with (A + B) v = l v and the
// odd ones (v, -v) / sqrt 2 with (A - B) v = l v: two eigenproblems of size 3 M^2
// instead of one of 6 M^2 (about 4x less work). For an eigenvector e_k of parity
// q_k = +-1, e_k[R b] = q_k e_k[b], so
//     Q = sum_k l_k e_k (R e_k)^T = sum_k |l_k| e_k (sign(l_k) q_k e_k)^T,
// an SVD with U[:, k] = e_k, s_k = |l_k|, V[:, k] = sign(l_k) q_k e_k: every view map
// is + or - its light map, h_k = sign(l_k) q_k g_k (and h_k(b) = sign(l_k) g_k(-b)).
// The l_k are the (discretised) Funk-Hecke coefficients g^l of the HG kernel: q_k =
// (-1)^l, and l_k < 0 exactly for odd l when g < 0.
void factorSymmetric(PhaseFactorization& f, const Tabulation& tab, int terms) {
    std::vector<size_t> half;  // H: texels of the positive faces 0, 2, 4
    const size_t faceTexels = size_t(f.mapSize) * f.mapSize;
    for (size_t t = 0; t < tab.direction.size(); ++t)
        if ((t / faceTexels) % 2 == 0) half.push_back(t);
    const Eigen::Index m = Eigen::Index(half.size());
    Eigen::MatrixXd sum(m, m), difference(m, m);
    for (Eigen::Index y = 0; y < m; ++y)
        for (Eigen::Index x = y; x < m; ++x) {
            const size_t tx = half[size_t(x)], ty = half[size_t(y)];
            const glm::dvec3& dx = tab.direction[tx];
            const glm::dvec3& dy = tab.direction[ty];
            const double w = tab.sqrtOmega[tx] * tab.sqrtOmega[ty];
            // direction[R y] = -dy exactly, so dot(dx, direction[R y]) = -dot(dx, dy).
            const double c = glm::dot(dx, dy);
            const double same = w * henyeyGreenstein(f.g, c);
            const double opposite = w * henyeyGreenstein(f.g, -c);
            sum(x, y) = sum(y, x) = same + opposite;
            difference(x, y) = difference(y, x) = same - opposite;
        }

    struct Mode {
        double lambda;
        int parity;          // +1 even, -1 odd
        Eigen::Index column;  // in the eigenvector matrix of that parity
    };
    std::vector<Mode> modes;
    modes.reserve(tab.direction.size());
    Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> even, odd;
    for (int parity : {1, -1}) {
        Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>& solver = parity > 0 ? even : odd;
        solver.compute(parity > 0 ? sum : difference, Eigen::ComputeEigenvectors);
        if (solver.info() != Eigen::Success) {
            throw Error("factorPhaseFunction", "symmetric eigendecomposition did not converge");
        }
        for (Eigen::Index i = 0; i < m; ++i) modes.push_back({solver.eigenvalues()(i), parity, i});
    }
    // Sort by |lambda| descending; ties keep their order (deterministic).
    std::stable_sort(modes.begin(), modes.end(),
                     [](const Mode& x, const Mode& y) { return std::abs(x.lambda) > std::abs(y.lambda); });
    f.singularValues.resize(modes.size());
    for (size_t k = 0; k < modes.size(); ++k) f.singularValues[k] = std::abs(modes[k].lambda);

    // Full-length eigenvectors of the K kept modes.
    const size_t count = tab.direction.size();
    std::vector<double> u(size_t(terms) * count), v(size_t(terms) * count);
    for (int k = 0; k < terms; ++k) {
        const Mode& mode = modes[size_t(k)];
        const Eigen::MatrixXd& vectors = (mode.parity > 0 ? even : odd).eigenvectors();
        const double viewSign = (mode.lambda < 0.0 ? -1.0 : 1.0) * mode.parity;
        for (Eigen::Index x = 0; x < m; ++x) {
            const double value = vectors(x, mode.column) / std::sqrt(2.0);
            const size_t t = half[size_t(x)];
            const size_t r = size_t(tab.antipode[t]);
            u[size_t(k) * count + t] = value;
            u[size_t(k) * count + r] = mode.parity * value;
            v[size_t(k) * count + t] = viewSign * value;
            v[size_t(k) * count + r] = viewSign * mode.parity * value;
        }
    }
    storeFactors(
        f, tab, terms, [&](size_t t, int k) { return u[size_t(k) * count + t]; },
        [&](size_t t, int k) { return v[size_t(k) * count + t]; });
}

// The direct SVD routes: Q[a][b] = sqrt(dOmega_a) p_HG(dot(a, -b)) sqrt(dOmega_b).
template <typename Svd>
void factorSvd(PhaseFactorization& f, const Tabulation& tab, int terms) {
    const Eigen::Index count = Eigen::Index(tab.direction.size());
    Eigen::MatrixXd q(count, count);
    for (Eigen::Index b = 0; b < count; ++b)
        for (Eigen::Index a = 0; a < count; ++a) {
            const double p =
                henyeyGreensteinDirections(f.g, tab.direction[size_t(a)], -tab.direction[size_t(b)]);
            q(a, b) = tab.sqrtOmega[size_t(a)] * p * tab.sqrtOmega[size_t(b)];
        }
    const Svd svd(q, Eigen::ComputeThinU | Eigen::ComputeThinV);
    if (svd.info() != Eigen::Success) throw Error("factorPhaseFunction", "SVD did not converge");
    const Eigen::VectorXd& s = svd.singularValues();  // descending
    f.singularValues.assign(s.data(), s.data() + s.size());
    const Eigen::MatrixXd& u = svd.matrixU();
    const Eigen::MatrixXd& v = svd.matrixV();
    storeFactors(
        f, tab, terms, [&](size_t t, int k) { return u(Eigen::Index(t), k); },
        [&](size_t t, int k) { return v(Eigen::Index(t), k); });
}

}  // namespace

const char* phaseSolverName(PhaseSolver solver) {
    switch (solver) {
        case PhaseSolver::SymmetricEigen: return "symmetric-eigen";
        case PhaseSolver::BdcSvd: return "bdcsvd";
        case PhaseSolver::JacobiSvd: return "jacobisvd";
    }
    return "unknown";
}

double PhaseFactorization::evaluate(const glm::dvec3& a, const glm::dvec3& b) const {
    double sum = 0.0;
    for (size_t k = 0; k < lightMaps.size(); ++k) {
        sum += double(lightMaps[k].sampleBilinear(a, 0)) * double(viewMaps[k].sampleBilinear(b, 0));
    }
    return sum;
}

double PhaseFactorization::evaluateTexels(size_t a, size_t b) const {
    const size_t count = texelCount();
    if (a >= count || b >= count) {
        throw Error("evaluateTexels", "texel index out of range (" + std::to_string(a) + ", " +
                                          std::to_string(b) + " >= " + std::to_string(count) + ")");
    }
    double sum = 0.0;
    const size_t k = size_t(terms());
    for (size_t i = 0; i < k; ++i) sum += lightTable[i * count + a] * viewTable[i * count + b];
    return sum;
}

PhaseFactorization factorPhaseFunction(double g, int terms, int mapSize) {
    return factorPhaseFunction(g, terms, mapSize, PhaseSolver::SymmetricEigen);
}

PhaseFactorization factorPhaseFunction(double g, int terms, int mapSize, PhaseSolver solver) {
    checkArguments(g, terms, mapSize);
    PhaseFactorization f;
    f.g = g;
    f.mapSize = mapSize;
    const Tabulation tab = tabulate(mapSize);
    switch (solver) {
        case PhaseSolver::SymmetricEigen: factorSymmetric(f, tab, terms); break;
        case PhaseSolver::BdcSvd: factorSvd<Eigen::BDCSVD<Eigen::MatrixXd>>(f, tab, terms); break;
        case PhaseSolver::JacobiSvd: factorSvd<Eigen::JacobiSVD<Eigen::MatrixXd>>(f, tab, terms); break;
        default: throw Error("factorPhaseFunction", "unknown solver");
    }
    return f;
}

double phaseApproximationError(const PhaseFactorization& f, int terms) {
    const int count = int(f.singularValues.size());
    if (terms < 0 || terms > count) {
        throw Error("phase terms", "must be in [0, " + std::to_string(count) + "], got " + std::to_string(terms));
    }
    // Sum the tail directly (not total minus head) so small errors keep their digits.
    double tail = 0.0, total = 0.0;
    for (int k = count - 1; k >= 0; --k) {
        const double s2 = f.singularValues[size_t(k)] * f.singularValues[size_t(k)];
        total += s2;
        if (k >= terms) tail += s2;
    }
    if (!(total > 0.0)) throw Error("phaseApproximationError", "factorisation has no singular values");
    return std::sqrt(tail / total);
}

}  // namespace prt
