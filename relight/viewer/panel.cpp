// The viewer's ImGui panel: see panel.h.

#include "relight/viewer/panel.h"

#include <imgui.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iterator>
#include <limits>

#include "common/error.h"
#include "common/material_edit.h"
#include "common/materials.h"
#include "common/util.h"
#include "relight/viewer/window.h"

namespace prt {

namespace fs = std::filesystem;

namespace {

// The viewer edits sigma_a and sigma_s' only (eta and g stay the file's).
bool sameCoefficients(const Material& a, const Material& b) {
    return a.sigmaA == b.sigmaA && a.sigmaSPrime == b.sigmaSPrime;
}

const ImVec4 kErrorColour(1.0f, 0.35f, 0.3f, 1.0f);

// Log-scale slider of three channels; writes back only the channels that moved, so the
// others keep their double values.
bool sliderChannels(const char* label, glm::dvec3& v, float lo, float hi, const char* format) {
    float f[3] = {float(v.x), float(v.y), float(v.z)};
    if (!ImGui::SliderFloat3(label, f, lo, hi, format, ImGuiSliderFlags_Logarithmic | ImGuiSliderFlags_AlwaysClamp))
        return false;
    for (int c = 0; c < 3; ++c)
        if (f[c] != float(v[c])) v[c] = double(f[c]);
    return true;
}

// The "material" section: editable files change the material and the size live; the
// edit goes to `state` only when the basis covers it (else the reason is shown and the
// previous material stays).
void drawMaterialPanel(const PanelInputs& in, ViewState& state) {
    if (!ImGui::CollapsingHeader("material", ImGuiTreeNodeFlags_DefaultOpen)) return;
    const RelightObject& object = in.setup.object;
    if (!object.editable) {
        ImGui::TextDisabled("not editable: the file's material and size are the precompute's");
        ImGui::TextDisabled("(make an editable file with prt-precompute --editable)");
        return;
    }
    const EditableTransport& e = *object.editable;
    Material m = state.material;
    double size = state.sizeMm;
    bool changed = false;

    // Presets: the measured materials at the file's eta.
    const std::vector<std::string> names = materialNames();
    std::string current = "custom";
    for (const std::string& n : names)
        if (sameCoefficients(m, materialByName(n))) current = n;
    if (ImGui::BeginCombo("preset", current.c_str())) {
        for (const std::string& n : names)
            if (ImGui::Selectable(n.c_str(), n == current)) {
                m = parseMaterial(n, e.fileMaterial().eta, e.fileMaterial().g);
                changed = true;
            }
        ImGui::Selectable("custom", current == "custom");
        ImGui::EndCombo();
    }
    int view = state.materialByAppearance ? 1 : 0;
    ImGui::RadioButton("sigma_a, sigma_s'", &view, 0);
    ImGui::SameLine();
    ImGui::RadioButton("colour, mean free path", &view, 1);
    state.materialByAppearance = view == 1;
    if (!state.materialByAppearance) {
        changed |= sliderChannels("sigma_a (1/mm)", m.sigmaA, 1e-5f, 10.0f, "%.4g");
        changed |= sliderChannels("sigma_s' (1/mm)", m.sigmaSPrime, 1e-3f, 1e3f, "%.4g");
        if (changed && current != "custom" && m.name == current) m.name = "custom";
    } else {
        const MaterialAppearance a = appearanceOf(m);
        float colour[3] = {float(a.diffuseColour.x), float(a.diffuseColour.y), float(a.diffuseColour.z)};
        glm::dvec3 mfp = a.meanFreePathMm;
        bool moved = ImGui::ColorEdit3("diffuse colour", colour, ImGuiColorEditFlags_Float);
        moved |= sliderChannels("mean free path (mm)", mfp, 1e-3f, 1e3f, "%.4g");
        if (moved) {
            glm::dvec3 c = a.diffuseColour;
            for (int k = 0; k < 3; ++k)
                if (colour[k] != float(a.diffuseColour[k])) c[k] = std::clamp(double(colour[k]), 1e-4, 0.9999);
            try {
                m = materialFromAppearance(c, mfp, e.fileMaterial().eta, e.fileMaterial().g);
                m.name = "custom";
                changed = true;
            } catch (const Error& err) {
                state.materialError = err.what();
            }
        }
    }
    const auto [lo, hi] = coveredSizesMm(e, m);
    if (lo <= hi) {
        float f = float(size);
        if (ImGui::SliderFloat("size (mm)", &f, float(lo), float(hi), "%.4g",
                               ImGuiSliderFlags_Logarithmic | ImGuiSliderFlags_AlwaysClamp) &&
            f != float(size)) {
            size = double(f);
            changed = true;
        }
        ImGui::TextDisabled("sizes the basis covers for it: %.4g .. %.4g mm (file: %.4g mm)", lo, hi,
                            e.objectSizeMm());
    } else {
        ImGui::TextDisabled("no size is covered for this material (file: %.4g mm)", e.objectSizeMm());
    }
    if (ImGui::Button("file's material and size")) {
        m = e.fileMaterial();
        size = e.objectSizeMm();
        changed = true;
    }
    if (changed) editMaterial(e, state, m, size);
    if (!state.materialError.empty()) ImGui::TextColored(kErrorColour, "%s", state.materialError.c_str());
    if (in.light && !in.light->materialError.empty())
        ImGui::TextColored(kErrorColour, "%s", in.light->materialError.c_str());
    ImGui::PushTextWrapPos(ImGui::GetCursorPosX() + 420.0f);
    ImGui::TextWrapped("%s at %.4g mm", describeMaterial(state.material).c_str(), state.sizeMm);
    ImGui::PopTextWrapPos();
    const bool fileMaterial = sameCoefficients(state.material, e.fileMaterial()) && state.sizeMm == e.objectSizeMm();
    if (in.available.singleScattering && !fileMaterial)
        ImGui::TextColored(ImVec4(1.0f, 0.8f, 0.3f, 1.0f), "single scattering: not edited (file's material)");
    const MaterialEditStats& s = in.edits;
    if (s.edits.count) {
        if (s.lastPath == LightResult::EditPath::Projected)
            ImGui::Text("last edit %.1f ms: projected%s", s.lastMs,
                        s.lastProjectMs > 0.0
                            ? (" (light projected, once per light: " + formatParameter(std::round(s.lastProjectMs)) +
                               " ms)").c_str()
                            : " (light already projected)");
        else
            ImGui::Text("last edit %.1f ms: recombined %.1f ms + relight", s.lastMs, s.lastRecombineMs);
        ImGui::Text("%zu edits, mean %.1f ms, min %.1f, max %.1f", s.edits.count, s.edits.mean(), s.edits.min,
                    s.edits.max);
    }
}

void drawPointLightPanel(const PanelInputs& in, ViewState& state, PointLightWorker* pointWorker,
                         PointLightComparison& comparison) {
    ImGui::Separator();
    ImGui::Checkbox("environment light (E)", &state.environmentLight);
    if (!pointWorker) {
        ImGui::TextDisabled("point lights: the transport file names no material");
        return;
    }
    ImGui::SameLine();
    ImGui::Checkbox("point lights (L)", &state.pointLights);
    if (!ImGui::CollapsingHeader("point lights (Chang et al. 2008)", ImGuiTreeNodeFlags_DefaultOpen)) return;
    static const char* kModes[] = {"sampling", "hybrid", "local", "global"};  // TextureSpaceMode order
    ImGui::Combo("R_d by", &state.splitMode, kModes, int(std::size(kModes)));
    ImGui::SliderInt("samples N", &state.pointSamples, 16, 20000, "%d", ImGuiSliderFlags_Logarithmic);
    // The surface terms, their rays at the vertices (vertex_surface_terms.h).
    ImGui::Checkbox("specular##point", &state.pointSpecular);
    ImGui::SameLine();
    ImGui::Checkbox("single scattering##point", &state.pointSingleScattering);
    if (state.pointSpecular)
        ImGui::SliderFloat("GGX alpha", &state.pointSpecularRoughness, 0.001f, 1.0f, "%.3f",
                           ImGuiSliderFlags_Logarithmic | ImGuiSliderFlags_AlwaysClamp);
    const float radius = float(std::max(in.setup.object.sphereRadius, 1e-3));
    int remove = -1;
    for (int i = 0; i < int(state.lights.size()); ++i) {
        Light& l = state.lights[size_t(i)];
        ImGui::PushID(i);
        ImGui::Text("light %d (%s)", i + 1,
                    l.type == LightType::Point  ? "point, W/sr"
                    : l.type == LightType::Spot ? "spot, W/sr on its axis"
                                                : "directional, W/m^2");
        if (hasPosition(l)) {
            float p[3] = {float(l.position.x), float(l.position.y), float(l.position.z)};
            if (ImGui::DragFloat3("position (mm)", p, 0.01f * radius, 0.0f, 0.0f, "%.2f"))
                l.position = glm::dvec3(p[0], p[1], p[2]);
        }
        if (l.type == LightType::Spot) {
            // Through spotLight, so the cone's cosines follow its angles and stay valid.
            float a[3] = {float(l.direction.x), float(l.direction.y), float(l.direction.z)};
            float cone[2] = {float(l.innerDegrees), float(l.outerDegrees)};
            bool edited = ImGui::DragFloat3("axis", a, 0.01f, -1.0f, 1.0f, "%.3f");
            edited |= ImGui::DragFloat2("cone (inner, outer deg)", cone, 0.2f, 0.0f, 90.0f, "%.1f");
            const glm::dvec3 axis(a[0], a[1], a[2]);
            if (edited && glm::length(axis) > 1e-6 && cone[1] > 0.0f) {
                const double outer = std::min(double(cone[1]), 90.0), inner = std::min(double(cone[0]), outer);
                l = spotLight(l.position, axis, l.rgb, std::max(inner, 0.0), outer, l.source);
            }
        } else if (l.type == LightType::Directional) {
            float d[3] = {float(l.direction.x), float(l.direction.y), float(l.direction.z)};
            if (ImGui::DragFloat3("toward", d, 0.01f, -1.0f, 1.0f, "%.3f")) {
                const glm::dvec3 v(d[0], d[1], d[2]);
                if (glm::length(v) > 1e-6) l.direction = glm::normalize(v);
            }
        }
        const double peak = std::max({l.rgb.x, l.rgb.y, l.rgb.z});
        float colour[3] = {1.0f, 1.0f, 1.0f};
        if (peak > 0.0)
            for (int c = 0; c < 3; ++c) colour[c] = float(l.rgb[c] / peak);
        float power = float(peak);
        bool changed = ImGui::ColorEdit3("colour", colour, ImGuiColorEditFlags_NoInputs);
        ImGui::SameLine();
        ImGui::SetNextItemWidth(110.0f);
        changed |= ImGui::DragFloat("intensity", &power, std::max(0.01f * power, 1e-6f), 0.0f, 1e9f, "%.4g",
                                    ImGuiSliderFlags_Logarithmic);
        if (changed && std::isfinite(power))
            l.rgb = glm::dvec3(colour[0], colour[1], colour[2]) * double(std::max(power, 0.0f));
        ImGui::SameLine();
        if (ImGui::SmallButton("remove")) remove = i;
        ImGui::PopID();
    }
    if (remove >= 0) state.lights.erase(state.lights.begin() + remove);
    if (ImGui::Button("add point light")) {
        // Above the camera's side of the object, 3 radii out, giving ~100 W/m^2 at the centre.
        const glm::dvec3 c = in.setup.object.sphereCentre;
        const glm::dvec3 dir = glm::normalize(glm::normalize(state.camera.eye - c) + glm::dvec3(state.camera.up));
        const double d = 3.0 * double(radius);
        state.lights.push_back(pointLight(c + d * dir, glm::dvec3(100.0 * d * d / kSquareMmPerSquareMetre), "viewer"));
    }
    if (in.pointLight) {
        const PointLightResult& r = *in.pointLight;
        if (!r.message.empty()) ImGui::TextColored(ImVec4(1.0f, 0.5f, 0.3f, 1.0f), "%s", r.message.c_str());
        const TextureSpaceTimings& t = r.timings;
        ImGui::Text("last update %.1f ms: irradiance %.1f, shadow maps %.1f, draws %.1f, sums %.1f", r.totalMs,
                    1e3 * t.irradianceSeconds, 1e3 * t.shadowMapSeconds, 1e3 * t.samplingSeconds, r.evaluationMs);
        ImGui::Text("%zu updates, mean %.1f ms; %zu distinct samples, R_p %.3g mm", in.pointUpdates.count,
                    in.pointUpdates.mean(), r.uniqueSamples, r.rp);
        if (r.request.specular || r.request.singleScattering)
            ImGui::Text("rays at the vertices: specular %.1f ms, single scattering %.1f ms (0: kept)", r.specularMs,
                        r.singleScatteringMs);
    }
    ImGui::BeginDisabled(comparison.running || state.lights.empty() || !state.pointLights);
    if (ImGui::Button("RMSE vs Jensen-Buhler")) {
        pointWorker->compare(state.camera, {double(state.exposure), ToneMapOperator(state.toneMap)});
        comparison.running = true;
        comparison.text = "rendering the reference ...";
    }
    ImGui::EndDisabled();
    if (!comparison.text.empty()) ImGui::TextWrapped("%s", comparison.text.c_str());
    const std::string atlas = pointWorker->atlasSummary();
    ImGui::TextDisabled("%s", atlas.empty() ? "surface atlas: built with the first light" : atlas.c_str());
}

}  // namespace

std::string materialProblem(const EditableTransport& editable, const Material& material, double sizeMm) {
    try {
        if (!(sizeMm > 0.0) || !std::isfinite(sizeMm))
            throw Error("size", "must be finite and > 0 mm, got " + formatParameter(sizeMm));
        Material m = material;
        m.eta = editable.fileMaterial().eta;
        validateMaterial(m);
        editable.basis().requireCovered(m, sizeMm / editable.objectSizeMm());
    } catch (const Error& e) {
        return e.what();
    }
    return "";
}

bool editMaterial(const EditableTransport& editable, ViewState& state, const Material& material, double sizeMm) {
    const std::string problem = materialProblem(editable, material, sizeMm);
    if (!problem.empty()) {
        state.materialError = problem;
        return false;
    }
    state.material = material;
    state.material.eta = editable.fileMaterial().eta;
    state.sizeMm = sizeMm;
    state.materialError.clear();
    return true;
}

std::pair<double, double> coveredSizesMm(const EditableTransport& editable, const Material& material) {
    // z_r = 1 / (s sigma_t') at size factor s must lie in [zrMin, zrMax] in every channel
    // (requireCovered allows 1e-9 relative; stay inside it).
    const RadialRange& range = editable.basis().range();
    double lo = 0.0, hi = std::numeric_limits<double>::infinity();
    for (int c = 0; c < 3; ++c) {
        const double sigmaT = material.sigmaA[c] + material.sigmaSPrime[c];
        if (!(sigmaT > 0.0)) return {1.0, 0.0};
        lo = std::max(lo, 1.0 / (sigmaT * range.zrMax));
        hi = std::min(hi, 1.0 / (sigmaT * range.zrMin));
    }
    const double s = editable.objectSizeMm();
    return {s * lo * (1.0 + 1e-9), s * hi * (1.0 - 1e-9)};
}

std::string materialArgument(const EditableTransport& editable, const Material& material) {
    if (sameCoefficients(material, editable.fileMaterial())) return "";
    for (const std::string& n : materialNames())
        if (sameCoefficients(material, materialByName(n))) return n;
    char buf[256];
    std::snprintf(buf, sizeof buf, "sigma:%.9g,%.9g,%.9g:%.9g,%.9g,%.9g", material.sigmaA.x, material.sigmaA.y,
                  material.sigmaA.z, material.sigmaSPrime.x, material.sigmaSPrime.y, material.sigmaSPrime.z);
    return buf;
}

void drawLightMarkers(const ViewState& state, bool shown) {
    if (!shown) return;
    const Camera& c = state.camera;
    const glm::dvec3 forward = glm::normalize(c.target - c.eye);
    const glm::dvec3 right = glm::normalize(glm::cross(forward, c.up));
    const glm::dvec3 up = glm::cross(right, forward);
    const double tanHalf = std::tan(glm::radians(c.fovY) * 0.5), aspect = double(c.width) / c.height;
    const ImVec2 size = ImGui::GetIO().DisplaySize;
    ImDrawList* draw = ImGui::GetBackgroundDrawList();
    for (size_t i = 0; i < state.lights.size(); ++i) {
        const Light& l = state.lights[i];
        if (!hasPosition(l)) continue;
        const glm::dvec3 d = l.position - c.eye;
        const double z = glm::dot(d, forward);
        if (!(z > 0.0)) continue;
        const double sx = glm::dot(d, right) / z / (tanHalf * aspect), sy = glm::dot(d, up) / z / tanHalf;
        const ImVec2 p(float((sx + 1.0) * 0.5 * size.x), float((1.0 - sy) * 0.5 * size.y));
        const double peak = std::max({l.rgb.x, l.rgb.y, l.rgb.z, 1e-30});
        const ImU32 colour = ImGui::ColorConvertFloat4ToU32(
            ImVec4(float(l.rgb.x / peak), float(l.rgb.y / peak), float(l.rgb.z / peak), 1.0f));
        draw->AddCircleFilled(p, 6.0f, colour);
        draw->AddCircle(p, 7.0f, IM_COL32(0, 0, 0, 255), 0, 1.5f);
        draw->AddText(ImVec2(p.x + 9.0f, p.y - 7.0f), IM_COL32(255, 255, 255, 255), std::to_string(i + 1).c_str());
    }
}

void drawPanel(const PanelInputs& in, ViewState& state, PointLightWorker* pointWorker,
               PointLightComparison& comparison) {
    ImGui::SetNextWindowPos(ImVec2(8, 8), ImGuiCond_FirstUseEver);
    ImGui::SetNextWindowBgAlpha(0.75f);
    ImGui::Begin("prt-relight view", &state.showPanel, ImGuiWindowFlags_AlwaysAutoResize);
    ImGui::PushItemWidth(170.0f);
    const TriangleMesh& mesh = in.setup.object.mesh;
    const TransportFile& file = in.setup.object.transport;
    ImGui::Text("%s: %zu vertices, %.3g mm", fs::path(in.setup.meshPath).filename().string().c_str(), mesh.vertexCount(),
                double(in.setup.object.box.diagonal()));
    ImGui::TextDisabled("eta %.3g, cubemap 6x%ux%u%s", in.setup.object.eta, file.cubemapSize, file.cubemapSize,
                        in.viewTerms > 0 ? (", K = " + std::to_string(in.viewTerms) + " view terms").c_str() : "");

    ImGui::Separator();
    const char* current = in.environmentNames[size_t(state.environment)].c_str();
    if (ImGui::BeginCombo("environment (N/B)", current)) {
        for (int i = 0; i < int(in.environmentNames.size()); ++i)
            if (ImGui::Selectable(in.environmentNames[size_t(i)].c_str(), i == state.environment)) state.environment = i;
        ImGui::EndCombo();
    }
    float rotation = float(state.rotation);
    if (ImGui::SliderFloat("rotation (deg)", &rotation, -180.0f, 180.0f, "%.1f")) state.rotation = double(rotation);
    ImGui::BeginDisabled(!in.available.multipleScattering);
    ImGui::Checkbox("MS (M)", &state.multipleScattering);
    ImGui::EndDisabled();
    ImGui::SameLine();
    ImGui::BeginDisabled(!in.available.singleScattering);
    ImGui::Checkbox("SS (S)", &state.singleScattering);
    ImGui::EndDisabled();
    ImGui::SameLine();
    ImGui::Checkbox("specular (G)", &state.specular);
    ImGui::SliderFloat("exposure (+/-)", &state.exposure, -10.0f, 10.0f, "%.2f stops");
    {
        static const char* const kToneMaps[] = {"clamp", "reinhard", "filmic", "chang"};
        ImGui::Combo("tone mapping (T)", &state.toneMap, kToneMaps, int(std::size(kToneMaps)));
    }
    const int maxTerms = 6 * int(file.cubemapSize * file.cubemapSize);
    ImGui::SliderInt("light terms ([/])", &state.lightTerms, 0, maxTerms, state.lightTerms == 0 ? "all" : "%d",
                     ImGuiSliderFlags_Logarithmic);
    if (in.light)
        ImGui::Text("light: %zu of %zu terms, L2 error %.3g", in.light->keptTerms, in.light->coefficients,
                    in.light->relativeL2Error);

    ImGui::Separator();
    ImGui::Text("%.1f fps (%.1f ms), %d x %d", in.fps, in.frameMs, state.camera.width, state.camera.height);
    if (in.light)
        ImGui::Text("relight %.0f ms = light %.0f + kernel %.1f + upload %.1f",
                    in.light->lightMs + in.light->relightMs + in.uploadMs, in.light->lightMs, in.light->relightMs,
                    in.uploadMs);
    if (!in.sunSplit.empty()) ImGui::TextWrapped("%s", in.sunSplit.c_str());
    if (in.light && in.light->editPath == LightResult::EditPath::None && in.light->recombineMs > 0.0)
        ImGui::TextDisabled("(kernel includes recombining the edited material: %.0f ms)", in.light->recombineMs);
    ImGui::Text("%zu relights (%.0f per second completed), mean %.0f ms%s", in.relights.count,
                in.relightRate, in.relights.mean(), in.relighting ? ", relighting..." : "");
    ImGui::TextDisabled("%zu vertices, %zu triangles, %s", mesh.vertexCount(), mesh.triangleCount(),
                        in.renderer.substr(0, in.renderer.find(' ')).c_str());

    drawMaterialPanel(in, state);
    drawPointLightPanel(in, state, pointWorker, comparison);
    if (ImGui::CollapsingHeader("camera")) {
        ImGui::Text("eye (%.4g, %.4g, %.4g) mm", state.camera.eye.x, state.camera.eye.y, state.camera.eye.z);
        ImGui::Text("target (%.4g, %.4g, %.4g), fov %.3g", state.camera.target.x, state.camera.target.y, state.camera.target.z,
                    state.camera.fovY);
        if (ImGui::Button("print render command")) {
            std::printf("%s\n", in.renderCommand().c_str());
            std::fflush(stdout);
        }
    }
    if (ImGui::CollapsingHeader("controls")) {
        ImGui::TextUnformatted(
            "left drag: orbit, right/middle drag: pan,\n"
            "wheel: zoom, R: reset camera\n"
            "shift/ctrl + left drag, arrows: rotate light\n"
            "N, B (PgDn, PgUp): next, previous environment\n"
            "M, S, G: multiple, single scattering, specular\n"
            "E, L: environment light, point lights\n"
            "+, -, 0: exposure; T: tone mapping; [, ]: light terms\n"
            "F12 or P: screenshot, H: panel, Esc: quit");
    }
    if (ImGui::Button("reset camera (R)")) resetCamera(state, in.limits);
    ImGui::SameLine();
    if (ImGui::Button("screenshot (F12)")) state.screenshotRequested = true;
    if (!in.status.empty()) ImGui::TextWrapped("%s", in.status.c_str());
    ImGui::PopItemWidth();
    ImGui::End();
}

}  // namespace prt
