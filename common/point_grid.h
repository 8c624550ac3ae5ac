#pragma once
// PointGrid: points bucketed in a hashed uniform grid, for neighbour queries over a
// fixed point set (samples, vertices). Built once in O(n log n); a query visits the
// buckets of the cells it overlaps. Positions are borrowed (they must outlive the grid
// and not change). Cell size in the positions' units (mm), > 0 and finite; cell
// coordinates must stay within +-2^20 (a mesh of 30 mm at a cell of 1e-4 mm fits).

#include <glm/glm.hpp>

#include <cmath>
#include <cstdint>
#include <span>
#include <unordered_map>
#include <utility>
#include <vector>

namespace prt {

class PointGrid {
public:
    PointGrid(std::span<const glm::vec3> positions, double cell);

    double cell() const { return cell_; }
    glm::ivec3 coords(const glm::vec3& p) const {
        return glm::ivec3(int(std::floor(p.x * inverse_)), int(std::floor(p.y * inverse_)),
                          int(std::floor(p.z * inverse_)));
    }
    // fn(i) for every point i in cell c, in increasing index order.
    template <class Fn>
    void forEachInCell(const glm::ivec3& c, Fn&& fn) const {
        const auto it = buckets_.find(key(c));
        if (it == buckets_.end()) return;
        for (uint32_t k = it->second.first; k < it->second.second; ++k) fn(order_[k]);
    }
    // fn(i, d2) for every point i with |positions[i] - p|^2 <= radius^2 (d2 that squared
    // distance), cell by cell (not in index order).
    template <class Fn>
    void forEachWithin(const glm::vec3& p, double radius, Fn&& fn) const {
        const glm::ivec3 lo = coords(p - glm::vec3(float(radius))), hi = coords(p + glm::vec3(float(radius)));
        const float r2 = float(radius * radius);
        for (int x = lo.x; x <= hi.x; ++x)
            for (int y = lo.y; y <= hi.y; ++y)
                for (int z = lo.z; z <= hi.z; ++z)
                    forEachInCell(glm::ivec3(x, y, z), [&](uint32_t i) {
                        const glm::vec3 d = positions_[i] - p;
                        const float d2 = glm::dot(d, d);
                        if (d2 <= r2) fn(i, d2);
                    });
    }

private:
    static uint64_t key(const glm::ivec3& c) {
        const auto part = [](int v) { return uint64_t(uint32_t(v + (1 << 20)) & 0x1FFFFFu); };
        return part(c.x) | (part(c.y) << 21) | (part(c.z) << 42);
    }

    std::span<const glm::vec3> positions_;
    double cell_, inverse_;
    std::vector<uint32_t> order_;  // point indices sorted by cell key, then index
    std::unordered_map<uint64_t, std::pair<uint32_t, uint32_t>> buckets_;  // key -> [first, end) in order_
};

}  // namespace prt
