/* test_imageio.c - image decoding and encoding (nodes/lib/sc_imageio.h).
 *
 * Binary images are made here: some with our encoder, and some byte by byte
 * (a PNG with stored deflate blocks), so that the row order is checked
 * against a file whose top row is known without trusting our own writer.
 */
#include <stdlib.h>
#include <string.h>

#include "sc_imageio.h"
#include "sc_test.h"

/* ---------------------------------------------------------------- a PNG by hand */

static uint32_t crc32_of(const uint8_t *p, size_t n, uint32_t crc) {
    crc = ~crc;
    for (size_t i = 0; i < n; i++) {
        crc ^= p[i];
        for (int k = 0; k < 8; k++) crc = (crc >> 1) ^ (0xEDB88320u & (0u - (crc & 1)));
    }
    return ~crc;
}

static void put_be32(sc_buf *b, uint32_t v) {
    uint8_t x[4] = {(uint8_t)(v >> 24), (uint8_t)(v >> 16), (uint8_t)(v >> 8), (uint8_t)v};
    sc_buf_append(b, x, 4);
}

static void put_chunk(sc_buf *png, const char *type, const uint8_t *data, size_t n) {
    put_be32(png, (uint32_t)n);
    size_t start = png->len;
    sc_buf_append(png, type, 4);
    if (n) sc_buf_append(png, data, n);
    put_be32(png, crc32_of(png->data + start, n + 4, 0));
}

/* Deflate as zlib stored blocks, with its Adler-32. */
static void zlib_stored(const sc_buf *raw, sc_buf *z) {
    sc_buf_u8(z, 0x78), sc_buf_u8(z, 0x01);
    uint32_t a = 1, b = 0;
    for (size_t i = 0; i < raw->len; i++) a = (a + raw->data[i]) % 65521, b = (b + a) % 65521;
    size_t off = 0;
    do {
        size_t n = raw->len - off > 65535 ? 65535 : raw->len - off;
        sc_buf_u8(z, off + n == raw->len ? 1 : 0);
        uint8_t len[4] = {(uint8_t)n, (uint8_t)(n >> 8), (uint8_t)~n, (uint8_t)(~n >> 8)};
        sc_buf_append(z, len, 4);
        if (n) sc_buf_append(z, raw->data + off, n);
        off += n;
    } while (off < raw->len);
    put_be32(z, (b << 16) | a);
}

/* An 8-bit RGB PNG of w x h with the given top-down rows (no compression:
 * zlib stored blocks). */
static void make_png(sc_buf *png, uint32_t w, uint32_t h, const uint8_t *rgb_top_down,
                     size_t rows_given) {
    sc_buf_init(png);
    sc_buf_append(png, "\x89PNG\r\n\x1a\n", 8);
    uint8_t ihdr[13] = {0};
    for (int i = 0; i < 4; i++) ihdr[i] = (uint8_t)(w >> (24 - 8 * i)), ihdr[4 + i] = (uint8_t)(h >> (24 - 8 * i));
    ihdr[8] = 8, ihdr[9] = 2;   /* 8 bits, RGB */
    put_chunk(png, "IHDR", ihdr, 13);
    sc_buf raw, z;
    sc_buf_init(&raw), sc_buf_init(&z);
    for (size_t y = 0; y < rows_given; y++) {
        sc_buf_u8(&raw, 0);   /* filter: none */
        sc_buf_append(&raw, rgb_top_down + y * w * 3, w * 3);
    }
    zlib_stored(&raw, &z);
    put_chunk(png, "IDAT", z.data, z.len);
    put_chunk(png, "IEND", NULL, 0);
    sc_buf_free(&raw), sc_buf_free(&z);
}

static uint8_t paeth_of(int a, int b, int c) {
    int p = a + b - c, pa = abs(p - a), pb = abs(p - b), pc = abs(p - c);
    return (uint8_t)(pa <= pb && pa <= pc ? a : pb <= pc ? b : c);
}

/* Row `row` (n bytes, bpp a pixel) filtered with filter f (PNG spec, 9.2),
 * appended to raw after its filter byte. */
static void filtered_row(sc_buf *raw, int f, const uint8_t *row, const uint8_t *prev, size_t n, size_t bpp) {
    sc_buf_u8(raw, (uint8_t)f);
    for (size_t i = 0; i < n; i++) {
        int a = i >= bpp ? row[i - bpp] : 0, b = prev ? prev[i] : 0, c = i >= bpp && prev ? prev[i - bpp] : 0;
        int pred = f == 0 ? 0 : f == 1 ? a : f == 2 ? b : f == 3 ? (a + b) / 2 : paeth_of(a, b, c);
        sc_buf_u8(raw, (uint8_t)(row[i] - pred));
    }
}

/* A PNG of w x h, `channels` (grey, grey+alpha, RGB, RGBA) of `depth` bits
 * from top-down big-endian samples: rows filtered in turn with each of the
 * five filters, the data split over three IDAT chunks; or, interlaced, the
 * seven Adam7 passes, unfiltered. */
static void make_png_form(sc_buf *png, uint32_t w, uint32_t h, int channels, int depth, const uint8_t *samples,
                          bool interlaced) {
    static const uint8_t colour_type[5] = {0, 0, 4, 2, 6};
    const size_t bpp = (size_t)channels * (size_t)depth / 8, n = bpp * w;
    sc_buf_init(png);
    sc_buf_append(png, "\x89PNG\r\n\x1a\n", 8);
    uint8_t ihdr[13] = {0};
    for (int i = 0; i < 4; i++) ihdr[i] = (uint8_t)(w >> (24 - 8 * i)), ihdr[4 + i] = (uint8_t)(h >> (24 - 8 * i));
    ihdr[8] = (uint8_t)depth, ihdr[9] = colour_type[channels], ihdr[12] = interlaced ? 1 : 0;
    put_chunk(png, "IHDR", ihdr, 13);
    sc_buf raw, z;
    sc_buf_init(&raw), sc_buf_init(&z);
    if (!interlaced) {
        for (uint32_t y = 0; y < h; y++)
            filtered_row(&raw, (int)(y % 5), samples + y * n, y ? samples + (y - 1) * n : NULL, n, bpp);
    } else {
        static const int x0[7] = {0, 4, 0, 2, 0, 1, 0}, y0[7] = {0, 0, 4, 0, 2, 0, 1};
        static const int dx[7] = {8, 8, 4, 4, 2, 2, 1}, dy[7] = {8, 8, 8, 4, 4, 2, 2};
        for (int pass = 0; pass < 7; pass++) {
            if ((uint32_t)x0[pass] >= w || (uint32_t)y0[pass] >= h) continue;   /* an empty pass */
            for (uint32_t y = (uint32_t)y0[pass]; y < h; y += (uint32_t)dy[pass]) {
                sc_buf_u8(&raw, 0);
                for (uint32_t x = (uint32_t)x0[pass]; x < w; x += (uint32_t)dx[pass])
                    sc_buf_append(&raw, samples + y * n + x * bpp, bpp);
            }
        }
    }
    zlib_stored(&raw, &z);
    size_t third = z.len / 3;
    put_chunk(png, "IDAT", z.data, third);
    put_chunk(png, "IDAT", z.data + third, third);
    put_chunk(png, "IDAT", z.data + 2 * third, z.len - 2 * third);
    put_chunk(png, "IEND", NULL, 0);
    sc_buf_free(&raw), sc_buf_free(&z);
}

/* ---------------------------------------------------------------- helpers */

static sc_image_data *gradient_u8(int w, int h, int c) {
    sc_image_data *im = sc_image_alloc(w, h, c, SC_PIXEL_U8);
    uint8_t *p = im->pixels;
    for (int j = 0; j < h; j++)
        for (int i = 0; i < w; i++)
            for (int k = 0; k < c; k++) p[((size_t)j * w + i) * c + k] = (uint8_t)((i * 7 + j * 13 + k * 50) & 255);
    return im;
}

static bool same_pixels(const sc_image_data *a, const sc_image_data *b) {
    if (a->width != b->width || a->height != b->height || a->channels != b->channels || a->pixel != b->pixel)
        return false;
    size_t n = (size_t)a->width * a->height * a->channels * a->pixel;
    return memcmp(a->pixels, b->pixels, n) == 0;
}

static bool message_has(const sc_error *err, const char *text) {
    bool ok = strstr(err->message, text) != NULL;
    if (!ok) fprintf(stderr, "  message was: %s\n  expected it to contain: %s\n", err->message, text);
    return ok;
}

/* ---------------------------------------------------------------- tests */

SC_TEST(png_rows_are_bottom_up) {
    /* 3 x 4, top row red at x = 0, bottom row green at x = 2 */
    uint8_t rows[4][3][3] = {{{0}}};
    rows[0][0][0] = 255;
    rows[3][2][1] = 255;
    sc_buf png;
    make_png(&png, 3, 4, &rows[0][0][0], 4);
    sc_image_data *im = NULL;
    sc_error err = {0};
    int rc = sc_image_decode("hand.png", png.data, png.len, &im, &err);
    SC_CHECK_MSG(rc == SC_OK, "%s", err.message);
    if (rc == SC_OK) {
        SC_CHECK_INT(im->width, 3);
        SC_CHECK_INT(im->height, 4);
        SC_CHECK_INT(im->channels, 3);
        SC_CHECK_INT(im->pixel, SC_PIXEL_U8);
        SC_CHECK_INT(im->colorspace, SC_COLOR_SRGB);
        SC_CHECK_STR(im->format, "png");
        const uint8_t *p = im->pixels;
        /* top row of the picture = row H-1 in memory */
        SC_CHECK_INT(p[((3 * 3) + 0) * 3 + 0], 255);
        SC_CHECK_INT(p[(0 * 3 + 2) * 3 + 1], 255);
        SC_CHECK_INT(p[0], 0);
        SC_CHECK_NEAR(sc_image_texel(im, 0, 3, 0), 1.0, 0);
        /* our encoder writes it back the same way round */
        sc_buf again;
        sc_buf_init(&again);
        SC_CHECK(sc_image_encode_png(im, 0, &again, &err) == SC_OK);
        sc_image_data *back = NULL;
        SC_CHECK(sc_image_decode("again.png", again.data, again.len, &back, &err) == SC_OK);
        SC_CHECK(back && same_pixels(im, back));
        sc_image_free(back);
        sc_buf_free(&again);
    }
    sc_image_free(im);
    sc_buf_free(&png);
}

/* Every form the C reader takes (8 and 16 bits, 1 to 4 channels), each row
 * with another filter and the data over three IDAT chunks, and the same
 * pixels interlaced, which OpenImageIO decodes: the samples written, rows
 * bottom-up. */
SC_TEST(png_reader_takes_every_filter_and_declines_interlacing) {
    const uint32_t w = 13, h = 11;
    for (int depth = 8; depth <= 16; depth += 8)
        for (int channels = 1; channels <= 4; channels++)
            for (int interlaced = 0; interlaced <= 1; interlaced++) {
                const size_t bytes = (size_t)depth / 8, n = (size_t)w * channels * bytes;
                uint8_t *samples = malloc(n * h);
                uint32_t x = 12345u + (uint32_t)(depth * 10 + channels);
                for (size_t i = 0; i < n * h; i++) x = x * 1103515245u + 12345u, samples[i] = (uint8_t)(x >> 16);
                for (size_t i = 0; i < n * 3; i++) samples[i] = (uint8_t)(i / 5);   /* smooth rows too */
                sc_buf png;
                make_png_form(&png, w, h, channels, depth, samples, interlaced);
                sc_error err = {0};
                sc_image_data *im = NULL;
                int rc = sc_image_decode("form.png", png.data, png.len, &im, &err);
                SC_CHECK_MSG(rc == SC_OK && im, "%d bits, %d channels, interlaced %d: %s", depth, channels, interlaced,
                             err.message);
                if (im) {
                    SC_CHECK(im->width == (int32_t)w && im->height == (int32_t)h && im->channels == channels);
                    SC_CHECK(im->pixel == (depth == 8 ? SC_PIXEL_U8 : SC_PIXEL_U16));
                    SC_CHECK(im->colorspace == SC_COLOR_SRGB);
                    bool same = true;
                    for (uint32_t y = 0; y < h; y++)
                        for (size_t i = 0; i < (size_t)w * channels; i++) {
                            const uint8_t *s = samples + (size_t)y * n + i * bytes;
                            size_t at = (size_t)(h - 1 - y) * w * channels + i;
                            unsigned want = depth == 8 ? s[0] : (unsigned)(s[0] << 8 | s[1]);
                            unsigned got = depth == 8 ? ((uint8_t *)im->pixels)[at] : ((uint16_t *)im->pixels)[at];
                            same = same && want == got;
                        }
                    SC_CHECK_MSG(same, "%d bits, %d channels, interlaced %d: samples differ", depth, channels,
                                 interlaced);
                }
                sc_image_free(im);
                sc_buf_free(&png);
                free(samples);
            }
}

SC_TEST(png_round_trip_u8_u16) {
    for (int c = 1; c <= 4; c++) {
        sc_image_data *im = gradient_u8(37, 19, c);
        sc_buf b;
        sc_buf_init(&b);
        sc_error err = {0};
        SC_CHECK(sc_image_encode_png(im, 0, &b, &err) == SC_OK);
        SC_CHECK(strcmp(sc_image_sniff(b.data, b.len), "png") == 0);
        sc_image_data *back = NULL;
        SC_CHECK_MSG(sc_image_decode("rt.png", b.data, b.len, &back, &err) == SC_OK, "%s", err.message);
        SC_CHECK_MSG(back && same_pixels(im, back), "u8 round trip, %d channels", c);
        /* the same samples at 16 bits: u x 257 */
        sc_buf wide;
        sc_buf_init(&wide);
        sc_image_data *back16 = NULL;
        SC_CHECK(sc_image_encode_png(im, 16, &wide, &err) == SC_OK &&
                 sc_image_decode("rt16.png", wide.data, wide.len, &back16, &err) == SC_OK);
        bool widened = back16 && back16->pixel == SC_PIXEL_U16;
        for (size_t k = 0; widened && k < (size_t)im->width * im->height * c; k++)
            widened = ((const uint16_t *)back16->pixels)[k] == 257u * ((const uint8_t *)im->pixels)[k];
        SC_CHECK_MSG(widened, "u8 written at 16 bits, %d channels", c);
        sc_image_free(back16);
        sc_buf_free(&wide);
        /* deterministic bytes */
        sc_buf b2;
        sc_buf_init(&b2);
        SC_CHECK(sc_image_encode_png(im, 0, &b2, &err) == SC_OK);
        SC_CHECK(b.len == b2.len && memcmp(b.data, b2.data, b.len) == 0);
        sc_buf_free(&b2);
        sc_image_free(back);
        sc_buf_free(&b);
        sc_image_free(im);
    }
    sc_image_data *im = sc_image_alloc(5, 3, 3, SC_PIXEL_U16);
    uint16_t *p = im->pixels;
    for (int k = 0; k < 45; k++) p[k] = (uint16_t)(k * 1457 + 3);
    sc_buf b;
    sc_buf_init(&b);
    sc_error err = {0};
    SC_CHECK(sc_image_encode_png(im, 0, &b, &err) == SC_OK);
    sc_image_data *back = NULL;
    SC_CHECK(sc_image_decode("rt16.png", b.data, b.len, &back, &err) == SC_OK);
    SC_CHECK(back && back->pixel == SC_PIXEL_U16 && same_pixels(im, back));
    sc_image_free(back);
    sc_buf_free(&b);
    sc_image_free(im);
}

SC_TEST(png_from_float_quantises) {
    sc_image_data *im = sc_image_alloc(4, 1, 1, SC_PIXEL_F32);
    float *f = im->pixels;
    f[0] = -0.5f, f[1] = 0.5f, f[2] = 2.0f, f[3] = 0.25f;
    im->colorspace = SC_COLOR_DATA;
    sc_buf b;
    sc_buf_init(&b);
    sc_error err = {0};
    SC_CHECK(sc_image_encode_png(im, 8, &b, &err) == SC_OK);
    sc_image_data *back = NULL;
    SC_CHECK(sc_image_decode("q.png", b.data, b.len, &back, &err) == SC_OK);
    if (back) {
        const uint8_t *p = back->pixels;
        SC_CHECK_INT(p[0], 0);
        SC_CHECK_INT(p[1], 128);   /* 127.5 rounds to nearest (up) */
        SC_CHECK_INT(p[2], 255);
        SC_CHECK_INT(p[3], 64);    /* 63.75 */
    }
    sc_image_free(back);
    /* linear float is written with the sRGB curve, 16 bits by default */
    im->colorspace = SC_COLOR_LINEAR;
    sc_buf_reset(&b);
    SC_CHECK(sc_image_encode_png(im, 0, &b, &err) == SC_OK);
    back = NULL;
    SC_CHECK(sc_image_decode("q16.png", b.data, b.len, &back, &err) == SC_OK);
    if (back) {
        SC_CHECK_INT(back->pixel, SC_PIXEL_U16);
        double expect = 1.055 * pow(0.5, 1 / 2.4) - 0.055;
        SC_CHECK_NEAR(sc_image_texel(back, 1, 0, 0), expect, 1.0 / 65535);
    }
    sc_image_free(back);
    sc_buf_free(&b);
    sc_image_free(im);
}

SC_TEST(jpeg_round_trip) {
    sc_image_data *im = sc_image_alloc(32, 16, 3, SC_PIXEL_U8);
    memset(im->pixels, 120, 32 * 16 * 3);
    uint8_t *p = im->pixels;
    for (int i = 0; i < 32 * 3; i++) p[(size_t)15 * 32 * 3 + i] = 200;   /* top row brighter */
    sc_buf b;
    sc_buf_init(&b);
    sc_error err = {0};
    SC_CHECK(sc_image_encode_jpeg(im, 95, &b, &err) == SC_OK);
    sc_image_data *back = NULL;
    SC_CHECK_MSG(sc_image_decode("rt.jpg", b.data, b.len, &back, &err) == SC_OK, "%s", err.message);
    if (back) {
        SC_CHECK_STR(back->format, "jpg");
        SC_CHECK_INT(back->channels, 3);
        SC_CHECK_NEAR(sc_image_texel(back, 5, 0, 0), 120 / 255.0, 6 / 255.0);
        SC_CHECK_NEAR(sc_image_texel(back, 5, 15, 1), 200 / 255.0, 12 / 255.0);
    }
    sc_image_free(back);
    sc_buf_free(&b);
    sc_image_free(im);
}

SC_TEST(exr_float_round_trip) {
    for (int c = 1; c <= 4; c++) {
        sc_image_data *im = sc_image_alloc(13, 7, c, SC_PIXEL_F32);
        im->colorspace = SC_COLOR_LINEAR;
        float *f = im->pixels;
        for (int k = 0; k < 13 * 7 * c; k++) f[k] = (float)(sin(k * 0.37) * 3.5 + (k % 5 == 0 ? 1e-6 : 0));
        f[0] = -0.0f;
        sc_buf b;
        sc_buf_init(&b);
        sc_error err = {0};
        SC_CHECK_MSG(sc_image_encode_exr(im, &b, &err) == SC_OK, "%s", err.message);
        SC_CHECK(strcmp(sc_image_sniff(b.data, b.len), "exr") == 0);
        sc_image_data *back = NULL;
        SC_CHECK_MSG(sc_image_decode("rt.exr", b.data, b.len, &back, &err) == SC_OK, "%s", err.message);
        SC_CHECK_MSG(back && same_pixels(im, back), "EXR round trip, %d channels", c);
        if (back) {
            SC_CHECK_STR(back->format, "exr");
            SC_CHECK_INT(back->colorspace, SC_COLOR_LINEAR);
        }
        sc_buf b2;
        sc_buf_init(&b2);
        SC_CHECK(sc_image_encode_exr(im, &b2, &err) == SC_OK);
        SC_CHECK(b.len == b2.len && memcmp(b.data, b2.data, b.len) == 0);
        sc_buf_free(&b2);
        sc_image_free(back);
        sc_buf_free(&b);
        sc_image_free(im);
    }
    /* 8-bit sRGB colour is linearised into the EXR */
    sc_image_data *im = sc_image_alloc(1, 1, 3, SC_PIXEL_U8);
    memset(im->pixels, 128, 3);
    sc_buf b;
    sc_buf_init(&b);
    sc_error err = {0};
    SC_CHECK(sc_image_encode_exr(im, &b, &err) == SC_OK);
    sc_image_data *back = NULL;
    SC_CHECK(sc_image_decode("lin.exr", b.data, b.len, &back, &err) == SC_OK);
    if (back) SC_CHECK_NEAR(sc_image_texel(back, 0, 0, 0), pow((128 / 255.0 + 0.055) / 1.055, 2.4), 1e-6);
    sc_image_free(back);
    sc_buf_free(&b);
    sc_image_free(im);
}

SC_TEST(encoders_write_no_time_stamps) {
    sc_image_data *im = gradient_u8(16, 8, 4);
    sc_image_data *f = sc_image_to_f32(im);
    sc_buf first[3], second[3];
    sc_error err = {0};
    for (int pass = 0; pass < 2; pass++) {
        sc_buf *b = pass ? second : first;
        for (int k = 0; k < 3; k++) sc_buf_init(&b[k]);
        SC_CHECK(sc_image_encode_png(im, 0, &b[0], &err) == SC_OK);
        SC_CHECK(sc_image_encode_jpeg(im, 90, &b[1], &err) == SC_OK);
        SC_CHECK(sc_image_encode_exr(f, &b[2], &err) == SC_OK);
        if (!pass) sc_test_system("sleep 1.1");
    }
    for (int k = 0; k < 3; k++) {
        SC_CHECK_MSG(first[k].len == second[k].len && memcmp(first[k].data, second[k].data, first[k].len) == 0,
                     "encoder %d wrote different bytes a second later", k);
        sc_buf_free(&first[k]), sc_buf_free(&second[k]);
    }
    sc_image_free(f);
    sc_image_free(im);
}

/* An image value's PNG is deflated once per process: the same pixels again
 * (another value with the same digest) copy the kept bytes, which are the
 * encoder's own; other pixels, another bit depth or a small image encode
 * anew. The hit counter is the library's, so the counts are differences. */
static bool same_bytes(const sc_buf *a, const sc_buf *b) {
    return a->len == b->len && memcmp(a->data, b->data, a->len) == 0;
}

SC_TEST(png_of_an_image_value_is_encoded_once) {
    sc_error err = {0};
    sc_image_data *im = gradient_u8(1024, 512, 3);   /* 1.5 MB of pixels */
    sc_image_data *twin = gradient_u8(1024, 512, 3);
    sc_image_data *other = gradient_u8(1024, 512, 3);
    ((uint8_t *)other->pixels)[12345] ^= 1;
    sc_image_data *small = gradient_u8(64, 64, 3);
    sc_buf direct;
    sc_buf_init(&direct);
    SC_CHECK(sc_image_encode_png(im, 0, &direct, &err) == SC_OK);
    sc_value *v = sc_value_new_image(im), *t = sc_value_new_image(twin), *o = sc_value_new_image(other),
             *s = sc_value_new_image(small);
    sc_buf b[6];
    for (int k = 0; k < 6; k++) sc_buf_init(&b[k]);
    int64_t h0 = sc_image_remembered_hits();
    SC_CHECK(sc_image_value_encode_png(v, 0, &b[0], &err) == SC_OK);   /* the first: deflated */
    int64_t h1 = sc_image_remembered_hits();
    SC_CHECK(sc_image_value_encode_png(v, 0, &b[1], &err) == SC_OK);   /* kept */
    SC_CHECK(sc_image_value_encode_png(t, 0, &b[2], &err) == SC_OK);   /* the same digest: kept */
    int64_t h2 = sc_image_remembered_hits();
    SC_CHECK(sc_image_value_encode_png(o, 0, &b[3], &err) == SC_OK);   /* one bit apart: deflated */
    SC_CHECK(sc_image_value_encode_png(v, 16, &b[4], &err) == SC_OK);  /* 16 bits: deflated */
    SC_CHECK(sc_image_value_encode_png(s, 0, &b[5], &err) == SC_OK);
    SC_CHECK(sc_image_value_encode_png(s, 0, &b[5], &err) == SC_OK);   /* small: never kept */
    int64_t h3 = sc_image_remembered_hits();
    SC_CHECK_MSG(h1 == h0 && h2 - h1 == 2 && h3 == h2, "hits %lld %lld %lld %lld", (long long)h0,
                 (long long)h1, (long long)h2, (long long)h3);
    SC_CHECK(same_bytes(&b[0], &direct) && same_bytes(&b[1], &direct) && same_bytes(&b[2], &direct));
    SC_CHECK(!same_bytes(&b[3], &direct) && !same_bytes(&b[4], &direct));
    sc_image_data *back = NULL;
    SC_CHECK(sc_image_decode("other.png", b[3].data, b[3].len, &back, &err) == SC_OK);
    SC_CHECK(back && memcmp(back->pixels, other->pixels, (size_t)1024 * 512 * 3) == 0);
    sc_image_free(back);
    for (int k = 0; k < 6; k++) sc_buf_free(&b[k]);
    sc_buf_free(&direct);
    sc_value_release(v), sc_value_release(t), sc_value_release(o), sc_value_release(s);
}

/* A mip chain of float images written as one tiled EXR reads back level
 * for level, bit for bit, and the bytes do not depend on the run. */
static int float_chain(int32_t w, int32_t h, sc_image_data **lv, int most) {
    int n = 0;
    for (; n < most; n++) {
        lv[n] = sc_image_alloc(w, h, 3, SC_PIXEL_F32);
        lv[n]->colorspace = SC_COLOR_DATA;
        float *p = lv[n]->pixels;
        for (int32_t t = 0; t < w * h * 3; t++) p[t] = (float)(t % 97) * 0.25f - 3.0f + (float)n;
        if (w == 1 && h == 1) break;
        w = w / 2 > 0 ? w / 2 : 1, h = h / 2 > 0 ? h / 2 : 1;
    }
    return n + 1;
}

SC_TEST(exr_mip_round_trip) {
    sc_image_data *lv[8] = {0};
    int n = float_chain(40, 24, lv, 8);   /* 40x24 ... 1x1: 6 levels */
    SC_CHECK_INT(n, 6);
    sc_buf a, b;
    sc_error err;
    sc_buf_init(&a), sc_buf_init(&b);
    SC_CHECK(sc_image_encode_exr_mip((const sc_image_data *const *)lv, n, &a, &err) == SC_OK);
    SC_CHECK(sc_image_encode_exr_mip((const sc_image_data *const *)lv, n, &b, &err) == SC_OK);
    SC_CHECK(a.len == b.len && memcmp(a.data, b.data, a.len) == 0);
    sc_image_data **dec = NULL;
    int nd = 0;
    SC_CHECK(sc_image_decode_levels("mip.exr", a.data, a.len, &dec, &nd, &err) == SC_OK);
    SC_CHECK_INT(nd, n);
    for (int k = 0; k < nd && k < n; k++) {
        SC_CHECK(dec[k]->width == lv[k]->width && dec[k]->height == lv[k]->height && dec[k]->channels == 3);
        SC_CHECK(memcmp(dec[k]->pixels, lv[k]->pixels, (size_t)lv[k]->width * lv[k]->height * 3 * 4) == 0);
    }
    for (int k = 0; k < nd; k++) sc_image_free(dec[k]);
    free(dec);
    /* the same bytes on several threads (520x300: 9 x 5 tiles at level 0);
     * OpenImageIO reads a chain from level 1 on too */
    sc_image_data *big[12] = {0};
    int nb = float_chain(520, 300, big, 12);
    sc_buf_reset(&a), sc_buf_reset(&b);
    SC_CHECK(sc_image_encode_exr_mip((const sc_image_data *const *)big, nb, &a, &err) == SC_OK);
    SC_CHECK(sc_image_encode_exr_mip_threads((const sc_image_data *const *)big, nb, 3, &b, &err) == SC_OK);
    SC_CHECK(a.len > 0 && a.len == b.len && memcmp(a.data, b.data, a.len) == 0);
    for (int k = 0; k < nb; k++) sc_image_free(big[k]);
    sc_buf_reset(&b);
    SC_CHECK(sc_image_encode_exr_mip((const sc_image_data *const *)lv + 1, n - 1, &b, &err) == SC_OK);
    SC_CHECK(sc_image_decode_levels("mip1.exr", b.data, b.len, &dec, &nd, &err) == SC_OK);
    SC_CHECK_INT(nd, n - 1);
    for (int k = 0; k < nd; k++) sc_image_free(dec[k]);
    free(dec);
    /* a wrong level size, or a chain that stops before 1 x 1, is refused
     * and writes nothing */
    sc_buf_reset(&b);
    const sc_image_data *bad[2] = {lv[0], lv[2]};
    SC_CHECK(sc_image_encode_exr_mip(bad, 2, &b, &err) == SC_EINPUT);
    SC_CHECK(sc_image_encode_exr_mip((const sc_image_data *const *)lv, 2, &b, &err) == SC_EINPUT);
    SC_CHECK(strstr(err.message, "1x1") != NULL);
    SC_CHECK_INT((int)b.len, 0);
    sc_buf_free(&a), sc_buf_free(&b);
    for (int k = 0; k < n; k++) sc_image_free(lv[k]);
}

/* A WebP (tests/data/images/grad8.webp, lossy, made from grad8.png) decodes
 * to the PNG's size and channels and, within the lossy coding, its values;
 * cut short it fails with a message. */
SC_TEST(webp_decodes) {
    sc_buf webp, png;
    sc_buf_init(&webp), sc_buf_init(&png);
    sc_error err = {0};
    char *wp = sc_test_source_path("tests/data/images/grad8.webp");
    char *pp = sc_test_source_path("tests/data/images/grad8.png");
    int rc = sc_read_file(wp, 1 << 16, &webp, &err);
    if (rc == SC_OK) rc = sc_read_file(pp, 1 << 16, &png, &err);
    SC_CHECK_MSG(rc == SC_OK, "%s", err.message);
    sc_image_data *a = NULL, *b = NULL;
    if (rc == SC_OK) {
        SC_CHECK_STR(sc_image_sniff(webp.data, webp.len), "webp");
        rc = sc_image_decode("grad8.webp", webp.data, webp.len, &a, &err);
        SC_CHECK_MSG(rc == SC_OK, "%s", err.message);
        SC_CHECK(sc_image_decode("grad8.png", png.data, png.len, &b, &err) == SC_OK);
    }
    if (a && b) {
        SC_CHECK_INT(a->width, 8);
        SC_CHECK_INT(a->height, 8);
        SC_CHECK_INT(a->channels, b->channels);
        SC_CHECK_INT(a->pixel, SC_PIXEL_U8);
        double sum = 0;
        int64_t n = (int64_t)a->width * a->height * a->channels;
        for (int64_t i = 0; i < n; i++) sum += fabs((double)((uint8_t *)a->pixels)[i] - ((uint8_t *)b->pixels)[i]);
        SC_CHECK_MSG(sum / n < 0.05 * 255, "mean difference %g of 255", sum / n);
        sc_image_data *cut = NULL;
        SC_CHECK(sc_image_decode("cut.webp", webp.data, webp.len / 2, &cut, &err) != SC_OK && cut == NULL);
        SC_CHECK(message_has(&err, "cut.webp"));
    }
    sc_image_free(a), sc_image_free(b);
    sc_buf_free(&webp), sc_buf_free(&png);
    free(wp), free(pp);
}

/* A Targa (no signature: its name says it) decodes to the very pixels of
 * the PNG it was made from, rows the same way up. */
SC_TEST(targa_decodes_by_its_name) {
    sc_buf tga, png;
    sc_buf_init(&tga), sc_buf_init(&png);
    sc_error err = {0};
    char *tp = sc_test_source_path("tests/data/images/grad8.tga");
    char *pp = sc_test_source_path("tests/data/images/grad8.png");
    int rc = sc_read_file(tp, 1 << 16, &tga, &err);
    if (rc == SC_OK) rc = sc_read_file(pp, 1 << 16, &png, &err);
    SC_CHECK_MSG(rc == SC_OK, "%s", err.message);
    sc_image_data *a = NULL, *b = NULL;
    if (rc == SC_OK) {
        SC_CHECK(sc_image_decode("grad8.data", tga.data, tga.len, &a, &err) != SC_OK && a == NULL);
        SC_CHECK(message_has(&err, "grad8.data: not an image seamcook reads"));
        rc = sc_image_decode("grad8.TGA", tga.data, tga.len, &a, &err);
        SC_CHECK_MSG(rc == SC_OK, "%s", err.message);
        SC_CHECK(sc_image_decode("grad8.png", png.data, png.len, &b, &err) == SC_OK);
    }
    if (a && b) {
        SC_CHECK(a->width == b->width && a->height == b->height && a->channels == b->channels && a->pixel == b->pixel);
        SC_CHECK(memcmp(a->pixels, b->pixels, (size_t)a->width * a->height * a->channels) == 0);
    }
    sc_image_free(a), sc_image_free(b);
    sc_buf_free(&tga), sc_buf_free(&png);
    free(tp), free(pp);
}

/* A DDS (tests/data/images/grad8.dds: 8 x 8 uncompressed BGRA, the picture's
 * top row first, texel (x, y) = (32 x, 32 y, 16 (x + y)) from the top)
 * decodes to those values, the picture's top row the last in memory as
 * every image here. */
SC_TEST(dds_decodes) {
    sc_buf dds;
    sc_buf_init(&dds);
    sc_error err = {0};
    char *path = sc_test_source_path("tests/data/images/grad8.dds");
    int rc = sc_read_file(path, 1 << 16, &dds, &err);
    sc_image_data *im = NULL;
    if (rc == SC_OK) rc = sc_image_decode("grad8.dds", dds.data, dds.len, &im, &err);
    SC_CHECK_MSG(rc == SC_OK, "%s", err.message);
    if (im) {
        SC_CHECK(im->width == 8 && im->height == 8 && im->channels == 4 && im->pixel == SC_PIXEL_U8);
        int wrong = 0;
        for (int y = 0; y < 8; y++)
            for (int x = 0; x < 8; x++) {
                const uint8_t *p = (const uint8_t *)im->pixels + 4 * ((size_t)(7 - y) * 8 + x);
                wrong += p[0] != 32 * x || p[1] != 32 * y || p[2] != 16 * (x + y) || p[3] != 255;
            }
        SC_CHECK_MSG(wrong == 0, "%d texels differ", wrong);
    }
    sc_image_free(im);
    sc_buf_free(&dds);
    free(path);
}

SC_TEST(bad_images_fail_cleanly) {
    sc_error err = {0};
    sc_image_data *im = NULL;
    /* garbage and empty */
    SC_CHECK(sc_image_decode("junk.png", "hello, world", 12, &im, &err) != SC_OK);
    SC_CHECK(message_has(&err, "junk.png: not an image"));
    SC_CHECK(sc_image_decode("empty.png", "", 0, &im, &err) != SC_OK);
    SC_CHECK(message_has(&err, "empty.png"));
    SC_CHECK(im == NULL);

    /* a valid PNG, then truncated and corrupted */
    sc_image_data *src = gradient_u8(64, 64, 3);
    sc_buf png;
    sc_buf_init(&png);
    SC_CHECK(sc_image_encode_png(src, 0, &png, &err) == SC_OK);
    SC_CHECK(sc_image_decode("cut.png", png.data, png.len / 2, &im, &err) != SC_OK);
    SC_CHECK(message_has(&err, "cut.png: corrupt or truncated png"));
    SC_CHECK(im == NULL);
    SC_CHECK(sc_image_decode("cut.png", png.data, 40, &im, &err) != SC_OK);
    SC_CHECK(message_has(&err, "cut.png"));
    for (size_t i = 60; i < png.len - 20; i += 7) png.data[i] ^= 0x5a;
    SC_CHECK(sc_image_decode("bits.png", png.data, png.len, &im, &err) != SC_OK);
    SC_CHECK(message_has(&err, "bits.png: corrupt or truncated png"));
    SC_CHECK(im == NULL);
    sc_buf_free(&png);

    /* a header claiming 100000 x 100000 (with a single row of data) */
    uint8_t row[3] = {1, 2, 3};
    make_png(&png, 100000, 100000, row, 0);
    SC_CHECK(sc_image_decode("huge.png", png.data, png.len, &im, &err) != SC_OK);
    SC_CHECK(message_has(&err, "huge.png: 100000x100000 pixels is beyond the limits"));
    SC_CHECK(err.code == SC_ENOMEM);
    SC_CHECK(im == NULL);
    sc_buf_free(&png);
    make_png(&png, 40000, 2, row, 0);   /* one side too long, few pixels */
    SC_CHECK(sc_image_decode("wide.png", png.data, png.len, &im, &err) != SC_OK);
    SC_CHECK(message_has(&err, "wide.png: 40000x2 pixels"));
    sc_buf_free(&png);

    /* truncated JPEG and EXR */
    sc_buf b;
    sc_buf_init(&b);
    SC_CHECK(sc_image_encode_jpeg(src, 90, &b, &err) == SC_OK);
    SC_CHECK(sc_image_decode("cut.jpg", b.data, b.len / 3, &im, &err) != SC_OK);
    SC_CHECK(message_has(&err, "cut.jpg"));
    sc_buf_reset(&b);
    sc_image_data *f = sc_image_to_f32(src);
    SC_CHECK(sc_image_encode_exr(f, &b, &err) == SC_OK);
    SC_CHECK(sc_image_decode("cut.exr", b.data, b.len / 2, &im, &err) != SC_OK);
    SC_CHECK(message_has(&err, "cut.exr"));
    SC_CHECK(im == NULL);
    sc_image_free(f);
    sc_buf_free(&b);
    sc_image_free(src);

    /* invalid images are refused by the encoders */
    sc_image_data bad = {0};
    sc_buf_init(&b);
    SC_CHECK(sc_image_encode_png(&bad, 0, &b, &err) != SC_OK);
    SC_CHECK(sc_image_encode_exr(&bad, &b, &err) != SC_OK);
    sc_buf_free(&b);
}

int main(void) { return sc_test_main(); }
