/* test_obj.c - the OBJ/MTL reader (nodes/lib/sc_obj.h), the load_atlas node on
 * OBJ files, and save -> load round trips. Corpus OBJs are compared with their
 * stats.json when the corpus is present. */
#include <stdarg.h>
#include <stdlib.h>

#include <cjson/cJSON.h>

#include "sc_exec.h"
#include "sc_gltf.h"
#include "sc_imageio.h"
#include "sc_nodes.h"
#include "sc_obj.h"
#include "sc_test.h"

/* ---------------------------------------------------------------- helpers */

static char *data_path(const char *name) {
    char rel[256];
    snprintf(rel, sizeof rel, "tests/data/obj/%s", name);
    return sc_test_source_path(rel);
}

/* Reads files relative to a directory (the OBJ's). */
static int read_relative(void *ud, const char *path, sc_buf *out, sc_error *err) {
    char *full = sc_path_join((const char *)ud, path);
    int rc = sc_read_file(full, 1 << 20, out, err);
    free(full);
    return rc;
}

static int failing_read(void *ud, const char *path, sc_buf *out, sc_error *err) {
    return sc_fail(err, SC_EINPUT, "%s: not here", path);
}

static int parse_data_file(const char *name, sc_obj *obj, sc_error *err) {
    char *path = data_path(name);
    char *dir = sc_path_dirname(path);
    sc_buf b;
    sc_buf_init(&b);
    int rc = sc_read_file(path, 1 << 20, &b, err);
    if (rc == SC_OK) rc = sc_obj_parse(name, b.data, b.len, read_relative, dir, obj, err);
    sc_buf_free(&b);
    free(dir);
    free(path);
    return rc;
}

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

static void write_text(const char *dir, const char *name, const char *text) {
    char *path = sc_path_join(dir, name);
    sc_error err = {0};
    SC_CHECK_MSG(sc_write_file_atomic(path, text, strlen(text), &err) == SC_OK, "%s", err.message);
    free(path);
}

static void write_png(const char *dir, const char *name, int w, int h, uint8_t value) {
    sc_image_data *im = sc_image_alloc(w, h, 3, SC_PIXEL_U8);
    memset(im->pixels, value, (size_t)w * h * 3);
    sc_buf b;
    sc_buf_init(&b);
    sc_error err = {0};
    SC_CHECK(sc_image_encode_png(im, 8, &b, &err) == SC_OK);
    char *path = sc_path_join(dir, name);
    SC_CHECK_MSG(sc_write_file_atomic(path, b.data, b.len, &err) == SC_OK, "%s", err.message);
    free(path);
    sc_buf_free(&b);
    sc_image_free(im);
}

static void copy_data_file(const char *name, const char *dir) {
    char *src = data_path(name);
    sc_buf b;
    sc_buf_init(&b);
    sc_error err = {0};
    SC_CHECK(sc_read_file(src, 1 << 20, &b, &err) == SC_OK);
    char *dst = sc_path_join(dir, name);
    SC_CHECK(sc_write_file_atomic(dst, b.data, b.len, &err) == SC_OK);
    free(dst);
    free(src);
    sc_buf_free(&b);
}

/* Run load_atlas with params given as "name", "value" pairs (NULL-ended). */
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

static const sc_atlas *atlas_of(sc_ctx *ctx) {
    sc_value *v = sc_ctx_output(ctx, 0);
    return v && v->kind == SC_KIND_ATLAS ? v->as.atlas : NULL;
}

/* ---------------------------------------------------------------- parsing */

SC_TEST(parses_every_textured_face_form) {
    sc_obj obj;
    sc_error err = {0};
    int rc = parse_data_file("square.obj", &obj, &err);
    SC_CHECK_MSG(rc == SC_OK, "%s", err.message);
    if (rc) return;
    const sc_mesh *m = obj.mesh;
    SC_CHECK_INT(m->nf, 4);
    SC_CHECK_INT(m->nv, 5);
    SC_CHECK_INT(m->nu, 5);
    SC_CHECK_INT(m->nn, 0);   /* some corners have no vn: normals dropped */
    SC_CHECK(obj.normals_dropped);
    SC_CHECK_INT(m->nmat, 2);
    SC_CHECK_STR(m->materials[0], "red");
    SC_CHECK_STR(m->materials[1], "blue");
    int fm[4] = {0, 1, 1, 0};
    for (int f = 0; f < 4; f++) SC_CHECK_INT(m->FM[f], fm[f]);
    /* the continued face with negative indices: -3 -2 -1 of 5 = 3 4 5 */
    for (int k = 0; k < 3; k++) {
        SC_CHECK_INT(m->FV[6 + k], 2 + k);
        SC_CHECK_INT(m->FU[6 + k], 2 + k);
    }
    SC_CHECK(m->V[3 * 4] == 0.5 && m->U[2 * 2] == 1 && m->U[2 * 2 + 1] == 1);
    SC_CHECK(sc_mesh_check(m, &err) == SC_OK);
    SC_CHECK_INT(obj.nmaps, 3);
    if (obj.nmaps == 3) {
        SC_CHECK_INT(obj.maps[0].material, 0);
        SC_CHECK_STR(obj.maps[0].slot, "color");
        SC_CHECK_STR(obj.maps[0].path, "red.png");   /* options skipped */
        SC_CHECK_STR(obj.maps[0].mtl, "square.mtl");
        SC_CHECK_INT(obj.maps[0].line, 5);
        SC_CHECK_STR(obj.maps[1].slot, "color");
        SC_CHECK_STR(obj.maps[1].path, "textures/blue.png");   /* backslash */
        SC_CHECK_STR(obj.maps[2].slot, "normal");
        SC_CHECK_STR(obj.maps[2].path, "blue_normal.png");     /* norm beats map_Bump */
    }
    sc_obj_free(&obj);
}

SC_TEST(polygons_degenerate_faces_and_defaults) {
    sc_obj obj;
    sc_error err = {0};
    int rc = parse_data_file("polygon.obj", &obj, &err);
    SC_CHECK_MSG(rc == SC_OK, "%s", err.message);
    if (rc) return;
    SC_CHECK_INT(obj.mesh->nf, 3);                 /* the pentagon's fan */
    SC_CHECK_INT(obj.degenerate_faces_dropped, 1);
    SC_CHECK_INT(obj.polygons, 1);
    SC_CHECK_INT(obj.mesh->nv, 5);                 /* v 9 9 9 dropped */
    SC_CHECK_INT(obj.mesh->nu, 5);                 /* vt 6 only in the dropped face */
    SC_CHECK_INT(obj.unreferenced_dropped, 2);
    SC_CHECK_INT(obj.mesh->nmat, 1);
    SC_CHECK_STR(obj.mesh->materials[0], "default");
    SC_CHECK_INT(obj.nmaps, 0);
    /* fan from the first corner */
    int fv[9] = {0, 1, 2, 0, 2, 3, 0, 3, 4};
    for (int k = 0; k < 9; k++) SC_CHECK_INT(obj.mesh->FV[k], fv[k]);
    sc_obj_free(&obj);
}

/* Faces without texture coordinates: uv (0, 0), one added vt, counted; a
 * face with them at some corners only is an error (above). */
SC_TEST(faces_without_texture_coordinates) {
    static const char *const text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nvt 0.5 0.5\nvt 1 0\nvt 0 1\n"
                                    "f 1 2 3\nf 2/1 4/2 3/3\n";
    sc_obj obj;
    sc_error err = {0};
    int rc = sc_obj_parse("mixed.obj", text, strlen(text), failing_read, NULL, &obj, &err);
    SC_CHECK_MSG(rc == SC_OK, "%s", err.message);
    if (rc == SC_OK) {
        SC_CHECK_INT(obj.faces_without_uv, 1);
        SC_CHECK(!obj.uv_missing);
        SC_CHECK_INT(obj.mesh->nf, 2);
        SC_CHECK_INT(obj.mesh->nu, 4);   /* the three vt and the added (0, 0) */
        for (int k = 0; k < 3; k++) {
            const double *uv = obj.mesh->U + 2 * obj.mesh->FU[k];
            SC_CHECK(uv[0] == 0 && uv[1] == 0);
        }
        SC_CHECK(obj.mesh->U[2 * obj.mesh->FU[3]] == 0.5);
        sc_obj_free(&obj);
    }
    char *path = data_path("blob_no_uv.obj");
    sc_buf b;
    sc_buf_init(&b);
    rc = sc_read_file(path, 1 << 20, &b, &err);
    if (rc == SC_OK) rc = sc_obj_parse("blob_no_uv.obj", b.data, b.len, failing_read, NULL, &obj, &err);
    SC_CHECK_MSG(rc == SC_OK, "%s", err.message);
    if (rc == SC_OK) {
        SC_CHECK_INT(obj.mesh->nf, 320);
        SC_CHECK_INT(obj.faces_without_uv, 320);
        SC_CHECK(obj.uv_missing);
        SC_CHECK_INT(obj.mesh->nu, 1);
        SC_CHECK(obj.mesh->U[0] == 0 && obj.mesh->U[1] == 0);
        sc_obj_free(&obj);
    }
    sc_buf_free(&b);
    free(path);
}

SC_TEST(crlf_and_normals) {
    const char *text =
        "\xEF\xBB\xBFv 0 0 0\r\nv 1 0 0\r\nv 0 1 0\r\nvt 0 0\r\nvt 1 0\r\nvt 0 1\r\n"
        "vn 0 0 1\r\nvn 0 0 -1\r\nf 1/1/2 2/2/2 3/3/2\r\n";
    sc_obj obj;
    sc_error err = {0};
    int rc = sc_obj_parse("crlf.obj", text, strlen(text), NULL, NULL, &obj, &err);
    SC_CHECK_MSG(rc == SC_OK, "%s", err.message);
    if (rc) return;
    SC_CHECK_INT(obj.mesh->nf, 1);
    SC_CHECK_INT(obj.mesh->nn, 1);   /* only the used normal is kept */
    SC_CHECK(obj.mesh->N[2] == -1);
    SC_CHECK_INT(obj.mesh->FN[0], 0);
    sc_obj_free(&obj);
    /* the same file with \n and with \r\n gives the same mesh */
    sc_obj a, b;
    char *path = data_path("seam.obj");
    sc_buf lf, crlf;
    sc_buf_init(&lf), sc_buf_init(&crlf);
    SC_CHECK(sc_read_file(path, 1 << 20, &lf, &err) == SC_OK);
    for (size_t i = 0; i < lf.len; i++) {
        if (lf.data[i] == '\n') sc_buf_u8(&crlf, '\r');
        sc_buf_u8(&crlf, lf.data[i]);
    }
    SC_CHECK(sc_obj_parse("lf.obj", lf.data, lf.len, NULL, NULL, &a, &err) == SC_OK);
    SC_CHECK(sc_obj_parse("crlf.obj", crlf.data, crlf.len, NULL, NULL, &b, &err) == SC_OK);
    if (a.mesh && b.mesh) {
        SC_CHECK(a.mesh->nv == b.mesh->nv && a.mesh->nf == b.mesh->nf);
        SC_CHECK(memcmp(a.mesh->V, b.mesh->V, sizeof(double) * 3 * a.mesh->nv) == 0);
        SC_CHECK(memcmp(a.mesh->FU, b.mesh->FU, sizeof(int32_t) * 3 * a.mesh->nf) == 0);
    }
    sc_obj_free(&a), sc_obj_free(&b);
    sc_buf_free(&lf), sc_buf_free(&crlf);
    free(path);
}

SC_TEST(bad_obj_inputs_name_file_and_line) {
    static const char *const tri = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\n";
    static const struct {
        const char *body;   /* appended to `tri` when it starts with '+' */
        const char *expect;
    } cases[] = {
        {"f 1/1 2/1 3/1\n", "bad.obj:1: vertex index 1 is out of range (the file has 0 vertices)"},
        {"+f 0/1 2/1 3/1\n", "bad.obj:6: face corner '0/1': vertex index 0 (OBJ indices start at 1)"},
        {"+f 1/1 2/1 9/1\n", "bad.obj:6: vertex index 9 is out of range (the file has 3 vertices)"},
        {"+f 1/1 2/2 3/7\n", "bad.obj:6: texture coordinate index 7 is out of range (the file has 2)"},
        {"+f 1/1 2/1 3/0\n", "bad.obj:6: face corner '3/0': texture coordinate index 0"},
        {"+f -5/1 2/1 3/1\n", "bad.obj:6: face corner '-5/1': relative vertex index -5 is out of range"},
        {"+f 1/1/1 2/1/1 3/1/4\n", "bad.obj:6: normal index 1 is out of range (the file has 0 normals)"},
        {"v nan 0 0\n", "bad.obj:1: vertex: coordinate 1 is not finite ('nan')"},
        {"v 0 inf 0\n", "bad.obj:1: vertex: coordinate 2 is not finite ('inf')"},
        {"v 0 0 1e999\n", "bad.obj:1: vertex: coordinate 3 is not finite"},
        {"+vt 0.5 NaN\n", "bad.obj:6: texture coordinate: coordinate 2 is not finite"},
        {"v 1 2\n", "bad.obj:1: vertex needs 3 numbers, found 2"},
        {"vn 1\n", "bad.obj:1: normal needs 3 numbers, found 1"},
        {"v 1 2 3abc\n", "bad.obj:1: vertex: '3abc' is not a number"},
        {"+f 1/1 2 3/1\n", "bad.obj:6: face has texture coordinates at some corners only (corner '2')"},
        {"+f 1//1 2//1 3//1\n", "bad.obj:6: normal index 1 is out of range (the file has 0 normals)"},
        {"+f 1/1 2/2\n", "bad.obj:6: face has 2 corners, needs at least 3"},
        {"+f 1/1 2/2 3/x\n", "bad.obj:6: face corner '3/x': missing or bad texture coordinate index"},
        {"+f 1/1 2/2 3/1a\n", "bad.obj:6: face corner '3/1a' is malformed"},
        {"+\n\nf 1/1 2/2 3/\n", "bad.obj:8: face has texture coordinates at some corners only (corner '3/')"},
        {"+f 1/1 2/2 99999999999/1\n", "bad.obj:6: face corner '99999999999/1': vertex index is too large"},
        {"\x01\x02\xff\xfe\n", "bad.obj:1: unexpected text '\\x01\\x02\\xff\\xfe' (not a statement)"},
        {"+v 1 2 3 \\\n\x00\x01", "bad.obj:7: NUL byte"},
        {"v1.0 2 3\n", "bad.obj:1: unexpected text 'v1.0'"},
        {"", "bad.obj: no faces"},
        {"+", "bad.obj: no faces"},
        {"+mtllib missing.mtl\nf 1/1 2/2 3/1\n", "bad.obj:6: mtllib missing.mtl: missing.mtl: not here"},
        {"+mtllib\n", "bad.obj:6: mtllib without a file name"},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        sc_buf text;
        sc_buf_init(&text);
        const char *body = cases[i].body;
        size_t body_len = strlen(body);
        if (body[0] == '+') {
            sc_buf_puts(&text, tri);
            body++, body_len--;
        }
        if (strstr(body, "\\\n")) body_len += 3;   /* the NUL case: keep the bytes after it */
        sc_buf_append(&text, body, body_len);
        sc_obj obj;
        sc_error err = {0};
        int rc = sc_obj_parse("bad.obj", text.data, text.len, failing_read, NULL, &obj, &err);
        SC_CHECK_MSG(rc != SC_OK, "case %zu parsed", i);
        SC_CHECK_MSG(message_has(&err, cases[i].expect), "case %zu", i);
        SC_CHECK(obj.mesh == NULL && obj.maps == NULL);
        sc_buf_free(&text);
    }
}

SC_TEST(bad_mtl_inputs) {
    static const struct {
        const char *mtl, *expect;
    } cases[] = {
        {"map_Kd a.png\n", "m.mtl:1: map_Kd before any newmtl"},
        {"newmtl\n", "m.mtl:1: newmtl without a name"},
        {"newmtl a\nmap_Kd -bm 1\n", "m.mtl:2: map_Kd without a file name"},
        {"newmtl a\n\x7f\n", "m.mtl:2: unexpected text"},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        const char *obj_text = "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/1 2/1 3/1\n";
        sc_obj obj;
        sc_error err = {0};
        char *dir = sc_test_tempdir("mtl");
        write_text(dir, "m.mtl", cases[i].mtl);
        int rc = sc_obj_parse("x.obj", obj_text, strlen(obj_text), read_relative, dir, &obj, &err);
        SC_CHECK_MSG(rc != SC_OK, "case %zu parsed", i);
        SC_CHECK_MSG(message_has(&err, cases[i].expect), "case %zu", i);
        sc_test_system("rm -rf '%s'", dir);
        free(dir);
    }
    /* an MTL in a sub-folder: its maps are relative to it */
    const char *obj_text = "mtllib sub/m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nusemtl a\nf 1/1 2/1 3/1\n";
    char *dir = sc_test_tempdir("mtl");
    sc_test_system("mkdir -p '%s/sub'", dir);
    write_text(dir, "sub/m.mtl", "newmtl a\nmap_Kd -s 1 1 1 -o 0.5 t.png\nmap_Ke glow.png\n");
    sc_obj obj;
    sc_error err = {0};
    SC_CHECK(sc_obj_parse("x.obj", obj_text, strlen(obj_text), read_relative, dir, &obj, &err) == SC_OK);
    SC_CHECK_INT(obj.nmaps, 2);
    if (obj.nmaps == 2) {
        SC_CHECK_STR(obj.maps[0].path, "sub/t.png");
        SC_CHECK_STR(obj.maps[1].slot, "emissive");
        SC_CHECK_STR(obj.maps[1].path, "sub/glow.png");
    }
    sc_obj_free(&obj);
    sc_test_system("rm -rf '%s'", dir);
    free(dir);
}

/* ---------------------------------------------------------------- the node */

SC_TEST(load_atlas_obj_node) {
    char *dir = sc_test_tempdir("load-obj");
    copy_data_file("square.obj", dir);
    copy_data_file("square.mtl", dir);
    sc_test_system("mkdir -p '%s/textures'", dir);
    write_png(dir, "red.png", 4, 2, 200);
    write_png(dir, "textures/blue.png", 8, 8, 50);
    write_png(dir, "blue_normal.png", 8, 8, 128);
    char *path = sc_path_join(dir, "square.obj");
    sc_error err = {0};
    sc_ctx *ctx = run_load(path, &err, NULL);
    SC_CHECK_MSG(ctx != NULL, "%s", err.message);
    if (ctx) {
        const sc_atlas *a = atlas_of(ctx);
        SC_CHECK_INT(a->ntex, 3);
        int red = sc_atlas_find_texture(a, 0, "color"), blue = sc_atlas_find_texture(a, 1, "color");
        int normal = sc_atlas_find_texture(a, 1, "normal");
        SC_CHECK(red >= 0 && blue >= 0 && normal >= 0);
        if (red >= 0 && blue >= 0 && normal >= 0) {
            SC_CHECK_STR(a->textures[red].source, "red.png");
            SC_CHECK_STR(a->textures[blue].source, "blue.png");
            SC_CHECK_INT(a->textures[red].wrap_u, SC_WRAP_REPEAT);
            SC_CHECK_INT(a->textures[red].image->as.image->width, 4);
            SC_CHECK_INT(a->textures[red].image->as.image->colorspace, SC_COLOR_SRGB);
            SC_CHECK_INT(a->textures[normal].image->as.image->colorspace, SC_COLOR_DATA);
        }
        SC_CHECK_NEAR(sc_ctx_metric_value(ctx, "faces"), 4, 0);
        SC_CHECK_NEAR(sc_ctx_metric_value(ctx, "textures"), 3, 0);
        SC_CHECK_NEAR(sc_ctx_metric_value(ctx, "boundary_edges"), 4, 0);
        SC_CHECK_NEAR(sc_ctx_metric_value(ctx, "seam_edges"), 0, 0);
        SC_CHECK_INT(sc_ctx_ndeps(ctx), 5);   /* obj, mtl, three textures */
        /* decoding on several threads gives the very same atlas */
        sc_ctx *parallel = run_load(path, &err, "threads", "3", NULL);
        SC_CHECK(parallel &&
                 sc_digest_equal(sc_value_digest(sc_ctx_output(parallel, 0)), sc_value_digest(sc_ctx_output(ctx, 0))));
        sc_ctx_free(parallel);
        sc_ctx_free(ctx);
    }
    /* wrap, slots, and the texture override */
    char *override = sc_path_join(dir, "red.png");
    ctx = run_load(path, &err, "wrap", "mirror", "slots", "color", "texture", override, NULL);
    SC_CHECK_MSG(ctx != NULL, "%s", err.message);
    if (ctx) {
        const sc_atlas *a = atlas_of(ctx);
        SC_CHECK_INT(a->ntex, 2);
        for (int t = 0; t < a->ntex; t++) {
            SC_CHECK_STR(a->textures[t].name, "color");
            SC_CHECK_STR(a->textures[t].source, "red.png");
            SC_CHECK_INT(a->textures[t].wrap_v, SC_WRAP_MIRROR);
        }
        /* one decoded image shared by both materials */
        if (a->ntex == 2) SC_CHECK(a->textures[0].image == a->textures[1].image);
        sc_ctx_free(ctx);
    }
    /* a model without texture coordinates: a warning and a metric; with a
     * texture to map, an error naming the file */
    char *bare = data_path("blob_no_uv.obj");
    ctx = run_load(bare, &err, NULL);
    SC_CHECK_MSG(ctx != NULL, "%s", err.message);
    if (ctx) {
        SC_CHECK_NEAR(sc_ctx_metric_value(ctx, "faces_without_uv"), 320, 0);
        SC_CHECK(warning_has(ctx, "320 of 320 faces have no texture coordinates"));
        sc_ctx_free(ctx);
    }
    ctx = run_load(bare, &err, "texture", override, NULL);
    SC_CHECK(ctx == NULL && message_has(&err, "blob_no_uv.obj has no texture coordinates, so its texture cannot be "
                                              "mapped"));
    sc_ctx_free(ctx);
    free(bare);
    /* an unknown slot is refused with the value, before anything runs */
    ctx = sc_ctx_new(&sc_node_load_atlas, NULL, NULL);
    SC_CHECK(sc_ctx_set_param(ctx, "slots", "color,bogus", &err) != SC_OK &&
             message_has(&err, "load_atlas:slots: unknown slot 'bogus'"));
    sc_ctx_free(ctx);
    /* a missing optional map is left out with a warning naming the MTL (and
     * line) and the texture; the colour maps stay */
    sc_test_system("rm -f '%s/blue_normal.png'", dir);
    ctx = run_load(path, &err, NULL);
    SC_CHECK_MSG(ctx != NULL, "%s", err.message);
    SC_CHECK(warning_has(ctx, "square.mtl:11: material 'blue': normal texture left out") &&
             warning_has(ctx, "blue_normal.png"));
    if (ctx) SC_CHECK_INT(sc_ctx_output(ctx, 0)->as.atlas->ntex, 2);
    sc_ctx_free(ctx);
    /* a corrupt one too */
    write_text(dir, "blue_normal.png", "\x89PNG\r\n\x1a\nnot really");
    ctx = run_load(path, &err, NULL);
    SC_CHECK(ctx != NULL && warning_has(ctx, "blue_normal.png: corrupt or truncated png"));
    sc_ctx_free(ctx);
    /* a colour map that cannot be read still fails, naming it */
    sc_test_system("cd '%s' && mv textures/blue.png textures/blue.gone", dir);
    ctx = run_load(path, &err, NULL);
    SC_CHECK(ctx == NULL && message_has(&err, "square.mtl:10: material 'blue': color texture") &&
             message_has(&err, "blue.png: cannot open"));
    sc_test_system("cd '%s' && mv textures/blue.gone textures/blue.png", dir);
    /* a missing MTL */
    sc_test_system("rm -f '%s/square.mtl'", dir);
    ctx = run_load(path, &err, NULL);
    SC_CHECK(ctx == NULL && message_has(&err, "square.obj:4: mtllib square.mtl"));
    /* missing model, unknown format */
    char *missing = sc_path_join(dir, "nothing.obj");
    ctx = run_load(missing, &err, NULL);
    SC_CHECK(ctx == NULL && message_has(&err, "nothing.obj: cannot open"));
    ctx = run_load("/tmp/model.ply", &err, NULL);
    SC_CHECK(ctx == NULL && message_has(&err, "/tmp/model.ply: unknown model format"));
    free(missing), free(override), free(path);
    sc_test_system("rm -rf '%s'", dir);
    free(dir);
}

/* A double-sided model made of two copies of its surface: the reversed
 * copy (same points, other orientation, same uv) is dropped and its
 * material marked double-sided; a reversed face with other uv, or a face
 * repeated in the same orientation, is no such copy and stays. */
SC_TEST(reversed_copies_dropped) {
    char *dir = sc_test_tempdir("reversed");
    write_text(dir, "two.obj",
               "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvt 0.5 0.5\n"
               "f 1/1 2/2 3/3\nf 1/1 3/3 4/4\n"      /* the surface */
               "f 3/3 2/2 1/1\nf 4/4 3/3 1/1\n");    /* reversed, same uv: dropped */
    char *path = sc_path_join(dir, "two.obj");
    sc_error err = {0};
    sc_ctx *ctx = run_load(path, &err, NULL);
    SC_CHECK_MSG(ctx != NULL, "%s", err.message);
    if (ctx) {
        const sc_atlas *a = atlas_of(ctx);
        SC_CHECK_INT(a->mesh->as.mesh->nf, 2);
        SC_CHECK_NEAR(sc_ctx_metric_value(ctx, "reversed_copies_dropped"), 2, 0);
        SC_CHECK(a->materials && a->materials[0].double_sided && a->materials[0].metallic == 0);
        SC_CHECK(warning_has(ctx, "2 faces are reversed copies of others"));
        sc_ctx_free(ctx);
    }
    write_text(dir, "two.obj",
               "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvt 0.5 0.5\n"
               "f 1/1 2/2 3/3\nf 1/1 3/3 4/4\n"
               "f 3/5 2/2 1/1\n"                     /* reversed, other uv: kept */
               "f 1/1 3/3 4/4\n");                   /* the same orientation: kept */
    ctx = run_load(path, &err, NULL);
    SC_CHECK_MSG(ctx != NULL, "%s", err.message);
    if (ctx) {
        const sc_atlas *a = atlas_of(ctx);
        SC_CHECK_INT(a->mesh->as.mesh->nf, 4);
        SC_CHECK_NEAR(sc_ctx_metric_value(ctx, "reversed_copies_dropped"), 0, 0);
        SC_CHECK(a->materials == NULL);
        sc_ctx_free(ctx);
    }
    sc_test_system("rm -rf '%s'", dir);
    free(path), free(dir);
}

/* A texture the MTL names where it was on another machine (an absolute
 * Windows path, a folder that is not there) is read from the file of that
 * name beside the model, with a warning; with no such file it still fails,
 * and nothing outside the asset's folder is read. */
SC_TEST(textures_named_elsewhere_read_beside_the_model) {
    char *dir = sc_test_tempdir("elsewhere");
    static const char *const obj = "mtllib m.mtl\nusemtl a\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\n"
                                   "f 1/1 2/2 3/3\n";
    write_text(dir, "m.obj", obj);
    write_text(dir, "m.mtl", "newmtl a\nmap_Kd C:\\Users\\me\\Desktop\\wood.png\nmap_Ke ../gone/glow.png\n");
    write_png(dir, "wood.png", 4, 4, 90);
    write_png(dir, "glow.png", 4, 4, 20);
    char *path = sc_path_join(dir, "m.obj");
    sc_error err = {0};
    sc_ctx *ctx = run_load(path, &err, NULL);
    SC_CHECK_MSG(ctx != NULL, "%s", err.message);
    if (ctx) {
        const sc_atlas *a = atlas_of(ctx);
        SC_CHECK_INT(a->ntex, 2);
        SC_CHECK(warning_has(ctx, "m.mtl:2: 'C:/Users/me/Desktop/wood.png' is outside the asset's folder: read "
                                  "wood.png, beside the model"));
        SC_CHECK(warning_has(ctx, "m.mtl:3: '../gone/glow.png' is outside the asset's folder: read glow.png"));
        sc_ctx_free(ctx);
    }
    sc_test_system("rm -f '%s/wood.png'", dir);
    ctx = run_load(path, &err, NULL);
    SC_CHECK(ctx == NULL && message_has(&err, "'C:/Users/me/Desktop/wood.png' is an absolute path"));
    sc_test_system("rm -rf '%s'", dir);
    free(path), free(dir);
}

SC_TEST(seam_and_boundary_edges) {
    char *path = data_path("seam.obj");
    sc_error err = {0};
    sc_ctx *ctx = run_load(path, &err, NULL);
    SC_CHECK_MSG(ctx != NULL, "%s", err.message);
    if (ctx) {
        SC_CHECK_NEAR(sc_ctx_metric_value(ctx, "seam_edges"), 1, 0);
        SC_CHECK_NEAR(sc_ctx_metric_value(ctx, "boundary_edges"), 4, 0);
        SC_CHECK_NEAR(sc_ctx_metric_value(ctx, "uv_vertices"), 6, 0);
        SC_CHECK_NEAR(sc_ctx_metric_value(ctx, "textures"), 0, 0);
        sc_ctx_free(ctx);
    }
    free(path);
}

/* ---------------------------------------------------------------- save -> load */

/* An atlas with awkward doubles, two materials and two textures. */
static sc_value *make_atlas(void) {
    int n = 6;   /* grid of n x n quads */
    sc_mesh *m = sc_mesh_alloc((n + 1) * (n + 1), (n + 1) * (n + 1), 0, 2 * n * n, 2);
    m->materials[0] = sc_strdup("skin one");   /* a space: written file-safe */
    m->materials[1] = sc_strdup("eyes");
    for (int j = 0; j <= n; j++)
        for (int i = 0; i <= n; i++) {
            int k = j * (n + 1) + i;
            m->V[3 * k] = i / 3.0 + 1e-17 * j;
            m->V[3 * k + 1] = sin(j * 0.731) * 1e-3;
            m->V[3 * k + 2] = -j / 7.0 + (i == 2 ? 0x1p-1074 : 0);   /* a subnormal */
            m->U[2 * k] = i / (double)n * 0.999999999999;
            m->U[2 * k + 1] = 1.0 / (3 + j);
        }
    int f = 0;
    for (int j = 0; j < n; j++)
        for (int i = 0; i < n; i++) {
            int a = j * (n + 1) + i, b = a + 1, c = a + n + 1, d = c + 1;
            int tri[2][3] = {{a, b, d}, {a, d, c}};
            for (int t = 0; t < 2; t++, f++) {
                for (int k = 0; k < 3; k++) m->FV[3 * f + k] = m->FU[3 * f + k] = tri[t][k];
                m->FM[f] = (i + j) % 3 == 1;   /* interleaved materials */
            }
        }
    sc_atlas *a = sc_atlas_new(sc_value_new_mesh(m));
    sc_image_data *im = sc_image_alloc(8, 4, 3, SC_PIXEL_U8);
    for (int k = 0; k < 8 * 4 * 3; k++) ((uint8_t *)im->pixels)[k] = (uint8_t)(k * 37);
    sc_value *image = sc_value_new_image(im);
    sc_atlas_add_texture(a, "color", 0, SC_WRAP_REPEAT, SC_WRAP_REPEAT, "skin.png", sc_value_retain(image));
    sc_atlas_add_texture(a, "color", 1, SC_WRAP_REPEAT, SC_WRAP_REPEAT, "skin.png", image);
    sc_image_data *nm = sc_image_alloc(4, 4, 3, SC_PIXEL_U16);
    for (int k = 0; k < 4 * 4 * 3; k++) ((uint16_t *)nm->pixels)[k] = (uint16_t)(k * 1111);
    nm->colorspace = SC_COLOR_DATA;
    sc_atlas_add_texture(a, "normal", 0, SC_WRAP_REPEAT, SC_WRAP_REPEAT, "n.png", sc_value_new_image(nm));
    return sc_value_new_atlas(a);
}

static void write_report(const sc_report *r, const char *dir) {
    for (int32_t i = 0; i < r->nfiles; i++) {
        char *path = sc_path_join(dir, r->files[i].path);
        sc_error err = {0};
        const sc_bytes *b = r->files[i].bytes->as.bytes;
        SC_CHECK(sc_write_file_atomic(path, b->data, b->size, &err) == SC_OK);
        free(path);
    }
}

static const sc_bytes *report_file(const sc_report *r, const char *path) {
    for (int32_t i = 0; i < r->nfiles; i++)
        if (strcmp(r->files[i].path, path) == 0) return r->files[i].bytes->as.bytes;
    return NULL;
}

/* The .glb read back with the glTF reader: node 0 is the atlas's mesh, face
 * for face (material by material, in face order), positions and uvs the
 * float32 of the source (v stored as 1 - v), its levels named in MSFT_lod,
 * and the embedded images the very bytes of the texture files. */
/* The .gltf's buffer, from the files the save wrote. */
static int read_saved(void *ud, const char *path, sc_buf *out, sc_error *err) {
    const sc_bytes *b = report_file(ud, path);
    if (!b) return sc_fail(err, SC_EINPUT, "%s: not written", path);
    sc_buf_append(out, b->data, b->size);
    return SC_OK;
}

static void check_glb_round_trip(const sc_report *r, const sc_atlas *atlas, bool separate) {
    const char *name = separate ? "thing.gltf" : "thing.glb";
    const sc_bytes *glb = report_file(r, name);
    SC_CHECK_MSG(glb != NULL, "%s not written", name);
    if (!glb) return;
    sc_gltf g;
    sc_error err = {0};
    int rc = sc_gltf_parse(name, glb->data, glb->size, read_saved, (void *)r, &g, &err);
    SC_CHECK_MSG(rc == SC_OK, "%s", err.message);
    if (rc != SC_OK) return;
    const sc_mesh *a = atlas->mesh->as.mesh, *b = g.mesh;
    SC_CHECK_INT(b->nf, a->nf);
    int32_t fb = 0, bad_pos = 0, bad_uv = 0;
    for (int32_t mat = 0; mat < a->nmat; mat++)
        for (int32_t f = 0; f < a->nf && fb < b->nf; f++) {
            if (a->FM[f] != mat) continue;
            for (int c = 0; c < 3; c++) {
                const double *pa = a->V + 3 * a->FV[3 * f + c], *pb = b->V + 3 * b->FV[3 * fb + c];
                const double *ua = a->U + 2 * a->FU[3 * f + c], *ub = b->U + 2 * b->FU[3 * fb + c];
                for (int d = 0; d < 3; d++) bad_pos += pb[d] != (double)(float)pa[d];
                bad_uv += ub[0] != (double)(float)ua[0] || ub[1] != 1.0 - (double)(float)(1.0 - ua[1]);
            }
            fb++;
        }
    SC_CHECK_INT(bad_pos, 0);
    SC_CHECK_INT(bad_uv, 0);
    char *json = sc_strndup((const char *)glb->data + (separate ? 0 : 20), glb->size - (separate ? 0 : 20));
    SC_CHECK(json && strstr(json, "\"MSFT_lod\":{\"ids\":[1,2]}") != NULL);
    SC_CHECK(!separate || (json && strstr(json, "\"buffers\":[{\"uri\":\"thing.bin\",")));
    free(json);
    SC_CHECK_INT(g.ntextures, 3);   /* colour on both materials, normal on one */
    for (int32_t t = 0; t < g.ntextures; t++) {
        const sc_gltf_image *im = &g.images[g.textures[t].image];
        const char *file = strcmp(g.textures[t].slot, "normal") == 0 ? "thing_skin_one_normal.png"
                                                                       : "thing_skin_one_color.png";
        const sc_bytes *png = report_file(r, file);
        if (separate)   /* named, not embedded: the very file written beside it */
            SC_CHECK(png && im->path && !im->data && strcmp(im->path, file) == 0);
        else
            SC_CHECK(png && im->data && im->size == png->size && memcmp(im->data, png->data, png->size) == 0);
    }
    sc_gltf_free(&g);
}

SC_TEST(save_then_load_is_exact) {
    sc_value *atlas = make_atlas();
    sc_lods *l = sc_lods_new();
    sc_lods_add(l, sc_value_retain(atlas));
    sc_lods_add(l, sc_value_retain(atlas));
    sc_value *lods = sc_value_new_lods(l);
    sc_value *inputs[3] = {atlas, lods, NULL};
    sc_ctx *ctx = sc_ctx_new(&sc_node_save, NULL, inputs);
    sc_error err = {0};
    char *glb = NULL;
    size_t glb_size = 0;
    SC_CHECK(sc_ctx_set_param(ctx, "file", "thing", &err) == SC_OK);
    SC_CHECK(sc_ctx_set_param(ctx, "exr_too", "true", &err) == SC_OK);
    int rc = sc_ctx_run(ctx, &err);
    SC_CHECK_MSG(rc == SC_OK, "%s", err.message);
    char *dir = sc_test_tempdir("save");
    if (rc == SC_OK) {
        const sc_report *r = sc_ctx_output(ctx, 0)->as.report;
        /* obj, mtl, 2 lods, shared colour png + exr, normal png + exr, glb */
        SC_CHECK_INT(r->nfiles, 9);
        SC_CHECK(report_file(r, "thing.obj") && report_file(r, "thing.mtl"));
        SC_CHECK(report_file(r, "thing_lod0.obj") && report_file(r, "thing_lod1.obj"));
        SC_CHECK(report_file(r, "thing_skin_one_color.png") && report_file(r, "thing_skin_one_color.exr"));
        SC_CHECK(report_file(r, "thing_skin_one_normal.png"));
        SC_CHECK(!report_file(r, "thing_eyes_color.png"));   /* the same image: written once */
        const sc_bytes *mtl = report_file(r, "thing.mtl");
        if (mtl) {
            char *text = sc_strndup((const char *)mtl->data, mtl->size);
            SC_CHECK(strstr(text, "newmtl skin_one\n") && strstr(text, "map_Kd thing_skin_one_color.png\n"));
            SC_CHECK(strstr(text, "map_Bump thing_skin_one_normal.png\n"));
            SC_CHECK(strstr(text, "newmtl eyes\nKd 1 1 1\nmap_Kd thing_skin_one_color.png\n"));
            free(text);
        }
        check_glb_round_trip(r, atlas->as.atlas, false);
        write_report(r, dir);
        const sc_bytes *g = report_file(r, "thing.glb");
        glb = g ? malloc(g->size + 1) : NULL;
        if (glb) memcpy(glb, g->data, g->size), glb[g->size] = 0, glb_size = g->size;
    }
    sc_ctx_free(ctx);
    /* obj = false: the .glb alone, the very bytes (its images are the PNG
     * files above, named so), and its textures measured as those files */
    ctx = sc_ctx_new(&sc_node_save, NULL, inputs);
    SC_CHECK(sc_ctx_set_param(ctx, "file", "thing", &err) == SC_OK);
    SC_CHECK(sc_ctx_set_param(ctx, "obj", "false", &err) == SC_OK);
    rc = sc_ctx_run(ctx, &err);
    SC_CHECK_MSG(rc == SC_OK, "%s", err.message);
    if (rc == SC_OK) {
        const sc_report *r = sc_ctx_output(ctx, 0)->as.report;
        const sc_bytes *g = report_file(r, "thing.glb");
        SC_CHECK_INT(r->nfiles, 1);
        SC_CHECK(g && glb && g->size == glb_size && memcmp(g->data, glb, glb_size) == 0);
        SC_CHECK(glb && strstr(glb + 20, "\"name\":\"thing_skin_one_color.png\""));   /* in the JSON chunk */
        SC_CHECK(isfinite(sc_ctx_metric_value(ctx, "thing_skin_one_normal.png.seam_energy")));
    }
    sc_ctx_free(ctx);
    ctx = sc_ctx_new(&sc_node_save, NULL, inputs);
    SC_CHECK(sc_ctx_set_param(ctx, "obj", "false", &err) == SC_OK);
    SC_CHECK(sc_ctx_set_param(ctx, "glb", "false", &err) == SC_OK);
    SC_CHECK(sc_ctx_run(ctx, &err) != SC_OK && message_has(&err, "nothing would hold the mesh"));
    sc_ctx_free(ctx);
    free(glb);
    /* .gltf + .bin in place of the .glb: the same document, its buffer beside it and the
     * textures by name; the buffer is the .glb's chunk less the embedded images */
    ctx = sc_ctx_new(&sc_node_save, NULL, inputs);
    SC_CHECK(sc_ctx_set_param(ctx, "file", "thing", &err) == SC_OK);
    SC_CHECK(sc_ctx_set_param(ctx, "gltf_form", "gltf", &err) == SC_OK);
    rc = sc_ctx_run(ctx, &err);
    SC_CHECK_MSG(rc == SC_OK, "%s", err.message);
    if (rc == SC_OK) {
        const sc_report *r = sc_ctx_output(ctx, 0)->as.report;
        SC_CHECK_INT(r->nfiles, 8);   /* obj, mtl, 2 lods, 2 png, gltf, bin */
        SC_CHECK(report_file(r, "thing.bin") && !report_file(r, "thing.glb"));
        check_glb_round_trip(r, atlas->as.atlas, true);
    }
    sc_ctx_free(ctx);
    const char *files[] = {"thing.obj", "thing_lod1.obj"};
    for (int i = 0; i < 2; i++) {
        char *path = sc_path_join(dir, files[i]);
        ctx = run_load(path, &err, NULL);
        SC_CHECK_MSG(ctx != NULL, "%s", err.message);
        if (ctx) {
            const sc_atlas *back = atlas_of(ctx);
            const sc_mesh *a = atlas->as.atlas->mesh->as.mesh, *b = back->mesh->as.mesh;
            SC_CHECK(a->nv == b->nv && a->nu == b->nu && a->nf == b->nf);
            SC_CHECK_MSG(memcmp(a->V, b->V, sizeof(double) * 3 * a->nv) == 0, "V differs");
            SC_CHECK_MSG(memcmp(a->U, b->U, sizeof(double) * 2 * a->nu) == 0, "U differs");
            SC_CHECK(memcmp(a->FV, b->FV, sizeof(int32_t) * 3 * a->nf) == 0);
            SC_CHECK(memcmp(a->FU, b->FU, sizeof(int32_t) * 3 * a->nf) == 0);
            SC_CHECK_STR(b->materials[0], "skin_one");
            SC_CHECK_INT(back->ntex, 3);
            for (int t = 0; t < back->ntex; t++) {
                const sc_texture *tb = &back->textures[t];
                int k = sc_atlas_find_texture(atlas->as.atlas, tb->material, tb->name);
                SC_CHECK(k >= 0);
                if (k < 0) continue;
                const sc_image_data *x = atlas->as.atlas->textures[k].image->as.image, *y = tb->image->as.image;
                SC_CHECK(x->pixel == y->pixel && x->width == y->width && x->channels == y->channels);
                SC_CHECK(memcmp(x->pixels, y->pixels, (size_t)x->width * x->height * x->channels * x->pixel) == 0);
            }
            sc_ctx_free(ctx);
        }
        free(path);
    }
    /* bad names and nothing to save */
    ctx = sc_ctx_new(&sc_node_save, NULL, inputs);
    SC_CHECK(sc_ctx_set_param(ctx, "file", "../evil", &err) != SC_OK &&
             message_has(&err, "save:file: '../evil' is not a plain file name"));
    sc_ctx_free(ctx);
    ctx = sc_ctx_new(&sc_node_save, NULL, NULL);
    SC_CHECK(sc_ctx_run(ctx, &err) != SC_OK && message_has(&err, "nothing to save"));
    sc_ctx_free(ctx);
    /* an image alone, float -> exr by default, png when asked */
    sc_image_data *f = sc_image_alloc(3, 3, 1, SC_PIXEL_F32);
    sc_value *image = sc_value_new_image(f);
    sc_value *only_image[3] = {NULL, NULL, image};
    ctx = sc_ctx_new(&sc_node_save, NULL, only_image);
    SC_CHECK(sc_ctx_run(ctx, &err) == SC_OK);
    if (sc_ctx_output(ctx, 0)) SC_CHECK(report_file(sc_ctx_output(ctx, 0)->as.report, "asset.exr") != NULL);
    sc_ctx_free(ctx);
    ctx = sc_ctx_new(&sc_node_save, NULL, only_image);
    SC_CHECK(sc_ctx_set_param(ctx, "format", "png", &err) == SC_OK);
    SC_CHECK(sc_ctx_run(ctx, &err) == SC_OK);
    if (sc_ctx_output(ctx, 0)) SC_CHECK(report_file(sc_ctx_output(ctx, 0)->as.report, "asset.png") != NULL);
    sc_ctx_free(ctx);
    sc_value_release(image);
    sc_value_release(lods);
    sc_value_release(atlas);
    sc_test_system("rm -rf '%s'", dir);
    free(dir);
}

/* ---------------------------------------------------------------- corpus */

SC_TEST(corpus_objs_match_their_stats) {
    const char *corpus = sc_test_corpus();
    if (!corpus) {
        printf("corpus absent, skipped\n");
        return;
    }
    static const struct {
        const char *asset, *file, *texture;
    } assets[] = {
        {"spot", "spot_triangulated.obj", "spot_texture.png"},
        {"blub", "blub.obj", "blub_texture.png"},
        {"pizza", "pizza.obj", "pizza_gloss_map.jpg"},
        {"Avocado", "Avocado_welded.obj", NULL},
        {"BoomBox", "BoomBox_welded.obj", NULL},
        {"Duck", "Duck_welded.obj", NULL},
        {"Lantern", "Lantern_welded.obj", NULL},
        {"MuruCat", "MuruCat_welded.obj", NULL},
        {"Suzanne", "Suzanne_welded.obj", NULL},
        {"WaterBottle", "WaterBottle_welded.obj", NULL},
    };
    static const char *const keys[] = {"tris", "verts3d", "uvverts", "seam_edges", "boundary_edges"};
    static const char *const metrics[] = {"faces", "vertices", "uv_vertices", "seam_edges", "boundary_edges"};
    printf("%-24s %7s %7s %7s %6s %6s %4s %8s %8s %8s\n", "asset", "faces", "verts", "uvs", "seams",
           "bound", "tex", "parse s", "decode s", "total s");
    for (size_t i = 0; i < sizeof assets / sizeof assets[0]; i++) {
        char path[4096], texture[4096];
        snprintf(path, sizeof path, "%s/%s/%s", corpus, assets[i].asset, assets[i].file);
        sc_error err = {0};
        sc_ctx *ctx;
        double t0 = sc_now();
        if (assets[i].texture) {
            snprintf(texture, sizeof texture, "%s/%s/%s", corpus, assets[i].asset, assets[i].texture);
            ctx = run_load(path, &err, "texture", texture, NULL);
        } else {
            ctx = run_load(path, &err, NULL);
        }
        double seconds = sc_now() - t0;
        SC_CHECK_MSG(ctx != NULL, "%s: %s", assets[i].file, err.message);
        cJSON *stats = sc_test_corpus_stats(corpus, assets[i].asset);
        SC_CHECK_MSG(stats != NULL, "%s: no stats.json", assets[i].asset);
        if (ctx && stats) {
            for (int k = 0; k < 5; k++)
                SC_CHECK_MSG(sc_ctx_metric_value(ctx, metrics[k]) == sc_test_stat(stats, keys[k]),
                             "%s: %s = %.0f, stats.json %s = %.0f", assets[i].file, metrics[k],
                             sc_ctx_metric_value(ctx, metrics[k]), keys[k], sc_test_stat(stats, keys[k]));
            SC_CHECK(sc_ctx_metric_value(ctx, "textures") >= 1);
            printf("%-24s %7.0f %7.0f %7.0f %6.0f %6.0f %4.0f %8.3f %8.3f %8.3f\n", assets[i].file,
                   sc_ctx_metric_value(ctx, "faces"), sc_ctx_metric_value(ctx, "vertices"),
                   sc_ctx_metric_value(ctx, "uv_vertices"), sc_ctx_metric_value(ctx, "seam_edges"),
                   sc_ctx_metric_value(ctx, "boundary_edges"), sc_ctx_metric_value(ctx, "textures"),
                   sc_ctx_metric_value(ctx, "seconds_parse"), sc_ctx_metric_value(ctx, "seconds_decode"),
                   seconds);
        }
        cJSON_Delete(stats);
        sc_ctx_free(ctx);
    }
}

SC_TEST(corpus_save_round_trip) {
    const char *corpus = sc_test_corpus();
    if (!corpus) {
        printf("corpus absent, skipped\n");
        return;
    }
    char path[4096], texture[4096];
    snprintf(path, sizeof path, "%s/pizza/pizza.obj", corpus);
    snprintf(texture, sizeof texture, "%s/pizza/pizza_gloss_map.jpg", corpus);
    sc_error err = {0};
    sc_ctx *load = run_load(path, &err, "texture", texture, NULL);
    SC_CHECK_MSG(load != NULL, "%s", err.message);
    if (!load) return;
    sc_value *atlas = sc_ctx_output(load, 0);
    sc_value *inputs[3] = {atlas, NULL, NULL};
    sc_ctx *save = sc_ctx_new(&sc_node_save, NULL, inputs);
    double t0 = sc_now();
    int rc = sc_ctx_run(save, &err);
    double seconds = sc_now() - t0;
    SC_CHECK_MSG(rc == SC_OK, "%s", err.message);
    if (rc == SC_OK) {
        const sc_report *r = sc_ctx_output(save, 0)->as.report;
        const sc_bytes *obj_bytes = report_file(r, "asset.obj");
        /* a JPEG input is written as PNG, every decoded byte kept */
        SC_CHECK(report_file(r, "asset_default_color.jpg") == NULL);
        const sc_bytes *png = report_file(r, "asset_default_color.png");
        sc_image_data *back = NULL;
        SC_CHECK_MSG(png && sc_image_decode("asset_default_color.png", png->data, png->size, &back, &err) == SC_OK,
                     "%s", err.message);
        const sc_image_data *in = atlas->as.atlas->textures[0].image->as.image;
        SC_CHECK(back && back->width == in->width && back->height == in->height && back->channels == in->channels &&
                 back->pixel == in->pixel &&
                 memcmp(back->pixels, in->pixels, (size_t)in->width * in->height * in->channels) == 0);
        sc_image_free(back);
        sc_obj obj;
        SC_CHECK(obj_bytes && sc_obj_parse("asset.obj", obj_bytes->data, obj_bytes->size, NULL, NULL, &obj, &err) == SC_OK);
        const sc_mesh *a = atlas->as.atlas->mesh->as.mesh;
        if (obj_bytes && obj.mesh) {
            SC_CHECK(obj.mesh->nv == a->nv && obj.mesh->nu == a->nu && obj.mesh->nf == a->nf);
            SC_CHECK(memcmp(obj.mesh->V, a->V, sizeof(double) * 3 * a->nv) == 0);
            SC_CHECK(memcmp(obj.mesh->U, a->U, sizeof(double) * 2 * a->nu) == 0);
            SC_CHECK(memcmp(obj.mesh->FU, a->FU, sizeof(int32_t) * 3 * a->nf) == 0);
            sc_obj_free(&obj);
        }
        printf("pizza: save (OBJ %.1f MB + 4096^2 PNG) %.3f s\n", obj_bytes ? obj_bytes->size / 1e6 : 0, seconds);
    }
    sc_ctx_free(save);
    sc_ctx_free(load);
}

int main(void) { return sc_test_main(); }
