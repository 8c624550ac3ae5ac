#pragma once
// The command-line helper of the tests that parse options (tests only; apart from
// test_support.h so that only these tests compile CLI/CLI.hpp).

#include <CLI/CLI.hpp>

#include <string>
#include <vector>

namespace prt::test {

// A command's options parsed from `args` (no program name) by its declarations.
template <typename Command>
Command parseCommand(void (*declare)(CLI::App&, Command&), const std::vector<std::string>& args) {
    CLI::App app;
    Command command;
    declare(app, command);
    app.parse(std::vector<std::string>(args.rbegin(), args.rend()));
    return command;
}

}  // namespace prt::test
