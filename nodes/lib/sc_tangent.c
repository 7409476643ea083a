/* sc_tangent.c - MikkTSpace frames, tangent <-> object space, and the
 * reconstructed normal's seam gap (see sc_tangent.h). */
#include "sc_tangent.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

static const sc_kernel *const tangent_uses[] = {&sc_kernel_seam, NULL};
const sc_kernel sc_kernel_tangent = {"tangent", SC_TANGENT_VERSION, tangent_uses};

static double dot3(const double a[3], const double b[3]) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
static void cross3(const double a[3], const double b[3], double o[3]) {
    o[0] = a[1] * b[2] - a[2] * b[1], o[1] = a[2] * b[0] - a[0] * b[2], o[2] = a[0] * b[1] - a[1] * b[0];
}
static bool normalize3(double v[3]) {
    double l = sqrt(dot3(v, v));
    if (!(l > 1e-300)) return false;
    v[0] /= l, v[1] /= l, v[2] /= l;
    return true;
}

/* ---------------------------------------------------------------- normals */

static void face_normal(const sc_mesh *m, int32_t f, double n[3]) {
    const double *P0 = m->V + 3 * (size_t)m->FV[3 * f], *P1 = m->V + 3 * (size_t)m->FV[3 * f + 1],
                 *P2 = m->V + 3 * (size_t)m->FV[3 * f + 2];
    double e1[3] = {P1[0] - P0[0], P1[1] - P0[1], P1[2] - P0[2]}, e2[3] = {P2[0] - P0[0], P2[1] - P0[1], P2[2] - P0[2]};
    cross3(e1, e2, n);
    if (!normalize3(n)) n[0] = 0, n[1] = 0, n[2] = 1;
}

/* The angle of face f at its corner c. */
static double corner_angle(const sc_mesh *m, int32_t f, int c) {
    const double *P = m->V + 3 * (size_t)m->FV[3 * f + c], *A = m->V + 3 * (size_t)m->FV[3 * f + (c + 1) % 3],
                 *B = m->V + 3 * (size_t)m->FV[3 * f + (c + 2) % 3];
    double a[3] = {A[0] - P[0], A[1] - P[1], A[2] - P[2]}, b[3] = {B[0] - P[0], B[1] - P[1], B[2] - P[2]};
    return normalize3(a) && normalize3(b) ? acos(fmax(-1.0, fmin(1.0, dot3(a, b)))) : 0;
}

double *sc_tangent_corner_normals(const sc_mesh *m) {
    size_t nc = (size_t)m->nf * 3;
    double *out = sc_alloc_array(nc ? nc * 3 : 1, sizeof *out);
    if (!out) return NULL;
    if (m->nn > 0) {
        for (size_t k = 0; k < nc; k++) {
            double *n = out + 3 * k;
            memcpy(n, m->N + 3 * (size_t)m->FN[k], 3 * sizeof *n);
            if (!normalize3(n)) face_normal(m, (int32_t)(k / 3), n);
        }
        return out;
    }
    /* the faces around each vertex (CSR), with their normals */
    int32_t *start = sc_calloc_array((size_t)m->nv + 1, sizeof *start), *at = sc_alloc_array(nc ? nc : 1, sizeof *at);
    double *fn = sc_alloc_array(m->nf ? (size_t)m->nf * 3 : 1, sizeof *fn);
    double *angle = sc_alloc_array(nc ? nc : 1, sizeof *angle);   /* per corner, each once */
    if (!start || !at || !fn || !angle) {
        free(start), free(at), free(fn), free(angle), free(out);
        return NULL;
    }
    for (int32_t f = 0; f < m->nf; f++) face_normal(m, f, fn + 3 * (size_t)f);
    for (size_t k = 0; k < nc; k++) angle[k] = corner_angle(m, (int32_t)(k / 3), (int)(k % 3));
    for (size_t k = 0; k < nc; k++) start[m->FV[k] + 1]++;
    for (int32_t v = 0; v < m->nv; v++) start[v + 1] += start[v];
    int32_t *fill = sc_alloc_array((size_t)m->nv + 1, sizeof *fill);
    if (!fill) {
        free(start), free(at), free(fn), free(angle), free(out);
        return NULL;
    }
    memcpy(fill, start, sizeof *fill * ((size_t)m->nv + 1));
    for (size_t k = 0; k < nc; k++) at[fill[m->FV[k]]++] = (int32_t)k;
    free(fill);
    const double smooth = cos(SC_TANGENT_SMOOTH_DEGREES * M_PI / 180);
    for (size_t k = 0; k < nc; k++) {
        const double *own = fn + 3 * (k / 3);
        double *n = out + 3 * k;
        n[0] = n[1] = n[2] = 0;
        int32_t v = m->FV[k];
        for (int32_t i = start[v]; i < start[v + 1]; i++) {
            int32_t c = at[i], f = c / 3;
            const double *o = fn + 3 * (size_t)f;
            if (dot3(o, own) < smooth) continue;
            double w = angle[c];
            for (int d = 0; d < 3; d++) n[d] += w * o[d];
        }
        if (!normalize3(n)) memcpy(n, own, 3 * sizeof *n);
    }
    free(start), free(at), free(fn), free(angle);
    return out;
}

/* ---------------------------------------------------------------- frames */

typedef struct corner_key {
    int32_t v, u, pad, orient, corner;
    double n[3];
} corner_key;

static int cmp_corner_key(const void *pa, const void *pb) {
    const corner_key *a = pa, *b = pb;
    if (a->v != b->v) return a->v < b->v ? -1 : 1;
    if (a->u != b->u) return a->u < b->u ? -1 : 1;
    int c = memcmp(a->n, b->n, sizeof a->n);
    if (c) return c;
    if (a->orient != b->orient) return a->orient < b->orient ? -1 : 1;
    return a->corner < b->corner ? -1 : a->corner > b->corner;
}

void sc_tangent_frames_free(sc_tangent_frames *f) {
    free(f->tangent), free(f->normal);
    *f = (sc_tangent_frames){0};
}

int sc_tangent_frames_build(const sc_mesh *m, sc_tangent_frames *out, sc_error *err) {
    *out = (sc_tangent_frames){0};
    const int32_t nf = m->nf;
    size_t nc = (size_t)nf * 3;
    out->nf = nf;
    out->tangent = sc_calloc_array(nc ? nc * 4 : 1, sizeof *out->tangent);
    out->normal = sc_calloc_array(nc ? nc * 3 : 1, sizeof *out->normal);
    double *face_t = sc_alloc_array(nc ? nc * 4 : 1, sizeof *face_t);   /* per corner: projected unit tangent, angle */
    int8_t *orient = sc_alloc_array(nf ? (size_t)nf : 1, sizeof *orient);
    corner_key *keys = sc_alloc_array(nc ? nc : 1, sizeof *keys);
    double *normals = sc_tangent_corner_normals(m);
    if (normals) memcpy(out->normal, normals, (nc ? nc : 1) * 3 * sizeof *normals);
    free(normals);
    if (!out->tangent || !out->normal || !face_t || !orient || !keys || !normals) {
        free(face_t), free(orient), free(keys);
        sc_tangent_frames_free(out);
        return sc_fail(err, SC_ENOMEM, "tangent frames: out of memory");
    }
    for (int32_t f = 0; f < nf; f++) {
        const double *P[3], *U[3];
        for (int c = 0; c < 3; c++) P[c] = m->V + 3 * (size_t)m->FV[3 * f + c], U[c] = m->U + 2 * (size_t)m->FU[3 * f + c];
        double e1[3], e2[3];
        for (int d = 0; d < 3; d++) e1[d] = P[1][d] - P[0][d], e2[d] = P[2][d] - P[0][d];
        double s1 = U[1][0] - U[0][0], t1 = U[1][1] - U[0][1], s2 = U[2][0] - U[0][0], t2 = U[2][1] - U[0][1];
        double area = s1 * t2 - s2 * t1, sign = area < 0 ? -1.0 : 1.0;
        /* the uv's orientation against the face's normals (its corners'),
         * not against its winding: a face wound against its normals keeps
         * the bitangent its neighbours have */
        double wound[3], navg[3] = {0, 0, 0};
        cross3(e1, e2, wound);
        for (int c = 0; c < 3; c++)
            for (int d = 0; d < 3; d++) navg[d] += out->normal[9 * (size_t)f + 3 * c + d];
        orient[f] = (area < 0) != (dot3(wound, navg) < 0) ? -1 : 1;
        double os[3];   /* d position / d u, up to a positive factor */
        for (int d = 0; d < 3; d++) os[d] = sign * (t2 * e1[d] - t1 * e2[d]);
        bool os_ok = area != 0 && normalize3(os);
        for (int c = 0; c < 3; c++) {
            size_t k = 3 * (size_t)f + c;
            const double *N = out->normal + 3 * k;
            /* the corner's angle, between its edges projected into N's plane */
            double a[3], b[3];
            for (int d = 0; d < 3; d++) a[d] = P[(c + 1) % 3][d] - P[c][d], b[d] = P[(c + 2) % 3][d] - P[c][d];
            double pa = dot3(a, N), pb = dot3(b, N);
            for (int d = 0; d < 3; d++) a[d] -= pa * N[d], b[d] -= pb * N[d];
            double angle = normalize3(a) && normalize3(b) ? acos(fmax(-1.0, fmin(1.0, dot3(a, b)))) : 0;
            double *T = face_t + 4 * k;
            double pt = dot3(os, N);
            for (int d = 0; d < 3; d++) T[d] = os[d] - pt * N[d];
            T[3] = os_ok && normalize3(T) ? angle : 0;
            keys[k] = (corner_key){m->FV[k], m->FU[k], 0, orient[f], (int32_t)k};
            memcpy(keys[k].n, N, sizeof keys[k].n);
        }
    }
    qsort(keys, nc, sizeof *keys, cmp_corner_key);
    for (size_t i = 0; i < nc;) {
        size_t j = i;
        while (j < nc && keys[j].v == keys[i].v && keys[j].u == keys[i].u && !memcmp(keys[j].n, keys[i].n, sizeof keys[i].n) &&
               keys[j].orient == keys[i].orient)
            j++;
        double sum[3] = {0, 0, 0};
        for (size_t t = i; t < j; t++) {
            const double *T = face_t + 4 * (size_t)keys[t].corner;
            for (int d = 0; d < 3; d++) sum[d] += T[3] * T[d];
        }
        for (size_t t = i; t < j; t++) {
            size_t k = (size_t)keys[t].corner;
            const double *N = out->normal + 3 * k;
            double *T = out->tangent + 4 * k;
            double p = dot3(sum, N);
            for (int d = 0; d < 3; d++) T[d] = sum[d] - p * N[d];
            if (!normalize3(T)) {   /* no uv to follow: any unit vector in N's plane */
                double axis[3] = {fabs(N[0]) < 0.9 ? 1 : 0, fabs(N[0]) < 0.9 ? 0 : 1, 0};
                cross3(N, axis, T);
                normalize3(T);
            }
            T[3] = orient[k / 3];
        }
        i = j;
    }
    free(face_t), free(orient), free(keys);
    return SC_OK;
}

void sc_tangent_frame_at(const sc_tangent_frames *f, int32_t face, const double b[3], double T[3], double B[3],
                         double N[3]) {
    const double *t = f->tangent + 12 * (size_t)face, *n = f->normal + 9 * (size_t)face;
    for (int d = 0; d < 3; d++) {
        T[d] = b[0] * t[d] + b[1] * t[4 + d] + b[2] * t[8 + d];
        N[d] = b[0] * n[d] + b[1] * n[3 + d] + b[2] * n[6 + d];
    }
    cross3(N, T, B);
    for (int d = 0; d < 3; d++) B[d] *= t[3];
}

/* ---------------------------------------------------------------- texels */

void sc_tangent_texels_free(sc_tangent_texels *t) {
    free(t->face), free(t->bary);
    *t = (sc_tangent_texels){0};
}

/* Whether triangle (x[k], y[k]) holds (px, py), and then its barycentrics. */
static bool triangle_holds(const double x[3], const double y[3], double px, double py, double b[3]) {
    double d = (y[1] - y[2]) * (x[0] - x[2]) + (x[2] - x[1]) * (y[0] - y[2]);
    if (d == 0) return false;
    double b0 = ((y[1] - y[2]) * (px - x[2]) + (x[2] - x[1]) * (py - y[2])) / d;
    double b1 = ((y[2] - y[0]) * (px - x[2]) + (x[0] - x[2]) * (py - y[2])) / d;
    double b2 = 1 - b0 - b1;
    if (!(b0 >= 0 && b1 >= 0 && b2 >= 0)) return false;
    b[0] = b0, b[1] = b1, b[2] = b2;
    return true;
}

/* The nearest point of triangle (x[k], y[k]) to (px, py): its barycentrics
 * and squared distance. */
static double nearest_on_triangle(const double x[3], const double y[3], double px, double py, double b[3]) {
    if (triangle_holds(x, y, px, py, b)) return 0;
    double best = INFINITY;
    for (int e = 0; e < 3; e++) {
        int i = e, j = (e + 1) % 3;
        double dx = x[j] - x[i], dy = y[j] - y[i], l2 = dx * dx + dy * dy;
        double s = l2 > 0 ? ((px - x[i]) * dx + (py - y[i]) * dy) / l2 : 0;
        s = s < 0 ? 0 : s > 1 ? 1 : s;
        double ex = x[i] + s * dx - px, ey = y[i] + s * dy - py, d2 = ex * ex + ey * ey;
        if (d2 < best) {
            best = d2;
            b[0] = b[1] = b[2] = 0;
            b[i] = 1 - s, b[j] = s;
        }
    }
    return best;
}

/* sc_tangent_texels_build's work, in bands of rows side by side: a band
 * takes every face in order for its own texels, so the result does not
 * depend on the split: first the texels each face holds (the first face
 * among those holding one), then the nearest face within the band of the
 * texels none holds (the first among equals), so a held texel skips the
 * distance to every other face. */
typedef struct texels_job {
    const sc_mesh *m;
    int32_t material;
    const sc_seam_grid *g;
    double band;
    sc_tangent_texels *out;
    float *dist;
} texels_job;

#define TEXELS_BAND_ROWS 64

/* Face f's texels in rows [row0, row1): those it holds (inside pass), or
 * those no face holds that it is the nearest to so far. */
static void texels_face(const texels_job *J, int32_t f, int32_t row0, int32_t row1, bool inside_pass) {
    const sc_mesh *m = J->m;
    const sc_seam_grid *g = J->g;
    sc_tangent_texels *out = J->out;
    const int32_t W = g->width, H = g->height;
    const double band = J->band;
    float *dist = J->dist;
    double x[3], y[3];
    for (int c = 0; c < 3; c++) {
        const double *U = m->U + 2 * (size_t)m->FU[3 * f + c];
        x[c] = U[0] * W - 0.5, y[c] = U[1] * H - 0.5;
    }
    double x0 = fmin(x[0], fmin(x[1], x[2])) - band, x1 = fmax(x[0], fmax(x[1], x[2])) + band;
    double y0 = fmin(y[0], fmin(y[1], y[2])) - band, y1 = fmax(y[0], fmax(y[1], y[2])) + band;
    if (!(x1 - x0 < 4.0 * W + 2 * band && y1 - y0 < 4.0 * H + 2 * band)) return;   /* uv far beyond the tile */
    const int64_t i0 = (int64_t)ceil(x0), i1 = (int64_t)floor(x1);
    const bool within = i0 >= 0 && i1 < W;   /* no column to wrap */
    for (int64_t j = (int64_t)ceil(y0); j <= (int64_t)floor(y1); j++) {
        int32_t jj = j >= 0 && j < H ? (int32_t)j : sc_seam_wrap(j, H, g->wrap_v);
        if (jj < row0 || jj >= row1) continue;
        for (int64_t i = i0; i <= i1; i++) {
            size_t id = (size_t)jj * W + (within ? (int32_t)i : sc_seam_wrap(i, W, g->wrap_u));
            double b[3] = {1, 0, 0}, d2 = 0;
            if (inside_pass) {
                if (dist[id] == 0 || !triangle_holds(x, y, (double)i, (double)j, b)) continue;   /* an earlier face's */
            } else if (dist[id] == 0) {
                continue;   /* held, or already at distance 0 */
            } else {
                d2 = nearest_on_triangle(x, y, (double)i, (double)j, b);
                if (d2 > band * band || !(d2 < dist[id])) continue;
            }
            dist[id] = (float)d2, out->face[id] = f;
            out->bary[2 * id] = (float)b[1], out->bary[2 * id + 1] = (float)b[2];
        }
    }
}

static int texels_band(void *ud, int32_t chunk) {
    const texels_job *J = ud;
    const sc_mesh *m = J->m;
    const int32_t W = J->g->width, H = J->g->height;
    const int32_t row0 = chunk * TEXELS_BAND_ROWS, row1 = row0 + TEXELS_BAND_ROWS < H ? row0 + TEXELS_BAND_ROWS : H;
    for (size_t i = (size_t)row0 * W; i < (size_t)row1 * W; i++) J->out->face[i] = -1, J->dist[i] = INFINITY;
    for (int pass = 0; pass < 2; pass++)
        for (int32_t f = 0; f < m->nf; f++)
            if (J->material < 0 || m->FM[f] == J->material) texels_face(J, f, row0, row1, pass == 0);
    return SC_OK;
}

int sc_tangent_texels_build(const sc_mesh *m, int32_t material, const sc_seam_grid *g, double band, int threads,
                            sc_tangent_texels *out, sc_error *err) {
    const int32_t W = g->width, H = g->height;
    size_t n = (size_t)W * H;
    *out = (sc_tangent_texels){W, H, sc_alloc_array(n, sizeof *out->face), sc_alloc_array(n * 2, sizeof *out->bary)};
    float *dist = sc_alloc_array(n, sizeof *dist);
    if (!out->face || !out->bary || !dist) {
        free(dist);
        sc_tangent_texels_free(out);
        return sc_fail(err, SC_ENOMEM, "tangent texels (%dx%d): out of memory", W, H);
    }
    texels_job J = {m, material, g, band, out, dist};
    int32_t chunks = (H + TEXELS_BAND_ROWS - 1) / TEXELS_BAND_ROWS;
    if (sc_parallel(threads, chunks, texels_band, &J) != SC_OK)
        for (int32_t c = 0; c < chunks; c++) texels_band(&J, c);
    free(dist);
    return SC_OK;
}

/* ---------------------------------------------------------------- maps */

bool sc_tangent_signed(const sc_image_data *img) {
    if (img->pixel != SC_PIXEL_F32 || img->channels < 3) return false;
    const float *p = img->pixels;
    size_t n = (size_t)img->width * img->height * img->channels;
    for (size_t i = 0; i < n; i++)
        if (p[i] < 0) return true;
    return false;
}

static void texel_frame(const sc_tangent_frames *f, const sc_tangent_texels *tx, size_t id, double M[3][3]) {
    double b[3] = {0, tx->bary[2 * id], tx->bary[2 * id + 1]};
    b[0] = 1 - b[1] - b[2];
    sc_tangent_frame_at(f, tx->face[id], b, M[0], M[1], M[2]);
}

/* A per-texel conversion between tangent and object space, in chunks of
 * texels on several threads (each texel depends on its own values alone). */
typedef struct frames_job {
    const sc_tangent_frames *f;
    const sc_tangent_texels *tx;
    const float *src;   /* from_object: the object-space field */
    float *dst;         /* the converted image, in place for to_object */
    int32_t C;
    size_t texels;
    bool is_signed;
} frames_job;

#define FRAMES_CHUNK ((size_t)1 << 16)

static int to_object_chunk(void *ud, int32_t chunk) {
    const frames_job *J = ud;
    size_t id0 = (size_t)chunk * FRAMES_CHUNK, id1 = id0 + FRAMES_CHUNK < J->texels ? id0 + FRAMES_CHUNK : J->texels;
    for (size_t id = id0; id < id1; id++) {
        float *px = J->dst + id * J->C;
        double t[3];
        for (int c = 0; c < 3; c++) t[c] = J->is_signed ? px[c] : 2.0 * px[c] - 1.0;
        double M[3][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
        if (J->tx->face[id] >= 0) texel_frame(J->f, J->tx, id, M);
        for (int d = 0; d < 3; d++) px[d] = (float)(t[0] * M[0][d] + t[1] * M[1][d] + t[2] * M[2][d]);
    }
    return SC_OK;
}

static int from_object_chunk(void *ud, int32_t chunk) {
    const frames_job *J = ud;
    size_t id0 = (size_t)chunk * FRAMES_CHUNK, id1 = id0 + FRAMES_CHUNK < J->texels ? id0 + FRAMES_CHUNK : J->texels;
    for (size_t id = id0; id < id1; id++) {
        const float *o = J->src + id * J->C;
        float *px = J->dst + id * J->C;
        double n[3] = {o[0], o[1], o[2]}, t[3] = {n[0], n[1], n[2]};
        if (J->tx->face[id] >= 0) {
            double M[3][3], c01[3], c12[3], c20[3];
            texel_frame(J->f, J->tx, id, M);   /* columns T, B, N: t = M^-1 n by Cramer's rule */
            cross3(M[1], M[2], c12), cross3(M[2], M[0], c20), cross3(M[0], M[1], c01);
            double det = dot3(M[0], c12);
            if (fabs(det) > 1e-12) t[0] = dot3(n, c12) / det, t[1] = dot3(n, c20) / det, t[2] = dot3(n, c01) / det;
        }
        double big = fmax(fabs(t[0]), fmax(fabs(t[1]), fabs(t[2])));
        double s = big > 1 ? 1 / big : 1;
        for (int c = 0; c < 3; c++) px[c] = (float)(J->is_signed ? s * t[c] : 0.5 * (s * t[c] + 1.0));
        for (int c = 3; c < J->C; c++) px[c] = o[c];
    }
    return SC_OK;
}

static void run_frames_job(frames_job *J, int threads, int (*fn)(void *, int32_t)) {
    int32_t chunks = (int32_t)((J->texels + FRAMES_CHUNK - 1) / FRAMES_CHUNK);
    if (sc_parallel(threads, chunks, fn, J) != SC_OK)
        for (int32_t c = 0; c < chunks; c++) fn(J, c);
}

sc_image_data *sc_tangent_to_object(const sc_image_data *img, const sc_tangent_frames *f,
                                    const sc_tangent_texels *tx, int threads) {
    if (img->channels < 3 || img->width != tx->width || img->height != tx->height) return NULL;
    bool is_signed = sc_tangent_signed(img);
    sc_image_data *o = sc_image_to_f32_threads(img, threads);
    if (!o) return NULL;
    o->colorspace = SC_COLOR_DATA;
    frames_job J = {f, tx, NULL, o->pixels, o->channels, (size_t)o->width * o->height, is_signed};
    run_frames_job(&J, threads, to_object_chunk);
    return o;
}

sc_image_data *sc_tangent_from_object(const sc_image_data *obj, const sc_image_data *like,
                                      const sc_tangent_frames *f, const sc_tangent_texels *tx, int threads) {
    if (obj->pixel != SC_PIXEL_F32 || obj->channels != like->channels || obj->width != like->width ||
        obj->height != like->height || obj->width != tx->width || obj->height != tx->height)
        return NULL;
    bool is_signed = sc_tangent_signed(like);
    sc_image_data *out = sc_image_to_f32_threads(like, threads);
    if (!out) return NULL;
    frames_job J = {f, tx, obj->pixels, out->pixels, out->channels, (size_t)out->width * out->height, is_signed};
    run_frames_job(&J, threads, from_object_chunk);
    return out;
}

/* ---------------------------------------------------------------- seam gap */

/* The corner of face f at surface vertex v, or -1. */
static int corner_of(const sc_mesh *m, int32_t f, int32_t v) {
    for (int c = 0; c < 3; c++)
        if (m->FV[3 * f + c] == v) return c;
    return -1;
}

/* sc_seam_sample on the image as stored: each tap read as sc_image_to_f32
 * would convert it (the same floats), without converting the whole map. */
static void sample_stored(const sc_seam_grid *g, const sc_image_data *img, int32_t channels, double u, double v,
                          double *out) {
    int32_t id[4];
    double w[4];
    sc_seam_taps(g, u, v, id, w);
    for (int32_t c = 0; c < channels; c++) {
        double s = 0;
        for (int k = 0; k < 4; k++) s += w[k] * sc_image_texel(img, id[k] % img->width, id[k] / img->width, c);
        out[c] = s;
    }
}

int sc_tangent_seam_gap(const sc_mesh *m, const sc_seam_set *seams, const sc_seam_grid *g,
                        const sc_tangent_frames *f, const sc_image_data *img, double *max_gap, double *mean_gap,
                        sc_error *err) {
    *max_gap = 0, *mean_gap = 0;
    if (img->channels < 3) return sc_fail(err, SC_EINPUT, "normal map: %d channels, 3 needed", img->channels);
    if (img->width != g->width || img->height != g->height)
        return sc_fail(err, SC_EINPUT, "normal map: %dx%d, its seam grid %dx%d", img->width, img->height, g->width,
                       g->height);
    bool is_signed = sc_tangent_signed(img);
    const int32_t channels = img->channels < 4 ? img->channels : 4;
    double sum = 0, length = 0;
    for (int32_t e = 0; e < seams->nseams; e++) {
        const sc_seam_edge *se = &seams->seams[e];
        int corner[2][2];
        double len_tex = 0;
        bool ok = true;
        for (int s = 0; s < 2; s++) {
            const sc_seam_side *sd = &se->side[s];
            corner[s][0] = corner_of(m, sd->face, se->v0), corner[s][1] = corner_of(m, sd->face, se->v1);
            ok &= corner[s][0] >= 0 && corner[s][1] >= 0;
            const double *a = m->U + 2 * (size_t)sd->uv0, *b = m->U + 2 * (size_t)sd->uv1;
            len_tex = fmax(len_tex, hypot((b[0] - a[0]) * g->width, (b[1] - a[1]) * g->height));
        }
        if (!ok) continue;
        int32_t samples = (int32_t)fmin(4096, ceil(2 * len_tex)) + 1;
        double edge_sum = 0;
        for (int32_t k = 0; k < samples; k++) {
            double gamma = (k + 0.5) / samples, n[2][3];
            for (int s = 0; s < 2; s++) {
                const sc_seam_side *sd = &se->side[s];
                const double *a = m->U + 2 * (size_t)sd->uv0, *b = m->U + 2 * (size_t)sd->uv1;
                double u = a[0] + gamma * (b[0] - a[0]), v = a[1] + gamma * (b[1] - a[1]), t[4] = {0, 0, 0, 0};
                sample_stored(g, img, channels, u, v, t);
                if (!is_signed)
                    for (int c = 0; c < 3; c++) t[c] = 2 * t[c] - 1;
                double bc[3] = {0, 0, 0}, T[3] = {1, 0, 0}, B[3] = {0, 1, 0}, N[3] = {0, 0, 1};
                bc[corner[s][0]] = 1 - gamma, bc[corner[s][1]] = gamma;
                if (f) sc_tangent_frame_at(f, sd->face, bc, T, B, N);
                for (int d = 0; d < 3; d++) n[s][d] = t[0] * T[d] + t[1] * B[d] + t[2] * N[d];
                normalize3(n[s]);
            }
            double dv[3] = {n[0][0] - n[1][0], n[0][1] - n[1][1], n[0][2] - n[1][2]};
            double gap = sqrt(dot3(dv, dv));
            if (gap > *max_gap) *max_gap = gap;
            edge_sum += gap;
        }
        sum += se->length * edge_sum / samples, length += se->length;
    }
    *mean_gap = length > 0 ? sum / length : 0;
    return SC_OK;
}
