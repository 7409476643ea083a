/* sc_exec.c - the context a node runs in.
 *
 * Design note: the context is the whole world of a running node. It holds
 * the input values (one reference each), a private copy of the parameter
 * values, and collects outputs, metrics and the files the node read (with the
 * digest of the bytes it actually got, so the cache records exactly what the
 * result depends on). Nothing in it is shared between runs, so nodes can run
 * on several threads at once.
 *
 * The context is also where a node's descriptor is held to: a node that asks
 * for a parameter, input or output its descriptor does not declare (or for a
 * parameter as another type) gets a neutral answer (NULL, 0 or ""), and its
 * run fails naming the first such name, whatever run() returned. So the
 * parameters and ports a node reads are exactly the ones the action key and
 * `seamcook nodes` know about.
 */
#include "sc_exec.h"

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef struct dep {
    char *path;
    sc_digest digest;   /* of the bytes read; all zero for a file that could not be read */
} dep;

struct sc_ctx {
    const sc_node_desc *desc;
    sc_param_value *params;
    sc_value **inputs;
    sc_value **outputs;
    sc_metric *metrics;
    int nmetrics;
    char **warnings;
    int nwarnings;
    dep *deps;
    int ndeps;
    int threads;
    char misuse[160];   /* the first parameter or port name run() got wrong, or "" */
};

/* Remember the first name run() asks for that its descriptor does not
 * declare (or declares as another type): sc_ctx_run fails on it. */
static void misuse(sc_ctx *ctx, const char *what, const char *name) {
    if (!ctx->misuse[0]) snprintf(ctx->misuse, sizeof ctx->misuse, "%s '%s'", what, name);
}

static int copy_param(sc_param_value *dst, const sc_param_value *src) {
    *dst = *src;
    dst->string = NULL, dst->numbers = NULL;
    if (src->string && !(dst->string = sc_strdup(src->string))) return SC_ENOMEM;
    if (src->count > 0) {
        dst->numbers = sc_alloc_array((size_t)src->count, sizeof(double));
        if (!dst->numbers) return SC_ENOMEM;
        memcpy(dst->numbers, src->numbers, sizeof(double) * (size_t)src->count);
    }
    return SC_OK;
}

sc_ctx *sc_ctx_new(const sc_node_desc *desc, const sc_param_value *params,
                   sc_value *const *inputs) {
    sc_ctx *ctx = calloc(1, sizeof *ctx);
    if (!ctx) return NULL;
    ctx->desc = desc;
    ctx->threads = 1;
    ctx->params = calloc((size_t)desc->nparams + 1, sizeof *ctx->params);
    ctx->inputs = calloc((size_t)desc->ninputs + 1, sizeof *ctx->inputs);
    ctx->outputs = calloc((size_t)desc->noutputs + 1, sizeof *ctx->outputs);
    if (!ctx->params || !ctx->inputs || !ctx->outputs) {
        sc_ctx_free(ctx);
        return NULL;
    }
    if (params) {
        for (int i = 0; i < desc->nparams; i++)
            if (copy_param(&ctx->params[i], &params[i]) != SC_OK) {
                sc_ctx_free(ctx);
                return NULL;
            }
    } else {
        /* defaults, the way a graph node starts */
        sc_graph *g = sc_graph_new("");
        int k = g ? sc_graph_add(g, desc, "", 0) : -1;
        for (int i = 0; k >= 0 && i < desc->nparams; i++)
            copy_param(&ctx->params[i], &g->nodes[k].params[i]);
        sc_graph_free(g);
        if (k < 0) {
            sc_ctx_free(ctx);
            return NULL;
        }
    }
    if (inputs)
        for (int i = 0; i < desc->ninputs; i++) ctx->inputs[i] = sc_value_retain(inputs[i]);
    return ctx;
}

static void drop_outputs(sc_ctx *ctx) {
    for (int i = 0; i < ctx->desc->noutputs; i++) {
        sc_value_release(ctx->outputs[i]);
        ctx->outputs[i] = NULL;
    }
}

void sc_ctx_free(sc_ctx *ctx) {
    if (!ctx) return;
    if (ctx->params)
        for (int i = 0; i < ctx->desc->nparams; i++) sc_param_value_clear(&ctx->params[i]);
    if (ctx->inputs)
        for (int i = 0; i < ctx->desc->ninputs; i++) sc_value_release(ctx->inputs[i]);
    if (ctx->outputs) drop_outputs(ctx);
    for (int i = 0; i < ctx->nmetrics; i++) free(ctx->metrics[i].name);
    for (int i = 0; i < ctx->ndeps; i++) free(ctx->deps[i].path);
    for (int i = 0; i < ctx->nwarnings; i++) free(ctx->warnings[i]);
    free(ctx->warnings);
    free(ctx->params), free(ctx->inputs), free(ctx->outputs);
    free(ctx->metrics), free(ctx->deps);
    free(ctx);
}

int sc_ctx_set_input(sc_ctx *ctx, const char *port, sc_value *value) {
    int i = sc_desc_input(ctx->desc, port);
    if (i < 0) return SC_EINPUT;
    sc_value_release(ctx->inputs[i]);
    ctx->inputs[i] = sc_value_retain(value);
    return SC_OK;
}

int sc_ctx_set_param(sc_ctx *ctx, const char *name, const char *text, sc_error *err) {
    int i = sc_desc_param(ctx->desc, name);
    if (i < 0) return sc_fail(err, SC_EINPUT, "%s: unknown parameter '%s'", ctx->desc->type, name);
    const sc_param_desc *pd = &ctx->desc->params[i];
    sc_param_value v;
    if (sc_param_parse(pd, text, &v, err) != SC_OK) {
        sc_param_value_clear(&v);
        return sc_error_prefix(err, "%s:%s", ctx->desc->type, name);
    }
    int rc = sc_param_check(pd, &v, ctx->desc->type, err);
    if (rc != SC_OK) {
        sc_param_value_clear(&v);
        return rc;
    }
    sc_param_value_clear(&ctx->params[i]);
    ctx->params[i] = v;
    return SC_OK;
}

void sc_ctx_set_threads(sc_ctx *ctx, int threads) { ctx->threads = threads > 0 ? threads : 1; }

int sc_ctx_run(sc_ctx *ctx, sc_error *err) {
    drop_outputs(ctx);
    for (int i = 0; i < ctx->desc->ninputs; i++)
        if (!ctx->inputs[i] && !ctx->desc->inputs[i].optional)
            return sc_fail(err, SC_EINPUT, "input '%s' is not connected", ctx->desc->inputs[i].name);
    sc_error local = {0};
    if (!err) err = &local;
    ctx->misuse[0] = 0;
    int rc = ctx->desc->run(ctx, err);
    if (ctx->misuse[0])   /* a programming error in the node, whatever run() returned */
        rc = sc_fail(err, SC_EINPUT, "node %s asked for %s, which its descriptor does not declare", ctx->desc->type,
                     ctx->misuse);
    if (rc == SC_OK) {
        for (int i = 0; i < ctx->desc->noutputs; i++)
            if (!ctx->outputs[i]) {
                rc = sc_fail(err, SC_EINPUT, "produced no '%s' output", ctx->desc->outputs[i].name);
                break;
            }
    } else if (!err->message[0]) {
        sc_fail(err, rc, "failed");
    }
    if (rc != SC_OK) drop_outputs(ctx);
    return rc;
}

sc_value *sc_ctx_output(sc_ctx *ctx, int port) {
    return (port >= 0 && port < ctx->desc->noutputs) ? ctx->outputs[port] : NULL;
}

int sc_ctx_nmetrics(const sc_ctx *ctx) { return ctx->nmetrics; }
const sc_metric *sc_ctx_metrics(const sc_ctx *ctx) { return ctx->metrics; }

double sc_ctx_metric_value(const sc_ctx *ctx, const char *name) {
    for (int i = 0; i < ctx->nmetrics; i++)
        if (strcmp(ctx->metrics[i].name, name) == 0) return ctx->metrics[i].value;
    return NAN;
}

int sc_ctx_ndeps(const sc_ctx *ctx) { return ctx->ndeps; }
const char *sc_ctx_dep_path(const sc_ctx *ctx, int i) { return ctx->deps[i].path; }
const sc_digest *sc_ctx_dep_digest(const sc_ctx *ctx, int i) { return &ctx->deps[i].digest; }

/* ---------------------------------------------------------------- the node's side */

const sc_value *sc_ctx_input(sc_ctx *ctx, const char *port) {
    int i = sc_desc_input(ctx->desc, port);
    if (i < 0) {
        misuse(ctx, "input", port);
        return NULL;
    }
    const sc_value *v = ctx->inputs[i];
    /* a mesh port fed an atlas sees the atlas's mesh */
    if (v && ctx->desc->inputs[i].kind == SC_KIND_MESH && v->kind == SC_KIND_ATLAS)
        v = v->as.atlas->mesh;
    return v;
}

#define TYPED_INPUT(fn, type, KIND, member)                         \
    const type *fn(sc_ctx *ctx, const char *port) {                 \
        const sc_value *v = sc_ctx_input(ctx, port);                \
        return (v && v->kind == KIND) ? v->as.member : NULL;        \
    }
TYPED_INPUT(sc_ctx_mesh, sc_mesh, SC_KIND_MESH, mesh)
TYPED_INPUT(sc_ctx_atlas, sc_atlas, SC_KIND_ATLAS, atlas)
TYPED_INPUT(sc_ctx_image, sc_image_data, SC_KIND_IMAGE, image)
TYPED_INPUT(sc_ctx_lods, sc_lods, SC_KIND_LODS, lods)

typedef enum param_use { USE_NUMBER, USE_STRING, USE_NUMBERS } param_use;

static bool used_as(sc_param_type t, param_use use) {
    switch (t) {
    case SC_PARAM_NUMBER:
    case SC_PARAM_INTEGER:
    case SC_PARAM_BOOL:
        return use == USE_NUMBER;
    case SC_PARAM_STRING:
    case SC_PARAM_ENUM:
    case SC_PARAM_PATH:
        return use == USE_STRING;
    case SC_PARAM_NUMBERS:
        return use == USE_NUMBERS;
    }
    return false;
}

/* The parameter `name` read as `use`; NULL (and the misuse noted) when the
 * descriptor has no such parameter of that type. */
static const sc_param_value *param(sc_ctx *ctx, const char *name, param_use use) {
    int i = sc_desc_param(ctx->desc, name);
    if (i < 0 || !used_as(ctx->desc->params[i].type, use)) {
        misuse(ctx, i < 0 ? "parameter" : "parameter (as another type)", name);
        return NULL;
    }
    return &ctx->params[i];
}

double sc_ctx_number(sc_ctx *ctx, const char *name) {
    const sc_param_value *p = param(ctx, name, USE_NUMBER);
    return p ? p->number : 0;
}

int64_t sc_ctx_integer(sc_ctx *ctx, const char *name) {
    return (int64_t)llround(sc_ctx_number(ctx, name));
}

bool sc_ctx_bool(sc_ctx *ctx, const char *name) { return sc_ctx_number(ctx, name) != 0; }

const char *sc_ctx_string(sc_ctx *ctx, const char *name) {
    const sc_param_value *p = param(ctx, name, USE_STRING);
    return (p && p->string) ? p->string : "";
}

const double *sc_ctx_numbers(sc_ctx *ctx, const char *name, int *count) {
    const sc_param_value *p = param(ctx, name, USE_NUMBERS);
    *count = p ? p->count : 0;
    return p ? p->numbers : NULL;
}

int sc_ctx_read_file(sc_ctx *ctx, const char *path, size_t max_bytes, sc_buf *out,
                     sc_error *err) {
    int rc = sc_read_file(path, max_bytes, out, err);
    /* a file that could not be read is kept too, as missing: a watch waits for it */
    dep *d = realloc(ctx->deps, sizeof *d * (size_t)(ctx->ndeps + 1));
    if (!d) return sc_fail(err, SC_ENOMEM, "out of memory");
    ctx->deps = d;
    d += ctx->ndeps;
    *d = (dep){.path = sc_strdup(path)};
    if (!d->path) return sc_fail(err, SC_ENOMEM, "out of memory");
    if (rc == SC_OK) sc_digest_bytes(out->data, out->len, &d->digest);
    ctx->ndeps++;
    return rc;
}

void sc_ctx_set_output(sc_ctx *ctx, const char *port, sc_value *value) {
    int i = sc_desc_output(ctx->desc, port);
    if (i < 0) {
        misuse(ctx, "output", port);
        sc_value_release(value);
        return;
    }
    sc_value_release(ctx->outputs[i]);
    ctx->outputs[i] = value;
}

void sc_ctx_metric(sc_ctx *ctx, const char *name, double value) {
    for (int i = 0; i < ctx->nmetrics; i++)
        if (strcmp(ctx->metrics[i].name, name) == 0) {
            ctx->metrics[i].value = value;
            return;
        }
    sc_metric *m = realloc(ctx->metrics, sizeof *m * (size_t)(ctx->nmetrics + 1));
    if (!m) return;
    ctx->metrics = m;
    m[ctx->nmetrics].name = sc_strdup(name);
    m[ctx->nmetrics].value = value;
    if (m[ctx->nmetrics].name) ctx->nmetrics++;
}

void sc_ctx_warn(sc_ctx *ctx, const char *fmt, ...) {
    char line[512];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(line, sizeof line, fmt, ap);
    va_end(ap);
    char **w = realloc(ctx->warnings, sizeof *w * (size_t)(ctx->nwarnings + 1));
    if (!w) return;
    ctx->warnings = w;
    if ((w[ctx->nwarnings] = sc_strdup(line))) ctx->nwarnings++;
}

int sc_ctx_nwarnings(const sc_ctx *ctx) { return ctx->nwarnings; }
const char *sc_ctx_warning(const sc_ctx *ctx, int i) { return ctx->warnings[i]; }

int sc_ctx_threads(sc_ctx *ctx) { return ctx->threads; }
