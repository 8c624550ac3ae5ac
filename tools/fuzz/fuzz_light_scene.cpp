// Fuzz target: the point-light scene file and light strings (relight/pointlight/point_lights.h
// parseLightScene, the JSON of --lights; parseLight, the TYPE:X,Y,Z:R,G,B of --light;
// relight/pointlight/point_animation.h parseLightPath, the X0,Y0,Z0:X1,Y1,Z1 of --light-path).
// The first input byte picks the parser, the rest is the text.
//
// Oracle: every accepted light has a finite position or unit direction and a finite,
// non-negative colour.

#include <cmath>
#include <cstdint>
#include <string>

#include "relight/pointlight/point_animation.h"
#include "relight/pointlight/point_lights.h"
#include "tools/fuzz/fuzz_support.h"

using namespace prt;

namespace {

void checkLight(const Light& l) {
    for (int k = 0; k < 3; ++k) {
        fuzz::require(std::isfinite(l.position[k]) && std::isfinite(l.direction[k]), "finite light geometry");
        fuzz::require(std::isfinite(l.rgb[k]) && l.rgb[k] >= 0.0, "finite non-negative colour");
    }
    if (l.type == LightType::Directional)
        fuzz::require(std::abs(glm::length(l.direction) - 1.0) < 1e-9, "unit direction");
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    if (size < 1) return 0;
    const std::string text(reinterpret_cast<const char*>(data + 1), size - 1);
    switch (data[0] % 3) {
        case 0:
            fuzz::expectErrors([&] {
                for (const Light& l : parseLightScene(text, "scene.json")) checkLight(l);
            });
            break;
        case 1:
            fuzz::expectErrors([&] { checkLight(parseLight(text)); });
            break;
        default:
            fuzz::expectErrors([&] {
                glm::dvec3 from, to;
                parseLightPath(text, from, to);
            });
    }
    return 0;
}
