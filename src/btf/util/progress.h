// SPDX-License-Identifier: MIT
#pragma once
/// Progress reporting and cancellation for long operations. The library reports through a
/// callback; the CLI draws a bar on a terminal and plain lines otherwise.

#include <atomic>
#include <cstdint>
#include <functional>
#include <mutex>
#include <string>
#include <string_view>

namespace btf {

class Progress {
  public:
    /// Called with the current stage name, units done and units total (total may be 0 when
    /// unknown). Calls are serialized and rate-limited by the caller of the callback.
    using Callback = std::function<void(std::string_view stage, uint64_t done, uint64_t total)>;

    Progress() = default;
    explicit Progress(Callback callback) : m_callback(std::move(callback)) {}

    /// A Progress that reports nothing and is never cancelled.
    static Progress& none();

    /// Starts a stage of `total` units.
    void begin(std::string_view stage, uint64_t total);
    /// Adds `units` to the current stage; thread-safe. Throws btf::Cancelled if cancelled.
    void advance(uint64_t units = 1);
    /// Marks the current stage complete.
    void finish();

    /// Requests cancellation; the next advance() or poll() throws btf::Cancelled.
    void cancel() { m_cancelled.store(true); }
    bool cancelled() const { return m_cancelled.load(); }
    /// Throws btf::Cancelled if cancellation was requested, for this operation or process-wide.
    void poll() const;

    /// Requests cancellation of every operation in the process (async-signal-safe: the CLI calls
    /// it from its SIGINT/SIGTERM handler so interrupted runs unwind and leave no temporary files).
    static void cancel_all() noexcept;
    static bool all_cancelled() noexcept;
    /// Throws btf::Cancelled if cancel_all() was called: for loops that read or decode input
    /// without a Progress of their own (zip entries, images, HDF5 chunks).
    static void check_all();

    uint64_t done() const { return m_done.load(); }
    uint64_t total() const { return m_total.load(); }

  private:
    void report(bool force);

    Callback m_callback;
    std::mutex m_mutex;  // serializes callback calls and stage changes
    std::string m_stage;
    std::atomic<uint64_t> m_done{0};
    std::atomic<uint64_t> m_total{0};
    std::atomic<bool> m_cancelled{false};
    std::atomic<int64_t> m_last_report_ns{0};
};

}  // namespace btf
