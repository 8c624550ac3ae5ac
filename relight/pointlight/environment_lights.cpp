#include "relight/pointlight/environment_lights.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "common/envmap.h"
#include "common/error.h"
#include "common/materials.h"
#include "common/transport_params.h"

namespace prt {

void validateSunSplitOptions(const SunSplitOptions& options) {
    if (!std::isfinite(options.threshold) || options.threshold <= 0.0)
        throw Error("--sun-threshold", "must be a finite number > 0 (times the environment's mean luminance), got " +
                                           formatParameter(options.threshold));
    if (!std::isfinite(options.cellDegrees) || options.cellDegrees <= 0.0 || options.cellDegrees > 90.0)
        throw Error("--sun-cell", "must be in (0, 90] degrees, got " + formatParameter(options.cellDegrees));
}

SunSplit splitSun(const Image& latLong, const SunSplitOptions& options) {
    validateSunSplitOptions(options);
    if (latLong.empty() || !latLong.consistent() || latLong.channels != 3)
        throw Error("environment", "the sun split needs a non-empty RGB lat-long image");
    const int W = latLong.width, H = latLong.height;
    if (W != 2 * H)
        throw Error("environment", "a lat-long map must be twice as wide as high, got " + std::to_string(W) + " x " +
                                       std::to_string(H));
    for (float v : latLong.pixels)
        if (!std::isfinite(v) || v < 0.0f)
            throw Error("environment", "the sun split needs finite, non-negative radiance");

    SunSplit split;
    double integral = 0.0;
    for (int y = 0; y < H; ++y) {
        double row = 0.0;
        for (int x = 0; x < W; ++x) {
            const float* p = latLong.pixel(x, y);
            row += luminance(glm::dvec3(p[0], p[1], p[2]));
        }
        integral += row * latLongPixelSolidAngle(y, W, H);
    }
    split.meanLuminance = integral / (4.0 * 3.14159265358979323846);
    split.thresholdLuminance = options.threshold * split.meanLuminance;
    split.cellTexels = std::clamp(int(std::lround(options.cellDegrees / (360.0 / W))), 1, H);
    split.residual = latLong;

    // One accumulator per cell; cells of the last row and column may be narrower.
    const int n = split.cellTexels;
    const int cellsX = (W + n - 1) / n, cellsY = (H + n - 1) / n;
    struct Cell {
        glm::dvec3 flux[3] = {glm::dvec3(0.0), glm::dvec3(0.0), glm::dvec3(0.0)};  // sum excess_c Omega d, per channel
        glm::dvec3 direction{0.0};  // sum Y_excess Omega d
        bool any = false;
    };
    std::vector<Cell> cells(size_t(cellsX) * size_t(cellsY));
    const double tau = split.thresholdLuminance;
    double excessIntegral = 0.0;
    if (tau > 0.0) {
        for (int y = 0; y < H; ++y) {
            const double omega = latLongPixelSolidAngle(y, W, H);
            for (int x = 0; x < W; ++x) {
                float* r = split.residual.pixel(x, y);
                const glm::dvec3 L(r[0], r[1], r[2]);
                const double Y = luminance(L);
                if (!(Y > tau)) continue;
                ++split.texelsAbove;
                const double s = tau / Y;
                for (int c = 0; c < 3; ++c) r[c] = float(L[c] * s);
                // From the stored (float) residual, so residual + excess = L exactly;
                // a float of L s <= L never exceeds L, so the excess is >= 0.
                const glm::dvec3 excess = L - glm::dvec3(r[0], r[1], r[2]);
                Cell& cell = cells[size_t(y / n) * size_t(cellsX) + size_t(x / n)];
                const glm::dvec3 d = latLongPixelDirection(x, y, W, H);
                for (int c = 0; c < 3; ++c) cell.flux[c] += excess[c] * omega * d;
                const double yExcess = luminance(excess) * omega;
                cell.direction += yExcess * d;
                cell.any = cell.any || excess.r > 0.0 || excess.g > 0.0 || excess.b > 0.0;
                excessIntegral += yExcess;
            }
        }
    }
    for (size_t k = 0; k < cells.size(); ++k) {
        const Cell& cell = cells[k];
        if (!cell.any) continue;
        const int cx = int(k % size_t(cellsX)), cy = int(k / size_t(cellsX));
        // A cell's excess of (near-)zero luminance still has a direction: its centre texel's.
        const glm::dvec3 d = glm::normalize(glm::length(cell.direction) > 0.0
                                                ? cell.direction
                                                : latLongPixelDirection(std::min(cx * n + n / 2, W - 1),
                                                                        std::min(cy * n + n / 2, H - 1), W, H));
        // What a surface facing d receives from the cell's texels (cosine-weighted).
        glm::dvec3 irradiance(0.0);
        for (int c = 0; c < 3; ++c) irradiance[c] = std::max(0.0, glm::dot(cell.flux[c], d));
        split.lights.push_back(directionalLight(d, irradiance,
                                                "sun split cell " + std::to_string(cx) + "," + std::to_string(cy)));
    }
    split.lightFraction = integral > 0.0 ? excessIntegral / integral : 0.0;
    return split;
}

std::vector<Light> rotatedLights(const std::vector<Light>& lights, const glm::dmat3& rotation) {
    std::vector<Light> out = lights;
    for (Light& l : out) {
        l.direction = rotation * l.direction;
        l.position = rotation * l.position;
    }
    return out;
}

}  // namespace prt
