// prt-vertex-error: a camera-independent accuracy check of a transport file's multiple
// scattering (docs/fidelity.md, docs/tools.md). Relights the file's vertices under an
// environment (the renderers' kernel, V_o . L) and compares them with prt-reference's
// dipole sum evaluated at the same vertices, from the reference's own samples and
// seed (its convergence rule) and its own Monte Carlo irradiance. It shares with the
// file only the mesh, the material and the dipole model: no sample, cubemap, wavelet,
// hierarchy or truncation.
//
// Why beside prt-reference's images: a frame sees one side of the object, and the
// truncation error shifts the mean of different sides in opposite directions, so a
// frame's figure can look better (or worse) than the object is.

#include <CLI/CLI.hpp>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <cmath>
#include <cstdio>
#include <optional>
#include <string>
#include <vector>

#include "common/envmap.h"
#include "common/error.h"
#include "common/mesh.h"
#include "common/mesh_io.h"
#include "common/options.h"
#include "common/progress.h"
#include "common/raytrace.h"
#include "common/sampling.h"
#include "common/transport_file.h"
#include "common/transport_params.h"
#include "common/util.h"
#include "common/material_edit.h"
#include "relight/prt/editable_transport.h"
#include "relight/prt/light_vector.h"
#include "relight/prt/relight_kernel.h"
#include "tools/reference/reference.h"

using namespace prt;

namespace {

struct Options {
    std::string mesh, transport, environment;
    double envRotation = 0.0;
    size_t stride = 8;
    std::optional<size_t> samples;
    size_t maxSamples = 300000;
    size_t envSamples = 0;  // 0: referenceIrradianceDirections(samples)
    uint64_t mcSeed = 1;
    int threads = 0;
    std::string material;          // editable files: relight with this material ...
    std::optional<double> sizeMm;  // ... at this object size (default: the file's)
};

void printGroup(const char* name, const VertexComparison::Group& g) {
    if (g.vertices == 0) return;
    std::printf("  %-5s %7zu vertices   mean ratio %.4f\n", name, g.vertices, g.ratio());
}

int run(const Options& o) {
    const Stopwatch start;
    const ThreadLimit limit(o.threads);
    if (!std::isfinite(o.envRotation)) throw Error("--env-rotation", "must be finite");
    if (o.stride < 1) throw Error("--stride", "must be at least 1");
    if (o.maxSamples < 1) throw Error("--max-samples", "must be at least 1");
    if (o.samples && *o.samples < 1) throw Error("--samples", "must be at least 1");

    TriangleMesh mesh = loadMesh(o.mesh);
    TransportFile file = loadTransportFile(o.transport, {mesh.vertexCount(), meshFingerprint(mesh)});
    scaleToPhysical(mesh, MeshScale{.sizeMm = std::nullopt, .mmPerUnit = file.mmPerUnit});
    const TransportParameters params = readTransportParameters(file.parameters, o.transport);
    if (!params.material) throw Error(o.transport, "has no material parameters (sigma_s_prime, sigma_a, eta)");
    // The material the reference sums: the file's, or an editable file's edit, whose size
    // is a material scale (R_d(r; s sigma) = s^2 R_d(s r; sigma), material_edit.h) on the
    // file's mesh.
    Material material = *params.material;
    const bool editableFile = bool(file.radialBasis);  // EditableTransport moves the basis out
    if (!editableFile && (!o.material.empty() || o.sizeMm))
        throw Error(o.transport, "is not editable (prt-precompute --editable): --material and --size-mm need one");
    if (editableFile) {
        const double fileSizeMm = double(bounds(mesh).diagonal());
        EditableTransport editable(file, fileSizeMm, o.transport);
        const Material edit =
            o.material.empty() ? editable.fileMaterial() : parseMaterial(o.material, editable.fileMaterial().eta);
        const double sizeMm = o.sizeMm.value_or(fileSizeMm);
        if (editable.setMaterial(edit, sizeMm))
            warn("--material: " + edit.name + " applied with the file's eta " + formatParameter(material.eta));
        file.components.insert(file.components.begin(), editable.recombine());
        material = scaledMaterial(editable.material(), sizeMm / fileSizeMm);
    }
    bool hasMultipleScattering = false;
    for (const TransportComponent& c : file.components)
        hasMultipleScattering |= c.kind == ComponentKind::MultipleScattering;
    if (!hasMultipleScattering) throw Error(o.transport, "has no multiple-scattering component to check");

    const Image environment = loadEnvironment(o.environment, NonFinitePolicy::ClampNegative);
    const glm::dmat3 rotation = rotationY(o.envRotation);

    // The file's side: the renderers' light vector and kernel.
    const LightVector light = makeLightVector(environment, int(file.cubemapSize), rotation);
    VertexRadiance radiance;
    relightVertices(file, light, ScatteringComponents{true, false}, radiance);

    // The reference's side: its own samples (convergence rule), irradiance and dipole sum.
    const double area = totalArea(mesh);
    const ReferenceSamplePlan plan =
        planReferenceSamples(material, area, params.seed.value_or(1), o.maxSamples);
    const size_t sampleCount = o.samples.value_or(plan.count);
    if (plan.capped && !o.samples)
        warn("the convergence rule asks for more samples than --max-samples " + std::to_string(o.maxSamples) +
             ": the reference's sample sum is less converged");
    const RayScene scene(mesh);
    SampleSet samples;
    {
        Progress p("reference samples", sampleCount, "samples");
        samples = poissonDiskSamples(mesh, sampleCount, plan.seed);
        p.advance(sampleCount);
    }
    IrradianceEstimatorOptions irradianceOptions;
    irradianceOptions.directions = o.envSamples ? o.envSamples : referenceIrradianceDirections(sampleCount);
    irradianceOptions.seed = o.mcSeed;
    const EnvironmentSampler sampler(environment, rotation);
    SampleIrradiance irradiance;
    {
        Progress p("reference irradiance (" + std::to_string(irradianceOptions.directions) + " directions per sample)",
                   samples.samples.size(), "samples");
        irradiance = computeSampleIrradiance(sampler, &scene, samples, material.eta, irradianceOptions, &p);
    }
    std::vector<glm::vec3> positions;
    positions.reserve(samples.samples.size());
    for (const SurfaceSample& s : samples.samples) positions.push_back(s.position);
    const MultipleScatteringReference reference(material, std::move(positions), samples.areaPerSample,
                                                std::move(irradiance));

    const size_t compared = (mesh.vertexCount() + o.stride - 1) / o.stride;
    std::vector<glm::dvec3> test(compared), ref(compared), variance(compared);
    std::vector<glm::vec3> normals(compared);
    {
        Progress p("reference at every " + std::to_string(o.stride) + (o.stride == 1 ? "st" : "th") + " vertex",
                   compared, "vertices");
        tbb::parallel_for(tbb::blocked_range<size_t>(0, compared, 16), [&](const tbb::blocked_range<size_t>& r) {
            for (size_t i = r.begin(); i != r.end(); ++i) {
                const size_t v = i * o.stride;
                const RadianceEstimate e = reference.diffuse(mesh.positions[v]);
                ref[i] = e.value;
                variance[i] = e.variance;
                test[i] = glm::dvec3(radiance.diffuse[v]);
                normals[i] = mesh.normals[v];
            }
            p.advance(r.size());
        });
    }
    const VertexComparison c = compareVertexValues(test, ref, normals, variance);

    std::printf("file: %s, %zu vertices, N = %u; environment %s (rotated %.4g degrees about +Y)\n",
                o.transport.c_str(), mesh.vertexCount(), file.cubemapSize, o.environment.c_str(), o.envRotation);
    if (editableFile) std::printf("material (editable file): %s\n", describeMaterial(material).c_str());
    std::printf("reference: %zu samples (own seed %llu), %zu directions per sample\n", samples.samples.size(),
                (unsigned long long)plan.seed, irradianceOptions.directions);
    std::printf("multiple scattering at %zu vertices (every %zu%s):\n", c.all.vertices, o.stride,
                o.stride == 1 ? "" : "th");
    std::printf("  relative L2 error %.3g%% (reference noise %.3g%%)\n", 100 * c.relativeL2, 100 * c.referenceNoise);
    printGroup("all", c.all);
    printGroup("up", c.up);
    printGroup("side", c.side);
    printGroup("down", c.down);
    std::printf("total %s\n", formatDuration(start.seconds()).c_str());
    return 0;
}

}  // namespace

int main(int argc, char** argv) {
    return runMain("prt-vertex-error", [&]() -> int {
        CLI::App app{
            "prt-vertex-error: camera-independent check of a transport file's multiple scattering. Relights\n"
            "every k-th vertex (V . L, the renderers' kernel) and compares it with prt-reference's dipole sum\n"
            "at the same vertices, from the reference's own samples and Monte Carlo irradiance. Prints the\n"
            "relative L2 error and the mean ratio over all vertices and over those facing up, sideways, down.\n"
            "Example:\n"
            "  prt-vertex-error bunny.off -t bunny.prt -e city.exr --stride 8"};
        Options o;
        app.add_option("mesh", o.mesh, "Mesh file the transport file was computed for (.obj .ply .off .stl, .gz)")
            ->required();
        app.add_option("-t,--transport", o.transport, "Transport file to check")->required();
        app.add_option("-e,--environment", o.environment, "Lat-long HDR environment (EXR, HDR, ...; width = 2 height)")
            ->required();
        app.add_option("--env-rotation", o.envRotation, "Rotate the environment by this many degrees about +Y")
            ->capture_default_str();
        app.add_option("--stride", o.stride, "Compare every k-th vertex")->capture_default_str();
        app.add_option("--samples", o.samples, "Reference surface samples (default: the convergence rule)");
        app.add_option("--max-samples", o.maxSamples, "Budget: at most this many reference samples")
            ->capture_default_str();
        app.add_option("--env-samples", o.envSamples,
                       "Monte Carlo directions per reference sample (default: 16.8 M rays / samples, in [64, 2048])");
        app.add_option("--mc-seed", o.mcSeed, "Seed of the Monte Carlo directions")->capture_default_str();
        app.add_option("--material", o.material,
                       "Editable files: relight and check with this material (a name, sigma:SA:SS or colour:C:L; "
                       "docs/editable-transport.md)");
        app.add_option("--size-mm", o.sizeMm, "Editable files: at this object size (mm, bounding-box diagonal)");
        addThreadsOption(app, o.threads);
        if (const auto exitCode = parseCommandLine(app, argc, argv, "prt-vertex-error")) return *exitCode;
        return run(o);
    });
}
