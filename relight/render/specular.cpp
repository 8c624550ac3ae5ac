#include "relight/render/specular.h"

#include <tbb/parallel_for.h>

#include <string>
#include <vector>

#include "common/bssrdf.h"
#include "common/envmap.h"
#include "common/error.h"

namespace prt {

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
