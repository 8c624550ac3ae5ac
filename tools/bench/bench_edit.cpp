// prt-bench-edit: what a live material edit costs on an editable transport file
// (docs/editable-transport.md, docs/performance.md): per edit, the weights
// (EditableTransport::setMaterial) and the multiple-scattering relight with the light
// standing still (relightProjected); once per light, projectLight; once per material
// that stands still, recombine; and the relight kernel on the recombined file (what a
// light change costs), beside the same kernel on a plain file of the same object when
// --plain is given (its runs after the editable file's). Each figure is the
// median of --repeat runs with the minimum and maximum, the edits alternating between
// the --material values; --json writes them with the files' sizes. Not included: the
// light vector (environment -> Haar; the same for every file), single scattering's
// relight (cached while the light stands still) and the frame's shading.

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <optional>
#include <string>
#include <vector>

#include "common/atomic_file.h"
#include "common/envmap.h"
#include "common/error.h"
#include "common/material_edit.h"
#include "common/options.h"
#include "common/transport_file.h"
#include "common/util.h"
#include "relight/prt/light_vector.h"
#include "relight/prt/relight_kernel.h"
#include "relight/prt/relight_object.h"

using namespace prt;

namespace {

struct Figure {
    std::vector<double> ms;
    void add(double v) { ms.push_back(v); }
    double min() const { return *std::min_element(ms.begin(), ms.end()); }
    double max() const { return *std::max_element(ms.begin(), ms.end()); }
    std::string text() const {
        char buf[96];
        std::snprintf(buf, sizeof buf, "%8.3f ms (min %.3f, max %.3f, %zu runs)", median(ms), min(), max(), ms.size());
        return buf;
    }
    nlohmann::json json() const {
        return {{"median_ms", median(ms)}, {"min_ms", min()}, {"max_ms", max()}, {"runs", ms.size()}};
    }
};

}  // namespace

int main(int argc, char** argv) {
    return runMain("prt-bench-edit", [&] {
        CLI::App app{"prt-bench-edit: the cost of a live material edit on an editable transport file"};
        std::string mesh, transport, environment, plain, json;
        std::vector<std::string> materials{"Marble", "Skin1"};
        int repeat = 21, threads = 0;
        app.add_option("mesh", mesh, "Mesh file of the transport file")->required();
        app.add_option("transport", transport, "Editable transport file (prt-precompute --editable)")->required();
        app.add_option("environment", environment, "Lat-long environment")->required();
        app.add_option("--material", materials, "Materials the edits alternate between (parseMaterial forms)")
            ->capture_default_str();
        app.add_option("--plain", plain, "A transport file of the same object made without --editable");
        app.add_option("--repeat", repeat, "Runs per figure (>= 5)")->capture_default_str();
        app.add_option("--json", json, "Also write the figures (median, min, max of each) and the files' sizes as JSON");
        addThreadsOption(app, threads);
        if (auto code = parseCommandLine(app, argc, argv, "prt-bench-edit")) return *code;
        if (repeat < 5) throw Error("--repeat", "must be >= 5 (a goal is met on the median of at least 5 runs)");
        const ThreadLimit limit(threads);

        RelightObject object = loadRelightObject(mesh, transport);
        if (!object.editable) throw Error(transport, "is not editable (prt-precompute --editable)");
        EditableTransport& e = *object.editable;
        std::vector<Material> edits;
        for (const std::string& text : materials) edits.push_back(parseMaterial(text, e.fileMaterial().eta));
        const Image env = loadEnvironment(environment, NonFinitePolicy::ClampNegative);
        const LightVector light = makeLightVector(env, int(object.transport.cubemapSize));
        std::printf("%s: %zu vertices, %d profiles; %zu materials alternating\n", transport.c_str(), e.vertexCount(),
                    e.profileCount(), edits.size());

        std::optional<TransportFile> plainFile;
        if (!plain.empty()) plainFile = loadTransportFile(plain);
        Figure project, weights, projected, edit, recombine, relightEditable, relightPlain;
        std::vector<glm::vec3> diffuse;
        VertexRadiance out;
        const ScatteringComponents ms{};
        for (int k = 0; k < repeat; ++k) {
            Stopwatch t;
            e.projectLight(light);
            project.add(t.milliseconds());
            const Material& m = edits[size_t(k) % edits.size()];
            t.restart();
            e.setMaterial(m, e.objectSizeMm());
            const double w = t.milliseconds();
            weights.add(w);
            t.restart();
            e.relightProjected(diffuse);
            const double r = t.milliseconds();
            projected.add(r);
            edit.add(w + r);
            t.restart();
            TransportComponent c = e.recombine();
            recombine.add(t.milliseconds());
            for (TransportComponent& x : object.transport.components)
                if (x.kind == ComponentKind::MultipleScattering) x = std::move(c);
            t.restart();
            relightVertices(object.transport, light, ms, out);
            relightEditable.add(t.milliseconds());
        }
        // Back to back, as a viewer relights one file: a file that fits the last-level
        // cache stays there between runs (both files' runs are alike in that).
        if (plainFile)
            for (int k = 0; k < repeat; ++k) {
                Stopwatch t;
                relightVertices(*plainFile, light, ms, out);
                relightPlain.add(t.milliseconds());
            }
        std::printf("edit (light still): weights      %s\n", weights.text().c_str());
        std::printf("                    relight      %s\n", projected.text().c_str());
        std::printf("                    total        %s\n", edit.text().c_str());
        std::printf("per light:          projectLight %s\n", project.text().c_str());
        std::printf("per material:       recombine    %s\n", recombine.text().c_str());
        std::printf("light change:       relight (recombined file) %s\n", relightEditable.text().c_str());
        if (!plain.empty()) {
            std::printf("                    relight (plain file)      %s\n", relightPlain.text().c_str());
            std::printf("                    ratio of medians          %.2f\n",
                        median(relightEditable.ms) / median(relightPlain.ms));
        }
        if (!json.empty()) {
            nlohmann::json j = {{"transport", transport},
                                {"transport_bytes", std::filesystem::file_size(transport)},
                                {"vertices", e.vertexCount()},
                                {"profiles", e.profileCount()},
                                {"repeat", repeat},
                                {"weights", weights.json()},
                                {"edit_relight", projected.json()},
                                {"edit", edit.json()},
                                {"project_light", project.json()},
                                {"recombine", recombine.json()},
                                {"light_change", relightEditable.json()}};
            if (plainFile) {
                j["plain"] = plain;
                j["plain_bytes"] = std::filesystem::file_size(plain);
                j["plain_light_change"] = relightPlain.json();
                j["light_change_ratio"] = median(relightEditable.ms) / median(relightPlain.ms);
            }
            writeAtomically(json, [&](const std::string& tmp) {
                std::ofstream f(tmp);
                f << j.dump(2) << "\n";
                if (!f) throw Error(json, "cannot write");
            });
        }
        return 0;
    });
}
