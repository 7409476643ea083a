/* sc_schur.c - clusters eliminated on their own, the interface by CHOLMOD,
 * and conjugate gradients around it.
 *
 * Design note.
 *  - Order. Private unknowns come first, cluster by cluster (clusters in
 *    increasing group id, unknowns in key order), then the interface in
 *    index order. A private unknown couples only to its own cluster and to
 *    the interface, so A is
 *        [ A_pp  A_pi ]      A_pp block diagonal (one block per cluster),
 *        [ A_ip  A_ii ]
 *    and S = A_ii - sum_c A_ic A_cc^-1 A_ci is the interface system.
 *  - Clusters. In key order a cluster's block is nearly banded (texels along
 *    a chain couple to texels a cell or two away; plan sends to the
 *    interface the unknowns of a cluster whose couplings span more than
 *    key_span, where a chain comes back near itself), so each block is factored
 *    in its envelope (row k stores columns first[k]..k; the envelope of L is
 *    that of A, so there is no fill outside it) by row Crout: inner loops are
 *    dot products of contiguous rows. Its Schur complement Z^T Z, with
 *    Z = L_c^-1 A_ci, is dense over the interface unknowns the cluster
 *    touches (a few dozen); forward substitution starts at each column's
 *    first nonzero, so the unknowns at the far end of a chain cost little.
 *    Only L_c is kept: a solve recomputes A_ci products from the couplings.
 *  - Interface. S is assembled from A_ii and every cluster's complement, in
 *    a fixed order, and factored by CHOLMOD (AMD, simplicial L L^T: its
 *    supernodes would be small). It is a small fraction of A and carries
 *    what makes the whole system hard to order: where chains meet.
 *  - Layout (the blocks' envelopes, A_pi's couplings, A_ii's triplets) is
 *    made in fixed chunks of positions on all threads: one pass counts,
 *    prefix sums place every chunk, a second pass fills; A_ii's triplets and
 *    then the clusters' complements join one sc_triplet_parts, list by list
 *    in chunk order, freed before CHOLMOD factors S. Exact zeros off the
 *    diagonal (a caller that drops terms in place, as sc_erase's
 *    preconditioner does) are not couplings anywhere: not in the plan, the
 *    layout or the clusters.
 *  - Solve: y = A_pp^-1 b_p; S x_i = b_i - A_ip y; x_p = y - A_pp^-1 A_pi x_i.
 *  - A + E, for rank-one couplings E between interface unknowns that
 *    would spoil the chain structure (sc_erase: grid couplings between
 *    texels of different charts that happen to lie side by side in the
 *    atlas), is solved the same way with (S + E) x_i = b_i - A_ip y in
 *    place of the interface solve: conjugate gradients on the interface
 *    alone, S kept for its products and its factor the preconditioner, are
 *    conjugate gradients on A + E preconditioned by A restricted to where
 *    A + E and A differ: iterations on the interface unknowns alone, each a
 *    product with S and an interface solve, not a product with the whole
 *    system and a whole solve. One round of
 *    refinement on the residual of A + E itself takes back what the
 *    factorisation's rounding loses.
 *  - The iterations on two threads. Each one is an interface solve and a
 *    product with S. The solves split S's elimination tree in two halves
 *    (sc_sparse_chol_solve_threads); the products cut S's columns at half
 *    its entries, each half into its own vector, summed after. The
 *    permutations between unknown and position order, and the private part
 *    of b^T A^-1 b, run over fixed chunks of positions on all threads. The
 *    sums are in another order than a single-threaded solve's, so the
 *    results differ from one by rounding; the split is fixed by the sizes,
 *    so they do not depend on the thread count.
 *  - Determinism. Work is split into chunks fixed by the sizes alone;
 *    complements join chunk by chunk; dot products are summed per
 *    fixed chunk of rows and then in chunk order. The bits do not depend on
 *    the thread count.
 * Measurements: docs/notes/erase_seams.md.
 */
#include "sc_schur.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

static const sc_kernel *const schur_uses[] = {&sc_kernel_sparse, NULL};
const sc_kernel sc_kernel_schur = {"schur", SC_SCHUR_VERSION, schur_uses};

#define CLUSTER_CHUNKS 256
#define ROW_CHUNK 16384

typedef struct csr {
    int32_t *ptr, *idx;
    double *val;
} csr;

static void csr_free(csr *c) {
    free(c->ptr), free(c->idx), free(c->val);
    memset(c, 0, sizeof *c);
}

struct sc_schur {
    int32_t n, npriv, nif, nclusters;
    int32_t *order;     /* position -> unknown */
    int32_t *position;  /* unknown -> position */
    int32_t *cstart;    /* nclusters + 1: positions of each cluster */
    int32_t *first;     /* npriv: first column of each envelope row */
    int64_t *envptr;    /* npriv + 1 */
    double *env;        /* envelope rows of the cluster factors */
    csr b;              /* private row -> (interface index, value) */
    csr bt;             /* interface index -> (private position, value) */
    sc_sparse sii;      /* S (upper triangle), kept for products with it */
    sc_sparse_chol *s;  /* its factor; NULL when there is no interface */
    sc_schur_stats stats;
    int threads;
    double *work, *work_if;  /* solve scratch: n and nif values per column, kept */
    int32_t work_cols;
};

/* ---------------------------------------------------------------- envelope */

static inline double *env_row(const sc_schur *f, int32_t k) { return f->env + f->envptr[k]; }

/* Row Crout on the envelope rows [k0, k1) (one cluster). */
static bool envelope_factor(sc_schur *f, int32_t k0, int32_t k1, double *flops) {
    for (int32_t i = k0; i < k1; i++) {
        double *ri = env_row(f, i);
        int32_t fi = f->first[i];
        for (int32_t j = fi; j <= i; j++) {
            const double *rj = env_row(f, j);
            int32_t fj = f->first[j], k = fi > fj ? fi : fj;
            const double *a = ri + (k - fi), *b = rj + (k - fj);
            double s = ri[j - fi];
            for (int32_t t = 0; t < j - k; t++) s -= a[t] * b[t];
            *flops += 2.0 * (j - k);
            if (j < i) {
                ri[j - fi] = s / rj[j - fj];
            } else {
                if (!(s > 0)) return false;
                ri[i - fi] = sqrt(s);
            }
        }
    }
    return true;
}

/* Forward substitution L y = x on the rows [k0, k1) of one cluster, from row
 * `from` on (x is zero above it); x[0] is row k0's entry. Returns the flops. */
static double envelope_forward(const sc_schur *f, int32_t k0, int32_t k1, int32_t from, double *x) {
    double flops = 0;
    for (int32_t i = from; i < k1; i++) {
        const double *ri = env_row(f, i);
        int32_t fi = f->first[i], k = fi > from ? fi : from;
        const double *a = ri + (k - fi), *xx = x + (k - k0);
        double s = x[i - k0];
        for (int32_t t = 0; t < i - k; t++) s -= a[t] * xx[t];
        x[i - k0] = s / ri[i - fi];
        flops += 2.0 * (i - k) + 1;
    }
    return flops;
}

/* Back substitution L^T y = x on the rows [k0, k1); x[0] is row k0's entry. */
static void envelope_backward(const sc_schur *f, int32_t k0, int32_t k1, double *x) {
    for (int32_t i = k1 - 1; i >= k0; i--) {
        const double *ri = env_row(f, i);
        int32_t fi = f->first[i];
        double xi = x[i - k0] / ri[i - fi];
        x[i - k0] = xi;
        double *xx = x + (fi - k0);
        for (int32_t t = 0; t < i - fi; t++) xx[t] -= ri[t] * xi;
    }
}

/* ---------------------------------------------------------------- factor */

typedef struct factor_job {
    sc_schur *f;
    const sc_sparse *a;
    int32_t per_chunk;
    sc_triplets *trip;  /* one list per chunk */
    double *flops;      /* one per chunk */
    int32_t *bad;       /* one per chunk: the first cluster that is not positive definite, or -1 */
} factor_job;

static int cmp_int32(const void *pa, const void *pb) {
    int32_t a = *(const int32_t *)pa, b = *(const int32_t *)pb;
    return a < b ? -1 : a > b;
}

/* Entry p of column t couples: a stored exact zero off the diagonal does not
 * (a caller that drops terms in place leaves them). */
static inline bool is_coupling(const sc_sparse *a, int32_t p, int32_t t) {
    return a->val[p] != 0 || a->rowind[p] == t;
}

/* Fill, factor and eliminate one cluster; its complement goes to trip. */
static int factor_cluster(factor_job *job, int32_t c, sc_triplets *trip, double *flops,
                          int32_t **loc, int32_t *loc_cap, double **z, size_t *z_cap) {
    sc_schur *f = job->f;
    const sc_sparse *a = job->a;
    int32_t k0 = f->cstart[c], k1 = f->cstart[c + 1], np = k1 - k0;
    for (int32_t k = k0; k < k1; k++) {
        double *rk = env_row(f, k);
        int32_t fk = f->first[k];
        memset(rk, 0, (size_t)(k - fk + 1) * sizeof *rk);
        int32_t t = f->order[k];
        for (int32_t p = a->colptr[t]; p < a->colptr[t + 1]; p++) {
            if (!is_coupling(a, p, t)) continue;
            int32_t q = f->position[a->rowind[p]];
            if (q <= k && q >= k0) rk[q - fk] += a->val[p];
        }
    }
    if (!envelope_factor(f, k0, k1, flops)) return 1;

    /* the interface unknowns this cluster touches, sorted and unique */
    int32_t nb = f->b.ptr[k1] - f->b.ptr[k0];
    if (nb == 0) return 0;
    if (nb > *loc_cap) {
        int32_t *p = realloc(*loc, (size_t)nb * sizeof *p);
        if (!p) return -1;
        *loc = p, *loc_cap = nb;
    }
    int32_t *ifs = *loc;
    memcpy(ifs, f->b.idx + f->b.ptr[k0], (size_t)nb * sizeof *ifs);
    qsort(ifs, (size_t)nb, sizeof *ifs, cmp_int32);
    int32_t m = 0;
    for (int32_t q = 0; q < nb; q++)
        if (m == 0 || ifs[q] != ifs[m - 1]) ifs[m++] = ifs[q];

    /* Z = L^-1 A_ci, one dense column (np long) per interface unknown */
    size_t need = (size_t)np * (size_t)m;
    if (need > *z_cap) {
        double *p = realloc(*z, need * sizeof *p);
        if (!p) return -1;
        *z = p, *z_cap = need;
    }
    double *zz = *z;
    memset(zz, 0, need * sizeof *zz);
    int32_t *start = sc_alloc_array((size_t)m, sizeof *start);
    if (!start) return -1;
    for (int32_t q = 0; q < m; q++) start[q] = np;
    for (int32_t k = k0; k < k1; k++)
        for (int32_t p = f->b.ptr[k]; p < f->b.ptr[k + 1]; p++) {
            int32_t lo = 0, hi = m - 1, want = f->b.idx[p];
            while (lo < hi) {
                int32_t mid = (lo + hi) / 2;
                if (ifs[mid] < want) lo = mid + 1;
                else hi = mid;
            }
            zz[(size_t)lo * np + (k - k0)] += f->b.val[p];
            if (k - k0 < start[lo]) start[lo] = k - k0;
        }
    for (int32_t q = 0; q < m; q++) *flops += envelope_forward(f, k0, k1, k0 + start[q], zz + (size_t)q * np);
    if (!sc_triplets_reserve(trip, (size_t)m * (size_t)(m + 1) / 2)) {
        free(start);
        return -1;
    }
    for (int32_t qa = 0; qa < m; qa++)
        for (int32_t qb = qa; qb < m; qb++) {
            int32_t s0 = start[qa] > start[qb] ? start[qa] : start[qb];
            const double *za = zz + (size_t)qa * np, *zb = zz + (size_t)qb * np;
            double s = 0;
            for (int32_t k = s0; k < np; k++) s += za[k] * zb[k];
            *flops += 2.0 * (np - s0);
            if (s != 0) sc_triplets_add(trip, ifs[qa], ifs[qb], -s);
        }
    free(start);
    return 0;
}

static int factor_chunk(void *ud, int32_t chunk) {
    factor_job *job = ud;
    int32_t c0 = chunk * job->per_chunk, c1 = c0 + job->per_chunk;
    if (c1 > job->f->nclusters) c1 = job->f->nclusters;
    int32_t *loc = NULL, loc_cap = 0;
    double *z = NULL;
    size_t z_cap = 0;
    int rc = SC_OK;
    job->bad[chunk] = -1;
    for (int32_t c = c0; c < c1; c++) {
        int r = factor_cluster(job, c, &job->trip[chunk], &job->flops[chunk], &loc, &loc_cap, &z, &z_cap);
        if (r < 0) {
            rc = SC_ENOMEM;
            break;
        }
        if (r > 0) {
            job->bad[chunk] = c;
            break;
        }
    }
    free(loc), free(z);
    return rc;
}

typedef struct keyed {
    double key;
    int32_t index;
} keyed;

static int cmp_keyed(const void *pa, const void *pb) {
    const keyed *a = pa, *b = pb;
    if (a->key != b->key) return a->key < b->key ? -1 : 1;
    return a->index < b->index ? -1 : a->index > b->index;
}

/* plan's parallel parts, in fixed chunks: which unknowns are interface
 * (pass 0), and each cluster's unknowns in key order (pass 1) */
typedef struct plan_job {
    const sc_sparse *a;
    const int32_t *group;
    const double *key;
    double key_span;
    uint8_t *is_if;
    const sc_schur *f;
    keyed *tmp;
    int32_t per_chunk;
    int pass;
} plan_job;

static int plan_chunk(void *ud, int32_t chunk) {
    plan_job *job = ud;
    int32_t i0 = chunk * job->per_chunk, i1 = i0 + job->per_chunk;
    if (job->pass == 0) {
        const sc_sparse *a = job->a;
        if (i1 > a->n) i1 = a->n;
        for (int32_t t = i0; t < i1; t++) {
            int32_t gt = job->group[t];
            bool itf = gt < 0;
            for (int32_t p = a->colptr[t]; p < a->colptr[t + 1] && !itf; p++) {
                if (!is_coupling(a, p, t)) continue;
                int32_t u = a->rowind[p], gu = job->group[u];
                itf = gu >= 0 && (gu != gt || fabs(job->key[u] - job->key[t]) > job->key_span);
            }
            job->is_if[t] = itf;
        }
    } else {
        const sc_schur *f = job->f;
        if (i1 > f->nclusters) i1 = f->nclusters;
        for (int32_t c = i0; c < i1; c++)
            qsort(job->tmp + f->cstart[c], (size_t)(f->cstart[c + 1] - f->cstart[c]), sizeof *job->tmp, cmp_keyed);
    }
    return SC_OK;
}

/* Which unknowns are private, and where everything goes. */
static int plan(sc_schur *f, const sc_sparse *a, const int32_t *group, const double *key, double key_span,
                sc_error *err) {
    const int32_t n = a->n;
    uint8_t *is_if = sc_alloc_array((size_t)n, 1);
    int32_t gmax = -1;
    if (!is_if) return sc_fail(err, SC_ENOMEM, "out of memory");
    plan_job job = {.a = a, .group = group, .key = key, .key_span = key_span, .is_if = is_if, .f = f,
                    .per_chunk = ROW_CHUNK};
    if (sc_parallel(f->threads, (n + ROW_CHUNK - 1) / ROW_CHUNK, plan_chunk, &job) != SC_OK) {
        free(is_if);
        return sc_fail(err, SC_ENOMEM, "out of memory");
    }
    for (int32_t t = 0; t < n; t++)
        if (!is_if[t] && group[t] > gmax) gmax = group[t];
    int32_t *count = sc_calloc_array((size_t)gmax + 2, sizeof *count);
    f->order = sc_alloc_array((size_t)n, sizeof *f->order);
    f->position = sc_alloc_array((size_t)n, sizeof *f->position);
    if (!count || !f->order || !f->position) {
        free(is_if), free(count);
        return sc_fail(err, SC_ENOMEM, "out of memory");
    }
    for (int32_t t = 0; t < n; t++)
        if (!is_if[t]) count[group[t] + 1]++;
    int32_t nclusters = 0;
    for (int32_t g = 0; g <= gmax; g++) nclusters += count[g + 1] > 0;
    f->cstart = sc_alloc_array((size_t)nclusters + 1, sizeof *f->cstart);
    if (!f->cstart) {
        free(is_if), free(count);
        return sc_fail(err, SC_ENOMEM, "out of memory");
    }
    /* counting sort by group (stable in the unknown's index) */
    for (int32_t g = 0, c = 0, at = 0; g <= gmax; g++) {
        int32_t cnt = count[g + 1];
        count[g + 1] = at;
        if (cnt > 0) f->cstart[c++] = at;
        at += cnt;
    }
    int32_t npriv = 0;
    for (int32_t t = 0; t < n; t++)
        if (!is_if[t]) f->order[count[group[t] + 1]++] = t, npriv++;
    f->cstart[nclusters] = npriv;
    f->nclusters = nclusters;
    f->npriv = npriv;
    f->nif = n - npriv;
    for (int32_t t = 0, at = npriv; t < n; t++)
        if (is_if[t]) f->order[at++] = t;
    free(count);
    free(is_if);

    /* key order within each cluster (ties by index) */
    keyed *tmp = sc_alloc_array(npriv ? (size_t)npriv : 1, sizeof *tmp);
    if (!tmp) return sc_fail(err, SC_ENOMEM, "out of memory");
    for (int32_t k = 0; k < npriv; k++) tmp[k].key = key[f->order[k]], tmp[k].index = f->order[k];
    job.pass = 1, job.tmp = tmp, job.per_chunk = 256;
    if (sc_parallel(f->threads, (nclusters + 255) / 256, plan_chunk, &job) != SC_OK) {
        free(tmp);
        return sc_fail(err, SC_ENOMEM, "out of memory");
    }
    for (int32_t k = 0; k < npriv; k++) f->order[k] = tmp[k].index;
    free(tmp);
    for (int32_t k = 0; k < n; k++) f->position[f->order[k]] = k;
    return SC_OK;
}

/* Envelope rows, and the couplings between private rows and the interface,
 * in fixed chunks of rows: each chunk counts, the counts are summed in
 * order, and each chunk then places its rows (interface entries go to one
 * triplet list per chunk, assembled in chunk order). */
typedef struct layout_job {
    sc_schur *f;
    const sc_sparse *a;
    int32_t rows_per_chunk, chunks_priv;   /* private chunks first, then interface chunks */
    int64_t *env_count;                    /* per private row: its envelope length */
    sc_triplets *sii;                      /* one per interface chunk */
    int pass;
} layout_job;

static void layout_rows(const layout_job *job, int32_t chunk, int32_t *k0, int32_t *k1, bool *priv) {
    const sc_schur *f = job->f;
    *priv = chunk < job->chunks_priv;
    int32_t c = *priv ? chunk : chunk - job->chunks_priv, limit = *priv ? f->npriv : f->nif;
    *k0 = c * job->rows_per_chunk, *k1 = *k0 + job->rows_per_chunk;
    if (*k1 > limit) *k1 = limit;
}

static int layout_chunk(void *ud, int32_t chunk) {
    layout_job *job = ud;
    sc_schur *f = job->f;
    const sc_sparse *a = job->a;
    const int32_t npriv = f->npriv;
    int32_t k0, k1;
    bool priv;
    layout_rows(job, chunk, &k0, &k1, &priv);
    for (int32_t k = k0; k < k1; k++) {
        int32_t row = priv ? k : npriv + k, t = f->order[row];
        if (job->pass == 0) {
            int32_t fk = k, nb = 0;
            for (int32_t p = a->colptr[t]; p < a->colptr[t + 1]; p++) {
                if (!is_coupling(a, p, t)) continue;
                int32_t q = f->position[a->rowind[p]];
                if (!priv) nb += q < npriv;
                else if (q >= npriv) nb++;
                else if (q < fk) fk = q;
            }
            if (priv) f->first[k] = fk, job->env_count[k] = k - fk + 1, f->b.ptr[k + 1] = nb;
            else f->bt.ptr[k + 1] = nb;
        } else if (priv) {
            int32_t w = f->b.ptr[k];
            for (int32_t p = a->colptr[t]; p < a->colptr[t + 1]; p++) {
                if (!is_coupling(a, p, t)) continue;
                int32_t q = f->position[a->rowind[p]];
                if (q >= npriv) f->b.idx[w] = q - npriv, f->b.val[w++] = a->val[p];
            }
        } else {
            int32_t w = f->bt.ptr[k];
            sc_triplets *sii = &job->sii[chunk - job->chunks_priv];
            for (int32_t p = a->colptr[t]; p < a->colptr[t + 1]; p++) {
                if (!is_coupling(a, p, t)) continue;
                int32_t q = f->position[a->rowind[p]];
                if (q < npriv) f->bt.idx[w] = q, f->bt.val[w++] = a->val[p];
                else if (q - npriv >= k) sc_triplets_add(sii, k, q - npriv, a->val[p]);
            }
            if (sii->failed) return SC_ENOMEM;
        }
    }
    return SC_OK;
}

/* A_ii's entries join sii, chunk after chunk. */
static int layout(sc_schur *f, const sc_sparse *a, sc_triplet_parts *sii, sc_error *err) {
    const int32_t npriv = f->npriv, nif = f->nif;
    f->first = sc_alloc_array(npriv ? (size_t)npriv : 1, sizeof *f->first);
    f->envptr = sc_alloc_array((size_t)npriv + 1, sizeof *f->envptr);
    f->b.ptr = sc_calloc_array((size_t)npriv + 1, sizeof *f->b.ptr);
    f->bt.ptr = sc_calloc_array((size_t)nif + 1, sizeof *f->bt.ptr);
    layout_job job = {.f = f, .a = a, .rows_per_chunk = ROW_CHUNK};
    job.chunks_priv = (npriv + ROW_CHUNK - 1) / ROW_CHUNK;
    int32_t chunks_if = (nif + ROW_CHUNK - 1) / ROW_CHUNK, chunks = job.chunks_priv + chunks_if;
    job.env_count = sc_alloc_array(npriv ? (size_t)npriv : 1, sizeof *job.env_count);
    job.sii = sc_calloc_array(chunks_if ? (size_t)chunks_if : 1, sizeof *job.sii);
    int rc = SC_OK;
    if (!f->first || !f->envptr || !f->b.ptr || !f->bt.ptr || !job.env_count || !job.sii) {
        rc = sc_fail(err, SC_ENOMEM, "out of memory");
        goto done;
    }
    for (int32_t c = 0; c < chunks_if; c++) sc_triplets_init(&job.sii[c], nif);
    if ((rc = sc_parallel(f->threads, chunks, layout_chunk, &job))) goto fail;
    int64_t env = 0, nb = 0, nbt = 0;
    f->envptr[0] = 0;
    for (int32_t k = 0; k < npriv; k++) {
        env += job.env_count[k], f->envptr[k + 1] = env;
        nb += f->b.ptr[k + 1], f->b.ptr[k + 1] = (int32_t)nb;
    }
    for (int32_t i = 0; i < nif; i++) nbt += f->bt.ptr[i + 1], f->bt.ptr[i + 1] = (int32_t)nbt;
    f->env = sc_alloc_array(env ? (size_t)env : 1, sizeof *f->env);
    f->b.idx = sc_alloc_array(nb ? (size_t)nb : 1, sizeof *f->b.idx);
    f->b.val = sc_alloc_array(nb ? (size_t)nb : 1, sizeof *f->b.val);
    f->bt.idx = sc_alloc_array(nbt ? (size_t)nbt : 1, sizeof *f->bt.idx);
    f->bt.val = sc_alloc_array(nbt ? (size_t)nbt : 1, sizeof *f->bt.val);
    if (!f->env || !f->b.idx || !f->b.val || !f->bt.idx || !f->bt.val) {
        rc = sc_fail(err, SC_ENOMEM, "out of memory for %.0f envelope entries", (double)env);
        goto done;
    }
    job.pass = 1;
    if ((rc = sc_parallel(f->threads, chunks, layout_chunk, &job))) goto fail;
    f->stats.envelope = (double)env;
    for (int32_t c = 0; c < chunks_if; c++) sc_triplet_parts_take(sii, &job.sii[c]);
    goto done;
fail:
    rc = sc_fail(err, SC_ENOMEM, "out of memory");
done:
    for (int32_t c = 0; job.sii && c < chunks_if; c++) sc_triplets_free(&job.sii[c]);
    free(job.sii), free(job.env_count);
    return rc;
}

int sc_schur_factor_clusters(const sc_sparse *a, const int32_t *group, const double *key, double key_span,
                             int threads, sc_schur **out, sc_error *err) {
    *out = NULL;
    if (!a || a->n <= 0) return sc_fail(err, SC_EINPUT, "factorisation of an empty matrix");
    sc_schur *f = calloc(1, sizeof *f);
    if (!f) return sc_fail(err, SC_ENOMEM, "out of memory");
    f->n = a->n;
    f->threads = threads < 1 ? 1 : threads;
    double t0 = sc_now();
    /* the interface matrix's entries: layout's lists, then one per cluster chunk */
    sc_triplet_parts sii;
    int rc = plan(f, a, group, key, key_span, err);
    sc_triplet_parts_init(&sii, f->nif);
    if (rc == SC_OK) rc = layout(f, a, &sii, err);

    /* clusters, in fixed chunks */
    int32_t nchunks = f->nclusters < CLUSTER_CHUNKS ? f->nclusters : CLUSTER_CHUNKS;
    factor_job job = {.f = f, .a = a};
    if (rc == SC_OK && nchunks > 0) {
        job.per_chunk = (f->nclusters + nchunks - 1) / nchunks;
        nchunks = (f->nclusters + job.per_chunk - 1) / job.per_chunk;
        job.trip = sc_calloc_array((size_t)nchunks, sizeof *job.trip);
        job.flops = sc_calloc_array((size_t)nchunks, sizeof *job.flops);
        job.bad = sc_calloc_array((size_t)nchunks, sizeof *job.bad);
        if (!job.trip || !job.flops || !job.bad) rc = sc_fail(err, SC_ENOMEM, "out of memory");
        for (int32_t c = 0; rc == SC_OK && c < nchunks; c++) sc_triplets_init(&job.trip[c], f->nif > 0 ? f->nif : 1);
        if (rc == SC_OK && sc_parallel(f->threads, nchunks, factor_chunk, &job) != SC_OK)
            rc = sc_fail(err, SC_ENOMEM, "out of memory factoring %d clusters", (int)f->nclusters);
        for (int32_t c = 0; rc == SC_OK && c < nchunks; c++) {
            if (job.bad[c] >= 0) {
                rc = sc_fail(err, SC_EINPUT,
                             "sparse factorisation: the matrix is not positive definite "
                             "(cluster %d of %d)", (int)job.bad[c], (int)f->nclusters);
                break;
            }
            f->stats.cluster_flops += job.flops[c];
            sc_triplet_parts_take(&sii, &job.trip[c]);
        }
    }
    for (int32_t c = 0; job.trip && c < nchunks; c++) sc_triplets_free(&job.trip[c]);
    free(job.trip), free(job.flops), free(job.bad);

    /* the interface matrix S */
    if (rc == SC_OK && f->nif > 0) {
        rc = sc_sparse_from_triplet_parts(&sii, f->threads, &f->sii, err);
        if (rc == SC_OK) f->stats.interface_nnz = (double)f->sii.nnz;
    }
    sc_triplet_parts_free(&sii);
    if (rc != SC_OK) {
        sc_schur_free(f);
        return rc;
    }
    f->stats.clusters = f->nclusters;
    f->stats.private_unknowns = f->npriv;
    f->stats.interface_unknowns = f->nif;
    f->stats.seconds_clusters = sc_now() - t0;
    *out = f;
    return SC_OK;
}

int sc_schur_factor_interface(sc_schur *f, sc_error *err) {
    if (f->nif == 0 || f->s) return SC_OK;
    double t0 = sc_now();
    /* simplicial unless S's supernodes are big: past 200 flops per entry,
     * not CHOLMOD's own switch at 40, which takes interfaces supernodal that
     * factor and solve faster simplicial (docs/notes/erase_seams.md) */
    sc_sparse_options opt = {.ordering = SC_SPARSE_ORDER_AMD, .kind = SC_SPARSE_AUTO, .supernodal_from = 200,
                             .definite = true};
    int rc = sc_sparse_chol_factor(&f->sii, &opt, &f->s, err);
    if (rc == SC_OK) {
        sc_sparse_stats st;
        sc_sparse_chol_stats(f->s, &st);
        f->stats.interface_factor_nnz = st.factor_nnz;
        f->stats.interface_flops = st.flops;
        f->stats.peak_bytes = st.peak_bytes;
    }
    f->stats.seconds_interface = sc_now() - t0;
    return rc;
}

int sc_schur_factor(const sc_sparse *a, const int32_t *group, const double *key, double key_span, int threads,
                    sc_schur **out, sc_error *err) {
    int rc = sc_schur_factor_clusters(a, group, key, key_span, threads, out, err);
    if (rc == SC_OK && (rc = sc_schur_factor_interface(*out, err))) {
        sc_schur_free(*out);
        *out = NULL;
    }
    return rc;
}

void sc_schur_get_stats(const sc_schur *f, sc_schur_stats *out) { *out = f->stats; }

void sc_schur_free(sc_schur *f) {
    if (!f) return;
    free(f->order), free(f->position), free(f->cstart), free(f->first), free(f->envptr), free(f->env);
    csr_free(&f->b);
    csr_free(&f->bt);
    sc_sparse_free(&f->sii);
    sc_sparse_chol_free(f->s);
    free(f->work), free(f->work_if);
    free(f);
}

/* ---------------------------------------------------------------- solve */

typedef struct solve_job {
    const sc_schur *f;
    double *x;          /* n x nrhs, in positions */
    int32_t nrhs, per_chunk;
    int phase;
} solve_job;

static int solve_chunk(void *ud, int32_t chunk) {
    const solve_job *job = ud;
    const sc_schur *f = job->f;
    const int32_t n = f->n, npriv = f->npriv;
    if (job->phase == 1 || job->phase == 3) {
        int32_t c0 = chunk * job->per_chunk, c1 = c0 + job->per_chunk;
        if (c1 > f->nclusters) c1 = f->nclusters;
        if (c0 >= c1) return SC_OK;
        int32_t k0 = f->cstart[c0], k1 = f->cstart[c1];
        double *w = NULL;
        if (job->phase == 3) {
            w = sc_alloc_array((size_t)(k1 - k0), sizeof *w);
            if (!w) return SC_ENOMEM;
        }
        for (int32_t col = 0; col < job->nrhs; col++) {
            double *x = job->x + (size_t)col * n;
            if (job->phase == 3) {
                /* w = A_pi x_i over these rows; x_p -= A_pp^-1 w */
                for (int32_t k = k0; k < k1; k++) {
                    double s = 0;
                    for (int32_t p = f->b.ptr[k]; p < f->b.ptr[k + 1]; p++) s += f->b.val[p] * x[npriv + f->b.idx[p]];
                    w[k - k0] = s;
                }
            }
            for (int32_t c = c0; c < c1; c++) {
                int32_t a0 = f->cstart[c], a1 = f->cstart[c + 1];
                double *v = job->phase == 1 ? x + a0 : w + (a0 - k0);
                envelope_forward(f, a0, a1, a0, v);
                envelope_backward(f, a0, a1, v);
            }
            if (job->phase == 3)
                for (int32_t k = k0; k < k1; k++) x[k] -= w[k - k0];
        }
        free(w);
    } else {
        /* phase 2: b_i -= A_ip y over these interface rows */
        int32_t i0 = chunk * job->per_chunk, i1 = i0 + job->per_chunk;
        if (i1 > f->nif) i1 = f->nif;
        for (int32_t col = 0; col < job->nrhs; col++) {
            double *x = job->x + (size_t)col * n;
            for (int32_t i = i0; i < i1; i++) {
                double s = x[npriv + i];
                for (int32_t p = f->bt.ptr[i]; p < f->bt.ptr[i + 1]; p++) s -= f->bt.val[p] * x[f->bt.idx[p]];
                x[npriv + i] = s;
            }
        }
    }
    return SC_OK;
}

static int run_phase(solve_job *job, int phase) {
    const sc_schur *f = job->f;
    job->phase = phase;
    int32_t items = phase == 2 ? f->nif : f->nclusters;
    if (items <= 0) return SC_OK;
    int32_t chunks = phase == 2 ? (items + ROW_CHUNK - 1) / ROW_CHUNK
                                : (items < CLUSTER_CHUNKS ? items : CLUSTER_CHUNKS);
    job->per_chunk = (items + chunks - 1) / chunks;
    chunks = (items + job->per_chunk - 1) / job->per_chunk;
    return sc_parallel(f->threads, chunks, solve_chunk, job);
}

/* x (n x nrhs, positions) <- A^-1 x; f->work_if holds nif x nrhs values. */
static int solve_positions(sc_schur *f, int32_t nrhs, double *x, sc_error *err) {
    solve_job job = {.f = f, .x = x, .nrhs = nrhs};
    if (run_phase(&job, 1) || run_phase(&job, 2)) return sc_fail(err, SC_ENOMEM, "out of memory");
    if (f->nif > 0) {
        double *xi = f->work_if;
        for (int32_t c = 0; c < nrhs; c++)
            memcpy(xi + (size_t)c * f->nif, x + (size_t)c * f->n + f->npriv, (size_t)f->nif * sizeof *xi);
        int rc = sc_sparse_chol_solve_threads(f->s, nrhs, xi, f->threads, err);
        if (rc) return rc;
        for (int32_t c = 0; c < nrhs; c++)
            memcpy(x + (size_t)c * f->n + f->npriv, xi + (size_t)c * f->nif, (size_t)f->nif * sizeof *xi);
    }
    if (run_phase(&job, 3)) return sc_fail(err, SC_ENOMEM, "out of memory");
    return SC_OK;
}

/* Scratch for nrhs columns, kept between solves (large blocks freed and
 * allocated again would cost the kernel a page clearing every time). */
static int reserve_work(sc_schur *f, int32_t nrhs, sc_error *err) {
    if (nrhs <= f->work_cols) return SC_OK;
    double *w = sc_realloc_array(f->work, (size_t)f->n * (size_t)nrhs, sizeof *w);
    if (w) f->work = w;
    double *wi = w ? sc_realloc_array(f->work_if, (size_t)(f->nif ? f->nif : 1) * (size_t)nrhs, sizeof *wi) : NULL;
    if (wi) f->work_if = wi;
    if (!w || !wi) return sc_fail(err, SC_ENOMEM, "out of memory for %d right-hand sides", (int)nrhs);
    f->work_cols = nrhs;
    return SC_OK;
}

/* Work over chunks of ROW_CHUNK positions, on all threads: b (unknown
 * order) gathered into x (positions) or x scattered back, and the private
 * rows' b^T y per chunk (part[c * chunks + chunk], for the columns whose
 * target is still to set), which the caller sums in chunk order. */
typedef enum rows_op { ROWS_GATHER, ROWS_SCATTER, ROWS_BPY } rows_op;

typedef struct rows_job {
    const sc_schur *f;
    int32_t nrhs, rows, chunks;
    double *b, *x, *part;
    const double *target;
    rows_op op;
} rows_job;

static int rows_chunk(void *ud, int32_t chunk) {
    const rows_job *j = ud;
    const int32_t n = j->f->n, *order = j->f->order;
    int32_t k0 = chunk * ROW_CHUNK, k1 = k0 + ROW_CHUNK < j->rows ? k0 + ROW_CHUNK : j->rows;
    for (int32_t c = 0; c < j->nrhs; c++) {
        double *b = j->b + (size_t)c * n, *x = j->x + (size_t)c * n;
        if (j->op == ROWS_GATHER) {
            for (int32_t k = k0; k < k1; k++) x[k] = b[order[k]];
        } else if (j->op == ROWS_SCATTER) {
            for (int32_t k = k0; k < k1; k++) b[order[k]] = x[k];
        } else if (j->target[c] < 0) {
            double part = 0;
            for (int32_t k = k0; k < k1; k++) part += b[order[k]] * x[k];
            j->part[(size_t)c * j->chunks + chunk] = part;
        }
    }
    return SC_OK;
}

static int run_rows(rows_job *j, rows_op op, int32_t rows) {
    j->op = op, j->rows = rows, j->chunks = (rows + ROW_CHUNK - 1) / ROW_CHUNK;
    return sc_parallel(j->f->threads, j->chunks, rows_chunk, j);
}

int sc_schur_solve(sc_schur *f, int32_t nrhs, double *b, sc_error *err) {
    if (nrhs <= 0) return SC_OK;
    int rc = reserve_work(f, nrhs, err);
    if (rc) return rc;
    rows_job rj = {.f = f, .nrhs = nrhs, .b = b, .x = f->work};
    if (run_rows(&rj, ROWS_GATHER, f->n)) return sc_fail(err, SC_ENOMEM, "out of memory");
    rc = solve_positions(f, nrhs, f->work, err);
    if (rc == SC_OK && run_rows(&rj, ROWS_SCATTER, f->n)) rc = sc_fail(err, SC_ENOMEM, "out of memory");
    return rc;
}

/* ---------------------------------------------------------------- conjugate gradients */

/* sum_k a[k] b[k] over n, in fixed chunks of rows summed in order */
static double dot(const double *a, const double *b, int32_t n) {
    double total = 0;
    for (int32_t k0 = 0; k0 < n; k0 += ROW_CHUNK) {
        int32_t k1 = k0 + ROW_CHUNK < n ? k0 + ROW_CHUNK : n;
        double s = 0;
        for (int32_t k = k0; k < k1; k++) s += a[k] * b[k];
        total += s;
    }
    return total;
}

/* Products with S (its upper triangle) in two halves of its columns, cut
 * at half its entries, each into its own vector (they are summed after, in
 * order): the same bits on any thread count. */
typedef struct symv_job {
    const sc_sparse *s;
    int32_t cut;
    const double *x;
    double *y;   /* 2 x n */
} symv_job;

static int symv_half(void *ud, int32_t h) {
    const symv_job *j = ud;
    const int32_t n = j->s->n;
    double *y = j->y + (size_t)h * (size_t)n;
    memset(y, 0, (size_t)n * sizeof *y);
    sc_sparse_symv_columns(j->s, h ? j->cut : 0, h ? n : j->cut, j->x, y);
    return SC_OK;
}

/* q = (S + E) p over the interface for the active columns (nif values
 * each): S from its upper triangle (job: its halves), E from its terms
 * (interface indices). */
static int interface_multiply(const sc_schur *f, const sc_triplets *terms, const int32_t *ti, int32_t nrhs,
                              const bool *active, const double *p, double *q, symv_job *job) {
    const int32_t nif = f->nif;
    for (int32_t c = 0; c < nrhs; c++) {
        if (!active[c]) continue;
        const double *pc = p + (size_t)c * nif;
        double *qc = q + (size_t)c * nif;
        job->x = pc;
        if (sc_parallel(f->threads, 2, symv_half, job) != SC_OK) return SC_ENOMEM;
        for (int32_t k = 0; k < nif; k++) qc[k] = job->y[k] + job->y[(size_t)nif + k];
        for (size_t k = 0; k < terms->count; k++) {
            int32_t a = ti[2 * k], b = ti[2 * k + 1];
            double d = terms->val[k] * (pc[a] - pc[b]);
            qc[a] += d, qc[b] -= d;
        }
    }
    return SC_OK;
}

/* Conjugate gradients on (S + E) x_i = g for every column of gi (nif x
 * nrhs, overwritten by x_i), S's factor as the preconditioner, until the
 * residual's S^-1 norm is at most target[c]; scale[c] scales the ratio
 * reported. A target < 0 is set here to tol scale[c], scale[c] being
 * sqrt(b^T A^-1 b) = sqrt(bpy[c] + g^T S^-1 g) (the first preconditioned
 * residual gives the second term). */
static int interface_cg(sc_schur *f, const sc_triplets *terms, const int32_t *ti, int32_t nrhs, double *gi,
                        double *target, double *scale, const double *bpy, double tol, int32_t max_iter,
                        sc_schur_pcg_result *res, sc_error *err) {
    const int32_t nif = f->nif;
    const size_t len = (size_t)nif * (size_t)nrhs;
    double *x = sc_calloc_array(len, sizeof *x), *r = sc_alloc_array(len, sizeof *r);
    double *z = sc_alloc_array(len, sizeof *z), *p = sc_alloc_array(len, sizeof *p);
    double *q = sc_alloc_array(len, sizeof *q), *rz = sc_alloc_array((size_t)nrhs, sizeof *rz);
    double *halves = sc_alloc_array(2 * (size_t)nif, sizeof *halves);
    bool *active = sc_alloc_array((size_t)nrhs, sizeof *active);
    int rc = SC_OK;
    if (!x || !r || !z || !p || !q || !rz || !halves || !active) {
        rc = sc_fail(err, SC_ENOMEM, "out of memory for conjugate gradients on %d unknowns", (int)nif);
        goto done;
    }
    symv_job halves_job = {&f->sii, 0, NULL, halves};
    while (halves_job.cut < nif && 2 * (int64_t)f->sii.colptr[halves_job.cut] < (int64_t)f->sii.colptr[nif])
        halves_job.cut++;
    memcpy(r, gi, len * sizeof *r);
    memcpy(z, r, len * sizeof *z);
    if ((rc = sc_sparse_chol_solve_threads(f->s, nrhs, z, f->threads, err))) goto done;
    int32_t nactive = 0;
    for (int32_t c = 0; c < nrhs; c++) {
        rz[c] = dot(r + (size_t)c * nif, z + (size_t)c * nif, nif);
        if (target[c] < 0) scale[c] = sqrt(bpy[c] + rz[c]), target[c] = tol * scale[c];
        active[c] = rz[c] > 0 && sqrt(rz[c]) > target[c];
        nactive += active[c];
    }
    memcpy(p, z, len * sizeof *p);
    int32_t it = 0;
    while (nactive > 0) {
        if (it == max_iter) {
            double worst = 0, asked = 0;
            for (int32_t c = 0; c < nrhs; c++)
                if (active[c] && sqrt(rz[c]) / scale[c] > worst)
                    worst = sqrt(rz[c]) / scale[c], asked = target[c] / scale[c];
            rc = sc_fail(err, SC_EINPUT,
                         "conjugate gradients did not converge in %d iterations "
                         "(residual ratio %.3g, asked for %.3g)", (int)max_iter, worst, asked);
            goto done;
        }
        it++;
        if (interface_multiply(f, terms, ti, nrhs, active, p, q, &halves_job) != SC_OK) {
            rc = sc_fail(err, SC_ENOMEM, "out of memory for conjugate gradients on %d unknowns", (int)nif);
            goto done;
        }
        for (int32_t c = 0; c < nrhs; c++) {
            if (!active[c]) continue;
            double *pc = p + (size_t)c * nif, *qc = q + (size_t)c * nif;
            double pq = dot(pc, qc, nif);
            if (!(pq > 0)) { /* p is zero: nothing left to gain */
                active[c] = false, nactive--;
                continue;
            }
            double alpha = rz[c] / pq;
            double *xc = x + (size_t)c * nif, *rc_ = r + (size_t)c * nif;
            for (int32_t k = 0; k < nif; k++) xc[k] += alpha * pc[k], rc_[k] -= alpha * qc[k];
        }
        memcpy(z, r, len * sizeof *z);
        if ((rc = sc_sparse_chol_solve_threads(f->s, nrhs, z, f->threads, err))) goto done;
        for (int32_t c = 0; c < nrhs; c++) {
            if (!active[c]) continue;
            double rzn = dot(r + (size_t)c * nif, z + (size_t)c * nif, nif);
            if (!(sqrt(rzn) > target[c])) {
                active[c] = false, nactive--;
                if (sqrt(rzn) / scale[c] > res->relative_residual) res->relative_residual = sqrt(rzn) / scale[c];
                continue;
            }
            double beta = rzn / rz[c];
            rz[c] = rzn;
            double *pc = p + (size_t)c * nif, *zc = z + (size_t)c * nif;
            for (int32_t k = 0; k < nif; k++) pc[k] = zc[k] + beta * pc[k];
        }
    }
    res->iterations += it;
    memcpy(gi, x, len * sizeof *gi);
done:
    free(x), free(r), free(z), free(p), free(q), free(rz), free(halves), free(active);
    return rc;
}

/* One solve of (A + E) x = b, b (n x nrhs, unknown order) overwritten by
 * x: the private unknowns eliminated, conjugate gradients on the interface
 * until each column's residual A^-1 norm is at most target[c], and back
 * substitution. A target < 0 becomes tol sqrt(b^T A^-1 b), and scale[c]
 * sqrt(b^T A^-1 b) (interface_cg). */
static int substructured_solve(sc_schur *f, const sc_triplets *terms, const int32_t *ti, int32_t nrhs, double *b,
                               double *target, double *scale, double tol, int32_t max_iter,
                               sc_schur_pcg_result *res, sc_error *err) {
    const int32_t n = f->n, npriv = f->npriv, nif = f->nif;
    int rc = reserve_work(f, nrhs, err);
    if (rc) return rc;
    /* eliminate the private unknowns: y = A_pp^-1 b_p, g = b_i - A_ip y */
    double *x = f->work, *gi = f->work_if;
    rows_job rj = {.f = f, .nrhs = nrhs, .b = b, .x = x, .target = target};
    if (run_rows(&rj, ROWS_GATHER, n)) return sc_fail(err, SC_ENOMEM, "out of memory");
    solve_job job = {.f = f, .x = x, .nrhs = nrhs};
    if (run_phase(&job, 1) || run_phase(&job, 2)) return sc_fail(err, SC_ENOMEM, "out of memory");
    for (int32_t c = 0; c < nrhs; c++)
        memcpy(gi + (size_t)c * nif, x + (size_t)c * n + npriv, (size_t)nif * sizeof *gi);
    /* b_p^T y, the private part of b^T A^-1 b, where a target is still to set:
     * summed per chunk of rows, then in chunk order */
    int32_t nparts = (npriv + ROW_CHUNK - 1) / ROW_CHUNK;
    double *bpy = sc_calloc_array((size_t)nrhs * ((size_t)nparts + 1), sizeof *bpy);
    if (!bpy) return sc_fail(err, SC_ENOMEM, "out of memory");
    rj.part = bpy + nrhs;
    if (run_rows(&rj, ROWS_BPY, npriv)) {
        free(bpy);
        return sc_fail(err, SC_ENOMEM, "out of memory");
    }
    for (int32_t c = 0; c < nrhs; c++)
        for (int32_t k = 0; k < nparts && target[c] < 0; k++) bpy[c] += rj.part[(size_t)c * nparts + k];
    rc = interface_cg(f, terms, ti, nrhs, gi, target, scale, bpy, tol, max_iter, res, err);
    free(bpy);
    if (rc) return rc;
    /* x_p = y - A_pp^-1 A_pi x_i */
    for (int32_t c = 0; c < nrhs; c++) memcpy(x + (size_t)c * n + npriv, gi + (size_t)c * nif, (size_t)nif * sizeof *x);
    if (run_phase(&job, 3) || run_rows(&rj, ROWS_SCATTER, n)) return sc_fail(err, SC_ENOMEM, "out of memory");
    return SC_OK;
}

/* y = A x for the full-pattern A, rows over up to `threads` threads. */
typedef struct full_rows {
    const sc_sparse *a;
    const double *x, *b;   /* b: y = b - A x instead */
    double *y;
} full_rows;

static int full_rows_chunk(void *ud, int32_t chunk) {
    const full_rows *j = ud;
    int32_t r0 = chunk * ROW_CHUNK, r1 = r0 + ROW_CHUNK < j->a->n ? r0 + ROW_CHUNK : j->a->n;
    for (int32_t r = r0; r < r1; r++) {
        double s = 0;
        for (int32_t p = j->a->colptr[r]; p < j->a->colptr[r + 1]; p++) s += j->a->val[p] * j->x[j->a->rowind[p]];
        j->y[r] = j->b ? j->b[r] - s : s;
    }
    return SC_OK;
}

int sc_schur_solve_terms(sc_schur *f, const sc_sparse *q, const sc_triplets *terms, int32_t nrhs, double *b,
                         double tol, int32_t max_iter, sc_schur_pcg_result *res, sc_error *err) {
    sc_schur_pcg_result local = {0, 0};
    if (!res) res = &local;
    res->iterations = 0;
    res->relative_residual = 0;
    const int32_t n = f->n, npriv = f->npriv;
    if (nrhs <= 0) return SC_OK;
    if (q && q->n != n)
        return sc_fail(err, SC_EINPUT, "conjugate gradients: matrix sizes %d and %d differ", (int)n, (int)q->n);
    int32_t *ti = sc_alloc_array(2 * terms->count + 1, sizeof *ti);
    if (!ti) return sc_fail(err, SC_ENOMEM, "out of memory");
    for (size_t k = 0; k < terms->count; k++) {
        int32_t r = terms->row[k], s = terms->col[k];
        bool ok = r >= 0 && s < n && r < s && terms->val[k] > 0;
        if (ok) ti[2 * k] = f->position[r] - npriv, ti[2 * k + 1] = f->position[s] - npriv;
        if (!ok || ti[2 * k] < 0 || ti[2 * k + 1] < 0) {
            free(ti);
            return sc_fail(err, SC_EINPUT, "term %d, (%d, %d, %g): not a coupling of two interface unknowns",
                           (int)k, (int)r, (int)s, terms->val[k]);
        }
    }
    const size_t len = (size_t)n * (size_t)nrhs;
    double *x = sc_alloc_array(len, sizeof *x), *target = sc_alloc_array(2 * (size_t)nrhs, sizeof *target);
    double *r = q ? sc_alloc_array(len, sizeof *r) : NULL;
    int rc = x && target && (r || !q) ? SC_OK : sc_fail(err, SC_ENOMEM, "out of memory");
    double *scale = target ? target + nrhs : NULL;
    if (rc == SC_OK) {
        memcpy(x, b, len * sizeof *x);
        for (int32_t c = 0; c < nrhs; c++) target[c] = -1;
        rc = substructured_solve(f, terms, ti, nrhs, x, target, scale, tol, max_iter, res, err);
    }
    if (rc == SC_OK && q) {
        /* one round of refinement on the residual of Q itself: the
         * factorisation of A is exact only to rounding, which Q's
         * conditioning (the seam penalty) turns into ~1e-10 of b */
        for (int32_t c = 0; c < nrhs; c++) {
            full_rows fr = {q, x + (size_t)c * n, b + (size_t)c * n, r + (size_t)c * n};
            int32_t chunks = (n + ROW_CHUNK - 1) / ROW_CHUNK;
            if (sc_parallel(f->threads, chunks, full_rows_chunk, &fr) != SC_OK)
                for (int32_t k = 0; k < chunks; k++) full_rows_chunk(&fr, k);
        }
        res->relative_residual = 0;
        rc = substructured_solve(f, terms, ti, nrhs, r, target, scale, tol, max_iter, res, err);
        for (size_t i = 0; rc == SC_OK && i < len; i++) x[i] += r[i];
    }
    if (rc == SC_OK) memcpy(b, x, len * sizeof *b);
    free(ti), free(x), free(target), free(r);
    return rc;
}
