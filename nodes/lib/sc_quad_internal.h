/* sc_quad_internal.h - what the two halves of the quad-atlas kernel share:
 * the refinable triangle mesh the charts are cut from (sc_quad_mesh.c) and
 * the charts it hands to the sampler (sc_quad_texture.c). Private to
 * nodes/lib/sc_quad*.c.
 */
#ifndef SC_QUAD_INTERNAL_H
#define SC_QUAD_INTERNAL_H

#include "sc_quad.h"

/* A triangle mesh that grows by splitting edges and faces. Every face keeps
 * the input face it lies in (old) and the barycentric coordinates of its
 * corners there (bary), so attributes are always read from the input face. */
typedef struct qmesh {
    int32_t nv, cap_v, nf, cap_f;
    double *pos;      /* 3 nv */
    int32_t *tri;     /* 3 nf */
    int32_t *opp;     /* 3 nf: the opposite half-edge, -1 on the border */
    int32_t *old;     /* nf */
    double *bary;     /* 9 nf */
    int32_t *patch;   /* nf */
    int32_t *quad;    /* nf */
    double arc_floor; /* added to every edge's length along a border */
} qmesh;

static inline int32_t qm_next(int32_t h) { return h - h % 3 + (h % 3 + 1) % 3; }
static inline int32_t qm_prev(int32_t h) { return h - h % 3 + (h % 3 + 2) % 3; }

/* The charts: quad q's faces carry chart coordinates st in [0,1]^2 per
 * corner (6 per face). Chart side k runs from corner k to corner k + 1 of
 * (0,0) (1,0) (1,1) (0,1); side_id[4q + k] is the side's global index (-1
 * never: a side on the mesh border has an index no other chart uses) and
 * side_rev[4q + k] says whether this chart runs it against its global
 * direction. corner_v[4q + k] is the mesh vertex at corner k. */
typedef struct qcharts {
    qmesh m;
    int32_t nquads, nsides, npatches;
    double *st;           /* 6 nf */
    int32_t *side_id;     /* 4 nquads */
    uint8_t *side_rev;    /* 4 nquads */
    int32_t *corner_v;    /* 4 nquads */
    int32_t sides_hist[9];    /* patches with 3..10+ sides at [n - 3], last bucket 10+ */
    double stretch_l2, stretch_linf;   /* of the atlas: every chart the same size */
    double stretch_l2_within;          /* each chart scaled to its own surface area */
    int32_t flipped;
    int32_t straight_cuts;    /* patches cut by straight domain segments, not along edges */
    int32_t straightened_borders;   /* patch borders re-drawn shorter (§4.1) */
} qcharts;

/* Patches, quads and chart maps of input mesh `in` (positions and faces). */
int sc_quad_charts(const sc_mesh *in, const sc_quad_options *o, int32_t target_quads, qcharts *out,
                   sc_error *err);
void sc_quad_charts_free(qcharts *c);

#endif
