/* sc_imageio_png.c - PNG files written in C, deflated by libdeflate.
 *
 * Design note. Every texture, mip level and picture the project writes is a
 * PNG, and zlib's deflate at libpng's default level was most of the CPU of
 * a main job on a 2048^2 asset (docs/notes/imageio.md). This writer does
 * what libpng does by default, with libdeflate in place of zlib:
 *  - IHDR, one IDAT, IEND; grey, grey+alpha, RGB or RGBA; 8 or 16 bits,
 *    big-endian; no interlace, no ancillary chunks;
 *  - each row filtered with the one of PNG's five filters (none, sub, up,
 *    average, Paeth) whose output has the smallest sum of absolute values
 *    (as signed bytes), libpng's heuristic;
 *  - the filtered rows deflated as one zlib stream at DEFLATE_LEVEL, which
 *    gives files no larger than zlib's level 6 in less time.
 * The samples are those sc_imageio.h states for PNG: the image's own depth
 * or `bits`, f32 rounded to nearest after the sRGB curve for linear
 * colour (sc_image_quantize). Bytes are deterministic.
 *
 * Decoding takes the forms this writer makes, which are also most PNGs in
 * the wild: 8 or 16 bits, grey, grey+alpha, RGB or RGBA, not interlaced,
 * without tRNS, every chunk's CRC right, the image data exactly the size
 * its rows need. It inflates with libdeflate and undoes the filters, about
 * ten times faster than OpenImageIO's libpng path (docs/notes/imageio.md),
 * with the same samples. Any other PNG, damaged ones included, is declined
 * and goes to OpenImageIO (sc_imageio.cpp), which decodes it or names what
 * is wrong as before.
 */
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <libdeflate.h>

#include "sc_imageio_codecs.h"

#define DEFLATE_LEVEL 6

static void put32(uint8_t *p, uint32_t v) {
    p[0] = (uint8_t)(v >> 24), p[1] = (uint8_t)(v >> 16), p[2] = (uint8_t)(v >> 8), p[3] = (uint8_t)v;
}

/* A chunk: length, type, data, CRC of type and data. */
static void put_chunk(sc_buf *out, const char type[4], const uint8_t *data, size_t n) {
    uint8_t head[8], tail[4];
    put32(head, (uint32_t)n);
    memcpy(head + 4, type, 4);
    uint32_t crc = libdeflate_crc32(0, type, 4);
    if (n) crc = libdeflate_crc32(crc, data, n);
    put32(tail, crc);
    sc_buf_append(out, head, 8);
    if (n) sc_buf_append(out, data, n);
    sc_buf_append(out, tail, 4);
}

static uint8_t paeth(uint8_t a, uint8_t b, uint8_t c) {
    int p = (int)a + b - c, pa = abs(p - a), pb = abs(p - b), pc = abs(p - c);
    return pa <= pb && pa <= pc ? a : pb <= pc ? b : c;
}

/* Row `raw` (n bytes, bpp bytes a pixel) filtered with filter f into out,
 * given the previous raw row (zeros for the first); returns the sum of the
 * output's absolute values as signed bytes. */
static uint64_t filter_row(int f, const uint8_t *raw, const uint8_t *prev, size_t n, size_t bpp, uint8_t *out) {
    uint64_t sum = 0;
    for (size_t i = 0; i < n; i++) {
        uint8_t a = i >= bpp ? raw[i - bpp] : 0, b = prev[i], c = i >= bpp ? prev[i - bpp] : 0;
        uint8_t pred = f == 0 ? 0 : f == 1 ? a : f == 2 ? b : f == 3 ? (uint8_t)(((unsigned)a + b) >> 1) : paeth(a, b, c);
        uint8_t v = (uint8_t)(raw[i] - pred);
        out[i] = v;
        sum += v < 128 ? v : 256u - v;
    }
    return sum;
}

/* The samples of top-down row y (the image's rows run bottom-up), big-endian. */
static void raw_row(const sc_image_data *im, int32_t y, uint8_t *row) {
    const size_t w = (size_t)im->width * (size_t)im->channels;
    const size_t src = (size_t)(im->height - 1 - y) * w;
    if (im->pixel == SC_PIXEL_U8) {
        memcpy(row, (const uint8_t *)im->pixels + src, w);
        return;
    }
    const uint16_t *p = (const uint16_t *)im->pixels + src;
    for (size_t i = 0; i < w; i++) row[2 * i] = (uint8_t)(p[i] >> 8), row[2 * i + 1] = (uint8_t)p[i];
}

/* `im` (u8 or u16) as a PNG of its own depth, appended to out. */
static int write_png(const sc_image_data *im, sc_buf *out, sc_error *err) {
    const size_t bytes_per_sample = im->pixel == SC_PIXEL_U8 ? 1 : 2;
    const size_t bpp = bytes_per_sample * (size_t)im->channels, n = bpp * (size_t)im->width;
    const size_t filtered_size = (n + 1) * (size_t)im->height;
    uint8_t *filtered = malloc(filtered_size), *rows = calloc(2 * n + 1, 1), *trial = malloc(2 * n + 1);
    struct libdeflate_compressor *z = libdeflate_alloc_compressor(DEFLATE_LEVEL);
    uint8_t *packed = NULL;
    int rc = SC_OK;
    if (!filtered || !rows || !trial || !z) {
        rc = sc_fail(err, SC_ENOMEM, "PNG: out of memory for %d x %d", (int)im->width, (int)im->height);
        goto done;
    }
    uint8_t *prev = rows, *raw = rows + n;
    for (int32_t y = 0; y < im->height; y++) {
        raw_row(im, y, raw);
        uint8_t *dst = filtered + (size_t)y * (n + 1);
        uint64_t best = UINT64_MAX;
        for (int f = 0; f < 5; f++) {
            uint64_t sum = filter_row(f, raw, prev, n, bpp, trial);
            if (sum < best) best = sum, dst[0] = (uint8_t)f, memcpy(dst + 1, trial, n);
        }
        uint8_t *t = prev;
        prev = raw, raw = t;
    }
    size_t bound = libdeflate_zlib_compress_bound(z, filtered_size);
    if (!(packed = malloc(bound))) {
        rc = sc_fail(err, SC_ENOMEM, "PNG: out of memory for %zu compressed bytes", bound);
        goto done;
    }
    size_t packed_size = libdeflate_zlib_compress(z, filtered, filtered_size, packed, bound);
    if (packed_size == 0) {
        rc = sc_fail(err, SC_EIO, "PNG: deflate failed");
        goto done;
    }
    static const uint8_t colour_type[5] = {0, 0, 4, 2, 6};   /* by channel count */
    uint8_t ihdr[13];
    put32(ihdr, (uint32_t)im->width);
    put32(ihdr + 4, (uint32_t)im->height);
    ihdr[8] = (uint8_t)(8 * bytes_per_sample), ihdr[9] = colour_type[im->channels];
    ihdr[10] = ihdr[11] = ihdr[12] = 0;
    sc_buf_append(out, "\x89PNG\r\n\x1a\n", 8);
    put_chunk(out, "IHDR", ihdr, sizeof ihdr);
    put_chunk(out, "IDAT", packed, packed_size);
    put_chunk(out, "IEND", NULL, 0);
    if (out->failed) rc = sc_fail(err, SC_ENOMEM, "out of memory for the encoded png");
done:
    free(filtered), free(rows), free(trial), free(packed);
    if (z) libdeflate_free_compressor(z);
    return rc;
}

int sc_imageio_png_encode(const sc_image_data *im, int bits, sc_buf *out, sc_error *err) {
    if (!im || im->width < 1 || im->height < 1 || im->channels < 1 || im->channels > 4 || !im->pixels)
        return sc_fail(err, SC_EINPUT, "PNG: no image, or 1 to 4 channels expected");
    if (bits == 0) bits = im->pixel == SC_PIXEL_U8 ? 8 : 16;
    if (bits != 8 && bits != 16) return sc_fail(err, SC_EINPUT, "PNG: %d bits per channel; 8 or 16", bits);
    sc_pixel want = bits == 8 ? SC_PIXEL_U8 : SC_PIXEL_U16;
    if (im->pixel == want) return write_png(im, out, err);
    /* another depth or float: through f32, rounded to nearest (linear colour
     * gets the sRGB curve) */
    sc_image_data *f = im->pixel == SC_PIXEL_F32 ? NULL : sc_image_to_f32(im);
    sc_image_data *q = (f || im->pixel == SC_PIXEL_F32)
                           ? sc_image_quantize(f ? f : im, want,
                                               im->colorspace == SC_COLOR_LINEAR ? SC_COLOR_SRGB : im->colorspace)
                           : NULL;
    int rc = q ? write_png(q, out, err) : sc_fail(err, SC_ENOMEM, "PNG: out of memory");
    sc_image_free(q), sc_image_free(f);
    return rc;
}

/* ---------------------------------------------------------------- decoding */

static uint32_t get32(const uint8_t *p) {
    return (uint32_t)p[0] << 24 | (uint32_t)p[1] << 16 | (uint32_t)p[2] << 8 | p[3];
}

/* What the chunks of a PNG this reader takes say. */
typedef struct png_layout {
    uint32_t width, height;
    int depth, channels;
    size_t idat_bytes;   /* all IDAT data together */
    int idat_chunks;
} png_layout;

static bool is_type(const uint8_t *t, const char *name) { return memcmp(t, name, 4) == 0; }

/* Walk the chunks (the signature is checked): false for any PNG this reader
 * does not take. */
static bool read_layout(const uint8_t *p, size_t size, png_layout *L) {
    memset(L, 0, sizeof *L);
    size_t at = 8;
    bool header = false;
    while (size - at >= 12) {
        uint32_t len = get32(p + at);
        if (len > 0x7fffffffu || len > size - at - 12) return false;
        const uint8_t *type = p + at + 4, *data = p + at + 8;
        if (libdeflate_crc32(0, type, 4 + (size_t)len) != get32(data + len)) return false;
        at += 12 + (size_t)len;
        if (!header) {   /* IHDR first */
            if (!is_type(type, "IHDR") || len != 13) return false;
            L->width = get32(data), L->height = get32(data + 4);
            int depth = data[8], colour = data[9];
            static const int channels[7] = {1, 0, 3, 0, 2, 0, 4};   /* by colour type; 0: not taken */
            if ((depth != 8 && depth != 16) || colour > 6 || !channels[colour]) return false;
            if (data[10] != 0 || data[11] != 0 || data[12] != 0) return false;   /* deflate, filters, no interlace */
            L->depth = depth, L->channels = channels[colour];
            header = true;
        } else if (is_type(type, "IDAT")) {
            L->idat_bytes += len, L->idat_chunks++;
        } else if (is_type(type, "IEND")) {
            return L->idat_chunks > 0;
        } else if (is_type(type, "tRNS") || (!(type[0] & 0x20) && !is_type(type, "PLTE"))) {
            /* transparency that would become alpha, or a critical chunk out of
             * place; PLTE in a truecolour image is a suggestion, and the other
             * ancillary chunks change no sample */
            return false;
        }
    }
    return false;
}

/* Undo row filter f on raw (n bytes, bpp a pixel) given the previous row. */
static bool unfilter_row(int f, uint8_t *raw, const uint8_t *prev, size_t n, size_t bpp) {
    switch (f) {
    case 0: return true;
    case 1:
        for (size_t i = bpp; i < n; i++) raw[i] = (uint8_t)(raw[i] + raw[i - bpp]);
        return true;
    case 2:
        for (size_t i = 0; i < n; i++) raw[i] = (uint8_t)(raw[i] + prev[i]);
        return true;
    case 3:
        for (size_t i = 0; i < bpp; i++) raw[i] = (uint8_t)(raw[i] + (prev[i] >> 1));
        for (size_t i = bpp; i < n; i++) raw[i] = (uint8_t)(raw[i] + (((unsigned)raw[i - bpp] + prev[i]) >> 1));
        return true;
    case 4:
        for (size_t i = 0; i < bpp; i++) raw[i] = (uint8_t)(raw[i] + prev[i]);
        for (size_t i = bpp; i < n; i++) raw[i] = (uint8_t)(raw[i] + paeth(raw[i - bpp], prev[i], prev[i - bpp]));
        return true;
    default: return false;
    }
}

int sc_imageio_png_decode(const char *name, const void *bytes, size_t size, sc_image_data **out, bool *declined,
                          sc_error *err) {
    *out = NULL;
    *declined = true;
    const uint8_t *p = bytes;
    png_layout L;
    if (!p || size < 8 || memcmp(p, "\x89PNG\r\n\x1a\n", 8) != 0 || !read_layout(p, size, &L)) return SC_OK;
    if (L.width < 1 || L.height < 1 || L.width > SC_IMAGE_MAX_SIDE || L.height > SC_IMAGE_MAX_SIDE ||
        (uint64_t)L.width * L.height > SC_IMAGE_MAX_PIXELS)
        return SC_OK;   /* OpenImageIO's reader says why */
    const size_t bpp = (size_t)L.channels * (size_t)(L.depth / 8), n = bpp * L.width;
    const size_t raw_size = (n + 1) * L.height;
    if (raw_size / 1032 > L.idat_bytes + 64) return SC_OK;   /* deflate packs at most 1032:1: data missing */
    uint8_t *idat = NULL, *raw = malloc(raw_size), *zeros = calloc(n, 1);
    struct libdeflate_decompressor *z = libdeflate_alloc_decompressor();
    sc_image_data *im = sc_image_alloc((int32_t)L.width, (int32_t)L.height, L.channels,
                                       L.depth == 8 ? SC_PIXEL_U8 : SC_PIXEL_U16);
    int rc = SC_OK;
    if (!raw || !zeros || !z || !im) {
        rc = sc_fail(err, SC_ENOMEM, "%s: out of memory for %u x %u pixels", name, L.width, L.height);
        goto done;
    }
    /* the IDAT data as one stream */
    if (!(idat = malloc(L.idat_bytes ? L.idat_bytes : 1))) {
        rc = sc_fail(err, SC_ENOMEM, "%s: out of memory", name);
        goto done;
    }
    size_t filled = 0;
    for (size_t at = 8; size - at >= 12;) {
        uint32_t len = get32(p + at);
        if (is_type(p + at + 4, "IDAT")) memcpy(idat + filled, p + at + 8, len), filled += len;
        if (is_type(p + at + 4, "IEND")) break;
        at += 12 + (size_t)len;
    }
    if (libdeflate_zlib_decompress(z, idat, filled, raw, raw_size, NULL) != LIBDEFLATE_SUCCESS) goto done;
    const uint8_t *prev = zeros;
    for (uint32_t y = 0; y < L.height; y++) {
        uint8_t *row = raw + (size_t)y * (n + 1);
        if (!unfilter_row(row[0], row + 1, prev, n, bpp)) goto done;
        prev = row + 1;
    }
    /* rows bottom-up; 16-bit samples big-endian in the file */
    for (uint32_t y = 0; y < L.height; y++) {
        const uint8_t *src = raw + (size_t)y * (n + 1) + 1;
        size_t dst_row = (size_t)(L.height - 1 - y) * (size_t)L.width * (size_t)L.channels;
        if (L.depth == 8) {
            memcpy((uint8_t *)im->pixels + dst_row, src, n);
        } else {
            uint16_t *dst = (uint16_t *)im->pixels + dst_row;
            for (size_t i = 0; i < n / 2; i++) dst[i] = (uint16_t)(src[2 * i] << 8 | src[2 * i + 1]);
        }
    }
    im->colorspace = SC_COLOR_SRGB;
    snprintf(im->format, sizeof im->format, "png");
    *out = im, im = NULL;
    *declined = false;
done:
    free(idat), free(raw), free(zeros);
    sc_image_free(im);
    if (z) libdeflate_free_decompressor(z);
    return rc;
}
