/* sc_imageio.h - image files <-> sc_image_data, in memory, over OpenImageIO.
 *
 * The only C++ in seamcook lives behind this header (sc_imageio.cpp): every
 * OpenImageIO call is wrapped so that no exception crosses into C, and every
 * failure becomes an sc_error with a message naming the image.
 *
 * Decoding (PNG, JPEG, TIFF, OpenEXR, Radiance HDR, BMP; told apart by their
 * first bytes, not by name):
 *   - 8-bit files give SC_PIXEL_U8, 16-bit SC_PIXEL_U16, anything else
 *     (half, float, 32-bit ints...) SC_PIXEL_F32;
 *   - colour space: 8/16-bit -> SC_COLOR_SRGB, float -> SC_COLOR_LINEAR (the
 *     caller re-tags data textures such as normal maps as SC_COLOR_DATA);
 *   - rows are flipped so that row 0 is the bottom of the picture (v = 0);
 *   - alpha is returned as stored (unassociated), never premultiplied;
 *   - format is "png", "jpg", "tif", "exr", "hdr" or "bmp";
 *   - 1 to 4 channels; sizes beyond SC_IMAGE_MAX_SIDE / SC_IMAGE_MAX_PIXELS
 *     are refused from the header, before any pixel memory is allocated;
 *     corrupt or truncated data is an error.
 *
 * Encoding (rows flipped back to top-down; output bytes are deterministic):
 *   - PNG, 8 or 16 bits per channel. bits = 0 picks the image's own depth
 *     (u8 -> 8, u16 and f32 -> 16). Converting to fewer bits rounds to
 *     nearest; f32 is clamped to [0, 1] and rounded to nearest. f32 images in
 *     SC_COLOR_LINEAR are encoded with the sRGB transfer curve (a PNG holds
 *     sRGB); SC_COLOR_SRGB and SC_COLOR_DATA values are written as they are.
 *   - JPEG, 8 bits, quality 1..100; 1 or 3 channels (alpha is dropped).
 *   - OpenEXR, float32, zip compression, channels Y / Y,A / R,G,B / R,G,B,A.
 *     u8/u16 are normalised to [0, 1]; SC_COLOR_SRGB values are linearised
 *     (an EXR holds linear colour); LINEAR and DATA are written as they are.
 */
#ifndef SC_IMAGEIO_H
#define SC_IMAGEIO_H

#ifdef __cplusplus
extern "C" {
#endif

#include "sc_value.h"

/* Bump whenever results of this library can change for the same inputs:
 * every node listing sc_kernel_imageio (or a kernel built on it) is re-keyed. */
#define SC_IMAGEIO_VERSION 3
extern const sc_kernel sc_kernel_imageio;

/* Decode image file bytes. `name` is used in messages. On success *out is a
 * new image (free with sc_image_free or wrap with sc_value_new_image). */
int sc_image_decode(const char *name, const void *bytes, size_t size, sc_image_data **out,
                    sc_error *err);

/* Encode into out (appended). */
int sc_image_encode_png(const sc_image_data *im, int bits, sc_buf *out, sc_error *err);
int sc_image_encode_jpeg(const sc_image_data *im, int quality, sc_buf *out, sc_error *err);
int sc_image_encode_exr(const sc_image_data *im, sc_buf *out, sc_error *err);

/* sc_image_encode_png of an image value, remembered for the process: the
 * PNG of the same image (its digest) at the same bits is deflated once and
 * copied after that, as nodes that run one after another write one texture
 * twice (save's top level and mipmap's level 0 of a chain). Images under
 * SC_IMAGE_REMEMBER_MIN bytes of pixels are encoded every time; the bytes
 * kept stay under SC_IMAGE_REMEMBER_MAX, the oldest dropped first. */
#define SC_IMAGE_REMEMBER_MIN ((size_t)1 << 20)
#define SC_IMAGE_REMEMBER_MAX ((size_t)64 << 20)
int sc_image_value_encode_png(const sc_value *image, int bits, sc_buf *out, sc_error *err);

/* How many sc_image_value_encode_png calls so far copied a kept encoding. */
int64_t sc_image_remembered_hits(void);

/* A tiled (64 x 64), mip-mapped OpenEXR holding every level in one file,
 * float32, ZIP-compressed (written through the OpenEXR C API, deflated by
 * libdeflate: sc_imageio_exr.c), channels named as in sc_image_encode_exr.
 * Level k + 1 must be max(1, floor(level k / 2)) on each side (OpenEXR's
 * round-down rule), down to 1 x 1. _threads packs and deflates the tiles on
 * up to `threads` threads (the same bytes for any count). */
int sc_image_encode_exr_mip(const sc_image_data *const *levels, int nlevels, sc_buf *out, sc_error *err);
int sc_image_encode_exr_mip_threads(const sc_image_data *const *levels, int nlevels, int threads, sc_buf *out,
                                    sc_error *err);

/* Every mip level of an OpenEXR file (one level for a flat file), as f32
 * images, rows bottom-up. *levels is a malloc'd array of *nlevels images:
 * free each with sc_image_free, then the array with free(). */
int sc_image_decode_levels(const char *name, const void *bytes, size_t size, sc_image_data ***levels,
                           int *nlevels, sc_error *err);

/* The format the first bytes of a file announce ("png", "jpg", "tif", "exr",
 * "hdr", "bmp"), or NULL when none. */
const char *sc_image_sniff(const void *bytes, size_t size);

#ifdef __cplusplus
}
#endif

#endif
