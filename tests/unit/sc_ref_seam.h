/* sc_ref_seam.h - the unit tests' own seam measure (sc_ref_seam.c): a bilinear
 * sampler, a seam finder and the seam energy of Liu et al. 2017 (eq. 9),
 * written apart from the library's seam operator so that tests can check the
 * library, and the files it writes, against an independent reading.
 */
#ifndef SC_REF_SEAM_H
#define SC_REF_SEAM_H

#include <stdbool.h>

#include "sc_value.h"

/* One seam edge: both sides' uv, from surface vertex v0 to v1, and its
 * length on the surface. */
typedef struct ref_seam {
    double a0[2], a1[2], b0[2], b1[2];
    double len;
} ref_seam;

/* 3-point Gauss-Legendre nodes and weights on [0, 1]. */
extern const double REF_GLX[3], REF_GLW[3];

/* A texel index wrapped as GL does (repeat, clamp to edge, mirrored repeat). */
long ref_wrap(long i, long n, sc_wrap w);
/* The sRGB transfer curve (IEC 61966-2-1); encode clamps to [0, 1]. */
double ref_srgb_decode(double c);
double ref_srgb_encode(double l);
/* Whether channel c of the image is alpha (2 or 4 channels, the last). */
bool ref_is_alpha(const sc_image_data *im, int c);
/* A texel as a GPU filters it: integer texels normalised, sRGB colour
 * (colorspace SC_COLOR_SRGB, alpha aside) decoded to linear light, other
 * values as stored. */
double ref_texel(const sc_image_data *im, long i, long j, int c);
/* Bilinear value and texel-space gradient at (u, v); any output may be NULL. */
void ref_sample(const sc_image_data *im, sc_wrap wu, sc_wrap wv, double u, double v, double *val, double *gx,
                double *gy);
/* The seam edges of one material: two faces on a surface edge whose uv
 * indices differ at either end and whose uv coordinates differ too. *out is
 * malloc'd (free it); returns the count. */
int ref_find_seams(const sc_mesh *m, int material, ref_seam **out);
void ref_lerp_uv(const double *a, const double *b, double t, double *o);
/* |B(side a at g) - B(side b at g)|^2 summed over channels; the largest
 * |difference| is kept in *maxabs when it is not NULL. */
double ref_gap2(const sc_image_data *im, sc_wrap wu, sc_wrap wv, const ref_seam *s, double g, double *maxabs);
/* The parameters in [0, 1] where either side of s crosses a texel-centre
 * line, with 0 and 1, sorted; *out is malloc'd. Returns the count. */
int ref_breaks(const sc_image_data *im, const ref_seam *s, double **out);
/* D_total of eq. 9 over n seams (the length-weighted mean of each seam's
 * integrated squared gap) and, when maxgap is not NULL, the largest gap
 * sampled at 17 points per piece. */
double ref_total(const sc_image_data *im, sc_wrap wu, sc_wrap wv, const ref_seam *s, int n, double *maxgap);

/* x with x[0] c0 + x[1] c1 + x[2] c2 = rhs (Gauss-Jordan, partial pivoting):
 * a vector in the frame of columns c0, c1, c2 (a tangent frame T, B, N). */
void ref_solve3(const double c0[3], const double c1[3], const double c2[3], const double rhs[3], double x[3]);

#endif
