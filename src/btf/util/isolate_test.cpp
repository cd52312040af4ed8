// SPDX-License-Identifier: MIT
#include "btf/util/isolate.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <csignal>
#include <cstdlib>
#include <filesystem>
#include <iterator>
#include <string>
#include <thread>

#include "btf/util/error.h"
#include "btf/util/progress.h"

namespace btf {
namespace {

using ::testing::HasSubstr;

std::string isolated_error(const std::function<void()>& work, const IsolateOptions& options = {}) {
    try {
        run_isolated(work, "input.x: somelib", options);
    } catch (const Error& e) {
        return e.what();
    }
    return "(no error)";
}

TEST(Isolate, ReturnsWhenTheWorkReturnsAndKeepsItsEffectsInTheChild) {
    int touched = 0;
    EXPECT_NO_THROW(run_isolated([&] { touched = 1; }, "input.x: somelib"));
    EXPECT_EQ(touched, 0);
}

TEST(Isolate, PassesOnTheChildsError) {
    EXPECT_EQ(isolated_error([] { fail("input.x: byte {}: bad magic", 12); }),
              "input.x: byte 12: bad magic");
    EXPECT_EQ(isolated_error([] { throw std::out_of_range("vector index"); }), "vector index");
    EXPECT_EQ(isolated_error([] { throw 7; }), "unknown error");
}

TEST(Isolate, ACrashInTheChildIsAnErrorHere) {
    EXPECT_EQ(isolated_error([] { std::raise(SIGKILL); }),
              fmt::format("input.x: somelib crashed ({}); the input is damaged or crafted",
                          ::strsignal(SIGKILL)));
    // (Under AddressSanitizer a segmentation fault is its report and exit status 1.)
    EXPECT_THAT(isolated_error([] { std::raise(SIGSEGV); }),
                HasSubstr("input.x: somelib crashed ("));
    EXPECT_THAT(isolated_error([] { std::abort(); }), HasSubstr("input.x: somelib crashed ("));
    EXPECT_EQ(isolated_error([] { ::_exit(3); }),
              "input.x: somelib crashed (exit status 3); the input is damaged or crafted");
    // Exit status 0 without a report (the work called exit()) is no success either.
    EXPECT_EQ(isolated_error([] { ::_exit(0); }),
              "input.x: somelib crashed (exit status 0); the input is damaged or crafted");
}

TEST(Isolate, AChildThatNeverFinishesIsKilledAtTheTimeout) {
    IsolateOptions options;
    options.timeout = std::chrono::seconds(1);
    EXPECT_EQ(isolated_error(
                  [] {
                      for (;;) ::pause();
                  },
                  options),
              "input.x: somelib did not finish within 1 s; the input is damaged or crafted");
}

TEST(Isolate, LongMessagesAndOtherThreadsInTheParent) {
    // A busy thread in the parent does not exist in the child, and a long message arrives whole.
    std::atomic<bool> stop{false};
    std::thread busy([&] {
        while (!stop.load()) std::this_thread::yield();
    });
    const auto threads = [] {
        namespace fs = std::filesystem;
        return std::distance(fs::directory_iterator("/proc/self/task"), fs::directory_iterator{});
    };
    ASSERT_GE(threads(), 2);
    const std::string message(20000, 'm');
    EXPECT_EQ(isolated_error([&] { throw Error(std::to_string(threads()) + " " + message); }),
              "1 " + message);
    stop.store(true);
    busy.join();
}

TEST(Isolate, CancellationKillsTheChild) {
    // Progress::cancel_all() cannot be undone, so it is tried in a process of its own.
    const pid_t tester = ::fork();
    ASSERT_GE(tester, 0);
    if (tester == 0) {
        // Cancelled before the wait starts or during it: either way the child is killed and
        // the wait throws btf::Cancelled (no timing involved).
        std::thread canceller([] { Progress::cancel_all(); });
        int outcome = 1;
        try {
            run_isolated(
                [] {
                    for (;;) ::pause();
                },
                "input.x: somelib");
        } catch (const Cancelled&) {
            outcome = 0;
        } catch (...) {
            outcome = 2;
        }
        canceller.join();
        ::_exit(outcome);
    }
    int status = 0;
    ASSERT_EQ(::waitpid(tester, &status, 0), tester);
    ASSERT_TRUE(WIFEXITED(status));
    EXPECT_EQ(WEXITSTATUS(status), 0);
}

}  // namespace
}  // namespace btf
