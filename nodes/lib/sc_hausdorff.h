/* sc_hausdorff.h - sampled symmetric Hausdorff distance between two triangle
 * meshes, and the closest-point BVH it uses.
 *
 * Sampling: every vertex a face uses, plus, on each triangle, the points of a
 * regular barycentric grid (i/r, j/r) with r chosen so that the spacing
 * matches the requested sample density (so edges are sampled too, not just
 * interiors). Each sample's distance to the other mesh is exact (closest point
 * on a triangle, Ericson's regions), found through a bounding-volume
 * hierarchy. The result depends only on the meshes and the sample count: no
 * randomness, no thread-count dependence.
 */
#ifndef SC_HAUSDORFF_H
#define SC_HAUSDORFF_H

#include "sc_base.h"

/* Bump whenever results of this library can change for the same inputs:
 * every node listing sc_kernel_hausdorff (or a kernel built on it) is re-keyed. */
#define SC_HAUSDORFF_VERSION 1
extern const sc_kernel sc_kernel_hausdorff;

/* A triangle mesh seen through its positions (nv x 3) and faces (nf x 3). */
typedef struct sc_hausdorff_mesh {
    const double *V;
    int32_t nv;
    const int32_t *F;
    int32_t nf;
} sc_hausdorff_mesh;

typedef struct sc_hausdorff_bvh sc_hausdorff_bvh;

/* Build a BVH over a mesh's triangles (the mesh must outlive it). NULL when
 * out of memory or the mesh has no faces. */
sc_hausdorff_bvh *sc_hausdorff_bvh_build(const sc_hausdorff_mesh *m);
void sc_hausdorff_bvh_free(sc_hausdorff_bvh *b);
/* Squared distance from p to the mesh, with the closest point and its face
 * (either may be NULL). */
double sc_hausdorff_bvh_closest(const sc_hausdorff_bvh *b, const double p[3], double closest[3],
                                int32_t *face);

/* The squared distance from p to the mesh where it exceeds floor2; at or
 * below floor2 the walk may stop at the first face found that close and
 * return its distance (<= floor2, not necessarily the least). That is all a
 * running maximum of distances needs, at a fraction of the cost. seed: a
 * face near p to start from, or -1; *face (may be NULL) receives the face
 * whose distance is returned, a good seed for a nearby point. */
double sc_hausdorff_bvh_closest_above(const sc_hausdorff_bvh *b, const double p[3], double floor2, int32_t seed,
                                      int32_t *face);

/* Closest point to p on triangle abc (Ericson, Real-Time Collision Detection 5.1.5). */
void sc_hausdorff_closest_on_triangle(const double p[3], const double a[3], const double b[3],
                                      const double c[3], double out[3]);

typedef struct sc_hausdorff_result {
    double a_to_b, b_to_a;     /* one-sided maxima (model units) */
    double distance;           /* max of the two */
    double mean_a_to_b, mean_b_to_a;
    int64_t samples_a, samples_b;
} sc_hausdorff_result;

/* Symmetric sampled Hausdorff distance. samples: the number of surface
 * samples to aim for on each mesh (>= 1; vertices come on top). threads: the
 * parallelism to use (results never depend on it). */
int sc_hausdorff(const sc_hausdorff_mesh *a, const sc_hausdorff_mesh *b, int64_t samples, int threads,
                 sc_hausdorff_result *out, sc_error *err);

/* The same, with a BVH of mesh a built beforehand (sc_hausdorff_bvh_build(a);
 * NULL: built here), so that several meshes can be measured against a
 * without rebuilding it. */
int sc_hausdorff_with_bvh(const sc_hausdorff_mesh *a, const sc_hausdorff_bvh *a_bvh, const sc_hausdorff_mesh *b,
                          int64_t samples, int threads, sc_hausdorff_result *out, sc_error *err);

#endif
