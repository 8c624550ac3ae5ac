// prt-envcheck: environment -> 6xNxN cubemap -> Haar -> largest K terms -> back,
// written as cross-layout EXR + PNG, with the relative L2 error of the truncation
// (the non-linear wavelet light approximation of Ng et al. 2003).

#include <CLI/CLI.hpp>

#include <cmath>
#include <cstdio>

#include "common/cubemap.h"
#include "common/envmap.h"
#include "common/error.h"
#include "common/haar.h"
#include "common/image.h"
#include "common/options.h"

using namespace prt;

int main(int argc, char** argv) {
    return runMain("prt-envcheck", [&]() -> int {
        CLI::App app{"prt-envcheck: turn a lat-long environment into a Haar-truncated cubemap\n"
                     "and report the relative L2 error of keeping only the largest K terms."};
        std::string input, out = "envcheck";
        int size = 32;
        size_t terms = 128;
        double rotateY = 0, exposure = 0;
        bool clamp = false;
        app.add_option("environment", input, "Lat-long environment (EXR/HDR, width = 2 x height)")->required();
        app.add_option("-n,--size", size, "Cubemap face size N (power of two)")->capture_default_str();
        app.add_option("-k,--terms", terms, "Haar terms kept (largest by RGB magnitude)")->capture_default_str();
        app.add_option("--rotate-y", rotateY, "Rotate the environment about +Y, degrees")->capture_default_str();
        app.add_option("--exposure", exposure, "PNG exposure in stops")->capture_default_str();
        app.add_flag("--clamp", clamp,
                     "Replace NaN/Inf pixels too (negative pixels, which lossy EXR compression leaves\n"
                     "in real maps, are always set to 0 with a warning)");
        app.add_option("-o,--out", out, "Output prefix: <out>.exr, <out>.png, <out>_full.exr, <out>_full.png")
            ->capture_default_str();
        if (const auto exitCode = parseCommandLine(app, argc, argv, "prt-envcheck")) return *exitCode;
        if (!isPowerOfTwo(size)) throw Error("--size", "must be a power of two");
        const size_t coefficients = size_t(6) * size * size;
        if (terms < 1 || terms > coefficients)
            throw Error("--terms", "must be between 1 and 6 N^2 = " + std::to_string(coefficients));

        Image env = loadEnvironment(input, clamp ? NonFinitePolicy::Clamp : NonFinitePolicy::ClampNegative);
        Cubemap cube = latLongToCubemap(env, size, rotationY(rotateY));
        const std::vector<double> cubeIntegral = cube.integrate();

        Cubemap coeffs = cube;
        haarForward(coeffs);
        SparseVector kept = truncateLargest(coeffs.data().data(), coefficients, 3, terms);
        const double total = energy(coeffs.data().data(), coeffs.data().size());
        const double relL2 = total > 0 ? std::sqrt(std::max(0.0, 1.0 - energy(kept) / total)) : 0.0;

        Cubemap approx(size, 3);
        addTo(kept, 1.0f, approx.data().data());
        haarInverse(approx);
        // The same error measured in texel space (Parseval says they agree).
        double diff = 0, ref = 0;
        for (size_t k = 0; k < cube.data().size(); ++k) {
            diff += double(cube.data()[k] - approx.data()[k]) * (cube.data()[k] - approx.data()[k]);
            ref += double(cube.data()[k]) * cube.data()[k];
        }

        writeExr(out + ".exr", cubemapToCross(approx));
        writePng(out + ".png", cubemapToCross(approx), exposure);
        writeExr(out + "_full.exr", cubemapToCross(cube));
        writePng(out + "_full.png", cubemapToCross(cube), exposure);

        std::printf("environment        %s (%d x %d)\n", input.c_str(), env.width, env.height);
        for (int c = 0; c < 3; ++c) {
            const double ll = latLongIntegral(env, c);
            std::printf("integral %c         lat-long %.6g, cubemap %.6g (%+.4f%%)\n", "RGB"[c], ll,
                        cubeIntegral[c], ll != 0 ? 100.0 * (cubeIntegral[c] / ll - 1.0) : 0.0);
        }
        std::printf("cubemap            6 x %d x %d, %zu coefficients\n", size, size, coefficients);
        std::printf("kept               %zu largest terms (%.2f%%)\n", kept.size(),
                    100.0 * kept.size() / coefficients);
        std::printf("relative L2 error  %.6f (coefficients), %.6f (texels)\n", relL2,
                    ref > 0 ? std::sqrt(diff / ref) : 0.0);
        std::printf("wrote              %s.exr %s.png %s_full.exr %s_full.png\n", out.c_str(),
                    out.c_str(), out.c_str(), out.c_str());
        return 0;
    });
}
