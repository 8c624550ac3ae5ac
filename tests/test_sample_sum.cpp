// The sample sum of the multiple-scattering reference against the exact plane
// integral of the dipole (issue 13): sum_i A_i R_d(|x_i - x_o|) over a Poisson-disk
// sample set must converge to int R_d dA per channel for every measured material at
// the spacing the reference chooses (tools/reference/reference.h,
// referenceSampleSpacing), and the same check at the precomputation's default spacing
// (l_u = min z_r) documents how far that is.
//
// Geometry: a sphere. The area of a sphere within chord distance c of a point on it
// is exactly pi c^2 (Archimedes), so int over the sphere of R_d(chord) dA equals the
// plane integral int_0^2rho R_d(r) 2 pi r dr (dipoleDiffuseReflectanceWithin(2 rho))
// with no curvature error, and a closed surface has no boundary, whose different
// sample density would bias a flat patch (measured: -1% on a square). The sum is the
// reference's own code: MultipleScatteringReference::diffuse with E_i = 1 (exact, no
// Monte Carlo), which is (1/pi) sum_i A_i R_d.
//
// One Poisson-disk set on a unit icosphere, scaled per material: a Poisson-disk set
// scaled by k is a Poisson-disk set of spacing k times (the construction is scale
// free), so this is the same as placing a set per material, for a fraction of the
// cost. Radius: 60000 samples at spacing h give rho = 64 h; within 2 rho lies 72-100%
// of each channel's total reflectance at the reference's spacing (Ketchup red, whose
// 1/sigma_tr = 4.8 mm is 96 spacings, the least): the exact within-2-rho value is the
// target, and the part beyond is the smooth far tail, which any spacing below
// 1/sigma_tr integrates well; the quadrature error that matters is the peak's.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "common/bssrdf.h"
#include "common/sampling.h"
#include "common/shapes.h"
#include "tools/reference/reference.h"

using namespace prt;

namespace {

constexpr double kPi = 3.14159265358979323846;

struct ChannelError {
    double mean = 0, rms = 0, worst = 0;  // of sum / exact - 1 over the points
    double captured = 0;                  // exact within 2 rho / total reflectance
};

struct UnitSet {
    TriangleMesh sphere = makeIcosphere(6, 1.0f);
    SampleSet samples = poissonDiskSamples(sphere, 60000, 20240613);
};

const UnitSet& unitSet() {
    static const UnitSet set;
    return set;
}

// Per channel: the sum at 32 vertices of the sphere (on the surface, spread over it)
// at spacing h, against dipoleDiffuseReflectanceWithin(d, 2 rho).
std::array<ChannelError, 3> sampleSumError(const Material& m, double h) {
    const UnitSet& u = unitSet();
    const double unitSpacing = std::sqrt(2.0 * u.samples.areaPerSample / std::sqrt(3.0));
    const double k = h / unitSpacing;  // scale: the sphere's radius rho in mm
    std::vector<glm::vec3> positions;
    for (const SurfaceSample& s : u.samples.samples) positions.push_back(s.position * float(k));
    SampleIrradiance one;
    one.value.assign(positions.size(), glm::dvec3(1.0));
    one.variance.assign(positions.size(), glm::dvec3(0.0));
    const MultipleScatteringReference ms(m, positions, u.samples.areaPerSample * k * k, one);
    std::array<ChannelError, 3> out;
    const int points = 32;
    for (int p = 0; p < points; ++p) {
        const glm::vec3 xo = u.sphere.positions[(size_t(p) * 7919u) % u.sphere.positions.size()] * float(k);
        const glm::dvec3 sum = kPi * ms.diffuse(xo).value;
        for (int c = 0; c < 3; ++c) {
            const DipoleChannel d = makeDipoleChannel(m, c);
            const double exact = dipoleDiffuseReflectanceWithin(d, 2.0 * k);
            out[c].captured = exact / dipoleTotalDiffuseReflectance(d);
            const double e = sum[c] / exact - 1.0;
            out[c].mean += e / points;
            out[c].rms += e * e / points;
            out[c].worst = std::max(out[c].worst, std::abs(e));
        }
    }
    for (ChannelError& e : out) e.rms = std::sqrt(e.rms);
    return out;
}

// The table for `spacing(m)`; every channel's RMS and mean error within `tolerance`.
void checkAllMaterials(const char* what, double (*spacing)(const Material&), double tolerance) {
    std::printf("%s: sample sum / exact plane integral - 1 per channel (mean, rms, worst over 32 points)\n", what);
    for (const std::string& name : materialNames()) {
        const Material m = materialByName(name);
        const double h = spacing(m);
        const std::array<ChannelError, 3> e = sampleSumError(m, h);
        std::printf("  %-10s h = %.4f mm (%.3f z_r,min):", name.c_str(), h, h / m.minMeanFreePath());
        for (int c = 0; c < 3; ++c) std::printf("  %c %+.4f %.4f %.4f", "RGB"[c], e[c].mean, e[c].rms, e[c].worst);
        std::printf("\n");
        for (int c = 0; c < 3; ++c) {
            EXPECT_LT(std::abs(e[c].mean), tolerance) << name << " channel " << c;
            EXPECT_LT(e[c].rms, tolerance) << name << " channel " << c;
            EXPECT_GT(e[c].captured, 0.7) << name << " channel " << c;
        }
    }
}

double referenceSpacing(const Material& m) { return referenceSampleSpacing(m); }
double precomputeDefaultSpacing(const Material& m) { return m.minMeanFreePath(); }

}  // namespace

// At the reference's spacing (0.2 / max_c(sigma_t' + sigma_tr)) every channel of every
// measured material is within 1%: measured RMS over points 0.11-0.96% (the blue
// channels of the absorbing materials the largest), mean -0.11% to +0.01%, single
// points up to 2.1%. (At 0.3 the RMS reached 1.4% with this sample set.)
TEST(SampleSum, ConvergesToThePlaneIntegralAtTheReferenceSpacing) {
    checkAllMaterials("reference spacing", referenceSpacing, 0.01);
}

// The same check at the precomputation's default spacing (PrecomputeSettings::
// sampleSpacingMm = 0 -> the material's smallest mean free path l_u = min z_r). It
// fails for every material: RMS over points 1.4-11.6% (mean up to +1.6%, single
// points up to 28%; Ketchup, Chicken1/2, Skin1 and Potato blue the worst: strongly
// absorbing channels whose kernel is no wider than the spacing). Disabled until the precomputation's default
// converges: issue 13, item 2 (do not change the default before then). Run with
// --gtest_also_run_disabled_tests for the table (docs/reference.md).
TEST(SampleSum, DISABLED_ConvergesToThePlaneIntegralAtThePrecomputesDefaultSpacing) {
    checkAllMaterials("precompute default spacing", precomputeDefaultSpacing, 0.01);
}
