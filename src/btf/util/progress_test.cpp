// SPDX-License-Identifier: MIT
#include "btf/util/progress.h"

#include <gtest/gtest.h>

#include <vector>

#include "btf/util/error.h"
#include "btf/util/parallel.h"

namespace btf {
namespace {

TEST(Progress, ReportsStagesAndCountsFromManyThreads) {
    std::vector<std::string> stages;
    uint64_t last_done = 0, last_total = 0;
    Progress progress([&](std::string_view stage, uint64_t done, uint64_t total) {
        if (stages.empty() || stages.back() != stage) stages.emplace_back(stage);
        last_done = done, last_total = total;
    });
    progress.begin("reading", 1000);
    parallel_for(0, 1000, [&](int64_t) { progress.advance(); });
    EXPECT_EQ(progress.done(), 1000u);
    progress.finish();
    EXPECT_EQ(last_done, 1000u);
    EXPECT_EQ(last_total, 1000u);
    progress.begin("writing", 5);
    EXPECT_EQ(stages, (std::vector<std::string>{"reading", "writing"}));
}

TEST(Progress, CancellationThrows) {
    Progress progress;
    progress.begin("work", 10);
    progress.advance();
    progress.cancel();
    EXPECT_THROW(progress.advance(), Cancelled);
    EXPECT_THROW(progress.poll(), Cancelled);
}

TEST(Parallel, ChunksDoNotDependOnThreadCount) {
    auto chunk_sums = [](int threads) {
        ThreadLimit limit(threads);
        std::vector<double> sums(10);
        parallel_chunks(0, 1000, 100, [&](int64_t b, int64_t e) {
            double s = 0;
            for (int64_t i = b; i < e; ++i) s += 1.0 / (i + 1);
            sums[b / 100] = s;
        });
        return sums;
    };
    EXPECT_EQ(chunk_sums(1), chunk_sums(2));
}

}  // namespace
}  // namespace btf
