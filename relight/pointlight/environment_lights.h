#pragma once
// The sun split: an environment's brightest texels (suns, lamps, windows) taken out as
// directional lights, leaving a residual environment no brighter than a threshold
// (docs/relight.md, "The sun split"; the error it removes: docs/fidelity.md).
//
// WHY. A small, very bright source puts its light in the finest Haar levels of the
// light vector, and the per-sample and per-vertex truncations of the transport drop
// those levels first: the sun's light is then misplaced. A directional light is
// relit without truncation by the point-light renderers (pass 1's shadow rays at the
// irradiance samples, then the dipole sum), so what the transport vectors must carry
// is only the residual, which is bounded.
//
// THE SPLIT (exact, per texel). Y(t) = the Rec. 709 luminance of texel t, Ybar the
// environment's mean luminance over the sphere (sum Y(t) Omega(t) / 4 pi, with the
// exact lat-long solid angles of envmap.h). With the threshold tau = k Ybar:
//   residual(t) = L(t) min(1, tau / Y(t))          (the texel's colour kept, Y <= tau)
//   excess(t)   = L(t) - residual(t)               (>= 0, zero where Y <= tau)
// so residual + excess = L texel by texel, in every channel. The excess of the texels
// of one cell (cellTexels x cellTexels lat-long texels, about cellDegrees wide) becomes
// one directional light:
//   direction        w = normalize(sum Y_excess(t) Omega(t) d(t)),  d(t) = the texel's centre
//   irradiance E_perp = sum excess(t) Omega(t) (d(t) . w)   (RGB, W/m^2 when L is W/(m^2 sr))
// i.e. what a surface facing w receives from the cell's texels, so a surface that sees
// the whole cell receives from the light what it receives from the texels, to first
// order in the cell's angular size (exactly, for cells of one texel seen along w). The
// only approximation of the split is each cell's light arriving from one direction
// instead of from its texels' (docs/relight.md measures it); the lights' sum is the
// excess's integral over the sphere times the mean cosine within each cell.
//
// FRAMES. Directions are the environment's own (envmap.h's lat-long convention, the
// unrotated map). An environment rotated by R (L'(d) = L(R^T d)) has the lights
// turned by R: rotatedLights.

#include <glm/glm.hpp>

#include <cstddef>
#include <vector>

#include "common/image.h"
#include "relight/pointlight/point_lights.h"

namespace prt {

struct SunSplitOptions {
    // k: the residual's luminance bound in units of the environment's mean luminance.
    // > 0; below 1 even texels dimmer than the mean give part of their light to the
    // lights (docs/relight.md, "The sun split", for the choice of the default).
    double threshold = 2.0;
    // The lights' cells: about this many degrees of latitude and longitude, rounded to
    // whole texels (at least one). In (0, 90].
    double cellDegrees = 8.0;
};

struct SunSplit {
    Image residual;             // the environment's size and channels (RGB), Y <= tau everywhere
    std::vector<Light> lights;  // directional, in the environment's frame; cells without excess have none
    double meanLuminance = 0;   // Ybar
    double thresholdLuminance = 0;  // tau = k Ybar
    size_t texelsAbove = 0;     // texels with Y > tau
    int cellTexels = 1;         // the cells' side in texels
    // The excess's share of the environment's luminance integral (what the residual no
    // longer holds), in [0, 1].
    double lightFraction = 0;
};

// Throws prt::Error("--sun-threshold" / "--sun-cell", ...) for options out of range and
// prt::Error("environment", ...) for an empty or non-RGB image, a width != 2 height,
// or a negative or non-finite value (loadEnvironment's maps have none). An all-black
// environment has no lights and itself as the residual.
SunSplit splitSun(const Image& latLong, const SunSplitOptions& options = {});

// The lights of an environment turned by `rotation` (direction d -> R d).
std::vector<Light> rotatedLights(const std::vector<Light>& lights, const glm::dmat3& rotation);

// Checks the options alone (the messages of splitSun).
void validateSunSplitOptions(const SunSplitOptions& options);

}  // namespace prt
