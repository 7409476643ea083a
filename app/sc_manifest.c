/* sc_manifest.c - keeping --out to what the graph writes (see sc_manifest.h).
 *
 * Design note: the list is read whole, checked line by line (a line that is
 * not "<64 hex digits> <plain relative path>" is ignored, so an edited or
 * damaged list can make us forget a file but never reach outside the folder)
 * and written again atomically. Lists are short (a file per saved level,
 * texture or picture), so entries are matched by a linear search.
 */
#include "sc_manifest.h"

#include <stdlib.h>
#include <string.h>
#include <unistd.h>

typedef struct entry {
    sc_digest digest;
    char *path;
} entry;

typedef struct entries {
    entry *items;
    int count, cap;
} entries;

static void entries_free(entries *l) {
    for (int i = 0; i < l->count; i++) free(l->items[i].path);
    free(l->items);
}

static int entries_add(entries *l, const sc_digest *d, const char *path, size_t len) {
    if (l->count == l->cap) {
        int cap = l->cap ? 2 * l->cap : 64;
        entry *items = sc_realloc_array(l->items, (size_t)cap, sizeof *items);
        if (!items) return SC_ENOMEM;
        l->items = items, l->cap = cap;
    }
    char *copy = sc_strndup(path, len);
    if (!copy) return SC_ENOMEM;
    l->items[l->count++] = (entry){*d, copy};
    return SC_OK;
}

static const entry *entries_find(const entries *l, const char *path) {
    for (int i = 0; i < l->count; i++)
        if (strcmp(l->items[i].path, path) == 0) return &l->items[i];
    return NULL;
}

/* The previous list; none when there is no file. */
static int read_manifest(const char *path, entries *l, sc_error *err) {
    if (access(path, F_OK) != 0) return SC_OK;
    sc_buf b;
    sc_buf_init(&b);
    int rc = sc_read_file(path, (size_t)64 << 20, &b, err);
    const char *p = rc == SC_OK && b.data ? (const char *)b.data : "";
    const char *end = p + (rc == SC_OK ? b.len : 0);
    while (rc == SC_OK && p < end) {
        const char *nl = memchr(p, '\n', (size_t)(end - p));
        size_t n = nl ? (size_t)(nl - p) : (size_t)(end - p);
        char hex[65], *rel = n > 65 && p[64] == ' ' ? sc_strndup(p + 65, n - 65) : NULL;
        sc_digest d;
        memcpy(hex, p, n >= 64 ? 64 : n);
        hex[n >= 64 ? 64 : n] = 0;
        if (rel && strlen(rel) == n - 65 && sc_digest_parse(hex, &d) == 0 && sc_path_is_plain_relative(rel))
            rc = entries_add(l, &d, rel, n - 65);
        free(rel);
        p += n + 1;
    }
    sc_buf_free(&b);
    return rc == SC_ENOMEM ? sc_fail(err, rc, "out of memory") : rc;
}

/* Remove out_dir/rel when it still holds `digest`, then the folders that
 * leaves empty, up to out_dir. */
static void remove_stale(const char *out_dir, const entry *e, sc_cache *cache, FILE *log) {
    char *path = sc_path_join(out_dir, e->path);
    sc_digest now;
    sc_error ignored;
    if (path && sc_cache_file_digest(cache, path, &now, &ignored) == SC_OK && sc_digest_equal(&now, &e->digest) &&
        unlink(path) == 0) {
        if (log) fprintf(log, "removed %s (the graph no longer writes it)\n", path);
        for (char *slash = strrchr(path, '/'); slash && slash > path + strlen(out_dir); slash = strrchr(path, '/')) {
            *slash = 0;
            if (rmdir(path) != 0) break;
        }
    }
    free(path);
}

int sc_manifest_update(const char *out_dir, const sc_run *run, bool prune, sc_cache *cache, FILE *log,
                       sc_error *err) {
    char *path = sc_path_join(out_dir, SC_MANIFEST_NAME);
    if (!path) return sc_fail(err, SC_ENOMEM, "out of memory");
    entries old = {0}, now = {0};
    int rc = read_manifest(path, &old, err);
    for (int i = 0; rc == SC_OK && i < run->graph->count; i++) {
        const sc_node_result *r = &run->results[i];
        for (int f = 0; rc == SC_OK && f < r->nfiles; f++)
            if (r->files[f] && !entries_find(&now, r->files[f]))
                rc = entries_add(&now, &r->file_digests[f], r->files[f], strlen(r->files[f]));
    }
    for (int i = 0; rc == SC_OK && i < old.count; i++) {
        const entry *e = &old.items[i];
        if (entries_find(&now, e->path)) continue;
        if (prune) remove_stale(out_dir, e, cache, log);
        else rc = entries_add(&now, &e->digest, e->path, strlen(e->path));   /* kept for a later run */
    }
    sc_buf text;
    sc_buf_init(&text);
    for (int i = 0; i < now.count; i++) {
        char hex[65];
        sc_digest_hex(&now.items[i].digest, hex);
        sc_buf_printf(&text, "%s %s\n", hex, now.items[i].path);
    }
    if (rc == SC_ENOMEM || text.failed) rc = sc_fail(err, SC_ENOMEM, "out of memory");
    if (rc == SC_OK) rc = sc_write_file_atomic(path, text.data ? (const char *)text.data : "", text.len, err);
    sc_buf_free(&text);
    entries_free(&old), entries_free(&now);
    free(path);
    return rc;
}
