/* sc_quadric.h - n-dimensional quadric error metrics and an exact small dense
 * quadratic-programming solver, for edge-collapse decimation.
 *
 * Quadrics (Garland & Heckbert 1997, 1998). A quadric in n dimensions is
 *     Q(x) = x^T A x + 2 b^T x + c,   A symmetric n x n,
 * stored packed in one array of sc_quadric_size(n) doubles:
 *     [ A's upper triangle, row by row (n(n+1)/2) | b (n) | c (1) ].
 * n <= SC_QUADRIC_MAX_DIM (10): five dimensions (x, y, z, u, v) for a vertex,
 * ten for the block metric of a seam edge (two copies of every dimension, one
 * per half-vertex, Liu et al. 2017 §5.2).
 *
 * QP. sc_qp_solve minimises 1/2 x^T H x + g^T x subject to equality
 * constraints Aeq x = beq and inequality constraints Ain x >= bin, with H
 * symmetric positive definite, by the dual active-set method of Goldfarb &
 * Idnani (1983), in the numerically stable form of Powell's and Di Gaspero's
 * implementations (Cholesky factor, orthogonal J = L^-T updated by Givens
 * rotations). It returns the exact minimiser (up to rounding), its Lagrange
 * multipliers and the active set. A bound l <= x_i <= h is two inequality rows.
 * sc_qp_minimize_quadric wraps it for a (possibly only semidefinite) quadric:
 * it adds rho |x - x_ref|^2, which makes the problem strictly convex and,
 * for a small rho, picks among the minimisers of a singular quadric the one
 * nearest x_ref.
 */
#ifndef SC_QUADRIC_H
#define SC_QUADRIC_H

#include <stdbool.h>

#include "sc_base.h"

/* Bump whenever results of this library can change for the same inputs:
 * every node listing sc_kernel_quadric (or a kernel built on it) is re-keyed. */
#define SC_QUADRIC_VERSION 1
extern const sc_kernel sc_kernel_quadric;

#define SC_QUADRIC_MAX_DIM 10
/* Doubles a packed quadric of dimension n takes. */
#define SC_QUADRIC_SIZE(n) ((n) * ((n) + 1) / 2 + (n) + 1)
#define SC_QUADRIC_MAX_SIZE SC_QUADRIC_SIZE(SC_QUADRIC_MAX_DIM)

static inline int sc_quadric_size(int n) { return SC_QUADRIC_SIZE(n); }

/* Index of A(i, j) in the packed upper triangle, any order of i, j. */
static inline int sc_quadric_index(int n, int i, int j) {
    if (i > j) {
        int t = i;
        i = j;
        j = t;
    }
    return i * n - i * (i - 1) / 2 + (j - i);
}

void sc_quadric_zero(double *q, int n);
/* dst += scale * src */
void sc_quadric_add(double *dst, const double *src, int n, double scale);
void sc_quadric_scale(double *q, int n, double s);
/* Q(x) */
double sc_quadric_eval(const double *q, int n, const double *x);
/* Unpack A into a dense row-major n x n matrix, b into b_out (either may be NULL). */
void sc_quadric_unpack(const double *q, int n, double *A, double *b_out);

/* Add weight * (squared distance to the affine plane through the triangle
 * p, q, r in R^n) (Garland & Heckbert 1998). Returns false (adding nothing)
 * when the triangle is degenerate in R^n. */
bool sc_quadric_add_triangle(double *quad, int n, const double *p, const double *q, const double *r,
                             double weight);
/* Add weight * (normal . x[0..2] + d)^2: a plane in the first three
 * dimensions (a 3D plane quadric extended by zeros). `normal` need not be unit. */
void sc_quadric_add_plane3(double *quad, int n, const double normal[3], double d, double weight);

/* The 2n-dimensional block-diagonal quadric Q1(x1) + Q2(x2) of two
 * n-dimensional quadrics, x = (x1, x2). */
void sc_quadric_block(double *out, const double *q1, const double *q2, int n);

/* The quadric restricted to its first k dimensions, the others fixed at
 * tail[0 .. n-k-1]: out(y) = Q(y, tail), a k-dimensional quadric. */
void sc_quadric_restrict(const double *q, int n, int k, const double *tail, double *out);

/* Unconstrained minimiser of Q(x) + rho |x - x_ref|^2 (rho <= 0: the default
 * of sc_qp_minimize_quadric) by Cholesky. False when not positive definite. */
bool sc_quadric_minimize(const double *q, int n, const double *x_ref, double rho, double *x);

/* Minimiser over y in R^m of Q(B y + c) + rho |B y + c - x_ref|^2, B an n x m
 * matrix (row-major, m <= n), by Cholesky of the m x m system: the exact
 * solution of the equality-constrained problem whose feasible set is the
 * affine subspace {B y + c}. False when that system is not positive definite
 * (rho > 0 and B of full column rank make it so). */
bool sc_quadric_minimize_affine(const double *q, int n, const double *B, int m, const double *c,
                                const double *x_ref, double rho, double *y);

/* The default regularisation weight: 1e-9 * (trace(A)/n + 1e-300). */
double sc_quadric_default_rho(const double *q, int n);

/* Eigen-decomposition of a symmetric 3x3 matrix given packed (a00 a01 a02 a11
 * a12 a22) by cyclic Jacobi rotations: values[k] with unit vectors[k][0..2]. */
void sc_sym3_eigen(const double a[6], double values[3], double vectors[3][3]);

/* Coll & Paradinas 2010 §4.1: the local area distortion weight of a vertex,
 *     w = (trace(A) - lambda) / (trace(A) + lambda),
 * where A is the 3x3 part of its geometric (plane) quadric, given packed
 * (a00 a01 a02 a11 a12 a22), and lambda the eigenvalue of A whose eigenvector
 * is closest to the surface normal n. 0 when A is zero. */
double sc_quadric_area_distortion(const double a3[6], const double normal[3]);

/* ---------------------------------------------------------------- QP */

#define SC_QP_MAX_N SC_QUADRIC_MAX_DIM
#define SC_QP_MAX_EQ 12
#define SC_QP_MAX_IN 12

typedef struct sc_qp {
    int n, neq, nin;
    double H[SC_QP_MAX_N * SC_QP_MAX_N];   /* row-major, symmetric positive definite */
    double g[SC_QP_MAX_N];
    double Aeq[SC_QP_MAX_EQ][SC_QP_MAX_N], beq[SC_QP_MAX_EQ];   /* Aeq x = beq */
    double Ain[SC_QP_MAX_IN][SC_QP_MAX_N], bin[SC_QP_MAX_IN];   /* Ain x >= bin */
} sc_qp;

typedef enum sc_qp_status {
    SC_QP_OK = 0,
    SC_QP_INFEASIBLE = 1,    /* the constraints admit no point */
    SC_QP_NOT_CONVEX = 2,    /* H is not positive definite */
    SC_QP_DEPENDENT = 3,     /* equality constraints linearly dependent */
    SC_QP_BAD_SIZE = 4,      /* n, neq or nin out of range */
    SC_QP_NO_PROGRESS = 5,   /* iteration limit (rounding trouble); never seen in practice */
} sc_qp_status;

typedef struct sc_qp_result {
    double x[SC_QP_MAX_N];
    double objective;                 /* 1/2 x^T H x + g^T x */
    double lambda_eq[SC_QP_MAX_EQ];   /* multipliers: H x + g = Aeq^T l_eq + Ain^T l_in */
    double lambda_in[SC_QP_MAX_IN];   /* >= 0, zero for inactive rows */
    bool active_in[SC_QP_MAX_IN];
    int iterations;
} sc_qp_result;

void sc_qp_init(sc_qp *p, int n);
/* Append a row; return its index or -1 when full. */
int sc_qp_add_eq(sc_qp *p, const double *row, double rhs);
int sc_qp_add_ge(sc_qp *p, const double *row, double rhs);

sc_qp_status sc_qp_solve(const sc_qp *p, sc_qp_result *out);
const char *sc_qp_status_name(sc_qp_status s);

/* Minimise Q(x) + rho |x - x_ref|^2 under the constraints already in p (its
 * H and g are overwritten from the quadric). rho <= 0 picks
 * 1e-9 * (trace(A)/n + 1e-300). *value receives Q(x) itself (not the
 * regularised value), clamped at 0 from below. */
sc_qp_status sc_qp_minimize_quadric(sc_qp *p, const double *quad, const double *x_ref, double rho,
                                    sc_qp_result *out, double *value);

#endif
