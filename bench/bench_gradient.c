/* bench_gradient.c - the gradient_domain node on a corpus asset.
 *
 *   bench_gradient [-r RUNS] [ASSET] [--set name=value]... [--peer FILE.png]
 *                  [--peer-bin PATH] [--peer-vcycles N]
 *   bench_gradient --geodesic SIZE... [--set name=value]...
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
 * `--peer-bin PATH` (or $SC_PEER_TSP): the paper's reference code
 * (TextureSignalProcessing's TextureFiltering executable, built apart from
 * the tree) runs in the same run, before each seamcook run, as a child
 * process on the same asset and system: `--in OBJ PNG --modulation BETA
 * --interpolation W --outVCycles N --out FILE` (BETA and W from --set
 * gradient_scale= and screening=, else 0 and 1e4; N from --peer-vcycles,
 * else the peer's default 6). Its wall time and peak resident memory
 * (wait4's rusage) are measured, its output compared as with --peer, and one
 * table prints both side by side. Beside a peer (--peer or --peer-bin) the
 * node runs with seamless=false, the system the peer solves, unless --set
 * seamless= is given. The peer's wall time includes decoding the
 * PNG and writing its result; seamcook's "load + node" column includes
 * decoding the PNG, not encoding the result. What the peer measured at is
 * in docs/notes/gradient_domain.md.
 *
 * `--geodesic SIZE...`: the heat-method distance from the pole (0, 0, 1) on
 * the procedural unit sphere (six charts, mesh resolution SIZE x 200 / 1024:
 * the procedural node's largest at 1024^2, the same ratio below; a
 * SIZE x SIZE texture, no bumps), against great-circle distance at every
 * texel centre inside a chart (its surface point found here by
 * point-in-triangle in uv): the mean and largest error, the V-cycles of
 * both solves, seconds and peak memory; also the mean signed error (a
 * constant offset, set by where the source falls among the texels) and the
 * mean error once it is taken out; one child process per size. The
 * unit test runs 48^2 to 192^2; this states the error at 1024^2.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>
#include <fcntl.h>

#include "sc_base.h"
#include "sc_exec.h"
#include "sc_imageio.h"
#include "sc_nodes.h"
#include "runs.h"

/* one run of the peer executable */
typedef struct peer_run {
    bool ran;
    int status;          /* its exit status (-1: killed or not started) */
    double seconds, cpu, peak_mb;
    int vcycles;
    long texels;         /* texels it solves for ("Resolution: N / W x H"), or -1 */
    char out[512], log[512];
} peer_run;

typedef struct run_args {
    const char *corpus, *model, *texture, *peer;
    int nsets;
    char **sets;
    const peer_run *pr;  /* the peer run beside this one, or NULL */
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
 * run changed, beside the input's own difference from the peer there
 * (*rms < 0 when the peer's file is unreadable or does not match) */
static void compare_peer(const char *path, const sc_image_data *in, const sc_image_data *ours, double *rms,
                         double *largest, double *moved) {
    *rms = *largest = *moved = -1;
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
    if (n > 0) *rms = sqrt(s_ours / (double)n), *largest = worst, *moved = sqrt(s_in / (double)n);
    printf("peer %s: over %ld changed texel channels, RMS difference %.4g (largest %.4g); the input's from the peer: %.4g\n",
           path, n, *rms, worst, *moved);
    sc_image_free(peer);
}

/* the value of --set NAME=..., or def */
static double set_number(const run_args *ra, const char *name, double def) {
    size_t n = strlen(name);
    for (int i = 0; i < ra->nsets; i++)
        if (!strncmp(ra->sets[i], name, n) && ra->sets[i][n] == '=') return atof(ra->sets[i] + n + 1);
    return def;
}

/* Runs the peer on the asset as a child process: wall time and peak
 * resident memory from wait4. Its output goes to pr->out, its text to pr->log. */
static void run_peer(const char *bin, const run_args *ra, int vcycles, peer_run *pr) {
    memset(pr, 0, sizeof *pr);
    pr->status = -1;
    pr->vcycles = vcycles;
    const char *tmp = getenv("TMPDIR");
    if (!tmp || !*tmp) tmp = "/tmp";
    snprintf(pr->out, sizeof pr->out, "%s/bench_gradient_peer_%d.png", tmp, (int)getpid());
    snprintf(pr->log, sizeof pr->log, "%s/bench_gradient_peer_%d.txt", tmp, (int)getpid());
    char *model = sc_path_join(ra->corpus, ra->model), *tex = sc_path_join(ra->corpus, ra->texture);
    char beta[32], w[32], nv[16];
    double b = set_number(ra, "gradient_scale", -1), sw = set_number(ra, "screening", -1);
    snprintf(beta, sizeof beta, "%.17g", b >= 0 ? b : 0.0);
    snprintf(w, sizeof w, "%.17g", sw >= 0 ? sw : 1e4);
    snprintf(nv, sizeof nv, "%d", vcycles);
    char *argv[] = {(char *)bin, "--in", model, tex, "--modulation", beta, "--interpolation", w,
                    "--outVCycles", nv, "--out", pr->out, "--verbose", NULL};
    printf("peer: %s --in %s %s --modulation %s --interpolation %s --outVCycles %s --out %s --verbose\n", bin, model,
           tex, beta, w, nv, pr->out);
    fflush(stdout);
    double t0 = sc_now();
    pid_t pid = fork();
    if (pid == 0) {
        int fd = open(pr->log, O_WRONLY | O_CREAT | O_TRUNC, 0644);
        if (fd >= 0) dup2(fd, 1), dup2(fd, 2), close(fd);
        execv(bin, argv);
        _exit(127);
    }
    free(model), free(tex);
    if (pid < 0) {
        printf("peer: fork failed\n");
        return;
    }
    int st = 0;
    struct rusage ru;
    memset(&ru, 0, sizeof ru);
    if (wait4(pid, &st, 0, &ru) < 0) {
        printf("peer: wait4 failed\n");
        return;
    }
    pr->seconds = sc_now() - t0;
    pr->peak_mb = (double)ru.ru_maxrss / 1024.0; /* kB on Linux */
    pr->cpu = (double)ru.ru_utime.tv_sec + 1e-6 * (double)ru.ru_utime.tv_usec + (double)ru.ru_stime.tv_sec +
              1e-6 * (double)ru.ru_stime.tv_usec;
    pr->texels = -1;
    FILE *lf = fopen(pr->log, "r");
    char line[512];
    while (lf && fgets(line, sizeof line, lf)) {
        if (strstr(line, "libpng warning")) continue;
        const char *at = strstr(line, "Resolution:");
        if (at) pr->texels = atol(at + 11);
        printf("  peer| %s", line);
    }
    if (lf) fclose(lf);
    pr->status = WIFEXITED(st) ? WEXITSTATUS(st) : -1;
    pr->ran = pr->status == 0 && access(pr->out, R_OK) == 0;
    printf("peer: exit %d after %.2f s, peak %.0f MB; its output in %s\n", pr->status, pr->seconds, pr->peak_mb,
           pr->log);
}

static int run_once(void *ud, int out) {
    const run_args *ra = ud;
    const char *peer_file = ra->pr ? (ra->pr->ran ? ra->pr->out : NULL) : ra->peer;
    double t_load = sc_now();
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
    if (peer_file || ra->pr) atlas = as_stored(atlas);
    sc_value *inputs[] = {atlas, NULL, NULL}; /* atlas, labels, field */
    sc_ctx *ctx = sc_ctx_new(&sc_node_gradient_domain, NULL, inputs);
    sc_ctx_set_threads(ctx, 2);
    /* beside the peer: the same system, so the paper's raw result (the peer
     * does not erase seams) unless --set seamless= says otherwise */
    bool set_seamless = false;
    for (int i = 0; i < ra->nsets; i++) set_seamless |= !strncmp(ra->sets[i], "seamless=", 9);
    if ((peer_file || ra->pr) && !set_seamless) rc = sc_ctx_set_param(ctx, "seamless", "false", &err);
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
    double secs = sc_now() - t0, peak = bench_peak_mb(), whole = sc_now() - t_load;
    struct rusage ru;
    getrusage(RUSAGE_SELF, &ru);
    double maxrss = (double)ru.ru_maxrss / 1024.0;
    double cpu = (double)ru.ru_utime.tv_sec + 1e-6 * (double)ru.ru_utime.tv_usec + (double)ru.ru_stime.tv_sec +
                 1e-6 * (double)ru.ru_stime.tv_usec;
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
        double rms = -1, largest = -1, moved = -1;
        if (peer_file) compare_peer(peer_file, atlas->as.atlas->textures[0].image->as.image, im, &rms, &largest, &moved);
        if (ra->pr) {
            const peer_run *pr = ra->pr;
            printf("\n| %dx%d | peer (TextureFiltering) | seamcook |\n|---|---|---|\n", (int)im->width, (int)im->height);
            printf("| texels solved for | %ld | %.0f |\n", pr->texels, sc_ctx_metric_value(ctx, "unknowns"));
            printf("| V-cycles | %d (fixed; no residual reported) | %.0f (to residual %.2g) |\n", pr->vcycles,
                   sc_ctx_metric_value(ctx, "smooth_vcycles"), sc_ctx_metric_value(ctx, "smooth_residual"));
            printf("| wall, whole process | %.2f s (PNG decode and encode included) | %.2f s (PNG decode "
                   "included) |\n", pr->seconds, whole);
            printf("| wall, node only | - | %.2f s |\n", secs);
            printf("| CPU (user + system), whole process | %.2f s | %.2f s |\n", pr->cpu, cpu);
            printf("| peak resident, whole process | %.0f MB | %.0f MB |\n", pr->peak_mb, maxrss);
            if (rms >= 0)
                printf("| RMS difference (largest), 0..1 | %.3g (%.3g) over the texels seamcook changed; the input "
                       "differs by %.3g |\n", rms, largest, moved);
            else
                printf("| RMS difference | peer output missing (exit %d) | |\n", pr->status);
            printf("| faster, at <= memory | | %s, %s |\n\n", whole < pr->seconds ? "yes" : "no",
                   maxrss <= pr->peak_mb ? "yes" : "no");
        }
        if (bench_report_seconds(out, secs) != 0) rc = SC_EINPUT;
    }
    fflush(stdout);
    sc_ctx_free(ctx);
    sc_value_release(atlas);
    return rc != SC_OK;
}

/* ---------------------------------------------------------------- geodesics on the unit sphere */

/* The surface point at every texel centre inside a uv triangle (NAN
 * elsewhere): pos[3 * (j * W + i)]; NULL when out of memory. */
static double *texel_points(const sc_mesh *m, int W, int H) {
    double *pos = malloc(sizeof(double) * 3 * (size_t)W * H);
    if (!pos) return NULL;
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

typedef struct geo_args {
    int size, nsets;
    char **sets;
} geo_args;

static int run_geodesic(void *ud, int out) {
    const geo_args *ga = ud;
    char res[16], sz[16];
    /* 200 (the procedural node's largest) at 1024^2, the same ratio below */
    int resolution = (int)lround(ga->size * 200.0 / 1024.0);
    if (resolution < 1) resolution = 1;
    if (resolution > 200) resolution = 200;
    snprintf(res, sizeof res, "%d", resolution);
    snprintf(sz, sizeof sz, "%d", ga->size);
    sc_error err = {0};
    sc_ctx *pc = sc_ctx_new(&sc_node_procedural, NULL, NULL);
    sc_ctx_set_threads(pc, 2);
    int rc = sc_ctx_set_param(pc, "resolution", res, &err);
    if (rc == SC_OK) rc = sc_ctx_set_param(pc, "texture_size", sz, &err);
    if (rc == SC_OK) rc = sc_ctx_set_param(pc, "bumpiness", "0", &err);
    if (rc == SC_OK) rc = sc_ctx_set_param(pc, "chart_tint", "0", &err);
    if (rc == SC_OK) rc = sc_ctx_run(pc, &err);
    if (rc != SC_OK) {
        printf("procedural failed: %s\n", err.message);
        sc_ctx_free(pc);
        return 1;
    }
    sc_value *sphere = sc_value_retain(sc_ctx_output(pc, 0));
    sc_ctx_free(pc);
    sc_value *inputs[] = {sphere, NULL, NULL}; /* atlas, labels, field */
    sc_ctx *ctx = sc_ctx_new(&sc_node_gradient_domain, NULL, inputs);
    sc_ctx_set_threads(ctx, 2);
    rc = sc_ctx_set_param(ctx, "operation", "geodesic", &err);
    if (rc == SC_OK) rc = sc_ctx_set_param(ctx, "sources", "0 0 1", &err);
    for (int i = 0; i < ga->nsets && rc == SC_OK; i++) {
        char *eq = strchr(ga->sets[i], '=');
        if (!eq) continue;
        *eq = 0;
        rc = sc_ctx_set_param(ctx, ga->sets[i], eq + 1, &err);
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
        double *pos = texel_points(sphere->as.atlas->mesh->as.mesh, im->width, im->height);
        double sum = 0, worst = 0, bias = 0, centred = 0;
        long n = 0;
        for (int pass = 0; pass < 2; pass++) {
            for (long t = 0; pos && t < (long)im->width * im->height; t++) {
                const double *q = &pos[3 * t];
                if (isnan(q[0])) continue;
                double r = sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2]);
                double gc = acos(fmax(-1.0, fmin(1.0, q[2] / r)));
                double d = ((const float *)im->pixels)[t] - gc;
                if (pass == 0) sum += fabs(d), bias += d, n++, worst = fmax(worst, fabs(d));
                else centred += fabs(d - bias);
            }
            if (pass == 0 && n) bias /= (double)n;
        }
        free(pos);
        printf("%d^2 (mesh resolution %d, %.0f unknowns): mean |distance - great circle| %.4g, largest %.4g over %ld "
               "texels (mean signed %.4g; without it %.4g); V-cycles %.0f + %.0f; %.2f s, peak %.0f MB (+%.0f MB "
               "during the run)\n",
               ga->size, resolution, sc_ctx_metric_value(ctx, "unknowns"), n ? sum / (double)n : NAN, worst, n, bias,
               n ? centred / (double)n : NAN,
               sc_ctx_metric_value(ctx, "heat_vcycles"), sc_ctx_metric_value(ctx, "distance_vcycles"), secs, peak,
               peak - rss0);
        if (!n || bench_report_seconds(out, secs) != 0) rc = SC_EINPUT;
    }
    fflush(stdout);
    sc_ctx_free(ctx);
    sc_value_release(sphere);
    return rc != SC_OK;
}

int main(int argc, char **argv) {
    sc_tune_allocator();
    int runs = 1, nsets = 0;
    char *sets[64];
    const char *name = "blub", *peer = NULL, *peer_bin = getenv("SC_PEER_TSP");
    int peer_vcycles = 6, geo[16], ngeo = 0;
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "-r") && i + 1 < argc) runs = atoi(argv[++i]);
        else if (!strcmp(argv[i], "--peer") && i + 1 < argc) peer = argv[++i];
        else if (!strcmp(argv[i], "--peer-bin") && i + 1 < argc) peer_bin = argv[++i];
        else if (!strcmp(argv[i], "--peer-vcycles") && i + 1 < argc) peer_vcycles = atoi(argv[++i]);
        else if (!strcmp(argv[i], "--geodesic")) {
            while (i + 1 < argc && atoi(argv[i + 1]) > 0 && ngeo < 16) geo[ngeo++] = atoi(argv[++i]);
        }
        else if (!strcmp(argv[i], "--set") && i + 1 < argc && nsets < 64) sets[nsets++] = argv[++i];
        else name = argv[i];
    }
    if (ngeo > 0) {
        int failed = 0;
        for (int k = 0; k < ngeo; k++) {
            geo_args ga = {geo[k], nsets, sets};
            double secs;
            failed += bench_in_child(run_geodesic, &ga, &secs) != 0;
        }
        return failed ? 1 : 0;
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
        run_args ra = {corpus, model, texture, peer, nsets, sets, NULL};
        peer_run pr;
        if (peer_bin && *peer_bin) {
            if (access(peer_bin, X_OK) != 0) {
                printf("peer: %s is not an executable\n", peer_bin);
                failed++;
                break;
            }
            run_peer(peer_bin, &ra, peer_vcycles, &pr);
            ra.pr = &pr;
        }
        if (bench_in_child(run_once, &ra, &secs[done]) == 0) done++;
        else failed++;
        if (ra.pr) unlink(pr.out);
    }
    bench_summary(name, "total", secs, done, 0);
    free(corpus);
    return failed ? 1 : 0;
}
