// SPDX-License-Identifier: MIT
#pragma once
/// Codec: a named encoder/decoder pair. `encode` turns a streamed BtfSource into a Package;
/// `open` turns a Package (or a clean prefix of one) into a random-access Material. The codecs
/// are compiled in and listed in one registry (codec.cpp); adding a codec means adding its folder
/// under codecs/ and one line there.

#include <initializer_list>
#include <map>
#include <memory>
#include <set>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "btf/core/material.h"
#include "btf/io/package.h"
#include "btf/io/source.h"
#include "btf/util/progress.h"

namespace btf {

/// One parameter a codec understands, as its ParamSchema declares it (codecs/param_schema.h):
/// shown by `btf codecs`, the report and Python's keyword arguments.
struct ParamInfo {
    std::string name;
    std::string type;           ///< "int", "number", "bool" or "choice"
    std::string default_value;  ///< as `-p name=value` takes it
    std::string range;          ///< "1..4096", "0..1", "rgb|decorrelated" or "true|false"
    std::string help;
};

/// Codec parameters as text (`components=32`, `quantize=f16`), read through typed getters that
/// check ranges. Every getter marks its key as used; check_all_used() then reports keys that no
/// getter read, so a misspelt or unknown parameter is an error rather than silently ignored.
class Params {
  public:
    Params() = default;
    explicit Params(std::map<std::string, std::string> values) : m_values(std::move(values)) {}
    Params(std::initializer_list<std::pair<const std::string, std::string>> values)
        : m_values(values) {}

    /// Parses "key=value" items (as from the command line); throws on an item without '='.
    static Params parse(const std::vector<std::string>& items);

    void set(const std::string& key, const std::string& value) { m_values[key] = value; }
    bool has(const std::string& key) const { return m_values.count(key) != 0; }
    const std::map<std::string, std::string>& values() const { return m_values; }

    std::string get_string(const std::string& key, const std::string& fallback) const;
    /// One of `allowed`; throws naming the key, the value and the allowed ones otherwise.
    std::string get_choice(const std::string& key, const std::string& fallback,
                           const std::vector<std::string>& allowed) const;
    int get_int(const std::string& key, int fallback, int min, int max) const;
    double get_double(const std::string& key, double fallback, double min, double max) const;
    bool get_bool(const std::string& key, bool fallback) const;

    /// Throws btf::Error "codec NAME: unknown parameter 'key' (known: a, b, c)" for the first
    /// key no getter has read.
    void check_all_used(std::string_view codec, const std::vector<ParamInfo>& known) const;

  private:
    std::map<std::string, std::string> m_values;
    mutable std::set<std::string> m_used;
};

class Codec {
  public:
    virtual ~Codec() = default;

    /// Registry name, e.g. "fmf".
    virtual std::string_view name() const = 0;
    /// One line for `btf codecs` and help texts.
    virtual std::string_view description() const = 0;
    /// Every parameter encode() accepts, with its default.
    virtual std::vector<ParamInfo> params() const = 0;
    /// Checks `params` as encode() reads them (unknown keys, types, ranges, combinations) without
    /// encoding anything: a caller can refuse bad parameters before reading a large input.
    virtual void validate(const Params& params) const = 0;

    /// Compresses `source`, reading it image by image (possibly in several passes). Throws
    /// btf::Error for bad parameters (unknown ones included) and btf::Cancelled when `progress`
    /// is cancelled.
    virtual Package encode(const BtfSource& source, const Params& params,
                           Progress& progress = Progress::none()) const = 0;

    /// Opens a package this codec wrote, or any clean prefix of one (fewer sections: a
    /// lower-quality material). Throws btf::Error if the header or a section is inconsistent.
    virtual std::unique_ptr<Material> open(const Package& package) const = 0;

    /// Whether encode_several() puts several materials into one package (mlvq: shared
    /// code-books). The default is false.
    virtual bool encodes_several() const { return false; }
    /// Throws "codec NAME compresses one input …" when `count` > 1 and !encodes_several(): a
    /// caller can refuse several inputs before opening them.
    void check_several(size_t count) const;
    /// Compresses several sources into one package, `names[k]` naming source k in it (empty: the
    /// source's own name). One source: encode(). Several: check_several() refuses by default.
    virtual Package encode_several(std::span<const BtfSource* const> sources,
                                   std::span<const std::string> names, const Params& params,
                                   Progress& progress = Progress::none()) const;
    /// Every material of a package, in order: one, unless encode_several() wrote it. open() of a
    /// package with several materials opens the first (what the viewer and `btf eval` show).
    virtual std::vector<std::unique_ptr<Material>> open_all(const Package& package) const;
};

/// Every compiled-in codec, in a fixed order.
const std::vector<const Codec*>& codecs();
/// The codec named `name`; throws btf::Error listing the known codecs otherwise.
const Codec& find_codec(std::string_view name);

/// Opens a package (or a clean prefix) with the codec its header names, or a BSVTF file
/// (bsvtf/material.h: its finest tiles).
std::unique_ptr<Material> open_material(const Package& package);
/// Every material of a package (Codec::open_all(): several for mlvq's shared code-books, else
/// one; a BSVTF file: one).
std::vector<std::unique_ptr<Material>> open_materials(const Package& package);
/// read_package(path) then open_materials(); a UBO2014 .btf file gives its one material.
std::vector<std::unique_ptr<Material>> open_materials(const std::filesystem::path& path);
/// read_package(path) then open_material(); a UBO2014 .btf file is opened as the material of its
/// own factors (open_ubo2014_material in codecs/dfmf_export.h: the same material as its package).
std::unique_ptr<Material> open_material(const std::filesystem::path& path);

}  // namespace btf
