#pragma once
// The object as the environment relighting tools place it (prt-relight render and
// view, prt-vertex-error): the mesh and its transport file, paired by the file's mesh
// fingerprint and put in physical size (mm) by the file's scale.

#include <glm/glm.hpp>

#include <optional>
#include <string>

#include "common/mesh.h"
#include "common/transport_file.h"
#include "relight/prt/editable_transport.h"
#include "relight/prt/ground_receiver.h"
#include "relight/prt/material_map.h"
#include "relight/render/base_colour.h"

namespace prt {

// The object as the relighting tools place it: the mesh file loaded, checked against
// the transport file's fingerprint (a mismatch is a prt::Error naming the transport
// file) and scaled by the file's mmPerUnit about the origin (as prt-precompute did),
// so positions are in mm and vertex v is the transport file's vertex v. Isotropic single
// scattering is held as the one-term phase (a SingleScatteringTerm component 0 with a
// constant view map h_0 = 1, 6 x 1 x 1), which renders the same, so that the
// renderers can put it along the eye's path (eye_path.h).
//
// An editable file (prt-precompute --editable, editable_transport.h) keeps its profile
// vectors in `editable`, and `transport` holds in their place the multiple-scattering
// component of the current material (first, as a precompute writes it), so that every
// renderer relights it like any other file; setObjectMaterial changes it.
struct RelightObject {
    TriangleMesh mesh;        // mm
    TransportFile transport;
    double eta = 1.3;         // transport.parameter("eta"); 1.3 when the file has none
    Bounds box;               // of the scaled mesh
    glm::dvec3 sphereCentre{0.0};  // bounding sphere: the box centre and the largest
    double sphereRadius = 0.0;     // distance of a vertex from it
    std::optional<EditableTransport> editable;  // the file has a radial basis
    BaseColour baseColour;    // --base-colour: tints the translucent exitance (white when off)
    std::optional<GroundReceiver> ground;  // --ground: the plane under the object
    std::optional<MaterialMap> materialMap;  // --material-map: a second material where the map says
    bool isotropicAsTerm = false;  // the file's isotropic single scattering is held as term 0 (above)
};
RelightObject loadRelightObject(const std::string& meshPath, const std::string& transportPath);

// --ground: loads the ground file `groundPath` into object.ground (loadGroundReceiver's
// checks against the object's file, transportPath). Returns the line the tools print:
// what the ground is; with no groundPath, a hint when the object's file was precomputed
// with a ground (its pass 1 saw the plane, so the object's underside is dark), else "".
std::string attachGround(RelightObject& object, const std::string& groundPath, const std::string& transportPath);

// The object's size as --size-mm measures it: the scaled mesh's bounding-box diagonal, mm.
double objectSizeMm(const RelightObject& object);

// Makes `material` at `sizeMm` the object's (editable files only: prt::Error naming
// transportPath otherwise; a material or size outside the basis's range is refused in
// one line and the object keeps its material). The file's eta is kept (returns whether
// the material asked for another).
bool setObjectMaterial(RelightObject& object, const Material& material, double sizeMm,
                       const std::string& transportPath = "transport file");

// The material the object shows, for the renderers that need the coefficients (the
// point lights, the sun split): an editable file's current material at its current
// size, as the material at the placed mesh's size (scaledMaterial); otherwise the
// file's (sigma_s_prime, sigma_a, eta), or none when the file does not name them.
std::optional<Material> shownMaterial(const RelightObject& object, const std::string& transportPath);

// --material / --size-mm (frame_settings.h) applied to the object: nothing when both are
// unset; else the material text parsed with the file's eta (parseMaterial; the file's
// material when empty) at sizeMm (the file's size when 0), by setObjectMaterial.
// Returns the line the tools print: what is shown, and that single scattering keeps the
// file's material when the object has single scattering and the material differs.
// Errors as setObjectMaterial, plus parseMaterial's naming --material.
std::string applyMaterialEdit(RelightObject& object, const std::string& materialText, double sizeMm,
                              const std::string& transportPath);

// applyMaterialEdit's line for the object's current material (after setObjectMaterial,
// whose result is etaChanged); "" for a file that is not editable.
std::string describeMaterialEdit(const RelightObject& object, bool etaChanged);

}  // namespace prt
