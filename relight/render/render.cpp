#include "relight/render/render.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include "common/bssrdf.h"
#include "common/envmap.h"
#include "common/error.h"
#include "common/mesh_io.h"

namespace prt {

// ---------------------------------------------------------------------------
// G-buffer
// ---------------------------------------------------------------------------

size_t GBuffer::objectPixels() const {
    size_t n = 0;
    for (const GBufferPixel& p : pixels) n += p.hit ? 1 : 0;
    return n;
}

GBuffer traceGBuffer(const RayScene& scene, const TriangleMesh& mesh, const Camera& camera) {
    validateCamera(camera);
    const bool haveNormals = mesh.normals.size() == mesh.positions.size();
    GBuffer g;
    g.width = camera.width;
    g.height = camera.height;
    g.pixels.resize(size_t(g.width) * size_t(g.height));
    const glm::vec3 eye(camera.eye);
    const float inf = std::numeric_limits<float>::infinity();

    // One row of rays per task, traced in packets by intersectBatch.
    tbb::parallel_for(tbb::blocked_range<int>(0, g.height), [&](const tbb::blocked_range<int>& rows) {
        const size_t w = size_t(g.width);
        std::vector<float> ox(w, eye.x), oy(w, eye.y), oz(w, eye.z), dx(w), dy(w), dz(w);
        std::vector<glm::vec3> dirs(w);
        std::vector<Hit> hits(w);
        for (int y = rows.begin(); y != rows.end(); ++y) {
            for (size_t x = 0; x < w; ++x) {
                const glm::vec3 d(cameraRayDirection(camera, double(x) + 0.5, double(y) + 0.5));
                dirs[x] = d;
                dx[x] = d.x;
                dy[x] = d.y;
                dz[x] = d.z;
            }
            scene.intersectBatch(ox.data(), oy.data(), oz.data(), dx.data(), dy.data(), dz.data(), w,
                                 0.0f, inf, hits.data());
            for (size_t x = 0; x < w; ++x) {
                GBufferPixel& p = g.pixels[size_t(y) * w + x];
                p = GBufferPixel{};
                p.rayDirection = dirs[x];
                p.toViewer = -dirs[x];
                const Hit& h = hits[x];
                if (!h.hit || h.triangle >= mesh.triangles.size()) continue;
                p.hit = true;
                p.triangle = h.triangle;
                p.barycentric = glm::vec3(1.0f - h.u - h.v, h.u, h.v);
                const glm::uvec3 tri = mesh.triangles[h.triangle];
                const glm::vec3 b = p.barycentric;
                p.position = b.x * mesh.positions[tri.x] + b.y * mesh.positions[tri.y] +
                             b.z * mesh.positions[tri.z];
                glm::vec3 n = h.geometricNormal;
                if (haveNormals) {
                    const glm::vec3 s =
                        b.x * mesh.normals[tri.x] + b.y * mesh.normals[tri.y] + b.z * mesh.normals[tri.z];
                    const float len = glm::length(s);
                    if (len > 1e-12f) n = s / len;
                }
                p.normal = n;
            }
        }
    });
    return g;
}

// ---------------------------------------------------------------------------
// Environment lookup and compositing
// ---------------------------------------------------------------------------

glm::vec3 environmentRadiance(const Image& latlong, const glm::dmat3& rotation, const glm::dvec3& d) {
    if (latlong.empty() || !latlong.consistent()) return glm::vec3(0.0f);
    const glm::dvec3 local = glm::transpose(rotation) * d;  // L(R^T d)
    if (!(glm::dot(local, local) > 0)) return glm::vec3(0.0f);
    const glm::dvec2 uv = directionToLatLong(local);
    const int w = latlong.width, h = latlong.height;
    // Continuous pixel coordinates whose integers are pixel centres.
    const double x = uv.x * w - 0.5;
    const double y = std::clamp(uv.y * h - 0.5, 0.0, double(h - 1));
    const double xf = std::floor(x);
    const double fx = x - xf;
    int x0 = int(xf) % w;
    if (x0 < 0) x0 += w;
    const int x1 = (x0 + 1) % w;  // u wraps around
    const int y0 = int(y);
    const int y1 = std::min(y0 + 1, h - 1);
    const double fy = y - y0;
    glm::vec3 out(0.0f);
    for (int c = 0; c < 3; ++c) {
        const int cc = std::min(c, latlong.channels - 1);
        const double top = (1 - fx) * latlong.at(x0, y0, cc) + fx * latlong.at(x1, y0, cc);
        const double bottom = (1 - fx) * latlong.at(x0, y1, cc) + fx * latlong.at(x1, y1, cc);
        out[c] = float((1 - fy) * top + fy * bottom);
    }
    return out;
}

Image compose(const GBuffer& g, const Image& background, const glm::dmat3& envRotation,
              const std::function<glm::vec3(const GBufferPixel&)>& shade) {
    if (g.width < 0 || g.height < 0 || g.pixels.size() != size_t(g.width) * size_t(g.height))
        throw Error("compose", "inconsistent G-buffer");
    Image out(g.width, g.height, 4, 0.0f);
    tbb::parallel_for(tbb::blocked_range<int>(0, g.height), [&](const tbb::blocked_range<int>& rows) {
        for (int y = rows.begin(); y != rows.end(); ++y)
            for (int x = 0; x < g.width; ++x) {
                const GBufferPixel& p = g.pixels[size_t(y) * g.width + x];
                float* o = out.pixel(x, y);
                glm::vec3 rgb;
                if (p.hit) {
                    rgb = shade(p);
                    o[3] = 1.0f;
                } else {
                    rgb = environmentRadiance(background, envRotation, glm::dvec3(p.rayDirection));
                    o[3] = 0.0f;
                }
                o[0] = rgb.x;
                o[1] = rgb.y;
                o[2] = rgb.z;
            }
    });
    return out;
}

// ---------------------------------------------------------------------------
// The object
// ---------------------------------------------------------------------------

RelightObject loadRelightObject(const std::string& meshPath, const std::string& transportPath) {
    RelightObject o;
    o.mesh = loadMesh(meshPath);
    const MeshFingerprint fingerprint{o.mesh.vertexCount(), meshFingerprint(o.mesh)};
    o.transport = loadTransportFile(transportPath, fingerprint);
    scaleToPhysical(o.mesh, MeshScale{.sizeMm = std::nullopt, .mmPerUnit = o.transport.mmPerUnit});
    o.eta = readTransportParameters(o.transport.parameters, transportPath).eta.value_or(1.3);
    o.box = bounds(o.mesh);
    const BoundingSphere sphere = boundingSphere(o.mesh);
    o.sphereCentre = sphere.centre;
    o.sphereRadius = sphere.radius;
    return o;
}

// ---------------------------------------------------------------------------
// Shading
// ---------------------------------------------------------------------------

TranslucentShader::TranslucentShader(const TriangleMesh& mesh, double eta, const ViewMaps* viewMaps)
    : mesh_(&mesh), eta_(eta) {
    if (!(eta > 0) || !std::isfinite(eta)) throw Error("eta", "must be positive and finite");
    if (viewMaps && viewMaps->terms > 0) {
        const int n = viewMaps->size, k = viewMaps->terms;
        const size_t texels = size_t(6) * n * n;
        if (n < 1 || viewMaps->data.size() != texels * size_t(k))
            throw Error("view maps", "inconsistent size");
        viewTerms_ = k;
        viewMaps_ = Cubemap(n, k);
        std::vector<float>& dst = viewMaps_.data();
        for (int t = 0; t < k; ++t) {
            const float* src = viewMaps->term(t);
            for (size_t i = 0; i < texels; ++i) dst[i * k + t] = src[i];
        }
    }
}

float TranslucentShader::viewTerm(int k, const glm::dvec3& wRefracted) const {
    if (k < 0 || k >= viewTerms_) return 0.0f;
    return viewMaps_.sampleBilinear(wRefracted, k);
}

glm::vec3 TranslucentShader::shade(const GBufferPixel& p, const VertexRadiance& radiance) const {
    if (!p.hit || p.triangle >= mesh_->triangles.size()) return glm::vec3(0.0f);
    const glm::uvec3 tri = mesh_->triangles[p.triangle];
    if (std::max({tri.x, tri.y, tri.z}) >= radiance.diffuse.size()) return glm::vec3(0.0f);
    const glm::dvec3 n(p.normal), wo(p.toViewer);
    const double cosO = glm::dot(n, wo);
    if (!(cosO > 0)) return glm::vec3(0.0f);  // F_t(eta, 0) = 0
    const double ft = fresnelTransmittance(eta_, cosO);
    const glm::vec3 b = p.barycentric;
    glm::dvec3 sum = glm::dvec3(b.x * radiance.diffuse[tri.x] + b.y * radiance.diffuse[tri.y] +
                                b.z * radiance.diffuse[tri.z]);
    const int terms = std::min<int>(viewTerms_, int(radiance.terms.size()));
    if (terms > 0) {
        glm::dvec3 woRefracted;
        if (refractDirection(wo, n, eta_, woRefracted)) {
            glm::dvec3 ss(0.0);
            for (int k = 0; k < terms; ++k) {
                const std::vector<glm::vec3>& t = radiance.terms[k];
                if (std::max({tri.x, tri.y, tri.z}) >= t.size()) continue;
                const double h = viewTerm(k, woRefracted);
                ss += h * glm::dvec3(b.x * t[tri.x] + b.y * t[tri.y] + b.z * t[tri.z]);
            }
            // The K-term phase (phase_factoring.h) has negative lobes where HG is small
            // (g = 0.4, cos = -1: -0.015 for 0.024); single scattering is never negative.
            sum += glm::max(ss, glm::dvec3(0.0));
        }
    }
    // Truncated wavelets can undershoot too; radiance is never negative.
    return glm::vec3(ft * glm::max(sum, glm::dvec3(0.0)));
}

// ---------------------------------------------------------------------------
// Turntable
// ---------------------------------------------------------------------------

Camera turntableCamera(const Camera& camera, const glm::dvec3& pivot, double degrees) {
    // The object's placement M = T(pivot) Ry(degrees) T(-pivot); the camera in the
    // object's frame is M^-1 applied to the camera.
    const glm::dmat3 inverse = rotationY(-degrees);
    Camera c = camera;
    c.eye = pivot + inverse * (camera.eye - pivot);
    c.target = pivot + inverse * (camera.target - pivot);
    c.up = inverse * camera.up;
    return c;
}

// ---------------------------------------------------------------------------
// Specular layer
// ---------------------------------------------------------------------------

glm::vec3 specularReflection(const GBufferPixel& p, double eta, const Image& prefiltered,
                             const glm::dmat3& rotation) {
    if (!p.hit) return glm::vec3(0.0f);
    const glm::dvec3 n(p.normal), wo(p.toViewer);
    const double cosO = glm::dot(n, wo);
    if (!(cosO > 0)) return glm::vec3(0.0f);
    const glm::dvec3 mirror = 2.0 * cosO * n - wo;  // reflect(-w_o, n)
    const double fr = fresnelReflectance(eta, cosO);
    return glm::vec3(fr * glm::dvec3(environmentRadiance(prefiltered, rotation, mirror)));
}

Image prefilterEnvironment(const Image& latlong, int factor) {
    if (latlong.empty() || !latlong.consistent()) throw Error("environment", "empty or inconsistent image");
    if (factor < 1 || latlong.width % factor != 0 || latlong.height % factor != 0)
        throw Error("specular pre-filter", "factor " + std::to_string(factor) + " does not divide the " +
                                               std::to_string(latlong.width) + " x " +
                                               std::to_string(latlong.height) + " map");
    if (factor == 1) return latlong;
    const int w = latlong.width / factor, h = latlong.height / factor, ch = latlong.channels;
    Image out(w, h, ch, 0.0f);
    tbb::parallel_for(0, h, [&](int y) {
        std::vector<double> sum(size_t(w) * ch, 0.0);
        double weight = 0;
        for (int sy = y * factor; sy < (y + 1) * factor; ++sy) {
            const double omega = latLongPixelSolidAngle(sy, latlong.width, latlong.height);
            weight += omega * factor;
            for (int sx = 0; sx < latlong.width; ++sx) {
                const float* v = latlong.pixel(sx, sy);
                double* acc = &sum[size_t(sx / factor) * ch];
                for (int c = 0; c < ch; ++c) acc[c] += omega * v[c];
            }
        }
        for (int x = 0; x < w; ++x)
            for (int c = 0; c < ch; ++c) out.at(x, y, c) = float(sum[size_t(x) * ch + c] / weight);
    });
    return out;
}

}  // namespace prt
