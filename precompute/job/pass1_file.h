#pragma once
// The pass-1 file: the truncated irradiance-transport vectors of every sample, saved
// once so that the shards of a job (precompute/job/distribution.h) load them instead of
// each recomputing pass 1 (docs/cluster.md). Little-endian, one CRC over everything:
//
//   8 bytes  magic "PRTPASS1"
//   u32      version (1)
//   u32      endianness marker 0x01020304
//   u64      key length K, then K bytes of key: the pass-1 inputs as "name=value\n" lines
//   u64      sample count S
//   S times: u32 coefficient count C, C x u32 Haar indices, C x f32 values
//   u32      zlib crc32 of every byte before it
//
// The key (pass1Key) names everything that determines the vectors: the mesh fingerprint
// and scale, the sample count and seed, the cubemap size, supersampling, pass-1
// visibility, coefficients kept, SH terms (when not 0) and eta. A file with another key
// belongs to another job and is refused.

#include <string>
#include <utility>
#include <vector>

#include "common/haar.h"

namespace prt {

// The pass-1 inputs among a job's parameters (settings.h settingsParameters), with the
// scale applied and the number of samples placed.
std::string pass1Key(const std::vector<std::pair<std::string, std::string>>& parameters, double mmPerUnit,
                     size_t samples);

// Written atomically (common/atomic_file.h). Vectors must have one channel.
void savePass1File(const std::string& path, const std::string& key, const std::vector<SparseVector>& vectors);

// Reads and checks the whole file: prt::Error(path, reason) when it is missing, not a
// pass-1 file, truncated, corrupt (CRC), or made for another key ("made for other pass-1
// inputs: <first differing line>").
std::vector<SparseVector> loadPass1File(const std::string& path, const std::string& key);

}  // namespace prt
