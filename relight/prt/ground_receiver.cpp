#include "relight/prt/ground_receiver.h"

#include "common/error.h"
#include "common/util.h"

namespace prt {

GroundReceiver loadGroundReceiver(const std::string& path, const TransportFile& objectTransport,
                                  const std::string& objectTransportPath) {
    const TransportFileInfo info = readTransportFileInfo(path);
    if (info.parameter("receiver") != "ground")
        throw Error(path, "not a ground transport file (prt-precompute --ground writes one beside the object's)");
    GroundReceiver g;
    g.plane = parseGroundPlane(info.parameter(kGroundPlaneParameter), path);
    if (info.parameter(kGroundObjectParameter) != groundObjectText(objectTransport.mesh))
        throw Error(path, "made for another object (" + info.parameter(kGroundObjectParameter) + ") than " +
                              objectTransportPath + " (" + groundObjectText(objectTransport.mesh) + ")");
    if (objectTransport.parameter(kGroundPlaneParameter) != info.parameter(kGroundPlaneParameter))
        throw Error(path, objectTransportPath + " was precomputed without this ground occluding it (precompute the "
                                                "object with --ground)");
    if (info.cubemapSize != objectTransport.cubemapSize || info.shTerms != objectTransport.shTerms)
        throw Error(path, "its cubemap or SH part differs from " + objectTransportPath + "'s");
    g.mesh = groundMesh(g.plane);
    g.transport = loadTransportFile(path, MeshFingerprint{g.mesh.vertexCount(), meshFingerprint(g.mesh)});
    if (g.transport.components.size() != 1 || g.transport.components[0].kind != ComponentKind::MultipleScattering)
        throw Error(path, "a ground file holds one Lambertian component");
    const std::vector<double> albedo = parseNumberList(g.transport.parameter("albedo"), path, "albedo");
    if (albedo.size() != 3) throw Error(path, "its albedo parameter is not R,G,B");
    g.albedo = {albedo[0], albedo[1], albedo[2]};
    return g;
}

glm::vec3 groundRadiance(const GroundReceiver& ground, const GBufferPixel& p, const VertexRadiance& radiance,
                         size_t objectTriangles) {
    const glm::uvec3 t = ground.mesh.triangles[p.triangle - objectTriangles];
    return p.barycentric.x * radiance.diffuse[t.x] + p.barycentric.y * radiance.diffuse[t.y] +
           p.barycentric.z * radiance.diffuse[t.z];
}

}  // namespace prt
