// prt-make-shape: writes one of the generated test meshes (common/shapes.h) to a
// file, for script tests that need a mesh without downloaded data.
//
//   prt-make-shape icosphere OUT.obj [--subdivisions N] [--radius R]
//   prt-make-shape torus OUT.obj [--radius R] [--tube r] [--segments N]

#include <CLI/CLI.hpp>

#include "common/error.h"
#include "common/mesh_io.h"
#include "common/options.h"
#include "common/shapes.h"

using namespace prt;

int main(int argc, char** argv) {
    return runMain("prt-make-shape", [&]() -> int {
        CLI::App app{"prt-make-shape: write a generated test mesh (common/shapes.h)"};
        std::string shape, output;
        int subdivisions = 3, segments = 32;
        float radius = 10.0f, tube = 3.0f;
        app.add_option("shape", shape, "icosphere or torus")->required();
        app.add_option("output", output, "Mesh file to write (.obj .ply .off .stl)")->required();
        app.add_option("--subdivisions", subdivisions, "Icosphere subdivisions")->capture_default_str();
        app.add_option("--radius", radius, "Sphere radius or torus ring radius")->capture_default_str();
        app.add_option("--tube", tube, "Torus tube radius")->capture_default_str();
        app.add_option("--segments", segments, "Torus segments around the ring and the tube")->capture_default_str();
        if (const auto exitCode = parseCommandLine(app, argc, argv, "prt-make-shape")) return *exitCode;
        TriangleMesh mesh;
        if (shape == "icosphere") mesh = makeIcosphere(subdivisions, radius);
        else if (shape == "torus") mesh = makeTorus(radius, tube, segments, segments);
        else throw Error(shape, "unknown shape; use icosphere or torus");
        saveMesh(mesh, output);
        std::printf("%s: %zu vertices, %zu triangles\n", output.c_str(), mesh.vertexCount(), mesh.triangleCount());
        return 0;
    });
}
