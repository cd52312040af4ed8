// SPDX-License-Identifier: MIT
// libbtfkit_images.so: btfkit's image file I/O through OpenImageIO (core/image_module.h). Built
// as a module of its own and loaded by core/image.cpp on first use; it links nothing of btfkit.

#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/imageio.h>

#include <memory>
#include <string>

#include "btf/core/image_module.h"

namespace btf::image_module {

struct Reader {
    // Declared first, destroyed last: the input reads through it.
    std::unique_ptr<OIIO::Filesystem::IOMemReader> memory;
    std::unique_ptr<OIIO::ImageInput> input;
};

namespace {

std::string first_line(std::string text) {
    if (const size_t nl = text.find('\n'); nl != std::string::npos) text.resize(nl);
    return text;
}

// OpenImageIO keeps one pending error message per thread: taken before each call, so that a
// failure can only report its own.
void clear_pending_error() {
    (void)OIIO::geterror();
}

// No exception leaves the module: each entry point reports it like any other failure.
template <typename Result, typename Body>
Result guarded(std::string* error, Result failed, Body&& body) {
    try {
        return body();
    } catch (const std::exception& e) {
        if (error) *error = e.what();
    } catch (...) {
        if (error) *error = "unknown error";
    }
    return failed;
}

Reader* open(const std::string& name, const void* data, size_t size, int limit_mb,
             std::string* error) {
    return guarded<Reader*>(error, nullptr, [&]() -> Reader* {
        clear_pending_error();
        // OpenImageIO's check of a header's size, applied by its readers when a file is opened.
        OIIO::attribute("limits:imagesize_MB", limit_mb);
        auto reader = std::make_unique<Reader>();
        if (data) {
            reader->memory =
                std::make_unique<OIIO::Filesystem::IOMemReader>(const_cast<void*>(data), size);
            // Passing the proxy directly (not as an "oiio:ioproxy" attribute) opens it once.
            reader->input = OIIO::ImageInput::open(name, nullptr, reader->memory.get());
        } else {
            reader->input = OIIO::ImageInput::open(name);
        }
        if (!reader->input) {
            *error = first_line(OIIO::geterror());
            return nullptr;
        }
        return reader.release();
    });
}

Header header(const Reader* reader) {
    const OIIO::ImageSpec& spec = reader->input->spec();
    const auto base = spec.format.basetype;
    Header h;
    h.width = spec.width, h.height = spec.height, h.channels = spec.nchannels;
    h.depth = spec.depth;
    h.is_float = base == OIIO::TypeDesc::FLOAT || base == OIIO::TypeDesc::HALF ||
                 base == OIIO::TypeDesc::DOUBLE;
    h.is_8bit = base == OIIO::TypeDesc::UINT8;
    return h;
}

// OpenImageIO calls this between scanlines with the CancelCheck it was given.
bool progress_callback(void* cancelled, float) {
    const CancelCheck check = *static_cast<const CancelCheck*>(cancelled);
    return check && check();
}

bool read(Reader* reader, bool as_8bit, void* pixels, CancelCheck cancelled, std::string* error) {
    return guarded(error, false, [&] {
        OIIO::ImageInput& input = *reader->input;
        (void)input.geterror();
        const bool ok = input.read_image(0, 0, 0, input.spec().nchannels,
                                         as_8bit ? OIIO::TypeDesc::UINT8 : OIIO::TypeDesc::FLOAT,
                                         pixels, OIIO::AutoStride, OIIO::AutoStride,
                                         OIIO::AutoStride, progress_callback, &cancelled);
        // OpenImageIO reports some damage (e.g. a truncated JPEG) only through its error state.
        if (ok && !input.has_error()) return true;
        *error = first_line(input.geterror());
        return false;
    });
}

void close(Reader* reader) {
    delete reader;
}

bool can_write(const std::string& name) {
    return guarded(nullptr, false, [&] {
        const bool found = OIIO::ImageOutput::create(name) != nullptr;
        clear_pending_error();  // "no writer for …" is an answer here, not an error to keep
        return found;
    });
}

bool write(const std::string& name, const std::string& temp_path, int width, int height,
           int channels, const float* pixels, Sample sample, const std::string& compression,
           const std::string& colour_space, std::string* error) {
    return guarded(error, false, [&] {
        clear_pending_error();
        auto output = OIIO::ImageOutput::create(name);
        if (!output) {
            *error = first_line(OIIO::geterror());
            return false;
        }
        const OIIO::TypeDesc type = sample == Sample::kUint8  ? OIIO::TypeDesc::UINT8
                                    : sample == Sample::kHalf ? OIIO::TypeDesc::HALF
                                                              : OIIO::TypeDesc::FLOAT;
        OIIO::ImageSpec spec(width, height, channels, type);
        if (!compression.empty()) spec.attribute("Compression", compression);
        spec.attribute("oiio:ColorSpace", colour_space);
        if (output->open(temp_path, spec) && output->write_image(OIIO::TypeDesc::FLOAT, pixels) &&
            output->close())
            return true;
        *error = first_line(output->geterror());
        return false;
    });
}

constexpr Table kTable{kAbiVersion, open, header, read, close, can_write, write};

}  // namespace
}  // namespace btf::image_module

extern "C" __attribute__((visibility("default"))) const btf::image_module::Table*
btf_image_module_table() {
    return &btf::image_module::kTable;
}
