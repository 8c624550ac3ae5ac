#pragma once
// prt-pointlight as a library function: offline frames of a translucent object under point, spot and
// directional lights (docs/point-lights.md): the translucent irradiance cache of Keng et al. 2006
// (--method cache, the default; irradiance_cache.h), the Jensen-Buhler hierarchical
// renderer it accelerates (--method jb), the brute-force sum (--method brute) or
// texture-space importance sampling (--method tsis). Mesh + material + physical size +
// lights in, linear EXR + sRGB PNG out, with the time of every stage. --specular and
// --single-scattering add those terms to every frame of every method, references
// included (point_animation.h, SurfaceTermSettings).
//
// Animations (--turntable N; --light-path P0:P1 --frames N) run in
// point_animation.h, whose header states what is reused between frames: for a
// turntable the irradiance samples and the octree (the lights are fixed relative to
// the object) but not the caches (they live on the visible points of each frame); for
// a moving light only the mesh, its ray scene, the sample positions/areas and the
// G-buffer of the fixed camera; for a material / size path (--material-path,
// --size-path: Chang et al. Fig. 11) everything but what depends on the material, the
// renderer changing its material in place (setMaterial).
//
// Placement: like prt-precompute, the mesh is scaled about the origin by --size-mm
// (bounding-box diagonal, default 30 mm) or --mm-per-unit; lights are given in mm in
// that scaled frame (the bounding box is printed to help placing them).

//
// The command is a struct of the tool's options (PointLightCommand), the options'
// declarations (addPointLightOptions: names, defaults, help) and the run
// (runPointLightCommand), which checks them with the tool's one-line messages, prints
// the tool's summary lines on stdout and hands every image to an ImageWriter: files for
// prt-pointlight, memory for the Python module, the same images either way.

#include "common/cli_fwd.h"

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "common/image.h"
#include "common/options.h"
#include "relight/pointlight/irradiance_cache.h"
#include "relight/pointlight/point_single_scattering.h"
#include "relight/pointlight/point_specular.h"
#include "relight/pointlight/texture_space_sampling.h"

namespace prt {

struct PointLightCommand {
    std::string mesh, output, lightsFile;
    std::vector<std::string> lights;
    ScaleOptions scale;
    MaterialOptions material;
    std::string samples = "faces";
    std::string nearField = "auto";
    std::optional<size_t> sampleCount;
    uint64_t seed = 1;
    double epsilon = 0.05;
    int leafSize = 8;
    std::string fresnel = "exact";
    DisplayTransform display;
    bool baseColour = false;
    bool compareBrute = false;
    std::string method = "cache";
    double a = IrradianceCacheOptions{}.a;
    double radius = 0.0;
    std::string splitDisk = "paper";
    bool compareJb = false, cacheImage = false;
    int threads = 0;
    CameraOptions camera;
    int turntable = 0, frames = 0;
    std::string lightPath, materialPath, sizePath;
    // Texture-space importance sampling (--method tsis).
    TextureSpaceOptions tsis;
    std::string split = "hybrid", evaluate = "vertex";
    int atlasSize = kDefaultIrradianceMapSize;
    // The surface terms added to every frame of every method (point_animation.h,
    // SurfaceTermSettings): --specular, --specular-roughness, --single-scattering,
    // --single-scattering-samples.
    bool specular = false;
    double specularRoughness = kDefaultSpecularRoughness;
    bool singleScattering = false;
    int singleScatteringSamples = PointSingleScatteringOptions{}.pathSamples;
};

// Declares every option of prt-pointlight (the mesh positional and -o included) on app.
void addPointLightOptions(CLI::App& app, PointLightCommand& o);

// Runs the command: a single frame, or an animation's frames, written through `writer`
// as <output>.exr / .png (and <output>_jb, _brute, _error, _caches ... as the options
// ask). Returns the exit code (0). Throws prt::Error for bad options and inputs.
int runPointLightCommand(const PointLightCommand& o, ImageWriter& writer);

}  // namespace prt
