// The shadowed diffuse BRDF baseline: see diffuse_baseline.h.

#include "precompute/passes/diffuse_baseline.h"

#include <cmath>
#include <cstdio>

#include "common/error.h"
#include "common/sampling.h"
#include "common/util.h"

namespace prt {

namespace {

struct LambertianTransport {
    TransportComponent component;
    uint64_t raysTraced = 0;
};

// (albedo / pi) V max(0, n . w) dOmega at every vertex of `mesh`, traced in `scene`.
LambertianTransport lambertianTransport(const TriangleMesh& mesh, const RayScene& scene,
                                        const DiffuseBaselineOptions& options, Progress* progress) {
    for (int c = 0; c < 3; ++c)
        if (!(options.albedo[c] >= 0.0 && options.albedo[c] <= 1.0))
            throw Error("--albedo", "each channel must be in [0, 1] (a Lambertian surface reflects at most what it "
                                    "receives)");
    if (mesh.normals.size() != mesh.positions.size()) throw Error("diffuse baseline", "the mesh has no vertex normals");

    // The vertices as pass 1's samples: position, shading normal and, for the ray
    // origin's offset, the same normal.
    SampleSet vertices;
    vertices.samples.resize(mesh.vertexCount());
    for (size_t v = 0; v < mesh.vertexCount(); ++v) {
        SurfaceSample& s = vertices.samples[v];
        s.position = mesh.positions[v];
        s.normal = mesh.normals[v];
        s.geometricNormal = mesh.normals[v];
    }
    IrradianceTransportOptions pass1;
    pass1.cubemapSize = options.cubemapSize;
    pass1.supersample = options.supersample;
    pass1.sampleCoefficients = options.coefficients;
    pass1.shTerms = options.shTerms;
    pass1.eta = 1.0;  // F_t(1, w) = 1: no interface, the bare cosine-weighted visibility
    pass1.sampling = options.sampling;
    IrradianceTransportResult directional = computeIrradianceTransport(&scene, vertices, pass1, progress);

    LambertianTransport out;
    out.component.kind = ComponentKind::MultipleScattering;
    std::vector<float> rgb;
    for (const SparseVector& e : directional.vectors) {
        rgb.resize(3 * e.size());
        for (size_t k = 0; k < e.size(); ++k)
            for (int c = 0; c < 3; ++c) rgb[3 * k + size_t(c)] = float(options.albedo[c] / kPi) * e.value[k];
        out.component.vectors.appendVertex(e.index, rgb);
    }
    out.raysTraced = directional.raysTraced;
    return out;
}

TransportFile lambertianFile(LambertianTransport transport, const DiffuseBaselineOptions& options,
                             const MeshFingerprint& fingerprint, double mmPerUnit,
                             std::vector<std::pair<std::string, std::string>> own,
                             const std::vector<std::pair<std::string, std::string>>& parameters) {
    TransportFile file;
    file.cubemapSize = uint32_t(options.cubemapSize);
    file.shTerms = uint32_t(options.shTerms);
    file.mesh = fingerprint;
    file.mmPerUnit = mmPerUnit;
    char albedo[96];
    std::snprintf(albedo, sizeof albedo, "%.9g,%.9g,%.9g", options.albedo.r, options.albedo.g, options.albedo.b);
    file.parameters = std::move(own);
    const std::vector<std::pair<std::string, std::string>> common = {
        {"albedo", albedo},
        {"eta", "1"},
        {"coefficients", std::to_string(options.coefficients)},
        {"supersample", std::to_string(options.supersample)},
        {"visibility_sampling", toString(options.sampling)},
        {"rays_traced", std::to_string(transport.raysTraced)}};
    for (const auto& p : common) file.parameters.push_back(p);
    for (const auto& p : parameters) file.parameters.push_back(p);
    file.components.push_back(std::move(transport.component));
    return file;
}

}  // namespace

TransportFile diffuseBaselineTransport(const TriangleMesh& mesh, const RayScene& scene,
                                       const MeshFingerprint& fingerprint, double mmPerUnit,
                                       const DiffuseBaselineOptions& options,
                                       const std::vector<std::pair<std::string, std::string>>& parameters,
                                       Progress* progress) {
    return lambertianFile(lambertianTransport(mesh, scene, options, progress), options, fingerprint, mmPerUnit,
                          {{"baseline", "diffuse-brdf"}}, parameters);
}

TransportFile groundTransport(const GroundPlane& plane, const RayScene& objectAndGround,
                              const MeshFingerprint& objectFingerprint, const DiffuseBaselineOptions& options,
                              const std::vector<std::pair<std::string, std::string>>& parameters,
                              Progress* progress) {
    const TriangleMesh ground = groundMesh(plane);
    const MeshFingerprint fingerprint{ground.vertexCount(), meshFingerprint(ground)};
    return lambertianFile(lambertianTransport(ground, objectAndGround, options, progress), options, fingerprint, 1.0,
                          {{"receiver", "ground"},
                           {kGroundPlaneParameter, formatGroundPlane(plane)},
                           {kGroundObjectParameter, groundObjectText(objectFingerprint)}},
                          parameters);
}

}  // namespace prt
