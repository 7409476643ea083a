/* test_quad.c - the quad-chart atlas (sc_quad_build) checked from its
 * output alone: the mesh, its uv and the images of every level.
 *
 * The input is a closed sphere whose uv mirror its two halves onto one
 * chart (every covered texel is shared), so the old atlas could not be
 * erased or baked. Each check recomputes what it needs from the bytes:
 * bilinear samples on both sides of every seam at every level (with the
 * level's uv offset), chart footprints per level, uv components and their
 * Euler characteristic, and the surface point under each texel.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "sc_quad.h"
#include "sc_test.h"

/* A latitude-longitude sphere of radius 1 (rings x segments), welded; uv
 * (|longitude| / pi, latitude) so the two halves mirror onto one chart. */
static sc_mesh *mirrored_sphere(int rings, int segs) {
    int32_t nv = 2 + (rings - 1) * segs, nf = 2 * segs * (rings - 1);
    sc_mesh *m = sc_mesh_alloc(nv, nv, 0, nf, 1);
    if (!m) return NULL;
    m->materials[0] = strdup("m");
    for (int32_t v = 0; v < nv; v++) {
        double th, ph;
        if (v == 0) th = 0, ph = 0;
        else if (v == nv - 1) th = M_PI, ph = 0;
        else th = M_PI * ((v - 1) / segs + 1) / rings, ph = 2 * M_PI * ((v - 1) % segs) / segs - M_PI;
        m->V[3 * v] = sin(th) * cos(ph), m->V[3 * v + 1] = sin(th) * sin(ph), m->V[3 * v + 2] = cos(th);
        m->U[2 * v] = 0.05 + 0.9 * fabs(ph) / M_PI, m->U[2 * v + 1] = 0.05 + 0.9 * (1 - th / M_PI);
    }
    int32_t f = 0;
#define RING(r, s) (1 + (r) * segs + ((s) % segs))
    for (int s = 0; s < segs; s++) {
        int32_t t[3] = {0, RING(0, s), RING(0, s + 1)};
        memcpy(m->FV + 3 * f, t, sizeof t), memcpy(m->FU + 3 * f, t, sizeof t), f++;
        int32_t b[3] = {nv - 1, RING(rings - 2, s + 1), RING(rings - 2, s)};
        memcpy(m->FV + 3 * f, b, sizeof b), memcpy(m->FU + 3 * f, b, sizeof b), f++;
    }
    for (int r = 0; r + 1 < rings - 1; r++)
        for (int s = 0; s < segs; s++) {
            int32_t a = RING(r, s), b = RING(r, s + 1), c = RING(r + 1, s + 1), d = RING(r + 1, s);
            int32_t t1[3] = {a, d, c}, t2[3] = {a, c, b};
            memcpy(m->FV + 3 * f, t1, sizeof t1), memcpy(m->FU + 3 * f, t1, sizeof t1), f++;
            memcpy(m->FV + 3 * f, t2, sizeof t2), memcpy(m->FU + 3 * f, t2, sizeof t2), f++;
        }
#undef RING
    return m;
}

/* A smooth f32 data texture: value (sin 7u, cos 5v, uv) in [0, 1]. */
static sc_value *smooth_texture(int n) {
    sc_image_data *im = sc_image_alloc(n, n, 3, SC_PIXEL_F32);
    im->colorspace = SC_COLOR_DATA;
    float *p = im->pixels;
    for (int j = 0; j < n; j++)
        for (int i = 0; i < n; i++) {
            double u = (i + 0.5) / n, v = (j + 0.5) / n;
            p[3 * (j * n + i)] = (float)(0.5 + 0.5 * sin(7 * u));
            p[3 * (j * n + i) + 1] = (float)(0.5 + 0.5 * cos(5 * v));
            p[3 * (j * n + i) + 2] = (float)(u * v);
        }
    return sc_value_new_image(im);
}

typedef struct built {
    sc_mesh *in;
    sc_value *img;
    sc_texture tex;
    sc_quad_result r;
} built;

static void build(built *b, int supersample) {
    memset(b, 0, sizeof *b);
    b->in = mirrored_sphere(16, 32);
    b->img = smooth_texture(128);
    b->tex = (sc_texture){.name = "data", .material = 0, .wrap_u = SC_WRAP_CLAMP, .wrap_v = SC_WRAP_CLAMP,
                          .source = "", .image = b->img};
    sc_quad_options o;
    sc_quad_defaults(&o);
    o.texture_size = 512;
    o.supersample = supersample;
    o.psnr_samples = 0;
    sc_error err = {0};
    int rc = sc_quad_build(b->in, &b->tex, 1, &o, 2, &b->r, &err);
    SC_CHECK_MSG(rc == SC_OK, "sc_quad_build: %s", err.message);
}

static void built_free(built *b) {
    sc_quad_result_free(&b->r);
    sc_mesh_free(b->in);
    sc_value_release(b->img);
}

static double metric(const sc_quad_result *r, const char *name) {
    for (int32_t i = 0; i < r->metrics.count; i++)
        if (strcmp(r->metrics.items[i].name, name) == 0) return r->metrics.items[i].value;
    return NAN;
}

/* Plain bilinear sampling, texel centres at (i + 1/2) / W, clamped. */
static void bilinear(const sc_image_data *im, double u, double v, double out[3]) {
    double x = u * im->width - 0.5, y = v * im->height - 0.5;
    int i0 = (int)floor(x), j0 = (int)floor(y);
    double ax = x - i0, ay = y - j0;
    for (int c = 0; c < 3; c++) out[c] = 0;
    for (int b = 0; b < 2; b++)
        for (int a = 0; a < 2; a++) {
            int i = i0 + a, j = j0 + b;
            i = i < 0 ? 0 : i >= im->width ? im->width - 1 : i;
            j = j < 0 ? 0 : j >= im->height ? im->height - 1 : j;
            double w = (a ? ax : 1 - ax) * (b ? ay : 1 - ay);
            for (int c = 0; c < 3; c++) out[c] += w * ((const float *)im->pixels)[3 * ((size_t)j * im->width + i) + c];
        }
}

typedef struct half {
    int32_t lo, hi, f, k;
} half;

static int cmp_half(const void *x, const void *y) {
    const half *a = x, *b = y;
    if (a->lo != b->lo) return a->lo < b->lo ? -1 : 1;
    return a->hi < b->hi ? -1 : a->hi > b->hi;
}

/* Every seam (an edge whose two faces use different uv), sampled at 17
 * points from both sides at every level: the values must agree. */
SC_TEST(seam_free_at_every_level_without_erasing) {
    built b;
    build(&b, 2);
    const sc_mesh *m = b.r.mesh;
    SC_CHECK(b.r.nlevels >= 3);
    SC_CHECK(metric(&b.r, "flipped_triangles") == 0);
    half *h = malloc((size_t)m->nf * 3 * sizeof *h);
    for (int32_t f = 0; f < m->nf; f++)
        for (int k = 0; k < 3; k++) {
            int32_t a = m->FV[3 * f + k], c = m->FV[3 * f + (k + 1) % 3];
            h[3 * f + k] = (half){a < c ? a : c, a < c ? c : a, f, k};
        }
    qsort(h, (size_t)m->nf * 3, sizeof *h, cmp_half);
    int64_t seams = 0;
    double worst = 0;
    for (int32_t L = 0; L < b.r.nlevels; L++) {
        const sc_image_data *im = b.r.textures[0].levels[L];
        SC_CHECK(im->width == b.r.width >> L && im->height == b.r.height >> L);
        double du = ((1 << L) - 1) * 0.5 / b.r.width, dv = ((1 << L) - 1) * 0.5 / b.r.height;
        for (int32_t i = 0; i + 1 < m->nf * 3; i++) {
            if (h[i].lo != h[i + 1].lo || h[i].hi != h[i + 1].hi) continue;
            const half *p = &h[i], *q = &h[i + 1];
            int32_t pa = m->FV[3 * p->f + p->k], pu0 = m->FU[3 * p->f + p->k], pu1 = m->FU[3 * p->f + (p->k + 1) % 3];
            int32_t qa = m->FV[3 * q->f + q->k], qu0 = m->FU[3 * q->f + q->k], qu1 = m->FU[3 * q->f + (q->k + 1) % 3];
            if (qa != pa) { int32_t t = qu0; qu0 = qu1, qu1 = t; }
            if (pu0 == qu0 && pu1 == qu1) continue;
            seams += L == 0;
            for (int s = 0; s <= 16; s++) {
                double t = s / 16.0, x[3], y[3];
                const double *a0 = m->U + 2 * pu0, *a1 = m->U + 2 * pu1, *b0 = m->U + 2 * qu0, *b1 = m->U + 2 * qu1;
                bilinear(im, a0[0] + t * (a1[0] - a0[0]) + du, a0[1] + t * (a1[1] - a0[1]) + dv, x);
                bilinear(im, b0[0] + t * (b1[0] - b0[0]) + du, b0[1] + t * (b1[1] - b0[1]) + dv, y);
                for (int c = 0; c < 3; c++) worst = fmax(worst, fabs(x[c] - y[c]));
            }
        }
    }
    SC_CHECK_MSG(seams > 100, "only %lld seam edges", (long long)seams);
    SC_CHECK_MSG(worst <= 1e-6, "values differ across a seam by %g", worst);
    free(h);
    built_free(&b);
}

/* The uv components of m as a forest: comp[i] == i at each root (the
 * caller frees it). */
static int32_t *uv_components(const sc_mesh *m) {
    int32_t *comp = malloc((size_t)m->nu * sizeof *comp);
    for (int32_t i = 0; i < m->nu; i++) comp[i] = i;
    for (int32_t f = 0; f < m->nf; f++)
        for (int k = 1; k < 3; k++) {
            int32_t x = m->FU[3 * f], y = m->FU[3 * f + k];
            while (comp[x] != x) x = comp[x];
            while (comp[y] != y) y = comp[y];
            if (x != y) comp[x] = y;
        }
    return comp;
}

/* Each chart is one uv component, a disc (V - E + F = 1), inside its own
 * square block; no texel lies in the bilinear footprint of two charts at
 * any level. */
SC_TEST(charts_are_discs_in_blocks_that_never_share_a_texel) {
    built b;
    build(&b, 1);
    const sc_mesh *m = b.r.mesh;
    int32_t *comp = uv_components(m);
    int32_t charts = 0;
    for (int32_t i = 0; i < m->nu; i++) charts += comp[i] == i;
    SC_CHECK_MSG(charts == (int32_t)metric(&b.r, "quads"), "%d uv components, %g quads", charts, metric(&b.r, "quads"));
    /* quads per n-gon: n quads from each n-sided patch */
    int64_t from_patches = 0;
    const char *names[] = {"patches_3_sided", "patches_4_sided", "patches_5_sided", "patches_6_sided",
                           "patches_7_sided", "patches_8_sided", "patches_9_sided", "patches_10_sided"};
    for (int n = 3; n <= 10; n++) from_patches += (int64_t)n * (int64_t)metric(&b.r, names[n - 3]);
    SC_CHECK(metric(&b.r, "patches_11plus_sided") == 0);
    SC_CHECK(from_patches == charts);
    /* Euler characteristic of every chart (its faces, their uv vertices and uv edges) */
    for (int32_t c = 0; c < m->nu; c++) {
        if (comp[c] != c) continue;
        int64_t F = 0, V = 0, E2 = 0;
        for (int32_t f = 0; f < m->nf; f++) {
            int32_t r = m->FU[3 * f];
            while (comp[r] != r) r = comp[r];
            if (r == c) F++;
        }
        for (int32_t i = 0; i < m->nu; i++) {
            int32_t r = i;
            while (comp[r] != r) r = comp[r];
            V += r == c;
        }
        /* uv edges: interior ones are seen twice, border ones once: E = (3F + border) / 2 */
        int64_t border = 0;
        for (int32_t f = 0; f < m->nf; f++) {
            int32_t r = m->FU[3 * f];
            while (comp[r] != r) r = comp[r];
            if (r != c) continue;
            for (int k = 0; k < 3; k++) {
                int32_t a = m->FU[3 * f + k], bb = m->FU[3 * f + (k + 1) % 3], twin = 0;
                for (int32_t g = 0; g < m->nf && !twin; g++)
                    for (int j = 0; j < 3; j++)
                        if (m->FU[3 * g + j] == bb && m->FU[3 * g + (j + 1) % 3] == a) twin = 1;
                border += !twin;
            }
        }
        E2 = 3 * F + border;
        SC_CHECK_MSG(E2 % 2 == 0 && V - E2 / 2 + F == 1, "chart of uv %d: V %lld E %lld F %lld", c, (long long)V,
                     (long long)(E2 / 2), (long long)F);
        if (c > 40) break;   /* a sample of charts keeps the quadratic twin search short */
    }
    /* footprints per level */
    for (int32_t L = 0; L < b.r.nlevels; L++) {
        int32_t W = b.r.width >> L, H = b.r.height >> L;
        int32_t *owner = malloc((size_t)W * H * sizeof *owner);
        for (int32_t i = 0; i < W * H; i++) owner[i] = -1;
        double du = ((1 << L) - 1) * 0.5 / b.r.width, dv = ((1 << L) - 1) * 0.5 / b.r.height;
        int64_t shared = 0;
        for (int32_t f = 0; f < m->nf; f++) {
            int32_t r = m->FU[3 * f];
            while (comp[r] != r) r = comp[r];
            for (int k = 0; k < 3; k++) {
                const double *uv = m->U + 2 * m->FU[3 * f + k];
                double x = (uv[0] + du) * W - 0.5, y = (uv[1] + dv) * H - 0.5;
                /* the taps of non-zero weight: one texel when the point is on its centre */
                int32_t i0 = (int32_t)floor(x + 1e-9), i1 = (int32_t)ceil(x - 1e-9);
                int32_t j0 = (int32_t)floor(y + 1e-9), j1 = (int32_t)ceil(y - 1e-9);
                for (int32_t j = j0; j <= j1; j++)
                    for (int32_t i = i0; i <= i1; i++) {
                        if (i < 0 || j < 0 || i >= W || j >= H) continue;
                        int32_t *o = owner + (size_t)j * W + i;
                        if (*o == -1) *o = r;
                        else if (*o != r) shared++;
                    }
            }
        }
        SC_CHECK_MSG(shared == 0, "level %d: %lld texels reached by two charts", L, (long long)shared);
        free(owner);
    }
    free(comp);
    built_free(&b);
}

/* With whole_texture, the uv are in units of texture_size, so a map of that
 * size holds every chart's border samples on its texel centres; and each
 * chart keeps the ring of texels just beyond its border to itself, which a
 * GPU's float32 uv weight a little. Both read from the mesh's uv alone. */
SC_TEST(borders_on_texel_centres_and_a_ring_per_chart) {
    built b;
    memset(&b, 0, sizeof b);
    b.in = mirrored_sphere(16, 32);
    sc_quad_options o;
    sc_quad_defaults(&o);
    o.texture_size = 512;
    o.supersample = 1;
    o.psnr_samples = 0;
    o.min_size = 256;   /* two levels: cells of 2^k + 2^1 would leave one texel between charts */
    o.whole_texture = true;
    sc_error err = {0};
    int rc = sc_quad_build(b.in, NULL, 0, &o, 2, &b.r, &err);
    SC_CHECK_MSG(rc == SC_OK, "sc_quad_build: %s", err.message);
    if (rc != SC_OK) return;
    SC_CHECK(b.r.width == 512 && b.r.height == 512);
    const sc_mesh *m = b.r.mesh;
    int32_t *comp = uv_components(m);
    /* each chart's box in texel coordinates: its ends on texel centres */
    double *box = malloc((size_t)m->nu * 4 * sizeof *box);
    for (int32_t i = 0; i < m->nu; i++)
        box[4 * i] = box[4 * i + 1] = INFINITY, box[4 * i + 2] = box[4 * i + 3] = -INFINITY;
    for (int32_t i = 0; i < m->nu; i++) {
        int32_t r = i;
        while (comp[r] != r) r = comp[r];
        double x = m->U[2 * i] * 512 - 0.5, y = m->U[2 * i + 1] * 512 - 0.5;
        box[4 * r] = fmin(box[4 * r], x), box[4 * r + 1] = fmin(box[4 * r + 1], y);
        box[4 * r + 2] = fmax(box[4 * r + 2], x), box[4 * r + 3] = fmax(box[4 * r + 3], y);
    }
    int32_t charts = 0, off_centre = 0, rings_met = 0;
    for (int32_t c = 0; c < m->nu; c++) {
        if (comp[c] != c) continue;
        charts++;
        for (int k = 0; k < 4; k++) off_centre += fabs(box[4 * c + k] - round(box[4 * c + k])) > 1e-9;
        for (int32_t d = 0; d < c; d++) {   /* samples and ring: one texel beyond the box */
            if (comp[d] != d) continue;
            bool apart = box[4 * c + 2] + 1 < box[4 * d] - 1 || box[4 * d + 2] + 1 < box[4 * c] - 1 ||
                         box[4 * c + 3] + 1 < box[4 * d + 1] - 1 || box[4 * d + 3] + 1 < box[4 * c + 1] - 1;
            rings_met += !apart;
        }
    }
    SC_CHECK(charts == (int32_t)metric(&b.r, "quads") && charts > 20);
    SC_CHECK_MSG(off_centre == 0, "%d chart box ends off texel centres", off_centre);
    SC_CHECK_MSG(rings_met == 0, "%d pairs of charts share a texel of their rings", rings_met);
    free(box), free(comp);
    built_free(&b);
}

/* Level 0 of a linear field on a flat square holds the field's value at
 * each texel's surface point (supersample 1: a point sample there). */
/* The unit square in the plane z = 0, n x n cells of two triangles, uv
 * 0.1 + 0.8 (x, y); with two materials, "left" for x < 1/2 and "right". */
static sc_mesh *plane(int n, int nmat) {
    sc_mesh *in = sc_mesh_alloc((n + 1) * (n + 1), (n + 1) * (n + 1), 0, 2 * n * n, nmat);
    in->materials[0] = strdup(nmat == 1 ? "m" : "left");
    if (nmat == 2) in->materials[1] = strdup("right");
    for (int j = 0; j <= n; j++)
        for (int i = 0; i <= n; i++) {
            int v = j * (n + 1) + i;
            in->V[3 * v] = (double)i / n, in->V[3 * v + 1] = (double)j / n, in->V[3 * v + 2] = 0;
            in->U[2 * v] = 0.1 + 0.8 * i / n, in->U[2 * v + 1] = 0.1 + 0.8 * j / n;
        }
    for (int j = 0, f = 0; j < n; j++)
        for (int i = 0; i < n; i++, f += 2) {
            int a = j * (n + 1) + i, b = a + 1, c = a + n + 2, d = a + n + 1;
            int t[6] = {a, b, c, a, c, d};
            for (int k = 0; k < 6; k++) in->FV[3 * f + k] = t[k], in->FU[3 * f + k] = t[k];
            in->FM[f] = in->FM[f + 1] = nmat == 2 && i >= n / 2 ? 1 : 0;
        }
    return in;
}

SC_TEST(linear_field_reproduced_at_level_zero) {
    int n = 12;
    sc_mesh *in = plane(n, 1);
    /* field value = u of the old atlas, stored linearly across a 256-wide image */
    sc_image_data *im = sc_image_alloc(256, 256, 3, SC_PIXEL_F32);
    im->colorspace = SC_COLOR_DATA;
    for (int j = 0; j < 256; j++)
        for (int i = 0; i < 256; i++)
            for (int c = 0; c < 3; c++) ((float *)im->pixels)[3 * (j * 256 + i) + c] = (float)(c == 0 ? (i + 0.5) / 256 : (j + 0.5) / 256);
    sc_value *img = sc_value_new_image(im);
    sc_texture tex = {.name = "data", .material = 0, .wrap_u = SC_WRAP_CLAMP, .wrap_v = SC_WRAP_CLAMP, .source = "", .image = img};
    sc_quad_options o;
    sc_quad_defaults(&o);
    o.texture_size = 256, o.supersample = 1, o.psnr_samples = 0;
    sc_quad_result r;
    sc_error err = {0};
    SC_CHECK_MSG(sc_quad_build(in, &tex, 1, &o, 1, &r, &err) == SC_OK, "%s", err.message);
    const sc_mesh *m = r.mesh;
    const sc_image_data *out = r.textures[0].levels[0];
    int64_t checked = 0;
    double worst = 0;
    for (int32_t f = 0; f < m->nf; f++) {
        double x[3], y[3];
        for (int k = 0; k < 3; k++) {
            const double *uv = m->U + 2 * m->FU[3 * f + k];
            x[k] = uv[0] * r.width - 0.5, y[k] = uv[1] * r.height - 0.5;
        }
        double area = (x[1] - x[0]) * (y[2] - y[0]) - (x[2] - x[0]) * (y[1] - y[0]);
        if (!(area > 0)) continue;
        for (int j = (int)floor(fmin(y[0], fmin(y[1], y[2]))); j <= (int)ceil(fmax(y[0], fmax(y[1], y[2]))); j++)
            for (int i = (int)floor(fmin(x[0], fmin(x[1], x[2]))); i <= (int)ceil(fmax(x[0], fmax(x[1], x[2]))); i++) {
                double l0 = ((x[1] - i) * (y[2] - j) - (x[2] - i) * (y[1] - j)) / area;
                double l1 = ((x[2] - i) * (y[0] - j) - (x[0] - i) * (y[2] - j)) / area, l2 = 1 - l0 - l1;
                if (l0 < 1e-6 || l1 < 1e-6 || l2 < 1e-6) continue;   /* strictly inside: one face */
                double px = 0;
                for (int k = 0; k < 3; k++) px += (k == 0 ? l0 : k == 1 ? l1 : l2) * m->V[3 * m->FV[3 * f + k]];
                double want = 0.1 + 0.8 * px;   /* old u at that surface point */
                double got = ((const float *)out->pixels)[3 * ((size_t)j * out->width + i)];
                worst = fmax(worst, fabs(got - want));
                checked++;
            }
    }
    SC_CHECK_MSG(checked > 1000, "only %lld texels checked", (long long)checked);
    SC_CHECK_MSG(worst < 1e-5, "level 0 misses the linear field by %g", worst);
    sc_quad_result_free(&r);
    sc_mesh_free(in);
    sc_value_release(img);
}

/* The total 3D length of m's seam edges (the two faces at an edge use
 * different uv indices at its ends), from the mesh alone. */
static double seam_length(const sc_mesh *m) {
    typedef struct { int32_t lo, hi, u0, u1; } edge;
    edge *e = malloc((size_t)m->nf * 3 * sizeof *e);
    int64_t n = 0;
    for (int32_t f = 0; f < m->nf; f++)
        for (int k = 0; k < 3; k++) {
            int32_t a = m->FV[3 * f + k], b = m->FV[3 * f + (k + 1) % 3];
            int32_t ua = m->FU[3 * f + k], ub = m->FU[3 * f + (k + 1) % 3];
            e[n++] = a < b ? (edge){a, b, ua, ub} : (edge){b, a, ub, ua};
        }
    double len = 0;
    for (int64_t i = 0; i < n; i++)   /* quadratic, but the meshes here are small */
        for (int64_t j = i + 1; j < n; j++)
            if (e[i].lo == e[j].lo && e[i].hi == e[j].hi && (e[i].u0 != e[j].u0 || e[i].u1 != e[j].u1)) {
                const double *p = m->V + 3 * e[i].lo, *q = m->V + 3 * e[i].hi;
                double dx = p[0] - q[0], dy = p[1] - q[1], dz = p[2] - q[2];
                len += sqrt(dx * dx + dy * dy + dz * dz);
            }
    free(e);
    return len;
}

/* §4.1's straightening: patch borders re-drawn as shorter edge paths give
 * shorter seams on the output mesh, and no more stretch, than the borders
 * the merging left. */
SC_TEST(straight_borders_shorten_the_seams) {
    sc_mesh *in = mirrored_sphere(16, 32);
    sc_value *img = smooth_texture(64);
    sc_texture tex = {.name = "data", .material = 0, .wrap_u = SC_WRAP_CLAMP, .wrap_v = SC_WRAP_CLAMP, .source = "",
                      .image = img};
    double length[2], stretch[2], straightened[2];
    for (int on = 0; on < 2; on++) {
        sc_quad_options o;
        sc_quad_defaults(&o);
        o.texture_size = 512, o.psnr_samples = 0, o.straight_borders = on, o.target_patches = 24;
        sc_quad_result r;
        sc_error err = {0};
        int rc = sc_quad_build(in, &tex, 1, &o, 2, &r, &err);
        SC_CHECK_MSG(rc == SC_OK, "%s", err.message);
        if (rc) break;
        length[on] = seam_length(r.mesh);
        stretch[on] = metric(&r, "stretch_l2");
        straightened[on] = metric(&r, "patch_borders_straightened");
        SC_CHECK(metric(&r, "boundary_mismatch") == 0 && metric(&r, "shared_texels") == 0);
        sc_quad_result_free(&r);
    }
    SC_CHECK_MSG(straightened[0] == 0 && straightened[1] > 0, "borders straightened: %g off, %g on", straightened[0],
                 straightened[1]);
    SC_CHECK_MSG(length[1] < 0.99 * length[0], "seams %g with straight borders, %g without", length[1], length[0]);
    SC_CHECK_MSG(stretch[1] <= stretch[0], "stretch %g with straight borders, %g without", stretch[1], stretch[0]);
    sc_mesh_free(in);
    sc_value_release(img);
}

/* Two materials on one plane (x < 1/2 and x > 1/2) with one uniform colour
 * texture: their colour factors differ, so each texel strictly inside a
 * face holds the texture times its own material's factor, and the one
 * material left has factor 1; metallic agrees and is kept; roughness
 * differs with no metallic-roughness map to take it (counted unbaked); the
 * alpha mode is the more transparent (BLEND over MASK), double-sided as
 * one of them is. */
SC_TEST(material_constants_merged_and_baked) {
    sc_mesh *in = plane(8, 2);
    sc_image_data *im = sc_image_alloc(64, 64, 4, SC_PIXEL_F32);
    im->colorspace = SC_COLOR_LINEAR;
    for (int64_t i = 0; i < 64 * 64 * 4; i++) ((float *)im->pixels)[i] = (i % 4) == 3 ? 1.0f : 0.8f;
    sc_value *img = sc_value_new_image(im);
    sc_texture tex[2];
    for (int k = 0; k < 2; k++)
        tex[k] = (sc_texture){.name = "color", .material = k, .wrap_u = SC_WRAP_CLAMP, .wrap_v = SC_WRAP_CLAMP,
                              .source = "", .image = img};
    sc_material c[2] = {sc_material_default(), sc_material_default()};
    c[0].base_color[0] = 0.5, c[1].base_color[1] = 0.25, c[1].base_color[3] = 0.5;
    c[0].metallic = c[1].metallic = 0.7;
    c[0].roughness = 0.2, c[1].roughness = 0.9;
    c[0].alpha_mode = SC_ALPHA_MASK, c[0].alpha_cutoff = 0.3, c[1].alpha_mode = SC_ALPHA_BLEND;
    c[1].double_sided = true;
    sc_quad_options o;
    sc_quad_defaults(&o);
    o.texture_size = 256, o.supersample = 1, o.psnr_samples = 0, o.constants = c;
    sc_quad_result r;
    sc_error err = {0};
    int rc = sc_quad_build(in, tex, 2, &o, 1, &r, &err);
    SC_CHECK_MSG(rc == SC_OK, "%s", err.message);
    if (rc == SC_OK) {
        SC_CHECK(r.has_constants);
        for (int k = 0; k < 4; k++) SC_CHECK(r.constants.base_color[k] == 1);
        SC_CHECK(r.constants.metallic == 0.7 && r.constants.roughness == 0.2);
        SC_CHECK(r.constants.alpha_mode == SC_ALPHA_BLEND && r.constants.double_sided);
        SC_CHECK(metric(&r, "material_constants_unbaked") == 1);
        const sc_mesh *m = r.mesh;
        const sc_image_data *out = r.textures[0].levels[0];
        int64_t checked = 0;
        double worst = 0;
        for (int32_t f = 0; f < m->nf; f++) {
            double x[3], y[3], cx = 0;
            for (int k = 0; k < 3; k++) {
                const double *uv = m->U + 2 * m->FU[3 * f + k];
                x[k] = uv[0] * r.width - 0.5, y[k] = uv[1] * r.height - 0.5;
                cx += m->V[3 * m->FV[3 * f + k]] / 3;
            }
            const double *want = cx < 0.5 ? c[0].base_color : c[1].base_color;
            double area = (x[1] - x[0]) * (y[2] - y[0]) - (x[2] - x[0]) * (y[1] - y[0]);
            if (!(area > 0)) continue;
            for (int j = (int)floor(fmin(y[0], fmin(y[1], y[2]))); j <= (int)ceil(fmax(y[0], fmax(y[1], y[2]))); j++)
                for (int i = (int)floor(fmin(x[0], fmin(x[1], x[2]))); i <= (int)ceil(fmax(x[0], fmax(x[1], x[2])));
                     i++) {
                    double l0 = ((x[1] - i) * (y[2] - j) - (x[2] - i) * (y[1] - j)) / area;
                    double l1 = ((x[2] - i) * (y[0] - j) - (x[0] - i) * (y[2] - j)) / area, l2 = 1 - l0 - l1;
                    if (l0 < 1e-6 || l1 < 1e-6 || l2 < 1e-6) continue;   /* strictly inside: one face */
                    const float *px = (const float *)out->pixels + 4 * ((size_t)j * out->width + i);
                    for (int k = 0; k < 4; k++) worst = fmax(worst, fabs(px[k] - (k == 3 ? 1.0 : 0.8) * want[k]));
                    checked++;
                }
        }
        SC_CHECK_MSG(checked > 1000, "only %lld texels checked", (long long)checked);
        SC_CHECK_MSG(worst < 1e-6, "texels miss their material's factor by %g", worst);
        sc_quad_result_free(&r);
    }
    /* constants they agree on stay constants: the texels keep the texture's values */
    c[1] = c[0];
    rc = sc_quad_build(in, tex, 2, &o, 1, &r, &err);
    SC_CHECK_MSG(rc == SC_OK, "%s", err.message);
    if (rc == SC_OK) {
        SC_CHECK(r.constants.base_color[0] == 0.5 && metric(&r, "material_constants_unbaked") == 0);
        SC_CHECK(r.constants.alpha_mode == SC_ALPHA_MASK && r.constants.alpha_cutoff == 0.3 &&
                 !r.constants.double_sided);
        const float *px = (const float *)r.textures[0].levels[0]->pixels;
        float most = 0;   /* red: the texture's 0.8, not times the factor */
        for (int64_t i = 0; i < (int64_t)r.width * r.height; i++) most = fmaxf(most, px[4 * i]);
        SC_CHECK_MSG(fabsf(most - 0.8f) < 1e-6, "largest red texel %g", most);
        sc_quad_result_free(&r);
    }
    sc_mesh_free(in);
    sc_value_release(img);
}

/* The quads are cut along the mesh's own edges where a path exists (the
 * paper's paths from each patch's centre to its sides' medians), so the
 * surface keeps nearly the faces it had: counted on the output mesh. */
SC_TEST(cuts_follow_mesh_edges) {
    built b;
    build(&b, 1);
    double grow = (double)b.r.mesh->nf / b.in->nf;
    SC_CHECK_MSG(grow <= 1.2, "faces grow %d -> %d (x%.3f)", b.in->nf, b.r.mesh->nf, grow);
    SC_CHECK_MSG(metric(&b.r, "patches_cut_straight") <= 0.1 * metric(&b.r, "patches"), "%g of %g patches cut straight",
                 metric(&b.r, "patches_cut_straight"), metric(&b.r, "patches"));
    built_free(&b);
}

int main(void) { return sc_test_main(); }
