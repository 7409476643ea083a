/* sc_sparse.h - symmetric sparse matrices and their Cholesky solves (CHOLMOD).
 *
 *   sc_triplets   (row, col, value) entries of a symmetric matrix, any order,
 *                 duplicates allowed (they are summed); only the upper
 *                 triangle is kept (an entry below the diagonal is mirrored).
 *   sc_sparse     the assembled matrix: upper triangle in compressed sparse
 *                 columns (CSC), rows sorted within each column, duplicates
 *                 summed in the order they were added (so the same triplets
 *                 always give the same bits).
 *   sc_sparse_chol  a Cholesky factorisation A = L L^T (CHOLMOD, supernodal by
 *                 default): analyse once, factor, then solve any number of
 *                 right-hand sides at once.
 *
 * Errors are sc_error values; "not positive definite" names the column where
 * the factorisation stopped. Nothing here prints.
 */
#ifndef SC_SPARSE_H
#define SC_SPARSE_H

#include "sc_base.h"

/* Bump whenever results of this library can change for the same inputs:
 * every node listing sc_kernel_sparse (or a kernel built on it) is re-keyed. */
#define SC_SPARSE_VERSION 1
extern const sc_kernel sc_kernel_sparse;

/* ---------------------------------------------------------------- triplets */

typedef struct sc_triplets {
    int32_t n;              /* matrix size (n x n) */
    size_t count, cap;
    int32_t *row, *col;
    double *val;
    bool failed;            /* an allocation failed; adds are then ignored */
} sc_triplets;

void sc_triplets_init(sc_triplets *t, int32_t n);
void sc_triplets_free(sc_triplets *t);
/* Make room for `extra` more entries (returns false when out of memory). */
bool sc_triplets_reserve(sc_triplets *t, size_t extra);
/* Add value at (i, j); (j, i) is the same entry of the symmetric matrix. */
void sc_triplets_add(sc_triplets *t, int32_t i, int32_t j, double v);
/* Append all entries of src (in order). */
void sc_triplets_append(sc_triplets *t, const sc_triplets *src);

/* Triplet lists made apart (chunks of work, on several threads), kept in
 * order: they read as one list, each list's entries after the previous
 * one's, and joining a list moves it in without copying its entries. */
typedef struct sc_triplet_parts {
    int32_t n;              /* matrix size (n x n) */
    int32_t count, cap;
    sc_triplets *list;
    bool failed;            /* an allocation failed, here or in a list */
} sc_triplet_parts;

void sc_triplet_parts_init(sc_triplet_parts *p, int32_t n);
void sc_triplet_parts_free(sc_triplet_parts *p);
/* Move t in as the last list; t is left empty (initialised for its size). */
void sc_triplet_parts_take(sc_triplet_parts *p, sc_triplets *t);

/* ---------------------------------------------------------------- matrices */

typedef struct sc_sparse {
    int32_t n;
    int64_t nnz;
    int32_t *colptr;        /* n + 1 */
    int32_t *rowind;        /* nnz, rows <= column, increasing within a column */
    double *val;            /* nnz */
} sc_sparse;

/* Assemble triplets into an upper-triangular CSC matrix. Entries with equal
 * (row, col) are summed in the order they were added. Fails with SC_EINPUT on
 * an index out of range and SC_ENOMEM when out of memory. */
int sc_sparse_from_triplets(const sc_triplets *t, sc_sparse *out, sc_error *err);
/* The same on up to `threads` threads: the same bits for any thread count. */
int sc_sparse_from_triplets_threads(const sc_triplets *t, int threads, sc_sparse *out, sc_error *err);
/* The same for the lists of p, in order, without copying them into one
 * list first. */
int sc_sparse_from_triplet_parts(const sc_triplet_parts *p, int threads, sc_sparse *out, sc_error *err);
/* The same, straight into the full pattern (both triangles, as
 * sc_sparse_full makes from the upper one, to the same bits). With
 * extra_start (n + 1) and extra_rows, column j also holds the rows
 * extra_rows[extra_start[j] .. extra_start[j + 1]) (any order, repeats and
 * rows the triplets give allowed), as zeros where no triplet adds to them:
 * the pattern of terms added to the matrix later. */
int sc_sparse_full_from_triplet_parts(const sc_triplet_parts *p, const int32_t *extra_start,
                                      const int32_t *extra_rows, int threads, sc_sparse *full, sc_error *err);
void sc_sparse_free(sc_sparse *a);

/* Where row i of column j is stored in rowind/val, -1 when it is not (rows
 * sorted within columns: an upper-triangular or a full-pattern matrix). */
int64_t sc_sparse_find(const sc_sparse *a, int32_t i, int32_t j);

/* C = alpha A + beta B (same size; the union of both patterns). */
int sc_sparse_add(const sc_sparse *a, double alpha, const sc_sparse *b, double beta, sc_sparse *c,
                  sc_error *err);

/* The principal submatrix on rows/columns with keep[i] >= 0, renumbered
 * keep[i] (keep maps old index -> new index in [0, count), increasing). */
int sc_sparse_submatrix(const sc_sparse *a, const int32_t *keep, int32_t count, sc_sparse *out,
                        sc_error *err);

/* y = A x for the symmetric A (x, y of length n; y is overwritten). */
void sc_sparse_symv(const sc_sparse *a, const double *x, double *y);
/* y += the part of A x that the upper columns [c0, c1) hold (both of their
 * triangles): sums over column ranges that cover 0..n make A x. */
void sc_sparse_symv_columns(const sc_sparse *a, int32_t c0, int32_t c1, const double *x, double *y);
/* x^T A x. */
double sc_sparse_quadform(const sc_sparse *a, const double *x);
/* Diagonal entry A(i, i) (0 when not stored). */
double sc_sparse_diag(const sc_sparse *a, int32_t i);

/* ---------------------------------------------------------------- Cholesky */

typedef enum sc_sparse_ordering {
    SC_SPARSE_ORDER_DEFAULT = 0,   /* CHOLMOD's choice (AMD, METIS when AMD fills badly) */
    SC_SPARSE_ORDER_AMD = 1,
    SC_SPARSE_ORDER_METIS = 2,
    SC_SPARSE_ORDER_NATURAL = 3,
} sc_sparse_ordering;

typedef enum sc_sparse_kind {
    SC_SPARSE_SUPERNODAL = 0,      /* supernodal L L^T (BLAS level 3) */
    SC_SPARSE_SIMPLICIAL = 1,      /* simplicial L L^T */
    SC_SPARSE_AUTO = 2,            /* CHOLMOD picks from the flop count (simplicial: L D L^T) */
} sc_sparse_kind;

typedef struct sc_sparse_options {
    sc_sparse_ordering ordering;
    sc_sparse_kind kind;
    /* auto: supernodal where the factorisation takes this many flops per
     * entry of L or more (0: CHOLMOD's 40) */
    double supernodal_from;
    /* L L^T whatever the kind, which fails on a matrix that is not positive
     * definite (auto's simplicial L D L^T takes any pivot but zero) */
    bool definite;
} sc_sparse_options;

typedef struct sc_sparse_stats {
    double factor_nnz;             /* entries of L */
    double flops;                  /* floating point operations of the factorisation */
    double peak_bytes;             /* CHOLMOD's peak memory */
    int ordering_used;             /* CHOLMOD ordering code */
    bool supernodal;
    double split_share;            /* entries of L in the halves sc_sparse_chol_solve_threads
                                      runs side by side (0: not split, or not yet solved with) */
} sc_sparse_stats;

typedef struct sc_sparse_chol sc_sparse_chol;

/* Analyse and factor A (n x n, symmetric positive definite; its upper
 * triangle, or a full pattern, whose lower entries are not read). opt may be
 * NULL for the defaults. With the AMD ordering, METIS is tried too where
 * AMD's factorisation would take over 1e12 flops or not fit CHOLMOD's
 * 32-bit sizes, and the cheaper one is kept. A factor of more than 6e8
 * entries is refused (SC_ENOMEM, "problem too large") before it is made.
 * On failure *out is NULL and err says why. */
int sc_sparse_chol_factor(const sc_sparse *a, const sc_sparse_options *opt,
                          sc_sparse_chol **out, sc_error *err);
/* Solve A X = B for nrhs right-hand sides at once: b holds n x nrhs values,
 * column-major (one column per right-hand side), and is overwritten by X. */
int sc_sparse_chol_solve(sc_sparse_chol *f, int32_t nrhs, double *b, sc_error *err);
/* The same on up to `threads` threads for a simplicial L L^T factor (its
 * elimination tree split in two fixed halves: the bits do not depend on the
 * thread count, but differ from sc_sparse_chol_solve's); other factors go
 * to sc_sparse_chol_solve. Like it, one call at a time per factor (the
 * plan and its scratch are kept in f). */
int sc_sparse_chol_solve_threads(sc_sparse_chol *f, int32_t nrhs, double *b, int threads, sc_error *err);
void sc_sparse_chol_stats(const sc_sparse_chol *f, sc_sparse_stats *out);
void sc_sparse_chol_free(sc_sparse_chol *f);

/* Inertia count: the number of eigenvalues of the symmetric A that are below
 * `shift` (Sylvester's law on an LDL^T factorisation of A - shift I). Used to
 * measure numerical null spaces (nullity = eigenvalues below a tolerance).
 * Declines (SC_ENOMEM) where the factorisation would take more than 2e10
 * flops. */
int sc_sparse_count_eigs_below(const sc_sparse *a, double shift, int64_t *count, sc_error *err);

/* An upper bound of the largest |eigenvalue| (largest absolute row sum). */
double sc_sparse_norm_bound(const sc_sparse *a);

/* The full pattern of a symmetric matrix stored as its upper triangle: both
 * triangles, rows sorted within each column. Being symmetric, it reads the
 * same as compressed sparse rows; only the sc_sparse_full_* functions (and
 * sc_schur) take it. */
int sc_sparse_full(const sc_sparse *upper, sc_sparse *full, sc_error *err);
/* The same on up to `threads` threads: the same bits for any thread count. */
int sc_sparse_full_threads(const sc_sparse *upper, int threads, sc_sparse *full, sc_error *err);

#endif
