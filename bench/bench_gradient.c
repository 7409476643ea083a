/* bench_gradient.c - the gradient_domain node on a corpus asset.
 *
 *   bench_gradient [-r RUNS] [ASSET] [--set name=value]...
 *
 * Loads the asset (blub by default: 14k faces, a 2048 x 2048 texture; from
 * ../shared/corpus or $SC_CORPUS), then runs gradient_domain (smooth, the
 * paper's beta 0 and screening 1e4, unless --set says otherwise) and prints
 * the unknowns, the boundary texels, the V-cycles and the residual after
 * each, the seam energy before and after, seconds and the process's peak
 * resident memory during the run. Each run is a child process of its own
 * (runs.h). `--set solver=direct` times one CHOLMOD factorisation instead.
 * `--peer FILE.png`: the texture is processed as stored (not in linear
 * light: the peer works on stored values) and the result compared with
 * FILE, the peer's output for the same asset and parameters, over the
 * texels solved for.
 *
 * Peer: the paper's reference code (TextureSignalProcessing); what it was
 * measured at, or why not, is in docs/notes/gradient_domain.md.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "sc_base.h"
#include "sc_exec.h"
#include "sc_imageio.h"
#include "sc_nodes.h"
#include "runs.h"

typedef struct run_args {
    const char *corpus, *model, *texture, *peer;
    int nsets;
    char **sets;
} run_args;

/* the atlas with its first texture as f32 data: processed as stored */
static sc_value *as_stored(sc_value *atlas) {
    const sc_atlas *a = atlas->as.atlas;
    sc_image_data *f = sc_image_to_f32(a->textures[0].image->as.image);
    f->colorspace = SC_COLOR_DATA;
    sc_atlas *o = sc_atlas_new(sc_value_retain(a->mesh));
    const sc_texture *t = &a->textures[0];
    sc_atlas_add_texture(o, t->name, t->material, t->wrap_u, t->wrap_v, t->source, sc_value_new_image(f));
    sc_value_release(atlas);
    return sc_value_new_atlas(o);
}

/* RMS and largest difference from the peer's result over the texels this
 * run changed, beside the input's own difference from the peer there */
static void compare_peer(const char *path, const sc_image_data *in, const sc_image_data *ours) {
    sc_buf b = {0};
    sc_error err = {0};
    sc_image_data *peer = NULL;
    if (sc_read_file(path, (size_t)1 << 30, &b, &err) != SC_OK || sc_image_decode(path, b.data, b.len, &peer, &err) != SC_OK) {
        printf("peer: %s\n", err.message);
        sc_buf_free(&b);
        return;
    }
    sc_buf_free(&b);
    if (peer->width != ours->width || peer->height != ours->height || peer->channels < ours->channels) {
        printf("peer: %dx%d x %d does not match\n", (int)peer->width, (int)peer->height, (int)peer->channels);
        sc_image_free(peer);
        return;
    }
    double s_ours = 0, s_in = 0, worst = 0;
    long n = 0;
    for (int32_t j = 0; j < ours->height; j++)
        for (int32_t i = 0; i < ours->width; i++) {
            bool changed = false;
            for (int32_t c = 0; c < ours->channels; c++) changed |= sc_image_texel(ours, i, j, c) != sc_image_texel(in, i, j, c);
            if (!changed) continue;
            for (int32_t c = 0; c < ours->channels; c++) {
                double p = sc_image_texel(peer, i, j, c), o = sc_image_texel(ours, i, j, c), x = sc_image_texel(in, i, j, c);
                s_ours += (o - p) * (o - p), s_in += (x - p) * (x - p), worst = fmax(worst, fabs(o - p));
                n++;
            }
        }
    printf("peer %s: over %ld changed texel channels, RMS difference %.4g (largest %.4g); the input's from the peer: %.4g\n",
           path, n, sqrt(s_ours / (double)n), worst, sqrt(s_in / (double)n));
    sc_image_free(peer);
}

static int run_once(void *ud, int out) {
    const run_args *ra = ud;
    char *model = sc_path_join(ra->corpus, ra->model), *tex = sc_path_join(ra->corpus, ra->texture);
    sc_error err = {0};
    sc_ctx *load = sc_ctx_new(&sc_node_load_atlas, NULL, NULL);
    sc_ctx_set_threads(load, 2);
    int rc = sc_ctx_set_param(load, "path", model, &err);
    if (rc == SC_OK) rc = sc_ctx_set_param(load, "texture", tex, &err);
    if (rc == SC_OK) rc = sc_ctx_run(load, &err);
    free(model), free(tex);
    if (rc != SC_OK) {
        printf("load failed: %s\n", err.message);
        sc_ctx_free(load);
        return 1;
    }
    sc_value *atlas = sc_value_retain(sc_ctx_output(load, 0));
    sc_ctx_free(load);
    if (ra->peer) atlas = as_stored(atlas);
    sc_value *inputs[] = {atlas, NULL}; /* atlas, labels */
    sc_ctx *ctx = sc_ctx_new(&sc_node_gradient_domain, NULL, inputs);
    sc_ctx_set_threads(ctx, 2);
    for (int i = 0; i < ra->nsets && rc == SC_OK; i++) {
        char *eq = strchr(ra->sets[i], '=');
        if (!eq) continue;
        *eq = 0;
        rc = sc_ctx_set_param(ctx, ra->sets[i], eq + 1, &err);
        *eq = '=';
    }
    double rss0 = bench_resident_mb();
    bench_reset_peak();
    double t0 = sc_now();
    if (rc == SC_OK) rc = sc_ctx_run(ctx, &err);
    double secs = sc_now() - t0, peak = bench_peak_mb();
    if (rc != SC_OK) {
        printf("gradient_domain failed: %s\n", err.message);
    } else {
        const sc_image_data *im = sc_ctx_output(ctx, 1)->as.image;
        printf("%dx%d texels, %.0f unknowns; %.2f s, peak %.0f MB (+%.0f MB during the run)\n", im->width,
               im->height, sc_ctx_metric_value(ctx, "unknowns"), secs, peak, peak - rss0);
        for (int i = 0; i < sc_ctx_nmetrics(ctx); i++) {
            const sc_metric *mt = &sc_ctx_metrics(ctx)[i];
            if (strcmp(mt->name, "unknowns") != 0) printf("  %-32s %.4g\n", mt->name, mt->value);
        }
        if (ra->peer) compare_peer(ra->peer, atlas->as.atlas->textures[0].image->as.image, im);
        if (bench_report_seconds(out, secs) != 0) rc = SC_EINPUT;
    }
    fflush(stdout);
    sc_ctx_free(ctx);
    sc_value_release(atlas);
    return rc != SC_OK;
}

int main(int argc, char **argv) {
    sc_tune_allocator();
    int runs = 1, nsets = 0;
    char *sets[64];
    const char *name = "blub", *peer = NULL;
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "-r") && i + 1 < argc) runs = atoi(argv[++i]);
        else if (!strcmp(argv[i], "--peer") && i + 1 < argc) peer = argv[++i];
        else if (!strcmp(argv[i], "--set") && i + 1 < argc && nsets < 64) sets[nsets++] = argv[++i];
        else name = argv[i];
    }
    const char *env = getenv("SC_CORPUS");
    char *corpus = env && *env ? sc_strdup(env) : sc_path_join(SC_SOURCE_DIR, "../shared/corpus");
    if (access(corpus, R_OK) != 0) {
        printf("bench_gradient: corpus not found at %s (set SC_CORPUS): nothing measured\n", corpus);
        free(corpus);
        return 0;
    }
    char model[256], texture[256];
    if (!strcmp(name, "spot")) {
        snprintf(model, sizeof model, "spot/spot_triangulated.obj");
        snprintf(texture, sizeof texture, "spot/spot_texture.png");
    } else {
        snprintf(model, sizeof model, "%s/%s.obj", name, name);
        snprintf(texture, sizeof texture, "%s/%s_texture.png", name, name);
    }
    if (runs < 1 || runs > 100) runs = 1;
    printf("gradient_domain on %s, %d run%s", name, runs, runs > 1 ? "s" : "");
    for (int i = 0; i < nsets; i++) printf(", %s", sets[i]);
    printf("\n");
    double secs[100];
    int done = 0, failed = 0;
    for (int r = 0; r < runs; r++) {
        run_args ra = {corpus, model, texture, peer, nsets, sets};
        if (bench_in_child(run_once, &ra, &secs[done]) == 0) done++;
        else failed++;
    }
    bench_summary(name, "total", secs, done, 0);
    free(corpus);
    return failed ? 1 : 0;
}
