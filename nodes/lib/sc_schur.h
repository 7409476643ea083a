/* sc_schur.h - symmetric positive definite systems whose unknowns fall mostly
 * into short chains ("clusters") that meet only through a few shared
 * "interface" unknowns, and conjugate gradients preconditioned by them.
 *
 * erase_seams is the user: the texels of the cells along one seam edge (both
 * sides) form a cluster, ordered by the edge parameter; texels that the cells
 * of two edges share, or that couple to another edge's texels, form the
 * interface. Each cluster is factored on its own (a banded, "envelope"
 * Cholesky factor in key order), its private unknowns are eliminated exactly
 * (a Schur complement onto the interface unknowns it touches), and the much
 * smaller interface system is factored by CHOLMOD. Nothing is approximated:
 * solving with the factorisation is a direct solve of A; the order only
 * decides how cheap it is.
 *
 * Input matrices here are full-pattern symmetric matrices (sc_sparse_full:
 * both triangles, so a column is also a row); an entry stored as an exact
 * zero off the diagonal is no coupling. Results are the same bits for
 * any thread count.
 */
#ifndef SC_SCHUR_H
#define SC_SCHUR_H

#include "sc_sparse.h"

typedef struct sc_schur sc_schur;

typedef struct sc_schur_stats {
    int32_t clusters;          /* clusters with at least one private unknown */
    int32_t private_unknowns;  /* eliminated inside their cluster */
    int32_t interface_unknowns;
    double envelope;           /* entries of the clusters' envelope factors */
    double cluster_flops;      /* their factorisation and Schur products */
    double interface_nnz;      /* entries (upper triangle) of the interface matrix */
    double interface_factor_nnz, interface_flops;
    double peak_bytes;         /* CHOLMOD's peak for the interface */
    double seconds_clusters, seconds_interface;
} sc_schur_stats;

/* Factor the full-pattern SPD matrix a. group[i] >= 0 names unknown i's
 * cluster (-1: none, i.e. interface), key[i] orders it within the cluster
 * (ties by index). An unknown is private to its cluster when every unknown it
 * couples to is in the same cluster or in none; the others form the
 * interface. Fails with SC_EINPUT when a is not positive definite. */
int sc_schur_factor(const sc_sparse *a, const int32_t *group, const double *key, int threads,
                    sc_schur **out, sc_error *err);

/* Solve A X = B for nrhs columns (b: n x nrhs, column-major, overwritten). */
int sc_schur_solve(sc_schur *f, int32_t nrhs, double *b, sc_error *err);

void sc_schur_get_stats(const sc_schur *f, sc_schur_stats *out);
void sc_schur_free(sc_schur *f);

/* Conjugate gradients on Q X = B, preconditioned by f, the factorisation of
 * an A close to Q (Q = A gives the answer in one iteration). q is the
 * symmetric positive definite Q in its full pattern (sc_sparse_full). Each column stops when its
 * preconditioned residual sqrt(r^T A^-1 r) has fallen to tol times its
 * starting value (a zero right-hand side gives exactly zero); more than
 * max_iter iterations is an error (SC_EINPUT, "did not converge"). b
 * (n x nrhs, column-major) is overwritten by X. */
typedef struct sc_schur_pcg_result {
    int32_t iterations;        /* the most any column took */
    double relative_residual;  /* the largest final preconditioned residual ratio */
} sc_schur_pcg_result;

int sc_schur_pcg(sc_schur *f, const sc_sparse *q, int32_t nrhs, double *b, double tol,
                 int32_t max_iter, int threads, sc_schur_pcg_result *res, sc_error *err);

#endif
