#pragma once
// The baseline the papers compare translucency against (Wang et al. 2005, Figs. 4, 5d
// and 7): a shadowed Lambertian (diffuse BRDF) PRT of the same mesh, stored as a
// transport file that every renderer relights unchanged (prt-precompute --baseline
// diffuse-brdf; docs/precompute.md, "The diffuse baseline").
//
// Per vertex v (position x_v, shading normal n_v, the mesh's vertex normal) and cubemap
// texel j (direction w_j, solid angle dOmega_j), channel c:
//   T_c(v, j) = (albedo_c / pi) V(x_v, w_j) max(0, n_v . w_j) dOmega_j,
// so that relighting, sum_j T_c(v, j) L_c(w_j), is the outgoing radiance of a Lambertian
// surface of reflectance albedo_c under the environment, with shadows. The directional
// part is pass 1's irradianceTransport at the vertices with eta = 1 (F_t = 1: no
// interface), with the same cubemap, supersampling, visibility sampling and truncation
// (the largest terms with the SH part) as a translucent job. Direct light only: no
// interreflection.
//
// The file: one MultipleScattering component (the only kind the renderers need), the
// parameters baseline = diffuse-brdf, albedo, eta = 1 (so the renderer's outgoing F_t
// is 1 too), the mesh's fingerprint and scale. Units: positions in mm; radiance in the
// environment's units.

#include <glm/glm.hpp>

#include <cstddef>
#include <string>
#include <utility>
#include <vector>

#include "common/ground.h"
#include "common/mesh.h"
#include "common/progress.h"
#include "common/raytrace.h"
#include "common/transport_file.h"
#include "precompute/passes/irradiance_transport.h"

namespace prt {

struct DiffuseBaselineOptions {
    glm::dvec3 albedo{0.8};         // in [0, 1] per channel
    int cubemapSize = 32;           // N, a power of two <= 64
    int shTerms = 9;                // SH part: 0, 1, 4 or 9
    size_t coefficients = 128;      // kept per vertex, the SH terms included
    int supersample = 2;            // sub-directions per texel side
    VisibilitySampling sampling = VisibilitySampling::Every;
};

// The baseline's transport file for `mesh` (scaled to mm, normals computed) traced in
// `scene` (the same mesh). `fingerprint` and `mmPerUnit` are the loaded file's (as the
// translucent pipeline records them); `parameters` are appended after the baseline's
// own. Throws prt::Error("--albedo", ...) for an albedo outside [0, 1] and as
// computeIrradianceTransport for bad cubemap options.
TransportFile diffuseBaselineTransport(const TriangleMesh& mesh, const RayScene& scene,
                                       const MeshFingerprint& fingerprint, double mmPerUnit,
                                       const DiffuseBaselineOptions& options,
                                       const std::vector<std::pair<std::string, std::string>>& parameters = {},
                                       Progress* progress = nullptr);

// The ground's transport file (common/ground.h; docs/ground.md): the same Lambertian
// transport at the vertices of groundMesh(plane) (normals +Y), traced in
// `objectAndGround`, the scene of withGround(object, groundMesh(plane)), so the object
// shadows the plane. options.albedo is the plane's. Its parameters: receiver = ground,
// kGroundPlaneParameter, kGroundObjectParameter (the object file's fingerprint, "V:hash"),
// albedo, eta = 1, then `parameters`. Its fingerprint is the ground mesh's, its
// mmPerUnit 1 (the plane is made in mm). Throws as diffuseBaselineTransport.
TransportFile groundTransport(const GroundPlane& plane, const RayScene& objectAndGround,
                              const MeshFingerprint& objectFingerprint, const DiffuseBaselineOptions& options,
                              const std::vector<std::pair<std::string, std::string>>& parameters = {},
                              Progress* progress = nullptr);

}  // namespace prt
