/* sc_topology.h - the edge table of a textured mesh: every surface edge with
 * its half-edges and its kind, and the surface's Euler characteristic,
 * connected components and boundary loops. Seams and uv silhouettes
 * (sc_seam), seam straightening and the renderer's topology check all read
 * this one table, so they agree on what each edge is.
 *
 * Definitions.
 *   half-edge     h = 3 f + k runs from corner k of face f to corner
 *                 (k + 1) % 3 (sc_topology_next); it uses the surface vertex
 *                 FV[h] and the uv index FU[h] at its start.
 *   surface edge  an unordered pair of surface vertices (FV) that a half-edge
 *                 joins; its half-edges are all the half-edges joining them.
 * Every surface edge has one kind:
 *   boundary      one half-edge.
 *   non-manifold  three or more half-edges.
 *   seam          two half-edges that use different uv indices (FU) at
 *                 either end (docs/design.md: "a surface edge whose two
 *                 half-edges use different U indices").
 *   foldover      two half-edges using the same uv at both ends, whose faces'
 *                 third corners lie strictly on the same side of that uv
 *                 edge: the parameter mesh folds over itself there.
 *   interior      any other edge of two half-edges.
 * The uv silhouette (the boundary of the parameter mesh) is both sides of
 * every seam, the boundary, the foldover and the non-manifold edges.
 *
 * Option `uv_by_coordinates`: two uv indices whose coordinates are equal
 * (bit for bit) count as the same uv, so an edge whose sides differ only in
 * their indices is no seam but an interior edge (or a foldover). Texture
 * sampling cannot tell such sides apart, so the seam operator (sc_seam_find)
 * takes this view: there is no discontinuity to erase and no silhouette to
 * pad. Whoever moves uv indices (seam straightening) keeps the default, as
 * two indices moved apart open a seam wherever they met.
 *
 * Surface counts, over the faces of the table (vertices: those they use):
 *   euler           V - E + F, E counting every surface edge once;
 *   components      connected components of the faces, a shared vertex
 *                   joining two faces;
 *   boundary_loops  connected components of the graph of the boundary edges
 *                   (two holes meeting at a vertex are one loop).
 */
#ifndef SC_TOPOLOGY_H
#define SC_TOPOLOGY_H

#include "sc_value.h"

/* Bump whenever results of this library can change for the same inputs:
 * every node listing sc_kernel_topology (or a kernel built on it) is re-keyed. */
#define SC_TOPOLOGY_VERSION 1
extern const sc_kernel sc_kernel_topology;

typedef enum sc_edge_kind {
    SC_EDGE_INTERIOR = 0,
    SC_EDGE_SEAM = 1,
    SC_EDGE_BOUNDARY = 2,
    SC_EDGE_FOLDOVER = 3,
    SC_EDGE_NONMANIFOLD = 4,
} sc_edge_kind;

typedef struct sc_topology_edge {
    int32_t v0, v1;          /* surface vertices, v0 < v1 */
    int32_t first, count;    /* its half-edges: half[first .. first + count) */
    sc_edge_kind kind;
} sc_topology_edge;

typedef struct sc_topology_options {
    int32_t material;        /* only the faces of this material; -1: all faces */
    bool uv_by_coordinates;  /* equal uv coordinates are the same uv (see above) */
} sc_topology_options;

typedef struct sc_topology {
    int32_t material;
    int32_t nedges;
    sc_topology_edge *edges; /* ordered by (v0, v1) */
    int32_t nhalf;
    int32_t *half;           /* the half-edges, edge by edge, ascending within one */
    int32_t *edge_of;        /* 3 nf: the edge of each half-edge; -1 outside the material */
    int32_t nseams, nboundary, nfoldover, nnonmanifold;   /* edges of each kind */
    int64_t euler;
    int32_t components, boundary_loops;
} sc_topology;

/* Build the table of m's faces (opt NULL: all faces, uvs by index). m must
 * pass sc_mesh_check. */
int sc_topology_build(const sc_mesh *m, const sc_topology_options *opt, sc_topology *out, sc_error *err);
void sc_topology_free(sc_topology *t);

/* The half-edge after h in its face. */
static inline int32_t sc_topology_next(int32_t h) { return 3 * (h / 3) + (h % 3 + 1) % 3; }

/* The uv index half-edge h uses at surface vertex v, one of its two ends. */
static inline int32_t sc_topology_uv_at(const sc_mesh *m, int32_t h, int32_t v) {
    return m->FV[h] == v ? m->FU[h] : m->FU[sc_topology_next(h)];
}

/* Half-edge k of edge e (-1 when it has fewer). */
static inline int32_t sc_topology_half(const sc_topology *t, const sc_topology_edge *e, int32_t k) {
    return k < e->count ? t->half[e->first + k] : -1;
}

#endif
