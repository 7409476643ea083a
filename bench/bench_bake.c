/* bench_bake.c - bake_displacement and mipmap on the corpus.
 *
 *   bench_bake [-j N] [-r RUNS] [-m] [ASSET...]
 *
 * For blub (2048^2) and pizza (4096^2) from ../shared/corpus (or $SC_CORPUS):
 * load, decimate to three levels (0.5, 0.1, 0.01; not timed; with -m for
 * the maps: decimate's map_size = the bake size), then time
 * bake_displacement (one geometry image + one displacement map per level,
 * all erased) and mipmap on its levels (every chain, every level erased),
 * and print the reconstruction errors and the worst seam energy (pizza's
 * levels below 2048^2 are not erased: mipmap's erase_min_size).
 * With SC_BENCH_DIGESTS set, the digests of both nodes' outputs are printed
 * too (equal digests: equal bytes).
 * Target (issue 6): <= 5 s for blub's 2048^2 geometry image + 3
 * displacement maps + their mip chains. Each asset runs in a process of its
 * own; with -r, RUNS times, summed up as the median total, its range and in
 * how many runs the target was met (runs.h: why several).
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "sc_base.h"
#include "sc_exec.h"
#include "sc_nodes.h"
#include "runs.h"

extern const sc_node_desc sc_node_bake_displacement;
extern const sc_node_desc sc_node_mipmap;

typedef struct asset {
    const char *name, *model, *texture, *size;
    const char *mip_erase_min;   /* mipmap's erase_min_size */
    double target;               /* seconds bake + mipmap should take at most, or 0 */
} asset;

static const asset assets[] = {
    {"blub", "blub/blub.obj", "blub/blub_texture.png", "2048", "1", 5.0},
    /* pizza's 4,740 charts fall under a texel from 1024^2 on: levels below
     * 2048^2 are averaged, not erased (docs/notes/mipmap.md) */
    {"pizza", "pizza/pizza.obj", "pizza/pizza_gloss_map.jpg", "4096", "2048", 0},
};

/* CPU seconds of the whole process (every thread). */
static double cpu_now(void) {
    struct timespec ts;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static sc_ctx *run(const sc_node_desc *d, const char *const *params, const char *p0, sc_value *v0, const char *p1,
                   sc_value *v1, int threads, double *seconds, double *cpu_seconds) {
    sc_ctx *ctx = sc_ctx_new(d, NULL, NULL);
    sc_error err;
    for (int i = 0; params && params[i]; i += 2)
        if (sc_ctx_set_param(ctx, params[i], params[i + 1], &err) != SC_OK) fprintf(stderr, "%s\n", err.message);
    if (p0 && v0) sc_ctx_set_input(ctx, p0, v0);
    if (p1 && v1) sc_ctx_set_input(ctx, p1, v1);
    sc_ctx_set_threads(ctx, threads);
    double t0 = sc_now(), c0 = cpu_now();
    int rc = sc_ctx_run(ctx, &err);
    if (seconds) *seconds = sc_now() - t0;
    if (cpu_seconds) *cpu_seconds = cpu_now() - c0;
    if (rc != SC_OK) {
        fprintf(stderr, "%s: %s\n", d->type, err.message);
        sc_ctx_free(ctx);
        return NULL;
    }
    return ctx;
}

static double m(sc_ctx *ctx, const char *name) { return sc_ctx_metric_value(ctx, name); }

typedef struct run_args {
    const asset *as;
    const char *corpus;
    int threads;
    bool for_maps;   /* -m */
} run_args;

/* Loads and decimates the asset, times bake and mipmap, prints its lines;
 * their seconds go to `out` for the summary. */
static int run_asset(void *ud, int out) {
    const run_args *ra = ud;
    const asset *as = ra->as;
    int threads = ra->threads;
    char model[8400], tex[8400];
    snprintf(model, sizeof model, "%s/%s", ra->corpus, as->model);
    snprintf(tex, sizeof tex, "%s/%s", ra->corpus, as->texture);
    const char *lp[] = {"path", model, "texture", tex, NULL};
    sc_ctx *load = run(&sc_node_load_atlas, lp, NULL, NULL, NULL, NULL, threads, NULL, NULL);
    if (!load) {
        printf("%-6s skipped (corpus absent)\n", as->name);
        return 1;
    }
    sc_value *atlas = sc_ctx_output(load, 0);
    const char *dp[] = {"ratio", "0.5,0.1,0.01", "hausdorff_samples", "0", "map_size", ra->for_maps ? as->size : "0", NULL};
    sc_ctx *dec = run(&sc_node_decimate, dp, "mesh", atlas, NULL, NULL, threads, NULL, NULL);
    double t_bake = 0, t_mip = 0, c_bake = 0, c_mip = 0;
    const char *bp[] = {"size", as->size, NULL};
    sc_ctx *bake = dec ? run(&sc_node_bake_displacement, bp, "atlas", atlas, "lods", sc_ctx_output(dec, 0), threads,
                             &t_bake, &c_bake)
                       : NULL;
    sc_ctx *mip = NULL;
    if (bake) {
        /* the maps only: the levels' colour chains are not part of the target */
        const char *mp[] = {"erase_min_size", as->mip_erase_min, NULL};
        mip = run(&sc_node_mipmap, mp, "lods", sc_ctx_output(bake, 1), NULL, NULL, threads, &t_mip, &c_mip);
    }
    if (bake && mip)
        printf("%-6s %6s %8d %9.2f %9.2f %8.2f %12.3g %12.3g\n", as->name, as->size,
               atlas->as.atlas->mesh->as.mesh->nf, t_bake, t_mip, t_bake + t_mip, m(bake, "reconstruction_error"),
               m(mip, "seam_energy"));
    if (bake)
        printf("       bake: geometry image same-uv error max %.3g p99 %.3g rms %.3g, texels %.0f covered %.0f shared; "
               "raster %.2f s, fit %.2f s "
               "(sampling %.2f s: %.0f samples in %.0f cells, solve %.2f s: %.0f cells, %.0f iterations), erase "
               "%.2f s, metrics %.2f s\n",
               m(bake, "geometry_image_error"), m(bake, "geometry_image_error_p99"),
               m(bake, "geometry_image_error_rms"), m(bake, "texels_covered"), m(bake, "texels_shared"),
               m(bake, "seconds_raster"), m(bake, "seconds_fit"), m(bake, "seconds_fit_sample"), m(bake, "fit_samples"),
               m(bake, "fit_cells_inexact"), m(bake, "seconds_fit_solve"), m(bake, "fit_cells_solved"),
               m(bake, "fit_iterations"), m(bake, "seconds_erase"), m(bake, "seconds_metrics"));
    for (int k = 0; bake && k < 3; k++) {
        char n[6][80], faces[32];
        const char *suffix[6] = {"reconstruction_error", "reconstruction_error_to_input",
                                 "reconstruction_error_from_input", "same_uv_error", "same_uv_error_rms",
                                 "samples_missed"};
        for (int i = 0; i < 6; i++) snprintf(n[i], sizeof n[i], "lod%d.%s", k, suffix[i]);
        snprintf(faces, sizeof faces, "lod%d.faces", k);
        printf("       lod %d (%.0f faces): surface distance %.3g (to input %.3g, from input %.3g); same-uv error max "
               "%.3g rms %.3g (%.0f samples outside the level)\n",
               k, m(dec, faces), m(bake, n[0]), m(bake, n[1]), m(bake, n[2]), m(bake, n[3]), m(bake, n[4]),
               m(bake, n[5]));
    }
    if (mip)
        printf("       mipmap: groups %.2f s (side by side; summed over them: erase %.2f s in %.0f erase_seams runs, "
               "files %.2f s; %.0f level-0 maps kept as baked, %.0f map levels below erase_min_size %s not "
               "erased), metrics %.2f s\n",
               m(mip, "seconds_groups"), m(mip, "seconds_erase"), m(mip, "erase_runs"), m(mip, "seconds_files"),
               m(mip, "level0_passed"), m(mip, "levels_not_erased"), as->mip_erase_min, m(mip, "seconds_metrics"));
    if (mip) {
        printf("       lod 0 seam energy per mip level:");
        for (int level = 0;; level++) {   /* every level built, down to 1 x 1 */
            char n[64];
            snprintf(n, sizeof n, "lod0.level%d.seam_energy", level);
            double e = m(mip, n);
            if (isnan(e)) break;
            printf(" %.2g", e);
        }
        printf("\n");
    }
    if (bake && mip)
        printf("       cpu: bake %.2f s, mipmap %.2f s, total %.2f s (%d threads)\n", c_bake, c_mip, c_bake + c_mip,
               threads);
    if (bake && mip && getenv("SC_BENCH_DIGESTS")) {   /* to check that a change keeps the bytes */
        char h[65];
        for (int o = 0; o < 2; o++) {
            sc_digest_hex(sc_value_digest(sc_ctx_output(bake, o)), h);
            printf("       digest bake.%d %s\n", o, h);
        }
        for (int o = 0; o < 2; o++) {
            sc_digest_hex(sc_value_digest(sc_ctx_output(mip, o)), h);
            printf("       digest mipmap.%d %s\n", o, h);
        }
    }
    int rc = bake && mip ? bench_report_seconds(out, t_bake + t_mip) : 1;
    if (mip) sc_ctx_free(mip);
    if (bake) sc_ctx_free(bake);
    if (dec) sc_ctx_free(dec);
    sc_ctx_free(load);
    return rc;
}

int main(int argc, char **argv) {
    sc_tune_allocator();   /* as the command line runs */
    int threads = 2, runs = 1;
    bool for_maps = false;
    const char *only[8];
    int nonly = 0;
    for (int i = 1; i < argc; i++) {
        if (strcmp(argv[i], "-j") == 0 && i + 1 < argc) threads = atoi(argv[++i]);
        else if (strcmp(argv[i], "-r") == 0 && i + 1 < argc) runs = atoi(argv[++i]);
        else if (strcmp(argv[i], "-m") == 0) for_maps = true;
        else if (nonly < 8) only[nonly++] = argv[i];
    }
    if (runs < 1 || runs > 100) runs = 1;
    const char *corpus = getenv("SC_CORPUS");
    char def[4096];
    if (!corpus) {
        snprintf(def, sizeof def, "%s/../shared/corpus", SC_SOURCE_DIR);
        corpus = def;
    }
    printf("%-6s %6s %8s %9s %9s %8s %12s %12s\n", "asset", "size", "faces", "bake_s", "mipmap_s", "total_s",
           "recon_max", "mip_energy");
    int failed = 0;
    for (size_t a = 0; a < sizeof assets / sizeof assets[0]; a++) {
        const asset *as = &assets[a];
        bool want = nonly == 0;
        for (int i = 0; i < nonly; i++) want |= strcmp(only[i], as->name) == 0;
        if (!want) continue;
        double totals[100];
        int done = 0;
        for (int r = 0; r < runs; r++) {
            run_args ra = {as, corpus, threads, for_maps};
            if (bench_in_child(run_asset, &ra, &totals[done]) == 0) done++;
            else failed++;
        }
        bench_summary(as->name, "bake + mipmap", totals, done, as->target);
    }
    return failed ? 1 : 0;
}
