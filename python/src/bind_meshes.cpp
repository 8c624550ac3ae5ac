// Meshes: load any format the command line reads, arrays of vertices, faces and
// normals (views, no copies), the physical scale.

#include <optional>

#include "common/mesh.h"
#include "common/mesh_io.h"
#include "python/src/bindings.h"

namespace prt::python {

namespace {

// A loaded mesh and what loading it found; `mmPerUnit` is 1 until scaled.
struct PyMesh {
    TriangleMesh mesh;
    MeshReport report;
    std::string path;
    double mmPerUnit = 1.0;
};

py::dict reportDict(const MeshReport& r) {
    py::dict d;
    d["format"] = r.format;
    d["compressed"] = r.compressed;
    d["file_vertices"] = r.fileVertices;
    d["file_faces"] = r.fileFaces;
    d["polygons_triangulated"] = r.polygonsTriangulated;
    d["degenerate_faces"] = r.degenerateFaces;
    d["removed_faces"] = r.removedFaces;
    d["unreferenced_vertices"] = r.unreferencedVertices;
    d["boundary_edges"] = r.boundaryEdges;
    d["non_manifold_edges"] = r.nonManifoldEdges;
    d["inconsistent_edges"] = r.inconsistentEdges;
    d["euler_characteristic"] = r.eulerCharacteristic;
    d["vertices"] = r.vertices;
    d["triangles"] = r.triangles;
    return d;
}

}  // namespace

void bindMeshes(py::module_& m) {
    py::class_<PyMesh>(m, "Mesh",
                       "A triangle mesh as the tools load it: triangulated, degenerate faces and unused vertices "
                       "removed, closed and consistently oriented (loading refuses anything else), unit vertex "
                       "normals. Arrays are read-only views of the mesh's own memory.")
        .def_property_readonly(
            "vertices",
            [](py::object self) {
                const PyMesh& p = self.cast<const PyMesh&>();
                return view(&p.mesh.positions.data()->x, {py::ssize_t(p.mesh.vertexCount()), 3}, self);
            },
            "(V, 3) float32 positions: the file's units, or mm once scaled")
        .def_property_readonly(
            "normals",
            [](py::object self) {
                const PyMesh& p = self.cast<const PyMesh&>();
                return view(&p.mesh.normals.data()->x, {py::ssize_t(p.mesh.normals.size()), 3}, self);
            },
            "(V, 3) float32 unit vertex normals (Max's weights, docs/conventions.md)")
        .def_property_readonly(
            "faces",
            [](py::object self) {
                const PyMesh& p = self.cast<const PyMesh&>();
                return view(&p.mesh.triangles.data()->x, {py::ssize_t(p.mesh.triangleCount()), 3}, self);
            },
            "(F, 3) uint32 vertex indices, counter-clockwise seen from outside")
        .def_property_readonly("vertex_count", [](const PyMesh& p) { return p.mesh.vertexCount(); })
        .def_property_readonly("triangle_count", [](const PyMesh& p) { return p.mesh.triangleCount(); })
        .def_property_readonly("path", [](const PyMesh& p) { return p.path; })
        .def_property_readonly("mm_per_unit", [](const PyMesh& p) { return p.mmPerUnit; },
                               "The scale applied by scaled() (1 for a mesh as loaded)")
        .def_property_readonly("report", [](const PyMesh& p) { return reportDict(p.report); },
                               "What loading found and repaired (prt-precompute's mesh summary)")
        .def_property_readonly("area", [](const PyMesh& p) { return totalArea(p.mesh); })
        .def_property_readonly("volume", [](const PyMesh& p) { return signedVolume(p.mesh); })
        .def_property_readonly("bounds",
                               [](const PyMesh& p) {
                                   const Bounds b = bounds(p.mesh);
                                   return py::make_tuple(tupleOf(glm::dvec3(b.lo)), tupleOf(glm::dvec3(b.hi)));
                               },
                               "((x, y, z) lowest, (x, y, z) highest) corner of the bounding box")
        .def_property_readonly("fingerprint",
                               [](const PyMesh& p) { return meshFingerprint(p.mesh); },
                               "The hash a transport file stores to recognise its mesh")
        .def(
            "scaled",
            [](const PyMesh& p, std::optional<double> sizeMm, std::optional<double> mmPerUnit) {
                PyMesh out = p;
                MeshScale scale;
                scale.sizeMm = sizeMm;
                scale.mmPerUnit = mmPerUnit;
                if (!sizeMm && !mmPerUnit) scale.sizeMm = 30.0;
                out.mmPerUnit = p.mmPerUnit * scaleToPhysical(out.mesh, scale);
                return out;
            },
            py::kw_only(), py::arg("size_mm") = py::none(), py::arg("mm_per_unit") = py::none(),
            "A copy in millimetres: the bounding-box diagonal made size_mm (default 30, as --size-mm), "
            "or every position times mm_per_unit")
        .def("save", [](const PyMesh& p, const std::string& path) { saveMesh(p.mesh, path); }, py::arg("path"),
             "Writes the mesh (.obj .ply .off .stl, by the extension)")
        .def("__repr__", [](const PyMesh& p) {
            return "<prt.Mesh " + std::to_string(p.mesh.vertexCount()) + " vertices, " +
                   std::to_string(p.mesh.triangleCount()) + " triangles" +
                   (p.path.empty() ? "" : ", from " + p.path) + ">";
        });

    m.def(
        "load_mesh",
        [](const std::string& path, std::optional<double> sizeMm, std::optional<double> mmPerUnit) {
            PyMesh p;
            p.path = path;
            p.mesh = withoutGil([&] { return loadMesh(path, &p.report); });
            if (sizeMm || mmPerUnit) {
                MeshScale scale;
                scale.sizeMm = sizeMm;
                scale.mmPerUnit = mmPerUnit;
                p.mmPerUnit = scaleToPhysical(p.mesh, scale);
            }
            return p;
        },
        py::arg("path"), py::kw_only(), py::arg("size_mm") = py::none(), py::arg("mm_per_unit") = py::none(),
        "Loads a mesh (.obj .ply .off .stl, optionally .gz) as every tool does; size_mm or mm_per_unit "
        "scales it to millimetres as --size-mm / --mm-per-unit do.");
}

}  // namespace prt::python
