/* sc_value.h - the immutable, content-addressed values that flow between nodes.
 *
 * Kinds:
 *   MESH    a surface mesh V (nv x 3) and a parameter mesh U (nu x 2) kept apart,
 *           faces FV and FU (nf x 3, same face order), optional normals N/FN,
 *           and a material index per face (FM) with material names.
 *   IMAGE   W x H x C pixels (u8, u16 or f32) with channel names and colour space.
 *   ATLAS   a MESH plus named textures, each bound to a material with its wrap
 *           mode. Refers to its parts (mesh, images) by digest.
 *   LODS    an ordered list of ATLAS values (sharing one texture set).
 *   REPORT  metrics (name -> number) and files (relative path -> BYTES value):
 *           what save and render produce; the engine writes the files to --out.
 *   BYTES   raw bytes (a file's content inside a REPORT).
 *
 * Texel convention (docs/design.md, used by every node and the renderer):
 * texel (i, j) has its centre at ((i + 1/2)/W, (j + 1/2)/H) in uv, and row j = 0
 * is the BOTTOM row of the picture (v = 0). Pixel memory is stored in that
 * order: row 0 first, i.e. bottom-up, exactly as OpenGL expects a texture.
 * Image readers and writers flip rows at the file boundary.
 *
 * Lifecycle: build the plain struct (sc_mesh, sc_image_data, ...), then wrap it
 * with sc_value_new_*, which takes ownership and freezes it. Its digest
 * (SHA-256 of the canonical serialisation; parts are referenced by their
 * digests) is computed when first asked for (sc_value_digest): a node's
 * scratch images, never compared or stored, are never hashed; the engine
 * asks for every output's as the node finishes. Values are reference
 * counted: sc_value_retain/_release. A value is never modified after it is
 * made.
 */
#ifndef SC_VALUE_H
#define SC_VALUE_H

#include "sc_base.h"

typedef enum sc_kind {
    SC_KIND_NONE = 0,
    SC_KIND_MESH = 1,
    SC_KIND_IMAGE = 2,
    SC_KIND_ATLAS = 3,
    SC_KIND_LODS = 4,
    SC_KIND_REPORT = 5,
    SC_KIND_BYTES = 6,
} sc_kind;

const char *sc_kind_name(sc_kind k);          /* "mesh", "image", ... */
sc_kind sc_kind_from_name(const char *name);  /* SC_KIND_NONE when unknown */

typedef struct sc_value sc_value;

/* ---------------------------------------------------------------- mesh */

typedef struct sc_mesh {
    int32_t nv, nu, nn, nf, nmat;
    double *V;        /* nv * 3 */
    double *U;        /* nu * 2 */
    double *N;        /* nn * 3, or NULL when nn == 0 */
    int32_t *FV;      /* nf * 3, indices into V */
    int32_t *FU;      /* nf * 3, indices into U */
    int32_t *FN;      /* nf * 3, indices into N, or NULL when nn == 0 */
    int32_t *FM;      /* nf, material index per face in [0, nmat) */
    char **materials; /* nmat names */
} sc_mesh;

/* Allocate all arrays for the given sizes (zeroed). nn may be 0. nmat >= 1.
 * Returns NULL when out of memory. */
sc_mesh *sc_mesh_alloc(int32_t nv, int32_t nu, int32_t nn, int32_t nf, int32_t nmat);
void sc_mesh_free(sc_mesh *m);
/* Check indices are in range, coordinates finite, faces not index-degenerate.
 * Fills err with the first problem ("face 12: uv index 40 out of range"). */
int sc_mesh_check(const sc_mesh *m, sc_error *err);

/* ---------------------------------------------------------------- image */

typedef enum sc_pixel {
    SC_PIXEL_U8 = 1,
    SC_PIXEL_U16 = 2,
    SC_PIXEL_F32 = 4,     /* the enum value is the bytes per channel */
} sc_pixel;

typedef enum sc_colorspace {
    SC_COLOR_SRGB = 0,    /* 8/16-bit colour as stored in PNG/JPEG */
    SC_COLOR_LINEAR = 1,  /* linear colour (EXR, HDR) */
    SC_COLOR_DATA = 2,    /* not colour: normals, positions, displacement, weights */
} sc_colorspace;

typedef struct sc_image_data {
    int32_t width, height, channels;   /* channels 1..4 */
    sc_pixel pixel;
    sc_colorspace colorspace;
    char format[8];     /* file format it came from ("png", "jpg", "exr"...) or "" */
    void *pixels;       /* width*height*channels samples, rows bottom-up */
} sc_image_data;

/* Limits that keep absurd images out: each side <= 32768, total <= 2^28 px. */
#define SC_IMAGE_MAX_SIDE 32768
#define SC_IMAGE_MAX_PIXELS (1u << 28)

/* Allocate zeroed pixels; fails (NULL) beyond the limits or out of memory. */
sc_image_data *sc_image_alloc(int32_t w, int32_t h, int32_t c, sc_pixel pixel);
void sc_image_free(sc_image_data *im);

/* Sample (i, j, c) as float: u8/u16 normalised to [0, 1], f32 as is. */
float sc_image_texel(const sc_image_data *im, int32_t i, int32_t j, int32_t c);
/* A new f32 copy (same size, channels, colour space). NULL when out of memory. */
sc_image_data *sc_image_to_f32(const sc_image_data *im);
/* The same on up to `threads` threads (the same bytes). */
sc_image_data *sc_image_to_f32_threads(const sc_image_data *im, int threads);

/* The sRGB transfer curve (IEC 61966-2-1) between a stored colour value and
 * linear light, in float, so every module decodes a stored value to the
 * same bits. sc_linear_to_srgb clamps to [0, 1] (NaN -> 0). */
float sc_srgb_to_linear(float c);
float sc_linear_to_srgb(float c);
/* Whether channel c of an image of `channels` channels is alpha (the second
 * of two, the fourth of four): coverage, linear in every colour space. */
bool sc_channel_is_alpha(int32_t channels, int32_t c);
/* Every stored value of an 8 or 16-bit colour channel in linear light, the
 * values sc_image_to_linear_f32 gives: a malloc'd table of 256 or 65536
 * floats, indexed by the stored value; NULL for f32 or when out of memory. */
float *sc_srgb_decode_table(sc_pixel pixel);
/* A linear-light f32 copy of an SC_COLOR_SRGB image (colour channels through
 * the transfer curve, alpha as is), tagged SC_COLOR_LINEAR; any other
 * colour space: sc_image_to_f32_threads. NULL when out of memory. */
sc_image_data *sc_image_to_linear_f32(const sc_image_data *im, int threads);
/* An f32 image rounded to nearest in `pixel` (u8 or u16, clamped to [0, 1],
 * NaN -> 0), tagged `space`; linear colour stored as SC_COLOR_SRGB goes
 * through the transfer curve (alpha as is). NULL when out of memory.
 * _threads: the same bytes, on that many threads. */
sc_image_data *sc_image_quantize(const sc_image_data *f, sc_pixel pixel, sc_colorspace space);
sc_image_data *sc_image_quantize_threads(const sc_image_data *f, sc_pixel pixel, sc_colorspace space, int threads);

/* ---------------------------------------------------------------- atlas */

typedef enum sc_wrap {
    SC_WRAP_REPEAT = 0,   /* OBJ and the GL default */
    SC_WRAP_CLAMP = 1,    /* clamp to edge */
    SC_WRAP_MIRROR = 2,   /* mirrored repeat */
} sc_wrap;

const char *sc_wrap_name(sc_wrap w);

typedef struct sc_texture {
    char *name;          /* slot: "color", "normal", "emissive", "occlusion", ... */
    int32_t material;    /* the material (mesh->materials index) it belongs to */
    sc_wrap wrap_u, wrap_v;
    char *source;        /* file name it was read from (base name), or "" */
    sc_value *image;     /* an IMAGE value (the atlas holds one reference) */
} sc_texture;

/* How a renderer blends a material (glTF 2.0's alphaMode). */
typedef enum sc_alpha_mode {
    SC_ALPHA_OPAQUE = 0,
    SC_ALPHA_MASK = 1,    /* alpha below alpha_cutoff is not drawn */
    SC_ALPHA_BLEND = 2,
} sc_alpha_mode;

/* A material's constants as glTF 2.0 states them: each multiplies its
 * texture (a texture that is absent reads as white; occlusion strength and
 * normal scale as glTF applies them), and the render state. */
typedef struct sc_material {
    double base_color[4];       /* linear RGBA factor */
    double metallic, roughness;
    double emissive[3];
    double normal_scale, occlusion_strength;
    double alpha_cutoff;        /* with SC_ALPHA_MASK */
    sc_alpha_mode alpha_mode;
    bool double_sided;
} sc_material;

/* glTF's defaults: factors 1, emissive 0, opaque, one-sided, cutoff 0.5. */
sc_material sc_material_default(void);

typedef struct sc_atlas {
    sc_value *mesh;      /* a MESH value (one reference held) */
    int32_t ntex;
    sc_texture *textures;
    /* mesh->nmat constants, or NULL where the source states none (OBJ, a
     * generated asset): writers then follow their format's conventions */
    sc_material *materials;
} sc_atlas;

/* ---------------------------------------------------------------- lods, report */

typedef struct sc_lods {
    int32_t count;
    sc_value **levels;   /* ATLAS values, one reference each */
} sc_lods;

typedef struct sc_metric {
    char *name;
    double value;
} sc_metric;

/* Named numbers in the order they were added, for code that measures outside
 * a node (a kernel): the node passes them on with sc_ctx_metric. */
typedef struct sc_metric_list {
    int32_t count, cap;
    sc_metric *items;
    bool failed;         /* an add ran out of memory */
} sc_metric_list;

/* Append (name copied); SC_ENOMEM (and `failed` set) when out of memory. */
int sc_metric_list_add(sc_metric_list *l, const char *name, double value);
void sc_metric_list_free(sc_metric_list *l);

typedef struct sc_report_file {
    char *path;          /* relative, '/'-separated, no "..", no leading '/' */
    sc_value *bytes;     /* a BYTES value */
} sc_report_file;

typedef struct sc_report {
    int32_t nmetrics, nfiles;
    sc_metric *metrics;
    sc_report_file *files;
} sc_report;

typedef struct sc_bytes {
    size_t size;
    uint8_t *data;
} sc_bytes;

/* ---------------------------------------------------------------- values */

struct sc_value {
    sc_kind kind;
    int refs;                 /* atomic; use retain/release */
    int digest_state;         /* atomic; private to sc_value_digest */
    sc_hasher *hasher;        /* private: made with the value, used by its first sc_value_digest */
    sc_digest known_digest;   /* private: read it through sc_value_digest */
    union {
        sc_mesh *mesh;
        sc_image_data *image;
        sc_atlas *atlas;
        sc_lods *lods;
        sc_report *report;
        sc_bytes *bytes;
    } as;
};

/* Wrap and freeze. Each takes ownership of its argument (also on failure,
 * where it is freed) and returns NULL only when out of memory.
 * sc_value_new_atlas takes the references held in the atlas. */
sc_value *sc_value_new_mesh(sc_mesh *m);
sc_value *sc_value_new_image(sc_image_data *im);
sc_value *sc_value_new_atlas(sc_atlas *a);
sc_value *sc_value_new_lods(sc_lods *l);
sc_value *sc_value_new_report(sc_report *r);
sc_value *sc_value_new_bytes(void *data, size_t size);   /* takes malloc'd data */

sc_value *sc_value_retain(sc_value *v);
void sc_value_release(sc_value *v);   /* NULL is fine */

/* The SHA-256 of v's canonical serialisation. Computed at the first call
 * (from any thread; a second caller meanwhile waits for it), so that the
 * values a node makes and drops on its way are never hashed. */
const sc_digest *sc_value_digest(const sc_value *v);

/* Helpers to build composite values. Each returns 0 or SC_ENOMEM. */
sc_atlas *sc_atlas_new(sc_value *mesh);   /* takes the reference to mesh */
int sc_atlas_add_texture(sc_atlas *a, const char *name, int32_t material,
                         sc_wrap wrap_u, sc_wrap wrap_v, const char *source,
                         sc_value *image);   /* takes the reference to image */
void sc_atlas_free(sc_atlas *a);
/* dst's material constants: a copy of src's (none where src has none). A
 * node that makes an atlas from another calls it, so the constants travel
 * with the textures. 0 or SC_ENOMEM. */
int sc_atlas_copy_materials(sc_atlas *dst, const sc_atlas *src);
/* Index of the texture with this slot name in this material, or -1. */
int sc_atlas_find_texture(const sc_atlas *a, int32_t material, const char *name);
/* The constants material k of a stands for: its own, or, where the source
 * states none, an OBJ's conventions (factors 1, a dielectric without a
 * metallic-roughness map, fully rough; emission as its emissive map). */
sc_material sc_atlas_material(const sc_atlas *a, int32_t material);

sc_lods *sc_lods_new(void);
int sc_lods_add(sc_lods *l, sc_value *atlas);       /* takes the reference */
void sc_lods_free(sc_lods *l);

sc_report *sc_report_new(void);
int sc_report_metric(sc_report *r, const char *name, double value);
int sc_report_add_file(sc_report *r, const char *path, void *data, size_t size); /* takes data */
/* Every file whose path starts with `from` again, `from` replaced by `to`,
 * sharing its bytes: a level that repeats another's pictures. */
int sc_report_copy_files(sc_report *r, const char *from, const char *to);
void sc_report_free(sc_report *r);

/* ---------------------------------------------------------------- storage */

/* The canonical bytes of v. Parts (mesh and images of an atlas, atlases of a
 * lods, files of a report) are written as their digests only. */
int sc_value_serialize(const sc_value *v, sc_buf *out);

/* Call visit for each direct part of v (in serialisation order). */
void sc_value_parts(const sc_value *v, void (*visit)(void *ud, sc_value *part), void *ud);

/* Rebuild a value from canonical bytes. Parts are fetched through resolve,
 * which returns a new reference or NULL with err filled (a miss). The result's
 * digest is recomputed and must equal `expect` when expect is not NULL. */
typedef sc_value *(*sc_value_resolver)(void *ud, const sc_digest *digest, sc_error *err);
sc_value *sc_value_deserialize(const void *bytes, size_t n, const sc_digest *expect,
                               sc_value_resolver resolve, void *ud, sc_error *err);

/* Format version of the serialisation; part of every cache key. */
#define SC_VALUE_FORMAT 2

#endif
