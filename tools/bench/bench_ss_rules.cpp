// prt-bench-ss: the single-scattering kernel under several rules (path quadrature,
// path samples, adaptive direction stride), each against a converged rule, in one run
// on the same vertices (SPEC section 8: ratios measured together). Per rule: CPU
// milliseconds per vertex of singleScatteringVertex (one thread, the rules interleaved
// vertex by vertex so machine load hits them alike), rays per vertex, the share of
// texels interpolated, and the dense transport's deviation from the reference rule
// (relative L2 per vertex, mean and worst; the uniform-light sum, mean and worst).
// docs/single-scattering.md quotes its tables.

#include <CLI/CLI.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <sstream>
#include <string>
#include <vector>

#include "common/error.h"
#include "common/materials.h"
#include "common/mesh.h"
#include "common/mesh_io.h"
#include "common/options.h"
#include "common/raytrace.h"
#include "precompute/passes/single_scattering.h"

using namespace prt;

namespace {

double threadSeconds() {
    timespec t{};
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
    return double(t.tv_sec) + 1e-9 * double(t.tv_nsec);
}

// "gauss:6:4" = rule, path samples, direction stride; an optional fourth field is the
// throughput cut-off (SingleScatteringOptions::minThroughput).
SingleScatteringOptions parseRule(const std::string& text, int cubemapSize) {
    std::string t = text;
    std::replace(t.begin(), t.end(), ':', ' ');
    std::istringstream in(t);
    std::string rule;
    SingleScatteringOptions o;
    o.cubemapSize = cubemapSize;
    if (!(in >> rule >> o.pathSamples >> o.directionStride))
        throw Error(text, "expected RULE:PATH_SAMPLES:STRIDE[:MIN_THROUGHPUT][:exit|ray], e.g. gauss:6:4");
    // The optional fields, in order: a number (MIN_THROUGHPUT), then exit or ray.
    std::string field;
    int index = 0;
    while (in >> field) {
        char* end = nullptr;
        const double cut = std::strtod(field.c_str(), &end);
        if (index == 0 && end && *end == '\0' && end != field.c_str()) {
            o.minThroughput = cut;
        } else if (index <= 1 && (field == "exit" || field == "ray")) {
            o.visibilityFromExitRay = field == "exit";
            index = 1;
        } else {
            throw Error(text, "expected RULE:PATH_SAMPLES:STRIDE[:MIN_THROUGHPUT][:exit|ray], not '" + field + "'");
        }
        ++index;
    }
    o.pathQuadrature = parsePathQuadrature(rule);
    return o;
}

struct Tally {
    double seconds = 0, rays = 0, interpolated = 0, relL2Sum = 0, relL2Worst = 0, sumDevSum = 0, sumDevWorst = 0;
    size_t ran = 0, compared = 0;  // vertices this rule ran on / was compared on
};

}  // namespace

int main(int argc, char** argv) {
    return runMain("prt-bench-ss", [&]() -> int {
        CLI::App app{"prt-bench-ss: single-scattering rules against a converged one, on the same vertices"};
        std::string meshPath, material = "Marble", reference = "midpoint:64:1";
        std::vector<std::string> rules = {"midpoint:16:1", "gauss:6:1", "gauss:6:4", "gauss:4:4"};
        double sizeMm = 30;
        size_t vertices = 40;
        int cubemapSize = 32;
        app.add_option("mesh", meshPath, "Mesh file")->required();
        app.add_option("--size-mm", sizeMm, "Bounding-box diagonal in mm")->capture_default_str();
        app.add_option("-m,--material", material, "Material (isotropic phase)")->capture_default_str();
        app.add_option("--vertices", vertices, "Vertices, spread over the mesh")->capture_default_str();
        app.add_option("--cubemap-size", cubemapSize, "Cubemap face size N")->capture_default_str();
        app.add_option("--reference", reference, "The converged rule RULE:PATH_SAMPLES:STRIDE")->capture_default_str();
        app.add_option("--rules", rules, "Rules to measure, RULE:PATH_SAMPLES:STRIDE[:MIN_THROUGHPUT][:exit|ray] each; exit: V from the "
                       "exit ray (the default), ray: a second ray from the exit point")->capture_default_str();
        if (const auto exitCode = parseCommandLine(app, argc, argv, "prt-bench-ss")) return *exitCode;
        if (vertices < 1) throw Error("--vertices", "must be at least 1");

        TriangleMesh mesh = loadMesh(meshPath);
        scaleToPhysical(mesh, MeshScale{.sizeMm = sizeMm, .mmPerUnit = std::nullopt});
        // The pipeline's single-scattering scene (precompute/job/pipeline.cpp).
        const RayScene scene(mesh, RaySceneOptions{RayBuildQuality::High, true});
        const Material m = materialByName(material);
        std::vector<std::string> names = {reference};
        names.insert(names.end(), rules.begin(), rules.end());
        std::vector<SingleScatteringContext> contexts;
        contexts.reserve(names.size());
        for (const std::string& r : names) contexts.emplace_back(scene, mesh, m, nullptr, parseRule(r, cubemapSize));

        std::vector<Tally> tally(names.size());
        std::vector<float> ref(contexts[0].denseSize()), dense(contexts[0].denseSize());
        SingleScatteringScratch scratch;
        const size_t count = mesh.vertexCount();
        size_t used = 0;
        for (size_t k = 0; k < vertices; ++k) {
            const size_t v = (k * 7919 + 13) % count;  // spread over the mesh, the same for every rule
            double refNorm2 = 0, refSum = 0;
            for (size_t r = 0; r < contexts.size(); ++r) {
                SingleScatteringStats st;
                float* out = r == 0 ? ref.data() : dense.data();
                const double t0 = threadSeconds();
                singleScatteringVertex(contexts[r], contexts[r].pathOrigin(v), mesh.normals[v], out, scratch, st);
                tally[r].seconds += threadSeconds() - t0;
                tally[r].rays += double(st.rays());
                tally[r].interpolated += double(st.interpolatedTexels);
                ++tally[r].ran;
                if (r == 0) {
                    for (float x : ref) {
                        refNorm2 += double(x) * x;
                        refSum += x;
                    }
                    if (!(refNorm2 > 0)) break;  // no single scattering here: nothing to compare
                    ++used;
                    continue;
                }
                double d2 = 0, sum = 0;
                for (size_t i = 0; i < dense.size(); ++i) {
                    d2 += double(dense[i] - ref[i]) * (dense[i] - ref[i]);
                    sum += dense[i];
                }
                const double l2 = std::sqrt(d2 / refNorm2), dev = sum / refSum - 1.0;
                tally[r].relL2Sum += l2;
                tally[r].relL2Worst = std::max(tally[r].relL2Worst, l2);
                tally[r].sumDevSum += dev;
                tally[r].sumDevWorst = std::max(tally[r].sumDevWorst, std::abs(dev));
                ++tally[r].compared;
            }
        }
        std::printf("mesh %s (%zu vertices, %.0f mm), %s, N = %d, %zu vertices measured (%zu with single "
                    "scattering), one thread\n",
                    meshPath.c_str(), count, sizeMm, material.c_str(), cubemapSize, vertices, used);
        std::printf("%-16s %10s %8s %12s %8s %21s %21s\n", "rule", "ms/vertex", "speed", "rays/vertex", "interp",
                    "rel L2 mean / worst", "sum dev mean / worst");
        // Per vertex the rule ran on (the reference also ran on vertices without single
        // scattering, where the others were skipped); speed per vertex against the first rule.
        auto perVertex = [](const Tally& t, double x) { return x / double(std::max<size_t>(t.ran, 1)); };
        const Tally& first = tally.size() > 1 ? tally[1] : tally[0];
        const double base = perVertex(first, first.seconds);
        for (size_t r = 0; r < names.size(); ++r) {
            const Tally& t = tally[r];
            const double texels = double(std::max<size_t>(t.ran, 1)) * double(contexts[0].texelCount());
            const double ms = 1e3 * perVertex(t, t.seconds), speed = base / perVertex(t, t.seconds);
            if (r == 0) {
                std::printf("%-16s %10.2f %7.2fx %12.0f %7.1f%% %21s %21s\n", names[r].c_str(), ms, speed,
                            perVertex(t, t.rays), 100.0 * t.interpolated / texels, "(reference)", "");
                continue;
            }
            const double n = double(std::max<size_t>(t.compared, 1));
            std::printf("%-16s %10.2f %7.2fx %12.0f %7.1f%% %9.3f%% / %6.2f%% %+9.4f%% / %6.3f%%\n", names[r].c_str(),
                        ms, speed, perVertex(t, t.rays), 100.0 * t.interpolated / texels, 100.0 * t.relL2Sum / n,
                        100.0 * t.relL2Worst, 100.0 * t.sumDevSum / n, 100.0 * t.sumDevWorst);
        }
        std::printf("speed: CPU time of the first rule (%s) / this rule's\n", names.size() > 1 ? names[1].c_str() : "");
        return 0;
    });
}
