// The Python module prt._prt (docs/python.md): the library's meshes, materials,
// transport files, environments, relighting, renderers, precomputation, reference
// and comparison, with numpy arrays in and out. python/prt/__init__.py re-exports it.

#include "python/src/bindings.h"

PYBIND11_MODULE(_prt, m) {
    using namespace prt::python;
    m.doc() = "Translucent precomputed radiance transport: precompute, relight, render, compare";
    bindErrors(m);
    bindImages(m);
    bindMeshes(m);
    bindMaterials(m);
    bindTransport(m);
    bindEnvironments(m);
    bindRendering(m);
    bindPrecompute(m);
    bindCommands(m);
}
