/* sc_seam.c - seams, silhouettes, bilinear sampling and the exact seam
 * operator of Liu et al. 2017 §3-4.
 *
 * Design note.
 *  - Seams and uv silhouettes are read off the edge table (sc_topology),
 *    built with uvs by coordinates: sc_topology.h says why.
 *  - Everything happens in texel space (x = uW - 1/2, y = vH - 1/2): texel
 *    centres are the integer lattice, cells are unit squares, and wrap modes
 *    only act on the texel ids of a cell's corners. That keeps sampling, the
 *    operator and coverage in exact agreement with the renderer's rule.
 *  - An edge (or an edge pair, both sides parametrised by the same gamma) is
 *    split at every texel-grid crossing of either side (eq. 5). On a piece
 *    every bilinear weight is a quadratic in the local parameter tau, so each
 *    integral of §3-4 is a small Gram sum with the exact moments
 *    int_0^1 tau^(a+b) = 1/(a+b+1): no sampling anywhere.
 *  - Assembly runs over fixed chunks of edges on worker threads; each chunk
 *    merges its own duplicates in a small hash, and chunks are appended in
 *    chunk order, so the triplets (and the sums CSC assembly makes of them)
 *    are the same for any thread count.
 *  - Seam chains (for the edge-cluster solver's groups): seam edges join
 *    end to end where two of them go on in the same two charts; a texel's
 *    place along its chain is measured in texels of the longer side, so
 *    that places along one chain compare across its edges.
 */
#include "sc_seam.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "sc_geometry.h"

static const sc_kernel *const seam_uses[] = {&sc_kernel_sparse, &sc_kernel_topology, NULL};
const sc_kernel sc_kernel_seam = {"seam", SC_SEAM_VERSION, seam_uses};

/* exact moments int_0^1 tau^k dtau */
static const double G3[3][3] = {{1.0, 1.0 / 2, 1.0 / 3}, {1.0 / 2, 1.0 / 3, 1.0 / 4},
                                {1.0 / 3, 1.0 / 4, 1.0 / 5}};
static const double G2[2][2] = {{1.0, 1.0 / 2}, {1.0 / 2, 1.0 / 3}};

/* ---------------------------------------------------------------- sampling */

/* floor as an integer, kept finite for absurd coordinates */
static int64_t cell_of(double x) {
    double f = floor(x);
    if (f > 4.0e15) f = 4.0e15;
    if (f < -4.0e15) f = -4.0e15;
    return (int64_t)f;
}

static void cell_ids(const sc_seam_grid *g, int64_t cx, int64_t cy, int32_t id[4]) {
    if (cx >= 0 && cy >= 0 && cx + 1 < g->width && cy + 1 < g->height) {   /* inside: no wrap to apply */
        int32_t at = (int32_t)cy * g->width + (int32_t)cx;
        id[0] = at, id[1] = at + 1, id[2] = at + g->width, id[3] = at + g->width + 1;
        return;
    }
    int32_t i0 = sc_seam_wrap(cx, g->width, g->wrap_u);
    int32_t i1 = sc_seam_wrap(cx + 1, g->width, g->wrap_u);
    int32_t j0 = sc_seam_wrap(cy, g->height, g->wrap_v);
    int32_t j1 = sc_seam_wrap(cy + 1, g->height, g->wrap_v);
    id[0] = j0 * g->width + i0;
    id[1] = j0 * g->width + i1;
    id[2] = j1 * g->width + i0;
    id[3] = j1 * g->width + i1;
}

void sc_seam_taps(const sc_seam_grid *g, double u, double v, int32_t id[4], double w[4]) {
    double x = u * g->width - 0.5, y = v * g->height - 0.5;
    int64_t cx = cell_of(x), cy = cell_of(y);
    double s = x - (double)cx, t = y - (double)cy;
    cell_ids(g, cx, cy, id);
    w[0] = (1 - s) * (1 - t);
    w[1] = s * (1 - t);
    w[2] = (1 - s) * t;
    w[3] = s * t;
}

void sc_seam_sample(const sc_seam_grid *g, const float *pixels, int32_t channels, double u,
                    double v, double *out) {
    int32_t id[4];
    double w[4];
    sc_seam_taps(g, u, v, id, w);
    for (int32_t c = 0; c < channels; c++) {
        double s = 0;
        for (int k = 0; k < 4; k++) s += w[k] * pixels[(size_t)id[k] * (size_t)channels + (size_t)c];
        out[c] = s;
    }
}

/* ---------------------------------------------------------------- topology */

/* the side of half-edge h, expressed at surface vertices v0 -> v1 */
static sc_seam_side side_of(const sc_mesh *m, int32_t h, int32_t v0) {
    int32_t h1 = sc_topology_next(h);
    return (sc_seam_side){.face = h / 3, .uv0 = sc_topology_uv_at(m, h, v0),
                          .uv1 = m->FV[h] == v0 ? m->FU[h1] : m->FU[h],
                          .uv_opp = m->FU[sc_topology_next(h1)]};
}

int sc_seam_from_topology(const sc_mesh *m, const sc_topology *t, sc_seam_set *out, sc_error *err) {
    memset(out, 0, sizeof *out);
    out->material = t->material;
    /* silhouettes: both sides of a seam, a foldover once, every half-edge of
     * a boundary or non-manifold edge */
    int64_t nsil = 0;
    for (int32_t i = 0; i < t->nedges; i++) {
        const sc_topology_edge *e = &t->edges[i];
        nsil += e->kind == SC_EDGE_SEAM       ? 2
                : e->kind == SC_EDGE_FOLDOVER ? 1
                : e->kind == SC_EDGE_INTERIOR ? 0
                                              : e->count;
    }
    out->seams = sc_alloc_array((size_t)t->nseams + 1, sizeof *out->seams);
    out->sil = sc_alloc_array((size_t)nsil + 1, sizeof *out->sil);
    if (!out->seams || !out->sil) {
        sc_seam_set_free(out);
        return sc_fail(err, SC_ENOMEM, "out of memory finding seams");
    }
    for (int32_t i = 0; i < t->nedges; i++) {
        const sc_topology_edge *e = &t->edges[i];
        if (e->kind == SC_EDGE_INTERIOR) continue;
        /* in the orientation of the edge's first half-edge */
        int32_t h0 = t->half[e->first];
        int32_t v0 = m->FV[h0], v1 = m->FV[sc_topology_next(h0)];
        double len = sc_dist3(&m->V[3 * v0], &m->V[3 * v1]);
        if (e->kind == SC_EDGE_SEAM) {
            sc_seam_side a = side_of(m, h0, v0), b = side_of(m, t->half[e->first + 1], v0);
            int32_t si = out->nseams++;
            out->seams[si] = (sc_seam_edge){v0, v1, len, {a, b}};
            out->seam_length += len;
            out->sil[out->nsil++] = (sc_seam_silhouette){v0, v1, len, a, SC_SEAM_SIDE, si};
            out->sil[out->nsil++] = (sc_seam_silhouette){v0, v1, len, b, SC_SEAM_SIDE, si};
            out->sil_length += len;
            out->sil_length += len;
        } else if (e->kind == SC_EDGE_FOLDOVER) {
            out->sil[out->nsil++] = (sc_seam_silhouette){v0, v1, len, side_of(m, h0, v0), SC_SEAM_FOLDOVER, -1};
            out->nfoldover++;
            out->sil_length += len;
        } else {
            /* boundary or non-manifold: every half-edge, in the orientation of its face */
            bool boundary = e->kind == SC_EDGE_BOUNDARY;
            for (int32_t q = 0; q < e->count; q++) {
                int32_t h = t->half[e->first + q], a0 = m->FV[h], a1 = m->FV[sc_topology_next(h)];
                out->sil[out->nsil++] = (sc_seam_silhouette){a0, a1, len, side_of(m, h, a0),
                                                             boundary ? SC_SEAM_BOUNDARY : SC_SEAM_NONMANIFOLD, -1};
                out->sil_length += len;
                if (boundary) out->nboundary++;
                else out->nnonmanifold++;
            }
        }
    }
    return SC_OK;
}

int sc_seam_find(const sc_mesh *m, int32_t material, sc_seam_set *out, sc_error *err) {
    memset(out, 0, sizeof *out);
    sc_topology t;
    sc_topology_options opt = {.material = material, .uv_by_coordinates = true};
    int rc = sc_topology_build(m, &opt, &t, err);
    if (rc == SC_OK) rc = sc_seam_from_topology(m, &t, out, err);
    sc_topology_free(&t);
    return rc;
}

void sc_seam_set_free(sc_seam_set *s) {
    if (!s) return;
    free(s->seams);
    free(s->sil);
    memset(s, 0, sizeof *s);
}

/* ---------------------------------------------------------------- texel sets */

int sc_seam_texset_init(sc_seam_texset *s, int32_t width, int32_t height) {
    memset(s, 0, sizeof *s);
    if (width <= 0 || height <= 0) return SC_EINPUT;
    s->width = width, s->height = height;
    s->words = ((int64_t)width * height + 63) / 64;
    s->bits = sc_calloc_array((size_t)s->words, sizeof *s->bits);
    return s->bits ? SC_OK : SC_ENOMEM;
}

void sc_seam_texset_free(sc_seam_texset *s) {
    if (!s) return;
    free(s->bits);
    free(s->rank);
    memset(s, 0, sizeof *s);
}

int sc_seam_texset_finish(sc_seam_texset *s) {
    free(s->rank);
    s->rank = sc_alloc_array((size_t)s->words + 1, sizeof *s->rank);
    if (!s->rank) return SC_ENOMEM;
    int64_t r = 0;
    for (int64_t w = 0; w < s->words; w++) {
        s->rank[w] = (int32_t)r;
        r += sc_seam_popcount64(s->bits[w]);
    }
    s->rank[s->words] = (int32_t)r;
    s->count = (int32_t)r;
    return SC_OK;
}

int sc_seam_texset_members(const sc_seam_texset *s, int32_t **ids) {
    *ids = sc_alloc_array(s->count ? (size_t)s->count : 1, sizeof **ids);
    if (!*ids) return SC_ENOMEM;
    int32_t k = 0;
    for (int64_t w = 0; w < s->words; w++) {
        uint64_t b = s->bits[w];
        while (b) {
            int bit = __builtin_ctzll(b);
            (*ids)[k++] = (int32_t)(w * 64 + bit);
            b &= b - 1;
        }
    }
    return SC_OK;
}

/* ---------------------------------------------------------------- coverage */

/* Edge function of the directed edge a -> b at p, evaluated the same way
 * (from the lexicographically smaller end) for both directions, so that the
 * two triangles of a shared edge see exactly opposite values. */
static double edge_fn(const double *a, const double *b, double px, double py) {
    if (a[0] < b[0] || (a[0] == b[0] && a[1] < b[1]))
        return (b[0] - a[0]) * (py - a[1]) - (b[1] - a[1]) * (px - a[0]);
    return -((a[0] - b[0]) * (py - b[1]) - (a[1] - b[1]) * (px - b[0]));
}

/* p inside the counter-clockwise triangle, ties broken as if p were moved by
 * (eps, eps^2): a partition of the plane covers every point exactly once. */
static bool edge_owns(const double *a, const double *b, double px, double py) {
    double e = edge_fn(a, b, px, py);
    if (e > 0) return true;
    if (e < 0) return false;
    double dx = b[0] - a[0], dy = b[1] - a[1];
    return dy < 0 || (dy == 0 && dx > 0);
}

/* Covered texels are gathered a 64-bit word at a time and put in with one
 * atomic OR: a bit the word held already is covered twice, so shared. Faces
 * are covered on several threads, and the sets come out the same. */
typedef struct cover_word {
    int64_t word;   /* -1: none yet */
    uint64_t bits;
} cover_word;

static void cover_flush(sc_seam_coverage *c, cover_word *cw) {
    if (cw->word < 0) return;
    uint64_t old = __atomic_fetch_or(&c->covered.bits[cw->word], cw->bits, __ATOMIC_RELAXED);
    if (old & cw->bits) __atomic_fetch_or(&c->shared.bits[cw->word], old & cw->bits, __ATOMIC_RELAXED);
    cw->word = -1, cw->bits = 0;
}

static void cover_id(sc_seam_coverage *c, cover_word *cw, int32_t id) {
    uint64_t bit = (uint64_t)1 << (id & 63);
    if (cw->word != id >> 6 || (cw->bits & bit)) cover_flush(c, cw), cw->word = id >> 6;
    cw->bits |= bit;
}

/* the texel centres x0..x1 (inclusive) of row iy, through the wrap modes */
static void cover_span(sc_seam_coverage *c, const sc_seam_grid *g, int64_t x0, int64_t x1, int64_t iy) {
    const int32_t W = g->width;
    if (g->wrap_v == SC_WRAP_CLAMP && (iy < 0 || iy >= g->height)) return;
    int32_t row = sc_seam_wrap(iy, g->height, g->wrap_v) * W;
    cover_word cw = {-1, 0};
    if (g->wrap_u == SC_WRAP_CLAMP) {
        if (x0 < 0) x0 = 0;
        if (x1 > W - 1) x1 = W - 1;
        for (int64_t x = x0; x <= x1; x++) cover_id(c, &cw, row + (int32_t)x);
    } else if (g->wrap_u == SC_WRAP_REPEAT) {
        int32_t i = sc_seam_wrap(x0, W, SC_WRAP_REPEAT);
        for (int64_t x = x0; x <= x1; x++) {
            cover_id(c, &cw, row + i);
            if (++i == W) i = 0;
        }
    } else {
        for (int64_t x = x0; x <= x1; x++) cover_id(c, &cw, row + sc_seam_wrap(x, W, g->wrap_u));
    }
    cover_flush(c, &cw);
}

/* Face f's uv triangle in texel space (texel (i, j) centred at (i, j)):
 * its corners counter-clockwise in T (when it has an area) and its box
 * (xmin, xmax, ymin, ymax); returns its signed area in uv order (0, or NaN
 * for a non-finite uv). */
static double texel_triangle(const sc_mesh *m, int32_t f, const sc_seam_grid *g, double T[3][2], double box[4]) {
    double P[3][2];
    for (int k = 0; k < 3; k++) {
        const double *uv = &m->U[2 * m->FU[3 * f + k]];
        P[k][0] = uv[0] * g->width - 0.5;
        P[k][1] = uv[1] * g->height - 0.5;
    }
    double area = sc_orient2(P[0], P[1], P[2]);
    memcpy(T[0], P[0], sizeof T[0]);
    memcpy(T[1], area > 0 ? P[1] : P[2], sizeof T[1]);
    memcpy(T[2], area > 0 ? P[2] : P[1], sizeof T[2]);
    box[0] = fmin(T[0][0], fmin(T[1][0], T[2][0])), box[1] = fmax(T[0][0], fmax(T[1][0], T[2][0]));
    box[2] = fmin(T[0][1], fmin(T[1][1], T[2][1])), box[3] = fmax(T[0][1], fmax(T[1][1], T[2][1]));
    return area;
}

#define COVER_FACES_PER_CHUNK 4096

typedef struct cover_job {
    const sc_mesh *m;
    int32_t material;
    const sc_seam_grid *g;
    sc_seam_coverage *out;
    int32_t *bad;   /* per chunk: its first face spanning too many textures (-1: none), then 1 (u) or 2 (v) */
} cover_job;

static int cover_chunk(void *ud, int32_t chunk) {
    cover_job *job = ud;
    const sc_mesh *m = job->m;
    const sc_seam_grid *g = job->g;
    const double W = g->width, H = g->height;
    int32_t f0 = chunk * COVER_FACES_PER_CHUNK, f1 = f0 + COVER_FACES_PER_CHUNK;
    if (f1 > m->nf) f1 = m->nf;
    job->bad[2 * chunk] = -1;
    for (int32_t f = f0; f < f1; f++) {
        if (job->material >= 0 && m->FM[f] != job->material) continue;
        double T[3][2], box[4];
        if (!(texel_triangle(m, f, g, T, box) != 0)) continue; /* zero uv area: covers nothing */
        const double *A = T[0], *B = T[1], *C = T[2];
        double xmin = box[0], xmax = box[1], ymin = box[2], ymax = box[3];
        bool wide_u = g->wrap_u != SC_WRAP_CLAMP && xmax - xmin > 64.0 * W;
        if (wide_u || (g->wrap_v != SC_WRAP_CLAMP && ymax - ymin > 64.0 * H)) {
            job->bad[2 * chunk] = f, job->bad[2 * chunk + 1] = wide_u ? 1 : 2;
            return SC_EINPUT;
        }
        double y0 = ceil(ymin), y1 = floor(ymax);
        if (g->wrap_v == SC_WRAP_CLAMP) y0 = fmax(y0, 0), y1 = fmin(y1, H - 1);
        const double *E[3][2] = {{A, B}, {B, C}, {C, A}};
        for (double y = y0; y <= y1; y++) {
            /* the x interval where all three edge functions are >= 0, widened by one */
            double xl = floor(xmin), xr = ceil(xmax);
            for (int e = 0; e < 3; e++) {
                const double *a = E[e][0], *b = E[e][1];
                double dy = b[1] - a[1];
                if (dy == 0) continue;
                double xc = a[0] + (y - a[1]) * (b[0] - a[0]) / dy; /* E = 0 at xc */
                if (dy < 0) xl = fmax(xl, floor(xc) - 1); /* E = -dy (x - xc) >= 0 for x >= xc */
                else xr = fmin(xr, ceil(xc) + 1);
            }
            if (g->wrap_u == SC_WRAP_CLAMP) xl = fmax(xl, 0), xr = fmin(xr, W - 1);
            /* the row's inside centres form one run (the triangle is convex):
             * find its ends with the exact test, fill between */
            double x0 = xl, x1 = xr;
            while (x0 <= x1 && !(edge_owns(A, B, x0, y) && edge_owns(B, C, x0, y) && edge_owns(C, A, x0, y)))
                x0++;
            while (x1 >= x0 && !(edge_owns(A, B, x1, y) && edge_owns(B, C, x1, y) && edge_owns(C, A, x1, y)))
                x1--;
            if (x0 <= x1) cover_span(job->out, g, (int64_t)x0, (int64_t)x1, (int64_t)y);
        }
    }
    return SC_OK;
}

int sc_seam_coverage_build(const sc_mesh *m, int32_t material, const sc_seam_grid *g, int threads,
                           sc_seam_coverage *out, sc_error *err) {
    memset(out, 0, sizeof *out);
    int32_t chunks = (m->nf + COVER_FACES_PER_CHUNK - 1) / COVER_FACES_PER_CHUNK;
    cover_job job = {m, material, g, out, sc_alloc_array(2 * (size_t)chunks + 2, sizeof *job.bad)};
    if (!job.bad || sc_seam_texset_init(&out->covered, g->width, g->height) != SC_OK ||
        sc_seam_texset_init(&out->shared, g->width, g->height) != SC_OK) {
        free(job.bad);
        sc_seam_coverage_free(out);
        return sc_fail(err, SC_ENOMEM, "out of memory for a %dx%d coverage mask", (int)g->width,
                       (int)g->height);
    }
    if (sc_parallel(threads, chunks, cover_chunk, &job) != SC_OK) {
        for (int32_t c = 0; c < chunks; c++)
            if (job.bad[2 * c] >= 0) {   /* the first face, in face order */
                int32_t f = job.bad[2 * c];
                bool u = job.bad[2 * c + 1] == 1;
                free(job.bad);
                sc_seam_coverage_free(out);
                return sc_fail(err, SC_EINPUT, "face %d: uv triangle spans more than 64 texture %s", (int)f,
                               u ? "widths" : "heights");
            }
        free(job.bad);
        sc_seam_coverage_free(out);
        return sc_fail(err, SC_ENOMEM, "out of memory");
    }
    free(job.bad);
    if (sc_seam_texset_finish(&out->covered) != SC_OK || sc_seam_texset_finish(&out->shared) != SC_OK) {
        sc_seam_coverage_free(out);
        return sc_fail(err, SC_ENOMEM, "out of memory");
    }
    out->ncovered = out->covered.count;
    out->nshared = out->shared.count;
    return SC_OK;
}

void sc_seam_coverage_free(sc_seam_coverage *c) {
    if (!c) return;
    sc_seam_texset_free(&c->covered);
    sc_seam_texset_free(&c->shared);
    c->ncovered = c->nshared = 0;
}

/* Face f's surface area and uv area. */
static void face_areas(const sc_mesh *m, int32_t f, double *area, double *uv_area) {
    double n[3];
    const int32_t *F = m->FV + 3 * (size_t)f, *T = m->FU + 3 * (size_t)f;
    sc_triangle_normal(m->V + 3 * (size_t)F[0], m->V + 3 * (size_t)F[1], m->V + 3 * (size_t)F[2], n);
    const double *a = m->U + 2 * (size_t)T[0], *b = m->U + 2 * (size_t)T[1], *c = m->U + 2 * (size_t)T[2];
    *area = 0.5 * sc_norm3(n);
    *uv_area = 0.5 * fabs((b[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (b[1] - a[1]));
}

double sc_seam_degenerate_uv_fraction(const sc_mesh *m) {
    double surface = 0, uv_total = 0, area, uv;
    for (int32_t f = 0; f < m->nf; f++) {
        face_areas(m, f, &area, &uv);
        surface += area, uv_total += uv;
    }
    if (!(surface > 0)) return 0;
    double density = uv_total / surface, degenerate = 0;
    for (int32_t f = 0; f < m->nf; f++) {
        face_areas(m, f, &area, &uv);
        if (!(uv > 1e-6 * density * area)) degenerate += area;
    }
    return degenerate / surface;
}

/* ---------------------------------------------------------------- taps */

int sc_seam_taps_meet(const sc_mesh *m, int32_t material, const sc_seam_grid *g, const int32_t *chart,
                      int64_t *reached, int64_t *met, sc_error *err) {
    *reached = 0, *met = 0;
    const int32_t W = g->width, H = g->height;
    /* per texel: the first chart that reaches it, -1 none yet, -2 met by two */
    int32_t *owner = sc_alloc_array((size_t)W * (size_t)H, sizeof *owner);
    if (!owner) return sc_fail(err, SC_ENOMEM, "out of memory for a %dx%d tap mask", (int)W, (int)H);
    for (size_t i = 0; i < (size_t)W * (size_t)H; i++) owner[i] = -1;
    for (int32_t f = 0; f < m->nf; f++) {
        if (material >= 0 && m->FM[f] != material) continue;
        double T[3][2], box[4];
        if (!(texel_triangle(m, f, g, T, box) != 0)) continue;
        double xmin = box[0], xmax = box[1], ymin = box[2], ymax = box[3];
        if (!isfinite(xmin) || !isfinite(xmax) || !isfinite(ymin) || !isfinite(ymax)) continue;
        if (xmax - xmin > 64.0 * W || ymax - ymin > 64.0 * H) {
            free(owner);
            return sc_fail(err, SC_EINPUT, "face %d: uv triangle spans more than 64 textures", (int)f);
        }
        const double *E[3][2] = {{T[0], T[1]}, {T[1], T[2]}, {T[2], T[0]}};
        /* the integers within one of the triangle's range, in x and in y
         * (a separating axis of the square and the triangle: none there) */
        for (double y = floor(ymin); y <= ceil(ymax); y++)
            for (double x = floor(xmin); x <= ceil(xmax); x++) {
                /* the open square of half-side 1 around (x, y) meets the
                 * triangle unless one edge has the whole square outside */
                bool in = true;
                for (int e = 0; e < 3 && in; e++) {
                    const double *a = E[e][0], *b = E[e][1];
                    double dx = b[0] - a[0], dy = b[1] - a[1];
                    in = dx * (y - a[1]) - dy * (x - a[0]) + fabs(dx) + fabs(dy) > 0;
                }
                if (!in) continue;
                size_t id = (size_t)sc_seam_wrap((int64_t)y, H, g->wrap_v) * (size_t)W +
                            (size_t)sc_seam_wrap((int64_t)x, W, g->wrap_u);
                if (owner[id] == -1) {
                    owner[id] = chart[f];
                    (*reached)++;
                } else if (owner[id] >= 0 && owner[id] != chart[f]) {
                    owner[id] = -2;
                    (*met)++;
                }
            }
    }
    free(owner);
    return SC_OK;
}

/* ---------------------------------------------------------------- pieces */

static bool grow_gammas(double **buf, int32_t *cap, int64_t need) {
    if (need <= *cap) return true;
    int64_t nc = *cap ? *cap : 64;
    while (nc < need) nc *= 2;
    double *p = sc_realloc_array(*buf, (size_t)nc, sizeof *p);
    if (!p) return false;
    *buf = p;
    *cap = (int32_t)nc;
    return true;
}

/* gamma of every integer crossing of x0 -> x1 (exclusive of the ends), in
 * increasing order */
static int add_axis(double x0, double x1, double **buf, int32_t *cap, int32_t *n) {
    if (!(x0 != x1)) return 0;
    double lo = fmin(x0, x1), hi = fmax(x0, x1);
    double k0 = floor(lo) + 1, k1 = ceil(hi) - 1;
    if (k1 < k0) return 0;
    if (k1 - k0 + 1 > SC_SEAM_MAX_CROSSINGS) return -1;
    int32_t cnt = (int32_t)(k1 - k0 + 1);
    if (!grow_gammas(buf, cap, (int64_t)*n + cnt + 2)) return -1;
    double d = x1 - x0;
    for (int32_t i = 0; i < cnt; i++) {
        int32_t q = d > 0 ? i : cnt - 1 - i;
        double gmm = ((k0 + q) - x0) / d;
        if (gmm > 0 && gmm < 1) (*buf)[(*n)++] = gmm;
    }
    return 0;
}

int32_t sc_seam_crossings(const sc_seam_grid *g, const double a0[2], const double a1[2],
                          const double *b0, const double *b1, double **buf, int32_t *cap) {
    const double W = g->width, H = g->height;
    int32_t n = 0, run[5], nrun = 0;   /* up to four increasing runs, one per side and axis */
    if (!grow_gammas(buf, cap, 2)) return -1;
    (*buf)[n++] = 0;
    for (int side = 0; side < 2; side++) {
        const double *p = side ? b0 : a0, *q = side ? b1 : a1;
        if (!p || !q) continue;
        run[nrun++] = n;
        if (add_axis(p[0] * W - 0.5, q[0] * W - 0.5, buf, cap, &n) < 0) return -1;
        run[nrun++] = n;
        if (add_axis(p[1] * H - 0.5, q[1] * H - 0.5, buf, cap, &n) < 0) return -1;
        if (n > SC_SEAM_MAX_CROSSINGS) return -1;
    }
    run[nrun] = n;
    /* merge the runs through the buffer's second half */
    if (!grow_gammas(buf, cap, 2 * (int64_t)n + 1)) return -1;
    double *gm = *buf, *merged = gm + n;
    int32_t head[4];
    for (int32_t r = 0; r < nrun; r++) head[r] = run[r];
    for (int32_t k = 0; k < n - 1; k++) {
        int32_t best = -1;
        for (int32_t r = 0; r < nrun; r++)
            if (head[r] < run[r + 1] && (best < 0 || gm[head[r]] < gm[head[best]])) best = r;
        merged[k] = gm[head[best]++];
    }
    memcpy(gm + 1, merged, (size_t)(n - 1) * sizeof *gm);
    gm[n++] = 1;
    /* merge near-duplicates (crossings of both sides at the same gamma, corners) */
    int32_t w = 1;
    for (int32_t i = 1; i < n - 1; i++)
        if (gm[i] - gm[w - 1] > 1e-13 && 1.0 - gm[i] > 1e-13) gm[w++] = gm[i];
    gm[w++] = 1;
    return w;
}

void sc_seam_cellpoly_make(const sc_seam_grid *g, const double a[2], const double b[2],
                           const double n[2], sc_seam_cellpoly *out) {
    const double W = g->width, H = g->height;
    double xa = a[0] * W - 0.5, ya = a[1] * H - 0.5;
    double xb = b[0] * W - 0.5, yb = b[1] * H - 0.5;
    int64_t cx = cell_of(0.5 * (xa + xb)), cy = cell_of(0.5 * (ya + yb));
    cell_ids(g, cx, cy, out->id);
    double s0 = xa - (double)cx, ds = xb - xa;
    double t0 = ya - (double)cy, dt = yb - ya;
    /* linear factors in tau: (1-s), s, (1-t), t */
    const double os[2] = {1 - s0, -ds}, ss[2] = {s0, ds};
    const double ot[2] = {1 - t0, -dt}, tt[2] = {t0, dt};
    const double *fs[4] = {os, ss, os, ss}, *ft[4] = {ot, ot, tt, tt};
    for (int k = 0; k < 4; k++) {
        out->q[k][0] = fs[k][0] * ft[k][0];
        out->q[k][1] = fs[k][0] * ft[k][1] + fs[k][1] * ft[k][0];
        out->q[k][2] = fs[k][1] * ft[k][1];
    }
    /* dB/dn = nx dB/ds + ny dB/dt, with
     * dB/ds = (1-t)(p10 - p00) + t (p11 - p01), dB/dt = (1-s)(p01 - p00) + s (p11 - p10) */
    double nx = n ? n[0] : 0, ny = n ? n[1] : 0;
    for (int c = 0; c < 2; c++) {
        out->d[0][c] = -nx * ot[c] - ny * os[c];
        out->d[1][c] = nx * ot[c] - ny * ss[c];
        out->d[2][c] = -nx * tt[c] + ny * os[c];
        out->d[3][c] = nx * tt[c] + ny * ss[c];
    }
}

bool sc_seam_inward_normal(const sc_mesh *m, const sc_seam_grid *g, const sc_seam_side *s,
                           double n[2]) {
    const double W = g->width, H = g->height;
    const double *p0 = &m->U[2 * s->uv0], *p1 = &m->U[2 * s->uv1], *po = &m->U[2 * s->uv_opp];
    double dx = (p1[0] - p0[0]) * W, dy = (p1[1] - p0[1]) * H;
    double ox = (po[0] - p0[0]) * W, oy = (po[1] - p0[1]) * H;
    double len = sqrt(dx * dx + dy * dy), cr = dx * oy - dy * ox;
    n[0] = n[1] = 0;
    if (!(len > 0) || !(cr != 0)) return false;
    if (cr > 0) n[0] = -dy / len, n[1] = dx / len; /* the face is on the left */
    else n[0] = dy / len, n[1] = -dx / len;
    return true;
}

/* ---------------------------------------------------------------- threads */

int sc_seam_parallel(int threads, int32_t nchunks, int (*fn)(void *ud, int32_t chunk), void *ud) {
    return sc_parallel(threads, nchunks, fn, ud);
}

/* ---------------------------------------------------------------- piece walks */

static const double *uvp(const sc_mesh *m, int32_t uv) { return &m->U[2 * uv]; }

static void lerp2(const double *a, const double *b, double t, double out[2]) {
    out[0] = a[0] + t * (b[0] - a[0]);
    out[1] = a[1] + t * (b[1] - a[1]);
}

/* Weight l_e / L of one edge in a normalised sum (uniform when L is 0). */
static double edge_weight(double len, double total, int32_t count) {
    if (total > 0) return len / total;
    return count > 0 ? 1.0 / count : 0;
}

/* A scratch workspace owned by one chunk. */
typedef struct walk {
    double *gm;
    int32_t gcap;
} walk;

/* Linear combination of taps merged by texel id: up to 8 entries. */
typedef struct combo {
    int n;
    int32_t id[8];
    double c[8][3];
} combo;

static void combo_add(combo *cb, int32_t id, const double *poly, int deg, double sign) {
    int k = 0;
    while (k < cb->n && cb->id[k] != id) k++;
    if (k == cb->n) {
        cb->id[k] = id;
        cb->c[k][0] = cb->c[k][1] = cb->c[k][2] = 0;
        cb->n++;
    }
    for (int a = 0; a < deg; a++) cb->c[k][a] += sign * poly[a];
}

/* ---------------------------------------------------------------- marking */

/* The cell of piece i (between grid parameters gm[i] and gm[i + 1]) of
 * the uv segment a0 a1; false for an empty piece. */
static bool piece_cell(const sc_seam_grid *g, const double *a0, const double *a1, const double *gm, int32_t i,
                       sc_seam_cellpoly *cp) {
    if (!(gm[i + 1] > gm[i])) return false;
    double pa[2], pb[2];
    lerp2(a0, a1, gm[i], pa);
    lerp2(a0, a1, gm[i + 1], pb);
    sc_seam_cellpoly_make(g, pa, pb, NULL, cp);
    return true;
}

/* Marks the cells' texels in set and, when given, in seam_set, with atomic
 * ORs: edges are marked on several threads, and the sets come out the same. */
static void mark_pieces(const sc_seam_grid *g, const double *a0, const double *a1,
                        const double *gm, int32_t n, sc_seam_texset *set, sc_seam_texset *seam_set) {
    sc_seam_cellpoly cp;
    for (int32_t i = 0; i + 1 < n; i++)
        if (piece_cell(g, a0, a1, gm, i, &cp))
            for (int k = 0; k < 4; k++) {
                int32_t id = cp.id[k];
                uint64_t bit = (uint64_t)1 << (id & 63);
                for (int t = 0; t < 2; t++) {
                    sc_seam_texset *x = t ? seam_set : set;
                    if (x && !(__atomic_load_n(&x->bits[id >> 6], __ATOMIC_RELAXED) & bit))
                        __atomic_fetch_or(&x->bits[id >> 6], bit, __ATOMIC_RELAXED);
                }
            }
}

/* The pieces of edge q of s (seams split as pairs, exactly as the operator
 * splits them; other silhouettes on their own): its sides into sd, the uv
 * ends of side 0 (a0, a1) and side 1 (b0, b1, NULL for one side) into ends,
 * the grid parameters into w->gm. Returns their count, 0 for an edge with
 * no pieces of its own (a silhouette side of a seam), -1 with err set. */
static int32_t edge_pieces(const sc_mesh *m, const sc_seam_set *s, const sc_seam_grid *g, int32_t q, walk *w,
                           const sc_seam_side *sd[2], const double *ends[4], sc_error *err) {
    sd[0] = sd[1] = NULL;
    if (q < s->nseams) {
        sd[0] = &s->seams[q].side[0], sd[1] = &s->seams[q].side[1];
    } else {
        const sc_seam_silhouette *x = &s->sil[q - s->nseams];
        if (x->kind == SC_SEAM_SIDE) return 0;
        sd[0] = &x->side;
    }
    ends[0] = uvp(m, sd[0]->uv0), ends[1] = uvp(m, sd[0]->uv1);
    ends[2] = sd[1] ? uvp(m, sd[1]->uv0) : NULL, ends[3] = sd[1] ? uvp(m, sd[1]->uv1) : NULL;
    int32_t n = sc_seam_crossings(g, ends[0], ends[1], ends[2], ends[3], &w->gm, &w->gcap);
    if (n < 0)
        sc_fail(err, SC_EINPUT, "face %d: a uv edge crosses more than %d texel lines (uvs out of range?)",
                (int)sd[0]->face, SC_SEAM_MAX_CROSSINGS);
    return n;
}

#define MARK_ITEMS_PER_CHUNK 256

typedef struct mark_job {
    const sc_mesh *m;
    const sc_seam_set *s;
    const sc_seam_grid *g;
    sc_seam_texset *set, *seam_set;
    int32_t *bad;   /* per chunk: its first edge that could not be split, or -1 */
} mark_job;

static int mark_chunk(void *ud, int32_t chunk) {
    mark_job *job = ud;
    const sc_seam_set *s = job->s;
    int32_t q0 = chunk * MARK_ITEMS_PER_CHUNK, q1 = q0 + MARK_ITEMS_PER_CHUNK;
    if (q1 > s->nseams + s->nsil) q1 = s->nseams + s->nsil;
    walk w = {0};
    job->bad[chunk] = -1;
    for (int32_t q = q0; q < q1; q++) {
        const sc_seam_side *sd[2];
        const double *e[4];
        int32_t n = edge_pieces(job->m, s, job->g, q, &w, sd, e, NULL);
        if (n < 0) {
            job->bad[chunk] = q;
            break;
        }
        if (n == 0) continue;
        sc_seam_texset *seam_set = q < s->nseams ? job->seam_set : NULL;
        mark_pieces(job->g, e[0], e[1], w.gm, n, job->set, seam_set);
        if (e[2]) mark_pieces(job->g, e[2], e[3], w.gm, n, job->set, seam_set);
    }
    free(w.gm);
    return job->bad[chunk] >= 0 ? SC_EINPUT : SC_OK;
}

int sc_seam_mark_texels(const sc_mesh *m, const sc_seam_set *s, const sc_seam_grid *g,
                        sc_seam_texset *set, sc_seam_texset *seam_set, int threads, sc_error *err) {
    int32_t chunks = (s->nseams + s->nsil + MARK_ITEMS_PER_CHUNK - 1) / MARK_ITEMS_PER_CHUNK;
    mark_job job = {m, s, g, set, seam_set, sc_alloc_array((size_t)chunks + 1, sizeof *job.bad)};
    if (!job.bad) return sc_fail(err, SC_ENOMEM, "out of memory");
    int rc = sc_parallel(threads, chunks, mark_chunk, &job);
    for (int32_t c = 0; rc != SC_OK && c < chunks; c++)
        if (job.bad[c] >= 0) {   /* the first such edge names the problem */
            walk w = {0};
            const sc_seam_side *sd[2];
            const double *e[4];
            edge_pieces(m, s, g, job.bad[c], &w, sd, e, err);
            free(w.gm);
            break;
        }
    if (rc == SC_ENOMEM) sc_fail(err, SC_ENOMEM, "out of memory");
    free(job.bad);
    return rc;
}

/* The uv a seam edge's side uses at surface vertex v (one of its ends). */
static const double *side_uv_at(const sc_mesh *m, const sc_seam_edge *e, int side, int32_t v) {
    return uvp(m, v == e->v0 ? e->side[side].uv0 : e->side[side].uv1);
}

static bool same_point(const double *a, const double *b) { return a[0] == b[0] && a[1] == b[1]; }

/* Seam edges a and b, both ending at v, go on in the same two charts there
 * (the same two uvs at v). */
static bool joined(const sc_mesh *m, const sc_seam_edge *a, const sc_seam_edge *b, int32_t v) {
    const double *a0 = side_uv_at(m, a, 0, v), *a1 = side_uv_at(m, a, 1, v);
    const double *b0 = side_uv_at(m, b, 0, v), *b1 = side_uv_at(m, b, 1, v);
    return (same_point(a0, b0) && same_point(a1, b1)) || (same_point(a0, b1) && same_point(a1, b0));
}

/* Seam chains: seam edges joined end to end at surface vertices, two at a
 * time, where both go on in the same two charts (the lowest such pair
 * first, where more seam edges meet). Per edge: its chain (the
 * chain's first edge), where along the chain it starts (`start`, in texels
 * of the longer side, summed over the edges before it) and its length
 * there, and whether it runs against the chain (from v1 to v0). A closed
 * chain is cut at the second vertex of its lowest edge. */
typedef struct chains {
    int32_t *chain;
    double *start, *len;
    uint8_t *flip;
} chains;

static void chains_free(chains *c) { free(c->chain), free(c->start), free(c->len), free(c->flip); }

static int make_chains(const sc_mesh *m, const sc_seam_set *s, const sc_seam_grid *g, chains *c) {
    const int32_t ns = s->nseams;
    memset(c, 0, sizeof *c);
    c->chain = sc_alloc_array(ns ? (size_t)ns : 1, sizeof *c->chain);
    c->start = sc_alloc_array(ns ? (size_t)ns : 1, sizeof *c->start);
    c->len = sc_alloc_array(ns ? (size_t)ns : 1, sizeof *c->len);
    c->flip = sc_alloc_array(ns ? (size_t)ns : 1, sizeof *c->flip);
    int32_t *off = sc_calloc_array((size_t)m->nv + 2, sizeof *off);     /* seam edges at each vertex */
    int32_t *inc = sc_alloc_array(2 * (size_t)ns + 1, sizeof *inc);
    int32_t *link = sc_alloc_array(2 * (size_t)ns + 1, sizeof *link);   /* the edge after edge i at its v0, v1 end */
    if (!c->chain || !c->start || !c->len || !c->flip || !off || !inc || !link) {
        free(off), free(inc), free(link), chains_free(c);
        return SC_ENOMEM;
    }
    for (int32_t i = 0; i < ns; i++) {
        const sc_seam_edge *e = &s->seams[i];
        c->chain[i] = -1;
        link[2 * i] = link[2 * i + 1] = -1;
        double l = 0;
        for (int side = 0; side < 2; side++) {
            const double *a = uvp(m, e->side[side].uv0), *b = uvp(m, e->side[side].uv1);
            double du = (b[0] - a[0]) * g->width, dv = (b[1] - a[1]) * g->height;
            l = fmax(l, sqrt(du * du + dv * dv));
        }
        c->len[i] = l;
        if (e->v0 != e->v1) off[e->v0 + 2]++, off[e->v1 + 2]++;
    }
    for (int32_t v = 0; v < m->nv; v++) off[v + 2] += off[v + 1];
    for (int32_t i = 0; i < ns; i++) {   /* edges at each vertex, in index order */
        const sc_seam_edge *e = &s->seams[i];
        if (e->v0 != e->v1) inc[off[e->v0 + 1]++] = i, inc[off[e->v1 + 1]++] = i;
    }
    for (int32_t v = 0; v < m->nv; v++)
        for (int32_t a = off[v]; a < off[v + 1]; a++) {
            int32_t i = inc[a], ei = v == s->seams[i].v0 ? 0 : 1;
            if (link[2 * i + ei] >= 0) continue;
            for (int32_t b = a + 1; b < off[v + 1]; b++) {
                int32_t j = inc[b], ej = v == s->seams[j].v0 ? 0 : 1;
                if (link[2 * j + ej] < 0 && joined(m, &s->seams[i], &s->seams[j], v)) {
                    link[2 * i + ei] = j, link[2 * j + ej] = i;
                    break;
                }
            }
        }
    free(off), free(inc);
#define NEXT_AT(i, v) link[2 * (i) + ((v) == s->seams[i].v0 ? 0 : 1)]
    for (int32_t i0 = 0; i0 < ns; i0++) {
        if (c->chain[i0] >= 0) continue;
        /* walk back from i0's v0 end to the chain's first edge (or round to i0) */
        int32_t first = i0, back = s->seams[i0].v0;
        for (int32_t steps = 0; steps < ns; steps++) {
            int32_t prev = NEXT_AT(first, back);
            if (prev < 0 || prev == i0) break;
            const sc_seam_edge *pe = &s->seams[prev];
            back = pe->v0 == back ? pe->v1 : pe->v0;
            first = prev;
        }
        /* then forward, numbering */
        int32_t e = first, entry = back;
        double at = 0;
        for (int32_t steps = 0; steps < ns && e >= 0 && c->chain[e] < 0; steps++) {
            const sc_seam_edge *se = &s->seams[e];
            c->chain[e] = first;
            c->flip[e] = entry == se->v1;
            c->start[e] = at;
            at += c->len[e];
            int32_t exit = entry == se->v0 ? se->v1 : se->v0;
            int32_t next = exit == back && e != first ? -1 : NEXT_AT(e, exit);
            entry = exit;
            e = next;
        }
    }
#undef NEXT_AT
    free(link);
    return SC_OK;
}

/* The walk of sc_seam_mark_texels, recording for each texel of `index` the
 * first piece that reaches it (and its seam chain). */
int sc_seam_texel_groups(const sc_mesh *m, const sc_seam_set *s, const sc_seam_grid *g,
                         const sc_seam_texset *index, int32_t *group, double *gamma,
                         int32_t *face, sc_error *err) {
    const int32_t n = index->count;
    for (int32_t r = 0; r < n; r++) group[r] = -1, gamma[r] = 0, face[r] = -1;
    chains ch;
    if (make_chains(m, s, g, &ch)) return sc_fail(err, SC_ENOMEM, "out of memory");
    walk w = {0};
    const int32_t multiple = -2;
    for (int32_t q = 0; q < s->nseams + s->nsil; q++) {
        const sc_seam_side *sd[2];
        const double *e[4];
        int32_t np = edge_pieces(m, s, g, q, &w, sd, e, err);
        if (np < 0) {
            free(w.gm);
            chains_free(&ch);
            return SC_EINPUT;
        }
        if (np == 0) continue;
        int32_t id = q < s->nseams ? ch.chain[q] : q;
        for (int side = 0; side < (sd[1] ? 2 : 1); side++) {
            const double *p0 = e[2 * side], *p1 = e[2 * side + 1];
            sc_seam_cellpoly cp;
            for (int32_t i = 0; i + 1 < np; i++) {
                if (!piece_cell(g, p0, p1, w.gm, i, &cp)) continue;
                for (int k = 0; k < 4; k++) {
                    int32_t r = sc_seam_texset_index(index, cp.id[k]);
                    if (r < 0) continue;
                    if (group[r] == -1) {
                        double t = 0.5 * (w.gm[i] + w.gm[i + 1]);
                        if (q < s->nseams) t = ch.start[q] + (ch.flip[q] ? 1 - t : t) * ch.len[q];
                        group[r] = id, gamma[r] = t, face[r] = sd[side]->face;
                    } else if (group[r] != id) {
                        group[r] = multiple;
                    }
                }
            }
        }
    }
    free(w.gm);
    chains_free(&ch);
    for (int32_t r = 0; r < n; r++)
        if (group[r] == multiple) group[r] = -1;
    return SC_OK;
}

/* ---------------------------------------------------------------- assembly */

/* Per-chunk hash of (row, col) -> value, insertion ordered. */
typedef struct acc {
    uint32_t cap;   /* power of two */
    uint64_t *keys; /* UINT64_MAX: empty */
    int32_t *slot;  /* index into the entry list */
    int32_t n, ncap;
    uint64_t *ekey;
    double *eval;
    bool failed;
} acc;

static bool acc_init(acc *a) {
    memset(a, 0, sizeof *a);
    a->cap = 1024;
    a->keys = sc_alloc_array(a->cap, sizeof *a->keys);
    a->slot = sc_alloc_array(a->cap, sizeof *a->slot);
    if (!a->keys || !a->slot) return false;
    memset(a->keys, 0xff, a->cap * sizeof *a->keys);
    return true;
}

static void acc_free(acc *a) {
    free(a->keys), free(a->slot), free(a->ekey), free(a->eval);
    memset(a, 0, sizeof *a);
}

static void acc_clear(acc *a) {
    for (int32_t i = 0; i < a->n; i++) {
        /* remove by re-probing: cheaper than wiping the table for short edges */
        uint64_t k = a->ekey[i];
        uint32_t h = (uint32_t)((k * 0x9E3779B97F4A7C15ull) >> 40) & (a->cap - 1);
        while (a->keys[h] != k) h = (h + 1) & (a->cap - 1);
        a->keys[h] = UINT64_MAX;
    }
    /* the table uses linear probing: clearing entries in place can break
     * probe chains of other keys, but every key is removed here, so none
     * remain to be found */
    a->n = 0;
}

static bool acc_rehash(acc *a) {
    uint32_t nc = a->cap * 2;
    uint64_t *k = sc_alloc_array(nc, sizeof *k);
    int32_t *s = sc_alloc_array(nc, sizeof *s);
    if (!k || !s) {
        free(k), free(s);
        return false;
    }
    memset(k, 0xff, nc * sizeof *k);
    for (int32_t i = 0; i < a->n; i++) {
        uint64_t key = a->ekey[i];
        uint32_t h = (uint32_t)((key * 0x9E3779B97F4A7C15ull) >> 40) & (nc - 1);
        while (k[h] != UINT64_MAX) h = (h + 1) & (nc - 1);
        k[h] = key;
        s[h] = i;
    }
    free(a->keys), free(a->slot);
    a->keys = k, a->slot = s, a->cap = nc;
    return true;
}

static void acc_add_key(acc *a, int32_t r, int32_t c, double v);

static void acc_add(acc *a, int32_t r, int32_t c, double v) {
    if (r > c) acc_add_key(a, c, r, v);
    else acc_add_key(a, r, c, v);
}

/* (r, c) taken as given: also used for (index, channel) right-hand sides */
static void acc_add_key(acc *a, int32_t r, int32_t c, double v) {
    if (a->failed) return;
    uint64_t key = ((uint64_t)(uint32_t)r << 32) | (uint32_t)c;
    uint32_t h = (uint32_t)((key * 0x9E3779B97F4A7C15ull) >> 40) & (a->cap - 1);
    while (a->keys[h] != UINT64_MAX) {
        if (a->keys[h] == key) {
            a->eval[a->slot[h]] += v;
            return;
        }
        h = (h + 1) & (a->cap - 1);
    }
    if (a->n == a->ncap) {
        int32_t nc = a->ncap ? a->ncap * 2 : 512;
        uint64_t *k = sc_realloc_array(a->ekey, (size_t)nc, sizeof *k);
        if (k) a->ekey = k;
        double *x = k ? sc_realloc_array(a->eval, (size_t)nc, sizeof *x) : NULL;
        if (x) a->eval = x;
        if (!k || !x) {
            a->failed = true;
            return;
        }
        a->ncap = nc;
    }
    a->keys[h] = key;
    a->slot[h] = a->n;
    a->ekey[a->n] = key;
    a->eval[a->n] = v;
    a->n++;
    if ((uint32_t)a->n * 2 > a->cap && !acc_rehash(a)) a->failed = true;
}

/* The keys are (row <= column) already: written straight into the room
 * reserved for them. */
static void acc_emit(acc *a, sc_triplets *t) {
    if (!sc_triplets_reserve(t, (size_t)a->n)) return;
    for (int32_t i = 0; i < a->n; i++, t->count++) {
        t->row[t->count] = (int32_t)(a->ekey[i] >> 32);
        t->col[t->count] = (int32_t)(a->ekey[i] & 0xffffffffu);
        t->val[t->count] = a->eval[i];
    }
}

typedef struct rhs_entry {
    int32_t index;
    int32_t channel;
    double value;
} rhs_entry;

typedef struct asm_chunk {
    sc_triplets trip;
    rhs_entry *rhs;
    int32_t nrhs, rhscap;
    int32_t bad_texel; /* a texel id missing from the index, or -1 */
    int rc;
} asm_chunk;

typedef struct asm_job {
    const sc_mesh *m;
    const sc_seam_set *s;
    const sc_seam_grid *g;
    const sc_seam_texset *index;
    const sc_seam_terms *terms;
    int32_t nitems;      /* seams then non-seam silhouettes */
    int32_t *nonseam;    /* silhouette indices of the non-seam ones */
    int32_t first_chunk; /* of the current batch */
    asm_chunk *chunks;
    bool matrix;         /* emit Q's triplets */
    int32_t channels;    /* of the right-hand side */
    /* room each chunk starts with, from the largest chunks so far: lists
     * that grow by doubling copy themselves and fault fresh pages */
    size_t trip_room;
    int32_t rhs_room;
} asm_job;

#define ITEMS_PER_CHUNK 64

static bool push_rhs(asm_chunk *c, int32_t index, int32_t channel, double v) {
    if (c->nrhs == c->rhscap) {
        int32_t nc = c->rhscap ? c->rhscap * 2 : 256;
        rhs_entry *p = sc_realloc_array(c->rhs, (size_t)nc, sizeof *p);
        if (!p) return false;
        c->rhs = p;
        c->rhscap = nc;
    }
    c->rhs[c->nrhs++] = (rhs_entry){index, channel, v};
    return true;
}

/* A right-hand side contribution, merged per item in its own hash. */
static bool add_rhs(const asm_job *job, asm_chunk *ch, acc *a, int32_t index, int32_t channel,
                    double v) {
    (void)job, (void)ch;
    acc_add_key(a, index, channel, v);
    return !a->failed;
}

static bool flush_rhs(asm_chunk *ch, acc *a) {
    for (int32_t i = 0; i < a->n; i++)
        if (!push_rhs(ch, (int32_t)(a->ekey[i] >> 32), (int32_t)(a->ekey[i] & 0xffffffffu), a->eval[i]))
            return false;
    return true;
}

/* Map the texel ids of a combination to unknown indices; false if one is missing. */
static bool to_index(const asm_job *job, asm_chunk *ch, combo *cb) {
    for (int k = 0; k < cb->n; k++) {
        int32_t r = sc_seam_texset_index(job->index, cb->id[k]);
        if (r < 0) {
            ch->bad_texel = cb->id[k];
            return false;
        }
        cb->id[k] = r;
    }
    return true;
}

/* scale * h * int_0^1 (c_k . tau) (c_l . tau) for all pairs of a combination */
static void add_gram(acc *a, const combo *cb, int deg, double scale) {
    const double(*G)[3] = G3;
    for (int k = 0; k < cb->n; k++)
        for (int l = k; l < cb->n; l++) {
            double v = 0;
            for (int x = 0; x < deg; x++)
                for (int y = 0; y < deg; y++)
                    v += cb->c[k][x] * cb->c[l][y] * (deg == 3 ? G[x][y] : G2[x][y]);
            acc_add(a, cb->id[k], cb->id[l], scale * v);
        }
}

/* wm * int (m_k m_l) + wd * int (d_k d_l) over two combinations with the
 * same texels in the same order (m quadratic, d linear) */
static void add_gram2(acc *a, const combo *m, const combo *d, double wm, double wd) {
    for (int k = 0; k < m->n; k++) {
        const double *mk = m->c[k], *dk = d->c[k];
        double gm[3], gd[2];
        for (int y = 0; y < 3; y++) gm[y] = mk[0] * G3[0][y] + mk[1] * G3[1][y] + mk[2] * G3[2][y];
        for (int y = 0; y < 2; y++) gd[y] = dk[0] * G2[0][y] + dk[1] * G2[1][y];
        for (int l = k; l < m->n; l++) {
            const double *ml = m->c[l], *dl = d->c[l];
            double v = wm * (gm[0] * ml[0] + gm[1] * ml[1] + gm[2] * ml[2]);
            if (wd != 0) v += wd * (gd[0] * dl[0] + gd[1] * dl[1]);
            acc_add(a, m->id[k], m->id[l], v);
        }
    }
}

/* E_outside / E_lerp of one side on one piece */
/* p0 along a combination: the polynomial sum_k c_k(tau) p0[texel_k] of channel c */
static void poly_of(const sc_image_data *p0, const combo *cb, const int32_t *texel, int deg,
                    int32_t c, double out[3]) {
    out[0] = out[1] = out[2] = 0;
    for (int k = 0; k < cb->n; k++) {
        double v = sc_seam_texel(p0, texel[k], c);
        for (int x = 0; x < deg; x++) out[x] += cb->c[k][x] * v;
    }
}

/* E_outside / E_lerp of one side on one piece. The residual -1/2 grad E at
 * p0: E_outside is minimal there (nothing to add); E_lerp adds
 * int q_k (l - B(p0)). */
static bool side_terms(const asm_job *job, asm_chunk *ch, acc *a, acc *ra,
                       const sc_seam_cellpoly *cp, double h, double wout, double wlerp,
                       const double *la, const double *lb) {
    const sc_seam_terms *t = job->terms;
    combo cb = {0};
    for (int k = 0; k < 4; k++) combo_add(&cb, cp->id[k], cp->q[k], 3, 1.0);
    int32_t texel[8];
    for (int k = 0; k < cb.n; k++) texel[k] = cb.id[k];
    if (!to_index(job, ch, &cb)) return false;
    if (job->matrix) add_gram(a, &cb, 3, (wout + wlerp) * h);
    if (!t->rhs || !(wlerp > 0 && la)) return true;
    int32_t C = job->channels;
    for (int32_t c = 0; c < C; c++) {
        double b0[3], e[3];
        poly_of(t->p0, &cb, texel, 3, c, b0);
        /* l(tau) - B(p0)(tau), a quadratic */
        e[0] = la[c] - b0[0], e[1] = (lb[c] - la[c]) - b0[1], e[2] = -b0[2];
        for (int k = 0; k < cb.n; k++) {
            double g = 0;
            for (int x = 0; x < 3; x++)
                for (int y = 0; y < 3; y++) g += cb.c[k][x] * e[y] * G3[x][y];
            if (g != 0 && !add_rhs(job, ch, ra, cb.id[k], c, wlerp * h * g)) return false;
        }
    }
    return true;
}

/* The residual of the seam and C1 terms at p0: -(wm int m_k (m . p0) +
 * wd int d_k (d . p0)), with m . p0 and d . p0 formed first (a difference of
 * two reconstructions), so a seam-free p0 gives an exact zero. */
static bool pair_residual(const asm_job *job, asm_chunk *ch, acc *a, const combo *m, const combo *d,
                          const int32_t *texel, double wm, double wd) {
    const sc_seam_terms *t = job->terms;
    for (int32_t c = 0; c < job->channels; c++) {
        double pm[3], pd[3];
        poly_of(t->p0, m, texel, 3, c, pm);
        poly_of(t->p0, d, texel, 2, c, pd);
        for (int k = 0; k < m->n; k++) {
            double v = 0;
            if (wm != 0)
                for (int x = 0; x < 3; x++)
                    for (int y = 0; y < 3; y++) v += wm * m->c[k][x] * pm[y] * G3[x][y];
            if (wd != 0)
                for (int x = 0; x < 2; x++)
                    for (int y = 0; y < 2; y++) v += wd * d->c[k][x] * pd[y] * G2[x][y];
            if (v != 0 && !add_rhs(job, ch, a, m->id[k], c, -v)) return false;
        }
    }
    return true;
}

static int asm_chunk_run(void *ud, int32_t chunk_in_batch) {
    asm_job *job = ud;
    int32_t chunk = job->first_chunk + chunk_in_batch;
    asm_chunk *ch = &job->chunks[chunk_in_batch];
    const sc_mesh *m = job->m;
    const sc_seam_set *s = job->s;
    const sc_seam_grid *g = job->g;
    const sc_seam_terms *t = job->terms;
    sc_triplets_init(&ch->trip, job->index->count > 0 ? job->index->count : 1);
    ch->bad_texel = -1;
    if (job->matrix && job->trip_room && !sc_triplets_reserve(&ch->trip, job->trip_room)) return ch->rc = SC_ENOMEM;
    if (job->rhs_room) {
        if (!(ch->rhs = sc_alloc_array((size_t)job->rhs_room, sizeof *ch->rhs))) return ch->rc = SC_ENOMEM;
        ch->rhscap = job->rhs_room;
    }
    acc a, ra; /* matrix entries; right-hand side entries (index, channel) */
    walk w = {0};
    bool ok_a = acc_init(&a), ok_ra = acc_init(&ra);
    if (!ok_a || !ok_ra) {
        acc_free(&a), acc_free(&ra);
        return ch->rc = SC_ENOMEM;
    }
    int32_t C = job->channels;
    double *la = NULL, *lb = NULL;
    if (t->w_lerp > 0 && t->vertex_values && t->rhs && C > 0) {
        la = sc_alloc_array((size_t)C, sizeof *la);
        lb = sc_alloc_array((size_t)C, sizeof *lb);
        if (!la || !lb) {
            free(la), free(lb), acc_free(&a), acc_free(&ra);
            return ch->rc = SC_ENOMEM;
        }
    }
    int rc = SC_OK;
    int32_t i0 = chunk * ITEMS_PER_CHUNK, i1 = i0 + ITEMS_PER_CHUNK;
    if (i1 > job->nitems) i1 = job->nitems;
    for (int32_t it = i0; it < i1 && rc == SC_OK; it++) {
        /* the item: a seam pair, or a single non-seam silhouette */
        const sc_seam_side *sides[2];
        int nsides;
        int32_t v0, v1;
        double wseam = 0, wc1 = 0, wsil = 0;
        bool c1_ok = false;
        double n0[2] = {0, 0}, n1[2] = {0, 0};
        if (it < s->nseams) {
            const sc_seam_edge *e = &s->seams[it];
            sides[0] = &e->side[0], sides[1] = &e->side[1], nsides = 2;
            v0 = e->v0, v1 = e->v1;
            double we = edge_weight(e->length, s->seam_length, s->nseams);
            wseam = t->w_seam * we;
            wc1 = t->w_c1 * we;
            wsil = edge_weight(e->length, s->sil_length, s->nsil);
            c1_ok = wc1 > 0 && sc_seam_inward_normal(m, g, sides[0], n0) &&
                    sc_seam_inward_normal(m, g, sides[1], n1);
        } else {
            const sc_seam_silhouette *x = &s->sil[job->nonseam[it - s->nseams]];
            sides[0] = &x->side, sides[1] = NULL, nsides = 1;
            v0 = x->v0, v1 = x->v1;
            wsil = edge_weight(x->length, s->sil_length, s->nsil);
        }
        double wout = job->matrix ? t->w_outside * wsil : 0; /* no residual at p0 */
        double wlerp = (job->matrix || la) ? t->w_lerp * wsil : 0;
        if (wseam == 0 && wc1 == 0 && wout == 0 && wlerp == 0) continue;
        const double *a0 = uvp(m, sides[0]->uv0), *a1 = uvp(m, sides[0]->uv1);
        const double *b0 = nsides > 1 ? uvp(m, sides[1]->uv0) : NULL;
        const double *b1 = nsides > 1 ? uvp(m, sides[1]->uv1) : NULL;
        int32_t n = sc_seam_crossings(g, a0, a1, b0, b1, &w.gm, &w.gcap);
        if (n < 0) {
            rc = SC_EINPUT;
            ch->bad_texel = -2 - sides[0]->face;
            break;
        }
        acc_clear(&a);
        acc_clear(&ra);
        for (int32_t i = 0; i + 1 < n && rc == SC_OK; i++) {
            double ga = w.gm[i], gb = w.gm[i + 1], h = gb - ga;
            if (!(h > 0)) continue;
            sc_seam_cellpoly cp[2];
            for (int q = 0; q < nsides; q++) {
                double pa[2], pb[2];
                const double *e0 = q ? b0 : a0, *e1 = q ? b1 : a1;
                lerp2(e0, e1, ga, pa);
                lerp2(e0, e1, gb, pb);
                sc_seam_cellpoly_make(g, pa, pb, q ? n1 : n0, &cp[q]);
            }
            if (wseam > 0 || c1_ok) {
                /* m(tau) = B(e1) - B(e2) (eq. 4) and dB/dn1 (e1) + dB/dn2 (e2) (E_C1)
                 * share their texels: one pass adds both Gram matrices */
                combo m1 = {0}, d1 = {0};
                for (int k = 0; k < 4; k++) {
                    combo_add(&m1, cp[0].id[k], cp[0].q[k], 3, 1.0);
                    combo_add(&d1, cp[0].id[k], cp[0].d[k], 2, 1.0);
                }
                for (int k = 0; k < 4; k++) {
                    combo_add(&m1, cp[1].id[k], cp[1].q[k], 3, -1.0);
                    combo_add(&d1, cp[1].id[k], cp[1].d[k], 2, c1_ok ? 1.0 : 0.0);
                }
                int32_t texel[8];
                for (int k = 0; k < m1.n; k++) texel[k] = m1.id[k];
                if (!to_index(job, ch, &m1)) {
                    rc = SC_EINPUT;
                    break;
                }
                if (job->matrix) add_gram2(&a, &m1, &d1, wseam * h, c1_ok ? wc1 * h : 0);
                if (t->rhs && !pair_residual(job, ch, &ra, &m1, &d1, texel, wseam * h, c1_ok ? wc1 * h : 0)) {
                    rc = SC_ENOMEM;
                    break;
                }
            }
            if (wout > 0 || wlerp > 0) {
                for (int q = 0; q < nsides; q++) {
                    double *pla = NULL, *plb = NULL;
                    if (wlerp > 0 && la) {
                        const double *x0 = &t->vertex_values[(size_t)v0 * (size_t)C];
                        const double *x1 = &t->vertex_values[(size_t)v1 * (size_t)C];
                        for (int32_t c = 0; c < C; c++) {
                            la[c] = x0[c] + ga * (x1[c] - x0[c]);
                            lb[c] = x0[c] + gb * (x1[c] - x0[c]);
                        }
                        pla = la, plb = lb;
                    }
                    if (!side_terms(job, ch, &a, &ra, &cp[q], h, wout, wlerp, pla, plb)) {
                        rc = ch->bad_texel >= 0 ? SC_EINPUT : SC_ENOMEM;
                        break;
                    }
                }
            }
        }
        if (a.failed || ra.failed) rc = SC_ENOMEM;
        if (rc == SC_OK && job->matrix) acc_emit(&a, &ch->trip);
        if (rc == SC_OK && !flush_rhs(ch, &ra)) rc = SC_ENOMEM;
        if (ch->trip.failed) rc = SC_ENOMEM;
    }
    free(la), free(lb), free(w.gm);
    acc_free(&a), acc_free(&ra);
    return ch->rc = rc;
}

int sc_seam_assemble(const sc_mesh *m, const sc_seam_set *s, const sc_seam_grid *g,
                     const sc_seam_texset *index, const sc_seam_terms *terms, int threads,
                     sc_triplet_parts *out, sc_error *err) {
    asm_job job = {m, s, g, index, terms, 0, NULL, 0, NULL, out != NULL, 0, 0, 0};
    if (terms->rhs && terms->p0) job.channels = terms->p0->channels;
    else if (terms->rhs) return sc_fail(err, SC_EINPUT, "seam operator: a right-hand side needs p0");
    int32_t nonseam = 0;
    for (int32_t q = 0; q < s->nsil; q++) nonseam += s->sil[q].kind != SC_SEAM_SIDE;
    bool sil_terms = terms->w_outside > 0 || terms->w_lerp > 0;
    job.nitems = s->nseams;
    if (sil_terms && nonseam > 0) {
        job.nonseam = sc_alloc_array((size_t)nonseam, sizeof *job.nonseam);
        if (!job.nonseam) return sc_fail(err, SC_ENOMEM, "out of memory");
        int32_t k = 0;
        for (int32_t q = 0; q < s->nsil; q++)
            if (s->sil[q].kind != SC_SEAM_SIDE) job.nonseam[k++] = q;
        job.nitems += nonseam;
    }
    int32_t nchunks = (job.nitems + ITEMS_PER_CHUNK - 1) / ITEMS_PER_CHUNK;
    int32_t batch = threads < 1 ? 4 : 4 * threads;
    job.chunks = sc_calloc_array((size_t)batch, sizeof *job.chunks);
    if (!job.chunks) {
        free(job.nonseam);
        return sc_fail(err, SC_ENOMEM, "out of memory");
    }
    int rc = SC_OK;
    for (int32_t c0 = 0; c0 < nchunks && rc == SC_OK; c0 += batch) {
        int32_t nb = nchunks - c0 < batch ? nchunks - c0 : batch;
        job.first_chunk = c0;
        memset(job.chunks, 0, (size_t)nb * sizeof *job.chunks);
        int prc = sc_seam_parallel(threads, nb, asm_chunk_run, &job);
        for (int32_t b = 0; b < nb; b++) {
            asm_chunk *ch = &job.chunks[b];
            size_t room = ch->trip.count + ch->trip.count / 8;
            if (room > job.trip_room) job.trip_room = room;
            if (ch->nrhs + ch->nrhs / 8 > job.rhs_room) job.rhs_room = ch->nrhs + ch->nrhs / 8;
            if (rc == SC_OK && ch->rc == SC_OK) {
                if (out) sc_triplet_parts_take(out, &ch->trip);
                for (int32_t r = 0; r < ch->nrhs && terms->rhs; r++)
                    terms->rhs[(size_t)ch->rhs[r].channel * (size_t)index->count +
                               (size_t)ch->rhs[r].index] += ch->rhs[r].value;
            } else if (rc == SC_OK) {
                /* the first failing chunk (in chunk order) names the problem */
                if (ch->bad_texel >= 0)
                    rc = sc_fail(err, SC_EINPUT, "seam operator: texel %d is not among the unknowns",
                                 (int)ch->bad_texel);
                else if (ch->bad_texel <= -2)
                    rc = sc_fail(err, SC_EINPUT,
                                 "face %d: a uv edge crosses more than %d texel lines (uvs out of range?)",
                                 (int)(-2 - ch->bad_texel), SC_SEAM_MAX_CROSSINGS);
                else
                    rc = sc_fail(err, SC_ENOMEM, "out of memory assembling the seam operator");
            }
            sc_triplets_free(&ch->trip);
            free(ch->rhs);
        }
        if (rc == SC_OK && prc != SC_OK) rc = sc_fail(err, prc, "out of memory assembling the seam operator");
        if (rc == SC_OK && out && out->failed) rc = sc_fail(err, SC_ENOMEM, "out of memory assembling the seam operator");
    }
    free(job.chunks);
    free(job.nonseam);
    return rc;
}

/* ---------------------------------------------------------------- energy */

bool sc_seam_reader_make(const sc_image_data *img, bool decode, sc_seam_reader *r) {
    memset(r, 0, sizeof *r);
    if (!decode || img->colorspace != SC_COLOR_SRGB) return true;
    for (int32_t c = 0; c < img->channels && c < SC_SEAM_MAX_CHANNELS; c++)
        r->any |= r->decode[c] = !sc_channel_is_alpha(img->channels, c);
    if (!r->any || img->pixel == SC_PIXEL_F32) return true;
    r->table = sc_srgb_decode_table(img->pixel);
    return r->table != NULL;
}

void sc_seam_reader_free(sc_seam_reader *r) {
    free(r->table);
    r->table = NULL;
}

void sc_seam_sample_read(const sc_seam_grid *g, const sc_image_data *img, const sc_seam_reader *r, double u,
                         double v, double *out) {
    int32_t id[4];
    double w[4];
    sc_seam_taps(g, u, v, id, w);
    const size_t C = (size_t)img->channels;
    if (!r->any && img->pixel == SC_PIXEL_U8) {   /* read as stored, the common case: sc_seam_texel's values */
        const uint8_t *px = img->pixels;
        for (size_t c = 0; c < C; c++) {
            double s = 0;
            for (int k = 0; k < 4; k++) s += w[k] * (double)(px[(size_t)id[k] * C + c] * (1.0f / 255.0f));
            out[c] = s;
        }
        return;
    }
    if (!r->any && img->pixel == SC_PIXEL_F32) {
        const float *px = img->pixels;
        for (size_t c = 0; c < C; c++) {
            double s = 0;
            for (int k = 0; k < 4; k++) s += w[k] * (double)px[(size_t)id[k] * C + c];
            out[c] = s;
        }
        return;
    }
    for (int32_t c = 0; c < img->channels; c++) {
        double s = 0;
        for (int k = 0; k < 4; k++) s += w[k] * sc_seam_read(img, r, id[k], c);
        out[c] = s;
    }
}

typedef struct energy_job {
    const sc_mesh *m;
    const sc_seam_set *s;
    const sc_seam_grid *g;
    const sc_image_data *const *imgs;
    sc_seam_reader read[SC_SEAM_ENERGY_IMAGES];
    int32_t same[SC_SEAM_ENERGY_IMAGES][SC_SEAM_MAX_CHANNELS];   /* sc_seam_same_channels of each image */
    int count;
    double *d;   /* per image, per seam */
    double *gap; /* per image, per seam */
    int failed_face;
} energy_job;

/* Channels of img equal to an earlier channel at every texel: src[c] names
 * that channel (-1: none). Grey images stored as RGB are common (gloss,
 * roughness and occlusion maps); the energies then take each piece's
 * integral once and add it once per channel, in the same order: the same
 * bits. Stops at the first difference, so colour images cost little. */
int32_t sc_seam_same_channels(const sc_image_data *img, int32_t src[SC_SEAM_MAX_CHANNELS]) {
    const int32_t C = img->channels < SC_SEAM_MAX_CHANNELS ? img->channels : SC_SEAM_MAX_CHANNELS;
    const size_t texels = (size_t)img->width * (size_t)img->height, stride = (size_t)img->channels;
    int32_t unique = 0;
    for (int32_t c = 0; c < C; c++) {
        src[c] = -1;
        for (int32_t e = 0; e < c && src[c] < 0; e++) {
            if (src[e] >= 0) continue;
            size_t t = 0;
            if (img->pixel == SC_PIXEL_U8) {
                const uint8_t *p = img->pixels;
                while (t < texels && p[t * stride + c] == p[t * stride + e]) t++;
            } else if (img->pixel == SC_PIXEL_U16) {
                const uint16_t *p = img->pixels;
                while (t < texels && p[t * stride + c] == p[t * stride + e]) t++;
            } else {
                const float *p = img->pixels;   /* bit patterns: -0 and +0 (or two NaNs) differ */
                while (t < texels && memcmp(&p[t * stride + c], &p[t * stride + e], sizeof *p) == 0) t++;
            }
            if (t == texels) src[c] = e;
        }
        unique += src[c] < 0;
    }
    for (int32_t c = C; c < SC_SEAM_MAX_CHANNELS; c++) src[c] = -1;
    return unique + (img->channels > C ? img->channels - C : 0);
}

/* D of one seam edge (eq. 9 before weighting, summed over channels) and its
 * largest sampled gap, for each of `count` images of the grid's size: the
 * pieces are found once and read in every image. */
static void edge_energy_gap(const sc_mesh *m, const sc_seam_edge *e, const sc_seam_grid *g,
                            const sc_image_data *const *imgs, const sc_seam_reader *read,
                            const int32_t (*same)[SC_SEAM_MAX_CHANNELS], int count, walk *w, double *d_out,
                            double *gap_out, bool *ok) {
    const double *a0 = uvp(m, e->side[0].uv0), *a1 = uvp(m, e->side[0].uv1);
    const double *b0 = uvp(m, e->side[1].uv0), *b1 = uvp(m, e->side[1].uv1);
    int32_t n = sc_seam_crossings(g, a0, a1, b0, b1, &w->gm, &w->gcap);
    *ok = n >= 0;
    for (int im = 0; im < count; im++) d_out[im] = 0, gap_out[im] = 0;
    for (int32_t i = 0; i + 1 < n; i++) {
        double ga = w->gm[i], gb = w->gm[i + 1], h = gb - ga;
        if (!(h > 0)) continue;
        sc_seam_cellpoly cp[2];
        double pa[2], pb[2];
        lerp2(a0, a1, ga, pa), lerp2(a0, a1, gb, pb);
        sc_seam_cellpoly_make(g, pa, pb, NULL, &cp[0]);
        lerp2(b0, b1, ga, pa), lerp2(b0, b1, gb, pb);
        sc_seam_cellpoly_make(g, pa, pb, NULL, &cp[1]);
        for (int im = 0; im < count; im++) {
            const sc_image_data *img = imgs[im];
            double d = d_out[im], gap = gap_out[im];
            double vch[SC_SEAM_MAX_CHANNELS];
            for (int32_t c = 0; c < img->channels; c++) {
                if (c < SC_SEAM_MAX_CHANNELS && same[im][c] >= 0) {   /* the same integral as its channel's */
                    d += h * vch[same[im][c]];
                    continue;
                }
                double q[3] = {0, 0, 0};
                for (int side = 0; side < 2; side++)
                    for (int k = 0; k < 4; k++) {
                        double p = sc_seam_read(img, &read[im], cp[side].id[k], c);
                        double sg = side ? -1.0 : 1.0;
                        for (int x = 0; x < 3; x++) q[x] += sg * cp[side].q[k][x] * p;
                    }
                double v = 0;
                for (int x = 0; x < 3; x++)
                    for (int y = 0; y < 3; y++) v += q[x] * q[y] * G3[x][y];
                if (c < SC_SEAM_MAX_CHANNELS) vch[c] = v;
                d += h * v;
                for (int k = 0; k <= 4; k++) {
                    double tau = 0.25 * k, val = fabs(q[0] + tau * (q[1] + tau * q[2]));
                    if (val > gap) gap = val;
                }
            }
            d_out[im] = d, gap_out[im] = gap;
        }
    }
}

typedef struct trace_job {
    const sc_mesh *m;
    const sc_seam_set *s;
    const sc_seam_grid *g;
    double *part; /* per chunk */
    int failed_face;
} trace_job;

static int trace_chunk(void *ud, int32_t chunk) {
    trace_job *job = ud;
    const sc_mesh *m = job->m;
    walk w = {0};
    int32_t i0 = chunk * ITEMS_PER_CHUNK, i1 = i0 + ITEMS_PER_CHUNK;
    if (i1 > job->s->nseams) i1 = job->s->nseams;
    double sum = 0;
    for (int32_t i = i0; i < i1; i++) {
        const sc_seam_edge *e = &job->s->seams[i];
        const double *a0 = uvp(m, e->side[0].uv0), *a1 = uvp(m, e->side[0].uv1);
        const double *b0 = uvp(m, e->side[1].uv0), *b1 = uvp(m, e->side[1].uv1);
        int32_t n = sc_seam_crossings(job->g, a0, a1, b0, b1, &w.gm, &w.gcap);
        if (n < 0) {
            job->failed_face = e->side[0].face;
            free(w.gm);
            return SC_EINPUT;
        }
        double te = 0;
        for (int32_t k = 0; k + 1 < n; k++) {
            double ga = w.gm[k], gb = w.gm[k + 1], h = gb - ga;
            if (!(h > 0)) continue;
            sc_seam_cellpoly cp[2];
            double pa[2], pb[2];
            lerp2(a0, a1, ga, pa), lerp2(a0, a1, gb, pb);
            sc_seam_cellpoly_make(job->g, pa, pb, NULL, &cp[0]);
            lerp2(b0, b1, ga, pa), lerp2(b0, b1, gb, pb);
            sc_seam_cellpoly_make(job->g, pa, pb, NULL, &cp[1]);
            combo c = {0};
            for (int q = 0; q < 4; q++) combo_add(&c, cp[0].id[q], cp[0].q[q], 3, 1.0);
            for (int q = 0; q < 4; q++) combo_add(&c, cp[1].id[q], cp[1].q[q], 3, -1.0);
            for (int q = 0; q < c.n; q++)
                for (int x = 0; x < 3; x++)
                    for (int y = 0; y < 3; y++) te += h * c.c[q][x] * c.c[q][y] * G3[x][y];
        }
        sum += edge_weight(e->length, job->s->seam_length, job->s->nseams) * te;
    }
    job->part[chunk] = sum;
    free(w.gm);
    return SC_OK;
}

int sc_seam_trace(const sc_mesh *m, const sc_seam_set *s, const sc_seam_grid *g, int threads,
                  double *trace, sc_error *err) {
    *trace = 0;
    int32_t nchunks = (s->nseams + ITEMS_PER_CHUNK - 1) / ITEMS_PER_CHUNK;
    if (nchunks == 0) return SC_OK;
    trace_job job = {m, s, g, sc_calloc_array((size_t)nchunks, sizeof(double)), -1};
    if (!job.part) return sc_fail(err, SC_ENOMEM, "out of memory");
    int rc = sc_seam_parallel(threads, nchunks, trace_chunk, &job);
    if (rc == SC_OK)
        for (int32_t c = 0; c < nchunks; c++) *trace += job.part[c];
    else if (rc == SC_EINPUT)
        sc_fail(err, rc, "face %d: a uv edge crosses more than %d texel lines (uvs out of range?)",
                job.failed_face, SC_SEAM_MAX_CROSSINGS);
    else
        sc_fail(err, rc, "out of memory");
    free(job.part);
    return rc;
}

double sc_seam_edge_energy(const sc_mesh *m, const sc_seam_edge *e, const sc_seam_grid *g,
                           const sc_image_data *img) {
    walk w = {0};
    bool ok;
    double d, gap;
    const int32_t none[1][SC_SEAM_MAX_CHANNELS] = {{-1, -1, -1, -1}};
    const sc_seam_reader stored = {0};
    edge_energy_gap(m, e, g, &img, &stored, none, 1, &w, &d, &gap, &ok);
    free(w.gm);
    return ok ? d : NAN;
}

static int energy_chunk(void *ud, int32_t chunk) {
    energy_job *job = ud;
    walk w = {0};
    int32_t i0 = chunk * ITEMS_PER_CHUNK, i1 = i0 + ITEMS_PER_CHUNK;
    if (i1 > job->s->nseams) i1 = job->s->nseams;
    int rc = SC_OK;
    for (int32_t i = i0; i < i1; i++) {
        bool ok;
        double d[SC_SEAM_ENERGY_IMAGES], gap[SC_SEAM_ENERGY_IMAGES];
        edge_energy_gap(job->m, &job->s->seams[i], job->g, job->imgs, job->read, job->same, job->count, &w, d, gap,
                        &ok);
        for (int im = 0; im < job->count; im++) {
            job->d[(size_t)im * job->s->nseams + i] = d[im];
            job->gap[(size_t)im * job->s->nseams + i] = gap[im];
        }
        if (!ok) {
            job->failed_face = job->s->seams[i].side[0].face;
            rc = SC_EINPUT;
            break;
        }
    }
    free(w.gm);
    return rc;
}

int sc_seam_energies(const sc_mesh *m, const sc_seam_set *s, const sc_seam_grid *g,
                     const sc_image_data *const *imgs, int count, int threads, double *energy,
                     double *max_gap, sc_error *err) {
    return sc_seam_energies_decoded(m, s, g, imgs, NULL, count, threads, energy, max_gap, err);
}

int sc_seam_energies_decoded(const sc_mesh *m, const sc_seam_set *s, const sc_seam_grid *g,
                             const sc_image_data *const *imgs, const bool *decode, int count, int threads,
                             double *energy, double *max_gap, sc_error *err) {
    if (count < 1 || count > SC_SEAM_ENERGY_IMAGES)
        return sc_fail(err, SC_EINPUT, "seam energy of %d images at once (1 to %d)", count,
                       SC_SEAM_ENERGY_IMAGES);
    for (int im = 0; im < count; im++) {
        if (energy) energy[im] = 0;
        if (max_gap) max_gap[im] = 0;
    }
    if (s->nseams == 0) return SC_OK;
    energy_job job = {.m = m, .s = s, .g = g, .imgs = imgs, .count = count, .failed_face = -1};
    bool readers = true;
    for (int im = 0; im < count; im++) {
        readers &= sc_seam_reader_make(imgs[im], decode && decode[im], &job.read[im]);
        sc_seam_same_channels(imgs[im], job.same[im]);
        /* a decoded channel equals a stored one only by chance: measured apart (the same bits) */
        for (int32_t c = 0; c < SC_SEAM_MAX_CHANNELS; c++)
            if (job.same[im][c] >= 0 && job.read[im].decode[c] != job.read[im].decode[job.same[im][c]])
                job.same[im][c] = -1;
    }
    size_t len = (size_t)s->nseams * (size_t)count;
    job.d = readers ? sc_alloc_array(len, sizeof *job.d) : NULL;
    job.gap = readers ? sc_alloc_array(len, sizeof *job.gap) : NULL;
    if (!job.d || !job.gap) {
        free(job.d), free(job.gap);
        for (int im = 0; im < count; im++) sc_seam_reader_free(&job.read[im]);
        return sc_fail(err, SC_ENOMEM, "out of memory");
    }
    int32_t nchunks = (s->nseams + ITEMS_PER_CHUNK - 1) / ITEMS_PER_CHUNK;
    int rc = sc_seam_parallel(threads, nchunks, energy_chunk, &job);
    if (rc == SC_OK) {
        for (int im = 0; im < count; im++) {
            const double *d = job.d + (size_t)im * s->nseams, *gp = job.gap + (size_t)im * s->nseams;
            double e = 0, gmax = 0;
            for (int32_t i = 0; i < s->nseams; i++) {
                e += edge_weight(s->seams[i].length, s->seam_length, s->nseams) * d[i];
                if (gp[i] > gmax) gmax = gp[i];
            }
            if (energy) energy[im] = e;
            if (max_gap) max_gap[im] = gmax;
        }
    } else if (rc == SC_EINPUT) {
        sc_fail(err, rc, "face %d: a uv edge crosses more than %d texel lines (uvs out of range?)",
                job.failed_face, SC_SEAM_MAX_CROSSINGS);
    } else {
        sc_fail(err, rc, "out of memory");
    }
    free(job.d), free(job.gap);
    for (int im = 0; im < count; im++) sc_seam_reader_free(&job.read[im]);
    return rc;
}

int sc_seam_energy(const sc_mesh *m, const sc_seam_set *s, const sc_seam_grid *g,
                   const sc_image_data *img, int threads, double *energy, double *max_gap,
                   sc_error *err) {
    return sc_seam_energies(m, s, g, &img, 1, threads, energy, max_gap, err);
}
