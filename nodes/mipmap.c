/* mipmap.c - the node `mipmap`: seam-free mip chains (Liu et al. 2017, §9:
 * "erase seams on each level independently").
 *
 * Design note.
 *  - Chains. Level m + 1 of a texture is the 2 x 2 box average of the erased
 *    level m (sides max(1, floor(n / 2)), GL's and OpenEXR's round-down rule;
 *    an odd last row or column is folded into its neighbour's box), down to
 *    1 x 1 (an OpenEXR mip-map holds every level); `levels` stops at
 *    `min_size`. Averaging is on the stored values, the
 *    way erase_seams and a GPU sampling the stored texture see them. A slot
 *    named "normal" (3+ channels) is renormalised after averaging (decoded
 *    as 2 x - 1 unless the image is float DATA with negative values).
 *  - Erasure. Every level (level 0 too, which passes through when its seam
 *    gaps are within `gap_tolerance`) is erased by the erase_seams node, run
 *    through sc_ctx (a pure function), on an atlas made of the mesh and that
 *    level's textures; 8/16-bit textures come back quantised by erase_seams
 *    (`quantize` optimal), float ones as f32. The next level is built from
 *    the erased float values.
 *  - Levels of detail. With `lods`, every level of detail gets its own chains,
 *    erased on its own seams, except a texture that is the very same image
 *    (same slot, material and digest) on every level: its chain is built once
 *    and erased on the union of every level's mesh (disjoint copies in one
 *    mesh), so it stays shared - the geometry image of bake_displacement.
 *  - Outputs. `levels` (LODS): with `atlas`, level m is the atlas's mesh with
 *    every texture at mip level m (a shorter chain repeats its last level);
 *    with `lods`, entry k * levels + m is LOD k at mip level m. render then
 *    checks every LOD at every mip level. `report`: the metrics and files
 *    mip/[lod<k>_]<material>_<slot>.exr (float textures: one tiled,
 *    mip-mapped OpenEXR holding every level) and
 *    mip/[lod<k>_]<material>_<slot>_level<m>.png (8/16-bit textures).
 *  - Metrics: [lod<k>.]level<m>.seam_energy and .max_seam_gap (the largest
 *    over the textures: sc_seam_energy on that LOD's mesh), level<m>.width,
 *    levels, erase runs and timings.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "sc_atlas_ops.h"
#include "sc_exec.h"
#include "sc_imageio.h"
#include "sc_nodes.h"
#include "sc_seam.h"


#define MAX_MIP 32

/* One mip chain: a texture of one source (or of all, when shared). */
typedef struct chain {
    const sc_texture *tex;     /* the level-0 texture (of the first source using it) */
    int32_t group;             /* erase group: source index, or nsrc for the union */
    int32_t source;            /* source index, or -1 when shared */
    int32_t count;             /* levels */
    sc_value *native[MAX_MIP]; /* erased, in the input's pixel type */
    sc_value *f32[MAX_MIP];    /* erased, float (what the next level is built from) */
} chain;

/* ---------------------------------------------------------------- images */

static void next_size(int32_t w, int32_t h, int32_t *w2, int32_t *h2) {
    *w2 = w / 2 > 0 ? w / 2 : 1;
    *h2 = h / 2 > 0 ? h / 2 : 1;
}

/* 2 x 2 box of a float image into the next size; odd remainders fold in. */
static sc_image_data *box_down(const sc_image_data *src, bool normal) {
    int32_t W = src->width, H = src->height, C = src->channels, w2, h2;
    next_size(W, H, &w2, &h2);
    sc_image_data *dst = sc_image_alloc(w2, h2, C, SC_PIXEL_F32);
    if (!dst) return NULL;
    dst->colorspace = src->colorspace;
    memcpy(dst->format, src->format, sizeof dst->format);
    const float *s = src->pixels;
    float *d = dst->pixels;
    bool signed_normals = false;
    if (normal && C >= 3 && src->colorspace == SC_COLOR_DATA)
        for (size_t t = 0; t < (size_t)W * H * C && !signed_normals; t++) signed_normals = s[t] < 0;
    for (int32_t j = 0; j < h2; j++) {
        int32_t j0 = H == 1 ? 0 : 2 * j, j1 = H == 1 ? 0 : (j == h2 - 1 ? H - 1 : 2 * j + 1);
        for (int32_t i = 0; i < w2; i++) {
            int32_t i0 = W == 1 ? 0 : 2 * i, i1 = W == 1 ? 0 : (i == w2 - 1 ? W - 1 : 2 * i + 1);
            double sum[4] = {0, 0, 0, 0};
            int n = 0;
            for (int32_t jj = j0; jj <= j1; jj++)
                for (int32_t ii = i0; ii <= i1; ii++, n++)
                    for (int32_t c = 0; c < C; c++) sum[c] += s[((size_t)jj * W + ii) * C + c];
            float *o = d + ((size_t)j * w2 + i) * C;
            for (int32_t c = 0; c < C; c++) o[c] = (float)(sum[c] / n);
            if (normal && C >= 3) {
                double v[3], l = 0;
                for (int c = 0; c < 3; c++) v[c] = signed_normals ? o[c] : 2.0 * o[c] - 1.0, l += v[c] * v[c];
                l = sqrt(l);
                if (l > 1e-12)
                    for (int c = 0; c < 3; c++) o[c] = (float)(signed_normals ? v[c] / l : 0.5 * (v[c] / l + 1.0));
            }
        }
    }
    return dst;
}

/* A float image in another pixel type, rounded to nearest (clamped). */
static sc_image_data *to_pixel(const sc_image_data *f, sc_pixel pixel) {
    sc_image_data *im = sc_image_alloc(f->width, f->height, f->channels, pixel);
    if (!im) return NULL;
    im->colorspace = f->colorspace;
    memcpy(im->format, f->format, sizeof im->format);
    size_t n = (size_t)f->width * f->height * f->channels;
    const float *s = f->pixels;
    double max = pixel == SC_PIXEL_U8 ? 255.0 : 65535.0;
    for (size_t t = 0; t < n; t++) {
        double v = s[t] > 0 ? (s[t] < 1 ? s[t] : 1) : 0;
        long q = lrint(v * max);
        if (pixel == SC_PIXEL_U8) ((uint8_t *)im->pixels)[t] = (uint8_t)q;
        else ((uint16_t *)im->pixels)[t] = (uint16_t)q;
    }
    return im;
}

/* ---------------------------------------------------------------- erasing */

/* Erase level m of the chains of one group on `mesh`: the input images are
 * in[i] (pixel type of the chain); results into the chains' level m. */
static int erase_level(sc_value *mesh, chain *const *chains, sc_value *const *in, int n, int m, double gap_tolerance,
                       int threads, int *runs, sc_error *err) {
    sc_atlas_ops_map *maps = calloc((size_t)n + 1, sizeof *maps);
    sc_value **f32 = calloc((size_t)n + 1, sizeof *f32), **native = calloc((size_t)n + 1, sizeof *native);
    int rc = maps && f32 && native ? SC_OK : sc_fail(err, SC_ENOMEM, "out of memory");
    for (int i = 0; i < n && rc == SC_OK; i++) {
        const sc_texture *t = chains[i]->tex;
        maps[i] = (sc_atlas_ops_map){t->material, t->wrap_u, t->wrap_v, in[i]};
    }
    if (rc == SC_OK) rc = sc_atlas_ops_erase(mesh, maps, n, gap_tolerance, NULL, NULL, threads, f32, native, err);
    if (rc == SC_OK) {
        (*runs)++;
        for (int i = 0; i < n; i++) chains[i]->f32[m] = f32[i], chains[i]->native[m] = native[i];
    } else {
        sc_error_prefix(err, "erase_seams at mip level %d", m);
    }
    free(maps), free(f32), free(native);
    return rc;
}

/* ---------------------------------------------------------------- files */

static void clean_name(const char *in, char *out, size_t size) {
    size_t k = 0;
    for (; in[k] && k + 1 < size; k++) {
        char c = in[k];
        bool ok = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_' || c == '-';
        out[k] = ok ? c : '_';
    }
    out[k] = 0;
    if (k == 0) snprintf(out, size, "material");
}

/* The report takes a copy of the buffer's bytes. */
static int add_copy(sc_report *r, const char *path, const sc_buf *b, sc_error *err) {
    void *copy = malloc(b->len ? b->len : 1);
    if (!copy) return sc_fail(err, SC_ENOMEM, "out of memory");
    memcpy(copy, b->data, b->len);
    if (sc_report_add_file(r, path, copy, b->len) != SC_OK) return sc_fail(err, SC_ENOMEM, "out of memory");
    return SC_OK;
}

static int add_files(sc_report *r, const chain *ch, const sc_mesh *mesh, sc_error *err) {
    char mat[96], slot[96], prefix[32] = "";
    clean_name(mesh->materials[ch->tex->material], mat, sizeof mat);
    clean_name(ch->tex->name, slot, sizeof slot);
    if (ch->source >= 0) snprintf(prefix, sizeof prefix, "lod%d_", ch->source);
    sc_buf b;
    sc_buf_init(&b);
    int rc = SC_OK;
    const sc_image_data *top = ch->native[0]->as.image;
    if (top->pixel == SC_PIXEL_F32) {
        const sc_image_data *levels[MAX_MIP];
        for (int m = 0; m < ch->count; m++) levels[m] = ch->native[m]->as.image;
        rc = sc_image_encode_exr_mip(levels, ch->count, &b, err);
        char path[320];
        snprintf(path, sizeof path, "mip/%s%s_%s.exr", prefix, mat, slot);
        if (rc == SC_OK) rc = add_copy(r, path, &b, err);
    } else {
        for (int m = 0; m < ch->count && rc == SC_OK; m++) {
            sc_buf_reset(&b);
            rc = sc_image_encode_png(ch->native[m]->as.image, 0, &b, err);
            char path[320];
            snprintf(path, sizeof path, "mip/%s%s_%s_level%d.png", prefix, mat, slot, m);
            if (rc == SC_OK) rc = add_copy(r, path, &b, err);
        }
    }
    sc_buf_free(&b);
    if (rc != SC_OK) sc_error_prefix(err, "writing the chain of '%s'", ch->tex->name);
    return rc;
}

/* ---------------------------------------------------------------- run */

static bool same_texture(const sc_texture *a, const sc_texture *b) {
    return a->material == b->material && strcmp(a->name, b->name) == 0 &&
           sc_digest_equal(&a->image->digest, &b->image->digest) && a->wrap_u == b->wrap_u && a->wrap_v == b->wrap_v;
}

static int run(sc_ctx *ctx, sc_error *err) {
    const sc_atlas *single = sc_ctx_atlas(ctx, "atlas");
    const sc_lods *lods = sc_ctx_lods(ctx, "lods");
    if (!single && !lods) return sc_fail(err, SC_EINPUT, "atlas: connect `atlas` or `lods`");
    if (single && lods) return sc_fail(err, SC_EINPUT, "lods: connect `atlas` or `lods`, not both");
    const int32_t nsrc = lods ? lods->count : 1;
    if (nsrc < 1) return sc_fail(err, SC_EINPUT, "lods: the list is empty");
    const int32_t min_size = (int32_t)sc_ctx_integer(ctx, "min_size");
    const double gap_tolerance = sc_ctx_number(ctx, "gap_tolerance");
    const int threads = sc_ctx_threads(ctx);
    const sc_atlas **src = calloc((size_t)nsrc, sizeof *src);
    if (!src) return sc_fail(err, SC_ENOMEM, "out of memory");
    int rc = SC_OK;
    for (int32_t k = 0; k < nsrc; k++) {
        src[k] = lods ? lods->levels[k]->as.atlas : single;
        if (src[k]->mesh->as.mesh->nmat != src[0]->mesh->as.mesh->nmat)
            rc = sc_fail(err, SC_EINPUT, "lods: level %d has other materials than level 0", k);
    }

    /* the chains: shared ones first (in level 0's texture order), then per source */
    int32_t cap = 0;
    for (int32_t k = 0; k < nsrc; k++) cap += src[k]->ntex;
    chain *chains = calloc((size_t)cap + 1, sizeof *chains);
    int32_t *map = calloc((size_t)cap + 1, sizeof *map);   /* (source, texture) -> chain */
    int32_t *first_tex = calloc((size_t)nsrc + 1, sizeof *first_tex);
    int32_t nchains = 0;
    if (!chains || !map || !first_tex) rc = sc_fail(err, SC_ENOMEM, "out of memory");
    for (int32_t k = 1; k <= nsrc && rc == SC_OK; k++) first_tex[k] = first_tex[k - 1] + src[k - 1]->ntex;
    for (int32_t t = 0; t < (rc == SC_OK ? src[0]->ntex : 0); t++) {
        const sc_texture *tx = &src[0]->textures[t];
        bool shared = nsrc > 1 && nsrc <= 256;
        int32_t idx[256];
        for (int32_t k = 1; k < nsrc && shared; k++) {
            idx[k] = -1;
            for (int32_t u = 0; u < src[k]->ntex && idx[k] < 0; u++)
                if (same_texture(tx, &src[k]->textures[u])) idx[k] = u;
            shared = idx[k] >= 0;
        }
        if (!shared) continue;
        chains[nchains] = (chain){.tex = tx, .group = nsrc, .source = -1};
        map[t] = nchains + 1;
        for (int32_t k = 1; k < nsrc; k++) map[first_tex[k] + idx[k]] = nchains + 1;
        nchains++;
    }
    for (int32_t k = 0; k < nsrc && rc == SC_OK; k++)
        for (int32_t t = 0; t < src[k]->ntex; t++) {
            if (map[first_tex[k] + t]) continue;
            chains[nchains] = (chain){.tex = &src[k]->textures[t], .group = k, .source = lods ? k : -1};
            map[first_tex[k] + t] = ++nchains;
        }

    /* chain lengths */
    int32_t nmip = 1, nall = 1;   /* levels output (down to min_size), levels built (down to 1 x 1) */
    for (int32_t c = 0; c < nchains && rc == SC_OK; c++) {
        const sc_image_data *im = chains[c].tex->image->as.image;
        int32_t w = im->width, h = im->height, n = 1, n_out = 0;
        while (true) {
            if (!n_out && w <= min_size && h <= min_size) n_out = n;
            if ((w == 1 && h == 1) || n == MAX_MIP) break;
            next_size(w, h, &w, &h), n++;
        }
        chains[c].count = n;
        if (!n_out) n_out = n;
        if (n_out > nmip) nmip = n_out;
        if (n > nall) nall = n;
    }

    /* erase meshes: each source's own, and the union for shared chains */
    sc_value *union_mesh = NULL;
    bool any_shared = nchains > 0 && chains[0].source < 0 && chains[0].group == nsrc;
    if (rc == SC_OK && any_shared) {
        const sc_mesh **ms = calloc((size_t)nsrc, sizeof *ms);
        for (int32_t k = 0; ms && k < nsrc; k++) ms[k] = src[k]->mesh->as.mesh;
        union_mesh = ms ? sc_atlas_ops_mesh_union(ms, nsrc) : NULL;
        free(ms);
        if (!union_mesh) rc = sc_fail(err, SC_ENOMEM, "out of memory for the union of the levels");
    }

    /* build and erase, level by level, one erase_seams run per group and level */
    double t0 = sc_now();
    int runs = 0;
    chain **members = calloc((size_t)nchains + 1, sizeof *members);
    sc_value **inputs = calloc((size_t)nchains + 1, sizeof *inputs);
    if (!members || !inputs) rc = sc_fail(err, SC_ENOMEM, "out of memory");
    for (int32_t m = 0; m < nall && rc == SC_OK; m++)
        for (int32_t g = 0; g <= nsrc && rc == SC_OK; g++) {
            int n = 0;
            for (int32_t c = 0; c < nchains && rc == SC_OK; c++) {
                chain *ch = &chains[c];
                if (ch->group != g || m >= ch->count) continue;
                sc_value *in = NULL;
                if (m == 0) {
                    in = sc_value_retain(ch->tex->image);
                } else {
                    bool normal = strcmp(ch->tex->name, "normal") == 0;
                    sc_image_data *f = box_down(ch->f32[m - 1]->as.image, normal);
                    sc_pixel px = ch->tex->image->as.image->pixel;
                    sc_image_data *q = f && px != SC_PIXEL_F32 ? to_pixel(f, px) : NULL;
                    if (q) sc_image_free(f), f = q;
                    else if (px != SC_PIXEL_F32) sc_image_free(f), f = NULL;
                    in = f ? sc_value_new_image(f) : NULL;
                    if (!in) rc = sc_fail(err, SC_ENOMEM, "out of memory at mip level %d", m);
                }
                members[n] = ch, inputs[n] = in, n++;
            }
            if (rc == SC_OK && n > 0) {
                sc_value *mesh = g == nsrc ? union_mesh : src[g]->mesh;
                rc = erase_level(mesh, members, inputs, n, m, gap_tolerance, threads, &runs, err);
            }
            for (int i = 0; i < n; i++) sc_value_release(inputs[i]);
        }
    double t_erase = sc_now() - t0;

    /* metrics: seam energy of every LOD at every mip level */
    t0 = sc_now();
    sc_report *report = rc == SC_OK ? sc_report_new() : NULL;
    if (rc == SC_OK && !report) rc = sc_fail(err, SC_ENOMEM, "out of memory");
    double worst_energy = 0, worst_gap = 0;
    for (int32_t k = 0; k < nsrc && rc == SC_OK; k++) {
        const sc_mesh *mesh = src[k]->mesh->as.mesh;
        double *energy = calloc((size_t)nall, sizeof *energy), *gap = calloc((size_t)nall, sizeof *gap);
        if (!energy || !gap) rc = sc_fail(err, SC_ENOMEM, "out of memory");
        for (int32_t mat = 0; mat < mesh->nmat && rc == SC_OK; mat++) {
            sc_seam_set seams;
            bool has = false;
            for (int32_t t = 0; t < src[k]->ntex; t++) has |= src[k]->textures[t].material == mat;
            if (!has) continue;
            rc = sc_seam_find(mesh, mat, &seams, err);
            if (rc != SC_OK) break;
            for (int32_t t = 0; t < src[k]->ntex && rc == SC_OK; t++) {
                if (src[k]->textures[t].material != mat) continue;
                const chain *ch = &chains[map[first_tex[k] + t] - 1];
                for (int32_t m = 0; m < ch->count && rc == SC_OK; m++) {
                    const sc_image_data *im = ch->native[m]->as.image;
                    sc_seam_grid g = {im->width, im->height, ch->tex->wrap_u, ch->tex->wrap_v};
                    double e = 0, gp = 0;
                    rc = sc_seam_energy(mesh, &seams, &g, im, threads, &e, &gp, err);
                    energy[m] = fmax(energy[m], e), gap[m] = fmax(gap[m], gp);
                }
            }
            sc_seam_set_free(&seams);
        }
        for (int32_t m = 0; m < nall && rc == SC_OK; m++) {
            char name[96], pre[24] = "";
            if (lods) snprintf(pre, sizeof pre, "lod%d.", k);
            snprintf(name, sizeof name, "%slevel%d.seam_energy", pre, m);
            sc_ctx_metric(ctx, name, energy[m]);   /* every level built, also below min_size */
            if (sc_report_metric(report, name, energy[m]) != SC_OK) rc = sc_fail(err, SC_ENOMEM, "out of memory");
            snprintf(name, sizeof name, "%slevel%d.max_seam_gap", pre, m);
            sc_ctx_metric(ctx, name, gap[m]);
            if (sc_report_metric(report, name, gap[m]) != SC_OK) rc = sc_fail(err, SC_ENOMEM, "out of memory");
            if (m < nmip) worst_energy = fmax(worst_energy, energy[m]), worst_gap = fmax(worst_gap, gap[m]);
        }
        free(energy), free(gap);
    }
    if (rc == SC_OK) {
        sc_ctx_metric(ctx, "levels", nmip);
        sc_ctx_metric(ctx, "chains", nchains);
        sc_ctx_metric(ctx, "erase_runs", runs);
        sc_ctx_metric(ctx, "seam_energy", worst_energy);
        sc_ctx_metric(ctx, "max_seam_gap", worst_gap);
        if (sc_report_metric(report, "levels", nmip) || sc_report_metric(report, "seam_energy", worst_energy) ||
            sc_report_metric(report, "max_seam_gap", worst_gap))
            rc = sc_fail(err, SC_ENOMEM, "out of memory");
    }
    double t_metrics = sc_now() - t0;

    /* files and the levels */
    t0 = sc_now();
    for (int32_t c = 0; c < nchains && rc == SC_OK; c++) {
        int32_t k = chains[c].source >= 0 ? chains[c].source : 0;
        rc = add_files(report, &chains[c], src[k]->mesh->as.mesh, err);
    }
    double t_files = sc_now() - t0;
    sc_lods *out = rc == SC_OK ? sc_lods_new() : NULL;
    if (rc == SC_OK && !out) rc = sc_fail(err, SC_ENOMEM, "out of memory");
    for (int32_t k = 0; k < nsrc && rc == SC_OK; k++)
        for (int32_t m = 0; m < nmip && rc == SC_OK; m++) {
            sc_atlas *a = sc_atlas_new(sc_value_retain(src[k]->mesh));
            if (!a) rc = SC_ENOMEM;
            for (int32_t t = 0; a && t < src[k]->ntex && rc == SC_OK; t++) {
                const sc_texture *tx = &src[k]->textures[t];
                const chain *ch = &chains[map[first_tex[k] + t] - 1];
                int32_t lm = m < ch->count ? m : ch->count - 1;
                rc = sc_atlas_add_texture(a, tx->name, tx->material, tx->wrap_u, tx->wrap_v, tx->source,
                                          sc_value_retain(ch->native[lm]));
            }
            sc_value *v = rc == SC_OK ? sc_value_new_atlas(a) : NULL;
            if (rc != SC_OK) sc_atlas_free(a);
            if (!v || sc_lods_add(out, v) != SC_OK) rc = sc_fail(err, SC_ENOMEM, "out of memory");
        }
    if (rc == SC_OK) {
        sc_value *lv = sc_value_new_lods(out);
        out = NULL;
        sc_value *rv = sc_value_new_report(report);
        report = NULL;
        if (!lv || !rv) {
            sc_value_release(lv), sc_value_release(rv);
            rc = sc_fail(err, SC_ENOMEM, "out of memory");
        } else {
            sc_ctx_set_output(ctx, "levels", lv);
            sc_ctx_set_output(ctx, "report", rv);
            sc_ctx_metric(ctx, "seconds_erase", t_erase);
            sc_ctx_metric(ctx, "seconds_metrics", t_metrics);
            sc_ctx_metric(ctx, "seconds_files", t_files);
        }
    }
    sc_lods_free(out);
    sc_report_free(report);
    for (int32_t c = 0; chains && c < nchains; c++)
        for (int m = 0; m < MAX_MIP; m++) sc_value_release(chains[c].native[m]), sc_value_release(chains[c].f32[m]);
    sc_value_release(union_mesh);
    free(members), free(inputs), free(chains), free(map), free(first_tex), free(src);
    return rc;
}

static const sc_param_desc params[] = {
    {.name = "min_size", .type = SC_PARAM_INTEGER, .def = 1, .min = 1, .max = 32768,
     .doc = "the chain stops once both sides are at most this many texels"},
    {.name = "gap_tolerance", .type = SC_PARAM_NUMBER, .def = 0, .min = 0, .max = 1,
     .doc = "erase_seams's gap_tolerance: a level whose seam gaps are within it is kept as it is"},
};

static const sc_port_desc inputs[] = {
    {.name = "atlas", .kind = SC_KIND_ATLAS, .optional = true, .doc = "a textured mesh"},
    {.name = "lods", .kind = SC_KIND_LODS, .optional = true,
     .doc = "levels of detail (instead of atlas): each gets its own chains, shared textures one chain"},
};

static const sc_port_desc outputs[] = {
    {.name = "levels", .kind = SC_KIND_LODS,
     .doc = "mip level m of the atlas at entry m; with lods, LOD k at mip level m at entry k * levels + m"},
    {.name = "report", .kind = SC_KIND_REPORT,
     .doc = "mip/<material>_<slot>.exr (tiled, mip-mapped), mip/<material>_<slot>_level<m>.png, seam energies"},
};

const sc_node_desc sc_node_mipmap = {
    .type = "mipmap",
    .version = 1,
    .summary = "mip chains with seams erased on every level independently (Liu et al. 2017 §9)",
    .inputs = inputs,
    .ninputs = SC_COUNT(inputs),
    .outputs = outputs,
    .noutputs = SC_COUNT(outputs),
    .params = params,
    .nparams = SC_COUNT(params),
    .run = run,
};
