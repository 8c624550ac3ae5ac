#pragma once
// Progress reporting for long stages: a single status line on stderr with count,
// percentage, rate and ETA, redrawn at most ~5 times a second. When stderr is not a
// terminal (CI, logs) it stays quiet until finish(), which always prints one summary
// line. advance() is thread-safe and cheap (one atomic add) so worker threads call it.

#include <atomic>
#include <chrono>
#include <cstdint>
#include <mutex>
#include <string>
#include <vector>

#include "common/error.h"

namespace prt {

// Thrown by Progress::advance() once a cancel was requested (Progress::requestCancel):
// the long stage unwinds like any other error, so nothing half-written is left (every
// output is written to a temporary file and renamed).
class Cancelled : public Error {
public:
    Cancelled() : Error("", "cancelled") {}
};

// What the newest unfinished Progress has done (Progress::snapshot).
struct ProgressSnapshot {
    bool active = false;  // false: no stage is reporting
    std::string label, unit;
    uint64_t done = 0, total = 0;
    double elapsedSeconds = 0.0;
    uint64_t stage = 0;  // counts Progress objects made so far; a new stage has a new number
};

class Progress {
public:
    Progress(std::string label, uint64_t total, std::string unit = "items");
    ~Progress();  // calls finish() if not yet finished

    void advance(uint64_t n = 1);
    // Prints "<label>: <total> <unit> in <t> s (<rate> <unit>/s)" and returns seconds.
    double finish();
    double elapsedSeconds() const;

    // Overrides terminal detection (tests): false = never redraw, only finish()'s line.
    static void setEnabled(bool enabled);
    // --quiet: no progress output at all, not even finish()'s line (stderr then holds
    // only warnings and errors; the summaries on stdout report the stage times).
    static void setQuiet(bool quiet);

    // For a host that embeds the library (the Python module): polls what the newest
    // unfinished Progress has done, from any thread; and the last 64 finished ones whose
    // stage number is above `stage`, oldest first (a stage shorter than the host's
    // polling period is seen there).
    static ProgressSnapshot snapshot();
    static std::vector<ProgressSnapshot> finishedAfter(uint64_t stage);
    // How many Progress objects were made so far (the newest one's stage number).
    static uint64_t stagesMade();
    // While set, every advance() throws Cancelled (in a worker thread of a parallel
    // loop the loop stops and rethrows it in the caller). Clear it before the next run.
    static void requestCancel(bool cancel);
    static bool cancelRequested();
    // Throws Cancelled when a cancel was requested: for the last step before an output
    // is written, which no advance() may come before.
    static void throwIfCancelled();

private:
    void redraw(uint64_t done);

    std::string label_;
    std::string unit_;
    uint64_t total_;
    std::atomic<uint64_t> done_{0};
    std::atomic<int64_t> lastDrawNs_{0};
    std::chrono::steady_clock::time_point start_;
    std::mutex drawMutex_;
    bool interactive_;
    bool finished_ = false;
    uint64_t stage_ = 0;
    ProgressSnapshot snapshotLocked() const;
};

// "1.2 s", "3 min 4 s", "1 h 2 min"
std::string formatDuration(double seconds);

}  // namespace prt
