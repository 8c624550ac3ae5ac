// prt-compare: error of a rendered image against a reference over the object's
// pixels (relative RMSE, PSNR, max errors, mean ratio) and a heat map of the
// per-pixel relative error (docs/reference.md). Exit code 0 when the overall
// relative RMSE is within --max-rel-rmse (or no threshold is given), 2 when above,
// 1 on errors.

#include <CLI/CLI.hpp>

#include <cmath>
#include <cstdio>
#include <optional>

#include "common/image_compare.h"
#include "common/error.h"
#include "common/image.h"
#include "common/options.h"

using namespace prt;

int main(int argc, char** argv) {
    return runMain("prt-compare", [&]() -> int {
        CLI::App app{"prt-compare: compare a rendered image with a reference over the object pixels\n"
                     "(reference alpha > 0.5; all pixels when neither image has alpha)."};
        std::string testPath, referencePath, heatmapPath;
        std::optional<double> maxRelRmse, heatScale;
        CompareOptions options;
        app.add_option("test", testPath, "Image to judge (EXR, linear RGB[A])")->required();
        app.add_option("reference", referencePath, "Reference image (EXR, linear RGB[A])")->required();
        app.add_option("--heatmap", heatmapPath, "Write a PNG heat map of the per-pixel relative error");
        app.add_option("--heatmap-scale", heatScale,
                       "Relative error shown as the top of the colour ramp (default: 99th percentile, rounded up)");
        app.add_option("--max-rel-rmse", maxRelRmse,
                       "Exit with code 2 when the overall relative RMSE is above this");
        app.add_option("--rel-floor", options.relativeFloor,
                       "Max relative error divides by max(|reference|, this x peak)")
            ->capture_default_str();
        if (const auto exitCode = parseCommandLine(app, argc, argv, "prt-compare")) return *exitCode;
        if (maxRelRmse && !(*maxRelRmse >= 0.0)) throw Error("--max-rel-rmse", "must be >= 0");

        const Image test = readImage(testPath);
        const Image reference = readImage(referencePath);
        const CompareResult result = compareImages(test, reference, options);
        std::printf("test:      %s\nreference: %s\n%s", testPath.c_str(), referencePath.c_str(),
                    formatCompareResult(result).c_str());

        if (!heatmapPath.empty()) {
            const Image relative = relativeErrorImage(test, reference, result, options);
            const double scale = heatScale ? *heatScale : heatmapScale(relative);
            writePng(heatmapPath, heatmapImage(relative, scale));
            std::printf("heat map:  %s (viridis: dark blue = 0, yellow = relative error %.3g or more; "
                        "black = not compared)\n",
                        heatmapPath.c_str(), scale);
        }

        if (maxRelRmse) {
            const int code = thresholdExitCode(result, *maxRelRmse);
            std::printf("%s: overall relative RMSE %.6g %s %.6g\n", code == 0 ? "PASS" : "FAIL",
                        result.overall.relativeRmse, code == 0 ? "<=" : ">", *maxRelRmse);
            return code;
        }
        return 0;
    });
}
