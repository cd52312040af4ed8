#include "btf/core/image.h"

#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/imageio.h>

// jpeglib.h needs FILE and size_t declared before it.
#include <jpeglib.h>
#include <csetjmp>
#include <cstddef>
#include <cstdio>

#include <algorithm>
#include <array>
#include <cmath>

#include "btf/core/color.h"
#include "btf/util/atomic_file.h"
#include "btf/util/error.h"
#include "btf/util/limits.h"
#include "btf/util/progress.h"

namespace btf {

Image::Image(int width, int height, int channels, float fill)
    : m_width(width), m_height(height), m_channels(channels) {
    m_data.assign(size_t(width) * height * channels, fill);
}

void Image::reshape(int width, int height, int channels) {
    m_width = width, m_height = height, m_channels = channels;
    m_data.resize(size_t(width) * height * channels);
}

Rgb Image::bilinear(double x, double y) const {
    const double fx = std::clamp(x - 0.5, 0.0, double(m_width - 1));
    const double fy = std::clamp(y - 0.5, 0.0, double(m_height - 1));
    const int x0 = std::min(int(fx), m_width - 1), y0 = std::min(int(fy), m_height - 1);
    const int x1 = std::min(x0 + 1, m_width - 1), y1 = std::min(y0 + 1, m_height - 1);
    const float tx = float(fx - x0), ty = float(fy - y0);
    return rgb(x0, y0) * ((1 - tx) * (1 - ty)) + rgb(x1, y0) * (tx * (1 - ty)) +
           rgb(x0, y1) * ((1 - tx) * ty) + rgb(x1, y1) * (tx * ty);
}

namespace {

// ---- JPEG frame headers ------------------------------------------------------------------------
// OpenImageIO's JPEG reader starts libjpeg's decompressor when it opens a file, and for a
// progressive JPEG that allocates coefficient buffers for the whole image: a crafted SOF claiming
// 65500² asks for tens of GB before OpenImageIO's own size check runs. So the size a JPEG declares
// is read first with libjpeg's header parser alone (jpeg_read_header allocates nothing that grows
// with the image), and checked against btfkit's limit.

struct JpegErrors {
    jpeg_error_mgr manager;
    std::jmp_buf jump;
};

extern "C" void jpeg_error_jump(j_common_ptr info) {
    std::longjmp(reinterpret_cast<JpegErrors*>(info->err)->jump, 1);
}
extern "C" void jpeg_quiet(j_common_ptr, int) {}

bool is_jpeg(const unsigned char* data, size_t size) {
    return size >= 3 && data[0] == 0xFF && data[1] == 0xD8 && data[2] == 0xFF;
}

// The declared width and height, or nothing when the header cannot be read (a prefix too short to
// reach the frame header, or damage OpenImageIO will report in its own words). Only plain C data
// lives between setjmp and longjmp.
std::optional<std::pair<int64_t, int64_t>> jpeg_declared_size(const unsigned char* data,
                                                              size_t size, std::FILE* file) {
    jpeg_decompress_struct info;
    JpegErrors errors;
    info.err = jpeg_std_error(&errors.manager);
    errors.manager.error_exit = jpeg_error_jump;
    errors.manager.emit_message = jpeg_quiet;
    if (setjmp(errors.jump)) {
        jpeg_destroy_decompress(&info);
        return std::nullopt;
    }
    jpeg_create_decompress(&info);
    if (file)
        jpeg_stdio_src(&info, file);
    else
        jpeg_mem_src(&info, data, static_cast<unsigned long>(size));
    const bool ok = jpeg_read_header(&info, TRUE) == JPEG_HEADER_OK;
    const std::pair<int64_t, int64_t> declared{info.image_width, info.image_height};
    jpeg_destroy_decompress(&info);
    if (!ok) return std::nullopt;
    return declared;
}

void check_jpeg_memory(const void* data, size_t size, const std::string& name) {
    const auto* bytes = static_cast<const unsigned char*>(data);
    if (!is_jpeg(bytes, size)) return;
    if (const auto declared = jpeg_declared_size(bytes, size, nullptr))
        check_image_size(declared->first, declared->second, name);
}

void check_jpeg_file(const std::filesystem::path& path) {
    std::FILE* file = std::fopen(path.c_str(), "rb");
    if (!file) return;  // OpenImageIO says why
    unsigned char magic[3] = {};
    std::optional<std::pair<int64_t, int64_t>> declared;
    if (std::fread(magic, 1, 3, file) == 3 && is_jpeg(magic, 3)) {
        std::rewind(file);
        declared = jpeg_declared_size(nullptr, 0, file);
    }
    std::fclose(file);
    if (declared) check_image_size(declared->first, declared->second, path.string());
}

// OpenImageIO's own check of a header's size, which its readers apply when a file is opened —
// before a progressive JPEG's decoder allocates coefficient buffers for the whole image (a crafted
// SOF of 65500² asks libjpeg for tens of GB right there). Set from btfkit's limit before every
// open, since the limit may change: the largest image, with four channels of 32-bit floats.
void apply_decoder_limits() {
    const uint64_t bytes = checked_bytes(uint64_t(limits().image_pixels), 16).value_or(UINT64_MAX);
    OIIO::attribute("limits:imagesize_MB",
                    int(std::clamp<uint64_t>(bytes >> 20, 1, uint64_t(INT32_MAX))));
}

// sRGB → linear for every 8-bit code value: a table instead of a pow() per value.
const std::array<float, 256>& srgb_table() {
    static const std::array<float, 256> table = [] {
        std::array<float, 256> t{};
        for (int i = 0; i < 256; ++i) t[i] = srgb_to_linear(i / 255.0f);
        return t;
    }();
    return table;
}

// OpenImageIO calls this between scanlines: returning true abandons the decode, so SIGINT and
// SIGTERM stop even a large image at once.
bool decode_cancelled(void*, float) {
    return Progress::all_cancelled();
}

Image read_from(OIIO::ImageInput& input, const std::string& name, Encoding encoding) {
    const OIIO::ImageSpec& spec = input.spec();
    if (spec.width <= 0 || spec.height <= 0 || spec.nchannels <= 0)
        fail("{}: image has no pixels", name);
    check_image_size(spec.width, spec.height, name);
    if (spec.nchannels > 64) fail("{}: image has {} channels", name, spec.nchannels);
    // The decode buffer (floats, every channel) is the largest allocation.
    check_alloc(
        checked_bytes(uint64_t(spec.width) * uint64_t(spec.height), uint64_t(spec.nchannels) * 4)
            .value_or(UINT64_MAX),
        name, "decoding the image");
    const bool is_float = spec.format.basetype == OIIO::TypeDesc::FLOAT ||
                          spec.format.basetype == OIIO::TypeDesc::HALF ||
                          spec.format.basetype == OIIO::TypeDesc::DOUBLE;
    const bool is_8bit = spec.format.basetype == OIIO::TypeDesc::UINT8;
    const int nc = spec.nchannels;
    const size_t count = size_t(spec.width) * spec.height * nc;
    auto decode_error = [&] {
        std::string err = input.geterror();
        if (const size_t nl = err.find('\n'); nl != std::string::npos) err.resize(nl);
        fail("{}: cannot decode image: {}", name, err.empty() ? "unknown error" : err);
    };
    Image image(spec.width, spec.height, 3);
    float* out = image.data();
    if (is_8bit) {
        // Decode 8-bit files as bytes and map through a table (exact, and much faster).
        std::vector<uint8_t> pixels(count);
        if (!input.read_image(0, 0, 0, nc, OIIO::TypeDesc::UINT8, pixels.data(), OIIO::AutoStride,
                              OIIO::AutoStride, OIIO::AutoStride, decode_cancelled)) {
            Progress::check_all();
            decode_error();
        }
        // OpenImageIO reports some damage (e.g. a truncated JPEG) only through its error state.
        if (input.has_error()) decode_error();
        std::array<float, 256> table;
        if (encoding == Encoding::kLinear) {
            table = srgb_table();
        } else {
            for (int i = 0; i < 256; ++i) table[i] = i / 255.0f;
        }
        for (int64_t p = 0; p < image.num_pixels(); ++p)
            for (int c = 0; c < 3; ++c) out[p * 3 + c] = table[pixels[p * nc + (nc < 3 ? 0 : c)]];
        return image;
    }
    std::vector<float> pixels(count);
    if (!input.read_image(0, 0, 0, nc, OIIO::TypeDesc::FLOAT, pixels.data(), OIIO::AutoStride,
                          OIIO::AutoStride, OIIO::AutoStride, decode_cancelled)) {
        Progress::check_all();
        decode_error();
    }
    if (input.has_error()) decode_error();
    const bool decode_srgb = !is_float && encoding == Encoding::kLinear;
    for (int64_t p = 0; p < image.num_pixels(); ++p) {
        for (int c = 0; c < 3; ++c) {
            float v = pixels[p * nc + (nc < 3 ? 0 : c)];
            if (decode_srgb) v = srgb_to_linear(v);
            // Refused where it enters: a NaN or infinity would spread through every codec.
            if (!std::isfinite(v))
                fail("{}: texel ({}, {}) holds a non-finite value ({})", name, p % image.width(),
                     p / image.width(), v);
            out[p * 3 + c] = v;
        }
    }
    return image;
}

}  // namespace

Image read_image(const std::filesystem::path& path, Encoding encoding) {
    std::error_code ec;
    if (!std::filesystem::is_regular_file(path, ec)) fail("{}: no such image file", path.string());
    apply_decoder_limits();
    check_jpeg_file(path);
    auto input = OIIO::ImageInput::open(path.string());
    if (!input) {
        std::string err = OIIO::geterror();
        fail("{}: cannot read image: {}", path.string(), err.empty() ? "unknown format" : err);
    }
    return read_from(*input, path.string(), encoding);
}

Image read_image_memory(const void* data, size_t size, const std::string& name, Encoding encoding) {
    OIIO::Filesystem::IOMemReader reader(const_cast<void*>(data), size);
    // Passing the proxy directly (not as an "oiio:ioproxy" attribute) opens the stream once.
    apply_decoder_limits();
    check_jpeg_memory(data, size, name);
    auto input = OIIO::ImageInput::open(name, nullptr, &reader);
    if (!input) {
        std::string err = OIIO::geterror();
        fail("{}: cannot read image: {}", name, err.empty() ? "unknown format" : err);
    }
    return read_from(*input, name, encoding);
}

std::optional<std::pair<int, int>> read_image_size_memory(const void* data, size_t size,
                                                          const std::string& name,
                                                          std::string* error) {
    OIIO::Filesystem::IOMemReader reader(const_cast<void*>(data), size);
    apply_decoder_limits();
    check_jpeg_memory(data, size, name);
    auto input = OIIO::ImageInput::open(name, nullptr, &reader);
    if (!input) {
        if (error) *error = OIIO::geterror();
        return std::nullopt;
    }
    const OIIO::ImageSpec& spec = input->spec();
    check_image_size(spec.width, spec.height, name);
    return std::pair<int, int>{spec.width, spec.height};
}

namespace {
std::string lower_extension(const std::filesystem::path& path) {
    std::string ext = path.extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(), ::tolower);
    return ext;
}
}  // namespace

bool is_float_image_format(const std::filesystem::path& path) {
    const std::string ext = lower_extension(path);
    return ext == ".exr" || ext == ".hdr" || ext == ".tif" || ext == ".tiff" || ext == ".pfm";
}

void check_image_output(const std::filesystem::path& path) {
    if (!OIIO::ImageOutput::create(path.string()))
        fail("{}: unsupported image format '{}'", path.string(), lower_extension(path));
    const AtomicOutput probe(path);  // checks the folder; creates nothing
}

void write_image(const std::filesystem::path& path, const Image& image, Encoding encoding) {
    if (image.empty()) fail("{}: refusing to write an empty image", path.string());
    const std::string ext = lower_extension(path);
    const bool is_float = is_float_image_format(path);
    AtomicOutput out(path);
    // OpenImageIO picks the format from the file name; keep the real extension on the temp file.
    std::filesystem::path temp = out.temp_path();
    temp += ext;
    auto output = OIIO::ImageOutput::create(path.string());
    if (!output) fail("{}: unsupported image format '{}'", path.string(), ext);
    OIIO::ImageSpec spec(image.width(), image.height(), image.channels(),
                         is_float ? (ext == ".exr" ? OIIO::TypeDesc::HALF : OIIO::TypeDesc::FLOAT)
                                  : OIIO::TypeDesc::UINT8);
    if (ext == ".jpg" || ext == ".jpeg") spec.attribute("Compression", "jpeg:95");
    std::vector<float> pixels = image.values();
    if (!is_float) {
        for (float& v : pixels) {
            v = std::clamp(v, 0.0f, 1.0f);
            if (encoding == Encoding::kLinear) v = linear_to_srgb(v);
        }
        spec.attribute("oiio:ColorSpace", "sRGB");
    } else {
        spec.attribute("oiio:ColorSpace", "Linear");
    }
    if (!output->open(temp.string(), spec) ||
        !output->write_image(OIIO::TypeDesc::FLOAT, pixels.data()) || !output->close()) {
        std::error_code ec;
        std::filesystem::remove(temp, ec);
        fail("{}: cannot write image: {}", path.string(), output->geterror());
    }
    std::error_code ec;
    std::filesystem::rename(temp, out.temp_path(), ec);
    if (ec) fail("{}: cannot write image: {}", path.string(), ec.message());
    out.commit();
}

}  // namespace btf
