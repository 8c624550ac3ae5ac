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

#include "relight/light_vector.h"
#include "common/transport_file.h"
#include "common/transport_params.h"

namespace prt {

struct VertexRadiance {
    std::vector<glm::vec3> diffuse;             // one per vertex
    std::vector<std::vector<glm::vec3>> terms;  // [k][vertex], empty without K-term SS
};

// Fast path: multithreaded (TBB) over blocks of vertices, streaming each component's
// CSR arrays once; int16 values are dequantized on the fly. Throws prt::Error when
// the light vector's N differs from the file's cubemap size.
//
// OUTPUT. out.diffuse always has one entry per vertex (zeros when no diffuse
// component is selected or present); out.terms has one vector per SingleScatteringTerm
// component of the file, ordered by term index (slot k = term k in a valid file), when
// singleScattering is selected, and is empty otherwise. The vertex count is the
// components' (they must agree; mesh.vertexCount only when there are none). `out` is
// resize()d, so its capacity is kept and reusing it across frames does not reallocate
// (a few small per-call allocations remain: the light in gather layout, ~100 KB at N=32).
//
// PRECISION. Per vertex, component and channel the sum of q_n * L_n (int16 value times
// float light) is accumulated in float in four interleaved partial sums, then multiplied
// by the vertex's scale. Against the exact sum of the dequantized products the error is
// at most about (n/4 + 3) * 2^-24 * sum_n |v_n L_n| for n coefficients (plus the float
// rounding of the scale): ~2e-6 of the absolute sum for n = 128, far below the 16-bit
// quantization error (kQuantizationMaxRelativeError ~ 1.5e-5 of the vertex's maximum).
// Each vertex is computed by the same instruction sequence whatever the blocking, so
// the result is bitwise independent of the number of threads.
//
// VALIDATION. Per call, O(1) per component plus one comparison per vertex: array sizes,
// offsets, and the largest (= last, indices increase) coefficient index of each vertex
// against 6 N^2, so a corrupt in-memory file raises prt::Error instead of reading out
// of bounds. Components with different vertex counts or a duplicated term are refused.
void relightVertices(const TransportFile& file, const LightVector& light,
                     const ScatteringComponents& components, VertexRadiance& out);

// Variants of the fast path, for tests and benchmarks (relightVertices above uses the
// defaults).
//   layout: how the light vector is laid out for the gathers (built once per call):
//     Rgb4: 4 floats (R, G, B, 0) per coefficient: one aligned 16-byte load, never
//           straddling a cache line;
//     Rgb3: 3 floats per coefficient, an unaligned 16-byte load (25% less cache).
//   isa: Baseline is SSE2 (any x86-64; portable scalar code elsewhere); Avx2Fma is
//     compiled with a target attribute and needs a CPU with AVX2 and FMA (x86-64-v3);
//     Best takes Avx2Fma when the CPU has it. FMA rounds once per product-sum, so the
//     two differ in the last bits (both within the PRECISION bound above); the choice
//     is fixed per process, so results are reproducible on one machine.
enum class RelightLayout { Rgb3, Rgb4 };
enum class RelightIsa { Best, Baseline, Avx2Fma };
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
void relightVerticesReference(const TransportFile& file, const LightVector& light,
                              const ScatteringComponents& components, VertexRadiance& out);

// Bytes the fast path streams for one evaluation (offsets, indices, values, scales of
// the selected components): the numerator of the bandwidth ratio in SPEC section 8.
size_t relightStreamBytes(const TransportFile& file, const ScatteringComponents& components);

}  // namespace prt
