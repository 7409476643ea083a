/* bench_chartify.c - the quad-chart atlas (sc_quad_build) against xatlas.
 *
 *   bench_chartify [-j N] [-r RUNS] [-s] [ASSET...]
 *
 * -s: with straight patch borders (sc_quad_options.straight_borders, the
 * node's straight_borders).
 *
 * For each corpus asset (../shared/corpus, or $SC_CORPUS): load it with
 * load_atlas (decode time reported apart), then time sc_quad_build with
 * sc_quad_defaults and the asset's texture size, and read back its metrics:
 * patches, quads (each quad is a chart), utilisation, stretch, PSNR per
 * texture slot, border mismatches and shared texels per level, levels and
 * seconds per stage. The process's peak resident memory during the build is
 * its high-water mark, reset after the load. Each measurement runs in a
 * child process of its own so peaks do not mix; with -r, RUNS times, and
 * the table shows the run of median time (runs.h: why several).
 *
 * The peer: xatlas (bench/xatlas, `npm ci --prefix bench/xatlas`) on the
 * same mesh as OBJ (the corpus's *_welded.obj for glTF assets) at the same
 * resolution, run with node in a child process of its own; its peak is the
 * node process's (ru_maxrss, the Node runtime included), its seconds are
 * the generateAtlas call alone. xatlas makes a seamed atlas: "seamless: no".
 *
 * Targets (pizza at 4096^2, 2-core machine): <= 10 s, <= 2 GB peak, fewer
 * than 4,740 charts, utilisation >= 0.655, 0 shared texels at every level;
 * PASS/FAIL from the measured numbers (the median with -r).
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include "sc_base.h"
#include "sc_exec.h"
#include "sc_nodes.h"
#include "sc_quad.h"
#include "runs.h"

typedef struct asset {
    const char *name;
    const char *model;    /* relative to the corpus */
    const char *texture;  /* texture override, or NULL (the model's own) */
    const char *obj;      /* the same mesh as OBJ, for xatlas */
    int texture_size;
    bool targets;         /* pizza: the stated targets */
} asset;

static const asset assets[] = {
    {"pizza", "pizza/pizza.obj", "pizza/pizza.png", "pizza/pizza.obj", 4096, true},
    {"Duck", "Duck/Duck.gltf", NULL, "Duck/Duck_welded.obj", 512, false},
    {"Duck", "Duck/Duck.gltf", NULL, "Duck/Duck_welded.obj", 4096, false},
    {"MuruCat", "MuruCat/scene.gltf", NULL, "MuruCat/MuruCat_welded.obj", 1024, false},
    {"blub", "blub/blub.obj", "blub/blub_texture.png", "blub/blub.obj", 2048, false},
};
#define NASSETS ((int)(sizeof assets / sizeof assets[0]))

#define MAX_SLOTS 8
#define MAX_LEVELS 16

/* What a child measured, sent back whole through a pipe (under PIPE_BUF). */
typedef struct result {
    int ok;
    double seconds, peak_mb, rss_mb, load_s;
    double charts, patches, utilisation, stretch_l2, levels, mismatch, shared;
    double faces_in, faces_out, straight_cuts;
    double stage[5];             /* seconds_charts, _sample, _levels, _encode, _measure */
    int nslots;
    char slot[MAX_SLOTS][24];
    double psnr[MAX_SLOTS];
    int nshared_levels;
    double shared_level[MAX_LEVELS];
    int width, height;           /* the atlas made */
} result;

static const char *const stage_names[5] = {"seconds_charts", "seconds_sample", "seconds_levels", "seconds_encode",
                                           "seconds_measure"};

static double metric(const sc_metric_list *ml, const char *name) {
    for (int32_t i = 0; i < ml->count; i++)
        if (!strcmp(ml->items[i].name, name)) return ml->items[i].value;
    return NAN;
}

typedef struct run_args {
    const char *corpus;
    const asset *a;
    int threads;
    int res_fd;            /* where the child writes its result */
    bool straight;         /* -s: straight patch borders */
} run_args;

/* Loads the asset and builds its quad atlas; the result goes to res_fd,
 * the build's seconds to `out`. */
static int run_quad(void *ud, int out) {
    const run_args *ra = ud;
    const asset *a = ra->a;
    result r;
    memset(&r, 0, sizeof r);
    char *model = sc_path_join(ra->corpus, a->model);
    char *tex = a->texture ? sc_path_join(ra->corpus, a->texture) : NULL;
    sc_error err = {0};
    sc_ctx *load = sc_ctx_new(&sc_node_load_atlas, NULL, NULL);
    sc_ctx_set_threads(load, ra->threads);
    int rc = sc_ctx_set_param(load, "path", model, &err);
    if (rc == SC_OK && tex) rc = sc_ctx_set_param(load, "texture", tex, &err);
    double t0 = sc_now();
    if (rc == SC_OK) rc = sc_ctx_run(load, &err);
    r.load_s = sc_now() - t0;
    free(model), free(tex);
    if (rc != SC_OK) {
        printf("%-8s load failed: %s\n", a->name, err.message);
        fflush(stdout);
        sc_ctx_free(load);
        return 1;
    }
    sc_value *atlas = sc_value_retain(sc_ctx_output(load, 0));
    sc_ctx_free(load);
    const sc_atlas *at = atlas->as.atlas;

    sc_quad_options o;
    sc_quad_defaults(&o);
    o.texture_size = a->texture_size;
    o.straight_borders = ra->straight;
    sc_quad_result q;
    memset(&q, 0, sizeof q);
    double rss0 = bench_resident_mb();
    bench_reset_peak();
    t0 = sc_now();
    rc = sc_quad_build(at->mesh->as.mesh, at->textures, at->ntex, &o, ra->threads, &q, &err);
    r.seconds = sc_now() - t0;
    r.peak_mb = bench_peak_mb();
    r.rss_mb = r.peak_mb - rss0;
    sc_value_release(atlas);
    if (rc != SC_OK) {
        printf("%-8s sc_quad_build failed: %s\n", a->name, err.message);
        fflush(stdout);
        return 1;
    }
    const sc_metric_list *ml = &q.metrics;
    r.ok = 1;
    r.charts = metric(ml, "quads");
    r.patches = metric(ml, "patches");
    r.utilisation = metric(ml, "utilisation");
    r.stretch_l2 = metric(ml, "stretch_l2");
    r.levels = metric(ml, "levels");
    r.mismatch = metric(ml, "boundary_mismatch");
    r.shared = metric(ml, "shared_texels");
    r.faces_in = metric(ml, "faces_in");
    r.faces_out = metric(ml, "faces_out");
    r.straight_cuts = metric(ml, "patches_cut_straight");
    r.width = q.width, r.height = q.height;
    for (int i = 0; i < 5; i++) r.stage[i] = metric(ml, stage_names[i]);
    for (int32_t i = 0; i < ml->count; i++) {
        const char *n = ml->items[i].name;
        if (!strncmp(n, "psnr_", 5) && r.nslots < MAX_SLOTS) {
            snprintf(r.slot[r.nslots], sizeof r.slot[0], "%s", n + 5);
            r.psnr[r.nslots++] = ml->items[i].value;
        }
    }
    for (int L = 0; L < MAX_LEVELS; L++) {
        char name[64];
        snprintf(name, sizeof name, "shared_texels_level%d", L);
        double v = metric(ml, name);
        if (isnan(v)) break;
        r.shared_level[r.nshared_levels++] = v;
    }
    sc_quad_result_free(&q);
    rc = write(ra->res_fd, &r, sizeof r) == (ssize_t)sizeof r ? 0 : 1;
    if (rc == 0) rc = bench_report_seconds(out, r.seconds);
    fflush(stdout);
    return rc;
}

/* The value of "key": in one line of JSON, or NAN. */
static double json_number(const char *json, const char *key) {
    char pat[64];
    snprintf(pat, sizeof pat, "\"%s\":", key);
    const char *p = strstr(json, pat);
    if (!p) return NAN;
    char *end;
    double v = strtod(p + strlen(pat), &end);
    return end == p + strlen(pat) ? NAN : v;
}

/* Appends s to buf in single quotes for sh. */
static void shell_quote(char *buf, size_t cap, const char *s) {
    size_t n = strlen(buf);
    if (n + 1 < cap) buf[n++] = '\'';
    for (; *s && n + 5 < cap; s++) {
        if (*s == '\'') {
            memcpy(buf + n, "'\\''", 4);
            n += 4;
        } else buf[n++] = *s;
    }
    if (n + 1 < cap) buf[n++] = '\'';
    buf[n] = 0;
}

/* Runs xatlas on the asset's OBJ through node; its peak is the largest
 * waited-for descendant's (this child's own children only). */
static int run_xatlas(void *ud, int out) {
    const run_args *ra = ud;
    const asset *a = ra->a;
    result r;
    memset(&r, 0, sizeof r);
    char *obj = sc_path_join(ra->corpus, a->obj);
    char *script = sc_path_join(SC_SOURCE_DIR, "bench/xatlas/xatlas_charts.mjs");
    char cmd[4096] = "exec node ";
    shell_quote(cmd, sizeof cmd, script);
    strncat(cmd, " ", sizeof cmd - strlen(cmd) - 1);
    shell_quote(cmd, sizeof cmd, obj);
    char tail[64];
    snprintf(tail, sizeof tail, " --resolution %d", a->texture_size);
    strncat(cmd, tail, sizeof cmd - strlen(cmd) - 1);
    free(obj), free(script);
    FILE *p = popen(cmd, "r");
    if (!p) return 1;
    char line[8192] = "";
    char buf[8192];
    while (fgets(buf, sizeof buf, p))
        if (buf[0] == '{') snprintf(line, sizeof line, "%s", buf);
    int st = pclose(p);
    if (st != 0 || !line[0]) {
        printf("%-8s xatlas failed (status %d)\n", a->name, st);
        fflush(stdout);
        return 1;
    }
    struct rusage ru;
    getrusage(RUSAGE_CHILDREN, &ru);
    r.ok = 1;
    r.peak_mb = ru.ru_maxrss / 1024.0;
    r.rss_mb = NAN;
    r.seconds = json_number(line, "seconds");
    r.charts = json_number(line, "charts");
    r.utilisation = json_number(line, "utilisation");
    r.width = (int)json_number(line, "atlas_width");
    r.height = (int)json_number(line, "atlas_height");
    r.load_s = json_number(line, "seconds_init");
    r.stage[0] = json_number(line, "seconds_charts");
    r.stage[1] = json_number(line, "seconds_pack");
    int rc = write(ra->res_fd, &r, sizeof r) == (ssize_t)sizeof r ? 0 : 1;
    if (rc == 0) rc = bench_report_seconds(out, r.seconds);
    return rc;
}

/* Runs fn in a child `runs` times; res gets the run of median seconds.
 * Returns the number of runs that succeeded. */
static int measure(int (*fn)(void *, int), run_args *ra, int runs, const char *what, double target,
                   result *res) {
    result all[100];
    double secs[100];
    int done = 0;
    for (int k = 0; k < runs; k++) {
        int fd[2];
        if (pipe(fd) != 0) break;
        ra->res_fd = fd[1];
        double s = 0;
        int bad = bench_in_child(fn, ra, &s);
        close(fd[1]);
        result r;
        if (!bad && read(fd[0], &r, sizeof r) == (ssize_t)sizeof r && r.ok) all[done] = r, secs[done++] = s;
        close(fd[0]);
    }
    if (done == 0) return 0;
    char name[48];
    snprintf(name, sizeof name, "%s %d", ra->a->name, ra->a->texture_size);
    double sorted[100];
    memcpy(sorted, secs, (size_t)done * sizeof *secs);
    bench_summary(name, what, sorted, done, target);
    /* the run of median time */
    int order[100];
    for (int i = 0; i < done; i++) order[i] = i;
    for (int i = 1; i < done; i++)
        for (int j = i; j > 0 && secs[order[j]] < secs[order[j - 1]]; j--) {
            int t = order[j];
            order[j] = order[j - 1], order[j - 1] = t;
        }
    *res = all[order[(done - 1) / 2]];
    return done;
}

static bool quad_seamless(const result *r) {
    if (!r->ok || r->mismatch != 0 || r->shared != 0 || r->nshared_levels == 0) return false;
    if (r->nshared_levels != (int)r->levels) return false;
    for (int L = 0; L < r->nshared_levels; L++)
        if (r->shared_level[L] != 0) return false;
    return true;
}

static void psnr_text(const result *r, char *psnr, size_t cap) {
    snprintf(psnr, cap, "-");
    if (r->nslots > 0) {
        psnr[0] = 0;
        for (int i = 0; i < r->nslots; i++) {
            char one[48];
            snprintf(one, sizeof one, "%s%s %.2f", i ? ", " : "", r->slot[i], r->psnr[i]);
            strncat(psnr, one, cap - strlen(psnr) - 1);
        }
    }
}

static void print_row(const char *name, int size, const char *tool, const result *r, int psnr_w, const char *seamless) {
    char label[32], psnr[400], peak[32];
    snprintf(label, sizeof label, "%s %d", name, size);
    psnr_text(r, psnr, sizeof psnr);
    snprintf(peak, sizeof peak, "%.0f", r->peak_mb);
    printf("%-13s | %-6s | %6.0f | %11.4f | %7.2f | %7s | %-*s | %s\n", label, tool, r->charts, r->utilisation,
           r->seconds, peak, psnr_w, psnr, seamless);
}

static bool have_xatlas(void) {
    char *mods = sc_path_join(SC_SOURCE_DIR, "bench/xatlas/node_modules");
    bool ok = access(mods, R_OK) == 0 && system("command -v node >/dev/null 2>&1") == 0;
    free(mods);
    return ok;
}

int main(int argc, char **argv) {
    sc_tune_allocator();   /* as the command line runs */
    int threads = 2, runs = 1;
    bool straight = false;
    const char *only[NASSETS];
    int nonly = 0;
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "-j") && i + 1 < argc) threads = atoi(argv[++i]);
        else if (!strcmp(argv[i], "-r") && i + 1 < argc) runs = atoi(argv[++i]);
        else if (!strcmp(argv[i], "-s")) straight = true;
        else if (nonly < NASSETS) only[nonly++] = argv[i];
    }
    const char *env = getenv("SC_CORPUS");
    char *corpus = env && *env ? sc_strdup(env) : sc_path_join(SC_SOURCE_DIR, "../shared/corpus");
    if (access(corpus, R_OK) != 0) {
        printf("bench_chartify: corpus not found at %s (set SC_CORPUS): nothing measured\n", corpus);
        free(corpus);
        return 0;
    }
    if (runs < 1 || runs > 100) runs = 1;
    bool xatlas = have_xatlas();
    printf("sc_quad_build (sc_quad_defaults%s) on %s, %d threads, %d run%s per asset\n",
           straight ? ", straight_borders" : "", corpus, threads, runs, runs > 1 ? "s" : "");
    if (!xatlas) printf("xatlas: not installed (npm ci --prefix bench/xatlas)\n");
    printf("\n");

    result quad[NASSETS], xa[NASSETS];
    bool have_q[NASSETS] = {0}, have_x[NASSETS] = {0}, want[NASSETS] = {0};
    int failed = 0;
    for (int k = 0; k < NASSETS; k++) {
        want[k] = nonly == 0;
        for (int i = 0; i < nonly; i++) want[k] |= !strcmp(only[i], assets[k].name);
        if (!want[k]) continue;
        run_args ra = {corpus, &assets[k], threads, -1, straight};
        have_q[k] = measure(run_quad, &ra, runs, "quad", assets[k].targets ? 10 : 0, &quad[k]) > 0;
        failed += !have_q[k];
        if (have_q[k]) {
            const result *r = &quad[k];
            printf("%-8s %4d^2  quad: %.0f patches, %.0f quads, atlas %dx%d, %.0f levels, stretch_l2 %.4f, "
                   "load %.2f s, +RSS %.0f MB\n",
                   assets[k].name, assets[k].texture_size, r->patches, r->charts, r->width, r->height, r->levels,
                   r->stretch_l2, r->load_s, r->rss_mb);
            double side = assets[k].texture_size;
            printf("%-8s         utilisation %.4f of the %dx%d atlas made, %.4f of %d^2\n", "", r->utilisation,
                   r->width, r->height, r->utilisation * r->width * r->height / (side * side), assets[k].texture_size);
            printf("%-8s         faces %.0f -> %.0f (x%.3f), patches cut straight %.0f\n", "", r->faces_in,
                   r->faces_out, r->faces_in > 0 ? r->faces_out / r->faces_in : 0, r->straight_cuts);
            printf("%-8s         seconds: charts %.2f, sample %.2f, levels %.2f, encode %.2f, measure %.2f\n", "",
                   r->stage[0], r->stage[1], r->stage[2], r->stage[3], r->stage[4]);
            printf("%-8s         psnr:", "");
            for (int i = 0; i < r->nslots; i++) printf(" psnr_%s %.2f dB", r->slot[i], r->psnr[i]);
            printf("%s; boundary_mismatch %.0f, shared_texels %.0f (per level:", r->nslots ? "" : " none",
                   r->mismatch, r->shared);
            for (int L = 0; L < r->nshared_levels; L++) printf(" %.0f", r->shared_level[L]);
            printf(")\n");
        }
        if (xatlas) {
            have_x[k] = measure(run_xatlas, &ra, runs, "xatlas", 0, &xa[k]) > 0;
            failed += !have_x[k];
            if (have_x[k])
                printf("%-8s %4d^2  xatlas: atlas %dx%d, charts %.2f s + pack %.2f s, init %.2f s\n", assets[k].name,
                       assets[k].texture_size, xa[k].width, xa[k].height, xa[k].stage[0], xa[k].stage[1],
                       xa[k].load_s);
        }
        fflush(stdout);
    }

    int psnr_w = 9;
    for (int k = 0; k < NASSETS; k++)
        if (want[k] && have_q[k]) {
            char t[400];
            psnr_text(&quad[k], t, sizeof t);
            if ((int)strlen(t) > psnr_w) psnr_w = (int)strlen(t);
        }
    printf("\n%-13s | %-6s | %6s | %11s | %7s | %7s | %-*s | %s\n", "asset", "tool", "charts", "utilisation",
           "seconds", "peak MB", psnr_w, "PSNR (dB)", "seamless");
    for (int k = 0; k < NASSETS; k++) {
        if (!want[k]) continue;
        int pad = 12 - (int)strlen(assets[k].name);
        if (have_q[k]) {
            char s[96];
            const result *r = &quad[k];
            if (quad_seamless(r)) snprintf(s, sizeof s, "yes: mismatch 0, shared 0 at every level");
            else snprintf(s, sizeof s, "NO: mismatch %.0f, shared %.0f", r->mismatch, r->shared);
            print_row(assets[k].name, assets[k].texture_size, "quad", r, psnr_w, s);
        } else printf("%s %-*d | quad   | failed\n", assets[k].name, pad, assets[k].texture_size);
        if (have_x[k]) print_row(assets[k].name, assets[k].texture_size, "xatlas", &xa[k], psnr_w, "no");
        else if (xatlas) printf("%s %-*d | xatlas | failed\n", assets[k].name, pad, assets[k].texture_size);
        else printf("%-13s | xatlas | not installed\n", "");
    }

    for (int k = 0; k < NASSETS; k++) {
        if (!want[k] || !assets[k].targets) continue;
        printf("\nTargets, %s at %d^2 (quad%s):\n", assets[k].name, assets[k].texture_size,
               runs > 1 ? ", run of median time" : "");
        if (!have_q[k]) {
            printf("  FAIL: no measurement\n");
            continue;
        }
        const result *r = &quad[k];
        printf("  seconds      <= 10       %10.2f   %s\n", r->seconds, r->seconds <= 10 ? "PASS" : "FAIL");
        printf("  peak memory  <= 2 GB     %7.0f MB   %s\n", r->peak_mb, r->peak_mb <= 2048 ? "PASS" : "FAIL");
        printf("  charts       < 4,740     %10.0f   %s\n", r->charts, r->charts < 4740 ? "PASS" : "FAIL");
        double side = assets[k].texture_size, of_square = r->utilisation * r->width * r->height / (side * side);
        printf("  utilisation  >= 0.655    %10.4f   %s  (of the %dx%d atlas made; of %d^2: %.4f, %s)\n", r->utilisation,
               r->utilisation >= 0.655 ? "PASS" : "FAIL", r->width, r->height, assets[k].texture_size, of_square,
               of_square >= 0.655 ? "PASS" : "FAIL");
        printf("  shared texels 0 at every level (%d levels)   %s\n", r->nshared_levels,
               quad_seamless(r) ? "PASS" : "FAIL");
    }
    printf("\nColumns: charts = quads for quad (one square chart each), connected uv pieces for xatlas;\n"
           "utilisation = covered fraction of the atlas each tool made (quad: its packed width x height,\n"
           "at most the texture size; xatlas: rasterised, of its own atlas, which may exceed it);\n"
           "seconds = sc_quad_build / xatlas generateAtlas only (no load, no module start);\n"
           "peak MB = process peak resident memory (MiB) during the build, the loaded input included;\n"
           "xatlas: the node process's whole peak. PSNR: quad's surface PSNR per texture slot against\n"
           "the input; xatlas makes uv only. seamless: quad's boundary_mismatch and shared_texels at\n"
           "every mip level; xatlas's charts are ordinary uv seams.\n");
    free(corpus);
    return failed ? 1 : 0;
}
