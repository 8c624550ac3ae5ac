// prt-pointlight and prt-reference from Python: keyword arguments become the tool's
// options (parsed by the same declarations, so names, defaults, checks and messages are
// the tool's), and the images the tool would write come back as arrays.

#include <CLI/CLI.hpp>

#include <cmath>
#include <map>

#include "common/options.h"
#include "python/src/bindings.h"
#include "relight/pointlight/pointlight_command.h"
#include "tools/reference/reference_command.h"

namespace prt::python {

namespace {

// Keeps every image a command writes, by the path it would have had.
class MemoryImageWriter : public ImageWriter {
public:
    void exr(const std::string& path, const Image& image) override { keep(path, image, true); }
    void png(const std::string& path, const Image& image, const DisplayTransform*) override { keep(path, image, false); }

    // "image" for <prefix>.exr, "jb" for <prefix>_jb.exr, "error" for <prefix>_error.png,
    // ...; a PNG beside an EXR of the same name is the same image, tone-mapped: the
    // linear EXR is kept. Paths outside the prefix keep their own name.
    py::dict images(const std::string& prefix) {
        py::dict d;
        for (auto& [path, entry] : kept_) {
            std::string key = path.substr(0, path.rfind('.'));
            if (key.rfind(prefix, 0) == 0) {
                key = key.substr(prefix.size());
                if (!key.empty() && key[0] == '_') key = key.substr(1);
                if (key.empty()) key = "image";
            }
            if (d.contains(py::str(key)) && !entry.linear) continue;
            d[py::str(key)] = imageArray(std::move(entry.image));
        }
        return d;
    }

private:
    struct Entry {
        Image image;
        bool linear = false;
    };
    void keep(const std::string& path, const Image& image, bool linear) { kept_[path] = Entry{image, linear}; }
    std::map<std::string, Entry> kept_;  // sorted: the EXR "x.exr" before the PNG "x.png"
};

// `name=value` as the tool's option: --name (underscores as dashes) with the value
// attached (--eye=-10,0,50); True a flag, False nothing; a list of numbers comma-joined;
// a list of strings the option repeated (--light).
void appendOption(std::vector<std::string>& args, const std::string& name, const py::handle& value) {
    std::string flag = "--" + name;
    std::replace(flag.begin(), flag.end(), '_', '-');
    auto number = [&](const py::handle& v) {
        if (py::isinstance<py::bool_>(v)) throw py::type_error(name + ": expected numbers");
        if (py::isinstance<py::int_>(v)) return std::to_string(v.cast<long long>());
        double x = 0.0;
        try {
            x = v.cast<double>();
        } catch (const py::cast_error&) {
            throw py::type_error(name + ": expected numbers");
        }
        char buf[32];
        std::snprintf(buf, sizeof buf, "%.17g", x);
        return std::string(buf);
    };
    if (py::isinstance<py::bool_>(value)) {
        if (value.cast<bool>()) args.push_back(flag);
    } else if (py::isinstance<py::str>(value)) {
        args.push_back(flag + "=" + value.cast<std::string>());
    } else if (py::isinstance<py::int_>(value) || py::isinstance<py::float_>(value)) {
        args.push_back(flag + "=" + number(value));
    } else if (py::isinstance<py::list>(value) || py::isinstance<py::tuple>(value) || py::isinstance<py::array>(value)) {
        if (py::len(value) == 0) return;
        std::string joined;
        bool strings = false;
        for (const py::handle& item : value) {
            if (py::isinstance<py::str>(item)) {
                strings = true;
                args.push_back(flag + "=" + item.cast<std::string>());
            } else {
                joined += (joined.empty() ? "" : ",") + number(item);
            }
        }
        if (!joined.empty() && strings) throw py::type_error(name + ": mixes strings and numbers");
        if (!strings) args.push_back(flag + "=" + joined);
    } else if (!value.is_none()) {
        throw py::type_error(name + ": expected a string, a number, a bool or a list, got " +
                             std::string(py::str(value.get_type().attr("__name__"))));
    }
}

// Parses `args` as the tool's command line would (parseCommandLine: the same one-line
// messages, "(see <program> --help)" included).
void parseArguments(CLI::App& app, const std::string& program, std::vector<std::string> args) {
    args.insert(args.begin(), program);
    std::vector<char*> argv;
    for (std::string& a : args) argv.push_back(a.data());
    if (parseCommandLine(app, int(argv.size()), argv.data(), program)) throw Error(program, "--help is not available here");
}

constexpr const char* kPrefix = "frame";

// The command line of a command: the mesh, the output prefix (never written), the
// lights (--light, repeated; --lights for the file) and the other options.
std::vector<std::string> commandArguments(const std::string& mesh, const py::object& lights,
                                          const py::object& lightsFile, const py::kwargs& options) {
    std::vector<std::string> args{mesh, std::string("--output=") + kPrefix};
    appendOption(args, "light", py::isinstance<py::str>(lights) ? py::list(py::make_tuple(lights)) : lights);
    appendOption(args, "lights", lightsFile);
    for (const auto& [key, value] : options) {
        const std::string name = py::str(key);
        if (name == "output" || name == "o") throw py::type_error(name + ": the images are returned, not written");
        if (name == "light") throw py::type_error("light: give the lights as `lights`");
        appendOption(args, name, value);
    }
    return args;
}

}  // namespace

void bindCommands(py::module_& m) {
    m.def(
        "render_point_lights",
        [](const std::string& mesh, const py::object& lights, const py::object& lightsFile, const py::kwargs& options) {
            const std::vector<std::string> args = commandArguments(mesh, lights, lightsFile, options);
            CLI::App app;
            PointLightCommand command;
            addPointLightOptions(app, command);
            parseArguments(app, "prt-pointlight", args);
            MemoryImageWriter writer;
            // The point-light renderers have no progress steps: Ctrl-C takes effect when the run ends.
            runCancellable([&] { runPointLightCommand(command, writer); }, py::none(), false, command.threads);
            return writer.images(kPrefix);
        },
        py::arg("mesh"), py::arg("lights") = py::list(), py::arg("lights_file") = py::none(),
        "prt-pointlight's frame(s) as arrays: a dict with 'image' (H, W, 4) float32 linear RGBA, equal bit for "
        "bit to its EXR, and whatever else the options ask ('jb', 'brute', 'error' with compare_jb / "
        "compare_brute; 'caches', 'gradient', 'variance' with cache_image; '0000', '0001', ... for an "
        "animation). lights: 'point:X,Y,Z:R,G,B' or 'dir:X,Y,Z:R,G,B' texts (mm, W/sr or W/m^2), one or a list "
        "(--light); lights_file: a JSON light scene (--lights). Keyword "
        "arguments are prt-pointlight's long options (method='tsis', material='Skin1', size_mm=40, width=256, "
        "compare_jb=True, ...). Ctrl-C raises KeyboardInterrupt when the run ends (the renderers have no progress "
        "steps to stop at). Prints the tool's summary lines on stdout.");
    m.def(
        "render_reference",
        [](const std::string& mesh, const py::object& lights, const py::object& lightsFile, const py::object& progress,
           const py::kwargs& options) {
            const std::vector<std::string> args = commandArguments(mesh, lights, lightsFile, options);
            CLI::App app;
            ReferenceCommand command;
            addReferenceOptions(app, command);
            parseArguments(app, "prt-reference", args);
            noteGivenReferenceOptions(app, command);
            MemoryImageWriter writer;
            runCancellable([&] { runReferenceCommand(command, writer); }, progress, false, command.threads);
            return writer.images(kPrefix);
        },
        py::arg("mesh"), py::arg("lights") = py::list(), py::arg("lights_file") = py::none(),
        py::arg("progress") = py::none(),
        "prt-reference's frame as arrays: a dict with 'image' (H, W, 4) float32 linear RGBA, equal bit for bit "
        "to its EXR ('ms' and 'ss' with component_images=True; the noise image under the path given as "
        "noise_image). Keyword arguments are prt-reference's long options (transport='bunny.prt', "
        "environment='forest.exr', width=256, pixel_stride=4, ...); lights and lights_file as render_point_lights. "
        "Prints the tool's "
        "summary lines on stdout.");
}

}  // namespace prt::python
