/* fuzz_uri.c - libFuzzer entry point for glTF uris: the input is a uri,
 * written (JSON-escaped) as a buffer's and an image's uri of a small glTF.
 * Whatever the glTF reader asks to read, and every image path it returns,
 * goes through sc_path_confine as load_atlas does; a path the rule accepts
 * must stay inside the asset's folder by its text. Nothing is read from the
 * file system: the read callback hands back 36 zero bytes.
 * Build with -DSC_FUZZ=ON (clang), run e.g.
 *   ./build-fuzz/fuzz_uri -max_total_time=30 /tmp/uri-corpus tests/data/uri
 */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fuzz_paths.h"
#include "sc_gltf.h"

static int read_zeros(void *ud, const char *path, sc_buf *out, sc_error *err) {
    (void)ud;
    fuzz_check_confined(path);
    static const uint8_t zeros[36];
    sc_buf_append(out, zeros, sizeof zeros);
    return out->failed ? sc_fail(err, SC_ENOMEM, "out of memory") : SC_OK;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
    if (size > 4096) return 0;
    sc_buf uri;
    sc_buf_init(&uri);
    for (size_t i = 0; i < size; i++) {   /* as a JSON string */
        if (data[i] == '"' || data[i] == '\\') sc_buf_printf(&uri, "\\%c", data[i]);
        else if (data[i] < 0x20) sc_buf_printf(&uri, "\\u%04x", data[i]);
        else sc_buf_append(&uri, &data[i], 1);
    }
    sc_buf_append(&uri, "", 1);
    if (uri.failed) {
        sc_buf_free(&uri);
        return 0;
    }
    char *json = sc_strprintf(
        "{\"asset\":{\"version\":\"2.0\"},\"buffers\":[{\"uri\":\"%s\",\"byteLength\":36}],"
        "\"bufferViews\":[{\"buffer\":0,\"byteLength\":36}],"
        "\"accessors\":[{\"bufferView\":0,\"componentType\":5126,\"count\":3,\"type\":\"VEC3\"},"
        "{\"bufferView\":0,\"componentType\":5126,\"count\":3,\"type\":\"VEC2\"}],"
        "\"images\":[{\"uri\":\"%s\"}],\"textures\":[{\"source\":0}],"
        "\"materials\":[{\"pbrMetallicRoughness\":{\"baseColorTexture\":{\"index\":0}}}],"
        "\"meshes\":[{\"primitives\":[{\"attributes\":{\"POSITION\":0,\"TEXCOORD_0\":1},\"material\":0}]}],"
        "\"nodes\":[{\"mesh\":0}],\"scenes\":[{\"nodes\":[0]}]}",
        (const char *)uri.data, (const char *)uri.data);
    sc_buf_free(&uri);
    if (!json) return 0;
    sc_gltf g;
    sc_error err = {0};
    if (sc_gltf_parse("fuzz.gltf", json, strlen(json), read_zeros, NULL, &g, &err) == SC_OK) {
        for (int32_t i = 0; i < g.nimages; i++)
            if (g.images[i].path) fuzz_check_confined(g.images[i].path);
        sc_gltf_free(&g);
    } else if (!err.message[0]) {
        abort();
    }
    free(json);
    return 0;
}
