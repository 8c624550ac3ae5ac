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

// What an embedding host polls: the newest unfinished stage, and the finished ones by
// stage number, even those that began and ended between two polls.
TEST(Progress, SnapshotsForAHostThatPolls) {
    Progress::setQuiet(true);
    const uint64_t before = Progress::stagesMade();
    {
        Progress short1("short stage", 5, "items");
        short1.advance(5);
    }
    {
        Progress outer("outer", 100, "vertices");
        outer.advance(40);
        {
            Progress inner("inner", 3, "samples");
            inner.advance(1);
            const ProgressSnapshot s = Progress::snapshot();
            EXPECT_TRUE(s.active);
            EXPECT_EQ(s.label, "inner");  // the newest unfinished one
            EXPECT_EQ(s.done, 1u);
            EXPECT_EQ(s.stage, before + 3);
        }
        const ProgressSnapshot s = Progress::snapshot();
        EXPECT_EQ(s.label, "outer");
        EXPECT_EQ(s.done, 40u);
        EXPECT_EQ(s.total, 100u);
        EXPECT_EQ(s.unit, "vertices");
    }
    Progress::setQuiet(false);
    EXPECT_FALSE(Progress::snapshot().active);
    EXPECT_EQ(Progress::stagesMade(), before + 3);
    const std::vector<ProgressSnapshot> done = Progress::finishedAfter(before);
    ASSERT_EQ(done.size(), 3u);
    EXPECT_EQ(done[0].label, "short stage");
    EXPECT_EQ(done[0].done, 5u);
    EXPECT_EQ(done[1].label, "inner");
    EXPECT_EQ(done[2].label, "outer");
    EXPECT_EQ(Progress::finishedAfter(before + 2).size(), 1u);
}

// A cancel request makes advance() throw Cancelled (in every thread) until cleared.
TEST(Progress, CancelThrowsFromAdvance) {
    Progress::setQuiet(true);
    Progress p("cancelled stage", 10);
    p.advance();
    Progress::requestCancel(true);
    EXPECT_TRUE(Progress::cancelRequested());
    EXPECT_THROW(p.advance(), Cancelled);
    std::thread other([&] { EXPECT_THROW(p.advance(), Cancelled); });
    other.join();
    Progress::requestCancel(false);
    EXPECT_NO_THROW(p.advance());
    Progress::setQuiet(false);
    try {
        throw Cancelled();
    } catch (const Error& e) {
        EXPECT_STREQ(e.what(), "cancelled");
    }
}

TEST(Progress, FormatDuration) {
    EXPECT_EQ(formatDuration(1.25), "1.2 s");
    EXPECT_EQ(formatDuration(125), "2 min 05 s");
    EXPECT_EQ(formatDuration(3725), "1 h 02 min");
    EXPECT_EQ(formatDuration(-1), "?");
}
