/* sc_quad_texture.c - layout, samples and mip levels of the quad atlas
 * (Purnomo et al. 2004 §3.2-3.4, §4.4-4.5; the method is in sc_quad.h),
 * and the measures of what it wrote: utilisation, stretch, surface PSNR,
 * border mismatch and shared texels per level, read back from the images.
 */
#include <math.h>
#include <stdio.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "sc_geometry.h"
#include "sc_quad_internal.h"
#include "sc_seam.h"

static const sc_kernel *const quad_uses[] = {&sc_kernel_seam, NULL};
const sc_kernel sc_kernel_quad = {"quad", SC_QUAD_VERSION, quad_uses};

void sc_quad_defaults(sc_quad_options *o) {
    memset(o, 0, sizeof *o);
    o->texture_size = 2048;
    o->supersample = 2;
    o->psnr_samples = 200000;
    o->straight_borders = false;
}

static double now_seconds(void) {
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

/* ---------------------------------------------------------------- reading the old textures */

typedef enum slot_kind { SLOT_COLOUR, SLOT_NORMAL, SLOT_DATA } slot_kind;

/* One input image as linear floats (colour decoded), for bilinear reads. */
typedef struct source {
    const sc_texture *tex;
    float *px;     /* w * h * 4 */
    int32_t w, h;
} source;

static int source_load(source *s, const sc_texture *t, bool decode) {
    const sc_image_data *im = t->image->as.image;
    s->tex = t, s->w = im->width, s->h = im->height;
    s->px = malloc((size_t)im->width * im->height * 4 * sizeof(float));
    if (!s->px) return SC_ENOMEM;
    float lut[256];
    for (int i = 0; i < 256; i++) lut[i] = decode ? sc_srgb_to_linear(i / 255.0f) : i / 255.0f;
    for (int32_t j = 0; j < im->height; j++)
        for (int32_t i = 0; i < im->width; i++) {
            float *o = s->px + 4 * ((size_t)j * im->width + i);
            for (int c = 0; c < 4; c++) {
                float v;
                if (c < im->channels) {
                    if (im->pixel == SC_PIXEL_U8 && (c < 3 || !decode))
                        v = lut[((const uint8_t *)im->pixels)[((size_t)j * im->width + i) * im->channels + c]];
                    else {
                        v = sc_image_texel(im, i, j, c);
                        if (decode && c < 3 && im->pixel != SC_PIXEL_F32) v = sc_srgb_to_linear(v);
                    }
                    if (im->pixel == SC_PIXEL_U8 && c == 3 && decode)
                        v = ((const uint8_t *)im->pixels)[((size_t)j * im->width + i) * im->channels + c] / 255.0f;
                } else
                    v = c == 3 ? 1.0f : (im->channels == 1 ? o[0] : 0.0f);
                o[c] = v;
            }
        }
    return SC_OK;
}

static void source_sample(const source *s, double u, double v, float out[4]) {
    double x = u * s->w - 0.5, y = v * s->h - 0.5;
    if (!isfinite(x) || !isfinite(y)) x = y = 0;
    double fx = floor(x), fy = floor(y);
    if (fabs(fx) > 1e9 || fabs(fy) > 1e9) fx = fy = 0;
    float ax = (float)(x - fx), ay = (float)(y - fy);
    int32_t i0 = (int32_t)fx, j0 = (int32_t)fy;
    int32_t i[2] = {sc_seam_wrap(i0, s->w, s->tex->wrap_u), sc_seam_wrap(i0 + 1, s->w, s->tex->wrap_u)};
    int32_t j[2] = {sc_seam_wrap(j0, s->h, s->tex->wrap_v), sc_seam_wrap(j0 + 1, s->h, s->tex->wrap_v)};
    const float *p00 = s->px + 4 * ((size_t)j[0] * s->w + i[0]), *p10 = s->px + 4 * ((size_t)j[0] * s->w + i[1]);
    const float *p01 = s->px + 4 * ((size_t)j[1] * s->w + i[0]), *p11 = s->px + 4 * ((size_t)j[1] * s->w + i[1]);
    for (int c = 0; c < 4; c++)
        out[c] = (1 - ay) * ((1 - ax) * p00[c] + ax * p10[c]) + ay * ((1 - ax) * p01[c] + ax * p11[c]);
}

/* ---------------------------------------------------------------- the job */

/* Which material constant a slot's texels take in (the quad atlas has one
 * material; constants its sources disagree on are multiplied into texels). */
typedef enum slot_constant { CONSTANT_NONE, CONSTANT_BASE_COLOR, CONSTANT_METALLIC_ROUGHNESS, CONSTANT_EMISSIVE,
                             CONSTANT_OCCLUSION, CONSTANT_NORMAL } slot_constant;

typedef struct slot {
    char *name;
    slot_kind kind;
    slot_constant bake;    /* the constant its texels take in, or none */
    int32_t channels;
    sc_pixel pixel;
    sc_colorspace colorspace;
    source *by_material;   /* nmat: NULL px when the material has no such texture */
    float neutral[4];
    float **level;         /* nlevels images of 4 floats per texel */
} slot;

typedef struct job {
    const sc_mesh *in;
    qcharts *c;
    int32_t lmax, gshift, W, H, nlevels, S;   /* cells: 2^k + 2^gshift texels */
    int32_t *kq;           /* per chart: 2^kq + 1 samples a side at level 0 */
    int32_t nslots;
    slot *slots;
    double (*frame)[9];    /* per input face: tangent, bitangent, normal (unit) */
    int32_t *chart_x, *chart_y;
    const sc_material *constants;   /* the input's, per material, or NULL */
} job;

static void input_frame(const sc_mesh *m, int32_t f, double fr[9]) {
    const int32_t *F = m->FV + 3 * (size_t)f;
    const double *p0 = m->V + 3 * (size_t)F[0], *p1 = m->V + 3 * (size_t)F[1], *p2 = m->V + 3 * (size_t)F[2];
    double e1[3], e2[3], n[3];
    sc_sub3(p1, p0, e1), sc_sub3(p2, p0, e2);
    sc_cross3(e1, e2, n);
    sc_normalize3(n);
    double T[3] = {1, 0, 0}, sign = 1;
    if (m->nu > 0) {
        const int32_t *U = m->FU + 3 * (size_t)f;
        const double *t0 = m->U + 2 * (size_t)U[0], *t1 = m->U + 2 * (size_t)U[1], *t2 = m->U + 2 * (size_t)U[2];
        double du1 = t1[0] - t0[0], dv1 = t1[1] - t0[1], du2 = t2[0] - t0[0], dv2 = t2[1] - t0[1];
        double det = du1 * dv2 - du2 * dv1;
        if (fabs(det) > 1e-20) {
            for (int i = 0; i < 3; i++) T[i] = (e1[i] * dv2 - e2[i] * dv1) / det;
            sign = det > 0 ? 1 : -1;
        }
    }
    double d = sc_dot3(T, n);
    for (int i = 0; i < 3; i++) T[i] -= d * n[i];
    if (!(sc_norm3(T) > 1e-30)) {
        double a[3] = {fabs(n[0]) < 0.9 ? 1 : 0, fabs(n[0]) < 0.9 ? 0 : 1, 0};
        sc_cross3(n, a, T);
    }
    sc_normalize3(T);
    double B[3];
    sc_cross3(n, T, B);
    for (int i = 0; i < 3; i++) fr[i] = T[i], fr[3 + i] = sign * B[i], fr[6 + i] = n[i];
}

/* The input image and old uv of slot s at a point of refined face f with
 * barycentric l (NULL when the face's material has no such image). */
static const source *old_point(const job *J, const slot *s, int32_t f, const double l[3], double *u, double *v) {
    const qmesh *m = &J->c->m;
    int32_t of = m->old[f];
    const source *src = &s->by_material[J->in->FM ? J->in->FM[of] : 0];
    if (!src->px) return NULL;
    const double *bb = m->bary + 9 * (size_t)f;
    double ob[3];
    for (int i = 0; i < 3; i++) ob[i] = l[0] * bb[i] + l[1] * bb[3 + i] + l[2] * bb[6 + i];
    const int32_t *U = J->in->FU + 3 * (size_t)of;
    *u = 0, *v = 0;
    for (int k = 0; k < 3; k++) *u += ob[k] * J->in->U[2 * (size_t)U[k]], *v += ob[k] * J->in->U[2 * (size_t)U[k] + 1];
    return src;
}

/* Samples a side of chart q at level L. */
static int32_t chart_n(const job *J, int32_t q, int32_t L) { return (1 << (J->kq[q] - L)) + 1; }

/* out (a value of slot s on input face of) times the constant of of's
 * material that s takes in, as glTF applies it. */
static void take_constant(const job *J, const slot *s, int32_t of, float out[4]) {
    const sc_material *c = &J->constants[J->in->FM ? J->in->FM[of] : 0];
    switch (s->bake) {
    case CONSTANT_BASE_COLOR:
        for (int k = 0; k < 4; k++) out[k] = (float)(out[k] * c->base_color[k]);
        break;
    case CONSTANT_METALLIC_ROUGHNESS:
        out[1] = (float)(out[1] * c->roughness), out[2] = (float)(out[2] * c->metallic);
        break;
    case CONSTANT_EMISSIVE:
        for (int k = 0; k < 3; k++) out[k] = (float)(out[k] * c->emissive[k]);
        break;
    case CONSTANT_OCCLUSION: out[0] = (float)(1 + c->occlusion_strength * (out[0] - 1)); break;
    default: break;
    }
}

/* The value of slot s at a point of refined face f with barycentric l. */
static void sample_point(const job *J, const slot *s, int32_t f, const double l[3], const double newT[3],
                         float out[4]) {
    double u, v;
    const source *src = old_point(J, s, f, l, &u, &v);
    int32_t of = J->c->m.old[f];
    if (!src) {
        memcpy(out, s->neutral, 4 * sizeof(float));
        if (s->bake != CONSTANT_NONE && s->bake != CONSTANT_NORMAL) take_constant(J, s, of, out);
        return;
    }
    source_sample(src, u, v, out);
    if (s->bake != CONSTANT_NONE && s->bake != CONSTANT_NORMAL) take_constant(J, s, of, out);
    if (s->kind != SLOT_NORMAL) return;
    const double *fr = J->frame[of];
    double t[3] = {2.0 * out[0] - 1, 2.0 * out[1] - 1, 2.0 * out[2] - 1}, w[3];
    if (s->bake == CONSTANT_NORMAL) {
        double scale = J->constants[J->in->FM ? J->in->FM[of] : 0].normal_scale;
        t[0] *= scale, t[1] *= scale;
    }
    for (int i = 0; i < 3; i++) w[i] = t[0] * fr[i] + t[1] * fr[3 + i] + t[2] * fr[6 + i];
    const double *n = fr + 6;
    double T[3], B[3];
    memcpy(T, newT, sizeof T);
    sc_cross3(n, T, B);
    double x = sc_dot3(w, T), y = sc_dot3(w, B), z = sc_dot3(w, n), len = sqrt(x * x + y * y + z * z);
    if (!(len > 0)) x = 0, y = 0, z = 1, len = 1;
    out[0] = (float)(0.5 * (x / len + 1)), out[1] = (float)(0.5 * (y / len + 1)), out[2] = (float)(0.5 * (z / len + 1));
}

/* The new tangent (d position / d s, in the face's plane, unit) of face f. */
static void chart_tangent(const job *J, int32_t f, double T[3]) {
    const qmesh *m = &J->c->m;
    const double *st = J->c->st + 6 * (size_t)f;
    const int32_t *F = m->tri + 3 * (size_t)f;
    double e1[3], e2[3];
    sc_sub3(m->pos + 3 * (size_t)F[1], m->pos + 3 * (size_t)F[0], e1);
    sc_sub3(m->pos + 3 * (size_t)F[2], m->pos + 3 * (size_t)F[0], e2);
    double ds1 = st[2] - st[0], dt1 = st[3] - st[1], ds2 = st[4] - st[0], dt2 = st[5] - st[1];
    double det = ds1 * dt2 - ds2 * dt1;
    for (int i = 0; i < 3; i++) T[i] = det != 0 ? (e1[i] * dt2 - e2[i] * dt1) / det : (i == 0);
    const double *n = J->frame[m->old[f]] + 6;
    double d = sc_dot3(T, n);
    for (int i = 0; i < 3; i++) T[i] -= d * n[i];
    if (!(sc_norm3(T) > 1e-30)) memcpy(T, J->frame[m->old[f]], 3 * sizeof(double));
    sc_normalize3(T);
}

/* ---------------------------------------------------------------- level 0 */

typedef struct chart_faces {
    int32_t *start, *faces;
} chart_faces;

typedef struct sample_task {
    job *J;
    chart_faces cf;
} sample_task;

/* Chart q's samples at level 0, every slot: S x S points per texel in the
 * texel's square (clipped to the chart), located in the chart's triangles. */
static int sample_chart(void *ud, int32_t q) {
    sample_task *t = ud;
    job *J = t->J;
    int32_t n = chart_n(J, q, 0), S = J->S, G = n * S;
    int32_t *hit = malloc((size_t)G * G * sizeof *hit);
    double *lam = malloc((size_t)G * G * 3 * sizeof *lam);
    double *acc = calloc((size_t)n * n * 4 * J->nslots, sizeof *acc);
    int32_t *cnt = calloc((size_t)n * n, sizeof *cnt);
    if (!hit || !lam || !acc || !cnt) {
        free(hit), free(lam), free(acc), free(cnt);
        return SC_ENOMEM;
    }
    for (int32_t i = 0; i < G * G; i++) hit[i] = -1;
    double scale = (double)(1 << J->kq[q]);
    for (int32_t i = t->cf.start[q]; i < t->cf.start[q + 1]; i++) {
        int32_t f = t->cf.faces[i];
        const double *st = J->c->st + 6 * (size_t)f;
        double x[3], y[3];
        for (int k = 0; k < 3; k++) x[k] = st[2 * k] * scale, y[k] = st[2 * k + 1] * scale;
        double area = (x[1] - x[0]) * (y[2] - y[0]) - (x[2] - x[0]) * (y[1] - y[0]);
        if (!(fabs(area) > 0)) continue;
        double lo_x = fmin(x[0], fmin(x[1], x[2])), hi_x = fmax(x[0], fmax(x[1], x[2]));
        double lo_y = fmin(y[0], fmin(y[1], y[2])), hi_y = fmax(y[0], fmax(y[1], y[2]));
        /* point (a, b) of the fine grid sits at ((a + 0.5) / S - 0.5) in sample units */
        int32_t a0 = (int32_t)floor((lo_x + 0.5) * S - 0.5) - 1, a1 = (int32_t)ceil((hi_x + 0.5) * S - 0.5) + 1;
        int32_t b0 = (int32_t)floor((lo_y + 0.5) * S - 0.5) - 1, b1 = (int32_t)ceil((hi_y + 0.5) * S - 0.5) + 1;
        if (a0 < 0) a0 = 0;
        if (b0 < 0) b0 = 0;
        if (a1 > G - 1) a1 = G - 1;
        if (b1 > G - 1) b1 = G - 1;
        for (int32_t bj = b0; bj <= b1; bj++)
            for (int32_t ai = a0; ai <= a1; ai++) {
                int32_t id = bj * G + ai;
                if (hit[id] >= 0) continue;
                double px = (ai + 0.5) / S - 0.5, py = (bj + 0.5) / S - 0.5;
                if (px < -1e-12 || py < -1e-12 || px > scale + 1e-12 || py > scale + 1e-12) continue;
                if (px < 0) px = 0;
                if (py < 0) py = 0;
                if (px > scale) px = scale;
                if (py > scale) py = scale;
                double l0 = ((x[1] - px) * (y[2] - py) - (x[2] - px) * (y[1] - py)) / area;
                double l1 = ((x[2] - px) * (y[0] - py) - (x[0] - px) * (y[2] - py)) / area;
                double l2 = 1 - l0 - l1;
                const double e = -1e-9;
                if (l0 < e || l1 < e || l2 < e) continue;
                hit[id] = f;
                lam[3 * (size_t)id] = l0, lam[3 * (size_t)id + 1] = l1, lam[3 * (size_t)id + 2] = l2;
            }
    }
    for (int32_t id = 0; id < G * G; id++) {
        if (hit[id] < 0) continue;
        int32_t ai = id % G, bj = id / G, ti = ai / S, tj = bj / S;
        double T[3];
        chart_tangent(J, hit[id], T);
        for (int32_t s = 0; s < J->nslots; s++) {
            float v[4];
            sample_point(J, &J->slots[s], hit[id], lam + 3 * (size_t)id, T, v);
            double *a = acc + ((size_t)s * n * n + (size_t)tj * n + ti) * 4;
            for (int c = 0; c < 4; c++) a[c] += v[c];
        }
        cnt[tj * n + ti]++;
    }
    int32_t x0 = J->chart_x[q], y0 = J->chart_y[q];
    for (int32_t s = 0; s < J->nslots; s++) {
        float *img = J->slots[s].level[0];
        for (int32_t tj = 0; tj < n; tj++)
            for (int32_t ti = 0; ti < n; ti++) {
                const double *a = acc + ((size_t)s * n * n + (size_t)tj * n + ti) * 4;
                int32_t c = cnt[tj * n + ti];
                float *o = img + 4 * ((size_t)(y0 + tj) * J->W + x0 + ti);
                for (int k = 0; k < 4; k++) o[k] = c > 0 ? (float)(a[k] / c) : J->slots[s].neutral[k];
                if (J->slots[s].kind == SLOT_NORMAL && c > 0) {
                    double x = 2.0 * o[0] - 1, y = 2.0 * o[1] - 1, z = 2.0 * o[2] - 1, len = sqrt(x * x + y * y + z * z);
                    if (len > 0) o[0] = (float)(0.5 * (x / len + 1)), o[1] = (float)(0.5 * (y / len + 1)), o[2] = (float)(0.5 * (z / len + 1));
                }
            }
    }
    free(hit), free(lam), free(acc), free(cnt);
    return SC_OK;
}

/* ---------------------------------------------------------------- shared borders */

/* Texel of chart q at level L for chart coordinates (i, j) in samples. */
static float *texel(const job *J, const slot *s, int32_t L, int32_t q, int32_t i, int32_t j) {
    int32_t W = J->W >> L;
    return s->level[L] + 4 * ((size_t)((J->chart_y[q] >> L) + j) * W + (J->chart_x[q] >> L) + i);
}

/* Sample position along side k of a chart of n samples: index t in [0, n). */
static void side_cell(int32_t k, int32_t n, int32_t t, int32_t *i, int32_t *j) {
    switch (k) {
    case 0: *i = t, *j = 0; break;
    case 1: *i = n - 1, *j = t; break;
    case 2: *i = n - 1 - t, *j = n - 1; break;
    default: *i = 0, *j = n - 1 - t; break;
    }
}

/* Make every side and corner of level L hold one set of samples: the first
 * chart (in order) that holds a side or corner gives its samples, every
 * other chart gets a bitwise copy, its own direction accounted for. Charts
 * that share a side have one size (choose_layout sizes whole connected
 * parts alike). */
static int share_borders(job *J, int32_t L) {
    qcharts *c = J->c;
    int32_t *side_owner = malloc((size_t)c->nsides * sizeof *side_owner);
    int32_t *corner_owner = malloc((size_t)c->m.nv * 2 * sizeof *corner_owner);
    if (!side_owner || !corner_owner) {
        free(side_owner), free(corner_owner);
        return SC_ENOMEM;
    }
    for (int32_t i = 0; i < c->nsides; i++) side_owner[i] = -1;
    for (int32_t i = 0; i < 2 * c->m.nv; i++) corner_owner[i] = -1;
    for (int32_t q = 0; q < c->nquads; q++) {
        int32_t n = chart_n(J, q, L);
        for (int k = 0; k < 4; k++) {
            int32_t v = c->corner_v[4 * q + k], ci, cj;
            side_cell(k, n, 0, &ci, &cj);
            if (corner_owner[2 * v] < 0) corner_owner[2 * v] = q, corner_owner[2 * v + 1] = k;
            else {
                int32_t oq = corner_owner[2 * v], ok = corner_owner[2 * v + 1], oi, oj;
                side_cell(ok, chart_n(J, oq, L), 0, &oi, &oj);
                for (int32_t s = 0; s < J->nslots; s++)
                    memcpy(texel(J, &J->slots[s], L, q, ci, cj), texel(J, &J->slots[s], L, oq, oi, oj), 4 * sizeof(float));
            }
            int32_t sid = c->side_id[4 * q + k];
            if (side_owner[sid] < 0) {
                side_owner[sid] = 4 * q + k;
                continue;
            }
            int32_t oq = side_owner[sid] / 4, ok = side_owner[sid] % 4;
            bool same = c->side_rev[4 * q + k] == c->side_rev[4 * oq + ok];
            for (int32_t t = 1; t < n - 1; t++) {
                int32_t i, j, oi, oj;
                side_cell(k, n, t, &i, &j);
                side_cell(ok, n, same ? t : n - 1 - t, &oi, &oj);
                for (int32_t s = 0; s < J->nslots; s++)
                    memcpy(texel(J, &J->slots[s], L, q, i, j), texel(J, &J->slots[s], L, oq, oi, oj), 4 * sizeof(float));
            }
        }
    }
    free(side_owner), free(corner_owner);
    return SC_OK;
}

/* Level L + 1 from level L, chart by chart: inside, the 3x3 binomial at the
 * nested sample; along a border, the 1-D binomial along it; corners kept.
 * Borders are then made one again by share_borders. */
static void filter_level(job *J, int32_t L) {
    for (int32_t s = 0; s < J->nslots; s++) {
        slot *sl = &J->slots[s];
        for (int32_t q = 0; q < J->c->nquads; q++) {
            int32_t n1 = chart_n(J, q, L + 1);
            for (int32_t j = 0; j < n1; j++)
                for (int32_t i = 0; i < n1; i++) {
                    float *o = texel(J, sl, L + 1, q, i, j);
                    int32_t I = 2 * i, Jj = 2 * j;
                    bool bi = i == 0 || i == n1 - 1, bj = j == 0 || j == n1 - 1;
                    for (int c = 0; c < 4; c++) {
                        double v;
                        if (bi && bj) v = texel(J, sl, L, q, I, Jj)[c];
                        else if (bj) v = 0.25 * texel(J, sl, L, q, I - 1, Jj)[c] + 0.5 * texel(J, sl, L, q, I, Jj)[c] + 0.25 * texel(J, sl, L, q, I + 1, Jj)[c];
                        else if (bi) v = 0.25 * texel(J, sl, L, q, I, Jj - 1)[c] + 0.5 * texel(J, sl, L, q, I, Jj)[c] + 0.25 * texel(J, sl, L, q, I, Jj + 1)[c];
                        else {
                            static const double w[3] = {0.25, 0.5, 0.25};
                            v = 0;
                            for (int b = -1; b <= 1; b++)
                                for (int a = -1; a <= 1; a++) v += w[a + 1] * w[b + 1] * texel(J, sl, L, q, I + a, Jj + b)[c];
                        }
                        o[c] = (float)v;
                    }
                }
        }
    }
}

/* Gutters: each chart's right column and top row repeat into the gap after
 * it (for engines that sample without the level offset). */
static void fill_gutters(job *J, int32_t L) {
    int32_t W = J->W >> L, H = J->H >> L;
    for (int32_t s = 0; s < J->nslots; s++)
        for (int32_t q = 0; q < J->c->nquads; q++) {
            int32_t x0 = J->chart_x[q] >> L, y0 = J->chart_y[q] >> L, n = chart_n(J, q, L);
            int32_t g = ((1 << J->kq[q]) >> L) + ((1 << J->gshift) >> L) - n;
            for (int32_t j = 0; j < n + g && y0 + j < H; j++)
                for (int32_t i = 0; i < n + g && x0 + i < W; i++) {
                    if (i < n && j < n) continue;
                    int32_t si = i < n ? i : n - 1, sj = j < n ? j : n - 1;
                    memcpy(J->slots[s].level[L] + 4 * ((size_t)(y0 + j) * W + x0 + i), texel(J, &J->slots[s], L, q, si, sj),
                           4 * sizeof(float));
                }
        }
}

/* ---------------------------------------------------------------- layout */

/* Cells of 2^k + 2^gshift texels, in rows of `cols` within texture_size. */
static bool layout_fits(int32_t k, int32_t gshift, int32_t T, int32_t Q, int32_t *cols, int32_t *rows) {
    int64_t cell = ((int64_t)1 << k) + ((int64_t)1 << gshift);
    if (cell > T) return false;
    *cols = (int32_t)(T / cell);
    *rows = (int32_t)((Q + *cols - 1) / *cols);
    return (int64_t)*rows * cell <= T;
}

static int32_t level_depth(const sc_quad_options *o, int32_t k) {
    int32_t lmax = k - 3;
    if (o->min_size > 0) {
        lmax = 0;
        while ((o->texture_size >> (lmax + 1)) >= o->min_size) lmax++;
    }
    if (lmax > k - 1) lmax = k - 1;
    return lmax < 0 ? 0 : lmax;
}

/* Cells are 2^k + 2^gutter_shift texels, gutter_shift at least lmax (no two
 * charts share a texel at any level) and at least 2: at level 0, where the
 * border samples lie on texel centres, three texels or more lie between two
 * charts, so each chart's border has a texel of its own beyond it. Float32
 * uv put a weight of about 1e-5 on that texel; one texel in both charts'
 * reach holds at least one of them far from its surface, and the GPU then
 * opens the seam by that weight times the distance between two unrelated
 * places of the surface. */
static int32_t gutter_shift(const sc_quad_options *o, int32_t k) {
    int32_t lmax = level_depth(o, k);
    return lmax > 2 ? lmax : 2;
}

/* Shelf packing of the charts in `order` (decreasing size): a shelf is as
 * tall as its first cell; smaller cells stack in columns inside it. Every
 * cell is 2^kq + G texels (G = 2^gshift), so every position is a multiple of
 * G. Returns the height used (INT64_MAX when a cell is wider than T) and
 * sets *width. */
static int64_t pack(const job *J, const int32_t *order, int32_t Q, int32_t T, int32_t *x, int32_t *y, int32_t *width) {
    int64_t G = (int64_t)1 << J->gshift, shelf_y = 0, shelf_h = 0, col_x = 0, col_w = 0, col_y = 0;
    *width = 0;
    for (int32_t i = 0; i < Q; i++) {
        int32_t q = order[i];
        int64_t c = ((int64_t)1 << J->kq[q]) + G;
        if (c > T) return INT64_MAX;
        if (shelf_h == 0) shelf_h = c, col_x = 0, col_w = c, col_y = 0;
        else if (!(col_w == c && col_y + c <= shelf_h)) {
            col_x += col_w, col_w = c, col_y = 0;
            if (col_x + c > T) shelf_y += shelf_h, shelf_h = c, col_x = 0;
        }
        x[q] = (int32_t)col_x, y[q] = (int32_t)(shelf_y + col_y);
        col_y += c;
        if (col_x + c > *width) *width = (int32_t)(col_x + c);
    }
    return shelf_y + shelf_h;
}

static int cmp_i64(const void *a, const void *b) {
    int64_t x = *(const int64_t *)a, y = *(const int64_t *)b;
    return x < y ? -1 : x > y;
}

/* The charts by decreasing size, then by index. */
static void order_by_size(const int32_t *kq, int32_t Q, int64_t *keys, int32_t *order) {
    for (int32_t q = 0; q < Q; q++) keys[q] = ((int64_t)(63 - kq[q]) << 32) | q;
    qsort(keys, (size_t)Q, sizeof *keys, cmp_i64);
    for (int32_t i = 0; i < Q; i++) order[i] = (int32_t)(keys[i] & 0xffffffff);
}

/* Chart sizes and places. One texel density for every chart (samples per
 * unit of surface length): chart q gets 2^k + 1 samples a side with k the
 * nearest to log2(density sqrt(area)), within [lmax + 1, kmax]; the
 * largest density whose packing fits texture_size is kept (bisection).
 * chart_texels fixes one size for all. lmax (levels below 0) comes from
 * min_size, else from the size every chart would have alone. */
static int choose_layout(job *J, const sc_quad_options *o, const double *area, int32_t Q, sc_error *err) {
    int32_t T = o->texture_size, ku = -1;
    if (o->chart_texels > 0) {
        int32_t c = o->chart_texels - 1, kk = 0;
        while ((1 << kk) < c) kk++;
        if ((1 << kk) != c || kk < 1)
            return sc_fail(err, SC_EINPUT, "chart_texels: %d is not 2^k + 1 (3, 5, 9, 17, ...)", (int)o->chart_texels);
        ku = kk;
    } else
        for (int32_t kk = 1; kk <= 14; kk++) {
            int32_t cols, rows;
            if (layout_fits(kk, gutter_shift(o, kk), T, Q, &cols, &rows)) ku = kk;
        }
    if (ku < 0)
        return sc_fail(err, SC_EINPUT, "texture_size: %d texels cannot hold %d charts of 3 x 3 samples", (int)T, (int)Q);
    J->lmax = level_depth(o, ku), J->gshift = gutter_shift(o, ku), J->nlevels = J->lmax + 1;
    int32_t kmin = o->chart_texels > 0 ? ku : J->lmax + 1, kmax = o->chart_texels > 0 ? ku : ku + 4;
    while (kmax > kmin && ((int64_t)1 << kmax) + ((int64_t)1 << J->gshift) > T) kmax--;
    J->kq = malloc((size_t)Q * sizeof *J->kq);
    J->chart_x = malloc((size_t)Q * sizeof *J->chart_x), J->chart_y = malloc((size_t)Q * sizeof *J->chart_y);
    int32_t *order = malloc((size_t)Q * sizeof *order), *best = malloc((size_t)Q * sizeof *best);
    int64_t *keys = malloc((size_t)Q * sizeof *keys);
    if (!J->kq || !J->chart_x || !J->chart_y || !order || !best || !keys) {
        free(order), free(best), free(keys);
        return SC_ENOMEM;
    }
    double total = 0;
    for (int32_t q = 0; q < Q; q++) total += area[q];
    /* density bounds: every chart at kmin, every chart at kmax */
    double lo = 0, hi = ((double)((int64_t)1 << kmax) * 4) / sqrt(total / Q > 0 ? total / Q : 1) * 64;
    bool found = false;
    for (int it = 0; it < 60; it++) {
        double d = it == 0 ? 0 : 0.5 * (lo + hi);
        for (int32_t q = 0; q < Q; q++) {
            double x = d * sqrt(area[q] > 0 ? area[q] : 0);
            int32_t k = x > 1 ? (int32_t)lround(log2(x)) : 0;
            J->kq[q] = k < kmin ? kmin : k > kmax ? kmax : k;
        }
        order_by_size(J->kq, Q, keys, order);
        int32_t w;
        if (pack(J, order, Q, T, J->chart_x, J->chart_y, &w) <= T) {
            found = true;
            memcpy(best, J->kq, (size_t)Q * sizeof *best);
            if (it > 0) lo = d;
        } else if (it == 0)
            break;
        else
            hi = d;
        if (o->chart_texels > 0) break;
    }
    if (!found) {
        free(order), free(best), free(keys);
        return sc_fail(err, SC_EINPUT, "texture_size: %d texels cannot hold %d charts of %d samples a side", (int)T,
                       (int)Q, (1 << kmin) + 1);
    }
    memcpy(J->kq, best, (size_t)Q * sizeof *best);
    order_by_size(J->kq, Q, keys, order);
    J->H = (int32_t)pack(J, order, Q, T, J->chart_x, J->chart_y, &J->W);
    /* whole_texture: the side a multiple of every cell's alignment, as the
     * levels halve it */
    if (o->whole_texture) J->W = J->H = T - T % (1 << J->gshift);
    free(order), free(best), free(keys);
    return SC_OK;
}

/* ---------------------------------------------------------------- the output mesh */

typedef struct uv_key {
    int32_t quad, vertex, corner;
} uv_key;

static int cmp_uv_key(const void *a, const void *b) {
    const uv_key *x = a, *y = b;
    if (x->quad != y->quad) return x->quad < y->quad ? -1 : 1;
    if (x->vertex != y->vertex) return x->vertex < y->vertex ? -1 : 1;
    return x->corner < y->corner ? -1 : x->corner > y->corner;
}

static sc_mesh *output_mesh(const job *J, const sc_mesh *in) {
    const qmesh *m = &J->c->m;
    size_t nc = (size_t)m->nf * 3;
    uv_key *keys = malloc(nc * sizeof *keys);
    if (!keys) return NULL;
    for (size_t h = 0; h < nc; h++) keys[h] = (uv_key){m->quad[h / 3], m->tri[h], (int32_t)h};
    qsort(keys, nc, sizeof *keys, cmp_uv_key);
    int32_t nu = 0;
    for (size_t i = 0; i < nc; i++) nu += i == 0 || keys[i].quad != keys[i - 1].quad || keys[i].vertex != keys[i - 1].vertex;
    sc_mesh *o = sc_mesh_alloc(m->nv, nu, 0, m->nf, 1);
    if (!o) { free(keys); return NULL; }
    memcpy(o->V, m->pos, (size_t)m->nv * 3 * sizeof(double));
    memcpy(o->FV, m->tri, nc * sizeof(int32_t));
    int32_t u = -1;
    for (size_t i = 0; i < nc; i++) {
        if (i == 0 || keys[i].quad != keys[i - 1].quad || keys[i].vertex != keys[i - 1].vertex) {
            u++;
            int32_t h = keys[i].corner, q = keys[i].quad;
            const double *st = J->c->st + 6 * (size_t)(h / 3) + 2 * (h % 3);
            double span = (double)(1 << J->kq[q]);
            o->U[2 * (size_t)u] = (J->chart_x[q] + 0.5 + st[0] * span) / J->W;
            o->U[2 * (size_t)u + 1] = (J->chart_y[q] + 0.5 + st[1] * span) / J->H;
        }
        o->FU[keys[i].corner] = u;
    }
    free(keys);
    const char *name = in->nmat > 0 && in->materials[0] ? in->materials[0] : "quad";
    o->materials[0] = strdup(name);
    if (!o->materials[0]) { sc_mesh_free(o); return NULL; }
    return o;
}

/* ---------------------------------------------------------------- output images */

static sc_image_data *encode_level(const job *J, const slot *s, int32_t L) {
    int32_t W = J->W >> L, H = J->H >> L;
    sc_image_data *im = sc_image_alloc(W, H, s->channels, s->pixel);
    if (!im) return NULL;
    im->colorspace = s->colorspace;
    const float *src = s->level[L];
    bool encode = s->kind == SLOT_COLOUR && s->pixel != SC_PIXEL_F32;
    size_t n = (size_t)W * H;
    for (size_t p = 0; p < n; p++)
        for (int c = 0; c < s->channels; c++) {
            float v = src[4 * p + c];
            if (encode && c < 3) v = sc_linear_to_srgb(v);
            if (s->pixel == SC_PIXEL_F32) ((float *)im->pixels)[p * s->channels + c] = v;
            else {
                double mx = s->pixel == SC_PIXEL_U8 ? 255 : 65535;
                double x = v * mx + 0.5;
                x = x < 0 ? 0 : x > mx ? mx : x;
                if (s->pixel == SC_PIXEL_U8) ((uint8_t *)im->pixels)[p * s->channels + c] = (uint8_t)x;
                else ((uint16_t *)im->pixels)[p * s->channels + c] = (uint16_t)x;
            }
        }
    return im;
}

/* ---------------------------------------------------------------- measures of the written images */

/* Border samples that differ (bytes) between two charts holding one side
 * or corner, at level L of image im. */
static int64_t border_mismatch(const job *J, const sc_image_data *im, int32_t L) {
    const qcharts *c = J->c;
    int32_t W = im->width;
    size_t bpp = (size_t)im->channels * im->pixel;
    int32_t *first = malloc((size_t)c->nsides * sizeof *first);
    if (!first) return -1;
    for (int32_t i = 0; i < c->nsides; i++) first[i] = -1;
    int64_t bad = 0;
    const uint8_t *px = im->pixels;
    for (int32_t q = 0; q < c->nquads; q++)
        for (int k = 0; k < 4; k++) {
            int32_t sid = c->side_id[4 * q + k];
            if (first[sid] < 0) { first[sid] = 4 * q + k; continue; }
            int32_t oq = first[sid] / 4, ok = first[sid] % 4, n = chart_n(J, q, L);
            if (chart_n(J, oq, L) != n) { bad += n; continue; }
            bool same = c->side_rev[4 * q + k] == c->side_rev[4 * oq + ok];
            for (int32_t t = 0; t < n; t++) {
                int32_t i, j, oi, oj;
                side_cell(k, n, t, &i, &j);
                side_cell(ok, n, same ? t : n - 1 - t, &oi, &oj);
                const uint8_t *a = px + ((size_t)((J->chart_y[q] >> L) + j) * W + (J->chart_x[q] >> L) + i) * bpp;
                const uint8_t *b = px + ((size_t)((J->chart_y[oq] >> L) + oj) * W + (J->chart_x[oq] >> L) + oi) * bpp;
                bad += memcmp(a, b, bpp) != 0;
            }
        }
    free(first);
    return bad;
}

/* Samples of every chart at level 0. */
static double chart_samples(const job *J) {
    double n = 0;
    for (int32_t q = 0; q < J->c->nquads; q++) n += (double)chart_n(J, q, 0) * chart_n(J, q, 0);
    return n;
}

/* Texels that the bilinear footprints of two charts' triangles both reach
 * at level L (uv of level 0 plus the level's offset). */
static int64_t shared_texels(const job *J, const sc_mesh *out, int32_t L) {
    int32_t W = J->W >> L, H = J->H >> L;
    int32_t *owner = malloc((size_t)W * H * sizeof *owner);
    if (!owner) return -1;
    for (size_t i = 0; i < (size_t)W * H; i++) owner[i] = -1;
    double du, dv;
    sc_quad_level_offset(J->W, J->H, L, &du, &dv);
    int64_t shared = 0;
    for (int32_t f = 0; f < out->nf; f++) {
        int32_t q = J->c->m.quad[f];
        double lx = 1e300, hx = -1e300, ly = 1e300, hy = -1e300;
        for (int k = 0; k < 3; k++) {
            const double *uv = out->U + 2 * (size_t)out->FU[3 * (size_t)f + k];
            double x = (uv[0] + du) * W - 0.5, y = (uv[1] + dv) * H - 0.5;
            lx = fmin(lx, x), hx = fmax(hx, x), ly = fmin(ly, y), hy = fmax(hy, y);
        }
        int32_t i0 = (int32_t)floor(lx + 1e-9), i1 = (int32_t)ceil(hx - 1e-9), j0 = (int32_t)floor(ly + 1e-9), j1 = (int32_t)ceil(hy - 1e-9);
        for (int32_t j = j0 < 0 ? 0 : j0; j <= j1 && j < H; j++)
            for (int32_t i = i0 < 0 ? 0 : i0; i <= i1 && i < W; i++) {
                int32_t *o = owner + (size_t)j * W + i;
                if (*o == -1) *o = q;
                else if (*o != q && *o != -2) *o = -2, shared++;
            }
    }
    free(owner);
    return shared;
}

static void image_sample(const sc_image_data *im, bool decode, double u, double v, float out[4]) {
    double x = u * im->width - 0.5, y = v * im->height - 0.5;
    int32_t i0 = (int32_t)floor(x), j0 = (int32_t)floor(y);
    double ax = x - i0, ay = y - j0;
    for (int c = 0; c < 4; c++) out[c] = 0;
    for (int b = 0; b < 2; b++)
        for (int a = 0; a < 2; a++) {
            int32_t i = sc_seam_wrap(i0 + a, im->width, SC_WRAP_CLAMP), j = sc_seam_wrap(j0 + b, im->height, SC_WRAP_CLAMP);
            double w = (a ? ax : 1 - ax) * (b ? ay : 1 - ay);
            for (int c = 0; c < im->channels && c < 4; c++) {
                float t = sc_image_texel(im, i, j, c);
                if (decode && c < 3 && im->pixel != SC_PIXEL_F32) t = sc_srgb_to_linear(t);
                out[c] += (float)(w * t);
            }
        }
}

/* The input image resampled to scale s of its sides (each new texel the
 * mean of bilinear reads over its footprint), read through the same wrap. */
static int source_resize(const source *src, double scale, source *out) {
    int32_t w = (int32_t)lround(src->w * scale), h = (int32_t)lround(src->h * scale);
    w = w < 1 ? 1 : w, h = h < 1 ? 1 : h;
    int32_t S = (int32_t)ceil((double)src->w / w);
    S = S < 1 ? 1 : S > 8 ? 8 : S;
    *out = (source){src->tex, malloc((size_t)w * h * 4 * sizeof(float)), w, h};
    if (!out->px) return SC_ENOMEM;
    for (int32_t j = 0; j < h; j++)
        for (int32_t i = 0; i < w; i++) {
            double acc[4] = {0};
            for (int32_t b = 0; b < S; b++)
                for (int32_t a = 0; a < S; a++) {
                    float t[4];
                    source_sample(src, (i + (a + 0.5) / S) / w, (j + (b + 0.5) / S) / h, t);
                    for (int c = 0; c < 4; c++) acc[c] += t[c];
                }
            for (int c = 0; c < 4; c++) out->px[4 * ((size_t)j * w + i) + c] = (float)(acc[c] / (S * S));
        }
    return SC_OK;
}

/* Surface PSNR of slot s: area-uniform points, the new image (as written,
 * decoded) against the input read through the old uv. The floor: the input
 * resampled into itself at the new atlas's texel count (its covered texels
 * scaled to the charts' samples) and read back through the old uv, the
 * loss any atlas of that many texels starts from. */
static int surface_psnr(const job *J, const slot *s, const sc_image_data *im, const sc_mesh *out, int32_t npts,
                        double *psnr, double *floor_psnr, sc_error *err) {
    const qmesh *m = &J->c->m;
    *psnr = *floor_psnr = NAN;
    if (npts <= 0) return SC_OK;
    int32_t nmat = J->in->nmat;
    double old_texels = 0, new_texels = chart_samples(J);
    for (int32_t mat = 0; mat < nmat; mat++) {
        const source *src = &s->by_material[mat];
        if (!src->px) continue;
        sc_seam_grid g = {src->w, src->h, src->tex->wrap_u, src->tex->wrap_v};
        sc_seam_coverage cov;
        int rc = sc_seam_coverage_build(J->in, mat, &g, 1, &cov, err);
        if (rc) return rc;
        old_texels += (double)cov.ncovered;
        sc_seam_coverage_free(&cov);
    }
    double scale = old_texels > 0 ? sqrt(new_texels / old_texels) : 1;
    source *small = calloc(nmat > 0 ? (size_t)nmat : 1, sizeof *small);
    double *cdf = malloc((m->nf > 0 ? (size_t)m->nf : 1) * sizeof *cdf);
    int rc = small && cdf ? SC_OK : SC_ENOMEM;
    for (int32_t mat = 0; mat < nmat && rc == SC_OK; mat++)
        if (s->by_material[mat].px) rc = source_resize(&s->by_material[mat], scale, &small[mat]);
    double acc = 0;
    for (int32_t f = 0; f < m->nf && rc == SC_OK; f++) {
        const int32_t *F = m->tri + 3 * (size_t)f;
        double nrm[3];
        sc_triangle_normal(m->pos + 3 * (size_t)F[0], m->pos + 3 * (size_t)F[1], m->pos + 3 * (size_t)F[2], nrm);
        acc += 0.5 * sc_norm3(nrm);
        cdf[f] = acc;
    }
    uint64_t rng = 0x9e3779b97f4a7c15ull;
    double se = 0, se_floor = 0;
    int64_t count = 0, count_floor = 0;
    int nch = s->channels < 3 ? s->channels : 3;
    for (int32_t p = 0; p < npts && rc == SC_OK; p++) {
        double r[3];
        for (int k = 0; k < 3; k++) {
            rng ^= rng << 13, rng ^= rng >> 7, rng ^= rng << 17;
            r[k] = (double)(rng >> 11) / 9007199254740992.0;
        }
        double target = r[0] * acc;
        int32_t lo = 0, hi = m->nf - 1;
        while (lo < hi) {
            int32_t mid = (lo + hi) / 2;
            if (cdf[mid] < target) lo = mid + 1;
            else hi = mid;
        }
        double a = sqrt(r[1]), l[3] = {1 - a, a * (1 - r[2]), a * r[2]};
        int32_t f = lo;
        double T[3];
        chart_tangent(J, f, T);
        float ref[4], got[4];
        sample_point(J, s, f, l, T, ref);
        double u = 0, v = 0;
        for (int k = 0; k < 3; k++) {
            const double *uv = out->U + 2 * (size_t)out->FU[3 * (size_t)f + k];
            u += l[k] * uv[0], v += l[k] * uv[1];
        }
        image_sample(im, s->kind == SLOT_COLOUR, u, v, got);
        for (int c = 0; c < nch; c++) se += (double)(got[c] - ref[c]) * (got[c] - ref[c]), count++;
        double ou, ov;
        const source *src = old_point(J, s, f, l, &ou, &ov);
        if (src) {
            float raw[4], low[4];
            source_sample(src, ou, ov, raw);
            source_sample(&small[src - s->by_material], ou, ov, low);
            for (int c = 0; c < nch; c++) se_floor += (double)(low[c] - raw[c]) * (low[c] - raw[c]), count_floor++;
        }
    }
    if (small)
        for (int32_t mat = 0; mat < nmat; mat++) free(small[mat].px);
    free(small), free(cdf);
    if (rc) return rc == SC_ENOMEM ? sc_fail(err, SC_ENOMEM, "out of memory") : rc;
    double mse = count ? se / count : 0, mse_floor = count_floor ? se_floor / count_floor : 0;
    *psnr = mse > 0 ? 10 * log10(1 / mse) : INFINITY;
    *floor_psnr = count_floor == 0 ? NAN : mse_floor > 0 ? 10 * log10(1 / mse_floor) : INFINITY;
    return SC_OK;
}

/* Charts that share a side must have one size (their border samples are
 * copied bit for bit), so sizes go by connected part: each chart's area is
 * replaced by the mean chart area of its part (charts joined by sides). */
static int part_mean_areas(const qcharts *c, double *area) {
    int32_t Q = c->nquads;
    int32_t *parent = malloc((size_t)Q * sizeof *parent), *holder = malloc((size_t)c->nsides * sizeof *holder);
    double *sum = calloc((size_t)Q, sizeof *sum), *count = calloc((size_t)Q, sizeof *count);
    if (!parent || !holder || !sum || !count) {
        free(parent), free(holder), free(sum), free(count);
        return SC_ENOMEM;
    }
    for (int32_t q = 0; q < Q; q++) parent[q] = q;
    for (int32_t i = 0; i < c->nsides; i++) holder[i] = -1;
    for (int32_t q = 0; q < Q; q++)
        for (int k = 0; k < 4; k++) {
            int32_t sid = c->side_id[4 * q + k];
            if (holder[sid] < 0) { holder[sid] = q; continue; }
            int32_t x = q, y = holder[sid];
            while (parent[x] != x) x = parent[x] = parent[parent[x]];
            while (parent[y] != y) y = parent[y] = parent[parent[y]];
            if (x != y) parent[x] = y;
        }
    for (int32_t q = 0; q < Q; q++) {
        int32_t r = q;
        while (parent[r] != r) r = parent[r];
        parent[q] = r, sum[r] += area[q], count[r] += 1;
    }
    for (int32_t q = 0; q < Q; q++) area[q] = sum[parent[q]] / count[parent[q]];
    free(parent), free(holder), free(sum), free(count);
    return SC_OK;
}

/* ---------------------------------------------------------------- the whole build */

static void job_free(job *J) {
    if (J->slots)
        for (int32_t s = 0; s < J->nslots; s++) {
            slot *sl = &J->slots[s];
            free(sl->name);
            if (sl->by_material)
                for (int32_t m = 0; m < J->in->nmat; m++) free(sl->by_material[m].px);
            free(sl->by_material);
            if (sl->level)
                for (int32_t L = 0; L < J->nlevels; L++) free(sl->level[L]);
            free(sl->level);
        }
    free(J->slots), free(J->frame), free(J->chart_x), free(J->chart_y), free(J->kq);
}

static int setup_slots(job *J, const sc_texture *tex, int32_t ntex) {
    J->slots = calloc((size_t)(ntex > 0 ? ntex : 1), sizeof *J->slots);
    if (!J->slots) return SC_ENOMEM;
    for (int32_t t = 0; t < ntex; t++) {
        const sc_image_data *im = tex[t].image->as.image;
        int32_t s = 0;
        while (s < J->nslots && strcmp(J->slots[s].name, tex[t].name) != 0) s++;
        slot *sl = &J->slots[s];
        if (s == J->nslots) {
            J->nslots++;
            sl->name = strdup(tex[t].name);
            sl->by_material = calloc((size_t)J->in->nmat, sizeof *sl->by_material);
            if (!sl->name || !sl->by_material) return SC_ENOMEM;
            sl->kind = strcmp(tex[t].name, "normal") == 0 ? SLOT_NORMAL
                       : im->colorspace == SC_COLOR_DATA ? SLOT_DATA
                                                         : SLOT_COLOUR;
            sl->pixel = im->pixel, sl->colorspace = im->colorspace, sl->channels = im->channels;
            float nv = strcmp(tex[t].name, "emissive") == 0 ? 0.0f : 1.0f;
            for (int c = 0; c < 4; c++) sl->neutral[c] = c == 3 ? 1.0f : nv;
            if (sl->kind == SLOT_NORMAL) sl->neutral[0] = sl->neutral[1] = 0.5f, sl->neutral[2] = 1.0f;
        }
        if (im->channels > sl->channels) sl->channels = im->channels;
        int32_t mat = tex[t].material;
        if (mat < 0 || mat >= J->in->nmat || sl->by_material[mat].px) continue;
        int rc = source_load(&sl->by_material[mat], &tex[t], sl->kind == SLOT_COLOUR && im->colorspace == SC_COLOR_SRGB);
        if (rc) return rc;
    }
    return SC_OK;
}

static int chart_faces_build(const qcharts *c, chart_faces *cf) {
    cf->start = calloc((size_t)c->nquads + 1, sizeof *cf->start);
    cf->faces = malloc((size_t)c->m.nf * sizeof *cf->faces);
    if (!cf->start || !cf->faces) return SC_ENOMEM;
    for (int32_t f = 0; f < c->m.nf; f++) cf->start[c->m.quad[f] + 1]++;
    for (int32_t q = 0; q < c->nquads; q++) cf->start[q + 1] += cf->start[q];
    int32_t *fill = malloc((size_t)c->nquads * sizeof *fill);
    if (!fill) return SC_ENOMEM;
    memcpy(fill, cf->start, (size_t)c->nquads * sizeof *fill);
    for (int32_t f = 0; f < c->m.nf; f++) cf->faces[fill[c->m.quad[f]]++] = f;
    free(fill);
    return SC_OK;
}

/* Each slot's surface PSNR on its own thread: slots are independent, and
 * their results go into the metrics in slot order. */
typedef struct psnr_result {
    double psnr, floor_psnr;
    int rc;
    sc_error err;
} psnr_result;

typedef struct psnr_task {
    const job *J;
    const sc_quad_result *out;
    int32_t samples;
    psnr_result *slots;
} psnr_task;

static int psnr_one(void *ud, int32_t s) {
    psnr_task *t = ud;
    psnr_result *r = &t->slots[s];
    r->rc = surface_psnr(t->J, &t->J->slots[s], t->out->textures[s].levels[0], t->out->mesh, t->samples, &r->psnr,
                         &r->floor_psnr, &r->err);
    return SC_OK;
}

/* The quad atlas's one material from the input's constants: a constant
 * every used material agrees on is kept; one they differ on is multiplied
 * into its slot's texels (the slot's `bake`) and left neutral, or, with no
 * such slot, taken from the first used material and counted in
 * *unbaked. Render state: the most transparent alpha mode (MASK with the
 * smallest cutoff), double-sided where any is. */
static sc_material merge_constants(job *J, int32_t *unbaked) {
    const sc_mesh *m = J->in;
    const sc_material *c = J->constants;
    bool *used = calloc((size_t)(m->nmat > 0 ? m->nmat : 1), sizeof *used);
    int32_t first = -1;
    for (int32_t f = 0; f < m->nf; f++) {
        int32_t k = m->FM ? m->FM[f] : 0;
        if (used) used[k] = true;
        if (first < 0) first = k;
    }
    sc_material out = c[first < 0 ? 0 : first];
    bool differ[6] = {false};
    double cutoff = INFINITY;
    out.alpha_mode = SC_ALPHA_OPAQUE, out.double_sided = false;
    for (int32_t k = 0; k < m->nmat; k++) {
        if (used && !used[k]) continue;
        const sc_material *a = &c[k], *b = &c[first];
        differ[CONSTANT_BASE_COLOR] |= memcmp(a->base_color, b->base_color, sizeof a->base_color) != 0;
        differ[CONSTANT_METALLIC_ROUGHNESS] |= a->metallic != b->metallic || a->roughness != b->roughness;
        differ[CONSTANT_EMISSIVE] |= memcmp(a->emissive, b->emissive, sizeof a->emissive) != 0;
        differ[CONSTANT_OCCLUSION] |= a->occlusion_strength != b->occlusion_strength;
        differ[CONSTANT_NORMAL] |= a->normal_scale != b->normal_scale;
        if (a->alpha_mode > out.alpha_mode) out.alpha_mode = a->alpha_mode;
        if (a->alpha_mode == SC_ALPHA_MASK && a->alpha_cutoff < cutoff) cutoff = a->alpha_cutoff;
        out.double_sided |= a->double_sided;
    }
    free(used);
    if (out.alpha_mode == SC_ALPHA_MASK) out.alpha_cutoff = cutoff;
    static const char *const slot_of[6] = {NULL, "color", "metallic_roughness", "emissive", "occlusion", "normal"};
    for (int k = CONSTANT_BASE_COLOR; k <= CONSTANT_NORMAL; k++) {
        if (!differ[k]) continue;
        int32_t s = 0;
        while (s < J->nslots && strcmp(J->slots[s].name, slot_of[k]) != 0) s++;
        if (s == J->nslots) {
            (*unbaked)++;
            continue;
        }
        J->slots[s].bake = (slot_constant)k;
        sc_material neutral = sc_material_default();
        switch (k) {
        case CONSTANT_BASE_COLOR: memcpy(out.base_color, neutral.base_color, sizeof out.base_color); break;
        case CONSTANT_METALLIC_ROUGHNESS: out.metallic = out.roughness = 1; break;
        case CONSTANT_EMISSIVE: out.emissive[0] = out.emissive[1] = out.emissive[2] = 1; break;
        case CONSTANT_OCCLUSION: out.occlusion_strength = 1; break;
        default: out.normal_scale = 1; break;
        }
    }
    return out;
}

int sc_quad_build(const sc_mesh *m, const sc_texture *tex, int32_t ntex, const sc_quad_options *o, int threads,
                  sc_quad_result *out, sc_error *err) {
    memset(out, 0, sizeof *out);
    if (m->nf <= 0) return sc_fail(err, SC_EINPUT, "atlas: the mesh has no faces");
    if (ntex > 0 && m->nu <= 0) return sc_fail(err, SC_EINPUT, "atlas: textures but no uv to read them through");
    if (o->texture_size < 8) return sc_fail(err, SC_EINPUT, "texture_size: %d is too small", (int)o->texture_size);
    double t0 = now_seconds();
    int32_t target = o->target_quads;
    int64_t slots = 0;   /* filling: the cells of the texture at the chosen chart size */
    if (target <= 0 && o->target_patches <= 0) {
        /* fill the texture: the quads that fit at the requested (or a middling) chart size */
        int32_t k = 0;
        if (o->chart_texels > 0)
            while ((1 << k) + 1 < o->chart_texels) k++;
        else {
            k = 4;
            int64_t want = m->nf / 32;
            while (k < 12) {
                int32_t cols, rows;
                int64_t cell = ((int64_t)1 << (k + 1)) + ((int64_t)1 << gutter_shift(o, k + 1));
                if (!layout_fits(k + 1, gutter_shift(o, k + 1), o->texture_size, 1, &cols, &rows)) break;
                if ((o->texture_size / cell) * (o->texture_size / cell) < want) break;
                k++;
            }
        }
        int64_t cell = ((int64_t)1 << k) + ((int64_t)1 << gutter_shift(o, k));
        int64_t per = o->texture_size / (cell > 0 ? cell : 1);
        slots = per * per;
        target = (int32_t)(slots * 9 / 10);
        if (target < 1) target = 1;
    }
    qcharts c;
    int rc = sc_quad_charts(m, o, target, &c, err);
    if (rc) return rc;
    if (slots > 0 && c.nquads < target * 0.9) {
        /* merging stops on an estimate of the quads (patch sides before
         * corners are final); aim once more, scaled by how far it fell
         * short, and keep that atlas if it still fits the cells */
        qcharts again;
        int64_t aim = (int64_t)target * target / (c.nquads > 0 ? c.nquads : 1);
        rc = sc_quad_charts(m, o, (int32_t)(aim < INT32_MAX ? aim : INT32_MAX), &again, err);
        if (rc) {
            sc_quad_charts_free(&c);
            return rc;
        }
        if (again.nquads <= slots && again.nquads > c.nquads) {
            sc_quad_charts_free(&c);
            c = again;
        } else
            sc_quad_charts_free(&again);
    }
    double t1 = now_seconds();
    job J = {0};
    J.in = m, J.c = &c, J.S = o->supersample > 0 ? o->supersample : 1;
    double *area = calloc((size_t)c.nquads + 1, sizeof *area);
    if (!area) rc = SC_ENOMEM;
    for (int32_t f = 0; f < c.m.nf && rc == SC_OK; f++) {
        const int32_t *F = c.m.tri + 3 * (size_t)f;
        double nrm[3];
        sc_triangle_normal(c.m.pos + 3 * (size_t)F[0], c.m.pos + 3 * (size_t)F[1], c.m.pos + 3 * (size_t)F[2], nrm);
        area[c.m.quad[f]] += 0.5 * sc_norm3(nrm);
    }
    if (rc == SC_OK) rc = part_mean_areas(&c, area);
    if (rc == SC_OK) rc = choose_layout(&J, o, area, c.nquads, err);
    free(area);
    if (rc == SC_OK) rc = setup_slots(&J, tex, ntex);
    int32_t unbaked = 0;
    if (rc == SC_OK && o->constants) {
        J.constants = o->constants;
        out->constants = merge_constants(&J, &unbaked);
        out->has_constants = true;
        for (int32_t s = 0; s < J.nslots; s++) {   /* glTF: an absent emissive map reads as white, times the factor */
            float *nv = J.slots[s].neutral;
            if (strcmp(J.slots[s].name, "emissive") == 0) nv[0] = nv[1] = nv[2] = 1;
        }
    }
    if (rc == SC_OK) {
        J.frame = malloc((size_t)m->nf * sizeof *J.frame);
        if (!J.frame) rc = SC_ENOMEM;
        else
            for (int32_t f = 0; f < m->nf; f++) input_frame(m, f, J.frame[f]);
    }
    for (int32_t s = 0; s < J.nslots && rc == SC_OK; s++) {
        J.slots[s].level = calloc((size_t)J.nlevels, sizeof *J.slots[s].level);
        if (!J.slots[s].level) rc = SC_ENOMEM;
        for (int32_t L = 0; L < J.nlevels && rc == SC_OK; L++) {
            J.slots[s].level[L] = calloc((size_t)(J.W >> L) * (J.H >> L) * 4, sizeof(float));
            if (!J.slots[s].level[L]) rc = SC_ENOMEM;
        }
    }
    sample_task task = {&J, {0}};
    if (rc == SC_OK) rc = chart_faces_build(&c, &task.cf);
    if (rc == SC_OK && J.nslots > 0) rc = sc_parallel(threads, c.nquads, sample_chart, &task);
    free(task.cf.start), free(task.cf.faces);
    double t2 = now_seconds();
    if (rc == SC_OK && J.nslots > 0) {
        rc = share_borders(&J, 0);
        for (int32_t L = 0; L + 1 < J.nlevels && rc == SC_OK; L++) {
            filter_level(&J, L);
            rc = share_borders(&J, L + 1);
        }
        for (int32_t L = 0; L < J.nlevels && rc == SC_OK; L++) fill_gutters(&J, L);
    }
    double t3 = now_seconds();
    sc_mesh *mesh = rc == SC_OK ? output_mesh(&J, m) : NULL;
    if (rc == SC_OK && !mesh) rc = SC_ENOMEM;
    if (rc == SC_OK) {
        out->mesh = mesh, out->width = J.W, out->height = J.H, out->nlevels = J.nlevels;
        out->textures = calloc((size_t)(J.nslots > 0 ? J.nslots : 1), sizeof *out->textures);
        if (!out->textures) rc = SC_ENOMEM;
        else out->ntex = J.nslots;
    }
    for (int32_t s = 0; s < J.nslots && rc == SC_OK; s++) {
        sc_quad_texture *t = &out->textures[s];
        t->name = strdup(J.slots[s].name), t->wrap_u = t->wrap_v = SC_WRAP_CLAMP;
        t->levels = calloc((size_t)J.nlevels, sizeof *t->levels);
        if (!t->name || !t->levels) { rc = SC_ENOMEM; break; }
        t->nlevels = J.nlevels;
        for (int32_t L = 0; L < J.nlevels && rc == SC_OK; L++) {
            t->levels[L] = encode_level(&J, &J.slots[s], L);
            if (!t->levels[L]) rc = SC_ENOMEM;
        }
    }
    double t4 = now_seconds();
    /* measures, read back from what was written */
    sc_metric_list *ml = &out->metrics;
    if (rc == SC_OK) {
        int64_t mismatch = 0, shared = 0;
        for (int32_t s = 0; s < J.nslots; s++)
            for (int32_t L = 0; L < J.nlevels; L++) {
                int64_t b = border_mismatch(&J, out->textures[s].levels[L], L);
                mismatch += b < 0 ? 0 : b;
            }
        for (int32_t L = 0; L < J.nlevels; L++) {
            int64_t sh = shared_texels(&J, out->mesh, L);
            char name[64];
            snprintf(name, sizeof name, "shared_texels_level%d", (int)L);
            sc_metric_list_add(ml, name, (double)sh);
            shared += sh < 0 ? 0 : sh;
        }
        double covered = chart_samples(&J);
        int32_t kmin = 30, kmax = 0;
        for (int32_t q = 0; q < c.nquads; q++) kmin = J.kq[q] < kmin ? J.kq[q] : kmin, kmax = J.kq[q] > kmax ? J.kq[q] : kmax;
        sc_metric_list_add(ml, "patches", c.npatches);
        sc_metric_list_add(ml, "quads", c.nquads);
        if (out->has_constants) sc_metric_list_add(ml, "material_constants_unbaked", unbaked);
        static const char *const hist[9] = {"patches_3_sided", "patches_4_sided", "patches_5_sided", "patches_6_sided",
                                            "patches_7_sided", "patches_8_sided", "patches_9_sided", "patches_10_sided",
                                            "patches_11plus_sided"};
        for (int i = 0; i < 9; i++) sc_metric_list_add(ml, hist[i], c.sides_hist[i]);
        sc_metric_list_add(ml, "faces_in", m->nf);
        sc_metric_list_add(ml, "faces_out", c.m.nf);
        sc_metric_list_add(ml, "patches_cut_straight", c.straight_cuts);
        sc_metric_list_add(ml, "patch_borders_straightened", c.straightened_borders);
        sc_metric_list_add(ml, "chart_texels_min", (1 << kmin) + 1);
        sc_metric_list_add(ml, "chart_texels_max", (1 << kmax) + 1);
        sc_metric_list_add(ml, "width", J.W);
        sc_metric_list_add(ml, "height", J.H);
        sc_metric_list_add(ml, "levels", J.nlevels);
        sc_metric_list_add(ml, "gutter_texels", 1 << J.gshift);
        sc_metric_list_add(ml, "utilisation", covered / ((double)J.W * J.H));
        sc_metric_list_add(ml, "stretch_l2", c.stretch_l2);
        sc_metric_list_add(ml, "stretch_linf", c.stretch_linf);
        sc_metric_list_add(ml, "stretch_l2_within_charts", c.stretch_l2_within);
        sc_metric_list_add(ml, "flipped_triangles", c.flipped);
        sc_metric_list_add(ml, "boundary_mismatch", (double)mismatch);
        sc_metric_list_add(ml, "shared_texels", (double)shared);
        psnr_task measure = {&J, out, o->psnr_samples, calloc((size_t)J.nslots + 1, sizeof *measure.slots)};
        if (!measure.slots) rc = sc_fail(err, SC_ENOMEM, "quad_chartify: out of memory");
        if (rc == SC_OK && sc_parallel(threads, J.nslots, psnr_one, &measure) != SC_OK)
            for (int32_t s = 0; s < J.nslots; s++) psnr_one(&measure, s);   /* one thread */
        for (int32_t s = 0; s < J.nslots && rc == SC_OK; s++) {
            char name[96];
            if (measure.slots[s].rc != SC_OK) {
                rc = measure.slots[s].rc;
                if (err) *err = measure.slots[s].err;
                break;
            }
            snprintf(name, sizeof name, "psnr_%s", J.slots[s].name);
            sc_metric_list_add(ml, name, measure.slots[s].psnr);
            snprintf(name, sizeof name, "psnr_floor_%s", J.slots[s].name);
            sc_metric_list_add(ml, name, measure.slots[s].floor_psnr);
        }
        free(measure.slots);
        double t5 = now_seconds();
        sc_metric_list_add(ml, "seconds_charts", t1 - t0);
        sc_metric_list_add(ml, "seconds_sample", t2 - t1);
        sc_metric_list_add(ml, "seconds_levels", t3 - t2);
        sc_metric_list_add(ml, "seconds_encode", t4 - t3);
        sc_metric_list_add(ml, "seconds_measure", t5 - t4);
        if (ml->failed) rc = SC_ENOMEM;
    }
    job_free(&J);
    sc_quad_charts_free(&c);
    if (rc) {
        if (!out->mesh && mesh) sc_mesh_free(mesh);
        sc_quad_result_free(out);
        if (rc == SC_ENOMEM && !err->message[0]) sc_fail(err, SC_ENOMEM, "out of memory");
    }
    return rc;
}

void sc_quad_result_free(sc_quad_result *r) {
    if (r->mesh) sc_mesh_free(r->mesh);
    if (r->textures)
        for (int32_t s = 0; s < r->ntex; s++) {
            free(r->textures[s].name);
            if (r->textures[s].levels)
                for (int32_t L = 0; L < r->textures[s].nlevels; L++) sc_image_free(r->textures[s].levels[L]);
            free(r->textures[s].levels);
        }
    free(r->textures);
    sc_metric_list_free(&r->metrics);
    memset(r, 0, sizeof *r);
}
