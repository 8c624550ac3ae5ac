#pragma once
// prt-reference as a library function: the brute-force reference renderer (docs/reference.md). Same mesh
// placement, camera, environment and material as prt-relight render, but no
// cubemap, no wavelets, no hierarchy, no truncation: per-sample irradiance by Monte
// Carlo from the full-resolution lat-long map with Embree visibility, then the dipole
// summed over all samples for every pixel; single scattering by Monte Carlo along
// the refracted view ray with the exact phase function (tools/reference/reference.h).
//
// The transport file is read only for its header and parameters (mesh fingerprint,
// mm per unit, material and g, sample count and seed, components), never for its
// vectors.

//
// The command is a struct of the tool's options (ReferenceCommand), their declarations
// (addReferenceOptions) and the run (runReferenceCommand), which checks them with the
// tool's one-line messages, prints its summary lines on stdout and hands every image to
// an ImageWriter: files for prt-reference, memory for the Python module.

#include <CLI/CLI.hpp>

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "common/image.h"
#include "common/options.h"
#include "tools/reference/reference.h"

namespace prt {

struct ReferenceCommand {
    std::string mesh, transport, environment, output;
    std::vector<std::string> lights;
    std::string lightsFile;
    CameraOptions camera;
    double envRotation = 0.0;
    DisplayTransform display;
    bool baseColour = false;  // --base-colour
    std::string ground;       // --ground: the ground's transport file (common/ground.h)
    std::string materialMap, mapMaterial;  // --material-map, --map-material
    MaterialOptions material;
    bool materialGiven = false;  // any of the material options was given
    ScaleOptions scale;
    size_t pixelStride = 1;
    std::optional<size_t> samples;
    std::optional<uint64_t> seed;
    bool sameSamples = false;
    std::optional<double> spacingFraction;  // default: kReferenceSpacingFraction, or ...Light... under lights
    std::optional<size_t> maxSamples;
    size_t envSamples = 0;  // 0: from the ray budget (or 2048 with --same-samples)
    size_t convergenceStride = 4;
    IrradianceEstimatorOptions irradiance;
    std::string components;  // empty: ms, plus ss when the file has it
    SingleScatteringReferenceOptions ss;
    std::string ssPath = "refracted";
    std::optional<double> g;
    bool componentImages = false;
    bool perVertex = false;
    std::string noiseImage;
    int threads = 0;
};

// Declares every option of prt-reference (the mesh positional and -o included) on app.
void addReferenceOptions(CLI::App& app, ReferenceCommand& o);
// After parsing: records which options were given where a default cannot tell
// (materialGiven: the material options override the transport file's).
void noteGivenReferenceOptions(const CLI::App& app, ReferenceCommand& o);

// Runs the command: <output>.exr / .png (and the per-component images and the noise
// image when asked) through `writer`. Returns the exit code (0). Throws prt::Error for
// bad options and inputs.
int runReferenceCommand(const ReferenceCommand& o, ImageWriter& writer);

}  // namespace prt
