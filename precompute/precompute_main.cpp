// prt-precompute: mesh + material in, transport file out (docs/precompute.md).
// Thin: parses options (from the command line or a JSON job file) into
// PrecomputeSettings and calls precomputeTransport().

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <fcntl.h>
#include <unistd.h>

#include <cstdio>
#include <string>
#include <vector>

#include "common/error.h"
#include "common/options.h"
#include "common/progress.h"
#include "precompute/job/job_options.h"
#include "precompute/job/mpi_distribution.h"
#include "precompute/job/pipeline.h"
#include "precompute/job/summary_json.h"

using namespace prt;

namespace {

// Under MPI only rank 0 speaks: the other ranks' progress, summaries and (identical,
// see Distribution::stage) error lines would repeat rank 0's.
void silenceOtherRanks(const Distribution* dist) {
    if (!dist || dist->rank() == 0) return;
    Progress::setQuiet(true);
    const int null = open("/dev/null", O_WRONLY);
    if (null < 0) return;
    std::fflush(stdout);
    std::fflush(stderr);
    dup2(null, STDOUT_FILENO);
    dup2(null, STDERR_FILENO);
    close(null);
}

int runJobFile(const std::string& path, bool force, const std::string& summaryJsonPath,
               const std::string& command, Distribution* dist) {
    const JobFile file = loadJobFile(path);
    const nlohmann::json& defaults = file.defaults;
    const nlohmann::json& jobs = file.jobs;
    int failed = 0, skipped = 0, done = 0;
    Json report = runJson(command);
    report["job_file"] = path;
    Json results = Json::array();
    for (size_t i = 0; i < jobs.size(); ++i) {
        const std::string where = path + ": job " + std::to_string(i + 1);
        // On stdout with the summaries: stderr holds only progress and the one-line errors.
        std::printf("== job %zu/%zu ==\n", i + 1, jobs.size());
        std::fflush(stdout);
        Json result;
        result["job"] = i + 1;
        result["load_average_start"] = loadAverage();
        try {
            if (!jobs[i].is_object()) throw Error(where, "a job must be an object");
            const PrecomputeSettings settings = parseJob(defaults, jobs[i], where);
            result["settings"] = settingsJson(settings);
            PrecomputeSummary summary = precomputeTransport(settings, force, dist);
            std::printf("%s", summary.format().c_str());
            std::fflush(stdout);
            result["summary"] = summaryJson(summary);
            (summary.skipped ? skipped : done)++;
        } catch (const std::exception& e) {
            std::fprintf(stderr, "prt-precompute: error: %s\n", e.what());
            result["error"] = e.what();
            ++failed;
        }
        result["load_average_end"] = loadAverage();
        results.push_back(std::move(result));
    }
    std::printf("jobs: %d computed, %d up to date, %d failed (of %zu)\n", done, skipped, failed,
                jobs.size());
    if (!summaryJsonPath.empty() && (!dist || dist->writes())) {
        report["machine"]["load_average_end"] = loadAverage();
        report["computed"] = done;
        report["up_to_date"] = skipped;
        report["failed"] = failed;
        report["jobs"] = std::move(results);
        writeJsonAtomically(summaryJsonPath, report);
        std::printf("summary: %s\n", summaryJsonPath.c_str());
    }
    return failed ? 1 : 0;
}

}  // namespace

int main(int argc, char** argv) {
    // Under mpirun / srun: MPI_Init here, MPI_Finalize when the session ends. The body's
    // errors are printed by the INNER runMain, while the session is still alive: a rank
    // that exits non-zero makes mpirun kill the others, so rank 0's error line must be
    // out before MPI_Finalize (a synchronisation) lets the other ranks exit: with one
    // runMain the session's destructor would run during the unwinding, before the line
    // is printed, and mpirun could kill rank 0 first. The outer runMain reports a
    // session that cannot start (an MPI launch of a build without MPI).
    return runMain("prt-precompute", [&]() -> int {
      MpiSession mpi(argc, argv);
      return runMain("prt-precompute", [&]() -> int {
        Distribution* dist = mpi.distribution();
        silenceOtherRanks(dist);
        CLI::App app{
            "prt-precompute: precompute translucent light transport (dipole multiple scattering,\n"
            "single scattering) into per-vertex Haar wavelet vectors. Examples:\n"
            "  prt-precompute data/meshes/bunny.off --size-mm 30 --material Marble -o out/bunny.prt\n"
            "  prt-precompute data/meshes/bunny.off --components ms,ss --g 0.25 --phase-terms 4 -o b.prt\n"
            "  prt-precompute --jobs jobs.json\n"
            "  mpirun -np 4 prt-precompute mesh.ply -o out.prt          (MPI ranks, docs/cluster.md)\n"
            "  prt-precompute mesh.ply --shard 1/4 -o part1.prt; prt-merge -o out.prt part*.prt"};
        JobOptions raw;
        PrecomputeSettings settings;
        addJobOptions(app, raw, settings);
        std::string jobFile, summaryJsonPath, baseline;
        std::vector<double> albedo{0.8};
        app.add_option("--baseline", baseline,
                       "Instead of translucency, the baseline the papers compare it with: diffuse-brdf, a shadowed "
                       "Lambertian PRT of the same mesh (albedo / pi x visibility x cosine per vertex; "
                       "docs/precompute.md, \"The diffuse baseline\"); every renderer relights the file as usual")
            ->check(CLI::IsMember({"diffuse-brdf"}))->group("Baseline");
        app.add_option("--albedo", albedo, "Baseline only: the Lambertian reflectance, one value or R,G,B in [0, 1]")
            ->delimiter(',')->expected(1, 3)->capture_default_str()->group("Baseline");
        bool force = false, quiet = false;
        int threads = 0;
        app.add_option("--jobs", jobFile, "JSON job file: {\"defaults\": {...}, \"jobs\": [{...}, ...]}");
        app.add_option("--summary-json", summaryJsonPath,
                       "Also write the summary (every field, settings, per-stage times and peak "
                       "memory) as JSON to this file (atomically); with --jobs one document for all jobs");
        app.add_flag("-f,--force", force, "Recompute even when the output is up to date");
        addThreadsOption(app, threads);
        app.add_flag("-q,--quiet", quiet, "No progress display");
        if (const auto exitCode = parseCommandLine(app, argc, argv, "prt-precompute")) return *exitCode;
        if (quiet) Progress::setQuiet(true);
        const ThreadLimit limit(threads);
        if (!summaryJsonPath.empty()) checkJsonPath(summaryJsonPath);
        const std::string command = commandLine(argc, argv);
        if (baseline.empty() && app.count("--albedo")) throw Error("--albedo", "only with --baseline diffuse-brdf");
        if (!baseline.empty() && !jobFile.empty()) throw Error("--baseline", "not in job files (give a mesh)");
        if (!jobFile.empty()) return runJobFile(jobFile, force, summaryJsonPath, command, dist);
        if (raw.mesh.empty()) throw Error("prt-precompute", "no mesh given (see --help)");
        if (raw.output.empty() && !settings.pass1Only) throw Error("--output", "no output path given (see --help)");
        if (!baseline.empty() && !raw.blockCoefficients) raw.blockCoefficients = 0;  // per-vertex vectors
        const PrecomputeSettings job = settingsFromOptions(raw, settings);
        if (!baseline.empty()) {
            if (albedo.size() == 2) throw Error("--albedo", "give one value or three (R,G,B)");
            if (dist && dist->partial()) throw Error("--baseline", "runs in one process (not under mpirun)");
            if (!summaryJsonPath.empty()) throw Error("--summary-json", "not with --baseline (it prints one line)");
            if (job.blockCoefficients > 0) throw Error("--block-coefficients", "not with --baseline (per-vertex vectors)");
            if (job.ground) throw Error("--ground", "not with --baseline (precompute the object with --ground)");
            const glm::dvec3 a = albedo.size() == 3 ? glm::dvec3(albedo[0], albedo[1], albedo[2]) : glm::dvec3(albedo[0]);
            precomputeDiffuseBaseline(job, a);
            return 0;
        }
        Json report = runJson(command);
        PrecomputeSummary summary = precomputeTransport(job, force, dist);
        std::printf("%s", summary.format().c_str());
        if (!summaryJsonPath.empty() && (!dist || dist->writes())) {
            report["machine"]["load_average_end"] = loadAverage();
            const Json j = jobJson(job, summary);
            for (auto it = j.begin(); it != j.end(); ++it) report[it.key()] = it.value();
            writeJsonAtomically(summaryJsonPath, report);
            std::printf("summary: %s\n", summaryJsonPath.c_str());
        }
        return 0;
      });
    });
}
