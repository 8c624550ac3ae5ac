#pragma once
// How one precompute job's work is divided between processes (docs/cluster.md).
//
// Every pass-1 result depends only on its own sample, and every pass-2 and
// single-scattering result only on its own vertex (plus the whole sample set), never
// on which process computed it or in which order. So any split, reassembled in index
// order, gives the same transport file, byte for byte, as one process:
//
//   Distribution          everything in this process (the default)
//   ShardDistribution     --shard i/n: every sample (each shard recomputes pass 1), the
//                         vertices of range i of n; the output is a shard file (vectors
//                         of the other vertices empty) that prt-merge joins
//   MpiDistribution       (precompute/job/mpi_distribution.h) samples and vertices split over
//                         the ranks of MPI_COMM_WORLD, sample vectors all-gathered, vertex
//                         vectors gathered at rank 0, which writes the file; the
//                         single-scattering sites split too and all-gathered
//                         (sharedWorkShares, gatherSharedWork)
//
// Samples split into even contiguous ranges (evenRange). Vertices: a shard takes one
// contiguous range (a shard file holds one vertex range); MPI ranks take interleaved
// blocks (interleavedBlocks), because a vertex's cost follows the local thickness and
// sample density, so contiguous ranges of a mesh's vertex order leave one rank with
// the expensive part (measured in docs/cluster.md).

#include <cstddef>
#include <cstdint>
#include <functional>
#include <string>
#include <utility>
#include <vector>

#include "common/haar.h"
#include "common/transport_file.h"

namespace prt {

// [begin, end) of an index space.
struct IndexRange {
    size_t begin = 0, end = 0;
    size_t size() const { return end - begin; }
    bool operator==(const IndexRange&) const = default;
};

// Part `part` of `parts` of [0, count): contiguous, sizes differing by at most one,
// the first count % parts parts one longer. Requires 0 <= part < parts.
IndexRange evenRange(size_t count, int part, int parts);

// Blocks of `block` indices of [0, count), block b going to part b mod parts: part
// `part`'s blocks, in order. Over all parts they partition [0, count).
std::vector<IndexRange> interleavedBlocks(size_t count, size_t block, int part, int parts);

// Sum of the ranges' sizes.
size_t totalSize(const std::vector<IndexRange>& ranges);

// --shard i/n: shard i (0-based, as Slurm's array task ids 0..n-1) of n.
struct ShardSpec {
    int index = 0, count = 1;
    bool operator==(const ShardSpec&) const = default;
};
// "i/n" with 0 <= i < n <= 65536; throws prt::Error("--shard", reason) otherwise.
ShardSpec parseShard(const std::string& text);
std::string toString(const ShardSpec& shard);  // "i/n"

// A shard file carries kShardParameter and kShardVerticesParameter (transport_file.h)
// beside the job's own parameters, whose input_digest is the whole job's, the same in
// every shard.

class Distribution {
public:
    virtual ~Distribution() = default;

    virtual int rank() const { return 0; }
    virtual int ranks() const { return 1; }
    // "1 process", "shard 2/4", "MPI rank 0 of 4": for the summary.
    virtual std::string describe() const { return "1 process"; }
    // Whether this process computes only a part of the vertices (a shard or a rank).
    virtual bool partial() const { return false; }
    // Whether the output is a shard file (outputParameters() not empty).
    virtual bool shard() const { return false; }

    // The samples (pass 1) and vertices (pass 2, single scattering) this process computes.
    virtual IndexRange sampleShare(size_t samples) const { return {0, samples}; }
    // Vertices: ascending, disjoint ranges.
    virtual std::vector<IndexRange> vertexShares(size_t vertices) const { return {{0, vertices}}; }

    // Runs one stage of the job on every process. When it throws on any process, every
    // process throws prt::Error with the lowest failing process's message (naming its
    // rank), so no process waits forever for a failed one.
    virtual void stage(const std::function<void()>& work) { work(); }

    // Pass 1's exchange: `mine` holds the vectors of sampleShare(total); returns all
    // `total` vectors in sample order, on every process.
    virtual std::vector<SparseVector> gatherSamples(std::vector<SparseVector> mine, size_t total) {
        (void)total;
        return mine;
    }
    // Work every process needs the whole of (the single-scattering sites): the indices
    // of [0, count) this process computes, ascending disjoint ranges; over all processes
    // they partition [0, count).
    virtual std::vector<IndexRange> sharedWorkShares(size_t count) const { return {{0, count}}; }
    // Their exchange: `mine` holds `perIndex` vectors for each index of
    // sharedWorkShares(count), in index order; returns all count x perIndex vectors in
    // index order (index i's at [i * perIndex, (i + 1) * perIndex)), on every process.
    virtual std::vector<SparseVector> gatherSharedWork(std::vector<SparseVector> mine, size_t count,
                                                       size_t perIndex) {
        (void)count, (void)perIndex;
        return mine;
    }
    // One component's vectors of vertexShares(vertices) (concatenated in that order) ->
    // all `vertices` of them, on
    // the process that writes (writes()); other processes get an empty result.
    virtual SparseRgbVectors gatherVertices(SparseRgbVectors mine, size_t vertices) {
        (void)vertices;
        return mine;
    }
    // Whether this process writes the output file.
    virtual bool writes() const { return true; }
    // Parameters added to the output (the shard's identity); empty for a whole file.
    virtual std::vector<std::pair<std::string, std::string>> outputParameters(size_t vertices) const {
        (void)vertices;
        return {};
    }
    // Sums of per-process statistics (rays traced, ...), on every process.
    virtual double sum(double value) { return value; }
    // The smallest and largest of a per-process value (each rank's busy time), on every process.
    virtual std::pair<double, double> minMax(double value) { return {value, value}; }
    // Process 0's value, on every process (decisions all processes must share).
    virtual bool agree(bool value) { return value; }
};

class ShardDistribution final : public Distribution {
public:
    explicit ShardDistribution(ShardSpec shard) : shard_(shard) {}
    std::string describe() const override;
    bool partial() const override { return true; }
    bool shard() const override { return true; }
    IndexRange vertexShare(size_t vertices) const;  // the shard's one range
    std::vector<IndexRange> vertexShares(size_t vertices) const override { return {vertexShare(vertices)}; }
    // The shard's vectors placed in a whole-mesh array, the other vertices empty.
    SparseRgbVectors gatherVertices(SparseRgbVectors mine, size_t vertices) override;
    std::vector<std::pair<std::string, std::string>> outputParameters(size_t vertices) const override;

private:
    ShardSpec shard_;
};

// Concatenates per-range vectors (in range order) into one array: the offsets are
// rebased, everything else appended. The result equals computing all ranges at once.
// An empty `all` takes part's encoding (SparseRgbVectors::haarBits, shFrom); a part of
// another encoding is a prt::Error.
void appendVertices(SparseRgbVectors& all, const SparseRgbVectors& part);

// The vertices [begin, end) of `all` as their own array (offsets rebased); the
// inverse of appendVertices.
SparseRgbVectors sliceVertices(const SparseRgbVectors& all, size_t begin, size_t end);

// `count` vertices without coefficients (scales 0, SH scales too with 8-bit Haar values).
void appendEmptyVertices(SparseRgbVectors& all, size_t count);

}  // namespace prt
