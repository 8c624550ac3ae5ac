#include "common/haar.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <functional>
#include <string>

#include "common/error.h"

namespace prt {

namespace {

void checkFaceSize(int n) {
    if (!isPowerOfTwo(n)) {
        throw Error("haar", "face size " + std::to_string(n) + " is not a power of two >= 1");
    }
}

// Reusable per-thread scratch; grows, never shrinks, so steady-state calls do not allocate.
float* scratch(size_t floats) {
    thread_local std::vector<float> buffer;
    if (buffer.size() < floats) buffer.resize(floats);
    return buffer.data();
}

// Copies the top-left s x s block of `src` into `dst` (both with row stride n).
void copyBlock(const float* src, float* dst, int n, int s) {
    for (int j = 0; j < s; ++j) {
        std::memcpy(dst + size_t(j) * n, src + size_t(j) * n, sizeof(float) * size_t(s));
    }
}

// One level of the forward transform for the rows 2l, 2l+1 of a block: the 2 x 2 blocks
// (r0[2k], r0[2k+1]; r1[2k], r1[2k+1]) go to the four quadrant rows. The row and column
// steps are fused; both orthonormal 1/sqrt2 factors combine into 0.5. Separate restrict
// parameters let the compiler vectorise the loop (it does at -O3).
void forwardRowPair(const float* __restrict r0, const float* __restrict r1, float* __restrict ll,
                    float* __restrict hl, float* __restrict lh, float* __restrict hh, int h) {
    for (int k = 0; k < h; ++k) {
        const float a0 = r0[2 * k], b0 = r0[2 * k + 1];
        const float c0 = r1[2 * k], d0 = r1[2 * k + 1];
        const float top = a0 + b0, bottom = c0 + d0;
        const float topDiff = a0 - b0, bottomDiff = c0 - d0;
        ll[k] = 0.5f * (top + bottom);
        hl[k] = 0.5f * (topDiff + bottomDiff);
        lh[k] = 0.5f * (top - bottom);
        hh[k] = 0.5f * (topDiff - bottomDiff);
    }
}

// Exact inverse of forwardRowPair (the 2 x 2 step matrix is its own inverse).
void inverseRowPair(const float* __restrict ll, const float* __restrict hl,
                    const float* __restrict lh, const float* __restrict hh, float* __restrict r0,
                    float* __restrict r1, int h) {
    for (int k = 0; k < h; ++k) {
        const float p = ll[k] + lh[k], q = ll[k] - lh[k];  // 2 x (a+b), 2 x (c+d)
        const float u = hl[k] + hh[k], v = hl[k] - hh[k];  // 2 x (a-b), 2 x (c-d)
        r0[2 * k] = 0.5f * (p + u);
        r0[2 * k + 1] = 0.5f * (p - u);
        r1[2 * k] = 0.5f * (q + v);
        r1[2 * k + 1] = 0.5f * (q - v);
    }
}

// Forward transform of a contiguous n x n face `a` (row stride n); `tmp` holds n * n
// floats. Each level writes the s x s block to tmp in quadrant layout and copies it back.
void forwardContiguous(float* a, int n, float* tmp) {
    for (int s = n; s >= 2; s /= 2) {
        const int h = s / 2;
        for (int l = 0; l < h; ++l) {
            const float* r0 = a + size_t(2 * l) * n;
            float* top = tmp + size_t(l) * n;
            float* bottom = tmp + size_t(h + l) * n;
            forwardRowPair(r0, r0 + n, top, top + h, bottom, bottom + h, h);
        }
        copyBlock(tmp, a, n, s);
    }
}

void inverseContiguous(float* a, int n, float* tmp) {
    for (int s = 2; s <= n; s *= 2) {
        const int h = s / 2;
        for (int l = 0; l < h; ++l) {
            const float* top = a + size_t(l) * n;
            const float* bottom = a + size_t(h + l) * n;
            float* r0 = tmp + size_t(2 * l) * n;
            inverseRowPair(top, top + h, bottom, bottom + h, r0, r0 + n, h);
        }
        copyBlock(tmp, a, n, s);
    }
}

template <bool Forward>
void transformFace(float* face, int n, int stride) {
    checkFaceSize(n);
    if (stride < 1) throw Error("haar", "stride must be >= 1");
    if (n == 1) return;
    const size_t nn = size_t(n) * n;
    if (stride == 1) {
        float* tmp = scratch(nn);
        if constexpr (Forward) forwardContiguous(face, n, tmp);
        else inverseContiguous(face, n, tmp);
        return;
    }
    float* buf = scratch(2 * nn);
    float* tmp = buf + nn;
    for (size_t t = 0; t < nn; ++t) buf[t] = face[t * stride];
    if constexpr (Forward) forwardContiguous(buf, n, tmp);
    else inverseContiguous(buf, n, tmp);
    for (size_t t = 0; t < nn; ++t) face[t * stride] = buf[t];
}

template <bool Forward>
void transformCubemap(Cubemap& map) {
    const int n = map.size();
    const int channels = map.channels();
    if (n == 0) return;  // default-constructed, empty
    float* data = map.data().data();
    const size_t nn = size_t(n) * n;
    for (int f = 0; f < kCubeFaces; ++f) {
        float* face = data + size_t(f) * nn * channels;
        for (int c = 0; c < channels; ++c) transformFace<Forward>(face + c, n, channels);
    }
}

void checkReferenceArgs(const double* in, const double* out, int n) {
    checkFaceSize(n);
    const uintptr_t bytes = uintptr_t(size_t(n) * n * sizeof(double));
    const uintptr_t x = reinterpret_cast<uintptr_t>(in), y = reinterpret_cast<uintptr_t>(out);
    if (x < y + bytes && y < x + bytes) throw Error("haar", "reference transform: in and out alias");
}

}  // namespace

void haarForwardFace(float* face, int n, int stride) { transformFace<true>(face, n, stride); }
void haarInverseFace(float* face, int n, int stride) { transformFace<false>(face, n, stride); }

void haarForward(Cubemap& map) { transformCubemap<true>(map); }
void haarInverse(Cubemap& map) { transformCubemap<false>(map); }

double haarBasis(int n, int ci, int cj, int i, int j) {
    checkFaceSize(n);
    if (ci < 0 || cj < 0 || ci >= n || cj >= n || i < 0 || j < 0 || i >= n || j >= n) {
        throw Error("haar", "haarBasis: index out of range");
    }
    if (ci == 0 && cj == 0) return 1.0 / n;
    const int m = std::max(ci, cj);
    int h = 1;
    while (h * 2 <= m) h *= 2;
    const int w = n / h;          // side of the support in texels
    const int k = ci % h, l = cj % h;
    const int x = i - k * w, y = j - l * w;  // position inside the support
    if (x < 0 || y < 0 || x >= w || y >= w) return 0.0;
    const bool right = x >= w / 2, bottom = y >= w / 2;
    bool negative = false;
    if (ci >= h) negative = negative != right;   // detail along i
    if (cj >= h) negative = negative != bottom;  // detail along j
    return (negative ? -1.0 : 1.0) / w;
}

void haarForwardFaceReference(const double* in, double* out, int n) {
    checkReferenceArgs(in, out, n);
    for (int cj = 0; cj < n; ++cj) {
        for (int ci = 0; ci < n; ++ci) {
            double sum = 0.0;
            for (int j = 0; j < n; ++j) {
                for (int i = 0; i < n; ++i) sum += haarBasis(n, ci, cj, i, j) * in[size_t(j) * n + i];
            }
            out[size_t(cj) * n + ci] = sum;
        }
    }
}

void haarInverseFaceReference(const double* in, double* out, int n) {
    checkReferenceArgs(in, out, n);
    for (int j = 0; j < n; ++j) {
        for (int i = 0; i < n; ++i) {
            double sum = 0.0;
            for (int cj = 0; cj < n; ++cj) {
                for (int ci = 0; ci < n; ++ci) sum += in[size_t(cj) * n + ci] * haarBasis(n, ci, cj, i, j);
            }
            out[size_t(j) * n + i] = sum;
        }
    }
}

// ---------------------------------------------------------------------------------

namespace {

void checkChannels(int channels, const char* what) {
    if (channels < 1) throw Error("haar", std::string(what) + ": channels must be >= 1");
}

void checkConsistent(const SparseVector& a, const char* what) {
    checkChannels(a.channels, what);
    if (a.value.size() != a.index.size() * size_t(a.channels)) {
        throw Error("haar", std::string(what) + ": sparse vector has " +
                                std::to_string(a.value.size()) + " values for " +
                                std::to_string(a.index.size()) + " indices of " +
                                std::to_string(a.channels) + " channels");
    }
}

struct Candidate {
    double key;
    uint32_t index;
};

}  // namespace

namespace {

// An entry's squared norm over its channels, the truncation's key: in channel order up
// to four channels; beyond, in four interleaved partial sums (channel c in sum c mod 4,
// added as (s0 + s1) + (s2 + s3)), so that a long chain of dependent additions does not
// set the pace. truncateLargest and its reference share it.
inline double squaredNorm(const float* v, int channels) {
    if (channels <= 4) {
        double e = 0.0;
        for (int c = 0; c < channels; ++c) e += double(v[c]) * double(v[c]);
        return e;
    }
    double s[4] = {0.0, 0.0, 0.0, 0.0};
    int c = 0;
    for (; c + 4 <= channels; c += 4)
        for (int q = 0; q < 4; ++q) s[q] += double(v[c + q]) * double(v[c + q]);
    for (int q = 0; c < channels; ++c, ++q) s[q] += double(v[c]) * double(v[c]);
    return (s[0] + s[1]) + (s[2] + s[3]);
}

}  // namespace

namespace {

// e when e > 0, else 0 (NaN included), without a branch: zero entries come at random,
// and a compiler's `e > 0 ? e : 0` is a jump mispredicted about as often.
inline double positiveOrZero(double e) {
    const uint64_t keep = uint64_t(0) - uint64_t(e > 0.0);
    return std::bit_cast<double>(std::bit_cast<uint64_t>(e) & keep);
}

// keys[idx] = squaredNorm of entry idx (0 unless > 0: also for NaN), for C channels
// known at compile time; the same sums in the same order as squaredNorm.
template <int C>
void keysOf(const float* dense, size_t count, double* keys) {
    for (size_t idx = 0; idx < count; ++idx) {
        const float* v = dense + idx * C;
        double e = 0.0;
        for (int c = 0; c < C; ++c) e += double(v[c]) * double(v[c]);
        keys[idx] = positiveOrZero(e);
    }
}
// Any channel count, the key then adjusted by adjust(idx, squaredNorm).
template <typename Adjust>
void keysOf(const float* dense, size_t count, int channels, double* keys, Adjust&& adjust) {
    for (size_t idx = 0; idx < count; ++idx) {
        const double e = adjust(idx, squaredNorm(dense + idx * size_t(channels), channels));
        keys[idx] = positiveOrZero(e);
    }
}

}  // namespace

SparseVector truncateLargest(const float* dense, size_t count, int channels, size_t keep,
                             const float* weights) {
    checkChannels(channels, "truncateLargest");
    if (count > size_t(UINT32_MAX) + 1) throw Error("haar", "truncateLargest: too many entries");
    SparseVector result;
    result.channels = channels;
    if (keep == 0 || count == 0) return result;

    // Keys per entry (0 for the never-kept: zero or NaN), and the positive ones apart.
    thread_local std::vector<double> keys, positive;
    keys.resize(count);
    // The keys first, then the positive ones: loops free of calls and branches let
    // consecutive entries' sums overlap (one entry's channels are a chain of dependent
    // additions) and vectorise; zeros come at random, so a branch per entry would be
    // mispredicted often.
    if (weights)
        keysOf(dense, count, channels, keys.data(), [&](size_t idx, double e) {
            // ||v|| * w orders the same as ||v||^2 * w^2 for w >= 0; no square root needed.
            return e * (double(weights[idx]) * double(weights[idx]));
        });
    else if (channels == 3)
        keysOf<3>(dense, count, keys.data());
    else if (channels == 1)
        keysOf<1>(dense, count, keys.data());
    else
        keysOf(dense, count, channels, keys.data(), [](size_t, double e) { return e; });
    positive.resize(count);
    size_t positives = 0;
    for (size_t idx = 0; idx < count; ++idx) {
        positive[positives] = keys[idx];
        positives += keys[idx] > 0.0;
    }
    positive.resize(positives);
    // The keep-th largest key is the threshold: every larger key is kept, and as many
    // keys equal to it as there is room for, lowest index first (the reference's
    // tie-break); one scan in index order then gives the sorted result.
    double threshold = 0.0;  // keep every positive key
    size_t ties = count;
    if (positive.size() > keep) {
        std::nth_element(positive.begin(), positive.begin() + std::ptrdiff_t(keep - 1), positive.end(),
                         std::greater<double>());
        threshold = positive[keep - 1];
        size_t above = 0;
        for (double k : positive) above += k > threshold;
        ties = keep - above;
    }
    result.index.reserve(std::min(keep, positive.size()));
    result.value.reserve(std::min(keep, positive.size()) * size_t(channels));
    for (size_t idx = 0; idx < count; ++idx) {
        const double k = keys[idx];
        // Below the threshold first: with one (> 0) that rejects the zeros too, and
        // most entries, predictably.
        if (k < threshold || !(k > 0.0)) continue;
        if (k == threshold) {
            if (ties == 0) continue;
            --ties;
        }
        result.index.push_back(uint32_t(idx));
        result.value.insert(result.value.end(), dense + idx * channels, dense + (idx + 1) * channels);
    }
    return result;
}

SparseVector truncateLargestReference(const float* dense, size_t count, int channels, size_t keep,
                             const float* weights) {
    checkChannels(channels, "truncateLargestReference");
    if (count > size_t(UINT32_MAX) + 1) throw Error("haar", "truncateLargestReference: too many entries");
    SparseVector result;
    result.channels = channels;
    if (keep == 0 || count == 0) return result;

    thread_local std::vector<Candidate> candidates;
    candidates.clear();
    candidates.reserve(count);
    for (size_t idx = 0; idx < count; ++idx) {
        const float* v = dense + idx * channels;
        double e = squaredNorm(v, channels);
        // ||v|| * w orders the same as ||v||^2 * w^2 for w >= 0; no square root needed.
        if (weights) e *= double(weights[idx]) * double(weights[idx]);
        if (e > 0.0) candidates.push_back({e, uint32_t(idx)});  // also drops NaN keys
    }
    if (candidates.size() > keep) {
        const auto larger = [](const Candidate& x, const Candidate& y) {
            return x.key > y.key || (x.key == y.key && x.index < y.index);
        };
        std::nth_element(candidates.begin(), candidates.begin() + std::ptrdiff_t(keep),
                         candidates.end(), larger);
        candidates.resize(keep);
        std::sort(candidates.begin(), candidates.end(),
                  [](const Candidate& x, const Candidate& y) { return x.index < y.index; });
    }
    // Otherwise every candidate is kept and they are already in index order.

    result.index.resize(candidates.size());
    result.value.resize(candidates.size() * channels);
    for (size_t e = 0; e < candidates.size(); ++e) {
        const uint32_t idx = candidates[e].index;
        result.index[e] = idx;
        std::copy_n(dense + size_t(idx) * channels, channels, result.value.begin() + e * channels);
    }
    return result;
}

SparseVector toSparse(const float* dense, size_t count, int channels) {
    checkChannels(channels, "toSparse");
    if (count > size_t(UINT32_MAX) + 1) throw Error("haar", "toSparse: too many entries");
    SparseVector result;
    result.channels = channels;
    for (size_t idx = 0; idx < count; ++idx) {
        const float* v = dense + idx * channels;
        bool nonZero = false;
        for (int c = 0; c < channels; ++c) nonZero = nonZero || v[c] != 0.0f;
        if (!nonZero) continue;
        result.index.push_back(uint32_t(idx));
        result.value.insert(result.value.end(), v, v + channels);
    }
    return result;
}

void addTo(const SparseVector& a, float scale, float* dense) {
    checkConsistent(a, "addTo");
    const size_t channels = size_t(a.channels);
    if (channels == 1) {
        for (size_t e = 0; e < a.index.size(); ++e) dense[a.index[e]] += scale * a.value[e];
        return;
    }
    for (size_t e = 0; e < a.index.size(); ++e) {
        float* d = dense + size_t(a.index[e]) * channels;
        const float* v = a.value.data() + e * channels;
        for (size_t c = 0; c < channels; ++c) d[c] += scale * v[c];
    }
}

float dot(const SparseVector& a, const float* dense) {
    checkConsistent(a, "dot");
    if (a.channels != 1) throw Error("haar", "dot: sparse vector must have one channel (use dotPerChannel)");
    float sum = 0.0f;
    for (size_t e = 0; e < a.index.size(); ++e) sum += a.value[e] * dense[a.index[e]];
    return sum;
}

void dotPerChannel(const SparseVector& a, const float* dense, int denseChannels, float* out) {
    checkConsistent(a, "dotPerChannel");
    checkChannels(denseChannels, "dotPerChannel");
    const int sc = a.channels;
    const int dc = denseChannels;
    if (sc != dc && sc != 1 && dc != 1) {
        throw Error("haar", "dotPerChannel: " + std::to_string(sc) + " sparse channels do not match " +
                                std::to_string(dc) + " dense channels");
    }
    const int oc = std::max(sc, dc);
    for (int c = 0; c < oc; ++c) out[c] = 0.0f;
    const size_t m = a.index.size();
    const float* v = a.value.data();
    if (sc == dc) {
        for (size_t e = 0; e < m; ++e) {
            const float* d = dense + size_t(a.index[e]) * dc;
            for (int c = 0; c < oc; ++c) out[c] += v[e * sc + c] * d[c];
        }
    } else if (dc == 1) {
        for (size_t e = 0; e < m; ++e) {
            const float d = dense[a.index[e]];
            for (int c = 0; c < oc; ++c) out[c] += v[e * sc + c] * d;
        }
    } else {  // sc == 1
        for (size_t e = 0; e < m; ++e) {
            const float* d = dense + size_t(a.index[e]) * dc;
            for (int c = 0; c < oc; ++c) out[c] += v[e] * d[c];
        }
    }
}

void dotRGB(const SparseVector& a, const float* dense, int denseChannels, float out[3]) {
    if (std::max(a.channels, denseChannels) != 3) {
        throw Error("haar", "dotRGB: the result must have 3 channels (sparse " +
                                std::to_string(a.channels) + ", dense " +
                                std::to_string(denseChannels) + ")");
    }
    dotPerChannel(a, dense, denseChannels, out);
}

double dot(const SparseVector& a, const SparseVector& b) {
    checkConsistent(a, "dot");
    checkConsistent(b, "dot");
    if (a.channels != b.channels) throw Error("haar", "dot: sparse vectors have different channel counts");
    const size_t channels = size_t(a.channels);
    double sum = 0.0;
    size_t x = 0, y = 0;
    while (x < a.index.size() && y < b.index.size()) {
        if (a.index[x] < b.index[y]) {
            ++x;
        } else if (b.index[y] < a.index[x]) {
            ++y;
        } else {
            for (size_t c = 0; c < channels; ++c) {
                sum += double(a.value[x * channels + c]) * double(b.value[y * channels + c]);
            }
            ++x;
            ++y;
        }
    }
    return sum;
}

double energy(const SparseVector& a) { return energy(a.value.data(), a.value.size()); }

double energy(const float* values, size_t count) {
    // Four partial sums, so consecutive additions do not wait on each other.
    double s[4] = {0.0, 0.0, 0.0, 0.0};
    size_t t = 0;
    for (; t + 4 <= count; t += 4)
        for (int q = 0; q < 4; ++q) s[q] += double(values[t + size_t(q)]) * double(values[t + size_t(q)]);
    for (int q = 0; t < count; ++t, ++q) s[q] += double(values[t]) * double(values[t]);
    return (s[0] + s[1]) + (s[2] + s[3]);
}

}  // namespace prt
