/* sc_tangent.h - tangent-space normal maps: MikkTSpace frames, the
 * conversion of a map to object space and back, and the seam gap of the
 * normal a renderer reconstructs.
 *
 * glTF normal maps are tangent-space: a renderer decodes t = 2 x - 1 from
 * the texture and shades with
 *     n = normalize(t.x T + t.y B + t.z N),   B = w cross(N, T),
 * where T (with its sign w) and N are the vertex tangent and normal,
 * interpolated across the triangle without renormalising (MikkTSpace's
 * recommended reconstruction, which the glTF specification names). Across a
 * uv seam the two sides' frames differ, so equal texel values on both sides
 * are not equal normals: the map must be made continuous in object space.
 * The erase kernel converts a tangent-space map to object space texel by
 * texel with the frame of the texel's face, erases it there and converts it
 * back; sc_tangent_seam_gap then measures what a renderer sees on both sides.
 *
 * Frames (sc_tangent_frames_build) follow MikkTSpace: each face's tangent is
 * d position / d u from its uv (u, v with v up, as seamcook stores uv and as
 * Blender's importer hands MikkTSpace glTF uv), projected into the tangent
 * plane of each corner's normal and normalised; the corners that share a
 * position, a normal and a uv and have the same uv orientation average these
 * with their corner angles as weights. w is +1 where the face's uv keep the
 * surface's orientation and -1 where they mirror it, the orientation being
 * taken against the face's normals: the same as MikkTSpace's on faces wound
 * the way their normals point, and on a face wound against them (which
 * MikkTSpace gives the mirrored sign) the sign its neighbours have, which is
 * what bakers and authored tangents use. Faces whose uv are
 * degenerate add nothing; a corner left with no tangent takes a unit vector
 * orthogonal to its normal.
 *
 * Normals (sc_tangent_corner_normals): the mesh's own; a mesh without them
 * (decimated levels, generated meshes) gets smooth ones, the corner angle
 * weighted mean of the normals of the faces around the vertex that turn less
 * than SC_TANGENT_SMOOTH_DEGREES from the corner's face, so hard edges stay
 * hard. The glTF writer writes these normals and these frames, so a renderer
 * rebuilds exactly the frames a map was converted with.
 */
#ifndef SC_TANGENT_H
#define SC_TANGENT_H

#include "sc_seam.h"
#include "sc_value.h"

/* Bump whenever results of this library can change for the same inputs:
 * every node listing sc_kernel_tangent (or a kernel built on it) is re-keyed. */
#define SC_TANGENT_VERSION 2
extern const sc_kernel sc_kernel_tangent;

#define SC_TANGENT_SMOOTH_DEGREES 60.0
/* Texels around a chart that take its faces' frames (sc_tangent_texels_build's band). */
#define SC_TANGENT_BAND 3.0

/* Per corner (face f, corner c at 3 f + c): 3 doubles, unit; NULL when out
 * of memory. Free with free(). */
double *sc_tangent_corner_normals(const sc_mesh *m);

/* Per corner (face f, corner c at 3 f + c) of a mesh. */
typedef struct sc_tangent_frames {
    int32_t nf;
    double *tangent;   /* 4 per corner: unit xyz orthogonal to the normal, then w = +1 or -1 */
    double *normal;    /* 3 per corner: unit */
} sc_tangent_frames;

int sc_tangent_frames_build(const sc_mesh *m, sc_tangent_frames *out, sc_error *err);
void sc_tangent_frames_free(sc_tangent_frames *f);

/* The frame at barycentric point b of face f, interpolated as a renderer
 * does: T and N linearly (not renormalised), B = w cross(N, T). */
void sc_tangent_frame_at(const sc_tangent_frames *f, int32_t face, const double b[3], double T[3], double B[3],
                         double N[3]);

/* The face each texel of a grid takes its frame from: the face of
 * `material` whose uv triangle holds the texel centre, else the nearest one
 * within `band` texels (the frame at the nearest point of the triangle),
 * the first in face order where several do; face -1 for texels further
 * from every face. Texels are taken through the
 * grid's wrap modes, on `threads` threads (the result is the same). */
typedef struct sc_tangent_texels {
    int32_t width, height;
    int32_t *face;     /* per texel */
    float *bary;       /* 2 per texel: barycentrics of corners 1 and 2 */
} sc_tangent_texels;

int sc_tangent_texels_build(const sc_mesh *m, int32_t material, const sc_seam_grid *g, double band, int threads,
                            sc_tangent_texels *out, sc_error *err);
void sc_tangent_texels_free(sc_tangent_texels *t);

/* Whether a normal map stores signed components (a float map with a
 * negative value) rather than 0..1 for -1..1. */
bool sc_tangent_signed(const sc_image_data *img);

/* The object-space normal field of tangent-space map img (any pixel type):
 * f32, signed, n = t.x T + t.y B + t.z N per texel with a face, t itself
 * elsewhere; channels past the third copied. NULL when out of memory.
 * threads: how many work on it (the result is the same). */
sc_image_data *sc_tangent_to_object(const sc_image_data *img, const sc_tangent_frames *f,
                                    const sc_tangent_texels *tx, int threads);

/* Back: per texel with a face, t solving [T B N] t = n, scaled into the unit
 * cube where it leaves it; elsewhere n itself. f32 in the encoding of
 * `like` (0..1 unless like is signed), with like's other channels and tags.
 * NULL when out of memory or when sizes differ. */
sc_image_data *sc_tangent_from_object(const sc_image_data *obj, const sc_image_data *like,
                                      const sc_tangent_frames *f, const sc_tangent_texels *tx, int threads);

/* The gap between the two sides' reconstructed unit normals along every
 * seam of `seams` (faces of one material), sampled as the grid is sampled
 * (bilinear, wrap modes) at several points per texel of each seam: the
 * largest |n_a - n_b| (about the angle in radians) and its mean over the
 * seams' 3D length. img: the map as stored (any pixel type). f NULL: the
 * stored vectors themselves are compared, as if every frame were the same. */
int sc_tangent_seam_gap(const sc_mesh *m, const sc_seam_set *seams, const sc_seam_grid *g,
                        const sc_tangent_frames *f, const sc_image_data *img, double *max_gap,
                        double *mean_gap, sc_error *err);

#endif
