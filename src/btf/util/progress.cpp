// SPDX-License-Identifier: MIT
#include "btf/util/progress.h"

#include <chrono>

#include "btf/util/error.h"

namespace btf {

namespace {
int64_t now_ns() {
    return std::chrono::duration_cast<std::chrono::nanoseconds>(
               std::chrono::steady_clock::now().time_since_epoch())
        .count();
}
constexpr int64_t kReportIntervalNs = 100'000'000;  // at most ten reports per second
}  // namespace

Progress& Progress::none() {
    static thread_local Progress silent;
    return silent;
}

void Progress::begin(std::string_view stage, uint64_t total) {
    poll();
    {
        std::lock_guard lock(m_mutex);
        m_stage = stage;
        m_done.store(0);
        m_total.store(total);
    }
    report(true);
}

void Progress::advance(uint64_t units) {
    poll();
    m_done.fetch_add(units);
    if (m_callback) report(false);
}

void Progress::finish() {
    m_done.store(m_total.load());
    report(true);
}

namespace {
std::atomic<bool> g_cancel_all{false};
static_assert(std::atomic<bool>::is_always_lock_free, "cancel_all must be async-signal-safe");
}  // namespace

void Progress::cancel_all() noexcept {
    g_cancel_all.store(true);
}
bool Progress::all_cancelled() noexcept {
    return g_cancel_all.load();
}

void Progress::check_all() {
    if (g_cancel_all.load()) throw Cancelled();
}

void Progress::poll() const {
    if (m_cancelled.load() || g_cancel_all.load()) throw Cancelled();
}

void Progress::report(bool force) {
    if (!m_callback) return;
    const int64_t now = now_ns();
    int64_t last = m_last_report_ns.load();
    if (!force) {
        if (now - last < kReportIntervalNs) return;
        if (!m_last_report_ns.compare_exchange_strong(last, now)) return;
    } else {
        m_last_report_ns.store(now);
    }
    std::lock_guard lock(m_mutex);
    m_callback(m_stage, m_done.load(), m_total.load());
}

}  // namespace btf
