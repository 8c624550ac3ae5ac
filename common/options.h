#pragma once
// Option groups that several command-line tools share, so each option has one name,
// default and meaning everywhere:
// - the camera (prt-relight render and view, prt-reference; docs/relight.md, "Camera"):
//   lengths in mm, in the object's space after scaling; angles in degrees;
// - -j/--threads (every tool with a parallel stage);
// - the object: its material and physical scale (prt-precompute, prt-pointlight);
// and the one way every tool parses its command line (parseCommandLine).

#include "common/cli_fwd.h"
#include <tbb/global_control.h>
#include <glm/glm.hpp>

#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "common/camera.h"
#include "common/materials.h"
#include "common/mesh.h"
#include "common/tonemap.h"

namespace prt {

struct CameraOptions {
    std::vector<double> eye, target, up{0.0, 1.0, 0.0};  // empty eye/target: automatic
    double fov = 30.0;                                    // vertical, degrees
    int width = 512, height = 512;
    double azimuth = 0.0, elevation = 15.0, fill = 0.9;  // automatic framing
    int spp = 1;  // --spp: sub-pixel samples (offline renderers; relight/render/supersample.h)
};

// Declares --eye --target --up --fov -W -H --azimuth --elevation --fill (group "Camera").
void addCameraOptions(CLI::App& app, CameraOptions& o);

// Declares --base-colour (a flag): the mesh file's base colour tints the translucent
// exitance (relight/render/base_colour.h).
void addBaseColourOption(CLI::App& app, bool& on, const std::string& group = "Object");

// Declares --spp (group "Camera") for the offline renderers and the viewer.
void addSamplesPerPixelOption(CLI::App& app, CameraOptions& o);

// The camera of `o` for an object with this bounding sphere: --eye given -> that
// camera looking at --target (default: the sphere centre); otherwise the sphere framed
// from --azimuth/--elevation so it fills --fill of the smaller image side. Throws
// prt::Error naming the option for non-finite or out-of-range values.
Camera makeCamera(const CameraOptions& o, const glm::dvec3& sphereCentre, double sphereRadius);

// The material: -m/--material (a measured one, default Marble), --sigma-a with
// --sigma-s-prime (custom, mm^-1) or --diffuse-colour with --mfp-mm (the artist's pair,
// common/material_edit.h), --eta and, with `withG`, --g.
struct MaterialOptions {
    std::string material = "Marble";
    std::vector<double> sigmaA, sigmaSPrime;
    std::vector<double> diffuseColour, meanFreePathMm;
    std::optional<double> eta, g;
};
void addMaterialOptions(CLI::App& app, MaterialOptions& o, bool withG, const std::string& group = "Object");
// The validated material; throws prt::Error naming the option.
Material makeMaterial(const MaterialOptions& o);

// The physical size: --size-mm (bounding-box diagonal, default 30) or --mm-per-unit.
struct ScaleOptions {
    std::optional<double> sizeMm, mmPerUnit;
};
void addScaleOptions(CLI::App& app, ScaleOptions& o, const std::string& group = "Object");
// Throws prt::Error when both are given.
MeshScale makeScale(const ScaleOptions& o);

// The display of PNG outputs (common/tonemap.h): --exposure (stops) and --tonemap
// (clamp, reinhard, filmic, chang), group `group`. An unknown operator throws
// prt::Error("--tonemap", ...) while parsing.
void addDisplayOptions(CLI::App& app, DisplayTransform& d, const std::string& group = "Output");

// Parses the command line. --help / --help-all print the help and give exit code 0;
// any other usage error (unknown option, missing or malformed value, missing
// positional) is thrown as one line, prt::Error("", "<CLI11's reason> (see <program>
// [subcommand] --help)"), which runMain prints as "<program>: error: ..." with exit
// code 1 like every other error. Returns nullopt when the tool should run.
std::optional<int> parseCommandLine(CLI::App& app, int argc, char** argv, const std::string& program);

// Declares -j,--threads bound to `threads` (0 = all cores).
void addThreadsOption(CLI::App& app, int& threads, const std::string& help = "Worker threads (default: all cores)");

// Limits every TBB-parallel stage to `threads` workers while it lives (0 = no limit).
// Throws prt::Error("--threads", ...) for a negative count.
class ThreadLimit {
public:
    explicit ThreadLimit(int threads);
    ~ThreadLimit();
    ThreadLimit(const ThreadLimit&) = delete;
    ThreadLimit& operator=(const ThreadLimit&) = delete;

private:
    std::unique_ptr<tbb::global_control> control_;
};

}  // namespace prt
