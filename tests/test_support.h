#pragma once
// Helpers the module tests share (header-only, tests only).

#include <gtest/gtest.h>

#include <functional>
#include <new>
#include <stdexcept>
#include <string>

#include "common/error.h"

namespace prt::test {

inline constexpr const char* kNoError = "<no error>";

// what() of the prt::Error that f throws, or kNoError when it throws none; any other
// exception (std::bad_alloc included) is a test failure: every user error must be a
// prt::Error with a one-line message.
inline std::string errorOf(const std::function<void()>& f) {
    try {
        f();
    } catch (const Error& e) {
        return e.what();
    } catch (const std::bad_alloc&) {
        ADD_FAILURE() << "std::bad_alloc instead of prt::Error";
        return "<bad_alloc>";
    } catch (const std::exception& e) {
        ADD_FAILURE() << "non-prt exception: " << e.what();
        return "<other exception>";
    }
    return kNoError;
}

// Expects f to throw prt::Error whose subject is `subject`.
inline void expectErrorSubject(const std::function<void()>& f, const std::string& subject) {
    try {
        f();
        ADD_FAILURE() << "expected prt::Error about " << subject;
    } catch (const Error& e) {
        EXPECT_EQ(e.subject(), subject) << e.what();
    }
}

}  // namespace prt::test
