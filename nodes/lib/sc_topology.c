/* sc_topology.c - the edge table (sc_topology.h).
 *
 * The half-edges of the table's faces are sorted by (min vertex, max vertex,
 * half-edge), so that each surface edge is one run of them and the table
 * comes out the same for any input order of equal keys. Each edge's kind
 * follows from its run: its length, then for two half-edges the uv indices
 * both use at the edge's two ends and, where those agree, the side of the uv
 * edge on which each face's third corner lies. Components and boundary loops
 * are the roots of two union-find forests over the surface vertices, one
 * joined along every edge, one along the boundary edges.
 */
#include "sc_topology.h"

#include <stdlib.h>
#include <string.h>

#include "sc_geometry.h"

const sc_kernel sc_kernel_topology = {"topology", SC_TOPOLOGY_VERSION, NULL};

typedef struct half_key {
    uint64_t key;   /* (min vertex << 32) | max vertex */
    int32_t half;
} half_key;

static int compare_keys(const void *pa, const void *pb) {
    const half_key *a = pa, *b = pb;
    if (a->key != b->key) return a->key < b->key ? -1 : 1;
    return (a->half > b->half) - (a->half < b->half);
}

static bool same_uv(const sc_mesh *m, bool by_coordinates, int32_t a, int32_t b) {
    return a == b || (by_coordinates && m->U[2 * a] == m->U[2 * b] && m->U[2 * a + 1] == m->U[2 * b + 1]);
}

/* The kind of an edge of two half-edges h0, h1. */
static sc_edge_kind pair_kind(const sc_mesh *m, bool by_coordinates, int32_t h0, int32_t h1) {
    int32_t p = m->FV[h0], q = m->FV[sc_topology_next(h0)];
    int32_t a0 = sc_topology_uv_at(m, h0, p), a1 = sc_topology_uv_at(m, h0, q);
    if (!same_uv(m, by_coordinates, a0, sc_topology_uv_at(m, h1, p)) ||
        !same_uv(m, by_coordinates, a1, sc_topology_uv_at(m, h1, q)))
        return SC_EDGE_SEAM;
    const double *u0 = &m->U[2 * a0], *u1 = &m->U[2 * a1];
    double o0 = sc_orient2(u0, u1, &m->U[2 * m->FU[sc_topology_next(sc_topology_next(h0))]]);
    double o1 = sc_orient2(u0, u1, &m->U[2 * m->FU[sc_topology_next(sc_topology_next(h1))]]);
    return o0 * o1 > 0 ? SC_EDGE_FOLDOVER : SC_EDGE_INTERIOR;
}

/* Euler characteristic, components and boundary loops of the table. */
static int surface_counts(const sc_mesh *m, sc_topology *t) {
    int32_t *all = sc_alloc_array((size_t)m->nv + 1, sizeof *all);
    int32_t *bnd = sc_alloc_array((size_t)m->nv + 1, sizeof *bnd);
    uint8_t *use = sc_calloc_array((size_t)m->nv + 1, 1);   /* 1: a face uses it, 2: a boundary edge too */
    if (!all || !bnd || !use) {
        free(all), free(bnd), free(use);
        return SC_ENOMEM;
    }
    for (int32_t v = 0; v < m->nv; v++) all[v] = bnd[v] = v;
    int64_t nfaces = t->nhalf / 3, nused = 0;
    for (int32_t e = 0; e < t->nedges; e++) {
        const sc_topology_edge *d = &t->edges[e];
        all[sc_set_root(all, d->v0)] = sc_set_root(all, d->v1);
        if (use[d->v0] == 0) use[d->v0] = 1;
        if (use[d->v1] == 0) use[d->v1] = 1;
        if (d->kind == SC_EDGE_BOUNDARY) {
            bnd[sc_set_root(bnd, d->v0)] = sc_set_root(bnd, d->v1);
            use[d->v0] = use[d->v1] = 2;
        }
    }
    for (int32_t v = 0; v < m->nv; v++) {
        if (!use[v]) continue;
        nused++;
        if (sc_set_root(all, v) == v) t->components++;
        if (use[v] == 2 && sc_set_root(bnd, v) == v) t->boundary_loops++;
    }
    t->euler = nused - t->nedges + nfaces;
    free(all), free(bnd), free(use);
    return SC_OK;
}

int sc_topology_build(const sc_mesh *m, const sc_topology_options *opt, sc_topology *t, sc_error *err) {
    memset(t, 0, sizeof *t);
    const int32_t material = opt ? opt->material : -1;
    const bool by_coordinates = opt && opt->uv_by_coordinates;
    t->material = material;
    size_t nh = 0;
    for (int32_t f = 0; f < m->nf; f++)
        if (material < 0 || m->FM[f] == material) nh += 3;
    half_key *keys = sc_alloc_array(nh + 1, sizeof *keys);
    t->half = sc_alloc_array(nh + 1, sizeof *t->half);
    t->edges = sc_alloc_array(nh + 1, sizeof *t->edges);
    t->edge_of = sc_alloc_array((size_t)m->nf * 3 + 1, sizeof *t->edge_of);
    if (!keys || !t->half || !t->edges || !t->edge_of) {
        free(keys);
        sc_topology_free(t);
        return sc_fail(err, SC_ENOMEM, "out of memory building the edge table");
    }
    size_t k = 0;
    for (int32_t h = 0; h < 3 * m->nf; h++) {
        t->edge_of[h] = -1;
        if (material >= 0 && m->FM[h / 3] != material) continue;
        uint32_t a = (uint32_t)m->FV[h], b = (uint32_t)m->FV[sc_topology_next(h)];
        keys[k++] = (half_key){(uint64_t)(a < b ? a : b) << 32 | (a < b ? b : a), h};
    }
    qsort(keys, nh, sizeof *keys, compare_keys);
    t->nhalf = (int32_t)nh;
    for (size_t i = 0, j; i < nh; i = j) {
        for (j = i + 1; j < nh && keys[j].key == keys[i].key; j++) {}
        sc_topology_edge *e = &t->edges[t->nedges];
        e->v0 = (int32_t)(keys[i].key >> 32), e->v1 = (int32_t)(keys[i].key & 0xffffffffu);
        e->first = (int32_t)i, e->count = (int32_t)(j - i);
        for (size_t q = i; q < j; q++) {
            t->half[q] = keys[q].half;
            t->edge_of[keys[q].half] = t->nedges;
        }
        if (e->count == 1) e->kind = SC_EDGE_BOUNDARY, t->nboundary++;
        else if (e->count > 2) e->kind = SC_EDGE_NONMANIFOLD, t->nnonmanifold++;
        else {
            e->kind = pair_kind(m, by_coordinates, keys[i].half, keys[i + 1].half);
            t->nseams += e->kind == SC_EDGE_SEAM;
            t->nfoldover += e->kind == SC_EDGE_FOLDOVER;
        }
        t->nedges++;
    }
    free(keys);
    if (surface_counts(m, t) != SC_OK) {
        sc_topology_free(t);
        return sc_fail(err, SC_ENOMEM, "out of memory building the edge table");
    }
    return SC_OK;
}

void sc_topology_free(sc_topology *t) {
    if (!t) return;
    free(t->edges);
    free(t->half);
    free(t->edge_of);
    memset(t, 0, sizeof *t);
}
