// Fuzz target: the command-line parsers of every executable, through their real main
// functions, renamed prt_<program>_main (prt_executable's MAIN objects: prt-precompute,
// prt-pointlight, prt-reference, prt-compare, prt-envcheck, prt-merge; prt-relight's
// compiled again without the viewer). The first input byte picks
// the program ('0'..'5' in the text seeds), the rest are its arguments, one per line.
//
// Run it in an empty directory (tools/fuzz.sh does): no argument list the fuzzer can
// build names an existing mesh, image or transport file, so every run stops in option
// parsing or validation, never in a computation.
//
// Oracle: exit code 0 (help) or 1; exit 1 prints exactly one stderr line
// "prt-x: error: ..." (docs/reliability.md, "Errors are one line, early").

#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

#include "tools/fuzz/fuzz_support.h"

int prt_precompute_main(int argc, char** argv);
int prt_relight_main(int argc, char** argv);
int prt_pointlight_main(int argc, char** argv);
int prt_reference_main(int argc, char** argv);
int prt_compare_main(int argc, char** argv);
int prt_envcheck_main(int argc, char** argv);
int prt_merge_main(int argc, char** argv);

namespace {

struct Program {
    const char* name;
    int (*main)(int, char**);
};

const Program kPrograms[] = {
    {"prt-precompute", prt_precompute_main}, {"prt-relight", prt_relight_main},
    {"prt-pointlight", prt_pointlight_main}, {"prt-reference", prt_reference_main},
    {"prt-compare", prt_compare_main},       {"prt-envcheck", prt_envcheck_main},
    {"prt-merge", prt_merge_main},
};
constexpr size_t kProgramCount = sizeof kPrograms / sizeof kPrograms[0];

// Runs main with stderr going to a file; returns the exit code and what it printed.
int runCaptured(const Program& p, std::vector<std::string>& args, std::string& errText) {
    std::vector<char*> argv;
    argv.push_back(const_cast<char*>(p.name));
    for (std::string& a : args) argv.push_back(a.data());
    argv.push_back(nullptr);

    std::fflush(stderr);
    const int saved = dup(2);
    FILE* capture = std::tmpfile();
    prt::fuzz::require(saved >= 0 && capture != nullptr, "stderr capture");
    dup2(fileno(capture), 2);
    const int code = p.main(int(argv.size()) - 1, argv.data());
    std::fflush(stderr);
    dup2(saved, 2);
    close(saved);

    std::rewind(capture);
    char buf[4096];
    size_t n;
    errText.clear();
    while ((n = std::fread(buf, 1, sizeof buf, capture)) > 0) errText.append(buf, n);
    std::fclose(capture);
    return code;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    if (size < 1 || size > 4096) return 0;
    // A digit picks the program by its value (the seeds' first lines), any other byte by
    // its value modulo the count.
    const size_t pick = data[0] >= '0' && data[0] <= '9' ? size_t(data[0] - '0') : size_t(data[0]);
    const Program& program = kPrograms[pick % kProgramCount];
    std::vector<std::string> args;
    std::string current;
    bool any = false;
    for (size_t i = 1; i < size; ++i) {
        const char c = char(data[i]);
        if (c == '\n') {
            if (any) args.push_back(current);
            current.clear();
            any = true;  // the first newline ends the program selector's line
        } else if (any) {
            current.push_back(c == '\0' ? ' ' : c);  // argv strings cannot hold NUL
        }
    }
    if (any && !current.empty()) args.push_back(current);

    std::string err;
    const int code = runCaptured(program, args, err);
    if (code == 1) {
        const std::string prefix = std::string(program.name) + ": error: ";
        const bool oneLine = !err.empty() && err.back() == '\n' && err.find('\n') == err.size() - 1;
        if (!oneLine || err.compare(0, prefix.size(), prefix) != 0) {
            std::fprintf(stderr, "prt-fuzz: %s printed, for exit code 1:\n%s\n", program.name, err.c_str());
            prt::fuzz::require(false, "an error is exactly one line 'prt-x: error: ...'");
        }
    } else if (code != 0) {
        std::fprintf(stderr, "prt-fuzz: %s exited %d; stderr:\n%s\n", program.name, code, err.c_str());
        prt::fuzz::require(false, "exit code 0 or 1");
    }
    return 0;
}
