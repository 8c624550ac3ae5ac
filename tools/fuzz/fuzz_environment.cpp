// Fuzz target: environment loading (common/envmap.h loadEnvironment through
// common/image.h readImage and OpenImageIO: format by extension, lat-long shape check,
// channel handling, NaN/Inf/negative policies) and the lat-long -> cubemap filter of
// what was accepted. The first input byte picks the extension (.exr .hdr .pfm .png
// .tif) and the non-finite policy, the rest is the file.
//
// Oracle: an accepted environment is RGB, width = 2 x height, every value finite and
// non-negative, and its cubemap (for one input in 16) is finite and non-negative too.

#include <cmath>
#include <cstdint>

#include "common/envmap.h"
#include "common/image.h"
#include "tools/fuzz/fuzz_support.h"

using namespace prt;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    if (size < 1) return 0;
    static const char* const kExtensions[] = {".exr", ".hdr", ".pfm", ".png", ".tif"};
    static const NonFinitePolicy kPolicies[] = {NonFinitePolicy::Reject, NonFinitePolicy::ClampNegative,
                                                NonFinitePolicy::Clamp};
    const std::string path = fuzz::writeInput(data + 1, size - 1, kExtensions[data[0] % 5]);
    const NonFinitePolicy policy = kPolicies[(data[0] / 5) % 3];
    fuzz::expectErrors([&] {
        const Image env = loadEnvironment(path, policy);
        fuzz::require(env.channels == 3 && env.width == 2 * env.height && env.consistent(),
                      "an accepted environment is an RGB lat-long image");
        for (float v : env.pixels) fuzz::require(std::isfinite(v) && v >= 0.0f, "finite non-negative values");
        // The exact box filter costs ~0.4 s under the sanitizers whatever the image
        // size; one input in 16 (by length) keeps the fuzzer near 100 runs/s.
        if (size % 16 == 0) {
            const Cubemap cube = latLongToCubemap(env, 2);
            for (float v : cube.data()) fuzz::require(std::isfinite(v) && v >= 0.0f, "finite non-negative cubemap");
        }
    });
    return 0;
}
