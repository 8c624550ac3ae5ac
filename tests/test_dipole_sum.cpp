// The reference's dipole sum (tools/reference/dipole_sum.h) on every instruction set
// against the plain double loop over dipoleRd.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include "common/bssrdf.h"
#include "common/materials.h"
#include "common/util.h"
#include "tools/reference/dipole_sum.h"

namespace prt {
namespace {

std::vector<DipoleSumIsa> isas() {
    std::vector<DipoleSumIsa> out{DipoleSumIsa::Portable};
    if (bestDipoleSumIsa() != DipoleSumIsa::Portable) out.push_back(bestDipoleSumIsa());
    return out;
}

// dipoleRd without its constant alpha' / (4 pi): the sum's term t_c(r).
double term(const DipoleChannel& d, double r) { return dipoleRd(d, r) * 4.0 * kPi / d.alphaPrime; }

struct Case {
    Material material;
    std::vector<glm::vec3> position, value, variance;
};

// n samples in a box of side `extent` mm around the origin, random E and Var.
Case randomCase(const Material& m, size_t n, float extent, unsigned seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> u(0.0f, 1.0f);
    Case c{m, {}, {}, {}};
    for (size_t i = 0; i < n; ++i) {
        c.position.push_back(extent * glm::vec3(u(rng) - 0.5f, u(rng) - 0.5f, u(rng) - 0.5f));
        c.value.push_back({u(rng), u(rng), u(rng)});
        c.variance.push_back(0.01f * glm::vec3(u(rng), u(rng), u(rng)));
    }
    return c;
}

void expectMatchesDoubleLoop(const Case& k, const std::vector<glm::vec3>& points, double tolerance) {
    DipoleSumSamples samples;
    for (size_t i = 0; i < k.position.size(); ++i) samples.add(k.position[i], k.value[i], k.variance[i]);
    samples.pad();
    ASSERT_EQ(samples.size() % kDipoleSumBlock, 0u);
    DipoleChannel d[3];
    DipoleSumChannel ch[3];
    for (int c = 0; c < 3; ++c) {
        d[c] = makeDipoleChannel(k.material, c);
        ch[c] = dipoleSumChannel(d[c]);
    }
    for (const glm::vec3& x : points) {
        double value[3] = {0, 0, 0}, variance[3] = {0, 0, 0};
        for (size_t i = 0; i < k.position.size(); ++i) {
            const double r = glm::length(glm::dvec3(k.position[i]) - glm::dvec3(x));
            for (int c = 0; c < 3; ++c) {
                const double t = term(d[c], r);
                value[c] += t * double(k.value[i][c]);
                variance[c] += t * t * double(k.variance[i][c]);
            }
        }
        for (DipoleSumIsa isa : isas()) {
            SCOPED_TRACE(toString(isa));
            const DipoleSumResult s = dipoleSum(samples, ch, x, isa);
            for (int c = 0; c < 3; ++c) {
                // The smallest normal float bounds what a float term can resolve.
                EXPECT_NEAR(s.value[c], value[c], tolerance * value[c] + 1e-36) << "channel " << c;
                EXPECT_NEAR(s.variance[c], variance[c], 2.0 * tolerance * variance[c] + 1e-36) << "channel " << c;
            }
        }
    }
}

TEST(DipoleSum, EveryInstructionSetMatchesTheDoubleLoopOverDipoleRd) {
    // Not a multiple of the block; points inside, at and far outside the cloud. Terms
    // are in float (~3e-7 each, measured within 1e-6 of the double loop).
    const std::vector<glm::vec3> points{{0, 0, 0}, {1.3f, -2.0f, 0.4f}, {7.9f, 7.9f, -7.9f}, {40, 0, 0}};
    for (const char* name : {"Marble", "Skin1", "Ketchup", "Apple"}) {
        SCOPED_TRACE(name);
        expectMatchesDoubleLoop(randomCase(materialByName(name), 3001, 16.0f, 7), points, 2e-6);
    }
}

TEST(DipoleSum, OneTermAtEveryDistanceIsDipoleRd) {
    // A single sample, E = 1, moved from the point itself (d = z_r) out to where
    // e^(-sigma_tr d) leaves the normal floats: each term, exp and 1/d^3 included,
    // within 1e-6 of the double formula, plus the float rounding of the exponent
    // sigma_tr d (2^-24 of it, relative, in e^(-sigma_tr d)); below the float range, zero.
    const Material m = materialByName("Marble");
    double sigmaMax = 0.0;
    for (int c = 0; c < 3; ++c) sigmaMax = std::max(sigmaMax, makeDipoleChannel(m, c).sigmaTr);
    for (double r : {0.0, 1e-4, 0.01, 0.3, 1.0, 3.7, 12.0, 55.0, 300.0, 700.0, 760.0}) {
        SCOPED_TRACE(r);
        Case k{m, {glm::vec3(float(r), 0, 0)}, {glm::vec3(1.0f)}, {glm::vec3(1.0f)}};
        expectMatchesDoubleLoop(k, {glm::vec3(0.0f)}, 1e-6 + 1.2e-7 * sigmaMax * r);
    }
    DipoleSumSamples far;
    far.add(glm::vec3(5000.0f, 0, 0), glm::vec3(1.0f), glm::vec3(1.0f));
    far.pad();
    DipoleSumChannel ch[3];
    for (int c = 0; c < 3; ++c) ch[c] = dipoleSumChannel(makeDipoleChannel(m, c));
    for (DipoleSumIsa isa : isas()) EXPECT_EQ(dipoleSum(far, ch, glm::vec3(0.0f), isa).value[0], 0.0);
}

TEST(DipoleSum, PaddingAddsNothing) {
    const Material m = materialByName("Skin1");
    const Case k = randomCase(m, 64, 4.0f, 3);
    DipoleSumSamples full, partial;
    for (size_t i = 0; i < k.position.size(); ++i) full.add(k.position[i], k.value[i], k.variance[i]);
    for (size_t i = 0; i < 63; ++i) partial.add(k.position[i], k.value[i], k.variance[i]);
    full.pad();
    partial.pad();
    EXPECT_EQ(full.size(), 64u);
    EXPECT_EQ(partial.size(), 64u);
    DipoleSumChannel ch[3];
    for (int c = 0; c < 3; ++c) ch[c] = dipoleSumChannel(makeDipoleChannel(m, c));
    for (DipoleSumIsa isa : isas()) {
        const DipoleSumResult a = dipoleSum(full, ch, glm::vec3(0.5f), isa);
        const DipoleSumResult b = dipoleSum(partial, ch, glm::vec3(0.5f), isa);
        const double last =
            term(makeDipoleChannel(m, 0), glm::length(glm::dvec3(k.position[63]) - glm::dvec3(0.5))) * k.value[63][0];
        EXPECT_NEAR(a.value[0] - b.value[0], last, 1e-5 * a.value[0]);
    }
}

}  // namespace
}  // namespace prt
