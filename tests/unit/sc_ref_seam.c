/* sc_ref_seam.c - the unit tests' own seam measure: a plain bilinear sampler
 * (texel centres at ((i + 1/2)/W, (j + 1/2)/H), row 0 at v = 0, GL wrap
 * rules, sRGB colour decoded to linear light as GPUs filter it), its own seam
 * finder, and the seam energy of Liu et al. 2017 (eq. 9) integrated exactly
 * by Gauss-Legendre over the pieces between texel-grid crossings. It shares
 * no code with the library's seam operator (sc_seam), so tests that compare
 * the two, or measure the files the library writes, check the library
 * against an independent reading of the same definitions.
 */
#include "sc_ref_seam.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* ================================================================ reference sampler */

long ref_wrap(long i, long n, sc_wrap w) {
    if (w == SC_WRAP_CLAMP) return i < 0 ? 0 : (i > n - 1 ? n - 1 : i);
    if (w == SC_WRAP_MIRROR) {
        /* GL: (n - 1) - mirror((i mod 2n) - n), mirror(a) = a >= 0 ? a : -(1 + a) */
        long m = ((i % (2 * n)) + 2 * n) % (2 * n);
        long a = m - n;
        long mir = a >= 0 ? a : -(1 + a);
        return (n - 1) - mir;
    }
    return ((i % n) + n) % n;
}

/* The sRGB transfer curve, written here from IEC 61966-2-1. */
double ref_srgb_decode(double c) { return c <= 0.04045 ? c / 12.92 : pow((c + 0.055) / 1.055, 2.4); }
double ref_srgb_encode(double l) {
    l = l < 0 ? 0 : l > 1 ? 1 : l;
    return l <= 0.0031308 ? 12.92 * l : 1.055 * pow(l, 1 / 2.4) - 0.055;
}
bool ref_is_alpha(const sc_image_data *im, int c) {
    return (im->channels == 2 && c == 1) || (im->channels == 4 && c == 3);
}

/* A texel as a GPU filters it: sRGB colour decoded to linear light (sRGB
 * texture formats decode before filtering), other values as stored. */
double ref_texel(const sc_image_data *im, long i, long j, int c) {
    size_t k = ((size_t)j * (size_t)im->width + (size_t)i) * (size_t)im->channels + (size_t)c;
    /* integer texels are normalised the way the runtime does (sc_image_texel) */
    double v = im->pixel == SC_PIXEL_U8    ? ((const uint8_t *)im->pixels)[k] * (1.0f / 255.0f)
               : im->pixel == SC_PIXEL_U16 ? ((const uint16_t *)im->pixels)[k] * (1.0f / 65535.0f)
                                           : ((const float *)im->pixels)[k];
    return im->colorspace == SC_COLOR_SRGB && !ref_is_alpha(im, c) ? ref_srgb_decode(v) : v;
}

/* bilinear value and texel-space gradient at uv */
void ref_sample(const sc_image_data *im, sc_wrap wu, sc_wrap wv, double u, double v, double *val, double *gx, double *gy) {
    double x = u * im->width - 0.5, y = v * im->height - 0.5;
    double fx = floor(x), fy = floor(y), a = x - fx, b = y - fy;
    long i0 = ref_wrap((long)fx, im->width, wu), i1 = ref_wrap((long)fx + 1, im->width, wu);
    long j0 = ref_wrap((long)fy, im->height, wv), j1 = ref_wrap((long)fy + 1, im->height, wv);
    for (int c = 0; c < im->channels; c++) {
        double p00 = ref_texel(im, i0, j0, c), p10 = ref_texel(im, i1, j0, c);
        double p01 = ref_texel(im, i0, j1, c), p11 = ref_texel(im, i1, j1, c);
        double bot = p00 + a * (p10 - p00), top = p01 + a * (p11 - p01);
        if (val) val[c] = bot + b * (top - bot);
        if (gx) gx[c] = (1 - b) * (p10 - p00) + b * (p11 - p01);
        if (gy) gy[c] = top - bot;
    }
}

/* ================================================================ reference seams */

typedef struct ref_he {
    int lo, hi, face, k;
} ref_he;

static int cmp_ref_he(const void *pa, const void *pb) {
    const ref_he *a = pa, *b = pb;
    if (a->lo != b->lo) return a->lo - b->lo;
    if (a->hi != b->hi) return a->hi - b->hi;
    return a->face - b->face;
}

/* Seam edges of one material: two faces on a surface edge whose uv indices
 * differ at either end (and whose uv coordinates differ too). */
int ref_find_seams(const sc_mesh *m, int material, ref_seam **out) {
    ref_he *h = malloc(sizeof *h * (size_t)m->nf * 3);
    int n = 0;
    for (int f = 0; f < m->nf; f++) {
        if (m->FM[f] != material) continue;
        for (int k = 0; k < 3; k++) {
            int a = m->FV[3 * f + k], b = m->FV[3 * f + (k + 1) % 3];
            h[n++] = (ref_he){a < b ? a : b, a < b ? b : a, f, k};
        }
    }
    qsort(h, (size_t)n, sizeof *h, cmp_ref_he);
    ref_seam *s = malloc(sizeof *s * (size_t)(n / 2 + 1));
    int ns = 0;
    for (int i = 0; i < n;) {
        int j = i;
        while (j < n && h[j].lo == h[i].lo && h[j].hi == h[i].hi) j++;
        if (j - i == 2) {
            int uvs[2][2]; /* [side][at lo, at hi] */
            for (int q = 0; q < 2; q++) {
                int f = h[i + q].face, k = h[i + q].k;
                int va = m->FV[3 * f + k];
                int ua = m->FU[3 * f + k], ub = m->FU[3 * f + (k + 1) % 3];
                uvs[q][0] = va == h[i].lo ? ua : ub;
                uvs[q][1] = va == h[i].lo ? ub : ua;
            }
            bool same = true;
            for (int e = 0; e < 2; e++)
                same &= m->U[2 * uvs[0][e]] == m->U[2 * uvs[1][e]] &&
                        m->U[2 * uvs[0][e] + 1] == m->U[2 * uvs[1][e] + 1];
            if (!same) {
                ref_seam *r = &s[ns++];
                memcpy(r->a0, &m->U[2 * uvs[0][0]], sizeof r->a0);
                memcpy(r->a1, &m->U[2 * uvs[0][1]], sizeof r->a1);
                memcpy(r->b0, &m->U[2 * uvs[1][0]], sizeof r->b0);
                memcpy(r->b1, &m->U[2 * uvs[1][1]], sizeof r->b1);
                const double *p = &m->V[3 * h[i].lo], *q = &m->V[3 * h[i].hi];
                r->len = sqrt((p[0] - q[0]) * (p[0] - q[0]) + (p[1] - q[1]) * (p[1] - q[1]) +
                              (p[2] - q[2]) * (p[2] - q[2]));
            }
        }
        i = j;
    }
    free(h);
    *out = s;
    return ns;
}


const double REF_GLX[3] = {0.11270166537925831148, 0.5, 0.88729833462074168852};
const double REF_GLW[3] = {5.0 / 18, 8.0 / 18, 5.0 / 18};

void ref_lerp_uv(const double *a, const double *b, double t, double *o) {
    o[0] = a[0] + t * (b[0] - a[0]);
    o[1] = a[1] + t * (b[1] - a[1]);
}

/* |B(e1(g)) - B(e2(g))|^2 summed over channels, and the largest |.| */
double ref_gap2(const sc_image_data *im, sc_wrap wu, sc_wrap wv, const ref_seam *s, double g, double *maxabs) {
    double p[2], q[2], va[4], vb[4], sum = 0;
    ref_lerp_uv(s->a0, s->a1, g, p);
    ref_lerp_uv(s->b0, s->b1, g, q);
    ref_sample(im, wu, wv, p[0], p[1], va, NULL, NULL);
    ref_sample(im, wu, wv, q[0], q[1], vb, NULL, NULL);
    for (int c = 0; c < im->channels; c++) {
        double d = va[c] - vb[c];
        sum += d * d;
        if (maxabs && fabs(d) > *maxabs) *maxabs = fabs(d);
    }
    return sum;
}

static int ref_cmp_dbl(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

/* parameters where either side crosses a line x or y = integer (texel space) */
int ref_breaks(const sc_image_data *im, const ref_seam *s, double **out) {
    int cap = 64, n = 0;
    double *t = malloc(sizeof *t * (size_t)cap);
    t[n++] = 0, t[n++] = 1;
    const double *ends[2][2] = {{s->a0, s->a1}, {s->b0, s->b1}};
    for (int side = 0; side < 2; side++)
        for (int axis = 0; axis < 2; axis++) {
            double sz = axis ? im->height : im->width;
            double x0 = ends[side][0][axis] * sz - 0.5, x1 = ends[side][1][axis] * sz - 0.5;
            if (x0 == x1) continue;
            for (double k = ceil(fmin(x0, x1)); k <= floor(fmax(x0, x1)); k++) {
                if (n == cap) t = realloc(t, sizeof *t * (size_t)(cap *= 2));
                t[n++] = (k - x0) / (x1 - x0);
            }
        }
    qsort(t, (size_t)n, sizeof *t, ref_cmp_dbl);
    *out = t;
    return n;
}

/* D exactly (Gauss-Legendre on each piece between crossings) and the largest
 * gap sampled at 17 points per piece */
static double ref_piece_D(const sc_image_data *im, sc_wrap wu, sc_wrap wv, const ref_seam *s, double *maxgap) {
    double *t;
    int n = ref_breaks(im, s, &t);
    double sum = 0;
    for (int i = 0; i + 1 < n; i++) {
        double a = t[i], b = t[i + 1];
        if (!(b > a)) continue;
        for (int k = 0; k < 3; k++) sum += REF_GLW[k] * (b - a) * ref_gap2(im, wu, wv, s, a + REF_GLX[k] * (b - a), NULL);
        for (int k = 0; k <= 16 && maxgap; k++) ref_gap2(im, wu, wv, s, a + (b - a) * k / 16.0, maxgap);
    }
    free(t);
    return sum;
}

/* D_total of eq. 9 over a list of seams, and the max gap */
double ref_total(const sc_image_data *im, sc_wrap wu, sc_wrap wv, const ref_seam *s, int n, double *maxgap) {
    double num = 0, L = 0;
    if (maxgap) *maxgap = 0;
    for (int i = 0; i < n; i++) {
        num += s[i].len * ref_piece_D(im, wu, wv, &s[i], maxgap);
        L += s[i].len;
    }
    return L > 0 ? num / L : 0;
}

void ref_solve3(const double c0[3], const double c1[3], const double c2[3], const double rhs[3], double x[3]) {
    double A[3][4];
    for (int i = 0; i < 3; i++) A[i][0] = c0[i], A[i][1] = c1[i], A[i][2] = c2[i], A[i][3] = rhs[i];
    for (int c = 0; c < 3; c++) {
        int piv = c;
        for (int i = c + 1; i < 3; i++)
            if (fabs(A[i][c]) > fabs(A[piv][c])) piv = i;
        for (int k = 0; k < 4; k++) {
            double tmp = A[c][k];
            A[c][k] = A[piv][k], A[piv][k] = tmp;
        }
        for (int i = 0; i < 3; i++)
            if (i != c) {
                double q = A[i][c] / A[c][c];
                for (int k = 0; k < 4; k++) A[i][k] -= q * A[c][k];
            }
    }
    for (int c = 0; c < 3; c++) x[c] = A[c][3] / A[c][c];
}
