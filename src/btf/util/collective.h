// SPDX-License-Identifier: MIT
#pragma once
/// The processes of one distributed run (MPI ranks), as btfkit's algorithms use them: element-wise
/// sums with the same bits on every rank, agreement on failures, strings gathered and broadcast.
/// The library itself does not link MPI: the `btf` command implements this interface over
/// MPI_COMM_WORLD (tools/btf/mpi_world.h) and makes it current for the thread that runs the command
/// (ScopedCollective); a distributed algorithm asks for current_collective() and, with more than
/// one rank, works on its share of the data only.
///
/// Every rank must call the collective operations in the same order with the same sizes. Work
/// that can fail on one rank only (reading its share of a source) runs through together(), which
/// makes every rank throw the failing rank's error instead of leaving the others waiting.

#include <cstdint>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

namespace btf {

class Collective {
  public:
    virtual ~Collective() = default;
    virtual int rank() const = 0;
    virtual int size() const = 0;
    /// Element-wise sums over the ranks, in place: every rank ends with the same values, the
    /// ranks' values added in rank order (the same bits in every run with as many ranks).
    virtual void sum(float* data, int64_t n) = 0;
    virtual void sum(double* data, int64_t n) = 0;
    /// Agreement after work that may have failed on some ranks: `error` is this rank's failure
    /// ("" for none). If any rank failed, throws on every rank btf::Error("rank R of N: …") with
    /// the lowest failing rank's message (btf::Cancelled where that rank was cancelled).
    virtual void agree(const std::string& error, bool cancelled = false) = 0;
    /// Rank 0's `text` on every rank.
    virtual void broadcast(std::string& text) = 0;
    /// On rank 0, every rank's `text` in rank order; on the other ranks, nothing.
    virtual std::vector<std::string> gather(const std::string& text) = 0;
    /// Bytes this rank has sent so far (payloads of the operations above).
    virtual uint64_t bytes_sent() const = 0;
};

/// The collective the calling thread's distributed algorithms run across: null (one process)
/// unless a ScopedCollective of more than one rank is alive on this thread.
Collective* current_collective();

/// Makes `collective` current for the calling thread while it lives (null or one rank: none).
class ScopedCollective {
  public:
    explicit ScopedCollective(Collective* collective);
    ~ScopedCollective();
    ScopedCollective(const ScopedCollective&) = delete;
    ScopedCollective& operator=(const ScopedCollective&) = delete;

  private:
    Collective* m_previous;
};

/// Rank `rank`'s share [first, last) of `count` items in contiguous, balanced blocks (the first
/// count % size ranks get one more).
std::pair<int64_t, int64_t> rank_share(int64_t count, int rank, int size);

/// Runs work() on this rank, then agrees with the others (Collective::agree): an exception of
/// work() on any rank is thrown on every rank. Without a collective, runs work() only.
template <typename Work>
void together(Collective* collective, Work&& work);

namespace detail {
/// The message and kind of the exception being handled (in a catch block).
std::pair<std::string, bool> current_failure();
}  // namespace detail

template <typename Work>
void together(Collective* collective, Work&& work) {
    if (!collective) {
        work();
        return;
    }
    std::string error;
    bool cancelled = false;
    try {
        work();
    } catch (...) {
        std::tie(error, cancelled) = detail::current_failure();
    }
    collective->agree(error, cancelled);
}

}  // namespace btf
