// SPDX-License-Identifier: MIT
#include "btf/bsvtf/file.h"

#include <Eigen/Core>

#include <cstring>

#include "btf/util/error.h"
#include "btf/util/half.h"
#include "btf/util/json_fields.h"

namespace btf::bsvtf {

namespace {

PackageSection section(std::string name, std::vector<uint8_t> data) {
    PackageSection s;
    s.name = std::move(name);
    s.data = std::move(data);
    return s;
}

template <typename T>
void put(std::vector<uint8_t>& out, T value) {
    const size_t at = out.size();
    out.resize(at + sizeof(T));
    std::memcpy(out.data() + at, &value, sizeof(T));
}

}  // namespace

bool angular_factors_are_half(const factor::Model& model) {
    for (const factor::Block& b : model.blocks)
        for (int64_t i = 0; i < b.a.size(); ++i)
            if (float(Eigen::half(b.a.data()[i])) != b.a.data()[i]) return false;
    return true;
}

Package make_bsvtf(const Package& fmf, const factor::Model& model, const Pyramid& pyramid,
                   const EncodedPyramid& encoded, double relative_error) {
    const TileGeometry& g = pyramid.geometry();
    nlohmann::json groups = nlohmann::json::array();
    for (const Group& group : pyramid.groups())
        groups.push_back({group.plane, group.first, group.count});
    Package out;
    out.header["codec"] = "bsvtf";
    out.header["source"] = fmf.header;
    out.header["bsvtf"] = {{"width", pyramid.width()},
                           {"height", pyramid.height()},
                           {"tile", g.tile},
                           {"pad", g.pad},
                           {"levels", pyramid.levels()},
                           {"groups", std::move(groups)},
                           {"step", encoded.step},
                           {"relative_error", relative_error},
                           {"tiles", pyramid.tile_count()},
                           {"u_format", angular_factors_are_half(model) ? "f16" : "f32"}};
    const bool half = out.header["bsvtf"]["u_format"] == "f16";
    out.sections.push_back(section("tables", fmf.at("tables").data));
    out.sections.push_back(section("means", fmf.at("means").data));

    // Payloads coarsest level first (the order a stream needs them), indexed by tile.
    std::vector<uint64_t> offset(pyramid.tile_count());
    std::vector<uint8_t> tiles;
    tiles.reserve(encoded.encoded_bytes);
    for (int level = pyramid.levels() - 1; level >= 0; --level)
        for (size_t t = 0; t < pyramid.tile_count(); ++t) {
            if (pyramid.id(t).level != level) continue;
            offset[t] = tiles.size();
            tiles.insert(tiles.end(), encoded.payloads[t].begin(), encoded.payloads[t].end());
        }
    std::vector<uint8_t> index;
    for (size_t t = 0; t < pyramid.tile_count(); ++t) {
        put<float>(index, pyramid.weights()[t]);
        put<uint32_t>(index, uint32_t(encoded.payloads[t].size()));
        put<uint64_t>(index, offset[t]);
    }
    out.sections.push_back(section("tiles.index", std::move(index)));
    for (size_t gi = 0; gi < pyramid.groups().size(); ++gi) {
        const Group& group = pyramid.groups()[gi];
        const factor::Block& block = model.blocks[size_t(model.block_index(group.plane, 0, 0))];
        std::vector<uint8_t> u;
        for (int k = group.first; k < group.first + group.count; ++k)
            for (int64_t r = 0; r < block.a.rows(); ++r) {
                if (half)
                    put<uint16_t>(u, to_half(block.a(r, k)));
                else
                    put<float>(u, block.a(r, k));
            }
        out.sections.push_back(section(fmt::format("u{}", gi), std::move(u)));
    }
    // Raw whatever the writer's zstd level: clients fetch single tiles by byte range.
    out.sections.push_back(section("tiles", std::move(tiles)));
    out.sections.back().keep_raw = true;
    out.declared_sections = int(out.sections.size());
    return out;
}

Bsvtf read_bsvtf(const Package& package, const std::string& what) {
    if (package.codec() != "bsvtf")
        fail("{}: a '{}' package, not a BSVTF (btf bsvtf makes one from an fmf package)", what,
             package.codec());
    return read_package_fields(what, [&] {
        Bsvtf out;
        const auto& h = package.header.at("bsvtf");
        // The angular part: the fmf header with its tables and means (a prefix without
        // components), then every component's a from the u<g> packets.
        Package source;
        source.header = package.header.at("source");
        source.sections.push_back(package.at("tables"));
        source.sections.push_back(package.at("means"));
        source.declared_sections = int(source.sections.size());  // only the angular part
        out.model = factor::from_package(source);
        std::vector<Group> groups;
        const auto& group_list = h.at("groups");
        if (!group_list.is_array() || group_list.empty() || group_list.size() > 4096)
            fail("'groups' must be an array of 1 to 4096 groups");
        for (const auto& g : group_list) {
            const std::vector<int> v = json_fields::integers(g, "groups", 0, 4096, 3);
            if (v.size() != 3) fail("a group must be [plane, first, count]");
            const Group group{v[0], v[1], v[2]};
            if (group.plane < 0 || group.plane >= out.model.colour.planes() || group.first < 0 ||
                group.count < 1 || group.count > 4)
                fail("group [{}, {}, {}] is out of range", group.plane, group.first, group.count);
            groups.push_back(group);
        }
        const auto [width, height] = json_fields::extent(h);
        if (width != out.model.width || height != out.model.height)
            fail("the tile layout disagrees with the header");
        out.layout = TileLayout(width, height,
                                {int(json_fields::integer_at(h, "tile", 1, 1 << 16)),
                                 int(json_fields::integer_at(h, "pad", 0, 1 << 16))},
                                groups);
        if (out.layout.levels() != json_fields::integer_at(h, "levels", 1, 64) ||
            int64_t(out.layout.tile_count()) != json_fields::integer_at(h, "tiles", 0, INT64_MAX))
            fail("the tile layout disagrees with the header");
        out.step = float(json_fields::number_at(h, "step", 0, 1e30));
        out.relative_error = json_fields::number_at(h, "relative_error", 0, 1e30);
        const std::string u_format = h.at("u_format").get<std::string>();
        if (u_format != "f16" && u_format != "f32") fail("u_format '{}'", u_format);
        const size_t u_bytes = u_format == "f16" ? 2 : 4;
        // A plane's groups cover its components 0, 1, … in order (as pyramid.cpp cuts them), and
        // each group's u section holds its rows: so the components allocated below are bounded
        // by the bytes of the file, checked before anything is allocated.
        const size_t rows = size_t(out.model.block_rows(0, 0));
        std::vector<int> components(size_t(out.model.colour.planes()), 0);
        for (size_t gi = 0; gi < groups.size(); ++gi) {
            const Group& g = groups[gi];
            if (g.first != components[size_t(g.plane)])
                fail("group {} [{}, {}, {}] does not continue plane {} at component {}", gi,
                     g.plane, g.first, g.count, g.plane, components[size_t(g.plane)]);
            components[size_t(g.plane)] += g.count;
            const PackageSection& u = package.at(fmt::format("u{}", gi));
            if (u.data.size() != rows * size_t(g.count) * u_bytes)
                fail("section '{}' holds {} bytes, expected {}", u.name, u.data.size(),
                     rows * size_t(g.count) * u_bytes);
        }
        for (int plane = 0; plane < out.model.colour.planes(); ++plane) {
            factor::Block& b = out.model.blocks[size_t(out.model.block_index(plane, 0, 0))];
            b.a = factor::Matrix::Zero(int64_t(rows), components[size_t(plane)]);
            b.b.resize(0, components[size_t(plane)]);
        }
        for (size_t gi = 0; gi < groups.size(); ++gi) {
            const Group& g = groups[gi];
            factor::Block& b = out.model.blocks[size_t(out.model.block_index(g.plane, 0, 0))];
            const PackageSection& u = package.at(fmt::format("u{}", gi));
            const uint8_t* v = u.data.data();
            for (int k = 0; k < g.count; ++k)
                for (int64_t r = 0; r < b.a.rows(); ++r, v += u_bytes) {
                    if (u_bytes == 2) {
                        uint16_t bits;
                        std::memcpy(&bits, v, 2);
                        b.a(r, g.first + k) = from_half(bits);
                    } else {
                        std::memcpy(&b.a(r, g.first + k), v, 4);
                    }
                }
        }
        const PackageSection& index = package.at("tiles.index");
        const size_t tiles = out.layout.tile_count();
        if (index.data.size() != tiles * 16)
            fail("section 'tiles.index' holds {} bytes, expected {}", index.data.size(),
                 tiles * 16);
        out.payloads = package.at("tiles").data;
        out.weights.resize(tiles);
        out.sizes.resize(tiles);
        out.offsets.resize(tiles);
        for (size_t t = 0; t < tiles; ++t) {
            const uint8_t* p = index.data.data() + t * 16;
            std::memcpy(&out.weights[t], p, 4);
            std::memcpy(&out.sizes[t], p + 4, 4);
            std::memcpy(&out.offsets[t], p + 8, 8);
            if (out.offsets[t] > out.payloads.size() ||
                out.sizes[t] > out.payloads.size() - out.offsets[t])
                fail("tile {} lies outside section 'tiles'", t);
        }
        return out;
    });
}

}  // namespace btf::bsvtf
