/* decimate.c - the node `decimate`: seam-aware edge-collapse decimation
 * (Liu, Ferguson, Jacobson, Gingold 2017, §5) producing a chain of levels of
 * detail that all keep the input's parameterisation, so one seam-free texture
 * set serves every level.
 *
 * Design note.
 *
 * Z-vertices. The surface mesh (V, FV) and the parameter mesh (U, FU) have
 * different connectivity. Every face corner names a Z-vertex: a (surface
 * vertex, uv index, material) triple, numbered through a hash table in order
 * of first appearance (§5.2). The uv mesh is then the faces over Z, the
 * surface mesh the faces over V; a seam edge is a surface edge whose two
 * faces use different Z at an endpoint. Splitting by material makes a
 * material border behave like a seam (it must keep its shape in uv on both
 * sides). Each Z carries its uv, its 5-D quadric over (x, y, z, s u, s v)
 * (Garland & Heckbert 1998: each face adds the squared distance to its plane
 * in R^5, weighted by its 3D area, to its three corners) and, for the
 * area-distortion weights (Coll & Paradinas 2010 §4), its 3D plane quadric
 * and summed normal. s (uv_scale) = uv_weight * sqrt(surface area / uv area)
 * makes one unit of uv worth one unit of surface length on average, so
 * neither part of the metric dominates by an accident of units. Surface
 * border edges add a plane through the edge, perpendicular to its face
 * (Garland & Heckbert 1997), so open borders keep their place in 3D.
 *
 * Collapses. An edge (a, b) is classified by its faces:
 *   interior  both faces use the same uv edge (za, zb). If both are uv
 *             silhouette vertices the parameter mesh's link condition fails
 *             (blocked); with one silhouette endpoint the new vertex keeps its
 *             uv; else the uv is free.
 *   seam      two uv half-edges e1 = (za1, zb1), e2 = (za2, zb2). At each end
 *             we look for the neighbouring seam edge d continuing both halves
 *             and test unifiability: both (d_i, e_i) collinear in uv and equal
 *             length ratios |e1|/|d1| = |e2|/|d2|. With both ends unifiable
 *             the new uv points w1, w2 slide on the lines d(0)..f(1) with the
 *             same parameter t in [0, 1] (§5.1's equality and inequality
 *             constraints); with one, the collapse goes onto the other end
 *             (w_i = that end's uv); with none it is not collapsible.
 *   boundary  a surface border edge: a non-seam silhouette, collinearity
 *             only.
 * The placement minimises the quadric under these constraints exactly: a
 * 5-D problem, or for a seam the 10-D block metric of the two half-vertex
 * quadrics with x1 = x2, y1 = y2, z1 = z2. The equalities (a shared point,
 * a kept uv, a uv on its line) describe an affine subspace, so the problem
 * is solved exactly over that subspace's coordinates by Cholesky; the one
 * inequality, t in [0, 1], puts t at the nearer end when the free minimiser
 * leaves it, which is exact for a convex objective in one bounded variable. A small rho |x - mid|^2
 * (rho = 1e-9 trace/n) makes every problem strictly convex and picks, among
 * the minimisers of a singular quadric (flat, linearly parameterised
 * regions), the one nearest the edge's midpoint. A slid uv is snapped exactly
 * onto its line and a kept uv copied, so silhouettes stay exact to rounding.
 * seam_mode "fixed" never collapses a silhouette edge (the Maya baseline);
 * "free" drops every uv constraint but keeps the link conditions and flip
 * tests (the MeshLab baseline).
 *
 *
 * Tolerances. Collinearity and equal ratios are tested with the relative
 * tolerances (1e-9) plus what the storage precision of the input's uv
 * explains: OBJ files store uv as decimal text (often 6 significant digits),
 * so seams straightened before export are straight only to half a unit in
 * the last digit. The storage (significant decimal digits, float32 or
 * double) is detected once; each Z keeps the step of its coordinates
 * (zstep; a merged or slid point the coarsest step it came from), and a
 * point within 2 steps of the chord of its neighbours, or lengths within the
 * matching slack, are taken as straight or equal. On exact data (the
 * procedural asset, double precision) this adds ~1e-16: silhouettes stay
 * exact. On decimal uv this slack is what a seam collapse costs: the
 * level's seam chords may sit off the input's seam polyline by up to the
 * slack, across the seam, where the seam-free texture agrees only on the
 * polyline; the new points themselves are exact (one parameter t on both
 * sides). No bound is put on the drift this accumulates over collapses: a
 * bound of half a storage step stops decimation far short of its targets,
 * and exact seams need exact uv (docs/notes/decimate.md).
 *
 * Validity, tested when an edge comes off the queue: the link condition on
 * the surface (with one virtual vertex joined to all borders, §5.2) and on
 * every uv half-edge; opposite vertices keep a valid valence; no surviving
 * face flips or degenerates in uv (orientation compared with the face's
 * current one) or in 3D, where a face's normal may also turn by at most
 * normal_turn degrees (30) per collapse: at extreme ratios this keeps
 * collapses from folding thin features; it is reported as its own blocking
 * reason. With refuse_crossings no face around the collapse may pass through
 * another face it shares no vertex with, unless it passed through it before
 * (the input's own crossings stay): two parts close together, decimated
 * apart, push through each other and show back faces (a bottle's cap ring
 * through its body). Faces live in a loose grid of levels, cells about
 * twice the mean edge long on the finest and four times longer on each
 * next, each face in the one cell holding its box's centre on the finest
 * level whose cells are as long as its box's half-side, taken out the
 * moment it moves or goes, and the grid built again whenever the faces
 * fall to a quarter. With
 * contact_distance, an open part's border vertex within that distance of
 * another connected part is in contact: no collapse may leave it (or the
 * vertex it merges into), or a point of a border edge between two
 * contacts, farther from the other parts or higher over their nearest face
 * than in the input, but for contact_slack; checked on the grid whenever
 * the collapse moves it or changes another part's faces within its reach
 * (blocked as "contact"; the state's note). Decimated apart, the two would
 * open a gap that shows the open part's inside; held so, both still
 * decimate (a seed in a cut fruit, a cap on a bottle's neck). An edge that
 * fails is dropped and its endpoints are marked; any later collapse next
 * to a marked vertex queues its edges again.
 *
 * Queue. A 4-ary heap of (cost bits, a << 32 | b, version a, version b):
 * ties broken by vertex ids, so the order never depends on memory addresses
 * or thread count. Collapsing bumps the version of the kept vertex (and, after
 * a silhouette collapse, of its silhouette neighbours, whose seam constraints
 * refer to it) and re-queues their edges; stale entries are skipped when
 * popped, and dropped in bulk whenever the heap outgrows the live edges.
 * The first queue is appended unordered and heapified once. After an
 * interior collapse only keep's edges (and those of marked neighbours) are
 * evaluated again; the spokes are classified only after a silhouette one.
 * Each evaluation is a plan and a 5-D solve; Hausdorff sampling is timed
 * apart (hausdorff_seconds), with the input's BVH built once for all levels
 * (or taken over from error tracking). A popped edge whose cost has risen
 * (see error tracking) goes only when no queued cost is below it.
 *
 * Error tracking. The quadric measures distances to planes. A vertex at the
 * tip of a thin feature (fins, tail lobes) or on a rounded rim slides along
 * the feature's own planes for next to nothing, and a face that bridges a
 * gap can have all its corners on planes it is far from; at very low face
 * counts quadric-greedy collapses therefore cut features off, overshoot
 * rims and bridge gaps, and which of them it picks changes with any small
 * change of the input or the weights. Changes to the quadric itself do not
 * cure this (docs/notes/decimate.md lists those measured).
 *   So near each target the cost of a collapse adds
 *       error_weight x (2 x input area / target) x E,
 * E the squared distance between the fan the collapse leaves and the input,
 * tracked both ways. Every surface vertex stands for the input vertices
 * merged into it (a list per vertex, joined on collapse), and E is the
 * larger of (a) their distance to the new fan and (b) the distance to the
 * input surface (its BVH) of points of the new fan: the moved vertex and,
 * on each face, the middle of its spoke, its centroid and the point 2/3 of
 * the way from the opposite edge to the moved vertex (the spoke middles
 * catch most bridges; centroids catch faces that span a hollow, which
 * spoke middles alone miss). 2 x area / target is the surface a vertex of
 * the target level stands for, so E counts as if that much surface were E
 * off: an L-infinity term in the quadric's units that does not shrink with
 * the feature's area. The quadric still places the vertex (the paper's
 * constrained optimum) and orders collapses of equal tracked error; uv,
 * seams and every validity test are untouched. The summed quadric cost
 * rises: the maximum is bought with some of the quadric's L2.
 *   Tracking runs from TRACKING_SPAN x target faces, and only below
 * 1 / TRACKING_START of the input's faces: the worst error of a level is
 * made in its last collapses, and a tracked collapse costs several times an
 * untracked one.
 *   E is computed lazily: queued costs leave it out, so they are lower
 * bounds, and the edge at the front gets E added when popped; it goes only
 * when its full cost is at most the next queued cost, else it is queued
 * again with it. (A full cost stays queued when a neighbouring collapse
 * later changes the fan it measured; it is measured again when popped.) E
 * is a maximum, so a point is let go at the first face (or BVH face) closer
 * than the maximum so far, the cheap plane test runs over the fan before
 * the general one, and measuring stops once the cost passes twice the next
 * queued one: the edge is then queued with that lower bound. The moved
 * vertex is measured first, before the fan is even built: where a collapse
 * is far off, it alone says so. An edge that comes back with its full cost
 * is tested for validity before it is measured again (near a stall most
 * edges at the front cannot collapse).
 *
 * A bound (max_error > 0). Tracking then runs on every collapse from the
 * first, and a collapse whose tracked distance E exceeds max_error x the
 * diagonal is refused (blocked_max_error in a stall's census; measuring
 * stops at the bound). Where seams and link conditions leave little else
 * to collapse, an unbounded run flattens what is left, and a bound stops
 * the level a little short of its target instead. Measuring every collapse
 * costs many times the time, so the bound is an option
 * (graphs/lod_chain.lua sets 0.02), not the default; ordering every
 * collapse by its full cost then helps well above the tracking range too.
 *   The tracked error samples each fan at a few points, so a level can pass
 * the bound between them (Duck to 1% within 1% measured 1.1%). With
 * hausdorff_samples > 0 each level is measured whole (sc_hausdorff), and
 * when one passes max_error the levels are made again from the input with
 * every collapse bounded by max_error x 0.95 / the overshoot, up to
 * MAX_TIGHTENINGS times (metrics bound_tightenings, bound_scale); a level
 * still over it after that says so in a warning. Where a pass leaves the
 * overshoot where it was (under a thousandth less), the farthest point is
 * one the tracked error does not sample, and the bound tightens by a fifth
 * at least (MuruCat's level 1: 2.0012% after three passes of 0.95 / the
 * overshoot, within 2% after one more of a fifth).
 *
 * Maps that restore the detail (map_size > 0). A level drawn with a
 * displacement map of map_size^2 (bake_displacement) gets back only what
 * the map can hold: where the uv is squeezed, one texel spans much of the
 * surface, and whatever a collapse moves there is lost for good. So each
 * input face gets an importance
 *     w = max(1, (h / (map_texel x diagonal))^2),
 * h = sqrt(3D area / uv area) / map_size the surface length of one texel
 * on it: it multiplies the face's quadric (area-weighted already), and a
 * surface vertex carries the largest w of the input faces it stands for,
 * which multiplies its collapses' tracked error. It orders collapses; it is
 * no bound, and not monotonic (on test_decimate's square whose right half is
 * squeezed along u, that half comes closer at some squeezes and not at
 * others). A level
 * drawn without its map pays for the detail kept elsewhere, so map_size is
 * off by default.
 *   Three things a map cannot restore are refused outright with map_size.
 * (1) uv slivers: a surviving face may not stretch (uv_stretch: the largest
 * singular value of uv -> surface, over map_size the longest surface span
 * of one texel) beyond STRETCH_SLACK (2) x the larger of map_texel's unit
 * and the largest stretch of the input faces its corners stand for (tracked
 * per vertex, like importance), unless it shrinks: a face with three nearly
 * collinear uv corners has texels spanning much of the surface, and its
 * map, bilinear across it, cannot follow the surface next to it.
 * (2) seams: erase_seams makes the two sides of a seam agree on a function
 * both texel grids can hold, which along a seam crossing the grids at
 * different places is little more than linear: the drawn seam is the
 * level's own seam, bent a little. So the input's vertices on uv
 * silhouettes, at each of their uvs, must stay within seam_error (5e-4 of
 * the diagonal) of the level at the same uv (seam_kept: measured on the
 * faces a collapse changes, for keep's, gone's and their silhouette
 * neighbours' input vertices, a point up to 1% of a face outside them
 * measured at its nearest: a border moved within the uv's storage slack).
 * (3) creases inside a chart: the displacement is the input minus the
 * level, so every crease of the level is one the map must hold, and a
 * bilinear cell rounds it off by a fraction of its texel length times the
 * angle. Every edge a collapse changes whose two faces share its uv keeps
 * dihedral angle (radians) x texel length (uv_stretch / map_size) within
 * map_crease (4e-3 of the diagonal; creases_ok).
 *   The price is faces: levels stop earlier, and the census says why
 * (blocked_texel_stretch, blocked_seam_error and blocked_texel_crease).
 *
 * Levels. One continuous decimation; a snapshot is taken each time the face
 * count reaches the next target, so level k is the previous level decimated
 * further with the quadrics it accumulated. When the queue runs dry before a
 * target, every remaining edge is classified once and the counts are
 * reported as lod<k>.blocked_<reason>; the level is still output (faces
 * reached next to target_faces), never an error. A stall is real: the queue
 * ran dry after a full re-evaluation of every live edge, and the census
 * then finds every live edge blocked.
 *
 * Output: each level is an ATLAS without textures (share_textures adds them).
 * Faces keep the input order (survivors only) and their material; surface
 * vertices and uv entries are renumbered in order of their ids. Normals
 * are the input's, per corner (normal_corner): its own, or without them the
 * smooth ones save writes for it (sc_tangent_corner_normals). A level shades
 * as the input does, and a tangent-space normal map, made for the frames
 * of the input's normals, authored ones included, turns with them: frames
 * built from a level's own normals would show it turned across seams
 * (docs/notes/decimate.md).
 *
 * Measurements and history behind these choices: docs/notes/decimate.md.
 */
#include <float.h>
#include <math.h>
#include <pthread.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "sc_geometry.h"
#include "sc_hausdorff.h"
#include "sc_nodes.h"
#include "sc_quadric.h"
#include "sc_tangent.h"

#define QDIM 5
#define QSIZE SC_QUADRIC_SIZE(QDIM)
#define BOUNDARY_PLANE_WEIGHT 1.0
/* Edges at a vertex of more faces than this never collapse: each look at
 * such an edge walks its fan, and a vertex that every face touches (a fan-
 * triangulated polygon) would make decimation quadratic. Real meshes keep
 * well under it (docs/notes/decimate.md). */
#define MAX_FAN 256
#define TRACKING_SPAN 3      /* the tracked error counts from TRACKING_SPAN x target faces ... */
#define TRACKING_START 8     /* ... but only below 1 / TRACKING_START of the input's faces */

enum { MODE_AWARE = 0, MODE_FIXED = 1, MODE_FREE = 2 };
enum { WEIGHTS_QEM = 0, WEIGHTS_AREA_DISTORTION = 1 };

/* Why an edge cannot collapse (metric names after "blocked_"). */
typedef enum block_reason {
    BLOCK_NONE = 0,
    BLOCK_NONMANIFOLD,          /* an endpoint with a non-manifold fan */
    BLOCK_SILHOUETTE_ENDPOINTS, /* interior uv edge joining two silhouette vertices */
    BLOCK_SEAM_CORNER,          /* no neighbouring edge continues the seam on either side */
    BLOCK_SEAM_NOT_COLLINEAR,
    BLOCK_SEAM_LENGTH_RATIO,
    BLOCK_BOUNDARY_CORNER,      /* surface border: no collinear neighbour */
    BLOCK_BOUNDARY_NOT_COLLINEAR,
    BLOCK_FIXED_SILHOUETTE,     /* seam_mode fixed */
    BLOCK_PLACEMENT,            /* the constrained QP has no solution */
    BLOCK_LINK_SURFACE,
    BLOCK_LINK_UV,
    BLOCK_VALENCE,
    BLOCK_SURFACE_FLIP,         /* a face would flip or degenerate in 3D */
    BLOCK_NORMAL_TURN,          /* a face's normal would turn by more than normal_turn */
    BLOCK_UV_FLIP,
    BLOCK_MAX_ERROR,            /* the level would leave the input by more than max_error */
    BLOCK_TEXEL_STRETCH,        /* with map_size: a face's texels would span too much surface */
    BLOCK_SEAM_ERROR,           /* with map_size: an input seam point would leave the level by more than seam_error */
    BLOCK_TEXEL_CREASE,         /* with map_size: a crease inside a chart would be too sharp for the map's texels */
    BLOCK_WIDE_FAN,             /* an endpoint with more than MAX_FAN faces */
    BLOCK_CROSSING,             /* a face would pass through another (refuse_crossings) */
    BLOCK_CONTACT,              /* an open part's border would move away from another part (contact_distance) */
    BLOCK_COUNT
} block_reason;

static const char *const block_names[BLOCK_COUNT] = {
    "none", "nonmanifold_vertex", "silhouette_endpoints", "seam_corner", "seam_not_collinear",
    "seam_length_ratio", "boundary_corner", "boundary_not_collinear", "fixed_silhouette", "placement",
    "link_surface", "link_uv", "valence", "surface_flip", "normal_turn", "uv_flip", "max_error",
    "texel_stretch", "seam_error", "texel_crease", "wide_fan", "crossing", "contact",
};

enum { V_ALIVE = 1, V_BOUNDARY = 2, V_LOCKED = 4, V_RETRY = 8, V_CONTACT = 16 /* holds a contact */ };
enum { Z_SILHOUETTE = 1, Z_PINNED = 2 };
enum { EDGE_INTERIOR = 0, EDGE_SEAM = 1, EDGE_BOUNDARY = 2 };
enum { UV_FREE = 0, UV_FIXED = 1, UV_SLIDE = 2 };

/* A queued edge. `key` is the bit pattern of its (non-negative) cost, which
 * orders like the cost itself; `pair` = a << 32 | b breaks ties, so the
 * order never depends on anything but the mesh. */
typedef struct heap_entry {
    uint64_t key, pair;
    uint32_t va, vb;
    bool full;                   /* the key holds the tracked error (else it is a lower bound) */
} heap_entry;

/* One uv half-edge of a collapse: Z `gone` merges into Z `keep`. */
typedef struct half_plan {
    int32_t keep, gone;
    int uv_mode;
    double line0[2], line1[2];   /* UV_SLIDE: the segment w must stay on (uv units) */
    int32_t end0, end1;          /* UV_SLIDE: the Z at the segment's ends */
    double fixed[2];             /* UV_FIXED */
    double w[2];                 /* the placement */
} half_plan;

typedef struct collapse_plan {
    int32_t keep, gone;          /* surface vertices */
    int kind, nhalf;
    half_plan h[2];
    int32_t faces[2];            /* the faces on the edge (removed) */
    int nfaces;
    double xyz[3];
    double cost;
    block_reason reason;
} collapse_plan;

/* A face in a grid cell, with its bounding box when put in, rounded outwards
 * to float: a query filters the cell's faces by box without leaving the
 * cell's memory. */
typedef struct grid_item {
    int32_t face, v[3];   /* the face and its vertices, */
    float lo[3], hi[3];   /* and its box (float, rounded outwards) */
} grid_item;

/* The items whose box centre falls in one cell, and a box holding theirs
 * (the union of those put since the cell was last empty). */
typedef struct grid_cell {
    grid_item *items;
    int32_t len, cap;
    float lo[3], hi[3];
} grid_cell;

/* One level of the grid: cells `cell` long from the grid's corner, and the
 * faces whose box's half-side is at most that. */
typedef struct grid_level {
    double cell, inv_cell;
    int32_t n[3];
    grid_cell *cells;
    double reach;                  /* the largest half-side of an item's box */
    int64_t items;                 /* items put since built (none: no cell to visit) */
    float lo[3], hi[3];            /* the union of their boxes */
} grid_level;

#define GRID_LEVELS 6              /* cells 1, 4, 16, ... 1024 times level 0's */

/* Live faces in a loose hierarchical grid (refuse_crossings, contact): each
 * face is in one cell, the one holding its box's centre, on the finest level
 * whose cells are at least its box's half-side long (cells four times longer
 * from one level to the next), or in `big` when its box is larger still. A
 * query visits, on each level holding faces, the cells within that level's
 * `reach` (the largest half-side of its items' boxes) of its box, and only
 * those whose union box meets it, so it meets every face once and no face is
 * spread over cells; long faces (a lantern's struts) sit on coarse levels,
 * where a query visits a few cells, instead of in a list every query reads.
 * A face that moves or goes is taken out of its cell at once (the cell's
 * last item takes its place), so a query scans live faces only. */
typedef struct face_grid {
    bool on;
    double lo[3];
    grid_level level[GRID_LEVELS];
    grid_cell big;                 /* faces larger than the coarsest level's cells */
    int32_t built_faces;           /* live faces when built */
    grid_cell **home;              /* per face: its cell, NULL when not in the grid */
    int32_t *slot;                 /* per face: its index there */
    const grid_item **found;       /* scratch: the items a query meets */
    int32_t found_cap;
    struct fan_entry *fan;         /* scratch: the new fan of a query */
    float *fan_box;                /* its boxes: 6 rows of fan_cap (lo x, y, z, hi x, y, z) */
    int32_t *met;                  /* scratch: the fan faces a box meets */
    int32_t fan_cap, met_cap;
    struct fan_entry *old_fan;     /* scratch: a query's faces around keep and gone as they are, */
    int32_t nold, old_cap;         /* prepared at its first crossing (crossed_before) */
} face_grid;

/* A triangle ready for crossing tests: its corners, its normal (not unit),
 * the normal's length and its longest edge, each computed once per query
 * however many triangles it meets. */
typedef struct crossing_triangle {
    const double *P[3];
    double n[3], len, longest;
} crossing_triangle;

/* A face of a collapse's new fan: the triangle and its vertices. */
typedef struct fan_entry {
    crossing_triangle T;
    int32_t v[3];
} fan_entry;

typedef struct state {
    /* parameters */
    int mode, weights;
    double uv_scale, collinear_tol, ratio_tol;
    double uv_precision;         /* the coarsest storage step of the input's uv (a metric) */
    int uv_digits;               /* uv stored with this many significant decimals, or 0 */
    int uv_mantissa;             /* else binary: 23 (float32) or 52 (double) mantissa bits */
    double uv_step_given;        /* the uv_precision parameter when >= 0 */
    double normal_cos;           /* a face's normal may turn by less than this angle's cosine */
    bool refuse_crossings;
    face_grid grid;              /* with refuse_crossings or contact_distance */
    double contact_distance;     /* model units (find_contacts); 0: off */
    double contact_slack;        /* model units: how much farther a contact may move */
    /* Contacts: an open part's border vertex within contact_distance of
     * another part may end up at most its input distance from the other
     * parts (reach), and at most its input height over the nearest face
     * (rise), each plus contact_slack; so may the points of a border edge
     * between two contacts (at the larger of their limits, or no worse than
     * before). A rim that rises off a body opens a gap that shows the open
     * part's inside; one that sinks into it passes through its faces, which
     * refuse_crossings refuses. */
    int32_t *contacts;           /* the vertices holding one (V_CONTACT), the dead ones dropped */
    int32_t ncontacts, input_contacts;
    double *contact_reach, *contact_rise;   /* per surface vertex, where V_CONTACT */
    int32_t *part;               /* per surface vertex: its connected part (with contacts) */
    double contact_lo[3], contact_hi[3];   /* the box of every contact's reach */
    double contact_reach_max;    /* the largest reach */
    double contact_edge;         /* no edge between two contacts is longer */
    /* surface vertices */
    int32_t nv;
    double *pos;                 /* centred on the input's bounding box */
    double center[3];
    uint8_t *vflags;
    uint32_t *version;
    uint32_t *vmark;
    uint32_t vstamp;   /* the last mark taken (fresh_mark) */
    /* vertex -> live faces, lists in one pool */
    int64_t *vf_off;
    int32_t *vf_len, *vf_cap;
    int32_t *vf_dead;        /* dead faces a wide fan's list still holds (remove_from_list) */
    int32_t *pool;
    int64_t pool_len, pool_cap;
    /* faces */
    int32_t nf, nf_alive;
    int32_t *fv, *fz, *fmat;
    uint8_t *falive;
    double *input_uv_area;
    /* Z-vertices */
    int32_t nz;
    int32_t *zv, *zuv_index;
    int32_t *zcorner;            /* the input corner (3 f + k) that first named the Z: its normal */
    double *smooth_normals;      /* per input corner, for an input without normals (made at its first level) */
    double *zuv;
    uint8_t *zflags;
    double *zq, *zgeo, *znormal, *zweight;
    double *zstep;               /* storage step of the Z's uv (the coarsest it was merged with) */
    uint32_t *zmark;
    uint32_t zstamp;
    /* queue */
    heap_entry *heap;
    int64_t heap_len, heap_cap;
    int64_t heap_compacted;      /* entries left by the last compaction */
    int64_t border_edges;        /* border spokes of the input: twice its border edges */
    /* scratch */
    int32_t *scratch;
    int32_t scratch_cap;
    int32_t *touched, *neighbours;
    int32_t touched_cap, neighbours_cap;
    bool out_of_memory;
    int threads;                 /* for the first evaluation of every edge */
    /* error tracking (see the design note) */
    double error_weight;         /* 0: off */
    double max_error2;           /* squared bound on the tracked error; 0: none */
    double input_area;           /* surface area of the input */
    const sc_hausdorff_mesh *input;   /* the input surface, uncentred */
    sc_hausdorff_bvh *input_bvh; /* over `input`, for tracking and the Hausdorff metric (input_bvh_take) */
    pthread_t bvh_thread;        /* with two threads: builds input_bvh while the collapses begin */
    bool bvh_pending;
    int32_t *owned_head, *owned_tail;   /* per surface vertex: the input vertices it stands for */
    int32_t *owned_next;         /* per input vertex: the next one in its owner's list, or -1 */
    int32_t *near_face;          /* per surface vertex: an input face near it, where queries start */
    int32_t *input_vf_off, *input_vf;   /* per input vertex: its input faces (input_vf_off[v] .. [v + 1]) */
    double map_texel_length;     /* map_texel x diagonal x map_size: the importance's unit of h x map_size; 0: off */
    double *importance;          /* per surface vertex: the largest importance of the input faces it stands for */
    double *stretch;             /* per surface vertex: the largest stretch (uv_stretch) of the input faces it stands for */
    double seam_error2;          /* with map_size: squared bound of seam_kept; 0: off */
    double map_size;             /* with map_size: the map's size (creases_ok) */
    double crease_limit;         /* with map_size: map_crease x diagonal (creases_ok); 0: off */
    int32_t *input_z_first;      /* per input vertex on a seam: its first input Z, or -1 (seam_kept) */
    int32_t *input_z_next;       /* per input Z: the next of the same vertex, or -1 */
    double *input_zuv;           /* per input Z: its uv in the input */
    int64_t tracking_from;       /* tracking is on while the face count is at most this */
    double tracking_scale;       /* error_weight x the mean area per vertex at the current target */
    struct fan_face *fan;        /* scratch: the new fan of a collapse */
    double *fan_h2;              /* scratch: a point's squared distance to each fan face's plane */
    int32_t fan_cap;
    /* statistics */
    int64_t seam_collapses, collapses, rejected, tracked_evaluations;
} state;

/* ---------------------------------------------------------------- small helpers */

static int32_t *vfaces(const state *st, int32_t v, int32_t *count) {
    *count = st->vf_len[v];
    return st->pool + st->vf_off[v];
}

static bool grow_scratch(state *st, int32_t need) {
    if (need <= st->scratch_cap) return true;
    int32_t cap = st->scratch_cap ? st->scratch_cap : 64;
    while (cap < need) cap *= 2;
    int32_t *p = sc_realloc_array(st->scratch, (size_t)cap, sizeof *p);
    if (!p) {
        st->out_of_memory = true;
        return false;
    }
    st->scratch = p;
    st->scratch_cap = cap;
    return true;
}

/* A growable int buffer owned by the state: NULL (and out_of_memory set)
 * when it cannot hold `need` entries. */
static int32_t *reserve(state *st, int32_t **buf, int32_t *cap, int32_t need) {
    if (need <= *cap) return *buf;
    int32_t c = *cap ? *cap : 64;
    while (c < need) c *= 2;
    int32_t *p = sc_realloc_array(*buf, (size_t)c, sizeof *p);
    if (!p) {
        st->out_of_memory = true;
        return NULL;
    }
    *buf = p;
    *cap = c;
    return p;
}

static int corner_of(const state *st, int32_t f, int32_t v) {
    for (int k = 0; k < 3; k++)
        if (st->fv[3 * f + k] == v) return k;
    return -1;
}


static void scaled_point(const state *st, int32_t z, double out[QDIM]) {
    const double *p = st->pos + 3 * st->zv[z];
    out[0] = p[0], out[1] = p[1], out[2] = p[2];
    out[3] = st->uv_scale * st->zuv[2 * z];
    out[4] = st->uv_scale * st->zuv[2 * z + 1];
}

/* ---------------------------------------------------------------- fans */

/* Distinct uv boundary neighbours of Z z (uv edges at z used by one face),
 * written to out (up to max); returns their count, or -1 when some uv edge
 * at z has more than two faces. */
static int z_boundary_neighbours(state *st, int32_t z, int32_t *out, int max) {
    int32_t n;
    const int32_t *list = vfaces(st, st->zv[z], &n);
    if (!grow_scratch(st, 2 * n + 2)) return -1;
    int32_t *spokes = st->scratch;
    int ns = 0;
    for (int32_t i = 0; i < n; i++) {
        int32_t f = list[i];
        for (int k = 0; k < 3; k++)
            if (st->fz[3 * f + k] == z) {
                spokes[ns++] = st->fz[3 * f + (k + 1) % 3];
                spokes[ns++] = st->fz[3 * f + (k + 2) % 3];
            }
    }
    int count = 0;
    for (int i = 0; i < ns; i++) {
        int same = 0, first = 1;
        for (int j = 0; j < ns; j++)
            if (spokes[j] == spokes[i]) {
                same++;
                if (j < i) first = 0;
            }
        if (same > 2) return -1;
        if (same == 1 && first) {
            if (count < max) out[count] = spokes[i];
            count++;
        }
    }
    return count;
}

/* Number of distinct Z-vertices the faces around surface vertex v use at v. */
static int vertex_wedges(const state *st, int32_t v, int32_t first_two[2]) {
    int32_t n;
    const int32_t *list = vfaces(st, v, &n);
    int count = 0;
    int32_t seen[8];
    for (int32_t i = 0; i < n; i++) {
        int k = corner_of(st, list[i], v);
        int32_t z = st->fz[3 * list[i] + k];
        bool known = false;
        for (int j = 0; j < count && j < 8; j++)
            if (seen[j] == z) known = true;
        if (!known) {
            if (count < 8) seen[count] = z;
            count++;
            if (count > 8) return count;
        }
    }
    if (first_two) {
        first_two[0] = count > 0 ? seen[0] : -1;
        first_two[1] = count > 1 ? seen[1] : -1;
    }
    return count;
}

/* Faces on the surface edge (a, b); returns their count (up to 3 recorded). */
static int edge_faces(const state *st, int32_t a, int32_t b, int32_t out[3]) {
    int32_t n;
    /* a's list, or b's when a's is past MAX_FAN and longer (the faces then
     * come in b's order): a polygon's fan centre is not walked per edge */
    if (st->vf_len[a] > MAX_FAN && st->vf_len[b] < st->vf_len[a]) {
        int32_t t = a;
        a = b;
        b = t;
    }
    const int32_t *list = vfaces(st, a, &n);
    int count = 0;
    for (int32_t i = 0; i < n; i++) {
        const int32_t *c = st->fv + 3 * list[i];
        if (!st->falive[list[i]]) continue;   /* a wide fan's dead face (remove_from_list) */
        if (c[0] == b || c[1] == b || c[2] == b) {
            if (count < 3) out[count] = list[i];
            count++;
        }
    }
    return count;
}

/* ---------------------------------------------------------------- unifiability */

/* |e0| / |d0| = |e1| / |d1| (as e0 d1 = e1 d0), to ratio_tol relative plus
 * the effect of the storage precision on the four lengths (each off by up
 * to 1.42 steps). */
static bool ratios_equal(const state *st, double e0, double d0, double e1, double d1, double q) {
    double lhs = e0 * d1, rhs = e1 * d0;
    double slack = st->ratio_tol * (lhs > rhs ? lhs : rhs) + 2.0 * q * (e0 + d0 + e1 + d1) + 8.0 * q * q;
    return fabs(lhs - rhs) <= slack;
}

/* At surface vertex `at`, end of a silhouette edge whose uv half-edges are
 * z_at[i] -> z_other[i] (i < nhalf): find the neighbouring edge continuing
 * every half and test whether it unifies with ours. On success far[i] is the
 * far end of the neighbour's half i. */
static block_reason unify_at(state *st, int nhalf, int32_t at, const int32_t *z_at, const int32_t *z_other,
                             int32_t *far) {
    bool seam = nhalf == 2;
    block_reason corner = seam ? BLOCK_SEAM_CORNER : BLOCK_BOUNDARY_CORNER;
    if (seam && z_at[0] == z_at[1]) return corner;   /* the tip of a slit */
    int32_t wedges[2];
    if (vertex_wedges(st, at, wedges) != nhalf) return corner;   /* another chart meets here */
    for (int i = 0; i < nhalf; i++) {
        if (st->zflags[z_at[i]] & Z_PINNED) return corner;
        int32_t nb[3];
        if (z_boundary_neighbours(st, z_at[i], nb, 3) != 2) return corner;
        if (nb[0] == z_other[i]) far[i] = nb[1];
        else if (nb[1] == z_other[i]) far[i] = nb[0];
        else return corner;
    }
    int32_t c = st->zv[far[0]];
    if (seam && st->zv[far[1]] != c) return corner;   /* the halves turn into different seams */
    int32_t fl[3];
    int nfl = edge_faces(st, at, c, fl);
    if (nfl != (seam ? 2 : 1)) return corner;
    block_reason not_collinear = seam ? BLOCK_SEAM_NOT_COLLINEAR : BLOCK_BOUNDARY_NOT_COLLINEAR;
    double step = 0;
    for (int i = 0; i < nhalf; i++) {
        double si = fmax(st->zstep[far[i]], fmax(st->zstep[z_at[i]], st->zstep[z_other[i]]));
        /* mid's distance from the chord may add what the storage precision
         * of the three points explains (each coordinate rounded by up to half
         * a step moves a point by up to 0.71 steps; 2 steps bound the chord's
         * distance from a straight line through the unrounded points) */
        if (!sc_collinear_through(st->zuv + 2 * far[i], st->zuv + 2 * z_at[i], st->zuv + 2 * z_other[i],
                                  st->collinear_tol, 2.0 * si))
            return not_collinear;
        step = fmax(step, si);
    }
    if (seam) {
        double d0 = sc_dist2(st->zuv + 2 * far[0], st->zuv + 2 * z_at[0]);
        double e0 = sc_dist2(st->zuv + 2 * z_at[0], st->zuv + 2 * z_other[0]);
        double d1 = sc_dist2(st->zuv + 2 * far[1], st->zuv + 2 * z_at[1]);
        double e1 = sc_dist2(st->zuv + 2 * z_at[1], st->zuv + 2 * z_other[1]);
        if (!ratios_equal(st, e0, d0, e1, d1, step)) return BLOCK_SEAM_LENGTH_RATIO;
    }
    return BLOCK_NONE;
}

/* The more informative of two reasons (length ratio > not collinear > corner). */
static block_reason better_reason(block_reason x, block_reason y) {
    static const int rank[BLOCK_COUNT] = {[BLOCK_SEAM_LENGTH_RATIO] = 3, [BLOCK_SEAM_NOT_COLLINEAR] = 2,
                                          [BLOCK_BOUNDARY_NOT_COLLINEAR] = 2, [BLOCK_SEAM_CORNER] = 1,
                                          [BLOCK_BOUNDARY_CORNER] = 1};
    return rank[x] >= rank[y] ? x : y;
}

/* ---------------------------------------------------------------- planning */

static void set_fixed(half_plan *h, const double *uv) {
    h->uv_mode = UV_FIXED;
    h->fixed[0] = uv[0];
    h->fixed[1] = uv[1];
}

/* Decide how edge (a, b) collapses: which vertex stays, which Z merge, and
 * the uv constraints. Fills p->reason when the edge cannot collapse. */
static void plan_edge(state *st, int32_t a, int32_t b, collapse_plan *p) {
    p->reason = BLOCK_NONE;
    p->nfaces = p->nhalf = 0;
    p->cost = INFINITY;
    if ((st->vflags[a] | st->vflags[b]) & V_LOCKED) {
        p->reason = BLOCK_NONMANIFOLD;
        return;
    }
    if (st->vf_len[a] > MAX_FAN || st->vf_len[b] > MAX_FAN) {
        p->reason = BLOCK_WIDE_FAN;
        return;
    }
    int32_t fl[3];
    int nf = edge_faces(st, a, b, fl);
    if (nf < 1 || nf > 2) {
        p->reason = BLOCK_NONMANIFOLD;
        return;
    }
    p->nfaces = nf;
    p->faces[0] = fl[0];
    p->faces[1] = nf > 1 ? fl[1] : -1;
    int32_t za[2], zb[2];
    for (int i = 0; i < nf; i++) {
        za[i] = st->fz[3 * fl[i] + corner_of(st, fl[i], a)];
        zb[i] = st->fz[3 * fl[i] + corner_of(st, fl[i], b)];
    }
    int32_t lo = a < b ? a : b;
    if (nf == 2 && za[0] == za[1] && zb[0] == zb[1]) {
        /* interior uv edge */
        p->kind = EDGE_INTERIOR;
        p->nhalf = 1;
        bool sa = st->zflags[za[0]] & (Z_SILHOUETTE | Z_PINNED);
        bool sb = st->zflags[zb[0]] & (Z_SILHOUETTE | Z_PINNED);
        if (sa && sb) {
            p->reason = BLOCK_SILHOUETTE_ENDPOINTS;
            return;
        }
        bool keep_a = sa || (!sb && a == lo);
        p->keep = keep_a ? a : b;
        p->gone = keep_a ? b : a;
        p->h[0].keep = keep_a ? za[0] : zb[0];
        p->h[0].gone = keep_a ? zb[0] : za[0];
        if ((sa || sb) && st->mode != MODE_FREE) set_fixed(&p->h[0], st->zuv + 2 * p->h[0].keep);
        else p->h[0].uv_mode = UV_FREE;
        return;
    }
    p->kind = nf == 1 ? EDGE_BOUNDARY : EDGE_SEAM;
    p->nhalf = nf;
    if (st->mode == MODE_FIXED) {
        p->reason = BLOCK_FIXED_SILHOUETTE;
        return;
    }
    if (st->mode == MODE_FREE) {
        /* keep the slit's tip, if any, so that no Z has to go two ways */
        bool keep_a = nf == 2 ? (za[0] == za[1] || (zb[0] != zb[1] && a == lo)) : a == lo;
        p->keep = keep_a ? a : b;
        p->gone = keep_a ? b : a;
        for (int i = 0; i < nf; i++) {
            p->h[i].keep = keep_a ? za[i] : zb[i];
            p->h[i].gone = keep_a ? zb[i] : za[i];
            p->h[i].uv_mode = UV_FREE;
        }
        if (nf == 2 && p->h[0].keep == p->h[1].keep)
            for (int i = 0; i < 2; i++) set_fixed(&p->h[i], st->zuv + 2 * p->h[0].keep);
        return;
    }
    /* aware: unifiability at each end */
    int32_t far_a[2] = {-1, -1}, far_b[2] = {-1, -1};
    block_reason ra = unify_at(st, nf, a, za, zb, far_a);
    block_reason rb = unify_at(st, nf, b, zb, za, far_b);
    if (ra != BLOCK_NONE && rb != BLOCK_NONE) {
        p->reason = better_reason(ra, rb);
        return;
    }
    if (ra == BLOCK_NONE && rb == BLOCK_NONE) {
        /* both ends free to slide: w_i on the line far_a[i] .. far_b[i] */
        bool keep_a = a == lo;
        p->keep = keep_a ? a : b;
        p->gone = keep_a ? b : a;
        for (int i = 0; i < nf; i++) {
            half_plan *h = &p->h[i];
            h->keep = keep_a ? za[i] : zb[i];
            h->gone = keep_a ? zb[i] : za[i];
            h->uv_mode = UV_SLIDE;
            memcpy(h->line0, st->zuv + 2 * far_a[i], sizeof h->line0);
            memcpy(h->line1, st->zuv + 2 * far_b[i], sizeof h->line1);
            h->end0 = far_a[i];
            h->end1 = far_b[i];
        }
        return;
    }
    /* one end unifiable: that end moves onto the other, which stays put */
    bool keep_a = rb == BLOCK_NONE;
    p->keep = keep_a ? a : b;
    p->gone = keep_a ? b : a;
    for (int i = 0; i < nf; i++) {
        half_plan *h = &p->h[i];
        h->keep = keep_a ? za[i] : zb[i];
        h->gone = keep_a ? zb[i] : za[i];
        set_fixed(h, st->zuv + 2 * h->keep);
    }
}

/* ---------------------------------------------------------------- placement */

static double z_weight(const state *st, int32_t z) { return st->zweight[z]; }

static inline void q5_set_sum(double *dst, const double *a, double wa, const double *b, double wb) {
    for (int i = 0; i < QSIZE; i++) dst[i] = wa * a[i] + wb * b[i];
}

/* The quadric of the half-vertex h: Q(keep) + Q(gone), or for the area
 * distortion weights w_k Q(keep) + w_g Q(gone). skip_keep leaves Q(keep)
 * out (it was counted in the other half already). */
static void half_quadric(const state *st, const half_plan *h, bool skip_keep, double *q) {
    double wk = 1, wg = 1;
    if (st->weights == WEIGHTS_AREA_DISTORTION) wk = z_weight(st, h->keep), wg = z_weight(st, h->gone);
    if (skip_keep) wk = 0;
    q5_set_sum(q, st->zq + (size_t)h->keep * QSIZE, wk, st->zq + (size_t)h->gone * QSIZE, wg);
}

/* The general case (a uv on a line, or free uv on both sides of a seam).
 * Every constraint but the bound on t is an equality that the points of an
 * affine subspace meet by construction: x = B y + c with y = (xyz, the free
 * uv, t). The point is shared by both halves, a fixed uv sits in c, and a
 * slid uv is line0 + t (line1 - line0) with the one parameter t of half 0
 * (a slid half 1 beside an unslid half 0 keeps t = 0, its line0). The
 * minimiser of Q + rho |x - ref|^2 over that subspace is exact; when its t
 * leaves [0, 1], the objective is convex in t, so the bounded minimiser has
 * t at the nearer end, and the rest is solved again with t fixed there. */
static bool solve_constrained(const state *st, const collapse_plan *p, const double *quad, const double *ref,
                              double rho, double *x) {
    const double s = st->uv_scale;
    int nh = p->nhalf, n = QDIM * nh, m = 3;
    double B[SC_QUADRIC_MAX_DIM * SC_QUADRIC_MAX_DIM] = {0}, c[SC_QUADRIC_MAX_DIM] = {0};
    double slope[SC_QUADRIC_MAX_DIM] = {0};   /* d x / d t */
    bool slides = p->h[0].uv_mode == UV_SLIDE;
    for (int i = 0; i < nh; i++) {
        const half_plan *h = &p->h[i];
        int o = QDIM * i;
        if (h->uv_mode == UV_FIXED) {
            c[o + 3] = s * h->fixed[0], c[o + 4] = s * h->fixed[1];
        } else if (h->uv_mode == UV_SLIDE) {
            double D[2] = {h->line1[0] - h->line0[0], h->line1[1] - h->line0[1]};
            if (!(D[0] * D[0] + D[1] * D[1] > 0)) return false;
            c[o + 3] = s * h->line0[0], c[o + 4] = s * h->line0[1];
            if (slides) slope[o + 3] = s * D[0], slope[o + 4] = s * D[1];
        }
    }
    /* the columns of B: xyz, then each free uv, then t */
    const int cols = 3 + 2 * (p->h[0].uv_mode == UV_FREE) + 2 * (nh == 2 && p->h[1].uv_mode == UV_FREE) + slides;
    for (int i = 0; i < nh; i++)
        for (int k = 0; k < 3; k++) B[(QDIM * i + k) * cols + k] = 1;
    for (int i = 0; i < nh; i++)
        if (p->h[i].uv_mode == UV_FREE) {
            B[(QDIM * i + 3) * cols + m] = 1, B[(QDIM * i + 4) * cols + m + 1] = 1;
            m += 2;
        }
    double y[SC_QUADRIC_MAX_DIM];
    if (slides) {
        for (int r = 0; r < n; r++) B[r * cols + m] = slope[r];
        if (!sc_quadric_minimize_affine(quad, n, B, cols, c, ref, rho, y)) return false;
        double t = y[m];
        if (t < 0 || t > 1) {   /* t at the nearer end: its column joins c */
            t = t < 0 ? 0 : 1;
            double fixed[SC_QUADRIC_MAX_DIM * SC_QUADRIC_MAX_DIM], at_end[SC_QUADRIC_MAX_DIM];
            for (int r = 0; r < n; r++) {
                at_end[r] = c[r] + t * slope[r];
                for (int j = 0; j < m; j++) fixed[r * m + j] = B[r * cols + j];
            }
            if (!sc_quadric_minimize_affine(quad, n, fixed, m, at_end, ref, rho, y)) return false;
            y[m] = t;
        }
    } else if (!sc_quadric_minimize_affine(quad, n, B, cols, c, ref, rho, y)) {
        return false;
    }
    for (int r = 0; r < n; r++) {
        double v = c[r];
        for (int j = 0; j < m; j++) v += B[r * cols + j] * y[j];
        x[r] = v + (slides ? slope[r] * y[m] : 0);
    }
    return true;
}

/* Solve for the placement of a planned collapse; sets cost, xyz, w.
 *
 * The placement is the exact minimiser of Q + rho |x - ref|^2 under the
 * plan's constraints (rho from sc_quadric_default_rho of the whole problem,
 * ref the midpoint of the edge in every dimension, or the fixed uv). When
 * every uv is fixed, or nothing is constrained, the equality constraints
 * only fix variables: eliminating them is exact and leaves a small positive
 * definite system. Lines and free seam uv go to solve_constrained. */
static void solve_plan(state *st, collapse_plan *p) {
    if (p->reason != BLOCK_NONE) return;
    const double s = st->uv_scale;
    int nh = p->nhalf == 2 ? 2 : 1;
    bool shared_keep = nh == 2 && p->h[0].keep == p->h[1].keep;
    double qh[2][QSIZE];
    half_quadric(st, &p->h[0], false, qh[0]);
    if (nh == 2) half_quadric(st, &p->h[1], shared_keep, qh[1]);
    double rho = sc_quadric_default_rho(qh[0], QDIM);
    if (nh == 2) rho = 0.5 * (rho + sc_quadric_default_rho(qh[1], QDIM));   /* trace / 10 of the block */

    double ref[SC_QUADRIC_MAX_DIM];
    const double *pk = st->pos + 3 * p->keep, *pg = st->pos + 3 * p->gone;
    bool all_fixed = true;
    for (int i = 0; i < nh; i++) {
        const half_plan *h = &p->h[i];
        int o = QDIM * i;
        for (int k = 0; k < 3; k++) ref[o + k] = 0.5 * (pk[k] + pg[k]);
        if (h->uv_mode == UV_FIXED) {
            ref[o + 3] = s * h->fixed[0];
            ref[o + 4] = s * h->fixed[1];
        } else {
            const double *uk = st->zuv + 2 * h->keep, *ug = st->zuv + 2 * h->gone;
            ref[o + 3] = 0.5 * s * (uk[0] + ug[0]);
            ref[o + 4] = 0.5 * s * (uk[1] + ug[1]);
            all_fixed = false;
        }
    }
    double x[SC_QUADRIC_MAX_DIM];
    bool ok;
    if (nh == 1 && p->h[0].uv_mode == UV_FREE) {
        ok = sc_quadric_minimize(qh[0], QDIM, ref, rho, x);
    } else if (all_fixed) {
        double reduced[SC_QUADRIC_SIZE(3)], part[SC_QUADRIC_SIZE(3)];
        for (int i = 0; i < nh; i++) {
            double tail[2] = {s * p->h[i].fixed[0], s * p->h[i].fixed[1]};
            sc_quadric_restrict(qh[i], QDIM, 3, tail, i == 0 ? reduced : part);
            if (i > 0) sc_quadric_add(reduced, part, 3, 1.0);
        }
        ok = sc_quadric_minimize(reduced, 3, ref, nh * rho, x);
    } else {
        double quad[SC_QUADRIC_MAX_SIZE];
        if (nh == 2) sc_quadric_block(quad, qh[0], qh[1], QDIM);
        else memcpy(quad, qh[0], sizeof qh[0]);
        ok = solve_constrained(st, p, quad, ref, rho, x);
    }
    if (!ok) {
        p->reason = BLOCK_PLACEMENT;
        return;
    }
    for (int k = 0; k < 3; k++) p->xyz[k] = x[k];
    /* Snap uv exactly: kept points copied, slid points put on their line at
     * one common parameter. */
    double t = 0;
    if (p->h[0].uv_mode == UV_SLIDE) {
        const half_plan *h0 = &p->h[0];
        double D0[2] = {h0->line1[0] - h0->line0[0], h0->line1[1] - h0->line0[1]};
        double w0[2] = {x[3] / s, x[4] / s};
        t = ((w0[0] - h0->line0[0]) * D0[0] + (w0[1] - h0->line0[1]) * D0[1]) / (D0[0] * D0[0] + D0[1] * D0[1]);
        t = t < 0 ? 0 : t > 1 ? 1 : t;
    }
    double cost = 0;
    for (int i = 0; i < nh; i++) {
        half_plan *h = &p->h[i];
        if (h->uv_mode == UV_FIXED) {
            h->w[0] = h->fixed[0];
            h->w[1] = h->fixed[1];
        } else if (h->uv_mode == UV_SLIDE) {
            for (int k = 0; k < 2; k++) h->w[k] = h->line0[k] + t * (h->line1[k] - h->line0[k]);
        } else {
            h->w[0] = x[QDIM * i + 3] / s;
            h->w[1] = x[QDIM * i + 4] / s;
        }
        double xi[QDIM] = {p->xyz[0], p->xyz[1], p->xyz[2], s * h->w[0], s * h->w[1]};
        cost += sc_quadric_eval(qh[i], QDIM, xi);
    }
    p->cost = cost > 0 ? cost : 0;
}

/* ---------------------------------------------------------------- validity */

/* A vertex mark no vertex carries yet: callers may leave mark, mark + 1 and
 * mark + 2 behind (link_surface_ok does), so each takes three. */
static uint32_t fresh_mark(state *st) { return st->vstamp += 3; }

/* Surface link condition (with one virtual vertex joined to all borders). */
static bool link_surface_ok(state *st, const collapse_plan *p) {
    int32_t a = p->keep, b = p->gone;
    if (p->nfaces == 2 && (st->vflags[a] & V_BOUNDARY) && (st->vflags[b] & V_BOUNDARY)) return false;
    uint32_t mark = fresh_mark(st);
    int32_t n;
    const int32_t *list = vfaces(st, a, &n);
    for (int32_t i = 0; i < n; i++)
        for (int k = 0; k < 3; k++) st->vmark[st->fv[3 * list[i] + k]] = mark;
    /* the opposite vertices of the edge's faces are the expected common ones */
    int expected = 0;
    for (int i = 0; i < p->nfaces; i++)
        for (int k = 0; k < 3; k++) {
            int32_t x = st->fv[3 * p->faces[i] + k];
            if (x != a && x != b && st->vmark[x] == mark) {
                st->vmark[x] = mark + 1;
                expected++;
            }
        }
    list = vfaces(st, b, &n);
    for (int32_t i = 0; i < n; i++)
        for (int k = 0; k < 3; k++) {
            int32_t x = st->fv[3 * list[i] + k];
            if (x == a || x == b) continue;
            if (st->vmark[x] == mark) return false;   /* common neighbour, not opposite */
            if (st->vmark[x] == mark + 1) st->vmark[x] = mark + 2;
        }
    return true;
}

/* Mark the uv neighbours of Z z with `value` (only where the mark is `from`,
 * unless from == 0, which marks all). */
static void mark_z_neighbours(state *st, int32_t z, uint32_t value) {
    int32_t n;
    const int32_t *list = vfaces(st, st->zv[z], &n);
    for (int32_t i = 0; i < n; i++) {
        const int32_t *c = st->fz + 3 * list[i];
        if (c[0] != z && c[1] != z && c[2] != z) continue;
        for (int k = 0; k < 3; k++)
            if (c[k] != z) st->zmark[c[k]] = value;
    }
}

/* uv link condition for one half-edge keep -> gone. */
static bool link_uv_ok(state *st, const collapse_plan *p, const half_plan *h) {
    /* the uv faces on this half-edge and their opposite Z */
    int32_t opposite[2];
    int nopp = 0;
    for (int i = 0; i < p->nfaces; i++) {
        const int32_t *c = st->fz + 3 * p->faces[i];
        bool has_k = c[0] == h->keep || c[1] == h->keep || c[2] == h->keep;
        bool has_g = c[0] == h->gone || c[1] == h->gone || c[2] == h->gone;
        if (!has_k || !has_g) continue;
        for (int k = 0; k < 3; k++)
            if (c[k] != h->keep && c[k] != h->gone) opposite[nopp++] = c[k];
    }
    bool boundary_edge = nopp == 1;
    bool sil_k = st->zflags[h->keep] & (Z_SILHOUETTE | Z_PINNED);
    bool sil_g = st->zflags[h->gone] & (Z_SILHOUETTE | Z_PINNED);
    if (!boundary_edge && sil_k && sil_g) return false;
    uint32_t mark = st->zstamp += 2;
    mark_z_neighbours(st, h->keep, mark);
    for (int i = 0; i < nopp; i++) st->zmark[opposite[i]] = mark + 1;
    int32_t n;
    const int32_t *list = vfaces(st, st->zv[h->gone], &n);
    for (int32_t i = 0; i < n; i++) {
        const int32_t *c = st->fz + 3 * list[i];
        if (c[0] != h->gone && c[1] != h->gone && c[2] != h->gone) continue;
        for (int k = 0; k < 3; k++)
            if (c[k] != h->gone && c[k] != h->keep && st->zmark[c[k]] == mark) return false;
    }
    return true;
}

/* When two gone Z merge into one kept Z (the tip of a slit), their uv
 * neighbourhoods must not overlap. */
static bool tip_merge_ok(state *st, const collapse_plan *p) {
    if (p->nhalf != 2 || p->h[0].keep != p->h[1].keep) return true;
    uint32_t mark = st->zstamp += 2;
    mark_z_neighbours(st, p->h[0].gone, mark);
    st->zmark[p->h[0].keep] = 0;
    int32_t n;
    const int32_t *list = vfaces(st, st->zv[p->h[1].gone], &n);
    for (int32_t i = 0; i < n; i++) {
        const int32_t *c = st->fz + 3 * list[i];
        if (c[0] != p->h[1].gone && c[1] != p->h[1].gone && c[2] != p->h[1].gone) continue;
        for (int k = 0; k < 3; k++)
            if (c[k] != p->h[1].gone && st->zmark[c[k]] == mark) return false;
    }
    return true;
}

static bool is_removed(const collapse_plan *p, int32_t f) {
    return f == p->faces[0] || (p->nfaces > 1 && f == p->faces[1]);
}

/* The opposite vertices keep a valid fan, and so does the new vertex. */
static bool valence_ok(state *st, const collapse_plan *p) {
    for (int i = 0; i < p->nfaces; i++)
        for (int k = 0; k < 3; k++) {
            int32_t x = st->fv[3 * p->faces[i] + k];
            if (x == p->keep || x == p->gone) continue;
            int32_t n = st->vf_len[x] - 1;
            if (n < ((st->vflags[x] & V_BOUNDARY) ? 1 : 3)) return false;
        }
    int32_t n = st->vf_len[p->keep] + st->vf_len[p->gone] - 2 * p->nfaces;
    bool boundary = (st->vflags[p->keep] | st->vflags[p->gone]) & V_BOUNDARY;
    return n >= (boundary ? 1 : 3);
}

/* New uv of Z z after the collapse, or NULL when it does not move. */
static const double *moved_uv(const collapse_plan *p, int32_t z) {
    for (int i = 0; i < p->nhalf; i++)
        if (z == p->h[i].keep || z == p->h[i].gone) return p->h[i].w;
    return NULL;
}

/* The stretch of the map uv -> surface on a triangle: the largest singular
 * value of its Jacobian (surface length per unit of uv in the direction it
 * is largest), HUGE_VAL on a triangle flat in uv. Over map_size it is the
 * longest surface length one texel of the map spans there. */
static double uv_stretch(const double *const P[3], const double *const W[3]) {
    double du1 = W[1][0] - W[0][0], dv1 = W[1][1] - W[0][1], du2 = W[2][0] - W[0][0], dv2 = W[2][1] - W[0][1];
    double det = du1 * dv2 - du2 * dv1, E = 0, F = 0, G = 0;
    if (det == 0) return HUGE_VAL;
    for (int k = 0; k < 3; k++) {
        double e1 = P[1][k] - P[0][k], e2 = P[2][k] - P[0][k];
        double ju = (e1 * dv2 - e2 * dv1) / det, jv = (e2 * du1 - e1 * du2) / det;
        E += ju * ju, F += ju * jv, G += jv * jv;
    }
    return sqrt(0.5 * (E + G + sqrt((E - G) * (E - G) + 4 * F * F)));
}

/* With map_size (design note): surviving face f may not stretch beyond
 * STRETCH_SLACK x the larger of the map texel's unit and the largest stretch
 * of the input faces its corners stand for, unless it stretched more before
 * the collapse and does not grow. */
#define STRETCH_SLACK 2.0
static bool stretch_ok(const state *st, const collapse_plan *p, int32_t f, const double *const oldP[3],
                       const double *const oldW[3], const double *const P[3], const double *const W[3]) {
    double after = uv_stretch(P, W);
    double limit = st->map_texel_length;
    for (int k = 0; k < 3; k++) {
        int32_t x = st->fv[3 * f + k];
        limit = fmax(limit, st->stretch[x]);
        if (x == p->keep || x == p->gone) limit = fmax(limit, fmax(st->stretch[p->keep], st->stretch[p->gone]));
    }
    return after <= STRETCH_SLACK * limit || after <= uv_stretch(oldP, oldW);
}

/* The faces around keep, then gone, that survive plan p, one at a time:
 *     fan_walk w = {0};
 *     for (int32_t f; (f = fan_next(st, p, &w)) >= 0;) ... */
typedef struct fan_walk {
    int side;
    int32_t next, count;
    const int32_t *list;
} fan_walk;

static int32_t fan_next(const state *st, const collapse_plan *p, fan_walk *w) {
    for (;;) {
        if (!w->list) w->list = vfaces(st, w->side ? p->gone : p->keep, &w->count), w->next = 0;
        while (w->next < w->count) {
            int32_t f = w->list[w->next++];
            if (!is_removed(p, f)) return f;
        }
        if (w->side++ == 1) return -1;
        w->list = NULL;
    }
}

static block_reason flips_ok(state *st, const collapse_plan *p) {
    fan_walk walk = {0};
    for (int32_t f; (f = fan_next(st, p, &walk)) >= 0;) {
        const double *P[3], *W[3];
        const double *oldP[3], *oldW[3];
        bool uv_moves = false;
        for (int k = 0; k < 3; k++) {
            int32_t x = st->fv[3 * f + k], z = st->fz[3 * f + k];
            oldP[k] = st->pos + 3 * x;
            oldW[k] = st->zuv + 2 * z;
            P[k] = (x == p->keep || x == p->gone) ? p->xyz : oldP[k];
            const double *w = moved_uv(p, z);
            W[k] = w ? w : oldW[k];
            if (w && (w[0] != oldW[k][0] || w[1] != oldW[k][1])) uv_moves = true;
        }
        /* surface */
        double n0[3], n1[3];
        sc_triangle_normal(oldP[0], oldP[1], oldP[2], n0);
        sc_triangle_normal(P[0], P[1], P[2], n1);
        double l0 = sqrt(sc_dot3(n0, n0)), l1 = sqrt(sc_dot3(n1, n1));
        double emax = 0;
        for (int k = 0; k < 3; k++) {
            const double *q = P[k], *r = P[(k + 1) % 3];
            double d[3] = {q[0] - r[0], q[1] - r[1], q[2] - r[2]};
            double e = sc_dot3(d, d);
            if (e > emax) emax = e;
        }
        if (!(l1 > 1e-12 * emax)) return BLOCK_SURFACE_FLIP;
        if (l0 > 0) {
            double d = sc_dot3(n0, n1);
            if (d <= 0) return BLOCK_SURFACE_FLIP;
            if (d <= st->normal_cos * l0 * l1) return BLOCK_NORMAL_TURN;
        }
        if (st->stretch && !stretch_ok(st, p, f, oldP, oldW, P, W)) return BLOCK_TEXEL_STRETCH;
        /* uv */
        if (!uv_moves) continue;
        double a0 = sc_orient2(oldW[0], oldW[1], oldW[2]), a1 = sc_orient2(W[0], W[1], W[2]);
        double umax = 0;
        for (int k = 0; k < 3; k++) {
            double e = sc_dist2(W[k], W[(k + 1) % 3]);
            if (e > umax) umax = e;
        }
        if (!(fabs(a1) > 1e-10 * umax * umax)) return BLOCK_UV_FLIP;
        if (!(a0 * a1 > 0)) return BLOCK_UV_FLIP;
    }
    return BLOCK_NONE;
}

/* Face f's corners after plan p: positions and uvs. */
static void planned_face(const state *st, const collapse_plan *p, int32_t f, const double *P[3], const double *W[3]) {
    for (int k = 0; k < 3; k++) {
        int32_t x = st->fv[3 * f + k], z = st->fz[3 * f + k];
        const double *w = moved_uv(p, z);
        P[k] = (x == p->keep || x == p->gone) ? p->xyz : st->pos + 3 * x;
        W[k] = w ? w : st->zuv + 2 * z;
    }
}

/* The level's point at input uv `uv` after plan p: the surviving face
 * around keep or gone whose uv triangle holds it best (barycentrics
 * clamped to the face), as placed by the plan. False when none comes within
 * 1% of holding it (it lies in faces the plan does not change). */
static bool point_after(state *st, const collapse_plan *p, const double uv[2], double at[3]) {
    double best = -HUGE_VAL;
    fan_walk walk = {0};
    for (int32_t f; (f = fan_next(st, p, &walk)) >= 0;) {
        const double *P[3], *W[3];
        planned_face(st, p, f, P, W);
        double d = sc_orient2(W[0], W[1], W[2]);
        if (d == 0) continue;
        double l[3] = {sc_orient2(uv, W[1], W[2]) / d, sc_orient2(W[0], uv, W[2]) / d, 0};
        l[2] = 1 - l[0] - l[1];
        double worst = fmin(l[0], fmin(l[1], l[2]));
        if (!(worst > best)) continue;
        best = worst;
        double sum = 0;
        for (int k = 0; k < 3; k++) l[k] = fmax(l[k], 0), sum += l[k];
        for (int k = 0; k < 3; k++) at[k] = (l[0] * P[0][k] + l[1] * P[1][k] + l[2] * P[2][k]) / sum;
    }
    return best > -1e-2;
}

/* Whether the input silhouette vertices that surface vertex v stands for
 * stay within seam_error of the level after plan p, at each of their uvs
 * that the plan's faces hold. */
static bool owned_silhouette_kept(state *st, const collapse_plan *p, int32_t v) {
    const double *c = st->center;
    for (int32_t i = st->owned_head[v]; i >= 0; i = st->owned_next[i])
        for (int32_t z = st->input_z_first[i]; z >= 0; z = st->input_z_next[z]) {
            double at[3];
            if (!point_after(st, p, st->input_zuv + 2 * z, at)) continue;
            double d2 = 0;
            for (int k = 0; k < 3; k++) {
                double e = st->input->V[3 * (size_t)i + k] - c[k] - at[k];
                d2 += e * e;
            }
            if (d2 > st->seam_error2) return false;
        }
    return true;
}

/* With map_size (design note): the input's vertices on uv silhouettes stay
 * within seam_error of the level at the same uv. The plan changes the faces
 * around keep and gone, so it is measured on the vertices those faces stand
 * for: keep's, gone's and their neighbours' (those on a silhouette: an
 * input silhouette vertex is only ever merged into one). */
static bool seam_kept(state *st, const collapse_plan *p) {
    if (!owned_silhouette_kept(st, p, p->keep) || !owned_silhouette_kept(st, p, p->gone)) return false;
    uint32_t mark = fresh_mark(st);   /* each neighbour once */
    for (int side = 0; side < 2; side++) {
        int32_t n;
        const int32_t *list = vfaces(st, side ? p->gone : p->keep, &n);
        for (int32_t j = 0; j < n; j++)
            for (int k = 0; k < 3; k++) {
                int32_t x = st->fv[3 * list[j] + k], z = st->fz[3 * list[j] + k];
                if (x == p->keep || x == p->gone || !(st->zflags[z] & Z_SILHOUETTE) || st->vmark[x] == mark) continue;
                st->vmark[x] = mark;
                if (!owned_silhouette_kept(st, p, x)) return false;
            }
    }
    return true;
}

/* The surviving face other than f on surface edge (x, y) after plan p, or
 * -1 (a border, or more than one). An endpoint that is keep or gone stands
 * for both. */
static int32_t face_across(const state *st, const collapse_plan *p, int32_t f, int32_t x, int32_t y) {
    bool xm = x == p->keep || x == p->gone, ym = y == p->keep || y == p->gone, merged = xm || ym;
    if (xm && ym) return -1;
    int32_t found = -1, faces[3], other = xm ? y : x;
    for (int e = 0; e < (merged ? 2 : 1); e++) {
        int n = merged ? edge_faces(st, e ? p->gone : p->keep, other, faces) : edge_faces(st, x, y, faces);
        for (int i = 0; i < n && i < 3; i++) {
            if (faces[i] == f || is_removed(p, faces[i])) continue;
            if (found >= 0 && found != faces[i]) return -1;
            found = faces[i];
        }
    }
    return found;
}

static bool in_fan(const state *st, const collapse_plan *p, int32_t f) {
    for (int k = 0; k < 3; k++)
        if (st->fv[3 * f + k] == p->keep || st->fv[3 * f + k] == p->gone) return true;
    return false;
}

/* With map_size (design note): every edge of the faces around keep and
 * gone after plan p whose two faces share its uv (a seam is no crease to
 * either side's texels) keeps its dihedral angle (radians) times the longer
 * texel span of the two faces (uv_stretch / map_size) within crease_limit.
 * An edge between two faces of the fan is measured from the lower one. */
static bool creases_ok(state *st, const collapse_plan *p) {
    fan_walk walk = {0};
    for (int32_t f; (f = fan_next(st, p, &walk)) >= 0;) {
        const double *P[3], *W[3], *Q[3], *X[3];
        planned_face(st, p, f, P, W);
        double nf[3], stretch_f = uv_stretch(P, W);
        sc_triangle_normal(P[0], P[1], P[2], nf);
        for (int k = 0; k < 3; k++) {
            int32_t g = face_across(st, p, f, st->fv[3 * f + k], st->fv[3 * f + (k + 1) % 3]);
            if (g < 0 || (g < f && in_fan(st, p, g))) continue;
            planned_face(st, p, g, Q, X);
            const double *wa = W[k], *wb = W[(k + 1) % 3];
            int shared = 0;
            for (int i = 0; i < 3; i++)
                shared += (X[i][0] == wa[0] && X[i][1] == wa[1]) + (X[i][0] == wb[0] && X[i][1] == wb[1]);
            if (shared < 2) continue;
            double ng[3], c[3];
            sc_triangle_normal(Q[0], Q[1], Q[2], ng);
            sc_cross3(nf, ng, c);
            double angle = atan2(sqrt(sc_dot3(c, c)), sc_dot3(nf, ng));
            if (angle * fmax(stretch_f, uv_stretch(Q, X)) / st->map_size > st->crease_limit) return false;
        }
    }
    return true;
}

/* ---------------------------------------------------------------- crossings */

/* min and max of finite values (and infinities), inlined: fmin and fmax are
 * library calls here, and the crossing tests make millions. */
static inline double min2(double a, double b) { return a < b ? a : b; }
static inline double max2(double a, double b) { return a > b ? a : b; }
static inline float min2f(float a, float b) { return a < b ? a : b; }
static inline float max2f(float a, float b) { return a > b ? a : b; }

/* The signed distances d of T's corners from the plane through o with
 * normal n of length len, those within eps set to 0; how many lie above and
 * below. */
static void plane_sides(const double *const T[3], const double *o, const double *n, double len, double eps,
                        double d[3], int *above, int *below) {
    *above = *below = 0;
    for (int k = 0; k < 3; k++) {
        double x[3];
        sc_sub3(T[k], o, x);
        d[k] = sc_dot3(n, x) / len;
        if (fabs(d[k]) <= eps) d[k] = 0;
        *above += d[k] > 0, *below += d[k] < 0;
    }
}

static void crossing_prepare(const double *const P[3], crossing_triangle *t) {
    for (int k = 0; k < 3; k++) t->P[k] = P[k];
    sc_triangle_normal(P[0], P[1], P[2], t->n);
    t->len = sc_norm3(t->n);
    t->longest = 0;
    for (int k = 0; k < 3; k++) t->longest = max2(t->longest, sc_dist3(P[k], P[(k + 1) % 3]));
}

/* Whether triangles A and B cross: each meets the other's plane, and the
 * segments where they meet the line of the two planes overlap by more than
 * a billionth of their size. Triangles in one plane, or that only touch,
 * do not cross. */
static bool triangles_cross(const crossing_triangle *A, const crossing_triangle *B) {
    double da[3], db[3], eps = 1e-9 * max2(A->longest, B->longest);
    if (!(A->len > 0 && B->len > 0)) return false;
    int above, below;
    plane_sides(A->P, B->P[0], B->n, B->len, eps, da, &above, &below);
    if (above == 3 || below == 3 || (above == 0 && below == 0)) return false;
    plane_sides(B->P, A->P[0], A->n, A->len, eps, db, &above, &below);
    if (above == 3 || below == 3) return false;
    /* both meet the line of the planes; compare their segments on its longest axis */
    double line[3];
    sc_cross3(A->n, B->n, line);
    int axis = fabs(line[0]) > fabs(line[1]) ? (fabs(line[0]) > fabs(line[2]) ? 0 : 2) : (fabs(line[1]) > fabs(line[2]) ? 1 : 2);
    double seg[2][2];
    for (int t = 0; t < 2; t++) {
        const double *const *T = t ? B->P : A->P;
        const double *d = t ? db : da;
        double lo = INFINITY, hi = -INFINITY;
        for (int k = 0; k < 3; k++) {
            int j = (k + 1) % 3;
            if (d[k] == 0) lo = min2(lo, T[k][axis]), hi = max2(hi, T[k][axis]);
            if ((d[k] > 0 && d[j] < 0) || (d[k] < 0 && d[j] > 0)) {
                double x = T[k][axis] + (T[j][axis] - T[k][axis]) * d[k] / (d[k] - d[j]);
                lo = min2(lo, x), hi = max2(hi, x);
            }
        }
        seg[t][0] = lo, seg[t][1] = hi;
    }
    return min2(seg[0][1], seg[1][1]) - max2(seg[0][0], seg[1][0]) > eps;
}

/* Whether Q's corners all lie on one side of A's plane, farther from it than
 * triangles_cross's tolerance could be for a triangle whose longest edge is
 * at most q_size: then the two do not cross (Q not yet prepared). */
static bool one_side(const crossing_triangle *A, const double *const Q[3], double q_size) {
    if (!(A->len > 0)) return true;
    double d[3];
    int above, below;
    plane_sides(Q, A->P[0], A->n, A->len, 1e-9 * max2(A->longest, q_size), d, &above, &below);
    return above == 3 || below == 3;
}

static void grid_free(face_grid *g) {
    for (int l = 0; l < GRID_LEVELS; l++) {
        grid_level *L = &g->level[l];
        int64_t cells = (int64_t)L->n[0] * L->n[1] * L->n[2];
        for (int64_t c = 0; L->cells && c < cells; c++) free(L->cells[c].items);
        free(L->cells);
    }
    free(g->big.items), free(g->home), free(g->slot), free(g->found);
    free(g->fan), free(g->fan_box), free(g->met), free(g->old_fan);
    memset(g, 0, sizeof *g);
}

/* The cell range [c0, c1] of a bounding box on level L, clamped to it. */
static void grid_range(const face_grid *g, const grid_level *L, const double lo[3], const double hi[3], int32_t c0[3],
                       int32_t c1[3]) {
    for (int k = 0; k < 3; k++) {   /* truncation is floor where it is not clamped */
        double a = (lo[k] - g->lo[k]) * L->inv_cell, b = (hi[k] - g->lo[k]) * L->inv_cell;
        c0[k] = !(a >= 0) ? 0 : a >= L->n[k] ? L->n[k] - 1 : (int32_t)a;
        c1[k] = !(b >= 0) ? 0 : b >= L->n[k] ? L->n[k] - 1 : (int32_t)b;
    }
}

static void triangle_box(const double *const P[3], double lo[3], double hi[3]) {
    for (int k = 0; k < 3; k++) {
        lo[k] = min2(P[0][k], min2(P[1][k], P[2][k]));
        hi[k] = max2(P[0][k], max2(P[1][k], P[2][k]));
    }
}

/* Four floats compared at once (GCC and Clang vector extensions). */
typedef float float4 __attribute__((vector_size(16)));
typedef int32_t int4 __attribute__((vector_size(16)));

static float4 load4(const float *x) {
    float4 v;
    memcpy(&v, x, sizeof v);
    return v;
}

static float4 splat4(float x) { return (float4){x, x, x, x}; }

/* Which of n boxes (rows lo x, y, z, hi x, y, z of `stride`, a multiple of
 * 4, padded with empty boxes) meet the box (lo, hi): their indices into
 * met, their count returned. Four at a time and without branches, as about
 * half of them meet at random. */
static int32_t boxes_meeting(const float *rows, int32_t stride, int32_t n, const float lo[3], const float hi[3],
                             int32_t *met) {
    float4 lo0 = splat4(lo[0]), lo1 = splat4(lo[1]), lo2 = splat4(lo[2]);
    float4 hi0 = splat4(hi[0]), hi1 = splat4(hi[1]), hi2 = splat4(hi[2]);
    int32_t count = 0;
    for (int32_t a = 0; a < n; a += 4) {
        int4 meets = ~(load4(rows + a) > hi0) & ~(load4(rows + 3 * stride + a) < lo0) &
                     ~(load4(rows + stride + a) > hi1) & ~(load4(rows + 4 * stride + a) < lo1) &
                     ~(load4(rows + 2 * stride + a) > hi2) & ~(load4(rows + 5 * stride + a) < lo2);
        for (int i = 0; i < 4; i++) {
            met[count] = a + i;
            count += (meets[i] != 0) & (a + i < n);
        }
    }
    return count;
}

/* Whether box (alo, ahi) meets box (lo, hi), without branches. */
static inline bool box_meets(const float alo[3], const float ahi[3], const float lo[3], const float hi[3]) {
    return !(alo[0] > hi[0]) & !(ahi[0] < lo[0]) & !(alo[1] > hi[1]) & !(ahi[1] < lo[1]) & !(alo[2] > hi[2]) &
           !(ahi[2] < lo[2]);
}

/* x rounded to float downwards (upwards): a rounding past x is taken back
 * by at least one step (|f| FLT_EPSILON is one or two units in f's last place). */
static float float_below(double x) {
    float f = (float)x;
    return (double)f > x ? f - (fabsf(f) * FLT_EPSILON + FLT_MIN) : f;
}

static float float_above(double x) {
    float f = (float)x;
    return (double)f < x ? f + (fabsf(f) * FLT_EPSILON + FLT_MIN) : f;
}

static void face_points(const state *st, int32_t f, const double *P[3]) {
    for (int k = 0; k < 3; k++) P[k] = st->pos + 3 * st->fv[3 * f + k];
}

/* Take face f out of the grid (when it is in): its cell's last item takes
 * its place. */
static void grid_take_out(face_grid *g, int32_t f) {
    grid_cell *c = g->home[f];
    if (!c) return;
    int32_t i = g->slot[f];
    c->items[i] = c->items[--c->len];
    g->slot[c->items[i].face] = i;
    g->home[f] = NULL;
    if (c->len == 0)
        for (int k = 0; k < 3; k++) c->lo[k] = INFINITY, c->hi[k] = -INFINITY;
}

/* Put face f in the grid at its current positions; false when out of memory. */
static bool grid_put(state *st, int32_t f) {
    face_grid *g = &st->grid;
    const double *P[3];
    double lo[3], hi[3], centre[3], half = 0;
    grid_take_out(g, f);
    face_points(st, f, P);
    triangle_box(P, lo, hi);
    grid_item item = {.face = f};
    for (int k = 0; k < 3; k++) {
        item.v[k] = st->fv[3 * f + k];
        item.lo[k] = float_below(lo[k]), item.hi[k] = float_above(hi[k]);
        /* of the float box, which queries compare: its centre is within `half` of every box it meets */
        centre[k] = 0.5 * ((double)item.lo[k] + item.hi[k]);
        half = max2(half, 0.5 * ((double)item.hi[k] - item.lo[k]));
    }
    grid_cell *c = &g->big;
    int l = 0;   /* the finest level whose cells are as long as half: one long face would widen every query there */
    while (l < GRID_LEVELS && !(half <= g->level[l].cell)) l++;
    if (l < GRID_LEVELS) {
        grid_level *L = &g->level[l];
        int32_t c0[3], c1[3];
        grid_range(g, L, centre, centre, c0, c1);
        c = &L->cells[((int64_t)c0[2] * L->n[1] + c0[1]) * L->n[0] + c0[0]];
        L->reach = max2(L->reach, half);
        L->items++;
        for (int k = 0; k < 3; k++) L->lo[k] = min2f(L->lo[k], item.lo[k]), L->hi[k] = max2f(L->hi[k], item.hi[k]);
    }
    if (c->len == c->cap) {
        int32_t cap = c->cap ? 2 * c->cap : 4;
        grid_item *items = realloc(c->items, (size_t)cap * sizeof *items);
        if (!items) return false;
        c->items = items, c->cap = cap;
    }
    g->home[f] = c, g->slot[f] = c->len;
    c->items[c->len++] = item;
    for (int k = 0; k < 3; k++) c->lo[k] = min2f(c->lo[k], item.lo[k]), c->hi[k] = max2f(c->hi[k], item.hi[k]);
    return true;
}

/* Cell c's live items whose boxes meet (lo, hi), appended to g->found at
 * *n; false when out of memory. */
static bool cell_query(face_grid *g, const grid_cell *c, const float lo[3], const float hi[3], int32_t *n) {
    if (c->len == 0 || !box_meets(c->lo, c->hi, lo, hi)) return true;
    if (*n + c->len > g->found_cap) {
        int32_t cap = 2 * (*n + c->len);
        const grid_item **found = realloc(g->found, (size_t)cap * sizeof *found);
        if (!found) return false;
        g->found = found, g->found_cap = cap;
    }
    for (int32_t x = 0; x < c->len; x++) {
        const grid_item *it = &c->items[x];
        g->found[*n] = it;
        *n += box_meets(it->lo, it->hi, lo, hi);
    }
    return true;
}

/* The live items whose boxes meet (lo, hi) into g->found: those of the
 * cells within reach on each level, finest first, then the big faces;
 * their count, -1 out of memory. */
static int32_t grid_query(face_grid *g, const float lo[3], const float hi[3]) {
    int32_t n = 0;
    for (int l = 0; l < GRID_LEVELS; l++) {
        const grid_level *L = &g->level[l];
        if (L->items == 0 || !box_meets(L->lo, L->hi, lo, hi)) continue;
        double qlo[3], qhi[3];
        int32_t c0[3], c1[3];
        double reach = L->reach * (1 + 1e-9);   /* past the rounding of the sums below */
        for (int k = 0; k < 3; k++) qlo[k] = (double)lo[k] - reach, qhi[k] = (double)hi[k] + reach;
        grid_range(g, L, qlo, qhi, c0, c1);
        for (int32_t k = c0[2]; k <= c1[2]; k++)
            for (int32_t j = c0[1]; j <= c1[1]; j++)
                for (int32_t i = c0[0]; i <= c1[0]; i++)
                    if (!cell_query(g, &L->cells[((int64_t)k * L->n[1] + j) * L->n[0] + i], lo, hi, &n)) return -1;
    }
    return cell_query(g, &g->big, lo, hi, &n) ? n : -1;
}

/* The grid over the live faces: the finest level's cells twice their mean
 * edge long, at most about four per face; each next level's four times
 * longer. */
static bool grid_build(state *st) {
    face_grid *g = &st->grid;
    grid_free(g);
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY}, edges = 0;
    int64_t nedges = 0;
    for (int32_t f = 0; f < st->nf; f++) {
        if (!st->falive[f]) continue;
        const double *P[3];
        face_points(st, f, P);
        for (int k = 0; k < 3; k++) {
            for (int d = 0; d < 3; d++) lo[d] = min2(lo[d], P[k][d]), hi[d] = max2(hi[d], P[k][d]);
            edges += sc_dist3(P[k], P[(k + 1) % 3]), nedges++;
        }
    }
    if (nedges == 0) return true;
    double cell = 2 * edges / (double)nedges, volume = 1;
    for (int d = 0; d < 3; d++) volume *= fmax(hi[d] - lo[d], cell);
    double most = 4.0 * st->nf_alive + 64;
    if (volume / (cell * cell * cell) > most) cell = cbrt(volume / most);
    if (!(cell > 0)) cell = 1;
    for (int d = 0; d < 3; d++) g->lo[d] = lo[d];
    g->on = true;
    for (int l = 0; l < GRID_LEVELS; l++, cell *= 4) {
        grid_level *L = &g->level[l];
        for (int d = 0; d < 3; d++) L->n[d] = (int32_t)fmin(fmax(ceil((hi[d] - lo[d]) / cell), 1), 1 << 20);
        L->cell = cell, L->inv_cell = 1 / cell;
        int64_t cells = (int64_t)L->n[0] * L->n[1] * L->n[2];
        L->cells = calloc((size_t)cells, sizeof *L->cells);
        if (!L->cells) return false;
        for (int64_t c = 0; c < cells; c++)
            for (int k = 0; k < 3; k++) L->cells[c].lo[k] = INFINITY, L->cells[c].hi[k] = -INFINITY;
        for (int k = 0; k < 3; k++) L->lo[k] = INFINITY, L->hi[k] = -INFINITY;
    }
    g->home = calloc((size_t)st->nf, sizeof *g->home);
    g->slot = calloc((size_t)st->nf, sizeof *g->slot);
    if (!g->home || !g->slot) return false;
    for (int k = 0; k < 3; k++) g->big.lo[k] = INFINITY, g->big.hi[k] = -INFINITY;
    g->built_faces = st->nf_alive;
    for (int32_t f = 0; f < st->nf; f++)
        if (st->falive[f] && !grid_put(st, f)) return false;
    return true;
}

static bool shares_vertex(const int32_t *a, const int32_t *b) {
    int same = 0;   /* without branches: which pairs agree is random */
    for (int i = 0; i < 3; i++) same |= (a[i] == b[0]) | (a[i] == b[1]) | (a[i] == b[2]);
    return same != 0;
}

/* The faces around keep and gone as they are now, prepared for crossing
 * tests into the grid's old_fan (once per query, at its first crossing);
 * false when out of memory. */
static bool old_fan_prepare(state *st, const collapse_plan *p) {
    face_grid *grid = &st->grid;
    int32_t need = st->vf_len[p->keep] + st->vf_len[p->gone];
    if (need > grid->old_cap) {
        fan_entry *old = realloc(grid->old_fan, (size_t)need * sizeof *old);
        if (!old) return false;
        grid->old_fan = old, grid->old_cap = need;
    }
    grid->nold = 0;
    for (int side = 0; side < 2; side++) {
        int32_t n;
        const int32_t *list = vfaces(st, side ? p->gone : p->keep, &n);
        for (int32_t i = 0; i < n; i++) {
            int32_t f = list[i];
            if (!st->falive[f]) continue;
            fan_entry *e = &grid->old_fan[grid->nold++];
            const double *P[3];
            face_points(st, f, P);
            crossing_prepare(P, &e->T);
            for (int k = 0; k < 3; k++) e->v[k] = st->fv[3 * f + k];
        }
    }
    return true;
}

/* Whether face g (outside the fan; TG, prepared) crosses a face around
 * keep or gone now (the grid's old_fan, prepared). */
static bool crossed_before(const state *st, int32_t g, const crossing_triangle *TG) {
    const face_grid *grid = &st->grid;
    for (int32_t i = 0; i < grid->nold; i++) {
        const fan_entry *e = &grid->old_fan[i];
        if (shares_vertex(e->v, st->fv + 3 * g)) continue;
        if (triangles_cross(&e->T, TG)) return true;
    }
    return false;
}

static bool grow_met(face_grid *grid, int32_t need) {
    int32_t *met = realloc(grid->met, (size_t)2 * need * sizeof *met);
    if (!met) return false;
    grid->met = met, grid->met_cap = 2 * need;
    return true;
}

/* No face around the collapse passes through a face it shares no vertex
 * with, after plan p, unless it did before. The grid is asked once for the
 * faces meeting the box of the new fan; each is tested against the fan's
 * faces whose boxes it meets. */
static bool crossings_ok(state *st, const collapse_plan *p) {
    face_grid *grid = &st->grid;
    if (!grid->on) return true;
    int32_t need = st->vf_len[p->keep] + st->vf_len[p->gone];
    if (need > grid->fan_cap) {
        fan_entry *fan = realloc(grid->fan, (size_t)need * sizeof *fan);
        if (fan) grid->fan = fan;
        float *box = realloc(grid->fan_box, (size_t)(need + 3) / 4 * 4 * 6 * sizeof *box);
        if (box) grid->fan_box = box;
        if (!fan || !box) {
            st->out_of_memory = true;
            return false;
        }
        grid->fan_cap = need;
    }
    double all_lo[3] = {INFINITY, INFINITY, INFINITY}, all_hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    int32_t nfan = 0, stride = (grid->fan_cap + 3) / 4 * 4;
    fan_walk walk = {0};
    for (int32_t f; (f = fan_next(st, p, &walk)) >= 0 && nfan < need; nfan++) {
        fan_entry *e = &grid->fan[nfan];
        const double *P[3], *W[3];
        double lo[3], hi[3];
        planned_face(st, p, f, P, W);
        crossing_prepare(P, &e->T);
        for (int k = 0; k < 3; k++) e->v[k] = st->fv[3 * f + k] == p->gone ? p->keep : st->fv[3 * f + k];
        triangle_box(P, lo, hi);
        for (int k = 0; k < 3; k++) {
            grid->fan_box[k * stride + nfan] = float_below(lo[k]);
            grid->fan_box[(3 + k) * stride + nfan] = float_above(hi[k]);
            all_lo[k] = min2(all_lo[k], lo[k]), all_hi[k] = max2(all_hi[k], hi[k]);
        }
    }
    for (int32_t a = nfan; a % 4; a++)   /* empty boxes up to a multiple of 4 */
        for (int k = 0; k < 3; k++) grid->fan_box[k * stride + a] = INFINITY, grid->fan_box[(3 + k) * stride + a] = -INFINITY;
    const int32_t fan_ends[3] = {p->keep, p->gone, p->gone};
    /* boxes compare as floats: rounded outwards, they only let more through */
    float lo[3], hi[3];
    for (int k = 0; k < 3; k++) lo[k] = float_below(all_lo[k]), hi[k] = float_above(all_hi[k]);
    int32_t nfound = grid_query(grid, lo, hi);
    if (nfound < 0 || (nfan + 4 > grid->met_cap && !grow_met(grid, nfan + 4))) {
        st->out_of_memory = true;
        return false;
    }
    bool old_prepared = false;
    for (int32_t x = 0; x < nfound; x++) {
        const grid_item *it = grid->found[x];
        int32_t g = it->face;
        if (shares_vertex(it->v, fan_ends)) continue;   /* a face of the fan */
        crossing_triangle TG;
        bool prepared = false;
        int before = -1;   /* whether g crossed the old fan: unknown until it crosses the new */
        const double *Q[3] = {NULL, NULL, NULL};
        double g_size = 0;
        int32_t nmet = boxes_meeting(grid->fan_box, stride, nfan, it->lo, it->hi, grid->met);
        for (int32_t m = 0; m < nmet; m++) {
            const fan_entry *e = &grid->fan[grid->met[m]];
            if (shares_vertex(e->v, it->v)) continue;
            if (!Q[0]) {
                face_points(st, g, Q);
                /* at least g's longest edge: the sum of its box's sides */
                g_size = ((double)it->hi[0] - it->lo[0]) + ((double)it->hi[1] - it->lo[1]) +
                         ((double)it->hi[2] - it->lo[2]);
            }
            if (one_side(&e->T, Q, g_size)) continue;
            if (!prepared) {
                crossing_prepare(Q, &TG);
                prepared = true;
            }
            if (!triangles_cross(&e->T, &TG)) continue;
            if (before < 0) {
                if (!old_prepared && !old_fan_prepare(st, p)) {
                    st->out_of_memory = true;
                    return false;
                }
                old_prepared = true;
                before = crossed_before(st, g, &TG);
            }
            if (!before) return false;
        }
    }
    return true;
}

static int32_t find_root(int32_t *parent, int32_t x) {
    while (parent[x] != x) x = parent[x] = parent[parent[x]];
    return x;
}

/* Face P's nearest point to x, kept in *d (distance) and *side (x's height
 * over that face's plane, along its normal) when nearer than *d. Faces as
 * near (to 1e-9, as when the nearest point is a corner or an edge they
 * share) keep the largest height, so the result does not depend on the
 * order faces come in. */
static void nearer_face(const double x[3], const double *const P[3], double *d, double *side) {
    double q[3];
    sc_hausdorff_closest_on_triangle(x, P[0], P[1], P[2], q);
    double dist = sc_dist3(x, q);
    if (!(dist <= *d * (1 + 1e-9))) return;
    double e1[3], e2[3], n[3], r[3];
    for (int k = 0; k < 3; k++) e1[k] = P[1][k] - P[0][k], e2[k] = P[2][k] - P[0][k], r[k] = x[k] - q[k];
    sc_cross3(e1, e2, n);
    double len = sc_norm3(n);
    double h = len > 0 ? sc_dot3(r, n) / len : 0;
    bool tie = dist >= *d * (1 - 1e-9);
    *side = tie ? max2(*side, h) : h;
    *d = min2(*d, dist);
}

/* The nearest face to x of another part than `own` within `reach` (grid
 * cells around x), skipping the faces around `keep` and `gone` (a plan's
 * old fan, or -1): its distance in *d (INFINITY when none is that near) and
 * x's height over it in *side. */
static void other_part_nearest(state *st, const double x[3], int32_t own, double reach, int32_t keep, int32_t gone,
                               double *d, double *side) {
    face_grid *g = &st->grid;
    float lo[3], hi[3];
    for (int k = 0; k < 3; k++) lo[k] = float_below(x[k] - reach), hi[k] = float_above(x[k] + reach);
    *d = INFINITY, *side = 0;
    int32_t nfound = grid_query(g, lo, hi);
    if (nfound < 0) st->out_of_memory = true;
    for (int32_t n = 0; n < nfound; n++) {
        const grid_item *it = g->found[n];
        if (st->part[it->v[0]] == own) continue;
        bool in_fan = false;
        for (int e = 0; e < 3; e++) in_fan |= it->v[e] == keep || it->v[e] == gone;
        if (in_fan) continue;
        double box2 = 0;   /* x's distance to the face's box: no nearer point inside */
        for (int e = 0; e < 3; e++) {
            double out = max2(max2((double)it->lo[e] - x[e], x[e] - (double)it->hi[e]), 0);
            box2 += out * out;
        }
        if (box2 > *d * *d * (1 + 1e-8)) continue;   /* (a face as near stays: nearer_face) */
        const double *P[3];
        face_points(st, it->face, P);
        nearer_face(x, P, d, side);
    }
    if (!(*d <= reach)) *d = INFINITY, *side = 0;
}

/* Contact v is where it is now: the box of the contacts' reach and the
 * longest edge between two contacts hold it. */
static void contact_moved(state *st, int32_t v) {
    const double *x = st->pos + 3 * v;
    double reach = st->contact_reach[v];
    for (int k = 0; k < 3; k++)
        st->contact_lo[k] = fmin(st->contact_lo[k], x[k] - reach), st->contact_hi[k] = fmax(st->contact_hi[k], x[k] + reach);
    int32_t n;
    const int32_t *list = vfaces(st, v, &n);
    for (int32_t i = 0; i < n; i++) {
        if (!st->falive[list[i]]) continue;
        for (int k = 0; k < 3; k++) {
            int32_t w = st->fv[3 * list[i] + k];
            if (w != v && (st->vflags[w] & V_CONTACT)) st->contact_edge = fmax(st->contact_edge, sc_dist3(x, st->pos + 3 * w));
        }
    }
}

/* The open parts' border vertices within contact_distance of another
 * connected part (a sleeve's rim on a bottle, a seed's rim in the fruit's
 * cut), each with its limits (the state's note). Returns false when out of
 * memory. */
static bool find_contacts(state *st) {
    st->part = malloc((size_t)st->nv * sizeof *st->part);
    st->contacts = malloc((size_t)st->nv * sizeof *st->contacts);
    st->contact_reach = malloc((size_t)st->nv * sizeof *st->contact_reach);
    st->contact_rise = malloc((size_t)st->nv * sizeof *st->contact_rise);
    if (!st->part || !st->contacts || !st->contact_reach || !st->contact_rise) return false;
    int32_t *part = st->part;
    for (int32_t v = 0; v < st->nv; v++) part[v] = v;
    for (int32_t f = 0; f < st->nf; f++) {
        const int32_t *c = st->fv + 3 * f;
        for (int k = 0; k < 2; k++) {
            int32_t x = find_root(part, c[k]), y = find_root(part, c[k + 1]);
            if (x != y) part[x] = y;
        }
    }
    for (int32_t v = 0; v < st->nv; v++) part[v] = find_root(part, v);
    for (int k = 0; k < 3; k++) st->contact_lo[k] = INFINITY, st->contact_hi[k] = -INFINITY;
    for (int32_t v = 0; v < st->nv; v++) {
        if (!(st->vflags[v] & V_BOUNDARY)) continue;
        const double *x = st->pos + 3 * v;
        double d, side;
        other_part_nearest(st, x, part[v], st->contact_distance, -1, -1, &d, &side);
        if (!(d <= st->contact_distance)) continue;
        double reach = d + st->contact_slack;
        st->contacts[st->ncontacts++] = v;
        st->contact_reach[v] = reach;
        st->contact_rise[v] = side + st->contact_slack;
        st->vflags[v] |= V_CONTACT;
    }
    st->input_contacts = st->ncontacts;
    for (int32_t i = 0; i < st->ncontacts; i++) {
        int32_t v = st->contacts[i];
        st->contact_reach_max = fmax(st->contact_reach_max, st->contact_reach[v]);
        contact_moved(st, v);
    }
    return true;
}

/* x's distance to the parts other than `own` after plan p (the grid's faces
 * within `reach`, the old fan replaced by the new when p changes one of
 * them), and its height over the nearest face. */
static void nearest_after(state *st, const collapse_plan *p, const double x[3], int32_t own, double reach, double *d,
                          double *side) {
    bool other = st->part[p->keep] != own;
    other_part_nearest(st, x, own, reach, other ? p->keep : -1, other ? p->gone : -1, d, side);
    if (!other) return;
    fan_walk walk = {0};
    for (int32_t f; (f = fan_next(st, p, &walk)) >= 0;) {
        const double *P[3], *W[3];
        planned_face(st, p, f, P, W);
        nearer_face(x, P, d, side);
    }
}

/* The border neighbours of v after plan p (for keep or gone, those of the
 * vertex they become): the vertices joined to it by an edge of one face.
 * Returns their count, of which at most 2 go to out. */
static int border_neighbours_after(const state *st, const collapse_plan *p, int32_t v, int32_t out[2]) {
    int32_t seen[2 * MAX_FAN + 4];
    int count[2 * MAX_FAN + 4], nseen = 0;
    bool merged = v == p->keep || v == p->gone;
    fan_walk walk = {0};
    int32_t n = 0, i = 0;
    const int32_t *list = merged ? NULL : vfaces(st, v, &n);
    for (;;) {
        int32_t f;
        if (merged) f = fan_next(st, p, &walk);
        else {
            while (i < n && (!st->falive[list[i]] || is_removed(p, list[i]))) i++;
            f = i < n ? list[i++] : -1;
        }
        if (f < 0) break;
        for (int k = 0; k < 3; k++) {
            int32_t x = st->fv[3 * f + k];
            if (x == v || (merged && (x == p->keep || x == p->gone))) continue;
            if (x == p->gone) x = p->keep;
            int j = 0;
            while (j < nseen && seen[j] != x) j++;
            if (j == nseen) {
                if (nseen == 2 * MAX_FAN + 4) return 3;
                seen[nseen] = x, count[nseen++] = 0;
            }
            count[j]++;
        }
    }
    int found = 0;
    for (int j = 0; j < nseen; j++)
        if (count[j] == 1) {
            if (found < 2) out[found] = seen[j];
            found++;
        }
    return found;
}

/* The distance from x to the box (lo, hi). */
static double box_distance(const double lo[3], const double hi[3], const double x[3]) {
    double sum = 0;
    for (int k = 0; k < 3; k++) {
        double out = fmax(fmax(lo[k] - x[k], x[k] - hi[k]), 0);
        sum += out * out;
    }
    return sqrt(sum);
}

/* Whether point x (own part `own`), with limits reach and rise, is within
 * them after plan p, or no worse than before when `before` is set (a point
 * of a border edge the plan does not move, which may already be beyond
 * them: the other part's faces near it then may not move away). */
static bool contact_point_ok(state *st, const collapse_plan *p, const double x[3], int32_t own, double reach,
                             double rise, bool before) {
    double d, side;
    nearest_after(st, p, x, own, reach, &d, &side);
    if ((d <= reach && side <= rise) || !before) return d <= reach && side <= rise;
    double d0, side0;
    other_part_nearest(st, x, own, 4 * reach, -1, -1, &d0, &side0);
    if (!isfinite(d0)) return true;   /* not near the other parts at all */
    reach = fmax(reach, d0), rise = fmax(rise, side0);
    nearest_after(st, p, x, own, reach, &d, &side);
    return d <= reach && side <= rise;
}

/* The contacts and the border edges between them are within their limits
 * after plan p (the state's note). A contact the plan moves (keep or gone)
 * is checked at the new point, with the border edges of the vertex it
 * becomes; a contact next to keep or gone, whose border edge moves, on that
 * edge; the contacts of other parts when the plan's fan, before or after,
 * comes within their reach. A contact whose vertex collapses goes to the
 * vertex kept (apply_plan). */
static bool contacts_ok(state *st, const collapse_plan *p) {
    double lo[3], hi[3];
    for (int k = 0; k < 3; k++) lo[k] = hi[k] = p->xyz[k];
    for (int side = 0; side < 2; side++) {
        int32_t n;
        const int32_t *list = vfaces(st, side ? p->gone : p->keep, &n);
        for (int32_t i = 0; i < n; i++) {
            if (!st->falive[list[i]]) continue;
            const double *P[3];
            face_points(st, list[i], P);
            for (int c = 0; c < 3; c++)
                for (int k = 0; k < 3; k++) lo[k] = min2(lo[k], P[c][k]), hi[k] = max2(hi[k], P[c][k]);
        }
    }
    for (int k = 0; k < 3; k++)
        if (lo[k] > st->contact_hi[k] || hi[k] < st->contact_lo[k]) return true;
    const int32_t own = st->part[p->keep];
    for (int32_t i = 0; i < st->ncontacts; i++) {
        int32_t v = st->contacts[i];
        bool moves = v == p->keep || v == p->gone, same_part = st->part[v] == own;
        const double *x = moves ? p->xyz : st->pos + 3 * v;
        double reach = st->contact_reach[v], rise = st->contact_rise[v];
        if (!moves && !same_part) {   /* near the fan, or its border edges (at most contact_edge long)? */
            double r = st->contact_edge + 2 * st->contact_reach_max;
            bool near = true;
            for (int k = 0; k < 3; k++) near &= !(lo[k] > x[k] + r || hi[k] < x[k] - r);
            if (!near) continue;
        } else if (!moves) {   /* of the plan's part: only its edges to keep or gone move */
            int32_t n;
            const int32_t *list = vfaces(st, v, &n);
            bool next_to = false;
            for (int32_t f = 0; f < n && !next_to; f++)
                for (int k = 0; k < 3; k++) next_to |= st->fv[3 * list[f] + k] == p->keep || st->fv[3 * list[f] + k] == p->gone;
            if (!next_to) continue;
        }
        /* (a point farther from the fan than it may be from the other
         * parts keeps its nearest face: the plan changes nothing there) */
        if ((moves || (!same_part && box_distance(lo, hi, x) <= reach)) &&
            !contact_point_ok(st, p, x, st->part[v], reach, rise, false))
            return false;
        int32_t nb[2];
        int nn = border_neighbours_after(st, p, v, nb);
        if (nn > 2) continue;   /* a pinched border: its edges are not told apart */
        for (int e = 0; e < nn; e++) {
            int32_t w = nb[e];
            if (!(st->vflags[w] & V_CONTACT)) continue;
            bool w_moves = w == p->keep;   /* (gone is already keep here) */
            if (same_part && !moves && !w_moves) continue;   /* an edge of this part the plan leaves */
            const double *y = w_moves ? p->xyz : st->pos + 3 * w;
            double reach_e = max2(reach, st->contact_reach[w]), rise_e = max2(rise, st->contact_rise[w]);
            bool unmoved = !moves && !w_moves;   /* then compared with before, as far as 4 reach */
            for (int t = 1; t < 4; t++) {
                double s[3];
                for (int k = 0; k < 3; k++) s[k] = x[k] + 0.25 * t * (y[k] - x[k]);
                if (unmoved && box_distance(lo, hi, s) > 4 * reach_e) continue;
                if (!contact_point_ok(st, p, s, st->part[v], reach_e, rise_e, unmoved)) return false;
            }
        }
    }
    return true;
}

static block_reason check_plan(state *st, const collapse_plan *p) {
    if (!link_surface_ok(st, p)) return BLOCK_LINK_SURFACE;
    for (int i = 0; i < p->nhalf; i++)
        if (!link_uv_ok(st, p, &p->h[i])) return BLOCK_LINK_UV;
    if (!tip_merge_ok(st, p)) return BLOCK_LINK_UV;
    if (!valence_ok(st, p)) return BLOCK_VALENCE;
    block_reason r = flips_ok(st, p);
    if (r == BLOCK_NONE && st->crease_limit > 0 && !creases_ok(st, p)) r = BLOCK_TEXEL_CREASE;
    if (r == BLOCK_NONE && st->seam_error2 > 0 && !seam_kept(st, p)) r = BLOCK_SEAM_ERROR;
    if (r == BLOCK_NONE && st->refuse_crossings && !crossings_ok(st, p)) r = BLOCK_CROSSING;
    if (r == BLOCK_NONE && st->ncontacts > 0 && !contacts_ok(st, p)) r = BLOCK_CONTACT;
    return r;
}

/* ---------------------------------------------------------------- applying */

static void update_weight(state *st, int32_t z) {
    if (st->weights == WEIGHTS_AREA_DISTORTION)
        st->zweight[z] = sc_quadric_area_distortion(st->zgeo + 6 * (size_t)z, st->znormal + 3 * (size_t)z);
}

/* Z `gone` merges into Z `keep` (whose quadric already holds what it had). */
static void merge_z_attributes(state *st, int32_t keep, const int32_t *gone, int ngone) {
    double *qk = st->zq + (size_t)keep * QSIZE, *gk = st->zgeo + 6 * (size_t)keep;
    if (st->weights == WEIGHTS_AREA_DISTORTION) {
        /* Coll & Paradinas: (w_k Q_k + w_g Q_g) / (w_k + w_g) */
        double wk = st->zweight[keep], wsum = wk;
        for (int i = 0; i < ngone; i++) wsum += st->zweight[gone[i]];
        bool equal = !(wsum > 0);
        double sk = equal ? 1.0 / (ngone + 1) : wk / wsum;
        sc_quadric_scale(qk, QDIM, sk);
        for (int k = 0; k < 6; k++) gk[k] *= sk;
        for (int i = 0; i < ngone; i++) {
            double sg = equal ? 1.0 / (ngone + 1) : st->zweight[gone[i]] / wsum;
            sc_quadric_add(qk, st->zq + (size_t)gone[i] * QSIZE, QDIM, sg);
            for (int k = 0; k < 6; k++) gk[k] += sg * st->zgeo[6 * (size_t)gone[i] + k];
        }
    } else {
        for (int i = 0; i < ngone; i++) sc_quadric_add(qk, st->zq + (size_t)gone[i] * QSIZE, QDIM, 1.0);
    }
    for (int i = 0; i < ngone; i++) {
        st->zstep[keep] = fmax(st->zstep[keep], st->zstep[gone[i]]);
        for (int k = 0; k < 3; k++) st->znormal[3 * (size_t)keep + k] += st->znormal[3 * (size_t)gone[i] + k];
        st->zflags[keep] |= st->zflags[gone[i]];
        st->zv[gone[i]] = -1;
    }
    update_weight(st, keep);
}

/* Face f leaves v's list. A list of more than MAX_FAN faces keeps it, dead,
 * until half the list is dead, and is then compacted in order (removing
 * faces one at a time from a fan centre would walk the centre's list each
 * time); only such a list holds dead faces, and its readers (edge_faces,
 * vertex_neighbours) skip them. */
static void remove_from_list(state *st, int32_t v, int32_t f) {
    int32_t n;
    int32_t *list = vfaces(st, v, &n);
    if (n > MAX_FAN) {
        if (++st->vf_dead[v] * 2 > n) {
            int32_t alive = 0;
            for (int32_t i = 0; i < n; i++)
                if (st->falive[list[i]]) list[alive++] = list[i];
            st->vf_len[v] = alive;
            st->vf_dead[v] = 0;
        }
        return;
    }
    for (int32_t i = 0; i < n; i++)
        if (list[i] == f) {
            memmove(list + i, list + i + 1, sizeof(int32_t) * (size_t)(n - i - 1));
            st->vf_len[v]--;
            return;
        }
}

static bool merge_lists(state *st, int32_t keep, int32_t gone) {
    int32_t need = st->vf_len[keep] + st->vf_len[gone];
    if (need > st->vf_cap[keep]) {
        int32_t cap = need * 2 > 8 ? need * 2 : 8;
        if (st->pool_len + cap > st->pool_cap) {
            int64_t ncap = st->pool_cap * 2;
            while (ncap < st->pool_len + cap) ncap *= 2;
            int32_t *np = sc_realloc_array(st->pool, (size_t)ncap, sizeof *np);
            if (!np) return false;
            st->pool = np;
            st->pool_cap = ncap;
        }
        memcpy(st->pool + st->pool_len, st->pool + st->vf_off[keep], sizeof(int32_t) * (size_t)st->vf_len[keep]);
        st->vf_off[keep] = st->pool_len;
        st->vf_cap[keep] = cap;
        st->pool_len += cap;
    }
    int32_t *dst = st->pool + st->vf_off[keep];
    int32_t n = 0;
    for (int32_t i = 0; i < st->vf_len[keep]; i++)
        if (st->falive[dst[i]]) dst[n++] = dst[i];
    const int32_t *src = st->pool + st->vf_off[gone];
    for (int32_t i = 0; i < st->vf_len[gone]; i++)
        if (st->falive[src[i]]) dst[n++] = src[i];
    st->vf_len[keep] = n;
    st->vf_len[gone] = 0;
    return true;
}

static bool apply_plan(state *st, const collapse_plan *p) {
    int32_t keep = p->keep, gone = p->gone;
    if (st->grid.on)   /* the fans' faces move (or go): out of the grid at their old places */
        for (int side = 0; side < 2; side++) {
            int32_t n;
            const int32_t *list = vfaces(st, side ? gone : keep, &n);
            for (int32_t i = 0; i < n; i++)
                if (st->falive[list[i]]) grid_take_out(&st->grid, list[i]);
        }
    for (int i = 0; i < p->nfaces; i++) {
        int32_t f = p->faces[i];
        st->falive[f] = 0;
        st->nf_alive--;
        for (int k = 0; k < 3; k++) {
            int32_t x = st->fv[3 * f + k];
            if (x != keep && x != gone) remove_from_list(st, x, f);
        }
    }
    memcpy(st->pos + 3 * keep, p->xyz, sizeof p->xyz);
    if (st->importance && st->importance[gone] > st->importance[keep]) st->importance[keep] = st->importance[gone];
    if (st->stretch && st->stretch[gone] > st->stretch[keep]) st->stretch[keep] = st->stretch[gone];
    if (st->owned_head && st->owned_head[gone] >= 0) {   /* keep stands for gone's input vertices too */
        if (st->owned_head[keep] < 0) st->owned_head[keep] = st->owned_head[gone];
        else st->owned_next[st->owned_tail[keep]] = st->owned_head[gone];
        st->owned_tail[keep] = st->owned_tail[gone];
        st->owned_head[gone] = st->owned_tail[gone] = -1;
    }
    /* Z merges */
    if (p->nhalf == 2 && p->h[0].keep == p->h[1].keep) {
        int32_t gone_z[2] = {p->h[0].gone, p->h[1].gone};
        memcpy(st->zuv + 2 * p->h[0].keep, p->h[0].w, sizeof p->h[0].w);
        merge_z_attributes(st, p->h[0].keep, gone_z, 2);

    } else {
        for (int i = 0; i < p->nhalf; i++) {
            const half_plan *h = &p->h[i];
            memcpy(st->zuv + 2 * h->keep, h->w, sizeof h->w);
            if (h->uv_mode == UV_SLIDE)   /* a point on a chord: as coarse as the chord's ends */
                st->zstep[h->keep] = fmax(st->zstep[h->keep], fmax(st->zstep[h->end0], st->zstep[h->end1]));
            merge_z_attributes(st, h->keep, &h->gone, 1);
        }
    }
    /* faces of the gone vertex now use the kept one */
    int32_t n;
    const int32_t *list = vfaces(st, gone, &n);
    for (int32_t i = 0; i < n; i++) {
        int32_t f = list[i];
        if (!st->falive[f]) continue;
        int k = corner_of(st, f, gone);
        st->fv[3 * f + k] = keep;
        int32_t z = st->fz[3 * f + k];
        for (int h = 0; h < p->nhalf; h++)
            if (z == p->h[h].gone) z = p->h[h].keep;
        if (st->zv[z] == gone) st->zv[z] = keep;   /* other wedges of the gone vertex */
        st->fz[3 * f + k] = z;
    }
    if (!merge_lists(st, keep, gone)) return false;
    if (st->grid.on) {
        list = vfaces(st, keep, &n);
        for (int32_t i = 0; i < n; i++)
            if (st->falive[list[i]] && !grid_put(st, list[i])) return false;
    }
    if (st->vflags[gone] & V_CONTACT) {   /* keep stands where gone's contact was: the stricter limits */
        bool both = st->vflags[keep] & V_CONTACT;
        st->contact_reach[keep] = both ? min2(st->contact_reach[keep], st->contact_reach[gone]) : st->contact_reach[gone];
        st->contact_rise[keep] = both ? min2(st->contact_rise[keep], st->contact_rise[gone]) : st->contact_rise[gone];
        for (int32_t i = 0; i < st->ncontacts; i++)
            if (st->contacts[i] == gone) {
                st->contacts[i] = both ? st->contacts[--st->ncontacts] : keep;
                break;
            }
    }
    st->vflags[keep] |= st->vflags[gone] & (V_BOUNDARY | V_CONTACT);
    st->vflags[gone] = 0;
    if (st->vflags[keep] & V_CONTACT) contact_moved(st, keep);
    st->collapses++;
    if (p->kind == EDGE_SEAM) st->seam_collapses++;
    return true;
}

/* ---------------------------------------------------------------- queue */

static inline bool entry_less(const heap_entry *x, const heap_entry *y) {
    return x->key < y->key || (x->key == y->key && x->pair < y->pair);
}

static heap_entry make_entry(const state *st, double cost, int32_t a, int32_t b) {
    heap_entry e;
    cost = cost > 0 ? cost : 0;   /* +0: its bits order like the value */
    memcpy(&e.key, &cost, sizeof e.key);
    e.pair = (uint64_t)(uint32_t)a << 32 | (uint32_t)b;
    e.va = st->version[a];
    e.vb = st->version[b];
    e.full = false;
    return e;
}

static double entry_cost(const heap_entry *e) {
    double cost;
    memcpy(&cost, &e->key, sizeof cost);
    return cost;
}

static int32_t entry_a(const heap_entry *e) { return (int32_t)(e->pair >> 32); }
static int32_t entry_b(const heap_entry *e) { return (int32_t)(e->pair & 0xffffffffu); }

/* A 4-ary min-heap: half the levels of a binary one, and the four children
 * of a node share a cache line or two. */
#define HEAP_ARITY 4

/* Append without restoring the order (heap_compact restores it). */
static bool heap_append(state *st, heap_entry e) {
    if (st->heap_len == st->heap_cap) {
        int64_t cap = st->heap_cap ? st->heap_cap * 2 : 1024;
        heap_entry *h = sc_realloc_array(st->heap, (size_t)cap, sizeof *h);
        if (!h) {
            st->out_of_memory = true;
            return false;
        }
        st->heap = h;
        st->heap_cap = cap;
    }
    st->heap[st->heap_len++] = e;
    return true;
}

static bool heap_push(state *st, heap_entry e) {
    if (!heap_append(st, e)) return false;
    int64_t i = st->heap_len - 1;   /* sifted up from the end */
    while (i > 0) {
        int64_t parent = (i - 1) / HEAP_ARITY;
        if (!entry_less(&e, &st->heap[parent])) break;
        st->heap[i] = st->heap[parent];
        i = parent;
    }
    st->heap[i] = e;
    return true;
}

/* Put `moving` at slot i of the first n entries, moving it down past its
 * least child while that child is less. */
static void sift_down(state *st, int64_t i, int64_t n, heap_entry moving) {
    for (;;) {
        int64_t first = HEAP_ARITY * i + 1;
        if (first >= n) break;
        int64_t best = first, end = first + HEAP_ARITY < n ? first + HEAP_ARITY : n;
        for (int64_t c = first + 1; c < end; c++)
            if (entry_less(&st->heap[c], &st->heap[best])) best = c;
        if (!entry_less(&st->heap[best], &moving)) break;
        st->heap[i] = st->heap[best];
        i = best;
    }
    st->heap[i] = moving;
}

static bool heap_pop(state *st, heap_entry *out) {
    if (st->heap_len == 0) return false;
    *out = st->heap[0];
    heap_entry last = st->heap[--st->heap_len];
    if (st->heap_len > 0) sift_down(st, 0, st->heap_len, last);
    return true;
}

/* Drop stale entries (a dead endpoint or an older version) and restore the
 * heap order bottom-up. Stale entries keep their old, low costs and would
 * otherwise be popped one by one; compacting whenever the heap has doubled
 * since the last compaction costs O(1) per push. The order of valid entries
 * is a total order, so compacting never changes which edge comes next. */
static void heap_compact(state *st) {
    int64_t n = 0;
    for (int64_t i = 0; i < st->heap_len; i++) {
        const heap_entry *e = &st->heap[i];
        int32_t a = entry_a(e), b = entry_b(e);
        if ((st->vflags[a] & st->vflags[b] & V_ALIVE) && st->version[a] == e->va && st->version[b] == e->vb)
            st->heap[n++] = *e;
    }
    st->heap_len = st->heap_compacted = n;
    for (int64_t start = (n - 2) / HEAP_ARITY; start >= 0 && n > 1; start--) sift_down(st, start, n, st->heap[start]);
}

/* Pop stale entries (a dead endpoint or an older version) off the top, so
 * that the top is the cheapest live candidate's key. */
static void heap_drop_stale_top(state *st) {
    while (st->heap_len > 0) {
        const heap_entry *e = &st->heap[0];
        int32_t a = entry_a(e), b = entry_b(e);
        if ((st->vflags[a] & st->vflags[b] & V_ALIVE) && st->version[a] == e->va && st->version[b] == e->vb) return;
        heap_entry dropped;
        heap_pop(st, &dropped);
    }
}

/* Evaluate edge (a, b) and queue it when it can collapse: pushed in heap
 * order, or only appended (`ordered` false: the caller restores the order). */
static void evaluate_edge(state *st, int32_t a, int32_t b, bool ordered) {
    collapse_plan p;
    plan_edge(st, a, b, &p);
    solve_plan(st, &p);
    if (p.reason != BLOCK_NONE || !isfinite(p.cost)) return;
    if (ordered) heap_push(st, make_entry(st, p.cost, a, b));
    else heap_append(st, make_entry(st, p.cost, a, b));
}

static void queue_edge_unordered(state *st, int32_t a, int32_t b) { evaluate_edge(st, a, b, false); }

/* Evaluate edge (a, b), its ends in either order, and queue it when it can collapse. */
static void queue_edge(state *st, int32_t a, int32_t b) {
    if (a > b) evaluate_edge(st, b, a, true);
    else evaluate_edge(st, a, b, true);
}

/* Distinct neighbours of v into the scratch buffer (from index `at`). */
static int32_t vertex_neighbours(state *st, int32_t v, int32_t at) {
    int32_t n;
    vfaces(st, v, &n);
    if (!grow_scratch(st, at + 2 * n + 2)) return 0;
    const int32_t *list = vfaces(st, v, &n);
    uint32_t mark = fresh_mark(st);
    int32_t count = 0;
    for (int32_t i = 0; i < n; i++)
        for (int k = 0; k < 3 && st->falive[list[i]]; k++) {   /* a wide fan's dead faces skipped */
            int32_t x = st->fv[3 * list[i] + k];
            if (x == v || st->vmark[x] == mark) continue;
            st->vmark[x] = mark;
            st->scratch[at + count++] = x;
        }
    return count;
}

/* The distinct neighbours of v, in a buffer that survives evaluations
 * (which reuse the scratch buffer). Returns the count, -1 out of memory. */
static int32_t copy_neighbours(state *st, int32_t v) {
    int32_t n = vertex_neighbours(st, v, 0);
    if (st->out_of_memory || !reserve(st, &st->neighbours, &st->neighbours_cap, n + 1)) return -1;
    memcpy(st->neighbours, st->scratch, sizeof(int32_t) * (size_t)n);
    return n;
}

/* After a collapse onto `keep`: bump versions and re-queue the edges of keep,
 * of its silhouette neighbours when a silhouette edge collapsed (their seam
 * constraints refer to keep's uv and to the silhouette's connectivity, which
 * an interior collapse leaves as they were), and of neighbours marked after
 * a rejected collapse. */
static void requeue_around(state *st, int32_t keep, bool silhouette_changed) {
    int32_t n;
    const int32_t *list = vfaces(st, keep, &n);
    /* spokes of keep: (neighbour, keep's Z, neighbour's Z), two per face */
    if (!reserve(st, &st->touched, &st->touched_cap, 8 * n + 2)) return;
    int32_t *spoke = st->touched + 2 * n + 1, ns = 0;
    for (int32_t i = 0; i < n; i++) {
        const int32_t *fv = st->fv + 3 * list[i], *fz = st->fz + 3 * list[i];
        int k = fv[0] == keep ? 0 : fv[1] == keep ? 1 : 2;
        for (int e = 1; e <= 2; e++) {
            int j = (k + e) % 3;
            spoke[3 * ns] = fv[j];
            spoke[3 * ns + 1] = fz[k];
            spoke[3 * ns + 2] = fz[j];
            ns++;
        }
    }
    int32_t *set = st->touched, nt = 0;
    set[nt++] = keep;
    uint32_t mark = fresh_mark(st);
    /* after an interior collapse only marked neighbours join keep: no need
     * to classify the spokes */
    for (int32_t i = 0; i < ns && !silhouette_changed; i++) {
        int32_t x = spoke[3 * i];
        if (st->vmark[x] == mark) continue;
        st->vmark[x] = mark;
        if (st->vflags[x] & V_RETRY) set[nt++] = x;
    }
    for (int32_t i = 0; i < ns && silhouette_changed; i++) {
        int32_t x = spoke[3 * i];
        if (st->vmark[x] == mark) continue;
        st->vmark[x] = mark;
        bool qualifies = (st->vflags[x] & V_RETRY) != 0;
        int count = 0;
        for (int32_t j = 0; j < ns; j++)
            if (spoke[3 * j] == x) {
                count++;
                if (spoke[3 * j + 1] != spoke[3 * i + 1] || spoke[3 * j + 2] != spoke[3 * i + 2]) qualifies = true;
            }
        if (count == 1) qualifies = true;   /* a surface border */
        if (qualifies && (silhouette_changed || (st->vflags[x] & V_RETRY))) set[nt++] = x;
    }
    for (int32_t i = 0; i < nt; i++) {
        st->version[set[i]]++;
        st->vflags[set[i]] &= (uint8_t)~V_RETRY;
    }
    /* set lives in st->touched, which nothing below reuses */
    for (int32_t i = 0; i < nt; i++) {
        int32_t v = set[i];
        int32_t m = copy_neighbours(st, v);
        for (int32_t j = 0; j < m; j++) {
            int32_t x = st->neighbours[j];
            bool x_touched = false;
            for (int32_t t = 0; t < nt; t++)
                if (set[t] == x) x_touched = true;
            if (x_touched && x < v) continue;   /* queued from x's side */
            queue_edge(st, v, x);
        }
    }
}

/* ---------------------------------------------------------------- setup */

typedef struct zkey_table {
    int64_t cap;
    int32_t *slot;   /* Z id or -1 */
} zkey_table;

static uint64_t mix3(uint64_t a, uint64_t b, uint64_t c) {
    uint64_t h = a * 0x9E3779B97F4A7C15ull ^ (b + 0x632BE59BD9B4E019ull) * 0xC2B2AE3D27D4EB4Full ^
                 (c + 0x165667B19E3779F9ull) * 0x27D4EB2F165667C5ull;
    h ^= h >> 29;
    h *= 0xBF58476D1CE4E5B9ull;
    h ^= h >> 32;
    return h;
}

static void state_free(state *st) {
    free(st->pos), free(st->vflags), free(st->version), free(st->vmark);
    free(st->vf_off), free(st->vf_len), free(st->vf_cap), free(st->vf_dead), free(st->pool);
    free(st->fv), free(st->fz), free(st->fmat), free(st->falive), free(st->input_uv_area);
    free(st->zv), free(st->zuv_index), free(st->zcorner), free(st->smooth_normals), free(st->zuv), free(st->zflags);
    free(st->zq), free(st->zgeo), free(st->znormal), free(st->zweight), free(st->zmark), free(st->zstep);
    free(st->heap), free(st->scratch), free(st->touched), free(st->neighbours);
    free(st->owned_head), free(st->owned_tail), free(st->owned_next), free(st->near_face), free(st->fan), free(st->fan_h2);
    free(st->input_vf_off), free(st->input_vf);
    free(st->contacts), free(st->contact_reach), free(st->contact_rise), free(st->part);
    free(st->importance), free(st->stretch), free(st->input_z_first), free(st->input_z_next), free(st->input_zuv);
    grid_free(&st->grid);
}

/* Classify the fan of n faces around a centre; face i's two spokes (the ids
 * of its other corners) are spokes[2i], spokes[2i + 1]. Returns the number
 * of boundary spokes (0 or 2), or -1 when the fan is not a single disk or
 * half-disk (a spoke of three faces, several pieces, more borders). count
 * (zeros) and first (-1) are indexed by spoke id and are left as found;
 * parent holds n entries. */
static int classify_fan(const int32_t *spokes, int32_t n, int32_t *count, int32_t *first, int32_t *parent) {
    for (int32_t i = 0; i < n; i++) parent[i] = i;
    for (int32_t j = 0; j < 2 * n; j++) {
        int32_t x = spokes[j];
        count[x]++;
        if (first[x] < 0) first[x] = j / 2;
        else {
            int32_t r1 = sc_set_root(parent, j / 2), r2 = sc_set_root(parent, first[x]);
            if (r1 != r2) parent[r1 > r2 ? r1 : r2] = r1 < r2 ? r1 : r2;
        }
    }
    int boundary = 0;
    bool bad = false;
    for (int32_t j = 0; j < 2 * n; j++) {
        int32_t c = count[spokes[j]];
        if (c > 2) bad = true;
        if (c == 1) boundary++;
    }
    for (int32_t j = 0; j < 2 * n; j++) count[spokes[j]] = 0, first[spokes[j]] = -1;
    int pieces = 0;
    for (int32_t i = 0; i < n; i++) pieces += parent[i] == i;
    if (bad || pieces != 1 || (boundary != 0 && boundary != 2)) return -1;
    return boundary;
}

/* How the input's uv coordinates are stored: with at most k <= 15
 * significant decimal digits (OBJ text, whether %g or fixed decimals; the
 * step at a coordinate of magnitude 10^e is then 10^(e - k + 1)), as
 * float32 (glTF) or as doubles. (All uv entries are looked at.) */

/* Whether x is written with at most k significant decimal digits. */
static bool fits_digits(double x, int k) {
    static const double pow10[] = {1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10, 1e11,
                                   1e12, 1e13, 1e14, 1e15, 1e16, 1e17, 1e18, 1e19, 1e20, 1e21, 1e22};
    x = fabs(x);
    if (x == 0) return true;
    int shift = k - 1 - (int)floor(log10(x));
    if (shift > 22 || shift < -22) return false;
    double scaled = shift >= 0 ? x * pow10[shift] : x / pow10[-shift];
    return fabs(scaled - nearbyint(scaled)) <= 1e-6;
}

/* Significant decimal digits (1..15) x is written with, 16 when more. */
static int significant_digits(double x) {
    for (int k = 1; k <= 15; k++)
        if (fits_digits(x, k)) return k;
    return 16;
}

static void detect_uv_storage(state *st, const sc_mesh *m) {
    int digits = 1;
    for (int32_t i = 0; i < m->nu && digits <= 15; i++)
        for (int c = 0; c < 2; c++) {
            if (fits_digits(m->U[2 * i + c], digits)) continue;
            int d = significant_digits(m->U[2 * i + c]);
            if (d > digits) digits = d;
        }
    st->uv_digits = digits <= 15 ? digits : 0;
    bool floats = true;
    for (int32_t i = 0; i < m->nu && floats; i++)
        for (int c = 0; c < 2; c++) {
            double x = m->U[2 * i + c];
            if ((double)(float)x != x) floats = false;
        }
    st->uv_mantissa = floats ? 23 : 52;
}

/* The storage step of a uv point: half of it is the rounding it may carry. */
static double storage_step(const state *st, const double *uv) {
    if (st->uv_step_given >= 0) return st->uv_step_given;
    double x = fmax(fabs(uv[0]), fabs(uv[1]));
    if (!(x > 0)) return 0;
    if (st->uv_digits > 0) return pow(10.0, floor(log10(x)) - st->uv_digits + 1);
    return ldexp(1.0, ilogb(x) - st->uv_mantissa);
}

/* A face's importance (design note, map_size): max(1, (h / map texel)^2),
 * from h x map_size = sqrt(3D area / uv area); a face flat in uv counts as
 * squeezed as can be. */
#define IMPORTANCE_MAX 1e8
static double face_importance(const state *st, int32_t f, double area) {
    double uv = fabs(st->input_uv_area[f]), unit = st->map_texel_length;
    double r = uv > 0 ? area / uv / (unit * unit) : IMPORTANCE_MAX;
    return r > 1 ? fmin(r, IMPORTANCE_MAX) : 1;
}

/* The surface's per-vertex and per-face arrays, and the pool of its vertex -> face lists. */
static int alloc_mesh_arrays(state *st, int32_t nv, int32_t nf, sc_error *err) {
    st->nv = nv;
    st->nf = st->nf_alive = nf;
    st->pos = sc_alloc_array((size_t)nv * 3, sizeof(double));
    st->vflags = sc_calloc_array((size_t)nv, 1);
    st->version = sc_calloc_array((size_t)nv, sizeof(uint32_t));
    st->vmark = sc_calloc_array((size_t)nv, sizeof(uint32_t));
    st->vf_off = sc_calloc_array((size_t)nv, sizeof(int64_t));
    st->vf_len = sc_calloc_array((size_t)nv, sizeof(int32_t));
    st->vf_cap = sc_calloc_array((size_t)nv, sizeof(int32_t));
    st->vf_dead = sc_calloc_array((size_t)nv, sizeof(int32_t));
    st->fv = sc_alloc_array((size_t)nf * 3, sizeof(int32_t));
    st->fz = sc_alloc_array((size_t)nf * 3, sizeof(int32_t));
    st->fmat = sc_alloc_array((size_t)nf, sizeof(int32_t));
    st->falive = sc_alloc_array((size_t)nf, 1);
    st->input_uv_area = sc_alloc_array((size_t)nf, sizeof(double));
    st->pool_cap = (int64_t)nf * 3 + (int64_t)nv * 4 + 16;
    st->pool = sc_alloc_array((size_t)st->pool_cap, sizeof(int32_t));
    if (!st->pos || !st->vflags || !st->version || !st->vmark || !st->vf_off || !st->vf_len || !st->vf_cap || !st->vf_dead ||
        !st->fv || !st->fz || !st->fmat || !st->falive || !st->input_uv_area || !st->pool)
        return sc_fail(err, SC_ENOMEM, "decimate: out of memory");
    return SC_OK;
}

/* Centre the positions on their bounding box (costs do not change; rounding does). */
static void center_positions(state *st, const sc_mesh *m) {
    const int32_t nv = m->nv;
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    sc_bbox_add(m->V, nv, lo, hi);
    for (int32_t v = 0; v < nv; v++)
        for (int k = 0; k < 3; k++) st->pos[3 * v + k] = m->V[3 * v + k] - 0.5 * (lo[k] + hi[k]);
    for (int k = 0; k < 3; k++) st->center[k] = nv > 0 ? 0.5 * (lo[k] + hi[k]) : 0;
}

/* Number the Z-vertices through a hash table on (vertex, uv index, material),
 * in order of first appearance, and copy the faces' corners and materials. */
static int number_z_vertices(state *st, const sc_mesh *m, sc_error *err) {
    const int32_t nf = m->nf;
    zkey_table table;
    table.cap = 16;
    while (table.cap < (int64_t)nf * 6) table.cap *= 2;
    table.slot = sc_alloc_array((size_t)table.cap, sizeof(int32_t));
    int32_t zcap = nf * 3;
    st->zv = sc_alloc_array((size_t)zcap, sizeof(int32_t));
    st->zuv_index = sc_alloc_array((size_t)zcap, sizeof(int32_t));
    st->zcorner = sc_alloc_array((size_t)zcap, sizeof(int32_t));
    int32_t *zmat = sc_alloc_array((size_t)zcap, sizeof(int32_t));
    if (!table.slot || !st->zv || !st->zuv_index || !st->zcorner || !zmat) {
        free(table.slot);
        free(zmat);
        return sc_fail(err, SC_ENOMEM, "decimate: out of memory");
    }
    for (int64_t i = 0; i < table.cap; i++) table.slot[i] = -1;
    int32_t nz = 0;
    for (int32_t f = 0; f < nf; f++) {
        st->fmat[f] = m->FM ? m->FM[f] : 0;
        st->falive[f] = 1;
        for (int k = 0; k < 3; k++) {
            int32_t v = m->FV[3 * f + k], u = m->FU[3 * f + k], mat = st->fmat[f];
            st->fv[3 * f + k] = v;
            uint64_t h = mix3((uint64_t)v, (uint64_t)u, (uint64_t)mat) & (uint64_t)(table.cap - 1);
            for (;;) {
                int32_t z = table.slot[h];
                if (z < 0) {
                    z = nz++;
                    table.slot[h] = z;
                    st->zv[z] = v;
                    st->zuv_index[z] = u;
                    st->zcorner[z] = 3 * f + k;
                    zmat[z] = mat;
                    st->fz[3 * f + k] = z;
                    break;
                }
                if (st->zv[z] == v && st->zuv_index[z] == u && zmat[z] == mat) {
                    st->fz[3 * f + k] = z;
                    break;
                }
                h = (h + 1) & (uint64_t)(table.cap - 1);
            }
        }
    }
    free(table.slot);
    free(zmat);
    st->nz = nz;
    return SC_OK;
}

/* The Z-vertices' attribute arrays, with each Z's uv and its storage step. */
static int init_z_attributes(state *st, const sc_mesh *m, sc_error *err) {
    const int32_t nz = st->nz;
    st->zuv = sc_alloc_array((size_t)nz * 2, sizeof(double));
    st->zflags = sc_calloc_array((size_t)nz, 1);
    st->zq = sc_calloc_array((size_t)nz * QSIZE, sizeof(double));
    st->zgeo = sc_calloc_array((size_t)nz * 6, sizeof(double));
    st->znormal = sc_calloc_array((size_t)nz * 3, sizeof(double));
    st->zweight = sc_calloc_array((size_t)nz, sizeof(double));
    st->zmark = sc_calloc_array((size_t)nz, sizeof(uint32_t));
    st->zstep = sc_alloc_array((size_t)nz, sizeof(double));
    if (!st->zuv || !st->zflags || !st->zq || !st->zgeo || !st->znormal || !st->zweight || !st->zmark || !st->zstep)
        return sc_fail(err, SC_ENOMEM, "decimate: out of memory");
    st->uv_precision = 0;
    for (int32_t z = 0; z < nz; z++) {
        st->zuv[2 * z] = m->U[2 * st->zuv_index[z]];
        st->zuv[2 * z + 1] = m->U[2 * st->zuv_index[z] + 1];
        st->zstep[z] = storage_step(st, st->zuv + 2 * z);
        st->uv_precision = fmax(st->uv_precision, st->zstep[z]);
    }
    return SC_OK;
}

/* The vertex -> face lists in the pool, each with room for two more; marks used vertices alive. */
static void build_vertex_faces(state *st) {
    const int32_t nv = st->nv, nf = st->nf;
    for (int32_t i = 0; i < nf * 3; i++) st->vf_cap[st->fv[i]]++;
    int64_t off = 0;
    for (int32_t v = 0; v < nv; v++) {
        st->vf_off[v] = off;
        st->vf_cap[v] += 2;
        off += st->vf_cap[v];
    }
    st->pool_len = off;
    for (int32_t f = 0; f < nf; f++)
        for (int k = 0; k < 3; k++) {
            int32_t v = st->fv[3 * f + k];
            st->pool[st->vf_off[v] + st->vf_len[v]++] = f;
        }
    for (int32_t v = 0; v < nv; v++)
        if (st->vf_len[v] > 0) st->vflags[v] |= V_ALIVE;
}

/* The uv scale (one unit of uv ~ one unit of surface length), the faces'
 * input uv areas and the input's surface area. */
static void measure_uv_scale(state *st, double uv_weight) {
    double area3 = 0, area_uv = 0;
    for (int32_t f = 0; f < st->nf; f++) {
        double n[3];
        const int32_t *c = st->fv + 3 * f;
        sc_triangle_normal(st->pos + 3 * c[0], st->pos + 3 * c[1], st->pos + 3 * c[2], n);
        area3 += 0.5 * sqrt(sc_dot3(n, n));
        const int32_t *z = st->fz + 3 * f;
        st->input_uv_area[f] = 0.5 * sc_orient2(st->zuv + 2 * z[0], st->zuv + 2 * z[1], st->zuv + 2 * z[2]);
        area_uv += fabs(st->input_uv_area[f]);
    }
    st->uv_scale = uv_weight * (area_uv > 0 && area3 > 0 ? sqrt(area3 / area_uv) : 1.0);
    st->input_area = area3;
}

/* The fans: lock non-manifold vertices, flag border vertices, uv silhouettes and pinned Z. */
static int classify_fans(state *st, sc_error *err) {
    const int32_t nv = st->nv, nz = st->nz;
    int32_t maxn = 0;
    for (int32_t v = 0; v < nv; v++) maxn = st->vf_len[v] > maxn ? st->vf_len[v] : maxn;
    int32_t ids = nv > nz ? nv : nz;
    int32_t *count = sc_calloc_array((size_t)ids, sizeof(int32_t));
    int32_t *first = sc_alloc_array((size_t)ids, sizeof(int32_t));
    int32_t *fan = sc_alloc_array((size_t)maxn * 6 + 6, sizeof(int32_t));
    if (!count || !first || !fan) {
        free(count), free(first), free(fan);
        return sc_fail(err, SC_ENOMEM, "decimate: out of memory");
    }
    for (int32_t i = 0; i < ids; i++) first[i] = -1;
    int32_t *spokes = fan, *parent = fan + 2 * maxn + 2, *order = fan + 4 * maxn + 4;
    for (int32_t v = 0; v < nv; v++) {
        int32_t n = st->vf_len[v];
        if (n == 0) continue;
        const int32_t *list = st->pool + st->vf_off[v];
        for (int32_t i = 0; i < n; i++) {
            const int32_t *c = st->fv + 3 * list[i];
            int k = c[0] == v ? 0 : c[1] == v ? 1 : 2;
            spokes[2 * i] = c[(k + 1) % 3];
            spokes[2 * i + 1] = c[(k + 2) % 3];
        }
        int cls = classify_fan(spokes, n, count, first, parent);
        st->border_edges += cls > 0 ? cls : 0;   /* two border spokes per border vertex, one per edge end */
        if (cls < 0) st->vflags[v] |= V_LOCKED;
        if (cls != 0) st->vflags[v] |= V_BOUNDARY;
        /* the Z fans at v: faces grouped by their Z at v (insertion sort) */
        for (int32_t i = 0; i < n; i++) {
            const int32_t *c = st->fv + 3 * list[i];
            int k = c[0] == v ? 0 : c[1] == v ? 1 : 2;
            int32_t key = 3 * list[i] + k, j = i;
            while (j > 0 && st->fz[order[j - 1]] > st->fz[key]) {
                order[j] = order[j - 1];
                j--;
            }
            order[j] = key;
        }
        for (int32_t g = 0; g < n;) {
            int32_t z = st->fz[order[g]], cnt = 0;
            for (; g < n && st->fz[order[g]] == z; g++, cnt++) {
                int32_t f = order[g] / 3, k = order[g] % 3;
                spokes[2 * cnt] = st->fz[3 * f + (k + 1) % 3];
                spokes[2 * cnt + 1] = st->fz[3 * f + (k + 2) % 3];
            }
            int zcls = classify_fan(spokes, cnt, count, first, parent);
            if (zcls < 0) st->zflags[z] |= Z_PINNED | Z_SILHOUETTE;
            else if (zcls > 0) st->zflags[z] |= Z_SILHOUETTE;
        }
    }
    free(count), free(first), free(fan);
    return SC_OK;
}

/* Face f's surface border edges: a plane through the edge, perpendicular to
 * the face (unit: its unit normal), into the quadrics of the edge's Z. */
static void add_border_planes(state *st, int32_t f, const double unit[3]) {
    for (int k = 0; k < 3; k++) {
        int32_t x = st->fv[3 * f + k], y = st->fv[3 * f + (k + 1) % 3];
        int32_t fl[3];
        if (!(st->vflags[x] & st->vflags[y] & V_BOUNDARY) || edge_faces(st, x, y, fl) != 1) continue;
        const double *px = st->pos + 3 * x, *py = st->pos + 3 * y;
        double e[3] = {py[0] - px[0], py[1] - px[1], py[2] - px[2]}, m3[3];
        sc_cross3(unit, e, m3);
        double ml = sqrt(sc_dot3(m3, m3));
        if (!(ml > 0)) continue;
        for (int j = 0; j < 3; j++) m3[j] /= ml;
        double d = -sc_dot3(m3, px);
        double w = BOUNDARY_PLANE_WEIGHT * sc_dot3(e, e);
        sc_quadric_add_plane3(st->zq + (size_t)st->fz[3 * f + k] * QSIZE, QDIM, m3, d, w);
        sc_quadric_add_plane3(st->zq + (size_t)st->fz[3 * f + (k + 1) % 3] * QSIZE, QDIM, m3, d, w);
    }
}

/* The quadrics: each face's 5-D quadric, plane quadric and normal into its
 * corners' Z (with map_size, weighted by its importance), the border
 * planes, then the Z weights. */
static int add_quadrics(state *st, sc_error *err) {
    const int32_t nv = st->nv;
    if (st->map_texel_length > 0) {
        if (!(st->importance = sc_alloc_array((size_t)nv, sizeof(double))))
            return sc_fail(err, SC_ENOMEM, "decimate: out of memory");
        for (int32_t v = 0; v < nv; v++) st->importance[v] = 1;
        if (!(st->stretch = sc_calloc_array((size_t)nv, sizeof(double))))
            return sc_fail(err, SC_ENOMEM, "decimate: out of memory");
    }
    for (int32_t f = 0; f < st->nf; f++) {
        if (st->stretch) {   /* every face, flat ones too */
            const double *S[3], *W[3];
            for (int k = 0; k < 3; k++) S[k] = st->pos + 3 * st->fv[3 * f + k], W[k] = st->zuv + 2 * st->fz[3 * f + k];
            double sigma = uv_stretch(S, W);
            for (int k = 0; k < 3; k++) st->stretch[st->fv[3 * f + k]] = fmax(st->stretch[st->fv[3 * f + k]], sigma);
        }
        double P[3][QDIM];
        for (int k = 0; k < 3; k++) scaled_point(st, st->fz[3 * f + k], P[k]);
        double n[3];
        sc_triangle_normal(P[0], P[1], P[2], n);
        double len = sqrt(sc_dot3(n, n)), area = 0.5 * len;
        if (!(area > 0)) continue;
        double importance = st->importance ? face_importance(st, f, area) : 1;
        double q[QSIZE];
        sc_quadric_zero(q, QDIM);
        sc_quadric_add_triangle(q, QDIM, P[0], P[1], P[2], importance * area);
        double unit[3] = {n[0] / len, n[1] / len, n[2] / len};
        double geo[6] = {unit[0] * unit[0], unit[0] * unit[1], unit[0] * unit[2],
                         unit[1] * unit[1], unit[1] * unit[2], unit[2] * unit[2]};
        for (int k = 0; k < 3; k++) {
            int32_t z = st->fz[3 * f + k];
            double *restrict zq = st->zq + (size_t)z * QSIZE, *restrict zg = st->zgeo + 6 * (size_t)z,
                             *restrict zn = st->znormal + 3 * (size_t)z;
            for (int j = 0; j < QSIZE; j++) zq[j] += q[j];
            for (int j = 0; j < 6; j++) zg[j] += area * geo[j];
            for (int j = 0; j < 3; j++) zn[j] += 0.5 * n[j];
            if (st->importance) {
                int32_t v = st->fv[3 * f + k];
                if (importance > st->importance[v]) st->importance[v] = importance;
            }
        }
        add_border_planes(st, f, unit);
    }
    for (int32_t z = 0; z < st->nz; z++) update_weight(st, z);
    return SC_OK;
}

/* Error tracking: every input vertex stands for itself; with seam_kept, the
 * input Zs of every seam vertex, with their uv. */
static int start_error_tracking(state *st, sc_error *err) {
    const int32_t nv = st->nv, nz = st->nz;
    if (st->error_weight > 0 || st->max_error2 > 0 || st->seam_error2 > 0) {
        st->owned_head = sc_alloc_array((size_t)nv, sizeof(int32_t));
        st->owned_tail = sc_alloc_array((size_t)nv, sizeof(int32_t));
        st->owned_next = sc_alloc_array((size_t)nv, sizeof(int32_t));
        st->near_face = sc_alloc_array((size_t)nv, sizeof(int32_t));
        if (!st->owned_head || !st->owned_tail || !st->owned_next || !st->near_face)
            return sc_fail(err, SC_ENOMEM, "decimate: out of memory");
        for (int32_t v = 0; v < nv; v++) {
            st->owned_head[v] = st->owned_tail[v] = v;
            st->owned_next[v] = -1;
            st->near_face[v] = st->vf_len[v] > 0 ? st->pool[st->vf_off[v]] : -1;
        }
        const sc_hausdorff_mesh *in = st->input;   /* the input's faces around each vertex (ring_within) */
        st->input_vf_off = sc_calloc_array((size_t)in->nv + 1, sizeof(int32_t));
        st->input_vf = sc_alloc_array((size_t)3 * in->nf + 1, sizeof(int32_t));
        if (!st->input_vf_off || !st->input_vf) return sc_fail(err, SC_ENOMEM, "decimate: out of memory");
        for (int32_t i = 0; i < 3 * in->nf; i++) st->input_vf_off[in->F[i] + 1]++;
        for (int32_t v = 0; v < in->nv; v++) st->input_vf_off[v + 1] += st->input_vf_off[v];
        for (int32_t i = 0; i < 3 * in->nf; i++)   /* each list filled from its start: input_vf_off[v] moves on */
            st->input_vf[st->input_vf_off[in->F[i]]++] = i / 3;
        for (int32_t v = in->nv; v > 0; v--) st->input_vf_off[v] = st->input_vf_off[v - 1];   /* moved back */
        st->input_vf_off[0] = 0;
    }
    if (st->seam_error2 > 0) {   /* seam_kept: the input Zs of every seam vertex, with their uv */
        st->input_z_first = sc_alloc_array((size_t)nv, sizeof(int32_t));
        st->input_z_next = sc_alloc_array((size_t)nz, sizeof(int32_t));
        st->input_zuv = sc_alloc_array((size_t)nz * 2, sizeof(double));
        if (!st->input_z_first || !st->input_z_next || !st->input_zuv)
            return sc_fail(err, SC_ENOMEM, "decimate: out of memory");
        memcpy(st->input_zuv, st->zuv, sizeof(double) * 2 * (size_t)nz);
        for (int32_t v = 0; v < nv; v++) st->input_z_first[v] = -1;
        for (int32_t z = nz - 1; z >= 0; z--) st->input_z_next[z] = st->input_z_first[st->zv[z]], st->input_z_first[st->zv[z]] = z;
        for (int32_t v = 0; v < nv; v++) {   /* kept for vertices on a uv silhouette only */
            bool silhouette = false;
            for (int32_t z = st->input_z_first[v]; z >= 0; z = st->input_z_next[z]) silhouette |= (st->zflags[z] & Z_SILHOUETTE) != 0;
            if (!silhouette) st->input_z_first[v] = -1;
        }
    }
    return SC_OK;
}

/* The state for decimating m: its surface, its Z-vertices and their quadrics. */
static int setup(state *st, const sc_mesh *m, double uv_weight, sc_error *err) {
    int rc = alloc_mesh_arrays(st, m->nv, m->nf, err);
    if (rc != SC_OK) return rc;
    center_positions(st, m);
    if ((rc = number_z_vertices(st, m, err)) != SC_OK || (rc = init_z_attributes(st, m, err)) != SC_OK) return rc;
    build_vertex_faces(st);
    measure_uv_scale(st, uv_weight);
    if ((rc = classify_fans(st, err)) != SC_OK || (rc = add_quadrics(st, err)) != SC_OK) return rc;
    if ((st->refuse_crossings || st->contact_distance > 0) && !grid_build(st))
        return sc_fail(err, SC_ENOMEM, "decimate: out of memory");
    if (st->contact_distance > 0 && !find_contacts(st)) return sc_fail(err, SC_ENOMEM, "decimate: out of memory");
    return start_error_tracking(st, err);
}

/* ---------------------------------------------------------------- output */

/* Whether live faces f (corner ka, kb) and g (corner la, lb) use different uv
 * at the edge: another uv index, or the same index moved apart. */
static bool z_differs(const state *st, int32_t z1, int32_t z2) {
    return z1 != z2 && (st->zuv_index[z1] != st->zuv_index[z2] || st->zuv[2 * z1] != st->zuv[2 * z2] ||
                        st->zuv[2 * z1 + 1] != st->zuv[2 * z2 + 1]);
}

typedef struct seam_census {
    int64_t seam_edges;
    int64_t uncollapsible, corner, not_collinear, length_ratio;
} seam_census;

/* Table 2 of Liu et al.: seam edges and those with no unifiable neighbour. */
static void census_seams(state *st, seam_census *c) {
    memset(c, 0, sizeof *c);
    for (int32_t a = 0; a < st->nv && !st->out_of_memory; a++) {
        if (!(st->vflags[a] & V_ALIVE)) continue;
        int32_t nn = copy_neighbours(st, a);
        const int32_t *nb = st->neighbours;
        for (int32_t i = 0; i < nn; i++) {
            int32_t b = nb[i];
            if (b < a) continue;
            int32_t fl[3];
            if (edge_faces(st, a, b, fl) != 2) continue;
            int32_t za[2], zb[2];
            for (int j = 0; j < 2; j++) {
                za[j] = st->fz[3 * fl[j] + corner_of(st, fl[j], a)];
                zb[j] = st->fz[3 * fl[j] + corner_of(st, fl[j], b)];
            }
            if (!z_differs(st, za[0], za[1]) && !z_differs(st, zb[0], zb[1])) continue;
            c->seam_edges++;
            int32_t far[2];
            block_reason ra = unify_at(st, 2, a, za, zb, far);
            block_reason rb = unify_at(st, 2, b, zb, za, far);
            if (ra == BLOCK_NONE || rb == BLOCK_NONE) continue;
            c->uncollapsible++;
            block_reason r = better_reason(ra, rb);
            if (r == BLOCK_SEAM_LENGTH_RATIO) c->length_ratio++;
            else if (r == BLOCK_SEAM_NOT_COLLINEAR) c->not_collinear++;
            else c->corner++;
        }
    }
}

/* Classify every live edge that cannot collapse now. */
static double tracked_error(state *st, const collapse_plan *p, int32_t *seed, double stop, bool *complete);
static sc_hausdorff_bvh *input_bvh_take(state *st);

static int64_t census_blocked(state *st, int64_t counts[BLOCK_COUNT]) {
    memset(counts, 0, sizeof(int64_t) * BLOCK_COUNT);
    int64_t blocked = 0;
    for (int32_t a = 0; a < st->nv && !st->out_of_memory; a++) {
        if (!(st->vflags[a] & V_ALIVE)) continue;
        int32_t nn = copy_neighbours(st, a);
        const int32_t *nb = st->neighbours;
        for (int32_t i = 0; i < nn; i++) {
            if (nb[i] < a) continue;
            collapse_plan p;
            plan_edge(st, a, nb[i], &p);
            solve_plan(st, &p);
            block_reason r = p.reason != BLOCK_NONE ? p.reason : check_plan(st, &p);
            if (r == BLOCK_NONE && st->max_error2 > 0 && input_bvh_take(st)) {
                int32_t seed = st->near_face[p.keep];
                bool complete;
                if (tracked_error(st, &p, &seed, st->max_error2, &complete) > st->max_error2) r = BLOCK_MAX_ERROR;
            }
            if (r != BLOCK_NONE) {
                counts[r]++;
                blocked++;
            }
        }
    }
    return blocked;
}

/* The input corner whose normal corner k of live face f takes: the face's
 * own where the corner still is the input's vertex, else (a vertex that
 * took a collapsed one's place) the corner that first named the corner's Z
 * (its vertex, uv index and material). */
static int32_t normal_corner(const state *st, const sc_mesh *in, int32_t f, int k) {
    int32_t v = st->fv[3 * f + k];
    for (int c = 0; c < 3; c++)
        if (in->FV[3 * f + c] == v) return 3 * f + c;
    return st->zcorner[st->fz[3 * f + k]];
}

/* The current mesh as an sc_mesh: live faces in input order, vertices and uv
 * entries renumbered in id order (Z of one vertex that share a uv index and
 * its coordinates become one entry again). */
static int build_level_mesh(state *st, const sc_mesh *in, sc_mesh **out, sc_error *err) {
    int32_t *vmap = sc_alloc_array((size_t)st->nv + 1, sizeof(int32_t));
    int32_t *zmap = sc_alloc_array((size_t)st->nz + 1, sizeof(int32_t));
    int64_t cap = 16;
    while (cap < 2 * (int64_t)st->nz) cap *= 2;
    int32_t *slot = sc_alloc_array((size_t)cap, sizeof(int32_t));
    if (!vmap || !zmap || !slot) {
        free(vmap), free(zmap), free(slot);
        return sc_fail(err, SC_ENOMEM, "decimate: out of memory");
    }
    for (int32_t v = 0; v < st->nv; v++) vmap[v] = -1;
    for (int32_t z = 0; z < st->nz; z++) zmap[z] = -1;
    for (int64_t i = 0; i < cap; i++) slot[i] = -1;
    for (int32_t f = 0; f < st->nf; f++)
        if (st->falive[f])
            for (int k = 0; k < 3; k++) {
                vmap[st->fv[3 * f + k]] = 0;
                zmap[st->fz[3 * f + k]] = 0;
            }
    int32_t nv = 0, nu = 0;
    for (int32_t v = 0; v < st->nv; v++)
        if (vmap[v] == 0) vmap[v] = nv++;
    int32_t *ufirst = sc_alloc_array((size_t)st->nz + 1, sizeof(int32_t));   /* output uv -> a Z */
    if (!ufirst) {
        free(vmap), free(zmap), free(slot);
        return sc_fail(err, SC_ENOMEM, "decimate: out of memory");
    }
    for (int32_t z = 0; z < st->nz; z++) {
        if (zmap[z] != 0) continue;
        uint64_t bu, bv;
        memcpy(&bu, st->zuv + 2 * z, 8);
        memcpy(&bv, st->zuv + 2 * z + 1, 8);
        uint64_t h = mix3((uint64_t)st->zv[z] ^ (bu * 31), (uint64_t)st->zuv_index[z], bv) & (uint64_t)(cap - 1);
        for (;;) {
            int32_t o = slot[h];
            if (o < 0) {
                slot[h] = nu;
                ufirst[nu] = z;
                zmap[z] = nu++;
                break;
            }
            int32_t y = ufirst[o];
            if (st->zv[y] == st->zv[z] && st->zuv_index[y] == st->zuv_index[z] && st->zuv[2 * y] == st->zuv[2 * z] &&
                st->zuv[2 * y + 1] == st->zuv[2 * z + 1]) {
                zmap[z] = o;
                break;
            }
            h = (h + 1) & (uint64_t)(cap - 1);
        }
    }
    free(slot);
    /* the input's normals: its own, or the smooth ones save writes for it */
    const bool own_normals = in->nn > 0 && in->FN;
    if (!own_normals && !st->smooth_normals) st->smooth_normals = sc_tangent_corner_normals(in);
    const double *smooth = st->smooth_normals;
    const int32_t nn = own_normals ? in->nn : 3 * st->nf_alive;
    sc_mesh *m = own_normals || smooth ? sc_mesh_alloc(nv, nu, nn, st->nf_alive, in->nmat) : NULL;
    int rc = m ? SC_OK : SC_ENOMEM;
    for (int32_t i = 0; rc == SC_OK && i < in->nmat; i++)
        if (!(m->materials[i] = sc_strdup(in->materials[i]))) rc = SC_ENOMEM;
    if (rc == SC_OK) {
        for (int32_t v = 0; v < st->nv; v++)
            if (vmap[v] >= 0)
                for (int k = 0; k < 3; k++) m->V[3 * vmap[v] + k] = st->pos[3 * v + k] + st->center[k];
        for (int32_t u = 0; u < nu; u++) {
            m->U[2 * u] = st->zuv[2 * ufirst[u]];
            m->U[2 * u + 1] = st->zuv[2 * ufirst[u] + 1];
        }
        int32_t g = 0;
        for (int32_t f = 0; f < st->nf; f++) {
            if (!st->falive[f]) continue;
            for (int k = 0; k < 3; k++) {
                m->FV[3 * g + k] = vmap[st->fv[3 * f + k]];
                m->FU[3 * g + k] = zmap[st->fz[3 * f + k]];
                int32_t c = normal_corner(st, in, f, k);
                if (own_normals) {
                    m->FN[3 * g + k] = in->FN[c];
                } else {
                    m->FN[3 * g + k] = 3 * g + k;
                    memcpy(m->N + 3 * (3 * (size_t)g + k), smooth + 3 * (size_t)c, 3 * sizeof(double));
                }
            }
            m->FM[g] = st->fmat[f];
            g++;
        }
        if (own_normals && nn > 0) memcpy(m->N, in->N, sizeof(double) * 3 * (size_t)nn);
    }
    free(vmap), free(zmap), free(ufirst);
    if (rc != SC_OK) {
        sc_mesh_free(m);
        return sc_fail(err, SC_ENOMEM, "decimate: out of memory");
    }
    *out = m;
    return SC_OK;
}

static double total_quadric_cost(const state *st) {
    double total = 0;
    for (int32_t z = 0; z < st->nz; z++) {
        if (st->zv[z] < 0) continue;
        double x[QDIM];
        scaled_point(st, z, x);
        double c = sc_quadric_eval(st->zq + (size_t)z * QSIZE, QDIM, x);
        total += c > 0 ? c : 0;
    }
    return total;
}

static int64_t count_flipped_uv(const state *st) {
    int64_t flipped = 0;
    for (int32_t f = 0; f < st->nf; f++) {
        if (!st->falive[f] || st->input_uv_area[f] == 0) continue;
        const int32_t *z = st->fz + 3 * f;
        double a = sc_orient2(st->zuv + 2 * z[0], st->zuv + 2 * z[1], st->zuv + 2 * z[2]);
        if (!(a * st->input_uv_area[f] > 0)) flipped++;
    }
    return flipped;
}

/* ---------------------------------------------------------------- the node */

/* What one pass over every level says: its metrics and its warnings (kept
 * apart from the node's until the pass is the one whose levels are output). */
typedef struct outcome {
    sc_metric_list metrics;
    sc_buf warnings;           /* lines, each ending in a newline */
    double over;               /* the largest sampled Hausdorff distance of a level / max_error */
    double seconds;            /* the pass's, measuring included */
    bool out_of_memory;
} outcome;

static void outcome_free(outcome *o) {
    sc_metric_list_free(&o->metrics);
    sc_buf_free(&o->warnings);
}

static void total(outcome *o, const char *name, double value) {
    if (sc_metric_list_add(&o->metrics, name, value) != SC_OK) o->out_of_memory = true;
}

static void metric(outcome *o, int level, const char *name, double value) {
    char key[96];
    snprintf(key, sizeof key, "lod%d.%s", level, name);
    total(o, key, value);
}

static void warn(outcome *o, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static void warn(outcome *o, const char *fmt, ...) {
    char line[400];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(line, sizeof line, fmt, ap);
    va_end(ap);
    sc_buf_printf(&o->warnings, "%s\n", line);
}

/* One line for a level that stopped above its target: the faces, the
 * target, and the three reasons that blocked the most edges. */
static void warn_short_level(outcome *o, int level, int32_t faces, int64_t target, const int64_t blocked[BLOCK_COUNT]) {
    char reasons[256] = "";
    size_t used = 0;
    bool taken[BLOCK_COUNT] = {false};
    for (int shown = 0; shown < 3; shown++) {
        int best = 0;
        for (int r = 1; r < BLOCK_COUNT; r++)
            if (!taken[r] && blocked[r] > 0 && (best == 0 || blocked[r] > blocked[best])) best = r;
        if (best == 0) break;
        taken[best] = true;
        int n = snprintf(reasons + used, sizeof reasons - used, "%s%lld %s", shown ? ", " : "",
                         (long long)blocked[best], block_names[best]);
        if (n < 0 || (size_t)n >= sizeof reasons - used) break;
        used += (size_t)n;
    }
    warn(o, "lod%d: %d faces for a target of %lld%s%s", level, (int)faces, (long long)target,
                used ? ": blocked by " : "", reasons);
}

/* The rules of the two target lists, checked wherever a value is (the graph
 * is built, a dry run too): each level is decimated from the one before, so
 * targets never increase. A ratio is in (0, 1]; a face count is whole. */
static int check_targets(const double *x, int n, bool faces, sc_error *err) {
    for (int i = 0; i < n; i++) {
        if (faces ? !(x[i] >= 1) || x[i] != floor(x[i]) : !(x[i] > 0 && x[i] <= 1))
            return sc_fail(err, SC_EINPUT, faces ? "target %d is %g; face counts are whole numbers >= 1"
                                                 : "target %d is %g; ratios lie in (0, 1]", i, x[i]);
        if (i > 0 && x[i] > x[i - 1])
            return sc_fail(err, SC_EINPUT, "targets must not increase (each level is decimated from the one "
                           "before): target %d is %g after %g", i, x[i], x[i - 1]);
    }
    return SC_OK;
}

static int check_ratios(const double *x, int n, sc_error *err) {
    if (n == 0) return sc_fail(err, SC_EINPUT, "no targets (give at least one ratio)");
    return check_targets(x, n, false, err);
}

static int check_faces(const double *x, int n, sc_error *err) { return check_targets(x, n, true, err); }

/* Face counts per level; rounding keeps them in order, as the ratios are. */
static int read_targets(sc_ctx *ctx, int32_t nf, int64_t **out, int *count, sc_error *err) {
    int nfaces = 0, nratio = 0;
    const double *faces = sc_ctx_numbers(ctx, "faces", &nfaces);
    const double *ratio = sc_ctx_numbers(ctx, "ratio", &nratio);
    int n = nfaces > 0 ? nfaces : nratio;
    int rc = nfaces > 0 ? check_faces(faces, nfaces, err) : check_ratios(ratio, nratio, err);
    if (rc) return sc_error_prefix(err, "decimate:%s", nfaces > 0 ? "faces" : "ratio");
    int64_t *t = sc_alloc_array((size_t)n, sizeof *t);
    if (!t) return sc_fail(err, SC_ENOMEM, "decimate: out of memory");
    for (int i = 0; i < n; i++) {
        t[i] = nfaces > 0 ? (int64_t)faces[i] : (int64_t)llround(ratio[i] * nf);
        if (t[i] < 1) t[i] = 1;
    }
    *out = t;
    *count = n;
    return SC_OK;
}

/* The edges (a, b > a) of the live vertices a in [a0, a1), appended in
 * vertex order. Evaluating an edge reads the state and writes only its
 * scratch (scratch, neighbours, vmark/vstamp) and heap. */
static void queue_vertex_range(state *st, int32_t a0, int32_t a1) {
    for (int32_t a = a0; a < a1 && !st->out_of_memory; a++) {
        if (!(st->vflags[a] & V_ALIVE)) continue;
        int32_t nn = copy_neighbours(st, a);
        for (int32_t i = 0; i < nn; i++)
            if (st->neighbours[i] > a) queue_edge_unordered(st, a, st->neighbours[i]);
    }
}

/* The first evaluation of every edge, the largest serial stretch of a
 * decimation: with two threads, the vertices [mid, nv) go to a copy of the
 * state with scratch and heap of its own, whose entries are then appended
 * after the caller's, so the heap holds the serial sequence of entries. */
typedef struct queue_split {
    state *st, *upper;
    int32_t mid;
} queue_split;

static int queue_split_run(void *ud, int32_t chunk) {
    queue_split *q = ud;
    if (chunk == 0) queue_vertex_range(q->st, 0, q->mid);
    else queue_vertex_range(q->upper, q->mid, q->st->nv);
    return SC_OK;
}

static void queue_all_edges(state *st, int threads) {
    for (int32_t a = 0; a < st->nv; a++) st->vflags[a] &= (uint8_t)~V_RETRY;
    state upper = *st;
    upper.scratch = NULL, upper.scratch_cap = 0;
    upper.neighbours = NULL, upper.neighbours_cap = 0;
    upper.touched = NULL, upper.touched_cap = 0;
    upper.heap = NULL, upper.heap_len = upper.heap_cap = 0;
    upper.vstamp = 0;
    upper.vmark = threads >= 2 ? sc_calloc_array((size_t)st->nv + 1, sizeof *upper.vmark) : NULL;
    queue_split q = {st, &upper, st->nv / 2};
    if (!upper.vmark || sc_parallel(2, 2, queue_split_run, &q) != SC_OK) {
        queue_vertex_range(st, 0, st->nv);   /* one thread */
    } else {
        for (int64_t i = 0; i < upper.heap_len && !upper.out_of_memory; i++)
            if (!heap_append(st, upper.heap[i])) st->out_of_memory = true;
        st->out_of_memory |= upper.out_of_memory;
    }
    free(upper.vmark), free(upper.scratch), free(upper.neighbours), free(upper.touched), free(upper.heap);
    heap_compact(st);   /* one O(n) heapify instead of n pushes */
}

/* ---------------------------------------------------------------- error tracking */

/* A face of the fan a collapse would leave, ready for many point queries:
 * its corners (the moved vertex first), the unit normal, and the dual
 * vectors whose dot products with q - corner[0] are q's barycentric
 * coordinates along the two edges from corner[0]. */
typedef struct fan_face {
    const double *corner[3];
    double normal[3], dual0[3], dual1[3];
    bool flat;                   /* degenerate: the general closest-point test only */
} fan_face;

static void prepare_face(fan_face *f) {
    const double *a = f->corner[0], *b = f->corner[1], *c = f->corner[2];
    double e0[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, e1[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
    double g00 = sc_dot3(e0, e0), g01 = sc_dot3(e0, e1), g11 = sc_dot3(e1, e1), det = g00 * g11 - g01 * g01;
    sc_cross3(e0, e1, f->normal);
    double len = sqrt(sc_dot3(f->normal, f->normal));
    f->flat = !(det > 1e-24 * g00 * g11) || !(len > 0);
    if (f->flat) return;
    for (int k = 0; k < 3; k++) {
        f->normal[k] /= len;
        f->dual0[k] = (g11 * e0[k] - g01 * e1[k]) / det;
        f->dual1[k] = (g00 * e1[k] - g01 * e0[k]) / det;
    }
}

/* The squared distance from q to the face's plane (a lower bound of its
 * distance to the face); true when q projects inside the face, where the
 * two are equal. */
static bool face_plane_distance2(const fan_face *f, const double *q, double *h2) {
    const double *a = f->corner[0];
    if (f->flat) {
        *h2 = 0;
        return false;
    }
    double w[3] = {q[0] - a[0], q[1] - a[1], q[2] - a[2]};
    double s = sc_dot3(w, f->dual0), t = sc_dot3(w, f->dual1), h = sc_dot3(w, f->normal);
    *h2 = h * h;
    return s >= 0 && t >= 0 && s + t <= 1;
}

static double face_distance2(const fan_face *f, const double *q) {
    double r[3];
    sc_hausdorff_closest_on_triangle(q, f->corner[0], f->corner[1], f->corner[2], r);
    double d[3] = {q[0] - r[0], q[1] - r[1], q[2] - r[2]};
    return sc_dot3(d, d);
}

/* Squared distance from q to the fan, or any value no larger than `enough`
 * once one face is found that close. The cheap plane test goes first over
 * all faces (exact where q projects inside); the general test only for the
 * faces whose plane is closer than the best so far. */
static double fan_distance2(const fan_face *fan, int32_t nfan, const double *q, double enough, double *h2) {
    double best = INFINITY;
    for (int32_t f = 0; f < nfan; f++) {
        bool inside = face_plane_distance2(&fan[f], q, &h2[f]);
        if (inside && h2[f] < best) {
            best = h2[f];
            if (best <= enough) return best;
        }
    }
    for (int32_t f = 0; f < nfan; f++) {
        if (!(h2[f] < best)) continue;   /* its plane, a lower bound, is no closer */
        double d = face_distance2(&fan[f], q);
        if (d < best) {
            best = d;
            if (best <= enough) return best;
        }
    }
    return best;
}

/* The fan the planned collapse leaves (the surviving faces around keep and
 * gone, moved vertex at p->xyz) into st->fan; returns its size, -1 out of
 * memory. */
static int32_t new_fan(state *st, const collapse_plan *p) {
    int32_t nk, ng;
    vfaces(st, p->keep, &nk);
    vfaces(st, p->gone, &ng);
    if (nk + ng > st->fan_cap) {
        int32_t cap = 2 * (nk + ng);
        fan_face *f = sc_realloc_array(st->fan, (size_t)cap, sizeof *f);
        if (f) st->fan = f;
        double *h = sc_realloc_array(st->fan_h2, (size_t)cap, sizeof *h);
        if (h) st->fan_h2 = h;
        if (!f || !h) {
            st->out_of_memory = true;
            return -1;
        }
        st->fan_cap = cap;
    }
    int32_t count = 0;
    for (int side = 0; side < 2; side++) {
        int32_t v = side ? p->gone : p->keep, n;
        const int32_t *list = vfaces(st, v, &n);
        for (int32_t i = 0; i < n; i++) {
            int32_t f = list[i];
            if (is_removed(p, f)) continue;
            const int32_t *c = st->fv + 3 * f;
            int k = c[0] == v ? 0 : c[1] == v ? 1 : 2;
            fan_face *ff = &st->fan[count++];
            ff->corner[0] = p->xyz;
            ff->corner[1] = st->pos + 3 * c[(k + 1) % 3];
            ff->corner[2] = st->pos + 3 * c[(k + 2) % 3];
            prepare_face(ff);
        }
    }
    return count;
}

/* Squared distance from q to input face g's bounding box: no nearer point of g. */
static double input_box_distance2(const sc_hausdorff_mesh *in, int32_t g, const double q[3]) {
    const double *A = in->V + 3 * in->F[3 * g], *B = in->V + 3 * in->F[3 * g + 1], *C = in->V + 3 * in->F[3 * g + 2];
    double d2 = 0;
    for (int k = 0; k < 3; k++) {
        double lo = min2(A[k], min2(B[k], C[k])), hi = max2(A[k], max2(B[k], C[k]));
        double e = q[k] < lo ? lo - q[k] : q[k] > hi ? q[k] - hi : 0;
        d2 += e * e;
    }
    return d2;
}

/* Whether input face g lies within sqrt(enough) of q. */
static bool input_face_within(const sc_hausdorff_mesh *in, int32_t g, const double q[3], double enough) {
    if (input_box_distance2(in, g, q) > enough) return false;
    const int32_t *c = in->F + 3 * g;
    double r[3];
    sc_hausdorff_closest_on_triangle(q, in->V + 3 * c[0], in->V + 3 * c[1], in->V + 3 * c[2], r);
    double d[3] = {q[0] - r[0], q[1] - r[1], q[2] - r[2]};
    return sc_dot3(d, d) <= enough;
}

/* Whether input face *face, or one sharing a corner with it, lies within
 * sqrt(enough) of q, *face becoming that face: then q cannot raise a
 * largest distance of `enough` and needs no walk through the BVH (the
 * nearest input face to a point of a fan is most often next to the last
 * one's). Each face is tried once. */
static bool ring_within(const state *st, const double q[3], int32_t *face, double enough) {
    const sc_hausdorff_mesh *in = st->input;
    if (input_face_within(in, *face, q, enough)) return true;
    int32_t tried[64], ntried = 0;
    tried[ntried++] = *face;
    for (int k = 0; k < 3; k++) {
        int32_t v = in->F[3 * *face + k];
        for (int32_t i = st->input_vf_off[v]; i < st->input_vf_off[v + 1]; i++) {
            int32_t g = st->input_vf[i];
            bool seen = false;
            for (int32_t t = 0; t < ntried && !seen; t++) seen = tried[t] == g;
            if (seen) continue;
            if (ntried < (int32_t)(sizeof tried / sizeof tried[0])) tried[ntried++] = g;
            if (input_face_within(in, g, q, enough)) {
                *face = g;
                return true;
            }
        }
    }
    return false;
}

/* The tracked error of a planned collapse: the larger squared distance of
 *   (a) the input vertices keep and gone stand for, to the new fan, and
 *   (b) points of the new fan, to the input surface: the moved vertex and,
 *       on each face, the middle of its spoke (where a collapse that
 *       bridges a gap or cuts off a feature leaves the new surface farthest
 *       from the input), its centroid and a point nearer the moved vertex
 *       (faces spanning a hollow).
 * Only the maximum matters, so a point is let go at the first face closer
 * than the maximum so far, and the measure stops (*complete false) as soon
 * as the maximum passes `stop`: it is then a lower bound. *seed carries an
 * input face near the moved vertex in and out. */
static double tracked_error(state *st, const collapse_plan *p, int32_t *seed, double stop, bool *complete) {
    *complete = false;
    const double *c = st->center;
    double q[3];
    /* (b) first for the moved vertex: it needs no fan, and where the
     * collapse is far off it alone passes `stop` */
    int32_t face = *seed;
    for (int k = 0; k < 3; k++) q[k] = p->xyz[k] + c[k];
    double worst = sc_hausdorff_bvh_closest_above(st->input_bvh, q, 0, face, &face);
    *seed = face;
    if (worst > stop) return worst;
    int32_t nfan = new_fan(st, p);
    if (nfan < 0) return INFINITY;
    const fan_face *fan = st->fan;
    /* (a) */
    double *h2 = st->fan_h2;   /* scratch for fan_distance2 */
    for (int side = 0; side < 2; side++)
        for (int32_t i = st->owned_head[side ? p->gone : p->keep]; i >= 0; i = st->owned_next[i]) {
            for (int k = 0; k < 3; k++) q[k] = st->input->V[3 * (size_t)i + k] - c[k];
            double d = fan_distance2(fan, nfan, q, worst, h2);
            if (d > worst) {
                worst = d;
                if (worst > stop) return worst;
            }
        }
    /* (b) on each face: the middle of the spoke to corner 1 (each spoke
     * once), the centroid, and the point 2/3 of the way from the opposite
     * edge's middle to the moved vertex */
    static const double weight[3][3] = {{0.5, 0.5, 0}, {1.0 / 3, 1.0 / 3, 1.0 / 3}, {2.0 / 3, 1.0 / 6, 1.0 / 6}};
    for (int32_t i = 0; i < nfan; i++)
        for (int w = 0; w < 3; w++) {
            for (int k = 0; k < 3; k++)
                q[k] = weight[w][0] * fan[i].corner[0][k] + weight[w][1] * fan[i].corner[1][k] +
                       weight[w][2] * fan[i].corner[2][k] + c[k];
            if (face >= 0 && ring_within(st, q, &face, worst)) continue;
            double d = sc_hausdorff_bvh_closest_above(st->input_bvh, q, worst, face, &face);
            if (d > worst) {
                worst = d;
                if (worst > stop) return worst;
            }
        }
    *complete = true;
    return worst;
}

/* The input's BVH. With two threads it is built beside the first
 * collapses (input_bvh_start), which do not need it; the tree is the same
 * either way. */
static void *input_bvh_worker(void *ud) {
    state *st = ud;
    st->input_bvh = sc_hausdorff_bvh_build(st->input);
    return NULL;
}

static void input_bvh_start(state *st, int threads) {
    if (threads >= 2 && pthread_create(&st->bvh_thread, NULL, input_bvh_worker, st) == 0) st->bvh_pending = true;
}

/* The BVH, once built (NULL out of memory). */
static sc_hausdorff_bvh *input_bvh_take(state *st) {
    if (st->bvh_pending) {
        pthread_join(st->bvh_thread, NULL);
        st->bvh_pending = false;
        if (!st->input_bvh) st->out_of_memory = true;
    }
    if (!st->input_bvh && !st->out_of_memory && !(st->input_bvh = sc_hausdorff_bvh_build(st->input)))
        st->out_of_memory = true;
    return st->input_bvh;
}

/* Whether the tracked error joins the cost now. */
static bool tracking_now(state *st) {
    if (!(st->error_weight > 0 || st->max_error2 > 0) || st->nf_alive > st->tracking_from) return false;
    return input_bvh_take(st) != NULL;
}

/* A valid plan that may not go now: dropped, its endpoints marked so that a
 * later collapse next to them queues it again. */
static void reject_edge(state *st, int32_t a, int32_t b) {
    st->rejected++;
    st->vflags[a] |= V_RETRY;
    st->vflags[b] |= V_RETRY;
}

/* Collapse until the face count is at most target or nothing can collapse.
 * Returns false when stalled. */
static bool decimate_to(state *st, int64_t target) {
    bool requeued_since_collapse = false;
    st->tracking_from = TRACKING_SPAN * target;
    if (st->tracking_from > st->nf / TRACKING_START) st->tracking_from = st->nf / TRACKING_START;
    if (st->max_error2 > 0) st->tracking_from = st->nf;   /* the bound holds for every collapse */
    st->tracking_scale = st->error_weight * 2.0 * st->input_area / (double)target;
    while (st->nf_alive > target && !st->out_of_memory) {
        /* live edges are at most 3/2 of the faces plus half the border
         * edges (edge_bound); every valid entry is a live edge, so past
         * 5 / 4 of that bound at least a fifth of the heap is stale, and
         * compacting then costs O(1) per push (stale entries popped one by
         * one cost more than dropping them in bulk) */
        int64_t edge_bound = (3 * (int64_t)st->nf_alive + st->border_edges) / 2;
        if (st->heap_len > edge_bound * 5 / 4 + 1024) heap_compact(st);
        if (st->grid.on && st->nf_alive < st->grid.built_faces / 4 && !grid_build(st)) {
            st->out_of_memory = true;
            break;
        }
        heap_entry e;
        if (!heap_pop(st, &e)) {
            if (requeued_since_collapse) return false;
            /* a last full pass catches edges a local update missed */
            queue_all_edges(st, st->threads);
            requeued_since_collapse = true;
            continue;
        }
        int32_t a = entry_a(&e), b = entry_b(&e);
        if (!(st->vflags[a] & V_ALIVE) || !(st->vflags[b] & V_ALIVE) || st->version[a] != e.va ||
            st->version[b] != e.vb) {
            continue;
        }
        collapse_plan p;
        plan_edge(st, a, b, &p);
        solve_plan(st, &p);
        if (p.reason != BLOCK_NONE || !isfinite(p.cost)) {
            st->vflags[a] |= V_RETRY;
            st->vflags[b] |= V_RETRY;
            continue;
        }
        /* With tracking on, the tracked error joins the cost here, at the
         * front of the queue: queued costs leave it out, so they are lower
         * bounds, and a collapse whose full cost is above the next queued
         * one waits with its full cost (lazy evaluation: the order is the
         * order of the full costs). */
        double popped = entry_cost(&e);
        bool complete = true, tracked = tracking_now(st), checked = false;
        int32_t seed = -1;
        if (tracked && e.full) {
            if (check_plan(st, &p) != BLOCK_NONE) {
                /* it was measured and is at the front, but cannot collapse: the
                 * test below would drop it; no need to measure it again first */
                reject_edge(st, a, b);
                continue;
            }
            checked = true;   /* the plan does not change before the test below */
        }
        if (tracked) {
            heap_drop_stale_top(st);
            /* past twice the next queued cost, measuring stops: the collapse
             * waits with the part measured, still a lower bound */
            double next = st->heap_len > 0 ? entry_cost(&st->heap[0]) : INFINITY;
            double stop = (2 * next - p.cost) / st->tracking_scale;
            seed = st->near_face[p.keep];
            if (st->max_error2 > 0 && !(stop < st->max_error2)) stop = st->max_error2;   /* past the bound: refused */
            double tracked_e = tracked_error(st, &p, &seed, stop, &complete);
            if (st->max_error2 > 0 && tracked_e > st->max_error2) {
                reject_edge(st, a, b);
                continue;
            }
            p.cost += st->tracking_scale * tracked_e * (st->importance ? fmax(st->importance[a], st->importance[b]) : 1);
            st->tracked_evaluations++;
        }
        if (!complete || p.cost > popped * (1 + 1e-12) + 1e-300) {   /* it costs more than its queued cost */
            heap_entry again = make_entry(st, p.cost, a, b);
            again.full = tracked && complete;
            if (!complete || (st->heap_len > 0 && entry_less(&st->heap[0], &again))) {
                heap_push(st, again);
                continue;
            }
        }
        block_reason r = checked ? BLOCK_NONE : check_plan(st, &p);
        if (r != BLOCK_NONE) {
            reject_edge(st, a, b);
            continue;
        }
        if (!apply_plan(st, &p)) {
            st->out_of_memory = true;
            break;
        }
        if (seed >= 0) st->near_face[p.keep] = seed;
        requeued_since_collapse = false;
        requeue_around(st, p.keep, p.kind != EDGE_INTERIOR);
    }
    return st->nf_alive <= target;
}

/* One pass: every level of `targets` decimated from `in`, each collapse's
 * tracked error bounded by bound_scale x max_error; the levels go to *out,
 * what they measure to *o. */
static int decimate_levels(sc_ctx *ctx, const sc_mesh *in, const int64_t *targets, int ntargets,
                           double bound_scale, sc_lods **out, outcome *o, sc_error *err) {
    int rc = SC_OK;
    *out = NULL;
    state st;
    memset(&st, 0, sizeof st);
    const char *mode = sc_ctx_string(ctx, "seam_mode");
    st.mode = !strcmp(mode, "fixed") ? MODE_FIXED : !strcmp(mode, "free") ? MODE_FREE : MODE_AWARE;
    st.weights = !strcmp(sc_ctx_string(ctx, "weights"), "area_distortion") ? WEIGHTS_AREA_DISTORTION : WEIGHTS_QEM;
    st.collinear_tol = sc_ctx_number(ctx, "collinear_tolerance");
    st.ratio_tol = sc_ctx_number(ctx, "ratio_tolerance");
    st.normal_cos = cos(sc_ctx_number(ctx, "normal_turn") * M_PI / 180.0);
    st.refuse_crossings = sc_ctx_bool(ctx, "refuse_crossings");
    st.uv_step_given = sc_ctx_number(ctx, "uv_precision");
    detect_uv_storage(&st, in);
    st.error_weight = sc_ctx_number(ctx, "error_weight");
    const double max_error = sc_ctx_number(ctx, "max_error");
    const double short_tolerance = sc_ctx_number(ctx, "short_tolerance");
    int64_t samples = sc_ctx_integer(ctx, "hausdorff_samples");
    double uv_weight = sc_ctx_number(ctx, "uv_weight");
    int threads = sc_ctx_threads(ctx);
    st.threads = threads;
    sc_hausdorff_mesh input_mesh = {in->V, in->nv, in->FV, in->nf};
    st.input = &input_mesh;

    double started = sc_now();
    sc_lods *lods = NULL;
    const double diagonal = sc_bbox_diagonal(in->V, in->nv, in->FV, in->nf);
    const double bound = bound_scale * max_error;
    if (bound > 0 && diagonal > 0) st.max_error2 = (diagonal * bound) * (diagonal * bound);
    st.contact_distance = sc_ctx_number(ctx, "contact_distance") * diagonal;
    st.contact_slack = sc_ctx_number(ctx, "contact_slack") * diagonal;
    st.map_texel_length = sc_ctx_number(ctx, "map_texel") * diagonal * (double)sc_ctx_integer(ctx, "map_size");
    const double seam_error = sc_ctx_number(ctx, "seam_error") * diagonal;
    if (st.map_texel_length > 0) {
        st.seam_error2 = seam_error * seam_error;
        st.map_size = (double)sc_ctx_integer(ctx, "map_size");
        st.crease_limit = sc_ctx_number(ctx, "map_crease") * diagonal;
    }
    if (st.error_weight > 0 || st.max_error2 > 0 || samples > 0) input_bvh_start(&st, threads);
    rc = setup(&st, in, uv_weight, err);
    if (rc == SC_OK) {
        seam_census before;
        census_seams(&st, &before);
        int64_t locked = 0;
        for (int32_t v = 0; v < st.nv; v++) locked += (st.vflags[v] & V_LOCKED) != 0;
        total(o, "input.faces", in->nf);
        total(o, "input.seam_edges", (double)before.seam_edges);
        total(o, "input.uncollapsible_seam_edges", (double)before.uncollapsible);
        total(o, "input.uncollapsible_seam_edges_corner", (double)before.corner);
        total(o, "input.uncollapsible_seam_edges_not_collinear", (double)before.not_collinear);
        total(o, "input.uncollapsible_seam_edges_length_ratio", (double)before.length_ratio);
        total(o, "uv_scale", st.uv_scale);
        total(o, "uv_precision", st.uv_precision);
        total(o, "locked_vertices", (double)locked);
        total(o, "contact_vertices", (double)st.input_contacts);
        queue_all_edges(&st, st.threads);
        lods = sc_lods_new();
        if (!lods) rc = sc_fail(err, SC_ENOMEM, "decimate: out of memory");
    }
    double hausdorff_seconds = 0;
    double level_start = started, total_seconds = 0;
    bool stalled = false;
    int64_t blocked[BLOCK_COUNT] = {0}, nblocked = 0;
    for (int level = 0; rc == SC_OK && level < ntargets; level++) {
        if (!stalled && !decimate_to(&st, targets[level])) {
            stalled = true;
            nblocked = census_blocked(&st, blocked);
        }
        if (st.out_of_memory) {
            rc = sc_fail(err, SC_ENOMEM, "decimate: out of memory");
            break;
        }
        double seconds = sc_now() - level_start;
        total_seconds += seconds;
        sc_mesh *mesh = NULL;
        rc = build_level_mesh(&st, in, &mesh, err);
        if (rc != SC_OK) break;
        seam_census census;
        census_seams(&st, &census);
        metric(o, level, "faces", mesh->nf);
        metric(o, level, "target_faces", (double)targets[level]);
        metric(o, level, "seam_edges", (double)census.seam_edges);
        metric(o, level, "seam_edges_collapsed", (double)st.seam_collapses);
        metric(o, level, "uncollapsible_seam_edges", (double)census.uncollapsible);
        metric(o, level, "uncollapsible_seam_edges_corner", (double)census.corner);
        metric(o, level, "uncollapsible_seam_edges_not_collinear", (double)census.not_collinear);
        metric(o, level, "uncollapsible_seam_edges_length_ratio", (double)census.length_ratio);
        metric(o, level, "quadric_cost", total_quadric_cost(&st));
        metric(o, level, "flipped_uv_faces", (double)count_flipped_uv(&st));
        metric(o, level, "seconds", seconds);
        if (stalled && mesh->nf > targets[level]) {
            if (mesh->nf > (1 + short_tolerance) * (double)targets[level])
                warn_short_level(o, level, mesh->nf, targets[level], blocked);
            metric(o, level, "blocked_edges", (double)nblocked);
            for (int r = 1; r < BLOCK_COUNT; r++)
                if (blocked[r] > 0) {
                    char name[64];
                    snprintf(name, sizeof name, "blocked_%s", block_names[r]);
                    metric(o, level, name, (double)blocked[r]);
                }
        }
        if (samples > 0) {
            sc_hausdorff_mesh level_mesh = {mesh->V, mesh->nv, mesh->FV, mesh->nf};
            sc_hausdorff_result hd;
            double measure_start = sc_now();
            if (!input_bvh_take(&st)) {
                sc_mesh_free(mesh);
                rc = sc_fail(err, SC_ENOMEM, "decimate: out of memory");
                break;
            }
            rc = sc_hausdorff_with_bvh(&input_mesh, st.input_bvh, &level_mesh, samples, threads, &hd, err);
            if (rc != SC_OK) {
                sc_mesh_free(mesh);
                break;
            }
            double measured = sc_now() - measure_start;
            hausdorff_seconds += measured;
            metric(o, level, "hausdorff_seconds", measured);
            metric(o, level, "hausdorff", diagonal > 0 ? hd.distance / diagonal : 0);
            if (max_error > 0 && diagonal > 0) {
                double over = hd.distance / (max_error * diagonal);
                if (over > o->over) o->over = over;
                if (over > 1)
                    warn(o, "lod%d: sampled Hausdorff distance %.3g%% of the diagonal is beyond max_error %.3g%%",
                         level, 100 * hd.distance / diagonal, 100 * max_error);
            }
            metric(o, level, "hausdorff_mean", diagonal > 0 ? 0.5 * (hd.mean_a_to_b + hd.mean_b_to_a) / diagonal : 0);
        }
        sc_value *mv = sc_value_new_mesh(mesh);
        sc_atlas *atlas = mv ? sc_atlas_new(mv) : NULL;
        sc_value *av = atlas ? sc_value_new_atlas(atlas) : NULL;
        if (!av || sc_lods_add(lods, av) != SC_OK) {
            if (!atlas) sc_value_release(mv);
            rc = sc_fail(err, SC_ENOMEM, "decimate: out of memory");
            break;
        }
        level_start = sc_now();
    }
    if (rc == SC_OK) {
        total(o, "seconds", total_seconds);
        o->seconds = total_seconds + hausdorff_seconds;
        if (samples > 0) total(o, "hausdorff_seconds", hausdorff_seconds);
        total(o, "collapses", (double)st.collapses);
        total(o, "rejected_collapses", (double)st.rejected);
        total(o, "tracked_evaluations", (double)st.tracked_evaluations);
        total(o, "levels", ntargets);
        if (o->out_of_memory) rc = sc_fail(err, SC_ENOMEM, "decimate: out of memory");
        else *out = lods, lods = NULL;
    }
    sc_lods_free(lods);
    if (st.bvh_pending) pthread_join(st.bvh_thread, NULL);   /* a build still running */
    sc_hausdorff_bvh_free(st.input_bvh);
    state_free(&st);
    return rc;
}

/* Levels whose sampled Hausdorff distance passes max_error (the tracked
 * error samples each collapse's fan at a few points; the measure samples
 * the whole level) are made again from the input, every collapse bounded
 * tighter by the overshoot measured, up to MAX_TIGHTENINGS times: the levels
 * output are within max_error by the sampled measure, or say they are not. */
#define MAX_TIGHTENINGS 8

static int run(sc_ctx *ctx, sc_error *err) {
    const sc_mesh *in = sc_ctx_mesh(ctx, "mesh");
    if (!in) return sc_fail(err, SC_EINPUT, "decimate:mesh: the input is not a mesh (or an atlas)");
    int rc = sc_mesh_check(in, err);
    if (rc != SC_OK) return sc_error_prefix(err, "decimate:mesh");
    if (in->nf < 1) return sc_fail(err, SC_EINPUT, "decimate:mesh: no faces");
    int64_t *targets = NULL;
    int ntargets = 0;
    rc = read_targets(ctx, in->nf, &targets, &ntargets, err);
    if (rc != SC_OK) return rc;
    bool measured_bound = sc_ctx_number(ctx, "max_error") > 0 && sc_ctx_integer(ctx, "hausdorff_samples") > 0;
    double scale = 1, seconds = 0, last_over = INFINITY;
    sc_lods *lods = NULL;
    outcome o = {0};
    for (int tightenings = 0;; tightenings++) {
        outcome_free(&o);
        o = (outcome){0};
        sc_buf_init(&o.warnings);
        sc_lods_free(lods);
        rc = decimate_levels(ctx, in, targets, ntargets, scale, &lods, &o, err);
        seconds += o.seconds;
        if (rc != SC_OK || !measured_bound || o.over <= 1 || tightenings == MAX_TIGHTENINGS) {
            total(&o, "bound_tightenings", tightenings);
            total(&o, "bound_scale", scale);
            total(&o, "seconds_all_passes", seconds);
            break;
        }
        double step = 0.95 / o.over;
        if (o.over > 0.999 * last_over) step = min2(step, 0.8);   /* stuck: not where the tracked error looks */
        last_over = o.over;
        scale *= step;
    }
    free(targets);
    if (rc == SC_OK && o.out_of_memory) rc = sc_fail(err, SC_ENOMEM, "decimate: out of memory");
    sc_value *value = rc == SC_OK ? sc_value_new_lods(lods) : NULL;
    if (rc == SC_OK && !value) rc = sc_fail(err, SC_ENOMEM, "decimate: out of memory");
    if (value) {
        lods = NULL;
        sc_ctx_set_output(ctx, "lods", value);
        for (int32_t i = 0; i < o.metrics.count; i++) sc_ctx_metric(ctx, o.metrics.items[i].name, o.metrics.items[i].value);
        for (char *line = (char *)o.warnings.data, *end; line && (end = strchr(line, '\n')); line = end + 1) {
            *end = 0;
            sc_ctx_warn(ctx, "%s", line);
        }
    }
    sc_lods_free(lods);
    outcome_free(&o);
    return rc;
}

static const char *const seam_modes[] = {"aware", "fixed", "free", NULL};
static const char *const weight_modes[] = {"qem", "area_distortion", NULL};

static const sc_param_desc params[] = {
    {.name = "ratio", .type = SC_PARAM_NUMBERS, .def_string = "0.5,0.1,0.01", .min = 0, .max = 1,
     .doc = "target face counts as fractions of the input, one level each, not increasing",
     .check_list = check_ratios},
    {.name = "faces", .type = SC_PARAM_NUMBERS, .def_string = "", .min = 1, .max = 2e9,
     .doc = "absolute target face counts (when given, they replace ratio), not increasing",
     .check_list = check_faces},
    {.name = "seam_mode", .type = SC_PARAM_ENUM, .def_string = "aware", .choices = seam_modes,
     .doc = "aware: Liu et al. 2017 seam-aware collapses; fixed: silhouette edges never collapse; "
            "free: uv constraints ignored (breaks seams; a baseline)"},
    {.name = "weights", .type = SC_PARAM_ENUM, .def_string = "qem", .choices = weight_modes,
     .doc = "qem: summed quadrics; area_distortion: Coll & Paradinas 2010 weighted quadrics"},
    {.name = "uv_weight", .type = SC_PARAM_NUMBER, .def = 1.0, .min = 1e-6, .max = 1e6,
     .doc = "scale of the uv dimensions in the 5-D quadric, relative to sqrt(surface area / uv area) "
            "(1: a unit of uv error counts like a unit of surface distance)"},
    {.name = "collinear_tolerance", .type = SC_PARAM_NUMBER, .def = 1e-9, .min = 0, .max = 0.1,
     .doc = "distance of a uv silhouette vertex from the chord of its neighbours still taken as collinear, "
            "relative to the chord's length (on top of uv_precision)"},
    {.name = "ratio_tolerance", .type = SC_PARAM_NUMBER, .def = 1e-9, .min = 0, .max = 0.1,
     .doc = "relative difference of the two sides' uv length ratios of a seam still taken as equal "
            "(on top of uv_precision)"},
    {.name = "uv_precision", .type = SC_PARAM_NUMBER, .def = -1, .min = -1, .max = 0.1,
     .doc = "the step the input's uv coordinates are stored with; rounding by up to half a step is not "
            "taken as a bend or a length difference; -1: detect it per coordinate (significant digits of "
            "OBJ text, float32, double)"},
    {.name = "error_weight", .type = SC_PARAM_NUMBER, .def = 30, .min = 0, .max = 1e6,
     .doc = "weight, near each target, of the tracked distance between the level and the input in the collapse "
            "cost, relative to the quadric of a vertex's share of the target's surface that far off "
            "(0: the quadric alone)"},
    {.name = "short_tolerance", .type = SC_PARAM_NUMBER, .def = 0.1, .min = 0, .max = 1e6,
     .doc = "a level that stops above its target by more than this fraction of the target is reported "
            "short: a warning naming what blocked it (--strict makes that exit status 1)"},
    {.name = "max_error", .type = SC_PARAM_NUMBER, .def = 0, .min = 0, .max = 1,
     .doc = "refuse every collapse that would leave the level farther than this from the input (fraction "
            "of the bounding-box diagonal; the tracked error, measured on every collapse); a level that "
            "cannot reach its target stops there (blocked_max_error). 0: no bound"},
    {.name = "map_size", .type = SC_PARAM_INTEGER, .def = 0, .min = 0, .max = 65536,
     .doc = "size of the displacement maps that will restore the levels' detail (bake_displacement's size): "
            "collapses cost more where one of their texels spans more than map_texel of the surface, and none "
            "makes a uv sliver or moves a uv silhouette by more than seam_error; 0: off"},
    {.name = "map_texel", .type = SC_PARAM_NUMBER, .def = 2e-3, .min = 1e-9, .max = 1,
     .doc = "with map_size: the texel length (fraction of the bounding-box diagonal) above which a face's "
            "collapses cost more, by the square of the ratio"},
    {.name = "seam_error", .type = SC_PARAM_NUMBER, .def = 5e-4, .min = 1e-9, .max = 1,
     .doc = "with map_size: the largest distance (fraction of the bounding-box diagonal) between an input vertex "
            "on a uv silhouette and the level at the same uv (a seam-free map cannot restore a seam)"},
    {.name = "map_crease", .type = SC_PARAM_NUMBER, .def = 4e-3, .min = 0, .max = 1e9,
     .doc = "with map_size: the sharpest crease a collapse may leave inside a chart, as the texel length "
            "(fraction of the bounding-box diagonal) times the dihedral angle (radians), which a bilinear map "
            "rounds off; 0: no bound"},
    {.name = "normal_turn", .type = SC_PARAM_NUMBER, .def = 30, .min = 0, .max = 90,
     .doc = "largest angle (degrees) a face's normal may turn in one collapse (90: refuse flips only)"},
    {.name = "contact_distance", .type = SC_PARAM_NUMBER, .def = 0, .min = 0, .max = 1,
     .doc = "where an open part's border lies within this fraction of the bounding-box diagonal of another "
            "part (a rim on a body), no collapse may take it, or a point of its edges, more than contact_slack "
            "farther from the other parts or higher over their nearest face: decimated apart they leave a gap "
            "that shows the open part's inside; 0: off"},
    {.name = "contact_slack", .type = SC_PARAM_NUMBER, .def = 1e-5, .min = 0, .max = 1,
     .doc = "with contact_distance: how much farther from the other parts, or higher over them (fraction of "
            "the bounding-box diagonal), an open part's border in contact may end up than in the input"},
    {.name = "refuse_crossings", .type = SC_PARAM_BOOL, .def = 1,
     .doc = "refuse collapses that push a face through another it shares no vertex with (parts decimated "
            "through each other show back faces); crossings of the input stay"},
    {.name = "hausdorff_samples", .type = SC_PARAM_INTEGER, .def = 100000, .min = 0, .max = 1e8,
     .doc = "surface samples per mesh for the Hausdorff metric (0: skip the metric)"},
};

static const sc_port_desc inputs[] = {
    {.name = "mesh", .kind = SC_KIND_MESH, .doc = "the mesh to decimate (an atlas's mesh: its textures do not matter)"},
};

static const sc_port_desc outputs[] = {
    {.name = "lods", .kind = SC_KIND_LODS,
     .doc = "one textureless atlas per target, each decimated from the one before, all in the input's uv layout"},
};

static const sc_kernel *const kernels[] = {&sc_kernel_hausdorff, &sc_kernel_quadric, &sc_kernel_tangent, NULL};

const sc_node_desc sc_node_decimate = {
    .type = "decimate",
    .version = 11,
    .summary = "seam-aware edge-collapse decimation into a chain of levels of detail sharing one parameterisation",
    .inputs = inputs,
    .ninputs = SC_COUNT(inputs),
    .outputs = outputs,
    .noutputs = SC_COUNT(outputs),
    .params = params,
    .nparams = SC_COUNT(params),
    .run = run,
    .kernels = kernels,
};
