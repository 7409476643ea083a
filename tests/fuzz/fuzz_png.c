/* fuzz_png.c - libFuzzer entry point for the C PNG reader
 * (nodes/lib/sc_imageio_png.c), without OpenImageIO behind it.
 *
 * The reader either decodes an image whose size and samples it vouches for
 * (every sample is read here, so a short buffer shows under the sanitizer),
 * declines the input with no image, or fails with a message and no image.
 * Each input is tried as it is and with its chunks' CRCs made right, so
 * that mutations reach the header, the inflater and the filters instead of
 * stopping at a CRC. Build with -DSC_FUZZ=ON (clang), run e.g.
 *   ./build-fuzz/fuzz_png -max_total_time=30 /tmp/png-corpus tests/data/png
 */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "sc_imageio_codecs.h"

static uint32_t crc32_of(const uint8_t *p, size_t n) {
    uint32_t crc = 0xFFFFFFFFu;
    for (size_t i = 0; i < n; i++) {
        crc ^= p[i];
        for (int k = 0; k < 8; k++) crc = (crc >> 1) ^ (0xEDB88320u & (0u - (crc & 1)));
    }
    return ~crc;
}

static volatile unsigned sink;

static void try_decode(const uint8_t *data, size_t size) {
    sc_image_data *im = NULL;
    bool declined = false;
    sc_error err = {0};
    int rc = sc_imageio_png_decode("fuzz.png", data, size, &im, &declined, &err);
    if (rc != SC_OK) {
        if (!err.message[0] || im) abort();
        return;
    }
    if (declined) {
        if (im) abort();
        return;
    }
    if (!im || im->width < 1 || im->height < 1 || im->channels < 1 || im->channels > 4) abort();
    if (im->pixel != SC_PIXEL_U8 && im->pixel != SC_PIXEL_U16) abort();
    size_t n = (size_t)im->width * (size_t)im->height * (size_t)im->channels * (size_t)im->pixel;
    unsigned sum = 0;
    for (size_t i = 0; i < n; i++) sum += ((const uint8_t *)im->pixels)[i];
    sc_image_free(im);
    sink = sum;   /* every sample read */
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
    try_decode(data, size);
    uint8_t *fixed = malloc(size ? size : 1);
    if (!fixed) return 0;
    memcpy(fixed, data, size);
    for (size_t at = 8; size >= 12 && at <= size - 12;) {
        uint32_t len = (uint32_t)fixed[at] << 24 | (uint32_t)fixed[at + 1] << 16 | (uint32_t)fixed[at + 2] << 8 |
                       fixed[at + 3];
        if (len > size - at - 12) break;
        uint32_t crc = crc32_of(fixed + at + 4, 4 + (size_t)len);
        uint8_t *c = fixed + at + 8 + len;
        c[0] = (uint8_t)(crc >> 24), c[1] = (uint8_t)(crc >> 16), c[2] = (uint8_t)(crc >> 8), c[3] = (uint8_t)crc;
        at += 12 + (size_t)len;
    }
    try_decode(fixed, size);
    free(fixed);
    return 0;
}
