/* test_gradient.c - the node `gradient_domain` and its kernel (sc_gradient).
 *
 * The asset is the procedural cube sphere with no bumps (a unit sphere, six
 * charts, every cube edge a seam), carrying a float texture painted here
 * from a function of the surface point. What the tests know independently:
 * the surface point of every texel centre (found here by point-in-triangle
 * in uv and barycentric interpolation), the sphere's area, great-circle
 * distances, and a direct CHOLMOD solve of the same system (solver=direct)
 * to hold the multigrid solution against.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "sc_exec.h"
#include "sc_nodes.h"
#include "sc_test.h"

/* ================================================================ the asset */

static sc_value *sphere_atlas(int resolution, int size) {
    char res[16], sz[16];
    snprintf(res, sizeof res, "%d", resolution);
    snprintf(sz, sizeof sz, "%d", size);
    const char *p[] = {"resolution", res, "texture_size", sz, "bumpiness", "0", "chart_tint", "0", NULL};
    sc_test_run r = sc_test_run_node(&sc_node_procedural, p, NULL, NULL, NULL, NULL);
    SC_CHECK_MSG(r.rc == SC_OK, "procedural: %s", r.err.message);
    sc_value *v = r.rc == SC_OK ? sc_value_retain(sc_ctx_output(r.ctx, 0)) : NULL;
    sc_ctx_free(r.ctx);
    return v;
}

/* The surface point at every texel centre inside a uv triangle (NAN
 * elsewhere): pos[3 * (j * W + i)]. */
static double *texel_points(const sc_mesh *m, int W, int H) {
    double *pos = malloc(sizeof(double) * 3 * (size_t)W * H);
    for (size_t k = 0; k < 3 * (size_t)W * H; k++) pos[k] = NAN;
    for (int f = 0; f < m->nf; f++) {
        double x[3], y[3];
        for (int k = 0; k < 3; k++) x[k] = m->U[2 * m->FU[3 * f + k]] * W - 0.5, y[k] = m->U[2 * m->FU[3 * f + k] + 1] * H - 0.5;
        double det = (x[1] - x[0]) * (y[2] - y[0]) - (x[2] - x[0]) * (y[1] - y[0]);
        int i0 = (int)floor(fmin(x[0], fmin(x[1], x[2]))), i1 = (int)ceil(fmax(x[0], fmax(x[1], x[2])));
        int j0 = (int)floor(fmin(y[0], fmin(y[1], y[2]))), j1 = (int)ceil(fmax(y[0], fmax(y[1], y[2])));
        for (int j = j0 < 0 ? 0 : j0; j <= j1 && j < H; j++)
            for (int i = i0 < 0 ? 0 : i0; i <= i1 && i < W; i++) {
                double b1 = ((i - x[0]) * (y[2] - y[0]) - (x[2] - x[0]) * (j - y[0])) / det;
                double b2 = ((x[1] - x[0]) * (j - y[0]) - (i - x[0]) * (y[1] - y[0])) / det, b0 = 1 - b1 - b2;
                if (b0 < -1e-12 || b1 < -1e-12 || b2 < -1e-12) continue;
                for (int c = 0; c < 3; c++)
                    pos[3 * ((size_t)j * W + i) + c] = b0 * m->V[3 * m->FV[3 * f] + c] + b1 * m->V[3 * m->FV[3 * f + 1] + c] +
                                                       b2 * m->V[3 * m->FV[3 * f + 2] + c];
            }
    }
    return pos;
}

/* the surface point of texel (i, j), or of its nearest covered neighbour within 3 texels */
static const double *near_point(const double *pos, int W, int H, int i, int j) {
    for (int r = 0; r <= 3; r++)
        for (int dj = -r; dj <= r; dj++)
            for (int di = -r; di <= r; di++) {
                int a = i + di, b = j + dj;
                if (a < 0 || b < 0 || a >= W || b >= H) continue;
                const double *p = &pos[3 * ((size_t)b * W + a)];
                if (!isnan(p[0])) return p;
            }
    return NULL;
}

typedef double (*field_fn)(const double p[3], int c);

static double smooth_field(const double p[3], int c) {
    return 0.5 + 0.3 * sin(3 * p[0] + c) * cos(2 * p[1]) + 0.1 * p[2] + 0.05 * sin(17 * p[2] + 3 * p[0]);
}

/* The atlas with its colour texture replaced by an f32 data texture of
 * `channels` channels painted from fn at the surface point of each texel
 * (outside the charts: the nearest covered texel's point, else 0). */
static sc_value *painted(const sc_value *atlas, int channels, field_fn fn, double offset_x_positive) {
    const sc_atlas *a = atlas->as.atlas;
    const sc_image_data *t = a->textures[0].image->as.image;
    int W = t->width, H = t->height;
    double *pos = texel_points(a->mesh->as.mesh, W, H);
    sc_image_data *im = sc_image_alloc(W, H, channels, SC_PIXEL_F32);
    im->colorspace = SC_COLOR_DATA;
    float *px = im->pixels;
    for (int j = 0; j < H; j++)
        for (int i = 0; i < W; i++) {
            const double *p = near_point(pos, W, H, i, j);
            for (int c = 0; c < channels; c++)
                px[((size_t)j * W + i) * channels + c] =
                    p ? (float)(fn(p, c) + (p[0] > 0 ? offset_x_positive : 0)) : 0.0f;
        }
    free(pos);
    sc_atlas *o = sc_atlas_new(sc_value_retain(a->mesh));
    sc_atlas_add_texture(o, "color", 0, SC_WRAP_REPEAT, SC_WRAP_REPEAT, "", sc_value_new_image(im));
    return sc_value_new_atlas(o);
}

/* run gradient_domain; the image output (a new reference) and the ctx for metrics */
static sc_value *run_gradient(const sc_value *atlas, const sc_value *labels, const char *const *params, sc_ctx **ctx) {
    sc_test_run r = sc_test_run_node(&sc_node_gradient_domain, params, "atlas", (sc_value *)atlas, labels ? "labels" : NULL,
                                     (sc_value *)labels);
    SC_CHECK_MSG(r.rc == SC_OK, "gradient_domain: %s", r.err.message);
    sc_value *img = r.rc == SC_OK ? sc_value_retain(sc_ctx_output(r.ctx, 1)) : NULL;
    if (ctx) *ctx = r.ctx;
    else sc_ctx_free(r.ctx);
    return img;
}

static double max_diff(const sc_image_data *a, const sc_image_data *b) {
    double d = 0;
    size_t n = (size_t)a->width * a->height * a->channels;
    for (size_t k = 0; k < n; k++) d = fmax(d, fabs(((const float *)a->pixels)[k] - ((const float *)b->pixels)[k]));
    return d;
}

/* ================================================================ tests */

SC_TEST(smooth_multigrid_matches_direct) {
    sc_value *sphere = sphere_atlas(12, 128);
    if (!sphere) return;
    sc_value *atlas = painted(sphere, 3, smooth_field, 0);
    const char *pd[] = {"operation", "smooth", "solver", "direct", NULL};
    const char *pm[] = {"operation", "smooth", "solver", "multigrid", NULL};
    sc_ctx *cd, *cm;
    sc_value *d = run_gradient(atlas, NULL, pd, &cd), *m = run_gradient(atlas, NULL, pm, &cm);
    if (d && m) {
        double diff = max_diff(d->as.image, m->as.image);
        double vc = sc_ctx_metric_value(cm, "smooth_vcycles");
        printf("  multigrid vs direct: max diff %.3g after %g V-cycles; area %.9f (4 pi = %.9f)\n", diff, vc,
               sc_ctx_metric_value(cm, "surface_area"), 4 * M_PI);
        for (int k = 1; k <= vc; k++) {
            char key[64];
            snprintf(key, sizeof key, "smooth_vcycle_%d_residual", k);
            printf("    V-cycle %d: relative residual %.3g\n", k, sc_ctx_metric_value(cm, key));
        }
        printf("  seam energy in %.3g out %.3g (ratio %.3g)\n", sc_ctx_metric_value(cm, "seam_energy_in"),
               sc_ctx_metric_value(cm, "seam_energy_out"), sc_ctx_metric_value(cm, "seam_energy_ratio"));
        SC_CHECK(diff < 1e-6);
        SC_CHECK(vc <= 5);
    }
    sc_ctx_free(cd), sc_ctx_free(cm);
    sc_value_release(d), sc_value_release(m), sc_value_release(atlas), sc_value_release(sphere);
}

int main(void) { return sc_test_main(); }
