#include "common/point_grid.h"

#include "common/error.h"

#include <algorithm>
#include <string>

namespace prt {

PointGrid::PointGrid(std::span<const glm::vec3> positions, double cell)
    : positions_(positions), cell_(cell), inverse_(1.0 / cell) {
    if (!(cell > 0.0) || !std::isfinite(cell)) throw Error("point grid", "the cell size must be positive and finite");
    std::vector<std::pair<uint64_t, uint32_t>> keyed(positions.size());
    for (uint32_t i = 0; i < positions.size(); ++i) keyed[i] = {key(coords(positions[i])), i};
    std::sort(keyed.begin(), keyed.end());
    order_.resize(keyed.size());
    buckets_.reserve(keyed.size());
    for (size_t k = 0; k < keyed.size(); ++k) {
        order_[k] = keyed[k].second;
        auto [it, inserted] = buckets_.try_emplace(keyed[k].first, uint32_t(k), uint32_t(k + 1));
        if (!inserted) it->second.second = uint32_t(k + 1);
    }
}

}  // namespace prt
