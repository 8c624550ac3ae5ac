#pragma once
// The relighting kernel: per-vertex sparse dot products of the transport file's
// vectors with a light vector (Wang et al. 2005, Eqs. 6 and 10 by cubature).
//
// What comes out, per vertex v and channel c:
//   diffuse[v]  = sum over the selected diffuse components (multiple scattering, which
//                 the file stores as T_d / pi, and isotropic single scattering) of
//                 dot(vector_v, light) -- the outgoing radiance is F_t(eta, w_o) * diffuse[v];
//   terms[k][v] = dot(T_k vector_v, light) for each SVD phase term k -- the outgoing
//                 radiance adds F_t(eta, w_o) * sum_k h_k(w_o') * terms[k][v].
// Fresnel and the view maps depend on the view, so renderers apply them per pixel.

#include <glm/glm.hpp>

#include <cstdint>
#include <vector>

#include "common/light.h"
#include "common/transport_file.h"

namespace prt {

// Which components to evaluate.
struct ComponentSet {
    bool multipleScattering = true;
    bool singleScattering = true;  // isotropic and K-term single scattering
};
// Parses "ms", "ss", "ms,ss" / "all"; throws prt::Error("--components", ...) otherwise.
ComponentSet parseComponents(const std::string& text);

struct VertexRadiance {
    std::vector<glm::vec3> diffuse;             // one per vertex
    std::vector<std::vector<glm::vec3>> terms;  // [k][vertex], empty without K-term SS
};

// Fast path: multithreaded (TBB) over blocks of vertices, streaming each component's
// CSR arrays once; int16 values are dequantized on the fly. Throws prt::Error when
// the light vector's N differs from the file's cubemap size.
void relightVertices(const TransportFile& file, const LightVector& light,
                     const ComponentSet& components, VertexRadiance& out);

// The slow obvious version (dequantize each vertex, dot in double), kept for tests.
void relightVerticesReference(const TransportFile& file, const LightVector& light,
                              const ComponentSet& components, VertexRadiance& out);

// Bytes the fast path streams for one evaluation (offsets, indices, values, scales of
// the selected components): the numerator of the bandwidth ratio in SPEC section 8.
size_t relightStreamBytes(const TransportFile& file, const ComponentSet& components);

}  // namespace prt
