/* sc_sparse.c - triplets -> CSC, and a thin layer over CHOLMOD.
 *
 * Design note. Assembly is a counting sort by column followed by a stable
 * merge sort of each column by row, so duplicates are summed in insertion
 * order: the same triplets give the same bits whatever happened before (the
 * callers emit triplets in a fixed order, whatever their thread count).
 * Triplets are the upper triangle; the matrix is stored as its upper
 * triangle, which is what CHOLMOD reads for stype = 1, or as its full
 * pattern (each triplet placed in both of its columns, so the two copies of
 * an entry are the same sum), which row-wise users want (CHOLMOD ignores
 * its lower half). Triplets may come as several lists (sc_triplet_parts,
 * made apart by chunks of work), read end to end without being copied into
 * one. On several threads the triplets are cut into consecutive ranges,
 * each counted and scattered by its own thread into its own slots of every
 * column (range after range, so a column still holds its entries in the
 * order they were added), and the columns are then sorted and summed in
 * ranges of about equal entries: the same bits for any thread count. The
 * full pattern of an upper triangle (sc_sparse_full) is made the same way,
 * by ranges of upper columns. Assembly can also reserve entries a caller
 * will add to later (rows given per column, as zeros), so that terms known
 * by their structure are added straight into the assembled matrix instead
 * of going through triplets.
 *
 * BLAS runs on the calling thread but in large factorisations (blas_find).
 * Solves with a simplicial L L^T factor can also run on two threads, its
 * elimination tree split in fixed halves (tree_split).
 *
 * Factorisations and solves are bit-reproducible for one CHOLMOD and one
 * BLAS on one kind of processor, not across them: OpenBLAS picks its inner
 * kernels by the processor it finds (DYNAMIC_ARCH), and their order of
 * summation differs. The kernel's platform text (sparse_platform) names the
 * CHOLMOD version and the BLAS's build and core, so a result is shared only
 * between machines that would compute the same bits.
 *
 * CHOLMOD is driven with one cholmod_common per factorisation (so several
 * nodes may factor at once on different threads), printing switched off, and
 * its status turned into sc_error messages. Our CSC arrays are handed to
 * CHOLMOD through a cholmod_sparse header that points at them: no copy.
 */
#include "sc_sparse.h"

#include <cholmod.h>
#include <dlfcn.h>
#include <math.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static char platform_text[320];

static void platform_find(void) {
    char *(*config)(void) = NULL, *(*core)(void) = NULL;
    *(void **)&config = dlsym(RTLD_DEFAULT, "openblas_get_config");
    *(void **)&core = dlsym(RTLD_DEFAULT, "openblas_get_corename");
    snprintf(platform_text, sizeof platform_text, "cholmod %d.%d.%d; blas %s; core %s",
             CHOLMOD_MAIN_VERSION, CHOLMOD_SUB_VERSION, CHOLMOD_SUBSUB_VERSION,
             config ? config() : "reference", core ? core() : "any");
}

static const char *sparse_platform(void) {
    static pthread_once_t once = PTHREAD_ONCE_INIT;
    pthread_once(&once, platform_find);
    return platform_text;
}

const sc_kernel sc_kernel_sparse = {"sparse", SC_SPARSE_VERSION, NULL, sparse_platform};

/* ---------------------------------------------------------------- triplets */

void sc_triplets_init(sc_triplets *t, int32_t n) {
    memset(t, 0, sizeof *t);
    t->n = n;
}

void sc_triplets_free(sc_triplets *t) {
    free(t->row);
    free(t->col);
    free(t->val);
    memset(t, 0, sizeof *t);
}

bool sc_triplets_reserve(sc_triplets *t, size_t extra) {
    if (t->failed) return false;
    if (t->count + extra <= t->cap) return true;
    size_t cap = t->cap ? t->cap : 1024;
    while (cap < t->count + extra) cap *= 2;
    int32_t *r = sc_realloc_array(t->row, cap, sizeof *r);
    if (r) t->row = r;
    int32_t *c = r ? sc_realloc_array(t->col, cap, sizeof *c) : NULL;
    if (c) t->col = c;
    double *v = c ? sc_realloc_array(t->val, cap, sizeof *v) : NULL;
    if (v) t->val = v;
    if (!r || !c || !v) {
        t->failed = true;
        return false;
    }
    t->cap = cap;
    return true;
}

void sc_triplets_add(sc_triplets *t, int32_t i, int32_t j, double v) {
    if (t->count == t->cap && !sc_triplets_reserve(t, 1)) return;
    if (i > j) {
        int32_t k = i;
        i = j, j = k;
    }
    t->row[t->count] = i;
    t->col[t->count] = j;
    t->val[t->count] = v;
    t->count++;
}

void sc_triplets_append(sc_triplets *t, const sc_triplets *src) {
    if (src->failed) t->failed = true;
    if (!src->count || !sc_triplets_reserve(t, src->count)) return;
    memcpy(t->row + t->count, src->row, src->count * sizeof *t->row);
    memcpy(t->col + t->count, src->col, src->count * sizeof *t->col);
    memcpy(t->val + t->count, src->val, src->count * sizeof *t->val);
    t->count += src->count;
}

void sc_triplet_parts_init(sc_triplet_parts *p, int32_t n) {
    memset(p, 0, sizeof *p);
    p->n = n;
}

void sc_triplet_parts_free(sc_triplet_parts *p) {
    for (int32_t k = 0; k < p->count; k++) sc_triplets_free(&p->list[k]);
    free(p->list);
    memset(p, 0, sizeof *p);
}

void sc_triplet_parts_take(sc_triplet_parts *p, sc_triplets *t) {
    int32_t n = t->n;
    if (t->failed) p->failed = true;
    if (!p->failed && t->count > 0 && p->count == p->cap) {
        int32_t cap = p->cap ? 2 * p->cap : 16;
        sc_triplets *l = sc_realloc_array(p->list, (size_t)cap, sizeof *l);
        if (l) p->list = l, p->cap = cap;
        else p->failed = true;
    }
    if (!p->failed && t->count > 0 && t->cap > t->count) {   /* room it did not use goes back */
        int32_t *r = sc_realloc_array(t->row, t->count, sizeof *r);
        if (r) t->row = r;
        int32_t *c = sc_realloc_array(t->col, t->count, sizeof *c);
        if (c) t->col = c;
        double *v = sc_realloc_array(t->val, t->count, sizeof *v);
        if (v) t->val = v;
        t->cap = t->count;
    }
    if (!p->failed && t->count > 0) p->list[p->count++] = *t;
    else sc_triplets_free(t);
    sc_triplets_init(t, n);
}

/* ---------------------------------------------------------------- assembly */

/* Stable sort of (row, val) pairs by row: insertion sort for short runs,
 * bottom-up merge sort (with scratch of the same length) for long ones. */
static void sort_column(int32_t *row, double *val, int32_t len, int32_t *trow, double *tval) {
    if (len < 2) return;
    if (len <= 32) {
        for (int32_t a = 1; a < len; a++) {
            int32_t r = row[a];
            double v = val[a];
            int32_t b = a;
            while (b > 0 && row[b - 1] > r) {
                row[b] = row[b - 1];
                val[b] = val[b - 1];
                b--;
            }
            row[b] = r, val[b] = v;
        }
        return;
    }
    int32_t *sr = row, *dr = trow;
    double *sv = val, *dv = tval;
    for (int32_t width = 1; width < len; width *= 2) {
        for (int32_t lo = 0; lo < len; lo += 2 * width) {
            int32_t mid = lo + width < len ? lo + width : len;
            int32_t hi = lo + 2 * width < len ? lo + 2 * width : len;
            int32_t a = lo, b = mid, k = lo;
            while (a < mid && b < hi) {
                if (sr[b] < sr[a]) dr[k] = sr[b], dv[k++] = sv[b++];
                else dr[k] = sr[a], dv[k++] = sv[a++];
            }
            while (a < mid) dr[k] = sr[a], dv[k++] = sv[a++];
            while (b < hi) dr[k] = sr[b], dv[k++] = sv[b++];
        }
        int32_t *xr = sr;
        sr = dr, dr = xr;
        double *xv = sv;
        sv = dv, dv = xv;
    }
    if (sr != row) {
        memcpy(row, sr, (size_t)len * sizeof *row);
        memcpy(val, sv, (size_t)len * sizeof *val);
    }
}

/* Assembly runs in `parts` pieces, each on its own thread: part p first
 * counts and scatters the triplets of its own range [first[p], first[p+1])
 * of the sources laid end to end, so within a column the entries of part p
 * follow those of part p - 1 (the order they were added in); then it sorts
 * and sums the columns of its own column range. */
#define ASSEMBLY_MAX_PARTS 8
#define ASSEMBLY_MIN_PER_PART 65536   /* fewer triplets per part: not worth a thread */

/* How many parts `entries` entries are worth on `threads` threads. */
static int32_t part_count(int threads, int64_t entries) {
    int64_t most = entries / ASSEMBLY_MIN_PER_PART;
    int32_t parts = threads < ASSEMBLY_MAX_PARTS ? threads : ASSEMBLY_MAX_PARTS;
    if (parts > most) parts = most > 1 ? (int32_t)most : 1;
    return parts < 1 ? 1 : parts;
}

/* col0[p] .. col0[p + 1]: the columns of part p, parts of about equal
 * entries (colptr: n + 1 column starts). */
static void split_columns(const int32_t *colptr, int32_t n, int32_t parts, int32_t *col0) {
    col0[0] = 0;
    for (int32_t p = 1; p < parts; p++) {
        int64_t target = (int64_t)colptr[n] * p / parts;
        int32_t lo = col0[p - 1], hi = n;
        while (lo < hi) {
            int32_t mid = lo + (hi - lo) / 2;
            if (colptr[mid] < target) lo = mid + 1;
            else hi = mid;
        }
        col0[p] = lo;
    }
    col0[parts] = n;
}

/* cursor (parts x n) holds how many entries each part gives each column:
 * colptr gets the column starts, and cursor where each part's entries of
 * each column begin (part after part, then extra_start[j + 1] -
 * extra_start[j] more when extra_start is given). */
static void column_starts(int32_t *cursor, int32_t n, int32_t parts, const int32_t *extra_start, int32_t *colptr) {
    int32_t at = 0;
    for (int32_t j = 0; j < n; j++) {
        colptr[j] = at;
        for (int32_t p = 0; p < parts; p++) {
            int32_t *c = &cursor[(size_t)p * (size_t)n + (size_t)j];
            int32_t count = *c;
            *c = at;
            at += count;
        }
        if (extra_start) at += extra_start[j + 1] - extra_start[j];
    }
    colptr[n] = at;
}

typedef struct assembly {
    const sc_triplets *src;
    int32_t nsrc;
    size_t *start;          /* nsrc + 1: where each source begins, end to end */
    int32_t n, parts;
    bool full;              /* both triangles: (i, j) also goes to column i as row j */
    const int32_t *extra_start, *extra_rows;   /* rows each column also holds, or NULL */
    size_t first[ASSEMBLY_MAX_PARTS + 1];     /* triplet range of each part */
    bool bad[ASSEMBLY_MAX_PARTS];             /* an entry out of range in it */
    int32_t bad_row[ASSEMBLY_MAX_PARTS], bad_col[ASSEMBLY_MAX_PARTS];   /* the first such */
    int32_t *cursor;        /* parts x n: entries per column in each part, then where the next goes */
    int32_t *colptr;        /* n + 1: the columns before summing duplicates */
    int32_t *rows;
    double *vals;
    int32_t col0[ASSEMBLY_MAX_PARTS + 1];     /* column range of each part (sorting) */
    int32_t *distinct;      /* n: distinct rows of each column */
} assembly;

/* The piece of source s that part `part` covers: entries [*k0, *k1). */
static void part_span(const assembly *a, int32_t part, int32_t s, size_t *k0, size_t *k1) {
    size_t lo = a->first[part] > a->start[s] ? a->first[part] : a->start[s];
    size_t hi = a->first[part + 1] < a->start[s + 1] ? a->first[part + 1] : a->start[s + 1];
    *k0 = lo - a->start[s], *k1 = hi > lo ? hi - a->start[s] : *k0;
}

static int assembly_count(void *ud, int32_t part) {
    assembly *a = ud;
    int32_t *count = a->cursor + (size_t)part * (size_t)a->n;
    a->bad[part] = false;
    for (int32_t s = 0; s < a->nsrc; s++) {
        const sc_triplets *t = &a->src[s];
        size_t k0, k1;
        part_span(a, part, s, &k0, &k1);
        for (size_t k = k0; k < k1; k++) {
            int32_t i = t->row[k], j = t->col[k];
            if (i < 0 || j >= a->n || i > j) {
                a->bad[part] = true, a->bad_row[part] = i, a->bad_col[part] = j;
                return SC_EINPUT;
            }
            count[j]++;
            if (a->full && i != j) count[i]++;
        }
    }
    return SC_OK;
}

static int assembly_scatter(void *ud, int32_t part) {
    assembly *a = ud;
    int32_t *next = a->cursor + (size_t)part * (size_t)a->n;
    for (int32_t s = 0; s < a->nsrc; s++) {
        const sc_triplets *t = &a->src[s];
        size_t k0, k1;
        part_span(a, part, s, &k0, &k1);
        for (size_t k = k0; k < k1; k++) {
            int32_t i = t->row[k], j = t->col[k], p = next[j]++;
            a->rows[p] = i;
            a->vals[p] = t->val[k];
            if (a->full && i != j) {
                p = next[i]++;
                a->rows[p] = j;
                a->vals[p] = t->val[k];
            }
        }
    }
    return SC_OK;
}

/* Sort the columns of the part, sum duplicates, and pack the result from
 * the part's first entry on (distinct[j] says how many each column kept). */
static int assembly_sum(void *ud, int32_t part) {
    assembly *a = ud;
    int32_t j0 = a->col0[part], j1 = a->col0[part + 1];
    int32_t longest = 0;
    for (int32_t j = j0; j < j1; j++)
        if (a->colptr[j + 1] - a->colptr[j] > longest) longest = a->colptr[j + 1] - a->colptr[j];
    int32_t *trow = sc_alloc_array((size_t)longest + 1, sizeof *trow);
    double *tval = sc_alloc_array((size_t)longest + 1, sizeof *tval);
    if (!trow || !tval) {
        free(trow), free(tval);
        return SC_ENOMEM;
    }
    int32_t *rows = a->rows;
    double *vals = a->vals;
    int32_t w = a->colptr[j0];
    for (int32_t j = j0; j < j1; j++) {
        int32_t p0 = a->colptr[j], p1 = a->colptr[j + 1], w0 = w;
        if (a->extra_start) {   /* the extra rows close the column, as zeros */
            int32_t e0 = a->extra_start[j], ne = a->extra_start[j + 1] - e0;
            for (int32_t e = 0; e < ne; e++) rows[p1 - ne + e] = a->extra_rows[e0 + e], vals[p1 - ne + e] = 0;
        }
        sort_column(rows + p0, vals + p0, p1 - p0, trow, tval);
        for (int32_t p = p0; p < p1;) {
            int32_t r = rows[p];
            double s = vals[p++];
            while (p < p1 && rows[p] == r) s += vals[p++];
            rows[w] = r;
            vals[w] = s;
            w++;
        }
        a->distinct[j] = w - w0;
    }
    free(trow), free(tval);
    return SC_OK;
}

int sc_sparse_from_triplets(const sc_triplets *t, sc_sparse *out, sc_error *err) {
    return sc_sparse_from_triplets_threads(t, 1, out, err);
}

/* The triplets of src[0 .. nsrc), laid end to end, for a matrix of size n:
 * its upper triangle, or with `full` both triangles; extra_start and
 * extra_rows (or NULL) give rows each column holds as well. */
static int assemble(const sc_triplets *src, int32_t nsrc, int32_t n, bool full, const int32_t *extra_start,
                    const int32_t *extra_rows, int threads, sc_sparse *out, sc_error *err) {
    memset(out, 0, sizeof *out);
    size_t count = 0;
    for (int32_t s = 0; s < nsrc; s++) {
        if (src[s].failed) return sc_fail(err, SC_ENOMEM, "out of memory assembling a sparse matrix");
        if (src[s].n != n)
            return sc_fail(err, SC_EINPUT, "sparse triplets of sizes %d and %d", (int)n, (int)src[s].n);
        count += src[s].count;
    }
    if (n <= 0) return sc_fail(err, SC_EINPUT, "sparse matrix of size %d", (int)n);
    for (int32_t e = 0; extra_start && e < extra_start[n]; e++)
        if (extra_rows[e] < 0 || extra_rows[e] >= n)
            return sc_fail(err, SC_EINPUT, "sparse row %d outside a %d x %d matrix", (int)extra_rows[e], (int)n,
                           (int)n);
    size_t placed = (full ? 2 * count : count) + (extra_start ? (size_t)extra_start[n] : 0);   /* an upper bound */
    if (placed > (size_t)INT32_MAX)
        return sc_fail(err, SC_ENOMEM, "sparse matrix with %zu entries is beyond the 2^31 limit",
                       placed);
    assembly a = {.src = src, .nsrc = nsrc, .n = n, .full = full, .extra_start = extra_start,
                  .extra_rows = extra_rows, .parts = part_count(threads, (int64_t)count)};
    for (int32_t p = 0; p <= a.parts; p++) a.first[p] = count / (size_t)a.parts * (size_t)p;
    a.first[a.parts] = count;
    a.start = sc_alloc_array((size_t)nsrc + 1, sizeof *a.start);
    a.colptr = sc_calloc_array((size_t)n + 1, sizeof *a.colptr);
    a.cursor = sc_calloc_array((size_t)n * (size_t)a.parts, sizeof *a.cursor);
    a.rows = sc_alloc_array(placed ? placed : 1, sizeof *a.rows);
    a.vals = sc_alloc_array(placed ? placed : 1, sizeof *a.vals);
    int rc = a.start && a.colptr && a.cursor && a.rows && a.vals ? SC_OK : SC_ENOMEM;
    if (rc == SC_OK) {
        a.start[0] = 0;
        for (int32_t s = 0; s < nsrc; s++) a.start[s + 1] = a.start[s] + src[s].count;
    }
    if (rc == SC_OK && (rc = sc_parallel(threads, a.parts, assembly_count, &a)) == SC_EINPUT) {
        for (int32_t p = 0; p < a.parts; p++)
            if (a.bad[p]) {
                sc_fail(err, SC_EINPUT, "sparse entry (%d, %d) outside a %d x %d matrix",
                        (int)a.bad_row[p], (int)a.bad_col[p], (int)n, (int)n);
                break;
            }
    }
    if (rc == SC_OK) {
        column_starts(a.cursor, n, a.parts, extra_start, a.colptr);
        rc = sc_parallel(threads, a.parts, assembly_scatter, &a);
    }
    free(a.cursor), free(a.start);
    a.cursor = NULL;
    a.distinct = rc == SC_OK ? sc_alloc_array((size_t)n, sizeof *a.distinct) : NULL;
    if (rc == SC_OK && !a.distinct) rc = SC_ENOMEM;
    if (rc == SC_OK) {
        split_columns(a.colptr, n, a.parts, a.col0);
        rc = sc_parallel(threads, a.parts, assembly_sum, &a);
    }
    if (rc == SC_OK) {
        /* close the gaps the summed duplicates left, part after part */
        int32_t w = 0;
        for (int32_t p = 0; p < a.parts; p++) {
            int32_t from = a.colptr[a.col0[p]], len = 0;
            for (int32_t j = a.col0[p]; j < a.col0[p + 1]; j++) {
                a.colptr[j] = w + len;
                len += a.distinct[j];
            }
            if (from != w && len > 0) {
                memmove(a.rows + w, a.rows + from, (size_t)len * sizeof *a.rows);
                memmove(a.vals + w, a.vals + from, (size_t)len * sizeof *a.vals);
            }
            w += len;
        }
        a.colptr[n] = w;
        if (w > 0) {
            int32_t *r2 = sc_realloc_array(a.rows, (size_t)w, sizeof *r2);
            if (r2) a.rows = r2;
            double *v2 = sc_realloc_array(a.vals, (size_t)w, sizeof *v2);
            if (v2) a.vals = v2;
        }
    }
    free(a.distinct);
    if (rc) {
        free(a.colptr), free(a.rows), free(a.vals);
        if (rc == SC_EINPUT) return rc;
        return sc_fail(err, SC_ENOMEM, "out of memory assembling a sparse matrix");
    }
    out->n = n;
    out->nnz = a.colptr[n];
    out->colptr = a.colptr;
    out->rowind = a.rows;
    out->val = a.vals;
    return SC_OK;
}

int sc_sparse_from_triplets_threads(const sc_triplets *t, int threads, sc_sparse *out, sc_error *err) {
    return assemble(t, 1, t->n, false, NULL, NULL, threads, out, err);
}

static int assemble_parts(const sc_triplet_parts *p, bool full, const int32_t *extra_start,
                          const int32_t *extra_rows, int threads, sc_sparse *out, sc_error *err) {
    if (p->failed) {
        memset(out, 0, sizeof *out);
        return sc_fail(err, SC_ENOMEM, "out of memory assembling a sparse matrix");
    }
    return assemble(p->list, p->count, p->n, full, extra_start, extra_rows, threads, out, err);
}

int sc_sparse_from_triplet_parts(const sc_triplet_parts *p, int threads, sc_sparse *out, sc_error *err) {
    return assemble_parts(p, false, NULL, NULL, threads, out, err);
}

int sc_sparse_full_from_triplet_parts(const sc_triplet_parts *p, const int32_t *extra_start,
                                      const int32_t *extra_rows, int threads, sc_sparse *full, sc_error *err) {
    return assemble_parts(p, true, extra_start, extra_rows, threads, full, err);
}

int64_t sc_sparse_find(const sc_sparse *a, int32_t i, int32_t j) {
    int32_t lo = a->colptr[j], hi = a->colptr[j + 1];
    while (lo < hi) {
        int32_t mid = lo + (hi - lo) / 2;
        if (a->rowind[mid] < i) lo = mid + 1;
        else hi = mid;
    }
    return lo < a->colptr[j + 1] && a->rowind[lo] == i ? lo : -1;
}

void sc_sparse_free(sc_sparse *a) {
    if (!a) return;
    free(a->colptr);
    free(a->rowind);
    free(a->val);
    memset(a, 0, sizeof *a);
}

int sc_sparse_add(const sc_sparse *a, double alpha, const sc_sparse *b, double beta, sc_sparse *c,
                  sc_error *err) {
    memset(c, 0, sizeof *c);
    if (a->n != b->n) return sc_fail(err, SC_EINPUT, "adding sparse matrices of sizes %d and %d",
                                     (int)a->n, (int)b->n);
    int32_t n = a->n;
    int64_t cap = a->nnz + b->nnz;
    if (cap > INT32_MAX) return sc_fail(err, SC_ENOMEM, "sparse sum beyond the 2^31 limit");
    c->colptr = sc_alloc_array((size_t)n + 1, sizeof *c->colptr);
    c->rowind = sc_alloc_array(cap ? (size_t)cap : 1, sizeof *c->rowind);
    c->val = sc_alloc_array(cap ? (size_t)cap : 1, sizeof *c->val);
    if (!c->colptr || !c->rowind || !c->val) {
        sc_sparse_free(c);
        return sc_fail(err, SC_ENOMEM, "out of memory adding sparse matrices");
    }
    int32_t w = 0;
    for (int32_t j = 0; j < n; j++) {
        c->colptr[j] = w;
        int32_t p = a->colptr[j], pe = a->colptr[j + 1], q = b->colptr[j], qe = b->colptr[j + 1];
        while (p < pe || q < qe) {
            int32_t ra = p < pe ? a->rowind[p] : INT32_MAX, rb = q < qe ? b->rowind[q] : INT32_MAX;
            if (ra == rb) {
                c->rowind[w] = ra, c->val[w++] = alpha * a->val[p++] + beta * b->val[q++];
            } else if (ra < rb) {
                c->rowind[w] = ra, c->val[w++] = alpha * a->val[p++];
            } else {
                c->rowind[w] = rb, c->val[w++] = beta * b->val[q++];
            }
        }
    }
    c->colptr[n] = w;
    c->n = n;
    c->nnz = w;
    return SC_OK;
}

int sc_sparse_submatrix(const sc_sparse *a, const int32_t *keep, int32_t count, sc_sparse *out,
                        sc_error *err) {
    memset(out, 0, sizeof *out);
    int64_t nnz = 0;
    for (int32_t j = 0; j < a->n; j++)
        if (keep[j] >= 0)
            for (int32_t p = a->colptr[j]; p < a->colptr[j + 1]; p++) nnz += keep[a->rowind[p]] >= 0;
    out->colptr = sc_calloc_array((size_t)count + 1, sizeof *out->colptr);
    out->rowind = sc_alloc_array(nnz ? (size_t)nnz : 1, sizeof *out->rowind);
    out->val = sc_alloc_array(nnz ? (size_t)nnz : 1, sizeof *out->val);
    if (!out->colptr || !out->rowind || !out->val) {
        sc_sparse_free(out);
        return sc_fail(err, SC_ENOMEM, "out of memory");
    }
    int32_t w = 0;
    for (int32_t j = 0; j < a->n; j++) {
        if (keep[j] < 0) continue;
        out->colptr[keep[j]] = w;
        for (int32_t p = a->colptr[j]; p < a->colptr[j + 1]; p++) {
            int32_t r = keep[a->rowind[p]];
            if (r >= 0) out->rowind[w] = r, out->val[w++] = a->val[p];
        }
    }
    out->colptr[count] = w;
    out->n = count;
    out->nnz = w;
    return SC_OK;
}

void sc_sparse_symv(const sc_sparse *a, const double *x, double *y) {
    memset(y, 0, (size_t)a->n * sizeof *y);
    sc_sparse_symv_columns(a, 0, a->n, x, y);
}

void sc_sparse_symv_columns(const sc_sparse *a, int32_t c0, int32_t c1, const double *x, double *y) {
    for (int32_t j = c0; j < c1; j++) {
        double xj = x[j], acc = 0;
        for (int32_t p = a->colptr[j]; p < a->colptr[j + 1]; p++) {
            int32_t i = a->rowind[p];
            double v = a->val[p];
            if (i == j) {
                acc += v * xj;
            } else {
                acc += v * x[i];
                y[i] += v * xj;
            }
        }
        y[j] += acc;
    }
}

/* The full pattern in parts, each on its own thread: part p counts and
 * then places the entries of the upper columns [col0[p], col0[p + 1]);
 * every column of the result receives its rows in increasing order of the
 * upper column they come from, part after part, so the result does not
 * depend on the number of parts. */
typedef struct mirror_job {
    const sc_sparse *u;
    sc_sparse *f;
    int32_t parts;
    int32_t col0[ASSEMBLY_MAX_PARTS + 1];
    int32_t *cursor;   /* parts x n: entries each part gives each column, then where the next goes */
} mirror_job;

static int mirror_count(void *ud, int32_t part) {
    mirror_job *m = ud;
    const sc_sparse *u = m->u;
    int32_t *count = m->cursor + (size_t)part * (size_t)u->n;
    for (int32_t j = m->col0[part]; j < m->col0[part + 1]; j++)
        for (int32_t p = u->colptr[j]; p < u->colptr[j + 1]; p++) {
            int32_t i = u->rowind[p];
            count[j]++;
            if (i != j) count[i]++;
        }
    return SC_OK;
}

static int mirror_place(void *ud, int32_t part) {
    mirror_job *m = ud;
    const sc_sparse *u = m->u;
    sc_sparse *f = m->f;
    int32_t *next = m->cursor + (size_t)part * (size_t)u->n;
    /* column c gets its own upper rows (<= c) at j = c, then rows j > c in
     * increasing j: sorted */
    for (int32_t j = m->col0[part]; j < m->col0[part + 1]; j++)
        for (int32_t p = u->colptr[j]; p < u->colptr[j + 1]; p++) {
            int32_t i = u->rowind[p];
            double v = u->val[p];
            f->rowind[next[j]] = i, f->val[next[j]++] = v;
            if (i != j) f->rowind[next[i]] = j, f->val[next[i]++] = v;
        }
    return SC_OK;
}

int sc_sparse_full(const sc_sparse *u, sc_sparse *f, sc_error *err) {
    return sc_sparse_full_threads(u, 1, f, err);
}

int sc_sparse_full_threads(const sc_sparse *u, int threads, sc_sparse *f, sc_error *err) {
    memset(f, 0, sizeof *f);
    int32_t n = u->n;
    int64_t nnz = 2 * u->nnz;
    for (int32_t j = 0; j < n; j++)
        if (u->colptr[j + 1] > u->colptr[j] && u->rowind[u->colptr[j + 1] - 1] == j) nnz--;
    if (nnz > INT32_MAX) return sc_fail(err, SC_ENOMEM, "symmetric matrix beyond the 2^31 limit");
    mirror_job m = {.u = u, .f = f, .parts = part_count(threads, u->nnz)};
    split_columns(u->colptr, n, m.parts, m.col0);   /* upper columns, parts of about equal entries */
    f->colptr = sc_alloc_array((size_t)n + 1, sizeof *f->colptr);
    f->rowind = sc_alloc_array(nnz ? (size_t)nnz : 1, sizeof *f->rowind);
    f->val = sc_alloc_array(nnz ? (size_t)nnz : 1, sizeof *f->val);
    m.cursor = sc_calloc_array((size_t)n * (size_t)m.parts, sizeof *m.cursor);
    int rc = f->colptr && f->rowind && f->val && m.cursor ? SC_OK : SC_ENOMEM;
    if (rc == SC_OK) rc = sc_parallel(threads, m.parts, mirror_count, &m);
    if (rc == SC_OK) {
        column_starts(m.cursor, n, m.parts, NULL, f->colptr);
        rc = sc_parallel(threads, m.parts, mirror_place, &m);
    }
    free(m.cursor);
    if (rc) {
        sc_sparse_free(f);
        return sc_fail(err, SC_ENOMEM, "out of memory for a symmetric matrix");
    }
    f->n = n;
    f->nnz = nnz;
    return SC_OK;
}

double sc_sparse_quadform(const sc_sparse *a, const double *x) {
    double s = 0;
    for (int32_t j = 0; j < a->n; j++) {
        double acc = 0;
        for (int32_t p = a->colptr[j]; p < a->colptr[j + 1]; p++) {
            int32_t i = a->rowind[p];
            acc += (i == j ? 1.0 : 2.0) * a->val[p] * x[i];
        }
        s += acc * x[j];
    }
    return s;
}

double sc_sparse_diag(const sc_sparse *a, int32_t i) {
    int32_t p1 = a->colptr[i + 1];
    if (p1 > a->colptr[i] && a->rowind[p1 - 1] == i) return a->val[p1 - 1];
    return 0;
}

double sc_sparse_norm_bound(const sc_sparse *a) {
    double *rs = sc_calloc_array((size_t)a->n, sizeof *rs);
    if (!rs) return INFINITY;
    for (int32_t j = 0; j < a->n; j++)
        for (int32_t p = a->colptr[j]; p < a->colptr[j + 1]; p++) {
            int32_t i = a->rowind[p];
            rs[j] += fabs(a->val[p]);
            if (i != j) rs[i] += fabs(a->val[p]);
        }
    double m = 0;
    for (int32_t j = 0; j < a->n; j++)
        if (rs[j] > m) m = rs[j];
    free(rs);
    return m;
}

/* ---------------------------------------------------------------- CHOLMOD */

typedef struct tree_split tree_split;

struct sc_sparse_chol {
    cholmod_common common;
    cholmod_factor *L;
    int32_t n;
    sc_sparse_stats stats;
    tree_split *split;   /* sc_sparse_chol_solve_threads's plan, made at its first call */
    bool split_tried;
};

static void header(const sc_sparse *a, cholmod_sparse *A) {
    memset(A, 0, sizeof *A);
    A->nrow = A->ncol = (size_t)a->n;
    A->nzmax = (size_t)a->nnz;
    A->p = a->colptr;
    A->i = a->rowind;
    A->x = a->val;
    A->stype = 1;
    A->itype = CHOLMOD_INT;
    A->xtype = CHOLMOD_REAL;
    A->dtype = CHOLMOD_DOUBLE;
    A->sorted = 1;
    A->packed = 1;
}

static int cholmod_status_error(const cholmod_common *c, const char *what, sc_error *err) {
    switch (c->status) {
    case CHOLMOD_OUT_OF_MEMORY:
        return sc_fail(err, SC_ENOMEM, "%s: out of memory", what);
    case CHOLMOD_TOO_LARGE:
        return sc_fail(err, SC_ENOMEM, "%s: problem too large", what);
    case CHOLMOD_NOT_INSTALLED:
        return sc_fail(err, SC_EINPUT, "%s: a CHOLMOD method is not installed", what);
    case CHOLMOD_INVALID:
        return sc_fail(err, SC_EINPUT, "%s: invalid input", what);
    default:
        return sc_fail(err, SC_EINPUT, "%s failed (CHOLMOD status %d)", what, c->status);
    }
}

/* BLAS threads. The nodes keep every core busy on their own (the erase
 * kernel factors on one thread while the others assemble, or all take
 * chunks of one job), and OpenBLAS's helper threads spin in sched_yield
 * after every call they shared, taking CPU from that other work. So BLAS
 * runs on the calling thread, except in the numeric factorisation of a
 * large factor (BLAS_THREADS_FROM flops), whose big supernodes gain from its
 * threads. OpenBLAS's result does not depend on its thread count. Found
 * once; a BLAS without these entry points is left as it is. Measurements:
 * docs/notes/sparse.md. */
#define BLAS_THREADS_FROM 1e10
/* AMD ordering: where its factorisation would take more flops than this, or
 * does not fit CHOLMOD's 32-bit sizes, METIS is tried as well, and the
 * cheaper kept: on systems that seams tie together all over, METIS's factor
 * can be much smaller (docs/notes/sparse.md) */
#define METIS_FROM_FLOPS 1e12
/* The most entries a factor may hold: CHOLMOD's supernodal factorisation
 * peaks at ~17 bytes an entry, and a factor past this would not fit beside
 * the rest on a 24 GB machine; such a system fails as too large instead of
 * running out of memory (docs/notes/sparse.md) */
#define MAX_FACTOR_ENTRIES 6e8

static void (*blas_set_threads)(int);
static int blas_threads_default = 1;

static void blas_find(void) {
    int (*get_threads)(void) = NULL;
    *(void **)&blas_set_threads = dlsym(RTLD_DEFAULT, "openblas_set_num_threads");
    *(void **)&get_threads = dlsym(RTLD_DEFAULT, "openblas_get_num_threads");
    if (get_threads) blas_threads_default = get_threads();
    if (blas_set_threads) blas_set_threads(1);
}

static void blas_threads(bool many) {
    if (blas_set_threads) blas_set_threads(many ? blas_threads_default : 1);
}

static void setup_common(cholmod_common *c, const sc_sparse_options *opt) {
    static pthread_once_t blas_once = PTHREAD_ONCE_INIT;
    pthread_once(&blas_once, blas_find);
    cholmod_start(c);
    c->print = 0;
    c->error_handler = NULL;
    sc_sparse_options o = {0};
    if (opt) o = *opt;
    c->supernodal = o.kind == SC_SPARSE_SIMPLICIAL ? CHOLMOD_SIMPLICIAL
                  : o.kind == SC_SPARSE_AUTO      ? CHOLMOD_AUTO
                                                  : CHOLMOD_SUPERNODAL;
    if (o.supernodal_from > 0) c->supernodal_switch = o.supernodal_from;
    c->final_ll = o.kind == SC_SPARSE_SIMPLICIAL || o.definite;   /* a pivot <= 0 then fails it */
    switch (o.ordering) {
    case SC_SPARSE_ORDER_AMD:
        c->nmethods = 1, c->method[0].ordering = CHOLMOD_AMD, c->postorder = 1;
        break;
    case SC_SPARSE_ORDER_METIS:
        c->nmethods = 1, c->method[0].ordering = CHOLMOD_METIS, c->postorder = 1;
        break;
    case SC_SPARSE_ORDER_NATURAL:
        c->nmethods = 1, c->method[0].ordering = CHOLMOD_NATURAL, c->postorder = 0;
        break;
    default:
        break;
    }
}

int sc_sparse_chol_factor(const sc_sparse *a, const sc_sparse_options *opt, sc_sparse_chol **out,
                          sc_error *err) {
    *out = NULL;
    if (!a || a->n <= 0) return sc_fail(err, SC_EINPUT, "factorisation of an empty matrix");
    sc_sparse_chol *f = calloc(1, sizeof *f);
    if (!f) return sc_fail(err, SC_ENOMEM, "out of memory");
    setup_common(&f->common, opt);
    f->n = a->n;
    cholmod_sparse A;
    header(a, &A);
    f->L = cholmod_analyze(&A, &f->common);
    double fl = f->common.fl, lnz = f->common.lnz;
    bool amd = opt && opt->ordering == SC_SPARSE_ORDER_AMD;
    if (amd && (f->L ? fl > METIS_FROM_FLOPS : f->common.status == CHOLMOD_TOO_LARGE)) {
        /* AMD's factor is huge or past CHOLMOD's 32-bit sizes: METIS too,
         * and the cheaper of the two */
        int keep_status = f->common.status;
        f->common.method[0].ordering = CHOLMOD_METIS;
        f->common.status = CHOLMOD_OK;
        cholmod_factor *L2 = cholmod_analyze(&A, &f->common);
        if (L2 && (!f->L || f->common.fl < fl)) {
            if (f->L) cholmod_free_factor(&f->L, &f->common);
            f->L = L2, fl = f->common.fl, lnz = f->common.lnz;
        } else {
            if (L2) cholmod_free_factor(&L2, &f->common);
            if (!f->L) f->common.status = keep_status;
        }
        f->common.fl = fl, f->common.lnz = lnz;
    }
    if (!f->L) {
        int rc = cholmod_status_error(&f->common, "sparse analysis", err);
        sc_sparse_chol_free(f);
        return rc;
    }
    if (lnz > MAX_FACTOR_ENTRIES) {
        int rc = sc_fail(err, SC_ENOMEM, "sparse analysis: problem too large (a factor of %.3g entries, %.3g flops; "
                         "the limit is %.3g entries)", lnz, fl, MAX_FACTOR_ENTRIES);
        sc_sparse_chol_free(f);
        return rc;
    }
    bool large = f->common.fl >= BLAS_THREADS_FROM;
    if (large) blas_threads(true);
    int ok = cholmod_factorize(&A, f->L, &f->common);
    if (large) blas_threads(false);
    if (!ok || f->common.status < CHOLMOD_OK) {
        int rc = cholmod_status_error(&f->common, "sparse factorisation", err);
        sc_sparse_chol_free(f);
        return rc;
    }
    if (f->common.status == CHOLMOD_NOT_POSDEF || f->L->minor < f->L->n) {
        int rc = sc_fail(err, SC_EINPUT,
                         "sparse factorisation: the matrix is not positive definite "
                         "(stopped at column %zu of %d)",
                         (size_t)f->L->minor, (int)a->n);
        sc_sparse_chol_free(f);
        return rc;
    }
    f->stats.factor_nnz = f->common.lnz;
    f->stats.flops = f->common.fl;
    f->stats.ordering_used = f->L->ordering;
    f->stats.supernodal = f->L->is_super != 0;
    f->stats.peak_bytes = (double)f->common.memory_usage;
    *out = f;
    return SC_OK;
}

int sc_sparse_chol_solve(sc_sparse_chol *f, int32_t nrhs, double *b, sc_error *err) {
    if (nrhs <= 0) return SC_OK;
    cholmod_dense B;
    memset(&B, 0, sizeof B);
    B.nrow = (size_t)f->n;
    B.ncol = (size_t)nrhs;
    B.nzmax = B.nrow * B.ncol;
    B.d = B.nrow;
    B.x = b;
    B.xtype = CHOLMOD_REAL;
    B.dtype = CHOLMOD_DOUBLE;
    cholmod_dense *X = cholmod_solve(CHOLMOD_A, f->L, &B, &f->common);
    if (!X) return cholmod_status_error(&f->common, "sparse solve", err);
    memcpy(b, X->x, B.nzmax * sizeof(double));
    cholmod_free_dense(&X, &f->common);
    if ((double)f->common.memory_usage > f->stats.peak_bytes)
        f->stats.peak_bytes = (double)f->common.memory_usage;
    return SC_OK;
}

/* ---------------------------------------------------------------- solves split by the elimination tree
 *
 * A simplicial L L^T factor's elimination tree (the parent of column j is
 * the first row below the diagonal of L's column j) is cut into two halves
 * of whole subtrees and the columns above them, the top: the heaviest
 * subtree (entries of L) is replaced by its children, its root joining the
 * top, until the subtrees, taken heaviest first into the lighter half, make
 * halves within SPLIT_BALANCE of each other (no split where the top would
 * hold more than SPLIT_TOP_MAX of the entries). A half's columns
 * reach only its own rows and the top's, so the forward solve runs the halves
 * side by side (their updates to the top's rows kept apart and added after,
 * half 0's then half 1's), then the top; the backward solve runs the top,
 * then the halves. The plan depends on L alone, so the bits do not depend on
 * the thread count (they differ from cholmod_solve's, which sums in another
 * order). SPLIT_HALVES is 2: the packing into halves assumes it. */
#define SPLIT_HALVES 2
#define SPLIT_BALANCE 0.02
#define SPLIT_TOP_MAX 0.4

struct tree_split {
    int32_t n;
    int32_t *cols;                 /* half 0's columns, half 1's, then the top's, each ascending */
    int32_t start[SPLIT_HALVES + 2];
    int8_t *half;                  /* column -> its half, or -1 for the top */
    double *acc;                   /* SPLIT_HALVES x n: a half's updates to the top's rows */
    double *perm;                  /* n: the permuted right-hand side */
};

static void tree_split_free(tree_split *t) {
    if (!t) return;
    free(t->cols), free(t->half), free(t->acc), free(t->perm);
    free(t);
}

typedef struct weighed {
    double weight;
    int32_t root;
} weighed;

/* heavier first, then the lower column */
static int cmp_weighed(const void *pa, const void *pb) {
    const weighed *a = pa, *b = pb;
    if (a->weight != b->weight) return a->weight > b->weight ? -1 : 1;
    return (a->root > b->root) - (a->root < b->root);
}

static bool heavier(const double *weight, int32_t a, int32_t b) {
    weighed wa = {weight[a], a}, wb = {weight[b], b};
    return cmp_weighed(&wa, &wb) < 0;
}

/* The plan, or NULL where there is none to make (not simplicial L L^T, no
 * good split, out of memory): the caller then uses cholmod_solve. */
static tree_split *tree_split_make(const cholmod_factor *L, double *share) {
    if (L->is_super || !L->is_ll || L->xtype != CHOLMOD_REAL || L->itype != CHOLMOD_INT || L->n < 2) return NULL;
    const int32_t n = (int32_t)L->n, *lp = L->p, *li = L->i, *lnz = L->nz;
    int32_t *parent = sc_alloc_array((size_t)n, sizeof *parent), *child = sc_alloc_array((size_t)n, sizeof *child);
    int32_t *next = sc_alloc_array((size_t)n, sizeof *next), *cand = sc_alloc_array((size_t)n, sizeof *cand);
    double *weight = sc_alloc_array((size_t)n, sizeof *weight);
    int8_t *half = sc_alloc_array((size_t)n, sizeof *half);
    tree_split *t = calloc(1, sizeof *t);
    bool ok = parent && child && next && cand && weight && half && t;
    double total = 0;
    for (int32_t j = 0; ok && j < n; j++) {
        ok = lnz[j] >= 1 && li[lp[j]] == j;   /* the diagonal first */
        parent[j] = -1;
        for (int32_t p = lp[j] + 1; ok && p < lp[j] + lnz[j]; p++) {
            ok = li[p] > j && li[p] < n;
            if (ok && (parent[j] < 0 || li[p] < parent[j])) parent[j] = li[p];
        }
        weight[j] = lnz[j], total += lnz[j];
        child[j] = -1, half[j] = -1;
    }
    /* subtree weights, and children lists in increasing order */
    int32_t ncand = 0;
    for (int32_t j = n - 1; ok && j >= 0; j--) {
        if (parent[j] < 0) {
            cand[ncand++] = j;
        } else {
            next[j] = child[parent[j]];
            child[parent[j]] = j;
        }
    }
    for (int32_t j = 0; ok && j < n; j++)
        if (parent[j] >= 0) weight[parent[j]] += weight[j];
    /* split the heaviest subtree until the subtrees pack into two halves
     * within SPLIT_BALANCE of each other */
    double top = 0;
    weighed *order = ok ? sc_alloc_array((size_t)n, sizeof *order) : NULL;
    ok = ok && order;
    while (ok) {
        int32_t heaviest = 0;
        for (int32_t k = 1; k < ncand; k++)
            if (heavier(weight, cand[k], cand[heaviest])) heaviest = k;
        if (ncand > 1 && weight[cand[heaviest]] <= (total - top) / 2) {
            for (int32_t k = 0; k < ncand; k++) order[k] = (weighed){weight[cand[k]], cand[k]};
            qsort(order, (size_t)ncand, sizeof *order, cmp_weighed);
            double load[SPLIT_HALVES] = {0};
            for (int32_t k = 0; k < ncand; k++) {
                int h = load[1] < load[0] ? 1 : 0;
                load[h] += order[k].weight;
                half[order[k].root] = (int8_t)h;
            }
            if (fabs(load[0] - load[1]) <= SPLIT_BALANCE * (load[0] + load[1])) break;
            for (int32_t k = 0; k < ncand; k++) half[cand[k]] = -1;
        }
        int32_t r = cand[heaviest];
        top += lnz[r];
        cand[heaviest] = cand[--ncand];
        for (int32_t c = child[r]; c >= 0; c = next[c]) cand[ncand++] = c;
        ok = ncand > 0 && top <= SPLIT_TOP_MAX * total;
    }
    free(order);
    if (ok) {
        /* a column belongs to the half of its subtree's root; the rest is the top */
        for (int32_t j = n - 1; j >= 0; j--)
            if (half[j] < 0 && parent[j] >= 0) half[j] = half[parent[j]];
        t->n = n;
        t->half = half, half = NULL;
        t->cols = sc_alloc_array((size_t)n, sizeof *t->cols);
        t->acc = sc_alloc_array((size_t)SPLIT_HALVES * (size_t)n, sizeof *t->acc);
        t->perm = sc_alloc_array((size_t)n, sizeof *t->perm);
        ok = t->cols && t->acc && t->perm;
    }
    if (ok) {
        int32_t at = 0;
        for (int h = 0; h <= SPLIT_HALVES; h++) {
            t->start[h] = at;
            int8_t want = h < SPLIT_HALVES ? (int8_t)h : -1;
            for (int32_t j = 0; j < n; j++)
                if (t->half[j] == want) t->cols[at++] = j;
        }
        t->start[SPLIT_HALVES + 1] = at;
        *share = total > 0 ? (total - top) / total : 0;
    }
    free(parent), free(child), free(next), free(cand), free(weight), free(half);
    if (!ok) {
        tree_split_free(t);
        return NULL;
    }
    return t;
}

typedef struct split_job {
    const cholmod_factor *L;
    const tree_split *t;
    double *x;
    bool forward;
} split_job;

/* L^T y = x over the columns [c0, c1) (ascending), last first: the values
 * of the rows below them are known. */
static void backward_columns(const cholmod_factor *L, const int32_t *c0, const int32_t *c1, double *x) {
    const int32_t *lp = L->p, *li = L->i, *lnz = L->nz;
    const double *lx = L->x;
    for (const int32_t *c = c1; c-- > c0;) {
        int32_t col = *c, p0 = lp[col], p1 = p0 + lnz[col];
        double s = x[col];
        for (int32_t p = p0 + 1; p < p1; p++) s -= lx[p] * x[li[p]];
        x[col] = s / lx[p0];
    }
}

/* L y = x over the columns [c0, c1) of part h (a half, or -1: the top),
 * in order: updates to rows of part h go to x, the others (the top's,
 * from a half) to acc. */
static void forward_columns(const cholmod_factor *L, const tree_split *t, const int32_t *c0, const int32_t *c1,
                            int h, double *x, double *acc) {
    const int32_t *lp = L->p, *li = L->i, *lnz = L->nz;
    const double *lx = L->x;
    for (const int32_t *c = c0; c < c1; c++) {
        int32_t col = *c, p0 = lp[col], p1 = p0 + lnz[col];
        double v = x[col] / lx[p0];
        x[col] = v;
        for (int32_t p = p0 + 1; p < p1; p++) {
            int32_t i = li[p];
            if (t->half[i] == h) x[i] -= lx[p] * v;
            else acc[i] -= lx[p] * v;
        }
    }
}

/* L y = x over half h's columns (updates to the top's rows into its acc), or
 * L^T y = x over them, the top's values known. */
static int split_half(void *ud, int32_t h) {
    const split_job *j = ud;
    const tree_split *t = j->t;
    const int32_t *c0 = t->cols + t->start[h], *c1 = t->cols + t->start[h + 1];
    if (j->forward) forward_columns(j->L, t, c0, c1, h, j->x, t->acc + (size_t)h * (size_t)t->n);
    else backward_columns(j->L, c0, c1, j->x);
    return SC_OK;
}

/* x <- L^-T L^-1 x (permuted order) for one column. */
static int split_solve(const cholmod_factor *L, tree_split *t, double *x, int threads) {
    const int32_t n = t->n;
    const int32_t *top0 = t->cols + t->start[SPLIT_HALVES], *top1 = t->cols + t->start[SPLIT_HALVES + 1];
    memset(t->acc, 0, (size_t)SPLIT_HALVES * (size_t)n * sizeof *t->acc);
    split_job job = {L, t, x, true};
    if (sc_parallel(threads, SPLIT_HALVES, split_half, &job) != SC_OK) return SC_ENOMEM;
    for (const int32_t *c = top0; c < top1; c++)
        for (int h = 0; h < SPLIT_HALVES; h++) x[*c] += t->acc[(size_t)h * (size_t)n + *c];
    forward_columns(L, t, top0, top1, -1, x, NULL);   /* the top's rows are all the top's */
    backward_columns(L, top0, top1, x);
    job.forward = false;
    return sc_parallel(threads, SPLIT_HALVES, split_half, &job) == SC_OK ? SC_OK : SC_ENOMEM;
}

int sc_sparse_chol_solve_threads(sc_sparse_chol *f, int32_t nrhs, double *b, int threads, sc_error *err) {
    if (!f->split_tried) {
        f->split = tree_split_make(f->L, &f->stats.split_share);
        f->split_tried = true;
    }
    if (!f->split) return sc_sparse_chol_solve(f, nrhs, b, err);
    tree_split *t = f->split;
    const int32_t *perm = f->L->Perm;
    for (int32_t c = 0; c < nrhs; c++) {
        double *bc = b + (size_t)c * (size_t)t->n;
        for (int32_t k = 0; k < t->n; k++) t->perm[k] = bc[perm ? perm[k] : k];
        if (split_solve(f->L, t, t->perm, threads) != SC_OK)
            return sc_fail(err, SC_ENOMEM, "out of memory in a sparse solve");
        for (int32_t k = 0; k < t->n; k++) bc[perm ? perm[k] : k] = t->perm[k];
    }
    return SC_OK;
}

void sc_sparse_chol_stats(const sc_sparse_chol *f, sc_sparse_stats *out) { *out = f->stats; }

void sc_sparse_chol_free(sc_sparse_chol *f) {
    if (!f) return;
    tree_split_free(f->split);
    if (f->L) cholmod_free_factor(&f->L, &f->common);
    cholmod_finish(&f->common);
    free(f);
}

/* The inertia count's L D L^T is simplicial (one thread): past this it
 * declines rather than run for many minutes (docs/notes/sparse.md) */
#define INERTIA_MAX_FLOPS 2e10

int sc_sparse_count_eigs_below(const sc_sparse *a, double shift, int64_t *count, sc_error *err) {
    *count = 0;
    if (!a || a->n <= 0) return SC_OK;
    cholmod_common c;
    sc_sparse_options opt = {.ordering = SC_SPARSE_ORDER_AMD, .kind = SC_SPARSE_SIMPLICIAL};
    setup_common(&c, &opt);
    c.final_ll = 0;           /* keep L D L^T: D carries the inertia */
    c.final_super = 0;
    cholmod_sparse A;
    header(a, &A);
    cholmod_factor *L = cholmod_analyze(&A, &c);
    if (!L) {
        int rc = cholmod_status_error(&c, "inertia analysis", err);
        cholmod_finish(&c);
        return rc;
    }
    if (c.fl > INERTIA_MAX_FLOPS) {
        int rc = sc_fail(err, SC_ENOMEM, "inertia: the factorisation would take %.3g flops (limit %.3g)", c.fl,
                         INERTIA_MAX_FLOPS);
        cholmod_free_factor(&L, &c);
        cholmod_finish(&c);
        return rc;
    }
    double beta[2] = {-shift, 0};
    int ok = cholmod_factorize_p(&A, beta, NULL, 0, L, &c);
    int rc = SC_OK;
    if (!ok || c.status < CHOLMOD_OK) {
        rc = cholmod_status_error(&c, "inertia factorisation", err);
    } else if (L->minor < L->n || L->is_ll || L->is_super) {
        rc = sc_fail(err, SC_EINPUT, "inertia factorisation broke down at column %zu",
                     (size_t)L->minor);
    } else {
        const int *Lp = L->p;
        const double *Lx = L->x;
        int64_t neg = 0;
        for (size_t j = 0; j < L->n; j++)
            if (Lx[Lp[j]] < 0) neg++;
        *count = neg;
    }
    cholmod_free_factor(&L, &c);
    cholmod_finish(&c);
    return rc;
}
