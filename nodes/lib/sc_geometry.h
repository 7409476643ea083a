/* sc_geometry.h - the small vector helpers nodes and kernels share, and the
 * bounding-box diagonal, the unit every error bound is a fraction of.
 *
 * All inline and written out term by term: each result is the same double,
 * bit for bit, wherever it is computed (the build contracts nothing into fused
 * multiply-adds), so moving a computation here changes no output. Points
 * are arrays of doubles: 3D (x, y, z) or 2D (u, v).
 */
#ifndef SC_GEOMETRY_H
#define SC_GEOMETRY_H

#include <math.h>
#include <stdbool.h>
#include <stdint.h>

/* ---------------------------------------------------------------- 3D */

static inline double sc_dot3(const double *a, const double *b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

/* out = a - b */
static inline void sc_sub3(const double *a, const double *b, double *out) {
    out[0] = a[0] - b[0], out[1] = a[1] - b[1], out[2] = a[2] - b[2];
}

/* out = a x b (out may be a or b) */
static inline void sc_cross3(const double *a, const double *b, double *out) {
    double c[3] = {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
    out[0] = c[0], out[1] = c[1], out[2] = c[2];
}

/* n = (q - p) x (r - p): normal to triangle p q r, as long as twice its area */
static inline void sc_triangle_normal(const double *p, const double *q, const double *r, double *n) {
    double e1[3], e2[3];
    sc_sub3(q, p, e1);
    sc_sub3(r, p, e2);
    sc_cross3(e1, e2, n);
}

static inline double sc_norm3(const double *a) { return sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]); }

/* a scaled to unit length; a zero vector stays as it is */
static inline void sc_normalize3(double *a) {
    double l = sc_norm3(a);
    if (l > 0) a[0] /= l, a[1] /= l, a[2] /= l;
}

/* |a - b|^2 */
static inline double sc_dist3_squared(const double *a, const double *b) {
    return (a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) + (a[2] - b[2]) * (a[2] - b[2]);
}

static inline double sc_dist3(const double *a, const double *b) {
    double dx = a[0] - b[0], dy = a[1] - b[1], dz = a[2] - b[2];
    return sqrt(dx * dx + dy * dy + dz * dz);
}

/* ---------------------------------------------------------------- 2D */

/* Twice the signed area of triangle a b c: > 0 when counter-clockwise. */
static inline double sc_orient2(const double *a, const double *b, const double *c) {
    return (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
}

/* |q - p| as sqrt(x^2 + y^2) */
static inline double sc_dist2(const double *p, const double *q) {
    double x = q[0] - p[0], y = q[1] - p[1];
    return sqrt(x * x + y * y);
}

/* |q - p| through hypot: no overflow or underflow in the squares, and a
 * last bit that can differ from sc_dist2's. */
static inline double sc_hypot2(const double *p, const double *q) { return hypot(q[0] - p[0], q[1] - p[1]); }

/* Whether `mid` lies strictly between p and q along the chord p-q and within
 * relative |q - p| + slack of the line through them. Each caller passes its
 * own tolerances. */
static inline bool sc_collinear_through(const double *p, const double *mid, const double *q, double relative,
                                        double slack) {
    double chord[2] = {q[0] - p[0], q[1] - p[1]}, d[2] = {mid[0] - p[0], mid[1] - p[1]};
    double len2 = chord[0] * chord[0] + chord[1] * chord[1];
    if (!(len2 > 0)) return false;
    double along = d[0] * chord[0] + d[1] * chord[1];
    if (!(along > 0) || !(along < len2)) return false;
    double len = sqrt(len2);
    return fabs(d[0] * chord[1] - d[1] * chord[0]) / len <= relative * len + slack;
}

/* ---------------------------------------------------------------- bounding box */

/* Widen lo, hi (3 each) by the n points P (n x 3). */
static inline void sc_bbox_add(const double *P, int32_t n, double lo[3], double hi[3]) {
    for (int32_t i = 0; i < n; i++)
        for (int c = 0; c < 3; c++) {
            double x = P[3 * (int64_t)i + c];
            if (x < lo[c]) lo[c] = x;
            if (x > hi[c]) hi[c] = x;
        }
}

/* The diagonal of the bounding box of the points V (nv x 3), or with faces F
 * (nf x 3, may be NULL) of the points they use only; 0 when there are none. */
static inline double sc_bbox_diagonal(const double *V, int32_t nv, const int32_t *F, int32_t nf) {
    double lo[3] = {HUGE_VAL, HUGE_VAL, HUGE_VAL}, hi[3] = {-HUGE_VAL, -HUGE_VAL, -HUGE_VAL};
    int64_t n = F ? 3 * (int64_t)nf : nv;
    if (n == 0) return 0;
    for (int64_t i = 0; i < n; i++) sc_bbox_add(V + 3 * (int64_t)(F ? F[i] : i), 1, lo, hi);
    double extent[3] = {hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]};
    return sc_norm3(extent);
}

#endif
