#pragma once
// MPI ranks (Open MPI; built when CMake finds MPI, PRT_HAVE_MPI): `mpirun -np R
// prt-precompute ...` splits pass 1 over the ranks by samples and pass 2 and single
// scattering by vertices, each rank threading its share with TBB as one process does.
// Communication (docs/cluster.md): every rank broadcasts its truncated pass-1 vectors
// (8 bytes per kept coefficient + 4 per sample, never dense cubemaps) so every rank
// holds all samples for pass 2; every rank sends its quantised per-vertex vectors
// (the transport file's own arrays) to rank 0, which writes the one output file.
// Messages are split into chunks below 1 GiB, so no count overflows MPI's int.
//
// Only rank 0 prints (progress, summaries, errors): main() silences the others.

#include <memory>

#include "precompute/job/distribution.h"

namespace prt {

// True when this process was started by an MPI launcher (mpirun / mpiexec / srun set
// OMPI_COMM_WORLD_SIZE, PMIX_RANK or PMI_RANK). A plain run never initialises MPI.
bool launchedByMpi();

// Whether this build has MPI (PRT_HAVE_MPI).
bool mpiAvailable();

// MPI_Init in the constructor (when launchedByMpi()), MPI_Finalize in the destructor.
// distribution() is the world's MpiDistribution, or nullptr when not under MPI.
class MpiSession {
public:
    MpiSession(int& argc, char**& argv);
    ~MpiSession();
    MpiSession(const MpiSession&) = delete;
    MpiSession& operator=(const MpiSession&) = delete;

    Distribution* distribution() { return distribution_.get(); }

private:
    bool initialised_ = false;
    std::unique_ptr<Distribution> distribution_;
};

}  // namespace prt
