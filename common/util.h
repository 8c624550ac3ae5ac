#pragma once
// Small helpers that several modules need, in one place: the constant pi, ASCII
// lowercasing, trimming, splitting and number lists, shell quoting, memory sizes (available memory, "41.2 GB"), RGB triples as text, the
// median, the CPU's AVX2 + FMA support, and a wall-clock stopwatch for the per-stage
// times the tools report.

#include <glm/glm.hpp>

#include <chrono>
#include <cstdint>
#include <ctime>
#include <numbers>
#include <string>
#include <vector>

namespace prt {

inline constexpr double kPi = std::numbers::pi;

// ASCII lowercase (file extensions, material names, option values); other bytes
// are left as they are.
std::string toLower(std::string s);

// s without its leading and trailing whitespace.
std::string trim(const std::string& s);
// A library's (sometimes multi-line) message on one line: line breaks become spaces,
// trailing whitespace goes.
std::string oneLine(std::string text);
// s cut at every `separator` ("a::b" gives "a", "", "b"; "" gives one empty part).
std::vector<std::string> splitText(const std::string& s, char separator);
// A comma-separated list of numbers as people type them (whitespace around each, a
// leading '+'), e.g. "1, 0.5,2". Throws prt::Error(subject, "... in the <what> ...")
// for an empty item or one that is not a number; values are not checked for range.
std::vector<double> parseNumberList(const std::string& text, const std::string& subject, const std::string& what);

// MemAvailable of /proc/meminfo (what can be allocated without swapping), or the
// physical memory when that is not readable; 0 when neither is known.
uint64_t availableMemoryBytes();

// VmRSS of /proc/self/status: the process's resident memory now; 0 when not readable.
uint64_t residentMemoryBytes();

// "41.2 GB", "830 MB", "12 kB" (decimal units).
std::string formatBytes(uint64_t bytes);

// s as one word of a POSIX shell command line (the commands the tools print for a user
// to paste): unchanged when it is non-empty and holds only letters, digits and
// _ . / : = , + - @ %; otherwise in single quotes, each ' written as '\''.
std::string shellQuote(const std::string& s);

// An RGB triple (or any 3-vector) as the tools print it: each component as printf's
// %.<significantDigits>g, joined by `separator`; formatRgb({0.5, 1, 2}) is "0.5, 1, 2".
// significantDigits >= 1.
std::string formatRgb(const glm::dvec3& rgb, int significantDigits = 4, const char* separator = ", ");

// The median of `values` (taken by value and reordered): the middle value, or the mean
// of the two middle ones for an even count; 0 for none.
double median(std::vector<double> values);

// Whether this CPU runs AVX2 + FMA code (x86-64-v3), for the kernels compiled with a
// target attribute and chosen at run time; false on other architectures. Cached. The
// environment variable PRT_ISA=baseline (or avx2) caps both answers at the process's
// start, so that the x86-64 (or AVX2) paths can be run and tested on any newer CPU.
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
