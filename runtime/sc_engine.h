/* sc_engine.h - cooking a graph: keys, cache lookups, the scheduler, reports.
 *
 * For each node, in dependency order, the engine computes the action key
 * (SHA-256 over: the cooker's format, node type and version, the name,
 * version and platform text of every kernel the node reaches, canonical
 * parameters, and the digests of its inputs in port order). A PATH
 * parameter enters the key as its path relative to the base folder (the
 * graph file's, or base_dir) and its file's content digest, and the files a
 * node reads are recorded relative to it too: a key is the same for a
 * checkout anywhere, under any HOME, TMPDIR, working folder or locale.
 * With a remote cache, a local miss asks the remote, whose answer enters the
 * local cache (verified) before the lookup is made again; an action cooked
 * here is queued for upload once it is recorded. A recorded action
 * whose source files are unchanged is a hit: the node's output digests are
 * known without loading any bytes. A node that must run gets its inputs
 * loaded (from memory, or from the blob store, verified), runs on libuv's
 * thread pool, and its outputs are stored before the action is recorded.
 * Because consumers are keyed by content, a re-run whose output bytes did not
 * change leaves its consumers cached (early cutoff).
 */
#ifndef SC_ENGINE_H
#define SC_ENGINE_H

#include <stdio.h>

#include "sc_cache.h"
#include "sc_graph.h"
#include "sc_remote.h"

/* Bumped whenever key derivation or stored formats change. */
#define SC_ENGINE_FORMAT 2

typedef enum sc_node_status {
    SC_STATUS_PENDING = 0,
    SC_STATUS_CACHED,      /* hit: nothing ran */
    SC_STATUS_RAN,         /* cooked now */
    SC_STATUS_FAILED,
    SC_STATUS_SKIPPED,     /* not cooked because another node failed */
    SC_STATUS_WOULD_RUN,   /* dry run: would cook */
} sc_node_status;

const char *sc_status_name(sc_node_status s);

typedef struct sc_engine_options {
    int jobs;               /* nodes cooking at once (-j), >= 1 */
    const char *out_dir;    /* where report files and report.json go; NULL: none */
    bool dry_run;           /* -n: say what would cook, cook nothing, write nothing */
    bool explain;           /* --explain: print why each node cooks */
    FILE *log;              /* progress and messages (stderr); NULL: silent */
    bool live;              /* a live progress line (a terminal) rather than plain lines */
    const char *base_dir;   /* paths enter keys relative to it; NULL: the graph file's folder */
    sc_remote *remote;      /* asked on a local miss, given what cooks; NULL: none */
} sc_engine_options;

typedef struct sc_node_output {
    sc_kind kind;
    sc_digest digest;
    sc_digest mesh;         /* ATLAS outputs: the digest of its mesh part */
} sc_node_output;

typedef struct sc_node_result {
    sc_node_status status;
    sc_digest key;
    double seconds;         /* of this run (0 for a hit) */
    double cooked_seconds;  /* how long the recorded cook took */
    int noutputs;
    sc_node_output *outputs;
    char *metrics_json;     /* {"name": number, ...} */
    int nwarnings;
    char **warnings;        /* the node's sc_ctx_warn lines, kept with its cooked result */
    char *why;              /* why it cooked (or would), NULL for hits */
    char *error;            /* the failure message */
    int nfiles;
    char **files;           /* report files written under out_dir (relative) */
    sc_digest *file_digests;/* per file: the SHA-256 of its bytes */
    int ndeps;
    char **deps;            /* source files it read (absolute); after a failure, also those it could not */
    sc_digest *dep_digests; /* per dep: the content it read, all zero for one it could not read */
} sc_node_result;

typedef struct sc_run {
    const sc_graph *graph;
    sc_node_result *results;   /* graph->count entries */
    int ran, cached, failed, skipped;
    double seconds;
} sc_run;

/* Cook the graph. Returns SC_OK when every node cooked or was cached, else
 * the first failure's code with err naming the node (file:line: name: ...).
 * *out receives the per-node results either way (free with sc_run_free). */
int sc_engine_run(const sc_graph *g, sc_cache *cache, const sc_engine_options *opt,
                  sc_run **out, sc_error *err);
void sc_run_free(sc_run *r);

/* Load a node's output value after a run (from the cache). NULL + err on miss. */
sc_value *sc_engine_load(sc_cache *cache, const sc_digest *digest, sc_error *err);

#endif
