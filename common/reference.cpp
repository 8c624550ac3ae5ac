#include "common/reference.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>

#include "common/envmap.h"
#include "common/error.h"
#include "common/progress.h"

namespace prt {

namespace {

constexpr double kPi = 3.14159265358979323846;

// Counter-based random numbers: SplitMix64 (Steele, Lea and Flood 2014) over a state
// seeded from (seed, stream), so every point owns an independent reproducible stream.
class Random {
public:
    Random(uint64_t seed, uint64_t stream) : state_(mix(seed ^ mix(stream + 0x9e3779b97f4a7c15ull))) {}
    uint64_t next() { return mix(state_ += 0x9e3779b97f4a7c15ull); }
    // Uniform in [0, 1): the top 53 bits.
    double uniform() { return double(next() >> 11) * (1.0 / 9007199254740992.0); }

private:
    static uint64_t mix(uint64_t z) {
        z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
        z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
        return z ^ (z >> 31);
    }
    uint64_t state_;
};

// Orthonormal basis (t, b, n) around the unit vector n (Duff et al. 2017).
void basisAround(const glm::dvec3& n, glm::dvec3& t, glm::dvec3& b) {
    const double sign = std::copysign(1.0, n.z);
    const double a = -1.0 / (sign + n.z);
    const double c = n.x * n.y * a;
    t = glm::dvec3(1.0 + sign * n.x * n.x * a, sign * c, -sign * n.x);
    b = glm::dvec3(c, sign + n.y * n.y * a, -n.y);
}

double median(std::vector<double> v) {
    if (v.empty()) return 0.0;
    const size_t mid = v.size() / 2;
    std::nth_element(v.begin(), v.begin() + mid, v.end());
    return v[mid];
}

double seconds(std::chrono::steady_clock::time_point since) {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - since).count();
}

}  // namespace

// ---------------------------------------------------------------------------
// EnvironmentSampler
// ---------------------------------------------------------------------------

EnvironmentSampler::EnvironmentSampler(const Image& latlong, const glm::dmat3& rotation)
    : width_(latlong.width), height_(latlong.height), rotation_(rotation) {
    if (latlong.empty() || !latlong.consistent() || latlong.channels < 3)
        throw Error("environment", "expected a non-empty RGB lat-long image");
    if (latlong.width != 2 * latlong.height)
        throw Error("environment", "a lat-long map needs width = 2 x height, got " +
                                       std::to_string(latlong.width) + " x " + std::to_string(latlong.height));
    const size_t count = size_t(width_) * height_;
    rgb_.resize(count);
    luminance_.resize(count);
    rowCdf_.resize(height_);
    columnCdf_.resize(count);
    double running = 0.0;
    for (int y = 0; y < height_; ++y) {
        const double omega = latLongPixelSolidAngle(y, width_, height_);
        double row = 0.0;
        for (int x = 0; x < width_; ++x) {
            const size_t i = size_t(y) * width_ + x;
            const float* p = latlong.pixel(x, y);
            for (int c = 0; c < 3; ++c)
                if (!std::isfinite(p[c]) || p[c] < 0.0f)
                    throw Error("environment", "pixel (" + std::to_string(x) + ", " + std::to_string(y) +
                                                   ") is negative or not finite");
            rgb_[i] = glm::vec3(p[0], p[1], p[2]);
            luminance_[i] = luminance(glm::dvec3(rgb_[i]));
            integral_ += glm::dvec3(rgb_[i]) * omega;
            row += luminance_[i] * omega;
            columnCdf_[i] = row;
        }
        running += row;
        rowCdf_[y] = running;
    }
    totalWeight_ = running;
}

size_t EnvironmentSampler::pixelOf(const glm::dvec3& worldDirection) const {
    // L'(d) = L(R^T d): look the direction up in the unrotated map.
    const glm::dvec2 uv = directionToLatLong(glm::transpose(rotation_) * worldDirection);
    const int x = std::min(width_ - 1, std::max(0, int(std::floor(uv.x * width_))));
    const int y = std::min(height_ - 1, std::max(0, int(std::floor(uv.y * height_))));
    return size_t(y) * width_ + x;
}

glm::dvec3 EnvironmentSampler::radiance(const glm::dvec3& d) const { return glm::dvec3(rgb_[pixelOf(d)]); }

double EnvironmentSampler::pdf(const glm::dvec3& d) const {
    if (black()) return 0.0;
    return luminance_[pixelOf(d)] / totalWeight_;
}

EnvironmentSampler::Sample EnvironmentSampler::sample(double u1, double u2, double u3, double u4) const {
    // Row: first y whose inclusive running sum exceeds u1 x total (rows of zero weight
    // are never chosen: their running sum equals the previous one).
    const double targetRow = u1 * totalWeight_;
    int y = int(std::upper_bound(rowCdf_.begin(), rowCdf_.end(), targetRow) - rowCdf_.begin());
    y = std::min(y, height_ - 1);
    while (y > 0 && rowCdf_[y] == rowCdf_[y - 1]) --y;  // rounding guard: never a zero-weight row
    // Column within the row, the same way.
    const double* cdf = &columnCdf_[size_t(y) * width_];
    const double rowTotal = cdf[width_ - 1];
    int x = int(std::upper_bound(cdf, cdf + width_, u2 * rowTotal) - cdf);
    x = std::min(x, width_ - 1);
    while (x > 0 && cdf[x] == cdf[x - 1]) --x;

    // Uniform in solid angle inside the pixel: uniform longitude, uniform cos(theta).
    const double u = (x + u3) / width_;
    const double cos0 = std::cos(kPi * y / height_), cos1 = std::cos(kPi * (y + 1) / height_);
    const double cosTheta = std::clamp(cos0 + u4 * (cos1 - cos0), -1.0, 1.0);
    const double v = std::acos(cosTheta) / kPi;

    Sample s;
    const size_t i = size_t(y) * width_ + x;
    s.direction = glm::normalize(rotation_ * latLongToDirection(u, v));
    s.radiance = glm::dvec3(rgb_[i]);
    s.pdf = luminance_[i] / totalWeight_;
    return s;
}

// ---------------------------------------------------------------------------
// Irradiance
// ---------------------------------------------------------------------------

IrradianceEstimate estimateIrradiance(const EnvironmentSampler& env, const RayScene* scene,
                                      const glm::vec3& position, const glm::vec3& normal,
                                      const glm::vec3& geometricNormal, double eta,
                                      const IrradianceEstimatorOptions& options, uint64_t stream) {
    if (options.directions < 1) throw Error("--env-samples", "need at least one direction per point");
    if (!(options.environmentFraction >= 0.0 && options.environmentFraction <= 1.0))
        throw Error("--env-fraction", "must be in [0, 1]");
    if (options.visibility && !scene) throw Error("reference", "visibility requested without a ray scene");

    IrradianceEstimate out;
    if (env.black()) return out;

    const glm::dvec3 n = glm::normalize(glm::dvec3(normal));
    glm::dvec3 t, b;
    basisAround(n, t, b);

    const size_t nEnv = size_t(std::llround(options.environmentFraction * double(options.directions)));
    const size_t nCos = options.directions - nEnv;
    const size_t total = nEnv + nCos;

    // Each direction: its strategy and the unoccluded contribution f / (n_e p_e + n_c p_c).
    struct Candidate {
        glm::dvec3 contribution;
        bool fromEnvironment;
    };
    std::vector<Candidate> candidates;
    std::vector<float> dx, dy, dz;
    candidates.reserve(total);
    dx.reserve(total);
    dy.reserve(total);
    dz.reserve(total);

    Random rng(options.seed, stream);
    for (size_t k = 0; k < total; ++k) {
        const bool fromEnvironment = k < nEnv;
        glm::dvec3 d, L;
        double pEnv;
        if (fromEnvironment) {
            const double u1 = rng.uniform(), u2 = rng.uniform(), u3 = rng.uniform(), u4 = rng.uniform();
            const EnvironmentSampler::Sample s = env.sample(u1, u2, u3, u4);
            d = s.direction;
            L = s.radiance;
            pEnv = s.pdf;
        } else {
            const double u1 = rng.uniform(), u2 = rng.uniform();
            const double r = std::sqrt(u1), phi = 2.0 * kPi * u2;
            d = glm::normalize(r * std::cos(phi) * t + r * std::sin(phi) * b + std::sqrt(std::max(0.0, 1.0 - u1)) * n);
            L = env.radiance(d);
            pEnv = env.pdf(d);
        }
        const double cosTheta = glm::dot(n, d);
        if (!(cosTheta > 0.0) || (L.x <= 0.0 && L.y <= 0.0 && L.z <= 0.0)) continue;  // f = 0
        const double pCos = cosTheta / kPi;
        const double denominator = double(nEnv) * pEnv + double(nCos) * pCos;
        if (!(denominator > 0.0)) continue;  // cannot happen: the drawing strategy has p > 0
        const double f = fresnelTransmittance(eta, cosTheta) * cosTheta;
        candidates.push_back({L * (f / denominator), fromEnvironment});
        dx.push_back(float(d.x));
        dy.push_back(float(d.y));
        dz.push_back(float(d.z));
    }

    std::vector<uint8_t> occluded(candidates.size(), 0);
    if (options.visibility && !candidates.empty()) {
        const glm::vec3 org = scene->offsetRayOrigin(position, geometricNormal, normal);
        scene->occludedFromPoint(org, dx.data(), dy.data(), dz.data(), candidates.size(), 0.0f,
                                 std::numeric_limits<float>::infinity(), occluded.data());
        out.rays = candidates.size();
    }

    // Sum and per-strategy sample variance (directions that contributed 0 count as
    // zero-valued draws of their strategy).
    glm::dvec3 sum[2] = {glm::dvec3(0.0), glm::dvec3(0.0)}, sumSq[2] = {glm::dvec3(0.0), glm::dvec3(0.0)};
    for (size_t k = 0; k < candidates.size(); ++k) {
        if (occluded[k]) continue;
        const int s = candidates[k].fromEnvironment ? 0 : 1;
        sum[s] += candidates[k].contribution;
        sumSq[s] += candidates[k].contribution * candidates[k].contribution;
    }
    const size_t count[2] = {nEnv, nCos};
    for (int s = 0; s < 2; ++s) {
        out.value += sum[s];
        if (count[s] >= 2) {
            // Var(sum of n iid Y) = n Var(Y), Var(Y) estimated by the unbiased sample variance.
            const double m = double(count[s]);
            const glm::dvec3 sampleVariance = (sumSq[s] - sum[s] * sum[s] / m) / (m - 1.0);
            out.variance += m * glm::max(sampleVariance, glm::dvec3(0.0));
        } else if (count[s] == 1) {
            // One draw gives no variance estimate; use its square (an upper bound of the
            // second moment) so the error is never reported as zero.
            out.variance += sumSq[s];
        }
    }
    return out;
}

SampleIrradiance computeSampleIrradiance(const EnvironmentSampler& env, const RayScene* scene,
                                         const SampleSet& samples, double eta,
                                         const IrradianceEstimatorOptions& options, Progress* progress) {
    const auto start = std::chrono::steady_clock::now();
    const size_t n = samples.samples.size();
    SampleIrradiance out;
    out.value.assign(n, glm::dvec3(0.0));
    out.variance.assign(n, glm::dvec3(0.0));
    std::vector<uint64_t> rays(n, 0);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, n, 16), [&](const tbb::blocked_range<size_t>& range) {
        for (size_t i = range.begin(); i != range.end(); ++i) {
            const SurfaceSample& s = samples.samples[i];
            const IrradianceEstimate e =
                estimateIrradiance(env, scene, s.position, s.normal, s.geometricNormal, eta, options, i);
            out.value[i] = e.value;
            out.variance[i] = e.variance;
            rays[i] = e.rays;
        }
        if (progress) progress->advance(range.size());
    });
    std::vector<double> relative;
    relative.reserve(n);
    for (size_t i = 0; i < n; ++i) {
        out.rays += rays[i];
        const double v = out.value[i].x + out.value[i].y + out.value[i].z;
        if (v > 0.0)
            relative.push_back(std::sqrt(out.variance[i].x + out.variance[i].y + out.variance[i].z) / v);
    }
    out.medianRelativeStandardError = median(std::move(relative));
    out.seconds = seconds(start);
    return out;
}

// ---------------------------------------------------------------------------
// Multiple scattering
// ---------------------------------------------------------------------------

MultipleScatteringReference::MultipleScatteringReference(const Material& material,
                                                         std::vector<glm::vec3> positions,
                                                         double areaPerSample, SampleIrradiance irradiance)
    : material_(material), positions_(std::move(positions)), area_(areaPerSample),
      irradiance_(std::move(irradiance)) {
    validateMaterial(material_);
    if (irradiance_.value.size() != positions_.size() || irradiance_.variance.size() != positions_.size())
        throw Error("reference", "one irradiance value per sample is needed");
    if (!(area_ > 0.0) || !std::isfinite(area_)) throw Error("reference", "sample area must be positive");
    for (int c = 0; c < 3; ++c) dipole_[c] = makeDipoleChannel(material_, c);
}

RadianceEstimate MultipleScatteringReference::diffuse(const glm::vec3& x) const {
    const glm::dvec3 xo(x);
    const double scale = area_ / kPi;
    RadianceEstimate out;
    for (size_t i = 0; i < positions_.size(); ++i) {
        const double r = glm::length(glm::dvec3(positions_[i]) - xo);
        for (int c = 0; c < 3; ++c) {
            const double w = scale * dipoleRd(dipole_[c], r);
            out.value[c] += w * irradiance_.value[i][c];
            out.variance[c] += w * w * irradiance_.variance[i][c];
        }
    }
    return out;
}

void MultipleScatteringReference::evaluateAtVertices(const TriangleMesh& mesh, Progress* progress) {
    const size_t n = mesh.vertexCount();
    std::vector<glm::dvec3> value(n), sigma(n);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, n, 8), [&](const tbb::blocked_range<size_t>& range) {
        for (size_t v = range.begin(); v != range.end(); ++v) {
            const RadianceEstimate e = diffuse(mesh.positions[v]);
            value[v] = e.value;
            sigma[v] = glm::sqrt(e.variance);
        }
        if (progress) progress->advance(range.size());
    });
    triangles_ = mesh.triangles;
    vertexValue_ = std::move(value);
    vertexSigma_ = std::move(sigma);
}

RadianceEstimate MultipleScatteringReference::radiance(const GBufferPixel& p) const {
    const double cosView = glm::dot(glm::dvec3(p.normal), glm::dvec3(p.toViewer));
    const double ft = fresnelTransmittance(material_.eta, std::max(0.0, cosView));
    RadianceEstimate d;
    if (perVertex()) {
        if (p.triangle >= triangles_.size()) throw Error("reference", "G-buffer triangle out of range");
        const glm::uvec3 tri = triangles_[p.triangle];
        glm::dvec3 sigma(0.0);
        for (int k = 0; k < 3; ++k) {
            d.value += double(p.barycentric[k]) * vertexValue_[tri[k]];
            sigma += double(p.barycentric[k]) * vertexSigma_[tri[k]];
        }
        d.variance = sigma * sigma;
    } else {
        d = diffuse(p.position);
    }
    d.value *= ft;
    d.variance *= ft * ft;
    return d;
}

// ---------------------------------------------------------------------------
// Frames
// ---------------------------------------------------------------------------

ReferenceFrame renderReference(const GBuffer& g, const std::vector<const ReferenceComponent*>& components,
                               const Image& background, const glm::dmat3& envRotation, Progress* progress) {
    const auto start = std::chrono::steady_clock::now();
    if (g.width < 1 || g.height < 1 || g.pixels.size() != size_t(g.width) * g.height)
        throw Error("reference", "inconsistent G-buffer");
    ReferenceFrame frame;
    frame.image = Image(g.width, g.height, 4, 0.0f);
    frame.standardError = Image(g.width, g.height, 3, 0.0f);
    std::vector<glm::dvec3> value(g.pixels.size(), glm::dvec3(0.0)), variance(g.pixels.size(), glm::dvec3(0.0));

    tbb::parallel_for(tbb::blocked_range<size_t>(0, g.pixels.size(), 16), [&](const tbb::blocked_range<size_t>& range) {
        size_t shaded = 0;
        for (size_t i = range.begin(); i != range.end(); ++i) {
            const GBufferPixel& p = g.pixels[i];
            const int x = int(i % size_t(g.width)), y = int(i / size_t(g.width));
            float* out = frame.image.pixel(x, y);
            if (p.hit) {
                for (const ReferenceComponent* c : components) {
                    const RadianceEstimate e = c->radiance(p);
                    value[i] += e.value;
                    variance[i] += e.variance;
                }
                for (int c = 0; c < 3; ++c) {
                    out[c] = float(value[i][c]);
                    frame.standardError.at(x, y, c) = float(std::sqrt(variance[i][c]));
                }
                out[3] = 1.0f;
                ++shaded;
            } else if (!background.empty()) {
                const glm::vec3 L = environmentRadiance(background, envRotation, glm::dvec3(p.rayDirection));
                for (int c = 0; c < 3; ++c) out[c] = L[c];
            }
        }
        if (progress && shaded) progress->advance(shaded);
    });

    double sumVariance = 0.0, sumSquares = 0.0;
    std::vector<double> relative;
    for (size_t i = 0; i < g.pixels.size(); ++i) {
        if (!g.pixels[i].hit) continue;
        ++frame.objectPixels;
        const double var = variance[i].x + variance[i].y + variance[i].z;
        sumVariance += var;
        sumSquares += glm::dot(value[i], value[i]);
        const double sum = value[i].x + value[i].y + value[i].z;
        if (sum > 0.0) relative.push_back(std::sqrt(var) / sum);
    }
    frame.expectedRelativeRmse = sumSquares > 0.0 ? std::sqrt(sumVariance / sumSquares) : 0.0;
    frame.maxRelativeStandardError = relative.empty() ? 0.0 : *std::max_element(relative.begin(), relative.end());
    frame.medianRelativeStandardError = median(std::move(relative));
    frame.seconds = seconds(start);
    return frame;
}

}  // namespace prt
