// prt-pointlight's frames and animations: see point_animation.h for what is reused
// between frames and why it is valid.

#include "relight/pointlight/point_animation.h"

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <utility>

#include "common/error.h"
#include "common/material_edit.h"
#include "common/util.h"
#include "relight/pointlight/vertex_surface_terms.h"

namespace prt {

const char* toString(PointMethod method) {
    switch (method) {
        case PointMethod::Cache: return "cache";
        case PointMethod::JensenBuhler: return "jb";
        case PointMethod::Brute: return "brute";
        case PointMethod::TextureSpace: return "tsis";
    }
    return "?";
}

PointMethod parsePointMethod(const std::string& text) {
    const std::string m = toLower(text);
    if (m == "cache") return PointMethod::Cache;
    if (m == "jb") return PointMethod::JensenBuhler;
    if (m == "brute") return PointMethod::Brute;
    if (m == "tsis") return PointMethod::TextureSpace;
    throw Error("--method", "must be cache, jb, brute or tsis, got '" + text + "'");
}

LitSamples lightSamples(const IrradianceSamples& placed, const RayScene& scene, const std::vector<Light>& lights,
                        const PointRenderSettings& settings) {
    LitSamples lit;
    lit.samples = placed;
    Stopwatch t;
    computeIrradiance(lit.samples, scene, lights, settings.material.eta, settings.fresnel);
    lit.irradianceSeconds = t.seconds();
    t.restart();
    lit.tree.emplace(lit.samples, OctreeOptions{.leafSize = settings.leafSize});
    lit.octreeSeconds = t.seconds();
    return lit;
}

std::optional<SampleCells> nearFieldCells(const TriangleMesh& mesh, const IrradianceSamples& placed,
                                          const PointRenderSettings& settings) {
    if (settings.nearField == NearFieldRule::Points) return std::nullopt;
    if (settings.nearField == NearFieldRule::Auto &&
        !nearFieldNeedsCells(placed.totalArea(), placed.size(), settings.material))
        return std::nullopt;
    return SampleCells(mesh, placed, settings.material);
}

PointFrameRenderer::PointFrameRenderer(IrradianceOctree tree, const PointRenderSettings& s,
                                       std::optional<SampleCells> cells)
    : settings_(s) {
    if (s.method == PointMethod::TextureSpace)
        throw Error("--method", "tsis renders through TextureSpaceRenderer (it needs a surface atlas)");
    if (s.method == PointMethod::Cache)
        cache_.emplace(s.material, std::move(tree),
                       IrradianceCacheOptions{.a = s.a, .radius = s.radius, .epsilon = s.epsilon, .fresnel = s.fresnel,
                                              .splitDisk = s.splitDisk},
                       std::move(cells));
    else
        jb_.emplace(s.material, std::move(tree),
                    JensenBuhlerOptions{.epsilon = s.method == PointMethod::Brute ? 0.0 : s.epsilon,
                                        .fresnel = s.fresnel},
                    std::move(cells));
}

void PointFrameRenderer::setMaterial(const Material& material) {
    if (cache_) cache_->setMaterial(material);
    else jb_->setMaterial(material);
    settings_.material = material;
}

PointFrame PointFrameRenderer::render(const GBuffer& g, bool wantVisuals) {
    PointFrame f;
    const Stopwatch t;
    if (cache_) {
        f.image = cache_->render(g, &f.cacheStats, wantVisuals ? &f.visuals : nullptr);
        f.renderSeconds = t.seconds();
        f.caches = cache_->caches();
    } else {
        f.image = jb_->render(g, &f.jbStats);
        f.renderSeconds = t.seconds();
    }
    if (settings_.baseColour) applyBaseColour(f.image, g, *settings_.baseColour);
    return f;
}

PointFrame renderPointFrame(const IrradianceOctree& tree, const GBuffer& g, const PointRenderSettings& s,
                            bool wantVisuals, const std::optional<SampleCells>& cells) {
    if (s.method == PointMethod::TextureSpace)
        throw Error("--method", "tsis renders single frames only (its animations run in prt-relight view)");
    return PointFrameRenderer(tree, s, cells).render(g, wantVisuals);
}

// ---------------------------------------------------------------------------
// The surface terms
// ---------------------------------------------------------------------------

SurfaceTerms renderSurfaceTerms(const GBuffer& g, const TriangleMesh& mesh, const RayScene& scene,
                                const std::vector<Light>& lights, const Material& material,
                                const SurfaceTermSettings& settings, const BaseColour* colour) {
    SurfaceTerms terms;
    if (!settings.any()) return terms;
    terms.radiance = Image(g.width, g.height, 3, 0.0f);
    if (settings.singleScattering) {
        const Stopwatch t;
        terms.radiance =
            settings.perVertex
                ? vertexSingleScatteringImage(g, mesh,
                                              vertexSingleScattering(scene, mesh, lights, material, settings.eye,
                                                                     settings.singleScatteringOptions),
                                              material.eta)
                : singleScatteringImage(g, mesh, scene, lights, material, settings.singleScatteringOptions);
        if (colour) applyBaseColour(terms.radiance, g, *colour);
        terms.singleScatteringSeconds = t.seconds();
    }
    if (settings.specular) {
        const Stopwatch t;
        const Image specular =
            settings.perVertex
                ? vertexSpecularImage(g, mesh, lights, vertexLightIrradiance(scene, mesh, lights), material.eta,
                                      settings.specularRoughness)
                : specularImage(g, mesh, scene, lights, material.eta, settings.specularRoughness);
        for (size_t i = 0; i < specular.pixels.size(); ++i) terms.radiance.pixels[i] += specular.pixels[i];
        terms.specularSeconds = t.seconds();
    }
    return terms;
}

void addSurfaceTerms(Image& frame, const SurfaceTerms& terms) {
    if (terms.radiance.empty()) return;
    if (frame.width != terms.radiance.width || frame.height != terms.radiance.height || frame.channels < 3)
        throw Error("surface terms", "the frame and the terms differ in size");
    const size_t n = size_t(frame.width) * size_t(frame.height);
    const size_t channels = size_t(frame.channels);
    for (size_t i = 0; i < n; ++i)
        for (size_t c = 0; c < 3; ++c) frame.pixels[i * channels + c] += terms.radiance.pixels[3 * i + c];
}

// ---------------------------------------------------------------------------
// Animation
// ---------------------------------------------------------------------------

namespace {

// t = k / (N - 1) of the light and material paths (0 for a single frame).
double pathT(const PointAnimation& a, int frame) {
    return a.frames > 1 ? double(frame) / double(a.frames - 1) : 0.0;
}

glm::dvec3 parsePoint(const std::string& text, const std::string& full) {
    glm::dvec3 p(0.0);
    const char* s = text.c_str();
    for (int i = 0; i < 3; ++i) {
        char* end = nullptr;
        errno = 0;
        p[i] = std::strtod(s, &end);
        if (end == s || errno == ERANGE || !std::isfinite(p[i]))
            throw Error("--light-path", "expected X0,Y0,Z0:X1,Y1,Z1 (finite numbers, mm), got '" + full + "'");
        s = end;
        if (i < 2) {
            if (*s != ',')
                throw Error("--light-path", "expected X0,Y0,Z0:X1,Y1,Z1 (three numbers per point), got '" + full + "'");
            ++s;
        }
    }
    if (*s != '\0')
        throw Error("--light-path", "expected X0,Y0,Z0:X1,Y1,Z1 (three numbers per point), got '" + full + "'");
    return p;
}

}  // namespace

void parseLightPath(const std::string& text, glm::dvec3& from, glm::dvec3& to) {
    const size_t colon = text.find(':');
    if (colon == std::string::npos || text.find(':', colon + 1) != std::string::npos)
        throw Error("--light-path", "expected X0,Y0,Z0:X1,Y1,Z1 (two points separated by ':'), got '" + text + "'");
    from = parsePoint(text.substr(0, colon), text);
    to = parsePoint(text.substr(colon + 1), text);
}

void parseSizePath(const std::string& text, double& s0, double& s1) {
    const std::vector<std::string> parts = splitText(text, ':');
    if (parts.size() != 2)
        throw Error("--size-path", "expected S0:S1 (two sizes in mm separated by ':'), got '" + text + "'");
    double s[2];
    for (int i = 0; i < 2; ++i) {
        const std::vector<double> v = parseNumberList(parts[size_t(i)], "--size-path", "size S0:S1");
        if (v.size() != 1)
            throw Error("--size-path", "expected S0:S1 (one number per size, mm), got '" + text + "'");
        if (!std::isfinite(v[0]) || !(v[0] > 0.0))
            throw Error("--size-path", "sizes must be finite and > 0 mm, got '" + text + "'");
        s[i] = v[0];
    }
    s0 = s[0];
    s1 = s[1];
}

void validateAnimation(const PointAnimation& a, const std::vector<Light>& lights) {
    if (a.kind == AnimationKind::None) return;
    const char* option = a.kind == AnimationKind::Turntable ? "--turntable" : "--frames";
    if (a.kind == AnimationKind::MaterialPath) {
        if (a.frames < 2)
            throw Error("--frames", "a material or size path needs N >= 2 frames (t = k / (N - 1)), got " +
                                        std::to_string(a.frames));
        if (!a.materials && !a.sizesMm)
            throw Error("--material-path", "a material animation needs --material-path A:B and/or --size-path S0:S1");
        if (a.materials) {
            validateMaterial(a.materials->first);
            validateMaterial(a.materials->second);
            if (a.materials->first.eta != a.materials->second.eta)
                throw Error("--material-path", "both ends need the same eta (the irradiance is computed once)");
        }
        if (a.sizesMm) {
            for (const double s : {a.sizesMm->first, a.sizesMm->second})
                if (!std::isfinite(s) || !(s > 0.0)) throw Error("--size-path", "sizes must be finite and > 0 mm");
            if (!std::isfinite(a.geometrySizeMm) || !(a.geometrySizeMm > 0.0))
                throw Error("--size-path", "the mesh's own size must be finite and > 0 mm");
        }
        return;
    }
    if (a.frames < 1) throw Error(option, "the frame count must be at least 1, got " + std::to_string(a.frames));
    if (a.kind == AnimationKind::LightPath) {
        for (int i = 0; i < 3; ++i)
            if (!std::isfinite(a.from[i]) || !std::isfinite(a.to[i]))
                throw Error("--light-path", "the end points must be finite");
        if (lights.empty() || !hasPosition(lights.front()))
            throw Error("--light-path", "moves the first light, which must be a point or spot light");
    }
}

double turntableDegrees(const PointAnimation& a, int frame) {
    return a.kind == AnimationKind::Turntable && a.frames > 0 ? 360.0 * frame / a.frames : 0.0;
}

Camera animationCamera(const PointAnimation& a, const Camera& base, const glm::dvec3& pivot, int frame) {
    if (a.kind != AnimationKind::Turntable) return base;
    return turntableCamera(base, pivot, turntableDegrees(a, frame));
}

std::vector<Light> animationLights(const PointAnimation& a, const std::vector<Light>& lights, int frame) {
    if (a.kind != AnimationKind::LightPath || lights.empty()) return lights;
    std::vector<Light> out = lights;
    const double t = pathT(a, frame);
    // (1 - t) P0 + t P1: exactly P0 at t = 0 and exactly P1 at t = 1. A spot keeps
    // its axis and cone (it is translated, not re-aimed).
    out.front().position = (1.0 - t) * a.from + t * a.to;
    out.front().source = "--light-path (frame " + std::to_string(frame) + ", light 1)";
    return out;
}

Material animationMaterial(const PointAnimation& a, const Material& base, int frame) {
    if (a.kind != AnimationKind::MaterialPath) return base;
    const double t = pathT(a, frame);
    // (1 - t) A + t B: exactly A at t = 0 and exactly B at t = 1.
    Material m = base;
    if (a.materials) {
        m = lerpMaterial(a.materials->first, a.materials->second, t);
        // (1 - t) eta + t eta is not eta in floating point for every t: the ends share
        // eta (validateAnimation), and the irradiance was computed with exactly it.
        m.eta = a.materials->first.eta;
    }
    if (a.sizesMm) m = scaledMaterial(m, animationSizeMm(a, frame) / a.geometrySizeMm);
    return m;
}

double animationSizeMm(const PointAnimation& a, int frame) {
    if (a.kind != AnimationKind::MaterialPath || !a.sizesMm) return a.geometrySizeMm;
    const double t = pathT(a, frame);
    return (1.0 - t) * a.sizesMm->first + t * a.sizesMm->second;
}

std::string animationFrameName(const std::string& prefix, int frame) {
    char buf[16];
    std::snprintf(buf, sizeof buf, "_%04d", frame);
    return prefix + buf;
}

void renderAnimation(const PointAnimation& a, const TriangleMesh& mesh, const RayScene& scene,
                     const IrradianceSamples& placed, const std::vector<Light>& lights, const Camera& baseCamera,
                     const glm::dvec3& pivot, const PointRenderSettings& settings, const AnimationSink& sink) {
    validateAnimation(a, lights);
    const int count = a.kind == AnimationKind::None ? 1 : a.frames;
    // A light path may pass through the object: refuse before rendering anything.
    for (int k = 0; k < count; ++k) checkLightsOutside(scene, animationLights(a, lights, k));
    const Stopwatch cellsTime;
    PointRenderSettings first = settings;
    if (a.kind == AnimationKind::MaterialPath) first.material = animationMaterial(a, settings.material, 0);
    const std::optional<SampleCells> cells = nearFieldCells(mesh, placed, first);
    const double cellsSeconds = cells ? cellsTime.seconds() : 0.0;

    if (a.kind == AnimationKind::MaterialPath) {
        // Pass 1 and the G-buffer once, one renderer whose material changes per frame.
        LitSamples lit = lightSamples(placed, scene, lights, first);
        const Stopwatch t;
        const GBuffer g = traceGBuffer(scene, mesh, baseCamera);
        const double gbufferSeconds = t.seconds();
        PointFrameRenderer renderer(std::move(*lit.tree), first, cells);
        for (int k = 0; k < count; ++k) {
            AnimationFrameInfo info;
            info.frame = k;
            info.camera = baseCamera;
            info.lights = lights;
            info.material = animationMaterial(a, settings.material, k);
            info.sizeMm = animationSizeMm(a, k);
            if (k == 0) {
                info.cellsSeconds = cellsSeconds;
                info.irradianceSeconds = lit.irradianceSeconds;
                info.octreeSeconds = lit.octreeSeconds;
                info.gbufferSeconds = gbufferSeconds;
            }
            const Stopwatch m;
            renderer.setMaterial(info.material);
            info.materialSeconds = m.seconds();
            info.hitPixels = g.objectPixels();
            PointFrame frame = renderer.render(g);
            const SurfaceTerms terms =
                renderSurfaceTerms(g, mesh, scene, info.lights, info.material, settings.surface, settings.baseColour);
            addSurfaceTerms(frame.image, terms);
            info.surfaceSeconds = terms.seconds();
            sink(info, frame);
        }
        return;
    }

    // Turntable: pass 1 once (lights fixed in the object's frame). Light path: the
    // camera is fixed, so one G-buffer.
    std::optional<LitSamples> shared;
    std::optional<GBuffer> sharedG;
    for (int k = 0; k < count; ++k) {
        AnimationFrameInfo info;
        info.frame = k;
        info.camera = animationCamera(a, baseCamera, pivot, k);
        info.lights = animationLights(a, lights, k);
        if (k == 0) info.cellsSeconds = cellsSeconds;

        std::optional<LitSamples> own;
        const LitSamples* lit = nullptr;
        if (a.kind == AnimationKind::LightPath || !shared) {
            LitSamples l = lightSamples(placed, scene, info.lights, settings);
            info.irradianceSeconds = l.irradianceSeconds;
            info.octreeSeconds = l.octreeSeconds;
            if (a.kind == AnimationKind::LightPath) {
                own = std::move(l);
                lit = &*own;
            } else {
                shared = std::move(l);
                lit = &*shared;
            }
        } else {
            lit = &*shared;
        }

        const GBuffer* g = nullptr;
        GBuffer frameG;
        if (a.kind == AnimationKind::LightPath && sharedG) {
            g = &*sharedG;
        } else {
            const Stopwatch t;
            frameG = traceGBuffer(scene, mesh, info.camera);
            info.gbufferSeconds = t.seconds();
            if (a.kind == AnimationKind::LightPath) {
                sharedG = std::move(frameG);
                g = &*sharedG;
            } else {
                g = &frameG;
            }
        }
        info.hitPixels = g->objectPixels();

        PointFrame frame = renderPointFrame(*lit->tree, *g, settings, false, cells);
        const SurfaceTerms terms =
            renderSurfaceTerms(*g, mesh, scene, info.lights, settings.material, settings.surface, settings.baseColour);
        addSurfaceTerms(frame.image, terms);
        info.surfaceSeconds = terms.seconds();
        sink(info, frame);
    }
}

void renderTextureSpaceAnimation(const PointAnimation& a, TextureSpaceRenderer& renderer, const GBuffer& g,
                                 bool perVertex, const Material& base, const AnimationSink& sink) {
    if (a.kind != AnimationKind::MaterialPath)
        throw Error("--method", "tsis animates the material and size only (--material-path / --size-path); move "
                                "its lights interactively in prt-relight view");
    validateAnimation(a, {});
    // The view's pixel list, the same for every frame (one G-buffer, one eta).
    const VertexInterpolation view = perVertex ? renderer.interpolation(g) : VertexInterpolation{};
    for (int k = 0; k < a.frames; ++k) {
        AnimationFrameInfo info;
        info.frame = k;
        info.material = animationMaterial(a, base, k);
        info.sizeMm = animationSizeMm(a, k);
        const Stopwatch m;
        renderer.setMaterial(info.material);
        info.materialSeconds = m.seconds();
        info.hitPixels = g.objectPixels();
        PointFrame frame;
        const Stopwatch t;
        frame.image = perVertex ? renderer.shadeVertices(view, renderer.vertexExitance()) : renderer.render(g);
        frame.renderSeconds = t.seconds();
        sink(info, frame);
    }
}

}  // namespace prt
