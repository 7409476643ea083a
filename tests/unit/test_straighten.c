/* test_straighten.c - the straighten node (Liu et al. 2017 §6).
 *
 * Every property is recomputed here from the output atlas, apart from the
 * node's own bookkeeping: seams are found again from FV/FU, length ratios of
 * both sides of every straightened seam are compared from the output uv,
 * flips from signed uv areas, and appearance with a bilinear sampler written
 * here from docs/design.md's convention (texel (i, j) centre at ((i + 1/2)/W,
 * (j + 1/2)/H), row 0 = v = 0, GL wrap modes).
 *
 * Corpus assets come from SC_CORPUS (default ../shared/corpus) and are
 * skipped when absent. The whole file takes ~6 s optimised, ~20 s under
 * ASan/UBSan.
 */
#include <stdlib.h>

#include "sc_exec.h"
#include "sc_imageio.h"
#include "sc_nodes.h"
#include "sc_ref_seam.h"
#include "sc_tangent.h"
#include "sc_test.h"

/* ================================================================ reference sampler */

static int32_t wrap_index(int64_t i, int32_t n, sc_wrap w) {
    if (w == SC_WRAP_CLAMP) return i < 0 ? 0 : i >= n ? n - 1 : (int32_t)i;
    if (w == SC_WRAP_MIRROR) {
        int64_t period = 2 * (int64_t)n, k = ((i % period) + period) % period;
        return (int32_t)(k < n ? k : period - 1 - k);
    }
    return (int32_t)(((i % n) + n) % n);
}

/* A texel as seen: sRGB colour decoded (IEC 61966-2-1) to linear light. */
static double seen_texel(const sc_image_data *im, int32_t i, int32_t j, int32_t c) {
    double v = sc_image_texel(im, i, j, c);
    bool alpha = (im->channels == 2 && c == 1) || (im->channels == 4 && c == 3);
    if (im->colorspace != SC_COLOR_SRGB || alpha) return v;
    return v <= 0.04045 ? v / 12.92 : pow((v + 0.055) / 1.055, 2.4);
}

static void bilinear(const sc_image_data *im, sc_wrap wu, sc_wrap wv, double u, double v, double *out) {
    double x = u * im->width - 0.5, y = v * im->height - 0.5;
    double fx = floor(x), fy = floor(y), s = x - fx, t = y - fy;
    int32_t i0 = wrap_index((int64_t)fx, im->width, wu), i1 = wrap_index((int64_t)fx + 1, im->width, wu);
    int32_t j0 = wrap_index((int64_t)fy, im->height, wv), j1 = wrap_index((int64_t)fy + 1, im->height, wv);
    for (int32_t c = 0; c < im->channels; c++)
        out[c] = (1 - s) * (1 - t) * seen_texel(im, i0, j0, c) + s * (1 - t) * seen_texel(im, i1, j0, c) +
                 (1 - s) * t * seen_texel(im, i0, j1, c) + s * t * seen_texel(im, i1, j1, c);
}

/* PSNR (peak 1, linear light for sRGB colour) of every texture of `in` that
 * the output replaced: colour at a barycentric grid of every face, old
 * texture at old uv against new texture at new uv. */
static double appearance_psnr(const sc_atlas *in, const sc_atlas *out, int grid, int *compared) {
    const sc_mesh *mi = in->mesh->as.mesh, *mo = out->mesh->as.mesh;
    double sum2 = 0, count = 0, a[4], b[4];
    *compared = 0;
    for (int32_t k = 0; k < in->ntex; k++) {
        const sc_texture *ti = &in->textures[k];
        int o = sc_atlas_find_texture(out, ti->material, ti->name);
        if (o < 0 || out->textures[o].image == ti->image) continue;
        (*compared)++;
        const sc_image_data *old = ti->image->as.image, *new = out->textures[o].image->as.image;
        for (int32_t f = 0; f < mi->nf; f++) {
            if (mi->FM[f] != ti->material) continue;
            for (int i = 0; i <= grid; i++)
                for (int j = 0; i + j <= grid; j++) {
                    double w[3] = {(double)i / grid, (double)j / grid, (double)(grid - i - j) / grid};
                    double uo[2] = {0, 0}, un[2] = {0, 0};
                    for (int c = 0; c < 3; c++)
                        for (int d = 0; d < 2; d++) {
                            uo[d] += w[c] * mi->U[2 * mi->FU[3 * f + c] + d];
                            un[d] += w[c] * mo->U[2 * mo->FU[3 * f + c] + d];
                        }
                    bilinear(old, ti->wrap_u, ti->wrap_v, uo[0], uo[1], a);
                    bilinear(new, out->textures[o].wrap_u, out->textures[o].wrap_v, un[0], un[1], b);
                    for (int32_t c = 0; c < old->channels; c++) sum2 += (a[c] - b[c]) * (a[c] - b[c]);
                    count += old->channels;
                }
        }
    }
    if (count == 0) return INFINITY;
    return sum2 > 0 ? 10 * log10(count / sum2) : INFINITY;
}

/* ================================================================ geometry checks */

static double area2(const double *U, const int32_t *fu) {
    const double *a = U + 2 * fu[0], *b = U + 2 * fu[1], *c = U + 2 * fu[2];
    return (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
}

/* Faces whose uv orientation changed (or vanished); input faces with no uv
 * area are left out. */
static int64_t flipped_faces(const sc_mesh *in, const sc_mesh *out) {
    int64_t n = 0;
    for (int32_t f = 0; f < in->nf; f++) {
        double a0 = area2(in->U, in->FU + 3 * f), a1 = area2(out->U, out->FU + 3 * f);
        if (a0 != 0 && !(a0 * a1 > 0)) n++;
    }
    return n;
}

typedef struct seam_half {
    int32_t lo, hi, face, uv_lo, uv_hi;
} seam_half;

static int compare_half(const void *x, const void *y) {
    const seam_half *p = x, *q = y;
    if (p->lo != q->lo) return p->lo < q->lo ? -1 : 1;
    if (p->hi != q->hi) return p->hi < q->hi ? -1 : 1;
    return (p->face > q->face) - (p->face < q->face);
}

typedef struct ratio_check {
    int64_t seam_edges, checked, bad;
    double worst;
} ratio_check;

/* At every surface vertex with exactly two seam edges whose uv moved on both
 * sides: both sides collinear there and the vertex at the same fraction of
 * the two edges' length on both sides (1e-12). */
static ratio_check check_seam_ratios(const sc_mesh *in, const sc_mesh *out) {
    ratio_check r = {0};
    size_t nh = (size_t)in->nf * 3;
    seam_half *h = malloc(nh * sizeof *h);
    int32_t *seam_count = calloc((size_t)in->nv, sizeof(int32_t));
    int32_t (*seams)[2] = malloc((size_t)in->nv * sizeof *seams);   /* index into h of a seam's first half */
    for (int32_t f = 0; f < in->nf; f++)
        for (int k = 0; k < 3; k++) {
            int32_t a = in->FV[3 * f + k], b = in->FV[3 * f + (k + 1) % 3];
            int32_t ua = in->FU[3 * f + k], ub = in->FU[3 * f + (k + 1) % 3];
            h[3 * f + k] = a < b ? (seam_half){a, b, f, ua, ub} : (seam_half){b, a, f, ub, ua};
        }
    qsort(h, nh, sizeof *h, compare_half);
    for (size_t i = 0; i + 1 < nh; i++) {
        if (h[i].lo != h[i + 1].lo || h[i].hi != h[i + 1].hi) continue;
        if ((i + 2 < nh && h[i + 2].lo == h[i].lo && h[i + 2].hi == h[i].hi) ||
            (i > 0 && h[i - 1].lo == h[i].lo && h[i - 1].hi == h[i].hi))
            continue;   /* non-manifold */
        if (h[i].uv_lo == h[i + 1].uv_lo && h[i].uv_hi == h[i + 1].uv_hi) continue;
        r.seam_edges++;
        int32_t ends[2] = {h[i].lo, h[i].hi};
        for (int e = 0; e < 2; e++) {
            int32_t v = ends[e];
            if (seam_count[v] < 2) seams[v][seam_count[v]] = (int32_t)i;
            seam_count[v]++;
        }
    }
    for (int32_t v = 0; v < in->nv; v++) {
        if (seam_count[v] != 2) continue;
        const seam_half *p = &h[seams[v][0]], *q = &h[seams[v][1]];
        /* per half: uv at v and at the far end */
        int32_t p_at[2], p_far[2], q_at[2], q_far[2];
        for (int s = 0; s < 2; s++) {
            p_at[s] = p[s].lo == v ? p[s].uv_lo : p[s].uv_hi;
            p_far[s] = p[s].lo == v ? p[s].uv_hi : p[s].uv_lo;
            q_at[s] = q[s].lo == v ? q[s].uv_lo : q[s].uv_hi;
            q_far[s] = q[s].lo == v ? q[s].uv_hi : q[s].uv_lo;
        }
        if (p_at[0] == p_at[1]) continue;
        int swap = q_at[0] == p_at[0] ? 0 : 1;
        if (q_at[swap] != p_at[0] || q_at[1 - swap] != p_at[1]) continue;
        bool moved = true;
        for (int s = 0; s < 2; s++) {
            int32_t x = p_at[s];
            moved = moved && (in->U[2 * x] != out->U[2 * x] || in->U[2 * x + 1] != out->U[2 * x + 1]);
        }
        if (!moved) continue;
        double frac[2];
        bool ok = true;
        for (int s = 0; s < 2; s++) {
            const double *x = out->U + 2 * p_at[s], *a = out->U + 2 * p_far[s];
            const double *b = out->U + 2 * q_far[swap == 0 ? s : 1 - s];
            double da = hypot(x[0] - a[0], x[1] - a[1]), db = hypot(b[0] - x[0], b[1] - x[1]);
            double chord = hypot(b[0] - a[0], b[1] - a[1]);
            double off = fabs((x[0] - a[0]) * (b[1] - a[1]) - (x[1] - a[1]) * (b[0] - a[0])) / chord;
            ok = ok && off <= 1e-12 && da + db > 0;
            frac[s] = da / (da + db);
        }
        double diff = fabs(frac[0] - frac[1]);
        r.checked++;
        if (!ok || !(diff <= 1e-12)) r.bad++;
        if (diff > r.worst) r.worst = diff;
    }
    free(h), free(seam_count), free(seams);
    return r;
}

/* ================================================================ running */

static sc_ctx *run_straighten(sc_value *atlas, const char *const *kv, sc_error *err) {
    sc_ctx *ctx = sc_ctx_new(&sc_node_straighten, NULL, NULL);
    sc_ctx_set_threads(ctx, 2);
    int rc = sc_ctx_set_input(ctx, "atlas", atlas);
    for (int i = 0; kv && kv[i] && rc == SC_OK; i += 2) rc = sc_ctx_set_param(ctx, kv[i], kv[i + 1], err);
    if (rc == SC_OK) rc = sc_ctx_run(ctx, err);
    if (rc != SC_OK) {
        sc_ctx_free(ctx);
        return NULL;
    }
    return ctx;
}

/* ================================================================ synthetic asset */

/* A wavy N x N grid cut down the middle column into two charts; the seam is
 * wiggly in uv and parameterised differently on its two sides, so neither
 * side is straight and their length ratios differ. */
static sc_value *make_cut_grid(int N, bool wiggle) {
    int half = N / 2;
    int32_t nv = (N + 1) * (N + 1), nuL = (half + 1) * (N + 1), nu = 2 * nuL, nf = 2 * N * N;
    sc_mesh *m = sc_mesh_alloc(nv, nu, 0, nf, 1);
    m->materials[0] = sc_strdup("grid");
    for (int j = 0; j <= N; j++)
        for (int i = 0; i <= N; i++) {
            double *p = m->V + 3 * (j * (N + 1) + i);
            p[0] = (double)i / N, p[1] = (double)j / N, p[2] = 0.1 * sin(3.0 * i / N) * cos(2.0 * j / N);
        }
    for (int side = 0; side < 2; side++)
        for (int j = 0; j <= N; j++)
            for (int k = 0; k <= half; k++) {
                double *q = m->U + 2 * (side * nuL + j * (half + 1) + k);
                double s = (double)j / N;
                bool on_seam = (side == 0 && k == half) || (side == 1 && k == 0);
                if (on_seam && wiggle && j > 0 && j < N) s = side == 0 ? pow(s, 1.15) : s + 0.02 * sin(7.0 * s);
                q[0] = (side == 0 ? 0.05 : 0.55) + 0.4 * k / half;
                q[1] = 0.05 + 0.9 * s;
                if (on_seam && wiggle && j > 0 && j < N) q[0] += (side == 0 ? 0.006 : -0.005) * sin(2.3 * j);
            }
    int32_t f = 0;
    for (int j = 0; j < N; j++)
        for (int i = 0; i < N; i++) {
            int side = i < half ? 0 : 1, k0 = i - side * half;
            int32_t v00 = j * (N + 1) + i, v10 = v00 + 1, v01 = v00 + N + 1, v11 = v01 + 1;
            int32_t u00 = side * nuL + j * (half + 1) + k0, u10 = u00 + 1, u01 = u00 + half + 1, u11 = u01 + 1;
            int32_t fv[6] = {v00, v10, v11, v00, v11, v01}, fu[6] = {u00, u10, u11, u00, u11, u01};
            for (int c = 0; c < 6; c++) m->FV[3 * f + c] = fv[c], m->FU[3 * f + c] = fu[c];
            m->FM[f] = m->FM[f + 1] = 0;
            f += 2;
        }
    sc_image_data *im = sc_image_alloc(128, 128, 3, SC_PIXEL_F32);
    float *px = im->pixels;
    for (int j = 0; j < 128; j++)
        for (int i = 0; i < 128; i++) {
            double u = (i + 0.5) / 128, v = (j + 0.5) / 128;
            px[3 * (j * 128 + i) + 0] = (float)(0.5 + 0.4 * sin(6 * u) * cos(5 * v));
            px[3 * (j * 128 + i) + 1] = (float)(0.5 + 0.3 * cos(4 * u + 3 * v));
            px[3 * (j * 128 + i) + 2] = (float)v;
        }
    im->colorspace = SC_COLOR_LINEAR;
    sc_atlas *a = sc_atlas_new(sc_value_new_mesh(m));
    sc_atlas_add_texture(a, "color", 0, SC_WRAP_CLAMP, SC_WRAP_CLAMP, "", sc_value_new_image(im));
    return sc_value_new_atlas(a);
}

SC_TEST(synthetic_seam_straightened) {
    sc_value *atlas = make_cut_grid(16, true);
    sc_error err = {0};
    sc_ctx *ctx = run_straighten(atlas, NULL, &err);
    SC_CHECK_MSG(ctx != NULL, "%s", err.message);
    if (!ctx) {
        sc_value_release(atlas);
        return;
    }
    const sc_atlas *in = atlas->as.atlas, *out = sc_ctx_output(ctx, 0)->as.atlas;
    const sc_mesh *mi = in->mesh->as.mesh, *mo = out->mesh->as.mesh;
    /* surface and uv topology untouched */
    SC_CHECK_INT(mo->nv, mi->nv);
    SC_CHECK_INT(mo->nu, mi->nu);
    SC_CHECK(memcmp(mo->V, mi->V, sizeof(double) * 3 * (size_t)mi->nv) == 0);
    SC_CHECK(memcmp(mo->FV, mi->FV, sizeof(int32_t) * 3 * (size_t)mi->nf) == 0);
    SC_CHECK(memcmp(mo->FU, mi->FU, sizeof(int32_t) * 3 * (size_t)mi->nf) == 0);
    ratio_check r = check_seam_ratios(mi, mo);
    SC_CHECK_INT(r.seam_edges, 16);
    SC_CHECK_MSG(r.checked >= 5 && r.bad == 0, "checked %lld, bad %lld, worst %g", (long long)r.checked,
                 (long long)r.bad, r.worst);
    SC_CHECK_INT(flipped_faces(mi, mo), 0);
    SC_CHECK_INT(sc_ctx_metric_value(ctx, "flipped_triangles"), 0);
    double before = sc_ctx_metric_value(ctx, "collapsible_seam_edges_before");
    double after = sc_ctx_metric_value(ctx, "collapsible_seam_edges_after");
    SC_CHECK_MSG(after > before, "collapsible %g -> %g", before, after);
    int compared = 0;
    double psnr = appearance_psnr(in, out, 6, &compared);
    SC_CHECK_INT(compared, 1);
    SC_CHECK_MSG(psnr >= 35, "psnr %g", psnr);
    printf("     grid: collapsible %g -> %g, psnr %.1f dB (node %.1f), ratio worst %.2g\n", before, after, psnr,
           sc_ctx_metric_value(ctx, "psnr"), r.worst);
    /* the output is a fixed point: straightening it again moves nothing */
    sc_error err2 = {0};
    sc_value *first = sc_value_retain(sc_ctx_output(ctx, 0));
    sc_ctx *again = run_straighten(first, (const char *const[]){"erase", "false", NULL}, &err2);
    SC_CHECK_MSG(again != NULL, "%s", err2.message);
    if (again) SC_CHECK(sc_ctx_output(again, 0) == first);
    sc_ctx_free(again);
    sc_value_release(first);
    sc_ctx_free(ctx);
    sc_value_release(atlas);
}

/* An 8-bit texture whose seams need no erasing after the warp (one colour
 * everywhere) still comes out of atlas_native in 8 bits, the warp's float
 * image rounded back to the input's type, as an erased one would: the
 * main job saves atlas_native, and an 8-bit input is written as 8-bit PNG. */
SC_TEST(an_already_seam_free_texture_keeps_its_pixel_type) {
    sc_value *grid = make_cut_grid(16, true);
    const sc_atlas *g = grid->as.atlas;
    sc_image_data *im = sc_image_alloc(128, 128, 3, SC_PIXEL_U8);
    memset(im->pixels, 200, (size_t)128 * 128 * 3);
    im->colorspace = SC_COLOR_SRGB;
    sc_atlas *a = sc_atlas_new(sc_value_retain(g->mesh));
    sc_atlas_add_texture(a, "color", 0, SC_WRAP_CLAMP, SC_WRAP_CLAMP, "", sc_value_new_image(im));
    sc_value *atlas = sc_value_new_atlas(a);
    sc_value_release(grid);
    sc_error err = {0};
    sc_ctx *ctx = run_straighten(atlas, NULL, &err);
    SC_CHECK_MSG(ctx != NULL, "%s", err.message);
    if (ctx) {
        SC_CHECK(sc_ctx_metric_value(ctx, "moved_uv_vertices") > 0);
        SC_CHECK(sc_ctx_metric_value(ctx, "erase.textures_unchanged") == 1);
        const sc_image_data *native = sc_ctx_output(ctx, 1)->as.atlas->textures[0].image->as.image;
        SC_CHECK_MSG(native->pixel == SC_PIXEL_U8 && native->colorspace == SC_COLOR_SRGB, "pixel %d, colour space %d",
                     (int)native->pixel, (int)native->colorspace);
        int64_t off = 0;
        for (size_t k = 0; native->pixel == SC_PIXEL_U8 && k < (size_t)128 * 128 * 3; k++)
            off += ((const uint8_t *)native->pixels)[k] != 200;
        SC_CHECK_MSG(off == 0, "%lld samples not 200", (long long)off);
        SC_CHECK(sc_ctx_output(ctx, 0)->as.atlas->textures[0].image->as.image->pixel == SC_PIXEL_F32);
    }
    sc_ctx_free(ctx);
    sc_value_release(atlas);
}

/* The object-space field of the tangent-space test map: the shading
 * normal N tipped toward +x. */
static void tipped(const double N[3], double n[3]) {
    double l = 0;
    for (int d = 0; d < 3; d++) n[d] = N[d] + (d == 0 ? 0.3 : 0), l += n[d] * n[d];
    for (int d = 0; d < 3; d++) n[d] /= sqrt(l);
}

/* The atlas with a W x W tangent-space normal map (f32, 0..1 encoded) of
 * `tipped`, through the mesh's frames, in place of its textures. */
static sc_value *with_tangent_map(const sc_value *atlas, int W) {
    const sc_mesh *m = atlas->as.atlas->mesh->as.mesh;
    sc_error err = {0};
    sc_tangent_frames fr;
    sc_tangent_texels tx;
    sc_seam_grid g = {W, W, SC_WRAP_CLAMP, SC_WRAP_CLAMP};
    SC_CHECK(sc_tangent_frames_build(m, &fr, &err) == SC_OK);
    SC_CHECK(sc_tangent_texels_build(m, 0, &g, 3.0, 2, &tx, &err) == SC_OK);
    sc_image_data *map = sc_image_alloc(W, W, 3, SC_PIXEL_F32);
    map->colorspace = SC_COLOR_DATA;
    float *px = map->pixels;
    for (size_t id = 0; id < (size_t)W * W; id++) {
        double t[3] = {0, 0, 1};
        if (tx.face[id] >= 0) {
            double b[3] = {1 - tx.bary[2 * id] - tx.bary[2 * id + 1], tx.bary[2 * id], tx.bary[2 * id + 1]};
            double T[3], B[3], N[3], n[3];
            sc_tangent_frame_at(&fr, tx.face[id], b, T, B, N);
            tipped(N, n);
            ref_solve3(T, B, N, n, t);
        }
        for (int c = 0; c < 3; c++) px[3 * id + c] = (float)(0.5 + 0.5 * t[c]);
    }
    sc_tangent_texels_free(&tx);
    sc_tangent_frames_free(&fr);
    sc_atlas *a = sc_atlas_new(sc_value_retain(atlas->as.atlas->mesh));
    sc_atlas_add_texture(a, "normal", 0, SC_WRAP_CLAMP, SC_WRAP_CLAMP, "", sc_value_new_image(map));
    return sc_value_new_atlas(a);
}

/* The largest distance from `tipped` of the normal a renderer rebuilds at
 * the face centres of `frames_of`: the map sampled (bilinear) at the
 * centre's uv in `uv_of`, decoded, taken through the frame there. */
static double field_error(const sc_mesh *uv_of, const sc_mesh *frames_of, const sc_image_data *map) {
    sc_error err = {0};
    sc_tangent_frames fr;
    if (sc_tangent_frames_build(frames_of, &fr, &err) != SC_OK) return INFINITY;
    double worst = 0;
    for (int32_t f = 0; f < frames_of->nf; f++) {
        double b[3] = {1.0 / 3, 1.0 / 3, 1.0 / 3}, uv[2] = {0, 0}, e[3], T[3], B[3], N[3], n[3], want[3], l = 0;
        for (int c = 0; c < 3; c++)
            for (int d = 0; d < 2; d++) uv[d] += b[c] * uv_of->U[2 * (size_t)uv_of->FU[3 * f + c] + d];
        bilinear(map, SC_WRAP_CLAMP, SC_WRAP_CLAMP, uv[0], uv[1], e);
        sc_tangent_frame_at(&fr, f, b, T, B, N);
        for (int d = 0; d < 3; d++) {
            n[d] = 0;
            for (int c = 0; c < 3; c++) n[d] += (2 * e[c] - 1) * (c == 0 ? T : c == 1 ? B : N)[d];
            l += n[d] * n[d];
        }
        tipped(N, want);
        for (int d = 0; d < 3; d++) e[d] = n[d] / sqrt(l) - want[d];
        worst = fmax(worst, sqrt(e[0] * e[0] + e[1] * e[1] + e[2] * e[2]));
    }
    sc_tangent_frames_free(&fr);
    return worst;
}

/* A tangent-space normal map holds vectors in frames that follow the uv:
 * straightening shears the charts, so the frames turn, and the map is
 * re-rendered through them (to object space with the input's frames, back
 * with the output's). The normal rebuilt from the output stays the field
 * the input held; the input's vectors taken as they are through the new
 * frames would not. */
SC_TEST(tangent_space_map_follows_the_moved_frames) {
    sc_value *grid = make_cut_grid(16, true), *atlas = with_tangent_map(grid, 256);
    sc_error err = {0};
    sc_ctx *ctx = run_straighten(atlas, (const char *const[]){"erase", "false", "normal_space", "tangent", NULL}, &err);
    SC_CHECK_MSG(ctx != NULL, "%s", err.message);
    if (ctx) {
        const sc_atlas *in = atlas->as.atlas, *out = sc_ctx_output(ctx, 0)->as.atlas;
        const sc_mesh *mi = in->mesh->as.mesh, *mo = out->mesh->as.mesh;
        const sc_image_data *before = in->textures[0].image->as.image, *after = out->textures[0].image->as.image;
        double held = field_error(mi, mi, before), kept = field_error(mo, mo, after), unturned = field_error(mi, mo, before);
        printf("     field error at face centres: input %.4f, output %.4f; the input's vectors through the "
               "output's frames %.4f\n", held, kept, unturned);
        SC_CHECK_INT(sc_ctx_metric_value(ctx, "tangent_maps_reframed"), 1);
        SC_CHECK(kept < 1e-3);
        SC_CHECK_MSG(unturned > 10 * kept, "%g against %g", unturned, kept);
    }
    sc_ctx_free(ctx);
    /* erased after the warp, an 8-bit map stays 8-bit in atlas_native,
     * whether erasure through the frames is kept or the map is left */
    sc_image_data *u8 = sc_image_quantize(atlas->as.atlas->textures[0].image->as.image, SC_PIXEL_U8, SC_COLOR_DATA);
    sc_atlas *a8 = sc_atlas_new(sc_value_retain(atlas->as.atlas->mesh));
    sc_atlas_add_texture(a8, "normal", 0, SC_WRAP_CLAMP, SC_WRAP_CLAMP, "", sc_value_new_image(u8));
    sc_value *atlas8 = sc_value_new_atlas(a8);
    ctx = run_straighten(atlas8, (const char *const[]){"normal_space", "tangent", NULL}, &err);
    SC_CHECK_MSG(ctx != NULL, "%s", err.message);
    if (ctx) {
        const sc_image_data *nat = sc_ctx_output(ctx, 1)->as.atlas->textures[0].image->as.image;
        printf("     8-bit map, erased: left %g, normal gap mean %.4f -> %.4f, written as %d-byte texels\n",
               sc_ctx_metric_value(ctx, "erase.tangent_space_left"),
               sc_ctx_metric_value(ctx, "erase.normal_gap_mean_before"),
               sc_ctx_metric_value(ctx, "erase.normal_gap_mean_after"), (int)nat->pixel);
        SC_CHECK(nat->pixel == SC_PIXEL_U8);
    }
    sc_ctx_free(ctx);
    sc_value_release(atlas8);
    sc_value_release(atlas);
    sc_value_release(grid);
}

/* Nothing to straighten: without erase the input itself; with it (the
 * default) the same mesh, its texture erased as it is. */
static void check_unmoved(sc_value *atlas, const char *tolerance) {
    sc_error err = {0};
    sc_ctx *ctx = run_straighten(atlas, (const char *const[]){"tolerance", tolerance, "erase", "0", NULL}, &err);
    SC_CHECK_MSG(ctx != NULL, "%s", err.message);
    if (ctx) {
        sc_value *out = sc_ctx_output(ctx, 0);
        SC_CHECK(out == atlas);
        SC_CHECK(out && sc_digest_equal(sc_value_digest(out), sc_value_digest(atlas)));
    }
    sc_ctx_free(ctx);
    ctx = run_straighten(atlas, (const char *const[]){"tolerance", tolerance, NULL}, &err);
    SC_CHECK_MSG(ctx != NULL, "%s", err.message);
    if (ctx) {
        const sc_atlas *in = atlas->as.atlas, *out = sc_ctx_output(ctx, 1)->as.atlas;
        const sc_mesh *a = in->mesh->as.mesh, *b = out->mesh->as.mesh;
        SC_CHECK(a->nu == b->nu && !memcmp(a->U, b->U, sizeof(double) * 2 * (size_t)a->nu));
        SC_CHECK_INT((int)sc_ctx_metric_value(ctx, "moved_uv_vertices"), 0);
        double before = sc_ctx_metric_value(ctx, "erase.seam_energy_before");
        double after = sc_ctx_metric_value(ctx, "erase.seam_energy_after");
        printf("     unmoved (tolerance %s): seam energy %.3g -> %.3g\n", tolerance, before, after);
        SC_CHECK(before > 0 && after < 1e-6 * before);
    }
    sc_ctx_free(ctx);
}

SC_TEST(already_straight_is_unchanged) {
    sc_value *atlas = make_cut_grid(8, false);
    check_unmoved(atlas, "0.01");
    sc_value_release(atlas);
}

SC_TEST(tolerance_zero_keeps_the_wiggle) {
    sc_value *atlas = make_cut_grid(8, true);
    check_unmoved(atlas, "0");
    sc_value_release(atlas);
}

SC_TEST(bad_tolerance_is_named) {
    sc_ctx *ctx = sc_ctx_new(&sc_node_straighten, NULL, NULL);
    sc_error err = {0};
    int rc = sc_ctx_set_param(ctx, "tolerance", "-0.5", &err);
    SC_CHECK(rc != SC_OK);
    SC_CHECK_MSG(strstr(err.message, "straighten:tolerance") != NULL, "%s", err.message);
    sc_ctx_free(ctx);
}

/* ================================================================ corpus */

/* PSNR (peak 1) between the render node's textured pictures of two atlases
 * (6 axis views, 256^2), over the pixels where either picture shows the
 * mesh: the appearance a user sees, before vs after. -1 when rendering
 * fails. */
static double render_psnr(sc_value *before, sc_value *after) {
    static const char *const views[] = {"posx", "negx", "posy", "negy", "posz", "negz"};
    static const char *const params[] = {"modes", "textured", "views", "6", "size", "256", "pictures", "all", NULL};
    sc_value *reports[2] = {NULL, NULL};
    sc_value *atlases[2] = {before, after};
    for (int k = 0; k < 2; k++) {
        sc_ctx *ctx = sc_ctx_new(&sc_node_render, NULL, NULL);
        sc_error err = {0};
        int rc = sc_ctx_set_input(ctx, "atlas", atlases[k]);
        for (int i = 0; params[i] && rc == SC_OK; i += 2) rc = sc_ctx_set_param(ctx, params[i], params[i + 1], &err);
        if (rc == SC_OK) rc = sc_ctx_run(ctx, &err);
        if (rc == SC_OK) reports[k] = sc_value_retain(sc_ctx_output(ctx, 0));
        else printf("     render: %s\n", err.message);
        sc_ctx_free(ctx);
    }
    double sum = 0;
    int64_t count = 0;
    bool ok = reports[0] && reports[1];
    for (int v = 0; v < 6 && ok; v++) {
        char path[64];
        snprintf(path, sizeof path, "render/lod0_textured_%s.png", views[v]);
        sc_image_data *im[2] = {NULL, NULL};
        for (int k = 0; k < 2 && ok; k++) {
            const sc_report *rep = reports[k]->as.report;
            const sc_bytes *png = NULL;
            for (int32_t f = 0; f < rep->nfiles; f++)
                if (strcmp(rep->files[f].path, path) == 0) png = rep->files[f].bytes->as.bytes;
            sc_error err = {0};
            ok = png && sc_image_decode(path, png->data, png->size, &im[k], &err) == SC_OK;
        }
        if (ok && (im[0]->width != im[1]->width || im[0]->height != im[1]->height)) ok = false;
        for (int32_t y = 0; ok && y < im[0]->height; y++)
            for (int32_t x = 0; x < im[0]->width; x++) {
                static const double background[3] = {38 / 255.0, 42 / 255.0, 48 / 255.0};
                bool mesh = false;
                double d2 = 0;
                for (int c = 0; c < 3; c++) {
                    double a = sc_image_texel(im[0], x, y, c), b = sc_image_texel(im[1], x, y, c);
                    mesh |= fabs(a - background[c]) > 1e-3 || fabs(b - background[c]) > 1e-3;
                    d2 += (a - b) * (a - b);
                }
                if (mesh) sum += d2 / 3, count++;
            }
        sc_image_free(im[0]);
        sc_image_free(im[1]);
    }
    sc_value_release(reports[0]);
    sc_value_release(reports[1]);
    if (!ok || count == 0) return -1;
    return sum > 0 ? 10 * log10((double)count / sum) : INFINITY;
}

static void corpus_check(const char *rel, const char *texture, const char *slots, bool expect_more_collapsible) {
    if (!sc_test_corpus()) {
        printf("     corpus absent: skipped %s\n", rel);
        return;
    }
    sc_value *atlas = sc_test_load_corpus(rel, texture, slots);
    if (!atlas) return;
    sc_error err = {0};
    double t0 = sc_now();
    sc_ctx *ctx = run_straighten(atlas, NULL, &err);
    double seconds = sc_now() - t0;
    SC_CHECK_MSG(ctx != NULL, "%s: %s", rel, err.message);
    if (!ctx) {
        sc_value_release(atlas);
        return;
    }
    const sc_atlas *in = atlas->as.atlas, *out = sc_ctx_output(ctx, 0)->as.atlas;
    const sc_mesh *mi = in->mesh->as.mesh, *mo = out->mesh->as.mesh;
    SC_CHECK(memcmp(mo->V, mi->V, sizeof(double) * 3 * (size_t)mi->nv) == 0);
    SC_CHECK(memcmp(mo->FU, mi->FU, sizeof(int32_t) * 3 * (size_t)mi->nf) == 0);
    ratio_check r = check_seam_ratios(mi, mo);
    SC_CHECK_MSG(r.bad == 0, "%s: %lld of %lld seam vertices with unequal ratios (worst %g)", rel, (long long)r.bad,
                 (long long)r.checked, r.worst);
    int64_t flips = flipped_faces(mi, mo);
    SC_CHECK_MSG(flips == 0, "%s: %lld flipped faces (node says %g)", rel, (long long)flips,
                 sc_ctx_metric_value(ctx, "flipped_triangles"));
    int compared = 0;
    double psnr = appearance_psnr(in, out, 3, &compared);
    SC_CHECK_MSG(compared >= 1, "%s: no texture re-rendered", rel);
    SC_CHECK_MSG(psnr >= 35, "%s: psnr %g dB", rel, psnr);
    double seen = render_psnr(atlas, sc_ctx_output(ctx, 0));
    SC_CHECK_MSG(seen >= 35, "%s: rendered psnr %g dB", rel, seen);
    printf("     %s: rendered appearance psnr %.1f dB (6 views)\n", rel, seen);
    double before = sc_ctx_metric_value(ctx, "collapsible_seam_edges_before");
    double after = sc_ctx_metric_value(ctx, "collapsible_seam_edges_after");
    if (expect_more_collapsible) SC_CHECK_MSG(after > before, "%s: collapsible %g -> %g", rel, before, after);
    printf("     %s: seams %g, collapsible %g -> %g, flips %lld, psnr %.1f dB (node %.1f), degenerate %g, "
           "ratios checked %lld (worst %.2g), max move %.3g, %.2f s\n",
           rel, sc_ctx_metric_value(ctx, "seam_edges"), before, after, (long long)flips, psnr,
           sc_ctx_metric_value(ctx, "psnr"), sc_ctx_metric_value(ctx, "degenerate_uv_faces"), (long long)r.checked,
           r.worst, sc_ctx_metric_value(ctx, "max_uv_displacement"), seconds);
    sc_ctx_free(ctx);
    sc_value_release(atlas);
}

SC_TEST(corpus_spot) { corpus_check("spot/spot_triangulated.obj", "spot/spot_texture.png", NULL, false); }

SC_TEST(corpus_blub) {
    corpus_check("blub/blub.obj", "blub/blub_texture.png", NULL, true);
}

SC_TEST(corpus_boombox) {
    corpus_check("BoomBox/BoomBox_welded.obj", NULL, "color,normal", false);
}

SC_TEST(corpus_suzanne_unchanged) {
    if (!sc_test_corpus()) {
        printf("     corpus absent: skipped\n");
        return;
    }
    sc_value *atlas = sc_test_load_corpus("Suzanne/Suzanne_welded.obj", NULL, NULL);
    if (!atlas) return;
    sc_error err = {0};
    sc_ctx *ctx = run_straighten(atlas, NULL, &err);
    SC_CHECK_MSG(ctx != NULL, "%s", err.message);
    if (ctx) {
        sc_value *out = sc_ctx_output(ctx, 0);
        SC_CHECK(out && sc_digest_equal(sc_value_digest(out), sc_value_digest(atlas)));
        SC_CHECK_INT(sc_ctx_metric_value(ctx, "seam_edges"), 0);
        printf("     Suzanne: boundary chains %g, moved uv vertices %g\n", sc_ctx_metric_value(ctx, "boundary_chains"),
               sc_ctx_metric_value(ctx, "moved_uv_vertices"));
    }
    sc_ctx_free(ctx);
    sc_value_release(atlas);
}

/* every border straightened, as in the paper: closed loops keep three edges
 * or more, nothing flips, the texture follows */
SC_TEST(corpus_suzanne_borders_always) {
    if (!sc_test_corpus()) {
        printf("     corpus absent: skipped\n");
        return;
    }
    sc_value *atlas = sc_test_load_corpus("Suzanne/Suzanne_welded.obj", NULL, NULL);
    if (!atlas) return;
    sc_error err = {0};
    sc_ctx *ctx = run_straighten(atlas, (const char *const[]){"borders", "always", NULL}, &err);
    SC_CHECK_MSG(ctx != NULL, "%s", err.message);
    if (ctx) {
        const sc_atlas *in = atlas->as.atlas, *out = sc_ctx_output(ctx, 0)->as.atlas;
        const sc_mesh *mi = in->mesh->as.mesh, *mo = out->mesh->as.mesh;
        SC_CHECK(sc_ctx_metric_value(ctx, "moved_uv_vertices") > 0);
        int64_t flips = flipped_faces(mi, mo);
        SC_CHECK_INT(flips, 0);
        int64_t vanished = 0;
        for (int32_t f = 0; f < mo->nf; f++) vanished += area2(mo->U, mo->FU + 3 * f) == 0;
        SC_CHECK_INT(vanished, 0);
        int compared = 0;
        double psnr = appearance_psnr(in, out, 3, &compared);
        SC_CHECK_INT(compared, 1);
        SC_CHECK_MSG(psnr >= 35, "psnr %g", psnr);
        printf("     Suzanne, borders always: %g border chains, %g uv vertices moved, psnr %.1f dB\n",
               sc_ctx_metric_value(ctx, "boundary_chains"), sc_ctx_metric_value(ctx, "moved_uv_vertices"), psnr);
    }
    sc_ctx_free(ctx);
    sc_value_release(atlas);
}

/* zero-area uv faces are reported, and the warp still solves */
SC_TEST(corpus_waterbottle_degenerate_reported) {
    if (!sc_test_corpus()) {
        printf("     corpus absent: skipped\n");
        return;
    }
    sc_value *atlas = sc_test_load_corpus("WaterBottle/WaterBottle_welded.obj", NULL, "color");
    if (!atlas) return;
    sc_error err = {0};
    sc_ctx *ctx = run_straighten(atlas, (const char *const[]){"erase", "false", NULL}, &err);
    SC_CHECK_MSG(ctx != NULL, "%s", err.message);
    if (ctx) {
        SC_CHECK(sc_ctx_metric_value(ctx, "degenerate_uv_faces") >= 80);
        const sc_mesh *mi = atlas->as.atlas->mesh->as.mesh, *mo = sc_ctx_output(ctx, 0)->as.atlas->mesh->as.mesh;
        int64_t flips = flipped_faces(mi, mo);
        SC_CHECK_INT(flips, sc_ctx_metric_value(ctx, "flipped_triangles"));
        printf("     WaterBottle: degenerate uv faces %g, flips %lld\n", sc_ctx_metric_value(ctx, "degenerate_uv_faces"),
               (long long)flips);
    }
    sc_ctx_free(ctx);
    sc_value_release(atlas);
}

int main(void) { return sc_test_main(); }
