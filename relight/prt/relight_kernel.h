#pragma once
// The relighting kernel: per-vertex sparse dot products of the transport file's
// vectors with a light vector (Wang et al. 2005, Eqs. 6 and 10 by cubature).
//
// What comes out, per vertex v and channel c:
//   diffuse[v]  = sum over the selected diffuse components (multiple scattering, which
//                 the file stores as T_d / pi, and isotropic single scattering) of
//                 dot(vector_v, light) -- the outgoing radiance is F_t(eta, w_o) * diffuse[v];
//   terms[k][v] = dot(T_k vector_v, light) for each SVD phase term k -- the outgoing
//                 radiance adds F_t(eta, w_o) * sum_k h_k(w_o') * terms[k][v].
// Fresnel and the view maps depend on the view, so renderers apply them per pixel.

#include <glm/glm.hpp>

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "relight/prt/light_vector.h"
#include "common/transport_file.h"
#include "common/transport_params.h"

namespace prt {

struct VertexRadiance {
    std::vector<glm::vec3> diffuse;             // one per vertex
    std::vector<std::vector<glm::vec3>> terms;  // [k][vertex], empty without K-term SS
};

// Fast path: multithreaded (TBB), streaming each component's arrays once, whichever its
// encoding (a file may mix them):
//   per vertex (CSR, TransportComponent::vectors): over ranges of vertices, int16 values
//     dequantized on the fly;
//   blocked (TransportComponent::blocks, common/blocked_vectors.h): over ranges of blocks
//     of 16 vertices; per index of a block the light's RGB is loaded once and multiplied
//     into the 16 vertices' int8 values (three 16-wide multiply-adds), and the block's 16
//     results are scattered to their vertices order[16 b + lane] (padding lanes skipped).
// Throws prt::Error when the light vector's N differs from the file's cubemap size.
//
// OUTPUT. out.diffuse always has one entry per vertex (zeros when no diffuse
// component is selected or present); out.terms has one vector per SingleScatteringTerm
// component of the file, ordered by term index (slot k = term k in a valid file), when
// singleScattering is selected, and is empty otherwise. The diffuse components sum in a
// fixed order: the per-vertex ones, then the blocked ones, each in the file's order (the
// first stores, the others add). The vertex count is the components' (vertexCount();
// they must agree; mesh.vertexCount only when there are none). `out` is
// resize()d, so its capacity is kept and reusing it across frames does not reallocate
// (a few small per-call allocations remain: the light in gather layout, ~100 KB at N=32).
//
// PRECISION. Per vertex, component and channel the sum of q_n * L_n (int16 value times
// float light) is accumulated in float in four interleaved partial sums (eight with
// AVX-512), then multiplied by the vertex's scale. Against the exact sum of the
// dequantized products the error is
// at most about (n/4 + 3) * 2^-24 * sum_n |v_n L_n| for n coefficients (plus the float
// rounding of the scale): ~2e-6 of the absolute sum for n = 128, far below the 16-bit
// quantization error (kQuantizationMaxRelativeError ~ 1.5e-5 of the vertex's maximum).
// Blocked components: per lane and channel the sum of q_n * L_n (int8 value times float
// light) is accumulated in one float accumulator in index order, then multiplied by the
// lane's scale (with SH scales: the Haar and the SH indices in two such sums, each times
// its scale, then added; one rounding more): the error is at most about (n + 3) * 2^-24
// * sum_n |v_n L_n| for a block
// of n indices (~1e-5 of the absolute sum for n = 160), far below the 8-bit
// quantization error (kBlockQuantizationMaxRelativeError ~ 3.9e-3 of the vertex's
// channel maximum).
// Each vertex (block) is computed by the same instruction sequence whatever the
// partition into tasks, so the result is bitwise independent of the number of threads.
//
// VALIDATION. Per call, O(1) per component plus one comparison per vertex (per-vertex
// components) or per block and lane (blocked): array sizes, offsets, the largest (=
// last, indices increase) coefficient index of each vertex or block against 6 N^2 + the
// file's SH terms, and
// a blocked component's `order` entries against the vertex count, so a corrupt in-memory
// file raises prt::Error instead of reading or writing out of bounds. (That `order` is
// a permutation is not checked per call: a duplicate gives wrong results in bounds;
// checkBlockedVectors and the file reader check it.) Components with different vertex
// counts or a duplicated term are refused.
void relightVertices(const TransportFile& file, const LightVector& light,
                     const ScatteringComponents& components, VertexRadiance& out);

// Variants of the fast path, for tests and benchmarks (relightVertices above uses the
// defaults).
//   layout: how the light vector is laid out for the gathers (built once per call):
//     Rgb4: 4 floats (R, G, B, 0) per coefficient: one aligned 16-byte load, never
//           straddling a cache line;
//     Rgb3: 3 floats per coefficient, an unaligned 16-byte load (25% less cache).
//     (Blocked components read the light with three scalar broadcasts per index in
//     either layout.)
//   isa: Baseline is SSE2 (any x86-64; portable scalar code elsewhere), for both
//     encodings (blocked: 16 lanes = four xmm per channel); Avx2Fma is compiled with a
//     target attribute and needs a CPU with AVX2 and FMA (x86-64-v3), 16 lanes = two ymm
//     per channel for blocked components;
//     Avx512 needs AVX-512 F, BW and VL besides AVX2 + FMA: blocked components take 16
//     lanes = one zmm per channel, per-vertex ones four coefficients per zmm (one per
//     128-bit lane, values widened and placed by one masked load, one permutation and one
//     conversion per four);
//     Best takes the best of these the CPU has. FMA rounds once per product-sum, so the
//     kernels differ in the last bits (all within the PRECISION bounds above); the
//     choice is fixed per process, so results are reproducible on one machine.
enum class RelightLayout { Rgb3, Rgb4 };
enum class RelightIsa { Best, Baseline, Avx2Fma, Avx512 };
struct RelightOptions {
    RelightLayout layout = RelightLayout::Rgb4;
    RelightIsa isa = RelightIsa::Best;
};
// Whether this build and CPU can run `isa` (Best and Baseline: always).
bool relightIsaSupported(RelightIsa isa);
// Throws prt::Error("relight", ...) for an unsupported isa.
void relightVertices(const TransportFile& file, const LightVector& light,
                     const ScatteringComponents& components, VertexRadiance& out,
                     const RelightOptions& options);

// The slow obvious version (dequantize each vertex, dot in double), kept for tests.
// Validates blocked components whole first (checkBlockedVectors) and reads them through
// TransportComponent::dequantizeVertex (slotOf), not through `order` as the fast path.
void relightVerticesReference(const TransportFile& file, const LightVector& light,
                              const ScatteringComponents& components, VertexRadiance& out);

// Bytes the fast path streams for one evaluation (offsets, indices, values, scales of
// the selected components, and `order` of blocked ones: BlockedRgbVectors::byteSize()
// + 4 bytes per vertex): the numerator of the bandwidth ratio in SPEC section 8.
size_t relightStreamBytes(const TransportFile& file, const ScatteringComponents& components);

}  // namespace prt
