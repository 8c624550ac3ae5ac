#include "relight/pointlight/point_lights.h"

#include <nlohmann/json.hpp>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <sstream>

#include "common/bssrdf.h"
#include "common/error.h"
#include "common/util.h"

namespace prt {

namespace {


glm::dvec3 colourFrom(const std::vector<double>& v, const std::string& subject, const char* what) {
    if (v.size() == 1) return glm::dvec3(v[0]);
    if (v.size() == 3) return glm::dvec3(v[0], v[1], v[2]);
    throw Error(subject, std::string("the ") + what + " needs 1 (gray) or 3 (R, G, B) values, got " +
                             std::to_string(v.size()));
}

glm::dvec3 vectorFrom(const std::vector<double>& v, const std::string& subject, const char* what) {
    if (v.size() != 3)
        throw Error(subject, std::string("the ") + what + " needs 3 values (x, y, z), got " + std::to_string(v.size()));
    return glm::dvec3(v[0], v[1], v[2]);
}

void checkColour(const glm::dvec3& c, const std::string& subject, const char* what) {
    for (int i = 0; i < 3; ++i)
        if (!std::isfinite(c[i]) || c[i] < 0.0)
            throw Error(subject, std::string("the ") + what + " must be finite and >= 0, got " + formatRgb(c, 6));
}

// A direction for the parity rays that is parallel to no axis, no face diagonal and
// no typical mesh feature, so grazing a face or running along an edge is unlikely.
const glm::dvec3 kParityDirections[3] = {
    glm::dvec3(0.5772, 0.6172, 0.5347),
    glm::dvec3(-0.7131, 0.2914, -0.6375),
    glm::dvec3(0.1733, -0.8865, 0.4291),
};

// Number of surface crossings of the ray p + t d, t > 0: repeated closest-hit queries,
// each starting just beyond the previous hit (so a crossing at a shared edge that
// both triangles report is counted once).
int crossings(const RayScene& scene, const glm::vec3& p, const glm::vec3& d) {
    const float step = 4.0f * scene.epsilon();
    const float inf = std::numeric_limits<float>::infinity();
    float tnear = 0.0f;
    int count = 0;
    for (int guard = 0; guard < 1000000; ++guard) {
        const Hit h = scene.intersect(p, d, tnear, inf);
        if (!h.hit) break;
        ++count;
        tnear = h.t + step;
    }
    return count;
}

}  // namespace

// ---------------------------------------------------------------------------
// Construction and parsing
// ---------------------------------------------------------------------------

Light pointLight(const glm::dvec3& positionMm, const glm::dvec3& intensity, std::string source) {
    const std::string subject = source.empty() ? "light" : source;
    for (int i = 0; i < 3; ++i)
        if (!std::isfinite(positionMm[i]))
            throw Error(subject, "the position must be finite, got " + formatRgb(positionMm, 6));
    checkColour(intensity, subject, "intensity (W/sr)");
    Light l;
    l.type = LightType::Point;
    l.position = positionMm;
    l.rgb = intensity;
    l.source = std::move(source);
    return l;
}

Light directionalLight(const glm::dvec3& towardLight, const glm::dvec3& irradiance, std::string source) {
    const std::string subject = source.empty() ? "light" : source;
    for (int i = 0; i < 3; ++i)
        if (!std::isfinite(towardLight[i]))
            throw Error(subject, "the direction must be finite, got " + formatRgb(towardLight, 6));
    const double len = glm::length(towardLight);
    if (!(len > 0.0) || !std::isfinite(len)) throw Error(subject, "the direction must not be zero");
    checkColour(irradiance, subject, "irradiance (W/m^2)");
    Light l;
    l.type = LightType::Directional;
    l.direction = towardLight / len;
    l.rgb = irradiance;
    l.source = std::move(source);
    return l;
}

Light spotLight(const glm::dvec3& positionMm, const glm::dvec3& axis, const glm::dvec3& intensity,
                double innerDegrees, double outerDegrees, std::string source) {
    const std::string subject = source.empty() ? "light" : source;
    Light l = pointLight(positionMm, intensity, source);
    for (int i = 0; i < 3; ++i)
        if (!std::isfinite(axis[i])) throw Error(subject, "the spot direction must be finite, got " + formatRgb(axis, 6));
    const double len = glm::length(axis);
    if (!(len > 0.0) || !std::isfinite(len)) throw Error(subject, "the spot direction must not be zero");
    if (!std::isfinite(innerDegrees) || !std::isfinite(outerDegrees) || innerDegrees < 0.0 ||
        innerDegrees > outerDegrees || !(outerDegrees > 0.0) || outerDegrees > 90.0) {
        char buf[160];
        std::snprintf(buf, sizeof buf, "the spot cone needs 0 <= inner <= outer <= 90 degrees and outer > 0, got inner %g, outer %g",
                      innerDegrees, outerDegrees);
        throw Error(subject, buf);
    }
    l.type = LightType::Spot;
    l.direction = axis / len;
    l.innerDegrees = innerDegrees;
    l.outerDegrees = outerDegrees;
    l.cosInner = std::cos(innerDegrees * kPi / 180.0);
    l.cosOuter = std::cos(outerDegrees * kPi / 180.0);
    return l;
}

Light parseLight(const std::string& text) {
    const std::string subject = "--light " + text;
    const std::vector<std::string> fields = splitText(text, ':');
    const std::string type = fields.empty() ? std::string() : toLower(trim(fields[0]));
    if (type == "spot") {
        if (fields.size() != 5)
            throw Error(subject, "expected spot:X,Y,Z:DX,DY,DZ:R,G,B:INNER,OUTER, got " + std::to_string(fields.size()) +
                                     " ':'-separated fields");
        const glm::dvec3 p = vectorFrom(parseNumberList(fields[1], subject, "position"), subject, "position");
        const glm::dvec3 d = vectorFrom(parseNumberList(fields[2], subject, "direction"), subject, "direction");
        const glm::dvec3 c = colourFrom(parseNumberList(fields[3], subject, "intensity"), subject, "intensity");
        const std::vector<double> cone = parseNumberList(fields[4], subject, "cone");
        if (cone.size() != 2)
            throw Error(subject, "the cone needs 2 values (inner, outer half-angles in degrees), got " +
                                     std::to_string(cone.size()));
        return spotLight(p, d, c, cone[0], cone[1], subject);
    }
    if (fields.size() != 3)
        throw Error(subject, "expected TYPE:X,Y,Z:R,G,B (TYPE point or dir) or spot:X,Y,Z:DX,DY,DZ:R,G,B:INNER,OUTER, got " +
                                 std::to_string(fields.size()) + " ':'-separated fields");
    if (type == "point") {
        const glm::dvec3 p = vectorFrom(parseNumberList(fields[1], subject, "position"), subject, "position");
        const glm::dvec3 c = colourFrom(parseNumberList(fields[2], subject, "intensity"), subject, "intensity");
        return pointLight(p, c, subject);
    }
    if (type == "dir" || type == "directional") {
        const glm::dvec3 d = vectorFrom(parseNumberList(fields[1], subject, "direction"), subject, "direction");
        const glm::dvec3 c = colourFrom(parseNumberList(fields[2], subject, "irradiance"), subject, "irradiance");
        return directionalLight(d, c, subject);
    }
    throw Error(subject, "unknown light type '" + trim(fields[0]) + "' (valid: point, dir, spot)");
}

std::vector<Light> parseLightScene(const std::string& jsonText, const std::string& path) {
    nlohmann::json doc;
    try {
        doc = nlohmann::json::parse(jsonText);
    } catch (const nlohmann::json::exception& e) {
        throw Error(path, std::string("not valid JSON: ") + e.what());
    }
    if (!doc.is_object()) throw Error(path, "expected a JSON object with a \"lights\" list");
    for (auto it = doc.begin(); it != doc.end(); ++it)
        if (it.key() != "lights") throw Error(path, "unknown key \"" + it.key() + "\" (expected \"lights\")");
    if (!doc.contains("lights") || !doc["lights"].is_array()) throw Error(path, "\"lights\" must be a list");

    // A JSON array of numbers (or one number when `allowScalar`).
    auto numbers = [](const nlohmann::json& v, const std::string& where, const char* key,
                      bool allowScalar) -> std::vector<double> {
        std::vector<double> out;
        if (allowScalar && v.is_number()) {
            out.push_back(v.get<double>());
            return out;
        }
        if (!v.is_array())
            throw Error(where, std::string("\"") + key + "\" must be a list of numbers" +
                                   (allowScalar ? " or one number" : ""));
        for (const nlohmann::json& x : v) {
            if (!x.is_number()) throw Error(where, std::string("\"") + key + "\" must contain numbers only");
            out.push_back(x.get<double>());
        }
        return out;
    };

    std::vector<Light> lights;
    const nlohmann::json& list = doc["lights"];
    for (size_t i = 0; i < list.size(); ++i) {
        const std::string where = path + ": lights[" + std::to_string(i) + "]";
        const nlohmann::json& l = list[i];
        if (!l.is_object()) throw Error(where, "must be an object");
        if (!l.contains("type") || !l["type"].is_string())
            throw Error(where, "needs \"type\": \"point\", \"directional\" or \"spot\"");
        const std::string type = toLower(l["type"].get<std::string>());
        const bool point = type == "point";
        const bool spot = type == "spot";
        const bool directional = type == "directional" || type == "dir";
        if (!point && !directional && !spot)
            throw Error(where, "unknown type \"" + l["type"].get<std::string>() + "\" (valid: point, directional, spot)");
        const std::vector<std::string> keys =
            point ? std::vector<std::string>{"position", "intensity"}
            : spot ? std::vector<std::string>{"position", "direction", "intensity", "inner", "outer"}
                   : std::vector<std::string>{"direction", "irradiance"};
        std::string expected;
        for (const std::string& k : keys) expected += (expected.empty() ? "\"" : ", \"") + k + "\"";
        for (auto it = l.begin(); it != l.end(); ++it)
            if (it.key() != "type" && std::find(keys.begin(), keys.end(), it.key()) == keys.end())
                throw Error(where, "unknown key \"" + it.key() + "\" for a " + type + " light (expected " + expected + ")");
        for (const std::string& k : keys)
            if (!l.contains(k)) throw Error(where, "missing \"" + k + "\"");
        if (spot) {
            for (const char* k : {"inner", "outer"})
                if (!l[k].is_number()) throw Error(where, std::string("\"") + k + "\" must be one number (degrees)");
            lights.push_back(spotLight(vectorFrom(numbers(l["position"], where, "position", false), where, "position"),
                                       vectorFrom(numbers(l["direction"], where, "direction", false), where, "direction"),
                                       colourFrom(numbers(l["intensity"], where, "intensity", true), where, "intensity"),
                                       l["inner"].get<double>(), l["outer"].get<double>(), where));
            continue;
        }
        const char* whereKey = point ? "position" : "direction";
        const char* colourKey = point ? "intensity" : "irradiance";
        const glm::dvec3 v = vectorFrom(numbers(l[whereKey], where, whereKey, false), where, whereKey);
        const glm::dvec3 c = colourFrom(numbers(l[colourKey], where, colourKey, true), where, colourKey);
        lights.push_back(point ? pointLight(v, c, where) : directionalLight(v, c, where));
    }
    return lights;
}

std::vector<Light> loadLightScene(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw Error(path, "cannot open the light scene file");
    std::ostringstream text;
    text << in.rdbuf();
    if (in.bad()) throw Error(path, "read error");
    return parseLightScene(text.str(), path);
}

std::string lightSceneJson(const std::vector<Light>& lights) {
    auto array = [](const glm::dvec3& v) { return nlohmann::json::array({v.x, v.y, v.z}); };
    nlohmann::json list = nlohmann::json::array();
    for (const Light& l : lights) {
        nlohmann::json j;
        if (l.type == LightType::Point) {
            j = {{"type", "point"}, {"position", array(l.position)}, {"intensity", array(l.rgb)}};
        } else if (l.type == LightType::Spot) {
            j = {{"type", "spot"},           {"position", array(l.position)}, {"direction", array(l.direction)},
                 {"intensity", array(l.rgb)}, {"inner", l.innerDegrees},       {"outer", l.outerDegrees}};
        } else {
            j = {{"type", "directional"}, {"direction", array(l.direction)}, {"irradiance", array(l.rgb)}};
        }
        list.push_back(std::move(j));
    }
    return nlohmann::json{{"lights", list}}.dump(2) + "\n";
}

std::string describe(const Light& light) {
    char buf[320];
    if (light.type == LightType::Point)
        std::snprintf(buf, sizeof buf, "point at (%g, %g, %g) mm, %g %g %g W/sr", light.position.x, light.position.y,
                      light.position.z, light.rgb.x, light.rgb.y, light.rgb.z);
    else if (light.type == LightType::Spot)
        std::snprintf(buf, sizeof buf,
                      "spot at (%g, %g, %g) mm along (%.4g, %.4g, %.4g), cone %g..%g deg, %g %g %g W/sr on the axis",
                      light.position.x, light.position.y, light.position.z, light.direction.x, light.direction.y,
                      light.direction.z, light.innerDegrees, light.outerDegrees, light.rgb.x, light.rgb.y,
                      light.rgb.z);
    else
        std::snprintf(buf, sizeof buf, "directional toward (%.4g, %.4g, %.4g), %g %g %g W/m^2", light.direction.x,
                      light.direction.y, light.direction.z, light.rgb.x, light.rgb.y, light.rgb.z);
    return buf;
}

// ---------------------------------------------------------------------------
// What a light delivers at a point
// ---------------------------------------------------------------------------

double spotFalloff(const Light& light, const glm::dvec3& fromLight) {
    if (light.type != LightType::Spot) return 1.0;
    const double c = glm::dot(light.direction, fromLight);
    if (light.cosInner <= light.cosOuter) return c >= light.cosOuter ? 1.0 : 0.0;  // inner == outer: hard edge
    const double t = std::clamp((c - light.cosOuter) / (light.cosInner - light.cosOuter), 0.0, 1.0);
    return t * t * (3.0 - 2.0 * t);
}

bool incidentLight(const Light& l, const glm::dvec3& x, IncidentLight& out) {
    if (l.type == LightType::Directional) {
        out.toLight = l.direction;
        out.irradiance = l.rgb;
        out.distance = std::numeric_limits<double>::infinity();
        return true;
    }
    const glm::dvec3 d = l.position - x;
    const double r2 = glm::dot(d, d);
    if (!(r2 > 0.0)) return false;  // a light on the point itself: no defined direction
    const double r = std::sqrt(r2);
    out.toLight = d / r;
    out.irradiance = l.rgb * (kSquareMmPerSquareMetre / r2);
    if (l.type == LightType::Spot) out.irradiance *= spotFalloff(l, -out.toLight);
    out.distance = r;
    return true;
}

bool lightUnoccluded(const RayScene& scene, const glm::vec3& x, const glm::vec3& ng, const IncidentLight& light) {
    const glm::vec3 wf(light.toLight);
    const glm::vec3 org = scene.offsetRayOrigin(x, ng, wf);
    // Stop short of a light with a position so that geometry behind it cannot shadow.
    const float tfar = std::isfinite(light.distance) ? float(light.distance * (1.0 - 1e-6))
                                                     : std::numeric_limits<float>::infinity();
    return !scene.occluded(org, wf, 0.0f, tfar);
}

// ---------------------------------------------------------------------------
// Inside / outside
// ---------------------------------------------------------------------------

bool insideClosedSurface(const RayScene& scene, const glm::dvec3& p) {
    const glm::vec3 origin(p);
    int insideVotes = 0;
    for (const glm::dvec3& d : kParityDirections)
        insideVotes += crossings(scene, origin, glm::vec3(glm::normalize(d))) % 2;
    return insideVotes >= 2;
}

void checkLightsOutside(const RayScene& scene, const std::vector<Light>& lights) {
    for (size_t i = 0; i < lights.size(); ++i) {
        const Light& l = lights[i];
        if (!hasPosition(l)) continue;
        if (insideClosedSurface(scene, l.position))
            throw Error(l.source.empty() ? "light " + std::to_string(i + 1) : l.source,
                        std::string(l.type == LightType::Spot ? "the spot light" : "the point light") + " at (" + formatRgb(l.position, 6) +
                            ") mm is inside the object; light sources must be outside it");
    }
}

// ---------------------------------------------------------------------------
// Direct irradiance
// ---------------------------------------------------------------------------

const char* toString(FresnelModel model) { return model == FresnelModel::Exact ? "exact" : "keng"; }

FresnelModel parseFresnelModel(const std::string& text) {
    const std::string t = toLower(trim(text));
    if (t == "exact") return FresnelModel::Exact;
    if (t == "keng") return FresnelModel::Keng;
    throw Error("--fresnel", "unknown model '" + text + "' (valid: exact, keng)");
}

double incidentTransmittance(FresnelModel model, double eta, double cosTheta) {
    if (model == FresnelModel::Keng) return 1.0 - fresnelDiffuseReflectance(eta);  // F_dt (Keng Eq. 2)
    return fresnelTransmittance(eta, cosTheta);
}

double outgoingTransmittance(FresnelModel model, double eta, double cosTheta) {
    if (model == FresnelModel::Keng) return 1.0;  // Keng Eq. 3: L = S / pi
    return fresnelTransmittance(eta, cosTheta);
}

glm::dvec3 directIrradiance(const RayScene& scene, const std::vector<Light>& lights, const SurfacePoint& x,
                            double eta, FresnelModel model) {
    const glm::dvec3 p(x.position);
    const glm::dvec3 n(x.normal);
    const glm::dvec3 ng(x.geometricNormal);
    glm::dvec3 sum(0.0);
    for (const Light& l : lights) {
        IncidentLight in;
        if (!incidentLight(l, p, in)) continue;
        const double cosTheta = glm::dot(n, in.toLight);
        if (cosTheta <= 0.0 || glm::dot(ng, in.toLight) <= 0.0) continue;
        if (!lightUnoccluded(scene, x.position, x.geometricNormal, in)) continue;
        sum += incidentTransmittance(model, eta, cosTheta) * cosTheta * in.irradiance;  // Keng Eq. 4: E^ = F E
    }
    return sum;
}

// ---------------------------------------------------------------------------
// Irradiance samples
// ---------------------------------------------------------------------------

double IrradianceSamples::totalArea() const {
    double a = 0.0;
    for (float x : areas) a += double(x);
    return a;
}

IrradianceSamples faceCentroidSamples(const TriangleMesh& mesh) {
    const bool haveNormals = mesh.normals.size() == mesh.positions.size();
    IrradianceSamples s;
    s.source = SampleSource::FaceCentroids;
    const size_t nf = mesh.triangleCount();
    s.positions.reserve(nf);
    s.normals.reserve(nf);
    s.geometricNormals.reserve(nf);
    s.areas.reserve(nf);
    s.triangles.reserve(nf);
    for (size_t f = 0; f < nf; ++f) {
        const glm::uvec3 t = mesh.triangles[f];
        if (t.x >= mesh.positions.size() || t.y >= mesh.positions.size() || t.z >= mesh.positions.size())
            throw Error("mesh", "triangle " + std::to_string(f) + " has a vertex index out of range");
        const float area = faceArea(mesh, f);
        if (!(area > 0.0f)) continue;
        const glm::vec3 ng = faceNormal(mesh, f);
        // The centroid in double so that large coordinates do not lose the last bits.
        const glm::dvec3 c = (glm::dvec3(mesh.positions[t.x]) + glm::dvec3(mesh.positions[t.y]) +
                              glm::dvec3(mesh.positions[t.z])) / 3.0;
        glm::vec3 n = ng;
        if (haveNormals) {
            const glm::vec3 sum = mesh.normals[t.x] + mesh.normals[t.y] + mesh.normals[t.z];
            const float len = glm::length(sum);
            if (len > 1e-12f && glm::dot(sum, ng) > 0.0f) n = sum / len;
        }
        s.positions.emplace_back(c);
        s.normals.push_back(n);
        s.geometricNormals.push_back(ng);
        s.areas.push_back(area);
        s.triangles.push_back(uint32_t(f));
    }
    if (s.positions.empty()) throw Error("mesh", "no face has a positive area; nothing to sample");
    s.irradiance.assign(s.positions.size(), glm::vec3(0.0f));
    return s;
}

IrradianceSamples samplesFromSampleSet(const SampleSet& set) {
    if (set.samples.empty()) throw Error("samples", "the sample set is empty");
    if (!(set.areaPerSample > 0.0) || !std::isfinite(set.areaPerSample))
        throw Error("samples", "the area per sample must be positive and finite");
    IrradianceSamples s;
    const size_t n = set.samples.size();
    s.positions.resize(n);
    s.normals.resize(n);
    s.geometricNormals.resize(n);
    s.areas.assign(n, float(set.areaPerSample));
    s.triangles.resize(n);
    for (size_t i = 0; i < n; ++i) {
        const SurfaceSample& x = set.samples[i];
        s.positions[i] = x.position;
        s.normals[i] = x.normal;
        s.geometricNormals[i] = x.geometricNormal;
        s.triangles[i] = x.triangle;
    }
    s.irradiance.assign(n, glm::vec3(0.0f));
    return s;
}

const char* toString(SampleSource source) {
    return source == SampleSource::FaceCentroids ? "faces" : "poisson";
}

SampleSource parseSampleSource(const std::string& text) {
    const std::string t = toLower(trim(text));
    if (t == "faces") return SampleSource::FaceCentroids;
    if (t == "poisson") return SampleSource::PoissonDisk;
    throw Error("--samples", "unknown sample source '" + text + "' (valid: faces, poisson)");
}

void computeIrradiance(IrradianceSamples& samples, const RayScene& scene, const std::vector<Light>& lights,
                       double eta, FresnelModel model) {
    std::vector<glm::vec3> irradiance;
    computeIrradiance(samples, scene, lights, eta, model, irradiance);
    samples.irradiance = std::move(irradiance);
}

void computeIrradiance(const IrradianceSamples& samples, const RayScene& scene, const std::vector<Light>& lights,
                       double eta, FresnelModel model, std::vector<glm::vec3>& irradiance,
                       std::vector<glm::dvec3>* lightPower) {
    const size_t n = samples.size();
    if (samples.normals.size() != n || samples.geometricNormals.size() != n)
        throw Error("samples", "inconsistent sample arrays");
    if (lightPower && samples.areas.size() != n) throw Error("samples", "inconsistent sample arrays");
    irradiance.assign(n, glm::vec3(0.0f));
    // Fail before the parallel loop, not inside it, for a bad eta.
    (void)incidentTransmittance(model, eta, 1.0);
    // directIrradiance's rays, traced in packets (occludedBatch) per block of samples:
    // the ray toward a point light is scaled so that t = 1 is the light's distance
    // (one tfar for the whole batch), which is the same segment.
    constexpr size_t kBlock = 256;
    const size_t blocks = (n + kBlock - 1) / kBlock;
    // Per block and light: sum of A_i E^_i (summed over blocks in order afterwards, so
    // the totals do not depend on the thread count).
    std::vector<glm::dvec3> blockPower(lightPower ? blocks * lights.size() : 0, glm::dvec3(0.0));
    tbb::parallel_for(size_t(0), blocks, [&](size_t b) {
        const tbb::blocked_range<size_t> r(b * kBlock, std::min(n, (b + 1) * kBlock));
        float ox[kBlock], oy[kBlock], oz[kBlock], dx[kBlock], dy[kBlock], dz[kBlock];
        uint8_t occluded[kBlock];
        size_t index[kBlock];
        glm::dvec3 value[kBlock];
        glm::dvec3 sum[kBlock];
        const size_t count = r.end() - r.begin();
        for (size_t k = 0; k < count; ++k) sum[k] = glm::dvec3(0.0);
        for (size_t li = 0; li < lights.size(); ++li) {
            const Light& l = lights[li];
            size_t m = 0;
            for (size_t k = 0; k < count; ++k) {
                const size_t i = r.begin() + k;
                const glm::dvec3 p(samples.positions[i]), nrm(samples.normals[i]), ng(samples.geometricNormals[i]);
                IncidentLight in;
                if (!incidentLight(l, p, in)) continue;
                const glm::dvec3 w = in.toLight, e = in.irradiance;
                const double dist = hasPosition(l) ? in.distance : 1.0;
                const double cosTheta = glm::dot(nrm, w);
                if (cosTheta <= 0.0 || glm::dot(ng, w) <= 0.0) continue;
                const glm::vec3 wf(w);
                const glm::vec3 org = scene.offsetRayOrigin(samples.positions[i], samples.geometricNormals[i], wf);
                const glm::vec3 dir = hasPosition(l) ? wf * float(dist) : wf;
                ox[m] = org.x; oy[m] = org.y; oz[m] = org.z;
                dx[m] = dir.x; dy[m] = dir.y; dz[m] = dir.z;
                index[m] = k;
                value[m] = incidentTransmittance(model, eta, cosTheta) * cosTheta * e;  // Keng Eq. 4: E^ = F E
                ++m;
            }
            const float tfar = hasPosition(l) ? float(1.0 - 1e-6) : std::numeric_limits<float>::infinity();
            scene.occludedBatch(ox, oy, oz, dx, dy, dz, m, 0.0f, tfar, occluded);
            for (size_t j = 0; j < m; ++j)
                if (!occluded[j]) {
                    sum[index[j]] += value[j];
                    if (lightPower) blockPower[b * lights.size() + li] += double(samples.areas[r.begin() + index[j]]) * value[j];
                }
        }
        for (size_t k = 0; k < count; ++k) irradiance[r.begin() + k] = glm::vec3(sum[k]);
    });
    if (lightPower) {
        lightPower->assign(lights.size(), glm::dvec3(0.0));
        for (size_t b = 0; b < blocks; ++b)
            for (size_t li = 0; li < lights.size(); ++li) (*lightPower)[li] += blockPower[b * lights.size() + li];
    }
}

void requireIrradianceEta(double irradianceEta, double materialEta) {
    if (materialEta == irradianceEta) return;
    char buf[200];
    std::snprintf(buf, sizeof buf,
                  "eta %.6g differs from the %.6g the irradiance was computed with; a new eta needs new irradiance "
                  "(a new renderer)",
                  materialEta, irradianceEta);
    throw Error("material", buf);
}

}  // namespace prt
