#include "common/progress.h"

#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <deque>
#include <vector>

namespace prt {

namespace {
int& enabledOverride() {
    static int value = -1;  // -1: detect, 0: off, 1: on
    return value;
}
}  // namespace

void Progress::setEnabled(bool enabled) { enabledOverride() = enabled ? 1 : 0; }

namespace {
std::atomic<bool>& quietFlag() {
    static std::atomic<bool> quiet{false};
    return quiet;
}
}  // namespace

void Progress::setQuiet(bool quiet) { quietFlag() = quiet; }

namespace {

std::atomic<bool> cancelFlag{false};

// The unfinished Progress objects in order of construction, for snapshot().
struct Registry {
    std::mutex mutex;
    std::vector<const Progress*> live;
    std::deque<ProgressSnapshot> finished;  // the last kKeptFinished, oldest first
    uint64_t made = 0;
};
constexpr size_t kKeptFinished = 64;
Registry& registry() {
    static Registry r;
    return r;
}

}  // namespace

void Progress::requestCancel(bool cancel) { cancelFlag.store(cancel); }
bool Progress::cancelRequested() { return cancelFlag.load(std::memory_order_relaxed); }

void Progress::throwIfCancelled() {
    if (cancelRequested()) throw Cancelled();
}

ProgressSnapshot Progress::snapshotLocked() const {
    ProgressSnapshot s;
    s.active = true;
    s.label = label_;
    s.unit = unit_;
    s.done = done_.load(std::memory_order_relaxed);
    s.total = total_;
    s.elapsedSeconds = elapsedSeconds();
    s.stage = stage_;
    return s;
}

ProgressSnapshot Progress::snapshot() {
    Registry& r = registry();
    std::lock_guard lock(r.mutex);
    if (r.live.empty()) return {};
    return r.live.back()->snapshotLocked();
}

uint64_t Progress::stagesMade() {
    Registry& r = registry();
    std::lock_guard lock(r.mutex);
    return r.made;
}

std::vector<ProgressSnapshot> Progress::finishedAfter(uint64_t stage) {
    Registry& r = registry();
    std::lock_guard lock(r.mutex);
    std::vector<ProgressSnapshot> out;
    for (const ProgressSnapshot& s : r.finished)
        if (s.stage > stage) out.push_back(s);
    return out;
}

std::string formatDuration(double s) {
    char buf[64];
    if (!std::isfinite(s) || s < 0) return "?";
    if (s < 60) {
        std::snprintf(buf, sizeof buf, "%.1f s", s);
    } else if (s < 3600) {
        std::snprintf(buf, sizeof buf, "%d min %02d s", int(s) / 60, int(s) % 60);
    } else {
        std::snprintf(buf, sizeof buf, "%d h %02d min", int(s) / 3600, (int(s) / 60) % 60);
    }
    return buf;
}

Progress::Progress(std::string label, uint64_t total, std::string unit)
    : label_(std::move(label)),
      unit_(std::move(unit)),
      total_(total),
      start_(std::chrono::steady_clock::now()) {
    int override = enabledOverride();
    interactive_ = !quietFlag() && (override >= 0 ? override == 1 : isatty(STDERR_FILENO) == 1);
    Registry& r = registry();
    std::lock_guard lock(r.mutex);
    stage_ = ++r.made;
    r.live.push_back(this);
}

Progress::~Progress() {
    if (!finished_) finish();
    Registry& r = registry();
    std::lock_guard lock(r.mutex);
    std::erase(r.live, this);
    ProgressSnapshot s = snapshotLocked();
    s.active = false;
    r.finished.push_back(std::move(s));
    if (r.finished.size() > kKeptFinished) r.finished.pop_front();
}

double Progress::elapsedSeconds() const {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
}

void Progress::advance(uint64_t n) {
    if (cancelFlag.load(std::memory_order_relaxed)) throw Cancelled();
    uint64_t done = done_.fetch_add(n, std::memory_order_relaxed) + n;
    if (!interactive_) return;
    int64_t now = std::chrono::duration_cast<std::chrono::nanoseconds>(
                      std::chrono::steady_clock::now() - start_).count();
    int64_t last = lastDrawNs_.load(std::memory_order_relaxed);
    if (now - last < 200'000'000) return;
    if (!lastDrawNs_.compare_exchange_strong(last, now)) return;
    redraw(done);
}

void Progress::redraw(uint64_t done) {
    std::lock_guard lock(drawMutex_);
    double t = elapsedSeconds();
    double rate = t > 0 ? done / t : 0;
    double frac = total_ ? double(done) / double(total_) : 1.0;
    double eta = rate > 0 ? (double(total_) - double(done)) / rate : NAN;
    std::fprintf(stderr, "\r\033[K%s: %llu/%llu %s (%.1f%%) %.3g %s/s, ETA %s", label_.c_str(),
                 (unsigned long long)done, (unsigned long long)total_, unit_.c_str(), 100 * frac,
                 rate, unit_.c_str(), formatDuration(eta).c_str());
    std::fflush(stderr);
}

double Progress::finish() {
    std::lock_guard lock(drawMutex_);
    finished_ = true;
    double t = elapsedSeconds();
    uint64_t done = done_.load();
    double rate = t > 0 ? done / t : 0;
    if (interactive_) std::fprintf(stderr, "\r\033[K");
    if (quietFlag()) return t;
    std::fprintf(stderr, "%s: %llu %s in %s (%.3g %s/s)\n", label_.c_str(),
                 (unsigned long long)done, unit_.c_str(), formatDuration(t).c_str(), rate,
                 unit_.c_str());
    return t;
}

}  // namespace prt
