// SPDX-License-Identifier: MIT
#pragma once
/// Parallel loops over index ranges (oneTBB). For deterministic numerics, reduce per fixed chunk
/// (parallel_chunks) and combine the chunk results in chunk order: the result is then the same for
/// any number of threads.

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <cstdint>

namespace btf {

/// Calls fn(i) for i in [begin, end) on all worker threads.
template <typename Fn>
void parallel_for(int64_t begin, int64_t end, Fn&& fn) {
    if (end <= begin) return;
    tbb::parallel_for(tbb::blocked_range<int64_t>(begin, end),
                      [&](const tbb::blocked_range<int64_t>& r) {
                          for (int64_t i = r.begin(); i != r.end(); ++i) fn(i);
                      });
}

/// Calls fn(chunk_begin, chunk_end) for fixed chunks of `grain` indices; chunk boundaries do not
/// depend on the number of threads.
template <typename Fn>
void parallel_chunks(int64_t begin, int64_t end, int64_t grain, Fn&& fn) {
    if (end <= begin) return;
    const int64_t chunks = (end - begin + grain - 1) / grain;
    tbb::parallel_for(int64_t{0}, chunks, [&](int64_t c) {
        const int64_t b = begin + c * grain;
        fn(b, std::min(end, b + grain));
    });
}

/// The number of worker threads parallel loops use now (all cores, or a ThreadLimit's).
int worker_threads();

/// Limits btfkit's worker threads for the lifetime of the returned object (0 = all cores).
class ThreadLimit {
  public:
    explicit ThreadLimit(int threads);
    ~ThreadLimit();
    ThreadLimit(const ThreadLimit&) = delete;
    ThreadLimit& operator=(const ThreadLimit&) = delete;

  private:
    void* m_control = nullptr;
};

}  // namespace btf
