/* sc_imageio.cpp - the extern "C" shim over OpenImageIO (see sc_imageio.h).
 *
 * Design note: OpenImageIO reads and writes through IOProxy objects, so no
 * temporary files are needed: IOMemReader serves the caller's bytes and
 * IOVecOutput collects the encoded file. The reader is chosen from the first
 * bytes of the data (never from a file name, which may lie). Header limits
 * are checked on the ImageSpec that open() returns, before the pixel array is
 * allocated. Reads land directly in bottom-up order by passing OpenImageIO a
 * negative row stride that starts at the last row. Writes convert to the
 * target type in a top-down scratch array first, with our own rounding and
 * transfer curves, so the output bytes do not depend on OpenImageIO's
 * conversions. Each entry point catches every exception, and OpenImageIO's
 * per-thread error text is drained after each failure so it cannot leak into
 * a later message.
 */
#include "sc_imageio.h"
#include "sc_imageio_codecs.h"

#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/imageio.h>

#include <cmath>
#include <cstring>
#include <strings.h>
#include <exception>
#include <string>
#include <vector>

using OIIO::ImageInput;
using OIIO::ImageOutput;
using OIIO::ImageSpec;
using OIIO::TypeDesc;

namespace {

/* An error message from OIIO, first line only and trimmed. */
std::string tidy(std::string s) {
    while (!s.empty() && (s.back() == '\n' || s.back() == ' ')) s.pop_back();
    size_t nl = s.find('\n');
    if (nl != std::string::npos) s = s.substr(0, nl);
    if (s.empty()) s = "unknown error";
    return s;
}

std::string global_error() { return tidy(OIIO::geterror()); }

/* Round a value in [0, 1] (clamped; NaN -> 0) to an integer in [0, max]. */
uint32_t quantize(float x, uint32_t max) {
    if (!(x > 0.0f)) return 0;
    if (x >= 1.0f) return max;
    return (uint32_t)std::floor((double)x * max + 0.5);
}

bool check_image(const sc_image_data *im, const char *what, sc_error *err) {
    if (!im || !im->pixels || im->width < 1 || im->height < 1 || im->channels < 1 ||
        im->channels > 4 ||
        (im->pixel != SC_PIXEL_U8 && im->pixel != SC_PIXEL_U16 && im->pixel != SC_PIXEL_F32)) {
        sc_fail(err, SC_EINPUT, "%s: not a valid image", what);
        return false;
    }
    return true;
}

/* Copy the image into a top-down array of `bits` integers per sample,
 * keeping channels [0, out_channels). */
template <typename T>
std::vector<T> to_integers(const sc_image_data *im, int out_channels, uint32_t max) {
    const size_t w = (size_t)im->width, h = (size_t)im->height, c = (size_t)im->channels;
    std::vector<T> out(w * h * (size_t)out_channels);
    const bool encode_srgb = im->pixel == SC_PIXEL_F32 && im->colorspace == SC_COLOR_LINEAR;
    for (size_t y = 0; y < h; y++) {
        const size_t src_row = (h - 1 - y) * w * c;   /* bottom-up -> top-down */
        T *dst = out.data() + y * w * (size_t)out_channels;
        for (size_t x = 0; x < w; x++)
            for (size_t k = 0; k < (size_t)out_channels; k++) {
                const size_t s = src_row + x * c + k;
                uint32_t v;
                if (im->pixel == SC_PIXEL_U8) {
                    uint32_t u = ((const uint8_t *)im->pixels)[s];
                    v = max == 255 ? u : u * 257;
                } else if (im->pixel == SC_PIXEL_U16) {
                    uint32_t u = ((const uint16_t *)im->pixels)[s];
                    v = max == 65535 ? u : (u * 255 + 32767) / 65535;
                } else {
                    float f = ((const float *)im->pixels)[s];
                    if (encode_srgb && !sc_channel_is_alpha(im->channels, (int32_t)k)) f = sc_linear_to_srgb(f);
                    v = quantize(f, max);
                }
                dst[x * (size_t)out_channels + k] = (T)v;
            }
    }
    return out;
}

/* Encode `pixels` (top-down, `type`, `channels`) with the OIIO writer for
 * `format` into out. */
int write_with_oiio(const char *format, const ImageSpec &spec, const void *pixels, sc_buf *out,
                    sc_error *err) {
    std::vector<unsigned char> bytes;
    OIIO::Filesystem::IOVecOutput proxy(bytes);
    std::string name = std::string("memory.") + format;
    auto writer = ImageOutput::create(name, &proxy);
    if (!writer) return sc_fail(err, SC_EIO, "%s writer: %s", format, global_error().c_str());
    if (!writer->open(name, spec) || !writer->write_image(spec.format, pixels) || !writer->close()) {
        std::string e = tidy(writer->geterror());
        global_error();
        return sc_fail(err, SC_EIO, "cannot encode %s: %s", format, e.c_str());
    }
    writer.reset();
    sc_buf_append(out, bytes.data(), bytes.size());
    if (out->failed) return sc_fail(err, SC_ENOMEM, "out of memory for the encoded %s", format);
    return SC_OK;
}

/* Walk a PNG's chunks: each must fit in the data, and IEND must come. A
 * truncated PNG is refused here, because OpenImageIO 2.4's reader leaks its
 * error text when libpng runs out of data (it longjmps over a std::string). */
bool png_chunks_complete(const unsigned char *p, size_t size) {
    size_t at = 8;
    while (size - at >= 12) {
        uint32_t len = (uint32_t)p[at] << 24 | (uint32_t)p[at + 1] << 16 | (uint32_t)p[at + 2] << 8 | p[at + 3];
        if (len > 0x7fffffffu || len > size - at - 12) return false;
        bool end = std::memcmp(p + at + 4, "IEND", 4) == 0;
        at += 12 + (size_t)len;
        if (end) return true;
    }
    return false;
}

/* Whether name ends in suffix, letters in either case. */
static bool ends_with(const char *name, const char *suffix) {
    size_t n = std::strlen(name), k = std::strlen(suffix);
    return n >= k && strcasecmp(name + n - k, suffix) == 0;
}

int decode(const char *name, const void *bytes, size_t size, sc_image_data **out, sc_error *err) {
    const char *format = sc_imageio_sniff(bytes, size);
    if (!format && ends_with(name, ".tga")) format = "tga";   /* Targa has no signature: its name says it */
    if (!format)
        return sc_fail(err, SC_EINPUT,
                       "%s: not an image seamcook reads (PNG, JPEG, WebP, TIFF, OpenEXR, HDR, BMP, Targa, DDS)", name);
    if (std::strcmp(format, "png") == 0 && !png_chunks_complete((const unsigned char *)bytes, size))
        return sc_fail(err, SC_EINPUT, "%s: corrupt or truncated png: a chunk runs past the end of the data", name);
    OIIO::Filesystem::IOMemReader proxy(bytes, size);
    auto in = ImageInput::create(format, false, nullptr, &proxy);
    if (!in) return sc_fail(err, SC_EIO, "%s: no %s reader: %s", name, format, global_error().c_str());
    ImageSpec config, spec;
    config.attribute("oiio:UnassociatedAlpha", 1);
    void *proxy_ptr = &proxy;
    config.attribute("oiio:ioproxy", TypeDesc::PTR, &proxy_ptr);
    std::string fake = std::string("memory.") + format;
    if (!in->open(fake, spec, config)) {
        std::string e = tidy(in->geterror());
        global_error();
        return sc_fail(err, SC_EINPUT, "%s: corrupt or truncated %s: %s", name, format, e.c_str());
    }
    const int64_t w = spec.width, h = spec.height, c = spec.nchannels;
    if (w < 1 || h < 1 || w > SC_IMAGE_MAX_SIDE || h > SC_IMAGE_MAX_SIDE ||
        (uint64_t)w * (uint64_t)h > SC_IMAGE_MAX_PIXELS)
        return sc_fail(err, SC_ENOMEM, "%s: %lldx%lld pixels is beyond the limits (%d per side, %u in all)",
                       name, (long long)w, (long long)h, SC_IMAGE_MAX_SIDE, SC_IMAGE_MAX_PIXELS);
    if (c < 1 || c > 4)
        return sc_fail(err, SC_EINPUT, "%s: %lld channels; 1 to 4 are supported", name, (long long)c);
    if (spec.depth > 1 || spec.deep)
        return sc_fail(err, SC_EINPUT, "%s: volume and deep images are not supported", name);
    sc_pixel pixel = SC_PIXEL_F32;
    TypeDesc type = TypeDesc::FLOAT;
    if (spec.format == TypeDesc::UINT8) pixel = SC_PIXEL_U8, type = TypeDesc::UINT8;
    else if (spec.format == TypeDesc::UINT16) pixel = SC_PIXEL_U16, type = TypeDesc::UINT16;
    sc_image_data *im = sc_image_alloc((int32_t)w, (int32_t)h, (int32_t)c, pixel);
    if (!im) return sc_fail(err, SC_ENOMEM, "%s: out of memory for %lldx%lld pixels", name, (long long)w, (long long)h);
    const OIIO::stride_t row = (OIIO::stride_t)(w * c * (int64_t)pixel);
    char *last_row = (char *)im->pixels + (size_t)(h - 1) * (size_t)row;
    if (!in->read_image(0, 0, 0, (int)c, type, last_row, OIIO::AutoStride, -row)) {
        std::string e = tidy(in->geterror());
        global_error();
        sc_image_free(im);
        return sc_fail(err, SC_EINPUT, "%s: corrupt or truncated %s: %s", name, format, e.c_str());
    }
    if (in->has_error()) {   /* warnings such as a premature end of data */
        std::string e = tidy(in->geterror());
        sc_image_free(im);
        return sc_fail(err, SC_EINPUT, "%s: corrupt or truncated %s: %s", name, format, e.c_str());
    }
    in->close();
    im->colorspace = pixel == SC_PIXEL_F32 ? SC_COLOR_LINEAR : SC_COLOR_SRGB;
    snprintf(im->format, sizeof im->format, "%s", format);
    *out = im;
    return SC_OK;
}

int encode_jpeg(const sc_image_data *im, int quality, sc_buf *out, sc_error *err) {
    if (!check_image(im, "JPEG", err)) return err ? err->code : SC_EINPUT;
    if (quality < 1 || quality > 100) return sc_fail(err, SC_EINPUT, "JPEG: quality %d is not in 1..100", quality);
    int channels = im->channels >= 3 ? 3 : 1;
    ImageSpec spec(im->width, im->height, channels, TypeDesc::UINT8);
    spec.attribute("Compression", "jpeg:" + std::to_string(quality));
    std::vector<uint8_t> px = to_integers<uint8_t>(im, channels, 255);
    return write_with_oiio("jpg", spec, px.data(), out, err);
}

/* Every mip level of an EXR (or of any OIIO-readable file), as f32 images. */
int decode_levels(const char *name, const void *bytes, size_t size, sc_image_data ***out, int *nout,
                  sc_error *err) {
    const char *format = sc_imageio_sniff(bytes, size);
    if (!format || std::strcmp(format, "exr") != 0) return sc_fail(err, SC_EINPUT, "%s: not an OpenEXR file", name);
    OIIO::Filesystem::IOMemReader proxy(bytes, size);
    auto in = ImageInput::create(format, false, nullptr, &proxy);
    if (!in) return sc_fail(err, SC_EIO, "%s: no exr reader: %s", name, global_error().c_str());
    ImageSpec config, spec;
    void *proxy_ptr = &proxy;
    config.attribute("oiio:ioproxy", TypeDesc::PTR, &proxy_ptr);
    if (!in->open("memory.exr", spec, config)) {
        std::string e = tidy(in->geterror());
        global_error();
        return sc_fail(err, SC_EINPUT, "%s: corrupt or truncated exr: %s", name, e.c_str());
    }
    std::vector<sc_image_data *> levels;
    for (int k = 0; k < 32 && in->seek_subimage(0, k); k++) {
        ImageSpec s = in->spec();
        const int64_t w = s.width, h = s.height, c = s.nchannels;
        if (w < 1 || h < 1 || w > SC_IMAGE_MAX_SIDE || h > SC_IMAGE_MAX_SIDE ||
            (uint64_t)w * (uint64_t)h > SC_IMAGE_MAX_PIXELS || c < 1 || c > 4) {
            for (sc_image_data *im : levels) sc_image_free(im);
            return sc_fail(err, SC_EINPUT, "%s: level %d: %lldx%lldx%lld is not supported", name, k,
                           (long long)w, (long long)h, (long long)c);
        }
        sc_image_data *im = sc_image_alloc((int32_t)w, (int32_t)h, (int32_t)c, SC_PIXEL_F32);
        if (!im) {
            for (sc_image_data *l : levels) sc_image_free(l);
            return sc_fail(err, SC_ENOMEM, "%s: out of memory", name);
        }
        const OIIO::stride_t row = (OIIO::stride_t)(w * c * 4);
        char *last_row = (char *)im->pixels + (size_t)(h - 1) * (size_t)row;
        if (!in->read_image(0, k, 0, (int)c, TypeDesc::FLOAT, last_row, OIIO::AutoStride, -row)) {
            std::string e = tidy(in->geterror());
            global_error();
            sc_image_free(im);
            for (sc_image_data *l : levels) sc_image_free(l);
            return sc_fail(err, SC_EINPUT, "%s: level %d: %s", name, k, e.c_str());
        }
        im->colorspace = SC_COLOR_LINEAR;
        snprintf(im->format, sizeof im->format, "exr");
        levels.push_back(im);
    }
    in->close();
    global_error();
    sc_image_data **arr = (sc_image_data **)calloc(levels.size() + 1, sizeof *arr);
    if (!arr) {
        for (sc_image_data *l : levels) sc_image_free(l);
        return sc_fail(err, SC_ENOMEM, "%s: out of memory", name);
    }
    for (size_t k = 0; k < levels.size(); k++) arr[k] = levels[k];
    *out = arr;
    *nout = (int)levels.size();
    return SC_OK;
}

}  // namespace

static int module_decode(const char *name, const void *bytes, size_t size, sc_image_data **out,
                               sc_error *err) {
    *out = NULL;
    try {
        return decode(name, bytes, size, out, err);
    } catch (const std::exception &e) {
        return sc_fail(err, SC_EINPUT, "%s: cannot decode: %s", name, e.what());
    } catch (...) {
        return sc_fail(err, SC_EINPUT, "%s: cannot decode (unknown exception)", name);
    }
}

static int module_encode_jpeg(const sc_image_data *im, int quality, sc_buf *out, sc_error *err) {
    try {
        return encode_jpeg(im, quality, out, err);
    } catch (const std::bad_alloc &) {
        return sc_fail(err, SC_ENOMEM, "JPEG: out of memory");
    } catch (const std::exception &e) {
        return sc_fail(err, SC_EIO, "JPEG: %s", e.what());
    } catch (...) {
        return sc_fail(err, SC_EIO, "JPEG: cannot encode (unknown exception)");
    }
}

static int module_decode_levels(const char *name, const void *bytes, size_t size, sc_image_data ***out,
                                int *nout, sc_error *err) {
    *out = NULL;
    *nout = 0;
    try {
        return decode_levels(name, bytes, size, out, nout, err);
    } catch (const std::exception &e) {
        return sc_fail(err, SC_EINPUT, "%s: cannot decode: %s", name, e.what());
    } catch (...) {
        return sc_fail(err, SC_EINPUT, "%s: cannot decode (unknown exception)", name);
    }
}

/* The module's one exported symbol: the table sc_imageio.c loads on first use. */
static const sc_imageio_codecs codecs = {
    SC_IMAGEIO_ABI, module_decode, module_encode_jpeg,
    module_decode_levels,
};

extern "C" __attribute__((visibility("default"))) const sc_imageio_codecs *sc_imageio_codecs_get(void) {
    return &codecs;
}
