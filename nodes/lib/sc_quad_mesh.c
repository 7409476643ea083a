/* sc_quad_mesh.c - patches, quads and chart maps of the quad atlas
 * (Purnomo et al. 2004 §4.1-4.3; the method is described in sc_quad.h).
 *
 * The mesh is refined where the construction needs a vertex that is not
 * there: a side's median inside an edge, a patch's centre and the fan
 * around it, the middle of an edge a cut must cross (or every crossing of a
 * straight cut, where paths along edges fail), an edge that would put a
 * triangle flat on a chart's side. Refinement splits triangles in their own plane, so the surface is
 * unchanged; each new face remembers the input face it lies in.
 */
#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <umfpack.h>

#include "sc_geometry.h"
#include "sc_quad_internal.h"
#include "sc_quadric.h"

/* ---------------------------------------------------------------- growable arrays */

typedef struct ivec {
    int32_t n, cap;
    int32_t *a;
} ivec;

static bool iv_push(ivec *v, int32_t x) {
    if (v->n == v->cap) {
        int32_t cap = v->cap ? v->cap * 2 : 8;
        int32_t *a = realloc(v->a, (size_t)cap * sizeof *a);
        if (!a) return false;
        v->a = a, v->cap = cap;
    }
    v->a[v->n++] = x;
    return true;
}

/* ---------------------------------------------------------------- the refinable mesh */

static bool qm_reserve(qmesh *m, int32_t nv, int32_t nf) {
    if (nv > m->cap_v) {
        int32_t cap = nv > 2 * m->cap_v ? nv : 2 * m->cap_v;
        double *p = realloc(m->pos, (size_t)cap * 3 * sizeof *p);
        if (!p) return false;
        m->pos = p;
        m->cap_v = cap;
    }
    if (nf > m->cap_f) {
        int32_t cap = nf > 2 * m->cap_f ? nf : 2 * m->cap_f;
        int32_t *t = realloc(m->tri, (size_t)cap * 3 * sizeof *t);
        if (t) m->tri = t;
        int32_t *o = t ? realloc(m->opp, (size_t)cap * 3 * sizeof *o) : NULL;
        if (o) m->opp = o;
        int32_t *old = o ? realloc(m->old, (size_t)cap * sizeof *old) : NULL;
        if (old) m->old = old;
        double *b = old ? realloc(m->bary, (size_t)cap * 9 * sizeof *b) : NULL;
        if (b) m->bary = b;
        int32_t *pa = b ? realloc(m->patch, (size_t)cap * sizeof *pa) : NULL;
        if (pa) m->patch = pa;
        int32_t *q = pa ? realloc(m->quad, (size_t)cap * sizeof *q) : NULL;
        if (q) m->quad = q;
        if (!q) return false;
        m->cap_f = cap;
    }
    return true;
}

static void qm_free(qmesh *m) {
    free(m->pos), free(m->tri), free(m->opp), free(m->old), free(m->bary), free(m->patch), free(m->quad);
    memset(m, 0, sizeof *m);
}

typedef struct edge_key {
    int32_t lo, hi, h;
} edge_key;

static int cmp_edge_key(const void *a, const void *b) {
    const edge_key *x = a, *y = b;
    if (x->lo != y->lo) return x->lo < y->lo ? -1 : 1;
    if (x->hi != y->hi) return x->hi < y->hi ? -1 : 1;
    return x->h < y->h ? -1 : x->h > y->h;
}

/* Opposite half-edges: an edge of exactly two half-edges running opposite
 * ways is interior; any other edge is border on each side (non-manifold
 * edges and flipped neighbours cut the surface there). */
static int qm_from_mesh(qmesh *m, const sc_mesh *in) {
    memset(m, 0, sizeof *m);
    if (!qm_reserve(m, in->nv + 16, in->nf + 16)) return SC_ENOMEM;
    m->nv = in->nv, m->nf = in->nf;
    memcpy(m->pos, in->V, (size_t)in->nv * 3 * sizeof(double));
    memcpy(m->tri, in->FV, (size_t)in->nf * 3 * sizeof(int32_t));
    for (int32_t f = 0; f < in->nf; f++) {
        m->old[f] = f, m->patch[f] = f, m->quad[f] = -1;
        double *b = m->bary + 9 * (size_t)f;
        for (int k = 0; k < 9; k++) b[k] = k % 4 == 0 ? 1 : 0;
    }
    size_t nh = (size_t)in->nf * 3;
    edge_key *keys = malloc(nh * sizeof *keys);
    if (!keys) return SC_ENOMEM;
    for (size_t h = 0; h < nh; h++) {
        int32_t a = m->tri[h], b = m->tri[qm_next((int32_t)h)];
        keys[h] = (edge_key){a < b ? a : b, a < b ? b : a, (int32_t)h};
        m->opp[h] = -1;
    }
    qsort(keys, nh, sizeof *keys, cmp_edge_key);
    for (size_t i = 0; i < nh;) {
        size_t j = i;
        while (j < nh && keys[j].lo == keys[i].lo && keys[j].hi == keys[i].hi) j++;
        if (j - i == 2) {
            int32_t h0 = keys[i].h, h1 = keys[i + 1].h;
            if (m->tri[h0] == m->tri[qm_next(h1)] && m->tri[h1] == m->tri[qm_next(h0)])
                m->opp[h0] = h1, m->opp[h1] = h0;
        }
        i = j;
    }
    free(keys);
    double sum = 0;
    for (size_t h = 0; h < nh; h++) sum += sc_dist3(m->pos + 3 * (size_t)m->tri[h], m->pos + 3 * (size_t)m->tri[qm_next((int32_t)h)]);
    m->arc_floor = nh > 0 && sum > 0 ? 1e-6 * sum / (double)nh : 1e-12;
    return SC_OK;
}

static int32_t qm_add_vertex(qmesh *m, const double *p) {
    int32_t v = m->nv++;
    memcpy(m->pos + 3 * (size_t)v, p, 3 * sizeof(double));
    return v;
}

/* Split face f at its half-edge h (from a to b) by vertex w at a + t (b - a):
 * f becomes (a, w, c) and a new face (w, b, c). Returns the new face; the
 * two halves of the split edge (a->w in f, w->b in g) are left for the
 * caller to link with the other side. */
static int32_t qm_split_face_edge(qmesh *m, int32_t h, int32_t w, double t) {
    int32_t f = h / 3, k0 = h % 3, k1 = (k0 + 1) % 3, k2 = (k0 + 2) % 3;
    int32_t g = m->nf++;
    int32_t *F = m->tri + 3 * (size_t)f, *G = m->tri + 3 * (size_t)g;
    double *bf = m->bary + 9 * (size_t)f, *bg = m->bary + 9 * (size_t)g;
    double bw[3];
    for (int i = 0; i < 3; i++) bw[i] = (1 - t) * bf[3 * k0 + i] + t * bf[3 * k1 + i];
    G[0] = w, G[1] = F[k1], G[2] = F[k2];
    memcpy(bg, bw, sizeof bw), memcpy(bg + 3, bf + 3 * k1, 3 * sizeof(double)), memcpy(bg + 6, bf + 3 * k2, 3 * sizeof(double));
    F[k1] = w;
    memcpy(bf + 3 * k1, bw, sizeof bw);
    m->old[g] = m->old[f], m->patch[g] = m->patch[f], m->quad[g] = m->quad[f];
    int32_t o_bc = m->opp[3 * f + k1];
    m->opp[3 * g + 1] = o_bc;
    if (o_bc >= 0) m->opp[o_bc] = 3 * g + 1;
    m->opp[3 * f + k1] = 3 * g + 2, m->opp[3 * g + 2] = 3 * f + k1;
    m->opp[3 * f + k0] = -1, m->opp[3 * g + 0] = -1;
    return g;
}

/* Split the edge of half-edge h at parameter t (from its start): both faces
 * on it are split. Returns the new vertex, or -1 when out of memory. */
static int32_t qm_split_edge(qmesh *m, int32_t h, double t) {
    if (!qm_reserve(m, m->nv + 1, m->nf + 2)) return -1;
    int32_t a = m->tri[h], b = m->tri[qm_next(h)], o = m->opp[h];
    double p[3];
    for (int i = 0; i < 3; i++) p[i] = (1 - t) * m->pos[3 * (size_t)a + i] + t * m->pos[3 * (size_t)b + i];
    int32_t w = qm_add_vertex(m, p);
    int32_t f = h / 3, k0 = h % 3;
    int32_t g = qm_split_face_edge(m, h, w, t);
    if (o >= 0) {
        int32_t f2 = o / 3, k2 = o % 3;
        int32_t g2 = qm_split_face_edge(m, o, w, 1 - t);
        /* f: a->w, g: w->b; f2: b->w, g2: w->a */
        m->opp[3 * f + k0] = 3 * g2, m->opp[3 * g2] = 3 * f + k0;
        m->opp[3 * g] = 3 * f2 + k2, m->opp[3 * f2 + k2] = 3 * g;
    }
    return w;
}

/* Split face f at the point of barycentric coordinates l into three. */
static int32_t qm_split_face_point(qmesh *m, int32_t f, const double l[3]) {
    if (!qm_reserve(m, m->nv + 1, m->nf + 2)) return -1;
    int32_t *F = m->tri + 3 * (size_t)f;
    int32_t a = F[0], b = F[1], c = F[2];
    double p[3];
    for (int i = 0; i < 3; i++)
        p[i] = l[0] * m->pos[3 * (size_t)a + i] + l[1] * m->pos[3 * (size_t)b + i] + l[2] * m->pos[3 * (size_t)c + i];
    int32_t w = qm_add_vertex(m, p);
    double *bf = m->bary + 9 * (size_t)f, B[9], bw[3];
    memcpy(B, bf, sizeof B);
    for (int i = 0; i < 3; i++) bw[i] = l[0] * B[i] + l[1] * B[3 + i] + l[2] * B[6 + i];
    int32_t g1 = m->nf++, g2 = m->nf++;
    int32_t o_bc = m->opp[3 * f + 1], o_ca = m->opp[3 * f + 2];
    /* f = (a, b, w), g1 = (b, c, w), g2 = (c, a, w) */
    int32_t *G1 = m->tri + 3 * (size_t)g1, *G2 = m->tri + 3 * (size_t)g2;
    F = m->tri + 3 * (size_t)f;
    F[2] = w;
    G1[0] = b, G1[1] = c, G1[2] = w;
    G2[0] = c, G2[1] = a, G2[2] = w;
    memcpy(bf + 6, bw, sizeof bw);
    double *b1 = m->bary + 9 * (size_t)g1, *b2 = m->bary + 9 * (size_t)g2;
    memcpy(b1, B + 3, 3 * sizeof(double)), memcpy(b1 + 3, B + 6, 3 * sizeof(double)), memcpy(b1 + 6, bw, sizeof bw);
    memcpy(b2, B + 6, 3 * sizeof(double)), memcpy(b2 + 3, B, 3 * sizeof(double)), memcpy(b2 + 6, bw, sizeof bw);
    for (int32_t g = g1; g <= g2; g++) m->old[g] = m->old[f], m->patch[g] = m->patch[f], m->quad[g] = m->quad[f];
    m->opp[3 * g1] = o_bc;
    if (o_bc >= 0) m->opp[o_bc] = 3 * g1;
    m->opp[3 * g2] = o_ca;
    if (o_ca >= 0) m->opp[o_ca] = 3 * g2;
    m->opp[3 * f + 1] = 3 * g1 + 2, m->opp[3 * g1 + 2] = 3 * f + 1;
    m->opp[3 * g1 + 1] = 3 * g2 + 2, m->opp[3 * g2 + 2] = 3 * g1 + 1;
    m->opp[3 * g2 + 1] = 3 * f + 2, m->opp[3 * f + 2] = 3 * g2 + 1;
    return w;
}

static double qm_len(const qmesh *m, int32_t a, int32_t b) {
    return sc_dist3(m->pos + 3 * (size_t)a, m->pos + 3 * (size_t)b);
}

/* Length along a border for arc-length placement: a zero-length edge (two
 * vertices at one point) still advances, so no two vertices of a side land
 * on one spot. */
static double qm_arc(const qmesh *m, int32_t a, int32_t b) { return qm_len(m, a, b) + m->arc_floor; }

static double qm_area(const qmesh *m, int32_t f) {
    const int32_t *F = m->tri + 3 * (size_t)f;
    double n[3];
    sc_triangle_normal(m->pos + 3 * (size_t)F[0], m->pos + 3 * (size_t)F[1], m->pos + 3 * (size_t)F[2], n);
    return 0.5 * sc_norm3(n);
}

/* ---------------------------------------------------------------- region loops */

/* The boundary loop of a set of faces (in_set(face) true), walked along its
 * boundary half-edges: verts[i] starts half-edge hs[i]. Fails (false) when
 * the set's boundary is not one simple loop (several loops, a pinch vertex,
 * or no boundary at all). `stamp`/`mark`/`slot` are per-vertex scratch. */
typedef struct loop_walk {
    ivec verts, hs;
    int32_t *mark, *slot;   /* per vertex */
    int32_t stamp;
} loop_walk;

typedef bool (*face_pred)(const qmesh *m, int32_t f, const void *arg);

static bool loop_build(const qmesh *m, const int32_t *faces, int32_t nfaces, face_pred in_set, const void *arg,
                       loop_walk *w, bool *oom) {
    w->verts.n = w->hs.n = 0;
    w->stamp++;
    int32_t nb = 0, first = -1;
    for (int32_t i = 0; i < nfaces; i++) {
        int32_t f = faces[i];
        for (int k = 0; k < 3; k++) {
            int32_t h = 3 * f + k, o = m->opp[h];
            if (o >= 0 && in_set(m, o / 3, arg)) continue;
            int32_t v = m->tri[h];
            if (w->mark[v] == w->stamp) return false;   /* two boundary half-edges leave v: a pinch */
            w->mark[v] = w->stamp, w->slot[v] = h;
            nb++;
            if (first < 0) first = h;
        }
    }
    if (nb == 0) return false;
    int32_t h = first, steps = 0;
    do {
        if (!iv_push(&w->verts, m->tri[h]) || !iv_push(&w->hs, h)) return *oom = true, false;
        int32_t v = m->tri[qm_next(h)];
        if (w->mark[v] != w->stamp) return false;
        h = w->slot[v];
        if (++steps > nb) return false;
    } while (h != first);
    return steps == nb;
}

/* ---------------------------------------------------------------- patches (§4.1) */

typedef struct patch {
    double area, s1[3], s2[6], nsum[3], perim;
    ivec faces;
    int32_t version;
    int32_t est_quads;
    bool alive;
} patch;

typedef struct cand {
    double cost;
    int32_t a, b, va, vb;
} cand;

typedef struct heap {
    int32_t n, cap;
    cand *c;
} heap;

static bool heap_push(heap *hp, cand x) {
    if (hp->n == hp->cap) {
        int32_t cap = hp->cap ? 2 * hp->cap : 1024;
        cand *c = realloc(hp->c, (size_t)cap * sizeof *c);
        if (!c) return false;
        hp->c = c, hp->cap = cap;
    }
    int32_t i = hp->n++;
    while (i > 0) {
        int32_t p = (i - 1) / 2;
        if (hp->c[p].cost <= x.cost) break;
        hp->c[i] = hp->c[p], i = p;
    }
    hp->c[i] = x;
    return true;
}

static cand heap_pop(heap *hp) {
    cand top = hp->c[0], x = hp->c[--hp->n];
    int32_t i = 0;
    for (;;) {
        int32_t l = 2 * i + 1, r = l + 1, s = i;
        double sc = x.cost;
        if (l < hp->n && hp->c[l].cost < sc) s = l, sc = hp->c[l].cost;
        if (r < hp->n && hp->c[r].cost < sc) s = r;
        if (s == i) break;
        hp->c[i] = hp->c[s], i = s;
    }
    if (hp->n > 0) hp->c[i] = x;
    return top;
}

typedef struct cluster {
    qmesh *m;
    patch *p;
    int32_t np_alive;
    double area_total;
    heap hp;
    int32_t *vf_start, *vf;   /* vertex -> faces of the input mesh */
    loop_walk lw;
    int32_t *seen;            /* per patch scratch */
    int32_t seen_stamp;
    int64_t total_est;
} cluster;

static double smallest_eigen(const double c[6]) {
    double vals[3], vecs[3][3];
    sc_sym3_eigen(c, vals, vecs);
    double lo = vals[0];
    for (int k = 1; k < 3; k++) lo = fmin(lo, vals[k]);
    return lo > 0 ? lo : 0;
}

/* The merge cost (§4.1: k1 Q + k2 P): the merged patch's area fraction
 * times its plane-fit error (smallest variance across, over its area), its
 * normal spread and its irregularity perimeter^2 / (4 pi area) - 1. */
static double merged_cost(const cluster *cl, const patch *a, const patch *b, double shared_len) {
    double A = a->area + b->area;
    if (!(A > 0)) return 0;
    double s1[3], s2[6], n[3], cov[6];
    for (int i = 0; i < 3; i++) s1[i] = a->s1[i] + b->s1[i], n[i] = a->nsum[i] + b->nsum[i];
    for (int i = 0; i < 6; i++) s2[i] = a->s2[i] + b->s2[i];
    double mu[3] = {s1[0] / A, s1[1] / A, s1[2] / A};
    int idx[6][2] = {{0, 0}, {0, 1}, {0, 2}, {1, 1}, {1, 2}, {2, 2}};
    for (int i = 0; i < 6; i++) cov[i] = s2[i] / A - mu[idx[i][0]] * mu[idx[i][1]];
    double fit = 4 * smallest_eigen(cov) / A;
    double spread = 1 - sc_norm3(n) / A;
    double perim = a->perim + b->perim - 2 * shared_len;
    double shape = perim * perim / (4 * M_PI * A) - 1;
    return A / cl->area_total * (fit + spread + 0.05 * (shape > 0 ? shape : 0));
}

static bool in_pair(const qmesh *m, int32_t f, const void *arg) {
    const int32_t *ab = arg;
    return m->patch[f] == ab[0] || m->patch[f] == ab[1];
}

static double shared_length(const cluster *cl, int32_t a, int32_t b) {
    const patch *pa = &cl->p[a], *pb = &cl->p[b];
    if (pb->faces.n < pa->faces.n) { const patch *t = pa; pa = pb, pb = t; int32_t x = a; a = b, b = x; }
    double len = 0;
    for (int32_t i = 0; i < pa->faces.n; i++) {
        int32_t f = pa->faces.a[i];
        for (int k = 0; k < 3; k++) {
            int32_t o = cl->m->opp[3 * f + k];
            if (o >= 0 && cl->m->patch[o / 3] == b) len += qm_len(cl->m, cl->m->tri[3 * f + k], cl->m->tri[3 * f + (k + 1) % 3]);
        }
    }
    return len;
}

typedef struct contact {
    int32_t patch, pos;
} contact;

static int cmp_contact(const void *x, const void *y) {
    const contact *a = x, *b = y;
    if (a->patch != b->patch) return a->patch < b->patch ? -1 : 1;
    return a->pos < b->pos ? -1 : a->pos > b->pos;
}

/* Both rules for the union of patches a and b (whose faces are listed in
 * fs): one simple boundary loop (a disc, as a and b are discs glued along
 * one arc), and every other patch touching it along one arc or at one
 * vertex. On success *runs is the number of label runs along the loop. */
static int merge_allowed(cluster *cl, int32_t a, int32_t b, const ivec *fs, int32_t *runs, bool *ok) {
    qmesh *m = cl->m;
    int32_t ab[2] = {a, b};
    bool oom = false;
    *ok = loop_build(m, fs->a, fs->n, in_pair, ab, &cl->lw, &oom);
    if (oom) return SC_ENOMEM;
    if (!*ok) return SC_OK;
    int32_t L = cl->lw.verts.n;
    int32_t *label = malloc((size_t)L * sizeof *label);
    ivec con = {0};
    if (!label) return SC_ENOMEM;
    for (int32_t i = 0; i < L; i++) {
        int32_t o = m->opp[cl->lw.hs.a[i]];
        label[i] = o < 0 ? -1 : m->patch[o / 3];
    }
    int32_t nr = 0;
    for (int32_t i = 0; i < L; i++) nr += label[i] != label[(i + L - 1) % L];
    *runs = nr;
    for (int32_t i = 0; i < L && *ok; i++) {
        int32_t v = cl->lw.verts.a[i];
        cl->seen_stamp++;
        for (int32_t j = cl->vf_start[v]; j < cl->vf_start[v + 1]; j++) {
            int32_t c = m->patch[cl->vf[j]];
            if (c == a || c == b || cl->seen[c] == cl->seen_stamp) continue;
            cl->seen[c] = cl->seen_stamp;
            if (!iv_push(&con, c) || !iv_push(&con, i)) { free(label), free(con.a); return SC_ENOMEM; }
        }
    }
    int32_t nc = con.n / 2;
    qsort(con.a, (size_t)nc, sizeof(contact), cmp_contact);
    const contact *cs = (const contact *)con.a;
    for (int32_t s = 0; s < nc && *ok;) {
        int32_t e = s;
        while (e < nc && cs[e].patch == cs[s].patch) e++;
        int32_t cnt = e - s, c = cs[s].patch;
        if (cnt >= L) *ok = false;
        else if (cnt > 1) {
            /* contiguous cyclically: at most one gap; the run's edges all carry c */
            int32_t gaps = 0, start = cs[s].pos;
            for (int32_t k = s; k < e; k++) {
                int32_t nxt = k + 1 < e ? cs[k + 1].pos : cs[s].pos + L;
                if (nxt - cs[k].pos > 1) gaps++, start = nxt % L;
            }
            if (gaps > 1) *ok = false;
            for (int32_t k = 0; k < cnt - 1 && *ok; k++)
                if (label[(start + k) % L] != c) *ok = false;
        }
        s = e;
    }
    free(label), free(con.a);
    return SC_OK;
}

static int push_pairs(cluster *cl, int32_t a) {
    qmesh *m = cl->m;
    patch *pa = &cl->p[a];
    cl->seen_stamp++;
    for (int32_t i = 0; i < pa->faces.n; i++) {
        int32_t f = pa->faces.a[i];
        for (int k = 0; k < 3; k++) {
            int32_t o = m->opp[3 * f + k];
            if (o < 0) continue;
            int32_t b = m->patch[o / 3];
            if (b == a || cl->seen[b] == cl->seen_stamp) continue;
            cl->seen[b] = cl->seen_stamp;
            double cost = merged_cost(cl, pa, &cl->p[b], shared_length(cl, a, b));
            if (!heap_push(&cl->hp, (cand){cost, a, b, pa->version, cl->p[b].version})) return SC_ENOMEM;
        }
    }
    return SC_OK;
}

static int merge(cluster *cl, int32_t a, int32_t b, double shared, int32_t runs) {
    patch *pa = &cl->p[a], *pb = &cl->p[b];
    if (pa->faces.n < pb->faces.n) {
        patch *t = pa; pa = pb, pb = t;
        int32_t x = a; a = b, b = x;
    }
    for (int32_t i = 0; i < pb->faces.n; i++) {
        if (!iv_push(&pa->faces, pb->faces.a[i])) return SC_ENOMEM;
        cl->m->patch[pb->faces.a[i]] = a;
    }
    pa->area += pb->area, pa->perim += pb->perim - 2 * shared;
    for (int i = 0; i < 3; i++) pa->s1[i] += pb->s1[i], pa->nsum[i] += pb->nsum[i];
    for (int i = 0; i < 6; i++) pa->s2[i] += pb->s2[i];
    cl->total_est -= pa->est_quads + pb->est_quads;
    pa->est_quads = runs < 3 ? 3 : runs;
    cl->total_est += pa->est_quads;
    pa->version++;
    pb->alive = false, free(pb->faces.a), memset(&pb->faces, 0, sizeof pb->faces);
    cl->np_alive--;
    return push_pairs(cl, a);
}

static int cluster_init(cluster *cl, qmesh *m, int32_t nv_in) {
    memset(cl, 0, sizeof *cl);
    cl->m = m;
    int32_t nf = m->nf;
    cl->p = calloc((size_t)nf, sizeof *cl->p);
    cl->seen = calloc((size_t)nf, sizeof *cl->seen);
    cl->vf_start = calloc((size_t)nv_in + 1, sizeof *cl->vf_start);
    cl->vf = malloc((size_t)nf * 3 * sizeof *cl->vf);
    cl->lw.mark = calloc((size_t)nv_in, sizeof(int32_t));
    cl->lw.slot = calloc((size_t)nv_in, sizeof(int32_t));
    if (!cl->p || !cl->seen || !cl->vf_start || !cl->vf || !cl->lw.mark || !cl->lw.slot) return SC_ENOMEM;
    for (int32_t h = 0; h < 3 * nf; h++) cl->vf_start[m->tri[h] + 1]++;
    for (int32_t v = 0; v < nv_in; v++) cl->vf_start[v + 1] += cl->vf_start[v];
    int32_t *fill = malloc((size_t)nv_in * sizeof *fill);
    if (!fill) return SC_ENOMEM;
    memcpy(fill, cl->vf_start, (size_t)nv_in * sizeof *fill);
    for (int32_t h = 0; h < 3 * nf; h++) cl->vf[fill[m->tri[h]]++] = h / 3;
    free(fill);
    for (int32_t f = 0; f < nf; f++) {
        patch *p = &cl->p[f];
        const int32_t *F = m->tri + 3 * (size_t)f;
        const double *x[3] = {m->pos + 3 * (size_t)F[0], m->pos + 3 * (size_t)F[1], m->pos + 3 * (size_t)F[2]};
        double n[3];
        sc_triangle_normal(x[0], x[1], x[2], n);
        double A = 0.5 * sc_norm3(n);
        p->area = A;
        for (int i = 0; i < 3; i++) p->s1[i] = A * (x[0][i] + x[1][i] + x[2][i]) / 3, p->nsum[i] = 0.5 * n[i];
        /* second moment of the triangle: A/12 (sum x x^T + s s^T) */
        int idx[6][2] = {{0, 0}, {0, 1}, {0, 2}, {1, 1}, {1, 2}, {2, 2}};
        for (int e = 0; e < 6; e++) {
            int r = idx[e][0], c = idx[e][1];
            double sxx = 0, sr = 0, sc = 0;
            for (int k = 0; k < 3; k++) sxx += x[k][r] * x[k][c], sr += x[k][r], sc += x[k][c];
            p->s2[e] = A / 12 * (sxx + sr * sc);
        }
        p->perim = qm_len(m, F[0], F[1]) + qm_len(m, F[1], F[2]) + qm_len(m, F[2], F[0]);
        if (!iv_push(&p->faces, f)) return SC_ENOMEM;
        p->alive = true, p->est_quads = 3;
        cl->area_total += A;
    }
    if (!(cl->area_total > 0)) cl->area_total = 1;
    cl->np_alive = nf;
    cl->total_est = 3 * (int64_t)nf;
    for (int32_t f = 0; f < nf; f++) {
        int rc = push_pairs(cl, f);
        if (rc) return rc;
    }
    return SC_OK;
}

static void cluster_free(cluster *cl, int32_t nf) {
    if (cl->p)
        for (int32_t i = 0; i < nf; i++) free(cl->p[i].faces.a);
    free(cl->p), free(cl->seen), free(cl->vf_start), free(cl->vf), free(cl->hp.c);
    free(cl->lw.verts.a), free(cl->lw.hs.a), free(cl->lw.mark), free(cl->lw.slot);
}

/* Greedy merging until the patch or estimated quad target is met or no
 * merge keeps both rules. Leaves m->patch numbered 0..npatches-1. */
static int make_patches(qmesh *m, int32_t nv_in, int32_t target_patches, int32_t target_quads, int32_t *npatches) {
    cluster cl;
    int32_t nf = m->nf;
    int rc = cluster_init(&cl, m, nv_in);
    ivec fs = {0};
    while (rc == SC_OK && cl.hp.n > 0) {
        if (target_patches > 0 ? cl.np_alive <= target_patches : cl.total_est <= target_quads) break;
        cand c = heap_pop(&cl.hp);
        patch *pa = &cl.p[c.a], *pb = &cl.p[c.b];
        if (!pa->alive || !pb->alive || pa->version != c.va || pb->version != c.vb) continue;
        double shared = shared_length(&cl, c.a, c.b);
        fs.n = 0;
        for (int32_t i = 0; i < pa->faces.n && rc == SC_OK; i++)
            if (!iv_push(&fs, pa->faces.a[i])) rc = SC_ENOMEM;
        for (int32_t i = 0; i < pb->faces.n && rc == SC_OK; i++)
            if (!iv_push(&fs, pb->faces.a[i])) rc = SC_ENOMEM;
        if (rc) break;
        int32_t runs = 0;
        bool ok = false;
        rc = merge_allowed(&cl, c.a, c.b, &fs, &runs, &ok);
        if (rc || !ok) continue;
        rc = merge(&cl, c.a, c.b, shared, runs);
    }
    free(fs.a);
    if (rc == SC_OK) {
        int32_t *id = malloc((size_t)nf * sizeof *id);
        if (!id) rc = SC_ENOMEM;
        else {
            int32_t n = 0;
            for (int32_t p = 0; p < nf; p++) id[p] = cl.p[p].alive ? n++ : -1;
            for (int32_t f = 0; f < nf; f++) m->patch[f] = id[m->patch[f]];
            *npatches = n;
            free(id);
        }
    }
    cluster_free(&cl, nf);
    return rc;
}

/* ---------------------------------------------------------------- the builder */

enum { FLAG_CORNER = 1, FLAG_MEDIAN = 2 };

typedef struct builder {
    qmesh *m;
    int32_t np;
    ivec *pf;              /* faces of each patch */
    ivec *qf;              /* faces of each quad */
    ivec qcorner;          /* 4 per quad: p_i, m_i, c, m_{i-1} */
    int32_t qcap;
    loop_walk lw;
    uint8_t *flag;         /* per vertex */
    int32_t *local;        /* per vertex: unknown index in a solve, -1 */
    double *xy;            /* per vertex: 2 coordinates of the current map */
    int32_t *side;         /* per vertex: side of the current region's loop, -1 inside, -2 a corner */
    int32_t vcap;
    ivec label;
    int32_t hist[9];
    int32_t straight_cuts;   /* patches cut by straight segments (no paths along edges) */
} builder;

static bool b_fit(builder *b) {
    if (b->m->nv <= b->vcap) return true;
    int32_t cap = b->m->nv * 2, old = b->vcap;
    int32_t *mk = realloc(b->lw.mark, (size_t)cap * sizeof *mk);
    if (mk) b->lw.mark = mk;
    int32_t *sl = mk ? realloc(b->lw.slot, (size_t)cap * sizeof *sl) : NULL;
    if (sl) b->lw.slot = sl;
    uint8_t *fl = sl ? realloc(b->flag, (size_t)cap) : NULL;
    if (fl) b->flag = fl;
    int32_t *lo = fl ? realloc(b->local, (size_t)cap * sizeof *lo) : NULL;
    if (lo) b->local = lo;
    double *xy = lo ? realloc(b->xy, (size_t)cap * 2 * sizeof *xy) : NULL;
    if (xy) b->xy = xy;
    int32_t *sd = xy ? realloc(b->side, (size_t)cap * sizeof *sd) : NULL;
    if (sd) b->side = sd;
    if (!sd) return false;
    for (int32_t v = old; v < cap; v++) b->lw.mark[v] = 0, b->flag[v] = 0, b->local[v] = -1, b->side[v] = -1;
    b->vcap = cap;
    return true;
}

/* Split the edge of half-edge h at t, keeping the patch and quad face lists. */
static int32_t b_split_edge(builder *b, int32_t h, double t) {
    int32_t nf0 = b->m->nf;
    int32_t w = qm_split_edge(b->m, h, t);
    if (w < 0 || !b_fit(b)) return -1;
    for (int32_t f = nf0; f < b->m->nf; f++) {
        if (!iv_push(&b->pf[b->m->patch[f]], f)) return -1;
        if (b->m->quad[f] >= 0 && !iv_push(&b->qf[b->m->quad[f]], f)) return -1;
    }
    return w;
}

static bool in_patch(const qmesh *m, int32_t f, const void *arg) { return m->patch[f] == *(const int32_t *)arg; }
static bool in_quad(const qmesh *m, int32_t f, const void *arg) { return m->quad[f] == *(const int32_t *)arg; }

/* The loop of patch p with its labels (neighbour patch, -1 border) in b->label. */
static int patch_loop(builder *b, int32_t p, bool *ok) {
    bool oom = false;
    *ok = loop_build(b->m, b->pf[p].a, b->pf[p].n, in_patch, &p, &b->lw, &oom);
    if (oom) return SC_ENOMEM;
    if (!*ok) return SC_OK;
    b->label.n = 0;
    for (int32_t i = 0; i < b->lw.hs.n; i++) {
        int32_t o = b->m->opp[b->lw.hs.a[i]];
        if (!iv_push(&b->label, o < 0 ? -1 : b->m->patch[o / 3])) return SC_ENOMEM;
    }
    return SC_OK;
}

static bool is_corner(const builder *b, int32_t i) {
    int32_t L = b->lw.verts.n;
    return (b->flag[b->lw.verts.a[i]] & FLAG_CORNER) || b->label.a[i] != b->label.a[(i + L - 1) % L];
}

/* Arc length along the loop from position i to position j (cyclic, j
 * after i; the whole loop when j == i). */
static double loop_arc(const builder *b, int32_t i, int32_t j) {
    int32_t L = b->lw.verts.n, k = i;
    double s = 0;
    do {
        s += qm_arc(b->m, b->lw.verts.a[k], b->lw.verts.a[(k + 1) % L]);
        k = (k + 1) % L;
    } while (k != j);
    return s;
}

/* Mark (or make) the vertex at arc-length fraction `at` of the loop stretch
 * from position i to position j: an inner vertex within [lo, hi] of the
 * stretch, else a new vertex splitting the edge that holds the point. */
static int mark_at(builder *b, int32_t i, int32_t j, double at, double lo, double hi, uint8_t fl) {
    int32_t L = b->lw.verts.n;
    double total = loop_arc(b, i, j), s = 0, best = 2;
    int32_t bestk = -1;
    for (int32_t k = (i + 1) % L; k != j; k = (k + 1) % L) {
        s += qm_arc(b->m, b->lw.verts.a[(k + L - 1) % L], b->lw.verts.a[k]);
        double f = total > 0 ? s / total : 0.5;
        if (f >= lo && f <= hi && fabs(f - at) < best) best = fabs(f - at), bestk = k;
    }
    if (bestk >= 0) {
        b->flag[b->lw.verts.a[bestk]] |= fl;
        return SC_OK;
    }
    s = 0;
    int32_t k = i;
    do {
        int32_t kn = (k + 1) % L;
        double e = qm_arc(b->m, b->lw.verts.a[k], b->lw.verts.a[kn]);
        if (s + e >= at * total || kn == j) {
            double t = e > 0 ? (at * total - s) / e : 0.5;
            t = t < 0.01 ? 0.01 : t > 0.99 ? 0.99 : t;
            int32_t w = b_split_edge(b, b->lw.hs.a[k], t);
            if (w < 0) return SC_ENOMEM;
            b->flag[w] |= fl;
            return SC_OK;
        }
        s += e, k = kn;
    } while (k != j);
    return SC_OK;
}

/* Every patch gets at least three corners (§4.2 needs an n-gon, n >= 3). */
static int add_corners(builder *b) {
    for (int32_t p = 0; p < b->np; p++) {
        for (int guard = 0; guard < 16; guard++) {
            bool ok;
            int rc = patch_loop(b, p, &ok);
            if (rc) return rc;
            if (!ok) return SC_EINPUT;
            int32_t L = b->lw.verts.n, nc = 0, first = -1;
            for (int32_t i = 0; i < L; i++)
                if (is_corner(b, i)) nc++, first = first < 0 ? i : first;
            if (nc >= 3) break;
            if (nc == 0) {
                b->flag[b->lw.verts.a[0]] |= FLAG_CORNER;
                continue;
            }
            /* split the longest side at its middle */
            int32_t bi = first, bj = first;
            double blen = -1;
            for (int32_t i = first, n = 0; n < nc; n++) {
                int32_t j = (i + 1) % L;
                while (!is_corner(b, j)) j = (j + 1) % L;
                double len = loop_arc(b, i, j);
                if (len > blen) blen = len, bi = i, bj = j;
                i = j;
            }
            if (bi == bj) rc = mark_at(b, bi, bi, nc == 1 ? 1.0 / 3 : 0.5, 0.15, 0.5, FLAG_CORNER);
            else rc = mark_at(b, bi, bj, 0.5, 0.2, 0.8, FLAG_CORNER);
            if (rc) return rc;
        }
    }
    return SC_OK;
}

/* Each patch side gets one median vertex (shared with the neighbour). */
static int add_medians(builder *b) {
    for (int32_t p = 0; p < b->np; p++) {
        for (int guard = 0; guard < 4096; guard++) {
            bool ok, done = true;
            int rc = patch_loop(b, p, &ok);
            if (rc) return rc;
            if (!ok) return SC_EINPUT;
            int32_t L = b->lw.verts.n, first = -1;
            for (int32_t i = 0; i < L && first < 0; i++)
                if (is_corner(b, i)) first = i;
            for (int32_t i = first, n = 0; n < L && done;) {
                int32_t j = (i + 1) % L, meds = 0;
                while (!is_corner(b, j)) meds += (b->flag[b->lw.verts.a[j]] & FLAG_MEDIAN) != 0, j = (j + 1) % L;
                if (meds == 0) {
                    rc = mark_at(b, i, j, 0.5, 0.3, 0.7, FLAG_MEDIAN);
                    if (rc) return rc;
                    done = false;
                }
                n += (j - i + L) % L;
                i = j;
                if (i == first) break;
            }
            if (done) break;
        }
    }
    return SC_OK;
}

/* ---------------------------------------------------------------- harmonic maps */

/* Mean-value (Tutte) map of a region: vertices with b->local[v] == -1 are
 * fixed at b->xy; the rest are solved. weight (per vertex, or NULL) divides
 * the weights of the edges into that vertex (stretch re-weighting). */
static int tutte(builder *b, const ivec *faces, const int32_t *unknowns, int32_t n, const double *weight,
                 sc_error *err) {
    if (n == 0) return SC_OK;
    qmesh *m = b->m;
    size_t cap = (size_t)faces->n * 6 + (size_t)n;
    int *Ti = malloc(cap * sizeof *Ti), *Tj = malloc(cap * sizeof *Tj);
    double *Tx = malloc(cap * sizeof *Tx), *rhs = calloc((size_t)n * 2, sizeof *rhs);
    double *x = malloc((size_t)n * 2 * sizeof *x), *diag = calloc((size_t)n, sizeof *diag);
    int *Ap = malloc(((size_t)n + 1) * sizeof *Ap), *Ai = malloc(cap * sizeof *Ai);
    double *Ax = malloc(cap * sizeof *Ax);
    int rc = SC_OK;
    void *sym = NULL, *num = NULL;
    if (!Ti || !Tj || !Tx || !rhs || !x || !diag || !Ap || !Ai || !Ax) { rc = SC_ENOMEM; goto done; }
    size_t nz = 0;
    for (int32_t i = 0; i < faces->n; i++) {
        const int32_t *F = m->tri + 3 * (size_t)faces->a[i];
        for (int k = 0; k < 3; k++) {
            int32_t vi = F[k], vj = F[(k + 1) % 3], vk = F[(k + 2) % 3];
            int32_t li = b->local[vi];
            if (li < 0) continue;
            double e1[3], e2[3], c[3];
            sc_sub3(m->pos + 3 * (size_t)vj, m->pos + 3 * (size_t)vi, e1);
            sc_sub3(m->pos + 3 * (size_t)vk, m->pos + 3 * (size_t)vi, e2);
            sc_cross3(e1, e2, c);
            double th = atan2(sc_norm3(c), sc_dot3(e1, e2));
            double t = tan(0.5 * th);
            if (!(t > 1e-8)) t = 1e-8;
            if (t > 1e3) t = 1e3;
            int32_t nb[2] = {vj, vk};
            double len[2] = {sc_norm3(e1), sc_norm3(e2)};
            for (int s = 0; s < 2; s++) {
                double w = t / (len[s] > 1e-300 ? len[s] : 1e-300);
                if (weight) w /= weight[nb[s]];
                if (!isfinite(w)) w = 1e300;
                diag[li] += w;
                int32_t lj = b->local[nb[s]];
                if (lj >= 0) Ti[nz] = li, Tj[nz] = lj, Tx[nz] = -w, nz++;
                else rhs[li] += w * b->xy[2 * (size_t)nb[s]], rhs[n + li] += w * b->xy[2 * (size_t)nb[s] + 1];
            }
        }
    }
    for (int32_t i = 0; i < n; i++) {
        /* rows scaled to unit diagonal keep the huge weights of slivers in range */
        Ti[nz] = i, Tj[nz] = i, Tx[nz] = diag[i], nz++;
    }
    for (size_t k = 0; k < nz; k++) Tx[k] /= diag[Ti[k]];
    for (int32_t i = 0; i < n; i++) rhs[i] /= diag[i], rhs[n + i] /= diag[i];
    if (umfpack_di_triplet_to_col(n, n, (int)nz, Ti, Tj, Tx, Ap, Ai, Ax, NULL) != UMFPACK_OK ||
        umfpack_di_symbolic(n, n, Ap, Ai, Ax, &sym, NULL, NULL) != UMFPACK_OK ||
        umfpack_di_numeric(Ap, Ai, Ax, sym, &num, NULL, NULL) != UMFPACK_OK ||
        umfpack_di_solve(UMFPACK_A, Ap, Ai, Ax, x, rhs, num, NULL, NULL) != UMFPACK_OK ||
        umfpack_di_solve(UMFPACK_A, Ap, Ai, Ax, x + n, rhs + n, num, NULL, NULL) != UMFPACK_OK) {
        rc = sc_fail(err, SC_EINPUT, "a chart's harmonic map has no solution (degenerate triangles)");
        goto done;
    }
    for (int32_t i = 0; i < n; i++) {
        int32_t v = unknowns[i];
        b->xy[2 * (size_t)v] = x[i], b->xy[2 * (size_t)v + 1] = x[n + i];
    }
done:
    if (sym) umfpack_di_free_symbolic(&sym);
    if (num) umfpack_di_free_numeric(&num);
    free(Ti), free(Tj), free(Tx), free(rhs), free(x), free(diag), free(Ap), free(Ai), free(Ax);
    return rc;
}

/* The unknowns of a region: its vertices not on its loop (b->side == -1),
 * numbered in b->local. */
static int region_unknowns(builder *b, const ivec *faces, ivec *out) {
    out->n = 0;
    for (int32_t i = 0; i < faces->n; i++)
        for (int k = 0; k < 3; k++) {
            int32_t v = b->m->tri[3 * (size_t)faces->a[i] + k];
            if (b->side[v] != -1 || b->local[v] >= 0) continue;
            b->local[v] = out->n;
            if (!iv_push(out, v)) return SC_ENOMEM;
        }
    return SC_OK;
}

/* Split every dividing edge of the region: an inner edge whose two ends lie
 * on one side of its polygon (a polygon corner counts for both of its
 * sides). Without dividing edges a Tutte map onto a convex polygon is one
 * to one (Floater 2003). Sides are in b->side: s >= 0 on side s, -2 - s at
 * corner s (the start of side s), of n sides; -1 inside. */
static bool on_side(int32_t code, int32_t s, int32_t n) {
    if (code >= 0) return code == s;
    if (code <= -2) {
        int32_t c = -2 - code;
        return c == s || (c + n - 1) % n == s;
    }
    return false;
}

static int split_dividing_edges(builder *b, ivec *faces, face_pred in_set, const void *arg, int32_t n) {
    for (int32_t i = 0; i < faces->n; i++) {
        int32_t f = faces->a[i];
        for (int k = 0; k < 3; k++) {
            int32_t h = 3 * f + k, o = b->m->opp[h];
            if (o < 0 || !in_set(b->m, o / 3, arg)) continue;
            int32_t va = b->m->tri[h], vb = b->m->tri[qm_next(h)];
            if (va > vb) continue;
            int32_t sa = b->side[va], sb = b->side[vb];
            if (sa == -1 || sb == -1) continue;
            bool dividing = false;
            for (int32_t s = 0; s < n && !dividing; s++) dividing = on_side(sa, s, n) && on_side(sb, s, n);
            if (!dividing) continue;
            int32_t w = b_split_edge(b, h, 0.5);
            if (w < 0) return SC_ENOMEM;
            b->side[w] = -1;
        }
    }
    return SC_OK;
}

/* ---------------------------------------------------------------- domains and cuts (§4.2) */

static double orient2(const double *a, const double *b, const double *c) {
    return (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
}

/* Label the loop vertices with their side (corners -2) and place them on the
 * regular polygon with `nc` corners by arc length. Returns the loop
 * positions of the corners in cpos. */
static void place_loop(builder *b, const int32_t *cpos, int32_t nc, const double (*poly)[2]) {
    int32_t L = b->lw.verts.n;
    for (int32_t s = 0; s < nc; s++) {
        int32_t i = cpos[s], j = cpos[(s + 1) % nc];
        double total = loop_arc(b, i, j), acc = 0;
        const double *P = poly[s], *Q = poly[(s + 1) % nc];
        for (int32_t k = i; ; k = (k + 1) % L) {
            int32_t v = b->lw.verts.a[k];
            double t = total > 0 ? acc / total : 0;
            if (k == i) t = 0;
            b->xy[2 * (size_t)v] = P[0] + t * (Q[0] - P[0]);
            b->xy[2 * (size_t)v + 1] = P[1] + t * (Q[1] - P[1]);
            b->side[v] = k == i ? -2 - s : s;
            int32_t kn = (k + 1) % L;
            if (kn == j) break;
            acc += qm_arc(b->m, v, b->lw.verts.a[kn]);
        }
    }
}

/* Cut patch p along the segment from its centre (domain origin, vertex c)
 * to vertex mv: every edge the segment crosses inside is split there. */
static int cut_segment(builder *b, int32_t p, int32_t cv, int32_t mv) {
    qmesh *m = b->m;
    const double O[2] = {b->xy[2 * (size_t)cv], b->xy[2 * (size_t)cv + 1]};
    double M[2] = {b->xy[2 * (size_t)mv], b->xy[2 * (size_t)mv + 1]};
    double scale = hypot(M[0] - O[0], M[1] - O[1]), eps = 1e-12 * (scale > 0 ? scale : 1);
    for (int32_t i = 0; i < b->pf[p].n; i++) {
        int32_t f = b->pf[p].a[i];
        for (int k = 0; k < 3; k++) {
            int32_t h = 3 * f + k, o = m->opp[h];
            if (o < 0 || m->patch[o / 3] != p) continue;
            int32_t va = m->tri[h], vb = m->tri[qm_next(h)];
            if (va > vb) continue;   /* each inner edge once */
            const double *A = b->xy + 2 * (size_t)va, *B = b->xy + 2 * (size_t)vb;
            double oa = orient2(O, M, A), ob = orient2(O, M, B);
            if (!((oa > eps && ob < -eps) || (oa < -eps && ob > eps))) continue;
            double s0 = orient2(A, B, O), s1 = orient2(A, B, M);
            if (!((s0 > eps && s1 < -eps) || (s0 < -eps && s1 > eps))) continue;
            double t = oa / (oa - ob), a0 = A[0], a1 = A[1], b0 = B[0], b1 = B[1];
            int32_t w = b_split_edge(b, h, t);
            if (w < 0) return SC_ENOMEM;
            b->xy[2 * (size_t)w] = a0 + t * (b0 - a0);
            b->xy[2 * (size_t)w + 1] = a1 + t * (b1 - a1);
            b->side[w] = -1;
            f = b->pf[p].a[i];
        }
    }
    return SC_OK;
}

/* The centre of patch p: the vertex at the domain origin (made if needed). */
static int32_t insert_centre(builder *b, int32_t p) {
    qmesh *m = b->m;
    const double O[2] = {0, 0};
    int32_t bestf = -1;
    double bestmin = -1e300, bestl[3] = {0};
    for (int32_t i = 0; i < b->pf[p].n; i++) {
        int32_t f = b->pf[p].a[i];
        const int32_t *F = m->tri + 3 * (size_t)f;
        const double *A = b->xy + 2 * (size_t)F[0], *B = b->xy + 2 * (size_t)F[1], *C = b->xy + 2 * (size_t)F[2];
        double area = orient2(A, B, C);
        if (!(fabs(area) > 0)) continue;
        double l[3] = {orient2(B, C, O) / area, orient2(C, A, O) / area, orient2(A, B, O) / area};
        double mn = fmin(l[0], fmin(l[1], l[2]));
        if (mn > bestmin) bestmin = mn, bestf = f, memcpy(bestl, l, sizeof bestl);
    }
    if (bestf < 0) return -1;
    const int32_t *F = m->tri + 3 * (size_t)bestf;
    for (int k = 0; k < 3; k++)
        if (bestl[k] > 1 - 1e-3 && b->side[F[k]] == -1) return F[k];
    for (int k = 0; k < 3; k++) {
        int32_t h = 3 * bestf + (k + 1) % 3;   /* the edge opposite corner k */
        if (bestl[k] < 1e-3 && m->opp[h] >= 0 && m->patch[m->opp[h] / 3] == p) {
            double la = bestl[(k + 1) % 3], lb = bestl[(k + 2) % 3];
            double t = la + lb > 0 ? lb / (la + lb) : 0.5;
            int32_t va = m->tri[h], vb = m->tri[qm_next(h)];
            double xa = b->xy[2 * (size_t)va], ya = b->xy[2 * (size_t)va + 1];
            double xb = b->xy[2 * (size_t)vb], yb = b->xy[2 * (size_t)vb + 1];
            int32_t w = b_split_edge(b, h, t);
            if (w >= 0) b->xy[2 * (size_t)w] = xa + t * (xb - xa), b->xy[2 * (size_t)w + 1] = ya + t * (yb - ya), b->side[w] = -1;
            return w;
        }
    }
    double l[3];
    for (int k = 0; k < 3; k++) l[k] = bestl[k] < 1e-6 ? 1e-6 : bestl[k];
    double s = l[0] + l[1] + l[2];
    for (int k = 0; k < 3; k++) l[k] /= s;
    int32_t nf0 = m->nf;
    int32_t w = qm_split_face_point(m, bestf, l);
    if (w < 0 || !b_fit(b)) return -1;
    for (int32_t f = nf0; f < m->nf; f++)
        if (!iv_push(&b->pf[p], f)) return -1;
    const int32_t *G = m->tri + 3 * (size_t)bestf;   /* (a, b, w) now */
    int32_t vc = m->tri[3 * (size_t)(nf0) + 1];      /* g1 = (b, c, w) */
    int32_t abc[3] = {G[0], G[1], vc};
    double x = 0, y = 0;
    for (int k = 0; k < 3; k++) x += l[k] * b->xy[2 * (size_t)abc[k]], y += l[k] * b->xy[2 * (size_t)abc[k] + 1];
    b->xy[2 * (size_t)w] = x, b->xy[2 * (size_t)w + 1] = y;
    b->side[w] = -1;
    return w;
}

/* ---------------------------------------------------------------- cuts along edges (§4.2) */

typedef struct dnode {
    double d;
    int32_t v;
} dnode;

static bool dheap_push(dnode **h, int32_t *n, int32_t *cap, dnode x) {
    if (*n == *cap) {
        int32_t c = *cap ? 2 * *cap : 256;
        dnode *a = realloc(*h, (size_t)c * sizeof *a);
        if (!a) return false;
        *h = a, *cap = c;
    }
    int32_t i = (*n)++;
    while (i > 0 && (*h)[(i - 1) / 2].d > x.d) (*h)[i] = (*h)[(i - 1) / 2], i = (i - 1) / 2;
    (*h)[i] = x;
    return true;
}

static dnode dheap_pop(dnode *h, int32_t *n) {
    dnode top = h[0], x = h[--*n];
    int32_t i = 0;
    for (;;) {
        int32_t c = 2 * i + 1;
        if (c >= *n) break;
        if (c + 1 < *n && h[c + 1].d < h[c].d) c++;
        if (h[c].d >= x.d) break;
        h[i] = h[c], i = c;
    }
    if (*n > 0) h[i] = x;
    return top;
}

/* Distance in the domain from point P to the segment O-M. */
static double segment_distance(const double *O, const double *M, const double *P) {
    double dx = M[0] - O[0], dy = M[1] - O[1], l2 = dx * dx + dy * dy;
    double t = l2 > 0 ? ((P[0] - O[0]) * dx + (P[1] - O[1]) * dy) / l2 : 0;
    t = t < 0 ? 0 : t > 1 ? 1 : t;
    return hypot(P[0] - O[0] - t * dx, P[1] - O[1] - t * dy);
}

/* Split the edge of half-edge h at its middle, the new vertex inside the
 * current region (side -1) at the middle of the edge's domain image. */
static int32_t split_inner_edge(builder *b, int32_t h) {
    int32_t va = b->m->tri[h], vb = b->m->tri[qm_next(h)];
    double x = 0.5 * (b->xy[2 * (size_t)va] + b->xy[2 * (size_t)vb]);
    double y = 0.5 * (b->xy[2 * (size_t)va + 1] + b->xy[2 * (size_t)vb + 1]);
    int32_t w = b_split_edge(b, h, 0.5);
    if (w >= 0) b->xy[2 * (size_t)w] = x, b->xy[2 * (size_t)w + 1] = y, b->side[w] = -1;
    return w;
}

/* The centre of patch p for cuts along edges: the inner vertex nearest the
 * domain origin (an inner edge split at its middle when the patch has no
 * inner vertex); -1 when the patch has no inner edge either. */
static int centre_vertex(builder *b, int32_t p, int32_t *c) {
    qmesh *m = b->m;
    double best = INFINITY;
    int32_t besth = -1;
    *c = -1;
    for (int32_t i = 0; i < b->pf[p].n; i++)
        for (int k = 0; k < 3; k++) {
            int32_t h = 3 * b->pf[p].a[i] + k, v = m->tri[h], vn = m->tri[qm_next(h)];
            double r = hypot(b->xy[2 * (size_t)v], b->xy[2 * (size_t)v + 1]);
            if (b->side[v] == -1 && r < best) best = r, *c = v, besth = -1;
            if (*c < 0 && m->opp[h] >= 0 && m->patch[m->opp[h] / 3] == p) {
                r = 0.5 * hypot(b->xy[2 * (size_t)v] + b->xy[2 * (size_t)vn], b->xy[2 * (size_t)v + 1] + b->xy[2 * (size_t)vn + 1]);
                if (r < best) best = r, besth = h;
            }
        }
    if (*c < 0 && besth >= 0 && (*c = split_inner_edge(b, besth)) < 0) return SC_ENOMEM;
    return SC_OK;
}

/* Inner edges of patch p that the straight domain segments from the origin
 * to the medians cross: the edge splits straight cuts would make. */
static int64_t straight_crossings(const builder *b, int32_t p, const int32_t *med, int32_t n) {
    const qmesh *m = b->m;
    const double O[2] = {0, 0};
    int64_t count = 0;
    for (int32_t s = 0; s < n; s++) {
        const double *M = b->xy + 2 * (size_t)med[s];
        for (int32_t i = 0; i < b->pf[p].n; i++)
            for (int k = 0; k < 3; k++) {
                int32_t h = 3 * b->pf[p].a[i] + k, o = m->opp[h], va = m->tri[h], vb = m->tri[qm_next(h)];
                if (o < 0 || m->patch[o / 3] != p || va > vb) continue;
                const double *A = b->xy + 2 * (size_t)va, *B = b->xy + 2 * (size_t)vb;
                double oa = orient2(O, M, A), ob = orient2(O, M, B), s0 = orient2(A, B, O), s1 = orient2(A, B, M);
                count += ((oa > 0 && ob < 0) || (oa < 0 && ob > 0)) && ((s0 > 0 && s1 < 0) || (s0 < 0 && s1 > 0));
            }
    }
    return count;
}

/* The graph paths run on: the patch's vertices (numbered in b->local) and
 * the middle of every inner edge, where a path may cross the edge (split
 * there only if a path takes it). A link joins two vertices along an edge
 * (lmid: that edge's middle, which a path along it blocks), or crosses face
 * lface from an edge's middle to the face's opposite vertex or to another
 * of its edges' middles. Node i's links are [start[i], start[i + 1]). */
typedef struct path_graph {
    ivec verts;               /* node i < verts.n: mesh vertex verts.a[i] */
    ivec mid_ends;            /* node verts.n + j: the middle of edge (mid_ends[2j], mid_ends[2j + 1]) */
    ivec mid_faces;           /* its two faces (indices into the patch's face list) */
    int32_t *start, *nb, *lface, *lmid;
    double *xy;               /* 2 per node */
} path_graph;

static void path_graph_free(builder *b, path_graph *g) {
    for (int32_t i = 0; i < g->verts.n; i++) b->local[g->verts.a[i]] = -1;
    free(g->verts.a), free(g->mid_ends.a), free(g->mid_faces.a);
    free(g->start), free(g->nb), free(g->lface), free(g->lmid), free(g->xy);
    memset(g, 0, sizeof *g);
}

static int path_graph_build(builder *b, int32_t p, path_graph *g) {
    qmesh *m = b->m;
    const ivec *pf = &b->pf[p];
    memset(g, 0, sizeof *g);
    int32_t nf = pf->n;
    int32_t *mid = malloc((size_t)nf * 3 * sizeof *mid);   /* per face edge: its middle's node, or -1 */
    edge_key *keys = malloc((size_t)nf * 3 * sizeof *keys);
    int rc = mid && keys ? SC_OK : SC_ENOMEM;
    for (int32_t i = 0; i < nf && rc == SC_OK; i++)
        for (int k = 0; k < 3; k++) {
            int32_t v = m->tri[3 * (size_t)pf->a[i] + k];
            if (b->local[v] >= 0) continue;
            b->local[v] = g->verts.n;
            if (!iv_push(&g->verts, v)) { rc = SC_ENOMEM; break; }
        }
    int32_t nk = 0, nv = g->verts.n;
    for (int32_t i = 0; i < nf && rc == SC_OK; i++)
        for (int k = 0; k < 3; k++) {
            int32_t h = 3 * pf->a[i] + k, o = m->opp[h], va = m->tri[h], vb = m->tri[qm_next(h)];
            mid[3 * i + k] = -1;
            if (o >= 0 && m->patch[o / 3] == p) keys[nk++] = (edge_key){va < vb ? va : vb, va < vb ? vb : va, 3 * i + k};
        }
    if (rc == SC_OK) qsort(keys, (size_t)nk, sizeof *keys, cmp_edge_key);
    for (int32_t j = 0; j < nk && rc == SC_OK; j++) {
        bool fresh = j == 0 || keys[j].lo != keys[j - 1].lo || keys[j].hi != keys[j - 1].hi;
        if (fresh && (!iv_push(&g->mid_ends, keys[j].lo) || !iv_push(&g->mid_ends, keys[j].hi) ||
                      !iv_push(&g->mid_faces, keys[j].h / 3) || !iv_push(&g->mid_faces, keys[j].h / 3)))
            rc = SC_ENOMEM;
        if (!fresh && rc == SC_OK) g->mid_faces.a[g->mid_faces.n - 1] = keys[j].h / 3;
        mid[keys[j].h] = nv + g->mid_ends.n / 2 - 1;
    }
    int32_t nn = nv + g->mid_ends.n / 2;
    g->start = calloc((size_t)nn + 1, sizeof *g->start);
    g->xy = malloc((size_t)nn * 2 * sizeof *g->xy);
    if (rc == SC_OK && (!g->start || !g->xy)) rc = SC_ENOMEM;
    for (int pass = 0; pass < 2 && rc == SC_OK; pass++) {
        int32_t *fill = NULL;
        if (pass == 1) {
            for (int32_t i = 0; i < nn; i++) g->start[i + 1] += g->start[i];
            size_t nl = (size_t)g->start[nn];
            g->nb = malloc(nl * sizeof *g->nb), g->lface = malloc(nl * sizeof *g->lface);
            g->lmid = malloc(nl * sizeof *g->lmid), fill = malloc((size_t)nn * sizeof *fill);
            if (!g->nb || !g->lface || !g->lmid || !fill) { free(fill); rc = SC_ENOMEM; break; }
            memcpy(fill, g->start, (size_t)nn * sizeof *fill);
        }
        for (int32_t i = 0; i < nf; i++) {
            const int32_t *F = m->tri + 3 * (size_t)pf->a[i];
            for (int k = 0; k < 3; k++) {
                int32_t a = b->local[F[k]], z = b->local[F[(k + 1) % 3]], apex = b->local[F[(k + 2) % 3]];
                int32_t md = mid[3 * i + k], md2 = mid[3 * i + (k + 1) % 3];
                /* along the edge (inner edges only), then across the face */
                int32_t links[3][4] = {{md >= 0 ? a : -1, z, -1, md}, {md, apex, i, -1}, {md, md2, i, -1}};
                for (int l = 0; l < 3; l++) {
                    int32_t x = links[l][0], y = links[l][1];
                    if (x < 0 || y < 0) continue;
                    if (pass == 0) {
                        g->start[x + 1]++, g->start[y + 1]++;
                        continue;
                    }
                    g->nb[fill[x]] = y, g->lface[fill[x]] = links[l][2], g->lmid[fill[x]++] = links[l][3];
                    g->nb[fill[y]] = x, g->lface[fill[y]] = links[l][2], g->lmid[fill[y]++] = links[l][3];
                }
            }
        }
        free(fill);
    }
    for (int32_t i = 0; i < nv && rc == SC_OK; i++)
        g->xy[2 * i] = b->xy[2 * (size_t)g->verts.a[i]], g->xy[2 * i + 1] = b->xy[2 * (size_t)g->verts.a[i] + 1];
    for (int32_t j = 0; j < g->mid_ends.n / 2 && rc == SC_OK; j++) {
        int32_t va = g->mid_ends.a[2 * j], vb = g->mid_ends.a[2 * j + 1];
        g->xy[2 * (nv + j)] = 0.5 * (b->xy[2 * (size_t)va] + b->xy[2 * (size_t)vb]);
        g->xy[2 * (nv + j) + 1] = 0.5 * (b->xy[2 * (size_t)va + 1] + b->xy[2 * (size_t)vb + 1]);
    }
    free(mid), free(keys);
    if (rc) path_graph_free(b, g);
    return rc;
}

/* Split the inner edge of patch p between vertices va and vb at its middle
 * (found by its ends: earlier splits renumber half-edges). */
static int32_t split_edge_between(builder *b, int32_t p, int32_t va, int32_t vb) {
    for (int32_t i = 0; i < b->pf[p].n; i++)
        for (int k = 0; k < 3; k++) {
            int32_t h = 3 * b->pf[p].a[i] + k;
            if (b->m->tri[h] == va && b->m->tri[qm_next(h)] == vb) return split_inner_edge(b, h);
        }
    return -2;
}

/* Cut patch p into its n quads along mesh edges, as the paper does: a
 * centre vertex c and, for each side s, the cheapest path from c to the
 * side's median med[s] near the straight domain segment between them. A
 * path runs along inner edges, or across a face through the middle of an
 * edge where it must (that edge is then split, costing two faces); it
 * shares no node with the other paths and crosses no face another path
 * crosses or splits. The paths meet only at c and cut the disc into n
 * sectors, sector s holding corner cor[s]; each face of sector s gets
 * m->quad = -2 - s. *ok is false (the mesh refined only in its plane) when
 * no such set of paths exists: no inner edge, a path blocked by the others,
 * or sectors that do not hold one corner each. */
static int cut_paths(builder *b, int32_t p, const int32_t *cor, const int32_t *med, int32_t n, int32_t *c_out,
                     bool *ok) {
    qmesh *m = b->m;
    *ok = false;
    int32_t cv;
    int rc = centre_vertex(b, p, &cv);
    if (rc || cv < 0) return rc;
    path_graph g;
    if ((rc = path_graph_build(b, p, &g))) return rc;
    int32_t nv = g.verts.n, nn = nv + g.mid_ends.n / 2, c = b->local[cv], hn = 0, hcap = 0;
    int32_t nfp = b->pf[p].n;
    int32_t *prev = malloc((size_t)nn * sizeof *prev), *via = malloc((size_t)nn * sizeof *via);
    int32_t *owner = malloc((size_t)nn * sizeof *owner);   /* the median a node touches, -2 several, -1 none */
    uint8_t *used = calloc((size_t)nn, 1), *ring = calloc((size_t)nn, 1), *crossed = calloc((size_t)nfp, 1);
    double *dist = malloc((size_t)nn * sizeof *dist);
    dnode *dheap = NULL;
    ivec path = {0}, pathv = {0}, fq = {0};   /* the paths' nodes, c excluded, each ended by -1 */
    if (!used || !prev || !via || !dist || !ring || !crossed || !owner) { rc = SC_ENOMEM; goto done; }
    /* c's neighbours are each only a path's first node, and a median's
     * neighbours serve only its own path, so no path takes another's way in */
    for (int32_t e = g.start[c]; e < g.start[c + 1]; e++) ring[g.nb[e]] = 1;
    for (int32_t i = 0; i < nn; i++) owner[i] = -1;
    for (int32_t s = 0; s < n; s++) {
        int32_t t = b->local[med[s]];
        for (int32_t e = g.start[t]; e < g.start[t + 1]; e++) {
            int32_t w = g.nb[e];
            owner[w] = owner[w] == -1 || owner[w] == s ? s : -2;
        }
    }
    /* three tries: the paths in side order; with each median's neighbours
     * kept for its own path; the same in reverse order */
    const double *O = g.xy + 2 * (size_t)c;
    bool found = false;
    for (int attempt = 0; attempt < 3 && !found; attempt++) {
        path.n = 0;
        memset(used, 0, (size_t)nn), memset(crossed, 0, (size_t)nfp);
        found = true;
        for (int32_t k = 0; k < n && found; k++) {
            int32_t s = attempt == 2 ? n - 1 - k : k;
            int32_t target = b->local[med[s]];
            const double *M = g.xy + 2 * (size_t)target;
            double seg = hypot(M[0] - O[0], M[1] - O[1]) + 1e-300;
            for (int32_t i = 0; i < nn; i++) dist[i] = INFINITY, prev[i] = -1;
            dist[c] = 0, hn = 0;
            if (!dheap_push(&dheap, &hn, &hcap, (dnode){0, c})) { rc = SC_ENOMEM; goto done; }
            while (hn > 0) {
                dnode x = dheap_pop(dheap, &hn);
                if (x.d > dist[x.v]) continue;
                if (x.v == target) break;
                const double *A = g.xy + 2 * (size_t)x.v;
                for (int32_t e = g.start[x.v]; e < g.start[x.v + 1]; e++) {
                    int32_t w = g.nb[e];
                    if (w != target && (used[w] || w == c || (w < nv && b->side[g.verts.a[w]] != -1) ||
                                        (ring[w] && x.v != c) || (attempt > 0 && owner[w] >= 0 && owner[w] != s)))
                        continue;
                    if ((g.lface[e] >= 0 && crossed[g.lface[e]]) || (g.lmid[e] >= 0 && used[g.lmid[e]])) continue;
                    const double *B = g.xy + 2 * (size_t)w;
                    double len = hypot(B[0] - A[0], B[1] - A[1]);
                    double off = 0.5 * (segment_distance(O, M, A) + segment_distance(O, M, B));
                    double d = x.d + len * (1 + 8 * off / seg) * (g.lface[e] >= 0 ? 2 : 1) + 1e-9 * seg;
                    if (d < dist[w]) {
                        dist[w] = d, prev[w] = x.v, via[w] = e;
                        if (!dheap_push(&dheap, &hn, &hcap, (dnode){d, w})) { rc = SC_ENOMEM; goto done; }
                    }
                }
            }
            if (prev[target] < 0) {
                found = false;
                break;
            }
            int32_t first = path.n;
            for (int32_t w = target; w != c; w = prev[w]) {
                int32_t e = via[w];
                used[w] = 1;
                if (g.lmid[e] >= 0) used[g.lmid[e]] = 1;
                if (g.lface[e] >= 0) crossed[g.lface[e]] = 1;
                if (w >= nv) crossed[g.mid_faces.a[2 * (w - nv)]] = crossed[g.mid_faces.a[2 * (w - nv) + 1]] = 1;
                if (!iv_push(&path, w)) { rc = SC_ENOMEM; goto done; }
            }
            for (int32_t i = first, j = path.n - 1; i < j; i++, j--) {
                int32_t t = path.a[i];
                path.a[i] = path.a[j], path.a[j] = t;
            }
            if (!iv_push(&path, -1)) { rc = SC_ENOMEM; goto done; }
        }
    }
    if (!found) goto done;
    int64_t splits = 0;
    for (int32_t i = 0; i < path.n; i++) splits += path.a[i] >= nv;
    if (splits >= straight_crossings(b, p, med, n)) goto done;   /* straight cuts split no more */
    /* the paths as mesh vertices, splitting each edge they cross */
    for (int32_t i = 0; i < path.n; i++) {
        int32_t x = path.a[i], v = x < nv ? (x < 0 ? -1 : g.verts.a[x])
                                           : split_edge_between(b, p, g.mid_ends.a[2 * (x - nv)], g.mid_ends.a[2 * (x - nv) + 1]);
        if (v == -2) goto done;   /* an edge split away by an earlier cut: no sectors */
        if (x >= nv && v < 0) { rc = SC_ENOMEM; goto done; }
        if (!iv_push(&pathv, v)) { rc = SC_ENOMEM; goto done; }
    }
    /* sectors: faces flooded from each corner, never across a path edge
     * (b->local of a path vertex: its index in pathv) */
    for (int32_t i = 0; i < nv; i++) b->local[g.verts.a[i]] = -1;
    g.verts.n = 0;
    for (int32_t i = 0; i < pathv.n && rc == SC_OK; i++)
        if (pathv.a[i] >= 0) {
            b->local[pathv.a[i]] = i;
            if (!iv_push(&g.verts, pathv.a[i])) rc = SC_ENOMEM;   /* so path_graph_free clears them */
        }
    const ivec *pf = &b->pf[p];
    for (int32_t s = 0; s < n && rc == SC_OK; s++) {
        fq.n = 0;
        for (int32_t i = 0; i < pf->n && fq.n == 0; i++) {
            const int32_t *F = m->tri + 3 * (size_t)pf->a[i];
            if (F[0] != cor[s] && F[1] != cor[s] && F[2] != cor[s]) continue;
            if (m->quad[pf->a[i]] != -1) goto unmark;   /* the corner lies in another sector */
            m->quad[pf->a[i]] = -2 - s;
            if (!iv_push(&fq, pf->a[i])) { rc = SC_ENOMEM; goto unmark; }
        }
        for (int32_t head = 0; head < fq.n; head++) {
            int32_t f = fq.a[head];
            for (int k = 0; k < 3; k++) {
                int32_t h = 3 * f + k, o = m->opp[h];
                if (o < 0 || m->patch[o / 3] != p) continue;
                int32_t a = m->tri[h], z = m->tri[qm_next(h)], ia = b->local[a], iz = b->local[z];
                bool cut = (a == cv && iz >= 0 && (iz == 0 || pathv.a[iz - 1] < 0)) ||
                           (z == cv && ia >= 0 && (ia == 0 || pathv.a[ia - 1] < 0)) ||
                           (ia >= 0 && iz >= 0 && abs(ia - iz) == 1);
                if (cut) continue;
                int32_t gf = o / 3;
                if (m->quad[gf] == -2 - s) continue;
                if (m->quad[gf] != -1) goto unmark;   /* two corners in one sector */
                m->quad[gf] = -2 - s;
                if (!iv_push(&fq, gf)) { rc = SC_ENOMEM; goto unmark; }
            }
        }
    }
    for (int32_t i = 0; i < pf->n && rc == SC_OK; i++)
        if (m->quad[pf->a[i]] == -1) goto unmark;
    if (rc == SC_OK) *ok = true, *c_out = cv;
    if (rc == SC_OK) goto done;
unmark:
    for (int32_t i = 0; i < pf->n; i++) m->quad[pf->a[i]] = -1;
done:
    path_graph_free(b, &g);
    free(used), free(ring), free(crossed), free(owner), free(prev), free(via), free(dist), free(dheap), free(path.a), free(pathv.a), free(fq.a);
    return rc;
}

static int new_quad(builder *b, int32_t *q) {
    if (b->qcorner.n / 4 == b->qcap) {
        int32_t cap = b->qcap ? 2 * b->qcap : 256;
        ivec *qf = realloc(b->qf, (size_t)cap * sizeof *qf);
        if (!qf) return SC_ENOMEM;
        memset(qf + b->qcap, 0, (size_t)(cap - b->qcap) * sizeof *qf);
        b->qf = qf, b->qcap = cap;
    }
    *q = b->qcorner.n / 4;
    return SC_OK;
}

/* Map patch p onto a regular n-gon, cut it into n quads, record them. */
static int quadrangulate(builder *b, int32_t p, sc_error *err) {
    bool ok;
    int rc = patch_loop(b, p, &ok);
    if (rc) return rc;
    if (!ok) return sc_fail(err, SC_EINPUT, "patch %d is not a disc", (int)p);
    int32_t L = b->lw.verts.n;
    ivec cpos = {0}, unk = {0};
    for (int32_t i = 0; i < L; i++)
        if (is_corner(b, i) && !iv_push(&cpos, i)) return SC_ENOMEM;
    int32_t n = cpos.n;
    double (*poly)[2] = malloc((size_t)n * sizeof *poly);
    if (!poly) { free(cpos.a); return SC_ENOMEM; }
    for (int32_t s = 0; s < n; s++) poly[s][0] = cos(2 * M_PI * s / n), poly[s][1] = sin(2 * M_PI * s / n);
    b->hist[n - 3 < 8 ? n - 3 : 8]++;
    place_loop(b, cpos.a, n, (const double (*)[2])poly);
    rc = split_dividing_edges(b, &b->pf[p], in_patch, &p, n);
    if (rc == SC_OK) rc = region_unknowns(b, &b->pf[p], &unk);
    if (rc == SC_OK) rc = tutte(b, &b->pf[p], unk.a, unk.n, NULL, err);
    for (int32_t i = 0; i < unk.n; i++) b->local[unk.a[i]] = -1;
    int32_t *med = malloc((size_t)n * sizeof *med), *cor = malloc((size_t)n * sizeof *cor);
    if (rc == SC_OK && (!med || !cor)) rc = SC_ENOMEM;
    for (int32_t s = 0; s < n && rc == SC_OK; s++) {
        cor[s] = b->lw.verts.a[cpos.a[s]], med[s] = -1;
        for (int32_t k = (cpos.a[s] + 1) % L; k != cpos.a[(s + 1) % n]; k = (k + 1) % L)
            if (b->flag[b->lw.verts.a[k]] & FLAG_MEDIAN) med[s] = b->lw.verts.a[k];
        if (med[s] < 0) rc = sc_fail(err, SC_EINPUT, "patch %d: a side without its median", (int)p);
    }
    int32_t c = -1;
    bool along_edges = false;
    if (rc == SC_OK) rc = cut_paths(b, p, cor, med, n, &c, &along_edges);
    if (rc == SC_OK && !along_edges) {
        /* no paths along edges: straight cuts in the domain, splitting the edges they cross */
        b->straight_cuts++;
        c = insert_centre(b, p);
        if (c < 0) rc = sc_fail(err, SC_EINPUT, "patch %d: no centre in its domain", (int)p);
        for (int32_t s = 0; s < n && rc == SC_OK; s++) rc = cut_segment(b, p, c, med[s]);
    }
    /* quads: sector s holds corner s, between the cuts to med[s-1] and med[s] */
    int32_t q0 = b->qcorner.n / 4;
    for (int32_t s = 0; s < n && rc == SC_OK; s++) {
        int32_t q;
        rc = new_quad(b, &q);
        if (rc == SC_OK && (!iv_push(&b->qcorner, cor[s]) || !iv_push(&b->qcorner, med[s]) ||
                            !iv_push(&b->qcorner, c) || !iv_push(&b->qcorner, med[(s + n - 1) % n])))
            rc = SC_ENOMEM;
    }
    for (int32_t i = 0; i < b->pf[p].n && rc == SC_OK && along_edges; i++) {
        int32_t f = b->pf[p].a[i];
        b->m->quad[f] = q0 + (-2 - b->m->quad[f]);
        if (!iv_push(&b->qf[b->m->quad[f]], f)) rc = SC_ENOMEM;
    }
    for (int32_t i = 0; i < b->pf[p].n && rc == SC_OK && !along_edges; i++) {
        int32_t f = b->pf[p].a[i];
        const int32_t *F = b->m->tri + 3 * (size_t)f;
        double g[2] = {0, 0};
        for (int k = 0; k < 3; k++) g[0] += b->xy[2 * (size_t)F[k]] / 3, g[1] += b->xy[2 * (size_t)F[k] + 1] / 3;
        int32_t best = 0;
        double bm = -1e300;
        const double O[2] = {b->xy[2 * (size_t)c], b->xy[2 * (size_t)c + 1]};
        for (int32_t s = 0; s < n; s++) {
            const double *A = b->xy + 2 * (size_t)med[(s + n - 1) % n], *B = b->xy + 2 * (size_t)med[s];
            double la = orient2(O, A, g) / (hypot(A[0] - O[0], A[1] - O[1]) + 1e-300);
            double lb = -orient2(O, B, g) / (hypot(B[0] - O[0], B[1] - O[1]) + 1e-300);
            double mn = fmin(la, lb);
            if (mn > bm) bm = mn, best = s;
        }
        b->m->quad[f] = q0 + best;
        if (!iv_push(&b->qf[q0 + best], f)) rc = SC_ENOMEM;
    }
    for (int32_t i = 0; i < b->lw.verts.n; i++) b->side[b->lw.verts.a[i]] = -1;
    free(poly), free(med), free(cor), free(cpos.a), free(unk.a);
    return rc;
}

/* ---------------------------------------------------------------- chart maps (§4.3) */

/* Stretch of face f under the map b->xy (Sander et al.): L2^2 and Gamma^2,
 * with the face's surface area. False when the map folds or flattens it. */
static bool face_stretch(const builder *b, int32_t f, double *l2sq, double *gsq, double *area) {
    const int32_t *F = b->m->tri + 3 * (size_t)f;
    const double *p[3], *q[3];
    for (int k = 0; k < 3; k++) p[k] = b->m->pos + 3 * (size_t)F[k], q[k] = b->xy + 2 * (size_t)F[k];
    *area = qm_area(b->m, f);
    double A = 0.5 * orient2(q[0], q[1], q[2]);
    if (!(A > 0)) return false;
    double Ss[3], St[3];
    for (int i = 0; i < 3; i++) {
        Ss[i] = (p[0][i] * (q[1][1] - q[2][1]) + p[1][i] * (q[2][1] - q[0][1]) + p[2][i] * (q[0][1] - q[1][1])) / (2 * A);
        St[i] = (p[0][i] * (q[2][0] - q[1][0]) + p[1][i] * (q[0][0] - q[2][0]) + p[2][i] * (q[1][0] - q[0][0])) / (2 * A);
    }
    double a = sc_dot3(Ss, Ss), bb = sc_dot3(Ss, St), c = sc_dot3(St, St);
    *l2sq = 0.5 * (a + c);
    *gsq = 0.5 * ((a + c) + sqrt((a - c) * (a - c) + 4 * bb * bb));
    return true;
}

/* Map quad q onto the unit square: sides by arc length, inside mean-value
 * coordinates re-weighted to reduce stretch (Yoshizawa et al. 2004), keeping
 * the map of least L2 stretch; then record chart coordinates per corner. */
static int parameterize_quad(builder *b, int32_t q, double **st, int32_t *st_cap, double *sum_l2, double *sum_area,
                             double *within_l2, double *max_g, int32_t *flipped, sc_error *err) {
    static const double square[4][2] = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};
    bool ok, oom = false;
    int32_t cpos[4];
    ivec unk = {0};
    int rc = SC_OK;
    double *best = NULL, *sigma = NULL;
    ok = loop_build(b->m, b->qf[q].a, b->qf[q].n, in_quad, &q, &b->lw, &oom);
    if (oom) return SC_ENOMEM;
    if (!ok) return sc_fail(err, SC_EINPUT, "quad %d is not a disc", (int)q);
    int32_t L = b->lw.verts.n;
    for (int k = 0; k < 4; k++) {
        cpos[k] = -1;
        for (int32_t i = 0; i < L; i++)
            if (b->lw.verts.a[i] == b->qcorner.a[4 * q + k]) cpos[k] = i;
        if (cpos[k] < 0) return sc_fail(err, SC_EINPUT, "quad %d: corner %d not on its border", (int)q, k);
    }
    for (int k = 1; k < 4; k++)
        if ((cpos[k] - cpos[0] + L) % L <= (cpos[k - 1] - cpos[0] + L) % L)
            return sc_fail(err, SC_EINPUT, "quad %d: corners out of order", (int)q);
    place_loop(b, cpos, 4, square);
    rc = split_dividing_edges(b, &b->qf[q], in_quad, &q, 4);
    if (rc) return rc;
    rc = region_unknowns(b, &b->qf[q], &unk);
    if (rc == SC_OK) rc = tutte(b, &b->qf[q], unk.a, unk.n, NULL, err);
    int32_t nu = unk.n;
    best = malloc(((size_t)nu * 2 + 1) * sizeof *best);
    sigma = malloc((size_t)b->m->nv * sizeof *sigma);
    double *acc = calloc((size_t)b->m->nv * 2, sizeof *acc);
    if (rc == SC_OK && (!best || !sigma || !acc)) rc = SC_ENOMEM;
    double best_l2 = INFINITY;
    for (int it = 0; it < 4 && rc == SC_OK; it++) {
        double s2 = 0, sa = 0;
        bool folded = false;
        for (int32_t i = 0; i < b->qf[q].n; i++) {
            double l2sq, gsq, a;
            int32_t f = b->qf[q].a[i];
            if (!face_stretch(b, f, &l2sq, &gsq, &a)) { folded = a > 0; continue; }
            s2 += a * l2sq, sa += a;
            for (int k = 0; k < 3; k++) {
                int32_t v = b->m->tri[3 * (size_t)f + k];
                acc[2 * (size_t)v] += a * l2sq, acc[2 * (size_t)v + 1] += a;
            }
        }
        double l2 = sa > 0 ? sqrt(s2 / sa) : 0;
        if (!folded && l2 < best_l2) {
            best_l2 = l2;
            for (int32_t i = 0; i < nu; i++) best[2 * i] = b->xy[2 * (size_t)unk.a[i]], best[2 * i + 1] = b->xy[2 * (size_t)unk.a[i] + 1];
        }
        if (it == 3 || nu == 0) break;
        for (int32_t i = 0; i < b->qf[q].n; i++)
            for (int k = 0; k < 3; k++) {
                int32_t v = b->m->tri[3 * (size_t)b->qf[q].a[i] + k];
                if (acc[2 * (size_t)v + 1] > 0) {
                    double s = sqrt(acc[2 * (size_t)v] / acc[2 * (size_t)v + 1]) / (l2 > 0 ? l2 : 1);
                    sigma[v] = it == 0 ? s : sigma[v] * s;
                    acc[2 * (size_t)v] = acc[2 * (size_t)v + 1] = 0;
                } else if (it == 0) sigma[v] = 1;
                if (!(sigma[v] > 1e-6)) sigma[v] = 1e-6;
            }
        rc = tutte(b, &b->qf[q], unk.a, unk.n, sigma, err);
    }
    if (rc == SC_OK && isfinite(best_l2))
        for (int32_t i = 0; i < nu; i++) b->xy[2 * (size_t)unk.a[i]] = best[2 * i], b->xy[2 * (size_t)unk.a[i] + 1] = best[2 * i + 1];
    for (int32_t i = 0; i < nu; i++) b->local[unk.a[i]] = -1;
    free(best), free(sigma), free(acc), free(unk.a);
    if (rc) return rc;
    /* chart coordinates per face corner; stretch sums */
    if (b->m->nf > *st_cap) {
        int32_t cap = b->m->nf * 2;
        double *s = realloc(*st, (size_t)cap * 6 * sizeof *s);
        if (!s) return SC_ENOMEM;
        *st = s, *st_cap = cap;
    }
    double chart_l2 = 0, chart_area = 0;
    for (int32_t i = 0; i < b->qf[q].n; i++) {
        int32_t f = b->qf[q].a[i];
        for (int k = 0; k < 3; k++) {
            int32_t v = b->m->tri[3 * (size_t)f + k];
            (*st)[6 * (size_t)f + 2 * k] = b->xy[2 * (size_t)v], (*st)[6 * (size_t)f + 2 * k + 1] = b->xy[2 * (size_t)v + 1];
        }
        double l2sq, gsq, a;
        if (!face_stretch(b, f, &l2sq, &gsq, &a)) {
            *flipped += a > 0;
            continue;
        }
        *sum_l2 += a * l2sq, *sum_area += a;
        chart_l2 += a * l2sq, chart_area += a;
        if (gsq > *max_g) *max_g = gsq;
    }
    /* the chart on its own: its unit square scaled to its surface area */
    if (chart_area > 0) *within_l2 += chart_l2 / chart_area;
    return SC_OK;
}

typedef struct side_key {
    int32_t lo, next, slot;
} side_key;

static int cmp_side_key(const void *a, const void *b) {
    const side_key *x = a, *y = b;
    if (x->lo != y->lo) return x->lo < y->lo ? -1 : 1;
    if (x->next != y->next) return x->next < y->next ? -1 : 1;
    return x->slot < y->slot ? -1 : x->slot > y->slot;
}

/* Global side numbers: a side is named by its lower corner and the vertex
 * after it along the side, so both charts that hold it find one name. */
static int number_sides(builder *b, qcharts *out) {
    int32_t Q = out->nquads;
    side_key *keys = malloc((size_t)Q * 4 * sizeof *keys);
    if (!keys) return SC_ENOMEM;
    for (int32_t q = 0; q < Q; q++) {
        bool oom = false;
        if (!loop_build(b->m, b->qf[q].a, b->qf[q].n, in_quad, &q, &b->lw, &oom)) { free(keys); return oom ? SC_ENOMEM : SC_EINPUT; }
        int32_t L = b->lw.verts.n, pos[4];
        for (int k = 0; k < 4; k++)
            for (int32_t i = 0; i < L; i++)
                if (b->lw.verts.a[i] == b->qcorner.a[4 * q + k]) pos[k] = i;
        for (int k = 0; k < 4; k++) {
            int32_t c0 = b->qcorner.a[4 * q + k], c1 = b->qcorner.a[4 * q + (k + 1) % 4];
            int32_t after = b->lw.verts.a[(pos[k] + 1) % L], before = b->lw.verts.a[(pos[(k + 1) % 4] + L - 1) % L];
            bool rev = c0 > c1;
            keys[4 * q + k] = (side_key){rev ? c1 : c0, rev ? before : after, 4 * q + k};
            out->side_rev[4 * q + k] = rev;
            out->corner_v[4 * q + k] = c0;
        }
    }
    qsort(keys, (size_t)Q * 4, sizeof *keys, cmp_side_key);
    int32_t n = 0;
    for (int32_t i = 0; i < 4 * Q; i++) {
        if (i > 0 && (keys[i].lo != keys[i - 1].lo || keys[i].next != keys[i - 1].next)) n++;
        out->side_id[keys[i].slot] = n;
    }
    out->nsides = Q > 0 ? n + 1 : 0;
    free(keys);
    return SC_OK;
}

static void builder_free(builder *b) {
    if (b->pf)
        for (int32_t p = 0; p < b->np; p++) free(b->pf[p].a);
    if (b->qf)
        for (int32_t q = 0; q < b->qcap; q++) free(b->qf[q].a);
    free(b->pf), free(b->qf), free(b->qcorner.a), free(b->lw.verts.a), free(b->lw.hs.a), free(b->lw.mark);
    free(b->lw.slot), free(b->flag), free(b->local), free(b->xy), free(b->side), free(b->label.a);
}

/* ---------------------------------------------------------------- straight patch borders (§4.1) */

/* Scratch for straightening: per vertex its outgoing half-edges (CSR) and
 * whether it lies on the mesh border; per face a stamp of the region being
 * re-split and the flood's side; Dijkstra's state. */
typedef struct straightener {
    qmesh *m;
    int32_t *out_start, *out_h;   /* per vertex: half-edges leaving it */
    uint8_t *border;              /* per vertex */
    int32_t *in_region, stamp;    /* per face: == stamp when in A or B */
    int32_t *side;                /* per face: the flood's mark */
    double *dist;                 /* per vertex */
    int32_t *via, *seen;          /* per vertex: the half-edge reaching it; == stamp when dist is set */
    uint8_t *on_path;             /* per vertex */
    dnode *heap;
    int32_t nheap, cap_heap;
    ivec arc, path, faces, queue;
} straightener;

static void straightener_free(straightener *S) {
    free(S->out_start), free(S->out_h), free(S->border), free(S->in_region), free(S->side), free(S->dist);
    free(S->via), free(S->seen), free(S->on_path), free(S->heap);
    free(S->arc.a), free(S->path.a), free(S->faces.a), free(S->queue.a);
}

static int straightener_init(straightener *S, qmesh *m) {
    memset(S, 0, sizeof *S);
    S->m = m;
    int32_t nv = m->nv, nh = 3 * m->nf;
    S->out_start = calloc((size_t)nv + 1, sizeof *S->out_start);
    S->out_h = malloc((size_t)(nh > 0 ? nh : 1) * sizeof *S->out_h);
    S->border = calloc((size_t)nv + 1, 1);
    S->in_region = calloc((size_t)m->nf + 1, sizeof *S->in_region);
    S->side = calloc((size_t)m->nf + 1, sizeof *S->side);
    S->dist = malloc(((size_t)nv + 1) * sizeof *S->dist);
    S->via = malloc(((size_t)nv + 1) * sizeof *S->via);
    S->seen = calloc((size_t)nv + 1, sizeof *S->seen);
    S->on_path = calloc((size_t)nv + 1, 1);
    if (!S->out_start || !S->out_h || !S->border || !S->in_region || !S->side || !S->dist || !S->via || !S->seen ||
        !S->on_path)
        return SC_ENOMEM;
    for (int32_t h = 0; h < nh; h++) {
        S->out_start[m->tri[h] + 1]++;
        if (m->opp[h] < 0) S->border[m->tri[h]] = S->border[m->tri[qm_next(h)]] = 1;
    }
    for (int32_t v = 0; v < nv; v++) S->out_start[v + 1] += S->out_start[v];
    int32_t *fill = malloc(((size_t)nv + 1) * sizeof *fill);
    if (!fill) return SC_ENOMEM;
    memcpy(fill, S->out_start, (size_t)nv * sizeof *fill);
    for (int32_t h = 0; h < nh; h++) S->out_h[fill[m->tri[h]]++] = h;
    free(fill);
    return SC_OK;
}

/* Distance from p to the segment a-b (3D). */
static double point_segment3(const double *p, const double *a, const double *b) {
    double ab[3], ap[3];
    sc_sub3(b, a, ab), sc_sub3(p, a, ap);
    double l2 = sc_dot3(ab, ab), t = l2 > 0 ? sc_dot3(ap, ab) / l2 : 0;
    t = t < 0 ? 0 : t > 1 ? 1 : t;
    double q[3] = {a[0] + t * ab[0], a[1] + t * ab[1], a[2] + t * ab[2]};
    return sc_dist3(p, q);
}

/* Whether vertex v may carry the new border inside region (A, B): not on
 * the mesh border, and every face around it in the region. */
static bool region_interior(const straightener *S, int32_t v) {
    if (S->border[v]) return false;
    for (int32_t i = S->out_start[v]; i < S->out_start[v + 1]; i++)
        if (S->in_region[S->out_h[i] / 3] != S->stamp) return false;
    return true;
}

/* The border of patches a and b as a chain of vertices from one end to the
 * other in S->arc; false when it is not one open chain of two edges or more. */
static bool border_chain(straightener *S, const ivec *fa, int32_t b, bool *oom) {
    qmesh *m = S->m;
    S->arc.n = 0;
    int32_t first = -1, n = 0;
    /* a chain's half-edges run a -> b side; from each vertex at most one leaves along it */
    S->stamp++;
    for (int32_t i = 0; i < fa->n; i++)
        for (int k = 0; k < 3; k++) {
            int32_t h = 3 * fa->a[i] + k, o = m->opp[h];
            if (o < 0 || m->patch[o / 3] != b) continue;
            int32_t v = m->tri[h];
            if (S->seen[v] == S->stamp) return false;
            S->seen[v] = S->stamp, S->via[v] = h;
            n++;
        }
    if (n < 2) return false;
    /* the start: a chain vertex no chain half-edge arrives at (on_path marks arrivals) */
    for (int pass = 0; pass < 3; pass++)
        for (int32_t i = 0; i < fa->n; i++)
            for (int k = 0; k < 3; k++) {
                int32_t h = 3 * fa->a[i] + k, o = m->opp[h];
                if (o < 0 || m->patch[o / 3] != b) continue;
                if (pass == 0) S->on_path[m->tri[qm_next(h)]] = 1;
                else if (pass == 1 && !S->on_path[m->tri[h]]) first = m->tri[h];
                else if (pass == 2) S->on_path[m->tri[qm_next(h)]] = 0;
            }
    if (first < 0) return false;   /* a closed loop */
    int32_t v = first;
    for (int32_t steps = 0; steps <= n; steps++) {
        if (!iv_push(&S->arc, v)) return *oom = true, false;
        if (S->seen[v] != S->stamp) break;
        int32_t nxt = m->tri[qm_next(S->via[v])];
        S->seen[v] = -1;   /* walked */
        v = nxt;
    }
    return S->arc.n == n + 1;
}

/* Faces of the region reached from a's faces along the outer border without
 * crossing the path: they stay a; the rest become b. False (labels as they
 * were) when either part is not one disc or the path does not separate. */
static bool resplit(straightener *S, int32_t a, int32_t b, ivec *fa, ivec *fb, loop_walk *lw, bool *oom) {
    qmesh *m = S->m;
    for (int32_t i = 0; i < S->path.n; i++) S->on_path[S->path.a[i]] = 1;
    int32_t mark = S->stamp;
    S->queue.n = 0;
    for (int32_t i = 0; i < fa->n; i++) {
        int32_t f = fa->a[i];
        for (int k = 0; k < 3; k++) {
            int32_t o = m->opp[3 * f + k];
            if ((o < 0 || S->in_region[o / 3] != mark) && S->side[f] != mark) {
                S->side[f] = mark;
                if (!iv_push(&S->queue, f)) *oom = true;
            }
        }
    }
    for (int32_t q = 0; q < S->queue.n && !*oom; q++) {
        int32_t f = S->queue.a[q];
        for (int k = 0; k < 3; k++) {
            int32_t h = 3 * f + k, o = m->opp[h];
            if (o < 0 || S->in_region[o / 3] != mark || S->side[o / 3] == mark) continue;
            if (S->on_path[m->tri[h]] && S->on_path[m->tri[qm_next(h)]]) {
                /* an edge of the path (consecutive on it) is a wall */
                bool wall = false;
                for (int32_t i = 0; i + 1 < S->path.n && !wall; i++) {
                    int32_t u = S->path.a[i], w = S->path.a[i + 1];
                    wall = (u == m->tri[h] && w == m->tri[qm_next(h)]) || (w == m->tri[h] && u == m->tri[qm_next(h)]);
                }
                if (wall) continue;
            }
            S->side[o / 3] = mark;
            if (!iv_push(&S->queue, o / 3)) *oom = true;
        }
    }
    for (int32_t i = 0; i < S->path.n; i++) S->on_path[S->path.a[i]] = 0;
    if (*oom) return false;
    bool separates = true;   /* b's outer faces must not be reached */
    for (int32_t i = 0; i < fb->n && separates; i++)
        for (int k = 0; k < 3; k++) {
            int32_t o = m->opp[3 * fb->a[i] + k];
            if ((o < 0 || S->in_region[o / 3] != mark) && S->side[fb->a[i]] == mark) separates = false;
        }
    if (!separates) return false;
    S->faces.n = 0;
    for (int32_t i = 0; i < fa->n; i++)
        if (!iv_push(&S->faces, fa->a[i])) return *oom = true, false;
    for (int32_t i = 0; i < fb->n; i++)
        if (!iv_push(&S->faces, fb->a[i])) return *oom = true, false;
    int32_t na = fa->n, total = S->faces.n;
    for (int32_t i = 0; i < total; i++) m->patch[S->faces.a[i]] = S->side[S->faces.a[i]] == mark ? a : b;
    /* the new parts, a's then b's, after the old lists in S->faces */
    for (int32_t i = 0; i < total && !*oom; i++)
        if (m->patch[S->faces.a[i]] == a && !iv_push(&S->faces, S->faces.a[i])) *oom = true;
    int32_t new_a = S->faces.n - total;
    for (int32_t i = 0; i < total && !*oom; i++)
        if (m->patch[S->faces.a[i]] == b && !iv_push(&S->faces, S->faces.a[i])) *oom = true;
    int32_t new_b = S->faces.n - total - new_a, pa = a, pb = b;
    bool ok = !*oom && new_a > 0 && new_b > 0 &&
              loop_build(m, S->faces.a + total, new_a, in_patch, &pa, lw, oom) &&
              loop_build(m, S->faces.a + total + new_a, new_b, in_patch, &pb, lw, oom);
    if (ok) {
        fa->n = fb->n = 0;
        for (int32_t i = 0; i < new_a && !*oom; i++)
            if (!iv_push(fa, S->faces.a[total + i])) *oom = true;
        for (int32_t i = 0; i < new_b && !*oom; i++)
            if (!iv_push(fb, S->faces.a[total + new_a + i])) *oom = true;
        return !*oom;
    }
    for (int32_t i = 0; i < total; i++) m->patch[S->faces.a[i]] = i < na ? a : b;   /* as they were */
    return false;
}

/* The border of patches a and b re-drawn as the shortest path of mesh edges
 * between its ends through the inside of a and b, each edge's length scaled
 * by 1 + its distance from the old border over a quarter of the ends'
 * distance (Purnomo et al. 2004 §4.1: locally shorter, not far from where
 * it was). Kept when shorter by that measure and both patches stay discs. */
static int straighten_border(straightener *S, int32_t a, int32_t b, ivec *fa, ivec *fb, loop_walk *lw,
                             int32_t *straightened) {
    qmesh *m = S->m;
    bool oom = false;
    if (!border_chain(S, fa, b, &oom)) return oom ? SC_ENOMEM : SC_OK;
    S->stamp++;
    for (int32_t i = 0; i < fa->n; i++) S->in_region[fa->a[i]] = S->stamp;
    for (int32_t i = 0; i < fb->n; i++) S->in_region[fb->a[i]] = S->stamp;
    const int32_t *arc = S->arc.a, n = S->arc.n, c0 = arc[0], c1 = arc[n - 1];
    double old_len = 0;
    for (int32_t i = 0; i + 1 < n; i++) old_len += qm_len(m, arc[i], arc[i + 1]);
    double scale = 0.25 * qm_len(m, c0, c1);
    if (!(scale > 0)) return SC_OK;
    /* Dijkstra from c0 to c1 over region-interior vertices */
    S->nheap = 0;
    S->seen[c0] = S->stamp, S->dist[c0] = 0, S->via[c0] = -1;
    if (!dheap_push(&S->heap, &S->nheap, &S->cap_heap, (dnode){0, c0})) return SC_ENOMEM;
    bool reached = false;
    while (S->nheap > 0) {
        dnode x = dheap_pop(S->heap, &S->nheap);
        if (x.d > S->dist[x.v]) continue;
        if (x.v == c1) {
            reached = true;
            break;
        }
        if (x.d >= old_len) break;   /* no shorter path left */
        for (int32_t i = S->out_start[x.v]; i < S->out_start[x.v + 1]; i++) {
            int32_t h = S->out_h[i], o = m->opp[h], w = m->tri[qm_next(h)];
            if (o < 0 || S->in_region[h / 3] != S->stamp || S->in_region[o / 3] != S->stamp) continue;
            if (w != c1 && !region_interior(S, w)) continue;
            double mid[3], near = INFINITY;
            for (int k = 0; k < 3; k++) mid[k] = 0.5 * (m->pos[3 * (size_t)x.v + k] + m->pos[3 * (size_t)w + k]);
            for (int32_t j = 0; j + 1 < n; j++)
                near = fmin(near, point_segment3(mid, m->pos + 3 * (size_t)arc[j], m->pos + 3 * (size_t)arc[j + 1]));
            double d = x.d + qm_len(m, x.v, w) * (1 + near / scale);
            if (S->seen[w] == S->stamp && S->dist[w] <= d) continue;
            S->seen[w] = S->stamp, S->dist[w] = d, S->via[w] = x.v;
            if (!dheap_push(&S->heap, &S->nheap, &S->cap_heap, (dnode){d, w})) return SC_ENOMEM;
        }
    }
    if (!reached || !(S->dist[c1] < old_len * (1 - 1e-9))) return SC_OK;
    S->path.n = 0;
    for (int32_t v = c1; v >= 0; v = S->via[v])
        if (!iv_push(&S->path, v)) return SC_ENOMEM;
    if (resplit(S, a, b, fa, fb, lw, &oom)) (*straightened)++;
    return oom ? SC_ENOMEM : SC_OK;
}

/* Every pair of neighbouring patches' border straightened once, pairs in
 * order of their patch numbers. */
static int straighten_patches(qmesh *m, int32_t np, int32_t nv_in, int32_t *straightened) {
    straightener S;
    loop_walk lw = {0};
    ivec *pf = calloc((size_t)np + 1, sizeof *pf);
    int rc = straightener_init(&S, m);
    lw.mark = calloc((size_t)nv_in + 1, sizeof(int32_t)), lw.slot = calloc((size_t)nv_in + 1, sizeof(int32_t));
    if (rc == SC_OK && (!pf || !lw.mark || !lw.slot)) rc = SC_ENOMEM;
    for (int32_t f = 0; f < m->nf && rc == SC_OK; f++)
        if (!iv_push(&pf[m->patch[f]], f)) rc = SC_ENOMEM;
    for (int32_t a = 0; a < np && rc == SC_OK; a++) {
        /* a's neighbours b > a, as they are now */
        ivec nb = {0};
        for (int32_t i = 0; i < pf[a].n && rc == SC_OK; i++)
            for (int k = 0; k < 3; k++) {
                int32_t o = m->opp[3 * pf[a].a[i] + k];
                if (o < 0 || m->patch[o / 3] <= a) continue;
                bool have = false;
                for (int32_t j = 0; j < nb.n && !have; j++) have = nb.a[j] == m->patch[o / 3];
                if (!have && !iv_push(&nb, m->patch[o / 3])) rc = SC_ENOMEM;
            }
        for (int32_t j = 0; j < nb.n && rc == SC_OK; j++)
            rc = straighten_border(&S, a, nb.a[j], &pf[a], &pf[nb.a[j]], &lw, straightened);
        free(nb.a);
    }
    for (int32_t p = 0; pf && p < np; p++) free(pf[p].a);
    free(pf), free(lw.verts.a), free(lw.hs.a), free(lw.mark), free(lw.slot);
    straightener_free(&S);
    return rc;
}

int sc_quad_charts(const sc_mesh *in, const sc_quad_options *o, int32_t target_quads, qcharts *out,
                   sc_error *err) {
    memset(out, 0, sizeof *out);
    builder b = {0};
    b.m = &out->m;
    int rc = qm_from_mesh(b.m, in);
    if (rc == SC_OK) rc = make_patches(b.m, in->nv, o->target_patches, target_quads, &b.np);
    if (rc == SC_OK && o->straight_borders) rc = straighten_patches(b.m, b.np, in->nv, &out->straightened_borders);
    if (rc == SC_OK) {
        b.pf = calloc((size_t)b.np, sizeof *b.pf);
        if (!b.pf || !b_fit(&b)) rc = SC_ENOMEM;
        for (int32_t f = 0; f < b.m->nf && rc == SC_OK; f++)
            if (!iv_push(&b.pf[b.m->patch[f]], f)) rc = SC_ENOMEM;
    }
    if (rc == SC_OK) rc = add_corners(&b);
    if (rc == SC_OK) rc = add_medians(&b);
    for (int32_t p = 0; p < b.np && rc == SC_OK; p++) rc = quadrangulate(&b, p, err);
    out->npatches = b.np;
    out->nquads = b.qcorner.n / 4;
    int32_t st_cap = 0;
    double sum_l2 = 0, sum_area = 0, within_l2 = 0, max_g = 0;
    for (int32_t q = 0; q < out->nquads && rc == SC_OK; q++)
        rc = parameterize_quad(&b, q, &out->st, &st_cap, &sum_l2, &sum_area, &within_l2, &max_g, &out->flipped, err);
    if (rc == SC_OK) {
        out->side_id = malloc((size_t)out->nquads * 4 * sizeof *out->side_id);
        out->side_rev = malloc((size_t)out->nquads * 4);
        out->corner_v = malloc((size_t)out->nquads * 4 * sizeof *out->corner_v);
        rc = !out->side_id || !out->side_rev || !out->corner_v ? SC_ENOMEM : number_sides(&b, out);
    }
    if (rc == SC_OK) {
        /* stretch of the atlas: every chart a unit square, so scale by quads / surface area */
        double norm = sum_area > 0 ? sqrt(out->nquads / sum_area) : 0;
        out->stretch_l2 = sum_area > 0 ? sqrt(sum_l2 / sum_area) * norm : 0;
        out->stretch_linf = sqrt(max_g) * norm;
        out->stretch_l2_within = sum_area > 0 ? sqrt(within_l2 / sum_area) : 0;
        memcpy(out->sides_hist, b.hist, sizeof b.hist);
        out->straight_cuts = b.straight_cuts;
    }
    builder_free(&b);
    if (rc == SC_ENOMEM && err && !err->message[0]) sc_fail(err, SC_ENOMEM, "quad_chartify: out of memory");
    else if (rc == SC_EINPUT && err && !err->message[0]) sc_fail(err, SC_EINPUT, "quad_chartify: a patch is not a disc");
    if (rc) sc_quad_charts_free(out);
    return rc;
}

void sc_quad_charts_free(qcharts *c) {
    qm_free(&c->m);
    free(c->st), free(c->side_id), free(c->side_rev), free(c->corner_v);
    memset(c, 0, sizeof *c);
}
