#include "tools/fuzz/fuzz_support.h"

#include <cstdio>
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <fstream>
#include <typeinfo>
#include <unistd.h>

#include "common/error.h"

namespace fs = std::filesystem;

namespace prt::fuzz {
namespace {

const fs::path& workDirectory() {
    static const fs::path dir = [] {
        const char* base = std::getenv("TMPDIR");
        std::string pattern = std::string(base && *base ? base : "/tmp") + "/prt-fuzz-XXXXXX";
        if (!mkdtemp(pattern.data())) {
            std::perror("prt-fuzz: mkdtemp");
            std::abort();
        }
        static const fs::path removeAtExit = pattern;
        std::atexit([] {
            std::error_code ec;
            fs::remove_all(removeAtExit, ec);
        });
        return fs::path(pattern);
    }();
    return dir;
}

}  // namespace

std::string writeInput(const uint8_t* data, size_t size, std::string_view extension) {
    const fs::path path = workDirectory() / ("input" + std::string(extension));
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out.write(reinterpret_cast<const char*>(data), std::streamsize(size));
    out.close();
    if (!out) {
        std::fprintf(stderr, "prt-fuzz: cannot write %s\n", path.c_str());
        std::abort();
    }
    return path.string();
}

std::string scratchPath(std::string_view name) { return (workDirectory() / std::string(name)).string(); }

void expectErrors(const std::function<void()>& body) {
    try {
        body();
    } catch (const prt::Error&) {
        // The loader refused the input: the contract.
    } catch (const std::exception& e) {
        std::fprintf(stderr, "prt-fuzz: escaped exception %s: %s\n", typeid(e).name(), e.what());
        std::abort();
    } catch (...) {
        std::fprintf(stderr, "prt-fuzz: escaped exception of unknown type\n");
        std::abort();
    }
}

void require(bool condition, const char* what) {
    if (condition) return;
    std::fprintf(stderr, "prt-fuzz: oracle failed: %s\n", what);
    std::abort();
}

}  // namespace prt::fuzz
