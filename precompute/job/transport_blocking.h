#pragma once
// The blocked layout of a whole transport file (prt-precompute's default: blocks of 16
// nearby vertices sharing M jointly chosen terms, 8-bit values; common/blocked_vectors.h),
// made from its per-vertex components. One home for the single process's writer
// (pipeline_stages.h, writeTransport) and prt-merge (shard_merge.h), which must give
// the same bytes.
//
// Blocks: spatialBlockOrder of the mesh's positions in mm, as the precompute scaled them
// (loadMesh, then scaleToPhysical with the file's mm per unit). Every component keeps
// its own index lists (jointTruncate), except an editable file's radial profiles, which
// keep nested lists per block (jointTruncateNested: a union of `keep` indices, which
// their recombination relights, and of it each profile component the indices whose own
// score reaches the block's threshold). Indices from 6 N^2 on (the SH part) are kept
// first with scales of their own.

#include <glm/vec3.hpp>

#include <cstddef>
#include <vector>

namespace prt {

struct TransportFile;

// The parameter that records a blocked file's mean retained energy (kept / total per
// vertex, over its components), written just before input_digest.
inline constexpr const char* kBlockRetainedEnergyParameter = "block_retained_energy";

// Replaces every per-vertex component of `file` by its blocks of `keep` terms
// (the per-vertex arrays are freed) and returns the mean over components of
// retainedEnergyFraction (the profile components counted as one). Preconditions: keep >= 1; positions.size() is the file's
// vertex count; every component is per vertex (prt::Error otherwise). Deterministic.
double blockTransportComponents(TransportFile& file, size_t keep, const std::vector<glm::vec3>& positions);

}  // namespace prt
