/* sc_report.c - report.json, report.html, the --json summary and JUnit XML.
 *
 * Design note: each is a view of what it is given (a run, or the outcomes of
 * graph tests) and nothing else; none reads the cache or the files. The HTML
 * page works from conventions only, so it needs no knowledge of any node:
 * the files the render node writes (render/lod<k>_sheet.png,
 * render/reference_sheet.png, render/lod<k>_<mode>_<view>.png) and the
 * metrics nodes report per level (lod<k>.faces, .target_faces, .hausdorff,
 * .seconds, render's lod<k>.crack_pixels, .fold_pixels, .max_seam_gap, and
 * mipmap's lod<k>.level<m>.seam_energy). It has no scripts and no remote
 * content; its plots are inline SVG.
 */
#include "sc_report.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include <cjson/cJSON.h>

static void hexof(const sc_digest *d, char out[65]) { sc_digest_hex(d, out); }

/* Text as XML or HTML character data or attribute value: the five escapes,
 * and control characters XML 1.0 cannot hold as spaces. */
static void markup_text(sc_buf *b, const char *s) {
    for (; *s; s++) {
        switch (*s) {
        case '<': sc_buf_puts(b, "&lt;"); break;
        case '>': sc_buf_puts(b, "&gt;"); break;
        case '&': sc_buf_puts(b, "&amp;"); break;
        case '"': sc_buf_puts(b, "&quot;"); break;
        case '\'': sc_buf_puts(b, "&apos;"); break;
        default: sc_buf_u8(b, (unsigned char)*s < 0x20 && *s != '\n' && *s != '\t' ? ' ' : (uint8_t)*s);
        }
    }
}

/* The content of report.json, as a tree. */
static cJSON *report_object(const sc_run *r) {
    const sc_graph *g = r->graph;
    cJSON *root = cJSON_CreateObject();
    cJSON_AddStringToObject(root, "graph", g->file);
    cJSON_AddNumberToObject(root, "seconds", r->seconds);
    cJSON *tot = cJSON_AddObjectToObject(root, "totals");
    cJSON_AddNumberToObject(tot, "nodes", g->count);
    cJSON_AddNumberToObject(tot, "ran", r->ran);
    cJSON_AddNumberToObject(tot, "cached", r->cached);
    cJSON_AddNumberToObject(tot, "failed", r->failed);
    cJSON_AddNumberToObject(tot, "skipped", r->skipped);
    int warnings = 0;
    for (int i = 0; i < g->count; i++) warnings += r->results[i].nwarnings;
    cJSON_AddNumberToObject(tot, "warnings", warnings);
    cJSON *nodes = cJSON_AddArrayToObject(root, "nodes");
    for (int i = 0; i < g->count; i++) {
        const sc_graph_node *n = &g->nodes[i];
        const sc_node_result *x = &r->results[i];
        cJSON *o = cJSON_CreateObject();
        char hex[65];
        cJSON_AddStringToObject(o, "name", n->name);
        cJSON_AddStringToObject(o, "type", n->desc->type);
        cJSON_AddNumberToObject(o, "version", n->desc->version);
        char *where = sc_strprintf("%s:%d", n->file, n->line);
        cJSON_AddStringToObject(o, "where", where ? where : "");
        free(where);
        cJSON_AddStringToObject(o, "status", sc_status_name(x->status));
        if (x->status == SC_STATUS_CACHED || x->status == SC_STATUS_RAN ||
            x->status == SC_STATUS_WOULD_RUN || x->status == SC_STATUS_FAILED) {
            hexof(&x->key, hex);
            if (!sc_digest_is_zero(&x->key)) cJSON_AddStringToObject(o, "key", hex);
        }
        cJSON_AddBoolToObject(o, "cached", x->status == SC_STATUS_CACHED);
        cJSON_AddNumberToObject(o, "seconds", x->seconds);
        if (x->status == SC_STATUS_CACHED) cJSON_AddNumberToObject(o, "cooked_seconds", x->cooked_seconds);
        cJSON *metrics = x->metrics_json ? cJSON_Parse(x->metrics_json) : NULL;
        cJSON_AddItemToObject(o, "metrics", metrics ? metrics : cJSON_CreateObject());
        cJSON *outs = cJSON_AddArrayToObject(o, "outputs");
        for (int k = 0; k < x->noutputs; k++) {
            if (x->status != SC_STATUS_CACHED && x->status != SC_STATUS_RAN) break;
            cJSON *po = cJSON_CreateObject();
            cJSON_AddStringToObject(po, "port", n->desc->outputs[k].name);
            cJSON_AddStringToObject(po, "kind", sc_kind_name(x->outputs[k].kind));
            hexof(&x->outputs[k].digest, hex);
            cJSON_AddStringToObject(po, "digest", hex);
            cJSON_AddItemToArray(outs, po);
        }
        cJSON *files = cJSON_AddArrayToObject(o, "files");
        for (int f = 0; f < x->nfiles; f++) cJSON_AddItemToArray(files, cJSON_CreateString(x->files[f]));
        if (x->ndeps) {
            cJSON *deps = cJSON_AddArrayToObject(o, "reads");
            for (int d = 0; d < x->ndeps; d++) cJSON_AddItemToArray(deps, cJSON_CreateString(x->deps[d]));
        }
        if (x->nwarnings) {
            cJSON *w = cJSON_AddArrayToObject(o, "warnings");
            for (int k = 0; k < x->nwarnings; k++) cJSON_AddItemToArray(w, cJSON_CreateString(x->warnings[k]));
        }
        if (x->why) cJSON_AddStringToObject(o, "why", x->why);
        if (x->error) cJSON_AddStringToObject(o, "error", x->error);
        cJSON_AddItemToArray(nodes, o);
    }
    return root;
}

char *sc_run_report_json(const sc_run *r) {
    cJSON *root = report_object(r);
    char *s = cJSON_Print(root);
    cJSON_Delete(root);
    return s;
}

char *sc_run_summary_json(const char *graph, const sc_run *r, int exit_status, const char *error) {
    cJSON *root = r ? report_object(r) : cJSON_CreateObject();
    if (!r) {
        cJSON_AddStringToObject(root, "graph", graph);
        cJSON_AddArrayToObject(root, "nodes");
    }
    cJSON_AddNumberToObject(root, "exit_status", exit_status);
    if (error && *error) cJSON_AddStringToObject(root, "error", error);
    char *s = cJSON_Print(root);
    cJSON_Delete(root);
    return s;
}

/* ---------------------------------------------------------------- JUnit */

char *sc_junit_xml(const sc_test_case *cases, int n) {
    int failures = 0;
    double seconds = 0;
    for (int i = 0; i < n; i++) failures += cases[i].failure != NULL, seconds += cases[i].seconds;
    sc_buf b;
    sc_buf_init(&b);
    sc_buf_printf(&b, "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n"
                      "<testsuites tests=\"%d\" failures=\"%d\" time=\"%.3f\">\n"
                      "  <testsuite name=\"seamcook\" tests=\"%d\" failures=\"%d\" errors=\"0\" time=\"%.3f\">\n",
                  n, failures, seconds, n, failures, seconds);
    for (int i = 0; i < n; i++) {
        sc_buf_puts(&b, "    <testcase classname=\"seamcook\" name=\"");
        markup_text(&b, cases[i].name);
        sc_buf_printf(&b, "\" time=\"%.3f\"", cases[i].seconds);
        if (!cases[i].failure) {
            sc_buf_puts(&b, "/>\n");
            continue;
        }
        /* the attribute holds the first line, the element all of it */
        size_t first = strcspn(cases[i].failure, "\n");
        char *line = sc_strndup(cases[i].failure, first);
        sc_buf_puts(&b, ">\n      <failure message=\"");
        markup_text(&b, line ? line : "");
        sc_buf_puts(&b, "\">");
        markup_text(&b, cases[i].failure);
        sc_buf_puts(&b, "</failure>\n    </testcase>\n");
        free(line);
    }
    sc_buf_puts(&b, "  </testsuite>\n</testsuites>\n");
    return sc_buf_take_string(&b);
}

/* ---------------------------------------------------------------- report.html */

/* A picture linked to itself, with a caption. */
static void figure(sc_buf *b, const char *file, const char *caption) {
    sc_buf_puts(b, "<figure><a href=\"");
    markup_text(b, file);
    sc_buf_puts(b, "\"><img src=\"");
    markup_text(b, file);
    sc_buf_puts(b, "\" alt=\"");
    markup_text(b, file);
    sc_buf_puts(b, "\"></a><figcaption>");
    markup_text(b, caption);
    sc_buf_puts(b, "</figcaption></figure>\n");
}

static void html_metrics(sc_buf *b, const cJSON *metrics, const char *prefix) {
    size_t pl = prefix ? strlen(prefix) : 0;
    int shown = 0;
    const cJSON *m;
    cJSON_ArrayForEach(m, metrics) {
        if (prefix && strncmp(m->string, prefix, pl) != 0) continue;
        if (!shown++) sc_buf_puts(b, "<table class=\"metrics\">\n");
        sc_buf_puts(b, "<tr><td>");
        markup_text(b, m->string + pl);
        if (cJSON_IsNumber(m)) sc_buf_printf(b, "</td><td>%.6g</td></tr>\n", m->valuedouble);
        else sc_buf_puts(b, "</td><td>&mdash;</td></tr>\n");
    }
    if (shown) sc_buf_puts(b, "</table>\n");
}

/* The level number of a file "render/lod<k>_..." or -1. */
static int lod_of_file(const char *path) {
    const char *base = strrchr(path, '/');
    base = base ? base + 1 : path;
    if (strncmp(base, "lod", 3) != 0) return -1;
    char *end;
    long k = strtol(base + 3, &end, 10);
    return (end != base + 3 && *end == '_') ? (int)k : -1;
}

static bool is_png(const char *path) {
    size_t n = strlen(path);
    return n > 4 && strcmp(path + n - 4, ".png") == 0;
}

/* Every node's metrics, parsed once (an entry may be NULL). */
typedef struct run_metrics {
    int count;
    cJSON **of;
} run_metrics;

static run_metrics metrics_of_run(const sc_run *r) {
    run_metrics m = {r->graph->count, calloc((size_t)r->graph->count + 1, sizeof(cJSON *))};
    for (int i = 0; m.of && i < m.count; i++)
        m.of[i] = r->results[i].metrics_json ? cJSON_Parse(r->results[i].metrics_json) : NULL;
    return m;
}

static void run_metrics_free(run_metrics *m) {
    for (int i = 0; m->of && i < m->count; i++) cJSON_Delete(m->of[i]);
    free(m->of);
}

/* The metric `name` of node `node` (-1: the first node that has it), or NaN. */
static double metric_value(const run_metrics *m, int node, const char *name) {
    for (int i = node < 0 ? 0 : node; m->of && i < (node < 0 ? m->count : node + 1); i++) {
        const cJSON *x = cJSON_GetObjectItemCaseSensitive(m->of[i], name);
        if (cJSON_IsNumber(x)) return x->valuedouble;
    }
    return NAN;
}

static double metricf_value(const run_metrics *m, int node, const char *fmt, int a, int b) {
    char name[96];
    snprintf(name, sizeof name, fmt, a, b);
    return metric_value(m, node, name);
}

/* The file of node i named exactly `name` relative to its folder
 * ("lod1_sheet.png" matches "render/lod1_sheet.png"), or NULL. */
static const char *file_named(const sc_node_result *x, const char *name) {
    for (int f = 0; f < x->nfiles; f++) {
        const char *base = strrchr(x->files[f], '/');
        if (strcmp(base ? base + 1 : x->files[f], name) == 0) return x->files[f];
    }
    return NULL;
}

static void number_cell(sc_buf *b, double v, const char *fmt) {
    if (v == v) {
        sc_buf_puts(b, "<td>");
        sc_buf_printf(b, fmt, v);
        sc_buf_puts(b, "</td>");
    } else {
        sc_buf_puts(b, "<td>&mdash;</td>");
    }
}

/* The first screen: per render node that drew levels of detail, its
 * reference's views above each level's, cracks and folds marked in them,
 * and one row of numbers per level. */
static void lod_overview(sc_buf *b, const sc_run *r, const run_metrics *m) {
    const sc_graph *g = r->graph;
    for (int i = 0; i < g->count; i++) {
        const sc_node_result *x = &r->results[i];
        if (!file_named(x, "lod0_sheet.png")) continue;
        sc_buf_puts(b, "<section class=\"overview\"><h2>Levels of detail <small>(");
        markup_text(b, g->nodes[i].name);
        sc_buf_puts(b, ": yellow marks crack pixels, cyan marks folds)</small></h2>\n<table class=\"levels\">\n");
        const char *ref = file_named(x, "reference_sheet.png");
        if (ref) {
            sc_buf_puts(b, "<tr><th>reference</th><td colspan=\"7\"><img class=\"sheet\" src=\"");
            markup_text(b, ref);
            sc_buf_puts(b, "\" alt=\"reference\"></td></tr>\n");
        }
        sc_buf_puts(b, "<tr><th>level</th><th>faces / target</th><th>Hausdorff</th><th>seam gap</th>"
                       "<th>cracks</th><th>folds</th><th>seconds</th><th></th></tr>\n");
        for (int k = 0;; k++) {
            char sheet[48];
            snprintf(sheet, sizeof sheet, "lod%d_sheet.png", k);
            const char *file = file_named(x, sheet);
            if (!file) break;
            double faces = metricf_value(m, -1, "lod%d.faces", k, 0);
            double target = metricf_value(m, -1, "lod%d.target_faces", k, 0);
            double cracks = metricf_value(m, i, "lod%d.crack_pixels", k, 0);
            double folds = metricf_value(m, i, "lod%d.fold_pixels", k, 0);
            sc_buf_printf(b, "<tr class=\"numbers%s\"><th>LOD %d</th>", cracks > 0 ? " bad" : "", k);
            if (faces == faces && target == target)
                sc_buf_printf(b, "<td>%.0f / %.0f</td>", faces, target);
            else
                number_cell(b, faces, "%.0f");
            double hd = metricf_value(m, -1, "lod%d.hausdorff", k, 0);
            number_cell(b, hd == hd ? 100 * hd : hd, "%.3g%%");
            number_cell(b, metricf_value(m, i, "lod%d.max_seam_gap", k, 0), "%.3g");
            number_cell(b, cracks, "%.0f");
            number_cell(b, folds, "%.0f");
            number_cell(b, metricf_value(m, -1, "lod%d.seconds", k, 0), "%.3f");
            char uv[48];
            snprintf(uv, sizeof uv, "lod%d_uv.png", k);
            const char *uvfile = file_named(x, uv);
            sc_buf_puts(b, "<td>");
            if (uvfile) {
                sc_buf_puts(b, "<a href=\"");
                markup_text(b, uvfile);
                sc_buf_puts(b, "\">uv</a>");
            }
            sc_buf_puts(b, "</td></tr>\n<tr><th></th><td colspan=\"7\"><a href=\"");
            markup_text(b, file);
            sc_buf_puts(b, "\"><img class=\"sheet\" src=\"");
            markup_text(b, file);
            sc_buf_printf(b, "\" alt=\"LOD %d\"></a></td></tr>\n", k);
        }
        sc_buf_puts(b, "</table></section>\n");
    }
}

/* ---------------------------------------------------------------- plots */

typedef struct series {
    char name[32];
    int n;
    double x[64], y[64];
} series;

static const char *const plot_colours[] = {"#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b"};

/* An inline SVG line plot of a few series; y (and x with log_x) on a log10
 * axis when asked. Points must be finite (and positive on a log axis). */
static void svg_plot(sc_buf *b, const char *title, const char *xlabel, const char *ylabel, const series *s,
                     int ns, bool log_x, bool log_y) {
    const double W = 420, H = 240, L = 64, R = 12, T = 24, B = 40;
    double x0 = INFINITY, x1 = -INFINITY, y0 = INFINITY, y1 = -INFINITY;
    for (int k = 0; k < ns; k++)
        for (int i = 0; i < s[k].n; i++) {
            double x = log_x ? log10(s[k].x[i]) : s[k].x[i], y = log_y ? log10(s[k].y[i]) : s[k].y[i];
            x0 = fmin(x0, x), x1 = fmax(x1, x), y0 = fmin(y0, y), y1 = fmax(y1, y);
        }
    if (!(x0 <= x1 && y0 <= y1)) return;
    if (x1 - x0 < 1e-12) x0 -= 0.5, x1 += 0.5;
    if (y1 - y0 < 1e-12) y0 -= 0.5, y1 += 0.5;
    sc_buf_printf(b, "<figure class=\"plot\"><svg xmlns=\"http://www.w3.org/2000/svg\" width=\"%.0f\" height=\"%.0f\" "
                     "viewBox=\"0 0 %.0f %.0f\" font-size=\"11\" font-family=\"sans-serif\">\n",
                  W, H, W, H);
    sc_buf_printf(b, "<rect x=\"%.0f\" y=\"%.0f\" width=\"%.0f\" height=\"%.0f\" fill=\"none\" stroke=\"#999\"/>\n", L, T,
                  W - L - R, H - T - B);
    sc_buf_puts(b, "<text x=\"4\" y=\"14\" font-weight=\"bold\">");
    markup_text(b, title);
    sc_buf_puts(b, "</text>\n");
    /* axis ends, as the values they stand for */
    double ends[2][2] = {{x0, x1}, {y0, y1}};
    for (int e = 0; e < 2; e++) {
        double vx = log_x ? pow(10, ends[0][e]) : ends[0][e], vy = log_y ? pow(10, ends[1][e]) : ends[1][e];
        sc_buf_printf(b, "<text x=\"%.1f\" y=\"%.1f\" text-anchor=\"%s\">%.3g</text>\n", e ? W - R : L, H - B + 14,
                      e ? "end" : "start", vx);
        sc_buf_printf(b, "<text x=\"%.1f\" y=\"%.1f\" text-anchor=\"end\">%.3g</text>\n", L - 4, e ? T + 10 : H - B, vy);
    }
    sc_buf_printf(b, "<text x=\"%.1f\" y=\"%.1f\" text-anchor=\"middle\">", (L + W - R) / 2, H - 8);
    markup_text(b, xlabel);
    sc_buf_printf(b, "</text>\n<text x=\"12\" y=\"%.1f\" transform=\"rotate(-90 12 %.1f)\" text-anchor=\"middle\">",
                  (T + H - B) / 2, (T + H - B) / 2);
    markup_text(b, ylabel);
    sc_buf_puts(b, "</text>\n");
    for (int k = 0; k < ns; k++) {
        const char *colour = plot_colours[k % (int)(sizeof plot_colours / sizeof *plot_colours)];
        sc_buf_printf(b, "<polyline fill=\"none\" stroke=\"%s\" stroke-width=\"1.5\" points=\"", colour);
        for (int i = 0; i < s[k].n; i++) {
            double x = log_x ? log10(s[k].x[i]) : s[k].x[i], y = log_y ? log10(s[k].y[i]) : s[k].y[i];
            sc_buf_printf(b, "%.1f,%.1f ", L + (x - x0) / (x1 - x0) * (W - L - R), H - B - (y - y0) / (y1 - y0) * (H - T - B));
        }
        sc_buf_puts(b, "\"/>\n");
        for (int i = 0; i < s[k].n; i++) {
            double x = log_x ? log10(s[k].x[i]) : s[k].x[i], y = log_y ? log10(s[k].y[i]) : s[k].y[i];
            sc_buf_printf(b, "<circle cx=\"%.1f\" cy=\"%.1f\" r=\"3\" fill=\"%s\"/>\n",
                          L + (x - x0) / (x1 - x0) * (W - L - R), H - B - (y - y0) / (y1 - y0) * (H - T - B), colour);
        }
        sc_buf_printf(b, "<text x=\"%.1f\" y=\"%.1f\" fill=\"%s\" text-anchor=\"end\">", W - R - 4, T + 14 + 13.0 * k, colour);
        markup_text(b, s[k].name);
        sc_buf_puts(b, "</text>\n");
    }
    sc_buf_puts(b, "</svg></figure>\n");
}

/* Faces against Hausdorff distance across the levels (the node that
 * reports both per level), and seam energy per mip level for each level of
 * detail (the node that reports lod<k>.level<m>.seam_energy). */
static void plots(sc_buf *b, const run_metrics *m) {
    int any = 0;
    for (int i = 0; i < m->count; i++) {
        series s = {.name = "levels"};
        for (int k = 0; k < 64; k++) {
            double f = metricf_value(m, i, "lod%d.faces", k, 0), h = metricf_value(m, i, "lod%d.hausdorff", k, 0);
            if (!(f > 0 && h > 0)) break;
            s.x[s.n] = f, s.y[s.n] = 100 * h, s.n++;
        }
        if (s.n < 1) continue;
        if (!any++) sc_buf_puts(b, "<section class=\"plots\">\n");
        svg_plot(b, "Faces against error", "faces", "Hausdorff, % diag.", &s, 1, true, false);
        break;
    }
    for (int i = 0; i < m->count; i++) {
        series s[6];
        int ns = 0;
        for (int k = 0; k < 6; k++) {
            series *x = &s[ns];
            *x = (series){.n = 0};
            snprintf(x->name, sizeof x->name, "LOD %d", k);
            for (int level = 0; level < 64; level++) {
                double e = metricf_value(m, i, "lod%d.level%d.seam_energy", k, level);
                if (!(e == e)) break;
                x->x[x->n] = level, x->y[x->n] = fmax(e, 1e-20), x->n++;
            }
            if (x->n == 0) break;
            ns++;
        }
        if (ns == 0) continue;
        if (!any++) sc_buf_puts(b, "<section class=\"plots\">\n");
        svg_plot(b, "Seam energy per mip level", "mip level", "seam energy", s, ns, false, true);
        break;
    }
    if (any) sc_buf_puts(b, "</section>\n");
}

char *sc_run_report_html(const sc_run *r) {
    const sc_graph *g = r->graph;
    sc_buf b;
    sc_buf_init(&b);
    sc_buf_puts(&b, "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">\n<title>seamcook: ");
    markup_text(&b, g->file);
    sc_buf_puts(&b,
                "</title>\n<style>\n"
                "body{font-family:sans-serif;margin:1.5em;color:#222}\n"
                "h1{font-size:1.3em} h2{font-size:1.1em;margin-top:1.5em} h3{font-size:1em}\n"
                "table{border-collapse:collapse;margin:.3em 0} td,th{border:1px solid #ccc;padding:2px 8px;text-align:left}\n"
                ".metrics td:last-child{text-align:right;font-family:monospace}\n"
                ".lod{display:flex;gap:1em;align-items:flex-start;flex-wrap:wrap;border-top:1px solid #ddd;padding-top:.5em}\n"
                ".pics{display:flex;flex-wrap:wrap;gap:4px;max-width:70em}\n"
                ".pics figure{margin:0} .pics img{width:160px;height:160px;image-rendering:pixelated;border:1px solid #ddd}\n"
                ".pics figcaption{font-size:.7em;color:#555;max-width:160px;overflow-wrap:anywhere}\n"
                ".ran{color:#0a5} .cached{color:#555} .failed{color:#c00;font-weight:bold} .skipped{color:#a60}\n"
                ".warnings{background:#fff4d6;border:1px solid #e0b84a;padding:.3em 1em}\n"
                ".levels img.sheet{max-width:100%;height:auto;display:block}\n"
                ".levels th{background:#f4f4f4} .levels td{font-family:monospace;text-align:right}\n"
                ".levels td[colspan]{text-align:left;padding:2px} tr.bad td{color:#c00;font-weight:bold}\n"
                ".plots{display:flex;flex-wrap:wrap;gap:1em} .plot{margin:0}\n"
                "</style></head><body>\n<h1>seamcook: ");
    markup_text(&b, g->file);
    int warnings = 0;
    for (int i = 0; i < g->count; i++) warnings += r->results[i].nwarnings;
    sc_buf_printf(&b, "</h1>\n<p>%d nodes: %d cooked, %d cached, %d failed, %d skipped, %d warnings, %.3f s.</p>\n",
                  g->count, r->ran, r->cached, r->failed, r->skipped, warnings, r->seconds);
    if (warnings) {
        sc_buf_puts(&b, "<div class=\"warnings\"><ul>\n");
        for (int i = 0; i < g->count; i++)
            for (int k = 0; k < r->results[i].nwarnings; k++) {
                sc_buf_puts(&b, "<li>");
                markup_text(&b, g->nodes[i].name);
                sc_buf_puts(&b, ": ");
                markup_text(&b, r->results[i].warnings[k]);
                sc_buf_puts(&b, "</li>\n");
            }
        sc_buf_puts(&b, "</ul></div>\n");
    }
    run_metrics all = metrics_of_run(r);
    lod_overview(&b, r, &all);
    plots(&b, &all);
    run_metrics_free(&all);

    sc_buf_puts(&b, "<h2>Nodes</h2>\n<table><tr><th>node</th><th>type</th><th>status</th><th>seconds</th><th>where</th></tr>\n");
    for (int i = 0; i < g->count; i++) {
        const sc_node_result *x = &r->results[i];
        const char *st = sc_status_name(x->status);
        sc_buf_puts(&b, "<tr><td><a href=\"#node-");
        markup_text(&b, g->nodes[i].name);
        sc_buf_puts(&b, "\">");
        markup_text(&b, g->nodes[i].name);
        sc_buf_puts(&b, "</a></td><td>");
        markup_text(&b, g->nodes[i].desc->type);
        sc_buf_printf(&b, "</td><td class=\"%s\">%s</td><td>%.3f</td><td>", st, st,
                      x->status == SC_STATUS_CACHED ? x->cooked_seconds : x->seconds);
        char line[32];
        snprintf(line, sizeof line, ":%d", g->nodes[i].line);
        markup_text(&b, g->nodes[i].file);
        sc_buf_puts(&b, line);
        sc_buf_puts(&b, "</td></tr>\n");
    }
    sc_buf_puts(&b, "</table>\n");

    for (int i = 0; i < g->count; i++) {
        const sc_node_result *x = &r->results[i];
        cJSON *metrics = x->metrics_json ? cJSON_Parse(x->metrics_json) : NULL;
        sc_buf_puts(&b, "<h2 id=\"node-");
        markup_text(&b, g->nodes[i].name);
        sc_buf_puts(&b, "\">");
        markup_text(&b, g->nodes[i].name);
        sc_buf_puts(&b, " <small>(");
        markup_text(&b, g->nodes[i].desc->type);
        sc_buf_puts(&b, ")</small></h2>\n");
        if (x->error) {
            sc_buf_puts(&b, "<p class=\"failed\">");
            markup_text(&b, x->error);
            sc_buf_puts(&b, "</p>\n");
        }
        if (x->why) {
            sc_buf_puts(&b, "<p>cooked because: ");
            markup_text(&b, x->why);
            sc_buf_puts(&b, "</p>\n");
        }
        /* pictures of each level of detail beside that level's metrics */
        int max_lod = -1;
        for (int f = 0; f < x->nfiles; f++)
            if (is_png(x->files[f]) && lod_of_file(x->files[f]) > max_lod) max_lod = lod_of_file(x->files[f]);
        for (int k = 0; k <= max_lod; k++) {
            char prefix[32];
            snprintf(prefix, sizeof prefix, "lod%d.", k);
            sc_buf_printf(&b, "<div class=\"lod\"><div><h3>LOD %d</h3>\n", k);
            /* this level's metrics from every node (faces from decimate, cracks from render...) */
            for (int j = 0; j < g->count; j++) {
                cJSON *other = j == i ? NULL : (r->results[j].metrics_json ? cJSON_Parse(r->results[j].metrics_json) : NULL);
                bool has = false;
                const cJSON *m;
                cJSON_ArrayForEach(m, other) has |= strncmp(m->string, prefix, strlen(prefix)) == 0;
                if (has) {
                    sc_buf_puts(&b, "<small>");
                    markup_text(&b, g->nodes[j].name);
                    sc_buf_puts(&b, "</small>\n");
                    html_metrics(&b, other, prefix);
                }
                cJSON_Delete(other);
            }
            sc_buf_puts(&b, "<small>");
            markup_text(&b, g->nodes[i].name);
            sc_buf_puts(&b, "</small>\n");
            html_metrics(&b, metrics, prefix);
            sc_buf_puts(&b, "</div><div class=\"pics\">\n");
            for (int f = 0; f < x->nfiles; f++) {
                if (!is_png(x->files[f]) || lod_of_file(x->files[f]) != k) continue;
                const char *base = strrchr(x->files[f], '/');
                figure(&b, x->files[f], base ? base + 1 : x->files[f]);
            }
            sc_buf_puts(&b, "</div></div>\n");
        }
        /* other pictures (textures with their seams drawn, ...) */
        bool other = false;
        for (int f = 0; f < x->nfiles; f++) {
            if (!is_png(x->files[f]) || lod_of_file(x->files[f]) >= 0) continue;
            if (!other) sc_buf_puts(&b, "<div class=\"pics\">\n");
            other = true;
            figure(&b, x->files[f], x->files[f]);
        }
        if (other) sc_buf_puts(&b, "</div>\n");
        if (max_lod < 0) html_metrics(&b, metrics, NULL);
        else {
            /* metrics that belong to no level */
            cJSON *rest = cJSON_CreateObject();
            const cJSON *m;
            cJSON_ArrayForEach(m, metrics) if (strncmp(m->string, "lod", 3) != 0)
                cJSON_AddItemToObject(rest, m->string, cJSON_Duplicate(m, 0));
            html_metrics(&b, rest, NULL);
            cJSON_Delete(rest);
        }
        cJSON_Delete(metrics);
    }
    sc_buf_puts(&b, "</body></html>\n");
    return sc_buf_take_string(&b);
}
