#pragma once
// The object as the environment relighting tools place it (prt-relight render and
// view, prt-vertex-error): the mesh and its transport file, paired by the file's mesh
// fingerprint and put in physical size (mm) by the file's scale.

#include <glm/glm.hpp>

#include <string>

#include "common/mesh.h"
#include "common/transport_file.h"

namespace prt {

// The object as the relighting tools place it: the mesh file loaded, checked against
// the transport file's fingerprint (a mismatch is a prt::Error naming the transport
// file) and scaled by the file's mmPerUnit about the origin (as prt-precompute did),
// so positions are in mm and vertex v is the transport file's vertex v.
struct RelightObject {
    TriangleMesh mesh;        // mm
    TransportFile transport;
    double eta = 1.3;         // transport.parameter("eta"); 1.3 when the file has none
    Bounds box;               // of the scaled mesh
    glm::dvec3 sphereCentre{0.0};  // bounding sphere: the box centre and the largest
    double sphereRadius = 0.0;     // distance of a vertex from it
};
RelightObject loadRelightObject(const std::string& meshPath, const std::string& transportPath);

}  // namespace prt
