#pragma once
// The reference's dipole sum over all of its surface samples (docs/reference.md,
// "Multiple scattering"): for a point x (mm) and samples x_i with irradiance E_i and
// its variance Var_i, per channel c,
//
//     S_c = sum_i t_c(|x_i - x|) E_i^c,        V_c = sum_i t_c(|x_i - x|)^2 Var_i^c,
//     t_c(r) = z_r (1 + s d_r) e^(-s d_r) / d_r^3 + z_v (1 + s d_v) e^(-s d_v) / d_v^3,
//     d_r = sqrt(r^2 + z_r^2), d_v = sqrt(r^2 + z_v^2), s = sigma_tr,
//
// i.e. dipoleRd's bracket (common/bssrdf.h) without its constant alpha' / (4 pi), which
// the caller multiplies in. No hierarchy, no table, no cut-off: every sample, every
// channel, the closed form.
//
// Precision: each term in single precision (within ~3e-7 of dipoleRd's double), summed
// in float over at most kDipoleSumBlock samples per lane and in double beyond. Every ISA
// evaluates the same formula; they differ only in rounding (tests hold each to the
// double loop over dipoleRd).
//
// Units: positions and z in mm, sigma_tr in mm^-1, t in mm^-2 (a term of R_d without
// its constant).

#include <glm/glm.hpp>

#include <cstddef>
#include <vector>

#include "common/bssrdf.h"

namespace prt {

// Samples per block: the arrays are padded to a multiple of it.
constexpr size_t kDipoleSumBlock = 64;

// The samples, structure of arrays. Padding samples have zero irradiance and variance
// and add exactly nothing.
class DipoleSumSamples {
public:
    // Appends one sample; call pad() after the last.
    void add(const glm::vec3& position, const glm::vec3& value, const glm::vec3& variance);
    // Pads every array to a multiple of kDipoleSumBlock.
    void pad();
    size_t size() const { return x.size(); }  // padded count after pad()

    std::vector<float> x, y, z, value[3], variance[3];
};

// One channel's dipole in single precision.
struct DipoleSumChannel {
    float zr = 0, zv = 0, sigmaTr = 0;
};
DipoleSumChannel dipoleSumChannel(const DipoleChannel& d);

struct DipoleSumResult {
    double value[3] = {0, 0, 0};     // S_c
    double variance[3] = {0, 0, 0};  // V_c
};

// Which instruction set evaluates the sum. Portable: Eigen's vectorised float sqrt and
// exp at the compiler's baseline; Avx2: 8 lanes with FMA, its own exp (range reduction
// to [-ln2/2, ln2/2] and a degree-6 polynomial, ~1 ulp) and sqrt.
enum class DipoleSumIsa { Portable, Avx2 };
// The fastest one this CPU runs.
DipoleSumIsa bestDipoleSumIsa();
const char* toString(DipoleSumIsa isa);

// Precondition: samples padded (size() a multiple of kDipoleSumBlock). An isa the CPU
// does not run falls back to Portable.
DipoleSumResult dipoleSum(const DipoleSumSamples& samples, const DipoleSumChannel channels[3],
                          const glm::vec3& x, DipoleSumIsa isa);

}  // namespace prt
