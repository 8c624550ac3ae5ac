// Editable transport at relight time (relight/prt/editable_transport.h), on a synthetic
// file: the recombination is the weighted sum of the profile vectors, the projected-light
// path equals relighting the recombination, a size is a scaled material, and what the
// basis cannot cover is refused in one line with the material kept. The end-to-end check
// against a full precompute is tests/test_pipeline.cpp (EditableMatchesFullPrecomputes).

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <numeric>
#include <random>

#include "common/blocked_vectors.h"
#include "common/error.h"
#include "common/material_edit.h"
#include "common/transport_params.h"
#include "relight/prt/editable_transport.h"
#include "relight/prt/relight_kernel.h"

using namespace prt;

namespace {

constexpr int kN = 4;                    // cubemap face size
constexpr size_t kTexels = 6 * kN * kN;  // Haar coefficients
constexpr size_t kVertices = 60;
constexpr double kObjectMm = 20.0;

const RadialBasis& testBasis() {
    static const RadialBasis basis =
        makeRadialBasis(rangeCovering({materialByName("Marble"), materialByName("Skin1")}, 0.5, 2.0, kObjectMm),
                        RadialBasisOptions{.size = 6});
    return basis;
}

constexpr uint32_t kShTerms = 9;  // the SH part of the 8-bit variant

// Two profile components (J = 6) sharing each vertex's random index list, the basis, and
// Marble as the file's material. eightBit: 8-bit Haar values (SparseRgbVectors::haarBits)
// and an SH part of kShTerms terms with its own scales, as prt-precompute --editable writes.
TransportFile syntheticFile(uint64_t seed, bool eightBit = false) {
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<float> value(-1.0f, 1.0f);
    const RadialBasis& basis = testBasis();
    TransportFile file;
    file.cubemapSize = kN;
    file.shTerms = eightBit ? kShTerms : 0;
    file.mesh.vertexCount = kVertices;
    file.parameters = materialParameters(materialByName("Marble"));
    file.radialBasis = StoredRadialBasis{basis.range(), basis.tables()};
    TransportComponent profiles[2];
    for (uint32_t p = 0; p < 2; ++p) {
        profiles[p].kind = ComponentKind::MultipleScatteringProfiles;
        profiles[p].term = p;
        if (eightBit) profiles[p].vectors.useEightBitHaar(uint32_t(kTexels));
    }
    for (size_t v = 0; v < kVertices; ++v) {
        std::vector<uint32_t> idx{0};
        for (uint32_t k = 1; k < kTexels; ++k)
            if (rng() % 4 == 0) idx.push_back(k);
        const size_t haar = idx.size();
        for (uint32_t k = 0; k < file.shTerms; ++k) idx.push_back(uint32_t(kTexels) + k);
        for (auto& c : profiles) {
            std::vector<float> rgb(3 * idx.size());
            for (float& x : rgb) x = value(rng);
            rgb[0] = rgb[1] = rgb[2] = 2.0f;  // a dominant scaling coefficient, as real transport has
            // An SH band-0 term that dwarfs the Haar ones, as real transport has.
            for (size_t n = haar; n < idx.size(); ++n)
                for (int ch = 0; ch < 3; ++ch) rgb[3 * n + size_t(ch)] *= n == haar ? 40.0f : 4.0f;
            c.vectors.appendVertex(idx, rgb);
        }
    }
    for (auto& c : profiles) file.components.push_back(std::move(c));
    return file;
}

// syntheticFile's profiles blocked together, keeping every index (lossless up to the
// int8 values), in a shuffled block order. nestedKeep > 0: nested lists of a union of
// that many indices per block (jointTruncateNested), the first profile component made
// ten times weaker so that it keeps fewer of them than the second. withSh: the 8-bit
// variant's SH part (kShTerms terms), kept first with scales of their own.
TransportFile blockedFile(uint64_t seed, size_t nestedKeep = 0, bool withSh = false) {
    TransportFile file = syntheticFile(seed, withSh);
    std::vector<uint32_t> order(kVertices);
    std::iota(order.begin(), order.end(), 0u);
    std::shuffle(order.begin(), order.end(), std::mt19937_64(seed + 100));
    if (nestedKeep > 0)
        for (int16_t& q : file.components[0].vectors.values) q = int16_t(q / 10);
    const std::vector<const SparseRgbVectors*> sources = {&file.components[0].vectors, &file.components[1].vectors};
    const uint32_t shFrom = withSh ? uint32_t(kTexels) : UINT32_MAX;
    std::vector<BlockedRgbVectors> blocks = nestedKeep > 0 ? jointTruncateNested(sources, nestedKeep, order, shFrom)
                                                           : jointTruncateShared(sources, kTexels, order, shFrom);
    for (size_t p = 0; p < 2; ++p) {
        file.components[p].blocks = std::move(blocks[p]);
        file.components[p].vectors = SparseRgbVectors();
    }
    return file;
}

// sum_j w_cj U_j(v) from the profiles' dequantized values at vertex v, whose index lists
// must lie in `idx` (the recombination's; a profile's value is 0 where its own list
// lacks an index): 3 per index, or empty (a failure) if one does not.
std::vector<double> weightedProfileSum(const std::vector<TransportComponent>& profiles, const EditableTransport& e,
                                       size_t v, const std::vector<uint32_t>& idx) {
    std::vector<double> sum(3 * idx.size(), 0.0);
    std::vector<uint32_t> idxU;
    std::vector<float> u;
    for (size_t p = 0; p < profiles.size(); ++p) {
        profiles[p].dequantizeVertex(v, idxU, u);
        for (size_t m = 0; m < idxU.size(); ++m) {
            const auto at = std::find(idx.begin(), idx.end(), idxU[m]);
            if (at == idx.end()) {
                ADD_FAILURE() << "profile component " << p << " has index " << idxU[m] << " outside the list at vertex "
                              << v;
                return {};
            }
            const size_t n = size_t(at - idx.begin());
            for (int ch = 0; ch < 3; ++ch)
                for (int c = 0; c < 3; ++c)
                    sum[3 * n + size_t(c)] += e.weights()[size_t(c)][3 * p + size_t(ch)] * u[3 * m + size_t(ch)];
        }
    }
    return sum;
}

// The recombination `ms` against weightedProfileSum at every vertex: each value within
// tolerance(maxAbs, c) of it, maxAbs the largest |expected| of channel c at the vertex
// (> 0). Returns the largest error relative to maxAbs (-1 after a failure).
double checkRecombination(const TransportComponent& ms, const std::vector<TransportComponent>& profiles,
                          const EditableTransport& e, const std::function<double(double, int)>& tolerance) {
    std::vector<uint32_t> idx;
    std::vector<float> rgb;
    double worst = 0.0;
    for (size_t v = 0; v < kVertices; ++v) {
        ms.dequantizeVertex(v, idx, rgb);
        const std::vector<double> expected = weightedProfileSum(profiles, e, v, idx);
        if (expected.size() != rgb.size()) {
            ADD_FAILURE() << "vertex " << v << ": " << rgb.size() / 3 << " recombined values, " << expected.size() / 3
                          << " expected";
            return -1.0;
        }
        for (int c = 0; c < 3; ++c) {
            double maxAbs = 0.0;
            for (size_t n = 0; n < idx.size(); ++n) maxAbs = std::max(maxAbs, std::abs(expected[3 * n + size_t(c)]));
            if (!(maxAbs > 0.0)) {
                ADD_FAILURE() << "vertex " << v << " channel " << c << ": all expected values are 0";
                return -1.0;
            }
            for (size_t n = 0; n < idx.size(); ++n) {
                const double err = std::abs(rgb[3 * n + size_t(c)] - expected[3 * n + size_t(c)]);
                if (!(err <= tolerance(maxAbs, c))) {
                    ADD_FAILURE() << "vertex " << v << " coefficient " << n << " channel " << c << ": error " << err
                                  << " over " << tolerance(maxAbs, c);
                    return -1.0;
                }
                worst = std::max(worst, err / maxAbs);
            }
        }
    }
    return worst;
}

LightVector randomLight(uint64_t seed) {
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<float> value(-0.5f, 1.0f);
    LightVector light;
    light.size = kN;
    light.rgb.resize(3 * kTexels);
    for (float& x : light.rgb) x = value(rng);
    light.sh.resize(3 * kShTerms);
    for (float& x : light.sh) x = value(rng);
    return light;
}

}  // namespace

TEST(EditableTransport, TakesTheProfilesAndStartsFromTheFilesMaterial) {
    TransportFile file = syntheticFile(1);
    const TransportFile original = file;
    const EditableTransport e(file, kObjectMm);
    EXPECT_TRUE(file.components.empty());
    EXPECT_FALSE(file.radialBasis);
    EXPECT_EQ(e.profileCount(), 6);
    EXPECT_EQ(e.vertexCount(), kVertices);
    EXPECT_EQ(e.material().name, "Marble");
    EXPECT_TRUE(e.isFileMaterial());
    const auto expected = testBasis().materialWeights(materialByName("Marble"), 1.0);
    for (int c = 0; c < 3; ++c) EXPECT_EQ(e.weights()[size_t(c)], expected[size_t(c)]);
    // A file without a basis, or without a material, is refused.
    TransportFile plain = original;
    plain.radialBasis.reset();
    EXPECT_THROW(EditableTransport(plain, kObjectMm, "plain.prt"), Error);
    TransportFile nameless = original;
    nameless.parameters.clear();
    EXPECT_THROW(EditableTransport(nameless, kObjectMm), Error);
}

// V_c = sum_j w_cj U_j per vertex, against the sum of the dequantized profiles: within
// the output's 16-bit quantization (kQuantizationMaxRelativeError of the vertex's channel
// maximum) and float rounding of the products (1e-6 of sum_j |w_cj| max |U_j|).
TEST(EditableTransport, RecombinationIsTheWeightedSumOfTheProfiles) {
    for (const bool eightBit : {false, true}) {
        SCOPED_TRACE(eightBit ? "8-bit Haar values" : "16-bit values");
        TransportFile file = syntheticFile(2, eightBit);
        std::vector<TransportComponent> profiles = file.components;
        EditableTransport e(file, kObjectMm);
        e.setMaterial(materialByName("Skin1"), 31.0);
        const TransportComponent ms = e.recombine();
        EXPECT_EQ(ms.kind, ComponentKind::MultipleScattering);
        double absWeights[3] = {0.0, 0.0, 0.0};
        for (int c = 0; c < 3; ++c)
            for (double w : e.weights()[size_t(c)]) absWeights[c] += std::abs(w);
        EXPECT_GE(checkRecombination(ms, profiles, e,
                                     [&](double maxAbs, int c) {
                                         return kQuantizationMaxRelativeError * maxAbs +
                                                1e-6 * absWeights[c] * (eightBit ? 80.0 : 2.0);
                                     }),
                  0.0);
    }
}

// recombineUnless (the viewer's recombination while idle) gives way when asked and is
// recombine() when never asked to, bit for bit.
TEST(EditableTransport, RecombinationGivesWayWhenAsked) {
    TransportFile file = syntheticFile(2, true);
    EditableTransport e(file, kObjectMm);
    e.setMaterial(materialByName("Skin1"), 31.0);
    const TransportComponent whole = e.recombine();
    const std::optional<TransportComponent> never = e.recombineUnless([] { return false; });
    ASSERT_TRUE(never.has_value());
    EXPECT_EQ(never->vectors, whole.vectors);
    EXPECT_FALSE(e.recombineUnless([] { return true; }).has_value());
}

// Relighting the recombined component and the projected-light path agree.
TEST(EditableTransport, ProjectedLightEqualsRelightingTheRecombination) {
    for (const bool eightBit : {false, true}) {
        SCOPED_TRACE(eightBit ? "8-bit Haar values" : "16-bit values");
        TransportFile file = syntheticFile(3, eightBit);
        EditableTransport e(file, kObjectMm);
        const LightVector light = randomLight(4);
        e.projectLight(light);
        for (const char* name : {"Marble", "Skin1"}) {
            e.setMaterial(materialByName(name), 17.0);
            TransportFile recombined = file;
            recombined.components.push_back(e.recombine());
            VertexRadiance viaFile;
            relightVertices(recombined, light, ScatteringComponents{}, viaFile);
            std::vector<glm::vec3> viaProjection;
            e.relightProjected(viaProjection);
            ASSERT_EQ(viaProjection.size(), kVertices);
            double diff = 0.0, norm = 0.0;
            for (size_t v = 0; v < kVertices; ++v)
                for (int c = 0; c < 3; ++c) {
                    diff += std::pow(double(viaProjection[v][c] - viaFile.diffuse[v][c]), 2);
                    norm += std::pow(double(viaFile.diffuse[v][c]), 2);
                }
            EXPECT_GT(norm, 0.0);
            // The recombination's own 16-bit quantization: ~1e-5 of each vertex's maximum.
            EXPECT_LT(std::sqrt(diff / norm), 1e-4) << name;
        }
    }
}

// A size S is the material scaled by S / S_file at the file's geometry, bit for bit.
TEST(EditableTransport, SizeIsAScaledMaterial) {
    TransportFile a = syntheticFile(5), b = a;
    EditableTransport ea(a, kObjectMm), eb(b, kObjectMm);
    const Material skin = materialByName("Skin1");
    ea.setMaterial(skin, 2.0 * kObjectMm);
    eb.setMaterial(scaledMaterial(skin, 2.0), kObjectMm);
    for (int c = 0; c < 3; ++c) EXPECT_EQ(ea.weights()[size_t(c)], eb.weights()[size_t(c)]);
    EXPECT_FALSE(ea.isFileMaterial());
    EXPECT_DOUBLE_EQ(ea.sizeMm(), 2.0 * kObjectMm);
}

// Outside the basis: one line, and the object keeps its material. Another eta is
// replaced by the file's and reported.
TEST(EditableTransport, RefusesWhatTheBasisCannotCover) {
    TransportFile file = syntheticFile(6);
    EditableTransport e(file, kObjectMm);
    e.setMaterial(materialByName("Skin1"), kObjectMm);
    const auto before = e.weights();
    for (const auto& [material, size] : std::vector<std::pair<Material, double>>{
             {materialByName("Spectralon"), kObjectMm},  // sigma_a = 0
             {materialByName("Ketchup"), kObjectMm},     // not in the range
             {materialByName("Marble"), 10.0 * kObjectMm},
             {materialByName("Marble"), 0.0},
             {materialByName("Marble"), std::nan("")}}) {
        try {
            e.setMaterial(material, size);
            ADD_FAILURE() << material.name << " at " << size << " mm accepted";
        } catch (const Error& err) {
            EXPECT_EQ(std::string(err.what()).find('\n'), std::string::npos);
        }
        EXPECT_EQ(e.material().name, "Skin1");
        EXPECT_EQ(e.weights()[0], before[0]);
    }
    Material otherEta = materialByName("Marble");
    otherEta.eta = 1.5;
    EXPECT_TRUE(e.setMaterial(otherEta, kObjectMm));
    EXPECT_DOUBLE_EQ(e.material().eta, 1.3);
    EXPECT_FALSE(e.setMaterial(materialByName("Marble"), kObjectMm));
    EXPECT_TRUE(e.isFileMaterial());
}

// Blocked profiles: the recombination keeps the block order and index lists and is the
// weighted sum of the dequantized profiles, within the output's int8 quantization
// (kBlockQuantizationMaxRelativeError of the lane's channel maximum over the block) and
// float rounding.
TEST(EditableTransport, BlockedRecombinationIsTheWeightedSumOfTheProfiles) {
    TransportFile file = blockedFile(5);
    const std::vector<TransportComponent> profiles = file.components;
    EditableTransport e(file, kObjectMm);
    EXPECT_EQ(e.vertexCount(), kVertices);
    e.setMaterial(materialByName("Skin1"), 23.0);
    const TransportComponent ms = e.recombine();
    ASSERT_TRUE(ms.blocked());
    EXPECT_EQ(ms.kind, ComponentKind::MultipleScattering);
    EXPECT_EQ(ms.blocks.order, profiles[0].blocks.order);
    EXPECT_EQ(ms.blocks.offsets, profiles[0].blocks.offsets);
    EXPECT_EQ(ms.blocks.indices, profiles[0].blocks.indices);
    EXPECT_EQ(checkBlockedVectors(ms.blocks, uint32_t(kTexels)), "");
    const double worst = checkRecombination(
        ms, profiles, e, [](double maxAbs, int) { return maxAbs * (kBlockQuantizationMaxRelativeError + 1e-5); });
    EXPECT_GT(worst, 0.1 * kBlockQuantizationMaxRelativeError);  // int8, not the 16-bit per-vertex steps
}

// The projected-light path on blocked profiles equals relighting their recombination up
// to the recombination's int8 quantization, and the per-vertex file's projected path up
// to the profiles' own int8 quantization (every index kept).
TEST(EditableTransport, BlockedProjectedLightMatchesTheRecombinationAndThePerVertexFile) {
    TransportFile blocked = blockedFile(6), perVertex = syntheticFile(6);
    EditableTransport e(blocked, kObjectMm), ePerVertex(perVertex, kObjectMm);
    const LightVector light = randomLight(7);
    e.projectLight(light);
    ePerVertex.projectLight(light);
    auto relRmse = [](const std::vector<glm::vec3>& a, const std::vector<glm::vec3>& b) {
        double diff = 0.0, norm = 0.0;
        for (size_t v = 0; v < a.size(); ++v)
            for (int c = 0; c < 3; ++c) {
                diff += std::pow(double(a[v][c] - b[v][c]), 2);
                norm += std::pow(double(b[v][c]), 2);
            }
        return norm > 0.0 ? std::sqrt(diff / norm) : 1.0;
    };
    for (const char* name : {"Marble", "Skin1"}) {
        e.setMaterial(materialByName(name), 17.0);
        ePerVertex.setMaterial(materialByName(name), 17.0);
        TransportFile recombined = blocked;
        recombined.components.push_back(e.recombine());
        VertexRadiance viaFile;
        relightVertices(recombined, light, ScatteringComponents{}, viaFile);
        std::vector<glm::vec3> viaProjection, viaPerVertex;
        e.relightProjected(viaProjection);
        ePerVertex.relightProjected(viaPerVertex);
        ASSERT_EQ(viaProjection.size(), kVertices);
        std::printf("%s: blocked projected vs its recombination %.5f, vs the per-vertex file %.5f\n", name,
                    relRmse(viaProjection, viaFile.diffuse), relRmse(viaProjection, viaPerVertex));
        // int8 steps of 1/254 of a lane's maximum, summed over ~30 random-signed terms
        // per vertex against a light of mean 0.25: a few tenths of a percent.
        EXPECT_LT(relRmse(viaProjection, viaFile.diffuse), 0.01) << name;
        EXPECT_LT(relRmse(viaProjection, viaPerVertex), 0.01) << name;
    }
}

// Nested lists (a union of 20 of the 96 indices per block, the weak profile component
// keeping fewer): the recombination's list is each block's union, its values the
// weighted sums with 0 where a profile's list lacks an index (int8 bound), and the
// projected path equals relighting it.
TEST(EditableTransport, NestedBlockedProfilesRecombineOverTheUnionOfTheirLists) {
  for (const bool withSh : {false, true}) {
    SCOPED_TRACE(withSh ? "with an SH part" : "Haar only");
    TransportFile file = blockedFile(8, withSh ? 20 + kShTerms : 20, withSh);
    const std::vector<TransportComponent> profiles = file.components;
    ASSERT_NE(profiles[0].blocks.indices, profiles[1].blocks.indices);
    EXPECT_LT(profiles[0].blocks.indices.size(), profiles[1].blocks.indices.size());
    EditableTransport e(file, kObjectMm);
    e.setMaterial(materialByName("Skin1"), 23.0);
    const TransportComponent ms = e.recombine();
    ASSERT_TRUE(ms.blocked());
    EXPECT_EQ(checkBlockedVectors(ms.blocks, uint32_t(kTexels + file.shTerms)), "");
    EXPECT_EQ(ms.blocks.order, profiles[0].blocks.order);
    for (size_t b = 0; b < ms.blocks.blockCount(); ++b) {
        std::vector<uint32_t> together;
        for (const TransportComponent& c : profiles)
            together.insert(together.end(), c.blocks.indices.begin() + c.blocks.offsets[b],
                            c.blocks.indices.begin() + c.blocks.offsets[b + 1]);
        std::sort(together.begin(), together.end());
        together.erase(std::unique(together.begin(), together.end()), together.end());
        EXPECT_EQ(std::vector<uint32_t>(ms.blocks.indices.begin() + ms.blocks.offsets[b],
                                        ms.blocks.indices.begin() + ms.blocks.offsets[b + 1]),
                  together)
            << "block " << b;
        EXPECT_LE(together.size(), withSh ? 20u + kShTerms : 20u);
    }
    EXPECT_GE(checkRecombination(ms, profiles, e,
                                 [](double maxAbs, int) { return maxAbs * (kBlockQuantizationMaxRelativeError + 1e-5); }),
              0.0);
    const LightVector light = randomLight(9);
    e.projectLight(light);
    std::vector<glm::vec3> viaProjection;
    e.relightProjected(viaProjection);
    TransportFile recombined = file;
    recombined.components.push_back(ms);
    VertexRadiance viaFile;
    relightVertices(recombined, light, ScatteringComponents{}, viaFile);
    double diff = 0.0, norm = 0.0;
    for (size_t v = 0; v < kVertices; ++v)
        for (int c = 0; c < 3; ++c) {
            diff += std::pow(double(viaProjection[v][c] - viaFile.diffuse[v][c]), 2);
            norm += std::pow(double(viaFile.diffuse[v][c]), 2);
        }
    EXPECT_LT(std::sqrt(diff / norm), 0.01);  // the recombination's int8 steps, as above
  }
}
