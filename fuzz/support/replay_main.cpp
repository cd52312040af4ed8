// SPDX-License-Identifier: MIT
// The main() of the replay programs (replay_<target>): runs every file of the folders (or files)
// named on the command line through the target's LLVMFuzzerTestOneInput, in name order, so that
// `make test` replays each fuzz corpus and every crash reproducer in the normal build. A missing
// folder counts as empty (a target without regressions has no fuzz/regressions/<target>/), but
// no input at all is a failure.
// Anything but a normal return is a failure: the process crashes, or an exception escapes and
// the program names the input and fails.
#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <exception>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <vector>

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size);

// The custom mutators call libFuzzer's mutator, which a replay program does not have; they are
// never called here.
extern "C" size_t LLVMFuzzerMutate(uint8_t*, size_t size, size_t) {
    return size;
}

namespace fs = std::filesystem;

int main(int argc, char** argv) {
    std::vector<fs::path> inputs;
    for (int i = 1; i < argc; ++i) {
        const fs::path arg = argv[i];
        std::error_code ec;
        if (fs::is_directory(arg, ec)) {
            for (const fs::directory_entry& e : fs::recursive_directory_iterator(arg))
                if (e.is_regular_file() && !e.path().filename().string().starts_with("."))
                    inputs.push_back(e.path());
        } else if (fs::is_regular_file(arg, ec)) {
            inputs.push_back(arg);
        }
    }
    std::sort(inputs.begin(), inputs.end());
    if (inputs.empty()) {
        // Every target has a seed corpus: none found means a wrong folder, not a pass.
        std::fprintf(stderr, "replay: no inputs found in the folders given\n");
        return 1;
    }
    for (const fs::path& input : inputs) {
        std::ifstream in(input, std::ios::binary);
        const std::vector<uint8_t> bytes((std::istreambuf_iterator<char>(in)),
                                         std::istreambuf_iterator<char>());
        if (!in.eof() && in.fail()) {
            std::fprintf(stderr, "replay: cannot read %s\n", input.c_str());
            return 1;
        }
        try {
            LLVMFuzzerTestOneInput(bytes.data(), bytes.size());
        } catch (const std::exception& e) {
            std::fprintf(stderr, "replay: %s: uncaught exception: %s\n", input.c_str(), e.what());
            return 1;
        } catch (...) {
            std::fprintf(stderr, "replay: %s: uncaught exception of unknown type\n", input.c_str());
            return 1;
        }
    }
    std::printf("replay: %zu inputs ran without a crash\n", inputs.size());
    return 0;
}
