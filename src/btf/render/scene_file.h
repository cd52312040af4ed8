// SPDX-License-Identifier: MIT
#pragma once
/// Scenes as JSON files (the format is documented in docs/scenes.md). Every key is checked: an
/// unknown or misspelt key, a value of the wrong type or range, or a file that cannot be read is
/// an error naming the scene file and the place, e.g.
/// `scene.json: objects[1].material: unknown key "albedoo"`. Paths in the scene resolve relative
/// to the scene file's directory.

#include <cmath>
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

/// What a caller changes of a scene's "render" block (`btf render`'s options, Python's
/// btfkit.render keywords); unset fields keep the scene's.
struct RenderOverrides {
    std::string integrator;     ///< "path" or "direct"; empty: the scene's
    int spp = -1;               ///< samples per pixel; 0 = until time_limit; < 0: the scene's
    int max_depth = -1;         ///< surface interactions per path (path only); < 0: the scene's
    double time_limit = -1;     ///< seconds; < 0: the scene's
    int64_t seed = -1;          ///< < 0: the scene's
    std::string filter;         ///< "stochastic" or "deterministic"; empty: the scene's
    int width = 0, height = 0;  ///< image size; 0: the camera's
    bool aovs = false;
    double exposure = NAN;  ///< EV for tone mapping; NaN: the scene's
};

/// A scene's render options and exposure with `overrides` applied.
struct RenderSetup {
    RenderOptions options;
    double exposure = 0;
};
/// Applies `overrides` to the loaded scene's settings (resizing its camera for a new size).
/// Throws btf::Error for a combination that cannot work: max_depth with the direct integrator,
/// spp 0 without a time limit, a size outside 1..16384.
RenderSetup apply_overrides(LoadedScene& loaded, const RenderOverrides& overrides);

/// Opens a material file for rendering: a btfkit package, a UBO2014 .btf file (its
/// factorization), or any raw BTF a reader recognizes (held in memory uncompressed:
/// SampledMaterial). Throws btf::Error naming the file.
std::shared_ptr<const Material> open_material_file(const std::filesystem::path& path);

}  // namespace btf::render
