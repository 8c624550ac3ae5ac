#pragma once
// The diffusion profile as the texture-space renderer evaluates it (Chang et al. 2008,
// sections 3 "Evaluating Translucency" and 4.1; docs/point-lights.md):
//   - RadialTable: any radial RGB kernel k(r) (R_d, R_d W_l, R_d W_g) tabulated once,
//     looked up from the SQUARED distance (what the sample loop has) with linear
//     interpolation; the paper's 1D R_d texture.
//   - DiffusionSplit: R_d = R_d W_l + R_d W_g with the weights of section 4.1 and R_p
//     from the importance lower bound.
//
// UNITS. r in mm, R_d in mm^-2, the importance R_d(r) 2 pi r and its lower bound c in
// mm^-1, K in mm^-1.
//
// THE WEIGHTS. As printed, W_l(r <= R_p) = 1 - 0.5 e^(-(r - R_p) K) would be negative
// near r = 0 whenever K R_p > ln 2 (Skimmilk's R_p = 2.41 mm with K = 1.5: W_l(0) =
// -17). We use the reading that matches their Fig. 3 (W_l = 1 at r = 0, 1/2 at R_p, -> 0
// far away) and is continuous with a continuous slope at R_p:
//     W_l(r) = 1 - 0.5 e^((r - R_p) K)     r <= R_p
//     W_l(r) = 0.5 e^(-(r - R_p) K)        r >  R_p
//     W_g(r) = 1 - W_l(r).
// R_p is the LARGEST r at which R_d(r) 2 pi r = c in any channel; c = 0.1 mm^-1 gives
// their Skimmilk R_p of 2.41 mm (Fig. 3), so it is the default. When c is above the
// importance everywhere (no crossing), R_p = 0.

#include <glm/glm.hpp>
#include <xmmintrin.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <vector>

#include "common/materials.h"

namespace prt {

inline constexpr double kDefaultImportanceBound = 0.1;  // c, mm^-1 (Chang Fig. 3-4: Skimmilk R_p = 2.41 mm)
inline constexpr double kDefaultSplitSharpness = 1.5;   // K, mm^-1 (Chang section 4.1)

// R_p (mm) for a material and lower bound c > 0: the largest crossing of R_d(r) 2 pi r
// with c over R, G, B, searched on (0, rMax] (bracketed on a fine grid, then bisected).
// 0 when the importance never reaches c. Throws prt::Error("--importance-bound", ...)
// unless c is finite and > 0.
double importanceRadius(const Material& material, double lowerBound, double rMax = 1000.0);

enum class SplitWeights {
    Paper,      // W_l, W_g as above
    AllLocal,   // W_l = 1, W_g = 0 (the hybrid reduces to the local filter alone)
    AllGlobal,  // W_l = 0, W_g = 1 (the hybrid reduces to sampling alone)
};

struct DiffusionSplit {
    double rp = 0.0;                        // R_p, mm (>= 0)
    double sharpness = kDefaultSplitSharpness;  // K, mm^-1 (> 0)
    SplitWeights weights = SplitWeights::Paper;

    double localWeight(double r) const;
    double globalWeight(double r) const { return 1.0 - localWeight(r); }
};

// A radial RGB kernel tabulated on t = sqrt(r / rMax) in [0, 1] (entries + 1 nodes),
// fine where kernels are steep (near r = 0) and coarse in the tail; 0 beyond rMax.
// With the default 4096 entries R_d's relative error is below 1e-4 wherever R_d is
// above 1e-6 of its peak (tests/test_diffusion_split.cpp).
class RadialTable {
public:
    RadialTable() = default;
    // kernel(r) for r in [0, rMax]; rMax > 0 (mm), entries >= 2. Throws prt::Error otherwise.
    RadialTable(const std::function<glm::dvec3(double r)>& kernel, double rMax, int entries = 4096);
    // From the kernel's values at the nodes (radialNodes with this rMax).
    RadialTable(const std::vector<glm::dvec3>& nodes, double rMax);

    // k(sqrt(r2)) by linear interpolation on the t grid; 0 for r2 >= rMax^2.
    glm::vec3 operator()(float r2) const {
        if (!(r2 < rMax2_)) return glm::vec3(0.0f);
        const float t = std::sqrt(std::sqrt(r2) * invRMax_) * scale_;
        const int i = std::min(int(t), last_);
        const float f = t - float(i);
        const glm::vec3 a(values_[size_t(i)]), b(values_[size_t(i) + 1]);
        return a + f * (b - a);
    }
    double rMax() const { return rMax_; }
    int entries() const { return int(values_.size()) - 1; }

    // The lookup split in two for loops over many distances: position(r2) is the
    // continuous index t (vectorisable: no branch, no table), then at(t, r2) is
    // operator()(r2) from it. at(position(r2), r2) == operator()(r2).
    float position(float r2) const { return std::sqrt(std::sqrt(r2) * invRMax_) * scale_; }
    glm::vec3 at(float t, float r2) const {
        if (!(r2 < rMax2_)) return glm::vec3(0.0f);
        const int i = std::min(int(t), last_);
        const float f = t - float(i);
        const glm::vec3 a(values_[size_t(i)]), b(values_[size_t(i) + 1]);
        return a + f * (b - a);
    }
    // at(t, r2) as (R, G, B, 0) in one SSE register, for the SIMD loops; the caller
    // checks r2 < rMax2() (beyond it the kernel is 0).
    __m128 atSse(float t) const {
        const int i = node(t);
        return lerpSse(i, _mm_set1_ps(t - float(i)));
    }
    // atSse split for tables on one grid (same rMax and entries): the node below t, and
    // the interpolation at node i with the fraction f (t - i in every lane).
    int node(float t) const { return std::min(int(t), last_); }
    __m128 lerpSse(int i, __m128 f) const {
        const __m128 a = _mm_loadu_ps(&values_[size_t(i)].x), b = _mm_loadu_ps(&values_[size_t(i) + 1].x);
        return _mm_add_ps(a, _mm_mul_ps(f, _mm_sub_ps(b, a)));
    }
    float rMax2() const { return rMax2_; }

private:
    double rMax_ = 0.0;
    float rMax2_ = 0.0f, invRMax_ = 0.0f, scale_ = 0.0f;
    int last_ = 0;  // entries - 1
    std::vector<glm::vec4> values_;  // RGB + 0 padding: one 16-byte load per node
};

// sum_k term(k) for k < count, term returning (R, G, B, 0) in an SSE register: the even
// and the odd terms in two accumulators, so that consecutive additions (the table loops'
// critical path) do not wait on each other. Inlined into its caller's target.
template <class Term>
[[gnu::always_inline]] inline __m128 sumInPairs(size_t count, const Term& term) {
    __m128 even = _mm_setzero_ps(), odd = _mm_setzero_ps();
    size_t k = 0;
    for (; k + 1 < count; k += 2) {
        even = _mm_add_ps(even, term(k));
        odd = _mm_add_ps(odd, term(k + 1));
    }
    if (k < count) even = _mm_add_ps(even, term(k));
    return _mm_add_ps(even, odd);
}

// The three kernels of a material as functions of r (mm): full R_d, local R_d W_l and
// global R_d W_g (mm^-2), and tabulated.
using RadialKernel = std::function<glm::dvec3(double r)>;
RadialKernel diffusionKernel(const Material& material);
RadialKernel localDiffusionKernel(const Material& material, const DiffusionSplit& split);
RadialKernel globalDiffusionKernel(const Material& material, const DiffusionSplit& split);
RadialTable diffusionTable(const Material& material, double rMax);
RadialTable localDiffusionTable(const Material& material, const DiffusionSplit& split, double rMax);
RadialTable globalDiffusionTable(const Material& material, const DiffusionSplit& split, double rMax);

// k at the nodes of the t grid: entries + 1 values, node i at r = rMax (i / entries)^2.
// Throws prt::Error for rMax not finite and > 0 or entries < 2. Parallel (TBB): kernel
// must be safe to call from several threads at once (a pure function of r).
std::vector<glm::dvec3> radialNodes(const RadialKernel& kernel, double rMax, int entries = 4096);

// The second-order part of a radial kernel's Taylor expansion. For y = c + d near c,
// with x - c = r u (u unit), the Hessian of k(|x - y|) in y is
// k''(r) u u^T + (k'(r) / r) (I - u u^T), so a sum of weights w_i at c + d_i with
// sum w_i d_i = 0 is, to second order,
//     sum w_i k(|x - c - d_i|) = W [k(r) + A(r) u^T S u + B(r) tr S],
//     A = (k'' - k'/r) / 2,  B = k' / (2 r),  S = sum w_i d_i d_i^T / W,  W = sum w_i.
// Both are tabulated as RadialTables on the kernel's own grid (the same nodes: one
// position() serves all three), from the kernel's node values (radialNodes: no
// evaluation of k beyond the kernel table's own) by second-order differences on the
// uneven node spacing; at r = 0, A = 0 and B = k''(0) / 2 from k being even in r; the
// last node repeats the one before it. Throws prt::Error as RadialTable for a bad rMax
// or fewer than 3 nodes.
struct RadialCurvature {
    RadialTable along;   // A(r), mm^-4
    RadialTable across;  // B(r), mm^-4
};
RadialCurvature radialCurvature(const std::vector<glm::dvec3>& nodes, double rMax);

}  // namespace prt
