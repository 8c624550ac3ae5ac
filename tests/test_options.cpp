// The shared camera options: parsing, automatic framing, explicit cameras, errors.

#include <gtest/gtest.h>

#include <CLI/CLI.hpp>

#include <cmath>

#include "common/options.h"
#include "common/error.h"

using namespace prt;

namespace {

CameraOptions parse(std::vector<std::string> args) {
    CLI::App app;
    CameraOptions o;
    addCameraOptions(app, o);
    args.insert(args.begin(), "test");
    std::vector<const char*> argv;
    for (const std::string& a : args) argv.push_back(a.c_str());
    app.parse(int(argv.size()), argv.data());
    return o;
}

}  // namespace

TEST(CameraOptions, DefaultsFrameTheBoundingSphere) {
    const CameraOptions o = parse({});
    const glm::dvec3 centre(1.0, 2.0, 3.0);
    const Camera c = makeCamera(o, centre, 10.0);
    const Camera expected = frameSphere(centre, 10.0, 0.0, 15.0, 30.0, 512, 512, 0.9);
    EXPECT_NEAR(glm::length(c.eye - expected.eye), 0.0, 1e-9);
    EXPECT_NEAR(glm::length(c.target - centre), 0.0, 1e-12);
    EXPECT_EQ(c.width, 512);
    EXPECT_EQ(c.height, 512);
}

TEST(CameraOptions, ExplicitEyeTargetAndSize) {
    const CameraOptions o = parse({"--eye=0,0,50", "--target=0,1,0", "-W", "64", "-H", "32", "--fov", "40"});
    const Camera c = makeCamera(o, glm::dvec3(9.0), 1.0);
    EXPECT_EQ(c.eye, glm::dvec3(0, 0, 50));
    EXPECT_EQ(c.target, glm::dvec3(0, 1, 0));
    EXPECT_EQ(c.width, 64);
    EXPECT_EQ(c.height, 32);
    EXPECT_DOUBLE_EQ(c.fovY, 40.0);
}

TEST(CameraOptions, NonsenseIsRefusedNamingTheOption) {
    CameraOptions o;
    o.fill = 1.5;
    EXPECT_THROW(makeCamera(o, glm::dvec3(0.0), 1.0), Error);
    o = CameraOptions{};
    o.elevation = 90.0;
    EXPECT_THROW(makeCamera(o, glm::dvec3(0.0), 1.0), Error);
    // Each refusal names the option the user gave (-W 0 used to surface as
    // "eye, target and up must be finite" from the framing's division by zero).
    const auto subjectOf = [](void (*change)(CameraOptions&)) {
        CameraOptions t;
        change(t);
        try {
            makeCamera(t, glm::dvec3(0.0), 1.0);
        } catch (const Error& e) {
            return e.subject();
        }
        return std::string("<accepted>");
    };
    EXPECT_EQ(subjectOf([](CameraOptions& t) { t.width = 0; }), "-W");
    EXPECT_EQ(subjectOf([](CameraOptions& t) { t.height = -5; }), "-H");
    EXPECT_EQ(subjectOf([](CameraOptions& t) { t.width = 100000; }), "-W");
    EXPECT_EQ(subjectOf([](CameraOptions& t) { t.fov = 0; }), "--fov");
    EXPECT_EQ(subjectOf([](CameraOptions& t) { t.fov = 180; }), "--fov");
    EXPECT_EQ(subjectOf([](CameraOptions& t) { t.fov = NAN; }), "--fov");
    EXPECT_THROW(parse({"--eye=1,2"}), CLI::ParseError);
}

TEST(ThreadsOption, LimitsTbbWhileItLivesAndRefusesNegativeCounts) {
    const size_t before = tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism);
    {
        const prt::ThreadLimit one(1);
        EXPECT_EQ(tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism), 1u);
    }
    EXPECT_EQ(tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism), before);
    {
        const prt::ThreadLimit none(0);  // 0 = all cores: no limit
        EXPECT_EQ(tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism), before);
    }
    try {
        prt::ThreadLimit bad(-2);
        ADD_FAILURE() << "accepted -2 threads";
    } catch (const prt::Error& e) {
        EXPECT_EQ(e.subject(), "--threads");
    }

    CLI::App app;
    int threads = 0;
    prt::addThreadsOption(app, threads);
    const char* argv[] = {"tool", "-j", "3"};
    app.parse(3, argv);
    EXPECT_EQ(threads, 3);
}

TEST(CameraOptions, AVectorOptionDoesNotSwallowTheNextPositional) {
    CLI::App app;
    prt::CameraOptions o;
    prt::addCameraOptions(app, o);
    std::string mesh;
    app.add_option("mesh", mesh);
    const char* argv[] = {"tool", "--eye", "1,2,3", "--up", "0,0,1", "bunny.off"};
    app.parse(6, argv);
    EXPECT_EQ(o.eye, (std::vector<double>{1, 2, 3}));
    EXPECT_EQ(o.up, (std::vector<double>{0, 0, 1}));
    EXPECT_EQ(mesh, "bunny.off");
}

TEST(CommandLine, UsageErrorsAreOneLineErrorsAndHelpIsNot) {
    const auto run = [](std::vector<const char*> args) -> std::string {
        CLI::App app{"test tool"};
        double size = 0;
        std::string mesh;
        app.add_option("--size-mm", size);
        app.add_subcommand("render", "a subcommand")->add_option("mesh", mesh)->required();
        args.insert(args.begin(), "tool");
        try {
            const auto code = prt::parseCommandLine(app, int(args.size()), const_cast<char**>(args.data()), "prt-x");
            return code ? "exit " + std::to_string(*code) : "run";
        } catch (const prt::Error& e) {
            return e.what();
        }
    };
    EXPECT_EQ(run({"render", "m.obj"}), "run");
    EXPECT_EQ(run({"--help"}), "exit 0");
    const auto expectOneLine = [&](std::vector<const char*> args, const std::string& hint) {
        const std::string e = run(args);
        EXPECT_EQ(e.find('\n'), std::string::npos) << e;
        EXPECT_NE(e.find("(see " + hint + " --help)"), std::string::npos) << e;
    };
    expectOneLine({"--bogus"}, "prt-x");
    expectOneLine({"--size-mm"}, "prt-x");
    expectOneLine({"--size-mm", "abc"}, "prt-x");
    expectOneLine({"render", "m.obj", "--bogus"}, "prt-x render");
    expectOneLine({"render"}, "prt-x render");
}

namespace {

Material parseMaterialOptions(std::vector<std::string> args) {
    CLI::App app;
    MaterialOptions o;
    addMaterialOptions(app, o, true);
    args.insert(args.begin(), "test");
    std::vector<const char*> argv;
    for (const std::string& a : args) argv.push_back(a.c_str());
    app.parse(int(argv.size()), argv.data());
    return makeMaterial(o);
}

}  // namespace

// The three ways to give a material, and their contradictions.
TEST(MaterialOptions, NamedCustomAndArtistsPair) {
    EXPECT_EQ(parseMaterialOptions({"-m", "skin2"}).name, "Skin2");
    const Material custom = parseMaterialOptions({"--sigma-a", "0.1,0.2,0.3", "--sigma-s-prime", "1,2,3", "--eta", "1.4"});
    EXPECT_EQ(custom.sigmaA, glm::dvec3(0.1, 0.2, 0.3));
    EXPECT_DOUBLE_EQ(custom.eta, 1.4);
    const Material artist = parseMaterialOptions({"--diffuse-colour", "0.8,0.6,0.4", "--mfp-mm", "2"});
    EXPECT_NEAR(artist.totalDiffuseReflectance().y, 0.6, 1e-12);
    EXPECT_NEAR(1.0 / artist.sigmaTr().z, 2.0, 1e-12);
    const Material perChannel = parseMaterialOptions({"--diffuse-colour", "0.8,0.6,0.4", "--mfp-mm", "3,2,1"});
    EXPECT_NEAR(1.0 / perChannel.sigmaTr().x, 3.0, 1e-12);
    EXPECT_THROW(parseMaterialOptions({"--diffuse-colour", "0.8,0.6,0.4"}), Error);
    EXPECT_THROW(parseMaterialOptions({"--diffuse-colour", "0.8,0.6,0.4", "--mfp-mm", "1,2"}), Error);
    EXPECT_THROW(parseMaterialOptions({"--diffuse-colour", "0.8,0.6,1.4", "--mfp-mm", "1"}), Error);
    EXPECT_THROW(parseMaterialOptions({"--diffuse-colour", "0.8,0.6,0.4", "--mfp-mm", "1", "--sigma-a", "1,1,1",
                                       "--sigma-s-prime", "1,1,1"}),
                 Error);
}
