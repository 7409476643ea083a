/* sc_gradient.c - gradient-domain processing inside a texture atlas (Prada et
 * al. 2018): the seam-continuous texel basis, its mass and stiffness
 * matrices under the surface metric, and the multigrid solver. The header
 * (sc_gradient.h) states the method; this file holds it in four parts:
 *
 *   pieces     every mesh triangle of the material cut by the texel grid,
 *              seam edges split at both sides' crossings, each convex piece
 *              fanned around its centroid into quadratic elements whose six
 *              nodes carry their bilinear (or seam-averaged) texel weights;
 *   assembly   per piece a small dense matrix over the texels it touches,
 *              added into a 3 x 3 stencil per texel (pairs beyond it, which
 *              only seams make, go to a triplet list), then the unknowns
 *              (texels of positive mass) and their CSC matrices;
 *   multigrid  bilinear prolongation, Galerkin coarse levels, interior
 *              texels relaxed by Gauss-Seidel, boundary texels and the
 *              coarsest level solved by CHOLMOD, V-cycles to a tolerance;
 *   operations smooth and sharpen (gradient scaling), stitch (gradients
 *              kept only inside one label), geodesic (the heat method), and
 *              the seam energy of what comes out (sc_seam_energy).
 *
 * Threads share the work in orders fixed by the mesh and the grid, so the
 * same inputs give the same bits on any number of threads: assembly walks
 * faces on workers that record each face's additions, made afterwards in
 * face order; Gauss-Seidel relaxes strips of rows, even strips side by side,
 * then odd; matrix-vector products go by chunks of rows. The hierarchy's
 * coarse matrices are formed in one pass (no intermediate A P) and the
 * fine system's other matrices are freed before it is built, which sets the
 * run's peak memory. Measurements: docs/notes/gradient_domain.md.
 */
#include "sc_geometry.h"
#include "sc_gradient.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "sc_seam.h"
#include "sc_sparse.h"
#include "sc_tangent.h"

static const sc_kernel *const gradient_uses[] = {&sc_kernel_seam, &sc_kernel_sparse, &sc_kernel_tangent, NULL};
const sc_kernel sc_kernel_gradient = {"gradient", SC_GRADIENT_VERSION, gradient_uses};

static const char *const op_names[] = {"smooth", "sharpen", "stitch", "geodesic", "lic"};

int sc_gradient_op_named(const char *name) {
    for (int i = 0; i < (int)(sizeof op_names / sizeof op_names[0]); i++)
        if (strcmp(name, op_names[i]) == 0) return i;
    return -1;
}

void sc_gradient_defaults(sc_gradient_options *o, sc_gradient_op op) {
    *o = (sc_gradient_options){
        .op = op,
        .gradient_scale = op == SC_GRADIENT_SHARPEN ? 2.0 : 0.0,
        .screening = op == SC_GRADIENT_STITCH ? 1e2 : 1e4,
        .time_step = 1e-3,
        .sources = "",
        .solver = SC_GRADIENT_MULTIGRID,
        .levels = 4,
        .relaxations = 4,
        .max_vcycles = 30,
        .tolerance = 1e-8,
        .lic_length = 16,
        .lic_seed = 1,
    };
    if (op == SC_GRADIENT_LIC) o->screening = 1;
}

/* ================================================================ pieces */

#define GD_MAX_TAPS 32 /* 4 taps x 8 uvs of one surface vertex */

typedef struct gd_node {
    int32_t n;
    int32_t id[GD_MAX_TAPS];
    double w[GD_MAX_TAPS];
} gd_node;

/* One convex piece of a mesh triangle inside one texel cell, fanned around
 * its centroid: m boundary vertices, element i has corners (i, i + 1, c). */
typedef struct gd_piece {
    int32_t face;
    int32_t m;
    double (*pos)[2];      /* m + 1 corner positions in texel space (centroid last) */
    gd_node *node;         /* 3m + 1: corners, centroid, boundary midpoints, spoke midpoints */
    bool full;             /* the piece is the whole cell, inside one face, no seam */
    int32_t cell[4];       /* then its corner texels: (cx, cy), (cx+1, cy), (cx, cy+1), (cx+1, cy+1) */
    double sqrtdet;        /* sqrt(det g) of the face */
    double ginv[3];        /* g^-1: xx, xy, yy (texel-space covectors) */
} gd_piece;

typedef int (*gd_visit)(void *ud, const gd_piece *p, sc_error *err);

/* a polygon vertex while clipping: position, the face edges it lies on
 * (bit k: edge corner k -> k + 1), the face corner it is (or -1) */
typedef struct gd_pv {
    double x, y;
    int mask, corner;
} gd_pv;

typedef struct gd_walk {
    const sc_mesh *m;
    int32_t material;
    sc_seam_grid g;
    sc_seam_set seams;
    int32_t *edge_seam;    /* nf * 3: the seam of face edge k, or -1 */
    int8_t *edge_fwd;      /* nf * 3: corner k is the seam's v0 */
    int32_t *xstart;       /* nseams + 1 */
    double *xs;            /* every seam's crossing parameters (both sides), sorted */
    int32_t *vstart, *vuv; /* per surface vertex: its distinct uvs (by coordinates) */
    /* scratch of one piece */
    int32_t cap;
    gd_pv *bv;
    double *g0, *g1;       /* seam parameter of a boundary sub-edge's ends */
    int32_t *bseam;        /* seam of boundary sub-edge i (i -> i + 1), or -1 */
    double (*pos)[2];
    gd_node *node;
    /* lic: per face, u_perp (3D, scaled), and epsilon; NULL: the surface metric */
    const double *lic_perp;
    double lic_epsilon;
} gd_walk;

static bool in_material(const gd_walk *w, int32_t f) { return w->material < 0 || w->m->FM[f] == w->material; }

static void walk_free(gd_walk *w) {
    sc_seam_set_free(&w->seams);
    free(w->edge_seam), free(w->edge_fwd), free(w->xstart), free(w->xs);
    free(w->vstart), free(w->vuv);
    free(w->bv), free(w->g0), free(w->g1), free(w->bseam), free(w->pos), free(w->node);
    memset(w, 0, sizeof *w);
}

static int walk_reserve(gd_walk *w, int32_t need) {
    if (need <= w->cap) return 0;
    int32_t cap = need * 2;
    gd_pv *bv = sc_realloc_array(w->bv, (size_t)cap, sizeof *bv);
    if (bv) w->bv = bv;
    double *g0 = sc_realloc_array(w->g0, (size_t)cap, sizeof *g0);
    if (g0) w->g0 = g0;
    double *g1 = sc_realloc_array(w->g1, (size_t)cap, sizeof *g1);
    if (g1) w->g1 = g1;
    int32_t *bs = sc_realloc_array(w->bseam, (size_t)cap, sizeof *bs);
    if (bs) w->bseam = bs;
    double(*pos)[2] = sc_realloc_array(w->pos, (size_t)cap + 1, sizeof *pos);
    if (pos) w->pos = pos;
    gd_node *nd = sc_realloc_array(w->node, 3 * (size_t)cap + 1, sizeof *nd);
    if (nd) w->node = nd;
    if (!bv || !g0 || !g1 || !bs || !pos || !nd) return -1;
    w->cap = cap;
    return 0;
}

static const double *uv_of(const sc_mesh *m, int32_t k) { return m->U + 2 * (size_t)k; }

static int walk_init(gd_walk *w, const sc_mesh *m, int32_t material, const sc_seam_grid *g, sc_error *err) {
    memset(w, 0, sizeof *w);
    w->m = m, w->material = material, w->g = *g;
    int rc = sc_seam_find(m, material, &w->seams, err);
    if (rc != SC_OK) return rc;
    int32_t ns = w->seams.nseams;
    w->edge_seam = sc_alloc_array((size_t)m->nf * 3, sizeof *w->edge_seam);
    w->edge_fwd = sc_calloc_array((size_t)m->nf * 3, 1);
    w->xstart = sc_calloc_array((size_t)ns + 1, sizeof *w->xstart);
    w->vstart = sc_calloc_array((size_t)m->nv + 1, sizeof *w->vstart);
    w->vuv = sc_alloc_array((size_t)m->nf * 3 + 1, sizeof *w->vuv);
    if (!w->edge_seam || !w->edge_fwd || !w->xstart || !w->vstart || !w->vuv || walk_reserve(w, 16)) goto oom;
    for (size_t i = 0; i < (size_t)m->nf * 3; i++) w->edge_seam[i] = -1;
    /* face edges of seams, and both sides' crossings of the grid */
    double *buf = NULL;
    int32_t bcap = 0;
    size_t xcap = 0, xn = 0;
    for (int32_t e = 0; e < ns; e++) {
        const sc_seam_edge *se = &w->seams.seams[e];
        for (int s = 0; s < 2; s++) {
            int32_t f = se->side[s].face;
            for (int k = 0; k < 3; k++) {
                int32_t a = m->FV[3 * f + k], b = m->FV[3 * f + (k + 1) % 3];
                if ((a == se->v0 && b == se->v1) || (a == se->v1 && b == se->v0)) {
                    w->edge_seam[3 * f + k] = e;
                    w->edge_fwd[3 * f + k] = a == se->v0;
                }
            }
        }
        int32_t c = sc_seam_crossings(g, uv_of(m, se->side[0].uv0), uv_of(m, se->side[0].uv1),
                                      uv_of(m, se->side[1].uv0), uv_of(m, se->side[1].uv1), &buf, &bcap);
        if (c < 0) {
            free(buf);
            sc_fail(err, SC_ENOMEM, "seam %d crosses too many texel lines", (int)e);
            walk_free(w);
            return SC_ENOMEM;
        }
        if (xn + (size_t)c > xcap) {
            size_t nc = (xn + (size_t)c) * 2;
            double *nx = sc_realloc_array(w->xs, nc, sizeof *nx);
            if (!nx) {
                free(buf);
                goto oom;
            }
            w->xs = nx, xcap = nc;
        }
        memcpy(w->xs + xn, buf, (size_t)c * sizeof *buf);
        xn += (size_t)c;
        w->xstart[e + 1] = (int32_t)xn;
    }
    free(buf);
    /* the distinct uvs of every surface vertex */
    for (int32_t f = 0; f < m->nf; f++)
        if (in_material(w, f))
            for (int k = 0; k < 3; k++) w->vstart[m->FV[3 * f + k] + 1]++;
    for (int32_t v = 0; v < m->nv; v++) w->vstart[v + 1] += w->vstart[v];
    int32_t *fill = sc_calloc_array((size_t)m->nv + 1, sizeof *fill);
    if (!fill) goto oom;
    for (int32_t f = 0; f < m->nf; f++) {
        if (!in_material(w, f)) continue;
        for (int k = 0; k < 3; k++) {
            int32_t v = m->FV[3 * f + k], t = m->FU[3 * f + k];
            const double *uv = uv_of(m, t);
            bool seen = false;
            for (int32_t j = w->vstart[v]; j < w->vstart[v] + fill[v] && !seen; j++) {
                const double *o = uv_of(m, w->vuv[j]);
                seen = o[0] == uv[0] && o[1] == uv[1];
            }
            if (!seen) w->vuv[w->vstart[v] + fill[v]++] = t;
        }
    }
    /* compact: vertex v's uvs are vuv[vstart[v] .. vstart[v] + fill[v]) */
    int32_t out = 0;
    for (int32_t v = 0; v < m->nv; v++) {
        int32_t s = w->vstart[v];
        w->vstart[v] = out;
        for (int32_t j = 0; j < fill[v]; j++) w->vuv[out++] = w->vuv[s + j];
    }
    w->vstart[m->nv] = out;
    free(fill);
    return SC_OK;
oom:
    walk_free(w);
    return sc_fail(err, SC_ENOMEM, "out of memory");
}

static void node_add_uv(gd_node *nd, const sc_seam_grid *g, double u, double v, double scale) {
    int32_t id[4];
    double wt[4];
    sc_seam_taps(g, u, v, id, wt);
    for (int k = 0; k < 4; k++) {
        if (wt[k] == 0) continue;
        int32_t j = 0;
        while (j < nd->n && nd->id[j] != id[k]) j++;
        if (j == nd->n) {
            if (nd->n == GD_MAX_TAPS) continue;
            nd->id[j] = id[k], nd->w[j] = 0, nd->n++;
        }
        nd->w[j] += scale * wt[k];
    }
}

static void node_at(gd_node *nd, const sc_seam_grid *g, double x, double y) {
    nd->n = 0;
    node_add_uv(nd, g, (x + 0.5) / g->width, (y + 0.5) / g->height, 1.0);
}

/* a node on seam e at parameter gamma: the mean of both sides */
static void node_seam(const gd_walk *w, gd_node *nd, int32_t e, double gamma) {
    nd->n = 0;
    const sc_seam_edge *se = &w->seams.seams[e];
    for (int s = 0; s < 2; s++) {
        const double *a = uv_of(w->m, se->side[s].uv0), *b = uv_of(w->m, se->side[s].uv1);
        node_add_uv(nd, &w->g, a[0] + gamma * (b[0] - a[0]), a[1] + gamma * (b[1] - a[1]), 0.5);
    }
}

/* a mesh corner: the mean over every uv of its surface vertex */
static void node_vertex(const gd_walk *w, gd_node *nd, int32_t v) {
    nd->n = 0;
    int32_t s = w->vstart[v], c = w->vstart[v + 1] - s;
    if (c > GD_MAX_TAPS / 4) c = GD_MAX_TAPS / 4;
    for (int32_t j = 0; j < c; j++) {
        const double *uv = uv_of(w->m, w->vuv[s + j]);
        node_add_uv(nd, &w->g, uv[0], uv[1], 1.0 / c);
    }
}

/* keep the side of an axis line: axis 0 = x, 1 = y; ge: keep coord >= c */
static int clip_line(const gd_pv *in, int n, gd_pv *out, int axis, double c, bool ge) {
    int k = 0;
    for (int i = 0; i < n; i++) {
        const gd_pv *a = &in[i], *b = &in[(i + 1) % n];
        double ca = axis ? a->y : a->x, cb = axis ? b->y : b->x;
        bool ia = ge ? ca >= c : ca <= c, ib = ge ? cb >= c : cb <= c;
        if (ia) out[k++] = *a;
        if (ia != ib) {
            double t = (c - ca) / (cb - ca);
            gd_pv p = {.x = a->x + t * (b->x - a->x), .y = a->y + t * (b->y - a->y), .mask = a->mask & b->mask, .corner = -1};
            if (axis) p.y = c; else p.x = c;
            out[k++] = p;
        }
    }
    return k;
}

/* Merge vertices closer than 1e-9 texel (a corner or a crossing on a
 * clipping line comes out twice): a near-zero edge would make an element
 * whose huge gradients drown the stiffness in rounding. The merged vertex
 * keeps a face corner's identity. */
static int drop_repeats(gd_pv *p, int n) {
    int k = 0;
    for (int i = 0; i < n; i++) {
        if (k > 0 && fabs(p[i].x - p[k - 1].x) < 1e-9 && fabs(p[i].y - p[k - 1].y) < 1e-9) {
            if (p[i].corner >= 0) p[k - 1] = p[i];
            continue;
        }
        p[k++] = p[i];
    }
    while (k > 1 && fabs(p[0].x - p[k - 1].x) < 1e-9 && fabs(p[0].y - p[k - 1].y) < 1e-9) {
        if (p[k - 1].corner >= 0) p[0] = p[k - 1];
        k--;
    }
    return k;
}

/* the seam parameter of point p on face edge k of f, snapped to the
 * seam's crossing list when within rounding of an entry */
static double seam_gamma(const gd_walk *w, int32_t f, int k, const double P[3][2], double x, double y) {
    const double *a = P[k], *b = P[(k + 1) % 3];
    double dx = b[0] - a[0], dy = b[1] - a[1];
    double t = ((x - a[0]) * dx + (y - a[1]) * dy) / (dx * dx + dy * dy);
    double gm = w->edge_fwd[3 * f + k] ? t : 1 - t;
    int32_t e = w->edge_seam[3 * f + k];
    const double *xs = w->xs + w->xstart[e];
    int32_t lo = 0, hi = w->xstart[e + 1] - w->xstart[e] - 1;
    while (hi - lo > 1) {
        int32_t mid = (lo + hi) / 2;
        if (xs[mid] <= gm) lo = mid; else hi = mid;
    }
    if (fabs(xs[lo] - gm) < 1e-9) return xs[lo];
    if (fabs(xs[hi] - gm) < 1e-9) return xs[hi];
    return gm < 0 ? 0 : gm > 1 ? 1 : gm;
}

/* the face's metric in texel space: g = E^-T (F^T F) E^-1; with perp (lic),
 * h = c c^T + eps g, c_x = dX/dx . perp, c_y = dX/dy . perp */
static bool face_metric(const sc_mesh *m, int32_t f, const double P[3][2], const double *perp, double eps,
                        double *sqrtdet, double ginv[3]) {
    const double *X0 = m->V + 3 * (size_t)m->FV[3 * f], *X1 = m->V + 3 * (size_t)m->FV[3 * f + 1],
                 *X2 = m->V + 3 * (size_t)m->FV[3 * f + 2];
    double e1[3], e2[3];
    for (int i = 0; i < 3; i++) e1[i] = X1[i] - X0[i], e2[i] = X2[i] - X0[i];
    double G11 = e1[0] * e1[0] + e1[1] * e1[1] + e1[2] * e1[2], G12 = e1[0] * e2[0] + e1[1] * e2[1] + e1[2] * e2[2],
           G22 = e2[0] * e2[0] + e2[1] * e2[1] + e2[2] * e2[2];
    double a = P[1][0] - P[0][0], b = P[2][0] - P[0][0], c = P[1][1] - P[0][1], d = P[2][1] - P[0][1];
    double det = a * d - b * c, detG = G11 * G22 - G12 * G12;
    if (!(fabs(det) > 1e-14) || !(detG > 0)) return false;
    /* Ei = E^-1 = [d -b; -c a] / det; g = Ei^T G Ei */
    double i11 = d / det, i12 = -b / det, i21 = -c / det, i22 = a / det;
    double t11 = G11 * i11 + G12 * i21, t12 = G11 * i12 + G12 * i22;
    double t21 = G12 * i11 + G22 * i21, t22 = G12 * i12 + G22 * i22;
    double gxx = i11 * t11 + i21 * t21, gxy = i11 * t12 + i21 * t22, gyy = i12 * t12 + i22 * t22;
    double dg = gxx * gyy - gxy * gxy;
    if (!(dg > 0)) return false;
    if (perp) {
        double cx = 0, cy = 0;
        for (int i = 0; i < 3; i++)
            cx += (i11 * e1[i] + i21 * e2[i]) * perp[i], cy += (i12 * e1[i] + i22 * e2[i]) * perp[i];
        gxx = cx * cx + eps * gxx, gxy = cx * cy + eps * gxy, gyy = cy * cy + eps * gyy;
        dg = gxx * gyy - gxy * gxy;
        if (!(dg > 0)) return false;
        *sqrtdet = sqrt(dg);
        ginv[0] = gyy / dg, ginv[1] = -gxy / dg, ginv[2] = gxx / dg;
        return true;
    }
    *sqrtdet = sqrt(detG) / fabs(det);
    ginv[0] = gyy / dg, ginv[1] = -gxy / dg, ginv[2] = gxx / dg;
    return true;
}

/* Visit every piece of every face of the material, in face order, cells
 * in row order. */
/* the pieces of face f, each given to visit */
static int walk_face(gd_walk *w, int32_t f, gd_visit visit, void *ud, sc_error *err) {
    const sc_mesh *m = w->m;
    const sc_seam_grid *g = &w->g;
    {
        if (!in_material(w, f)) return SC_OK;
        double P[3][2];
        for (int k = 0; k < 3; k++) {
            const double *uv = uv_of(m, m->FU[3 * f + k]);
            P[k][0] = uv[0] * g->width - 0.5, P[k][1] = uv[1] * g->height - 0.5;
        }
        gd_piece pc = {.face = f};
        if (!face_metric(m, f, P, w->lic_perp ? w->lic_perp + 3 * (size_t)f : NULL, w->lic_epsilon, &pc.sqrtdet,
                         pc.ginv))
            return SC_OK;
        double x0 = fmin(P[0][0], fmin(P[1][0], P[2][0])), x1 = fmax(P[0][0], fmax(P[1][0], P[2][0]));
        double y0 = fmin(P[0][1], fmin(P[1][1], P[2][1])), y1 = fmax(P[0][1], fmax(P[1][1], P[2][1]));
        if (x1 - x0 > 1e6 || y1 - y0 > 1e6) return sc_fail(err, SC_EINPUT, "face %d spans too many texels", (int)f);
        for (double cy = floor(y0); cy <= y1; cy += 1) {
            for (double cx = floor(x0); cx <= x1; cx += 1) {
                gd_pv A[16], B[16];
                for (int k = 0; k < 3; k++)
                    A[k] = (gd_pv){.x = P[k][0], .y = P[k][1], .mask = (1 << k) | (1 << ((k + 2) % 3)), .corner = k};
                int n = clip_line(A, 3, B, 0, cx, true);
                n = clip_line(B, n, A, 0, cx + 1, false);
                n = clip_line(A, n, B, 1, cy, true);
                n = clip_line(B, n, A, 1, cy + 1, false);
                n = drop_repeats(A, n);
                if (n < 3) continue;
                double area2 = 0;
                for (int i = 0; i < n; i++) area2 += A[i].x * A[(i + 1) % n].y - A[(i + 1) % n].x * A[i].y;
                if (fabs(area2) < 1e-12) continue;
                /* boundary with the other side's crossings inserted on seams */
                int32_t mb = 0;
                for (int i = 0; i < n; i++) {
                    const gd_pv *a = &A[i], *b = &A[(i + 1) % n];
                    int common = a->mask & b->mask;
                    int k = common & 1 ? 0 : common & 2 ? 1 : common & 4 ? 2 : -1;
                    int32_t e = k >= 0 ? w->edge_seam[3 * f + k] : -1;
                    if (walk_reserve(w, mb + 2)) return sc_fail(err, SC_ENOMEM, "out of memory");
                    w->bv[mb] = *a;
                    w->bseam[mb] = -1;
                    if (e < 0) {
                        mb++;
                        continue;
                    }
                    double ga = seam_gamma(w, f, k, P, a->x, a->y), gb = seam_gamma(w, f, k, P, b->x, b->y);
                    bool fwd = w->edge_fwd[3 * f + k];
                    const double *xs = w->xs + w->xstart[e];
                    int32_t nx = w->xstart[e + 1] - w->xstart[e];
                    double glo = fmin(ga, gb), ghi = fmax(ga, gb);
                    int32_t j0 = 0, j1 = nx - 1, dir = 1;
                    if (gb < ga) j0 = nx - 1, j1 = 0, dir = -1;
                    w->bseam[mb] = e, w->g0[mb] = ga;
                    for (int32_t j = j0; j != j1 + dir; j += dir) {
                        if (!(xs[j] > glo + 1e-12 && xs[j] < ghi - 1e-12)) continue;
                        double t = fwd ? xs[j] : 1 - xs[j];
                        w->g1[mb] = xs[j];
                        mb++;
                        if (walk_reserve(w, mb + 2)) return sc_fail(err, SC_ENOMEM, "out of memory");
                        w->bv[mb] = (gd_pv){.x = P[k][0] + t * (P[(k + 1) % 3][0] - P[k][0]),
                                            .y = P[k][1] + t * (P[(k + 1) % 3][1] - P[k][1]),
                                            .mask = 1 << k, .corner = -1};
                        w->bseam[mb] = e, w->g0[mb] = xs[j];
                    }
                    w->g1[mb] = gb;
                    mb++;
                }
                /* nodes: corners, centroid, boundary midpoints, spoke midpoints */
                double ccx = 0, ccy = 0;
                for (int i = 0; i < n; i++) ccx += A[i].x, ccy += A[i].y;
                ccx /= n, ccy /= n;
                for (int32_t i = 0; i < mb; i++) {
                    const gd_pv *p = &w->bv[i];
                    w->pos[i][0] = p->x, w->pos[i][1] = p->y;
                    gd_node *nd = &w->node[i];
                    if (p->corner >= 0) {
                        node_vertex(w, nd, m->FV[3 * f + p->corner]);
                        continue;
                    }
                    int32_t prev = (i + mb - 1) % mb;
                    if (w->bseam[i] >= 0) node_seam(w, nd, w->bseam[i], w->g0[i]);
                    else if (w->bseam[prev] >= 0) node_seam(w, nd, w->bseam[prev], w->g1[prev]);
                    else node_at(nd, g, p->x, p->y);
                }
                w->pos[mb][0] = ccx, w->pos[mb][1] = ccy;
                node_at(&w->node[mb], g, ccx, ccy);
                for (int32_t i = 0; i < mb; i++) {
                    int32_t i1 = (i + 1) % mb;
                    if (w->bseam[i] >= 0) node_seam(w, &w->node[mb + 1 + i], w->bseam[i], 0.5 * (w->g0[i] + w->g1[i]));
                    else node_at(&w->node[mb + 1 + i], g, 0.5 * (w->pos[i][0] + w->pos[i1][0]), 0.5 * (w->pos[i][1] + w->pos[i1][1]));
                    node_at(&w->node[2 * mb + 1 + i], g, 0.5 * (w->pos[i][0] + ccx), 0.5 * (w->pos[i][1] + ccy));
                }
                pc.m = mb, pc.pos = w->pos, pc.node = w->node;
                pc.full = mb == 4 && fabs(0.5 * fabs(area2) - 1) < 1e-12;
                for (int32_t i = 0; i < mb && pc.full; i++) pc.full = w->bseam[i] < 0 && w->bv[i].corner < 0;
                if (pc.full) {
                    double tw[4];
                    sc_seam_taps(g, (ccx + 0.5) / g->width, (ccy + 0.5) / g->height, pc.cell, tw);
                    for (int i = 0; i < 4; i++)
                        for (int j = 0; j < i; j++) pc.full &= pc.cell[i] != pc.cell[j];
                }
                int rc = visit(ud, &pc, err);
                if (rc != SC_OK) return rc;
            }
        }
    }
    return SC_OK;
}

static int walk_pieces(gd_walk *w, gd_visit visit, void *ud, sc_error *err) {
    for (int32_t f = 0; f < w->m->nf; f++) {
        int rc = walk_face(w, f, visit, ud, err);
        if (rc != SC_OK) return rc;
    }
    return SC_OK;
}

/* the texel cells face f's uv bounding box spans */
static double face_cells(const gd_walk *w, int32_t f) {
    double x0 = INFINITY, x1 = -INFINITY, y0 = INFINITY, y1 = -INFINITY;
    for (int k = 0; k < 3; k++) {
        const double *uv = uv_of(w->m, w->m->FU[3 * f + k]);
        x0 = fmin(x0, uv[0] * w->g.width), x1 = fmax(x1, uv[0] * w->g.width);
        y0 = fmin(y0, uv[1] * w->g.height), y1 = fmax(y1, uv[1] * w->g.height);
    }
    return (floor(x1) - floor(x0) + 2) * (floor(y1) - floor(y0) + 2);
}

/* element i of a piece: its corners and its six nodes (P2 order: corners,
 * then midpoints of edges 01, 12, 20) */
static void piece_element(const gd_piece *p, int32_t i, double c[3][2], const gd_node *nd[6]) {
    int32_t m = p->m, i1 = (i + 1) % m;
    for (int k = 0; k < 2; k++) c[0][k] = p->pos[i][k], c[1][k] = p->pos[i1][k], c[2][k] = p->pos[m][k];
    nd[0] = &p->node[i], nd[1] = &p->node[i1], nd[2] = &p->node[m];
    nd[3] = &p->node[m + 1 + i], nd[4] = &p->node[2 * m + 1 + i1], nd[5] = &p->node[2 * m + 1 + i];
}

/* ---------------------------------------------------------------- P2 element */

/* the 6-point rule (Strang-Fix), exact for degree 4: barycentric points, weights summing to 1 */
static const double quad_l[6][3] = {
    {0.108103018168070, 0.445948490915965, 0.445948490915965}, {0.445948490915965, 0.108103018168070, 0.445948490915965},
    {0.445948490915965, 0.445948490915965, 0.108103018168070}, {0.816847572980459, 0.091576213509771, 0.091576213509771},
    {0.091576213509771, 0.816847572980459, 0.091576213509771}, {0.091576213509771, 0.091576213509771, 0.816847572980459}};
static const double quad_w[6] = {0.223381589678011, 0.223381589678011, 0.223381589678011,
                                 0.109951743655322, 0.109951743655322, 0.109951743655322};

/* gradients of the barycentric coordinates; returns the signed double area */
static double bary_grad(const double c[3][2], double dl[3][2]) {
    double a2 = (c[1][0] - c[0][0]) * (c[2][1] - c[0][1]) - (c[2][0] - c[0][0]) * (c[1][1] - c[0][1]);
    for (int i = 0; i < 3; i++) {
        const double *pj = c[(i + 1) % 3], *pk = c[(i + 2) % 3];
        dl[i][0] = (pj[1] - pk[1]) / a2;
        dl[i][1] = (pk[0] - pj[0]) / a2;
    }
    return a2;
}

static void p2_values(const double l[3], double N[6]) {
    N[0] = l[0] * (2 * l[0] - 1), N[1] = l[1] * (2 * l[1] - 1), N[2] = l[2] * (2 * l[2] - 1);
    N[3] = 4 * l[0] * l[1], N[4] = 4 * l[1] * l[2], N[5] = 4 * l[2] * l[0];
}

static void p2_grads(const double l[3], double dl[3][2], double dN[6][2]) {
    for (int k = 0; k < 2; k++) {
        dN[0][k] = (4 * l[0] - 1) * dl[0][k];
        dN[1][k] = (4 * l[1] - 1) * dl[1][k];
        dN[2][k] = (4 * l[2] - 1) * dl[2][k];
        dN[3][k] = 4 * (l[1] * dl[0][k] + l[0] * dl[1][k]);
        dN[4][k] = 4 * (l[2] * dl[1][k] + l[1] * dl[2][k]);
        dN[5][k] = 4 * (l[0] * dl[2][k] + l[2] * dl[0][k]);
    }
}

static double gdot(const double gi[3], const double a[2], const double b[2]) {
    return gi[0] * a[0] * b[0] + gi[1] * (a[0] * b[1] + a[1] * b[0]) + gi[2] * a[1] * b[1];
}

/* mass and stiffness of one element under the metric (false: degenerate) */
static bool p2_local(const double c[3][2], double sqrtdet, const double gi[3], double M[6][6], double S[6][6]) {
    double dl[3][2];
    double a2 = bary_grad(c, dl);
    if (!(fabs(a2) > 1e-300)) return false;
    double area = 0.5 * fabs(a2) * sqrtdet;
    memset(M, 0, 36 * sizeof(double)), memset(S, 0, 36 * sizeof(double));
    for (int q = 0; q < 6; q++) {
        double N[6], dN[6][2];
        p2_values(quad_l[q], N);
        p2_grads(quad_l[q], dl, dN);
        double wq = quad_w[q] * area;
        for (int i = 0; i < 6; i++)
            for (int j = 0; j < 6; j++) M[i][j] += wq * N[i] * N[j], S[i][j] += wq * gdot(gi, dN[i], dN[j]);
    }
    return true;
}

/* ================================================================ assembly */

/* Per texel of the grid, the upper half of its 3 x 3 neighbourhood:
 * offsets (0,0) (1,0) (-1,1) (0,1) (1,1); other pairs go to `extra`. */
#define GD_NMAT 3 /* mass, stiffness, stiffness inside one label */
typedef struct gd_asm {
    const sc_seam_grid *g;
    double *st[GD_NMAT];       /* W * H * 5 each (st[2] only with labels) */
    sc_triplets extra[GD_NMAT];
    const sc_image_data *labels;
    int nmat;
    /* local scratch; the whole-cell matrices of face cell_face */
    int32_t cell_face;
    double cellm[2][4][4];
    int32_t cap, *tid;
    double *loc;               /* GD_NMAT x cap x cap */
    struct gd_reclist *rec;    /* set: additions are recorded here, not made */
} gd_asm;

/* the additions one face makes, recorded on a worker thread and made on the
 * calling one in face order */
typedef struct gd_rec {
    int32_t a, b;
    double v;
    int32_t k;
} gd_rec;

typedef struct gd_reclist {
    size_t n, cap;
    gd_rec *r;
    bool failed;
} gd_reclist;

static void rec_push(gd_reclist *l, int k, int32_t a, int32_t b, double v) {
    if (l->n == l->cap) {
        size_t cap = l->cap ? 2 * l->cap : 1024;
        gd_rec *r = sc_realloc_array(l->r, cap, sizeof *r);
        if (!r) {
            l->failed = true;
            return;
        }
        l->r = r, l->cap = cap;
    }
    l->r[l->n++] = (gd_rec){a, b, v, k};
}

static int stencil_slot(const sc_seam_grid *g, int32_t *a, int32_t *b) {
    int32_t W = g->width;
    int32_t ax = *a % W, ay = *a / W, bx = *b % W, by = *b / W;
    int32_t dx = bx - ax, dy = by - ay;
    if (dy < 0 || (dy == 0 && dx < 0)) {
        int32_t t = *a;
        *a = *b, *b = t, dx = -dx, dy = -dy;
    }
    if (dy == 0) return dx <= 1 ? dx : -1;
    if (dy == 1 && dx >= -1 && dx <= 1) return 3 + dx;
    return -1;
}

static const int slot_dx[5] = {0, 1, -1, 0, 1}, slot_dy[5] = {0, 0, 1, 1, 1};

static void asm_add(gd_asm *s, int k, int32_t a, int32_t b, double v) {
    if (v == 0) return;
    if (s->rec) {
        rec_push(s->rec, k, a, b, v);
        return;
    }
    int slot = stencil_slot(s->g, &a, &b);
    if (slot >= 0) s->st[k][(size_t)a * 5 + (size_t)slot] += v;
    else sc_triplets_add(&s->extra[k], a, b, v);
}

static double label_of(const sc_image_data *l, int32_t id) { return sc_seam_texel(l, id, 0); }

/* Mass and stiffness of a whole cell inside one face over its four corner
 * texels (order of gd_piece.cell): the same for every such cell of a face. */
static void cell_matrices(double sqrtdet, const double gi[3], double out[2][4][4]) {
    static const double q[5][2] = {{0, 0}, {1, 0}, {1, 1}, {0, 1}, {0.5, 0.5}};
    memset(out, 0, 2 * 16 * sizeof(double));
    for (int e = 0; e < 4; e++) {
        double c[3][2] = {{q[e][0], q[e][1]}, {q[(e + 1) % 4][0], q[(e + 1) % 4][1]}, {q[4][0], q[4][1]}};
        double M[6][6], S[6][6], E[6][4];
        if (!p2_local(c, sqrtdet, gi, M, S)) continue;
        for (int a = 0; a < 6; a++) {
            int i = a < 3 ? a : a - 3, j = a < 3 ? a : (a - 2) % 3;
            double x = 0.5 * (c[i][0] + c[j][0]), y = 0.5 * (c[i][1] + c[j][1]);
            E[a][0] = (1 - x) * (1 - y), E[a][1] = x * (1 - y), E[a][2] = (1 - x) * y, E[a][3] = x * y;
        }
        for (int a = 0; a < 6; a++)
            for (int b = 0; b < 6; b++)
                for (int k = 0; k < 4; k++)
                    for (int l = 0; l < 4; l++) {
                        out[0][k][l] += E[a][k] * M[a][b] * E[b][l];
                        out[1][k][l] += E[a][k] * S[a][b] * E[b][l];
                    }
    }
}

static int asm_visit(void *ud, const gd_piece *p, sc_error *err) {
    gd_asm *s = ud;
    if (p->full) {
        if (s->cell_face != p->face) cell_matrices(p->sqrtdet, p->ginv, s->cellm), s->cell_face = p->face;
        bool same = s->labels != NULL;
        for (int k = 1; k < 4 && same; k++) same = label_of(s->labels, p->cell[k]) == label_of(s->labels, p->cell[0]);
        for (int k = 0; k < s->nmat; k++) {
            if (k == 2 && !same) break;
            for (int i = 0; i < 4; i++)
                for (int j = i; j < 4; j++) asm_add(s, k, p->cell[i], p->cell[j], s->cellm[k ? 1 : 0][i][j]);
        }
        return SC_OK;
    }
    /* the piece's texels */
    int32_t K = 0;
    for (int32_t i = 0; i < 3 * p->m + 1; i++) {
        const gd_node *nd = &p->node[i];
        for (int32_t t = 0; t < nd->n; t++) {
            int32_t j = 0;
            while (j < K && s->tid[j] != nd->id[t]) j++;
            if (j < K) continue;
            if (K == s->cap) {
                int32_t cap = 2 * s->cap;
                int32_t *tid = sc_realloc_array(s->tid, (size_t)cap, sizeof *tid);
                if (!tid) return sc_fail(err, SC_ENOMEM, "out of memory");
                s->tid = tid;
                double *loc = sc_realloc_array(s->loc, (size_t)GD_NMAT * cap * cap, sizeof *loc);
                if (!loc) return sc_fail(err, SC_ENOMEM, "out of memory");
                s->loc = loc, s->cap = cap;
            }
            s->tid[K++] = nd->id[t];
        }
    }
    size_t KK = (size_t)K * (size_t)K;
    memset(s->loc, 0, GD_NMAT * KK * sizeof *s->loc);
    for (int32_t e = 0; e < p->m; e++) {
        double c[3][2], M[6][6], S[6][6];
        const gd_node *nd[6];
        piece_element(p, e, c, nd);
        if (!p2_local(c, p->sqrtdet, p->ginv, M, S)) continue;
        bool same = false;
        if (s->labels) {
            double l0 = label_of(s->labels, nd[0]->id[0]);
            same = true;
            for (int a = 0; a < 6 && same; a++)
                for (int32_t t = 0; t < nd[a]->n && same; t++) same = label_of(s->labels, nd[a]->id[t]) == l0;
        }
        /* E^T M E with E the 6 x K node weights */
        int32_t li[6][GD_MAX_TAPS];
        for (int a = 0; a < 6; a++)
            for (int32_t t = 0; t < nd[a]->n; t++) {
                int32_t j = 0;
                while (s->tid[j] != nd[a]->id[t]) j++;
                li[a][t] = j;
            }
        for (int a = 0; a < 6; a++)
            for (int b = 0; b < 6; b++)
                for (int32_t ta = 0; ta < nd[a]->n; ta++)
                    for (int32_t tb = 0; tb < nd[b]->n; tb++) {
                        double ww = nd[a]->w[ta] * nd[b]->w[tb];
                        size_t at = (size_t)li[a][ta] * (size_t)K + (size_t)li[b][tb];
                        s->loc[at] += ww * M[a][b];
                        s->loc[KK + at] += ww * S[a][b];
                        if (same) s->loc[2 * KK + at] += ww * S[a][b];
                    }
    }
    for (int k = 0; k < s->nmat; k++)
        for (int32_t i = 0; i < K; i++)
            for (int32_t j = i; j < K; j++) asm_add(s, k, s->tid[i], s->tid[j], s->loc[k * KK + (size_t)i * K + j]);
    return SC_OK;
}

/* Assembly on several threads, the same bytes as on one: faces go in
 * batches; within a batch, worker t walks faces t, t + T, ... with a scratch
 * of its own and records each face's additions; then the calling thread
 * makes them in face order, exactly the additions one thread makes. A face
 * spanning more than GD_REC_CELLS cells is walked by the calling thread in
 * its turn instead (its record would be large). */
#define GD_BATCH 256
#define GD_REC_CELLS 4096.0

typedef struct gd_asm_job {
    gd_walk *w;                /* per worker: shared tables, own scratch */
    gd_asm *s;                 /* per worker: own scratch, recording */
    gd_reclist *lists;         /* per face of the batch */
    int *rcs;
    sc_error *errs;
    int32_t f0, nfaces, workers;
} gd_asm_job;

static int asm_batch(void *ud, int32_t t) {
    gd_asm_job *j = ud;
    for (int32_t i = t; i < j->nfaces; i += j->workers) {
        int32_t f = j->f0 + i;
        j->lists[i].n = 0, j->lists[i].failed = false, j->rcs[i] = SC_OK;
        if (!in_material(&j->w[t], f) || face_cells(&j->w[t], f) > GD_REC_CELLS) continue;
        j->s[t].rec = &j->lists[i];
        j->rcs[i] = walk_face(&j->w[t], f, asm_visit, &j->s[t], &j->errs[i]);
    }
    return SC_OK;
}

static int assemble(gd_walk *w, gd_asm *s, int threads, sc_error *err) {
    int T = threads < 1 ? 1 : threads > 16 ? 16 : threads;
    if (T == 1) return walk_pieces(w, asm_visit, s, err);
    gd_walk *ws = sc_calloc_array((size_t)T, sizeof *ws);
    gd_asm *ss = sc_calloc_array((size_t)T, sizeof *ss);
    gd_reclist *lists = sc_calloc_array(GD_BATCH, sizeof *lists);
    int *rcs = sc_calloc_array(GD_BATCH, sizeof *rcs);
    sc_error *errs = sc_calloc_array(GD_BATCH, sizeof *errs);
    int rc = ws && ss && lists && rcs && errs ? SC_OK : SC_ENOMEM;
    for (int t = 0; t < T && rc == SC_OK; t++) {
        ws[t] = *w;
        ws[t].cap = 0, ws[t].bv = NULL, ws[t].g0 = ws[t].g1 = NULL, ws[t].bseam = NULL, ws[t].pos = NULL, ws[t].node = NULL;
        ss[t] = *s;
        ss[t].cap = 64, ss[t].cell_face = -1, ss[t].rec = NULL;
        ss[t].tid = sc_alloc_array((size_t)ss[t].cap, sizeof *ss[t].tid);
        ss[t].loc = sc_alloc_array((size_t)GD_NMAT * ss[t].cap * ss[t].cap, sizeof *ss[t].loc);
        if (!ss[t].tid || !ss[t].loc) rc = SC_ENOMEM;
    }
    if (rc == SC_ENOMEM) sc_fail(err, SC_ENOMEM, "out of memory");
    for (int32_t f0 = 0; f0 < w->m->nf && rc == SC_OK; f0 += GD_BATCH) {
        gd_asm_job j = {ws, ss, lists, rcs, errs, f0, w->m->nf - f0 < GD_BATCH ? w->m->nf - f0 : GD_BATCH, T};
        if (sc_parallel(T, T, asm_batch, &j) != SC_OK) {
            rc = sc_fail(err, SC_ENOMEM, "out of memory");
            break;
        }
        for (int32_t i = 0; i < j.nfaces && rc == SC_OK; i++) {
            int32_t f = f0 + i;
            if (!in_material(w, f)) continue;
            if (face_cells(w, f) > GD_REC_CELLS) {
                rc = walk_face(w, f, asm_visit, s, err);
                continue;
            }
            if (rcs[i] != SC_OK) {
                *err = errs[i];
                rc = rcs[i];
            } else if (lists[i].failed) {
                rc = sc_fail(err, SC_ENOMEM, "out of memory");
            }
            for (size_t e = 0; e < lists[i].n && rc == SC_OK; e++)
                asm_add(s, lists[i].r[e].k, lists[i].r[e].a, lists[i].r[e].b, lists[i].r[e].v);
        }
    }
    for (int t = 0; ws && ss && t < T; t++) {
        free(ws[t].bv), free(ws[t].g0), free(ws[t].g1), free(ws[t].bseam), free(ws[t].pos), free(ws[t].node);
        free(ss[t].tid), free(ss[t].loc);
    }
    for (int32_t i = 0; lists && i < GD_BATCH; i++) free(lists[i].r);
    free(ws), free(ss), free(lists), free(rcs), free(errs);
    return rc;
}

/* The system over the unknowns: texels of positive mass. */
typedef struct gd_system {
    sc_seam_grid g;
    int32_t n;
    int32_t *texel;            /* n: grid id of each unknown */
    int32_t *unknown;          /* W * H: unknown of each texel, or -1 */
    sc_sparse mat[GD_NMAT];    /* mass, stiffness, labelled stiffness (upper CSC) */
    double area;               /* surface area of the material's faces */
    int threads;               /* the solver's parallel loops */
} gd_system;

static void system_free(gd_system *y) {
    free(y->texel), free(y->unknown);
    for (int k = 0; k < GD_NMAT; k++) sc_sparse_free(&y->mat[k]);
    memset(y, 0, sizeof *y);
}

static int system_build(gd_walk *w, const sc_image_data *labels, int threads, gd_system *y, sc_error *err) {
    memset(y, 0, sizeof *y);
    y->g = w->g;
    size_t np = (size_t)w->g.width * (size_t)w->g.height;
    gd_asm s = {.g = &w->g, .labels = labels, .nmat = labels ? 3 : 2, .cap = 64, .cell_face = -1};
    int rc = SC_ENOMEM;
    for (int k = 0; k < GD_NMAT; k++) sc_triplets_init(&s.extra[k], (int32_t)np);
    for (int k = 0; k < s.nmat; k++)
        if (!(s.st[k] = sc_calloc_array(np * 5, sizeof(double)))) goto done;
    s.tid = sc_alloc_array((size_t)s.cap, sizeof *s.tid);
    s.loc = sc_alloc_array((size_t)GD_NMAT * s.cap * s.cap, sizeof *s.loc);
    if (!s.tid || !s.loc) goto done;
    rc = assemble(w, &s, threads, err);
    if (rc != SC_OK) goto done;
    rc = SC_ENOMEM;
    for (int k = 0; k < s.nmat; k++)
        if (s.extra[k].failed) goto done;
    /* unknowns: mass on the diagonal above 1e-12 of the largest */
    double dmax = 0;
    for (size_t t = 0; t < np; t++) dmax = fmax(dmax, s.st[0][t * 5]);
    y->unknown = sc_alloc_array(np, sizeof *y->unknown);
    if (!y->unknown) goto done;
    for (size_t t = 0; t < np; t++) y->unknown[t] = dmax > 0 && s.st[0][t * 5] > 1e-12 * dmax ? y->n++ : -1;
    y->texel = sc_alloc_array((size_t)y->n + 1, sizeof *y->texel);
    if (!y->texel) goto done;
    for (size_t t = 0; t < np; t++)
        if (y->unknown[t] >= 0) y->texel[y->unknown[t]] = (int32_t)t;
    int32_t W = w->g.width, H = w->g.height;
    for (int k = 0; k < s.nmat; k++) {
        sc_triplets t;
        sc_triplets_init(&t, y->n);
        if (!sc_triplets_reserve(&t, (size_t)y->n * 5 + s.extra[k].count)) {
            sc_triplets_free(&t);
            goto done;
        }
        for (int32_t i = 0; i < y->n; i++) {
            int32_t id = y->texel[i], x = id % W, yy = id / W;
            for (int sl = 0; sl < 5; sl++) {
                int32_t x2 = x + slot_dx[sl], y2 = yy + slot_dy[sl];
                if (x2 < 0 || x2 >= W || y2 >= H) continue;
                int32_t j = y->unknown[(size_t)y2 * W + x2];
                double v = s.st[k][(size_t)id * 5 + sl];
                if (j >= 0 && v != 0) sc_triplets_add(&t, i, j, v);
            }
        }
        for (size_t e = 0; e < s.extra[k].count; e++) {
            int32_t i = y->unknown[s.extra[k].row[e]], j = y->unknown[s.extra[k].col[e]];
            if (i >= 0 && j >= 0) sc_triplets_add(&t, i, j, s.extra[k].val[e]);
        }
        rc = sc_sparse_from_triplets(&t, &y->mat[k], err);
        sc_triplets_free(&t);
        if (rc != SC_OK) goto done;
    }
    /* the surface area: the sum of the mass matrix */
    y->area = 0;
    for (int64_t e = 0; e < y->mat[0].nnz; e++) y->area += y->mat[0].val[e];
    for (int32_t j = 0; j < y->n; j++)
        for (int32_t e = y->mat[0].colptr[j]; e < y->mat[0].colptr[j + 1]; e++)
            if (y->mat[0].rowind[e] != j) y->area += y->mat[0].val[e];
    rc = SC_OK;
done:
    for (int k = 0; k < GD_NMAT; k++) free(s.st[k]), sc_triplets_free(&s.extra[k]);
    free(s.tid), free(s.loc);
    if (rc == SC_ENOMEM) sc_fail(err, SC_ENOMEM, "out of memory");
    if (rc != SC_OK) system_free(y);
    return rc;
}

/* ================================================================ multigrid */

/* a sparse matrix by rows (a full symmetric one reads the same by columns) */
typedef struct gd_csr {
    int32_t rows, cols;
    int32_t *ptr, *col;
    double *val;
} gd_csr;

static void csr_free(gd_csr *a) {
    free(a->ptr), free(a->col), free(a->val);
    memset(a, 0, sizeof *a);
}

static void sort_row(int32_t *col, double *val, int32_t n) {
    for (int32_t i = 1; i < n; i++) {
        int32_t c = col[i], j = i;
        double v = val[i];
        while (j > 0 && col[j - 1] > c) col[j] = col[j - 1], val[j] = val[j - 1], j--;
        col[j] = c, val[j] = v;
    }
}

/* C = PT A P in one pass over the coarse rows (PT = P^T), without the
 * intermediate A P: coarse row I gathers PT(I,i) A(i,j) P(j,J) */
static int csr_galerkin(const gd_csr *pt, const gd_csr *a, const gd_csr *p, gd_csr *c) {
    memset(c, 0, sizeof *c);
    c->rows = pt->rows, c->cols = p->cols;
    size_t cap = (size_t)pt->rows * 12 + 16, nnz = 0;
    int32_t *mark = sc_alloc_array((size_t)p->cols + 1, sizeof *mark), *pos = sc_alloc_array((size_t)p->cols + 1, sizeof *pos);
    c->ptr = sc_calloc_array((size_t)pt->rows + 1, sizeof *c->ptr);
    c->col = sc_alloc_array(cap, sizeof *c->col);
    c->val = sc_alloc_array(cap, sizeof *c->val);
    if (!mark || !pos || !c->ptr || !c->col || !c->val) goto oom;
    for (int32_t j = 0; j < p->cols; j++) mark[j] = -1;
    for (int32_t I = 0; I < pt->rows; I++) {
        size_t start = nnz;
        for (int32_t et = pt->ptr[I]; et < pt->ptr[I + 1]; et++) {
            int32_t i = pt->col[et];
            double vt = pt->val[et];
            for (int32_t ea = a->ptr[i]; ea < a->ptr[i + 1]; ea++) {
                int32_t j = a->col[ea];
                double va = vt * a->val[ea];
                for (int32_t ep = p->ptr[j]; ep < p->ptr[j + 1]; ep++) {
                    int32_t J = p->col[ep];
                    if (mark[J] == I) {
                        c->val[pos[J]] += va * p->val[ep];
                        continue;
                    }
                    if (nnz == cap) {
                        cap *= 2;
                        int32_t *nc = sc_realloc_array(c->col, cap, sizeof *nc);
                        if (nc) c->col = nc;
                        double *nv = sc_realloc_array(c->val, cap, sizeof *nv);
                        if (nv) c->val = nv;
                        if (!nc || !nv) goto oom;
                    }
                    mark[J] = I, pos[J] = (int32_t)nnz;
                    c->col[nnz] = J, c->val[nnz] = va * p->val[ep], nnz++;
                }
            }
        }
        sort_row(c->col + start, c->val + start, (int32_t)(nnz - start));
        if (nnz > INT32_MAX) goto oom;
        c->ptr[I + 1] = (int32_t)nnz;
    }
    free(mark), free(pos);
    return 0;
oom:
    free(mark), free(pos), csr_free(c);
    return -1;
}

static int csr_transpose(const gd_csr *a, gd_csr *t) {
    memset(t, 0, sizeof *t);
    t->rows = a->cols, t->cols = a->rows;
    int32_t nnz = a->ptr[a->rows];
    t->ptr = sc_calloc_array((size_t)t->rows + 2, sizeof *t->ptr);
    t->col = sc_alloc_array((size_t)nnz + 1, sizeof *t->col);
    t->val = sc_alloc_array((size_t)nnz + 1, sizeof *t->val);
    if (!t->ptr || !t->col || !t->val) {
        csr_free(t);
        return -1;
    }
    for (int32_t e = 0; e < nnz; e++) t->ptr[a->col[e] + 2]++;
    for (int32_t j = 0; j < t->rows; j++) t->ptr[j + 2] += t->ptr[j + 1];
    for (int32_t i = 0; i < a->rows; i++)
        for (int32_t e = a->ptr[i]; e < a->ptr[i + 1]; e++) {
            int32_t k = t->ptr[a->col[e] + 1]++;
            t->col[k] = i, t->val[k] = a->val[e];
        }
    return 0;
}

/* the upper triangle (CSC) of the full symmetric a on the rows with
 * keep[i] >= 0 (increasing; NULL: all) */
static int csr_upper(const gd_csr *a, const int32_t *keep, int32_t count, sc_sparse *out, sc_error *err) {
    memset(out, 0, sizeof *out);
    out->n = count;
    out->colptr = sc_calloc_array((size_t)count + 1, sizeof *out->colptr);
    out->rowind = sc_alloc_array((size_t)a->ptr[a->rows] + 1, sizeof *out->rowind);
    out->val = sc_alloc_array((size_t)a->ptr[a->rows] + 1, sizeof *out->val);
    if (!out->colptr || !out->rowind || !out->val) {
        sc_sparse_free(out);
        return sc_fail(err, SC_ENOMEM, "out of memory");
    }
    int32_t nnz = 0;
    for (int32_t j = 0; j < a->rows; j++) {
        int32_t kj = keep ? keep[j] : j;
        if (kj < 0) continue;
        for (int32_t e = a->ptr[j]; e < a->ptr[j + 1]; e++) {
            int32_t ki = keep ? keep[a->col[e]] : a->col[e];
            if (ki < 0 || ki > kj) continue;
            out->rowind[nnz] = ki, out->val[nnz] = a->val[e], nnz++;
        }
        out->colptr[kj + 1] = nnz;
    }
    out->nnz = nnz;
    return SC_OK;
}

/* Gauss-Seidel runs by strips of GD_STRIP rows: the even strips first, each
 * on a thread of its own (an interior texel's row reaches only the rows next
 * to it, so strips of one parity never read each other's texels), then the
 * odd ones; backwards, the reverse. The order is fixed by the grid, not by
 * the thread count, so the results are the same on any number of threads. */
#define GD_STRIP 32
#define GD_ROWS_CHUNK 16384   /* rows per chunk of a parallel matrix-vector product */

typedef struct gd_level {
    int32_t n, W, H;
    int32_t *x, *y;            /* grid coordinates of each unknown */
    gd_csr A;                  /* full symmetric */
    gd_csr P, PT;              /* prolongation from the next level, and its transpose */
    int32_t nb, *blist, *bidx; /* boundary unknowns, and each unknown's place among them (-1: interior) */
    int32_t ni, *ilist;        /* interior unknowns, relaxed (in row order) */
    int32_t nstrips, *istart;  /* strips of GD_STRIP rows: ilist[istart[s] .. istart[s + 1]) */
    sc_sparse_chol *f;         /* boundary block (the whole matrix on the coarsest level) */
    double *xv, *bv, *rv, *tmp;
    double *dinv;              /* 1 / the diagonal of A, per unknown */
} gd_level;

typedef struct gd_mg {
    int32_t nl, C;
    int threads;
    gd_level *lv;
} gd_mg;

static void mg_free(gd_mg *mg) {
    for (int32_t l = 0; l < mg->nl; l++) {
        gd_level *v = &mg->lv[l];
        free(v->x), free(v->y), csr_free(&v->A), csr_free(&v->P), csr_free(&v->PT);
        free(v->blist), free(v->bidx), free(v->ilist), free(v->istart), sc_sparse_chol_free(v->f);
        free(v->xv), free(v->bv), free(v->rv), free(v->tmp), free(v->dinv);
    }
    free(mg->lv);
    memset(mg, 0, sizeof *mg);
}

/* boundary and interior unknowns of a level, and the factor of its
 * boundary block (coarsest: of the whole matrix) */
static int level_split(gd_level *v, bool coarsest, sc_error *err) {
    int32_t *map = sc_alloc_array((size_t)v->W * v->H, sizeof *map);
    v->bidx = sc_alloc_array((size_t)v->n, sizeof *v->bidx);
    v->blist = sc_alloc_array((size_t)v->n + 1, sizeof *v->blist);
    v->ilist = sc_alloc_array((size_t)v->n + 1, sizeof *v->ilist);
    if (!map || !v->bidx || !v->blist || !v->ilist) {
        free(map);
        return sc_fail(err, SC_ENOMEM, "out of memory");
    }
    for (size_t t = 0; t < (size_t)v->W * v->H; t++) map[t] = -1;
    for (int32_t i = 0; i < v->n; i++) map[(size_t)v->y[i] * v->W + v->x[i]] = i;
    v->nb = v->ni = 0;
    for (int32_t i = 0; i < v->n; i++) {
        bool inner = !coarsest;
        for (int dy = -1; dy <= 1 && inner; dy++)
            for (int dx = -1; dx <= 1 && inner; dx++) {
                int32_t x = v->x[i] + dx, y = v->y[i] + dy;
                inner = x >= 0 && y >= 0 && x < v->W && y < v->H && map[(size_t)y * v->W + x] >= 0;
            }
        for (int32_t e = v->A.ptr[i]; e < v->A.ptr[i + 1] && inner; e++) {
            int32_t j = v->A.col[e];
            inner = abs(v->x[j] - v->x[i]) <= 1 && abs(v->y[j] - v->y[i]) <= 1;
        }
        if (inner) v->ilist[v->ni++] = i, v->bidx[i] = -1;
        else v->bidx[i] = v->nb, v->blist[v->nb++] = i;
    }
    free(map);
    v->dinv = sc_alloc_array((size_t)v->n + 1, sizeof *v->dinv);
    if (!v->dinv) return sc_fail(err, SC_ENOMEM, "out of memory");
    for (int32_t i = 0; i < v->n; i++) {
        v->dinv[i] = 0;
        for (int32_t e = v->A.ptr[i]; e < v->A.ptr[i + 1]; e++)
            if (v->A.col[e] == i && v->A.val[e] != 0) v->dinv[i] = 1 / v->A.val[e];
    }
    /* the interior by strips of rows (unknowns are numbered row by row) */
    v->nstrips = (v->H + GD_STRIP - 1) / GD_STRIP;
    v->istart = sc_alloc_array((size_t)v->nstrips + 1, sizeof *v->istart);
    if (!v->istart) return sc_fail(err, SC_ENOMEM, "out of memory");
    for (int32_t st = 0, k = 0; st <= v->nstrips; st++) {
        while (k < v->ni && v->y[v->ilist[k]] < st * GD_STRIP) k++;
        v->istart[st] = st == v->nstrips ? v->ni : k;
    }
    if (v->nb == 0) return SC_OK;
    sc_sparse up;
    int rc = csr_upper(&v->A, v->bidx, v->nb, &up, err);
    if (rc != SC_OK) return rc;
    rc = sc_sparse_chol_factor(&up, NULL, &v->f, err);
    sc_sparse_free(&up);
    return rc;
}

/* the next level: every other texel, bilinear prolongation, P^T A P */
static int level_coarsen(gd_level *v, gd_level *c, sc_error *err) {
    c->W = v->W / 2 + 1, c->H = v->H / 2 + 1;
    int32_t *cmap = sc_alloc_array((size_t)c->W * c->H, sizeof *cmap);
    if (!cmap) return sc_fail(err, SC_ENOMEM, "out of memory");
    for (size_t t = 0; t < (size_t)c->W * c->H; t++) cmap[t] = -1;
    for (int32_t i = 0; i < v->n; i++)
        for (int32_t Y = v->y[i] / 2; Y <= (v->y[i] + 1) / 2; Y++)
            for (int32_t X = v->x[i] / 2; X <= (v->x[i] + 1) / 2; X++) cmap[(size_t)Y * c->W + X] = 0;
    c->n = 0;
    for (size_t t = 0; t < (size_t)c->W * c->H; t++)
        if (cmap[t] == 0) cmap[t] = c->n++;
    c->x = sc_alloc_array((size_t)c->n + 1, sizeof *c->x);
    c->y = sc_alloc_array((size_t)c->n + 1, sizeof *c->y);
    gd_csr *P = &v->P;
    P->rows = v->n, P->cols = c->n;
    P->ptr = sc_calloc_array((size_t)v->n + 1, sizeof *P->ptr);
    P->col = sc_alloc_array((size_t)v->n * 4, sizeof *P->col);
    P->val = sc_alloc_array((size_t)v->n * 4, sizeof *P->val);
    if (!c->x || !c->y || !P->ptr || !P->col || !P->val) {
        free(cmap);
        return sc_fail(err, SC_ENOMEM, "out of memory");
    }
    for (size_t t = 0; t < (size_t)c->W * c->H; t++)
        if (cmap[t] >= 0) c->x[cmap[t]] = (int32_t)(t % c->W), c->y[cmap[t]] = (int32_t)(t / c->W);
    int32_t nnz = 0;
    for (int32_t i = 0; i < v->n; i++) {
        int32_t x = v->x[i], y = v->y[i];
        double wx = x % 2 ? 0.5 : 1.0, wy = y % 2 ? 0.5 : 1.0;
        int32_t s = nnz;
        for (int32_t Y = y / 2; Y <= (y + 1) / 2; Y++)
            for (int32_t X = x / 2; X <= (x + 1) / 2; X++)
                P->col[nnz] = cmap[(size_t)Y * c->W + X], P->val[nnz] = wx * wy, nnz++;
        sort_row(P->col + s, P->val + s, nnz - s);
        P->ptr[i + 1] = nnz;
    }
    free(cmap);
    if (csr_transpose(P, &v->PT) || csr_galerkin(&v->PT, &v->A, P, &c->A)) return sc_fail(err, SC_ENOMEM, "out of memory");
    return SC_OK;
}

/* the hierarchy for A (consumed: freed once its full copy is made, also on failure) */
static int mg_build(sc_sparse *A, const gd_system *y, int32_t levels, int32_t C, gd_mg *mg, sc_error *err) {
    memset(mg, 0, sizeof *mg);
    if (levels < 1) levels = 1;
    mg->lv = sc_calloc_array((size_t)levels, sizeof *mg->lv);
    if (!mg->lv) {
        sc_sparse_free(A);
        return sc_fail(err, SC_ENOMEM, "out of memory");
    }
    mg->C = C;
    mg->threads = y->threads;
    gd_level *v = &mg->lv[0];
    mg->nl = 1;
    v->n = y->n, v->W = y->g.width, v->H = y->g.height;
    v->x = sc_alloc_array((size_t)v->n + 1, sizeof *v->x);
    v->y = sc_alloc_array((size_t)v->n + 1, sizeof *v->y);
    sc_sparse full;
    int rc = sc_sparse_full(A, &full, err);
    sc_sparse_free(A);
    if (rc != SC_OK) goto fail;
    v->A = (gd_csr){.rows = full.n, .cols = full.n, .ptr = full.colptr, .col = full.rowind, .val = full.val};
    rc = SC_ENOMEM;
    if (!v->x || !v->y) goto fail;
    for (int32_t i = 0; i < v->n; i++) v->x[i] = y->texel[i] % v->W, v->y[i] = y->texel[i] / v->W;
    for (int32_t l = 0;; l++) {
        v = &mg->lv[l];
        bool coarsest = l == levels - 1 || v->n <= 1024;
        rc = level_split(v, coarsest, err);
        if (rc != SC_OK) goto fail;
        size_t nc = (size_t)v->n * (size_t)C + 1;
        v->xv = sc_calloc_array(nc, sizeof(double));
        v->bv = sc_calloc_array(nc, sizeof(double));
        v->rv = sc_calloc_array(nc, sizeof(double));
        v->tmp = sc_calloc_array(nc, sizeof(double));
        rc = SC_ENOMEM;
        if (!v->xv || !v->bv || !v->rv || !v->tmp) goto fail;
        if (coarsest) break;
        mg->nl++;
        rc = level_coarsen(v, &mg->lv[l + 1], err);
        if (rc != SC_OK) goto fail;
    }
    return SC_OK;
fail:
    if (rc == SC_ENOMEM) sc_fail(err, SC_ENOMEM, "out of memory");
    mg_free(mg);
    return rc;
}

/* fn(ud, chunk) for chunk in [0, n) on `threads` threads; in order on this
 * one when no thread (nor the bookkeeping) can be had: every chunk's work is
 * independent of the others and of the thread that runs it */
static void gd_for(int threads, int32_t n, int (*fn)(void *ud, int32_t chunk), void *ud) {
    if (threads > 1 && n > 1 && sc_parallel(threads, n, fn, ud) == SC_OK) return;
    for (int32_t c = 0; c < n; c++) fn(ud, c);
}

typedef struct gd_relax_job {
    gd_level *v;
    int32_t C, parity;
    bool backwards;
} gd_relax_job;

/* Gauss-Seidel over strip 2 * chunk + parity of the interior unknowns,
 * forwards or (after the coarse correction, which keeps the V-cycle
 * symmetric) backwards: x_i += (b_i - A_i x) / a_ii. Three channels (colour)
 * have a loop of their own, the same arithmetic unrolled. */
static int relax_strip(void *ud, int32_t chunk) {
    const gd_relax_job *j = ud;
    gd_level *v = j->v;
    int32_t C = j->C, st = 2 * chunk + j->parity;
    if (st >= v->nstrips) return SC_OK;
    int32_t k0 = v->istart[st], k1 = v->istart[st + 1];
    const int32_t *ptr = v->A.ptr, *col = v->A.col;
    const double *val = v->A.val, *b = v->bv, *dinv = v->dinv;
    double *x = v->xv;
    for (int32_t kk = 0; kk < k1 - k0; kk++) {
        int32_t i = v->ilist[j->backwards ? k1 - 1 - kk : k0 + kk];
        if (C == 3) {
            double s0 = b[3 * (size_t)i], s1 = b[3 * (size_t)i + 1], s2 = b[3 * (size_t)i + 2];
            for (int32_t e = ptr[i]; e < ptr[i + 1]; e++) {
                const double a = val[e], *xj = x + 3 * (size_t)col[e];
                s0 -= a * xj[0], s1 -= a * xj[1], s2 -= a * xj[2];
            }
            double d = dinv[i];
            x[3 * (size_t)i] += s0 * d, x[3 * (size_t)i + 1] += s1 * d, x[3 * (size_t)i + 2] += s2 * d;
            continue;
        }
        double acc[4] = {0, 0, 0, 0};
        for (int32_t c = 0; c < C; c++) acc[c] = b[(size_t)i * C + c];
        for (int32_t e = ptr[i]; e < ptr[i + 1]; e++)
            for (int32_t c = 0; c < C; c++) acc[c] -= val[e] * x[(size_t)col[e] * C + c];
        for (int32_t c = 0; c < C; c++) x[(size_t)i * C + c] += acc[c] * dinv[i];
    }
    return SC_OK;
}

static void relax(gd_level *v, int32_t C, int32_t sweeps, bool backwards, int threads) {
    for (int32_t s = 0; s < sweeps; s++)
        for (int pass = 0; pass < 2; pass++) {
            gd_relax_job j = {v, C, backwards ? 1 - pass : pass, backwards};
            gd_for(threads, (v->nstrips + 1) / 2, relax_strip, &j);
        }
}

/* x_b = A_bb^-1 (b_b - A_bi x_i) (coarsest: x = A^-1 b) */
static int boundary_solve(gd_level *v, int32_t C, sc_error *err) {
    if (v->nb == 0) return SC_OK;
    for (int32_t k = 0; k < v->nb; k++) {
        int32_t i = v->blist[k];
        for (int32_t c = 0; c < C; c++) {
            double s = v->bv[(size_t)i * C + c];
            for (int32_t e = v->A.ptr[i]; e < v->A.ptr[i + 1]; e++) {
                int32_t j = v->A.col[e];
                if (v->bidx[j] < 0) s -= v->A.val[e] * v->xv[(size_t)j * C + c];
            }
            v->tmp[(size_t)c * v->nb + k] = s;
        }
    }
    int rc = sc_sparse_chol_solve(v->f, C, v->tmp, err);
    if (rc != SC_OK) return rc;
    for (int32_t k = 0; k < v->nb; k++)
        for (int32_t c = 0; c < C; c++) v->xv[(size_t)v->blist[k] * C + c] = v->tmp[(size_t)c * v->nb + k];
    return SC_OK;
}

typedef struct gd_rows_job {
    const gd_csr *M;
    int32_t C;
    const double *b, *x;  /* residual: r = b - M x; product: y = M x (+ y when add) */
    double *out;
    bool residual, add;
} gd_rows_job;

static int rows_chunk(void *ud, int32_t chunk) {
    const gd_rows_job *j = ud;
    const gd_csr *M = j->M;
    int32_t C = j->C, i0 = chunk * GD_ROWS_CHUNK, i1 = i0 + GD_ROWS_CHUNK < M->rows ? i0 + GD_ROWS_CHUNK : M->rows;
    for (int32_t i = i0; i < i1; i++) {
        double acc[4] = {0, 0, 0, 0};
        if (C == 3) {
            double a0 = 0, a1 = 0, a2 = 0;
            for (int32_t e = M->ptr[i]; e < M->ptr[i + 1]; e++) {
                const double a = M->val[e], *xj = j->x + 3 * (size_t)M->col[e];
                a0 += a * xj[0], a1 += a * xj[1], a2 += a * xj[2];
            }
            acc[0] = a0, acc[1] = a1, acc[2] = a2;
        } else {
            for (int32_t e = M->ptr[i]; e < M->ptr[i + 1]; e++)
                for (int32_t c = 0; c < C; c++) acc[c] += M->val[e] * j->x[(size_t)M->col[e] * C + c];
        }
        for (int32_t c = 0; c < C; c++) {
            size_t at = (size_t)i * C + c;
            j->out[at] = j->residual ? j->b[at] - acc[c] : j->add ? j->out[at] + acc[c] : acc[c];
        }
    }
    return SC_OK;
}

static int32_t row_chunks(const gd_csr *M) { return (M->rows + GD_ROWS_CHUNK - 1) / GD_ROWS_CHUNK; }

/* r = b - A x for C interleaved channels */
static void residual(const gd_csr *A, int32_t C, const double *b, const double *x, double *r, int threads) {
    gd_rows_job j = {A, C, b, x, r, true, false};
    gd_for(threads, row_chunks(A), rows_chunk, &j);
}

/* y = M x for a row matrix and C interleaved channels (add: y += M x) */
static void csr_apply(const gd_csr *M, int32_t C, const double *x, double *y, bool add, int threads) {
    gd_rows_job j = {M, C, NULL, x, y, false, add};
    gd_for(threads, row_chunks(M), rows_chunk, &j);
}

/* Fig. 8: relax the interior, solve the boundary, restrict the residual,
 * recurse, prolong the correction, solve the boundary, relax the interior
 * (in the reverse order: the cycle is a symmetric operator) */
static int vcycle(gd_mg *mg, int32_t l, int32_t sweeps, sc_error *err) {
    gd_level *v = &mg->lv[l];
    int32_t C = mg->C;
    if (l == mg->nl - 1) return boundary_solve(v, C, err);
    relax(v, C, sweeps, false, mg->threads);
    int rc = boundary_solve(v, C, err);
    if (rc != SC_OK) return rc;
    residual(&v->A, C, v->bv, v->xv, v->rv, mg->threads);
    gd_level *c = &mg->lv[l + 1];
    csr_apply(&v->PT, C, v->rv, c->bv, false, mg->threads);
    memset(c->xv, 0, (size_t)c->n * C * sizeof(double));
    rc = vcycle(mg, l + 1, sweeps, err);
    if (rc != SC_OK) return rc;
    csr_apply(&v->P, C, c->xv, v->xv, true, mg->threads);
    rc = boundary_solve(v, C, err);
    if (rc != SC_OK) return rc;
    relax(v, C, sweeps, true, mg->threads);
    return SC_OK;
}

static double norm2(const double *a, size_t n) {
    double s = 0;
    for (size_t i = 0; i < n; i++) s += a[i] * a[i];
    return sqrt(s);
}

/* ================================================================ solving */

static void metric(sc_metric_list *ml, const char *fmt, const char *name, double value) {
    char key[96];
    snprintf(key, sizeof key, fmt, name);
    sc_metric_list_add(ml, key, value);
}

static void vcycle_metric(sc_metric_list *ml, const char *name, int32_t k, double rel) {
    char key[96];
    snprintf(key, sizeof key, "%s_vcycle_%d_residual", name, (int)k);
    sc_metric_list_add(ml, key, rel);
}

/* the finest level's xv = one V-cycle applied to its bv from a zero guess
 * (a V-cycle reads the finest bv and leaves it as it is) */
static int precondition(gd_mg *mg, int32_t sweeps, sc_error *err) {
    gd_level *v = &mg->lv[0];
    memset(v->xv, 0, (size_t)v->n * (size_t)mg->C * sizeof *v->xv);
    return vcycle(mg, 0, sweeps, err);
}

static void dot_channels(int32_t C, int32_t n, const double *a, const double *b, double out[4]) {
    for (int32_t c = 0; c < C; c++) out[c] = 0;
    for (int32_t i = 0; i < n; i++)
        for (int32_t c = 0; c < C; c++) out[c] += a[(size_t)i * C + c] * b[(size_t)i * C + c];
}

/* A x = b for C interleaved channels; x holds the initial guess (multigrid).
 * A is consumed (freed as soon as the factor or the hierarchy holds it). */
static int solve(sc_sparse *A, const gd_system *y, const sc_gradient_options *o, int32_t C, const double *b,
                 double *x, const char *name, sc_metric_list *ml, int32_t *vcycles, sc_error *err) {
    size_t nn = (size_t)y->n * (size_t)C;
    if (o->solver == SC_GRADIENT_DIRECT) {
        sc_sparse_chol *f = NULL;
        double *cm = sc_alloc_array(nn + 1, sizeof *cm);
        if (!cm) return sc_fail(err, SC_ENOMEM, "out of memory");
        int rc = sc_sparse_chol_factor(A, NULL, &f, err);
        sc_sparse_free(A);
        if (rc == SC_OK) {
            for (int32_t i = 0; i < y->n; i++)
                for (int32_t c = 0; c < C; c++) cm[(size_t)c * y->n + i] = b[(size_t)i * C + c];
            rc = sc_sparse_chol_solve(f, C, cm, err);
        }
        if (rc == SC_OK)
            for (int32_t i = 0; i < y->n; i++)
                for (int32_t c = 0; c < C; c++) x[(size_t)i * C + c] = cm[(size_t)c * y->n + i];
        sc_sparse_chol_free(f), free(cm);
        return rc;
    }
    gd_mg mg;
    int rc = mg_build(A, y, o->levels, C, &mg, err);
    if (rc != SC_OK) return rc;
    gd_level *v = &mg.lv[0];
    double bn = norm2(b, nn), rel = 1;
    int32_t k = 0;
    metric(ml, "%s_levels", name, mg.nl);
    metric(ml, "%s_boundary_texels", name, v->nb);
    double *p = NULL, *q = NULL;
    if (bn == 0) {
        memset(x, 0, nn * sizeof *x);
        rel = 0;
    } else if (o->solver == SC_GRADIENT_VCYCLES) {
        memcpy(v->bv, b, nn * sizeof *b);
        memcpy(v->xv, x, nn * sizeof *x);
        while (rel > o->tolerance && k < o->max_vcycles && rc == SC_OK) {
            rc = vcycle(&mg, 0, o->relaxations, err);
            residual(&v->A, C, v->bv, v->xv, v->rv, mg.threads);
            rel = norm2(v->rv, nn) / bn;
            vcycle_metric(ml, name, ++k, rel);
        }
        memcpy(x, v->xv, nn * sizeof *x);
    } else {
        /* conjugate gradients, one V-cycle (a symmetric operator) as the
         * preconditioner; the residual r lives in the finest level's bv and
         * the preconditioned z in its xv, which the V-cycle reads and writes */
        double *r = v->bv, *z = v->xv;
        p = sc_alloc_array(nn, sizeof *p), q = sc_alloc_array(nn, sizeof *q);
        if (!p || !q) rc = sc_fail(err, SC_ENOMEM, "out of memory");
        double rz[4] = {0, 0, 0, 0};
        if (rc == SC_OK) {
            residual(&v->A, C, b, x, r, mg.threads);
            rel = norm2(r, nn) / bn;
            rc = precondition(&mg, o->relaxations, err);
            memcpy(p, z, nn * sizeof *z);
            dot_channels(C, y->n, r, z, rz);
        }
        while (rc == SC_OK && rel > o->tolerance && k < o->max_vcycles) {
            double pq[4] = {0, 0, 0, 0}, rz1[4] = {0, 0, 0, 0};
            csr_apply(&v->A, C, p, q, false, mg.threads);
            dot_channels(C, y->n, p, q, pq);
            for (size_t i = 0; i < nn; i++) {
                double alpha = pq[i % C] > 0 ? rz[i % C] / pq[i % C] : 0;
                x[i] += alpha * p[i], r[i] -= alpha * q[i];
            }
            rel = norm2(r, nn) / bn;
            vcycle_metric(ml, name, ++k, rel);
            if (rel <= o->tolerance || k == o->max_vcycles) break;
            rc = precondition(&mg, o->relaxations, err);
            dot_channels(C, y->n, r, z, rz1);
            for (size_t i = 0; i < nn; i++) p[i] = z[i] + (rz[i % C] > 0 ? rz1[i % C] / rz[i % C] : 0) * p[i];
            memcpy(rz, rz1, sizeof rz);
        }
    }
    free(p), free(q);
    if (rc == SC_OK) {
        metric(ml, "%s_vcycles", name, k);
        metric(ml, "%s_residual", name, rel);
        if (*vcycles < k) *vcycles = k;
    }
    mg_free(&mg);
    return rc;
}

/* ================================================================ operations */

/* y = A x, one channel at a time, for C interleaved channels */
static int symv_channels(const sc_sparse *A, int32_t C, const double *x, double *y, double scale, bool add) {
    int32_t n = A->n;
    double *in = sc_alloc_array((size_t)n + 1, sizeof *in), *out = sc_alloc_array((size_t)n + 1, sizeof *out);
    if (!in || !out) {
        free(in), free(out);
        return -1;
    }
    for (int32_t c = 0; c < C; c++) {
        for (int32_t i = 0; i < n; i++) in[i] = x[(size_t)i * C + c];
        sc_sparse_symv(A, in, out);
        for (int32_t i = 0; i < n; i++) {
            double *d = &y[(size_t)i * C + c];
            *d = (add ? *d : 0) + scale * out[i];
        }
    }
    free(in), free(out);
    return 0;
}

/* geodesic: the divergence of X = -du/|du| against every texel function,
 * X constant per element (taken at its centroid) */
typedef struct gd_div {
    const gd_system *y;
    const double *u;
    double *div;
} gd_div;

static double node_value(const gd_div *d, const gd_node *nd) {
    double s = 0;
    for (int32_t t = 0; t < nd->n; t++) {
        int32_t k = d->y->unknown[nd->id[t]];
        if (k >= 0) s += nd->w[t] * d->u[k];
    }
    return s;
}

static int div_visit(void *ud, const gd_piece *p, sc_error *err) {
    (void)err;
    gd_div *d = ud;
    for (int32_t e = 0; e < p->m; e++) {
        double c[3][2], dl[3][2], dN[6][2], uv[6];
        const gd_node *nd[6];
        piece_element(p, e, c, nd);
        double a2 = bary_grad(c, dl);
        if (!(fabs(a2) > 1e-300)) continue;
        static const double mid[3] = {1.0 / 3, 1.0 / 3, 1.0 / 3};
        p2_grads(mid, dl, dN);
        double gu[2] = {0, 0};
        for (int a = 0; a < 6; a++) {
            uv[a] = node_value(d, nd[a]);
            gu[0] += uv[a] * dN[a][0], gu[1] += uv[a] * dN[a][1];
        }
        double len = sqrt(gdot(p->ginv, gu, gu));
        if (!(len > 0)) continue;
        double X[2] = {-gu[0] / len, -gu[1] / len};
        double area = 0.5 * fabs(a2) * p->sqrtdet;
        for (int q = 0; q < 6; q++) {
            p2_grads(quad_l[q], dl, dN);
            for (int a = 0; a < 6; a++) {
                double s = quad_w[q] * area * gdot(p->ginv, dN[a], X);
                for (int32_t t = 0; t < nd[a]->n; t++) {
                    int32_t k = d->y->unknown[nd[a]->id[t]];
                    if (k >= 0) d->div[k] += nd[a]->w[t] * s;
                }
            }
        }
    }
    return SC_OK;
}

/* the sources: unit weights spread on texels by bilinear taps (delta[n]);
 * taps[]/tapw[] keep each source's taps to read distances back */
typedef struct gd_source {
    int32_t id[4];
    double w[4];
} gd_source;

static int parse_sources(const sc_mesh *m, int32_t material, const gd_system *y, const char *text, gd_source **out,
                         int32_t *count, sc_error *err) {
    *out = NULL, *count = 0;
    size_t len = strlen(text);
    gd_source *s = sc_calloc_array(len / 2 + 2, sizeof *s);
    if (!s) return sc_fail(err, SC_ENOMEM, "out of memory");
    const char *p = text;
    while (*p) {
        const char *end = strchr(p, ';');
        size_t n = end ? (size_t)(end - p) : strlen(p);
        char item[256];
        if (n >= sizeof item) n = sizeof item - 1;
        memcpy(item, p, n);
        item[n] = 0;
        p += n + (end ? 1 : 0);
        char *q = item;
        while (*q == ' ') q++;
        if (!*q) continue;
        gd_source *src = &s[*count];
        int i, j, used = 0;
        double X[3];
        if (sscanf(q, "texel %d %d %n", &i, &j, &used) == 2 && q[used] == 0) {
            if (i < 0 || j < 0 || i >= y->g.width || j >= y->g.height) {
                free(s);
                return sc_fail(err, SC_EINPUT, "sources: texel %d %d is outside the %dx%d texture", i, j,
                               (int)y->g.width, (int)y->g.height);
            }
            src->id[0] = j * y->g.width + i, src->w[0] = 1;
            src->id[1] = src->id[2] = src->id[3] = src->id[0];
        } else if (sscanf(q, "%lf %lf %lf %n", &X[0], &X[1], &X[2], &used) == 3 && q[used] == 0) {
            int32_t best = -1;
            double bd = INFINITY;
            for (int32_t f = 0; f < m->nf; f++) {
                if (material >= 0 && m->FM[f] != material) continue;
                for (int k = 0; k < 3; k++) {
                    const double *V = m->V + 3 * (size_t)m->FV[3 * f + k];
                    double dd = (V[0] - X[0]) * (V[0] - X[0]) + (V[1] - X[1]) * (V[1] - X[1]) + (V[2] - X[2]) * (V[2] - X[2]);
                    if (dd < bd) bd = dd, best = 3 * f + k;
                }
            }
            if (best < 0) {
                free(s);
                return sc_fail(err, SC_EINPUT, "sources: the material has no faces");
            }
            const double *uv = m->U + 2 * (size_t)m->FU[best];
            sc_seam_taps(&y->g, uv[0], uv[1], src->id, src->w);
        } else {
            free(s);
            return sc_fail(err, SC_EINPUT, "sources: '%s' is neither \"x y z\" nor \"texel i j\"", q);
        }
        (*count)++;
    }
    if (*count == 0) {
        free(s);
        return sc_fail(err, SC_EINPUT, "geodesic: no sources given");
    }
    *out = s;
    return SC_OK;
}

static int run_geodesic(const sc_mesh *mesh, int32_t material, gd_walk *w, const gd_system *y,
                        const sc_gradient_options *o, double *dist, sc_metric_list *ml, int32_t *vcycles, sc_error *err) {
    gd_source *src;
    int32_t ns;
    int rc = parse_sources(mesh, material, y, o->sources, &src, &ns, err);
    if (rc != SC_OK) return rc;
    size_t n = (size_t)y->n;
    double *delta = sc_calloc_array(n + 1, sizeof *delta), *b = sc_calloc_array(n + 1, sizeof *b);
    double *u = sc_calloc_array(n + 1, sizeof *u);
    sc_sparse A = {0}, A2 = {0};
    if (!delta || !b || !u) goto oom;
    for (int32_t s = 0; s < ns; s++)
        for (int k = 0; k < 4; k++) {
            int32_t i = y->unknown[src[s].id[k]];
            if (i >= 0 && src[s].w[k] != 0) delta[i] += src[s].w[k];
        }
    double total = 0;
    for (size_t i = 0; i < n; i++) total += delta[i];
    if (!(total > 0)) {
        rc = sc_fail(err, SC_EINPUT, "sources: none lies on a texel of the charts");
        goto done;
    }
    /* (M + t S) u = M delta, t in unit-area units scaled to the surface.
     * u decays like exp(-d / sqrt(t)): with t much below the paper's 1e-3,
     * far texels fall under what a V-cycle's residual resolves and the
     * direction of du there is noise (docs/notes/gradient_domain.md). */
    double t = o->time_step * y->area;
    if (symv_channels(&y->mat[0], 1, delta, b, 1.0, false)) goto oom;
    if ((rc = sc_sparse_add(&y->mat[0], 1.0, &y->mat[1], t, &A, err)) != SC_OK) goto done;
    if ((rc = solve(&A, y, o, 1, b, u, "heat", ml, vcycles, err)) != SC_OK) goto done;
    /* S y = div X, screened by 1e-6 (unit area) to fix the constant */
    memset(b, 0, n * sizeof *b);
    gd_div d = {.y = y, .u = u, .div = b};
    if ((rc = walk_pieces(w, div_visit, &d, err)) != SC_OK) goto done;
    if ((rc = sc_sparse_add(&y->mat[1], 1.0, &y->mat[0], 1e-6 / y->area, &A2, err)) != SC_OK) goto done;
    memset(dist, 0, n * sizeof *dist);
    if ((rc = solve(&A2, y, o, 1, b, dist, "distance", ml, vcycles, err)) != SC_OK) goto done;
    /* distance 0 at the nearest source */
    double lo = INFINITY;
    for (int32_t s = 0; s < ns; s++) {
        double v = 0, ws = 0;
        for (int k = 0; k < 4; k++) {
            int32_t i = y->unknown[src[s].id[k]];
            if (i >= 0) v += src[s].w[k] * dist[i], ws += src[s].w[k];
        }
        if (ws > 0 && v / ws < lo) lo = v / ws;
    }
    if (isfinite(lo))
        for (size_t i = 0; i < n; i++) dist[i] -= lo;
    rc = SC_OK;
    goto done;
oom:
    rc = sc_fail(err, SC_ENOMEM, "out of memory");
done:
    free(src), free(delta), free(b), free(u);
    sc_sparse_free(&A), sc_sparse_free(&A2);
    return rc;
}

/* smooth, sharpen, stitch: (a M + S) x = a M x0 + beta S x0 (stitch: + S_same x0).
 * Once the right-hand side and the system matrix are formed, y's mass and
 * stiffness matrices are freed: nothing after the solve reads them, and the
 * hierarchy is built next, at the run's peak. */
static int run_filter(gd_system *y, const sc_gradient_options *o, int32_t C, const double *x0, double *x,
                      sc_metric_list *ml, int32_t *vcycles, sc_error *err) {
    double a = o->screening / y->area;
    size_t nn = (size_t)y->n * (size_t)C;
    double *b = sc_calloc_array(nn + 1, sizeof *b);
    sc_sparse A = {0};
    int rc = SC_ENOMEM;
    bool ok = b && !symv_channels(&y->mat[0], C, x0, b, a, false);
    if (ok && o->op == SC_GRADIENT_STITCH) ok = !symv_channels(&y->mat[2], C, x0, b, 1.0, true);
    else if (ok && o->gradient_scale != 0) ok = !symv_channels(&y->mat[1], C, x0, b, o->gradient_scale, true);
    if (!ok) rc = sc_fail(err, SC_ENOMEM, "out of memory");
    else if ((rc = sc_sparse_add(&y->mat[0], a, &y->mat[1], 1.0, &A, err)) == SC_OK) {
        for (int k = 0; k < GD_NMAT; k++) sc_sparse_free(&y->mat[k]);
        memcpy(x, x0, nn * sizeof *x);
        rc = solve(&A, y, o, C, b, x, op_names[o->op], ml, vcycles, err);
    }
    free(b), sc_sparse_free(&A);
    return rc;
}

static int seam_energy(const sc_mesh *m, const sc_seam_set *s, const sc_seam_grid *g, const sc_image_data *im,
                       int threads, const char *name, sc_metric_list *ml, double *energy, sc_error *err) {
    double gap = 0;
    int rc = sc_seam_energy(m, s, g, im, threads, energy, &gap, err);
    if (rc != SC_OK) return rc;
    metric(ml, "seam_energy_%s", name, *energy);
    metric(ml, "seam_max_gap_%s", name, gap);
    return SC_OK;
}

/* ================================================================ lic */

static int cmp_double(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

/* Per face of `material`, u_perp for lic: the direction of largest
 * |principal curvature| turned a quarter in the face's plane, scaled by
 * |k1 - k2| over its 90th percentile on the surface (capped at 1); the shape operator of each face is the
 * least-squares fit S e = dn over its three edges (e in the face's plane,
 * dn the change of the corner normals along it). NULL when out of memory. */
/* Per face, u_perp from a direction map (sc_gradient_options.lic_field):
 * the map at the face's uv centroid (bilinear, the grid's wrap modes),
 * projected into the face's plane, turned a quarter, length capped at 1. */
static double *lic_field_from_map(const sc_mesh *m, int32_t material, const sc_seam_grid *g,
                                  const sc_image_data *map) {
    double *out = sc_calloc_array(m->nf ? (size_t)m->nf * 3 : 1, sizeof *out);
    sc_image_data *f = sc_image_to_f32(map);
    if (!out || !f) {
        free(out), sc_image_free(f);
        return NULL;
    }
    bool is_signed = false;
    const float *px = f->pixels;
    for (size_t i = 0; i < (size_t)f->width * f->height * f->channels && !is_signed; i++) is_signed = px[i] < 0;
    sc_seam_grid mg = {f->width, f->height, g->wrap_u, g->wrap_v};
    for (int32_t fc = 0; fc < m->nf; fc++) {
        if (material >= 0 && m->FM[fc] != material) continue;
        double uv[2] = {0, 0}, v[4] = {0, 0, 0, 0}, e1[3], e2[3], n[3];
        const double *X0 = m->V + 3 * (size_t)m->FV[3 * fc], *X1 = m->V + 3 * (size_t)m->FV[3 * fc + 1],
                     *X2 = m->V + 3 * (size_t)m->FV[3 * fc + 2];
        for (int k = 0; k < 3; k++)
            for (int d = 0; d < 2; d++) uv[d] += m->U[2 * (size_t)m->FU[3 * fc + k] + d] / 3;
        sc_seam_sample(&mg, f->pixels, f->channels, uv[0], uv[1], v);
        if (!is_signed)
            for (int d = 0; d < 3; d++) v[d] = 2 * v[d] - 1;
        for (int d = 0; d < 3; d++) e1[d] = X1[d] - X0[d], e2[d] = X2[d] - X0[d];
        n[0] = e1[1] * e2[2] - e1[2] * e2[1], n[1] = e1[2] * e2[0] - e1[0] * e2[2], n[2] = e1[0] * e2[1] - e1[1] * e2[0];
        double ln = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
        if (!(ln > 0)) continue;
        for (int d = 0; d < 3; d++) n[d] /= ln;
        double p = v[0] * n[0] + v[1] * n[1] + v[2] * n[2];
        for (int d = 0; d < 3; d++) v[d] -= p * n[d];
        double l = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]), k = l > 1 ? 1 / l : 1;
        out[3 * (size_t)fc] = k * (n[1] * v[2] - n[2] * v[1]);
        out[3 * (size_t)fc + 1] = k * (n[2] * v[0] - n[0] * v[2]);
        out[3 * (size_t)fc + 2] = k * (n[0] * v[1] - n[1] * v[0]);
    }
    sc_image_free(f);
    return out;
}

static double det3(const double A[3][3]) {
    return A[0][0] * (A[1][1] * A[2][2] - A[1][2] * A[2][1]) - A[0][1] * (A[1][0] * A[2][2] - A[1][2] * A[2][0]) +
           A[0][2] * (A[1][0] * A[2][1] - A[1][1] * A[2][0]);
}

static double *lic_field(const sc_mesh *m, int32_t material) {
    double *normals = sc_tangent_corner_normals(m);
    double *out = sc_calloc_array(m->nf ? (size_t)m->nf * 3 : 1, sizeof *out);
    double *aniso = sc_calloc_array(m->nf ? (size_t)m->nf : 1, sizeof *aniso);
    if (!normals || !out || !aniso) {
        free(normals), free(out), free(aniso);
        return NULL;
    }
    double top = 0;
    for (int32_t f = 0; f < m->nf; f++) {
        if (material >= 0 && m->FM[f] != material) continue;
        const double *X[3], *N[3];
        for (int k = 0; k < 3; k++) X[k] = m->V + 3 * (size_t)m->FV[3 * f + k], N[k] = normals + 9 * (size_t)f + 3 * k;
        double e1[3], nf[3], t1[3], t2[3];
        sc_sub3(X[1], X[0], e1);
        sc_triangle_normal(X[0], X[1], X[2], nf);
        double ln = sc_norm3(nf), l1 = sc_norm3(e1);
        if (!(ln > 0) || !(l1 > 0)) continue;
        for (int i = 0; i < 3; i++) nf[i] /= ln, t1[i] = e1[i] / l1;
        sc_cross3(nf, t1, t2);
        /* normal equations of  a ex + b ey = dnx,  b ex + c ey = dny  over the edges */
        double A[3][3] = {{0}}, r[3] = {0};
        for (int k = 0; k < 3; k++) {
            int i = (k + 1) % 3, j = (k + 2) % 3;
            double ex = 0, ey = 0, nx = 0, ny = 0;
            for (int d = 0; d < 3; d++) {
                double e = X[j][d] - X[i][d], dn = N[j][d] - N[i][d];
                ex += e * t1[d], ey += e * t2[d], nx += dn * t1[d], ny += dn * t2[d];
            }
            double row1[3] = {ex, ey, 0}, row2[3] = {0, ex, ey};
            for (int p = 0; p < 3; p++) {
                r[p] += row1[p] * nx + row2[p] * ny;
                for (int q = 0; q < 3; q++) A[p][q] += row1[p] * row1[q] + row2[p] * row2[q];
            }
        }
        double det = det3(A);
        if (!(fabs(det) > 1e-300)) continue;
        double sol[3];
        for (int c = 0; c < 3; c++) {   /* Cramer's rule */
            double B[3][3];
            memcpy(B, A, sizeof B);
            for (int p = 0; p < 3; p++) B[p][c] = r[p];
            sol[c] = det3(B) / det;
        }
        double a = sol[0], b = sol[1], c = sol[2];
        double mid = 0.5 * (a + c), rad = sqrt(0.25 * (a - c) * (a - c) + b * b);
        double theta = 0.5 * atan2(2 * b, a - c);   /* eigenvector of the larger eigenvalue mid + rad */
        if (fabs(mid - rad) > fabs(mid + rad)) theta += M_PI / 2;
        /* u = cos t1 + sin t2, u_perp = -sin t1 + cos t2 */
        for (int i = 0; i < 3; i++) out[3 * (size_t)f + i] = -sin(theta) * t1[i] + cos(theta) * t2[i];
        aniso[f] = 2 * rad;   /* |k1 - k2| */
        if (aniso[f] > top) top = aniso[f];
    }
    /* scaled by the 90th percentile of the faces' |k1 - k2| (the largest is
     * often one sharp feature's), capped at 1 */
    double *sorted = sc_alloc_array(m->nf ? (size_t)m->nf : 1, sizeof *sorted);
    int32_t ns = 0;
    for (int32_t f = 0; sorted && f < m->nf; f++)
        if (aniso[f] > 0) sorted[ns++] = aniso[f];
    if (sorted && ns > 0) {
        qsort(sorted, (size_t)ns, sizeof *sorted, cmp_double);
        top = sorted[(size_t)(0.9 * (ns - 1))];
    }
    free(sorted);
    for (int32_t f = 0; f < m->nf; f++)
        for (int i = 0; i < 3; i++) out[3 * (size_t)f + i] *= top > 0 ? fmin(1.0, aniso[f] / top) : 0;
    free(normals), free(aniso);
    return out;
}

/* White noise in [0, 1) from a 64-bit seed and a texel id (splitmix64). */
static double lic_noise(uint64_t seed, uint64_t id) {
    uint64_t z = seed * 0x9e3779b97f4a7c15ull + id + 0x9e3779b97f4a7c15ull;
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
    z ^= z >> 31;
    return (double)(z >> 11) / 9007199254740992.0;
}

void sc_gradient_result_free(sc_gradient_result *res) {
    sc_image_free(res->image);
    sc_metric_list_free(&res->metrics);
    memset(res, 0, sizeof *res);
}

int sc_gradient_apply(const sc_mesh *mesh, const sc_texture *tex, const sc_image_data *image,
                      const sc_gradient_options *o, int threads, sc_gradient_result *res, sc_error *err) {
    memset(res, 0, sizeof *res);
    if (o->op == SC_GRADIENT_LIC && !(o->lic_length >= 1))
        return sc_fail(err, SC_EINPUT, "lic_length must be at least 1 texel");
    if ((int)o->op < 0 || o->op > SC_GRADIENT_LIC) return sc_fail(err, SC_EINPUT, "unknown operation %d", (int)o->op);
    if (o->op == SC_GRADIENT_STITCH) {
        if (!o->labels) return sc_fail(err, SC_EINPUT, "stitch: no labels image given");
        if (o->labels->width != image->width || o->labels->height != image->height)
            return sc_fail(err, SC_EINPUT, "stitch: labels are %dx%d, the texture %dx%d", (int)o->labels->width,
                           (int)o->labels->height, (int)image->width, (int)image->height);
    }
    if (!(o->screening > 0) && o->op != SC_GRADIENT_GEODESIC)
        return sc_fail(err, SC_EINPUT, "screening must be positive");
    if (!(o->time_step > 0) && o->op == SC_GRADIENT_GEODESIC)
        return sc_fail(err, SC_EINPUT, "time_step must be positive");
    sc_gradient_result r = {0};
    sc_seam_grid g = {image->width, image->height, tex->wrap_u, tex->wrap_v};
    gd_walk w;
    gd_system y = {0};
    double *x0 = NULL, *x = NULL;
    sc_image_data *in = sc_image_to_linear_f32(image, threads);
    if (!in) return sc_fail(err, SC_ENOMEM, "out of memory");
    int rc = walk_init(&w, mesh, tex->material, &g, err);
    if (rc != SC_OK) {
        sc_image_free(in);
        return rc;
    }
    double *perp = NULL;
    if (o->op == SC_GRADIENT_LIC) {
        if (o->lic_field && (o->lic_field->width != image->width || o->lic_field->height != image->height ||
                             o->lic_field->channels < 3)) {
            rc = sc_fail(err, SC_EINPUT, "lic: the field is %dx%d with %d channels; the texture is %dx%d, 3 needed",
                         (int)o->lic_field->width, (int)o->lic_field->height, (int)o->lic_field->channels,
                         (int)image->width, (int)image->height);
            goto done;
        }
        perp = o->lic_field ? lic_field_from_map(mesh, tex->material, &g, o->lic_field) : lic_field(mesh, tex->material);
        if (!perp) {
            rc = sc_fail(err, SC_ENOMEM, "out of memory");
            goto done;
        }
        w.lic_perp = perp, w.lic_epsilon = 1 / (o->lic_length * o->lic_length);
    }
    rc = system_build(&w, o->op == SC_GRADIENT_STITCH ? o->labels : NULL, threads, &y, err);
    if (rc != SC_OK) goto done;
    y.threads = threads;
    r.unknowns = y.n;
    sc_metric_list_add(&r.metrics, "unknowns", y.n);
    sc_metric_list_add(&r.metrics, "surface_area", y.area);
    if (y.n == 0) {
        rc = sc_fail(err, SC_EINPUT, "the texture's material covers no texel");
        goto done;
    }
    int32_t C = o->op == SC_GRADIENT_GEODESIC ? 1 : in->channels;
    size_t nn = (size_t)y.n * (size_t)C;
    x0 = sc_calloc_array(nn + 1, sizeof *x0);
    x = sc_calloc_array(nn + 1, sizeof *x);
    r.image = o->op == SC_GRADIENT_GEODESIC ? sc_image_alloc(in->width, in->height, 1, SC_PIXEL_F32) : in;
    if (o->op != SC_GRADIENT_GEODESIC) in = NULL;
    if (!x0 || !x || !r.image) {
        rc = sc_fail(err, SC_ENOMEM, "out of memory");
        goto done;
    }
    float *px = r.image->pixels;
    if (o->op == SC_GRADIENT_GEODESIC) {
        r.image->colorspace = SC_COLOR_DATA;
        rc = run_geodesic(mesh, tex->material, &w, &y, o, x, &r.metrics, &r.vcycles, err);
    } else {
        for (int32_t i = 0; i < y.n; i++)
            for (int32_t c = 0; c < C; c++) {
                bool colour = !(C == 2 || C == 4) || c < C - 1;   /* alpha keeps its values */
                x0[(size_t)i * C + c] = o->op == SC_GRADIENT_LIC && colour ? lic_noise(o->lic_seed, (uint64_t)y.texel[i])
                                                                           : px[(size_t)y.texel[i] * C + c];
                if (o->op == SC_GRADIENT_LIC) px[(size_t)y.texel[i] * C + c] = (float)x0[(size_t)i * C + c];
            }
        if (o->op == SC_GRADIENT_LIC) {
            /* w = screening / (area per texel): under h the mass scales by sqrt(det h) / sqrt(det g), so the
             * texel's area is taken under g, from the faces */
            double area = 0;
            for (int32_t f = 0; f < mesh->nf; f++) {
                if (tex->material >= 0 && mesh->FM[f] != tex->material) continue;
                double n[3];
                sc_triangle_normal(mesh->V + 3 * (size_t)mesh->FV[3 * f], mesh->V + 3 * (size_t)mesh->FV[3 * f + 1],
                                   mesh->V + 3 * (size_t)mesh->FV[3 * f + 2], n);
                area += 0.5 * sc_norm3(n);
            }
            sc_gradient_options lo = *o;
            lo.screening = o->screening * y.area * y.n / area;   /* run_filter divides by y.area */
            lo.gradient_scale = 0;
            rc = run_filter(&y, &lo, C, x0, x, &r.metrics, &r.vcycles, err);
            /* diffusion shrinks the noise's contrast: back to mean 1/2, deviation 1/6 */
            for (int32_t c = 0; c < C && rc == SC_OK; c++) {
                if ((C == 2 || C == 4) && c == C - 1) continue;
                double sum = 0, sq = 0;
                for (int32_t i = 0; i < y.n; i++) sum += x[(size_t)i * C + c];
                double mean = sum / y.n;
                for (int32_t i = 0; i < y.n; i++) sq += (x[(size_t)i * C + c] - mean) * (x[(size_t)i * C + c] - mean);
                double sd = sqrt(sq / y.n), k = sd > 0 ? 1.0 / (6 * sd) : 0;
                metric(&r.metrics, "%s_deviation", "lic", sd);
                for (int32_t i = 0; i < y.n; i++) x[(size_t)i * C + c] = 0.5 + k * (x[(size_t)i * C + c] - mean);
            }
        } else {
            rc = run_filter(&y, o, C, x0, x, &r.metrics, &r.vcycles, err);
        }
    }
    if (rc != SC_OK) goto done;
    double e_in = 0, e_out = 0;
    if (o->op != SC_GRADIENT_GEODESIC) {
        rc = seam_energy(mesh, &w.seams, &g, r.image, threads, "in", &r.metrics, &e_in, err);
        if (rc != SC_OK) goto done;
    }
    for (int32_t i = 0; i < y.n; i++)
        for (int32_t c = 0; c < C; c++) px[(size_t)y.texel[i] * C + c] = (float)x[(size_t)i * C + c];
    rc = seam_energy(mesh, &w.seams, &g, r.image, threads, "out", &r.metrics, &e_out, err);
    if (rc != SC_OK) goto done;
    if (o->op != SC_GRADIENT_GEODESIC && e_in > 0) sc_metric_list_add(&r.metrics, "seam_energy_ratio", e_out / e_in);
    rc = r.metrics.failed ? sc_fail(err, SC_ENOMEM, "out of memory") : SC_OK;
done:
    free(x0), free(x), free(perp);
    sc_image_free(in);
    system_free(&y);
    walk_free(&w);
    if (rc != SC_OK) sc_gradient_result_free(&r);
    else *res = r;
    return rc;
}
