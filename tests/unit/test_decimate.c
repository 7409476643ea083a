/* test_decimate.c - the node `decimate`, checked by properties computed here
 * independently of the decimator's own bookkeeping:
 *
 *   - uv silhouettes: the uv boundary edges of every level (edges of the
 *     parameter mesh used by one face) lie on the input's uv boundary
 *     polylines, and cover them, to 1e-9 in uv;
 *   - orientation: the uv centroid of every face of a level lies in an input
 *     uv triangle of the same orientation (no flipped uv faces);
 *   - validity: edge-manifold with consistent orientation, the input's Euler
 *     characteristic, no degenerate triangles in 3D or uv;
 *   - targets reached; materials kept; deterministic bytes;
 *   - the Figure 8 case of Liu et al. 2017 (collinear seam halves with
 *     mismatched length ratios) does not collapse, the matched one does;
 *   - seam-aware beats the frozen-silhouette baseline in Hausdorff distance at
 *     an equal face count; "free" raises the seam energy of a seam-free
 *     texture, "aware" keeps it (sc_seam's exact energy; an independent
 *     sampler from check_seams.h is used when present);
 *   - error tracking: on a thin disk at 100 and 60 faces the tracked cost
 *     keeps the rim the quadric alone cuts (Hausdorff by brute force here,
 *     under half); the bounded BVH query it uses against brute force;
 *   - corpus (blub, spot; skipped without it): erase_seams -> straighten ->
 *     decimate keeps the seam energy of the straightened seam-free texture
 *     on every level within 1e-8 of the input's energy before erasure, the
 *     straightened uv boundary exactly (1e-9), with no flipped uv faces;
 *     blub at 1% (142 faces) within 2% Hausdorff (project issue 4).
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "sc_exec.h"
#include "sc_geometry.h"
#include "sc_hausdorff.h"
#include "sc_nodes.h"
#include "sc_obj.h"
#include "sc_test.h"

/* ---------------------------------------------------------------- running nodes */

typedef struct node_run {
    sc_ctx *ctx;
    sc_value *out;   /* output 0, borrowed from ctx */
    sc_error err;
    int rc;
} node_run;

/* sc_test_run_node with one optional input on port `port`, output 0 at hand. */
static node_run run_node(const sc_node_desc *d, const char *const *params, const char *port, sc_value *input) {
    sc_test_run t = sc_test_run_node(d, params, port, input, NULL, NULL);
    node_run r = {t.ctx, t.rc == SC_OK ? sc_ctx_output(t.ctx, 0) : NULL, t.err, t.rc};
    return r;
}

static void run_free(node_run *r) {
    sc_ctx_free(r->ctx);
    memset(r, 0, sizeof *r);
}

static sc_value *procedural(int resolution, int texture_size, double tint) {
    char res[16], tex[16], tin[32];
    snprintf(res, sizeof res, "%d", resolution);
    snprintf(tex, sizeof tex, "%d", texture_size);
    snprintf(tin, sizeof tin, "%g", tint);
    const char *params[] = {"resolution", res, "texture_size", tex, "chart_tint", tin, NULL};
    node_run r = run_node(&sc_node_procedural, params, NULL, NULL);
    SC_CHECK_MSG(r.rc == SC_OK, "procedural: %s", r.err.message);
    sc_value *v = r.out ? sc_value_retain(r.out) : NULL;
    run_free(&r);
    return v;
}

static const sc_mesh *level_mesh(const sc_value *lods, int k) {
    return lods->as.lods->levels[k]->as.atlas->mesh->as.mesh;
}

/* ---------------------------------------------------------------- independent checks */

typedef struct seg2 {
    double a[2], b[2];
} seg2;

static int compare_uv_edge(const void *p, const void *q) {
    const int32_t *a = p, *b = q;
    if (a[0] != b[0]) return a[0] < b[0] ? -1 : 1;
    if (a[1] != b[1]) return a[1] < b[1] ? -1 : 1;
    return a[2] < b[2] ? -1 : a[2] > b[2];
}

/* uv boundary edges: uv index pairs used by exactly one face. */
static int boundary_segments(const sc_mesh *m, seg2 **out) {
    int n = m->nf * 3, count = 0;
    int32_t (*e)[3] = malloc(sizeof(*e) * (size_t)n);
    seg2 *s = malloc(sizeof(*s) * (size_t)n);
    for (int f = 0; f < m->nf; f++)
        for (int k = 0; k < 3; k++) {
            int32_t x = m->FU[3 * f + k], y = m->FU[3 * f + (k + 1) % 3];
            e[3 * f + k][0] = x < y ? x : y;
            e[3 * f + k][1] = x < y ? y : x;
            e[3 * f + k][2] = 3 * f + k;
        }
    qsort(e, (size_t)n, sizeof(*e), compare_uv_edge);
    for (int i = 0; i < n;) {
        int j = i;
        while (j < n && e[j][0] == e[i][0] && e[j][1] == e[i][1]) j++;
        if (j - i == 1) {
            int32_t x = e[i][0], y = e[i][1];
            memcpy(s[count].a, m->U + 2 * x, sizeof(double) * 2);
            memcpy(s[count].b, m->U + 2 * y, sizeof(double) * 2);
            count++;
        }
        i = j;
    }
    free(e);
    *out = s;
    return count;
}

static double point_segment_distance(const double p[2], const seg2 *s) {
    double d[2] = {s->b[0] - s->a[0], s->b[1] - s->a[1]};
    double len2 = d[0] * d[0] + d[1] * d[1];
    double t = len2 > 0 ? ((p[0] - s->a[0]) * d[0] + (p[1] - s->a[1]) * d[1]) / len2 : 0;
    t = t < 0 ? 0 : t > 1 ? 1 : t;
    return hypot(s->a[0] + t * d[0] - p[0], s->a[1] + t * d[1] - p[1]);
}

static bool near_any(const double p[2], const seg2 *s, int n, double tol) {
    for (int i = 0; i < n; i++)
        if (point_segment_distance(p, &s[i]) <= tol) return true;
    return false;
}

static int cmp_double(const void *p, const void *q) {
    double a = *(const double *)p, b = *(const double *)q;
    return a < b ? -1 : a > b;
}

/* Returns the number of violations: LOD boundary pieces off the input's
 * silhouettes, plus input silhouette points the LOD does not cover. */
static int check_silhouettes(const sc_mesh *in, const sc_mesh *out, double tol) {
    seg2 *si, *so;
    int ni = boundary_segments(in, &si), no = boundary_segments(out, &so);
    int bad = 0;
    double *params = malloc(sizeof(double) * (size_t)(2 * ni + 2));
    for (int i = 0; i < no; i++) {
        const seg2 *s = &so[i];
        double d[2] = {s->b[0] - s->a[0], s->b[1] - s->a[1]};
        double len2 = d[0] * d[0] + d[1] * d[1];
        int np = 0;
        params[np++] = 0;
        params[np++] = 1;
        for (int j = 0; j < ni; j++)
            for (int e = 0; e < 2; e++) {
                const double *p = e ? si[j].b : si[j].a;
                if (point_segment_distance(p, s) > tol || len2 <= 0) continue;
                double t = ((p[0] - s->a[0]) * d[0] + (p[1] - s->a[1]) * d[1]) / len2;
                if (t > 0 && t < 1) params[np++] = t;
            }
        qsort(params, (size_t)np, sizeof(double), cmp_double);
        for (int k = 0; k < np; k++) {
            double q[2] = {s->a[0] + params[k] * d[0], s->a[1] + params[k] * d[1]};
            bool ok = near_any(q, si, ni, tol);
            if (ok && k + 1 < np) {
                double mid = 0.5 * (params[k] + params[k + 1]);
                double m2[2] = {s->a[0] + mid * d[0], s->a[1] + mid * d[1]};
                ok = near_any(m2, si, ni, tol);
            }
            if (!ok) {
                if (bad < 5)
                    fprintf(stderr, "  level boundary (%.12g %.12g)-(%.12g %.12g) leaves the input silhouette\n",
                            s->a[0], s->a[1], s->b[0], s->b[1]);
                bad++;
                break;
            }
        }
    }
    for (int j = 0; j < ni; j++) {
        double mid[2] = {0.5 * (si[j].a[0] + si[j].b[0]), 0.5 * (si[j].a[1] + si[j].b[1])};
        if (!near_any(si[j].a, so, no, tol) || !near_any(mid, so, no, tol)) {
            if (bad < 10)
                fprintf(stderr, "  input silhouette (%.12g %.12g)-(%.12g %.12g) not covered\n", si[j].a[0], si[j].a[1],
                        si[j].b[0], si[j].b[1]);
            bad++;
        }
    }
    free(params);
    free(si);
    free(so);
    return bad;
}

static double uv_signed_area(const sc_mesh *m, int f) {
    const double *a = m->U + 2 * m->FU[3 * f], *b = m->U + 2 * m->FU[3 * f + 1], *c = m->U + 2 * m->FU[3 * f + 2];
    return 0.5 * ((b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]));
}

/* The cells of a G x G grid over [lo, hi] that a uv box overlaps. */
enum { GRID = 64 };
static void grid_range(const double lo[2], const double hi[2], const double blo[2], const double bhi[2], int r[4]) {
    for (int k = 0; k < 2; k++) {
        double span = hi[k] - lo[k] > 0 ? hi[k] - lo[k] : 1;
        int a = (int)floor((blo[k] - lo[k]) / span * GRID), b = (int)floor((bhi[k] - lo[k]) / span * GRID);
        r[2 * k] = a < 0 ? 0 : a >= GRID ? GRID - 1 : a;
        r[2 * k + 1] = b < 0 ? 0 : b >= GRID ? GRID - 1 : b;
    }
}

static void face_uv_box(const sc_mesh *m, int f, double blo[2], double bhi[2]) {
    blo[0] = blo[1] = INFINITY, bhi[0] = bhi[1] = -INFINITY;
    for (int c = 0; c < 3; c++)
        for (int k = 0; k < 2; k++) {
            double x = m->U[2 * m->FU[3 * f + c] + k];
            blo[k] = fmin(blo[k], x);
            bhi[k] = fmax(bhi[k], x);
        }
}

/* Faces of `out` whose uv centroid is not inside an input uv triangle of the
 * same orientation (a flipped or misplaced uv face). */
static int check_uv_orientation(const sc_mesh *in, const sc_mesh *out) {
    double lo[2] = {INFINITY, INFINITY}, hi[2] = {-INFINITY, -INFINITY};
    for (int i = 0; i < in->nu; i++)
        for (int k = 0; k < 2; k++) {
            lo[k] = fmin(lo[k], in->U[2 * i + k]);
            hi[k] = fmax(hi[k], in->U[2 * i + k]);
        }
    int *start = calloc(GRID * GRID + 1, sizeof(int)), *fill = calloc(GRID * GRID, sizeof(int));
    for (int pass = 0; pass < 2; pass++) {
        for (int f = 0; f < in->nf; f++) {
            double blo[2], bhi[2];
            int r[4];
            face_uv_box(in, f, blo, bhi);
            grid_range(lo, hi, blo, bhi, r);
            for (int j = r[2]; j <= r[3]; j++)
                for (int i = r[0]; i <= r[1]; i++) fill[j * GRID + i]++;
        }
        if (pass == 0) {
            int acc = 0;
            for (int c = 0; c < GRID * GRID; c++) {
                start[c] = acc;
                acc += fill[c];
                fill[c] = 0;
            }
            start[GRID * GRID] = acc;
        }
    }
    /* fill again, now writing the face ids */
    int *items = malloc(sizeof(int) * (size_t)(start[GRID * GRID] + 1));
    memset(fill, 0, sizeof(int) * GRID * GRID);
    for (int f = 0; f < in->nf; f++) {
        double blo[2], bhi[2];
        int r[4];
        face_uv_box(in, f, blo, bhi);
        grid_range(lo, hi, blo, bhi, r);
        for (int j = r[2]; j <= r[3]; j++)
            for (int i = r[0]; i <= r[1]; i++) items[start[j * GRID + i] + fill[j * GRID + i]++] = f;
    }
    int bad = 0;
    for (int f = 0; f < out->nf; f++) {
        double area = uv_signed_area(out, f);
        double c[2] = {0, 0};
        for (int k = 0; k < 3; k++)
            for (int d = 0; d < 2; d++) c[d] += out->U[2 * out->FU[3 * f + k] + d] / 3.0;
        int r[4];
        grid_range(lo, hi, c, c, r);
        int cell = r[2] * GRID + r[0];
        bool found = false;
        for (int t = start[cell]; t < start[cell + 1] && !found; t++) {
            int g = items[t];
            const double *a = in->U + 2 * in->FU[3 * g], *b = in->U + 2 * in->FU[3 * g + 1],
                         *cc = in->U + 2 * in->FU[3 * g + 2];
            double s0 = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
            double s1 = (cc[0] - b[0]) * (c[1] - b[1]) - (cc[1] - b[1]) * (c[0] - b[0]);
            double s2 = (a[0] - cc[0]) * (c[1] - cc[1]) - (a[1] - cc[1]) * (c[0] - cc[0]);
            double gin = uv_signed_area(in, g);
            bool inside = gin > 0 ? (s0 >= 0 && s1 >= 0 && s2 >= 0) : (s0 <= 0 && s1 <= 0 && s2 <= 0);
            if (inside && gin != 0 && area * gin > 0) found = true;
        }
        if (!found) bad++;
    }
    free(items);
    free(start);
    free(fill);
    return bad;
}

typedef struct edge3 {
    int32_t lo, hi, face, forward;
} edge3;

static int cmp_edge3(const void *p, const void *q) {
    const edge3 *a = p, *b = q;
    if (a->lo != b->lo) return a->lo < b->lo ? -1 : 1;
    if (a->hi != b->hi) return a->hi < b->hi ? -1 : 1;
    return a->face < b->face ? -1 : a->face > b->face;
}

/* Edge-manifold with consistent orientation; returns the violations and the
 * Euler characteristic V - E + F of the used vertices. */
static int check_manifold(const sc_mesh *m, int *euler) {
    int n = m->nf * 3, bad = 0, edges = 0;
    edge3 *e = malloc(sizeof *e * (size_t)n);
    for (int f = 0; f < m->nf; f++)
        for (int k = 0; k < 3; k++) {
            int32_t x = m->FV[3 * f + k], y = m->FV[3 * f + (k + 1) % 3];
            e[3 * f + k] = (edge3){x < y ? x : y, x < y ? y : x, f, x < y};
        }
    qsort(e, (size_t)n, sizeof *e, cmp_edge3);
    for (int i = 0; i < n;) {
        int j = i;
        while (j < n && e[j].lo == e[i].lo && e[j].hi == e[i].hi) j++;
        edges++;
        if (j - i > 2) bad++;
        if (j - i == 2 && e[i].forward == e[i + 1].forward) bad++;
        i = j;
    }
    free(e);
    char *used = calloc((size_t)m->nv + 1, 1);
    int nv = 0;
    for (int i = 0; i < n; i++) used[m->FV[i]] = 1;
    for (int v = 0; v < m->nv; v++) nv += used[v];
    free(used);
    *euler = nv - edges + m->nf;
    return bad;
}

static int check_degenerate(const sc_mesh *m) {
    int bad = 0;
    for (int f = 0; f < m->nf; f++) {
        const int32_t *c = m->FV + 3 * f;
        if (c[0] == c[1] || c[1] == c[2] || c[0] == c[2]) {
            bad++;
            continue;
        }
        const double *a = m->V + 3 * c[0], *b = m->V + 3 * c[1], *d = m->V + 3 * c[2];
        double u[3], v[3], x[3];
        for (int k = 0; k < 3; k++) u[k] = b[k] - a[k], v[k] = d[k] - a[k];
        x[0] = u[1] * v[2] - u[2] * v[1], x[1] = u[2] * v[0] - u[0] * v[2], x[2] = u[0] * v[1] - u[1] * v[0];
        double area = sqrt(x[0] * x[0] + x[1] * x[1] + x[2] * x[2]);
        double lmax = fmax(fmax(u[0] * u[0] + u[1] * u[1] + u[2] * u[2], v[0] * v[0] + v[1] * v[1] + v[2] * v[2]), 1e-300);
        if (!(area > 1e-12 * lmax)) bad++;
        if (!(fabs(uv_signed_area(m, f)) > 0)) bad++;
    }
    return bad;
}

static double hausdorff_fraction(const sc_mesh *a, const sc_mesh *b) {
    sc_hausdorff_mesh ma = {a->V, a->nv, a->FV, a->nf}, mb = {b->V, b->nv, b->FV, b->nf};
    sc_hausdorff_result r;
    sc_error err;
    if (sc_hausdorff(&ma, &mb, 200000, 2, &r, &err) != SC_OK) return INFINITY;
    return r.distance / sc_bbox_diagonal(a->V, a->nv, a->FV, a->nf);
}

/* Level faces whose signed uv area differs in sign from the input's, when
 * every input face has the same sign (-1 when they do not). */
static int check_uv_signs(const sc_mesh *in, const sc_mesh *out) {
    int positive = 0;
    for (int f = 0; f < in->nf; f++) positive += uv_signed_area(in, f) > 0;
    if (positive != 0 && positive != in->nf) return -1;
    int bad = 0;
    for (int f = 0; f < out->nf; f++) {
        double a = uv_signed_area(out, f);
        if (!(positive ? a > 0 : a < 0)) bad++;
    }
    return bad;
}

/* What check_level checks beyond validity: uv faces inside the input's
 * charts with the orientation they had (what aware and fixed keep; free
 * moves silhouettes, so its faces may leave the charts and only their
 * orientation is checked, on inputs whose uv faces share one), and the uv
 * silhouettes kept exactly. */
enum { LEVEL_FREE = 0, LEVEL_CHARTS = 1, LEVEL_SILHOUETTES = 3 };

/* Squared distance from p to triangle abc, written here apart from
 * sc_hausdorff: the plane's distance where p projects inside, else the
 * nearest of the three edges. */
static double segment_distance2(const double *p, const double *a, const double *b) {
    double d[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, w[3] = {p[0] - a[0], p[1] - a[1], p[2] - a[2]};
    double len2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
    double t = len2 > 0 ? (w[0] * d[0] + w[1] * d[1] + w[2] * d[2]) / len2 : 0;
    t = t < 0 ? 0 : t > 1 ? 1 : t;
    double e[3] = {w[0] - t * d[0], w[1] - t * d[1], w[2] - t * d[2]};
    return e[0] * e[0] + e[1] * e[1] + e[2] * e[2];
}

static double triangle_distance2(const double *p, const double *a, const double *b, const double *c) {
    double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, v[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
    double w[3] = {p[0] - a[0], p[1] - a[1], p[2] - a[2]};
    double uu = u[0] * u[0] + u[1] * u[1] + u[2] * u[2], uv = u[0] * v[0] + u[1] * v[1] + u[2] * v[2];
    double vv = v[0] * v[0] + v[1] * v[1] + v[2] * v[2], wu = w[0] * u[0] + w[1] * u[1] + w[2] * u[2];
    double wv = w[0] * v[0] + w[1] * v[1] + w[2] * v[2], det = uu * vv - uv * uv;
    if (det > 0) {
        double s = (vv * wu - uv * wv) / det, t = (uu * wv - uv * wu) / det;
        if (s >= 0 && t >= 0 && s + t <= 1) {
            double e[3] = {w[0] - s * u[0] - t * v[0], w[1] - s * u[1] - t * v[1], w[2] - s * u[2] - t * v[2]};
            return e[0] * e[0] + e[1] * e[1] + e[2] * e[2];
        }
    }
    return fmin(segment_distance2(p, a, b), fmin(segment_distance2(p, b, c), segment_distance2(p, c, a)));
}

/* The largest distance from points of `from` (each face's barycentric grid
 * of step 1/8) to the surface of `to`, by brute force. */
static double brute_one_sided(const sc_mesh *from, const sc_mesh *to) {
    enum { STEPS = 8 };
    double worst = 0;
    for (int f = 0; f < from->nf; f++) {
        const double *a = from->V + 3 * from->FV[3 * f], *b = from->V + 3 * from->FV[3 * f + 1],
                     *c = from->V + 3 * from->FV[3 * f + 2];
        for (int i = 0; i <= STEPS; i++)
            for (int j = 0; i + j <= STEPS; j++) {
                double s = (double)i / STEPS, t = (double)j / STEPS, p[3];
                for (int k = 0; k < 3; k++) p[k] = a[k] + s * (b[k] - a[k]) + t * (c[k] - a[k]);
                double best = INFINITY;
                for (int g = 0; g < to->nf && best > worst; g++)
                    best = fmin(best, triangle_distance2(p, to->V + 3 * to->FV[3 * g], to->V + 3 * to->FV[3 * g + 1],
                                                         to->V + 3 * to->FV[3 * g + 2]));
                worst = fmax(worst, best);
            }
    }
    return sqrt(worst);
}

/* Symmetric sampled Hausdorff distance over the diagonal of a's bounding box. */
static double brute_hausdorff(const sc_mesh *a, const sc_mesh *b) {
    return fmax(brute_one_sided(a, b), brute_one_sided(b, a)) / sc_bbox_diagonal(a->V, a->nv, NULL, 0);
}

/* All the validity checks of one level against the input. */
static void check_level(const sc_mesh *in, const sc_mesh *lvl, int kept, const char *what) {
    int euler_in, euler_out;
    SC_CHECK_MSG(check_manifold(in, &euler_in) == 0, "%s: input not manifold", what);
    int nonmanifold = check_manifold(lvl, &euler_out);
    SC_CHECK_MSG(nonmanifold == 0, "%s: %d non-manifold or mis-oriented edges", what, nonmanifold);
    SC_CHECK_MSG(euler_in == euler_out, "%s: Euler characteristic %d, input %d", what, euler_out, euler_in);
    int degenerate = check_degenerate(lvl);
    SC_CHECK_MSG(degenerate == 0, "%s: %d degenerate faces", what, degenerate);
    if (kept & LEVEL_CHARTS) {
        int flipped = check_uv_orientation(in, lvl);
        SC_CHECK_MSG(flipped == 0, "%s: %d uv faces flipped or outside the input charts", what, flipped);
    } else {
        int flipped = check_uv_signs(in, lvl);
        SC_CHECK_MSG(flipped == 0, "%s: %d uv faces flipped (-1: the input's uv faces differ in orientation)", what,
                     flipped);
    }
    if ((kept & LEVEL_SILHOUETTES) == LEVEL_SILHOUETTES) {
        int off = check_silhouettes(in, lvl, 1e-9);
        SC_CHECK_MSG(off == 0, "%s: %d uv silhouette violations", what, off);
    }
}

/* ---------------------------------------------------------------- seam energy sampler */

/* Bilinear sample of channel c at uv with the docs/design.md convention (texel
 * (i, j) centred at ((i + 1/2)/W, (j + 1/2)/H), row 0 at v = 0) and repeat
 * wrapping. Written here, apart from sc_seam. */
static double texel(const sc_image_data *im, long i, long j, int c) {
    long w = im->width, h = im->height;
    i = ((i % w) + w) % w;
    j = ((j % h) + h) % h;
    return sc_image_texel(im, (int32_t)i, (int32_t)j, c);
}

static double bilinear(const sc_image_data *im, double u, double v, int c) {
    double x = u * im->width - 0.5, y = v * im->height - 0.5;
    double fx = floor(x), fy = floor(y), s = x - fx, t = y - fy;
    long i = (long)fx, j = (long)fy;
    return (1 - s) * (1 - t) * texel(im, i, j, c) + s * (1 - t) * texel(im, i + 1, j, c) +
           (1 - s) * t * texel(im, i, j + 1, c) + s * t * texel(im, i + 1, j + 1, c);
}

/* Seam energy of a texture on a mesh: for every seam edge (two faces whose
 * uv index pairs differ), the mean squared difference of the two sides'
 * samples at matching points along the edge, weighted by 3D length and
 * divided by the total seam length (Liu et al. eq. 9, by dense sampling).
 * The edge is sampled at least every 1/8 texel. */
static double sampled_seam_energy(const sc_mesh *m, const sc_image_data *im) {
    int n = m->nf * 3;
    edge3 *e = malloc(sizeof *e * (size_t)n);
    for (int f = 0; f < m->nf; f++)
        for (int k = 0; k < 3; k++) {
            int32_t x = m->FV[3 * f + k], y = m->FV[3 * f + (k + 1) % 3];
            e[3 * f + k] = (edge3){x < y ? x : y, x < y ? y : x, f, k};
        }
    qsort(e, (size_t)n, sizeof *e, cmp_edge3);
    double total = 0, length = 0;
    for (int i = 0; i + 1 < n; i++) {
        if (e[i].lo != e[i + 1].lo || e[i].hi != e[i + 1].hi) continue;
        int32_t lo = e[i].lo, hi = e[i].hi;
        const double *uv[2][2];   /* side, endpoint (lo, hi) */
        int32_t idx[2][2] = {{-1, -1}, {-1, -1}};
        for (int sd = 0; sd < 2; sd++) {
            int f = e[i + sd].face;
            for (int k = 0; k < 3; k++) {
                if (m->FV[3 * f + k] == lo) idx[sd][0] = m->FU[3 * f + k];
                if (m->FV[3 * f + k] == hi) idx[sd][1] = m->FU[3 * f + k];
            }
            uv[sd][0] = m->U + 2 * idx[sd][0];
            uv[sd][1] = m->U + 2 * idx[sd][1];
        }
        if (idx[0][0] == idx[1][0] && idx[0][1] == idx[1][1]) continue;
        const double *p = m->V + 3 * lo, *q = m->V + 3 * hi;
        double l = sqrt((p[0] - q[0]) * (p[0] - q[0]) + (p[1] - q[1]) * (p[1] - q[1]) + (p[2] - q[2]) * (p[2] - q[2]));
        double texels = 0;
        for (int sd = 0; sd < 2; sd++)
            texels = fmax(texels, fmax(fabs(uv[sd][1][0] - uv[sd][0][0]) * im->width,
                                       fabs(uv[sd][1][1] - uv[sd][0][1]) * im->height));
        int samples = 8 + (int)(8 * texels);
        double sum = 0;
        for (int k = 0; k < samples; k++) {
            double g = (k + 0.5) / samples;
            for (int c = 0; c < im->channels; c++) {
                double a = bilinear(im, uv[0][0][0] + g * (uv[0][1][0] - uv[0][0][0]),
                                    uv[0][0][1] + g * (uv[0][1][1] - uv[0][0][1]), c);
                double b = bilinear(im, uv[1][0][0] + g * (uv[1][1][0] - uv[1][0][0]),
                                    uv[1][0][1] + g * (uv[1][1][1] - uv[1][0][1]), c);
                sum += (a - b) * (a - b);
            }
        }
        total += l * sum / samples;
        length += l;
    }
    free(e);
    return length > 0 ? total / length : 0;
}

/* ---------------------------------------------------------------- synthetic meshes */

static sc_value *mesh_value(sc_mesh *m) {
    for (int i = 0; i < m->nmat; i++)
        if (!m->materials[i]) {
            char name[16];
            snprintf(name, sizeof name, "m%d", i);
            m->materials[i] = sc_strdup(name);
        }
    return sc_value_new_mesh(m);
}

/* An open, gently bumpy rectangle of (2n) x n cells split into two uv charts
 * along the middle column: a seam of n edges. The left chart is laid out
 * uniformly; on the right side the seam's uv steps are `right_steps`
 * (n values, summing to anything): collinear with the left side, with equal
 * length ratios only when the steps are all equal. uv are dyadic, so every
 * straight line is exactly straight. */
static sc_value *two_chart_strip(int n, const double *right_steps) {
    int cols = 2 * n, rows = n;
    int nv = (cols + 1) * (rows + 1), nu = 2 * (n + 1) * (rows + 1), nf = 2 * cols * rows;
    sc_mesh *m = sc_mesh_alloc(nv, nu, 0, nf, 1);
    for (int j = 0; j <= rows; j++)
        for (int i = 0; i <= cols; i++) {
            double x = (double)i / n, y = (double)j / n;
            double *p = m->V + 3 * (j * (cols + 1) + i);
            p[0] = x, p[1] = y, p[2] = 0.05 * sin(3.0 * x) * cos(2.5 * y);
        }
    double total = 0, *acc = malloc(sizeof(double) * (size_t)(rows + 1));
    acc[0] = 0;
    for (int j = 0; j < rows; j++) acc[j + 1] = acc[j] + right_steps[j], total += right_steps[j];
    for (int side = 0; side < 2; side++)
        for (int j = 0; j <= rows; j++)
            for (int i = 0; i <= n; i++) {
                double *u = m->U + 2 * (side * (n + 1) * (rows + 1) + j * (n + 1) + i);
                if (side == 0) {
                    u[0] = 0.0625 + 0.375 * i / n;
                    u[1] = 0.0625 + 0.75 * j / rows;
                } else {
                    /* the right chart: its own rows follow the seam's steps */
                    u[0] = 0.5625 + 0.375 * i / n;
                    u[1] = 0.0625 + 0.75 * acc[j] / total;
                }
            }
    free(acc);
    int f = 0;
    for (int j = 0; j < rows; j++)
        for (int i = 0; i < cols; i++) {
            int side = i < n ? 0 : 1, li = i - side * n;
            int v00 = j * (cols + 1) + i, v10 = v00 + 1, v01 = v00 + cols + 1, v11 = v01 + 1;
            int base = side * (n + 1) * (rows + 1);
            int u00 = base + j * (n + 1) + li, u10 = u00 + 1, u01 = u00 + n + 1, u11 = u01 + 1;
            int tv[2][3] = {{v00, v10, v11}, {v00, v11, v01}}, tu[2][3] = {{u00, u10, u11}, {u00, u11, u01}};
            for (int t = 0; t < 2; t++, f++)
                for (int k = 0; k < 3; k++) m->FV[3 * f + k] = tv[t][k], m->FU[3 * f + k] = tu[t][k];
        }
    return mesh_value(m);
}

/* A thin lens: a disk of radius 1 and thickness 2 t, rounded at its rim,
 * as two caps of `rings` rings of `segments` vertices around a centre,
 * sharing the rim. Each cap is a uv chart (its planar projection), so the
 * rim is a seam: a thin feature whose faces' planes all but contain the
 * disk, like blub's fins. */
static sc_value *thin_lens(int rings, int segments, double t) {
    int per_cap = 1 + (rings - 1) * segments;   /* centre and the rings inside the rim */
    int nv = 2 * per_cap + segments, nu = 2 * (per_cap + segments);
    int nf = 2 * (segments + 2 * segments * (rings - 1));
    sc_mesh *m = sc_mesh_alloc(nv, nu, 0, nf, 1);
    /* the vertex and the uv entry of cap c (0 top, 1 bottom), ring i (0 the
     * centre .. rings the rim, one vertex shared by both caps but a uv entry
     * in each), segment j */
#define LENS_V(c, i, j) \
    ((i) == rings ? 2 * per_cap + (j) % segments : (c) * per_cap + ((i) ? 1 + ((i) - 1) * segments + (j) % segments : 0))
#define LENS_U(c, i, j) ((c) * (per_cap + segments) + ((i) ? 1 + ((i) - 1) * segments + (j) % segments : 0))
    for (int c = 0; c < 2; c++)
        for (int i = 0; i <= rings; i++)
            for (int j = 0; j < (i ? segments : 1); j++) {
                double r = (double)i / rings, a = 2 * M_PI * j / segments;
                double x = r * cos(a), z = r * sin(a), y = (c ? -t : t) * sqrt(fmax(0, 1 - r * r));
                double *p = m->V + 3 * LENS_V(c, i, j), *u = m->U + 2 * LENS_U(c, i, j);
                p[0] = x, p[1] = y, p[2] = z;
                u[0] = (c ? 0.75 : 0.25) + 0.2 * x;
                u[1] = 0.5 + (c ? 0.2 : -0.2) * z;   /* mirrored so that both charts keep one orientation */
            }
    /* each cell between rings i and i + 1 is a quad (ring, segment) split in
     * two; around the centre only the first triangle exists */
    static const int tris[2][3] = {{0, 1, 2}, {0, 2, 3}};
    int f = 0;
    for (int c = 0; c < 2; c++)
        for (int i = 0; i < rings; i++)
            for (int j = 0; j < segments; j++) {
                const int quad[4][2] = {{i, j}, {i + 1, j}, {i + 1, j + 1}, {i, j + 1}};
                for (int k = 0; k < (i ? 2 : 1); k++, f++)
                    for (int e = 0; e < 3; e++) {
                        const int *corner = quad[tris[k][e]];
                        int slot = c ? 2 - e : e;   /* the bottom cap faces down */
                        m->FV[3 * f + slot] = LENS_V(c, corner[0], corner[1]);
                        m->FU[3 * f + slot] = LENS_U(c, corner[0], corner[1]);
                    }
            }
#undef LENS_V
#undef LENS_U
    return mesh_value(m);
}

/* The procedural asset's mesh, with material = chart % 2 (two materials). */
static sc_value *two_material_copy(const sc_mesh *in) {
    sc_mesh *m = sc_mesh_alloc(in->nv, in->nu, 0, in->nf, 2);
    memcpy(m->V, in->V, sizeof(double) * 3 * (size_t)in->nv);
    memcpy(m->U, in->U, sizeof(double) * 2 * (size_t)in->nu);
    memcpy(m->FV, in->FV, sizeof(int32_t) * 3 * (size_t)in->nf);
    memcpy(m->FU, in->FU, sizeof(int32_t) * 3 * (size_t)in->nf);
    for (int f = 0; f < in->nf; f++) m->FM[f] = (f / (in->nf / 6)) % 2;   /* 6 charts in face order */
    m->materials[0] = sc_strdup("paint");
    m->materials[1] = sc_strdup("metal");
    return mesh_value(m);
}

static double metric_of(const node_run *r, const char *name) { return sc_ctx_metric_value(r->ctx, name); }

/* The stretch of uv -> surface on face f of m: the largest singular value
 * of its Jacobian, HUGE_VAL on a face flat in uv. */
static double face_stretch(const sc_mesh *m, int f) {
    const double *a = m->U + 2 * m->FU[3 * f], *b = m->U + 2 * m->FU[3 * f + 1], *c = m->U + 2 * m->FU[3 * f + 2];
    double du1 = b[0] - a[0], dv1 = b[1] - a[1], du2 = c[0] - a[0], dv2 = c[1] - a[1], det = du1 * dv2 - du2 * dv1;
    if (det == 0) return HUGE_VAL;
    double g[2][2] = {{0, 0}, {0, 0}};   /* J^T J */
    for (int k = 0; k < 3; k++) {
        double e1 = m->V[3 * m->FV[3 * f + 1] + k] - m->V[3 * m->FV[3 * f] + k];
        double e2 = m->V[3 * m->FV[3 * f + 2] + k] - m->V[3 * m->FV[3 * f] + k];
        double ju = (e1 * dv2 - e2 * dv1) / det, jv = (e2 * du1 - e1 * du2) / det;
        g[0][0] += ju * ju, g[0][1] += ju * jv, g[1][1] += jv * jv;
    }
    double tr = g[0][0] + g[1][1], dt = g[0][0] * g[1][1] - g[0][1] * g[0][1];
    return sqrt(0.5 * tr + sqrt(fmax(0, 0.25 * tr * tr - dt)));
}

static double largest_stretch(const sc_mesh *m) {
    double worst = 0;
    for (int f = 0; f < m->nf; f++) worst = fmax(worst, face_stretch(m, f));
    return worst;
}

/* A face as 15 numbers: its corners' uvs (kept exactly by the decimation),
 * then their positions (which come back through a centring, so only within
 * rounding). */
static void face_key(const sc_mesh *m, int f, double key[15]) {
    for (int k = 0; k < 3; k++) {
        memcpy(key + 2 * k, m->U + 2 * m->FU[3 * f + k], sizeof(double) * 2);
        memcpy(key + 6 + 3 * k, m->V + 3 * m->FV[3 * f + k], sizeof(double) * 3);
    }
}

static int compare_key(const void *p, const void *q) {   /* the uvs only */
    const double *a = p, *b = q;
    for (int i = 0; i < 6; i++)
        if (a[i] != b[i]) return a[i] < b[i] ? -1 : 1;
    return 0;
}

/* Whether face f of level is one of the input's (sorted keys): the same uvs,
 * positions within 1e-9 of the diagonal. */
static bool input_face(const double (*keys)[15], int n, const sc_mesh *level, int f, double diag) {
    double k[15];
    face_key(level, f, k);
    const double (*hit)[15] = bsearch(k, keys, (size_t)n, sizeof(*keys), compare_key);
    if (!hit) return false;
    while (hit > keys && !compare_key(hit - 1, k)) hit--;
    for (; hit < keys + n && !compare_key(hit, k); hit++) {
        bool same = true;
        for (int i = 6; i < 15 && same; i++) same = fabs((*hit)[i] - k[i]) <= 1e-9 * diag;
        if (same) return true;
    }
    return false;
}

static double face_normal_angle(const sc_mesh *m, int f, int g) {
    double n[2][3];
    for (int i = 0; i < 2; i++) {
        const int32_t *c = m->FV + 3 * (i ? g : f);
        double e1[3], e2[3];
        for (int k = 0; k < 3; k++) e1[k] = m->V[3 * c[1] + k] - m->V[3 * c[0] + k], e2[k] = m->V[3 * c[2] + k] - m->V[3 * c[0] + k];
        n[i][0] = e1[1] * e2[2] - e1[2] * e2[1], n[i][1] = e1[2] * e2[0] - e1[0] * e2[2], n[i][2] = e1[0] * e2[1] - e1[1] * e2[0];
    }
    double x[3] = {n[0][1] * n[1][2] - n[0][2] * n[1][1], n[0][2] * n[1][0] - n[0][0] * n[1][2], n[0][0] * n[1][1] - n[0][1] * n[1][0]};
    return atan2(sqrt(x[0] * x[0] + x[1] * x[1] + x[2] * x[2]), n[0][0] * n[1][0] + n[0][1] * n[1][1] + n[0][2] * n[1][2]);
}

/* The sharpest crease the level made inside its charts: over its edges
 * whose two faces share the edge's uv indices, unless both faces are the
 * input's own (same positions and uvs), the dihedral angle (radians) times
 * the longer texel span of the two faces (stretch / map_size), over diag. */
static double sharpest_new_crease(const sc_mesh *in, const sc_mesh *level, double map_size, double diag) {
    double (*keys)[15] = malloc(sizeof(*keys) * (size_t)in->nf);
    int32_t (*e)[3] = malloc(sizeof(*e) * 3 * (size_t)level->nf);
    double worst = keys && e ? 0 : INFINITY;
    for (int f = 0; keys && f < in->nf; f++) face_key(in, f, keys[f]);
    if (keys) qsort(keys, (size_t)in->nf, sizeof(*keys), compare_key);
    for (int f = 0; e && f < level->nf; f++)
        for (int k = 0; k < 3; k++) {
            int32_t x = level->FU[3 * f + k], y = level->FU[3 * f + (k + 1) % 3];
            e[3 * f + k][0] = x < y ? x : y, e[3 * f + k][1] = x < y ? y : x, e[3 * f + k][2] = f;
        }
    const int n = 3 * level->nf;
    if (e) qsort(e, (size_t)n, sizeof(*e), compare_uv_edge);
    for (int i = 0; keys && e && i + 1 < n; i++) {
        if (e[i][0] != e[i + 1][0] || e[i][1] != e[i + 1][1] || (i + 2 < n && e[i + 2][0] == e[i][0] && e[i + 2][1] == e[i][1]))
            continue;
        int f = e[i][2], g = e[i + 1][2];
        if (input_face((const double(*)[15])keys, in->nf, level, f, diag) &&
            input_face((const double(*)[15])keys, in->nf, level, g, diag))
            continue;
        worst = fmax(worst, face_normal_angle(level, f, g) * fmax(face_stretch(level, f), face_stretch(level, g)) / map_size / diag);
    }
    free(keys), free(e);
    return worst;
}

/* The largest distance, over the input's vertices on uv silhouettes (uv
 * edges with one face) at each of their uvs there, to the level's point at
 * the same uv (the level face holding it best, by brute force), over the
 * input's diagonal. */
static double silhouette_same_uv_distance(const sc_mesh *in, const sc_mesh *level, double diag) {
    seg2 *segs = NULL;
    int nseg = boundary_segments(in, &segs);
    double worst = 0;
    for (int i = 0; i < 3 * in->nf; i++) {
        const double *uv = in->U + 2 * in->FU[i], *p = in->V + 3 * in->FV[i];
        if (!near_any(uv, segs, nseg, 0)) continue;
        double best = -HUGE_VAL, q[3] = {0, 0, 0};
        for (int f = 0; f < level->nf; f++) {
            const double *a = level->U + 2 * level->FU[3 * f], *b = level->U + 2 * level->FU[3 * f + 1],
                         *c = level->U + 2 * level->FU[3 * f + 2];
            double d = (b[1] - c[1]) * (a[0] - c[0]) + (c[0] - b[0]) * (a[1] - c[1]);
            if (d == 0) continue;
            double l0 = ((b[1] - c[1]) * (uv[0] - c[0]) + (c[0] - b[0]) * (uv[1] - c[1])) / d;
            double l1 = ((c[1] - a[1]) * (uv[0] - c[0]) + (a[0] - c[0]) * (uv[1] - c[1])) / d, l2 = 1 - l0 - l1;
            if (!(fmin(l0, fmin(l1, l2)) > best)) continue;
            best = fmin(l0, fmin(l1, l2));
            for (int k = 0; k < 3; k++)
                q[k] = l0 * level->V[3 * level->FV[3 * f] + k] + l1 * level->V[3 * level->FV[3 * f + 1] + k] +
                       l2 * level->V[3 * level->FV[3 * f + 2] + k];
        }
        worst = fmax(worst, sqrt((q[0] - p[0]) * (q[0] - p[0]) + (q[1] - p[1]) * (q[1] - p[1]) + (q[2] - p[2]) * (q[2] - p[2])));
    }
    free(segs);
    return worst / diag;
}

/* With map_size, no level face stretches beyond twice the larger of the map
 * texel's unit and the input's largest stretch, the level keeps the input's
 * uv silhouettes within seam_error at the same uv (a seam-free map cannot
 * restore them), and no edge inside a chart that is not the input's own
 * creases sharper than map_crease (angle x texel length). BoomBox as the
 * main job cooks it (straightened, max_error 0.02): without map_size its
 * level 0.1 breaks all three (a uv sliver 5.9x the bound, silhouettes 2.2%
 * of the diagonal off, a crease of 0.019, 4.7x its bound; before collapses
 * that push faces through others were refused, 12.6x, 3.3% and 0.35),
 * which cost its 1024^2 map 1.7e-2 of the diagonal in test_bake. */
static void map_size_bounds(sc_value *asset, const char *what, const char *max_error, int kept, bool broken_without) {
    const sc_mesh *in = asset->as.atlas->mesh->as.mesh;
    const double input_stretch = largest_stretch(in);
    const double diag = sc_bbox_diagonal(in->V, in->nv, in->FV, in->nf);
    const double unit = 2e-3 * diag * 1024;   /* map_texel's default x diagonal x map_size */
    double seam[2][2] = {{0, 0}, {0, 0}}, stretch[2][2] = {{0, 0}, {0, 0}}, crease[2][2] = {{0, 0}, {0, 0}};
    for (int on = 0; on < 2; on++) {
        const char *params[] = {"ratio", "0.5,0.1", "hausdorff_samples", "0", "max_error", max_error,
                                "map_size", on ? "1024" : "0", NULL};
        node_run r = run_node(&sc_node_decimate, params, "mesh", asset);
        SC_CHECK_MSG(r.rc == SC_OK, "%s: decimate: %s", what, r.err.message);
        for (int k = 0; k < 2 && r.rc == SC_OK; k++) {
            const sc_mesh *m = level_mesh(r.out, k);
            check_level(in, m, kept, what);
            seam[on][k] = silhouette_same_uv_distance(in, m, diag), stretch[on][k] = largest_stretch(m);
            crease[on][k] = sharpest_new_crease(in, m, 1024, diag);
            printf("     %s, map_size %s, level %d: %d faces, silhouettes at the same uv %.3g of the diagonal, largest "
                   "stretch %.3g of the bound, sharpest crease %.3g\n", what, on ? "1024" : "0", k, m->nf, seam[on][k],
                   stretch[on][k] / (2 * fmax(unit, input_stretch)), crease[on][k]);
        }
        run_free(&r);
    }
    for (int k = 0; k < 2; k++) {
        SC_CHECK_MSG(seam[1][k] <= 5e-4 * (1 + 1e-9), "%s level %d: silhouettes %g off", what, k, seam[1][k]);
        SC_CHECK_MSG(stretch[1][k] <= 2 * fmax(unit, input_stretch) * (1 + 1e-9), "%s level %d: stretch %g", what, k,
                     stretch[1][k]);
        SC_CHECK_MSG(crease[1][k] <= 4e-3 * (1 + 1e-6), "%s level %d: crease %g", what, k, crease[1][k]);
    }
    if (broken_without)   /* the bounds are not met by chance: level 0.1 without map_size breaks all three */
        SC_CHECK(seam[0][1] > 10 * 5e-4 && stretch[0][1] > 2 * fmax(unit, input_stretch) && crease[0][1] > 3 * 4e-3);
}

SC_TEST(map_size_bounds_stretch_and_silhouettes) {
    sc_value *p = procedural(24, 64, 0);
    if (p) map_size_bounds(p, "procedural", "0", LEVEL_SILHOUETTES, false);
    sc_value_release(p);
    if (!sc_test_corpus()) {
        printf("     corpus absent: skipped BoomBox\n");
        return;
    }
    /* the main job's path (straightened seams, max_error 0.02) */
    sc_value *b = sc_test_load_corpus("BoomBox/BoomBox_welded.obj", NULL, NULL);
    const char *none[] = {NULL};
    node_run e = b ? run_node(&sc_node_erase_seams, none, "atlas", b) : (node_run){0};
    node_run s = e.out ? run_node(&sc_node_straighten, none, "atlas", e.out) : (node_run){0};
    SC_CHECK_MSG(s.out, "BoomBox: erase_seams %s, straighten %s", e.err.message, s.err.message);
    if (s.out) map_size_bounds(s.out, "BoomBox", "0.02", LEVEL_SILHOUETTES, true);
    run_free(&s), run_free(&e);
    sc_value_release(b);
    sc_value *blub = sc_test_load_corpus("blub/blub.obj", NULL, NULL);
    if (blub) map_size_bounds(blub, "blub", "0", LEVEL_CHARTS, false);   /* seams within the OBJ's 6 digits */
    sc_value_release(blub);
}

static node_run decimate(sc_value *input, const char *ratio, const char *mode, const char *more_key,
                         const char *more_value) {
    const char *params[] = {"ratio", ratio, "seam_mode", mode, "hausdorff_samples", "20000",
                            more_key, more_value, NULL};
    if (!more_key) params[6] = NULL;
    node_run r = run_node(&sc_node_decimate, params, "mesh", input);
    SC_CHECK_MSG(r.rc == SC_OK, "decimate %s %s: %s", ratio, mode, r.err.message);
    return r;
}

/* ---------------------------------------------------------------- tests */

SC_TEST(procedural_aware_levels) {
    sc_value *atlas = procedural(16, 256, 0.0);
    if (!atlas) return;
    const sc_mesh *in = atlas->as.atlas->mesh->as.mesh;
    node_run r = decimate(atlas, "0.5,0.1,0.03", "aware", NULL, NULL);
    if (r.rc == SC_OK) {
        const sc_lods *l = r.out->as.lods;
        SC_CHECK_INT(l->count, 3);
        double ratios[3] = {0.5, 0.1, 0.03};
        for (int k = 0; k < l->count && k < 3; k++) {
            const sc_mesh *m = level_mesh(r.out, k);
            char what[32];
            snprintf(what, sizeof what, "level %d", k);
            int64_t target = llround(ratios[k] * in->nf);
            SC_CHECK_MSG(m->nf <= target && m->nf >= target - 1, "%s: %d faces, target %lld", what, m->nf,
                         (long long)target);
            SC_CHECK_INT(l->levels[k]->as.atlas->ntex, 0);
            SC_CHECK_INT(m->nmat, in->nmat);
            check_level(in, m, LEVEL_SILHOUETTES, what);
            char name[64];
            snprintf(name, sizeof name, "lod%d.flipped_uv_faces", k);
            SC_CHECK(metric_of(&r, name) == 0);
            snprintf(name, sizeof name, "lod%d.faces", k);
            SC_CHECK(metric_of(&r, name) == m->nf);
            snprintf(name, sizeof name, "lod%d.hausdorff", k);
            double hd = metric_of(&r, name), mine = hausdorff_fraction(in, m);
            /* the node's sampled distance is a lower bound of the true one */
            SC_CHECK_MSG(hd > 0 && hd <= mine * 1.05 && hd >= mine * 0.5, "%s: hausdorff %g vs %g", what, hd, mine);
        }
        /* the procedural seams are straight and uniformly parameterised on
         * both sides: every seam edge can be unified, and many collapse */
        SC_CHECK(metric_of(&r, "input.uncollapsible_seam_edges") == 0);
        SC_CHECK(metric_of(&r, "input.seam_edges") == 12 * 16);
        SC_CHECK(metric_of(&r, "lod2.seam_edges_collapsed") > 100);
        SC_CHECK(metric_of(&r, "lod2.seam_edges") < 12 * 16);
    }
    run_free(&r);
    sc_value_release(atlas);
}

SC_TEST(deterministic_bytes_for_any_thread_count) {
    sc_value *atlas = procedural(12, 64, 0.0);
    if (!atlas) return;
    for (int with_map = 0; with_map < 2; with_map++) {   /* map_size's bounds and weights too */
        sc_digest d[3];
        for (int t = 0; t < 3; t++) {
            sc_ctx *ctx = sc_ctx_new(&sc_node_decimate, NULL, NULL);
            sc_error err;
            sc_ctx_set_param(ctx, "ratio", "0.3,0.05", &err);
            sc_ctx_set_param(ctx, "map_size", with_map ? "256" : "0", &err);
            sc_ctx_set_input(ctx, "mesh", atlas);
            sc_ctx_set_threads(ctx, t == 2 ? 2 : 1);
            SC_CHECK(sc_ctx_run(ctx, &err) == SC_OK);
            d[t] = sc_ctx_output(ctx, 0) ? *sc_value_digest(sc_ctx_output(ctx, 0)) : (sc_digest){{0}};
            sc_ctx_free(ctx);
        }
        SC_CHECK(sc_digest_equal(&d[0], &d[1]));
        SC_CHECK(sc_digest_equal(&d[0], &d[2]));
    }
    sc_value_release(atlas);
}

SC_TEST(figure8_mismatched_ratios_do_not_collapse) {
    enum { N = 8 };
    /* collinear on both sides, but the right side's steps alternate 1, 2 */
    double mismatched[N], matched[N];
    for (int j = 0; j < N; j++) mismatched[j] = j % 2 ? 2.0 : 1.0, matched[j] = 1.0;
    for (int variant = 0; variant < 2; variant++) {
        sc_value *strip = two_chart_strip(N, variant == 0 ? mismatched : matched);
        const sc_mesh *in = strip->as.mesh;
        SC_CHECK(sc_mesh_check(in, NULL) == SC_OK);
        node_run r = decimate(strip, "0.1", "aware", NULL, NULL);
        if (r.rc == SC_OK) {
            const sc_mesh *m = level_mesh(r.out, 0);
            check_level(in, m, LEVEL_SILHOUETTES, variant == 0 ? "figure 8" : "matched strip");
            /* every uv point of the right side of the seam must survive in
             * the mismatched case: count LOD uv entries on the seam line */
            int on_seam = 0;
            for (int i = 0; i < m->nu; i++) on_seam += m->U[2 * i] == 0.5625;
            if (variant == 0) {
                SC_CHECK_MSG(on_seam == N + 1, "figure 8: %d uv points left on the right side of the seam", on_seam);
                SC_CHECK(metric_of(&r, "lod0.seam_edges_collapsed") == 0);
                SC_CHECK(metric_of(&r, "input.uncollapsible_seam_edges_length_ratio") >= N - 2);
                SC_CHECK(metric_of(&r, "lod0.seam_edges") == N);
            } else {
                SC_CHECK_MSG(on_seam < N + 1, "matched strip: the seam kept all %d points", on_seam);
                SC_CHECK(metric_of(&r, "lod0.seam_edges_collapsed") > 0);
                SC_CHECK(metric_of(&r, "input.uncollapsible_seam_edges") == 0);
            }
        }
        run_free(&r);
        sc_value_release(strip);
    }
}

SC_TEST(open_border_keeps_its_shape) {
    enum { N = 10 };
    double steps[N];
    for (int j = 0; j < N; j++) steps[j] = 1.0;
    sc_value *strip = two_chart_strip(N, steps);
    const sc_mesh *in = strip->as.mesh;
    node_run r = decimate(strip, "0.3,0.05", "aware", NULL, NULL);
    if (r.rc == SC_OK) {
        for (int k = 0; k < 2; k++) {
            const sc_mesh *m = level_mesh(r.out, k);
            check_level(in, m, LEVEL_SILHOUETTES, k ? "strip level 1" : "strip level 0");
            /* the rectangle's 3D border: every border vertex stays on the
             * plane of its side (x = 0, x = 2, y = 0 or y = 1) */
            int euler;
            check_manifold(m, &euler);
            SC_CHECK_INT(euler, 1);
        }
        SC_CHECK(metric_of(&r, "lod1.faces") <= llround(0.05 * in->nf));
    }
    run_free(&r);
    sc_value_release(strip);
}

SC_TEST(fixed_freezes_silhouettes_and_aware_is_closer) {
    sc_value *atlas = procedural(16, 64, 0.0);
    if (!atlas) return;
    const sc_mesh *in = atlas->as.atlas->mesh->as.mesh;
    const char *params_fixed[] = {"faces", "1000", "seam_mode", "fixed", "hausdorff_samples", "0", NULL};
    const char *params_aware[] = {"faces", "1000", "seam_mode", "aware", "hausdorff_samples", "0", NULL};
    node_run f = run_node(&sc_node_decimate, params_fixed, "mesh", atlas);
    node_run a = run_node(&sc_node_decimate, params_aware, "mesh", atlas);
    SC_CHECK(f.rc == SC_OK && a.rc == SC_OK);
    if (f.rc == SC_OK && a.rc == SC_OK) {
        const sc_mesh *mf = level_mesh(f.out, 0), *ma = level_mesh(a.out, 0);
        SC_CHECK_INT(mf->nf, 1000);
        SC_CHECK_INT(ma->nf, 1000);
        check_level(in, mf, LEVEL_SILHOUETTES, "fixed");
        check_level(in, ma, LEVEL_SILHOUETTES, "aware");
        /* fixed: the input's uv boundary edges are all still there */
        seg2 *si, *so;
        int ni = boundary_segments(in, &si), no = boundary_segments(mf, &so);
        SC_CHECK_INT(no, ni);
        free(si);
        free(so);
        SC_CHECK(metric_of(&f, "lod0.seam_edges_collapsed") == 0);
        double hf = hausdorff_fraction(in, mf), ha = hausdorff_fraction(in, ma);
        printf("     at 1000 faces: hausdorff aware %.4f%%, fixed %.4f%%\n", 100 * ha, 100 * hf);
        SC_CHECK_MSG(ha < hf, "aware %g is not closer than fixed %g", ha, hf);
    }
    run_free(&f);
    run_free(&a);
    sc_value_release(atlas);
}

SC_TEST(erased_texture_survives_aware_and_free_breaks_it) {
    sc_value *atlas = procedural(12, 256, 0.08);
    if (!atlas) return;
    const sc_mesh *in = atlas->as.atlas->mesh->as.mesh;
    const char *erase_params[] = {NULL};
    node_run e = run_node(&sc_node_erase_seams, erase_params, "atlas", atlas);
    SC_CHECK_MSG(e.rc == SC_OK, "erase_seams: %s", e.err.message);
    if (e.rc == SC_OK) {
        const sc_image_data *original = atlas->as.atlas->textures[0].image->as.image;
        const sc_image_data *erased = e.out->as.atlas->textures[0].image->as.image;
        double before = sampled_seam_energy(in, original), floor_in = sampled_seam_energy(in, erased);
        node_run aw = decimate(atlas, "0.3,0.05", "aware", NULL, NULL);
        node_run fr = decimate(atlas, "0.3,0.05", "free", NULL, NULL);
        if (aw.rc == SC_OK && fr.rc == SC_OK)
            for (int k = 0; k < 2; k++) {
                double ea = sampled_seam_energy(level_mesh(aw.out, k), erased);
                double ef = sampled_seam_energy(level_mesh(fr.out, k), erased);
                printf("     level %d: seam energy before erasure %.3g, erased input %.3g, aware %.3g, free %.3g\n", k,
                       before, floor_in, ea, ef);
                SC_CHECK_MSG(ea <= 1e-8 * before, "level %d: aware seam energy %g vs %g before erasure", k, ea, before);
                SC_CHECK_MSG(ef > 1e3 * (ea + 1e-30) && ef > 1e-6 * before, "level %d: free %g, aware %g", k, ef, ea);
                check_level(in, level_mesh(fr.out, k), LEVEL_FREE, "free");
            }
        run_free(&aw);
        run_free(&fr);
    }
    run_free(&e);
    sc_value_release(atlas);
}

/* Error tracking: at low face counts the quadric alone lets the rim of a
 * thin disk slide inwards (its faces' planes all but contain the disk) and
 * cuts it; with the tracked error the rim stays. Free mode, so that the
 * rim (a round seam in uv) may collapse at all. Hausdorff by brute force. */
SC_TEST(tracked_error_keeps_a_thin_rim) {
    sc_value *lens = thin_lens(12, 48, 0.03);
    if (!lens) return;
    const sc_mesh *in = lens->as.mesh;
    int euler = 0;
    SC_CHECK_MSG(check_manifold(in, &euler) == 0 && euler == 2, "lens: not a closed manifold (Euler %d)", euler);
    SC_CHECK_INT(check_uv_signs(in, in), 0);
    const char *targets[] = {"100", "60"};
    for (int k = 0; k < 2; k++) {
        double hd[2] = {INFINITY, INFINITY};
        for (int w = 0; w < 2; w++) {
            const char *params[] = {"faces", targets[k], "seam_mode", "free", "hausdorff_samples", "0",
                                    "error_weight", w ? "30" : "0", NULL};
            node_run r = run_node(&sc_node_decimate, params, "mesh", lens);
            SC_CHECK_MSG(r.rc == SC_OK, "decimate: %s", r.err.message);
            if (r.rc == SC_OK) {
                const sc_mesh *m = level_mesh(r.out, 0);
                char what[48];
                snprintf(what, sizeof what, "lens at %s faces, error_weight %s", targets[k], w ? "30" : "0");
                SC_CHECK_MSG(m->nf == atoi(targets[k]), "%s: %d faces", what, m->nf);
                check_level(in, m, LEVEL_FREE, what);
                hd[w] = brute_hausdorff(in, m);
                SC_CHECK_MSG((metric_of(&r, "tracked_evaluations") > 0) == (w == 1), "%s: %g tracked evaluations",
                             what, metric_of(&r, "tracked_evaluations"));
            }
            run_free(&r);
        }
        printf("     lens at %s faces: hausdorff quadric alone %.3f%%, tracked %.3f%%\n", targets[k], 100 * hd[0],
               100 * hd[1]);
        SC_CHECK_MSG(hd[1] < 0.5 * hd[0], "at %s faces: tracked %g is not under half of %g", targets[k], hd[1], hd[0]);
    }
    sc_value_release(lens);
}

/* Two meshes as one (b's indices after a's). */
static sc_value *two_parts(const sc_mesh *a, const sc_mesh *b) {
    sc_mesh *m = sc_mesh_alloc(a->nv + b->nv, a->nu + b->nu, 0, a->nf + b->nf, 1);
    memcpy(m->V, a->V, sizeof(double) * 3 * a->nv), memcpy(m->V + 3 * a->nv, b->V, sizeof(double) * 3 * b->nv);
    memcpy(m->U, a->U, sizeof(double) * 2 * a->nu), memcpy(m->U + 2 * a->nu, b->U, sizeof(double) * 2 * b->nu);
    for (int f = 0; f < a->nf + b->nf; f++)
        for (int k = 0; k < 3; k++) {
            bool in_a = f < a->nf;
            int g = in_a ? f : f - a->nf;
            m->FV[3 * f + k] = (in_a ? a : b)->FV[3 * g + k] + (in_a ? 0 : a->nv);
            m->FU[3 * f + k] = (in_a ? a : b)->FU[3 * g + k] + (in_a ? 0 : a->nu);
        }
    return mesh_value(m);
}

/* Whether segment p q passes through the inside of triangle a b c
 * (Moller-Trumbore, ends and borders excluded by a margin). */
static bool segment_pierces(const double *p, const double *q, const double *a, const double *b, const double *c) {
    double d[3], e1[3], e2[3], h[3], s[3], qv[3];
    for (int k = 0; k < 3; k++) d[k] = q[k] - p[k], e1[k] = b[k] - a[k], e2[k] = c[k] - a[k], s[k] = p[k] - a[k];
    h[0] = d[1] * e2[2] - d[2] * e2[1], h[1] = d[2] * e2[0] - d[0] * e2[2], h[2] = d[0] * e2[1] - d[1] * e2[0];
    double det = e1[0] * h[0] + e1[1] * h[1] + e1[2] * h[2];
    if (fabs(det) < 1e-18) return false;
    double u = (s[0] * h[0] + s[1] * h[1] + s[2] * h[2]) / det;
    qv[0] = s[1] * e1[2] - s[2] * e1[1], qv[1] = s[2] * e1[0] - s[0] * e1[2], qv[2] = s[0] * e1[1] - s[1] * e1[0];
    double v = (d[0] * qv[0] + d[1] * qv[1] + d[2] * qv[2]) / det;
    double t = (e2[0] * qv[0] + e2[1] * qv[1] + e2[2] * qv[2]) / det;
    const double m = 1e-9;
    return u > m && v > m && u + v < 1 - m && t > m && t < 1 - m;
}

/* Pairs of faces with no vertex in common where an edge of one passes
 * through the other, by brute force. */
static int crossing_pairs(const sc_mesh *m) {
    int count = 0;
    for (int f = 0; f < m->nf; f++)
        for (int g = f + 1; g < m->nf; g++) {
            const int32_t *a = m->FV + 3 * f, *b = m->FV + 3 * g;
            bool shared = false;
            for (int i = 0; i < 9; i++) shared |= a[i / 3] == b[i % 3];
            if (shared) continue;
            bool cross = false;
            for (int t = 0; t < 2 && !cross; t++) {
                const int32_t *x = t ? b : a, *y = t ? a : b;
                for (int e = 0; e < 3 && !cross; e++)
                    cross = segment_pierces(m->V + 3 * x[e], m->V + 3 * x[(e + 1) % 3], m->V + 3 * y[0],
                                            m->V + 3 * y[1], m->V + 3 * y[2]);
            }
            count += cross;
        }
    return count;
}

/* Decimate `both` (no crossing pair, checked) to `faces` in seam_mode free,
 * crossings allowed and then refused: the level allowed to cross must show
 * crossing pairs (counted by brute force), the refused one none. */
static void crossings_refused(const sc_value *both, const char *faces, const char *what) {
    SC_CHECK_INT(crossing_pairs(both->as.mesh), 0);
    int crossings[2] = {-1, -1};
    for (int refuse = 0; refuse < 2; refuse++) {
        const char *params[] = {"faces", faces, "seam_mode", "free", "hausdorff_samples", "0", "max_error", "0",
                                "refuse_crossings", refuse ? "true" : "false", NULL};
        node_run r = run_node(&sc_node_decimate, params, "mesh", (sc_value *)both);
        SC_CHECK_MSG(r.rc == SC_OK, "decimate: %s", r.err.message);
        if (r.rc == SC_OK) {
            const sc_mesh *lvl = level_mesh(r.out, 0);
            crossings[refuse] = crossing_pairs(lvl);
            printf("     %s at %d faces, crossings %s: %d crossing pairs\n", what, lvl->nf,
                   refuse ? "refused" : "allowed", crossings[refuse]);
        }
        run_free(&r);
    }
    SC_CHECK_MSG(crossings[0] > 0, "%s did not cross without the check (%d): the test shows nothing", what,
                 crossings[0]);
    SC_CHECK_INT(crossings[1], 0);
}

/* A thin lens inside another, 0.01 apart at the middle: decimated far, the
 * outer caps flatten through the inner ones unless crossings are refused;
 * refused, the level has none (counted by brute force), as the input. */
SC_TEST(refused_crossings_keep_nested_parts_apart) {
    sc_value *outer = thin_lens(10, 40, 0.06), *inner = thin_lens(10, 40, 0.05);
    if (!outer || !inner) return;
    sc_mesh *in_scaled = inner->as.mesh;   /* inner lens: 0.97 of the radius */
    for (int v = 0; v < in_scaled->nv; v++) in_scaled->V[3 * v] *= 0.97, in_scaled->V[3 * v + 2] *= 0.97;
    sc_value *both = two_parts(outer->as.mesh, inner->as.mesh);
    crossings_refused(both, "120", "nested lenses");
    sc_value_release(both), sc_value_release(outer), sc_value_release(inner);
}

/* A lens around a flat square of two faces, each far wider than the grid's
 * finest cells (which follow the mean edge): the crossing check finds such
 * faces on a coarser level of the grid. Decimated far, the top cap flattens
 * through the square unless crossings are refused. */
SC_TEST(refused_crossings_see_faces_wider_than_a_cell) {
    sc_value *lens = thin_lens(10, 40, 0.06);
    if (!lens) return;
    sc_mesh *square = sc_mesh_alloc(4, 4, 0, 2, 1);
    static const double corner[4][2] = {{-0.6, -0.6}, {0.6, -0.6}, {0.6, 0.6}, {-0.6, 0.6}};
    for (int i = 0; i < 4; i++) {   /* at height 0.03, inside the lens (its caps are 0.032 high there) */
        square->V[3 * i] = corner[i][0], square->V[3 * i + 1] = 0.03, square->V[3 * i + 2] = corner[i][1];
        square->U[2 * i] = 0.05 + 0.04 * (corner[i][0] + 0.6), square->U[2 * i + 1] = 0.9 + 0.04 * (corner[i][1] + 0.6);
    }
    static const int32_t faces[2][3] = {{0, 1, 2}, {0, 2, 3}};
    for (int f = 0; f < 2; f++)
        for (int k = 0; k < 3; k++) square->FV[3 * f + k] = square->FU[3 * f + k] = faces[f][k];
    sc_value *both = two_parts(lens->as.mesh, square);
    sc_mesh_free(square);
    crossings_refused(both, "24", "lens around a square");
    sc_value_release(both), sc_value_release(lens);
}

/* The first nf faces of m, with only the vertices and uv they use. */
static sc_value *first_faces(const sc_mesh *m, int nf) {
    int *vmap = malloc(sizeof(int) * (size_t)m->nv), *umap = malloc(sizeof(int) * (size_t)m->nu), nv = 0, nu = 0;
    for (int i = 0; i < m->nv; i++) vmap[i] = -1;
    for (int i = 0; i < m->nu; i++) umap[i] = -1;
    for (int c = 0; c < 3 * nf; c++) {
        if (vmap[m->FV[c]] < 0) vmap[m->FV[c]] = nv++;
        if (umap[m->FU[c]] < 0) umap[m->FU[c]] = nu++;
    }
    sc_mesh *o = sc_mesh_alloc(nv, nu, 0, nf, 1);
    for (int i = 0; i < m->nv; i++)
        if (vmap[i] >= 0) memcpy(o->V + 3 * vmap[i], m->V + 3 * i, sizeof(double) * 3);
    for (int i = 0; i < m->nu; i++)
        if (umap[i] >= 0) memcpy(o->U + 2 * umap[i], m->U + 2 * i, sizeof(double) * 2);
    for (int c = 0; c < 3 * nf; c++) o->FV[c] = vmap[m->FV[c]], o->FU[c] = umap[m->FU[c]];
    free(vmap), free(umap);
    return mesh_value(o);
}

/* The connected part of each vertex of m (union-find over its faces). */
static int *vertex_parts(const sc_mesh *m) {
    int *parent = malloc(sizeof(int) * (size_t)m->nv);
    for (int v = 0; v < m->nv; v++) parent[v] = v;
    for (int f = 0; f < m->nf; f++)
        for (int k = 0; k < 2; k++) {
            int x = m->FV[3 * f + k], y = m->FV[3 * f + k + 1];
            while (parent[x] != x) x = parent[x];
            while (parent[y] != y) y = parent[y];
            parent[x] = y;
        }
    for (int v = 0; v < m->nv; v++) {
        int r = v;
        while (parent[r] != r) r = parent[r];
        parent[v] = r;
    }
    return parent;
}

/* The farthest point of m's border edges (at t = 0, 1/4, 1/2, 3/4) from the
 * faces of the other parts, and the number of border edges, by brute force. */
static double border_gap(const sc_mesh *m, int *border_edges) {
    int *part = vertex_parts(m);
    double worst = 0;
    *border_edges = 0;
    for (int f = 0; f < m->nf; f++)
        for (int k = 0; k < 3; k++) {
            int a = m->FV[3 * f + k], b = m->FV[3 * f + (k + 1) % 3], shared = 0;
            for (int g = 0; g < m->nf; g++)
                for (int j = 0; j < 3; j++)
                    shared += g != f && m->FV[3 * g + j] == b && m->FV[3 * g + (j + 1) % 3] == a;
            if (shared) continue;
            (*border_edges)++;
            for (int t = 0; t < 4; t++) {
                double p[3];
                for (int c = 0; c < 3; c++) p[c] = m->V[3 * a + c] + 0.25 * t * (m->V[3 * b + c] - m->V[3 * a + c]);
                double best = INFINITY;
                for (int g = 0; g < m->nf; g++)
                    if (part[m->FV[3 * g]] != part[a])
                        best = fmin(best, triangle_distance2(p, m->V + 3 * m->FV[3 * g], m->V + 3 * m->FV[3 * g + 1],
                                                             m->V + 3 * m->FV[3 * g + 2]));
                worst = fmax(worst, best);
            }
        }
    free(part);
    return sqrt(worst);
}

/* An open cap (a thicker lens's top) whose rim lies on a closed lens's rim:
 * with contact_distance the cap's border stays on the lens (every point of
 * its border edges within 1e-9, as in the input) while both parts decimate
 * to near the target; without, decimation moves the border off the lens. */
SC_TEST(contact_distance_keeps_an_open_rim_on_its_body) {
    sc_value *body = thin_lens(8, 32, 0.05), *thick = thin_lens(8, 32, 0.08);
    if (!body || !thick) return;
    sc_value *cap = first_faces(thick->as.mesh, thick->as.mesh->nf / 2);
    sc_value *both = two_parts(body->as.mesh, cap->as.mesh);
    int input_border = 0;
    double input_gap = border_gap(both->as.mesh, &input_border);
    SC_CHECK_MSG(input_gap < 1e-12, "the cap's rim is %g off the lens in the input", input_gap);
    double gap[2] = {-1, -1};
    int faces[2] = {0, 0};
    for (int on = 0; on < 2; on++) {
        const char *params[] = {"faces", "100", "seam_mode", "free", "hausdorff_samples", "0", "max_error", "0",
                                "contact_distance", on ? "0.01" : "0", NULL};
        node_run r = run_node(&sc_node_decimate, params, "mesh", both);
        SC_CHECK_MSG(r.rc == SC_OK, "decimate: %s", r.err.message);
        if (r.rc == SC_OK) {
            const sc_mesh *lvl = level_mesh(r.out, 0);
            int border = 0;
            gap[on] = border_gap(lvl, &border);
            faces[on] = lvl->nf;
            printf("     cap on a lens (%d faces, %d border edges) at %d faces, contact_distance %s: %d border edges, "
                   "the farthest %.3g off the lens, %g contact vertices\n",
                   both->as.mesh->nf, input_border, lvl->nf, on ? "0.01" : "0", border, gap[on],
                   metric_of(&r, "contact_vertices"));
        }
        run_free(&r);
    }
    SC_CHECK_MSG(gap[1] >= 0 && gap[1] < 1e-9, "with contact_distance the cap's border is %g off the lens", gap[1]);
    SC_CHECK_MSG(faces[1] <= 120, "with contact_distance the level stops at %d faces for 100", faces[1]);
    SC_CHECK_MSG(gap[0] > 1e-3, "without contact_distance the border stayed (%g): the test shows nothing", gap[0]);
    sc_value_release(both), sc_value_release(cap), sc_value_release(body), sc_value_release(thick);
}

/* max_error bounds every collapse: the lens taken far below what its rim
 * allows stops short of the target, within the bound (measured here by
 * brute force), where the unbounded run goes to the target far off. */
SC_TEST(max_error_bounds_the_level) {
    sc_value *lens = thin_lens(12, 48, 0.03);
    if (!lens) return;
    const sc_mesh *in = lens->as.mesh;
    const double bound = 0.005;
    double hd[2] = {INFINITY, INFINITY};
    int faces[2] = {0, 0};
    for (int bounded = 0; bounded < 2; bounded++) {
        const char *params[] = {"faces", "24", "seam_mode", "free", "hausdorff_samples", "0",
                                "max_error", bounded ? "0.005" : "0", NULL};
        node_run r = run_node(&sc_node_decimate, params, "mesh", lens);
        SC_CHECK_MSG(r.rc == SC_OK, "decimate: %s", r.err.message);
        if (r.rc == SC_OK) {
            const sc_mesh *m = level_mesh(r.out, 0);
            check_level(in, m, LEVEL_FREE, bounded ? "bounded" : "unbounded");
            hd[bounded] = brute_hausdorff(in, m);
            faces[bounded] = m->nf;
            SC_CHECK((metric_of(&r, "lod0.blocked_max_error") > 0) == (bounded == 1));
        }
        run_free(&r);
    }
    printf("     lens to 24 faces: unbounded %d faces %.3f%%, max_error %.1f%%: %d faces %.3f%%\n", faces[0],
           100 * hd[0], 100 * bound, faces[1], 100 * hd[1]);
    SC_CHECK_INT(faces[0], 24);
    SC_CHECK(hd[0] > 2 * bound);
    SC_CHECK_MSG(faces[1] > 24, "bounded: %d faces", faces[1]);
    /* the tracked error is measured at points of each fan, the brute force
     * at 45 points a face: a little above the bound is sampling */
    SC_CHECK_MSG(hd[1] <= 1.15 * bound, "bounded: hausdorff %g over %g", hd[1], bound);
    sc_value_release(lens);
}

/* A level within max_error by decimate's own measure is within it by brute
 * force too: where the collapses' tracked error let a level pass the bound
 * (measured over the whole level), the levels are made again, bounded
 * tighter. Duck to 1% of its faces within 1% of its diagonal: its first
 * pass passes the bound (0.011 by the sampled measure) and is made again. */
SC_TEST(corpus_duck_levels_hold_max_error) {
    if (!sc_test_corpus()) {
        printf("     corpus absent: skipped\n");
        return;
    }
    sc_value *atlas = sc_test_load_corpus("Duck/Duck_welded.obj", NULL, NULL);
    if (!atlas) return;
    const sc_mesh *in = atlas->as.atlas->mesh->as.mesh;
    const char *params[] = {"ratio", "0.5,0.1,0.01", "max_error", "0.01", NULL};
    node_run r = run_node(&sc_node_decimate, params, "mesh", atlas);
    SC_CHECK_MSG(r.rc == SC_OK, "decimate: %s", r.err.message);
    for (int k = 0; r.rc == SC_OK && k < 3; k++) {
        const sc_mesh *m = level_mesh(r.out, k);
        double hd = brute_hausdorff(in, m);
        char name[32];
        snprintf(name, sizeof name, "lod%d.hausdorff", k);
        printf("     Duck level %d: %d faces, hausdorff %.3f%% (decimate's %.3f%%), tightenings %g\n", k, m->nf,
               100 * hd, 100 * metric_of(&r, name), metric_of(&r, "bound_tightenings"));
        SC_CHECK_MSG(metric_of(&r, name) <= 0.01, "level %d: decimate measures %g", k, metric_of(&r, name));
        SC_CHECK_MSG(hd <= 0.01 * 1.02, "level %d: hausdorff %g by brute force", k, hd);
    }
    SC_CHECK(metric_of(&r, "bound_tightenings") >= 1 && metric_of(&r, "bound_scale") < 1);
    run_free(&r);
    sc_value_release(atlas);
}

SC_TEST(materials_are_kept) {
    sc_value *atlas = procedural(10, 64, 0.0);
    if (!atlas) return;
    sc_value *two = two_material_copy(atlas->as.atlas->mesh->as.mesh);
    const sc_mesh *in = two->as.mesh;
    node_run r = decimate(two, "0.2", "aware", NULL, NULL);
    if (r.rc == SC_OK) {
        const sc_mesh *m = level_mesh(r.out, 0);
        SC_CHECK_INT(m->nmat, 2);
        SC_CHECK_STR(m->materials[1], "metal");
        check_level(in, m, LEVEL_SILHOUETTES, "two materials");
        /* each face keeps the material of the input face under its uv centroid */
        int wrong = 0;
        for (int f = 0; f < m->nf; f++) {
            double c[2] = {0, 0};
            for (int k = 0; k < 3; k++)
                for (int d = 0; d < 2; d++) c[d] += m->U[2 * m->FU[3 * f + k] + d] / 3.0;
            int found = -1;
            for (int g = 0; g < in->nf && found < 0; g++) {
                const double *a = in->U + 2 * in->FU[3 * g], *b = in->U + 2 * in->FU[3 * g + 1],
                             *cc = in->U + 2 * in->FU[3 * g + 2];
                double s0 = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
                double s1 = (cc[0] - b[0]) * (c[1] - b[1]) - (cc[1] - b[1]) * (c[0] - b[0]);
                double s2 = (a[0] - cc[0]) * (c[1] - cc[1]) - (a[1] - cc[1]) * (c[0] - cc[0]);
                if ((s0 >= 0 && s1 >= 0 && s2 >= 0) || (s0 <= 0 && s1 <= 0 && s2 <= 0)) found = g;
            }
            if (found < 0 || in->FM[found] != m->FM[f]) wrong++;
        }
        SC_CHECK_INT(wrong, 0);
    }
    run_free(&r);
    sc_value_release(two);
    sc_value_release(atlas);
}

/* A copy of `in` with authored normals, one per vertex, that no smooth
 * normal computation would give: the direction from a far point, which
 * turns slowly along the surface. */
static sc_value *authored_normals_copy(const sc_mesh *in) {
    sc_mesh *m = sc_mesh_alloc(in->nv, in->nu, in->nv, in->nf, in->nmat);
    memcpy(m->V, in->V, sizeof(double) * 3 * (size_t)in->nv);
    memcpy(m->U, in->U, sizeof(double) * 2 * (size_t)in->nu);
    memcpy(m->FV, in->FV, sizeof(int32_t) * 3 * (size_t)in->nf);
    memcpy(m->FU, in->FU, sizeof(int32_t) * 3 * (size_t)in->nf);
    memcpy(m->FN, in->FV, sizeof(int32_t) * 3 * (size_t)in->nf);
    memcpy(m->FM, in->FM, sizeof(int32_t) * (size_t)in->nf);
    for (int v = 0; v < in->nv; v++) {
        double d[3] = {in->V[3 * v] + 3, in->V[3 * v + 1] - 2, in->V[3 * v + 2] + 7};
        double len = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
        for (int k = 0; k < 3; k++) m->N[3 * v + k] = d[k] / len;
    }
    for (int i = 0; i < in->nmat; i++) m->materials[i] = sc_strdup(in->materials[i]);
    return mesh_value(m);
}

/* A level shades with the input's normals (a tangent-space normal map is
 * made for their frames): every normal of the level is one of the input's,
 * bit for bit, and it points as the authored field does where the level's
 * vertex is (collapses move vertices a little, and the field turns by a
 * hundredth of a radian over a tenth of a unit). */
SC_TEST(levels_keep_the_input_normals) {
    sc_value *atlas = procedural(10, 64, 0.0);
    if (!atlas) return;
    sc_value *with = authored_normals_copy(atlas->as.atlas->mesh->as.mesh);
    const sc_mesh *in = with->as.mesh;
    node_run r = decimate(with, "0.2", "aware", NULL, NULL);
    SC_CHECK_MSG(r.rc == SC_OK, "decimate: %s", r.err.message);
    if (r.rc == SC_OK) {
        const sc_mesh *m = level_mesh(r.out, 0);
        SC_CHECK(m->nn > 0 && m->FN != NULL);
        int foreign = 0;
        double worst = 0;
        for (int c = 0; m->nn > 0 && c < 3 * m->nf; c++) {
            const double *n = m->N + 3 * m->FN[c], *p = m->V + 3 * m->FV[c];
            bool known = false;
            for (int v = 0; v < in->nv && !known; v++)
                known = n[0] == in->N[3 * v] && n[1] == in->N[3 * v + 1] && n[2] == in->N[3 * v + 2];
            foreign += !known;
            double d[3] = {p[0] + 3, p[1] - 2, p[2] + 7};
            double cosine = (n[0] * d[0] + n[1] * d[1] + n[2] * d[2]) / sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
            worst = fmax(worst, acos(fmin(1, cosine)));
        }
        SC_CHECK_INT(foreign, 0);
        SC_CHECK_MSG(worst < 0.05, "a normal turned %.3g rad from the authored field", worst);
    }
    run_free(&r);
    /* without normals, the level still has some: the input's smooth ones */
    node_run bare = decimate(atlas->as.atlas->mesh, "0.2", "aware", NULL, NULL);
    if (bare.rc == SC_OK) SC_CHECK_INT(level_mesh(bare.out, 0)->nn, 3 * level_mesh(bare.out, 0)->nf);
    run_free(&bare);
    sc_value_release(with);
    sc_value_release(atlas);
}

SC_TEST(area_distortion_weights) {
    sc_value *atlas = procedural(16, 64, 0.0);
    if (!atlas) return;
    const sc_mesh *in = atlas->as.atlas->mesh->as.mesh;
    node_run q = decimate(atlas, "0.1", "aware", "weights", "qem");
    node_run w = decimate(atlas, "0.1", "aware", "weights", "area_distortion");
    if (q.rc == SC_OK && w.rc == SC_OK) {
        const sc_mesh *mq = level_mesh(q.out, 0), *mw = level_mesh(w.out, 0);
        check_level(in, mw, LEVEL_SILHOUETTES, "area distortion");
        SC_CHECK_INT(mw->nf, mq->nf);
        /* a different order of collapses: a different mesh */
        SC_CHECK(!sc_digest_equal(sc_value_digest(q.out), sc_value_digest(w.out)));
    }
    run_free(&q);
    run_free(&w);
    sc_value_release(atlas);
}

/* A bumpy square of n x n cells, one chart, whose right half is squeezed
 * `squeeze` times along u: there one texel of a map spans `squeeze` times
 * more surface than on the left. */
static sc_value *half_squeezed_square(int n, double squeeze) {
    int nv = (n + 1) * (n + 1), nf = 2 * n * n;
    sc_mesh *m = sc_mesh_alloc(nv, nv, 0, nf, 1);
    for (int j = 0; j <= n; j++)
        for (int i = 0; i <= n; i++) {
            double x = (double)i / n, y = (double)j / n, *p = m->V + 3 * (j * (n + 1) + i), *t = m->U + 2 * (j * (n + 1) + i);
            p[0] = x, p[1] = y, p[2] = 0.04 * sin(9.0 * x) * cos(7.0 * y);
            t[0] = x <= 0.5 ? x : 0.5 + (x - 0.5) / squeeze, t[1] = y;
        }
    for (int j = 0, f = 0; j < n; j++)
        for (int i = 0; i < n; i++, f += 2) {
            int a = j * (n + 1) + i, b = a + 1, c = a + n + 1, d = c + 1;
            int tri[6] = {a, b, d, a, d, c};
            for (int k = 0; k < 6; k++) m->FV[3 * f + k] = m->FU[3 * f + k] = tri[k];
        }
    return mesh_value(m);
}

/* Largest distance from samples of the input faces whose centroid has
 * x > 0.5 (the squeezed half) to the level. */
static double squeezed_half_distance(const sc_mesh *in, const sc_mesh *level) {
    sc_mesh half = *in;
    int32_t *fv = malloc(sizeof(int32_t) * 3 * (size_t)in->nf), nf = 0;
    for (int f = 0; fv && f < in->nf; f++) {
        double cx = 0;
        for (int k = 0; k < 3; k++) cx += in->V[3 * in->FV[3 * f + k]] / 3;
        if (cx > 0.5)
            for (int k = 0; k < 3; k++) fv[3 * nf + k] = in->FV[3 * f + k];
        nf += cx > 0.5;
    }
    half.FV = fv, half.nf = nf;
    double d = fv ? brute_one_sided(&half, level) : INFINITY;
    free(fv);
    return d;
}

SC_TEST(map_size_keeps_the_squeezed_detail) {
    /* 32 x 32 cells, map 64^2, map_texel 2% of the diagonal: a texel spans
     * 1.1% of the diagonal on the left (importance 1), 10x that on the
     * right (100x along x; importance ~31). The importance alone: with
     * map_crease's bound the squeezed half, whose bumps no texel there
     * follows, keeps every face (0.0000; the level stops at 1,155 faces) */
    sc_value *sq = half_squeezed_square(32, 100);
    if (!sq) return;
    const sc_mesh *in = sq->as.mesh;
    double half[3] = {0, 0, 0}, whole[3] = {0, 0, 0};
    int faces[3] = {0, 0, 0};
    const char *sizes[3] = {"0", "64", "64"}, *texels[3] = {"0.02", "0.02", "1"}, *seams[3] = {"5e-4", "5e-4", "1"};
    const sc_mesh *level[3] = {NULL, NULL, NULL};
    node_run runs[3];
    for (int k = 0; k < 3; k++) {
        const char *params[] = {"ratio", "0.15", "hausdorff_samples", "0", "map_size", sizes[k], "map_texel", texels[k],
                                "seam_error", seams[k], "map_crease", "0", NULL};
        runs[k] = run_node(&sc_node_decimate, params, "mesh", sq);
        SC_CHECK_MSG(runs[k].rc == SC_OK, "decimate: %s", runs[k].err.message);
        if (runs[k].rc != SC_OK) continue;
        const sc_mesh *m = level[k] = level_mesh(runs[k].out, 0);
        check_level(in, m, LEVEL_SILHOUETTES, sizes[k]);
        half[k] = squeezed_half_distance(in, m), whole[k] = brute_hausdorff(in, m), faces[k] = m->nf;
    }
    /* every importance 1 (map_texel 1), no stretch or seam bound that can
     * bind (map_texel 1, seam_error 1): the very same level as without map_size */
    const sc_mesh *off = level[0], *ones = level[2];
    SC_CHECK(off && ones && off->nf == ones->nf && off->nv == ones->nv &&
             !memcmp(off->V, ones->V, sizeof(double) * 3 * (size_t)off->nv) &&
             !memcmp(off->FV, ones->FV, sizeof(int32_t) * 3 * (size_t)off->nf));
    for (int k = 0; k < 3; k++) run_free(&runs[k]);
    printf("     squeezed half at 15%%: off %d faces, squeezed half %.4f, whole %.4f; map_size 64: %d faces, %.4f, %.4f\n",
           faces[0], half[0], whole[0], faces[1], half[1], whole[1]);
    SC_CHECK_INT(faces[1], faces[0]);
    /* measured: 0.0040 -> 0.0030 on the squeezed half, the whole 0.0028 ->
     * 0.0033 (the left half, where a map restores what it loses, pays).
     * Not monotonic in the squeeze: at 300 and 1000 the squeezed half got
     * worse (0.0043, 0.0084; not looked into) */
    SC_CHECK_MSG(half[1] < 0.85 * half[0], "squeezed half: %g with map_size against %g", half[1], half[0]);
    SC_CHECK_MSG(whole[1] < 1.5 * whole[0], "whole: %g with map_size against %g", whole[1], whole[0]);
    sc_value_release(sq);
}

SC_TEST(hausdorff_with_a_prebuilt_bvh_is_the_same) {
    /* the node measures every level against one BVH of its input, and
     * seeds each query with the previous sample's face: the distances must
     * be those of a fresh, unseeded measurement, checked here against a
     * brute-force closest point for the vertices (and so must the bounded
     * query error tracking uses) */
    sc_value *atlas = procedural(8, 32, 0.0);
    if (!atlas) return;
    const sc_mesh *in = atlas->as.atlas->mesh->as.mesh;
    node_run r = decimate(atlas, "0.2", "aware", NULL, NULL);
    if (r.rc == SC_OK) {
        const sc_mesh *m = level_mesh(r.out, 0);
        sc_hausdorff_mesh ma = {in->V, in->nv, in->FV, in->nf}, mb = {m->V, m->nv, m->FV, m->nf};
        sc_hausdorff_bvh *bvh = sc_hausdorff_bvh_build(&ma);
        sc_hausdorff_result fresh, pre;
        sc_error err;
        SC_CHECK(bvh != NULL);
        SC_CHECK(sc_hausdorff(&ma, &mb, 5000, 1, &fresh, &err) == SC_OK);
        SC_CHECK(sc_hausdorff_with_bvh(&ma, bvh, &mb, 5000, 2, &pre, &err) == SC_OK);
        SC_CHECK(fresh.distance == pre.distance && fresh.mean_a_to_b == pre.mean_a_to_b &&
                 fresh.mean_b_to_a == pre.mean_b_to_a);
        /* vertices of the level against the input, brute force */
        double worst = 0;
        for (int v = 0; v < m->nv; v++) {
            double best = INFINITY;
            for (int f = 0; f < in->nf; f++) {
                double q[3];
                const double *p = m->V + 3 * v;
                sc_hausdorff_closest_on_triangle(p, in->V + 3 * in->FV[3 * f], in->V + 3 * in->FV[3 * f + 1],
                                                 in->V + 3 * in->FV[3 * f + 2], q);
                best = fmin(best, (q[0] - p[0]) * (q[0] - p[0]) + (q[1] - p[1]) * (q[1] - p[1]) +
                                      (q[2] - p[2]) * (q[2] - p[2]));
            }
            double d = sc_hausdorff_bvh_closest(bvh, m->V + 3 * v, NULL, NULL);
            SC_CHECK_MSG(d == best, "vertex %d: bvh %g, brute force %g", v, d, best);
            /* the query for a running maximum (decimate's error tracking):
             * exact above its floor, at most the floor (and no less than the
             * distance) below it, from any seed */
            const double floors[4] = {0, 0.5 * best, best, 2 * best + 1e-12};
            for (int k = 0; k < 4; k++) {
                int32_t seed = (int32_t)((v * 7 + k * 131) % in->nf), face = -1;
                double above = sc_hausdorff_bvh_closest_above(bvh, m->V + 3 * v, floors[k], k ? seed : -1, &face);
                bool ok = best > floors[k] ? above == best : (above <= floors[k] && above >= best);
                SC_CHECK_MSG(ok && face >= 0, "vertex %d, floor %g: %g, brute force %g (face %d)", v, floors[k], above,
                             best, face);
            }
            worst = fmax(worst, sqrt(best));
        }
        SC_CHECK(worst <= pre.b_to_a);
        sc_hausdorff_bvh_free(bvh);
    }
    run_free(&r);
    sc_value_release(atlas);
}

SC_TEST(parameters_are_checked) {
    sc_value *atlas = procedural(4, 32, 0.0);
    if (!atlas) return;
    const char *bad_ratio[] = {"ratio", "0.5,0", NULL};
    node_run r = run_node(&sc_node_decimate, bad_ratio, "mesh", atlas);
    SC_CHECK(r.rc != SC_OK && strstr(r.err.message, "decimate:ratio"));
    run_free(&r);
    const char *increasing[] = {"ratio", "0.1,0.5", NULL};
    r = run_node(&sc_node_decimate, increasing, "mesh", atlas);
    SC_CHECK(r.rc != SC_OK && strstr(r.err.message, "must not increase"));
    run_free(&r);
    const char *faces[] = {"faces", "100,40", "ratio", "0.9", "hausdorff_samples", "0", NULL};
    r = run_node(&sc_node_decimate, faces, "mesh", atlas);
    SC_CHECK(r.rc == SC_OK);
    if (r.rc == SC_OK) {
        SC_CHECK_INT(level_mesh(r.out, 0)->nf, 100);
        SC_CHECK(level_mesh(r.out, 1)->nf <= 40);
    }
    run_free(&r);
    const char *bad_faces[] = {"faces", "10.5", NULL};
    r = run_node(&sc_node_decimate, bad_faces, "mesh", atlas);
    SC_CHECK(r.rc != SC_OK && strstr(r.err.message, "decimate:faces"));
    run_free(&r);
    sc_value_release(atlas);
}

SC_TEST(unreachable_target_reports_what_blocks) {
    /* fixed mode on a tiny asset: the frozen silhouettes bound the count */
    sc_value *atlas = procedural(6, 32, 0.0);
    if (!atlas) return;
    const char *params[] = {"faces", "20", "seam_mode", "fixed", "hausdorff_samples", "0", NULL};
    node_run r = run_node(&sc_node_decimate, params, "mesh", atlas);
    SC_CHECK(r.rc == SC_OK);
    if (r.rc == SC_OK) {
        SC_CHECK(metric_of(&r, "lod0.faces") > 20);
        SC_CHECK(metric_of(&r, "lod0.blocked_edges") > 0);
        SC_CHECK(metric_of(&r, "lod0.blocked_fixed_silhouette") > 0);
        check_level(atlas->as.atlas->mesh->as.mesh, level_mesh(r.out, 0), LEVEL_SILHOUETTES, "stalled fixed");
    }
    run_free(&r);
    sc_value_release(atlas);
}

SC_TEST(nonmanifold_input_is_locked_not_broken) {
    /* the strip plus a fin: a third face on one interior edge, with its own
     * vertex and uv */
    enum { N = 6 };
    double steps[N];
    for (int j = 0; j < N; j++) steps[j] = 1.0;
    sc_value *strip = two_chart_strip(N, steps);
    const sc_mesh *s0 = strip->as.mesh;
    sc_mesh *m = sc_mesh_alloc(s0->nv + 1, s0->nu + 1, 0, s0->nf + 1, 1);
    memcpy(m->V, s0->V, sizeof(double) * 3 * (size_t)s0->nv);
    memcpy(m->U, s0->U, sizeof(double) * 2 * (size_t)s0->nu);
    memcpy(m->FV, s0->FV, sizeof(int32_t) * 3 * (size_t)s0->nf);
    memcpy(m->FU, s0->FU, sizeof(int32_t) * 3 * (size_t)s0->nf);
    /* face 40's first edge gets a third face */
    int f = 40;
    double *apex = m->V + 3 * s0->nv;
    for (int k = 0; k < 3; k++) apex[k] = 0.5 * (s0->V[3 * s0->FV[3 * f] + k] + s0->V[3 * s0->FV[3 * f + 1] + k]);
    apex[2] += 0.3;
    m->U[2 * s0->nu] = 0.99, m->U[2 * s0->nu + 1] = 0.99;
    m->FV[3 * s0->nf] = s0->FV[3 * f], m->FV[3 * s0->nf + 1] = s0->FV[3 * f + 1], m->FV[3 * s0->nf + 2] = s0->nv;
    m->FU[3 * s0->nf] = s0->FU[3 * f], m->FU[3 * s0->nf + 1] = s0->FU[3 * f + 1], m->FU[3 * s0->nf + 2] = s0->nu;
    sc_value *fin = mesh_value(m);
    node_run r = decimate(fin, "0.2", "aware", NULL, NULL);
    if (r.rc == SC_OK) {
        SC_CHECK(metric_of(&r, "locked_vertices") >= 2);
        const sc_mesh *out = level_mesh(r.out, 0);
        SC_CHECK(out->nf < m->nf);
        SC_CHECK_INT(check_degenerate(out), 0);
        SC_CHECK_INT(check_uv_orientation(fin->as.mesh, out), 0);
    }
    run_free(&r);
    sc_value_release(fin);
    sc_value_release(strip);
}

/* ---------------------------------------------------------------- corpus */

SC_TEST(corpus_blub_one_percent) {
    if (!sc_test_corpus()) {
        printf("     corpus absent: skipped\n");
        return;
    }
    sc_value *atlas = sc_test_load_corpus("blub/blub.obj", "blub/blub_texture.png", NULL);
    if (!atlas) return;
    SC_CHECK_INT(atlas->as.atlas->ntex, 1);
    if (atlas->as.atlas->ntex < 1) {
        sc_value_release(atlas);
        return;
    }
    const sc_mesh *in = atlas->as.atlas->mesh->as.mesh;
    node_run aw = decimate(atlas, "0.1,0.01", "aware", NULL, NULL);
    node_run fr = decimate(atlas, "0.1,0.01", "free", NULL, NULL);
    const char *erase_params[] = {NULL};
    node_run e = run_node(&sc_node_erase_seams, erase_params, "atlas", atlas);
    SC_CHECK_MSG(e.rc == SC_OK, "erase_seams: %s", e.err.message);
    if (aw.rc == SC_OK && fr.rc == SC_OK && e.rc == SC_OK) {
        const sc_image_data *original = atlas->as.atlas->textures[0].image->as.image;
        const sc_image_data *erased = e.out->as.atlas->textures[0].image->as.image;
        double before = sampled_seam_energy(in, original), floor_in = sampled_seam_energy(in, erased);
        double precision = metric_of(&aw, "uv_precision");
        SC_CHECK(precision > 0 && precision <= 1e-6);
        for (int k = 0; k < 2; k++) {
            const sc_mesh *m = level_mesh(aw.out, k);
            char what[32];
            snprintf(what, sizeof what, "blub level %d", k);
            SC_CHECK(m->nf <= (k ? 142 : 1421));
            check_level(in, m, LEVEL_CHARTS, what);
            /* blub's straight seams are stored with 6 significant digits:
             * the levels keep them to that precision (1/500 texel) */
            int off = check_silhouettes(in, m, 4 * precision);
            SC_CHECK_MSG(off == 0, "%s: %d uv silhouette violations", what, off);
            double ea = sampled_seam_energy(m, erased), ef = sampled_seam_energy(level_mesh(fr.out, k), erased);
            double hd = hausdorff_fraction(in, m);
            printf("     %s: %d faces, hausdorff %.3f%%, seam energy before erasure %.3g, erased %.3g, aware %.3g, free %.3g\n",
                   what, m->nf, 100 * hd, before, floor_in, ea, ef);
            /* blub's uv carry 6 significant digits: a straight seam is
             * straight to ~5e-7 uv (1/1000 texel), and a level's seam chords
             * may sit that far from the input's polylines. Measured: 2e-8 of
             * the energy before erasure (the 8-bit floor is ~3e-7). */
            SC_CHECK_MSG(ea <= 1e-7 * before, "%s: seam energy %g (before erasure %g)", what, ea, before);
            SC_CHECK_MSG(ef > 10 * ea, "%s: free %g is not above aware %g", what, ef, ea);
            if (k == 1) SC_CHECK_MSG(hd <= 0.02, "%s: hausdorff %g", what, hd);
        }
    }
    run_free(&aw);
    run_free(&fr);
    run_free(&e);
    sc_value_release(atlas);
}

/* erase_seams -> straighten -> decimate on blub and spot: straightened seams
 * are exact lines with equal length ratios on both sides, so every aware
 * level keeps the seam-free texture of the straightened atlas seam-free to
 * 1e-8 of the input's seam energy before erasure (without straightening the
 * 6-digit uv of the OBJ leave 1.4e-8 to 4.2e-8, see corpus_blub_one_percent). */
static void straightened_chain(const char *name, const char *model, const char *texture, double max_hausdorff_1) {
    sc_value *atlas = sc_test_load_corpus(model, texture, NULL);
    if (!atlas) return;
    if (atlas->as.atlas->ntex < 1) {
        SC_CHECK_MSG(0, "%s: no texture", name);
        sc_value_release(atlas);
        return;
    }
    const sc_mesh *in = atlas->as.atlas->mesh->as.mesh;
    const char *none[] = {NULL};
    node_run e = run_node(&sc_node_erase_seams, none, "atlas", atlas);
    SC_CHECK_MSG(e.rc == SC_OK, "%s: erase_seams: %s", name, e.err.message);
    node_run s = {0};
    if (e.rc == SC_OK) {
        s = run_node(&sc_node_straighten, none, "atlas", e.out);
        SC_CHECK_MSG(s.rc == SC_OK, "%s: straighten: %s", name, s.err.message);
    }
    if (s.rc == SC_OK && s.out && s.out->as.atlas->ntex >= 1) {
        const sc_mesh *sm = s.out->as.atlas->mesh->as.mesh;
        const sc_image_data *original = atlas->as.atlas->textures[0].image->as.image;
        const sc_image_data *straight = s.out->as.atlas->textures[0].image->as.image;
        SC_CHECK(metric_of(&s, "flipped_triangles") == 0);
        double before = sampled_seam_energy(in, original), floor_in = sampled_seam_energy(sm, straight);
        node_run d = decimate(s.out->as.atlas->mesh, "0.5,0.1,0.01", "aware", NULL, NULL);
        if (d.rc == SC_OK) {
            SC_CHECK_INT(d.out->as.lods->count, 3);
            for (int k = 0; k < d.out->as.lods->count; k++) {
                const sc_mesh *m = level_mesh(d.out, k);
                char what[48], metric[48];
                snprintf(what, sizeof what, "%s straightened level %d", name, k);
                double ea = sampled_seam_energy(m, straight);
                snprintf(metric, sizeof metric, "lod%d.flipped_uv_faces", k);
                double flipped_metric = metric_of(&d, metric);
                int flipped = check_uv_orientation(sm, m);
                printf("     %s: %d faces, seam energy before erasure %.3g, straightened %.3g, level %.3g "
                       "(%.2g of before)\n",
                       what, m->nf, before, floor_in, ea, ea / before);
                SC_CHECK_MSG(ea <= 1e-8 * before, "%s: seam energy %g vs %g before erasure", what, ea, before);
                SC_CHECK_MSG(flipped_metric == 0 && flipped == 0, "%s: %g flipped uv faces (%d by the check here)",
                             what, flipped_metric, flipped);
                /* straightened seams are exact lines: the level's uv boundary
                 * lies on the straightened input's to rounding */
                int off = check_silhouettes(sm, m, 1e-9);
                SC_CHECK_MSG(off == 0, "%s: %d uv silhouette violations", what, off);
                if (k == 2 && max_hausdorff_1 > 0) {
                    double hd = hausdorff_fraction(in, m);
                    printf("     %s: hausdorff %.3f%% (target %d faces)\n", what, 100 * hd,
                           (int)llround(0.01 * in->nf));
                    SC_CHECK_MSG(m->nf <= llround(0.01 * in->nf), "%s: %d faces", what, m->nf);
                    SC_CHECK_MSG(hd <= max_hausdorff_1, "%s: hausdorff %g", what, hd);
                }
            }
        }
        run_free(&d);
    }
    run_free(&s);
    run_free(&e);
    sc_value_release(atlas);
}

SC_TEST(corpus_straightened_levels_keep_the_erased_seams) {
    if (!sc_test_corpus()) {
        printf("     corpus absent: skipped\n");
        return;
    }
    /* project issue 4: blub at 1% keeps its seams exactly within 2% of the
     * bounding-box diagonal (spot stalls above 1%: no bound there) */
    straightened_chain("blub", "blub/blub.obj", "blub/blub_texture.png", 0.02);
    straightened_chain("spot", "spot/spot_triangulated.obj", "spot/spot_texture.png", 0);
}

int main(void) { return sc_test_main(); }
