#pragma once
// The ground under a relit object (common/ground.h; docs/ground.md): its mesh, rebuilt
// from the plane its transport file records, and that file's Lambertian transport
// vectors, relit with the object's light vector. Direct light only: the ground
// receives the environment and the object's shadow; nothing bounces between them.
//
// Radiance of a ground vertex: sum_j T_c(v, j) L_c(w_j), the outgoing radiance of a
// Lambertian surface of the file's albedo (precompute/passes/diffuse_baseline.h),
// view-independent; at a pixel, interpolated with the hit's barycentrics.

#include <glm/glm.hpp>

#include <string>

#include "common/ground.h"
#include "common/mesh.h"
#include "common/transport_file.h"
#include "relight/prt/relight_kernel.h"
#include "relight/render/gbuffer.h"

namespace prt {

struct GroundReceiver {
    GroundPlane plane;
    TriangleMesh mesh;          // groundMesh(plane), mm
    TransportFile transport;    // one MultipleScattering component, a vector per mesh vertex
    glm::dvec3 albedo{0.0};     // the file's
};

// Loads the ground transport file `path` written beside `objectTransport` (the object's
// file, loaded, from objectTransportPath). Throws prt::Error(path, one line) for a file
// that is not a ground file, one made for another object (fingerprint) or by another
// job (input digest), another cubemap or SH part, or when the object's file was precomputed without this plane
// occluding it (its "ground_plane" differs or is absent); and loadTransportFile's
// errors.
GroundReceiver loadGroundReceiver(const std::string& path, const TransportFile& objectTransport,
                                  const std::string& objectTransportPath);

// The ground's radiance at pixel `p` of a G-buffer traced against withGround(object,
// ground.mesh): the barycentric blend of `radiance` (relightVertices of
// ground.transport) at the hit triangle's vertices. p.triangle must be a ground
// triangle (isGroundTriangle(p.triangle, objectTriangles)). Black when seen from below
// (p.toViewer.y <= 0): the plane's back receives nothing.
glm::vec3 groundRadiance(const GroundReceiver& ground, const GBufferPixel& p, const VertexRadiance& radiance,
                         size_t objectTriangles);

}  // namespace prt
