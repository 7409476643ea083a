/* sc_gltf.h - glTF 2.0 reader (.gltf JSON and .glb binary), from bytes in memory.
 *
 * The reader never touches the file system: external buffers (and nothing
 * else) are fetched through a callback, so a node can route them through
 * sc_ctx_read_file; data: URIs (base64) are decoded inline; a .glb's binary
 * chunk serves buffer 0. External images are returned as paths for the
 * caller to read; embedded images (data: URI or bufferView) as bytes.
 *
 * What it reads: the default scene (`scene`, else scene 0, else every root
 * node), its node hierarchy with TRS or matrix transforms baked in (positions
 * by the full matrix, normals by the inverse transpose, renormalised), every
 * primitive of mode TRIANGLES (4 or absent; other modes are skipped and
 * counted), indexed (u8/u16/u32) or not; POSITION and NORMAL as float VEC3,
 * TEXCOORD_0 as float or normalised u8/u16 VEC2; with KHR_mesh_quantization
 * (gltfpack's output) POSITION and TEXCOORD_0 also as 8/16-bit integers,
 * normalised or not, and NORMAL as normalised signed 8/16-bit integers, which
 * the node and texture transforms scale back. glTF's uv origin is the top
 * left: v is stored as 1 - v (OBJ and GL convention, v = 0 at the bottom).
 * A primitive without TEXCOORD_0 gets uv (0, 0) (counted in
 * sc_gltf.faces_without_uv): uv without area, which quad_chartify's auto
 * mode replaces; normals are kept only when every primitive has them.
 *
 * Welding: glTF splits vertices at uv seams. Surface vertices whose positions
 * (after the transform, in double precision) are equal are merged into one V
 * entry, and uv vertices are the distinct (position, uv) pairs, numbered in
 * order of first appearance. This is the rule of the corpus tools
 * (meshstats.py), so seam and vertex counts agree with their stats. -0 and +0
 * count as equal. Triangles that repeat a welded position are dropped and
 * counted; positions and uvs no triangle uses are dropped.
 *
 * Materials: the glTF materials the scene uses, in glTF order, then "default"
 * for primitives without one. Textures per material: baseColorTexture (or
 * KHR_materials_pbrSpecularGlossiness diffuseTexture) -> "color",
 * normalTexture -> "normal", emissiveTexture -> "emissive", occlusionTexture ->
 * "occlusion", metallicRoughnessTexture -> "metallic_roughness"; wrap from the
 * texture's sampler (default repeat). A texture that uses a uv set other than
 * TEXCOORD_0 (or whose KHR_texture_transform names another) is skipped and
 * counted. KHR_texture_transform is applied to the uv as they are read, so
 * the atlas and every file written from it need no transform: the textures of
 * one material that sample TEXCOORD_0 must share one transform, else the file
 * is refused naming the material and both textures.
 *
 * Errors name the file and the element: "Duck.gltf: accessor 3: count 506 with
 * stride 12 needs 6072 bytes, bufferView 2 has 6000". Every index, offset,
 * length and count is checked before use; sparse accessors, accessors without
 * a bufferView (all zeros), Draco and other required extensions (all but
 * KHR_materials_*, KHR_mesh_quantization, KHR_texture_transform and
 * EXT_texture_webp, whose image is read where a texture has no other) are rejected
 * with a clear message. So every vertex and index the reader allocates is
 * backed by bytes of the file (or, through node instancing, bounded by
 * SC_GLTF_MAX_ELEMENTS).
 */
#ifndef SC_GLTF_H
#define SC_GLTF_H

#include "sc_value.h"

/* Bump whenever results of this library can change for the same inputs:
 * every node listing sc_kernel_gltf (or a kernel built on it) is re-keyed. */
#define SC_GLTF_VERSION 10
extern const sc_kernel sc_kernel_gltf;

/* Limits on raw vertices and triangles, against memory bombs. */
#define SC_GLTF_MAX_ELEMENTS (1 << 26)

/* Fetch the bytes of an external buffer, `path` relative to the glTF's
 * directory (the URI with %XX escapes decoded). SC_OK or an error code with
 * err filled (the reader prefixes "file: buffer N"). */
typedef int (*sc_gltf_read_fn)(void *ud, const char *path, sc_buf *out, sc_error *err);

typedef struct sc_gltf_image {
    int32_t index;      /* glTF image index (for messages) */
    char *path;         /* external file relative to the glTF's directory, or NULL */
    uint8_t *data;      /* embedded bytes (data: URI or bufferView), or NULL */
    size_t size;
} sc_gltf_image;

typedef struct sc_gltf_texture {
    int32_t material;   /* index into mesh->materials */
    char *slot;         /* "color", "normal", "emissive", "occlusion", "metallic_roughness" */
    int32_t image;      /* index into sc_gltf.images */
    sc_wrap wrap_u, wrap_v;
    /* normal: most of the material's TANGENT bitangents run against
     * increasing v, so the map's green channel is stored the other way up
     * from frames whose bitangent follows v (MikkTSpace's, which seamcook
     * writes): the caller flips channel 1 (g -> 1 - g) */
    bool green_flipped;
} sc_gltf_texture;

typedef struct sc_gltf {
    sc_mesh *mesh;                    /* owned; NULL after a failed parse */
    int32_t nimages;
    sc_gltf_image *images;            /* the images the textures use */
    int32_t ntextures;
    sc_gltf_texture *textures;
    sc_material *materials;           /* mesh->nmat: each material's constants */
    int64_t degenerate_faces_dropped; /* triangles that repeat a welded position */
    int64_t primitives_skipped;       /* primitives whose mode is not TRIANGLES */
    int64_t textures_skipped;         /* textures on a uv set other than TEXCOORD_0 */
    int64_t faces_without_uv;         /* triangles of primitives without TEXCOORD_0: uv (0, 0) */
    bool uv_missing;                  /* every triangle's */
    int64_t raw_vertices;             /* vertices before welding */
} sc_gltf;

/* Parse a .gltf or .glb (told apart by content). `name` is for messages. */
int sc_gltf_parse(const char *name, const void *bytes, size_t size, sc_gltf_read_fn read,
                  void *ud, sc_gltf *out, sc_error *err);
void sc_gltf_free(sc_gltf *g);

/* ---------------------------------------------------------------- writing (sc_gltf_write.c) */

/* A texture: its material and slot (the reader's slot names), its wrap
 * modes, and its file: the bytes to embed in a .glb (PNG or JPEG; borrowed),
 * or the uri a .gltf names it by (the file beside it). */
typedef struct sc_gltf_out_texture {
    int32_t material;
    const char *slot;
    sc_wrap wrap_u, wrap_v;
    const uint8_t *bytes;
    size_t size;
    const char *mime;   /* "image/png" or "image/jpeg" */
    const char *uri;    /* the image file: sc_gltf_write_gltf names it, the .glb names its image so */
} sc_gltf_out_texture;

/* One .glb holding every level of detail: node 0 draws levels[0] and names
 * the others in MSFT_lod (finest first), each level a mesh with a primitive
 * per material (unindexed corners welded into glTF vertices: equal position,
 * uv and normal indices), materials named as the levels' (all levels share
 * level 0's materials) with `constants` (one per material: factors, normal
 * scale, occlusion strength, alpha mode and cutoff, double-sidedness; see
 * sc_atlas_material), textures embedded with
 * samplers from their wrap modes. Positions, uvs (v stored as 1 - v) and
 * normals are float32. */
int sc_gltf_write_glb(const sc_mesh *const *levels, int32_t nlevels, const sc_gltf_out_texture *textures,
                      int32_t ntextures, const sc_material *constants, sc_buf *out, sc_error *err);

/* The same document as a .gltf: its JSON text appended to *json, the binary
 * buffer (the .glb's chunk without the images) to *bin, which the JSON names
 * bin_uri; images by their textures' uri. */
int sc_gltf_write_gltf(const sc_mesh *const *levels, int32_t nlevels, const sc_gltf_out_texture *textures,
                       int32_t ntextures, const sc_material *constants, const char *bin_uri, sc_buf *json,
                       sc_buf *bin, sc_error *err);

#endif
