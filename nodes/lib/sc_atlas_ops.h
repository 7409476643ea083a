/* sc_atlas_ops.h - small operations on atlases that several nodes share.
 *
 *  - sc_atlas_ops_mesh_union: meshes as disjoint copies in one mesh, so that
 *    one erase_seams run sees the seams of all of them at once (one texture
 *    serving every level of detail).
 *  - sc_atlas_ops_erase: erase the seams of a set of images on a mesh by
 *    running the erase_seams node (a pure function, through sc_ctx). Each
 *    image gets a slot of its own, so two images of one name and material are
 *    erased side by side.
 */
#ifndef SC_ATLAS_OPS_H
#define SC_ATLAS_OPS_H

#include "sc_value.h"

/* The meshes one after the other (vertex, uv and face indices shifted) in a
 * new mesh value; every mesh must have the materials of the first (same
 * count and names). NULL when out of memory, or when the counts overflow or
 * the materials differ. */
sc_value *sc_atlas_ops_mesh_union(const sc_mesh *const *meshes, int n);

/* One image to erase: its material, wrap modes and (retained by the caller)
 * image value. */
typedef struct sc_atlas_ops_map {
    int32_t material;
    sc_wrap wrap_u, wrap_v;
    sc_value *image;
} sc_atlas_ops_map;

/* Run erase_seams on `mesh` with maps[0..n) (params gap_tolerance and
 * quantize; quantize NULL keeps the node's default; `params`, when not
 * NULL, more name, value pairs, NULL-terminated). On success f32_out[i]
 * (erase_seams's float output) and native_out[i] (its output in the input's
 * pixel type) hold new references, either array may be NULL. On failure
 * nothing is stored and err says what failed. */
int sc_atlas_ops_erase(sc_value *mesh, const sc_atlas_ops_map *maps, int n, double gap_tolerance,
                       const char *quantize, const char *const *params, int threads, sc_value **f32_out,
                       sc_value **native_out, sc_error *err);

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

#endif
