// The look shared by prt-relight render and view: options, defaults, checks, and the
// render arguments that give a setting back.

#include <gtest/gtest.h>

#include <CLI/CLI.hpp>

#include <cmath>
#include <sstream>
#include <string>
#include <vector>

#include "common/error.h"
#include "relight/prt/frame_settings.h"

using namespace prt;

namespace {

FrameSettings parse(const std::vector<std::string>& args) {
    CLI::App app;
    FrameSettings s;
    addFrameOptions(app, s);
    std::vector<std::string> all{"test"};
    all.insert(all.end(), args.begin(), args.end());
    std::vector<const char*> argv;
    for (const std::string& a : all) argv.push_back(a.c_str());
    app.parse(int(argv.size()), argv.data());
    return s;
}

// Splits renderArguments' text at spaces (it has no quoted values).
std::vector<std::string> words(const std::string& text) {
    std::istringstream in(text);
    std::vector<std::string> out;
    for (std::string w; in >> w;) out.push_back(w);
    return out;
}

void expectSame(const FrameSettings& a, const FrameSettings& b) {
    EXPECT_EQ(a.envRotation, b.envRotation);
    EXPECT_EQ(a.components, b.components);
    EXPECT_EQ(a.lightTerms, b.lightTerms);
    EXPECT_EQ(a.ssPath, b.ssPath);
    EXPECT_EQ(a.specular, b.specular);
    EXPECT_EQ(a.specularBlur, b.specularBlur);
    EXPECT_EQ(a.display.exposureStops, b.display.exposureStops);
    EXPECT_EQ(a.display.op, b.display.op);
}

}  // namespace

TEST(FrameSettings, DefaultsAreTheStructs) {
    expectSame(parse({}), FrameSettings{});
    const FrameSettings d;
    EXPECT_EQ(d.components, "all");
    EXPECT_EQ(d.lightTerms, 0u);
    EXPECT_EQ(d.ssPath, "refracted");
    EXPECT_FALSE(d.specular);
    EXPECT_EQ(d.specularBlur, 0);
    EXPECT_EQ(d.envRotation, 0.0);
    EXPECT_EQ(d.display.exposureStops, 0.0);
    EXPECT_EQ(d.display.op, ToneMapOperator::Clamp);
}

TEST(FrameSettings, OptionsBindEveryField) {
    const FrameSettings s = parse({"--env-rotation=-70", "--components", "ms", "-L", "40", "--specular",
                                   "--specular-blur", "4", "--exposure", "1.5", "--tonemap", "Filmic",
                                   "--ss-path", "normal"});
    EXPECT_EQ(s.envRotation, -70.0);
    EXPECT_EQ(s.components, "ms");
    EXPECT_EQ(s.lightTerms, 40u);
    EXPECT_TRUE(s.specular);
    EXPECT_EQ(s.specularBlur, 4);
    EXPECT_EQ(s.display.exposureStops, 1.5);
    EXPECT_EQ(s.display.op, ToneMapOperator::Filmic);
    EXPECT_EQ(s.ssPath, "normal");
    EXPECT_EQ(parse({"--light-terms", "7"}).lightTerms, 7u);
}

TEST(FrameSettings, OptionGroups) {
    CLI::App app;
    FrameSettings s;
    const FrameOptions o = addFrameOptions(app, s);
    ASSERT_NE(o.specular, nullptr);
    ASSERT_NE(o.specularBlur, nullptr);
    EXPECT_EQ(o.specular->get_group(), "Lighting");
    EXPECT_EQ(o.specularBlur->get_group(), "Lighting");
    EXPECT_EQ(app.get_option("--exposure")->get_group(), "Output");
    EXPECT_EQ(app.get_option("--tonemap")->get_group(), "Output");
    for (const char* name : {"--env-rotation", "--components", "--light-terms", "--ss-path"})
        EXPECT_EQ(app.get_option(name)->get_group(), "Lighting") << name;
}

TEST(FrameSettings, ChecksNameTheOption) {
    const auto subjectOf = [](void (*change)(FrameSettings&)) {
        FrameSettings s;
        change(s);
        try {
            checkFrameSettings(s);
        } catch (const Error& e) {
            return e.subject();
        }
        return std::string("<accepted>");
    };
    EXPECT_EQ(subjectOf([](FrameSettings&) {}), "<accepted>");
    EXPECT_EQ(subjectOf([](FrameSettings& s) { s.envRotation = NAN; }), "--env-rotation");
    EXPECT_EQ(subjectOf([](FrameSettings& s) { s.envRotation = INFINITY; }), "--env-rotation");
    EXPECT_EQ(subjectOf([](FrameSettings& s) { s.display.exposureStops = -INFINITY; }), "--exposure");
    EXPECT_EQ(subjectOf([](FrameSettings& s) { s.specularBlur = -1; }), "--specular-blur");
    EXPECT_EQ(subjectOf([](FrameSettings& s) { s.ssPath = "eye"; }), "--ss-path");
    EXPECT_EQ(subjectOf([](FrameSettings& s) { s.ssPath = "normal"; }), "<accepted>");
    EXPECT_EQ(subjectOf([](FrameSettings& s) { s.envRotation = -1e300; }), "<accepted>");
}

TEST(FrameSettings, RenderArgumentsText) {
    EXPECT_EQ(renderArguments(FrameSettings{}), " --env-rotation=0 --exposure=0");
    FrameSettings s;
    s.envRotation = -70.25;
    s.display.exposureStops = double(1.1f);  // the viewer's float exposure, printed to float precision
    s.lightTerms = 256;
    s.components = "ms,ss";
    s.specular = true;
    s.specularBlur = 2;
    EXPECT_EQ(renderArguments(s),
              " --env-rotation=-70.25 --exposure=1.10000002 -L 256 --components ms,ss --specular --specular-blur 2");
    s.specular = false;  // the blur goes with the layer
    EXPECT_EQ(renderArguments(s), " --env-rotation=-70.25 --exposure=1.10000002 -L 256 --components ms,ss");
    s.ssPath = "normal";
    EXPECT_EQ(renderArguments(s),
              " --env-rotation=-70.25 --exposure=1.10000002 -L 256 --components ms,ss --ss-path normal");
}

TEST(FrameSettings, RenderArgumentsParseBackToTheSettings) {
    FrameSettings s;
    s.envRotation = -123.456789012;  // %.9g: float precision survives
    s.display = {-2.5, ToneMapOperator::Chang};
    s.lightTerms = 40;
    s.components = "ss";
    s.ssPath = "normal";
    s.specular = true;
    s.specularBlur = 8;
    FrameSettings back = parse(words(renderArguments(s)));
    EXPECT_NEAR(back.envRotation, s.envRotation, 1e-6);
    back.envRotation = s.envRotation;
    expectSame(back, s);
    expectSame(parse(words(renderArguments(FrameSettings{}))), FrameSettings{});
}
