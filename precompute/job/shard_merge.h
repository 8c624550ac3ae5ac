#pragma once
// Joining the shard files of one job (`prt-precompute --shard i/n`, docs/cluster.md)
// into the whole transport file: the file one process would have written, byte for
// byte (tests/test_distribution.cpp).
//
// The shards must belong together: the same mesh fingerprint, cubemap size, scale,
// components, view maps, radial basis (editable files: the profiles' components are
// joined like any other, their shared index lists stay shared) and parameters
// (input_digest included) apart from the shard's
// own two; one shard count n; every index 0..n-1 exactly once; each shard's vertex
// range the one evenRange gives for its index, with no coefficients outside it. A
// missing, duplicated or foreign shard is a prt::Error naming the file (or the
// missing index) and the problem.

#include <string>
#include <vector>

#include "common/transport_file.h"

namespace prt {

// Reads the shards (any order) and returns the whole file. Shards are per vertex; when
// their job asked for blocks (a block_coefficients parameter above 0, prt-precompute's
// default) the whole file is blocked here as one process blocks it
// (transport_blocking.h), from the mesh at meshPath (loaded and scaled as the
// precompute did); without meshPath that is a prt::Error. A given meshPath must be the
// shards' mesh (its fingerprint). Peak memory: the result plus one shard.
TransportFile mergeShards(const std::vector<std::string>& paths, const std::string& meshPath = "");

}  // namespace prt
