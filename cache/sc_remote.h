/* sc_remote.h - a remote cache over Bazel's HTTP remote-cache protocol.
 *
 * A server that speaks it (bazel-remote, nginx with WebDAV PUT, any HTTP
 * store) keeps two namespaces under one base URL:
 *
 *   /cas/<sha256 hex>   blobs, named by the SHA-256 of their bytes
 *   /ac/<key hex>       action results: a REAPI ActionResult protobuf
 *                       (build.bazel.remote.execution.v2), whose output_files
 *                       name the blobs an action needs
 *
 * each read with GET (HEAD: does it exist) and written with PUT. An action
 * of the local cache travels as: its blobs (output_files "blobs/<hex>"),
 * then its record (the local cache's sc_cache_action as JSON, output_file
 * "seamcook/action.json"), then the ActionResult under its key. The AC entry
 * is written last, so it never names a blob the server lacks; a server that
 * lost one anyway (evicted) gives a miss, and the action cooks again.
 *
 * Lookups go to the local cache first; the remote is asked only on a local
 * miss (sc_remote_fetch), and everything it gives is verified against its
 * digest before it enters the local cache: a blob whose bytes do not match
 * is a miss, remembered as bad, and uploaded again over the server's copy
 * once the action has cooked. Uploads run on a thread of their own, in the
 * order they were queued; sc_remote_close waits for them.
 *
 * The remote is an accelerator, never a reason for a cook to fail: a server
 * that cannot be reached, refuses the credentials (401/403) or answers
 * otherwise amiss is named once in a warning on the log ("...; cooking
 * without it"), and from then on left alone while everything cooks locally. Network errors and 5xx answers
 * are retried a bounded number of times with a growing pause.
 */
#ifndef SC_REMOTE_H
#define SC_REMOTE_H

#include <stdio.h>

#include "sc_cache.h"

typedef struct sc_remote sc_remote;

typedef struct sc_remote_config {
    /* http(s)://[user:password@]host[:port][/prefix]: the base URL. The
     * user and password of the URL are sent as Basic authentication, and
     * ~/.netrc is read for a host the URL gives none for. */
    const char *url;
    const char *const *headers;   /* "Name: value", sent with every request */
    int nheaders;
    bool read_only;               /* look up, never upload */
    double timeout;               /* seconds to connect, and a transfer may stall (0: 10) */
    int retries;                  /* tries after the first on a network error or a 5xx (< 0: 2) */
    FILE *log;                    /* where the one warning goes; NULL: nowhere */
} sc_remote_config;

typedef struct sc_remote_stats {
    int64_t ac_hits, ac_misses;             /* actions found / not found remotely */
    int64_t blobs_downloaded, bytes_downloaded;
    int64_t blobs_uploaded, bytes_uploaded, actions_uploaded;
    int64_t blobs_present;                  /* uploads skipped: the server had the blob (HEAD) */
    int64_t bad_blobs;                      /* downloads whose bytes did not match their digest */
    int64_t missing_blobs;                  /* an action found whose blob the server lacks */
    bool disabled;                          /* the server failed and was left alone */
} sc_remote_stats;

/* Open a remote over the local cache `local`. Fails (SC_EUSAGE) on a URL
 * that is not http(s) or a header without a colon; reaches no server. */
int sc_remote_open(const sc_remote_config *cfg, sc_cache *local, sc_remote **out, sc_error *err);
/* Calls around every use of the local cache's index by sc_remote_fetch, for
 * a caller whose threads share it (the engine's cache mutex); NULL: none.
 * The upload thread never uses the index: it reads blob files only. */
void sc_remote_set_lock(sc_remote *r, void (*lock)(void *ud), void (*unlock)(void *ud), void *ud);
/* Finish the queued uploads, then free. NULL is fine. */
void sc_remote_close(sc_remote *r);
/* Wait until every queued upload is done. */
void sc_remote_flush(sc_remote *r);

/* Look an action up remotely and, when every blob it needs is there and
 * sound, put them and its record into the local cache. SC_OK: the local
 * cache now holds the action; SC_EMISS: it does not (not there, a blob gone
 * or bad, the server unreachable: see the stats and the warning). */
int sc_remote_fetch(sc_remote *r, const sc_digest *key, sc_error *err);

/* Queue the upload of an action the local cache has recorded (its blobs
 * are read from the store when the upload runs). Does nothing when read-only
 * or the server was left alone. Fails only when out of memory. */
int sc_remote_upload(sc_remote *r, const sc_cache_action *a, sc_error *err);

void sc_remote_stats_get(sc_remote *r, sc_remote_stats *out);

/* ---------------------------------------------------------------- the wire format */

/* One output file of an ActionResult: its path and the digest and size of
 * its bytes. */
typedef struct sc_remote_output {
    char *path;
    sc_digest digest;
    int64_t size;
    bool hashed;     /* decoding: the digest's hash was there */
} sc_remote_output;

/* An ActionResult protobuf with these output files (field 2: OutputFile
 * {path = 1, digest = 2: Digest {hash = 1 (hex), size_bytes = 2}}) and
 * exit_code 0. */
int sc_remote_encode_result(const sc_remote_output *outs, int n, sc_buf *out);
/* Read an ActionResult's output files (other fields are skipped). Fails with
 * SC_EINPUT on bytes that are not a well-formed protobuf, or an output whose
 * hash is not 64 hex digits. *outs: free with sc_remote_outputs_free. */
int sc_remote_decode_result(const void *bytes, size_t n, sc_remote_output **outs, int *count,
                            sc_error *err);
void sc_remote_outputs_free(sc_remote_output *outs, int count);

/* An action record as JSON (what travels as seamcook/action.json), and
 * back: decoding checks every field's type and every digest. */
char *sc_remote_record_encode(const sc_cache_action *a);
int sc_remote_record_decode(const char *text, size_t n, sc_cache_action *out, sc_error *err);

#endif
