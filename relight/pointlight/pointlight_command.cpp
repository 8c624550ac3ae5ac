#include "relight/pointlight/pointlight_command.h"


#include <CLI/CLI.hpp>

#include <algorithm>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "common/bssrdf.h"
#include "common/options.h"
#include "common/image_compare.h"
#include "common/error.h"
#include "common/image.h"
#include "common/material_edit.h"
#include "common/mesh.h"
#include "common/mesh_io.h"
#include "common/progress.h"
#include "common/raytrace.h"
#include "relight/render/gbuffer.h"
#include "relight/render/supersample.h"
#include "common/sampling.h"
#include "common/transport_params.h"
#include "common/util.h"
#include "relight/pointlight/irradiance_cache.h"
#include "relight/pointlight/jensen_buhler.h"
#include "relight/pointlight/point_lights.h"
#include "relight/pointlight/point_animation.h"
#include "relight/pointlight/surface_atlas.h"
#include "relight/pointlight/texture_space_sampling.h"

namespace prt {

namespace {

// Writes an animation frame as <base>.exr and <base>.png, remembers the first and the
// last frame written (for the summary) and returns the seconds the writing took.
double writeAnimationFrame(ImageWriter& writer, const std::string& base, const Image& image,
                           const DisplayTransform& display, std::string& first, std::string& last) {
    const Stopwatch t;
    writer.exr(base + ".exr", image);
    writer.png(base + ".png", image, &display);
    if (first.empty()) first = base;
    last = base;
    return t.seconds();
}

// <output>_error.png: the relative error of `image` against `reference` as a heat map
// scaled to its 99th percentile (rounded up); returns that scale.
double writeErrorHeatmap(ImageWriter& writer, const std::string& output, const Image& image, const Image& reference,
                         const CompareResult& result) {
    const Image error = relativeErrorImage(image, reference, result);
    const double scale = heatmapScale(error);
    writer.png(output + "_error.png", heatmapImage(error, scale));
    return scale;
}

// Keng Figs. 8-9: the cache positions (red dots over the frame), the interpolated
// gradient of S (world |x|, |y|, |z| of the channel-mean gradient as R, G, B; brightness
// = magnitude / its 99th percentile) and the split-disk spread V (gray, / its 99th
// percentile).
void writeCacheImages(ImageWriter& writer, const std::string& output, const Image& frame, const GBuffer& g,
                      const std::vector<CacheRecord>& caches, const CacheVisuals& visuals, const DisplayTransform& display) {
    const DisplayMapping mapping = displayMapping(frame, display);
    Image dots(g.width, g.height, 3, 0.0f);
    for (int y = 0; y < g.height; ++y)
        for (int x = 0; x < g.width; ++x) {
            const glm::vec3 shown = mapping.apply({frame.at(x, y, 0), frame.at(x, y, 1), frame.at(x, y, 2)});
            for (int c = 0; c < 3; ++c) dots.at(x, y, c) = 0.6f * shown[c];
        }
    for (const CacheRecord& r : caches) {
        const int cx = int(r.pixel % uint32_t(g.width)), cy = int(r.pixel / uint32_t(g.width));
        for (int dy = -1; dy <= 1; ++dy)
            for (int dx = -1; dx <= 1; ++dx) {
                const int x = cx + dx, y = cy + dy;
                if (x < 0 || y < 0 || x >= g.width || y >= g.height || std::abs(dx) + std::abs(dy) > 1) continue;
                dots.at(x, y, 0) = 1.0f;
                dots.at(x, y, 1) = 0.0f;
                dots.at(x, y, 2) = 0.0f;
            }
    }
    writer.png(output + "_caches.png", dots);
    auto percentile99 = [](std::vector<float> v) {
        v.erase(std::remove_if(v.begin(), v.end(), [](float x) { return !(x > 0.0f); }), v.end());
        if (v.empty()) return 1.0f;
        std::nth_element(v.begin(), v.begin() + ptrdiff_t(0.99 * double(v.size() - 1)), v.end());
        return v[size_t(0.99 * double(v.size() - 1))];
    };
    std::vector<float> magnitude(visuals.gradient.size());
    for (size_t i = 0; i < magnitude.size(); ++i) magnitude[i] = glm::length(visuals.gradient[i]);
    const float gScale = percentile99(magnitude), vScale = percentile99(visuals.spread);
    Image grad(g.width, g.height, 3, 0.0f), spread(g.width, g.height, 1, 0.0f);
    for (size_t i = 0; i < magnitude.size(); ++i) {
        const glm::vec3 v = glm::abs(visuals.gradient[i]) / gScale;
        grad.pixels[3 * i] = v.x;
        grad.pixels[3 * i + 1] = v.y;
        grad.pixels[3 * i + 2] = v.z;
        spread.pixels[i] = visuals.spread[i] / vScale;
    }
    writer.png(output + "_gradient.png", grad);
    writer.png(output + "_variance.png", spread);
}

// One line on the surface terms of a single frame (nothing when both are off).
void printSurfaceTerms(const SurfaceTermSettings& s, const SurfaceTerms& terms) {
    const char* where = s.perVertex ? "rays at the vertices, interpolated" : "rays per pixel";
    if (s.specular)
        std::printf("specular: GGX alpha %g, Fresnel F_r at the material's eta, shadowed (%s), untinted; %.3f s\n",
                    s.specularRoughness, where, terms.specularSeconds);
    if (s.singleScattering)
        std::printf("single scattering: along the refracted view ray (%s), %d Gauss-Legendre samples, HG phase; "
                    "%.3f s\n",
                    where, s.singleScatteringOptions.pathSamples, terms.singleScatteringSeconds);
}

// One line on the near field's cells (sample_cells.h), or on the point rule.
void printCells(const std::optional<SampleCells>& cells) {
    if (!cells) {
        std::printf("near field: point rule (A_i R_d(|x - x_i|) at every sample)\n");
        return;
    }
    const CellQuadrature& q = cells->quadrature();
    std::printf("near field: R_d integrated over each sample's %s within %.4g mm (%zu sub-points at %.4g mm, split "
                "%.4g..%.4g mm); built in %.3f s\n",
                cells->faceCells() ? "face" : "nearest-surface cell", cells->nearRadius(), q.subPointCount(),
                q.subSpacing(), q.innerRadius(), q.outerRadius(), cells->buildSeconds());
}

// --turntable N / --light-path P0:P1 --frames N / --material-path A:B and/or --size-path
// S0:S1 with --frames N: renderAnimation (point_animation.h, which states what is reused
// between frames and why it is valid), one summary line per frame, then the mean time
// per frame of every pass.
int runAnimation(const PointLightCommand& o, ImageWriter& writer, const PointAnimation& animation, const TriangleMesh& mesh, const RayScene& scene,
                 const IrradianceSamples& placed, const std::vector<Light>& lights, const Camera& camera,
                 const glm::dvec3& pivot, const PointRenderSettings& settings, const std::string& output,
                 const Stopwatch& start) {
    const bool turntable = animation.kind == AnimationKind::Turntable;
    const bool materialPath = animation.kind == AnimationKind::MaterialPath;
    const int count = animation.frames;
    const char* what = turntable ? "turntable (camera orbit about +Y through the box centre, lights fixed in the object)"
                       : materialPath
                           ? "material / size path (Chang et al. Fig. 11: coefficients and size interpolated "
                             "linearly; lights, camera and irradiance attached to the object)"
                           : "light path (the first light moves linearly from P0 to P1)";
    const char* reused =
        turntable ? "the irradiance samples (with their irradiance) and the octree; NOT the G-buffer or the caches "
                    "(they live on each frame's visible points)"
        : materialPath ? "the irradiance samples (with their irradiance), the octree, the G-buffer and the renderer "
                         "(setMaterial); NOT the caches (they depend on the material)"
                       : "the mesh, its ray scene, the sample positions/areas and the G-buffer (fixed camera); NOT the "
                         "irradiance, the octree or the caches (they all depend on the light)";
    std::printf("animation: %s, %d frames; reused between frames: %s\n", what, count, reused);
    std::fflush(stdout);
    double sumIrr = 0, sumTree = 0, sumG = 0, sumPass2 = 0, sumPass3 = 0, sumRender = 0, sumWrite = 0, sumMat = 0;
    size_t sumCaches = 0, sumHit = 0;
    std::string first, last;
    const Stopwatch runStart;
    renderAnimation(animation, mesh, scene, placed, lights, camera, pivot, settings,
                    [&](const AnimationFrameInfo& info, PointFrame& frame) {
        const std::string base = animationFrameName(output, info.frame);
        const double tWrite = writeAnimationFrame(writer, base, frame.image, o.display, first, last);
        sumIrr += info.irradianceSeconds;
        sumTree += info.octreeSeconds;
        sumG += info.gbufferSeconds;
        sumRender += frame.renderSeconds;
        sumWrite += tWrite;
        sumHit += info.hitPixels;
        sumMat += info.materialSeconds;
        if (info.frame == 0 && info.cellsSeconds > 0.0)
            std::printf("near field: cells built in %.3f s (once for every frame)\n", info.cellsSeconds);
        std::printf("frame %d/%d", info.frame + 1, count);
        if (turntable) std::printf(" (object %.1f deg)", turntableDegrees(animation, info.frame));
        else if (materialPath)
            std::printf(" (%s; size %.4g mm)", describeMaterial(info.material).c_str(), info.sizeMm);
        else {
            const glm::dvec3 p = info.lights.front().position;
            std::printf(" (light 1 at %.4g, %.4g, %.4g mm)", p.x, p.y, p.z);
        }
        std::printf(": ");
        if (!turntable && !materialPath) {
            std::printf("irradiance %.3f s, octree %.3f s, ", info.irradianceSeconds, info.octreeSeconds);
            if (info.frame > 0) std::printf("G-buffer reused, ");
            else std::printf("G-buffer %.3f s, ", info.gbufferSeconds);
        } else if (info.frame > 0) {
            std::printf(materialPath ? "irradiance + octree + G-buffer reused, " : "irradiance + octree reused, ");
        } else {
            std::printf("irradiance %.3f s, octree %.3f s, ", info.irradianceSeconds, info.octreeSeconds);
        }
        if (turntable) std::printf("G-buffer %.3f s, ", info.gbufferSeconds);
        if (materialPath) {
            if (info.frame == 0) std::printf("G-buffer %.3f s, ", info.gbufferSeconds);
            std::printf("material change %.3f ms, ", 1e3 * info.materialSeconds);
        }
        if (settings.method == PointMethod::Cache) {
            const IrradianceCacheStats& cs = frame.cacheStats;
            sumPass2 += cs.pass2Seconds;
            sumPass3 += cs.pass3Seconds;
            sumCaches += cs.caches;
            std::printf("pass 2 %.3f s, pass 3 %.3f s (T_cache %.3f s; %zu caches / %zu hit pixels = %.2f%%)",
                        cs.pass2Seconds, cs.pass3Seconds, frame.renderSeconds, cs.caches, cs.hitPixels,
                        100.0 * cs.ratio());
        } else {
            std::printf("%s %.3f s (%zu hit pixels, %.1f terms per pixel)", toString(settings.method),
                        frame.renderSeconds, info.hitPixels, frame.jbStats.meanTerms());
        }
        if (settings.surface.any()) std::printf(", surface terms %.3f s", info.surfaceSeconds);
        std::printf(", write %.3f s -> %s.exr/.png\n", tWrite, base.c_str());
        std::fflush(stdout);
    });
    const double n = double(count);
    std::printf("done: %d frame%s in %s; mean per frame: irradiance %.3f s, octree %.3f s, G-buffer %.3f s, ", count,
                count == 1 ? "" : "s", formatDuration(runStart.seconds()).c_str(), sumIrr / n, sumTree / n, sumG / n);
    if (materialPath) std::printf("material change %.3f ms, ", 1e3 * sumMat / n);
    if (settings.method == PointMethod::Cache)
        std::printf("pass 2 %.3f s, pass 3 %.3f s (T_cache %.3f s), %.0f caches / %.0f hit pixels, ", sumPass2 / n,
                    sumPass3 / n, sumRender / n, double(sumCaches) / n, double(sumHit) / n);
    else
        std::printf("%s %.3f s, ", toString(settings.method), sumRender / n);
    std::printf("write %.3f s (%s)\n", sumWrite / n,
                turntable      ? "irradiance and octree computed once, shown amortised"
                : materialPath ? "irradiance, octree and G-buffer computed once, shown amortised"
                               : "G-buffer traced once, shown amortised");
    std::printf("wrote %s.exr/.png ... %s.exr/.png in %s\n", first.c_str(), last.c_str(),
                formatDuration(start.seconds()).c_str());
    return 0;
}

// --method tsis with --material-path / --size-path: the renderer lit once (irradiance
// map, draws, shadow maps) and one G-buffer; per frame setMaterial (the R_d tables, R_p,
// the local filter) and the sums (renderTextureSpaceAnimation, point_animation.h).
int runTextureSpaceAnimation(const PointLightCommand& o, ImageWriter& writer, const PointAnimation& animation, TextureSpaceRenderer& renderer,
                             const GBuffer& g, bool perVertex, const Material& base, const BaseColour* colour,
                             const TriangleMesh& mesh, const RayScene& scene, const std::vector<Light>& lights,
                             const SurfaceTermSettings& surface, double tGBuffer, const std::string& output,
                             const Stopwatch& start) {
    const TextureSpaceTimings& tt = renderer.timings();
    std::printf("animation: material / size path (Chang et al. Fig. 11: coefficients and size interpolated linearly; "
                "lights, camera and irradiance attached to the object), %d frames; reused between frames: the atlas, "
                "the irradiance map, the draws, the shadow maps (irradiance map %.4f s, shadow maps %.4f s, draws "
                "%.4f s) and the G-buffer (%.4f s); rebuilt per frame: R_p, the R_d tables and the local filter\n",
                animation.frames, tt.irradianceSeconds, tt.shadowMapSeconds, tt.samplingSeconds, tGBuffer);
    std::fflush(stdout);
    double sumMat = 0.0, sumEval = 0.0, sumWrite = 0.0;
    std::string first, last;
    const Stopwatch runStart;
    renderTextureSpaceAnimation(animation, renderer, g, perVertex, base,
                                [&](const AnimationFrameInfo& info, PointFrame& frame) {
        const std::string name = animationFrameName(output, info.frame);
        if (colour) applyBaseColour(frame.image, g, *colour);
        // The frame's material: single scattering changes with it, the specular does not.
        const SurfaceTerms terms = renderSurfaceTerms(g, mesh, scene, lights, info.material, surface, colour);
        addSurfaceTerms(frame.image, terms);
        const double tWrite = writeAnimationFrame(writer, name, frame.image, o.display, first, last);
        sumMat += info.materialSeconds;
        sumEval += frame.renderSeconds;
        sumWrite += tWrite;
        std::printf("frame %d/%d (%s; size %.4g mm): R_p %.4g mm, material change %.3f ms, evaluation %.4f s, "
                    "surface terms %.3f s, write %.3f s -> %s.exr/.png\n",
                    info.frame + 1, animation.frames, describeMaterial(info.material).c_str(), info.sizeMm,
                    renderer.split().rp, 1e3 * info.materialSeconds, frame.renderSeconds, terms.seconds(), tWrite,
                    name.c_str());
        std::fflush(stdout);
    });
    const double n = double(animation.frames);
    std::printf("done: %d frames in %s; mean per frame: material change %.3f ms, evaluation %.4f s, write %.3f s\n",
                animation.frames, formatDuration(runStart.seconds()).c_str(), 1e3 * sumMat / n, sumEval / n,
                sumWrite / n);
    std::printf("wrote %s.exr/.png ... %s.exr/.png in %s\n", first.c_str(), last.c_str(),
                formatDuration(start.seconds()).c_str());
    return 0;
}

// --method tsis: texture-space importance sampling (Chang et al. 2008). Everything a
// new light position needs (irradiance map, draws, shadow maps) and the evaluation are
// timed apart; the atlas is built once per mesh.
// The --method tsis options, checked (before the mesh is read: errors come first).
TextureSpaceOptions textureSpaceOptions(const PointLightCommand& o, FresnelModel fresnel) {
    TextureSpaceOptions to = o.tsis;
    to.mode = parseTextureSpaceMode(o.split);
    to.fresnel = fresnel;
    const std::string evaluate = toLower(o.evaluate);
    if (evaluate != "pixel" && evaluate != "vertex")
        throw Error("--evaluate", "expected pixel or vertex, got '" + o.evaluate + "'");
    validateTextureSpaceOptions(to);
    validateAtlasResolution(o.atlasSize);
    return to;
}

int runTextureSpace(const PointLightCommand& o, ImageWriter& writer, const TriangleMesh& mesh, const RayScene& scene, const IrradianceSamples& placed,
                    const std::vector<Light>& lights, const PointRenderSettings& settings, SampleSource source,
                    const Camera& camera, const PointAnimation& animation, const std::string& output,
                    const Stopwatch& start) {
    // The frame-0 material of a material / size path (the base material otherwise).
    const Material material = animationMaterial(animation, settings.material, 0);
    const TextureSpaceOptions to = textureSpaceOptions(o, settings.fresnel);
    const std::string evaluate = toLower(o.evaluate);
    // --evaluate vertex: the surface terms as the viewer draws them too (vertex_surface_terms.h).
    SurfaceTermSettings surface = settings.surface;
    surface.perVertex = evaluate == "vertex";
    surface.eye = camera.eye;

    const SurfaceAtlas atlas = buildSurfaceAtlas(mesh, o.atlasSize);
    const SurfaceAtlasStats& as = atlas.stats;
    std::printf("atlas: %d x %d, %zu charts (one per triangle, isometric: area distortion %.4f .. %.4f), %.1f%% of "
                "texels cover surface (%zu), %.2f texels per triangle, %zu triangles under one texel; mapped area "
                "%.6g of %.6g mm^2; built in %.3f s\n",
                atlas.resolution, atlas.resolution, as.triangles, as.minDistortion, as.maxDistortion,
                100.0 * as.coverage, as.coveredTexels, as.meanTexelsPerTriangle, as.subTexelTriangles,
                as.mappedAreaMm2, as.meshAreaMm2, as.buildSeconds);

    TextureSpaceRenderer renderer(mesh, scene, atlas, material, to);
    const DiffusionSplit& split = renderer.split();
    std::printf("texture-space sampling: %s, N = %d, seed %llu; R_p %.4g mm (c = %g /mm), K = %g /mm",
                toString(to.mode), to.samples, static_cast<unsigned long long>(to.seed), split.rp,
                to.importanceBound, to.sharpness);
    if (to.mode == TextureSpaceMode::Hybrid || to.mode == TextureSpaceMode::Local)
        std::printf("; local filter %d x %d + 1 taps to %.4g mm on a %d^2 shadow map per light",
                    to.rings, to.ringSamples, renderer.localFilter().rhoMax, to.lightMapSize);
    std::printf("; evaluated per %s\n", evaluate.c_str());

    renderer.setLights(lights);
    const TextureSpaceTimings& tt = renderer.timings();
    Stopwatch t;
    const GBuffer g = traceGBuffer(scene, mesh, camera);
    // Per vertex, the view's pixel list belongs with the G-buffer (once per view).
    const VertexInterpolation view = evaluate == "vertex" ? renderer.interpolation(g) : VertexInterpolation{};
    const double tGBuffer = t.seconds();
    t.restart();
    if (animation.kind == AnimationKind::MaterialPath)
        return runTextureSpaceAnimation(o, writer, animation, renderer, g, evaluate == "vertex", settings.material,
                                        settings.baseColour, mesh, scene, lights, surface, tGBuffer,
                                        output, start);
    Image image = evaluate == "vertex" ? renderer.shadeVertices(view, renderer.vertexExitance()) : renderer.render(g);
    if (settings.baseColour) applyBaseColour(image, g, *settings.baseColour);
    const double tEval = t.seconds();
    const SurfaceTerms terms = renderSurfaceTerms(g, mesh, scene, lights, material, surface, settings.baseColour);
    addSurfaceTerms(image, terms);
    printSurfaceTerms(surface, terms);
    std::printf("frame: %d x %d, %zu hit pixels; %zu distinct sample texels of %d draws\n", g.width, g.height,
                g.objectPixels(), renderer.uniqueSamples(), to.samples);
    std::printf("times: irradiance map %.4f s, shadow maps %.4f s, draws %.4f s, evaluation %.4f s = %.4f s per "
                "new light position (%.1f fps); G-buffer%s %.4f s (once per view)\n",
                tt.irradianceSeconds, tt.shadowMapSeconds, tt.samplingSeconds, tEval, tt.lighting() + tEval,
                1.0 / std::max(tt.lighting() + tEval, 1e-9), evaluate == "vertex" ? " and pixel list" : "", tGBuffer);
    t.restart();
    writer.exr(output + ".exr", image);
    writer.png(output + ".png", image, &o.display);
    const double tWrite = t.seconds();

    if (o.compareJb || o.compareBrute) {
        // The reference: Jensen-Buhler (or the brute-force sum) over its own irradiance
        // samples (face centroids by default), not the atlas texels.
        const LitSamples lit = lightSamples(placed, scene, lights, settings);
        PointRenderSettings reference = settings;
        reference.method = o.compareBrute ? PointMethod::Brute : PointMethod::JensenBuhler;
        const double epsilon = o.compareBrute ? 0.0 : o.epsilon;
        const std::optional<SampleCells> cells = nearFieldCells(mesh, placed, reference);
        printCells(cells);
        PointFrame frame = renderPointFrame(*lit.tree, g, reference, false, cells);
        addSurfaceTerms(frame.image, terms);  // the same terms as the tsis frame
        const Image& ref = frame.image;
        const double tRef = frame.renderSeconds;
        const std::string suffix = o.compareBrute ? "_brute" : "_jb";
        writer.exr(output + suffix + ".exr", ref);
        writer.png(output + suffix + ".png", ref, &o.display);
        const CompareResult r = compareImages(image, ref);
        const double scale = writeErrorHeatmap(writer, output, image, ref, r);
        std::printf("%s_error.png: relative error, yellow = %g or more (the 99th percentile, rounded up)\n",
                    output.c_str(), scale);
        std::printf("%s (epsilon %g, %zu %s samples): %.3f s; RMSE (hit pixels, mean of R G B of the displayed 0..1 "
                    "image at exposure %g, %s) %.5f; relative RMSE (linear) %.4g, mean ratio %.5f\n",
                    o.compareBrute ? "brute force" : "Jensen-Buhler", epsilon, placed.size(), toString(source), tRef,
                    o.display.exposureStops, toneMapOperatorName(o.display.op), displayRmse(image, ref, o.display),
                    r.overall.relativeRmse, r.overall.meanRatio);
    }
    std::printf("wrote %s.exr and %s.png (write %.3f s) in %s\n", output.c_str(), output.c_str(), tWrite,
                formatDuration(start.seconds()).c_str());
    return 0;
}

}  // namespace

int runPointLightCommand(const PointLightCommand& o, ImageWriter& target) {
    const Stopwatch start;
    const ThreadLimit limit(o.threads);
    const int subpixels = subpixelGridSize(o.camera.spp);
    validateEpsilon(o.epsilon);
    if (o.leafSize < 1) throw Error("--leaf-size", "must be at least 1");
    if (!std::isfinite(o.display.exposureStops)) throw Error("--exposure", "must be finite");
    const FresnelModel fresnel = parseFresnelModel(o.fresnel);
    const PointMethod method = parsePointMethod(o.method);
    const SplitDiskModel splitDisk = parseSplitDiskModel(o.splitDisk);
    validateCacheOptions({.a = o.a, .radius = o.radius, .epsilon = o.epsilon});
    if (o.cacheImage && method != PointMethod::Cache) throw Error("--cache-image", "needs --method cache");
    if (o.compareJb && o.compareBrute && method == PointMethod::TextureSpace)
        throw Error("--compare-brute", "with --method tsis give --compare-jb or --compare-brute, not both");
    const SampleSource source = parseSampleSource(o.samples);
    const NearFieldRule nearField = parseNearFieldRule(o.nearField);
    if (o.sampleCount && source != SampleSource::PoissonDisk)
        throw Error("--sample-count", "applies to --samples poisson only (faces: one sample per face)");
    if (o.sampleCount && *o.sampleCount == 0) throw Error("--sample-count", "must be at least 1");
    const Material material = makeMaterial(o.material);
    const SurfaceTermSettings surface{.specular = o.specular, .specularRoughness = o.specularRoughness,
                                      .singleScattering = o.singleScattering,
                                      .singleScatteringOptions = {.pathSamples = o.singleScatteringSamples}};
    validateSpecularRoughness(surface.specularRoughness);
    validatePointSingleScattering(surface.singleScatteringOptions);
    const std::string output = outputPrefix(o.output);
    if (output.empty()) throw Error("--output", "empty prefix");
    const MeshScale scale = makeScale(o.scale);

    // Animation mode.
    PointAnimation animation;
    const bool materialPath = !o.materialPath.empty() || !o.sizePath.empty();
    const char* pathOption = !o.materialPath.empty() ? "--material-path" : "--size-path";
    if (o.turntable < 0) throw Error("--turntable", "the frame count must be >= 1, got " + std::to_string(o.turntable));
    if (o.turntable > 0 && !o.lightPath.empty())
        throw Error("--turntable", "give either --turntable N or --light-path P0:P1 --frames N, not both");
    if (materialPath && (o.turntable > 0 || !o.lightPath.empty()))
        throw Error(pathOption, "cannot be combined with --turntable or --light-path (one animation at a time)");
    if (!o.lightPath.empty()) {
        if (o.frames < 1) throw Error("--frames", "--light-path needs --frames N with N >= 1");
        animation.kind = AnimationKind::LightPath;
        animation.frames = o.frames;
        parseLightPath(o.lightPath, animation.from, animation.to);
    } else if (materialPath) {
        if (o.frames < 2)
            throw Error("--frames", std::string(pathOption) + " needs --frames N with N >= 2 (t = k / (N - 1))");
        animation.kind = AnimationKind::MaterialPath;
        animation.frames = o.frames;
        if (!o.materialPath.empty()) {
            if (!o.material.sigmaA.empty() || !o.material.sigmaSPrime.empty())
                throw Error("--material-path", "replaces --sigma-a / --sigma-s-prime: give custom ends as "
                                               "sigma:SA_R,SA_G,SA_B:SS_R,SS_G,SS_B");
            animation.materials =
                parseMaterialPath(o.materialPath, o.material.eta.value_or(1.3), o.material.g.value_or(0.0));
        }
        if (!o.sizePath.empty()) {
            double s0 = 0.0, s1 = 0.0;
            parseSizePath(o.sizePath, s0, s1);
            animation.sizesMm = std::make_pair(s0, s1);
        }
        // The placed size: --size-mm; with --mm-per-unit the bounding-box diagonal once
        // the mesh is read (1 until then: only its sign is checked before).
        animation.geometrySizeMm = scale.sizeMm.value_or(1.0);
    } else if (o.frames != 0) {
        throw Error("--frames", "applies to --light-path, --material-path and --size-path only (--turntable N takes "
                                "its own frame count)");
    } else if (o.turntable > 0) {
        animation.kind = AnimationKind::Turntable;
        animation.frames = o.turntable;
    }
    const bool animated = animation.kind != AnimationKind::None;
    if (animated && !materialPath && method == PointMethod::TextureSpace)
        throw Error("--method", "tsis animates the material and size here (--material-path / --size-path); move its "
                                "lights interactively in prt-relight view");
    if (method == PointMethod::TextureSpace) (void)textureSpaceOptions(o, fresnel);
    if (animated && (o.compareJb || o.compareBrute || o.cacheImage))
        throw Error(o.compareJb ? "--compare-jb" : o.compareBrute ? "--compare-brute" : "--cache-image",
                    "applies to single frames, not to --turntable / --light-path / --material-path / --size-path");

    std::vector<Light> lights;
    if (!o.lightsFile.empty()) lights = loadLightScene(o.lightsFile);
    for (const std::string& text : o.lights) lights.push_back(parseLight(text));
    if (lights.empty()) throw Error("--light", "no light: give --light (repeatable) and/or --lights scene.json");
    validateAnimation(animation, lights);

    // Mesh, placed in mm.
    Stopwatch t;
    TriangleMesh mesh = loadMesh(o.mesh);
    const double factor = scaleToPhysical(mesh, scale);
    const Bounds box = bounds(mesh);
    const double tLoad = t.seconds();
    std::printf("mesh: %s, %zu vertices, %zu triangles, x %.4g mm per unit; box (%.4g, %.4g, %.4g) .. (%.4g, %.4g, %.4g) mm\n",
                o.mesh.c_str(), mesh.vertexCount(), mesh.triangleCount(), factor, box.lo.x, box.lo.y, box.lo.z,
                box.hi.x, box.hi.y, box.hi.z);
    if (materialPath && !scale.sizeMm) animation.geometrySizeMm = glm::length(glm::dvec3(box.size()));
    // The frame-0 material of a material / size path (what a single render would use).
    const Material firstMaterial = animationMaterial(animation, material, 0);
    if (materialPath) {
        std::printf("material path: %s -> %s over %d frames; size %.4g -> %.4g mm (the mesh stays at %.4g mm: frame k "
                    "uses scaledMaterial(m_k, S_k / %.4g); lights, camera and irradiance stay attached to the "
                    "object); Fresnel %s\n",
                    describeMaterial(animation.materials ? animation.materials->first : material).c_str(),
                    describeMaterial(animation.materials ? animation.materials->second : material).c_str(),
                    animation.frames, animationSizeMm(animation, 0), animationSizeMm(animation, animation.frames - 1),
                    animation.geometrySizeMm, animation.geometrySizeMm, toString(fresnel));
    } else {
        std::printf("material: %s, sigma_s' %s /mm, sigma_a %s /mm, eta %.4g; Fresnel %s\n", material.name.c_str(),
                    formatRgb(material.sigmaSPrime, 4, " ").c_str(), formatRgb(material.sigmaA, 4, " ").c_str(),
                    material.eta, toString(fresnel));
    }
    for (const Light& l : lights) std::printf("light: %s\n", describe(l).c_str());
    if (animation.kind == AnimationKind::LightPath)
        std::printf("light path: light 1 from (%.4g, %.4g, %.4g) to (%.4g, %.4g, %.4g) mm over %d frames\n",
                    animation.from.x, animation.from.y, animation.from.z, animation.to.x, animation.to.y,
                    animation.to.z, animation.frames);

    t.restart();
    const RayScene scene(mesh);
    const double tScene = t.seconds();
    if (!animated) checkLightsOutside(scene, lights);  // renderAnimation checks every frame's lights

    // Sample placement (positions, normals, areas: the surface only).
    t.restart();
    IrradianceSamples placed;
    if (source == SampleSource::FaceCentroids) {
        placed = faceCentroidSamples(mesh);
    } else {
        const size_t rule = defaultSampleCount(totalArea(mesh), firstMaterial.minMeanFreePath());
        const size_t n = o.sampleCount.value_or(rule);
        // As prt-precompute: beyond twice the spacing rule the sum was not found to converge.
        if (4 * n < rule)
            warn("--sample-count " + std::to_string(n) + " is far below the convergence rule's " +
                 std::to_string(rule) + " (spacing l_u = " + formatParameter(firstMaterial.minMeanFreePath()) +
                 " mm): the irradiance samples will under-resolve the dipole");
        placed = samplesFromSampleSet(poissonDiskSamples(mesh, n, o.seed));
    }
    const double tPlace = t.seconds();

    const BaseColour colour = o.baseColour ? BaseColour::load(o.mesh, mesh) : BaseColour();
    if (colour.enabled()) std::printf("%s\n", colour.describe().c_str());
    const PointRenderSettings settings{.material = material, .method = method, .fresnel = fresnel,
                                       .leafSize = o.leafSize, .epsilon = o.epsilon, .a = o.a,
                                       .radius = o.radius, .splitDisk = splitDisk, .nearField = nearField,
                                       .baseColour = colour.enabled() ? &colour : nullptr, .surface = surface};
    glm::dvec3 centre(box.centre());
    double radius = 0.0;
    for (const glm::vec3& p : mesh.positions) radius = std::max(radius, glm::length(glm::dvec3(p) - centre));
    // At --spp N every frame is drawn N times larger and written box-downsampled
    // (supersample.h); the figures printed on the way are over the sub-pixel samples.
    const Camera camera = supersampledCamera(makeCamera(o.camera, centre, radius), subpixels);
    DownsamplingImageWriter downsampled(target, subpixels);
    ImageWriter& writer = downsampled;
    if (subpixels > 1)
        std::printf("anti-aliasing: %d spp (a %d x %d sub-pixel grid, box filter); frames are traced at %d x %d\n",
                    o.camera.spp, subpixels, subpixels, camera.width, camera.height);

    const std::filesystem::path parent = std::filesystem::path(output).parent_path();
    if (!parent.empty()) std::filesystem::create_directories(parent);

    if (method == PointMethod::TextureSpace)
        return runTextureSpace(o, writer, mesh, scene, placed, lights, settings, source, camera, animation, output, start);

    if (animated) {
        std::printf("samples: %zu (%s), %.4g mm^2 in all; load %.3f s, Embree scene %.3f s, sample placement %.3f s\n",
                    placed.size(), toString(source), placed.totalArea(), tLoad, tScene, tPlace);
        return runAnimation(o, writer, animation, mesh, scene, placed, lights, camera, centre, settings, output, start);
    }

    // The near field's cells (the surface and the material: no light), then pass 1:
    // irradiance samples and their octree.
    t.restart();
    const std::optional<SampleCells> cells = nearFieldCells(mesh, placed, settings);
    const double tCells = t.seconds();
    printCells(cells);
    const LitSamples lit = lightSamples(placed, scene, lights, settings);
    const double tIrradiance = lit.irradianceSeconds, tTree = lit.octreeSeconds;
    const IrradianceOctree& tree = *lit.tree;
    std::printf("samples: %zu (%s), %.4g mm^2 in all; octree %zu nodes, %zu leaves, depth %d\n", placed.size(),
                toString(source), placed.totalArea(), tree.nodes().size(), tree.leafCount(), tree.depth());

    // Primary rays, then the frame by the chosen method.
    t.restart();
    const GBuffer g = traceGBuffer(scene, mesh, camera);
    const double tGBuffer = t.seconds();

    PointFrame frame = renderPointFrame(tree, g, settings, o.cacheImage, cells);
    // The surface terms once: the references below get the same (they compare the
    // translucent methods; the terms do not depend on the method).
    const SurfaceTerms terms = renderSurfaceTerms(g, mesh, scene, lights, material, settings.surface, settings.baseColour);
    addSurfaceTerms(frame.image, terms);
    printSurfaceTerms(settings.surface, terms);
    const Image& image = frame.image;
    const double tRender = frame.renderSeconds;
    if (method == PointMethod::Cache) {
        const IrradianceCacheStats& cs = frame.cacheStats;
        std::printf("irradiance cache: a %g, R %.4g mm (split disk %s), epsilon %g, S_ref %.4g W/m^2; %zu caches / "
                    "%zu hit pixels = %.2f%% (%zu shaded), %.1f terms per cache walk, %.2f valid caches per pixel\n",
                    o.a, cs.radius, toString(splitDisk), o.epsilon, cs.sRef, cs.caches, cs.hitPixels,
                    100.0 * cs.ratio(), cs.shadedPixels, cs.caches ? double(cs.walkTerms) / double(cs.caches) : 0.0,
                    cs.meanValidCaches);
        std::printf("cache times: pass 2 %.3f s (serial scan %.3f s, S and gradient in parallel tasks), pass 3 %.3f s; "
                    "T_cache %.3f s\n",
                    cs.pass2Seconds, cs.scanSeconds, cs.pass3Seconds, tRender);
        // At the traced resolution (sub-pixels at --spp > 1): a cache's dot would fade in the box filter.
        if (o.cacheImage) writeCacheImages(target, output, image, g, frame.caches, frame.visuals, o.display);
    } else {
        std::printf("%s: epsilon %g, %zu object pixels, %.1f terms per pixel (of %zu samples)\n",
                    method == PointMethod::Brute ? "brute force" : "Jensen-Buhler",
                    method == PointMethod::Brute ? 0.0 : o.epsilon, frame.jbStats.pixels, frame.jbStats.meanTerms(),
                    placed.size());
    }

    t.restart();
    writer.exr(output + ".exr", image);
    writer.png(output + ".png", image, &o.display);
    const double tWrite = t.seconds();

    std::printf("frame: %d x %d, %zu hit pixels, %zu samples\n", g.width, g.height, g.objectPixels(), placed.size());
    std::printf("times: load %.3f s, Embree scene %.3f s, sample placement %.3f s, near-field cells %.3f s, "
                "irradiance sampling %.3f s, octree %.3f s, G-buffer %.3f s, %s %.3f s, write %.3f s\n",
                tLoad, tScene, tPlace, tCells, tIrradiance, tTree, tGBuffer, toString(method), tRender, tWrite);

    // The Jensen-Buhler / brute-force references; their times exclude irradiance
    // sampling and the octree, as Keng's T_1.
    auto reference = [&](PointMethod m) {
        PointRenderSettings s = settings;
        s.method = m;
        PointFrame f = renderPointFrame(tree, g, s, false, cells);
        addSurfaceTerms(f.image, terms);
        return f;
    };
    if (o.compareJb && method != PointMethod::JensenBuhler) {
        const PointFrame jb = reference(PointMethod::JensenBuhler);
        const double tJb = jb.renderSeconds;
        writer.exr(output + "_jb.exr", jb.image);
        writer.png(output + "_jb.png", jb.image, &o.display);
        const CompareResult r = compareImages(image, jb.image);
        writeErrorHeatmap(writer, output, image, jb.image, r);
        std::printf("Jensen-Buhler (epsilon %g): T_JB %.3f s, speedup %.2fx; RMS (paper: hit pixels, mean of R G B of "
                    "the displayed 0..1 image, exposure %g, %s) %.5f; relative RMSE (linear) %.4g, mean ratio %.5f\n",
                    o.epsilon, tJb, tJb / std::max(tRender, 1e-9), o.display.exposureStops,
                    toneMapOperatorName(o.display.op), displayRmse(image, jb.image, o.display),
                    r.overall.relativeRmse, r.overall.meanRatio);
    }
    if (o.compareBrute) {
        const PointFrame brute = reference(PointMethod::Brute);
        const double tBrute = brute.renderSeconds;
        writer.exr(output + "_brute.exr", brute.image);
        const CompareResult r = compareImages(image, brute.image);
        std::printf("brute force (epsilon 0): %.3f s, %.1fx the %s time; %s vs brute: relative RMSE %.3g, max relative "
                    "error %.3g, mean ratio %.6f, RMS (paper, %s) %.5f\n",
                    tBrute, tBrute / std::max(tRender, 1e-9), toString(method), toString(method),
                    r.overall.relativeRmse, r.overall.maxRelative, r.overall.meanRatio,
                    toneMapOperatorName(o.display.op), displayRmse(image, brute.image, o.display));
    }
    std::printf("wrote %s.exr and %s.png in %s\n", output.c_str(), output.c_str(),
                formatDuration(start.seconds()).c_str());
    return 0;
}

void addPointLightOptions(CLI::App& app, PointLightCommand& o) {
    app.add_option("mesh", o.mesh, "Mesh file (.obj .ply .off .stl, optionally .gz)")->required();
    app.add_option("-o,--output", o.output,
                   "Output prefix: writes <prefix>.exr (linear RGBA float, A = 1 on the object) and <prefix>.png")
        ->required();
    app.add_option("--light", o.lights,
                   "A light, repeatable: point:X,Y,Z:R,G,B (mm, W/sr), dir:X,Y,Z:R,G,B (toward the light, W/m^2) "
                   "or spot:X,Y,Z:DX,DY,DZ:R,G,B:INNER,OUTER (mm, the axis it shines along, W/sr on the axis, cone "
                   "half-angles in degrees: smoothstep falloff from OUTER to INNER)")
        ->group("Lights");
    app.add_option("--lights", o.lightsFile, "JSON scene file with a \"lights\" list (docs/point-lights.md)")
        ->group("Lights");
    addScaleOptions(app, o.scale);
    addMaterialOptions(app, o.material, /*withG=*/true);
    addBaseColourOption(app, o.baseColour);
    app.add_option("--samples", o.samples,
                   "Irradiance samples: faces (one per face at its centroid with the face area, Keng's choice) "
                   "or poisson (the precompute's Poisson-disk samples)")
        ->capture_default_str()->group("Jensen-Buhler");
    app.add_option("--sample-count", o.sampleCount,
                   "Poisson-disk sample count (default: spacing = the material's mean free path)")
        ->group("Jensen-Buhler");
    app.add_option("--seed", o.seed, "Seed of the Poisson-disk samples")->capture_default_str()->group("Jensen-Buhler");
    app.add_option("--epsilon", o.epsilon, "Solid-angle threshold A_node / d^2 (0 = brute-force sum)")
        ->capture_default_str()->group("Jensen-Buhler");
    app.add_option("--near-field", o.nearField,
                   "Near-field rule of jb, brute and the cache's S: cells (R_d integrated over each sample's "
                   "face or cell), points (the papers' A_i R_d(|x - x_i|)) or auto (cells where the samples lie "
                   "farther apart than the narrowest kernel width)")
        ->capture_default_str()->group("Jensen-Buhler");
    app.add_option("--leaf-size", o.leafSize, "Samples per octree leaf")->capture_default_str()->group("Jensen-Buhler");
    app.add_option("--fresnel", o.fresnel,
                   "exact (F_t per light and view direction) or keng (diffuse F_dt in, none out: Keng Eqs. 3-4)")
        ->capture_default_str()->group("Jensen-Buhler");
    app.add_flag("--compare-brute", o.compareBrute,
                 "Also render the brute-force sum (epsilon 0, slow) to <prefix>_brute.exr and report time and error")
        ->group("Jensen-Buhler");
    app.add_option("--method", o.method,
                   "cache (Keng et al. 2006 translucent irradiance cache), jb (Jensen-Buhler at every pixel), "
                   "brute (the sum over all samples) or tsis (Chang et al. 2008 texture-space importance "
                   "sampling; --compare-jb / --compare-brute then render the reference)")
        ->capture_default_str()->group("Irradiance cache");
    app.add_option("--a", o.a,
                   "Cache error bound a (> 0): a cache is valid where its Eq. 11 error is below a S_ref "
                   "(S_ref = exitance of the brightest sample irradiance); smaller = more caches")
        ->capture_default_str()->group("Irradiance cache");
    app.add_option("--radius", o.radius,
                   "Split-disk radius R in mm (0 = the material's default: the radius collecting a fifth of int R_d dA, widest channel)")
        ->capture_default_str()->group("Irradiance cache");
    app.add_option("--split-disk", o.splitDisk,
                   "dS/du bound of the split disk: paper (Keng's four-sector formula) or exact (half-bright disk)")
        ->capture_default_str()->group("Irradiance cache");
    app.add_flag("--compare-jb", o.compareJb,
                 "Also render Jensen-Buhler (same epsilon) to <prefix>_jb.exr/png, <prefix>_error.png; print "
                 "T_JB, speedup, the paper's RMS and the relative RMSE")
        ->group("Irradiance cache");
    app.add_flag("--cache-image", o.cacheImage,
                 "Write <prefix>_caches.png (cache positions over the frame), <prefix>_gradient.png and "
                 "<prefix>_variance.png (Keng Figs. 8-9)")
        ->group("Irradiance cache");
    app.add_option("--split", o.split,
                   "What renders R_d: hybrid (local part by the shadow-map filter + global part by the samples, "
                   "Chang section 4), sampling (the samples alone, section 3), local or global (one part alone)")
        ->capture_default_str()->group("Texture-space sampling");
    app.add_option("--tsis-samples", o.tsis.samples, "N, importance samples drawn from the irradiance map")
        ->capture_default_str()->group("Texture-space sampling");
    app.add_option("--tsis-seed", o.tsis.seed, "Seed of the stratified draws' jitter (the frame's seed)")
        ->capture_default_str()->group("Texture-space sampling");
    app.add_option("--atlas-size", o.atlasSize, "Surface atlas / irradiance map resolution (power of two)")
        ->capture_default_str()->group("Texture-space sampling");
    app.add_option("--importance-bound", o.tsis.importanceBound,
                   "c in mm^-1: R_p is the largest r with R_d(r) 2 pi r = c (0.1 gives the paper's Skimmilk 2.41 mm)")
        ->capture_default_str()->group("Texture-space sampling");
    app.add_option("--split-sharpness", o.tsis.sharpness, "K in mm^-1 of the weights W_l, W_g")
        ->capture_default_str()->group("Texture-space sampling");
    app.add_option("--light-map", o.tsis.lightMapSize, "Translucent shadow map resolution per light")
        ->capture_default_str()->group("Texture-space sampling");
    app.add_option("--rings", o.tsis.rings, "L, rings of the local filter")->capture_default_str()->group("Texture-space sampling");
    app.add_option("--ring-samples", o.tsis.ringSamples, "C, taps per ring of the local filter")
        ->capture_default_str()->group("Texture-space sampling");
    app.add_option("--cluster-angle", o.tsis.clusterAngle,
                   "theta: the global sum uses a cluster of samples whole when its cell's diagonal is below theta "
                   "times its distance (0 sums every sample)")
        ->capture_default_str()->group("Texture-space sampling");
    app.add_option("--evaluate", o.evaluate,
                   "pixel (the sums at every visible point) or vertex (at mesh vertices, interpolated, and so are "
                   "the rays of --specular and --single-scattering: what prt-relight view draws)")
        ->capture_default_str()->group("Texture-space sampling");
    app.add_option("--turntable", o.turntable,
                   "Render N frames <prefix>_0000 ... of the object turning 360 degrees about the vertical axis "
                   "through its bounding-box centre (a camera orbit, as prt-relight render), lights fixed in the "
                   "object's frame. Reused between frames: the irradiance samples and the octree (the lights do "
                   "not move relative to the object); NOT the caches (they live on each frame's visible points)")
        ->group("Animation");
    app.add_option("--light-path", o.lightPath,
                   "X0,Y0,Z0:X1,Y1,Z1 (mm): with --frames N, the FIRST light (a point or spot light; a spot keeps its axis) "
                   "moves linearly "
                   "from P0 (frame 0) to P1 (frame N-1). Reused between frames: only the mesh, its ray scene, "
                   "the sample positions/areas and the G-buffer (fixed camera); irradiance, octree and caches "
                   "are recomputed every frame. Write a negative first value as --light-path=-20,...")
        ->group("Animation");
    app.add_option("--material-path", o.materialPath,
                   "A:B: with --frames N (>= 2), the material moves linearly from A (frame 0) to B (frame N-1), "
                   "t = k / (N - 1), coefficients interpolated (Chang et al. Fig. 11). Each end is a measured "
                   "name, sigma:SA_R,SA_G,SA_B:SS_R,SS_G,SS_B (mm^-1) or colour:R,G,B:MFP (the artist's pair); "
                   "--eta applies to both ends; replaces -m. Works with every --method. Reused between frames: "
                   "everything that does not depend on the material (irradiance samples and octree, G-buffer; "
                   "for tsis the atlas, irradiance map, draws and shadow maps)")
        ->group("Animation");
    app.add_option("--size-path", o.sizePath,
                   "S0:S1 (mm): with --frames N (>= 2), the object's size moves linearly from S0 to S1, alone or "
                   "with --material-path. The mesh stays at --size-mm; frame k renders scaledMaterial(m_k, S_k / "
                   "size-mm, or the bounding-box diagonal with --mm-per-unit) (scaling an object by s = scaling sigma by s), so the lights, the camera and the "
                   "irradiance stay attached to the object: how it would look s times larger, lit the same way")
        ->group("Animation");
    app.add_option("--frames", o.frames, "Frame count of --light-path, --material-path or --size-path")
        ->group("Animation");
    app.add_flag("--specular", o.specular,
                 "Add the specular reflection of the lights: a GGX microfacet lobe weighted by the exact dielectric "
                 "F_r = 1 - F_t at the material's eta, shadowed; added untinted by --base-colour, to every method's "
                 "frames (docs/point-lights.md, \"Specular\")")
        ->group("Surface terms");
    app.add_option("--specular-roughness", o.specularRoughness,
                   "GGX roughness alpha of --specular, in (0, 1] (used as given, not squared)")
        ->capture_default_str()->group("Surface terms");
    app.add_flag("--single-scattering", o.singleScattering,
                 "Add single scattering (Jensen et al. 2001) along the refracted view ray at every pixel: HG phase "
                 "with --g, Fresnel in and out, the light shadowed at its entry point; tinted by --base-colour like "
                 "the diffusion (docs/point-lights.md, \"Single scattering\")")
        ->group("Surface terms");
    app.add_option("--single-scattering-samples", o.singleScatteringSamples,
                   "Gauss-Legendre samples along the refracted view ray of --single-scattering (1..256)")
        ->capture_default_str()->group("Surface terms");
    addDisplayOptions(app, o.display);
    addThreadsOption(app, o.threads);
    addCameraOptions(app, o.camera);
    addSamplesPerPixelOption(app, o.camera);
}

}  // namespace prt
