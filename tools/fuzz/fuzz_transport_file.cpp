// Fuzz target: the transport-file loader (common/transport_file.h), both the cheap
// readTransportFileInfo and the full loadTransportFile, over whole files (preamble,
// header, parameter, per-vertex (COMP) and blocked (BLKC) component, view-map and radial
// basis (RBAS) sections, end marker; format versions 1 to 7). The fuzz build skips the checksum comparison
// (FUZZING_BUILD_MODE_UNSAFE_FOR_PRODUCTION) so mutations reach the sections behind it.
//
// Oracle: a file the loader accepts satisfies saveTransportFile's validation, and
// saving then loading it gives the same TransportFile (load accepts nothing that save
// would refuse or write differently).

#include <cstdint>
#include <cstdio>

#include "common/error.h"
#include "common/transport_file.h"
#include "tools/fuzz/fuzz_support.h"

using namespace prt;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    const std::string path = fuzz::writeInput(data, size, ".prt");
    fuzz::expectErrors([&] {
        const TransportFileInfo info = readTransportFileInfo(path);
        fuzz::require(!describe(info).empty(), "describe(info) is empty");
    });
    fuzz::expectErrors([&] {
        const TransportFile file = loadTransportFile(path);
        fuzz::require(!describe(file).empty(), "describe(file) is empty");
        const std::string copy = fuzz::scratchPath("copy.prt");
        try {
            saveTransportFile(copy, file);
        } catch (const Error& e) {
            std::fprintf(stderr, "prt-fuzz: loaded file refused by save: %s\n", e.what());
            fuzz::require(false, "a loaded transport file saves");
        }
        fuzz::require(loadTransportFile(copy) == file, "save + load round trip is the identity");
    });
    return 0;
}
