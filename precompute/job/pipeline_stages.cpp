#include "precompute/job/pipeline_stages.h"

#include <tbb/task_arena.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <span>
#include <utility>

#include "common/atomic_file.h"
#include "common/bssrdf.h"
#include "common/error.h"
#include "common/material_edit.h"
#include "common/radial_basis.h"
#include "common/mesh_io.h"
#include "common/progress.h"
#include "precompute/job/memory_estimate.h"
#include "precompute/job/pass1_file.h"
#include "precompute/job/fold_single_scattering.h"
#include "precompute/job/pipeline.h"
#include "precompute/job/transport_blocking.h"
#include "common/cell_quadrature.h"
#include "precompute/passes/diffuse_baseline.h"
#include "precompute/passes/irradiance_transport.h"
#include "precompute/passes/multiple_scattering.h"
#include "precompute/passes/phase_factoring.h"
#include "common/radial_kernels.h"
#include "precompute/passes/single_scattering.h"

namespace prt {

namespace {

std::string fmt(double v) { return formatParameter(v); }

}  // namespace

JobInputs readInputs(const JobContext& job, bool force) {
    const PrecomputeSettings& s = job.settings;
    Distribution& dist = job.distribution;
    JobInputs in;
    dist.stage([&] {
        validateSettings(s);
        if (dist.writes() && !s.outputPath.empty()) checkOutputPath(s.outputPath);
        if (dist.writes() && !s.pass1File.empty()) checkOutputPath(s.pass1File);
        if (dist.writes() && s.ground && !s.outputPath.empty()) checkOutputPath(groundTransportPath(s.outputPath));
        in.mesh = loadMesh(s.meshPath);
        in.fingerprint = MeshFingerprint{in.mesh.vertexCount(), meshFingerprint(in.mesh)};
        in.parameters = settingsParameters(s, in.fingerprint);
        const std::string digest = in.parameters.back().second;
        if (force || !dist.writes() || s.pass1Only || !std::filesystem::exists(s.outputPath)) return;
        try {
            const TransportFileInfo info = readTransportFileInfo(s.outputPath);
            bool same = info.parameter("input_digest") == digest && info.mesh == in.fingerprint;
            for (const auto& [key, value] : dist.outputParameters(in.mesh.vertexCount()))
                same = same && info.parameter(key) == value;
            // A whole file is not up to date for a shard job nor a shard for a whole job.
            same = same && info.hasParameter(kShardParameter) == dist.shard();
            // With a ground, its file too: made for the same job, and whole.
            if (same && s.ground) {
                const std::string groundPath = groundTransportPath(s.outputPath);
                same = std::filesystem::exists(groundPath) &&
                       readTransportFileInfo(groundPath).parameter("input_digest") == digest;
                if (same) loadTransportFile(groundPath);
            }
            if (same) {
                loadTransportFile(s.outputPath);  // every checksum
                in.upToDate = true;
            }
        } catch (const Error&) {
            // Not valid: recompute and replace it.
        }
    });
    return in;
}

PreparedJob setUp(const JobContext& job, JobInputs inputs, const Stopwatch& jobStart) {
    const PrecomputeSettings& s = job.settings;
    Distribution& dist = job.distribution;
    PreparedJob p;
    p.mesh = std::move(inputs.mesh);
    p.fingerprint = inputs.fingerprint;
    p.parameters = std::move(inputs.parameters);
    p.vertexShares = dist.vertexShares(p.mesh.vertexCount());
    p.myVertices = totalSize(p.vertexShares);
    p.summary.computedVertices = size_t(dist.sum(double(p.myVertices)));
    dist.stage([&] {
        p.mmPerUnit = scaleToPhysical(p.mesh, s.scale);
        p.summary.vertices = p.mesh.vertexCount();
        p.summary.triangles = p.mesh.triangleCount();
        p.summary.totalAreaMm2 = totalArea(p.mesh);
        p.derived.push_back({"mm_per_unit", fmt(p.mmPerUnit)});
        if (s.components.multipleScattering) {
            // Spacing about the mean free path l_u = 1 / sigma_t' (Jensen-Buhler).
            const double spacing = s.samples.spacingMm > 0 ? s.samples.spacingMm : s.material.minMeanFreePath();
            p.sampleCount = s.samples.count > 0
                                ? s.samples.count
                                : defaultSampleCount(p.summary.totalAreaMm2, spacing, s.samples.maxCount);
            // The convergence rule is a spacing of about l_u; beyond twice it (a quarter of
            // the rule's count) the cell rule was not found to converge (docs/precompute.md,
            // "Samples"), so a request that coarse is said aloud.
            const size_t rule =
                defaultSampleCount(p.summary.totalAreaMm2, s.material.minMeanFreePath(), s.samples.maxCount);
            if (4 * p.sampleCount < rule && dist.writes())
                warn(std::to_string(p.sampleCount) + " samples (" +
                     (s.samples.count > 0 ? "--samples" : "--sample-spacing " + fmt(s.samples.spacingMm) + " mm") +
                     ") are far below the convergence rule's " + std::to_string(rule) + " (spacing l_u = " +
                     fmt(s.material.minMeanFreePath()) +
                     " mm of " + s.material.name + "): multiple scattering will be under-resolved");
        }
        const MemoryEstimate need =
            estimatePrecomputeMemory(s, p.mesh.vertexCount(), p.mesh.triangleCount(), p.sampleCount,
                                     tbb::this_task_arena::max_concurrency(),
                                     p.summary.totalAreaMm2,
                                     bounds(p.mesh).diagonal());
        checkMemory(need, s.maxMemoryGb);
        p.summary.estimatedMemoryBytes = need.bytes;
        if (s.ground) {
            p.ground = groundPlaneUnder(bounds(p.mesh), *s.ground);
            p.derived.push_back({kGroundPlaneParameter, formatGroundPlane(*p.ground)});
        }
        if (s.components.multipleScattering) {
            if (p.ground) p.scene.emplace(withGround(p.mesh, groundMesh(*p.ground)));
            else p.scene.emplace(p.mesh);
        }
        p.summary.seconds = jobStart.seconds();
        p.summary.peakMemoryBytes = peakMemoryBytes();
    });
    return p;
}

PlacedSamples placeSamples(const JobContext& job, const PreparedJob& prepared) {
    PlacedSamples out;
    job.distribution.stage([&] {
        const Stopwatch start;
        {
            Progress p("samples", prepared.sampleCount, "samples");
            out.samples = poissonDiskSamples(prepared.mesh, prepared.sampleCount, job.settings.samples.seed);
            p.advance(prepared.sampleCount);
        }
        out.summary.seconds = start.seconds();
        out.summary.peakMemoryBytes = peakMemoryBytes();
        out.summary.count = out.samples.samples.size();
        out.summary.spacingMm = std::sqrt(2.0 * out.samples.areaPerSample / std::sqrt(3.0));
        out.derived.push_back({"samples", std::to_string(out.summary.count)});
        out.derived.push_back({"sample_area_mm2", fmt(out.samples.areaPerSample)});
    });
    return out;
}

Pass1Output runPass1(const JobContext& job, const PreparedJob& prepared, const PlacedSamples& placed) {
    const PrecomputeSettings& s = job.settings;
    Distribution& dist = job.distribution;
    const size_t sampleCount = placed.samples.samples.size();
    Pass1Output out;
    out.summary.file = s.pass1File;
    // A pass-1 file that exists is read by every process (rank 0 decides, so all agree).
    const bool fromFile = dist.agree(!s.pass1File.empty() && std::filesystem::exists(s.pass1File));
    const std::string key =
        s.pass1File.empty() ? std::string() : pass1Key(prepared.parameters, prepared.mmPerUnit, sampleCount);
    IrradianceTransportResult pass1;
    IndexRange mine{0, sampleCount};
    dist.stage([&] {
        if (fromFile) {
            const Stopwatch loadStart;
            pass1.vectors = loadPass1File(s.pass1File, key);
            pass1.seconds = loadStart.seconds();
            out.summary.loaded = true;
            return;
        }
        mine = dist.sampleShare(sampleCount);
        SampleSet share;
        share.areaPerSample = placed.samples.areaPerSample;
        share.samples.assign(placed.samples.samples.begin() + ptrdiff_t(mine.begin),
                             placed.samples.samples.begin() + ptrdiff_t(mine.end));
        Progress p("pass 1 (irradiance transport)" + job.share, share.samples.size(), "samples");
        pass1 = computeIrradianceTransport(&*prepared.scene, share, s.pass1, &p);
        out.busySeconds = pass1.seconds;
    });
    const Stopwatch exchangeStart;
    // What MpiDistribution::gatherSamples sends: the channel count, two 8-byte counts and
    // 8 bytes per coefficient.
    double exchangeBytes = 0;
    for (const SparseVector& v : pass1.vectors) exchangeBytes += 20 + 8 * double(v.size());
    if (!fromFile) pass1.vectors = dist.gatherSamples(std::move(pass1.vectors), sampleCount);
    out.summary.exchangeBytes = dist.ranks() > 1 ? dist.sum(exchangeBytes) : 0.0;
    out.summary.exchangeSeconds = exchangeStart.seconds();
    out.summary.rays = uint64_t(dist.sum(double(pass1.raysTraced)));
    out.summary.seconds = pass1.seconds + out.summary.exchangeSeconds;
    // All ranks' rays over this rank's time: the shares run side by side.
    out.summary.raysPerSecond = pass1.seconds > 0 ? double(out.summary.rays) / pass1.seconds : 0;
    out.summary.retainedEnergy =
        dist.sum(pass1.retainedEnergyFraction * double(mine.size())) / double(sampleCount);
    out.summary.peakMemoryBytes = peakMemoryBytes();
    if (!s.pass1File.empty() && !fromFile)
        dist.stage([&] {
            if (dist.writes()) savePass1File(s.pass1File, key, pass1.vectors);
        });
    out.vectors = std::move(pass1.vectors);
    return out;
}

namespace {

// An editable job's basis (radial_basis.h) for this mesh, and its fit errors as file
// parameters: the worst over the covered materials at the smallest, the job's and the
// largest size, and the job's own material's.
RadialBasis editableBasis(const PrecomputeSettings& s, const TriangleMesh& mesh, ParameterList& derived) {
    const double objectSizeMm = bounds(mesh).diagonal();
    const RadialRange range = editableRange(s, objectSizeMm);
    const bool sized = s.editable.sizeMinMm > 0.0;
    const double sizes[3] = {sized ? s.editable.sizeMinMm / objectSizeMm : 0.5, 1.0,
                             sized ? s.editable.sizeMaxMm / objectSizeMm : 2.0};
    // In coordinates balanced for the covered materials, so that the joint truncation of
    // the profile vectors keeps what those materials' recombinations need; each material
    // and size counts by its relative error (its channels weighted by 1 / (R_R^2 + R_G^2 +
    // R_B^2), R_c the channel's total diffuse reflectance, the scale of its transport).
    std::vector<DipoleChannel> covered;
    std::vector<double> importance;
    for (const Material& m : editableMaterials(s))
        for (double f : sizes) {
            double scale = 0.0;
            for (int c = 0; c < 3; ++c) {
                covered.push_back(makeDipoleChannel(scaledMaterial(m, f), c));
                scale += std::pow(dipoleTotalDiffuseReflectance(covered.back()), 2.0);
            }
            for (int c = 0; c < 3; ++c) importance.push_back(1.0 / scale);
        }
    RadialBasis basis = balancedForDipoles(makeRadialBasis(range, s.editable.basis), covered, importance);
    double worstL1 = 0.0, worstDisk = 0.0;
    std::string worstCase;
    for (const Material& m : editableMaterials(s))
        for (double f : sizes)
            for (int c = 0; c < 3; ++c) {
                const RadialFitError e = basis.fitError(makeDipoleChannel(scaledMaterial(m, f), c));
                if (e.l1 > worstL1) {
                    worstL1 = e.l1;
                    worstCase = m.name + " channel " + "RGB"[c] + " at size x" + formatParameter(f);
                }
                worstDisk = std::max(worstDisk, e.disk);
            }
    double ownL1 = 0.0;
    for (int c = 0; c < 3; ++c) ownL1 = std::max(ownL1, basis.fitError(makeDipoleChannel(s.material, c)).l1);
    derived.push_back({"editable_object_size_mm", formatParameter(objectSizeMm)});
    derived.push_back({"editable_sizes_mm", formatParameter(sizes[0] * objectSizeMm) + ":" +
                                                formatParameter(sizes[2] * objectSizeMm)});
    derived.push_back({"radial_range", "z_r " + formatParameter(range.zrMin) + " .. " + formatParameter(range.zrMax) +
                                           " mm, alpha' " + formatParameter(range.alphaMin) + " .. " +
                                           formatParameter(range.alphaMax) + ", r <= " + formatParameter(range.rMax) +
                                           " mm"});
    derived.push_back({"radial_coordinates", "balanced for the covered materials (radial_basis.h)"});
    derived.push_back({"radial_fit_worst_l1", formatParameter(worstL1) + " (" + worstCase + ")"});
    derived.push_back({"radial_fit_worst_disk", formatParameter(worstDisk)});
    derived.push_back({"radial_fit_l1_own_material", formatParameter(ownL1)});
    return basis;
}

// Appends pass 2's vectors of consecutive vertices to the components: the RGB vector, or
// with profiles (editable) the K channels split into K / 3 components of three.
void appendPass2Vectors(const std::vector<SparseVector>& transport, bool profiles, int K,
                        std::vector<TransportComponent>& components) {
    std::vector<float> rgb;
    for (size_t p = 0; p < components.size(); ++p) {
        SparseRgbVectors& out = components[p].vectors;
        for (const SparseVector& v : transport) {
            if (!profiles) {
                out.appendVertex(v.index, v.value);
                continue;
            }
            rgb.resize(3 * v.index.size());
            for (size_t n = 0; n < v.index.size(); ++n)
                for (size_t ch = 0; ch < 3; ++ch) rgb[3 * n + ch] = v.value[n * size_t(K) + 3 * p + ch];
            out.appendVertex(v.index, rgb);
        }
    }
}

}  // namespace

Pass2Output runPass2(const JobContext& job, const PreparedJob& prepared, const PlacedSamples& placed,
                     std::vector<SparseVector> pass1Vectors) {
    const PrecomputeSettings& s = job.settings;
    Distribution& dist = job.distribution;
    const size_t texelCount = size_t(6) * s.cubemapSize * s.cubemapSize;
    Pass2Output out;
    MultipleScatteringStats stats;
    const Stopwatch start;
    // Every process builds the same basis (deterministic), so only the writer's is kept.
    std::optional<RadialBasis> basis;
    if (s.editable.enabled) basis = editableBasis(s, prepared.mesh, out.derived);
    const RadialKernels kernels = basis ? radialBasisKernels(*basis) : RadialKernels(s.material);
    // RGB transport; or profiles 3p, 3p+1, 3p+2 of every vertex in component p, all
    // components sharing the vertex's one index list.
    out.components.resize(basis ? size_t(kernels.count() / 3) : 1);
    for (size_t p = 0; p < out.components.size(); ++p) {
        TransportComponent& c = out.components[p];
        c.kind = basis ? ComponentKind::MultipleScatteringProfiles : ComponentKind::MultipleScattering;
        c.term = basis ? uint32_t(p) : 0;
        if (basis && s.editable.haarBits == 8 && s.blockCoefficients == 0)
            c.vectors.useEightBitHaar(s.shTerms > 0 ? uint32_t(6 * s.cubemapSize * s.cubemapSize) : UINT32_MAX);
        c.vectors.reserve(prepared.myVertices, prepared.myVertices * s.vertexCoefficients);
    }
    dist.stage([&] {
        SampleCloud cloud;
        cloud.positions.reserve(placed.samples.samples.size());
        std::vector<glm::vec3> normals;
        normals.reserve(placed.samples.samples.size());
        for (const SurfaceSample& sample : placed.samples.samples) {
            cloud.positions.push_back(sample.position);
            normals.push_back(sample.geometricNormal);
        }
        // The converged quadrature of Eq. 7 (cell_quadrature.h): E constant over each
        // sample's Voronoi cell, R_d (or each radial profile) integrated over the cells
        // near each vertex.
        const Stopwatch cellsStart;
        CellQuadratureOptions cellOptions;
        if (basis) cellOptions.gradedPiecesPerDistance = s.editable.cellGrading;
        const CellQuadrature cells(prepared.mesh, cloud.positions, normals, placed.summary.spacingMm, kernels,
                                   cellOptions);
        out.summary.cellSeconds = cellsStart.seconds();
        out.summary.cellSubPoints = cells.subPointCount();
        cloud.areas.assign(cells.cellAreas().begin(), cells.cellAreas().end());
        cloud.irradianceTransport = std::move(pass1Vectors);
        const SampleTree tree(std::move(cloud), s.pass2);
        std::vector<glm::vec3> positions;
        positions.reserve(prepared.myVertices);
        for (const IndexRange& r : prepared.vertexShares)
            positions.insert(positions.end(), prepared.mesh.positions.begin() + ptrdiff_t(r.begin),
                             prepared.mesh.positions.begin() + ptrdiff_t(r.end));
        Progress p("pass 2 (multiple scattering" + std::string(basis ? ", radial profiles" : "") + ")" + job.share,
                   prepared.myVertices, "vertices");
        // In chunks of vertices, each moved into the file's quantized arrays at once: the
        // float vectors of one chunk, not of the whole mesh, are held beside them.
        const std::span<const glm::vec3> all(positions);
        double nodesVisited = 0.0, retained = 0.0;
        const size_t chunkVertices = std::max<size_t>(s.pass2ChunkVertices, 1);
        for (size_t first = 0; first < all.size(); first += chunkVertices) {
            const size_t count = std::min(chunkVertices, all.size() - first);
            MultipleScatteringStats chunk;
            const std::vector<SparseVector> transport = multipleScatteringTransport(
                tree, all.subspan(first, count), kernels, s.pass2, texelCount, &chunk, &p, &cells);
            appendPass2Vectors(transport, basis.has_value(), kernels.count(), out.components);
            nodesVisited += chunk.meanNodesVisited * double(count);
            retained += chunk.retainedEnergyFraction * double(count);
        }
        if (!all.empty()) {
            stats.meanNodesVisited = nodesVisited / double(all.size());
            stats.retainedEnergyFraction = retained / double(all.size());
        }
        out.busySeconds = start.seconds();
    });
    // Means over the vertices computed (all ranks'; a shard's own range).
    const size_t computed = prepared.summary.computedVertices;
    const double vertexWeight = computed ? double(prepared.myVertices) / double(computed) : 0.0;
    out.summary.meanNodesVisited = dist.sum(stats.meanNodesVisited * vertexWeight);
    out.summary.retainedEnergy = dist.sum(stats.retainedEnergyFraction * vertexWeight);

    const Stopwatch gatherStart;
    for (TransportComponent& c : out.components)
        c.vectors = dist.gatherVertices(std::move(c.vectors), prepared.mesh.vertexCount());
    out.summary.gatherSeconds = gatherStart.seconds();
    if (basis) out.radialBasis = StoredRadialBasis{basis->range(), basis->tables()};
    out.summary.seconds = start.seconds();
    // After the gather: the file's arrays and the last chunk's float vectors have both been held.
    out.summary.peakMemoryBytes = peakMemoryBytes();
    return out;
}

SingleScatteringOutput runSingleScattering(const JobContext& job, const PreparedJob& prepared) {
    const PrecomputeSettings& s = job.settings;
    Distribution& dist = job.distribution;
    SingleScatteringOutput out;
    SingleScatteringSummary& summary = out.summary;
    std::optional<PhaseFactorization> phase;
    std::optional<RayScene> scene;
    std::optional<SingleScatteringContext> context;
    SingleScatteringResult result;
    VertexRanges ranges;
    for (const IndexRange& r : prepared.vertexShares) ranges.push_back({r.begin, r.end});
    const auto appendVertex = [&](size_t, const std::vector<SparseVector>& vectors) {
        for (size_t k = 0; k < vectors.size(); ++k) out.components[k].vectors.appendVertex(vectors[k].index, vectors[k].value);
    };
    // MPI ranks share the sites: each computes its share of all of them, they exchange
    // them, and each blends its own vertices. A shard or a single process computes the
    // sites its vertices blend (all of them for a whole mesh).
    const bool shareSites = dist.ranks() > 1 && s.singleScattering.siteSpacing > 0.0;
    SingleScatteringSites sites;
    SingleScatteringStats siteStats;
    std::vector<SparseVector> mySites;  // [site of my share][term]
    std::string label;
    dist.stage([&] {
        // Isotropic for g = 0, else the K-term SVD of HG(g) (phase_factoring.h).
        if (s.material.g != 0.0) {
            const Stopwatch phaseStart;
            phase = factorPhaseFunction(s.material.g, s.phase);
            summary.phaseSeconds = phaseStart.seconds();
            summary.phaseRmsError = phaseApproximationError(*phase, s.phase.terms);
            out.derived.push_back({"phase_rms_error", fmt(summary.phaseRmsError)});
        }
        // Its own scene with robust traversal, traced in coherent packets (fewer rays slip
        // through shared edges; docs/single-scattering.md, "Speed").
        scene.emplace(prepared.mesh, RaySceneOptions{RayBuildQuality::High, true});
        context.emplace(*scene, prepared.mesh, s.material, phase ? &*phase : nullptr, s.singleScattering);
        const int terms = context->terms();
        out.components.resize(size_t(terms));
        for (int k = 0; k < terms; ++k) {
            TransportComponent& c = out.components[size_t(k)];
            c.kind = context->isotropic() ? ComponentKind::SingleScatteringIsotropic : ComponentKind::SingleScatteringTerm;
            c.term = context->isotropic() ? 0 : uint32_t(k);
            c.vectors.reserve(prepared.myVertices, prepared.myVertices * s.vertexCoefficients);
        }
        label = context->isotropic() ? "single scattering (isotropic)"
                                     : "single scattering (" + std::to_string(terms) + " terms)";
        if (shareSites) {
            const Stopwatch siteStart;
            sites = chooseSingleScatteringSites(prepared.mesh.positions, prepared.mesh.normals,
                                                s.singleScattering.siteSpacing);
            std::vector<uint32_t> numbers;
            for (const IndexRange& r : dist.sharedWorkShares(sites.site.size()))
                for (size_t i = r.begin; i < r.end; ++i) numbers.push_back(uint32_t(i));
            Progress p(label + ", sites" + job.share, numbers.size(), "sites");
            for (std::vector<SparseVector>& v : computeSiteTransport(*context, sites, numbers, siteStats, &p, numbers.size()))
                for (SparseVector& t : v) mySites.push_back(std::move(t));
            out.busySeconds = siteStart.seconds();
            return;
        }
        Progress p(label + job.share, prepared.myVertices, "vertices");
        // All of this process's shares in one call, so the sites they share are computed once.
        result = computeSingleScattering(*context, appendVertex, &p, ranges);
        out.busySeconds = result.seconds;
    });
    if (shareSites) {
        const Stopwatch exchangeStart;
        const size_t terms = out.components.size();
        // What MpiDistribution::gatherSharedWork sends: the channel count, two 8-byte
        // counts and 16 bytes per RGB entry.
        double exchangeBytes = 0;
        for (const SparseVector& v : mySites) exchangeBytes += 20 + 16 * double(v.size());
        std::vector<SparseVector> all = dist.gatherSharedWork(std::move(mySites), sites.site.size(), terms);
        const double exchangeSeconds = exchangeStart.seconds();
        summary.siteExchangeBytes = dist.sum(exchangeBytes);
        summary.siteExchangeSeconds = exchangeSeconds;
        dist.stage([&] {
            const Stopwatch blendStart;
            std::vector<std::vector<SparseVector>> vectors(sites.site.size());
            std::vector<uint32_t> held(sites.site.size());
            for (size_t i = 0; i < vectors.size(); ++i) {
                held[i] = uint32_t(i);
                for (size_t k = 0; k < terms; ++k) vectors[i].push_back(std::move(all[i * terms + k]));
            }
            all = {};
            Progress p(label + ", blend" + job.share, prepared.myVertices, "vertices");
            result = blendSiteTransport(*context, sites, held, vectors, appendVertex, &p, ranges);
            result.stats.add(siteStats);
            result.seconds += out.busySeconds + exchangeSeconds;
            out.busySeconds += blendStart.seconds();
        });
    }
    // The scene, the context and the sites are done with: not held while rank 0 gathers.
    context.reset();
    scene.reset();
    sites = {};
    const Stopwatch gatherStart;
    for (TransportComponent& c : out.components)
        c.vectors = dist.gatherVertices(std::move(c.vectors), prepared.mesh.vertexCount());
    summary.gatherSeconds = gatherStart.seconds();
    if (phase) {
        ViewMaps maps;
        maps.size = phase->mapSize;
        maps.terms = result.terms;
        for (const Cubemap& h : phase->viewMaps) maps.data.insert(maps.data.end(), h.data().begin(), h.data().end());
        out.viewMaps = std::move(maps);
    }
    summary.terms = result.terms;
    summary.isotropic = result.isotropic;
    summary.seconds = result.seconds;
    const SingleScatteringStats& st = result.stats;
    const auto total = [&](uint64_t v) { return uint64_t(dist.sum(double(v))); };
    summary.rays = total(st.rays());
    summary.exitRays = total(st.exitRays);
    summary.occlusionRays = total(st.occlusionRays);
    summary.occludedExits = total(st.occludedExits);
    summary.culledRays = total(st.culledRays);
    summary.tracedTexels = total(st.tracedTexels);
    summary.interpolatedTexels = total(st.interpolatedTexels);
    summary.sites = total(st.sites);
    summary.siteSpacing = s.singleScattering.siteSpacing;
    summary.splitsByStake = total(st.splitsByStake);
    summary.splitsByThroughput = total(st.splitsByThroughput);
    summary.splitsByExitKind = total(st.splitsByExitKind);
    summary.reversedHits = total(st.reversedHits);
    summary.outsideSamples = total(st.outsideSamples);
    summary.flippedNormals = total(st.flippedNormals);
    summary.escapedRays = total(st.escapedRays);
    summary.cappedDepths = total(st.cappedDepths);
    summary.raysPerSecond = result.seconds > 0 ? double(summary.rays) / result.seconds : 0.0;
    const size_t computed = prepared.summary.computedVertices;
    // d_m is found once per computed point (a site, or every vertex without sites).
    summary.meanDepthMm = summary.sites ? dist.sum(st.depthSum) / double(summary.sites) : 0.0;
    summary.retainedEnergy =
        computed ? dist.sum(result.retainedEnergyFraction * double(prepared.myVertices)) / double(computed) : 1.0;
    summary.peakMemoryBytes = peakMemoryBytes();
    return out;
}

WriteOutput writeTransport(const JobContext& job, const PreparedJob& prepared,
                           std::vector<TransportComponent> components, std::optional<ViewMaps> viewMaps,
                           std::optional<StoredRadialBasis> radialBasis, ParameterList derived) {
    const PrecomputeSettings& s = job.settings;
    Distribution& dist = job.distribution;
    WriteOutput out;
    dist.stage([&] {
        if (!dist.writes()) return;
        TransportFile file;
        file.cubemapSize = uint32_t(s.cubemapSize);
        file.shTerms = uint32_t(s.shTerms);
        file.mesh = prepared.fingerprint;
        file.mmPerUnit = prepared.mmPerUnit;
        file.parameters = prepared.parameters;
        file.components = std::move(components);
        file.viewMaps = std::move(viewMaps);
        file.radialBasis = std::move(radialBasis);
        if (s.foldSingleScattering) foldSingleScattering(file.components, s.vertexCoefficients, file.shIndexBegin());
        // A shard stays per vertex: prt-merge blocks the whole file (the same bytes).
        if (s.blockCoefficients > 0 && !s.shard) {
            // The joint choice needs every vertex's vectors: after the gather, on the writer.
            const Stopwatch blockStart;
            out.blockRetainedEnergy =
                blockTransportComponents(file, s.blockCoefficients, prepared.mesh.positions);
            out.blockSeconds = blockStart.seconds();
            derived.push_back({kBlockRetainedEnergyParameter, fmt(out.blockRetainedEnergy)});
        }
        const ParameterList shard = dist.outputParameters(prepared.mesh.vertexCount());
        derived.insert(derived.end(), shard.begin(), shard.end());
        file.parameters.insert(file.parameters.end() - 1, derived.begin(), derived.end());
        const Stopwatch writeStart;
        // A cancel that came after the last progress step still writes nothing.
        Progress::throwIfCancelled();
        saveTransportFile(s.outputPath, file);
        out.summary.seconds = writeStart.seconds();
        out.summary.fileBytes = std::filesystem::file_size(s.outputPath);
    });
    return out;
}

GroundSummary writeGroundTransport(const JobContext& job, const PreparedJob& prepared) {
    const PrecomputeSettings& s = job.settings;
    GroundSummary out;
    if (!prepared.ground || !job.distribution.writes()) return out;
    const Stopwatch start;
    out.path = groundTransportPath(s.outputPath);
    DiffuseBaselineOptions o;
    o.albedo = s.ground->albedo;
    o.cubemapSize = s.cubemapSize;
    o.shTerms = s.shTerms;
    o.coefficients = s.vertexCoefficients;
    o.supersample = s.pass1.supersample;
    o.sampling = s.pass1.sampling;
    out.vertices = size_t(prepared.ground->cells + 1) * size_t(prepared.ground->cells + 1);
    Progress progress("ground: vertices", out.vertices);
    const TransportFile file =
        groundTransport(*prepared.ground, *prepared.scene, prepared.fingerprint, o,
                        {{"input_digest", prepared.parameters.back().second}}, &progress);
    progress.finish();
    saveTransportFile(out.path, file);
    out.rays = std::stoull(file.parameter("rays_traced"));
    out.seconds = start.seconds();
    return out;
}

}  // namespace prt
