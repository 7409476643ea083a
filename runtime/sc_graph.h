/* sc_graph.h - a graph of node instances, as a graph file builds it.
 *
 * Nodes are stored in creation order, which is a topological order (a node can
 * only name nodes made before it). Each node keeps where the graph file made
 * it (file:line) so every message can point there. Parameters are validated
 * against the descriptor when the node is added; sc_graph_validate checks the
 * whole graph (port kinds, required inputs, cycles, duplicate names) before
 * anything cooks.
 */
#ifndef SC_GRAPH_H
#define SC_GRAPH_H

#include "sc_node.h"

typedef struct sc_param_value {
    sc_param_type type;
    double number;          /* NUMBER, INTEGER, BOOL */
    char *string;           /* STRING, ENUM, PATH (PATH: absolute) */
    double *numbers;        /* NUMBERS */
    int count;              /* NUMBERS */
} sc_param_value;

typedef struct sc_graph_node {
    const sc_node_desc *desc;
    char *name;             /* given by the graph, or "<type>_<n>" */
    char *file;             /* graph file that made it */
    int line;
    sc_param_value *params; /* desc->nparams entries, in descriptor order */
    int *input_node;        /* per input port: producing node index, -1 if none */
    int *input_port;        /* per input port: producer's output port index */
} sc_graph_node;

/* An expectation a graph test file states about a run (seamcook test):
 *   op "<", "<=", "==", ">=", ">", "~"  metric compared with value (~: within tolerance)
 *   op "image"    metric is a file the node wrote; it matches its golden image when at
 *                 most `tolerance` (a share) of pixels differ by more than `value`
 *                 (in 1/255 steps of any channel)
 *   op "metrics"  every metric of the node matches its golden metric file within the
 *                 relative `tolerance` (metrics named "seconds..." are timings: ignored) */
typedef struct sc_expect {
    char *node;             /* node name */
    char *metric;           /* metric name, or file path for "image" */
    char *op;
    double value, tolerance;
    char *file;             /* graph file and line that stated it */
    int line;
} sc_expect;

typedef struct sc_graph {
    char *file;             /* the graph file */
    int count, cap;
    sc_graph_node *nodes;
    int nexpect;
    sc_expect *expects;
    /* Private to sc_graph.c: how many nodes of each type sc_graph_add has
     * made, for default names without rescanning the graph. */
    int ntypes;
    struct sc_graph_type_count *type_counts;
} sc_graph;

sc_graph *sc_graph_new(const char *file);
void sc_graph_free(sc_graph *g);

/* Add a node of this type; its params start at their defaults. Returns the
 * node index or -1 (out of memory). */
int sc_graph_add(sc_graph *g, const sc_node_desc *desc, const char *file, int line);

/* Index of a parameter / port in a descriptor by name, or -1. */
int sc_desc_param(const sc_node_desc *d, const char *name);
int sc_desc_input(const sc_node_desc *d, const char *name);
int sc_desc_output(const sc_node_desc *d, const char *name);

/* Whether an output of kind `from` may feed an input of kind `to`
 * (equal kinds, or an atlas feeding a mesh port). */
bool sc_kind_feeds(sc_kind from, sc_kind to);

/* Check a parameter value against its descriptor (type, range, choice, a
 * list's rule); the message names "node:param". */
int sc_param_check(const sc_param_desc *pd, const sc_param_value *v, const char *node,
                   sc_error *err);
void sc_param_value_clear(sc_param_value *v);

/* Text as a parameter value of pd's type, as the command line gives it:
 * a number, a boolean (true/false, yes/no, 1/0), a string, or a list of
 * numbers "0.5,0.1" (every element a number; "" is the empty list). PATH
 * text is kept as it is. The value is not checked (sc_param_check); the
 * message says what is wrong with the text. Clear v after use. */
int sc_param_parse(const sc_param_desc *pd, const char *text, sc_param_value *v, sc_error *err);
bool sc_parse_bool(const char *text, bool *out);
/* "0.5, 0.1,0.01" -> {0.5, 0.1, 0.01} (caller frees *out); "" -> none. */
int sc_parse_numbers(const char *text, double **out, int *count, sc_error *err);

/* Whole-graph validation: every required input connected with a feeding kind,
 * producers earlier than consumers (no cycles), unique names, required params
 * given. Messages carry "file:line: node: ...". */
int sc_graph_validate(const sc_graph *g, sc_error *err);

/* How a PATH parameter enters the canonical text: *shown receives the text
 * that stands for the path (a new string; the engine's: the path relative to
 * its base folder), and the function returns true with *content set when the
 * path names a file (its content digest is then written too). */
typedef bool (*sc_path_key_fn)(void *ud, const char *path, char **shown, sc_digest *content);

/* Canonical text of a node's parameters: one "name=value\n" per parameter,
 * sorted by name; numbers as shortest exact round-trip text; strings quoted
 * with escapes. The same parameters always give the same bytes. A PATH is
 * written as given when path_key is NULL, else as `"SHOWN"` followed by
 * ` sha256:HEX` when path_key finds its content. */
void sc_graph_canonical_params(const sc_graph_node *n, sc_path_key_fn path_key, void *ud, sc_buf *out);

#endif
