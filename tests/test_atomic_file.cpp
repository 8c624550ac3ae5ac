// writeAtomically / writeFileAtomically / checkOutputPath: all or nothing, no
// temporary left behind, the old file intact after any failure.
#include <gtest/gtest.h>

#include <sys/resource.h>
#include <sys/stat.h>
#include <unistd.h>

#include <csignal>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "common/atomic_file.h"
#include "common/error.h"
#include "tests/test_support.h"

namespace fs = std::filesystem;
using prt::Error;

namespace {

using prt::test::errorOf;

class AtomicFileTest : public ::testing::Test {
protected:
    void SetUp() override {
        dir_ = fs::temp_directory_path() / ("prt_atomic_" + std::to_string(::getpid()));
        fs::remove_all(dir_);
        fs::create_directories(dir_);
    }
    void TearDown() override { fs::remove_all(dir_); }
    std::string path(const std::string& name) const { return (dir_ / name).string(); }
    std::vector<std::string> entries() const {
        std::vector<std::string> out;
        for (const auto& e : fs::directory_iterator(dir_)) out.push_back(e.path().filename().string());
        std::sort(out.begin(), out.end());
        return out;
    }
    static std::string read(const std::string& p) { return prt::test::fileBytes(p); }
    fs::path dir_;
};


}  // namespace

TEST_F(AtomicFileTest, WritesAndReplacesByRename) {
    const std::string p = path("out.json");
    prt::writeFileAtomically(p, "first\n");
    EXPECT_EQ(read(p), "first\n");
    struct stat before {};
    ASSERT_EQ(::stat(p.c_str(), &before), 0);
    prt::writeFileAtomically(p, std::string("second\0binary", 13));
    EXPECT_EQ(read(p), std::string("second\0binary", 13));
    struct stat after {};
    ASSERT_EQ(::stat(p.c_str(), &after), 0);
    EXPECT_NE(before.st_ino, after.st_ino) << "rewritten in place, not renamed";
    EXPECT_EQ(entries(), std::vector<std::string>{"out.json"});
}

TEST_F(AtomicFileTest, TemporaryKeepsTheExtensionLastAndInTheSameDirectory) {
    std::string seen;
    prt::writeAtomically(path("frame.exr"), [&](const std::string& temp) {
        seen = temp;
        std::ofstream(temp) << "x";
    });
    EXPECT_EQ(fs::path(seen).parent_path(), dir_);
    EXPECT_EQ(fs::path(seen).extension(), ".exr");
    EXPECT_TRUE(prt::isTemporaryFor(fs::path(seen).filename().string(), "frame.exr"));
    EXPECT_FALSE(prt::isTemporaryFor("frame.exr", "frame.exr"));
    EXPECT_FALSE(prt::isTemporaryFor("other.tmp1-0.exr", "frame.exr"));
    EXPECT_EQ(entries(), std::vector<std::string>{"frame.exr"});
}

TEST_F(AtomicFileTest, AFailingWriterLeavesTheOldFileAndNoTemporary) {
    const std::string p = path("keep.txt");
    prt::writeFileAtomically(p, "old");
    const std::string e = errorOf([&] {
        prt::writeAtomically(p, [&](const std::string& temp) {
            std::ofstream(temp) << "half";
            throw Error(p, "writer gave up");
        });
    });
    EXPECT_NE(e.find("writer gave up"), std::string::npos) << e;
    EXPECT_EQ(read(p), "old");
    EXPECT_EQ(entries(), std::vector<std::string>{"keep.txt"});

    // A writer that creates nothing is an error too, not an empty file.
    EXPECT_NE(errorOf([&] { prt::writeAtomically(p, [](const std::string&) {}); }).find("no file"),
              std::string::npos);
    EXPECT_EQ(read(p), "old");
}

TEST_F(AtomicFileTest, DiskFullKeepsTheOldFile) {
    const std::string p = path("big.bin");
    prt::writeFileAtomically(p, "old");
    struct rlimit saved {};
    ASSERT_EQ(getrlimit(RLIMIT_FSIZE, &saved), 0);
    auto oldHandler = std::signal(SIGXFSZ, SIG_IGN);
    struct rlimit small = saved;
    small.rlim_cur = 1024;
    ASSERT_EQ(setrlimit(RLIMIT_FSIZE, &small), 0);
    const std::string e = errorOf([&] { prt::writeFileAtomically(p, std::string(100000, 'x')); });
    ASSERT_EQ(setrlimit(RLIMIT_FSIZE, &saved), 0);
    std::signal(SIGXFSZ, oldHandler);
    EXPECT_NE(e.find("cannot write temporary file"), std::string::npos) << e;
    EXPECT_EQ(read(p), "old");
    EXPECT_EQ(entries(), std::vector<std::string>{"big.bin"});
}

TEST_F(AtomicFileTest, OutputPathsAreCheckedUpFront) {
    EXPECT_NO_THROW(prt::checkOutputPath(path("new.prt")));
    EXPECT_NE(errorOf([&] { prt::checkOutputPath(path("no/such/dir/x.prt")); }).find("does not exist"),
              std::string::npos);
    fs::create_directories(dir_ / "sub");
    EXPECT_NE(errorOf([&] { prt::checkOutputPath(path("sub")); }).find("is a directory"), std::string::npos);
    EXPECT_NE(errorOf([&] { prt::checkOutputPath(""); }).find("not a file name"), std::string::npos);
    if (::geteuid() != 0) {  // root writes anywhere
        fs::permissions(dir_ / "sub", fs::perms::owner_read | fs::perms::owner_exec);
        EXPECT_NE(errorOf([&] { prt::checkOutputPath(path("sub/x")); }).find("not writable"), std::string::npos);
        fs::permissions(dir_ / "sub", fs::perms::owner_all);
    }
    // The error names the file.
    EXPECT_EQ(errorOf([&] { prt::checkOutputPath(path("no/x")); }).rfind(path("no/x"), 0), 0u);
}

TEST_F(AtomicFileTest, LeftoversOfDeadProcessesAreRemovedOthersKept) {
    const std::string p = path("out.prt");
    // A pid that cannot be running (above the kernel's pid_max of 2^22).
    const std::string dead = "out.tmp999999999-0.prt";
    const std::string mine = "out.tmp" + std::to_string(::getpid()) + "-77.prt";  // in flight here
    const std::string alive = "out.tmp1-0.prt";                                   // init is running
    const std::string other = "other.tmp999999999-0.prt";                         // another target's
    for (const std::string& n : {dead, mine, alive, other}) std::ofstream(path(n)) << "x";
    prt::writeFileAtomically(p, "new");
    EXPECT_EQ(read(p), "new");
    std::vector<std::string> expected = {alive, other, mine, "out.prt"};
    std::sort(expected.begin(), expected.end());
    EXPECT_EQ(entries(), expected);
    EXPECT_EQ(prt::removeStaleTemporaries(p), 0u);
}
