// SPDX-License-Identifier: MIT
#include "btf/util/atomic_file.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <fstream>
#include <sstream>

#include "btf/util/error.h"

namespace btf {
namespace {

namespace fs = std::filesystem;

std::string slurp(const fs::path& p) {
    std::ifstream in(p);
    std::stringstream ss;
    ss << in.rdbuf();
    return ss.str();
}

class AtomicOutputTest : public testing::Test {
  protected:
    void SetUp() override {
        m_dir = fs::path(testing::TempDir()) / ("btf_atomic_test_" + std::to_string(::getpid()));
        fs::remove_all(m_dir);
        fs::create_directories(m_dir);
    }
    void TearDown() override { fs::remove_all(m_dir); }
    fs::path m_dir;
};

TEST_F(AtomicOutputTest, CommitReplacesAndFailureKeepsOld) {
    const fs::path target = m_dir / "out.txt";
    std::ofstream(target) << "old";
    {
        AtomicOutput out(target);
        std::ofstream(out.temp_path()) << "half-written";
        // No commit: the destructor must remove the temporary and leave the old file alone.
    }
    EXPECT_EQ(slurp(target), "old");
    EXPECT_EQ(std::distance(fs::directory_iterator(m_dir), fs::directory_iterator()), 1);
    {
        AtomicOutput out(target);
        std::ofstream(out.temp_path()) << "new";
        out.commit();
    }
    EXPECT_EQ(slurp(target), "new");
}

TEST_F(AtomicOutputTest, FolderOutput) {
    const fs::path target = m_dir / "set";
    {
        AtomicOutput out(target, true);
        std::ofstream(out.temp_path() / "a.txt") << "a";
    }
    EXPECT_FALSE(fs::exists(target));
    {
        AtomicOutput out(target, true);
        std::ofstream(out.temp_path() / "a.txt") << "a";
        out.commit();
    }
    EXPECT_EQ(slurp(target / "a.txt"), "a");
    // An existing folder is never replaced.
    EXPECT_THROW(AtomicOutput(target, true), Error);
}

TEST_F(AtomicOutputTest, MissingParentFolderIsAnError) {
    try {
        AtomicOutput out(m_dir / "no" / "such" / "file.h5");
        FAIL();
    } catch (const Error& e) {
        EXPECT_NE(std::string(e.what()).find("does not exist"), std::string::npos) << e.what();
    }
}

}  // namespace
}  // namespace btf
