// SPDX-License-Identifier: MIT
#pragma once
/// What the fuzz targets in fuzz/ share. A target is one fuzz/<name>.cpp that defines
/// LLVMFuzzerTestOneInput; it is built twice (CMakeLists.txt): as a libFuzzer program
/// (fuzz_<name>, `make fuzz`) and as a plain program (replay_<name>, replay_main.cpp) that
/// `make test` runs over fuzz/corpus/<name>/ and fuzz/regressions/<name>/.
///
/// The contract every target checks: whatever the input, the code under test either succeeds or
/// throws btf::Error. Any other exception escaping, a crash, a sanitizer report, a hang or an
/// allocation beyond libFuzzer's limits is a bug.
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "btf/core/material.h"
#include "btf/io/source.h"
#include "btf/util/error.h"

namespace btf::fuzz {

/// Prints the message of a btf::Error that ended a run when the environment variable
/// BTF_FUZZ_VERBOSE is set (to see what a seed or a reproducer reaches).
void report(const Error& error);

/// Runs `body`; a btf::Error (the expected answer to bad input) ends the run quietly. Every other
/// exception propagates, and libFuzzer (or the replay program) reports it as a crash.
template <typename Body>
int run(Body&& body) {
    try {
        body();
    } catch (const Error& e) {
        report(e);
    }
    return 0;
}

/// A few evaluations of everything a Material offers, so that decoders run on what was opened:
/// eval at some positions and directions, eval_sample at the corners, one batch, one light sample
/// and one pdf. Results are not checked (there is no expected value for random input); the
/// sanitizers watch the work.
void exercise(const Material& material);

/// Reads a few images of `source` (the first, the last, one in the middle) and looks at them.
void exercise(const BtfSource& source);

/// A folder of this process's own under the temporary directory (/dev/shm when it exists: the
/// readers that take paths are given files written there), created on first use and removed at
/// exit.
const std::filesystem::path& scratch_dir();

/// Writes `bytes` to scratch_dir()/name (replacing it) and returns the path.
std::filesystem::path write_scratch(const std::string& name, std::span<const uint8_t> bytes);

/// Splits `data` into lines (at '\n'; a '\r' before it is dropped).
std::vector<std::string> lines(std::span<const uint8_t> data);

/// A relative path made of the components of `line` that are safe to create below a folder: no
/// empty, "." or ".." component, no NUL, at most `max_depth` components of at most 200 bytes.
/// Empty when `line` has none.
std::filesystem::path safe_relative_path(const std::string& line, int max_depth);

}  // namespace btf::fuzz

namespace btf::fuzz {

/// The package in `data` (decode_package(), checksums verified) opened by the codec `codec`
/// from the registry, whatever codec its header names, and exercised.
int open_with_codec(std::string_view codec, const uint8_t* data, size_t size);

}  // namespace btf::fuzz

namespace btf::fuzz {

/// A new folder scratch_dir()/name (what was there is removed) with one file per line of `data`
/// (safe_relative_path(), at most `max_depth` components, at most `max_files` files; other lines
/// are skipped). A file whose name ends in .png, .jpg, .jpeg, .hdr or .exr is a tiny valid image
/// of that format (a hard link to one made once per process); any other file is empty.
std::filesystem::path image_folder(const std::string& name, std::span<const uint8_t> data,
                                   int max_depth, size_t max_files);

}  // namespace btf::fuzz
