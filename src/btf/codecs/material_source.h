// SPDX-License-Identifier: MIT
#pragma once
/// MaterialSource: a decoded Material seen as a BtfSource, so that everything that reads raw BTFs
/// (the HDF5 and UTIA writers, the slicer, the metrics) reads a compressed material the same way,
/// and so that every error measure compares two sources.

#include <filesystem>
#include <memory>
#include <string>

#include "btf/core/material.h"
#include "btf/io/open.h"
#include "btf/io/source.h"
#include "btf/util/progress.h"

namespace btf {

class MaterialSource final : public BtfSource {
  public:
    /// `codec` names the decoder ("fmf"); info().format is "btfkit package (<codec>)" and
    /// info().path is `path`. `hdr` says whether values may exceed 1 (it picks the image format
    /// writers choose by default).
    MaterialSource(std::shared_ptr<const Material> material, const std::string& codec,
                   std::filesystem::path path = {}, bool hdr = false);

    int width() const override { return m_material->width(); }
    int height() const override { return m_material->height(); }
    const Sampling& sampling() const override { return m_material->sampling(); }
    const SourceInfo& info() const override { return m_info; }

    /// The image of view `view` and light `light`: Material::eval_sample at every texel.
    /// Thread-safe as Material evaluation is.
    void read_image(int view, int light, Image& out) const override;

    const Material& material() const { return *m_material; }

  private:
    std::shared_ptr<const Material> m_material;
    SourceInfo m_info;
};

/// Opens a btfkit package file (or a clean prefix of one) with the codec its header names.
/// info().hdr is taken from the header's "hdr" field when the codec stores one.
std::unique_ptr<MaterialSource> open_package_source(const std::filesystem::path& path);

/// Any input a measurement takes: a btfkit package decoded through its codec
/// (open_package_source(), `options` not applying), or a BTF that a reader opens.
std::unique_ptr<BtfSource> open_package_or_source(const std::filesystem::path& path,
                                                  const OpenOptions& options = {});

/// Root-mean-square difference, over every texel, view, light and RGB channel (linear values),
/// between `reference` and `material` evaluated at the reference's sample indices. Reads the
/// reference image by image, in parallel; one progress unit per image (stage "measuring error").
/// Across the ranks of a current_collective(), each reads its share of the views.
/// Throws btf::Error naming the reference when extent or direction counts differ.
double sample_rmse(const BtfSource& reference, const Material& material,
                   Progress& progress = Progress::none());

}  // namespace btf
