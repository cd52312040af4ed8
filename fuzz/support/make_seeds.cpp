// SPDX-License-Identifier: MIT
// fuzz_make_seeds OUT: writes the seed inputs that no `btf` command writes, with the project's
// own writers, into OUT/<target>/ (fuzz/make_corpus.sh runs it):
//   bsvtf_tile       tiles encoded by encode_tile (DCT and lossless, with and without parent)
//   coded_component  coded factor sections by put_component (channel prediction or distances,
//                    DCT image or plain texels), behind the target's two shape bytes
//   ubo2003_archive  a zip archive of one UBO2003 view (81 tiny JPEGs), one of HDR images
//   ubo2003_names    the names of such materials, one per line (with and without view folder)
//   utia_names       UTIA image names made by utia::file_name, one per line
#include <zip.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "btf/bsvtf/tile_codec.h"
#include "btf/codecs/factor/coded.h"
#include "btf/core/direction.h"
#include "btf/core/image.h"
#include "btf/io/image_set.h"
#include "btf/io/utia.h"
#include "btf/util/half.h"
#include "fuzz/support/tile_input.h"

namespace fs = std::filesystem;
using namespace btf;

namespace {

void write_file(const fs::path& path, const std::vector<uint8_t>& bytes) {
    fs::create_directories(path.parent_path());
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out.write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size()));
    if (!out) throw std::runtime_error("cannot write " + path.string());
}

void write_text(const fs::path& path, const std::vector<std::string>& lines) {
    std::string text;
    for (const std::string& line : lines) text += line + "\n";
    write_file(path, std::vector<uint8_t>(text.begin(), text.end()));
}

std::vector<uint8_t> read_file(const fs::path& path) {
    std::ifstream in(path, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

void tiles(const fs::path& out) {
    int n = 0;
    for (const uint8_t geometry_byte : {uint8_t(0), uint8_t(1), uint8_t(4)}) {
        const bsvtf::TileGeometry g = fuzz::tile_geometry(geometry_byte);
        std::vector<uint16_t> tile(size_t(g.values()));
        for (size_t i = 0; i < tile.size(); ++i)
            tile[i] = to_half(0.5f + 0.25f * std::sin(float(i) * 0.01f) * float(i % 4));
        for (const uint8_t prediction_byte : {uint8_t(0), uint8_t(32)})
            for (const float step : {0.0f, 0.02f}) {
                const std::vector<float> prediction = fuzz::tile_prediction(prediction_byte, g);
                std::vector<uint8_t> input = {geometry_byte, prediction_byte};
                const std::vector<uint8_t> payload = bsvtf::encode_tile(tile, prediction, g, step);
                input.insert(input.end(), payload.begin(), payload.end());
                write_file(out / "bsvtf_tile" / ("tile" + std::to_string(n++)), input);
            }
    }
}

// Inputs of fuzz/coded_component.cpp: its shape bytes, then a section put_component writes for
// that shape.
void coded_components(const fs::path& out) {
    namespace coded = factor::coded;
    int n = 0;
    for (const uint8_t rows_byte : {uint8_t(80), uint8_t(3)})  // 81 rows (27 triples), 4
        for (const uint8_t shape_byte :
             {uint8_t(0x77), uint8_t(0xF3)}) {  // 8 × 8 image, 4 × 8 plain
            const int rows = 1 + rows_byte % 96;
            const int texels = (1 + (shape_byte & 15)) * (1 + ((shape_byte >> 4) & 7));
            std::vector<float> a(static_cast<size_t>(rows)), b(static_cast<size_t>(texels));
            // Laid out as fuzz/coded_component.cpp lays them out: 81 rows are 3 views × 9
            // lights × 3 channels, smooth over both directions.
            const int channels = rows % 3 == 0 ? 3 : 1;
            const int lights = (rows / channels) % 9 == 0 ? 9 : (rows / channels) % 3 == 0 ? 3 : 1;
            for (int i = 0; i < rows; ++i) {
                const int pair = i / channels;
                a[size_t(i)] =
                    std::sin(0.2f * float(pair % lights)) * std::cos(0.3f * float(pair / lights)) +
                    0.1f * float(i % channels);
            }
            for (int t = 0; t < texels; ++t)
                b[size_t(t)] = std::cos(0.3f * float(t)) * float(1 + t % 5);
            const coded::Image image =
                (shape_byte & 128)
                    ? coded::Image{}
                    : coded::Image{1 + (shape_byte & 15), 1 + ((shape_byte >> 4) & 7)};
            for (const double step : {0.01, 0.3}) {
                std::vector<uint8_t> input = {rows_byte, shape_byte};
                coded::put_component(input, {a.data(), rows, 1}, {b.data(), texels, 1}, image, step,
                                     nullptr, {lights, channels});
                write_file(out / "coded_component" / ("component" + std::to_string(n++)), input);
            }
        }
}

// The UBO2003 name of the image of (view, light): "tvTTT_pvPPP/NNNNN tlTTT plPPP tvTTT pvPPP.ext".
std::string ubo2003_name(int view, int light, const char* ext, bool folder) {
    const DirectionSet& set = DirectionSet::ubo81();
    std::string name = fmt::format("{:05d} {} {}{}", 81 * light + view,
                                   format_direction_fields(set[light], "tl", "pl", ' '),
                                   format_direction_fields(set[view], "tv", "pv", ' '), ext);
    if (folder) name = format_direction_fields(set[view], "tv", "pv", '_') + "/" + name;
    return name;
}

void ubo2003(const fs::path& out, const fs::path& scratch) {
    Image image(4, 4, 3);
    for (int y = 0; y < 4; ++y)
        for (int x = 0; x < 4; ++x)
            for (int c = 0; c < 3; ++c) image.at(x, y, c) = float(x * 4 + y + c) / 20.0f;
    for (const char* ext : {".jpg", ".hdr"}) {
        const fs::path file = scratch / (std::string("tiny") + ext);
        write_image(file, image);
        const std::vector<uint8_t> bytes = read_file(file);
        const fs::path zip_path = out / "ubo2003_archive" / (std::string("view0") + ext + ".zip");
        fs::create_directories(zip_path.parent_path());
        int error = 0;
        zip_t* archive = zip_open(zip_path.c_str(), ZIP_CREATE | ZIP_TRUNCATE, &error);
        if (!archive) throw std::runtime_error("cannot create " + zip_path.string());
        std::vector<std::string> names;
        for (int light = 0; light < 81; ++light) {
            names.push_back(ubo2003_name(0, light, ext, true));
            zip_source_t* s = zip_source_buffer(archive, bytes.data(), bytes.size(), 0);
            const zip_int64_t i = zip_file_add(archive, names.back().c_str(), s, ZIP_FL_ENC_UTF_8);
            if (i < 0) throw std::runtime_error("cannot add to " + zip_path.string());
            zip_set_file_compression(archive, zip_uint64_t(i), ZIP_CM_STORE, 0);
        }
        if (zip_close(archive) != 0) throw std::runtime_error("cannot write " + zip_path.string());
        write_text(out / "ubo2003_names" / (std::string("view0") + ext), names);
    }
    // Two views without view folders; a listing with a stray file and a misnumbered image.
    std::vector<std::string> names;
    for (int view : {5, 40})
        for (int light = 0; light < 81; ++light)
            names.push_back(ubo2003_name(view, light, ".jpg", false));
    write_text(out / "ubo2003_names" / "views5_40_flat", names);
    write_text(out / "ubo2003_names" / "damaged",
               {ubo2003_name(0, 0, ".jpg", true), "tv000_pv000/readme.txt",
                "tv000_pv000/00002 tl000 pl000 tv000 pv000.jpg", ".hidden/x.jpg"});
}

void utia_names(const fs::path& out) {
    const DirectionSet& set = DirectionSet::ubo81();
    std::vector<std::string> names;
    for (int light = 0; light < 81; ++light)
        names.push_back(utia::file_name(set[light], set[3], "png"));
    write_text(out / "utia_names" / "ubo81_lights_one_view", names);
    names.clear();
    const Direction lights[] = {Direction::from_degrees(0, 0), Direction::from_degrees(23.5, 7.25),
                                Direction::from_degrees(60, 120)};
    const Direction views[] = {Direction::from_degrees(0, 0), Direction::from_degrees(45, 300)};
    for (const char* format : {"png", "exr"}) {
        names.clear();
        for (const Direction& l : lights)
            for (const Direction& v : views) names.push_back(utia::file_name(l, v, format));
        write_text(out / "utia_names" / (std::string("three_by_two_") + format), names);
    }
}

}  // namespace

int main(int argc, char** argv) {
    if (argc != 2) {
        std::fprintf(stderr, "usage: fuzz_make_seeds OUT\n");
        return 2;
    }
    try {
        const fs::path out = argv[1];
        const fs::path scratch = out / ".scratch";
        fs::create_directories(scratch);
        tiles(out);
        coded_components(out);
        ubo2003(out, scratch);
        utia_names(out);
        fs::remove_all(scratch);
    } catch (const std::exception& e) {
        std::fprintf(stderr, "fuzz_make_seeds: %s\n", e.what());
        return 1;
    }
    return 0;
}
