/* sc_gradient.h - gradient-domain processing inside a texture atlas (Prada,
 * Kazhdan, Chuang, Hoppe 2018): smoothing, sharpening, stitching and heat
 * geodesics solved over the texels of one texture, with a function space
 * that is continuous across seams and a metric taken from the surface.
 *
 * The discretisation (§4-5). Every mesh triangle is cut by the texel grid
 * into convex pieces (the mutual refinement T ⊕ T̂ of the paper), every
 * piece into triangles around its centroid, and every such triangle carries
 * quadratic Lagrange elements (6 nodes). A node takes its value from the
 * texels by bilinear reconstruction at its uv, so inside a chart the
 * function is exactly the bilinear texture; a node on a seam takes the mean
 * of both sides' bilinear values at the same point of the seam edge, and a
 * mesh corner the mean over every uv of its surface vertex. Both sides of a
 * seam are split at the union of their grid crossings, so they share every
 * node and the function is continuous across seams; the weights of every
 * node sum to one, so the texel functions are a partition of unity. Mass
 * and stiffness matrices integrate these functions (and their gradients)
 * with the first fundamental form of the uv -> surface map of each mesh
 * triangle, by a 6-point rule exact for degree 4.
 *
 * The solver (§6). Multigrid over the texel grid: level l + 1 keeps every
 * other texel of level l, prolongation is the bilinear up-sampling stencil,
 * coarse matrices are Galerkin (P^T A P). On every level, texels whose row
 * reaches beyond their 3 x 3 neighbourhood or whose neighbourhood is not
 * all unknowns (chart borders, seams) are "boundary" and solved directly
 * (CHOLMOD, sc_sparse), the rest are relaxed by Gauss-Seidel; the coarsest
 * level is solved directly. V-cycles run until the relative residual is
 * below the tolerance.
 *
 *     sc_gradient_options o;
 *     sc_gradient_defaults(&o, SC_GRADIENT_SMOOTH);
 *     sc_gradient_result r;
 *     if (sc_gradient_apply(mesh, &texture, image, &o, threads, &r, &err) == SC_OK) { ... }
 *     sc_gradient_result_free(&r);
 */
#ifndef SC_GRADIENT_H
#define SC_GRADIENT_H

#include <stdint.h>

#include "sc_value.h"

/* Bump whenever sc_gradient_apply's output for the same inputs can change. */
#define SC_GRADIENT_VERSION 3
extern const sc_kernel sc_kernel_gradient;

typedef enum sc_gradient_op {
    SC_GRADIENT_SMOOTH = 0,   /* (w M + S) x = (w M + beta S) x0, beta < 1 */
    SC_GRADIENT_SHARPEN = 1,  /* the same with beta > 1 */
    SC_GRADIENT_STITCH = 2,   /* (w M + S) x = w M x0 + S_same x0: gradients kept inside each label */
    SC_GRADIENT_GEODESIC = 3, /* heat method: distance to the sources */
    SC_GRADIENT_LIC = 4,      /* line integral convolution: white noise diffused along the max-curvature
                                 direction under the anisotropic metric of §7.4 */
} sc_gradient_op;

/* The operation named (smooth, sharpen, stitch, geodesic, lic), or -1. */
int sc_gradient_op_named(const char *name);

typedef enum sc_gradient_solver {
    SC_GRADIENT_MULTIGRID = 0, /* conjugate gradients, one V-cycle per iteration as the preconditioner */
    SC_GRADIENT_DIRECT = 1,    /* one CHOLMOD factorisation of the whole system */
    SC_GRADIENT_VCYCLES = 2,   /* V-cycles alone, as the paper runs them */
} sc_gradient_solver;

typedef struct sc_gradient_options {
    sc_gradient_op op;
    /* beta, the factor of the gradients kept (smooth, sharpen) */
    double gradient_scale;
    /* w, the screening weight, for a surface scaled to unit area (the
     * paper's convention; 1e4 smoothing, 1e2 stitching) */
    double screening;
    /* geodesic: the heat step t in unit-area units (the paper's 1e-3) */
    double time_step;
    /* geodesic: the sources, ';'-separated: "x y z" (the mesh vertex nearest
     * a surface point) or "texel i j" (borrowed) */
    const char *sources;
    /* stitch: one label per texel (channel 0, same size as the texture) */
    const sc_image_data *labels;
    sc_gradient_solver solver;
    int32_t levels;           /* multigrid levels, the finest included */
    int32_t relaxations;      /* Gauss-Seidel sweeps before and after the coarse correction */
    int32_t max_vcycles;
    double tolerance;         /* V-cycles stop below this relative residual */
    /* lic: the streaks' length in texels (epsilon = 1 / length^2), and the
     * seed of the white noise diffused (the input's values are not used) */
    double lic_length;
    uint64_t lic_seed;
    /* lic: the vector field instead of the curvature directions, an
     * object-space direction map (xyz in channels 0-2: signed float, else 0..1
     * for -1..1) of the texture's size, read at each face's uv centroid and
     * projected into the face's plane; its length (capped at 1) scales the
     * anisotropy. NULL: the curvature directions. Borrowed. */
    const sc_image_data *lic_field;
} sc_gradient_options;

/* The paper's settings for op: beta 0 (smooth) or 2 (sharpen), w 1e4 (1e2
 * for stitch; lic: 1, a factor on one over a texel's area, so that streaks
 * are one texel wide), t = 1e-3, 4 levels, 3 sweeps, tolerance 1e-8 in
 * at most 30 V-cycles; lic: length 16 texels, seed 1.
 *
 * lic (§7.4): h(v, w) = g(v, u_perp) g(w, u_perp) + epsilon g(v, w), with u the
 * direction of largest principal curvature, constant per face (the shape
 * operator fitted to the face's edges and corner normals), scaled by
 * |k1 - k2| over its 90th percentile on the surface (capped at 1), and u_perp its
 * quarter-turn in the tangent plane; white noise psi is diffused by
 * (w M_h + S_h) x = w M_h psi with w = screening / (surface area per
 * texel), then rescaled to mean 1/2 and deviation 1/6 (the diffusion shrinks
 * the noise's contrast). Where |k1 - k2| vanishes (umbilics) the metric is
 * isotropic and the noise blurs round. */
void sc_gradient_defaults(sc_gradient_options *o, sc_gradient_op op);

typedef struct sc_gradient_result {
    sc_image_data *image;     /* f32: the texture's channels (geodesic: one, the distance) */
    int32_t unknowns;         /* texels solved for; the others keep the input's values */
    int32_t vcycles;          /* per solve, the most taken (0: direct) */
    sc_metric_list metrics;   /* residuals per V-cycle, seam energies, sizes */
} sc_gradient_result;

/* Process `image` (the texture `tex` of `mesh`: its material and wrap modes)
 * as o says, assembling and relaxing on `threads` threads in an order fixed
 * by the mesh and the grid: the result does not depend on the thread count.
 * sRGB colour is processed in linear light and returned linear.
 * On failure *res is empty and err says why. */
int sc_gradient_apply(const sc_mesh *mesh, const sc_texture *tex, const sc_image_data *image,
                      const sc_gradient_options *o, int threads, sc_gradient_result *res, sc_error *err);
void sc_gradient_result_free(sc_gradient_result *res);

#endif
