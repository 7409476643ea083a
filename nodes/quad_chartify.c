/* quad_chartify.c - the node `quad_chartify`: a seamless atlas of square
 * charts (Purnomo et al. 2004) for any textured mesh, through the quad
 * kernel (nodes/lib/sc_quad.h, which holds the method).
 *
 * mode "always" re-chartifies; "never" passes the atlas through; "auto"
 * re-chartifies when the input atlas cannot serve the chain as it is: its
 * uv share texels (overlapping or mirrored charts), it has no uv or uv
 * without area on more than 0.1% of its surface, it is
 * fragmented into more charts than seam-aware decimation can keep
 * collapsing (`max_charts`), or two of its charts lie within a texel of
 * each other on the maps the chain bakes (`map_size`: a texel there would
 * hold the surface of both, and the seams of the geometry and displacement
 * maps land off the surface). The node measures those on the input and
 * reports them, so a run says why it chose.
 *
 * Outputs: `atlas` (level 0) and `levels`, one atlas per mip level whose uv
 * carry the level's offset (sc_quad_level_offset), so a renderer samples
 * each level with plain bilinear filtering and finds no seam.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "sc_nodes.h"
#include "sc_quad.h"
#include "sc_seam.h"

static const char *const mode_choices[] = {"auto", "always", "never", NULL};
static const char *const layout_choices[] = {"blocks", NULL};

/* The uv charts of m: uv indices joined by the faces that use them. */
static int32_t count_charts(const sc_mesh *m, int32_t *parent) {
    for (int32_t i = 0; i < m->nu; i++) parent[i] = -1;
    for (int32_t f = 0; f < m->nf; f++)
        for (int k = 0; k < 3; k++) {
            int32_t x = m->FU[3 * f + k];
            if (parent[x] < 0) parent[x] = x;
        }
    for (int32_t f = 0; f < m->nf; f++)
        for (int k = 1; k < 3; k++) {
            int32_t x = m->FU[3 * f], y = m->FU[3 * f + k];
            while (parent[x] != x) x = parent[x] = parent[parent[x]];
            while (parent[y] != y) y = parent[y] = parent[parent[y]];
            if (x != y) parent[x] = y;
        }
    int32_t n = 0;
    for (int32_t i = 0; i < m->nu; i++) n += parent[i] == i;
    return n;
}

/* What auto decides on, measured on the input. */
typedef struct input_measures {
    double shared_fraction;   /* of the covered texels, those two or more faces cover */
    double degenerate_fraction;   /* of the surface area, that of faces whose uv have no area */
    int32_t charts;           /* uv charts */
    int64_t tap_reached, tap_met;   /* on map_size^2 grids: texels a chart's taps reach, two charts' */
} input_measures;

/* The chart of every face: the root of its first uv index (parent from
 * count_charts). */
static int32_t *face_charts(const sc_mesh *m, int32_t *parent) {
    int32_t *chart = malloc((size_t)(m->nf > 0 ? m->nf : 1) * sizeof *chart);
    for (int32_t f = 0; chart && f < m->nf; f++) {
        int32_t x = m->FU[3 * f];
        while (parent[x] != x) x = parent[x];
        chart[f] = x;
    }
    return chart;
}

/* Shared texels (each material on its largest texture's grid,
 * sc_seam_coverage), charts, and with map_size > 0 the texels two charts'
 * bilinear taps reach on a map_size^2 grid (sc_seam_taps_meet, the largest
 * texture's wrap modes). */
static int measure_input(const sc_atlas *a, int32_t map_size, int threads, input_measures *out, sc_error *err) {
    const sc_mesh *m = a->mesh->as.mesh;
    *out = (input_measures){0};
    if (m->nu <= 0) return SC_OK;
    out->degenerate_fraction = sc_seam_degenerate_uv_fraction(m);
    int32_t *parent = malloc((size_t)m->nu * sizeof *parent);
    if (!parent) return sc_fail(err, SC_ENOMEM, "out of memory");
    out->charts = count_charts(m, parent);
    int32_t *chart = map_size > 0 ? face_charts(m, parent) : NULL;
    free(parent);
    if (map_size > 0 && !chart) return sc_fail(err, SC_ENOMEM, "out of memory");
    double covered = 0, shared = 0;
    int rc = SC_OK;
    for (int32_t mat = 0; mat < m->nmat && rc == SC_OK; mat++) {
        sc_seam_grid g = {1024, 1024, SC_WRAP_REPEAT, SC_WRAP_REPEAT};
        int64_t best = 0;
        for (int32_t t = 0; t < a->ntex; t++) {
            const sc_image_data *im = a->textures[t].image->as.image;
            if (a->textures[t].material != mat || (int64_t)im->width * im->height <= best) continue;
            best = (int64_t)im->width * im->height;
            g = (sc_seam_grid){im->width, im->height, a->textures[t].wrap_u, a->textures[t].wrap_v};
        }
        sc_seam_coverage c;
        rc = sc_seam_coverage_build(m, mat, &g, threads, &c, err);
        if (rc) break;
        covered += (double)c.ncovered, shared += (double)c.nshared;
        sc_seam_coverage_free(&c);
        if (map_size > 0) {
            sc_seam_grid mg = {map_size, map_size, g.wrap_u, g.wrap_v};
            int64_t reached, met;
            rc = sc_seam_taps_meet(m, mat, &mg, chart, &reached, &met, err);
            out->tap_reached += reached, out->tap_met += met;
        }
    }
    free(chart);
    out->shared_fraction = covered > 0 ? shared / covered : 0;
    return rc;
}

static int pass_through(sc_ctx *ctx, const sc_value *in) {
    sc_lods *l = sc_lods_new();
    if (!l || sc_lods_add(l, sc_value_retain((sc_value *)in)) != SC_OK) {
        sc_lods_free(l);
        return SC_ENOMEM;
    }
    sc_value *lv = sc_value_new_lods(l);
    if (!lv) return SC_ENOMEM;
    sc_ctx_set_output(ctx, "atlas", sc_value_retain((sc_value *)in));
    sc_ctx_set_output(ctx, "levels", lv);
    return SC_OK;
}

/* The atlas of level L: the mesh with uv shifted by the level's offset and
 * every texture's level L (taken from r). */
static sc_value *level_atlas(sc_quad_result *r, sc_value *mesh0, int32_t L) {
    sc_value *mesh = sc_value_retain(mesh0);
    if (L > 0) {
        const sc_mesh *m0 = mesh0->as.mesh;
        sc_mesh *m = sc_mesh_alloc(m0->nv, m0->nu, 0, m0->nf, 1);
        if (!m) return sc_value_release(mesh), NULL;
        memcpy(m->V, m0->V, (size_t)m0->nv * 3 * sizeof(double));
        memcpy(m->FV, m0->FV, (size_t)m0->nf * 3 * sizeof(int32_t));
        memcpy(m->FU, m0->FU, (size_t)m0->nf * 3 * sizeof(int32_t));
        double du, dv;
        sc_quad_level_offset(r->width, r->height, L, &du, &dv);
        for (int32_t i = 0; i < m0->nu; i++) m->U[2 * i] = m0->U[2 * i] + du, m->U[2 * i + 1] = m0->U[2 * i + 1] + dv;
        m->materials[0] = strdup(m0->materials[0]);
        sc_value_release(mesh);
        mesh = m->materials[0] ? sc_value_new_mesh(m) : (sc_mesh_free(m), NULL);
        if (!mesh) return NULL;
    }
    sc_atlas *a = sc_atlas_new(mesh);
    if (!a) return NULL;
    if (r->has_constants) {
        if (!(a->materials = malloc(sizeof *a->materials))) return sc_atlas_free(a), NULL;
        a->materials[0] = r->constants;
    }
    for (int32_t t = 0; t < r->ntex; t++) {
        sc_value *iv = sc_value_new_image(r->textures[t].levels[L]);   /* takes it */
        r->textures[t].levels[L] = NULL;
        if (!iv || sc_atlas_add_texture(a, r->textures[t].name, 0, SC_WRAP_CLAMP, SC_WRAP_CLAMP, "", iv) != SC_OK)
            return sc_atlas_free(a), NULL;
    }
    return sc_value_new_atlas(a);
}

static int run(sc_ctx *ctx, sc_error *err) {
    const sc_value *in = sc_ctx_input(ctx, "atlas");
    if (!in || in->kind != SC_KIND_ATLAS) return sc_fail(err, SC_EINPUT, "atlas: no atlas given");
    const sc_atlas *a = in->as.atlas;
    const sc_mesh *m = a->mesh->as.mesh;
    const char *mode = sc_ctx_string(ctx, "mode");
    int32_t tex_w = 0, tex_h = 0;
    for (int32_t t = 0; t < a->ntex; t++) {
        const sc_image_data *im = a->textures[t].image->as.image;
        if ((int64_t)im->width * im->height > (int64_t)tex_w * tex_h) tex_w = im->width, tex_h = im->height;
    }
    input_measures in_m = {0};
    int32_t map_size = (int32_t)sc_ctx_integer(ctx, "map_size");
    if (strcmp(mode, "auto") == 0 || strcmp(mode, "always") == 0) {
        int rc = measure_input(a, map_size, sc_ctx_threads(ctx), &in_m, err);
        if (rc) return rc;
    }
    int32_t max_charts = (int32_t)sc_ctx_integer(ctx, "max_charts");
    bool chartify = strcmp(mode, "always") == 0 ||
                    (strcmp(mode, "auto") == 0 && (m->nu <= 0 || in_m.shared_fraction > 0.001 ||
                                                   in_m.degenerate_fraction > 0.001 ||
                                                   in_m.charts > max_charts || in_m.tap_met > 0));
    sc_ctx_metric(ctx, "input_shared_texel_fraction", in_m.shared_fraction);
    sc_ctx_metric(ctx, "input_degenerate_uv_fraction", in_m.degenerate_fraction);
    sc_ctx_metric(ctx, "input_charts", in_m.charts);
    if (map_size > 0) {
        sc_ctx_metric(ctx, "input_tap_met_texels", (double)in_m.tap_met);
        sc_ctx_metric(ctx, "input_tap_met_fraction",
                      in_m.tap_reached > 0 ? (double)in_m.tap_met / (double)in_m.tap_reached : 0);
    }
    sc_ctx_metric(ctx, "chartified", chartify);
    if (!chartify) return pass_through(ctx, in) ? sc_fail(err, SC_ENOMEM, "out of memory") : SC_OK;

    sc_quad_options o;
    sc_quad_defaults(&o);
    o.texture_size = (int32_t)sc_ctx_integer(ctx, "texture_size");
    if (o.texture_size == 0) {   /* map_size when the texture is no larger */
        int32_t side = tex_w > tex_h ? tex_w : tex_h;
        o.texture_size = map_size > 0 && side <= map_size ? map_size : side > 0 ? side : 1024;
    }
    /* the maps the chain bakes hold the chart borders on their texel centres */
    o.whole_texture = o.texture_size == map_size;
    o.chart_texels = (int32_t)sc_ctx_integer(ctx, "chart_texels");
    o.target_patches = (int32_t)sc_ctx_integer(ctx, "target_patches");
    o.target_quads = (int32_t)sc_ctx_integer(ctx, "target_quads");
    double min_ratio = sc_ctx_number(ctx, "min_ratio");
    if (o.target_quads == 0 && o.target_patches == 0 && min_ratio > 0) {
        /* a quad decimates to two triangles at best: leave the coarsest level room */
        o.target_quads = (int32_t)floor(m->nf * min_ratio * 0.4);
        if (o.target_quads < 8) o.target_quads = 8;
    }
    o.min_size = (int32_t)sc_ctx_integer(ctx, "min_size");
    o.supersample = (int32_t)sc_ctx_integer(ctx, "supersample");
    o.psnr_samples = (int32_t)sc_ctx_integer(ctx, "psnr_samples");
    o.constants = a->materials;
    o.straight_borders = sc_ctx_bool(ctx, "straight_borders");
    (void)sc_ctx_string(ctx, "layout");
    sc_quad_result r;
    int rc = sc_quad_build(m, a->textures, a->ntex, &o, sc_ctx_threads(ctx), &r, err);
    if (rc) return rc;
    for (int32_t i = 0; i < r.metrics.count; i++) sc_ctx_metric(ctx, r.metrics.items[i].name, r.metrics.items[i].value);
    sc_value *mesh = sc_value_new_mesh(r.mesh);
    r.mesh = NULL;
    sc_lods *levels = mesh ? sc_lods_new() : NULL;
    sc_value *top = NULL;
    for (int32_t L = 0; L < r.nlevels && levels && rc == SC_OK; L++) {
        sc_value *lv = level_atlas(&r, mesh, L);
        if (!lv || sc_lods_add(levels, lv) != SC_OK) rc = SC_ENOMEM;
        else if (L == 0) top = sc_value_retain(lv);
    }
    sc_value_release(mesh);
    sc_quad_result_free(&r);
    sc_value *lodv = rc == SC_OK && levels ? sc_value_new_lods(levels) : (sc_lods_free(levels), NULL);
    if (!lodv || !top) {
        sc_value_release(lodv), sc_value_release(top);
        return sc_fail(err, SC_ENOMEM, "out of memory");
    }
    sc_ctx_set_output(ctx, "atlas", top);
    sc_ctx_set_output(ctx, "levels", lodv);
    return SC_OK;
}

static const sc_param_desc params[] = {
    {.name = "mode", .type = SC_PARAM_ENUM, .def_string = "always", .choices = mode_choices,
     .doc = "always: re-chartify; never: pass the atlas through; auto: re-chartify when the uv share texels, are "
            "missing or without area on more than 0.1% of the surface, hold more than max_charts charts, or come "
            "within a texel of each other at map_size"},
    {.name = "max_charts", .type = SC_PARAM_INTEGER, .def = 256, .min = 1, .max = 1e9,
     .doc = "auto: more uv charts than this re-chartify (decimation stalls on many non-collinear seams)"},
    {.name = "map_size", .type = SC_PARAM_INTEGER, .def = 0, .min = 0, .max = 32768,
     .doc = "auto: re-chartify when two uv charts' bilinear taps reach one texel of a map_size^2 map (the "
            "size the chain bakes its geometry and displacement maps at); 0: not measured"},
    {.name = "texture_size", .type = SC_PARAM_INTEGER, .def = 0, .min = 0, .max = 32768,
     .doc = "the side of level 0 in texels; 0: the input's largest texture side, or map_size when that is larger "
            "(1024 without either); at map_size the uv put chart borders on the maps' texel centres"},
    {.name = "chart_texels", .type = SC_PARAM_INTEGER, .def = 0, .min = 0, .max = 16385,
     .doc = "samples per side of every chart, 2^k + 1; 0: by surface area, one texel density for the atlas"},
    {.name = "target_patches", .type = SC_PARAM_INTEGER, .def = 0, .min = 0, .max = 1e9,
     .doc = "stop merging at this many patches; 0: by target_quads"},
    {.name = "target_quads", .type = SC_PARAM_INTEGER, .def = 0, .min = 0, .max = 1e9,
     .doc = "stop merging once the patches would make at most this many quads; 0: as many as fill the texture"},
    {.name = "min_ratio", .type = SC_PARAM_NUMBER, .def = 0, .min = 0, .max = 1,
     .doc = "the smallest face ratio the chain decimates to: with no target given, quads stay few enough "
            "(0.4 x faces x ratio) for that level to reach its face target; 0: fill the texture"},
    {.name = "layout", .type = SC_PARAM_ENUM, .def_string = "blocks", .choices = layout_choices,
     .doc = "blocks: each chart its own cell with gutters that keep charts apart at every level"},
    {.name = "min_size", .type = SC_PARAM_INTEGER, .def = 0, .min = 0, .max = 32768,
     .doc = "mip levels down to this larger side (charts keep at least 3 samples a side); 0: until charts hold 9"},
    {.name = "supersample", .type = SC_PARAM_INTEGER, .def = 2, .min = 1, .max = 8,
     .doc = "S x S points averaged per texel"},
    {.name = "psnr_samples", .type = SC_PARAM_INTEGER, .def = 200000, .min = 0, .max = 1e8,
     .doc = "surface points for the psnr_<slot> metrics (0: none)"},
    {.name = "straight_borders", .type = SC_PARAM_BOOL, .def = 0,
     .doc = "re-draw the patches' borders as shorter paths of mesh edges (Purnomo et al. 2004 4.1): less stretch, "
            "levels nearer their face targets; off by default, as WaterBottle's decimated level then shows folds "
            "at its cap's rim (docs/notes/quad_chartify.md)"},
};

static const sc_port_desc inputs[] = {
    {.name = "atlas", .kind = SC_KIND_ATLAS, .doc = "the textured mesh (uv may overlap, mirror or be missing)"},
};

static const sc_port_desc outputs[] = {
    {.name = "atlas", .kind = SC_KIND_ATLAS, .doc = "the quad atlas, level 0 (or the input, passed through)"},
    {.name = "levels", .kind = SC_KIND_LODS,
     .doc = "one atlas per mip level, uv shifted by the level's offset, seam-free at every level"},
};

static const sc_kernel *const kernels[] = {&sc_kernel_quad, &sc_kernel_seam, NULL};

const sc_node_desc sc_node_quad_chartify = {
    .type = "quad_chartify",
    .version = 5,
    .summary = "a seamless quad-chart atlas, seam-free at every mip level (Purnomo et al. 2004)",
    .inputs = inputs,
    .ninputs = SC_COUNT(inputs),
    .outputs = outputs,
    .noutputs = SC_COUNT(outputs),
    .params = params,
    .nparams = SC_COUNT(params),
    .run = run,
    .kernels = kernels,
};
