#include <gtest/gtest.h>

#include <cmath>
#include <thread>

#include "common/util.h"

TEST(Util, PiIsPi) {
    EXPECT_DOUBLE_EQ(prt::kPi, std::acos(-1.0));
    EXPECT_DOUBLE_EQ(std::sin(prt::kPi / 2), 1.0);
}

TEST(Util, ToLowerIsAsciiOnly) {
    EXPECT_EQ(prt::toLower("MaRbLe.EXR"), "marble.exr");
    EXPECT_EQ(prt::toLower("Skin1 \xC3\x89"), "skin1 \xC3\x89");  // UTF-8 bytes untouched
    EXPECT_EQ(prt::toLower(""), "");
}

TEST(Util, StopwatchMeasuresElapsedTime) {
    prt::Stopwatch w;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    const double t = w.seconds();
    EXPECT_GE(t, 0.019);
    EXPECT_NEAR(w.milliseconds(), 1e3 * w.seconds(), 5.0);
    w.restart();
    EXPECT_LT(w.seconds(), t);
}
