// The sample sums of Wang Eq. 7 against the exact plane integral of the dipole (issue
// 13): with E_i = 1 the sum over a Poisson-disk sample set must converge to int R_d dA
// per channel, for every measured material:
//   - the reference's point rule (1/pi) sum_i A R_d(|x_i - x_o|) at the spacing the
//     reference chooses (tools/reference/reference.h, referenceSampleSpacing);
//   - the precomputation's cell rule (common/cell_quadrature.h: R_d integrated over
//     each sample's Voronoi cell near x_o) at the spacing the precomputation chooses by
//     default (l_u = min z_r), and at half and twice that;
//   - and, so that the cell rule's test is seen to discriminate, the point rule at the
//     precomputation's spacing, which does NOT converge there.
//
// Geometry: a sphere. The area of a sphere within chord distance c of a point on it
// is exactly pi c^2 (Archimedes), so int over the sphere of R_d(chord) dA equals the
// plane integral int_0^2rho R_d(r) 2 pi r dr (dipoleDiffuseReflectanceWithin(2 rho))
// with no curvature error, and a closed surface has no boundary, whose different
// sample density would bias a flat patch (measured: -1% on a square). The point rule is
// the reference's own code: MultipleScatteringReference::diffuse with E_i = 1 (exact,
// no Monte Carlo).
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
#include "common/material_edit.h"
#include "common/radial_basis.h"
#include "common/sampling.h"
#include "common/shapes.h"
#include "common/cell_quadrature.h"
#include "common/radial_kernels.h"
#include <optional>
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

// The two quadratures under test: the reference's point rule (1/pi) sum_i A R_d(|x_i -
// x_o|) (MultipleScatteringReference::diffuse with E_i = 1, exact, no Monte Carlo), and
// the precomputation's cell-averaged rule (1/pi) sum_i A Rbar(|x_i - x_o|)
// (common/cell_quadrature.h).
enum class Rule { Point, Cells };

// Per channel: the sum at 32 vertices of the sphere (on the surface, spread over it)
// at spacing h, against dipoleDiffuseReflectanceWithin(d, 2 rho).
std::array<ChannelError, 3> sampleSumError(const Material& m, double h, Rule rule) {
    const UnitSet& u = unitSet();
    const double unitSpacing = std::sqrt(2.0 * u.samples.areaPerSample / std::sqrt(3.0));
    const double k = h / unitSpacing;  // scale: the sphere's radius rho in mm
    std::vector<glm::vec3> positions;
    for (const SurfaceSample& s : u.samples.samples) positions.push_back(s.position * float(k));
    const double area = u.samples.areaPerSample * k * k;
    SampleIrradiance one;
    one.value.assign(positions.size(), glm::dvec3(1.0));
    one.variance.assign(positions.size(), glm::dvec3(0.0));
    const MultipleScatteringReference ms(m, positions, area, one);
    std::optional<CellQuadrature> cells;
    if (rule == Rule::Cells) {
        TriangleMesh mesh = u.sphere;
        for (glm::vec3& p : mesh.positions) p *= float(k);
        std::vector<glm::vec3> normals;
        for (const SurfaceSample& s : u.samples.samples) normals.push_back(s.geometricNormal);
        cells.emplace(mesh, positions, normals, h, m);
    }
    std::array<ChannelError, 3> out;
    const int points = 32;
    for (int p = 0; p < points; ++p) {
        const glm::vec3 xo = u.sphere.positions[(size_t(p) * 7919u) % u.sphere.positions.size()] * float(k);
        glm::dvec3 sum(0.0);
        if (rule == Rule::Point) {
            sum = kPi * ms.diffuse(xo).value;
        } else {
            for (size_t i = 0; i < positions.size(); ++i) {
                double w[3];
                cells->sampleWeightOverPi(i, xo, w);
                sum += kPi * glm::dvec3(w[0], w[1], w[2]);
            }
        }
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
void checkAllMaterials(const char* what, double (*spacing)(const Material&), Rule rule, double tolerance,
                       const std::vector<std::string>& names = materialNames()) {
    std::printf("%s: sample sum / exact plane integral - 1 per channel (mean, rms, worst over 32 points)\n", what);
    for (const std::string& name : names) {
        const Material m = materialByName(name);
        const double h = spacing(m);
        const std::array<ChannelError, 3> e = sampleSumError(m, h, rule);
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
double halfDefaultSpacing(const Material& m) { return 0.5 * m.minMeanFreePath(); }
double twiceDefaultSpacing(const Material& m) { return 2.0 * m.minMeanFreePath(); }

}  // namespace

// At the reference's spacing (0.2 / max_c(sigma_t' + sigma_tr)) every channel of every
// measured material is within 1%: measured RMS over points 0.11-0.96% (the blue
// channels of the absorbing materials the largest), mean -0.11% to +0.01%, single
// points up to 2.1%. (At 0.3 the RMS reached 1.4% with this sample set.)
TEST(SampleSum, PointRuleConvergesAtTheReferenceSpacing) {
    checkAllMaterials("point rule, reference spacing", referenceSpacing, Rule::Point, 0.01);
}

// The precomputation's cell rule at its default spacing (PrecomputeSettings::
// samples.spacingMm = 0 -> l_u = min z_r): every material and channel within 1%.
// Measured: RMS over points 0.17-0.40%, mean within 0.1%, single points up to 1.24%
// (Ketchup green). The point rule at this spacing: RMS 1.4-11.6% (next test).
TEST(SampleSum, CellRuleConvergesAtThePrecomputesDefaultSpacing) {
    checkAllMaterials("cell rule, precompute default spacing", precomputeDefaultSpacing, Rule::Cells, 0.01);
}

// The same at half and twice the default spacing (--sample-spacing; the near radius
// follows the spacing, the sub-spacing the material) for the materials of the issue's
// goals: within 1% too. (Not every material: twice the spacing makes this test's sphere
// 4x larger in area, and Ketchup's sub-spacing, set by its narrow blue kernel, would
// then need over 2^26 sub-points.)
TEST(SampleSum, CellRuleConvergesAtHalfAndTwiceTheDefaultSpacing) {
    const std::vector<std::string> names = {"Marble", "Skin1", "Wholemilk"};
    checkAllMaterials("cell rule, half the default spacing", halfDefaultSpacing, Rule::Cells, 0.01, names);
    checkAllMaterials("cell rule, twice the default spacing", twiceDefaultSpacing, Rule::Cells, 0.01, names);
}

// What the cell rule repairs: the point rule at the precomputation's spacing is off by
// more than 1% RMS in some channel of every material (measured 1.4-11.6%, single points
// up to 28%; the absorbing materials' blue channels the worst, whose kernel is no wider
// than the spacing). Also Voronoi cell areas alone (2.7% RMS for Apple red) and R_d
// averaged over a disk of the sample's area (3.0%) were measured and do not converge:
// the error is the irregularity of the sample positions at the scale of R_d's peak.
TEST(SampleSum, PointRuleDoesNotConvergeAtThePrecomputesDefaultSpacing) {
    for (const std::string& name : materialNames()) {
        const Material m = materialByName(name);
        const std::array<ChannelError, 3> e = sampleSumError(m, precomputeDefaultSpacing(m), Rule::Point);
        const double worst = std::max({e[0].rms, e[1].rms, e[2].rms});
        std::printf("  point rule, %-10s worst channel RMS %.4f\n", name.c_str(), worst);
        EXPECT_GT(worst, 0.01) << name;
    }
}

// Editable transport's quadrature: the profiles of the default editable basis (every
// measured material with absorption, half to twice the size) integrated by graded cells
// (cell_quadrature.h, g = 8, the precompute's default) at the job's default spacing
// (Marble's l_u), recombined for the narrowest and the widest materials of the range,
// equal each channel's exact plane integral within 1% like the dipole's own cells above.
// One level of sub-points at the narrowest profile's spacing would need about 25 times
// as many sub-points on this sphere (over the 2^26 limit). With E = 1 the sum does not
// see how a kernel's peak is shared among neighbouring cells (the sub-triangles'
// centroids alone pass too): CellQuadrature.GradedSubPointsMatchTheFineOnes checks that.
TEST(SampleSum, GradedCellRuleConvergesForTheEditableRange) {
    std::vector<Material> covered;
    for (const std::string& name : materialNames()) {
        const Material m = materialByName(name);
        if (m.sigmaA.x > 0.0 && m.sigmaA.y > 0.0 && m.sigmaA.z > 0.0) covered.push_back(m);
    }
    const UnitSet& u = unitSet();
    const double h = materialByName("Marble").minMeanFreePath();
    const double unitSpacing = std::sqrt(2.0 * u.samples.areaPerSample / std::sqrt(3.0));
    const double k = h / unitSpacing;  // the sphere's radius rho in mm
    const RadialBasis basis = makeRadialBasis(rangeCovering(covered, 0.5, 2.0, 2.0 * k));
    const RadialKernels kernels = radialBasisKernels(basis);
    std::vector<glm::vec3> positions, normals;
    for (const SurfaceSample& s : u.samples.samples) {
        positions.push_back(s.position * float(k));
        normals.push_back(s.geometricNormal);
    }
    TriangleMesh mesh = u.sphere;
    for (glm::vec3& p : mesh.positions) p *= float(k);
    CellQuadratureOptions graded;
    graded.gradedPiecesPerDistance = 8.0;
    const CellQuadrature cells(mesh, positions, normals, h, kernels, graded);
    ASSERT_TRUE(cells.graded());
    EXPECT_GT(cells.coarseSpacing(), 4.0 * cells.subSpacing());
    std::printf("graded cells: %zu sub-points at %.4f mm, pieces down to %.4f mm\n", cells.subPointCount(),
                cells.coarseSpacing(), cells.subSpacing());

    // S_j(x_o) = sum_i int_{cell_i} B_j: the plane integral of each profile.
    const int J = basis.size(), points = 32;
    std::vector<std::vector<double>> profileSum(points, std::vector<double>(size_t(J), 0.0));
    for (int p = 0; p < points; ++p) {
        const glm::vec3 xo = u.sphere.positions[(size_t(p) * 7919u) % u.sphere.positions.size()] * float(k);
        double w[kMaxRadialKernels];
        for (size_t i = 0; i < positions.size(); ++i) {
            cells.sampleWeightOverPi(i, xo, w);
            for (int j = 0; j < J; ++j) profileSum[size_t(p)][size_t(j)] += kPi * w[j];
        }
    }
    // Narrowest: the most opaque materials twice as large; widest: the most translucent
    // at half the size.
    for (const auto& [name, factor] : std::vector<std::pair<std::string, double>>{
             {"Ketchup", 2.0}, {"Skin1", 2.0}, {"Marble", 1.0}, {"Cream", 0.5}, {"Skimmilk", 0.5}}) {
        const Material m = scaledMaterial(materialByName(name), factor);
        const std::array<std::vector<double>, 3> weights = basis.materialWeights(materialByName(name), factor);
        std::printf("  %-9s x%.1f:", name.c_str(), factor);
        for (int c = 0; c < 3; ++c) {
            const DipoleChannel d = makeDipoleChannel(m, c);
            const double exact = dipoleDiffuseReflectanceWithin(d, 2.0 * k);
            ChannelError e;
            for (int p = 0; p < points; ++p) {
                double sum = 0.0;
                for (int j = 0; j < J; ++j) sum += weights[size_t(c)][size_t(j)] * profileSum[size_t(p)][size_t(j)];
                const double rel = sum / exact - 1.0;
                e.mean += rel / points;
                e.rms += rel * rel / points;
                e.worst = std::max(e.worst, std::abs(rel));
            }
            e.rms = std::sqrt(e.rms);
            std::printf("  %c %+.4f %.4f %.4f", "RGB"[c], e.mean, e.rms, e.worst);
            EXPECT_LT(std::abs(e.mean), 0.01) << name << " x" << factor << " channel " << c;
            EXPECT_LT(e.rms, 0.01) << name << " x" << factor << " channel " << c;
        }
        std::printf("\n");
    }
}
