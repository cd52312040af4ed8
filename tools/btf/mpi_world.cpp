// SPDX-License-Identifier: MIT
// The btf command's MPI world as a btf::Collective (mpi_world.h). Sums add the ranks' values in
// rank order: each rank sums one slice of the data from every rank's copy (MPI_Alltoallv), then
// every rank gathers the summed slices (MPI_Allgatherv); bytes moved per rank are 2 (N − 1) / N of
// the data, as a ring all-reduce, and the result does not depend on how MPI schedules its messages.

#include "mpi_world.h"

#include <fmt/format.h>

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <vector>

#include "btf/util/error.h"

#ifdef BTF_WITH_MPI
#include <mpi.h>
#endif

namespace btf::cli {

namespace {

int env_int(const char* name) {
    const char* v = std::getenv(name);
    return v ? std::atoi(v) : 0;
}

bool g_agreed = false;

}  // namespace

int launcher_size() {
    // Open MPI, then the PMI of MPICH and others.
    for (const char* name : {"OMPI_COMM_WORLD_SIZE", "PMI_SIZE", "PMIX_SIZE"})
        if (const int n = env_int(name); n > 0) return n;
    return 1;
}

bool failure_agreed() {
    return g_agreed;
}

#ifdef BTF_WITH_MPI

namespace {

// Elements summed per round: bounds the receive buffer (a slice from every rank) to this many.
constexpr int64_t kRound = int64_t(1) << 24;

class MpiCollective final : public Collective {
  public:
    MpiCollective() {
        MPI_Comm_dup(MPI_COMM_WORLD, &m_comm);
        MPI_Comm_rank(m_comm, &m_rank);
        MPI_Comm_size(m_comm, &m_size);
    }
    ~MpiCollective() override { MPI_Comm_free(&m_comm); }
    int rank() const override { return m_rank; }
    int size() const override { return m_size; }
    void sum(float* data, int64_t n) override { ordered_sum(data, n, MPI_FLOAT); }
    void sum(double* data, int64_t n) override { ordered_sum(data, n, MPI_DOUBLE); }

    void agree(const std::string& error, bool cancelled) override {
        const int mine[2] = {error.empty() ? m_size : m_rank, error.empty() ? 0 : 1};
        int lowest = 0, failed = 0;
        MPI_Allreduce(&mine[0], &lowest, 1, MPI_INT, MPI_MIN, m_comm);
        MPI_Allreduce(&mine[1], &failed, 1, MPI_INT, MPI_SUM, m_comm);
        if (lowest == m_size) return;
        std::string message = error;
        int kind = cancelled ? 1 : 0;
        if (failed < m_size) {  // some ranks failed: everyone reports the lowest one's failure
            broadcast_from(message, lowest);
            MPI_Bcast(&kind, 1, MPI_INT, lowest, m_comm);
            message = fmt::format("rank {} of {}: {}", lowest, m_size, message);
        }
        g_agreed = true;
        if (kind) throw Cancelled();
        throw Error(message);  // every rank failed: each reports its own
    }

    void broadcast(std::string& text) override { broadcast_from(text, 0); }

    std::vector<std::string> gather(const std::string& text) override {
        const int length = static_cast<int>(text.size());
        std::vector<int> lengths(m_rank == 0 ? m_size : 0), offsets(lengths.size());
        MPI_Gather(&length, 1, MPI_INT, lengths.data(), 1, MPI_INT, 0, m_comm);
        int64_t total = 0;
        for (size_t r = 0; r < lengths.size(); ++r) {
            offsets[r] = static_cast<int>(total);
            total += lengths[r];
        }
        if (total > INT32_MAX) fail("gathering {} bytes from the ranks: more than 2 GiB", total);
        std::string all(static_cast<size_t>(total), '\0');
        MPI_Gatherv(text.data(), length, MPI_CHAR, all.data(), lengths.data(), offsets.data(),
                    MPI_CHAR, 0, m_comm);
        if (m_rank != 0) m_bytes += static_cast<uint64_t>(length);
        std::vector<std::string> out;
        for (size_t r = 0; r < lengths.size(); ++r)
            out.push_back(all.substr(offsets[r], lengths[r]));
        return out;
    }

    uint64_t bytes_sent() const override { return m_bytes; }

  private:
    void broadcast_from(std::string& text, int root) {
        int64_t length = static_cast<int64_t>(text.size());
        MPI_Bcast(&length, 1, MPI_INT64_T, root, m_comm);
        if (length > INT32_MAX) fail("broadcasting {} bytes: more than 2 GiB", length);
        text.resize(static_cast<size_t>(length));
        MPI_Bcast(text.data(), static_cast<int>(length), MPI_CHAR, root, m_comm);
        if (m_rank == root) m_bytes += static_cast<uint64_t>(length) * (m_size - 1);
    }

    template <typename T>
    void ordered_sum(T* data, int64_t n, MPI_Datatype type) {
        std::vector<int> counts(m_size), offsets(m_size), from(m_size), at(m_size);
        std::vector<T> received, slice;
        for (int64_t start = 0; start < n; start += kRound) {
            const int64_t length = std::min(kRound, n - start);
            for (int r = 0; r < m_size; ++r) {
                const auto [first, last] = rank_share(length, r, m_size);
                counts[r] = static_cast<int>(last - first);
                offsets[r] = static_cast<int>(first);
            }
            const int mine = counts[m_rank];
            for (int r = 0; r < m_size; ++r) {
                from[r] = mine;
                at[r] = r * mine;
            }
            received.resize(static_cast<size_t>(mine) * m_size);
            MPI_Alltoallv(data + start, counts.data(), offsets.data(), type, received.data(),
                          from.data(), at.data(), type, m_comm);
            slice.assign(received.begin(), received.begin() + mine);
            for (int r = 1; r < m_size; ++r) {
                const T* part = received.data() + int64_t(r) * mine;
                for (int i = 0; i < mine; ++i) slice[i] += part[i];
            }
            MPI_Allgatherv(slice.data(), mine, type, data + start, counts.data(), offsets.data(),
                           type, m_comm);
            m_bytes +=
                sizeof(T) * static_cast<uint64_t>(length - mine + int64_t(mine) * (m_size - 1));
        }
    }

    MPI_Comm m_comm = MPI_COMM_NULL;
    int m_rank = 0, m_size = 1;
    uint64_t m_bytes = 0;
};

MpiCollective* g_world = nullptr;

}  // namespace

MpiSession::MpiSession() {
    if (launcher_size() <= 1) return;
    int provided = 0;
    // Only the thread that runs the command calls MPI; worker threads never do.
    MPI_Init_thread(nullptr, nullptr, MPI_THREAD_FUNNELED, &provided);
    g_world = new MpiCollective();
}

MpiSession::~MpiSession() {
    if (!g_world) return;
    delete g_world;
    g_world = nullptr;
    MPI_Finalize();
}

Collective* mpi_world() {
    return g_world;
}

int mpi_rank() {
    return g_world ? g_world->rank() : 0;
}

void agree_everywhere(const std::string& error) {
    if (!g_world) return;
    try {
        g_world->agree(error, false);
    } catch (const Error&) {
    }
}

void abort_world(int code) {
    std::fflush(stdout);
    std::fflush(stderr);
    if (g_world) MPI_Abort(MPI_COMM_WORLD, code);
    std::exit(code);
}

#else  // no MPI in this build

MpiSession::MpiSession() {
    if (launcher_size() > 1)
        fail(
            "this btf was built without MPI, but a launcher started it as one of {} ranks: "
            "build with libopenmpi-dev installed (docs/distributed.md), or run it without mpirun",
            launcher_size());
}

MpiSession::~MpiSession() = default;

Collective* mpi_world() {
    return nullptr;
}

int mpi_rank() {
    return 0;
}

void agree_everywhere(const std::string&) {}

void abort_world(int code) {
    std::exit(code);
}

#endif

}  // namespace btf::cli
