/* sc_node.h - what a node is, and all a node may see while it runs.
 *
 * A node is a pure function (inputs, params) -> (outputs, metrics). It is
 * described by one constant sc_node_desc, exported from its file in nodes/ and
 * listed in the registry (app/sc_registry.c). A node knows nothing of
 * graphs, scheduling, Lua, the cache or the command line: it reads its inputs
 * and parameters through sc_ctx, and sets its outputs and metrics there.
 *
 * Purity rules: no global mutable state, no clock in outputs, no environment,
 * no file access except sc_ctx_read_file (which records the file as a
 * dependency so the cache can notice when it changes). Bump `version`
 * whenever the node's own code can change its output bytes for the same
 * inputs; a change in a kernel it lists bumps that kernel's version instead.
 */
#ifndef SC_NODE_H
#define SC_NODE_H

#include "sc_value.h"

typedef enum sc_param_type {
    SC_PARAM_NUMBER = 1,   /* double, within [min, max] */
    SC_PARAM_INTEGER,      /* integral double, within [min, max] */
    SC_PARAM_BOOL,
    SC_PARAM_STRING,
    SC_PARAM_ENUM,         /* a string among choices */
    SC_PARAM_PATH,         /* a file path, resolved against the working directory */
    SC_PARAM_NUMBERS,      /* a list of numbers, each within [min, max] */
} sc_param_type;

typedef struct sc_param_desc {
    const char *name;
    sc_param_type type;
    const char *doc;
    double def;                  /* NUMBER, INTEGER, BOOL (0/1) */
    const char *def_string;      /* STRING, ENUM, PATH; NULL with `required` */
    double min, max;             /* NUMBER, INTEGER, NUMBERS */
    const char *const *choices;  /* ENUM: NULL-terminated */
    bool required;               /* no default: the graph must give it */
    /* Optional rules a value must meet beyond its type, range and choices:
     * for NUMBERS, on the whole list (an order, say); for STRING and PATH, on
     * the text (a list of names it must parse as). They are part of the
     * parameter's check, so a graph that breaks one fails when it is built
     * (a dry run too), not when the node cooks; run() may call the same
     * function. SC_OK, or err filled with text that follows "node:param: ". */
    int (*check_list)(const double *values, int count, sc_error *err);
    int (*check_text)(const char *text, sc_error *err);
} sc_param_desc;

typedef struct sc_port_desc {
    const char *name;
    sc_kind kind;
    const char *doc;
    bool optional;               /* inputs only */
} sc_port_desc;

typedef struct sc_ctx sc_ctx;

typedef struct sc_node_desc {
    const char *type;            /* "load_atlas" */
    int version;                 /* implementation version, >= 1 */
    const char *summary;         /* one line */
    const sc_port_desc *inputs;
    int ninputs;
    const sc_port_desc *outputs;
    int noutputs;
    const sc_param_desc *params;
    int nparams;
    /* Produce every output or fail with err filled (no output is kept then).
     * The message should name the parameter or input at fault; the engine
     * prefixes it with the node's name and graph file:line. */
    int (*run)(sc_ctx *ctx, sc_error *err);
    /* The kernels (nodes/lib) run calls, NULL-terminated, or NULL: the
     * action key hashes each one's name and version and those of the
     * kernels it builds on, so a kernel change re-keys this node. */
    const sc_kernel *const *kernels;
} sc_node_desc;

#define SC_COUNT(a) ((int)(sizeof(a) / sizeof((a)[0])))

/* ---------------------------------------------------------------- inputs */

/* The value on an input port, or NULL for an unconnected optional port (an
 * undeclared port name fails the run, see the parameters below).
 * The ctx keeps the reference; retain it to keep it past run(). An input port
 * of kind MESH fed by an ATLAS output receives that atlas's mesh. */
const sc_value *sc_ctx_input(sc_ctx *ctx, const char *port);

/* Typed shortcuts; NULL when unconnected. */
const sc_mesh *sc_ctx_mesh(sc_ctx *ctx, const char *port);
const sc_atlas *sc_ctx_atlas(sc_ctx *ctx, const char *port);
const sc_image_data *sc_ctx_image(sc_ctx *ctx, const char *port);
const sc_lods *sc_ctx_lods(sc_ctx *ctx, const char *port);

/* ---------------------------------------------------------------- params */

/* Validated parameter values (defaults filled in). Asking for a name the
 * descriptor does not declare, or through the call of another type, is a
 * programming error: it returns 0/"" and fails the run (sc_ctx_run names
 * it), as does asking for an undeclared input or output port. */
double sc_ctx_number(sc_ctx *ctx, const char *name);
int64_t sc_ctx_integer(sc_ctx *ctx, const char *name);
bool sc_ctx_bool(sc_ctx *ctx, const char *name);
const char *sc_ctx_string(sc_ctx *ctx, const char *name);   /* STRING, ENUM, PATH */
const double *sc_ctx_numbers(sc_ctx *ctx, const char *name, int *count);

/* ---------------------------------------------------------------- files */

/* Read a file the node depends on (the PATH parameter's file, or a file it
 * names: an MTL, a texture). The engine records (path, content digest) so a
 * later change of that file invalidates the cached result. Relative paths are
 * taken as they are (PATH parameters arrive absolute). */
int sc_ctx_read_file(sc_ctx *ctx, const char *path, size_t max_bytes, sc_buf *out,
                     sc_error *err);

/* ---------------------------------------------------------------- outputs */

/* Set an output; takes the reference. Setting a port twice replaces it. */
void sc_ctx_set_output(sc_ctx *ctx, const char *port, sc_value *value);

/* Record a metric for report.json (numbers only; NaN is written as null). */
void sc_ctx_metric(sc_ctx *ctx, const char *name, double value);

/* Say, in one line without a newline, where the result falls short of what
 * was asked: a level that stops above its target, a texture missing or
 * skipped, a map left unerased. The outputs still stand. The engine keeps
 * the line with the cooked result, so a cache hit says it again; the command
 * line prints it on stderr naming the node, and --strict makes it exit 1. */
void sc_ctx_warn(sc_ctx *ctx, const char *fmt, ...) __attribute__((format(printf, 2, 3)));

/* Number of worker threads the node may use for its own parallel loops
 * (the engine's -j); results must not depend on it. */
int sc_ctx_threads(sc_ctx *ctx);

#endif
