// prt-merge: joins the shard files of `prt-precompute --shard i/n` into the whole
// transport file (docs/cluster.md). Thin: parses arguments and calls mergeShards().

#include <CLI/CLI.hpp>

#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include "common/atomic_file.h"
#include "common/error.h"
#include "common/mesh_io.h"
#include "common/options.h"
#include "common/progress.h"
#include "common/util.h"
#include "precompute/job/shard_merge.h"

using namespace prt;

int main(int argc, char** argv) {
    return runMain("prt-merge", [&]() -> int {
        CLI::App app{
            "prt-merge: join the n shard files of one precompute job (prt-precompute --shard i/n) into\n"
            "the whole transport file, byte for byte the file one process writes. The shards must\n"
            "come from the same mesh and settings, with every index 0..n-1 exactly once. Example:\n"
            "  for i in 0 1 2 3; do prt-precompute mesh.ply --shard $i/4 -o part$i.prt; done\n"
            "  prt-merge -o mesh.prt part0.prt part1.prt part2.prt part3.prt"};
        std::vector<std::string> shards;
        std::string output, meshPath;
        app.add_option("shards", shards, "Shard files, in any order")->required();
        app.add_option("-o,--output", output, "Transport file to write (atomically)")->required();
        app.add_option("--mesh", meshPath,
                       "The shards' mesh file: checked against them, and needed to form the blocks of a blocked "
                       "job (prt-precompute's default)");
        if (const auto exitCode = parseCommandLine(app, argc, argv, "prt-merge")) return *exitCode;
        checkOutputPath(output);
        for (const std::string& s : shards)
            if (std::filesystem::exists(output) && std::filesystem::equivalent(s, output))
                throw Error(output, "the output is one of the shards");
        const Stopwatch start;
        const TransportFile whole = mergeShards(shards, meshPath);
        saveTransportFile(output, whole);
        std::printf("%s: %zu shards joined, %llu vertices, %.2f MB, %s\n", output.c_str(), shards.size(),
                    (unsigned long long)whole.mesh.vertexCount, double(std::filesystem::file_size(output)) / 1e6,
                    formatDuration(start.seconds()).c_str());
        return 0;
    });
}
