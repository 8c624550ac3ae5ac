// prt-phase-table: how well the K-term separable (SVD) approximation of the
// Henyey-Greenstein phase function reproduces it (Wang et al. 2005, Fig. 6f), for
// several g and K (docs/phase.md). Three error tables:
//   1. table: ||Q - Q_K||_F / ||Q||_F from the singular values (phaseApproximationError),
//      the solid-angle weighted relative RMS error over the tabulated direction pairs;
//   2. sphere (analytic): the same for the continuous operator on the sphere, whose
//      singular values are |g|^l with multiplicity 2l + 1 (Funk-Hecke), the limit M -> inf;
//   3. random pairs: relative RMS error of PhaseFactorization::evaluate (bilinear float
//      cubemaps) against henyeyGreenstein over uniformly random direction pairs (a, b),
//      so the tabulation and interpolation error is included. Column "all" is the
//      floor of that error: the bilinear interpolation of the full table P, which is
//      what evaluate() returns when all 6 M^2 terms are kept.
// With --markdown FILE the same tables are written as Markdown.

#include <CLI/CLI.hpp>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <ctime>
#include <fstream>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "common/bssrdf.h"
#include "common/cubemap.h"
#include "common/error.h"
#include "precompute/passes/phase_factoring.h"
#include "common/util.h"
#include "common/options.h"

using namespace prt;

namespace {



// Relative RMS error of the continuous K-term approximation on the sphere: the HG
// kernel has eigenvalues g^l (multiplicity 2l + 1), so the singular values are |g|^l
// and sum_l (2l + 1) g^(2l) = (1 + g^2) / (1 - g^2)^2.
double analyticError(double g, int terms) {
    const double x = g * g;
    if (x == 0.0) return 0.0;
    const double total = (1.0 + x) / ((1.0 - x) * (1.0 - x));
    double head = 0.0;
    int kept = 0;
    for (int l = 0; kept < terms; ++l) {
        const int take = std::min(2 * l + 1, terms - kept);
        head += take * std::pow(x, l);
        kept += take;
    }
    return std::sqrt(std::max(0.0, total - head) / total);
}


glm::dvec3 uniformDirection(std::mt19937_64& rng) {
    std::uniform_real_distribution<double> uniform(0.0, 1.0);
    const double z = 1.0 - 2.0 * uniform(rng);
    const double phi = 2.0 * kPi * uniform(rng);
    const double r = std::sqrt(std::max(0.0, 1.0 - z * z));
    return {r * std::cos(phi), r * std::sin(phi), z};
}

struct Row {
    double g = 0.0;
    double factorSeconds = 0.0, factorCpu = 0.0;
    double sampleSeconds = 0.0, sampleCpu = 0.0;
    std::vector<double> tableError;     // per K
    std::vector<double> analytic;       // per K
    std::vector<double> sampledError;   // per K, then one more: all terms (bilinear table)
};

std::string formatTables(const std::vector<Row>& rows, const std::vector<int>& terms, int mapSize,
                         int samples, bool markdown) {
    std::ostringstream out;
    char buffer[64];
    auto cell = [&](double v) {
        // Values that would print as 0.0000 keep their magnitude (g = 0 is rank 1).
        std::snprintf(buffer, sizeof buffer, v != 0.0 && std::abs(v) < 5e-5 ? "%.0e" : "%.4f", v);
        return std::string(buffer);
    };
    auto table = [&](const std::string& title, auto value, bool withAll, bool withTime) {
        out << (markdown ? "**" : "") << title << (markdown ? "**\n\n" : "\n");
        std::string header = markdown ? "| g |" : "      g  ";
        for (int k : terms) {
            std::snprintf(buffer, sizeof buffer, markdown ? " K = %d |" : "   K=%-4d", k);
            header += buffer;
        }
        if (withAll) header += markdown ? " all |" : "   all   ";
        if (withTime) header += markdown ? " wall / CPU (s) |" : "   wall / CPU (s)";
        out << header << "\n";
        if (markdown) {
            out << "|---:|";
            for (size_t i = 0; i < terms.size() + (withAll ? 1 : 0) + (withTime ? 1 : 0); ++i) out << "---:|";
            out << "\n";
        }
        for (const Row& row : rows) {
            std::snprintf(buffer, sizeof buffer, markdown ? "| %+.2f |" : "  %+.2f  ", row.g);
            out << buffer;
            const size_t columns = terms.size() + (withAll ? 1 : 0);
            for (size_t i = 0; i < columns; ++i) out << (markdown ? " " : " ") << cell(value(row, i))
                                                     << (markdown ? " |" : "  ");
            if (withTime) {
                std::snprintf(buffer, sizeof buffer, markdown ? " %.2f / %.2f |" : "   %.2f / %.2f",
                              withAll ? row.sampleSeconds : row.factorSeconds,
                              withAll ? row.sampleCpu : row.factorCpu);
                out << buffer;
            }
            out << "\n";
        }
        out << "\n";
    };
    table("Relative RMS error of the tabulated phase, ||Q - Q_K||_F / ||Q||_F (6 x " + std::to_string(mapSize) +
              " x " + std::to_string(mapSize) + " directions; time = tabulate + factor)",
          [](const Row& r, size_t i) { return r.tableError[i]; }, false, true);
    table("Continuous sphere, analytic (singular values |g|^l, multiplicity 2l + 1)",
          [](const Row& r, size_t i) { return r.analytic[i]; }, false, false);
    table("Relative RMS error of evaluate() (bilinear float cubemaps) on " + std::to_string(samples) +
              " uniformly random direction pairs; all = bilinear full table; time = evaluation",
          [](const Row& r, size_t i) { return r.sampledError[i]; }, true, true);
    return out.str();
}

}  // namespace

int main(int argc, char** argv) {
    return runMain("prt-phase-table", [&]() -> int {
        CLI::App app{"prt-phase-table: relative RMS error of the K-term SVD factorisation of the\n"
                     "Henyey-Greenstein phase function (Wang et al. 2005, Fig. 6f)."};
        std::vector<double> gs{-0.4, -0.25, 0.0, 0.25, 0.4};
        std::vector<int> terms{1, 2, 4, 8, 16};
        int mapSize = 16;
        int samples = 200000;
        std::uint64_t seed = 1;
        std::string solverName = "symmetric-eigen";
        std::string markdownPath;
        bool compareSolvers = false;
        app.add_option("-g,--g", gs, "HG asymmetry values")->capture_default_str()->delimiter(',');
        app.add_option("-K,--terms", terms, "Numbers of terms")->capture_default_str()->delimiter(',');
        app.add_option("-M,--map-size", mapSize, "Cubemap face size M (table of 6 M^2 x 6 M^2)")
            ->capture_default_str();
        app.add_option("-n,--samples", samples, "Random direction pairs for the evaluate() error")
            ->capture_default_str();
        app.add_option("--seed", seed, "Random seed")->capture_default_str();
        app.add_option("--solver", solverName, "symmetric-eigen | bdcsvd | jacobisvd")->capture_default_str();
        app.add_flag("--compare-solvers", compareSolvers,
                     "Also time BDCSVD on the first g and compare singular values and reconstructions");
        app.add_option("--markdown", markdownPath, "Also write the tables as Markdown to this file");
        if (const auto exitCode = parseCommandLine(app, argc, argv, "prt-phase-table")) return *exitCode;
        PhaseSolver solver;
        if (solverName == "symmetric-eigen") solver = PhaseSolver::SymmetricEigen;
        else if (solverName == "bdcsvd") solver = PhaseSolver::BdcSvd;
        else if (solverName == "jacobisvd") solver = PhaseSolver::JacobiSvd;
        else throw Error("--solver", "unknown solver '" + solverName + "'");
        if (samples < 1) throw Error("--samples", "must be >= 1");
        if (gs.empty() || terms.empty()) throw Error("prt-phase-table", "need at least one g and one K");
        if (!isPowerOfTwo(mapSize) || mapSize > kMaxPhaseMapSize) {
            throw Error("--map-size", "must be a power of two in [1, " + std::to_string(kMaxPhaseMapSize) + "]");
        }
        const int maxTerms = *std::max_element(terms.begin(), terms.end());
        if (*std::min_element(terms.begin(), terms.end()) < 1 || maxTerms > kCubeFaces * mapSize * mapSize) {
            throw Error("--terms", "each K must be in [1, 6 M^2 = " + std::to_string(kCubeFaces * mapSize * mapSize) +
                                       "]");
        }
        for (double g : gs)
            if (!(g > -1.0 && g < 1.0)) throw Error("--g", "each g must satisfy -1 < g < 1");

        // Uniform random direction pairs, the same for every g.
        std::mt19937_64 rng(seed);
        const size_t pairs = static_cast<size_t>(samples);
        std::vector<glm::dvec3> as(pairs), bs(pairs);
        std::vector<BilinearTaps> aTaps(pairs), bTaps(pairs);
        for (int i = 0; i < samples; ++i) {
            as[size_t(i)] = uniformDirection(rng);
            bs[size_t(i)] = uniformDirection(rng);
            aTaps[size_t(i)] = bilinearTaps(mapSize, as[size_t(i)]);
            bTaps[size_t(i)] = bilinearTaps(mapSize, bs[size_t(i)]);
        }
        std::vector<glm::dvec3> centres(size_t(kCubeFaces) * mapSize * mapSize);
        for (int f = 0; f < kCubeFaces; ++f)
            for (int j = 0; j < mapSize; ++j)
                for (int i = 0; i < mapSize; ++i)
                    centres[(size_t(f) * mapSize + j) * mapSize + i] = texelDirection(mapSize, f, i, j);

        std::printf("prt-phase-table: M = %d (%d x %d table), solver %s, %d random pairs (seed %llu)\n"
                    "phase p(a, b) = HG(g, dot(a, -b)); a = light propagation direction, b = refracted "
                    "view direction (both into the medium)\n\n",
                    mapSize, kCubeFaces * mapSize * mapSize, kCubeFaces * mapSize * mapSize,
                    phaseSolverName(solver), samples, static_cast<unsigned long long>(seed));
        std::fflush(stdout);
        std::vector<Row> rows;
        for (double g : gs) {
            Row row;
            row.g = g;
            Stopwatch factorWatch;
            const PhaseFactorization f = factorPhaseFunction(g, maxTerms, mapSize, solver);
            row.factorSeconds = factorWatch.seconds();
            row.factorCpu = factorWatch.cpuSeconds();
            for (int k : terms) {
                row.tableError.push_back(phaseApproximationError(f, k));
                row.analytic.push_back(analyticError(g, k));
            }

            Stopwatch sampleWatch;
            std::vector<double> squaredError(terms.size() + 1, 0.0);
            std::vector<double> byK(size_t(maxTerms) + 1, 0.0);
            double squaredReference = 0.0;
            for (int i = 0; i < samples; ++i) {
                const glm::dvec3& a = as[size_t(i)];
                const glm::dvec3& b = bs[size_t(i)];
                const double exact = henyeyGreensteinDirections(g, a, -b);
                squaredReference += exact * exact;
                // Prefix sums over k give every K from one pass over the maps.
                double partial = 0.0;
                size_t next = 0;
                for (int k = 0; k < maxTerms; ++k) {
                    partial += double(f.lightMaps[size_t(k)].sampleBilinear(a, 0)) *
                               double(f.viewMaps[size_t(k)].sampleBilinear(b, 0));
                    byK[size_t(k) + 1] = partial;
                }
                for (int k : terms) {
                    const double e = byK[size_t(k)] - exact;
                    squaredError[next++] += e * e;
                }
                // All terms: bilinear interpolation of P[a][b] = HG(dot(a, -b)) at texel centres.
                const BilinearTaps& ta = aTaps[size_t(i)];
                const BilinearTaps& tb = bTaps[size_t(i)];
                double interpolated = 0.0;
                for (int x = 0; x < 4; ++x)
                    for (int y = 0; y < 4; ++y)
                        interpolated += ta.weight[size_t(x)] * tb.weight[size_t(y)] *
                                        henyeyGreenstein(g, -glm::dot(centres[ta.texel[size_t(x)]],
                                                                      centres[tb.texel[size_t(y)]]));
                squaredError[next] += (interpolated - exact) * (interpolated - exact);
            }
            for (double e : squaredError) row.sampledError.push_back(std::sqrt(e / squaredReference));
            row.sampleSeconds = sampleWatch.seconds();
            row.sampleCpu = sampleWatch.cpuSeconds();
            std::fprintf(stderr, "g = %+.2f: factor %.2f s (CPU %.2f s), %d pairs %.2f s (CPU %.2f s)\n", g,
                         row.factorSeconds, row.factorCpu, samples, row.sampleSeconds, row.sampleCpu);
            rows.push_back(std::move(row));
        }
        std::printf("%s", formatTables(rows, terms, mapSize, samples, false).c_str());

        std::string comparison;
        if (compareSolvers) {
            const double g = gs.front();
            Stopwatch eigWatch;
            const PhaseFactorization eig = factorPhaseFunction(g, maxTerms, mapSize, PhaseSolver::SymmetricEigen);
            const double eigSeconds = eigWatch.seconds(), eigCpu = eigWatch.cpuSeconds();
            Stopwatch svdWatch;
            const PhaseFactorization svd = factorPhaseFunction(g, maxTerms, mapSize, PhaseSolver::BdcSvd);
            const double svdSeconds = svdWatch.seconds(), svdCpu = svdWatch.cpuSeconds();
            double maxSingular = 0.0;
            for (size_t k = 0; k < eig.singularValues.size(); ++k)
                maxSingular = std::max(maxSingular, std::abs(eig.singularValues[k] - svd.singularValues[k]));
            // The K-term reconstructions can differ only where K splits a group of
            // (nearly) equal singular values, so s_K and s_K+1 are printed with it.
            double maxReconstruction = 0.0, maxTable = 0.0;
            const size_t count = eig.texelCount();
            for (size_t a = 0; a < count; a += 7)
                for (size_t b = 0; b < count; b += 3) {
                    maxReconstruction = std::max(maxReconstruction,
                                                 std::abs(eig.evaluateTexels(a, b) - svd.evaluateTexels(a, b)));
                    maxTable = std::max(maxTable, henyeyGreensteinDirections(g, centres[a], -centres[b]));
                }
            const size_t k = size_t(maxTerms);
            std::ostringstream line;
            line.precision(3);
            line << "g = " << g << ", M = " << mapSize << ": symmetric-eigen " << eigSeconds << " s wall ("
                 << eigCpu << " s CPU), bdcsvd " << svdSeconds << " s wall (" << svdCpu << " s CPU); max |s_k difference| = " << maxSingular << "; K = " << maxTerms
                 << " reconstructions differ by at most " << maxReconstruction / maxTable
                 << " of max P (s_K = " << eig.singularValues[k - 1]
                 << ", s_K+1 = " << (k < count ? eig.singularValues[k] : 0.0) << ")\n";
            comparison = line.str();
            std::printf("Solver comparison: %s", comparison.c_str());
        }

        if (!markdownPath.empty()) {
            std::ofstream out(markdownPath);
            if (!out) throw Error(markdownPath, "cannot open for writing");
            out << formatTables(rows, terms, mapSize, samples, true);
            if (!comparison.empty()) out << "Solver comparison: " << comparison;
            if (!out) throw Error(markdownPath, "write failed");
            std::printf("wrote %s\n", markdownPath.c_str());
        }
        return 0;
    });
}
