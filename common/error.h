#pragma once
// The one error type of the project: every failure that a user can cause (a missing
// file, a bad format, a nonsense parameter) is thrown as prt::Error carrying the
// file (or parameter) it concerns and a one-line reason. Executables catch it in
// main, print what() on one line and exit non-zero (see runMain).

#include <functional>
#include <stdexcept>
#include <string>

namespace prt {

class Error : public std::runtime_error {
public:
    // what() is "<subject>: <reason>", or just "<reason>" when subject is empty.
    Error(std::string subject, std::string reason);

    const std::string& subject() const { return subject_; }
    const std::string& reason() const { return reason_; }

private:
    std::string subject_;
    std::string reason_;
};

// Runs body, turning any prt::Error or std::exception into "<program>: error: <what>"
// on stderr and exit code 1. Returns body's exit code otherwise.
int runMain(const char* program, const std::function<int()>& body);

// Prints "<program>: warning: <message>" to stderr (thread-safe).
void warn(const std::string& message);

}  // namespace prt
