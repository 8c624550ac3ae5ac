// R_d tables and the local/global split (relight/pointlight/diffusion_split.h). Asserted: the
// table reproduces dipoleRd; W_l + W_g = 1 with W_l(0) ~ 1, W_l(R_p) = 1/2 and a
// continuous slope at R_p; R_p is where the importance R_d 2 pi r crosses c (the
// paper's Skimmilk figure: 2.41 mm at c = 0.1 /mm); local + global tables = full table;
// the curvature tables against a Gaussian's closed forms, and the second-order
// expansion they serve against the sum over a cluster's points (third order left).

#include "relight/pointlight/diffusion_split.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <utility>
#include <vector>

#include "common/bssrdf.h"
#include "common/util.h"
#include "tests/test_support.h"

using namespace prt;

TEST(DiffusionSplit, TableMatchesTheDipole) {
    for (const char* name : {"Marble", "Skin1", "Ketchup", "Skimmilk"}) {
        const Material m = materialByName(name);
        const RadialTable t = diffusionTable(m, 60.0);
        const glm::dvec3 peak = dipoleRd(m, 0.0);
        for (double r = 0.0; r < 60.0; r = r * 1.07 + 1e-3) {
            const glm::dvec3 ref = dipoleRd(m, r);
            const glm::vec3 got = t(float(r * r));
            for (int c = 0; c < 3; ++c) {
                if (ref[c] < 1e-6 * peak[c]) continue;
                EXPECT_NEAR(got[c], ref[c], 1e-4 * ref[c] + 1e-12) << name << " r " << r << " channel " << c;
            }
        }
        EXPECT_EQ(t(float(60.0 * 60.0)), glm::vec3(0.0f));
    }
}

TEST(DiffusionSplit, WeightsSumToOneAndJoinSmoothlyAtRp) {
    const DiffusionSplit s{.rp = 2.4, .sharpness = 1.5};
    for (double r = 0.0; r < 30.0; r += 0.01) {
        EXPECT_DOUBLE_EQ(s.localWeight(r) + s.globalWeight(r), 1.0);
        EXPECT_GE(s.localWeight(r), 0.0);
        EXPECT_LE(s.localWeight(r), 1.0);
    }
    EXPECT_NEAR(s.localWeight(2.4), 0.5, 1e-12);
    EXPECT_GT(s.localWeight(0.0), 0.98);
    EXPECT_LT(s.localWeight(10.0), 1e-5);
    const double h = 1e-6;
    EXPECT_NEAR(s.localWeight(2.4 - h), s.localWeight(2.4 + h), 1e-5);  // continuous
    const double left = (s.localWeight(2.4) - s.localWeight(2.4 - h)) / h;
    const double right = (s.localWeight(2.4 + h) - s.localWeight(2.4)) / h;
    EXPECT_NEAR(left, -0.75, 1e-4);  // -K/2 from both sides
    EXPECT_NEAR(right, -0.75, 1e-4);
    const DiffusionSplit local{.rp = 2.4, .weights = SplitWeights::AllLocal};
    const DiffusionSplit global{.rp = 2.4, .weights = SplitWeights::AllGlobal};
    EXPECT_EQ(local.localWeight(7.0), 1.0);
    EXPECT_EQ(global.localWeight(0.0), 0.0);
}

TEST(DiffusionSplit, ImportanceRadiusIsTheLastCrossing) {
    // Chang et al. Fig. 3: Skimmilk red (sigma_s' 0.70, sigma_a 0.0014 /mm as in Jensen's
    // table; the caption's 0.0024 gives 2.37 mm), eta 1.3: R_p = 2.4141 mm.
    const Material skim = customMaterial({0.70, 0.70, 0.70}, {0.0014, 0.0014, 0.0014}, 1.3);
    EXPECT_NEAR(importanceRadius(skim, 0.1), 2.4141, 0.01);
    for (const char* name : {"Marble", "Skin1", "Skin2", "Skimmilk"}) {
        const Material m = materialByName(name);
        const double rp = importanceRadius(m, 0.1);
        ASSERT_GT(rp, 0.0) << name;
        double at = 0.0, beyond = 0.0;
        for (int c = 0; c < 3; ++c) {
            const DipoleChannel d = makeDipoleChannel(m, c);
            at = std::max(at, dipoleRd(d, rp) * 2.0 * kPi * rp);
            for (double r = rp * 1.01; r < 200.0; r *= 1.05) beyond = std::max(beyond, dipoleRd(d, r) * 2.0 * kPi * r);
        }
        EXPECT_NEAR(at, 0.1, 1e-6) << name;
        EXPECT_LT(beyond, 0.1) << name;
    }
    // A bound above the importance everywhere: no crossing. Ketchup's wide, weak
    // profile (z_r = 4 mm in red) never reaches c = 0.1 /mm: no local part to speak of.
    double ketchupPeak = 0.0;
    for (int c = 0; c < 3; ++c)
        for (double r = 1e-3; r < 100.0; r *= 1.01)
            ketchupPeak = std::max(ketchupPeak, dipoleRd(makeDipoleChannel(materialByName("Ketchup"), c), r) * 2.0 * kPi * r);
    EXPECT_LT(ketchupPeak, 0.1);
    EXPECT_EQ(importanceRadius(materialByName("Ketchup"), 0.1), 0.0);
    EXPECT_EQ(importanceRadius(materialByName("Marble"), 100.0), 0.0);
    test::expectErrorSubject([] { importanceRadius(materialByName("Marble"), 0.0); }, "--importance-bound");
}

TEST(DiffusionSplit, LocalPlusGlobalIsTheFullKernel) {
    const Material m = materialByName("Skin1");
    const DiffusionSplit s{.rp = importanceRadius(m, 0.1)};
    const RadialTable full = diffusionTable(m, 40.0), local = localDiffusionTable(m, s, 40.0),
                      global = globalDiffusionTable(m, s, 40.0);
    for (double r = 0.0; r < 40.0; r += 0.037) {
        const float r2 = float(r * r);
        const glm::vec3 sum = local(r2) + global(r2), ref = full(r2);
        for (int c = 0; c < 3; ++c) EXPECT_NEAR(sum[c], ref[c], 1e-6f * ref[c] + 1e-12f) << r;
    }
}

TEST(DiffusionSplit, CurvatureTablesMatchAGaussiansClosedForms) {
    // k = e^(-r^2 / s^2): k' = -2 r k / s^2, k'' = (4 r^2 / s^4 - 2 / s^2) k, so
    // A = (k'' - k'/r) / 2 = 2 r^2 k / s^4 and B = k' / (2 r) = -k / s^2.
    const double s = 1.7;
    const RadialKernel k = [s](double r) { return glm::dvec3(1.0, 2.0, 3.0) * std::exp(-r * r / (s * s)); };
    const RadialCurvature c = radialCurvature(radialNodes(k, 12.0), 12.0);
    for (double r = 0.0; r < 8.0; r += 0.0371) {
        const double g = std::exp(-r * r / (s * s));
        for (int ch = 0; ch < 3; ++ch) {
            const double a = (ch + 1) * 2.0 * r * r * g / (s * s * s * s), b = -(ch + 1) * g / (s * s);
            EXPECT_NEAR(c.along(float(r * r))[ch], a, 2e-4 * (ch + 1)) << r;
            EXPECT_NEAR(c.across(float(r * r))[ch], b, 2e-4 * (ch + 1)) << r;
        }
    }
    test::expectErrorSubject([&] { radialCurvature({glm::dvec3(1.0), glm::dvec3(1.0)}, 12.0); }, "diffusion table");
    test::expectErrorSubject([&] { radialNodes(k, -1.0); }, "diffusion table");
}

TEST(DiffusionSplit, SecondOrderClusterExpansionLeavesThirdOrder) {
    // Points around a centre c (zero weighted mean), seen from x at distance d along
    // an oblique direction, summed through the global kernel of Skin1: the monopole
    // W k(d) errs at second order in the cluster's size a, the expansion
    // W [k + A u^T S u + B tr S] at third. Halving a must cut its error by more than
    // 4 (second order would), and it must beat the monopole by far.
    const Material m = materialByName("Skin1");
    const DiffusionSplit split{.rp = importanceRadius(m, 0.1)};
    const RadialKernel k = globalDiffusionKernel(m, split);
    const std::vector<glm::dvec3> nodes = radialNodes(k, 40.0);
    const RadialTable table(nodes, 40.0);
    const RadialCurvature curvature = radialCurvature(nodes, 40.0);
    const glm::dvec3 x(0.0, 0.0, 0.0), u = glm::normalize(glm::dvec3(1.0, 0.4, 0.2));
    const double d = 4.0;
    auto errors = [&](double a) {
        // A flattened, uneven cluster: 27 points on a grid, weights 1 .. 3, recentred.
        std::vector<glm::dvec3> p;
        std::vector<double> w;
        for (int i = -1; i <= 1; ++i)
            for (int j = -1; j <= 1; ++j)
                for (int l = -1; l <= 1; ++l) {
                    p.push_back(a * glm::dvec3(i, 0.3 * j + 0.2 * i * i, 0.8 * l));
                    w.push_back(1.0 + (i + 1) * 0.5 + (l == 1 ? 0.5 : 0.0));
                }
        double total = 0.0;
        glm::dvec3 mean(0.0);
        for (size_t i = 0; i < p.size(); ++i) {
            total += w[i];
            mean += w[i] * p[i];
        }
        mean /= total;
        glm::dmat3 cov(0.0);
        glm::dvec3 exact(0.0);
        const glm::dvec3 c = x + d * u;
        for (size_t i = 0; i < p.size(); ++i) {
            const glm::dvec3 q = p[i] - mean;
            cov += w[i] * glm::outerProduct(q, q) / total;
            exact += w[i] * k(glm::length(x - (c + q)));
        }
        const float r2 = float(d * d);
        const glm::dvec3 monopole = total * glm::dvec3(table(r2));
        const double q = glm::dot(u, cov * u), tr = cov[0][0] + cov[1][1] + cov[2][2];
        const glm::dvec3 second =
            total * (glm::dvec3(table(r2)) + q * glm::dvec3(curvature.along(r2)) + tr * glm::dvec3(curvature.across(r2)));
        return std::make_pair(glm::length(monopole - exact) / glm::length(exact),
                              glm::length(second - exact) / glm::length(exact));
    };
    const auto coarse = errors(0.6), fine = errors(0.3);
    std::printf("cluster 1.2 mm at 4 mm: monopole %.3g, second order %.3g; 0.6 mm: %.3g, %.3g\n", coarse.first,
                coarse.second, fine.first, fine.second);
    EXPECT_LT(coarse.second, 0.1 * coarse.first);
    EXPECT_LT(fine.second, coarse.second / 5.0);
    EXPECT_GT(fine.first, coarse.first / 5.0);  // the monopole: second order (about 4)
}
