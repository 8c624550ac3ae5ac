#include "tools/reference/reference_command.h"

#include "common/ground.h"


#include <CLI/CLI.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "common/asset_io.h"
#include "common/bssrdf.h"
#include "common/material_edit.h"
#include "common/camera.h"
#include "common/envmap.h"
#include "common/error.h"
#include "common/image.h"
#include "common/options.h"
#include "common/mesh.h"
#include "common/progress.h"
#include "common/raytrace.h"
#include "tools/reference/reference.h"
#include "common/transport_file.h"
#include "common/transport_params.h"
#include "relight/render/gbuffer.h"
#include "relight/render/base_colour.h"
#include "relight/render/supersample.h"
#include "common/sampling.h"
#include "common/mesh_io.h"
#include "common/util.h"

namespace prt {

namespace {






// A parameter the reference needs from the transport file unless given explicitly.
template <typename T>
T require(const std::optional<T>& value, const std::string& path, const std::string& key, const std::string& option) {
    if (!value) throw Error(path, "has no parameter '" + key + "'; give " + option + " explicitly");
    return *value;
}

SingleScatteringPath parsePath(const std::string& text) {
    if (text == "refracted" || text == "true") return SingleScatteringPath::Refracted;
    if (text == "normal") return SingleScatteringPath::Normal;
    throw Error("--ss-path", "unknown path '" + text + "'; use refracted or normal");
}

void printNoise(const char* what, const ReferenceFrame& f) {
    std::printf("  %s noise: expected relative RMSE from Monte Carlo noise %.3g%% (per pixel: median %.3g%%, max "
                "%.3g%% relative standard error)\n",
                what, 100 * f.expectedRelativeRmse, 100 * f.medianRelativeStandardError,
                100 * f.maxRelativeStandardError);
}

// The reference of a diffuse-baseline file (prt-precompute --baseline diffuse-brdf):
// the shadowed Lambertian surface traced per pixel (DiffuseBrdfReference).
int runDiffuseBaselineReference(const ReferenceCommand& o, const TriangleMesh& mesh, const TransportFileInfo& info,
                                int subpixels, const std::string& output, ImageWriter& writer,
                                const Stopwatch& start) {
    const std::vector<double> a = parseNumberList(info.parameter("albedo"), o.transport, "albedo");
    if (a.size() != 3) throw Error(o.transport, "the baseline's albedo is not R,G,B");
    const glm::dvec3 albedo(a[0], a[1], a[2]);
    const BoundingSphere sphere = boundingSphere(mesh);
    const Camera camera = supersampledCamera(makeCamera(o.camera, sphere.centre, sphere.radius), subpixels);
    const BaseColour colour = o.baseColour ? BaseColour::load(o.mesh, mesh) : BaseColour();
    const Image environment = loadEnvironment(o.environment, NonFinitePolicy::ClampNegative);
    const glm::dmat3 rotation = rotationY(o.envRotation);
    const EnvironmentSampler sampler(environment, rotation);
    IrradianceEstimatorOptions irradiance = o.irradiance;
    irradiance.directions = o.envSamples ? o.envSamples : 4096;
    const std::filesystem::path parent = std::filesystem::path(output).parent_path();
    if (!parent.empty()) std::filesystem::create_directories(parent);
    std::printf("baseline: shadowed Lambertian (diffuse-brdf), albedo (%.4g, %.4g, %.4g); %zu irradiance directions "
                "per pixel, seed %llu\n",
                albedo.r, albedo.g, albedo.b, irradiance.directions, (unsigned long long)irradiance.seed);
    std::fflush(stdout);
    const RayScene scene(mesh);
    const GBuffer full = traceGBuffer(scene, mesh, camera);
    const GBuffer gbuffer = o.pixelStride > 1 ? subsampleObjectPixels(full, o.pixelStride) : full;
    const DiffuseBrdfReference diffuse(sampler, scene, albedo, irradiance);
    Progress progress("diffuse baseline per pixel", gbuffer.objectPixels(), "pixels");
    ReferenceFrame frame = renderReference(gbuffer, {&diffuse}, environment, rotation, &progress);
    progress.finish();
    applyBaseColour(frame.image, gbuffer, colour);
    applyBaseColour(frame.standardError, gbuffer, colour);
    DownsamplingImageWriter downsampled(writer, subpixels);
    downsampled.exr(output + ".exr", frame.image);
    downsampled.png(output + ".png", frame.image, &o.display);
    if (!o.noiseImage.empty()) downsampled.exr(o.noiseImage, frame.standardError);
    printNoise("total", frame);
    std::printf("wrote %s.exr and %s.png; total %s\n", output.c_str(), output.c_str(),
                formatDuration(start.seconds()).c_str());
    return 0;
}

}  // namespace

int runReferenceCommand(const ReferenceCommand& o, ImageWriter& writer) {
    const Stopwatch start;
    const ThreadLimit limit(o.threads);
    const int subpixels = subpixelGridSize(o.camera.spp);
    if (o.pixelStride > 1 && subpixels > 1)
        throw Error("--pixel-stride", "not with --spp > 1 (it would thin out the sub-pixel samples of each pixel)");
    if (!std::isfinite(o.envRotation)) throw Error("--env-rotation", "must be finite");
    if (!std::isfinite(o.display.exposureStops)) throw Error("--exposure", "must be finite");
    const std::string output = outputPrefix(o.output);
    if (output.empty()) throw Error("--output", "empty prefix");
    if (o.spacingFraction && !(*o.spacingFraction > 0 && *o.spacingFraction <= 10))
        throw Error("--spacing-fraction", "must be in (0, 10]");
    if (o.maxSamples && *o.maxSamples < 1) throw Error("--max-samples", "must be at least 1");
    if (!(o.irradiance.environmentFraction >= 0 && o.irradiance.environmentFraction <= 1))
        throw Error("--env-fraction", "must be in [0, 1]");
    if (o.pixelStride < 1) throw Error("--pixel-stride", "must be at least 1");

    // The light: an environment map, or point and directional lights (docs/reference.md).
    std::vector<Light> lights;
    if (!o.lightsFile.empty()) lights = loadLightScene(o.lightsFile);
    for (const std::string& text : o.lights) lights.push_back(parseLight(text));
    const bool lightMode = !o.lights.empty() || !o.lightsFile.empty();
    // Under lights the irradiance costs one shadow ray per sample, so the rule can be
    // denser (reference.h, kReferenceLightSpacingFraction).
    const double spacingFraction =
        o.spacingFraction.value_or(lightMode ? kReferenceLightSpacingFraction : kReferenceSpacingFraction);
    const size_t maxSamples = o.maxSamples.value_or(lightMode ? kReferenceLightMaxSamples : kDefaultSampleCap);
    if (lightMode && !o.environment.empty())
        throw Error("--environment", "give either an environment or --light/--lights, not both");
    if (!lightMode && o.environment.empty())
        throw Error("--environment", "no light: give -e ENVIRONMENT or --light/--lights");
    if (lightMode && lights.empty()) throw Error(o.lightsFile, "the scene has no light");
    if (!lightMode && o.transport.empty())
        throw Error("--transport", "an environment reference needs the transport file it is compared with");
    if (!o.transport.empty() && (o.scale.sizeMm || o.scale.mmPerUnit))
        throw Error(o.scale.sizeMm ? "--size-mm" : "--mm-per-unit",
                    "the transport file fixes the size; give it only without -t");

    // Mesh and (when given) the transport file's header: the same placement as
    // prt-relight render, or, for lights without a file, as prt-pointlight.
    TriangleMesh mesh = loadMesh(o.mesh);
    std::optional<TransportFileInfo> info;
    TransportParameters params;
    double mmPerUnit = 0.0;
    if (!o.transport.empty()) {
        info = readTransportFileInfo(o.transport);
        const MeshFingerprint fingerprint{mesh.vertexCount(), meshFingerprint(mesh)};
        if (!(fingerprint == info->mesh)) {
            char buf[256];
            std::snprintf(
                buf, sizeof buf,
                "was computed for another mesh (%llu vertices, hash %016llx), not %s (%llu vertices, hash %016llx)",
                (unsigned long long)info->mesh.vertexCount, (unsigned long long)info->mesh.positionHash,
                o.mesh.c_str(), (unsigned long long)fingerprint.vertexCount,
                (unsigned long long)fingerprint.positionHash);
            throw Error(o.transport, buf);
        }
        mmPerUnit = scaleToPhysical(mesh, MeshScale{.sizeMm = std::nullopt, .mmPerUnit = info->mmPerUnit});
        params = readTransportParameters(info->parameters, o.transport);
    } else {
        mmPerUnit = scaleToPhysical(mesh, makeScale(o.scale));
    }

    // --ground: the plane traced with the object, described by its file's header only
    // (plane and albedo), never by its vectors.
    std::optional<GroundDescription> ground;
    if (!o.ground.empty()) {
        if (lightMode) throw Error("--ground", "the ground is referenced under environments only");
        if (!info) throw Error("--ground", "needs the object's transport file (-t)");
        if (info->parameter("baseline") == "diffuse-brdf")
            throw Error("--ground", "not with a diffuse-baseline file (" + o.transport + ")");
        ground = readGroundDescription(o.ground, info->mesh, info->parameter(kGroundPlaneParameter),
                                       info->parameter("input_digest"), info->cubemapSize, info->shTerms,
                                       o.transport);
    }
    if (info && info->parameter("baseline") == "diffuse-brdf") {
        if (lightMode) throw Error(o.transport, "the diffuse baseline is referenced under environments only");
        const std::pair<bool, const char*> scatteringOnly[] = {
            {o.componentImages, "--component-images"}, {o.perVertex, "--per-vertex"},
            {o.sameSamples, "--same-samples"},         {!o.components.empty(), "--components"},
            {o.materialGiven, "--material"},           {o.samples.has_value(), "--samples"},
            {o.maxSamples.has_value(), "--max-samples"}, {o.spacingFraction.has_value(), "--spacing-fraction"}};
        for (const auto& [given, option] : scatteringOnly)
            if (given) throw Error(option, "does not apply to a diffuse-baseline file (" + o.transport + ")");
        return runDiffuseBaselineReference(o, mesh, *info, subpixels, output, writer, start);
    }
    Material material;
    if (info && !o.materialGiven) {
        material = require(params.material, o.transport, "sigma_s_prime, sigma_a or eta", "--material");
    } else {
        material = makeMaterial(o.material);
        if (info)
            warn("--material " + material.name + " overrides the transport file's material (" +
                 (params.material ? params.material->name : std::string("none")) +
                 "): the reference no longer matches the file");
    }
    if (o.g) {
        material.g = *o.g;
        validateMaterial(material);
        warn("--g overrides the phase asymmetry (sigma_s' kept): single scattering no longer matches the file");
    }
    // Default: multiple scattering, plus single scattering when the file has it (and the
    // light is an environment: under lights the reference has no single scattering).
    const ScatteringComponents components =
        !o.components.empty() ? parseScatteringComponents(o.components)
        : lightMode           ? ScatteringComponents{true, false}
                              : ScatteringComponents{true, componentsOf(*info).singleScattering ||
                                                               params.components.value_or(ScatteringComponents::none())
                                                                   .singleScattering};
    if (lightMode && components.singleScattering)
        throw Error("--components", "single scattering is referenced under environments only (under lights "
                                    "prt-pointlight's --single-scattering is checked by its own tests)");
    if (o.perVertex && !components.multipleScattering) warn("--per-vertex applies to multiple scattering only; ignored");
    SingleScatteringReferenceOptions ssOptions = o.ss;
    ssOptions.path = parsePath(o.ssPath);
    ssOptions.seed = o.irradiance.seed;
    if (components.singleScattering) {
        if (ssOptions.pathSamples < 1) throw Error("--ss-samples", "must be at least 1");
        if (ssOptions.lightSamples < 1) throw Error("--ss-light-samples", "must be at least 1");
        if (!(ssOptions.environmentFraction >= 0 && ssOptions.environmentFraction <= 1))
            throw Error("--ss-env-fraction", "must be in [0, 1]");
    }
    const BoundingSphere sphere = boundingSphere(mesh);  // as prt-relight and prt-pointlight frame it
    // At --spp N the frame is traced N times larger and box-downsampled (supersample.h).
    const Camera camera = supersampledCamera(makeCamera(o.camera, sphere.centre, sphere.radius), subpixels);
    const BaseColour colour = o.baseColour ? BaseColour::load(o.mesh, mesh) : BaseColour();
    // --material-map: the blend at each pixel's own texture coordinate, written here again
    // (the renderers blend per vertex; relight/prt/material_map.h).
    std::optional<Material> mapSecond;
    std::shared_ptr<const Asset> mapAsset;
    Image mapImage;
    if (!o.materialMap.empty()) {
        if (o.mapMaterial.empty()) throw Error("--material-map", "needs --map-material");
        if (o.perVertex) throw Error("--material-map", "not with --per-vertex (the blend is per pixel)");
        if (!components.multipleScattering) throw Error("--material-map", "blends multiple scattering: select it");
        mapSecond = parseMaterial(o.mapMaterial, material.eta, material.g);
        mapAsset = std::make_shared<const Asset>(loadAsset(o.mesh));
        if (mapAsset->uvs.empty()) throw Error(o.mesh, "has no texture coordinates for --material-map");
        mapImage = readImage(o.materialMap);
        for (size_t k = 0; k < mapImage.pixels.size(); k += size_t(mapImage.channels))
            if (!(mapImage.pixels[k] >= 0.0f && mapImage.pixels[k] <= 1.0f))
                throw Error(o.materialMap, "material map values must lie in [0, 1]");
        std::printf("material map: %s (%d x %d), %s where it is 1, blended per pixel at the exit point\n",
                    o.materialMap.c_str(), mapImage.width, mapImage.height, describeMaterial(*mapSecond).c_str());
    } else if (!o.mapMaterial.empty()) {
        throw Error("--map-material", "needs --material-map");
    }
    const auto mapAt = [&](const GBufferPixel& p) -> float {
        const glm::vec2* uv = &mapAsset->uvs[3 * size_t(p.triangle)];
        const glm::vec2 at = p.barycentric.x * uv[0] + p.barycentric.y * uv[1] + p.barycentric.z * uv[2];
        if (std::isnan(at.x) || std::isnan(at.y)) return 0.0f;
        return std::clamp(sampleTexture(mapImage, at, TextureWrap::Repeat, TextureWrap::Repeat).r, 0.0f, 1.0f);
    };
    const Image environment =
        lightMode ? Image() : loadEnvironment(o.environment, NonFinitePolicy::ClampNegative);
    const glm::dmat3 rotation = rotationY(o.envRotation);
    std::optional<EnvironmentSampler> sampler;
    if (!lightMode) sampler.emplace(environment, rotation);

    const std::filesystem::path parent = std::filesystem::path(output).parent_path();
    if (!parent.empty()) std::filesystem::create_directories(parent);

    std::printf("mesh: %s, %zu vertices, %zu triangles, %.4g mm per unit, %.4g mm across\n", o.mesh.c_str(),
                mesh.vertexCount(), mesh.triangleCount(), mmPerUnit, double(bounds(mesh).diagonal()));
    std::printf("material: %s, sigma_s' %s /mm, sigma_a %s /mm, eta %.4g, g %.4g (sigma_s %s /mm)\n",
                material.name.c_str(), formatRgb(material.sigmaSPrime).c_str(), formatRgb(material.sigmaA).c_str(),
                material.eta, material.g, formatRgb(material.sigmaS()).c_str());
    std::printf("components: %s%s%s\n", components.multipleScattering ? "multiple scattering" : "",
                components.multipleScattering && components.singleScattering ? " + " : "",
                components.singleScattering ? (std::string("single scattering (") + toString(ssOptions.path) + " path)").c_str()
                              : "");
    std::printf("camera: eye (%.4g, %.4g, %.4g) target (%.4g, %.4g, %.4g) fov %.4g, %dx%d, %d spp%s\n",
                camera.eye.x, camera.eye.y, camera.eye.z, camera.target.x, camera.target.y, camera.target.z,
                camera.fovY, camera.width / subpixels, camera.height / subpixels, o.camera.spp,
                subpixels > 1 ? " (a regular sub-pixel grid, box filter)" : "");
    for (const Light& l : lights) std::printf("light: %s (exact Fresnel)\n", describe(l).c_str());
    if (colour.enabled()) std::printf("%s\n", colour.describe().c_str());
    if (ground)
        std::printf("ground: %s, %.4g mm square at y = %.4g mm, albedo (%.4g, %.4g, %.4g); it occludes the object's "
                    "irradiance, not its single scattering\n",
                    o.ground.c_str(), 2.0 * ground->plane.halfExtent, ground->plane.height, ground->albedo.r,
                    ground->albedo.g, ground->albedo.b);
    std::fflush(stdout);

    // With a ground, rays see the object and the plane (the object's triangles first);
    // single scattering keeps the object's own scene, as the precompute does.
    const std::optional<TriangleMesh> objectAndGround =
        ground ? std::optional<TriangleMesh>(withGround(mesh, groundMesh(ground->plane))) : std::nullopt;
    const TriangleMesh& traced = objectAndGround ? *objectAndGround : mesh;
    const size_t objectTriangles = mesh.triangleCount();
    const RayScene scene(traced);
    std::optional<RayScene> objectOnly;
    if (ground && components.singleScattering) objectOnly.emplace(mesh);
    checkLightsOutside(scene, lights);
    const Stopwatch raysStart;
    const GBuffer fullGBuffer = traceGBuffer(scene, traced, camera);
    const double raysSeconds = raysStart.seconds();
    // --pixel-stride: every k-th object pixel only (the others come out as background).
    const GBuffer gbuffer = o.pixelStride > 1 ? subsampleObjectPixels(fullGBuffer, o.pixelStride) : fullGBuffer;
    if (o.pixelStride > 1)
        std::printf("pixels: every %zu-th object pixel, %zu of %zu (--pixel-stride)\n", o.pixelStride,
                    gbuffer.objectPixels(), fullGBuffer.objectPixels());

    std::vector<ReferenceFrame> parts;
    std::vector<std::string> partNames;

    if (components.multipleScattering) {
        // The sample set. By default the reference's own (docs/reference.md, reference.h):
        // spacing from the convergence rule, its own seed, never the precomputation's;
        // --same-samples reproduces the precomputation's set to isolate the transport error.
        const std::optional<uint64_t> fileSeed = params.seed;
        const std::optional<uint64_t> fileSamples = params.samples;
        if (o.sameSamples && !info)
            throw Error("--same-samples", "needs the transport file (-t) whose samples it reuses");
        if (o.seed && fileSeed && *o.seed == *fileSeed && !o.sameSamples)
            throw Error("--seed", "is the transport file's placement seed (" + std::to_string(*fileSeed) +
                                      "): the reference would share the precomputation's sample set; give "
                                      "--same-samples to do that deliberately");
        const double totalArea = prt::totalArea(mesh);
        size_t sampleCount = 0;
        uint64_t seed = 0;
        std::string sampleRule;
        if (o.sameSamples) {
            sampleCount = o.samples ? *o.samples : size_t(require(fileSamples, o.transport, "samples", "--samples"));
            seed = o.seed ? *o.seed : require(fileSeed, o.transport, "seed", "--seed");
            sampleRule = "SAME SAMPLES as the precomputation (--same-samples): this reference measures the transport "
                         "error only (cubemap, wavelets, hierarchy, truncation, interpolation), NOT the error of the "
                         "sample sum";
        } else {
            const ReferenceSamplePlan plan = planReferenceSamples(material, totalArea, fileSeed.value_or(1),
                                                                  maxSamples, spacingFraction, o.seed);
            sampleCount = o.samples ? *o.samples : plan.count;
            seed = plan.seed;
            char buf[512];
            if (o.samples)
                std::snprintf(buf, sizeof buf, "independent samples: --samples %zu, own seed", sampleCount);
            else
                std::snprintf(buf, sizeof buf,
                              "independent samples: spacing %.4g mm = %.3g x 1/max_c(sigma_t' + sigma_tr) (the "
                              "convergence rule), own seed",
                              plan.spacingMm, spacingFraction);
            sampleRule = buf;
            if (o.samples && 4 * *o.samples < plan.count)
                warn("--samples " + std::to_string(*o.samples) + " is far below the convergence rule's " +
                     std::to_string(plan.count) + " (spacing " + formatParameter(plan.spacingMm) +
                     " mm): the reference's sample sum will not be converged");
            if (plan.capped && !o.samples)
                warn("the convergence rule asks for " +
                     std::to_string(defaultSampleCount(totalArea, plan.spacingMm, size_t(-1))) +
                     " samples (spacing " + formatParameter(plan.spacingMm) + " mm); capped at --max-samples " +
                     std::to_string(maxSamples) + " (spacing " + formatParameter(plan.cappedSpacingMm) +
                     " mm): the sample sum is less converged, see the discretisation estimate below");
            if (fileSamples && fileSeed && sampleCount == *fileSamples && seed == *fileSeed)
                throw Error("reference", "internal: the default sample set equals the precomputation's");
        }
        if (sampleCount < 1) throw Error("--samples", "must be at least 1");
        IrradianceEstimatorOptions irradianceOptions = o.irradiance;
        if (o.envSamples == 0)
            irradianceOptions.directions = o.sameSamples ? 2048 : referenceIrradianceDirections(sampleCount);
        else
            irradianceOptions.directions = o.envSamples;
        if (irradianceOptions.directions < 1) throw Error("--env-samples", "must be at least 1");
        if (lightMode && o.envSamples != 0)
            warn("--env-samples applies to environments; the lights' irradiance is exact");
        std::printf("samples: %s\n", sampleRule.c_str());
        std::printf("  planned: %zu samples x %zu object pixels = %.3g point-sample pairs%s\n", sampleCount,
                    gbuffer.objectPixels(), double(sampleCount) * double(gbuffer.objectPixels()),
                    o.convergenceStride ? " (+ the convergence run)" : "");
        std::fflush(stdout);

        // One multiple-scattering render from `count` samples placed with `placementSeed`.
        struct MsRun {
            ReferenceFrame frame;
            SampleSet samples;
            uint64_t rays = 0;
            size_t litSamples = 0;  // samples that enter the sum (E or its variance non-zero)
            double irradianceSeconds = 0, sampleRelativeError = 0, vertexSeconds = 0;
        };
        auto renderMs = [&](size_t count, uint64_t placementSeed, const GBuffer& pixels, bool perVertex,
                            const std::string& label) {
            MsRun run;
            {
                Progress p(label + "samples", count, "samples");
                run.samples = poissonDiskSamples(mesh, count, placementSeed);
                p.advance(count);
            }
            SampleIrradiance irradiance;
            if (lightMode) {
                Progress p(label + "irradiance (exact, " + std::to_string(lights.size()) + " light" +
                               (lights.size() == 1 ? "" : "s") + ")",
                           run.samples.samples.size(), "samples");
                irradiance = computeLightIrradiance(lights, scene, run.samples, material.eta, &p);
            } else {
                Progress p(label + "irradiance (" + std::to_string(irradianceOptions.directions) +
                               " directions per sample)",
                           run.samples.samples.size(), "samples");
                irradiance = computeSampleIrradiance(*sampler, &scene, run.samples, material.eta, irradianceOptions, &p);
            }
            run.rays = irradiance.rays;
            run.irradianceSeconds = irradiance.seconds;
            run.sampleRelativeError = irradiance.medianRelativeStandardError;
            std::vector<glm::vec3> positions;
            positions.reserve(run.samples.samples.size());
            for (const SurfaceSample& s : run.samples.samples) positions.push_back(s.position);
            // With a material map, B's sum over the same samples and irradiance.
            std::optional<MultipleScatteringReference> second;
            if (mapSecond)
                second.emplace(*mapSecond, positions, run.samples.areaPerSample, irradiance);
            MultipleScatteringReference ms(material, std::move(positions), run.samples.areaPerSample,
                                           std::move(irradiance));
            run.litSamples = ms.contributingSamples();
            if (perVertex) {
                const Stopwatch t0;
                Progress p(label + "multiple scattering at vertices", mesh.vertexCount(), "vertices");
                ms.evaluateAtVertices(mesh, &p);
                run.vertexSeconds = t0.seconds();
            }
            Progress p(label + (perVertex ? "multiple scattering (interpolated)" : "multiple scattering per pixel"),
                       pixels.objectPixels(), "pixels");
            std::optional<MaterialBlendComponent> blended;
            if (second) blended.emplace(ms, *second, mapAt);
            const TriangleRangeComponent onObject(blended ? static_cast<const ReferenceComponent&>(*blended) : ms, 0,
                                                  objectTriangles);
            run.frame = renderReference(pixels, {&onObject}, environment, rotation, &p);
            return run;
        };

        const MsRun main = renderMs(sampleCount, seed, gbuffer, o.perVertex, "");
        parts.push_back(main.frame);
        partNames.push_back("ms");
        const ReferenceFrame& frame = main.frame;
        const SampleSet& samples = main.samples;

        // Cross-check: with the file's count and seed the samples must be the file's.
        if (o.sameSamples && !o.samples && !o.seed && params.sampleAreaMm2) {
            const double fileArea = *params.sampleAreaMm2;
            if (!(std::abs(fileArea - samples.areaPerSample) <= 1e-6 * fileArea))
                warn("sample area " + std::to_string(samples.areaPerSample) +
                     " mm^2 differs from the transport file's " + formatParameter(fileArea) +
                     " mm^2: the samples are not the ones it was computed from");
        }

        const size_t nEnv =
            size_t(std::llround(irradianceOptions.environmentFraction * double(irradianceOptions.directions)));
        std::printf("samples: %zu (seed %llu%s), A_i = %.4g mm^2 (total %.4g mm^2), spacing %.4g mm, min spacing "
                    "%.4g mm\n",
                    samples.samples.size(), (unsigned long long)seed,
                    o.sameSamples ? ", the precomputation's" : ", the reference's own", samples.areaPerSample,
                    samples.totalArea, std::sqrt(2.0 * samples.areaPerSample / std::sqrt(3.0)), samples.minSpacing);
        if (lightMode) {
            std::printf("irradiance: exact per sample (one shadow ray per light), %llu occlusion rays in %.1f s; %zu "
                        "of %zu samples lit\n",
                        (unsigned long long)main.rays, main.irradianceSeconds, main.litSamples,
                        samples.samples.size());
        } else {
            std::printf("irradiance: %zu directions per sample (%zu environment + %zu cosine, MIS balance heuristic, "
                        "Monte Carlo seed %llu), %llu occlusion rays in %.1f s (%.3g rays/s)\n",
                        irradianceOptions.directions, nEnv, irradianceOptions.directions - nEnv,
                        (unsigned long long)irradianceOptions.seed, (unsigned long long)main.rays,
                        main.irradianceSeconds, main.irradianceSeconds > 0 ? main.rays / main.irradianceSeconds : 0.0);
            std::printf("  median relative standard error of one sample's irradiance: %.3g%%\n",
                        100 * main.sampleRelativeError);
        }
        const double pairs =
            double(o.perVertex ? mesh.vertexCount() : frame.objectPixels) * double(main.litSamples);
        std::printf("multiple scattering: %s, %.3g point-sample pairs in %.1f s\n",
                    o.perVertex ? "per vertex, interpolated" : "per pixel", pairs,
                    o.perVertex ? main.vertexSeconds + frame.seconds : frame.seconds);
        printNoise("multiple scattering", frame);
        std::fflush(stdout);

        // Convergence: the same render from an independent set of half as many samples
        // (its own seed) over every k-th object pixel; their difference, less the noise,
        // estimates the quadrature error that remains (reference.h).
        if (o.convergenceStride > 0 && o.perVertex) {
            std::printf("  discretisation: no estimate in --per-vertex mode\n");
        } else if (o.convergenceStride > 0 && sampleCount >= 2) {
            const GBuffer subset = subsampleObjectPixels(gbuffer, o.convergenceStride);
            const uint64_t halfSeed = referenceSampleSeed(fileSeed.value_or(seed), 1, seed);
            const MsRun half = renderMs(sampleCount / 2, halfSeed, subset, false, "convergence: ");
            const DiscretisationEstimate d = estimateDiscretisationError(frame, half.frame);
            std::printf("  discretisation (sample sum): estimated remaining error %.3g%% relative RMSE (from %zu "
                        "samples, seed %llu, over %zu pixels: they differ by %.3g%%, noise floor %.3g%%, so %.3g%% "
                        "of quadrature error, divided by sqrt(1 + 2^%.2g))\n",
                        100 * d.estimatedError, half.samples.samples.size(), (unsigned long long)halfSeed, d.pixels,
                        100 * d.difference, 100 * d.noiseFloor, 100 * d.halfError, 2 * kDiscretisationRate);
            std::fflush(stdout);
        }
    }

    if (components.singleScattering) {
        SingleScatteringReference ss(material, mesh, objectOnly ? *objectOnly : scene, *sampler, ssOptions);
        {
            Progress p(std::string("single scattering (") + toString(ssOptions.path) + " path)",
                       gbuffer.objectPixels(), "pixels");
            const TriangleRangeComponent onObject(ss, 0, objectTriangles);
            parts.push_back(renderReference(gbuffer, {&onObject}, environment, rotation, &p));
            partNames.push_back("ss");
        }
        const ReferenceFrame& frame = parts.back();
        const size_t nEnv = size_t(std::llround(ssOptions.environmentFraction * double(ssOptions.lightSamples)));
        std::printf("single scattering: %s path, %zu path samples x %zu directions (%zu environment + %zu uniform, "
                    "MIS balance heuristic) per pixel, HG g = %.4g; %llu rays in %.1f s (%.3g rays/s)\n",
                    toString(ssOptions.path), ssOptions.pathSamples, ssOptions.lightSamples, nEnv,
                    ssOptions.lightSamples - nEnv, material.g, (unsigned long long)ss.raysTraced(), frame.seconds,
                    frame.seconds > 0 ? double(ss.raysTraced()) / frame.seconds : 0.0);
        printNoise("single scattering", frame);
        std::fflush(stdout);
    }

    if (ground) {
        // The plane's pixels: its shadowed Lambertian radiance traced per pixel, as the
        // diffuse baseline's reference (DiffuseBrdfReference) in the object + plane scene.
        IrradianceEstimatorOptions irradiance = o.irradiance;
        irradiance.directions = o.envSamples ? o.envSamples : 4096;
        const DiffuseBrdfReference diffuse(*sampler, scene, ground->albedo, irradiance);
        const TriangleRangeComponent onGround(diffuse, objectTriangles, traced.triangleCount());
        Progress p("ground per pixel", gbuffer.objectPixels(), "pixels");
        parts.push_back(renderReference(gbuffer, {&onGround}, environment, rotation, &p));
        partNames.push_back("ground");
        std::printf("ground: %zu irradiance directions per pixel (seed %llu), %.1f s\n", irradiance.directions,
                    (unsigned long long)irradiance.seed, parts.back().seconds);
        printNoise("ground", parts.back());
    }

    // The base colour tints what leaves at each pixel's surface point, as in every renderer.
    for (ReferenceFrame& f : parts) {
        applyBaseColour(f.image, gbuffer, colour);
        applyBaseColour(f.standardError, gbuffer, colour);
    }
    std::vector<const ReferenceFrame*> partPointers;
    for (const ReferenceFrame& f : parts) partPointers.push_back(&f);
    const ReferenceFrame frame = parts.size() == 1 ? parts[0] : sumReferenceFrames(partPointers);

    DownsamplingImageWriter downsampled(writer, subpixels);
    downsampled.exr(output + ".exr", frame.image);
    downsampled.png(output + ".png", frame.image, &o.display);
    // The mean of the sub-pixel standard errors bounds the standard error of their mean
    // whatever their correlation (they share the sample set).
    if (!o.noiseImage.empty()) downsampled.exr(o.noiseImage, frame.standardError);
    if (o.componentImages)
        for (size_t k = 0; k < parts.size(); ++k) {
            downsampled.exr(output + "_" + partNames[k] + ".exr", parts[k].image);
            downsampled.png(output + "_" + partNames[k] + ".png", parts[k].image, &o.display);
        }

    std::printf("%zu object pixels, %d x %d primary rays in %.2f s\n", frame.objectPixels, camera.width,
                camera.height, raysSeconds);
    printNoise("total", frame);
    std::printf("wrote %s.exr and %s.png%s%s%s; total %s\n", output.c_str(), output.c_str(),
                o.noiseImage.empty() ? "" : " and ", o.noiseImage.c_str(),
                o.componentImages ? " and per-component images" : "", formatDuration(start.seconds()).c_str());
    return 0;
}

void addReferenceOptions(CLI::App& app, ReferenceCommand& o) {
    app.add_option("mesh", o.mesh, "Mesh file the transport file was computed for (.obj .ply .off .stl, .gz)")
        ->required();
    app.add_option("-t,--transport", o.transport,
                   "Transport file (only its header and parameters are read: fingerprint, scale, material, "
                   "sample count and seed); required with -e, optional with lights");
    app.add_option("-e,--environment", o.environment, "Lat-long HDR environment (EXR, HDR, ...; width = 2 height)")
        ->group("Lighting");
    app.add_option("--light", o.lights,
                   "Instead of -e: a light, repeatable: point:X,Y,Z:R,G,B (mm, W/sr) or dir:X,Y,Z:R,G,B "
                   "(toward the light, W/m^2), as prt-pointlight")
        ->group("Lighting");
    app.add_option("--lights", o.lightsFile, "Instead of -e: a JSON scene file with a \"lights\" list")
        ->group("Lighting");
    app.add_option("-o,--output", o.output,
                   "Output prefix (a trailing .exr/.png is dropped): writes <prefix>.exr (linear RGBA float, A = 1 on the object) and "
                   "<prefix>.png (sRGB)")
        ->required();
    addCameraOptions(app, o.camera);
    addSamplesPerPixelOption(app, o.camera);
    app.add_option("--env-rotation", o.envRotation, "Rotate the environment by this many degrees about +Y")
        ->capture_default_str()->group("Lighting");
    addDisplayOptions(app, o.display);
    app.add_option("--noise-image", o.noiseImage,
                   "Also write the estimated standard error of every pixel (RGB EXR) to this file")
        ->group("Output");
    // Without -t they place the object as prt-pointlight does; with -t the file's size
    // holds and a material overrides the file's (experiments only, with a warning).
    const std::string objectGroup = "Object (without -t; with -t a material overrides the file's)";
    addMaterialOptions(app, o.material, false, objectGroup);
    addBaseColourOption(app, o.baseColour, objectGroup);
    app.add_option("--material-map", o.materialMap,
                   "A texture in the asset's texture coordinates (first channel in [0, 1]): where it is t, "
                   "--map-material replaces the material by t, blended per pixel at the exit point")
        ->group(objectGroup);
    app.add_option("--map-material", o.mapMaterial, "The material where --material-map is 1")->group(objectGroup);
    app.add_option("--ground", o.ground,
                   "The ground's transport file (prt-precompute --ground): traces the plane with the object, its "
                   "shadowed Lambertian radiance per pixel by Monte Carlo (only its plane and albedo are read)")
        ->group(objectGroup);
    addScaleOptions(app, o.scale, objectGroup);
    app.add_flag("--same-samples", o.sameSamples,
                 "Use the precomputation's sample set (the file's count and seed): isolates the transport "
                 "error (cubemap, wavelets, hierarchy, truncation) and hides the sample-sum error")
        ->group("Reference");
    app.add_option("--samples", o.samples,
                   "Surface samples (default: from the convergence rule; with --same-samples the file's)")
        ->group("Reference");
    app.add_option("--seed", o.seed,
                   "Seed of the sample placement (default: the reference's own; the file's seed is refused "
                   "without --same-samples)")
        ->group("Reference");
    app.add_option("--spacing-fraction", o.spacingFraction,
                   "Convergence rule: sample spacing = this x 1/max_c(sigma_t' + sigma_tr) (default " +
                       formatParameter(kReferenceSpacingFraction) + " under an environment, " +
                       formatParameter(kReferenceLightSpacingFraction) + " under lights)")
        ->group("Reference");
    app.add_option("--max-samples", o.maxSamples,
                   "Budget: at most this many samples, a warning says so (default " +
                       std::to_string(kDefaultSampleCap) + " under an environment, " +
                       std::to_string(kReferenceLightMaxSamples) + " under lights)")
        ->group("Reference");
    app.add_option("--convergence-stride", o.convergenceStride,
                   "Convergence estimate: render every k-th object pixel again from half as many samples "
                   "(0: off)")
        ->capture_default_str()->group("Reference");
    app.add_option("--env-samples", o.envSamples,
                   "Monte Carlo directions per sample (default: 16.8 M rays / samples, in [64, 2048]; 2048 "
                   "with --same-samples)")
        ->group("Reference");
    app.add_option("--env-fraction", o.irradiance.environmentFraction,
                   "Share of the directions drawn from the environment's luminance (the rest cosine-weighted)")
        ->capture_default_str()->group("Reference");
    app.add_option("--mc-seed", o.irradiance.seed, "Seed of the Monte Carlo directions")
        ->capture_default_str()->group("Reference");
    app.add_option("--components", o.components,
                   "Components: ms, ss, ms,ss or all (default: ms, plus ss when the transport file has single "
                   "scattering)")
        ->group("Reference");
    app.add_option("--ss-samples", o.ss.pathSamples,
                   "Single scattering: stratified path samples per pixel (along the refracted view ray)")
        ->capture_default_str()->group("Single scattering");
    app.add_option("--ss-light-samples", o.ss.lightSamples, "Single scattering: directions per path sample")
        ->capture_default_str()->group("Single scattering");
    app.add_option("--ss-env-fraction", o.ss.environmentFraction,
                   "Single scattering: share of the directions drawn from the environment's luminance (the "
                   "rest uniform on the sphere)")
        ->capture_default_str()->group("Single scattering");
    app.add_option("--ss-path", o.ssPath,
                   "Single scattering integration path: refracted (the true w_o', Wang Fig. 5a) or normal "
                   "(-n_o, the precomputation's approximation, Fig. 5b)")
        ->capture_default_str()->group("Single scattering");
    app.add_option("--g", o.g,
                   "Override the Henyey-Greenstein asymmetry (default: the transport file's 'g'); sigma_s' is "
                   "kept, so sigma_s = sigma_s' / (1 - g) changes")
        ->group("Single scattering");
    app.add_flag("--component-images", o.componentImages,
                 "Also write <prefix>_ms.exr/.png and <prefix>_ss.exr/.png, one per rendered component")
        ->group("Output");
    app.add_flag("--per-vertex", o.perVertex,
                 "Sum at the mesh vertices and interpolate barycentrically (as the precomputed renderer "
                 "does) instead of summing at every pixel's hit point")
        ->group("Reference");
    app.add_option("--pixel-stride", o.pixelStride,
                   "Render every k-th object pixel only (the others are background, A = 0): an unbiased "
                   "sample of a large frame's error at 1/k of the cost")
        ->capture_default_str()->group("Reference");
    addThreadsOption(app, o.threads);
}

void noteGivenReferenceOptions(const CLI::App& app, ReferenceCommand& o) {
    for (const char* name : {"--material", "--sigma-a", "--sigma-s-prime", "--diffuse-colour", "--mfp-mm", "--eta"})
        if (app.count(name) > 0) o.materialGiven = true;
}

}  // namespace prt
