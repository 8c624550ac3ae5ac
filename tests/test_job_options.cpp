// Job options: a JSON job parses exactly like the same options on the command line.
#include <gtest/gtest.h>

#include <CLI/CLI.hpp>

#include <unistd.h>

#include <filesystem>
#include <fstream>

#include "precompute/job/job_options.h"
#include "tests/test_support.h"

using namespace prt;
using prt::test::errorOf;

namespace {

PrecomputeSettings fromCommandLine(std::vector<std::string> args) {
    CLI::App app;
    JobOptions raw;
    PrecomputeSettings s;
    addJobOptions(app, raw, s);
    std::reverse(args.begin(), args.end());
    app.parse(args);
    return settingsFromOptions(raw, s);
}

bool sameSettings(const PrecomputeSettings& a, const PrecomputeSettings& b) {
    return a.meshPath == b.meshPath && a.outputPath == b.outputPath && a.scale.sizeMm == b.scale.sizeMm &&
           a.scale.mmPerUnit == b.scale.mmPerUnit && a.material.name == b.material.name &&
           a.material.sigmaA == b.material.sigmaA && a.material.sigmaSPrime == b.material.sigmaSPrime &&
           a.material.eta == b.material.eta && a.material.g == b.material.g && a.cubemapSize == b.cubemapSize &&
           a.vertexCoefficients == b.vertexCoefficients && a.pass2.epsilon == b.pass2.epsilon &&
           a.samples.seed == b.samples.seed && a.components == b.components && a.phase.terms == b.phase.terms;
}

}  // namespace

TEST(JobOptions, AJsonJobEqualsTheCommandLine) {
    const nlohmann::json defaults = {{"material", "Skin1"}, {"cubemap-size", 16}, {"size_mm", 20}};
    const nlohmann::json job = {{"mesh", "m.obj"},       {"output", "o.prt"}, {"cubemap-size", 64},
                                {"components", "ms,ss"}, {"g", 0.25},         {"epsilon", 0.02}};
    const PrecomputeSettings fromJson = parseJob(defaults, job, "jobs.json: job 1");
    const PrecomputeSettings fromCli =
        fromCommandLine({"m.obj", "--output", "o.prt", "--material", "Skin1", "--cubemap-size", "64",
                         "--size-mm", "20", "--components", "ms,ss", "--g", "0.25", "--epsilon", "0.02"});
    EXPECT_TRUE(sameSettings(fromJson, fromCli));
    EXPECT_EQ(fromJson.cubemapSize, 64);  // the job's key overrides the default
    EXPECT_EQ(*fromJson.scale.sizeMm, 20.0);
    EXPECT_EQ(fromJson.material.name, "Skin1");
    EXPECT_EQ(fromJson.components, ScatteringComponents::all());
}

TEST(JobOptions, ArraysBecomeCommaListsForCustomMaterials) {
    const PrecomputeSettings s = parseJob(
        {}, {{"mesh", "m.obj"}, {"output", "o"}, {"sigma-a", {0.1, 0.2, 0.3}}, {"sigma-s-prime", {1, 2, 3}}}, "j");
    EXPECT_EQ(s.material.name, "custom");
    EXPECT_EQ(s.material.sigmaA, glm::dvec3(0.1, 0.2, 0.3));
    EXPECT_EQ(s.material.sigmaSPrime, glm::dvec3(1, 2, 3));
}

TEST(JobOptions, DefaultsAndContradictions) {
    const PrecomputeSettings s = fromCommandLine({"m.obj", "-o", "o"});
    EXPECT_EQ(*s.scale.sizeMm, 30.0);  // the documented default scale
    EXPECT_FALSE(s.scale.mmPerUnit);
    EXPECT_EQ(s.material.name, "Marble");
    EXPECT_EQ(s.components, (ScatteringComponents{true, false}));

    EXPECT_NE(errorOf([] { fromCommandLine({"m", "--size-mm", "3", "--mm-per-unit", "1"}); }).find("not both"),
              std::string::npos);
    EXPECT_NE(errorOf([] { fromCommandLine({"m", "--sigma-a", "1,1,1"}); }).find("needs both"), std::string::npos);
    EXPECT_NE(errorOf([] { fromCommandLine({"m", "--material", "Jade"}); }).find("unknown material"),
              std::string::npos);
    EXPECT_NE(errorOf([] { fromCommandLine({"m", "--eta", "9"}); }).find("eta"), std::string::npos);
}

TEST(JobOptions, PathQuadratureChoosesTheDefaultPathSamples) {
    // Gauss-Legendre is the default rule; --path-samples defaults per rule, so
    // --path-quadrature midpoint alone is Wang's rule (16 midpoints).
    const PrecomputeSettings d = fromCommandLine({"m.obj", "-o", "o"});
    EXPECT_EQ(d.singleScattering.pathQuadrature, PathQuadrature::GaussLegendre);
    EXPECT_EQ(d.singleScattering.pathSamples, defaultPathSamples(PathQuadrature::GaussLegendre));
    EXPECT_EQ(d.singleScattering.pathSamples, PrecomputeSettings{}.singleScattering.pathSamples);
    const PrecomputeSettings mid = fromCommandLine({"m.obj", "-o", "o", "--path-quadrature", "midpoint"});
    EXPECT_EQ(mid.singleScattering.pathQuadrature, PathQuadrature::Midpoint);
    EXPECT_EQ(mid.singleScattering.pathSamples, 16);
    const PrecomputeSettings g8 =
        fromCommandLine({"m.obj", "-o", "o", "--path-samples", "8", "--path-quadrature", "gauss"});
    EXPECT_EQ(g8.singleScattering.pathQuadrature, PathQuadrature::GaussLegendre);
    EXPECT_EQ(g8.singleScattering.pathSamples, 8);
    const PrecomputeSettings json = parseJob({{"path-quadrature", "midpoint"}}, {{"mesh", "m.obj"}, {"output", "o"}}, "j");
    EXPECT_EQ(json.singleScattering.pathQuadrature, PathQuadrature::Midpoint);
    EXPECT_EQ(json.singleScattering.pathSamples, 16);
    const std::string bad = errorOf([] { fromCommandLine({"m", "--path-quadrature", "simpson"}); });
    EXPECT_NE(bad.find("--path-quadrature"), std::string::npos) << bad;
    EXPECT_NE(bad.find("midpoint or gauss"), std::string::npos) << bad;
}

TEST(JobOptions, SiteSpacing) {
    // Unset: 0.75 mean free paths of the material (Marble: 1 / luminance(sigma_t) = 0.39 mm).
    const PrecomputeSettings d = fromCommandLine({"m.obj", "-o", "o", "--material", "Marble"});
    EXPECT_FALSE(d.ssSiteSpacing);
    EXPECT_NEAR(resolvedSiteSpacing(d), 0.75 / luminance(d.material.sigmaT()), 1e-12);
    EXPECT_NEAR(resolvedSiteSpacing(d), 0.294, 0.002);
    EXPECT_EQ(withSharedValues(d).singleScattering.siteSpacing, resolvedSiteSpacing(d));
    EXPECT_FALSE(fromCommandLine({"m.obj", "-o", "o", "--ss-site-spacing", "auto"}).ssSiteSpacing);
    EXPECT_EQ(*fromCommandLine({"m.obj", "-o", "o", "--ss-site-spacing", "0.25"}).ssSiteSpacing, 0.25);
    EXPECT_EQ(withSharedValues(fromCommandLine({"m.obj", "-o", "o", "--ss-site-spacing", "0"})).singleScattering.siteSpacing, 0.0);
    EXPECT_EQ(*parseJob({{"ss-site-spacing", "0.5"}}, {{"mesh", "m.obj"}, {"output", "o"}}, "j").ssSiteSpacing, 0.5);
    for (const char* bad : {"-0.1", "inf", "nan", "x", "1,2"}) {
        const std::string e = errorOf([&] {
            PrecomputeSettings s = fromCommandLine({"m.obj", "-o", "o", "--ss-site-spacing", bad});
            s.components = {true, true};
            validateSettings(s);
        });
        EXPECT_NE(e.find("--ss-site-spacing"), std::string::npos) << bad << ": " << e;
    }
}

TEST(JobOptions, DirectionStride) {
    EXPECT_EQ(fromCommandLine({"m.obj", "-o", "o"}).singleScattering.directionStride, PrecomputeSettings{}.singleScattering.directionStride);
    EXPECT_EQ(PrecomputeSettings{}.singleScattering.directionStride, 4);
    EXPECT_EQ(fromCommandLine({"m.obj", "-o", "o", "--ss-direction-stride", "1"}).singleScattering.directionStride, 1);
    EXPECT_EQ(parseJob({{"ss-direction-stride", "8"}}, {{"mesh", "m.obj"}, {"output", "o"}}, "j").singleScattering.directionStride, 8);
    for (const char* bad : {"0", "3", "32", "-4"}) {
        PrecomputeSettings s = fromCommandLine({"m.obj", "-o", "o", "--ss-direction-stride", bad});
        s.components = {true, true};
        const std::string e = errorOf([&] { validateSettings(s); });
        EXPECT_NE(e.find("--ss-direction-stride"), std::string::npos) << bad << ": " << e;
    }
}

TEST(JobOptions, EditableBits) {
    EXPECT_EQ(fromCommandLine({"m.obj", "-o", "o", "--editable"}).editable.haarBits, 8);
    EXPECT_EQ(fromCommandLine({"m.obj", "-o", "o", "--editable", "--editable-bits", "16"}).editable.haarBits, 16);
    for (const char* bad : {"0", "12", "32", "-8"}) {
        const std::string e = errorOf([&] {
            validateSettings(fromCommandLine({"m.obj", "-o", "o", "--editable", "--editable-bits", bad}));
        });
        EXPECT_NE(e.find("--editable-bits"), std::string::npos) << bad << ": " << e;
    }
}

TEST(JobOptions, FlagsTakeTrueAndFalse) {
    const nlohmann::json job = {{"mesh", "m.obj"}, {"output", "o"}};
    EXPECT_TRUE(parseJob({{"editable", true}}, job, "j").editable.enabled);
    EXPECT_FALSE(parseJob({{"editable", false}}, job, "j").editable.enabled);
    EXPECT_FALSE(parseJob({}, job, "j").editable.enabled);
    // The job's false overrides the defaults' true.
    nlohmann::json off = job;
    off["editable"] = false;
    EXPECT_FALSE(parseJob({{"editable", true}}, off, "j").editable.enabled);
}

TEST(JobOptions, BadJobsNameWhereTheyAre) {
    const std::string unknown = errorOf([] { parseJob({}, {{"mesh", "m"}, {"colour", "red"}}, "jobs.json: job 3"); });
    EXPECT_EQ(unknown.rfind("jobs.json: job 3: ", 0), 0u) << unknown;
    const std::string badValue =
        errorOf([] { parseJob({}, {{"mesh", "m"}, {"seed", {{"a", 1}}}}, "jobs.json: job 1"); });
    EXPECT_NE(badValue.find("strings, numbers or arrays"), std::string::npos) << badValue;
}

TEST(JobOptions, JobFileShapeIsChecked) {
    const auto dir = std::filesystem::temp_directory_path() / ("prt_jobs_" + std::to_string(::getpid()));
    std::filesystem::create_directories(dir);
    const auto write = [&](const std::string& name, const std::string& text) {
        std::ofstream((dir / name).string()) << text;
        return (dir / name).string();
    };
    const JobFile f = loadJobFile(write("ok.json", R"({"defaults": {"material": "Ketchup"}, "jobs": [{}, {}]})"));
    EXPECT_EQ(f.jobs.size(), 2u);
    EXPECT_EQ(f.defaults["material"], "Ketchup");
    EXPECT_TRUE(loadJobFile(write("nodefaults.json", R"({"jobs": []})")).defaults.is_object());
    EXPECT_NE(errorOf([&] { loadJobFile(write("a.json", "{")); }).find("not valid JSON"), std::string::npos);
    EXPECT_NE(errorOf([&] { loadJobFile(write("b.json", "[]")); }).find("\"jobs\" array"), std::string::npos);
    EXPECT_NE(errorOf([&] { loadJobFile(write("c.json", R"({"jobs": [], "defaults": 3})")); }).find("defaults"),
              std::string::npos);
    EXPECT_NE(errorOf([&] { loadJobFile((dir / "missing.json").string()); }).find("cannot open"), std::string::npos);
    std::filesystem::remove_all(dir);
}

TEST(JobOptions, ACustomMaterialDoesNotSwallowTheMesh) {
    // The command line with the mesh after a 3-value option (CLI11 used to take the
    // mesh as a fourth value).
    const PrecomputeSettings s =
        fromCommandLine({"--sigma-a", "0.1,0.1,0.1", "--sigma-s-prime", "1,1,1", "m.obj", "-o", "o"});
    EXPECT_EQ(s.meshPath, "m.obj");
    EXPECT_EQ(s.material.sigmaA, glm::dvec3(0.1));
}

TEST(JobOptions, SingleScatteringVisibility) {
    EXPECT_TRUE(fromCommandLine({"m.obj", "-o", "o"}).singleScattering.visibilityFromExitRay);
    EXPECT_TRUE(PrecomputeSettings{}.singleScattering.visibilityFromExitRay);
    EXPECT_FALSE(fromCommandLine({"m.obj", "-o", "o", "--ss-visibility", "ray"}).singleScattering.visibilityFromExitRay);
    EXPECT_TRUE(fromCommandLine({"m.obj", "-o", "o", "--ss-visibility", "exit"}).singleScattering.visibilityFromExitRay);
    EXPECT_FALSE(parseJob({{"ss-visibility", "ray"}}, {{"mesh", "m.obj"}, {"output", "o"}}, "j").singleScattering.visibilityFromExitRay);
    const std::string bad = errorOf([] { fromCommandLine({"m.obj", "-o", "o", "--ss-visibility", "both"}); });
    EXPECT_NE(bad.find("--ss-visibility"), std::string::npos) << bad;
}

// Blocked files are the default (their accuracy, bytes and speed: docs/precompute.md);
// a per-vertex count, an editable job or a 0 asks for per-vertex vectors, and the
// defaults shrink to what a small cubemap holds.
TEST(JobOptions, BlocksAreTheDefault) {
    const std::vector<std::string> base = {"m.obj", "-o", "o.prt"};
    auto with = [&](std::vector<std::string> extra) {
        std::vector<std::string> args = base;
        args.insert(args.end(), extra.begin(), extra.end());
        return fromCommandLine(args);
    };
    const PrecomputeSettings d = with({});
    EXPECT_EQ(d.blockCoefficients, kDefaultBlockCoefficients);
    EXPECT_EQ(d.vertexCoefficients, kDefaultPreBlockCoefficients);
    EXPECT_EQ(with({"-k", "64"}).blockCoefficients, 0u);
    EXPECT_EQ(with({"-k", "64"}).vertexCoefficients, 64u);
    EXPECT_EQ(with({"--editable"}).blockCoefficients, 0u);
    EXPECT_EQ(with({"--editable"}).vertexCoefficients, kDefaultEditableCoefficients);
    EXPECT_EQ(with({"--editable", "--editable-bits", "16"}).vertexCoefficients, 128u);
    EXPECT_EQ(with({"--editable", "--editable-bits", "16", "-k", "200"}).vertexCoefficients, 200u);
    EXPECT_EQ(with({"--block-coefficients", "0"}).vertexCoefficients, 128u);
    EXPECT_EQ(with({"--block-coefficients", "200", "-k", "300"}).blockCoefficients, 200u);
    EXPECT_EQ(with({"--block-coefficients", "200", "-k", "300"}).vertexCoefficients, 300u);
    EXPECT_EQ(with({"--shard", "1/2"}).blockCoefficients, kDefaultBlockCoefficients);
    // 6 x 4 x 4 + 9 SH terms = 105: every default fits.
    const PrecomputeSettings small = with({"--cubemap-size", "4"});
    EXPECT_EQ(small.blockCoefficients, 105u);
    EXPECT_EQ(small.vertexCoefficients, 105u);
    EXPECT_EQ(with({"--cubemap-size", "8"}).vertexCoefficients, 192u);  // 393 hold 192
    // A job file resolves the same way.
    EXPECT_EQ(parseJob({}, {{"mesh", "m.obj"}, {"output", "o"}}, "j").blockCoefficients, kDefaultBlockCoefficients);
    EXPECT_EQ(parseJob({}, {{"mesh", "m.obj"}, {"output", "o"}, {"coefficients", 64}}, "j").blockCoefficients, 0u);
}
