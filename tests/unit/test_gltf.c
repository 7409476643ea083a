/* test_gltf.c - the glTF reader (nodes/lib/sc_gltf.h) and load_atlas on glTF.
 *
 * tests/data/gltf/quad.gltf is a hand-made asset: two triangles of a unit
 * square that glTF splits at a uv seam (6 vertices, 4 distinct positions),
 * under a rotated, scaled, translated node, plus a LINES primitive (skipped)
 * and an occlusion texture on TEXCOORD_1 (skipped). The .glb variants and all
 * the broken files are made from it here, with cJSON.
 */
#include <math.h>
#include <stdarg.h>
#include <stdlib.h>

#include <cjson/cJSON.h>

#include "sc_exec.h"
#include "sc_gltf.h"
#include "sc_imageio.h"
#include "sc_nodes.h"
#include "sc_test.h"

/* ---------------------------------------------------------------- helpers */

/* Whether one of the node's warnings contains text. */
static bool warning_has(const sc_ctx *ctx, const char *text) {
    for (int i = 0; ctx && i < sc_ctx_nwarnings(ctx); i++)
        if (strstr(sc_ctx_warning(ctx, i), text)) return true;
    fprintf(stderr, "  no warning contains: %s\n", text);
    return false;
}

static bool message_has(const sc_error *err, const char *text) {
    bool ok = strstr(err->message, text) != NULL;
    if (!ok) fprintf(stderr, "  message was: %s\n  expected it to contain: %s\n", err->message, text);
    return ok;
}

static cJSON *load_quad(void) {
    char *path = sc_test_source_path("tests/data/gltf/quad.gltf");
    sc_buf b;
    sc_buf_init(&b);
    sc_error err = {0};
    cJSON *j = NULL;
    if (sc_read_file(path, 1 << 20, &b, &err) == SC_OK) j = cJSON_ParseWithLength((const char *)b.data, b.len);
    SC_CHECK_MSG(j != NULL, "cannot read quad.gltf: %s", err.message);
    sc_buf_free(&b);
    free(path);
    return j;
}

static cJSON *at(cJSON *j, const char *key, int index) {
    return cJSON_GetArrayItem(cJSON_GetObjectItemCaseSensitive(j, key), index);
}

static void set_number(cJSON *obj, const char *key, double v) {
    cJSON_DeleteItemFromObjectCaseSensitive(obj, key);
    cJSON_AddNumberToObject(obj, key, v);
}

static void set_string(cJSON *obj, const char *key, const char *v) {
    cJSON_DeleteItemFromObjectCaseSensitive(obj, key);
    cJSON_AddStringToObject(obj, key, v);
}

static int base64_value(char c) {
    const char *digits = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    const char *p = strchr(digits, c);
    return c && p ? (int)(p - digits) : -1;
}

/* The bytes of buffer 0's data: URI. */
static void quad_bin(cJSON *j, sc_buf *out) {
    const char *uri = cJSON_GetObjectItemCaseSensitive(at(j, "buffers", 0), "uri")->valuestring;
    const char *s = strchr(uri, ',') + 1;
    uint32_t acc = 0;
    int bits = 0;
    sc_buf_init(out);
    for (; *s && *s != '='; s++) {
        acc = acc << 6 | (uint32_t)base64_value(*s);
        bits += 6;
        if (bits >= 8) bits -= 8, sc_buf_u8(out, (uint8_t)(acc >> bits));
    }
}

/* A .glb of the JSON and binary chunk (the JSON's buffer 0 loses its uri). */
static void make_glb(cJSON *j, const sc_buf *bin, sc_buf *out) {
    cJSON_DeleteItemFromObjectCaseSensitive(at(j, "buffers", 0), "uri");
    char *text = cJSON_PrintUnformatted(j);
    size_t jl = strlen(text), jp = (jl + 3) & ~(size_t)3, bp = (bin->len + 3) & ~(size_t)3;
    sc_buf_init(out);
    sc_buf_append(out, "glTF", 4);
    sc_buf_u32(out, 2);
    sc_buf_u32(out, (uint32_t)(12 + 8 + jp + 8 + bp));
    sc_buf_u32(out, (uint32_t)jp);
    sc_buf_u32(out, 0x4E4F534A);
    sc_buf_append(out, text, jl);
    for (size_t k = jl; k < jp; k++) sc_buf_u8(out, ' ');
    sc_buf_u32(out, (uint32_t)bp);
    sc_buf_u32(out, 0x004E4942);
    sc_buf_append(out, bin->data, bin->len);
    for (size_t k = bin->len; k < bp; k++) sc_buf_u8(out, 0);
    free(text);
}

static int failing_read(void *ud, const char *path, sc_buf *out, sc_error *err) {
    return sc_fail(err, SC_EINPUT, "%s: not here", path);
}

static int parse_json(const char *name, cJSON *j, sc_gltf *out, sc_error *err) {
    char *text = cJSON_Print(j);
    int rc = sc_gltf_parse(name, text, strlen(text), failing_read, NULL, out, err);
    free(text);
    return rc;
}

static void write_bytes(const char *dir, const char *name, const void *p, size_t n) {
    char *path = sc_path_join(dir, name);
    sc_error err = {0};
    SC_CHECK_MSG(sc_write_file_atomic(path, p, n, &err) == SC_OK, "%s", err.message);
    free(path);
}

static void png_bytes(int w, int h, uint8_t value, sc_buf *out) {
    sc_image_data *im = sc_image_alloc(w, h, 3, SC_PIXEL_U8);
    memset(im->pixels, value, (size_t)w * h * 3);
    sc_error err = {0};
    sc_buf_init(out);
    SC_CHECK(sc_image_encode_png(im, 8, out, &err) == SC_OK);
    sc_image_free(im);
}

static sc_ctx *run_load(const char *path, sc_error *err, ...) {
    sc_ctx *ctx = sc_ctx_new(&sc_node_load_atlas, NULL, NULL);
    sc_ctx_set_param(ctx, "path", path, err);
    va_list ap;
    va_start(ap, err);
    for (const char *k; (k = va_arg(ap, const char *));) {
        const char *v = va_arg(ap, const char *);
        if (strcmp(k, "threads") == 0) sc_ctx_set_threads(ctx, atoi(v));
        else SC_CHECK(sc_ctx_set_param(ctx, k, v, err) == SC_OK);
    }
    va_end(ap);
    if (sc_ctx_run(ctx, err) != SC_OK) {
        sc_ctx_free(ctx);
        return NULL;
    }
    return ctx;
}

/* ---------------------------------------------------------------- parsing */

static void check_quad(const sc_gltf *g) {
    const sc_mesh *m = g->mesh;
    SC_CHECK_INT(m->nf, 2);
    SC_CHECK_INT(m->nv, 4);      /* welded: the seam's two ends are shared */
    SC_CHECK_INT(m->nu, 6);      /* distinct (position, uv) pairs */
    SC_CHECK_INT(m->nn, 6);
    SC_CHECK_INT(g->raw_vertices, 6);
    SC_CHECK_INT(g->primitives_skipped, 1);
    SC_CHECK_INT(g->textures_skipped, 1);
    SC_CHECK_INT(m->nmat, 1);
    SC_CHECK_STR(m->materials[0], "paint");
    /* p' = 2 * Rx(90) p + (1, 2, 3), Rx(90): (x, y, z) -> (x, -z, y) */
    const double expect[4][3] = {{1, 2, 3}, {3, 2, 3}, {1, 2, 5}, {3, 2, 5}};
    for (int v = 0; v < 4; v++)
        for (int k = 0; k < 3; k++) SC_CHECK_NEAR(m->V[3 * v + k], expect[v][k], 1e-6);
    /* normals (0, 0, 1) -> (0, -1, 0), unit length */
    SC_CHECK_NEAR(m->N[0], 0, 1e-6);
    SC_CHECK_NEAR(m->N[1], -1, 1e-6);
    SC_CHECK_NEAR(m->N[2], 0, 1e-6);
    /* glTF uv (0, 1) at the first vertex -> (0, 0) */
    SC_CHECK(m->U[0] == 0 && m->U[1] == 0);
    SC_CHECK(m->U[2] == 1 && m->U[3] == 0);
    SC_CHECK(m->U[2 * 3] == 0.5 && m->U[2 * 3 + 1] == 0);
    /* the second triangle reuses positions 1 and 2 */
    SC_CHECK_INT(m->FV[3], 1);
    SC_CHECK_INT(m->FV[5], 2);
    SC_CHECK_INT(m->FU[3], 3);
    SC_CHECK(sc_mesh_check(m, NULL) == SC_OK);
    SC_CHECK_INT(g->ntextures, 2);
    if (g->ntextures == 2) {
        SC_CHECK_STR(g->textures[0].slot, "color");
        SC_CHECK_INT(g->textures[0].wrap_u, SC_WRAP_CLAMP);
        SC_CHECK_INT(g->textures[0].wrap_v, SC_WRAP_MIRROR);
        SC_CHECK_STR(g->textures[1].slot, "normal");
        SC_CHECK_INT(g->textures[1].wrap_u, SC_WRAP_REPEAT);
    }
}

SC_TEST(parses_gltf_with_transforms_and_seams) {
    cJSON *j = load_quad();
    if (!j) return;
    sc_gltf g;
    sc_error err = {0};
    int rc = parse_json("quad.gltf", j, &g, &err);
    SC_CHECK_MSG(rc == SC_OK, "%s", err.message);
    if (rc == SC_OK) {
        check_quad(&g);
        SC_CHECK_INT(g.nimages, 2);
        if (g.nimages == 2) {
            SC_CHECK_STR(g.images[0].path, "color.png");
            SC_CHECK_STR(g.images[1].path, "normal map.png");   /* %20 decoded */
            SC_CHECK(g.images[0].data == NULL);
        }
    }
    sc_gltf_free(&g);
    cJSON_Delete(j);
}

/* The quad with a TANGENT of handedness w on every vertex, as a .glb. */
static int parse_with_tangent(cJSON *j, float w, sc_gltf *g, sc_error *err) {
    sc_buf bin, glb;
    quad_bin(j, &bin);
    size_t offset = bin.len;
    for (int i = 0; i < 6; i++) {
        float t[4] = {1, 0, 0, w};
        sc_buf_append(&bin, t, sizeof t);
    }
    set_number(at(j, "buffers", 0), "byteLength", (double)bin.len);
    cJSON *view = cJSON_CreateObject();
    cJSON_AddNumberToObject(view, "buffer", 0), cJSON_AddNumberToObject(view, "byteOffset", (double)offset);
    cJSON_AddNumberToObject(view, "byteLength", 96);
    cJSON_AddItemToArray(cJSON_GetObjectItemCaseSensitive(j, "bufferViews"), view);
    cJSON *acc = cJSON_CreateObject();
    cJSON_AddNumberToObject(acc, "bufferView", 2), cJSON_AddNumberToObject(acc, "componentType", 5126);
    cJSON_AddNumberToObject(acc, "count", 6), cJSON_AddStringToObject(acc, "type", "VEC4");
    cJSON_AddItemToArray(cJSON_GetObjectItemCaseSensitive(j, "accessors"), acc);
    cJSON_AddNumberToObject(cJSON_GetObjectItemCaseSensitive(at(at(j, "meshes", 0), "primitives", 0), "attributes"),
                            "TANGENT", 4);
    make_glb(j, &bin, &glb);
    int rc = sc_gltf_parse("quad.glb", glb.data, glb.len, failing_read, NULL, g, err);
    sc_buf_free(&bin), sc_buf_free(&glb);
    return rc;
}

/* TANGENT's handedness: of the two, exactly one has bitangents against v
 * and marks the normal map green-flipped; without TANGENT none is. */
SC_TEST(tangent_handedness_marks_green_down_normal_maps) {
    int flagged = 0;
    for (int k = 0; k < 2; k++) {
        cJSON *j = load_quad();
        if (!j) return;
        sc_gltf g;
        sc_error err = {0};
        int rc = parse_with_tangent(j, k ? -1.0f : 1.0f, &g, &err);
        SC_CHECK_MSG(rc == SC_OK, "%s", err.message);
        if (rc == SC_OK && g.ntextures >= 2) {
            SC_CHECK_STR(g.textures[1].slot, "normal");
            SC_CHECK(!g.textures[0].green_flipped);
            flagged += g.textures[1].green_flipped;
        }
        if (rc == SC_OK) sc_gltf_free(&g);
        cJSON_Delete(j);
    }
    SC_CHECK_INT(flagged, 1);
    cJSON *j = load_quad();
    sc_gltf g;
    sc_error err = {0};
    if (j && parse_json("quad.gltf", j, &g, &err) == SC_OK) {
        SC_CHECK(g.ntextures >= 2 && !g.textures[1].green_flipped);
        sc_gltf_free(&g);
    }
    cJSON_Delete(j);
}

/* KHR_texture_transform, written out by hand: u' = sx u cos r + sy v sin r + ox,
 * v' = sy v cos r - sx u sin r + oy in glTF's uv (v down), the atlas's v = 1 - v' */
static void add_transform(cJSON *info, double ox, double oy, double r, double sx, double sy, int texcoord) {
    cJSON *x = cJSON_AddObjectToObject(cJSON_AddObjectToObject(info, "extensions"), "KHR_texture_transform");
    double offset[2] = {ox, oy}, scale[2] = {sx, sy};
    cJSON_AddItemToObject(x, "offset", cJSON_CreateDoubleArray(offset, 2));
    cJSON_AddNumberToObject(x, "rotation", r);
    cJSON_AddItemToObject(x, "scale", cJSON_CreateDoubleArray(scale, 2));
    if (texcoord >= 0) cJSON_AddNumberToObject(x, "texCoord", texcoord);
}

SC_TEST(texture_transform_is_baked_into_the_uv) {
    cJSON *plain = load_quad(), *moved = load_quad();
    if (!plain || !moved) return;
    cJSON *m = at(moved, "materials", 0);
    const double ox = 0.25, oy = -0.5, r = 0.3, sx = 2, sy = 0.5;
    add_transform(cJSON_GetObjectItemCaseSensitive(cJSON_GetObjectItemCaseSensitive(m, "pbrMetallicRoughness"),
                                                   "baseColorTexture"), ox, oy, r, sx, sy, -1);
    add_transform(cJSON_GetObjectItemCaseSensitive(m, "normalTexture"), ox, oy, r, sx, sy, -1);
    /* the occlusion texture samples TEXCOORD_1: its own transform does not enter */
    add_transform(cJSON_GetObjectItemCaseSensitive(m, "occlusionTexture"), 0, 0, 1.0, 3, 3, -1);
    sc_gltf a, b;
    sc_error err = {0};
    SC_CHECK(parse_json("quad.gltf", plain, &a, &err) == SC_OK);
    SC_CHECK_MSG(parse_json("quad.gltf", moved, &b, &err) == SC_OK, "%s", err.message);
    if (a.mesh && b.mesh) {
        SC_CHECK_INT(b.mesh->nu, a.mesh->nu);
        SC_CHECK_INT(b.textures_skipped, 1);
        double worst = 0;
        for (int32_t k = 0; k < a.mesh->nu && k < b.mesh->nu; k++) {
            double u = a.mesh->U[2 * k], v = 1 - a.mesh->U[2 * k + 1];
            double tu = sx * u * cos(r) + sy * v * sin(r) + ox, tv = sy * v * cos(r) - sx * u * sin(r) + oy;
            worst = fmax(worst, fmax(fabs(b.mesh->U[2 * k] - tu), fabs(b.mesh->U[2 * k + 1] - (1 - tv))));
        }
        SC_CHECK_MSG(worst < 1e-12, "uv off the hand-applied transform by %g", worst);
        for (int32_t f = 0; f < 3 * a.mesh->nf; f++) SC_CHECK_INT(b.mesh->FU[f], a.mesh->FU[f]);
    }
    sc_gltf_free(&a), sc_gltf_free(&b);
    /* texCoord 1 in the extension takes the normal texture off TEXCOORD_0: it is skipped, and the
     * colour's transform alone moves the uv */
    cJSON *other = load_quad();
    m = at(other, "materials", 0);
    add_transform(cJSON_GetObjectItemCaseSensitive(cJSON_GetObjectItemCaseSensitive(m, "pbrMetallicRoughness"),
                                                   "baseColorTexture"), 0.5, 0, 0, 1, 1, -1);
    add_transform(cJSON_GetObjectItemCaseSensitive(m, "normalTexture"), 0, 0, 0.7, 1, 1, 1);
    SC_CHECK(parse_json("quad.gltf", plain, &a, &err) == SC_OK);
    SC_CHECK_MSG(parse_json("quad.gltf", other, &b, &err) == SC_OK, "%s", err.message);
    if (a.mesh && b.mesh) {
        SC_CHECK_INT(b.textures_skipped, 2);
        SC_CHECK_INT(b.mesh->nu, a.mesh->nu);
        for (int32_t k = 0; k < a.mesh->nu && k < b.mesh->nu; k++) {
            SC_CHECK(b.mesh->U[2 * k] == a.mesh->U[2 * k] + 0.5);
            SC_CHECK(b.mesh->U[2 * k + 1] == a.mesh->U[2 * k + 1]);
        }
    }
    sc_gltf_free(&a), sc_gltf_free(&b);
    cJSON_Delete(plain), cJSON_Delete(moved), cJSON_Delete(other);
}

SC_TEST(parses_glb_with_embedded_image) {
    cJSON *j = load_quad();
    if (!j) return;
    sc_buf bin, png, glb;
    quad_bin(j, &bin);
    png_bytes(4, 4, 77, &png);
    /* image 0 moves into the binary chunk */
    size_t offset = bin.len;
    sc_buf_append(&bin, png.data, png.len);
    set_number(at(j, "buffers", 0), "byteLength", (double)bin.len);
    cJSON *view = cJSON_CreateObject();
    cJSON_AddNumberToObject(view, "buffer", 0);
    cJSON_AddNumberToObject(view, "byteOffset", (double)offset);
    cJSON_AddNumberToObject(view, "byteLength", (double)png.len);
    cJSON_AddItemToArray(cJSON_GetObjectItemCaseSensitive(j, "bufferViews"), view);
    cJSON *image = at(j, "images", 0);
    cJSON_DeleteItemFromObjectCaseSensitive(image, "uri");
    cJSON_AddNumberToObject(image, "bufferView", 2);
    cJSON_AddStringToObject(image, "mimeType", "image/png");
    make_glb(j, &bin, &glb);
    sc_gltf g;
    sc_error err = {0};
    int rc = sc_gltf_parse("quad.glb", glb.data, glb.len, failing_read, NULL, &g, &err);
    SC_CHECK_MSG(rc == SC_OK, "%s", err.message);
    if (rc == SC_OK) {
        check_quad(&g);
        SC_CHECK(g.images[0].data && g.images[0].size == png.len &&
                 memcmp(g.images[0].data, png.data, png.len) == 0);
    }
    sc_gltf_free(&g);
    /* through the node: the embedded image and an external one */
    char *dir = sc_test_tempdir("glb");
    write_bytes(dir, "quad.glb", glb.data, glb.len);
    sc_buf normal;
    png_bytes(2, 2, 128, &normal);
    write_bytes(dir, "normal map.png", normal.data, normal.len);
    char *path = sc_path_join(dir, "quad.glb");
    sc_ctx *ctx = run_load(path, &err, NULL);
    SC_CHECK_MSG(ctx != NULL, "%s", err.message);
    if (ctx) {
        const sc_atlas *a = sc_ctx_output(ctx, 0)->as.atlas;
        SC_CHECK_INT(a->ntex, 2);
        SC_CHECK_STR(a->textures[0].source, "");
        SC_CHECK_INT(a->textures[0].image->as.image->width, 4);
        SC_CHECK_STR(a->textures[1].source, "normal map.png");
        SC_CHECK_INT(sc_ctx_ndeps(ctx), 2);
        sc_ctx_free(ctx);
    }
    sc_test_system("rm -rf '%s'", dir);
    free(path), free(dir);
    sc_buf_free(&normal), sc_buf_free(&bin), sc_buf_free(&png), sc_buf_free(&glb);
    cJSON_Delete(j);
}

/* ---------------------------------------------------------------- bad files */

typedef void (*mutation)(cJSON *j, sc_buf *bin);

static void view_past_end(cJSON *j, sc_buf *bin) { set_number(at(j, "bufferViews", 0), "byteLength", 400); }
static void count_too_big(cJSON *j, sc_buf *bin) { set_number(at(j, "accessors", 0), "count", 100); }
static void index_out_of_range(cJSON *j, sc_buf *bin) { bin->data[192] = 9; }
static void nan_position(cJSON *j, sc_buf *bin) { memcpy(bin->data + 12, "\x00\x00\xc0\x7f", 4); }
static void inf_uv(cJSON *j, sc_buf *bin) { memcpy(bin->data + 148, "\x00\x00\x80\x7f", 4); }
static void sparse(cJSON *j, sc_buf *bin) { cJSON_AddObjectToObject(at(j, "accessors", 1), "sparse"); }
static void no_texcoord(cJSON *j, sc_buf *bin) {
    cJSON_DeleteItemFromObjectCaseSensitive(
        cJSON_GetObjectItemCaseSensitive(at(at(j, "meshes", 0), "primitives", 0), "attributes"), "TEXCOORD_0");
}
static void cycle(cJSON *j, sc_buf *bin) {
    cJSON *children = cJSON_AddArrayToObject(at(j, "nodes", 1), "children");
    cJSON_AddItemToArray(children, cJSON_CreateNumber(0));
}
static void old_version(cJSON *j, sc_buf *bin) { set_string(cJSON_GetObjectItemCaseSensitive(j, "asset"), "version", "1.0"); }
static void bad_reference(cJSON *j, sc_buf *bin) { set_number(at(at(j, "meshes", 0), "primitives", 0), "indices", 17); }
static void integer_positions(cJSON *j, sc_buf *bin) { set_number(at(j, "accessors", 0), "componentType", 5123); }
static void vec2_positions(cJSON *j, sc_buf *bin) { set_string(at(j, "accessors", 0), "type", "VEC2"); }
static void odd_index_count(cJSON *j, sc_buf *bin) { set_number(at(j, "accessors", 3), "count", 5); }
static void tiny_stride(cJSON *j, sc_buf *bin) { set_number(at(j, "bufferViews", 0), "byteStride", 4); }
static void negative_offset(cJSON *j, sc_buf *bin) { set_number(at(j, "bufferViews", 0), "byteOffset", -4); }
static void fractional_count(cJSON *j, sc_buf *bin) { set_number(at(j, "accessors", 2), "count", 2.5); }
static void short_bin(cJSON *j, sc_buf *bin) { bin->len = 100; }
static void draco(cJSON *j, sc_buf *bin) {
    cJSON *list = cJSON_AddArrayToObject(j, "extensionsRequired");
    cJSON_AddItemToArray(list, cJSON_CreateString("KHR_draco_mesh_compression"));
}
static void no_triangles(cJSON *j, sc_buf *bin) { set_number(at(at(j, "meshes", 0), "primitives", 0), "mode", 0); }
static void bad_wrap(cJSON *j, sc_buf *bin) { set_number(at(j, "samplers", 0), "wrapS", 1234); }
/* a transform on the normal texture alone: color and normal sample TEXCOORD_0 differently */
static void texture_transform(cJSON *j, sc_buf *bin) {
    cJSON *info = cJSON_GetObjectItemCaseSensitive(at(j, "materials", 0), "normalTexture");
    cJSON *x = cJSON_AddObjectToObject(cJSON_AddObjectToObject(info, "extensions"), "KHR_texture_transform");
    cJSON_AddNumberToObject(x, "rotation", 0.5);
}
static void bad_transform_scale(cJSON *j, sc_buf *bin) {
    cJSON *info = cJSON_GetObjectItemCaseSensitive(at(j, "materials", 0), "normalTexture");
    cJSON *x = cJSON_AddObjectToObject(cJSON_AddObjectToObject(info, "extensions"), "KHR_texture_transform");
    cJSON_AddStringToObject(x, "scale", "big");
}
static void huge_scale(cJSON *j, sc_buf *bin) {
    cJSON_ReplaceItemInArray(cJSON_GetObjectItemCaseSensitive(at(j, "nodes", 0), "scale"), 0, cJSON_CreateNumber(1e308));
    cJSON_ReplaceItemInArray(cJSON_GetObjectItemCaseSensitive(at(j, "nodes", 0), "translation"), 0,
                             cJSON_CreateNumber(1e308));
}
static void no_view(cJSON *j, sc_buf *bin) { cJSON_DeleteItemFromObjectCaseSensitive(at(j, "accessors", 2), "bufferView"); }

SC_TEST(bad_glb_inputs_name_file_and_element) {
    static const struct {
        mutation change;
        const char *expect;
    } cases[] = {
        {view_past_end, "bad.glb: accessor 0: bufferView 0: bytes 0 to 400 are past the end of buffer 0 (204 bytes)"},
        {count_too_big, "bad.glb: accessor 0: count 100 with stride 12 from offset 0 needs 1200 bytes, bufferView 0 has 192"},
        {index_out_of_range, "bad.glb: accessor 3: index 9 at position 0 is out of range (the primitive has 6 vertices)"},
        {nan_position, "bad.glb: accessor 0: POSITION 1 is not finite"},
        {inf_uv, "bad.glb: accessor 2: TEXCOORD_0 0 is not finite"},
        {sparse, "bad.glb: accessor 1: sparse accessors are not supported"},
        {cycle, "bad.glb: node 0: the node hierarchy has a cycle"},
        {old_version, "bad.glb: asset.version is 1.0, only glTF 2.0 is supported"},
        {bad_reference, "bad.glb: mesh 0 primitive 0: 'indices' refers to accessor 17, the file has 4"},
        {integer_positions, "bad.glb: accessor 0: POSITION must be float"},
        {vec2_positions, "bad.glb: accessor 0: POSITION must have 3 components, has type VEC2"},
        {odd_index_count, "bad.glb: mesh 0 primitive 0: 5 indices is not a multiple of 3"},
        {tiny_stride, "bad.glb: accessor 0: bufferView 0 has byteStride 4, smaller than an element (12 bytes)"},
        {negative_offset, "bad.glb: accessor 0: bufferView 0: 'byteOffset' must be an integer in [0, "},
        {fractional_count, "bad.glb: accessor 2: 'count' must be an integer in [1, 67108864]"},
        {short_bin, "bad.glb: buffer 0: byteLength is 204 but only 100 bytes are there"},
        {draco, "bad.glb: requires extension KHR_draco_mesh_compression"},
        {no_triangles, "bad.glb: the scene has no triangles"},
        {bad_wrap, "bad.glb: sampler 0: wrapS 1234 is not a glTF wrap mode"},
        {texture_transform, "bad.glb: material 0: the color and normal textures transform TEXCOORD_0 differently"},
        {bad_transform_scale, "bad.glb: material 0: the normal texture's KHR_texture_transform: 'scale' must be an array of 2 numbers"},
        {huge_scale, "bad.glb: mesh 0 primitive 0: POSITION 1 is not finite after the node transform"},
        {no_view, "bad.glb: accessor 2: has no bufferView (all-zero accessors are not supported)"},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        cJSON *j = load_quad();
        if (!j) return;
        sc_buf bin, glb;
        quad_bin(j, &bin);
        cases[i].change(j, &bin);
        make_glb(j, &bin, &glb);
        sc_gltf g;
        sc_error err = {0};
        int rc = sc_gltf_parse("bad.glb", glb.data, glb.len, failing_read, NULL, &g, &err);
        SC_CHECK_MSG(rc != SC_OK, "case %zu parsed", i);
        SC_CHECK_MSG(message_has(&err, cases[i].expect), "case %zu", i);
        SC_CHECK(g.mesh == NULL && g.textures == NULL);
        /* every prefix of the file fails cleanly too (truncation) */
        if (i == 0) {
            for (size_t n = 0; n < glb.len; n += 1 + n / 8) {
                rc = sc_gltf_parse("cut.glb", glb.data, n, failing_read, NULL, &g, &err);
                SC_CHECK_MSG(rc != SC_OK, "prefix of %zu bytes parsed", n);
            }
            rc = sc_gltf_parse("cut.glb", glb.data, glb.len - 10, failing_read, NULL, &g, &err);
            SC_CHECK(message_has(&err, "cut.glb: truncated: the GLB header says"));
        }
        sc_buf_free(&bin), sc_buf_free(&glb);
        cJSON_Delete(j);
    }
}

/* The load_atlas node (its `slots` SLOTS, or all with NULL) on `glb`
 * written as NAME in a folder of its own beside its images: "normal
 * map.png" (2 x 2 grey) and the colour image COLOR (the bytes of
 * COLOR_FILE under the source tree, or the grey PNG). NULL when the node
 * fails (err says why). */
static sc_ctx *load_glb_beside(const sc_buf *glb, const char *name, const char *color, const char *color_file,
                               const char *slots, sc_error *err) {
    char *dir = sc_test_tempdir("glb-node");
    sc_buf png, img;
    png_bytes(2, 2, 128, &png);
    sc_buf_init(&img);
    if (color_file) {
        char *src = sc_test_source_path(color_file);
        SC_CHECK(sc_read_file(src, 1 << 20, &img, err) == SC_OK);
        free(src);
    }
    write_bytes(dir, color, color_file ? img.data : png.data, color_file ? img.len : png.len);
    write_bytes(dir, "normal map.png", png.data, png.len);
    write_bytes(dir, name, glb->data, glb->len);
    char *path = sc_path_join(dir, name);
    sc_ctx *ctx = slots ? run_load(path, err, "slots", slots, NULL) : run_load(path, err, NULL);
    sc_test_system("rm -rf '%s'", dir);
    free(path), free(dir);
    sc_buf_free(&png), sc_buf_free(&img);
    return ctx;
}

/* A primitive without TEXCOORD_0: uv (0, 0), counted; through the node, a
 * model whose every face lacks them cannot map its textures. */
SC_TEST(glb_without_texcoord) {
    cJSON *j = load_quad();
    if (!j) return;
    sc_buf bin, glb;
    quad_bin(j, &bin);
    no_texcoord(j, &bin);
    make_glb(j, &bin, &glb);
    sc_gltf g;
    sc_error err = {0};
    int rc = sc_gltf_parse("bare.glb", glb.data, glb.len, failing_read, NULL, &g, &err);
    SC_CHECK_MSG(rc == SC_OK, "%s", err.message);
    if (rc == SC_OK) {
        SC_CHECK_INT(g.faces_without_uv, g.mesh->nf);
        SC_CHECK(g.uv_missing);
        for (int32_t i = 0; i < g.mesh->nu; i++) SC_CHECK(g.mesh->U[2 * i] == 0 && g.mesh->U[2 * i + 1] == 0);
    }
    sc_gltf_free(&g);
    sc_ctx *ctx = load_glb_beside(&glb, "bare.glb", "color.png", NULL, NULL, &err);
    SC_CHECK(ctx == NULL && message_has(&err, "bare.glb has no texture coordinates, so its"));
    sc_ctx_free(ctx);
    sc_buf_free(&bin), sc_buf_free(&glb);
    cJSON_Delete(j);
}

static void constants_on_quad(cJSON *j) {
    cJSON *mat = at(j, "materials", 0), *pbr = cJSON_GetObjectItemCaseSensitive(mat, "pbrMetallicRoughness");
    cJSON *base = cJSON_AddArrayToObject(pbr, "baseColorFactor");
    const double bc[4] = {0.9, 0.5, 0.25, 0.75};
    for (int k = 0; k < 4; k++) cJSON_AddItemToArray(base, cJSON_CreateNumber(bc[k]));
    cJSON_AddNumberToObject(pbr, "metallicFactor", 0.125);
    cJSON_AddNumberToObject(pbr, "roughnessFactor", 0.3);
    cJSON *em = cJSON_AddArrayToObject(mat, "emissiveFactor");
    const double ef[3] = {0.125, 0.25, 2.5};
    for (int k = 0; k < 3; k++) cJSON_AddItemToArray(em, cJSON_CreateNumber(ef[k]));
    cJSON_AddNumberToObject(cJSON_GetObjectItemCaseSensitive(mat, "normalTexture"), "scale", 0.6);
    cJSON_AddNumberToObject(cJSON_GetObjectItemCaseSensitive(mat, "occlusionTexture"), "strength", 0.4);
    cJSON_AddStringToObject(mat, "alphaMode", "MASK");
    cJSON_AddNumberToObject(mat, "alphaCutoff", 0.35);
    cJSON_AddBoolToObject(mat, "doubleSided", true);
}

static void check_constants(const sc_material *m) {
    SC_CHECK(m->base_color[0] == 0.9 && m->base_color[1] == 0.5 && m->base_color[2] == 0.25 &&
             m->base_color[3] == 0.75);
    SC_CHECK(m->metallic == 0.125 && m->roughness == 0.3);
    SC_CHECK(m->emissive[0] == 0.125 && m->emissive[1] == 0.25 && m->emissive[2] == 2.5);
    SC_CHECK(m->normal_scale == 0.6 && m->occlusion_strength == 0.4);
    SC_CHECK(m->alpha_mode == SC_ALPHA_MASK && m->alpha_cutoff == 0.35 && m->double_sided);
}

/* A material's constants read, carried by load_atlas, and written back
 * into a .glb that reads them again bit for bit; bad ones are refused. */
SC_TEST(material_constants_round_trip) {
    cJSON *j = load_quad();
    if (!j) return;
    constants_on_quad(j);
    sc_buf bin, glb, out;
    quad_bin(j, &bin);
    make_glb(j, &bin, &glb);
    sc_buf_init(&out);
    sc_gltf g;
    sc_error err = {0};
    int rc = sc_gltf_parse("paint.glb", glb.data, glb.len, failing_read, NULL, &g, &err);
    SC_CHECK_MSG(rc == SC_OK, "%s", err.message);
    sc_buf png;
    png_bytes(2, 2, 128, &png);
    if (rc == SC_OK) {
        check_constants(&g.materials[0]);
        const sc_mesh *levels[1] = {g.mesh};
        sc_gltf_out_texture t[2] = {{0, "normal", SC_WRAP_REPEAT, SC_WRAP_REPEAT, png.data, png.len, "image/png", NULL},
                                    {0, "occlusion", SC_WRAP_REPEAT, SC_WRAP_REPEAT, png.data, png.len, "image/png",
                                     NULL}};
        rc = sc_gltf_write_glb(levels, 1, t, 2, g.materials, &out, &err);
        SC_CHECK_MSG(rc == SC_OK, "%s", err.message);
    }
    sc_gltf_free(&g);
    if (rc == SC_OK) {
        /* the JSON chunk, read here: glTF's own names and values */
        uint32_t n;
        memcpy(&n, out.data + 12, 4);
        cJSON *doc = cJSON_ParseWithLength((const char *)out.data + 20, n);
        const cJSON *mat = doc ? at(doc, "materials", 0) : NULL;
        SC_CHECK(mat && cJSON_IsTrue(cJSON_GetObjectItemCaseSensitive(mat, "doubleSided")));
        SC_CHECK(mat && strcmp(cJSON_GetObjectItemCaseSensitive(mat, "alphaMode")->valuestring, "MASK") == 0);
        SC_CHECK(mat && cJSON_GetObjectItemCaseSensitive(mat, "alphaCutoff")->valuedouble == 0.35);
        const cJSON *nt = mat ? cJSON_GetObjectItemCaseSensitive(mat, "normalTexture") : NULL;
        SC_CHECK(nt && cJSON_GetObjectItemCaseSensitive(nt, "scale")->valuedouble == 0.6);
        cJSON_Delete(doc);
        rc = sc_gltf_parse("again.glb", out.data, out.len, failing_read, NULL, &g, &err);
        SC_CHECK_MSG(rc == SC_OK, "%s", err.message);
        if (rc == SC_OK) check_constants(&g.materials[0]);
        sc_gltf_free(&g);
    }
    /* through the node: the atlas carries them */
    sc_ctx *ctx = load_glb_beside(&glb, "paint.glb", "color.png", NULL, NULL, &err);
    SC_CHECK_MSG(ctx != NULL, "%s", err.message);
    if (ctx) {
        const sc_atlas *a = sc_ctx_output(ctx, 0)->as.atlas;
        SC_CHECK(a->materials != NULL);
        if (a->materials) check_constants(&a->materials[0]);
        sc_ctx_free(ctx);
    }
    /* a metallic-roughness or emissive map the atlas goes without (here not
     * among `slots`) takes its factor with it: a dielectric, no emission */
    cJSON *mat = at(j, "materials", 0);
    cJSON_AddNumberToObject(cJSON_AddObjectToObject(cJSON_GetObjectItemCaseSensitive(mat, "pbrMetallicRoughness"),
                                                    "metallicRoughnessTexture"), "index", 0);
    cJSON_AddNumberToObject(cJSON_AddObjectToObject(mat, "emissiveTexture"), "index", 0);
    sc_buf_free(&glb);
    make_glb(j, &bin, &glb);
    for (int all = 0; all < 2; all++) {
        ctx = load_glb_beside(&glb, "paint.glb", "color.png", NULL, all ? NULL : "color,normal", &err);
        SC_CHECK_MSG(ctx != NULL, "%s", err.message);
        if (!ctx) continue;
        const sc_material *c = sc_ctx_output(ctx, 0)->as.atlas->materials;
        SC_CHECK(c && c->roughness == 0.3 && c->base_color[0] == 0.9);
        if (c && all) SC_CHECK(c->metallic == 0.125 && c->emissive[2] == 2.5);
        if (c && !all) SC_CHECK(c->metallic == 0 && c->emissive[0] == 0 && c->emissive[1] == 0 && c->emissive[2] == 0);
        sc_ctx_free(ctx);
    }
    sc_buf_free(&png), sc_buf_free(&bin), sc_buf_free(&glb), sc_buf_free(&out);
    cJSON_Delete(j);
    /* refused: each names the material and the field */
    static const char *const bad[][3] = {
        {"alphaMode", "SOMETIMES", "material 0: 'alphaMode' must be OPAQUE, MASK or BLEND"},
        {"doubleSided", "yes", "material 0: 'doubleSided' must be true or false"},
    };
    for (int i = 0; i < 2; i++) {
        j = load_quad();
        if (!j) return;
        cJSON_AddStringToObject(at(j, "materials", 0), bad[i][0], bad[i][1]);
        quad_bin(j, &bin);
        make_glb(j, &bin, &glb);
        rc = sc_gltf_parse("bad.glb", glb.data, glb.len, failing_read, NULL, &g, &err);
        SC_CHECK_MSG(rc != SC_OK && message_has(&err, bad[i][2]), "case %d: %s", i, err.message);
        sc_buf_free(&bin), sc_buf_free(&glb);
        cJSON_Delete(j);
    }
}

/* KHR_mesh_quantization (gltfpack's output): positions as normalized 16-bit
 * integers, the node's scale taking them back; the mesh matches the float
 * one within a quantization step. Without the extension they are refused. */
SC_TEST(quantized_positions) {
    cJSON *j = load_quad();
    if (!j) return;
    sc_buf bin, glb;
    quad_bin(j, &bin);
    make_glb(j, &bin, &glb);
    sc_gltf plain, q;
    sc_error err = {0};
    int rc = sc_gltf_parse("plain.glb", glb.data, glb.len, failing_read, NULL, &plain, &err);
    SC_CHECK_MSG(rc == SC_OK, "%s", err.message);
    sc_buf_free(&glb);
    /* the six positions as int16 / 32767 of the largest magnitude, after the float data */
    double most = 0;
    float p[18];
    memcpy(p, bin.data, sizeof p);
    for (int i = 0; i < 18; i++) most = fmax(most, fabs(p[i]));
    size_t offset = bin.len;
    for (int i = 0; i < 18; i++) {
        int16_t v = (int16_t)lround(p[i] / most * 32767);
        sc_buf_append(&bin, &v, 2);
    }
    set_number(at(j, "buffers", 0), "byteLength", (double)bin.len);
    cJSON *view = cJSON_CreateObject();
    cJSON_AddNumberToObject(view, "buffer", 0);
    cJSON_AddNumberToObject(view, "byteOffset", (double)offset);
    cJSON_AddNumberToObject(view, "byteLength", 36);
    cJSON_AddItemToArray(cJSON_GetObjectItemCaseSensitive(j, "bufferViews"), view);
    cJSON *pos = at(j, "accessors", 0);
    set_number(pos, "bufferView", 2);
    set_number(pos, "componentType", 5122);
    cJSON_AddBoolToObject(pos, "normalized", true);
    cJSON *scale = cJSON_AddArrayToObject(at(j, "nodes", 1), "scale");
    for (int k = 0; k < 3; k++) cJSON_AddItemToArray(scale, cJSON_CreateNumber(most));
    cJSON *copy = cJSON_Duplicate(j, true);
    make_glb(copy, &bin, &glb);
    rc = sc_gltf_parse("bare.glb", glb.data, glb.len, failing_read, NULL, &q, &err);
    SC_CHECK(rc != SC_OK && message_has(&err, "POSITION must be float (integers need KHR_mesh_quantization)"));
    sc_buf_free(&glb);
    cJSON_Delete(copy);
    cJSON *used = cJSON_AddArrayToObject(j, "extensionsUsed");
    cJSON *required = cJSON_AddArrayToObject(j, "extensionsRequired");
    cJSON_AddItemToArray(used, cJSON_CreateString("KHR_mesh_quantization"));
    cJSON_AddItemToArray(required, cJSON_CreateString("KHR_mesh_quantization"));
    make_glb(j, &bin, &glb);
    rc = sc_gltf_parse("quantized.glb", glb.data, glb.len, failing_read, NULL, &q, &err);
    SC_CHECK_MSG(rc == SC_OK, "%s", err.message);
    if (rc == SC_OK && plain.mesh) {
        SC_CHECK_INT(q.mesh->nv, plain.mesh->nv);
        SC_CHECK_INT(q.mesh->nf, plain.mesh->nf);
        double worst = 0;   /* the parent's scale 2 doubles the step */
        for (int32_t i = 0; i < 3 * q.mesh->nv && i < 3 * plain.mesh->nv; i++)
            worst = fmax(worst, fabs(q.mesh->V[i] - plain.mesh->V[i]));
        SC_CHECK_MSG(worst <= 2 * most / 32767, "quantized positions off by %g", worst);
        sc_gltf_free(&q);
    }
    sc_gltf_free(&plain);
    sc_buf_free(&bin), sc_buf_free(&glb);
    cJSON_Delete(j);
}

/* A texture whose image is named by EXT_texture_webp alone loads (the
 * tests' WebP); one with neither that nor a source is refused. */
SC_TEST(webp_texture) {
    cJSON *j = load_quad();
    if (!j) return;
    cJSON *t = at(j, "textures", 0);
    cJSON_DeleteItemFromObjectCaseSensitive(t, "source");
    cJSON *webp = cJSON_AddObjectToObject(cJSON_AddObjectToObject(t, "extensions"), "EXT_texture_webp");
    cJSON_AddNumberToObject(webp, "source", 0);
    set_string(at(j, "images", 0), "uri", "grad8.webp");
    cJSON *required = cJSON_AddArrayToObject(j, "extensionsRequired");
    cJSON_AddItemToArray(required, cJSON_CreateString("EXT_texture_webp"));
    sc_buf bin, glb;
    quad_bin(j, &bin);
    make_glb(j, &bin, &glb);
    sc_error err = {0};
    sc_ctx *ctx = load_glb_beside(&glb, "webp.glb", "grad8.webp", "tests/data/images/grad8.webp", NULL, &err);
    SC_CHECK_MSG(ctx != NULL, "%s", err.message);
    if (ctx) {
        const sc_atlas *a = sc_ctx_output(ctx, 0)->as.atlas;
        int c = sc_atlas_find_texture(a, 0, "color");
        SC_CHECK(c >= 0 && a->textures[c].image->as.image->width == 8 &&
                 strcmp(a->textures[c].source, "grad8.webp") == 0);
        sc_ctx_free(ctx);
    }
    cJSON_DeleteItemFromObjectCaseSensitive(t, "extensions");
    sc_buf_free(&glb);
    make_glb(j, &bin, &glb);
    sc_gltf g;
    int rc = sc_gltf_parse("bare.glb", glb.data, glb.len, failing_read, NULL, &g, &err);
    SC_CHECK(rc != SC_OK && message_has(&err, "texture 0 has no source image"));
    sc_buf_free(&bin), sc_buf_free(&glb);
    cJSON_Delete(j);
}

SC_TEST(bad_gltf_text_inputs) {
    sc_gltf g;
    sc_error err = {0};
    const char *garbage = "\x89\x01\x02 this is not json {";
    SC_CHECK(sc_gltf_parse("junk.gltf", garbage, strlen(garbage), NULL, NULL, &g, &err) != SC_OK);
    SC_CHECK(message_has(&err, "junk.gltf: JSON syntax error at line 1"));
    SC_CHECK(sc_gltf_parse("empty.gltf", "", 0, NULL, NULL, &g, &err) != SC_OK);
    SC_CHECK(message_has(&err, "empty.gltf: JSON syntax error"));
    const char *multi = "{\n\"asset\": {\"version\": \"2.0\"},\n\"nodes\": [,]\n}";
    SC_CHECK(sc_gltf_parse("multi.gltf", multi, strlen(multi), NULL, NULL, &g, &err) != SC_OK);
    SC_CHECK(message_has(&err, "multi.gltf: JSON syntax error at line 3"));
    const char *array = "[1, 2]";
    SC_CHECK(sc_gltf_parse("array.gltf", array, strlen(array), NULL, NULL, &g, &err) != SC_OK);
    SC_CHECK(message_has(&err, "array.gltf: the JSON is not an object"));
    /* an external buffer that cannot be read, and a bad data: URI */
    cJSON *j = load_quad();
    if (!j) return;
    set_string(at(j, "buffers", 0), "uri", "quad%20data.bin");
    SC_CHECK(parse_json("quad.gltf", j, &g, &err) != SC_OK);
    SC_CHECK(message_has(&err, "quad.gltf: buffer 0 (quad data.bin): quad data.bin: not here"));
    set_string(at(j, "buffers", 0), "uri", "data:application/octet-stream;base64,AAAA!AAA");
    SC_CHECK(parse_json("quad.gltf", j, &g, &err) != SC_OK);
    SC_CHECK(message_has(&err, "quad.gltf: buffer 0: data: URI has a byte that is not base64"));
    set_string(at(j, "buffers", 0), "uri", "http://example.com/quad.bin");
    SC_CHECK(parse_json("quad.gltf", j, &g, &err) != SC_OK);
    SC_CHECK(message_has(&err, "quad.gltf: buffer 0: uri 'http://example.com/quad.bin' is not a relative file name"));
    cJSON_Delete(j);
}

/* ---------------------------------------------------------------- the node */

SC_TEST(load_atlas_gltf_node) {
    char *dir = sc_test_tempdir("gltf");
    sc_test_system("cp '%s/tests/data/gltf/quad.gltf' '%s/'", getenv("SC_SOURCE_DIR") ? getenv("SC_SOURCE_DIR") : SC_SOURCE_DIR, dir);
    sc_buf color, normal;
    png_bytes(8, 8, 10, &color);
    png_bytes(4, 4, 128, &normal);
    write_bytes(dir, "color.png", color.data, color.len);
    write_bytes(dir, "normal map.png", normal.data, normal.len);
    char *path = sc_path_join(dir, "quad.gltf");
    sc_error err = {0};
    sc_ctx *ctx = run_load(path, &err, NULL);
    SC_CHECK_MSG(ctx != NULL, "%s", err.message);
    if (ctx) {
        const sc_atlas *a = sc_ctx_output(ctx, 0)->as.atlas;
        SC_CHECK_INT(a->ntex, 2);
        int c = sc_atlas_find_texture(a, 0, "color"), n = sc_atlas_find_texture(a, 0, "normal");
        SC_CHECK(c >= 0 && n >= 0);
        if (c >= 0 && n >= 0) {
            SC_CHECK_INT(a->textures[c].wrap_u, SC_WRAP_CLAMP);
            SC_CHECK_INT(a->textures[c].wrap_v, SC_WRAP_MIRROR);
            SC_CHECK_INT(a->textures[n].image->as.image->colorspace, SC_COLOR_DATA);
        }
        SC_CHECK_NEAR(sc_ctx_metric_value(ctx, "faces"), 2, 0);
        SC_CHECK_NEAR(sc_ctx_metric_value(ctx, "vertices"), 4, 0);
        SC_CHECK_NEAR(sc_ctx_metric_value(ctx, "uv_vertices"), 6, 0);
        SC_CHECK_NEAR(sc_ctx_metric_value(ctx, "seam_edges"), 1, 0);
        SC_CHECK_NEAR(sc_ctx_metric_value(ctx, "boundary_edges"), 4, 0);
        SC_CHECK_NEAR(sc_ctx_metric_value(ctx, "primitives_skipped"), 1, 0);
        SC_CHECK_NEAR(sc_ctx_metric_value(ctx, "textures_skipped"), 1, 0);
        sc_ctx_free(ctx);
    }
    ctx = run_load(path, &err, "wrap", "repeat", NULL);
    if (ctx) {
        const sc_atlas *a = sc_ctx_output(ctx, 0)->as.atlas;
        SC_CHECK_INT(a->textures[0].wrap_u, SC_WRAP_REPEAT);
        sc_ctx_free(ctx);
    }
    /* a missing normal map is left out, with a warning naming the glTF and the image */
    sc_test_system("rm -f '%s/normal map.png'", dir);
    ctx = run_load(path, &err, NULL);
    SC_CHECK_MSG(ctx != NULL, "%s", err.message);
    SC_CHECK(warning_has(ctx, "quad.gltf: image 1: material 'paint': normal texture left out") &&
             warning_has(ctx, "normal map.png: cannot open"));
    sc_ctx_free(ctx);
    ctx = run_load(path, &err, "slots", "color", NULL);   /* not asked for: not read */
    SC_CHECK_MSG(ctx != NULL, "%s", err.message);
    sc_ctx_free(ctx);
    char *missing = sc_path_join(dir, "none.glb");
    ctx = run_load(missing, &err, NULL);
    SC_CHECK(ctx == NULL && message_has(&err, "none.glb: cannot open"));
    free(missing), free(path);
    sc_buf_free(&color), sc_buf_free(&normal);
    sc_test_system("rm -rf '%s'", dir);
    free(dir);
}

/* ---------------------------------------------------------------- corpus */

SC_TEST(corpus_gltf_match_stats_and_welded_objs) {
    const char *corpus = sc_test_corpus();
    if (!corpus) {
        printf("corpus absent, skipped\n");
        return;
    }
    /* Lantern_baseColor.png and BoomBox_occlusionRoughnessMetallic.png are not
     * in the corpus (see its SOURCE.txt): Lantern gets the staged diffuse map,
     * BoomBox loads the colour and normal slots only. */
    static const struct {
        const char *asset, *file, *slots, *texture;
    } assets[] = {
        {"Avocado", "Avocado.gltf", "all", NULL},
        {"BoomBox", "BoomBox.gltf", "color,normal", NULL},
        {"Lantern", "Lantern.gltf", "all", "Lantern_diffuse_from_specGloss.png"},
        {"Duck", "Duck.gltf", "all", NULL},
        {"MuruCat", "scene.gltf", "all", NULL},
        {"Suzanne", "Suzanne.gltf", "all", NULL},
        {"WaterBottle", "WaterBottle.gltf", "all", NULL},
    };
    static const char *const keys[] = {"tris", "verts3d", "uvverts", "seam_edges", "boundary_edges"};
    static const char *const metrics[] = {"faces", "vertices", "uv_vertices", "seam_edges", "boundary_edges"};
    printf("%-18s %6s %6s %6s %6s %6s %4s %9s %8s %8s %8s\n", "asset", "faces", "verts", "uvs", "seams",
           "bound", "tex", "obj seams", "parse s", "decode s", "total s");
    for (size_t i = 0; i < sizeof assets / sizeof assets[0]; i++) {
        char path[4096], texture[4096], welded[4096];
        snprintf(path, sizeof path, "%s/%s/%s", corpus, assets[i].asset, assets[i].file);
        snprintf(welded, sizeof welded, "%s/%s/%s_welded.obj", corpus, assets[i].asset, assets[i].asset);
        sc_error err = {0};
        sc_ctx *ctx;
        double t0 = sc_now();
        if (assets[i].texture) {
            snprintf(texture, sizeof texture, "%s/%s/%s", corpus, assets[i].asset, assets[i].texture);
            ctx = run_load(path, &err, "slots", assets[i].slots, "texture", texture, NULL);
        } else {
            ctx = run_load(path, &err, "slots", assets[i].slots, NULL);
        }
        double seconds = sc_now() - t0;
        SC_CHECK_MSG(ctx != NULL, "%s: %s", assets[i].file, err.message);
        sc_ctx *obj = run_load(welded, &err, "slots", "color", NULL);
        SC_CHECK_MSG(obj != NULL, "%s: %s", welded, err.message);
        cJSON *stats = sc_test_corpus_stats(corpus, assets[i].asset);
        if (ctx && obj && stats) {
            for (int k = 0; k < 5; k++)
                SC_CHECK_MSG(sc_ctx_metric_value(ctx, metrics[k]) == sc_test_stat(stats, keys[k]),
                             "%s: %s = %.0f, stats.json %s = %.0f", assets[i].file, metrics[k],
                             sc_ctx_metric_value(ctx, metrics[k]), keys[k], sc_test_stat(stats, keys[k]));
            SC_CHECK_MSG(sc_ctx_metric_value(ctx, "seam_edges") == sc_ctx_metric_value(obj, "seam_edges"),
                         "%s: glTF and welded OBJ disagree on seams", assets[i].asset);
            SC_CHECK(sc_ctx_metric_value(ctx, "materials") == sc_test_stat(stats, "materials_used"));
            printf("%-18s %6.0f %6.0f %6.0f %6.0f %6.0f %4.0f %9.0f %8.3f %8.3f %8.3f\n", assets[i].file,
                   sc_ctx_metric_value(ctx, "faces"), sc_ctx_metric_value(ctx, "vertices"),
                   sc_ctx_metric_value(ctx, "uv_vertices"), sc_ctx_metric_value(ctx, "seam_edges"),
                   sc_ctx_metric_value(ctx, "boundary_edges"), sc_ctx_metric_value(ctx, "textures"),
                   sc_ctx_metric_value(obj, "seam_edges"), sc_ctx_metric_value(ctx, "seconds_parse"),
                   sc_ctx_metric_value(ctx, "seconds_decode"), seconds);
        }
        cJSON_Delete(stats);
        sc_ctx_free(ctx);
        sc_ctx_free(obj);
    }
    /* several decoding threads: the same atlas, sooner */
    char avocado[4096];
    snprintf(avocado, sizeof avocado, "%s/Avocado/Avocado.gltf", corpus);
    sc_error e1 = {0};
    double t0 = sc_now();
    sc_ctx *one = run_load(avocado, &e1, NULL);
    double t1 = sc_now();
    sc_ctx *three = run_load(avocado, &e1, "threads", "3", NULL);
    double t2 = sc_now();
    SC_CHECK(one && three &&
             sc_digest_equal(sc_value_digest(sc_ctx_output(one, 0)), sc_value_digest(sc_ctx_output(three, 0))));
    printf("Avocado.gltf, 3 textures: %.3f s on 1 thread, %.3f s on 3\n", t1 - t0, t2 - t1);
    sc_ctx_free(one), sc_ctx_free(three);
    /* BoomBox's glTF names a map the corpus lacks: it loads without it, and
     * the warning names the glTF and the missing file */
    char path[4096];
    snprintf(path, sizeof path, "%s/BoomBox/BoomBox.gltf", corpus);
    sc_error err = {0};
    sc_ctx *ctx = run_load(path, &err, NULL);
    SC_CHECK_MSG(ctx != NULL, "%s", err.message);
    SC_CHECK(warning_has(ctx, "BoomBox.gltf: image 1: material 'BoomBox_Mat'") &&
             warning_has(ctx, "BoomBox_occlusionRoughnessMetallic.png: cannot open"));
    sc_ctx_free(ctx);
}

int main(void) { return sc_test_main(); }
