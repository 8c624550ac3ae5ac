#include "precompute/job/summary.h"

#include <cstdio>
#include <sstream>

#include "common/progress.h"

namespace prt {

namespace {

std::string megabytes(size_t bytes) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.0f MB", double(bytes) / 1e6);
    return buf;
}

}  // namespace

std::string PrecomputeSummary::format() const {
    std::ostringstream o;
    char line[256];
    auto add = [&](const char* f, auto... args) {
        std::snprintf(line, sizeof line, f, args...);
        o << line << '\n';
    };
    if (skipped) {
        add("%s: up to date (same mesh and settings), skipped", outputPath.c_str());
        return o.str();
    }
    const DistributionSummary& d = distribution;
    if (outputPath.empty())
        add("output            none (--pass1-only)");
    else if (d.ranks > 1)
        add("output            %s (%.2f MB), %d MPI ranks", outputPath.c_str(), write.fileBytes / 1e6, d.ranks);
    else if (d.description != "1 process")
        add("output            %s (%.2f MB), %s", outputPath.c_str(), write.fileBytes / 1e6, d.description.c_str());
    else
        add("output            %s (%.2f MB)", outputPath.c_str(), write.fileBytes / 1e6);
    if (!ground.path.empty())
        add("ground            %s: %zu vertices, %.3g rays, %s", ground.path.c_str(), ground.vertices,
            double(ground.rays), formatDuration(ground.seconds).c_str());
    add("mesh              %zu vertices, %zu triangles, %.1f mm^2", setup.vertices, setup.triangles,
        setup.totalAreaMm2);
    if (components.multipleScattering) {
        add("samples           %zu (spacing %.3f mm), %s", samples.count, samples.spacingMm,
            formatDuration(samples.seconds).c_str());
        if (pass1.loaded)
            add("pass 1            loaded from %s in %s", pass1.file.c_str(), formatDuration(pass1.seconds).c_str());
        else
            add("pass 1            %s, %.3g rays, %.3g rays/s, retained energy %.4f%s%s",
                formatDuration(pass1.seconds).c_str(), double(pass1.rays), pass1.raysPerSecond,
                pass1.retainedEnergy, pass1.file.empty() ? "" : ", saved to ", pass1.file.c_str());
        if (!outputPath.empty()) {  // not with --pass1-only
            add("pass 2            %s, %.1f nodes visited per vertex, retained energy %.4f",
                formatDuration(pass2.seconds).c_str(), pass2.meanNodesVisited, pass2.retainedEnergy);
            add("  sample cells    %zu sub-points in %s", pass2.cellSubPoints,
                formatDuration(pass2.cellSeconds).c_str());
        }
    }
    if (blocks.coefficients > 0 && !outputPath.empty() && d.shard)
        add("blocks            %zu shared terms per 16 vertices, formed by prt-merge (the shard keeps %zu per vertex)",
            blocks.coefficients, blocks.sourceCoefficients);
    else if (blocks.coefficients > 0 && !outputPath.empty())
        add("blocks            16 nearby vertices share %zu terms chosen jointly from %zu per vertex, "
            "8-bit values: %s, retained energy %.4f",
            blocks.coefficients, blocks.sourceCoefficients, formatDuration(blocks.seconds).c_str(),
            blocks.retainedEnergy);
    if (d.ranks > 1) {
        add("exchange          pass-1 vectors %.3g MB in %s (%.0f bytes per sample), vertex "
            "vectors gathered in %s",
            pass1.exchangeBytes / 1e6, formatDuration(pass1.exchangeSeconds).c_str(),
            samples.count ? pass1.exchangeBytes / double(samples.count) : 0.0,
            formatDuration(gatherSeconds()).c_str());
        add("ranks busy        %s to %s (the even split's balance: %.0f%%)",
            formatDuration(d.busySecondsMin).c_str(), formatDuration(d.busySecondsMax).c_str(),
            d.busySecondsMax > 0 ? 100.0 * d.busySecondsMin / d.busySecondsMax : 100.0);
    }
    if (components.singleScattering && !outputPath.empty()) {
        const SingleScatteringSummary& s = singleScattering;
        if (s.isotropic)
            add("phase             isotropic (1/(4 pi) folded into one vector)");
        else
            add("phase             HG svd, %d terms, rms error %.4f, %s", s.terms, s.phaseRmsError,
                formatDuration(s.phaseSeconds).c_str());
        add("single scattering %s, %.3g rays, %.3g rays/s, retained energy %.4f",
            formatDuration(s.seconds).c_str(), double(s.rays), s.raysPerSecond, s.retainedEnergy);
        if (s.siteSpacing > 0 && s.siteExchangeBytes > 0)
            add("  sites           %llu, about %g mm apart, blended into the vertices; shared between the ranks: "
                "%.3g MB in %s",
                (unsigned long long)s.sites, s.siteSpacing, s.siteExchangeBytes / 1e6,
                formatDuration(s.siteExchangeSeconds).c_str());
        else if (s.siteSpacing > 0)
            add("  sites           %llu, about %g mm apart, blended into the vertices", (unsigned long long)s.sites,
                s.siteSpacing);
        add("  rays            %.3g exit, %.3g occlusion, %.3g culled (throughput), %.3g escaping, "
            "%.3g exits through reversed triangles, %.3g occluded exits",
            double(s.exitRays), double(s.occlusionRays), double(s.culledRays), double(s.escapedRays),
            double(s.reversedHits), double(s.occludedExits));
        if (s.interpolatedTexels > 0)
            add("  directions      %.3g traced, %.3g interpolated from agreeing corners (%.1f%% traced)",
                double(s.tracedTexels), double(s.interpolatedTexels),
                100.0 * double(s.tracedTexels) / double(s.tracedTexels + s.interpolatedTexels));
        if (s.splitsByStake + s.splitsByThroughput + s.splitsByExitKind > 0)
            add("  cells split     %.3g by light at stake (wide cells), %.3g by throughput spread, %.3g by "
                "exit kind", double(s.splitsByStake), double(s.splitsByThroughput), double(s.splitsByExitKind));
        add("  path            mean d_m %.3f mm, %llu points with capped d_m, %llu integrated "
            "along +n (normal pointing inward), %llu path samples outside the object",
            s.meanDepthMm, (unsigned long long)s.cappedDepths, (unsigned long long)s.flippedNormals,
            (unsigned long long)s.outsideSamples);
    }
    add("total             %s, peak memory %.0f MB, estimated %.0f MB for the job's data above the %.0f MB "
        "resident at its start (setup %s, write %s)",
        formatDuration(totalSeconds).c_str(), peakMemoryBytes / 1e6, setup.estimatedMemoryBytes / 1e6,
        startMemoryBytes / 1e6, formatDuration(setup.seconds).c_str(), formatDuration(write.seconds).c_str());
    // ru_maxrss only grows: each figure is the process's peak up to the end of that stage.
    std::string peaks = "peak memory so far after setup " + megabytes(setup.peakMemoryBytes);
    if (components.multipleScattering)
        peaks += ", samples " + megabytes(samples.peakMemoryBytes) + ", pass 1 " +
                 megabytes(pass1.peakMemoryBytes) + ", pass 2 " + megabytes(pass2.peakMemoryBytes);
    if (components.singleScattering)
        peaks += ", single scattering " + megabytes(singleScattering.peakMemoryBytes);
    o << "  " << peaks << '\n';
    return o.str();
}

}  // namespace prt
