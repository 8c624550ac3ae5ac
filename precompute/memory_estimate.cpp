#include "precompute/memory_estimate.h"

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <utility>
#include <vector>

#include "common/error.h"

namespace prt {

namespace {
constexpr double kSafety = 1.5;
}

std::string formatBytes(uint64_t bytes) {
    char buf[64];
    const double b = double(bytes);
    if (b >= 1e9) std::snprintf(buf, sizeof buf, "%.1f GB", b / 1e9);
    else if (b >= 1e6) std::snprintf(buf, sizeof buf, "%.0f MB", b / 1e6);
    else std::snprintf(buf, sizeof buf, "%.0f kB", b / 1e3);
    return buf;
}

MemoryEstimate estimatePrecomputeMemory(const PrecomputeSettings& s, size_t vertices, size_t triangles,
                                        size_t samples, int threads) {
    const double texels = 6.0 * double(s.cubemapSize) * double(s.cubemapSize);
    const bool ms = s.components.multipleScattering;
    const double terms = s.components.singleScattering ? 1.0 + (s.material.g != 0.0 ? s.phaseTerms : 0) : 0.0;
    const double n = ms ? double(samples) : 0.0;
    const std::vector<std::pair<const char*, double>> parts = {
        {"mesh and ray scene", 250.0 * double(triangles)},
        {"samples", 200.0 * n},
        {"pass 1 vectors", n * (double(s.sampleCoefficients) * 8.0 + 64.0)},
        {"pass 2 kd-tree sums", n / 4.0 * (double(s.nodeCoefficients) * 8.0 + 64.0)},
        {"per-vertex results",
         double(vertices) * double(s.vertexCoefficients) * 16.0 * ((ms ? 1.0 : 0.0) + terms)},
        {"per-thread workspaces", double(std::max(threads, 1)) * texels * 64.0},
    };
    MemoryEstimate e;
    double total = 0.0, largest = -1.0;
    for (const auto& [name, bytes] : parts) {
        total += bytes;
        if (bytes > largest) {
            largest = bytes;
            e.largest = std::string(name) + " " + formatBytes(uint64_t(bytes));
        }
    }
    e.bytes = uint64_t(std::min(total * kSafety, 1.8e19));
    return e;
}

uint64_t availableMemoryBytes() {
    std::ifstream in("/proc/meminfo");
    std::string line;
    while (std::getline(in, line)) {
        std::istringstream ss(line);
        std::string key;
        uint64_t kb = 0;
        if (ss >> key >> kb && key == "MemAvailable:") return kb * 1024;
    }
    const long pages = sysconf(_SC_PHYS_PAGES), size = sysconf(_SC_PAGE_SIZE);
    return pages > 0 && size > 0 ? uint64_t(pages) * uint64_t(size) : 0;
}

void checkMemory(const MemoryEstimate& estimate, double maxMemoryGb) {
    if (!std::isfinite(maxMemoryGb) || maxMemoryGb < 0.0)
        throw Error("--max-memory", "must be a finite number of GB >= 0 (0 = the available memory)");
    const uint64_t limit = maxMemoryGb > 0.0 ? uint64_t(maxMemoryGb * 1e9) : availableMemoryBytes();
    if (limit == 0 || estimate.bytes <= limit) return;
    throw Error("memory", "the job needs about " + formatBytes(estimate.bytes) + " (largest: " + estimate.largest +
                              "), " + formatBytes(limit) + (maxMemoryGb > 0.0 ? " allowed by --max-memory" : " available") +
                              "; use --max-memory GB to allow more, or fewer samples (--samples, --sample-spacing) "
                              "or coefficients");
}

}  // namespace prt
