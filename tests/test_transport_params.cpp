// The typed transport-file parameters: one --components grammar for every tool,
// the material written and read back exactly, malformed values refused naming the file.
#include <gtest/gtest.h>

#include <string>

#include "common/error.h"
#include "common/transport_file.h"
#include "common/transport_params.h"
#include "tests/test_support.h"

using namespace prt;

namespace {

using prt::test::errorOf;


TransportFile fileWith(std::initializer_list<ComponentKind> kinds) {
    TransportFile f;
    uint32_t term = 0;
    for (ComponentKind k : kinds) {
        TransportComponent c;
        c.kind = k;
        c.term = k == ComponentKind::SingleScatteringTerm ? term++ : 0;
        f.components.push_back(c);
    }
    return f;
}

}  // namespace

TEST(ScatteringComponents, OneGrammarForEveryTool) {
    EXPECT_EQ(parseScatteringComponents("ms"), (ScatteringComponents{true, false}));
    EXPECT_EQ(parseScatteringComponents("ss"), (ScatteringComponents{false, true}));
    EXPECT_EQ(parseScatteringComponents("ms,ss"), ScatteringComponents::all());
    EXPECT_EQ(parseScatteringComponents("ss,ms"), ScatteringComponents::all());
    EXPECT_EQ(parseScatteringComponents("all"), ScatteringComponents::all());
    for (const char* bad : {"", "ms,", ",ss", "ms,,ss", "MS", "ms,ms", "xs", "ms ss", "ms, ss", " ms", "ms;ss",
                            "all,ms", "specular"}) {
        try {
            parseScatteringComponents(bad);
            ADD_FAILURE() << "accepted '" << bad << "'";
        } catch (const Error& e) {
            EXPECT_EQ(e.subject(), "--components") << bad;
            EXPECT_EQ(std::string(e.what()).find('\n'), std::string::npos) << "one line";
        }
    }
    EXPECT_NE(errorOf([] { parseScatteringComponents("ss,ss"); }).find("twice"), std::string::npos);
}

TEST(ScatteringComponents, ToStringReadsBack) {
    for (const ScatteringComponents c : {ScatteringComponents{true, false}, ScatteringComponents{false, true},
                                         ScatteringComponents::all()})
        EXPECT_EQ(parseScatteringComponents(toString(c)), c);
    EXPECT_EQ(toString(ScatteringComponents{}), "ms");  // the default: multiple scattering only
    EXPECT_EQ(toString(ScatteringComponents::none()), "");
}

TEST(ScatteringComponents, WhatAFileHasAndWhatToRender) {
    EXPECT_EQ(componentsOf(fileWith({ComponentKind::MultipleScattering})), (ScatteringComponents{true, false}));
    EXPECT_EQ(componentsOf(fileWith({ComponentKind::SingleScatteringIsotropic})), (ScatteringComponents{false, true}));
    EXPECT_EQ(componentsOf(fileWith({ComponentKind::MultipleScattering, ComponentKind::SingleScatteringTerm,
                                     ComponentKind::SingleScatteringTerm})),
              ScatteringComponents::all());
    EXPECT_EQ(componentsOf(TransportFile{}), ScatteringComponents::none());

    const ScatteringComponents msOnly{true, false};
    EXPECT_EQ(selectComponents("all", msOnly, "f.prt"), msOnly);            // "all" = what the file has
    EXPECT_EQ(selectComponents("ms", ScatteringComponents::all(), "f.prt"), msOnly);
    const std::string e = errorOf([&] { selectComponents("ss", msOnly, "f.prt"); });
    EXPECT_EQ(e.rfind("f.prt: has no single-scattering component", 0), 0u) << e;
    EXPECT_NE(errorOf([&] { selectComponents("all", ScatteringComponents::none(), "f.prt"); }).find("none"),
              std::string::npos);
}

// A folded file (prt-precompute --fold-ss) has both components in one vector: shown
// together or refused, never one silently with the other in it.
TEST(ScatteringComponents, AFoldedFileShowsBothOrRefuses) {
    TransportFile f;
    TransportComponent ms;
    ms.kind = ComponentKind::MultipleScattering;
    f.components.push_back(ms);
    EXPECT_EQ(componentsOf(f), (ScatteringComponents{true, false}));
    f.parameters.push_back({kFoldedSingleScatteringParameter, "1"});
    const ScatteringComponents folded = componentsOf(f);
    EXPECT_TRUE(folded.multipleScattering && folded.singleScattering && folded.folded);
    EXPECT_EQ(selectComponents("all", folded, "f.prt"), ScatteringComponents::all());
    EXPECT_EQ(selectComponents("ss,ms", folded, "f.prt"), ScatteringComponents::all());
    for (const char* alone : {"ms", "ss"}) {
        const std::string e = errorOf([&] { selectComponents(alone, folded, "f.prt"); });
        EXPECT_EQ(e.rfind("f.prt: has its single scattering folded", 0), 0u) << e;
    }
}

TEST(TransportParameters, MaterialRoundTripsExactlyToStoredPrecision) {
    Material m = materialByName("Skin1");
    m.eta = 1.44;
    m.g = -0.25;
    ParameterList p = materialParameters(m);
    ASSERT_EQ(p.size(), 5u);
    EXPECT_EQ(p[0].first, "material");  // the file's key order, part of the input digest
    EXPECT_EQ(p[1].first, "sigma_s_prime");
    EXPECT_EQ(p[2].first, "sigma_a");
    EXPECT_EQ(p[3].first, "eta");
    EXPECT_EQ(p[4].first, "g");
    p.push_back({"components", "ms,ss"});
    p.push_back({"samples", "1234"});
    p.push_back({"seed", "7"});
    p.push_back({"sample_area_mm2", formatParameter(0.0125)});
    const TransportParameters t = readTransportParameters(p, "f.prt");
    ASSERT_TRUE(t.material);
    EXPECT_EQ(t.material->name, "Skin1");
    for (int c = 0; c < 3; ++c) {
        EXPECT_NEAR(t.material->sigmaSPrime[c], m.sigmaSPrime[c], 1e-9 * m.sigmaSPrime[c]);
        EXPECT_NEAR(t.material->sigmaA[c], m.sigmaA[c], 1e-9 * m.sigmaA[c]);
    }
    EXPECT_DOUBLE_EQ(t.material->eta, 1.44);
    EXPECT_DOUBLE_EQ(*t.eta, 1.44);
    EXPECT_DOUBLE_EQ(t.material->g, -0.25);
    EXPECT_EQ(*t.components, ScatteringComponents::all());
    EXPECT_EQ(*t.samples, 1234u);
    EXPECT_EQ(*t.seed, 7u);
    EXPECT_DOUBLE_EQ(*t.sampleAreaMm2, 0.0125);
}

TEST(TransportParameters, AbsentKeysStayAbsent) {
    // A synthetic file with eta only (prt-make-test-scene): no material, eta known.
    const TransportParameters t = readTransportParameters({{"material", "synthetic"}, {"eta", "1.4"}}, "f.prt");
    EXPECT_FALSE(t.material);
    EXPECT_DOUBLE_EQ(*t.eta, 1.4);
    EXPECT_FALSE(t.components);
    EXPECT_FALSE(t.samples);
    const TransportParameters empty = readTransportParameters({}, "f.prt");
    EXPECT_FALSE(empty.eta);
    EXPECT_FALSE(empty.material);
}

TEST(TransportParameters, MalformedValuesNameTheFileAndTheKey) {
    const auto err = [](ParameterList p) { return errorOf([&] { readTransportParameters(p, "f.prt"); }); };
    EXPECT_EQ(err({{"eta", "abc"}}), "f.prt: parameter eta is not a number: 'abc'");
    EXPECT_NE(err({{"eta", "7"}}).find("outside"), std::string::npos);
    EXPECT_NE(err({{"eta", "1.3"}, {"sigma_a", "1,2"}, {"sigma_s_prime", "1,1,1"}}).find("sigma_a"), std::string::npos);
    EXPECT_NE(err({{"eta", "1.3"}, {"sigma_a", "-1,0,0"}, {"sigma_s_prime", "1,1,1"}}).rfind("f.prt: parameter", 0),
              std::string::npos);
    EXPECT_NE(err({{"components", "ms,xx"}}).find("parameter components"), std::string::npos);
    EXPECT_NE(err({{"samples", "-3"}}).find("non-negative integer"), std::string::npos);
    EXPECT_NE(err({{"eta", "nan"}}).find("not a number"), std::string::npos);
}
