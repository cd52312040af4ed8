// SPDX-License-Identifier: MIT
#include "fuzz/support/fuzz.h"

#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <map>
#include <memory>
#include <vector>

#include "btf/codecs/codec.h"
#include "btf/core/image.h"
#include "btf/io/package.h"

namespace btf::fuzz {

namespace fs = std::filesystem;

namespace {

// Keeps the compiler from dropping evaluations whose results nobody reads.
volatile float g_sink = 0;

void consume(const Rgb& value) {
    g_sink = g_sink + value.r + value.g + value.b;
}

const Vec3 kDirections[] = {
    {0, 0, 1},
    normalize(Vec3{0.3, 0.2, 0.9}),
    normalize(Vec3{-0.7, 0.1, 0.3}),
    normalize(Vec3{0.1, -0.9, 0.05}),
};
const Uv kPositions[] = {{0, 0}, {0.5, 0.25}, {0.999, 0.999}, {-0.3, 7.1}};

}  // namespace

void report(const Error& error) {
    static const bool verbose = std::getenv("BTF_FUZZ_VERBOSE") != nullptr;
    if (verbose) std::fprintf(stderr, "btf::Error: %s\n", error.what());
}

void exercise(const Material& material) {
    for (const Uv& uv : kPositions)
        for (const Vec3& wi : kDirections) consume(material.eval(uv, wi, kDirections[1]));
    const int w = material.width(), h = material.height();
    const Sampling& s = material.sampling();
    if (w > 0 && h > 0 && s.num_views() > 0 && s.num_lights() > 0) {
        consume(material.eval_sample(0, 0, 0, 0));
        consume(material.eval_sample(w - 1, h - 1, s.num_views() - 1, s.num_lights() - 1));
        // The batch of them prefetches ahead: more indices than its distance.
        std::vector<SampleIndex> indices(20);
        for (size_t i = 0; i < indices.size(); ++i)
            indices[i] = {int(i) % w, int(i * 7) % h, int(i * 3) % s.num_views(),
                          int(i * 5) % s.num_lights()};
        std::vector<Rgb> values(indices.size());
        material.eval_sample_batch(indices, values);
        for (const Rgb& v : values) consume(v);
    }
    const Query queries[] = {{kPositions[1], kDirections[0], kDirections[2]},
                             {kPositions[2], kDirections[0], kDirections[2]},
                             {kPositions[0], kDirections[3], kDirections[1]}};
    Rgb out[3];
    material.eval_batch(queries, out);
    for (const Rgb& v : out) consume(v);
    // The stochastic batch: lanes of four (weights4(), pick_lanes()) and a partial group, with a
    // zero and a downward direction among them, which take the one-by-one lookup.
    const StochasticQuery stochastic[] = {
        {kPositions[0], kDirections[0], kDirections[1], 0.1},
        {kPositions[1], kDirections[2], kDirections[3], 0.5},
        {kPositions[2], Vec3{0, 0, 0}, kDirections[0], 0.9},
        {kPositions[3], kDirections[1], Vec3{0.2, 0.1, -1}, 0.999},
        {kPositions[1], kDirections[3], kDirections[2], 0.3}};
    Rgb stochastic_out[5];
    material.eval_stochastic_batch(stochastic, stochastic_out);
    for (const Rgb& v : stochastic_out) consume(v);
    // Only a material's own sampling: the generic sampler first tabulates the whole material
    // through eval(), which would make every input slow and test nothing new.
    if (material.native_sampling()) {
        const LightSample ls = material.sample(kPositions[1], kDirections[1], 0.3, 0.7);
        consume(ls.value);
        g_sink = g_sink + float(material.pdf(kPositions[1], kDirections[1], kDirections[2]));
        const StochasticSampleQuery samples[] = {{kPositions[0], kDirections[1], 0.2, 0.3, 0.7},
                                                 {kPositions[1], kDirections[2], 0.6, 0.9, 0.1},
                                                 {kPositions[2], Vec3{0, 0, 0}, 0.4, 0.5, 0.5},
                                                 {kPositions[3], kDirections[3], 0.8, 0.1, 0.9},
                                                 {kPositions[1], kDirections[0], 0.0, 0.6, 0.0}};
        LightSample drawn[5];
        material.sample_stochastic_batch(samples, drawn);
        for (const LightSample& d : drawn) consume(d.value);
        // The deterministic batch, with draws at ξ2 = 0 and just below 1 (mlvq: the poles of its
        // light frame, which take the drawn direction's own corners).
        const SampleQuery batch[] = {{kPositions[0], kDirections[1], 0.2, 0.0},
                                     {kPositions[1], kDirections[2], 0.6, 0.4},
                                     {kPositions[2], Vec3{0, 0, 0}, 0.4, 0.5},
                                     {kPositions[3], kDirections[3], 0.8, std::nextafter(1.0, 0.0)},
                                     {kPositions[1], kDirections[0], 0.0, 0.2}};
        LightSample batch_out[5];
        material.sample_batch(batch, batch_out);
        for (const LightSample& d : batch_out) consume(d.value);
    }
}

void exercise(const BtfSource& source) {
    const int views = source.num_views(), lights = source.num_lights();
    if (views <= 0 || lights <= 0) return;
    Image image;
    const std::pair<int, int> picks[] = {{0, 0}, {views / 2, lights / 2}, {views - 1, lights - 1}};
    for (const auto& [view, light] : picks) {
        source.read_image(view, light, image);
        if (image.empty()) continue;
        g_sink = g_sink + image.data()[0] + image.data()[image.num_pixels() * image.channels() - 1];
    }
}

const fs::path& scratch_dir() {
    // Never destroyed: the exit handler that removes the folder runs after static destructors.
    static const fs::path* const dir = [] {
        std::error_code ec;
        const fs::path base =
            fs::is_directory("/dev/shm", ec) ? fs::path("/dev/shm") : fs::temp_directory_path();
        auto* d = new fs::path(base / ("btf-fuzz-" + std::to_string(::getpid())));
        fs::create_directories(*d);
        std::atexit([] {
            std::error_code ignored;
            fs::remove_all(scratch_dir(), ignored);
        });
        return d;
    }();
    return *dir;
}

fs::path write_scratch(const std::string& name, std::span<const uint8_t> bytes) {
    const fs::path path = scratch_dir() / name;
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out.write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size()));
    out.close();
    if (!out) throw std::runtime_error("fuzz: cannot write " + path.string());
    return path;
}

std::vector<std::string> lines(std::span<const uint8_t> data) {
    std::vector<std::string> out;
    std::string line;
    for (uint8_t c : data) {
        if (c == '\n') {
            if (!line.empty() && line.back() == '\r') line.pop_back();
            out.push_back(std::move(line));
            line.clear();
        } else {
            line.push_back(char(c));
        }
    }
    if (!line.empty()) out.push_back(std::move(line));
    return out;
}

fs::path safe_relative_path(const std::string& line, int max_depth) {
    fs::path out;
    int depth = 0;
    size_t start = 0;
    while (start <= line.size()) {
        size_t slash = line.find('/', start);
        if (slash == std::string::npos) slash = line.size();
        const std::string part = line.substr(start, slash - start);
        start = slash + 1;
        if (part.empty() || part == "." || part == ".." || part.size() > 200 ||
            part.find('\0') != std::string::npos)
            return {};
        if (++depth > max_depth) return {};
        out /= part;
    }
    return out;
}

int open_with_codec(std::string_view codec, const uint8_t* data, size_t size) {
    return run([&] {
        const Package package = decode_package({data, size}, "input");
        const std::unique_ptr<Material> material = find_codec(codec).open(package);
        exercise(*material);
    });
}

namespace {

// One tiny image per format, made on first use, that image_folder() links its files to.
const fs::path* tiny_image(const std::string& extension) {
    static const std::map<std::string, fs::path> images = [] {
        std::map<std::string, fs::path> out;
        Image image(4, 4, 3);
        for (int y = 0; y < 4; ++y)
            for (int x = 0; x < 4; ++x)
                for (int c = 0; c < 3; ++c) image.at(x, y, c) = float(x + y + c) / 10.0f;
        for (const char* ext : {".png", ".jpg", ".hdr", ".exr"}) {
            const fs::path path = scratch_dir() / (std::string("tiny") + ext);
            write_image(path, image);
            out[ext] = path;
        }
        out[".jpeg"] = out[".jpg"];
        return out;
    }();
    std::string ext = extension;
    std::transform(ext.begin(), ext.end(), ext.begin(),
                   [](unsigned char c) { return char(std::tolower(c)); });
    const auto it = images.find(ext);
    return it == images.end() ? nullptr : &it->second;
}

}  // namespace

fs::path image_folder(const std::string& name, std::span<const uint8_t> data, int max_depth,
                      size_t max_files) {
    const fs::path folder = scratch_dir() / name;
    fs::remove_all(folder);
    fs::create_directories(folder);
    size_t files = 0;
    for (const std::string& line : lines(data)) {
        if (files >= max_files) break;
        const fs::path relative = safe_relative_path(line, max_depth);
        if (relative.empty()) continue;
        const fs::path path = folder / relative;
        std::error_code ec;
        fs::create_directories(path.parent_path(), ec);
        if (ec || fs::exists(path, ec)) continue;
        if (const fs::path* image = tiny_image(relative.extension().string()))
            fs::create_hard_link(*image, path, ec);
        else
            std::ofstream(path, std::ios::binary);
        ++files;
    }
    return folder;
}

}  // namespace btf::fuzz
