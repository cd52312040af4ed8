#pragma once
/// Output written under a temporary name in the destination's folder and renamed into place on
/// commit(), so an interrupted or failed run never leaves a truncated file that looks valid and
/// never destroys what the user had at that path.

#include <filesystem>

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

  private:
    std::filesystem::path m_destination;
    std::filesystem::path m_temp;
    bool m_directory;
    bool m_committed = false;
};

}  // namespace btf
