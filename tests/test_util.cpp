#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <string>
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

TEST(Util, OneLineJoinsALibrarysMessage) {
    EXPECT_EQ(prt::oneLine("cannot open\nfile.exr: no such file\r\n"), "cannot open file.exr: no such file");
    EXPECT_EQ(prt::oneLine("one line"), "one line");
    EXPECT_EQ(prt::oneLine("\n\n"), "");
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

TEST(Util, CpuAvx2FmaAgreesWithTheKernelsFlags) {
    // On Linux x86-64 the kernel lists the CPU's features: AVX2 + FMA support must be
    // reported exactly when both flags are there (the SIMD kernels rely on it).
    std::ifstream in("/proc/cpuinfo");
    std::string line;
    while (std::getline(in, line) && line.rfind("flags", 0) != 0) {
    }
    if (line.empty()) GTEST_SKIP() << "no /proc/cpuinfo flags on this machine";
    std::istringstream flags(line.substr(line.find(':') + 1));
    bool avx2 = false, fma = false, f512 = false, bw = false, vl = false;
    for (std::string f; flags >> f;) {
        avx2 = avx2 || f == "avx2";
        fma = fma || f == "fma";
        f512 = f512 || f == "avx512f";
        bw = bw || f == "avx512bw";
        vl = vl || f == "avx512vl";
    }
    EXPECT_EQ(prt::cpuHasAvx2Fma(), avx2 && fma);
    EXPECT_EQ(prt::cpuHasAvx512(), avx2 && fma && f512 && bw && vl);
}

// Round trip through a real shell: the quoted word comes back as the string itself.
TEST(Util, ShellQuoteRoundTripsThroughTheShell) {
    EXPECT_EQ(prt::shellQuote("data/meshes/bunny.off"), "data/meshes/bunny.off");
    EXPECT_EQ(prt::shellQuote("sigma:0.1,0.2,0.3:1,2,3"), "sigma:0.1,0.2,0.3:1,2,3");
    EXPECT_EQ(prt::shellQuote(""), "''");
    EXPECT_EQ(prt::shellQuote("it's"), "'it'\\''s'");
    for (const std::string s : {std::string("a b"), std::string("it's here"), std::string("$HOME `x` \"q\" \\ *"),
                                std::string("''"), std::string("semi;colon|pipe&amp"), std::string("")}) {
        const std::string command = "printf '%s' " + prt::shellQuote(s);
        FILE* p = popen(command.c_str(), "r");
        ASSERT_NE(p, nullptr);
        std::string out;
        char buf[256];
        for (size_t n; (n = fread(buf, 1, sizeof buf, p)) > 0;) out.append(buf, n);
        EXPECT_EQ(pclose(p), 0);
        EXPECT_EQ(out, s) << command;
    }
}
