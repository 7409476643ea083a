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
 * colour (sc_image_quantize). Bytes are deterministic. Decoding stays with
 * OpenImageIO (sc_imageio.cpp).
 */
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
