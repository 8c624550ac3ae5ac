#include "common/haar.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numeric>
#include <random>
#include <vector>

#include "common/error.h"

namespace {

using prt::Cubemap;
using prt::SparseVector;

Cubemap randomCubemap(int n, int channels, uint32_t seed) {
    Cubemap map(n, channels);
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> dist(-1.0f, 1.0f);
    for (float& v : map.data()) v = dist(rng);
    return map;
}

std::vector<float> randomVector(size_t count, uint32_t seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> dist(-1.0f, 1.0f);
    std::vector<float> v(count);
    for (float& x : v) x = dist(rng);
    return v;
}

float maxAbsDiff(const std::vector<float>& a, const std::vector<float>& b) {
    EXPECT_EQ(a.size(), b.size());
    float m = 0.0f;
    for (size_t t = 0; t < a.size(); ++t) m = std::max(m, std::abs(a[t] - b[t]));
    return m;
}

double denseDot(const std::vector<float>& a, const std::vector<float>& b) {
    double s = 0.0;
    for (size_t t = 0; t < a.size(); ++t) s += double(a[t]) * double(b[t]);
    return s;
}

int log2i(int n) {
    int l = 0;
    while ((1 << l) < n) ++l;
    return l;
}

// ---------------------------------------------------------------------------------
// Transform

TEST(Haar, ForwardInverseIsIdentityOnMultiChannelCubemaps) {
    for (int n : {1, 2, 4, 32, 64}) {
        SCOPED_TRACE(n);
        const Cubemap original = randomCubemap(n, 3, 17u + uint32_t(n));
        Cubemap map = original;
        prt::haarForward(map);
        if (n > 1) {
            EXPECT_GT(maxAbsDiff(map.data(), original.data()), 0.1f);  // it did something
        }
        prt::haarInverse(map);
        EXPECT_LT(maxAbsDiff(map.data(), original.data()), 2e-6f);
    }
}

TEST(Haar, SingleChannelFaceRoundTrip) {
    const int n = 16;
    std::vector<float> face = randomVector(size_t(n) * n, 5);
    const std::vector<float> original = face;
    prt::haarForwardFace(face.data(), n);
    prt::haarInverseFace(face.data(), n);
    EXPECT_LT(maxAbsDiff(face, original), 1e-6f);
}

TEST(Haar, BasisIsOrthonormal) {
    // The reference transform is only a reference if its basis really is orthonormal.
    const int n = 8;
    for (int a = 0; a < n * n; ++a) {
        for (int b = 0; b < n * n; ++b) {
            double s = 0.0;
            for (int j = 0; j < n; ++j) {
                for (int i = 0; i < n; ++i) {
                    s += prt::haarBasis(n, a % n, a / n, i, j) * prt::haarBasis(n, b % n, b / n, i, j);
                }
            }
            ASSERT_NEAR(s, a == b ? 1.0 : 0.0, 1e-12) << "coefficients " << a << ", " << b;
        }
    }
}

TEST(Haar, ReferenceInverseUndoesReferenceForward) {
    const int n = 8;
    std::mt19937 rng(3);
    std::uniform_real_distribution<double> dist(-1.0, 1.0);
    std::vector<double> in(n * n), coeffs(n * n), back(n * n);
    for (double& v : in) v = dist(rng);
    prt::haarForwardFaceReference(in.data(), coeffs.data(), n);
    prt::haarInverseFaceReference(coeffs.data(), back.data(), n);
    for (int t = 0; t < n * n; ++t) EXPECT_NEAR(back[t], in[t], 1e-12);
}

TEST(Haar, FastTransformMatchesExplicitBasisReference) {
    for (int n : {1, 2, 4, 8, 16, 32}) {
        SCOPED_TRACE(n);
        const size_t nn = size_t(n) * n;
        std::vector<float> face = randomVector(nn, 100u + uint32_t(n));
        std::vector<double> in(face.begin(), face.end()), ref(nn);
        prt::haarForwardFaceReference(in.data(), ref.data(), n);
        const double scale = std::abs(*std::max_element(ref.begin(), ref.end(), [](double x, double y) {
            return std::abs(x) < std::abs(y);
        }));

        prt::haarForwardFace(face.data(), n);
        for (size_t t = 0; t < nn; ++t) ASSERT_NEAR(face[t], ref[t], 1e-5 * scale) << "coefficient " << t;

        // The fast inverse of the reference coefficients gives back the input.
        std::vector<float> coeffs(ref.begin(), ref.end());
        prt::haarInverseFace(coeffs.data(), n);
        for (size_t t = 0; t < nn; ++t) ASSERT_NEAR(coeffs[t], in[t], 1e-5) << "texel " << t;
    }
}

TEST(Haar, CubemapTransformMatchesReferencePerFaceAndChannel) {
    const int n = 8, channels = 3;
    const Cubemap original = randomCubemap(n, channels, 77);
    Cubemap map = original;
    prt::haarForward(map);
    std::vector<double> in(n * n), ref(n * n);
    for (int f = 0; f < prt::kCubeFaces; ++f) {
        for (int c = 0; c < channels; ++c) {
            for (int j = 0; j < n; ++j) {
                for (int i = 0; i < n; ++i) in[j * n + i] = original.texel(f, i, j)[c];
            }
            prt::haarForwardFaceReference(in.data(), ref.data(), n);
            for (int j = 0; j < n; ++j) {
                for (int i = 0; i < n; ++i) {
                    ASSERT_NEAR(map.texel(f, i, j)[c], ref[j * n + i], 1e-5)
                        << "face " << f << " channel " << c << " (" << i << ", " << j << ")";
                }
            }
        }
    }
}

TEST(Haar, StridedFaceEqualsContiguousPerChannel) {
    const int n = 16, channels = 3;
    std::vector<float> interleaved = randomVector(size_t(n) * n * channels, 9);
    std::vector<std::vector<float>> planes(channels, std::vector<float>(n * n));
    for (int t = 0; t < n * n; ++t) {
        for (int c = 0; c < channels; ++c) planes[c][t] = interleaved[t * channels + c];
    }
    for (int c = 0; c < channels; ++c) {
        prt::haarForwardFace(interleaved.data() + c, n, channels);
        prt::haarForwardFace(planes[c].data(), n);
    }
    for (int t = 0; t < n * n; ++t) {
        for (int c = 0; c < channels; ++c) ASSERT_EQ(interleaved[t * channels + c], planes[c][t]);
    }
}

TEST(Haar, ParsevalEnergyAndDotProductsPreserved) {
    for (int n : {4, 32, 64}) {
        SCOPED_TRACE(n);
        Cubemap a = randomCubemap(n, 3, 1000u + uint32_t(n));
        Cubemap b = randomCubemap(n, 3, 2000u + uint32_t(n));
        const double energyBefore = prt::energy(a.data().data(), a.data().size());
        const double dotBefore = denseDot(a.data(), b.data());
        prt::haarForward(a);
        prt::haarForward(b);
        const double energyAfter = prt::energy(a.data().data(), a.data().size());
        const double dotAfter = denseDot(a.data(), b.data());
        EXPECT_NEAR(energyAfter, energyBefore, 1e-5 * energyBefore);
        // Random vectors are nearly orthogonal: scale the tolerance by the norms.
        const double norms = std::sqrt(energyBefore * prt::energy(b.data().data(), b.data().size()));
        EXPECT_NEAR(dotAfter, dotBefore, 1e-5 * norms);
    }
}

TEST(Haar, ConstantCubemapLeavesOnlyScalingCoefficients) {
    for (int n : {1, 2, 4, 32, 64}) {
        SCOPED_TRACE(n);
        const float values[3] = {0.75f, -2.0f, 3.5f};
        Cubemap map(n, 3);
        for (size_t t = 0; t < map.texelCount(); ++t) {
            for (int c = 0; c < 3; ++c) map.data()[t * 3 + c] = values[c];
        }
        prt::haarForward(map);
        for (int f = 0; f < prt::kCubeFaces; ++f) {
            for (int j = 0; j < n; ++j) {
                for (int i = 0; i < n; ++i) {
                    for (int c = 0; c < 3; ++c) {
                        const float v = map.texel(f, i, j)[c];
                        if (i == 0 && j == 0) {
                            EXPECT_NEAR(v, values[c] * n, 1e-6 * n);
                        } else {
                            ASSERT_EQ(v, 0.0f) << "face " << f << " (" << i << ", " << j << ")";
                        }
                    }
                }
            }
        }
    }
}

TEST(Haar, ImpulseHasOneCoefficientPerLevelAndOrientation) {
    for (int n : {1, 2, 4, 32, 64}) {
        const std::vector<prt::TexelCoord> where = {
            {0, 0, 0}, {3, n - 1, n - 1}, {5, n / 2, n / 3}, {2, n - 1, 0}};
        for (const prt::TexelCoord& p : where) {
            SCOPED_TRACE(::testing::Message() << "n " << n << " face " << p.face << " (" << p.i
                                              << ", " << p.j << ")");
            Cubemap map(n, 1);
            map.texel(p.face, p.i, p.j)[0] = 1.0f;
            prt::haarForward(map);
            int nonZero = 0;
            for (size_t t = 0; t < map.texelCount(); ++t) {
                if (map.data()[t] != 0.0f) {
                    ++nonZero;
                    EXPECT_EQ(t / (size_t(n) * n), size_t(p.face)) << "coefficient on another face";
                }
            }
            EXPECT_EQ(nonZero, 3 * log2i(n) + 1);
            EXPECT_FLOAT_EQ(map.texel(p.face, 0, 0)[0], 1.0f / n);
            EXPECT_NEAR(prt::energy(map.data().data(), map.data().size()), 1.0, 1e-6);
        }
    }
}

TEST(Haar, RejectsNonPowerOfTwoFaces) {
    std::vector<float> face(9);
    EXPECT_THROW(prt::haarForwardFace(face.data(), 3), prt::Error);
    EXPECT_THROW(prt::haarInverseFace(face.data(), 0), prt::Error);
    std::vector<double> in(36), out(36);
    EXPECT_THROW(prt::haarForwardFaceReference(in.data(), out.data(), 6), prt::Error);
}

// ---------------------------------------------------------------------------------
// Sparse vectors

// Brute force: sort every non-zero by (magnitude desc, index asc), keep K, sort by index.
std::vector<uint32_t> bruteForceLargest(const std::vector<float>& dense, int channels, size_t K,
                                        const std::vector<float>* weights = nullptr) {
    const size_t count = dense.size() / channels;
    std::vector<std::pair<double, uint32_t>> all;
    for (size_t idx = 0; idx < count; ++idx) {
        double e = 0.0;
        for (int c = 0; c < channels; ++c) e += double(dense[idx * channels + c]) * dense[idx * channels + c];
        double m = std::sqrt(e);
        if (weights) m *= (*weights)[idx];
        if (m > 0.0) all.push_back({m, uint32_t(idx)});
    }
    std::sort(all.begin(), all.end(), [](const auto& x, const auto& y) {
        return x.first > y.first || (x.first == y.first && x.second < y.second);
    });
    if (all.size() > K) all.resize(K);
    std::vector<uint32_t> idx;
    for (const auto& e : all) idx.push_back(e.second);
    std::sort(idx.begin(), idx.end());
    return idx;
}

void expectWellFormed(const SparseVector& s) {
    ASSERT_EQ(s.value.size(), s.index.size() * size_t(s.channels));
    for (size_t e = 1; e < s.index.size(); ++e) ASSERT_LT(s.index[e - 1], s.index[e]);
}

TEST(SparseVector, TruncateKeepsExactlyTheKLargest) {
    const std::vector<float> dense = randomVector(1000, 42);
    for (size_t K : {size_t(1), size_t(7), size_t(50), size_t(999)}) {
        SCOPED_TRACE(K);
        const SparseVector s = prt::truncateLargest(dense.data(), dense.size(), 1, K);
        expectWellFormed(s);
        EXPECT_EQ(s.size(), K);
        EXPECT_EQ(s.index, bruteForceLargest(dense, 1, K));
        // Every kept magnitude >= every dropped one; kept values are the originals.
        float smallestKept = INFINITY;
        std::vector<bool> kept(dense.size(), false);
        for (size_t e = 0; e < s.size(); ++e) {
            EXPECT_EQ(s.value[e], dense[s.index[e]]);
            smallestKept = std::min(smallestKept, std::abs(s.value[e]));
            kept[s.index[e]] = true;
        }
        for (size_t t = 0; t < dense.size(); ++t) {
            if (!kept[t]) {
                ASSERT_LE(std::abs(dense[t]), smallestKept);
            }
        }
    }
}

TEST(SparseVector, TruncateBreaksTiesByLowerIndex) {
    //                           0     1     2     3     4     5     6     7
    const std::vector<float> d = {0.0f, 1.0f, -1.0f, 1.0f, 2.0f, 0.0f, -1.0f, -2.0f};
    const SparseVector s3 = prt::truncateLargest(d.data(), d.size(), 1, 3);
    EXPECT_EQ(s3.index, (std::vector<uint32_t>{1, 4, 7}));
    const SparseVector s4 = prt::truncateLargest(d.data(), d.size(), 1, 4);
    EXPECT_EQ(s4.index, (std::vector<uint32_t>{1, 2, 4, 7}));
    const SparseVector s1 = prt::truncateLargest(d.data(), d.size(), 1, 1);
    EXPECT_EQ(s1.index, (std::vector<uint32_t>{4}));

    // Many exact ties: always the lowest indices, and the same answer every time.
    std::vector<float> flat(5000, 0.5f);
    for (size_t t = 0; t < flat.size(); t += 3) flat[t] = -0.5f;
    const SparseVector a = prt::truncateLargest(flat.data(), flat.size(), 1, 100);
    std::vector<uint32_t> first(100);
    std::iota(first.begin(), first.end(), 0u);
    EXPECT_EQ(a.index, first);
    const SparseVector b = prt::truncateLargest(flat.data(), flat.size(), 1, 100);
    EXPECT_EQ(a.index, b.index);
    EXPECT_EQ(a.value, b.value);
}

TEST(SparseVector, TruncateEqualsTheReference) {
    // The threshold-and-scan selection against the (key, index) selection and sort it
    // replaced: identical indices and values, with ties (values on a coarse grid), zero
    // and NaN entries, weights, one and three channels, keep below, at and above the
    // number of non-zeros.
    std::mt19937 rng(5);
    std::uniform_int_distribution<int> level(-6, 6);
    for (int channels : {1, 3}) {
        for (size_t count : {size_t(1), size_t(37), size_t(6144)}) {
            std::vector<float> d(count * size_t(channels)), w(count);
            for (float& x : d) x = 0.25f * float(level(rng));
            for (size_t i = 0; i < count; ++i) w[i] = float(1 + i % 3);
            if (count > 10) {
                d[7] = std::numeric_limits<float>::quiet_NaN();
                w[3] = 0.0f;
            }
            const size_t nonZeros = prt::toSparse(d.data(), count, channels).size();
            for (size_t keep : {size_t(0), size_t(1), size_t(5), size_t(128), nonZeros - 1, nonZeros, count + 3}) {
                for (const float* weights : {static_cast<const float*>(nullptr), static_cast<const float*>(w.data())}) {
                    const SparseVector a = prt::truncateLargest(d.data(), count, channels, keep, weights);
                    const SparseVector b = prt::truncateLargestReference(d.data(), count, channels, keep, weights);
                    ASSERT_EQ(a.index, b.index) << channels << " channels, " << count << " entries, keep " << keep;
                    ASSERT_EQ(a.value.size(), b.value.size());
                    for (size_t k = 0; k < a.value.size(); ++k)
                        ASSERT_TRUE(a.value[k] == b.value[k] || (std::isnan(a.value[k]) && std::isnan(b.value[k])));
                    EXPECT_LE(a.index.size(), keep);
                }
            }
        }
    }
}

TEST(SparseVector, TruncateWithLargeKKeepsAllNonZerosAndNeverZeros) {
    std::vector<float> d = randomVector(300, 8);
    for (size_t t = 0; t < d.size(); t += 4) d[t] = 0.0f;
    const size_t nonZeros = size_t(std::count_if(d.begin(), d.end(), [](float x) { return x != 0.0f; }));
    const SparseVector all = prt::toSparse(d.data(), d.size(), 1);
    expectWellFormed(all);
    EXPECT_EQ(all.size(), nonZeros);
    for (size_t K : {nonZeros, d.size(), size_t(1) << 40}) {
        const SparseVector s = prt::truncateLargest(d.data(), d.size(), 1, K);
        EXPECT_EQ(s.index, all.index);
        EXPECT_EQ(s.value, all.value);
    }
    EXPECT_EQ(prt::truncateLargest(d.data(), d.size(), 1, 0).size(), 0u);
    const std::vector<float> zeros(64, 0.0f);
    EXPECT_EQ(prt::truncateLargest(zeros.data(), zeros.size(), 1, 10).size(), 0u);
}

TEST(SparseVector, TruncateWithAllCoefficientsReconstructsExactly) {
    const int n = 16, channels = 3;
    const Cubemap original = randomCubemap(n, channels, 11);
    Cubemap coeffs = original;
    prt::haarForward(coeffs);
    const SparseVector s = prt::truncateLargest(coeffs.data().data(), coeffs.texelCount(), channels,
                                                coeffs.texelCount());
    Cubemap back(n, channels);
    prt::addTo(s, 1.0f, back.data().data());
    EXPECT_EQ(back.data(), coeffs.data());
    prt::haarInverse(back);
    EXPECT_LT(maxAbsDiff(back.data(), original.data()), 2e-6f);
}

TEST(SparseVector, TruncationErrorEqualsDroppedEnergy) {
    const int n = 32, channels = 3;
    // A smooth signal plus a little noise, so truncation is meaningful.
    Cubemap original(n, channels);
    std::mt19937 rng(5);
    std::uniform_real_distribution<float> noise(-0.05f, 0.05f);
    for (int f = 0; f < prt::kCubeFaces; ++f) {
        for (int j = 0; j < n; ++j) {
            for (int i = 0; i < n; ++i) {
                for (int c = 0; c < channels; ++c) {
                    original.texel(f, i, j)[c] = float(f + 1) * std::sin(0.2 * i + c) * std::cos(0.1 * j) + noise(rng);
                }
            }
        }
    }
    Cubemap coeffs = original;
    prt::haarForward(coeffs);
    const double total = prt::energy(coeffs.data().data(), coeffs.data().size());
    for (size_t K : {size_t(10), size_t(128), size_t(1000)}) {
        SCOPED_TRACE(K);
        const SparseVector s = prt::truncateLargest(coeffs.data().data(), coeffs.texelCount(), channels, K);
        EXPECT_EQ(s.size(), K);
        const double dropped = total - prt::energy(s);
        Cubemap approx(n, channels);
        prt::addTo(s, 1.0f, approx.data().data());
        prt::haarInverse(approx);
        double error = 0.0;
        for (size_t t = 0; t < approx.data().size(); ++t) {
            const double e = double(approx.data()[t]) - original.data()[t];
            error += e * e;
        }
        EXPECT_NEAR(error, dropped, 1e-4 * dropped + 1e-6 * total);
    }
}

TEST(SparseVector, MultiChannelMagnitudeUsesAllChannels) {
    // Entry 0 has the largest single channel; entry 1 the largest norm over channels.
    const std::vector<float> d = {3.0f, 0.0f, 0.0f,   //
                                  2.0f, 2.0f, 2.0f,   //
                                  0.0f, 0.0f, 2.9f,   //
                                  0.0f, 0.0f, 0.0f};
    const SparseVector s = prt::truncateLargest(d.data(), 4, 3, 1);
    expectWellFormed(s);
    ASSERT_EQ(s.size(), 1u);
    EXPECT_EQ(s.index[0], 1u);
    EXPECT_EQ(s.value, (std::vector<float>{2.0f, 2.0f, 2.0f}));
    const SparseVector s2 = prt::truncateLargest(d.data(), 4, 3, 2);
    EXPECT_EQ(s2.index, (std::vector<uint32_t>{0, 1}));
    EXPECT_EQ(s2.value, (std::vector<float>{3.0f, 0.0f, 0.0f, 2.0f, 2.0f, 2.0f}));
    EXPECT_EQ(prt::truncateLargest(d.data(), 4, 3, 10).size(), 3u);  // the all-zero entry is dropped

    const std::vector<float> big = randomVector(3 * 500, 21);
    const SparseVector r = prt::truncateLargest(big.data(), 500, 3, 40);
    EXPECT_EQ(r.index, bruteForceLargest(big, 3, 40));
}

TEST(SparseVector, WeightsMultiplyTheMagnitude) {
    const std::vector<float> d = {1.0f, 2.0f};
    EXPECT_EQ(prt::truncateLargest(d.data(), 2, 1, 1).index, (std::vector<uint32_t>{1}));
    // Weighted magnitudes 3 * |1| = 3 > 1 * |2| = 2. (Weighting the squared magnitude
    // instead, 3 * 1 < 4, would keep index 1.)
    const std::vector<float> w = {3.0f, 1.0f};
    const SparseVector s = prt::truncateLargest(d.data(), 2, 1, 1, w.data());
    EXPECT_EQ(s.index, (std::vector<uint32_t>{0}));
    EXPECT_EQ(s.value, (std::vector<float>{1.0f}));  // values are not weighted
    // A zero weight drops an entry even when K would allow it.
    const std::vector<float> w0 = {0.0f, 1.0f};
    EXPECT_EQ(prt::truncateLargest(d.data(), 2, 1, 5, w0.data()).index, (std::vector<uint32_t>{1}));

    // Solid-angle weights on a real cubemap: compare with the brute force.
    const int n = 8;
    const Cubemap map = randomCubemap(n, 3, 4);
    const std::vector<double> omega = prt::faceSolidAngles(n);
    std::vector<float> weights(map.texelCount());
    for (size_t t = 0; t < weights.size(); ++t) weights[t] = float(omega[t % (size_t(n) * n)]);
    const SparseVector ws = prt::truncateLargest(map.data().data(), map.texelCount(), 3, 30, weights.data());
    EXPECT_EQ(ws.index, bruteForceLargest(map.data(), 3, 30, &weights));
    EXPECT_NE(ws.index, bruteForceLargest(map.data(), 3, 30));  // the weights did change the choice
}

TEST(SparseVector, SparseSparseDotEqualsDenseDot) {
    for (int channels : {1, 3}) {
        SCOPED_TRACE(channels);
        const size_t count = 2000;
        const std::vector<float> a = randomVector(count * channels, 31);
        const std::vector<float> b = randomVector(count * channels, 32);
        const SparseVector sa = prt::truncateLargest(a.data(), count, channels, 300);
        const SparseVector sb = prt::truncateLargest(b.data(), count, channels, 700);
        std::vector<float> da(count * channels, 0.0f), db(count * channels, 0.0f);
        prt::addTo(sa, 1.0f, da.data());
        prt::addTo(sb, 1.0f, db.data());
        const double expected = denseDot(da, db);
        EXPECT_NEAR(prt::dot(sa, sb), expected, 1e-9 + 1e-9 * std::abs(expected));
        EXPECT_NEAR(prt::dot(sb, sa), expected, 1e-9 + 1e-9 * std::abs(expected));
        EXPECT_NEAR(prt::dot(sa, sa), prt::energy(sa), 1e-9 * prt::energy(sa));
        EXPECT_NEAR(prt::energy(sa), prt::energy(da.data(), da.size()), 1e-9 * prt::energy(sa));
        // Full vectors: the sparse dot is the dense dot.
        const SparseVector fa = prt::toSparse(a.data(), count, channels);
        const SparseVector fb = prt::toSparse(b.data(), count, channels);
        EXPECT_NEAR(prt::dot(fa, fb), denseDot(a, b), 1e-9);
    }
    SparseVector one, three;
    three.channels = 3;
    EXPECT_THROW(prt::dot(one, three), prt::Error);
}

TEST(SparseVector, SparseDenseDots) {
    const size_t count = 1500;
    const std::vector<float> scalar = randomVector(count, 51);
    const std::vector<float> rgb = randomVector(count * 3, 52);
    const SparseVector s1 = prt::truncateLargest(scalar.data(), count, 1, 200);
    const SparseVector s3 = prt::truncateLargest(rgb.data(), count, 3, 200);
    const std::vector<float> light1 = randomVector(count, 53);
    const std::vector<float> light3 = randomVector(count * 3, 54);

    double expected = 0.0;
    for (size_t e = 0; e < s1.size(); ++e) expected += double(s1.value[e]) * light1[s1.index[e]];
    EXPECT_NEAR(prt::dot(s1, light1.data()), expected, 1e-5);
    EXPECT_THROW(prt::dot(s3, light1.data()), prt::Error);

    // RGB sparse . RGB dense, RGB sparse . scalar dense, scalar sparse . RGB dense.
    double e33[3] = {0, 0, 0}, e31[3] = {0, 0, 0}, e13[3] = {0, 0, 0};
    for (size_t e = 0; e < s3.size(); ++e) {
        for (int c = 0; c < 3; ++c) {
            e33[c] += double(s3.value[e * 3 + c]) * light3[s3.index[e] * 3 + c];
            e31[c] += double(s3.value[e * 3 + c]) * light1[s3.index[e]];
        }
    }
    for (size_t e = 0; e < s1.size(); ++e) {
        for (int c = 0; c < 3; ++c) e13[c] += double(s1.value[e]) * light3[s1.index[e] * 3 + c];
    }
    float out[3];
    prt::dotRGB(s3, light3.data(), 3, out);
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(out[c], e33[c], 1e-5);
    prt::dotRGB(s3, light1.data(), 1, out);
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(out[c], e31[c], 1e-5);
    prt::dotPerChannel(s1, light3.data(), 3, out);
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(out[c], e13[c], 1e-5);
    float single = 0.0f;
    prt::dotPerChannel(s1, light1.data(), 1, &single);
    EXPECT_NEAR(single, expected, 1e-5);
    EXPECT_THROW(prt::dotRGB(s1, light1.data(), 1, out), prt::Error);
    SparseVector two;
    two.channels = 2;
    EXPECT_THROW(prt::dotPerChannel(two, light3.data(), 3, out), prt::Error);
}

TEST(SparseVector, AddToScalesAndAccumulates) {
    SparseVector s;
    s.channels = 2;
    s.index = {1, 3};
    s.value = {1.0f, 2.0f, -3.0f, 4.0f};
    std::vector<float> dense(8, 1.0f);
    prt::addTo(s, 0.5f, dense.data());
    EXPECT_EQ(dense, (std::vector<float>{1, 1, 1.5f, 2, 1, 1, -0.5f, 3}));
    prt::addTo(s, -0.5f, dense.data());
    EXPECT_EQ(dense, std::vector<float>(8, 1.0f));
    EXPECT_DOUBLE_EQ(prt::energy(s), 1.0 + 4.0 + 9.0 + 16.0);

    SparseVector broken;
    broken.index = {0, 1};
    broken.value = {1.0f};
    EXPECT_THROW(prt::addTo(broken, 1.0f, dense.data()), prt::Error);
}

}  // namespace
