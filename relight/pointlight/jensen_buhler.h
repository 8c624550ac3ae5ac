#pragma once
// The Jensen-Buhler hierarchical renderer for point and directional lights (Jensen and
// Buhler 2002, "A rapid hierarchical rendering technique for translucent materials";
// the baseline of Keng et al. 2006 section 3.4 and their Table 1; SPEC section 9).
//
// WHAT IS COMPUTED. Pass 1 (point_lights.h) gives irradiance samples: positions x_i
// (mm), areas A_i (mm^2) and transmitted irradiances E^_i (W/m^2, RGB). The exitance
// at a surface point x is the cubature of Keng Eq. 4 (S in their notation), per colour
// channel c with the dipole profile R_d^c of the material (bssrdf.h, mm^-2):
//
//     M^c(x) = sum_i A_i R_d^c(|x - x_i|) E^_i^c                       [W/m^2]
//
// With SampleCells (sample_cells.h; prt-pointlight's --near-field) the term of a sample
// whose cell reaches the near field of x is R_d integrated over that cell instead,
// w_i(x) E^_i, and no node within the cells' near radius of x is used whole: the point
// rule above does not converge where the samples lie a kernel width apart or more.
//
// and the radiance toward the viewer w_o at x with shading normal n is
//
//     L(x, w_o) = F_out(n . w_o) M(x) / pi                             [W/(m^2 sr)]
//
// with F_out = outgoingTransmittance(model, eta, .) (point_lights.h): F_t(eta, n . w_o)
// for the product's exact Fresnel, 1 for Keng's Eq. 3.
//
// THE OCTREE (IrradianceOctree). Cubic cells; the root is the bounding cube of the
// samples. A cell holding more than leafSize samples is split into its 8 octants
// (only non-empty children are stored), down to maxDepth (the depth guard for
// coincident samples: a cell at maxDepth is a leaf whatever its count). Every node
// stores
//   - A_node = sum A_i                     total area (double),
//   - p_node = sum A_i x_i / A_node        AREA-weighted mean position,
//   - E_node = sum A_i E^_i / A_node       AREA-weighted mean irradiance (RGB),
// so that A_node E_node = sum A_i E^_i: the node's cluster carries exactly the flux of
// its samples. (A plain mean of E over samples of unequal area is the SPEC's
// "cluster irradiance averaged without area weights" trap; face-centroid samples have
// very unequal areas.) A node of zero total area uses the plain means.
//
// TRAVERSAL (Jensen-Buhler's solid-angle criterion). From the root: a node is used
// whole, contributing A_node R_d(|x - p_node|) E_node, when x is not inside its cell
// and A_node / |x - p_node|^2 < epsilon (evaluated as A_node < epsilon |x - p_node|^2);
// otherwise its children are visited, and a leaf that is not used whole contributes
// its samples one by one. epsilon = 0 never uses a node whole: the result is the
// brute-force sum in another order (equal to float rounding; the sums are in double).
// Larger epsilon means fewer, coarser terms; 0.05 is the default (as the
// precompute's kd-tree, precompute/passes/multiple_scattering.h).
//
// MATERIAL. The octree (positions, areas, irradiance) depends on the lights and on eta
// only; the material enters through R_d alone. setMaterial replaces the dipole
// constants (DipoleRGB) and keeps the tree, so it costs microseconds (plus the
// rebuild of the cells' quadrature when there are cells), and a renderer
// after setMaterial(B) renders exactly as one constructed with B. eta is fixed at
// construction (the tree's transmitted irradiance was computed with it): another eta is
// refused (requireIrradianceEta, point_lights.h). A size change is a material change
// (common/material_edit.h, scaledMaterial).
//
// Threads: the octree is immutable after construction; every query is const and may
// run concurrently (setMaterial is not: call it between renders). Construction is serial and deterministic; render() is parallel over
// rows and deterministic (every pixel is summed serially in a fixed order).

#include <glm/glm.hpp>

#include <cstddef>
#include <cstdint>
#include <optional>
#include <type_traits>
#include <vector>

#include "common/bssrdf.h"
#include "common/image.h"
#include "relight/render/gbuffer.h"
#include "relight/pointlight/point_lights.h"
#include "relight/pointlight/sample_cells.h"

namespace prt {

// The three channels of a material's dipole, evaluated together (one distance, three
// profiles). rd(r2) takes the SQUARED distance (mm^2), which is what the traversal
// has, and returns R_d per channel (mm^-2) as dipoleRd(material, sqrt(r2)) does, but
// in single precision (relative error below 1e-6) and with the six exponentials (3
// channels x real and virtual source) in one SIMD evaluation (Eigen's vectorised
// exp), since exp dominates the renderer's time (docs/point-lights.md, "The
// Jensen-Buhler renderer"). Sums over terms stay in double.
struct DipoleRGB {
    DipoleChannel channel[3];

    explicit DipoleRGB(const Material& m);
    glm::dvec3 rd(double r2) const;

private:
    // Lanes 0-2: the real source of R, G, B; lanes 4-6: the virtual source; lanes 3
    // and 7 are padding (factor 0). Per lane: z^2, sigma_tr and alpha' z / (4 pi), the
    // factor of (1 + sigma_tr d) e^(-sigma_tr d) / d^3.
    alignas(32) float z2_[8], sigma_[8], k_[8];
};

// The index traverse() passes for a node used whole.
inline constexpr uint32_t kNodeTerm = 0xffffffffu;

struct OctreeOptions {
    int leafSize = 8;   // >= 1
    int maxDepth = 24;  // >= 0 (root is depth 0)
};

class IrradianceOctree {
public:
    struct Node {
        glm::dvec3 cellLo{0.0};    // cubic cell [cellLo, cellLo + cellSize]^3, mm
        double cellSize = 0.0;
        glm::dvec3 position{0.0};    // area-weighted mean position p_node, mm
        glm::dvec3 irradiance{0.0};  // area-weighted mean irradiance E_node, W/m^2
        double area = 0.0;           // A_node, mm^2
        uint32_t firstChild = 0;     // children are nodes[firstChild, firstChild + childCount)
        uint32_t childCount = 0;     // 0 for a leaf
        uint32_t firstSample = 0;    // the node's samples are sorted [firstSample, firstSample + sampleCount)
        uint32_t sampleCount = 0;
        uint32_t depth = 0;

        bool leaf() const { return childCount == 0; }
        bool cellContains(const glm::dvec3& x) const;
        // Squared distance from x to the cell (0 inside), mm^2.
        double cellDistance2(const glm::dvec3& x) const {
            const glm::dvec3 d = glm::max(glm::max(cellLo - x, x - (cellLo + cellSize)), glm::dvec3(0.0));
            return glm::dot(d, d);
        }
    };

    // A sample as the tree stores it (in tree order, see order()).
    struct Sample {
        glm::vec3 position{0.0f};
        float area = 0.0f;
        glm::vec3 irradiance{0.0f};
    };

    // Builds the tree over samples.positions / areas / irradiance. Throws prt::Error for
    // empty or inconsistent arrays, a non-finite position, a negative or non-finite
    // area or irradiance, leafSize < 1 or maxDepth < 0.
    explicit IrradianceOctree(const IrradianceSamples& samples, const OctreeOptions& options = {});

    const std::vector<Node>& nodes() const { return nodes_; }
    const Node& root() const { return nodes_.front(); }
    // Samples in tree order: the samples of every node are a contiguous range.
    const std::vector<Sample>& samples() const { return samples_; }
    // order()[k] = index in the input of the k-th sample in tree order.
    const std::vector<uint32_t>& order() const { return order_; }
    int depth() const { return depth_; }
    size_t leafCount() const;

    // Calls term(position, area, irradiance, k) for every term of the hierarchical sum
    // at x with this epsilon (nodes used whole, then samples of leaves that are not), in
    // a fixed order; k is the tree-order index of a sample term (order()[k] its input
    // index) and kNodeTerm for a node used whole (a term taking three arguments is
    // called without k). With nearRadius > 0 a node whose cell comes closer to x than
    // that is never used whole (its samples have near parts: sample_cells.h). Returns the
    // number of terms. Templated so that other evaluations (the irradiance cache's
    // gradient and spread) share the walk.
    template <class Term>
    size_t traverse(const glm::dvec3& x, double epsilon, Term&& term, double nearRadius = 0.0) const;

private:
    void build(uint32_t nodeIndex, uint32_t begin, uint32_t end, int depth, const OctreeOptions& options);

    std::vector<Node> nodes_;
    std::vector<Sample> samples_;
    std::vector<uint32_t> order_;
    int depth_ = 0;
};

struct JensenBuhlerOptions {
    double epsilon = 0.05;  // solid-angle threshold A_node / d^2, >= 0 (0 = brute force)
    FresnelModel fresnel = FresnelModel::Exact;
};

// Throws prt::Error("--epsilon", ...) unless epsilon is finite and >= 0.
void validateEpsilon(double epsilon);

struct JensenBuhlerStats {
    size_t pixels = 0;  // object pixels shaded
    uint64_t terms = 0;  // R_d evaluations (nodes + samples) summed over pixels
    double meanTerms() const { return pixels ? double(terms) / double(pixels) : 0.0; }
};

class JensenBuhler {
public:
    // The tree is taken by value (std::move it in). Validates the material and epsilon.
    // cells: the near field's cells over the same samples as the tree (sample_cells.h;
    // set to this material if they hold another); none = the point rule everywhere.
    // Throws prt::Error when the cells hold another number of samples than the tree.
    JensenBuhler(const Material& material, IrradianceOctree tree, const JensenBuhlerOptions& options = {},
                 std::optional<SampleCells> cells = std::nullopt);

    // Replaces the material, keeping the tree (see MATERIAL above). Throws prt::Error
    // for an invalid material or another eta than the constructor's (the renderer is
    // then unchanged).
    void setMaterial(const Material& material);
    const SampleCells* cells() const { return cells_ ? &*cells_ : nullptr; }

    // M(x), W/m^2 per channel; *terms (optional) receives the number of terms summed.
    glm::dvec3 exitance(const glm::dvec3& x, size_t* terms = nullptr) const;
    // L = F_out(n . w_o) M(x) / pi at a G-buffer pixel (0 for a miss). With the exact
    // Fresnel a pixel whose normal faces away from the viewer (n . w_o <= 0, at
    // silhouettes) gets F_t(eta, 0) = 0, i.e. black, as TranslucentShader does.
    glm::vec3 radiance(const GBufferPixel& pixel, size_t* terms = nullptr) const;
    // Every object pixel of g through compose() (gbuffer.h): RGBA, A = 1 on the object,
    // black background with A = 0.
    Image render(const GBuffer& g, JensenBuhlerStats* stats = nullptr) const;

    const IrradianceOctree& tree() const { return tree_; }
    const Material& material() const { return material_; }
    const JensenBuhlerOptions& options() const { return options_; }

private:
    Material material_;
    DipoleRGB dipole_;
    IrradianceOctree tree_;
    JensenBuhlerOptions options_;
    std::optional<SampleCells> cells_;
};

// The check of both renderers' constructors: cells over as many samples as the tree,
// set to `material` when they hold another. Throws prt::Error("sample cells", ...).
void adoptCells(std::optional<SampleCells>& cells, const IrradianceOctree& tree, const Material& material);

// One term of Keng Eq. 4 as both renderers sum it (S of irradiance_cache.h is bit for
// bit JensenBuhler::exitance): the cell weight of a tree sample k in the near field of
// x, else area R_d(|x - p|) with rd = R_d(|x - p|) per channel.
inline glm::dvec3 exitanceTerm(const SampleCells* cells, const IrradianceOctree& tree, uint32_t k,
                               const glm::vec3& x, double area, const glm::dvec3& rd, const glm::dvec3& e) {
    if (cells && k != kNodeTerm) {
        const uint32_t i = tree.order()[k];
        if (cells->isNear(i, x)) return cells->weight(i, x) * e;
    }
    return area * rd * e;
}

// The brute-force sum over all samples (no hierarchy), in input order, in double:
// the reference of the epsilon = 0 test.
glm::dvec3 bruteForceExitance(const IrradianceSamples& samples, const Material& material, const glm::dvec3& x);

// ---------------------------------------------------------------------------
// Implementation of the template
// ---------------------------------------------------------------------------

template <class Term>
size_t IrradianceOctree::traverse(const glm::dvec3& x, double epsilon, Term&& term, double nearRadius) const {
    constexpr bool withIndex = std::is_invocable_v<Term&, const glm::dvec3&, double, const glm::dvec3&, uint32_t>;
    const double near2 = nearRadius * nearRadius;
    size_t terms = 0;
    // Depth-first with an explicit stack; children are pushed in reverse so that they
    // are visited in storage order (a fixed order: deterministic sums).
    uint32_t stack[8 * 64];
    int top = 0;
    stack[top++] = 0;
    while (top > 0) {
        const Node& node = nodes_[stack[--top]];
        const glm::dvec3 d = x - node.position;
        const double d2 = glm::dot(d, d);
        if (node.area < epsilon * d2 && !node.cellContains(x) && (near2 == 0.0 || node.cellDistance2(x) >= near2)) {
            if constexpr (withIndex) term(node.position, node.area, node.irradiance, kNodeTerm);
            else term(node.position, node.area, node.irradiance);
            ++terms;
            continue;
        }
        if (node.leaf()) {
            for (uint32_t k = node.firstSample, e = node.firstSample + node.sampleCount; k < e; ++k) {
                const Sample& s = samples_[k];
                if constexpr (withIndex) term(glm::dvec3(s.position), double(s.area), glm::dvec3(s.irradiance), k);
                else term(glm::dvec3(s.position), double(s.area), glm::dvec3(s.irradiance));
            }
            terms += node.sampleCount;
            continue;
        }
        for (uint32_t c = node.childCount; c-- > 0;) stack[top++] = node.firstChild + c;
    }
    return terms;
}

}  // namespace prt
