/* bench_decimate.c - the node `decimate` (seam_mode aware, fixed, free) and
 * meshoptimizer's meshopt_simplify, side by side in one run, on corpus assets
 * at 50%, 10% and 1% of their faces.
 *
 * Usage: bench_decimate [CORPUS_DIR] [asset,asset,...] [key=value ...]
 *   CORPUS_DIR defaults to ../shared/corpus next to the source tree; each
 *   key=value is passed to every decimate run (error_weight=0: the quadric
 *   alone, without error tracking), but methods=aware,straight, say, which
 *   runs only the methods named.
 *
 * Per asset: load it (load_atlas), erase its colour texture's seams
 * (erase_seams, f32 output), then for each target and method report
 *   faces       reached (target in the header)
 *   hausdorff   symmetric, sampled (sc_hausdorff, 200k samples a side), in %
 *               of the input's bounding-box diagonal
 *   seam E      seam energy (sc_seam_energy, Liu et al. eq. 9) of the ERASED
 *               texture on the level, relative to the energy of the ORIGINAL
 *               texture on the input ("floor": the erased texture on the input)
 *   uv off      the largest distance, in texels, from a point of the level's
 *               uv boundary to the input's uv boundary (0 when silhouettes
 *               are kept)
 *   seams cut   seam edges collapsed (decimate's metric; for meshoptimizer,
 *               input seam edges minus level seam edges)
 *   ms          wall time of the simplification alone (no metrics), best of
 *               REPEATS runs (three above 20k input faces), for every method
 *               alike: the machine's noise only ever adds
 * and aware's time over meshoptimizer's (from the unrounded times), and at
 * the end the largest such ratio over every asset and target.
 * Methods: aware, fixed and free on the erased atlas; "straight" is aware
 * after the straighten node (the path graphs/lod_chain.lua takes), its
 * seam energy measured with the straightened texture and its uv offset
 * against the straightened uv boundary (3D is unchanged, so Hausdorff is
 * against the input).
 * Decimate runs one target at a time from the input so times compare with the
 * peer's. meshopt_simplify gets the glTF-style vertex buffer (one vertex per
 * distinct position/uv pair), target_error = FLT_MAX so only the face count
 * stops it, options 0.
 */
#include <float.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "sc_base.h"
#include "sc_exec.h"
#include "sc_geometry.h"
#include "sc_hausdorff.h"
#include "sc_nodes.h"
#include "sc_seam.h"

#ifdef SC_HAVE_MESHOPT
#include <meshoptimizer.h>
#endif

#define REPEATS 5   /* timed runs per method and target; the best counts */

typedef struct asset {
    const char *name, *model, *texture;
} asset;

static const asset assets[] = {
    {"spot", "spot/spot_triangulated.obj", "spot/spot_texture.png"},
    {"blub", "blub/blub.obj", "blub/blub_texture.png"},
    {"BoomBox", "BoomBox/BoomBox.gltf", NULL},
    {"Lantern", "Lantern/Lantern_welded.obj", NULL},   /* the glTF names a texture the corpus lacks */
    {"pizza", "pizza/pizza.obj", "pizza/pizza_gloss_map.jpg"},
    {"Avocado", "Avocado/Avocado.gltf", NULL},
    {"Suzanne", "Suzanne/Suzanne.gltf", NULL},
};

static const double ratios[] = {0.5, 0.1, 0.01};

/* ---------------------------------------------------------------- running nodes */

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

/* ---------------------------------------------------------------- measures */

/* Seam energy of the colour texture of every material (summed). */
static double seam_energy(const sc_mesh *m, const sc_atlas *tex) {
    double total = 0;
    for (int32_t t = 0; t < tex->ntex; t++) {
        if (strcmp(tex->textures[t].name, "color") != 0) continue;
        const sc_image_data *img = tex->textures[t].image->as.image;
        sc_seam_grid g = {img->width, img->height, tex->textures[t].wrap_u, tex->textures[t].wrap_v};
        sc_seam_set set;
        sc_error err;
        if (sc_seam_find(m, tex->textures[t].material, &set, &err) != SC_OK) return NAN;
        double e = 0;
        if (set.nseams > 0 && sc_seam_energy(m, &set, &g, img, 2, &e, NULL, &err) != SC_OK) e = NAN;
        total += e;
        sc_seam_set_free(&set);
    }
    return total;
}

static int texture_side(const sc_atlas *tex) {
    int side = 0;
    for (int32_t t = 0; t < tex->ntex; t++) {
        const sc_image_data *img = tex->textures[t].image->as.image;
        if (img->width > side) side = img->width;
        if (img->height > side) side = img->height;
    }
    return side ? side : 1024;
}

typedef struct seg {
    double a[2], b[2];
} seg;

static int compare_pair(const void *x, const void *y) {
    const int64_t *a = x, *b = y;
    return a[0] < b[0] ? -1 : a[0] > b[0];
}

/* uv boundary segments: uv index pairs used by one face. */
static int64_t boundary_segments(const sc_mesh *m, seg **out) {
    int64_t n = (int64_t)m->nf * 3, count = 0;
    int64_t *keys = malloc(sizeof(int64_t) * 2 * (size_t)n);
    seg *s = malloc(sizeof(seg) * (size_t)n);
    for (int64_t i = 0; i < n; i++) {
        int64_t f = i / 3, k = i % 3;
        int64_t x = m->FU[3 * f + k], y = m->FU[3 * f + (k + 1) % 3];
        keys[2 * i] = x < y ? x * m->nu + y : y * m->nu + x;
        keys[2 * i + 1] = i;
    }
    qsort(keys, (size_t)n, 2 * sizeof(int64_t), compare_pair);
    for (int64_t i = 0; i < n;) {
        int64_t j = i;
        while (j < n && keys[2 * j] == keys[2 * i]) j++;
        if (j - i == 1) {
            int64_t key = keys[2 * i];
            int64_t x = key / m->nu, y = key % m->nu;
            memcpy(s[count].a, m->U + 2 * x, sizeof(double) * 2);
            memcpy(s[count].b, m->U + 2 * y, sizeof(double) * 2);
            count++;
        }
        i = j;
    }
    free(keys);
    *out = s;
    return count;
}

static double point_segment(const double p[2], const seg *s) {
    double d[2] = {s->b[0] - s->a[0], s->b[1] - s->a[1]};
    double l2 = d[0] * d[0] + d[1] * d[1];
    double t = l2 > 0 ? ((p[0] - s->a[0]) * d[0] + (p[1] - s->a[1]) * d[1]) / l2 : 0;
    t = t < 0 ? 0 : t > 1 ? 1 : t;
    return hypot(s->a[0] + t * d[0] - p[0], s->a[1] + t * d[1] - p[1]);
}

/* The largest distance from points of out's uv boundary (5 per edge) to in's
 * uv boundary, through a uniform grid over in's boundary segments. */
static double boundary_offset(const sc_mesh *in, const sc_mesh *out) {
    enum { G = 512 };
    seg *si, *so;
    int64_t ni = boundary_segments(in, &si), no = boundary_segments(out, &so);
    if (ni == 0 || no == 0) {
        free(si), free(so);
        return ni == no ? 0 : INFINITY;
    }
    double lo[2] = {INFINITY, INFINITY}, hi[2] = {-INFINITY, -INFINITY};
    for (int64_t i = 0; i < ni; i++)
        for (int k = 0; k < 2; k++) {
            lo[k] = fmin(lo[k], fmin(si[i].a[k], si[i].b[k]));
            hi[k] = fmax(hi[k], fmax(si[i].a[k], si[i].b[k]));
        }
    double cell[2] = {fmax(hi[0] - lo[0], 1e-9) / G, fmax(hi[1] - lo[1], 1e-9) / G};
    int *count = calloc(G * G + 1, sizeof(int));
    int pass;
    int *start = calloc(G * G + 1, sizeof(int)), *items = NULL;
    for (pass = 0; pass < 2; pass++) {
        if (pass == 1) {
            int acc = 0;
            for (int c = 0; c < G * G; c++) start[c] = acc, acc += count[c], count[c] = 0;
            start[G * G] = acc;
            items = malloc(sizeof(int) * (size_t)(acc + 1));
        }
        for (int64_t i = 0; i < ni; i++) {
            int r[4];
            for (int k = 0; k < 2; k++) {
                double a = (fmin(si[i].a[k], si[i].b[k]) - lo[k]) / cell[k], b = (fmax(si[i].a[k], si[i].b[k]) - lo[k]) / cell[k];
                r[2 * k] = a < 0 ? 0 : a >= G ? G - 1 : (int)a;
                r[2 * k + 1] = b < 0 ? 0 : b >= G ? G - 1 : (int)b;
            }
            for (int y = r[2]; y <= r[3]; y++)
                for (int x = r[0]; x <= r[1]; x++) {
                    if (pass == 1) items[start[y * G + x] + count[y * G + x]] = (int)i;
                    count[y * G + x]++;
                }
        }
    }
    double worst = 0;
    for (int64_t i = 0; i < no; i++)
        for (int k = 0; k <= 4; k++) {
            double t = k / 4.0, p[2] = {so[i].a[0] + t * (so[i].b[0] - so[i].a[0]), so[i].a[1] + t * (so[i].b[1] - so[i].a[1])};
            int cx = (int)((p[0] - lo[0]) / cell[0]), cy = (int)((p[1] - lo[1]) / cell[1]);
            double best = INFINITY;
            for (int ring = 0; ring < G; ring++) {
                for (int y = cy - ring; y <= cy + ring; y++)
                    for (int x = cx - ring; x <= cx + ring; x++) {
                        if (x < 0 || y < 0 || x >= G || y >= G) continue;
                        if (ring > 0 && y != cy - ring && y != cy + ring && x != cx - ring && x != cx + ring) continue;
                        for (int j = start[y * G + x]; j < start[y * G + x + 1]; j++) best = fmin(best, point_segment(p, &si[items[j]]));
                    }
                if (best <= ring * fmin(cell[0], cell[1])) break;
            }
            worst = fmax(worst, best);
        }
    free(count), free(start), free(items), free(si), free(so);
    return worst;
}

static int64_t count_seams(const sc_mesh *m) {
    sc_seam_set set;
    sc_error err;
    if (sc_seam_find(m, -1, &set, &err) != SC_OK) return -1;
    int64_t n = set.nseams;
    sc_seam_set_free(&set);
    return n;
}

static double hausdorff(const sc_mesh *a, const sc_mesh *b) {
    sc_hausdorff_mesh ma = {a->V, a->nv, a->FV, a->nf}, mb = {b->V, b->nv, b->FV, b->nf};
    sc_hausdorff_result r;
    sc_error err;
    if (sc_hausdorff(&ma, &mb, 200000, 2, &r, &err) != SC_OK) return NAN;
    return r.distance / sc_bbox_diagonal(a->V, a->nv, a->FV, a->nf);
}

/* ---------------------------------------------------------------- meshoptimizer */

#ifdef SC_HAVE_MESHOPT
/* meshopt_simplify on the glTF-style vertex buffer; returns a new mesh. */
static sc_mesh *meshopt_level(const sc_mesh *in, int64_t target, double *seconds) {
    /* one vertex per distinct (position, uv) index pair */
    int64_t corners = (int64_t)in->nf * 3;
    int64_t *pairs = malloc(sizeof(int64_t) * 2 * (size_t)corners);
    for (int64_t i = 0; i < corners; i++) pairs[2 * i] = (int64_t)in->FV[i] * in->nu + in->FU[i], pairs[2 * i + 1] = i;
    qsort(pairs, (size_t)corners, 2 * sizeof(int64_t), compare_pair);
    unsigned *index = malloc(sizeof(unsigned) * (size_t)corners);
    float *pos = malloc(sizeof(float) * 3 * (size_t)corners);
    int64_t *key_of = malloc(sizeof(int64_t) * (size_t)corners);
    size_t nvert = 0;
    for (int64_t i = 0; i < corners; i++) {
        if (i == 0 || pairs[2 * i] != pairs[2 * i - 2]) {
            int64_t v = pairs[2 * i] / in->nu;
            for (int k = 0; k < 3; k++) pos[3 * nvert + k] = (float)in->V[3 * v + k];
            key_of[nvert] = pairs[2 * i];
            nvert++;
        }
        index[pairs[2 * i + 1]] = (unsigned)(nvert - 1);
    }
    unsigned *dest = malloc(sizeof(unsigned) * (size_t)corners);
    size_t got = 0;
    double best = INFINITY;
    for (int rep = 0; rep < REPEATS; rep++) {
        double t0 = sc_now();
        got = meshopt_simplify(dest, index, (size_t)corners, pos, nvert, sizeof(float) * 3, (size_t)target * 3, FLT_MAX,
                               0, NULL);
        best = fmin(best, sc_now() - t0);
    }
    *seconds = best;
    int32_t nf = (int32_t)(got / 3);
    sc_mesh *m = sc_mesh_alloc(in->nv, in->nu, 0, nf > 0 ? nf : 1, in->nmat);
    for (int32_t i = 0; i < in->nmat; i++) m->materials[i] = sc_strdup(in->materials[i]);
    memcpy(m->V, in->V, sizeof(double) * 3 * (size_t)in->nv);
    memcpy(m->U, in->U, sizeof(double) * 2 * (size_t)in->nu);
    m->nf = nf;
    for (size_t i = 0; i < got; i++) {
        int64_t key = key_of[dest[i]];
        m->FV[i] = (int32_t)(key / in->nu);
        m->FU[i] = (int32_t)(key % in->nu);
    }
    for (int32_t f = 0; f < nf; f++) m->FM[f] = 0;
    free(pairs), free(index), free(pos), free(key_of), free(dest);
    return m;
}
#endif

/* ---------------------------------------------------------------- report */

static void row(const char *method, const sc_mesh *in, const sc_mesh *lod, const sc_atlas *erased, double e0,
                int side, double seams_cut, double seconds) {
    double hd = hausdorff(in, lod);
    double e = erased ? seam_energy(lod, erased) : NAN;
    double off = boundary_offset(in, lod) * side;
    printf("  %-10s %8d %9.3f%% %11.3g %10.3g %9.0f %9.2f\n", method, lod->nf, 100 * hd, e / e0, off, seams_cut,
           1e3 * seconds);
    fflush(stdout);
}

int main(int argc, char **argv) {
    sc_tune_allocator();   /* as the command line runs */
    const char *corpus = argc > 1 ? argv[1] : SC_SOURCE_DIR "/../shared/corpus";
    const char *only = argc > 2 ? argv[2] : NULL;
    /* decimate parameters from the command line, after the method's own */
    enum { MAX_EXTRA = 16 };
    char *extra[2 * MAX_EXTRA + 1] = {NULL};
    int nextra = 0;
    const char *methods = NULL;
    for (int i = 3; i < argc && nextra < 2 * MAX_EXTRA; i++) {
        char *eq = strchr(argv[i], '=');
        if (!eq) {
            fprintf(stderr, "bench_decimate: %s is not key=value\n", argv[i]);
            return 2;
        }
        *eq = 0;
        if (!strcmp(argv[i], "methods")) {   /* the bench's own: which methods run */
            methods = eq + 1;
            continue;
        }
        extra[nextra++] = argv[i];
        extra[nextra++] = eq + 1;
        printf("decimate %s = %s\n", argv[i], eq + 1);
    }
#ifdef SC_HAVE_MESHOPT
    printf("decimate vs meshoptimizer %d.%d (meshopt_simplify, options 0)\n", MESHOPTIMIZER_VERSION / 1000,
           MESHOPTIMIZER_VERSION % 1000 / 10);
#else
    printf("decimate (meshoptimizer not found at build time: no peer column)\n");
#endif
    printf("corpus: %s\n", corpus);
    double worst_ratio = 0;   /* aware against meshopt, over every asset and target */
    char worst_at[96] = "";
    for (size_t a = 0; a < sizeof assets / sizeof assets[0]; a++) {
        if (only && !strstr(only, assets[a].name)) continue;
        char path[4096], tex[4096];
        snprintf(path, sizeof path, "%s/%s", corpus, assets[a].model);
        snprintf(tex, sizeof tex, "%s/%s", corpus, assets[a].texture ? assets[a].texture : "");
        const char *load_kv[] = {"path", path, "slots", "color", "texture", tex, NULL};
        if (!assets[a].texture) load_kv[4] = NULL;
        sc_error err = {0};
        sc_ctx *load = run(&sc_node_load_atlas, load_kv, NULL, NULL, &err);
        if (!load) {
            printf("%s: skipped (%s)\n", assets[a].name, err.message);
            continue;
        }
        sc_value *atlas = sc_ctx_output(load, 0);
        const sc_mesh *in = atlas->as.atlas->mesh->as.mesh;
        int side = texture_side(atlas->as.atlas);
        double t0 = sc_now();
        const char *erase_kv[] = {"textures", "color", NULL};
        sc_ctx *erase = run(&sc_node_erase_seams, erase_kv, "atlas", atlas, &err);
        double erase_seconds = sc_now() - t0;
        const sc_atlas *erased = erase ? sc_ctx_output(erase, 0)->as.atlas : NULL;
        double e0 = seam_energy(in, atlas->as.atlas);
        double floor_e = erased ? seam_energy(in, erased) : NAN;
        /* the pipeline's own path: erase_seams -> straighten -> decimate */
        sc_ctx *straight = erase ? run(&sc_node_straighten, NULL, "atlas", sc_ctx_output(erase, 0), &err) : NULL;
        sc_value *straight_atlas = straight ? sc_ctx_output(straight, 0) : NULL;
        int64_t seams_in = count_seams(in);
        printf("\n%s: %d faces, %lld seam edges, texture %d; seam energy %.3g, erased %.3g (floor %.3g relative; "
               "erase_seams %.1f s%s%s)\n",
               assets[a].name, in->nf, (long long)seams_in, side, e0, floor_e, floor_e / e0, erase_seconds,
               erase ? "" : ": ", erase ? "" : err.message);
        for (size_t r = 0; r < sizeof ratios / sizeof ratios[0]; r++) {
            int64_t target = llround(ratios[r] * in->nf);
            double aware_seconds = INFINITY;
            char faces[32];
            snprintf(faces, sizeof faces, "%lld", (long long)target);
            printf(" %g%% -> %lld faces\n  %-10s %8s %10s %11s %10s %9s %9s\n", 100 * ratios[r], (long long)target,
                   "method", "faces", "hausdorff", "seam E", "uv off", "seams cut", "ms");
            /* aware, fixed and free on the erased atlas; "straight" is aware
             * on the straightened one, measured against it */
            static const char *const names[] = {"aware", "fixed", "free", "straight"};
            static const char *const modes[] = {"aware", "fixed", "free", "aware"};
            for (int mo = 0; mo < 4; mo++) {
                sc_value *source = mo < 3 ? atlas : straight_atlas;
                if (!source || (methods && !strstr(methods, names[mo]))) continue;
                const sc_atlas *ref = mo < 3 ? erased : straight_atlas->as.atlas;
                const char *kv[8 + 2 * MAX_EXTRA + 1] = {"faces", faces, "seam_mode", modes[mo], "hausdorff_samples", "0"};
                for (int i = 0; i <= nextra; i++) kv[6 + i] = extra[i];
                sc_ctx *best = NULL;
                double best_seconds = INFINITY;
                for (int rep = 0; rep < (in->nf > 20000 ? 3 : REPEATS); rep++) {
                    t0 = sc_now();
                    sc_ctx *ctx = run(&sc_node_decimate, kv, "mesh", source, &err);
                    double s = sc_now() - t0;
                    if (!ctx) break;
                    if (s < best_seconds) {
                        sc_ctx_free(best);
                        best = ctx, best_seconds = s;
                    } else {
                        sc_ctx_free(ctx);
                    }
                }
                if (!best) {
                    printf("  %-10s failed: %s\n", names[mo], err.message);
                    continue;
                }
                const sc_mesh *lod = sc_ctx_output(best, 0)->as.lods->levels[0]->as.atlas->mesh->as.mesh;
                row(names[mo], mo < 3 ? in : ref->mesh->as.mesh, lod, ref, e0, side,
                    sc_ctx_metric_value(best, "lod0.seam_edges_collapsed"), best_seconds);
                if (mo == 0) aware_seconds = best_seconds;
                if (lod->nf > target) {
                    printf("  %-10s stopped at %d faces; blocked edges:", "", lod->nf);
                    for (int i = 0; i < sc_ctx_nmetrics(best); i++) {
                        const sc_metric *m = &sc_ctx_metrics(best)[i];
                        if (!strncmp(m->name, "lod0.blocked_", 13)) printf(" %s %g", m->name + 13, m->value);
                    }
                    printf("\n");
                }
                sc_ctx_free(best);
            }
#ifdef SC_HAVE_MESHOPT
            double seconds;
            sc_mesh *mo_lod = meshopt_level(in, target, &seconds);
            row("meshopt", in, mo_lod, erased, e0, side, (double)(seams_in - count_seams(mo_lod)), seconds);
            sc_mesh_free(mo_lod);
            if (isfinite(aware_seconds) && seconds > 0) {   /* from the unrounded best times */
                double ratio = aware_seconds / seconds;
                printf("  aware / meshopt: %.1fx\n", ratio);
                if (ratio > worst_ratio) {
                    worst_ratio = ratio;
                    snprintf(worst_at, sizeof worst_at, "%s at %g%%", assets[a].name, 100 * ratios[r]);
                }
            }
#endif
        }
        sc_ctx_free(straight);
        sc_ctx_free(erase);
        sc_ctx_free(load);
    }
    if (worst_ratio > 0) printf("\nworst aware / meshopt: %.1fx (%s)\n", worst_ratio, worst_at);
    return 0;
}
