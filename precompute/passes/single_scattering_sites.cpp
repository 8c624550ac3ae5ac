#include "precompute/passes/single_scattering_sites.h"

#include "common/error.h"
#include "common/point_grid.h"

#include <algorithm>
#include <cmath>
#include <utility>

namespace prt {

namespace {

constexpr float kNormalLimit = 0.5f;  // cos 60 degrees

bool unitNormal(const glm::vec3& n) { return std::abs(glm::dot(n, n) - 1.0f) < 1e-3f; }

}  // namespace

std::vector<uint32_t> SingleScatteringSites::sitesOf(size_t first, size_t end) const {
    const std::pair<size_t, size_t> range{first, end};
    return sitesOf(std::span(&range, 1));
}

std::vector<uint32_t> SingleScatteringSites::sitesOf(std::span<const std::pair<size_t, size_t>> ranges) const {
    std::vector<uint32_t> out;
    for (const auto& [first, end] : ranges)
        out.insert(out.end(), blendSite.begin() + std::ptrdiff_t(offset[first]),
                   blendSite.begin() + std::ptrdiff_t(offset[end]));
    std::sort(out.begin(), out.end());
    out.erase(std::unique(out.begin(), out.end()), out.end());
    return out;
}

SingleScatteringSites chooseSingleScatteringSites(std::span<const glm::vec3> positions,
                                                  std::span<const glm::vec3> normals, double spacing) {
    if (!(spacing >= 0.0) || !std::isfinite(spacing))
        throw Error("--ss-site-spacing", "must be a non-negative number of mm");
    if (positions.size() != normals.size()) throw Error("single scattering sites", "one normal per vertex needed");
    const size_t n = positions.size();
    SingleScatteringSites s;
    s.offset.resize(n + 1);
    if (spacing == 0.0) {
        s.site.resize(n);
        s.blendSite.resize(n);
        s.blendWeight.assign(n, 1.0f);
        for (uint32_t v = 0; v < n; ++v) s.site[v] = s.blendSite[v] = s.offset[v] = v;
        s.offset[n] = uint32_t(n);
        return s;
    }

    // Greedy in vertex order: v is a site unless an earlier site covers it. Covering
    // from each new site forward gives the same sites as asking each vertex about the
    // sites before it.
    const PointGrid vertexGrid(positions, spacing);
    constexpr uint32_t kNone = UINT32_MAX;
    std::vector<uint32_t> coveredBy(n, kNone);  // vertex -> the first site within reach
    std::vector<uint8_t> isSite(n, 0);
    for (uint32_t v = 0; v < n; ++v) {
        if (coveredBy[v] != kNone) continue;
        const uint32_t k = uint32_t(s.site.size());
        s.site.push_back(v);
        coveredBy[v] = k;
        isSite[v] = 1;
        if (!unitNormal(normals[v])) continue;
        vertexGrid.forEachWithin(positions[v], spacing, [&](uint32_t u, float) {
            if (u > v && coveredBy[u] == kNone && unitNormal(normals[u]) &&
                glm::dot(normals[u], normals[v]) > kNormalLimit)
                coveredBy[u] = k;
        });
    }

    std::vector<glm::vec3> sitePositions(s.site.size());
    for (size_t k = 0; k < s.site.size(); ++k) sitePositions[k] = positions[s.site[k]];
    const double radius = 2.0 * spacing;
    const PointGrid siteGrid(sitePositions, radius);
    const float invR2 = float(1.0 / (radius * radius));
    std::vector<std::pair<uint32_t, float>> blend;
    for (uint32_t v = 0; v < n; ++v) {
        blend.clear();
        if (isSite[v] && !unitNormal(normals[v])) {
            blend.push_back({coveredBy[v], 1.0f});
        } else {
            siteGrid.forEachWithin(positions[v], radius, [&](uint32_t k, float d2) {
                const uint32_t u = s.site[k];
                if (!unitNormal(normals[u])) return;
                const float facing = glm::dot(normals[u], normals[v]) - kNormalLimit;
                if (!(facing > 0.0f)) return;
                const float t = 1.0f - d2 * invR2;
                const float w = t * t * facing;
                if (w > 0.0f) blend.push_back({k, w});
            });
            if (blend.empty())  // only if rounding made the covering site's weight vanish
                blend.push_back({coveredBy[v], 1.0f});
        }
        std::sort(blend.begin(), blend.end());
        float sum = 0.0f;
        for (const auto& b : blend) sum += b.second;
        s.offset[v] = uint32_t(s.blendSite.size());
        for (const auto& b : blend) {
            s.blendSite.push_back(b.first);
            s.blendWeight.push_back(b.second / sum);
        }
    }
    s.offset[n] = uint32_t(s.blendSite.size());
    return s;
}

}  // namespace prt
