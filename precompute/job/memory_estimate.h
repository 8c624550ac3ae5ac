#pragma once
// The precomputation's memory, estimated before any pass runs, so that an absurd job
// (a million samples x 1024 coefficients, a 64^2 cubemap on a big mesh) is refused up
// front with its estimate instead of dying of std::bad_alloc or the out-of-memory
// killer an hour in (docs/reliability.md).
//
// The estimate adds the largest live data of the passes, from their data structures:
//   mesh + Embree scene        ~ 250 bytes per triangle (286 with single scattering)
//   samples (Poisson disk)     ~ 200 bytes per sample (candidates included)
//   pass 1 vectors             samples x (sample coefficients x 8 + 64) bytes
//   pass 2 kd-tree sums        samples / 4 nodes x (node coefficients x 8 + 64) bytes
//   pass 2 cell sub-points     estimateCellSubPoints(...) x 36 bytes (68 when graded,
//                              as editable jobs are; cell_quadrature.h; 0 when the
//                              area is not given)
//   per-vertex results         vertices x vertex coefficients x 8 bytes (the file's
//                              16-bit index and RGB values) per component: one for
//                              multiple scattering (J/3 when editable), one per
//                              single-scattering vector (K, or 1 when isotropic)
//   pass 2 vectors of a chunk  min(vertices, pass2ChunkVertices) x vertex coefficients x
//                              (4 + 4 x 3) bytes (4 + 4 J when editable)
//   blocks                     vertices / 16 x block coefficients x 50 bytes per
//                              component, when the file stores blocks
//   single-scattering sites    with --ss-site-spacing h: min(vertices, 2 area / (sqrt 3 h^2))
//                              sites x terms x site coefficients (at most 6 N^2) x 16 bytes, + 112
//                              bytes per vertex of blend
//   per-thread workspaces      threads x 6 N^2 x 64 bytes
// times kSafety = 1.5 (allocator slack, vector growth). A refusal only has to tell 40 GB
// from 24 GB (how close it lands to measured peaks: docs/reliability.md).

#include <cstddef>
#include <cstdint>
#include <string>

#include "common/util.h"  // availableMemoryBytes, formatBytes
#include "precompute/job/settings.h"

namespace prt {

struct MemoryEstimate {
    uint64_t bytes = 0;
    std::string largest;  // the largest term, e.g. "pass 1 vectors 31.2 GB"
};

// The samples count only with multiple scattering; totalAreaMm2 = 0 leaves out the cell
// sub-points and counts every vertex as a single-scattering site. An editable job
// (settings.h) integrates J radial profiles instead of three
// channels, with sub-points spaced for the narrowest dipole of its range, which needs
// the object's size (bounding-box diagonal, mm; 0: taken as the material's own widths).
MemoryEstimate estimatePrecomputeMemory(const PrecomputeSettings& s, size_t vertices, size_t triangles,
                                        size_t samples, int threads, double totalAreaMm2 = 0.0,
                                        double objectSizeMm = 0.0);

// Throws prt::Error("memory", "needs 41.2 GB (largest: ...), 23.8 GB available; use
// --max-memory GB to allow more, or fewer samples / coefficients") when the estimate
// exceeds maxMemoryGb (> 0) or, with maxMemoryGb = 0, the available memory (when known).
void checkMemory(const MemoryEstimate& estimate, double maxMemoryGb);

}  // namespace prt
