/* sc_schur.h - symmetric positive definite systems whose unknowns fall mostly
 * into short chains ("clusters") that meet only through a few shared
 * "interface" unknowns, and conjugate gradients preconditioned by them.
 *
 * The erase kernel (sc_erase) is the user: the texels of the cells along one seam chain (seam
 * edges joined end to end; both sides) form a cluster, ordered along it;
 * texels that the cells of two chains share, or that couple to another
 * chain's texels, form the interface. Each cluster is factored on its own (a
 * banded, "envelope" Cholesky factor in key order), its private unknowns are
 * eliminated exactly (a Schur complement onto the interface unknowns it
 * touches), and the much smaller interface system is factored by CHOLMOD.
 * Nothing is approximated: solving with the factorisation is a direct solve
 * of A; the order only decides how cheap it is.
 *
 * Input matrices here are full-pattern symmetric matrices (sc_sparse_full:
 * both triangles, so a column is also a row); an entry stored as an exact
 * zero off the diagonal is no coupling. Results are the same bits for
 * any thread count.
 */
#ifndef SC_SCHUR_H
#define SC_SCHUR_H

#include "sc_sparse.h"

#include "sc_base.h"

/* Bump whenever results of this library can change for the same inputs:
 * every node listing sc_kernel_schur (or a kernel built on it) is re-keyed. */
#define SC_SCHUR_VERSION 1
extern const sc_kernel sc_kernel_schur;

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
 * couples to is in the same cluster, with a key at most key_span from its
 * own, or in none; the others form the interface. key_span keeps each
 * cluster's factor banded where a long cluster comes back near itself
 * (INFINITY: no limit). Fails with SC_EINPUT when a is not positive
 * definite. */
int sc_schur_factor(const sc_sparse *a, const int32_t *group, const double *key, double key_span, int threads,
                    sc_schur **out, sc_error *err);
/* The same in two steps, so that a caller can run other work beside the
 * second: the clusters and S (on `threads` threads; they read a), then S's
 * factorisation (CHOLMOD, mostly on the calling thread; a is not read).
 * After a failed second step the caller frees f. */
int sc_schur_factor_clusters(const sc_sparse *a, const int32_t *group, const double *key, double key_span,
                             int threads, sc_schur **out, sc_error *err);
int sc_schur_factor_interface(sc_schur *f, sc_error *err);

/* Solve A X = B for nrhs columns (b: n x nrhs, column-major, overwritten). */
int sc_schur_solve(sc_schur *f, int32_t nrhs, double *b, sc_error *err);

void sc_schur_get_stats(const sc_schur *f, sc_schur_stats *out);
void sc_schur_free(sc_schur *f);

/* Solve (A + E) X = B, f the factorisation of A and E the sum of the
 * rank-one couplings w (x_r - x_s)^2 listed in terms (row r < column s,
 * weight w > 0) between interface unknowns (group -1 in sc_schur_factor):
 * couplings that would spoil the cluster structure (sc_erase: grid
 * couplings between texels of charts side by side in the atlas). The
 * private unknowns are eliminated exactly, and conjugate gradients run on
 * the interface alone, on S + E with S's factor as the preconditioner
 * (iterative substructuring: the iterates of conjugate gradients on A + E
 * preconditioned by A, for a fraction of the work). Each column stops when
 * its residual's A^-1 norm, sqrt(r^T A^-1 r), has fallen to tol times
 * b's (a zero right-hand side gives exactly zero); more than max_iter
 * iterations is an error (SC_EINPUT, "did not converge"). With q, A + E
 * itself in its full pattern, the answer is refined once on q's residual:
 * the factorisation holds A only to rounding, which an ill-conditioned A
 * turns into a residual far above tol; one refinement brings it down to
 * what conjugate gradients on q preconditioned by A reach. b (n x nrhs, column-major) is overwritten by X. */
typedef struct sc_schur_pcg_result {
    int32_t iterations;        /* the most any column took (both rounds) */
    double relative_residual;  /* the largest final residual ratio */
} sc_schur_pcg_result;

int sc_schur_solve_terms(sc_schur *f, const sc_sparse *q, const sc_triplets *terms, int32_t nrhs, double *b,
                         double tol, int32_t max_iter, sc_schur_pcg_result *res, sc_error *err);

#endif
