/* bake_displacement.c - the node `bake_displacement`: geometry images and
 * vector displacement maps in the shared parameterisation (Liu et al. 2017,
 * §7).
 *
 * Design note.
 *  - Geometry image. For each material, a size x size f32 RGB image (colour
 *    space DATA) holding the input mesh's positions at texel centres
 *    (docs/design.md: texel (i, j) at ((i + 1/2)/W, (j + 1/2)/H), row 0 = v = 0).
 *    Every face's uv triangle is scanned over its bounding box grown by
 *    `padding` texels (each row cut to the columns that can lie within it);
 *    a texel takes the face nearest to its centre (in
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
 *    them, faces smaller than a texel, cells reaching out of the chart)
 *    get 4 x 4 samples of the input surface per cell (a barycentric grid on
 *    faces under two texels across); where point sampling misses them by more
 *    than `fit_tolerance` of the bounding-box diagonal, the corner texels are
 *    solved for in least squares (mean squared error per cell; exact cells
 *    enter through the bilinear mass matrix), by Jacobi-preconditioned
 *    conjugate gradients. The geometry image gets the same fit (P_k = 0).
 *    Sampling runs in bands of rows, each band visiting (from a per-band face
 *    list built once per map) the faces that can reach its rows in face
 *    order, so each cell sums its own samples in the serial order: the same
 *    bytes on any thread count. A first pass only measures the miss per cell,
 *    and skips the samples of a face in a cell that provably all miss by less
 *    than the tolerance (cell_within: the map is affine there, so the miss is
 *    bounded by the corners'), counting them only; a second pass repeats the
 *    same samples in the cells next to a solved texel only, summing their
 *    Gram matrices and residuals. In each cell row a face visits only the
 *    cells its four sample rows cross, and on each sample row only the points
 *    within the face's span (line_span, grown by 1e-6 per texel of the face's
 *    extent, far above barycentric's rounding): the points left out are
 *    outside the face, so the samples and their order are those of a scan of
 *    the face's box. The level's faces at a cell's corners are read once per
 *    cell (level_cell). The solver's matrix products gather per unknown in
 *    the order a scatter over the cells would add, so they split over threads
 *    with the same bytes.
 *  - Seams. With `erase` (the default), the maps are erased by the erase
 *    kernel (sc_erase through sc_atlas_ops_erase, with erase_seams's defaults
 *    but no E_C1 term: the two sides of a seam map uv to the surface with
 *    their own Jacobians, so positions have no reason to be C1 across it): G
 *    on the union of the input mesh and every level (disjoint copies in one
 *    mesh, so one geometry image serves every level; a level repeating
 *    another is in it once), each D_k on level k's own seams. Each map set's
 *    erasure and then its metrics run on a worker thread (with more than one
 *    thread) as soon as the set is fitted (after_fit), so the erase kernel's
 *    serial stretches overlap the next level's raster and fit; each depends
 *    on its own set alone. Without `erase` the maps are only fitted and
 *    filled, e.g. to feed erase_seams from the graph or to show that unerased
 *    maps crack.
 *  - Repeated levels. A level whose mesh is an earlier level's (the same
 *    digest: a decimation that stalled repeats its last level) takes that
 *    level's erased maps and metrics instead of being fitted and erased
 *    again; the bytes are the same either way.
 *  - Limits. Where a chart's uv is squeezed below a texel per face (a texel
 *    then spans a large part of the surface), no bilinear map follows the
 *    surface: the RMS residual of the best bilinear fit of each cell on its
 *    own bounds the max error from below. Erasure next to such charts moves
 *    texels further. Levels decimated for the maps (decimate's map_size)
 *    keep what no map restores - seams, uv slivers, creases sharper than a
 *    texel follows - so that their maps can restore the rest
 *    (docs/notes/bake_displacement.md).
 *  - Outputs. `atlas`: the input mesh, its textures (slots geometry_image and
 *    displacement dropped) plus "geometry_image" per material. `lods`: every
 *    level (or the input alone when `lods` is unconnected) with its own
 *    textures plus the very same geometry_image value and its own
 *    "displacement" per material: what render's geometry_image, displaced and
 *    tessellated modes look up. The images are f32 DATA values; files are
 *    written by whoever saves them (save, mipmap), not here.
 *  - Metrics, over the bounding-box diagonal, two readings of "level k plus
 *    its displacement reconstructs the input":
 *    lod<k>.reconstruction_error: the surface distance, the drawn surface
 *    (base_k + bilinear(D_k) over the level's faces) against the input
 *    surface as surfaces, both ways (the larger of the one-sided maxima
 *    lod<k>.reconstruction_error_to_input and _from_input; surface_distance
 *    says how: both surfaces sampled by area, vertices and edges included,
 *    `surface_samples` each; exact distances to the input through a BVH,
 *    upper bounds by Gauss-Newton to the drawn surface);
 *    lod<k>.same_uv_error (max), _rms and _p99: base_k + bilinear(D_k)
 *    against the input point of the same uv, at 7 points inside every input
 *    face (the level's face found exactly, through a bucket grid of its uv
 *    faces) - stricter, as a squeezed uv makes a point slide along the
 *    surface; geometry_image_error (and _rms, _p99): the same-uv error of G;
 *    reconstruction_error and same_uv_error: the worst level;
 *    texels_covered and texels_shared (sc_seam_coverage, input mesh: the
 *    node fails, before any work, when more than max_shared_fraction of the
 *    covered texels are shared, as overlapping or mirrored charts make them:
 *    one value per texel cannot serve two places of the surface);
 *    degenerate_uv_fraction (sc_seam_degenerate_uv_fraction: the node
 *    fails, before any work, when more than max_degenerate_uv_fraction of
 *    the surface lies on faces whose uv have no area, as missing texture
 *    coordinates leave them: no texel holds their points);
 *    texels fitted and timings per stage.
 * Measurements and history: docs/notes/bake_displacement.md.
 */
#include <float.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "sc_atlas_ops.h"
#include "sc_geometry.h"
#include "sc_hausdorff.h"
#include "sc_nodes.h"
#include "sc_seam.h"

/* ---------------------------------------------------------------- raster */

/* One rasterisation of a mesh material: per texel the nearest face (or -1),
 * its distance and the position extended to the texel centre. raster_build
 * reuses the arrays of a raster of the same size (first touches of fresh
 * pages cost more than the work on them). */
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
 * texel's winner (nearest, ties to the lower face) is the serial one. A texel
 * some face holds at distance 0 is final (a later face only ties), so later
 * faces skip it; columns are cut to those within `pad` (sc_atlas_ops_row_span). */
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
            int64_t i0, i1;
            sc_atlas_ops_row_span(x, y, pad, (double)j, &i0, &i1);
            if (i0 < (int64_t)ceil(x0)) i0 = (int64_t)ceil(x0);
            if (i1 > (int64_t)floor(x1)) i1 = (int64_t)floor(x1);
            for (int64_t i = i0; i <= i1; i++) {
                size_t t = (size_t)jw * W + (size_t)sc_seam_wrap(i, W, g->wrap_u);
                if (r->dist[t] == 0) continue;
                double l[3];
                barycentric(x, y, (double)i, (double)j, l);
                double d2 = 0;
                if (l[0] < 0 || l[1] < 0 || l[2] < 0)
                    d2 = fmin(sc_atlas_ops_segment_distance2((double)i, (double)j, x[0], y[0], x[1], y[1]),
                              fmin(sc_atlas_ops_segment_distance2((double)i, (double)j, x[1], y[1], x[2], y[2]),
                                   sc_atlas_ops_segment_distance2((double)i, (double)j, x[2], y[2], x[0], y[0])));
                float d = (float)sqrt(d2);
                if (d > (float)pad) continue;
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
    if (!(r->value && r->dist && r->face && r->width == W && r->height == H)) {   /* else its arrays are reused */
        raster_free(r);
        r->width = W, r->height = H;
        r->value = sc_alloc_array(n * 3, sizeof(float));
        r->dist = sc_alloc_array(n, sizeof(float));
        r->face = sc_alloc_array(n, sizeof(int32_t));
    }
    if (r->value) memset(r->value, 0, n * 3 * sizeof(float));
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
 * extended a little beyond it); -1 when no face is within reach. Every face
 * holding uv has its box in uv's own bucket, so that bucket is searched
 * first: when a face there holds uv, the 3 x 3 buckets around could only
 * add faces that do not, and the answer is the same. */
static int32_t locate(const locator *L, double u, double v, double p[3]) {
    const sc_mesh *m = L->m;
    int32_t bi = bucket_of(u, L->gw), bj = bucket_of(v, L->gw), best = -1;
    double best_min = -HUGE_VAL, bl[3] = {0, 0, 0};
    for (int32_t ring = 0; ring < 2 && !(best_min >= 0); ring++) {   /* uv's bucket, then the 3 x 3 around it */
        for (int32_t j = bj - ring; j <= bj + ring; j++)
            for (int32_t i = bi - ring; i <= bi + ring; i++) {
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

/* One axis of cell_key: the key column (row) of cell column (row) c of a
 * grid of n texels under wrap mode w; false when the cell is outside it. */
static inline bool key_axis(int64_t c, int32_t n, sc_wrap w, int64_t *k) {
    if (w == SC_WRAP_REPEAT) *k = c >= 0 && c < n ? c : sc_seam_wrap(c, n, SC_WRAP_REPEAT);
    else if (c < -1 || c > n - 1) return false;
    else *k = c + 1;
    return true;
}

static bool cell_key(const cellgrid *cg, int64_t cx, int64_t cy, size_t *key) {
    int64_t kx, ky;
    if (!key_axis(cx, cg->W, cg->wu, &kx) || !key_axis(cy, cg->H, cg->wv, &ky)) return false;
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

/* The faces the level's raster gives a cell's four corners (a face equal
 * to the previous corner's once), with their uv triangles and corner
 * positions: where the level's position at a sample of the cell is looked
 * up first (level_at), far cheaper than locate. */
typedef struct level_cell {
    int n;
    double x[4][3], y[4][3];
    const double *p[4][3];
} level_cell;

static void level_cell_make(const sc_mesh *m, const raster *rl, const int32_t id[4], level_cell *lc) {
    lc->n = 0;
    for (int q = 0; q < 4; q++) {
        int32_t f = rl->face[id[q]];
        if (f < 0 || (q > 0 && f == rl->face[id[q - 1]])) continue;
        for (int c = 0; c < 3; c++) {
            const double *uv = m->U + 2 * m->FU[3 * f + c];
            lc->x[lc->n][c] = uv[0], lc->y[lc->n][c] = uv[1], lc->p[lc->n][c] = m->V + 3 * m->FV[3 * f + c];
        }
        lc->n++;
    }
}

/* The level's position at uv when one of the cell's corner faces holds it. */
static bool level_at(const level_cell *lc, double u, double v, double p[3]) {
    for (int i = 0; i < lc->n; i++) {
        double l[3];
        if (!barycentric(lc->x[i], lc->y[i], u, v, l) || l[0] < 0 || l[1] < 0 || l[2] < 0) continue;
        for (int k = 0; k < 3; k++) p[k] = l[0] * lc->p[i][0][k] + l[1] * lc->p[i][1][k] + l[2] * lc->p[i][2][k];
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
    double tol;            /* pass 1: cells whose samples provably miss by no more skip them (cell_within) */
    const int32_t *list_start, *list;   /* per chunk, the faces that may sample its rows, in face order */
    int64_t *samples;   /* per chunk */
} sample_job;

/* Face f's uv corners in texel-centre coordinates and whether it is sampled
 * at all (not absurd, not NaN, not flat); *small: under two texels across. */
static bool sample_face(const sc_mesh *in, int32_t f, int32_t W, int32_t H, double fx[3], double fy[3], bool *small,
                        double *extent) {
    for (int c = 0; c < 3; c++) {
        const double *t = in->U + 2 * in->FU[3 * f + c];
        fx[c] = t[0] * W - 0.5, fy[c] = t[1] * H - 0.5;
    }
    double e = 0, lt[3];
    for (int c = 0; c < 3; c++) e = fmax(e, hypot(fx[(c + 1) % 3] - fx[c], fy[(c + 1) % 3] - fy[c]));
    *small = e < 2;
    if (extent) *extent = e;
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
            if (!sample_face(in, f, cg->W, cg->H, fx, fy, &small, NULL)) continue;
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

/* Where the line y = Y (texel-centre coordinates) crosses triangle (fx, fy):
 * [*lo, *hi] grown by `margin` (empty, lo > hi, when it misses). A sample
 * point of the line outside it is outside the face: barycentric's rounding
 * is far below the margin. */
static void line_span(const double fx[3], const double fy[3], double Y, double margin, double *lo, double *hi) {
    double a = HUGE_VAL, b = -HUGE_VAL;
    for (int c = 0; c < 3; c++) {
        double x0 = fx[c], y0 = fy[c], x1 = fx[(c + 1) % 3], y1 = fy[(c + 1) % 3];
        if (!((y0 <= Y && Y <= y1) || (y1 <= Y && Y <= y0))) continue;
        double xa = x0, xb = x1;
        if (y1 != y0) xa = xb = x0 + (x1 - x0) * ((Y - y0) / (y1 - y0));
        if (xa > xb) {
            double t = xa;
            xa = xb, xb = t;
        }
        if (xa < a) a = xa;
        if (xb > b) b = xb;
    }
    *lo = a - margin, *hi = b + margin;
}

/* A big face's spans on the four sample rows y = cy + (j + 1/2) / 4 of a
 * cell row. */
typedef struct row_spans {
    double lo[4], hi[4];
} row_spans;

/* The spans on cell row cy and the cell columns [*xa, *xb] (within
 * [cx0, cx1]) they reach; false when none does. */
static bool sample_rows(const double fx[3], const double fy[3], double margin, int64_t cy, int64_t cx0, int64_t cx1,
                        row_spans *rs, int64_t *xa, int64_t *xb) {
    double lo = HUGE_VAL, hi = -HUGE_VAL;
    for (int j = 0; j < 4; j++) {
        line_span(fx, fy, (double)cy + (j + 0.5) / 4, margin, &rs->lo[j], &rs->hi[j]);
        if (rs->lo[j] <= rs->hi[j]) lo = rs->lo[j] < lo ? rs->lo[j] : lo, hi = rs->hi[j] > hi ? rs->hi[j] : hi;
    }
    if (!(lo <= hi)) return false;
    double l = floor(lo), h = floor(hi);
    *xa = l > (double)cx0 ? (int64_t)l : cx0, *xb = h < (double)cx1 ? (int64_t)h : cx1;
    return *xa <= *xb;
}

/* Whether sample s (4 x 4, row-major) of cell column cx can be inside. */
static inline bool in_span(const row_spans *rs, int64_t cx, int32_t s) {
    double X = (double)cx + ((s & 3) + 0.5) / 4;
    return rs->lo[s >> 2] <= X && X <= rs->hi[s >> 2];
}

/* Pass 1 only: whether no sample of big face f (texel coordinates fx, fy,
 * positions p) in cell (cx, cy) with corner texels id can miss by more than
 * `tol`, so that its samples need only be counted. Over the cell, f = L_F -
 * M_G is affine when one level face G holds all four corners (a triangle is
 * convex, so it then holds the whole cell; no level: M = 0), and bilinear
 * interpolation reproduces affine maps, so at any point s of the cell
 *     bilinear(x)(s) - f(s) = sum_q w_q(s) (x_q - f(c_q)),
 * a convex combination: the miss is at most max_q |x_q - f(c_q)|, and at the
 * 16 sample points it is that sum with their fixed weights. A margin of
 * 0.1% of tol covers rounding, so this skips only samples whose miss the
 * full evaluation would also find within tol: the solved cells are the
 * same. *nsamples gets the samples the full evaluation would count (those
 * inside the face; G holds them all). */
static bool cell_within(const sample_job *J, const double fx[3], const double fy[3], const double *const p[3],
                        int64_t cx, int64_t cy, const int32_t id[4], const row_spans *rs, double tol,
                        int64_t *nsamples) {
    double f[4][3];
    bool corners_inside = true;   /* then so is every sample point (a triangle is convex) */
    for (int q = 0; q < 4; q++) {
        double l[3], X = (double)(cx + (q & 1)), Y = (double)(cy + (q >> 1));
        barycentric(fx, fy, X, Y, l);
        corners_inside = corners_inside && l[0] >= 0 && l[1] >= 0 && l[2] >= 0;
        for (int k = 0; k < 3; k++) f[q][k] = l[0] * p[0][k] + l[1] * p[1][k] + l[2] * p[2][k];
    }
    if (J->lev) {
        const sc_mesh *m = J->lev->m;
        const raster *rl = J->rlev;
        const int32_t G = rl->face[id[0]];
        if (G < 0) return false;
        for (int q = 0; q < 4; q++)
            if (rl->face[id[q]] != G || rl->dist[id[q]] != 0) return false;
        double gx[3], gy[3];
        const double *gp[3];
        for (int c = 0; c < 3; c++) {
            const double *uv = m->U + 2 * m->FU[3 * G + c];
            gx[c] = uv[0] * J->g->width - 0.5, gy[c] = uv[1] * J->g->height - 0.5;
            gp[c] = m->V + 3 * m->FV[3 * G + c];
        }
        for (int q = 0; q < 4; q++) {   /* G holds the corners where the samples are (not a wrapped copy) */
            double l[3];
            if (!barycentric(gx, gy, (double)(cx + (q & 1)), (double)(cy + (q >> 1)), l) || l[0] < 0 || l[1] < 0 ||
                l[2] < 0)
                return false;
            for (int k = 0; k < 3; k++) f[q][k] -= l[0] * gp[0][k] + l[1] * gp[1][k] + l[2] * gp[2][k];
        }
    }
    double e[4][3], emax = 0;   /* the corners' errors; their largest bounds every miss */
    for (int q = 0; q < 4; q++) {
        double d2 = 0;
        for (int k = 0; k < 3; k++) e[q][k] = (double)J->x[3 * (size_t)id[q] + k] - f[q][k], d2 += e[q][k] * e[q][k];
        emax = fmax(emax, d2);
    }
    if (sqrt(emax) > 0.999 * tol)   /* else the 16 sample points themselves (in the face or not) */
        for (int32_t s = 0; s < 16; s++) {
            const double ss = ((s & 3) + 0.5) / 4, tt = ((s >> 2) + 0.5) / 4;
            const double w[4] = {(1 - ss) * (1 - tt), ss * (1 - tt), (1 - ss) * tt, ss * tt};
            double d2 = 0;
            for (int k = 0; k < 3; k++) {
                double d = w[0] * e[0][k] + w[1] * e[1][k] + w[2] * e[2][k] + w[3] * e[3][k];
                d2 += d * d;
            }
            if (!(sqrt(d2) <= 0.999 * tol)) return false;
        }
    if (corners_inside) {
        *nsamples += 16;
        return true;
    }
    for (int32_t s = 0; s < 16; s++) {
        double l[3];
        if (!in_span(rs, cx, s)) continue;
        barycentric(fx, fy, (double)cx + ((s & 3) + 0.5) / 4, (double)cy + ((s >> 2) + 0.5) / 4, l);
        *nsamples += !(l[0] < 0 || l[1] < 0 || l[2] < 0);
    }
    return true;
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
    level_cell lc;                 /* the level's faces at the corners of cell lc_key */
    size_t lc_key = SIZE_MAX;
    /* dense samples of f in those cells: 4 x 4 per cell inside a face,
     * and a barycentric grid on faces under two texels across */
    for (int32_t lq = J->list_start[chunk]; lq < J->list_start[chunk + 1]; lq++) {
        const int32_t f = J->list[lq];
        if (in->FM[f] != material) continue;
        const double *t[3], *p[3];
        double fx[3], fy[3];
        bool small;
        double extent;
        if (!sample_face(in, f, W, H, fx, fy, &small, &extent)) continue;   /* absurd, NaN, flat */
        const double margin = 1e-6 * (1 + extent);   /* of the sample rows' spans: far above rounding */
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
        for (int64_t cy = small ? cy0 : ry0; cy <= (small ? cy0 : ry1); cy++) {
            int64_t ky = 0, xa = cx0, xb = cx0;
            row_spans rs;
            if (!small) {   /* the key row, then the cells of the row whose sample points can be in the face */
                if (!key_axis(cy, H, cg.wv, &ky) || ky < (int64_t)k0 || ky >= (int64_t)k1) continue;
                if (!sample_rows(fx, fy, margin, cy, cx0, cx1, &rs, &xa, &xb)) continue;
            }
            for (int64_t cx = xa; cx <= xb; cx++) {
                size_t key = 0;
                int64_t kx;
                if (!small && (!key_axis(cx, W, cg.wu, &kx) || slot[key = (size_t)ky * cg.CW + (size_t)kx] < 0))
                    continue;
                const size_t cell_key0 = key;   /* a big face's samples land in this cell */
                int32_t cell_id[4];
                if (!small) cell_corners(&cg, cell_key0, cell_id);
                if (!small && !cells && cell_within(J, fx, fy, p, cx, cy, cell_id, &rs, J->tol, &nsamples)) continue;
                int32_t npts = small ? (n + 1) * (n + 2) / 2 : 16;
                for (int32_t s = 0; s < npts; s++) {
                    double l[3];
                    if (small) {
                        int32_t a = 0, rem = s;
                        while (rem > n - a) rem -= n - a + 1, a++;
                        l[0] = (double)a / n, l[1] = (double)rem / n, l[2] = 1 - l[0] - l[1];
                    } else {
                        if (!in_span(&rs, cx, s)) continue;
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
                        if (key != lc_key) level_cell_make(lev->m, rlev, id, &lc), lc_key = key;
                        if (!level_at(&lc, u, v, q) && locate(lev, u, v, q) < 0) continue;
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
                        double miss = sqrt(gap);
                        if (miss > worst[slot[key]]) worst[slot[key]] = miss;
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
    }
    J->samples[chunk] = nsamples;
    return SC_OK;
}

/* Over cells [chunk * CELL_CHUNK, ...): slot[k] = -1 where x0 is exact (the
 * four corners inside one face of the input and, with `rlev`, one of the
 * level), else 0. */
#define CELL_CHUNK 65536
typedef struct cell_job {
    const cellgrid *cg;
    const raster *rin, *rlev;
    int32_t *slot;
    size_t ncell;
} cell_job;

static int cell_band(void *ud, int32_t chunk) {
    const cell_job *J = ud;
    const size_t k0 = (size_t)chunk * CELL_CHUNK, k1 = k0 + CELL_CHUNK < J->ncell ? k0 + CELL_CHUNK : J->ncell;
    const raster *rin = J->rin, *rlev = J->rlev;
    for (size_t k = k0; k < k1; k++) {
        int32_t id[4];
        cell_corners(J->cg, k, id);
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

/* Ap = (sum P^T G P) p, gathered per unknown: unknown v sums the terms of
 * its entries (active cell, corner q; cells in ascending order), each over
 * the cell's free corners s (G[q][s] p_s): the very order a scatter over the
 * cells adds them in, so any split of the unknowns gives the same bytes.
 * The terms are laid out once per solve (coefficient, column). */
typedef struct apply_job {
    const int64_t *row;      /* unknown v's terms: [row[v], row[v + 1]) */
    const double *coef;      /* each term: coefficient and column */
    const int32_t *col;
    const double *p;
    double *Ap;
    int64_t nvar, chunk;
} apply_job;

static int apply_band(void *ud, int32_t chunk) {
    const apply_job *J = ud;
    const int64_t v0 = (int64_t)chunk * J->chunk, v1 = v0 + J->chunk < J->nvar ? v0 + J->chunk : J->nvar;
    for (int64_t v = v0; v < v1; v++) {
        double acc[3] = {0, 0, 0};
        for (int64_t t = J->row[v]; t < J->row[v + 1]; t++) {
            const double *pv = J->p + 3 * (size_t)J->col[t];
            for (int c = 0; c < 3; c++) acc[c] += J->coef[t] * pv[c];
        }
        for (int c = 0; c < 3; c++) J->Ap[3 * v + c] = acc[c];
    }
    return SC_OK;
}

/* fit_map's large work arrays, kept from one map to the next of a bake (a
 * fresh allocation pays a page fault per 4 KiB on first touch, more than the
 * work done on most of them). */
typedef struct fit_scratch {
    int32_t *slot, *slot2, *var;
    double *worst;
    fit_cell *cells;
    size_t n_slot, n_slot2, n_var, n_worst, n_cells;
} fit_scratch;

static void fit_scratch_free(fit_scratch *ws) {
    free(ws->slot), free(ws->slot2), free(ws->var), free(ws->worst), free(ws->cells);
    memset(ws, 0, sizeof *ws);
}

/* *p with room for n items of `size` bytes (contents not kept when it grows). */
static void *scratch(void *p, size_t *have, size_t n, size_t size) {
    void **pp = p;
    if (n <= *have) return *pp;
    free(*pp);
    *pp = sc_alloc_array(n, size);
    *have = *pp ? n : 0;
    return *pp;
}

static int cmp_size(const void *a, const void *b) {
    size_t x = *(const size_t *)a, y = *(const size_t *)b;
    return (x > y) - (x < y);
}

/* What fit_map's steps share: its inputs, then what each step makes. */
typedef struct fit_work {
    const sc_mesh *in;
    int32_t material;
    const sc_seam_grid *g;
    const raster *rin, *rlev;
    const locator *lev;
    float *x;                  /* the map: x0 in, the fit out */
    double tol;
    int threads;
    fit_scratch *ws;
    fit_stats *st;
    cellgrid cg;
    size_t ncell;
    int32_t *slot;             /* per cell: its index among the inexact cells, or -1 */
    int64_t nbad;              /* inexact cells */
    double *worst;             /* per inexact cell: the largest miss of x0 at its samples */
    int32_t band, nchunks;     /* the sampling chunks: `band` key rows each */
    int64_t *counts;           /* per chunk: samples taken */
    int32_t *list_start, *list;   /* per chunk: the faces that may sample its rows (sample_lists) */
    double t0;                 /* when the solve's clock started (the second sampling pass aside) */
    int32_t *var;              /* per texel: its index among the free texels, or -1 */
    int64_t nvar;
    int32_t *free_texel;       /* the free texels, in the order of their index in var */
    size_t *touched;           /* the cells with a free corner, ascending */
    int64_t ntouched;
    int32_t *slot2;            /* inexact cells with a free corner: index in `cells` */
    fit_cell *cells;
    active *act;               /* the cells that enter the fit */
    int64_t nact;
    int64_t *inc_start, *inc;  /* each unknown's (cell, corner) entries: [inc_start[v], inc_start[v + 1]) */
    int64_t *row;              /* each unknown's terms (apply_job) */
    double *coef;
    int32_t *col;
    double *vec;               /* the solve's vectors: d, r, z, p, Ap and the diagonal, 3 nvar each */
} fit_work;

/* Frees fit_map's own arrays (the scratch arrays stay in ws for the next map). */
static void fit_work_free(fit_work *f) {
    free(f->inc_start), free(f->inc), free(f->row), free(f->coef), free(f->col), free(f->touched), free(f->free_texel);
    free(f->counts), free(f->list_start), free(f->list);
    free(f->act), free(f->vec);
}

/* 1. The cells where x0 may be inexact, numbered in slot (-1: exact). */
static int mark_inexact_cells(fit_work *f, sc_error *err) {
    int32_t *slot = f->slot = scratch(&f->ws->slot, &f->ws->n_slot, f->ncell, sizeof(int32_t));
    if (!slot) return sc_fail(err, SC_ENOMEM, "out of memory");
    cell_job cj = {&f->cg, f->rin, f->rlev, slot, f->ncell};
    if (sc_seam_parallel(f->threads, (int32_t)((f->ncell + CELL_CHUNK - 1) / CELL_CHUNK), cell_band, &cj) != SC_OK)
        return sc_fail(err, SC_ENOMEM, "out of memory");
    int64_t nbad = 0;
    for (size_t k = 0; k < f->ncell; k++)
        if (slot[k] >= 0) slot[k] = nbad < INT32_MAX - 1 ? (int32_t)nbad++ : -1;
    f->nbad = nbad;
    return SC_OK;
}

/* The sampling passes' chunks: the misses per inexact cell, the samples per
 * chunk and the faces of each chunk (sample_lists). */
static int prepare_sampling(fit_work *f, sc_error *err) {
    f->worst = scratch(&f->ws->worst, &f->ws->n_worst, (size_t)f->nbad + 1, sizeof *f->worst);
    if (f->worst) memset(f->worst, 0, ((size_t)f->nbad + 1) * sizeof *f->worst);
    f->band = 16, f->nchunks = (f->cg.CH + f->band - 1) / f->band;
    f->counts = sc_calloc_array((size_t)f->nchunks, sizeof(int64_t));
    if (!f->worst || !f->counts ||
        sample_lists(f->in, f->material, &f->cg, f->band, f->nchunks, &f->list_start, &f->list) != SC_OK)
        return sc_fail(err, SC_ENOMEM, "out of memory for %lld cells", (long long)f->nbad);
    return SC_OK;
}

/* A pass of sample_band over every chunk: into `cells` (the Gram matrices
 * and residuals) when given, else the misses into `worst`. */
static int sample_pass(const fit_work *f, const int32_t *slot, fit_cell *cells, double *worst) {
    sample_job job = {.in = f->in, .material = f->material, .g = f->g, .cg = f->cg, .slot = slot, .cells = cells,
                      .worst = worst, .rlev = f->rlev, .lev = f->lev, .x = f->x, .band = f->band, .tol = f->tol,
                      .list_start = f->list_start, .list = f->list, .samples = f->counts};
    return sc_seam_parallel(f->threads, f->nchunks, sample_band, &job);
}

/* 2. Dense samples of f in the inexact cells (4 x 4 per cell inside a face,
 * a barycentric grid on faces under two texels across), a first pass: only
 * how far x0 misses them. The Gram matrices and residuals (step 4) are
 * summed in a second pass over the same samples (sum_cell_samples), in the
 * cells next to free texels only. */
static int measure_misses(fit_work *f, sc_error *err) {
    double t0 = sc_now();
    int rc = sample_pass(f, f->slot, NULL, f->worst);
    for (int32_t c = 0; c < f->nchunks; c++) f->st->samples += f->counts[c];
    if (rc != SC_OK) rc = sc_fail(err, rc, "sampling the surface failed");
    f->st->seconds_sample += sc_now() - t0;
    return rc;
}

/* 3. The free texels: corners of the cells x0 misses by more than tol. */
static int find_free_texels(fit_work *f, sc_error *err) {
    const size_t texels = (size_t)f->g->width * f->g->height;
    fit_stats *st = f->st;
    int32_t *var = f->var = scratch(&f->ws->var, &f->ws->n_var, texels, sizeof(int32_t));
    if (!var) return sc_fail(err, SC_ENOMEM, "out of memory");
    for (size_t t = 0; t < texels; t++) var[t] = -1;
    for (size_t k = 0; k < f->ncell; k++) {
        if (f->slot[k] < 0) continue;
        st->cells_inexact++;
        if (!(f->worst[f->slot[k]] > f->tol)) continue;
        st->cells_solved++;
    }
    f->free_texel = sc_alloc_array((size_t)st->cells_solved * 4 + 1, sizeof(int32_t));
    if (!f->free_texel) return sc_fail(err, SC_ENOMEM, "out of memory");
    for (size_t k = 0; k < f->ncell; k++) {
        if (f->slot[k] < 0 || !(f->worst[f->slot[k]] > f->tol)) continue;
        int32_t id[4];
        cell_corners(&f->cg, k, id);
        for (int q = 0; q < 4; q++)
            if (var[id[q]] < 0) f->free_texel[f->nvar] = id[q], var[id[q]] = (int32_t)f->nvar++;
    }
    return SC_OK;
}

/* Room for the active cells and the solve's vectors. */
static int alloc_solve(fit_work *f, sc_error *err) {
    f->act = sc_alloc_array((size_t)f->nvar * 4 + 1, sizeof *f->act);
    f->vec = sc_calloc_array((size_t)f->nvar * 3 * 6, sizeof(double));
    if (!f->act || !f->vec) return sc_fail(err, SC_ENOMEM, "out of memory for %lld unknowns", (long long)f->nvar);
    return SC_OK;
}

/* The cells with a free corner, ascending: those having a free texel
 * (i, j) as a corner are cells (i - 1 .. i, j - 1 .. j), through the wrap
 * modes (cell_corners' inverse). The inexact ones are numbered in slot2,
 * with zeroed sums in `cells`. */
static int cells_with_free_corner(fit_work *f, sc_error *err) {
    const int32_t W = f->g->width;
    size_t *touched = f->touched = sc_alloc_array((size_t)f->nvar * 4 + 1, sizeof(size_t));
    int32_t *slot2 = f->slot2 = scratch(&f->ws->slot2, &f->ws->n_slot2, f->ncell + 1, sizeof(int32_t));
    if (!touched || !slot2) return sc_fail(err, SC_ENOMEM, "out of memory");
    int64_t ntouched = 0;
    for (int64_t v = 0; v < f->nvar; v++) {
        const int64_t i = f->free_texel[v] % W, j = f->free_texel[v] / W;
        for (int q = 0; q < 4; q++) {
            size_t key;
            if (cell_key(&f->cg, i - 1 + (q & 1), j - 1 + (q >> 1), &key)) touched[ntouched++] = key;
        }
    }
    qsort(touched, (size_t)ntouched, sizeof *touched, cmp_size);
    int64_t u = 0;
    for (int64_t a = 0; a < ntouched; a++)
        if (u == 0 || touched[a] != touched[u - 1]) touched[u++] = touched[a];
    f->ntouched = u;
    for (size_t k = 0; k < f->ncell; k++) slot2[k] = -1;
    int64_t nsampled = 0;
    for (int64_t a = 0; a < f->ntouched; a++)
        if (f->slot[touched[a]] >= 0) slot2[touched[a]] = (int32_t)nsampled++;
    f->cells = scratch(&f->ws->cells, &f->ws->n_cells, (size_t)nsampled + 1, sizeof *f->cells);
    if (f->cells) memset(f->cells, 0, ((size_t)nsampled + 1) * sizeof *f->cells);
    if (!f->cells) return sc_fail(err, SC_ENOMEM, "out of memory for %lld cells", (long long)nsampled);
    return SC_OK;
}

/* The second sampling pass: each cell next to a free texel sums its
 * samples' Gram matrix and residual in the first pass's order. */
static int sum_cell_samples(fit_work *f, sc_error *err) {
    double t1 = sc_now();
    int rc = SC_OK;
    int prc = sample_pass(f, f->slot2, f->cells, NULL);
    if (prc != SC_OK) rc = sc_fail(err, prc, "sampling the surface failed");
    f->st->seconds_sample += sc_now() - t1;
    f->t0 += sc_now() - t1;
    return rc;
}

/* The active cells: each touched cell's free corners, with its Gram matrix
 * and residual over its samples (an exact cell: the bilinear mass matrix);
 * an inexact cell without samples stays out. */
static void active_cells(fit_work *f) {
    for (int64_t a = 0; a < f->ntouched; a++) {
        const size_t k = f->touched[a];
        int32_t id[4];
        cell_corners(&f->cg, k, id);
        active *A = &f->act[f->nact];
        if (f->slot[k] >= 0) {
            fit_cell *C = &f->cells[f->slot2[k]];
            if (!(C->n > 0)) continue;
            for (int i = 0; i < 10; i++) C->G[i] /= C->n;
            for (int i = 0; i < 4; i++)
                for (int c = 0; c < 3; c++) C->b[i][c] /= C->n;
            A->G = C->G, A->b = (const double(*)[3])C->b;
        } else {
            A->G = mass, A->b = NULL;
        }
        for (int q = 0; q < 4; q++) A->var[q] = f->var[id[q]];
        f->nact++;
    }
}

/* Each unknown's (cell, corner) entries, cells in ascending order. */
static int unknown_entries(fit_work *f, sc_error *err) {
    const int64_t nvar = f->nvar, nact = f->nact;
    const active *act = f->act;
    int64_t *inc_start = f->inc_start = sc_calloc_array((size_t)nvar + 1, sizeof(int64_t));
    int64_t *inc = f->inc = sc_alloc_array((size_t)nact * 4 + 1, sizeof(int64_t));
    if (!inc_start || !inc) return sc_fail(err, SC_ENOMEM, "out of memory for %lld unknowns", (long long)nvar);
    for (int64_t a = 0; a < nact; a++)
        for (int q = 0; q < 4; q++)
            if (act[a].var[q] >= 0) inc_start[act[a].var[q] + 1]++;
    for (int64_t v = 0; v < nvar; v++) inc_start[v + 1] += inc_start[v];
    for (int64_t a = 0; a < nact; a++)
        for (int q = 0; q < 4; q++)
            if (act[a].var[q] >= 0) inc[inc_start[act[a].var[q]]++] = 4 * a + q;
    for (int64_t v = nvar; v > 0; v--) inc_start[v] = inc_start[v - 1];
    inc_start[0] = 0;
    return SC_OK;
}

/* Each unknown's terms, in the order of its entries and their corners. */
static int unknown_terms(fit_work *f, sc_error *err) {
    const int64_t nvar = f->nvar;
    int64_t *row = f->row = sc_alloc_array((size_t)nvar + 1, sizeof *f->row);
    double *coef = f->coef = sc_alloc_array((size_t)f->nact * 16 + 1, sizeof *f->coef);
    int32_t *col = f->col = sc_alloc_array((size_t)f->nact * 16 + 1, sizeof *f->col);
    if (!row || !coef || !col) return sc_fail(err, SC_ENOMEM, "out of memory for %lld unknowns", (long long)nvar);
    int64_t nterm = 0;
    for (int64_t v = 0; v < nvar; v++) {
        row[v] = nterm;
        for (int64_t e = f->inc_start[v]; e < f->inc_start[v + 1]; e++) {
            const active *A = &f->act[f->inc[e] >> 2];
            const int q = (int)(f->inc[e] & 3);
            for (int s = 0; s < 4; s++)
                if (A->var[s] >= 0) coef[nterm] = A->G[gram_index[q][s]], col[nterm++] = A->var[s];
        }
    }
    row[nvar] = nterm;
    return SC_OK;
}

/* CG on (sum P^T G P + eps I) d = sum P^T b, three channels at once, with
 * the Jacobi preconditioner: d into the first 3 nvar of vec. */
static int conjugate_gradients(fit_work *f, sc_error *err) {
    const int64_t nvar = f->nvar;
    const double eps = 1e-4;
    double *vec = f->vec;
    double *d = vec, *r = vec + 3 * nvar, *z = vec + 6 * nvar, *pp = vec + 9 * nvar, *Ap = vec + 12 * nvar,
           *diag = vec + 15 * nvar;
    for (int64_t i = 0; i < nvar; i++) diag[3 * i] = eps;
    for (int64_t a = 0; a < f->nact; a++) {
        const active *A = &f->act[a];
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
        apply_job aj = {f->row, f->coef, f->col, pp, Ap, nvar, 4096};
        int arc = sc_seam_parallel(f->threads, (int32_t)((nvar + aj.chunk - 1) / aj.chunk), apply_band, &aj);
        if (arc != SC_OK) return sc_fail(err, arc, "the conjugate gradients failed");
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
        f->st->iterations++;
        if (!(rr > 1e-12 * rr0)) break;
        for (int c = 0; c < 3; c++) {
            double beta = rz[c] > 0 ? rz2[c] / rz[c] : 0;
            rz[c] = rz2[c];
            for (int64_t i = 0; i < nvar; i++) pp[3 * i + c] = z[3 * i + c] + beta * pp[3 * i + c];
        }
    }
    return SC_OK;
}

/* 5. The free texels' least-squares values: each unknown's terms, d by
 * conjugate gradients, then x += d. */
static int solve_free_texels(fit_work *f, sc_error *err) {
    int rc = unknown_terms(f, err);
    if (rc == SC_OK) rc = conjugate_gradients(f, err);
    const double *d = f->vec;
    for (size_t t = 0; t < (size_t)f->g->width * f->g->height && rc == SC_OK; t++)
        if (f->var[t] >= 0)
            for (int c = 0; c < 3; c++) f->x[3 * t + c] = (float)(f->x[3 * t + c] + d[3 * (size_t)f->var[t] + c]);
    f->st->texels_solved += f->nvar;
    return rc;
}

/* Refine the map x (x0 in) where it is not exact: the texels of the cells
 * whose samples of f it misses by more than tol, solved in least squares. */
static int fit_map(const sc_mesh *in, int32_t material, const sc_seam_grid *g, const raster *rin,
                   const raster *rlev, const locator *lev, float *x, double tol, int threads, fit_scratch *ws,
                   fit_stats *st, sc_error *err) {
    const int32_t W = g->width, H = g->height;
    fit_work f = {.in = in, .material = material, .g = g, .rin = rin, .rlev = rlev, .lev = lev, .x = x, .tol = tol,
                  .threads = threads, .ws = ws, .st = st};
    f.cg = (cellgrid){W, H, W + (g->wrap_u == SC_WRAP_REPEAT ? 0 : 1), H + (g->wrap_v == SC_WRAP_REPEAT ? 0 : 1),
                      g->wrap_u, g->wrap_v};
    f.ncell = (size_t)f.cg.CW * f.cg.CH;
    int rc = mark_inexact_cells(&f, err);
    if (rc == SC_OK) rc = prepare_sampling(&f, err);
    if (rc != SC_OK) {
        fit_work_free(&f);
        return rc;
    }
    rc = measure_misses(&f, err);
    f.t0 = sc_now();
    if (rc == SC_OK) rc = find_free_texels(&f, err);
    if (rc == SC_OK && f.nvar > 0) {   /* 4. the cells the free texels sit in: their Gram and residual */
        rc = alloc_solve(&f, err);
        if (rc == SC_OK) rc = cells_with_free_corner(&f, err);
        if (rc == SC_OK) rc = sum_cell_samples(&f, err);
        if (rc == SC_OK) active_cells(&f);
        if (rc == SC_OK) rc = unknown_entries(&f, err);
        if (rc == SC_OK) rc = solve_free_texels(&f, err);
    }
    st->seconds_solve += sc_now() - f.t0;
    fit_work_free(&f);
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
                    const raster *rlev, const locator *lev, double tol, int threads, fit_scratch *ws, fit_stats *st,
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
        rc = fit_map(in, material, g, rin, rlev, lev, d, tol, threads, ws, st, err);
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
    int rc = sc_atlas_copy_materials(a, src);
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


/* Erase images[0..nmat) (one per material) on `mesh`; replaces them. */
static int erase_maps(sc_value *mesh, sc_value **images, const sc_seam_grid *grids, int32_t nmat,
                      double gap_tolerance, int threads, sc_error *err) {
    sc_atlas_ops_map *maps = calloc((size_t)nmat + 1, sizeof *maps);
    sc_value **out = calloc((size_t)nmat + 1, sizeof *out);
    int rc = maps && out ? SC_OK : sc_fail(err, SC_ENOMEM, "out of memory");
    for (int32_t k = 0; k < nmat && rc == SC_OK; k++)
        maps[k] = (sc_atlas_ops_map){k, grids[k].wrap_u, grids[k].wrap_v, images[k], NULL};
    /* erase_seams's terms for positions, less E_C1: the two sides of a seam map
     * uv to the surface with their own Jacobians, so a geometry image has no
     * reason to be C1 across it */
    sc_erase_options o;
    sc_erase_defaults(&o);
    o.w_c1 = 0;
    o.gap_tolerance = gap_tolerance;
    o.quantize = SC_ERASE_QUANTIZE_NONE;
    if (rc == SC_OK) rc = sc_atlas_ops_erase(mesh->as.mesh, maps, nmat, &o, threads, out, NULL, err);
    for (int32_t k = 0; k < nmat && rc == SC_OK; k++) {
        sc_value_release(images[k]);
        images[k] = out[k];
    }
    free(maps), free(out);
    return rc;
}

/* ---------------------------------------------------------------- metrics */

static const double sample_bary[7][3] = {
    {1.0 / 3, 1.0 / 3, 1.0 / 3}, {0.6, 0.2, 0.2}, {0.2, 0.6, 0.2}, {0.2, 0.2, 0.6},
    {0.45, 0.45, 0.1}, {0.1, 0.45, 0.45}, {0.45, 0.1, 0.45}};

typedef struct recon {
    double *same;   /* same-uv errors over the diagonal */
    int64_t nsame, cap_same;
    double to_input, from_input;   /* the one-sided surface distances' maxima */
    int64_t missed, surf_missed;
} recon;

static int recon_grow(double **a, int64_t *cap, int64_t need) {
    if (need <= *cap) return SC_OK;
    double *e = realloc(*a, sizeof(double) * (size_t)(need + 1));
    if (!e) return SC_ENOMEM;
    *a = e, *cap = need + 1;
    return SC_OK;
}

/* Same-uv error: what the renderer draws, base_level(uv) + bilinear(map)(uv)
 * (only the map when level is NULL), against the input point of the same uv
 * at 7 points of every input face of the material, over the bounding-box
 * diagonal. Faces are measured in parallel chunks into slots of their own
 * (-1: the level has no face there); the errors are then sorted, so the
 * metrics do not depend on the thread count. */
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

static int same_uv(const sc_mesh *in, int32_t material, const locator *lev, const sc_seam_grid *g,
                   const sc_image_data *map, double diag, int threads, recon *acc, sc_error *err) {
    int64_t nf = 0;
    for (int32_t f = 0; f < in->nf; f++) nf += in->FM[f] == material;
    if (recon_grow(&acc->same, &acc->cap_same, acc->nsame + 7 * nf) != SC_OK)
        return sc_fail(err, SC_ENOMEM, "out of memory");
    int32_t *faces = sc_alloc_array((size_t)nf + 1, sizeof(int32_t));
    if (!faces) return sc_fail(err, SC_ENOMEM, "out of memory");
    nf = 0;
    for (int32_t f = 0; f < in->nf; f++)
        if (in->FM[f] == material) faces[nf++] = f;
    /* the slots are the tail of acc->same, compacted in place below */
    recon_job job = {in, faces, nf, lev, g, map, diag, acc->same + acc->nsame};
    int rc = sc_seam_parallel(threads, (int32_t)((nf + RECON_CHUNK - 1) / RECON_CHUNK), recon_band, &job);
    free(faces);
    if (rc != SC_OK) return sc_fail(err, rc, "measuring the reconstruction failed");
    const double *slots = acc->same + acc->nsame;
    int64_t kept = acc->nsame;
    for (int64_t i = 0; i < 7 * nf; i++) {
        if (slots[i] < 0) acc->missed++;
        else acc->same[kept++] = slots[i];
    }
    acc->nsame = kept;
    return SC_OK;
}

/* Grid samples of a mesh's faces of one material, by area, as sc_hausdorff
 * samples a mesh (see surface_distance). */
typedef struct grid_samples {
    int32_t *face, *res;   /* per sampled face: its index and grid resolution r */
    uint8_t *owns;         /* per sampled face: bit c when it is the first face of corner c's vertex (which
                            * measures it; the others skip it) */
    int64_t *start;        /* first sample of each; start[nfaces] = the total */
    int64_t nfaces;
} grid_samples;

static void grid_samples_free(grid_samples *gs) {
    free(gs->face), free(gs->res), free(gs->start), free(gs->owns);
    memset(gs, 0, sizeof *gs);
}

static double face_area(const sc_mesh *m, int32_t f) {
    const double *a = m->V + 3 * m->FV[3 * f], *b = m->V + 3 * m->FV[3 * f + 1], *c = m->V + 3 * m->FV[3 * f + 2];
    double n[3];
    sc_triangle_normal(a, b, c, n);
    double area = 0.5 * sc_norm3(n);
    return isfinite(area) ? area : 0;
}

static int grid_samples_build(const sc_mesh *m, int32_t material, int64_t target, grid_samples *gs) {
    int64_t n = 0;
    double total = 0;
    for (int32_t f = 0; f < m->nf; f++)
        if (m->FM[f] == material) n++, total += face_area(m, f);
    gs->face = sc_alloc_array((size_t)n + 1, sizeof(int32_t));
    gs->res = sc_alloc_array((size_t)n + 1, sizeof(int32_t));
    gs->start = sc_alloc_array((size_t)n + 1, sizeof(int64_t));
    gs->owns = sc_alloc_array((size_t)n + 1, 1);
    int32_t *first = sc_alloc_array((size_t)m->nv + 1, sizeof(int32_t));   /* each vertex's first face */
    if (!gs->face || !gs->res || !gs->start || !gs->owns || !first) {
        grid_samples_free(gs);
        free(first);
        return SC_ENOMEM;
    }
    for (int32_t v = 0; v < m->nv; v++) first[v] = -1;
    for (int32_t f = 0; f < m->nf; f++)
        for (int c = 0; c < 3 && m->FM[f] == material; c++)
            if (first[m->FV[3 * f + c]] < 0) first[m->FV[3 * f + c]] = f;
    const double per = total > 0 && target > 0 ? total / (double)target : 0;
    int64_t q = 0, at = 0;
    for (int32_t f = 0; f < m->nf; f++) {
        if (m->FM[f] != material) continue;
        double r = per > 0 ? ceil(sqrt(face_area(m, f) / per)) : 1;
        gs->face[q] = f, gs->res[q] = r < 1 ? 1 : r > 64 ? 64 : (int32_t)r, gs->owns[q] = 0;
        for (int c = 0; c < 3; c++) gs->owns[q] |= (uint8_t)((first[m->FV[3 * f + c]] == f) << c);
        gs->start[q] = at, at += (int64_t)(gs->res[q] + 1) * (gs->res[q] + 2) / 2;
        q++;
    }
    gs->start[q] = at, gs->nfaces = q;
    free(first);
    return SC_OK;
}

typedef struct surface_job {
    const sc_mesh *in;
    const sc_hausdorff_bvh *in_bvh;   /* over the whole input */
    const locator *lev;               /* its mesh is the level's */
    const sc_seam_grid *g;
    const sc_image_data *map;
    double diag;
    const grid_samples *gs;
    /* the coarse drawn surface: its points, their uv and level face, its
     * triangles and their BVH (NULL while the drawn side is measured) */
    double *drawn, *drawn_uv;
    int32_t *drawn_face;
    const sc_hausdorff_bvh *drawn_bvh;
    const int32_t *drawn_tri;
    double *input, *input_uv;   /* the input side's samples: points, uv */
    double *out;   /* per sample, over the diagonal; -1: the level has no face near it */
} surface_job;

#define SURFACE_CHUNK 256
#define COARSE_DRAWN 4    /* the coarse drawn surface has this many times fewer samples */
#define INSIDE_EPS 1e-9   /* a barycentric coordinate this far below 0 still counts as inside */

/* Face f of the level at uv: the position (linear in the face, extended
 * beyond it), its derivatives along u and v, and the smallest barycentric
 * coordinate (>= 0 inside). False for a face flat in uv. */
static bool face_frame(const sc_mesh *m, int32_t f, double u, double v, double p[3], double pu[3], double pv[3],
                       double *min_l) {
    double fx[3], fy[3], l[3];
    const double *P[3];
    for (int c = 0; c < 3; c++) {
        const double *uv = m->U + 2 * m->FU[3 * f + c];
        fx[c] = uv[0], fy[c] = uv[1], P[c] = m->V + 3 * m->FV[3 * f + c];
    }
    if (!barycentric(fx, fy, u, v, l)) return false;
    double det = (fx[1] - fx[0]) * (fy[2] - fy[0]) - (fx[2] - fx[0]) * (fy[1] - fy[0]);
    double l1u = (fy[2] - fy[0]) / det, l1v = -(fx[2] - fx[0]) / det;   /* d l1 / du, d l1 / dv */
    double l2u = -(fy[1] - fy[0]) / det, l2v = (fx[1] - fx[0]) / det;
    for (int k = 0; k < 3; k++) {
        p[k] = l[0] * P[0][k] + l[1] * P[1][k] + l[2] * P[2][k];
        pu[k] = l1u * (P[1][k] - P[0][k]) + l2u * (P[2][k] - P[0][k]);
        pv[k] = l1v * (P[1][k] - P[0][k]) + l2v * (P[2][k] - P[0][k]);
    }
    *min_l = fmin(l[0], fmin(l[1], l[2]));
    return true;
}

/* The drawn surface at uv when uv lies in a face of the level (*face tried
 * first, then the faces of uv's locator bucket; *face updated), with its
 * derivatives along u, v. */
static bool drawn_at(const surface_job *J, double u, double v, int32_t *face, double r[3], double ru[3],
                     double rv[3]) {
    const sc_mesh *m = J->lev->m;
    double min_l = -1;
    if (!(*face >= 0 && face_frame(m, *face, u, v, r, ru, rv, &min_l) && min_l >= -INSIDE_EPS)) {
        /* a face holding uv has its box in uv's bucket: the one that holds it best */
        const locator *L = J->lev;
        const size_t b = (size_t)bucket_of(v, L->gw) * L->gw + (size_t)bucket_of(u, L->gw);
        int32_t best = -1;
        double best_l = -INSIDE_EPS;
        for (int32_t q = L->start[b]; q < L->start[b + 1]; q++)
            if (face_frame(m, L->faces[q], u, v, r, ru, rv, &min_l) && min_l >= best_l) best = L->faces[q], best_l = min_l;
        if (best < 0 || !face_frame(m, best, u, v, r, ru, rv, &min_l)) return false;
        *face = best;
    }
    int32_t id[4];
    double w[4];
    sc_seam_taps(J->g, u, v, id, w);
    const double s = w[1] + w[3], t = w[2] + w[3], W = J->g->width, H = J->g->height;
    const float *px = J->map->pixels;
    const int32_t C = J->map->channels;
    for (int k = 0; k < 3; k++) {
        double d[4];
        for (int q = 0; q < 4; q++) d[q] = px[(size_t)id[q] * C + k];
        r[k] += w[0] * d[0] + w[1] * d[1] + w[2] * d[2] + w[3] * d[3];
        ru[k] += W * ((1 - t) * (d[1] - d[0]) + t * (d[3] - d[2]));
        rv[k] += H * ((1 - s) * (d[2] - d[0]) + s * (d[3] - d[1]));
    }
    return true;
}

#define DESCENT_STEPS 32
#define DESCENT_REACH 8.0   /* texels */

/* Gauss-Newton on |drawn(uv) - p|^2 from a drawn point r (derivatives ru,
 * rv, in `face`, at uv): the least distance of the points it visits. */
static double descend(const surface_job *J, const double p[3], double u, double v, int32_t face, double r[3],
                      double ru[3], double rv[3]) {
    double d2 = sc_dist3_squared(r, p);
    const double W = J->g->width, H = J->g->height;
    for (int it = 0; it < DESCENT_STEPS && d2 > 0; it++) {
        double e[3] = {p[0] - r[0], p[1] - r[1], p[2] - r[2]};
        double a = 0, b = 0, c = 0, gu = 0, gv = 0;
        for (int k = 0; k < 3; k++)
            a += ru[k] * ru[k], b += ru[k] * rv[k], c += rv[k] * rv[k], gu += ru[k] * e[k], gv += rv[k] * e[k];
        double det = a * c - b * b;
        if (!(det > 1e-12 * a * c)) break;
        double du = (c * gu - b * gv) / det, dv = (a * gv - b * gu) / det;
        double step = fmax(fabs(du) * W, fabs(dv) * H);   /* texels */
        if (!(step >= 1e-4)) break;                         /* converged (or not a number) */
        if (step > DESCENT_REACH) du *= DESCENT_REACH / step, dv *= DESCENT_REACH / step, step = DESCENT_REACH;
        bool moved = false;
        for (int h = 0; h < 6 && !moved; h++, du *= 0.5, dv *= 0.5, step *= 0.5) {
            int32_t f2 = face;
            double r2[3], ru2[3], rv2[3];
            if (!drawn_at(J, u + du, v + dv, &f2, r2, ru2, rv2)) continue;
            double n2 = sc_dist3_squared(r2, p);
            if (!(n2 < d2)) continue;
            u += du, v += dv, face = f2, d2 = n2, moved = true;
            memcpy(r, r2, sizeof r2), memcpy(ru, ru2, sizeof ru2), memcpy(rv, rv2, sizeof rv2);
        }
        if (!moved || step < 1e-4) break;
    }
    return sqrt(d2);
}

/* The uv of the point of face f (uv triangle) nearest to (u, v). */
static void nearest_in_face(const sc_mesh *m, int32_t f, double *u, double *v) {
    double a[3][3], x[3] = {*u, *v, 0}, c[3];
    for (int k = 0; k < 3; k++) {
        const double *uv = m->U + 2 * m->FU[3 * f + k];
        a[k][0] = uv[0], a[k][1] = uv[1], a[k][2] = 0;
    }
    sc_hausdorff_closest_on_triangle(x, a[0], a[1], a[2], c);
    *u = c[0], *v = c[1];
}

/* The distance from p to the drawn surface by a descent from p's own uv (or
 * from the nearest point of the face locate() gives, outside the level), or
 * -1 when the level has no face near uv. */
static double from_input_local(const surface_job *J, const double p[3], double u, double v) {
    int32_t face = -1;
    double r[3], ru[3], rv[3];
    if (!drawn_at(J, u, v, &face, r, ru, rv)) {
        double q[3];
        face = locate(J->lev, u, v, q);
        if (face < 0) return -1;
        nearest_in_face(J->lev->m, face, &u, &v);
        if (!drawn_at(J, u, v, &face, r, ru, rv)) return -1;
    }
    return descend(J, p, u, v, face, r, ru, rv);
}

/* The same from the uv of the point nearest to p on the coarse drawn surface
 * (triangles of sample grids on the level's faces, their vertices drawn
 * points), found through its BVH; HUGE_VAL when that start is not inside
 * the level. */
static double from_input_global(const surface_job *J, const double p[3]) {
    double c[3], r[3], ru[3], rv[3];
    int32_t t = -1;
    sc_hausdorff_bvh_closest(J->drawn_bvh, p, c, &t);
    if (t < 0) return HUGE_VAL;
    const int32_t *k = J->drawn_tri + 3 * t;   /* c's barycentric coordinates in triangle t, then its uv */
    const double *P0 = J->drawn + 3 * k[0], *P1 = J->drawn + 3 * k[1], *P2 = J->drawn + 3 * k[2];
    double e1[3], e2[3], w[3], a = 0, b = 0, cc = 0, d1 = 0, d2 = 0;
    for (int i = 0; i < 3; i++) e1[i] = P1[i] - P0[i], e2[i] = P2[i] - P0[i], w[i] = c[i] - P0[i];
    for (int i = 0; i < 3; i++) a += e1[i] * e1[i], b += e1[i] * e2[i], cc += e2[i] * e2[i], d1 += e1[i] * w[i], d2 += e2[i] * w[i];
    double det = a * cc - b * b, l1 = det > 0 ? (cc * d1 - b * d2) / det : 0, l2 = det > 0 ? (a * d2 - b * d1) / det : 0;
    const double *t0 = J->drawn_uv + 2 * k[0], *t1 = J->drawn_uv + 2 * k[1], *t2 = J->drawn_uv + 2 * k[2];
    double u = (1 - l1 - l2) * t0[0] + l1 * t1[0] + l2 * t2[0], v = (1 - l1 - l2) * t0[1] + l1 * t1[1] + l2 * t2[1];
    int32_t face = J->drawn_face[k[0]];
    if (!drawn_at(J, u, v, &face, r, ru, rv)) return HUGE_VAL;
    return descend(J, p, u, v, face, r, ru, rv);
}

/* Refine candidates [c0, c1) of the input side (indices into its samples):
 * the global descent, keeping the lesser distance. */
typedef struct refine_job {
    const surface_job *S;
    const int64_t *order;
    const double *point, *uv;   /* per input sample */
    double *out;
    int64_t c0, c1;
} refine_job;

#define REFINE_BATCH 64

static int refine_band(void *ud, int32_t chunk) {
    const refine_job *R = ud;
    const int64_t c0 = R->c0 + (int64_t)chunk * REFINE_BATCH, c1 = c0 + REFINE_BATCH < R->c1 ? c0 + REFINE_BATCH : R->c1;
    for (int64_t c = c0; c < c1; c++) {
        const int64_t i = R->order[c];
        double d = from_input_global(R->S, R->point + 3 * i) / R->S->diag;
        if (d < R->out[i]) R->out[i] = d;
    }
    return SC_OK;
}

/* One chunk of faces of one side (J->drawn: the drawn side, else the input's). */
static int surface_band(void *ud, int32_t chunk) {
    const surface_job *J = ud;
    const grid_samples *gs = J->gs;
    const bool drawn_side = J->drawn_bvh == NULL;
    const sc_mesh *m = drawn_side ? J->lev->m : J->in;
    const int64_t q0 = (int64_t)chunk * SURFACE_CHUNK, q1 = q0 + SURFACE_CHUNK < gs->nfaces ? q0 + SURFACE_CHUNK : gs->nfaces;
    for (int64_t q = q0; q < q1; q++) {
        const int32_t f = gs->face[q], r = gs->res[q];
        int64_t slot = gs->start[q];
        for (int32_t i = 0; i <= r; i++)
            for (int32_t j = 0; j <= r - i; j++, slot++) {
                const int corner = i == r ? 0 : j == r ? 1 : i == 0 && j == 0 ? 2 : -1;
                if (J->out && corner >= 0 && !(gs->owns[q] >> corner & 1)) {   /* measured by its first face */
                    J->out[slot] = NAN;
                    continue;
                }
                const double l[3] = {(double)i / r, (double)j / r, (double)(r - i - j) / r};
                double p[3] = {0, 0, 0}, uv[2] = {0, 0};
                for (int c = 0; c < 3; c++) {
                    const double *pv = m->V + 3 * m->FV[3 * f + c], *tv = m->U + 2 * m->FU[3 * f + c];
                    for (int k = 0; k < 3; k++) p[k] += l[c] * pv[k];
                    uv[0] += l[c] * tv[0], uv[1] += l[c] * tv[1];
                }
                if (drawn_side) {   /* the drawn point: its distance (out), or it is kept (drawn) */
                    double d[4];
                    sc_seam_sample(J->g, J->map->pixels, J->map->channels, uv[0], uv[1], d);
                    for (int k = 0; k < 3; k++) p[k] += d[k];
                    if (J->drawn) {
                        memcpy(J->drawn + 3 * slot, p, sizeof p), memcpy(J->drawn_uv + 2 * slot, uv, sizeof uv);
                        J->drawn_face[slot] = f;
                    }
                    if (J->out) J->out[slot] = sqrt(sc_hausdorff_bvh_closest(J->in_bvh, p, NULL, NULL)) / J->diag;
                } else {
                    double d = from_input_local(J, p, uv[0], uv[1]);
                    J->out[slot] = d < 0 ? -1 : d / J->diag;
                    memcpy(J->input + 3 * slot, p, sizeof p), memcpy(J->input_uv + 2 * slot, uv, sizeof uv);
                }
            }
    }
    return SC_OK;
}

/* Surface distance: the drawn surface (uv over the level's faces, base +
 * bilinear(map)) against the input surface as surfaces, both ways, over the
 * diagonal: the largest distance of a sample of either to the other. Each
 * surface is sampled as sc_hausdorff samples a mesh: face f of the material
 * gets the barycentric grid (i/r, j/r), i + j <= r, with
 * r = ceil(sqrt(area_f / area per sample)) (1..64), so vertices and edges
 * (chart borders, where erasure moves texels) are sampled too; a vertex is
 * measured once, by the first face using it.
 *  - To the input: a sample of a level face, moved by bilinear(map) at its
 *    uv, and its exact distance to the whole input mesh (closest point on a
 *    triangle, sc_hausdorff's BVH).
 *  - From the input: a sample p of an input face and its distance to the
 *    drawn surface, by Gauss-Newton on |drawn(uv) - p|^2 (steps of at most
 *    DESCENT_REACH texels, halved until the distance falls; only points
 *    inside faces of the level). Every candidate is a drawn point, so each
 *    distance is an upper bound of the true one. The descent starts at p's
 *    own uv; where the drawn surface lies far from there in uv (a large
 *    displacement, a seam), a second descent starts from the nearest point
 *    of a coarse drawn surface: the triangles of grids like the drawn side's,
 *    with COARSE_DRAWN times fewer points (from_input_global). That
 *    second descent is run on the samples in decreasing order of the first
 *    one's distance, in fixed batches, until no remaining sample's first
 *    distance exceeds the largest refined one: the maximum is the one that
 *    refining every sample would give, at a fraction of the cost.
 * Samples are measured in parallel chunks into slots of their own, and the
 * batches are fixed: the same bytes for any thread count. */
typedef struct ranked {
    double d;
    int64_t i;
} ranked;

static int cmp_ranked_desc(const void *a, const void *b) {
    const ranked *x = a, *y = b;
    return x->d > y->d ? -1 : x->d < y->d ? 1 : (x->i > y->i) - (x->i < y->i);
}

static int surface_distance(const sc_mesh *in, const sc_hausdorff_bvh *in_bvh, int32_t material, const locator *lev,
                            const sc_seam_grid *g, const sc_image_data *map, double diag, int64_t samples,
                            int threads, recon *acc, sc_error *err) {
    grid_samples gd = {0}, gi = {0}, gc = {0};   /* drawn side, input side, the coarse drawn surface */
    surface_job job = {in, in_bvh, lev, g, map, diag, &gd, NULL, NULL, NULL, NULL, NULL, NULL, NULL, NULL};
    int32_t *tri = NULL;
    int64_t *order = NULL;
    double *out = NULL;
    sc_hausdorff_bvh *drawn_bvh = NULL;
    int rc = SC_OK;
    if (grid_samples_build(lev->m, material, samples, &gd) != SC_OK ||
        grid_samples_build(in, material, samples, &gi) != SC_OK ||
        grid_samples_build(lev->m, material, samples / COARSE_DRAWN, &gc) != SC_OK || gc.start[gc.nfaces] >= INT32_MAX)
        rc = SC_ENOMEM;
    const int64_t nd = rc == SC_OK ? gd.start[gd.nfaces] : 0, ni = rc == SC_OK ? gi.start[gi.nfaces] : 0;
    const int64_t nc_pts = rc == SC_OK ? gc.start[gc.nfaces] : 0;
    int64_t ntri = 0;
    for (int64_t q = 0; q < gc.nfaces; q++) ntri += (int64_t)gc.res[q] * gc.res[q];
    if (rc == SC_OK) {
        job.drawn = sc_alloc_array((size_t)nc_pts * 3 + 1, sizeof(double));
        job.drawn_uv = sc_alloc_array((size_t)nc_pts * 2 + 1, sizeof(double));
        job.drawn_face = sc_alloc_array((size_t)nc_pts + 1, sizeof(int32_t));
        job.input = sc_alloc_array((size_t)ni * 3 + 1, sizeof(double));
        job.input_uv = sc_alloc_array((size_t)ni * 2 + 1, sizeof(double));
        out = sc_alloc_array((size_t)(nd > ni ? nd : ni) + 1, sizeof(double));
        order = sc_alloc_array((size_t)ni + 1, sizeof(int64_t));
        tri = ntri < INT32_MAX ? sc_alloc_array((size_t)ntri * 3 + 1, sizeof(int32_t)) : NULL;
        if (!job.drawn || !job.drawn_uv || !job.drawn_face || !job.input || !job.input_uv || !out || !order || !tri)
            rc = SC_ENOMEM;
    }
    if (rc != SC_OK) rc = sc_fail(err, SC_ENOMEM, "out of memory for the surface samples");
    /* the drawn side's distances */
    double *drawn = job.drawn;
    job.drawn = NULL, job.out = out;
    if (rc == SC_OK)
        rc = sc_seam_parallel(threads, (int32_t)((gd.nfaces + SURFACE_CHUNK - 1) / SURFACE_CHUNK), surface_band, &job);
    for (int64_t i = 0; i < nd && rc == SC_OK; i++) {
        if (isnan(out[i])) continue;   /* a vertex measured by another face */
        if (out[i] < 0) acc->surf_missed++;
        else acc->to_input = fmax(acc->to_input, out[i]);
    }
    /* the coarse drawn surface: the points of coarser grids and their triangles */
    job.gs = &gc, job.drawn = drawn, job.out = NULL;
    if (rc == SC_OK)
        rc = sc_seam_parallel(threads, (int32_t)((gc.nfaces + SURFACE_CHUNK - 1) / SURFACE_CHUNK), surface_band, &job);
    if (rc == SC_OK) {
        int64_t t = 0;
        for (int64_t q = 0; q < gc.nfaces; q++) {
            const int32_t r = gc.res[q];
            const int64_t s0 = gc.start[q];
#define GRID_AT(i, j) ((int32_t)(s0 + (int64_t)(i) * (r + 1) - (int64_t)(i) * ((i) - 1) / 2 + (j)))
            for (int32_t i = 0; i < r; i++)
                for (int32_t j = 0; j < r - i; j++) {
                    tri[3 * t] = GRID_AT(i, j), tri[3 * t + 1] = GRID_AT(i + 1, j), tri[3 * t + 2] = GRID_AT(i, j + 1), t++;
                    if (j + 1 < r - i)
                        tri[3 * t] = GRID_AT(i + 1, j), tri[3 * t + 1] = GRID_AT(i + 1, j + 1),
                        tri[3 * t + 2] = GRID_AT(i, j + 1), t++;
                }
#undef GRID_AT
        }
    }
    const sc_hausdorff_mesh drawn_mesh = {job.drawn, (int32_t)nc_pts, tri, (int32_t)ntri};
    if (rc == SC_OK && !(drawn_bvh = sc_hausdorff_bvh_build(&drawn_mesh)))
        rc = sc_fail(err, SC_ENOMEM, "out of memory for the drawn surface's BVH");
    /* the input side: the local descents, then the global ones while they can
     * raise the maximum */
    if (rc == SC_OK) {
        job.gs = &gi, job.drawn_bvh = drawn_bvh, job.drawn_tri = tri, job.out = out;
        rc = sc_seam_parallel(threads, (int32_t)((gi.nfaces + SURFACE_CHUNK - 1) / SURFACE_CHUNK), surface_band, &job);
    }
    int64_t nc = 0;
    ranked *rank = rc == SC_OK ? sc_alloc_array((size_t)ni + 1, sizeof *rank) : NULL;
    if (rc == SC_OK && !rank) rc = sc_fail(err, SC_ENOMEM, "out of memory");
    for (int64_t i = 0; i < ni && rc == SC_OK; i++) {
        if (isnan(out[i])) continue;
        if (out[i] < 0) acc->surf_missed++;
        else rank[nc++] = (ranked){out[i], i};
    }
    if (rc == SC_OK) qsort(rank, (size_t)nc, sizeof *rank, cmp_ranked_desc);
    for (int64_t c = 0; c < nc; c++) order[c] = rank[c].i;
    free(rank);
    double max = 0;
    for (int64_t c = 0; c < nc && rc == SC_OK && out[order[c]] > max;) {
        const int64_t c1 = c + 8 * REFINE_BATCH < nc ? c + 8 * REFINE_BATCH : nc;
        refine_job R = {&job, order, job.input, job.input_uv, out, c, c1};
        rc = sc_seam_parallel(threads, (int32_t)((c1 - c + REFINE_BATCH - 1) / REFINE_BATCH), refine_band, &R);
        for (; c < c1; c++) max = fmax(max, out[order[c]]);
    }
    if (rc == SC_OK) acc->from_input = fmax(acc->from_input, max);
    if (rc != SC_OK && rc != SC_ENOMEM) rc = sc_fail(err, rc, "measuring the surface distance failed");
    sc_hausdorff_bvh_free(drawn_bvh);
    free(job.drawn), free(job.drawn_uv), free(job.drawn_face), free(job.input), free(job.input_uv), free(tri);
    free(out), free(order);
    grid_samples_free(&gd), grid_samples_free(&gi), grid_samples_free(&gc);
    return rc;
}

static int cmp_double(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

/* name (the max), name_rms, name_p99 of e[0..n); e gets sorted. */
static double report_errors(sc_ctx *ctx, const char *name, double *e, int64_t n) {
    char m[96];
    double sum2 = 0, max = 0, p99 = 0;
    if (n > 0) {
        qsort(e, (size_t)n, sizeof(double), cmp_double);
        for (int64_t i = 0; i < n; i++) sum2 += e[i] * e[i];
        max = e[n - 1];
        p99 = e[(int64_t)floor(0.99 * (double)(n - 1))];
    }
    sc_ctx_metric(ctx, name, max);
    snprintf(m, sizeof m, "%s_rms", name);
    sc_ctx_metric(ctx, m, n ? sqrt(sum2 / (double)n) : 0);
    snprintf(m, sizeof m, "%s_p99", name);
    sc_ctx_metric(ctx, m, p99);
    return max;
}

/* ---------------------------------------------------------------- after the fits */

/* What follows a map set's fit - its erasure, then its metrics - runs on a
 * worker thread (with more than one thread) as soon as the set is handed
 * over, so it overlaps the next level's raster and fit (the erase kernel has
 * long serial stretches). Each set's erasure and metrics depend on that set
 * alone, so the results do not depend on the timing; failures are reported
 * in hand-over order. */
typedef struct map_job {
    sc_value *mesh;       /* erase on it; NULL: no erasure */
    sc_value **images;    /* nmat maps, replaced by their erased versions */
    int32_t level;        /* -1: the geometry image */
    const locator *locs;  /* the level's, per material (NULL for the geometry image) */
    recon acc;            /* its metrics */
    int rc;
    sc_error err;
} map_job;

typedef struct after_fit {
    map_job *jobs;
    int32_t njobs;         /* jobs[0..njobs) handed over */
    sc_pipe *pipe;         /* runs them (sc_pipe: on a worker thread when there are two) */
    /* what the jobs read */
    const sc_mesh *in;
    const sc_hausdorff_bvh *in_bvh;
    const sc_seam_grid *grids;
    int32_t nmat;
    double gap_tolerance, diag;
    int64_t surface_samples;
    int threads;
    double seconds_erase, seconds_metrics;
} after_fit;

static void map_job_run(void *ud, int32_t job) {
    after_fit *A = ud;
    map_job *J = &A->jobs[job];
    double t0 = sc_now();
    J->rc = J->mesh ? erase_maps(J->mesh, J->images, A->grids, A->nmat, A->gap_tolerance, A->threads, &J->err) : SC_OK;
    if (J->rc != SC_OK && J->level < 0) sc_error_prefix(&J->err, "erase_seams on the geometry image");
    else if (J->rc != SC_OK) sc_error_prefix(&J->err, "lods: level %d: erase_seams on the displacement", J->level);
    double t1 = sc_now();
    for (int32_t m = 0; m < A->nmat && J->rc == SC_OK; m++) {
        const sc_image_data *map = J->images[m]->as.image;
        const locator *L = J->locs ? &J->locs[m] : NULL;
        J->rc = same_uv(A->in, m, L, &A->grids[m], map, A->diag, A->threads, &J->acc, &J->err);
        if (J->rc == SC_OK && L)
            J->rc = surface_distance(A->in, A->in_bvh, m, L, &A->grids[m], map, A->diag, A->surface_samples,
                                     A->threads, &J->acc, &J->err);
    }
    A->seconds_erase += t1 - t0, A->seconds_metrics += sc_now() - t1;   /* one job at a time */
}

static bool after_fit_start(after_fit *A, int32_t njobs, int threads) {
    A->jobs = calloc((size_t)njobs + 1, sizeof *A->jobs);
    A->pipe = A->jobs ? sc_pipe_start(threads, njobs, map_job_run, A) : NULL;
    if (!A->pipe) {
        free(A->jobs);
        A->jobs = NULL;
        return false;
    }
    A->threads = threads;
    return true;
}

/* Erase (mesh not NULL) and measure images[0..nmat): by the worker, else
 * here and now. */
static void after_fit_hand(after_fit *A, sc_value *mesh, sc_value **images, int32_t level, const locator *locs) {
    A->jobs[A->njobs] = (map_job){.mesh = mesh, .images = images, .level = level, .locs = locs};
    sc_pipe_hand(A->pipe, A->njobs++);
}

/* Wait for every job; the first failure in hand-over order. */
static int after_fit_finish(after_fit *A, sc_error *err) {
    sc_pipe_finish(A->pipe, SC_PIPE_WAIT);   /* the jobs share the threads: one at a time */
    int rc = SC_OK;
    for (int32_t j = 0; j < A->njobs && rc == SC_OK; j++)
        if ((rc = A->jobs[j].rc) != SC_OK && err) *err = A->jobs[j].err;
    return rc;
}

static void after_fit_free(after_fit *A) {
    if (!A->jobs) return;
    for (int32_t j = 0; j < A->njobs; j++) free(A->jobs[j].acc.same);
    sc_pipe_free(A->pipe);
    free(A->jobs);
    A->jobs = NULL;
}

/* ---------------------------------------------------------------- run */

/* What run's steps share: the inputs, the maps being made and the work beside them. */
typedef struct bake_run {
    const sc_atlas *atlas;
    const sc_lods *lods;          /* NULL: the atlas is the only level */
    const sc_mesh *in;
    int32_t size, pad, nmat, nlevels;
    bool erase;
    double diag, tol;             /* the input's bounding-box diagonal; fit_tolerance x diag */
    int threads;
    sc_seam_grid *grids;          /* per material */
    sc_value **geometry;          /* per material */
    sc_value **disp;              /* level k, material m: k * nmat + m */
    raster *rin;                  /* the input's, per material */
    const sc_mesh **meshes;       /* the input, then each level's */
    fit_stats st;                 /* every fit's */
    fit_scratch ws;
    double cov, shared;           /* texels the input's charts cover, and cover twice or more */
    double degenerate;            /* the share of the input's surface on faces whose uv have no area */
    sc_hausdorff_mesh in_surface; /* the input's, which in_bvh refers to */
    sc_hausdorff_bvh *in_bvh;
    after_fit af;
    bool started;                 /* af was started */
    sc_value *union_mesh;         /* the geometry images' erase mesh: the union of every level */
    locator *locs;                /* level k, material m: k * nmat + m */
    int64_t *texels_fitted;       /* per level */
    /* a level whose mesh is an earlier level's (a stalled decimation repeats
     * its last level) gets that level's maps and metrics: job_of[k] is the
     * after_fit job that made them */
    int32_t *job_of, *same_as;
    raster rl;                    /* the level's, one material at a time */
    double worst, worst_same;     /* the levels' largest reconstruction and same-uv errors */
    double t_raster, t_fit, t_erase, t_metrics, t_wait;
} bake_run;

/* Each level's mesh is valid and has the input's materials. */
static int check_levels(const sc_mesh *in, const sc_lods *lods, int32_t nlevels, sc_error *err) {
    const int32_t nmat = in->nmat;
    for (int32_t k = 0; k < nlevels && lods; k++) {
        const sc_mesh *lm = lods->levels[k]->as.atlas->mesh->as.mesh;
        int rc = sc_mesh_check(lm, err);
        if (rc != SC_OK) return sc_error_prefix(err, "lods: level %d", k);
        if (lm->nmat != nmat) return sc_fail(err, SC_EINPUT, "lods: level %d has %d materials, atlas has %d", k, lm->nmat, nmat);
        for (int32_t m = 0; m < nmat; m++)
            if (strcmp(lm->materials[m], in->materials[m]) != 0)
                return sc_fail(err, SC_EINPUT, "lods: level %d material %d is '%s', atlas has '%s'", k, m,
                               lm->materials[m], in->materials[m]);
    }
    return SC_OK;
}

/* The per-material and per-level arrays; false when out of memory. */
static bool alloc_maps(bake_run *b) {
    const size_t nmat = (size_t)b->nmat, nlevels = (size_t)b->nlevels;
    b->grids = calloc(nmat + 1, sizeof *b->grids);
    b->geometry = calloc(nmat + 1, sizeof *b->geometry);
    b->disp = calloc(nmat * nlevels + 1, sizeof *b->disp);
    b->rin = calloc(nmat + 1, sizeof *b->rin);
    b->meshes = calloc(nlevels + 1, sizeof *b->meshes);
    return b->grids && b->geometry && b->disp && b->meshes && b->rin;
}

/* Each material's grid: size x size, with the wrap modes of its first texture (repeat without one). */
static void material_grids(bake_run *b) {
    for (int32_t m = 0; m < b->nmat; m++) {
        b->grids[m] = (sc_seam_grid){b->size, b->size, SC_WRAP_REPEAT, SC_WRAP_REPEAT};
        for (int32_t t = 0; t < b->atlas->ntex; t++)
            if (b->atlas->textures[t].material == m) {
                b->grids[m].wrap_u = b->atlas->textures[t].wrap_u, b->grids[m].wrap_v = b->atlas->textures[t].wrap_v;
                break;
            }
    }
}

/* Fails where more than max_degenerate of the input's surface lies on faces
 * whose uv have no area (no texel holds their points), or more than
 * max_shared of the texels the input's charts cover are covered twice or
 * more: they would hold one value for two places of the surface. */
static int check_coverage(bake_run *b, double max_degenerate, double max_shared, sc_error *err) {
    int rc = SC_OK;
    b->degenerate = sc_seam_degenerate_uv_fraction(b->in);
    if (b->degenerate > max_degenerate)
        return sc_fail(err, SC_EINPUT,
                       "max_degenerate_uv_fraction: %.1f%% of the input's surface lies on faces whose uv have no "
                       "area (missing texture coordinates, or triangles squashed to a segment; %.3g%% allowed): no "
                       "texel of a geometry image or a displacement map holds their points. Give the asset an atlas "
                       "(quad_chartify)",
                       100.0 * b->degenerate, 100.0 * max_degenerate);
    for (int32_t m = 0; m < b->nmat && rc == SC_OK; m++) {
        sc_seam_coverage c;
        rc = sc_seam_coverage_build(b->in, m, &b->grids[m], b->threads, &c, err);
        if (rc == SC_OK) b->cov += (double)c.ncovered, b->shared += (double)c.nshared, sc_seam_coverage_free(&c);
    }
    if (rc == SC_OK && b->shared > max_shared * b->cov)
        rc = sc_fail(err, SC_EINPUT,
                     "max_shared_fraction: %.1f%% of the %.0f texels the input's uv charts cover at %d x %d are "
                     "covered twice or more (overlapping or mirrored charts; %.3g%% allowed): a geometry image "
                     "and a displacement map hold one value per texel, so those texels would mix distant parts "
                     "of the surface. Give the asset an atlas without overlaps",
                     100.0 * b->shared / b->cov, b->cov, (int)b->size, (int)b->size, 100.0 * max_shared);
    return rc;
}

/* The geometry images, padded 2 texels more than the displacement needs. */
static int fit_geometry_images(bake_run *b, sc_error *err) {
    int rc = SC_OK;
    double t0 = sc_now();
    for (int32_t m = 0; m < b->nmat && rc == SC_OK; m++) {
        rc = raster_build(b->in, m, &b->grids[m], b->pad + 2, b->threads, &b->rin[m], err);
        double t1 = sc_now();
        b->t_raster += t1 - t0;
        if (rc == SC_OK)
            rc = make_map(b->in, m, &b->grids[m], &b->rin[m], NULL, NULL, b->tol, b->threads, &b->ws, &b->st,
                          &b->geometry[m], err);
        t0 = sc_now();
        b->t_fit += t0 - t1;
    }
    return rc;
}

/* Start the erasure and metrics after each fit (after_fit), measured
 * against the input surface, and hand over the geometry images (erased on
 * the union of every level's mesh). */
static int hand_geometry_images(bake_run *b, double gap_tolerance, int64_t surface_samples, sc_error *err) {
    const sc_mesh *in = b->in;
    b->in_surface = (sc_hausdorff_mesh){in->V, in->nv, in->FV, in->nf};
    if (!(b->in_bvh = sc_hausdorff_bvh_build(&b->in_surface)))
        return sc_fail(err, SC_ENOMEM, "out of memory for the input's BVH");
    b->af = (after_fit){.in = in, .in_bvh = b->in_bvh, .grids = b->grids, .nmat = b->nmat,
                        .gap_tolerance = gap_tolerance, .diag = b->diag, .surface_samples = surface_samples};
    if (!(b->started = after_fit_start(&b->af, b->nlevels + 1, b->threads)))
        return sc_fail(err, SC_ENOMEM, "out of memory");
    if (b->erase) {
        const sc_lods *lods = b->lods;
        const sc_value **mv = calloc((size_t)b->nlevels + 1, sizeof *mv);
        for (int32_t k = 0; mv && k <= b->nlevels; k++)
            mv[k] = k == 0 || !lods ? b->atlas->mesh : lods->levels[k - 1]->as.atlas->mesh;
        b->union_mesh = mv ? sc_atlas_ops_mesh_union_distinct(mv, lods ? b->nlevels + 1 : 1) : NULL;
        free(mv);
        if (!b->union_mesh) return sc_fail(err, SC_ENOMEM, "out of memory for the union of the levels");
    }
    after_fit_hand(&b->af, b->union_mesh, b->geometry, -1, NULL);
    return SC_OK;
}

/* Level k's displacement maps, handed over as they are fitted; a level
 * whose mesh is an earlier level's takes that level's maps once the jobs are done. */
static int fit_level(bake_run *b, int32_t k, sc_error *err) {
    const sc_lods *lods = b->lods;
    const int32_t nmat = b->nmat;
    const sc_mesh *lm = b->meshes[k + 1];
    fit_stats sk = {0};
    int rc = SC_OK;
    b->same_as[k] = -1;
    for (int32_t j = 0; lods && j < k && b->same_as[k] < 0; j++)   /* the first of equal levels */
        if (sc_digest_equal(sc_value_digest(lods->levels[j]->as.atlas->mesh),
                            sc_value_digest(lods->levels[k]->as.atlas->mesh)))
            b->same_as[k] = j;
    if (b->same_as[k] >= 0) {   /* its maps are taken once the jobs are done */
        b->job_of[k] = b->job_of[b->same_as[k]];
        b->texels_fitted[k] = b->texels_fitted[b->same_as[k]];
        return SC_OK;
    }
    b->job_of[k] = b->af.njobs;
    for (int32_t m = 0; m < nmat && rc == SC_OK; m++) {
        double t0 = sc_now();
        locator *L = &b->locs[(size_t)k * nmat + m];
        rc = raster_build(lm, m, &b->grids[m], b->pad, b->threads, &b->rl, err);
        if (rc == SC_OK) rc = locator_build(lm, m, locator_side(b->size), L, err);
        double t1 = sc_now();
        b->t_raster += t1 - t0;
        if (rc == SC_OK)
            rc = make_map(b->in, m, &b->grids[m], &b->rin[m], &b->rl, L, b->tol, b->threads, &b->ws, &sk,
                          &b->disp[(size_t)k * nmat + m], err);
        b->t_fit += sc_now() - t1;
    }
    if (rc == SC_OK)
        after_fit_hand(&b->af, !b->erase ? NULL : lods ? lods->levels[k]->as.atlas->mesh : b->atlas->mesh,
                       b->disp + (size_t)k * nmat, k, &b->locs[(size_t)k * nmat]);
    b->texels_fitted[k] = sk.texels_solved;
    fit_stats *st = &b->st;
    st->seconds_sample += sk.seconds_sample, st->seconds_solve += sk.seconds_solve, st->iterations += sk.iterations;
    st->samples += sk.samples, st->cells_inexact += sk.cells_inexact, st->cells_solved += sk.cells_solved;
    return rc;
}

/* Every level's displacement (fit_level), in level order. */
static int fit_levels(bake_run *b, sc_error *err) {
    const int32_t nlevels = b->nlevels;
    b->meshes[0] = b->in;
    for (int32_t k = 0; k < nlevels; k++)
        b->meshes[k + 1] = b->lods ? b->lods->levels[k]->as.atlas->mesh->as.mesh : b->in;
    b->locs = calloc((size_t)b->nmat * nlevels + 1, sizeof *b->locs);
    b->texels_fitted = calloc((size_t)nlevels + 1, sizeof *b->texels_fitted);
    b->job_of = calloc((size_t)nlevels + 1, sizeof *b->job_of);
    b->same_as = calloc((size_t)nlevels + 1, sizeof *b->same_as);
    if (!b->locs || !b->texels_fitted || !b->job_of || !b->same_as) return sc_fail(err, SC_ENOMEM, "out of memory");
    int rc = SC_OK;
    for (int32_t k = 0; k < nlevels && rc == SC_OK; k++) rc = fit_level(b, k, err);
    return rc;
}

/* Wait for the jobs handed over; rc, or where it is SC_OK their first failure. */
static int finish_after_fit(bake_run *b, int rc, sc_error *err) {
    if (!b->started) return rc;
    int arc = after_fit_finish(&b->af, rc == SC_OK ? err : NULL);
    if (rc == SC_OK) rc = arc;
    b->t_erase = b->af.seconds_erase, b->t_metrics = b->af.seconds_metrics;
    return rc;
}

/* A level equal to an earlier one takes that level's maps. */
static void share_repeated_levels(bake_run *b) {
    for (int32_t k = 0; k < b->nlevels; k++)
        if (b->same_as[k] >= 0)
            for (int32_t m = 0; m < b->nmat; m++)
                b->disp[(size_t)k * b->nmat + m] = sc_value_retain(b->disp[(size_t)b->same_as[k] * b->nmat + m]);
}

/* The metrics the jobs measured: the geometry image's same-uv error, each
 * level's same-uv and reconstruction errors, and their worst. */
static void report_measured(sc_ctx *ctx, bake_run *b) {
    const after_fit *af = &b->af;
    report_errors(ctx, "geometry_image_error", af->jobs[0].acc.same, af->jobs[0].acc.nsame);
    for (int32_t k = 0; k < b->nlevels; k++) {
        recon *acc = &af->jobs[b->job_of[k]].acc;
        char name[64];
        snprintf(name, sizeof name, "lod%d.same_uv_error", k);
        b->worst_same = fmax(b->worst_same, report_errors(ctx, name, acc->same, acc->nsame));
        snprintf(name, sizeof name, "lod%d.reconstruction_error", k);
        sc_ctx_metric(ctx, name, fmax(acc->to_input, acc->from_input));
        b->worst = fmax(b->worst, fmax(acc->to_input, acc->from_input));
        snprintf(name, sizeof name, "lod%d.surface_samples_missed", k);
        sc_ctx_metric(ctx, name, (double)acc->surf_missed);
        snprintf(name, sizeof name, "lod%d.reconstruction_error_to_input", k);
        sc_ctx_metric(ctx, name, acc->to_input);
        snprintf(name, sizeof name, "lod%d.reconstruction_error_from_input", k);
        sc_ctx_metric(ctx, name, acc->from_input);
        snprintf(name, sizeof name, "lod%d.samples_missed", k);
        sc_ctx_metric(ctx, name, (double)acc->missed);
        snprintf(name, sizeof name, "lod%d.texels_fitted", k);
        sc_ctx_metric(ctx, name, (double)b->texels_fitted[k]);
    }
    sc_ctx_metric(ctx, "reconstruction_error", b->worst), sc_ctx_metric(ctx, "same_uv_error", b->worst_same);
}

/* Frees what the fits and their jobs used, before the outputs are made. */
static void free_fit_work(bake_run *b) {
    if (b->started) after_fit_free(&b->af);
    for (size_t i = 0; b->locs && i < (size_t)b->nmat * b->nlevels; i++) locator_free(&b->locs[i]);
    free(b->texels_fitted);
    free(b->job_of), free(b->same_as);
    free(b->locs);
    raster_free(&b->rl);
    fit_scratch_free(&b->ws);
    sc_hausdorff_bvh_free(b->in_bvh);
}

/* The input's coverage, the level count and the geometry images' fitted texels. */
static void report_totals(sc_ctx *ctx, const bake_run *b) {
    sc_ctx_metric(ctx, "texels_covered", b->cov);
    sc_ctx_metric(ctx, "texels_shared", b->shared);
    sc_ctx_metric(ctx, "degenerate_uv_fraction", b->degenerate);
    sc_ctx_metric(ctx, "levels", b->nlevels);
    sc_ctx_metric(ctx, "geometry_image.texels_fitted", (double)b->st.texels_solved);
}

/* The outputs: the atlas with its geometry images, and every level with
 * them and its own displacement; then the timings and fit statistics. */
static int set_outputs(sc_ctx *ctx, const bake_run *b, sc_error *err) {
    const int32_t nmat = b->nmat;
    int rc = SC_OK;
    sc_value *out_atlas = atlas_with(b->atlas, "geometry_image", b->geometry, NULL, NULL, b->grids, nmat);
    sc_lods *out_lods = sc_lods_new();
    if (!out_atlas || !out_lods) rc = sc_fail(err, SC_ENOMEM, "out of memory");
    for (int32_t k = 0; k < b->nlevels && rc == SC_OK; k++) {
        const sc_atlas *src = b->lods ? b->lods->levels[k]->as.atlas : b->atlas;
        sc_value *lv = atlas_with(src, "geometry_image", b->geometry, "displacement", b->disp + (size_t)k * nmat,
                                  b->grids, nmat);
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
        sc_ctx_metric(ctx, "seconds_raster", b->t_raster);
        sc_ctx_metric(ctx, "seconds_fit", b->t_fit);
        sc_ctx_metric(ctx, "seconds_fit_sample", b->st.seconds_sample);
        sc_ctx_metric(ctx, "seconds_fit_solve", b->st.seconds_solve);
        sc_ctx_metric(ctx, "fit_iterations", (double)b->st.iterations);
        sc_ctx_metric(ctx, "fit_samples", (double)b->st.samples);
        sc_ctx_metric(ctx, "fit_cells_inexact", (double)b->st.cells_inexact);
        sc_ctx_metric(ctx, "fit_cells_solved", (double)b->st.cells_solved);
        sc_ctx_metric(ctx, "seconds_erase", b->t_erase);             /* in the erase kernel, beside the fits */
        sc_ctx_metric(ctx, "seconds_erase_wait", b->t_wait);         /* left after the last fit */
        sc_ctx_metric(ctx, "seconds_metrics", b->t_metrics);
    }
    sc_value_release(out_atlas);
    sc_lods_free(out_lods);
    return rc;
}

/* Frees the maps and what run kept for the outputs. */
static void bake_run_free(bake_run *b) {
    sc_value_release(b->union_mesh);
    for (int32_t m = 0; b->geometry && m < b->nmat; m++) sc_value_release(b->geometry[m]);
    for (int32_t m = 0; b->rin && m < b->nmat; m++) raster_free(&b->rin[m]);
    for (size_t i = 0; b->disp && i < (size_t)b->nmat * b->nlevels; i++) sc_value_release(b->disp[i]);
    free(b->grids), free(b->geometry), free(b->disp), free(b->meshes), free(b->rin);
}

static int run(sc_ctx *ctx, sc_error *err) {
    const sc_atlas *atlas = sc_ctx_atlas(ctx, "atlas");
    const sc_lods *lods = sc_ctx_lods(ctx, "lods");
    const sc_mesh *in = atlas->mesh->as.mesh;
    const int32_t size = (int32_t)sc_ctx_integer(ctx, "size");
    const int32_t pad = (int32_t)sc_ctx_integer(ctx, "padding");
    const bool erase = sc_ctx_bool(ctx, "erase");
    const double gap_tolerance = sc_ctx_number(ctx, "gap_tolerance");
    const double fit_tolerance = sc_ctx_number(ctx, "fit_tolerance");
    const int64_t surface_samples = sc_ctx_integer(ctx, "surface_samples");
    const double max_shared = sc_ctx_number(ctx, "max_shared_fraction");
    const int threads = sc_ctx_threads(ctx);
    int rc = sc_mesh_check(in, err);
    if (rc != SC_OK) return sc_error_prefix(err, "atlas");
    if (in->nf < 1) return sc_fail(err, SC_EINPUT, "atlas: the mesh has no faces");
    if ((uint64_t)size * (uint64_t)size > SC_IMAGE_MAX_PIXELS)
        return sc_fail(err, SC_EINPUT, "size: %d x %d is beyond the image limits", size, size);
    const int32_t nlevels = lods ? lods->count : 1;
    if (lods && nlevels < 1) return sc_fail(err, SC_EINPUT, "lods: the list is empty");
    if ((rc = check_levels(in, lods, nlevels, err)) != SC_OK) return rc;

    /* the unit of tolerances and error metrics (1 for a mesh without extent) */
    const double extent = sc_bbox_diagonal(in->V, in->nv, NULL, 0);
    const double diag = extent > 0 && isfinite(extent) ? extent : 1, tol = fit_tolerance * diag;
    bake_run b = {.atlas = atlas, .lods = lods, .in = in, .size = size, .pad = pad, .nmat = in->nmat,
                  .nlevels = nlevels, .erase = erase, .diag = diag, .tol = tol, .threads = threads};
    if (!alloc_maps(&b)) rc = sc_fail(err, SC_ENOMEM, "out of memory");
    if (rc == SC_OK) material_grids(&b);
    double t0 = sc_now();
    if (rc == SC_OK) rc = check_coverage(&b, sc_ctx_number(ctx, "max_degenerate_uv_fraction"), max_shared, err);
    b.t_metrics += sc_now() - t0;
    if (rc == SC_OK) rc = fit_geometry_images(&b, err);
    if (rc == SC_OK) rc = hand_geometry_images(&b, gap_tolerance, surface_samples, err);
    if (rc == SC_OK) rc = fit_levels(&b, err);
    t0 = sc_now();
    rc = finish_after_fit(&b, rc, err);
    b.t_wait = sc_now() - t0;
    if (rc == SC_OK) share_repeated_levels(&b);
    if (rc == SC_OK) report_measured(ctx, &b);
    free_fit_work(&b);

    t0 = sc_now();
    if (rc == SC_OK) report_totals(ctx, &b);
    b.t_metrics += sc_now() - t0;
    if (rc == SC_OK) rc = set_outputs(ctx, &b, err);
    bake_run_free(&b);
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
    {.name = "surface_samples", .type = SC_PARAM_INTEGER, .def = 100000, .min = 100, .max = 100000000,
     .doc = "samples of each surface (input, and each level as drawn) per material for the surface distance "
            "(lod<k>.reconstruction_error), spread by area over every face, its edges and vertices too"},
    {.name = "max_shared_fraction", .type = SC_PARAM_NUMBER, .def = 0.01, .min = 0, .max = 1,
     .doc = "fail when more than this fraction of the texels the input's charts cover are covered twice or "
            "more (overlapping or mirrored charts: Duck 94%, WaterBottle 0.2%, the rest of the corpus 0)"},
    {.name = "max_degenerate_uv_fraction", .type = SC_PARAM_NUMBER, .def = 0.01, .min = 0, .max = 1,
     .doc = "fail when more than this fraction of the input's surface lies on faces whose uv have no area "
            "(missing texture coordinates: no texel holds their points)"},
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

static const sc_kernel *const kernels[] = {&sc_kernel_atlas_ops, &sc_kernel_hausdorff, &sc_kernel_seam, NULL};

const sc_node_desc sc_node_bake_displacement = {
    .type = "bake_displacement",
    .version = 9,
    .summary = "bakes a geometry image and a vector displacement map per level of detail (Liu et al. 2017 §7)",
    .inputs = inputs,
    .ninputs = SC_COUNT(inputs),
    .outputs = outputs,
    .noutputs = SC_COUNT(outputs),
    .params = params,
    .nparams = SC_COUNT(params),
    .run = run,
    .kernels = kernels,
};
