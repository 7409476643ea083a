/* fuzz_obj.c - libFuzzer entry point for the OBJ/MTL reader.
 *
 * The input is the OBJ; an mtllib statement gets the same bytes back as its
 * MTL, so one input exercises both parsers. Nothing touches the file system.
 * A mesh the reader accepts must pass sc_mesh_check: anything else is a bug.
 * Build with -DSC_FUZZ=ON (clang), run e.g.
 *   mkdir -p /tmp/obj-corpus && ./build-fuzz/fuzz_obj -max_total_time=30 /tmp/obj-corpus tests/data/obj
 */
#include <stdint.h>
#include <stdlib.h>

#include "sc_obj.h"

typedef struct input {
    const uint8_t *data;
    size_t size;
} input;

static int read_input_as_mtl(void *ud, const char *path, sc_buf *out, sc_error *err) {
    const input *in = ud;
    (void)path;
    sc_buf_append(out, in->data, in->size);
    return out->failed ? sc_fail(err, SC_ENOMEM, "out of memory") : SC_OK;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
    input in = {data, size};
    sc_obj obj;
    sc_error err = {0};
    if (sc_obj_parse("fuzz.obj", data, size, read_input_as_mtl, &in, &obj, &err) == SC_OK) {
        if (sc_mesh_check(obj.mesh, &err) != SC_OK) abort();
        for (int32_t i = 0; i < obj.nmaps; i++)
            if (obj.maps[i].material < 0 || obj.maps[i].material >= obj.mesh->nmat) abort();
        sc_obj_free(&obj);
    } else if (!err.message[0] || obj.mesh) {
        abort();   /* a failure must say why, and leave nothing behind */
    }
    return 0;
}
