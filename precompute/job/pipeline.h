#pragma once
// The precomputation of prt-precompute as one function from settings to a transport
// file (Wang et al. 2005, section 3; docs/precompute.md, "Pipeline"):
//
//   mesh --scale--> samples (Poisson disk) --pass 1--> sparse Haar irradiance transport
//   per sample --pass 2 (kd-tree, Jensen-Buhler)--> sparse RGB multiple-scattering
//   vector per vertex (component "ms");
//   mesh --single scattering along -n_o (Eqs. 10-11)--> one isotropic sparse RGB vector
//   per vertex (g = 0) or K term vectors + the h_k view maps (g != 0) (component "ss");
//   --> optional blocks --> transport file (atomic write).
//
// The passes are library functions of their own (irradiance_transport.h,
// multiple_scattering.h, phase_factoring.h, single_scattering.h); this module runs them
// as stages (pipeline_stages.h), splits the work over processes and collects the
// summary.

#include <glm/glm.hpp>

#include <cstddef>

#include "precompute/job/distribution.h"
#include "precompute/job/settings.h"
#include "precompute/job/summary.h"

namespace prt {

// Runs the job. When the output exists, is valid and was made from the same settings
// and mesh, returns a summary with skipped = true unless force is set. `distribution`
// divides the work between processes (distribution.h: MPI ranks); null = all of it in
// this process, or the shard of settings.shard. The file written is the same, byte for
// byte, however the work was divided (a shard writes its part, which prt-merge joins
// into that file). Throws prt::Error (bad settings, unreadable mesh, unwritable output,
// too little memory, ...) before any pass where it can.
PrecomputeSummary precomputeTransport(const PrecomputeSettings& settings, bool force = false,
                                      Distribution* distribution = nullptr);

// The diffuse baseline (prt-precompute --baseline diffuse-brdf; precompute/passes/diffuse_baseline.h)
// for the mesh, scale, cubemap, SH terms, coefficients, supersampling and visibility
// sampling of `settings` (the material, samples and passes do not apply), written
// atomically to settings.outputPath. Prints one summary line; returns the file's
// vertex count. Throws prt::Error for bad settings, an unreadable mesh, an unwritable
// output, and for settings it cannot honour (single scattering, --editable, shards, a
// pass-1 file).
size_t precomputeDiffuseBaseline(const PrecomputeSettings& settings, const glm::dvec3& albedo);

// Peak resident set size of this process in bytes (getrusage).
size_t peakMemoryBytes();

}  // namespace prt
