/* bench_straighten.c - Figure 12 of Liu et al. 2017: the effect of the
 * straightening tolerance on seam-aware decimation.
 *
 * Usage: bench_straighten [-o PLOT.png] [asset ...]     (assets: blub, spot)
 *   The corpus is $SC_CORPUS, or ../shared/corpus next to the source tree.
 *
 * Per asset and tolerance (0, 0.001, 0.01, 0.1): straighten the atlas (the
 * node `straighten`, erase off: decimation reads the mesh only), then run
 * `decimate` (seam_mode aware, no Hausdorff sampling, uv_precision 0) with a ladder of
 * face targets from 90% of the input down to 300 faces, and read its per-level
 * metrics lod<k>.faces and lod<k>.quadric_cost (the summed quadric error of
 * the level: the cost accumulated by its collapses). Printed: seconds of each
 * step, the collapsible seam edges before and after straightening (the
 * straighten node's census), decimate's uncollapsible seam edges of its input,
 * and the accumulated cost at a few face counts. The plot (PNG, one panel per
 * asset, x = faces on a log scale decreasing to the right, y = accumulated
 * cost on a log scale) draws one line per tolerance: 0 black, 0.001 blue,
 * 0.01 red, 0.1 green.
 *
 * uv_precision 0: decimate otherwise widens its collinearity and ratio tests
 * by the storage step it detects in the input's uv (OBJ text: 1e-5 on spot),
 * which passes nearly every seam of a 6-digit OBJ as unifiable while the
 * straightened uv (full doubles) is judged exactly; with 0 every tolerance is
 * judged by the same exact test, as in the paper.
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

typedef struct asset {
    const char *name, *model, *texture;
} asset;

static const asset assets[] = {
    {"blub", "blub/blub.obj", "blub/blub_texture.png"},
    {"spot", "spot/spot_triangulated.obj", "spot/spot_texture.png"},
};
#define NASSETS ((int)(sizeof assets / sizeof assets[0]))

static const char *const tolerances[] = {"0", "0.001", "0.01", "0.1"};
#define NTOL 4
static const float colours[NTOL][3] = {{0, 0, 0}, {0.1f, 0.3f, 0.9f}, {0.9f, 0.1f, 0.1f}, {0.1f, 0.65f, 0.2f}};

#define MIN_FACES 300
#define MAX_LEVELS 64

typedef struct curve {
    int n;
    double faces[MAX_LEVELS], cost[MAX_LEVELS];
} curve;

static sc_ctx *run(const sc_node_desc *d, const char *const *kv, const char *port, sc_value *in, sc_error *err) {
    sc_ctx *ctx = sc_ctx_new(d, NULL, NULL);
    for (int i = 0; kv && kv[i]; i += 2)
        if (sc_ctx_set_param(ctx, kv[i], kv[i + 1], err) != SC_OK) {
            sc_ctx_free(ctx);
            return NULL;
        }
    if (port) sc_ctx_set_input(ctx, port, in);
    sc_ctx_set_threads(ctx, 2);
    if (sc_ctx_run(ctx, err) != SC_OK) {
        sc_ctx_free(ctx);
        return NULL;
    }
    return ctx;
}

/* ---------------------------------------------------------------- plotting */

typedef struct canvas {
    sc_image_data *im;
    int x0, y0, w, h;   /* the panel, in pixels (y up) */
    double fmin, fmax, cmin, cmax;
} canvas;

static void put(sc_image_data *im, int x, int y, const float *rgb) {
    if (x < 0 || y < 0 || x >= im->width || y >= im->height) return;
    float *p = (float *)im->pixels + 3 * ((size_t)y * im->width + x);
    p[0] = rgb[0], p[1] = rgb[1], p[2] = rgb[2];
}

static void line(sc_image_data *im, double xa, double ya, double xb, double yb, const float *rgb, int thick) {
    int steps = (int)(fmax(fabs(xb - xa), fabs(yb - ya))) + 1;
    for (int i = 0; i <= steps; i++) {
        double t = (double)i / steps, x = xa + t * (xb - xa), y = ya + t * (yb - ya);
        for (int dx = -thick / 2; dx <= thick / 2; dx++)
            for (int dy = -thick / 2; dy <= thick / 2; dy++) put(im, (int)lround(x) + dx, (int)lround(y) + dy, rgb);
    }
}

/* faces decrease to the right on a log axis; cost up on a log axis */
static double px_x(const canvas *c, double faces) {
    return c->x0 + c->w * (log(c->fmax) - log(faces)) / (log(c->fmax) - log(c->fmin));
}
static double px_y(const canvas *c, double cost) {
    return c->y0 + c->h * (log(cost) - log(c->cmin)) / (log(c->cmax) - log(c->cmin));
}

static void draw_panel(canvas *c, const curve *curves) {
    const float grey[3] = {0.75f, 0.75f, 0.75f}, dark[3] = {0.2f, 0.2f, 0.2f};
    /* decades as grid lines */
    for (double d = pow(10, floor(log10(c->cmin))); d <= c->cmax * 1.0001; d *= 10)
        if (d >= c->cmin) line(c->im, c->x0, px_y(c, d), c->x0 + c->w, px_y(c, d), grey, 1);
    for (double d = pow(10, ceil(log10(c->fmin))); d <= c->fmax; d *= 10)
        line(c->im, px_x(c, d), c->y0, px_x(c, d), c->y0 + c->h, grey, 1);
    line(c->im, c->x0, c->y0, c->x0 + c->w, c->y0, dark, 2);
    line(c->im, c->x0, c->y0, c->x0, c->y0 + c->h, dark, 2);
    for (int t = 0; t < NTOL; t++)
        for (int i = 1; i < curves[t].n; i++)
            line(c->im, px_x(c, curves[t].faces[i - 1]), px_y(c, curves[t].cost[i - 1]), px_x(c, curves[t].faces[i]),
                 px_y(c, curves[t].cost[i]), colours[t], t == NTOL - 1 ? 3 : 2);
}

/* ---------------------------------------------------------------- one asset */

static int run_asset(const char *corpus, const asset *a, curve curves[NTOL]) {
    char model[4096], texture[4096];
    snprintf(model, sizeof model, "%s/%s", corpus, a->model);
    snprintf(texture, sizeof texture, "%s/%s", corpus, a->texture);
    sc_error err = {0};
    double t0 = sc_now();
    sc_ctx *load = run(&sc_node_load_atlas, (const char *const[]){"path", model, "texture", texture, NULL}, NULL,
                       NULL, &err);
    if (!load) {
        printf("%s: load failed: %s\n", a->name, err.message);
        return 1;
    }
    sc_value *atlas = sc_ctx_output(load, 0);
    int32_t nf = atlas->as.atlas->mesh->as.mesh->nf;
    printf("\n%s: %d faces, loaded in %.2f s\n", a->name, nf, sc_now() - t0);
    /* the target ladder: 90% of the input, then x0.8 down to MIN_FACES */
    char targets[1024] = "";
    int ntargets = 0;
    for (double f = 0.9 * nf; f >= MIN_FACES && ntargets < MAX_LEVELS - 1; f *= 0.8, ntargets++) {
        char item[32];
        snprintf(item, sizeof item, "%s%d", ntargets ? "," : "", (int)f);
        strcat(targets, item);
    }
    printf("%-9s %9s %11s %11s %7s %9s %10s | %11s %11s %11s %11s\n", "tolerance", "straight s", "collapsible",
           "(before)", "flips", "decim s", "uncollaps.", "cost@50%", "cost@10%", "cost@5%", "cost@min");
    printf("(cost@N%%: accumulated quadric cost at the first level with at most N%% of the faces; -: never reached)\n");
    int failed = 0;
    for (int t = 0; t < NTOL; t++) {
        curves[t].n = 0;
        double ts = sc_now();
        sc_ctx *st = run(&sc_node_straighten, (const char *const[]){"tolerance", tolerances[t], "erase", "false", NULL},
                         "atlas", atlas, &err);
        ts = sc_now() - ts;
        if (!st) {
            printf("%-9s straighten failed: %s\n", tolerances[t], err.message);
            failed = 1;
            continue;
        }
        sc_value *straight = sc_ctx_output(st, 0);
        double td = sc_now();
        sc_ctx *dec = run(&sc_node_decimate,
                          (const char *const[]){"faces", targets, "hausdorff_samples", "0", "uv_precision", "0", NULL}, "mesh",
                          straight->as.atlas->mesh, &err);
        td = sc_now() - td;
        if (!dec) {
            printf("%-9s decimate failed: %s\n", tolerances[t], err.message);
            sc_ctx_free(st);
            failed = 1;
            continue;
        }
        curves[t].faces[0] = nf, curves[t].cost[0] = 0;
        curves[t].n = 1;
        for (int k = 0; k < ntargets; k++) {
            char name[64];
            snprintf(name, sizeof name, "lod%d.faces", k);
            double faces = sc_ctx_metric_value(dec, name);
            snprintf(name, sizeof name, "lod%d.quadric_cost", k);
            double cost = sc_ctx_metric_value(dec, name);
            if (isnan(faces) || isnan(cost)) break;
            curves[t].faces[curves[t].n] = faces, curves[t].cost[curves[t].n] = cost;
            curves[t].n++;
        }
        double at[3] = {0.5 * nf, 0.1 * nf, 0.05 * nf}, cost_at[3] = {NAN, NAN, NAN};
        for (int q = 0; q < 3; q++)   /* the first level at or below the fraction */
            for (int i = 1; i < curves[t].n; i++)
                if (curves[t].faces[i] <= at[q]) {
                    cost_at[q] = curves[t].cost[i];
                    break;
                }
        const curve *c = &curves[t];
        char at_text[3][32];   /* a fraction the decimation stalled above: "-" */
        for (int q = 0; q < 3; q++)
            if (isnan(cost_at[q])) snprintf(at_text[q], sizeof at_text[q], "-");
            else snprintf(at_text[q], sizeof at_text[q], "%.4g", cost_at[q]);
        printf("%-9s %9.2f %11g %11g %7g %9.2f %10g | %11s %11s %11s %11.4g (%g faces)\n", tolerances[t], ts,
               sc_ctx_metric_value(st, "collapsible_seam_edges_after"),
               sc_ctx_metric_value(st, "collapsible_seam_edges_before"),
               isnan(sc_ctx_metric_value(st, "flipped_triangles")) ? 0 : sc_ctx_metric_value(st, "flipped_triangles"),
               td, sc_ctx_metric_value(dec, "input.uncollapsible_seam_edges"), at_text[0], at_text[1], at_text[2],
               c->cost[c->n - 1], c->faces[c->n - 1]);
        sc_ctx_free(dec);
        sc_ctx_free(st);
    }
    sc_ctx_free(load);
    return failed;
}

int main(int argc, char **argv) {
    sc_tune_allocator();   /* as the command line runs */
    const char *plot = "bench_straighten.png";
    const char *only[NASSETS];
    int nonly = 0;
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "-o") && i + 1 < argc) plot = argv[++i];
        else if (nonly < NASSETS) only[nonly++] = argv[i];
    }
    const char *env = getenv("SC_CORPUS");
    char *corpus = env && *env ? sc_strdup(env) : sc_path_join(SC_SOURCE_DIR, "../shared/corpus");
    if (access(corpus, R_OK) != 0) {
        printf("bench_straighten: corpus not found at %s (set SC_CORPUS): nothing measured\n", corpus);
        free(corpus);
        return 0;
    }
    double started = sc_now();
    printf("straighten + decimate (Liu et al. 2017 Fig. 12) on %s\n", corpus);
    curve curves[NASSETS][NTOL];
    bool done[NASSETS] = {false};
    int failed = 0, npanels = 0;
    for (int k = 0; k < NASSETS; k++) {
        bool want = nonly == 0;
        for (int i = 0; i < nonly; i++) want |= !strcmp(only[i], assets[k].name);
        if (!want) continue;
        failed |= run_asset(corpus, &assets[k], curves[k]);
        done[k] = true;
        npanels++;
    }
    if (npanels > 0) {
        const int pw = 640, ph = 420, margin = 40;
        sc_image_data *im = sc_image_alloc(npanels * (pw + margin) + margin, ph + 2 * margin, 3, SC_PIXEL_F32);
        if (!im) {
            printf("out of memory for the plot\n");
            free(corpus);
            return 1;
        }
        for (size_t i = 0; i < (size_t)im->width * im->height * 3; i++) ((float *)im->pixels)[i] = 1.0f;
        int panel = 0;
        for (int k = 0; k < NASSETS; k++) {
            if (!done[k]) continue;
            canvas c = {im, margin + panel * (pw + margin), margin, pw, ph, 1e300, 0, 1e300, 0};
            for (int t = 0; t < NTOL; t++)
                for (int i = 0; i < curves[k][t].n; i++) {
                    c.fmin = fmin(c.fmin, curves[k][t].faces[i]), c.fmax = fmax(c.fmax, curves[k][t].faces[i]);
                    if (curves[k][t].cost[i] > 0)
                        c.cmin = fmin(c.cmin, curves[k][t].cost[i]), c.cmax = fmax(c.cmax, curves[k][t].cost[i]);
                }
            if (c.fmax > c.fmin && c.cmax > c.cmin) {
                for (int t = 0; t < NTOL; t++)   /* the zero-cost start is drawn at the bottom */
                    for (int i = 0; i < curves[k][t].n; i++)
                        curves[k][t].cost[i] = fmax(curves[k][t].cost[i], c.cmin);
                draw_panel(&c, curves[k]);
            }
            panel++;
        }
        im->colorspace = SC_COLOR_SRGB;
        sc_buf png;
        sc_buf_init(&png);
        sc_error err = {0};
        if (sc_image_encode_png(im, 8, &png, &err) == SC_OK && sc_write_file_atomic(plot, png.data, png.len, &err) == SC_OK)
            printf("\nplot: %s (panels left to right:", plot);
        else
            printf("\nplot not written: %s (", err.message);
        for (int k = 0; k < NASSETS; k++)
            if (done[k]) printf(" %s", assets[k].name);
        printf("; x: faces, log, decreasing; y: accumulated quadric cost, log; tolerance 0 black,\n"
               "0.001 blue, 0.01 red, 0.1 green)\n");
        sc_buf_free(&png);
        sc_image_free(im);
    }
    printf("total %.1f s\n", sc_now() - started);
    free(corpus);
    return failed;
}
