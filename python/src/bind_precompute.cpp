// The precomputation from Python: prt-precompute's options as keyword arguments (the
// job-file route, so the names, defaults, checks and messages are the command line's),
// progress to a Python callable, Ctrl-C cancelling cleanly; and runCancellable, which
// does the last two for every long call.
//
// The job runs on a worker thread while the calling thread, without the GIL, waits for
// it in short steps; between steps it takes the GIL, reports progress and lets Python
// check for signals (only the main thread sees SIGINT). A KeyboardInterrupt, or an
// exception from the callable, requests a cancel (Progress::requestCancel): the job's
// next progress step throws, the passes unwind, and no output is written (the file is
// written to a temporary name and renamed only when complete).

#include <chrono>
#include <cstdio>
#include <exception>
#include <filesystem>
#include <future>
#include <mutex>
#include <optional>
#include <thread>

#include <unistd.h>

#include "common/options.h"
#include "common/progress.h"
#include "precompute/job/job_options.h"
#include "precompute/job/pipeline.h"
#include "precompute/job/summary_json.h"
#include "python/src/bindings.h"

namespace prt::python {

namespace {

nlohmann::json jsonValue(const py::handle& value, const std::string& key) {
    if (py::isinstance<py::bool_>(value)) return value.cast<bool>();
    if (py::isinstance<py::int_>(value)) return value.cast<long long>();
    if (py::isinstance<py::float_>(value)) return value.cast<double>();
    if (py::isinstance<py::str>(value)) return value.cast<std::string>();
    if (py::isinstance<py::list>(value) || py::isinstance<py::tuple>(value) || py::isinstance<py::array>(value)) {
        nlohmann::json array = nlohmann::json::array();
        for (const py::handle& item : value) {
            if (!py::isinstance<py::int_>(item) && !py::isinstance<py::float_>(item) &&
                !py::isinstance<py::array>(item))
                throw py::type_error(key + ": expected numbers in the list");
            try {
                array.push_back(item.cast<double>());
            } catch (const py::cast_error&) {
                throw py::type_error(key + ": expected numbers in the list");
            }
        }
        return array;
    }
    throw py::type_error(key + ": expected a string, a number, a bool or a list of numbers, got " +
                         std::string(py::str(value.get_type().attr("__name__"))));
}

py::object jsonToPython(const nlohmann::json& j) {
    return py::module_::import("json").attr("loads")(j.dump());
}

// Reports every stage to `callback(stage, done, total, unit)`: the newest unfinished
// one as it goes, and each finished one once more with its final count (also the
// stages that began and ended between two polls).
class ProgressRelay {
public:
    explicit ProgressRelay(py::object callback) : callback_(std::move(callback)) {}

    void poll() {
        if (callback_.is_none()) return;
        for (const ProgressSnapshot& f : Progress::finishedAfter(lastFinished_)) {
            if (f.stage <= firstStage_) continue;  // a stage of an earlier call
            callback_(f.label, f.done, f.total, f.unit);
            lastFinished_ = f.stage;
        }
        const ProgressSnapshot s = Progress::snapshot();
        if (s.active && s.stage > lastFinished_ && s.stage > firstStage_) callback_(s.label, s.done, s.total, s.unit);
    }

private:
    py::object callback_;
    // Stages up to this number were made before the call.
    uint64_t firstStage_ = Progress::stagesMade();
    uint64_t lastFinished_ = firstStage_;
};

// Restores the process-wide progress switches however the call ends.
struct ProgressSwitches {
    explicit ProgressSwitches(bool quiet) {
        Progress::requestCancel(false);
        if (quiet) Progress::setQuiet(true);
        quiet_ = quiet;
    }
    ~ProgressSwitches() {
        Progress::requestCancel(false);
        if (quiet_) Progress::setQuiet(false);
    }
    bool quiet_ = false;
};

std::string temporaryOutput() {
    const std::filesystem::path dir = std::filesystem::temp_directory_path();
    static int counter = 0;
    return (dir / ("prt_python_" + std::to_string(::getpid()) + "_" + std::to_string(++counter) + ".prt")).string();
}

}  // namespace

void runCancellable(const std::function<void()>& job, const py::object& progress, bool quiet, int threads) {
    if (!progress.is_none() && !PyCallable_Check(progress.ptr()))
        throw py::type_error("progress: expected a callable (stage, done, total, unit)");
    // The cancel flag, the quiet switch, the thread limit and the stage numbers are the
    // process's: one long call at a time (another Python thread's call waits here,
    // without the GIL).
    static std::mutex oneAtATime;
    std::unique_lock<std::mutex> turn(oneAtATime, std::defer_lock);
    {
        py::gil_scoped_release release;
        turn.lock();
    }
    ProgressSwitches switches(quiet);
    const ThreadLimit limit(threads);
    ProgressRelay relay(progress);
    std::promise<void> promise;
    std::future<void> done = promise.get_future();
    std::thread worker([&] {
        try {
            job();
            promise.set_value();
        } catch (...) {
            promise.set_exception(std::current_exception());
        }
    });
    auto wait = [&](std::chrono::milliseconds step) {
        py::gil_scoped_release release;
        return done.wait_for(step) == std::future_status::ready;
    };
    try {
        while (!wait(std::chrono::milliseconds(100))) {
            relay.poll();
            if (PyErr_CheckSignals() != 0) throw py::error_already_set();
        }
        relay.poll();
    } catch (...) {
        // A KeyboardInterrupt or the callable's own exception: stop the job, then raise
        // it (the worker's Cancelled is not reported).
        Progress::requestCancel(true);
        {
            py::gil_scoped_release release;
            worker.join();
        }
        throw;
    }
    worker.join();
    done.get();  // the job's own error, if any
}

void bindPrecompute(py::module_& m) {
    m.def(
        "precompute",
        [](const std::string& mesh, const py::object& output, const py::object& progress, bool force, int threads,
           bool quiet, const py::kwargs& options) {
            nlohmann::json job = nlohmann::json::object();
            job["mesh"] = mesh;
            for (const auto& [key, value] : options) {
                const std::string name = py::str(key);
                if (name == "mesh" || name == "output" || name == "o")
                    throw py::type_error(name + ": give it as precompute's own argument");
                job[name] = jsonValue(value, name);
            }
            const bool keep = !output.is_none();
            const std::string path = keep ? stringArgument(output, "output") : temporaryOutput();
            job["output"] = path;
            if (!progress.is_none() && !PyCallable_Check(progress.ptr()))
                throw py::type_error("progress: expected a callable (stage, done, total, unit)");
            const PrecomputeSettings settings = parseJob(nlohmann::json::object(), job, "precompute");
            if (settings.pass1Only) throw Error("--pass1-only", "not available from Python (use the command line)");
            if (settings.ground && !keep)
                throw Error("ground", "needs output= (the ground's file is written beside it, <output>.ground.prt)");

            PrecomputeSummary summary;
            runCancellable([&] { summary = precomputeTransport(settings, force, nullptr); }, progress, quiet, threads);

            auto t = std::make_shared<PyTransport>();
            t->path = keep ? path : "";
            try {
                t->file = std::make_shared<TransportFile>(withoutGil([&] { return loadTransportFile(path); }));
            } catch (...) {
                std::error_code ec;
                if (!keep) std::filesystem::remove(path, ec);
                throw;
            }
            if (!keep) std::filesystem::remove(path);
            py::object result = py::cast(t);
            result.attr("summary") = jsonToPython(summaryJson(summary));
            result.attr("settings") = jsonToPython(settingsJson(settings));
            return result;
        },
        py::arg("mesh"), py::arg("output") = py::none(), py::kw_only(), py::arg("progress") = py::none(),
        py::arg("force") = false, py::arg("threads") = 0, py::arg("quiet") = true,
        "Runs prt-precompute on a mesh file and returns the prt.Transport (with .summary and .settings "
        "dicts). Keyword arguments are prt-precompute's long options (size_mm=30, material='Marble', "
        "cubemap_size=16, components='ms,ss', editable=True, ...), checked with its messages. output: the "
        "file to write (kept; an up-to-date one is reused unless force), or None for a temporary one. "
        "progress: called as progress(stage, done, total, unit) about ten times a second from this thread. "
        "Ctrl-C (KeyboardInterrupt) cancels cleanly. quiet: no progress lines on stderr.");
}

}  // namespace prt::python
