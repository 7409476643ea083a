/* mipmap.c - the node `mipmap`: seam-free mip chains (Liu et al. 2017, §9:
 * "erase seams on each level independently").
 *
 * Design note.
 *  - Chains. Level m + 1 of a texture is the 2 x 2 box average of the erased
 *    level m (sides max(1, floor(n / 2)), GL's and OpenEXR's round-down rule;
 *    an odd last row or column is folded into its neighbour's box), down to
 *    1 x 1 (an OpenEXR mip-map holds every level); `levels` stops at
 *    `min_size`. Averaging is on the values as erased: sRGB colour in linear
 *    light (filter_space linear, the way GPUs filter and build mips of sRGB
 *    textures, and the erase kernel solves them), else the stored values. A slot named "normal"
 *    (3+ channels) is renormalised after averaging (decoded as 2 x - 1
 *    unless the image is float DATA with negative values).
 *  - DATA maps (float, colour space DATA, not "normal": geometry image,
 *    displacement) hold a band of linear continuation around each chart and
 *    push-pull fill beyond it. Level 0's valid texels are those within 2
 *    texels of a face, labelled with the chart of the nearest face (charts:
 *    faces joined by uv vertices or overlapping texel centres; the nearest
 *    face is found in bands of rows, faces in order in each, so the labels
 *    do not depend on the thread count). A texel of
 *    level m + 1 is the box mean as above, valid only when every texel of its
 *    box is valid and of one chart; then 2 rings are grown from the valid
 *    texels (linear continuation 2 v(t + d) - v(t + 2 d) within the chart
 *    with the most neighbours) and the rest is push-pull filled. Erasure then
 *    runs as for every map.
 *  - Erasure. Every level is erased by the erase kernel (sc_erase through
 *    sc_atlas_ops_erase, erase_seams's defaults with this node's w_seam and
 *    gap_tolerance) on the mesh and that level's textures (one call per
 *    group and level, so one factorisation serves all of a group's textures
 *    of one size); 8/16-bit textures come back quantised (optimal
 *    rounding), float ones as f32. The next level is built from the erased
 *    float values. The seam stiffness `w_seam` is 1e12, 100 times
 *    erase_seams's default: a coarse level's charts are a few texels across,
 *    and at 1e10 the penalty leaves gaps that the render check sees.
 *    Cholesky's backward error, ~1e-16 * 1e12 of the grid stiffness, is
 *    still far below it.
 *  - Tangent-space normal maps. A "normal" slot is judged once, at level 0
 *    (sc_erase_takes_tangent_space with `normal_space`); a tangent-space
 *    map's vectors live in the frames of one mesh, so its levels are erased
 *    in a call of their own through those frames (in object space, the
 *    kernel's way), and a shared chain's through the first level of
 *    detail's, the finest that shares it: the union's copies overlap in uv
 *    and would give a texel any copy's frame. Its level 0 is the kernel's
 *    to keep, when its object-space seams are within what 8-bit rounding
 *    opens there. The saved map was erased for the reference's frames, so
 *    where the first level's differ the chain's level 0 differs from it
 *    (docs/notes/mipmap.md).
 *  - Levels not erased. Where an atlas's charts fall under a texel, the seams
 *    tie texels all over the level together and no ordering keeps the factor
 *    sparse: from some size on the factor passes sc_sparse's limit (6e8
 *    entries), and below it METIS's factors still take minutes. Iterations do
 *    not reach the same answer in less: conjugate gradients with Jacobi (and
 *    every component's constant deflated, which the penalty's rounding leaves
 *    behind) stall short of the factorisation's residual on the larger
 *    levels; incomplete Cholesky needs a large shift and gains little, and
 *    factors of Q with its weak couplings dropped fill as badly. Such a level
 *    fails with a message naming `erase_min_size`: levels whose sides are
 *    both below it are box-averaged (DATA maps as above) but not erased
 *    (counted: levels_not_erased); their seam energies are reported like any
 *    other level's.
 *  - Level 0 already erased. A level-0 texture whose largest seam gap,
 *    measured as the erasure filters it (sRGB colour in linear light with
 *    filter_space linear), is within what its storage holds (`level0_gap`
 *    times its largest magnitude for float, one step for 8/16-bit; or
 *    `gap_tolerance`) is kept as it is (a chain's level 0 is then the very
 *    texture the graph saves): it comes erased from upstream
 *    (bake_displacement erases every map on these seams or more). Erasing
 *    it again buys nothing and costs much: it leaves the gaps about where
 *    they were but moves texels (mipmap's erase keeps erase_seams's E_C1
 *    term, which the bake leaves out for positions), at a large share of
 *    the node's erase time.
 *  - Levels of detail. With `lods`, every level of detail gets its own chains,
 *    erased on its own seams, except a texture that is the very same image
 *    (same slot, material and digest) on every level: its chain is built once
 *    and erased on the union of every level's mesh (disjoint copies in one
 *    mesh, a repeated mesh once), so it stays shared - the geometry image
 *    of bake_displacement.
 *  - Outputs. `levels` (LODS): with `atlas`, level m is the atlas's mesh with
 *    every texture at mip level m (a shorter chain repeats its last level);
 *    with `lods`, entry k * levels + m is LOD k at mip level m. render then
 *    checks every LOD at every mip level. `report`: the metrics and files
 *    mip/[lod<k>_]<material>_<slot>.exr (float textures: one tiled,
 *    mip-mapped OpenEXR holding every level) and
 *    mip/[lod<k>_]<material>_<slot>_level<m>.png (8/16-bit textures).
 *    `files` picks the chains written (all; textures, leaving out the baked
 *    geometry_image and displacement maps, which only a tessellating
 *    renderer reads; none) and `files_from_level` a PNG chain's first level
 *    written (1 where level 0 is the texture save writes), so --out holds
 *    each texture once; the levels and metrics are the same either way.
 *  - Work. Groups (each source's chains, and the shared ones) are built side
 *    by side, as many at once as there are threads, each using every thread
 *    in its own parallel parts (labelling, the erase kernel, its files), so
 *    one group's serial stretches (box averages, ring growth, push-pull, the
 *    erase kernel's setup) overlap another's work; the shared group, the
 *    largest (every level's seams), starts first. A group encodes its chains'
 *    files once its levels are erased, each file (a PNG level, a whole EXR
 *    chain) on its own thread, the largest first: the shared group holds
 *    every 8-bit chain, whose files would otherwise follow one another on
 *    one core. A PNG level goes through sc_image_value_encode_png: a level
 *    0 kept as it is, the texture save writes, is deflated once. Each
 *    chain, level and file depends on its own inputs alone and the report
 *    takes the files in chain order, so neither the order groups finish in
 *    nor the thread count shows in the results. seconds_groups is that
 *    stage's wall time; seconds_erase and seconds_files the time in the
 *    erase kernel and in encoding, summed over the groups.
 *  - Metrics: [lod<k>.]level<m>.seam_energy and .max_seam_gap (the largest
 *    over the textures: sc_seam_energy on that LOD's mesh, of the level as
 *    stored and decoded as filtered: sRGB colour in linear light in linear
 *    mode), level<m>.width,
 *    levels, erase runs, level-0 textures kept as they are, and timings.
 * Measurements and history: docs/notes/mipmap.md.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "sc_atlas_ops.h"
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
    int32_t *band;             /* DATA maps: chart of each valid texel of the last level built, else -1 */
    bool tangent;              /* a tangent-space normal map, erased through its mesh's frames */
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

/* ---------------------------------------------------------------- data maps
 *
 * A float DATA map (geometry image, displacement) holds, around each chart, a
 * band of texels that continue the surface linearly; beyond it, push-pull
 * fill that has nothing to do with the surface. `band` marks the texels that
 * hold meaningful values (chart and band); a level is built from the valid
 * texels of the one above only, and its band is then grown again. */

#define DATA_BAND0 2.0   /* level 0: texels within this distance of a face (bake pads >= 2) */
#define DATA_RINGS 2     /* rings of linear continuation grown at each level */

static bool is_data_map(const sc_texture *t) {
    const sc_image_data *im = t->image->as.image;
    return im->pixel == SC_PIXEL_F32 && im->colorspace == SC_COLOR_DATA && strcmp(t->name, "normal") != 0;
}

/* Face f's uv corners in texel-centre coordinates. */
static void face_texels(const sc_mesh *m, int32_t f, int32_t W, int32_t H, double x[3], double y[3]) {
    for (int k = 0; k < 3; k++) {
        const double *uv = m->U + 2 * (size_t)m->FU[3 * f + k];
        x[k] = uv[0] * W - 0.5, y[k] = uv[1] * H - 0.5;
    }
}

/* Point (px, py) in the closed triangle x, y of signed double area d != 0. */
static bool inside(const double x[3], const double y[3], double d, double px, double py) {
    double e0 = (x[1] - px) * (y[2] - py) - (x[2] - px) * (y[1] - py);
    double e1 = (x[2] - px) * (y[0] - py) - (x[0] - px) * (y[2] - py);
    double e2 = (x[0] - px) * (y[1] - py) - (x[1] - px) * (y[0] - py);
    return d > 0 ? (e0 >= 0 && e1 >= 0 && e2 >= 0) : (e0 <= 0 && e1 <= 0 && e2 <= 0);
}

/* The nearest-face pass of data_band0 on texel rows [chunk * BAND_ROWS, ...):
 * every face in face order, so each texel sees the serial sequence of
 * updates (ties to the lower face) on any thread count. A texel held at
 * distance 0 is final; columns are cut to those within r (sc_atlas_ops_row_span). */
#define BAND_ROWS 32
typedef struct band_job {
    const sc_mesh *m;
    int32_t material, W, H;
    sc_wrap wu, wv;
    double r;
    const int32_t *fid;
    int32_t *label;
    double *best;
} band_job;

static int band_rows(void *ud, int32_t chunk) {
    const band_job *J = ud;
    const sc_mesh *m = J->m;
    const int32_t W = J->W, H = J->H, b0 = chunk * BAND_ROWS, b1 = b0 + BAND_ROWS < H ? b0 + BAND_ROWS : H;
    const double r = J->r;
    for (int32_t f = 0; f < m->nf; f++) {
        if (m->FM[f] != J->material) continue;
        int32_t id = J->fid[f];
        double x[3], y[3];
        face_texels(m, f, W, H, x, y);
        double xmin = fmin(x[0], fmin(x[1], x[2])) - r, xmax = fmax(x[0], fmax(x[1], x[2])) + r;
        double ymin = fmin(y[0], fmin(y[1], y[2])) - r, ymax = fmax(y[0], fmax(y[1], y[2])) + r;
        if (!(xmax - xmin < 4.0 * W + 8 && ymax - ymin < 4.0 * H + 8)) continue;   /* not finite or absurd */
        int64_t j0 = (int64_t)ceil(ymin), j1 = (int64_t)floor(ymax);
        if (j0 >= 0 && j1 < H) {   /* no wrapping: the band's rows only */
            if (j0 < b0) j0 = b0;
            if (j1 > b1 - 1) j1 = b1 - 1;
        }
        double d = (x[1] - x[0]) * (y[2] - y[0]) - (x[2] - x[0]) * (y[1] - y[0]);
        for (int64_t j = j0; j <= j1; j++) {
            int32_t jw = sc_seam_wrap(j, H, J->wv);
            if (jw < b0 || jw >= b1) continue;
            int64_t i0, i1;
            sc_atlas_ops_row_span(x, y, r, (double)j, &i0, &i1);
            if (i0 < (int64_t)ceil(xmin)) i0 = (int64_t)ceil(xmin);
            if (i1 > (int64_t)floor(xmax)) i1 = (int64_t)floor(xmax);
            for (int64_t i = i0; i <= i1; i++) {
                size_t t = (size_t)jw * W + sc_seam_wrap(i, W, J->wu);
                if (J->best[t] == 0) continue;   /* held at distance 0: a later face only ties */
                bool in = d != 0 && inside(x, y, d, (double)i, (double)j);
                double d2 = in ? 0 : fmin(sc_atlas_ops_segment_distance2((double)i, (double)j, x[0], y[0], x[1], y[1]),
                                          fmin(sc_atlas_ops_segment_distance2((double)i, (double)j, x[1], y[1], x[2], y[2]),
                                               sc_atlas_ops_segment_distance2((double)i, (double)j, x[2], y[2], x[0], y[0])));
                if (d2 <= r * r && d2 < J->best[t]) J->best[t] = d2, J->label[t] = id;   /* faces in order: ties to the lower */
            }
        }
    }
    return SC_OK;
}

/* Level 0's band: every texel whose centre lies within `r` texels of a uv
 * triangle of the material (through the wrap modes) gets the chart of the
 * nearest such face (charts: faces joined through shared uv vertices, named
 * by their first face; ties to the lower face index), the others -1. NULL
 * when out of memory. */
static int32_t *data_band0(const sc_mesh *m, int32_t material, int32_t W, int32_t H, sc_wrap wu, sc_wrap wv,
                           double r, int threads) {
    int32_t *label = malloc((size_t)W * H * sizeof *label);
    double *best = malloc((size_t)W * H * sizeof *best);
    int32_t *parent = malloc(((size_t)m->nu + 1) * sizeof *parent);
    int32_t *chart = malloc(((size_t)m->nu + 1) * sizeof *chart);
    if (!label || !best || !parent || !chart) {
        free(label), free(best), free(parent), free(chart);
        return NULL;
    }
    for (int32_t u = 0; u < m->nu; u++) parent[u] = u, chart[u] = -1;
    for (int32_t f = 0; f < m->nf; f++)
        if (m->FM[f] == material)
            for (int k = 1; k < 3; k++) {
                int32_t a = sc_set_root(parent, m->FU[3 * f]), b = sc_set_root(parent, m->FU[3 * f + k]);
                if (a != b) parent[a > b ? a : b] = a < b ? a : b;
            }
    /* copies of one chart (levels of detail in a union) overlap: texel centres
     * inside faces of two components join them */
    for (size_t t = 0; t < (size_t)W * H; t++) label[t] = -1;
    for (int32_t f = 0; f < m->nf; f++) {
        if (m->FM[f] != material) continue;
        double x[3], y[3];
        face_texels(m, f, W, H, x, y);
        double d = (x[1] - x[0]) * (y[2] - y[0]) - (x[2] - x[0]) * (y[1] - y[0]);
        double xmin = fmin(x[0], fmin(x[1], x[2])), xmax = fmax(x[0], fmax(x[1], x[2]));
        double ymin = fmin(y[0], fmin(y[1], y[2])), ymax = fmax(y[0], fmax(y[1], y[2]));
        if (d == 0 || !(xmax - xmin < 4.0 * W + 8 && ymax - ymin < 4.0 * H + 8)) continue;
        for (int64_t j = (int64_t)ceil(ymin); j <= (int64_t)floor(ymax); j++) {
            int64_t i0, i1;   /* the columns that can be inside */
            sc_atlas_ops_row_span(x, y, 0, (double)j, &i0, &i1);
            if (i0 < (int64_t)ceil(xmin)) i0 = (int64_t)ceil(xmin);
            if (i1 > (int64_t)floor(xmax)) i1 = (int64_t)floor(xmax);
            for (int64_t i = i0; i <= i1; i++) {
                if (!inside(x, y, d, (double)i, (double)j)) continue;
                size_t t = (size_t)sc_seam_wrap(j, H, wv) * W + sc_seam_wrap(i, W, wu);
                int32_t a = sc_set_root(parent, m->FU[3 * f]), b = label[t] >= 0 ? sc_set_root(parent, label[t]) : a;
                if (a != b) parent[a > b ? a : b] = a < b ? a : b;
                label[t] = a < b ? a : b;
            }
        }
    }
    for (int32_t f = 0; f < m->nf; f++) {
        int32_t root = m->FM[f] == material ? sc_set_root(parent, m->FU[3 * f]) : -1;
        if (root >= 0 && chart[root] < 0) chart[root] = f;
    }
    int32_t *fid = malloc(((size_t)m->nf + 1) * sizeof *fid);   /* each face's chart */
    if (!fid) {
        free(label), free(best), free(parent), free(chart);
        return NULL;
    }
    for (int32_t f = 0; f < m->nf; f++) fid[f] = m->FM[f] == material ? chart[sc_set_root(parent, m->FU[3 * f])] : -1;
    for (size_t t = 0; t < (size_t)W * H; t++) label[t] = -1, best[t] = INFINITY;
    band_job job = {m, material, W, H, wu, wv, r, fid, label, best};
    int rc = sc_seam_parallel(threads, (H + BAND_ROWS - 1) / BAND_ROWS, band_rows, &job);
    free(best), free(parent), free(chart), free(fid);
    if (rc != SC_OK) free(label), label = NULL;
    return label;
}

/* Grow the valid texels (label >= 0: their chart) by `rings` rings. A texel
 * next to valid ones joins the chart with the most valid neighbours (ties to
 * the lower label) and takes the mean of that chart's linear continuations
 * 2 v(t + d) - v(t + 2 d) over the eight directions d where both are valid
 * texels of it, else the mean of its neighbours in it. Each ring reads the
 * previous rings only, so the result is independent of the scan order. */
static int grow_band(float *px, int32_t *label, int32_t W, int32_t H, int32_t C, int rings) {
    static const int dd[8][2] = {{1, 0}, {-1, 0}, {0, 1}, {0, -1}, {1, 1}, {1, -1}, {-1, 1}, {-1, -1}};
    int32_t *next = malloc((size_t)W * H * sizeof *next);
    if (!next) return SC_ENOMEM;
    for (int ring = 0; ring < rings; ring++) {
        memcpy(next, label, (size_t)W * H * sizeof *next);
        bool grew = false;
        for (int32_t j = 0; j < H; j++)
            for (int32_t i = 0; i < W; i++) {
                size_t t = (size_t)j * W + i;
                if (label[t] >= 0) continue;
                int32_t nb[8];
                for (int k = 0; k < 8; k++) {
                    int32_t i1 = i + dd[k][0], j1 = j + dd[k][1];
                    nb[k] = i1 < 0 || j1 < 0 || i1 >= W || j1 >= H ? -1 : label[(size_t)j1 * W + i1];
                }
                int32_t pick = -1;
                int best = 0;
                for (int k = 0; k < 8; k++) {
                    if (nb[k] < 0) continue;
                    int n = 0;
                    for (int q = 0; q < 8; q++) n += nb[q] == nb[k];
                    if (n > best || (n == best && nb[k] < pick)) best = n, pick = nb[k];
                }
                if (pick < 0) continue;
                double lin[4] = {0, 0, 0, 0}, near[4] = {0, 0, 0, 0};
                int nlin = 0, nnear = 0;
                for (int k = 0; k < 8; k++) {
                    if (nb[k] != pick) continue;
                    int32_t i1 = i + dd[k][0], j1 = j + dd[k][1], i2 = i + 2 * dd[k][0], j2 = j + 2 * dd[k][1];
                    const float *a = px + ((size_t)j1 * W + i1) * C;
                    for (int32_t c = 0; c < C; c++) near[c] += a[c];
                    nnear++;
                    if (i2 < 0 || j2 < 0 || i2 >= W || j2 >= H || label[(size_t)j2 * W + i2] != pick) continue;
                    const float *b = px + ((size_t)j2 * W + i2) * C;
                    for (int32_t c = 0; c < C; c++) lin[c] += 2.0 * a[c] - b[c];
                    nlin++;
                }
                float *o = px + t * C;
                for (int32_t c = 0; c < C; c++) o[c] = (float)(nlin ? lin[c] / nlin : near[c] / nnear);
                next[t] = pick, grew = true;
            }
        memcpy(label, next, (size_t)W * H * sizeof *next);
        if (!grew) break;
    }
    free(next);
    return SC_OK;
}

/* Push-pull: texels not valid take the mean of the valid texels of their
 * block on the coarsest level of a 2 x 2 pyramid that has one. */
static int push_pull(float *px, const int32_t *label, int32_t W, int32_t H, int32_t C) {
    if (W <= 1 && H <= 1) return SC_OK;
    int32_t w2 = (W + 1) / 2, h2 = (H + 1) / 2;
    float *p2 = calloc((size_t)w2 * h2 * C, sizeof *p2);
    int32_t *v2 = malloc((size_t)w2 * h2 * sizeof *v2);
    int rc = p2 && v2 ? SC_OK : SC_ENOMEM;
    for (size_t t = 0; rc == SC_OK && t < (size_t)w2 * h2; t++) v2[t] = -1;
    bool any_invalid = false;
    for (int32_t j = 0; j < h2 && rc == SC_OK; j++)
        for (int32_t i = 0; i < w2; i++) {
            double sum[4] = {0, 0, 0, 0};
            int n = 0;
            for (int32_t jj = 2 * j; jj < 2 * j + 2 && jj < H; jj++)
                for (int32_t ii = 2 * i; ii < 2 * i + 2 && ii < W; ii++) {
                    size_t t = (size_t)jj * W + ii;
                    if (label[t] < 0) { any_invalid = true; continue; }
                    for (int32_t c = 0; c < C; c++) sum[c] += px[t * C + c];
                    n++;
                }
            if (n) {
                for (int32_t c = 0; c < C; c++) p2[((size_t)j * w2 + i) * C + c] = (float)(sum[c] / n);
                v2[(size_t)j * w2 + i] = 0;
            }
        }
    if (rc == SC_OK && any_invalid) rc = push_pull(p2, v2, w2, h2, C);
    for (int32_t j = 0; j < H && rc == SC_OK && any_invalid; j++)
        for (int32_t i = 0; i < W; i++) {
            size_t t = (size_t)j * W + i;
            if (label[t] < 0) memcpy(px + t * C, p2 + ((size_t)(j / 2) * w2 + i / 2) * C, (size_t)C * sizeof *px);
        }
    free(p2), free(v2);
    return rc;
}

/* The next level of a DATA map: each texel the mean of its box (as box_down)
 * where every texel of the box is valid, then DATA_RINGS rings of linear
 * continuation from those, then push-pull for the rest. *band_io: in, the
 * valid texels of src; out, those of the new level. */
static sc_image_data *data_down(const sc_image_data *src, int32_t **band_io) {
    int32_t W = src->width, H = src->height, C = src->channels, w2, h2;
    next_size(W, H, &w2, &h2);
    sc_image_data *dst = C <= 4 ? sc_image_alloc(w2, h2, C, SC_PIXEL_F32) : NULL;
    int32_t *band = malloc((size_t)w2 * h2 * sizeof *band);
    if (!dst || !band) {
        sc_image_free(dst), free(band);
        return NULL;
    }
    dst->colorspace = src->colorspace;
    memcpy(dst->format, src->format, sizeof dst->format);
    const float *s = src->pixels;
    const int32_t *in = *band_io;
    float *d = dst->pixels;
    for (int32_t j = 0; j < h2; j++) {
        int32_t j0 = H == 1 ? 0 : 2 * j, j1 = H == 1 ? 0 : (j == h2 - 1 ? H - 1 : 2 * j + 1);
        for (int32_t i = 0; i < w2; i++) {
            int32_t i0 = W == 1 ? 0 : 2 * i, i1 = W == 1 ? 0 : (i == w2 - 1 ? W - 1 : 2 * i + 1);
            double sum[4] = {0, 0, 0, 0};
            int n = 0;
            int32_t lab = in[(size_t)j0 * W + i0];
            for (int32_t jj = j0; jj <= j1; jj++)
                for (int32_t ii = i0; ii <= i1; ii++, n++) {
                    if (in[(size_t)jj * W + ii] != lab) lab = -1;
                    for (int32_t c = 0; c < C; c++) sum[c] += s[((size_t)jj * W + ii) * C + c];
                }
            float *o = d + ((size_t)j * w2 + i) * C;
            for (int32_t c = 0; c < C; c++) o[c] = (float)(sum[c] / n);
            band[(size_t)j * w2 + i] = lab;
        }
    }
    int rc = grow_band(d, band, w2, h2, C, DATA_RINGS);
    if (rc == SC_OK) rc = push_pull(d, band, w2, h2, C);
    if (rc != SC_OK) {
        sc_image_free(dst), free(band);
        return NULL;
    }
    free(*band_io);
    *band_io = band;
    return dst;
}

/* ---------------------------------------------------------------- erasing */

/* How levels are erased (the node's parameters). */
/* Which files the node writes (params files and files_from_level). */
typedef struct file_choice {
    bool any, maps;           /* any file at all; the baked maps (geometry_image, displacement) too */
    int32_t from_level;       /* a PNG chain's first level written */
} file_choice;

typedef struct erase_settings {
    int32_t min_size;            /* erase_min_size */
    double gap_tolerance, level0_gap;
    sc_erase_options erase;      /* sc_erase's: the defaults, with w_seam and gap_tolerance */
    int threads;
    file_choice files;           /* which chains and levels become files */
} erase_settings;

/* Whether level 0 of a chain is seam-free already: its largest sampled seam
 * gap (sc_seam_energy) within `gap_tolerance`, or within what its storage
 * holds: `level0_gap` times its largest magnitude (float), one step (8/16
 * bit). The gap is measured on `filtered`, the level as the erasure filters
 * it (float_view: sRGB colour in linear light by default), the tolerance
 * from `im`, the level as stored. level0_gap = 0: never (every level 0 is
 * erased). Tangent-space normal maps are the erase kernel's to judge
 * (erase_level). */
static int seam_free_already(const sc_mesh *mesh, const sc_seam_set *seams, const sc_texture *tex,
                             const sc_image_data *im, const sc_image_data *filtered, const erase_settings *es,
                             bool *clean, sc_error *err) {
    *clean = false;
    const double gap_tolerance = es->gap_tolerance, level0_gap = es->level0_gap;
    const int threads = es->threads;
    if (!(level0_gap > 0)) return SC_OK;
    double tol = gap_tolerance;
    if (im->pixel == SC_PIXEL_F32) {
        const float *px = im->pixels;
        float mag = 0;   /* a NaN compares false and is skipped, as fmax would */
        for (size_t t = 0; t < (size_t)im->width * im->height * im->channels; t++)
            if (fabsf(px[t]) > mag) mag = fabsf(px[t]);
        tol = fmax(tol, level0_gap * mag);
    } else {
        tol = fmax(tol, im->pixel == SC_PIXEL_U8 ? 1.0 / 255 : 1.0 / 65535);
    }
    if (seams->nseams == 0) {
        *clean = true;
        return SC_OK;
    }
    sc_seam_grid g = {im->width, im->height, tex->wrap_u, tex->wrap_v};
    double energy = 0, gap = 0;
    int rc = sc_seam_energy(mesh, seams, &g, filtered, threads, &energy, &gap, err);
    if (rc == SC_OK) *clean = gap <= tol;
    return rc;
}

/* What erasing the levels did. */
typedef struct erase_counts {
    int runs;       /* sc_atlas_ops_erase calls */
    int passed;     /* level-0 maps kept as they are */
    int unerased;   /* map levels below erase_min_size */
} erase_counts;

/* Level image `in` as the f32 image the next level is built from: itself
 * when float, else decoded into the space the erasure filters in. */
static sc_value *float_view(sc_value *in, const erase_settings *es) {
    const sc_image_data *im = in->as.image;
    if (im->pixel == SC_PIXEL_F32) return sc_value_retain(in);
    sc_image_data *f = es->erase.filter_space == SC_ERASE_FILTER_LINEAR ? sc_image_to_linear_f32(im, 1)
                                                                         : sc_image_to_f32(im);
    sc_value *fv = f ? sc_value_new_image(f) : NULL;
    if (f && !fv) sc_image_free(f);
    return fv;
}

/* Erase level m of the chains of one group on `mesh`: the input images are
 * in[i] (pixel type of the chain); results into the chains' level m. At
 * level 0, chains whose seams are closed already (seam_free_already) pass
 * through as they are; so do maps whose sides are both below erase_min_size
 * (counted as unerased); the others are erased in one sc_atlas_ops_erase
 * call with options eo. With `tangent` every chain is a tangent-space
 * normal map, and the kernel itself judges level 0 in the space it erases
 * it in (object space through the frames), with level0_gap as the
 * tolerance beside what rounding alone opens there (sc_erase). */
static int erase_level(sc_value *mesh, chain *const *chains, sc_value *const *in, int n, int m, bool tangent,
                       const sc_erase_options *eo, const erase_settings *es, erase_counts *counts, sc_error *err) {
    sc_atlas_ops_map *maps = calloc((size_t)n + 1, sizeof *maps);
    sc_value **f32 = calloc((size_t)n + 1, sizeof *f32), **native = calloc((size_t)n + 1, sizeof *native);
    int *which = calloc((size_t)n + 1, sizeof *which);   /* erased map i is chain which[i] */
    int rc = maps && f32 && native && which ? SC_OK : sc_fail(err, SC_ENOMEM, "out of memory");
    int nerase = 0;
    sc_seam_set seams = {0};
    int32_t seams_material = -1;
    for (int i = 0; i < n && rc == SC_OK; i++) {
        const sc_texture *t = chains[i]->tex;
        const sc_image_data *level = in[i]->as.image;
        bool erase = level->width >= es->min_size || level->height >= es->min_size;
        bool clean = !erase;
        if (!erase) counts->unerased++;
        sc_value *fv = NULL;   /* the level as the erasure filters it */
        if (erase && m == 0 && es->level0_gap > 0 && !tangent) {
            fv = float_view(in[i], es);
            if (!fv) rc = sc_fail(err, SC_ENOMEM, "out of memory");
        }
        if (rc == SC_OK && erase && m == 0 && es->level0_gap > 0 && !tangent) {
            if (seams_material != t->material) {
                if (seams_material >= 0) sc_seam_set_free(&seams);
                seams_material = -1;
                rc = sc_seam_find(mesh->as.mesh, t->material, &seams, err);
                if (rc == SC_OK) seams_material = t->material;
            }
            if (rc == SC_OK)
                rc = seam_free_already(mesh->as.mesh, &seams, t, in[i]->as.image, fv->as.image, es, &clean, err);
        }
        if (rc == SC_OK && clean) {
            if (!fv) fv = float_view(in[i], es);
            if (!fv) rc = sc_fail(err, SC_ENOMEM, "out of memory");
            chains[i]->f32[m] = fv, chains[i]->native[m] = fv ? sc_value_retain(in[i]) : NULL;
            if (erase) counts->passed++;
        } else {
            sc_value_release(fv);
            if (rc == SC_OK) {
                maps[nerase] = (sc_atlas_ops_map){t->material, t->wrap_u, t->wrap_v, in[i], t->name};
                which[nerase++] = i;
            }
        }
    }
    if (seams_material >= 0) sc_seam_set_free(&seams);
    if (rc == SC_OK && nerase > 0) {
        sc_erase_options o = *eo;
        if (tangent && m == 0 && es->level0_gap > 0) o.gap_tolerance = fmax(o.gap_tolerance, es->level0_gap);
        rc = sc_atlas_ops_erase(mesh->as.mesh, maps, nerase, &o, es->threads, f32, native, err);
        if (rc == SC_OK) {
            counts->runs++;
            for (int i = 0; i < nerase; i++) {
                if (tangent && m == 0 && native[i] == in[which[i]]) counts->passed++;   /* kept as it is */
                /* a map the kernel passes through comes back as it went in */
                sc_value *fv = float_view(f32[i], es);
                sc_value_release(f32[i]);
                if (!fv) rc = sc_fail(err, SC_ENOMEM, "out of memory");
                chains[which[i]]->f32[m] = fv, chains[which[i]]->native[m] = native[i];
            }
        }
    }
    if (rc == SC_ENOMEM && m > 0)   /* e.g. a factor over CHOLMOD's size limit: charts under a texel */
        sc_error_prefix(err, "erase_seams at mip level %d (%dx%d; erase_min_size above this size keeps such levels "
                             "unerased)", m, in[0]->as.image->width, in[0]->as.image->height);
    else if (rc != SC_OK)
        sc_error_prefix(err, "erase_seams at mip level %d", m);
    free(maps), free(f32), free(native), free(which);
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

/* The report takes the buffer's bytes over (no copy: a mip file is tens of
 * megabytes); the buffer is left empty. */
static int add_buffer(sc_report *r, const char *path, sc_buf *b, sc_error *err) {
    void *data = b->data ? b->data : malloc(1);
    size_t len = b->len;
    sc_buf_init(b);
    if (!data || sc_report_add_file(r, path, data, len) != SC_OK) return sc_fail(err, SC_ENOMEM, "out of memory");
    return SC_OK;
}

/* The files of one chain, encoded into `files` (one buffer per file, the
 * paths alongside), apart from the report so that files encode side by
 * side. */
typedef struct chain_files {
    int n;
    char path[MAX_MIP][320];
    sc_buf buf[MAX_MIP];
    int rc[MAX_MIP];
    sc_error err[MAX_MIP];
} chain_files;

/* One file to encode: a PNG chain's level m, or a float chain's whole EXR
 * (m = -1), at out->path[i]; bytes, its size to schedule by. */
typedef struct file_item {
    chain *ch;
    chain_files *out;
    int m, i;
    size_t bytes;
} file_item;

static size_t pixel_bytes(const sc_image_data *im) {
    return (size_t)im->width * (size_t)im->height * (size_t)im->channels * (size_t)im->pixel;
}

static bool baked_map(const sc_texture *tex) {
    return strcmp(tex->name, "geometry_image") == 0 || strcmp(tex->name, "displacement") == 0;
}

/* Name chain ch's files in out and list them in items (appended at *n):
 * none when `which` leaves the chain out. */
static void list_files(chain *ch, const sc_mesh *mesh, const file_choice *which, chain_files *out,
                       file_item *items, int32_t *n) {
    char mat[96], slot[96], prefix[32] = "";
    clean_name(mesh->materials[ch->tex->material], mat, sizeof mat);
    clean_name(ch->tex->name, slot, sizeof slot);
    if (ch->source >= 0) snprintf(prefix, sizeof prefix, "lod%d_", ch->source);
    bool exr = ch->native[0]->as.image->pixel == SC_PIXEL_F32;
    bool chosen = which->any && (which->maps || !baked_map(ch->tex));
    int32_t from = exr ? 0 : which->from_level;
    out->n = !chosen ? 0 : exr ? 1 : ch->count > from ? ch->count - from : 0;
    for (int i = 0; i < out->n; i++) {
        sc_buf_init(&out->buf[i]);
        out->rc[i] = SC_OK;
        if (exr) snprintf(out->path[i], sizeof out->path[i], "mip/%s%s_%s.exr", prefix, mat, slot);
        else snprintf(out->path[i], sizeof out->path[i], "mip/%s%s_%s_level%d.png", prefix, mat, slot, from + i);
    }
    if (exr && out->n) {
        size_t bytes = 0;
        for (int m = 0; m < ch->count; m++) bytes += pixel_bytes(ch->native[m]->as.image);
        items[(*n)++] = (file_item){ch, out, -1, 0, bytes};
    } else {
        for (int i = 0; i < out->n; i++)
            items[(*n)++] = (file_item){ch, out, from + i, i, pixel_bytes(ch->native[from + i]->as.image)};
    }
}

static int encode_item(void *ud, int32_t i) {
    const file_item *it = (const file_item *)ud + i;
    const chain *ch = it->ch;
    int *rc = &it->out->rc[it->i];
    sc_error *err = &it->out->err[it->i];
    if (it->m >= 0) {
        *rc = sc_image_value_encode_png(ch->native[it->m], 0, &it->out->buf[it->i], err);
    } else {
        const sc_image_data *levels[MAX_MIP];
        for (int m = 0; m < ch->count; m++) levels[m] = ch->native[m]->as.image;
        *rc = sc_image_encode_exr_mip(levels, ch->count, &it->out->buf[it->i], err);
    }
    if (*rc != SC_OK) sc_error_prefix(err, "writing the chain of '%s'", ch->tex->name);
    return SC_OK;
}

static int larger_first(const void *a, const void *b) {
    const file_item *x = a, *y = b;
    if (x->bytes != y->bytes) return x->bytes < y->bytes ? 1 : -1;
    if (x->ch != y->ch) return x->ch < y->ch ? -1 : 1;
    return (x->m > y->m) - (x->m < y->m);
}

/* Every chain's files into the report, in chain order (the order groups
 * finish in does not show); frees the buffers. */
static int collect_files(sc_report *r, chain_files *out, int32_t nchains, sc_error *err) {
    int rc = r ? SC_OK : SC_ENOMEM;
    for (int32_t c = 0; c < nchains; c++)
        for (int i = 0; i < out[c].n; i++) {
            if (rc == SC_OK) rc = add_buffer(r, out[c].path[i], &out[c].buf[i], err);
            sc_buf_free(&out[c].buf[i]);
        }
    return rc;
}

/* The files of a repeated source under its own name: "mip/lod1_..." again
 * as "mip/lod2_..." (the report's files up to now are the chains'). */
static int repeat_files(sc_report *r, int32_t j, int32_t k, sc_error *err) {
    char from[32], to[32];
    snprintf(from, sizeof from, "mip/lod%d_", j);
    snprintf(to, sizeof to, "mip/lod%d_", k);
    return sc_report_copy_files(r, from, to) == SC_OK ? SC_OK : sc_fail(err, SC_ENOMEM, "out of memory");
}

/* ---------------------------------------------------------------- groups */

/* What one group did. */
typedef struct group_result {
    erase_counts counts;
    int rc;
    sc_error err;
    double seconds_erase, seconds_files;
} group_result;

/* What building the groups reads, and where each group puts what it made
 * (its chains' levels and files, and its result, are its own). */
typedef struct groups_job {
    chain *chains;
    int32_t nchains, nall, nsrc;
    const sc_atlas *const *src;
    sc_value *union_mesh;
    const erase_settings *es;
    chain_files *files;       /* per chain */
    group_result *results;    /* per group */
} groups_job;

/* Level m of group g's chains (members[0..n), their inputs beside), erased
 * on the group's mesh, but for tangent-space normal maps: each normal map
 * is judged once, at level 0 (sc_erase_takes_tangent_space, the node's
 * normal_space), and a tangent-space one is erased through its mesh's
 * frames in a call of its own. Its vectors are held in the frames of one
 * mesh, and the union's copies overlap in uv and would give a texel any
 * copy's frame: the shared chains' go through the first level's, the
 * finest of those that share them. */
static int erase_parts(groups_job *J, int32_t g, sc_value *mesh, chain **members, sc_value **inputs, int n,
                       int32_t m, group_result *res, sc_error *err) {
    const erase_settings *es = J->es;
    sc_value *frames_mesh = g == J->nsrc ? J->src[0]->mesh : mesh;
    int rc = SC_OK, k = 0;
    for (int i = 0; i < n && rc == SC_OK; i++) {
        chain *c = members[i];
        if (m == 0 && strcmp(c->tex->name, "normal") == 0)
            rc = sc_erase_takes_tangent_space(frames_mesh->as.mesh, c->tex, es->erase.normal_space, &c->tangent, err);
        if (!c->tangent) {   /* the others first */
            sc_value *v = inputs[i];
            members[i] = members[k], inputs[i] = inputs[k];
            members[k] = c, inputs[k] = v;
            k++;
        }
    }
    sc_erase_options others = es->erase, normals = es->erase;
    others.normal_space = SC_ERASE_NORMALS_OBJECT, normals.normal_space = SC_ERASE_NORMALS_TANGENT;
    if (rc == SC_OK && k > 0) rc = erase_level(mesh, members, inputs, k, m, false, &others, es, &res->counts, err);
    if (rc == SC_OK && k < n)
        rc = erase_level(frames_mesh, members + k, inputs + k, n - k, m, true, &normals, es, &res->counts, err);
    return rc;
}

/* Group `g`: its chains level by level, one erasure per level,
 * then their files. Work item 0 is the shared group (g = nsrc), the
 * largest (the union of every level's seams), so it starts first. */
static int build_group(void *ud, int32_t item) {
    groups_job *J = ud;
    const int32_t nsrc = J->nsrc, g = item == 0 ? nsrc : item - 1;
    const erase_settings *es = J->es;
    chain *chains = J->chains;
    group_result *res = &J->results[g];
    sc_error *err = &res->err;
    sc_value *mesh = g == nsrc ? J->union_mesh : J->src[g]->mesh;
    chain **members = calloc((size_t)J->nchains + 1, sizeof *members);
    sc_value **inputs = calloc((size_t)J->nchains + 1, sizeof *inputs);
    int rc = members && inputs ? SC_OK : sc_fail(err, SC_ENOMEM, "out of memory");
    double t_erase = 0;
    for (int32_t m = 0; m < J->nall && rc == SC_OK; m++) {
        int n = 0;
        for (int32_t c = 0; c < J->nchains && rc == SC_OK; c++) {
            chain *ch = &chains[c];
            if (ch->group != g || m >= ch->count) continue;
            sc_value *in = NULL;
            bool data = is_data_map(ch->tex);
            if (m == 0) {
                in = sc_value_retain(ch->tex->image);
                if (data) {
                    const sc_image_data *im = ch->tex->image->as.image;
                    ch->band = data_band0(mesh->as.mesh, ch->tex->material, im->width, im->height, ch->tex->wrap_u,
                                          ch->tex->wrap_v, DATA_BAND0, es->threads);
                    if (!ch->band) rc = sc_fail(err, SC_ENOMEM, "out of memory at mip level 0");
                }
            } else if (data) {
                sc_image_data *f = data_down(ch->f32[m - 1]->as.image, &ch->band);
                in = f ? sc_value_new_image(f) : NULL;
                if (!in) rc = sc_fail(err, SC_ENOMEM, "out of memory at mip level %d", m);
            } else {
                bool normal = strcmp(ch->tex->name, "normal") == 0;
                sc_image_data *f = box_down(ch->f32[m - 1]->as.image, normal);
                sc_pixel px = ch->tex->image->as.image->pixel;
                sc_image_data *q = NULL;   /* 8/16-bit colour is stored sRGB-encoded */
                if (f && px != SC_PIXEL_F32)
                    q = sc_image_quantize_threads(f, px,
                                                  f->colorspace == SC_COLOR_LINEAR ? SC_COLOR_SRGB : f->colorspace,
                                                  es->threads);
                if (q) sc_image_free(f), f = q;
                else if (px != SC_PIXEL_F32) sc_image_free(f), f = NULL;
                in = f ? sc_value_new_image(f) : NULL;
                if (!in) rc = sc_fail(err, SC_ENOMEM, "out of memory at mip level %d", m);
            }
            members[n] = ch, inputs[n] = in, n++;
        }
        if (rc == SC_OK && n > 0) {
            double t1 = sc_now();
            rc = erase_parts(J, g, mesh, members, inputs, n, m, res, err);
            t_erase += sc_now() - t1;
        }
        for (int i = 0; i < n; i++) sc_value_release(inputs[i]);
    }
    /* the files: every one of the group on its own, the largest first, side by side */
    double t1 = sc_now();
    int32_t nitems = 0, cap = 0;
    for (int32_t c = 0; c < J->nchains; c++) cap += chains[c].group == g ? MAX_MIP : 0;
    file_item *items = rc == SC_OK && cap > 0 ? calloc((size_t)cap, sizeof *items) : NULL;
    if (rc == SC_OK && cap > 0 && !items) rc = sc_fail(err, SC_ENOMEM, "out of memory");
    for (int32_t c = 0; c < J->nchains && items; c++)
        if (chains[c].group == g)
            list_files(&chains[c], J->src[chains[c].source >= 0 ? chains[c].source : 0]->mesh->as.mesh,
                       &es->files, &J->files[c], items, &nitems);
    if (items) {
        qsort(items, (size_t)nitems, sizeof *items, larger_first);
        if (sc_parallel(es->threads, nitems, encode_item, items) != SC_OK)
            for (int32_t i = 0; i < nitems; i++) encode_item(items, i);
        for (int32_t c = 0; c < J->nchains && rc == SC_OK; c++)   /* the first failure in chain order */
            for (int i = 0; chains[c].group == g && i < J->files[c].n && rc == SC_OK; i++)
                if (J->files[c].rc[i] != SC_OK) *err = J->files[c].err[i], rc = J->files[c].rc[i];
        free(items);
    }
    res->seconds_erase = t_erase, res->seconds_files = sc_now() - t1;
    free(members), free(inputs);
    return res->rc = rc;
}

/* ---------------------------------------------------------------- run */

static bool same_texture(const sc_texture *a, const sc_texture *b) {
    return a->material == b->material && strcmp(a->name, b->name) == 0 &&
           sc_digest_equal(sc_value_digest(a->image), sc_value_digest(b->image)) && a->wrap_u == b->wrap_u &&
           a->wrap_v == b->wrap_v;
}

/* What run's steps share: the sources, their chains and what they made. */
typedef struct mip_run {
    const sc_atlas **src;        /* the sources: each level of `lods`, or the atlas */
    int32_t nsrc;
    bool lods;                   /* the sources came as levels of detail */
    bool linear;                 /* filter_space linear: sRGB colour measured in linear light */
    chain *chains;               /* shared ones first (in level 0's texture order), then per source */
    int32_t nchains;
    int32_t *map;                /* (source, texture) -> chain + 1 */
    int32_t *first_tex;          /* source k's first entry in map */
    int32_t *repeats;            /* per source: the earlier source with the same atlas, or -1 */
    int32_t nmip, nall;          /* levels output (down to min_size), levels built (down to 1 x 1) */
    sc_value *union_mesh;        /* the erase mesh of the shared chains; NULL when none */
    chain_files *files;          /* per chain */
    erase_counts counts;
    double worst_energy, worst_gap;   /* over the sources, on the levels output */
    sc_report *report;
    sc_lods *out;
    double t_groups, t_erase, t_files, t_metrics;
} mip_run;

/* The sources, each with as many materials as level 0 (the last mismatch is the one reported). */
static int read_sources(mip_run *r, const sc_atlas *single, const sc_lods *lods, sc_error *err) {
    int rc = SC_OK;
    for (int32_t k = 0; k < r->nsrc; k++) {
        r->src[k] = lods ? lods->levels[k]->as.atlas : single;
        if (r->src[k]->mesh->as.mesh->nmat != r->src[0]->mesh->as.mesh->nmat)
            rc = sc_fail(err, SC_EINPUT, "lods: level %d has other materials than level 0", k);
    }
    return rc;
}

/* Room for a chain per texture of every source; false when out of memory. */
static bool alloc_chains(mip_run *r) {
    int32_t cap = 0;
    for (int32_t k = 0; k < r->nsrc; k++) cap += r->src[k]->ntex;
    r->chains = calloc((size_t)cap + 1, sizeof *r->chains);
    r->map = calloc((size_t)cap + 1, sizeof *r->map);
    r->first_tex = calloc((size_t)r->nsrc + 1, sizeof *r->first_tex);
    r->repeats = calloc((size_t)r->nsrc + 1, sizeof *r->repeats);
    return r->chains && r->map && r->first_tex && r->repeats;
}

/* The chains: a shared one for each texture of level 0 that every other
 * source has too (2 to 256 sources; in level 0's texture order), then one
 * per other texture of each source. A source whose atlas is an earlier
 * source's (by digest: a decimation that stopped repeats its mesh, and the
 * bake its maps) takes that source's chains. */
static void make_chains(mip_run *r, const sc_lods *lods) {
    const int32_t nsrc = r->nsrc;
    const sc_atlas **src = r->src;
    for (int32_t k = 1; k <= nsrc; k++) r->first_tex[k] = r->first_tex[k - 1] + src[k - 1]->ntex;
    for (int32_t t = 0; t < src[0]->ntex; t++) {
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
        r->chains[r->nchains] = (chain){.tex = tx, .group = nsrc, .source = -1};
        r->map[t] = r->nchains + 1;
        for (int32_t k = 1; k < nsrc; k++) r->map[r->first_tex[k] + idx[k]] = r->nchains + 1;
        r->nchains++;
    }
    for (int32_t k = 0; k < nsrc; k++) {
        int32_t j = -1;
        for (int32_t i = 0; lods && i < k && j < 0; i++)
            if (sc_digest_equal(sc_value_digest(lods->levels[i]), sc_value_digest(lods->levels[k]))) j = i;
        r->repeats[k] = j;
        for (int32_t t = 0; t < src[k]->ntex; t++) {
            if (r->map[r->first_tex[k] + t]) continue;
            if (j >= 0) {   /* the same texture list: j's chains, made already */
                r->map[r->first_tex[k] + t] = r->map[r->first_tex[j] + t];
                continue;
            }
            r->chains[r->nchains] = (chain){.tex = &src[k]->textures[t], .group = k, .source = r->lods ? k : -1};
            r->map[r->first_tex[k] + t] = ++r->nchains;
        }
    }
}

/* Each chain's length (down to 1 x 1), and the levels output and built. */
static void chain_lengths(mip_run *r, int32_t min_size) {
    r->nmip = 1, r->nall = 1;
    for (int32_t c = 0; c < r->nchains; c++) {
        const sc_image_data *im = r->chains[c].tex->image->as.image;
        int32_t w = im->width, h = im->height, n = 1, n_out = 0;
        while (true) {
            if (!n_out && w <= min_size && h <= min_size) n_out = n;
            if ((w == 1 && h == 1) || n == MAX_MIP) break;
            next_size(w, h, &w, &h), n++;
        }
        r->chains[c].count = n;
        if (!n_out) n_out = n;
        if (n_out > r->nmip) r->nmip = n_out;
        if (n > r->nall) r->nall = n;
    }
}

/* The erase mesh of the shared chains, when there are any: the union of the sources' meshes. */
static int make_union_mesh(mip_run *r, sc_error *err) {
    bool any_shared = r->nchains > 0 && r->chains[0].source < 0 && r->chains[0].group == r->nsrc;
    if (!any_shared) return SC_OK;
    const sc_value **ms = calloc((size_t)r->nsrc, sizeof *ms);
    for (int32_t k = 0; ms && k < r->nsrc; k++) ms[k] = r->src[k]->mesh;
    r->union_mesh = ms ? sc_atlas_ops_mesh_union_distinct(ms, r->nsrc) : NULL;
    free(ms);
    if (!r->union_mesh) return sc_fail(err, SC_ENOMEM, "out of memory for the union of the levels");
    return SC_OK;
}

/* Build, erase and encode the groups side by side (build_group); the
 * first failure in group order. */
static int erase_groups(mip_run *r, const erase_settings *es, group_result *results, sc_error *err) {
    const int32_t ngroups = r->nsrc + 1;
    int32_t busy = 0;   /* groups with chains: as many work side by side, each on every thread */
    for (int32_t g = 0; g < ngroups; g++) {
        bool any = false;
        for (int32_t c = 0; c < r->nchains && !any; c++) any = r->chains[c].group == g;
        busy += any;
    }
    groups_job gj = {r->chains, r->nchains, r->nall, r->nsrc, r->src, r->union_mesh, es, r->files, results};
    int prc = sc_parallel(es->threads < busy ? es->threads : busy, ngroups, build_group, &gj);
    int rc = SC_OK;
    for (int32_t g = 0; g < ngroups && rc == SC_OK; g++)
        if (results[g].rc != SC_OK) *err = results[g].err, rc = results[g].rc;
    if (rc == SC_OK && prc != SC_OK) rc = sc_fail(err, prc, "out of memory");
    for (int32_t g = 0; g < ngroups; g++) {
        const group_result *res = &results[g];
        r->counts.runs += res->counts.runs, r->counts.passed += res->counts.passed;
        r->counts.unerased += res->counts.unerased;
        r->t_erase += res->seconds_erase, r->t_files += res->seconds_files;
    }
    return rc;
}

/* Source k's seam energy and largest seam gap at every mip level built
 * (energy, gap: nall each, the largest over its textures). */
static int source_energies(const mip_run *r, int32_t k, int threads, double *energy, double *gap, sc_error *err) {
    const sc_atlas *s = r->src[k];
    const sc_mesh *mesh = s->mesh->as.mesh;
    int rc = SC_OK;
    for (int32_t mat = 0; mat < mesh->nmat && rc == SC_OK; mat++) {
        sc_seam_set seams;
        bool has = false;
        for (int32_t t = 0; t < s->ntex; t++) has |= s->textures[t].material == mat;
        if (!has) continue;
        rc = sc_seam_find(mesh, mat, &seams, err);
        if (rc != SC_OK) break;
        for (int32_t t = 0; t < s->ntex && rc == SC_OK; t++) {
            if (s->textures[t].material != mat) continue;
            const chain *ch = &r->chains[r->map[r->first_tex[k] + t] - 1];
            for (int32_t m = 0; m < ch->count && rc == SC_OK; m++) {
                const sc_image_data *im = ch->native[m]->as.image;
                sc_seam_grid g = {im->width, im->height, ch->tex->wrap_u, ch->tex->wrap_v};
                double e = 0, gp = 0;
                /* measured as filtered: sRGB colour decoded to linear light in linear mode */
                rc = sc_seam_energies_decoded(mesh, &seams, &g, &im, &r->linear, 1, threads, &e, &gp, err);
                energy[m] = fmax(energy[m], e), gap[m] = fmax(gap[m], gp);
            }
        }
        sc_seam_set_free(&seams);
    }
    return rc;
}

/* Metrics: the seam energy and largest gap of every source at every mip
 * level (into the report too), and their worst on the levels output. */
static int measure_levels(sc_ctx *ctx, mip_run *r, int threads, sc_error *err) {
    int rc = SC_OK;
    for (int32_t k = 0; k < r->nsrc && rc == SC_OK; k++) {
        double *energy = calloc((size_t)r->nall, sizeof *energy), *gap = calloc((size_t)r->nall, sizeof *gap);
        if (!energy || !gap) rc = sc_fail(err, SC_ENOMEM, "out of memory");
        if (rc == SC_OK) rc = source_energies(r, k, threads, energy, gap, err);
        for (int32_t m = 0; m < r->nall && rc == SC_OK; m++) {
            char name[96], pre[24] = "";
            if (r->lods) snprintf(pre, sizeof pre, "lod%d.", k);
            snprintf(name, sizeof name, "%slevel%d.seam_energy", pre, m);
            sc_ctx_metric(ctx, name, energy[m]);   /* every level built, also below min_size */
            if (sc_report_metric(r->report, name, energy[m]) != SC_OK) rc = sc_fail(err, SC_ENOMEM, "out of memory");
            snprintf(name, sizeof name, "%slevel%d.max_seam_gap", pre, m);
            sc_ctx_metric(ctx, name, gap[m]);
            if (sc_report_metric(r->report, name, gap[m]) != SC_OK) rc = sc_fail(err, SC_ENOMEM, "out of memory");
            if (m < r->nmip)
                r->worst_energy = fmax(r->worst_energy, energy[m]), r->worst_gap = fmax(r->worst_gap, gap[m]);
        }
        free(energy), free(gap);
    }
    return rc;
}

/* The node's totals: levels, chains, erase runs and the worst seams. */
static int report_totals(sc_ctx *ctx, const mip_run *r, sc_error *err) {
    sc_ctx_metric(ctx, "levels", r->nmip);
    sc_ctx_metric(ctx, "chains", r->nchains);
    sc_ctx_metric(ctx, "erase_runs", r->counts.runs);
    sc_ctx_metric(ctx, "level0_passed", r->counts.passed);
    sc_ctx_metric(ctx, "levels_not_erased", r->counts.unerased);
    if (r->counts.unerased > 0)
        sc_ctx_warn(ctx, "%d map levels below erase_min_size are averaged but not erased: their seams stay "
                         "(worst seam gap over all levels %.3g)", r->counts.unerased, r->worst_gap);
    sc_ctx_metric(ctx, "seam_energy", r->worst_energy);
    sc_ctx_metric(ctx, "max_seam_gap", r->worst_gap);
    if (sc_report_metric(r->report, "levels", r->nmip) || sc_report_metric(r->report, "seam_energy", r->worst_energy) ||
        sc_report_metric(r->report, "max_seam_gap", r->worst_gap))
        return sc_fail(err, SC_ENOMEM, "out of memory");
    return SC_OK;
}

/* The output levels into r->out: source k at mip level m at entry
 * k * nmip + m, a chain shorter than that repeating its last level. */
static int add_levels(mip_run *r, sc_error *err) {
    int rc = SC_OK;
    for (int32_t k = 0; k < r->nsrc && rc == SC_OK; k++)
        for (int32_t m = 0; m < r->nmip && rc == SC_OK; m++) {
            const sc_atlas *s = r->src[k];
            sc_atlas *a = sc_atlas_new(sc_value_retain(s->mesh));
            rc = a ? sc_atlas_copy_materials(a, s) : SC_ENOMEM;
            for (int32_t t = 0; a && t < s->ntex && rc == SC_OK; t++) {
                const sc_texture *tx = &s->textures[t];
                const chain *ch = &r->chains[r->map[r->first_tex[k] + t] - 1];
                int32_t lm = m < ch->count ? m : ch->count - 1;
                rc = sc_atlas_add_texture(a, tx->name, tx->material, tx->wrap_u, tx->wrap_v, tx->source,
                                          sc_value_retain(ch->native[lm]));
            }
            sc_value *v = rc == SC_OK ? sc_value_new_atlas(a) : NULL;
            if (rc != SC_OK) sc_atlas_free(a);
            if (!v || sc_lods_add(r->out, v) != SC_OK) rc = sc_fail(err, SC_ENOMEM, "out of memory");
        }
    return rc;
}

/* The outputs (the levels and the report, taken from r) and the timings. */
static int set_outputs(sc_ctx *ctx, mip_run *r, sc_error *err) {
    sc_value *lv = sc_value_new_lods(r->out);
    r->out = NULL;
    sc_value *rv = sc_value_new_report(r->report);
    r->report = NULL;
    if (!lv || !rv) {
        sc_value_release(lv), sc_value_release(rv);
        return sc_fail(err, SC_ENOMEM, "out of memory");
    }
    sc_ctx_set_output(ctx, "levels", lv);
    sc_ctx_set_output(ctx, "report", rv);
    sc_ctx_metric(ctx, "seconds_groups", r->t_groups);   /* building, erasing, encoding: groups side by side */
    sc_ctx_metric(ctx, "seconds_erase", r->t_erase);     /* in the erase kernel, summed over the groups */
    sc_ctx_metric(ctx, "seconds_files", r->t_files);     /* encoding, summed over the groups */
    sc_ctx_metric(ctx, "seconds_metrics", r->t_metrics);
    return SC_OK;
}

/* Frees what r still holds: the outputs not handed over, the chains' levels, the sources. */
static void mip_run_free(mip_run *r) {
    sc_lods_free(r->out);
    sc_report_free(r->report);
    for (int32_t c = 0; r->chains && c < r->nchains; c++) free(r->chains[c].band);
    for (int32_t c = 0; r->chains && c < r->nchains; c++)
        for (int m = 0; m < MAX_MIP; m++)
            sc_value_release(r->chains[c].native[m]), sc_value_release(r->chains[c].f32[m]);
    sc_value_release(r->union_mesh);
    free(r->chains), free(r->map), free(r->first_tex), free(r->repeats), free(r->src);
}

static int run(sc_ctx *ctx, sc_error *err) {
    const sc_atlas *single = sc_ctx_atlas(ctx, "atlas");
    const sc_lods *lods = sc_ctx_lods(ctx, "lods");
    if (!single && !lods) return sc_fail(err, SC_EINPUT, "atlas: connect `atlas` or `lods`");
    if (single && lods) return sc_fail(err, SC_EINPUT, "lods: connect `atlas` or `lods`, not both");
    const int32_t nsrc = lods ? lods->count : 1;
    if (nsrc < 1) return sc_fail(err, SC_EINPUT, "lods: the list is empty");
    const int32_t min_size = (int32_t)sc_ctx_integer(ctx, "min_size");
    const int threads = sc_ctx_threads(ctx);
    erase_settings es = {(int32_t)sc_ctx_integer(ctx, "erase_min_size"), sc_ctx_number(ctx, "gap_tolerance"),
                         sc_ctx_number(ctx, "level0_gap"), .threads = threads};
    sc_erase_defaults(&es.erase);
    es.erase.w_seam = sc_ctx_number(ctx, "w_seam");
    es.erase.filter_space = sc_erase_filter_space_named(sc_ctx_string(ctx, "filter_space"));
    es.erase.gap_tolerance = es.gap_tolerance;
    const char *files = sc_ctx_string(ctx, "files");
    es.files = (file_choice){strcmp(files, "none") != 0, strcmp(files, "all") == 0,
                             (int32_t)sc_ctx_integer(ctx, "files_from_level")};
    mip_run r = {.nsrc = nsrc, .lods = lods != NULL, .linear = es.erase.filter_space == SC_ERASE_FILTER_LINEAR};
    r.src = calloc((size_t)nsrc, sizeof *r.src);
    if (!r.src) return sc_fail(err, SC_ENOMEM, "out of memory");
    int rc = read_sources(&r, single, lods, err);
    if (rc == SC_OK) es.erase.normal_space = sc_erase_normal_space_of(sc_ctx_string(ctx, "normal_space"), r.src[0]);

    /* the chains, and the erase meshes: each source's own, and the union for shared chains */
    if (!alloc_chains(&r)) rc = sc_fail(err, SC_ENOMEM, "out of memory");
    if (rc == SC_OK) {
        make_chains(&r, lods);
        chain_lengths(&r, min_size);
        rc = make_union_mesh(&r, err);
    }

    /* build, erase and encode the groups, side by side */
    double t0 = sc_now();
    r.files = calloc((size_t)r.nchains + 1, sizeof *r.files);
    group_result *results = calloc((size_t)nsrc + 1, sizeof *results);
    if (!r.files || !results) rc = sc_fail(err, SC_ENOMEM, "out of memory");
    if (rc == SC_OK) rc = erase_groups(&r, &es, results, err);
    free(results);
    r.t_groups = sc_now() - t0;

    /* metrics: seam energy of every LOD at every mip level */
    t0 = sc_now();
    r.report = rc == SC_OK ? sc_report_new() : NULL;
    if (rc == SC_OK && !r.report) rc = sc_fail(err, SC_ENOMEM, "out of memory");
    if (rc == SC_OK) rc = measure_levels(ctx, &r, threads, err);
    if (rc == SC_OK) rc = report_totals(ctx, &r, err);
    r.t_metrics = sc_now() - t0;

    /* the files, in chain order, and the levels */
    if (r.files) {
        /* frees the buffers either way */
        int frc = collect_files(rc == SC_OK ? r.report : NULL, r.files, r.nchains, err);
        if (rc == SC_OK) rc = frc;
        for (int32_t k = 0; k < nsrc && rc == SC_OK; k++)
            if (r.repeats[k] >= 0) rc = repeat_files(r.report, r.repeats[k], k, err);
        free(r.files);
        r.files = NULL;
    }
    r.out = rc == SC_OK ? sc_lods_new() : NULL;
    if (rc == SC_OK && !r.out) rc = sc_fail(err, SC_ENOMEM, "out of memory");
    if (rc == SC_OK) rc = add_levels(&r, err);
    if (rc == SC_OK) rc = set_outputs(ctx, &r, err);
    mip_run_free(&r);
    return rc;
}

static const char *const filter_space_choices[] = {"linear", "encoded", NULL};
static const char *const normal_space_choices[] = {"auto", "tangent", "object", NULL};
static const char *const files_choices[] = {"all", "textures", "none", NULL};

static const sc_param_desc params[] = {
    {.name = "filter_space", .type = SC_PARAM_ENUM, .def_string = "linear", .choices = filter_space_choices,
     .doc = SC_ERASE_FILTER_SPACE_DOC},
    {.name = "normal_space", .type = SC_PARAM_ENUM, .def_string = "auto", .choices = normal_space_choices,
     .doc = SC_ERASE_NORMAL_SPACE_DOC},
    {.name = "min_size", .type = SC_PARAM_INTEGER, .def = 1, .min = 1, .max = 32768,
     .doc = "the chain stops once both sides are at most this many texels"},
    {.name = "gap_tolerance", .type = SC_PARAM_NUMBER, .def = 0, .min = 0, .max = 1,
     .doc = "erase_seams's gap_tolerance: a level whose seam gaps are within it is kept as it is"},
    {.name = "level0_gap", .type = SC_PARAM_NUMBER, .def = 1e-5, .min = 0, .max = 1,
     .doc = "level 0 of a chain is kept as it is when its largest seam gap is within this fraction of its "
            "largest magnitude (float) or one step (8/16-bit): seams already erased; 0 erases every level 0"},
    {.name = "erase_min_size", .type = SC_PARAM_INTEGER, .def = 1, .min = 1, .max = 32768,
     .doc = "levels whose sides are both below this are averaged but not erased (reported as not erased): for "
            "atlases whose charts fall under a texel there, where an exact erasure can outgrow memory"},
    {.name = "w_seam", .type = SC_PARAM_NUMBER, .def = 1e12, .min = 0, .max = 1e30,
     .doc = "erase_seams's w_seam on every level: the seam stiffness against the grid terms"},
    {.name = "files", .type = SC_PARAM_ENUM, .def_string = "all", .choices = files_choices,
     .doc = "the chains written as files: all; textures (not the baked geometry_image and displacement maps, "
            "which a renderer without tessellation does not read); none (the levels only)"},
    {.name = "files_from_level", .type = SC_PARAM_INTEGER, .def = 0, .min = 0, .max = MAX_MIP,
     .doc = "the first level of a PNG chain written (1: level 0 is the texture save writes); an EXR file holds "
            "its whole chain"},
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

static const sc_kernel *const kernels[] = {&sc_kernel_atlas_ops, &sc_kernel_imageio, &sc_kernel_seam, NULL};

const sc_node_desc sc_node_mipmap = {
    .type = "mipmap",
    .version = 15,
    .summary = "mip chains with seams erased on every level independently (Liu et al. 2017 §9)",
    .inputs = inputs,
    .ninputs = SC_COUNT(inputs),
    .outputs = outputs,
    .noutputs = SC_COUNT(outputs),
    .params = params,
    .nparams = SC_COUNT(params),
    .run = run,
    .kernels = kernels,
};
