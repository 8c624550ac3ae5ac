#include "common/transport_params.h"

#include <cmath>
#include <cstdio>
#include <sstream>

#include "common/error.h"

namespace prt {

namespace {

const std::string* find(const ParameterList& p, const std::string& key) {
    for (const auto& [k, v] : p)
        if (k == key) return &v;
    return nullptr;
}

double parseNumber(const std::string& text, const std::string& path, const std::string& key) {
    try {
        size_t used = 0;
        const double v = std::stod(text, &used);
        if (used == text.size() && std::isfinite(v)) return v;
    } catch (const std::exception&) {
    }
    throw Error(path, "parameter " + key + " is not a number: '" + text + "'");
}

uint64_t parseCount(const std::string& text, const std::string& path, const std::string& key) {
    try {
        size_t used = 0;
        const unsigned long long v = std::stoull(text, &used);
        if (used == text.size() && !text.empty() && text[0] != '-') return v;
    } catch (const std::exception&) {
    }
    throw Error(path, "parameter " + key + " is not a non-negative integer: '" + text + "'");
}

glm::dvec3 parseRgb(const std::string& text, const std::string& path, const std::string& key) {
    std::vector<double> v;
    std::stringstream in(text);
    std::string item;
    while (std::getline(in, item, ',')) v.push_back(parseNumber(item, path, key));
    if (v.size() != 3 || text.back() == ',')
        throw Error(path, "parameter " + key + " is not three comma-separated numbers: '" + text + "'");
    return {v[0], v[1], v[2]};
}

}  // namespace

ScatteringComponents parseScatteringComponents(const std::string& text) {
    const std::string expected = " (expected ms, ss, ms,ss or all)";
    if (text == "all") return ScatteringComponents::all();
    ScatteringComponents c = ScatteringComponents::none();
    size_t start = 0;
    while (true) {
        const size_t comma = text.find(',', start);
        const std::string token = text.substr(start, comma == std::string::npos ? std::string::npos : comma - start);
        bool* flag = token == "ms" ? &c.multipleScattering : token == "ss" ? &c.singleScattering : nullptr;
        if (!flag)
            throw Error("--components",
                        (token.empty() ? "empty component name in '" + text + "'" : "unknown component '" + token + "'") +
                            expected);
        if (*flag) throw Error("--components", "'" + token + "' given twice in '" + text + "'");
        *flag = true;
        if (comma == std::string::npos) break;
        start = comma + 1;
    }
    return c;
}

std::string toString(const ScatteringComponents& c) {
    if (c.multipleScattering && c.singleScattering) return "ms,ss";
    if (c.singleScattering) return "ss";
    if (c.multipleScattering) return "ms";
    return "";
}

namespace {

// A folded file's multiple-scattering vectors hold its single scattering too.
ScatteringComponents withFolding(ScatteringComponents c, bool folded) {
    if (folded && c.multipleScattering) c.singleScattering = c.folded = true;
    return c;
}

bool foldedParameter(const std::vector<std::pair<std::string, std::string>>& parameters) {
    for (const auto& [key, value] : parameters)
        if (key == kFoldedSingleScatteringParameter) return value == "1";
    return false;
}

}  // namespace

ScatteringComponents componentsOf(const TransportFile& file) {
    ScatteringComponents c = ScatteringComponents::none();
    for (const TransportComponent& t : file.components)
        (t.kind == ComponentKind::MultipleScattering || t.kind == ComponentKind::MultipleScatteringProfiles
             ? c.multipleScattering
             : c.singleScattering) = true;
    return withFolding(c, foldedParameter(file.parameters));
}

ScatteringComponents componentsOf(const TransportFileInfo& info) {
    ScatteringComponents c = ScatteringComponents::none();
    for (const TransportFileInfo::Component& t : info.components)
        (t.kind == ComponentKind::MultipleScattering || t.kind == ComponentKind::MultipleScatteringProfiles
             ? c.multipleScattering
             : c.singleScattering) = true;
    return withFolding(c, foldedParameter(info.parameters));
}

ScatteringComponents selectComponents(const std::string& request, const ScatteringComponents& available,
                                      const std::string& transportPath) {
    const ScatteringComponents asked = parseScatteringComponents(request);
    if (request != "all") {
        if (asked.multipleScattering && !available.multipleScattering)
            throw Error(transportPath, "has no multiple-scattering component (asked for by --components)");
        if (asked.singleScattering && !available.singleScattering)
            throw Error(transportPath, "has no single-scattering component (asked for by --components)");
    }
    const ScatteringComponents s = asked & available;
    if (!s.any()) throw Error(transportPath, "has none of the requested components");
    if (available.folded && !(s.multipleScattering && s.singleScattering))
        throw Error(transportPath, "has its single scattering folded into the multiple-scattering vectors "
                                   "(prt-precompute --fold-ss): the two show only together (--components all)");
    return s;
}

std::string formatParameter(double v) {
    char buf[64];
    std::snprintf(buf, sizeof buf, "%.9g", v);
    return buf;
}

std::string formatParameter(const glm::dvec3& v) {
    return formatParameter(v.x) + "," + formatParameter(v.y) + "," + formatParameter(v.z);
}

ParameterList materialParameters(const Material& m) {
    return {{"material", m.name},
            {"sigma_s_prime", formatParameter(m.sigmaSPrime)},
            {"sigma_a", formatParameter(m.sigmaA)},
            {"eta", formatParameter(m.eta)},
            {"g", formatParameter(m.g)}};
}

TransportParameters readTransportParameters(const ParameterList& p, const std::string& path) {
    TransportParameters t;
    if (const std::string* eta = find(p, "eta")) {
        t.eta = parseNumber(*eta, path, "eta");
        if (!(*t.eta >= kMinEta && *t.eta <= kMaxEta))
            throw Error(path, "parameter eta = " + *eta + " is outside [" + formatParameter(kMinEta) + ", " +
                                  formatParameter(kMaxEta) + "]");
    }
    const std::string* sigmaSPrime = find(p, "sigma_s_prime");
    const std::string* sigmaA = find(p, "sigma_a");
    if (sigmaSPrime && sigmaA && t.eta) {
        const std::string* g = find(p, "g");
        try {
            t.material = customMaterial(parseRgb(*sigmaSPrime, path, "sigma_s_prime"),
                                        parseRgb(*sigmaA, path, "sigma_a"), *t.eta,
                                        g ? parseNumber(*g, path, "g") : 0.0);
        } catch (const Error& e) {
            if (e.subject() == path) throw;
            throw Error(path, "parameter " + e.subject() + ": " + e.reason());
        }
        if (const std::string* name = find(p, "material"); name && !name->empty()) t.material->name = *name;
    }
    if (const std::string* c = find(p, "components")) {
        try {
            t.components = parseScatteringComponents(*c);
        } catch (const Error& e) {
            throw Error(path, "parameter components: " + e.reason());
        }
    }
    if (const std::string* a = find(p, "sample_area_mm2")) t.sampleAreaMm2 = parseNumber(*a, path, "sample_area_mm2");
    if (const std::string* n = find(p, "samples")) t.samples = parseCount(*n, path, "samples");
    if (const std::string* n = find(p, "seed")) t.seed = parseCount(*n, path, "seed");
    return t;
}

}  // namespace prt
