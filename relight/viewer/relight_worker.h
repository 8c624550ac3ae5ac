#pragma once
// The viewer's relight worker (prt-relight view, docs/viewer.md): light vector
// (relight/prt/light_vector.h) + relight kernel (relight/prt/relight_kernel.h) on a
// thread of its own (latest_request_worker.h: the latest request wins, results are
// triple-buffered, take() rethrows a failure as prt::Error("relight", ...)).
// The transport file and the environments must outlive the worker and not change
// while it exists.

#include <glm/glm.hpp>

#include <cstddef>
#include <cstdint>
#include <memory>
#include <vector>

#include "common/image.h"
#include "common/transport_file.h"
#include "relight/prt/light_vector.h"
#include "relight/prt/relight_kernel.h"
#include "relight/viewer/latest_request_worker.h"

namespace prt {

struct LightRequest {
    int environment = 0;
    double rotation = 0.0;  // degrees about +Y
    size_t lightTerms = 0;
    bool multipleScattering = true, singleScattering = true;
    uint64_t id = 0;

    bool sameLight(const LightRequest& o) const {
        return environment == o.environment && rotation == o.rotation && lightTerms == o.lightTerms &&
               multipleScattering == o.multipleScattering && singleScattering == o.singleScattering;
    }
};

struct LightResult {
    LightRequest request;
    VertexRadiance radiance;
    // What the GPU gets: diffuse then each term, one RGBA (A unused) per vertex, so
    // (1 + K) V entries (K = 0 without view-dependent single scattering).
    std::vector<glm::vec4> packed;
    size_t keptTerms = 0, coefficients = 0;
    double relativeL2Error = 0.0;
    double lightMs = 0.0, relightMs = 0.0;
};

class RelightWorker {
public:
    RelightWorker(const TransportFile& file, const std::vector<Image>& environments);

    void submit(const LightRequest& r) { worker_.submit(r); }
    // A request queued or running.
    bool busy() const { return worker_.busy(); }
    // Swaps the newest finished result into `out`; throws the worker's error, if any.
    bool take(LightResult& out) { return worker_.take(out); }

private:
    void compute(const LightRequest& r, LightResult& out);  // on the worker's thread

    const TransportFile& file_;
    const std::vector<Image>& environments_;
    // The environment of the latest request, prepared for turning (EnvironmentLight;
    // docs/relight.md, "Turning the environment: the fast path"); a request for another
    // environment prepares that one.
    std::unique_ptr<EnvironmentLight> prepared_;
    int preparedEnvironment_ = -1;
    LatestRequestWorker<LightRequest, LightResult> worker_;  // last: its thread uses the members above
};

}  // namespace prt
