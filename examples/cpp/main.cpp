// SPDX-License-Identifier: MIT
// btfkit from C++, start to end: synthesize a material, compress it, evaluate the compressed
// material, and measure what the compression lost. Everything used here comes from one header,
// <btf/btf.h>; docs/library.md describes the API and how to build this program against an
// installed btfkit (CMake or pkg-config).
//
// Usage: btfkit_example [OUTPUT_FOLDER]   (the package is written there; default: .)

#include <btf/btf.h>

#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>

namespace {

// btfkit takes directions as unit vectors in the surface's local frame (z = normal, x = the
// direction of increasing u); people write them as (theta, phi) in degrees.
btf::Vec3 direction(double theta_deg, double phi_deg) {
    return btf::Direction::from_degrees(theta_deg, phi_deg).vector();
}

}  // namespace

int main(int argc, char** argv) try {
    const std::filesystem::path folder = argc > 1 ? argv[1] : ".";

    // 1. A raw BTF. A BtfSource hands out one image per (view, light) pair in linear RGB; this one
    //    renders a synthetic woven fabric of 32×32 texels on demand, at the 81 view and 81 light
    //    directions of the Bonn UBO2003 measurements. btf::open_source(path) opens a measured one.
    const btf::Sampling sampling{btf::DirectionSet::ubo81(), btf::DirectionSet::ubo81()};
    const std::unique_ptr<btf::BtfSource> source =
        btf::synth::make("woven_fabric", 32, sampling, /*seed=*/1);
    std::printf("source: %s, %dx%d texels, %d views x %d lights\n", source->info().format.c_str(),
                source->width(), source->height(), source->num_views(), source->num_lights());

    // 2. Compress it with a codec from the registry (`btf codecs` lists them and their
    //    parameters). Parameters are text, as `btf compress -p components=8` takes them; an
    //    unknown one is an error. write_package() writes atomically: a complete file or none.
    const btf::Codec& fmf = btf::find_codec("fmf");
    btf::Package package = fmf.encode(*source, btf::Params{{"components", "8"}});
    const std::filesystem::path path = folder / "woven_fabric.btfpkg";
    btf::write_package(path, package);
    const double raw_8bit = double(source->num_texels()) * double(sampling.num_images()) * 3;
    std::printf("package: %s, %llu bytes, ratio %.1f:1 to 8-bit RGB\n", path.string().c_str(),
                static_cast<unsigned long long>(package.file_bytes),
                raw_8bit / double(package.file_bytes));

    // 3. Open the package as a Material (any codec: the header names it) and ask it for values at
    //    any texture position and any pair of directions, interpolated between the sampled ones.
    //    Values are relative to a white diffuser and include cos(theta_light).
    const std::shared_ptr<const btf::Material> material = btf::open_material(path);
    const btf::Uv uv{0.25, 0.5};
    const btf::Vec3 wo = direction(30, 90);  // the viewer
    for (const double theta : {0.0, 30.0, 60.0}) {
        const btf::Rgb value = material->eval(uv, direction(theta, 0), wo);
        std::printf("eval uv (0.25, 0.5) light (%g, 0) view (30, 90): rgb %.4f %.4f %.4f\n", theta,
                    value.r, value.g, value.b);
    }
    //    A renderer draws light directions where the material reflects most (importance
    //    sampling) from two uniform numbers, and weighs them by their density.
    const btf::LightSample drawn = material->sample(uv, wo, 0.3, 0.7);
    const btf::Direction wi = btf::Direction::from_vector(drawn.wi);
    std::printf("sample: light (%.1f, %.1f), pdf %.4f, pdf() %.4f\n", wi.theta_deg(), wi.phi_deg(),
                drawn.pdf, material->pdf(uv, wo, drawn.wi));
    const btf::Rgb albedo = material->albedo(uv, wo);
    std::printf("albedo: rgb %.4f %.4f %.4f\n", albedo.r, albedo.g, albedo.b);

    // 4. What did compression lose? A MaterialSource shows the decoded material as a BtfSource,
    //    so the metrics compare it with the original image by image, as `btf quality` does.
    const btf::MaterialSource decoded(material, std::string(fmf.name()), path);
    const btf::quality::QualityResult quality =
        btf::quality::measure(*source, decoded, btf::quality::QualityRequest::parse("rmse,de2000"));
    std::printf("quality: rmse %.5f, psnr %.2f dB, de2000 mean %.3f\n", quality.metrics->rmse,
                quality.metrics->psnr, quality.metrics->de2000_mean);
    return 0;
} catch (const btf::Error& e) {
    // Every btfkit error is one line that names the file or the value at fault.
    std::fprintf(stderr, "btfkit_example: %s\n", e.what());
    return 1;
}
