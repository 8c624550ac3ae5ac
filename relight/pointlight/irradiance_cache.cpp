#include "relight/pointlight/irradiance_cache.h"

#include <Eigen/Core>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_group.h>

#include <algorithm>
#include <cmath>
#include <deque>
#include <string>
#include <unordered_map>

#include "common/error.h"
#include "common/util.h"

namespace prt {

// ---------------------------------------------------------------------------
// Options and the split disk
// ---------------------------------------------------------------------------

const char* toString(SplitDiskModel model) { return model == SplitDiskModel::Paper ? "paper" : "exact"; }

SplitDiskModel parseSplitDiskModel(const std::string& text) {
    const std::string t = toLower(text);
    if (t == "paper") return SplitDiskModel::Paper;
    if (t == "exact") return SplitDiskModel::Exact;
    throw Error("--split-disk", "must be paper or exact, got '" + text + "'");
}

double splitDiskGradientFactor(const DipoleChannel& d, double radius, SplitDiskModel model) {
    if (!std::isfinite(radius) || radius <= 0.0)
        throw Error("--radius", "split-disk radius must be finite and > 0 mm, got " + std::to_string(radius));
    if (model == SplitDiskModel::Paper) {
        // Keng section 3.3: dS/du ~ V 2 alpha'/(pi R) sum_z (e^(-s z) - z/R_z e^(-s R_z)).
        double sum = 0.0;
        for (const double z : {d.zr, d.zv}) {
            const double rz = std::sqrt(radius * radius + z * z);
            sum += std::exp(-d.sigmaTr * z) - z / rz * std::exp(-d.sigmaTr * rz);
        }
        return 2.0 * d.alphaPrime / (kPi * radius) * sum;
    }
    // Exact half-bright disk: moving the point by du turns a strip of width du across
    // the disk bright, dS/du = 2 E int_0^R R_d(y) dy = 4 V int_0^R R_d(y) dy (E = 2V).
    // Composite Simpson; R_d is smooth on the scale z_r, and 8192 intervals resolve it
    // for R up to thousands of z_r.
    const int n = 8192;
    const double h = radius / n;
    double sum = dipoleRd(d, 0.0) + dipoleRd(d, radius);
    for (int i = 1; i < n; ++i) sum += (i % 2 ? 4.0 : 2.0) * dipoleRd(d, i * h);
    return 4.0 * sum * h / 3.0;
}

double defaultSplitDiskRadius(const Material& m) {
    double r = 0.0;
    for (int c = 0; c < 3; ++c) r = std::max(r, dipoleRadiusForFraction(makeDipoleChannel(m, c), 0.2));
    return r;
}

void validateCacheOptions(const IrradianceCacheOptions& o) {
    if (!std::isfinite(o.a) || o.a <= 0.0)
        throw Error("--a", "error bound must be finite and > 0, got " + std::to_string(o.a));
    if (!std::isfinite(o.radius) || o.radius < 0.0)
        throw Error("--radius", "split-disk radius must be finite and > 0 mm (0 = the material's default), got " +
                                    std::to_string(o.radius));
    validateEpsilon(o.epsilon);
    if (o.batch < 1) throw Error("--cache-batch", "must be at least 1, got " + std::to_string(o.batch));
}

// ---------------------------------------------------------------------------
// The cache grid (see the top of the header)
// ---------------------------------------------------------------------------

namespace {

struct CellKey {
    int64_t x, y, z;
    bool operator==(const CellKey& o) const { return x == o.x && y == o.y && z == o.z; }
};
struct CellHash {
    size_t operator()(const CellKey& k) const {
        uint64_t h = uint64_t(k.x) * 0x9E3779B97F4A7C15ull;
        h ^= uint64_t(k.y) * 0xC2B2AE3D27D4EB4Full + (h << 6) + (h >> 2);
        h ^= uint64_t(k.z) * 0x165667B19E3779F9ull + (h << 6) + (h >> 2);
        return size_t(h ^ (h >> 29));
    }
};

class CacheGrid {
public:
    static constexpr int kMaxLevel = 40;  // h = 2R / 2^40: radii far below any pixel spacing

    explicit CacheGrid(double radius) : h0_(2.0 * radius), levels_(kMaxLevel + 1) {}

    // Cache k at p, valid within r (0 < r <= R), at the deepest level whose cells are
    // at least 2r wide, in every cell its ball overlaps (at most 2 per axis).
    void insert(uint32_t k, const glm::dvec3& p, double r) {
        int level = kMaxLevel;
        if (r > 0.0) level = std::clamp(int(std::floor(std::log2(h0_ / (2.0 * r)))), 0, kMaxLevel);
        const double h = std::ldexp(h0_, -level);
        const glm::dvec3 lo = glm::floor((p - r) / h), hi = glm::floor((p + r) / h);
        auto& cells = levels_[level];
        for (int64_t z = int64_t(lo.z); z <= int64_t(hi.z); ++z)
            for (int64_t y = int64_t(lo.y); y <= int64_t(hi.y); ++y)
                for (int64_t x = int64_t(lo.x); x <= int64_t(hi.x); ++x) cells[CellKey{x, y, z}].push_back(k);
        if (std::find(occupied_.begin(), occupied_.end(), level) == occupied_.end()) {
            occupied_.push_back(level);
            std::sort(occupied_.begin(), occupied_.end());
        }
    }

    // Calls f(k) for every cache whose ball may contain p (a superset of the valid
    // ones), in a fixed order (levels ascending, then insertion order); stops early
    // when f returns true.
    template <class F>
    void visit(const glm::dvec3& p, F&& f) const {
        for (const int level : occupied_) {
            const double h = std::ldexp(h0_, -level);
            const glm::dvec3 c = glm::floor(p / h);
            const auto& cells = levels_[level];
            const auto it = cells.find(CellKey{int64_t(c.x), int64_t(c.y), int64_t(c.z)});
            if (it == cells.end()) continue;
            for (const uint32_t k : it->second)
                if (f(k)) return;
        }
    }

private:
    double h0_;
    std::vector<std::unordered_map<CellKey, std::vector<uint32_t>, CellHash>> levels_;
    std::vector<int> occupied_;
};

}  // namespace

// ---------------------------------------------------------------------------
// The cache
// ---------------------------------------------------------------------------

IrradianceCache::IrradianceCache(const Material& material, IrradianceOctree tree,
                                 const IrradianceCacheOptions& options, std::optional<SampleCells> cells)
    : tree_(std::move(tree)), options_(options), cells_(std::move(cells)) {
    validateMaterial(material);
    validateCacheOptions(options_);
    adoptCells(cells_, tree_, material);
    for (const IrradianceOctree::Sample& s : tree_.samples()) maxE_ = glm::max(maxE_, glm::dvec3(s.irradiance));
    applyMaterial(material);
}

void IrradianceCache::setMaterial(const Material& material) {
    validateMaterial(material);
    requireIrradianceEta(material_.eta, material.eta);
    if (cells_) cells_->setMaterial(material);
    applyMaterial(material);
}

void IrradianceCache::applyMaterial(const Material& material) {
    material_ = material;
    caches_.clear();  // S, grad S and the validity radii were the old material's
    radius_ = options_.radius > 0.0 ? options_.radius : defaultSplitDiskRadius(material_);

    // The lanes exactly as DipoleRGB builds them (same float values: S is then summed
    // bit for bit as JensenBuhler::exitance sums it).
    for (int lane = 0; lane < 8; ++lane) {
        z2_[lane] = 1.0f;
        sigma_[lane] = 0.0f;
        k_[lane] = 0.0f;
    }
    double gMax = 0.0;
    sRef_ = 0.0;
    for (int c = 0; c < 3; ++c) {
        const DipoleChannel d = makeDipoleChannel(material_, c);
        for (int s = 0; s < 2; ++s) {
            const double z = s == 0 ? d.zr : d.zv;
            z2_[4 * s + c] = float(z * z);
            sigma_[4 * s + c] = float(d.sigmaTr);
            k_[4 * s + c] = float(d.alphaPrime * z / (4.0 * kPi));
        }
        gFactor_[c] = splitDiskGradientFactor(d, radius_, options_.splitDisk);
        gMax = std::max(gMax, gFactor_[c]);
        sRef_ = std::max(sRef_, maxE_[c] * dipoleTotalDiffuseReflectance(d));
    }
    if (!(sRef_ > 0.0)) sRef_ = 1.0;  // no light at all: every S is 0, any scale will do
    gFloor_ = 1e-3 * sRef_ * gMax;
    validScale_ = options_.a * sRef_;
}

void IrradianceCache::evaluate(const glm::dvec3& x, glm::dvec3& s, glm::dvec3 gradient[3], glm::dvec3& v,
                               size_t* terms) const {
    using Lanes = Eigen::Array<float, 8, 1>;
    const Lanes z2 = Eigen::Map<const Lanes, Eigen::Aligned32>(z2_);
    const Lanes sigma = Eigen::Map<const Lanes, Eigen::Aligned32>(sigma_);
    const Lanes k = Eigen::Map<const Lanes, Eigen::Aligned32>(k_);
    const double r2max = radius_ * radius_;
    glm::dvec3 m(0.0), g[3] = {glm::dvec3(0.0), glm::dvec3(0.0), glm::dvec3(0.0)};
    double wA = 0.0;
    glm::dvec3 wE(0.0), wEE(0.0);
    const glm::vec3 xf(x);
    const SampleCells* cells = this->cells();
    const auto term = [&](const glm::dvec3& p, double area, const glm::dvec3& e, uint32_t index) {
        const glm::dvec3 d = x - p;
        const double r2 = glm::dot(d, d);
        // R_d as DipoleRGB::rd (same expression per lane), and D = (1/r) dR_d/dr from
        // the same exponentials (Keng Eq. 9's dR_s/dx = x D).
        const Lanes d2 = z2 + float(r2);
        const Lanes dist = d2.sqrt();
        const Lanes sd = sigma * dist;
        const Lanes ex = (-sd).exp();
        const Lanes rdLanes = k * (1.0f + sd) * ex / (d2 * dist);
        const Lanes dLanes = -k * ex * (sigma * sd + 3.0f * sigma + 3.0f / dist) / (d2 * d2);
        const glm::dvec3 rd{double(rdLanes[0]) + double(rdLanes[4]), double(rdLanes[1]) + double(rdLanes[5]),
                            double(rdLanes[2]) + double(rdLanes[6])};
        m += exitanceTerm(cells, tree_, index, xf, area, rd, e);  // Eq. 4, as JensenBuhler::exitance
        // The gradient keeps the point rule in the near field too (it only steers the
        // interpolation; docs/point-lights.md, "The near field").
        for (int c = 0; c < 3; ++c)
            g[c] += (area * e[c] * (double(dLanes[c]) + double(dLanes[c + 4]))) * d;  // Eqs. 8-9
        if (r2 < r2max) {  // the split disk (a ball of radius R)
            wA += area;
            wE += area * e;
            wEE += area * e * e;
        }
    };
    const size_t n = tree_.traverse(x, options_.epsilon, term, cells ? cells->nearRadius() : 0.0);
    s = m;
    for (int c = 0; c < 3; ++c) gradient[c] = g[c];
    v = glm::dvec3(0.0);
    if (wA > 0.0) {
        const glm::dvec3 mean = wE / wA;
        v = glm::sqrt(glm::max(glm::dvec3(0.0), wEE / wA - mean * mean));
    }
    if (terms) *terms = n;
}

glm::dvec3 IrradianceCache::spread(const glm::dvec3& x) const {
    const double r2max = radius_ * radius_;
    double wA = 0.0;
    glm::dvec3 wE(0.0), wEE(0.0);
    tree_.traverse(
        x, options_.epsilon,
        [&](const glm::dvec3& p, double area, const glm::dvec3& e) {
            const glm::dvec3 d = x - p;
            if (glm::dot(d, d) < r2max) {
                wA += area;
                wE += area * e;
                wEE += area * e * e;
            }
        },
        cells_ ? cells_->nearRadius() : 0.0);
    if (!(wA > 0.0)) return glm::dvec3(0.0);
    const glm::dvec3 mean = wE / wA;
    return glm::sqrt(glm::max(glm::dvec3(0.0), wEE / wA - mean * mean));
}

Image IrradianceCache::render(const GBuffer& gb, IrradianceCacheStats* stats, CacheVisuals* visuals) {
    const int width = gb.width, height = gb.height;
    const size_t count = size_t(width) * size_t(height);
    if (gb.pixels.size() != count) throw Error("irradiance cache", "inconsistent G-buffer");
    if (count >= size_t(0xffffffffu)) throw Error("irradiance cache", "image too large");

    // F_out per pixel; 0 marks pixels that nothing leaves toward the viewer from (and
    // misses): they are neither cache sites nor interpolated (black, as in JB).
    std::vector<double> fout(count, 0.0);
    size_t hitPixels = 0, shaded = 0;
    for (size_t i = 0; i < count; ++i) {
        const GBufferPixel& p = gb.pixels[i];
        if (!p.hit) continue;
        ++hitPixels;
        const double cosO = glm::dot(glm::dvec3(p.normal), glm::dvec3(p.toViewer));
        fout[i] = outgoingTransmittance(options_.fresnel, material_.eta, std::max(0.0, cosO));
        shaded += fout[i] != 0.0 ? 1 : 0;
    }

    // ---- Pass 2: the bottom-up scan (serial) and S / grad S of new caches (tasks).
    Stopwatch pass2;
    std::deque<CacheRecord> records;  // stable addresses while the tasks fill them in
    CacheGrid grid(radius_);
    tbb::task_group tasks;
    std::vector<CacheRecord*> batch;
    auto flush = [&]() {
        if (batch.empty()) return;
        tasks.run([this, todo = std::move(batch)]() {
            for (CacheRecord* r : todo) {
                glm::dvec3 v;
                size_t terms = 0;
                evaluate(r->position, r->s, r->gradient, v, &terms);
                r->terms = uint32_t(terms);
            }
        });
        batch.clear();
    };
    auto validAt = [&](const CacheRecord& r, const glm::dvec3& p) {
        const glm::dvec3 d = p - r.position;
        return glm::dot(d, d) < r.validRadius * r.validRadius;  // w_k > 1/(a S_ref), within R
    };
    Stopwatch scan;
    const CacheRecord* last = nullptr;  // the cache that covered the previous pixel: checked first
    for (int y = height - 1; y >= 0; --y) {
        for (int x = 0; x < width; ++x) {
            const size_t i = size_t(y) * width + x;
            if (fout[i] == 0.0) continue;
            const glm::dvec3 p(gb.pixels[i].position);
            if (last && validAt(*last, p)) continue;
            const CacheRecord* found = nullptr;
            grid.visit(p, [&](uint32_t k) {
                if (!validAt(records[k], p)) return false;
                found = &records[k];
                return true;
            });
            if (found) {
                last = found;
                continue;
            }
            // No valid cache: a new one here. V now (its validity radius decides the
            // next pixels), S and grad S later in a task.
            CacheRecord r;
            r.position = p;
            r.pixel = uint32_t(i);
            r.v = spread(p);
            double g = 0.0;
            for (int c = 0; c < 3; ++c) g = std::max(g, r.v[c] * gFactor_[c]);
            r.g = std::max(g, gFloor_);
            r.validRadius = std::min(validScale_ / r.g, radius_);
            records.push_back(r);
            grid.insert(uint32_t(records.size() - 1), p, r.validRadius);
            last = &records.back();
            batch.push_back(&records.back());
            if (int(batch.size()) >= options_.batch) flush();
        }
    }
    flush();
    const double tScan = scan.seconds();
    tasks.wait();
    caches_.assign(records.begin(), records.end());
    const double tPass2 = pass2.seconds();

    // ---- Pass 3: Eq. 10 at every shaded pixel, parallel over rows.
    Stopwatch pass3;
    Image image(width, height, 4, 0.0f);
    if (visuals) {
        visuals->gradient.assign(count, glm::vec3(0.0f));
        visuals->spread.assign(count, 0.0f);
    }
    std::vector<uint32_t> validCount(size_t(height), 0);
    tbb::parallel_for(tbb::blocked_range<int>(0, height), [&](const tbb::blocked_range<int>& rows) {
        for (int y = rows.begin(); y < rows.end(); ++y) {
            uint32_t rowValid = 0;
            for (int x = 0; x < width; ++x) {
                const size_t i = size_t(y) * width + x;
                if (!gb.pixels[i].hit) continue;
                float* out = image.pixel(x, y);
                out[3] = 1.0f;
                if (fout[i] == 0.0) continue;
                const glm::dvec3 p(gb.pixels[i].position);
                double wSum = 0.0;
                glm::dvec3 sum(0.0), gSum(0.0), vSum(0.0);
                const CacheRecord* exact = nullptr;
                grid.visit(p, [&](uint32_t k) {
                    const CacheRecord& r = caches_[k];
                    const glm::dvec3 d = p - r.position;
                    const double dist2 = glm::dot(d, d);
                    if (!(dist2 < r.validRadius * r.validRadius)) return false;
                    ++rowValid;
                    if (dist2 == 0.0) {  // w infinite: the cache's own value (Eq. 10's limit)
                        exact = &r;
                        return true;
                    }
                    const double w = 1.0 / (std::sqrt(dist2) * r.g);  // Eq. 11
                    wSum += w;
                    sum += w * (r.s + glm::dvec3(glm::dot(d, r.gradient[0]), glm::dot(d, r.gradient[1]),
                                                 glm::dot(d, r.gradient[2])));  // Eq. 10
                    if (visuals) {
                        gSum += w * (r.gradient[0] + r.gradient[1] + r.gradient[2]) / 3.0;
                        vSum += w * r.v;
                    }
                    return false;
                });
                glm::dvec3 s(0.0);
                if (exact) {
                    s = exact->s;
                    gSum = (exact->gradient[0] + exact->gradient[1] + exact->gradient[2]) / 3.0;
                    vSum = exact->v;
                } else if (wSum > 0.0) {
                    s = glm::max(glm::dvec3(0.0), sum / wSum);  // the gradient term may overshoot
                    gSum /= wSum;
                    vSum /= wSum;
                }
                const glm::vec3 l(fout[i] / kPi * s);  // as JensenBuhler::radiance
                out[0] = l.x;
                out[1] = l.y;
                out[2] = l.z;
                if (visuals) {
                    visuals->gradient[i] = glm::vec3(gSum);
                    visuals->spread[i] = float((vSum.x + vSum.y + vSum.z) / 3.0);
                }
            }
            validCount[size_t(y)] = rowValid;
        }
    });
    const double tPass3 = pass3.seconds();

    if (stats) {
        stats->hitPixels = hitPixels;
        stats->shadedPixels = shaded;
        stats->caches = caches_.size();
        stats->scanSeconds = tScan;
        stats->pass2Seconds = tPass2;
        stats->pass3Seconds = tPass3;
        stats->walkTerms = 0;
        for (const CacheRecord& r : caches_) stats->walkTerms += r.terms;
        uint64_t valid = 0;
        for (uint32_t v : validCount) valid += v;
        stats->meanValidCaches = shaded ? double(valid) / double(shaded) : 0.0;
        stats->sRef = sRef_;
        stats->radius = radius_;
    }
    return image;
}

}  // namespace prt
