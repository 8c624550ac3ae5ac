#pragma once
// Small helpers that several modules need, in one place: the constant pi, ASCII
// lowercasing, memory sizes (available memory, "41.2 GB"), the CPU's AVX2 + FMA support, and a wall-clock stopwatch
// for the per-stage times the tools report.

#include <chrono>
#include <cstdint>
#include <ctime>
#include <numbers>
#include <string>

namespace prt {

inline constexpr double kPi = std::numbers::pi;

// ASCII lowercase (file extensions, material names, option values); other bytes
// are left as they are.
std::string toLower(std::string s);

// MemAvailable of /proc/meminfo (what can be allocated without swapping), or the
// physical memory when that is not readable; 0 when neither is known.
uint64_t availableMemoryBytes();

// "41.2 GB", "830 MB", "12 kB" (decimal units).
std::string formatBytes(uint64_t bytes);

// Whether this CPU runs AVX2 + FMA code (x86-64-v3), for the kernels compiled with a
// target attribute and chosen at run time; false on other architectures. Cached.
bool cpuHasAvx2Fma();
// Whether it also runs AVX-512 F, BW and VL code (the blocked relight kernel). Cached.
bool cpuHasAvx512();

// Wall-clock time since construction or the last restart(), on the steady clock
// (never goes backwards when the system clock is set), and the process's CPU time
// over the same span (all threads: on a shared machine, CPU time of a single-threaded
// stage is what an idle machine would take).
class Stopwatch {
public:
    Stopwatch() { restart(); }
    void restart() {
        start_ = std::chrono::steady_clock::now();
        cpuStart_ = std::clock();
    }
    double seconds() const {
        return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
    }
    double milliseconds() const { return 1e3 * seconds(); }
    double cpuSeconds() const { return double(std::clock() - cpuStart_) / CLOCKS_PER_SEC; }

private:
    std::chrono::steady_clock::time_point start_;
    std::clock_t cpuStart_ = 0;
};

}  // namespace prt
