#pragma once
// Single-scattering sites: the vertices at which single scattering is computed when
// neighbouring vertices share it (SingleScatteringOptions::siteSpacing;
// docs/single-scattering.md, "Sites").
//
// Sites are chosen greedily in vertex order: a vertex becomes a site unless a site
// chosen before it lies within `spacing` (mm) with a normal within 60 degrees of its own
// (n_v . n_s > 1/2), so the two sides of a sheet thinner than the spacing keep sites of
// their own. Every vertex then blends the sites within 2 x spacing whose normals are
// within 60 degrees of its own:
//
//     T(x_v) ~ sum_s w_vs T(x_s),   w_vs proportional to (1 - d^2 / (2 h)^2)^2 (n_v . n_s - 1/2),
//
// normalised to sum 1 (d = |x_v - x_s|, h = spacing, unit normals). The blend holds at
// least the site that kept v from being one (d <= h); a site blends its neighbours too,
// so the transport is low-pass filtered over about one spacing: the reuse's bias,
// measured in the docs. A vertex without a unit normal is its own site, alone.
// spacing 0: every vertex is a site, blended with weight 1 from itself alone.
//
// Deterministic (depends only on the positions, normals and spacing), so shards of a
// job choose the same sites. Throws prt::Error on a negative or non-finite spacing or
// mismatched arrays.

#include <glm/glm.hpp>

#include <cstddef>
#include <cstdint>
#include <span>
#include <utility>
#include <vector>

namespace prt {

struct SingleScatteringSites {
    std::vector<uint32_t> site;         // vertex index of each site, increasing
    // Per vertex v its blend: sites blendSite[offset[v] .. offset[v + 1]) (indices into
    // `site`, increasing) with weights blendWeight[...] (> 0, summing to 1).
    std::vector<uint32_t> offset;
    std::vector<uint32_t> blendSite;
    std::vector<float> blendWeight;

    size_t vertexCount() const { return offset.empty() ? 0 : offset.size() - 1; }
    // The sites that vertices [first, end) blend, increasing (indices into `site`).
    std::vector<uint32_t> sitesOf(size_t first, size_t end) const;
    // The same for the vertices of several ranges, each site once.
    std::vector<uint32_t> sitesOf(std::span<const std::pair<size_t, size_t>> ranges) const;
};

SingleScatteringSites chooseSingleScatteringSites(std::span<const glm::vec3> positions,
                                                  std::span<const glm::vec3> normals, double spacing);

}  // namespace prt
