#include <gtest/gtest.h>

#include <thread>
#include <vector>

#include "common/error.h"
#include "common/progress.h"

using namespace prt;

TEST(Error, MessageNamesSubjectAndReason) {
    Error e("data/bunny.off", "file not found");
    EXPECT_STREQ(e.what(), "data/bunny.off: file not found");
    EXPECT_EQ(e.subject(), "data/bunny.off");
    EXPECT_EQ(e.reason(), "file not found");
    EXPECT_STREQ(Error("", "bad").what(), "bad");
}

TEST(Error, RunMainTurnsExceptionsIntoExitCodeOne) {
    EXPECT_EQ(runMain("t", [] { return 0; }), 0);
    EXPECT_EQ(runMain("t", [] { return 3; }), 3);
    testing::internal::CaptureStderr();
    int rc = runMain("prt-test", []() -> int { throw Error("x.exr", "pixel (1, 2) is NaN"); });
    std::string err = testing::internal::GetCapturedStderr();
    EXPECT_EQ(rc, 1);
    EXPECT_EQ(err, "prt-test: error: x.exr: pixel (1, 2) is NaN\n");
}

TEST(Progress, CountsAcrossThreadsAndSummarises) {
    Progress::setEnabled(false);
    testing::internal::CaptureStderr();
    {
        Progress p("pass 1", 4000, "samples");
        std::vector<std::thread> threads;
        for (int t = 0; t < 4; ++t)
            threads.emplace_back([&] {
                for (int k = 0; k < 1000; ++k) p.advance();
            });
        for (auto& t : threads) t.join();
        p.finish();
    }
    std::string err = testing::internal::GetCapturedStderr();
    EXPECT_NE(err.find("pass 1: 4000 samples in"), std::string::npos) << err;
    // Non-interactive: exactly one line, no carriage-return redraws.
    EXPECT_EQ(std::count(err.begin(), err.end(), '\n'), 1);
    EXPECT_EQ(err.find('\r'), std::string::npos);
}

TEST(Progress, QuietPrintsNothing) {
    Progress::setQuiet(true);
    testing::internal::CaptureStderr();
    {
        Progress p("pass 1", 10, "samples");
        p.advance(10);
        p.finish();
    }
    const std::string quiet = testing::internal::GetCapturedStderr();
    Progress::setQuiet(false);
    EXPECT_EQ(quiet, "");
    testing::internal::CaptureStderr();
    Progress("pass 2", 1).finish();
    EXPECT_NE(testing::internal::GetCapturedStderr().find("pass 2: 0 items in"), std::string::npos);
}

TEST(Progress, FormatDuration) {
    EXPECT_EQ(formatDuration(1.25), "1.2 s");
    EXPECT_EQ(formatDuration(125), "2 min 05 s");
    EXPECT_EQ(formatDuration(3725), "1 h 02 min");
    EXPECT_EQ(formatDuration(-1), "?");
}
