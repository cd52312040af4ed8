// SPDX-License-Identifier: MIT
#pragma once
/// Output written under a temporary name in the destination's folder and renamed into place on
/// commit(), so an interrupted or failed run never leaves a truncated file that looks valid and
/// never destroys what the user had at that path.

#include <filesystem>
#include <memory>
#include <vector>

namespace btf {

class AtomicOutput {
  public:
    /// Prepares to write `destination` (a file, or a folder when `directory` is true). Throws
    /// btf::Error if the destination's folder does not exist, or if `destination` is an existing
    /// folder (folders are never replaced).
    explicit AtomicOutput(std::filesystem::path destination, bool directory = false);
    /// Removes the temporary file or folder unless commit() succeeded.
    ~AtomicOutput();
    AtomicOutput(const AtomicOutput&) = delete;
    AtomicOutput& operator=(const AtomicOutput&) = delete;

    /// Where to write now: a file path, or an existing empty folder.
    const std::filesystem::path& temp_path() const { return m_temp; }
    const std::filesystem::path& destination() const { return m_destination; }

    /// Renames the temporary into place (replacing an existing file atomically).
    void commit();

    /// Removes every temporary of every AtomicOutput and AtomicOutputSet that has not been
    /// committed: for a process about to end at once (the CLI's second signal, or a cancellation
    /// that does not unwind in time), so that it still leaves no partial output.
    static void remove_all_temporaries() noexcept;

  private:
    std::filesystem::path m_destination;
    std::filesystem::path m_temp;
    bool m_directory;
    bool m_committed = false;
};

/// Several output files that appear together or not at all (an image and its companions): each
/// is written to the temporary name add() returns, and commit() moves them all into place. If
/// the run fails before commit(), every temporary is removed and no destination is touched.
class AtomicOutputSet {
  public:
    AtomicOutputSet() = default;
    ~AtomicOutputSet();
    AtomicOutputSet(const AtomicOutputSet&) = delete;
    AtomicOutputSet& operator=(const AtomicOutputSet&) = delete;

    /// Checks `destination` like AtomicOutput and returns where to write it now: a hidden name in
    /// its folder that keeps its extension (image libraries choose the format by it).
    std::filesystem::path add(std::filesystem::path destination);
    /// Moves every file into place; each must have been written.
    void commit();

  private:
    std::vector<std::unique_ptr<AtomicOutput>> m_outputs;
    std::vector<std::filesystem::path> m_written;
    bool m_committed = false;
};

}  // namespace btf
