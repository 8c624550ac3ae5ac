#include "relight/render/gbuffer.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "common/envmap.h"
#include "common/error.h"

namespace prt {

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

}  // namespace prt
