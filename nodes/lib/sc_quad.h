/* sc_quad.h - seamless quad-chart atlases (Purnomo, Cohen and Kumar 2004).
 *
 * sc_quad_build turns any textured mesh (uv that overlap, mirror, fragment or
 * are missing) into a new atlas of square charts that is seam-free at every
 * mip level by construction:
 *
 *   patches   (§4.1) faces merge greedily by plane-fit error, normal spread
 *             and compactness, under the paper's two rules: every patch is a
 *             disc, and two patches meet in one vertex, one boundary arc, or
 *             not at all. Corners are the vertices where three regions (two
 *             patches and the mesh border, or three patches) meet. With
 *             straight_borders, each border between two patches is then
 *             re-drawn as the shortest edge path between its ends inside
 *             the two, lengths scaled by the distance from the old border,
 *             where that is shorter and both stay discs.
 *   quads     (§4.2) each n-sided patch is mapped harmonically onto a
 *             regular n-gon and cut into n quads by paths from a centre
 *             vertex to the median of each side: shortest paths along mesh
 *             edges near the straight domain segment, crossing an edge at
 *             its middle only where they must. Where no such set of paths
 *             exists, straight cuts in the domain (splitting every triangle
 *             they cross, so a cut always exists).
 *   charts    (§4.3) each quad maps onto the unit square: sides by arc
 *             length, the interior by mean-value coordinates, then
 *             stretch-reducing re-weighting (a Tutte map stays one-to-one).
 *   samples   (§3.2) a chart holds 2^k + 1 samples per side, its border
 *             samples lie on its border, each sample of a shared side or
 *             corner is computed once and copied bit for bit to every chart
 *             that holds it. The texel centres of level L are the samples
 *             of level 0 at multiples of 2^L, so levels nest.
 *   levels    (§4.5) interior samples filter with a 3x3 binomial, border
 *             rows with the 1-D binomial along the border (computed once,
 *             copied), corners keep their value: still seam-free.
 *   layout    "blocks": each chart in a cell of 2^k + 2^G texels, cells
 *             aligned to 2^G (shelf packing), G = max(Lmax, 2), so no two
 *             charts share a texel at any level down to the last, and at
 *             level 0 each chart's border samples have a texel of their
 *             own beyond them (float32 uv give it a small weight). With
 *             whole_texture, uv are in units of texture_size, so maps of
 *             that size hold the border samples on texel centres. One
 *             texel density for the whole atlas: a chart's k follows the
 *             mean chart area of its connected part (charts that share a
 *             side have one size, so their border samples copy bit for
 *             bit), and the density is the largest whose packing fits
 *             texture_size. Level L is sampled at the level-0 uv plus
 *             (2^L - 1) / 2 texels of level 0 in u and v (the sampling
 *             rule; sc_quad_level_offset); gutters repeat the chart's
 *             border texels for engines that sample without it.
 *
 * Textures are read through each face's own old uv (so overlaps do no
 * harm), supersampled, colour decoded from sRGB to linear before it is
 * filtered, tangent-space normals re-expressed in the new charts' frames,
 * data as stored. The result is in each input texture's pixel type.
 */
#ifndef SC_QUAD_H
#define SC_QUAD_H

#include "sc_value.h"

/* Bump whenever results of this library can change for the same inputs:
 * every node listing sc_kernel_quad is re-keyed. */
#define SC_QUAD_VERSION 6
extern const sc_kernel sc_kernel_quad;

typedef struct sc_quad_options {
    int32_t texture_size;    /* the larger side of level 0, in texels */
    int32_t chart_texels;    /* samples per side of every chart (2^k + 1); 0: by area, one density */
    int32_t target_patches;  /* stop merging at this many patches; 0: by target_quads */
    int32_t target_quads;    /* stop merging once the quads would be at most this; 0: fill the texture */
    int32_t min_size;        /* levels down to this larger side; 0: until charts hold 9 samples a side */
    int32_t supersample;     /* S x S points averaged per texel */
    int32_t psnr_samples;    /* surface points for the PSNR metric (0: none) */
    bool whole_texture;      /* uv in units of texture_size (maps of that size hold the border samples
                              * on their texel centres); else of the packed charts' extent */
    const sc_material *constants;   /* the input's material constants (one per material), or NULL */
    bool straight_borders;   /* re-draw patch borders as shorter edge paths (§4.1; default false) */
} sc_quad_options;

void sc_quad_defaults(sc_quad_options *o);

typedef struct sc_quad_texture {
    char *name;              /* the slot ("color", "normal", ...) */
    sc_wrap wrap_u, wrap_v;  /* always clamp */
    int32_t nlevels;
    sc_image_data **levels;  /* level 0 first, each half the size of the one before */
} sc_quad_texture;

typedef struct sc_quad_result {
    sc_mesh *mesh;           /* the refined mesh; uv of level 0; one material */
    int32_t width, height;   /* level 0 */
    int32_t nlevels;
    int32_t ntex;
    sc_quad_texture *textures;
    sc_metric_list metrics;
    sc_material constants;   /* with has_constants: the one material's (merged: sc_quad_build) */
    bool has_constants;
} sc_quad_result;

/* Build the quad atlas of mesh m with textures tex[0..ntex) (their images
 * read through m's uv; ntex may be 0, and m may have no uv then). With
 * o->constants, the atlas's one material gets the constants every used
 * material agrees on; one they differ on (a colour factor, say) is
 * multiplied into its slot's texels as glTF applies it, per source
 * material, and left neutral (metric material_constants_unbaked: those
 * without a slot to take them, kept as the first material's); the most
 * transparent alpha mode and any double-sidedness hold for the whole. On
 * failure nothing is kept and err names the cause. */
int sc_quad_build(const sc_mesh *m, const sc_texture *tex, int32_t ntex, const sc_quad_options *o,
                  int threads, sc_quad_result *out, sc_error *err);
void sc_quad_result_free(sc_quad_result *r);

/* The uv offset of level L (added to the level-0 uv in u and v). */
static inline void sc_quad_level_offset(int32_t width, int32_t height, int32_t level, double *du, double *dv) {
    double s = (double)((1 << level) - 1) * 0.5;
    *du = s / width;
    *dv = s / height;
}

#endif
