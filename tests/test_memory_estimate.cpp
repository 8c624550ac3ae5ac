// The precomputation's memory estimate and its refusal (precompute/job/memory_estimate.h).
// Asserted: the estimate grows linearly with the sample count and the coefficients as
// the data structures do; a job whose estimate exceeds --max-memory is refused before
// any pass, and the old output is left untouched; the message names the estimate, the
// limit and what to change; bad limits are errors.

#include "precompute/job/memory_estimate.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <unistd.h>

#include "common/error.h"
#include "common/mesh_io.h"
#include "common/progress.h"
#include "common/shapes.h"
#include "precompute/job/pipeline.h"
#include "tests/test_support.h"

using namespace prt;
namespace fs = std::filesystem;

namespace {

PrecomputeSettings settings() {
    PrecomputeSettings s;
    s.material = materialByName("Marble");
    s.scale.sizeMm = 30;
    return s;
}

}  // namespace

TEST(MemoryEstimate, GrowsWithSamplesAndCoefficients) {
    const PrecomputeSettings s = settings();
    const uint64_t a = estimatePrecomputeMemory(s, 10000, 20000, 100000, 2).bytes;
    const uint64_t b = estimatePrecomputeMemory(s, 10000, 20000, 200000, 2).bytes;
    const uint64_t c = estimatePrecomputeMemory(s, 10000, 20000, 300000, 2).bytes;
    EXPECT_GT(b, a);
    EXPECT_NEAR(double(c - b), double(b - a), 1e-6 * double(c));  // linear in samples
    // Per sample: 1.5 x (200 + 128 x 8 + 64 + (256 x 8 + 64) / 4) bytes = 2.7 kB.
    EXPECT_NEAR(double(b - a) / 100000.0, 1.5 * (200.0 + 128 * 8 + 64 + (256 * 8 + 64) / 4.0), 1.0);
    PrecomputeSettings more = s;
    more.pass1.sampleCoefficients = 1024;
    EXPECT_GT(estimatePrecomputeMemory(more, 10000, 20000, 100000, 2).bytes, a);
    // Single scattering alone needs no samples: the sample count does not matter.
    PrecomputeSettings ss = s;
    ss.components = {false, true};
    EXPECT_EQ(estimatePrecomputeMemory(ss, 10000, 20000, 100000, 2).bytes,
              estimatePrecomputeMemory(ss, 10000, 20000, 0, 2).bytes);
    EXPECT_NE(estimatePrecomputeMemory(s, 10000, 20000, 1000000, 2).largest.find("pass 1 vectors"), std::string::npos);
    // The cell quadrature's sub-points grow with the area (and the material's kernel):
    // a 1 m^2 object of Marble needs more than the machine has, named as such.
    EXPECT_EQ(estimatePrecomputeMemory(s, 10000, 20000, 100000, 2, 0.0).bytes, a);
    const MemoryEstimate huge = estimatePrecomputeMemory(s, 10000, 20000, 100000, 2, 1e6);
    EXPECT_GT(huge.bytes, 24'000'000'000ull);
    EXPECT_NE(huge.largest.find("cell sub-points"), std::string::npos) << huge.largest;
    EXPECT_EQ(formatBytes(41'200'000'000ull), "41.2 GB");
    EXPECT_EQ(formatBytes(830'000'000ull), "830 MB");
}

TEST(MemoryEstimate, CheckNamesTheNeedAndTheLimit) {
    MemoryEstimate e;
    e.bytes = 3'000'000'000ull;
    e.largest = "pass 1 vectors 1.9 GB";
    EXPECT_NO_THROW(checkMemory(e, 4.0));
    const std::string message = test::errorOf([&] { checkMemory(e, 2.0); });
    EXPECT_NE(message.find("3.0 GB"), std::string::npos) << message;
    EXPECT_NE(message.find("2.0 GB allowed by --max-memory"), std::string::npos) << message;
    EXPECT_NE(message.find("pass 1 vectors"), std::string::npos) << message;
    test::expectErrorSubject([&] { checkMemory(e, -1.0); }, "--max-memory");
    EXPECT_GT(availableMemoryBytes(), 0u);
}

// The whole pipeline: a job over its --max-memory is refused before any pass, and the
// previous output survives byte for byte.
TEST(MemoryEstimate, PrecomputeRefusesAJobOverTheLimitAndKeepsTheOldOutput) {
    Progress::setEnabled(false);
    const fs::path dir = fs::temp_directory_path() / ("prt-memory-" + std::to_string(::getpid()));
    fs::create_directories(dir);
    PrecomputeSettings s = settings();
    s.meshPath = (dir / "sphere.obj").string();
    saveMesh(makeIcosphere(2, 1.0f), s.meshPath);
    s.outputPath = (dir / "sphere.prt").string();
    {
        std::ofstream old(s.outputPath);
        old << "the previous output";
    }
    s.samples.count = 2'000'000;  // ~5.5 GB estimated
    s.maxMemoryGb = 1.0;
    const std::string message = test::errorOf([&] { precomputeTransport(s); });
    EXPECT_NE(message.find("memory"), std::string::npos) << message;
    EXPECT_NE(message.find("allowed by --max-memory"), std::string::npos) << message;
    std::ifstream in(s.outputPath);
    std::stringstream content;
    content << in.rdbuf();
    EXPECT_EQ(content.str(), "the previous output");
    fs::remove_all(dir);
}
