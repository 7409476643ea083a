/* procedural.c - the node `procedural`: a textured test asset made from
 * nothing, so the demo and the tests never depend on files from elsewhere.
 *
 * Design note. The shape is a bumpy "cube sphere": the six faces of a cube,
 * each an n x n grid, pushed out onto a sphere and displaced by a smooth bump
 * function. Surface vertices are shared along cube edges (found through the
 * integer lattice of the cube), so the surface is closed and manifold. Each
 * cube face is its own uv chart, laid out in a 3 x 2 grid of cells and turned
 * by a different quarter turn, so every cube edge is a real seam: the same
 * surface edge with two different uv edges. The colour texture is painted by
 * evaluating a smooth function of the surface point at every texel centre
 * (docs/design.md's convention), padding included, with a small per-chart tint so
 * the seams are visible until erase_seams removes them. Everything is plain
 * arithmetic on the parameters: the same parameters give the same bytes.
 *
 * Gutters. Each chart keeps `padding` (a fraction of the texture side) of
 * empty texture on every side, so neighbouring charts are 2 x padding apart.
 * A mip level of side S sees that gap as 2 x padding x S texels; below about
 * 2 texels the charts' bilinear cells share texels, and a geometry image
 * there pulls each chart's border towards the other chart's positions
 * (folds that the render check counts, though the seams still meet). The
 * default, 1/16, keeps charts 2 texels apart down to 16 x 16 mips.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "sc_nodes.h"

/* Face f: lattice point = O + a*A + b*B with a, b in [0, n]; A x B points out. */
static const int face_origin[6][3] = {{1, 0, 0}, {0, 0, 0}, {0, 1, 0}, {0, 0, 0}, {0, 0, 1}, {0, 0, 0}};
static const int face_a[6][3] = {{0, 1, 0}, {0, 0, 1}, {0, 0, 1}, {1, 0, 0}, {1, 0, 0}, {0, 1, 0}};
static const int face_b[6][3] = {{0, 0, 1}, {0, 1, 0}, {1, 0, 0}, {0, 0, 1}, {0, 1, 0}, {1, 0, 0}};
static const int face_turns[6] = {0, 1, 2, 3, 1, 2};

typedef struct shape {
    int n;              /* grid cells per cube face side */
    double bump;        /* relative height of the bumps */
    int size;           /* texture side in texels */
    int pad;            /* texels of padding around each chart */
    int chart_side;     /* chart side in texels */
} shape;

/* Surface point for continuous face coordinates (a, b) in [0, n]. */
static void surface_point(const shape *s, int f, double a, double b, double out[3]) {
    double c[3], len = 0;
    for (int k = 0; k < 3; k++) {
        double lattice = face_origin[f][k] * s->n + a * face_a[f][k] + b * face_b[f][k];
        c[k] = 2.0 * lattice / s->n - 1.0;
        len += c[k] * c[k];
    }
    len = sqrt(len);
    double d[3] = {c[0] / len, c[1] / len, c[2] / len};
    double r = 1.0 + s->bump * sin(3.0 * d[0]) * sin(2.0 * d[1] + 1.0) * sin(4.0 * d[2] + 0.5);
    for (int k = 0; k < 3; k++) out[k] = r * d[k];
}

/* Where face f's chart sits in the texture, in texels. */
static void chart_origin(const shape *s, int f, double *ox, double *oy) {
    int cell_w = s->size / 3, cell_h = s->size / 2;
    *ox = (f % 3) * cell_w + (cell_w - s->chart_side) / 2;
    *oy = (f / 3) * cell_h + (cell_h - s->chart_side) / 2;
}

/* Turn unit-square coordinates by q quarter turns about the centre. */
static void turn(int q, double x, double y, double *tx, double *ty) {
    for (int k = 0; k < (q & 3); k++) {
        double t = x;
        x = 1.0 - y;
        y = t;
    }
    *tx = x, *ty = y;
}

static void unturn(int q, double x, double y, double *tx, double *ty) { turn(4 - (q & 3), x, y, tx, ty); }

static void paint(const double p[3], int f, double tint, uint8_t rgb[3]) {
    double len = sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]);
    double x = p[0] / len, y = p[1] / len, z = p[2] / len;
    double stripes = 0.5 + 0.5 * sin(9.0 * (x + 0.5 * y));
    double spots = 0.5 + 0.5 * sin(7.0 * y + 1.3) * sin(7.0 * z - 0.4);
    double rgbf[3] = {0.25 + 0.6 * stripes, 0.2 + 0.55 * spots, 0.35 + 0.5 * (0.5 + 0.5 * z)};
    double scale = 1.0 + tint * ((double)f - 2.5) / 2.5;
    for (int k = 0; k < 3; k++) {
        double v = rgbf[k] * scale;
        v = v < 0 ? 0 : v > 1 ? 1 : v;
        rgb[k] = (uint8_t)lrint(v * 255.0);
    }
}

static int lattice_index(const shape *s, int f, int a, int b) {
    int m = s->n + 1, l[3];
    for (int k = 0; k < 3; k++) l[k] = face_origin[f][k] * s->n + a * face_a[f][k] + b * face_b[f][k];
    return (l[0] * m + l[1]) * m + l[2];
}

static int build_mesh(const shape *s, sc_mesh **out, sc_error *err) {
    int n = s->n, m = n + 1;
    int *vertex_of = malloc(sizeof(int) * (size_t)m * m * m);
    if (!vertex_of) return sc_fail(err, SC_ENOMEM, "procedural: out of memory");
    for (int i = 0; i < m * m * m; i++) vertex_of[i] = -1;
    /* surface vertices: 6 n^2 + 2 for a closed cube grid */
    int nv = 6 * n * n + 2, nu = 6 * m * m, nf = 12 * n * n;
    sc_mesh *mesh = sc_mesh_alloc(nv, nu, 0, nf, 1);
    if (!mesh || !(mesh->materials[0] = sc_strdup("default"))) {
        free(vertex_of);
        sc_mesh_free(mesh);
        return sc_fail(err, SC_ENOMEM, "procedural: out of memory");
    }
    int next_v = 0, face = 0;
    for (int f = 0; f < 6; f++) {
        double ox, oy;
        chart_origin(s, f, &ox, &oy);
        for (int b = 0; b <= n; b++)
            for (int a = 0; a <= n; a++) {
                int li = lattice_index(s, f, a, b);
                if (vertex_of[li] < 0) {
                    vertex_of[li] = next_v;
                    surface_point(s, f, a, b, mesh->V + 3 * next_v);
                    next_v++;
                }
                double tx, ty;
                turn(face_turns[f], (double)a / n, (double)b / n, &tx, &ty);
                int ui = f * m * m + b * m + a;
                mesh->U[2 * ui] = (ox + tx * s->chart_side) / s->size;
                mesh->U[2 * ui + 1] = (oy + ty * s->chart_side) / s->size;
            }
        for (int b = 0; b < n; b++)
            for (int a = 0; a < n; a++) {
                int c[4][2] = {{a, b}, {a + 1, b}, {a + 1, b + 1}, {a, b + 1}};
                int v[4], u[4];
                for (int k = 0; k < 4; k++) {
                    v[k] = vertex_of[lattice_index(s, f, c[k][0], c[k][1])];
                    u[k] = f * m * m + c[k][1] * m + c[k][0];
                }
                /* alternate the diagonal so the triangulation is symmetric */
                int tri[2][3] = {{0, 1, 2}, {0, 2, 3}};
                if ((a + b) & 1) {
                    int alt[2][3] = {{0, 1, 3}, {1, 2, 3}};
                    memcpy(tri, alt, sizeof tri);
                }
                for (int t = 0; t < 2; t++, face++)
                    for (int k = 0; k < 3; k++) {
                        mesh->FV[3 * face + k] = v[tri[t][k]];
                        mesh->FU[3 * face + k] = u[tri[t][k]];
                    }
            }
    }
    free(vertex_of);
    if (next_v != nv) {
        sc_mesh_free(mesh);
        return sc_fail(err, SC_EINPUT, "procedural: made %d vertices, expected %d", next_v, nv);
    }
    *out = mesh;
    return SC_OK;
}

static sc_image_data *paint_texture(const shape *s, double tint) {
    sc_image_data *im = sc_image_alloc(s->size, s->size, 3, SC_PIXEL_U8);
    if (!im) return NULL;
    memcpy(im->format, "png", 4);
    im->colorspace = SC_COLOR_SRGB;
    uint8_t *px = im->pixels;
    int cell_w = s->size / 3, cell_h = s->size / 2;
    for (int j = 0; j < s->size; j++)
        for (int i = 0; i < s->size; i++) {
            uint8_t *rgb = px + 3 * ((size_t)j * s->size + i);
            int f = (i / cell_w < 3 ? i / cell_w : 2) + 3 * (j / cell_h < 2 ? j / cell_h : 1);
            double ox, oy;
            chart_origin(s, f, &ox, &oy);
            double x = (i + 0.5 - ox) / s->chart_side, y = (j + 0.5 - oy) / s->chart_side;
            double margin = (double)s->pad / s->chart_side;
            if (x < -margin || y < -margin || x > 1 + margin || y > 1 + margin) {
                rgb[0] = rgb[1] = rgb[2] = 128;
                continue;
            }
            double a, b, p[3];
            unturn(face_turns[f], x, y, &a, &b);
            surface_point(s, f, a * s->n, b * s->n, p);
            paint(p, f, tint, rgb);
        }
    return im;
}

static int run(sc_ctx *ctx, sc_error *err) {
    shape s = {
        .n = (int)sc_ctx_integer(ctx, "resolution"),
        .bump = sc_ctx_number(ctx, "bumpiness"),
        .size = (int)sc_ctx_integer(ctx, "texture_size"),
    };
    s.pad = (int)lround(sc_ctx_number(ctx, "padding") * s.size);
    if (s.pad < 2) s.pad = 2;
    int cell = s.size / 3 < s.size / 2 ? s.size / 3 : s.size / 2;
    s.chart_side = cell - 2 * s.pad;
    if (s.chart_side < 4) return sc_fail(err, SC_EINPUT, "texture_size %d is too small for six charts", s.size);
    sc_mesh *mesh = NULL;
    int rc = build_mesh(&s, &mesh, err);
    if (rc != SC_OK) return rc;
    sc_value *mesh_value = sc_value_new_mesh(mesh);
    sc_image_data *tex = paint_texture(&s, sc_ctx_number(ctx, "chart_tint"));
    sc_value *image = tex ? sc_value_new_image(tex) : NULL;
    sc_atlas *atlas = mesh_value ? sc_atlas_new(mesh_value) : NULL;
    if (!atlas || !image ||
        sc_atlas_add_texture(atlas, "color", 0, SC_WRAP_REPEAT, SC_WRAP_REPEAT, "procedural.png",
                             sc_value_retain(image)) != SC_OK) {
        sc_value_release(image);
        sc_atlas_free(atlas);
        return sc_fail(err, SC_ENOMEM, "procedural: out of memory");
    }
    sc_value_release(image);
    sc_value *out = sc_value_new_atlas(atlas);
    if (!out) return sc_fail(err, SC_ENOMEM, "procedural: out of memory");
    sc_ctx_metric(ctx, "faces", 12.0 * s.n * s.n);
    sc_ctx_metric(ctx, "vertices", 6.0 * s.n * s.n + 2);
    sc_ctx_metric(ctx, "charts", 6);
    sc_ctx_metric(ctx, "seam_edges", 12.0 * s.n);
    sc_ctx_set_output(ctx, "atlas", out);
    return SC_OK;
}

static const sc_param_desc params[] = {
    {.name = "resolution", .type = SC_PARAM_INTEGER, .def = 24, .min = 1, .max = 200,
     .doc = "grid cells along each side of each cube face"},
    {.name = "texture_size", .type = SC_PARAM_INTEGER, .def = 512, .min = 32, .max = 8192,
     .doc = "side of the square colour texture, in texels"},
    {.name = "bumpiness", .type = SC_PARAM_NUMBER, .def = 0.15, .min = 0, .max = 0.5,
     .doc = "height of the bumps relative to the radius"},
    {.name = "padding", .type = SC_PARAM_NUMBER, .def = 0.0625, .min = 0, .max = 0.15,
     .doc = "empty border around each chart, as a fraction of the texture side (at least 2 texels); "
            "1/16 keeps charts apart down to 16 x 16 mip levels"},
    {.name = "chart_tint", .type = SC_PARAM_NUMBER, .def = 0.08, .min = 0, .max = 1,
     .doc = "brightness difference between charts (makes seams visible)"},
};

static const sc_port_desc outputs[] = {
    {.name = "atlas", .kind = SC_KIND_ATLAS, .doc = "a closed bumpy sphere, six charts, colour texture"},
};

const sc_node_desc sc_node_procedural = {
    .type = "procedural",
    .version = 2,
    .summary = "a closed textured shape with six uv charts and real seams, made from parameters",
    .outputs = outputs,
    .noutputs = SC_COUNT(outputs),
    .params = params,
    .nparams = SC_COUNT(params),
    .run = run,
};
