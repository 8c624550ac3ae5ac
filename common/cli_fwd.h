#pragma once
// CLI11's parser types, declared for the headers that only pass a CLI::App& or hold a
// CLI::Option*. CLI/CLI.hpp (a header-only library that defines its validators as
// objects) is costly to compile in every unit that includes it, so only the sources
// that declare or parse options include it (docs/building.md, "Build and test time").

namespace CLI {
class App;
class Option;
}  // namespace CLI
