// SPDX-License-Identifier: MIT
// Wavefront OBJ meshes (render/mesh.h): load_obj() of any text (written to a scratch file: the
// reader takes a path). What it returns must be consistent: whole triangles, indices in range and
// every per-vertex array of the vertex count.
#include <cstdlib>

#include "btf/render/mesh.h"
#include "fuzz/support/fuzz.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    const std::filesystem::path path = btf::fuzz::write_scratch("input.obj", {data, size});
    return btf::fuzz::run([&] {
        const btf::render::TriangleMesh mesh = btf::render::load_obj(path);
        const size_t n = mesh.vertex_count();
        if (mesh.positions.size() != 3 * n || mesh.normals.size() != 3 * n ||
            mesh.uvs.size() != 2 * n || mesh.tangents.size() != 3 * n ||
            mesh.indices.size() % 3 != 0)
            std::abort();
        for (uint32_t i : mesh.indices)
            if (i >= n) std::abort();
    });
}
