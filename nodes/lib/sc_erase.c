/* sc_erase.c - seam erasure (Liu et al. 2017, §3-4; the interface is
 * sc_erase.h): the kernel every node that erases calls. erase_seams wraps it
 * as a node; straighten erases the textures it warps; bake_displacement and
 * mipmap erase their maps through sc_atlas_ops_erase. None of them runs
 * another node: they call sc_erase, and list sc_kernel_erase (directly or
 * through sc_kernel_atlas_ops), so SC_ERASE_VERSION re-keys them all.
 *
 * Design note.
 *
 * What is solved. For each texture, the texels p minimise
 *     w_change E_change + w_grad_in E_grad_in + w_c1 E_C1 + w_grad_out E_grad_out
 *   + [w_lerp E_lerp] + [w_outside E_outside] + w_seam p^T M' p
 * where M is the exact seam operator normalised as in eq. 9 (sc_seam.c builds
 * M, E_C1, E_lerp and E_outside in closed form over the texel-grid pieces of
 * every edge; the reported seam energies are p^T M p). The unknowns are the
 * texels of the bilinear cells that uv silhouette edges (both sides of every
 * seam, surface boundaries, uv foldovers) pass through; every other texel is
 * fixed. Texels whose centre lies inside a uv triangle of the material
 * (top-left rule) are "inside" (T_in), the others "outside":
 *   E_change   = 1/|T_in| sum_{i in T_in} |p_i - p0_i|^2  (|T_in|: all inside
 *                texels of the texture, as the paper writes it)
 *   E_grad_in  = sum over grid edges with both texels inside of
 *                |(p_a - p_b) - (p0_a - p0_b)|^2
 *   E_grad_out = sum over grid edges with an outside unknown texel whose
 *                other texel is inside or unknown, of |p_a - p_b|^2 (outside
 *                texels beyond the unknowns are unreliable and left out)
 * Grid neighbours follow the wrap mode (repeat wraps; clamp and mirror stop
 * at the border). Derivatives in E_C1 and the grid are per texel, so the
 * weights mean the same at every resolution. A Tikhonov floor of
 * 1e-8 |p - p0|^2 on every unknown keeps components without an inside texel
 * (zero-area charts) well posed.
 *
 * The seam penalty. Eq. 9 makes M an average over the seams, so its size per
 * texel falls with the total seam length in texels, while the grid terms
 * stay ~1 per texel: with the paper's w_seam = 1e10 on M itself the
 * constraint is too soft on an atlas of many long seams. So the penalty uses
 * M' = M / mean(diag M over the seam texels): w_seam is the seam stiffness of
 * a texel against the per-texel grid terms, whatever the seam count or
 * texture size. A direct solve of the penalised system keeps its accuracy
 * there (Cholesky's backward error, ~1e-16 * 1e10, stays far below the grid
 * stiffness).
 *
 * Solving. Q d = r for the correction d = x - p0, with r = -1/2 grad E(p0)
 * taken term by term (seam differences formed before they are weighted), so
 * a seam-free, constant or otherwise optimal p0 gives d = 0 exactly and
 * untouched texels keep their exact bits. One factorisation serves every
 * channel of every texture of one material that shares its size and wrap
 * modes; a slot holding an image already erased for this material reuses
 * the result. (An image shared by two materials is erased once per
 * material.) Right-hand-side columns equal to an earlier one (grey images
 * stored as RGB) are solved once and copied.
 *
 * One factorisation of all of Q (solver cholmod): CHOLMOD with the AMD
 * ordering, supernodal. The factorisation runs on one thread while
 * everything that needs only the seams (the textures' residuals, the rows
 * rounding reads, the nullity) runs beside it; both are independent tasks,
 * so results do not depend on the thread count. The side work uses every
 * thread, which with the factorisation's makes more threads than cores: it
 * runs behind, at a lower priority (sc_run_beside), so the factorisation,
 * the longer path, keeps its core.
 *
 * Building the system. Q is kept in its full pattern (both triangles) only:
 * the edge-cluster solver reads its rows, its refinement multiplies by it and
 * the 8-bit rounding reads M = Q / w_pen from its seam rows, so no upper
 * triangle is kept beside it. sc_seam_assemble's chunks keep their
 * triplet lists (sc_triplet_parts: no copy into one list), and
 * sc_sparse_full_from_triplet_parts assembles them straight into the full
 * pattern, reserving the grid terms' entries (grid_pattern) as zeros;
 * grid_terms then adds every unknown's own terms to its own row (column),
 * so rows are filled on all threads with no two writing one entry. The
 * edge-cluster solver's groups (schur_groups, serial) are found while Q is
 * assembled. Fresh memory is a large part of the cost, which is why
 * sc_alloc_array maps large blocks in one call (sc_base.h).
 *
 * The edge-cluster solver (`solver` schur, sc_schur.h; `auto`, the default,
 * takes it from schur_from unknowns, SC_ERASE_SCHUR_FROM). Seam edges join
 * end to end into chains where two of them go on in the same two charts (on
 * real atlases most seam vertices are corners of three or more charts). The
 * texels that only one chain's cells reach form that chain's cluster, ordered
 * along it; texels shared by two chains' cells, or coupled to another chain's
 * texels (or to their own chain's more than SCHUR_KEY_SPAN texels further
 * along it), form the interface. Chains, not single edges, are the clusters:
 * with single edges the texels around every seam vertex would be interface.
 * Grid couplings between texels of different charts that happen to lie side
 * by side in the atlas would join far-apart parts of the interface: the
 * factored matrix A is Q less those terms, whole (so it stays positive
 * definite; grid_terms lists them while it assembles Q), with each cluster
 * eliminated on its own and the interface factored by CHOLMOD. The texels
 * those terms join are made interface unknowns, so that Q and A differ on
 * the interface alone, and conjugate gradients take the terms back in there
 * (sc_schur_solve_terms: iterations on the interface unknowns only, then one
 * round of refinement on Q's own residual), to a residual of 1e-12 of the
 * start in A^-1's norm (auto falls back to one CHOLMOD factorisation should
 * that fail). Those terms are few, but kept in A they would fill the
 * interface factor many times over; the iterations cost far less. Below
 * schur_from one factorisation is as fast and simpler. Where most texels
 * lie in the cells of two or more chains (a geometry image erased on a mesh
 * and its levels in one uv) there are no clusters, and `auto` factors Q
 * itself.
 *
 * Memory. The preconditioner is made in Q in place (each dropped grid
 * coupling's four entries saved, zeroed, and put back after the
 * factorisation; sc_schur reads exact zeros as no coupling). The seam
 * energies of the float and naively rounded results are measured while the
 * optimal rounding runs.
 *
 * Weights. The paper's values are the defaults (w_seam 1e10, w_grad_in =
 * w_grad_out = 1, w_c1 = w_lerp = w_outside = 1e2); erase_seams's `preset`
 * sets w_change: local 1e4, global 1e2. E_lerp and E_outside are optional
 * (o->lerp, o->outside): E_outside trusts the original texels along the
 * silhouettes; E_lerp pulls each silhouette edge towards the linear
 * interpolation of per-vertex values, taken as the mean of the texture's
 * samples at all wedges of each vertex.
 *
 * Passing through. A texture whose material has no seam edge, or whose
 * largest sampled seam gap is within o->gap_tolerance (default 1e-4) or one
 * step of its 8/16-bit encoding (a tangent-space normal map: measured in
 * object space, where rounding opens sqrt(3) steps), is passed on as the
 * same value (its native result rounded to native_like's type where that
 * is another); when every result is the input's own image, sc_erase_result_atlas
 * returns the input atlas itself.
 * This is what makes a re-run on an erased texture change nothing: the
 * penalty leaves near-null directions of M (relative eigenvalues ~1e-10)
 * partly free, and a forced second solve would keep easing them.
 *
 * Signals. Solving is in double, in the space the texture's consumers
 * filter it: with o->filter_space linear (the default) an sRGB colour
 * texture is erased as linear light, from a linear f32 copy (GL and Vulkan
 * sRGB formats decode before they filter, and glTF, Unity and Unreal sample
 * base colour so); encoded erases the stored values, for engines that
 * filter those. Data textures are erased as stored. The result holds, per
 * texture, an f32 image (same channels and format tag; linear colour is
 * tagged linear) and the same texture in the input's own pixel type and
 * encoding: 8/16-bit inputs are quantised once, with o->quantize naive
 * (round to nearest) or optimal (8-bit: the rounding direction of every
 * seam texel is chosen by coordinate descent on the quantised seam energy
 * q^T M q, M applied to the values the consumer filters (linear light for
 * sRGB colour in linear mode), each byte staying within one step of its
 * float value; 16-bit inputs round to nearest). Every energy and gap of a
 * quantised result is measured on its bytes decoded as the consumer does.
 *
 * Tangent-space normal maps (o->normal_space; the paper's footnote 3 leaves
 * them) are erased in object space: the map is converted texel by texel
 * with the MikkTSpace frame of the texel's face (sc_tangent.h), that field
 * is erased as a float data map by the same method, and converted back with
 * the same frames and rounded to nearest. A frame changes inside a texel's
 * footprint, so the result is continuous up to that change: the metrics give
 * the gap of the reconstructed normal on the bytes written, before and after,
 * and `tangent_space_discontinuous` flags a map left beyond
 * SC_ERASE_NORMAL_GAP_LIMIT.
 *
 * Shared texels. Texels whose centre lies in two or more uv triangles of the
 * material (mirrored or overlapping charts, foldovers) are counted and
 * reported; every seam is still erased, those texels being single unknowns
 * that every seam through them constrains.
 *
 * Determinism. Assembly emits triplets in a fixed order for any thread count,
 * sums them in that order on any thread count, and then each unknown adds
 * its grid terms to its own row in the order of its links; the channels of
 * the rounding are independent (a channel equal to an earlier one at every
 * seam texel, floats and bytes, copies its rounding);
 * the rounding revisits only texels whose gradient changed, which makes the
 * same choices in the same order as full sweeps; CHOLMOD is deterministic.
 *
 * Measurements behind these choices: docs/notes/erase_seams.md.
 */
#include <float.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "sc_erase.h"
#include "sc_schur.h"
#include "sc_seam.h"
#include "sc_sparse.h"
#include "sc_tangent.h"

#define TIKHONOV 1e-8
#define FLOOR_RETRY 1e-12         /* a refused factorisation retries with this share of the largest diagonal added */
#define NULLITY_MAX_TEXELS 100000
#define ROUND_MAX_SWEEPS 64
#define ROUND_ROWS_PER_CHUNK 16384
#define SCHUR_MAX_SHARED 0.5      /* solver auto: CHOLMOD when more than this fraction of the unknowns is in no chain's cluster */
#define SCHUR_KEY_SPAN 256.0      /* texels along a seam chain that one cluster's couplings may span */
#define PCG_TOLERANCE 1e-12         /* preconditioned residual, relative to the start */


typedef struct options {
    double w_change, w_seam, w_grad_in, w_c1, w_grad_out, w_lerp, w_outside;
    bool lerp, outside;
    sc_erase_normal_space normal_space;
    double gap_tolerance;
    sc_erase_quantize quantize;
    sc_erase_filter_space filter_space;
    const sc_image_data *const *native_like;   /* per texture, or NULL */
    sc_erase_solver solver;
    int64_t schur_from;       /* solver auto: the edge-cluster solver from this many unknowns */
    int32_t pcg_iterations;   /* the most conjugate-gradient iterations */
    const char *textures;     /* slots to erase, or "all" */
    const bool *inputs_private;   /* per texture, or NULL (sc_erase_options) */
    int threads;
} options;

/* What happens to one texture of the atlas. */
typedef enum tex_fate {
    FATE_KEEP = 0,        /* not selected, or no seams: passed through */
    FATE_ERASE = 1,       /* erased (possibly as a duplicate of another slot) */
    FATE_TANGENT = 2,     /* tangent-space normal map: erased in object space */
    FATE_CLEAN = 3,       /* seams already within the tolerance: passed through */
} tex_fate;

typedef struct tex_state {
    tex_fate fate;
    int32_t same_as;      /* an earlier texture with the same image value, or -1 */
    bool writable;        /* its float image is this call's alone: the solution is written into it */
    sc_value *f32, *native;
    double energy_before, gap_before;
    char prefix[160];
} tex_state;

/* Sums over the whole atlas. */
typedef struct totals {
    double seam_edges, silhouette_edges, unknowns, shared_texels;
    double energy_before, energy_after, gap_before, gap_after;
    double energy_u8_naive, energy_u8_optimal, gap_u8;
    bool any_u8, any_optimal;
    double max_change_in;
    double nullity;
    bool nullity_all;
    double seconds_build, seconds_factor, seconds_solve, seconds_quantize, seconds_nullity;
    double solver_peak_mb, factor_nnz, factor_flops;
    double schur_groups, interface_unknowns, pcg_iterations, solver_fallbacks;
    int factorizations, erased, unchanged, tangent;
} totals;

static void metric(sc_metric_list *ml, const char *prefix, const char *name, double v) {
    char full[256];
    snprintf(full, sizeof full, "%s%s", prefix, name);
    sc_metric_list_add(ml, full, v);
}

/* ---------------------------------------------------------------- grid terms */

/* A grid edge from an unknown texel to one of its four neighbours that
 * carries a term of E_grad_in or E_grad_out. */
typedef struct grid_link {
    int32_t texel, index;   /* the neighbour, and its unknown index (-1: fixed) */
    double w;
    bool keep_gradient;     /* E_grad_in (the original gradient) or E_grad_out (zero) */
    bool other_end;         /* between two unknowns, and met first from the other one */
} grid_link;

/* The grid links of texel t (inside: t is covered), neighbours in the order
 * right, up, left, down, following the wrap modes; returns their count. */
static int grid_links(const sc_seam_grid *g, const sc_seam_texset *unk, const sc_seam_texset *covered,
                      const options *o, int32_t t, bool inside, grid_link out[4]) {
    static const int di[4] = {1, 0, -1, 0}, dj[4] = {0, 1, 0, -1};
    const int32_t W = g->width, H = g->height, i = t % W, j = t / W;
    int count = 0;
    for (int d = 0; d < 4; d++) {
        int64_t ii = (int64_t)i + di[d], jj = (int64_t)j + dj[d];
        if (ii < 0 || ii >= W) {
            if (g->wrap_u != SC_WRAP_REPEAT) continue;
            ii = sc_seam_wrap(ii, W, SC_WRAP_REPEAT);
        }
        if (jj < 0 || jj >= H) {
            if (g->wrap_v != SC_WRAP_REPEAT) continue;
            jj = sc_seam_wrap(jj, H, SC_WRAP_REPEAT);
        }
        int32_t nb = (int32_t)jj * W + (int32_t)ii;
        if (nb == t) continue;
        int32_t r2 = sc_seam_texset_index(unk, nb);
        bool nb_inside = sc_seam_texset_has(covered, nb);
        grid_link *l = &out[count];
        if (inside && nb_inside) {
            l->w = o->w_grad_in, l->keep_gradient = true;
        } else if ((!inside && (nb_inside || r2 >= 0)) || (inside && r2 >= 0)) {
            l->w = o->w_grad_out, l->keep_gradient = false;
        } else {
            continue; /* an unreliable outside texel beyond the unknowns */
        }
        if (l->w == 0) continue;
        l->texel = nb, l->index = r2;
        l->other_end = d >= 2 && r2 >= 0;
        count++;
    }
    return count;
}

/* Grid work in fixed chunks of unknowns, each unknown from its own row:
 * the same results on any thread count. */
#define GRID_ROWS_PER_CHUNK 16384

typedef struct grid_job {
    const sc_seam_grid *g;
    const sc_seam_texset *unk, *covered;
    const int32_t *ids;
    const options *o;
    int32_t n;
    /* the pattern: per unknown its count (pass 0), then its sorted rows */
    int32_t *start, *rows;
    int pass;
    /* the terms */
    double w_change_texel;
    sc_sparse *q;
    const sc_image_data *p0;
    double *rhs;
    const int32_t *chart;
    sc_triplets *apart;   /* one list per chunk */
} grid_job;

static int grid_pattern_chunk(void *ud, int32_t chunk) {
    grid_job *job = ud;
    int32_t r0 = chunk * GRID_ROWS_PER_CHUNK, r1 = r0 + GRID_ROWS_PER_CHUNK;
    if (r1 > job->n) r1 = job->n;
    for (int32_t r = r0; r < r1; r++) {
        grid_link links[4];
        int nl = grid_links(job->g, job->unk, job->covered, job->o, job->ids[r],
                            sc_seam_texset_has(job->covered, job->ids[r]), links);
        if (job->pass == 0) {
            int32_t count = 1;
            for (int k = 0; k < nl; k++) count += links[k].index >= 0;
            job->start[r + 1] = count;
            continue;
        }
        int32_t *rows = job->rows + job->start[r], at = 0;
        rows[at++] = r;
        for (int k = 0; k < nl; k++) {
            int32_t x = links[k].index;
            if (x < 0) continue;
            int32_t b = at++;   /* insertion sort: at most five */
            while (b > 0 && rows[b - 1] > x) rows[b] = rows[b - 1], b--;
            rows[b] = x;
        }
    }
    return SC_OK;
}

/* The entries the grid terms add to Q's full pattern: row (= column) r holds
 * its diagonal and its unknown neighbours, (*rows)[(*start)[r] ..
 * (*start)[r + 1]), sorted (a neighbour reached twice through a wrap is
 * listed twice). */
static int grid_pattern(const sc_seam_grid *g, const sc_seam_texset *unk, const int32_t *ids,
                        const sc_seam_texset *covered, const options *o, int32_t **start, int32_t **rows,
                        sc_error *err) {
    const int32_t n = unk->count, chunks = (n + GRID_ROWS_PER_CHUNK - 1) / GRID_ROWS_PER_CHUNK;
    grid_job job = {.g = g, .unk = unk, .covered = covered, .ids = ids, .o = o, .n = n};
    job.start = sc_alloc_array((size_t)n + 1, sizeof *job.start);
    int rc = job.start ? sc_parallel(o->threads, chunks, grid_pattern_chunk, &job) : SC_ENOMEM;
    if (rc == SC_OK) {
        job.start[0] = 0;
        for (int32_t r = 0; r < n; r++) job.start[r + 1] += job.start[r];
        job.rows = sc_alloc_array((size_t)job.start[n] + 1, sizeof *job.rows);
        job.pass = 1;
        rc = job.rows ? sc_parallel(o->threads, chunks, grid_pattern_chunk, &job) : SC_ENOMEM;
    }
    if (rc) {
        free(job.start), free(job.rows);
        return sc_fail(err, SC_ENOMEM, "out of memory for the grid terms of %d unknowns", (int)n);
    }
    *start = job.start, *rows = job.rows;
    return SC_OK;
}

/* Entry (i, j) of Q (full pattern; grid_pattern stored it). */
static double *entry(sc_sparse *q, int32_t i, int32_t j) { return &q->val[sc_sparse_find(q, i, j)]; }

static int grid_terms_chunk(void *ud, int32_t chunk) {
    grid_job *job = ud;
    const int32_t n = job->n, C = job->p0 ? job->p0->channels : 0;
    int32_t r0 = chunk * GRID_ROWS_PER_CHUNK, r1 = r0 + GRID_ROWS_PER_CHUNK;
    if (r1 > n) r1 = n;
    sc_triplets *apart = job->apart ? &job->apart[chunk] : NULL;
    for (int32_t r = r0; r < r1; r++) {
        int32_t t = job->ids[r];
        bool inside = sc_seam_texset_has(job->covered, t);
        grid_link links[4];
        int nl = grid_links(job->g, job->unk, job->covered, job->o, t, inside, links);
        double *diag = job->q ? entry(job->q, r, r) : NULL;
        if (diag) *diag += TIKHONOV + (inside ? job->w_change_texel : 0);
        for (int k = 0; k < nl; k++) {
            const grid_link *l = &links[k];
            int32_t r2 = l->index;
            double w = l->w;
            if (diag) {
                *diag += w;
                if (r2 >= 0) *entry(job->q, r2, r) += -w;   /* row r2 of column r */
            }
            if (apart && r2 >= 0 && !l->other_end && job->chart[r] >= 0 && job->chart[r2] >= 0 &&
                job->chart[r] != job->chart[r2])
                sc_triplets_add(apart, r, r2, w);
            if (job->rhs && !l->keep_gradient)
                for (int32_t c = 0; c < C; c++)
                    job->rhs[(size_t)c * n + r] -=
                        w * (sc_seam_texel(job->p0, t, c) - sc_seam_texel(job->p0, l->texel, c));
        }
        if (apart && apart->failed) return SC_ENOMEM;
    }
    return SC_OK;
}

/* The per-texel terms: E_change, the Tikhonov floor, E_grad_in and
 * E_grad_out, each unknown's from its own row (a link between two unknowns
 * is met from both ends, each adding its half: w to its diagonal and -w to
 * the pair, or its side of the gradient to its residual). With q (Q's seam
 * terms, assembled in the full pattern with grid_pattern's entries), they
 * are added to it; with p0 and rhs (n x C, one column per channel), the
 * residual -1/2 grad E at p0 is: only E_grad_out is not minimal there. With
 * chart, every coupling of unknowns of two different charts (side by side
 * in the atlas) is also listed in apart_out, once, from the end that meets
 * it first. */
static int grid_terms(const sc_seam_grid *g, const sc_seam_texset *unk, const int32_t *ids,
                      const sc_seam_texset *covered, const options *o, int threads, double w_change_texel,
                      sc_sparse *q, const sc_image_data *p0, double *rhs, const int32_t *chart,
                      sc_triplets *apart_out, sc_error *err) {
    const int32_t n = unk->count, chunks = (n + GRID_ROWS_PER_CHUNK - 1) / GRID_ROWS_PER_CHUNK;
    grid_job job = {.g = g, .unk = unk, .covered = covered, .ids = ids, .o = o, .n = n,
                    .w_change_texel = w_change_texel, .q = q, .p0 = p0, .rhs = rhs, .chart = chart};
    if (chart && apart_out) {
        job.apart = sc_calloc_array((size_t)chunks + 1, sizeof *job.apart);
        if (!job.apart) return sc_fail(err, SC_ENOMEM, "out of memory");
        for (int32_t c = 0; c < chunks; c++) sc_triplets_init(&job.apart[c], n);
    }
    int rc = sc_parallel(threads, chunks, grid_terms_chunk, &job);
    for (int32_t c = 0; job.apart && c < chunks; c++) {
        if (rc == SC_OK) sc_triplets_append(apart_out, &job.apart[c]);
        sc_triplets_free(&job.apart[c]);
    }
    free(job.apart);
    if (rc == SC_OK && apart_out && apart_out->failed) rc = SC_ENOMEM;
    return rc ? sc_fail(err, SC_ENOMEM, "out of memory for the grid terms of %d unknowns", (int)n) : SC_OK;
}

/* ---------------------------------------------------------------- E_lerp targets */

/* Per-vertex values: the mean of the texture's samples at every wedge of the
 * vertex in this material. */
static double *vertex_values(const sc_mesh *m, int32_t material, const sc_seam_grid *g,
                             const sc_image_data *img) {
    int32_t C = img->channels;
    double *vv = sc_calloc_array((size_t)m->nv * (size_t)C, sizeof *vv);
    int32_t *cnt = sc_calloc_array((size_t)m->nv, sizeof *cnt);
    if (!vv || !cnt) {
        free(vv), free(cnt);
        return NULL;
    }
    for (int32_t f = 0; f < m->nf; f++) {
        if (m->FM[f] != material) continue;
        for (int k = 0; k < 3; k++) {
            int32_t v = m->FV[3 * f + k];
            const double *uv = &m->U[2 * m->FU[3 * f + k]];
            int32_t id[4];
            double w[4];
            sc_seam_taps(g, uv[0], uv[1], id, w);
            for (int32_t c = 0; c < C; c++) {
                double s = 0;
                for (int q = 0; q < 4; q++) s += w[q] * sc_seam_texel(img, id[q], c);
                vv[(size_t)v * C + c] += s;
            }
            cnt[v]++;
        }
    }
    for (int32_t v = 0; v < m->nv; v++)
        if (cnt[v] > 1)
            for (int32_t c = 0; c < C; c++) vv[(size_t)v * C + c] /= cnt[v];
    free(cnt);
    return vv;
}

/* ---------------------------------------------------------------- 8-bit rounding */

typedef struct round_job {
    const sc_sparse *mf;     /* full symmetric M over rows that include the seam texels */
    const uint8_t *rows;     /* the rows that are seam texels (1), or NULL: every row */
    const int32_t *ids;      /* texel id of each row */
    const float *x;          /* float solution image */
    uint8_t *bytes;          /* quantised image, changed in place */
    int32_t channels;
    const int32_t *chan;     /* the channel of each chunk */
    int threads;             /* for each channel's start (fewer channels than threads) */
    /* sRGB colour in linear light: x is linear, each byte k stands for
     * 255 sc_srgb_to_linear(k / 255) (value[k]) in channels where srgb[c];
     * elsewhere x is the stored value and byte k stands for k */
    const double *value;
    bool srgb[4];
} round_job;

static inline double round_value(const round_job *job, int32_t c, int32_t q) {
    return job->value && job->srgb[c] ? job->value[q] : (double)q;
}

static inline bool round_row(const round_job *job, int32_t k) { return !job->rows || job->rows[k]; }

/* Channels c with the same float values and bytes as an earlier channel at
 * every seam texel round the same way: src[c] names that channel (or -1). */
static int32_t round_unique_channels(const round_job *job, int32_t *src, int32_t *chan) {
    int32_t n = job->mf->n, C = job->channels, nu = 0;
    for (int32_t c = 0; c < C; c++) {
        src[c] = -1;
        for (int32_t e = 0; e < c && src[c] < 0; e++) {
            if (src[e] >= 0 || (job->value && job->srgb[c]) != (job->value && job->srgb[e])) continue;
            bool same = true;
            for (int32_t k = 0; k < n && same; k++) {
                if (!round_row(job, k)) continue;
                size_t at = (size_t)job->ids[k] * (size_t)C;
                same = job->x[at + c] == job->x[at + e] && job->bytes[at + c] == job->bytes[at + e];
            }
            if (same) src[c] = e;
        }
        if (src[c] < 0) chan[nu++] = c;
    }
    return nu;
}

/* A channel's start, in fixed chunks of rows: its bounds and first choice
 * (pass 0), then the gradient g = M q and M's diagonal (pass 1), row by
 * row: M's full pattern holds row i as column i, and summing its entries
 * in column order is the order a column sweep adds them to g[i] in. */
typedef struct round_start {
    const round_job *job;
    int32_t c;
    int32_t *q, *lo, *hi;
    double *g, *dg;
    uint8_t *dirty;
    int pass;
} round_start;

static int round_start_chunk(void *ud, int32_t chunk) {
    const round_start *rs = ud;
    const round_job *job = rs->job;
    const sc_sparse *mf = job->mf;
    const int32_t C = job->channels, c = rs->c;
    int32_t k0 = chunk * ROUND_ROWS_PER_CHUNK;
    int32_t k1 = k0 + ROUND_ROWS_PER_CHUNK < mf->n ? k0 + ROUND_ROWS_PER_CHUNK : mf->n;
    int32_t *q = rs->q, *lo = rs->lo, *hi = rs->hi;
    for (int32_t k = k0; k < k1; k++) {
        if (!round_row(job, k)) {
            if (rs->pass == 0) q[k] = lo[k] = hi[k] = 0;
            else rs->g[k] = rs->dg[k] = 0, rs->dirty[k] = 0;
            continue;
        }
        if (rs->pass == 0) {
            size_t at = (size_t)job->ids[k] * (size_t)C + (size_t)c;
            double x = (job->value && job->srgb[c] ? sc_linear_to_srgb(job->x[at]) : job->x[at]) * 255.0;
            if (!(x > 0)) x = 0;
            if (x > 255) x = 255;
            int32_t f = (int32_t)floor(x);
            lo[k] = f, hi[k] = f < 255 ? f + 1 : 255;
            if ((double)f == x) hi[k] = f; /* exact: nothing to choose */
            q[k] = job->bytes[at];
            if (q[k] < lo[k] || q[k] > hi[k]) q[k] = (int32_t)lrint(x);
            continue;
        }
        double s = 0, d = 0;
        for (int32_t p = mf->colptr[k]; p < mf->colptr[k + 1]; p++) {
            int32_t j = mf->rowind[p];
            if (!round_row(job, j)) continue;
            s += mf->val[p] * round_value(job, c, q[j]);
            if (j == k) d = mf->val[p];
        }
        rs->g[k] = s, rs->dg[k] = d;
        /* a texel is looked at again only when its gradient changed since
         * it was last looked at (otherwise the test gives the same "stay"):
         * the same choices, in the same order, as full sweeps */
        rs->dirty[k] = lo[k] != hi[k];
    }
    return SC_OK;
}

/* Greedy coordinate descent on q^T M q over q_k in {floor(255 x_k), +1}
 * (rows that are not seam texels take no part). */
static int round_channel(void *ud, int32_t chunk) {
    round_job *job = ud;
    int32_t c = job->chan[chunk];
    const sc_sparse *mf = job->mf;
    int32_t n = mf->n, C = job->channels;
    int32_t *q = sc_alloc_array((size_t)n, sizeof *q), *lo = sc_alloc_array((size_t)n, sizeof *lo);
    int32_t *hi = sc_alloc_array((size_t)n, sizeof *hi);
    double *g = sc_alloc_array((size_t)n, sizeof *g), *dg = sc_alloc_array((size_t)n, sizeof *dg);
    uint8_t *dirty = sc_alloc_array((size_t)n, sizeof *dirty);
    if (!q || !lo || !hi || !g || !dg || !dirty) {
        free(q), free(lo), free(hi), free(g), free(dg), free(dirty);
        return SC_ENOMEM;
    }
    round_start rs = {job, c, q, lo, hi, g, dg, dirty, 0};
    int32_t chunks = (n + ROUND_ROWS_PER_CHUNK - 1) / ROUND_ROWS_PER_CHUNK;
    int rc = sc_parallel(job->threads, chunks, round_start_chunk, &rs);
    rs.pass = 1;
    if (rc == SC_OK) rc = sc_parallel(job->threads, chunks, round_start_chunk, &rs);
    if (rc != SC_OK) {   /* sc_parallel ran nothing: out of memory */
        free(q), free(lo), free(hi), free(g), free(dg), free(dirty);
        return SC_ENOMEM;
    }
    for (int sweep = 0; sweep < ROUND_MAX_SWEEPS; sweep++) {
        int64_t moved = 0;
        for (int32_t k = 0; k < n; k++) {
            if (!dirty[k]) continue;
            dirty[k] = 0;
            int32_t alt = q[k] == lo[k] ? hi[k] : lo[k];
            double d = round_value(job, c, alt) - round_value(job, c, q[k]);
            double de = 2.0 * d * g[k] + d * d * dg[k];
            if (!(de < -1e-13 * dg[k])) continue;
            q[k] = alt;
            dirty[k] = 1;
            for (int32_t p = mf->colptr[k]; p < mf->colptr[k + 1]; p++) {
                int32_t i = mf->rowind[p];
                if (!round_row(job, i)) continue;
                g[i] += d * mf->val[p];
                dirty[i] = lo[i] != hi[i];
            }
            moved++;
        }
        if (!moved) break;
    }
    for (int32_t k = 0; k < n; k++)
        if (round_row(job, k)) job->bytes[(size_t)job->ids[k] * (size_t)C + (size_t)c] = (uint8_t)q[k];
    free(q), free(lo), free(hi), free(g), free(dg), free(dirty);
    return SC_OK;
}

/* The measurements after a solve, side by side with the optimal rounding:
 * task 0 takes the seam energy of the float result and of the naive
 * rounding, task 1 makes the optimal rounding (its channels on all
 * threads) and takes its energy. */
typedef struct measure_job {
    const sc_mesh *m;
    const sc_seam_set *seams;
    const sc_seam_grid *g;
    int threads;
    const sc_image_data *f32, *naive;  /* naive: NULL when not quantised */
    const sc_image_data *optimal;      /* the optimal rounding's image (round's bytes) */
    bool decode;                       /* measure naive and optimal as the consumer decodes them (linear light) */
    round_job *round;                  /* NULL: no optimal rounding */
    int32_t *src, *chan;               /* per channel: the channel it copies, or -1; the channels rounded */
    int threads_energy;
    double e_float, g_float, e_naive, g_naive, e_optimal, g_optimal;
    int rc[2];
    sc_error err[2];
} measure_job;

static int measure_task(void *ud, int32_t chunk) {
    measure_job *j = ud;
    if (chunk == 0) {
        const sc_image_data *imgs[2] = {j->f32, j->naive};
        const bool decode[2] = {false, j->decode};
        double e[2] = {0, 0}, gap[2] = {0, 0};
        j->rc[0] = sc_seam_energies_decoded(j->m, j->seams, j->g, imgs, decode, j->naive ? 2 : 1, j->threads_energy,
                                            e, gap, &j->err[0]);
        j->e_float = e[0], j->g_float = gap[0], j->e_naive = e[1], j->g_naive = gap[1];
        return j->rc[0];
    }
    round_job *rj = j->round;
    int32_t C = rj->channels;
    int32_t nu = round_unique_channels(rj, j->src, j->chan);
    rj->threads = nu < j->threads ? j->threads : 1;
    int rc = sc_seam_parallel(j->threads, nu, round_channel, rj);
    for (int32_t c = 0; c < C && rc == SC_OK; c++)
        if (j->src[c] >= 0)
            for (int32_t s2 = 0; s2 < rj->mf->n; s2++) {
                if (!round_row(rj, s2)) continue;
                uint8_t *b = rj->bytes + (size_t)rj->ids[s2] * C;
                b[c] = b[j->src[c]];
            }
    if (rc) return j->rc[1] = sc_fail(&j->err[1], rc, "out of memory rounding to 8 bits");
    j->rc[1] = sc_seam_energies_decoded(j->m, j->seams, j->g, &j->optimal, &j->decode, 1, j->threads,
                                        &j->e_optimal, &j->g_optimal, &j->err[1]);
    return j->rc[1];
}

/* ---------------------------------------------------------------- one group */

/* Textures of one material sharing size and wrap modes: one system. */
typedef struct group {
    int32_t material;
    sc_seam_grid grid;
    int32_t ntex;
    int32_t *tex;
} group;

typedef struct group_work {
    sc_seam_coverage cov;
    sc_seam_texset unk, seamset;
    int32_t *ids, *seam_ids;
    int32_t nseam_texels;
    /* Q in its full pattern: the edge-cluster solver's factored matrix is
     * made in it, its refinement multiplies by it, and 8-bit rounding then
     * reads M = Q / w_pen from the rows marked in round_rows */
    sc_sparse q, msub, mfull;
    uint8_t *round_rows;
    sc_sparse_chol *chol;
    /* the edge-cluster solver (solver schur): Q without the grid couplings
     * between charts (apart: row, column, weight), factored by sc_schur,
     * the couplings taken back in by its iterations on the interface */
    bool use_schur, fallback;   /* fallback: solver auto went to CHOLMOD */
    sc_triplets apart;
    int32_t *group;
    double *gamma;
    sc_schur *schur;
    sc_schur_pcg_result pcg;
    double *rhs;
    double **vv;
} group_work;

static void group_work_free(group_work *w, int32_t ntex) {
    sc_seam_coverage_free(&w->cov);
    sc_seam_texset_free(&w->unk);
    sc_seam_texset_free(&w->seamset);
    free(w->ids), free(w->seam_ids);
    sc_sparse_free(&w->q);
    sc_sparse_free(&w->msub);
    sc_sparse_free(&w->mfull);
    free(w->round_rows);
    sc_sparse_chol_free(w->chol);
    sc_triplets_free(&w->apart);
    free(w->group), free(w->gamma);
    sc_schur_free(w->schur);
    free(w->rhs);
    if (w->vv)
        for (int32_t k = 0; k < ntex; k++) free(w->vv[k]);
    free(w->vv);
}

static bool is_normal_slot(const char *name) { return strcmp(name, "normal") == 0; }

/* A cheap look at a normal map: tangent-space maps sit near (0.5, 0.5, 1). */
static bool looks_tangent_space(const sc_image_data *img) {
    if (img->channels < 3) return false;
    int64_t n = (int64_t)img->width * img->height;
    int64_t step = n > 262144 ? n / 262144 : 1;
    double s[3] = {0, 0, 0};
    int64_t cnt = 0;
    for (int64_t t = 0; t < n; t += step, cnt++)
        for (int c = 0; c < 3; c++) s[c] += sc_seam_texel(img, (int32_t)t, c);
    for (int c = 0; c < 3; c++) s[c] /= (double)(cnt ? cnt : 1);
    return s[2] > 0.7 && fabs(s[0] - 0.5) < 0.15 && fabs(s[1] - 0.5) < 0.15;
}

/* What the tasks that build and factor the system share (read-only). */
typedef struct prep_ctx {
    const sc_mesh *m;
    const sc_seam_set *seams, *seams_only;
    const sc_seam_grid *g;
    const sc_texture *textures;
    const group *gr;
    const options *o;
    group_work *w;
    const sc_seam_terms *qterms;
    double w_pen, w_change_texel;
} prep_ctx;

typedef struct prep_job {
    prep_ctx ctx;
    bool want_round, want_nullity;
    int rc_factor, rc_side;
    sc_error err_factor, err_side;
    double nullity;
    double seconds_nullity, seconds_round_prep;
} prep_job;

/* The preconditioner's matrix is Q less each listed coupling term
 * w (p_r - p_r2)^2 (both diagonals and the pair): it is made in place in
 * Q's full pattern, and the couplings that end at exactly zero join no
 * cluster to another (sc_schur reads stored zeros as no coupling). The
 * values it overwrites are kept in `saved` (4 per term) and put back, last
 * term first, by preconditioner_restore: Q keeps its exact bits. */
static void term_entries(const sc_sparse *full, const sc_triplets *apart, size_t k, int64_t at[4]) {
    int32_t r = apart->row[k], r2 = apart->col[k];
    at[0] = sc_sparse_find(full, r, r), at[1] = sc_sparse_find(full, r2, r2);
    at[2] = sc_sparse_find(full, r2, r), at[3] = sc_sparse_find(full, r, r2);
    if (at[0] < 0 || at[1] < 0 || at[2] < 0 || at[3] < 0) at[0] = -1;   /* assembled with Q: never */
}

static int preconditioner_apply(sc_sparse *full, const sc_triplets *apart, double **saved, sc_error *err) {
    *saved = sc_alloc_array(4 * apart->count + 1, sizeof **saved);
    if (!*saved) return sc_fail(err, SC_ENOMEM, "out of memory");
    for (size_t k = 0; k < apart->count; k++) {
        double w = apart->val[k];
        int64_t at[4];
        term_entries(full, apart, k, at);
        if (at[0] < 0) continue;
        for (int i = 0; i < 4; i++) (*saved)[4 * k + i] = full->val[at[i]];
        full->val[at[0]] -= w, full->val[at[1]] -= w, full->val[at[2]] += w, full->val[at[3]] += w;
    }
    return SC_OK;
}

static void preconditioner_restore(sc_sparse *full, const sc_triplets *apart, const double *saved) {
    for (size_t k = apart->count; k-- > 0;) {
        int64_t at[4];
        term_entries(full, apart, k, at);
        if (at[0] < 0) continue;
        for (int i = 0; i < 4; i++) full->val[at[i]] = saved[4 * k + i];
    }
}

/* Factor Q with CHOLMOD (AMD). The Tikhonov floor keeps Q positive
 * definite in exact arithmetic, but beside a seam stiffness of 1e12 (mipmap)
 * it is below Q's rounding: a level whose few texels all lie on seams (a 2 x 2
 * level of hundreds of charts) can stop the factorisation. Then the factor
 * is made once more of Q plus FLOOR_RETRY times its largest diagonal entry
 * on the diagonal (counted as a solver fallback); every later use of Q
 * (refinement, rounding) still reads Q itself. */
static int factor_q(group_work *w, sc_error *err) {
    sc_sparse_options sopt = {.ordering = SC_SPARSE_ORDER_AMD, .kind = SC_SPARSE_AUTO};
    int rc = sc_sparse_chol_factor(&w->q, &sopt, &w->chol, err);
    if (rc != SC_EINPUT) return rc;
    sc_sparse shifted = w->q;
    shifted.val = malloc((size_t)w->q.nnz * sizeof *shifted.val);
    if (!shifted.val) return sc_fail(err, SC_ENOMEM, "out of memory");
    memcpy(shifted.val, w->q.val, (size_t)w->q.nnz * sizeof *shifted.val);
    double dmax = 0;
    for (int32_t j = 0; j < w->q.n; j++) dmax = fmax(dmax, sc_sparse_diag(&w->q, j));
    for (int32_t j = 0; j < w->q.n; j++) {
        int64_t at = sc_sparse_find(&w->q, j, j);
        if (at >= 0) shifted.val[at] += FLOOR_RETRY * dmax;
    }
    rc = sc_sparse_chol_factor(&shifted, &sopt, &w->chol, err);
    free(shifted.val);
    if (rc == SC_OK) w->fallback = true;
    return rc;
}

/* Task 0: analyse and factor Q (supernodal where the factor is big,
 * simplicial where it is tiny), or, for the edge-cluster solver, its
 * interface (prep_clusters did the rest). */
static int prep_factor(prep_job *pj) {
    group_work *w = pj->ctx.w;
    if (w->use_schur) {
        if (pj->rc_factor == SC_OK) pj->rc_factor = sc_schur_factor_interface(w->schur, &pj->err_factor);
        if (pj->rc_factor != SC_OK && pj->ctx.o->solver == SC_ERASE_SOLVER_AUTO) {   /* CHOLMOD instead */
            sc_schur_free(w->schur);
            w->schur = NULL;
            w->fallback = true;
            pj->rc_factor = factor_q(w, &pj->err_factor);
        }
    } else {
        pj->rc_factor = factor_q(w, &pj->err_factor);
    }
    return pj->rc_factor;
}

/* Before the two tasks, on all threads: the edge-cluster solver's clusters
 * and S, which read Q made the factored matrix in place (and put back
 * after); its failure is task 0's to handle. */
static void prep_clusters(prep_job *pj) {
    group_work *w = pj->ctx.w;
    double *saved = NULL;
    pj->rc_factor = preconditioner_apply(&w->q, &w->apart, &saved, &pj->err_factor);
    if (pj->rc_factor == SC_OK)
        pj->rc_factor = sc_schur_factor_clusters(&w->q, w->group, w->gamma, SCHUR_KEY_SPAN, pj->ctx.o->threads,
                                                 &w->schur, &pj->err_factor);
    if (saved) preconditioner_restore(&w->q, &w->apart, saved);
    free(saved);
}

/* The channels that copy no earlier one (same: sc_seam_same_channels) into
 * keep, in order; returns how many. */
static int32_t kept_channels(const int32_t *same, int32_t channels, int32_t keep[SC_SEAM_MAX_CHANNELS]) {
    int32_t nu = 0;
    for (int32_t c = 0; c < channels; c++)
        if (same[c] < 0) keep[nu++] = c;
    return nu;
}

/* Those channels of img as an image of their own; NULL when out of memory. */
static sc_image_data *unique_channels(const sc_image_data *img, const int32_t *same) {
    int32_t keep[SC_SEAM_MAX_CHANNELS], nu = kept_channels(same, img->channels, keep);
    sc_image_data *u = sc_image_alloc(img->width, img->height, nu, img->pixel);
    if (!u) return NULL;
    const size_t texels = (size_t)img->width * (size_t)img->height, bytes = (size_t)img->pixel;
    const uint8_t *src = img->pixels;
    uint8_t *dst = u->pixels;
    for (size_t t = 0; t < texels; t++)
        for (int32_t j = 0; j < nu; j++)
            memcpy(dst + (t * (size_t)nu + (size_t)j) * bytes,
                   src + (t * (size_t)img->channels + (size_t)keep[j]) * bytes, bytes);
    return u;
}

/* Right-hand sides made for unique_channels' image (its channels in the
 * first columns of rhs, n rows each) spread to all `channels` columns. */
static void spread_columns(double *rhs, int32_t n, int32_t channels, const int32_t *same) {
    int32_t keep[SC_SEAM_MAX_CHANNELS], nu = kept_channels(same, channels, keep);
    for (int32_t j = nu - 1; j >= 0; j--)
        if (keep[j] != j) memcpy(rhs + (size_t)keep[j] * n, rhs + (size_t)j * n, (size_t)n * sizeof *rhs);
    for (int32_t c = 0; c < channels; c++)
        if (same[c] >= 0) memcpy(rhs + (size_t)c * n, rhs + (size_t)same[c] * n, (size_t)n * sizeof *rhs);
}

/* Task 1: the textures' residuals, the rows of M for rounding,
 * and the nullity of M. It does not read Q, which task 0 changes in place. */
static int prep_side(prep_job *pj) {
    const prep_ctx *c = &pj->ctx;
    group_work *w = c->w;
    sc_error *err = &pj->err_side;
    const int32_t n = w->unk.count;
    /* all threads, even beside the edge-cluster solver's interface
     * factorisation (one thread): with seam chains as its clusters, the
     * interface is small and this is the longer task on large atlases */
    const int threads = c->o->threads;
    int rc = SC_OK;
    double t0 = sc_now();
    if (pj->want_round && !pj->want_nullity) {
        /* for rounding, M on the seam texels is Q / w_pen there: the other
         * terms are ~1e-10 of it and only nudge the greedy choices. Rounding
         * reads the rows of seam texels of Q's full pattern. */
        w->round_rows = sc_alloc_array((size_t)n + 1, sizeof *w->round_rows);
        if (!w->round_rows) return pj->rc_side = sc_fail(err, SC_ENOMEM, "out of memory");
        for (int32_t r = 0; r < n; r++) w->round_rows[r] = sc_seam_texset_has(&w->seamset, w->ids[r]);
    }
    double t1 = sc_now();

    /* the residual r = -1/2 grad E at p0 of every texture (here, off the
     * factorisation's path); the solve gives d = x - p0, so texels that
     * need no change keep their exact value */
    for (int32_t k = 0, col = 0; k < c->gr->ntex; k++) {
        const sc_image_data *img = c->textures[c->gr->tex[k]].image->as.image;
        double *rhs = w->rhs + (size_t)col * n;
        /* channels that copy an earlier one (a grey image stored as RGB)
         * take that channel's residual: one channel's work, the same bits */
        int32_t same[SC_SEAM_MAX_CHANNELS];
        sc_image_data *uniq = NULL;
        if (!w->vv[k] && img->channels <= SC_SEAM_MAX_CHANNELS && sc_seam_same_channels(img, same) < img->channels)
            uniq = unique_channels(img, same);
        sc_seam_terms rterms = *c->qterms;
        rterms.p0 = uniq ? uniq : img;
        rterms.vertex_values = w->vv[k];
        rterms.rhs = rhs;
        if ((rc = sc_seam_assemble(c->m, c->seams, c->g, &w->unk, &rterms, threads, NULL, err))) {
            sc_image_free(uniq);
            return pj->rc_side = rc;
        }
        grid_terms(c->g, &w->unk, w->ids, &w->cov.covered, c->o, threads, c->w_change_texel, NULL, rterms.p0, rhs,
                   NULL, NULL, NULL);
        if (uniq) spread_columns(rhs, n, img->channels, same);
        sc_image_free(uniq);
        col += img->channels;
    }
    double t2 = sc_now();

    /* M on the seam texels (the texels of cells seam edges pass through) */
    w->nseam_texels = w->seamset.count;
    if (sc_seam_texset_members(&w->seamset, &w->seam_ids))
        return pj->rc_side = sc_fail(err, SC_ENOMEM, "out of memory");
    if (pj->want_nullity) {
        /* M (eq. 9) alone, exactly, over the seam texels */
        sc_triplet_parts t;
        sc_triplet_parts_init(&t, w->seamset.count);
        sc_seam_terms mterms = {.w_seam = 1.0};
        rc = sc_seam_assemble(c->m, c->seams_only, c->g, &w->seamset, &mterms, c->o->threads, &t, err);
        if (rc == SC_OK) rc = sc_sparse_from_triplet_parts(&t, 1, &w->msub, err);
        sc_triplet_parts_free(&t);
        if (rc) return pj->rc_side = rc;
    }
    if (pj->want_nullity && w->msub.n > 0) {
        /* numerical nullity as numpy's matrix_rank counts it: eigenvalues
         * below n eps |M| (|M| bounded by the largest row sum) */
        double tol = sc_sparse_norm_bound(&w->msub) * (double)w->msub.n * DBL_EPSILON;
        int64_t below = 0;
        if (sc_sparse_count_eigs_below(&w->msub, tol, &below, NULL) == SC_OK) pj->nullity = (double)below;
    }
    double t3 = sc_now();
    if (pj->want_round && pj->want_nullity && (rc = sc_sparse_full(&w->msub, &w->mfull, err))) return pj->rc_side = rc;
    sc_sparse_free(&w->msub);
    double t4 = sc_now();
    pj->seconds_nullity = t3 - t2;
    pj->seconds_round_prep = (t1 - t0) + (t4 - t3);
    return SC_OK;
}

static void prep_front(void *ud) { prep_factor(ud); }
static void prep_back(void *ud) { prep_side(ud); }

/* Solve Q X = B for the columns of rhs (n x ncols, overwritten by X). A
 * column equal to an earlier one (a grey image stored as RGB, the same image
 * in two slots) is solved once and copied. */
static int solve_unique(group_work *w, const options *o, int32_t n, int32_t ncols, double *rhs, sc_error *err) {
    int32_t *src = sc_alloc_array((size_t)ncols, sizeof *src);
    if (!src) return sc_fail(err, SC_ENOMEM, "out of memory");
    int32_t nu = 0;
    for (int32_t c = 0; c < ncols; c++) {
        src[c] = -1;
        for (int32_t e = 0; e < c && src[c] < 0; e++)
            if (src[e] < 0 && memcmp(rhs + (size_t)e * n, rhs + (size_t)c * n, (size_t)n * sizeof *rhs) == 0)
                src[c] = e;
        if (src[c] < 0) {
            if (nu != c) memcpy(rhs + (size_t)nu * n, rhs + (size_t)c * n, (size_t)n * sizeof *rhs);
            nu++;
        }
    }
    int rc = SC_OK;
    bool direct = w->schur == NULL;
    if (w->schur) {
        /* solver auto keeps the right-hand sides, to go to CHOLMOD should
         * the iterations not converge */
        double *kept = o->solver == SC_ERASE_SOLVER_AUTO ? sc_alloc_array((size_t)n * (size_t)nu, sizeof *kept) : NULL;
        if (kept) memcpy(kept, rhs, (size_t)n * (size_t)nu * sizeof *rhs);
        rc = sc_schur_solve_terms(w->schur, &w->q, &w->apart, nu, rhs, PCG_TOLERANCE, o->pcg_iterations, &w->pcg, err);
        if (rc == SC_EINPUT && kept) {
            sc_schur_free(w->schur);
            w->schur = NULL;
            w->fallback = true;
            memcpy(rhs, kept, (size_t)n * (size_t)nu * sizeof *rhs);
            rc = factor_q(w, err);
            direct = rc == SC_OK;
        }
        free(kept);
    }
    if (direct) rc = sc_sparse_chol_solve(w->chol, nu, rhs, err);
    if (rc == SC_OK && nu < ncols) {
        /* spread the solved columns back to their places, last first */
        int32_t *slot = sc_alloc_array((size_t)ncols, sizeof *slot);
        if (!slot) {
            free(src);
            return sc_fail(err, SC_ENOMEM, "out of memory");
        }
        for (int32_t c = 0, u = 0; c < ncols; c++) slot[c] = src[c] < 0 ? u++ : -1;
        for (int32_t c = ncols - 1; c >= 0; c--)
            if (src[c] < 0 && slot[c] != c)
                memcpy(rhs + (size_t)c * n, rhs + (size_t)slot[c] * n, (size_t)n * sizeof *rhs);
        for (int32_t c = 0; c < ncols; c++)
            if (src[c] >= 0) memcpy(rhs + (size_t)c * n, rhs + (size_t)src[c] * n, (size_t)n * sizeof *rhs);
        free(slot);
    }
    free(src);
    return rc;
}

/* Q (full pattern) from the seam terms, with room for the grid terms
 * (task 0), and the edge-cluster solver's groups (task 1): independent. */
typedef struct build_job {
    const prep_ctx *ctx;
    int rc[2];
    sc_error err[2];
} build_job;

static int schur_groups(const sc_mesh *m, const sc_seam_set *seams, const sc_seam_grid *g, group_work *w,
                        sc_error *err);

static int build_task(void *ud, int32_t task) {
    build_job *bj = ud;
    const prep_ctx *c = bj->ctx;
    group_work *w = c->w;
    sc_error *err = &bj->err[task];
    if (task == 1) return bj->rc[1] = schur_groups(c->m, c->seams, c->g, w, err);
    sc_triplet_parts trip;
    sc_triplet_parts_init(&trip, w->unk.count);
    int rc = sc_seam_assemble(c->m, c->seams, c->g, &w->unk, c->qterms, c->o->threads, &trip, err);
    int32_t *grid_start = NULL, *grid_rows = NULL;
    if (rc == SC_OK) rc = grid_pattern(c->g, &w->unk, w->ids, &w->cov.covered, c->o, &grid_start, &grid_rows, err);
    if (rc == SC_OK) rc = sc_sparse_full_from_triplet_parts(&trip, grid_start, grid_rows, c->o->threads, &w->q, err);
    free(grid_start), free(grid_rows);
    sc_triplet_parts_free(&trip);
    return bj->rc[0] = rc;
}

/* For the edge-cluster solver: per unknown, its seam chain (w->group[r],
 * -1 when cells of several chains reach it), its place along the chain
 * (w->gamma[r]) and, in w->group + n, the chart (a connected piece of the
 * parameter mesh) of the face whose piece reaches it first. */
static int schur_groups(const sc_mesh *m, const sc_seam_set *seams, const sc_seam_grid *g, group_work *w,
                        sc_error *err) {
    const int32_t n = w->unk.count;
    w->group = sc_alloc_array(2 * (size_t)n + 1, sizeof *w->group);
    w->gamma = sc_alloc_array((size_t)n + 1, sizeof *w->gamma);
    int32_t *parent = sc_alloc_array((size_t)m->nu + 1, sizeof *parent);
    if (!w->group || !w->gamma || !parent) {
        free(parent);
        return sc_fail(err, SC_ENOMEM, "out of memory for %d unknowns", (int)n);
    }
    int32_t *chart = w->group + n;   /* first the face, then its chart */
    int rc = sc_seam_texel_groups(m, seams, g, &w->unk, w->group, w->gamma, chart, err);
    if (rc == SC_OK) {
        for (int32_t i = 0; i < m->nu; i++) parent[i] = i;
        for (int32_t f = 0; f < m->nf; f++)
            for (int k = 1; k < 3; k++) {
                int32_t a = m->FU[3 * f], b = m->FU[3 * f + k];
                while (parent[a] != a) a = parent[a] = parent[parent[a]];
                while (parent[b] != b) b = parent[b] = parent[parent[b]];
                if (a != b) parent[a > b ? a : b] = a < b ? a : b;
            }
        for (int32_t r = 0; r < n; r++) {
            if (chart[r] < 0) continue;
            int32_t a = m->FU[3 * chart[r]];
            while (parent[a] != a) a = parent[a];
            chart[r] = a;
        }
    }
    free(parent);
    return rc;
}

/* What erase_group's steps share: the group and its inputs, its system and
 * solve (w), and the numbers its metrics and totals take. */
typedef struct group_run {
    sc_metric_list *ml;
    const sc_mesh *m;
    const sc_seam_set *seams;
    sc_seam_set seams_only;      /* the seams without the silhouettes: M alone */
    const sc_texture *textures;
    const sc_image_data *const *stored;   /* per texture: its stored 8/16-bit sRGB image when solved linear, or NULL */
    double srgb_value[256];               /* 255 x the linear light of each sRGB byte */
    const group *gr;
    const options *o;
    tex_state *st;
    bool several;
    totals *tot;
    group_work w;
    int32_t n;                   /* unknowns */
    int32_t ncols;               /* right-hand sides: one column per channel of every texture */
    int64_t n_inside, n_shared_unk;   /* unknowns inside the charts, and shared by two */
    double w_change_texel, w_pen;
    sc_seam_terms qterms;        /* the system matrix's, shared by every channel of every texture here */
    prep_ctx pc;
    double nullity, seconds_nullity;
    sc_sparse_stats stats;       /* the solver's */
    double t0, t1, t2, t3;       /* the stages' times: build, factor, solve */
    double tq;                   /* time spent quantising */
} group_run;

/* Which texels are inside, which are unknown, which are the seam texels (of
 * cells seam edges pass through); how many unknowns are inside, and shared. */
static int mark_texels(group_run *r, sc_error *err) {
    const sc_seam_grid *g = &r->gr->grid;
    group_work *w = &r->w;
    int rc = sc_seam_coverage_build(r->m, r->gr->material, g, r->o->threads, &w->cov, err);
    if (rc) return rc;
    if (sc_seam_texset_init(&w->unk, g->width, g->height) || sc_seam_texset_init(&w->seamset, g->width, g->height))
        return sc_fail(err, SC_ENOMEM, "out of memory");
    if ((rc = sc_seam_mark_texels(r->m, r->seams, g, &w->unk, &w->seamset, r->o->threads, err))) return rc;
    if (sc_seam_texset_finish(&w->unk) || sc_seam_texset_members(&w->unk, &w->ids) ||
        sc_seam_texset_finish(&w->seamset))
        return sc_fail(err, SC_ENOMEM, "out of memory");
    r->n = w->unk.count;
    for (int32_t i = 0; i < r->n; i++) {
        r->n_inside += sc_seam_texset_has(&w->cov.covered, w->ids[i]);
        r->n_shared_unk += sc_seam_texset_has(&w->cov.shared, w->ids[i]);
    }
    r->w_change_texel = w->cov.ncovered > 0 ? r->o->w_change / (double)w->cov.ncovered : 0;
    return SC_OK;
}

/* The scale of M on the seam texels (w_pen), and the system matrix's terms. */
static int scale_seam_terms(group_run *r, sc_error *err) {
    const options *o = r->o;
    double trace = 0;
    int rc = sc_seam_trace(r->m, r->seams, &r->gr->grid, o->threads, &trace, err);
    if (rc) return rc;
    r->w_pen = o->w_seam * (trace > 0 ? (double)r->w.seamset.count / trace : 1.0);
    r->qterms = (sc_seam_terms){.w_seam = r->w_pen,
                                .w_c1 = o->w_c1,
                                .w_outside = o->outside ? o->w_outside : 0,
                                .w_lerp = o->lerp ? o->w_lerp : 0};
    return SC_OK;
}

/* Room for the right-hand sides (n x ncols) and each texture's vertex values. */
static int alloc_right_hand_sides(group_run *r, sc_error *err) {
    for (int32_t k = 0; k < r->gr->ntex; k++) r->ncols += r->textures[r->gr->tex[k]].image->as.image->channels;
    r->w.rhs = sc_calloc_array((size_t)r->n * (size_t)r->ncols, sizeof *r->w.rhs);
    r->w.vv = sc_calloc_array((size_t)r->gr->ntex, sizeof *r->w.vv);
    if (!r->w.rhs || !r->w.vv)
        return sc_fail(err, SC_ENOMEM, "out of memory for %d x %d right-hand sides", (int)r->n, (int)r->ncols);
    return SC_OK;
}

/* Each texture's texels at the unknowns, which must be finite, and with
 * lerp its values at the mesh's vertices (w.vv). */
static int read_textures(group_run *r, sc_error *err) {
    const sc_seam_grid *g = &r->gr->grid;
    group_work *w = &r->w;
    for (int32_t k = 0; k < r->gr->ntex; k++) {
        const sc_texture *tx = &r->textures[r->gr->tex[k]];
        const sc_image_data *img = tx->image->as.image;
        for (int32_t i = 0; i < r->n; i++)
            for (int32_t c = 0; c < img->channels; c++)
                if (!isfinite(sc_seam_texel(img, w->ids[i], c)))
                    return sc_fail(err, SC_EINPUT, "texture %s (%s): non-finite value at texel (%d, %d)", tx->name,
                                   tx->source, (int)(w->ids[i] % g->width), (int)(w->ids[i] / g->width));
        if (r->o->lerp && r->o->w_lerp > 0 && !(w->vv[k] = vertex_values(r->m, r->gr->material, g, img)))
            return sc_fail(err, SC_ENOMEM, "out of memory");
    }
    return SC_OK;
}

/* Q's seam terms, and the edge-cluster solver's groups, side by side. */
static int assemble_seam_terms(group_run *r, sc_error *err) {
    const options *o = r->o;
    group_work *w = &r->w;
    w->use_schur = o->solver == SC_ERASE_SOLVER_SCHUR || (o->solver == SC_ERASE_SOLVER_AUTO && r->n >= o->schur_from);
    r->pc = (prep_ctx){r->m, r->seams, &r->seams_only, &r->gr->grid, r->textures, r->gr, o, w, &r->qterms, r->w_pen,
                       r->w_change_texel};
    build_job bj = {.ctx = &r->pc};
    sc_seam_parallel(o->threads >= 2 && w->use_schur ? 2 : 1, w->use_schur ? 2 : 1, build_task, &bj);
    int rc = bj.rc[0] ? bj.rc[0] : bj.rc[1];
    if (rc && err) *err = bj.err[bj.rc[0] ? 0 : 1];
    return rc;
}

/* Solver auto keeps the edge-cluster solver only where its clusters are
 * most of the system: texels that two chains' cells reach join no cluster,
 * and where they are most of it (a geometry image of a mesh and its levels
 * in one uv), every unknown is interface, and one factorisation of Q does
 * what the edge-cluster solver would, without the iterations. */
static void choose_solver(group_run *r) {
    group_work *w = &r->w;
    if (!w->use_schur) return;
    int64_t shared = 0;
    for (int32_t i = 0; i < r->n; i++) shared += w->group[i] < 0;
    if (r->o->solver == SC_ERASE_SOLVER_AUTO && (double)shared > SCHUR_MAX_SHARED * (double)r->n) {
        w->use_schur = false;
        free(w->group), free(w->gamma);
        w->group = NULL, w->gamma = NULL;
    }
}

/* Q's grid terms; for the edge-cluster solver, the couplings between charts
 * apart, and the texels they join made interface unknowns (the solve
 * iterates on the interface alone). */
static int add_grid_terms(group_run *r, sc_error *err) {
    group_work *w = &r->w;
    const options *o = r->o;
    if (w->use_schur) sc_triplets_init(&w->apart, r->n);
    int rc = grid_terms(&r->gr->grid, &w->unk, w->ids, &w->cov.covered, o, o->threads, r->w_change_texel, &w->q, NULL,
                        NULL, w->group ? w->group + r->n : NULL, w->use_schur ? &w->apart : NULL, err);
    if (rc) return rc;
    for (size_t k = 0; w->use_schur && k < w->apart.count; k++)
        w->group[w->apart.row[k]] = w->group[w->apart.col[k]] = -1;
    return SC_OK;
}

/* The factorisation (for the edge-cluster solver, of its interface alone,
 * mostly on one thread) and everything else that needs only the seams (the
 * textures' residuals, the rows of M for rounding, the nullity) side by
 * side: two independent tasks, the same results on any thread count. The
 * factorisation is the longer path: the side work (on all threads) runs
 * behind it, at a lower priority. */
static int factor_beside_residuals(group_run *r, sc_error *err) {
    const sc_texture *textures = r->textures;
    const group *gr = r->gr;
    group_work *w = &r->w;
    bool want_round = false;
    for (int32_t k = 0; k < gr->ntex; k++) {
        const int32_t ti = gr->tex[k];
        const sc_image_data *as_stored = r->stored[ti] ? r->stored[ti] : textures[ti].image->as.image;
        want_round |= as_stored->pixel == SC_PIXEL_U8 && r->o->quantize == SC_ERASE_QUANTIZE_OPTIMAL;
    }
    prep_job pj = {.ctx = r->pc,
                   .want_round = want_round,
                   .want_nullity = w->seamset.count <= NULLITY_MAX_TEXELS,
                   .nullity = NAN};
    r->t1 = sc_now();
    if (w->use_schur) prep_clusters(&pj);
    sc_run_beside(r->o->threads, prep_front, prep_back, &pj);
    if (pj.rc_factor) {
        if (err) *err = pj.err_factor;
        sc_error_prefix(err, "material %s", r->m->materials[gr->material]);
        return pj.rc_factor;
    }
    if (pj.rc_side) {
        if (err) *err = pj.err_side;
        return pj.rc_side;
    }
    /* conjugate gradients multiply by Q, and rounding reads it */
    if (!w->use_schur && !w->round_rows) sc_sparse_free(&w->q);
    /* stage times in wall time: the factorisation's stage holds the side
     * work beside it */
    r->t2 = sc_now();
    r->nullity = pj.nullity;
    r->seconds_nullity = pj.seconds_nullity;
    r->tq = pj.seconds_round_prep;
    return SC_OK;
}

/* Solve Q X = B for every right-hand side (w.rhs, overwritten by X = the changes). */
static int solve_group(group_run *r, sc_error *err) {
    double ts = r->t2;
    int rc = solve_unique(&r->w, r->o, r->n, r->ncols, r->w.rhs, err);
    if (rc) {
        sc_error_prefix(err, "material %s", r->m->materials[r->gr->material]);
        return rc;
    }
    r->t3 = r->t2 + (sc_now() - ts);
    return SC_OK;
}

/* The solver's statistics (the edge-cluster solver's counts into the
 * totals), then the solver freed; Q is kept, as M = Q / w_pen, only where
 * rounding reads it. */
static void release_solver(group_run *r) {
    group_work *w = &r->w;
    totals *tot = r->tot;
    if (w->schur) {
        sc_schur_stats ss;
        sc_schur_get_stats(w->schur, &ss);
        r->stats.factor_nnz = ss.envelope + ss.interface_factor_nnz;
        r->stats.flops = ss.cluster_flops + ss.interface_flops;
        r->stats.peak_bytes = ss.peak_bytes;
        tot->schur_groups += ss.clusters;
        tot->interface_unknowns += ss.interface_unknowns;
        if (w->pcg.iterations > tot->pcg_iterations) tot->pcg_iterations = w->pcg.iterations;
        sc_schur_free(w->schur);
        w->schur = NULL;
    } else {
        sc_sparse_chol_stats(w->chol, &r->stats);
        sc_sparse_chol_free(w->chol);
        w->chol = NULL;
    }
    if (!w->round_rows) sc_sparse_free(&w->q);
    else   /* rounding reads M = Q / w_pen on the seam rows */
        for (int64_t e = 0; e < w->q.nnz; e++) w->q.val[e] /= r->w_pen;
}

/* The group's share of the totals: its system, its solve and its stages' times. */
static void add_group_totals(const group_run *r) {
    totals *tot = r->tot;
    const sc_sparse_stats *stats = &r->stats;
    tot->seconds_nullity += r->seconds_nullity;
    tot->seam_edges += r->seams->nseams;
    tot->silhouette_edges += r->seams->nsil;
    tot->unknowns += r->n;
    tot->shared_texels += (double)r->w.cov.nshared;
    tot->seconds_build += r->t1 - r->t0;
    tot->seconds_factor += r->t2 - r->t1;
    tot->seconds_solve += r->t3 - r->t2;
    tot->factorizations++;
    tot->solver_fallbacks += r->w.fallback;
    tot->factor_nnz += stats->factor_nnz;
    tot->factor_flops += stats->flops;
    if (stats->peak_bytes / 1048576.0 > tot->solver_peak_mb) tot->solver_peak_mb = stats->peak_bytes / 1048576.0;
    if (isnan(r->nullity)) tot->nullity_all = false;
    else tot->nullity += r->nullity;
}

/* One texture of the group, from its solution to its metrics. */
typedef struct texture_out {
    int32_t ti;                   /* its index in the atlas */
    const sc_texture *tx;
    const sc_image_data *img;     /* the input, as solved (a linear copy of sRGB colour in linear mode) */
    const sc_image_data *store;   /* the input as stored: the native result's pixel type and encoding */
    bool like;                    /* store is a native_like image: its type only, not its texels */
    bool decode;                  /* the solution is linear light, store sRGB colour */
    sc_value *fv;                 /* the float result (st[ti].f32) */
    float *px;                    /* its pixels */
    sc_image_data *nat, *opt;     /* the naive and the optimal rounding, until handed over */
    round_job rj;
    int32_t src[4], chan[4];
    double max_in, sum_in, max_out;   /* the changes: inside the charts (largest, sum), outside */
    double e0, e1, g0, g1;        /* seam energy and largest gap, before and after */
    double eq_naive, eq_opt, gq;  /* after rounding to the input's pixel type; NaN when not measured */
    double tangent_suspect;       /* a normal slot: the input looks tangent-space (1) or not (0) */
} texture_out;

/* Write the solution: the input as floats plus its columns of changes,
 * with the largest and summed changes. A writable input (a float image made
 * for this call and read by nothing after it) takes the changes itself and
 * is the result; any other is copied first. */
static int write_solution(group_run *r, texture_out *t, int32_t col, sc_error *err) {
    const group_work *w = &r->w;
    const int32_t C = t->img->channels, n = r->n;
    bool in_place = r->st[t->ti].writable;   /* a float image (sc_erase) */
    sc_image_data *out = in_place ? (sc_image_data *)t->img : sc_image_to_f32_threads(t->img, r->o->threads);
    if (!out) return sc_fail(err, SC_ENOMEM, "out of memory");
    float *px = out->pixels;
    bool finite = true;
    for (int32_t i = 0; i < n; i++) {
        int32_t id = w->ids[i];
        bool inside = sc_seam_texset_has(&w->cov.covered, id);
        for (int32_t c = 0; c < C; c++) {
            double d = w->rhs[(size_t)(col + c) * n + i];
            finite &= isfinite(d);
            float *p = &px[(size_t)id * C + c];
            float x = (float)((double)*p + d);
            double ch = fabs((double)x - (double)*p);
            *p = x;
            if (inside) {
                if (ch > t->max_in) t->max_in = ch;
                t->sum_in += ch;
            } else if (ch > t->max_out) {
                t->max_out = ch;
            }
        }
    }
    if (!finite) {
        if (!in_place) sc_image_free(out);
        return sc_fail(err, SC_EINPUT, "texture %s: the solve gave non-finite texels", t->tx->name);
    }
    sc_value *fv = in_place ? sc_value_retain(t->tx->image) : sc_value_new_image(out);
    if (!fv) return sc_fail(err, SC_ENOMEM, "out of memory");
    r->st[t->ti].f32 = fv;
    t->fv = fv, t->px = px;
    return SC_OK;
}

/* A copy of img (its pixels, colour space and format); NULL when out of memory. */
static sc_image_data *copy_image(const sc_image_data *img) {
    sc_image_data *copy = sc_image_alloc(img->width, img->height, img->channels, img->pixel);
    if (!copy) return NULL;
    copy->colorspace = img->colorspace;
    memcpy(copy->format, img->format, sizeof copy->format);
    memcpy(copy->pixels, img->pixels, (size_t)img->width * img->height * img->channels * (size_t)img->pixel);
    return copy;
}

/* Float image f rounded to nearest in like's pixel type, colour space and
 * format tag. */
static sc_image_data *quantised_like(const sc_image_data *f, const sc_image_data *like, int threads) {
    sc_image_data *q = sc_image_quantize_threads(f, like->pixel, like->colorspace, threads);
    if (q) memcpy(q->format, like->format, sizeof q->format);
    return q;
}

/* The input's own pixel type: the naive rounding of the solution (nat)
 * and, for the optimal one, a copy of it that round_job changes (opt),
 * with M on the seam texels: exactly (small atlases, where the nullity was
 * measured), or Q's rows there over w_pen. */
static int prepare_rounding(group_run *r, texture_out *t, sc_error *err) {
    const group_work *w = &r->w;
    const sc_image_data *img = t->store;
    const int32_t C = img->channels;
    /* the input's own bytes where nothing was solved; a native_like image
     * lends only its type, so every texel is rounded from the solution */
    if (!(t->nat = t->like ? quantised_like(t->fv->as.image, img, r->o->threads) : copy_image(img)))
        return sc_fail(err, SC_ENOMEM, "out of memory");
    double maxv = img->pixel == SC_PIXEL_U8 ? 255.0 : 65535.0;
    for (int32_t i = 0; i < r->n && !t->like; i++)
        for (int32_t c = 0; c < C; c++) {
            size_t at = (size_t)w->ids[i] * C + c;
            double x = t->decode && !sc_channel_is_alpha(C, c) ? sc_linear_to_srgb(t->px[at]) : t->px[at];
            x = x < 0 ? 0 : x > 1 ? 1 : x;
            long v = lrint(x * maxv);
            if (img->pixel == SC_PIXEL_U8) ((uint8_t *)t->nat->pixels)[at] = (uint8_t)v;
            else ((uint16_t *)t->nat->pixels)[at] = (uint16_t)v;
        }
    if (w->round_rows && w->q.n > 0) t->rj.mf = &w->q, t->rj.rows = w->round_rows, t->rj.ids = w->ids;
    if (img->pixel != SC_PIXEL_U8 || r->o->quantize != SC_ERASE_QUANTIZE_OPTIMAL || t->rj.mf->n <= 0) return SC_OK;
    if (C > 4)   /* images hold at most 4 channels */
        return sc_fail(err, SC_EINPUT, "rounding to 8 bits: more than 4 channels");
    if (!(t->opt = copy_image(t->nat))) return sc_fail(err, SC_ENOMEM, "out of memory");
    t->rj.bytes = t->opt->pixels, t->rj.chan = t->chan;
    if (t->decode) {
        t->rj.value = r->srgb_value;
        for (int32_t c = 0; c < C; c++) t->rj.srgb[c] = !sc_channel_is_alpha(C, c);
    }
    return SC_OK;
}

/* The seam energies of the float result and of the naive rounding, beside
 * the optimal rounding (measure_task); then the result in the input's
 * pixel type (st[ti].native): the optimal rounding, the naive one, or the
 * float result itself. */
static int measure_and_round(group_run *r, texture_out *t, double tq0, sc_error *err) {
    const options *o = r->o;
    measure_job mj = {r->m, r->seams, &r->gr->grid, o->threads, t->fv->as.image, t->nat,
                      t->opt, t->decode, t->opt ? &t->rj : NULL, t->src, t->chan, 0};
    mj.threads_energy = t->opt && o->threads > 1 ? o->threads - 1 : o->threads;
    sc_seam_parallel(t->opt && o->threads > 1 ? 2 : 1, t->opt ? 2 : 1, measure_task, &mj);
    if (mj.rc[0] || mj.rc[1]) {
        if (err) *err = mj.err[mj.rc[0] ? 0 : 1];
        return mj.rc[0] ? mj.rc[0] : mj.rc[1];
    }
    if (t->opt) t->eq_opt = mj.e_optimal, t->gq = mj.g_optimal;
    t->e1 = mj.e_float, t->g1 = mj.g_float;
    tex_state *s = &r->st[t->ti];
    if (!t->nat) {
        s->native = sc_value_retain(t->fv);
        return SC_OK;
    }
    t->eq_naive = mj.e_naive;
    if (!t->opt) t->gq = mj.g_naive;
    if (t->opt) sc_image_free(t->nat);
    s->native = sc_value_new_image(t->opt ? t->opt : t->nat);   /* owns it, even on failure */
    t->nat = t->opt = NULL;
    if (!s->native) return sc_fail(err, SC_ENOMEM, "out of memory");
    r->tq += sc_now() - tq0;
    return SC_OK;
}

/* The metrics of one texture, and its share of the totals. */
static void texture_metrics(const group_run *r, const texture_out *t) {
    sc_metric_list *ml = r->ml;
    const sc_seam_set *seams = r->seams;
    const group_work *w = &r->w;
    const char *pre = r->st[t->ti].prefix;
    const sc_image_data *img = t->img;
    totals *tot = r->tot;
    metric(ml, pre, "seam_edges", seams->nseams);
    metric(ml, pre, "silhouette_edges", seams->nsil);
    metric(ml, pre, "boundary_edges", seams->nboundary);
    metric(ml, pre, "foldover_edges", seams->nfoldover);
    metric(ml, pre, "unknowns", r->n);
    metric(ml, pre, "unknowns_inside", (double)r->n_inside);
    metric(ml, pre, "seam_texels", w->nseam_texels);
    metric(ml, pre, "covered_texels", (double)w->cov.ncovered);
    metric(ml, pre, "shared_texels", (double)w->cov.nshared);
    metric(ml, pre, "shared_texel_fraction", w->cov.ncovered ? (double)w->cov.nshared / (double)w->cov.ncovered : 0);
    metric(ml, pre, "shared_unknowns", (double)r->n_shared_unk);
    metric(ml, pre, "seam_energy_before", t->e0);
    metric(ml, pre, "seam_energy_after", t->e1);
    metric(ml, pre, "max_seam_gap_before", t->g0);
    metric(ml, pre, "max_seam_gap_after", t->g1);
    if (!isnan(t->eq_naive)) {
        const char *bits = t->store->pixel == SC_PIXEL_U8 ? "u8" : "u16";
        char name[64];
        snprintf(name, sizeof name, "seam_energy_after_%s_naive", bits);
        metric(ml, pre, name, t->eq_naive);
        if (!isnan(t->eq_opt)) {
            snprintf(name, sizeof name, "seam_energy_after_%s_optimal", bits);
            metric(ml, pre, name, t->eq_opt);
        }
        snprintf(name, sizeof name, "max_seam_gap_after_%s", bits);
        metric(ml, pre, name, t->gq);
        if (t->store->pixel == SC_PIXEL_U8) {
            tot->any_u8 = true;
            tot->energy_u8_naive += t->eq_naive;
            if (!isnan(t->eq_opt)) tot->any_optimal = true, tot->energy_u8_optimal += t->eq_opt;
            else tot->energy_u8_optimal += t->eq_naive;
            if (t->gq > tot->gap_u8) tot->gap_u8 = t->gq;
        }
    }
    metric(ml, pre, "max_change_interior", t->max_in);
    metric(ml, pre, "mean_change_interior", r->n_inside ? t->sum_in / ((double)r->n_inside * img->channels) : 0);
    metric(ml, pre, "max_change_outside", t->max_out);
    if (!isnan(r->nullity)) metric(ml, pre, "nullity", r->nullity);
    if (is_normal_slot(t->tx->name)) metric(ml, pre, "tangent_space_suspect", t->tangent_suspect);
    if (r->several) {
        metric(ml, pre, "seconds_build", r->t1 - r->t0);
        metric(ml, pre, "seconds_factor", r->t2 - r->t1);
        metric(ml, pre, "seconds_solve", r->t3 - r->t2);
    }
    tot->energy_before += t->e0;
    tot->energy_after += t->e1;
    if (t->g0 > tot->gap_before) tot->gap_before = t->g0;
    if (t->g1 > tot->gap_after) tot->gap_after = t->g1;
    if (t->max_in > tot->max_change_in) tot->max_change_in = t->max_in;
    tot->erased++;
}

/* Texture k of the group (its changes from column col of w.rhs): write the
 * solution, measure, quantise, then its metrics. */
static int finish_texture(group_run *r, int32_t k, int32_t col, sc_error *err) {
    const int32_t ti = r->gr->tex[k];
    const sc_texture *tx = &r->textures[ti];
    texture_out t = {.ti = ti, .tx = tx, .img = tx->image->as.image, .eq_naive = NAN, .eq_opt = NAN, .gq = NAN};
    t.store = r->stored[ti] ? r->stored[ti] : t.img;
    t.like = r->o->native_like && r->o->native_like[ti] == t.store;
    t.decode = t.img->colorspace == SC_COLOR_LINEAR && t.store->colorspace == SC_COLOR_SRGB;
    if (is_normal_slot(tx->name)) t.tangent_suspect = looks_tangent_space(t.img) ? 1 : 0;   /* before it changes */
    int rc = write_solution(r, &t, col, err);
    if (rc) return rc;
    t.e0 = r->st[ti].energy_before, t.g0 = r->st[ti].gap_before;
    bool quantise = t.store->pixel != SC_PIXEL_F32 && r->o->quantize != SC_ERASE_QUANTIZE_NONE;
    double tq0 = sc_now();
    t.rj = (round_job){&r->w.mfull, NULL, r->w.seam_ids, t.px, NULL, t.img->channels, NULL};
    if (quantise) rc = prepare_rounding(r, &t, err);
    if (rc == SC_OK) rc = measure_and_round(r, &t, tq0, err);
    sc_image_free(t.nat), sc_image_free(t.opt);   /* not handed over: a failure */
    if (rc == SC_OK) texture_metrics(r, &t);
    return rc;
}

/* Erase the seams of one group: its system, built and factored once, then
 * every texture solved, measured, quantised. */
static int erase_group(sc_metric_list *ml, const sc_mesh *m, const sc_seam_set *seams,
                       const sc_texture *textures, const sc_image_data *const *stored, const group *gr,
                       const options *o, tex_state *st, bool several, totals *tot, sc_error *err) {
    group_run r = {.ml = ml, .m = m, .seams = seams, .seams_only = *seams, .textures = textures, .stored = stored,
                   .gr = gr, .o = o, .st = st, .several = several, .tot = tot};
    for (int k = 0; k < 256; k++) r.srgb_value[k] = 255.0 * sc_srgb_to_linear(k * (1.0f / 255.0f));
    r.seams_only.nsil = 0;
    r.t0 = sc_now();
    int rc = mark_texels(&r, err);
    if (rc == SC_OK) rc = scale_seam_terms(&r, err);
    if (rc == SC_OK) rc = alloc_right_hand_sides(&r, err);
    if (rc == SC_OK) rc = read_textures(&r, err);
    if (rc == SC_OK) rc = assemble_seam_terms(&r, err);
    if (rc == SC_OK) choose_solver(&r);
    if (rc == SC_OK) rc = add_grid_terms(&r, err);
    if (rc == SC_OK) rc = factor_beside_residuals(&r, err);
    if (rc == SC_OK) rc = solve_group(&r, err);
    if (rc == SC_OK) {
        release_solver(&r);
        add_group_totals(&r);
    }
    for (int32_t k = 0, col = 0; k < gr->ntex && rc == SC_OK; k++) {
        rc = finish_texture(&r, k, col, err);
        col += textures[gr->tex[k]].image->as.image->channels;
    }
    if (rc == SC_OK) tot->seconds_quantize += r.tq;
    group_work_free(&r.w, gr->ntex);
    return rc;
}

/* ---------------------------------------------------------------- warnings */

/* The length of the texture prefix of metric `name` ending in "suffix"
 * (without the '.' before the suffix), or -1 when it ends otherwise. */
static int prefix_before(const char *name, const char *suffix) {
    size_t n = strlen(name), l = strlen(suffix);
    if (n < l || strcmp(name + n - l, suffix) != 0) return -1;
    return (int)(n - l - (n > l));
}

bool sc_erase_warning(const sc_metric_list *ml, int32_t k, sc_erase_normal_space space, char *out, size_t size) {
    const sc_metric *m = &ml->items[k];
    if (m->value != 1) return false;
    int p;
    if ((p = prefix_before(m->name, "tangent_space_left")) >= 0) {
        snprintf(out, size, "%.*s: the tangent-space normal map is left as it is: erasing it through its frames would "
                 "widen the normals' seams (texels that charts with other frames share)", p, m->name);
        return true;
    }
    if ((p = prefix_before(m->name, "tangent_space_discontinuous")) >= 0) {
        double gap = NAN;   /* the normal_gap_after just before it */
        for (int32_t j = k - 1; j >= 0 && isnan(gap); j--)
            if (prefix_before(ml->items[j].name, "normal_gap_after") >= 0) gap = ml->items[j].value;
        snprintf(out, size, "%.*s: the tangent-space normal map cannot be made continuous: reconstructed normals "
                 "still differ by up to %.3g (about radians) across a seam", p, m->name, gap);
        return true;
    }
    if (space == SC_ERASE_NORMALS_OBJECT && (p = prefix_before(m->name, "tangent_space_suspect")) >= 0) {
        snprintf(out, size, "%.*s: the normal map looks tangent-space but is erased as object-space "
                 "(normal_space=tangent or auto erases it through its tangent frames)", p, m->name);
        return true;
    }
    return false;
}

/* ---------------------------------------------------------------- the kernel */

static const sc_kernel *const erase_uses[] = {&sc_kernel_seam, &sc_kernel_sparse, &sc_kernel_schur,
                                              &sc_kernel_tangent, NULL};
const sc_kernel sc_kernel_erase = {"erase", SC_ERASE_VERSION, erase_uses};

static bool slot_selected(const char *list, const char *name) {
    if (strcmp(list, "all") == 0) return true;
    size_t len = strlen(name);
    for (const char *p = list; *p;) {
        while (*p == ' ' || *p == ',') p++;
        const char *e = p;
        while (*e && *e != ',') e++;
        const char *t = e;
        while (t > p && t[-1] == ' ') t--;
        if ((size_t)(t - p) == len && strncmp(p, name, len) == 0) return true;
        p = e;
    }
    return false;
}

/* Every name of the `textures` list must name some slot of the atlas. */
static int check_selection(const char *list, const sc_texture *textures, int32_t ntex, sc_error *err) {
    if (strcmp(list, "all") == 0) return SC_OK;
    for (const char *p = list; *p;) {
        while (*p == ' ' || *p == ',') p++;
        if (!*p) break;
        const char *e = p;
        while (*e && *e != ',') e++;
        const char *t = e;
        while (t > p && t[-1] == ' ') t--;
        bool found = false;
        for (int32_t i = 0; i < ntex && !found; i++)
            found = strlen(textures[i].name) == (size_t)(t - p) &&
                    strncmp(textures[i].name, p, (size_t)(t - p)) == 0;
        if (!found) {
            sc_buf have;
            sc_buf_init(&have);
            for (int32_t i = 0; i < ntex; i++)
                sc_buf_printf(&have, "%s%s", i ? ", " : "", textures[i].name);
            char *h = sc_buf_take_string(&have);
            int rc = sc_fail(err, SC_EINPUT, "textures: '%.*s' names no texture of the atlas (it has: %s)",
                             (int)(t - p), p, h && *h ? h : "none");
            free(h);
            sc_buf_free(&have);
            return rc;
        }
        p = e;
    }
    return SC_OK;
}

static void make_prefix(const sc_mesh *m, const sc_texture *t, bool several, char *out, size_t n) {
    if (!several) {
        out[0] = 0;
        return;
    }
    if (m->nmat > 1) snprintf(out, n, "%s.%s.", m->materials[t->material], t->name);
    else snprintf(out, n, "%s.", t->name);
    for (char *p = out; *p; p++)
        if (*p == ' ' || *p == '\t' || *p == '"') *p = '_';
}

sc_value *sc_erase_result_atlas(const sc_value *atlas, const sc_erase_result *res, bool native) {
    const sc_atlas *a = atlas->as.atlas;
    bool own = true;   /* every texture the atlas's own image: nothing erased, nothing converted */
    for (int32_t i = 0; i < a->ntex && own; i++) own = (native ? res->native[i] : res->f32[i]) == a->textures[i].image;
    if (own) return sc_value_retain((sc_value *)atlas);
    sc_atlas *o = sc_atlas_new(sc_value_retain(a->mesh));
    if (o && sc_atlas_copy_materials(o, a) != SC_OK) sc_atlas_free(o), o = NULL;
    if (!o) return NULL;
    for (int32_t i = 0; i < a->ntex; i++) {
        const sc_texture *t = &a->textures[i];
        sc_value *img = native ? res->native[i] : res->f32[i];
        if (sc_atlas_add_texture(o, t->name, t->material, t->wrap_u, t->wrap_v, t->source, sc_value_retain(img))) {
            sc_atlas_free(o);
            return NULL;
        }
    }
    return sc_value_new_atlas(o);
}

static void emit_totals(sc_metric_list *ml, const totals *t, bool several) {
    if (several) {
        sc_metric_list_add(ml, "seam_edges", t->seam_edges);
        sc_metric_list_add(ml, "silhouette_edges", t->silhouette_edges);
        sc_metric_list_add(ml, "unknowns", t->unknowns);
        sc_metric_list_add(ml, "shared_texels", t->shared_texels);
        sc_metric_list_add(ml, "seam_energy_before", t->energy_before);
        sc_metric_list_add(ml, "seam_energy_after", t->energy_after);
        sc_metric_list_add(ml, "max_seam_gap_before", t->gap_before);
        sc_metric_list_add(ml, "max_seam_gap_after", t->gap_after);
        if (t->any_u8) {
            sc_metric_list_add(ml, "seam_energy_after_u8_naive", t->energy_u8_naive);
            if (t->any_optimal) sc_metric_list_add(ml, "seam_energy_after_u8_optimal", t->energy_u8_optimal);
            sc_metric_list_add(ml, "max_seam_gap_after_u8", t->gap_u8);
        }
        sc_metric_list_add(ml, "max_change_interior", t->max_change_in);
        if (t->nullity_all && t->factorizations > 0) sc_metric_list_add(ml, "nullity", t->nullity);
    }
    sc_metric_list_add(ml, "textures_erased", t->erased);
    sc_metric_list_add(ml, "textures_unchanged", t->unchanged);
    if (t->tangent > 0) sc_metric_list_add(ml, "tangent_space_maps", t->tangent);
    sc_metric_list_add(ml, "factorizations", t->factorizations);
    sc_metric_list_add(ml, "seconds_build", t->seconds_build);
    sc_metric_list_add(ml, "seconds_factor", t->seconds_factor);
    sc_metric_list_add(ml, "seconds_solve", t->seconds_solve);
    sc_metric_list_add(ml, "seconds_quantize", t->seconds_quantize);
    sc_metric_list_add(ml, "seconds_nullity", t->seconds_nullity);
    sc_metric_list_add(ml, "solver_peak_mb", t->solver_peak_mb);
    sc_metric_list_add(ml, "factor_nnz", t->factor_nnz);
    if (t->solver_fallbacks > 0) sc_metric_list_add(ml, "solver_fallbacks", t->solver_fallbacks);
    if (t->schur_groups > 0 || t->interface_unknowns > 0) {
        sc_metric_list_add(ml, "schur_clusters", t->schur_groups);
        sc_metric_list_add(ml, "interface_unknowns", t->interface_unknowns);
        sc_metric_list_add(ml, "pcg_iterations", t->pcg_iterations);
    }
    sc_metric_list_add(ml, "factor_flops", t->factor_flops);
}

sc_erase_normal_space sc_erase_normal_space_named(const char *name) {
    return strcmp(name, "tangent") == 0  ? SC_ERASE_NORMALS_TANGENT
           : strcmp(name, "object") == 0 ? SC_ERASE_NORMALS_OBJECT
                                         : SC_ERASE_NORMALS_AUTO;
}

sc_erase_normal_space sc_erase_normal_space_of(const char *name, const sc_atlas *atlas) {
    sc_erase_normal_space s = sc_erase_normal_space_named(name);
    return s == SC_ERASE_NORMALS_AUTO && atlas && atlas->materials ? SC_ERASE_NORMALS_TANGENT : s;
}

sc_erase_filter_space sc_erase_filter_space_named(const char *name) {
    return strcmp(name, "encoded") == 0 ? SC_ERASE_FILTER_ENCODED : SC_ERASE_FILTER_LINEAR;
}

void sc_erase_defaults(sc_erase_options *o) {
    *o = (sc_erase_options){
        .w_change = SC_ERASE_W_CHANGE_LOCAL,
        .w_seam = SC_ERASE_W_SEAM,
        .w_grad_in = SC_ERASE_W_GRAD,
        .w_c1 = SC_ERASE_W_C1,
        .w_grad_out = SC_ERASE_W_GRAD,
        .w_lerp = SC_ERASE_W_LERP,
        .w_outside = SC_ERASE_W_OUTSIDE,
        .gap_tolerance = SC_ERASE_GAP_TOLERANCE,
        .textures = "all",
        .quantize = SC_ERASE_QUANTIZE_OPTIMAL,
        .solver = SC_ERASE_SOLVER_AUTO,
        .schur_from = SC_ERASE_SCHUR_FROM,
        .pcg_iterations = SC_ERASE_PCG_ITERATIONS,
    };
}

/* Each texture's image: erased (its own or an earlier slot's of the same
 * image), or the input's passed through (its native result in the type of
 * native_like[i] where that is another image). */
static int collect_results(const sc_texture *textures, int32_t ntex, const tex_state *st,
                           const sc_image_data *const *native_like, int threads, sc_erase_result *res, sc_error *err) {
    res->count = ntex;
    res->f32 = sc_calloc_array(ntex ? (size_t)ntex : 1, sizeof *res->f32);
    res->native = sc_calloc_array(ntex ? (size_t)ntex : 1, sizeof *res->native);
    if (!res->f32 || !res->native || res->metrics.failed) return sc_fail(err, SC_ENOMEM, "out of memory");
    for (int32_t i = 0; i < ntex; i++) {
        int32_t src = st[i].same_as >= 0 ? st[i].same_as : i;
        bool own = st[src].fate == FATE_ERASE || st[src].fate == FATE_TANGENT;
        const sc_image_data *img = textures[i].image->as.image;
        res->f32[i] = sc_value_retain(own ? st[src].f32 : textures[i].image);
        if (own || !native_like || !native_like[i] || native_like[i] == img) {
            res->native[i] = sc_value_retain(own ? st[src].native : textures[i].image);
        } else {
            /* passed through, in native_like's type */
            sc_image_data *f = img->pixel == SC_PIXEL_F32 ? NULL : sc_image_to_f32_threads(img, threads);
            sc_image_data *q = quantised_like(f ? f : img, native_like[i], threads);
            sc_image_free(f);
            if (!q || !(res->native[i] = sc_value_new_image(q))) return sc_fail(err, SC_ENOMEM, "out of memory");
        }
    }
    return SC_OK;
}

void sc_erase_result_free(sc_erase_result *res) {
    for (int32_t i = 0; i < res->count; i++) {
        if (res->f32) sc_value_release(res->f32[i]);
        if (res->native) sc_value_release(res->native[i]);
    }
    free(res->f32), free(res->native);
    sc_metric_list_free(&res->metrics);
    *res = (sc_erase_result){0};
}

/* normal_space auto, for a map that looks tangent-space: is it one whose
 * normals meet across the seams through the tangent frames here (MikkTSpace's,
 * which glTF names), or one whose stored vectors already meet, as a map baked
 * with frames that are continuous across seams is? The smaller mean gap
 * along the seams decides; both are reported. */
static int frames_explain_seams(const sc_mesh *m, const sc_seam_set *seams, const sc_texture *t,
                                const sc_tangent_frames *frames, bool *tangent, sc_metric_list *ml,
                                const char *prefix, sc_error *err) {
    const sc_image_data *img = t->image->as.image;
    const sc_seam_grid g = {img->width, img->height, t->wrap_u, t->wrap_v};
    double max_framed, mean_framed, max_stored, mean_stored;
    int rc = sc_tangent_seam_gap(m, seams, &g, frames, img, &max_framed, &mean_framed, err);
    if (rc == SC_OK) rc = sc_tangent_seam_gap(m, seams, &g, NULL, img, &max_stored, &mean_stored, err);
    if (rc != SC_OK) return rc;
    metric(ml, prefix, "normal_gap_mean_through_frames", mean_framed);
    metric(ml, prefix, "normal_gap_mean_as_stored", mean_stored);
    *tangent = mean_framed < mean_stored;
    return SC_OK;
}

/* Whether texture t is taken as a tangent-space normal map under `space`:
 * a normal slot of 3+ channels, always with tangent, never with object, and
 * with auto when it looks like one and frames_explain_seams says so (the
 * frames built into *frames on first need). */
static int tangent_decision(const sc_mesh *m, const sc_seam_set *seams, const sc_texture *t,
                            sc_erase_normal_space space, sc_tangent_frames *frames, bool *tangent, sc_metric_list *ml,
                            const char *prefix, sc_error *err) {
    *tangent = false;
    if (!is_normal_slot(t->name) || t->image->as.image->channels < 3 || space == SC_ERASE_NORMALS_OBJECT) return SC_OK;
    *tangent = space == SC_ERASE_NORMALS_TANGENT;
    if (*tangent || !looks_tangent_space(t->image->as.image)) return SC_OK;
    int rc = frames->tangent ? SC_OK : sc_tangent_frames_build(m, frames, err);
    return rc ? rc : frames_explain_seams(m, seams, t, frames, tangent, ml, prefix, err);
}

int sc_erase_takes_tangent_space(const sc_mesh *m, const sc_texture *t, sc_erase_normal_space space, bool *tangent,
                                 sc_error *err) {
    *tangent = false;
    if (t->material < 0 || t->material >= m->nmat)
        return sc_fail(err, SC_EINPUT, "texture %s: material %d out of range", t->name, (int)t->material);
    sc_seam_set seams;
    int rc = sc_seam_find(m, t->material, &seams, err);
    if (rc) return rc;
    sc_tangent_frames frames = {0};
    sc_metric_list ml = {0};
    rc = tangent_decision(m, &seams, t, space, &frames, tangent, &ml, "", err);
    sc_metric_list_free(&ml);
    sc_tangent_frames_free(&frames);
    sc_seam_set_free(&seams);
    return rc;
}

/* The largest object-space seam gap that rounding a seam-free field to
 * img's pixel type can open: each side's components off by half a step of
 * the signed decoding (2 x - 1), turned by a frame whose rows are at most
 * unit vectors, so sqrt(3) steps; 0 for float. */
static double tangent_rounding_gap(const sc_image_data *img) {
    double step = img->pixel == SC_PIXEL_U8 ? 2.0 / 255 : img->pixel == SC_PIXEL_U16 ? 2.0 / 65535 : 0;
    return sqrt(3.0) * step;
}

/* A tangent-space map kept as it is: its float copy, and as written: the
 * input itself, or *as_left (taken over) where a float input goes back to
 * its 8/16-bit original's type. */
static int keep_tangent_map(const sc_texture *t, sc_image_data **as_left, tex_state *s, sc_error *err) {
    sc_image_data *f = sc_image_to_f32(t->image->as.image);
    sc_value_release(s->f32), sc_value_release(s->native);
    s->f32 = f ? sc_value_new_image(f) : NULL;
    s->native = *as_left ? sc_value_new_image(*as_left) : sc_value_retain(t->image);
    *as_left = NULL;
    return s->f32 && s->native ? SC_OK : sc_fail(err, SC_ENOMEM, "out of memory");
}

/* A tangent-space normal map (FATE_TANGENT): to object space with the
 * frames of `frames`, erased there as one float data map with the caller's
 * weights (no rounding), back to tangent space, and rounded to nearest in
 * the input's pixel type (like's, when given: an 8/16-bit original). A map
 * whose mean rendered gap would widen (texels shared by faces with other
 * frames) is left as it is, and tangent_space_left says so. A map written in
 * its own pixel type whose object-space field is seam-free already passes
 * through, as any texture does (already_seam_free): its largest seam gap
 * there is within the options' gap_tolerance or within what rounding to
 * that type can open (tangent_rounding_gap). Its metrics: the
 * reconstructed normal's seam gap on the input and on the bytes written,
 * and the object-space field's seam energy before and after the solve. */
static int erase_tangent_space(const sc_mesh *m, const sc_seam_set *seams, const sc_texture *t,
                               const sc_image_data *like, const sc_erase_options *eo, int threads, const sc_tangent_frames *frames,
                               tex_state *s, sc_metric_list *ml, sc_error *err) {
    const sc_image_data *img = t->image->as.image;
    const sc_seam_grid g = {img->width, img->height, t->wrap_u, t->wrap_v};
    sc_tangent_texels tx = {0};
    sc_erase_result sub = {0};
    sc_image_data *back = NULL;
    double gap_before = 0, mean_before = 0, gap_after = 0, mean_after = 0;
    /* written in like's pixel type when like is 8/16-bit; a float input (a
     * map re-rendered from an 8-bit one) is measured as it would be written
     * if left, rounded the same way */
    const sc_image_data *to = like && like->pixel != SC_PIXEL_F32 ? like : img;
    sc_image_data *as_left =
        img->pixel == SC_PIXEL_F32 && to->pixel != SC_PIXEL_F32 ? quantised_like(img, to, threads) : NULL;
    int rc = img->pixel == SC_PIXEL_F32 && to->pixel != SC_PIXEL_F32 && !as_left
                 ? sc_fail(err, SC_ENOMEM, "out of memory")
                 : sc_tangent_texels_build(m, t->material, &g, SC_TANGENT_BAND, threads, &tx, err);
    if (rc == SC_OK)
        rc = sc_tangent_seam_gap(m, seams, &g, frames, as_left ? as_left : img, &gap_before, &mean_before, err);
    bool clean = false;
    double object_energy = 0, object_gap = 0;
    if (rc == SC_OK) {
        sc_image_data *obj = sc_tangent_to_object(img, frames, &tx, threads);
        sc_value *objv = obj ? sc_value_new_image(obj) : NULL;
        if (!objv) rc = sc_fail(err, SC_ENOMEM, "out of memory");
        if (rc == SC_OK && eo->gap_tolerance > 0 && to->pixel == img->pixel) {
            rc = sc_seam_energy(m, seams, &g, obj, threads, &object_energy, &object_gap, err);
            clean = rc == SC_OK && object_gap <= fmax(eo->gap_tolerance, tangent_rounding_gap(img));
        }
        sc_erase_options so = *eo;
        so.normal_space = SC_ERASE_NORMALS_OBJECT, so.quantize = SC_ERASE_QUANTIZE_NONE, so.gap_tolerance = 0;
        so.native_like = NULL, so.textures = "all";
        const bool made_here = true;   /* obj, read no more once erased */
        so.inputs_private = &made_here;
        sc_texture st = *t;
        st.image = objv;
        if (rc == SC_OK && !clean) rc = sc_erase(m, &st, 1, &so, threads, &sub, err);
        sc_value_release(objv);
    }
    bool left = false;
    if (rc == SC_OK && clean) {   /* passed through: the input itself */
        rc = keep_tangent_map(t, &as_left, s, err);
        gap_after = gap_before, mean_after = mean_before;
    } else if (rc == SC_OK) {
        if (!(back = sc_tangent_from_object(sub.f32[0]->as.image, img, frames, &tx, threads)))
            rc = sc_fail(err, SC_ENOMEM, "out of memory");
        if (rc == SC_OK) {
            sc_image_data *nat = to->pixel == SC_PIXEL_F32 ? NULL : quantised_like(back, to, threads);
            s->f32 = sc_value_new_image(back), back = NULL;
            s->native = to->pixel == SC_PIXEL_F32 ? sc_value_retain(s->f32) : nat ? sc_value_new_image(nat) : NULL;
            if (!s->f32 || !s->native) rc = sc_fail(err, SC_ENOMEM, "out of memory");
        }
        if (rc == SC_OK)
            rc = sc_tangent_seam_gap(m, seams, &g, frames, s->native->as.image, &gap_after, &mean_after, err);
        if (rc == SC_OK && mean_after > mean_before) {
            /* texels that faces with other frames share (overlapping or mirrored
             * charts) cannot hold one object-space value: rather than widen
             * the rendered gaps, the map is left as it is */
            rc = keep_tangent_map(t, &as_left, s, err);
            gap_after = gap_before, mean_after = mean_before, left = true;
        }
    }
    if (rc == SC_OK) {
        const char *pre = s->prefix;
        metric(ml, pre, "tangent_space", 1);
        metric(ml, pre, "tangent_space_left", left);
        metric(ml, pre, "seam_edges", seams->nseams);
        if (clean) {
            metric(ml, pre, "already_seam_free", 1);
            metric(ml, pre, "object_seam_energy_before", object_energy);
            metric(ml, pre, "object_seam_energy_after", object_energy);
            metric(ml, pre, "object_max_seam_gap", object_gap);
        }
        for (int32_t k = 0; k < sub.metrics.count; k++) {
            const char *name = sub.metrics.items[k].name;
            if (!strcmp(name, "seam_energy_before") || !strcmp(name, "seam_energy_after")) {
                char full[64];
                snprintf(full, sizeof full, "object_%s", name);
                metric(ml, pre, full, sub.metrics.items[k].value);
            }
        }
        metric(ml, pre, "normal_gap_before", gap_before);
        metric(ml, pre, "normal_gap_mean_before", mean_before);
        metric(ml, pre, "normal_gap_after", gap_after);
        metric(ml, pre, "normal_gap_mean_after", mean_after);
        metric(ml, pre, "tangent_space_discontinuous", gap_after > SC_ERASE_NORMAL_GAP_LIMIT);
    } else {
        sc_error_prefix(err, "texture %s (tangent-space)", t->name);
    }
    sc_image_free(back);
    sc_image_free(as_left);
    sc_erase_result_free(&sub);
    sc_tangent_texels_free(&tx);
    return rc;
}

/* Linear mode: every selected sRGB texture is solved from a linear f32 copy
 * (one per image value, so slots sharing an image still share it); the
 * copies go into work[] in place of the inputs, and stored[i] keeps an
 * 8/16-bit original, whose pixel type and encoding the native result takes. */
static int linear_copies(const sc_texture *textures, int32_t ntex, const char *list, int threads, sc_texture *work,
                         sc_value **copies, const sc_image_data **stored, sc_error *err) {
    for (int32_t i = 0; i < ntex; i++) {
        work[i] = textures[i];
        const sc_image_data *img = textures[i].image->as.image;
        if (!slot_selected(list, textures[i].name) || img->colorspace != SC_COLOR_SRGB) continue;
        for (int32_t k = 0; k < i && !copies[i]; k++)
            if (copies[k] && textures[k].image == textures[i].image) copies[i] = sc_value_retain(copies[k]);
        if (!copies[i]) {
            sc_image_data *lin = sc_image_to_linear_f32(img, threads);
            if (!lin || !(copies[i] = sc_value_new_image(lin))) return sc_fail(err, SC_ENOMEM, "out of memory");
        }
        work[i].image = copies[i];
        if (img->pixel != SC_PIXEL_F32) stored[i] = img;
    }
    return SC_OK;
}

int sc_erase(const sc_mesh *m, const sc_texture *textures, int32_t ntex, const sc_erase_options *eo, int threads,
             sc_erase_result *res, sc_error *err) {
    *res = (sc_erase_result){0};
    const options o = {
        .w_change = eo->w_change,
        .w_seam = eo->w_seam,
        .w_grad_in = eo->w_grad_in,
        .w_c1 = eo->w_c1,
        .w_grad_out = eo->w_grad_out,
        .w_lerp = eo->w_lerp,
        .w_outside = eo->w_outside,
        .lerp = eo->lerp,
        .outside = eo->outside,
        .normal_space = eo->normal_space,
        .gap_tolerance = eo->gap_tolerance,
        .textures = eo->textures ? eo->textures : "all",
        .quantize = eo->quantize,
        .filter_space = eo->filter_space,
        .native_like = eo->native_like,
        .solver = eo->solver,
        .schur_from = eo->schur_from,
        .pcg_iterations = eo->pcg_iterations,
        .inputs_private = eo->inputs_private,
        .threads = threads,
    };
    const char *list = o.textures;
    int rc = check_selection(list, textures, ntex, err);
    if (rc) return rc;

    tex_state *st = sc_calloc_array(ntex ? (size_t)ntex : 1, sizeof *st);
    sc_seam_set *sets = sc_calloc_array((size_t)m->nmat, sizeof *sets);
    bool *found = sc_calloc_array((size_t)m->nmat, sizeof *found);
    group *groups = sc_calloc_array(ntex ? (size_t)ntex : 1, sizeof *groups);
    sc_texture *work = sc_calloc_array(ntex ? (size_t)ntex : 1, sizeof *work);
    sc_value **copies = sc_calloc_array(ntex ? (size_t)ntex : 1, sizeof *copies);
    const sc_image_data **stored = sc_calloc_array(ntex ? (size_t)ntex : 1, sizeof *stored);
    const sc_texture *inputs = textures;
    sc_tangent_frames frames = {0};
    int32_t ngroups = 0;
    totals tot = {.nullity_all = true};
    if (!st || !sets || !found || !groups || !work || !copies || !stored) {
        rc = sc_fail(err, SC_ENOMEM, "out of memory");
        goto done;
    }
    if (o.filter_space == SC_ERASE_FILTER_LINEAR) {
        if ((rc = linear_copies(inputs, ntex, list, threads, work, copies, stored, err))) goto done;
        textures = work;
    }
    for (int32_t i = 0; o.native_like && i < ntex; i++) {
        const sc_image_data *like = o.native_like[i], *img = inputs[i].image->as.image;
        if (like && like->pixel != SC_PIXEL_F32 && like->width == img->width && like->height == img->height &&
            like->channels == img->channels)
            stored[i] = like;
    }
    /* a float image only one slot holds, made here (a linear copy) or by the
     * caller for this call, takes its solution in place */
    for (int32_t i = 0; i < ntex; i++) {
        bool alone = true;
        for (int32_t k = 0; k < ntex && alone; k++) alone = k == i || textures[k].image != textures[i].image;
        st[i].writable = alone && (copies[i] != NULL || (o.inputs_private && o.inputs_private[i])) &&
                         textures[i].image->as.image->pixel == SC_PIXEL_F32;
    }
    int32_t nselected = 0;
    for (int32_t i = 0; i < ntex; i++) nselected += slot_selected(list, textures[i].name);
    bool several = nselected > 1;

    /* decide each texture's fate; group the ones to erase */
    for (int32_t i = 0; i < ntex; i++) {
        const sc_texture *t = &textures[i];
        st[i].same_as = -1;
        make_prefix(m, t, several, st[i].prefix, sizeof st[i].prefix);
        if (!slot_selected(list, t->name)) continue;
        if (t->material < 0 || t->material >= m->nmat) {
            rc = sc_fail(err, SC_EINPUT, "texture %s: material %d out of range", t->name, (int)t->material);
            goto done;
        }
        if (!found[t->material]) {
            if ((rc = sc_seam_find(m, t->material, &sets[t->material], err))) goto done;
            found[t->material] = true;
        }
        bool tangent = false;
        if ((rc = tangent_decision(m, &sets[t->material], t, o.normal_space, &frames, &tangent, &res->metrics,
                                   st[i].prefix, err)))
            goto done;
        if (tangent) {
            st[i].fate = FATE_TANGENT;
            continue;
        }
        if (sets[t->material].nseams == 0) {
            metric(&res->metrics, st[i].prefix, "seam_edges", 0);
            metric(&res->metrics, st[i].prefix, "seam_energy_before", 0);
            metric(&res->metrics, st[i].prefix, "seam_energy_after", 0);
            metric(&res->metrics, st[i].prefix, "max_seam_gap_after", 0);
            tot.unchanged++;
            continue;
        }
        {
            /* already seam-free (within the tolerance, or within one step of an
             * 8/16-bit encoding, the best such an image can hold)? */
            const sc_image_data *img = t->image->as.image;
            sc_seam_grid g = {img->width, img->height, t->wrap_u, t->wrap_v};
            if ((rc = sc_seam_energy(m, &sets[t->material], &g, img, o.threads, &st[i].energy_before,
                                     &st[i].gap_before, err)))
                goto done;
            const sc_image_data *as_stored = stored[i] ? stored[i] : img;
            double step = as_stored->pixel == SC_PIXEL_U8    ? 1.0 / 255
                          : as_stored->pixel == SC_PIXEL_U16 ? 1.0 / 65535
                                                             : 0;
            if (o.gap_tolerance > 0 && st[i].gap_before <= fmax(o.gap_tolerance, step)) {
                st[i].fate = FATE_CLEAN;
                const char *pre = st[i].prefix;
                metric(&res->metrics, pre, "seam_edges", sets[t->material].nseams);
                metric(&res->metrics, pre, "already_seam_free", 1);
                metric(&res->metrics, pre, "seam_energy_before", st[i].energy_before);
                metric(&res->metrics, pre, "seam_energy_after", st[i].energy_before);
                metric(&res->metrics, pre, "max_seam_gap_before", st[i].gap_before);
                metric(&res->metrics, pre, "max_seam_gap_after", st[i].gap_before);
                tot.unchanged++;
                continue;
            }
        }
        st[i].fate = FATE_ERASE;
        for (int32_t k = 0; k < i; k++)
            if (st[k].fate == FATE_ERASE && st[k].same_as < 0 && textures[k].image == t->image &&
                textures[k].material == t->material && textures[k].wrap_u == t->wrap_u &&
                textures[k].wrap_v == t->wrap_v) {
                st[i].same_as = k;
                break;
            }
        if (st[i].same_as >= 0) continue;
        const sc_image_data *img = t->image->as.image;
        sc_seam_grid g = {img->width, img->height, t->wrap_u, t->wrap_v};
        int32_t gi = 0;
        while (gi < ngroups &&
               !(groups[gi].material == t->material && groups[gi].grid.width == g.width &&
                 groups[gi].grid.height == g.height && groups[gi].grid.wrap_u == g.wrap_u &&
                 groups[gi].grid.wrap_v == g.wrap_v))
            gi++;
        if (gi == ngroups) {
            groups[gi].material = t->material;
            groups[gi].grid = g;
            groups[gi].tex = sc_alloc_array((size_t)ntex, sizeof *groups[gi].tex);
            if (!groups[gi].tex) {
                rc = sc_fail(err, SC_ENOMEM, "out of memory");
                goto done;
            }
            ngroups++;
        }
        groups[gi].tex[groups[gi].ntex++] = i;
    }

    for (int32_t gi = 0; gi < ngroups && rc == SC_OK; gi++)
        rc = erase_group(&res->metrics, m, &sets[groups[gi].material], textures, stored, &groups[gi], &o, st, several,
                         &tot, err);
    for (int32_t i = 0; i < ntex && rc == SC_OK; i++)
        if (st[i].fate == FATE_TANGENT) {
            if (!frames.tangent && (rc = sc_tangent_frames_build(m, &frames, err))) break;
            rc = erase_tangent_space(m, &sets[textures[i].material], &textures[i], o.native_like ? stored[i] : NULL,
                                     eo, threads, &frames, &st[i], &res->metrics, err);
            tot.tangent++;
            if (rc == SC_OK && st[i].native == textures[i].image) tot.unchanged++;
            else tot.erased++;
        }
    if (rc) goto done;
    for (int32_t i = 0; i < ntex; i++)
        if (st[i].fate == FATE_ERASE && st[i].same_as >= 0) {
            /* a second slot of an image already erased */
            tot.erased++;
            metric(&res->metrics, st[i].prefix, "same_image_as_slot", st[i].same_as);
        }
    emit_totals(&res->metrics, &tot, several);
    rc = collect_results(inputs, ntex, st, o.native_like ? stored : NULL, o.threads, res, err);

done:
    if (st)
        for (int32_t i = 0; i < ntex; i++) {
            sc_value_release(st[i].f32);
            sc_value_release(st[i].native);
        }
    if (sets)
        for (int32_t k = 0; k < m->nmat; k++) sc_seam_set_free(&sets[k]);
    if (groups)
        for (int32_t gi = 0; gi < ngroups; gi++) free(groups[gi].tex);
    if (copies)
        for (int32_t i = 0; i < ntex; i++) sc_value_release(copies[i]);
    free(st), free(sets), free(found), free(groups), free(work), free(copies), free(stored);
    sc_tangent_frames_free(&frames);
    if (rc != SC_OK) sc_erase_result_free(res);
    return rc;
}

