/* sc_golden.c - expectations, golden images and golden metric files.
 *
 * Design note: a check reads only what a run left behind: the metrics in its
 * results and the files under --out. Image comparisons decode both PNGs, count
 * the pixels whose largest channel difference exceeds the threshold, and fail
 * when their share exceeds the allowed one; the diff picture shows those
 * pixels in red over a dimmed copy of the golden. Metric files are JSON
 * objects with sorted keys, written with exact round-trip numbers.
 */
#include "sc_golden.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include <cjson/cJSON.h>

#include "sc_imageio.h"

static const sc_node_result *result_of(const sc_run *r, const char *node) {
    for (int i = 0; i < r->graph->count; i++)
        if (strcmp(r->graph->nodes[i].name, node) == 0) return &r->results[i];
    return NULL;
}

static double metric_of(const sc_node_result *x, const char *metric, bool *found) {
    *found = false;
    cJSON *m = x && x->metrics_json ? cJSON_Parse(x->metrics_json) : NULL;
    const cJSON *v = cJSON_GetObjectItemCaseSensitive(m, metric);
    double value = NAN;
    if (cJSON_IsNumber(v)) value = v->valuedouble, *found = true;
    cJSON_Delete(m);
    return value;
}

/* goldens/<graph name>/ beside the graph file. */
static char *golden_dir(const sc_graph *g) {
    char *dir = sc_path_dirname(g->file);
    const char *base = strrchr(g->file, '/') ? strrchr(g->file, '/') + 1 : g->file;
    size_t len = strcspn(base, ".");
    char *out = dir ? sc_strprintf("%s/goldens/%.*s", dir, (int)len, base) : NULL;
    free(dir);
    return out;
}

static int write_bytes(const char *path, const void *p, size_t n, sc_error *err) {
    char *dir = sc_path_dirname(path);
    int rc = dir ? sc_make_dirs(dir, err) : sc_fail(err, SC_ENOMEM, "out of memory");
    free(dir);
    return rc == SC_OK ? sc_write_file_atomic(path, p, n, err) : rc;
}

/* ---------------------------------------------------------------- metrics */

static bool compare(double v, const char *op, double value, double tolerance) {
    if (!strcmp(op, "<")) return v < value;
    if (!strcmp(op, "<=")) return v <= value;
    if (!strcmp(op, "==")) return v == value;
    if (!strcmp(op, ">=")) return v >= value;
    if (!strcmp(op, ">")) return v > value;
    if (!strcmp(op, "~")) return fabs(v - value) <= tolerance;
    return false;
}

static int check_metric(const sc_run *r, const sc_expect *x, FILE *log) {
    bool found;
    double v = metric_of(result_of(r, x->node), x->metric, &found);
    if (found && compare(v, x->op, x->value, x->tolerance)) return 0;
    if (!found) {
        fprintf(log, "%s:%d: expectation failed: %s has no metric '%s'\n", x->file, x->line, x->node, x->metric);
    } else {
        char got[32], want[32], tol[32];
        sc_format_double(v, got);
        sc_format_double(x->value, want);
        sc_format_double(x->tolerance, tol);
        fprintf(log, "%s:%d: expectation failed: %s.%s = %s, expected %s %s%s%s\n", x->file, x->line, x->node,
                x->metric, got, x->op, want, !strcmp(x->op, "~") ? " within " : "", !strcmp(x->op, "~") ? tol : "");
    }
    return 1;
}

/* Timings (seconds, seconds_build, hausdorff_seconds...) are no goldens. */
static bool is_timing(const char *name) {
    const char *last = strrchr(name, '.');
    last = last ? last + 1 : name;
    return strstr(last, "seconds") != NULL;
}

static int check_metric_file(const sc_run *r, const sc_expect *x, const char *dir, bool update, FILE *log) {
    const sc_node_result *res = result_of(r, x->node);
    cJSON *now = res && res->metrics_json ? cJSON_Parse(res->metrics_json) : NULL;
    char *path = sc_strprintf("%s/%s.metrics.json", dir, x->node);
    sc_error err = {0};
    int failed = 0;
    if (!now || !path) {
        fprintf(log, "%s:%d: %s has no metrics\n", x->file, x->line, x->node);
        failed = 1;
    } else if (update) {
        /* sorted keys, timings left out, exact numbers */
        cJSON *sorted = cJSON_CreateObject();
        int n = cJSON_GetArraySize(now);
        const char **names = calloc((size_t)n + 1, sizeof *names);
        int k = 0;
        const cJSON *m;
        cJSON_ArrayForEach(m, now) if (!is_timing(m->string) && names) names[k++] = m->string;
        for (int a = 1; a < k; a++)
            for (int b = a; b > 0 && strcmp(names[b - 1], names[b]) > 0; b--) {
                const char *t = names[b];
                names[b] = names[b - 1], names[b - 1] = t;
            }
        for (int a = 0; a < k; a++)
            cJSON_AddItemToObject(sorted, names[a],
                                  cJSON_Duplicate(cJSON_GetObjectItemCaseSensitive(now, names[a]), 0));
        char *text = cJSON_Print(sorted);
        if (!text || write_bytes(path, text, strlen(text), &err) != SC_OK) {
            fprintf(log, "%s: %s\n", path, err.message);
            failed = 1;
        }
        free(text), free(names);
        cJSON_Delete(sorted);
    } else {
        sc_buf b;
        sc_buf_init(&b);
        cJSON *golden = sc_read_file(path, 1u << 26, &b, &err) == SC_OK ? cJSON_Parse((const char *)b.data) : NULL;
        sc_buf_free(&b);
        if (!golden) {
            fprintf(log, "%s:%d: no golden metrics at %s (run seamcook test --update-goldens)\n", x->file,
                    x->line, path);
            failed = 1;
        }
        const cJSON *g;
        cJSON_ArrayForEach(g, golden) {
            const cJSON *v = cJSON_GetObjectItemCaseSensitive(now, g->string);
            double want = cJSON_IsNumber(g) ? g->valuedouble : NAN;
            double have = cJSON_IsNumber(v) ? v->valuedouble : NAN;
            bool same = (isnan(want) && isnan(have) && (cJSON_IsNull(g) == cJSON_IsNull(v))) ||
                        fabs(have - want) <= x->tolerance * fmax(1.0, fabs(want));
            if (!same) {
                fprintf(log, "%s:%d: golden metric failed: %s.%s = %.17g, golden %.17g (relative tolerance %g; %s)\n",
                        x->file, x->line, x->node, g->string, have, want, x->tolerance, path);
                failed = 1;
            }
        }
        cJSON_Delete(golden);
    }
    cJSON_Delete(now);
    free(path);
    return failed;
}

/* ---------------------------------------------------------------- images */

static int decode_file(const char *path, sc_image_data **im, sc_error *err) {
    sc_buf b;
    sc_buf_init(&b);
    int rc = sc_read_file(path, 1u << 30, &b, err);
    if (rc == SC_OK) rc = sc_image_decode(path, b.data, b.len, im, err);
    sc_buf_free(&b);
    return rc;
}

/* Share of pixels whose largest channel difference exceeds threshold (in
 * 1/255 steps); fills a diff picture (RGB u8) when asked. */
static double differing_share(const sc_image_data *a, const sc_image_data *b, double threshold,
                              sc_image_data *diff) {
    int64_t n = (int64_t)a->width * a->height, bad = 0;
    int channels = a->channels < b->channels ? a->channels : b->channels;
    for (int32_t j = 0; j < a->height; j++)
        for (int32_t i = 0; i < a->width; i++) {
            double worst = 0;
            for (int c = 0; c < channels; c++) {
                double d = fabs((double)sc_image_texel(a, i, j, c) - (double)sc_image_texel(b, i, j, c)) * 255.0;
                if (d > worst) worst = d;
            }
            bool differs = worst > threshold;
            bad += differs;
            if (diff) {
                uint8_t *px = (uint8_t *)diff->pixels + 3 * ((size_t)j * a->width + i);
                uint8_t grey = (uint8_t)(64 + 0.25 * 255.0 * sc_image_texel(b, i, j, 0));
                px[0] = differs ? 255 : grey;
                px[1] = differs ? 0 : grey;
                px[2] = differs ? 0 : grey;
            }
        }
    return n ? (double)bad / (double)n : 0;
}

static char *flat_name(const char *path) {
    char *s = sc_strdup(path);
    for (char *c = s; c && *c; c++)
        if (*c == '/') *c = '_';
    return s;
}

static int check_image(const sc_expect *x, const char *out_dir, const char *dir, bool update, FILE *log) {
    char *made = sc_path_join(out_dir, x->metric);
    char *flat = flat_name(x->metric);
    char *golden = flat ? sc_strprintf("%s/%s/%s", dir, x->node, flat) : NULL;
    sc_error err = {0};
    int failed = 0;
    if (update) {
        sc_buf b;
        sc_buf_init(&b);
        if (!made || !golden || sc_read_file(made, 1u << 30, &b, &err) != SC_OK ||
            write_bytes(golden, b.data, b.len, &err) != SC_OK) {
            fprintf(log, "%s:%d: cannot update the golden image: %s\n", x->file, x->line, err.message);
            failed = 1;
        }
        sc_buf_free(&b);
    } else {
        sc_image_data *now = NULL, *want = NULL;
        if (decode_file(made, &now, &err) != SC_OK) {
            fprintf(log, "%s:%d: %s did not write %s: %s\n", x->file, x->line, x->node, x->metric, err.message);
            failed = 1;
        } else if (decode_file(golden, &want, &err) != SC_OK) {
            fprintf(log, "%s:%d: no golden image %s (run seamcook test --update-goldens): %s\n", x->file,
                    x->line, golden, err.message);
            failed = 1;
        } else if (now->width != want->width || now->height != want->height) {
            fprintf(log, "%s:%d: golden image failed: %s is %dx%d, golden %s is %dx%d\n", x->file, x->line,
                    x->metric, now->width, now->height, golden, want->width, want->height);
            failed = 1;
        } else {
            double share = differing_share(now, want, x->value, NULL);
            if (share > x->tolerance) {
                sc_image_data *diff = sc_image_alloc(now->width, now->height, 3, SC_PIXEL_U8);
                char *diff_path = sc_strprintf("%s/diff/%s/%s", out_dir, x->node, flat);
                sc_buf png;
                sc_buf_init(&png);
                if (diff) differing_share(now, want, x->value, diff);
                bool wrote = diff && diff_path && sc_image_encode_png(diff, 8, &png, &err) == SC_OK &&
                             write_bytes(diff_path, png.data, png.len, &err) == SC_OK;
                fprintf(log, "%s:%d: golden image failed: %s: %.4f%% of pixels differ by more than %g "
                        "(allowed %.4f%%); diff: %s\n", x->file, x->line, x->metric, 100 * share, x->value,
                        100 * x->tolerance, wrote ? diff_path : "(could not be written)");
                sc_buf_free(&png);
                sc_image_free(diff);
                free(diff_path);
                failed = 1;
            }
        }
        sc_image_free(now);
        sc_image_free(want);
    }
    free(made), free(flat), free(golden);
    return failed;
}

int sc_golden_check(const sc_run *run, const char *out_dir, bool update, FILE *log) {
    char *dir = golden_dir(run->graph);
    int failed = 0;
    for (int k = 0; k < run->graph->nexpect; k++) {
        const sc_expect *x = &run->graph->expects[k];
        if (!strcmp(x->op, "image")) failed += check_image(x, out_dir, dir, update, log);
        else if (!strcmp(x->op, "metrics")) failed += check_metric_file(run, x, dir, update, log);
        else failed += check_metric(run, x, log);
    }
    free(dir);
    return failed;
}
