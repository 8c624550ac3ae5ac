// prt-reference: the brute-force reference renderer (docs/reference.md). Thin: parses
// the options declared by addReferenceOptions and runs runReferenceCommand
// (tools/reference/reference_command.h), writing its images as files.

#include <CLI/CLI.hpp>

#include "common/error.h"
#include "common/image.h"
#include "common/options.h"
#include "tools/reference/reference_command.h"

using namespace prt;

int main(int argc, char** argv) {
    return runMain("prt-reference", [&]() -> int {
        CLI::App app{
            "prt-reference: brute-force reference frames of a translucent object. Multiple scattering:\n"
            "per-sample irradiance from the full-resolution environment (Monte Carlo, Embree visibility),\n"
            "dipole summed over all samples per pixel, from the reference's own denser sample set\n"
            "(--same-samples: the precomputation's, which isolates the transport error). Single\n"
            "scattering (--components ss): Monte Carlo along the refracted view ray with the exact\n"
            "Henyey-Greenstein phase (Wang Eq. 4 + Eq. 5).\n"
            "Point and directional lights (--light, --lights) instead of an environment: the exact\n"
            "transmitted irradiance at the same independent samples, multiple scattering only.\n"
            "Same placement, camera and outputs as prt-relight render (environment, -t) or\n"
            "prt-pointlight (lights, -m and --size-mm); compare with prt-compare.\n"
            "Examples:\n"
            "  prt-reference bunny.off -t bunny.prt -e sunset.exr -o out/bunny_ref\n"
            "  prt-reference bunny.off -m Marble --size-mm 40 --light point:30,40,30:0.01 -o out/bunny_pl_ref\n"
            "Vector options take comma-separated values; write negative ones as --eye=-10,0,50."};
        ReferenceCommand o;
        addReferenceOptions(app, o);
        if (const auto exitCode = parseCommandLine(app, argc, argv, "prt-reference")) return *exitCode;
        noteGivenReferenceOptions(app, o);
        FileImageWriter files;
        return runReferenceCommand(o, files);
    });
}
