// SPDX-License-Identifier: MIT
#pragma once
// MPI for the btf command (docs/distributed.md): started when an MPI launcher (mpirun, mpiexec)
// started the process, finalized when main() returns. The world's ranks are a btf::Collective
// (src/btf/util/collective.h) for the commands that run across ranks: compress and compress-many.
// In a build without MPI (BTF_WITH_MPI undefined) a process started by a launcher of more than
// one rank is refused.

#include <string>

#include "btf/util/collective.h"

namespace btf::cli {

/// Holds MPI for the lifetime of main(): MPI_Init_thread when a launcher started this process
/// with more than one rank, MPI_Finalize at the end.
class MpiSession {
  public:
    MpiSession();
    ~MpiSession();
    MpiSession(const MpiSession&) = delete;
    MpiSession& operator=(const MpiSession&) = delete;
};

/// The ranks this process runs with (null: one process, not started by a launcher or with one
/// rank).
Collective* mpi_world();
/// This process's rank (0 in one process).
int mpi_rank();
/// The world size a launcher announced in the environment (1 without one).
int launcher_size();
/// Whether the exception being handled was agreed by every rank (thrown by Collective::agree),
/// so that every rank reports it and exits in order; otherwise a rank must abort the others.
bool failure_agreed();
/// For a failure that every rank meets at the same point (a command line they all parse): agrees
/// on it, so that failure_agreed() is true and every rank ends in order.
void agree_everywhere(const std::string& error);
/// Ends every rank with `code` (MPI_Abort) after a failure only this rank saw.
[[noreturn]] void abort_world(int code);

}  // namespace btf::cli
