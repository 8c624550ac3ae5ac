// Work split over processes (precompute/job/distribution.h) and the shard merge
// (precompute/job/shard_merge.h): ranges partition their index space, slices and
// concatenation are inverse, and a job computed as shards and merged is the same file,
// byte for byte, as the job computed in one process. The MPI route runs through the
// real executables in tests/cluster_test.sh.

#include "precompute/job/distribution.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <random>

#include "common/materials.h"
#include "common/mesh_io.h"
#include "common/progress.h"
#include "common/shapes.h"
#include "precompute/job/pass1_file.h"
#include "precompute/job/pipeline.h"
#include "precompute/job/shard_merge.h"
#include "tests/test_support.h"

using namespace prt;
using prt::test::errorOf;
namespace fs = std::filesystem;

namespace {

fs::path tempDir() {
    fs::path d = fs::temp_directory_path() / ("prt_test_distribution_" + std::to_string(getpid()));
    fs::create_directories(d);
    return d;
}

// Random sparse vectors, some vertices empty.
SparseRgbVectors randomVectors(size_t vertices, uint32_t seed) {
    std::mt19937 rng(seed);
    SparseRgbVectors v;
    for (size_t i = 0; i < vertices; ++i) {
        const size_t n = rng() % 5;
        std::vector<uint32_t> idx;
        std::vector<float> rgb;
        for (size_t k = 0; k < n; ++k) {
            idx.push_back(uint32_t(k * 7 + rng() % 7));
            for (int c = 0; c < 3; ++c) rgb.push_back(float(int(rng() % 2001) - 1000) / 100.0f);
        }
        v.appendVertex(idx, rgb);
    }
    return v;
}

// A small job with both components and a K = 2 phase, so every component kind and
// the view maps go through the split.
PrecomputeSettings smallJob(const fs::path& dir) {
    const fs::path mesh = dir / "sphere.obj";
    if (!fs::exists(mesh)) saveMesh(makeIcosphere(2, 1.0f), mesh.string());
    PrecomputeSettings s;
    s.meshPath = mesh.string();
    s.scale.sizeMm = 20.0;
    s.material = materialByName("Skin1");
    s.material.g = 0.3;
    s.components = parseScatteringComponents("ms,ss");
    s.phase.terms = 2;
    s.phase.mapSize = 4;
    s.cubemapSize = 8;
    s.samples.count = 600;
    s.singleScattering.pathSamples = 4;
    s.vertexCoefficients = 48;
    s.pass1.sampleCoefficients = 48;
    return s;
}

}  // namespace

TEST(EvenRange, PartitionsTheIndexSpace) {
    for (size_t count : {size_t(0), size_t(1), size_t(7), size_t(100), size_t(1001)})
        for (int parts : {1, 2, 3, 4, 7, 64}) {
            size_t next = 0, smallest = SIZE_MAX, largest = 0;
            for (int p = 0; p < parts; ++p) {
                const IndexRange r = evenRange(count, p, parts);
                EXPECT_EQ(r.begin, next) << count << " " << parts << " " << p;
                next = r.end;
                smallest = std::min(smallest, r.size());
                largest = std::max(largest, r.size());
            }
            EXPECT_EQ(next, count);
            EXPECT_LE(largest - smallest, 1u);
        }
    EXPECT_NE(errorOf([] { evenRange(10, 3, 3); }), prt::test::kNoError);
}

TEST(InterleavedBlocks, PartitionTheIndexSpace) {
    for (size_t count : {size_t(0), size_t(5), size_t(1024), size_t(5000)})
        for (int parts : {1, 2, 3, 4}) {
            std::vector<int> owner(count, -1);
            for (int p = 0; p < parts; ++p) {
                size_t last = 0;
                for (const IndexRange& r : interleavedBlocks(count, 100, p, parts)) {
                    EXPECT_GE(r.begin, last);
                    EXPECT_LE(r.size(), 100u);
                    EXPECT_EQ(r.begin / 100 % size_t(parts), size_t(p));
                    last = r.end;
                    for (size_t i = r.begin; i < r.end; ++i) {
                        EXPECT_EQ(owner[i], -1) << i;
                        owner[i] = p;
                    }
                }
            }
            for (size_t i = 0; i < count; ++i) EXPECT_NE(owner[i], -1) << count << " " << parts << " " << i;
        }
}

TEST(ShardSpec, ParsesAndRefuses) {
    EXPECT_EQ(parseShard("0/1"), (ShardSpec{0, 1}));
    EXPECT_EQ(parseShard("3/4"), (ShardSpec{3, 4}));
    EXPECT_EQ(toString(parseShard("12/64")), "12/64");
    for (const char* bad : {"", "1", "4/4", "-1/4", "1/0", "a/4", "1/4x", "1//4", " 1/4", "1/70000"}) {
        const std::string e = errorOf([&] { parseShard(bad); });
        EXPECT_EQ(e.rfind("--shard: ", 0), 0u) << bad << ": " << e;
    }
}

TEST(SparseRgbSplit, SlicesConcatenateToTheWhole) {
    const SparseRgbVectors all = randomVectors(101, 5);
    for (int parts : {1, 2, 3, 10}) {
        SparseRgbVectors joined;
        for (int p = 0; p < parts; ++p) {
            const IndexRange r = evenRange(all.vertexCount(), p, parts);
            appendVertices(joined, sliceVertices(all, r.begin, r.end));
        }
        EXPECT_EQ(joined, all) << parts;
    }
}

TEST(ShardDistribution, PadsItsRangeWithEmptyVertices) {
    const SparseRgbVectors all = randomVectors(50, 9);
    ShardDistribution shard(ShardSpec{1, 3});
    const IndexRange r = shard.vertexShare(50);
    EXPECT_EQ(r, (IndexRange{17, 34}));
    const SparseRgbVectors padded = shard.gatherVertices(sliceVertices(all, r.begin, r.end), 50);
    ASSERT_EQ(padded.vertexCount(), 50u);
    EXPECT_EQ(sliceVertices(padded, r.begin, r.end), sliceVertices(all, r.begin, r.end));
    EXPECT_EQ(padded.offsets[r.begin], 0u);
    EXPECT_EQ(padded.offsets[r.end], padded.coefficientCount());
    const auto params = shard.outputParameters(50);
    ASSERT_EQ(params.size(), 2u);
    EXPECT_EQ(params[0], (std::pair<std::string, std::string>{kShardParameter, "1/3"}));
    EXPECT_EQ(params[1], (std::pair<std::string, std::string>{kShardVerticesParameter, "17-34"}));
}

namespace {

// The n shards of `whole`'s job, written to dir/part<i>.prt; their paths.
std::vector<std::string> runShards(const PrecomputeSettings& whole, int n, const fs::path& dir) {
    std::vector<std::string> parts;
    for (int i = 0; i < n; ++i) {
        PrecomputeSettings s = whole;
        s.shard = ShardSpec{i, n};
        s.outputPath = (dir / ("part" + std::to_string(i) + ".prt")).string();
        precomputeTransport(s, true);
        parts.push_back(s.outputPath);
    }
    return parts;
}

}  // namespace

TEST(Shards, MergedShardsAreTheSingleProcessFileByteForByte) {
    Progress::setQuiet(true);
    const fs::path dir = tempDir() / "merge";
    fs::create_directories(dir);
    PrecomputeSettings whole = smallJob(dir);
    whole.outputPath = (dir / "whole.prt").string();
    precomputeTransport(whole, true);

    for (int n : {1, 3, 7}) {
        std::vector<std::string> parts;
        for (int i = n - 1; i >= 0; --i) {  // any order
            PrecomputeSettings s = whole;
            s.shard = ShardSpec{i, n};
            s.outputPath = (dir / ("part" + std::to_string(i) + "of" + std::to_string(n) + ".prt")).string();
            const PrecomputeSummary summary = precomputeTransport(s, true);
            EXPECT_EQ(summary.distribution.description, "shard " + std::to_string(i) + "/" + std::to_string(n));
            parts.push_back(s.outputPath);
            // A shard is not a whole file: the renderers' loader refuses it.
            const TransportFile shardFile = loadTransportFile(s.outputPath);
            const std::string e = errorOf([&] { loadTransportFile(s.outputPath, shardFile.mesh); });
            EXPECT_NE(e.find("prt-merge"), std::string::npos) << e;
        }
        const fs::path merged = dir / ("merged" + std::to_string(n) + ".prt");
        saveTransportFile(merged.string(), mergeShards(parts));
        EXPECT_EQ(prt::test::fileBytes(merged), prt::test::fileBytes(whole.outputPath)) << n << " shards";
    }
    fs::remove_all(dir);
}

// A blocked job's shards are per vertex; the merge forms the blocks from the mesh as
// the single process does (scaled by the file's own factor), to the same bytes, and
// without the mesh it says what is missing.
TEST(Shards, BlockedJobsShardsMergeToTheSingleProcessFileByteForByte) {
    Progress::setQuiet(true);
    const fs::path dir = tempDir() / "blocked";
    fs::create_directories(dir);
    PrecomputeSettings whole = smallJob(dir);
    whole.blockCoefficients = 24;
    whole.outputPath = (dir / "whole.prt").string();
    precomputeTransport(whole, true);
    const TransportFile wholeFile = loadTransportFile(whole.outputPath);
    ASSERT_FALSE(wholeFile.components.empty());
    for (const TransportComponent& c : wholeFile.components) EXPECT_TRUE(c.blocked());

    const std::vector<std::string> parts = runShards(whole, 3, dir);
    for (const std::string& part : parts)
        for (const TransportComponent& c : loadTransportFile(part).components) EXPECT_FALSE(c.blocked());
    const fs::path merged = dir / "merged.prt";
    saveTransportFile(merged.string(), mergeShards(parts, whole.meshPath));
    EXPECT_EQ(prt::test::fileBytes(merged), prt::test::fileBytes(whole.outputPath));
    EXPECT_EQ(errorOf([&] { mergeShards(parts); }),
              "shards: their job stores blocks of 24 terms (--block-coefficients), formed from the mesh: give it "
              "with --mesh");
    // Another mesh is refused before any block is formed.
    const fs::path other = dir / "other.obj";
    saveMesh(makeIcosphere(1, 1.0f), other.string());
    EXPECT_NE(errorOf([&] { mergeShards(parts, other.string()); }).find("is not the mesh"), std::string::npos);
    fs::remove_all(dir);
}

// Editable shards (radial profiles, one shared index list per vertex) merge like any
// other: the basis is each shard's own and must agree.
TEST(Shards, EditableShardsMergeToTheSingleProcessFileByteForByte) {
    Progress::setQuiet(true);
    const fs::path dir = tempDir() / "editable";
    fs::create_directories(dir);
    PrecomputeSettings whole = smallJob(dir);
    whole.components = parseScatteringComponents("ms");
    whole.editable.enabled = true;
    whole.editable.materials = {"Skin1", "Marble"};
    whole.outputPath = (dir / "whole.prt").string();
    precomputeTransport(whole, true);
    ASSERT_TRUE(loadTransportFile(whole.outputPath).radialBasis);

    const std::vector<std::string> parts = runShards(whole, 3, dir);
    const fs::path merged = dir / "merged.prt";
    saveTransportFile(merged.string(), mergeShards(parts));
    EXPECT_EQ(prt::test::fileBytes(merged), prt::test::fileBytes(whole.outputPath));

    // A shard whose basis differs (another material range, same everything else the
    // check reads first) is refused by name.
    TransportFile foreign = loadTransportFile(parts[2]);
    foreign.radialBasis->range.zrMax *= 1.5;
    const std::string foreignPath = (dir / "foreign.prt").string();
    saveTransportFile(foreignPath, foreign);
    EXPECT_EQ(errorOf([&] { mergeShards({parts[0], parts[1], foreignPath}); }),
              foreignPath + ": does not belong with " + parts[0] + ": different radial basis (editable profiles)");
    fs::remove_all(dir);
}

TEST(Shards, UpToDateCheckTellsShardsFromWholeFiles) {
    Progress::setQuiet(true);
    const fs::path dir = tempDir() / "uptodate";
    fs::create_directories(dir);
    PrecomputeSettings s = smallJob(dir);
    s.components = parseScatteringComponents("ms");
    s.outputPath = (dir / "out.prt").string();
    s.shard = ShardSpec{0, 2};
    EXPECT_FALSE(precomputeTransport(s).skipped);
    EXPECT_TRUE(precomputeTransport(s).skipped);
    s.shard = ShardSpec{1, 2};  // another shard at the same path: recomputed
    EXPECT_FALSE(precomputeTransport(s).skipped);
    s.shard.reset();  // the whole job where a shard lies: recomputed
    EXPECT_FALSE(precomputeTransport(s).skipped);
    EXPECT_TRUE(precomputeTransport(s).skipped);
    s.shard = ShardSpec{1, 2};  // a shard job where the whole file lies: recomputed
    EXPECT_FALSE(precomputeTransport(s).skipped);
    fs::remove_all(dir);
}

TEST(Shards, MergeRefusesShardsThatDoNotBelongTogether) {
    Progress::setQuiet(true);
    const fs::path dir = tempDir() / "refuse";
    fs::create_directories(dir);
    PrecomputeSettings s = smallJob(dir);
    s.components = parseScatteringComponents("ms");
    auto shard = [&](int i, int n, const std::string& name, uint64_t seed = 1) {
        PrecomputeSettings t = s;
        t.samples.seed = seed;
        t.shard = ShardSpec{i, n};
        t.outputPath = (dir / name).string();
        precomputeTransport(t, true);
        return t.outputPath;
    };
    const std::string a = shard(0, 3, "a.prt"), b = shard(1, 3, "b.prt"), c = shard(2, 3, "c.prt");
    const std::string other = shard(2, 3, "other_seed.prt", 2), half = shard(1, 2, "half.prt");
    PrecomputeSettings w = s;
    w.outputPath = (dir / "whole.prt").string();
    precomputeTransport(w, true);

    EXPECT_EQ(errorOf([&] { mergeShards({a, b}); }), "shards: shard 2/3 is missing (2 of 3 given)");
    EXPECT_EQ(errorOf([&] { mergeShards({a, b, b}); }), b + ": shard 1/3 is given twice (also " + b + ")");
    EXPECT_EQ(errorOf([&] { mergeShards({a, b, half}); }), half + ": is shard 1/2 but " + a + " is one of 3");
    const std::string foreign = errorOf([&] { mergeShards({a, b, other}); });
    EXPECT_EQ(foreign, other + ": does not belong with " + a + ": different settings (input_digest)");
    EXPECT_EQ(errorOf([&] { mergeShards({a, b, w.outputPath}); }),
              w.outputPath + ": is a whole transport file, not a shard (it has no 'shard' parameter)");
    EXPECT_EQ(errorOf([&] { mergeShards({}); }), "shards: no shard files given");
    EXPECT_EQ(errorOf([&] { mergeShards({c, a, b}); }), prt::test::kNoError);
    fs::remove_all(dir);
}

TEST(Pass1File, RoundTripsAndRefusesWhatIsNotItsOwn) {
    const fs::path dir = tempDir() / "pass1";
    fs::create_directories(dir);
    std::vector<SparseVector> vectors(5);
    for (size_t i = 0; i < vectors.size(); ++i)
        for (uint32_t k = 0; k < i; ++k) {
            vectors[i].index.push_back(k * 3 + uint32_t(i));
            vectors[i].value.push_back(float(i) - 0.25f * float(k));
        }
    const std::string path = (dir / "p.pass1").string(), key = "seed=1\nsamples=5\n";
    savePass1File(path, key, vectors);
    const std::vector<SparseVector> back = loadPass1File(path, key);
    ASSERT_EQ(back.size(), vectors.size());
    for (size_t i = 0; i < back.size(); ++i) {
        EXPECT_EQ(back[i].index, vectors[i].index);
        EXPECT_EQ(back[i].value, vectors[i].value);
        EXPECT_EQ(back[i].channels, 1);
    }
    EXPECT_EQ(errorOf([&] { loadPass1File(path, "seed=2\nsamples=5\n"); }),
              path + ": was made for other pass-1 inputs (file has 'seed=1', this job 'seed=2')");
    // Every flipped byte is refused (magic, version, marker, or the CRC).
    const std::string bytes = prt::test::fileBytes(path);
    for (size_t at = 0; at < bytes.size(); ++at) {
        std::string bad = bytes;
        bad[at] = char(bad[at] ^ 0x5a);
        std::ofstream(path, std::ios::binary | std::ios::trunc) << bad;
        EXPECT_NE(errorOf([&] { loadPass1File(path, key); }), prt::test::kNoError) << "byte " << at;
    }
    for (size_t cut : {size_t(0), size_t(10), bytes.size() / 2, bytes.size() - 1}) {
        std::ofstream(path, std::ios::binary | std::ios::trunc) << bytes.substr(0, cut);
        EXPECT_NE(errorOf([&] { loadPass1File(path, key); }), prt::test::kNoError) << "cut at " << cut;
    }
    fs::remove_all(dir);
}

TEST(Pass1File, ShardsThatLoadPassOneMergeToTheSingleProcessFile) {
    Progress::setQuiet(true);
    const fs::path dir = tempDir() / "pass1shards";
    fs::create_directories(dir);
    PrecomputeSettings whole = smallJob(dir);
    whole.outputPath = (dir / "whole.prt").string();
    precomputeTransport(whole, true);

    PrecomputeSettings first = whole;  // computes pass 1 and saves it, nothing else
    first.pass1File = (dir / "job.pass1").string();
    first.pass1Only = true;
    first.outputPath.clear();
    const PrecomputeSummary p1 = precomputeTransport(first);
    EXPECT_FALSE(p1.pass1.loaded);
    ASSERT_TRUE(fs::exists(first.pass1File));

    std::vector<std::string> parts;
    for (int i = 0; i < 3; ++i) {
        PrecomputeSettings s = whole;
        s.pass1File = first.pass1File;
        s.shard = ShardSpec{i, 3};
        s.outputPath = (dir / ("part" + std::to_string(i) + ".prt")).string();
        EXPECT_TRUE(precomputeTransport(s, true).pass1.loaded);
        parts.push_back(s.outputPath);
    }
    const fs::path merged = dir / "merged.prt";
    saveTransportFile(merged.string(), mergeShards(parts));
    EXPECT_EQ(prt::test::fileBytes(merged), prt::test::fileBytes(whole.outputPath));

    // Another job's pass 1 is refused, not used.
    PrecomputeSettings other = whole;
    other.samples.seed = 7;
    other.pass1File = first.pass1File;
    other.outputPath = (dir / "other.prt").string();
    EXPECT_NE(errorOf([&] { precomputeTransport(other, true); }).find("was made for other pass-1 inputs"),
              std::string::npos);
    EXPECT_FALSE(fs::exists(other.outputPath));
    fs::remove_all(dir);
}
