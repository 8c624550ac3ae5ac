#include "common/util.h"

#include "common/error.h"

#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <sstream>

namespace prt {

std::string toLower(std::string s) {
    for (char& c : s) c = char(std::tolower(static_cast<unsigned char>(c)));
    return s;
}

std::string trim(const std::string& s) {
    size_t a = 0, b = s.size();
    while (a < b && std::isspace(static_cast<unsigned char>(s[a]))) ++a;
    while (b > a && std::isspace(static_cast<unsigned char>(s[b - 1]))) --b;
    return s.substr(a, b - a);
}

std::string oneLine(std::string text) {
    for (char& c : text)
        if (c == '\n' || c == '\r') c = ' ';
    while (!text.empty() && std::isspace(static_cast<unsigned char>(text.back()))) text.pop_back();
    return text;
}

std::vector<std::string> splitText(const std::string& s, char separator) {
    std::vector<std::string> parts;
    size_t start = 0;
    for (;;) {
        const size_t end = s.find(separator, start);
        parts.push_back(s.substr(start, end == std::string::npos ? std::string::npos : end - start));
        if (end == std::string::npos) return parts;
        start = end + 1;
    }
}

std::vector<double> parseNumberList(const std::string& text, const std::string& subject, const std::string& what) {
    std::vector<double> values;
    for (const std::string& raw : splitText(text, ',')) {
        const std::string t = trim(raw);
        if (t.empty()) throw Error(subject, "empty number in the " + what);
        double v = 0.0;
        const char* first = t.data();
        // from_chars takes no leading '+'; accept it as people write it.
        if (*first == '+') ++first;
        const auto [end, ec] = std::from_chars(first, t.data() + t.size(), v);
        if (ec != std::errc() || end != t.data() + t.size())
            throw Error(subject, "'" + t + "' in the " + what + " is not a number");
        values.push_back(v);
    }
    return values;
}

double median(std::vector<double> values) {
    if (values.empty()) return 0.0;
    std::sort(values.begin(), values.end());
    const size_t n = values.size();
    return n % 2 ? values[n / 2] : 0.5 * (values[n / 2 - 1] + values[n / 2]);
}

std::string formatRgb(const glm::dvec3& rgb, int significantDigits, const char* separator) {
    std::string out;
    for (int c = 0; c < 3; ++c) {
        char buf[64];
        std::snprintf(buf, sizeof buf, "%.*g", significantDigits, rgb[c]);
        if (c > 0) out += separator;
        out += buf;
    }
    return out;
}

namespace {

// PRT_ISA caps the kernels' choice: "baseline" (x86-64), "avx2" (no AVX-512); unset or
// anything else: what the CPU runs.
int isaCap() {
    static const int cap = [] {
        const char* v = std::getenv("PRT_ISA");
        if (v && std::strcmp(v, "baseline") == 0) return 0;
        if (v && std::strcmp(v, "avx2") == 0) return 1;
        return 2;
    }();
    return cap;
}

}  // namespace

bool cpuHasAvx2Fma() {
#if defined(__x86_64__) && defined(__GNUC__)
    static const bool has = [] {
        __builtin_cpu_init();
        return __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
    }();
    return has && isaCap() >= 1;
#else
    return false;
#endif
}

bool cpuHasAvx512() {
#if defined(__x86_64__) && defined(__GNUC__)
    static const bool has = [] {
        __builtin_cpu_init();
        return __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512bw") &&
               __builtin_cpu_supports("avx512vl");
    }();
    return has && cpuHasAvx2Fma() && isaCap() >= 2;
#else
    return false;
#endif
}

std::string shellQuote(const std::string& s) {
    const auto safe = [](unsigned char c) {
        return std::isalnum(c) || std::strchr("_./:=,+-@%", c) != nullptr;
    };
    if (!s.empty() && std::all_of(s.begin(), s.end(), [&](char c) { return c != '\0' && safe(c); })) return s;
    std::string out = "'";
    for (const char c : s) out += c == '\'' ? std::string("'\\''") : std::string(1, c);
    return out + "'";
}

std::string formatBytes(uint64_t bytes) {
    char buf[64];
    const double b = double(bytes);
    if (b >= 1e9) std::snprintf(buf, sizeof buf, "%.1f GB", b / 1e9);
    else if (b >= 1e6) std::snprintf(buf, sizeof buf, "%.0f MB", b / 1e6);
    else std::snprintf(buf, sizeof buf, "%.0f kB", b / 1e3);
    return buf;
}

namespace {

// The "Key:  N kB" line of a /proc file, in bytes; 0 when absent or unreadable.
uint64_t procKilobytesLine(const char* path, const std::string& key) {
    std::ifstream in(path);
    std::string line;
    while (std::getline(in, line)) {
        std::istringstream ss(line);
        std::string name;
        uint64_t kb = 0;
        if (ss >> name >> kb && name == key) return kb * 1024;
    }
    return 0;
}

}  // namespace

uint64_t residentMemoryBytes() { return procKilobytesLine("/proc/self/status", "VmRSS:"); }

uint64_t availableMemoryBytes() {
    if (const uint64_t available = procKilobytesLine("/proc/meminfo", "MemAvailable:")) return available;
    const long pages = sysconf(_SC_PHYS_PAGES), size = sysconf(_SC_PAGE_SIZE);
    return pages > 0 && size > 0 ? uint64_t(pages) * uint64_t(size) : 0;
}

}  // namespace prt
