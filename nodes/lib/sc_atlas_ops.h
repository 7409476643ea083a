/* sc_atlas_ops.h - small operations on atlases that several nodes share.
 *
 *  - sc_atlas_ops_mesh_union: meshes as disjoint copies in one mesh, so that
 *    one erasure (sc_erase) sees the seams of all of them at once (one texture
 *    serving every level of detail); _distinct takes each distinct mesh
 *    value once.
 *  - sc_atlas_ops_erase: erase the seams of a set of images on a mesh with
 *    sc_erase. Each image gets a slot of its own, so two images of one name
 *    and material are erased side by side.
 *  - Inline helpers of the per-texel rasterisers (bake_displacement's raster,
 *    mipmap's chart band): segment distance and the columns of a row that
 *    can lie within a distance of a triangle.
 */
#ifndef SC_ATLAS_OPS_H
#define SC_ATLAS_OPS_H

#include <math.h>

#include "sc_erase.h"
#include "sc_value.h"

/* Bump whenever results of this library can change for the same inputs:
 * every node listing sc_kernel_atlas_ops (or a kernel built on it) is re-keyed. */
#define SC_ATLAS_OPS_VERSION 3
extern const sc_kernel sc_kernel_atlas_ops;

/* The meshes one after the other (vertex, uv and face indices shifted) in a
 * new mesh value, with a normal per corner (each mesh's, or the smooth ones
 * sc_tangent_corner_normals gives a mesh without), so that tangent frames on
 * the union are each mesh's own; every mesh must have the materials of the
 * first (same count and names). NULL when out of memory, or when the counts overflow or
 * the materials differ. */
sc_value *sc_atlas_ops_mesh_union(const sc_mesh *const *meshes, int n);

/* The same over mesh values, each distinct value (by digest) once: a level
 * that repeats another (a stalled decimation) adds no second copy of its
 * seams, which would weigh them twice in the seam energy. */
sc_value *sc_atlas_ops_mesh_union_distinct(const sc_value *const *meshes, int n);

/* One image to erase: its material, wrap modes, (retained by the caller)
 * image value, and the slot it fills, which tells the erase kernel what it
 * holds (a "normal" slot may be a tangent-space map, erased through the
 * mesh's frames); NULL: a data map. */
typedef struct sc_atlas_ops_map {
    int32_t material;
    sc_wrap wrap_u, wrap_v;
    sc_value *image;
    const char *slot;
} sc_atlas_ops_map;

/* Erase maps[0..n) on `mesh` with sc_erase (each map a texture of its own,
 * named by its slot, or map<i> without one). On success f32_out[i] and native_out[i] (sc_erase's float
 * and native results) hold new references, either array may be NULL. On
 * failure nothing is stored and err says what failed. */
int sc_atlas_ops_erase(const sc_mesh *mesh, const sc_atlas_ops_map *maps, int n, const sc_erase_options *o,
                       int threads, sc_value **f32_out, sc_value **native_out, sc_error *err);

/* Squared distance of point (px, py) from the segment (ax, ay)-(bx, by)
 * (inline: rasterisers call it per texel). */
static inline double sc_atlas_ops_segment_distance2(double px, double py, double ax, double ay, double bx,
                                                    double by) {
    double dx = bx - ax, dy = by - ay, l2 = dx * dx + dy * dy;
    double t = l2 > 0 ? ((px - ax) * dx + (py - ay) * dy) / l2 : 0;
    t = t < 0 ? 0 : t > 1 ? 1 : t;
    double ex = ax + t * dx - px, ey = ay + t * dy - py;
    return ex * ex + ey * ey;
}

/* The columns [*i0, *i1] of row `row` whose distance to triangle (x, y) may
 * be within r (all in texel-centre coordinates): the triangle's box grown by
 * r, cut by its three edge lines pushed out by r (a point farther than r
 * from an edge's line, on its outer side, is farther than r from the
 * triangle). The cut keeps a slack of 1e-6 texel, so rounding never drops a
 * texel that is within r; callers still measure each texel exactly. */
static inline void sc_atlas_ops_row_span(const double x[3], const double y[3], double r, double row, int64_t *i0,
                                         int64_t *i1) {
    double lo = fmin(x[0], fmin(x[1], x[2])) - r, hi = fmax(x[0], fmax(x[1], x[2])) + r;
    double area = (x[1] - x[0]) * (y[2] - y[0]) - (x[2] - x[0]) * (y[1] - y[0]);
    for (int k = 0; k < 3 && area != 0; k++) {
        double ax = x[k], ay = y[k], dx = x[(k + 1) % 3] - ax, dy = y[(k + 1) % 3] - ay, len = sqrt(dx * dx + dy * dy);
        if (!(len > 0)) continue;
        double ox = (area > 0 ? dy : -dy) / len, oy = (area > 0 ? -dx : dx) / len;   /* outward unit normal */
        double rest = r + 1e-6 - (row - ay) * oy;   /* within: (i - ax) ox <= rest */
        if (ox > 1e-12) hi = fmin(hi, ax + rest / ox);
        else if (ox < -1e-12) lo = fmax(lo, ax + rest / ox);
        else if (rest < 0) hi = lo - 1;   /* the whole row lies beyond this edge */
    }
    *i0 = (int64_t)ceil(lo), *i1 = (int64_t)floor(hi);
}

#endif
