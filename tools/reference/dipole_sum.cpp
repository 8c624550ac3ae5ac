#include "tools/reference/dipole_sum.h"

#include <Eigen/Core>

#if defined(__x86_64__) && defined(__GNUC__)
#include <immintrin.h>
#define PRT_DIPOLE_SUM_AVX2 1
#endif

#include "common/util.h"

namespace prt {

void DipoleSumSamples::add(const glm::vec3& position, const glm::vec3& e, const glm::vec3& v) {
    x.push_back(position.x);
    y.push_back(position.y);
    z.push_back(position.z);
    for (int c = 0; c < 3; ++c) {
        value[c].push_back(e[c]);
        variance[c].push_back(v[c]);
    }
}

void DipoleSumSamples::pad() {
    const size_t padded = (x.size() + kDipoleSumBlock - 1) / kDipoleSumBlock * kDipoleSumBlock;
    for (std::vector<float>* a : {&x, &y, &z, &value[0], &value[1], &value[2], &variance[0], &variance[1],
                                  &variance[2]})
        a->resize(padded, 0.0f);
}

DipoleSumChannel dipoleSumChannel(const DipoleChannel& d) {
    return {float(d.zr), float(d.zv), float(d.sigmaTr)};
}

DipoleSumIsa bestDipoleSumIsa() {
#ifdef PRT_DIPOLE_SUM_AVX2
    if (cpuHasAvx2Fma()) return DipoleSumIsa::Avx2;
#endif
    return DipoleSumIsa::Portable;
}

const char* toString(DipoleSumIsa isa) {
    return isa == DipoleSumIsa::Avx2 ? "avx2+fma" : "portable";
}

namespace {

DipoleSumResult dipoleSumPortable(const DipoleSumSamples& s, const DipoleSumChannel ch[3], const glm::vec3& x) {
    // Eigen's float sqrt and exp run twice as many lanes as its double ones.
    using Block = Eigen::Array<float, kDipoleSumBlock, 1>;
    using Column = Eigen::Map<const Block>;
    DipoleSumResult out;
    for (size_t b = 0; b < s.size(); b += kDipoleSumBlock) {
        const Block dx = Column(&s.x[b]) - x.x, dy = Column(&s.y[b]) - x.y, dz = Column(&s.z[b]) - x.z;
        const Block r2 = dx * dx + dy * dy + dz * dz;
        for (int c = 0; c < 3; ++c) {
            const float sigma = ch[c].sigmaTr;
            const Block dr = (r2 + ch[c].zr * ch[c].zr).sqrt(), dv = (r2 + ch[c].zv * ch[c].zv).sqrt();
            const Block real = ch[c].zr * (1.0f + sigma * dr) * (-sigma * dr).exp() / (dr * dr * dr);
            const Block virt = ch[c].zv * (1.0f + sigma * dv) * (-sigma * dv).exp() / (dv * dv * dv);
            const Block t = real + virt;
            out.value[c] += double((t * Column(&s.value[c][b])).sum());
            out.variance[c] += double((t * t * Column(&s.variance[c][b])).sum());
        }
    }
    return out;
}

#ifdef PRT_DIPOLE_SUM_AVX2

// e^x for x <= 0 (Cephes' expf: x = n ln 2 + r, |r| <= ln2 / 2, e^r by a degree-6
// polynomial, 2^n through the exponent bits); 0 below -87, where e^x is no longer a
// normal float.
__attribute__((target("avx2,fma"))) inline __m256 expNonPositiveAvx2(__m256 x) {
    const __m256 lowest = _mm256_set1_ps(-87.0f);
    const __m256 underflow = _mm256_cmp_ps(x, lowest, _CMP_LT_OQ);
    x = _mm256_max_ps(x, lowest);
    const __m256 n =
        _mm256_round_ps(_mm256_mul_ps(x, _mm256_set1_ps(1.44269504088896341f)), _MM_FROUND_TO_NEAREST_INT | _MM_FROUND_NO_EXC);
    // ln 2 in two parts, the first exact in 9 bits, so n * its first part is exact.
    __m256 r = _mm256_fnmadd_ps(n, _mm256_set1_ps(0.693359375f), x);
    r = _mm256_fnmadd_ps(n, _mm256_set1_ps(-2.12194440e-4f), r);
    __m256 p = _mm256_set1_ps(1.9875691500e-4f);
    p = _mm256_fmadd_ps(p, r, _mm256_set1_ps(1.3981999507e-3f));
    p = _mm256_fmadd_ps(p, r, _mm256_set1_ps(8.3334519073e-3f));
    p = _mm256_fmadd_ps(p, r, _mm256_set1_ps(4.1665795894e-2f));
    p = _mm256_fmadd_ps(p, r, _mm256_set1_ps(1.6666665459e-1f));
    p = _mm256_fmadd_ps(p, r, _mm256_set1_ps(5.0000001201e-1f));
    const __m256 y = _mm256_fmadd_ps(p, _mm256_mul_ps(r, r), _mm256_add_ps(r, _mm256_set1_ps(1.0f)));
    const __m256i twoToN = _mm256_slli_epi32(_mm256_add_epi32(_mm256_cvtps_epi32(n), _mm256_set1_epi32(127)), 23);
    return _mm256_andnot_ps(underflow, _mm256_mul_ps(y, _mm256_castsi256_ps(twoToN)));
}

// One source's term z (1 + s d) e^(-s d) / d^3 with d = sqrt(r2 + z^2); 1/d from the
// hardware's 12-bit estimate and one Newton step (~2^-23).
__attribute__((target("avx2,fma"))) inline __m256 sourceTermAvx2(__m256 r2, __m256 z, __m256 z2, __m256 sigma) {
    const __m256 q = _mm256_add_ps(r2, z2);
    __m256 inv = _mm256_rsqrt_ps(q);
    const __m256 half = _mm256_mul_ps(_mm256_set1_ps(0.5f), q);
    inv = _mm256_mul_ps(inv, _mm256_fnmadd_ps(half, _mm256_mul_ps(inv, inv), _mm256_set1_ps(1.5f)));
    const __m256 d = _mm256_mul_ps(q, inv);
    const __m256 sd = _mm256_mul_ps(sigma, d);
    const __m256 e = expNonPositiveAvx2(_mm256_sub_ps(_mm256_setzero_ps(), sd));
    const __m256 inv3 = _mm256_mul_ps(_mm256_mul_ps(inv, inv), inv);
    return _mm256_mul_ps(_mm256_mul_ps(z, _mm256_add_ps(_mm256_set1_ps(1.0f), sd)), _mm256_mul_ps(e, inv3));
}

__attribute__((target("avx2,fma"))) inline double horizontalSumAvx2(__m256d v) {
    const __m128d pair = _mm_add_pd(_mm256_castpd256_pd128(v), _mm256_extractf128_pd(v, 1));
    return _mm_cvtsd_f64(_mm_add_sd(pair, _mm_unpackhi_pd(pair, pair)));
}

__attribute__((target("avx2,fma"))) DipoleSumResult dipoleSumAvx2(const DipoleSumSamples& s,
                                                                    const DipoleSumChannel ch[3],
                                                                    const glm::vec3& x) {
    __m256 zr[3], zv[3], zr2[3], zv2[3], sigma[3];
    for (int c = 0; c < 3; ++c) {
        zr[c] = _mm256_set1_ps(ch[c].zr), zv[c] = _mm256_set1_ps(ch[c].zv);
        zr2[c] = _mm256_set1_ps(ch[c].zr * ch[c].zr), zv2[c] = _mm256_set1_ps(ch[c].zv * ch[c].zv);
        sigma[c] = _mm256_set1_ps(ch[c].sigmaTr);
    }
    const __m256 px = _mm256_set1_ps(x.x), py = _mm256_set1_ps(x.y), pz = _mm256_set1_ps(x.z);
    __m256d value[3][2], variance[3][2];
    for (int c = 0; c < 3; ++c)
        value[c][0] = value[c][1] = variance[c][0] = variance[c][1] = _mm256_setzero_pd();
    for (size_t b = 0; b < s.size(); b += kDipoleSumBlock) {
        __m256 blockValue[3], blockVariance[3];
        for (int c = 0; c < 3; ++c) blockValue[c] = blockVariance[c] = _mm256_setzero_ps();
        for (size_t i = b; i < b + kDipoleSumBlock; i += 8) {
            const __m256 dx = _mm256_sub_ps(_mm256_loadu_ps(&s.x[i]), px);
            const __m256 dy = _mm256_sub_ps(_mm256_loadu_ps(&s.y[i]), py);
            const __m256 dz = _mm256_sub_ps(_mm256_loadu_ps(&s.z[i]), pz);
            const __m256 r2 = _mm256_fmadd_ps(dz, dz, _mm256_fmadd_ps(dy, dy, _mm256_mul_ps(dx, dx)));
            for (int c = 0; c < 3; ++c) {
                const __m256 t = _mm256_add_ps(sourceTermAvx2(r2, zr[c], zr2[c], sigma[c]),
                                               sourceTermAvx2(r2, zv[c], zv2[c], sigma[c]));
                blockValue[c] = _mm256_fmadd_ps(t, _mm256_loadu_ps(&s.value[c][i]), blockValue[c]);
                blockVariance[c] =
                    _mm256_fmadd_ps(_mm256_mul_ps(t, t), _mm256_loadu_ps(&s.variance[c][i]), blockVariance[c]);
            }
        }
        for (int c = 0; c < 3; ++c) {
            value[c][0] = _mm256_add_pd(value[c][0], _mm256_cvtps_pd(_mm256_castps256_ps128(blockValue[c])));
            value[c][1] = _mm256_add_pd(value[c][1], _mm256_cvtps_pd(_mm256_extractf128_ps(blockValue[c], 1)));
            variance[c][0] =
                _mm256_add_pd(variance[c][0], _mm256_cvtps_pd(_mm256_castps256_ps128(blockVariance[c])));
            variance[c][1] =
                _mm256_add_pd(variance[c][1], _mm256_cvtps_pd(_mm256_extractf128_ps(blockVariance[c], 1)));
        }
    }
    DipoleSumResult out;
    for (int c = 0; c < 3; ++c) {
        out.value[c] = horizontalSumAvx2(_mm256_add_pd(value[c][0], value[c][1]));
        out.variance[c] = horizontalSumAvx2(_mm256_add_pd(variance[c][0], variance[c][1]));
    }
    return out;
}

#endif

}  // namespace

DipoleSumResult dipoleSum(const DipoleSumSamples& samples, const DipoleSumChannel channels[3], const glm::vec3& x,
                          DipoleSumIsa isa) {
#ifdef PRT_DIPOLE_SUM_AVX2
    if (isa == DipoleSumIsa::Avx2 && cpuHasAvx2Fma()) return dipoleSumAvx2(samples, channels, x);
#endif
    return dipoleSumPortable(samples, channels, x);
}

}  // namespace prt
