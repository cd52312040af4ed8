// SPDX-License-Identifier: MIT
#pragma once
/// Runs work whose failure could take the process down in a child process of its own, so that a
/// crash there becomes a btf::Error here. btfkit uses it where a third-party library reads
/// untrusted structure that btfkit cannot check beforehand (libhdf5 walking a file's metadata).

#include <chrono>
#include <functional>
#include <string>

namespace btf {

struct IsolateOptions {
    /// The child is killed, and run_isolated() fails, if it has not finished by then.
    std::chrono::seconds timeout{120};
};

/// Forks, runs `work` in the child and waits for it. Returns if `work` returned; throws
/// btf::Error with the child's message if `work` threw (any std::exception), and btf::Error
/// "<what> crashed (<signal>); the input is damaged or crafted" (or "did not finish within <n> s")
/// if the child died, exited without reporting, or ran past the timeout: `what` names the input
/// and the library, e.g. "x.h5: libhdf5". While waiting it polls Progress::check_all(): a cancelled
/// process kills the child and throws btf::Cancelled.
///
/// The child only runs `work` and leaves with _exit(): no atexit handlers, no destructors of
/// globals, no flushing of stdio buffers inherited from the parent. Its standard error goes to
/// /dev/null (a library's own crash report would otherwise interleave with the parent's output).
/// SIGINT, SIGTERM, SIGHUP and SIGQUIT take their default action there (signals stay blocked from
/// the fork until then), so a ^C to the process group ends the child without running the
/// parent's handlers; it dies with its parent, too.
/// `work` must not need other threads of the parent (the child has only the calling thread) and
/// must not take locks that another thread may hold at the time of the fork; hold any such lock
/// around the call, and let `work` start by re-creating it: the child's thread has another
/// thread id, so a recursive lock held by the caller is not its own there. The side effects of
/// `work` stay in the child.
void run_isolated(const std::function<void()>& work, const std::string& what,
                  const IsolateOptions& options = {});

}  // namespace btf
