// SPDX-License-Identifier: MIT
#pragma once
/// Synthetic BTFs with the effects that make measured BTFs hard: cast shadows, masking,
/// parallax, inter-reflection, and highlights that wander with the mesostructure.
///
/// Model (docs/synth.md has the full description): a tileable height field generated
/// procedurally per preset carries spatially varying material maps (diffuse albedo, specular F0,
/// anisotropic GGX roughness along a tangent direction, optional sheen and clear coat). An image
/// for a (view, light) pair is
///
///   value(p) = S(hit_view(p)),
///   S(q)     = π · f(q, wi, wo) · cos θi(q) · V_light(q) + ambient_light(q)
///
/// where hit_view(p) is the surface point the viewer sees through output texel p (ray-marched
/// masking and parallax, as in rectified measured data), V_light is the ray-marched soft shadow
/// toward the light, cos θi is taken at the local normal, f is the BRDF (GGX microfacet with
/// height-correlated Smith masking and Schlick Fresnel, Lambertian diffuse, optional sheen and
/// coat) and ambient is one diffuse bounce approximated from the sky visibility and the locally
/// averaged direct irradiance.
///
/// Values follow the convention of measurement labs, which calibrate against a white standard:
/// radiance relative to that of an ideal white Lambertian reflector lit by the same light at
/// normal incidence. They include the cosine at the local surface normal and are NOT divided by
/// the macro-surface cos θ_light; a white Lambertian plane gives cos θ_light. Linear RGB,
/// typically in [0, 1]; narrow highlights exceed 1.
///
/// Per-view data (hit map, view vectors in every texel's frame) and per-light data (shadow map,
/// light vectors, inter-reflection) are computed once and cached (bounded by a memory budget),
/// so a full BTF costs one shading pass per image.

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "btf/core/direction.h"
#include "btf/io/source.h"
#include "btf/synth/heightfield.h"

namespace btf::synth {

/// A preset's name and one-line description (for --help texts).
struct PresetInfo {
    std::string name;
    std::string description;
};

/// Every preset, in a fixed order.
const std::vector<PresetInfo>& presets();
/// Preset names, in the same order.
std::vector<std::string> preset_names();

/// Smallest and largest size (texels per side) a synthetic BTF may have.
constexpr int kMinSize = 4;
constexpr int kMaxSize = 2048;

/// The mesostructure and material maps of one synthetic material (size² texels, row-major).
struct Surface {
    int size = 0;
    Field height;                      ///< texel units, tileable
    double reference = 0;              ///< height of the rectification plane (texel units)
    std::vector<Rgb> albedo;           ///< diffuse albedo
    std::vector<Rgb> specular;         ///< specular reflectance at normal incidence (F0)
    std::vector<Rgb> bounce;           ///< albedo for the inter-reflected (ambient) light
    std::vector<Rgb> sheen;            ///< sheen colour; empty when the preset has no sheen
    std::vector<float> alpha_t;        ///< GGX roughness along the tangent
    std::vector<float> alpha_b;        ///< GGX roughness along the bitangent
    std::vector<float> tangent;        ///< tangent azimuth in the texture plane (radians from +x)
    float sheen_roughness = 0.5f;      ///< Charlie sheen roughness
    bool coat = false;                 ///< clear coat over the base layer
    float coat_alpha = 0.05f;          ///< coat GGX roughness (isotropic)
    float coat_f0 = 0.04f;             ///< coat reflectance at normal incidence
    Field coat_height;                 ///< coat surface (texel units); its normals shade the coat
    double light_size = radians(3.0);  ///< angular diameter of the lamp (soft shadow width)
    int bounce_radius = 2;             ///< texels over which direct light is averaged for bounces
};

/// A preset's height (in patch widths) and diffuse albedo at a continuous position (u, v);
/// periodic with period 1 in u and v. make_surface() samples this at the texel centres
/// ((x + 0.5) / size, (y + 0.5) / size) and scales heights by size.
struct PresetSample {
    double height = 0;
    Rgb albedo;
};
PresetSample sample_preset(const std::string& preset, uint64_t seed, double u, double v);

/// Generates a preset's surface. Throws btf::Error for an unknown preset (the message lists the
/// valid names) or a size outside [kMinSize, kMaxSize].
Surface make_surface(const std::string& preset, int size, uint64_t seed);

/// Options of a synthetic source.
struct SynthOptions {
    /// Memory for cached per-view data (28 bytes per texel, 40 with a coat) and per-light data
    /// (24 per texel, 36 with a coat); least recently used entries are dropped beyond it and
    /// recomputed when needed again. The default holds everything of a 256² ubo81 BTF and all
    /// lights of a 512² one: read such BTFs view by view (or light by light) so that the
    /// evicted entries are the ones not needed again.
    int64_t cache_bytes = int64_t(1) << 30;
};

/// A BtfSource that renders each image on demand from a preset. Deterministic for a given
/// seed and independent of the number of threads. Thread-safe.
class SynthSource final : public BtfSource {
  public:
    SynthSource(const std::string& preset, int size, Sampling sampling, uint64_t seed,
                const SynthOptions& options = {});
    ~SynthSource() override;

    int width() const override { return m_surface.size; }
    int height() const override { return m_surface.size; }
    const Sampling& sampling() const override { return m_sampling; }
    const SourceInfo& info() const override { return m_info; }
    void read_image(int view, int light, Image& out) const override;

    const std::string& preset() const { return m_preset; }
    uint64_t seed() const { return m_seed; }
    /// The generated mesostructure and material maps.
    const Surface& surface() const { return m_surface; }

  private:
    struct Frames;
    struct ViewData;
    struct LightData;
    class Cache;

    std::shared_ptr<const ViewData> view_data(int view) const;
    std::shared_ptr<const LightData> light_data(int light) const;
    std::shared_ptr<ViewData> compute_view(int view) const;
    std::shared_ptr<LightData> compute_light(int light) const;

    std::string m_preset;
    uint64_t m_seed;
    Sampling m_sampling;
    SourceInfo m_info;
    Surface m_surface;
    std::unique_ptr<Frames> m_frames;
    Field m_sky;
    std::vector<Rgb> m_bounce_tint;  // bounce albedo × mean bounce albedo, per texel
    std::unique_ptr<Cache> m_cache;
};

/// Makes a synthetic BTF source: `preset` (see preset_names()), size × size texels, the given
/// light and view sampling (e.g. DirectionSet::ubo81() for both), and a seed.
std::unique_ptr<BtfSource> make(const std::string& preset, int size, const Sampling& sampling,
                                uint64_t seed, const SynthOptions& options = {});

}  // namespace btf::synth
