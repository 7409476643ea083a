/* test_quadric.c - quadric algebra and the Goldfarb-Idnani QP solver.
 *
 * The solver is checked against facts computed independently here: a brute
 * force that enumerates every subset of inequality rows as the active set,
 * solves that KKT system by Gaussian elimination and keeps the feasible,
 * dual-feasible point of least objective; and the KKT conditions themselves
 * (stationarity, feasibility, complementary slackness, non-negative
 * multipliers). Quadrics are checked against explicit point-to-plane
 * distances computed by projection.
 */
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "sc_quadric.h"
#include "sc_test.h"

/* A small deterministic generator (xorshift64*), so every run is the same. */
static uint64_t rng_state = 0x9E3779B97F4A7C15ull;
static double uniform(double lo, double hi) {
    rng_state ^= rng_state >> 12;
    rng_state ^= rng_state << 25;
    rng_state ^= rng_state >> 27;
    uint64_t v = rng_state * 0x2545F4914F6CDD1Dull;
    return lo + (hi - lo) * ((double)(v >> 11) / 9007199254740992.0);
}

/* Solve the dense system M y = rhs (size m) by Gaussian elimination with
 * partial pivoting; false when singular. */
static bool dense_solve(int m, double *M, double *rhs, double *y) {
    for (int c = 0; c < m; c++) {
        int piv = c;
        for (int r = c + 1; r < m; r++)
            if (fabs(M[r * m + c]) > fabs(M[piv * m + c])) piv = r;
        if (fabs(M[piv * m + c]) < 1e-13) return false;
        if (piv != c) {
            for (int k = 0; k < m; k++) {
                double t = M[c * m + k];
                M[c * m + k] = M[piv * m + k];
                M[piv * m + k] = t;
            }
            double t = rhs[c];
            rhs[c] = rhs[piv];
            rhs[piv] = t;
        }
        for (int r = c + 1; r < m; r++) {
            double f = M[r * m + c] / M[c * m + c];
            for (int k = c; k < m; k++) M[r * m + k] -= f * M[c * m + k];
            rhs[r] -= f * rhs[c];
        }
    }
    for (int r = m - 1; r >= 0; r--) {
        double v = rhs[r];
        for (int k = r + 1; k < m; k++) v -= M[r * m + k] * y[k];
        y[r] = v / M[r * m + r];
    }
    return true;
}

static double objective(const sc_qp *p, const double *x) {
    double v = 0;
    for (int i = 0; i < p->n; i++) {
        double hx = 0;
        for (int j = 0; j < p->n; j++) hx += p->H[i * p->n + j] * x[j];
        v += 0.5 * x[i] * hx + p->g[i] * x[i];
    }
    return v;
}

/* Brute force: every active subset of the inequality rows. Returns false
 * when no subset gives a KKT point (infeasible). */
static bool brute_force(const sc_qp *p, double *best_x) {
    int n = p->n;
    double best = INFINITY;
    bool found = false;
    for (unsigned mask = 0; mask < (1u << p->nin); mask++) {
        int rows[SC_QP_MAX_EQ + SC_QP_MAX_IN], m = 0;
        for (int i = 0; i < p->neq; i++) rows[m++] = i;
        for (int i = 0; i < p->nin; i++)
            if (mask & (1u << i)) rows[m++] = p->neq + i;
        if (m > n) continue;
        int size = n + m;
        double M[(SC_QP_MAX_N + SC_QP_MAX_EQ + SC_QP_MAX_IN) * (SC_QP_MAX_N + SC_QP_MAX_EQ + SC_QP_MAX_IN)];
        double rhs[SC_QP_MAX_N + SC_QP_MAX_EQ + SC_QP_MAX_IN], y[SC_QP_MAX_N + SC_QP_MAX_EQ + SC_QP_MAX_IN];
        memset(M, 0, sizeof(double) * (size_t)(size * size));
        for (int i = 0; i < n; i++) {
            for (int j = 0; j < n; j++) M[i * size + j] = p->H[i * n + j];
            rhs[i] = -p->g[i];
        }
        for (int k = 0; k < m; k++) {
            const double *a = rows[k] < p->neq ? p->Aeq[rows[k]] : p->Ain[rows[k] - p->neq];
            double b = rows[k] < p->neq ? p->beq[rows[k]] : p->bin[rows[k] - p->neq];
            for (int j = 0; j < n; j++) {
                M[(n + k) * size + j] = a[j];
                M[j * size + n + k] = -a[j];   /* H x + g - A^T l = 0 */
            }
            rhs[n + k] = b;
        }
        if (!dense_solve(size, M, rhs, y)) continue;
        bool ok = true;
        for (int k = 0; k < m && ok; k++)
            if (rows[k] >= p->neq && y[n + k] < -1e-9) ok = false;
        for (int i = 0; i < p->nin && ok; i++) {
            double s = -p->bin[i];
            for (int j = 0; j < n; j++) s += p->Ain[i][j] * y[j];
            if (s < -1e-9) ok = false;
        }
        if (!ok) continue;
        double f = objective(p, y);
        if (f < best) {
            best = f;
            memcpy(best_x, y, sizeof(double) * (size_t)n);
            found = true;
        }
    }
    return found;
}

static void random_qp(sc_qp *p, int n, int neq, int nin) {
    sc_qp_init(p, n);
    /* H = M^T M + small diagonal: positive definite, often ill-conditioned */
    double M[SC_QP_MAX_N * SC_QP_MAX_N];
    for (int i = 0; i < n * n; i++) M[i] = uniform(-1, 1);
    for (int i = 0; i < n; i++)
        for (int j = 0; j < n; j++) {
            double v = 0;
            for (int k = 0; k < n; k++) v += M[k * n + i] * M[k * n + j];
            p->H[i * n + j] = v + (i == j ? 1e-3 : 0);
        }
    for (int i = 0; i < n; i++) p->g[i] = uniform(-3, 3);
    double row[SC_QP_MAX_N];
    for (int k = 0; k < neq; k++) {
        for (int j = 0; j < n; j++) row[j] = uniform(-1, 1);
        sc_qp_add_eq(p, row, uniform(-1, 1));
    }
    for (int k = 0; k < nin; k++) {
        for (int j = 0; j < n; j++) row[j] = uniform(-1, 1);
        /* feasible around the origin-ish, so most problems are feasible */
        sc_qp_add_ge(p, row, uniform(-1.0, 0.2));
    }
}

static void check_kkt(const sc_qp *p, const sc_qp_result *r) {
    int n = p->n;
    double scale = 1;
    for (int i = 0; i < n; i++) scale += fabs(p->g[i]);
    for (int i = 0; i < n; i++) {
        double res = p->g[i];
        for (int j = 0; j < n; j++) res += p->H[i * n + j] * r->x[j];
        for (int k = 0; k < p->neq; k++) res -= p->Aeq[k][i] * r->lambda_eq[k];
        for (int k = 0; k < p->nin; k++) res -= p->Ain[k][i] * r->lambda_in[k];
        SC_CHECK_MSG(fabs(res) < 1e-7 * scale, "stationarity row %d residual %g", i, res);
    }
    for (int k = 0; k < p->neq; k++) {
        double s = -p->beq[k];
        for (int j = 0; j < n; j++) s += p->Aeq[k][j] * r->x[j];
        SC_CHECK_MSG(fabs(s) < 1e-9, "equality %d residual %g", k, s);
    }
    for (int k = 0; k < p->nin; k++) {
        double s = -p->bin[k];
        for (int j = 0; j < n; j++) s += p->Ain[k][j] * r->x[j];
        SC_CHECK_MSG(s > -1e-9, "inequality %d violated by %g", k, s);
        SC_CHECK_MSG(r->lambda_in[k] >= -1e-12, "multiplier %d = %g", k, r->lambda_in[k]);
        SC_CHECK_MSG(fabs(s * r->lambda_in[k]) < 1e-7 * scale, "complementarity %d: %g * %g", k, s,
                     r->lambda_in[k]);
    }
}

SC_TEST(qp_matches_brute_force) {
    int solved = 0, infeasible = 0;
    for (int trial = 0; trial < 3000; trial++) {
        int n = 1 + trial % SC_QP_MAX_N;
        int neq = (int)uniform(0, n < 4 ? n : 4);
        int nin = (int)uniform(0, 8);
        sc_qp p;
        random_qp(&p, n, neq, nin);
        double expect[SC_QP_MAX_N];
        bool feasible = brute_force(&p, expect);
        sc_qp_result r;
        sc_qp_status st = sc_qp_solve(&p, &r);
        if (!feasible) {
            SC_CHECK_MSG(st == SC_QP_INFEASIBLE, "trial %d: brute force infeasible, solver says %s", trial,
                         sc_qp_status_name(st));
            infeasible++;
            continue;
        }
        SC_CHECK_MSG(st == SC_QP_OK, "trial %d (n %d, eq %d, in %d): %s", trial, n, neq, nin,
                     sc_qp_status_name(st));
        if (st != SC_QP_OK) continue;
        solved++;
        double fe = objective(&p, expect), fr = objective(&p, r.x);
        SC_CHECK_MSG(fabs(fe - fr) <= 1e-8 * (1 + fabs(fe)), "trial %d: objective %.17g vs brute %.17g", trial,
                     fr, fe);
        SC_CHECK_NEAR(r.objective, fr, 1e-8 * (1 + fabs(fr)));
        check_kkt(&p, &r);
    }
    SC_CHECK(solved > 2000);
    SC_CHECK(infeasible > 10);
    printf("  %d solved, %d infeasible\n", solved, infeasible);
}

SC_TEST(qp_simple_cases) {
    /* min (x-2)^2 + (y-1)^2, s.t. x + y = 1, x >= 0.2 (inactive), y >= 0.5 (active) */
    sc_qp p;
    sc_qp_init(&p, 2);
    p.H[0] = 2, p.H[3] = 2;
    p.g[0] = -4, p.g[1] = -2;
    sc_qp_add_eq(&p, (double[]){1, 1}, 1);
    sc_qp_add_ge(&p, (double[]){1, 0}, 0.2);
    sc_qp_add_ge(&p, (double[]){0, 1}, 0.5);
    sc_qp_result r;
    SC_CHECK_INT(sc_qp_solve(&p, &r), SC_QP_OK);
    /* on x + y = 1 the unconstrained optimum is (1, 0); y >= 0.5 gives (0.5, 0.5) */
    SC_CHECK_NEAR(r.x[0], 0.5, 1e-14);
    SC_CHECK_NEAR(r.x[1], 0.5, 1e-14);
    SC_CHECK(r.active_in[1] && !r.active_in[0]);
    check_kkt(&p, &r);

    /* infeasible bounds */
    sc_qp_init(&p, 1);
    p.H[0] = 1;
    sc_qp_add_ge(&p, (double[]){1}, 1);
    sc_qp_add_ge(&p, (double[]){-1}, 0);
    SC_CHECK_INT(sc_qp_solve(&p, &r), SC_QP_INFEASIBLE);

    /* dependent equalities */
    sc_qp_init(&p, 2);
    p.H[0] = 1, p.H[3] = 1;
    sc_qp_add_eq(&p, (double[]){1, 1}, 1);
    sc_qp_add_eq(&p, (double[]){2, 2}, 2);
    SC_CHECK_INT(sc_qp_solve(&p, &r), SC_QP_DEPENDENT);

    /* not convex */
    sc_qp_init(&p, 2);
    p.H[0] = 1, p.H[3] = -1;
    SC_CHECK_INT(sc_qp_solve(&p, &r), SC_QP_NOT_CONVEX);

    /* a duplicated inequality row is harmless */
    sc_qp_init(&p, 2);
    p.H[0] = 2, p.H[3] = 2;
    p.g[0] = 2, p.g[1] = 2;   /* optimum (-1, -1) */
    sc_qp_add_ge(&p, (double[]){1, 0}, 0);
    sc_qp_add_ge(&p, (double[]){1, 0}, 0);
    SC_CHECK_INT(sc_qp_solve(&p, &r), SC_QP_OK);
    SC_CHECK_NEAR(r.x[0], 0, 1e-14);
    SC_CHECK_NEAR(r.x[1], -1, 1e-14);
    check_kkt(&p, &r);
}

/* Squared distance from x to the affine plane through p, q, r in R^n,
 * by explicit projection (Gram matrix of the two edge vectors). */
static double plane_distance2(int n, const double *p, const double *q, const double *r, const double *x) {
    double e1[SC_QUADRIC_MAX_DIM], e2[SC_QUADRIC_MAX_DIM], d[SC_QUADRIC_MAX_DIM];
    double g11 = 0, g12 = 0, g22 = 0, b1 = 0, b2 = 0;
    for (int i = 0; i < n; i++) {
        e1[i] = q[i] - p[i];
        e2[i] = r[i] - p[i];
        d[i] = x[i] - p[i];
        g11 += e1[i] * e1[i], g12 += e1[i] * e2[i], g22 += e2[i] * e2[i];
        b1 += e1[i] * d[i], b2 += e2[i] * d[i];
    }
    double det = g11 * g22 - g12 * g12;
    double s = (b1 * g22 - b2 * g12) / det, t = (g11 * b2 - g12 * b1) / det;
    double dist = 0;
    for (int i = 0; i < n; i++) {
        double v = d[i] - s * e1[i] - t * e2[i];
        dist += v * v;
    }
    return dist;
}

SC_TEST(quadric_triangle_is_squared_plane_distance) {
    for (int trial = 0; trial < 200; trial++) {
        int n = 3 + trial % 8;
        double p[SC_QUADRIC_MAX_DIM], q[SC_QUADRIC_MAX_DIM], r[SC_QUADRIC_MAX_DIM], x[SC_QUADRIC_MAX_DIM];
        for (int i = 0; i < n; i++) {
            p[i] = uniform(-2, 2), q[i] = uniform(-2, 2), r[i] = uniform(-2, 2), x[i] = uniform(-3, 3);
        }
        double quad[SC_QUADRIC_MAX_SIZE];
        sc_quadric_zero(quad, n);
        SC_CHECK(sc_quadric_add_triangle(quad, n, p, q, r, 2.5));
        double expect = 2.5 * plane_distance2(n, p, q, r, x);
        SC_CHECK_NEAR(sc_quadric_eval(quad, n, x), expect, 1e-10 * (1 + expect));
        /* zero on the triangle's plane */
        double y[SC_QUADRIC_MAX_DIM];
        for (int i = 0; i < n; i++) y[i] = 0.2 * p[i] + 0.3 * q[i] + 0.5 * r[i];
        SC_CHECK_NEAR(sc_quadric_eval(quad, n, y), 0, 1e-10);
        for (int i = 0; i < n; i++) y[i] = 1.7 * p[i] - 2.0 * q[i] + 1.3 * r[i];
        SC_CHECK_NEAR(sc_quadric_eval(quad, n, y), 0, 1e-9);
    }
    /* degenerate triangles add nothing */
    double quad[SC_QUADRIC_MAX_SIZE];
    sc_quadric_zero(quad, 5);
    double a[5] = {0, 0, 0, 0, 0}, b[5] = {1, 1, 1, 1, 1}, c[5] = {2, 2, 2, 2, 2};
    SC_CHECK(!sc_quadric_add_triangle(quad, 5, a, b, c, 1));
    SC_CHECK(!sc_quadric_add_triangle(quad, 5, a, a, c, 1));
    for (int i = 0; i < sc_quadric_size(5); i++) SC_CHECK(quad[i] == 0);
}

SC_TEST(quadric_block_plane_and_sums) {
    int n = 5;
    double q1[SC_QUADRIC_MAX_SIZE], q2[SC_QUADRIC_MAX_SIZE], blk[SC_QUADRIC_MAX_SIZE];
    double p[5], q[5], r[5];
    sc_quadric_zero(q1, n);
    sc_quadric_zero(q2, n);
    for (int t = 0; t < 4; t++) {
        for (int i = 0; i < n; i++) p[i] = uniform(-1, 1), q[i] = uniform(-1, 1), r[i] = uniform(-1, 1);
        sc_quadric_add_triangle(t & 1 ? q1 : q2, n, p, q, r, uniform(0.5, 2));
    }
    sc_quadric_block(blk, q1, q2, n);
    double x[10];
    for (int i = 0; i < 10; i++) x[i] = uniform(-2, 2);
    SC_CHECK_NEAR(sc_quadric_eval(blk, 10, x), sc_quadric_eval(q1, n, x) + sc_quadric_eval(q2, n, x + 5), 1e-10);
    /* add and scale are linear */
    double sum[SC_QUADRIC_MAX_SIZE];
    sc_quadric_zero(sum, n);
    sc_quadric_add(sum, q1, n, 2.0);
    sc_quadric_add(sum, q2, n, -0.5);
    sc_quadric_scale(sum, n, 3.0);
    SC_CHECK_NEAR(sc_quadric_eval(sum, n, x),
                  3.0 * (2.0 * sc_quadric_eval(q1, n, x) - 0.5 * sc_quadric_eval(q2, n, x)), 1e-9);
    /* a plane in xyz ignores the other dimensions */
    double pl[SC_QUADRIC_MAX_SIZE];
    sc_quadric_zero(pl, n);
    double nrm[3] = {0, 0, 2};
    sc_quadric_add_plane3(pl, n, nrm, -1.0, 0.5);
    double y[5] = {7, -3, 1.5, 100, -100};
    SC_CHECK_NEAR(sc_quadric_eval(pl, n, y), 0.5 * (2 * 1.5 - 1.0) * (2 * 1.5 - 1.0), 1e-12);
    /* unpack agrees with index */
    double A[25], b[5];
    sc_quadric_unpack(q1, n, A, b);
    for (int i = 0; i < n; i++)
        for (int j = 0; j < n; j++) SC_CHECK(A[i * n + j] == q1[sc_quadric_index(n, i, j)]);
}

SC_TEST(eigen_and_area_distortion) {
    for (int trial = 0; trial < 100; trial++) {
        double a[6];
        for (int i = 0; i < 6; i++) a[i] = uniform(-1, 1);
        double values[3], vectors[3][3];
        sc_sym3_eigen(a, values, vectors);
        double M[3][3] = {{a[0], a[1], a[2]}, {a[1], a[3], a[4]}, {a[2], a[4], a[5]}};
        for (int k = 0; k < 3; k++) {
            double len = 0;
            for (int i = 0; i < 3; i++) {
                double mv = 0;
                for (int j = 0; j < 3; j++) mv += M[i][j] * vectors[k][j];
                SC_CHECK_NEAR(mv, values[k] * vectors[k][i], 1e-12);
                len += vectors[k][i] * vectors[k][i];
            }
            SC_CHECK_NEAR(len, 1, 1e-12);
        }
    }
    /* Coll & Paradinas: A = diag(a11, a22, a33) in the frame (e1, e2, n):
     * w = (a11 + a22) / (a11 + a22 + 2 a33), in any rotated frame. */
    double a11 = 0.3, a22 = 0.1, a33 = 2.0;
    double c = cos(0.7), s = sin(0.7), c2 = cos(-1.1), s2 = sin(-1.1);
    double R[3][3] = {{c, -s, 0}, {s, c, 0}, {0, 0, 1}}, R2[3][3] = {{1, 0, 0}, {0, c2, -s2}, {0, s2, c2}};
    double Rt[3][3];
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) {
            Rt[i][j] = 0;
            for (int k = 0; k < 3; k++) Rt[i][j] += R2[i][k] * R[k][j];
        }
    double D[3] = {a11, a22, a33}, M[3][3];
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) {
            M[i][j] = 0;
            for (int k = 0; k < 3; k++) M[i][j] += Rt[i][k] * D[k] * Rt[j][k];
        }
    double packed[6] = {M[0][0], M[0][1], M[0][2], M[1][1], M[1][2], M[2][2]};
    double normal[3] = {Rt[0][2] * 0.9 + 0.05, Rt[1][2] * 0.9, Rt[2][2] * 0.9};   /* roughly the n axis */
    SC_CHECK_NEAR(sc_quadric_area_distortion(packed, normal), (a11 + a22) / (a11 + a22 + 2 * a33), 1e-12);
    /* flat: all planes the same -> 0 */
    double flat[6] = {0, 0, 0, 0, 0, 4.0};
    double up[3] = {0, 0, 1};
    SC_CHECK_NEAR(sc_quadric_area_distortion(flat, up), 0, 1e-15);
    double zero[6] = {0};
    SC_CHECK(sc_quadric_area_distortion(zero, up) == 0);
}

SC_TEST(minimize_quadric_singular_picks_nearest) {
    /* A quadric that only constrains x[0] = 1 (a plane in 3D): the minimiser
     * nearest the reference point (0, 5, -2) is (1, 5, -2). */
    int n = 3;
    double quad[SC_QUADRIC_MAX_SIZE];
    sc_quadric_zero(quad, n);
    double nrm[3] = {1, 0, 0};
    sc_quadric_add_plane3(quad, n, nrm, -1.0, 1.0);
    sc_qp p;
    sc_qp_init(&p, n);
    double ref[3] = {0, 5, -2}, value;
    sc_qp_result r;
    SC_CHECK_INT(sc_qp_minimize_quadric(&p, quad, ref, 0, &r, &value), SC_QP_OK);
    SC_CHECK_NEAR(r.x[0], 1, 1e-8);
    SC_CHECK_NEAR(r.x[1], 5, 1e-8);
    SC_CHECK_NEAR(r.x[2], -2, 1e-8);
    SC_CHECK_NEAR(value, 0, 1e-15);
    /* with x[0] bounded to <= 0.25, the constrained optimum is on the bound */
    sc_qp_init(&p, n);
    sc_qp_add_ge(&p, (double[]){-1, 0, 0}, -0.25);
    SC_CHECK_INT(sc_qp_minimize_quadric(&p, quad, ref, 0, &r, &value), SC_QP_OK);
    SC_CHECK_NEAR(r.x[0], 0.25, 1e-12);
    SC_CHECK_NEAR(value, 0.75 * 0.75, 1e-9);
}

SC_TEST(restrict_and_minimize_match_the_qp) {
    /* Fixing the last dimensions of a quadric and minimising over the rest
     * equals the QP with those dimensions held by equality constraints. */
    for (int trial = 0; trial < 300; trial++) {
        int n = 3 + trial % 8, k = 1 + trial % (n - 1);
        double quad[SC_QUADRIC_MAX_SIZE];
        sc_quadric_zero(quad, n);
        for (int t = 0; t < 4; t++) {
            double p[SC_QUADRIC_MAX_DIM], q[SC_QUADRIC_MAX_DIM], r[SC_QUADRIC_MAX_DIM];
            for (int i = 0; i < n; i++) p[i] = uniform(-1, 1), q[i] = uniform(-1, 1), r[i] = uniform(-1, 1);
            sc_quadric_add_triangle(quad, n, p, q, r, uniform(0.2, 2));
        }
        double tail[SC_QUADRIC_MAX_DIM], ref[SC_QUADRIC_MAX_DIM], y[SC_QUADRIC_MAX_DIM];
        for (int i = 0; i < n; i++) ref[i] = uniform(-1, 1);
        for (int i = 0; i < n - k; i++) tail[i] = uniform(-1, 1);
        /* restricted quadric evaluates like the full one */
        double part[SC_QUADRIC_MAX_SIZE];
        sc_quadric_restrict(quad, n, k, tail, part);
        for (int i = 0; i < k; i++) y[i] = uniform(-2, 2);
        for (int i = k; i < n; i++) y[i] = tail[i - k];
        SC_CHECK_NEAR(sc_quadric_eval(part, k, y), sc_quadric_eval(quad, n, y), 1e-10);
        /* and its minimiser is the QP's with the tail fixed */
        double rho = 1e-3, x[SC_QUADRIC_MAX_DIM];
        SC_CHECK(sc_quadric_minimize(part, k, ref, rho, x));
        sc_qp p;
        sc_qp_init(&p, n);
        for (int i = k; i < n; i++) {
            double row[SC_QUADRIC_MAX_DIM] = {0};
            row[i] = 1;
            sc_qp_add_eq(&p, row, tail[i - k]);
        }
        /* the QP regularises the fixed dimensions too; make that term
         * constant by putting their reference on the fixed values */
        double ref_full[SC_QUADRIC_MAX_DIM];
        for (int i = 0; i < n; i++) ref_full[i] = i < k ? ref[i] : tail[i - k];
        sc_qp_result r;
        SC_CHECK_INT(sc_qp_minimize_quadric(&p, quad, ref_full, rho, &r, NULL), SC_QP_OK);
        for (int i = 0; i < k; i++) SC_CHECK_NEAR(x[i], r.x[i], 1e-9);
        /* unconstrained: the normal equations hold */
        double xf[SC_QUADRIC_MAX_DIM], A[SC_QUADRIC_MAX_DIM * SC_QUADRIC_MAX_DIM], b[SC_QUADRIC_MAX_DIM];
        SC_CHECK(sc_quadric_minimize(quad, n, ref, rho, xf));
        sc_quadric_unpack(quad, n, A, b);
        for (int i = 0; i < n; i++) {
            double g = b[i] + rho * (xf[i] - ref[i]);
            for (int j = 0; j < n; j++) g += A[i * n + j] * xf[j];
            SC_CHECK_NEAR(g, 0, 1e-10);
        }
    }
}

/* The minimiser over an affine subspace {B y + c} is the QP's under the
 * equalities that describe the same subspace: N^T x = N^T c for a basis N of
 * B's orthogonal complement (built here by Gram-Schmidt, apart from the code
 * under test), and its gradient is orthogonal to the subspace. */
SC_TEST(affine_minimize_matches_the_qp) {
    srand(7);
    for (int trial = 0; trial < 200; trial++) {
        int n = 3 + rand() % 8, m = 1 + rand() % n;
        double quad[SC_QUADRIC_MAX_SIZE];
        sc_quadric_zero(quad, n);
        for (int t = 0; t < 3; t++) {   /* semidefinite: rho makes it definite */
            double p[SC_QUADRIC_MAX_DIM], q[SC_QUADRIC_MAX_DIM], r[SC_QUADRIC_MAX_DIM];
            for (int i = 0; i < n; i++) p[i] = uniform(-1, 1), q[i] = uniform(-1, 1), r[i] = uniform(-1, 1);
            sc_quadric_add_triangle(quad, n, p, q, r, uniform(0.2, 2));
        }
        double B[SC_QUADRIC_MAX_DIM * SC_QUADRIC_MAX_DIM], c[SC_QUADRIC_MAX_DIM], ref[SC_QUADRIC_MAX_DIM];
        for (int i = 0; i < n; i++) {
            c[i] = uniform(-1, 1), ref[i] = uniform(-1, 1);
            for (int j = 0; j < m; j++) B[i * m + j] = uniform(-1, 1);
        }
        double rho = 1e-3, y[SC_QUADRIC_MAX_DIM], x[SC_QUADRIC_MAX_DIM];
        SC_CHECK(sc_quadric_minimize_affine(quad, n, B, m, c, ref, rho, y));
        for (int i = 0; i < n; i++) {
            x[i] = c[i];
            for (int j = 0; j < m; j++) x[i] += B[i * m + j] * y[j];
        }
        /* an orthonormal basis of range(B), then of its complement */
        double basis[SC_QUADRIC_MAX_DIM][SC_QUADRIC_MAX_DIM];
        int nb = 0;
        for (int v = 0; v < m + n; v++) {
            double w[SC_QUADRIC_MAX_DIM];
            for (int i = 0; i < n; i++) w[i] = v < m ? B[i * m + v] : (i == v - m);
            for (int b = 0; b < nb; b++) {
                double d = 0;
                for (int i = 0; i < n; i++) d += w[i] * basis[b][i];
                for (int i = 0; i < n; i++) w[i] -= d * basis[b][i];
            }
            double len = 0;
            for (int i = 0; i < n; i++) len += w[i] * w[i];
            if (len < 1e-12) continue;
            for (int i = 0; i < n; i++) basis[nb][i] = w[i] / sqrt(len);
            nb++;
        }
        SC_CHECK_INT(nb, n);
        sc_qp p;
        sc_qp_init(&p, n);
        for (int b = m; b < n; b++) {
            double rhs = 0;
            for (int i = 0; i < n; i++) rhs += basis[b][i] * c[i];
            sc_qp_add_eq(&p, basis[b], rhs);
        }
        sc_qp_result r;
        SC_CHECK_INT(sc_qp_minimize_quadric(&p, quad, ref, rho, &r, NULL), SC_QP_OK);
        for (int i = 0; i < n; i++) SC_CHECK_NEAR(x[i], r.x[i], 1e-8);
        double A[SC_QUADRIC_MAX_DIM * SC_QUADRIC_MAX_DIM], b[SC_QUADRIC_MAX_DIM], g[SC_QUADRIC_MAX_DIM];
        sc_quadric_unpack(quad, n, A, b);
        for (int i = 0; i < n; i++) {
            g[i] = b[i] + rho * (x[i] - ref[i]);
            for (int j = 0; j < n; j++) g[i] += A[i * n + j] * x[j];
        }
        for (int j = 0; j < m; j++) {
            double d = 0;
            for (int i = 0; i < n; i++) d += B[i * m + j] * g[i];
            SC_CHECK_NEAR(d, 0, 1e-9);
        }
    }
}

int main(void) { return sc_test_main(); }
