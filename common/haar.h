#pragma once
// Haar wavelets on the cubemap and sparse coefficient vectors (Ng et al. 2003,
// Wang et al. 2005).
//
// TRANSFORM. Each N x N face (N a power of two) is transformed on its own with the
// 2D *nonstandard* orthonormal Haar decomposition (Stollnitz, DeRose, Salesin):
// at each level the current top-left s x s block (s = N, N/2, ..., 2) gets one step
// of the 1D orthonormal Haar transform, (a + b)/sqrt2 and (a - b)/sqrt2, along every
// row and then along every column; the recursion continues on the s/2 x s/2 block of
// averages only. One level therefore maps each 2 x 2 block of texels
//     a = (2k, 2l)    b = (2k+1, 2l)        (i, j) = (column, row)
//     c = (2k, 2l+1)  d = (2k+1, 2l+1)
// to four coefficients (h = s/2):
//     (k,     l    ) = (a + b + c + d) / 2   averages (recursed on)
//     (h + k, l    ) = (a - b + c - d) / 2   detail along i (left minus right)
//     (k,     h + l) = (a + b - c - d) / 2   detail along j (top row minus bottom row)
//     (h + k, h + l) = (a - b - c + d) / 2   diagonal detail
// The result is stored in place in the pyramid layout: texel (0, 0) of a face holds
// the face's scaling coefficient, sum of the face's texels / N, and the three detail
// quadrants of the level with half-size h sit at columns/rows [h, 2h).
//
// Basis functions (what haarBasis evaluates): the coefficient at (ci, cj) with
// h = the largest power of two <= max(ci, cj) (h >= 1), k = ci mod h, l = cj mod h,
// is supported on the w x w texel square, w = N / h, with corner (k w, l w), where it
// is +-1/w: the sign is - on the right half (i-detail), the bottom half (j-detail) or
// exactly one of them (diagonal). (0, 0) is the constant 1/N. These N^2 functions
// are orthonormal in the plain texel inner product (sum over texels, no solid-angle
// weights), so the transform preserves sums of squares and dot products (Parseval).
//
// COEFFICIENT INDEX. Coefficient k of a cubemap with N x N faces is stored in the
// in-place layout at the texel with the same flat index, k = face * N * N + j * N + i
// (Cubemap::texelIndex). Sparse vectors use this index. The face's scaling
// coefficient is index face * N * N.
//
// All functions act on every channel independently.

#include "common/cubemap.h"

#include <cstddef>
#include <cstdint>
#include <vector>

namespace prt {

// ---------------------------------------------------------------------------------
// Per-face transforms on raw arrays. Element (i, j) of the face is face[(j*n + i) *
// stride]: stride = channels transforms one channel of a channel-interleaved face.
// n must be a power of two >= 1 (else prt::Error). No heap allocation after the first
// call on a thread for a given n (a thread-local scratch buffer is reused).
void haarForwardFace(float* face, int n, int stride = 1);
void haarInverseFace(float* face, int n, int stride = 1);

// Whole cubemaps: every channel of all 6 faces, in place.
void haarForward(Cubemap& map);
void haarInverse(Cubemap& map);

// Slow, obvious reference versions for tests: explicit basis functions, double
// precision, O(n^4). `in` and `out` are contiguous n x n arrays [j][i] and must not
// alias. Forward: out[c] = sum_t basis_c(t) in[t]; inverse: out[t] = sum_c in[c]
// basis_c(t).
double haarBasis(int n, int ci, int cj, int i, int j);
void haarForwardFaceReference(const double* in, double* out, int n);
void haarInverseFaceReference(const double* in, double* out, int n);

// ---------------------------------------------------------------------------------
// Sparse coefficient vectors.
struct SparseVector {
    int channels = 1;
    std::vector<uint32_t> index;  // strictly increasing flat coefficient indices
    std::vector<float> value;     // index.size() * channels values, channel-interleaved
    size_t size() const { return index.size(); }  // number of stored entries
    bool empty() const { return index.empty(); }
};

// Non-linear approximation: keeps the `keep` entries of largest magnitude from the dense
// vector `dense` of `count` entries of `channels` floats each (count * channels floats).
// The magnitude of entry idx is its Euclidean norm over the channels, ||v_idx||
// (|v_idx| for one channel), multiplied by weights[idx] when weights is given (e.g.
// the solid angle or area of a coefficient's support; weights must be >= 0).
// Ties are broken by lower index. Entries of zero magnitude (all channels zero, or
// weight zero) are never kept, so keep >= the number of such non-zeros keeps them all.
// O(count): the keep-th largest magnitude by selection (nth_element over the keys
// alone), then one scan in index order, so the kept indices come out ascending.
// Kept values are the original, unweighted values.
SparseVector truncateLargest(const float* dense, size_t count, int channels, size_t keep,
                             const float* weights = nullptr);
// The same by selecting (key, index) pairs and sorting the kept ones by index: the
// slower form truncateLargest is tested against (identical results).
SparseVector truncateLargestReference(const float* dense, size_t count, int channels, size_t keep,
                                      const float* weights = nullptr);

// All entries with at least one non-zero channel.
SparseVector toSparse(const float* dense, size_t count, int channels);

// dense[idx * a.channels + c] += scale * value (dense has a.channels floats per entry).
void addTo(const SparseVector& a, float scale, float* dense);

// Sum over stored entries of a.value * dense[idx]. Requires a.channels == 1.
float dot(const SparseVector& a, const float* dense);

// Per-channel dot product of a sparse vector with a dense one of `denseChannels`
// floats per entry. The result has max(a.channels, denseChannels) channels written to
// out[]; a.channels and denseChannels must be equal or one of them 1 (that side is
// broadcast over the other's channels):
//   equal:           out[c] = sum a[idx][c] * dense[idx][c]   (RGB transport . RGB light)
//   denseChannels 1: out[c] = sum a[idx][c] * dense[idx]      (RGB transport . grey light)
//   a.channels 1:    out[c] = sum a[idx]    * dense[idx][c]   (grey transport . RGB light)
void dotPerChannel(const SparseVector& a, const float* dense, int denseChannels,
                   float* out);
// dotPerChannel for three output channels (throws unless the result has 3 channels).
void dotRGB(const SparseVector& a, const float* dense, int denseChannels, float out[3]);

// Inner product of two sparse vectors with the same channel count: the sum over
// common indices and all channels of products (merge of the sorted indices).
double dot(const SparseVector& a, const SparseVector& b);

// Sum of squares of all stored values (all channels).
double energy(const SparseVector& a);
// Sum of squares of `count` floats (in double, four partial sums).
double energy(const float* values, size_t count);

}  // namespace prt
