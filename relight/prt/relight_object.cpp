#include "relight/prt/relight_object.h"

#include <cstdio>
#include <optional>

#include "common/error.h"
#include "common/material_edit.h"
#include "common/mesh_io.h"
#include "common/transport_params.h"

namespace prt {

namespace {

// Isotropic single scattering is the one-term phase factorisation with h_0 = 1 (its
// 1/(4 pi) is in the vectors): shown as that term, it leaves the diffuse sum, so the
// shaders can give it the eye's-path factor (eye_path.h) like the K-term files.
bool showIsotropicSingleScatteringAsATerm(TransportFile& file) {
    TransportComponent* isotropic = nullptr;
    for (TransportComponent& c : file.components) {
        if (c.kind == ComponentKind::SingleScatteringTerm) return false;
        if (c.kind == ComponentKind::SingleScatteringIsotropic) isotropic = &c;
    }
    if (!isotropic || file.viewMaps) return false;
    isotropic->kind = ComponentKind::SingleScatteringTerm;
    isotropic->term = 0;
    file.viewMaps = ViewMaps{.size = 1, .terms = 1, .data = std::vector<float>(6, 1.0f)};
    return true;
}

}  // namespace

RelightObject loadRelightObject(const std::string& meshPath, const std::string& transportPath) {
    RelightObject o;
    o.mesh = loadMesh(meshPath);
    const MeshFingerprint fingerprint{o.mesh.vertexCount(), meshFingerprint(o.mesh)};
    o.transport = loadTransportFile(transportPath, fingerprint);
    scaleToPhysical(o.mesh, MeshScale{.sizeMm = std::nullopt, .mmPerUnit = o.transport.mmPerUnit});
    o.eta = readTransportParameters(o.transport.parameters, transportPath).eta.value_or(1.3);
    o.isotropicAsTerm = showIsotropicSingleScatteringAsATerm(o.transport);
    o.box = bounds(o.mesh);
    const BoundingSphere sphere = boundingSphere(o.mesh);
    o.sphereCentre = sphere.centre;
    o.sphereRadius = sphere.radius;
    if (o.transport.radialBasis) {
        o.editable.emplace(o.transport, objectSizeMm(o), transportPath);
        o.transport.components.insert(o.transport.components.begin(), o.editable->recombine());
    }
    return o;
}

std::string attachGround(RelightObject& object, const std::string& groundPath, const std::string& transportPath) {
    if (groundPath.empty()) {
        if (!object.transport.hasParameter(kGroundPlaneParameter)) return "";
        return "note: " + transportPath + " was precomputed with a ground under it; --ground " +
               groundTransportPath(transportPath) + " draws it";
    }
    object.ground = loadGroundReceiver(groundPath, object.transport, transportPath);
    const GroundPlane& p = object.ground->plane;
    char line[256];
    std::snprintf(line, sizeof line, "ground: %s, %.4g mm square at y = %.4g mm, %zu vertices, albedo (%.3g, %.3g, %.3g)",
                  groundPath.c_str(), 2.0 * p.halfExtent, p.height, object.ground->mesh.vertexCount(),
                  object.ground->albedo.r, object.ground->albedo.g, object.ground->albedo.b);
    return line;
}

double objectSizeMm(const RelightObject& object) { return double(object.box.diagonal()); }

std::optional<Material> shownMaterial(const RelightObject& object, const std::string& transportPath) {
    if (object.editable)
        return scaledMaterial(object.editable->material(), object.editable->sizeMm() / object.editable->objectSizeMm());
    return readTransportParameters(object.transport.parameters, transportPath).material;
}

bool setObjectMaterial(RelightObject& object, const Material& material, double sizeMm,
                       const std::string& transportPath) {
    if (!object.editable)
        throw Error(transportPath, "is not editable (made without prt-precompute --editable): its material and "
                                   "size are the precompute's");
    const bool etaChanged = object.editable->setMaterial(material, sizeMm);
    for (TransportComponent& c : object.transport.components)
        if (c.kind == ComponentKind::MultipleScattering) c = object.editable->recombine();
    return etaChanged;
}

std::string applyMaterialEdit(RelightObject& object, const std::string& materialText, double sizeMm,
                              const std::string& transportPath) {
    if (materialText.empty() && sizeMm == 0.0) {
        if (!object.editable) return "";
        return "material: the file's, " + describeMaterial(object.editable->material()) + " at " +
               formatParameter(object.editable->sizeMm()) + " mm (editable: --material, --size-mm)";
    }
    if (!object.editable) setObjectMaterial(object, Material{}, 1.0, transportPath);  // the one-line refusal
    const EditableTransport& e = *object.editable;
    const Material material =
        materialText.empty() ? e.fileMaterial() : parseMaterial(materialText, e.fileMaterial().eta, e.fileMaterial().g);
    const bool etaChanged = setObjectMaterial(object, material, sizeMm > 0.0 ? sizeMm : e.objectSizeMm(), transportPath);
    return describeMaterialEdit(object, etaChanged);
}

std::string describeMaterialEdit(const RelightObject& object, bool etaChanged) {
    if (!object.editable) return "";
    const EditableTransport& e = *object.editable;
    std::string line = "material: " + describeMaterial(e.material()) + " at " + formatParameter(e.sizeMm()) +
                       " mm (edited; the file's: " + e.fileMaterial().name + " at " + formatParameter(e.objectSizeMm()) +
                       " mm)";
    if (etaChanged) line += "; eta stays the file's " + formatParameter(e.fileMaterial().eta);
    bool singleScattering = false;
    for (const TransportComponent& c : object.transport.components)
        singleScattering |= c.kind != ComponentKind::MultipleScattering;
    if (singleScattering && !e.isFileMaterial())
        line += "; single scattering is NOT edited: it stays the file's material and size";
    return line;
}

}  // namespace prt
