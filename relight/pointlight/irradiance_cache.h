#pragma once
// The translucent irradiance cache of Keng, Lee and Chuang 2006 (section 3; SPEC
// section 9; docs/point-lights.md, "The translucent irradiance cache"): the
// Jensen-Buhler sum (jensen_buhler.h)
// evaluated at a few visible points only ("caches", about 2% of the object pixels),
// and every visible point interpolated from them with the gradient of the subsurface
// illuminance. The three passes of section 3.4:
//
//   pass 1  irradiance samples and their octree (point_lights.h, jensen_buhler.h);
//   pass 2  the visible points (G-buffer hit pixels) in BOTTOM-UP scan-line order
//           (the last row first, each row left to right); a point where no existing
//           cache k has w_k(p) > 1/a gets a new cache storing
//             S      the subsurface illuminance (Keng Eq. 4; = M of jensen_buhler.h),
//             grad S its gradient (Eqs. 8-9, through dR_d/dr, same hierarchical walk),
//             V      the spread of irradiance within the split disk of radius R;
//   pass 3  every visible point interpolated by Eq. 10 with the weight of Eq. 11.
// Radiance is then L = F_out(n . w_o) S / pi exactly as JensenBuhler::radiance.
//
// UNITS AND FRAMES. Positions in mm, world frame; E, S, V in W/m^2 per colour channel;
// grad S in W/m^2 per mm; R in mm; R_d in mm^-2; `a` is dimensionless (see below).
//
// THE HIERARCHICAL WALK. S, grad S and V of a cache at x use the terms of
// IrradianceOctree::traverse(x, epsilon) -- the Jensen-Buhler terms, same epsilon,
// same order, same near field -- each term (position p, area A, irradiance E) adding
//   S      += A R_d(|x - p|) E                                  (Eq. 4, cubature)
//             (the cell weight w E for a sample in the cells' near field, jensen_buhler.h)
//   grad S += A E (x - p) D(|x - p|),   D(r) = (1/r) dR_d/dr     (Eqs. 8-9)
// with, per source z in {z_r, z_v}, s = sqrt(r^2 + z^2):
//   D = alpha'/(4 pi) sum_z z (-e^(-sigma_tr s) / s^4) (sigma_tr^2 s + 3 sigma_tr + 3/s)
// (Keng's dR_s/dx divided by x). S is summed with the same expression as
// JensenBuhler::exitance, bit for bit, so a -> 0 reproduces the Jensen-Buhler image.
//
// V, THE SPLIT-DISK SPREAD. Keng's split disk has a bright half of irradiance E and a
// dark half and "variance V" with E = 2V: that holds for the STANDARD DEVIATION (the
// half-bright disk has mean E/2 and standard deviation E/2), and Eq. 11 is
// dimensionally consistent only with V in units of E. So V is the area-weighted
// standard deviation of E over the walk's terms within distance R of x (a ball: the
// disk of a locally flat surface), per channel.
//
// THE WEIGHT (Eq. 11). Per channel c the split disk bounds the rate of change of S by
//   dS/du <= V^c G^c(R),
//   G(R) = 2 alpha' / (pi R) sum_z (e^(-sigma_tr z) - z/R_z e^(-sigma_tr R_z)),  R_z = sqrt(R^2 + z^2)
// (SplitDiskModel::Paper, Keng's four-sector approximation of the half-bright disk;
// SplitDiskModel::Exact is the exact derivative of the half-bright disk,
// G = 4 int_0^R R_d(y) dy, which is larger: the paper's approximation underestimates
// the gradient, more so for large R / z_r; docs/point-lights.md). Over the
// channels the largest bound is used:
//   eps_k(p) = |p - p_k| g_k,   g_k = max_c V_k^c G^c     (floored, see below)
//   w_k(p)   = 1 / eps_k(p)   for |p - p_k| < R, 0 beyond R (the split disk says
//                             nothing about points outside it)
// and cache k is valid at p when w_k(p) > 1 / (a S_ref): Keng's absolute bound a is
// a S_ref here, so that `a` is a RELATIVE error bound that does not change with the
// light intensity. S_ref = max_c (max_i E^_i^c) Rtot^c (Rtot = int R_d dA, bssrdf.h),
// the exitance of a flat surface under the brightest sample irradiance. The floor
// g_k >= 1e-3 S_ref max_c G^c keeps weights finite where the disk is uniformly lit
// or dark (V = 0); such a cache is valid over its whole disk (radius min(R, ..)).
// Validity radius r_k = min(a S_ref / g_k, R).
//
// THE INTERPOLATION (Eq. 10), per channel, over the valid caches C(p):
//   S(p) = sum_k w_k (S_k + (p - p_k) . grad S_k) / sum_k w_k,  clamped to >= 0,
// and a cache at exactly p (w infinite) gives S_k itself (the limit of Eq. 10). A
// visible point with no valid cache in pass 3 cannot happen (pass 2 made one there or
// found one valid), except for pixels skipped because nothing leaves toward the
// viewer (F_out = 0: black, as in the Jensen-Buhler renderer).
//
// DETERMINISM AND THREADS. The scan of pass 2 is serial (it defines the cache set):
// it computes each new cache's V at once -- with the same walk as S but without the
// exponentials, cheap -- because the next pixel's decision needs the new cache's
// validity radius. S and grad S of the new caches (the expensive part) are computed
// meanwhile by TBB tasks, in batches, one cache per task, so both cores are busy.
// Pass 3 is parallel over rows. Every value is computed by one thread in a fixed
// order, so the image, the caches and the statistics do not depend on the number of
// threads (tested bit for bit).
//
// MATERIAL. The octree (pass 1) depends on the lights and eta only and is kept by
// setMaterial; everything else of the cache depends on the material and is rebuilt by
// it: the dipole lanes, the default split-disk radius R (an explicit options.radius
// stays), G^c(R), S_ref (from the brightest sample irradiance, kept, and the new
// Rtot), the floor of g and a S_ref. The caches of the last render are dropped (S,
// grad S, V's radius and the validity radii all depend on the material): the next
// render() makes new ones, so a cache after setMaterial(B) renders exactly as one
// constructed with B. eta is fixed at construction (requireIrradianceEta,
// point_lights.h). A size change is a material change (common/material_edit.h).
//
// THE CACHE LOOK-UP. Caches live in a multi-level hash grid (CacheGrid): level l has
// cubic cells of size h_l = 2R / 2^l; a cache of validity radius r is stored at the
// deepest level with h_l >= 2r, in each of the (at most 8) cells its ball overlaps,
// so a query visits one cell per occupied level.

#include <glm/glm.hpp>

#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <vector>

#include "common/bssrdf.h"
#include "common/image.h"
#include "relight/pointlight/jensen_buhler.h"
#include "relight/pointlight/point_lights.h"
#include "relight/render/gbuffer.h"

namespace prt {

enum class SplitDiskModel { Paper, Exact };
const char* toString(SplitDiskModel model);
// "paper" or "exact" (case-insensitive); prt::Error("--split-disk", ...) otherwise.
SplitDiskModel parseSplitDiskModel(const std::string& text);

// G(R) of one channel: dS/du <= V G for the split disk of radius R mm (see the top).
// Throws prt::Error("--radius", ...) unless R is finite and > 0.
double splitDiskGradientFactor(const DipoleChannel& d, double radiusMm, SplitDiskModel model);

// The default split-disk radius of a material (mm): the radius within which a fifth of
// the diffuse reflectance int R_d dA is collected, for the channel where that radius
// is largest (Keng: "heuristically determined according to the material scattering
// property"). Its caches per pixel with the default `a`: docs/point-lights.md, "The
// cache's goals".
double defaultSplitDiskRadius(const Material& m);

struct IrradianceCacheOptions {
    double a = 0.01;         // relative error bound (> 0, finite); smaller = more caches
    double radius = 0.0;     // split-disk radius R in mm (> 0); 0 = defaultSplitDiskRadius
    double epsilon = 0.05;   // the walk's solid-angle threshold (jensen_buhler.h), >= 0
    FresnelModel fresnel = FresnelModel::Exact;
    SplitDiskModel splitDisk = SplitDiskModel::Paper;
    int batch = 32;          // caches per S/grad-S task of pass 2 (>= 1; no effect on results)
};

// One-line prt::Errors naming the option: "--a" unless a is finite and > 0, "--radius"
// unless radius is finite and >= 0 (0 = default), "--epsilon" (validateEpsilon),
// "--cache-batch" unless batch >= 1.
void validateCacheOptions(const IrradianceCacheOptions& o);

struct CacheRecord {
    glm::dvec3 position{0.0};   // p_k, mm (the hit point of pixel `pixel`)
    glm::dvec3 s{0.0};          // S_k, W/m^2
    glm::dvec3 gradient[3];     // grad S_k per channel, W/m^2/mm
    glm::dvec3 v{0.0};          // V_k (standard deviation of E within R), W/m^2
    double g = 0.0;             // g_k = max_c V^c G^c (floored), W/m^2/mm
    double validRadius = 0.0;   // r_k = min(a S_ref / g_k, R), mm
    uint32_t pixel = 0;         // y * width + x of the pixel that created it
    uint32_t terms = 0;         // terms of its walk
};

struct IrradianceCacheStats {
    size_t hitPixels = 0;       // G-buffer hit pixels (the paper's "hit pixels")
    size_t shadedPixels = 0;    // hit pixels with F_out > 0 (examined by passes 2 and 3)
    size_t caches = 0;
    double ratio() const { return hitPixels ? double(caches) / double(hitPixels) : 0.0; }
    double scanSeconds = 0.0;   // pass 2 serial scan (incl. the V walks), wall
    double pass2Seconds = 0.0;  // pass 2 in all (scan + S/grad S of every cache), wall
    double pass3Seconds = 0.0;  // pass 3 (interpolation), wall
    uint64_t walkTerms = 0;     // terms summed over the caches' walks
    double meanValidCaches = 0.0;  // valid caches per shaded pixel in pass 3
    double sRef = 0.0;          // S_ref, W/m^2
    double radius = 0.0;        // R used, mm
};

// Per pixel by-products of pass 3 for the pictures (Keng Figs. 8-9): the interpolated
// gradient (mean over channels) and V (mean over channels); zero elsewhere.
struct CacheVisuals {
    std::vector<glm::vec3> gradient;  // width * height, W/m^2/mm
    std::vector<float> spread;        // width * height, W/m^2
};

class IrradianceCache {
public:
    // The tree is taken by value (std::move it in); `samples` give S_ref. Validates the
    // material and the options (validateCacheOptions).
    // cells: the near field of S (as JensenBuhler's; none = the point rule).
    IrradianceCache(const Material& material, IrradianceOctree tree, const IrradianceCacheOptions& options = {},
                    std::optional<SampleCells> cells = std::nullopt);
    const SampleCells* cells() const { return cells_ ? &*cells_ : nullptr; }

    // Replaces the material, keeping the tree (see MATERIAL above); costs the split-disk
    // factors (the exact model integrates numerically: about a millisecond). Throws
    // prt::Error for an invalid material or another eta than the constructor's (the
    // cache is then unchanged).
    void setMaterial(const Material& material);
    const Material& material() const { return material_; }

    // S, grad S (per channel) and V at x by one walk; *terms receives the term count.
    // s is bit-identical to JensenBuhler(material, tree, {epsilon}).exitance(x).
    void evaluate(const glm::dvec3& x, glm::dvec3& s, glm::dvec3 gradient[3], glm::dvec3& v,
                  size_t* terms = nullptr) const;
    // V alone (the walk without exponentials), as the scan needs it.
    glm::dvec3 spread(const glm::dvec3& x) const;

    // Passes 2 and 3 over g: RGBA image as JensenBuhler::render (A = 1 on the object).
    // Also keeps the caches (caches()) and, when visuals != nullptr, fills them.
    Image render(const GBuffer& g, IrradianceCacheStats* stats = nullptr, CacheVisuals* visuals = nullptr);

    const std::vector<CacheRecord>& caches() const { return caches_; }
    double sRef() const { return sRef_; }
    double radius() const { return radius_; }
    const glm::dvec3& gradientFactor() const { return gFactor_; }  // G^c(R)

private:
    void applyMaterial(const Material& material);

    Material material_;
    IrradianceOctree tree_;
    glm::dvec3 maxE_{0.0};  // the brightest sample irradiance per channel (S_ref's)
    IrradianceCacheOptions options_;
    double radius_ = 0.0, sRef_ = 0.0, gFloor_ = 0.0, validScale_ = 0.0;  // validScale = a S_ref
    glm::dvec3 gFactor_{0.0};
    // SIMD lanes as DipoleRGB (jensen_buhler.h): 0-2 real source R G B, 4-6 virtual.
    alignas(32) float z2_[8], sigma_[8], k_[8];
    std::vector<CacheRecord> caches_;
    std::optional<SampleCells> cells_;
};

}  // namespace prt
