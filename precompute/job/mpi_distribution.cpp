#include "precompute/job/mpi_distribution.h"

#include <algorithm>
#include <climits>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <functional>
#include <string>

#include "common/error.h"

#ifdef PRT_HAVE_MPI
#include <mpi.h>
#endif

namespace prt {

bool launchedByMpi() {
    for (const char* name : {"OMPI_COMM_WORLD_SIZE", "PMIX_RANK", "PMI_RANK"})
        if (std::getenv(name)) return true;
    return false;
}

#ifndef PRT_HAVE_MPI

bool mpiAvailable() { return false; }

MpiSession::MpiSession(int&, char**&) {
    const char* size = std::getenv("OMPI_COMM_WORLD_SIZE");
    if (size && std::atoi(size) > 1)
        throw Error("prt-precompute", "started by mpirun with " + std::string(size) +
                                          " ranks, but this build has no MPI (install libopenmpi-dev "
                                          "and rebuild; docs/cluster.md)");
}
MpiSession::~MpiSession() = default;

#else

bool mpiAvailable() { return true; }

namespace {

// Vertices go to the ranks in interleaved blocks (distribution.h): at least 16 per rank,
// of at most 1024 vertices (pass 2 walks a block's vertices in Morton order, so blocks
// keep their locality).
size_t vertexBlock(size_t vertices, int ranks) {
    return std::clamp<size_t>(vertices / (16 * size_t(ranks)), 1, 1024);
}

// Below 1 GiB per message, so every count fits MPI's int.
constexpr size_t kChunk = size_t(1) << 30;

class Buffer {
public:
    template <class T>
    void put(const T& v) {
        const size_t at = bytes.size();
        bytes.resize(at + sizeof(T));
        std::memcpy(bytes.data() + at, &v, sizeof(T));
    }
    template <class T>
    void putArray(const std::vector<T>& v) {
        put<uint64_t>(v.size());
        const size_t at = bytes.size();
        bytes.resize(at + v.size() * sizeof(T));
        if (!v.empty()) std::memcpy(bytes.data() + at, v.data(), v.size() * sizeof(T));
    }
    std::vector<char> bytes;
};

class Reader {
public:
    Reader(const char* data, size_t size) : p_(data), end_(data + size) {}
    template <class T>
    T get() {
        T v;
        need(sizeof(T));
        std::memcpy(&v, p_, sizeof(T));
        p_ += sizeof(T);
        return v;
    }
    template <class T>
    void getArray(std::vector<T>& v) {
        const uint64_t n = get<uint64_t>();
        need(n * sizeof(T));
        v.resize(n);
        if (n) std::memcpy(v.data(), p_, n * sizeof(T));
        p_ += n * sizeof(T);
    }
    bool done() const { return p_ == end_; }

private:
    void need(size_t n) const {
        if (size_t(end_ - p_) < n) throw Error("MPI", "a message ended early (ranks built from different sources?)");
    }
    const char* p_;
    const char* end_;
};

void send(const std::vector<char>& bytes, int to, int tag) {
    uint64_t size = bytes.size();
    MPI_Send(&size, 1, MPI_UINT64_T, to, tag, MPI_COMM_WORLD);
    for (size_t at = 0; at < bytes.size(); at += kChunk)
        MPI_Send(bytes.data() + at, int(std::min(kChunk, bytes.size() - at)), MPI_BYTE, to, tag, MPI_COMM_WORLD);
}

std::vector<char> receive(int from, int tag) {
    uint64_t size = 0;
    MPI_Recv(&size, 1, MPI_UINT64_T, from, tag, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
    std::vector<char> bytes(size);
    for (size_t at = 0; at < bytes.size(); at += kChunk)
        MPI_Recv(bytes.data() + at, int(std::min(kChunk, bytes.size() - at)), MPI_BYTE, from, tag, MPI_COMM_WORLD,
                 MPI_STATUS_IGNORE);
    return bytes;
}

// `bytes` of rank `root` on every rank.
void broadcast(std::vector<char>& bytes, int root) {
    uint64_t size = bytes.size();
    MPI_Bcast(&size, 1, MPI_UINT64_T, root, MPI_COMM_WORLD);
    bytes.resize(size);
    for (size_t at = 0; at < bytes.size(); at += kChunk)
        MPI_Bcast(bytes.data() + at, int(std::min(kChunk, bytes.size() - at)), MPI_BYTE, root, MPI_COMM_WORLD);
}

class MpiDistribution final : public Distribution {
public:
    MpiDistribution() {
        MPI_Comm_rank(MPI_COMM_WORLD, &rank_);
        MPI_Comm_size(MPI_COMM_WORLD, &ranks_);
    }
    int rank() const override { return rank_; }
    int ranks() const override { return ranks_; }
    std::string describe() const override {
        return "MPI rank " + std::to_string(rank_) + " of " + std::to_string(ranks_);
    }
    bool partial() const override { return ranks_ > 1; }
    IndexRange sampleShare(size_t samples) const override { return evenRange(samples, rank_, ranks_); }
    std::vector<IndexRange> vertexShares(size_t vertices) const override { return vertexShares_(vertices, rank_); }
    bool writes() const override { return rank_ == 0; }

    void stage(const std::function<void()>& work) override {
        std::string message;
        bool failed = false;
        ++stage_;
        try {
            injectFailure();
            work();
        } catch (const std::exception& e) {
            failed = true;
            message = e.what();
        } catch (...) {
            failed = true;
            message = "unknown exception";
        }
        int mine = failed ? rank_ : INT_MAX, first = INT_MAX;
        MPI_Allreduce(&mine, &first, 1, MPI_INT, MPI_MIN, MPI_COMM_WORLD);
        if (first == INT_MAX) return;
        std::vector<char> text(message.begin(), message.end());
        broadcast(text, first);
        throw Error("rank " + std::to_string(first) + " of " + std::to_string(ranks_),
                    std::string(text.begin(), text.end()));
    }

    std::vector<SparseVector> gatherSamples(std::vector<SparseVector> mine, size_t total) override {
        for (const SparseVector& v : mine)
            if (v.channels != 1) throw Error("MPI", "pass-1 vectors must have one channel");
        return gather(std::move(mine), total, 1, [&](int r) { return std::vector<IndexRange>{sampleShare_(total, r)}; },
                      "pass-1 vectors");
    }

    std::vector<IndexRange> sharedWorkShares(size_t count) const override { return sharedWorkShares_(count, rank_); }
    std::vector<SparseVector> gatherSharedWork(std::vector<SparseVector> mine, size_t count, size_t perIndex) override {
        return gather(std::move(mine), count, perIndex, [&](int r) { return sharedWorkShares_(count, r); },
                      "shared vectors");
    }

    SparseRgbVectors gatherVertices(SparseRgbVectors mine, size_t vertices) override {
        constexpr int kTag = 7;
        if (rank_ != 0) {
            Buffer out;
            out.putArray(mine.offsets);
            out.putArray(mine.indices);
            out.putArray(mine.values);
            out.putArray(mine.scales);
            out.putArray(mine.shScales);
            mine.clear();
            send(out.bytes, 0, kTag);
            return {};
        }
        std::vector<SparseRgbVectors> parts(static_cast<size_t>(ranks_));
        parts[0] = std::move(mine);
        for (int r = 1; r < ranks_; ++r) {
            const std::vector<char> bytes = receive(r, kTag);
            Reader in(bytes.data(), bytes.size());
            SparseRgbVectors& part = parts[size_t(r)];
            part.haarBits = parts[0].haarBits;  // every rank runs the same settings
            part.shFrom = parts[0].shFrom;
            in.getArray(part.offsets);
            in.getArray(part.indices);
            in.getArray(part.values);
            in.getArray(part.scales);
            in.getArray(part.shScales);
            if (part.vertexCount() != totalSize(vertexShares_(vertices, r)) || !in.done())
                throw Error("MPI", "rank " + std::to_string(r) + " sent the wrong number of vertices");
        }
        // Block b of the vertex order is rank b mod R's (b / R)-th block.
        SparseRgbVectors all;
        size_t coefficients = 0;
        for (const SparseRgbVectors& p : parts) coefficients += p.coefficientCount();
        all.reserve(vertices, coefficients);
        std::vector<size_t> next(size_t(ranks_), 0);  // next vertex of each rank's part
        const size_t block = vertexBlock(vertices, ranks_);
        for (size_t b = 0; b * block < vertices; ++b) {
            const size_t r = b % size_t(ranks_);
            const size_t n = std::min(block, vertices - b * block);
            appendVertices(all, sliceVertices(parts[r], next[r], next[r] + n));
            next[r] += n;
        }
        return all;
    }

    double sum(double value) override {
        double total = 0;
        MPI_Allreduce(&value, &total, 1, MPI_DOUBLE, MPI_SUM, MPI_COMM_WORLD);
        return total;
    }
    std::pair<double, double> minMax(double value) override {
        double lo = 0, hi = 0;
        MPI_Allreduce(&value, &lo, 1, MPI_DOUBLE, MPI_MIN, MPI_COMM_WORLD);
        MPI_Allreduce(&value, &hi, 1, MPI_DOUBLE, MPI_MAX, MPI_COMM_WORLD);
        return {lo, hi};
    }
    bool agree(bool value) override {
        int v = value ? 1 : 0;
        MPI_Bcast(&v, 1, MPI_INT, 0, MPI_COMM_WORLD);
        return v != 0;
    }

private:
    // Every rank's vectors of its shares of [0, count) (perIndex each, in its shares'
    // order), broadcast in turn and placed in index order, on every rank.
    std::vector<SparseVector> gather(std::vector<SparseVector> mine, size_t count, size_t perIndex,
                                     const std::function<std::vector<IndexRange>(int)>& sharesOf,
                                     const char* what) {
        Buffer out;
        for (const SparseVector& v : mine) {
            out.put<int32_t>(v.channels);
            out.putArray(v.index);
            out.putArray(v.value);
        }
        mine.clear();
        std::vector<SparseVector> all(count * perIndex);
        for (int r = 0; r < ranks_; ++r) {
            std::vector<char> bytes = r == rank_ ? std::move(out.bytes) : std::vector<char>();
            broadcast(bytes, r);
            Reader in(bytes.data(), bytes.size());
            for (const IndexRange& range : sharesOf(r))
                for (size_t i = range.begin * perIndex; i < range.end * perIndex; ++i) {
                    SparseVector& v = all[i];
                    v.channels = in.get<int32_t>();
                    in.getArray(v.index);
                    in.getArray(v.value);
                    if (v.channels < 1 || v.value.size() != v.index.size() * size_t(v.channels))
                        throw Error("MPI", "rank " + std::to_string(r) + " sent a malformed vector");
                }
            if (!in.done()) throw Error("MPI", "rank " + std::to_string(r) + " sent more " + what + " than its share");
        }
        return all;
    }

    // Fault injection for tests/cluster_test.sh: PRT_MPI_FAIL=R:S makes rank R fail in
    // its S-th stage (1-based), as a rank that runs out of memory or disk would.
    void injectFailure() const {
        const char* spec = std::getenv("PRT_MPI_FAIL");
        int r = -1, s = -1;
        if (spec && std::sscanf(spec, "%d:%d", &r, &s) == 2 && r == rank_ && s == stage_)
            throw Error("PRT_MPI_FAIL", "injected failure in stage " + std::to_string(s));
    }

    int stage_ = 0;
    IndexRange sampleShare_(size_t samples, int r) const { return evenRange(samples, r, ranks_); }
    // Shared work in interleaved blocks too (a site's cost follows the local thickness,
    // as a vertex's does), of at most 64 indices.
    std::vector<IndexRange> sharedWorkShares_(size_t count, int r) const {
        return interleavedBlocks(count, std::clamp<size_t>(count / (16 * size_t(ranks_)), 1, 64), r, ranks_);
    }
    std::vector<IndexRange> vertexShares_(size_t vertices, int r) const {
        return interleavedBlocks(vertices, vertexBlock(vertices, ranks_), r, ranks_);
    }

    int rank_ = 0, ranks_ = 1;
};

}  // namespace

MpiSession::MpiSession(int& argc, char**& argv) {
    if (!launchedByMpi()) return;
    int provided = 0;
    // Only the main thread calls MPI; TBB's workers never do.
    MPI_Init_thread(&argc, &argv, MPI_THREAD_FUNNELED, &provided);
    initialised_ = true;
    distribution_ = std::make_unique<MpiDistribution>();
}

MpiSession::~MpiSession() {
    distribution_.reset();
    if (initialised_) MPI_Finalize();
}

#endif

}  // namespace prt
