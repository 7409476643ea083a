/* sc_imageio_codecs.h - private: the table the image codec module exports.
 *
 * OpenImageIO brings in hundreds of shared libraries, and loading them
 * costs every process noticeable time before main() even starts
 * (docs/notes/imageio.md). So the codecs
 * (sc_imageio.cpp, the only C++ in seamcook) are built as a loadable module,
 * libseamcook_imageio.so, that sc_imageio.c opens the first time an image is
 * decoded or encoded: a run whose nodes are all cached never loads it.
 */
#ifndef SC_IMAGEIO_CODECS_H
#define SC_IMAGEIO_CODECS_H

#include <stdbool.h>
#include <string.h>

#include "sc_value.h"

#ifdef __cplusplus
extern "C" {
#endif

#define SC_IMAGEIO_ABI 4
#define SC_IMAGEIO_MODULE "libseamcook_imageio.so"
#define SC_IMAGEIO_ENTRY "sc_imageio_codecs_get"

typedef struct sc_imageio_codecs {
    int abi;   /* SC_IMAGEIO_ABI */
    int (*decode)(const char *name, const void *bytes, size_t size, sc_image_data **out, sc_error *err);
    int (*encode_jpeg)(const sc_image_data *im, int quality, sc_buf *out, sc_error *err);
    /* ABI 2: reading every level of a mip-mapped EXR (ABI 3: writing one is
     * sc_imageio_exr.c's, in C; ABI 4: so is writing a one-level EXR, and
     * PNG files are written by sc_imageio_png.c, in C) */
    int (*decode_levels)(const char *name, const void *bytes, size_t size, sc_image_data ***out, int *nout,
                         sc_error *err);
} sc_imageio_codecs;

/* PNG writing, in C (sc_imageio_png.c): sc_image_encode_png's work. */
int sc_imageio_png_encode(const sc_image_data *im, int bits, sc_buf *out, sc_error *err);
/* PNG reading, in C, of the forms sc_imageio_png.c takes: SC_OK with *out,
 * an error (out of memory), or SC_OK with *declined set and *out NULL for
 * any other PNG, which OpenImageIO decodes. */
int sc_imageio_png_decode(const char *name, const void *bytes, size_t size, sc_image_data **out, bool *declined,
                          sc_error *err);

/* The format the first bytes announce; shared by the module and the loader. */
static inline const char *sc_imageio_sniff(const void *bytes, size_t size) {
    const unsigned char *p = (const unsigned char *)bytes;
    if (!p) return NULL;
    if (size >= 8 && memcmp(p, "\x89PNG\r\n\x1a\n", 8) == 0) return "png";
    if (size >= 3 && p[0] == 0xFF && p[1] == 0xD8 && p[2] == 0xFF) return "jpg";
    if (size >= 4 && (memcmp(p, "II*\0", 4) == 0 || memcmp(p, "MM\0*", 4) == 0)) return "tif";
    if (size >= 4 && memcmp(p, "\x76\x2f\x31\x01", 4) == 0) return "exr";
    if (size >= 6 && (memcmp(p, "#?RADI", 6) == 0 || memcmp(p, "#?RGBE", 6) == 0)) return "hdr";
    if (size >= 2 && p[0] == 'B' && p[1] == 'M') return "bmp";
    if (size >= 12 && memcmp(p, "RIFF", 4) == 0 && memcmp(p + 8, "WEBP", 4) == 0) return "webp";
    if (size >= 4 && memcmp(p, "DDS ", 4) == 0) return "dds";
    return NULL;
}

#ifdef __cplusplus
}
#endif

#endif
