/* bake_displacement.c - the node `bake_displacement`: geometry images and
 * vector displacement maps in the shared parameterisation (Liu et al. 2017,
 * §7).
 *
 * Design note.
 *  - Geometry image. For each material, a size x size f32 RGB image (colour
 *    space DATA) holding the input mesh's positions at texel centres
 *    (design.md: texel (i, j) at ((i + 1/2)/W, (j + 1/2)/H), row 0 = v = 0).
 *    Every face's uv triangle is scanned over its bounding box grown by
 *    `padding` texels; a texel takes the face nearest to its centre (in
 *    texel space; distance 0 inside, ties to the lower face index, so the
 *    result is the same on any machine) and the value of that face's linear
 *    map uv -> position *extended* to the texel centre. Inside a chart this is
 *    the surface; in the padding band it is the linear continuation of the
 *    border faces, which bilinear reconstruction reproduces exactly, so the
 *    texels that sampling reads along uv silhouettes already hold what
 *    erase_seams needs to start from. Texels beyond the band are filled by
 *    push-pull (averages of the valid texels over a pyramid, pulled back
 *    down), so coarser mip levels average meaningful values. Texels are taken
 *    through the texture's wrap mode (the material's first texture's, else
 *    repeat: the OBJ/GL default).
 *  - Displacement (§7). For level k, D_k = P_in - P_k at every texel where
 *    both rasterisations (same rules, padding band) define them: the input's
 *    and the level's surfaces linearly extended (not G - P_k: G is erased on
 *    other seams). The renderer draws base_k(uv) + bilinear(D_k)(uv); that is
 *    exact in every bilinear cell whose four corner texels lie inside one face
 *    of the input and one of the level.
 *  - Least-squares fit. The other cells (a face edge of either mesh crosses
 *    them, faces smaller than a texel, cells reaching out of the chart) get
 *    4 x 4 samples of the input surface per cell (a barycentric grid on faces
 *    under two texels across); where point sampling misses them by more than
 *    `fit_tolerance` of the bounding-box diagonal, the corner texels are
 *    solved for in least squares (mean squared error per cell; exact cells
 *    enter through the bilinear mass matrix), by Jacobi-preconditioned
 *    conjugate gradients. The geometry image gets the same fit (P_k = 0).
 *    Sampling runs in bands of rows, each band visiting (from a per-band
 *    face list built once per map) the faces that can reach its rows in face
 *    order, so each cell sums its own samples in the serial order: the same
 *    bytes on any thread count. A first pass only measures the miss per
 *    cell; a second pass repeats the same samples in the cells next to a
 *    solved texel only, summing their Gram matrices and residuals. The
 *    solver's matrix products gather per unknown in the order a scatter over
 *    the cells would add, so they split over threads with the same bytes.
 *  - Seams. With `erase` (the default), the node runs the erase_seams node
 *    (sc_atlas_ops_erase; no E_C1 term: the two sides of a seam map uv to the
 *    surface with their own Jacobians, so positions have no reason to be C1
 *    across it): G on the union of the input mesh and every level (disjoint
 *    copies in one mesh, so one geometry image serves every level), each D_k
 *    on level k's own seams. Without `erase` the maps are only fitted and
 *    filled, e.g. to feed erase_seams from the graph or to show that unerased
 *    maps crack.
 *  - Limits (measured at 1024^2). Where a chart's uv is squeezed below a
 *    texel per face (blub: faces of 0.01 texel, a texel spanning ~5% of the
 *    diagonal), no bilinear map follows the surface: the RMS residual of the
 *    best bilinear fit of each cell on its own bounds the max error from
 *    below by 1.1e-3 (blub, level 0.5) and 4.3e-3 (level 0.1). Erasure next
 *    to such charts moves texels further.
 *  - Outputs. `atlas`: the input mesh, its textures (slots geometry_image and
 *    displacement dropped) plus "geometry_image" per material. `lods`: every
 *    level (or the input alone when `lods` is unconnected) with its own
 *    textures plus the very same geometry_image value and its own
 *    "displacement" per material: what render's geometry_image, displaced and
 *    tessellated modes look up. The images are f32 DATA values; files are
 *    written by whoever saves them (save, mipmap), not here.
 *  - Metrics: lod<k>.reconstruction_error (max), _rms and _p99: base_k +
 *    bilinear(D_k) against the input surface at 7 points of every input face
 *    (the level's face found exactly, through a bucket grid of its uv faces),
 *    over the bounding-box diagonal; geometry_image_error likewise for G;
 *    texels_covered and texels_shared (sc_seam_coverage, input mesh);
 *    texels fitted and timings per stage.
 */
#include <float.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "sc_atlas_ops.h"
#include "sc_exec.h"
#include "sc_nodes.h"
#include "sc_seam.h"

/* ---------------------------------------------------------------- raster */

/* One rasterisation of a mesh material: per texel the nearest face (or -1),
 * its distance and the position extended to the texel centre. */
typedef struct raster {
    int32_t width, height;
    float *value;     /* W*H*3 */
    float *dist;      /* W*H, texel units; FLT_MAX where undefined */
    int32_t *face;    /* W*H, -1 where undefined */
} raster;

static void raster_free(raster *r) {
    free(r->value);
    free(r->dist);
    free(r->face);
    memset(r, 0, sizeof *r);
}

/* Barycentric coordinates of (px, py) in triangle x[3], y[3] (any point of the
 * plane); false (and zeros) for a degenerate triangle. */
static inline bool barycentric(const double x[3], const double y[3], double px, double py, double l[3]) {
    double d = (y[1] - y[2]) * (x[0] - x[2]) + (x[2] - x[1]) * (y[0] - y[2]);
    if (!(fabs(d) > 1e-300)) {
        l[0] = l[1] = l[2] = 0;
        return false;
    }
    l[0] = ((y[1] - y[2]) * (px - x[2]) + (x[2] - x[1]) * (py - y[2])) / d;
    l[1] = ((y[2] - y[0]) * (px - x[2]) + (x[0] - x[2]) * (py - y[2])) / d;
    l[2] = 1 - l[0] - l[1];
    return true;
}

/* A face of the material in texel space, with its row range (padded). */
typedef struct rface {
    int32_t f;
    double x[3], y[3];
    int64_t j0, j1;
} rface;

typedef struct raster_job {
    const sc_mesh *m;
    const sc_seam_grid *g;
    const rface *faces;
    int32_t nfaces, pad, band;
    raster *r;
} raster_job;

static bool rows_meet(int64_t j0, int64_t j1, int32_t b0, int32_t b1, int32_t H, sc_wrap w) {
    if (j1 - j0 + 1 >= H) return true;
    if (w != SC_WRAP_REPEAT) return j1 >= b0 - 1 && j0 <= b1;   /* clamp/mirror: checked per row */
    for (int64_t s = -H; s <= H; s += H)
        if (j1 + s >= b0 && j0 + s < b1) return true;
    int64_t k = j0 >= 0 ? j0 / H : -((-j0 + H - 1) / H);   /* far outside [0, H) */
    return j1 - k * H >= b0 && j0 - k * H < b1;
}

/* Rows [band * chunk, ...) of the raster: every face in face order, so a
 * texel's winner (nearest, ties to the lower face) is the serial one. */
static int raster_band(void *ud, int32_t chunk) {
    raster_job *J = ud;
    const sc_seam_grid *g = J->g;
    const int32_t W = g->width, H = g->height, b0 = chunk * J->band;
    const int32_t b1 = b0 + J->band < H ? b0 + J->band : H;
    raster *r = J->r;
    for (int32_t q = 0; q < J->nfaces; q++) {
        const rface *F = &J->faces[q];
        if (!rows_meet(F->j0, F->j1, b0, b1, H, g->wrap_v)) continue;
        const double *x = F->x, *y = F->y;
        const int32_t pad = J->pad;
        double x0 = fmin(x[0], fmin(x[1], x[2])) - pad, x1 = fmax(x[0], fmax(x[1], x[2])) + pad;
        const sc_mesh *m = J->m;
        const double *p[3] = {m->V + 3 * m->FV[3 * F->f], m->V + 3 * m->FV[3 * F->f + 1], m->V + 3 * m->FV[3 * F->f + 2]};
        for (int64_t j = F->j0; j <= F->j1; j++) {
            int32_t jw = sc_seam_wrap(j, H, g->wrap_v);
            if (jw < b0 || jw >= b1) continue;
            for (int64_t i = (int64_t)ceil(x0); i <= (int64_t)floor(x1); i++) {
                double l[3];
                barycentric(x, y, (double)i, (double)j, l);
                double d2 = 0;
                if (l[0] < 0 || l[1] < 0 || l[2] < 0)
                    d2 = fmin(sc_atlas_ops_segment_distance2((double)i, (double)j, x[0], y[0], x[1], y[1]),
                              fmin(sc_atlas_ops_segment_distance2((double)i, (double)j, x[1], y[1], x[2], y[2]),
                                   sc_atlas_ops_segment_distance2((double)i, (double)j, x[2], y[2], x[0], y[0])));
                float d = (float)sqrt(d2);
                if (d > (float)pad) continue;
                size_t t = (size_t)jw * W + (size_t)sc_seam_wrap(i, W, g->wrap_u);
                if (!(d < r->dist[t])) continue;
                r->dist[t] = d;
                r->face[t] = F->f;
                for (int c = 0; c < 3; c++)
                    r->value[3 * t + c] = (float)(l[0] * p[0][c] + l[1] * p[1][c] + l[2] * p[2][c]);
            }
        }
    }
    return SC_OK;
}

static int raster_build(const sc_mesh *m, int32_t material, const sc_seam_grid *g, int32_t pad, int threads,
                        raster *r, sc_error *err) {
    const int32_t W = g->width, H = g->height;
    size_t n = (size_t)W * (size_t)H;
    r->width = W, r->height = H;
    r->value = sc_calloc_array(n * 3, sizeof(float));
    r->dist = sc_alloc_array(n, sizeof(float));
    r->face = sc_alloc_array(n, sizeof(int32_t));
    rface *faces = sc_alloc_array((size_t)m->nf + 1, sizeof *faces);
    if (!r->value || !r->dist || !r->face || !faces) {
        raster_free(r);
        free(faces);
        return sc_fail(err, SC_ENOMEM, "out of memory for a %dx%d raster", W, H);
    }
    for (size_t t = 0; t < n; t++) r->dist[t] = FLT_MAX, r->face[t] = -1;
    int32_t nfaces = 0;
    for (int32_t f = 0; f < m->nf; f++) {
        if (m->FM[f] != material) continue;
        rface *F = &faces[nfaces];
        F->f = f;
        for (int c = 0; c < 3; c++) {
            const double *uv = m->U + 2 * m->FU[3 * f + c];
            F->x[c] = uv[0] * W - 0.5, F->y[c] = uv[1] * H - 0.5;
        }
        double l[3];
        if (!barycentric(F->x, F->y, F->x[0], F->y[0], l)) continue;   /* zero uv area */
        double x0 = fmin(F->x[0], fmin(F->x[1], F->x[2])) - pad, x1 = fmax(F->x[0], fmax(F->x[1], F->x[2])) + pad;
        double y0 = fmin(F->y[0], fmin(F->y[1], F->y[2])) - pad, y1 = fmax(F->y[0], fmax(F->y[1], F->y[2])) + pad;
        if (!(x1 - x0 <= 4.0 * W + 2 * pad && y1 - y0 <= 4.0 * H + 2 * pad)) continue;   /* absurd uv */
        if (!(fabs(x0) < 1e9 && fabs(y0) < 1e9)) continue;
        F->j0 = (int64_t)ceil(y0), F->j1 = (int64_t)floor(y1);
        nfaces++;
    }
    int32_t band = 32;
    raster_job job = {.m = m, .g = g, .faces = faces, .nfaces = nfaces, .pad = pad, .band = band, .r = r};
    int rc = sc_seam_parallel(threads, (H + band - 1) / band, raster_band, &job);
    free(faces);
    if (rc != SC_OK) {
        raster_free(r);
        return sc_fail(err, rc, "rasterising the uv faces failed");
    }
    return SC_OK;
}

/* Fill the texels where valid[t] == 0 from a pyramid of averages of the valid
 * ones (push), each taking its nearest coarser average (pull). */
static int push_pull(float *img, const uint8_t *valid, int32_t W, int32_t H, int C, sc_error *err) {
    if (W <= 1 && H <= 1) return SC_OK;
    int32_t w2 = W > 1 ? (W + 1) / 2 : 1, h2 = H > 1 ? (H + 1) / 2 : 1;
    float *coarse = sc_calloc_array((size_t)w2 * h2 * C, sizeof(float));
    uint8_t *cvalid = sc_calloc_array((size_t)w2 * h2, 1);
    if (!coarse || !cvalid) {
        free(coarse), free(cvalid);
        return sc_fail(err, SC_ENOMEM, "out of memory");
    }
    bool any_invalid = false;
    for (int32_t j = 0; j < h2; j++)
        for (int32_t i = 0; i < w2; i++) {
            double sum[4] = {0, 0, 0, 0};
            int cnt = 0;
            for (int dj = 0; dj < 2; dj++)
                for (int di = 0; di < 2; di++) {
                    int32_t ii = 2 * i + di, jj = 2 * j + dj;
                    if (ii >= W || jj >= H) continue;
                    size_t t = (size_t)jj * W + ii;
                    if (!valid[t]) continue;
                    cnt++;
                    for (int c = 0; c < C; c++) sum[c] += img[t * C + c];
                }
            size_t ct = (size_t)j * w2 + i;
            if (cnt) {
                cvalid[ct] = 1;
                for (int c = 0; c < C; c++) coarse[ct * C + c] = (float)(sum[c] / cnt);
            } else {
                any_invalid = true;
            }
        }
    int rc = SC_OK;
    if (any_invalid) rc = push_pull(coarse, cvalid, w2, h2, C, err);
    if (rc == SC_OK)
        for (int32_t j = 0; j < H; j++)
            for (int32_t i = 0; i < W; i++) {
                size_t t = (size_t)j * W + i, ct = (size_t)(j / 2) * w2 + (size_t)(i / 2);
                if (!valid[t])
                    for (int c = 0; c < C; c++) img[t * C + c] = coarse[ct * C + c];
            }
    free(coarse), free(cvalid);
    return rc;
}

/* ---------------------------------------------------------------- locating uv in a level */

/* Buckets of a gw x gw grid over uv [0, 1)^2 (clamped at the sides, so uv
 * outside still meets the faces there), each listing the faces of one
 * material whose uv bounding box meets it. */
typedef struct locator {
    const sc_mesh *m;
    int32_t gw;
    int32_t *start, *faces;
} locator;

static void locator_free(locator *L) {
    free(L->start), free(L->faces);
    memset(L, 0, sizeof *L);
}

static int32_t bucket_of(double u, int32_t gw) {
    double b = floor(u * gw);
    return b < 0 ? 0 : b >= gw ? gw - 1 : (int32_t)b;
}

static int locator_build(const sc_mesh *m, int32_t material, int32_t gw, locator *L, sc_error *err) {
    L->m = m, L->gw = gw;
    L->start = sc_calloc_array((size_t)gw * gw + 1, sizeof(int32_t));
    if (!L->start) return sc_fail(err, SC_ENOMEM, "out of memory");
    int32_t *count = sc_calloc_array((size_t)gw * gw, sizeof(int32_t));
    if (!count) {
        locator_free(L);
        return sc_fail(err, SC_ENOMEM, "out of memory");
    }
    int rc = SC_OK;
    for (int pass = 0; pass < 2 && rc == SC_OK; pass++) {
        for (int32_t f = 0; f < m->nf; f++) {
            if (m->FM[f] != material) continue;
            double u0 = HUGE_VAL, u1 = -HUGE_VAL, v0 = HUGE_VAL, v1 = -HUGE_VAL;
            for (int c = 0; c < 3; c++) {
                const double *uv = m->U + 2 * m->FU[3 * f + c];
                u0 = fmin(u0, uv[0]), u1 = fmax(u1, uv[0]), v0 = fmin(v0, uv[1]), v1 = fmax(v1, uv[1]);
            }
            if (!(u0 <= u1 && v0 <= v1)) continue;   /* NaN */
            for (int32_t j = bucket_of(v0, gw); j <= bucket_of(v1, gw); j++)
                for (int32_t i = bucket_of(u0, gw); i <= bucket_of(u1, gw); i++) {
                    size_t b = (size_t)j * gw + i;
                    if (pass == 0) {
                        if (count[b] == INT32_MAX || L->start[gw * gw] > INT32_MAX - 1) rc = SC_ENOMEM;
                        count[b]++, L->start[gw * gw]++;
                    } else {
                        L->faces[L->start[b] + count[b]++] = f;
                    }
                }
        }
        if (pass == 0 && rc == SC_OK) {
            int64_t total = 0;
            for (size_t b = 0; b < (size_t)gw * gw; b++) L->start[b] = (int32_t)total, total += count[b], count[b] = 0;
            L->start[(size_t)gw * gw] = (int32_t)total;
            L->faces = sc_alloc_array((size_t)total + 1, sizeof(int32_t));
            if (!L->faces) rc = SC_ENOMEM;
        }
    }
    free(count);
    if (rc != SC_OK) {
        locator_free(L);
        return sc_fail(err, SC_ENOMEM, "out of memory for a uv locator");
    }
    return SC_OK;
}

/* The face that best contains uv (largest smallest barycentric) among the
 * faces near it, and the level's position there (linear in that face,
 * extended a little beyond it); -1 when no face is within reach. */
static int32_t locate(const locator *L, double u, double v, double p[3]) {
    const sc_mesh *m = L->m;
    int32_t bi = bucket_of(u, L->gw), bj = bucket_of(v, L->gw), best = -1;
    double best_min = -HUGE_VAL, bl[3] = {0, 0, 0};
    for (int32_t j = bj - 1; j <= bj + 1; j++)
        for (int32_t i = bi - 1; i <= bi + 1; i++) {
            if (i < 0 || j < 0 || i >= L->gw || j >= L->gw) continue;
            size_t b = (size_t)j * L->gw + i;
            for (int32_t q = L->start[b]; q < L->start[b + 1]; q++) {
                int32_t f = L->faces[q];
                if (f == best) continue;
                double fx[3], fy[3], l[3];
                for (int c = 0; c < 3; c++) {
                    const double *uv = m->U + 2 * m->FU[3 * f + c];
                    fx[c] = uv[0], fy[c] = uv[1];
                }
                if (!barycentric(fx, fy, u, v, l)) continue;
                double mn = fmin(l[0], fmin(l[1], l[2]));
                if (mn > best_min || (mn == best_min && f < best)) best_min = mn, best = f, memcpy(bl, l, sizeof l);
            }
        }
    if (best < 0 || best_min < -0.5) return -1;
    for (int k = 0; k < 3; k++)
        p[k] = bl[0] * m->V[3 * m->FV[3 * best] + k] + bl[1] * m->V[3 * m->FV[3 * best + 1] + k] +
               bl[2] * m->V[3 * m->FV[3 * best + 2] + k];
    return best;
}

static int32_t locator_side(int32_t size) {
    int32_t gw = size / 4;
    return gw < 16 ? 16 : gw > 1024 ? 1024 : gw;
}

/* ---------------------------------------------------------------- least-squares fit */

/* The map x0 (texel-centre values of f = input - level, exact wherever a
 * bilinear cell lies inside one face of the input and one of the level) is
 * refined where it is not: in the cells that straddle a face edge of either
 * mesh, hold faces smaller than a texel, or reach outside the chart. There
 * f is sampled densely (every input face on a barycentric grid of about 3
 * points per texel) and the texels of the cells whose samples x0 misses by
 * more than `tol` are solved for in least squares:
 *     min sum_cells w_c mean_{s in c} |bilinear(x)(s) - f(s)|^2 + eps |x - x0|^2
 * with w_c = 1 and exact cells entering through the bilinear mass matrix
 * (their samples would all read f = bilinear(x0)). Conjugate gradients with a
 * Jacobi preconditioner, in a fixed order: deterministic. */

typedef struct fit_cell {
    double G[10];   /* upper triangle of the 4 x 4 Gram matrix, row-major */
    double b[4][3];
    double n;       /* samples */
} fit_cell;

static const int gram_index[4][4] = {{0, 1, 2, 3}, {1, 4, 5, 6}, {2, 5, 7, 8}, {3, 6, 8, 9}};
static const double mass[10] = {4.0 / 36, 2.0 / 36, 2.0 / 36, 1.0 / 36, 4.0 / 36,
                                1.0 / 36, 2.0 / 36, 4.0 / 36, 2.0 / 36, 4.0 / 36};

/* Cells are keyed by their lower-left texel: cx in [0, W) under repeat, else
 * cx + 1 in [0, W] (cx = -1 .. W - 1). */
typedef struct cellgrid {
    int32_t W, H, CW, CH;
    sc_wrap wu, wv;
} cellgrid;

static bool cell_key(const cellgrid *cg, int64_t cx, int64_t cy, size_t *key) {
    int64_t kx, ky;
    if (cg->wu == SC_WRAP_REPEAT) kx = sc_seam_wrap(cx, cg->W, SC_WRAP_REPEAT);
    else if (cx < -1 || cx > cg->W - 1) return false;
    else kx = cx + 1;
    if (cg->wv == SC_WRAP_REPEAT) ky = sc_seam_wrap(cy, cg->H, SC_WRAP_REPEAT);
    else if (cy < -1 || cy > cg->H - 1) return false;
    else ky = cy + 1;
    *key = (size_t)ky * cg->CW + (size_t)kx;
    return true;
}

static void cell_corners(const cellgrid *cg, size_t key, int32_t id[4]) {
    int64_t kx = (int64_t)(key % cg->CW), ky = (int64_t)(key / cg->CW);
    int64_t cx = cg->wu == SC_WRAP_REPEAT ? kx : kx - 1, cy = cg->wv == SC_WRAP_REPEAT ? ky : ky - 1;
    if (cx >= 0 && cy >= 0 && cx + 1 < cg->W && cy + 1 < cg->H) {   /* inside: no wrapping */
        id[0] = (int32_t)(cy * cg->W + cx), id[1] = id[0] + 1;
        id[2] = id[0] + cg->W, id[3] = id[2] + 1;
        return;
    }
    for (int q = 0; q < 4; q++)
        id[q] = sc_seam_wrap(cy + (q >> 1), cg->H, cg->wv) * cg->W + sc_seam_wrap(cx + (q & 1), cg->W, cg->wu);
}

/* The level's position at uv when one of the faces the raster gives the
 * cell's corners contains it (the common case, far cheaper than locate). */
static bool level_at_corners(const sc_mesh *m, const raster *rl, const int32_t id[4], double u, double v,
                             double p[3]) {
    for (int q = 0; q < 4; q++) {
        int32_t f = rl->face[id[q]];
        if (f < 0 || (q > 0 && f == rl->face[id[q - 1]])) continue;
        double fx[3], fy[3], l[3];
        for (int c = 0; c < 3; c++) {
            const double *uv = m->U + 2 * m->FU[3 * f + c];
            fx[c] = uv[0], fy[c] = uv[1];
        }
        if (!barycentric(fx, fy, u, v, l) || l[0] < 0 || l[1] < 0 || l[2] < 0) continue;
        for (int k = 0; k < 3; k++)
            p[k] = l[0] * m->V[3 * m->FV[3 * f] + k] + l[1] * m->V[3 * m->FV[3 * f + 1] + k] +
                   l[2] * m->V[3 * m->FV[3 * f + 2] + k];
        return true;
    }
    return false;
}

typedef struct fit_stats {
    int64_t cells_inexact, cells_solved, texels_solved, samples, iterations;
    double seconds_sample, seconds_solve;
} fit_stats;

typedef struct sample_job {
    const sc_mesh *in;
    int32_t material;
    const sc_seam_grid *g;
    cellgrid cg;
    const int32_t *slot;   /* per cell key: its index in `worst` or `cells`, -1 to skip it */
    fit_cell *cells;       /* NULL: the first pass, the worst miss per cell */
    double *worst;         /* largest |bilinear(x0) - f| of a sample, per inexact cell */
    const raster *rlev;
    const locator *lev;
    const float *x;
    int32_t band;
    const int32_t *list_start, *list;   /* per chunk, the faces that may sample its rows, in face order */
    int64_t *samples;   /* per chunk */
} sample_job;

/* Face f's uv corners in texel-centre coordinates and whether it is sampled
 * at all (not absurd, not NaN, not flat); *small: under two texels across. */
static bool sample_face(const sc_mesh *in, int32_t f, int32_t W, int32_t H, double fx[3], double fy[3], bool *small) {
    for (int c = 0; c < 3; c++) {
        const double *t = in->U + 2 * in->FU[3 * f + c];
        fx[c] = t[0] * W - 0.5, fy[c] = t[1] * H - 0.5;
    }
    double e = 0, lt[3];
    for (int c = 0; c < 3; c++) e = fmax(e, hypot(fx[(c + 1) % 3] - fx[c], fy[(c + 1) % 3] - fy[c]));
    *small = e < 2;
    return e < 4.0 * (W + H) && barycentric(fx, fy, fx[0], fy[0], lt);
}

/* The sampling chunks (key rows [c * band, (c + 1) * band)) each face may put
 * samples in: its cell rows, one more on each side (rounding), through the
 * wrap mode; every face of the material in face order. A superset of what
 * sample_band keeps, so the sums are the ones a scan of every face gives. */
static int sample_lists(const sc_mesh *in, int32_t material, const cellgrid *cg, int32_t band, int32_t nchunks,
                        int32_t **start_out, int32_t **list_out) {
    int32_t *start = sc_calloc_array((size_t)nchunks + 1, sizeof(int32_t));
    int32_t *last = sc_alloc_array((size_t)nchunks + 1, sizeof(int32_t));
    int32_t *list = NULL, *fill = NULL;
    if (!start || !last) {
        free(start), free(last);
        return SC_ENOMEM;
    }
    int64_t total = 0;
    for (int pass = 0; pass < 2; pass++) {
        for (int32_t c = 0; c < nchunks; c++) last[c] = -1;
        for (int32_t f = 0; f < in->nf; f++) {
            if (in->FM[f] != material) continue;
            double fx[3], fy[3];
            bool small;
            if (!sample_face(in, f, cg->W, cg->H, fx, fy, &small)) continue;
            int64_t cy0 = (int64_t)floor(fmin(fy[0], fmin(fy[1], fy[2]))) - 1;
            int64_t cy1 = (int64_t)floor(fmax(fy[0], fmax(fy[1], fy[2]))) + 1;
            int64_t r0, r1;   /* key rows, or every row */
            bool all = false;
            if (cg->wv == SC_WRAP_REPEAT) {
                all = cy1 - cy0 + 1 >= cg->H;
                r0 = cy0, r1 = cy1;
            } else {
                r0 = cy0 + 1 < 0 ? 0 : cy0 + 1, r1 = cy1 + 1 > cg->CH - 1 ? cg->CH - 1 : cy1 + 1;
            }
            if (all) r0 = 0, r1 = cg->CH - 1;
            for (int64_t r = r0; r <= r1; r++) {
                int64_t row = cg->wv == SC_WRAP_REPEAT && !all ? sc_seam_wrap(r, cg->H, SC_WRAP_REPEAT) : r;
                int32_t c = (int32_t)(row / band);
                if (c < 0 || c >= nchunks || last[c] == f) continue;
                last[c] = f;
                if (pass == 0) start[c + 1]++, total++;
                else list[fill[c]++] = f;
            }
        }
        if (pass == 0) {
            for (int32_t c = 0; c < nchunks; c++) start[c + 1] += start[c];
            list = total < INT32_MAX ? sc_alloc_array((size_t)total + 1, sizeof(int32_t)) : NULL;
            fill = sc_alloc_array((size_t)nchunks + 1, sizeof(int32_t));
            if (!list || !fill) {
                free(start), free(last), free(list), free(fill);
                return SC_ENOMEM;
            }
            memcpy(fill, start, sizeof(int32_t) * (size_t)nchunks);
        }
    }
    free(last), free(fill);
    *start_out = start, *list_out = list;
    return SC_OK;
}

/* Samples of f in the inexact cells of key rows [chunk * band, ...): every
 * face in face order, so each cell sums its samples in the serial order. */
static int sample_band(void *ud, int32_t chunk) {
    sample_job *J = ud;
    const sc_mesh *in = J->in;
    const int32_t material = J->material, W = J->g->width, H = J->g->height;
    const cellgrid cg = J->cg;
    const int32_t *slot = J->slot;
    fit_cell *cells = J->cells;
    double *worst = J->worst;
    const raster *rlev = J->rlev;
    const locator *lev = J->lev;
    const float *x = J->x;
    const size_t k0 = (size_t)chunk * J->band, k1 = k0 + (size_t)J->band;
    int64_t nsamples = 0;
    /* dense samples of f in those cells: 4 x 4 per cell inside a face,
     * and a barycentric grid on faces under two texels across */
    for (int32_t lq = J->list_start[chunk]; lq < J->list_start[chunk + 1]; lq++) {
        const int32_t f = J->list[lq];
        if (in->FM[f] != material) continue;
        const double *t[3], *p[3];
        double fx[3], fy[3];
        bool small;
        if (!sample_face(in, f, W, H, fx, fy, &small)) continue;   /* absurd, NaN, flat */
        for (int c = 0; c < 3; c++) t[c] = in->U + 2 * in->FU[3 * f + c], p[c] = in->V + 3 * in->FV[3 * f + c];
        int32_t n = small ? 3 : 0;
        int64_t cx0 = (int64_t)floor(fmin(fx[0], fmin(fx[1], fx[2]))), cx1 = (int64_t)floor(fmax(fx[0], fmax(fx[1], fx[2])));
        int64_t cy0 = (int64_t)floor(fmin(fy[0], fmin(fy[1], fy[2]))), cy1 = (int64_t)floor(fmax(fy[0], fmax(fy[1], fy[2])));
        if (!small && cg.wv != SC_WRAP_REPEAT && (cy1 + 1 < (int64_t)k0 || cy0 + 1 >= (int64_t)k1)) continue;
        if (!small && cg.wv == SC_WRAP_REPEAT && cy1 - cy0 + 1 < H && cy0 >= 0 && cy1 < H && (cy1 < (int64_t)k0 || cy0 >= (int64_t)k1))
            continue;
        /* the cells of the face's box, row by row, on the band's rows only
         * (the others put no sample in it) */
        int64_t ry0 = cy0, ry1 = cy1;
        if (!small && cg.wv != SC_WRAP_REPEAT) {
            ry0 = cy0 > (int64_t)k0 - 1 ? cy0 : (int64_t)k0 - 1;
            ry1 = cy1 < (int64_t)k1 - 2 ? cy1 : (int64_t)k1 - 2;
        } else if (!small && cy0 >= 0 && cy1 < H) {
            ry0 = cy0 > (int64_t)k0 ? cy0 : (int64_t)k0;
            ry1 = cy1 < (int64_t)k1 - 1 ? cy1 : (int64_t)k1 - 1;
        }
        const int64_t bw = small ? 1 : cx1 - cx0 + 1;
        int64_t ncells = small ? 1 : ry1 < ry0 ? 0 : bw * (ry1 - ry0 + 1);
        for (int64_t cell = 0; cell < ncells; cell++) {
            int64_t cx = cx0 + cell % bw, cy = (small ? cy0 : ry0) + cell / bw;
            size_t key;
            if (!small && (!cell_key(&cg, cx, cy, &key) || slot[key] < 0 || key / cg.CW < k0 || key / cg.CW >= k1)) continue;
            const size_t cell_key0 = small ? 0 : key;   /* a big face's samples land in this cell */
            int32_t cell_id[4];
            if (!small) cell_corners(&cg, cell_key0, cell_id);
            int32_t npts = small ? (n + 1) * (n + 2) / 2 : 16;
            for (int32_t s = 0; s < npts; s++) {
                double l[3];
                if (small) {
                    int32_t a = 0, rem = s;
                    while (rem > n - a) rem -= n - a + 1, a++;
                    l[0] = (double)a / n, l[1] = (double)rem / n, l[2] = 1 - l[0] - l[1];
                } else {
                    barycentric(fx, fy, (double)cx + ((s & 3) + 0.5) / 4, (double)cy + ((s >> 2) + 0.5) / 4, l);
                    if (l[0] < 0 || l[1] < 0 || l[2] < 0) continue;
                }
                double u = l[0] * t[0][0] + l[1] * t[1][0] + l[2] * t[2][0];
                double v = l[0] * t[0][1] + l[1] * t[1][1] + l[2] * t[2][1];
                double px = u * W - 0.5, py = v * H - 0.5, qx = floor(px), qy = floor(py);
                int32_t id[4];
                if (!small && (int64_t)qx == cx && (int64_t)qy == cy) {
                    key = cell_key0;
                    memcpy(id, cell_id, sizeof id);
                } else {
                    if (!cell_key(&cg, (int64_t)qx, (int64_t)qy, &key) || slot[key] < 0 || key / cg.CW < k0 ||
                        key / cg.CW >= k1)
                        continue;
                    cell_corners(&cg, key, id);
                }
                double y[3];
                for (int k = 0; k < 3; k++) y[k] = l[0] * p[0][k] + l[1] * p[1][k] + l[2] * p[2][k];
                if (lev) {
                    double q[3];
                    if (!level_at_corners(lev->m, rlev, id, u, v, q) && locate(lev, u, v, q) < 0) continue;
                    for (int k = 0; k < 3; k++) y[k] -= q[k];
                }
                double ss = px - qx, tt = py - qy;
                double w[4] = {(1 - ss) * (1 - tt), ss * (1 - tt), (1 - ss) * tt, ss * tt};
                double r[3], gap = 0;
                for (int k = 0; k < 3; k++) {
                    double bx = 0;
                    for (int q = 0; q < 4; q++) bx += w[q] * x[3 * (size_t)id[q] + k];
                    r[k] = y[k] - bx;
                    gap += r[k] * r[k];
                }
                nsamples++;
                if (!cells) {
                    worst[slot[key]] = fmax(worst[slot[key]], sqrt(gap));
                    continue;
                }
                fit_cell *C = &cells[slot[key]];
                for (int i = 0; i < 4; i++) {
                    for (int j = i; j < 4; j++) C->G[gram_index[i][j]] += w[i] * w[j];
                    for (int k = 0; k < 3; k++) C->b[i][k] += w[i] * r[k];
                }
                C->n += 1;
            }
        }
    }
    J->samples[chunk] = nsamples;
    return SC_OK;
}

/* Per-cell flags over cells [chunk * CELL_CHUNK, ...): with `rin`, slot[k] =
 * -1 where x0 is exact (the four corners inside one face of the input and,
 * with `rlev`, one of the level), else 0; with `var`, touch[k] = whether a
 * corner is a free texel. */
#define CELL_CHUNK 65536
typedef struct cell_job {
    const cellgrid *cg;
    const raster *rin, *rlev;
    const int32_t *var;
    int32_t *slot;
    uint8_t *touch;
    size_t ncell;
} cell_job;

static int cell_band(void *ud, int32_t chunk) {
    const cell_job *J = ud;
    const size_t k0 = (size_t)chunk * CELL_CHUNK, k1 = k0 + CELL_CHUNK < J->ncell ? k0 + CELL_CHUNK : J->ncell;
    const raster *rin = J->rin, *rlev = J->rlev;
    for (size_t k = k0; k < k1; k++) {
        int32_t id[4];
        cell_corners(J->cg, k, id);
        if (J->var) {
            bool any = false;
            for (int q = 0; q < 4; q++) any |= J->var[id[q]] >= 0;
            J->touch[k] = any;
            continue;
        }
        bool exact = true;
        for (int q = 0; q < 4 && exact; q++) {
            exact = rin->face[id[q]] >= 0 && rin->dist[id[q]] == 0 && rin->face[id[q]] == rin->face[id[0]];
            if (exact && rlev)
                exact = rlev->face[id[q]] >= 0 && rlev->dist[id[q]] == 0 && rlev->face[id[q]] == rlev->face[id[0]];
        }
        J->slot[k] = exact ? -1 : 0;
    }
    return SC_OK;
}

/* A cell with a free corner: the free texels' indices (-1: fixed), its
 * (normalised) Gram matrix and residual (NULL: an exact cell). */
typedef struct active {
    int32_t var[4];
    const double *G;
    const double (*b)[3];
} active;

/* Ap = (sum P^T G P) p, gathered per unknown: unknown v sums its entries
 * inc[inc_start[v] .. inc_start[v + 1]) (active cell * 4 + corner, cells in
 * ascending order), the very order a scatter over the cells adds them in, so
 * any split of the unknowns gives the same bytes. */
typedef struct apply_job {
    const active *act;
    const int64_t *inc_start, *inc;
    const double *p;
    double *Ap;
    int64_t nvar, chunk;
} apply_job;

static int apply_band(void *ud, int32_t chunk) {
    const apply_job *J = ud;
    const int64_t v0 = (int64_t)chunk * J->chunk, v1 = v0 + J->chunk < J->nvar ? v0 + J->chunk : J->nvar;
    for (int64_t v = v0; v < v1; v++) {
        double acc[3] = {0, 0, 0};
        for (int64_t e = J->inc_start[v]; e < J->inc_start[v + 1]; e++) {
            const active *A = &J->act[J->inc[e] >> 2];
            const int q = (int)(J->inc[e] & 3);
            for (int s = 0; s < 4; s++) {
                int32_t vs = A->var[s];
                if (vs < 0) continue;
                double gq = A->G[gram_index[q][s]];
                for (int c = 0; c < 3; c++) acc[c] += gq * J->p[3 * vs + c];
            }
        }
        for (int c = 0; c < 3; c++) J->Ap[3 * v + c] = acc[c];
    }
    return SC_OK;
}

static int fit_map(const sc_mesh *in, int32_t material, const sc_seam_grid *g, const raster *rin,
                   const raster *rlev, const locator *lev, float *x, double tol, int threads, fit_stats *st,
                   sc_error *err) {
    const int32_t W = g->width, H = g->height;
    cellgrid cg = {W, H, W + (g->wrap_u == SC_WRAP_REPEAT ? 0 : 1), H + (g->wrap_v == SC_WRAP_REPEAT ? 0 : 1),
                   g->wrap_u, g->wrap_v};
    const size_t ncell = (size_t)cg.CW * cg.CH;
    int32_t *slot = sc_alloc_array(ncell, sizeof(int32_t));
    if (!slot) return sc_fail(err, SC_ENOMEM, "out of memory");
    /* 1. the cells where x0 may be inexact */
    int64_t nbad = 0;
    cell_job cj = {&cg, rin, rlev, NULL, slot, NULL, ncell};
    if (sc_seam_parallel(threads, (int32_t)((ncell + CELL_CHUNK - 1) / CELL_CHUNK), cell_band, &cj) != SC_OK) {
        free(slot);
        return sc_fail(err, SC_ENOMEM, "out of memory");
    }
    for (size_t k = 0; k < ncell; k++)
        if (slot[k] >= 0) slot[k] = nbad < INT32_MAX - 1 ? (int32_t)nbad++ : -1;
    double *worst = sc_calloc_array((size_t)nbad + 1, sizeof *worst);
    const int32_t band = 16, nchunks = (cg.CH + band - 1) / band;
    int64_t *counts = sc_calloc_array((size_t)nchunks, sizeof(int64_t));
    int32_t *list_start = NULL, *list = NULL;
    if (!worst || !counts || sample_lists(in, material, &cg, band, nchunks, &list_start, &list) != SC_OK) {
        free(worst), free(counts), free(slot);
        return sc_fail(err, SC_ENOMEM, "out of memory for %lld cells", (long long)nbad);
    }
    double t0 = sc_now();
    /* 2. dense samples of f in those cells (4 x 4 per cell inside a face, a
     * barycentric grid on faces under two texels across): first only how far
     * x0 misses them; the Gram matrices and residuals (step 4) are summed in
     * a second pass over the same samples, in the cells next to free texels
     * only */
    sample_job job = {in, material, g, cg, slot, NULL, worst, rlev, lev, x, band, list_start, list, counts};
    int rc = sc_seam_parallel(threads, nchunks, sample_band, &job);
    for (int32_t c = 0; c < nchunks; c++) st->samples += counts[c];
    if (rc != SC_OK) rc = sc_fail(err, rc, "sampling the surface failed");
    st->seconds_sample += sc_now() - t0;
    t0 = sc_now();
    /* 3. the free texels: corners of the cells x0 misses by more than tol */
    int32_t *var = rc == SC_OK ? sc_alloc_array((size_t)W * H, sizeof(int32_t)) : NULL;
    if (rc == SC_OK && !var) rc = sc_fail(err, SC_ENOMEM, "out of memory");
    int64_t nvar = 0;
    if (rc == SC_OK) {
        for (size_t t = 0; t < (size_t)W * H; t++) var[t] = -1;
        for (size_t k = 0; k < ncell; k++) {
            if (slot[k] < 0) continue;
            st->cells_inexact++;
            if (!(worst[slot[k]] > tol)) continue;
            st->cells_solved++;
            int32_t id[4];
            cell_corners(&cg, k, id);
            for (int q = 0; q < 4; q++)
                if (var[id[q]] < 0) var[id[q]] = (int32_t)nvar++;
        }
    }
    /* 4. the cells the free texels sit in: their Gram and residual */
    active *act = NULL;
    int64_t *inc_start = NULL, *inc = NULL;
    int64_t nact = 0;
    double *vec = NULL;
    if (rc == SC_OK && nvar > 0) {
        act = sc_alloc_array(ncell, sizeof *act);
        vec = sc_calloc_array((size_t)nvar * 3 * 6, sizeof(double));
        if (!act || !vec) rc = sc_fail(err, SC_ENOMEM, "out of memory for %lld unknowns", (long long)nvar);
    }
    uint8_t *touch = NULL;   /* cells with a free corner */
    int32_t *slot2 = NULL;   /* inexact cells with a free corner: index in `cells` */
    fit_cell *cells = NULL;
    if (rc == SC_OK && nvar > 0) {
        touch = sc_alloc_array(ncell + 1, 1);
        slot2 = sc_alloc_array(ncell + 1, sizeof(int32_t));
        cell_job tj = {&cg, NULL, NULL, var, NULL, touch, ncell};
        if (!touch || !slot2 ||
            sc_seam_parallel(threads, (int32_t)((ncell + CELL_CHUNK - 1) / CELL_CHUNK), cell_band, &tj) != SC_OK)
            rc = sc_fail(err, SC_ENOMEM, "out of memory");
    }
    if (rc == SC_OK && nvar > 0) {
        int64_t ntouched = 0;
        for (size_t k = 0; k < ncell; k++) slot2[k] = slot[k] >= 0 && touch[k] ? (int32_t)ntouched++ : -1;
        cells = sc_calloc_array((size_t)ntouched + 1, sizeof *cells);
        if (!cells) rc = sc_fail(err, SC_ENOMEM, "out of memory for %lld cells", (long long)ntouched);
    }
    if (rc == SC_OK && nvar > 0) {   /* the second pass: each cell sums its samples in the first pass's order */
        double t1 = sc_now();
        job.slot = slot2, job.cells = cells, job.worst = NULL;
        int prc = sc_seam_parallel(threads, nchunks, sample_band, &job);
        if (prc != SC_OK) rc = sc_fail(err, prc, "sampling the surface failed");
        st->seconds_sample += sc_now() - t1;
        t0 += sc_now() - t1;
    }
    if (rc == SC_OK && nvar > 0) {
        for (size_t k = 0; k < ncell; k++) {
            if (!touch[k]) continue;
            int32_t id[4];
            cell_corners(&cg, k, id);
            active *A = &act[nact];
            if (slot[k] >= 0) {
                fit_cell *C = &cells[slot2[k]];
                if (!(C->n > 0)) continue;
                for (int i = 0; i < 10; i++) C->G[i] /= C->n;
                for (int i = 0; i < 4; i++)
                    for (int c = 0; c < 3; c++) C->b[i][c] /= C->n;
                A->G = C->G, A->b = (const double(*)[3])C->b;
            } else {
                A->G = mass, A->b = NULL;
            }
            for (int q = 0; q < 4; q++) A->var[q] = var[id[q]];
            nact++;
        }
        /* each unknown's (cell, corner) entries, cells in ascending order */
        inc_start = sc_calloc_array((size_t)nvar + 1, sizeof(int64_t));
        inc = sc_alloc_array((size_t)nact * 4 + 1, sizeof(int64_t));
        if (!inc_start || !inc) rc = sc_fail(err, SC_ENOMEM, "out of memory for %lld unknowns", (long long)nvar);
    }
    if (rc == SC_OK && nvar > 0) {
        for (int64_t a = 0; a < nact; a++)
            for (int q = 0; q < 4; q++)
                if (act[a].var[q] >= 0) inc_start[act[a].var[q] + 1]++;
        for (int64_t v = 0; v < nvar; v++) inc_start[v + 1] += inc_start[v];
        for (int64_t a = 0; a < nact; a++)
            for (int q = 0; q < 4; q++)
                if (act[a].var[q] >= 0) inc[inc_start[act[a].var[q]]++] = 4 * a + q;
        for (int64_t v = nvar; v > 0; v--) inc_start[v] = inc_start[v - 1];
        inc_start[0] = 0;
        /* CG on (sum P^T G P + eps I) d = sum P^T b, three channels at once */
        const double eps = 1e-4;
        double *d = vec, *r = vec + 3 * nvar, *z = vec + 6 * nvar, *pp = vec + 9 * nvar, *Ap = vec + 12 * nvar,
               *diag = vec + 15 * nvar;
        for (int64_t i = 0; i < nvar; i++) diag[3 * i] = eps;
        for (int64_t a = 0; a < nact; a++) {
            const active *A = &act[a];
            for (int q = 0; q < 4; q++) {
                int32_t vq = A->var[q];
                if (vq < 0) continue;
                diag[3 * vq] += A->G[gram_index[q][q]];
                if (A->b)
                    for (int c = 0; c < 3; c++) r[3 * vq + c] += A->b[q][c];
            }
        }
        double rz[3] = {0, 0, 0}, r0[3] = {0, 0, 0};
        for (int64_t i = 0; i < nvar; i++)
            for (int c = 0; c < 3; c++) {
                z[3 * i + c] = r[3 * i + c] / diag[3 * i];
                pp[3 * i + c] = z[3 * i + c];
                rz[c] += r[3 * i + c] * z[3 * i + c];
                r0[c] += r[3 * i + c] * r[3 * i + c];
            }
        for (int it = 0; it < 60; it++) {
            double rr = 0, rr0 = r0[0] + r0[1] + r0[2];
            apply_job aj = {act, inc_start, inc, pp, Ap, nvar, 4096};
            int arc = sc_seam_parallel(threads, (int32_t)((nvar + aj.chunk - 1) / aj.chunk), apply_band, &aj);
            if (arc != SC_OK) {
                rc = sc_fail(err, arc, "the conjugate gradients failed");
                break;
            }
            double pAp[3] = {0, 0, 0};
            for (int64_t i = 0; i < nvar; i++)
                for (int c = 0; c < 3; c++) {
                    Ap[3 * i + c] += eps * pp[3 * i + c];
                    pAp[c] += pp[3 * i + c] * Ap[3 * i + c];
                }
            double alpha[3], rz2[3] = {0, 0, 0};
            for (int c = 0; c < 3; c++) alpha[c] = pAp[c] > 0 ? rz[c] / pAp[c] : 0;
            for (int64_t i = 0; i < nvar; i++)
                for (int c = 0; c < 3; c++) {
                    d[3 * i + c] += alpha[c] * pp[3 * i + c];
                    r[3 * i + c] -= alpha[c] * Ap[3 * i + c];
                    rr += r[3 * i + c] * r[3 * i + c];
                    z[3 * i + c] = r[3 * i + c] / diag[3 * i];
                    rz2[c] += r[3 * i + c] * z[3 * i + c];
                }
            st->iterations++;
            if (!(rr > 1e-12 * rr0)) break;
            for (int c = 0; c < 3; c++) {
                double beta = rz[c] > 0 ? rz2[c] / rz[c] : 0;
                rz[c] = rz2[c];
                for (int64_t i = 0; i < nvar; i++) pp[3 * i + c] = z[3 * i + c] + beta * pp[3 * i + c];
            }
        }
        for (size_t t = 0; t < (size_t)W * H && rc == SC_OK; t++)
            if (var[t] >= 0)
                for (int c = 0; c < 3; c++) x[3 * t + c] = (float)(x[3 * t + c] + d[3 * (size_t)var[t] + c]);
        st->texels_solved += nvar;
    }
    st->seconds_solve += sc_now() - t0;
    free(inc_start), free(inc), free(touch), free(slot2), free(worst), free(counts), free(list_start), free(list);
    free(act), free(vec), free(var), free(cells), free(slot);
    return rc;
}

/* ---------------------------------------------------------------- maps */

static sc_image_data *new_map(int32_t size) {
    sc_image_data *im = sc_image_alloc(size, size, 3, SC_PIXEL_F32);
    if (im) im->colorspace = SC_COLOR_DATA, snprintf(im->format, sizeof im->format, "exr");
    return im;
}

/* One map of one material: x0 = input - level (level NULL: the input
 * positions) where both rasters define them, the least-squares fit, then
 * push-pull beyond. */
static int make_map(const sc_mesh *in, int32_t material, const sc_seam_grid *g, const raster *rin,
                    const raster *rlev, const locator *lev, double tol, int threads, fit_stats *st,
                    sc_value **out, sc_error *err) {
    size_t n = (size_t)g->width * g->height;
    uint8_t *valid = malloc(n);
    sc_image_data *im = new_map(g->width);
    int rc = valid && im ? SC_OK : sc_fail(err, SC_ENOMEM, "out of memory");
    if (rc == SC_OK) {
        float *d = im->pixels;
        for (size_t t = 0; t < n; t++) {
            valid[t] = rin->face[t] >= 0 && (!rlev || rlev->face[t] >= 0);
            for (int c = 0; c < 3; c++)
                d[3 * t + c] = valid[t] ? rin->value[3 * t + c] - (rlev ? rlev->value[3 * t + c] : 0.0f) : 0.0f;
        }
        rc = fit_map(in, material, g, rin, rlev, lev, d, tol, threads, st, err);
    }
    if (rc == SC_OK) rc = push_pull(im->pixels, valid, g->width, g->height, 3, err);
    free(valid);
    if (rc != SC_OK) {
        sc_image_free(im);
        return rc;
    }
    *out = sc_value_new_image(im);
    return *out ? SC_OK : sc_fail(err, SC_ENOMEM, "out of memory");
}

/* A copy of `src` (its mesh and textures, minus the slots we make) plus
 * `slot_a` images and, when given, `slot_b` images per material. */
static sc_value *atlas_with(const sc_atlas *src, const char *slot_a, sc_value *const *a_images,
                            const char *slot_b, sc_value *const *b_images, const sc_seam_grid *grids,
                            int32_t nmat) {
    sc_atlas *a = sc_atlas_new(sc_value_retain(src->mesh));
    if (!a) return NULL;
    int rc = SC_OK;
    for (int32_t t = 0; t < src->ntex && rc == SC_OK; t++) {
        const sc_texture *tx = &src->textures[t];
        if (strcmp(tx->name, "geometry_image") == 0 || strcmp(tx->name, "displacement") == 0) continue;
        rc = sc_atlas_add_texture(a, tx->name, tx->material, tx->wrap_u, tx->wrap_v, tx->source,
                                  sc_value_retain(tx->image));
    }
    for (int32_t k = 0; k < nmat && rc == SC_OK; k++) {
        rc = sc_atlas_add_texture(a, slot_a, k, grids[k].wrap_u, grids[k].wrap_v, "",
                                  sc_value_retain(a_images[k]));
        if (rc == SC_OK && slot_b)
            rc = sc_atlas_add_texture(a, slot_b, k, grids[k].wrap_u, grids[k].wrap_v, "",
                                      sc_value_retain(b_images[k]));
    }
    if (rc != SC_OK) {
        sc_atlas_free(a);
        return NULL;
    }
    return sc_value_new_atlas(a);
}

/* erase_seams's terms for positions: no E_C1 (the two sides of a seam map
 * uv to the surface with their own Jacobians, so a geometry image has no
 * reason to be C1 across it). */
static const char *const erase_params[] = {"w_c1", "0", NULL};

/* Erase images[0..nmat) (one per material) on `mesh`; replaces them. */
static int erase_maps(sc_value *mesh, sc_value **images, const sc_seam_grid *grids, int32_t nmat,
                      double gap_tolerance, int threads, sc_error *err) {
    sc_atlas_ops_map *maps = calloc((size_t)nmat + 1, sizeof *maps);
    sc_value **out = calloc((size_t)nmat + 1, sizeof *out);
    int rc = maps && out ? SC_OK : sc_fail(err, SC_ENOMEM, "out of memory");
    for (int32_t k = 0; k < nmat && rc == SC_OK; k++)
        maps[k] = (sc_atlas_ops_map){k, grids[k].wrap_u, grids[k].wrap_v, images[k]};
    if (rc == SC_OK) rc = sc_atlas_ops_erase(mesh, maps, nmat, gap_tolerance, "none", erase_params, threads, out, NULL, err);
    for (int32_t k = 0; k < nmat && rc == SC_OK; k++) {
        sc_value_release(images[k]);
        images[k] = out[k];
    }
    free(maps), free(out);
    return rc;
}

/* ---------------------------------------------------------------- metrics */

static double bbox_diagonal(const sc_mesh *m) {
    double lo[3] = {HUGE_VAL, HUGE_VAL, HUGE_VAL}, hi[3] = {-HUGE_VAL, -HUGE_VAL, -HUGE_VAL};
    for (int32_t v = 0; v < m->nv; v++)
        for (int c = 0; c < 3; c++) lo[c] = fmin(lo[c], m->V[3 * v + c]), hi[c] = fmax(hi[c], m->V[3 * v + c]);
    double d = sqrt((hi[0] - lo[0]) * (hi[0] - lo[0]) + (hi[1] - lo[1]) * (hi[1] - lo[1]) +
                    (hi[2] - lo[2]) * (hi[2] - lo[2]));
    return d > 0 && isfinite(d) ? d : 1;
}

static const double sample_bary[7][3] = {
    {1.0 / 3, 1.0 / 3, 1.0 / 3}, {0.6, 0.2, 0.2}, {0.2, 0.6, 0.2}, {0.2, 0.2, 0.6},
    {0.45, 0.45, 0.1}, {0.1, 0.45, 0.45}, {0.45, 0.1, 0.45}};

typedef struct recon {
    double *e;   /* errors / diagonal */
    int64_t count, cap, missed;
} recon;

/* What the renderer draws, base_level(uv) + bilinear(map)(uv) (only the
 * map when level is NULL), against the input surface at 7 points of every
 * input face of the material; errors over the bounding-box diagonal. Faces
 * are measured in parallel chunks into slots of their own (-1: the level has
 * no face there); the errors are then sorted, so the metrics do not depend on
 * the thread count. */
typedef struct recon_job {
    const sc_mesh *in;
    const int32_t *faces;
    int64_t nfaces;
    const locator *lev;
    const sc_seam_grid *g;
    const sc_image_data *map;
    double diag;
    double *out;   /* 7 per face */
} recon_job;

#define RECON_CHUNK 1024

static int recon_band(void *ud, int32_t chunk) {
    const recon_job *J = ud;
    const sc_mesh *in = J->in;
    const int64_t q0 = (int64_t)chunk * RECON_CHUNK, q1 = q0 + RECON_CHUNK < J->nfaces ? q0 + RECON_CHUNK : J->nfaces;
    for (int64_t qf = q0; qf < q1; qf++) {
        const int32_t f = J->faces[qf];
        for (int s = 0; s < 7; s++) {
            const double *b = sample_bary[s];
            double p[3] = {0, 0, 0}, uv[2] = {0, 0};
            for (int c = 0; c < 3; c++) {
                const double *pv = in->V + 3 * in->FV[3 * f + c], *tv = in->U + 2 * in->FU[3 * f + c];
                for (int k = 0; k < 3; k++) p[k] += b[c] * pv[k];
                uv[0] += b[c] * tv[0], uv[1] += b[c] * tv[1];
            }
            double q[3] = {0, 0, 0}, s3[4];
            if (J->lev && locate(J->lev, uv[0], uv[1], q) < 0) {
                J->out[7 * qf + s] = -1;
                continue;
            }
            sc_seam_sample(J->g, J->map->pixels, J->map->channels, uv[0], uv[1], s3);
            double e2 = 0;
            for (int k = 0; k < 3; k++) e2 += (q[k] + s3[k] - p[k]) * (q[k] + s3[k] - p[k]);
            J->out[7 * qf + s] = sqrt(e2) / J->diag;
        }
    }
    return SC_OK;
}

static int reconstruction(const sc_mesh *in, int32_t material, const locator *lev, const sc_seam_grid *g,
                          const sc_image_data *map, double diag, int threads, recon *acc, sc_error *err) {
    int64_t nf = 0;
    for (int32_t f = 0; f < in->nf; f++) nf += in->FM[f] == material;
    if (acc->count + 7 * nf > acc->cap) {
        int64_t cap = acc->count + 7 * nf + 1;
        double *e = realloc(acc->e, sizeof(double) * (size_t)cap);
        if (!e) return sc_fail(err, SC_ENOMEM, "out of memory");
        acc->e = e, acc->cap = cap;
    }
    int32_t *faces = sc_alloc_array((size_t)nf + 1, sizeof(int32_t));
    if (!faces) return sc_fail(err, SC_ENOMEM, "out of memory");
    nf = 0;
    for (int32_t f = 0; f < in->nf; f++)
        if (in->FM[f] == material) faces[nf++] = f;
    /* the slots are the tail of acc->e, compacted in place below */
    recon_job job = {in, faces, nf, lev, g, map, diag, acc->e + acc->count};
    int rc = sc_seam_parallel(threads, (int32_t)((nf + RECON_CHUNK - 1) / RECON_CHUNK), recon_band, &job);
    free(faces);
    if (rc != SC_OK) return sc_fail(err, rc, "measuring the reconstruction failed");
    const double *slots = acc->e + acc->count;
    int64_t kept = acc->count;
    for (int64_t i = 0; i < 7 * nf; i++) {
        if (slots[i] < 0) acc->missed++;
        else acc->e[kept++] = slots[i];
    }
    acc->count = kept;
    return SC_OK;
}

static int cmp_double(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

/* name.max (as `name`), name_rms, name_p99; the errors get sorted. */
static double report_errors(sc_ctx *ctx, const char *name, recon *acc) {
    char n[96];
    double sum2 = 0, max = 0, p99 = 0;
    if (acc->count > 0) {
        qsort(acc->e, (size_t)acc->count, sizeof(double), cmp_double);
        for (int64_t i = 0; i < acc->count; i++) sum2 += acc->e[i] * acc->e[i];
        max = acc->e[acc->count - 1];
        p99 = acc->e[(int64_t)floor(0.99 * (double)(acc->count - 1))];
    }
    sc_ctx_metric(ctx, name, max);
    snprintf(n, sizeof n, "%s_rms", name);
    sc_ctx_metric(ctx, n, acc->count ? sqrt(sum2 / (double)acc->count) : 0);
    snprintf(n, sizeof n, "%s_p99", name);
    sc_ctx_metric(ctx, n, p99);
    return max;
}

/* ---------------------------------------------------------------- run */

static int run(sc_ctx *ctx, sc_error *err) {
    const sc_atlas *atlas = sc_ctx_atlas(ctx, "atlas");
    const sc_lods *lods = sc_ctx_lods(ctx, "lods");
    const sc_mesh *in = atlas->mesh->as.mesh;
    const int32_t size = (int32_t)sc_ctx_integer(ctx, "size");
    const int32_t pad = (int32_t)sc_ctx_integer(ctx, "padding");
    const bool erase = sc_ctx_bool(ctx, "erase");
    const double gap_tolerance = sc_ctx_number(ctx, "gap_tolerance");
    const double fit_tolerance = sc_ctx_number(ctx, "fit_tolerance");
    const int threads = sc_ctx_threads(ctx);
    int rc = sc_mesh_check(in, err);
    if (rc != SC_OK) return sc_error_prefix(err, "atlas");
    if (in->nf < 1) return sc_fail(err, SC_EINPUT, "atlas: the mesh has no faces");
    if ((uint64_t)size * (uint64_t)size > SC_IMAGE_MAX_PIXELS)
        return sc_fail(err, SC_EINPUT, "size: %d x %d is beyond the image limits", size, size);

    const int32_t nlevels = lods ? lods->count : 1;
    if (lods && nlevels < 1) return sc_fail(err, SC_EINPUT, "lods: the list is empty");
    const int32_t nmat = in->nmat;
    for (int32_t k = 0; k < nlevels && lods; k++) {
        const sc_mesh *lm = lods->levels[k]->as.atlas->mesh->as.mesh;
        rc = sc_mesh_check(lm, err);
        if (rc != SC_OK) return sc_error_prefix(err, "lods: level %d", k);
        if (lm->nmat != nmat) return sc_fail(err, SC_EINPUT, "lods: level %d has %d materials, atlas has %d", k, lm->nmat, nmat);
        for (int32_t m = 0; m < nmat; m++)
            if (strcmp(lm->materials[m], in->materials[m]) != 0)
                return sc_fail(err, SC_EINPUT, "lods: level %d material %d is '%s', atlas has '%s'", k, m,
                               lm->materials[m], in->materials[m]);
    }

    const double diag = bbox_diagonal(in), tol = fit_tolerance * diag;
    sc_seam_grid *grids = calloc((size_t)nmat + 1, sizeof *grids);
    sc_value **geometry = calloc((size_t)nmat + 1, sizeof *geometry);
    sc_value **disp = calloc((size_t)nmat * nlevels + 1, sizeof *disp);
    raster *rin = calloc((size_t)nmat + 1, sizeof *rin);
    const sc_mesh **meshes = calloc((size_t)nlevels + 1, sizeof *meshes);
    sc_value *union_mesh = NULL, *out_atlas = NULL;
    sc_lods *out_lods = NULL;
    fit_stats st = {0};
    recon acc = {0};
    if (!grids || !geometry || !disp || !meshes || !rin) rc = sc_fail(err, SC_ENOMEM, "out of memory");
    for (int32_t m = 0; m < nmat && rc == SC_OK; m++) {
        grids[m] = (sc_seam_grid){size, size, SC_WRAP_REPEAT, SC_WRAP_REPEAT};
        for (int32_t t = 0; t < atlas->ntex; t++)
            if (atlas->textures[t].material == m) {
                grids[m].wrap_u = atlas->textures[t].wrap_u, grids[m].wrap_v = atlas->textures[t].wrap_v;
                break;
            }
    }
    double t0 = sc_now(), t_raster = 0, t_fit = 0, t_erase = 0, t_metrics = 0;
    /* geometry images, padded 2 texels more than the displacement needs */
    for (int32_t m = 0; m < nmat && rc == SC_OK; m++) {
        rc = raster_build(in, m, &grids[m], pad + 2, threads, &rin[m], err);
        double t1 = sc_now();
        t_raster += t1 - t0;
        if (rc == SC_OK) rc = make_map(in, m, &grids[m], &rin[m], NULL, NULL, tol, threads, &st, &geometry[m], err);
        t0 = sc_now();
        t_fit += t0 - t1;
    }
    meshes[0] = in;
    for (int32_t k = 0; k < nlevels && rc == SC_OK; k++)
        meshes[k + 1] = lods ? lods->levels[k]->as.atlas->mesh->as.mesh : in;
    t0 = sc_now();
    if (rc == SC_OK && erase) {
        union_mesh = sc_atlas_ops_mesh_union(meshes, lods ? nlevels + 1 : 1);
        if (!union_mesh) rc = sc_fail(err, SC_ENOMEM, "out of memory for the union of the levels");
        if (rc == SC_OK) rc = erase_maps(union_mesh, geometry, grids, nmat, gap_tolerance, threads, err);
        if (rc != SC_OK) sc_error_prefix(err, "erase_seams on the geometry image");
    }
    t_erase += sc_now() - t0;
    t0 = sc_now();
    for (int32_t m = 0; m < nmat && rc == SC_OK; m++)
        rc = reconstruction(in, m, NULL, &grids[m], geometry[m]->as.image, diag, threads, &acc, err);
    if (rc == SC_OK) report_errors(ctx, "geometry_image_error", &acc);
    acc.count = acc.missed = 0;
    t_metrics += sc_now() - t0;

    double worst = 0;
    locator *locs = calloc((size_t)nmat + 1, sizeof *locs);
    if (!locs && rc == SC_OK) rc = sc_fail(err, SC_ENOMEM, "out of memory");
    for (int32_t k = 0; k < nlevels && rc == SC_OK; k++) {
        const sc_mesh *lm = meshes[k + 1];
        fit_stats sk = {0};
        for (int32_t m = 0; m < nmat && rc == SC_OK; m++) {
            raster rl = {0};
            t0 = sc_now();
            rc = raster_build(lm, m, &grids[m], pad, threads, &rl, err);
            if (rc == SC_OK) rc = locator_build(lm, m, locator_side(size), &locs[m], err);
            double t1 = sc_now();
            t_raster += t1 - t0;
            if (rc == SC_OK)
                rc = make_map(in, m, &grids[m], &rin[m], &rl, &locs[m], tol, threads, &sk,
                              &disp[(size_t)k * nmat + m], err);
            t_fit += sc_now() - t1;
            raster_free(&rl);
        }
        t0 = sc_now();
        if (rc == SC_OK && erase) {
            sc_value *mv = lods ? lods->levels[k]->as.atlas->mesh : atlas->mesh;
            rc = erase_maps(mv, disp + (size_t)k * nmat, grids, nmat, gap_tolerance, threads, err);
            if (rc != SC_OK) sc_error_prefix(err, "lods: level %d: erase_seams on the displacement", k);
        }
        t_erase += sc_now() - t0;
        t0 = sc_now();
        for (int32_t m = 0; m < nmat && rc == SC_OK; m++)
            rc = reconstruction(in, m, &locs[m], &grids[m], disp[(size_t)k * nmat + m]->as.image, diag, threads,
                                    &acc, err);
        for (int32_t m = 0; m < nmat; m++) locator_free(&locs[m]);
        if (rc == SC_OK) {
            char name[64];
            snprintf(name, sizeof name, "lod%d.reconstruction_error", k);
            worst = fmax(worst, report_errors(ctx, name, &acc));
            snprintf(name, sizeof name, "lod%d.samples_missed", k);
            sc_ctx_metric(ctx, name, (double)acc.missed);
            snprintf(name, sizeof name, "lod%d.texels_fitted", k);
            sc_ctx_metric(ctx, name, (double)sk.texels_solved);
            st.seconds_sample += sk.seconds_sample, st.seconds_solve += sk.seconds_solve, st.iterations += sk.iterations;
            st.samples += sk.samples, st.cells_inexact += sk.cells_inexact, st.cells_solved += sk.cells_solved;
        }
        acc.count = acc.missed = 0;
        t_metrics += sc_now() - t0;
    }
    free(locs);
    free(acc.e);
    if (rc == SC_OK) sc_ctx_metric(ctx, "reconstruction_error", worst);

    t0 = sc_now();
    double cov = 0, shared = 0;
    for (int32_t m = 0; m < nmat && rc == SC_OK; m++) {
        sc_seam_coverage c;
        rc = sc_seam_coverage_build(in, m, &grids[m], &c, err);
        if (rc == SC_OK) cov += (double)c.ncovered, shared += (double)c.nshared, sc_seam_coverage_free(&c);
    }
    if (rc == SC_OK) {
        sc_ctx_metric(ctx, "texels_covered", cov);
        sc_ctx_metric(ctx, "texels_shared", shared);
        sc_ctx_metric(ctx, "levels", nlevels);
        sc_ctx_metric(ctx, "geometry_image.texels_fitted", (double)st.texels_solved);
    }
    t_metrics += sc_now() - t0;

    /* outputs */
    if (rc == SC_OK) {
        out_atlas = atlas_with(atlas, "geometry_image", geometry, NULL, NULL, grids, nmat);
        out_lods = sc_lods_new();
        if (!out_atlas || !out_lods) rc = sc_fail(err, SC_ENOMEM, "out of memory");
    }
    for (int32_t k = 0; k < nlevels && rc == SC_OK; k++) {
        const sc_atlas *src = lods ? lods->levels[k]->as.atlas : atlas;
        sc_value *lv = atlas_with(src, "geometry_image", geometry, "displacement", disp + (size_t)k * nmat, grids, nmat);
        if (!lv || sc_lods_add(out_lods, lv) != SC_OK) rc = sc_fail(err, SC_ENOMEM, "out of memory");
    }
    sc_value *lods_value = NULL;
    if (rc == SC_OK) {
        lods_value = sc_value_new_lods(out_lods);
        out_lods = NULL;
        if (!lods_value) rc = sc_fail(err, SC_ENOMEM, "out of memory");
    }
    if (rc == SC_OK) {
        sc_ctx_set_output(ctx, "atlas", out_atlas);
        sc_ctx_set_output(ctx, "lods", lods_value);
        out_atlas = NULL;
        sc_ctx_metric(ctx, "seconds_raster", t_raster);
        sc_ctx_metric(ctx, "seconds_fit", t_fit);
        sc_ctx_metric(ctx, "seconds_fit_sample", st.seconds_sample);
        sc_ctx_metric(ctx, "seconds_fit_solve", st.seconds_solve);
        sc_ctx_metric(ctx, "fit_iterations", (double)st.iterations);
        sc_ctx_metric(ctx, "fit_samples", (double)st.samples);
        sc_ctx_metric(ctx, "fit_cells_inexact", (double)st.cells_inexact);
        sc_ctx_metric(ctx, "fit_cells_solved", (double)st.cells_solved);
        sc_ctx_metric(ctx, "seconds_erase", t_erase);
        sc_ctx_metric(ctx, "seconds_metrics", t_metrics);
    }
    sc_value_release(out_atlas);
    sc_lods_free(out_lods);
    sc_value_release(union_mesh);
    for (int32_t m = 0; geometry && m < nmat; m++) sc_value_release(geometry[m]);
    for (int32_t m = 0; rin && m < nmat; m++) raster_free(&rin[m]);
    for (size_t i = 0; disp && i < (size_t)nmat * nlevels; i++) sc_value_release(disp[i]);
    free(grids), free(geometry), free(disp), free(meshes), free(rin);
    return rc;
}

static const sc_param_desc params[] = {
    {.name = "size", .type = SC_PARAM_INTEGER, .def = 1024, .min = 16, .max = 16384,
     .doc = "side of the geometry image and of every displacement map, in texels"},
    {.name = "padding", .type = SC_PARAM_INTEGER, .def = 4, .min = 2, .max = 64,
     .doc = "texels around each chart filled with the linear continuation of its border faces "
            "(the geometry image gets 2 more); beyond, push-pull fill"},
    {.name = "erase", .type = SC_PARAM_BOOL, .def = 1,
     .doc = "erase seams (the erase_seams node): the geometry image on the seams of the input and every "
            "level at once, each displacement map on its level's seams"},
    {.name = "gap_tolerance", .type = SC_PARAM_NUMBER, .def = 0, .min = 0, .max = 1,
     .doc = "erase_seams's gap_tolerance: maps whose seam gaps are within it are left as they are"},
    {.name = "fit_tolerance", .type = SC_PARAM_NUMBER, .def = 5e-5, .min = 0, .max = 1,
     .doc = "texels of cells whose point samples miss the surface by more than this (fraction of the "
            "bounding-box diagonal) are fitted in least squares; 1 fits none"},
};

static const sc_port_desc inputs[] = {
    {.name = "atlas", .kind = SC_KIND_ATLAS, .doc = "the full-resolution mesh and its parameterisation"},
    {.name = "lods", .kind = SC_KIND_LODS, .optional = true,
     .doc = "levels of detail sharing the parameterisation (default: the atlas alone)"},
};

static const sc_port_desc outputs[] = {
    {.name = "atlas", .kind = SC_KIND_ATLAS,
     .doc = "the input atlas plus texture slot geometry_image (f32 RGB positions) per material"},
    {.name = "lods", .kind = SC_KIND_LODS,
     .doc = "every level plus the shared geometry_image and its own displacement (f32 RGB, original - level)"},
};

const sc_node_desc sc_node_bake_displacement = {
    .type = "bake_displacement",
    .version = 1,
    .summary = "bakes a geometry image and a vector displacement map per level of detail (Liu et al. 2017 §7)",
    .inputs = inputs,
    .ninputs = SC_COUNT(inputs),
    .outputs = outputs,
    .noutputs = SC_COUNT(outputs),
    .params = params,
    .nparams = SC_COUNT(params),
    .run = run,
};
