/* sc_report.c - report.json, report.html, the --json summary and JUnit XML.
 *
 * Design note: each is a view of what it is given (a run, or the outcomes of
 * graph tests) and nothing else; none reads the cache or the files. The HTML page groups pictures by level of detail using
 * the file names the render node writes (render/lod<k>_<mode>_<view>.png) and
 * the metrics it reports (lod<k>.<mode>.<metric>), so it needs no knowledge of
 * any node beyond those conventions. It has no scripts and no remote content.
 */
#include "sc_report.h"

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
                "</style></head><body>\n<h1>seamcook: ");
    markup_text(&b, g->file);
    sc_buf_printf(&b, "</h1>\n<p>%d nodes: %d cooked, %d cached, %d failed, %d skipped, %.3f s.</p>\n", g->count,
                  r->ran, r->cached, r->failed, r->skipped, r->seconds);

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
