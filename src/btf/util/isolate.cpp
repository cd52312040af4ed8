// SPDX-License-Identifier: MIT
#include "btf/util/isolate.h"

#include <fcntl.h>
#include <poll.h>
#include <pthread.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <csignal>
#include <cstring>
#include <exception>

#include "btf/util/error.h"
#include "btf/util/progress.h"

namespace btf {

namespace {

constexpr char kReturned = 'O';
constexpr char kThrew = 'E';
constexpr size_t kMaxMessage = 64 * 1024;  ///< longer reports from the child are cut
constexpr int kPollMs = 50;                ///< how often the wait looks at cancellation

void write_all(int fd, const char* data, size_t size) {
    while (size > 0) {
        const ssize_t n = ::write(fd, data, size);
        if (n < 0 && errno == EINTR) continue;
        if (n <= 0) return;
        data += n;
        size -= size_t(n);
    }
}

constexpr int kChildDefaultSignals[] = {SIGINT, SIGTERM, SIGHUP, SIGQUIT};

/// Starts with every signal blocked (run_isolated() blocks them around the fork).
[[noreturn]] void run_child(const std::function<void()>& work, int report, pid_t parent,
                            const sigset_t& unblocked) {
    // Die with the parent (its watchdog may end it without unwinding to the wait below).
    ::prctl(PR_SET_PDEATHSIG, SIGKILL);
    if (::getppid() != parent) ::_exit(1);
    // A terminal's ^C reaches the whole process group: the child just dies, and the parent,
    // which got the same signal, handles it. The parent's handlers (the CLI's cancellation) must
    // not run here, so signals stay blocked until they are reset.
    for (int sig : kChildDefaultSignals) std::signal(sig, SIG_DFL);
    ::pthread_sigmask(SIG_SETMASK, &unblocked, nullptr);
    if (const int null = ::open("/dev/null", O_WRONLY | O_CLOEXEC); null >= 0) ::dup2(null, 2);

    std::string message(1, kReturned);
    try {
        work();
    } catch (const std::exception& e) {
        message = std::string(1, kThrew) + e.what();
    } catch (...) {
        message = std::string(1, kThrew) + "unknown error";
    }
    if (message.size() > kMaxMessage) message.resize(kMaxMessage);
    write_all(report, message.data(), message.size());
    ::_exit(0);
}

/// Kills the child (if still there) and reaps it; returns its wait status.
int reap(pid_t child, bool kill_first) {
    if (kill_first) ::kill(child, SIGKILL);
    int status = 0;
    while (::waitpid(child, &status, 0) < 0 && errno == EINTR) {
    }
    return status;
}

}  // namespace

void run_isolated(const std::function<void()>& work, const std::string& what,
                  const IsolateOptions& options) {
    int fds[2];
    if (::pipe2(fds, O_CLOEXEC) != 0)
        fail("{} cannot be run in a process of its own: {}", what, std::strerror(errno));
    const pid_t parent = ::getpid();
    sigset_t all, before;
    ::sigfillset(&all);
    ::pthread_sigmask(SIG_BLOCK, &all, &before);
    const pid_t child = ::fork();
    if (child == 0) {
        ::close(fds[0]);
        run_child(work, fds[1], parent, before);
    }
    const int fork_error = errno;
    ::pthread_sigmask(SIG_SETMASK, &before, nullptr);
    if (child < 0) {
        ::close(fds[0]);
        ::close(fds[1]);
        fail("{} cannot be run in a process of its own: {}", what, std::strerror(fork_error));
    }
    ::close(fds[1]);
    const int report = fds[0];

    std::string message;
    const auto deadline = std::chrono::steady_clock::now() + options.timeout;
    bool timed_out = false;
    int broken = 0;  // errno of a failed poll or read: the child is killed, not waited for
    for (;;) {
        if (Progress::all_cancelled()) {
            ::close(report);
            reap(child, true);
            Progress::check_all();
        }
        if (std::chrono::steady_clock::now() >= deadline) {
            timed_out = true;
            break;
        }
        pollfd p{report, POLLIN, 0};
        const int ready = ::poll(&p, 1, kPollMs);
        if (ready < 0 && errno != EINTR) {
            broken = errno;
            break;
        }
        if (ready <= 0) continue;
        char buffer[4096];
        const ssize_t n = ::read(report, buffer, sizeof buffer);
        if (n < 0 && errno == EINTR) continue;
        if (n < 0) {
            broken = errno;
            break;
        }
        if (n == 0) break;  // end of the report: the child has finished or died
        if (message.size() < kMaxMessage) message.append(buffer, size_t(n));
    }
    ::close(report);
    const int status = reap(child, timed_out || broken != 0);
    Progress::check_all();

    if (broken) fail("{} could not be watched in its own process: {}", what, std::strerror(broken));
    if (timed_out)
        fail("{} did not finish within {} s; the input is damaged or crafted", what,
             options.timeout.count());
    if (WIFEXITED(status) && WEXITSTATUS(status) == 0 && !message.empty()) {
        if (message[0] == kReturned) return;
        if (message[0] == kThrew) throw Error(message.substr(1));
    }
    if (WIFSIGNALED(status))
        fail("{} crashed ({}); the input is damaged or crafted", what,
             ::strsignal(WTERMSIG(status)));
    fail("{} crashed (exit status {}); the input is damaged or crafted", what,
         WIFEXITED(status) ? WEXITSTATUS(status) : -1);
}

}  // namespace btf
