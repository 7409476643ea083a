/* fuzz_gltf.c - libFuzzer entry point for the glTF / GLB reader.
 *
 * The input is the .gltf or .glb; external URIs resolve to a callback that
 * always fails, so nothing touches the file system (data: URIs and the GLB
 * binary chunk are read inline). A mesh the reader accepts must pass
 * sc_mesh_check, and every texture must point at an image it returned.
 * Build with -DSC_FUZZ=ON (clang), run e.g.
 *   mkdir -p /tmp/gltf-corpus && ./build-fuzz/fuzz_gltf -max_total_time=30 /tmp/gltf-corpus tests/data/gltf
 */
#include <stdint.h>
#include <stdlib.h>

#include "sc_gltf.h"
#include "sc_obj.h"

static int no_files(void *ud, const char *path, sc_buf *out, sc_error *err) {
    (void)ud, (void)out;
    return sc_fail(err, SC_EINPUT, "%s: external files are not available", path);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
    sc_gltf g;
    sc_error err = {0};
    if (sc_gltf_parse("fuzz.gltf", data, size, no_files, NULL, &g, &err) == SC_OK) {
        if (sc_mesh_check(g.mesh, &err) != SC_OK) abort();
        for (int32_t i = 0; i < g.ntextures; i++)
            if (g.textures[i].image < 0 || g.textures[i].image >= g.nimages ||
                g.textures[i].material < 0 || g.textures[i].material >= g.mesh->nmat)
                abort();
        sc_gltf_free(&g);
    } else if (!err.message[0] || g.mesh) {
        abort();
    }
    return 0;
}
