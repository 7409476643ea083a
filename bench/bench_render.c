/* bench_render.c - how long the render check takes.
 *
 * Design note. The asset is blub from the shared corpus (load_atlas), cooked
 * the way graphs/lod_chain.lua cooks it: erase_seams, seam-aware decimation
 * at decimate's default ratios 0.5, 0.1 and 0.01, share_textures, then
 * bake_displacement at 1024^2 (a seam-free geometry image shared by every
 * level and a displacement map per level), so every mode has its texture and
 * the crack numbers are the pipeline's own. The input itself (with the
 * geometry image) is timed too. Without the corpus, the procedural asset
 * stands in (and the numbers say so).
 *
 * Reported:
 *   - per level and size (512^2, 1024^2): milliseconds per render (one view
 *     of one pass: draw + read back), PNG encoding per picture, the GPU seam
 *     gap check per pass, and the node's total;
 *   - the target run: all three levels, all modes (textured, geometry_image,
 *     displaced, tessellated 1/2/4/8), 10 views at 512^2 in one render call,
 *     against the 10 s budget.
 * Timings come from the node's seconds_* metrics and the wall clock around
 * sc_ctx_run; the target run is made twice and the faster kept. PNG encoding
 * runs on 2 worker threads (the node's threads = 2, this machine's cores);
 * the target is also timed with encoding inline (threads = 1).
 */
#include <stdio.h>
#include <sys/resource.h>
#include <stdlib.h>

#include "sc_base.h"
#include "sc_exec.h"
#include "sc_nodes.h"

extern const sc_node_desc sc_node_render;   /* nodes/render.c */

#define GI_SIZE 1024

/* Run node d on up to two inputs (port/value pairs, NULL for none) and return
 * output number `output` (and output 1 in *second when second is not NULL),
 * or NULL after printing why. */
static sc_value *run_node(const sc_node_desc *d, const char *const *params, const char *port, sc_value *input,
                          const char *port2, sc_value *input2, int output, sc_value **second, const char *what) {
    sc_ctx *ctx = sc_ctx_new(d, NULL, NULL);
    sc_error err;
    if (input) sc_ctx_set_input(ctx, port, input);
    if (input2) sc_ctx_set_input(ctx, port2, input2);
    sc_ctx_set_threads(ctx, 2);
    for (int i = 0; params && params[i]; i += 2)
        if (sc_ctx_set_param(ctx, params[i], params[i + 1], &err) != SC_OK) {
            fprintf(stderr, "%s: %s\n", what, err.message);
            sc_ctx_free(ctx);
            return NULL;
        }
    sc_value *out = NULL;
    if (sc_ctx_run(ctx, &err) == SC_OK) {
        out = sc_value_retain(sc_ctx_output(ctx, output));
        if (second) *second = sc_value_retain(sc_ctx_output(ctx, 1));
    } else fprintf(stderr, "%s: %s\n", what, err.message);
    sc_ctx_free(ctx);
    return out;
}


static double cpu_seconds(void) {
    struct rusage u;
    getrusage(RUSAGE_SELF, &u);
    return (double)u.ru_utime.tv_sec + 1e-6 * (double)u.ru_utime.tv_usec + (double)u.ru_stime.tv_sec +
           1e-6 * (double)u.ru_stime.tv_usec;
}

typedef struct timing {
    double wall, cpu, render, gap, encode, context;
    double renders, crack_pixels, max_seam_gap;
    int ok;
} timing;

static timing time_render(sc_value *lods, sc_value *atlas, const char *size, const char *views, int threads,
                          int reps) {
    timing best = {0};
    for (int rep = 0; rep < reps; rep++) {
        sc_ctx *ctx = sc_ctx_new(&sc_node_render, NULL, NULL);
        sc_error err;
        if (lods) sc_ctx_set_input(ctx, "lods", lods);
        if (atlas) sc_ctx_set_input(ctx, "atlas", atlas);
        sc_ctx_set_param(ctx, "size", size, &err);
        sc_ctx_set_param(ctx, "views", views, &err);
        sc_ctx_set_threads(ctx, threads);
        double t0 = sc_now(), c0 = cpu_seconds();
        int rc = sc_ctx_run(ctx, &err);
        timing t = {.wall = sc_now() - t0, .cpu = cpu_seconds() - c0, .ok = rc == SC_OK};
        if (rc != SC_OK) fprintf(stderr, "render: %s\n", err.message);
        t.render = sc_ctx_metric_value(ctx, "seconds_render");
        t.gap = sc_ctx_metric_value(ctx, "seconds_seam_gap");
        t.encode = sc_ctx_metric_value(ctx, "seconds_encode");
        t.context = sc_ctx_metric_value(ctx, "seconds_context");
        t.renders = sc_ctx_metric_value(ctx, "renders");
        t.crack_pixels = sc_ctx_metric_value(ctx, "crack_pixels");
        t.max_seam_gap = sc_ctx_metric_value(ctx, "max_seam_gap");
        sc_ctx_free(ctx);
        if (rep == 0 || t.wall < best.wall) best = t;
    }
    return best;
}

int main(int argc, char **argv) {
    sc_tune_allocator();   /* as the command line runs */
    setvbuf(stdout, NULL, _IOLBF, 0);
    char path[1024], texture[1024];
    const char *root = argc > 1 ? argv[1] : SC_SOURCE_DIR;
    snprintf(path, sizeof path, "%s/../shared/corpus/blub/blub.obj", root);
    snprintf(texture, sizeof texture, "%s/../shared/corpus/blub/blub_texture.png", root);
    FILE *probe = fopen(path, "rb");
    sc_value *atlas = NULL;
    const char *asset = "blub";
    if (probe) {
        fclose(probe);
        atlas = run_node(&sc_node_load_atlas, (const char *const[]){"path", path, "texture", texture, NULL}, NULL, NULL,
                         NULL, NULL, 0, NULL, "load_atlas");
    }
    if (!atlas) {
        asset = "procedural (corpus not found)";
        atlas = run_node(&sc_node_procedural, (const char *const[]){"resolution", "48", "texture_size", "1024", NULL},
                         NULL, NULL, NULL, NULL, 0, NULL, "procedural");
    }
    if (!atlas) return 1;
    /* lod_chain's maps: erased colour, seam-aware levels at decimate's default
     * ratios, a geometry image and a displacement map per level, seam-free */
    double t0 = sc_now();
    sc_value *erased = run_node(&sc_node_erase_seams, NULL, "atlas", atlas, NULL, NULL, 1, NULL, "erase_seams");
    double t_erase = sc_now() - t0;
    if (!erased) return 1;
    t0 = sc_now();
    sc_value *decimated = run_node(&sc_node_decimate, (const char *const[]){"ratio", "0.5,0.1,0.01", NULL}, "mesh",
                                   erased, NULL, NULL, 0, NULL, "decimate");
    double t_decimate = sc_now() - t0;
    sc_value *chain = decimated ? run_node(&sc_node_share_textures, NULL, "lods", decimated, "atlas", erased, 0,
                                           NULL, "share_textures")
                                : NULL;
    t0 = sc_now();
    char gi_size[16];
    snprintf(gi_size, sizeof gi_size, "%d", GI_SIZE);
    const char *bake_params[] = {"size", gi_size, NULL};
    sc_value *lods = NULL;
    sc_value *input = chain ? run_node(&sc_node_bake_displacement, bake_params, "atlas", erased, "lods", chain, 0,
                                       &lods, "bake_displacement")
                            : NULL;
    double t_bake = sc_now() - t0;
    if (!input || !lods || lods->as.lods->count != 3) {
        fprintf(stderr, "bench_render: could not make the three levels and their maps\n");
        return 1;
    }
    const sc_mesh *m = atlas->as.atlas->mesh->as.mesh;
    sc_value *const *levels = lods->as.lods->levels;
    const char *lod_source = "decimate 0.5, 0.1, 0.01 (lod_chain's levels)";

    printf("bench_render: asset %s, levels from %s\n", asset, lod_source);
    printf("  faces: input %d, levels %d, %d, %d\n", m->nf, levels[0]->as.atlas->mesh->as.mesh->nf,
           levels[1]->as.atlas->mesh->as.mesh->nf, levels[2]->as.atlas->mesh->as.mesh->nf);
    printf("  set-up (not part of the check): erase_seams %.2f s, decimate %.2f s, bake_displacement %d^2 %.2f s\n",
           t_erase, t_decimate, GI_SIZE, t_bake);
    printf("  passes per level: textured, geometry_image, displaced, tessellated 1/2/4/8 (7), 10 views each\n\n");
    printf("  %-5s %-6s %10s %10s %10s %10s %9s\n", "level", "size", "ms/render", "ms/png", "ms/gapchk",
           "total s", "cracks");
    const char *sizes[2] = {"512", "1024"};
    for (int s = 0; s < 2; s++)
        for (int k = -1; k < 3; k++) {
            timing t = time_render(NULL, k < 0 ? input : levels[k], sizes[s], "10", 2, 1);
            if (!t.ok) continue;
            if (k < 0) printf("  input %-6s %10.1f %10.1f %10.1f %10.2f %9.0f\n", sizes[s], 1e3 * t.render / t.renders,
                              1e3 * t.encode / (t.renders + 1), 1e3 * t.gap / 7, t.wall, t.crack_pixels);
            else printf("  lod%-2d %-6s %10.1f %10.1f %10.1f %10.2f %9.0f\n", k, sizes[s], 1e3 * t.render / t.renders,
                   1e3 * t.encode / (t.renders + 1), 1e3 * t.gap / 7, t.wall, t.crack_pixels);
        }
    timing all = time_render(lods, NULL, "512", "10", 2, 2);
    timing all1 = time_render(lods, NULL, "512", "10", 1, 1);
    printf("\n  target: 3 levels x all modes x 10 views at 512^2 in one call: %.2f s (budget 10 s) %s\n", all.wall,
           all.ok && all.wall <= 10 ? "OK" : "OVER");
    printf("    CPU time %.2f s (all threads: GL, llvmpipe, PNG workers)\n", all.cpu);
    printf("    with PNG encoding inline (threads = 1): %.2f s, CPU %.2f s\n", all1.wall, all1.cpu);
    printf("    renders %.0f: draw+readback %.2f s, png %.2f s, seam-gap checks %.2f s, context %.2f s\n",
           all.renders, all.render, all.encode, all.gap, all.context);
    printf("    crack_pixels %.0f, max_seam_gap %.3g (of the bbox diagonal)\n", all.crack_pixels, all.max_seam_gap);
    sc_value_release(lods);
    sc_value_release(input);
    sc_value_release(chain);
    sc_value_release(decimated);
    sc_value_release(erased);
    sc_value_release(atlas);
    return 0;
}
