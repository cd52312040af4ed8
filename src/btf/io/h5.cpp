// SPDX-License-Identifier: MIT
#include "btf/io/h5.h"

#include <hdf5.h>
#include <libdeflate.h>

#if defined(__x86_64__)
#include <cpuid.h>
#include <immintrin.h>
#endif
#include <fcntl.h>
#include <unistd.h>

#include <Eigen/Core>
#include <algorithm>
#include <bit>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <exception>
#include <fstream>
#include <functional>
#include <new>
#include <nlohmann/json.hpp>
#include <optional>
#include <thread>
#include <utility>
#include <vector>

#include "btf/util/atomic_file.h"
#include "btf/util/error.h"
#include "btf/util/isolate.h"
#include "btf/util/limits.h"
#include "btf/util/parallel.h"

namespace btf::h5 {

namespace fs = std::filesystem;

// Stored bytes are written from and read into host memory as they are.
static_assert(std::endian::native == std::endian::little, "btfkit HDF5 I/O assumes little endian");

std::recursive_mutex& library_mutex() {
    static std::recursive_mutex mutex;
    return mutex;
}

namespace {

// Sane limits checked before allocating anything a file declares.
constexpr hsize_t kMaxDirections = 1u << 20;
constexpr hsize_t kMaxSide = 1u << 16;
constexpr uint64_t kMaxChunkBytes = 0xFFFFFFFFull;  // HDF5 stores chunk sizes in 32 bits
// Angles within this many degrees outside their range are clamped, not rejected (float32 files).
constexpr double kAngleToleranceDeg = 1e-6;
// Unit vectors may differ from the ones computed from the angles by this much per component.
constexpr double kVectorTolerance = 1e-6;
// Memory the writer spends on one batch of images read in parallel.
constexpr int64_t kBatchBytes = int64_t{256} << 20;

/// Holds the HDF5 lock. HDF5 would print its error stack to stderr; the library never prints, so
/// automatic printing is switched off and failures become btf::Error (see hdf5_detail()).
class Lock {
  public:
    Lock() : m_lock(library_mutex()) { H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr); }

  private:
    std::unique_lock<std::recursive_mutex> m_lock;
};

/// An HDF5 identifier closed (under the lock) when the handle goes away.
class Handle {
  public:
    Handle() = default;
    Handle(hid_t id, herr_t (*close)(hid_t)) : m_id(id), m_close(close) {}
    Handle(Handle&& other) noexcept
        : m_id(std::exchange(other.m_id, H5I_INVALID_HID)), m_close(other.m_close) {}
    Handle& operator=(Handle&& other) noexcept {
        if (this != &other) {
            reset();
            m_id = std::exchange(other.m_id, H5I_INVALID_HID);
            m_close = other.m_close;
        }
        return *this;
    }
    Handle(const Handle&) = delete;
    Handle& operator=(const Handle&) = delete;
    ~Handle() { reset(); }

    hid_t get() const { return m_id; }
    operator hid_t() const { return m_id; }

    /// Closes now and returns HDF5's status (closing a file flushes it, which can fail).
    herr_t close() {
        if (m_id < 0) return 0;
        Lock lock;
        const herr_t status = m_close(m_id);
        m_id = H5I_INVALID_HID;
        return status;
    }
    void reset() { close(); }

  private:
    hid_t m_id = H5I_INVALID_HID;
    herr_t (*m_close)(hid_t) = nullptr;
};

herr_t collect_error(unsigned, const H5E_error2_t* error, void* data) {
    auto* out = static_cast<std::string*>(data);
    if (out->empty() && error->desc && *error->desc) *out = error->desc;
    return 0;
}

/// The innermost message on HDF5's error stack (where the failure was detected), e.g.
/// "truncated file: eof = 4096, sblock->base_addr = 0, stored_eof = 8736". Call under the lock.
std::string hdf5_detail() {
    std::string detail;
    H5Ewalk2(H5E_DEFAULT, H5E_WALK_UPWARD, collect_error, &detail);
    H5Eclear2(H5E_DEFAULT);
    return detail.empty() ? std::string("HDF5 reported an error") : detail;
}

/// Error reporting for one file: every message starts with the file's name.
class Context {
  public:
    explicit Context(const fs::path& path) : m_name(path.string()) {}
    const std::string& name() const { return m_name; }

    /// Throws "<file>: <what>: <HDF5's reason>" if `id` is negative; returns it otherwise.
    template <typename T>
    T h5(T id, std::string_view what) const {
        if (id < 0) fail("{}: {}: {}", m_name, what, hdf5_detail());
        return id;
    }
    Handle handle(hid_t id, herr_t (*close)(hid_t), std::string_view what) const {
        return Handle(h5(id, what), close);
    }
    template <typename... Args>
    [[noreturn]] void layout_error(fmt::format_string<Args...> format, Args&&... args) const {
        fail("{}: btfkit HDF5 layout: {}", m_name,
             fmt::format(format, std::forward<Args>(args)...));
    }

  private:
    std::string m_name;
};

// ---- element types ---------------------------------------------------------------------------

/// IEEE binary16, little endian, built as h5py builds it, so numpy sees float16.
Handle make_half_type(const Context& ctx) {
    Handle type = ctx.handle(H5Tcopy(H5T_IEEE_F32LE), H5Tclose, "cannot create half-float type");
    ctx.h5(H5Tset_fields(type, 15, 10, 5, 0, 10), "cannot create half-float type");
    ctx.h5(H5Tset_size(type, 2), "cannot create half-float type");
    ctx.h5(H5Tset_ebias(type, 15), "cannot create half-float type");
    return type;
}

bool is_half_type(hid_t type) {
    if (H5Tget_class(type) != H5T_FLOAT || H5Tget_size(type) != 2) return false;
    if (H5Tget_order(type) != H5T_ORDER_LE || H5Tget_precision(type) != 16) return false;
    size_t spos = 0, epos = 0, esize = 0, mpos = 0, msize = 0;
    if (H5Tget_fields(type, &spos, &epos, &esize, &mpos, &msize) < 0) return false;
    return spos == 15 && epos == 10 && esize == 5 && mpos == 0 && msize == 10 &&
           H5Tget_ebias(type) == 15;
}

std::string describe_type(hid_t type) {
    const H5T_class_t cls = H5Tget_class(type);
    const size_t bytes = H5Tget_size(type);
    const char* order = H5Tget_order(type) == H5T_ORDER_BE ? " big-endian" : "";
    switch (cls) {
        case H5T_FLOAT:
            return fmt::format("{}-byte{} float", bytes, order);
        case H5T_INTEGER:
            return fmt::format("{}-byte{} integer", bytes, order);
        case H5T_STRING:
            return "string";
        case H5T_ENUM:
            return "enum";
        case H5T_COMPOUND:
            return "compound";
        default:
            return fmt::format("HDF5 type class {}", int(cls));
    }
}

// ---- attributes ------------------------------------------------------------------------------

void write_string_attribute(const Context& ctx, hid_t object, const char* name,
                            const std::string& value) {
    const std::string what = fmt::format("cannot write attribute '{}'", name);
    Handle type = ctx.handle(H5Tcopy(H5T_C_S1), H5Tclose, what);
    ctx.h5(H5Tset_size(type, H5T_VARIABLE), what);
    ctx.h5(H5Tset_cset(type, H5T_CSET_UTF8), what);
    Handle space = ctx.handle(H5Screate(H5S_SCALAR), H5Sclose, what);
    Handle attr =
        ctx.handle(H5Acreate2(object, name, type, space, H5P_DEFAULT, H5P_DEFAULT), H5Aclose, what);
    const char* text = value.c_str();
    ctx.h5(H5Awrite(attr, type, &text), what);
}

void write_int_attribute(const Context& ctx, hid_t object, const char* name, hid_t file_type,
                         int value) {
    const std::string what = fmt::format("cannot write attribute '{}'", name);
    Handle space = ctx.handle(H5Screate(H5S_SCALAR), H5Sclose, what);
    Handle attr = ctx.handle(H5Acreate2(object, name, file_type, space, H5P_DEFAULT, H5P_DEFAULT),
                             H5Aclose, what);
    ctx.h5(H5Awrite(attr, H5T_NATIVE_INT, &value), what);
}

/// Opens attribute `name` of `object` (`where` names the object in messages) and checks that it
/// holds a single value; nullopt if absent.
std::optional<Handle> open_scalar_attribute(const Context& ctx, hid_t object, const char* name,
                                            const std::string& where) {
    const htri_t exists = ctx.h5(H5Aexists(object, name), "cannot list attributes");
    if (exists == 0) return std::nullopt;
    Handle attr = ctx.handle(H5Aopen(object, name, H5P_DEFAULT), H5Aclose,
                             fmt::format("cannot open attribute '{}'", name));
    Handle space = ctx.handle(H5Aget_space(attr), H5Sclose, "cannot read attribute");
    if (H5Sget_simple_extent_npoints(space) != 1)
        ctx.layout_error("{}attribute '{}' holds {} values, expected one", where, name,
                         H5Sget_simple_extent_npoints(space));
    return attr;
}

std::optional<std::string> read_string_attribute(const Context& ctx, hid_t object, const char* name,
                                                 const std::string& where = "") {
    std::optional<Handle> attr = open_scalar_attribute(ctx, object, name, where);
    if (!attr) return std::nullopt;
    const std::string what = fmt::format("cannot read attribute '{}'", name);
    Handle type = ctx.handle(H5Aget_type(*attr), H5Tclose, what);
    if (H5Tget_class(type) != H5T_STRING)
        ctx.layout_error("{}attribute '{}' is a {}, expected a string", where, name,
                         describe_type(type));
    Handle memory = ctx.handle(H5Tcopy(H5T_C_S1), H5Tclose, what);
    ctx.h5(H5Tset_cset(memory, H5Tget_cset(type)), what);
    if (ctx.h5(H5Tis_variable_str(type), what) > 0) {
        ctx.h5(H5Tset_size(memory, H5T_VARIABLE), what);
        char* text = nullptr;
        ctx.h5(H5Aread(*attr, memory, &text), what);
        std::string value = text ? text : "";
        H5free_memory(text);
        return value;
    }
    const size_t size = H5Tget_size(type);
    if (size == 0 || size > (size_t{1} << 30))
        ctx.layout_error("{}attribute '{}' declares a string of {} bytes", where, name, size);
    ctx.h5(H5Tset_size(memory, size), what);
    ctx.h5(H5Tset_strpad(memory, H5T_STR_NULLPAD), what);
    std::string value(size, '\0');
    ctx.h5(H5Aread(*attr, memory, value.data()), what);
    value.resize(std::strlen(value.c_str()));
    return value;
}

/// Integer attribute; also accepts h5py's bool (an enum over an integer type).
std::optional<int64_t> read_int_attribute(const Context& ctx, hid_t object, const char* name) {
    std::optional<Handle> attr = open_scalar_attribute(ctx, object, name, "root ");
    if (!attr) return std::nullopt;
    const std::string what = fmt::format("cannot read attribute '{}'", name);
    Handle type = ctx.handle(H5Aget_type(*attr), H5Tclose, what);
    const H5T_class_t cls = H5Tget_class(type);
    if (cls == H5T_INTEGER) {
        int64_t value = 0;
        ctx.h5(H5Aread(*attr, H5T_NATIVE_INT64, &value), what);
        return value;
    }
    if (cls == H5T_ENUM) {
        // HDF5 converts enums only to enums: read the native form of the enum and take the
        // integer it stores.
        Handle native = ctx.handle(H5Tget_native_type(type, H5T_DIR_ASCEND), H5Tclose, what);
        Handle base = ctx.handle(H5Tget_super(native), H5Tclose, what);
        const size_t size = H5Tget_size(native);
        if (size > 8) ctx.layout_error("root attribute '{}' is an enum of {} bytes", name, size);
        uint64_t raw = 0;
        ctx.h5(H5Aread(*attr, native, &raw), what);
        if (H5Tget_sign(base) == H5T_SGN_2 && size < 8 && (raw >> (8 * size - 1)) & 1)
            raw |= ~uint64_t{0} << (8 * size);
        return static_cast<int64_t>(raw);
    }
    ctx.layout_error("root attribute '{}' is a {}, expected an integer", name, describe_type(type));
}

// ---- small datasets ----------------------------------------------------------------------------

void write_matrix(const Context& ctx, hid_t file, const char* name, const std::vector<double>& data,
                  hsize_t rows, hsize_t cols) {
    const std::string what = fmt::format("cannot write dataset '{}'", name);
    const hsize_t dims[2] = {rows, cols};
    Handle space = ctx.handle(H5Screate_simple(2, dims, nullptr), H5Sclose, what);
    Handle set = ctx.handle(
        H5Dcreate2(file, name, H5T_IEEE_F64LE, space, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT),
        H5Dclose, what);
    ctx.h5(H5Dwrite(set, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, data.data()), what);
    if (std::strcmp(name, "views") == 0 || std::strcmp(name, "lights") == 0)
        write_string_attribute(ctx, set, "columns", "theta_deg, phi_deg");
    else
        write_string_attribute(ctx, set, "columns", "x, y, z");
}

// A dataset must live in this file: an external or soft link (which may lead to one), external
// raw storage and virtual datasets would read other files on the machine, so they are refused
// unless the user allows them (Limits::allow_hdf5_external).
void check_local(const Context& ctx, hid_t file, const char* name, hid_t set) {
    if (limits().allow_hdf5_external) return;
    const char* how =
        "(refused: it would read another file; allow it with "
        "--allow-hdf5-external or BTF_ALLOW_HDF5_EXTERNAL=1)";
    H5L_info_t link;
    ctx.h5(H5Lget_info(file, name, &link, H5P_DEFAULT), "cannot list the root group");
    if (link.type == H5L_TYPE_EXTERNAL)
        ctx.layout_error("dataset '{}' is an external link to another file {}", name, how);
    if (link.type != H5L_TYPE_HARD)
        ctx.layout_error("dataset '{}' is a soft or user-defined link {}", name, how);
    if (set < 0) return;
    Handle dcpl = ctx.handle(H5Dget_create_plist(set), H5Pclose,
                             fmt::format("cannot read dataset '{}'", name));
    if (H5Pget_layout(dcpl) == H5D_VIRTUAL)
        ctx.layout_error("dataset '{}' is a virtual dataset {}", name, how);
    if (ctx.h5(H5Pget_external_count(dcpl), fmt::format("cannot read dataset '{}'", name)) > 0)
        ctx.layout_error("dataset '{}' keeps its data in external files {}", name, how);
}

Handle open_dataset(const Context& ctx, hid_t file, const char* name) {
    const htri_t exists = ctx.h5(H5Lexists(file, name, H5P_DEFAULT), "cannot list the root group");
    if (exists == 0) ctx.layout_error("dataset '{}' is missing", name);
    check_local(ctx, file, name, -1);
    Handle set = ctx.handle(H5Dopen2(file, name, H5P_DEFAULT), H5Dclose,
                            fmt::format("cannot open dataset '{}'", name));
    check_local(ctx, file, name, set);
    return set;
}

/// Reads a [rows, cols] numeric dataset as doubles; rows ≤ kMaxDirections.
std::vector<double> read_matrix(const Context& ctx, hid_t file, const char* name, hsize_t cols,
                                hsize_t& rows) {
    Handle set = open_dataset(ctx, file, name);
    const std::string what = fmt::format("cannot read dataset '{}'", name);
    Handle type = ctx.handle(H5Dget_type(set), H5Tclose, what);
    const H5T_class_t cls = H5Tget_class(type);
    if (cls != H5T_FLOAT && cls != H5T_INTEGER)
        ctx.layout_error("dataset '{}' holds {} values, expected float64", name,
                         describe_type(type));
    Handle space = ctx.handle(H5Dget_space(set), H5Sclose, what);
    hsize_t dims[2] = {0, 0};
    if (H5Sget_simple_extent_ndims(space) != 2)
        ctx.layout_error("dataset '{}' has {} dimensions, expected 2 ([n, {}])", name,
                         H5Sget_simple_extent_ndims(space), cols);
    ctx.h5(H5Sget_simple_extent_dims(space, dims, nullptr), what);
    if (dims[1] != cols)
        ctx.layout_error("dataset '{}' has shape [{}, {}], expected [n, {}]", name, dims[0],
                         dims[1], cols);
    if (dims[0] < 1 || dims[0] > kMaxDirections)
        ctx.layout_error("dataset '{}' lists {} directions (expected 1 to {})", name, dims[0],
                         kMaxDirections);
    rows = dims[0];
    std::vector<double> data(rows * cols);
    ctx.h5(H5Dread(set, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, data.data()), what);
    return data;
}

// ---- directions --------------------------------------------------------------------------------

/// Angles in degrees as stored: θ clamped into [0, 90], φ wrapped into [0, 360). Returns nullopt
/// when θ is outside [0, 90] by more than the tolerance, or either angle is not finite.
std::optional<std::pair<double, double>> stored_angles(double theta_deg, double phi_deg) {
    if (!std::isfinite(theta_deg) || !std::isfinite(phi_deg)) return std::nullopt;
    if (theta_deg < -kAngleToleranceDeg || theta_deg > 90 + kAngleToleranceDeg) return std::nullopt;
    double phi = std::fmod(phi_deg, 360.0);
    if (phi < 0) phi += 360.0;
    if (phi >= 360.0) phi = 0.0;
    return std::pair{std::clamp(theta_deg, 0.0, 90.0), phi};
}

void write_directions(const Context& ctx, hid_t file, const char* name, const char* vectors_name,
                      const DirectionSet& set) {
    const int n = set.size();
    std::vector<double> angles(size_t(n) * 2), vectors(size_t(n) * 3);
    for (int i = 0; i < n; ++i) {
        // Validated before the file was created (check_sampling).
        const auto [theta, phi] = *stored_angles(set[i].theta_deg(), set[i].phi_deg());
        const Vec3 v = Direction::from_degrees(theta, phi).vector();
        angles[2 * i] = theta, angles[2 * i + 1] = phi;
        vectors[3 * i] = v.x, vectors[3 * i + 1] = v.y, vectors[3 * i + 2] = v.z;
    }
    write_matrix(ctx, file, name, angles, n, 2);
    write_matrix(ctx, file, vectors_name, vectors, n, 3);
    Handle set_id = ctx.handle(H5Dopen2(file, name, H5P_DEFAULT), H5Dclose, "cannot reopen");
    write_string_attribute(ctx, set_id, "name", set.name());
}

DirectionSet read_directions(const Context& ctx, hid_t file, const char* name,
                             const char* vectors_name) {
    hsize_t n = 0, n_vectors = 0;
    const std::vector<double> angles = read_matrix(ctx, file, name, 2, n);
    const std::vector<double> vectors = read_matrix(ctx, file, vectors_name, 3, n_vectors);
    if (n_vectors != n)
        ctx.layout_error("dataset '{}' has {} rows but '{}' has {}", vectors_name, n_vectors, name,
                         n);
    std::vector<Direction> directions;
    directions.reserve(n);
    for (hsize_t i = 0; i < n; ++i) {
        const auto angle = stored_angles(angles[2 * i], angles[2 * i + 1]);
        if (!angle || angles[2 * i + 1] < -kAngleToleranceDeg ||
            angles[2 * i + 1] > 360 + kAngleToleranceDeg)
            ctx.layout_error(
                "dataset '{}' row {}: theta {}°, phi {}° is outside the hemisphere (theta in "
                "[0, 90], phi in [0, 360))",
                name, i, angles[2 * i], angles[2 * i + 1]);
        const Direction d = Direction::from_degrees(angle->first, angle->second);
        const Vec3 v = d.vector();
        const Vec3 stored{vectors[3 * i], vectors[3 * i + 1], vectors[3 * i + 2]};
        const Vec3 diff = stored - v;
        if (!(std::max({std::abs(diff.x), std::abs(diff.y), std::abs(diff.z)}) <= kVectorTolerance))
            ctx.layout_error(
                "dataset '{}' row {} ({}, {}, {}) is not the unit vector of '{}' row {} (theta "
                "{}°, phi {}°)",
                vectors_name, i, stored.x, stored.y, stored.z, name, i, angles[2 * i],
                angles[2 * i + 1]);
        directions.push_back(d);
    }
    Handle set = ctx.handle(H5Dopen2(file, name, H5P_DEFAULT), H5Dclose, "cannot reopen");
    std::optional<std::string> set_name =
        read_string_attribute(ctx, set, "name", fmt::format("dataset '{}': ", name));
    if (!set_name) ctx.layout_error("dataset '{}' has no attribute 'name'", name);
    return DirectionSet(*set_name, std::move(directions));
}

std::string describe_direction(const Direction& d) {
    return fmt::format("theta {:.4g}°, phi {:.4g}°", d.theta_deg(), d.phi_deg());
}

// ---- image chunks --------------------------------------------------------------------------

struct Compressor {
    libdeflate_compressor* compressor = nullptr;
    int level = 0;
    ~Compressor() { libdeflate_free_compressor(compressor); }
    libdeflate_compressor* get(int wanted) {
        if (compressor && level == wanted) return compressor;
        libdeflate_free_compressor(compressor);
        compressor = libdeflate_alloc_compressor(wanted);
        level = wanted;
        if (!compressor) throw std::bad_alloc();
        return compressor;
    }
};

struct Decompressor {
    libdeflate_decompressor* decompressor = libdeflate_alloc_decompressor();
    ~Decompressor() { libdeflate_free_decompressor(decompressor); }
};

/// HDF5's shuffle filter: byte k of every element goes to plane k. The element size is a
/// template parameter so that the compiler turns the byte scatter into vector shuffles.
template <size_t kElement>
void shuffle_fixed(const uint8_t* in, uint8_t* out, size_t n) {
    for (size_t i = 0; i < n; ++i)
        for (size_t k = 0; k < kElement; ++k) out[k * n + i] = in[i * kElement + k];
}

template <size_t kElement>
void unshuffle_fixed(const uint8_t* in, uint8_t* out, size_t n) {
    for (size_t i = 0; i < n; ++i)
        for (size_t k = 0; k < kElement; ++k) out[i * kElement + k] = in[k * n + i];
}

void shuffle(const uint8_t* in, uint8_t* out, size_t bytes, size_t element) {
    if (element == 2) return shuffle_fixed<2>(in, out, bytes / 2);
    return shuffle_fixed<4>(in, out, bytes / 4);
}

void unshuffle(const uint8_t* in, uint8_t* out, size_t bytes, size_t element) {
    if (element == 2) return unshuffle_fixed<2>(in, out, bytes / 2);
    return unshuffle_fixed<4>(in, out, bytes / 4);
}

// ---- half floats -------------------------------------------------------------------------------
// Converting is most of the CPU time of writing and reading float16 files. Eigen converts one value
// at a time in software unless the whole build targets F16C, so the F16C instructions are used
// directly where the CPU has them (every x86-64 CPU since 2012); results are identical (IEEE
// round to nearest even).

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#define BTF_H5_F16C 1
__attribute__((target("avx,f16c"))) void to_half_f16c(const float* in, uint16_t* out, size_t n) {
    size_t i = 0;
    for (; i + 8 <= n; i += 8)
        _mm_storeu_si128(reinterpret_cast<__m128i*>(out + i),
                         _mm256_cvtps_ph(_mm256_loadu_ps(in + i), _MM_FROUND_TO_NEAREST_INT));
    for (; i < n; ++i) out[i] = Eigen::numext::bit_cast<uint16_t>(Eigen::half(in[i]));
}
__attribute__((target("avx,f16c"))) void from_half_f16c(const uint16_t* in, float* out, size_t n) {
    size_t i = 0;
    for (; i + 8 <= n; i += 8)
        _mm256_storeu_ps(
            out + i, _mm256_cvtph_ps(_mm_loadu_si128(reinterpret_cast<const __m128i*>(in + i))));
    for (; i < n; ++i) out[i] = float(Eigen::numext::bit_cast<Eigen::half>(in[i]));
}
bool have_f16c() {
    // F16C from CPUID directly: clang's __builtin_cpu_supports does not know "f16c".
    static const bool have = [] {
        unsigned eax = 0, ebx = 0, ecx = 0, edx = 0;
        return __builtin_cpu_supports("avx") && __get_cpuid(1, &eax, &ebx, &ecx, &edx) &&
               (ecx & bit_F16C) != 0;
    }();
    return have;
}
#endif

void to_half(const float* in, uint16_t* out, size_t n) {
#ifdef BTF_H5_F16C
    if (have_f16c()) return to_half_f16c(in, out, n);
#endif
    for (size_t i = 0; i < n; ++i) out[i] = Eigen::numext::bit_cast<uint16_t>(Eigen::half(in[i]));
}

void from_half(const uint16_t* in, float* out, size_t n) {
#ifdef BTF_H5_F16C
    if (have_f16c()) return from_half_f16c(in, out, n);
#endif
    for (size_t i = 0; i < n; ++i) out[i] = float(Eigen::numext::bit_cast<Eigen::half>(in[i]));
}

constexpr uint32_t kFloatFiniteMax = 0x7F7FFFFFu;  // bits of FLT_MAX
constexpr uint32_t kHalfFiniteMax = 0x477FE000u;   // bits of 65504.0f

/// True if any of the `kCount` values' magnitude bits exceed `limit`. A fixed trip count with no
/// early exit, so that -O2 vectorizes it.
template <size_t kCount>
bool any_above(const float* values, uint32_t limit) {
    uint32_t bad = 0;
    for (size_t i = 0; i < kCount; ++i) {
        uint32_t bits;
        std::memcpy(&bits, values + i, 4);
        bad |= uint32_t((bits & 0x7FFFFFFFu) > limit);
    }
    return bad != 0;
}

/// Index of the first value whose magnitude's bits exceed `limit` (NaN and ±inf always do), or
/// n if there is none; fast when all values are good.
size_t first_bad_value(const float* values, size_t n, uint32_t limit) {
    constexpr size_t kBlock = 1024;
    size_t begin = 0;
    for (; begin + kBlock <= n; begin += kBlock)
        if (any_above<kBlock>(values + begin, limit)) break;
    for (size_t i = begin; i < n; ++i) {
        uint32_t bits;
        std::memcpy(&bits, values + i, 4);
        if ((bits & 0x7FFFFFFFu) > limit) return i;
    }
    return n;
}

/// Everything the reader validated at open.
struct Layout {
    Handle file;
    Handle images;
    int width = 0, height = 0;
    Sampling sampling;
    FileHeader header;
    std::vector<H5Z_filter_t> filters;  ///< the images' filter pipeline, in application order
    size_t element = 0;                 ///< bytes per stored value
};

/// File access properties for every file btfkit opens: HDF5 locks files it opens, and fails on
/// file systems without locks (some network mounts) unless told to go on without.
Handle file_access(const Context& ctx) {
    Handle fapl = ctx.handle(H5Pcreate(H5P_FILE_ACCESS), H5Pclose, "cannot set up file access");
    ctx.h5(H5Pset_file_locking(fapl, true, true), "cannot set up file access");
    return fapl;
}

bool has_hdf5_signature(const fs::path& path) {
    static constexpr char kSignature[8] = {'\x89', 'H', 'D', 'F', '\r', '\n', '\x1a', '\n'};
    std::ifstream in(path, std::ios::binary);
    if (!in) return false;
    // The superblock sits at 0 or, after a user block, at 512, 1024, 2048, ...
    for (uint64_t offset = 0; offset < (uint64_t{1} << 40); offset = offset ? offset * 2 : 512) {
        char bytes[8];
        in.seekg(std::streamoff(offset));
        if (!in.read(bytes, 8)) return false;
        if (std::memcmp(bytes, kSignature, 8) == 0) return true;
    }
    return false;
}

/// File access properties for a file image in memory: the core driver, no backing store.
Handle memory_access(const Context& ctx, const std::vector<uint8_t>& image) {
    Handle fapl = ctx.handle(H5Pcreate(H5P_FILE_ACCESS), H5Pclose, "cannot set up file access");
    ctx.h5(H5Pset_fapl_core(fapl, 1 << 16, false), "cannot set up file access");
    ctx.h5(H5Pset_file_image(fapl, const_cast<uint8_t*>(image.data()), image.size()),
           "cannot set up file access");
    return fapl;
}

/// Runs `work` (libhdf5 calls on the input `name`) in a child process (util/isolate.h). The library
/// lock is held across the fork, so no other thread is inside libhdf5 when the child starts. The
/// child's copy of this thread has another thread id, to which the held lock does not belong:
/// the child, where nothing else runs, starts from a fresh lock.
void in_child_process(const std::function<void()>& work, const std::string& name) {
    limits();  // read the environment here: after that, limits() takes no lock (in the child too)
    Lock lock;
    run_isolated(
        [&] {
            new (&library_mutex()) std::recursive_mutex;
            work();
        },
        name + ": libhdf5");
}

/// Opens and validates the file at `path` or, when `image` is given, the file image in memory
/// (`path` then only names it): everything open_layout() does after its checks of the path.
/// `open_as`, when given, is the name libhdf5 opens instead of `path` (which still names the file
/// in messages).
Layout read_layout(const fs::path& path, const std::vector<uint8_t>* image,
                   const fs::path& open_as = {});

/// A file open for reading, named by its descriptor: /proc/self/fd/N opens the same file however
/// its path is renamed over, in this process and in a forked child.
class PinnedFile {
  public:
    explicit PinnedFile(const fs::path& path) : m_fd(::open(path.c_str(), O_RDONLY | O_CLOEXEC)) {
        if (m_fd < 0) fail("{}: cannot open for reading: {}", path.string(), std::strerror(errno));
    }
    ~PinnedFile() { ::close(m_fd); }
    PinnedFile(const PinnedFile&) = delete;
    PinnedFile& operator=(const PinnedFile&) = delete;
    fs::path name() const { return fmt::format("/proc/self/fd/{}", m_fd); }

  private:
    int m_fd;
};

/// Opens and validates the file at `path` or, when `image` is given, the file image in memory
/// (`path` then only names it).
///
/// libhdf5 trusts sizes in a file's metadata that btfkit cannot check before the call: a damaged
/// global heap makes libhdf5 1.10 copy or read far outside its buffers while reading the (variable-
/// length string) root attributes (fuzz/regressions/hdf5/). So the whole walk is done first in a
/// child process, where a crash is only a failed check, and then again here.
Layout open_layout(const fs::path& path, const std::vector<uint8_t>* image = nullptr) {
    const Context ctx(path);
    std::error_code ec;
    if (image) {
        if (image->size() < 8 || std::memcmp(image->data(), "\x89HDF\r\n\x1a\n", 8) != 0)
            fail("{}: not an HDF5 file (no HDF5 signature at byte 0)", ctx.name());
    } else {
        if (!fs::exists(path, ec)) fail("{}: no such file", ctx.name());
        if (!fs::is_regular_file(path, ec)) fail("{}: not a file", ctx.name());
        if (!std::ifstream(path, std::ios::binary))
            fail("{}: cannot open for reading: {}", ctx.name(), std::strerror(errno));
        if (!has_hdf5_signature(path)) fail("{}: not an HDF5 file (no HDF5 signature)", ctx.name());
    }
    if (image) {
        in_child_process([&] { read_layout(path, image); }, ctx.name());
        return read_layout(path, image);
    }
    // The child checks the very file this process then reads, even if the path is renamed over
    // in between (libhdf5 keeps its own descriptor once the file is open).
    const PinnedFile pinned(path);
    in_child_process([&] { read_layout(path, nullptr, pinned.name()); }, ctx.name());
    return read_layout(path, nullptr, pinned.name());
}

Layout read_layout(const fs::path& path, const std::vector<uint8_t>* image,
                   const fs::path& open_as) {
    const Context ctx(path);
    Lock lock;
    Layout layout;
    const Handle fapl = image ? memory_access(ctx, *image) : file_access(ctx);
    const fs::path& opened = open_as.empty() ? path : open_as;
    layout.file = ctx.handle(H5Fopen(opened.c_str(), H5F_ACC_RDONLY, fapl), H5Fclose,
                             "cannot open HDF5 file (truncated or corrupt?)");
    const hid_t file = layout.file;

    const std::optional<std::string> format = read_string_attribute(ctx, file, "format", "root ");
    if (!format)
        fail(
            "{}: HDF5 file but not btfkit's layout: root attribute 'format' is missing (expected "
            "\"{}\")",
            ctx.name(), kFormatName);
    if (*format != kFormatName)
        fail(
            "{}: HDF5 file but not btfkit's layout: root attribute 'format' is \"{}\", expected "
            "\"{}\"",
            ctx.name(), *format, kFormatName);
    const std::optional<int64_t> version = read_int_attribute(ctx, file, "format_version");
    if (!version) ctx.layout_error("root attribute 'format_version' is missing");
    if (*version != kFormatVersion)
        fail("{}: btfkit HDF5 format version {} is not supported (this btfkit reads version {})",
             ctx.name(), *version, kFormatVersion);
    FileHeader& header = layout.header;
    header.version = int(*version);

    auto required_string = [&](const char* name) {
        std::optional<std::string> value = read_string_attribute(ctx, file, name, "root ");
        if (!value) ctx.layout_error("root attribute '{}' is missing", name);
        return *value;
    };
    const std::string encoding = required_string("value_encoding");
    if (encoding != kValueEncoding)
        ctx.layout_error("root attribute 'value_encoding' is \"{}\"; btfkit reads only \"{}\"",
                         encoding, kValueEncoding);
    const std::string frame = required_string("frame");
    if (frame != kFrame)
        ctx.layout_error(
            "root attribute 'frame' is \"{}\"; btfkit reads only its own convention "
            "\"{}\"",
            frame, kFrame);
    const std::optional<int64_t> hdr = read_int_attribute(ctx, file, "hdr");
    if (!hdr) ctx.layout_error("root attribute 'hdr' is missing");
    if (*hdr != 0 && *hdr != 1)
        ctx.layout_error("root attribute 'hdr' is {}, expected 0 or 1", *hdr);
    header.hdr = *hdr == 1;
    header.source_format = required_string("source_format");
    header.source_path = required_string("source_path");
    header.source_note = required_string("source_note");
    header.metadata = required_string("metadata");
    try {
        if (!nlohmann::json::parse(header.metadata).is_object())
            ctx.layout_error("root attribute 'metadata' is JSON but not an object");
    } catch (const nlohmann::json::exception& e) {
        ctx.layout_error("root attribute 'metadata' is not valid JSON: {}", e.what());
    }

    layout.sampling.views = read_directions(ctx, file, "views", "view_vectors");
    layout.sampling.lights = read_directions(ctx, file, "lights", "light_vectors");

    layout.images = open_dataset(ctx, file, "images");
    const hid_t images = layout.images;
    Handle space = ctx.handle(H5Dget_space(images), H5Sclose, "cannot read dataset 'images'");
    const int rank = H5Sget_simple_extent_ndims(space);
    if (rank != 5)
        ctx.layout_error(
            "dataset 'images' has {} dimensions, expected 5 ([n_views, n_lights, "
            "height, width, 3])",
            rank);
    hsize_t dims[5];
    ctx.h5(H5Sget_simple_extent_dims(space, dims, nullptr), "cannot read dataset 'images'");
    const hsize_t n_views = layout.sampling.views.size(), n_lights = layout.sampling.lights.size();
    if (dims[0] != n_views || dims[1] != n_lights || dims[4] != 3)
        ctx.layout_error(
            "dataset 'images' has shape [{}, {}, {}, {}, {}] but 'views' lists {} and "
            "'lights' {} directions (expected [{}, {}, height, width, 3])",
            dims[0], dims[1], dims[2], dims[3], dims[4], n_views, n_lights, n_views, n_lights);
    if (dims[2] < 1 || dims[3] < 1 || dims[2] > kMaxSide || dims[3] > kMaxSide)
        ctx.layout_error("dataset 'images' declares {}×{} texels (each side must be 1 to {})",
                         dims[3], dims[2], kMaxSide);
    check_image_size(int64_t(dims[3]), int64_t(dims[2]), ctx.name());
    layout.height = int(dims[2]);
    layout.width = int(dims[3]);

    Handle type = ctx.handle(H5Dget_type(images), H5Tclose, "cannot read dataset 'images'");
    if (is_half_type(type)) {
        header.half = true;
        layout.element = 2;
    } else if (H5Tequal(type, H5T_IEEE_F32LE) > 0) {
        layout.element = 4;
    } else {
        ctx.layout_error(
            "dataset 'images' holds {} values, expected little-endian float16 or "
            "float32",
            describe_type(type));
    }
    if (dims[2] * dims[3] * 3 * layout.element > kMaxChunkBytes)
        ctx.layout_error(
            "dataset 'images': one image of {}×{} texels exceeds HDF5's 4 GiB chunk "
            "limit",
            dims[3], dims[2]);

    Handle dcpl = ctx.handle(H5Dget_create_plist(images), H5Pclose, "cannot read dataset 'images'");
    if (H5Pget_layout(dcpl) != H5D_CHUNKED)
        ctx.layout_error(
            "dataset 'images' is not chunked (expected one chunk per image, [1, 1, "
            "{}, {}, 3])",
            dims[2], dims[3]);
    hsize_t chunk[5] = {0, 0, 0, 0, 0};
    if (H5Pget_chunk(dcpl, 5, chunk) != 5 || chunk[0] != 1 || chunk[1] != 1 ||
        chunk[2] != dims[2] || chunk[3] != dims[3] || chunk[4] != 3)
        ctx.layout_error(
            "dataset 'images' has chunks [{}, {}, {}, {}, {}], expected one chunk "
            "per image [1, 1, {}, {}, 3]",
            chunk[0], chunk[1], chunk[2], chunk[3], chunk[4], dims[2], dims[3]);
    const int n_filters = ctx.h5(H5Pget_nfilters(dcpl), "cannot read dataset 'images'");
    for (int i = 0; i < n_filters; ++i) {
        unsigned flags = 0, config = 0;
        size_t n_values = 4;
        unsigned values[4] = {0, 0, 0, 0};
        char name[64] = {};
        const H5Z_filter_t filter = ctx.h5(H5Pget_filter2(dcpl, unsigned(i), &flags, &n_values,
                                                          values, sizeof name, name, &config),
                                           "cannot read dataset 'images'");
        if (filter == H5Z_FILTER_DEFLATE) {
            header.deflate = n_values > 0 ? int(values[0]) : 1;
        } else if (filter == H5Z_FILTER_SHUFFLE) {
            header.shuffle = true;
        } else {
            ctx.layout_error(
                "dataset 'images' uses HDF5 filter {} ('{}'); btfkit reads images "
                "without filter or with deflate ('gzip') and shuffle",
                int(filter), name);
        }
        layout.filters.push_back(filter);
    }

    hsize_t stored = 0;
    ctx.h5(H5Dget_num_chunks(images, space, &stored), "cannot count images");
    if (stored != n_views * n_lights)
        ctx.layout_error("dataset 'images' stores {} of its {} images (an interrupted write?)",
                         stored, n_views * n_lights);
    // Look up every image as read_image() will, so that the child process of open_layout() walks
    // all of the chunk index that reading can reach.
    for (hsize_t v = 0; v < n_views; ++v)
        for (hsize_t l = 0; l < n_lights; ++l) {
            const hsize_t offset[5] = {v, l, 0, 0, 0};
            hsize_t bytes = 0;
            ctx.h5(H5Dget_chunk_storage_size(images, offset, &bytes), "cannot locate the images");
            if (bytes == 0)
                ctx.layout_error("dataset 'images' lacks the image of view {} light {}", v, l);
        }
    return layout;
}

// ---- the reader -------------------------------------------------------------------------------

class H5Source final : public BtfSource {
  public:
    H5Source(const fs::path& path, Layout layout, const OpenOptions& options)
        : m_ctx(path), m_layout(std::move(layout)) {
        const int n_views = m_layout.sampling.num_views();
        if (options.views.empty()) {
            for (int v = 0; v < n_views; ++v) m_file_views.push_back(v);
            m_sampling = m_layout.sampling;
        } else {
            std::vector<bool> seen(n_views, false);
            for (int v : options.views) {
                check(v >= 0 && v < n_views, "{}: view {} requested but the file has {} views",
                      m_ctx.name(), v, n_views);
                check(!seen[v], "{}: view {} requested twice", m_ctx.name(), v);
                seen[v] = true;
            }
            m_file_views = options.views;
            m_sampling.views = m_layout.sampling.views.subset(
                options.views, m_layout.sampling.views.name() + "-subset");
            m_sampling.lights = m_layout.sampling.lights;
        }
        const FileHeader& h = m_layout.header;
        m_info.format = "btfkit HDF5";
        m_info.path = path;
        m_info.hdr = h.hdr;
        m_info.note = fmt::format("{}{}; written from {}", h.half ? "float16" : "float32",
                                  h.deflate ? fmt::format(", deflate {}", h.deflate) : "",
                                  h.source_format.empty() ? "an unnamed source" : h.source_format);
        if (!h.source_path.empty()) m_info.note += " " + h.source_path;
        if (!h.source_note.empty()) m_info.note += " (" + h.source_note + ")";
        if (!options.views.empty())
            m_info.note += fmt::format("; {} of {} views", m_sampling.num_views(), n_views);
        m_raw_bytes = size_t(m_layout.width) * m_layout.height * 3 * m_layout.element;
    }

    int width() const override { return m_layout.width; }
    int height() const override { return m_layout.height; }
    const Sampling& sampling() const override { return m_sampling; }
    const SourceInfo& info() const override { return m_info; }

    void read_image(int view, int light, Image& out) const override {
        check(view >= 0 && view < m_sampling.num_views() && light >= 0 &&
                  light < m_sampling.num_lights(),
              "{}: image view {} light {} requested but the source has {} views × {} lights",
              m_ctx.name(), view, light, m_sampling.num_views(), m_sampling.num_lights());
        thread_local std::vector<uint8_t> buffer_a, buffer_b;
        thread_local Decompressor decompressor;
        std::vector<uint8_t>* data = &buffer_a;
        std::vector<uint8_t>* spare = &buffer_b;
        const hsize_t offset[5] = {hsize_t(m_file_views[view]), hsize_t(light), 0, 0, 0};
        uint32_t mask = 0;
        {
            Lock lock;
            hsize_t stored = 0;
            if (H5Dget_chunk_storage_size(m_layout.images, offset, &stored) < 0)
                fail("{}: {}: cannot locate the stored image: {}", m_ctx.name(),
                     image_name(view, light), hdf5_detail());
            if (stored == 0)
                fail("{}: {}: image is missing from the file", m_ctx.name(),
                     image_name(view, light));
            // Deflate expands incompressible data by a few bytes per 64 KiB block at most.
            if (stored > m_raw_bytes + m_raw_bytes / 16 + 1024)
                fail("{}: {}: stored image of {} bytes is larger than any encoding of {} bytes",
                     m_ctx.name(), image_name(view, light), stored, m_raw_bytes);
            data->resize(stored);
            if (H5Dread_chunk(m_layout.images, H5P_DEFAULT, offset, &mask, data->data()) < 0)
                fail("{}: {}: cannot read the stored image: {}", m_ctx.name(),
                     image_name(view, light), hdf5_detail());
        }
        // Undo the filters outside the lock, last applied first; a set mask bit means HDF5
        // skipped that filter for this chunk.
        for (int i = int(m_layout.filters.size()) - 1; i >= 0; --i) {
            if (mask & (1u << i)) continue;
            spare->resize(m_raw_bytes);
            if (m_layout.filters[i] == H5Z_FILTER_DEFLATE) {
                size_t produced = 0;
                const libdeflate_result result =
                    libdeflate_zlib_decompress(decompressor.decompressor, data->data(),
                                               data->size(), spare->data(), m_raw_bytes, &produced);
                if (result != LIBDEFLATE_SUCCESS || produced != m_raw_bytes)
                    fail(
                        "{}: {}: compressed image data is corrupt (deflate stream of {} bytes does "
                        "not inflate to {} bytes)",
                        m_ctx.name(), image_name(view, light), data->size(), m_raw_bytes);
            } else {
                if (data->size() != m_raw_bytes)
                    fail("{}: {}: shuffled image holds {} bytes, expected {}", m_ctx.name(),
                         image_name(view, light), data->size(), m_raw_bytes);
                unshuffle(data->data(), spare->data(), m_raw_bytes, m_layout.element);
            }
            std::swap(data, spare);
        }
        if (data->size() != m_raw_bytes)
            fail("{}: {}: stored image holds {} bytes, expected {}", m_ctx.name(),
                 image_name(view, light), data->size(), m_raw_bytes);

        out.reshape(m_layout.width, m_layout.height, 3);
        float* values = out.data();
        const size_t n = m_raw_bytes / m_layout.element;
        if (m_layout.element == 2)
            from_half(reinterpret_cast<const uint16_t*>(data->data()), values, n);
        else
            std::memcpy(values, data->data(), m_raw_bytes);
        if (const size_t i = first_bad_value(values, n, kFloatFiniteMax); i < n) {
            const size_t texel = i / 3;
            fail("{}: {}: texel ({}, {}) channel {} is {}", m_ctx.name(), image_name(view, light),
                 texel % m_layout.width, texel / m_layout.width, i % 3,
                 std::isnan(values[i]) ? "NaN" : "infinite");
        }
    }

  private:
    std::string image_name(int view, int light) const {
        const std::string file_view = m_file_views[view] == view
                                          ? std::string()
                                          : fmt::format(" = file view {}", m_file_views[view]);
        return fmt::format("image view {}{} ({}) light {} ({})", view, file_view,
                           describe_direction(m_sampling.views[view]), light,
                           describe_direction(m_sampling.lights[light]));
    }

    Context m_ctx;
    Layout m_layout;
    Sampling m_sampling;
    SourceInfo m_info;
    std::vector<int> m_file_views;
    size_t m_raw_bytes = 0;
};

// ---- the writer -------------------------------------------------------------------------------

void check_directions(const Context& ctx, const DirectionSet& set, const char* what) {
    check(set.size() >= 1 && hsize_t(set.size()) <= kMaxDirections,
          "{}: cannot write: the source has {} {} (expected 1 to {})", ctx.name(), set.size(), what,
          kMaxDirections);
    for (int i = 0; i < set.size(); ++i)
        check(stored_angles(set[i].theta_deg(), set[i].phi_deg()).has_value(),
              "{}: cannot write: {} {} has theta {}°, phi {}° (outside the hemisphere)", ctx.name(),
              what, i, set[i].theta_deg(), set[i].phi_deg());
}

/// One image of a batch: read from the source, then encoded as the bytes of its chunk.
struct Slot {
    Image image;
    std::vector<uint8_t> raw;
    std::vector<uint8_t> shuffled;
    std::vector<uint8_t> encoded;
    const uint8_t* chunk = nullptr;  ///< the chunk's bytes: in `image`, `raw` or `encoded`
    size_t chunk_bytes = 0;
    std::exception_ptr error;
};

std::string image_name(const Sampling& sampling, int view, int light) {
    return fmt::format("image view {} ({}) light {} ({})", view,
                       describe_direction(sampling.views[view]), light,
                       describe_direction(sampling.lights[light]));
}

void encode(const Context& ctx, const BtfSource& source, int view, int light,
            const WriteOptions& options, Slot& slot) {
    const Image& image = slot.image;
    const Sampling& sampling = source.sampling();
    if (image.width() != source.width() || image.height() != source.height() ||
        image.channels() != 3)
        fail("{}: {}: the source returned a {}×{}×{} image, expected {}×{}×3", ctx.name(),
             image_name(sampling, view, light), image.width(), image.height(), image.channels(),
             source.width(), source.height());
    const size_t n = size_t(image.num_pixels()) * 3;
    const float* values = image.data();
    if (const size_t i =
            first_bad_value(values, n, options.half ? kHalfFiniteMax : kFloatFiniteMax);
        i < n) {
        const float v = values[i];
        const size_t texel = i / 3;
        const std::string problem =
            std::isnan(v)   ? std::string("is NaN")
            : std::isinf(v) ? std::string("is infinite")
                            : fmt::format(
                                  "is {}, beyond the float16 range (±65504); write float32 "
                                  "instead",
                                  v);
        fail("{}: {}: texel ({}, {}) channel {} {}", ctx.name(), image_name(sampling, view, light),
             texel % image.width(), texel / image.width(), i % 3, problem);
    }
    const size_t element = options.half ? 2 : 4;
    const size_t bytes = n * element;
    const uint8_t* raw = reinterpret_cast<const uint8_t*>(values);
    if (options.half) {
        slot.raw.resize(bytes);
        to_half(values, reinterpret_cast<uint16_t*>(slot.raw.data()), n);
        raw = slot.raw.data();
    }
    slot.chunk = raw;
    slot.chunk_bytes = bytes;
    if (options.deflate == 0) return;

    thread_local Compressor compressor;
    libdeflate_compressor* c = compressor.get(options.deflate);
    slot.shuffled.resize(bytes);
    shuffle(raw, slot.shuffled.data(), bytes, element);
    slot.encoded.resize(libdeflate_zlib_compress_bound(c, bytes));
    const size_t size = libdeflate_zlib_compress(c, slot.shuffled.data(), bytes,
                                                 slot.encoded.data(), slot.encoded.size());
    if (size == 0) fail("{}: {}: deflate failed", ctx.name(), image_name(sampling, view, light));
    slot.chunk = slot.encoded.data();
    slot.chunk_bytes = size;
}

}  // namespace

namespace {

/// What probe()'s child process throws for an HDF5 file in another layout.
constexpr const char* kNotBtfkit = "an HDF5 file but not btfkit's";

/// probe() after the signature check; run in a child process (the attribute read is the one that
/// damaged global heaps crash).
void probe_format(const fs::path& path) {
    bool ours = true;
    try {
        const Context ctx(path);
        Lock lock;
        const Handle fapl = file_access(ctx);
        const hid_t id = H5Fopen(path.c_str(), H5F_ACC_RDONLY, fapl);
        if (id < 0) {
            H5Eclear2(H5E_DEFAULT);
            return;  // an HDF5 signature but unreadable: let open() say what is wrong
        }
        Handle file(id, H5Fclose);
        const std::optional<std::string> format =
            read_string_attribute(ctx, file, "format", "root ");
        ours = format && *format == kFormatName;
    } catch (...) {
        ours = false;
    }
    if (!ours) throw Error(kNotBtfkit);
}

}  // namespace

bool probe(const fs::path& path) {
    std::error_code ec;
    if (!fs::is_regular_file(path, ec) || !has_hdf5_signature(path)) return false;
    try {
        in_child_process([&] { probe_format(path); }, path.string());
        return true;
    } catch (const std::exception& e) {
        // A crash (or a cancelled wait) also says "ours": open() then reports it.
        return e.what() != std::string_view(kNotBtfkit);
    }
}

std::unique_ptr<BtfSource> open(const fs::path& path, const OpenOptions& options) {
    check(options.encoding == Encoding::kLinear,
          "{}: btfkit HDF5 holds linear float values; raw 8-bit code values cannot be read from it",
          path.string());
    return std::make_unique<H5Source>(path, open_layout(path), options);
}

std::unique_ptr<BtfSource> open_memory(std::vector<uint8_t> image, const std::string& name,
                                       const OpenOptions& options) {
    check(options.encoding == Encoding::kLinear,
          "{}: btfkit HDF5 holds linear float values; raw 8-bit code values cannot be read from it",
          name);
    // HDF5 copies the image into the file access properties and the core driver copies it
    // again: `image` need not outlive the source.
    return std::make_unique<H5Source>(name, open_layout(name, &image), options);
}

FileHeader read_header(const fs::path& path) {
    return open_layout(path).header;
}

void write(const BtfSource& source, const fs::path& path, const WriteOptions& options,
           Progress& progress) {
    const Context ctx(path);
    const Sampling& sampling = source.sampling();
    const int width = source.width(), height = source.height();
    const int n_views = sampling.num_views(), n_lights = sampling.num_lights();
    check(width >= 1 && height >= 1 && hsize_t(width) <= kMaxSide && hsize_t(height) <= kMaxSide,
          "{}: cannot write: the source has {}×{} texels (each side must be 1 to {})", ctx.name(),
          width, height, kMaxSide);
    const size_t element = options.half ? 2 : 4;
    const uint64_t image_bytes = uint64_t(width) * height * 3 * element;
    check(image_bytes <= kMaxChunkBytes,
          "{}: cannot write: one {}×{} image exceeds HDF5's 4 GiB chunk limit", ctx.name(), width,
          height);
    check_directions(ctx, sampling.views, "view");
    check_directions(ctx, sampling.lights, "light");
    check(options.deflate >= 0 && options.deflate <= 9,
          "{}: cannot write: deflate level {} (expected 0 = none, or 1 to 9)", ctx.name(),
          options.deflate);
    try {
        if (!nlohmann::json::parse(options.metadata).is_object())
            fail("{}: cannot write: the metadata is JSON but not an object", ctx.name());
    } catch (const nlohmann::json::exception& e) {
        fail("{}: cannot write: the metadata is not valid JSON: {}", ctx.name(), e.what());
    }

    AtomicOutput output(path);
    Handle file, images;
    {
        Lock lock;
        Handle fapl = file_access(ctx);
        // The 1.8 file format: readable by every HDF5 since 2008, and it stores attributes of
        // any size (the free-form metadata can exceed the 64 KiB of the original format).
        ctx.h5(H5Pset_libver_bounds(fapl, H5F_LIBVER_V18, H5F_LIBVER_V18), "cannot create file");
        file = ctx.handle(H5Fcreate(output.temp_path().c_str(), H5F_ACC_EXCL, H5P_DEFAULT, fapl),
                          H5Fclose, "cannot create file");
        write_string_attribute(ctx, file, "format", kFormatName);
        write_int_attribute(ctx, file, "format_version", H5T_STD_I32LE, kFormatVersion);
        write_string_attribute(ctx, file, "value_encoding", kValueEncoding);
        write_string_attribute(ctx, file, "frame", kFrame);
        write_int_attribute(ctx, file, "hdr", H5T_STD_I8LE, source.info().hdr ? 1 : 0);
        write_string_attribute(ctx, file, "source_format", source.info().format);
        write_string_attribute(ctx, file, "source_path", source.info().path.string());
        write_string_attribute(ctx, file, "source_note", source.info().note);
        write_string_attribute(ctx, file, "metadata", options.metadata);
        write_directions(ctx, file, "views", "view_vectors", sampling.views);
        write_directions(ctx, file, "lights", "light_vectors", sampling.lights);

        Handle type = options.half ? make_half_type(ctx)
                                   : ctx.handle(H5Tcopy(H5T_IEEE_F32LE), H5Tclose,
                                                "cannot create float type");
        const hsize_t dims[5] = {hsize_t(n_views), hsize_t(n_lights), hsize_t(height),
                                 hsize_t(width), 3};
        const hsize_t chunk[5] = {1, 1, hsize_t(height), hsize_t(width), 3};
        const char* what = "cannot create dataset 'images'";
        Handle space = ctx.handle(H5Screate_simple(5, dims, nullptr), H5Sclose, what);
        Handle dcpl = ctx.handle(H5Pcreate(H5P_DATASET_CREATE), H5Pclose, what);
        ctx.h5(H5Pset_chunk(dcpl, 5, chunk), what);
        // Every chunk is written, so filling them first would only cost time.
        ctx.h5(H5Pset_fill_time(dcpl, H5D_FILL_TIME_NEVER), what);
        if (options.deflate > 0) {
            ctx.h5(H5Pset_shuffle(dcpl), what);
            ctx.h5(H5Pset_deflate(dcpl, unsigned(options.deflate)), what);
        }
        images = ctx.handle(H5Dcreate2(file, "images", type, space, H5P_DEFAULT, dcpl, H5P_DEFAULT),
                            H5Dclose, what);
    }

    // Batches of images are read and encoded in parallel (the source may be slow: JPEG decoding,
    // factorized reconstruction); their chunks are then written in order under the HDF5 lock.
    const int64_t n_images = int64_t(n_views) * n_lights;
    const int64_t threads = std::max<int64_t>(1, std::thread::hardware_concurrency());
    const int64_t per_image = int64_t(width) * height * 3 * 4 + 3 * int64_t(image_bytes);
    const int64_t batch = std::clamp<int64_t>(kBatchBytes / per_image, 1, 4 * threads);
    std::vector<Slot> slots(size_t(std::min(batch, n_images)));
    progress.begin("write HDF5", uint64_t(n_images));
    for (int64_t first = 0; first < n_images; first += batch) {
        const int64_t count = std::min(batch, n_images - first);
        progress.poll();
        parallel_for(0, count, [&](int64_t k) {
            Slot& slot = slots[size_t(k)];
            slot.error = nullptr;
            const int view = int((first + k) / n_lights), light = int((first + k) % n_lights);
            try {
                source.read_image(view, light, slot.image);
                encode(ctx, source, view, light, options, slot);
            } catch (...) {
                slot.error = std::current_exception();
            }
        });
        // Report the first failing image of the batch, whatever the thread timing.
        for (int64_t k = 0; k < count; ++k)
            if (slots[size_t(k)].error) std::rethrow_exception(slots[size_t(k)].error);
        for (int64_t k = 0; k < count; ++k) {
            const int view = int((first + k) / n_lights), light = int((first + k) % n_lights);
            const hsize_t offset[5] = {hsize_t(view), hsize_t(light), 0, 0, 0};
            const Slot& slot = slots[size_t(k)];
            {
                Lock lock;
                if (H5Dwrite_chunk(images, H5P_DEFAULT, 0, offset, slot.chunk_bytes, slot.chunk) <
                    0)
                    fail("{}: {}: cannot write: {}", ctx.name(), image_name(sampling, view, light),
                         hdf5_detail());
            }
            progress.advance();
        }
    }
    {
        Lock lock;
        if (images.close() < 0 || file.close() < 0)
            fail("{}: cannot finish writing: {}", ctx.name(), hdf5_detail());
    }
    output.commit();
    progress.finish();
}

}  // namespace btf::h5
