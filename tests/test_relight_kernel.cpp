#include "relight/prt/relight_kernel.h"

#include <gtest/gtest.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <functional>
#include <numeric>
#include <random>
#include <string>
#include <vector>

#include "common/envmap.h"
#include "common/error.h"
#include "common/haar.h"
#include "common/sh_part.h"
#include "relight/prt/light_vector.h"

namespace {

using prt::ComponentKind;
using prt::ScatteringComponents;
using prt::Cubemap;
using prt::LightVector;
using prt::TransportComponent;
using prt::TransportFile;
using prt::VertexRadiance;

// Faces in cubemap order.
constexpr int kPX = 0, kNX = 1, kPY = 2, kNY = 3, kPZ = 4, kNZ = 5;

float coefficient(const LightVector& l, int face, int i, int j, int c) {
    const size_t n = size_t(l.size);
    return l.rgb[3 * ((size_t(face) * n + size_t(j)) * n + size_t(i)) + size_t(c)];
}

float maxAbs(const std::vector<float>& v) {
    float m = 0.0f;
    for (float x : v) m = std::max(m, std::abs(x));
    return m;
}

// A lat-long map with structure at several scales: smooth lobes plus per-pixel noise.
prt::Image randomEnvironment(int width, uint32_t seed) {
    prt::Image env(width, width / 2, 3);
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    std::vector<glm::dvec3> lobes;
    for (int k = 0; k < 5; ++k)
        lobes.push_back(glm::normalize(glm::dvec3(u(rng) - 0.5, u(rng) - 0.5, u(rng) - 0.5)));
    for (int y = 0; y < env.height; ++y)
        for (int x = 0; x < env.width; ++x) {
            const glm::dvec3 d = prt::latLongPixelDirection(x, y, env.width, env.height);
            for (int c = 0; c < 3; ++c) {
                double v = 0.2 * u(rng);
                for (size_t k = 0; k < lobes.size(); ++k)
                    v += double(k + c + 1) * std::pow(std::max(0.0, glm::dot(d, lobes[k])), 8.0);
                env.at(x, y, c) = float(v);
            }
        }
    return env;
}

Cubemap randomCubemap(int n, uint32_t seed) {
    Cubemap map(n, 3);
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> dist(0.0f, 2.0f);
    for (float& v : map.data()) v = dist(rng);
    return map;
}

// ---------------------------------------------------------------------------------
// Light vectors

TEST(LightVector, ConstantEnvironmentHasOnlyFaceScalingCoefficients) {
    const glm::vec3 value(1.0f, 2.0f, 3.0f);
    for (int n : {1, 4, 16}) {
        SCOPED_TRACE(n);
        const LightVector l = prt::makeLightVector(prt::constantEnvironment(128, value), n);
        ASSERT_EQ(l.size, n);
        ASSERT_EQ(l.rgb.size(), size_t(3 * 6 * n * n));
        EXPECT_EQ(l.relativeL2Error, 0.0);
        for (int f = 0; f < 6; ++f)
            for (int j = 0; j < n; ++j)
                for (int i = 0; i < n; ++i)
                    for (int c = 0; c < 3; ++c) {
                        // Closed form: the scaling coefficient is sum of the face's
                        // texels / N = N^2 value / N; every detail of a constant is 0.
                        const double expected = (i == 0 && j == 0) ? double(value[c]) * n : 0.0;
                        EXPECT_NEAR(coefficient(l, f, i, j, c), expected, 1e-6 * value[c] * n)
                            << "face " << f << " (" << i << ", " << j << ") channel " << c;
                    }
        EXPECT_EQ(l.keptTerms, 6u);
        // Keeping the 6 non-zero terms loses nothing.
        const LightVector six = prt::makeLightVector(prt::constantEnvironment(128, value), n,
                                                     glm::dmat3(1.0), 6);
        EXPECT_EQ(six.keptTerms, 6u);
        EXPECT_LT(six.relativeL2Error, 1e-6);
    }
}

TEST(LightVector, CubemapOverloadMatchesLatLongOverload) {
    const prt::Image env = randomEnvironment(64, 3);
    const glm::dmat3 r = prt::rotationAxisAngle(glm::dvec3(1, 2, 3), 40.0);
    const LightVector a = prt::makeLightVector(env, 8, r, 50);
    const LightVector b = prt::makeLightVector(prt::latLongToCubemap(env, 8, r), 50);
    EXPECT_EQ(a.rgb, b.rgb);
    EXPECT_EQ(a.keptTerms, b.keptTerms);
    EXPECT_EQ(a.relativeL2Error, b.relativeL2Error);
}

TEST(LightVector, AboutYMatchesExactFilterAtWholePixelAngles) {
    // Rotations about +Y take the sparse filter (envmap.h); at whole-pixel angles it is
    // the exact filter up to float weights.
    const prt::Image env = randomEnvironment(128, 5);
    const int n = 8;
    for (int k : {0, 3, 32, 77, 127}) {
        const double degrees = 360.0 * k / env.width;
        const glm::dmat3 r = prt::rotationY(degrees);
        const LightVector fast = prt::makeLightVector(env, n, r);
        const LightVector exact = prt::makeLightVector(prt::latLongToCubemap(env, n, r));
        ASSERT_EQ(fast.rgb.size(), exact.rgb.size());
        const double tol = 1e-6 * maxAbs(exact.rgb);
        for (size_t t = 0; t < fast.rgb.size(); ++t)
            ASSERT_NEAR(fast.rgb[t], exact.rgb[t], tol) << "shift " << k << " coefficient " << t;
    }
    // A turntable frame: product of rotationY matrices, 45 + 11.25 degrees = 20 pixels.
    const glm::dmat3 composed = prt::rotationY(-45.0) * prt::rotationY(101.25);
    const LightVector fast = prt::makeLightVector(env, n, composed, 40);
    const LightVector exact = prt::makeLightVector(prt::latLongToCubemap(env, n, prt::rotationY(56.25)), 40);
    ASSERT_EQ(fast.rgb.size(), exact.rgb.size());
    for (size_t t = 0; t < fast.rgb.size(); ++t) EXPECT_NEAR(fast.rgb[t], exact.rgb[t], 1e-6 * maxAbs(exact.rgb));
    EXPECT_EQ(fast.keptTerms, exact.keptTerms);
    EXPECT_NEAR(fast.relativeL2Error, exact.relativeL2Error, 1e-5);
}

TEST(LightVector, AboutYBetweenPixelsStaysCloseAndKeepsEnergy) {
    // Between whole-pixel angles the light is the exact filter of the map interpolated
    // in longitude: close to the exact rotated filter, with the map's integral over the
    // sphere.
    const prt::Image env = randomEnvironment(256, 9);
    const int n = 8;
    for (double degrees : {37.5, -100.1, 200.7}) {
        const glm::dmat3 r = prt::rotationY(degrees);
        const LightVector fast = prt::makeLightVector(env, n, r);
        const LightVector exact = prt::makeLightVector(prt::latLongToCubemap(env, n, r));
        double diff = 0.0, norm = 0.0;
        for (size_t t = 0; t < fast.rgb.size(); ++t) {
            diff += (double(fast.rgb[t]) - exact.rgb[t]) * (double(fast.rgb[t]) - exact.rgb[t]);
            norm += double(exact.rgb[t]) * exact.rgb[t];
        }
        EXPECT_LT(std::sqrt(diff / norm), 2e-3) << degrees;
        std::printf("[ info ] %g degrees: relative L2 difference from the exact filter %.2e\n", degrees,
                    std::sqrt(diff / norm));
        Cubemap radiance(n, 3);
        radiance.data() = fast.rgb;
        prt::haarInverse(radiance);
        const std::vector<double> integral = radiance.integrate();
        for (int c = 0; c < 3; ++c) {
            const double expected = prt::latLongIntegral(env, c);
            EXPECT_NEAR(integral[size_t(c)], expected, 1e-5 * expected) << degrees << " channel " << c;
        }
    }
}

TEST(LightVector, OtherRotationsUseTheExactFilter) {
    const prt::Image env = randomEnvironment(64, 13);
    for (const glm::dmat3& r : {prt::rotationX(30.0), prt::rotationZ(-12.0),
                                prt::rotationAxisAngle(glm::dvec3(0, 1, 1e-6), 40.0),
                                prt::rotationY(20.0) * prt::rotationX(5.0)}) {
        const LightVector a = prt::makeLightVector(env, 8, r);
        const LightVector b = prt::makeLightVector(prt::latLongToCubemap(env, 8, r));
        EXPECT_EQ(a.rgb, b.rgb);
    }
    // Bad input is still reported by the exact path, whatever the rotation.
    EXPECT_THROW(prt::makeLightVector(env, 12, prt::rotationY(10.0)), prt::Error);
    EXPECT_THROW(prt::makeLightVector(prt::Image(), 8, prt::rotationY(10.0)), prt::Error);
}

TEST(LightVector, RejectsNonRgbInput) {
    EXPECT_THROW(prt::makeLightVector(prt::Image(8, 4, 1, 1.0f), 4), prt::Error);
    EXPECT_THROW(prt::makeLightVector(Cubemap(4, 1)), prt::Error);
}

// Face energies (sum of squares of the coefficients, Parseval = of the texels).
std::vector<double> faceEnergies(const LightVector& l) {
    std::vector<double> e(6, 0.0);
    const size_t perFace = size_t(l.size) * l.size * 3;
    for (size_t t = 0; t < l.rgb.size(); ++t) e[t / perFace] += double(l.rgb[t]) * l.rgb[t];
    return e;
}

TEST(LightVector, SunAtMinusZRotatedBy90AboutYLandsOnMinusX) {
    const int n = 8;
    const prt::Image sun = prt::sunEnvironment(256, glm::dvec3(0, 0, -1), glm::vec3(1000.0f));
    const LightVector a = prt::makeLightVector(sun, n);
    const LightVector b = prt::makeLightVector(sun, n, prt::rotationY(90.0));

    const std::vector<double> ea = faceEnergies(a), eb = faceEnergies(b);
    EXPECT_EQ(std::max_element(ea.begin(), ea.end()) - ea.begin(), kNZ);
    EXPECT_EQ(std::max_element(eb.begin(), eb.end()) - eb.begin(), kNX);
    for (int f = 0; f < 6; ++f) {
        if (f != kNZ) {
            EXPECT_EQ(ea[size_t(f)], 0.0) << "unrotated face " << f;
        }
        if (f != kNX) {
            EXPECT_EQ(eb[size_t(f)], 0.0) << "rotated face " << f;
        }
    }
    // The scaling coefficient carries the energy: sun energy / texel solid angle / N.
    EXPECT_GT(coefficient(b, kNX, 0, 0, 0), 0.0f);
    EXPECT_NEAR(coefficient(b, kNX, 0, 0, 0), coefficient(a, kNZ, 0, 0, 0),
                1e-5 * coefficient(a, kNZ, 0, 0, 0));
    // Texel (i, j) of -Z goes to texel (i, j) of -X, so the whole face carries over.
    for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i)
            for (int c = 0; c < 3; ++c)
                EXPECT_NEAR(coefficient(b, kNX, i, j, c), coefficient(a, kNZ, i, j, c),
                            1e-5 * maxAbs(a.rgb));
}

TEST(LightVector, RotationBy90AboutYPermutesFacesAsTheConventionsSay) {
    // L'(d) = L(R^T d), R = rotationY(90): R^T maps (x, y, z) to (-z, y, x). The side
    // faces' OpenGL coordinates map onto each other texel for texel:
    //   -X <- -Z, -Z <- +X, +X <- +Z, +Z <- -X   (whole Haar faces carry over);
    // +Y and -Y turn in place: +Y'(i, j) = +Y(N-1-j, i), -Y'(i, j) = -Y(j, N-1-i).
    const int n = 8;
    const prt::Image env = randomEnvironment(128, 11);
    const LightVector a = prt::makeLightVector(env, n);
    const LightVector b = prt::makeLightVector(env, n, prt::rotationY(90.0));
    const double tol = 2e-5 * maxAbs(a.rgb);

    const int from[6] = {kPZ, kNZ, -1, -1, kNX, kPX};  // rotated face f <- unrotated face
    for (int f : {kPX, kNX, kPZ, kNZ})
        for (int j = 0; j < n; ++j)
            for (int i = 0; i < n; ++i)
                for (int c = 0; c < 3; ++c)
                    ASSERT_NEAR(coefficient(b, f, i, j, c), coefficient(a, from[f], i, j, c), tol)
                        << "face " << f << " (" << i << ", " << j << ")";

    // +-Y: compare in texel space (the Haar coefficients of a turned face are a signed
    // permutation); the light vectors are orthonormal transforms of the cubemaps.
    const auto toCubemap = [n](const LightVector& l) {
        Cubemap m(n, 3);
        m.data() = l.rgb;
        prt::haarInverse(m);
        return m;
    };
    const Cubemap ca = toCubemap(a), cb = toCubemap(b);
    for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i)
            for (int c = 0; c < 3; ++c) {
                EXPECT_NEAR(cb.texel(kPY, i, j)[c], ca.texel(kPY, n - 1 - j, i)[c], tol);
                EXPECT_NEAR(cb.texel(kNY, i, j)[c], ca.texel(kNY, j, n - 1 - i)[c], tol);
            }
    // A wrong turn direction would fail: the map is not symmetric under it.
    double asym = 0.0;
    for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i)
            asym = std::max(asym, double(std::abs(cb.texel(kPY, i, j)[0] - ca.texel(kPY, j, n - 1 - i)[0])));
    EXPECT_GT(asym, 100 * tol);
}

TEST(LightVector, TruncationKeepsTheLargestTermsAndReportsTheParsevalError) {
    const int n = 8;
    const Cubemap cube = randomCubemap(n, 5);
    const LightVector full = prt::makeLightVector(cube);
    const size_t count = full.coefficientCount();
    ASSERT_EQ(count, size_t(6 * n * n));
    EXPECT_EQ(full.keptTerms, count);
    EXPECT_EQ(full.relativeL2Error, 0.0);

    std::vector<double> energy(count);
    double total = 0.0;
    for (size_t k = 0; k < count; ++k) {
        energy[k] = 0.0;
        for (int c = 0; c < 3; ++c) energy[k] += double(full.rgb[3 * k + c]) * full.rgb[3 * k + c];
        total += energy[k];
    }
    std::vector<double> sorted = energy;
    std::sort(sorted.begin(), sorted.end(), std::greater<>());

    double previous = 2.0;
    for (size_t L : {size_t(1), size_t(2), size_t(10), size_t(50), size_t(200), count - 1, count,
                     count + 5}) {
        SCOPED_TRACE(L);
        const LightVector l = prt::makeLightVector(cube, L);
        EXPECT_EQ(l.keptTerms, std::min(L, count));
        double dropped = 0.0;
        for (size_t k = std::min(L, count); k < count; ++k) dropped += sorted[k];
        const double expected = std::sqrt(dropped / total);
        EXPECT_NEAR(l.relativeL2Error, expected, 1e-6 * expected + 1e-12);
        if (L < count) {
            EXPECT_LT(l.relativeL2Error, previous);
        }
        previous = l.relativeL2Error;
        // Kept values are the original ones; the smallest kept >= the largest dropped.
        double smallestKept = 1e300, largestDropped = 0.0;
        for (size_t k = 0; k < count; ++k) {
            const bool kept = l.rgb[3 * k] != 0.0f || l.rgb[3 * k + 1] != 0.0f || l.rgb[3 * k + 2] != 0.0f;
            if (kept) {
                for (int c = 0; c < 3; ++c) ASSERT_EQ(l.rgb[3 * k + c], full.rgb[3 * k + c]);
                smallestKept = std::min(smallestKept, energy[k]);
            } else {
                largestDropped = std::max(largestDropped, energy[k]);
            }
        }
        EXPECT_GE(smallestKept, largestDropped);
    }
}

// ---------------------------------------------------------------------------------
// Relighting

struct FileSpec {
    bool ms = true;
    bool iso = true;
    int terms = 4;
};

// Random file: per vertex 0..maxCoefficients random distinct indices, values with
// magnitudes over four decades and random signs, occasionally an all-zero channel.
TransportFile randomFile(uint32_t n, size_t vertices, const FileSpec& spec, uint32_t seed,
                         size_t maxCoefficients = 200) {
    TransportFile file;
    file.cubemapSize = n;
    file.mesh.vertexCount = vertices;
    std::mt19937 rng(seed);
    const uint32_t count = 6 * n * n;
    std::vector<uint32_t> all(count);
    std::iota(all.begin(), all.end(), 0u);
    std::uniform_real_distribution<float> unit(-1.0f, 1.0f), decade(-3.0f, 1.0f);

    const auto makeComponent = [&](ComponentKind kind, uint32_t term) {
        TransportComponent c;
        c.kind = kind;
        c.term = term;
        std::vector<float> rgb;
        for (size_t v = 0; v < vertices; ++v) {
            const size_t m = std::uniform_int_distribution<size_t>(
                0, std::min<size_t>(maxCoefficients, count))(rng);
            std::shuffle(all.begin(), all.end(), rng);
            const int zeroChannel = std::uniform_int_distribution<int>(-8, 2)(rng);
            rgb.resize(3 * m);
            for (size_t k = 0; k < m; ++k)
                for (int ch = 0; ch < 3; ++ch)
                    rgb[3 * k + ch] = ch == zeroChannel ? 0.0f : unit(rng) * std::pow(10.0f, decade(rng));
            c.vectors.appendVertex(std::span<const uint32_t>(all.data(), m), rgb);
        }
        return c;
    };
    // Term components deliberately out of term order.
    std::vector<uint32_t> termOrder(size_t(spec.terms));
    std::iota(termOrder.begin(), termOrder.end(), 0u);
    std::reverse(termOrder.begin(), termOrder.end());
    if (spec.terms > 0) file.components.push_back(makeComponent(ComponentKind::SingleScatteringTerm, termOrder[0]));
    if (spec.ms) file.components.push_back(makeComponent(ComponentKind::MultipleScattering, 0));
    for (size_t k = 1; k < termOrder.size(); ++k)
        file.components.push_back(makeComponent(ComponentKind::SingleScatteringTerm, termOrder[k]));
    if (spec.iso) file.components.push_back(makeComponent(ComponentKind::SingleScatteringIsotropic, 0));
    if (spec.terms > 0) {
        prt::ViewMaps maps;
        maps.size = 2;
        maps.terms = spec.terms;
        maps.data.assign(size_t(spec.terms) * 6 * 4, 1.0f);
        file.viewMaps = maps;
    }
    return file;
}

// The test's own expectation, straight from the definition: per vertex, the sum over
// the selected components of dequantized value x light in double, and the sum of
// absolute products (the scale of the float error allowed).
struct Expected {
    std::vector<glm::dvec3> diffuse, diffuseAbs;
    std::vector<std::vector<glm::dvec3>> terms, termsAbs;  // by term index
};

Expected expectedRadiance(const TransportFile& file, const LightVector& light, const ScatteringComponents& set) {
    const size_t vertices = file.mesh.vertexCount;
    Expected e;
    e.diffuse.assign(vertices, glm::dvec3(0.0));
    e.diffuseAbs.assign(vertices, glm::dvec3(0.0));
    std::vector<uint32_t> idx;
    std::vector<float> rgb;
    size_t termCount = 0;
    for (const TransportComponent& c : file.components)
        if (c.kind == ComponentKind::SingleScatteringTerm) termCount = std::max<size_t>(termCount, c.term + 1);
    if (set.singleScattering) {
        e.terms.assign(termCount, std::vector<glm::dvec3>(vertices, glm::dvec3(0.0)));
        e.termsAbs = e.terms;
    }
    for (const TransportComponent& c : file.components) {
        const bool selected =
            c.kind == ComponentKind::MultipleScattering ? set.multipleScattering : set.singleScattering;
        if (!selected) continue;
        const bool term = c.kind == ComponentKind::SingleScatteringTerm;
        for (size_t v = 0; v < vertices; ++v) {
            c.dequantizeVertex(v, idx, rgb);  // per-vertex or blocked
            glm::dvec3 s(0.0), a(0.0);
            const size_t haar = light.rgb.size() / 3;
            for (size_t k = 0; k < idx.size(); ++k)
                for (int ch = 0; ch < 3; ++ch) {
                    // SH entries (6 N^2 + i) against the light's SH projections.
                    const double l = idx[k] < haar ? light.rgb[3 * size_t(idx[k]) + ch]
                                                   : light.sh.at(3 * (idx[k] - haar) + ch);
                    const double p = double(rgb[3 * k + ch]) * l;
                    s[ch] += p;
                    a[ch] += std::abs(p);
                }
            (term ? e.terms[c.term][v] : e.diffuse[v]) += s;
            (term ? e.termsAbs[c.term][v] : e.diffuseAbs[v]) += a;
        }
    }
    return e;
}

void expectClose(const std::vector<glm::vec3>& got, const std::vector<glm::dvec3>& want,
                 const std::vector<glm::dvec3>& scale, double relative, const std::string& what) {
    ASSERT_EQ(got.size(), want.size()) << what;
    size_t failures = 0;
    for (size_t v = 0; v < got.size() && failures < 5; ++v)
        for (int c = 0; c < 3; ++c)
            if (!(std::abs(double(got[v][c]) - want[v][c]) <= relative * scale[v][c] + 1e-30)) {
                ADD_FAILURE() << what << " vertex " << v << " channel " << c << ": " << got[v][c]
                              << " vs " << want[v][c] << " (scale " << scale[v][c] << ")";
                ++failures;
            }
}

void expectMatches(const VertexRadiance& got, const Expected& e, double relative, const std::string& what) {
    expectClose(got.diffuse, e.diffuse, e.diffuseAbs, relative, what + " diffuse");
    ASSERT_EQ(got.terms.size(), e.terms.size()) << what;
    for (size_t k = 0; k < e.terms.size(); ++k)
        expectClose(got.terms[k], e.terms[k], e.termsAbs[k], relative, what + " term " + std::to_string(k));
}

bool bitwiseEqual(const VertexRadiance& a, const VertexRadiance& b) {
    const auto same = [](const std::vector<glm::vec3>& x, const std::vector<glm::vec3>& y) {
        return x.size() == y.size() && std::memcmp(x.data(), y.data(), x.size() * sizeof(glm::vec3)) == 0;
    };
    if (!same(a.diffuse, b.diffuse) || a.terms.size() != b.terms.size()) return false;
    for (size_t k = 0; k < a.terms.size(); ++k)
        if (!same(a.terms[k], b.terms[k])) return false;
    return true;
}

// Every fast-path variant this machine can run.
std::vector<prt::RelightOptions> variants() {
    std::vector<prt::RelightOptions> out;
    for (prt::RelightIsa isa : {prt::RelightIsa::Baseline, prt::RelightIsa::Avx2Fma, prt::RelightIsa::Avx512})
        for (prt::RelightLayout layout : {prt::RelightLayout::Rgb3, prt::RelightLayout::Rgb4})
            if (prt::relightIsaSupported(isa)) out.push_back({layout, isa});
    return out;
}

std::string variantName(const prt::RelightOptions& o) {
    return std::string(o.isa == prt::RelightIsa::Avx512    ? "avx512"
                       : o.isa == prt::RelightIsa::Avx2Fma ? "avx2"
                                                           : "baseline") +
           (o.layout == prt::RelightLayout::Rgb3 ? " rgb3" : " rgb4");
}

const ScatteringComponents kSets[] = {{true, true}, {true, false}, {false, true}, {false, false}};

std::string setName(const ScatteringComponents& s) {
    return std::string(s.multipleScattering ? "ms" : "-") + "," + (s.singleScattering ? "ss" : "-");
}

TEST(Relight, FastKernelMatchesReferenceOnRandomFiles) {
    const uint32_t n = 8;
    const LightVector light = prt::makeLightVector(randomCubemap(int(n), 21));
    const FileSpec specs[] = {{true, true, 4}, {true, false, 0}, {false, true, 4}, {true, true, 0},
                              {false, false, 4}};
    uint32_t seed = 100;
    for (const FileSpec& spec : specs) {
        const TransportFile file = randomFile(n, 2100, spec, seed++);
        for (const ScatteringComponents& set : kSets) {
            const std::string what = "file ms=" + std::to_string(spec.ms) + " iso=" +
                                     std::to_string(spec.iso) + " K=" + std::to_string(spec.terms) +
                                     ", set " + setName(set);
            SCOPED_TRACE(what);
            const Expected e = expectedRadiance(file, light, set);
            VertexRadiance reference, fast;
            prt::relightVerticesReference(file, light, set, reference);
            prt::relightVertices(file, light, set, fast);
            expectMatches(reference, e, 1e-7, "reference");
            expectMatches(fast, e, 1e-5, "fast");
            EXPECT_EQ(fast.terms.size(), set.singleScattering ? size_t(spec.terms) : 0u);
            for (const prt::RelightOptions& options : variants()) {
                VertexRadiance v;
                prt::relightVertices(file, light, set, v, options);
                expectMatches(v, e, 1e-5, variantName(options));
            }
        }
    }
}

// A file whose vectors carry SH parts (common/sh_part.h): made from dense random
// transports by truncateWithShPart. Keeping everything, the relit value is the dense
// product T . L of the original transport (the split is invisible); truncated, every
// kernel matches the definition; a hand-built light without `sh` gives the same.
TEST(Relight, ShPartRelightsAsTheDenseTransport) {
    const uint32_t n = 8, count = 6 * n * n;
    const size_t vertices = 300;
    const LightVector light = prt::makeLightVector(randomCubemap(int(n), 41));
    ASSERT_EQ(light.sh.size(), 3u * prt::kMaxShTerms);  // every SH term a file of this N can hold
    std::mt19937 rng(42);
    std::uniform_real_distribution<float> unit(0.0f, 1.0f);
    std::vector<std::vector<float>> dense(vertices);
    for (size_t keep : {size_t(count + 9), size_t(40)}) {
        TransportFile file;
        file.cubemapSize = n;
        file.shTerms = 9;
        file.mesh.vertexCount = vertices;
        TransportComponent c;
        for (size_t v = 0; v < vertices; ++v) {
            if (dense[v].empty()) {
                // A smooth positive texel function with a random lobe: mostly SH.
                Cubemap t(int(n), 3);
                const glm::dvec3 axis = glm::normalize(glm::dvec3(unit(rng) - 0.5, unit(rng) - 0.5, unit(rng) - 0.5));
                for (int f = 0; f < 6; ++f)
                    for (int j = 0; j < int(n); ++j)
                        for (int i = 0; i < int(n); ++i)
                            for (int ch = 0; ch < 3; ++ch)
                                t.texel(f, i, j)[ch] = float(prt::texelSolidAngle(int(n), i, j) *
                                                             (std::max(0.0, glm::dot(prt::texelDirection(int(n), f, i, j), axis)) +
                                                              0.1 * unit(rng)) * (1 + ch));
                prt::haarForward(t);
                dense[v] = t.data();
            }
            std::vector<float> d = dense[v];
            d.resize((count + 9) * 3, 0.0f);
            const prt::SparseVector sv = prt::truncateWithShPart(d.data(), count, 3, 9, keep);
            c.vectors.appendVertex(sv.index, sv.value);
        }
        file.components.push_back(std::move(c));
        const ScatteringComponents set{true, false};
        VertexRadiance reference, fast, handBuilt;
        prt::relightVerticesReference(file, light, set, reference);
        prt::relightVertices(file, light, set, fast);
        LightVector noSh = light;
        noSh.sh.clear();
        prt::relightVertices(file, noSh, set, handBuilt);
        const Expected e = expectedRadiance(file, light, set);
        expectMatches(reference, e, 1e-7, "reference");
        expectMatches(fast, e, 1e-5, "fast");
        expectMatches(handBuilt, e, 1e-5, "light without sh");
        for (const prt::RelightOptions& options : variants()) {
            VertexRadiance v;
            prt::relightVertices(file, light, set, v, options);
            expectMatches(v, e, 1e-5, variantName(options));
        }
        // Blocked (SH indices forced into every block): the blocked kernels read the
        // SH entries like any other index.
        TransportFile blocked = file;
        TransportComponent& bc = blocked.components[0];
        std::vector<uint32_t> order(vertices);
        std::iota(order.begin(), order.end(), 0u);
        bc.blocks = prt::jointTruncate(bc.vectors, 24, order, count);
        bc.vectors.clear();
        ASSERT_EQ(prt::checkBlockedVectors(bc.blocks, count + 9), "");
        VertexRadiance blockedReference, blockedFast;
        prt::relightVerticesReference(blocked, light, set, blockedReference);
        const Expected eb = expectedRadiance(blocked, light, set);
        expectMatches(blockedReference, eb, 1e-7, "blocked reference");
        for (const prt::RelightOptions& options : variants()) {
            prt::relightVertices(blocked, light, set, blockedFast, options);
            expectMatches(blockedFast, eb, 1e-5, "blocked " + variantName(options));
        }
        if (keep == count + 9) {
            for (size_t v = 0; v < vertices; ++v)
                for (int ch = 0; ch < 3; ++ch) {
                    double exact = 0.0;
                    for (size_t k = 0; k < count; ++k) exact += double(dense[v][3 * k + ch]) * light.rgb[3 * k + ch];
                    // int16 quantization of the vector (~1.5e-5 of its largest value) dominates.
                    EXPECT_NEAR(fast.diffuse[v][ch], exact, 2e-4 * std::fabs(exact)) << "vertex " << v;
                }
        }
    }
}

TEST(Relight, FastKernelWithTruncatedLightAndLargeCubemap) {
    // N = 64 (24576 coefficients), an approximated light vector with many zeros.
    const uint32_t n = 64;
    const LightVector light = prt::makeLightVector(randomCubemap(int(n), 8), 500);
    const TransportFile file = randomFile(n, 700, {true, true, 2}, 9, 300);
    const Expected e = expectedRadiance(file, light, {true, true});
    for (const prt::RelightOptions& options : variants()) {
        VertexRadiance fast;
        prt::relightVertices(file, light, {true, true}, fast, options);
        expectMatches(fast, e, 1e-5, variantName(options));
    }
}

TEST(Relight, ResultIsIndependentOfThreadCountAndReusesOutput) {
    const uint32_t n = 16;
    const LightVector light = prt::makeLightVector(randomCubemap(int(n), 4));
    const TransportFile file = randomFile(n, 5000, {true, true, 4}, 77, 128);
    const ScatteringComponents all{true, true};
    // (More threads than cores would only be refused by TBB's market on a small machine.)
    for (const prt::RelightOptions& options : variants()) {
        SCOPED_TRACE(variantName(options));
        VertexRadiance one, two, defaultArena;
        tbb::task_arena(1).execute([&] { prt::relightVertices(file, light, all, one, options); });
        tbb::task_arena(2).execute([&] { prt::relightVertices(file, light, all, two, options); });
        prt::relightVertices(file, light, all, defaultArena, options);
        EXPECT_TRUE(bitwiseEqual(one, two));
        EXPECT_TRUE(bitwiseEqual(one, defaultArena));
    }
    VertexRadiance one;
    prt::relightVertices(file, light, all, one);

    // Reusing an output that held another result (more terms, other values) gives the
    // same answer: every entry is overwritten, surplus terms are dropped.
    VertexRadiance reused;
    reused.diffuse.assign(9000, glm::vec3(7.0f));
    reused.terms.assign(6, std::vector<glm::vec3>(9000, glm::vec3(-1.0f)));
    prt::relightVertices(file, light, all, reused);
    EXPECT_EQ(reused.diffuse.size(), 5000u);
    EXPECT_EQ(reused.terms.size(), 4u);
    EXPECT_TRUE(bitwiseEqual(one, reused));
}

TEST(Relight, SingleScalingCoefficientUnderConstantLightIsClosedForm) {
    // MS vector of vertex v: the scaling coefficient of face f = v % 6 with value a_v;
    // constant light `value` has scaling coefficient value * N on every face, so the
    // relit radiance is a_v * value * N. Vertices >= 6 also carry a larger detail
    // coefficient (3 a_v; zero light), so a_v is quantized to round(32767 / 3) steps:
    // the result then carries the 16-bit quantization error, within its documented bound.
    const int n = 4;
    const glm::vec3 value(1.0f, 2.0f, 3.0f);
    const LightVector light = prt::makeLightVector(prt::constantEnvironment(64, value), n);
    TransportFile file;
    file.cubemapSize = uint32_t(n);
    const size_t vertices = 18;
    file.mesh.vertexCount = vertices;
    TransportComponent ms;
    std::vector<glm::vec3> a(vertices);
    for (size_t v = 0; v < vertices; ++v) {
        a[v] = glm::vec3(0.5f + float(v), -2.0f + 0.37f * float(v), 1e-3f * float(v + 1));
        const uint32_t f = uint32_t(v % 6);
        std::vector<uint32_t> idx{f * uint32_t(n * n)};
        std::vector<float> rgb{a[v].x, a[v].y, a[v].z};
        if (v >= 6) {
            idx.push_back(f * uint32_t(n * n) + 5);
            for (int c = 0; c < 3; ++c) rgb.push_back(3.0f * a[v][c]);
        }
        ms.vectors.appendVertex(idx, rgb);
    }
    file.components.push_back(ms);

    VertexRadiance fast, reference;
    prt::relightVertices(file, light, {true, true}, fast);
    prt::relightVerticesReference(file, light, {true, true}, reference);
    ASSERT_EQ(fast.diffuse.size(), vertices);
    EXPECT_TRUE(fast.terms.empty());
    bool quantizationVisible = false;
    for (size_t v = 0; v < vertices; ++v)
        for (int c = 0; c < 3; ++c) {
            const double exact = double(a[v][c]) * value[c] * n;
            const double vertexMax = (v >= 6 ? 3.0 : 1.0) * std::abs(a[v][c]);
            const double bound = prt::kQuantizationMaxRelativeError * vertexMax * value[c] * n +
                                 1e-6 * std::abs(exact);
            EXPECT_NEAR(fast.diffuse[v][c], exact, bound) << "vertex " << v << " channel " << c;
            EXPECT_NEAR(reference.diffuse[v][c], exact, bound) << "vertex " << v << " channel " << c;
            if (std::abs(fast.diffuse[v][c] - exact) > 1e-5 * std::abs(exact)) quantizationVisible = true;
        }
    EXPECT_TRUE(quantizationVisible) << "the test should exercise the quantization error";
}

TEST(Relight, CubemapSizeMismatchThrows) {
    TransportFile file;
    file.cubemapSize = 32;
    file.mesh.vertexCount = 1;
    TransportComponent ms;
    const std::vector<uint32_t> idx{0};
    const std::vector<float> rgb{1, 1, 1};
    ms.vectors.appendVertex(idx, rgb);
    file.components.push_back(ms);
    const LightVector light = prt::makeLightVector(prt::constantEnvironment(32, glm::vec3(1.0f)), 16);
    VertexRadiance out;
    for (int pass = 0; pass < 2; ++pass) {
        try {
            if (pass == 0)
                prt::relightVertices(file, light, {true, true}, out);
            else
                prt::relightVerticesReference(file, light, {true, true}, out);
            ADD_FAILURE() << "no exception";
        } catch (const prt::Error& e) {
            EXPECT_STREQ(e.what(), "light vector: cubemap size 16 does not match the transport file's 32");
        }
    }
}

TEST(Relight, CorruptInMemoryVectorsAreRefusedNotRead) {
    const uint32_t n = 4;
    TransportFile good = randomFile(n, 3000, {true, false, 0}, 5, 40);
    const LightVector light = prt::makeLightVector(randomCubemap(int(n), 1));
    VertexRadiance out;
    EXPECT_NO_THROW(prt::relightVertices(good, light, {true, true}, out));

    TransportFile badIndex = good;  // an index past 6 N^2 at a vertex's end
    auto& s = badIndex.components[0].vectors;
    size_t v = 2500;
    while (s.offsets[v + 1] == s.offsets[v]) ++v;
    s.indices[s.offsets[v + 1] - 1] = uint16_t(6 * n * n);
    EXPECT_THROW(prt::relightVertices(badIndex, light, {true, true}, out), prt::Error);
    EXPECT_THROW(prt::relightVerticesReference(badIndex, light, {true, true}, out), prt::Error);
    EXPECT_NO_THROW(prt::relightVertices(badIndex, light, {false, true}, out));  // not selected

    TransportFile badOffsets = good;
    badOffsets.components[0].vectors.offsets[1000] = badOffsets.components[0].vectors.offsets[1001] + 1;
    EXPECT_THROW(prt::relightVertices(badOffsets, light, {true, true}, out), prt::Error);

    TransportFile badSizes = good;
    badSizes.components[0].vectors.scales.pop_back();
    EXPECT_THROW(prt::relightVertices(badSizes, light, {true, true}, out), prt::Error);

    TransportFile mixedCounts = randomFile(n, 10, {true, true, 0}, 6, 10);
    mixedCounts.components[1].vectors.appendVertex(std::span<const uint32_t>(), std::span<const float>());
    EXPECT_THROW(prt::relightVertices(mixedCounts, light, {true, true}, out), prt::Error);

    LightVector shortLight = light;
    shortLight.rgb.pop_back();
    EXPECT_THROW(prt::relightVertices(good, shortLight, {true, true}, out), prt::Error);
}

TEST(Relight, StreamBytesCountTheSelectedComponents) {
    const TransportFile file = randomFile(4, 300, {true, true, 3}, 12, 30);
    size_t ms = 0, ss = 0;
    for (const TransportComponent& c : file.components)
        (c.kind == ComponentKind::MultipleScattering ? ms : ss) += c.vectors.byteSize();
    ASSERT_GT(ms, 0u);
    ASSERT_GT(ss, 0u);
    EXPECT_EQ(prt::relightStreamBytes(file, {true, false}), ms);
    EXPECT_EQ(prt::relightStreamBytes(file, {false, true}), ss);
    EXPECT_EQ(prt::relightStreamBytes(file, {true, true}), ms + ss);
    EXPECT_EQ(prt::relightStreamBytes(file, {false, false}), 0u);
    // offsets (V + 1) x 4 + indices x 2 + values x 6 + scales V x 12
    const auto& v = file.components[1].vectors;
    EXPECT_EQ(v.byteSize(), 4 * 301 + 8 * v.indices.size() + 12 * 300);
}

TEST(Relight, VariantsAreAvailable) {
    EXPECT_TRUE(prt::relightIsaSupported(prt::RelightIsa::Best));
    EXPECT_TRUE(prt::relightIsaSupported(prt::RelightIsa::Baseline));
    if (prt::relightIsaSupported(prt::RelightIsa::Avx512)) {
        EXPECT_TRUE(prt::relightIsaSupported(prt::RelightIsa::Avx2Fma));  // it runs per-vertex components
    } else {
        const TransportFile file = randomFile(4, 10, {true, false, 0}, 1, 5);
        VertexRadiance out;
        EXPECT_THROW(prt::relightVertices(file, prt::makeLightVector(randomCubemap(4, 1)), {true, true},
                                          out, {prt::RelightLayout::Rgb4, prt::RelightIsa::Avx512}),
                     prt::Error);
        std::printf("[ info ] no AVX-512 (F, BW, VL): the blocked AVX-512 kernel is not tested\n");
    }
    if (!prt::relightIsaSupported(prt::RelightIsa::Avx2Fma)) {
        const TransportFile file = randomFile(4, 10, {true, false, 0}, 1, 5);
        VertexRadiance out;
        EXPECT_THROW(prt::relightVertices(file, prt::makeLightVector(randomCubemap(4, 1)), {true, true},
                                          out, {prt::RelightLayout::Rgb4, prt::RelightIsa::Avx2Fma}),
                     prt::Error);
        GTEST_SKIP() << "no AVX2 + FMA: only the baseline kernel is tested";
    }
}

// ---------------------------------------------------------------------------------
// Blocked components (common/blocked_vectors.h)

// A shuffled vertex order: blocks are not runs of consecutive vertices, and with V not a
// multiple of 16 the last block is partial.
std::vector<uint32_t> shuffledOrder(size_t vertices, uint32_t seed) {
    std::vector<uint32_t> order(vertices);
    std::iota(order.begin(), order.end(), 0u);
    std::mt19937 rng(seed);
    std::shuffle(order.begin(), order.end(), rng);
    return order;
}

// `file` with the components `which` selects converted to blocks keeping `keep` indices
// per block (jointTruncate of their per-vertex vectors, in a shuffled order).
TransportFile blockedCopy(TransportFile file, size_t keep, uint32_t seed,
                          const std::function<bool(const TransportComponent&)>& which) {
    const std::vector<uint32_t> order = shuffledOrder(file.mesh.vertexCount, seed);
    for (TransportComponent& c : file.components) {
        if (!which(c)) continue;
        c.blocks = prt::jointTruncate(c.vectors, keep, order);
        c.vectors.clear();
        EXPECT_EQ(prt::checkBlockedVectors(c.blocks, 6 * file.cubemapSize * file.cubemapSize), "");
    }
    return file;
}

bool everyComponent(const TransportComponent&) { return true; }

// The float error of the blocked kernel (relight_kernel.h, PRECISION): at most
// (n + 3) 2^-24 of sum |v_n L_n| for a block of n <= keep indices; adding the diffuse
// components costs a rounding of the running sum each (<= 3 of them here), and the
// reference's own float output half an ulp.
double blockedTolerance(size_t keep) { return (double(keep) + 3.0 + 3.0 + 1.0) * 0x1p-24; }

TEST(RelightBlocked, FastKernelMatchesReferenceOnRandomBlocks) {
    struct Case {
        uint32_t n;
        size_t vertices, maxCoefficients, keep;
        int lightTerms;  // 0: full light vector
    };
    // 1000 = 62 x 16 + 8 vertices: a partial last block. N = 32 with a truncated light:
    // larger indices, zero light coefficients.
    const Case cases[] = {{8, 1000, 200, 100, 0}, {32, 1000, 300, 160, 400}, {4, 37, 6, 64, 0}};
    uint32_t seed = 300;
    for (const Case& k : cases) {
        const LightVector light = prt::makeLightVector(randomCubemap(int(k.n), seed), size_t(k.lightTerms));
        const TransportFile file =
            blockedCopy(randomFile(k.n, k.vertices, {true, true, 3}, seed, k.maxCoefficients), k.keep, seed + 1,
                        everyComponent);
        ++seed;
        for (const ScatteringComponents& set : kSets) {
            const std::string what = "N " + std::to_string(k.n) + " keep " + std::to_string(k.keep) + ", set " +
                                     setName(set);
            SCOPED_TRACE(what);
            const Expected e = expectedRadiance(file, light, set);
            VertexRadiance reference, fast;
            prt::relightVerticesReference(file, light, set, reference);
            prt::relightVertices(file, light, set, fast);
            expectMatches(reference, e, 1e-7, "reference");
            expectMatches(fast, e, blockedTolerance(k.keep), "fast");
            EXPECT_EQ(fast.terms.size(), set.singleScattering ? 3u : 0u);
            for (const prt::RelightOptions& options : variants()) {
                VertexRadiance v;
                prt::relightVertices(file, light, set, v, options);
                expectMatches(v, e, blockedTolerance(k.keep), variantName(options));
            }
        }
    }
}

TEST(RelightBlocked, MatchesPerVertexWhenNothingIsDropped) {
    // Per-vertex vectors of at most 5 coefficients from 40 indices, so a block's union
    // (<= 40) is within keep = 48: jointTruncate keeps everything and the blocked result
    // differs from the per-vertex one of the same source vectors only by the 8-bit
    // quantization: |v - dequantized v| <= kBlockQuantizationMaxRelativeError max_n |v_nc|
    // per value, so per vertex and channel the sum moves by at most that times
    // max_n |v_nc| sum_n |L_nc|, plus both kernels' float error (blockedTolerance of the
    // sum of |v_n L_n|). The vertices in the first block of the order have no
    // coefficients at all (an empty block: zero output).
    const uint32_t n = 8;
    const size_t vertices = 999;
    const LightVector light = prt::makeLightVector(randomCubemap(int(n), 17));
    const std::vector<uint32_t> order = shuffledOrder(vertices, 18);
    std::vector<bool> empty(vertices, false);
    for (size_t s = 0; s < 16; ++s) empty[order[s]] = true;
    TransportFile perVertex;
    perVertex.cubemapSize = n;
    perVertex.mesh.vertexCount = vertices;
    TransportComponent ms;
    std::mt19937 rng(19);
    std::uniform_real_distribution<float> unit(-1.0f, 1.0f), decade(-2.0f, 1.0f);
    std::vector<uint32_t> pool(40);
    for (uint32_t& x : pool) x = std::uniform_int_distribution<uint32_t>(0, 6 * n * n - 1)(rng);
    std::sort(pool.begin(), pool.end());
    pool.erase(std::unique(pool.begin(), pool.end()), pool.end());
    for (size_t v = 0; v < vertices; ++v) {
        std::shuffle(pool.begin(), pool.end(), rng);
        const size_t m = empty[v] ? 0 : std::uniform_int_distribution<size_t>(1, 5)(rng);
        std::vector<float> rgb(3 * m);
        for (float& x : rgb) x = unit(rng) * std::pow(10.0f, decade(rng));
        ms.vectors.appendVertex(std::span<const uint32_t>(pool.data(), m), rgb);
    }
    perVertex.components.push_back(ms);
    const size_t keep = 48;
    TransportFile blocked = perVertex;
    blocked.components[0].blocks = prt::jointTruncate(ms.vectors, keep, order);
    blocked.components[0].vectors.clear();
    ASSERT_EQ(blocked.components[0].blocks.offsets[1], 0u) << "the first block should be empty";
    std::vector<uint32_t> idx, kept;
    std::vector<float> rgb;
    for (size_t v = 0; v < vertices; ++v) {  // every vertex keeps all its indices
        ms.vectors.dequantizeVertex(v, idx, rgb);
        blocked.components[0].blocks.dequantizeVertex(v, kept, rgb);
        ASSERT_TRUE(std::includes(kept.begin(), kept.end(), idx.begin(), idx.end())) << "vertex " << v;
    }

    VertexRadiance want;
    prt::relightVertices(perVertex, light, {true, true}, want);
    for (const prt::RelightOptions& options : variants()) {
        SCOPED_TRACE(variantName(options));
        VertexRadiance got;
        prt::relightVertices(blocked, light, {true, true}, got, options);
        ASSERT_EQ(got.diffuse.size(), vertices);
        size_t failures = 0;
        bool quantizationVisible = false;
        for (size_t v = 0; v < vertices && failures < 5; ++v) {
            ms.vectors.dequantizeVertex(v, idx, rgb);
            for (int c = 0; c < 3; ++c) {
                double maxV = 0.0, sumL = 0.0, sumVL = 0.0;
                for (size_t k = 0; k < idx.size(); ++k) {
                    const double l = std::abs(light.rgb[3 * size_t(idx[k]) + size_t(c)]);
                    maxV = std::max(maxV, double(std::abs(rgb[3 * k + size_t(c)])));
                    sumL += l;
                    sumVL += std::abs(rgb[3 * k + size_t(c)]) * l;
                }
                const double bound = prt::kBlockQuantizationMaxRelativeError * maxV * sumL +
                                     2.0 * blockedTolerance(keep) * sumVL;
                const double diff = std::abs(double(got.diffuse[v][c]) - want.diffuse[v][c]);
                if (empty[v]) {
                    EXPECT_EQ(got.diffuse[v][c], 0.0f);
                } else if (!(diff <= bound)) {
                    ADD_FAILURE() << "vertex " << v << " channel " << c << ": " << got.diffuse[v][c] << " vs "
                                  << want.diffuse[v][c] << " (bound " << bound << ")";
                    ++failures;
                }
                if (diff > 1e-3 * sumVL) quantizationVisible = true;
            }
        }
        EXPECT_TRUE(quantizationVisible) << "the test should exercise the 8-bit quantization";
    }
}

TEST(RelightBlocked, ShPartHasScalesOfItsOwnInEveryVariant) {
    // Like MatchesPerVertexWhenNothingIsDropped, with an SH part whose band 0 is ~30x the
    // Haar values (as on real meshes): with SH scales (jointTruncate's forcedFrom) each
    // part's quantization is bounded by its own maximum, per vertex and channel
    //     |blocked - per vertex| <= eps (max_Haar |v| sum_Haar |L| + max_SH |v| sum_SH |L|)
    // plus both kernels' float error; with one scale (format version 3) the Haar part's
    // steps follow the SH band 0 and the bound fails. Two lights: an environment's, and
    // the same with its SH projections zeroed, under which only the Haar part's
    // quantization shows (under the first, the SH part's error bound hides it).
    const uint32_t n = 8, haar = 6 * n * n;
    const size_t vertices = 203;
    const LightVector environment = prt::makeLightVector(randomCubemap(int(n), 23));
    ASSERT_EQ(environment.sh.size(), 3u * prt::kMaxShTerms);
    const LightVector haarOnly = [&] {
        LightVector l = environment;
        std::fill(l.sh.begin(), l.sh.end(), 0.0f);
        return l;
    }();
    const std::vector<uint32_t> order = shuffledOrder(vertices, 24);
    TransportFile perVertex;
    perVertex.cubemapSize = n;
    perVertex.shTerms = 9;
    perVertex.mesh.vertexCount = vertices;
    TransportComponent ms;
    std::mt19937 rng(25);
    std::uniform_real_distribution<float> unit(-1.0f, 1.0f);
    std::vector<uint32_t> pool(40);
    for (uint32_t& x : pool) x = std::uniform_int_distribution<uint32_t>(0, haar - 1)(rng);
    std::sort(pool.begin(), pool.end());
    pool.erase(std::unique(pool.begin(), pool.end()), pool.end());
    for (size_t v = 0; v < vertices; ++v) {
        std::shuffle(pool.begin(), pool.end(), rng);
        const size_t m = std::uniform_int_distribution<size_t>(1, 5)(rng);
        std::vector<uint32_t> idx(pool.begin(), pool.begin() + ptrdiff_t(m));
        std::vector<float> rgb(3 * m);
        for (float& x : rgb) x = unit(rng);
        for (uint32_t i = 0; i < 9; ++i) {
            idx.push_back(haar + i);
            for (int c = 0; c < 3; ++c) rgb.push_back(i == 0 ? 30.0f * (1.0f + 0.3f * unit(rng)) : unit(rng));
        }
        ms.vectors.appendVertex(idx, rgb);
    }
    perVertex.components.push_back(ms);
    const size_t keep = 48 + 9;
    for (const LightVector* light : {&environment, &haarOnly}) {
        for (bool shScales : {true, false}) {
            const auto lightAt = [&](uint32_t i, int c) {
                return double(i < haar ? light->rgb[3 * size_t(i) + size_t(c)]
                                       : light->sh[3 * size_t(i - haar) + size_t(c)]);
            };
            VertexRadiance want;
            prt::relightVertices(perVertex, *light, {true, true}, want);
            TransportFile blocked = perVertex;
            blocked.components[0].blocks = prt::jointTruncate(ms.vectors, keep, order, shScales ? haar : UINT32_MAX);
            blocked.components[0].vectors.clear();
            ASSERT_EQ(blocked.components[0].blocks.shFrom, shScales ? haar : UINT32_MAX);
            for (const prt::RelightOptions& options : variants()) {
                SCOPED_TRACE(variantName(options) + (shScales ? ", SH scales" : ", one scale") +
                             (light == &haarOnly ? ", SH light zeroed" : ""));
                VertexRadiance got, reference;
                prt::relightVertices(blocked, *light, {true, true}, got, options);
                prt::relightVerticesReference(blocked, *light, {true, true}, reference);
                size_t failures = 0;
                std::vector<uint32_t> idx;
                std::vector<float> rgb;
                for (size_t v = 0; v < vertices; ++v) {
                    ms.vectors.dequantizeVertex(v, idx, rgb);
                    for (int c = 0; c < 3; ++c) {
                        double maxV[2] = {}, sumL[2] = {}, sumVL = 0.0;  // [0] Haar, [1] SH
                        for (size_t k = 0; k < idx.size(); ++k) {
                            const double x = std::abs(rgb[3 * k + size_t(c)]), l = std::abs(lightAt(idx[k], c));
                            const int part = idx[k] < haar ? 0 : 1;
                            maxV[part] = std::max(maxV[part], x);
                            sumL[part] += l;
                            sumVL += x * l;
                        }
                        const double bound = prt::kBlockQuantizationMaxRelativeError *
                                                 (maxV[0] * sumL[0] + maxV[1] * sumL[1]) +
                                             2.0 * blockedTolerance(keep) * sumVL;
                        EXPECT_NEAR(got.diffuse[v][c], reference.diffuse[v][c], blockedTolerance(keep) * sumVL);
                        if (!(std::abs(double(got.diffuse[v][c]) - want.diffuse[v][c]) <= bound)) ++failures;
                    }
                }
                if (shScales) {
                    EXPECT_EQ(failures, 0u);
                } else if (light == &haarOnly) {
                    EXPECT_GT(failures, vertices / 2) << "one scale should break the per-part bound";
                }
            }
        }
    }
}

TEST(RelightBlocked, ShScalesOnBlocksWithOnePartOrNone) {
    // Hand-built blocks with SH scales (shFrom = 6 N^2): Haar indices only, SH indices
    // only, no index, both, and a partial last block with one SH index. Every variant
    // against the slow reference (dequantizeVertex, double sums).
    const uint32_t n = 4, haar = 6 * n * n;
    const LightVector light = prt::makeLightVector(randomCubemap(int(n), 27));
    TransportFile file;
    file.cubemapSize = n;
    file.shTerms = 4;
    TransportComponent c;
    c.blocks.shFrom = haar;
    const std::vector<std::vector<uint32_t>> blockIndices = {
        {0, 7, 50}, {haar, haar + 3}, {}, {3, 90, haar, haar + 1, haar + 2, haar + 3}, {haar + 2}};
    std::mt19937 rng(28);
    std::uniform_real_distribution<float> unit(-1.0f, 1.0f);
    uint32_t vertex = 0;
    for (size_t k = 0; k < blockIndices.size(); ++k) {
        const uint32_t lanes = k + 1 == blockIndices.size() ? 5 : 16;
        std::vector<uint32_t> laneVertices;
        for (uint32_t lane = 0; lane < lanes; ++lane) laneVertices.push_back(vertex++);
        std::vector<float> rgb(3 * lanes * blockIndices[k].size());
        for (size_t i = 0; i < rgb.size(); ++i)
            rgb[i] = unit(rng) * (blockIndices[k][i / (3 * lanes)] >= haar ? 30.0f : 1.0f);
        c.blocks.appendBlock(blockIndices[k], rgb, laneVertices);
    }
    file.mesh.vertexCount = vertex;
    file.components.push_back(c);
    ASSERT_EQ(prt::checkBlockedVectors(file.components[0].blocks, haar + 4), "");
    VertexRadiance reference;
    prt::relightVerticesReference(file, light, {true, true}, reference);
    for (size_t v = 32; v < 48; ++v) EXPECT_EQ(reference.diffuse[v], glm::vec3(0.0f)) << "the empty block";
    for (const prt::RelightOptions& options : variants()) {
        SCOPED_TRACE(variantName(options));
        VertexRadiance got;
        prt::relightVertices(file, light, {true, true}, got, options);
        ASSERT_EQ(got.diffuse.size(), size_t(vertex));
        for (size_t v = 0; v < vertex; ++v)
            for (int ch = 0; ch < 3; ++ch)
                EXPECT_NEAR(got.diffuse[v][ch], reference.diffuse[v][ch],
                            1e-5 * (1.0 + std::abs(reference.diffuse[v][ch])))
                    << "vertex " << v;
    }
}

TEST(RelightBlocked, MixedFileAndThreadIndependence) {
    // Blocked multiple scattering beside per-vertex isotropic single scattering and
    // per-vertex SS terms (and the other way round): the diffuse sum mixes both
    // encodings; all blocked, in one or two orders; a blocked diffuse component alone. The result does not depend on the number of threads, and an output
    // holding another result is overwritten everywhere.
    const uint32_t n = 16;
    const size_t keep = 128;
    const LightVector light = prt::makeLightVector(randomCubemap(int(n), 23));
    const TransportFile source = randomFile(n, 3001, {true, true, 4}, 24, 128);
    const auto isMs = [](const TransportComponent& c) { return c.kind == ComponentKind::MultipleScattering; };
    const TransportFile msBlocked = blockedCopy(source, keep, 25, isMs);
    const TransportFile ssBlocked = blockedCopy(source, keep, 26, [&](const TransportComponent& c) { return !isMs(c); });
    // Every component blocked in one order (MS and isotropic SS summed block by block in
    // one pass), and MS and isotropic SS blocked in different orders (one pass each).
    const TransportFile allBlocked = blockedCopy(source, keep, 27, everyComponent);
    const TransportFile twoOrders = blockedCopy(msBlocked, keep, 28, [](const TransportComponent& c) {
        return c.kind == ComponentKind::SingleScatteringIsotropic;
    });
    TransportFile msOnly = msBlocked;  // the only diffuse component is blocked: it stores
    msOnly.components.erase(std::remove_if(msOnly.components.begin(), msOnly.components.end(),
                                           [&](const TransportComponent& c) { return !isMs(c); }),
                            msOnly.components.end());
    msOnly.viewMaps.reset();
    int checked = 0;
    for (const TransportFile* file : std::vector<const TransportFile*>{&msBlocked, &ssBlocked, &allBlocked, &twoOrders, &msOnly}) {
        SCOPED_TRACE(checked++);
        ASSERT_TRUE(std::any_of(file->components.begin(), file->components.end(),
                                [](const TransportComponent& c) { return c.blocked(); }));
        for (const ScatteringComponents& set : kSets) {
            SCOPED_TRACE(setName(set));
            const Expected e = expectedRadiance(*file, light, set);
            VertexRadiance reference;
            prt::relightVerticesReference(*file, light, set, reference);
            expectMatches(reference, e, 1e-7, "reference");
            for (const prt::RelightOptions& options : variants()) {
                SCOPED_TRACE(variantName(options));
                VertexRadiance one, two, reused;
                tbb::task_arena(1).execute([&] { prt::relightVertices(*file, light, set, one, options); });
                tbb::task_arena(2).execute([&] { prt::relightVertices(*file, light, set, two, options); });
                reused.diffuse.assign(5000, glm::vec3(7.0f));
                reused.terms.assign(6, std::vector<glm::vec3>(5000, glm::vec3(-1.0f)));
                prt::relightVertices(*file, light, set, reused, options);
                expectMatches(one, e, blockedTolerance(keep), "fast");
                EXPECT_TRUE(bitwiseEqual(one, two));
                EXPECT_TRUE(bitwiseEqual(one, reused));
            }
        }
    }
}

TEST(RelightBlocked, CorruptInMemoryBlocksAreRefusedNotRead) {
    const uint32_t n = 4;
    const uint32_t count = 6 * n * n;
    const TransportFile good =
        blockedCopy(randomFile(n, 1000, {true, false, 0}, 31, 40), 32, 32, everyComponent);
    const LightVector light = prt::makeLightVector(randomCubemap(int(n), 33));
    VertexRadiance out;
    EXPECT_NO_THROW(prt::relightVertices(good, light, {true, true}, out));
    EXPECT_NO_THROW(prt::relightVerticesReference(good, light, {true, true}, out));
    const auto refused = [&](const TransportFile& file, const char* what) {
        SCOPED_TRACE(what);
        for (const prt::RelightOptions& options : variants())
            EXPECT_THROW(prt::relightVertices(file, light, {true, true}, out, options), prt::Error)
                << variantName(options);
        EXPECT_THROW(prt::relightVerticesReference(file, light, {true, true}, out), prt::Error);
        EXPECT_NO_THROW(prt::relightVertices(file, light, {false, true}, out));  // not selected
    };
    {
        TransportFile f = good;  // an index >= 6 N^2 at the end of a block
        prt::BlockedRgbVectors& b = f.components[0].blocks;
        size_t k = 40;
        while (b.offsets[k + 1] == b.offsets[k]) ++k;
        b.indices[b.offsets[k + 1] - 1] = uint16_t(count);
        refused(f, "index = 6 N^2");
        b.indices[b.offsets[k + 1] - 1] = uint16_t(65535);
        refused(f, "index 65535");
    }
    {
        TransportFile f = good;  // a vertex number past the vertex count, in the partial last block
        f.components[0].blocks.order.back() = 1000;
        refused(f, "order entry = V");
        f.components[0].blocks.order[5] = UINT32_MAX;
        refused(f, "order entry 2^32 - 1");
    }
    {
        TransportFile f = good;  // offsets out of order
        prt::BlockedRgbVectors& b = f.components[0].blocks;
        b.offsets[10] = b.offsets[11] + 1;
        refused(f, "decreasing offsets");
    }
    {
        TransportFile f = good;  // offsets past the index count (the last one too large)
        prt::BlockedRgbVectors& b = f.components[0].blocks;
        b.offsets[20] = uint32_t(b.indices.size()) + 100;
        refused(f, "offset past the indices");
    }
    const auto sizes = [&](const std::function<void(prt::BlockedRgbVectors&)>& corrupt, const char* what) {
        TransportFile f = good;
        corrupt(f.components[0].blocks);
        refused(f, what);
    };
    sizes([](prt::BlockedRgbVectors& b) { b.values.pop_back(); }, "values size");
    sizes([](prt::BlockedRgbVectors& b) { b.scales.resize(b.scales.size() - 48); }, "scales size");
    sizes([](prt::BlockedRgbVectors& b) { b.order.pop_back(); }, "order size");
    sizes([](prt::BlockedRgbVectors& b) { b.offsets.pop_back(); }, "offsets size");
    sizes([](prt::BlockedRgbVectors& b) { b.indices.push_back(0); }, "indices size");
    sizes([](prt::BlockedRgbVectors& b) { b.vertices += 16; }, "vertex count");
    {
        // A duplicated vertex in `order` stays in bounds: the fast path does not check the
        // permutation per call (relight_kernel.h), the reference does.
        TransportFile f = good;
        f.components[0].blocks.order[3] = f.components[0].blocks.order[4];
        EXPECT_NO_THROW(prt::relightVertices(f, light, {true, true}, out));
        EXPECT_THROW(prt::relightVerticesReference(f, light, {true, true}, out), prt::Error);
    }
    {
        // A blocked component whose vertex count differs from another component's.
        TransportFile f = blockedCopy(randomFile(n, 1000, {true, true, 0}, 34, 20), 16, 35, everyComponent);
        f.components[1] = blockedCopy(randomFile(n, 1001, {false, true, 0}, 36, 20), 16, 37,
                                      everyComponent).components[0];
        EXPECT_THROW(prt::relightVertices(f, light, {true, true}, out), prt::Error);
        EXPECT_THROW(prt::relightVerticesReference(f, light, {true, true}, out), prt::Error);
    }
}

TEST(RelightBlocked, StreamBytesCountTheBlockedArrays) {
    const TransportFile source = randomFile(4, 300, {true, true, 2}, 41, 30);
    const TransportFile file = blockedCopy(source, 24, 42, [](const TransportComponent& c) {
        return c.kind == ComponentKind::MultipleScattering;
    });
    size_t ms = 0, ss = 0;
    for (const TransportComponent& c : file.components) {
        if (c.kind == ComponentKind::MultipleScattering) {
            ASSERT_TRUE(c.blocked());
            // order (4 bytes per vertex), offsets, indices, values, scales (no SH scales here)
            ms += c.blocks.byteSize();
            EXPECT_EQ(c.blocks.byteSize(), 4 * 300 + 4 * (19 + 1) + 2 * c.blocks.indices.size() +
                                               48 * c.blocks.indices.size() + 4 * 48 * 19);
        } else {
            ASSERT_FALSE(c.blocked());
            ss += c.vectors.byteSize();
        }
    }
    EXPECT_EQ(prt::relightStreamBytes(file, {true, false}), ms);
    EXPECT_EQ(prt::relightStreamBytes(file, {false, true}), ss);
    EXPECT_EQ(prt::relightStreamBytes(file, {true, true}), ms + ss);
    // SH scales stream 48 floats more per block: one block of one vertex, two indices.
    prt::BlockedRgbVectors sh;
    sh.shFrom = 10;
    sh.appendBlock({1, 10}, std::vector<float>(6, 1.0f), {0});
    EXPECT_EQ(sh.byteSize(), 4 * 1 + 4 * 2 + 2 * 2 + 48 * 2 + 4 * 48 + 4 * 48);
}

}  // namespace
