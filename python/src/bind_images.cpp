// Errors, images (read, write, compare) and the array helpers of bindings.h.

#include <cmath>
#include <filesystem>
#include <new>

#include "common/error.h"
#include "common/image.h"
#include "common/image_compare.h"
#include "common/progress.h"
#include "common/tonemap.h"
#include "python/src/bindings.h"

namespace prt::python {

namespace {

// A missing file or folder: the readers' and writers' own words for it, or a file that
// could not be opened and does not exist.
bool missingFile(const Error& e) {
    const std::string& r = e.reason();
    auto endsWith = [&](const std::string& tail) {
        return r.size() >= tail.size() && r.compare(r.size() - tail.size(), tail.size(), tail) == 0;
    };
    if (r == "no such file" || r == "file does not exist" || r == "no such file or folder") return true;
    if (r.rfind("directory '", 0) == 0 && endsWith("' does not exist")) return true;
    std::error_code ec;
    return r.rfind("cannot open", 0) == 0 && !e.subject().empty() && !std::filesystem::exists(e.subject(), ec);
}

std::string shapeText(const py::array& a) {
    std::string s = "(";
    for (py::ssize_t i = 0; i < a.ndim(); ++i) s += (i ? ", " : "") + std::to_string(a.shape(i));
    return s + (a.ndim() == 1 ? ",)" : ")");
}

py::dict channelDict(const ChannelErrors& c) {
    py::dict d;
    d["relative_rmse"] = c.relativeRmse;
    d["psnr"] = c.psnr;
    d["max_absolute"] = c.maxAbsolute;
    d["max_relative"] = c.maxRelative;
    d["max_relative_at"] = py::make_tuple(c.maxRelativeX, c.maxRelativeY);
    d["mean_ratio"] = c.meanRatio;
    return d;
}

Image imageArgument(const py::handle& value, const std::string& name) {
    if (py::isinstance<py::str>(value)) return readImage(value.cast<std::string>());
    return imageFromArray(value, name, 1, 4);
}

}  // namespace

py::array_t<float> imageArray(Image&& image) {
    const py::ssize_t h = image.height, w = image.width, c = image.channels;
    return adopt(std::move(image.pixels), {h, w, c});
}

Image imageFromArray(const py::handle& value, const std::string& name, int minChannels, int maxChannels) {
    if (!py::isinstance<py::array>(value))
        throw py::type_error(name + ": expected a numpy array, got " + std::string(py::str(value.get_type().attr("__name__"))));
    const py::array a = py::reinterpret_borrow<py::array>(value);
    const char kind = a.dtype().kind();
    if (kind != 'f')
        throw py::type_error(name + ": expected a float array (float16, float32 or float64), got " +
                             std::string(py::str(a.dtype())));
    const bool gray = a.ndim() == 2 && minChannels == 1;
    const int channels = gray ? 1 : a.ndim() == 3 ? int(a.shape(2)) : -1;
    if ((a.ndim() != 3 && !gray) || channels < minChannels || channels > maxChannels || a.shape(0) <= 0 ||
        a.shape(1) <= 0) {
        const std::string want = minChannels == maxChannels ? std::to_string(minChannels)
                                                            : std::to_string(minChannels) + ".." + std::to_string(maxChannels);
        throw py::value_error(name + ": expected an (H, W, C) array with C = " + want + ", got shape " + shapeText(a));
    }
    if (a.shape(0) > kMaxImageSide || a.shape(1) > kMaxImageSide)
        throw py::value_error(name + ": larger than " + std::to_string(kMaxImageSide) + " pixels on a side");
    const auto f = py::array_t<float, py::array::c_style | py::array::forcecast>::ensure(a);
    Image image(int(a.shape(1)), int(a.shape(0)), channels);
    std::copy(f.data(), f.data() + image.pixels.size(), image.pixels.begin());
    return image;
}

glm::dvec3 vec3From(const py::handle& value, const std::string& name) {
    glm::dvec3 v;
    if (py::isinstance<py::float_>(value) || py::isinstance<py::int_>(value)) {
        v = glm::dvec3(value.cast<double>());
    } else {
        std::vector<double> values;
        try {
            values = value.cast<std::vector<double>>();
        } catch (const py::cast_error&) {
            throw py::type_error(name + ": expected three numbers (r, g, b)");
        }
        if (values.size() != 3)
            throw py::value_error(name + ": expected three numbers (r, g, b), got " + std::to_string(values.size()));
        v = glm::dvec3(values[0], values[1], values[2]);
    }
    for (int c = 0; c < 3; ++c)
        if (!std::isfinite(v[c])) throw py::value_error(name + ": must be finite");
    return v;
}

py::tuple tupleOf(const glm::dvec3& v) { return py::make_tuple(v.x, v.y, v.z); }

std::string stringArgument(const py::handle& value, const std::string& name) {
    if (!py::isinstance<py::str>(value) && !py::isinstance(value, py::module_::import("os").attr("PathLike")))
        throw py::type_error(name + ": expected a string, got " + std::string(py::str(value.get_type().attr("__name__"))));
    return py::str(value).cast<std::string>();
}

void bindErrors(py::module_& m) {
    py::register_exception_translator([](std::exception_ptr p) {
        try {
            if (p) std::rethrow_exception(p);
        } catch (const Cancelled& e) {
            PyErr_SetString(PyExc_KeyboardInterrupt, e.what());
        } catch (const Error& e) {
            PyErr_SetString(missingFile(e) ? PyExc_FileNotFoundError : PyExc_ValueError, e.what());
        } catch (const std::bad_alloc&) {
            PyErr_SetString(PyExc_MemoryError, "out of memory");
        }
        // Anything else falls through to pybind11's own translation (RuntimeError for a
        // std::exception).
    });
}

void bindImages(py::module_& m) {
    m.def("read_image", [](const std::string& path) { return imageArray(readImage(path)); }, py::arg("path"),
          "An image file (EXR, HDR, PNG, ...) as an (H, W, C) float32 array, linear.");
    m.def(
        "write_exr",
        [](const std::string& path, const py::handle& image, bool half) {
            const Image im = imageFromArray(image, "image", 1, 4);
            writeExr(path, im, half ? ExrPixelType::Half : ExrPixelType::Float);
        },
        py::arg("path"), py::arg("image"), py::arg("half") = false,
        "Writes an (H, W, C) float array as OpenEXR (atomically: a temporary file, then a rename).");
    m.def(
        "write_png",
        [](const std::string& path, const py::handle& image, double exposure, const std::string& tonemap) {
            const Image im = imageFromArray(image, "image", 1, 4);
            writePng(path, im, DisplayTransform{exposure, parseToneMapOperator(tonemap)});
        },
        py::arg("path"), py::arg("image"), py::arg("exposure") = 0.0, py::arg("tonemap") = "clamp",
        "Writes a linear (H, W, C) float array as an sRGB PNG, `exposure` stops brighter, through the tone "
        "mapping operator `tonemap` (clamp, reinhard, filmic, chang; docs/conventions.md, \"Display\").");
    m.def(
        "tonemap",
        [](const py::handle& image, double exposure, const std::string& tonemap) {
            const Image im = imageFromArray(image, "image", 1, 4);
            const DisplayTransform display{exposure, parseToneMapOperator(tonemap)};
            return imageArray(displayImage(im, displayMapping(im, display)));
        },
        py::arg("image"), py::arg("exposure") = 0.0, py::arg("tonemap") = "clamp",
        "The display-linear values (H, W, 3) in [0, 1] that write_png encodes (before the sRGB curve).");
    m.def(
        "compare",
        [](const py::handle& test, const py::handle& reference, double alphaThreshold, double relativeFloor) {
            CompareOptions options;
            options.alphaThreshold = alphaThreshold;
            options.relativeFloor = relativeFloor;
            const Image t = imageArgument(test, "test");
            const Image r = imageArgument(reference, "reference");
            const CompareResult res = withoutGil([&] { return compareImages(t, r, options); });
            py::dict d;
            d["width"] = res.width;
            d["height"] = res.height;
            d["mask"] = res.mask;
            d["compared_pixels"] = res.comparedPixels;
            d["coverage_mismatch"] = res.coverageMismatch;
            d["peak"] = res.peak;
            d["relative_rmse"] = res.overall.relativeRmse;
            d["psnr"] = res.overall.psnr;
            d["max_relative"] = res.overall.maxRelative;
            d["mean_ratio"] = res.overall.meanRatio;
            d["overall"] = channelDict(res.overall);
            py::list channels;
            for (int c = 0; c < res.colourChannels; ++c) channels.append(channelDict(res.channel[c]));
            d["channels"] = channels;
            d["text"] = formatCompareResult(res);
            return d;
        },
        py::arg("test"), py::arg("reference"), py::arg("alpha_threshold") = 0.5, py::arg("relative_floor") = 1e-3,
        "prt-compare's numbers as a dict: images as arrays or file paths; pixels with the reference's "
        "alpha above alpha_threshold are compared (docs/tools.md, prt-compare).");
}

}  // namespace prt::python
