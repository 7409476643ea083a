/* sc_engine.c - cooking a graph.
 *
 * Design note. The engine is a small state machine per node, driven from one
 * libuv loop on the calling thread:
 *
 *   WAITING --inputs' digests known--> key --hit--> CACHED (digests, no bytes)
 *                                          \-miss-> NEED_RUN --inputs loaded--> RUNNING --> DONE
 *
 * Nodes ready to cook start in the order of the longest chain of consumers
 * after them, then graph order (start_order_build): with fewer job slots than
 * ready nodes, the critical path goes first.
 *
 * Only the loop thread touches node states; worker threads run a node (or
 * load a cached node's outputs) on data nobody else changes meanwhile, and
 * hand the result back in the after-work callback. Every call into the cache
 * is made under one mutex (the index is one SQLite connection).
 *
 * Values are loaded lazily: a hit costs one indexed lookup, a stat per
 * output and no bytes. Only when a consumer must cook are its inputs read from
 * the blob store (verified against their digests). If a cached output turns
 * out to be missing or corrupt, its producer simply cooks again. An input port
 * of kind MESH fed by an ATLAS is keyed by the atlas's mesh digest, so a
 * texture change does not re-cook mesh-only nodes.
 *
 * The cache keeps the outputs a graph reads, every REPORT (its files make the
 * output folder again) and every output of a node that no node reads (a
 * result of the graph). An output of a node whose consumers all read other
 * outputs (the float atlas of erase_seams in the main job, 150 MB on a
 * 2048^2 asset) is in the action's record by digest but its bytes are not
 * stored. A later graph that reads it finds it missing, and the node cooks
 * again and stores it.
 */
#include "sc_engine.h"

#include <limits.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>

#include <sys/stat.h>

#include <cjson/cJSON.h>
#include <uv.h>

#include "sc_exec.h"

typedef enum node_state {
    ST_WAITING,
    ST_CACHED,
    ST_NEED_RUN,
    ST_RUNNING,
    ST_DONE,
    ST_FAILED,
    ST_SKIPPED,
    ST_WOULD_RUN,
    ST_LEASE_WAIT,   /* another process is cooking the same action */
} node_state;

/* Leases (one cook per action among processes sharing a cache): how often a
 * waiting node looks again, how often held leases are renewed, and how old a
 * heartbeat may be before its lease is taken over. */
#define LEASE_POLL_MS 50
#define LEASE_BEAT_SECONDS 1.0
#define LEASE_STALE_SECONDS 10.0

typedef struct report_file {
    char *path;
    sc_digest value;     /* the BYTES value's digest (the blob) */
    sc_digest content;   /* SHA-256 of the file's bytes */
} report_file;

typedef struct node_rt {
    node_state state;
    char *canon;               /* canonical action text: the key's preimage */
    sc_value **values;         /* per output, when in memory */
    sc_value **meshes;         /* per ATLAS output: its mesh alone, when loaded */
    bool loading;
    bool leased;               /* this process holds the action's lease */
    bool waited;               /* it said once that it waits for another process */
    int pending_consumers;     /* consumer edges not yet finished */
    bool *kept;                /* per output: stored in the cache (see the design note) */
    int nfiles;
    report_file *files;        /* report files of every REPORT output */
} node_rt;

typedef struct claim {
    char *path;                /* an output file name, relative to out_dir */
    uint32_t hash;
    int node;                  /* the node that writes it */
} claim;

typedef struct engine {
    const sc_graph *g;
    sc_cache *cache;
    const sc_engine_options *opt;
    uv_loop_t loop;
    uv_mutex_t cache_lock;
    int stores;                /* cooked nodes whose outputs are being stored */
    node_rt *rt;
    sc_run *run;
    int inflight;              /* cooking jobs */
    int loads;                 /* load jobs */
    int lease_waits;           /* nodes waiting for another process's cook */
    uv_timer_t tick;           /* polls waiting nodes, renews held leases */
    double last_beat;
    bool batched;              /* pump holds one write transaction for its pass */
    bool stop;                 /* a node failed: start nothing new */
    int first_rc;
    sc_error first_err;
    int done_count;
    double t0;
    char graph_path[PATH_MAX]; /* the graph file's real path */
    char base_dir[PATH_MAX];   /* paths in keys and records are relative to it */
    claim *claims;             /* output file names taken so far */
    int nclaims, claim_cap;
    int *start_order;          /* the nodes, longest chain after them first (start_order_build) */
} engine;

const char *sc_status_name(sc_node_status s) {
    switch (s) {
    case SC_STATUS_PENDING: return "pending";
    case SC_STATUS_CACHED: return "cached";
    case SC_STATUS_RAN: return "ran";
    case SC_STATUS_FAILED: return "failed";
    case SC_STATUS_SKIPPED: return "skipped";
    case SC_STATUS_WOULD_RUN: return "would run";
    }
    return "?";
}

/* ---------------------------------------------------------------- loading values */

typedef struct loader {
    sc_cache *cache;
    int depth;
} loader;

static sc_value *load_digest(void *ud, const sc_digest *d, sc_error *err) {
    loader *ld = ud;
    if (ld->depth > 8) {
        sc_fail(err, SC_EINPUT, "values nest too deeply");
        return NULL;
    }
    sc_buf buf;
    sc_buf_init(&buf);
    int rc = sc_cache_get_blob(ld->cache, d, &buf, err);
    if (rc != SC_OK) {
        sc_buf_free(&buf);
        return NULL;
    }
    ld->depth++;
    sc_value *v = sc_value_deserialize(buf.data, buf.len, d, load_digest, ld, err);
    ld->depth--;
    sc_buf_free(&buf);
    return v;
}

sc_value *sc_engine_load(sc_cache *cache, const sc_digest *digest, sc_error *err) {
    loader ld = {cache, 0};
    return load_digest(&ld, digest, err);
}

/* ---------------------------------------------------------------- storing values */

typedef struct storer {
    sc_cache *cache;
    uv_mutex_t *lock;   /* the engine's cache lock: held for the index, not for the bytes */
    sc_digest *blobs;
    int nblobs, cap;
    int rc;
    sc_error *err;
} storer;

static void store_value(void *ud, sc_value *v) {
    storer *s = ud;
    if (s->rc != SC_OK) return;
    sc_value_parts(v, store_value, s);   /* parts first: a record never names missing bytes */
    if (s->rc != SC_OK) return;          /* a part failed: keep its error (a full disk, say) */
    if (s->nblobs == s->cap) {
        int cap = s->cap ? 2 * s->cap : 16;
        sc_digest *b = realloc(s->blobs, sizeof *b * (size_t)cap);
        if (!b) {
            s->rc = sc_fail(s->err, SC_ENOMEM, "out of memory");
            return;
        }
        s->blobs = b, s->cap = cap;
    }
    s->blobs[s->nblobs++] = *sc_value_digest(v);
    if (sc_cache_has_blob(s->cache, sc_value_digest(v))) return;
    sc_buf buf;
    sc_buf_init(&buf);
    if (sc_value_serialize(v, &buf) != SC_OK)
        s->rc = sc_fail(s->err, SC_ENOMEM, "out of memory serialising a %s", sc_kind_name(v->kind));
    else
        s->rc = sc_cache_write_blob_file(s->cache, sc_value_digest(v), buf.data, buf.len, s->err);
    if (s->rc == SC_OK) {
        uv_mutex_lock(s->lock);
        s->rc = sc_cache_put_blob(s->cache, sc_value_digest(v), buf.data, buf.len, s->err);
        uv_mutex_unlock(s->lock);
    }
    sc_buf_free(&buf);
}

/* ---------------------------------------------------------------- small helpers */

static const sc_graph_node *gnode(engine *e, int i) { return &e->g->nodes[i]; }

static void hexof(const sc_digest *d, char out[65]) { sc_digest_hex(d, out); }

/* A node's identity across runs, which explain compares a cook with: the
 * graph file's real path, its name and its lineage, the values of the PATH
 * parameters of the node and of every node upstream of it (hashed). So a
 * chain cooked on one asset and then on another keeps a history per asset:
 * an edit of the first is explained against its own last cook, not as a
 * change of path. A node with no path upstream is "graph#name". */
static char *node_id(engine *e, int i) {
    const sc_graph *g = e->g;
    bool *upstream = calloc((size_t)i + 1, sizeof *upstream);
    if (!upstream) return NULL;
    upstream[i] = true;
    sc_buf paths;
    sc_buf_init(&paths);
    for (int k = i; k >= 0; k--) {   /* producers come before consumers */
        if (!upstream[k]) continue;
        const sc_graph_node *n = &g->nodes[k];
        for (int port = 0; port < n->desc->ninputs; port++)
            if (n->input_node[port] >= 0) upstream[n->input_node[port]] = true;
        for (int p = 0; p < n->desc->nparams; p++)
            if (n->desc->params[p].type == SC_PARAM_PATH)
                sc_buf_printf(&paths, "%s.%s=%s\n", n->name, n->desc->params[p].name,
                              n->params[p].string ? n->params[p].string : "");
    }
    free(upstream);
    char *id = NULL;
    if (!paths.failed && paths.len == 0) {
        id = sc_strprintf("%s#%s", e->graph_path, gnode(e, i)->name);
    } else if (!paths.failed) {
        sc_digest d;
        char hex[65];
        sc_digest_bytes(paths.data, paths.len, &d);
        hexof(&d, hex);
        id = sc_strprintf("%s#%s#%s", e->graph_path, gnode(e, i)->name, hex);
    }
    sc_buf_free(&paths);
    return id;
}

static void say(engine *e, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static void say(engine *e, const char *fmt, ...) {
    if (!e->opt->log) return;
    if (e->opt->live) fputs("\r\033[K", e->opt->log);
    va_list ap;
    va_start(ap, fmt);
    vfprintf(e->opt->log, fmt, ap);
    va_end(ap);
    fputc('\n', e->opt->log);
    fflush(e->opt->log);
}

static void show_progress(engine *e) {
    if (!e->opt->log || !e->opt->live) return;
    int running = 0;
    char names[160] = "";
    size_t used = 0;
    for (int i = 0; i < e->g->count; i++) {
        if (e->rt[i].state != ST_RUNNING) continue;
        running++;
        int n = snprintf(names + used, sizeof names - used, "%s%s", used ? ", " : "",
                         gnode(e, i)->name);
        if (n > 0 && (size_t)n < sizeof names - used) used += (size_t)n;
    }
    fprintf(e->opt->log, "\r\033[K[%d/%d] %d cached, %d ran%s%s", e->done_count, e->g->count,
            e->run->cached, e->run->ran, running ? " | cooking: " : "", names);
    fflush(e->opt->log);
}

/* The digest a consumer's input port is keyed by. */
static const sc_digest *input_digest(engine *e, int i, int port) {
    const sc_graph_node *n = gnode(e, i);
    int p = n->input_node[port], k = n->input_port[port];
    const sc_node_output *o = &e->run->results[p].outputs[k];
    if (n->desc->inputs[port].kind == SC_KIND_MESH && o->kind == SC_KIND_ATLAS) return &o->mesh;
    return &o->digest;
}

static bool wants_mesh_only(engine *e, int i, int port) {
    const sc_graph_node *n = gnode(e, i);
    int p = n->input_node[port], k = n->input_port[port];
    return n->desc->inputs[port].kind == SC_KIND_MESH &&
           gnode(e, p)->desc->outputs[k].kind == SC_KIND_ATLAS;
}

/* Every kernel a node's descriptor reaches (its own and, transitively, the
 * ones they build on), each once, sorted by name. */
#define MAX_KERNELS 64
static void kernel_add(const sc_kernel *k, const sc_kernel **out, int *n) {
    for (int i = 0; i < *n; i++)
        if (out[i] == k) return;
    if (*n == MAX_KERNELS) return;   /* a programming error: test_engine checks every shipped node stays under */
    out[(*n)++] = k;
    for (int i = 0; k->uses && k->uses[i]; i++) kernel_add(k->uses[i], out, n);
}

static int kernel_name_order(const void *a, const void *b) {
    return strcmp((*(const sc_kernel *const *)a)->name, (*(const sc_kernel *const *)b)->name);
}

static int kernel_closure(const sc_node_desc *d, const sc_kernel **out) {
    int n = 0;
    for (int i = 0; d->kernels && d->kernels[i]; i++) kernel_add(d->kernels[i], out, &n);
    qsort(out, (size_t)n, sizeof *out, kernel_name_order);
    return n;
}

/* A PATH parameter in the key: relative to the base folder, and the content
 * digest of the file it names (a folder, or a file not there, has none; a
 * node that reads it fails or records what it read). */
static bool path_key(void *ud, const char *path, char **shown, sc_digest *content) {
    engine *e = ud;
    *shown = sc_path_relative(e->base_dir, path);
    struct stat st;
    if (stat(path, &st) != 0 || !S_ISREG(st.st_mode)) return false;
    sc_error ignored;
    uv_mutex_lock(&e->cache_lock);
    int rc = sc_cache_file_digest(e->cache, path, content, &ignored);
    uv_mutex_unlock(&e->cache_lock);
    return rc == SC_OK;
}

/* The canonical action text: its SHA-256 is the key. */
static char *canonical_action(engine *e, int i) {
    const sc_graph_node *n = gnode(e, i);
    sc_buf b, params;
    sc_buf_init(&b);
    sc_buf_init(&params);
    sc_buf_printf(&b, "seamcook action\nformat %d.%d\ntype %s\nversion %d\n", SC_ENGINE_FORMAT,
                  SC_VALUE_FORMAT, n->desc->type, n->desc->version);
    const sc_kernel *kernels[MAX_KERNELS];
    int nkernels = kernel_closure(n->desc, kernels);
    for (int k = 0; k < nkernels; k++) sc_buf_printf(&b, "kernel %s %d\n", kernels[k]->name, kernels[k]->version);
    for (int k = 0; k < nkernels; k++)
        if (kernels[k]->platform) sc_buf_printf(&b, "platform %s %s\n", kernels[k]->name, kernels[k]->platform());
    sc_graph_canonical_params(n, path_key, e, &params);
    /* prefix each parameter line, so explain can tell lines apart */
    const char *p = params.data ? (const char *)params.data : "";
    while (*p) {
        const char *nl = strchr(p, '\n');
        size_t len = nl ? (size_t)(nl - p) : strlen(p);
        sc_buf_puts(&b, "param ");
        sc_buf_append(&b, p, len);
        sc_buf_puts(&b, "\n");
        p += len + (nl ? 1 : 0);
    }
    sc_buf_free(&params);
    for (int port = 0; port < n->desc->ninputs; port++) {
        if (n->input_node[port] < 0) continue;
        char hex[65];
        hexof(input_digest(e, i, port), hex);
        sc_buf_printf(&b, "input %s %s\n", n->desc->inputs[port].name, hex);
    }
    return sc_buf_take_string(&b);
}

/* ---------------------------------------------------------------- output records */

static cJSON *outputs_json(engine *e, int i) {
    const sc_node_result *r = &e->run->results[i];
    node_rt *rt = &e->rt[i];
    cJSON *arr = cJSON_CreateArray();
    for (int k = 0; k < r->noutputs; k++) {
        char hex[65];
        cJSON *o = cJSON_CreateObject();
        cJSON_AddStringToObject(o, "kind", sc_kind_name(r->outputs[k].kind));
        hexof(&r->outputs[k].digest, hex);
        cJSON_AddStringToObject(o, "digest", hex);
        if (r->outputs[k].kind == SC_KIND_ATLAS) {
            hexof(&r->outputs[k].mesh, hex);
            cJSON_AddStringToObject(o, "mesh", hex);
        }
        cJSON_AddItemToArray(arr, o);
    }
    cJSON *files = cJSON_CreateArray();
    for (int f = 0; f < rt->nfiles; f++) {
        char hex[65];
        cJSON *o = cJSON_CreateObject();
        cJSON_AddStringToObject(o, "path", rt->files[f].path);
        hexof(&rt->files[f].value, hex);
        cJSON_AddStringToObject(o, "value", hex);
        hexof(&rt->files[f].content, hex);
        cJSON_AddStringToObject(o, "content", hex);
        cJSON_AddItemToArray(files, o);
    }
    cJSON *root = cJSON_CreateObject();
    cJSON_AddItemToObject(root, "outputs", arr);
    cJSON_AddItemToObject(root, "files", files);
    return root;
}

static int parse_digest_field(const cJSON *o, const char *name, sc_digest *d) {
    const cJSON *s = cJSON_GetObjectItemCaseSensitive(o, name);
    return (cJSON_IsString(s) && sc_digest_parse(s->valuestring, d) == 0) ? 0 : -1;
}

/* Read a recorded action's outputs into the node's result. 0 ok, -1 unusable. */
static int read_outputs(engine *e, int i, const char *text) {
    sc_node_result *r = &e->run->results[i];
    node_rt *rt = &e->rt[i];
    cJSON *root = cJSON_Parse(text);
    const cJSON *arr = cJSON_GetObjectItemCaseSensitive(root, "outputs");
    const cJSON *files = cJSON_GetObjectItemCaseSensitive(root, "files");
    int rc = (cJSON_IsArray(arr) && cJSON_IsArray(files) &&
              cJSON_GetArraySize(arr) == r->noutputs) ? 0 : -1;
    for (int k = 0; rc == 0 && k < r->noutputs; k++) {
        const cJSON *o = cJSON_GetArrayItem(arr, k);
        const cJSON *kind = cJSON_GetObjectItemCaseSensitive(o, "kind");
        r->outputs[k].kind = cJSON_IsString(kind) ? sc_kind_from_name(kind->valuestring) : SC_KIND_NONE;
        if (r->outputs[k].kind != gnode(e, i)->desc->outputs[k].kind ||
            parse_digest_field(o, "digest", &r->outputs[k].digest) != 0 ||
            (r->outputs[k].kind == SC_KIND_ATLAS && parse_digest_field(o, "mesh", &r->outputs[k].mesh) != 0))
            rc = -1;
    }
    int nf = rc == 0 ? cJSON_GetArraySize(files) : 0;
    if (nf > 0) {
        rt->files = calloc((size_t)nf, sizeof *rt->files);
        if (!rt->files) rc = -1;
    }
    for (int f = 0; rc == 0 && f < nf; f++) {
        const cJSON *o = cJSON_GetArrayItem(files, f);
        const cJSON *path = cJSON_GetObjectItemCaseSensitive(o, "path");
        if (!cJSON_IsString(path) || parse_digest_field(o, "value", &rt->files[f].value) != 0 ||
            parse_digest_field(o, "content", &rt->files[f].content) != 0) {
            rc = -1;
            break;
        }
        rt->files[f].path = sc_strdup(path->valuestring);
        rt->nfiles++;
    }
    cJSON_Delete(root);
    return rc;
}

static void forget_files(node_rt *rt) {
    for (int f = 0; f < rt->nfiles; f++) free(rt->files[f].path);
    free(rt->files);
    rt->files = NULL;
    rt->nfiles = 0;
}

/* ---------------------------------------------------------------- explain */

/* The first line of `text` that starts with `prefix` and a space, or NULL. */
static const char *find_line(const char *text, const char *prefix, const char *name, size_t *len) {
    size_t pl = strlen(prefix), nl = name ? strlen(name) : 0;
    for (const char *p = text; p && *p;) {
        const char *end = strchr(p, '\n');
        size_t l = end ? (size_t)(end - p) : strlen(p);
        if (l > pl && strncmp(p, prefix, pl) == 0 && p[pl] == ' ' &&
            (!name || (l > pl + 1 + nl && strncmp(p + pl + 1, name, nl) == 0 &&
                       (p[pl + 1 + nl] == ' ' || p[pl + 1 + nl] == '=')))) {
            *len = l;
            return p;
        }
        p = end ? end + 1 : NULL;
    }
    return NULL;
}

/* Whether two PATH parameter lines name the same path (their content
 * digests, " sha256:...", aside). */
static bool same_path(const char *a, size_t la, const char *b, size_t lb) {
    const char *tag = " sha256:";
    size_t tl = strlen(tag), pa = la, pb = lb;
    for (size_t k = 0; k + tl <= la; k++)
        if (strncmp(a + k, tag, tl) == 0) pa = k;
    for (size_t k = 0; k + tl <= lb; k++)
        if (strncmp(b + k, tag, tl) == 0) pb = k;
    return pa == pb && (pa < la || pb < lb) && strncmp(a, b, pa) == 0;
}

/* Why the node with canonical text `now` cooks, given what it was last time. */
static char *explain(engine *e, int i, const char *now, const char *before) {
    if (!before) return sc_strdup("no previous cook of this node");
    sc_buf why;
    sc_buf_init(&why);
    size_t la, lb;
    const char *a = find_line(before, "version", NULL, &la), *b = find_line(now, "version", NULL, &lb);
    if (a && b && (la != lb || strncmp(a, b, la) != 0))
        sc_buf_printf(&why, "node version %.*s -> %.*s; ", (int)(la - 8), a + 8, (int)(lb - 8), b + 8);
    const sc_graph_node *n = gnode(e, i);
    const sc_kernel *kernels[MAX_KERNELS];
    int nkernels = kernel_closure(n->desc, kernels);
    for (int k = 0; k < nkernels; k++) {
        const char *name = kernels[k]->name;
        a = find_line(before, "kernel", name, &la);
        b = find_line(now, "kernel", name, &lb);
        if (a && b && la == lb && strncmp(a, b, la) == 0) continue;
        size_t skip = 7 + strlen(name) + 1;
        sc_buf_printf(&why, "kernel %s version %.*s -> %.*s; ", name, a ? (int)(la - skip) : 7,
                      a ? a + skip : "(unset)", (int)(lb - skip), b + skip);
    }
    for (int k = 0; k < nkernels; k++) {
        const char *name = kernels[k]->name;
        a = find_line(before, "platform", name, &la);
        b = find_line(now, "platform", name, &lb);
        if ((!a && !b) || (a && b && la == lb && strncmp(a, b, la) == 0)) continue;
        size_t skip = 9 + strlen(name) + 1;
        sc_buf_printf(&why, "kernel %s platform %.*s -> %.*s; ", name, a ? (int)(la - skip) : 7,
                      a ? a + skip : "(unset)", b ? (int)(lb - skip) : 7, b ? b + skip : "(unset)");
    }
    for (int k = 0; k < n->desc->nparams; k++) {
        const char *name = n->desc->params[k].name;
        a = find_line(before, "param", name, &la);
        b = find_line(now, "param", name, &lb);
        if (a && b && la == lb && strncmp(a, b, la) == 0) continue;
        if (a && b && same_path(a, la, b, lb)) continue;   /* the file changed: its dep line says so */
        size_t skip = 6 + strlen(name) + 1;
        sc_buf_printf(&why, "parameter %s: %.*s -> %.*s; ", name, a ? (int)(la - skip) : 7,
                      a ? a + skip : "(unset)", b ? (int)(lb - skip) : 7, b ? b + skip : "(unset)");
    }
    for (int k = 0; k < n->desc->ninputs; k++) {
        const char *name = n->desc->inputs[k].name;
        a = find_line(before, "input", name, &la);
        b = find_line(now, "input", name, &lb);
        if (a && b && la == lb && strncmp(a, b, la) == 0) continue;
        if (!a && !b) continue;
        int p = n->input_node[k];
        sc_buf_printf(&why, "input %s changed (from %s); ", name, p >= 0 ? gnode(e, p)->name : "nothing");
    }
    /* files read last time that differ now */
    for (const char *p = before; p && *p;) {
        const char *end = strchr(p, '\n');
        size_t l = end ? (size_t)(end - p) : strlen(p);
        if (l > 4 + 65 && strncmp(p, "dep ", 4) == 0) {
            char hex[65], *path = sc_strndup(p + 4 + 65, l - 4 - 65);
            memcpy(hex, p + 4, 64);
            hex[64] = 0;
            sc_digest then, cur;
            sc_error ignored;
            if (path && sc_digest_parse(hex, &then) == 0) {
                uv_mutex_lock(&e->cache_lock);
                int rc = sc_cache_file_digest(e->cache, path, &cur, &ignored);
                uv_mutex_unlock(&e->cache_lock);
                if (rc != SC_OK) sc_buf_printf(&why, "file %s is gone; ", path);
                else if (!sc_digest_equal(&then, &cur)) sc_buf_printf(&why, "file %s changed; ", path);
            }
            free(path);
        }
        p = end ? end + 1 : NULL;
    }
    if (why.len == 0) sc_buf_puts(&why, "no cache entry for this key (removed, or never stored)");
    else why.len -= 2, why.data[why.len] = 0;   /* drop the last "; " */
    return sc_buf_take_string(&why);
}

/* History text = canonical action + "dep <hex> <path>" per file read. */
static char *history_text(const char *canon, const sc_node_result *r, const sc_digest *dep_digests) {
    sc_buf b;
    sc_buf_init(&b);
    sc_buf_puts(&b, canon);
    for (int d = 0; d < r->ndeps; d++) {
        char hex[65];
        hexof(&dep_digests[d], hex);
        sc_buf_printf(&b, "dep %s %s\n", hex, r->deps[d]);
    }
    return sc_buf_take_string(&b);
}

static void remember(engine *e, int i, const sc_digest *dep_digests) {
    if (e->opt->dry_run) return;
    char *id = node_id(e, i);
    char *text = history_text(e->rt[i].canon, &e->run->results[i], dep_digests);
    char *old = NULL;
    sc_error err;
    uv_mutex_lock(&e->cache_lock);
    if (id && text && (sc_cache_get_history(e->cache, id, &old, &err) != SC_OK || strcmp(old, text) != 0))
        sc_cache_put_history(e->cache, id, text, &err);
    uv_mutex_unlock(&e->cache_lock);
    free(old), free(text), free(id);
}

/* ---------------------------------------------------------------- report files */

/* Claim an output file name for node i: returns i, or the node that claimed
 * it first, or -1 when out of memory. An open-addressing table of names. */
static int claim_path(engine *e, const char *rel, int i) {
    if (e->nclaims * 2 >= e->claim_cap) {
        int cap = e->claim_cap ? 2 * e->claim_cap : 256;
        claim *t = calloc((size_t)cap, sizeof *t);
        if (!t) return -1;
        for (int k = 0; k < e->claim_cap; k++) {
            if (!e->claims[k].path) continue;
            uint32_t h = e->claims[k].hash & (uint32_t)(cap - 1);
            while (t[h].path) h = (h + 1) & (uint32_t)(cap - 1);
            t[h] = e->claims[k];
        }
        free(e->claims);
        e->claims = t, e->claim_cap = cap;
    }
    uint32_t hash = 2166136261u;   /* FNV-1a */
    for (const char *c = rel; *c; c++) hash = (hash ^ (uint8_t)*c) * 16777619u;
    uint32_t h = hash & (uint32_t)(e->claim_cap - 1);
    while (e->claims[h].path) {
        if (e->claims[h].hash == hash && strcmp(e->claims[h].path, rel) == 0) return e->claims[h].node;
        h = (h + 1) & (uint32_t)(e->claim_cap - 1);
    }
    e->claims[h].path = sc_strdup(rel);
    if (!e->claims[h].path) return -1;
    e->claims[h].hash = hash;
    e->claims[h].node = i;
    e->nclaims++;
    return i;
}

/* The BYTES value with this digest among the node's in-memory reports. */
static sc_value *bytes_in_memory(engine *e, int i, const sc_digest *d) {
    for (int k = 0; k < gnode(e, i)->desc->noutputs; k++) {
        const sc_value *v = e->rt[i].values[k];
        if (!v || v->kind != SC_KIND_REPORT) continue;
        for (int f = 0; f < v->as.report->nfiles; f++)
            if (sc_digest_equal(sc_value_digest(v->as.report->files[f].bytes), d))
                return sc_value_retain(v->as.report->files[f].bytes);
    }
    return NULL;
}

/* Write the node's report files under out_dir, skipping those already there. */
static int materialize(engine *e, int i, sc_error *err) {
    node_rt *rt = &e->rt[i];
    sc_node_result *r = &e->run->results[i];
    if (!e->opt->out_dir || e->opt->dry_run || rt->nfiles == 0) return SC_OK;
    r->files = calloc((size_t)rt->nfiles, sizeof(char *));
    r->file_digests = calloc((size_t)rt->nfiles, sizeof *r->file_digests);
    if (!r->files || !r->file_digests) return sc_fail(err, SC_ENOMEM, "out of memory");
    for (int f = 0; f < rt->nfiles; f++) {
        const char *rel = rt->files[f].path;
        if (!sc_path_is_plain_relative(rel))
            return sc_fail(err, SC_EINPUT, "output file name '%s' is not a plain relative path", rel);
        int other = claim_path(e, rel, i);
        if (other != i)
            return sc_fail(err, other < 0 ? SC_ENOMEM : SC_EINPUT, "output file '%s' is also written by %s",
                           rel, other < 0 ? "?" : gnode(e, other)->name);
        char *path = sc_path_join(e->opt->out_dir, rel);
        char *dir = path ? sc_path_dirname(path) : NULL;
        sc_digest have;
        sc_error ignored;
        int rc = SC_OK;
        uv_mutex_lock(&e->cache_lock);
        bool same = path && sc_cache_file_digest(e->cache, path, &have, &ignored) == SC_OK &&
                    sc_digest_equal(&have, &rt->files[f].content);
        uv_mutex_unlock(&e->cache_lock);
        if (!path || !dir) rc = sc_fail(err, SC_ENOMEM, "out of memory");
        if (rc == SC_OK && !same) {
            rc = sc_make_dirs(dir, err);
            sc_value *bytes = bytes_in_memory(e, i, &rt->files[f].value);
            if (!bytes && rc == SC_OK) {
                uv_mutex_lock(&e->cache_lock);
                bytes = sc_engine_load(e->cache, &rt->files[f].value, err);
                uv_mutex_unlock(&e->cache_lock);
            }
            if (rc == SC_OK && (!bytes || bytes->kind != SC_KIND_BYTES))
                rc = sc_fail(err, SC_EMISS, "%s: its stored bytes are missing or corrupt", rel);
            if (rc == SC_OK)
                rc = sc_write_file_atomic(path, bytes->as.bytes->data, bytes->as.bytes->size, err);
            sc_value_release(bytes);
        }
        free(path), free(dir);
        if (rc != SC_OK) return rc;
        r->file_digests[r->nfiles] = rt->files[f].content;
        r->files[r->nfiles++] = sc_strdup(rel);
    }
    return SC_OK;
}

/* Collect report files from in-memory REPORT outputs. */
static int files_from_values(engine *e, int i) {
    node_rt *rt = &e->rt[i];
    const sc_node_desc *d = gnode(e, i)->desc;
    for (int k = 0; k < d->noutputs; k++) {
        sc_value *v = rt->values[k];
        if (!v || v->kind != SC_KIND_REPORT) continue;
        const sc_report *rep = v->as.report;
        report_file *files = realloc(rt->files, sizeof *files * (size_t)(rt->nfiles + rep->nfiles + 1));
        if (!files) return SC_ENOMEM;
        rt->files = files;
        for (int f = 0; f < rep->nfiles; f++) {
            report_file *rf = &rt->files[rt->nfiles++];
            rf->path = sc_strdup(rep->files[f].path);
            rf->value = *sc_value_digest(rep->files[f].bytes);
            sc_digest_bytes(rep->files[f].bytes->as.bytes->data, rep->files[f].bytes->as.bytes->size,
                            &rf->content);
        }
    }
    return SC_OK;
}

/* ---------------------------------------------------------------- node transitions */

static void pump(engine *e);

static void finish_consumer_edges(engine *e, int i) {
    const sc_graph_node *n = gnode(e, i);
    for (int port = 0; port < n->desc->ninputs; port++) {
        int p = n->input_node[port];
        if (p < 0) continue;
        node_rt *prt = &e->rt[p];
        if (--prt->pending_consumers > 0) continue;
        for (int k = 0; k < gnode(e, p)->desc->noutputs; k++) {
            sc_value_release(prt->values[k]);
            sc_value_release(prt->meshes[k]);
            prt->values[k] = prt->meshes[k] = NULL;
        }
    }
}

static void set_terminal(engine *e, int i, node_state st) {
    e->rt[i].state = st;
    e->done_count++;
    sc_node_result *r = &e->run->results[i];
    switch (st) {
    case ST_CACHED: r->status = SC_STATUS_CACHED; e->run->cached++; break;
    case ST_DONE: r->status = SC_STATUS_RAN; e->run->ran++; break;
    case ST_FAILED: r->status = SC_STATUS_FAILED; e->run->failed++; break;
    case ST_SKIPPED: r->status = SC_STATUS_SKIPPED; e->run->skipped++; break;
    case ST_WOULD_RUN: r->status = SC_STATUS_WOULD_RUN; break;
    default: break;
    }
    finish_consumer_edges(e, i);   /* a finished node no longer needs its inputs */
}

/* Keep a node's error, stop the run (the first failure names it) and say so. */
static void note_failure(engine *e, int i, int rc, const sc_error *err) {
    const sc_graph_node *n = gnode(e, i);
    sc_node_result *r = &e->run->results[i];
    r->error = sc_strprintf("%s:%d: %s (%s): %s", n->file, n->line, n->name, n->desc->type,
                            err->message);
    if (!e->stop) {
        e->stop = true;
        e->first_rc = rc ? rc : SC_EINPUT;
        snprintf(e->first_err.message, sizeof e->first_err.message, "%s", r->error ? r->error : "failed");
        e->first_err.code = e->first_rc;
    }
    say(e, "FAILED %s", r->error ? r->error : n->name);
}

static void fail_node(engine *e, int i, int rc, const sc_error *err) {
    note_failure(e, i, rc, err);
    set_terminal(e, i, ST_FAILED);
}

static void keep_warnings(sc_node_result *r, const sc_ctx *ctx) {
    int n = sc_ctx_nwarnings(ctx);
    if (n == 0 || !(r->warnings = calloc((size_t)n, sizeof(char *)))) return;
    for (int k = 0; k < n; k++)
        if ((r->warnings[r->nwarnings] = sc_strdup(sc_ctx_warning(ctx, k)))) r->nwarnings++;
}

/* What the cache's action record keeps as its metrics text:
 * {"metrics": {...}, "warnings": ["...", ...]}. */
static char *record_json(const sc_node_result *r) {
    cJSON *o = cJSON_CreateObject();
    cJSON *m = cJSON_Parse(r->metrics_json);
    cJSON *w = cJSON_AddArrayToObject(o, "warnings");
    if (m) cJSON_AddItemToObject(o, "metrics", m);
    for (int k = 0; w && k < r->nwarnings; k++) cJSON_AddItemToArray(w, cJSON_CreateString(r->warnings[k]));
    char *s = m && w ? cJSON_PrintUnformatted(o) : NULL;
    cJSON_Delete(o);
    return s;
}

/* The other way: fills metrics_json and the warnings; false if the text is
 * not such a record. */
static bool read_record(sc_node_result *r, const char *text) {
    cJSON *o = text ? cJSON_Parse(text) : NULL;
    cJSON *m = cJSON_GetObjectItemCaseSensitive(o, "metrics");
    cJSON *w = cJSON_GetObjectItemCaseSensitive(o, "warnings");
    bool ok = cJSON_IsObject(m) && cJSON_IsArray(w) && (r->metrics_json = cJSON_PrintUnformatted(m));
    int n = ok ? cJSON_GetArraySize(w) : 0;
    if (n > 0 && (r->warnings = calloc((size_t)n, sizeof(char *)))) {
        const cJSON *line;
        cJSON_ArrayForEach(line, w)
            if (cJSON_IsString(line) && (r->warnings[r->nwarnings] = sc_strdup(line->valuestring))) r->nwarnings++;
    }
    cJSON_Delete(o);
    return ok;
}

/* Drop what a hit filled in, when it turns out not to be usable. */
static void forget_result(sc_node_result *r) {
    free(r->metrics_json);
    r->metrics_json = NULL;
    for (int k = 0; k < r->nwarnings; k++) free(r->warnings[k]);
    free(r->warnings);
    r->warnings = NULL, r->nwarnings = 0;
    for (int d = 0; d < r->ndeps; d++) free(r->deps[d]);
    free(r->deps), free(r->dep_digests);
    r->deps = NULL, r->dep_digests = NULL, r->ndeps = 0;
    for (int f = 0; f < r->nfiles; f++) free(r->files[f]);
    free(r->files), free(r->file_digests);
    r->files = NULL, r->file_digests = NULL, r->nfiles = 0;
}

/* Take the lease on node i's action. False when another live process holds
 * it: the node then waits (ST_LEASE_WAIT) and is resolved again on the next
 * tick, a hit once that process has recorded the result. A lease that cannot
 * be taken for another reason (the index is read-only) does not stop the
 * cook. */
static bool take_lease(engine *e, int i) {
    node_rt *rt = &e->rt[i];
    sc_cache_lease_holder h;
    sc_error err;
    uv_mutex_lock(&e->cache_lock);
    int rc = sc_cache_lease_take(e->cache, &e->run->results[i].key, LEASE_STALE_SECONDS, &h, &err);
    uv_mutex_unlock(&e->cache_lock);
    const sc_graph_node *n = gnode(e, i);
    if (rc == SC_EBUSY) {
        if (!rt->waited) say(e, "waiting for %s (%s): %s (pid %lld) is cooking it", n->name, n->desc->type, h.host,
                             (long long)h.pid);
        rt->waited = true;
        free(rt->canon);
        rt->canon = NULL;
        rt->state = ST_LEASE_WAIT;
        e->lease_waits++;
        return false;
    }
    rt->leased = rc == SC_OK;
    if (rc == SC_OK && h.taken_over)
        say(e, "taking over %s (%s) from %s (pid %lld, gone)", n->name, n->desc->type, h.host, (long long)h.pid);
    return true;
}

static void lock_cache(void *ud) { uv_mutex_lock(&((engine *)ud)->cache_lock); }
static void unlock_cache(void *ud) { uv_mutex_unlock(&((engine *)ud)->cache_lock); }

static void give_lease_back(engine *e, int i) {
    if (!e->rt[i].leased) return;
    sc_error ignored;
    uv_mutex_lock(&e->cache_lock);
    sc_cache_lease_release(e->cache, &e->run->results[i].key, &ignored);
    uv_mutex_unlock(&e->cache_lock);
    e->rt[i].leased = false;
}

/* Every LEASE_POLL_MS: renew this process's leases once a second, and look
 * again at the nodes that wait for another process's cook. */
static void tick(uv_timer_t *t) {
    engine *e = t->data;
    double now = sc_now();
    if (now - e->last_beat >= LEASE_BEAT_SECONDS) {
        sc_error ignored;
        uv_mutex_lock(&e->cache_lock);
        sc_cache_lease_renew(e->cache, &ignored);
        uv_mutex_unlock(&e->cache_lock);
        e->last_beat = now;
    }
    if (e->lease_waits == 0) return;
    for (int i = 0; i < e->g->count; i++) {
        if (e->rt[i].state != ST_LEASE_WAIT) continue;
        e->rt[i].state = ST_WAITING;
        e->lease_waits--;
    }
    pump(e);
}

/* Decide hit or miss for a node whose inputs' digests are all known. */
static void resolve(engine *e, int i) {
    node_rt *rt = &e->rt[i];
    sc_node_result *r = &e->run->results[i];
    rt->canon = canonical_action(e, i);
    if (!rt->canon) {
        sc_error err;
        sc_fail(&err, SC_ENOMEM, "out of memory");
        fail_node(e, i, SC_ENOMEM, &err);
        return;
    }
    sc_digest_bytes(rt->canon, strlen(rt->canon), &r->key);

    sc_cache_action act = {0};
    sc_error err = {0};
    const char *miss = NULL;
    sc_digest *dep_digests = NULL;
    uv_mutex_lock(&e->cache_lock);
    int rc = sc_cache_get_action(e->cache, &r->key, &act, &err);
    if (rc == SC_EMISS && e->opt->remote && !e->opt->dry_run) {
        /* the remote puts what it finds into the local cache, taking the lock itself;
         * the pass's transaction is closed meanwhile, so that other processes
         * sharing the cache do not wait on the network */
        sc_error ignored;
        if (e->batched) sc_cache_commit(e->cache, &ignored);
        uv_mutex_unlock(&e->cache_lock);
        bool fetched = sc_remote_fetch(e->opt->remote, &r->key, &err) == SC_OK;
        uv_mutex_lock(&e->cache_lock);
        if (e->batched) e->batched = sc_cache_begin(e->cache, &ignored) == SC_OK;
        if (fetched) rc = sc_cache_get_action(e->cache, &r->key, &act, &err);
    }
    if (rc == SC_OK) {
        dep_digests = calloc((size_t)act.ndeps + 1, sizeof *dep_digests);
        for (int d = 0; d < act.ndeps && !miss; d++) {
            sc_digest cur;
            char *abs = sc_path_resolve(e->base_dir, act.deps[d].path);   /* recorded relative to the base */
            if (!abs) {
                miss = "out of memory";
                break;
            }
            free(act.deps[d].path);
            act.deps[d].path = abs;
            if (sc_cache_file_changed(e->cache, act.deps[d].path, &act.deps[d].digest, &cur))
                miss = sc_digest_is_zero(&act.deps[d].digest) ? "a file that was missing is there now"
                                                              : "a source file changed";
            else if (dep_digests)
                dep_digests[d] = cur;   /* all zero for a file still missing */
        }
        if (!miss && (read_outputs(e, i, act.outputs) != 0 || !read_record(r, act.metrics)))
            miss = "the cache entry is unreadable";
        for (int k = 0; !miss && k < r->noutputs; k++)
            if (rt->kept[k] && !sc_cache_has_blob(e->cache, &r->outputs[k].digest))
                miss = "an output this graph reads is not in the cache";
    }
    uv_mutex_unlock(&e->cache_lock);
    if (miss) forget_result(r);   /* the record's metrics and warnings, if read */

    if (rc == SC_OK && !miss) {
        r->cooked_seconds = act.seconds;
        r->deps = calloc((size_t)act.ndeps + 1, sizeof(char *));
        for (int d = 0; r->deps && d < act.ndeps; d++) r->deps[r->ndeps++] = sc_strdup(act.deps[d].path);
        remember(e, i, dep_digests);
        r->dep_digests = dep_digests;
        dep_digests = NULL;
        sc_cache_action_free(&act);
        int mrc = materialize(e, i, &err);
        if (mrc == SC_OK) {
            set_terminal(e, i, ST_CACHED);
            return;
        }
        if (mrc != SC_EMISS) {
            fail_node(e, i, mrc, &err);
            return;
        }
        /* the record is fine but the bytes of a file it made are not: cook again */
        miss = "the bytes of a cached output are missing or corrupt";
        forget_result(r);
        rc = SC_EMISS;
        memset(&act, 0, sizeof act);
    }
    free(dep_digests);
    sc_cache_action_free(&act);
    forget_files(rt);

    /* a miss: one cook per action among the processes sharing the cache */
    if (!e->opt->dry_run && !take_lease(e, i)) return;

    /* find out why, from what this node was last time */
    if (e->opt->explain || e->opt->dry_run) {
        char *id = node_id(e, i), *before = NULL;
        uv_mutex_lock(&e->cache_lock);
        if (id) sc_cache_get_history(e->cache, id, &before, &err);
        uv_mutex_unlock(&e->cache_lock);
        r->why = explain(e, i, rt->canon, before);
        if (miss && r->why && strstr(r->why, "no cache entry")) {
            free(r->why);
            r->why = sc_strdup(miss);
        }
        free(id), free(before);
    }
    if (e->opt->dry_run) {
        say(e, "would cook %s (%s)%s%s", gnode(e, i)->name, gnode(e, i)->desc->type,
            r->why ? ": " : "", r->why ? r->why : "");
        set_terminal(e, i, ST_WOULD_RUN);
        return;
    }
    if (e->opt->explain) say(e, "why %s: %s", gnode(e, i)->name, r->why ? r->why : "?");
    rt->state = ST_NEED_RUN;
}

/* ---------------------------------------------------------------- jobs */

typedef enum job_kind { JOB_RUN, JOB_LOAD, JOB_STORE } job_kind;

typedef struct job {
    uv_work_t req;
    engine *e;
    int node;
    job_kind kind;
    int rc;
    sc_error err;
    double seconds;
    sc_ctx *ctx;
    bool *want_full, *want_mesh;   /* JOB_LOAD: which outputs to load */
    sc_value **full, **mesh;       /* JOB_LOAD: what was loaded */
    storer stored;                 /* JOB_STORE: blobs written */
    char *outputs, *record;        /* JOB_STORE: the action's record once they are */
    sc_cache_dep *deps;
    int ndeps;
} job;

/* Values whose digests are to be computed side by side (digest_outputs). */
typedef struct value_list {
    sc_value **items;
    int32_t count, cap;
    bool failed;
} value_list;

static void value_list_add(void *ud, sc_value *v) {
    value_list *l = ud;
    if (l->count == l->cap) {
        int32_t cap = l->cap ? 2 * l->cap : 16;
        sc_value **items = realloc(l->items, (size_t)cap * sizeof *items);
        if (!items) {
            l->failed = true;
            return;
        }
        l->items = items, l->cap = cap;
    }
    l->items[l->count++] = v;
}

static int digest_one(void *ud, int32_t i) {
    sc_value_digest(((sc_value *const *)ud)[i]);
    return SC_OK;
}

/* Every output's digest, computed on the worker that cooked it, so that the
 * loop thread only reads them: the parts (an atlas's mesh and images, a
 * lods' atlases and theirs, a report's files) side by side on `threads`,
 * then the values made of them. */
static void digest_outputs(sc_ctx *ctx, int noutputs, int threads) {
    value_list parts = {0};
    for (int k = 0; k < noutputs; k++) {
        sc_value *v = sc_ctx_output(ctx, k);
        if (!v) continue;
        int32_t from = parts.count;
        sc_value_parts(v, value_list_add, &parts);
        for (int32_t i = from, to = parts.count; i < to; i++) sc_value_parts(parts.items[i], value_list_add, &parts);
    }
    /* deepest first: a part's own parts are hashed before it asks for them */
    for (int32_t i = 0, j = parts.count - 1; i < j; i++, j--) {
        sc_value *t = parts.items[i];
        parts.items[i] = parts.items[j], parts.items[j] = t;
    }
    if (!parts.failed && parts.count > 0 && sc_parallel(threads, parts.count, digest_one, parts.items) != SC_OK)
        for (int32_t i = 0; i < parts.count; i++) sc_value_digest(parts.items[i]);
    free(parts.items);
    for (int k = 0; k < noutputs; k++)
        if (sc_ctx_output(ctx, k)) sc_value_digest(sc_ctx_output(ctx, k));
}

static void run_work(uv_work_t *req) {
    job *j = req->data;
    engine *e = j->e;
    const sc_graph_node *n = gnode(e, j->node);
    sc_value **inputs = calloc((size_t)n->desc->ninputs + 1, sizeof *inputs);
    if (!inputs) {
        j->rc = sc_fail(&j->err, SC_ENOMEM, "out of memory");
        return;
    }
    for (int port = 0; port < n->desc->ninputs; port++) {
        int p = n->input_node[port], k = n->input_port[port];
        if (p < 0) continue;
        inputs[port] = e->rt[p].values[k] ? e->rt[p].values[k] : e->rt[p].meshes[k];
    }
    double t = sc_now();
    j->ctx = sc_ctx_new(n->desc, n->params, inputs);
    free(inputs);
    if (!j->ctx) {
        j->rc = sc_fail(&j->err, SC_ENOMEM, "out of memory");
        return;
    }
    sc_ctx_set_threads(j->ctx, e->opt->jobs);
    j->rc = sc_ctx_run(j->ctx, &j->err);
    if (j->rc == SC_OK) digest_outputs(j->ctx, n->desc->noutputs, e->opt->jobs);
    j->seconds = sc_now() - t;
}

static char *metrics_json(const sc_ctx *ctx) {
    cJSON *o = cJSON_CreateObject();
    const sc_metric *m = sc_ctx_metrics(ctx);
    for (int k = 0; k < sc_ctx_nmetrics(ctx); k++) {
        if (m[k].value == m[k].value && m[k].value - m[k].value == 0)
            cJSON_AddNumberToObject(o, m[k].name, m[k].value);
        else
            cJSON_AddNullToObject(o, m[k].name);
    }
    char *s = cJSON_PrintUnformatted(o);
    cJSON_Delete(o);
    return s;
}

/* The files a failed run read or could not read, for watch to wait on. */
static void keep_deps_of_failure(sc_node_result *r, const sc_ctx *ctx) {
    int nd = sc_ctx_ndeps(ctx);
    r->deps = calloc((size_t)nd + 1, sizeof(char *));
    r->dep_digests = calloc((size_t)nd + 1, sizeof *r->dep_digests);
    if (!r->deps || !r->dep_digests) {
        free(r->deps), free(r->dep_digests);
        r->deps = NULL, r->dep_digests = NULL;
        return;
    }
    for (int d = 0; d < nd; d++) {
        r->dep_digests[r->ndeps] = *sc_ctx_dep_digest(ctx, d);
        if ((r->deps[r->ndeps] = sc_strdup(sc_ctx_dep_path(ctx, d)))) r->ndeps++;
    }
}

static void store_work(uv_work_t *req);
static void store_done(uv_work_t *req, int status);

/* What an action's record is built from, freed. */
static void free_record(sc_cache_dep *deps, int ndeps, char *outputs, char *record) {
    for (int d = 0; deps && d < ndeps; d++) free(deps[d].path);
    free(deps), free(outputs), free(record);
}

static void run_done(uv_work_t *req, int status) {
    (void)status;
    job *j = req->data;
    engine *e = j->e;
    int i = j->node;
    node_rt *rt = &e->rt[i];
    sc_node_result *r = &e->run->results[i];
    const sc_graph_node *n = gnode(e, i);
    e->inflight--;
    r->seconds = j->seconds;
    if (j->rc == SC_OK) {
        for (int k = 0; k < n->desc->noutputs; k++) {
            sc_value *v = sc_ctx_output(j->ctx, k);
            rt->values[k] = sc_value_retain(v);
            r->outputs[k].kind = v->kind;
            r->outputs[k].digest = *sc_value_digest(v);
            if (v->kind == SC_KIND_ATLAS) r->outputs[k].mesh = *sc_value_digest(v->as.atlas->mesh);
        }
        r->metrics_json = metrics_json(j->ctx);
        keep_warnings(r, j->ctx);
        char *record = r->metrics_json ? record_json(r) : NULL;
        int nd = sc_ctx_ndeps(j->ctx);
        r->deps = calloc((size_t)nd + 1, sizeof(char *));
        sc_digest *dep_digests = calloc((size_t)nd + 1, sizeof *dep_digests);
        sc_cache_dep *deps = calloc((size_t)nd + 1, sizeof *deps);
        bool paths_ok = true;
        for (int d = 0; r->deps && dep_digests && deps && d < nd; d++) {
            r->deps[r->ndeps++] = sc_strdup(sc_ctx_dep_path(j->ctx, d));
            dep_digests[d] = *sc_ctx_dep_digest(j->ctx, d);
            deps[d].path = sc_path_relative(e->base_dir, sc_ctx_dep_path(j->ctx, d));
            deps[d].digest = dep_digests[d];
            paths_ok = paths_ok && deps[d].path;
        }
        int rc = files_from_values(e, i);
        cJSON *oj = outputs_json(e, i);
        char *outputs = cJSON_PrintUnformatted(oj);
        cJSON_Delete(oj);
        if (rc == SC_OK && (!outputs || !record || !r->deps || !deps || !dep_digests || !paths_ok))
            rc = sc_fail(&j->err, SC_ENOMEM, "out of memory");
        if (rc == SC_OK) rc = materialize(e, i, &j->err);
        r->dep_digests = dep_digests;
        if (rc == SC_OK) {
            /* Consumers start now; the outputs go to the cache meanwhile,
             * and the action is recorded once they are there (store_done). */
            say(e, "cooked %s (%s) in %.3f s", n->name, n->desc->type, j->seconds);
            set_terminal(e, i, ST_DONE);
            j->kind = JOB_STORE;
            j->stored = (storer){.cache = e->cache, .lock = &e->cache_lock, .err = &j->err};
            j->outputs = outputs, j->record = record, j->deps = deps, j->ndeps = nd;
            e->stores++;
            uv_queue_work(&e->loop, &j->req, store_work, store_done);
            show_progress(e);
            pump(e);
            return;
        }
        free_record(deps, nd, outputs, record);
        give_lease_back(e, i);
        fail_node(e, i, rc, &j->err);
    } else {
        keep_deps_of_failure(r, j->ctx);
        give_lease_back(e, i);
        fail_node(e, i, j->rc, &j->err);
    }
    sc_ctx_free(j->ctx);
    free(j);
    show_progress(e);
    pump(e);
}

/* A cooked node's outputs into the cache (on a pool thread, beside the
 * cooks of its consumers). */
static void store_work(uv_work_t *req) {
    job *j = req->data;
    const sc_graph_node *n = gnode(j->e, j->node);
    for (int k = 0; k < n->desc->noutputs && j->stored.rc == SC_OK; k++)
        if (j->e->rt[j->node].kept[k]) store_value(&j->stored, sc_ctx_output(j->ctx, k));
}

/* Record the action once its blobs are stored. A node whose outputs cannot
 * be stored (a full disk) fails the run, though its consumers may have
 * cooked with them already. */
static void store_done(uv_work_t *req, int status) {
    (void)status;
    job *j = req->data;
    engine *e = j->e;
    int i = j->node;
    sc_node_result *r = &e->run->results[i];
    const sc_graph_node *n = gnode(e, i);
    e->stores--;
    int rc = j->stored.rc;
    if (rc == SC_OK) {
        sc_cache_action act = {
            .key = r->key, .node_type = (char *)n->desc->type, .outputs = j->outputs,
            .metrics = j->record, .ndeps = j->ndeps, .deps = j->deps,
            .nblobs = j->stored.nblobs, .blobs = j->stored.blobs, .seconds = j->seconds,
        };
        uv_mutex_lock(&e->cache_lock);
        rc = sc_cache_put_action(e->cache, &act, &j->err);
        uv_mutex_unlock(&e->cache_lock);
        if (rc == SC_OK && e->opt->remote) rc = sc_remote_upload(e->opt->remote, &act, &j->err);
        /* a concurrent gc took a blob: the result stands, it is just not recorded */
        if (rc == SC_EMISS) {
            say(e, "note: %s was cooked but not recorded: %s", n->name, j->err.message);
            rc = SC_OK;
        }
    }
    if (rc == SC_OK) remember(e, i, r->dep_digests);
    give_lease_back(e, i);   /* after the record: a waiter finds the result */
    if (rc != SC_OK) {   /* it counts as finished already, as cooked: now as failed */
        note_failure(e, i, rc, &j->err);
        e->rt[i].state = ST_FAILED;
        r->status = SC_STATUS_FAILED;
        e->run->ran--, e->run->failed++;
    }
    free_record(j->deps, j->ndeps, j->outputs, j->record);
    free(j->stored.blobs);
    sc_ctx_free(j->ctx);
    free(j);
    show_progress(e);
    pump(e);
}

static void load_work(uv_work_t *req) {
    job *j = req->data;
    engine *e = j->e;
    const sc_node_result *r = &e->run->results[j->node];
    uv_mutex_lock(&e->cache_lock);
    for (int k = 0; k < r->noutputs && j->rc == SC_OK; k++) {
        if (j->want_full[k]) {
            j->full[k] = sc_engine_load(e->cache, &r->outputs[k].digest, &j->err);
            if (!j->full[k]) j->rc = SC_EMISS;
        } else if (j->want_mesh[k]) {
            j->mesh[k] = sc_engine_load(e->cache, &r->outputs[k].mesh, &j->err);
            if (!j->mesh[k]) j->rc = SC_EMISS;
        }
    }
    uv_mutex_unlock(&e->cache_lock);
}

static void load_done(uv_work_t *req, int status) {
    (void)status;
    job *j = req->data;
    engine *e = j->e;
    int p = j->node;
    node_rt *rt = &e->rt[p];
    int nout = e->run->results[p].noutputs;
    e->loads--;
    rt->loading = false;
    if (j->rc == SC_OK) {
        for (int k = 0; k < nout; k++) {
            if (j->full[k]) rt->values[k] = j->full[k];
            if (j->mesh[k]) rt->meshes[k] = j->mesh[k];
        }
    } else {
        for (int k = 0; k < nout; k++) sc_value_release(j->full[k]), sc_value_release(j->mesh[k]);
        /* the cached bytes are gone or bad: cook the producer again */
        sc_node_result *r = &e->run->results[p];
        if (rt->state == ST_CACHED) e->run->cached--, e->done_count--;
        else if (rt->state == ST_DONE) e->run->ran--, e->done_count--;
        free(r->why);
        r->why = sc_strprintf("its cached output could not be read (%s)", j->err.message);
        if (e->opt->explain) say(e, "why %s: %s", gnode(e, p)->name, r->why);
        forget_result(r);
        forget_files(rt);
        rt->state = ST_NEED_RUN;
        r->status = SC_STATUS_PENDING;
        /* its consumers still count on it */
    }
    free(j->want_full), free(j->want_mesh), free(j->full), free(j->mesh);
    free(j);
    pump(e);
}

static void start_load(engine *e, int p) {
    int nout = e->run->results[p].noutputs;
    job *j = calloc(1, sizeof *j);
    if (!j) return;
    j->e = e, j->node = p, j->kind = JOB_LOAD, j->req.data = j;
    j->want_full = calloc((size_t)nout + 1, sizeof(bool));
    j->want_mesh = calloc((size_t)nout + 1, sizeof(bool));
    j->full = calloc((size_t)nout + 1, sizeof(sc_value *));
    j->mesh = calloc((size_t)nout + 1, sizeof(sc_value *));
    if (!j->want_full || !j->want_mesh || !j->full || !j->mesh) {
        free(j->want_full), free(j->want_mesh), free(j->full), free(j->mesh), free(j);
        return;
    }
    /* what do the consumers that must cook need? */
    for (int c = p + 1; c < e->g->count; c++) {
        if (e->rt[c].state != ST_NEED_RUN) continue;
        const sc_graph_node *n = gnode(e, c);
        for (int port = 0; port < n->desc->ninputs; port++) {
            if (n->input_node[port] != p) continue;
            int k = n->input_port[port];
            if (e->rt[p].values[k]) continue;
            if (wants_mesh_only(e, c, port)) {
                if (!e->rt[p].meshes[k]) j->want_mesh[k] = true;
            } else {
                j->want_full[k] = true;
            }
        }
    }
    e->rt[p].loading = true;
    e->loads++;
    uv_queue_work(&e->loop, &j->req, load_work, load_done);
}

static void start_run(engine *e, int i) {
    job *j = calloc(1, sizeof *j);
    if (!j) return;
    j->e = e, j->node = i, j->kind = JOB_RUN, j->req.data = j;
    e->rt[i].state = ST_RUNNING;
    e->inflight++;
    show_progress(e);
    uv_queue_work(&e->loop, &j->req, run_work, run_done);
}

/* Whether every input value node i needs is in memory; starts loads if not. */
static bool inputs_in_memory(engine *e, int i) {
    const sc_graph_node *n = gnode(e, i);
    bool ready = true;
    for (int port = 0; port < n->desc->ninputs; port++) {
        int p = n->input_node[port], k = n->input_port[port];
        if (p < 0) continue;
        node_rt *prt = &e->rt[p];
        if (prt->values[k] || (wants_mesh_only(e, i, port) && prt->meshes[k])) continue;
        ready = false;
        if ((prt->state == ST_CACHED || prt->state == ST_DONE) && !prt->loading) start_load(e, p);
    }
    return ready;
}

static void pump(engine *e) {
    /* one index transaction for the whole pass: a pass over hundreds of
     * cached nodes then takes SQLite's locks once, not once per lookup */
    sc_error ignored;
    uv_mutex_lock(&e->cache_lock);
    e->batched = !e->opt->dry_run && sc_cache_begin(e->cache, &ignored) == SC_OK;
    uv_mutex_unlock(&e->cache_lock);
    bool progress = true;
    while (progress) {
        progress = false;
        for (int i = 0; i < e->g->count; i++) {
            node_rt *rt = &e->rt[i];
            if (rt->state != ST_WAITING) continue;
            const sc_graph_node *n = gnode(e, i);
            bool known = true, blocked = false, would = false;
            for (int port = 0; port < n->desc->ninputs; port++) {
                int p = n->input_node[port];
                if (p < 0) continue;
                node_state ps = e->rt[p].state;
                if (ps == ST_FAILED || ps == ST_SKIPPED) blocked = true;
                else if (ps == ST_WOULD_RUN) would = true;
                else if (ps != ST_CACHED && ps != ST_DONE) known = false;
            }
            if (blocked || (e->stop && known)) {
                set_terminal(e, i, ST_SKIPPED);
                progress = true;
            } else if (would) {
                sc_node_result *r = &e->run->results[i];
                for (int port = 0; port < n->desc->ninputs && !r->why; port++) {
                    int p = n->input_node[port];
                    if (p >= 0 && e->rt[p].state == ST_WOULD_RUN)
                        r->why = sc_strprintf("input %s comes from %s, which would cook",
                                              n->desc->inputs[port].name, gnode(e, p)->name);
                }
                say(e, "would cook %s (%s): %s", n->name, n->desc->type, r->why ? r->why : "");
                set_terminal(e, i, ST_WOULD_RUN);
                progress = true;
            } else if (known) {
                resolve(e, i);
                progress = true;
            }
        }
        for (int r = 0; r < e->g->count; r++) {
            int i = e->start_order ? e->start_order[r] : r;   /* none: out of memory, stopping */
            if (e->rt[i].state != ST_NEED_RUN) continue;
            if (e->stop) {
                set_terminal(e, i, ST_SKIPPED);
                progress = true;
                continue;
            }
            if (e->inflight >= e->opt->jobs) continue;
            if (inputs_in_memory(e, i)) {
                start_run(e, i);
                progress = true;
            }
        }
    }
    if (e->batched) {
        e->batched = false;
        uv_mutex_lock(&e->cache_lock);
        sc_cache_commit(e->cache, &ignored);
        uv_mutex_unlock(&e->cache_lock);
    }
}

/* The order in which nodes ready to cook start: the longest chain of
 * consumers after a node first (the critical path), then graph order. With
 * fewer job slots than ready nodes, a node many others wait on starts before
 * a leaf (the main job's bake_displacement before its save and first crack
 * check, which nothing reads). */
typedef struct start_rank {
    int chain, index;
} start_rank;

static int longer_chain_first(const void *a, const void *b) {
    const start_rank *x = a, *y = b;
    if (x->chain != y->chain) return y->chain - x->chain;
    return x->index - y->index;
}

static int *start_order_build(const sc_graph *g) {
    start_rank *rank = calloc((size_t)g->count + 1, sizeof *rank);
    int *order = calloc((size_t)g->count + 1, sizeof *order);
    if (!rank || !order) {
        free(rank), free(order);
        return NULL;
    }
    for (int i = 0; i < g->count; i++) rank[i] = (start_rank){1, i};
    for (int i = g->count - 1; i >= 0; i--)   /* producers come before consumers */
        for (int port = 0; port < g->nodes[i].desc->ninputs; port++) {
            int p = g->nodes[i].input_node[port];
            if (p >= 0 && rank[p].chain < rank[i].chain + 1) rank[p].chain = rank[i].chain + 1;
        }
    qsort(rank, (size_t)g->count, sizeof *rank, longer_chain_first);
    for (int i = 0; i < g->count; i++) order[i] = rank[i].index;
    free(rank);
    return order;
}

/* ---------------------------------------------------------------- the run */

int sc_engine_run(const sc_graph *g, sc_cache *cache, const sc_engine_options *opt,
                  sc_run **out, sc_error *err) {
    *out = NULL;
    engine e = {.g = g, .cache = cache, .opt = opt};
    sc_run *run = calloc(1, sizeof *run);
    e.rt = calloc((size_t)g->count + 1, sizeof *e.rt);
    if (!run || !e.rt) {
        free(run), free(e.rt);
        return sc_fail(err, SC_ENOMEM, "out of memory");
    }
    run->graph = g;
    run->results = calloc((size_t)g->count + 1, sizeof *run->results);
    e.run = run;
    if (!run->results) {
        free(e.rt);
        sc_run_free(run);
        return sc_fail(err, SC_ENOMEM, "out of memory");
    }
    for (int i = 0; i < g->count; i++) {
        int nout = g->nodes[i].desc->noutputs;
        run->results[i].noutputs = nout;
        run->results[i].outputs = calloc((size_t)nout + 1, sizeof(sc_node_output));
        e.rt[i].values = calloc((size_t)nout + 1, sizeof(sc_value *));
        e.rt[i].meshes = calloc((size_t)nout + 1, sizeof(sc_value *));
        if (!run->results[i].outputs || !e.rt[i].values || !e.rt[i].meshes) {
            e.stop = true;
            e.first_rc = sc_fail(&e.first_err, SC_ENOMEM, "out of memory");
        }
        e.rt[i].kept = calloc((size_t)nout + 1, sizeof(bool));
        if (!e.rt[i].kept) {
            e.stop = true;
            e.first_rc = sc_fail(&e.first_err, SC_ENOMEM, "out of memory");
        }
    }
    for (int i = 0; i < g->count && !e.stop; i++)
        for (int port = 0; port < g->nodes[i].desc->ninputs; port++) {
            int p = g->nodes[i].input_node[port];
            if (p < 0) continue;
            e.rt[p].pending_consumers++;
            e.rt[p].kept[g->nodes[i].input_port[port]] = true;
        }
    for (int i = 0; i < g->count && !e.stop; i++)   /* a node no node reads is a result: all of it */
        for (int k = 0; k < g->nodes[i].desc->noutputs; k++)
            if (g->nodes[i].desc->outputs[k].kind == SC_KIND_REPORT || e.rt[i].pending_consumers == 0)
                e.rt[i].kept[k] = true;
    if (!e.stop && !(e.start_order = start_order_build(g))) {
        e.stop = true;
        e.first_rc = sc_fail(&e.first_err, SC_ENOMEM, "out of memory");
    }
    if (!realpath(g->file, e.graph_path)) snprintf(e.graph_path, sizeof e.graph_path, "%s", g->file);
    char *graph_dir = sc_path_dirname(e.graph_path);
    if (!opt->base_dir || !realpath(opt->base_dir, e.base_dir))
        snprintf(e.base_dir, sizeof e.base_dir, "%s", opt->base_dir ? opt->base_dir : graph_dir ? graph_dir : "/");
    free(graph_dir);
    e.t0 = sc_now();
    uv_loop_init(&e.loop);
    uv_mutex_init(&e.cache_lock);
    sc_remote_set_lock(opt->remote, lock_cache, unlock_cache, &e);
    uv_timer_init(&e.loop, &e.tick);
    e.tick.data = &e;
    e.last_beat = e.t0;
    if (!opt->dry_run) uv_timer_start(&e.tick, tick, LEASE_POLL_MS, LEASE_POLL_MS);
    if (!e.stop) {
        pump(&e);
        while (e.inflight > 0 || e.stores > 0 || e.loads > 0 || e.lease_waits > 0) {
            uv_run(&e.loop, UV_RUN_ONCE);
        }
    }
    uv_timer_stop(&e.tick);
    uv_close((uv_handle_t *)&e.tick, NULL);
    sc_remote_set_lock(opt->remote, NULL, NULL, NULL);
    if (!opt->dry_run) {
        sc_error ignored;
        sc_cache_lease_release(cache, NULL, &ignored);   /* any this run still holds */
    }
    /* anything left could not cook */
    for (int i = 0; i < g->count; i++)
        if (e.rt[i].state == ST_WAITING || e.rt[i].state == ST_NEED_RUN) set_terminal(&e, i, ST_SKIPPED);
    uv_run(&e.loop, UV_RUN_DEFAULT);
    uv_loop_close(&e.loop);
    uv_mutex_destroy(&e.cache_lock);
    run->seconds = sc_now() - e.t0;
    if (opt->log && opt->live) {
        fputs("\r\033[K", opt->log);
        fflush(opt->log);
    }
    for (int i = 0; i < g->count; i++) {
        for (int k = 0; k < g->nodes[i].desc->noutputs; k++) {
            if (e.rt[i].values) sc_value_release(e.rt[i].values[k]);
            if (e.rt[i].meshes) sc_value_release(e.rt[i].meshes[k]);
        }
        free(e.rt[i].values), free(e.rt[i].meshes), free(e.rt[i].kept), free(e.rt[i].canon);
        forget_files(&e.rt[i]);
    }
    free(e.rt), free(e.start_order);
    for (int k = 0; k < e.claim_cap; k++) free(e.claims[k].path);
    free(e.claims);
    if (!opt->dry_run) {
        sc_error ignored;
        sc_cache_put_run(cache, g->file, run->ran, run->cached, run->failed, run->seconds, &ignored);
    }
    *out = run;
    if (e.stop) {
        if (err) *err = e.first_err;
        return e.first_rc ? e.first_rc : SC_EINPUT;
    }
    return SC_OK;
}

void sc_run_free(sc_run *r) {
    if (!r) return;
    for (int i = 0; r->results && i < r->graph->count; i++) {
        sc_node_result *x = &r->results[i];
        free(x->outputs), free(x->metrics_json), free(x->why), free(x->error);
        for (int k = 0; k < x->nwarnings; k++) free(x->warnings[k]);
        free(x->warnings);
        for (int f = 0; f < x->nfiles; f++) free(x->files[f]);
        for (int d = 0; d < x->ndeps; d++) free(x->deps[d]);
        free(x->files), free(x->file_digests), free(x->deps), free(x->dep_digests);
    }
    free(r->results);
    free(r);
}
