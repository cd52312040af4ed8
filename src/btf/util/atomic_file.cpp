// SPDX-License-Identifier: MIT
#include "btf/util/atomic_file.h"

#include <unistd.h>

#include <atomic>
#include <mutex>
#include <set>
#include <system_error>

#include "btf/util/error.h"

namespace btf {

namespace fs = std::filesystem;

namespace {
// Every temporary that exists now, so that a process which must end at once (a second SIGINT, a
// cancellation that a library call does not notice) can still leave no partial output.
std::mutex g_live_mutex;
std::multiset<fs::path>& live() {
    // Never destroyed: the CLI's watchdog thread may remove the temporaries while the main thread
    // is already running the destructors of static objects at exit.
    static auto* paths = new std::multiset<fs::path>;
    return *paths;
}
void remember(const fs::path& path) {
    std::lock_guard lock(g_live_mutex);
    live().insert(path);
}
void forget(const fs::path& path) {
    std::lock_guard lock(g_live_mutex);
    if (auto it = live().find(path); it != live().end()) live().erase(it);
}
}  // namespace

void AtomicOutput::remove_all_temporaries() noexcept {
    std::lock_guard lock(g_live_mutex);
    for (const fs::path& path : live()) {
        std::error_code ec;
        fs::remove_all(path, ec);
    }
    live().clear();
}

AtomicOutput::AtomicOutput(fs::path destination, bool directory)
    : m_destination(std::move(destination)), m_directory(directory) {
    static std::atomic<unsigned> counter{0};
    fs::path parent = m_destination.parent_path();
    if (parent.empty()) parent = ".";
    std::error_code ec;
    if (!fs::is_directory(parent, ec))
        fail("{}: cannot write: folder {} does not exist", m_destination.string(), parent.string());
    if (fs::is_directory(m_destination, ec))
        fail("{}: cannot write: a folder of that name exists (remove it first)",
             m_destination.string());
    if (directory && fs::exists(m_destination, ec))
        fail("{}: cannot write a folder: a file of that name exists", m_destination.string());
    m_temp = parent / fmt::format(".{}.tmp-{}-{}", m_destination.filename().string(), ::getpid(),
                                  counter.fetch_add(1));
    remember(m_temp);
    if (directory) {
        if (!fs::create_directory(m_temp, ec))
            fail("{}: cannot create temporary folder: {}", m_temp.string(), ec.message());
    }
}

AtomicOutput::~AtomicOutput() {
    if (m_committed) return;
    std::error_code ec;
    fs::remove_all(m_temp, ec);
    forget(m_temp);
}

void AtomicOutput::commit() {
    std::error_code ec;
    if (!fs::exists(m_temp, ec))
        fail("{}: nothing was written (temporary {} is missing)", m_destination.string(),
             m_temp.string());
    if (m_directory && fs::exists(m_destination, ec))
        fail("{}: cannot write a folder: it exists already", m_destination.string());
    {
        // Under the lock: a forced exit removes the temporary before or never.
        std::lock_guard lock(g_live_mutex);
        fs::rename(m_temp, m_destination, ec);
        if (!ec)
            if (auto it = live().find(m_temp); it != live().end()) live().erase(it);
    }
    if (ec) fail("{}: cannot move output into place: {}", m_destination.string(), ec.message());
    m_committed = true;
}

fs::path AtomicOutputSet::add(fs::path destination) {
    const fs::path extension = destination.extension();
    m_outputs.push_back(std::make_unique<AtomicOutput>(std::move(destination)));
    fs::path written = m_outputs.back()->temp_path();
    written += extension;
    m_written.push_back(written);
    remember(written);
    return written;
}

void AtomicOutputSet::commit() {
    for (size_t i = 0; i < m_outputs.size(); ++i) {
        std::error_code ec;
        if (!fs::exists(m_written[i], ec))
            fail("{}: nothing was written", m_outputs[i]->destination().string());
    }
    for (size_t i = 0; i < m_outputs.size(); ++i) {
        std::error_code ec;
        fs::rename(m_written[i], m_outputs[i]->temp_path(), ec);
        forget(m_written[i]);
        if (ec)
            fail("{}: cannot move output into place: {}", m_outputs[i]->destination().string(),
                 ec.message());
        m_outputs[i]->commit();
    }
    m_committed = true;
}

AtomicOutputSet::~AtomicOutputSet() {
    if (m_committed) return;
    for (const fs::path& p : m_written) {
        std::error_code ec;
        fs::remove(p, ec);
        forget(p);
    }
}

}  // namespace btf
