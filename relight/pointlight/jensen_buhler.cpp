#include "relight/pointlight/jensen_buhler.h"

#include <Eigen/Core>
#include <tbb/enumerable_thread_specific.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>
#include <string>

#include "common/error.h"

namespace prt {

// ---------------------------------------------------------------------------
// Dipole, three channels
// ---------------------------------------------------------------------------

DipoleRGB::DipoleRGB(const Material& m) {
    for (int lane = 0; lane < 8; ++lane) {
        z2_[lane] = 1.0f;
        sigma_[lane] = 0.0f;
        k_[lane] = 0.0f;
    }
    for (int c = 0; c < 3; ++c) {
        channel[c] = makeDipoleChannel(m, c);
        const DipoleChannel& d = channel[c];
        for (int s = 0; s < 2; ++s) {
            const double z = s == 0 ? d.zr : d.zv;
            z2_[4 * s + c] = float(z * z);
            sigma_[4 * s + c] = float(d.sigmaTr);
            k_[4 * s + c] = float(d.alphaPrime * z / (4.0 * std::numbers::pi));
        }
    }
}

glm::dvec3 DipoleRGB::rd(double r2) const {
    // dipoleRd (bssrdf.h) with d_r and d_v from r^2 directly:
    // alpha'/(4 pi) sum_{s in r, v} z_s (1 + sigma_tr d_s) e^(-sigma_tr d_s) / d_s^3.
    using Lanes = Eigen::Array<float, 8, 1>;
    const Lanes d2 = Eigen::Map<const Lanes, Eigen::Aligned32>(z2_) + float(r2);
    const Lanes d = d2.sqrt();
    const Lanes sd = Eigen::Map<const Lanes, Eigen::Aligned32>(sigma_) * d;
    const Lanes v = Eigen::Map<const Lanes, Eigen::Aligned32>(k_) * (1.0f + sd) * (-sd).exp() / (d2 * d);
    return glm::dvec3(double(v[0]) + double(v[4]), double(v[1]) + double(v[5]), double(v[2]) + double(v[6]));
}

// ---------------------------------------------------------------------------
// Octree
// ---------------------------------------------------------------------------

bool IrradianceOctree::Node::cellContains(const glm::dvec3& x) const {
    return x.x >= cellLo.x && x.y >= cellLo.y && x.z >= cellLo.z && x.x <= cellLo.x + cellSize &&
           x.y <= cellLo.y + cellSize && x.z <= cellLo.z + cellSize;
}

IrradianceOctree::IrradianceOctree(const IrradianceSamples& in, const OctreeOptions& options) {
    const size_t n = in.positions.size();
    if (n == 0) throw Error("octree", "no irradiance samples");
    if (in.areas.size() != n || in.irradiance.size() != n) throw Error("octree", "inconsistent sample arrays");
    if (n >= size_t(0xffffffffu)) throw Error("octree", "too many samples");
    if (options.leafSize < 1) throw Error("octree", "leaf size must be at least 1");
    // The traversal stack holds at most 7 per level + 8 entries (jensen_buhler.h).
    if (options.maxDepth < 0 || options.maxDepth > 64) throw Error("octree", "maximum depth must be in [0, 64]");

    samples_.resize(n);
    order_.resize(n);
    glm::dvec3 lo(std::numeric_limits<double>::infinity()), hi(-std::numeric_limits<double>::infinity());
    for (size_t i = 0; i < n; ++i) {
        const glm::vec3 p = in.positions[i];
        const glm::vec3 e = in.irradiance[i];
        const float a = in.areas[i];
        if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
            throw Error("octree", "sample " + std::to_string(i) + " has a non-finite position");
        if (!(a >= 0.0f) || !std::isfinite(a))
            throw Error("octree", "sample " + std::to_string(i) + " has a negative or non-finite area");
        for (int c = 0; c < 3; ++c)
            if (!(e[c] >= 0.0f) || !std::isfinite(e[c]))
                throw Error("octree", "sample " + std::to_string(i) + " has a negative or non-finite irradiance");
        samples_[i] = Sample{p, a, e};
        order_[i] = uint32_t(i);
        lo = glm::min(lo, glm::dvec3(p));
        hi = glm::max(hi, glm::dvec3(p));
    }

    // The root cell: the bounding cube, a hair larger so that no sample sits exactly on
    // its upper faces (octants take the upper half for >= centre).
    const glm::dvec3 extent = hi - lo;
    const double size = std::max({extent.x, extent.y, extent.z});
    const double pad = 1e-6 * size + 1e-9 * std::max(1.0, glm::length(glm::abs(lo) + glm::abs(hi)));
    nodes_.reserve(2 * (n / size_t(options.leafSize)) + 8);
    nodes_.push_back(Node{});
    nodes_[0].cellLo = lo - glm::dvec3(pad);
    nodes_[0].cellSize = size + 2.0 * pad;
    build(0, 0, uint32_t(n), 0, options);
}

// Builds node `nodeIndex` (whose cell is already set) over samples [begin, end) and
// records the tree depth. Aggregates are computed bottom-up: leaves from
// their samples, inner nodes from their children (area sums, area-weighted means).
void IrradianceOctree::build(uint32_t nodeIndex, uint32_t begin, uint32_t end, int depth,
                                 const OctreeOptions& options) {
    {
        Node& node = nodes_[nodeIndex];
        node.firstSample = begin;
        node.sampleCount = end - begin;
        node.depth = uint32_t(depth);
    }
    depth_ = std::max(depth_, depth);
    const uint32_t count = end - begin;
    const bool leaf = count <= uint32_t(options.leafSize) || depth >= options.maxDepth;

    if (!leaf) {
        const glm::dvec3 cellLo = nodes_[nodeIndex].cellLo;
        const double half = 0.5 * nodes_[nodeIndex].cellSize;
        const glm::dvec3 centre = cellLo + glm::dvec3(half);
        auto octant = [&](const Sample& s) {
            return (double(s.position.x) >= centre.x ? 1 : 0) | (double(s.position.y) >= centre.y ? 2 : 0) |
                   (double(s.position.z) >= centre.z ? 4 : 0);
        };
        // Stable counting sort of the range by octant (deterministic order).
        std::array<uint32_t, 9> offset{};
        for (uint32_t k = begin; k < end; ++k) ++offset[octant(samples_[k]) + 1];
        for (int o = 0; o < 8; ++o) offset[o + 1] += offset[o];
        std::vector<Sample> sorted(count);
        std::vector<uint32_t> sortedOrder(count);
        std::array<uint32_t, 8> cursor;
        std::copy(offset.begin(), offset.begin() + 8, cursor.begin());
        for (uint32_t k = begin; k < end; ++k) {
            const uint32_t dst = cursor[octant(samples_[k])]++;
            sorted[dst] = samples_[k];
            sortedOrder[dst] = order_[k];
        }
        std::copy(sorted.begin(), sorted.end(), samples_.begin() + begin);
        std::copy(sortedOrder.begin(), sortedOrder.end(), order_.begin() + begin);

        uint32_t children = 0;
        for (int o = 0; o < 8; ++o) children += offset[o + 1] > offset[o] ? 1 : 0;
        const uint32_t first = uint32_t(nodes_.size());
        nodes_.resize(nodes_.size() + children);  // may reallocate: no references held across
        nodes_[nodeIndex].firstChild = first;
        nodes_[nodeIndex].childCount = children;
        uint32_t c = 0;
        for (int o = 0; o < 8; ++o) {
            if (offset[o + 1] == offset[o]) continue;
            Node& child = nodes_[first + c];
            child.cellSize = half;
            child.cellLo = cellLo + glm::dvec3((o & 1) ? half : 0.0, (o & 2) ? half : 0.0, (o & 4) ? half : 0.0);
            ++c;
        }
        c = 0;
        for (int o = 0; o < 8; ++o) {
            if (offset[o + 1] == offset[o]) continue;
            build(first + c, begin + offset[o], begin + offset[o + 1], depth + 1, options);
            ++c;
        }
    }

    // Aggregates: A = sum A_i, p = sum A_i x_i / A, E = sum A_i E_i / A (area weights).
    Node& node = nodes_[nodeIndex];
    double area = 0.0;
    glm::dvec3 ap(0.0), ae(0.0), plainP(0.0), plainE(0.0);
    double weight = 0.0;
    if (node.leaf()) {
        for (uint32_t k = begin; k < end; ++k) {
            const Sample& s = samples_[k];
            area += s.area;
            ap += double(s.area) * glm::dvec3(s.position);
            ae += double(s.area) * glm::dvec3(s.irradiance);
            plainP += glm::dvec3(s.position);
            plainE += glm::dvec3(s.irradiance);
        }
        weight = double(count);
    } else {
        for (uint32_t c = 0; c < node.childCount; ++c) {
            const Node& child = nodes_[node.firstChild + c];
            area += child.area;
            ap += child.area * child.position;
            ae += child.area * child.irradiance;
            plainP += double(child.sampleCount) * child.position;
            plainE += double(child.sampleCount) * child.irradiance;
        }
        weight = double(count);
    }
    node.area = area;
    if (area > 0.0) {
        node.position = ap / area;
        node.irradiance = ae / area;
    } else {
        // Zero area: no flux either way; plain means keep the position meaningful.
        node.position = plainP / weight;
        node.irradiance = plainE / weight;
    }
}

size_t IrradianceOctree::leafCount() const {
    size_t n = 0;
    for (const Node& node : nodes_) n += node.leaf() ? 1 : 0;
    return n;
}

// ---------------------------------------------------------------------------
// Renderer
// ---------------------------------------------------------------------------

void validateEpsilon(double epsilon) {
    if (!std::isfinite(epsilon) || epsilon < 0.0)
        throw Error("--epsilon", "must be finite and >= 0 (0 = brute force), got " + std::to_string(epsilon));
}

namespace {
Material validated(const Material& m) {
    validateMaterial(m);
    return m;
}
}  // namespace

void adoptCells(std::optional<SampleCells>& cells, const IrradianceOctree& tree, const Material& material) {
    if (!cells) return;
    if (cells->sampleCount() != tree.samples().size())
        throw Error("sample cells", "cells over " + std::to_string(cells->sampleCount()) + " samples, octree over " +
                                        std::to_string(tree.samples().size()));
    const Material& held = cells->material();
    if (held.sigmaA != material.sigmaA || held.sigmaSPrime != material.sigmaSPrime || held.eta != material.eta)
        cells->setMaterial(material);
}

JensenBuhler::JensenBuhler(const Material& material, IrradianceOctree tree, const JensenBuhlerOptions& options,
                           std::optional<SampleCells> cells)
    : material_(validated(material)), dipole_(material_), tree_(std::move(tree)), options_(options),
      cells_(std::move(cells)) {
    validateEpsilon(options.epsilon);
    adoptCells(cells_, tree_, material_);
}

void JensenBuhler::setMaterial(const Material& material) {
    validateMaterial(material);
    requireIrradianceEta(material_.eta, material.eta);
    if (cells_) cells_->setMaterial(material);
    material_ = material;
    dipole_ = DipoleRGB(material_);
}

glm::dvec3 JensenBuhler::exitance(const glm::dvec3& x, size_t* terms) const {
    glm::dvec3 m(0.0);
    const glm::vec3 xf(x);
    const SampleCells* cells = this->cells();
    const size_t n = tree_.traverse(
        x, options_.epsilon,
        [&](const glm::dvec3& p, double area, const glm::dvec3& e, uint32_t k) {
            const glm::dvec3 d = x - p;
            m += exitanceTerm(cells, tree_, k, xf, area, dipole_.rd(glm::dot(d, d)), e);  // Keng Eq. 4
        },
        cells ? cells->nearRadius() : 0.0);
    if (terms) *terms = n;
    return m;
}

glm::vec3 JensenBuhler::radiance(const GBufferPixel& pixel, size_t* terms) const {
    if (terms) *terms = 0;
    if (!pixel.hit) return glm::vec3(0.0f);
    const double cosO = glm::dot(glm::dvec3(pixel.normal), glm::dvec3(pixel.toViewer));
    const double fo = outgoingTransmittance(options_.fresnel, material_.eta, std::max(0.0, cosO));
    if (fo == 0.0) return glm::vec3(0.0f);  // nothing leaves toward the viewer: skip the sum
    return glm::vec3(fo / std::numbers::pi * exitance(glm::dvec3(pixel.position), terms));
}

Image JensenBuhler::render(const GBuffer& g, JensenBuhlerStats* stats) const {
    tbb::enumerable_thread_specific<uint64_t> terms(0), pixels(0);
    Image image = compose(g, Image(), glm::dmat3(1.0), [&](const GBufferPixel& p) {
        size_t n = 0;
        const glm::vec3 l = radiance(p, &n);
        terms.local() += n;
        pixels.local() += 1;
        return l;
    });
    if (stats) {
        stats->terms = 0;
        stats->pixels = 0;
        for (uint64_t t : terms) stats->terms += t;
        for (uint64_t p : pixels) stats->pixels += p;
    }
    return image;
}

glm::dvec3 bruteForceExitance(const IrradianceSamples& samples, const Material& material, const glm::dvec3& x) {
    const DipoleRGB dipole(material);
    glm::dvec3 m(0.0);
    for (size_t i = 0; i < samples.size(); ++i) {
        const glm::dvec3 d = x - glm::dvec3(samples.positions[i]);
        m += double(samples.areas[i]) * dipole.rd(glm::dot(d, d)) * glm::dvec3(samples.irradiance[i]);
    }
    return m;
}

}  // namespace prt
