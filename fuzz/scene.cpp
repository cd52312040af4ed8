// SPDX-License-Identifier: MIT
// Scene files (render/scene_file.h): parse_scene() of any text, with relative paths resolving
// to fuzz/data/ (a tiny OBJ mesh and a tiny package that make_corpus.sh writes there).
#include "btf/render/scene_file.h"
#include "fuzz/support/fuzz.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    static const std::filesystem::path base = std::filesystem::path(BTF_SOURCE_DIR) / "fuzz/data";
    return btf::fuzz::run([&] {
        const std::string text(reinterpret_cast<const char*>(data), size);
        (void)btf::render::parse_scene(text, "scene.json", base);
    });
}
