#include "precompute/job/transport_blocking.h"

#include "common/blocked_vectors.h"
#include "common/error.h"
#include "common/transport_file.h"

namespace prt {

double blockTransportComponents(TransportFile& file, size_t keep, const std::vector<glm::vec3>& positions) {
    if (keep < 1) throw Error("--block-coefficients", "must be at least 1");
    if (positions.size() != file.mesh.vertexCount)
        throw Error("blocks", "the mesh has " + std::to_string(positions.size()) + " vertices, the file " +
                                  std::to_string(file.mesh.vertexCount));
    for (const TransportComponent& c : file.components)
        if (c.blocked()) throw Error("blocks", "the " + componentName(c.kind, c.term) + " component is already blocked");
    const std::vector<uint32_t> order = spatialBlockOrder(positions);
    const uint32_t forcedFrom = file.shIndexBegin();
    double retained = 0.0;
    std::vector<TransportComponent*> profiles;
    for (TransportComponent& c : file.components) {
        if (c.kind == ComponentKind::MultipleScatteringProfiles) {
            profiles.push_back(&c);
            continue;
        }
        c.blocks = jointTruncate(c.vectors, keep, order, forcedFrom);
        retained += retainedEnergyFraction(c.vectors, c.blocks);
        c.vectors = SparseRgbVectors();
    }
    if (!profiles.empty()) {
        std::vector<const SparseRgbVectors*> sources;
        for (const TransportComponent* c : profiles) sources.push_back(&c->vectors);
        std::vector<BlockedRgbVectors> blocks = jointTruncateNested(sources, keep, order, forcedFrom);
        std::vector<const BlockedRgbVectors*> kept;
        for (size_t k = 0; k < profiles.size(); ++k) {
            profiles[k]->blocks = std::move(blocks[k]);
            kept.push_back(&profiles[k]->blocks);
        }
        // The profiles count as one component: a profile that matters little keeps little.
        retained += retainedEnergyFraction(sources, kept);
        for (TransportComponent* c : profiles) c->vectors = SparseRgbVectors();
    }
    const size_t counted = file.components.size() - (profiles.empty() ? 0 : profiles.size() - 1);
    return file.components.empty() ? 1.0 : retained / double(counted);
}

}  // namespace prt
