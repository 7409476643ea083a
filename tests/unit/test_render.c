/* test_render.c - the node `render`: GPU seam gaps, crack pixels, open meshes
 * against a reference, limits that fail the cook, skipped modes, and
 * byte-identical pictures from run to run and thread to thread.
 *
 * The assets are made here. The main one is a flat cube (six faces, each an
 * n x n grid and its own uv chart with padding), because on it every chart's
 * map uv -> position is affine: its geometry image, rasterised at texel
 * centres with the padding extrapolated, is reproduced exactly by bilinear
 * filtering, so the seam gap of a correct renderer is float rounding only.
 * Variants add a per-chart offset to the geometry image or the displacement
 * (real seams), split one face off and shrink it (a real crack), or drop a
 * face (an open mesh). Levels of detail of the flat cube are the same cube
 * with a coarser grid and the very same textures.
 */
#include <math.h>
#include <pthread.h>
#include <stdlib.h>
#include <string.h>

#include "sc_exec.h"
#include "sc_imageio.h"
#include "sc_nodes.h"
#include "sc_test.h"

extern const sc_node_desc sc_node_render;   /* nodes/render.c */

/* ---------------------------------------------------------------- the flat cube */

enum {
    CUBE_GI_SEAMS = 1,     /* per-chart offset in the geometry image */
    CUBE_DISP_SEAMS = 2,   /* per-chart offset in the displacement */
    CUBE_SPLIT = 4,        /* face 0 has its own vertices, slid by 0.08 along y */
    CUBE_OPEN = 8,         /* face 0 removed */
    CUBE_NO_POSITIONS = 16,/* colour texture only */
    CUBE_HAIRLINE = 32,    /* with CUBE_GI_SEAMS: a tenth of the offset */
    CUBE_FOLD = 64         /* one cell of face 1 (x = -1) turned over (its two triangles
                              wound the other way): a fold, the same topology */
};

static const int face_origin[6][3] = {{1, 0, 0}, {0, 0, 0}, {0, 1, 0}, {0, 0, 0}, {0, 0, 1}, {0, 0, 0}};
static const int face_a[6][3] = {{0, 1, 0}, {0, 0, 1}, {0, 0, 1}, {1, 0, 0}, {1, 0, 0}, {0, 1, 0}};
static const int face_b[6][3] = {{0, 0, 1}, {0, 1, 0}, {1, 0, 0}, {0, 0, 1}, {0, 1, 0}, {1, 0, 0}};

#define CELL 32   /* texels per chart cell; the texture is 3 x 2 cells */
#define PAD 3     /* texels of padding on each side of a chart */

/* Point of face f at chart coordinates (a, b) (any reals: the plane extends). */
static void cube_point(int f, double a, double b, double out[3]) {
    for (int k = 0; k < 3; k++)
        out[k] = 2.0 * (face_origin[f][k] + a * face_a[f][k] + b * face_b[f][k]) - 1.0;
}

static void chart_uv(int f, double a, double b, double uv[2]) {
    double side = CELL - 2 * PAD;
    uv[0] = ((f % 3) * CELL + PAD + a * side) / (3.0 * CELL);
    uv[1] = ((f / 3) * CELL + PAD + b * side) / (2.0 * CELL);
}

static sc_value *image_value(sc_image_data *im) { return im ? sc_value_new_image(im) : NULL; }

/* The three textures of the flat cube, shared by all its levels. */
typedef struct cube_textures {
    sc_value *color, *geometry, *displacement;
} cube_textures;

static cube_textures cube_textures_make(int flags) {
    int w = 3 * CELL, h = 2 * CELL;
    sc_image_data *color = sc_image_alloc(w, h, 3, SC_PIXEL_U8);
    sc_image_data *geom = sc_image_alloc(w, h, 3, SC_PIXEL_F32);
    sc_image_data *disp = sc_image_alloc(w, h, 4, SC_PIXEL_F32);
    SC_CHECK(color && geom && disp);
    color->colorspace = SC_COLOR_SRGB;
    geom->colorspace = disp->colorspace = SC_COLOR_DATA;
    double side = CELL - 2 * PAD;
    for (int j = 0; j < h; j++)
        for (int i = 0; i < w; i++) {
            int f = i / CELL + 3 * (j / CELL);
            double a = (i + 0.5 - ((f % 3) * CELL + PAD)) / side, b = (j + 0.5 - ((f / 3) * CELL + PAD)) / side;
            double p[3];
            cube_point(f, a, b, p);
            size_t t = (size_t)j * w + i;
            uint8_t *c = (uint8_t *)color->pixels + 3 * t;
            int check = ((int)floor(a * 4) + (int)floor(b * 4)) & 1;
            c[0] = (uint8_t)(90 + 25 * f + 40 * check);
            c[1] = (uint8_t)(200 - 20 * f);
            c[2] = (uint8_t)(120 + 50 * check);
            float *g = (float *)geom->pixels + 3 * t, *d = (float *)disp->pixels + 4 * t;
            double off_g = (flags & CUBE_GI_SEAMS) ? ((flags & CUBE_HAIRLINE) ? 0.002 : 0.02) * (f + 1) : 0.0;
            double off_d = (flags & CUBE_DISP_SEAMS) ? 0.02 * (f + 1) : 0.0;
            for (int k = 0; k < 3; k++) {
                g[k] = (float)(p[k] + off_g);
                d[k] = (float)(0.25 * p[k] + off_d);   /* affine: the cube grows by a quarter */
            }
            d[3] = 1.0f;
        }
    cube_textures t = {image_value(color), image_value(geom), image_value(disp)};
    SC_CHECK(t.color && t.geometry && t.displacement);
    return t;
}

static void cube_textures_free(cube_textures *t) {
    sc_value_release(t->color);
    sc_value_release(t->geometry);
    sc_value_release(t->displacement);
}

static int lattice_index(int n, int f, int a, int b) {
    int m = n + 1, l[3];
    for (int k = 0; k < 3; k++) l[k] = face_origin[f][k] * n + a * face_a[f][k] + b * face_b[f][k];
    return (l[0] * m + l[1]) * m + l[2];
}

static sc_value *cube_atlas(int n, int flags, const cube_textures *tex) {
    int m = n + 1;
    int *vertex_of = malloc(sizeof(int) * (size_t)m * m * m);
    for (int i = 0; i < m * m * m; i++) vertex_of[i] = -1;
    int nv_max = 6 * m * m, nf = 12 * n * n - ((flags & CUBE_OPEN) ? 2 * n * n : 0);
    sc_mesh *mesh = sc_mesh_alloc(nv_max, 6 * m * m, 0, nf, 1);
    mesh->materials[0] = sc_strdup("cube");
    int nv = 0, face = 0;
    int *local = malloc(sizeof(int) * (size_t)m * m);
    for (int f = 0; f < 6; f++) {
        for (int b = 0; b <= n; b++)
            for (int a = 0; a <= n; a++) {
                int li = lattice_index(n, f, a, b), vi;
                if (f == 0 && (flags & CUBE_SPLIT)) {
                    vi = nv++;
                    cube_point(f, (double)a / n, (double)b / n, mesh->V + 3 * vi);
                    mesh->V[3 * vi + 1] += 0.08;   /* slide along y: a slit opens at y = -1 */
                } else {
                    if (vertex_of[li] < 0) {
                        vertex_of[li] = nv++;
                        cube_point(f, (double)a / n, (double)b / n, mesh->V + 3 * vertex_of[li]);
                    }
                    vi = vertex_of[li];
                }
                local[b * m + a] = vi;
                chart_uv(f, (double)a / n, (double)b / n, mesh->U + 2 * (f * m * m + b * m + a));
            }
        if (f == 0 && (flags & CUBE_OPEN)) continue;
        for (int b = 0; b < n; b++)
            for (int a = 0; a < n; a++) {
                int c[4][2] = {{a, b}, {a + 1, b}, {a + 1, b + 1}, {a, b + 1}};
                bool turned = (flags & CUBE_FOLD) && f == 1 && a == n / 2 && b == n / 2;
                int tri[2][3] = {{0, 1, 2}, {0, 2, 3}};
                if (turned) tri[0][1] = 2, tri[0][2] = 1, tri[1][1] = 3, tri[1][2] = 2;
                for (int t = 0; t < 2; t++, face++)
                    for (int k = 0; k < 3; k++) {
                        int q = tri[t][k];
                        mesh->FV[3 * face + k] = local[c[q][1] * m + c[q][0]];
                        mesh->FU[3 * face + k] = f * m * m + c[q][1] * m + c[q][0];
                    }
            }
    }
    free(local);
    free(vertex_of);
    mesh->nv = nv;   /* the unused tail of V is never referenced */
    SC_CHECK_INT(face, nf);
    sc_atlas *a = sc_atlas_new(sc_value_new_mesh(mesh));
    sc_atlas_add_texture(a, "color", 0, SC_WRAP_REPEAT, SC_WRAP_REPEAT, "cube.png", sc_value_retain(tex->color));
    if (!(flags & CUBE_NO_POSITIONS)) {
        sc_atlas_add_texture(a, "geometry_image", 0, SC_WRAP_CLAMP, SC_WRAP_CLAMP, "",
                             sc_value_retain(tex->geometry));
        sc_atlas_add_texture(a, "displacement", 0, SC_WRAP_CLAMP, SC_WRAP_CLAMP, "",
                             sc_value_retain(tex->displacement));
    }
    return sc_value_new_atlas(a);
}

static sc_value *lods_of(sc_value *const *levels, int n) {
    sc_lods *l = sc_lods_new();
    for (int i = 0; i < n; i++) sc_lods_add(l, sc_value_retain(levels[i]));
    return sc_value_new_lods(l);
}

/* ---------------------------------------------------------------- running render */

typedef struct run_result {
    int rc;
    sc_error err;
    sc_ctx *ctx;
    sc_value *report;   /* borrowed from ctx */
} run_result;

/* params: "name", "value", ..., NULL */
static run_result render(sc_value *lods, sc_value *atlas, sc_value *reference, const char *const *params) {
    run_result r = {0};
    r.ctx = sc_ctx_new(&sc_node_render, NULL, NULL);
    sc_error pe;
    SC_CHECK(sc_ctx_set_param(r.ctx, "pictures", "all", &pe) == SC_OK);   /* every picture, unless params say */
    if (lods) sc_ctx_set_input(r.ctx, "lods", lods);
    if (atlas) sc_ctx_set_input(r.ctx, "atlas", atlas);
    if (reference) sc_ctx_set_input(r.ctx, "reference", reference);
    for (int i = 0; params && params[i]; i += 2) {
        sc_error e;
        int rc = sc_ctx_set_param(r.ctx, params[i], params[i + 1], &e);
        SC_CHECK_MSG(rc == SC_OK, "set %s: %s", params[i], e.message);
    }
    r.rc = sc_ctx_run(r.ctx, &r.err);
    if (r.rc == SC_OK) r.report = sc_ctx_output(r.ctx, 0);
    return r;
}

static double M(const run_result *r, const char *name) { return sc_ctx_metric_value(r->ctx, name); }

static const sc_report *report_of(const run_result *r) { return r->report ? r->report->as.report : NULL; }

static bool has_file(const run_result *r, const char *path) {
    const sc_report *rep = report_of(r);
    for (int i = 0; rep && i < rep->nfiles; i++)
        if (strcmp(rep->files[i].path, path) == 0) return true;
    return false;
}

/* Pixels of colour rgb in a PNG file of the run's report (-1 if absent). */
static int64_t pixels_of_colour(const run_result *r, const char *path, const uint8_t rgb[3]) {
    const sc_report *rep = report_of(r);
    for (int i = 0; rep && i < rep->nfiles; i++) {
        if (strcmp(rep->files[i].path, path) != 0) continue;
        const sc_bytes *b = rep->files[i].bytes->as.bytes;
        sc_image_data *im = NULL;
        sc_error e = {0};
        if (sc_image_decode(path, b->data, b->size, &im, &e) != SC_OK) return -1;
        int64_t n = 0;
        for (int64_t k = 0; k < (int64_t)im->width * im->height; k++) {
            const uint8_t *px = (const uint8_t *)im->pixels + (size_t)k * (size_t)im->channels;
            n += px[0] == rgb[0] && px[1] == rgb[1] && px[2] == rgb[2];
        }
        sc_image_free(im);
        return n;
    }
    return -1;
}

/* The marks render puts on its contact sheets. */
static const uint8_t yellow[3] = {255, 230, 0}, cyan[3] = {0, 200, 255};

/* ---------------------------------------------------------------- tests */

static const char *const small[] = {"size", "128", "views", "10", "tess_levels", "1,2,4,8", NULL};

/* pictures = sheets (the default): a contact sheet and the uv picture per
 * LOD, and a view's own picture only where it has crack candidates. */
SC_TEST(default_pictures_are_sheets_and_failing_views) {
    cube_textures tex = cube_textures_make(0);
    sc_value *cube = cube_atlas(4, 0, &tex);
    run_result r = render(NULL, cube, NULL, (const char *const[]){"size", "64", "views", "6", "pictures", "sheets", NULL});
    SC_CHECK_MSG(r.rc == SC_OK, "%s", r.err.message);
    SC_CHECK(M(&r, "crack_pixels") == 0);
    SC_CHECK(has_file(&r, "render/lod0_sheet.png") && has_file(&r, "render/lod0_uv.png"));
    SC_CHECK(!has_file(&r, "render/lod0_textured_posx.png"));
    SC_CHECK_INT(report_of(&r)->nfiles, 2);
    sc_ctx_free(r.ctx);
    /* an open cube without a reference: the views looking into the hole have crack pixels */
    sc_value *open = cube_atlas(4, CUBE_OPEN, &tex);
    r = render(NULL, open, NULL, (const char *const[]){"size", "64", "views", "6", "pictures", "sheets", NULL});
    SC_CHECK_MSG(r.rc == SC_OK, "%s", r.err.message);
    /* the pictures written show back faces (pure red), the others are left out */
    int failing = 0, written = 0;
    static const char *const names[6] = {"posx", "negx", "posy", "negy", "posz", "negz"};
    const sc_report *rep = report_of(&r);
    for (int i = 0; rep && i < rep->nfiles; i++)
        for (int v = 0; v < 6; v++) {
            char path[96];
            snprintf(path, sizeof path, "render/lod0_textured_%s.png", names[v]);
            if (strcmp(rep->files[i].path, path) != 0) continue;
            written++;
            const sc_bytes *b = rep->files[i].bytes->as.bytes;
            sc_image_data *im = NULL;
            sc_error e = {0};
            if (sc_image_decode(path, b->data, b->size, &im, &e) != SC_OK) continue;
            int64_t red = 0;
            for (int64_t k = 0; k < (int64_t)im->width * im->height; k++) {
                const uint8_t *px = (const uint8_t *)im->pixels + (size_t)k * (size_t)im->channels;
                red += px[0] == 255 && px[1] == 0 && px[2] == 0;
            }
            failing += red > 0;
            sc_image_free(im);
        }
    SC_CHECK_MSG(written > 0 && written < 6 && failing == written, "%d views written, %d showing back faces", written,
                 failing);
    sc_ctx_free(r.ctx);
    sc_value_release(open);
    sc_value_release(cube);
    cube_textures_free(&tex);
}

SC_TEST(seam_free_geometry_image_has_no_gap) {
    cube_textures tex = cube_textures_make(0);
    sc_value *cube = cube_atlas(4, 0, &tex);
    run_result r = render(NULL, cube, NULL, small);
    SC_CHECK_MSG(r.rc == SC_OK, "%s", r.err.message);
    const char *modes[] = {"textured", "geometry_image", "displaced", "tessellated1", "tessellated2",
                           "tessellated4", "tessellated8"};
    for (int i = 0; i < 7; i++) {
        char name[96];
        snprintf(name, sizeof name, "lod0.%s.max_seam_gap", modes[i]);
        SC_CHECK_MSG(M(&r, name) <= 1e-6, "%s = %g", name, M(&r, name));
        snprintf(name, sizeof name, "lod0.%s.crack_pixels", modes[i]);
        SC_CHECK_MSG(M(&r, name) == 0, "%s = %g", name, M(&r, name));
        /* the maps' own gap, sampled in double: the charts meet exactly */
        snprintf(name, sizeof name, "lod0.%s.map_seam_gap", modes[i]);
        if (i == 0) SC_CHECK_MSG(isnan(M(&r, name)), "%s = %g (base positions have no map)", name, M(&r, name));
        else SC_CHECK_MSG(M(&r, name) <= 1e-12, "%s = %g", name, M(&r, name));
    }
    SC_CHECK(M(&r, "crack_pixels") == 0);
    SC_CHECK(M(&r, "max_seam_gap") <= 1e-6);
    SC_CHECK(M(&r, "lod0.closed") == 1);
    SC_CHECK(M(&r, "lod0.seam_edges") == 12 * 4);
    SC_CHECK(M(&r, "lod0.tessellated.source") == 1);
    SC_CHECK(M(&r, "renders") == 70);
    SC_CHECK(has_file(&r, "render/lod0_textured_posx.png"));
    SC_CHECK(has_file(&r, "render/lod0_tessellated8_obl3.png"));
    SC_CHECK(has_file(&r, "render/lod0_sheet.png"));
    SC_CHECK(has_file(&r, "render/lod0_uv.png"));
    SC_CHECK(!has_file(&r, "render/lod0_textured_obl4.png"));
    SC_CHECK_INT(report_of(&r)->nfiles, 70 + 2);
    sc_ctx_free(r.ctx);
    sc_value_release(cube);
    cube_textures_free(&tex);
}

/* More seam faces than one capture draw holds (1,440 > 1,365): every seam
 * side still finds its own tessellated vertices, so no gap appears. */
SC_TEST(many_seam_patches_are_captured_in_several_draws) {
    cube_textures tex = cube_textures_make(0);
    sc_value *cube = cube_atlas(60, 0, &tex);
    run_result r = render(NULL, cube, NULL,
                          (const char *const[]){"size", "64", "views", "1", "tess_levels", "1",
                                                "modes", "tessellated", NULL});
    SC_CHECK_MSG(r.rc == SC_OK, "%s", r.err.message);
    SC_CHECK(M(&r, "lod0.seam_edges") == 12 * 60);
    SC_CHECK_MSG(M(&r, "lod0.tessellated1.max_seam_gap") <= 1e-6, "gap %g", M(&r, "lod0.tessellated1.max_seam_gap"));
    sc_ctx_free(r.ctx);
    sc_value_release(cube);
    cube_textures_free(&tex);
}

SC_TEST(geometry_image_with_seams_has_gap_and_cracks) {
    cube_textures tex = cube_textures_make(CUBE_GI_SEAMS | CUBE_DISP_SEAMS);
    sc_value *cube = cube_atlas(4, 0, &tex);
    run_result r = render(NULL, cube, NULL, small);
    SC_CHECK_MSG(r.rc == SC_OK, "%s", r.err.message);
    /* neighbouring charts are offset by 0.02 per axis: 0.0346 / diagonal 3.46 */
    SC_CHECK_MSG(M(&r, "lod0.geometry_image.max_seam_gap") > 1e-3, "%g", M(&r, "lod0.geometry_image.max_seam_gap"));
    SC_CHECK_NEAR(M(&r, "lod0.geometry_image.max_seam_gap"), 0.02 * 5 * sqrt(3.0) / (2 * sqrt(3.0)), 1e-5);
    /* the maps' own gap is that offset too, as float32 texels hold it: it is
     * in the maps */
    SC_CHECK_NEAR(M(&r, "lod0.geometry_image.map_seam_gap"), 0.02 * 5 * sqrt(3.0) / (2 * sqrt(3.0)), 1e-7);
    SC_CHECK(M(&r, "lod0.tessellated4.map_seam_gap") > 1e-3);
    SC_CHECK(M(&r, "lod0.geometry_image.max_vertex_gap") > 1e-3);
    SC_CHECK(M(&r, "lod0.displaced.max_seam_gap") > 1e-3);
    SC_CHECK(M(&r, "lod0.tessellated4.max_seam_gap") > 1e-3);
    SC_CHECK(M(&r, "lod0.geometry_image.crack_pixels") > 0);
    SC_CHECK(M(&r, "lod0.displaced.crack_pixels") > 0);
    SC_CHECK(M(&r, "lod0.tessellated2.crack_pixels") > 0);
    SC_CHECK(M(&r, "lod0.textured.max_seam_gap") == 0);
    SC_CHECK(M(&r, "lod0.textured.crack_pixels") == 0);
    sc_ctx_free(r.ctx);
    sc_value_release(cube);
    cube_textures_free(&tex);
}

/* The flat cube's geometry image with two texels moved by `by` in z: those
 * on both sides of face 0's chart border b = 0 (x = 1, its seam with face 5,
 * z = -1) halfway along that border's third edge (a = 5/16) of the 8 x 8
 * grid, which the tessellated points of level 1 (the edge's ends) do not
 * reach and those of level 8 do. Moved up (+z), face 0 draws back from the
 * seam there and opens a notch onto the cube's inside. */
static cube_textures cube_with_moved_texels(float by) {
    cube_textures t = cube_textures_make(0);
    const sc_image_data *src = t.geometry->as.image;
    sc_image_data *moved = sc_image_alloc(src->width, src->height, src->channels, src->pixel);
    SC_CHECK(moved != NULL);
    if (!moved) return t;
    memcpy(moved->pixels, src->pixels, (size_t)src->width * src->height * src->channels * (size_t)src->pixel);
    moved->colorspace = src->colorspace;
    int32_t i = PAD + (int32_t)floor(0.3125 * (CELL - 2 * PAD)), j = PAD;
    for (int32_t y = j - 1; y <= j; y++)   /* the border row and the padding row below it */
        ((float *)moved->pixels)[((size_t)y * src->width + i) * src->channels + 2] += by;
    sc_value_release(t.geometry);
    t.geometry = sc_value_new_image(moved);
    return t;
}

/* A tessellated level with more triangles than a view has pixels is probed,
 * not drawn, when the seam-gap limit is at or under the rasteriser's vertex
 * grid: its seam gap is still measured at its own points and bounded. The
 * flat cube of 8 x 8 cells a side (768 faces) at 128 x 128 pixels: level 8
 * makes 49,152 triangles, level 1 768. Texels moved beside a seam, which
 * only level 8's points reach: drawn (no gap limit), level 8 shows the
 * crack and level 1 does not; probed (a limit), level 8 fails the node on
 * its gap, without a single view of it drawn. */
SC_TEST(levels_finer_than_the_pixels_are_probed_and_still_fail) {
    const char *drawn[] = {"size", "128", "views", "14", "modes", "tessellated", "tess_levels", "1,8", NULL};
    const char *probed[] = {"size", "128", "views", "14", "modes", "tessellated", "tess_levels", "1,8",
                            "max_seam_gap", "1e-5", NULL};
    cube_textures clean = cube_textures_make(0);
    sc_value *cube = cube_atlas(8, 0, &clean);
    run_result r = render(NULL, cube, NULL, probed);
    SC_CHECK_MSG(r.rc == SC_OK, "%s", r.err.message);
    SC_CHECK(M(&r, "lod0.tessellated1.drawn") == 1 && M(&r, "lod0.tessellated8.drawn") == 0);
    SC_CHECK(M(&r, "renders") == 14);   /* level 1's views only */
    SC_CHECK_MSG(M(&r, "lod0.tessellated8.max_seam_gap") <= 1e-6, "%g", M(&r, "lod0.tessellated8.max_seam_gap"));
    SC_CHECK(isnan(M(&r, "lod0.tessellated8.crack_pixels")));
    SC_CHECK(!has_file(&r, "render/lod0_tessellated8_posx.png"));
    sc_ctx_free(r.ctx);
    /* with no gap limit, or a limit above the vertex grid, every level is drawn */
    r = render(NULL, cube, NULL, drawn);
    SC_CHECK_MSG(r.rc == SC_OK && M(&r, "lod0.tessellated8.drawn") == 1 && M(&r, "renders") == 28, "%s",
                 r.err.message);
    sc_ctx_free(r.ctx);
    const char *coarse_limit[] = {"size", "128", "views", "14", "modes", "tessellated", "tess_levels", "1,8",
                                  "max_seam_gap", "1e-3", NULL};
    r = render(NULL, cube, NULL, coarse_limit);
    SC_CHECK_MSG(r.rc == SC_OK && M(&r, "lod0.tessellated8.drawn") == 1, "%s", r.err.message);
    sc_ctx_free(r.ctx);
    sc_value_release(cube);
    cube_textures_free(&clean);

    cube_textures moved = cube_with_moved_texels(0.3f);
    cube = cube_atlas(8, 0, &moved);
    r = render(NULL, cube, NULL, drawn);
    SC_CHECK_MSG(r.rc == SC_OK, "%s", r.err.message);
    printf("     drawn: level 1 %g crack pixels (gap %.3g), level 8 %g (gap %.3g)\n",
           M(&r, "lod0.tessellated1.crack_pixels"), M(&r, "lod0.tessellated1.max_seam_gap"),
           M(&r, "lod0.tessellated8.crack_pixels"), M(&r, "lod0.tessellated8.max_seam_gap"));
    SC_CHECK(M(&r, "lod0.tessellated1.crack_pixels") == 0 && M(&r, "lod0.tessellated1.max_seam_gap") <= 1e-6);
    SC_CHECK(M(&r, "lod0.tessellated8.crack_pixels") > 0 && M(&r, "lod0.tessellated8.max_seam_gap") > 1e-2);
    sc_ctx_free(r.ctx);
    r = render(NULL, cube, NULL, probed);
    SC_CHECK(r.rc != SC_OK);
    SC_CHECK_MSG(strstr(r.err.message, "max_seam_gap") && strstr(r.err.message, "tessellated8"), "%s",
                 r.err.message);
    sc_ctx_free(r.ctx);
    sc_value_release(cube);
    cube_textures_free(&moved);
}

/* Seams open by less than a pixel still crack, and welding closes them: the
 * crack check draws a pass again with every seam welded shut when its gap
 * is under a pixel, and takes a crack pixel for a fold only if the welded
 * picture shows a back face there too. Here none may be taken. */
SC_TEST(hairline_seams_crack_and_are_no_folds) {
    cube_textures tex = cube_textures_make(CUBE_GI_SEAMS | CUBE_HAIRLINE);
    sc_value *cube = cube_atlas(4, 0, &tex);
    run_result r = render(NULL, cube, NULL,
                          (const char *const[]){"size", "128", "views", "26", "tess_levels", "1,4",
                                                "modes", "geometry_image,tessellated", NULL});
    SC_CHECK_MSG(r.rc == SC_OK, "%s", r.err.message);
    const char *modes[] = {"geometry_image", "tessellated1", "tessellated4"};
    /* pixels per unit: at most 128 / (2 sqrt 3), the views framing at least
     * the cube's bounding sphere; so every gap below is under a pixel */
    double px = 128 / (2 * sqrt(3.0));
    for (int i = 0; i < 3; i++) {
        char name[96];
        snprintf(name, sizeof name, "lod0.%s.max_seam_gap", modes[i]);
        double gap_px = M(&r, name) * 2 * sqrt(3.0) * px;
        SC_CHECK_MSG(gap_px > 0.2 && gap_px < 1, "%s: %g pixels", name, gap_px);
        snprintf(name, sizeof name, "lod0.%s.crack_pixels", modes[i]);
        printf("     %s: gap at most %.2f pixels, %g crack pixels\n", modes[i], gap_px, M(&r, name));
        SC_CHECK_MSG(M(&r, name) > 20, "%s = %g", name, M(&r, name));
        snprintf(name, sizeof name, "lod0.%s.fold_pixels", modes[i]);
        SC_CHECK_MSG(M(&r, name) == 0, "%s = %g", name, M(&r, name));
    }
    sc_ctx_free(r.ctx);
    sc_value_release(cube);
    cube_textures_free(&tex);
}

/* A fold is not a crack: the geometry image of face 0 (x = +1) pushes a disk
 * of texels, far from every seam, through the cube to x = -2.5, so the
 * position modes draw a spike whose back faces stick out of face 3
 * (x = -1). Those back-face pixels lie behind no front face and are not on a
 * contour; they stay when the pass is drawn with every seam welded shut, so
 * they are fold pixels, and the seams, free of gaps, crack nowhere. */
SC_TEST(fold_is_not_a_crack) {
    cube_textures tex = cube_textures_make(0);
    sc_image_data *g = tex.geometry->as.image;
    double side = CELL - 2 * PAD;
    int pushed = 0;
    for (int j = 0; j < CELL; j++)
        for (int i = 0; i < CELL; i++) {
            double a = (i + 0.5 - PAD) / side, b = (j + 0.5 - PAD) / side;
            if ((a - 0.5) * (a - 0.5) + (b - 0.5) * (b - 0.5) > 0.2 * 0.2) continue;
            ((float *)g->pixels)[3 * ((size_t)j * g->width + i)] = -2.5f;
            pushed++;
        }
    SC_CHECK(pushed > 20);
    sc_value *cube = cube_atlas(4, 0, &tex);
    run_result r = render(NULL, cube, NULL,
                          (const char *const[]){"size", "128", "views", "10", "tess_levels", "1,4",
                                                "modes", "textured,geometry_image,tessellated", NULL});
    SC_CHECK_MSG(r.rc == SC_OK, "%s", r.err.message);
    SC_CHECK(M(&r, "lod0.closed") == 1);
    const char *modes[] = {"geometry_image", "tessellated1", "tessellated4"};
    for (int i = 0; i < 3; i++) {
        char name[96];
        snprintf(name, sizeof name, "lod0.%s.fold_pixels", modes[i]);
        SC_CHECK_MSG(M(&r, name) > 10, "%s = %g", name, M(&r, name));
        snprintf(name, sizeof name, "lod0.%s.crack_pixels", modes[i]);
        SC_CHECK_MSG(M(&r, name) == 0, "%s = %g", name, M(&r, name));
        snprintf(name, sizeof name, "lod0.%s.max_seam_gap", modes[i]);
        SC_CHECK_MSG(M(&r, name) <= 1e-6, "%s = %g", name, M(&r, name));
    }
    SC_CHECK(M(&r, "lod0.textured.fold_pixels") == 0 && M(&r, "lod0.textured.crack_pixels") == 0);
    SC_CHECK(M(&r, "crack_pixels") == 0);
    SC_CHECK(M(&r, "fold_pixels") > 30);
    sc_ctx_free(r.ctx);
    /* the maps' folds have their own gate: max_map_fold_pixels catches them,
     * max_fold_pixels (the level's own vertices, none folded) does not */
    const char *const gates[2] = {"max_fold_pixels", "max_map_fold_pixels"};
    for (int gate = 0; gate < 2; gate++) {
        r = render(NULL, cube, NULL,
                   (const char *const[]){"size", "128", "views", "10", "modes", "textured,geometry_image",
                                         gates[gate], "0", NULL});
        SC_CHECK_MSG(gate == 0 ? r.rc == SC_OK
                               : r.rc != SC_OK && strstr(r.err.message, "max_map_fold_pixels: lod 0, mode geometry_image"),
                     "%s: %s", gates[gate], r.err.message);
        sc_ctx_free(r.ctx);
    }
    sc_value_release(cube);
    cube_textures_free(&tex);
}

/* The default procedural sphere at 512^2 once showed one back-face pixel on
 * an occluding contour (view obl3); contours are not cracks. */
SC_TEST(closed_procedural_textured_has_no_cracks) {
    sc_ctx *p = sc_ctx_new(&sc_node_procedural, NULL, NULL);
    sc_error e;
    SC_CHECK(sc_ctx_set_param(p, "texture_size", "256", &e) == SC_OK);
    SC_CHECK(sc_ctx_run(p, &e) == SC_OK);
    sc_value *atlas = sc_ctx_output(p, 0);
    run_result r = render(NULL, atlas, NULL, (const char *const[]){"size", "512", NULL});
    SC_CHECK_MSG(r.rc == SC_OK, "%s", r.err.message);
    SC_CHECK(M(&r, "lod0.textured.crack_pixels") == 0);
    SC_CHECK(M(&r, "lod0.textured.max_seam_gap") == 0);
    SC_CHECK(M(&r, "crack_pixels") == 0);
    /* the procedural asset has a colour texture only */
    SC_CHECK(M(&r, "lod0.geometry_image.skipped") == 1);
    SC_CHECK(M(&r, "lod0.displaced.skipped") == 1);
    SC_CHECK(M(&r, "lod0.tessellated.skipped") == 1);
    SC_CHECK(M(&r, "skipped_modes") == 3);
    SC_CHECK(M(&r, "renders") == 10);
    SC_CHECK(M(&r, "lod0.seam_edges") == 12 * 24);
    sc_ctx_free(r.ctx);
    sc_ctx_free(p);
}

SC_TEST(split_mesh_shows_cracks) {
    cube_textures tex = cube_textures_make(0);
    sc_value *cube = cube_atlas(4, CUBE_SPLIT | CUBE_NO_POSITIONS, &tex);
    run_result r = render(NULL, cube, NULL, (const char *const[]){"size", "128", NULL});
    SC_CHECK_MSG(r.rc == SC_OK, "%s", r.err.message);
    SC_CHECK_MSG(M(&r, "lod0.textured.crack_pixels") > 50, "%g", M(&r, "lod0.textured.crack_pixels"));
    /* split along a boundary: no longer closed */
    SC_CHECK(M(&r, "lod0.closed") == 0);
    double alone = M(&r, "lod0.textured.crack_pixels");
    /* the contact sheet marks them (yellow), and marks no folds */
    SC_CHECK_MSG(pixels_of_colour(&r, "render/lod0_sheet.png", yellow) > 20 &&
                     pixels_of_colour(&r, "render/lod0_sheet.png", cyan) == 0,
                 "yellow %lld, cyan %lld", (long long)pixels_of_colour(&r, "render/lod0_sheet.png", yellow),
                 (long long)pixels_of_colour(&r, "render/lod0_sheet.png", cyan));
    SC_CHECK_INT(M(&r, "lod0.crack_pixels"), alone);
    sc_ctx_free(r.ctx);

    /* against the unsplit cube: a boundary the reference lacks, so the
     * textured pass's gap of 0 hides nothing */
    sc_value *whole = cube_atlas(4, CUBE_NO_POSITIONS, &tex);
    r = render(NULL, cube, whole, (const char *const[]){"size", "128", NULL});
    SC_CHECK_MSG(r.rc == SC_OK, "%s", r.err.message);
    SC_CHECK(M(&r, "lod0.same_topology") == 0);
    SC_CHECK_MSG(M(&r, "lod0.textured.crack_pixels") == alone, "%g", M(&r, "lod0.textured.crack_pixels"));
    SC_CHECK(M(&r, "lod0.textured.fold_pixels") == 0);
    sc_ctx_free(r.ctx);
    sc_value_release(whole);

    /* the limit fails the cook and names the LOD, the mode and the view */
    r = render(NULL, cube, NULL, (const char *const[]){"size", "128", "max_crack_pixels", "0", NULL});
    SC_CHECK(r.rc != SC_OK);
    SC_CHECK_MSG(strstr(r.err.message, "max_crack_pixels") && strstr(r.err.message, "lod 0") &&
                     strstr(r.err.message, "mode textured") && strstr(r.err.message, "view "),
                 "%s", r.err.message);
    SC_CHECK(sc_ctx_output(r.ctx, 0) == NULL);
    sc_ctx_free(r.ctx);
    sc_value_release(cube);
    cube_textures_free(&tex);
}

/* Faces turned over with nothing opened (the textured pass's gap is 0, the
 * topology the reference's) show back faces: folds, not cracks. */
SC_TEST(fold_with_the_references_topology_is_not_a_crack) {
    cube_textures tex = cube_textures_make(0);
    sc_value *closed = cube_atlas(4, CUBE_NO_POSITIONS, &tex);
    sc_value *folded = cube_atlas(4, CUBE_NO_POSITIONS | CUBE_FOLD, &tex);
    const char *const p[] = {"size", "128", "max_fold_pixels", "1e9", NULL};

    /* alone, its back faces count */
    run_result r = render(NULL, folded, NULL, p);
    SC_CHECK_MSG(r.rc == SC_OK, "%s", r.err.message);
    double alone = M(&r, "lod0.textured.crack_pixels");
    SC_CHECK_MSG(alone > 10, "%g", alone);
    SC_CHECK(M(&r, "lod0.closed") == 1);
    sc_ctx_free(r.ctx);

    /* against the unfolded cube: the same pixels, as folds */
    r = render(NULL, folded, closed, p);
    SC_CHECK_MSG(r.rc == SC_OK, "%s", r.err.message);
    SC_CHECK(M(&r, "lod0.same_topology") == 1);
    SC_CHECK(M(&r, "lod0.textured.crack_pixels") == 0);
    SC_CHECK_MSG(M(&r, "lod0.textured.fold_pixels") == alone, "%g", M(&r, "lod0.textured.fold_pixels"));
    /* the sheet marks folds (cyan), no cracks; the reference has its own sheet */
    SC_CHECK(pixels_of_colour(&r, "render/lod0_sheet.png", cyan) > 20);
    SC_CHECK(pixels_of_colour(&r, "render/lod0_sheet.png", yellow) == 0);
    SC_CHECK(pixels_of_colour(&r, "render/reference_sheet.png", cyan) == 0);
    SC_CHECK_INT(M(&r, "lod0.fold_pixels"), alone);
    sc_ctx_free(r.ctx);

    /* the fold gate: by default a level may show twice the reference's own
     * back-face pixels (here none), so the fold fails the node, naming it;
     * the crack gate does not fire, and a fold allowance lets it pass */
    r = render(NULL, folded, closed, (const char *const[]){"size", "128", "max_crack_pixels", "0", NULL});
    SC_CHECK(r.rc != SC_OK);
    SC_CHECK_MSG(strstr(r.err.message, "max_fold_pixels: lod 0, mode textured") != NULL, "%s", r.err.message);
    sc_ctx_free(r.ctx);
    char limit[32];
    snprintf(limit, sizeof limit, "%.0f", alone);
    r = render(NULL, folded, closed, (const char *const[]){"size", "128", "max_fold_pixels", limit, "max_crack_pixels", "0", NULL});
    SC_CHECK_MSG(r.rc == SC_OK, "%s", r.err.message);
    sc_ctx_free(r.ctx);
    snprintf(limit, sizeof limit, "%.0f", alone - 1);
    r = render(NULL, folded, closed, (const char *const[]){"size", "128", "max_fold_pixels", limit, NULL});
    SC_CHECK(r.rc != SC_OK && strstr(r.err.message, "max_fold_pixels") != NULL);
    sc_ctx_free(r.ctx);

    /* the same fold in an open cube, against the open cube */
    sc_value *open = cube_atlas(4, CUBE_NO_POSITIONS | CUBE_OPEN, &tex);
    sc_value *open_folded = cube_atlas(4, CUBE_NO_POSITIONS | CUBE_OPEN | CUBE_FOLD, &tex);
    r = render(NULL, open_folded, open, p);
    SC_CHECK_MSG(r.rc == SC_OK, "%s", r.err.message);
    SC_CHECK(M(&r, "lod0.closed") == 0 && M(&r, "lod0.same_topology") == 1);
    SC_CHECK(M(&r, "lod0.textured.crack_pixels") == 0);
    SC_CHECK_MSG(M(&r, "lod0.textured.fold_pixels") > 10, "%g", M(&r, "lod0.textured.fold_pixels"));
    double open_folds = M(&r, "lod0.textured.fold_pixels"), open_back = M(&r, "reference.back_pixels");
    sc_ctx_free(r.ctx);
    /* by default it may show twice the reference's back-face pixels: passes
     * with an allowance just above its folds, fails just below */
    for (int above = 0; above < 2; above++) {
        char allowance[32];
        snprintf(allowance, sizeof allowance, "%.17g", (open_folds + (above ? 0.5 : -0.5)) / open_back);
        r = render(NULL, open_folded, open, (const char *const[]){"size", "128", "fold_allowance", allowance, NULL});
        SC_CHECK_MSG(above ? r.rc == SC_OK : r.rc != SC_OK, "allowance %s: %s", allowance, r.err.message);
        sc_ctx_free(r.ctx);
    }

    /* against a reference of another topology (the open cube has a hole the
     * folded closed one lacks) the rule does not apply */
    r = render(NULL, folded, open, p);
    SC_CHECK_MSG(r.rc == SC_OK, "%s", r.err.message);
    SC_CHECK(M(&r, "lod0.same_topology") == 0);
    SC_CHECK_MSG(M(&r, "lod0.textured.crack_pixels") == alone, "%g", M(&r, "lod0.textured.crack_pixels"));
    sc_ctx_free(r.ctx);
    sc_value_release(open_folded);
    sc_value_release(open);
    sc_value_release(folded);
    sc_value_release(closed);
    cube_textures_free(&tex);
}

SC_TEST(displacement_with_seams_fails_the_gap_limit) {
    cube_textures tex = cube_textures_make(CUBE_DISP_SEAMS);
    sc_value *good = cube_atlas(3, 0, &tex);
    sc_value *lods = lods_of((sc_value *const[]){good}, 1);
    run_result r = render(lods, NULL, NULL,
                          (const char *const[]){"size", "64", "views", "2", "modes", "geometry_image,displaced",
                                                "max_seam_gap", "1e-6", NULL});
    SC_CHECK(r.rc != SC_OK);
    SC_CHECK_MSG(strstr(r.err.message, "max_seam_gap: lod 0, mode displaced") != NULL, "%s", r.err.message);
    /* and how much of the gap the maps hold: all of it, here */
    SC_CHECK_MSG(strstr(r.err.message, "the maps themselves differ by") != NULL, "%s", r.err.message);
    sc_ctx_free(r.ctx);
    sc_value_release(lods);
    sc_value_release(good);
    cube_textures_free(&tex);
}

SC_TEST(open_mesh_is_compared_with_the_reference) {
    cube_textures tex = cube_textures_make(0);
    sc_value *open = cube_atlas(4, CUBE_OPEN, &tex);
    const char *const p[] = {"size", "128", "modes", "textured,geometry_image", NULL};

    /* without a reference every back face of the hole counts */
    run_result r = render(NULL, open, NULL, p);
    SC_CHECK_MSG(r.rc == SC_OK, "%s", r.err.message);
    SC_CHECK(M(&r, "lod0.closed") == 0);
    SC_CHECK(M(&r, "lod0.textured.crack_pixels") > 100);
    sc_ctx_free(r.ctx);

    /* with itself as the reference, nothing is new */
    r = render(NULL, open, open, p);
    SC_CHECK_MSG(r.rc == SC_OK, "%s", r.err.message);
    SC_CHECK(M(&r, "reference.back_pixels") > 100);
    SC_CHECK_MSG(M(&r, "lod0.textured.crack_pixels") == 0, "%g", M(&r, "lod0.textured.crack_pixels"));
    SC_CHECK_MSG(M(&r, "lod0.geometry_image.crack_pixels") == 0, "%g", M(&r, "lod0.geometry_image.crack_pixels"));
    SC_CHECK(has_file(&r, "render/reference_posx.png"));
    sc_ctx_free(r.ctx);

    /* a coarser level of the same open box: the hole barely moves */
    sc_value *coarse = cube_atlas(2, CUBE_OPEN, &tex);
    sc_value *lods = lods_of((sc_value *const[]){open, coarse}, 2);
    r = render(lods, NULL, open, p);
    SC_CHECK_MSG(r.rc == SC_OK, "%s", r.err.message);
    SC_CHECK(M(&r, "lod1.textured.crack_pixels") == 0);
    SC_CHECK(has_file(&r, "render/lod1_sheet.png"));
    sc_ctx_free(r.ctx);

    /* a crack that the reference does not have still counts */
    sc_value *cracked = cube_atlas(4, CUBE_OPEN | CUBE_GI_SEAMS, &tex);
    cube_textures seams = cube_textures_make(CUBE_GI_SEAMS);
    sc_value *bad = cube_atlas(4, CUBE_OPEN, &seams);
    r = render(NULL, bad, open, p);
    SC_CHECK_MSG(r.rc == SC_OK, "%s", r.err.message);
    SC_CHECK(M(&r, "lod0.textured.crack_pixels") == 0);
    SC_CHECK_MSG(M(&r, "lod0.geometry_image.crack_pixels") > 0, "%g", M(&r, "lod0.geometry_image.crack_pixels"));
    sc_ctx_free(r.ctx);
    sc_value_release(bad);
    sc_value_release(cracked);
    cube_textures_free(&seams);
    sc_value_release(lods);
    sc_value_release(coarse);
    sc_value_release(open);
    cube_textures_free(&tex);
}

SC_TEST(levels_share_textures_and_all_stay_crack_free) {
    cube_textures tex = cube_textures_make(0);
    sc_value *l0 = cube_atlas(6, 0, &tex), *l1 = cube_atlas(3, 0, &tex), *l2 = cube_atlas(1, 0, &tex);
    sc_value *lods = lods_of((sc_value *const[]){l0, l1, l2}, 3);
    run_result r = render(lods, NULL, NULL, (const char *const[]){"size", "96", "views", "14", NULL});
    SC_CHECK_MSG(r.rc == SC_OK, "%s", r.err.message);
    SC_CHECK(M(&r, "levels") == 3);
    SC_CHECK(M(&r, "crack_pixels") == 0);
    SC_CHECK(M(&r, "max_seam_gap") <= 1e-6);
    SC_CHECK(M(&r, "lod2.faces") == 12);
    SC_CHECK(M(&r, "lod2.tessellated.crack_pixels") == 0);
    SC_CHECK(has_file(&r, "render/lod2_displaced_obl7.png"));
    SC_CHECK(has_file(&r, "render/lod0_sheet.png") && has_file(&r, "render/lod2_sheet.png"));
    sc_ctx_free(r.ctx);
    sc_value_release(lods);
    sc_value_release(l0), sc_value_release(l1), sc_value_release(l2);
    cube_textures_free(&tex);
}

/* A level whose atlas is an earlier level's (equal digests: a decimation
 * that stopped gives its next level the same mesh) is not drawn again: its
 * metrics and pictures are the earlier level's, and it counts in the totals
 * as often as it appears. Level 2 here is built apart from level 0 with the
 * same content; the cracks of the split cube show under both names. */
SC_TEST(a_repeated_level_is_checked_once_with_the_same_results) {
    cube_textures tex = cube_textures_make(0);
    sc_value *split = cube_atlas(4, CUBE_SPLIT | CUBE_NO_POSITIONS, &tex);
    sc_value *whole = cube_atlas(2, CUBE_NO_POSITIONS, &tex);
    sc_value *again = cube_atlas(4, CUBE_SPLIT | CUBE_NO_POSITIONS, &tex);
    const char *const params[] = {"size", "128", "modes", "textured", NULL};
    run_result one = render(NULL, split, NULL, params), other = render(NULL, whole, NULL, params);
    SC_CHECK(one.rc == SC_OK && other.rc == SC_OK);
    sc_value *lods = lods_of((sc_value *const[]){split, whole, again}, 3);
    run_result r = render(lods, NULL, NULL, params);
    SC_CHECK_MSG(r.rc == SC_OK, "%s", r.err.message);
    SC_CHECK_INT(M(&r, "renders"), M(&one, "renders") + M(&other, "renders"));
    double cracks = M(&one, "lod0.textured.crack_pixels");
    SC_CHECK_MSG(cracks > 50, "%g", cracks);
    SC_CHECK_INT(M(&r, "lod0.textured.crack_pixels"), cracks);
    SC_CHECK_INT(M(&r, "lod2.textured.crack_pixels"), cracks);
    SC_CHECK_INT(M(&r, "lod2.faces"), M(&r, "lod0.faces"));
    SC_CHECK_INT(M(&r, "lod2.repeats_level"), 0);
    SC_CHECK(isnan(M(&r, "lod1.repeats_level")) && isnan(M(&r, "lod0.repeats_level")));
    SC_CHECK_INT(M(&r, "crack_pixels"), 2 * cracks + M(&other, "crack_pixels"));
    int64_t marks0 = pixels_of_colour(&r, "render/lod0_sheet.png", yellow);
    SC_CHECK_MSG(marks0 > 20 && pixels_of_colour(&r, "render/lod2_sheet.png", yellow) == marks0, "%lld %lld",
                 (long long)marks0, (long long)pixels_of_colour(&r, "render/lod2_sheet.png", yellow));
    SC_CHECK(has_file(&r, "render/lod1_sheet.png"));
    sc_ctx_free(r.ctx), sc_ctx_free(one.ctx), sc_ctx_free(other.ctx);
    sc_value_release(lods);
    sc_value_release(split), sc_value_release(whole), sc_value_release(again);
    cube_textures_free(&tex);
}

/* ---------------------------------------------------------------- determinism */

typedef struct thread_job {
    sc_value *atlas;
    sc_digest digest;
    int rc;
    int threads;   /* the node's worker threads (PNG encoding) */
} thread_job;

static void *thread_render(void *ud) {
    thread_job *j = ud;
    run_result r = {0};
    r.ctx = sc_ctx_new(&sc_node_render, NULL, NULL);
    sc_ctx_set_input(r.ctx, "atlas", j->atlas);
    sc_ctx_set_threads(r.ctx, j->threads);
    sc_error e;
    sc_ctx_set_param(r.ctx, "size", "96", &e);
    sc_ctx_set_param(r.ctx, "views", "7", &e);
    r.rc = sc_ctx_run(r.ctx, &r.err);
    if (r.rc == SC_OK) r.report = sc_ctx_output(r.ctx, 0);
    j->rc = r.rc;
    if (r.rc == SC_OK) j->digest = *sc_value_digest(r.report);
    sc_ctx_free(r.ctx);
    return NULL;
}

SC_TEST(rendering_is_deterministic) {
    cube_textures tex = cube_textures_make(CUBE_GI_SEAMS);
    sc_value *cube = cube_atlas(5, 0, &tex);
    /* the same bytes twice, and whatever the number of encoding threads */
    thread_job serial[3] = {{cube, {{0}}, -1, 1}, {cube, {{0}}, -1, 1}, {cube, {{0}}, -1, 3}};
    for (int i = 0; i < 3; i++) {
        thread_render(&serial[i]);
        SC_CHECK(serial[i].rc == SC_OK);
        SC_CHECK(sc_digest_equal(&serial[i].digest, &serial[0].digest));
    }
    /* several renders at once on different threads: each its own context */
    thread_job jobs[3] = {{cube, {{0}}, -1, 2}, {cube, {{0}}, -1, 1}, {cube, {{0}}, -1, 2}};
    pthread_t th[3];
    for (int i = 0; i < 3; i++) pthread_create(&th[i], NULL, thread_render, &jobs[i]);
    for (int i = 0; i < 3; i++) pthread_join(th[i], NULL);
    for (int i = 0; i < 3; i++) {
        SC_CHECK(jobs[i].rc == SC_OK);
        SC_CHECK(sc_digest_equal(&jobs[i].digest, &serial[0].digest));
    }
    sc_value_release(cube);
    cube_textures_free(&tex);
}

/* ---------------------------------------------------------------- bad input */

SC_TEST(parameters_and_inputs_are_checked) {
    cube_textures tex = cube_textures_make(0);
    sc_value *cube = cube_atlas(2, 0, &tex);
    /* parameters are refused with the value (so a graph fails when it is built) */
    const char *const refused[][3] = {
        {"modes", "textured,wireframe", "render:modes: unknown mode 'wireframe'"},
        {"tess_levels", "2,2.5", "render:tess_levels: element 2 (2.5) is not an integer"},
        {"tess_levels", "2,4,2", "render:tess_levels: level 2 is given twice"},
        {"folder", "../up", "render:folder: '../up' is not a relative folder name"},
    };
    for (int i = 0; i < 4; i++) {
        sc_ctx *ctx = sc_ctx_new(&sc_node_render, NULL, NULL);
        sc_error e;
        SC_CHECK_MSG(sc_ctx_set_param(ctx, refused[i][0], refused[i][1], &e) == SC_EINPUT &&
                         strstr(e.message, refused[i][2]),
                     "%s=%s: %s", refused[i][0], refused[i][1], e.message);
        sc_ctx_free(ctx);
    }
    run_result r = render(NULL, NULL, NULL, NULL);
    SC_CHECK(r.rc == SC_EINPUT);
    SC_CHECK_MSG(strstr(r.err.message, "lods") != NULL, "%s", r.err.message);
    sc_ctx_free(r.ctx);
    sc_value *lods = lods_of(&cube, 1);
    r = render(lods, cube, NULL, NULL);
    SC_CHECK(r.rc == SC_EINPUT);
    sc_ctx_free(r.ctx);
    sc_value_release(lods);

    /* a one-channel geometry image cannot hold positions */
    sc_image_data *gray = sc_image_alloc(8, 8, 1, SC_PIXEL_F32);
    sc_value *gray_value = sc_value_new_image(gray);
    sc_atlas *a = sc_atlas_new(sc_value_retain(cube->as.atlas->mesh));
    sc_atlas_add_texture(a, "geometry_image", 0, SC_WRAP_REPEAT, SC_WRAP_REPEAT, "", gray_value);
    sc_value *bad = sc_value_new_atlas(a);
    r = render(NULL, bad, NULL, (const char *const[]){"size", "32", "views", "1", NULL});
    SC_CHECK(r.rc == SC_EINPUT);
    SC_CHECK_MSG(strstr(r.err.message, "geometry_image") && strstr(r.err.message, "channel"), "%s", r.err.message);
    sc_ctx_free(r.ctx);
    sc_value_release(bad);
    sc_value_release(cube);
    cube_textures_free(&tex);
}

int main(void) { return sc_test_main(); }
