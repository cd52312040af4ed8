// SPDX-License-Identifier: MIT
#pragma once
/// The headless BSVTF simulator (`btf bsvtf-sim`): how the method behaves without a GPU.
///
/// A scene (docs/scenes.md) whose BTF objects use fmf packages is rendered along a camera path.
/// Each material is preprocessed (pyramid.h, tile_codec.h); then every frame
///  1. traces a feedback image at 1/feedback_divisor of the resolution: per pixel the material,
///     its texture position and the level the frame needs there (equation 1: the level whose
///     texels are as large as the pixel's footprint, from the texture positions of neighbouring
///     pixels), as votes (equation 9);
///  2. requests what the cache needs most from a simulated server over a link of `bandwidth`
///     bits per second: tiles (add candidates, P = w·v), the coarsest tiles and the Eigen-ABRDF
///     packets U_g (priority Σ v·‖T‖² over the group's tiles, §6), keeping about two frames of
///     data in flight; what arrives is decoded into the client's LRU store of tiles;
///  3. applies add and swap operations with the decision rule of §5.2, using tiles the store
///     holds;
///  4. renders the frame through the CPU evaluator (evaluator.h) from the tiles the cache shows
///     (a group whose U_g or tile has not arrived contributes nothing), direct light from the
///     scene's point and directional lights with shadows, and the same frame from the full FMF
///     data — every group at the level the pixel needs, uncompressed — and compares them (SSIM,
///     PSNR, ΔE00 of the tone-mapped frames).
///
/// With bandwidth 0 the link is unlimited: each frame repeats steps 2 and 3 until the cache
/// settles, so the frames show what a cache of that size can hold (the converged state).

#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include "btf/bsvtf/pyramid.h"
#include "btf/core/image.h"
#include "btf/core/math.h"
#include "btf/util/progress.h"

namespace btf::bsvtf {

struct CameraPose {
    Vec3 position, look_at;
};

/// {"frames": N, "keys": [{"frame": F, "position": [x, y, z], "look_at": [x, y, z]}, …]}: poses
/// interpolated linearly between keys (held before the first and after the last).
struct CameraPath {
    int frames = 1;
    std::vector<std::pair<double, CameraPose>> keys;
    CameraPose at(int frame) const;
};
/// Throws btf::Error naming the file and the problem.
CameraPath read_camera_path(const std::filesystem::path& path);

struct SimOptions {
    int cache = 2048;          ///< side of the tile cache in texels: (cache / stride)² tiles
    double bandwidth = 10e6;   ///< bits per second; 0 = unlimited
    double fps = 30;           ///< frames per second of the path (the link's time per frame)
    int feedback_divisor = 4;  ///< the feedback image is this much smaller in each direction
    TileGeometry geometry{64, 4};
    double tile_error = 0.01;          ///< the tile codec's relative error; 0 = lossless
    uint64_t store_bytes = 256 << 20;  ///< the client's store of received tiles
    int operations = 256;              ///< cache operations per frame at most
    int width = 0, height = 0;         ///< frame size; 0 = the scene camera's
};

struct SimMaterial {
    std::string file;
    int width = 0, height = 0, components = 0, levels = 0;
    size_t tiles = 0;
    double prep_seconds = 0;
    uint64_t raw_tile_bytes = 0, encoded_tile_bytes = 0;
    uint64_t u_bytes = 0;    ///< all U packets (the angular factors)
    uint64_t fmf_bytes = 0;  ///< the factors in half floats: a and b, what plain FMF holds
    double codec_error = 0;  ///< EncodedPyramid::relative_rms_error
};

struct SimFrame {
    int frame = 0;
    double time = 0;          ///< seconds of the path
    uint64_t bytes = 0;       ///< received so far (tiles and U packets)
    uint64_t tile_bytes = 0;  ///< of them tiles
    int resident = 0;         ///< tiles in the cache
    int adds = 0, swaps = 0;  ///< operations in this frame
    int pending = 0;          ///< requests not yet received
    double ssim = 0, psnr = 0, de2000 = 0;
};

struct SimReport {
    std::vector<SimMaterial> materials;
    std::vector<SimFrame> frames;
    int capacity = 0;          ///< tiles
    uint64_t cache_bytes = 0;  ///< capacity × tile size (half floats, RGBA)
    int width = 0, height = 0;
};

/// Receives each frame's linear images and the scene's exposure (EV for tone mapping).
using FrameCallback = std::function<void(const SimFrame&, const Image& rendered,
                                         const Image& reference, double exposure)>;

/// Runs the simulation. Throws btf::Error for a scene without point or directional light, a BTF
/// object whose material is not an fmf package, or a cache too small for the coarsest tiles.
SimReport simulate(const std::filesystem::path& scene, const CameraPath& path,
                   const SimOptions& options, Progress& progress,
                   const FrameCallback& on_frame = {});

}  // namespace btf::bsvtf
