#pragma once
// One worker thread that computes the newest request, off the viewer's UI thread: the
// pattern of both of the viewer's workers (relight_worker.h, point_light_worker.h;
// docs/viewer.md, "How it works").
//
// Contract: submit() replaces any request not yet started (the latest wins); take()
// hands over the newest finished result, if any, and rethrows a failure of the worker
// as prt::Error(subject, what), the worker then having stopped. Results are
// triple-buffered by swapping (work -> ready -> the caller's), so nothing is
// reallocated once the sizes are reached. post() queues a job run on the same thread
// when no request is pending (requests first; a newer job replaces one not yet
// started). `compute` runs on the worker's thread only, one call at a time; whatever it
// reads must outlive the worker. The thread starts in the constructor; the destructor
// stops it after the request or job in progress.

#include <condition_variable>
#include <exception>
#include <functional>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <utility>

#include "common/error.h"

namespace prt {

template <class Request, class Result>
class LatestRequestWorker {
public:
    using Compute = std::function<void(const Request&, Result&)>;

    LatestRequestWorker(std::string subject, Compute compute)
        : subject_(std::move(subject)), compute_(std::move(compute)), thread_([this] { run(); }) {}
    ~LatestRequestWorker() {
        {
            std::lock_guard<std::mutex> lock(mutex_);
            stop_ = true;
        }
        cv_.notify_all();
        thread_.join();
    }
    LatestRequestWorker(const LatestRequestWorker&) = delete;
    LatestRequestWorker& operator=(const LatestRequestWorker&) = delete;

    void submit(const Request& r) {
        {
            std::lock_guard<std::mutex> lock(mutex_);
            pending_ = r;
        }
        cv_.notify_all();
    }

    void post(std::function<void()> job) {
        {
            std::lock_guard<std::mutex> lock(mutex_);
            job_ = std::move(job);
        }
        cv_.notify_all();
    }

    // A request queued and not yet started (a long job checks it to give way).
    bool requestPending() const {
        std::lock_guard<std::mutex> lock(mutex_);
        return pending_.has_value();
    }

    // A request or job queued or running.
    bool busy() const {
        std::lock_guard<std::mutex> lock(mutex_);
        return pending_.has_value() || job_ != nullptr || running_;
    }

    // Swaps the newest finished result into `out`; throws the worker's error, if any.
    bool take(Result& out) {
        std::lock_guard<std::mutex> lock(mutex_);
        if (!error_.empty()) throw Error(subject_, error_);
        if (!haveReady_) return false;
        std::swap(out, ready_);
        haveReady_ = false;
        return true;
    }

private:
    void run() {
        for (;;) {
            std::optional<Request> request;
            std::function<void()> job;
            {
                std::unique_lock<std::mutex> lock(mutex_);
                cv_.wait(lock, [&] { return stop_ || pending_.has_value() || job_ != nullptr; });
                if (stop_) return;
                if (pending_) {
                    request = std::move(pending_);
                    pending_.reset();
                } else {
                    job = std::move(job_);
                    job_ = nullptr;
                }
                running_ = true;
            }
            try {
                if (request) {
                    compute_(*request, work_);
                    std::lock_guard<std::mutex> lock(mutex_);
                    std::swap(work_, ready_);
                    haveReady_ = true;
                    running_ = false;
                } else {
                    job();
                    std::lock_guard<std::mutex> lock(mutex_);
                    running_ = false;
                }
            } catch (const std::exception& e) {
                std::lock_guard<std::mutex> lock(mutex_);
                error_ = e.what();
                running_ = false;
                return;
            }
        }
    }

    const std::string subject_;
    const Compute compute_;
    mutable std::mutex mutex_;
    std::condition_variable cv_;
    std::optional<Request> pending_;
    std::function<void()> job_;
    bool running_ = false, stop_ = false, haveReady_ = false;
    std::string error_;
    Result work_, ready_;
    std::thread thread_;  // last: started once everything above exists
};

}  // namespace prt
