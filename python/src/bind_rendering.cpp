// Environments, light vectors, the relight kernel, relit objects (with live materials)
// and prt-relight render's frames.

#include <cmath>
#include <optional>

#include "common/envmap.h"
#include "common/material_edit.h"
#include "common/options.h"
#include "common/transport_params.h"
#include "common/util.h"
#include "python/src/bindings.h"
#include "relight/prt/editable_transport.h"
#include "relight/prt/environment_frame.h"
#include "relight/prt/frame_settings.h"
#include "relight/prt/light_vector.h"
#include "relight/combined/sun_split_frame.h"
#include "relight/render/supersample.h"

namespace prt::python {

namespace {

void requireEditable(const PyObject& o) {
    if (!o.object->editable) throw Error(o.transportPath, "is not editable (prt-precompute --editable)");
}

// A lat-long environment (prt.Environment): RGB, finite, twice as wide as high.
struct PyEnvironment {
    Image image;
    std::string path;
};

NonFinitePolicy policyOf(const std::string& text) {
    if (text == "reject") return NonFinitePolicy::Reject;
    if (text == "clamp_negative") return NonFinitePolicy::ClampNegative;
    if (text == "clamp") return NonFinitePolicy::Clamp;
    throw py::value_error("non_finite: expected 'reject', 'clamp_negative' or 'clamp', got '" + text + "'");
}

// Degrees about +Y (rotationY), or a 3 x 3 rotation matrix (row-major, as numpy).
glm::dmat3 rotationOf(const py::handle& value) {
    if (py::isinstance<py::float_>(value) || py::isinstance<py::int_>(value)) {
        const double degrees = value.cast<double>();
        if (!std::isfinite(degrees)) throw Error("--env-rotation", "must be finite");
        return rotationY(degrees);
    }
    const auto a = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(value);
    if (!a || a.ndim() != 2 || a.shape(0) != 3 || a.shape(1) != 3)
        throw py::value_error("rotation: expected degrees about +Y or a (3, 3) matrix");
    glm::dmat3 r;
    for (int row = 0; row < 3; ++row)
        for (int col = 0; col < 3; ++col) {
            if (!std::isfinite(a.at(row, col))) throw py::value_error("rotation: must be finite");
            r[col][row] = a.at(row, col);
        }
    return r;
}

py::array_t<double> matrixArray(const glm::dmat3& r) {
    std::vector<double> v(9);
    for (int row = 0; row < 3; ++row)
        for (int col = 0; col < 3; ++col) v[size_t(row) * 3 + size_t(col)] = r[col][row];
    return adopt(std::move(v), {3, 3});
}

// The (V, 3) float32 output: `out` when given (checked), else a new array.
py::array_t<float> outputArray(const py::object& out, size_t vertices) {
    if (out.is_none()) return py::array_t<float>({py::ssize_t(vertices), py::ssize_t(3)});
    if (!py::isinstance<py::array_t<float>>(out)) throw py::type_error("out: expected a float32 array");
    auto a = py::reinterpret_borrow<py::array_t<float>>(out);
    if (a.ndim() != 2 || a.shape(0) != py::ssize_t(vertices) || a.shape(1) != 3)
        throw py::value_error("out: expected shape (" + std::to_string(vertices) + ", 3)");
    if (!(a.flags() & py::array::c_style) || !a.writeable())
        throw py::value_error("out: must be C-contiguous and writable");
    return a;
}

const LightVector& lightOf(const py::handle& value) {
    try {
        return value.cast<const LightVector&>();
    } catch (const py::cast_error&) {
        throw py::type_error("light: expected a prt.LightVector (Environment.light_vector)");
    }
}

// isotropicTerm: the file's term 0 is isotropic single scattering that loadRelightObject
// moved out of the diffuse sum (RelightObject::isotropicAsTerm); it is added back, so an
// object relights as its transport file does.
py::array_t<float> relightInto(PyTransport& t, const TransportFile& file, const LightVector& light,
                               const std::string& components, const py::object& out, bool isotropicTerm = false) {
    const ScatteringComponents which = selectComponents(components, componentsOf(file), t.path);
    if (light.size != int(file.cubemapSize))
        throw Error("light", "its cubemap is 6x" + std::to_string(light.size) + "^2, the transport file's 6x" +
                                 std::to_string(file.cubemapSize) + "^2");
    py::array_t<float> result = outputArray(out, file.mesh.vertexCount);
    float* dst = result.mutable_data();
    {
        py::gil_scoped_release release;
        std::lock_guard lock(t.mutex);
        relightVertices(file, light, which, t.scratch);
        if (isotropicTerm && t.scratch.terms.size() == 1)
            for (size_t v = 0; v < t.scratch.diffuse.size(); ++v) t.scratch.diffuse[v] += t.scratch.terms[0][v];
        std::copy_n(&t.scratch.diffuse.data()->x, 3 * t.scratch.diffuse.size(), dst);
    }
    return result;
}

}  // namespace

void bindEnvironments(py::module_& m) {
    py::class_<LightVector>(m, "LightVector",
                            "An environment projected onto the 6 x N x N Haar basis of a transport file "
                            "(docs/relight.md): what relight() dots with each vertex's vector.")
        .def_property_readonly("size", [](const LightVector& l) { return l.size; }, "N")
        .def_property_readonly(
            "rgb",
            [](py::object self) {
                const LightVector& l = self.cast<const LightVector&>();
                return view(l.rgb.data(), {py::ssize_t(l.coefficientCount()), 3}, self);
            },
            "(6 N^2, 3) float32 Haar coefficients (a view)")
        .def_property_readonly(
            "sh", [](py::object self) {
                const LightVector& l = self.cast<const LightVector&>();
                return view(l.sh.data(), {py::ssize_t(l.sh.size() / 3), 3}, self);
            },
            "(T, 3) SH coefficients of the radiance (empty when the files have no SH part)")
        .def_property_readonly("kept_terms", [](const LightVector& l) { return l.keptTerms; })
        .def_property_readonly("relative_l2_error", [](const LightVector& l) { return l.relativeL2Error; },
                               "||L - L_kept|| / ||L|| of the kept terms (Parseval)");

    py::class_<PyEnvironment>(m, "Environment",
                              "A lat-long HDR environment (width = 2 height), RGB radiance, finite "
                              "(docs/conventions.md for its directions)")
        .def(py::init([](const py::handle& pixels, const std::string& nonFinite) {
                 PyEnvironment e;
                 const Image raw = imageFromArray(pixels, "pixels", 1, 4);
                 if (raw.width != 2 * raw.height)
                     throw Error("environment", "a lat-long environment must be twice as wide as high, got " +
                                                    std::to_string(raw.width) + " x " + std::to_string(raw.height));
                 e.image = Image(raw.width, raw.height, 3);
                 const size_t nc = size_t(raw.channels);
                 for (size_t p = 0; p < size_t(raw.width) * size_t(raw.height); ++p)
                     for (size_t c = 0; c < 3; ++c) e.image.pixels[p * 3 + c] = raw.pixels[p * nc + (nc >= 3 ? c : 0)];
                 checkEnvironmentValues(e.image, "environment", policyOf(nonFinite));
                 return e;
             }),
             py::arg("pixels"), py::arg("non_finite") = "reject",
             "From an (H, W, C) float array (C = 1..4; gray is spread to RGB, alpha ignored). non_finite: "
             "'reject' (NaN/Inf raise), 'clamp_negative' (also negatives to 0, as render does) or 'clamp'")
        .def_property_readonly(
            "pixels",
            [](py::object self) {
                const PyEnvironment& e = self.cast<const PyEnvironment&>();
                return view(e.image.pixels.data(), {e.image.height, e.image.width, 3}, self);
            },
            "(H, W, 3) float32 radiance (a read-only view)")
        .def_property_readonly("width", [](const PyEnvironment& e) { return e.image.width; })
        .def_property_readonly("height", [](const PyEnvironment& e) { return e.image.height; })
        .def_property_readonly("path", [](const PyEnvironment& e) { return e.path; })
        .def(
            "integral",
            [](const PyEnvironment& e) {
                return py::make_tuple(latLongIntegral(e.image, 0), latLongIntegral(e.image, 1),
                                      latLongIntegral(e.image, 2));
            },
            "The radiance integrated over the sphere per channel (W/m^2 for a unit environment)")
        .def(
            "light_vector",
            [](const PyEnvironment& e, int n, const py::object& rotation, size_t terms) {
                const glm::dmat3 r = rotationOf(rotation);
                return withoutGil([&] { return makeLightVector(e.image, n, r, terms); });
            },
            py::arg("n"), py::arg("rotation") = 0.0, py::arg("terms") = 0,
            "The light vector for an N x N cubemap (a transport file's cubemap_size), the environment rotated "
            "(degrees about +Y or a 3 x 3 matrix), its `terms` largest Haar terms kept (0 = all; -L)")
        .def("__repr__", [](const PyEnvironment& e) {
            return "<prt.Environment " + std::to_string(e.image.width) + "x" + std::to_string(e.image.height) +
                   (e.path.empty() ? "" : ", from " + e.path) + ">";
        });

    m.def(
        "load_environment",
        [](const std::string& path, const std::string& nonFinite) {
            PyEnvironment e;
            e.path = path;
            const NonFinitePolicy policy = policyOf(nonFinite);
            e.image = withoutGil([&] { return loadEnvironment(path, policy); });
            return e;
        },
        py::arg("path"), py::arg("non_finite") = "clamp_negative",
        "Loads a lat-long environment (EXR, HDR, ...). Negative values become 0 by default, as prt-relight "
        "render does; NaN or Inf raise (non_finite as Environment)");
    m.def("rotation_y", [](double degrees) { return matrixArray(rotationY(degrees)); }, py::arg("degrees"),
          "The 3 x 3 rotation about +Y the tools use for --env-rotation");
    m.def(
        "rotation",
        [](const py::handle& axis, double degrees) {
            return matrixArray(rotationAxisAngle(vec3From(axis, "axis"), degrees));
        },
        py::arg("axis"), py::arg("degrees"), "The 3 x 3 rotation about an axis (right-handed)");
}

void bindRendering(py::module_& m) {
    m.def(
        "relight",
        [](PyTransport& t, const py::handle& light, const std::string& components, const py::object& out) {
            return relightInto(t, *t.file, lightOf(light), components, out);
        },
        py::arg("transport"), py::arg("light"), py::arg("components") = "all", py::arg("out") = py::none(),
        "Per-vertex outgoing radiance (V, 3) float32: each vertex's transport vectors dotted with the light "
        "(the sparse relight kernel; docs/relight.md). components: 'all', 'ms', 'ss' or 'ms,ss'. out: a (V, 3) "
        "float32 array to fill instead of a new one.");

    m.def(
        "time_relight",
        [](PyTransport& t, const py::handle& light, const std::string& components, int repeats) {
            if (repeats < 1) throw py::value_error("repeats: must be >= 1");
            const LightVector& l = lightOf(light);
            const ScatteringComponents which = selectComponents(components, componentsOf(*t.file), t.path);
            std::vector<double> seconds;
            py::gil_scoped_release release;
            std::lock_guard lock(t.mutex);
            for (int i = 0; i < repeats; ++i) {
                const Stopwatch clock;
                relightVertices(*t.file, l, which, t.scratch);
                seconds.push_back(clock.seconds());
            }
            return seconds;
        },
        py::arg("transport"), py::arg("light"), py::arg("components") = "all", py::arg("repeats") = 20,
        "The relight kernel's own time, seconds per call, measured in C++ (no Python, no copy): the "
        "yardstick of relight()'s overhead (python/benchmarks/relight_overhead.py)");

    py::class_<PyObject>(m, "Object",
                         "A mesh and its transport file placed as prt-relight places them (positions in mm); an "
                         "editable file's material and size are live (set_material).")
        .def_property_readonly("transport", [](const PyObject& o) { return o.transport; })
        .def_property_readonly(
            "vertices",
            [](py::object self) {
                const RelightObject& r = *self.cast<const PyObject&>().object;
                return view(&r.mesh.positions.data()->x, {py::ssize_t(r.mesh.vertexCount()), 3}, self);
            },
            "(V, 3) float32 positions in mm (a view)")
        .def_property_readonly(
            "normals",
            [](py::object self) {
                const RelightObject& r = *self.cast<const PyObject&>().object;
                return view(&r.mesh.normals.data()->x, {py::ssize_t(r.mesh.vertexCount()), 3}, self);
            },
            "(V, 3) float32 unit vertex normals (a view)")
        .def_property_readonly(
            "faces",
            [](py::object self) {
                const RelightObject& r = *self.cast<const PyObject&>().object;
                return view(&r.mesh.triangles.data()->x, {py::ssize_t(r.mesh.triangleCount()), 3}, self);
            },
            "(F, 3) uint32 vertex indices (a view)")
        .def_property_readonly("eta", [](const PyObject& o) { return o.object->eta; })
        .def_property_readonly("size_mm", [](const PyObject& o) { return objectSizeMm(*o.object); },
                               "The bounding-box diagonal in mm, as --size-mm measures it")
        .def_property_readonly("editable", [](const PyObject& o) { return o.object->editable.has_value(); })
        .def_property_readonly(
            "material",
            [](const PyObject& o) -> std::optional<Material> {
                return locked(o, [&]() -> std::optional<Material> {
                    if (o.object->editable) return o.object->editable->material();
                    return readTransportParameters(o.object->transport.parameters, o.transportPath).material;
                });
            },
            "The material the object relights with (an editable file's current one)")
        .def_property_readonly(
            "weights",
            [](const PyObject& o) {
                requireEditable(o);
                std::vector<double> flat = locked(o, [&] {
                    std::vector<double> w;
                    for (const auto& channel : o.object->editable->weights()) w.insert(w.end(), channel.begin(), channel.end());
                    return w;
                });
                const py::ssize_t J = py::ssize_t(flat.size() / 3);
                return adopt(std::move(flat), {3, J});
            },
            "(3, J) float64: the current material's weights on the file's J radial profiles")
        .def(
            "set_material",
            [](PyObject& o, const py::object& material, std::optional<double> sizeMm) {
                requireEditable(o);
                if (sizeMm && !(*sizeMm > 0.0 && std::isfinite(*sizeMm))) throw Error("--size-mm", "must be a size in mm > 0");
                // Taken with the GIL: a Material, --material's text, or None (keep the material).
                std::optional<Material> given;
                std::string text;
                if (py::isinstance<Material>(material)) given = material.cast<Material>();
                else if (!material.is_none()) text = stringArgument(material, "material");
                return locked(o, [&] {
                    EditableTransport& e = *o.object->editable;
                    const double size = sizeMm.value_or(e.sizeMm());
                    if (!text.empty()) return applyMaterialEdit(*o.object, text, size, o.transportPath);
                    const bool etaChanged =
                        setObjectMaterial(*o.object, given ? *given : e.material(), size, o.transportPath);
                    return describeMaterialEdit(*o.object, etaChanged);
                });
            },
            py::arg("material") = py::none(), py::kw_only(), py::arg("size_mm") = py::none(),
            "Makes the material (a prt.Material, --material's text, or None for the current one) at size_mm "
            "(default: the current size) the object's, without a new precompute (editable files only; outside the "
            "file's range it raises and the object keeps its material). Returns the line render prints (single "
            "scattering keeps the file's material).")
        .def(
            "relight",
            [](PyObject& o, const py::handle& light, const std::string& components, const py::object& out) {
                return relightInto(*o.transport, o.object->transport, lightOf(light), components, out,
                                   o.object->isotropicAsTerm);
            },
            py::arg("light"), py::arg("components") = "all", py::arg("out") = py::none(),
            "prt.relight of the object's transport (the current material's)")
        .def(
            "project_light",
            [](PyObject& o, const py::handle& light) {
                requireEditable(o);
                const LightVector& l = lightOf(light);
                locked(o, [&] {
                    o.object->editable->projectLight(l);
                    return 0;
                });
            },
            py::arg("light"),
            "Editable files: dots every profile vector with the light once, so that relight_projected() after "
            "each set_material costs J multiply-adds per vertex and channel (multiple scattering only)")
        .def(
            "relight_projected",
            [](PyObject& o, const py::object& out) {
                requireEditable(o);
                py::array_t<float> result = outputArray(out, o.object->mesh.vertexCount());
                float* dst = result.mutable_data();
                locked(o, [&] {
                    if (!o.object->editable->hasProjectedLight())
                        throw Error(o.transportPath, "no projected light (call project_light first)");
                    std::vector<glm::vec3>& diffuse = o.transport->scratch.diffuse;
                    o.object->editable->relightProjected(diffuse);
                    std::copy_n(&diffuse.data()->x, 3 * diffuse.size(), dst);
                    return 0;
                });
                return result;
            },
            py::arg("out") = py::none(),
            "The multiple scattering of the current material under the projected light, (V, 3) float32");

    m.def(
        "load_object",
        [](const std::string& meshPath, const std::string& transportPath, bool baseColour, const py::object& ground) {
            PyObject o;
            o.meshPath = meshPath;
            o.transportPath = transportPath;
            const std::string groundPath = ground.is_none() ? std::string() : stringArgument(ground, "ground");
            o.object = std::make_shared<RelightObject>(withoutGil([&] {
                RelightObject object = loadRelightObject(meshPath, transportPath);
                if (baseColour) object.baseColour = BaseColour::load(meshPath, object.mesh);
                if (!groundPath.empty()) attachGround(object, groundPath, transportPath);
                return object;
            }));
            o.transport = std::make_shared<PyTransport>();
            o.transport->file = std::shared_ptr<TransportFile>(o.object, &o.object->transport);
            o.transport->path = transportPath;
            o.transport->edited = o.object->editable.has_value();
            return o;
        },
        py::arg("mesh"), py::arg("transport"), py::arg("base_colour") = false, py::arg("ground") = py::none(),
        "The mesh file and its transport file, checked against each other and scaled to mm (prt-relight's object). "
        "base_colour: the mesh file's base colour tints the translucent exitance in render (render's --base-colour; "
        "docs/assets.md). ground: the ground's transport file (prt-precompute --ground), drawn by render under the "
        "object (render's --ground; docs/ground.md)");

    m.def(
        "render",
        [](PyObject& o, const PyEnvironment& environment, const py::object& eye, const py::object& target,
           const py::object& up, double fov, int width, int height, double azimuth, double elevation, double fill,
           const py::object& envRotation, const std::string& components, size_t lightTerms, bool specular,
           int specularBlur, const py::object& material, std::optional<double> sizeMm, int spp,
           const std::string& ssPath, bool sunSplit, double sunThreshold, double sunCell,
           const std::string& sunMethod) {
            const int subpixels = subpixelGridSize(spp);
            FrameSettings look;
            look.components = components;
            look.ssPath = ssPath;
            look.lightTerms = lightTerms;
            look.specular = specular;
            look.specularBlur = specularBlur;
            if (specularBlur != 0 && !specular) throw Error("--specular-blur", "needs --specular");
            checkFrameSettings(look);
            CameraOptions camera;
            auto vec = [](const py::object& v, const std::string& name) -> std::vector<double> {
                if (v.is_none()) return {};
                const glm::dvec3 x = vec3From(v, name);
                return {x.x, x.y, x.z};
            };
            camera.eye = vec(eye, "eye");
            camera.target = vec(target, "target");
            camera.up = vec(up, "up");
            camera.fov = fov;
            camera.width = width;
            camera.height = height;
            camera.azimuth = azimuth;
            camera.elevation = elevation;
            camera.fill = fill;
            const glm::dmat3 rotation = rotationOf(envRotation);
            const std::string materialText = material.is_none() ? "" : stringArgument(material, "material");
            if (sizeMm && !(*sizeMm > 0.0 && std::isfinite(*sizeMm))) throw Error("--size-mm", "must be a size in mm > 0");
            const SunSplitOptions sun{.threshold = sunThreshold, .cellDegrees = sunCell};
            // Checked whether or not the split is asked for: no argument is silently ignored.
            const PointMethod lightsMethod = parseSunSplitMethod(sunMethod);
            validateSunSplitOptions(sun);
            py::gil_scoped_release release;
            std::lock_guard lock(o.transport->mutex);
            // Checked before the edit, which stays the object's: a refused frame leaves it as it was.
            const Camera cam =
                supersampledCamera(makeCamera(camera, o.object->sphereCentre, o.object->sphereRadius), subpixels);
            const ScatteringComponents which =
                selectComponents(look.components, componentsOf(o.object->transport), o.transportPath);
            if (sunSplit) sunSplitMaterial(*o.object, o.transportPath);  // refused before the edit
            if (!materialText.empty() || sizeMm) {
                // As set_material: the current size unless size_mm, the current material
                // unless material.
                if (!o.object->editable) applyMaterialEdit(*o.object, materialText, 1.0, o.transportPath);  // refused
                const EditableTransport& e = *o.object->editable;
                const double size = sizeMm.value_or(e.sizeMm());
                if (!materialText.empty()) applyMaterialEdit(*o.object, materialText, size, o.transportPath);
                else setObjectMaterial(*o.object, e.material(), size, o.transportPath);
            }
            Image image;
            if (sunSplit) {
                SunSplitFrameRenderer renderer(*o.object, environment.image, look, which, sun, o.transportPath, false,
                                               lightsMethod);
                image = boxDownsample(renderer.render(cam, rotation), subpixels);
            } else {
                EnvironmentFrameRenderer renderer(*o.object, environment.image, look, which);
                image = boxDownsample(renderer.render(cam, rotation), subpixels);
            }
            py::gil_scoped_acquire acquire;
            return imageArray(std::move(image));
        },
        py::arg("object"), py::arg("environment"), py::kw_only(), py::arg("eye") = py::none(),
        py::arg("target") = py::none(), py::arg("up") = py::make_tuple(0.0, 1.0, 0.0), py::arg("fov") = 30.0,
        py::arg("width") = 512, py::arg("height") = 512, py::arg("azimuth") = 0.0, py::arg("elevation") = 15.0,
        py::arg("fill") = 0.9, py::arg("env_rotation") = 0.0, py::arg("components") = "all",
        py::arg("light_terms") = 0, py::arg("specular") = false, py::arg("specular_blur") = 0,
        py::arg("material") = py::none(), py::arg("size_mm") = py::none(), py::arg("spp") = 1,
        py::arg("ss_path") = "refracted", py::arg("sun_split") = false,
        py::arg("sun_threshold") = SunSplitOptions{}.threshold, py::arg("sun_cell") = SunSplitOptions{}.cellDegrees,
        py::arg("sun_method") = "jb",
        "prt-relight render's frame as an (H, W, 4) float32 linear RGBA array (A = 1 on the object), the same "
        "bit for bit as its EXR for the same arguments. Camera: eye/target/up in mm (default: the object framed "
        "from azimuth/elevation to fill that share of the image), fov in degrees; spp: anti-aliasing samples per "
        "pixel (a square number; render's --spp). material/size_mm: as "
        "set_material, and they stay the object's. ss_path: single scattering along the eye's refracted ray "
        "('refracted') or the inward normal as precomputed ('normal'; render's --ss-path). sun_split, "
        "sun_threshold, sun_cell, sun_method: render's --sun-split, --sun-threshold, --sun-cell, --sun-method "
        "(the environment's brightest "
        "texels as directional lights by Jensen-Buhler; docs/relight.md).");
}

}  // namespace prt::python
