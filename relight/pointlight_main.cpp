// prt-pointlight: offline frames of a translucent object under point and directional
// lights (docs/point-lights.md). Thin: parses the options declared by
// addPointLightOptions and runs runPointLightCommand (relight/pointlight/pointlight_command.h),
// writing its images as files.

#include <CLI/CLI.hpp>

#include "common/error.h"
#include "common/image.h"
#include "common/options.h"
#include "relight/pointlight/pointlight_command.h"

using namespace prt;

int main(int argc, char** argv) {
    return runMain("prt-pointlight", [&]() -> int {
        CLI::App app{
            "prt-pointlight: a translucent object under point and directional lights, rendered by the\n"
            "translucent irradiance cache (Keng et al. 2006, the default), the Jensen-Buhler hierarchical\n"
            "dipole integration it accelerates, or texture-space importance sampling (Chang et al. 2008,\n"
            "--method tsis; docs/point-lights.md). Lights in mm in the\n"
            "scaled mesh's frame; point intensity in W/sr, directional irradiance in W/m^2; output radiance\n"
            "in W/(m^2 sr). Example:\n"
            "  prt-pointlight bunny.off --size-mm 60 -m Marble --light point:40,80,60:3 -o out/bunny_pl\n"
            "  prt-pointlight bunny.off -m Skin1 --light point:-20,30,-40:1 --method tsis --compare-jb -o out/tsis\n"
            "Animations (frames <prefix>_0000.exr/.png ...): --turntable N, or --light-path P0:P1 --frames N, or\n"
            "--material-path A:B and/or --size-path S0:S1 with --frames N (Chang et al. Fig. 11; lights and\n"
            "irradiance stay attached to the object)\n"
            "(what each reuses between frames, and why that is valid: docs/point-lights.md, \"Animation\").\n"
            "Vector options take comma-separated values; write negative ones as --eye=-10,0,50."};
        PointLightCommand o;
        addPointLightOptions(app, o);
        if (const auto exitCode = parseCommandLine(app, argc, argv, "prt-pointlight")) return *exitCode;
        FileImageWriter files;
        return runPointLightCommand(o, files);
    });
}
