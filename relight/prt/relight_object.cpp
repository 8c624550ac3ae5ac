#include "relight/prt/relight_object.h"

#include <optional>

#include "common/mesh_io.h"
#include "common/transport_params.h"

namespace prt {

RelightObject loadRelightObject(const std::string& meshPath, const std::string& transportPath) {
    RelightObject o;
    o.mesh = loadMesh(meshPath);
    const MeshFingerprint fingerprint{o.mesh.vertexCount(), meshFingerprint(o.mesh)};
    o.transport = loadTransportFile(transportPath, fingerprint);
    scaleToPhysical(o.mesh, MeshScale{.sizeMm = std::nullopt, .mmPerUnit = o.transport.mmPerUnit});
    o.eta = readTransportParameters(o.transport.parameters, transportPath).eta.value_or(1.3);
    o.box = bounds(o.mesh);
    const BoundingSphere sphere = boundingSphere(o.mesh);
    o.sphereCentre = sphere.centre;
    o.sphereRadius = sphere.radius;
    return o;
}

}  // namespace prt
