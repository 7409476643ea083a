/* sc_obj.h - Wavefront OBJ + MTL reader, from bytes in memory.
 *
 * The reader never touches the file system: the caller passes the OBJ's bytes
 * and a callback that fetches an MTL named by `mtllib` (a node passes one that
 * goes through sc_ctx_read_file, so the cache records the MTL as a dependency).
 *
 * What it reads: v (3 numbers; more are ignored: w or vertex colours), vt (u
 * [v [w]], v defaults to 0), vn, f in every form (v, v/vt, v//vn, v/vt/vn)
 * with negative (relative) indices, polygons (fan-triangulated from the first
 * corner), mtllib, usemtl, comments, line continuations ('\' at the end of a
 * line), CRLF line ends, a UTF-8 byte order mark. o, g, s, l, p and other
 * statements with a plain keyword are ignored. From MTL files: newmtl, map_Kd
 * (-> "color"), norm / map_Bump / bump (-> "normal", norm preferred), map_Ke
 * (-> "emissive"); map options such as `-bm 1.0` or `-o 0 0 0` are skipped.
 *
 * Errors name "file:LINE: ..." for: NUL bytes or bytes that are not a
 * statement, numbers that do not parse, NaN/Inf coordinates, vertex lines with
 * too few numbers, faces with fewer than 3 corners, a face with texture
 * coordinates at some corners only, index 0, indices out of range (which one, and how many there
 * are), more than SC_OBJ_MAX_ELEMENTS of anything, an OBJ without faces, and
 * an MTL the callback cannot read.
 *
 * A face without texture coordinates gets uv (0, 0), one vt added for all
 * of them (counted in sc_obj.faces_without_uv): uv without area, which
 * quad_chartify's auto mode replaces with an atlas of its own.
 *
 * Documented repairs (counted in sc_obj.degenerate_faces_dropped etc.):
 *   - a triangle that repeats a position index is dropped;
 *   - positions, uvs and normals no face refers to are dropped (order kept);
 *   - normals are kept only when every face corner has one, else dropped;
 *   - coordinates of -0 are stored as +0 (so text round trips are exact);
 *   - backslashes in MTL map file names become '/'.
 *
 * Materials are numbered in the order faces first use them. Faces before any
 * usemtl use the material "default". Positive indices may refer to elements
 * defined later in the file (they are checked once the whole file is read);
 * negative indices count back from the elements read so far.
 */
#ifndef SC_OBJ_H
#define SC_OBJ_H

#include "sc_value.h"

/* Bump whenever results of this library can change for the same inputs:
 * every node listing sc_kernel_obj (or a kernel built on it) is re-keyed. */
#define SC_OBJ_VERSION 2
extern const sc_kernel sc_kernel_obj;

/* Limit on vertices, uvs, normals and triangles alike, so that a small file
 * cannot ask for gigabytes. */
#define SC_OBJ_MAX_ELEMENTS (1 << 26)

/* Fetch the bytes of a file named in the OBJ (an MTL), `path` relative to the
 * OBJ's directory as written in the file. Return SC_OK, or an error code with
 * err filled (the reader prefixes it with "file:line: mtllib NAME"). */
typedef int (*sc_obj_read_fn)(void *ud, const char *path, sc_buf *out, sc_error *err);

/* A texture file named by an MTL for one material. */
typedef struct sc_obj_map {
    int32_t material;   /* index into mesh->materials */
    char *slot;         /* "color", "normal" or "emissive" */
    char *path;         /* file name relative to the OBJ's directory (or absolute) */
    char *mtl;          /* the MTL that names it (as written after mtllib) */
    int line;           /* line of the map statement in that MTL */
} sc_obj_map;

typedef struct sc_obj {
    sc_mesh *mesh;                    /* owned; NULL after a failed parse */
    int32_t nmaps;
    sc_obj_map *maps;                 /* in material order, then slot order */
    int64_t degenerate_faces_dropped; /* triangles that repeated a position */
    int64_t polygons;                 /* faces with more than 3 corners */
    int64_t unreferenced_dropped;     /* v/vt/vn lines no face used */
    int64_t faces_without_uv;         /* triangles whose corners name no vt: uv (0, 0) */
    bool uv_missing;                  /* every triangle's */
    bool normals_dropped;             /* some corner had no vn */
} sc_obj;

/* Parse an OBJ. `name` is used in messages only (the file name). read_mtl may
 * be NULL: mtllib statements are then ignored. On success fills *out (free it
 * with sc_obj_free); on failure *out is left empty. */
int sc_obj_parse(const char *name, const void *bytes, size_t size, sc_obj_read_fn read_mtl,
                 void *ud, sc_obj *out, sc_error *err);
void sc_obj_free(sc_obj *obj);

/* The common last step of the OBJ and glTF readers: build an sc_mesh from
 * indexed triangles (0-based FV/FU/FN, FM material per triangle), dropping
 * triangles that repeat a position index (count in *degenerate) and the
 * positions, uvs and normals no remaining triangle uses (count added to
 * *unreferenced when not NULL), keeping the order of what remains. N/FN may be
 * NULL (no normals). Indices must already be in range. Names are copied. */
int sc_mesh_build_compact(const double *V, int64_t nv, const double *U, int64_t nu,
                          const double *N, int64_t nn, const int32_t *FV, const int32_t *FU,
                          const int32_t *FN, const int32_t *FM, int64_t nf,
                          char *const *materials, int32_t nmat, sc_mesh **out,
                          int64_t *degenerate, int64_t *unreferenced, sc_error *err);

#endif
