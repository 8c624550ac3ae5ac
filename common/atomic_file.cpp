#include "common/atomic_file.h"

#include <fcntl.h>
#include <signal.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstring>
#include <filesystem>

#include "common/error.h"

namespace prt {

namespace fs = std::filesystem;

namespace {

fs::path directoryOf(const fs::path& target) {
    fs::path dir = target.parent_path();
    return dir.empty() ? fs::path(".") : dir;
}

// fsync by name (the writer may have used its own file handle and closed it).
bool syncPath(const fs::path& p, int flags) {
    const int fd = ::open(p.c_str(), flags | O_CLOEXEC);
    if (fd < 0) return false;
    const bool ok = ::fsync(fd) == 0;
    ::close(fd);
    return ok;
}

}  // namespace

void checkOutputPath(const std::string& path) {
    const fs::path target(path);
    if (path.empty() || !target.has_filename()) throw Error(path, "not a file name");
    const fs::path dir = directoryOf(target);
    std::error_code ec;
    if (!fs::is_directory(dir, ec)) throw Error(path, "directory '" + dir.string() + "' does not exist");
    if (::access(dir.c_str(), W_OK | X_OK) != 0)
        throw Error(path, "directory '" + dir.string() + "' is not writable");
    if (fs::is_directory(target, ec)) throw Error(path, "is a directory");
}

size_t removeStaleTemporaries(const std::string& path) {
    const fs::path target(path);
    const std::string targetName = target.filename().string();
    const std::string prefix = target.stem().string() + ".tmp";
    size_t removed = 0;
    std::error_code ec;
    for (fs::directory_iterator it(directoryOf(target), ec), end; !ec && it != end; it.increment(ec)) {
        const std::string name = it->path().filename().string();
        if (!isTemporaryFor(name, targetName)) continue;
        // "<stem>.tmp<pid>-<n><ext>": the pid runs from the prefix to the dash.
        const size_t dash = name.find('-', prefix.size());
        if (dash == std::string::npos || dash == prefix.size()) continue;
        const std::string digits = name.substr(prefix.size(), dash - prefix.size());
        if (digits.find_first_not_of("0123456789") != std::string::npos || digits.size() > 9) continue;
        const long pid = std::stol(digits);
        if (pid == long(::getpid())) continue;                       // ours: maybe in flight
        if (::kill(pid_t(pid), 0) == 0 || errno != ESRCH) continue;  // alive (or not ours to judge)
        std::error_code removeError;
        if (fs::remove(it->path(), removeError)) ++removed;
    }
    return removed;
}

void writeAtomically(const std::string& path, const std::function<void(const std::string&)>& write) {
    checkOutputPath(path);
    removeStaleTemporaries(path);
    const fs::path target(path);
    const fs::path dir = directoryOf(target);
    static std::atomic<unsigned> counter{0};
    const fs::path temp = dir / (target.stem().string() + ".tmp" + std::to_string(long(::getpid())) + "-" +
                                 std::to_string(counter.fetch_add(1)) + target.extension().string());
    auto removeTemp = [&] {
        std::error_code ignored;
        fs::remove(temp, ignored);
    };
    try {
        write(temp.string());
    } catch (...) {
        removeTemp();
        throw;
    }
    std::error_code ec;
    if (!fs::is_regular_file(temp, ec)) {
        removeTemp();
        throw Error(path, "the writer produced no file");
    }
    if (!syncPath(temp, O_RDONLY)) {
        const std::string reason = std::strerror(errno);
        removeTemp();
        throw Error(path, "cannot sync temporary file '" + temp.string() + "': " + reason);
    }
    fs::rename(temp, target, ec);
    if (ec) {
        removeTemp();
        throw Error(path, "cannot replace it with the new file: " + ec.message());
    }
    syncPath(dir, O_RDONLY | O_DIRECTORY);  // make the rename itself durable (best effort)
}

void writeFileAtomically(const std::string& path, std::string_view bytes) {
    writeAtomically(path, [&](const std::string& temp) {
        const int fd = ::open(temp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0666);
        if (fd < 0) throw Error(path, "cannot create temporary file '" + temp + "': " + std::strerror(errno));
        size_t done = 0;
        while (done < bytes.size()) {
            const ssize_t n = ::write(fd, bytes.data() + done, bytes.size() - done);
            if (n < 0) {
                if (errno == EINTR) continue;
                const std::string reason = std::strerror(errno);
                ::close(fd);
                throw Error(path, "cannot write temporary file '" + temp + "': " + reason);
            }
            done += size_t(n);
        }
        if (::close(fd) != 0)
            throw Error(path, "cannot close temporary file '" + temp + "': " + std::strerror(errno));
    });
}

bool isTemporaryFor(const std::string& name, const std::string& targetName) {
    const fs::path target(targetName);
    const std::string prefix = target.stem().string() + ".tmp";
    const std::string suffix = target.extension().string();
    return name.size() > prefix.size() + suffix.size() && name.compare(0, prefix.size(), prefix) == 0 &&
           name.compare(name.size() - suffix.size(), suffix.size(), suffix) == 0;
}

}  // namespace prt
