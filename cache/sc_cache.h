/* sc_cache.h - the content-addressed store and its SQLite index.
 *
 * On disk, under one directory:
 *   objects/ab/cdef...   blobs named by the hex SHA-256 of their bytes,
 *                        published by write-temp + fsync + rename
 *   tmp/                 temporary files of publishes in flight
 *   index.sqlite         WAL mode, busy timeout; every write transaction is
 *                        BEGIN IMMEDIATE. Tables: blobs, actions, stamps,
 *                        history, runs, leases.
 *
 * The cache knows bytes and digests only: no node, no value type. Several
 * processes may share one cache directory at once. A blob whose bytes do not
 * match its digest is a miss (and is removed), never an answer. An action is
 * recorded only after all its output blobs are published, so a crash or a
 * kill -9 never leaves an entry pointing at missing bytes.
 */
#ifndef SC_CACHE_H
#define SC_CACHE_H

#include "sc_base.h"

typedef struct sc_cache sc_cache;

/* Open (or create) a cache. An index that SQLite finds malformed, or that is
 * not a database, is moved aside and rebuilt from the blob store; the cache
 * then has a notice for the caller to print once. Files and folders are
 * made with the umask's modes (a group-writable umask and a setgid folder
 * let several users share one cache). */
int sc_cache_open(const char *dir, sc_cache **out, sc_error *err);
void sc_cache_close(sc_cache *c);   /* NULL is fine */
const char *sc_cache_dir(const sc_cache *c);
/* What opening did that the user should hear of (the index rebuilt), or NULL. */
const char *sc_cache_notice(const sc_cache *c);

/* ---------------------------------------------------------------- blobs */

/* Store bytes under their digest (the caller computed it). Does nothing when
 * a blob with this digest already exists. Safe against concurrent writers. */
int sc_cache_put_blob(sc_cache *c, const sc_digest *d, const void *bytes, size_t n,
                      sc_error *err);

/* The part of sc_cache_put_blob that touches no index: publish the blob's
 * file unless a file of its size is there. It reads nothing of the cache
 * that changes after opening, so threads that share one sc_cache under a
 * lock may call it outside that lock (writing gigabytes while others use the
 * index), then sc_cache_put_blob under the lock to record it. */
int sc_cache_write_blob_file(sc_cache *c, const sc_digest *d, const void *bytes, size_t n, sc_error *err);

/* Read and verify a blob. Returns SC_EMISS when absent or when its bytes do
 * not hash to d (the bad file is then deleted). Updates its last use. */
int sc_cache_get_blob(sc_cache *c, const sc_digest *d, sc_buf *out, sc_error *err);

/* Whether a blob file exists (no read, no verification). */
bool sc_cache_has_blob(sc_cache *c, const sc_digest *d);

/* The path a blob has (or would have) in the store, as a new string. */
char *sc_cache_blob_path(const sc_cache *c, const sc_digest *d);

/* ---------------------------------------------------------------- actions */

typedef struct sc_cache_dep {
    char *path;            /* a file the node read: relative to the base folder of
                              the cook that recorded it (the engine's), or absolute */
    sc_digest digest;      /* its content digest at that time */
} sc_cache_dep;

typedef struct sc_cache_action {
    sc_digest key;         /* the action key (see runtime/sc_engine.h) */
    char *node_type;
    char *outputs;         /* engine-defined text (JSON): output digests */
    char *metrics;         /* engine-defined text (JSON): the node's metrics */
    int ndeps;
    sc_cache_dep *deps;
    int nblobs;
    sc_digest *blobs;      /* every blob the outputs need (parts included):
                              gc and verify drop the action when one is gone */
    double seconds;        /* how long the run took */
} sc_cache_action;

void sc_cache_action_free(sc_cache_action *a);   /* frees the members, not a */

/* Look up an action. Returns 0 and fills out (caller frees with
 * sc_cache_action_free) when found, SC_EMISS when not. */
int sc_cache_get_action(sc_cache *c, const sc_digest *key, sc_cache_action *out,
                        sc_error *err);

/* Record an action (replacing an older record with the same key). */
int sc_cache_put_action(sc_cache *c, const sc_cache_action *a, sc_error *err);

/* ---------------------------------------------------------------- sources */

/* Content digest of a source file. A (path, size, mtime_ns, inode) stamp
 * recorded in the index skips re-hashing an unchanged file. Fails with
 * SC_EINPUT naming the path when it cannot be read. */
int sc_cache_file_digest(sc_cache *c, const char *path, sc_digest *out, sc_error *err);

/* Whether the file at path no longer holds what was seen: `seen` is the
 * digest of its content then, all zero when it was missing (so its
 * appearing is a change). *now (may be NULL) receives its digest now. */
bool sc_cache_file_changed(sc_cache *c, const char *path, const sc_digest *seen, sc_digest *now);

/* ---------------------------------------------------------------- history */

/* The last description recorded for a node identity (the engine's: graph
 * file, node name and its assets' paths): engine-defined text the engine
 * compares to explain why a node ran.
 * Returns 0 with *text (caller frees) or SC_EMISS. */
int sc_cache_get_history(sc_cache *c, const char *node_id, char **text, sc_error *err);
int sc_cache_put_history(sc_cache *c, const char *node_id, const char *text, sc_error *err);

/* Record one run of a graph (for stats). */
int sc_cache_put_run(sc_cache *c, const char *graph, int ran, int cached, int failed,
                     double seconds, sc_error *err);

/* Begin/commit one write transaction around many puts (optional; each put
 * otherwise commits by itself). Nested calls are counted. */
int sc_cache_begin(sc_cache *c, sc_error *err);
int sc_cache_commit(sc_cache *c, sc_error *err);

/* ---------------------------------------------------------------- leases */

/* One cook per action among the processes sharing a cache: a process that
 * must cook an action first takes its lease (a row of the index naming its
 * host and pid, with a heartbeat); the others wait for the recorded result.
 * A lease whose holder is gone is taken over: a pid that no longer exists on
 * this host, or a heartbeat older than stale_seconds. */
typedef struct sc_cache_lease_holder {
    char host[256];
    int64_t pid;
    double age_seconds;    /* since its last heartbeat */
    bool taken_over;       /* the lease was this holder's, who is gone */
} sc_cache_lease_holder;

/* Take the lease on an action key for this process. SC_OK when taken (free,
 * already this process's, or taken over: holder->taken_over), SC_EBUSY with
 * *holder filled (may be NULL) when a live process holds it. */
int sc_cache_lease_take(sc_cache *c, const sc_digest *key, double stale_seconds,
                        sc_cache_lease_holder *holder, sc_error *err);
/* The heartbeat: every lease this process holds is renewed. */
int sc_cache_lease_renew(sc_cache *c, sc_error *err);
/* Give a lease back (key NULL: every lease this process holds). */
int sc_cache_lease_release(sc_cache *c, const sc_digest *key, sc_error *err);

/* ---------------------------------------------------------------- upkeep */

typedef struct sc_cache_stats {
    int64_t blobs, blob_bytes, actions, stamps, runs;
} sc_cache_stats;

int sc_cache_stats_get(sc_cache *c, sc_cache_stats *out, sc_error *err);

typedef struct sc_cache_verify_result {
    int64_t checked, bad, missing, actions_dropped;
    int64_t not_files;       /* things in a blob's place that are not files (removed) */
    bool index_rebuilt;      /* the index failed SQLite's quick check and was rebuilt */
} sc_cache_verify_result;

/* Check the index (PRAGMA quick_check; rebuilt from the store when it
 * fails), re-hash every blob; delete bad ones and anything else in a blob's
 * place, forget missing ones, and drop the actions that refer to a blob no
 * longer present. */
int sc_cache_verify(sc_cache *c, sc_cache_verify_result *out, sc_error *err);

/* gc first deletes a reserve file kept beside the index (4 MiB, made again
 * after), so it can run on a full disk. */
typedef struct sc_cache_gc_result {
    int64_t blobs_removed, bytes_removed, actions_dropped, bytes_left;
} sc_cache_gc_result;

/* Remove least recently used blobs until the store holds at most max_bytes;
 * drop actions that refer to removed blobs; remove stale temporary files. */
int sc_cache_gc(sc_cache *c, int64_t max_bytes, sc_cache_gc_result *out, sc_error *err);

#endif
