/* straighten.c - the node `straighten`: seam straightening (Liu, Ferguson,
 * Jacobson, Gingold 2017, §6), so that seam-aware decimation (§5) can
 * collapse seam edges.
 *
 * Design note.
 *
 * Topology. The edge table of sc_topology, uvs by index: one half-edge is a
 * surface boundary, two that use different uv indices at an endpoint a seam
 * (docs/design.md), three or more a non-manifold edge; a foldover is an interior
 * edge here. Two uv indices with equal coordinates still make a seam, as
 * straightening may move them apart. A uv index used by corners of several
 * surface vertices has no single surface correspondence.
 *
 * Protected vertices (§6, rules 1-4). A surface vertex is protected when
 *   (1) it has a number of seam edges other than 0 or 2;
 *   (2) it has seam edges and surface boundary edges;
 *   (3) it is the apex of an "ear", a face with two seam or boundary
 *       half-edges (the corner between them), or a corner of a face with
 *       three;
 * and, beyond the paper, when it has a boundary valence other than 0 or 2,
 * a non-manifold edge, a uv index shared with another surface vertex, or
 * when the two halves of its seam do not continue through it cleanly (both
 * sides use the same uv index, or the uv indices of the two seam edges do
 * not pair up). Protection is kept per surface vertex, so a uv vertex is
 * protected exactly when its surface vertex is: rule (4), propagation across
 * the correspondence, holds by construction. Rule (3) is narrower than the
 * paper's, which protects all three corners of an ear: only the apex, moved
 * onto the line through its neighbours, would flatten the ear; the two
 * other corners slide along their own chains like any chain vertex (an ear
 * that still flipped would be retried and counted in flipped_triangles like
 * any face). Next to a junction of seams every face between two seams is an
 * ear, and protecting its side corners would leave the first edge of each
 * seam neither straight nor collapsible, so that decimate keeps it to the
 * coarsest level (docs/notes/straighten.md).
 *
 * Components. Seam and boundary edges joined at unprotected vertices form
 * chains between protected vertices, or closed loops with none. A seam chain
 * is walked once on the surface, which pairs each half-edge with its copy:
 * side A starts with the first half-edge of the first edge and continues
 * through the uv index it reaches; side B is the copy.
 *
 * Straightening. Each chain is a polyline: 2D (its uv) for a boundary, 4D
 * (side A's uv then side B's, vertex by vertex) for a seam. Ramer-Douglas-
 * Peucker (distance to the segment, ties to the first vertex) keeps the
 * vertices farther than `tolerance` times the diagonal of the polyline's
 * bounding box, the scale the authors' implementation (libigl
 * straighten_seams) gives the tolerance. A closed polyline (a loop, or a
 * chain returning to the uv point it started from on either side) keeps at
 * least three edges, adding the farthest vertex while it has fewer. Every
 * removed vertex moves to t = (arc length from the previous kept vertex) /
 * (arc length between the kept vertices), measured along the original
 * polyline (in 4D for seams), on the segment between the kept vertices;
 * both sides of a seam use the same t, so their length ratios agree to
 * rounding.
 *
 * Interior warp. Every uv vertex on a boundary of the parameter mesh (both
 * sides of seams, surface borders, non-manifold uv edges) stays where it is
 * unless straightening moved it. The interior vertices of the parameter-mesh
 * components that contain a moved vertex follow in `steps` equal steps of
 * the boundary along straight paths: each step solves the harmonic
 * displacement K_II d_I = -K_IB d_B with cotangent weights of the current
 * uv mesh (CHOLMOD through sc_sparse), so the composite map bends with the
 * mesh as it deforms (§6, after Schneider et al. 2013). Interior vertices of
 * other components keep their exact coordinates. Degenerate uv faces (twice
 * the area at most 1e-12 of the longest edge squared) have no usable
 * cotangents; instead of the paper's constrained Delaunay ambient mesh they
 * take the cotangents of their 3D triangle (equilateral when that is
 * degenerate too), and every edge gets a floor weight of 1e-9 so the system
 * stays definite; degenerate_uv_faces counts them. A face is flipped when
 * its signed uv area changes sign (or vanishes) against the input, degenerate
 * input faces excluded; when a run flips faces, it is repeated with four
 * times the steps (twice at most) and the run with the fewest flips is kept.
 *
 * Signals. Every texture of a material with a moved face is re-rendered on
 * the CPU in f32 (same size, channels, colour space): each face of the
 * material claims the texel centres (docs/design.md: texel (i, j) at
 * ((i + 1/2)/W, (j + 1/2)/H), row 0 = v = 0) within `padding` texels of its
 * new uv triangle, nearest face first (distance 0 inside; ties to the lower
 * face), so the padding the bilinear stencil reads around charts is filled
 * too. A texel of a moved face takes its barycentric coordinates in the new
 * triangle (extended beyond it in the padding), maps them to the old uv and
 * samples the old texture there bilinearly with its wrap mode (sc_seam); a
 * texel of an unmoved face or of no face keeps its value. A tangent-space
 * normal map (as the erase kernel judges it, sc_erase_takes_tangent_space)
 * holds vectors in frames that follow the uv, and a warp turns them: it is
 * taken to object space through the input's frames, re-rendered there, and
 * brought back through the frames of the new uv, every texel (a kept face's
 * frame can turn with a moved neighbour). With `erase` (the
 * default) the erase kernel (sc_erase, erase_seams's defaults but for
 * `preset`) then erases every texture of the new atlas, re-rendered or not,
 * as the resampling leaves the two sides of each seam slightly different
 * and the others may come with seams of their own: the output is seam-free
 * either way, so a chain needs no erase_seams before straighten (an erased
 * input's textures are seam-free already and pass through the kernel).
 *
 * Output. The input's surface mesh, faces, normals and materials unchanged,
 * U moved, FU unchanged. When no uv coordinate moves (nothing to straighten,
 * e.g. a mesh without seams whose borders are already straight within the
 * tolerance) the input's textures are erased as they are, or without
 * `erase` the input atlas itself is the output.
 *
 * Metrics. seam_edges; collapsible_seam_edges_before/_after: seam edges that
 * unify (§5.1) with the neighbouring seam edge at one of their ends: the
 * neighbour continues both halves through a vertex with exactly two seam
 * edges, each half is collinear with its continuation (the middle point
 * strictly between, within 1e-9 of the chord length) and the length ratios
 * agree (|e1| |d2| = |e2| |d1| within 1e-9 relative), the census decimate
 * makes without its storage-precision slack, computed the same way on the
 * input and output uv; protected_vertices, seam_chains, boundary_chains
 * (straightened), boundary_chains_kept (left by `borders`), skipped_chains
 * (halves that do not pair up: left as they are), moved_uv_vertices,
 * flipped_triangles, max_uv_displacement (uv units), degenerate_uv_faces,
 * warp_steps, textures_rendered, tangent_maps_reframed; erase.* (the erase
 * kernel's metrics, with its warnings passed on); psnr: colour (sRGB colour in linear light,
 * as seen) at 15 barycentric points of
 * every face of every re-rendered texture, old texture at old uv against the
 * output texture at new uv, peak 1; seconds (report only).
 * History and measurements: docs/notes/straighten.md.
 */
#include <float.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "sc_erase.h"
#include "sc_geometry.h"
#include "sc_nodes.h"
#include "sc_seam.h"
#include "sc_sparse.h"
#include "sc_tangent.h"
#include "sc_topology.h"

#define DEGENERATE_AREA 1e-12      /* twice the area / longest edge^2 */
#define FLOOR_WEIGHT 1e-9
#define CENSUS_TOLERANCE 1e-9
#define MAX_WARP_ATTEMPTS 3
#define PSNR_GRID 4                /* barycentric grid subdivisions */
#define ROUNDING (8 * DBL_EPSILON)   /* a move smaller than this (relative) is rounding */

/* The edge table (sc_topology: uvs by index, since straightening moves uv
 * indices) and what protection and the chain walk need per surface vertex. */
typedef struct topology {
    const sc_mesh *mesh;
    sc_topology table;
    int32_t *seam_degree, *boundary_degree, *nonmanifold_degree;
    int32_t (*incident)[2];      /* first two seam or boundary edges */
    int32_t *uv_vertex;          /* surface vertex of each uv index; -1 unused, -2 several */
} topology;

static void topology_free(topology *t) {
    sc_topology_free(&t->table);
    free(t->seam_degree), free(t->boundary_degree), free(t->nonmanifold_degree), free(t->incident);
    free(t->uv_vertex);
    memset(t, 0, sizeof *t);
}

/* Half-edge k of edge e. */
static int32_t half_of(const topology *t, const sc_topology_edge *e, int k) {
    return sc_topology_half(&t->table, e, k);
}

static const sc_topology_edge *edge_at(const topology *t, int32_t e) { return &t->table.edges[e]; }

/* The uv index half-edge k of edge e uses at surface vertex v. */
static int32_t side_uv(const topology *t, const sc_topology_edge *e, int k, int32_t v) {
    return sc_topology_uv_at(t->mesh, half_of(t, e, k), v);
}

static int topology_build(const sc_mesh *m, topology *t, sc_error *err) {
    memset(t, 0, sizeof *t);
    t->mesh = m;
    int rc = sc_topology_build(m, NULL, &t->table, err);
    if (rc != SC_OK) return rc;
    t->seam_degree = sc_calloc_array((size_t)m->nv + 1, sizeof(int32_t));
    t->boundary_degree = sc_calloc_array((size_t)m->nv + 1, sizeof(int32_t));
    t->nonmanifold_degree = sc_calloc_array((size_t)m->nv + 1, sizeof(int32_t));
    t->incident = sc_alloc_array((size_t)m->nv + 1, sizeof *t->incident);
    t->uv_vertex = sc_alloc_array((size_t)m->nu + 1, sizeof(int32_t));
    if (!t->seam_degree || !t->boundary_degree || !t->nonmanifold_degree || !t->incident || !t->uv_vertex) {
        topology_free(t);
        return sc_fail(err, SC_ENOMEM, "straighten: out of memory");
    }
    for (int32_t v = 0; v < m->nv; v++) t->incident[v][0] = t->incident[v][1] = -1;
    for (int32_t i = 0; i < t->table.nedges; i++) {
        const sc_topology_edge *e = edge_at(t, i);
        int32_t ends[2] = {e->v0, e->v1};
        for (int k = 0; k < 2; k++) {
            int32_t v = ends[k];
            if (e->kind == SC_EDGE_SEAM) t->seam_degree[v]++;
            if (e->kind == SC_EDGE_BOUNDARY) t->boundary_degree[v]++;
            if (e->kind == SC_EDGE_NONMANIFOLD) t->nonmanifold_degree[v]++;
            if (e->kind == SC_EDGE_SEAM || e->kind == SC_EDGE_BOUNDARY) {
                if (t->incident[v][0] < 0) t->incident[v][0] = i;
                else if (t->incident[v][1] < 0) t->incident[v][1] = i;
            }
        }
    }
    for (int32_t u = 0; u < m->nu; u++) t->uv_vertex[u] = -1;
    for (size_t c = 0; c < (size_t)m->nf * 3; c++) {
        int32_t u = m->FU[c], v = m->FV[c];
        if (t->uv_vertex[u] == -1) t->uv_vertex[u] = v;
        else if (t->uv_vertex[u] != v) t->uv_vertex[u] = -2;
    }
    return SC_OK;
}

/* ---------------------------------------------------------------- protection */

static bool is_silhouette(const sc_topology_edge *e) { return e->kind == SC_EDGE_SEAM || e->kind == SC_EDGE_BOUNDARY; }

/* Fills protect[v] for every surface vertex; returns the count. */
static int32_t protect_vertices(const topology *t, bool *protect) {
    const sc_mesh *m = t->mesh;
    for (int32_t v = 0; v < m->nv; v++) {
        int32_t s = t->seam_degree[v], b = t->boundary_degree[v];
        protect[v] = (s != 0 && s != 2)          /* rule 1 */
                     || (s > 0 && b > 0)         /* rule 2 */
                     || (b != 0 && b != 2) || t->nonmanifold_degree[v] > 0;
    }
    /* rule 3: ears. An ear's apex (the corner between its two silhouette
     * half-edges) would flatten it onto its third edge if it moved onto
     * the line through its neighbours; the two other corners slide along
     * their own chains (a flip is retried and counted like any face's). A face
     * with three silhouette half-edges keeps all its corners. */
    for (int32_t f = 0; f < m->nf; f++) {
        int count = 0, inner = -1;
        for (int k = 0; k < 3; k++) {
            if (is_silhouette(edge_at(t, t->table.edge_of[3 * f + k]))) count++;
            else inner = k;
        }
        if (count == 3)
            for (int k = 0; k < 3; k++) protect[m->FV[3 * f + k]] = true;
        else if (count == 2)
            protect[m->FV[3 * f + (inner + 2) % 3]] = true;
    }
    /* uv indices shared by several surface vertices */
    for (size_t c = 0; c < (size_t)m->nf * 3; c++)
        if (t->uv_vertex[m->FU[c]] == -2) protect[m->FV[c]] = true;
    /* the halves must continue cleanly through an unprotected vertex */
    for (int32_t v = 0; v < m->nv; v++) {
        if (protect[v]) continue;
        const sc_topology_edge *e1 = t->incident[v][0] >= 0 ? edge_at(t, t->incident[v][0]) : NULL;
        const sc_topology_edge *e2 = t->incident[v][1] >= 0 ? edge_at(t, t->incident[v][1]) : NULL;
        if (t->seam_degree[v] == 2) {
            int32_t x1 = side_uv(t, e1, 0, v), x2 = side_uv(t, e1, 1, v);
            int32_t y1 = side_uv(t, e2, 0, v), y2 = side_uv(t, e2, 1, v);
            if (x1 == x2 || !((x1 == y1 && x2 == y2) || (x1 == y2 && x2 == y1))) protect[v] = true;
        } else if (t->boundary_degree[v] == 2) {
            if (side_uv(t, e1, 0, v) != side_uv(t, e2, 0, v)) protect[v] = true;
        }
    }
    int32_t n = 0;
    for (int32_t v = 0; v < m->nv; v++) n += protect[v];
    return n;
}

/* ---------------------------------------------------------------- census (§5.1) */

/* Does seam edge e unify with the seam edge continuing it through `at`? */
static bool unifiable_at(const topology *t, const double *U, int32_t e_index, int32_t at) {
    if (t->seam_degree[at] != 2 || t->boundary_degree[at] != 0 || t->nonmanifold_degree[at] != 0) return false;
    const sc_topology_edge *e = edge_at(t, e_index);
    int32_t d_index = t->incident[at][0] == e_index ? t->incident[at][1] : t->incident[at][0];
    const sc_topology_edge *d = edge_at(t, d_index);
    int32_t other = e->v0 == at ? e->v1 : e->v0, far = d->v0 == at ? d->v1 : d->v0;
    double len_e[2], len_d[2];
    int32_t z_at_prev = -1;
    for (int s = 0; s < 2; s++) {
        int32_t z_at = side_uv(t, e, s, at), z_other = side_uv(t, e, s, other);
        if (z_at == z_at_prev) return false;   /* the tip of a slit */
        z_at_prev = z_at;
        int32_t z_far = -1;
        for (int g = 0; g < 2; g++)
            if (side_uv(t, d, g, at) == z_at) z_far = side_uv(t, d, g, far);
        if (z_far < 0) return false;
        if (!sc_collinear_through(U + 2 * z_far, U + 2 * z_at, U + 2 * z_other, CENSUS_TOLERANCE, 0)) return false;
        len_e[s] = sc_hypot2(U + 2 * z_at, U + 2 * z_other);
        len_d[s] = sc_hypot2(U + 2 * z_far, U + 2 * z_at);
    }
    double lhs = len_e[0] * len_d[1], rhs = len_e[1] * len_d[0];
    return fabs(lhs - rhs) <= CENSUS_TOLERANCE * fmax(lhs, rhs);
}

static int64_t count_collapsible(const topology *t, const double *U) {
    int64_t n = 0;
    for (int32_t i = 0; i < t->table.nedges; i++) {
        const sc_topology_edge *e = edge_at(t, i);
        if (e->kind != SC_EDGE_SEAM) continue;
        if (unifiable_at(t, U, i, e->v0) || unifiable_at(t, U, i, e->v1)) n++;
    }
    return n;
}

/* ---------------------------------------------------------------- charts */

/* chart[u]: the smallest uv index of u's connected component of the
 * parameter mesh (faces joined through shared uv indices). */
static void uv_charts(const sc_mesh *m, int32_t *chart) {
    for (int32_t u = 0; u < m->nu; u++) chart[u] = u;
    for (int32_t f = 0; f < m->nf; f++) {
        int32_t r0 = sc_set_root(chart, m->FU[3 * f]);
        for (int k = 1; k < 3; k++) {
            int32_t r = sc_set_root(chart, m->FU[3 * f + k]);
            if (r < r0) chart[r0] = r, r0 = r;
            else if (r > r0) chart[r] = r0;
        }
    }
    for (int32_t u = 0; u < m->nu; u++) chart[u] = sc_set_root(chart, u);
}

/* ---------------------------------------------------------------- chains and RDP */

typedef struct chain_buffers {
    int32_t cap;
    int32_t *surface;          /* n + 1 surface vertices */
    int32_t *uv[2];            /* n + 1 uv indices per side */
    double *points;            /* (n + 1) x dim */
    double *arc;               /* n + 1 cumulative arc lengths */
    bool *kept;
    int32_t *stack;
} chain_buffers;

static void chain_buffers_free(chain_buffers *c) {
    free(c->surface), free(c->uv[0]), free(c->uv[1]), free(c->points), free(c->arc), free(c->kept), free(c->stack);
    memset(c, 0, sizeof *c);
}

static bool chain_buffers_reserve(chain_buffers *c, int32_t n) {
    if (n <= c->cap) return true;
    int32_t cap = n * 2;
    int32_t *s = realloc(c->surface, sizeof(int32_t) * (size_t)cap);
    if (s) c->surface = s;
    int32_t *u0 = realloc(c->uv[0], sizeof(int32_t) * (size_t)cap);
    if (u0) c->uv[0] = u0;
    int32_t *u1 = realloc(c->uv[1], sizeof(int32_t) * (size_t)cap);
    if (u1) c->uv[1] = u1;
    double *p = realloc(c->points, sizeof(double) * 4 * (size_t)cap);
    if (p) c->points = p;
    double *a = realloc(c->arc, sizeof(double) * (size_t)cap);
    if (a) c->arc = a;
    bool *k = realloc(c->kept, sizeof(bool) * (size_t)cap);
    if (k) c->kept = k;
    int32_t *st = realloc(c->stack, sizeof(int32_t) * 2 * (size_t)cap);
    if (st) c->stack = st;
    if (!s || !u0 || !u1 || !p || !a || !k || !st) return false;
    c->cap = cap;
    return true;
}

/* Distance from point k to the segment i-j (dim coordinates each). */
static double segment_distance(const double *P, int dim, int32_t i, int32_t j, int32_t k) {
    const double *a = P + (size_t)dim * i, *b = P + (size_t)dim * j, *p = P + (size_t)dim * k;
    double dd = 0, wd = 0;
    for (int c = 0; c < dim; c++) dd += (b[c] - a[c]) * (b[c] - a[c]), wd += (p[c] - a[c]) * (b[c] - a[c]);
    double t = dd > 0 ? wd / dd : 0;
    t = t < 0 ? 0 : t > 1 ? 1 : t;
    double r = 0;
    for (int c = 0; c < dim; c++) {
        double x = p[c] - a[c] - t * (b[c] - a[c]);
        r += x * x;
    }
    return sqrt(r);
}

/* The vertex of (i, j) farthest from segment i-j (-1 when none lies between). */
static int32_t farthest(const double *P, int dim, int32_t i, int32_t j, double *dist) {
    int32_t best = -1;
    double dmax = -1;
    for (int32_t k = i + 1; k < j; k++) {
        double d = segment_distance(P, dim, i, j, k);
        if (d > dmax) dmax = d, best = k;
    }
    *dist = dmax;
    return best;
}

/* Ramer-Douglas-Peucker over points 0..n, keeping at least min_edges edges
 * where the polyline has the vertices for them. */
static void simplify(chain_buffers *c, int dim, int32_t n, double tol, int min_edges) {
    for (int32_t i = 0; i <= n; i++) c->kept[i] = false;
    c->kept[0] = c->kept[n] = true;
    int32_t top = 0;
    c->stack[top++] = 0, c->stack[top++] = n;
    while (top > 0) {
        int32_t j = c->stack[--top], i = c->stack[--top];
        if (j <= i + 1) continue;
        double d;
        int32_t k = farthest(c->points, dim, i, j, &d);
        if (k >= 0 && d > tol) {
            c->kept[k] = true;
            c->stack[top++] = i, c->stack[top++] = k;
            c->stack[top++] = k, c->stack[top++] = j;
        }
    }
    for (;;) {
        int edges = 0;
        for (int32_t i = 1; i <= n; i++) edges += c->kept[i];
        if (edges >= min_edges) break;
        int32_t best = -1, prev = 0;
        double best_d = -1;
        for (int32_t i = 1; i <= n; i++) {
            if (!c->kept[i]) continue;
            double d;
            int32_t k = farthest(c->points, dim, prev, i, &d);
            if (k >= 0 && d > best_d) best_d = d, best = k;
            prev = i;
        }
        if (best < 0) break;
        c->kept[best] = true;
    }
}

typedef struct straighten_stats {
    int32_t seam_chains, boundary_chains, skipped_chains, kept_boundary_chains;
} straighten_stats;

/* Straighten one walked chain of n edges (its buffers filled): write the new
 * uv of every removed vertex into Unew. */
static void straighten_chain(chain_buffers *c, const sc_mesh *m, bool seam, bool cycle, int32_t n, double tol,
                             double *Unew) {
    int dim = seam ? 4 : 2;
    int sides = seam ? 2 : 1;
    for (int32_t i = 0; i <= n; i++)
        for (int s = 0; s < sides; s++) {
            c->points[(size_t)dim * i + 2 * s] = m->U[2 * c->uv[s][i]];
            c->points[(size_t)dim * i + 2 * s + 1] = m->U[2 * c->uv[s][i] + 1];
        }
    double lo[4], hi[4];
    for (int d = 0; d < dim; d++) lo[d] = hi[d] = c->points[d];
    for (int32_t i = 1; i <= n; i++)
        for (int d = 0; d < dim; d++) {
            double x = c->points[(size_t)dim * i + d];
            lo[d] = fmin(lo[d], x), hi[d] = fmax(hi[d], x);
        }
    double diag = 0;
    for (int d = 0; d < dim; d++) diag += (hi[d] - lo[d]) * (hi[d] - lo[d]);
    diag = sqrt(diag);
    bool closed = cycle;
    for (int s = 0; s < sides; s++) closed = closed || c->uv[s][0] == c->uv[s][n];
    simplify(c, dim, n, tol * diag, closed ? 3 : 1);
    c->arc[0] = 0;
    for (int32_t i = 1; i <= n; i++) {
        double r = 0;
        for (int d = 0; d < dim; d++) {
            double x = c->points[(size_t)dim * i + d] - c->points[(size_t)dim * (i - 1) + d];
            r += x * x;
        }
        c->arc[i] = c->arc[i - 1] + sqrt(r);
    }
    int32_t prev = 0;
    for (int32_t j = 1; j <= n; j++) {
        if (!c->kept[j]) continue;
        double span = c->arc[j] - c->arc[prev];
        for (int32_t k = prev + 1; k < j; k++) {
            double t = span > 0 ? (c->arc[k] - c->arc[prev]) / span : (double)(k - prev) / (double)(j - prev);
            double target[2][2];
            bool changes = false;
            for (int s = 0; s < sides; s++) {
                const double *a = m->U + 2 * c->uv[s][prev], *b = m->U + 2 * c->uv[s][j];
                const double *old = m->U + 2 * c->uv[s][k];
                for (int d = 0; d < 2; d++) {
                    target[s][d] = a[d] + t * (b[d] - a[d]);
                    changes = changes || fabs(target[s][d] - old[d]) > ROUNDING * fmax(1.0, fabs(old[d]));
                }
            }
            /* a vertex already in place (to rounding) keeps its exact coordinates */
            for (int s = 0; s < sides && changes; s++)
                memcpy(Unew + 2 * c->uv[s][k], target[s], sizeof target[s]);
        }
        prev = j;
    }
}

/* Walk every chain and loop of seam or boundary edges and straighten it. */
static int straighten_all(const topology *t, const bool *protect, const bool *straighten_border, double tol,
                          double *Unew, straighten_stats *st, sc_error *err) {
    const sc_mesh *m = t->mesh;
    memset(st, 0, sizeof *st);
    bool *visited = sc_calloc_array((size_t)t->table.nedges + 1, sizeof(bool));
    chain_buffers c = {0};
    if (!visited || !chain_buffers_reserve(&c, 16)) {
        free(visited), chain_buffers_free(&c);
        return sc_fail(err, SC_ENOMEM, "straighten: out of memory");
    }
    int rc = SC_OK;
    /* pass 0: chains that start at a protected vertex; pass 1: loops */
    for (int pass = 0; pass < 2 && rc == SC_OK; pass++) {
        for (int32_t e0 = 0; e0 < t->table.nedges && rc == SC_OK; e0++) {
            const sc_topology_edge *first = edge_at(t, e0);
            if (!is_silhouette(first) || visited[e0]) continue;
            int32_t start;
            if (pass == 0) {
                if (protect[first->v0]) start = first->v0;
                else if (protect[first->v1]) start = first->v1;
                else continue;
            } else {
                start = first->v0;
            }
            bool seam = first->kind == SC_EDGE_SEAM;
            int sides = seam ? 2 : 1;
            int32_t n = 0, e = e0, v = start;
            bool ok = true;
            c.surface[0] = start;
            for (int s = 0; s < sides; s++) c.uv[s][0] = side_uv(t, first, s, start);
            for (;;) {
                visited[e] = true;
                const sc_topology_edge *ed = edge_at(t, e);
                if (ed->kind != first->kind) {
                    ok = false;
                    break;
                }
                int32_t next = ed->v0 == v ? ed->v1 : ed->v0;
                if (!chain_buffers_reserve(&c, n + 2)) {
                    rc = sc_fail(err, SC_ENOMEM, "straighten: out of memory");
                    break;
                }
                /* side s continues through the half-edge using the same uv at v */
                int32_t used = -1;
                for (int s = 0; s < sides && ok; s++) {
                    int32_t h = -1;
                    for (int g = 0; g < sides; g++)
                        if (g != used && side_uv(t, ed, g, v) == c.uv[s][n]) {
                            h = half_of(t, ed, g);
                            used = g;
                            break;
                        }
                    if (h < 0) ok = false;
                    else c.uv[s][n + 1] = sc_topology_uv_at(m, h, next);
                }
                n++;
                c.surface[n] = next;
                if (!ok || protect[next] || next == start) break;
                int32_t after = t->incident[next][0] == e ? t->incident[next][1] : t->incident[next][0];
                if (after < 0 || visited[after] || n > t->table.nedges) {
                    ok = false;
                    break;
                }
                v = next;
                e = after;
            }
            if (rc != SC_OK) break;
            bool cycle = pass == 1;
            if (ok && cycle)
                for (int s = 0; s < sides; s++) ok = ok && c.surface[n] == start && c.uv[s][n] == c.uv[s][0];
            if (!ok) {
                st->skipped_chains++;
                continue;
            }
            if (!seam && !straighten_border[c.uv[0][0]]) {
                st->kept_boundary_chains++;
                continue;
            }
            if (seam) st->seam_chains++;
            else st->boundary_chains++;
            if (n >= 2) straighten_chain(&c, m, seam, cycle, n, tol, Unew);
        }
    }
    free(visited);
    chain_buffers_free(&c);
    return rc;
}

/* ---------------------------------------------------------------- interior warp */

static bool uv_face_degenerate(const double *U, const int32_t *fu) {
    const double *p[3] = {U + 2 * fu[0], U + 2 * fu[1], U + 2 * fu[2]};
    double longest = 0;
    for (int k = 0; k < 3; k++) {
        double d = sc_hypot2(p[k], p[(k + 1) % 3]);
        longest = fmax(longest, d);
    }
    return !(fabs(sc_orient2(p[0], p[1], p[2])) > DEGENERATE_AREA * longest * longest);
}

/* cot of the angle at corner k (in dim dimensions) of triangle p; false when degenerate */
static bool corner_cotangents(const double *const p[3], int dim, double cot[3]) {
    for (int k = 0; k < 3; k++) {
        const double *o = p[k], *a = p[(k + 1) % 3], *b = p[(k + 2) % 3];
        double dot = 0, aa = 0, bb = 0;
        for (int c = 0; c < dim; c++) {
            dot += (a[c] - o[c]) * (b[c] - o[c]);
            aa += (a[c] - o[c]) * (a[c] - o[c]);
            bb += (b[c] - o[c]) * (b[c] - o[c]);
        }
        double cross2 = aa * bb - dot * dot;
        double longest = fmax(aa, bb);
        if (!(cross2 > DEGENERATE_AREA * DEGENERATE_AREA * longest * longest)) return false;
        cot[k] = dot / sqrt(cross2);
    }
    return true;
}

typedef struct warp_problem {
    const sc_mesh *mesh;
    int32_t nunknown;
    int32_t *unknown;       /* per uv index: unknown number, or -1 */
    bool *affected_face;
    const bool *moved;
} warp_problem;

/* One run of `steps` harmonic steps from U to the boundary targets in Unew;
 * X receives the result. */
static int warp_run(const warp_problem *w, const double *Unew, int steps, double *X, sc_error *err) {
    const sc_mesh *m = w->mesh;
    memcpy(X, m->U, sizeof(double) * 2 * (size_t)m->nu);
    double *rhs = sc_alloc_array((size_t)w->nunknown * 2 + 1, sizeof(double));
    if (!rhs) return sc_fail(err, SC_ENOMEM, "straighten: out of memory");
    int rc = SC_OK;
    for (int step = 1; step <= steps && rc == SC_OK; step++) {
        sc_triplets tr;
        sc_triplets_init(&tr, w->nunknown);
        memset(rhs, 0, sizeof(double) * 2 * (size_t)w->nunknown);
        for (int32_t f = 0; f < m->nf; f++) {
            if (!w->affected_face[f]) continue;
            const int32_t *fu = m->FU + 3 * f;
            const double *p[3] = {X + 2 * fu[0], X + 2 * fu[1], X + 2 * fu[2]};
            double cot[3];
            if (uv_face_degenerate(X, fu) || !corner_cotangents(p, 2, cot)) {
                const double *q[3] = {m->V + 3 * m->FV[3 * f], m->V + 3 * m->FV[3 * f + 1], m->V + 3 * m->FV[3 * f + 2]};
                if (!corner_cotangents(q, 3, cot)) cot[0] = cot[1] = cot[2] = 1.0 / sqrt(3.0);
            }
            for (int k = 0; k < 3; k++) {
                int32_t i = fu[(k + 1) % 3], j = fu[(k + 2) % 3];
                double wt = 0.5 * cot[k] + FLOOR_WEIGHT;
                int32_t ui = w->unknown[i], uj = w->unknown[j];
                if (ui >= 0) sc_triplets_add(&tr, ui, ui, wt);
                if (uj >= 0) sc_triplets_add(&tr, uj, uj, wt);
                if (ui >= 0 && uj >= 0) sc_triplets_add(&tr, ui, uj, -wt);
                /* a moved fixed vertex moves by (Unew - U) / steps this step */
                for (int side = 0; side < 2; side++) {
                    int32_t a = side ? j : i, b = side ? i : j;
                    int32_t ua = w->unknown[a];
                    if (ua < 0 || w->unknown[b] >= 0 || !w->moved[b]) continue;
                    for (int c = 0; c < 2; c++)
                        rhs[(size_t)c * w->nunknown + ua] += wt * (Unew[2 * b + c] - m->U[2 * b + c]) / steps;
                }
            }
        }
        if (tr.failed) rc = sc_fail(err, SC_ENOMEM, "straighten: out of memory");
        sc_sparse a = {0};
        sc_sparse_chol *chol = NULL;
        if (rc == SC_OK) rc = sc_sparse_from_triplets(&tr, &a, err);
        sc_triplets_free(&tr);
        if (rc == SC_OK) rc = sc_sparse_chol_factor(&a, NULL, &chol, err);
        if (rc == SC_OK) rc = sc_sparse_chol_solve(chol, 2, rhs, err);
        sc_sparse_chol_free(chol);
        sc_sparse_free(&a);
        if (rc != SC_OK) break;
        for (int32_t u = 0; u < m->nu; u++) {
            int32_t k = w->unknown[u];
            if (k >= 0) {
                X[2 * u] += rhs[k];
                X[2 * u + 1] += rhs[(size_t)w->nunknown + k];
            } else if (w->moved[u]) {
                double s = step == steps ? 1.0 : (double)step / steps;
                for (int c = 0; c < 2; c++) X[2 * u + c] = m->U[2 * u + c] + s * (Unew[2 * u + c] - m->U[2 * u + c]);
            }
        }
    }
    if (rc == SC_OK)   /* the straightened boundary exactly */
        for (int32_t u = 0; u < m->nu; u++)
            if (w->moved[u]) X[2 * u] = Unew[2 * u], X[2 * u + 1] = Unew[2 * u + 1];
    free(rhs);
    if (rc != SC_OK) sc_error_prefix(err, "straighten: interior warp");
    return rc;
}

static int64_t count_flips(const sc_mesh *m, const double *X) {
    int64_t n = 0;
    for (int32_t f = 0; f < m->nf; f++) {
        const int32_t *fu = m->FU + 3 * f;
        if (uv_face_degenerate(m->U, fu)) continue;
        double a0 = sc_orient2(m->U + 2 * fu[0], m->U + 2 * fu[1], m->U + 2 * fu[2]);
        double a1 = sc_orient2(X + 2 * fu[0], X + 2 * fu[1], X + 2 * fu[2]);
        if (!(a0 * a1 > 0)) n++;
    }
    return n;
}

/* A uv edge (lo < hi uv indices) and one of its half-edges. */
typedef struct uv_key {
    int32_t lo, hi, half;
} uv_key;

static int compare_uv_keys(const void *x, const void *y) {
    const uv_key *p = x, *q = y;
    if (p->lo != q->lo) return p->lo < q->lo ? -1 : 1;
    if (p->hi != q->hi) return p->hi < q->hi ? -1 : 1;
    return (p->half > q->half) - (p->half < q->half);
}

typedef struct warp_result {
    int64_t flips;
    int steps;
} warp_result;

/* Warp the interior: U_out gets the final uv of every uv index. */
static int warp_interior(const sc_mesh *m, const int32_t *chart, const bool *moved, const double *Unew, int steps,
                         double *Uout, warp_result *res, sc_error *err) {
    warp_problem w = {.mesh = m, .moved = moved};
    bool *comp_moved = sc_calloc_array((size_t)m->nu + 1, sizeof(bool));
    bool *fixed = sc_calloc_array((size_t)m->nu + 1, sizeof(bool));
    w.unknown = sc_alloc_array((size_t)m->nu + 1, sizeof(int32_t));
    w.affected_face = sc_calloc_array((size_t)m->nf + 1, sizeof(bool));
    uv_key *keys = sc_alloc_array((size_t)m->nf * 3, sizeof *keys);
    double *X = sc_alloc_array((size_t)m->nu * 2 + 1, sizeof(double));
    int rc = SC_OK;
    if (!comp_moved || !fixed || !w.unknown || !w.affected_face || !keys || !X)
        rc = sc_fail(err, SC_ENOMEM, "straighten: out of memory");
    if (rc == SC_OK) {
        /* boundary of the parameter mesh: uv edges of one face, or of three or more */
        size_t nh = (size_t)m->nf * 3;
        for (int32_t h = 0; h < (int32_t)nh; h++) {
            int32_t a = m->FU[h], b = m->FU[sc_topology_next(h)];
            keys[h] = (uv_key){a < b ? a : b, a < b ? b : a, h};
        }
        qsort(keys, nh, sizeof *keys, compare_uv_keys);
        for (size_t i = 0; i < nh;) {
            size_t j = i;
            while (j < nh && keys[j].lo == keys[i].lo && keys[j].hi == keys[i].hi) j++;
            if (j - i != 2) fixed[keys[i].lo] = fixed[keys[i].hi] = true;
            i = j;
        }
        for (int32_t u = 0; u < m->nu; u++) fixed[u] = fixed[u] || moved[u];
        for (int32_t u = 0; u < m->nu; u++)
            if (moved[u]) comp_moved[chart[u]] = true;
        for (int32_t u = 0; u < m->nu; u++) w.unknown[u] = -1;
        for (int32_t f = 0; f < m->nf; f++) {
            if (!comp_moved[chart[m->FU[3 * f]]]) continue;
            w.affected_face[f] = true;
            for (int k = 0; k < 3; k++) {
                int32_t u = m->FU[3 * f + k];
                if (!fixed[u] && w.unknown[u] < 0) w.unknown[u] = w.nunknown++;
            }
        }
    }
    res->flips = -1;
    res->steps = steps;
    for (int attempt = 0; attempt < MAX_WARP_ATTEMPTS && rc == SC_OK; attempt++) {
        int run_steps = steps;
        for (int i = 0; i < attempt; i++) run_steps *= 4;
        if (w.nunknown == 0) {
            memcpy(X, m->U, sizeof(double) * 2 * (size_t)m->nu);
            for (int32_t u = 0; u < m->nu; u++)
                if (moved[u]) X[2 * u] = Unew[2 * u], X[2 * u + 1] = Unew[2 * u + 1];
        } else {
            rc = warp_run(&w, Unew, run_steps, X, err);
            if (rc != SC_OK) break;
        }
        int64_t flips = count_flips(m, X);
        if (res->flips < 0 || flips < res->flips) {
            res->flips = flips;
            res->steps = run_steps;
            memcpy(Uout, X, sizeof(double) * 2 * (size_t)m->nu);
        }
        if (flips == 0 || w.nunknown == 0) break;
    }
    free(comp_moved), free(fixed), free(w.unknown), free(w.affected_face), free(keys), free(X);
    return rc;
}

/* ---------------------------------------------------------------- signal warp */

/* Whether triangle t holds p (its edges included). */
static bool triangle_holds(const double t[3][2], double px, double py) {
    double p[2] = {px, py};
    double s0 = sc_orient2(t[0], t[1], p), s1 = sc_orient2(t[1], t[2], p), s2 = sc_orient2(t[2], t[0], p);
    return (s0 >= 0 && s1 >= 0 && s2 >= 0) || (s0 <= 0 && s1 <= 0 && s2 <= 0);
}

/* Distance in texel space from p to triangle t (0 inside). */
static double triangle_distance(const double t[3][2], double px, double py) {
    if (triangle_holds(t, px, py)) return 0;
    double ex[3], ey[3], d2[3], least = DBL_MAX;
    for (int k = 0; k < 3; k++) {
        const double *a = t[k], *b = t[(k + 1) % 3];
        double dx = b[0] - a[0], dy = b[1] - a[1], wx = px - a[0], wy = py - a[1];
        double dd = dx * dx + dy * dy, s = dd > 0 ? (wx * dx + wy * dy) / dd : 0;
        s = s < 0 ? 0 : s > 1 ? 1 : s;
        ex[k] = wx - s * dx, ey[k] = wy - s * dy;
        d2[k] = ex[k] * ex[k] + ey[k] * ey[k];
        least = fmin(least, d2[k]);
    }
    /* hypot (slow, exact) only where the square is within its rounding of
     * the least: the same minimum as hypot over all three */
    double best = DBL_MAX;
    for (int k = 0; k < 3; k++)
        if (d2[k] <= least * (1 + 1e-12)) best = fmin(best, hypot(ex[k], ey[k]));
    return best;
}

/* One texture's re-rendering, split into bands of rows that render side by
 * side: a band claims its own texels (every face in order, see claim) and
 * then samples them, so the result does not depend on the split. */
typedef struct warp_job {
    const sc_mesh *m;
    const double *Unew;
    const bool *face_moved;
    const sc_texture *tex;
    int32_t pad, W, H, C, rows;   /* rows: a band's */
    const sc_image_data *src;     /* the old texture, */
    const sc_seam_reader *read;   /* read as stored */
    float *dp;                    /* the new one: its f32 copy, warped where a moved face claims */
    float *best;                  /* per texel: the claiming face's distance */
    int32_t *owner, *lattice;     /* per texel: the claiming face, and the lattice point it claimed */
    const uint8_t *reach;         /* per texel: 1 where a moved face may claim it (within pad of it) */
    const int32_t *reach_lo, *reach_hi;   /* per row: its first and last reached texel (none: lo > hi) */
} warp_job;

/* A face's lattice box in texel space, widened by pad: the texels it may
 * claim lie in it. False for a face that claims none. */
static bool face_box(const double *Unew, const int32_t *fu, int32_t W, int32_t H, int32_t pad, double t[3][2],
                     int64_t box[4]) {
    double lo[2] = {DBL_MAX, DBL_MAX}, hi[2] = {-DBL_MAX, -DBL_MAX};
    for (int k = 0; k < 3; k++) {
        t[k][0] = Unew[2 * fu[k]] * W - 0.5;
        t[k][1] = Unew[2 * fu[k] + 1] * H - 0.5;
        for (int c = 0; c < 2; c++) lo[c] = fmin(lo[c], t[k][c]), hi[c] = fmax(hi[c], t[k][c]);
    }
    if (!(fabs(sc_orient2(t[0], t[1], t[2])) > 0)) return false;
    if (hi[0] - lo[0] > 2.0 * W + 2 * pad || hi[1] - lo[1] > 2.0 * H + 2 * pad) return false;
    box[0] = (int64_t)ceil(lo[0] - pad), box[1] = (int64_t)floor(hi[0] + pad);
    box[2] = (int64_t)ceil(lo[1] - pad), box[3] = (int64_t)floor(hi[1] + pad);
    return true;
}

/* The texel (*col, *row) a lattice point (i, j) lands on; false off a
 * clamped side. */
static bool lattice_texel(int64_t i, int64_t j, int32_t W, int32_t H, const sc_texture *tex, int32_t *col,
                          int32_t *row) {
    if ((tex->wrap_u == SC_WRAP_CLAMP && (i < 0 || i >= W)) || (tex->wrap_v == SC_WRAP_CLAMP && (j < 0 || j >= H)))
        return false;
    *col = tex->wrap_u == SC_WRAP_CLAMP ? (int32_t)i : sc_seam_wrap(i, W, tex->wrap_u);
    *row = tex->wrap_v == SC_WRAP_CLAMP ? (int32_t)j : sc_seam_wrap(j, H, tex->wrap_v);
    return true;
}

/* The texels a moved face may claim: only there can the claim change a
 * texel, so only there is every face's distance needed. A point within pad
 * of the triangle lies within pad (and a rounding's slack) of the inner side
 * of each of its edges' lines: a cheap test that keeps every such texel. */
static void mark_reach(const sc_mesh *m, const double *Unew, const bool *face_moved, const sc_texture *tex,
                       int32_t W, int32_t H, int32_t pad, uint8_t *reach, int32_t *reach_lo, int32_t *reach_hi) {
    for (int32_t j = 0; j < H; j++) reach_lo[j] = W, reach_hi[j] = -1;
    for (int32_t f = 0; f < m->nf; f++) {
        double t[3][2];
        int64_t box[4];
        if (!face_moved[f] || m->FM[f] != tex->material || !face_box(Unew, m->FU + 3 * f, W, H, pad, t, box)) continue;
        double side = sc_orient2(t[0], t[1], t[2]) > 0 ? 1.0 : -1.0, least[3];
        for (int k = 0; k < 3; k++) {
            const double *a = t[k], *b = t[(k + 1) % 3];
            least[k] = -(pad + 1e-3) * hypot(b[0] - a[0], b[1] - a[1]);
        }
        for (int64_t j = box[2]; j <= box[3]; j++)
            for (int64_t i = box[0]; i <= box[1]; i++) {
                double p[2] = {(double)i, (double)j};
                if (side * sc_orient2(t[0], t[1], p) < least[0] || side * sc_orient2(t[1], t[2], p) < least[1] ||
                    side * sc_orient2(t[2], t[0], p) < least[2])
                    continue;
                int32_t col, row;
                if (!lattice_texel(i, j, W, H, tex, &col, &row)) continue;
                reach[(size_t)row * W + col] = 1;
                reach_lo[row] = col < reach_lo[row] ? col : reach_lo[row];
                reach_hi[row] = col > reach_hi[row] ? col : reach_hi[row];
            }
    }
}

/* Face f's claims in the band's rows [row0, row1), on the texels a moved
 * face reaches. Inside pass: the texels f holds that no earlier face holds.
 * Outside pass: the texels no face holds, within pad of f and nearer it
 * than the faces before. Together they give each texel the first face in
 * order that holds it, else the nearest within pad (the first among
 * equals); texels inside a face, most of them, skip the distance. */
static void claim(const warp_job *J, int32_t f, int32_t row0, int32_t row1, bool inside_pass) {
    const sc_texture *tex = J->tex;
    const int32_t W = J->W, H = J->H, pad = J->pad;
    float *best = J->best;
    double t[3][2];
    int64_t box[4];
    if (!face_box(J->Unew, J->m->FU + 3 * f, W, H, pad, t, box)) return;
    int64_t i0 = box[0], i1 = box[1], j0 = box[2], j1 = box[3];
    if (tex->wrap_v == SC_WRAP_CLAMP) j0 = j0 > row0 ? j0 : row0, j1 = j1 < row1 - 1 ? j1 : row1 - 1;
    for (int64_t j = j0; j <= j1; j++) {
        int32_t jj = tex->wrap_v == SC_WRAP_CLAMP ? (int32_t)j : sc_seam_wrap(j, H, tex->wrap_v);
        if (jj < row0 || jj >= row1 || J->reach_lo[jj] > J->reach_hi[jj]) continue;
        const bool within = i0 >= 0 && i1 < W;   /* a box inside the texture: only the row's reached span */
        int64_t from = within && i0 < J->reach_lo[jj] ? J->reach_lo[jj] : i0;
        int64_t to = within && i1 > J->reach_hi[jj] ? J->reach_hi[jj] : i1;
        for (int64_t i = from; i <= to; i++) {
            int32_t ii;
            if (within) {
                ii = (int32_t)i;
            } else if (tex->wrap_u == SC_WRAP_CLAMP) {
                if (i < 0 || i >= W) continue;
                ii = (int32_t)i;
            } else {
                ii = sc_seam_wrap(i, W, tex->wrap_u);
            }
            size_t id = (size_t)jj * W + ii;
            if (!J->reach[id]) continue;   /* kept as it is */
            double d, p[2] = {(double)i, (double)j};
            if (inside_pass) {
                if (best[id] == 0 || !triangle_holds(t, p[0], p[1])) continue;   /* held by an earlier face */
                d = 0;
            } else if (best[id] == 0) {
                continue;   /* held, or already at distance 0 */
            } else {
                d = triangle_distance(t, p[0], p[1]);
                if (d > pad || !((float)d < best[id])) continue;
            }
            best[id] = (float)d;
            J->owner[id] = f;
            J->lattice[2 * id] = (int32_t)i;
            J->lattice[2 * id + 1] = (int32_t)j;
        }
    }
}

static int warp_band(void *ud, int32_t band) {
    const warp_job *J = ud;
    const sc_mesh *m = J->m;
    const double *Unew = J->Unew;
    const sc_texture *tex = J->tex;
    const int32_t W = J->W, H = J->H, C = J->C;
    const int32_t row0 = band * J->rows, row1 = row0 + J->rows < H ? row0 + J->rows : H;
    float *best = J->best;
    int32_t *owner = J->owner, *lattice = J->lattice;
    bool any = false;   /* only texels a moved face reaches are claimed, and only they touch the arrays */
    for (size_t i = (size_t)row0 * W; i < (size_t)row1 * W; i++)
        if (J->reach[i]) best[i] = FLT_MAX, owner[i] = -1, any = true;
    for (int pass = 0; pass < 2 && any; pass++)
        for (int32_t f = 0; f < m->nf; f++)
            if (m->FM[f] == tex->material) claim(J, f, row0, row1, pass == 0);
    const sc_seam_grid grid = {W, H, tex->wrap_u, tex->wrap_v};
    double sample[4];
    for (size_t id = (size_t)row0 * W; id < (size_t)row1 * W; id++) {
        if (!J->reach[id]) continue;
        int32_t f = owner[id];
        if (f < 0 || !J->face_moved[f]) continue;
        const int32_t *fu = m->FU + 3 * f;
        double u = (lattice[2 * id] + 0.5) / W, v = (lattice[2 * id + 1] + 0.5) / H;
        const double *a = Unew + 2 * fu[0], *b = Unew + 2 * fu[1], *c = Unew + 2 * fu[2];
        double p[2] = {u, v};
        double area = sc_orient2(a, b, c);
        double l0 = sc_orient2(b, c, p) / area, l1 = sc_orient2(c, a, p) / area, l2 = 1.0 - l0 - l1;
        double ou = l0 * m->U[2 * fu[0]] + l1 * m->U[2 * fu[1]] + l2 * m->U[2 * fu[2]];
        double ov = l0 * m->U[2 * fu[0] + 1] + l1 * m->U[2 * fu[1] + 1] + l2 * m->U[2 * fu[2] + 1];
        sc_seam_sample_read(&grid, J->src, J->read, ou, ov, sample);
        for (int32_t k = 0; k < C; k++) J->dp[id * C + k] = (float)sample[k];
    }
    return SC_OK;
}

#define WARP_BAND_ROWS 64

/* Re-render one texture (material `material`) from the old uv U to the new
 * Unew, on `threads` threads. */
static int warp_texture(const sc_mesh *m, const double *Unew, const bool *face_moved, const sc_texture *tex,
                        int32_t pad, int threads, sc_image_data **out, sc_error *err) {
    const sc_image_data *src = tex->image->as.image;
    const int32_t W = src->width, H = src->height, C = src->channels;
    /* resampled as stored (the erasure after it works as filtered): rendered
     * appearance keeps closer so (docs/notes/straighten.md); the new texture
     * starts as the old one's f32 copy, and moved faces' texels sample the
     * old one where it is, read tap by tap */
    sc_image_data *dst = sc_image_to_f32_threads(src, threads);
    size_t npx = (size_t)W * H;
    float *best = sc_alloc_array(npx, sizeof(float));
    int32_t *owner = sc_alloc_array(npx, sizeof(int32_t));
    int32_t *lattice = sc_alloc_array(npx * 2, sizeof(int32_t));
    uint8_t *reach = sc_calloc_array(npx, 1);
    int32_t *reach_lo = sc_alloc_array((size_t)H * 2, sizeof(int32_t)), *reach_hi = reach_lo ? reach_lo + H : NULL;
    const sc_seam_reader as_stored = {0};
    if (!dst || !best || !owner || !lattice || !reach || !reach_lo) {
        sc_image_free(dst), free(best), free(owner), free(lattice), free(reach), free(reach_lo);
        return sc_fail(err, SC_ENOMEM, "straighten: out of memory for the %s texture", tex->name);
    }
    mark_reach(m, Unew, face_moved, tex, W, H, pad, reach, reach_lo, reach_hi);
    warp_job J = {m, Unew, face_moved, tex, pad, W, H, C, WARP_BAND_ROWS, src, &as_stored, dst->pixels, best, owner,
                  lattice, reach, reach_lo, reach_hi};
    int32_t bands = (H + WARP_BAND_ROWS - 1) / WARP_BAND_ROWS;
    if (sc_parallel(threads, bands, warp_band, &J) != SC_OK)
        for (int32_t b = 0; b < bands; b++) warp_band(&J, b);
    free(best), free(owner), free(lattice), free(reach), free(reach_lo);
    *out = dst;
    return SC_OK;
}

static sc_mesh *mesh_with_uv(const sc_mesh *in, const double *U);

/* Re-render a tangent-space normal map: its vectors are relative to frames
 * that follow the uv, so the map goes to object space through the input's
 * frames, is re-rendered there, and comes back through the frames of the
 * moved uv (warped texels and kept ones alike: a kept face's frame can turn
 * with a moved neighbour's). */
static int warp_tangent_texture(const sc_mesh *m, const double *Unew, const bool *face_moved, const sc_texture *tex,
                                int32_t pad, int threads, sc_image_data **out, sc_error *err) {
    const sc_image_data *img = tex->image->as.image;
    const sc_seam_grid g = {img->width, img->height, tex->wrap_u, tex->wrap_v};
    sc_tangent_frames f_old = {0}, f_new = {0};
    sc_tangent_texels x_old = {0}, x_new = {0};
    sc_mesh *moved = mesh_with_uv(m, Unew);
    sc_value *object = NULL;
    sc_image_data *warped = NULL;
    int rc = moved ? SC_OK : sc_fail(err, SC_ENOMEM, "straighten: out of memory");
    if (rc == SC_OK) rc = sc_tangent_frames_build(m, &f_old, err);
    if (rc == SC_OK) rc = sc_tangent_texels_build(m, tex->material, &g, SC_TANGENT_BAND, threads, &x_old, err);
    if (rc == SC_OK) rc = sc_tangent_frames_build(moved, &f_new, err);
    if (rc == SC_OK) rc = sc_tangent_texels_build(moved, tex->material, &g, SC_TANGENT_BAND, threads, &x_new, err);
    if (rc == SC_OK) {
        sc_image_data *o = sc_tangent_to_object(img, &f_old, &x_old, threads);
        if (!o || !(object = sc_value_new_image(o))) rc = sc_fail(err, SC_ENOMEM, "straighten: out of memory");
    }
    if (rc == SC_OK) {
        sc_texture in_object = *tex;
        in_object.image = object;
        rc = warp_texture(m, Unew, face_moved, &in_object, pad, threads, &warped, err);
    }
    if (rc == SC_OK && !(*out = sc_tangent_from_object(warped, img, &f_new, &x_new, threads)))
        rc = sc_fail(err, SC_ENOMEM, "straighten: out of memory");
    sc_image_free(warped);
    sc_value_release(object);
    sc_tangent_texels_free(&x_old), sc_tangent_texels_free(&x_new);
    sc_tangent_frames_free(&f_old), sc_tangent_frames_free(&f_new);
    sc_mesh_free(moved);
    return rc;
}

/* ---------------------------------------------------------------- atlas assembly */

static sc_mesh *mesh_with_uv(const sc_mesh *in, const double *U) {
    sc_mesh *m = sc_mesh_alloc(in->nv, in->nu, in->nn, in->nf, in->nmat);
    if (!m) return NULL;
    memcpy(m->V, in->V, sizeof(double) * 3 * (size_t)in->nv);
    memcpy(m->U, U, sizeof(double) * 2 * (size_t)in->nu);
    memcpy(m->FV, in->FV, sizeof(int32_t) * 3 * (size_t)in->nf);
    memcpy(m->FU, in->FU, sizeof(int32_t) * 3 * (size_t)in->nf);
    memcpy(m->FM, in->FM, sizeof(int32_t) * (size_t)in->nf);
    if (in->nn > 0) {
        memcpy(m->N, in->N, sizeof(double) * 3 * (size_t)in->nn);
        memcpy(m->FN, in->FN, sizeof(int32_t) * 3 * (size_t)in->nf);
    }
    for (int32_t k = 0; k < in->nmat; k++)
        if (!(m->materials[k] = sc_strdup(in->materials[k]))) {
            sc_mesh_free(m);
            return NULL;
        }
    return m;
}

/* Erase the re-rendered atlas: the float result (*out) and, in each input
 * texture's own pixel type and encoding, its optimal rounding (*native).
 * The textures re-rendered here (made[i]) take their solutions in place.
 * The kernel's metrics go to ctx prefixed "erase." (seam energies, rounding
 * floors, tangent-space maps' normal gaps). */
static int erase_atlas(sc_ctx *ctx, const sc_value *atlas, const sc_atlas *input, const bool *made,
                       sc_erase_filter_space space, sc_erase_normal_space normals, int threads, sc_value **out,
                       sc_value **native, sc_error *err) {
    sc_erase_options o;
    sc_erase_defaults(&o);
    bool global = strcmp(sc_ctx_string(ctx, "preset"), "global") == 0;
    o.w_change = global ? SC_ERASE_W_CHANGE_GLOBAL : SC_ERASE_W_CHANGE_LOCAL;
    o.filter_space = space;
    o.normal_space = normals;
    o.inputs_private = made;
    const sc_atlas *a = atlas->as.atlas;
    const sc_image_data **like = calloc(a->ntex ? (size_t)a->ntex : 1, sizeof *like);
    if (!like) return sc_fail(err, SC_ENOMEM, "straighten: out of memory");
    for (int32_t i = 0; i < a->ntex && i < input->ntex; i++) like[i] = input->textures[i].image->as.image;
    o.native_like = like;
    sc_erase_result r;
    int rc = sc_erase(a->mesh->as.mesh, a->textures, a->ntex, &o, threads, &r, err);
    for (int32_t i = 0; rc == SC_OK && i < r.metrics.count; i++) {
        char name[256];
        snprintf(name, sizeof name, "erase.%s", r.metrics.items[i].name);
        sc_ctx_metric(ctx, name, r.metrics.items[i].value);
        char line[512];
        if (sc_erase_warning(&r.metrics, i, normals, line, sizeof line)) sc_ctx_warn(ctx, "%s", line);
    }
    if (rc == SC_OK && (!(*out = sc_erase_result_atlas(atlas, &r, false)) ||
                        !(*native = sc_erase_result_atlas(atlas, &r, true))))
        rc = sc_fail(err, SC_ENOMEM, "out of memory");
    if (rc != SC_OK) sc_error_prefix(err, "straighten: erase_seams");
    sc_erase_result_free(&r);
    free(like);
    return rc;
}

/* Appearance: old texture at old uv against new texture at new uv. */
static void appearance_error(const sc_mesh *m, const double *Unew, const sc_texture *old_tex,
                             const sc_image_data *old_img, const sc_seam_reader *old_read,
                             const sc_image_data *new_img, const sc_seam_reader *new_read, double *sum2,
                             double *count) {
    const sc_seam_grid g_old = {old_img->width, old_img->height, old_tex->wrap_u, old_tex->wrap_v};
    const sc_seam_grid g_new = {new_img->width, new_img->height, old_tex->wrap_u, old_tex->wrap_v};
    const int32_t C = old_img->channels;
    double a[4], b[4];
    for (int32_t f = 0; f < m->nf; f++) {
        if (m->FM[f] != old_tex->material) continue;
        const int32_t *fu = m->FU + 3 * f;
        for (int i = 0; i <= PSNR_GRID; i++)
            for (int j = 0; i + j <= PSNR_GRID; j++) {
                double l0 = (double)i / PSNR_GRID, l1 = (double)j / PSNR_GRID, l2 = 1.0 - l0 - l1;
                double uo = l0 * m->U[2 * fu[0]] + l1 * m->U[2 * fu[1]] + l2 * m->U[2 * fu[2]];
                double vo = l0 * m->U[2 * fu[0] + 1] + l1 * m->U[2 * fu[1] + 1] + l2 * m->U[2 * fu[2] + 1];
                double un = l0 * Unew[2 * fu[0]] + l1 * Unew[2 * fu[1]] + l2 * Unew[2 * fu[2]];
                double vn = l0 * Unew[2 * fu[0] + 1] + l1 * Unew[2 * fu[1] + 1] + l2 * Unew[2 * fu[2] + 1];
                sc_seam_sample_read(&g_old, old_img, old_read, uo, vo, a);
                sc_seam_sample_read(&g_new, new_img, new_read, un, vn, b);
                for (int32_t c = 0; c < C; c++) *sum2 += (a[c] - b[c]) * (a[c] - b[c]);
                *count += C;
            }
    }
}

/* ---------------------------------------------------------------- run */

/* One run's state, step to step. */
typedef struct job {
    sc_ctx *ctx;
    const sc_atlas *atlas;
    const sc_mesh *mesh;
    topology topo;
    bool *protect;              /* nv */
    int32_t *chart;             /* nu: uv_charts */
    bool *straighten_border;    /* nu */
    double *Unew;               /* nu x 2: the uv after straightening the chains */
    double *Uout;               /* nu x 2: the uv after the interior warp */
    bool *moved;                /* nu: straightening moved it */
    bool *face_moved;           /* nf: the warp moved a corner */
    sc_value **images;          /* ntex: the re-rendered textures, NULL where kept */
    sc_erase_normal_space normals;  /* the normal_space parameter */
    int32_t tangent_maps;       /* re-rendered through the frames (warp_tangent_texture) */
} job;

static void job_free(job *J) {
    for (int32_t i = 0; J->images && i < J->atlas->ntex; i++) sc_value_release(J->images[i]);
    free(J->images);
    free(J->protect), free(J->moved), free(J->face_moved), free(J->chart), free(J->straighten_border);
    free(J->Unew), free(J->Uout);
    topology_free(&J->topo);
}

static int job_init(job *J, sc_ctx *ctx, const sc_atlas *atlas, sc_error *err) {
    memset(J, 0, sizeof *J);
    const sc_mesh *m = atlas->mesh->as.mesh;
    J->ctx = ctx, J->atlas = atlas, J->mesh = m;
    int rc = topology_build(m, &J->topo, err);
    if (rc != SC_OK) return rc;
    J->protect = sc_calloc_array((size_t)m->nv + 1, sizeof(bool));
    J->moved = sc_calloc_array((size_t)m->nu + 1, sizeof(bool));
    J->face_moved = sc_calloc_array((size_t)m->nf + 1, sizeof(bool));
    J->chart = sc_alloc_array((size_t)m->nu + 1, sizeof(int32_t));
    J->straighten_border = sc_calloc_array((size_t)m->nu + 1, sizeof(bool));
    J->Unew = sc_alloc_array((size_t)m->nu * 2 + 1, sizeof(double));
    J->Uout = sc_alloc_array((size_t)m->nu * 2 + 1, sizeof(double));
    J->images = sc_calloc_array((size_t)atlas->ntex + 1, sizeof(sc_value *));
    if (!J->protect || !J->moved || !J->face_moved || !J->chart || !J->straighten_border || !J->Unew || !J->Uout ||
        !J->images)
        return sc_fail(err, SC_ENOMEM, "straighten: out of memory");
    return SC_OK;
}

/* Straightening: protection, the census before, every chain straightened
 * into Unew, and what moved. */
static int straighten_step(job *J, double tol, const char *borders, int64_t *nmoved, int64_t *collapsible_before,
                           sc_error *err) {
    const sc_mesh *m = J->mesh;
    int32_t nprotected = protect_vertices(&J->topo, J->protect);
    *collapsible_before = count_collapsible(&J->topo, m->U);
    uv_charts(m, J->chart);
    /* which charts may have their surface borders straightened */
    for (int32_t u = 0; u < m->nu; u++) J->straighten_border[u] = !strcmp(borders, "always");
    if (!strcmp(borders, "with_seams")) {
        for (int32_t h = 0; h < 3 * m->nf; h++)
            if (J->topo.table.edges[J->topo.table.edge_of[h]].kind == SC_EDGE_SEAM)
                J->straighten_border[J->chart[m->FU[h]]] = true;
        for (int32_t u = 0; u < m->nu; u++) J->straighten_border[u] = J->straighten_border[J->chart[u]];
    }
    memcpy(J->Unew, m->U, sizeof(double) * 2 * (size_t)m->nu);
    straighten_stats st;
    int rc = straighten_all(&J->topo, J->protect, J->straighten_border, tol, J->Unew, &st, err);
    if (rc != SC_OK) return rc;
    *nmoved = 0;
    for (int32_t u = 0; u < m->nu; u++) {
        J->moved[u] = J->Unew[2 * u] != m->U[2 * u] || J->Unew[2 * u + 1] != m->U[2 * u + 1];
        *nmoved += J->moved[u];
    }
    int64_t degenerate = 0;
    for (int32_t f = 0; f < m->nf; f++) degenerate += uv_face_degenerate(m->U, m->FU + 3 * f);
    sc_ctx *ctx = J->ctx;
    sc_ctx_metric(ctx, "seam_edges", J->topo.table.nseams);
    sc_ctx_metric(ctx, "collapsible_seam_edges_before", (double)*collapsible_before);
    sc_ctx_metric(ctx, "protected_vertices", nprotected);
    sc_ctx_metric(ctx, "seam_chains", st.seam_chains);
    sc_ctx_metric(ctx, "boundary_chains", st.boundary_chains);
    sc_ctx_metric(ctx, "skipped_chains", st.skipped_chains);
    sc_ctx_metric(ctx, "boundary_chains_kept", st.kept_boundary_chains);
    sc_ctx_metric(ctx, "moved_uv_vertices", (double)*nmoved);
    sc_ctx_metric(ctx, "degenerate_uv_faces", (double)degenerate);
    return SC_OK;
}

/* Interior warp: Uout, and the faces it moved. */
static int warp_step(job *J, int steps, sc_error *err) {
    const sc_mesh *m = J->mesh;
    double t_warp = sc_now();
    warp_result wr = {0};
    int rc = warp_interior(m, J->chart, J->moved, J->Unew, steps, J->Uout, &wr, err);
    if (rc != SC_OK) return rc;
    t_warp = sc_now() - t_warp;
    double max_disp = 0;
    for (int32_t u = 0; u < m->nu; u++) max_disp = fmax(max_disp, sc_hypot2(m->U + 2 * u, J->Uout + 2 * u));
    for (int32_t f = 0; f < m->nf; f++)
        for (int k = 0; k < 3; k++) {
            int32_t u = m->FU[3 * f + k];
            bool changed = J->Uout[2 * u] != m->U[2 * u] || J->Uout[2 * u + 1] != m->U[2 * u + 1];
            J->face_moved[f] = J->face_moved[f] || changed;
        }
    sc_ctx_metric(J->ctx, "collapsible_seam_edges_after", (double)count_collapsible(&J->topo, J->Uout));
    sc_ctx_metric(J->ctx, "flipped_triangles", (double)wr.flips);
    sc_ctx_metric(J->ctx, "warp_steps", wr.steps);
    sc_ctx_metric(J->ctx, "max_uv_displacement", max_disp);
    sc_ctx_metric(J->ctx, "seconds_warp", t_warp);
    return SC_OK;
}

/* Signals: every texture of a material with a moved face, re-rendered at Uout
 * (once per image, material and wrap modes). */
/* The textures render_signals re-renders, one per chunk of sc_parallel:
 * each is independent of the others (about a second each at 2048^2). */
typedef struct render_list {
    const job *J;
    int32_t pad;
    int threads;             /* each texture's own (warp_texture) */
    int32_t *which, count;   /* the textures re-rendered (indices) */
    sc_image_data **im;     /* per entry of which */
    bool *tangent;
    sc_error *errs;
} render_list;

static int render_one(void *ud, int32_t k) {
    render_list *L = ud;
    const job *J = L->J;
    const sc_texture *tex = &J->atlas->textures[L->which[k]];
    int rc = sc_erase_takes_tangent_space(J->mesh, tex, J->normals, &L->tangent[k], &L->errs[k]);
    if (rc == SC_OK)
        rc = L->tangent[k] ? warp_tangent_texture(J->mesh, J->Uout, J->face_moved, tex, L->pad, L->threads, &L->im[k],
                                                  &L->errs[k])
                           : warp_texture(J->mesh, J->Uout, J->face_moved, tex, L->pad, L->threads, &L->im[k],
                                          &L->errs[k]);
    return rc;
}

static int render_signals(job *J, int32_t pad, int32_t *rendered, sc_error *err) {
    const sc_atlas *atlas = J->atlas;
    const sc_mesh *m = J->mesh;
    *rendered = 0;
    int32_t *source = sc_alloc_array((size_t)atlas->ntex + 1, sizeof *source);   /* the texture it copies, or -1 */
    render_list L = {.J = J, .pad = pad, .threads = sc_ctx_threads(J->ctx),
                     .which = sc_alloc_array((size_t)atlas->ntex + 1, sizeof *L.which)};
    L.im = sc_calloc_array((size_t)atlas->ntex + 1, sizeof *L.im);
    L.tangent = sc_calloc_array((size_t)atlas->ntex + 1, sizeof *L.tangent);
    L.errs = sc_calloc_array((size_t)atlas->ntex + 1, sizeof *L.errs);
    int rc = source && L.which && L.im && L.tangent && L.errs ? SC_OK : sc_fail(err, SC_ENOMEM, "straighten: out of memory");
    for (int32_t i = 0; i < atlas->ntex && rc == SC_OK; i++) {
        const sc_texture *tex = &atlas->textures[i];
        bool touched = false;
        for (int32_t f = 0; f < m->nf && !touched; f++) touched = J->face_moved[f] && m->FM[f] == tex->material;
        source[i] = touched ? i : -1;
        for (int32_t j = 0; j < i && touched && source[i] == i; j++)   /* the same image in the same material */
            if (source[j] == j && atlas->textures[j].image == tex->image && atlas->textures[j].material == tex->material &&
                atlas->textures[j].wrap_u == tex->wrap_u && atlas->textures[j].wrap_v == tex->wrap_v)
                source[i] = j;
        if (source[i] == i) L.which[L.count++] = i;
    }
    int failed = rc == SC_OK ? sc_parallel(sc_ctx_threads(J->ctx), L.count, render_one, &L) : SC_OK;
    if (failed != SC_OK) {   /* the first texture's error, or sc_parallel's own */
        rc = sc_fail(err, failed, "straighten: out of memory");
        for (int32_t k = 0; k < L.count; k++)
            if (L.errs[k].code != SC_OK) {
                rc = sc_fail(err, L.errs[k].code, "%s", L.errs[k].message);
                break;
            }
    }
    for (int32_t k = 0; k < L.count; k++) {
        if (rc == SC_OK && !(J->images[L.which[k]] = sc_value_new_image(L.im[k])))
            rc = sc_fail(err, SC_ENOMEM, "straighten: out of memory");
        else if (!J->images[L.which[k]])
            sc_image_free(L.im[k]);
        J->tangent_maps += L.tangent[k];
        (*rendered)++;
    }
    for (int32_t i = 0; i < atlas->ntex && rc == SC_OK; i++)
        if (source[i] >= 0 && source[i] != i) J->images[i] = sc_value_retain(J->images[source[i]]);
    free(source), free(L.which), free(L.im), free(L.tangent), free(L.errs);
    return rc;
}

/* Output: the input's mesh with Uout, its textures where kept, the
 * re-rendered ones elsewhere. */
static int assemble_atlas(const job *J, sc_value **out, sc_error *err) {
    const sc_atlas *atlas = J->atlas;
    sc_mesh *nm = mesh_with_uv(J->mesh, J->Uout);
    sc_value *mesh_value = nm ? sc_value_new_mesh(nm) : NULL;
    sc_atlas *na = mesh_value ? sc_atlas_new(sc_value_retain(mesh_value)) : NULL;
    sc_value_release(mesh_value);
    int rc = na && sc_atlas_copy_materials(na, atlas) == SC_OK ? SC_OK
                                                               : sc_fail(err, SC_ENOMEM, "straighten: out of memory");
    for (int32_t i = 0; i < atlas->ntex && rc == SC_OK; i++) {
        const sc_texture *tex = &atlas->textures[i];
        sc_value *img = sc_value_retain(J->images[i] ? J->images[i] : tex->image);
        if (sc_atlas_add_texture(na, tex->name, tex->material, tex->wrap_u, tex->wrap_v, tex->source, img) != SC_OK)
            rc = sc_fail(err, SC_ENOMEM, "straighten: out of memory");
    }
    if (rc == SC_OK && !(*out = sc_value_new_atlas(na))) rc = sc_fail(err, SC_ENOMEM, "straighten: out of memory");
    else if (rc != SC_OK) sc_atlas_free(na);
    return rc;
}

/* Appearance: the psnr of the re-rendered textures of `result`. */
static int appearance_step(const job *J, const sc_atlas *result, sc_error *err) {
    const sc_atlas *atlas = J->atlas;
    double sum2 = 0, count = 0;
    int rc = SC_OK;
    for (int32_t i = 0; i < atlas->ntex && rc == SC_OK; i++) {
        if (!J->images[i]) continue;
        const sc_texture *tex = &atlas->textures[i];
        int k = sc_atlas_find_texture(result, tex->material, tex->name);
        if (k < 0) continue;
        /* compared as seen: sRGB colour in linear light, each tap decoded as it is read */
        const sc_image_data *a = tex->image->as.image, *b = result->textures[k].image->as.image;
        sc_seam_reader ra, rb;
        bool readers = sc_seam_reader_make(a, true, &ra);
        readers &= sc_seam_reader_make(b, true, &rb);
        if (!readers) rc = sc_fail(err, SC_ENOMEM, "straighten: out of memory");
        else appearance_error(J->mesh, J->Uout, tex, a, &ra, b, &rb, &sum2, &count);
        sc_seam_reader_free(&ra), sc_seam_reader_free(&rb);
    }
    if (rc == SC_OK && count > 0)
        sc_ctx_metric(J->ctx, "psnr", sum2 > 0 ? 10.0 * log10(count / sum2) : 200.0);
    return rc;
}

static int run(sc_ctx *ctx, sc_error *err) {
    double started = sc_now();
    const sc_value *in_value = sc_ctx_input(ctx, "atlas");
    const sc_atlas *atlas = sc_ctx_atlas(ctx, "atlas");
    const sc_mesh *m = atlas->mesh->as.mesh;
    const double tol = sc_ctx_number(ctx, "tolerance");
    const int steps = (int)sc_ctx_integer(ctx, "steps");
    const int32_t pad = (int32_t)sc_ctx_integer(ctx, "padding");
    const bool erase = sc_ctx_bool(ctx, "erase");
    const char *borders = sc_ctx_string(ctx, "borders");
    const int threads = sc_ctx_threads(ctx);
    int rc = sc_mesh_check(m, err);
    if (rc != SC_OK) return sc_error_prefix(err, "straighten:atlas");
    if (m->nf < 1) return sc_fail(err, SC_EINPUT, "straighten:atlas: the mesh has no faces");

    job J;
    rc = job_init(&J, ctx, atlas, err);
    J.normals = sc_erase_normal_space_of(sc_ctx_string(ctx, "normal_space"), atlas);
    int64_t nmoved = 0, collapsible_before = 0;
    if (rc == SC_OK) rc = straighten_step(&J, tol, borders, &nmoved, &collapsible_before, err);
    if (rc == SC_OK && nmoved == 0) {   /* nothing to straighten */
        sc_ctx_metric(ctx, "collapsible_seam_edges_after", (double)collapsible_before);
        sc_ctx_metric(ctx, "flipped_triangles", 0);
        sc_ctx_metric(ctx, "max_uv_displacement", 0);
    }
    if (rc == SC_OK && nmoved == 0 && !erase) {   /* the input itself */
        sc_ctx_metric(ctx, "seconds", sc_now() - started);
        sc_ctx_set_output(ctx, "atlas", sc_value_retain((sc_value *)in_value));
        sc_ctx_set_output(ctx, "atlas_native", sc_value_retain((sc_value *)in_value));
    } else if (rc == SC_OK) {
        /* moved: the textures re-rendered into the new uv; unmoved: the input's, erased all the same */
        sc_value *warped = NULL, *result = NULL, *native = NULL;
        int32_t rendered = 0;
        double t_render = sc_now();
        if (nmoved > 0) {
            rc = warp_step(&J, steps, err);
            t_render = sc_now();
            if (rc == SC_OK) rc = render_signals(&J, pad, &rendered, err);
            if (rc == SC_OK) rc = assemble_atlas(&J, &warped, err);
        } else {
            warped = sc_value_retain((sc_value *)in_value);
        }
        t_render = sc_now() - t_render;
        double t_erase = sc_now();
        if (rc == SC_OK && erase) {
            /* the re-rendered images are this run's and nothing reads them after the erasure */
            bool *made = sc_calloc_array((size_t)atlas->ntex + 1, sizeof *made);
            for (int32_t i = 0; made && i < atlas->ntex; i++) made[i] = J.images[i] != NULL;
            rc = made ? erase_atlas(ctx, warped, atlas, made,
                                    sc_erase_filter_space_named(sc_ctx_string(ctx, "filter_space")), J.normals,
                                    threads, &result, &native, err)
                      : sc_fail(err, SC_ENOMEM, "straighten: out of memory");
            free(made);
        } else if (rc == SC_OK) {
            result = sc_value_retain(warped), native = sc_value_retain(warped);
        }
        t_erase = sc_now() - t_erase;
        if (rc == SC_OK) rc = appearance_step(&J, result->as.atlas, err);
        if (rc == SC_OK) {
            sc_ctx_metric(ctx, "textures_rendered", rendered);
            sc_ctx_metric(ctx, "tangent_maps_reframed", J.tangent_maps);
            sc_ctx_metric(ctx, "seconds_render", t_render);
            sc_ctx_metric(ctx, "seconds_erase", t_erase);
            sc_ctx_metric(ctx, "seconds", sc_now() - started);
            sc_ctx_set_output(ctx, "atlas", result);
            sc_ctx_set_output(ctx, "atlas_native", native);
            result = native = NULL;
        }
        sc_value_release(warped), sc_value_release(result), sc_value_release(native);
    }
    job_free(&J);
    return rc;
}

static const char *const border_choices[] = {"with_seams", "always", "never", NULL};
static const char *const preset_choices[] = {"local", "global", NULL};

static const char *const filter_space_choices[] = {"linear", "encoded", NULL};
static const char *const normal_space_choices[] = {"auto", "tangent", "object", NULL};

static const sc_param_desc params[] = {
    {.name = "filter_space", .type = SC_PARAM_ENUM, .def_string = "linear", .choices = filter_space_choices,
     .doc = SC_ERASE_FILTER_SPACE_DOC},
    {.name = "normal_space", .type = SC_PARAM_ENUM, .def_string = "auto", .choices = normal_space_choices,
     .doc = SC_ERASE_NORMAL_SPACE_DOC},
    {.name = "tolerance", .type = SC_PARAM_NUMBER, .def = 0.01, .min = 0, .max = 1,
     .doc = "Ramer-Douglas-Peucker tolerance as a fraction of each seam or boundary chain's bounding-box "
            "diagonal (4D for seams); 0 removes only exactly collinear vertices"},
    {.name = "borders", .type = SC_PARAM_ENUM, .def_string = "with_seams", .choices = border_choices,
     .doc = "which surface-boundary chains to straighten: with_seams (those in charts that have a seam), "
            "always, never"},
    {.name = "steps", .type = SC_PARAM_INTEGER, .def = 10, .min = 1, .max = 1000,
     .doc = "harmonic steps of the composite interior warp (repeated with 4x and 16x the steps when faces flip)"},
    {.name = "padding", .type = SC_PARAM_INTEGER, .def = 4, .min = 1, .max = 64,
     .doc = "texels around each moved chart re-rendered from the linear continuation of its border faces"},
    {.name = "erase", .type = SC_PARAM_BOOL, .def = 1,
     .doc = "erase the output's textures, re-rendered or not (the erase kernel with erase_seams's defaults), so "
            "no erase_seams need come first; 0: the re-rendered textures as they are, the input when nothing moves"},
    {.name = "preset", .type = SC_PARAM_ENUM, .def_string = "local", .choices = preset_choices,
     .doc = "the erasure's w_change, as erase_seams's preset: local 1e4 (keep interior texels), global 1e2"},
};

static const sc_port_desc inputs[] = {
    {.name = "atlas", .kind = SC_KIND_ATLAS, .doc = "the textured mesh"},
};

static const sc_port_desc outputs[] = {
    {.name = "atlas", .kind = SC_KIND_ATLAS,
     .doc = "the same surface mesh with straightened seams and boundaries in uv and its textures re-rendered "
            "(f32) and erased; without erase, the input itself when nothing moves"},
    {.name = "atlas_native", .kind = SC_KIND_ATLAS,
     .doc = "the same with each texture in the input's pixel type and encoding (8-bit: optimal rounding, "
            "judged as filtered); without erase, the input itself when nothing moves"},
};

static const sc_kernel *const kernels[] = {&sc_kernel_erase, &sc_kernel_seam, &sc_kernel_sparse, &sc_kernel_tangent,
                                            &sc_kernel_topology, NULL};

const sc_node_desc sc_node_straighten = {
    .type = "straighten",
    .version = 11,
    .summary = "straighten seams and boundaries in uv (Liu et al. 2017 §6) and warp the textures to match",
    .inputs = inputs,
    .ninputs = SC_COUNT(inputs),
    .outputs = outputs,
    .noutputs = SC_COUNT(outputs),
    .params = params,
    .nparams = SC_COUNT(params),
    .run = run,
    .kernels = kernels,
};
