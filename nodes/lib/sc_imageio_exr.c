/* sc_imageio_exr.c - OpenEXR files (sc_image_encode_exr, sc_image_encode_exr_mip)
 * through the OpenEXR C API, their tiles deflated by libdeflate.
 *
 * Design note.
 *  - The file. One tiled part, 64 x 64 tiles: ONE_LEVEL for one image,
 *    MIPMAP_LEVELS with OpenEXR's ROUND_DOWN sizes for a chain, float channels named as sc_image_encode_exr names them
 *    (Y / Y,A / R,G,B / R,G,B,A; the header lists them sorted by name and
 *    the tiles hold them in that order), ZIP compression, increasing-y chunk
 *    order. The OpenEXR C API writes the header, the chunk table and each
 *    chunk (exr_write_tile_chunk takes a chunk's bytes as they are stored);
 *    no attribute holds a time or a host, so the bytes depend only on the
 *    pixels.
 *  - The compression. A ZIP chunk is the tile's bytes (per scanline, top
 *    down: each channel's row of little-endian floats) with the even bytes
 *    moved before the odd ones, then each byte replaced by its difference
 *    to the one before (+128, mod 256), then a zlib stream; one that would
 *    not be smaller is stored raw, which readers tell by its size. OpenEXR
 *    3.1's own compressor is zlib's; libdeflate's level 1 writes the same
 *    format faster, for files of about the same size. A tile's samples are
 *    gathered once (f32 rows read as stored) and written straight into the
 *    even/odd split; a tile stored raw is written again from them. Deflate
 *    is most of the cost: libdeflate's level 1 is the fastest of the
 *    deflaters and levels that give that size (docs/notes/imageio.md).
 *  - Work. Tiles are packed and deflated by `threads` workers (sc_parallel
 *    over bands of tile rows, each into its own buffers), then written in
 *    chunk order: the same bytes for any thread count.
 *  - Pixels. f32 DATA and LINEAR values are written as they are; u8 and u16
 *    are normalised to [0, 1]; SC_COLOR_SRGB values are linearised (an EXR
 *    holds linear colour), alpha excepted. Rows are flipped: the file's row
 *    0 is the top, the image's row 0 the bottom (v = 0).
 */
#include "sc_imageio.h"

#include <libdeflate.h>
#include <math.h>
#include <openexr.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define TILE 64
#define DEFLATE_LEVEL 1
#define ROWS_PER_BAND 4   /* tile rows per parallel work item */

/* ---------------------------------------------------------------- stream */

/* The file is written into an sc_buf, at the offsets the library asks for. */
typedef struct exr_stream {
    sc_buf *out;
    size_t base;        /* where the file starts in out */
    char error[256];    /* the library's last message */
} exr_stream;

static int64_t stream_write(exr_const_context_t ctxt, void *userdata, const void *buffer, uint64_t sz,
                            uint64_t offset, exr_stream_error_func_ptr_t error_cb) {
    exr_stream *s = userdata;
    size_t end = s->base + (size_t)offset + (size_t)sz;
    if (end > s->out->len) {
        if (!sc_buf_reserve(s->out, end - s->out->len)) {
            if (error_cb) error_cb(ctxt, EXR_ERR_OUT_OF_MEMORY, "out of memory for the encoded exr");
            return -1;
        }
        memset(s->out->data + s->out->len, 0, end - s->out->len);
        s->out->len = end;
    }
    memcpy(s->out->data + s->base + offset, buffer, (size_t)sz);
    return (int64_t)sz;
}

static void stream_error(exr_const_context_t ctxt, exr_result_t code, const char *msg) {
    void *ud = NULL;
    if (exr_get_user_data(ctxt, &ud) == EXR_ERR_SUCCESS && ud) {
        exr_stream *s = ud;
        snprintf(s->error, sizeof s->error, "%s", msg ? msg : exr_get_default_error_message(code));
    }
}

/* ---------------------------------------------------------------- tiles */

/* Sample (x, file row y) of channel c as the file stores it. */
static float file_sample(const sc_image_data *im, int32_t x, int32_t y, int c) {
    size_t at = ((size_t)(im->height - 1 - y) * (size_t)im->width + (size_t)x) * (size_t)im->channels + (size_t)c;
    float f;
    if (im->pixel == SC_PIXEL_U8) f = ((const uint8_t *)im->pixels)[at] * (1.0f / 255.0f);
    else if (im->pixel == SC_PIXEL_U16) f = ((const uint16_t *)im->pixels)[at] * (1.0f / 65535.0f);
    else f = ((const float *)im->pixels)[at];
    if (im->colorspace == SC_COLOR_SRGB && !sc_channel_is_alpha(im->channels, c)) f = sc_srgb_to_linear(f);
    return f;
}

/* The stored bytes of one tile: packed, then ZIP-transformed and deflated
 * when that is smaller. */
typedef struct tile_bytes {
    uint8_t *data;
    size_t size;
} tile_bytes;

typedef struct level_job {
    const sc_image_data *im;
    const int *order;            /* image channel of each file channel */
    int32_t tiles_x, tiles_y;
    tile_bytes *tiles;           /* tiles_x * tiles_y, row-major */
} level_job;

/* The tile's samples in the file's order: per scanline (top down), each
 * channel's row. */
static size_t tile_floats(const level_job *J, int32_t x0, int32_t y0, int32_t w, int32_t h, float *dst) {
    const sc_image_data *im = J->im;
    const int C = im->channels;
    const bool as_stored = im->pixel == SC_PIXEL_F32 && im->colorspace != SC_COLOR_SRGB;
    size_t n = 0;
    for (int32_t y = y0; y < y0 + h; y++)
        for (int k = 0; k < C; k++) {
            if (as_stored) {
                const float *row = (const float *)im->pixels +
                                   ((size_t)(im->height - 1 - y) * (size_t)im->width + (size_t)x0) * (size_t)C +
                                   (size_t)J->order[k];
                for (int32_t x = 0; x < w; x++) dst[n++] = row[(size_t)x * (size_t)C];
            } else {
                for (int32_t x = x0; x < x0 + w; x++) dst[n++] = file_sample(im, x, y, J->order[k]);
            }
        }
    return n;
}

/* Sample k's four little-endian bytes, at 4k .. 4k + 3 of the raw tile. */
static void put_raw(const float *f, size_t count, uint8_t *raw) {
    for (size_t k = 0; k < count; k++) {
        uint32_t b;
        memcpy(&b, &f[k], 4);
        raw[4 * k] = (uint8_t)b, raw[4 * k + 1] = (uint8_t)(b >> 8);
        raw[4 * k + 2] = (uint8_t)(b >> 16), raw[4 * k + 3] = (uint8_t)(b >> 24);
    }
}

/* The same bytes in ZIP's order: the even ones (bytes 0 and 2 of each
 * sample) first, then the odd ones. */
static void put_split(const float *f, size_t count, uint8_t *split) {
    uint8_t *even = split, *odd = split + 2 * count;
    for (size_t k = 0; k < count; k++) {
        uint32_t b;
        memcpy(&b, &f[k], 4);
        even[2 * k] = (uint8_t)b, even[2 * k + 1] = (uint8_t)(b >> 16);
        odd[2 * k] = (uint8_t)(b >> 8), odd[2 * k + 1] = (uint8_t)(b >> 24);
    }
}

static bool encode_tile(const level_job *J, struct libdeflate_compressor *z, float *samples, uint8_t *split,
                        uint8_t *delta, int32_t tx, int32_t ty, tile_bytes *out) {
    const sc_image_data *im = J->im;
    int32_t x0 = tx * TILE, y0 = ty * TILE;
    int32_t w = im->width - x0 < TILE ? im->width - x0 : TILE, h = im->height - y0 < TILE ? im->height - y0 : TILE;
    size_t count = tile_floats(J, x0, y0, w, h, samples), n = 4 * count;
    /* ZIP's transform: even bytes, then odd ones; then byte deltas */
    put_split(samples, count, split);
    delta[0] = split[0];
    for (size_t i = 1; i < n; i++) delta[i] = (uint8_t)(split[i] - split[i - 1] + 128);
    size_t bound = libdeflate_zlib_compress_bound(z, n);
    out->data = malloc(bound > n ? bound : n);
    if (!out->data) return false;
    size_t zn = libdeflate_zlib_compress(z, delta, n, out->data, bound);
    if (zn == 0 || zn >= n) {   /* stored as the raw bytes */
        put_raw(samples, count, out->data);
        zn = n;
    }
    out->size = zn;
    return true;
}

static int encode_band(void *ud, int32_t band) {
    level_job *J = ud;
    struct libdeflate_compressor *z = libdeflate_alloc_compressor(DEFLATE_LEVEL);
    size_t most = (size_t)TILE * TILE * (size_t)J->im->channels * 4;
    float *samples = malloc(most);
    uint8_t *split = malloc(most), *delta = malloc(most);
    bool ok = z && samples && split && delta;
    int32_t ty1 = (band + 1) * ROWS_PER_BAND < J->tiles_y ? (band + 1) * ROWS_PER_BAND : J->tiles_y;
    for (int32_t ty = band * ROWS_PER_BAND; ty < ty1 && ok; ty++)
        for (int32_t tx = 0; tx < J->tiles_x && ok; tx++)
            ok = encode_tile(J, z, samples, split, delta, tx, ty, &J->tiles[(size_t)ty * J->tiles_x + tx]);
    free(samples), free(split), free(delta);
    if (z) libdeflate_free_compressor(z);
    return ok ? SC_OK : SC_ENOMEM;
}

/* ---------------------------------------------------------------- file */

static int exr_fail(sc_error *err, const exr_stream *s, exr_result_t rv, const char *what) {
    return sc_fail(err, rv == EXR_ERR_OUT_OF_MEMORY ? SC_ENOMEM : SC_EIO, "cannot encode a mip-mapped exr: %s: %s",
                   what, s->error[0] ? s->error : exr_get_default_error_message(rv));
}

/* Channel names in sc_image_encode_exr's convention, and the file's order
 * of them (sorted by name, as the header lists them). */
static void channel_names(int channels, const char *names[4], int order[4]) {
    static const char *const all[4][4] = {{"Y"}, {"Y", "A"}, {"R", "G", "B"}, {"R", "G", "B", "A"}};
    for (int k = 0; k < channels; k++) names[k] = all[channels - 1][k], order[k] = k;
    for (int a = 1; a < channels; a++)
        for (int b = a; b > 0 && strcmp(names[order[b]], names[order[b - 1]]) < 0; b--) {
            int t = order[b];
            order[b] = order[b - 1], order[b - 1] = t;
        }
}

static int check_levels(const sc_image_data *const *levels, int nlevels, bool mipmap, sc_error *err) {
    if (nlevels < 1 || !levels) return sc_fail(err, SC_EINPUT, "mip-mapped EXR: no levels");
    if (!mipmap) {
        const sc_image_data *im = levels[0];
        if (nlevels != 1 || !im || !im->pixels || im->width < 1 || im->height < 1 || im->channels < 1 ||
            im->channels > 4)
            return sc_fail(err, SC_EINPUT, "EXR: not an image of 1 to 4 channels");
        return SC_OK;
    }
    for (int k = 0; k < nlevels; k++) {
        const sc_image_data *im = levels[k];
        if (!im || !im->pixels || im->width < 1 || im->height < 1 || im->channels < 1 || im->channels > 4)
            return sc_fail(err, SC_EINPUT, "mip-mapped EXR: level %d is not an image of 1 to 4 channels", k);
        if (im->channels != levels[0]->channels)
            return sc_fail(err, SC_EINPUT, "mip-mapped EXR: level %d has %d channels, level 0 has %d", k,
                           im->channels, levels[0]->channels);
        if (k > 0) {
            int32_t ew = levels[k - 1]->width / 2, eh = levels[k - 1]->height / 2;
            if (ew < 1) ew = 1;
            if (eh < 1) eh = 1;
            if (im->width != ew || im->height != eh)
                return sc_fail(err, SC_EINPUT, "mip-mapped EXR: level %d is %dx%d, expected %dx%d", k, im->width,
                               im->height, ew, eh);
        }
    }
    const sc_image_data *last = levels[nlevels - 1];
    if (last->width != 1 || last->height != 1)
        return sc_fail(err, SC_EINPUT,
                       "mip-mapped EXR: the chain stops at %dx%d; OpenEXR's mip-map levels go down to 1x1",
                       last->width, last->height);
    return SC_OK;
}

/* levels[0 .. nlevels) as a tiled file: MIPMAP_LEVELS, or ONE_LEVEL for one
 * image with mipmap false. */
static int write_tiled(const sc_image_data *const *levels, int nlevels, bool mipmap, int threads, sc_buf *out,
                       sc_error *err) {
    int rc = check_levels(levels, nlevels, mipmap, err);
    if (rc) return rc;
    const int C = levels[0]->channels;
    const char *names[4];
    int order[4];
    channel_names(C, names, order);

    exr_stream s = {.out = out, .base = out->len};
    exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
    init.user_data = &s;
    init.write_fn = stream_write;
    init.error_handler_fn = stream_error;
    exr_context_t ctx = NULL;
    int part = 0;
    exr_result_t rv = exr_start_write(&ctx, "mip.exr", EXR_WRITE_FILE_DIRECTLY, &init);
    if (rv != EXR_ERR_SUCCESS) return exr_fail(err, &s, rv, "start");
    const char *step = "header";
    if ((rv = exr_add_part(ctx, "", EXR_STORAGE_TILED, &part)) == EXR_ERR_SUCCESS &&
        (rv = exr_initialize_required_attr_simple(ctx, part, levels[0]->width, levels[0]->height,
                                                  EXR_COMPRESSION_ZIP)) == EXR_ERR_SUCCESS &&
        (rv = exr_set_tile_descriptor(ctx, part, TILE, TILE, mipmap ? EXR_TILE_MIPMAP_LEVELS : EXR_TILE_ONE_LEVEL,
                                      EXR_TILE_ROUND_DOWN)) ==
            EXR_ERR_SUCCESS) {
        for (int k = 0; k < C && rv == EXR_ERR_SUCCESS; k++)
            rv = exr_add_channel(ctx, part, names[order[k]], EXR_PIXEL_FLOAT, EXR_PERCEPTUALLY_LINEAR, 1, 1);
    }
    if (rv == EXR_ERR_SUCCESS) rv = exr_write_header(ctx);
    int32_t nx = 0, ny = 0;
    if (rv == EXR_ERR_SUCCESS && (rv = exr_get_tile_levels(ctx, part, &nx, &ny)) == EXR_ERR_SUCCESS &&
        nx != nlevels) {
        exr_finish(&ctx);
        out->len = s.base;
        return sc_fail(err, SC_EINPUT, "mip-mapped EXR: %d levels given, the file has %d", nlevels, (int)nx);
    }
    for (int lv = 0; lv < nlevels && rv == EXR_ERR_SUCCESS; lv++) {
        step = "tiles";
        level_job J = {.im = levels[lv], .order = order};
        J.tiles_x = (levels[lv]->width + TILE - 1) / TILE;
        J.tiles_y = (levels[lv]->height + TILE - 1) / TILE;
        J.tiles = sc_calloc_array((size_t)J.tiles_x * (size_t)J.tiles_y, sizeof *J.tiles);
        if (!J.tiles) {
            rv = EXR_ERR_OUT_OF_MEMORY;
            break;
        }
        int32_t bands = (J.tiles_y + ROWS_PER_BAND - 1) / ROWS_PER_BAND;
        if (sc_parallel(threads, bands, encode_band, &J) != SC_OK) rv = EXR_ERR_OUT_OF_MEMORY;
        for (int32_t ty = 0; ty < J.tiles_y && rv == EXR_ERR_SUCCESS; ty++)
            for (int32_t tx = 0; tx < J.tiles_x && rv == EXR_ERR_SUCCESS; tx++) {
                const tile_bytes *t = &J.tiles[(size_t)ty * J.tiles_x + tx];
                rv = exr_write_tile_chunk(ctx, part, tx, ty, lv, lv, t->data, t->size);
            }
        for (size_t k = 0; k < (size_t)J.tiles_x * (size_t)J.tiles_y; k++) free(J.tiles[k].data);
        free(J.tiles);
    }
    if (rv == EXR_ERR_SUCCESS) step = "finish";
    exr_result_t fin = exr_finish(&ctx);
    if (rv == EXR_ERR_SUCCESS) rv = fin;
    if (rv != EXR_ERR_SUCCESS) {
        out->len = s.base;   /* no half-written file */
        return exr_fail(err, &s, rv, step);
    }
    return SC_OK;
}

int sc_image_encode_exr_mip_threads(const sc_image_data *const *levels, int nlevels, int threads, sc_buf *out,
                                    sc_error *err) {
    return write_tiled(levels, nlevels, true, threads, out, err);
}

int sc_image_encode_exr_mip(const sc_image_data *const *levels, int nlevels, sc_buf *out, sc_error *err) {
    return write_tiled(levels, nlevels, true, 1, out, err);
}

int sc_image_encode_exr(const sc_image_data *im, sc_buf *out, sc_error *err) {
    return write_tiled(&im, 1, false, 1, out, err);
}
