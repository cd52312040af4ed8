// SPDX-License-Identifier: MIT
// The btfkit Python module's native part (_btfkit): sources, synthesis, compression and
// materials over NumPy arrays. python/btfkit/__init__.py re-exports it with the pure-Python
// helpers; docs/python.md describes the API.
#include <dlfcn.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include <chrono>
#include <cmath>
#include <condition_variable>
#include <filesystem>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>

#include "btf/codecs/codec.h"
#include "btf/codecs/material_source.h"
#include "btf/core/image.h"
#include "btf/core/material.h"
#include "btf/io/open.h"
#include "btf/io/package.h"
#include "btf/quality/measure.h"
#include "btf/render/scene_file.h"
#include "btf/synth/synth.h"
#include "btf/util/error.h"
#include "btf/util/parallel.h"
#include "btf/version.h"

namespace py = pybind11;

namespace {

using btf::BtfSource;
using btf::Material;

// Queries per task of a batch: large enough that a task's setup is noise, small enough that both
// cores get work on a small batch.
constexpr int64_t kChunk = 4096;

// A C-contiguous float64 view of `array` with `columns` columns (any real dtype is converted);
// ValueError naming `name` for another shape or a value that is not finite.
py::array_t<double, py::array::c_style | py::array::forcecast> rows_of(const py::handle& array,
                                                                       const char* name,
                                                                       int64_t columns) {
    auto a = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(array);
    if (!a) throw py::value_error(std::string(name) + ": expected an array of numbers");
    if (a.ndim() != 2 || a.shape(1) != columns)
        throw py::value_error(std::string(name) + ": expected shape (N, " +
                              std::to_string(columns) + "), got " +
                              std::string(py::str(py::make_tuple(a.request().shape))));
    const double* p = a.data();
    for (py::ssize_t i = 0; i < a.size(); ++i)
        if (!std::isfinite(p[i]))
            throw py::value_error(std::string(name) + ": row " + std::to_string(i / columns) +
                                  " holds a value that is not finite");
    return a;
}

void same_rows(int64_t n, const py::array& a, const char* name) {
    if (a.shape(0) != n)
        throw py::value_error(std::string(name) + ": " + std::to_string(a.shape(0)) +
                              " rows, expected " + std::to_string(n));
}

// The arrays of one batch call: each checked by rows_of(), all with the first one's rows.
struct BatchArg {
    const py::object& value;
    const char* name;
    int64_t columns;
};
std::vector<py::array_t<double, py::array::c_style | py::array::forcecast>> batch_of(
    std::initializer_list<BatchArg> args) {
    std::vector<py::array_t<double, py::array::c_style | py::array::forcecast>> out;
    for (const BatchArg& a : args) {
        out.push_back(rows_of(a.value, a.name, a.columns));
        same_rows(out.front().shape(0), out.back(), a.name);
    }
    return out;
}

btf::Vec3 vec3(const double* p) {
    return {p[0], p[1], p[2]};
}

// Runs batch(begin, end) over [0, n) in chunks of kChunk on every core, with the GIL released.
template <typename Batch>
void in_chunks(int64_t n, const Batch& batch) {
    py::gil_scoped_release release;
    btf::parallel_for(0, (n + kChunk - 1) / kChunk, [&](int64_t chunk) {
        const int64_t begin = chunk * kChunk;
        batch(begin, std::min(n, begin + kChunk));
    });
}

// Directions of a set as an (N, 3) array of unit vectors and an (N, 2) array of (θ, φ) degrees.
py::array_t<double> vectors(const btf::DirectionSet& set) {
    py::array_t<double> out({py::ssize_t(set.size()), py::ssize_t(3)});
    auto o = out.mutable_unchecked<2>();
    for (int i = 0; i < set.size(); ++i) {
        const btf::Vec3 v = set[i].vector();
        o(i, 0) = v.x, o(i, 1) = v.y, o(i, 2) = v.z;
    }
    return out;
}
py::array_t<double> degrees(const btf::DirectionSet& set) {
    py::array_t<double> out({py::ssize_t(set.size()), py::ssize_t(2)});
    auto o = out.mutable_unchecked<2>();
    for (int i = 0; i < set.size(); ++i) o(i, 0) = set[i].theta_deg(), o(i, 1) = set[i].phi_deg();
    return out;
}

// An image handed to NumPy without a copy: the array views its values and owns it.
py::array_t<float> owning_array(std::unique_ptr<btf::Image> image) {
    btf::Image* raw = image.release();
    py::capsule owner(raw, [](void* p) { delete static_cast<btf::Image*>(p); });
    return py::array_t<float>(
        {py::ssize_t(raw->height()), py::ssize_t(raw->width()), py::ssize_t(raw->channels())},
        raw->data(), owner);
}

void check_index(int index, int count, const char* what) {
    if (index < 0 || index >= count)
        throw py::index_error(std::string(what) + " " + std::to_string(index) +
                              " is out of range (0 to " + std::to_string(count - 1) + ")");
}

// Keyword arguments as codec parameters: their text as `btf compress -p key=value` takes it
// (True/False as true/false), with '_' in a name read as '-' (power_iterations).
btf::Params params_of(const py::dict& kwargs) {
    btf::Params params;
    for (const auto& [key, value] : kwargs) {
        std::string name = py::str(key);
        std::replace(name.begin(), name.end(), '_', '-');
        std::string text = py::isinstance<py::bool_>(value)
                               ? (value.cast<bool>() ? "true" : "false")
                               : std::string(py::str(value));
        params.set(name, text);
    }
    return params;
}

// Runs work(progress) on a worker thread while the calling thread waits with the GIL released,
// waking when the work reports progress and every 50 ms otherwise, to hold the GIL briefly:
// Python's signal handlers run then (Ctrl-C cancels the work, which unwinds and leaves no partial
// output, and KeyboardInterrupt is raised), and `callback(stage, done, total)` is called on this
// thread. With a callback, each report waits until the callback has run, so an exception it
// raises cancels the work before the work goes on (and before any output is committed); that
// exception is raised in the work's place.
void interruptible(const py::object& callback, const std::function<void(btf::Progress&)>& work) {
    struct Shared {
        std::mutex mutex;
        std::condition_variable changed;
        bool done = false;
        bool event = false;      // a report the calling thread has not handled yet
        bool abandoned = false;  // the calling thread stops handling reports
        std::string stage;
        uint64_t units = 0, total = 0;
        std::exception_ptr error;
    } shared;
    const bool synchronous = !callback.is_none();
    btf::Progress progress([&](std::string_view stage, uint64_t done, uint64_t total) {
        std::unique_lock lock(shared.mutex);
        shared.stage = stage;
        shared.units = done;
        shared.total = total;
        shared.event = true;
        shared.changed.notify_all();
        if (synchronous)
            shared.changed.wait(lock, [&] { return !shared.event || shared.abandoned; });
    });
    std::thread worker([&] {
        try {
            work(progress);
        } catch (...) {
            shared.error = std::current_exception();
        }
        const std::lock_guard lock(shared.mutex);
        shared.done = true;
        shared.changed.notify_all();
    });
    // However this function is left, the work is cancelled (unless done), released and joined.
    struct Join {
        Shared& shared;
        btf::Progress& progress;
        std::thread& worker;
        ~Join() {
            {
                const std::lock_guard lock(shared.mutex);
                if (!shared.done) progress.cancel();
                shared.abandoned = true;
                shared.changed.notify_all();
            }
            py::gil_scoped_release release;
            worker.join();
        }
    } join{shared, progress, worker};

    std::optional<py::error_already_set> raised;  // by a signal handler or the callback
    for (;;) {
        std::string stage;
        uint64_t units = 0, total = 0;
        bool event = false, done = false;
        {
            py::gil_scoped_release release;
            std::unique_lock lock(shared.mutex);
            shared.changed.wait_for(lock, std::chrono::milliseconds(50),
                                    [&] { return shared.done || shared.event; });
            done = shared.done, event = shared.event;
            stage = shared.stage, units = shared.units, total = shared.total;
        }
        if (raised) {
            // Cancelling already: a second Ctrl-C is not raised later out of context.
            if (PyErr_CheckSignals() != 0) PyErr_Clear();
        } else {
            try {
                if (PyErr_CheckSignals() != 0) throw py::error_already_set();
                if (event && synchronous) callback(stage, units, total);
            } catch (py::error_already_set& e) {
                raised.emplace(std::move(e));
                progress.cancel();
            }
        }
        if (event) {
            const std::lock_guard lock(shared.mutex);
            shared.event = false;
            shared.changed.notify_all();
        }
        if (done) break;
    }
    if (raised) throw std::move(*raised);
    if (shared.error) std::rethrow_exception(shared.error);
}

}  // namespace

PYBIND11_MODULE(_btfkit, m) {
    m.doc() = "btfkit's native module; import btfkit instead.";
    m.attr("__version__") = btf::version();
#ifdef BTFKIT_PYTHON_TO_IMAGES
    // Installed (cmake --install --component python), the image module lies at this path
    // relative to this file, whatever the prefix.
    if (Dl_info info; dladdr(reinterpret_cast<void*>(&interruptible), &info) && info.dli_fname)
        btf::add_image_module_candidate(std::filesystem::path(info.dli_fname).parent_path() /
                                        BTFKIT_PYTHON_TO_IMAGES / "libbtfkit_images.so");
#endif

    // btf::Error → btfkit.Error (the same one-line message); btf::Cancelled → KeyboardInterrupt.
    static py::exception<btf::Error> error(m, "Error");
    py::register_exception_translator([](std::exception_ptr p) {
        try {
            if (p) std::rethrow_exception(p);
        } catch (const btf::Cancelled&) {
            PyErr_SetNone(PyExc_KeyboardInterrupt);
        } catch (const btf::Error& e) {
            error(e.what());
        }
    });

    py::class_<BtfSource, std::shared_ptr<BtfSource>>(
        m, "Source", R"(A BTF on disk or synthesized: images read one at a time.

width, height: texels; views, lights: (N, 3) unit vectors in the sample's frame;
view_degrees, light_degrees: (N, 2) arrays of (theta, phi) in degrees;
image(view, light): float32 (height, width, 3) linear RGB.)")
        .def_property_readonly("width", &BtfSource::width)
        .def_property_readonly("height", &BtfSource::height)
        .def_property_readonly("num_views", &BtfSource::num_views)
        .def_property_readonly("num_lights", &BtfSource::num_lights)
        .def_property_readonly("views",
                               [](const BtfSource& s) { return vectors(s.sampling().views); })
        .def_property_readonly("lights",
                               [](const BtfSource& s) { return vectors(s.sampling().lights); })
        .def_property_readonly("view_degrees",
                               [](const BtfSource& s) { return degrees(s.sampling().views); })
        .def_property_readonly("light_degrees",
                               [](const BtfSource& s) { return degrees(s.sampling().lights); })
        .def_property_readonly("format", [](const BtfSource& s) { return s.info().format; })
        .def_property_readonly("hdr", [](const BtfSource& s) { return s.info().hdr; })
        .def(
            "image",
            [](const BtfSource& s, int view, int light) {
                check_index(view, s.num_views(), "view");
                check_index(light, s.num_lights(), "light");
                auto image = std::make_unique<btf::Image>();
                {
                    py::gil_scoped_release release;
                    s.read_image(view, light, *image);
                }
                return owning_array(std::move(image));
            },
            py::arg("view"), py::arg("light"),
            "The image of one view and light: float32 (height, width, 3), linear RGB.");

    m.def(
        "open",
        [](const std::filesystem::path& path) -> std::shared_ptr<BtfSource> {
            py::gil_scoped_release release;
            return btf::open_source(path);
        },
        py::arg("path"),
        "Opens a BTF with the reader that recognizes it: Bonn UBO2003 (zip or folder), UBO2014 "
        "(.btf), UTIA, or btfkit HDF5.");

    m.def(
        "synth",
        [](const std::string& preset, int size, const std::string& sampling,
           uint64_t seed) -> std::shared_ptr<BtfSource> {
            if (size < 1) throw py::value_error("size: must be at least 1");
            const btf::DirectionSet set = btf::DirectionSet::named(sampling);
            return btf::synth::make(preset, size, btf::Sampling{set, set}, seed);
        },
        py::arg("preset"), py::arg("size"), py::arg("sampling") = "ubo81", py::arg("seed") = 1,
        "A synthetic material (btf synth): preset name, size x size texels, the same direction "
        "set (ubo81, dome151 or a file) for views and lights, and a seed.");

    m.def("presets", &btf::synth::preset_names, "The names synth() accepts.");
    m.def("_image_module", &btf::image_module_path,
          "Where the image module (pictures: JPEG, PNG, EXR) was loaded from.");
    m.def(
        "codecs",
        [] {
            py::dict out;
            for (const btf::Codec* c : btf::codecs()) {
                py::dict params;
                for (const btf::ParamInfo& p : c->params()) {
                    py::dict info;
                    info["type"] = p.type;
                    info["default"] = p.default_value;
                    info["range"] = p.range;
                    info["help"] = p.help;
                    params[py::str(p.name)] = info;
                }
                out[py::str(std::string(c->name()))] =
                    py::make_tuple(std::string(c->description()), params);
            }
            return out;
        },
        "Every codec: name -> (description, {parameter: {'type', 'default', 'range', 'help'}}), "
        "the default as `-p name=value` takes it.");

    m.def(
        "_compress",
        [](const std::vector<std::shared_ptr<BtfSource>>& sources,
           const std::vector<std::string>& names, const std::filesystem::path& out,
           const std::string& codec_name, const py::dict& kwargs, const py::object& callback) {
            const btf::Params params = params_of(kwargs);
            const btf::Codec& codec = btf::find_codec(codec_name);
            codec.validate(params);
            std::vector<const BtfSource*> list;
            for (const auto& s : sources) list.push_back(s.get());
            interruptible(callback, [&](btf::Progress& progress) {
                btf::Package package = codec.encode_several(list, names, params, progress);
                btf::write_package(out, package, {}, progress);
            });
        },
        py::arg("sources"), py::arg("names"), py::arg("out"), py::arg("codec"), py::arg("params"),
        py::arg("progress"));

    m.def(
        "_decompress",
        [](const std::filesystem::path& package, const std::filesystem::path& out, bool half,
           int deflate, const std::string& format, const py::object& callback) {
            if (deflate < 0 || deflate > 9) throw py::value_error("deflate: must be 0 to 9");
            if (!format.empty() && format != "png" && format != "exr")
                throw py::value_error("format: expected 'png' or 'exr'");
            interruptible(callback, [&](btf::Progress& progress) {
                const auto source = btf::open_package_source(package);
                btf::write_source(*source, out, {half, deflate, format}, progress);
            });
        },
        py::arg("package"), py::arg("out"), py::arg("half"), py::arg("deflate"), py::arg("format"),
        py::arg("progress"));

    m.def(
        "_render",
        [](const std::string& scene, const std::string& json, const std::string& base,
           const std::optional<std::filesystem::path>& material, const std::string& sampling,
           const btf::render::RenderOverrides& overrides, const py::object& callback) {
            btf::render::LoadOptions load;
            if (sampling == "cosine")
                load.sampling = btf::render::SamplingMode::kCosine;
            else if (sampling == "generic")
                load.sampling = btf::render::SamplingMode::kGeneric;
            else if (sampling != "material")
                throw py::value_error("sampling: expected 'material', 'generic' or 'cosine'");
            btf::render::RenderResult result;
            interruptible(callback, [&](btf::Progress& progress) {
                if (material) load.btf_override = btf::render::open_material_file(*material);
                btf::render::LoadedScene loaded =
                    json.empty() ? btf::render::load_scene(scene, load)
                                 : btf::render::parse_scene(json, scene, base, load);
                if (material && loaded.btf_objects == 0)
                    btf::fail("{}: material needs an object with a \"btf\" material", scene);
                const btf::render::RenderSetup setup =
                    btf::render::apply_overrides(loaded, overrides);
                result = btf::render::render(loaded.scene, setup.options, progress);
            });
            return owning_array(std::make_unique<btf::Image>(std::move(result.color)));
        },
        py::arg("scene"), py::arg("json"), py::arg("base"), py::arg("material"),
        py::arg("sampling"), py::arg("overrides"), py::arg("progress"));

    py::class_<btf::render::RenderOverrides>(m, "_RenderOverrides")
        .def(py::init<>())
        .def_readwrite("integrator", &btf::render::RenderOverrides::integrator)
        .def_readwrite("spp", &btf::render::RenderOverrides::spp)
        .def_readwrite("max_depth", &btf::render::RenderOverrides::max_depth)
        .def_readwrite("time_limit", &btf::render::RenderOverrides::time_limit)
        .def_readwrite("seed", &btf::render::RenderOverrides::seed)
        .def_readwrite("filter", &btf::render::RenderOverrides::filter)
        .def_readwrite("width", &btf::render::RenderOverrides::width)
        .def_readwrite("height", &btf::render::RenderOverrides::height);

    py::class_<Material, std::shared_ptr<Material>>(
        m, "Material", R"(A random-access BTF material (a package, or a UBO2014 file).

eval(uv, wi, wo): (N, 2), (N, 3), (N, 3) -> (N, 3) float32, the filtered value;
sample(uv, wo, xi): (N, 2), (N, 3), (N, 2) -> (wi (N, 3), pdf (N,), value (N, 3));
pdf(uv, wo, wi): (N, 2), (N, 3), (N, 3) -> (N,), the density sample() draws wi with;
albedo(uv, wo): (N, 2), (N, 3) -> (N, 3). Directions are in the sample's frame (z up) and need
not be unit length; the batches run on every core with the GIL released.)")
        .def_property_readonly("width", &Material::width)
        .def_property_readonly("height", &Material::height)
        .def(
            "eval",
            [](const Material& material, const py::object& uv_in, const py::object& wi_in,
               const py::object& wo_in) {
                const auto a = batch_of({{uv_in, "uv", 2}, {wi_in, "wi", 3}, {wo_in, "wo", 3}});
                const int64_t n = a[0].shape(0);
                py::array_t<float> out({py::ssize_t(n), py::ssize_t(3)});
                static_assert(sizeof(btf::Rgb) == 3 * sizeof(float));
                btf::Rgb* values = reinterpret_cast<btf::Rgb*>(out.mutable_data());
                const double *u = a[0].data(), *i = a[1].data(), *o = a[2].data();
                in_chunks(n, [&](int64_t begin, int64_t end) {
                    std::vector<btf::Query> queries(size_t(end - begin));
                    for (int64_t k = begin; k < end; ++k)
                        queries[size_t(k - begin)] = {
                            {u[2 * k], u[2 * k + 1]}, vec3(i + 3 * k), vec3(o + 3 * k)};
                    material.eval_batch(queries, std::span(values + begin, size_t(end - begin)));
                });
                return out;
            },
            py::arg("uv"), py::arg("wi"), py::arg("wo"),
            "The filtered BTF value at each (uv, wi, wo): (N, 2), (N, 3), (N, 3) -> float32 (N, "
            "3).")
        .def(
            "sample",
            [](const Material& material, const py::object& uv_in, const py::object& wo_in,
               const py::object& xi_in) {
                const auto a = batch_of({{uv_in, "uv", 2}, {wo_in, "wo", 3}, {xi_in, "xi", 2}});
                const int64_t n = a[0].shape(0);
                py::array_t<double> wi({py::ssize_t(n), py::ssize_t(3)});
                py::array_t<double> pdf(py::ssize_t{n});
                py::array_t<float> value({py::ssize_t(n), py::ssize_t(3)});
                double *w = wi.mutable_data(), *p = pdf.mutable_data();
                float* v = value.mutable_data();
                const double *u = a[0].data(), *o = a[1].data(), *x = a[2].data();
                in_chunks(n, [&](int64_t begin, int64_t end) {
                    std::vector<btf::SampleQuery> queries(size_t(end - begin));
                    std::vector<btf::LightSample> drawn(queries.size());
                    for (int64_t k = begin; k < end; ++k)
                        queries[size_t(k - begin)] = {
                            {u[2 * k], u[2 * k + 1]}, vec3(o + 3 * k), x[2 * k], x[2 * k + 1]};
                    material.sample_batch(queries, drawn);
                    for (int64_t k = begin; k < end; ++k) {
                        const btf::LightSample& s = drawn[size_t(k - begin)];
                        w[3 * k] = s.wi.x, w[3 * k + 1] = s.wi.y, w[3 * k + 2] = s.wi.z;
                        p[k] = s.pdf;
                        v[3 * k] = s.value.r, v[3 * k + 1] = s.value.g, v[3 * k + 2] = s.value.b;
                    }
                });
                return py::make_tuple(wi, pdf, value);
            },
            py::arg("uv"), py::arg("wo"), py::arg("xi"),
            "Light directions drawn for (uv, wo) from uniform numbers xi in [0, 1)^2: "
            "(wi (N, 3), pdf (N,) per unit solid angle, value (N, 3) float32).")
        .def(
            "pdf",
            [](const Material& material, const py::object& uv_in, const py::object& wo_in,
               const py::object& wi_in) {
                const auto a = batch_of({{uv_in, "uv", 2}, {wo_in, "wo", 3}, {wi_in, "wi", 3}});
                const int64_t n = a[0].shape(0);
                py::array_t<double> out(py::ssize_t{n});
                double* p = out.mutable_data();
                const double *u = a[0].data(), *o = a[1].data(), *i = a[2].data();
                in_chunks(n, [&](int64_t begin, int64_t end) {
                    for (int64_t k = begin; k < end; ++k)
                        p[k] = material.pdf({u[2 * k], u[2 * k + 1]}, vec3(o + 3 * k),
                                            vec3(i + 3 * k));
                });
                return out;
            },
            py::arg("uv"), py::arg("wo"), py::arg("wi"),
            "The density per unit solid angle with which sample(uv, wo, .) draws wi: (N, 2), "
            "(N, 3), (N, 3) -> float64 (N,).")
        .def(
            "eval_sample",
            [](const Material& material, const py::object& indices_in) {
                auto a = py::array_t<int64_t, py::array::c_style | py::array::forcecast>::ensure(
                    indices_in);
                if (!a || a.ndim() != 2 || a.shape(1) != 4)
                    throw py::value_error("indices: expected an integer array of shape (N, 4)");
                const int64_t n = a.shape(0);
                const int64_t limit[4] = {material.width(), material.height(),
                                          material.sampling().num_views(),
                                          material.sampling().num_lights()};
                const char* names[4] = {"x", "y", "view", "light"};
                std::vector<btf::SampleIndex> indices(static_cast<size_t>(n));
                const int64_t* p = a.data();
                for (int64_t k = 0; k < n; ++k) {
                    for (int c = 0; c < 4; ++c)
                        if (p[4 * k + c] < 0 || p[4 * k + c] >= limit[c])
                            throw py::value_error("indices: row " + std::to_string(k) + ": " +
                                                  names[c] + " " + std::to_string(p[4 * k + c]) +
                                                  " is out of range (0 to " +
                                                  std::to_string(limit[c] - 1) + ")");
                    indices[size_t(k)] = {int(p[4 * k]), int(p[4 * k + 1]), int(p[4 * k + 2]),
                                          int(p[4 * k + 3])};
                }
                py::array_t<float> out({py::ssize_t(n), py::ssize_t(3)});
                btf::Rgb* values = reinterpret_cast<btf::Rgb*>(out.mutable_data());
                in_chunks(n, [&](int64_t begin, int64_t end) {
                    material.eval_sample_batch(
                        std::span(indices.data() + begin, size_t(end - begin)),
                        std::span(values + begin, size_t(end - begin)));
                });
                return out;
            },
            py::arg("indices"),
            "Values at exact samples, without interpolation: rows (x, y, view, light) of the "
            "material's texels and direction sets -> float32 (N, 3).")
        .def_property_readonly("views",
                               [](const Material& m) { return vectors(m.sampling().views); })
        .def_property_readonly("lights",
                               [](const Material& m) { return vectors(m.sampling().lights); })
        .def(
            "albedo",
            [](const Material& material, const py::object& uv_in, const py::object& wo_in) {
                const auto a = batch_of({{uv_in, "uv", 2}, {wo_in, "wo", 3}});
                const int64_t n = a[0].shape(0);
                py::array_t<float> out({py::ssize_t(n), py::ssize_t(3)});
                float* v = out.mutable_data();
                const double *u = a[0].data(), *o = a[1].data();
                {
                    py::gil_scoped_release release;
                    btf::parallel_for(0, n, [&](int64_t k) {
                        const btf::Rgb a =
                            material.albedo({u[2 * k], u[2 * k + 1]}, vec3(o + 3 * k));
                        v[3 * k] = a.r, v[3 * k + 1] = a.g, v[3 * k + 2] = a.b;
                    });
                }
                return out;
            },
            py::arg("uv"), py::arg("wo"),
            "Directional albedo (1/pi) * integral of value over the light hemisphere, per "
            "channel.");

    m.def(
        "_open_input",
        [](const std::filesystem::path& path) -> std::shared_ptr<BtfSource> {
            py::gil_scoped_release release;
            return btf::open_package_or_source(path);
        },
        py::arg("path"));

    m.def(
        "_quality",
        [](const std::shared_ptr<BtfSource>& reference, const std::shared_ptr<BtfSource>& test,
           const std::string& metrics, bool cos_weight, double peak, const py::object& callback) {
            btf::quality::QualityRequest request = btf::quality::QualityRequest::parse(metrics);
            request.compare.cos_weight = cos_weight;
            request.compare.peak = peak;
            std::string json;
            interruptible(callback, [&](btf::Progress& progress) {
                json = btf::quality::to_json(
                           btf::quality::measure(*reference, *test, request, progress))
                           .dump();
            });
            return json;
        },
        py::arg("reference"), py::arg("test"), py::arg("metrics"), py::arg("cos_weight"),
        py::arg("peak"), py::arg("progress"));

    m.def(
        "open_material",
        [](const std::filesystem::path& path) -> std::shared_ptr<Material> {
            py::gil_scoped_release release;
            return btf::open_material(path);
        },
        py::arg("path"),
        "Opens a btfkit package (any codec) or a UBO2014 .btf file as a material (a package of "
        "several materials: the first).");

    m.def(
        "open_materials",
        [](const std::filesystem::path& path) {
            std::vector<std::unique_ptr<Material>> all;
            {
                py::gil_scoped_release release;
                all = btf::open_materials(path);
            }
            std::vector<std::shared_ptr<Material>> out;
            for (auto& material : all) out.push_back(std::move(material));
            return out;
        },
        py::arg("path"),
        "Every material of a package: several for one that compress() wrote from a list of "
        "sources (mlvq's shared code-books), one otherwise.");
}
