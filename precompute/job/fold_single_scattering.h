#pragma once
// Folding isotropic single scattering into the multiple-scattering vectors
// (prt-precompute --fold-ss; Wang et al. 2005, Sec. 5, "single scattering ... can be
// folded into the diffuse transport vector" when the phase is isotropic).
//
// WHY it is exact before truncation: both components relight as
// F_t(eta, w_o) dot(T, L) (the multiple-scattering vector is stored as T_d / pi and the
// isotropic single-scattering vector has 1 / (4 pi) folded in; single_scattering.h), so
// F_t dot(T_ms, L) + F_t dot(T_ss, L) = F_t dot(T_ms + T_ss, L) for every light L. The
// folded file relights one vector per vertex instead of two.
//
// WHAT it costs: each vertex's sum is truncated again to `keep` terms (the SH part,
// indices >= forcedFrom, kept first whatever its size; then the largest Haar terms by
// Euclidean norm over RGB, ties to the lower index), and the int16 quantization runs on
// the sum. A folded file cannot show the two components apart; it records
// kFoldedSingleScatteringParameter (common/transport_params.h) and the renderers refuse
// a request for one of them alone.

#include <cstddef>
#include <cstdint>
#include <vector>

namespace prt {

struct SparseRgbVectors;
struct TransportComponent;

// Per vertex: a + b (dequantized), truncated to `keep` terms as above, quantized again.
// Preconditions: the same vertex count (prt::Error otherwise), keep >= 1.
SparseRgbVectors foldVectors(const SparseRgbVectors& a, const SparseRgbVectors& b, size_t keep,
                             uint32_t forcedFrom = UINT32_MAX);

// Replaces the MultipleScattering and SingleScatteringIsotropic components (one each,
// per vertex; prt::Error otherwise) by one MultipleScattering component holding their
// folded sum, where the multiple-scattering component was. Other components are kept.
void foldSingleScattering(std::vector<TransportComponent>& components, size_t keep, uint32_t forcedFrom);

}  // namespace prt
