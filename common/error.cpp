#include "common/error.h"

#include <cstdio>
#include <mutex>

namespace prt {

namespace {
std::string joinMessage(const std::string& subject, const std::string& reason) {
    return subject.empty() ? reason : subject + ": " + reason;
}
std::mutex& stderrMutex() {
    static std::mutex m;
    return m;
}
std::string& programName() {
    static std::string name = "prt";
    return name;
}
}  // namespace

Error::Error(std::string subject, std::string reason)
    : std::runtime_error(joinMessage(subject, reason)),
      subject_(std::move(subject)),
      reason_(std::move(reason)) {}

int runMain(const char* program, const std::function<int()>& body) {
    programName() = program;
    try {
        return body();
    } catch (const std::exception& e) {
        std::lock_guard lock(stderrMutex());
        std::fprintf(stderr, "%s: error: %s\n", program, e.what());
        return 1;
    }
}

void warn(const std::string& message) {
    std::lock_guard lock(stderrMutex());
    std::fprintf(stderr, "%s: warning: %s\n", programName().c_str(), message.c_str());
}

}  // namespace prt
