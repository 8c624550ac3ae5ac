#pragma once
// The viewer's relight worker (prt-relight view, docs/viewer.md): light vector
// (relight/prt/light_vector.h) + relight kernel (relight/prt/relight_kernel.h) on one thread
// of its own, off the UI thread.
//
// Contract: submit() replaces any request not yet started (the latest light wins);
// take() hands over the newest finished result, if any, and rethrows as prt::Error a
// failure of the worker (which then stops). Results are triple-buffered by swapping
// vectors (work -> ready -> the caller's), so nothing is reallocated once the sizes are
// reached. The transport file and the environments must outlive the worker and not
// change while it exists; the destructor stops the thread after the request in
// progress.

#include <glm/glm.hpp>

#include <condition_variable>
#include <memory>
#include <cstddef>
#include <cstdint>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "common/image.h"
#include "common/transport_file.h"
#include "relight/prt/light_vector.h"
#include "relight/prt/relight_kernel.h"

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
    RelightWorker(const TransportFile& file, const std::vector<Image>& environments)
        : file_(file), environments_(environments), thread_([this] { run(); }) {}
    ~RelightWorker() {
        {
            std::lock_guard<std::mutex> lock(mutex_);
            stop_ = true;
        }
        cv_.notify_all();
        thread_.join();
    }
    RelightWorker(const RelightWorker&) = delete;
    RelightWorker& operator=(const RelightWorker&) = delete;

    void submit(const LightRequest& r) {
        {
            std::lock_guard<std::mutex> lock(mutex_);
            pending_ = r;
        }
        cv_.notify_all();
    }
    // A request queued or running.
    bool busy() const {
        std::lock_guard<std::mutex> lock(mutex_);
        return pending_.has_value() || running_;
    }
    // Swaps the newest finished result into `out`; throws the worker's error, if any.
    bool take(LightResult& out);

private:
    void run();
    void compute(const LightRequest& r, LightResult& out);

    const TransportFile& file_;
    const std::vector<Image>& environments_;
    mutable std::mutex mutex_;
    std::condition_variable cv_;
    std::optional<LightRequest> pending_;
    bool running_ = false, stop_ = false, haveReady_ = false;
    std::string error_;
    LightResult work_, ready_;
    // The environment of the latest request, prepared for turning (EnvironmentLight: a
    // light vector in ~0.4 of makeLightVector's time from the image). Touched only by the
    // worker's thread; a switch of environment prepares the new one (~25 ms, 1024 x 512).
    std::unique_ptr<EnvironmentLight> prepared_;
    int preparedEnvironment_ = -1;
    std::thread thread_;  // last: started once everything above exists
};

}  // namespace prt
