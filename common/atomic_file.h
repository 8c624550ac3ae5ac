#pragma once
// Writing a file all or nothing: the one way every tool replaces an output (transport
// files, images, meshes, JSON summaries), so that a crash, a full disk or an error
// half-way never leaves a partial file where a good one was.
//
// The content goes to a temporary file in the target's directory (same file system,
// so the rename is atomic), named "<stem>.tmp<pid>-<n><ext>": the real extension stays
// last for writers that choose the format by it (OpenImageIO, OpenMesh). Once the
// writer returns, the temporary file is fsynced, renamed over the target and the
// directory is fsynced (best effort: some file systems refuse). If the writer throws,
// or any step fails, the temporary file is removed, the target is untouched and a
// prt::Error(path, reason) is thrown (the writer's own prt::Error passes through).
//
// A process killed mid-write (SIGKILL, power loss) leaves its temporary file behind;
// the next writeAtomically of the same target removes such leftovers of processes that
// no longer run (the pid is in the name), so a killed and re-run job leaves nothing.

#include <functional>
#include <string>
#include <string_view>

namespace prt {

// Throws prt::Error(path, ...) unless `path` names a file in an existing, writable
// directory. Tools call it for every output before a long computation starts.
void checkOutputPath(const std::string& path);

// Runs write(temporaryPath), then commits the temporary file over `path` as above.
void writeAtomically(const std::string& path, const std::function<void(const std::string& temporaryPath)>& write);

// The same for content already in memory (text or binary).
void writeFileAtomically(const std::string& path, std::string_view bytes);

// Whether `name` (a file name, no directory) has the shape of writeAtomically's
// temporary files for target `targetName` (tests, clean-up).
bool isTemporaryFor(const std::string& name, const std::string& targetName);

// Removes the temporary files of `path` left by processes that are no longer running;
// returns how many. (writeAtomically calls it; exposed for tests and tools.)
size_t removeStaleTemporaries(const std::string& path);

}  // namespace prt
