#pragma once
// What every fuzz target of tools/fuzz/ shares (docs/reliability.md, "Fuzzing").
//
// A target is a function LLVMFuzzerTestOneInput(data, size) that feeds one input to a
// loader or parser of ours. Built with PRT_FUZZ=ON (clang) it links libFuzzer; in the
// normal build replay_main.cpp drives it over the committed corpus and crash inputs
// (CTest fuzz_replay_*), so every input that ever crashed stays a regression test.
//
// The contract checked: bad input throws prt::Error and nothing else. Any other
// exception (std::logic_error, std::bad_alloc, nlohmann's, CLI11's) escaping a loader
// is a bug and aborts, as does every crash, sanitizer report or oracle failure.

#include <cstddef>
#include <cstdint>
#include <functional>
#include <string>
#include <string_view>

namespace prt::fuzz {

// Writes the input to a file named "input<extension>" in this process's own temporary
// directory (created on first use under $TMPDIR or /tmp, removed at exit) and returns
// its path. Loaders that only take paths read it from there.
std::string writeInput(const uint8_t* data, size_t size, std::string_view extension);

// A second path in the same directory, for outputs (round trips); removed by the caller
// or overwritten by the next input.
std::string scratchPath(std::string_view name);

// Runs body; a prt::Error (the loader refusing bad input) is the expected way out.
// Any other exception aborts with its type and message.
void expectErrors(const std::function<void()>& body);

// Aborts with a message when `condition` is false: an oracle of a target failed.
void require(bool condition, const char* what);

}  // namespace prt::fuzz
