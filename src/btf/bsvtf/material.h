// SPDX-License-Identifier: MIT
#pragma once
/// A BSVTF file as a material for every command (`btf eval`, `decompress`, `quality`, `render`):
/// all its tiles decoded, and the finest level's texels taken as the eigen-textures of the fmf
/// model it was made from. That is the Evaluator (evaluator.h) with the finest tile of every
/// group resident — the value a BSVTF renderer converges to — evaluated by FactorMaterial, so that
/// it is the source fmf package's value up to the tile codec's error and half-float rounding.

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "btf/bsvtf/file.h"
#include "btf/core/material.h"
#include "btf/io/package.h"
#include "btf/util/progress.h"

namespace btf::bsvtf {

/// Every tile decoded (coarsest level first, each against its decoded parent, as a receiver
/// decodes them): tile_count() × geometry().values() half-float bits, by TileLayout::index().
/// Throws btf::Error naming `what` and the tile for a damaged payload.
std::vector<uint16_t> decode_tiles(const Bsvtf& file, const std::string& what,
                                   Progress& progress = Progress::none());

/// The fmf model of `file` with each block's b filled from the finest tiles of `decoded`; throws
/// btf::Error naming `what` when the eigen-textures would exceed the allocation limit.
factor::Model finest_model(const Bsvtf& file, const std::vector<uint16_t>& decoded,
                           const std::string& what);

/// read_bsvtf(), decode_tiles() and finest_model() as a FactorMaterial; `what` names the file
/// in errors.
std::unique_ptr<Material> open_material(const Package& package, const std::string& what);

}  // namespace btf::bsvtf
