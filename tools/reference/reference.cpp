#include "tools/reference/reference.h"

#include <Eigen/Core>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <bit>
#include <chrono>
#include <cmath>
#include <cstring>
#include <limits>

#include "common/envmap.h"
#include "common/error.h"
#include "common/progress.h"
#include "common/util.h"

namespace prt {

namespace {


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

// SplitMix64's finaliser, for hashing pixel data into stream numbers.
uint64_t mix64(uint64_t z) {
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
    return z ^ (z >> 31);
}

// The upper median: the middle value, the upper of the two middle ones for an even
// count (prt::median averages them), 0 for none. The reference reports this one.
double upperMedian(std::vector<double> v) {
    if (v.empty()) return 0.0;
    const size_t mid = v.size() / 2;
    std::nth_element(v.begin(), v.begin() + mid, v.end());
    return v[mid];
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

namespace {

// `estimate(i, sample)` -> IrradianceEstimate for every sample, in parallel (blocks of
// `grain` samples), with the totals and the median relative standard error.
template <typename Estimate>
SampleIrradiance irradianceAtSamples(const SampleSet& samples, size_t grain, Progress* progress,
                                     const Estimate& estimate) {
    const Stopwatch start;
    const size_t n = samples.samples.size();
    SampleIrradiance out;
    out.value.assign(n, glm::dvec3(0.0));
    out.variance.assign(n, glm::dvec3(0.0));
    std::vector<uint64_t> rays(n, 0);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, n, grain), [&](const tbb::blocked_range<size_t>& range) {
        for (size_t i = range.begin(); i != range.end(); ++i) {
            const IrradianceEstimate e = estimate(i, samples.samples[i]);
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
    out.medianRelativeStandardError = upperMedian(std::move(relative));
    out.seconds = start.seconds();
    return out;
}

}  // namespace

SampleIrradiance computeSampleIrradiance(const EnvironmentSampler& env, const RayScene* scene,
                                         const SampleSet& samples, double eta,
                                         const IrradianceEstimatorOptions& options, Progress* progress) {
    return irradianceAtSamples(samples, 16, progress, [&](size_t i, const SurfaceSample& s) {
        return estimateIrradiance(env, scene, s.position, s.normal, s.geometricNormal, eta, options, i);
    });
}

// ---------------------------------------------------------------------------
// Irradiance from point and directional lights
// ---------------------------------------------------------------------------

glm::dvec3 lightIrradiance(const std::vector<Light>& lights, const RayScene* scene, const glm::vec3& position,
                           const glm::vec3& normal, const glm::vec3& geometricNormal, double eta, bool visibility,
                           uint64_t* rays) {
    if (visibility && !scene) throw Error("reference", "visibility requested without a ray scene");
    const glm::dvec3 x(position), n = glm::normalize(glm::dvec3(normal));
    const glm::vec3 origin = visibility ? scene->offsetRayOrigin(position, geometricNormal, normal) : position;
    glm::dvec3 e(0.0);
    for (const Light& light : lights) {
        glm::dvec3 w;
        double reach, unoccluded;  // tfar of the shadow ray, and E_light
        if (light.type == LightType::Point || light.type == LightType::Spot) {
            const glm::dvec3 toLight = light.position - x;
            const double r2 = glm::dot(toLight, toLight);
            if (!(r2 > 0.0)) continue;
            const double r = std::sqrt(r2);
            w = toLight / r;
            reach = r * (1.0 - 1e-6);
            // A spot is a point light times its falloff along -w (the light's definition,
            // point_lights.h).
            unoccluded = kSquareMmPerSquareMetre / r2 * (light.type == LightType::Spot ? spotFalloff(light, -w) : 1.0);
        } else {
            w = glm::normalize(light.direction);
            reach = std::numeric_limits<double>::infinity();
            unoccluded = 1.0;
        }
        const double mu = glm::dot(n, w);
        if (!(mu > 0.0)) continue;
        if (visibility) {
            if (rays) ++*rays;
            if (scene->occluded(origin, glm::vec3(w), 0.0f, float(reach))) continue;
        }
        e += fresnelTransmittance(eta, mu) * mu * unoccluded * light.rgb;
    }
    return e;
}

SampleIrradiance computeLightIrradiance(const std::vector<Light>& lights, const RayScene& scene,
                                        const SampleSet& samples, double eta, Progress* progress) {
    if (lights.empty()) throw Error("reference", "no light");
    return irradianceAtSamples(samples, 256, progress, [&](size_t, const SurfaceSample& s) {
        IrradianceEstimate e;
        e.value = lightIrradiance(lights, &scene, s.position, s.normal, s.geometricNormal, eta, true, &e.rays);
        return e;
    });
}

// ---------------------------------------------------------------------------
// Multiple scattering
// ---------------------------------------------------------------------------

MultipleScatteringReference::MultipleScatteringReference(const Material& material,
                                                         std::vector<glm::vec3> positions,
                                                         double areaPerSample, SampleIrradiance irradiance)
    : material_(material), sampleCount_(positions.size()), area_(areaPerSample), isa_(bestDipoleSumIsa()) {
    validateMaterial(material_);
    if (irradiance.value.size() != positions.size() || irradiance.variance.size() != positions.size())
        throw Error("reference", "one irradiance value per sample is needed");
    if (!(area_ > 0.0) || !std::isfinite(area_)) throw Error("reference", "sample area must be positive");
    for (int c = 0; c < 3; ++c) {
        dipole_[c] = makeDipoleChannel(material_, c);
        channels_[c] = dipoleSumChannel(dipole_[c]);
    }
    for (size_t i = 0; i < positions.size(); ++i) {
        const glm::dvec3 &e = irradiance.value[i], &v = irradiance.variance[i];
        if (e == glm::dvec3(0.0) && v == glm::dvec3(0.0)) continue;
        samples_.add(positions[i], glm::vec3(e), glm::vec3(v));
    }
    contributing_ = samples_.size();
    samples_.pad();
}

RadianceEstimate MultipleScatteringReference::diffuse(const glm::vec3& x) const {
    const DipoleSumResult sum = dipoleSum(samples_, channels_, x, isa_);
    RadianceEstimate out;
    for (int c = 0; c < 3; ++c) {
        const double coefficient = area_ / kPi * dipole_[c].alphaPrime / (4.0 * kPi);
        out.value[c] = coefficient * sum.value[c];
        out.variance[c] = coefficient * coefficient * sum.variance[c];
    }
    return out;
}

RadianceEstimate MultipleScatteringReference::diffuseScalar(const glm::vec3& x) const {
    const glm::dvec3 xo(x);
    const double scale = area_ / kPi;
    RadianceEstimate out;
    const DipoleSumSamples& s = samples_;
    for (size_t i = 0; i < s.size(); ++i) {
        const double r = glm::length(glm::dvec3(s.x[i], s.y[i], s.z[i]) - xo);
        for (int c = 0; c < 3; ++c) {
            const double w = scale * dipoleRd(dipole_[c], r);
            out.value[c] += w * double(s.value[c][i]);
            out.variance[c] += w * w * double(s.variance[c][i]);
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
// Single scattering
// ---------------------------------------------------------------------------

const char* toString(SingleScatteringPath path) {
    return path == SingleScatteringPath::Refracted ? "refracted" : "normal";
}

SingleScatteringReference::SingleScatteringReference(const Material& material, const TriangleMesh& mesh,
                                                     const RayScene& scene, const EnvironmentSampler& env,
                                                     const SingleScatteringReferenceOptions& options)
    : material_(material), mesh_(&mesh), scene_(&scene), env_(&env), options_(options) {
    validateMaterial(material_);
    if (options_.pathSamples < 1) throw Error("--ss-samples", "need at least one path sample per pixel");
    if (options_.lightSamples < 1) throw Error("--ss-light-samples", "need at least one direction per path sample");
    if (!(options_.environmentFraction >= 0.0 && options_.environmentFraction <= 1.0))
        throw Error("--ss-env-fraction", "must be in [0, 1]");
    if (mesh.normals.size() != mesh.positions.size())
        throw Error("reference", "single scattering needs one normal per vertex");
    if (scene.triangleCount() != mesh.triangleCount())
        throw Error("reference", "the ray scene was not built from this mesh");
    sigmaS_ = material_.sigmaS();
    sigmaT_ = material_.sigmaT();
    sigmaTLuminance_ = luminance(sigmaT_);
    if (!(sigmaTLuminance_ > 0.0)) throw Error("sigma_t", "single scattering needs a positive extinction");
}

uint64_t SingleScatteringReference::pixelStream(const GBufferPixel& p) {
    uint64_t h = mix64(0x5353u + uint64_t(p.triangle));
    for (const glm::vec3* v : {&p.position, &p.normal, &p.toViewer})
        for (int k = 0; k < 3; ++k) h = mix64(h ^ (uint64_t(std::bit_cast<uint32_t>((*v)[k])) + 0x9e3779b97f4a7c15ull));
    return h;
}

RadianceEstimate SingleScatteringReference::radiance(const GBufferPixel& p) const {
    if (p.triangle >= mesh_->triangleCount()) throw Error("reference", "G-buffer triangle out of range");
    return estimate(p.position, p.normal, faceNormal(*mesh_, p.triangle), p.toViewer, pixelStream(p));
}

RadianceEstimate SingleScatteringReference::estimate(const glm::vec3& position, const glm::vec3& normal,
                                                     const glm::vec3& geometricNormal, const glm::vec3& toViewer,
                                                     uint64_t stream) const {
    RadianceEstimate out;
    const double eta = material_.eta;
    const glm::dvec3 n = glm::normalize(glm::dvec3(normal));
    const glm::dvec3 wo = glm::normalize(glm::dvec3(toViewer));
    const double cosView = glm::dot(n, wo);
    if (!(cosView > 0.0) || env_->black()) return out;
    glm::dvec3 woRefracted;
    if (!refractDirection(wo, n, eta, woRefracted)) return out;
    const glm::dvec3 toEye = -woRefracted;  // propagation direction after scattering
    const glm::dvec3 path = options_.path == SingleScatteringPath::Refracted ? woRefracted : -n;
    // Triangles wound against their vertex normals (meshes with inconsistent
    // orientation) are taken to face the way the shading normal does.
    glm::dvec3 ng(geometricNormal);
    if (glm::dot(ng, n) < 0.0) ng = -ng;
    if (!(glm::dot(path, ng) < 0.0)) return out;  // the path does not enter the object

    // The path's length d inside the object, from an origin offset inward.
    const glm::vec3 pathF(path);
    const glm::vec3 origin = scene_->offsetRayOrigin(position, geometricNormal, pathF);
    const Hit exit = scene_->intersect(origin, pathF, 0.0f, std::numeric_limits<float>::infinity());
    uint64_t rays = 1;
    const double d = exit.hit ? double(exit.t) : 0.0;
    if (!(d > 0.0)) {
        rays_.fetch_add(rays, std::memory_order_relaxed);
        return out;
    }
    const double st = sigmaTLuminance_;
    const double lambda = -std::expm1(-st * d);  // 1 - e^(-|sigma_t| d)

    const size_t M = options_.pathSamples, L = options_.lightSamples;
    const size_t nEnv = size_t(std::llround(options_.environmentFraction * double(L)));
    const size_t nUni = L - nEnv;
    const double pUniform = 1.0 / (4.0 * kPi);

    // Draw all path points and directions; keep those with non-zero radiance.
    struct Candidate {
        uint32_t pathSample;
        double s;               // distance along the path
        glm::dvec3 direction;   // w, toward the light
        glm::dvec3 weight;      // L(w) / (n_env p_env + n_uni p_uni) / pdf(s)
    };
    std::vector<Candidate> candidates;
    candidates.reserve(M * L);
    std::vector<float> ox, oy, oz, dx, dy, dz;
    ox.reserve(M * L), oy.reserve(M * L), oz.reserve(M * L);
    dx.reserve(M * L), dy.reserve(M * L), dz.reserve(M * L);

    Random rng(options_.seed ^ 0x53494e474c45ull, stream);  // "SINGLE": apart from the irradiance streams
    for (size_t m = 0; m < M; ++m) {
        const double xi = (double(m) + rng.uniform()) / double(M);
        const double s = std::min(d, -std::log1p(-lambda * xi) / st);
        const double pdfS = st * std::exp(-st * s) / lambda;
        const glm::dvec3 xp = glm::dvec3(origin) + s * path;
        for (size_t k = 0; k < L; ++k) {
            glm::dvec3 w, radiance;
            double pEnv;
            if (k < nEnv) {
                const double u1 = rng.uniform(), u2 = rng.uniform(), u3 = rng.uniform(), u4 = rng.uniform();
                const EnvironmentSampler::Sample smp = env_->sample(u1, u2, u3, u4);
                w = smp.direction;
                radiance = smp.radiance;
                pEnv = smp.pdf;
            } else {
                const double z = 1.0 - 2.0 * rng.uniform(), phi = 2.0 * kPi * rng.uniform();
                const double r = std::sqrt(std::max(0.0, 1.0 - z * z));
                w = glm::normalize(glm::dvec3(r * std::cos(phi), r * std::sin(phi), z));
                radiance = env_->radiance(w);
                pEnv = env_->pdf(w);
            }
            if (radiance.x <= 0.0 && radiance.y <= 0.0 && radiance.z <= 0.0) continue;
            const double denominator = double(nEnv) * pEnv + double(nUni) * pUniform;
            if (!(denominator > 0.0)) continue;  // cannot happen: the drawing strategy has p > 0
            candidates.push_back({uint32_t(m), s, w, radiance / (denominator * pdfS)});
            ox.push_back(float(xp.x)), oy.push_back(float(xp.y)), oz.push_back(float(xp.z));
            dx.push_back(float(w.x)), dy.push_back(float(w.y)), dz.push_back(float(w.z));
        }
    }

    // Where each direction's (unrefracted) ray leaves the object.
    std::vector<Hit> hits(candidates.size());
    if (!candidates.empty())
        scene_->intersectBatch(ox.data(), oy.data(), oz.data(), dx.data(), dy.data(), dz.data(), candidates.size(),
                               0.0f, std::numeric_limits<float>::infinity(), hits.data());
    rays += candidates.size();

    // Unoccluded contributions; the occlusion rays start at the exit points.
    std::vector<glm::dvec3> contribution;
    std::vector<uint32_t> owner;
    contribution.reserve(candidates.size());
    owner.reserve(candidates.size());
    size_t shadowRays = 0;
    const double invEta2 = 1.0 / (eta * eta);
    for (size_t c = 0; c < candidates.size(); ++c) {
        const Hit& hit = hits[c];
        const Candidate& cand = candidates[c];
        if (!hit.hit) continue;
        const glm::dvec3 w = cand.direction;
        const glm::uvec3 tri = mesh_->triangles[hit.triangle];
        const double b0 = 1.0 - double(hit.u) - double(hit.v), b1 = hit.u, b2 = hit.v;
        const glm::dvec3 ni = glm::normalize(b0 * glm::dvec3(mesh_->normals[tri.x]) +
                                             b1 * glm::dvec3(mesh_->normals[tri.y]) +
                                             b2 * glm::dvec3(mesh_->normals[tri.z]));
        glm::dvec3 ngi(hit.geometricNormal);
        if (glm::dot(ngi, ni) < 0.0) ngi = -ngi;         // reversed triangle: as at x_o
        if (!(glm::dot(ngi, w) > 0.0)) continue;          // entered, not left: x_p outside
        const double cosI = glm::dot(w, ni);
        glm::dvec3 a;
        if (!(cosI > 0.0) || !refractDirection(w, ni, eta, a)) continue;
        // Eq. 5: the refracted length from the observed one.
        const double si = double(hit.t);
        const double siRefracted = si * cosI / std::sqrt(1.0 - invEta2 * (1.0 - cosI * cosI));
        const double phase = options_.phase == SingleScatteringPhase::Isotropic
                                 ? pUniform
                                 : henyeyGreenstein(material_.g, glm::dot(a, toEye));
        const double common = phase * fresnelTransmittance(eta, cosI);
        glm::dvec3 f;
        for (int ch = 0; ch < 3; ++ch)
            f[ch] = sigmaS_[ch] * common * std::exp(-sigmaT_[ch] * (siRefracted + cand.s)) * cand.weight[ch];
        if (f.x <= 0.0 && f.y <= 0.0 && f.z <= 0.0) continue;
        const glm::vec3 xi = float(b0) * mesh_->positions[tri.x] + float(b1) * mesh_->positions[tri.y] +
                             float(b2) * mesh_->positions[tri.z];
        const glm::vec3 o = scene_->offsetRayOrigin(xi, hit.geometricNormal, glm::vec3(w));
        contribution.push_back(f);
        owner.push_back(cand.pathSample);
        ox[shadowRays] = o.x, oy[shadowRays] = o.y, oz[shadowRays] = o.z;
        dx[shadowRays] = dx[c], dy[shadowRays] = dy[c], dz[shadowRays] = dz[c];
        ++shadowRays;
    }
    std::vector<uint8_t> occluded(shadowRays, 0);
    if (options_.visibility && shadowRays > 0) {
        scene_->occludedBatch(ox.data(), oy.data(), oz.data(), dx.data(), dy.data(), dz.data(), shadowRays, 0.0f,
                              std::numeric_limits<float>::infinity(), occluded.data());
        rays += shadowRays;
    }

    // Per path sample Y_m, their mean, and the paired-strata variance.
    std::vector<glm::dvec3> Y(M, glm::dvec3(0.0));
    for (size_t c = 0; c < shadowRays; ++c)
        if (!occluded[c]) Y[owner[c]] += contribution[c];
    glm::dvec3 sum(0.0), variance(0.0);
    for (size_t m = 0; m < M; ++m) sum += Y[m];
    const double Md = double(M);
    if (M >= 2) {
        const size_t pairs = M / 2;
        for (size_t j = 0; j < pairs; ++j) {
            const glm::dvec3 diff = Y[2 * j] - Y[2 * j + 1];
            variance += diff * diff;
        }
        variance /= 2.0 * double(pairs) * Md;
    } else {
        variance = Y[0] * Y[0];  // one sample: no spread to estimate; its square bounds the second moment
    }
    const double ft = fresnelTransmittance(eta, cosView);
    out.value = ft * sum / Md;
    out.variance = ft * ft * variance;
    rays_.fetch_add(rays, std::memory_order_relaxed);
    paths_.fetch_add(M, std::memory_order_relaxed);
    return out;
}

// ---------------------------------------------------------------------------
// Frames
// ---------------------------------------------------------------------------

namespace {

// Object-pixel count and noise statistics of a frame from its per-pixel values and
// variances (see ReferenceFrame).
void frameStatistics(ReferenceFrame& frame, const std::vector<uint8_t>& object, const std::vector<glm::dvec3>& value,
                     const std::vector<glm::dvec3>& variance) {
    double sumVariance = 0.0, sumSquares = 0.0;
    std::vector<double> relative;
    frame.objectPixels = 0;
    for (size_t i = 0; i < object.size(); ++i) {
        if (!object[i]) continue;
        ++frame.objectPixels;
        const double var = variance[i].x + variance[i].y + variance[i].z;
        sumVariance += var;
        sumSquares += glm::dot(value[i], value[i]);
        const double sum = value[i].x + value[i].y + value[i].z;
        if (sum > 0.0) relative.push_back(std::sqrt(var) / sum);
    }
    frame.expectedRelativeRmse = sumSquares > 0.0 ? std::sqrt(sumVariance / sumSquares) : 0.0;
    frame.maxRelativeStandardError = relative.empty() ? 0.0 : *std::max_element(relative.begin(), relative.end());
    frame.medianRelativeStandardError = upperMedian(std::move(relative));
}

}  // namespace

RadianceEstimate DiffuseBrdfReference::radiance(const GBufferPixel& p) const {
    // The renderers' convention at silhouettes (translucent_shader.h): an interpolated
    // normal facing away from the viewer shows black.
    if (!(glm::dot(p.normal, p.toViewer) > 0.0f)) return {};
    // A stream per surface point: the triangle and the barycentrics' bits.
    uint64_t stream = 1469598103934665603ull ^ p.triangle;
    for (int k = 0; k < 2; ++k) {
        uint32_t bits;
        std::memcpy(&bits, &p.barycentric[k + 1], sizeof bits);
        stream = (stream ^ bits) * 1099511628211ull;
    }
    const IrradianceEstimate e = estimateIrradiance(env_, &scene_, p.position, p.normal, p.normal, 1.0, options_, stream);
    RadianceEstimate r;
    const glm::dvec3 k = albedo_ / kPi;
    r.value = k * e.value;
    r.variance = k * k * e.variance;
    return r;
}

ReferenceFrame renderReference(const GBuffer& g, const std::vector<const ReferenceComponent*>& components,
                               const Image& background, const glm::dmat3& envRotation, Progress* progress) {
    const Stopwatch start;
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

    std::vector<uint8_t> object(g.pixels.size());
    for (size_t i = 0; i < g.pixels.size(); ++i) object[i] = g.pixels[i].hit ? 1 : 0;
    frameStatistics(frame, object, value, variance);
    frame.seconds = start.seconds();
    return frame;
}

ReferenceFrame sumReferenceFrames(const std::vector<const ReferenceFrame*>& parts) {
    if (parts.empty() || !parts[0]) throw Error("reference", "no frames to add");
    const ReferenceFrame& first = *parts[0];
    const int w = first.image.width, h = first.image.height;
    if (first.image.channels != 4 || first.standardError.channels != 3 || first.standardError.width != w ||
        first.standardError.height != h)
        throw Error("reference", "malformed reference frame");
    ReferenceFrame out;
    out.image = first.image;
    out.standardError = Image(w, h, 3, 0.0f);
    const size_t count = size_t(w) * h;
    std::vector<uint8_t> object(count);
    std::vector<glm::dvec3> value(count, glm::dvec3(0.0)), variance(count, glm::dvec3(0.0));
    for (const ReferenceFrame* part : parts) {
        if (!part || part->image.width != w || part->image.height != h || part->image.channels != 4 ||
            part->standardError.width != w || part->standardError.height != h || part->standardError.channels != 3)
            throw Error("reference", "frames of different sizes cannot be added");
        out.seconds += part->seconds;
    }
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            const size_t i = size_t(y) * w + x;
            const bool isObject = first.image.at(x, y, 3) > 0.5f;
            object[i] = isObject ? 1 : 0;
            for (const ReferenceFrame* part : parts) {
                if ((part->image.at(x, y, 3) > 0.5f) != isObject)
                    throw Error("reference", "frames with different object pixels cannot be added");
                if (!isObject) continue;
                for (int c = 0; c < 3; ++c) {
                    value[i][c] += double(part->image.at(x, y, c));
                    const double se = double(part->standardError.at(x, y, c));
                    variance[i][c] += se * se;
                }
            }
            if (!isObject) continue;
            for (int c = 0; c < 3; ++c) {
                out.image.at(x, y, c) = float(value[i][c]);
                out.standardError.at(x, y, c) = float(std::sqrt(variance[i][c]));
            }
        }
    frameStatistics(out, object, value, variance);
    return out;
}

// ---------------------------------------------------------------------------
// The reference's own sample set
// ---------------------------------------------------------------------------

double referenceSampleSpacing(const Material& m, double fraction) {
    validateMaterial(m);
    if (!(fraction > 0.0 && fraction <= 10.0)) throw Error("spacing fraction", "must be in (0, 10]");
    double widest = 0.0;  // max over channels of sigma_t' + sigma_tr (1 / the narrowest width)
    for (int c = 0; c < 3; ++c) widest = std::max(widest, m.sigmaTPrime()[c] + m.sigmaTr()[c]);
    return fraction / widest;
}

uint64_t referenceSampleSeed(uint64_t precomputeSeed, int level, std::optional<uint64_t> userSeed) {
    // SplitMix64 finaliser of (base + level): distinct, well-mixed seeds per level.
    uint64_t z = (userSeed ? *userSeed : kReferenceSampleSeed) + 0x9e3779b97f4a7c15ull * uint64_t(level + 1);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
    z ^= z >> 31;
    if (level == 0 && userSeed) z = *userSeed;  // the user's seed as given for the render itself
    if (z == precomputeSeed) z = z + 0x632be59bd9b4e019ull;
    return z;
}

size_t referenceIrradianceDirections(size_t samples) {
    const double d = std::ceil(kReferenceRayBudget / double(std::max<size_t>(samples, 1)));
    return size_t(std::clamp(d, 64.0, 2048.0));
}

ReferenceSamplePlan planReferenceSamples(const Material& m, double totalAreaMm2, uint64_t precomputeSeed,
                                         size_t maxSamples, double fraction, std::optional<uint64_t> userSeed) {
    ReferenceSamplePlan plan;
    plan.spacingMm = referenceSampleSpacing(m, fraction);
    const size_t wanted = defaultSampleCount(totalAreaMm2, plan.spacingMm, std::numeric_limits<size_t>::max());
    plan.count = std::min(wanted, maxSamples);
    plan.capped = plan.count < wanted;
    plan.cappedSpacingMm =
        plan.capped ? std::sqrt(2.0 * totalAreaMm2 / (std::sqrt(3.0) * double(plan.count))) : plan.spacingMm;
    plan.seed = referenceSampleSeed(precomputeSeed, 0, userSeed);
    return plan;
}

DiscretisationEstimate estimateDiscretisationError(const ReferenceFrame& full, const ReferenceFrame& half) {
    const Image &a = full.image, &b = half.image;
    if (a.width != b.width || a.height != b.height || a.channels != 4 || b.channels != 4 ||
        full.standardError.width != a.width || half.standardError.width != b.width)
        throw Error("reference", "convergence frames differ in size");
    DiscretisationEstimate e;
    double diff = 0, ref = 0, var = 0;
    for (int y = 0; y < a.height; ++y)
        for (int x = 0; x < a.width; ++x) {
            if (b.at(x, y, 3) < 0.5f) continue;
            if (a.at(x, y, 3) < 0.5f) throw Error("reference", "convergence pixel is not an object pixel");
            ++e.pixels;
            for (int c = 0; c < 3; ++c) {
                const double va = a.at(x, y, c), vb = b.at(x, y, c);
                const double sa = full.standardError.at(x, y, c), sb = half.standardError.at(x, y, c);
                diff += (va - vb) * (va - vb);
                ref += va * va;
                var += sa * sa + sb * sb;
            }
        }
    if (e.pixels == 0 || !(ref > 0)) return e;
    e.difference = std::sqrt(diff / ref);
    e.noiseFloor = std::sqrt(var / ref);
    e.halfError = std::sqrt(std::max(0.0, diff - var) / ref);
    e.estimatedError = e.halfError / std::sqrt(1.0 + std::pow(2.0, 2.0 * kDiscretisationRate));
    return e;
}

GBuffer subsampleObjectPixels(const GBuffer& g, size_t stride) {
    if (stride < 1) throw Error("reference", "pixel stride must be at least 1");
    GBuffer out = g;
    size_t k = 0;
    for (GBufferPixel& p : out.pixels)
        if (p.hit && (k++ % stride) != 0) p.hit = false;
    return out;
}

double VertexComparison::Group::ratio() const {
    const double t = sumTest.x + sumTest.y + sumTest.z;
    const double r = sumReference.x + sumReference.y + sumReference.z;
    if (r == 0.0) return t == 0.0 ? 0.0 : std::numeric_limits<double>::infinity();
    return t / r;
}

VertexComparison compareVertexValues(const std::vector<glm::dvec3>& test,
                                     const std::vector<glm::dvec3>& reference,
                                     const std::vector<glm::vec3>& normals,
                                     const std::vector<glm::dvec3>& referenceVariance) {
    if (test.size() != reference.size() || test.size() != normals.size() ||
        (!referenceVariance.empty() && referenceVariance.size() != test.size()))
        throw Error("vertex comparison", "test, reference, normals and variances differ in size");
    if (test.empty()) throw Error("vertex comparison", "no vertices to compare");
    VertexComparison c;
    double squaredError = 0.0, squaredReference = 0.0, variance = 0.0;
    for (size_t v = 0; v < test.size(); ++v) {
        VertexComparison::Group& g = normals[v].y > 0.5f ? c.up : normals[v].y < -0.5f ? c.down : c.side;
        for (VertexComparison::Group* group : {&g, &c.all}) {
            ++group->vertices;
            group->sumTest += test[v];
            group->sumReference += reference[v];
        }
        const glm::dvec3 d = test[v] - reference[v];
        squaredError += glm::dot(d, d);
        squaredReference += glm::dot(reference[v], reference[v]);
        if (!referenceVariance.empty())
            variance += referenceVariance[v].x + referenceVariance[v].y + referenceVariance[v].z;
    }
    if (squaredReference > 0.0) {
        c.relativeL2 = std::sqrt(squaredError / squaredReference);
        c.referenceNoise = std::sqrt(variance / squaredReference);
    } else {
        c.relativeL2 = squaredError > 0.0 ? std::numeric_limits<double>::infinity() : 0.0;
    }
    return c;
}

}  // namespace prt
