/* sc_erase.h - seam erasure (Liu et al. 2017, §3-4): textures moved onto the
 * seam operator's null space, so that both sides of every seam sample the
 * same values.
 *
 * One library serves every node that erases: erase_seams itself, straighten
 * (after it warps a texture), bake_displacement (its geometry images and
 * displacement maps) and mipmap (every level of a chain). Each of them lists
 * sc_kernel_erase in its descriptor (bake_displacement and mipmap through
 * sc_kernel_atlas_ops, which builds on it), so a change of SC_ERASE_VERSION
 * re-keys all of them at once.
 *
 *     sc_erase_options o;
 *     sc_erase_defaults(&o);
 *     o.quantize = SC_ERASE_QUANTIZE_NONE;
 *     sc_erase_result r;
 *     if (sc_erase(mesh, atlas->textures, atlas->ntex, &o, threads, &r, &err) == SC_OK) {
 *         sc_value *erased = sc_erase_result_atlas(atlas_value, &r, false);
 *         ...
 *     }
 *     sc_erase_result_free(&r);
 */
#ifndef SC_ERASE_H
#define SC_ERASE_H

#include "sc_value.h"

/* Bump whenever sc_erase's output bytes for the same inputs can change. */
#define SC_ERASE_VERSION 7
extern const sc_kernel sc_kernel_erase;

/* The paper's weights: the defaults of erase_seams's parameters. */
#define SC_ERASE_W_SEAM 1e10
#define SC_ERASE_W_CHANGE_LOCAL 1e4
#define SC_ERASE_W_CHANGE_GLOBAL 1e2
#define SC_ERASE_W_GRAD 1.0
#define SC_ERASE_W_C1 1e2
#define SC_ERASE_W_LERP 1e2
#define SC_ERASE_W_OUTSIDE 1e2
#define SC_ERASE_GAP_TOLERANCE 1e-4
#define SC_ERASE_SCHUR_FROM 500000   /* solver auto takes the edge-cluster solver from here */
#define SC_ERASE_PCG_ITERATIONS 500

typedef enum sc_erase_quantize {
    SC_ERASE_QUANTIZE_NONE = 0,      /* native results stay f32 */
    SC_ERASE_QUANTIZE_NAIVE = 1,     /* 8/16-bit: round to nearest */
    SC_ERASE_QUANTIZE_OPTIMAL = 2,   /* 8-bit: rounding that minimises the quantised seam energy */
} sc_erase_quantize;

typedef enum sc_erase_solver {
    SC_ERASE_SOLVER_AUTO = 0,
    SC_ERASE_SOLVER_CHOLMOD = 1,     /* one direct factorisation of the whole system */
    SC_ERASE_SOLVER_SCHUR = 2,       /* seam chains eliminated on their own, the rest factored */
} sc_erase_solver;

typedef enum sc_erase_filter_space {
    SC_ERASE_FILTER_LINEAR = 0,      /* sRGB colour erased in linear light, as GPUs filter it (sRGB formats) */
    SC_ERASE_FILTER_ENCODED = 1,     /* colour erased as stored: for engines that filter encoded values */
} sc_erase_filter_space;

/* The nodes' filter_space parameter: "encoded", or "linear" (anything else). */
sc_erase_filter_space sc_erase_filter_space_named(const char *name);
#define SC_ERASE_FILTER_SPACE_DOC                                                                            \
    "where sRGB colour is erased: linear (light, as GPUs filter sRGB textures: glTF, GL/Vulkan sRGB formats) " \
    "or encoded (the stored values, for engines that filter those)"

/* What a "normal" slot holds. Tangent-space maps are converted to object
 * space with MikkTSpace frames (sc_tangent.h), erased there and converted
 * back texel by texel; what is measured is the seam gap of the normal a
 * renderer reconstructs from the bytes written. */
typedef enum sc_erase_normal_space {
    SC_ERASE_NORMALS_AUTO = 0,       /* tangent-space when the map looks it (mean near (0.5, 0.5, 1)) and its
                                        normals meet across seams better through the frames than as stored */
    SC_ERASE_NORMALS_TANGENT = 1,
    SC_ERASE_NORMALS_OBJECT = 2,     /* erased as stored */
} sc_erase_normal_space;

/* The nodes' normal_space parameter: "tangent", "object", or "auto" (anything else). */
sc_erase_normal_space sc_erase_normal_space_named(const char *name);

/* The same for the textures of `atlas`: auto is tangent for an atlas whose
 * source states its materials (glTF, whose normal textures are
 * tangent-space by its spec: a re-chartified atlas's map meets across
 * seams as stored, by construction, and would read as object-space). */
sc_erase_normal_space sc_erase_normal_space_of(const char *name, const sc_atlas *atlas);
#define SC_ERASE_NORMAL_SPACE_DOC                                                                           \
    "what the normal slot holds: tangent (erased in object space through MikkTSpace frames, as glTF's maps " \
    "are), object (erased as stored), or auto (tangent for a glTF asset's maps, as its spec says; else when " \
    "the map looks tangent-space and its seams meet better through the frames than as stored)"
/* A tangent-space map whose reconstructed normals still differ by more than
 * this across a seam (|n_a - n_b|, about radians: 3 degrees) after erasure is
 * reported as discontinuous. What erasure leaves below it: the frames' turn
 * within one texel's footprint (texels are converted with the frame at their
 * centre, the renderer uses the frame at the seam) and 8-bit rounding (about
 * 0.01). */
#define SC_ERASE_NORMAL_GAP_LIMIT 0.05

typedef struct sc_erase_options {
    double w_change, w_seam, w_grad_in, w_c1, w_grad_out, w_lerp, w_outside;
    bool lerp, outside;              /* add E_lerp, E_outside */
    sc_erase_normal_space normal_space;
    double gap_tolerance;            /* a texture within this (or one encoding step) passes through */
    const char *textures;            /* slots to erase, comma-separated, or "all" (borrowed) */
    sc_erase_quantize quantize;
    sc_erase_filter_space filter_space;
    /* per texture (or NULL): an image of the same size whose pixel type and
     * encoding the native result takes instead of the texture's own (a float
     * texture re-rendered from an 8-bit one goes back to 8 bits); borrowed */
    const sc_image_data *const *native_like;
    sc_erase_solver solver;
    int64_t schur_from;              /* solver auto: schur from this many unknowns */
    int32_t pcg_iterations;          /* the most conjugate-gradient iterations of each schur round */
    /* per texture (or NULL): true where its float image is one the caller
     * made for this call and reads no more (its value never hashed, nor held
     * by anything else): erased, it takes its solution in place and is its
     * f32 result, with no copy; borrowed */
    const bool *inputs_private;
} sc_erase_options;

/* The paper's weights (preset local), every texture, optimal rounding, solver auto. */
void sc_erase_defaults(sc_erase_options *o);

typedef struct sc_erase_result {
    int32_t count;          /* = the number of textures given */
    sc_value **f32;         /* per texture: the erased f32 image, or the input image passed through */
    sc_value **native;      /* per texture: the same in the input's pixel type (quantised once) */
    sc_metric_list metrics; /* what erase_seams reports, in its order */
} sc_erase_result;

/* Erase the seams of textures[0..n) (each bound to a material of `mesh` with
 * its wrap modes; slot names select and prefix metrics) on `threads` threads;
 * results do not depend on the thread count. On success *res holds new
 * references (free with sc_erase_result_free); on failure *res is empty and
 * err names the texture or option at fault. */
int sc_erase(const sc_mesh *mesh, const sc_texture *textures, int32_t n, const sc_erase_options *o,
             int threads, sc_erase_result *res, sc_error *err);

void sc_erase_result_free(sc_erase_result *res);

/* The line a node warns with for metric k of ml (sc_erase's metrics, in
 * their order), into out (at most size bytes), when there is one: a
 * tangent-space normal map left as it is, one whose reconstructed normals
 * stay apart across a seam (with its largest gap), or, with normal_space
 * object, a normal map that looks tangent-space. False: no line. */
bool sc_erase_warning(const sc_metric_list *ml, int32_t k, sc_erase_normal_space space, char *out, size_t size);

/* Whether sc_erase, with normal_space `space`, takes texture t of `mesh` as
 * a tangent-space normal map (and so erases it through the mesh's frames):
 * a slot named "normal" of 3 or more channels; with auto, one whose values
 * sit near (0.5, 0.5, 1) and whose seams meet better through the frames
 * than as stored. A node that moves uv re-expresses such a map in the
 * frames of the new uv. */
int sc_erase_takes_tangent_space(const sc_mesh *mesh, const sc_texture *t, sc_erase_normal_space space,
                                 bool *tangent, sc_error *err);

/* The atlas `atlas` (an ATLAS value whose textures were given to sc_erase)
 * with each texture's image replaced by the result's f32 or native image: a
 * new reference, the atlas itself when every such image is the atlas's own
 * (nothing erased, nor rounded to native_like's type); NULL when out of
 * memory. */
sc_value *sc_erase_result_atlas(const sc_value *atlas, const sc_erase_result *res, bool native);

#endif
