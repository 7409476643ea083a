/* sc_quadric.c - n-D quadric error metrics and the Goldfarb-Idnani QP solver.
 *
 * Design note. Everything here is small and dense (n <= 10), so it is plain
 * fixed-size arrays on the stack: no allocation, no failure paths beyond the
 * status codes. The QP solver is the dual method of Goldfarb & Idnani (1983):
 * start from the unconstrained minimum of the strictly convex objective, add
 * the equality constraints one by one, then repeatedly pick the most violated
 * inequality and move along the primal-dual step direction, dropping active
 * inequalities whose multipliers would turn negative, until no constraint is
 * violated. The active-set factorisation is kept as J = L^-T Q (L the
 * Cholesky factor of H) and the upper-triangular R, both updated by Givens
 * rotations when a constraint enters or leaves; this is the formulation of
 * Powell's ZQPCVX and of QuadProg++ (Di Gaspero), written afresh for C11 with
 * the same numerical safeguards (a relative tolerance for dependent
 * constraints, a psi test for termination). The iteration count is bounded,
 * so rounding trouble surfaces as a status, never as a loop.
 */
#include "sc_quadric.h"

#include <float.h>
#include <math.h>
#include <string.h>

const sc_kernel sc_kernel_quadric = {"quadric", SC_QUADRIC_VERSION, NULL};

/* ---------------------------------------------------------------- quadrics */

void sc_quadric_zero(double *q, int n) { memset(q, 0, sizeof(double) * (size_t)sc_quadric_size(n)); }

void sc_quadric_add(double *dst, const double *src, int n, double scale) {
    int size = sc_quadric_size(n);
    for (int i = 0; i < size; i++) dst[i] += scale * src[i];
}

void sc_quadric_scale(double *q, int n, double s) {
    int size = sc_quadric_size(n);
    for (int i = 0; i < size; i++) q[i] *= s;
}

static inline __attribute__((always_inline)) double eval_sized(const double *q, const int n, const double *x) {
    const double *b = q + n * (n + 1) / 2;
    double c = b[n];
    double quad = 0, lin = 0;
    int k = 0;
    _Pragma("GCC unroll 10")
    for (int i = 0; i < n; i++) {
        quad += q[k++] * x[i] * x[i];
        _Pragma("GCC unroll 10")
        for (int j = i + 1; j < n; j++) quad += 2.0 * q[k++] * x[i] * x[j];
        lin += b[i] * x[i];
    }
    return quad + 2.0 * lin + c;
}

double sc_quadric_eval(const double *q, int n, const double *x) {
    switch (n) {
    case 3: return eval_sized(q, 3, x);
    case 5: return eval_sized(q, 5, x);
    default: return eval_sized(q, n, x);
    }
}

void sc_quadric_unpack(const double *q, int n, double *A, double *b_out) {
    int k = 0;
    for (int i = 0; i < n; i++)
        for (int j = i; j < n; j++, k++) {
            if (A) A[i * n + j] = A[j * n + i] = q[k];
        }
    if (b_out)
        for (int i = 0; i < n; i++) b_out[i] = q[k + i];
}

bool sc_quadric_add_triangle(double *quad, int n, const double *p, const double *q, const double *r,
                             double weight) {
    double e1[SC_QUADRIC_MAX_DIM], e2[SC_QUADRIC_MAX_DIM];
    double len1 = 0, lenr = 0;
    for (int i = 0; i < n; i++) {
        e1[i] = q[i] - p[i];
        e2[i] = r[i] - p[i];
        len1 += e1[i] * e1[i];
        lenr += e2[i] * e2[i];
    }
    len1 = sqrt(len1);
    lenr = sqrt(lenr);
    if (!(len1 > 0) || !(lenr > 0)) return false;
    for (int i = 0; i < n; i++) e1[i] /= len1;
    double along = 0;
    for (int i = 0; i < n; i++) along += e2[i] * e1[i];
    double len2 = 0;
    for (int i = 0; i < n; i++) {
        e2[i] -= along * e1[i];
        len2 += e2[i] * e2[i];
    }
    len2 = sqrt(len2);
    if (!(len2 > 1e-12 * (len1 > lenr ? len1 : lenr))) return false;
    for (int i = 0; i < n; i++) e2[i] /= len2;
    double pe1 = 0, pe2 = 0, pp = 0;
    for (int i = 0; i < n; i++) {
        pe1 += p[i] * e1[i];
        pe2 += p[i] * e2[i];
        pp += p[i] * p[i];
    }
    int k = 0;
    for (int i = 0; i < n; i++)
        for (int j = i; j < n; j++, k++)
            quad[k] += weight * ((i == j ? 1.0 : 0.0) - e1[i] * e1[j] - e2[i] * e2[j]);
    double *b = quad + k;
    for (int i = 0; i < n; i++) b[i] += weight * (pe1 * e1[i] + pe2 * e2[i] - p[i]);
    b[n] += weight * (pp - pe1 * pe1 - pe2 * pe2);
    return true;
}

void sc_quadric_add_plane3(double *quad, int n, const double normal[3], double d, double weight) {
    for (int i = 0; i < 3; i++)
        for (int j = i; j < 3; j++) quad[sc_quadric_index(n, i, j)] += weight * normal[i] * normal[j];
    double *b = quad + n * (n + 1) / 2;
    for (int i = 0; i < 3; i++) b[i] += weight * d * normal[i];
    b[n] += weight * d * d;
}

void sc_quadric_block(double *out, const double *q1, const double *q2, int n) {
    int m = 2 * n;
    sc_quadric_zero(out, m);
    for (int i = 0; i < n; i++)
        for (int j = i; j < n; j++) {
            out[sc_quadric_index(m, i, j)] = q1[sc_quadric_index(n, i, j)];
            out[sc_quadric_index(m, n + i, n + j)] = q2[sc_quadric_index(n, i, j)];
        }
    const double *b1 = q1 + n * (n + 1) / 2, *b2 = q2 + n * (n + 1) / 2;
    double *b = out + m * (m + 1) / 2;
    for (int i = 0; i < n; i++) {
        b[i] = b1[i];
        b[n + i] = b2[i];
    }
    b[m] = b1[n] + b2[n];
}

void sc_quadric_restrict(const double *q, int n, int k, const double *tail, double *out) {
    sc_quadric_zero(out, k);
    const double *b = q + n * (n + 1) / 2;
    double *ob = out + k * (k + 1) / 2;
    for (int i = 0; i < k; i++)
        for (int j = i; j < k; j++) out[sc_quadric_index(k, i, j)] = q[sc_quadric_index(n, i, j)];
    /* linear part: b_head + A_head,tail t */
    for (int i = 0; i < k; i++) {
        double v = b[i];
        for (int j = k; j < n; j++) v += q[sc_quadric_index(n, i, j)] * tail[j - k];
        ob[i] = v;
    }
    /* constant: t^T A_tt t + 2 b_tail . t + c */
    double c = b[n];
    for (int i = k; i < n; i++) {
        c += 2.0 * b[i] * tail[i - k];
        for (int j = k; j < n; j++) c += q[sc_quadric_index(n, i, j)] * tail[i - k] * tail[j - k];
    }
    ob[k] = c;
}

double sc_quadric_default_rho(const double *q, int n) {
    double trace = 0;
    for (int i = 0, k = 0; i < n; k += n - i, i++) trace += q[k];
    return 1e-9 * (fabs(trace) / n + 1e-300);
}

/* The body of sc_quadric_minimize; always inlined so that the common sizes
 * get loops the compiler unrolls completely. */
static inline __attribute__((always_inline)) bool minimize_sized(const double *q, const int n,
                                                                 const double *x_ref, double rho, double *x) {
    double L[SC_QUADRIC_MAX_DIM][SC_QUADRIC_MAX_DIM];
    /* unpack A + rho I (lower triangle is enough) */
    double trace = 0;
    int k = 0;
    _Pragma("GCC unroll 10")
    for (int i = 0; i < n; i++) {
        L[i][i] = q[k++] + rho;
        trace += L[i][i];
        _Pragma("GCC unroll 10")
        for (int j = i + 1; j < n; j++) L[j][i] = q[k++];
    }
    const double *b = q + k;
    /* in-place Cholesky (A + rho I) = L L^T, keeping 1 / L[j][j] */
    double inv[SC_QUADRIC_MAX_DIM];
    const double floor_pivot = DBL_EPSILON * 1e-6 * fabs(trace);
    _Pragma("GCC unroll 10")
    for (int j = 0; j < n; j++) {
        double v = L[j][j];
        _Pragma("GCC unroll 10")
        for (int m = 0; m < j; m++) v -= L[j][m] * L[j][m];
        if (!(v > floor_pivot) || !(v > 0)) return false;
        inv[j] = 1.0 / sqrt(v);
        _Pragma("GCC unroll 10")
        for (int i = j + 1; i < n; i++) {
            double w = L[i][j];
            _Pragma("GCC unroll 10")
            for (int m = 0; m < j; m++) w -= L[i][m] * L[j][m];
            L[i][j] = w * inv[j];
        }
    }
    /* (A + rho I) x = rho x_ref - b */
    double y[SC_QUADRIC_MAX_DIM];
    _Pragma("GCC unroll 10")
    for (int i = 0; i < n; i++) {
        double v = rho * x_ref[i] - b[i];
        _Pragma("GCC unroll 10")
        for (int m = 0; m < i; m++) v -= L[i][m] * y[m];
        y[i] = v * inv[i];
    }
    _Pragma("GCC unroll 10")
    for (int i = n - 1; i >= 0; i--) {
        double v = y[i];
        _Pragma("GCC unroll 10")
        for (int m = i + 1; m < n; m++) v -= L[m][i] * x[m];
        x[i] = v * inv[i];
    }
    return true;
}

bool sc_quadric_minimize(const double *q, int n, const double *x_ref, double rho, double *x) {
    if (n < 1 || n > SC_QUADRIC_MAX_DIM) return false;
    if (rho <= 0) rho = sc_quadric_default_rho(q, n);
    switch (n) {
    case 3: return minimize_sized(q, 3, x_ref, rho, x);
    case 5: return minimize_sized(q, 5, x_ref, rho, x);
    default: return minimize_sized(q, n, x_ref, rho, x);
    }
}

bool sc_quadric_minimize_affine(const double *q, int n, const double *B, int m, const double *c,
                                const double *x_ref, double rho, double *y) {
    if (n < 1 || n > SC_QUADRIC_MAX_DIM || m < 1 || m > n) return false;
    double A[SC_QUADRIC_MAX_DIM * SC_QUADRIC_MAX_DIM], b[SC_QUADRIC_MAX_DIM];
    sc_quadric_unpack(q, n, A, b);
    for (int i = 0; i < n; i++) A[i * n + i] += rho;
    /* the gradient of the objective at B y + c is 2 ((A + rho I)(B y + c) + b - rho x_ref) */
    double r[SC_QUADRIC_MAX_DIM], AB[SC_QUADRIC_MAX_DIM * SC_QUADRIC_MAX_DIM];
    for (int i = 0; i < n; i++) {
        double v = b[i] - rho * x_ref[i];
        for (int k = 0; k < n; k++) v += A[i * n + k] * c[k];
        r[i] = v;
        for (int j = 0; j < m; j++) {
            double w = 0;
            for (int k = 0; k < n; k++) w += A[i * n + k] * B[k * m + j];
            AB[i * m + j] = w;
        }
    }
    /* B^T (A + rho I) B y = -B^T r, lower triangle into L */
    double L[SC_QUADRIC_MAX_DIM][SC_QUADRIC_MAX_DIM], rhs[SC_QUADRIC_MAX_DIM], trace = 0;
    for (int i = 0; i < m; i++) {
        double v = 0;
        for (int k = 0; k < n; k++) v -= B[k * m + i] * r[k];
        rhs[i] = v;
        for (int j = 0; j <= i; j++) {
            double w = 0;
            for (int k = 0; k < n; k++) w += B[k * m + i] * AB[k * m + j];
            L[i][j] = w;
        }
        trace += L[i][i];
    }
    double inv[SC_QUADRIC_MAX_DIM];
    const double floor_pivot = DBL_EPSILON * 1e-6 * fabs(trace);
    for (int j = 0; j < m; j++) {
        double v = L[j][j];
        for (int k = 0; k < j; k++) v -= L[j][k] * L[j][k];
        if (!(v > floor_pivot) || !(v > 0)) return false;
        inv[j] = 1.0 / sqrt(v);
        for (int i = j + 1; i < m; i++) {
            double w = L[i][j];
            for (int k = 0; k < j; k++) w -= L[i][k] * L[j][k];
            L[i][j] = w * inv[j];
        }
    }
    double z[SC_QUADRIC_MAX_DIM];
    for (int i = 0; i < m; i++) {
        double v = rhs[i];
        for (int k = 0; k < i; k++) v -= L[i][k] * z[k];
        z[i] = v * inv[i];
    }
    for (int i = m - 1; i >= 0; i--) {
        double v = z[i];
        for (int k = i + 1; k < m; k++) v -= L[k][i] * y[k];
        y[i] = v * inv[i];
    }
    return true;
}

void sc_sym3_eigen(const double a[6], double values[3], double vectors[3][3]) {
    double m[3][3] = {{a[0], a[1], a[2]}, {a[1], a[3], a[4]}, {a[2], a[4], a[5]}};
    double v[3][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
    for (int sweep = 0; sweep < 50; sweep++) {
        double off = fabs(m[0][1]) + fabs(m[0][2]) + fabs(m[1][2]);
        double diag = fabs(m[0][0]) + fabs(m[1][1]) + fabs(m[2][2]);
        if (off <= 1e-300 || off <= DBL_EPSILON * 1e-3 * diag) break;
        for (int p = 0; p < 2; p++)
            for (int q = p + 1; q < 3; q++) {
                if (m[p][q] == 0) continue;
                double theta = (m[q][q] - m[p][p]) / (2.0 * m[p][q]);
                double t = (theta >= 0 ? 1.0 : -1.0) / (fabs(theta) + sqrt(theta * theta + 1.0));
                double c = 1.0 / sqrt(t * t + 1.0), s = t * c;
                for (int k = 0; k < 3; k++) {   /* m = G^T m G */
                    double mkp = m[k][p], mkq = m[k][q];
                    m[k][p] = c * mkp - s * mkq;
                    m[k][q] = s * mkp + c * mkq;
                }
                for (int k = 0; k < 3; k++) {
                    double mpk = m[p][k], mqk = m[q][k];
                    m[p][k] = c * mpk - s * mqk;
                    m[q][k] = s * mpk + c * mqk;
                }
                for (int k = 0; k < 3; k++) {
                    double vkp = v[k][p], vkq = v[k][q];
                    v[k][p] = c * vkp - s * vkq;
                    v[k][q] = s * vkp + c * vkq;
                }
            }
    }
    for (int k = 0; k < 3; k++) {
        values[k] = m[k][k];
        for (int i = 0; i < 3; i++) vectors[k][i] = v[i][k];
    }
}

double sc_quadric_area_distortion(const double a3[6], const double normal[3]) {
    double trace = a3[0] + a3[3] + a3[5];
    if (!(trace > 0)) return 0.0;
    double values[3], vectors[3][3];
    sc_sym3_eigen(a3, values, vectors);
    double nlen = sqrt(normal[0] * normal[0] + normal[1] * normal[1] + normal[2] * normal[2]);
    int best = 0;
    if (nlen > 0) {
        double best_dot = -1;
        for (int k = 0; k < 3; k++) {
            double d = fabs(vectors[k][0] * normal[0] + vectors[k][1] * normal[1] + vectors[k][2] * normal[2]);
            if (d > best_dot) best_dot = d, best = k;
        }
    } else {   /* no normal: the plane quadric's dominant direction */
        for (int k = 1; k < 3; k++)
            if (values[k] > values[best]) best = k;
    }
    double lambda = values[best];
    if (lambda < 0) lambda = 0;
    if (lambda > trace) lambda = trace;
    return (trace - lambda) / (trace + lambda);
}

/* ---------------------------------------------------------------- QP */

const char *sc_qp_status_name(sc_qp_status s) {
    switch (s) {
    case SC_QP_OK: return "ok";
    case SC_QP_INFEASIBLE: return "infeasible";
    case SC_QP_NOT_CONVEX: return "not positive definite";
    case SC_QP_DEPENDENT: return "dependent equality constraints";
    case SC_QP_BAD_SIZE: return "size out of range";
    case SC_QP_NO_PROGRESS: return "no progress";
    }
    return "?";
}

void sc_qp_init(sc_qp *p, int n) {
    /* H and g start at zero (callers often set only some entries); rows are
     * written as they are added */
    p->n = n;
    p->neq = p->nin = 0;
    if (n > 0 && n <= SC_QP_MAX_N) {
        memset(p->H, 0, sizeof(double) * (size_t)n * (size_t)n);
        memset(p->g, 0, sizeof(double) * (size_t)n);
    }
}

int sc_qp_add_eq(sc_qp *p, const double *row, double rhs) {
    if (p->neq >= SC_QP_MAX_EQ) return -1;
    memcpy(p->Aeq[p->neq], row, sizeof(double) * (size_t)p->n);
    p->beq[p->neq] = rhs;
    return p->neq++;
}

int sc_qp_add_ge(sc_qp *p, const double *row, double rhs) {
    if (p->nin >= SC_QP_MAX_IN) return -1;
    memcpy(p->Ain[p->nin], row, sizeof(double) * (size_t)p->n);
    p->bin[p->nin] = rhs;
    return p->nin++;
}

enum { MAXN = SC_QP_MAX_N, MAXC = SC_QP_MAX_EQ + SC_QP_MAX_IN };

/* The working state of one solve. Constraint k (0 <= k < neq + nin) is row
 * k of Aeq for k < neq, else row k - neq of Ain, written as a.x - b >= 0 (or
 * = 0). */
typedef struct qp_state {
    int n, neq, nin;
    const sc_qp *p;
    double J[MAXN][MAXN];     /* J = L^-T Q: columns 0..nact-1 span the active normals */
    double R[MAXN][MAXN];     /* upper triangular, nact x nact */
    int nact;                 /* active constraints */
    int active[MAXN];         /* their indices */
    double u[MAXN + 1];       /* their multipliers (+ the one being added) */
    double r_norm;
} qp_state;

static const double *constraint_row(const qp_state *s, int k) {
    return k < s->neq ? s->p->Aeq[k] : s->p->Ain[k - s->neq];
}

static double constraint_rhs(const qp_state *s, int k) {
    return k < s->neq ? s->p->beq[k] : s->p->bin[k - s->neq];
}

static double dot(const double *a, const double *b, int n) {
    double s = 0;
    for (int i = 0; i < n; i++) s += a[i] * b[i];
    return s;
}

/* d = J^T a */
static void compute_d(const qp_state *s, const double *a, double *d) {
    for (int i = 0; i < s->n; i++) {
        double v = 0;
        for (int k = 0; k < s->n; k++) v += s->J[k][i] * a[k];
        d[i] = v;
    }
}

/* z = J2 d2: the primal step direction in the null space of the active set. */
static void compute_z(const qp_state *s, const double *d, double *z) {
    for (int i = 0; i < s->n; i++) {
        double v = 0;
        for (int j = s->nact; j < s->n; j++) v += s->J[i][j] * d[j];
        z[i] = v;
    }
}

/* r = R^-1 d1: the dual step direction. */
static void compute_r(const qp_state *s, const double *d, double *r) {
    for (int i = s->nact - 1; i >= 0; i--) {
        double v = d[i];
        for (int j = i + 1; j < s->nact; j++) v -= s->R[i][j] * r[j];
        r[i] = v / s->R[i][i];
    }
}

/* Givens rotation zeroing b against a: returns (c, s) and the new a. */
static bool givens(double a, double b, double *c, double *sn, double *h) {
    double hyp = hypot(a, b);
    if (hyp == 0) return false;
    *c = a / hyp;
    *sn = b / hyp;
    *h = hyp;
    return true;
}

/* Make d's tail (past nact) zero by rotating J's columns, then append d's head
 * as R's new column. False when the new normal depends on the active ones. */
static bool add_constraint(qp_state *s, double *d) {
    int n = s->n;
    for (int j = n - 1; j > s->nact; j--) {
        double c, sn, h;
        if (!givens(d[j - 1], d[j], &c, &sn, &h)) continue;
        d[j - 1] = h;
        d[j] = 0;
        for (int k = 0; k < n; k++) {
            double t1 = s->J[k][j - 1], t2 = s->J[k][j];
            s->J[k][j - 1] = c * t1 + sn * t2;
            s->J[k][j] = -sn * t1 + c * t2;
        }
    }
    int q = s->nact;
    for (int i = 0; i <= q; i++) s->R[i][q] = d[i];
    for (int i = q + 1; i < n; i++) s->R[i][q] = 0;
    double diag = fabs(d[q]);
    if (!(diag > DBL_EPSILON * 16 * s->r_norm) || !(diag > 1e-300)) return false;
    if (diag > s->r_norm) s->r_norm = diag;
    s->nact++;
    return true;
}

/* Remove active constraint at position pos (>= the equality count), keep R
 * upper triangular by rotating rows of R and columns of J. */
static void drop_constraint(qp_state *s, int pos) {
    int n = s->n, q = s->nact;
    for (int i = pos; i < q - 1; i++) {
        s->active[i] = s->active[i + 1];
        s->u[i] = s->u[i + 1];
        for (int k = 0; k < n; k++) s->R[k][i] = s->R[k][i + 1];
    }
    s->active[q - 1] = s->active[q];
    s->u[q - 1] = s->u[q];
    for (int k = 0; k < n; k++) s->R[k][q - 1] = 0;
    s->nact = --q;
    for (int j = pos; j < q; j++) {
        double c, sn, h;
        if (!givens(s->R[j][j], s->R[j + 1][j], &c, &sn, &h)) continue;
        s->R[j][j] = h;
        s->R[j + 1][j] = 0;
        for (int k = j + 1; k < q; k++) {
            double t1 = s->R[j][k], t2 = s->R[j + 1][k];
            s->R[j][k] = c * t1 + sn * t2;
            s->R[j + 1][k] = -sn * t1 + c * t2;
        }
        for (int k = 0; k < n; k++) {
            double t1 = s->J[k][j], t2 = s->J[k][j + 1];
            s->J[k][j] = c * t1 + sn * t2;
            s->J[k][j + 1] = -sn * t1 + c * t2;
        }
    }
}

sc_qp_status sc_qp_solve(const sc_qp *p, sc_qp_result *out) {
    int n = p->n;
    out->objective = 0;
    out->iterations = 0;
    for (int i = 0; i < SC_QP_MAX_EQ; i++) out->lambda_eq[i] = 0;
    for (int i = 0; i < SC_QP_MAX_IN; i++) out->lambda_in[i] = 0, out->active_in[i] = false;
    if (n < 1 || n > MAXN || p->neq < 0 || p->neq > SC_QP_MAX_EQ || p->nin < 0 || p->nin > SC_QP_MAX_IN)
        return SC_QP_BAD_SIZE;
    if (p->neq > n) return SC_QP_DEPENDENT;
    qp_state s;
    s.n = n, s.neq = p->neq, s.nin = p->nin, s.p = p;
    s.nact = 0;
    s.r_norm = 0;
    for (int i = 0; i < n; i++)
        for (int j = 0; j < n; j++) s.R[i][j] = 0;

    /* Cholesky H = L L^T */
    double L[MAXN][MAXN];
    double trace_h = 0;
    for (int i = 0; i < n; i++) trace_h += p->H[i * n + i];
    for (int j = 0; j < n; j++) {
        double v = p->H[j * n + j];
        for (int k = 0; k < j; k++) v -= L[j][k] * L[j][k];
        if (!(v > DBL_EPSILON * 1e-6 * fabs(trace_h)) || !(v > 0)) return SC_QP_NOT_CONVEX;
        L[j][j] = sqrt(v);
        for (int i = j + 1; i < n; i++) {
            double w = p->H[i * n + j];
            for (int k = 0; k < j; k++) w -= L[i][k] * L[j][k];
            L[i][j] = w / L[j][j];
        }
    }
    /* J = L^-T (upper triangular): solve L^T J = I column by column. */
    for (int col = 0; col < n; col++)
        for (int i = n - 1; i >= 0; i--) {
            double v = i == col ? 1.0 : 0.0;
            for (int k = i + 1; k < n; k++) v -= L[k][i] * s.J[k][col];
            s.J[i][col] = v / L[i][i];
        }
    /* unconstrained minimum x = -H^-1 g */
    double x[MAXN], y[MAXN];
    for (int i = 0; i < n; i++) {
        double v = -p->g[i];
        for (int k = 0; k < i; k++) v -= L[i][k] * y[k];
        y[i] = v / L[i][i];
    }
    for (int i = n - 1; i >= 0; i--) {
        double v = y[i];
        for (int k = i + 1; k < n; k++) v -= L[k][i] * x[k];
        x[i] = v / L[i][i];
    }
    double d[MAXN], z[MAXN], r[MAXN];
    /* equality constraints: full steps, always */
    for (int k = 0; k < p->neq; k++) {
        const double *a = constraint_row(&s, k);
        compute_d(&s, a, d);
        compute_z(&s, d, z);
        compute_r(&s, d, r);
        double za = dot(z, a, n);
        if (!(za > 1e-24 * dot(d, d, n))) return SC_QP_DEPENDENT;
        double t = -(dot(a, x, n) - constraint_rhs(&s, k)) / za;
        for (int i = 0; i < n; i++) x[i] += t * z[i];
        for (int i = 0; i < s.nact; i++) s.u[i] -= t * r[i];
        s.u[s.nact] = t;
        s.active[s.nact] = k;
        if (!add_constraint(&s, d)) return SC_QP_DEPENDENT;
    }

    /* inequality constraints */
    bool excluded[SC_QP_MAX_IN];   /* given up on (numerically dependent) */
    memset(excluded, 0, sizeof excluded);
    int iterations = 0;
    const int max_iterations = 20 * (p->nin + 1) + 20;
    for (;;) {
        if (++iterations > max_iterations) return SC_QP_NO_PROGRESS;
        /* Step 1: the most violated inequality not in the active set. */
        bool is_active[SC_QP_MAX_IN] = {0};
        for (int i = p->neq; i < s.nact; i++) is_active[s.active[i] - p->neq] = true;
        double xnorm = sqrt(dot(x, x, n));
        double worst = 0;
        int chosen = -1;
        for (int i = 0; i < p->nin; i++) {
            if (is_active[i] || excluded[i]) continue;
            double slack = dot(p->Ain[i], x, n) - p->bin[i];
            double tol = 1e-12 * (sqrt(dot(p->Ain[i], p->Ain[i], n)) * xnorm + fabs(p->bin[i]) + 1e-300);
            if (slack < -tol && slack / tol < worst) worst = slack / tol, chosen = i;
        }
        if (chosen < 0) break;
        /* Step 2: move until constraint `chosen` holds with equality. */
        qp_state saved = s;
        double saved_x[MAXN];
        memcpy(saved_x, x, sizeof x);
        const double *a = p->Ain[chosen];
        s.u[s.nact] = 0;
        s.active[s.nact] = p->neq + chosen;
        bool done = false;
        for (int inner = 0; inner < 4 * (MAXN + SC_QP_MAX_IN) && !done; inner++) {
            compute_d(&s, a, d);
            compute_z(&s, d, z);
            compute_r(&s, d, r);
            /* partial step: the longest before an active inequality's
             * multiplier reaches zero */
            double t1 = INFINITY;
            int drop_pos = -1;
            for (int i = p->neq; i < s.nact; i++)
                if (r[i] > 0) {
                    double ratio = s.u[i] / r[i];
                    if (ratio < t1) t1 = ratio, drop_pos = i;
                }
            /* full step: the one that makes constraint `chosen` active */
            double za = dot(z, a, n);
            double t2 = INFINITY;
            if (za > 1e-24 * dot(d, d, n)) {
                t2 = -(dot(a, x, n) - p->bin[chosen]) / za;
                if (t2 < 0) t2 = 0;
            }
            double t = t1 < t2 ? t1 : t2;
            if (!isfinite(t)) return SC_QP_INFEASIBLE;
            if (!isfinite(t2)) {   /* dual step only */
                for (int i = 0; i < s.nact; i++) s.u[i] -= t * r[i];
                s.u[s.nact] += t;
                drop_constraint(&s, drop_pos);
                continue;
            }
            for (int i = 0; i < n; i++) x[i] += t * z[i];
            for (int i = 0; i < s.nact; i++) s.u[i] -= t * r[i];
            s.u[s.nact] += t;
            if (t2 <= t1) {
                if (!add_constraint(&s, d)) {   /* rounding: give up on this row */
                    s = saved;
                    memcpy(x, saved_x, sizeof x);
                    excluded[chosen] = true;
                }
                done = true;
            } else {
                drop_constraint(&s, drop_pos);
            }
        }
        if (!done) return SC_QP_NO_PROGRESS;
    }
    /* a row given up on must still hold, to a looser tolerance */
    double xnorm = sqrt(dot(x, x, n));
    for (int i = 0; i < p->nin; i++)
        if (excluded[i]) {
            double slack = dot(p->Ain[i], x, n) - p->bin[i];
            if (slack < -1e-9 * (sqrt(dot(p->Ain[i], p->Ain[i], n)) * xnorm + fabs(p->bin[i]) + 1e-300))
                return SC_QP_NO_PROGRESS;
        }

    memcpy(out->x, x, sizeof(double) * (size_t)n);
    double hx = 0;
    for (int i = 0; i < n; i++) {
        double v = 0;
        for (int j = 0; j < n; j++) v += p->H[i * n + j] * x[j];
        hx += x[i] * v;
    }
    out->objective = 0.5 * hx + dot(p->g, x, n);
    for (int i = 0; i < s.nact; i++) {
        int k = s.active[i];
        if (k < p->neq) out->lambda_eq[k] = s.u[i];
        else {
            out->lambda_in[k - p->neq] = s.u[i];
            out->active_in[k - p->neq] = true;
        }
    }
    out->iterations = iterations;
    return SC_QP_OK;
}

sc_qp_status sc_qp_minimize_quadric(sc_qp *p, const double *quad, const double *x_ref, double rho,
                                    sc_qp_result *out, double *value) {
    int n = p->n;
    double A[MAXN * MAXN], b[MAXN];
    sc_quadric_unpack(quad, n, A, b);
    if (rho <= 0) {
        double trace = 0;
        for (int i = 0; i < n; i++) trace += A[i * n + i];
        rho = 1e-9 * (fabs(trace) / n + 1e-300);
    }
    for (int i = 0; i < n; i++) {
        for (int j = 0; j < n; j++) p->H[i * n + j] = 2.0 * A[i * n + j];
        p->H[i * n + i] += 2.0 * rho;
        p->g[i] = 2.0 * b[i] - 2.0 * rho * x_ref[i];
    }
    sc_qp_status st = sc_qp_solve(p, out);
    if (st == SC_QP_OK && value) {
        double v = sc_quadric_eval(quad, n, out->x);
        *value = v > 0 ? v : 0;
    }
    return st;
}
