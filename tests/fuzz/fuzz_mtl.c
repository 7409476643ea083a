/* fuzz_mtl.c - libFuzzer entry point for the MTL reader and the path rule
 * of the files it names.
 *
 * The input is an MTL that a fixed OBJ names (mtllib) and uses (usemtl a, b).
 * Every texture map the reader accepts goes through sc_path_confine, as
 * load_atlas does; a path the rule accepts must stay inside the asset's
 * folder by its text. A failure must say why and leave nothing behind.
 * Build with -DSC_FUZZ=ON (clang), run e.g.
 *   ./build-fuzz/fuzz_mtl -max_total_time=30 /tmp/mtl-corpus tests/data/mtl
 */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "fuzz_paths.h"
#include "sc_obj.h"

typedef struct input {
    const uint8_t *data;
    size_t size;
} input;

static int read_input(void *ud, const char *path, sc_buf *out, sc_error *err) {
    const input *in = ud;
    (void)path;
    sc_buf_append(out, in->data, in->size);
    return out->failed ? sc_fail(err, SC_ENOMEM, "out of memory") : SC_OK;
}

static const char obj_text[] =
    "mtllib fuzz.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\n"
    "usemtl a\nf 1/1 2/2 3/3\nusemtl b\nf 1/1 3/3 2/2\n";

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
    input in = {data, size};
    sc_obj obj;
    sc_error err = {0};
    if (sc_obj_parse("fuzz.obj", obj_text, sizeof obj_text - 1, read_input, &in, &obj, &err) != SC_OK) {
        if (!err.message[0] || obj.mesh) abort();
        return 0;
    }
    for (int32_t i = 0; i < obj.nmaps; i++) fuzz_check_confined(obj.maps[i].path);
    sc_obj_free(&obj);
    return 0;
}
