// prt-bench-tsis: the frame rate of texture-space importance sampling (Chang et al.
// 2008; docs/point-lights.md, docs/performance.md) and, optionally, its error against
// the Jensen-Buhler reference, for a list of sample counts N: the analogues of the
// paper's Table 2 (everything a new light position needs: irradiance map, shadow maps,
// draws, the sums), Table 3 (the sums alone: the light is still, the view changes) and
// Fig. 7 (RMSE against N).
//
// With --material-change B: the cost of a live material change (docs/point-lights.md,
// "Live material and size"), setMaterial alternating between the material and B, for
// the texture-space renderer (the --split mode; R_p, the R_d tables, the local filter),
// Jensen-Buhler and the irradiance cache (both split-disk models), each with the
// per-vertex sums that follow it for TSIS.
//
// Every figure is the median of --repeat runs in this process. "per vertex" frames add
// the CPU's per-pixel interpolation and shading (what the viewer does on the GPU) only
// when --evaluate pixel; the per-vertex frame time is the lighting + the vertex sums.

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <string>
#include <thread>
#include <vector>

#include "common/atomic_file.h"
#include "common/error.h"
#include "common/image_compare.h"
#include "common/material_edit.h"
#include "common/mesh_io.h"
#include "common/options.h"
#include "common/util.h"
#include "relight/pointlight/irradiance_cache.h"
#include "relight/pointlight/jensen_buhler.h"
#include "relight/render/gbuffer.h"
#include "relight/pointlight/surface_atlas.h"
#include "relight/pointlight/texture_space_sampling.h"

using namespace prt;

namespace {

struct Options {
    std::string mesh, json;
    ScaleOptions scale;
    MaterialOptions material;
    std::vector<std::string> lights;
    std::vector<int> samples{49, 100, 169, 256, 400, 900, 1600, 2500};
    std::string split = "hybrid", evaluate = "vertex";
    int atlasSize = kDefaultIrradianceMapSize, repeat = 5, seeds = 1;
    double epsilon = 0.0, exposure = 0.0;
    bool reference = false;
    std::string materialChange;
    CameraOptions camera;
    int threads = 0;
    TextureSpaceOptions tsis;
};

// "median (min .. max) ms" of a list of seconds.
std::string spread(const std::vector<double>& seconds) {
    char buf[96];
    std::snprintf(buf, sizeof buf, "%.3f ms (%.3f .. %.3f)", 1e3 * median(seconds),
                  1e3 * *std::min_element(seconds.begin(), seconds.end()),
                  1e3 * *std::max_element(seconds.begin(), seconds.end()));
    return buf;
}

// setMaterial alternating between `material` and --material-change, --repeat times each
// way, for every renderer: the live material edit's cost (the lighting is kept).
nlohmann::json materialChangeCost(const Options& o, const TriangleMesh& mesh, const RayScene& scene,
                                  const SurfaceAtlas& atlas, const Material& material, const std::vector<Light>& lights,
                                  const TextureSpaceOptions& to) {
    const Material other = parseMaterial(o.materialChange, material.eta, material.g, "--material-change");
    const int runs = 2 * o.repeat;
    std::printf("material change %s <-> %s, %d changes each:\n", material.name.c_str(), other.name.c_str(), runs);
    nlohmann::json out = nlohmann::json::object();
    auto report = [&](const std::string& what, const std::vector<double>& seconds) {
        std::printf("  %-44s %s\n", what.c_str(), spread(seconds).c_str());
        out[what] = {{"median_ms", 1e3 * median(seconds)},
                     {"min_ms", 1e3 * *std::min_element(seconds.begin(), seconds.end())},
                     {"max_ms", 1e3 * *std::max_element(seconds.begin(), seconds.end())},
                     {"runs", seconds.size()}};
    };
    std::vector<TextureSpaceMode> modes{to.mode};
    if (to.mode != TextureSpaceMode::Sampling) modes.push_back(TextureSpaceMode::Sampling);
    for (const TextureSpaceMode mode : modes) {
        TextureSpaceOptions om = to;
        om.mode = mode;
        om.samples = o.samples.empty() ? 900 : o.samples.front();
        TextureSpaceRenderer r(mesh, scene, atlas, material, om);
        r.setLights(lights);
        std::vector<double> change, sums;
        for (int k = 0; k < runs; ++k) {
            const Stopwatch t;
            r.setMaterial(k % 2 == 0 ? other : material);
            change.push_back(t.seconds());
            const Stopwatch s;
            if (r.vertexExitance().empty()) throw Error("bench", "no vertices");
            sums.push_back(s.seconds());
        }
        report(std::string("tsis ") + toString(mode) + " setMaterial", change);
        report(std::string("tsis ") + toString(mode) + " per-vertex sums after it (N = " +
                   std::to_string(om.samples) + ")",
               sums);
    }
    IrradianceSamples faces = faceCentroidSamples(mesh);
    computeIrradiance(faces, scene, lights, material.eta, to.fresnel);
    {
        JensenBuhler jb(material, IrradianceOctree(faces), {.fresnel = to.fresnel});
        std::vector<double> change;
        for (int k = 0; k < runs; ++k) {
            const Stopwatch t;
            jb.setMaterial(k % 2 == 0 ? other : material);
            change.push_back(t.seconds());
        }
        report("jb setMaterial", change);
    }
    for (const SplitDiskModel model : {SplitDiskModel::Paper, SplitDiskModel::Exact}) {
        IrradianceCache cache(material, IrradianceOctree(faces), {.fresnel = to.fresnel, .splitDisk = model});
        std::vector<double> change;
        for (int k = 0; k < runs; ++k) {
            const Stopwatch t;
            cache.setMaterial(k % 2 == 0 ? other : material);
            change.push_back(t.seconds());
        }
        report(std::string("cache (split disk ") + toString(model) + ") setMaterial", change);
    }
    return out;
}

int run(const Options& o) {
    const ThreadLimit limit(o.threads);
    if (o.repeat < 1) throw Error("--repeat", "must be at least 1");
    if (o.seeds < 1) throw Error("--seeds", "must be at least 1");
    const Material material = makeMaterial(o.material);
    TriangleMesh mesh = loadMesh(o.mesh);
    scaleToPhysical(mesh, makeScale(o.scale));
    std::vector<Light> lights;
    for (const std::string& t : o.lights) lights.push_back(parseLight(t));
    if (lights.empty()) throw Error("--light", "give at least one light");
    const RayScene scene(mesh);
    checkLightsOutside(scene, lights);
    const BoundingSphere sphere = boundingSphere(mesh);
    const Camera camera = makeCamera(o.camera, sphere.centre, sphere.radius);
    const GBuffer g = traceGBuffer(scene, mesh, camera);
    const bool perVertex = toLower(o.evaluate) == "vertex";
    if (!perVertex && toLower(o.evaluate) != "pixel") throw Error("--evaluate", "expected pixel or vertex");
    TextureSpaceOptions to = o.tsis;
    to.mode = parseTextureSpaceMode(o.split);
    const SurfaceAtlas atlas = buildSurfaceAtlas(mesh, o.atlasSize);

    Image reference;
    double referenceSeconds = 0.0;
    if (o.reference) {
        IrradianceSamples faces = faceCentroidSamples(mesh);
        computeIrradiance(faces, scene, lights, material.eta, to.fresnel);
        const JensenBuhler jb(material, IrradianceOctree(faces), {.epsilon = o.epsilon, .fresnel = to.fresnel});
        const Stopwatch t;
        reference = jb.render(g);
        referenceSeconds = t.seconds();
    }
    std::printf("prt-bench-tsis: %s, %zu triangles, %zu vertices, %s, %s, atlas %d^2 (%.0f%% covered), %d x %d "
                "(%zu object pixels), evaluated per %s, %d threads; median of %d runs\n",
                o.mesh.c_str(), mesh.triangleCount(), mesh.vertexCount(), material.name.c_str(), toString(to.mode),
                o.atlasSize, 100.0 * atlas.stats.coverage, g.width, g.height, g.objectPixels(),
                perVertex ? "vertex" : "pixel", o.threads > 0 ? o.threads : int(std::thread::hardware_concurrency()), o.repeat);
    if (o.reference)
        std::printf("reference: Jensen-Buhler epsilon %g over %zu face centroids, per pixel, %.2f s\n", o.epsilon,
                    mesh.triangleCount(), referenceSeconds);
    std::printf("| N | irradiance map ms | shadow maps ms | draws ms | sums ms | shading ms | new light: ms (fps) | "
                "sums only: fps |%s\n",
                o.reference ? " RMSE (displayed) | rel. RMSE |" : "");
    std::printf("|---|---|---|---|---|---|---|---|%s\n", o.reference ? "---|---|" : "");
    nlohmann::json rows = nlohmann::json::array();
    for (int n : o.samples) {
        TextureSpaceOptions on = to;
        on.samples = n;
        TextureSpaceRenderer r(mesh, scene, atlas, material, on);
        std::vector<double> irr, maps, draws, sums, shading;
        // The view's pixel list, once per view as in prt-pointlight (per vertex only).
        const VertexInterpolation view = perVertex ? r.interpolation(g) : VertexInterpolation{};
        Image image;
        for (int k = 0; k < o.repeat; ++k) {
            r.setLights(lights);
            const TextureSpaceTimings& t = r.timings();
            irr.push_back(1e3 * t.irradianceSeconds);
            maps.push_back(1e3 * t.shadowMapSeconds);
            draws.push_back(1e3 * t.samplingSeconds);
            Stopwatch s;
            if (perVertex) {
                const std::vector<glm::vec3> m = r.vertexExitance();
                sums.push_back(s.milliseconds());
                s.restart();
                image = r.shadeVertices(view, m);
                shading.push_back(s.milliseconds());
            } else {
                image = r.render(g);  // the sums and the shading at every pixel
                sums.push_back(s.milliseconds());
                shading.push_back(0.0);
            }
        }
        const double total = median(irr) + median(maps) + median(draws) + median(sums) + median(shading);
        std::printf("| %d | %.2f | %.2f | %.2f | %.2f | %.2f | %.1f (%.1f) | %.1f |", n, median(irr), median(maps),
                    median(draws), median(sums), median(shading), total, 1e3 / total, 1e3 / median(sums));
        nlohmann::json row = {{"samples", n},           {"irradiance_ms", median(irr)}, {"shadow_maps_ms", median(maps)},
                              {"draws_ms", median(draws)}, {"sums_ms", median(sums)},    {"shading_ms", median(shading)},
                              {"frame_ms", total}};
        if (o.reference) {
            // RMS over seeds of the error of one frame.
            double d2 = 0.0, r2 = 0.0;
            for (int seed = 1; seed <= o.seeds; ++seed) {
                r.redraw(n, uint64_t(seed));
                const Image frame = perVertex ? r.renderPerVertex(g) : r.render(g);
                const double d = displayRmse(frame, reference, o.exposure);
                const double rel = compareImages(frame, reference).overall.relativeRmse;
                d2 += d * d;
                r2 += rel * rel;
            }
            const double d = std::sqrt(d2 / o.seeds), rel = std::sqrt(r2 / o.seeds);
            std::printf(" %.4f | %.4f |", d, rel);
            row["rmse_display"] = d;
            row["relative_rmse"] = rel;
        }
        std::printf("\n");
        std::fflush(stdout);
        rows.push_back(row);
    }
    nlohmann::json change;
    if (!o.materialChange.empty()) change = materialChangeCost(o, mesh, scene, atlas, material, lights, to);
    if (!o.json.empty()) {
        nlohmann::json j = {{"mesh", o.mesh},
                            {"triangles", mesh.triangleCount()},
                            {"vertices", mesh.vertexCount()},
                            {"material", material.name},
                            {"split", toString(to.mode)},
                            {"evaluate", perVertex ? "vertex" : "pixel"},
                            {"atlas", o.atlasSize},
                            {"width", g.width},
                            {"height", g.height},
                            {"exposure", o.exposure},
                            {"rows", rows}};
        if (!change.is_null()) j["material_change"] = change;
        writeAtomically(o.json, [&](const std::string& tmp) {
            std::ofstream out(tmp);
            out << j.dump(2) << "\n";
            if (!out) throw Error(o.json, "cannot write");
        });
    }
    return 0;
}

}  // namespace

int main(int argc, char** argv) {
    return runMain("prt-bench-tsis", [&]() -> int {
        CLI::App app{"prt-bench-tsis: frame time of texture-space importance sampling against the sample count, "
                     "and its error against Jensen-Buhler (docs/performance.md)"};
        Options o;
        app.add_option("mesh", o.mesh, "Mesh file")->required();
        addScaleOptions(app, o.scale);
        addMaterialOptions(app, o.material, /*withG=*/false);
        app.add_option("--light", o.lights, "point:X,Y,Z:R,G,B or dir:X,Y,Z:R,G,B, repeatable")->required();
        app.add_option("--samples", o.samples, "Sample counts N")->delimiter(',')->capture_default_str();
        app.add_option("--split", o.split, "hybrid, sampling, local or global")->capture_default_str();
        app.add_option("--evaluate", o.evaluate, "vertex (the viewer's) or pixel")->capture_default_str();
        app.add_option("--atlas-size", o.atlasSize, "Irradiance map resolution")->capture_default_str();
        app.add_option("--light-map", o.tsis.lightMapSize, "Shadow map resolution")->capture_default_str();
        app.add_option("--rings", o.tsis.rings, "L")->capture_default_str();
        app.add_option("--ring-samples", o.tsis.ringSamples, "C")->capture_default_str();
        app.add_option("--cluster-angle", o.tsis.clusterAngle, "theta (0: every sample)")->capture_default_str();
        app.add_option("--importance-bound", o.tsis.importanceBound, "c in mm^-1 (R_p)")->capture_default_str();
        app.add_option("--repeat", o.repeat, "Runs per N (the median is reported)")->capture_default_str();
        app.add_flag("--reference", o.reference, "Also render Jensen-Buhler and report the error at each N");
        app.add_option("--epsilon", o.epsilon, "Jensen-Buhler's epsilon for --reference (0 = brute force)")
            ->capture_default_str();
        app.add_option("--seeds", o.seeds, "Seeds the error is averaged over (RMS)")->capture_default_str();
        app.add_option("--exposure", o.exposure, "Exposure of the displayed-image RMSE")->capture_default_str();
        app.add_option("--json", o.json, "Also write the rows as JSON");
        app.add_option("--material-change", o.materialChange,
                       "Also time setMaterial between -m and this material (a name, sigma:... or colour:...; the "
                       "same eta) for every renderer, 2 x --repeat changes");
        addCameraOptions(app, o.camera);
        addThreadsOption(app, o.threads);
        if (const auto code = parseCommandLine(app, argc, argv, "prt-bench-tsis")) return *code;
        return run(o);
    });
}
