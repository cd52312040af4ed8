// SPDX-License-Identifier: MIT
#include "btf/codecs/dfmf_export.h"

#include <vector>

#include "btf/codecs/fmf/fmf.h"
#include "btf/util/error.h"

namespace btf {

ubo2014::Factorization to_dfmf(const factor::Model& model, int scalar_size,
                               const ubo2014::Meta& meta, const std::string& what) {
    model.validate(what);
    int32_t color_model = 0;
    if (model.colour.basis == factor::ColourBasis::kPerChannel)
        color_model = ubo2014::kColorModelRgb;
    else if (model.colour.basis == factor::ColourBasis::kUboModel11)
        color_model = ubo2014::kColorModelLogYUV;
    else
        fail(
            "{}: colour handling '{}' has no DFMF colour model (DFMF takes per-channel or model11)",
            what, factor::to_string(model.colour.basis));
    check(!model.colour.log, "{}: log colour has no DFMF colour model", what);
    check(model.levels == 1 && model.angular_levels.empty(),
          "{}: eigen-textures or eigen-ABRDFs at reduced resolution; DFMF holds full-resolution "
          "factors",
          what);
    check(model.groups.size() == 1 && model.clusters == 1,
          "{}: {} view groups and {} texel clusters; DFMF holds one factorization per channel",
          what, model.groups.size(), model.clusters);

    const int nv = model.sampling.num_views(), nl = model.sampling.num_lights();
    // Model rows run over the group's views in group order; DFMF rows in view order.
    std::vector<int> slot_of_view(nv, -1);
    for (size_t slot = 0; slot < model.groups[0].size(); ++slot)
        slot_of_view[model.groups[0][slot]] = static_cast<int>(slot);

    ubo2014::Factorization f;
    f.body = ubo2014::Body::kDfmf;
    f.meta = meta;
    f.sampling = model.sampling;
    f.width = model.width;
    f.height = model.height;
    f.color_model = color_model;
    for (int plane = 0; plane < 3; ++plane) {
        const factor::Block& block = model.blocks[model.block_index(plane, 0, 0)];
        check(block.mean.empty(), "{}: channel {} has row means, which DFMF cannot hold", what,
              plane);
        const int k = block.components();
        ubo2014::Factor factor;
        factor.scalar_size = scalar_size;
        factor.s.resize(k);
        for (int i = 0; i < k; ++i) factor.s[i] = block.energy[i];
        factor.u.resize(int64_t(nv) * nl, k);
        for (int v = 0; v < nv; ++v)
            factor.u.middleRows(int64_t(v) * nl, nl) =
                block.a.middleRows(int64_t(slot_of_view[v]) * nl, nl);
        factor.sxv = block.b;
        f.factors.push_back(std::move(factor));
    }
    f.validate(what);
    return f;
}

factor::Model model_of(const ubo2014::Factorization& f, const std::string& what) {
    f.validate(what);
    check(!f.meta.cosine_flag,
          "{}: the values are multiplied by cos θ_light (meta cosine flag), which btfkit's factor "
          "model does not hold yet",
          what);
    factor::Model model;
    model.width = f.width;
    model.height = f.height;
    model.sampling = f.sampling;
    model.hdr = true;  // measured values, in the lab's units: nothing bounds them by 1
    model.groups.emplace_back();
    for (int v = 0; v < f.sampling.num_views(); ++v) model.groups[0].push_back(v);
    const auto block_of = [](const ubo2014::Factor& factor, int plane) {
        factor::Block block;
        block.plane = plane;
        block.a = factor.u;
        block.b = factor.sxv;
        block.energy.assign(factor.s.data(), factor.s.data() + factor.s.size());
        return block;
    };
    if (f.body == ubo2014::Body::kDfmf) {
        model.colour.basis = f.color_model == ubo2014::kColorModelLogYUV
                                 ? factor::ColourBasis::kUboModel11
                                 : factor::ColourBasis::kPerChannel;
        for (int plane = 0; plane < 3; ++plane)
            model.blocks.push_back(block_of(f.factors[size_t(plane)], plane));
    } else {
        // FMF rows are (view·nL + light)·3 + channel: the rgb plane's rows, views in order.
        model.colour.basis = factor::ColourBasis::kRgb;
        model.colour.log = f.dynamic_range_reduction != 0;
        model.colour.log_eps = ubo2014::kDynamicRangeEps;
        model.blocks.push_back(block_of(f.factors[0], 0));
    }
    model.validate(what);
    return model;
}

std::unique_ptr<Material> ubo2014_material(std::shared_ptr<const ubo2014::Factorization> f,
                                           const std::string& what) {
    check(f != nullptr, "{}: no factorization", what);
    if (f->meta.cosine_flag) return ubo2014::make_material(std::move(f));
    factor::Model model = model_of(*f, what);
    f.reset();
    return std::make_unique<factor::FactorMaterial>(std::move(model));
}

std::unique_ptr<Material> open_ubo2014_material(const std::filesystem::path& path,
                                                Progress& progress) {
    return ubo2014_material(ubo2014::read(path, progress), path.string());
}

Package package_of(const ubo2014::Factorization& f, const std::string& what) {
    const factor::Model model = model_of(f, what);
    bool half = true;
    for (const ubo2014::Factor& factor : f.factors) half = half && factor.scalar_size == 2;
    const factor::Quantization quantization =
        half ? factor::Quantization::kF16 : factor::Quantization::kF32;
    const nlohmann::json params = {{"from", f.signature()},
                                   {"colour", factor::to_string(model.colour.basis)},
                                   {"log", model.colour.log},
                                   {"log-eps", model.colour.log_eps},
                                   {"quantize", factor::to_string(quantization)}};
    return factor::to_package(model, "fmf", params, quantization);
}

ubo2014::Factorization factorize_dfmf(const BtfSource& source, const DfmfExportOptions& options,
                                      Progress& progress) {
    const std::string name =
        source.info().path.empty() ? source.info().format : source.info().path.string();
    check(options.color_model == ubo2014::kColorModelRgb ||
              options.color_model == ubo2014::kColorModelLogYUV,
          "{}: cannot factorize into colour model {} (btfkit writes 0 = RGB and 11 = log Y, U/Y, "
          "V/Y)",
          name, options.color_model);
    check(options.components >= 1, "{}: {} components per channel; need at least 1", name,
          options.components);
    check(!options.meta.cosine_flag,
          "{}: the cosine flag would make readers divide by cos θ, but the values are not "
          "multiplied by it",
          name);
    fmf::Options fmf;
    fmf.components = options.components;
    fmf.colour.basis = options.color_model == ubo2014::kColorModelRgb
                           ? factor::ColourBasis::kPerChannel
                           : factor::ColourBasis::kUboModel11;
    fmf.subtract_mean = false;
    fmf.seed = options.seed;
    // DFMF stores float32 or half itself; the package quantization does not apply.
    fmf.quantization = factor::Quantization::kF32;
    const factor::Model model = fmf::factorize(source, fmf, progress);
    return to_dfmf(model, options.scalar_size, options.meta, name);
}

void export_dfmf(const std::filesystem::path& path, const BtfSource& source,
                 const DfmfExportOptions& options, Progress& progress) {
    ubo2014::write_dfmf(path, factorize_dfmf(source, options, progress), progress);
}

}  // namespace btf
