// SPDX-License-Identifier: MIT
#pragma once
/// btfkit's public API in one include: `#include <btf/btf.h>`.
///
/// The installed headers are exactly this file and what it includes, directly or not
/// (cmake/install.cmake computes that closure at configure time); the rest of src/btf (codec
/// internals, kernels, the server, BSVTF) stays private to the library. A header added here is
/// installed by the next configure. docs/library.md shows the API at work.
///
/// The flow of data, left to right (DESIGN.md):
///
///     open_source / synth::make ─► BtfSource ─► find_codec(name).encode ─► Package
///     write_package / read_package ─► open_material ─► Material (eval, sample, pdf, albedo)
///     MaterialSource (a Material as a BtfSource) ─► quality::measure, h5::write, slice_image,
///                                                   utia::write
///     render::load_scene ─► render::render ─► render::write_render

// The version (btf::version()).
#include "btf/version.h"

// Errors (btf::Error, btf::Cancelled) and progress reports of long operations.
#include "btf/util/error.h"
#include "btf/util/progress.h"

// Directions, direction sets, images and the Material interface.
#include "btf/core/direction.h"
#include "btf/core/image.h"
#include "btf/core/material.h"

// Raw BTFs: the BtfSource interface, the readers (open_source), the writers of btfkit's HDF5 form
// and of UTIA image sets, pictures at any direction, value statistics.
#include "btf/io/h5.h"
#include "btf/io/inspect.h"
#include "btf/io/open.h"
#include "btf/io/slice.h"
#include "btf/io/source.h"
#include "btf/io/utia.h"

// Synthetic materials (synth::make, synth::preset_names).
#include "btf/synth/synth.h"

// Compression: the codec registry, packages on disk, decoded materials seen as sources.
#include "btf/codecs/codec.h"
#include "btf/codecs/material_source.h"
#include "btf/io/package.h"

// Fidelity: the measures of `btf quality` (quality::measure), the per-image metrics, the
// comparison of rendered pictures and the compression report of `btf report`.
#include "btf/quality/measure.h"
#include "btf/quality/metrics.h"
#include "btf/quality/render_compare.h"
#include "btf/quality/report.h"

// Rendering: scene files and the path tracer.
#include "btf/render/renderer.h"
#include "btf/render/scene_file.h"
