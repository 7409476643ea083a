/* sc_exec.h - running one node: the engine's side of sc_ctx.
 *
 * The scheduler makes a context per node run; tests and benchmarks use the
 * same calls to run a node on values they made themselves:
 *
 *     sc_ctx *ctx = sc_ctx_new(&sc_node_erase_seams, params, inputs);
 *     sc_ctx_set_param(ctx, "preset", "global");
 *     if (sc_ctx_run(ctx, &err) == SC_OK) out = sc_ctx_output(ctx, 0);
 *     sc_ctx_free(ctx);
 */
#ifndef SC_EXEC_H
#define SC_EXEC_H

#include "sc_graph.h"

/* params: desc->nparams values (copied), or NULL for the defaults.
 * inputs: desc->ninputs values (retained; NULL for unconnected), or NULL. */
sc_ctx *sc_ctx_new(const sc_node_desc *desc, const sc_param_value *params,
                   sc_value *const *inputs);
void sc_ctx_free(sc_ctx *ctx);

/* Set an input or a parameter after sc_ctx_new (for tests and benchmarks).
 * set_param parses text as the parameter's type (sc_param_parse: "1.5", "true",
 * "0.5,0.1") and checks it. */
int sc_ctx_set_input(sc_ctx *ctx, const char *port, sc_value *value);   /* retains */
int sc_ctx_set_param(sc_ctx *ctx, const char *name, const char *text, sc_error *err);
void sc_ctx_set_threads(sc_ctx *ctx, int threads);

/* Run the node. On failure every output is dropped. */
int sc_ctx_run(sc_ctx *ctx, sc_error *err);

/* After a run: output by index (borrowed; NULL if unset), the metrics and the
 * files read (or, after a failure, tried). */
sc_value *sc_ctx_output(sc_ctx *ctx, int port);
int sc_ctx_nmetrics(const sc_ctx *ctx);
const sc_metric *sc_ctx_metrics(const sc_ctx *ctx);
/* The metric with this name, or NAN. */
double sc_ctx_metric_value(const sc_ctx *ctx, const char *name);
/* The lines run() gave sc_ctx_warn, in order. */
int sc_ctx_nwarnings(const sc_ctx *ctx);
const char *sc_ctx_warning(const sc_ctx *ctx, int i);
int sc_ctx_ndeps(const sc_ctx *ctx);
const char *sc_ctx_dep_path(const sc_ctx *ctx, int i);
/* The digest of the bytes read; all zero for a file the node tried to read
 * and could not. */
const sc_digest *sc_ctx_dep_digest(const sc_ctx *ctx, int i);

#endif
