#pragma once
// prt-precompute --summary-json (docs/precompute.md, "Summary as JSON"): a job's
// PrecomputeSummary (every field; fields of a stage that did not run are null), its
// settings, the command line and the machine's state.

#include <nlohmann/json.hpp>

#include <string>

#include "precompute/job/settings.h"
#include "precompute/job/summary.h"

namespace prt {

using Json = nlohmann::ordered_json;

Json settingsJson(const PrecomputeSettings& s);
Json summaryJson(const PrecomputeSummary& r);
// {"settings": ..., "summary": ...}
Json jobJson(const PrecomputeSettings& settings, const PrecomputeSummary& summary);
// The document's common head: tool, command, UTC time, machine (threads, load average).
Json runJson(const std::string& command);
// The 1, 5 and 15 minute load averages, or null.
Json loadAverage();
// The command line as one string, arguments with shell-special characters quoted.
std::string commandLine(int argc, char** argv);

// Throws prt::Error(path, ...) now, before a long job, when the JSON could not be
// written at the end.
void checkJsonPath(const std::string& path);
// Pretty-printed, written atomically (common/atomic_file.h).
void writeJsonAtomically(const std::string& path, const Json& doc);

}  // namespace prt
