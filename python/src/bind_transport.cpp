// Transport files: load (verified), save (atomic), describe (header only or loaded),
// and the per-vertex vectors as arrays.

#include <optional>

#include "common/mesh.h"
#include "common/mesh_io.h"
#include "common/blocked_vectors.h"
#include "common/transport_file.h"
#include "common/transport_params.h"
#include "python/src/bindings.h"

namespace prt::python {

namespace {

py::dict parametersDict(const std::vector<std::pair<std::string, std::string>>& parameters) {
    py::dict d;
    for (const auto& [key, value] : parameters) d[py::str(key)] = value;
    return d;
}

// The short name Python uses for a component: "ms", "ss", "ss:k" (the k-th term of the
// factored phase), "profiles:j" (an editable file's j-th group of profile vectors).
std::string shortName(ComponentKind kind, uint32_t term) {
    switch (kind) {
    case ComponentKind::MultipleScattering: return "ms";
    case ComponentKind::SingleScatteringIsotropic: return "ss";
    case ComponentKind::SingleScatteringTerm: return "ss:" + std::to_string(term);
    case ComponentKind::MultipleScatteringProfiles: return "profiles:" + std::to_string(term);
    }
    return componentName(kind, term);
}

py::dict infoDict(const TransportFileInfo& info) {
    py::dict d;
    d["version"] = info.version;
    d["cubemap_size"] = info.cubemapSize;
    d["sh_terms"] = info.shTerms;
    d["vertex_count"] = info.mesh.vertexCount;
    d["mesh_hash"] = info.mesh.positionHash;
    d["mm_per_unit"] = info.mmPerUnit;
    d["parameters"] = parametersDict(info.parameters);
    py::list components;
    for (const auto& c : info.components) {
        py::dict e;
        e["name"] = shortName(c.kind, c.term);
        e["description"] = componentName(c.kind, c.term);
        e["vertex_count"] = c.vertexCount;
        e["coefficient_count"] = c.coefficientCount;
        e["payload_bytes"] = c.payloadBytes;
        e["blocked"] = c.blocked;
        components.append(e);
    }
    d["components"] = components;
    d["view_map_size"] = info.viewMapSize;
    d["view_map_terms"] = info.viewMapTerms;
    d["editable"] = info.radialRange.has_value();
    if (info.radialRange) {
        py::dict r;
        r["zr_min_mm"] = info.radialRange->zrMin;
        r["zr_max_mm"] = info.radialRange->zrMax;
        r["alpha_min"] = info.radialRange->alphaMin;
        r["alpha_max"] = info.radialRange->alphaMax;
        r["eta"] = info.radialRange->eta;
        r["r_max_mm"] = info.radialRange->rMax;
        r["profiles"] = info.radialProfiles;
        d["radial_range"] = r;
    }
    d["file_bytes"] = info.fileBytes;
    d["text"] = describe(info);
    return d;
}

const TransportComponent& findComponent(const TransportFile& file, const std::string& name) {
    for (const TransportComponent& c : file.components)
        if (shortName(c.kind, c.term) == name) return c;
    std::string names;
    for (const TransportComponent& c : file.components) names += (names.empty() ? "" : ", ") + shortName(c.kind, c.term);
    throw Error("component", "'" + name + "' is not in the file (it has: " + names + ")");
}

}  // namespace

void bindTransport(py::module_& m) {
    py::class_<PyTransport, std::shared_ptr<PyTransport>>(
        m, "Transport",
        "A transport file in memory (docs/transport-format.md): per-vertex sparse RGB Haar vectors over a "
        "6 x N x N lighting cubemap (+ SH terms), one per component.",
        py::dynamic_attr())
        .def_property_readonly("path", [](const PyTransport& t) { return t.path; })
        .def_property_readonly("cubemap_size", [](const PyTransport& t) { return t.file->cubemapSize; })
        .def_property_readonly("sh_terms", [](const PyTransport& t) { return t.file->shTerms; })
        .def_property_readonly("vertex_count", [](const PyTransport& t) { return t.file->mesh.vertexCount; })
        .def_property_readonly("mm_per_unit", [](const PyTransport& t) { return t.file->mmPerUnit; })
        .def_property_readonly("parameters", [](const PyTransport& t) { return parametersDict(t.file->parameters); },
                               "The precompute's parameters (material, seed, ...), as stored")
        .def_property_readonly("components",
                               [](const PyTransport& t) {
                                   std::vector<std::string> names;
                                   for (const TransportComponent& c : t.file->components)
                                       names.push_back(shortName(c.kind, c.term));
                                   return names;
                               },
                               "The components' short names: ms, ss, ss:k (a phase term), profiles:j (editable)")
        .def_property_readonly("editable", [](const PyTransport& t) { return t.file->radialBasis.has_value(); })
        .def("describe", [](PyTransport& t) { return locked(t, [&] { return describe(*t.file); }); },
             "prt-relight info --full's text")
        .def(
            "vectors",
            [](py::object self, const std::string& component) {
                PyTransport& t = self.cast<PyTransport&>();
                py::dict d;
                auto arrays = [&](const SparseRgbVectors& v, py::handle owner) {
                    d["blocked"] = false;
                    d["offsets"] = view(v.offsets.data(), {py::ssize_t(v.offsets.size())}, owner);
                    d["indices"] = view(v.indices.data(), {py::ssize_t(v.indices.size())}, owner);
                    d["values"] = view(v.values.data(), {py::ssize_t(v.indices.size()), 3}, owner);
                    d["scales"] = view(v.scales.data(), {py::ssize_t(v.vertexCount()), 3}, owner);
                    d["haar_bits"] = v.haarBits;
                    d["sh_from"] = v.shFrom == UINT32_MAX ? py::object(py::none()) : py::object(py::int_(v.shFrom));
                    if (!v.shScales.empty())
                        d["sh_scales"] = view(v.shScales.data(), {py::ssize_t(v.vertexCount()), 3}, owner);
                };
                auto blockArrays = [&](const BlockedRgbVectors& b, py::handle owner) {
                    const py::ssize_t lanes = py::ssize_t(kVertexBlock), blocks = py::ssize_t(b.blockCount());
                    d["blocked"] = true;
                    d["order"] = view(b.order.data(), {py::ssize_t(b.order.size())}, owner);
                    d["offsets"] = view(b.offsets.data(), {py::ssize_t(b.offsets.size())}, owner);
                    d["indices"] = view(b.indices.data(), {py::ssize_t(b.indices.size())}, owner);
                    d["values"] = view(b.values.data(), {py::ssize_t(b.indices.size()), 3, lanes}, owner);
                    d["scales"] = view(b.scales.data(), {blocks, 3, lanes}, owner);
                    d["sh_from"] = b.shFrom == UINT32_MAX ? py::object(py::none()) : py::object(py::int_(b.shFrom));
                    if (b.shFrom != UINT32_MAX) d["sh_scales"] = view(b.shScales.data(), {blocks, 3, lanes}, owner);
                };
                if (!t.edited) {
                    const TransportComponent& c = findComponent(*t.file, component);
                    if (c.blocked())
                        blockArrays(c.blocks, self);
                    else
                        arrays(c.vectors, self);
                    return d;
                }
                // An edited object's vectors change with its material: a copy, which its
                // arrays keep alive.
                auto* copy = new TransportComponent(locked(t, [&] { return findComponent(*t.file, component); }));
                py::capsule owner(copy, [](void* p) { delete static_cast<TransportComponent*>(p); });
                if (copy->blocked())
                    blockArrays(copy->blocks, owner);
                else
                    arrays(copy->vectors, owner);
                return d;
            },
            py::arg("component") = "ms",
            "The component's stored arrays, d['blocked'] telling the layout. Per vertex: vertex v owns "
            "indices[offsets[v]:offsets[v+1]] and the int16 values of the same rows; value = q * scales[v] per "
            "channel, or with haar_bits 8 (an editable file's profiles) q * sh_scales[v] for indices >= sh_from "
            "(the Haar values then lie in -127..127). Blocked (blocks of 16 vertices sharing indices): block b holds the vertices "
            "order[16 b:16 b + 16] (lanes) and the indices[offsets[b]:offsets[b+1]]; values[n, c, lane] is int8, "
            "value = q * scales[b, c, lane], or q * sh_scales[b, c, lane] for indices >= sh_from. Views of a "
            "loaded file; copies for an editable Object's transport, whose multiple scattering changes with "
            "set_material")
        .def(
            "vertex_vector",
            [](PyTransport& t, size_t v, const std::string& component) {
                std::vector<uint32_t> idx;
                std::vector<float> rgb;
                const size_t count = locked(t, [&] {
                    const TransportComponent& c = findComponent(*t.file, component);
                    if (v < c.vertexCount()) c.dequantizeVertex(v, idx, rgb);
                    return c.vertexCount();
                });
                if (v >= count) throw py::index_error("vertex " + std::to_string(v) + " of " + std::to_string(count));
                const py::ssize_t k = py::ssize_t(idx.size());
                return py::make_tuple(adopt(std::move(idx), {k}), adopt(std::move(rgb), {k, 3}));
            },
            py::arg("v"), py::arg("component") = "ms",
            "Vertex v's vector: (coefficient indices uint32 (K,), RGB values float32 (K, 3)); indices < 6 N^2 are "
            "Haar coefficients of the cubemap, the rest SH terms")
        .def(
            "save",
            [](PyTransport& t, const std::string& path) {
                if (t.edited)
                    throw Error(t.path, "is an editable object's transport: its multiple scattering is the edited "
                                        "material's, which its parameters do not name (save the file itself)");
                withoutGil([&] { saveTransportFile(path, *t.file); });
            },
            py::arg("path"), "Writes the file (atomically: a temporary file, then a rename)")
        .def(
            "__eq__",
            [](PyTransport& a, PyTransport& b) {
                if (&a == &b) return true;
                py::gil_scoped_release release;
                std::scoped_lock lock(a.mutex, b.mutex);  // both at once: no order to deadlock on
                return *a.file == *b.file;
            },
            py::is_operator())
        .def("__repr__", [](const PyTransport& t) {
            return "<prt.Transport " + std::to_string(t.file->mesh.vertexCount) + " vertices, cubemap 6x" +
                   std::to_string(t.file->cubemapSize) + "^2, " + std::to_string(t.file->components.size()) +
                   " components" + (t.path.empty() ? "" : ", from " + t.path) + ">";
        });

    m.def(
        "load_transport",
        [](const std::string& path, const py::object& mesh) {
            auto t = std::make_shared<PyTransport>();
            t->path = path;
            std::optional<MeshFingerprint> expected;
            if (!mesh.is_none()) {
                const TriangleMesh tm = loadMesh(stringArgument(mesh, "mesh"));
                expected = MeshFingerprint{tm.vertexCount(), meshFingerprint(tm)};
            }
            t->file = std::make_shared<TransportFile>(withoutGil(
                [&] { return expected ? loadTransportFile(path, *expected) : loadTransportFile(path); }));
            return t;
        },
        py::arg("path"), py::kw_only(), py::arg("mesh") = py::none(),
        "Loads a transport file and verifies every checksum; with mesh (a mesh file's path) also that the file "
        "was computed for that mesh");
    m.def("transport_info", [](const std::string& path) { return infoDict(readTransportFileInfo(path)); },
          py::arg("path"), "prt-relight info's header as a dict (the vectors are not read)");
}

}  // namespace prt::python
