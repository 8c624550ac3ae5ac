#include "common/sh_part.h"

#include "common/cubemap.h"
#include "common/error.h"

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <utility>

namespace prt {


void shBasis(const glm::dvec3& d, int terms, double* y) {
    // Real SH, bands 0..4 (Sloan, "Stupid Spherical Harmonics Tricks", Appendix A2;
    // bands 3 and 4 in the same convention, z the polar axis).
    const double x = d.x, yy = d.y, z = d.z;
    const double x2 = x * x, y2 = yy * yy, z2 = z * z;
    const double all[kMaxShTerms] = {
        0.28209479177387814,                  // 1 / (2 sqrt(pi))
        0.48860251190291992 * yy,             // sqrt(3 / (4 pi))
        0.48860251190291992 * z,
        0.48860251190291992 * x,
        1.0925484305920792 * x * yy,          // sqrt(15 / pi) / 2
        1.0925484305920792 * yy * z,
        0.31539156525252005 * (3.0 * z * z - 1.0),  // sqrt(5 / pi) / 4
        1.0925484305920792 * x * z,
        0.54627421529603959 * (x * x - yy * yy),    // sqrt(15 / pi) / 4
        0.59004358992664352 * yy * (3.0 * x2 - y2),  // sqrt(35 / (2 pi)) / 4
        2.8906114426405538 * x * yy * z,             // sqrt(105 / pi) / 2
        0.45704579946446572 * yy * (5.0 * z2 - 1.0), // sqrt(21 / (2 pi)) / 4
        0.37317633259011540 * z * (5.0 * z2 - 3.0),  // sqrt(7 / pi) / 4
        0.45704579946446572 * x * (5.0 * z2 - 1.0),
        1.4453057213202769 * z * (x2 - y2),          // sqrt(105 / pi) / 4
        0.59004358992664352 * x * (x2 - 3.0 * y2),
        2.5033429417967046 * x * yy * (x2 - y2),     // 3 sqrt(35 / pi) / 4
        1.7701307697799304 * yy * z * (3.0 * x2 - y2),  // 3 sqrt(35 / (2 pi)) / 4
        0.94617469575756008 * x * yy * (7.0 * z2 - 1.0),  // 3 sqrt(5 / pi) / 4
        0.66904654355728917 * yy * z * (7.0 * z2 - 3.0),  // 3 sqrt(5 / (2 pi)) / 4
        0.10578554691520431 * (35.0 * z2 * z2 - 30.0 * z2 + 3.0),  // 3 / (16 sqrt(pi))
        0.66904654355728917 * x * z * (7.0 * z2 - 3.0),
        0.47308734787878004 * (x2 - y2) * (7.0 * z2 - 1.0),  // 3 sqrt(5 / pi) / 8
        1.7701307697799304 * x * z * (x2 - 3.0 * y2),
        0.62583573544917614 * (x2 * (x2 - 3.0 * y2) - y2 * (3.0 * x2 - y2)),  // 3 sqrt(35 / pi) / 16
    };
    for (int i = 0; i < terms; ++i) y[i] = all[i];
}

namespace {

// sum_e a[e] b[e] in 16 float partial sums (independent lanes, so the compiler
// vectorizes it without reassociating), added up in double.
double blockedDot(const float* a, const float* b, size_t n) {
    constexpr size_t kLanes = 16;
    float lane[kLanes] = {};
    size_t e = 0;
    for (; e + kLanes <= n; e += kLanes)
        for (size_t j = 0; j < kLanes; ++j) lane[j] += a[e + j] * b[e + j];
    double s = 0.0;
    for (size_t j = 0; j < kLanes; ++j) s += double(lane[j]);
    for (; e < n; ++e) s += double(a[e]) * double(b[e]);
    return s;
}

// planes[k * n + e] -= d[k] row[e] for the channels k < ch (ch <= 4): one pass over
// the row for all channels. Applied term by term, in term order, it gives per element
// and channel the sequence of subtractions of one channel at a time.
void subtractRow(float* planes, size_t n, size_t ch, const float* row, const float* d) {
    switch (ch) {
        case 3: {
            float *p0 = planes, *p1 = planes + n, *p2 = planes + 2 * n;
            const float d0 = d[0], d1 = d[1], d2 = d[2];
            for (size_t e = 0; e < n; ++e) {
                p0[e] -= d0 * row[e];
                p1[e] -= d1 * row[e];
                p2[e] -= d2 * row[e];
            }
            return;
        }
        default:
            for (size_t k = 0; k < ch; ++k) {
                float* p = planes + k * n;
                const float dk = d[k];
                for (size_t e = 0; e < n; ++e) p[e] -= dk * row[e];
            }
    }
}

// Row k of the (count x terms) channel-interleaved cubemap, Haar-transformed, as
// `terms` rows of `count` floats.
std::vector<float> haarRows(Cubemap map) {
    haarForward(map);
    const size_t count = map.texelCount(), terms = size_t(map.channels());
    std::vector<float> rows(count * terms);
    for (size_t e = 0; e < count; ++e)
        for (size_t k = 0; k < terms; ++k) rows[k * count + e] = map.data()[e * terms + k];
    return rows;
}

std::unique_ptr<ShTables> buildTables(int n, int terms) {
    auto t = std::make_unique<ShTables>();
    t->size = n;
    t->terms = terms;
    const size_t count = t->coefficientCount();
    const auto dependent = [&] {
        return Error("sh part", std::to_string(terms) + " SH terms are not independent on a 6 x " +
                                    std::to_string(n) + " x " + std::to_string(n) +
                                    " cubemap (use fewer terms or a larger cubemap)");
    };
    Cubemap w(n, terms), v(n, terms);  // channel k: W_k = dOmega Y_k, V_k = Y_k at the texels
    double y[kMaxShTerms];
    for (int f = 0; f < kCubeFaces; ++f)
        for (int j = 0; j < n; ++j)
            for (int i = 0; i < n; ++i) {
                shBasis(texelDirection(n, f, i, j), terms, y);
                const double dOmega = texelSolidAngle(n, i, j);
                for (int k = 0; k < terms; ++k) {
                    w.texel(f, i, j)[k] = float(dOmega * y[k]);
                    v.texel(f, i, j)[k] = float(y[k]);
                }
            }
    t->weightedHaar = haarRows(std::move(w));
    const std::vector<float> vHaar = haarRows(std::move(v));
    // Each W^_i scaled to unit texel norm, so SH coefficients are on the scale of the
    // Haar coefficients beside them (one quantization scale serves both).
    for (int k = 0; k < terms; ++k) {
        float* row = &t->weightedHaar[size_t(k) * count];
        double norm = 0.0;
        for (size_t e = 0; e < count; ++e) norm += double(row[e]) * double(row[e]);
        norm = std::sqrt(norm);
        if (!(norm > 0.0)) throw dependent();  // Y_k vanishes at every texel centre
        for (size_t e = 0; e < count; ++e) row[e] = float(double(row[e]) / norm);
    }
    t->weightedGram.assign(size_t(terms) * size_t(terms), 0.0);
    for (int a = 0; a < terms; ++a)
        for (int b = 0; b < terms; ++b) {
            double s = 0.0;
            for (size_t e = 0; e < count; ++e)
                s += double(t->weightedHaar[size_t(a) * count + e]) * double(t->weightedHaar[size_t(b) * count + e]);
            t->weightedGram[size_t(a) * size_t(terms) + size_t(b)] = s;
        }
    // G = V^T W; P = G^-1 V^T, so P W = I and V^T (T - W P T) = 0.
    Eigen::MatrixXd g(terms, terms);
    for (int a = 0; a < terms; ++a)
        for (int b = 0; b < terms; ++b) {
            double s = 0.0;
            const float* va = &vHaar[size_t(a) * count];
            const float* wb = &t->weightedHaar[size_t(b) * count];
            for (size_t e = 0; e < count; ++e) s += double(va[e]) * double(wb[e]);
            g(a, b) = s;
        }
    // On a cubemap with too few texels (N = 1: 6 for 9 functions) the functions are
    // not independent and G is singular.
    const Eigen::JacobiSVD<Eigen::MatrixXd> svd(g);
    const Eigen::VectorXd sv = svd.singularValues();
    if (!g.allFinite() || !(sv(terms - 1) > 1e-6 * sv(0))) throw dependent();
    const Eigen::MatrixXd inverse = g.fullPivLu().inverse();
    t->projection.assign(count * size_t(terms), 0.0f);
    for (int a = 0; a < terms; ++a)
        for (size_t e = 0; e < count; ++e) {
            double s = 0.0;
            for (int b = 0; b < terms; ++b) s += inverse(a, b) * double(vHaar[size_t(b) * count + e]);
            t->projection[size_t(a) * count + e] = float(s);
        }
    return t;
}

}  // namespace

const ShTables& shTables(int n, int terms) {
    if (!validShTerms(terms) || terms == 0)
        throw Error("sh part", "SH term count " + std::to_string(terms) + " is not 1, 4, 9, 16 or 25");
    if (n < 1 || n > 64 || !isPowerOfTwo(n))
        throw Error("sh part", "cubemap size " + std::to_string(n) + " is not a power of two in 1..64");
    // The last table this thread used, without the lock (tables live as long as the
    // process and never move).
    thread_local const ShTables* last = nullptr;
    if (last && last->size == n && last->terms == terms) return *last;
    static std::mutex mutex;
    static std::map<std::pair<int, int>, std::unique_ptr<ShTables>> cache;
    const std::lock_guard<std::mutex> lock(mutex);
    std::unique_ptr<ShTables>& slot = cache[{n, terms}];
    if (!slot) slot = buildTables(n, terms);
    last = slot.get();
    return *slot;
}

SparseVector truncateWithShPart(float* dense, size_t count, int channels, int terms, size_t keep,
                                double* retained) {
    if (!validShTerms(terms))
        throw Error("sh part", "SH term count " + std::to_string(terms) + " is not " + kShTermCounts);
    if (keep <= size_t(terms))
        throw Error("sh part", "keeping " + std::to_string(keep) + " terms leaves no room beside " +
                                   std::to_string(terms) + " SH terms");
    const size_t ch = size_t(channels);
    if (terms == 0) {
        const double before = energy(dense, count * ch);
        SparseVector kept = truncateLargest(dense, count, channels, keep);
        if (retained) *retained = before > 0.0 ? energy(kept) / before : 1.0;
        return kept;
    }
    const int n = int(std::lround(std::sqrt(double(count) / 6.0)));
    if (size_t(6) * size_t(n) * size_t(n) != count)
        throw Error("sh part", std::to_string(count) + " Haar entries are not a 6 x N x N cubemap");
    const ShTables& t = shTables(n, terms);
    if (channels < 1 || channels > kMaxShChannels)
        throw Error("sh part", "1 to " + std::to_string(kMaxShChannels) + " channels, got " + std::to_string(channels));
    // Channel planes, so every product below runs over contiguous floats.
    thread_local std::vector<float> planes;
    planes.resize(count * ch);
    for (size_t e = 0; e < count; ++e)
        for (size_t k = 0; k < ch; ++k) planes[k * count + e] = dense[e * ch + k];
    // d = P T^ (the fit of the Haar entries); the carried part s adds to it unchanged
    // (P W = I), and the residual of the whole vector T^ + W s is T^ - W d.
    float* carried = dense + count * ch;
    double c[kMaxShTerms * kMaxShChannels] = {};
    double d[kMaxShTerms * kMaxShChannels] = {};
    // Term-major, so each table row is read once for all channels (it stays in L1
    // while the channels' planes pass by); per channel the sums are those of a
    // channel-major loop, bit for bit.
    for (int i = 0; i < terms; ++i)
        for (size_t k = 0; k < ch; ++k) {
            d[size_t(i) * ch + k] = blockedDot(&t.projection[size_t(i) * count], &planes[k * count], count);
            c[size_t(i) * ch + k] = d[size_t(i) * ch + k] + double(carried[size_t(i) * ch + k]);
        }
    for (int i = 0; i < terms; ++i) {
        float di[kMaxShChannels];
        for (size_t k = 0; k < ch; ++k) di[k] = float(d[size_t(i) * ch + k]);
        subtractRow(planes.data(), count, ch, &t.weightedHaar[size_t(i) * count], di);
    }
    std::fill(carried, carried + size_t(terms) * ch, 0.0f);
    double residual = 0.0;
    for (size_t k = 0; k < ch; ++k) residual += blockedDot(&planes[k * count], &planes[k * count], count);
    double shEnergy = 0.0;  // ||W c||^2 = c^T (W^T W) c per channel
    for (size_t k = 0; k < ch; ++k)
        for (int a = 0; a < terms; ++a)
            for (int b = 0; b < terms; ++b)
                shEnergy += c[size_t(a) * ch + k] * t.weightedGram[size_t(a) * size_t(terms) + size_t(b)] *
                            c[size_t(b) * ch + k];
    for (size_t e = 0; e < count; ++e)
        for (size_t k = 0; k < ch; ++k) dense[e * ch + k] = planes[k * count + e];
    SparseVector out = truncateLargest(dense, count, channels, keep - size_t(terms));
    // What is dropped is the residual's dropped entries (the SH part is kept whole).
    const double whole = residual + shEnergy;
    if (retained) *retained = whole > 0.0 ? 1.0 - std::max(0.0, residual - energy(out)) / whole : 1.0;
    for (int i = 0; i < terms; ++i) {
        out.index.push_back(uint32_t(count + size_t(i)));
        for (size_t k = 0; k < ch; ++k) out.value.push_back(float(c[size_t(i) * ch + k]));
    }
    return out;
}

void shProjectLight(const float* haar, int n, int channels, int terms, float* out) {
    if (terms == 0) return;
    if (channels < 1 || channels > 4) throw Error("sh part", "1 to 4 channels");
    const ShTables& t = shTables(n, terms);
    const size_t count = t.coefficientCount();
    const size_t ch = size_t(channels);
    thread_local std::vector<float> plane;
    plane.resize(count);
    for (size_t k = 0; k < ch; ++k) {
        for (size_t e = 0; e < count; ++e) plane[e] = haar[ch * e + k];
        for (int i = 0; i < terms; ++i)
            out[ch * size_t(i) + k] = float(blockedDot(&t.weightedHaar[size_t(i) * count], plane.data(), count));
    }
}

}  // namespace prt
