#include "relight/prt/ground_receiver.h"

#include "common/error.h"

namespace prt {

GroundReceiver loadGroundReceiver(const std::string& path, const TransportFile& objectTransport,
                                  const std::string& objectTransportPath) {
    const GroundDescription d =
        readGroundDescription(path, objectTransport.mesh, objectTransport.parameter(kGroundPlaneParameter),
                              objectTransport.parameter("input_digest"), objectTransport.cubemapSize,
                              objectTransport.shTerms, objectTransportPath);
    GroundReceiver g;
    g.plane = d.plane;
    g.albedo = d.albedo;
    g.mesh = groundMesh(g.plane);
    g.transport = loadTransportFile(path, MeshFingerprint{g.mesh.vertexCount(), meshFingerprint(g.mesh)});
    if (g.transport.components.size() != 1 || g.transport.components[0].kind != ComponentKind::MultipleScattering)
        throw Error(path, "a ground file holds one Lambertian component");
    return g;
}

glm::vec3 groundRadiance(const GroundReceiver& ground, const GBufferPixel& p, const VertexRadiance& radiance,
                         size_t objectTriangles) {
    // Seen from below, the plane shows its unlit back: black, as the renderers show a
    // surface whose normal faces away from the viewer.
    if (!(p.toViewer.y > 0.0f)) return glm::vec3(0.0f);
    const glm::uvec3 t = ground.mesh.triangles[p.triangle - objectTriangles];
    return p.barycentric.x * radiance.diffuse[t.x] + p.barycentric.y * radiance.diffuse[t.y] +
           p.barycentric.z * radiance.diffuse[t.z];
}

}  // namespace prt
