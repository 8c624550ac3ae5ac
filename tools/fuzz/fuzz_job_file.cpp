// Fuzz target: the job-file parser of prt-precompute --jobs (precompute/job/job_options.h:
// loadJobFile, then parseJob of every job against the defaults, as runJobFile does, but
// without running them).
//
// Oracle: a parsed job has a mesh and an output path (the options every job needs)
// and passes settingsFromOptions' checks, which parseJob ends with.

#include <cstdint>

#include "common/error.h"
#include "precompute/job/job_options.h"
#include "tools/fuzz/fuzz_support.h"

using namespace prt;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    const std::string path = fuzz::writeInput(data, size, ".json");
    JobFile file;
    bool loaded = false;
    fuzz::expectErrors([&] {
        file = loadJobFile(path);
        loaded = true;
    });
    if (!loaded) return 0;
    fuzz::require(file.jobs.is_array(), "jobs is an array");
    for (size_t i = 0; i < file.jobs.size() && i < 64; ++i) {
        fuzz::expectErrors([&] {
            if (!file.jobs[i].is_object()) throw Error("job", "a job must be an object");
            const PrecomputeSettings s = parseJob(file.defaults, file.jobs[i], "job " + std::to_string(i + 1));
            (void)s;
        });
    }
    return 0;
}
