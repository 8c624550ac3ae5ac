// Materials: the measured table (Jensen et al. 2001, docs/materials.md), custom
// coefficients, the artist's pair, and the constants the dipole derives from them.
// Units: coefficients in mm^-1, lengths in mm.

#include <optional>

#include "common/material_edit.h"
#include "common/materials.h"
#include "python/src/bindings.h"

namespace prt::python {

void bindMaterials(py::module_& m) {
    py::class_<Material>(m, "Material",
                         "A homogeneous translucent material: sigma_a and sigma_s' per RGB channel (mm^-1), the "
                         "relative index of refraction eta and the Henyey-Greenstein g. Immutable; derived "
                         "constants are the dipole's (docs/physics.md).")
        .def(py::init([](const py::handle& sigmaA, const py::handle& sigmaSPrime, double eta, double g,
                         std::optional<std::string> name) {
                 Material mat = customMaterial(vec3From(sigmaSPrime, "sigma_s_prime"), vec3From(sigmaA, "sigma_a"),
                                               eta, g);
                 if (name) mat.name = *name;
                 return mat;
             }),
             py::arg("sigma_a"), py::arg("sigma_s_prime"), py::arg("eta") = 1.3, py::arg("g") = 0.0,
             py::arg("name") = py::none(),
             "A custom material, validated as --sigma-a / --sigma-s-prime are")
        .def_property_readonly("name", [](const Material& x) { return x.name; })
        .def_property_readonly("sigma_a", [](const Material& x) { return tupleOf(x.sigmaA); })
        .def_property_readonly("sigma_s_prime", [](const Material& x) { return tupleOf(x.sigmaSPrime); })
        .def_property_readonly("eta", [](const Material& x) { return x.eta; })
        .def_property_readonly("g", [](const Material& x) { return x.g; })
        .def_property_readonly("sigma_s", [](const Material& x) { return tupleOf(x.sigmaS()); })
        .def_property_readonly("sigma_t", [](const Material& x) { return tupleOf(x.sigmaT()); })
        .def_property_readonly("sigma_t_prime", [](const Material& x) { return tupleOf(x.sigmaTPrime()); })
        .def_property_readonly("alpha_prime", [](const Material& x) { return tupleOf(x.alphaPrime()); },
                               "Reduced albedo sigma_s' / sigma_t'")
        .def_property_readonly("albedo", [](const Material& x) { return tupleOf(x.albedo()); })
        .def_property_readonly("sigma_tr", [](const Material& x) { return tupleOf(x.sigmaTr()); },
                               "Effective transport coefficient sqrt(3 sigma_a sigma_t'), mm^-1")
        .def_property_readonly("zr", [](const Material& x) { return tupleOf(x.zr()); },
                               "Depth of the dipole's real source, mm")
        .def_property_readonly("zv", [](const Material& x) { return tupleOf(x.zv()); },
                               "Height of the dipole's virtual source, mm")
        .def_property_readonly("fresnel_diffuse", &Material::fresnelDiffuse, "F_dr at eta")
        .def_property_readonly("boundary_a", &Material::boundaryA, "A = (1 + F_dr) / (1 - F_dr)")
        .def_property_readonly("mean_free_path", [](const Material& x) { return tupleOf(x.meanFreePath()); },
                               "1 / sigma_tr per channel, mm")
        .def_property_readonly("total_diffuse_reflectance",
                               [](const Material& x) { return tupleOf(x.totalDiffuseReflectance()); },
                               "R_d integrated over the plane (the dipole's albedo)")
        .def_property_readonly("appearance",
                               [](const Material& x) {
                                   const MaterialAppearance a = appearanceOf(x);
                                   return py::make_tuple(tupleOf(a.diffuseColour), tupleOf(a.meanFreePathMm));
                               },
                               "(diffuse colour, mean free path in mm): the artist's pair that gives this material")
        .def("scaled", &scaledMaterial, py::arg("s"),
             "sigma_a and sigma_s' times s: the same look on an object 1/s times the size")
        .def(
            "__eq__",
            [](const Material& a, const Material& b) {
                return a.name == b.name && a.sigmaA == b.sigmaA && a.sigmaSPrime == b.sigmaSPrime && a.eta == b.eta &&
                       a.g == b.g;
            },
            py::is_operator())
        .def("__str__", &describeMaterial)
        .def("__repr__", [](const Material& x) { return "<prt.Material " + describeMaterial(x) + ">"; });

    m.def("material_names", &materialNames, "The measured materials' names (docs/materials.md)");
    m.def(
        "material",
        [](const std::string& text, std::optional<double> eta, std::optional<double> g) {
            return parseMaterial(text, eta.value_or(1.3), g.value_or(0.0));
        },
        py::arg("text"), py::kw_only(), py::arg("eta") = py::none(), py::arg("g") = py::none(),
        "A material as --material takes it: a measured name (\"Marble\"), sigma:SA:SS or colour:RGB:MFP");
    m.def(
        "material_from_appearance",
        [](const py::handle& colour, const py::handle& mfp, double eta, double g) {
            return materialFromAppearance(vec3From(colour, "diffuse_colour"), vec3From(mfp, "mean_free_path_mm"), eta,
                                          g);
        },
        py::arg("diffuse_colour"), py::arg("mean_free_path_mm"), py::arg("eta") = 1.3, py::arg("g") = 0.0,
        "The artist's pair (--diffuse-colour, --mfp-mm) inverted to coefficients (docs/materials.md)");
    m.def("lerp_material", &lerpMaterial, py::arg("a"), py::arg("b"), py::arg("t"),
          "(1 - t) a + t b of the coefficients (Chang et al. 2008's material animation)");
}

}  // namespace prt::python
