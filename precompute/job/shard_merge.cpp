#include "precompute/job/shard_merge.h"

#include <algorithm>
#include <map>
#include <optional>

#include "common/error.h"
#include "common/mesh.h"
#include "common/mesh_io.h"
#include "common/transport_params.h"
#include "precompute/job/distribution.h"
#include "precompute/job/transport_blocking.h"

namespace prt {

namespace {

using Parameters = std::vector<std::pair<std::string, std::string>>;

Parameters withoutShardParameters(const Parameters& p) {
    Parameters out;
    for (const auto& kv : p)
        if (kv.first != kShardParameter && kv.first != kShardVerticesParameter) out.push_back(kv);
    return out;
}

struct ShardInfo {
    std::string path;
    ShardSpec spec;
    IndexRange range;
};

// The merge slices and appends per-vertex vectors (one CSR range per shard) and forms
// the blocks of the whole file afterwards; prt-precompute writes shards per vertex.
[[noreturn]] void refuseBlocked(const std::string& path, ComponentKind kind, uint32_t term) {
    throw Error(path, "has a blocked " + componentName(kind, term) + " component; shards are per vertex");
}

ShardInfo readShardInfo(const std::string& path) {
    const TransportFileInfo info = readTransportFileInfo(path);
    if (!info.hasParameter(kShardParameter))
        throw Error(path, "is a whole transport file, not a shard (it has no 'shard' parameter)");
    for (const TransportFileInfo::Component& c : info.components)
        if (c.blocked) refuseBlocked(path, c.kind, c.term);
    ShardInfo s;
    s.path = path;
    try {
        s.spec = parseShard(info.parameter(kShardParameter));
    } catch (const Error& e) {
        throw Error(path, std::string("bad 'shard' parameter: ") + e.what());
    }
    s.range = evenRange(info.mesh.vertexCount, s.spec.index, s.spec.count);
    const std::string expected = std::to_string(s.range.begin) + "-" + std::to_string(s.range.end);
    if (info.parameter(kShardVerticesParameter) != expected)
        throw Error(path, "shard " + toString(s.spec) + " of " + std::to_string(info.mesh.vertexCount) +
                              " vertices must hold vertices " + expected + ", it says " +
                              info.parameter(kShardVerticesParameter));
    return s;
}

// Everything but the vectors and the shard's own parameters must match.
void checkSameJob(const TransportFile& first, const std::string& firstPath, const TransportFile& f,
                  const std::string& path) {
    auto differ = [&](const std::string& what) {
        throw Error(path, "does not belong with " + firstPath + ": different " + what);
    };
    if (f.mesh != first.mesh) differ("mesh (vertex count or position hash)");
    if (f.cubemapSize != first.cubemapSize) differ("cubemap size");
    if (f.shTerms != first.shTerms) differ("SH term count");
    if (f.mmPerUnit != first.mmPerUnit) differ("scale (mm per unit)");
    if (withoutShardParameters(f.parameters) != withoutShardParameters(first.parameters))
        differ(f.parameter("input_digest") != first.parameter("input_digest") ? "settings (input_digest)"
                                                                               : "parameters");
    if (f.components.size() != first.components.size()) differ("components");
    for (size_t c = 0; c < f.components.size(); ++c)
        if (f.components[c].kind != first.components[c].kind || f.components[c].term != first.components[c].term)
            differ("components");
    if (f.viewMaps != first.viewMaps) differ("view maps");
    // Every shard builds the job's radial basis itself (deterministic), so editable
    // shards of one job carry the same one.
    if (f.radialBasis != first.radialBasis) differ("radial basis (editable profiles)");
}

}  // namespace

TransportFile mergeShards(const std::vector<std::string>& paths, const std::string& meshPath) {
    if (paths.empty()) throw Error("shards", "no shard files given");
    // Cheap look at every shard first: membership errors before any large read.
    std::map<int, ShardInfo> byIndex;
    int count = 0;
    for (const std::string& path : paths) {
        ShardInfo s = readShardInfo(path);
        if (byIndex.empty()) count = s.spec.count;
        if (s.spec.count != count)
            throw Error(path, "is shard " + toString(s.spec) + " but " + byIndex.begin()->second.path + " is one of " +
                                  std::to_string(count));
        if (const auto it = byIndex.find(s.spec.index); it != byIndex.end())
            throw Error(path, "shard " + toString(s.spec) + " is given twice (also " + it->second.path + ")");
        byIndex.emplace(s.spec.index, std::move(s));
    }
    for (int i = 0; i < count; ++i)
        if (!byIndex.count(i))
            throw Error("shards", "shard " + std::to_string(i) + "/" + std::to_string(count) +
                                         " is missing (" + std::to_string(byIndex.size()) + " of " +
                                         std::to_string(count) + " given)");

    TransportFile whole;
    std::string firstPath;
    for (const auto& [index, s] : byIndex) {
        TransportFile f = loadTransportFile(s.path);
        if (firstPath.empty()) {
            firstPath = s.path;
            whole.cubemapSize = f.cubemapSize;
            whole.shTerms = f.shTerms;
            whole.mesh = f.mesh;
            whole.mmPerUnit = f.mmPerUnit;
            whole.parameters = withoutShardParameters(f.parameters);
            whole.viewMaps = f.viewMaps;
            whole.radialBasis = f.radialBasis;
            for (const TransportComponent& c : f.components) {
                TransportComponent empty;
                empty.kind = c.kind;
                empty.term = c.term;
                whole.components.push_back(std::move(empty));
            }
        } else {
            checkSameJob(whole, firstPath, f, s.path);
        }
        for (size_t c = 0; c < f.components.size(); ++c) {
            // (readShardInfo refused blocked shards; the file may have changed since.)
            if (f.components[c].blocked()) refuseBlocked(s.path, f.components[c].kind, f.components[c].term);
            const SparseRgbVectors& v = f.components[c].vectors;
            if (v.offsets[s.range.begin] != 0 || v.offsets[s.range.end] != v.coefficientCount())
                throw Error(s.path, "has coefficients outside its vertex range " + std::to_string(s.range.begin) +
                                        "-" + std::to_string(s.range.end));
            appendVertices(whole.components[c].vectors, sliceVertices(v, s.range.begin, s.range.end));
        }
    }

    std::optional<TriangleMesh> mesh;
    if (!meshPath.empty()) {
        mesh = loadMesh(meshPath);
        if (MeshFingerprint{mesh->vertexCount(), meshFingerprint(*mesh)} != whole.mesh)
            throw Error(meshPath, "is not the mesh the shards were computed for (vertex count or position hash differs)");
    }
    const std::string blocks = whole.hasParameter("block_coefficients") ? whole.parameter("block_coefficients") : "0";
    size_t keep = 0;
    try {
        keep = size_t(std::stoull(blocks));
    } catch (const std::exception&) {
        throw Error(firstPath, "bad 'block_coefficients' parameter '" + blocks + "'");
    }
    if (keep > 0) {
        if (!mesh)
            throw Error("shards", "their job stores blocks of " + blocks +
                                      " terms (--block-coefficients), formed from the mesh: give it with --mesh");
        // The positions in mm exactly as the precompute scaled them (the file's factor).
        scaleToPhysical(*mesh, MeshScale{.sizeMm = std::nullopt, .mmPerUnit = whole.mmPerUnit});
        const double retained = blockTransportComponents(whole, keep, mesh->positions);
        // Where the single process writes it: after the derived parameters, before
        // input_digest (the last).
        whole.parameters.insert(whole.parameters.end() - 1, {kBlockRetainedEnergyParameter, formatParameter(retained)});
    }
    return whole;
}

}  // namespace prt
