#pragma once
// What every binding file of the Python module shares: the bind functions that
// module.cpp calls, numpy views of C++ arrays, and the checks of incoming arrays.
// Errors: prt::Error becomes FileNotFoundError (a missing file) or ValueError (any
// other bad input), with the same one-line message the command line prints after
// "<program>: error: "; prt::Cancelled becomes KeyboardInterrupt; a wrong dtype is a
// TypeError and a wrong shape a ValueError, both naming the argument.

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <glm/glm.hpp>

#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "common/error.h"
#include "common/image.h"
#include "common/transport_file.h"
#include "relight/prt/relight_kernel.h"
#include "relight/prt/relight_object.h"

namespace prt::python {

namespace py = pybind11;

void bindErrors(py::module_& m);
void bindMeshes(py::module_& m);
void bindMaterials(py::module_& m);
void bindImages(py::module_& m);
void bindTransport(py::module_& m);
void bindEnvironments(py::module_& m);
void bindRendering(py::module_& m);
void bindPrecompute(py::module_& m);
void bindCommands(py::module_& m);

// A transport file in memory (prt.Transport). It may be a part of a RelightObject
// (prt.Object.transport), which the shared pointer then keeps alive. `scratch` is the
// relight's output, kept between calls so a relight allocates nothing.
struct PyTransport {
    std::shared_ptr<TransportFile> file;
    std::string path;
    VertexRadiance scratch;
    std::mutex mutex;     // guards scratch, and the file when it is an object's (set_material changes it)
    bool edited = false;  // an editable object's: its multiple scattering is the current material's
};

// A mesh + transport file placed as the relighting tools place them (prt.Object).
struct PyObject {
    std::shared_ptr<RelightObject> object;
    std::string meshPath, transportPath;
    std::shared_ptr<PyTransport> transport;  // aliases object->transport
};

// A numpy array over `data` (no copy) that keeps `owner` alive; `shape` in elements,
// C order. Read-only unless `writable`.
template <typename T>
py::array_t<T> view(const T* data, std::vector<py::ssize_t> shape, py::handle owner, bool writable = false) {
    std::vector<py::ssize_t> strides(shape.size());
    py::ssize_t stride = sizeof(T);
    for (size_t i = shape.size(); i-- > 0;) {
        strides[i] = stride;
        stride *= shape[i];
    }
    py::array_t<T> a(shape, strides, data, owner);
    if (!writable) py::detail::array_proxy(a.ptr())->flags &= ~py::detail::npy_api::NPY_ARRAY_WRITEABLE_;
    return a;
}

// A new array that owns a copy of `values` (moved into a capsule: no second copy).
template <typename T>
py::array_t<T> adopt(std::vector<T>&& values, std::vector<py::ssize_t> shape) {
    auto* owned = new std::vector<T>(std::move(values));
    py::capsule free(owned, [](void* p) { delete static_cast<std::vector<T>*>(p); });
    return view<T>(owned->data(), std::move(shape), free, true);
}

// An image as an (H, W, C) float32 array that owns its pixels.
py::array_t<float> imageArray(Image&& image);

// `value` as an image: a float (float16/32/64) array of shape (H, W, C) with C in
// [minChannels, maxChannels], or (H, W) when minChannels == 1. `name` is the argument's
// name in the messages (TypeError for the dtype, ValueError for the shape).
Image imageFromArray(const py::handle& value, const std::string& name, int minChannels, int maxChannels);

// Three finite numbers (a tuple, a list or an array), or one number for all three.
glm::dvec3 vec3From(const py::handle& value, const std::string& name);
py::tuple tupleOf(const glm::dvec3& v);

// Runs a long job (precompute, a command) on a worker thread while this thread waits
// without the GIL, reports progress to `progress(stage, done, total, unit)` (None: no
// reports) and lets Python see Ctrl-C; a KeyboardInterrupt, or an exception from the
// callable, cancels the job (Progress::requestCancel) and is raised once it has stopped.
// The job's own error is rethrown. `quiet`: no progress lines on stderr meanwhile;
// `threads`: at most that many workers (0 = all cores).
void runCancellable(const std::function<void()>& job, const py::object& progress, bool quiet, int threads);

// `value` as a string; TypeError naming the argument otherwise.
std::string stringArgument(const py::handle& value, const std::string& name);

// Runs f with the GIL released and the transport's mutex held (in that order, so a
// thread waiting for the mutex never holds the GIL).
template <typename F>
auto locked(PyTransport& t, F&& f) {
    py::gil_scoped_release release;
    std::lock_guard lock(t.mutex);
    return f();
}
template <typename F>
auto locked(const PyObject& o, F&& f) {
    return locked(*o.transport, std::forward<F>(f));
}

// Runs f with the GIL released (long calls: other Python threads run meanwhile).
template <typename F>
auto withoutGil(F&& f) {
    py::gil_scoped_release release;
    return f();
}

}  // namespace prt::python
