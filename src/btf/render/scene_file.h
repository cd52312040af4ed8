#pragma once
/// Scenes as JSON files (the format is documented in docs/scenes.md). Every key is checked: an
/// unknown or misspelt key, a value of the wrong type or range, or a file that cannot be read is
/// an error naming the scene file and the place, e.g.
/// `scene.json: objects[1].material: unknown key "albedoo"`. Paths in the scene resolve relative
/// to the scene file's directory.

#include <filesystem>
#include <functional>
#include <memory>
#include <string>

#include "btf/core/material.h"
#include "btf/render/renderer.h"
#include "btf/render/scene.h"

namespace btf::render {

/// The "render" block of a scene: how to render it unless the command line says otherwise.
struct SceneSettings {
    std::string integrator = "path";  ///< "path" or "direct" (options.integrator.max_depth 1)
    RenderOptions options;
    double exposure = 0;  ///< EV for the tone-mapped PNG
};

struct LoadOptions {
    SamplingMode sampling = SamplingMode::kMaterial;
    /// When set, every object whose material is a BTF file gets this material instead (the
    /// compare mode renders one scene with two versions of a material); its "file" may then be
    /// left out and is not opened.
    std::shared_ptr<const Material> btf_override;
};

struct LoadedScene {
    Scene scene;
    SceneSettings settings;
    int btf_objects = 0;  ///< objects whose material is a BTF file
};

/// Reads, validates and commits a scene.
LoadedScene load_scene(const std::filesystem::path& path, const LoadOptions& options = {});
/// The same from JSON text; `name` stands for the file in errors and `base` is the directory
/// relative paths resolve against.
LoadedScene parse_scene(const std::string& json, const std::string& name,
                        const std::filesystem::path& base, const LoadOptions& options = {});

/// Opens a material file for rendering: a btfkit package, a UBO2014 .btf file (its
/// factorization), or any raw BTF a reader recognizes (held in memory uncompressed:
/// SampledMaterial). Throws btf::Error naming the file.
std::shared_ptr<const Material> open_material_file(const std::filesystem::path& path);

}  // namespace btf::render
