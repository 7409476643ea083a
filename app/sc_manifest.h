/* sc_manifest.h - the files a run wrote in its --out folder, so that the
 * next run can remove those the graph no longer writes.
 *
 * DIR/.seamcook-manifest lists them, one "<sha-256 of the bytes> <path
 * relative to DIR>" a line. After a run that cooked every node, a file the
 * previous list names, that this run did not write and that still holds the
 * bytes the list says, is removed, with the folders that leaves empty.
 * Nothing the list does not name is ever touched, nor a file changed since
 * the run that wrote it. After a failed run nothing is removed: the list
 * keeps the old entries beside the new ones until a run succeeds.
 */
#ifndef SC_MANIFEST_H
#define SC_MANIFEST_H

#include <stdio.h>

#include "sc_engine.h"

#define SC_MANIFEST_NAME ".seamcook-manifest"

/* Update out_dir's manifest with what run wrote there; with `prune`, first
 * remove what the previous run wrote and this one did not (each removal is
 * said on log, which may be NULL). The cache hashes the files (its stamps
 * spare the re-reading). */
int sc_manifest_update(const char *out_dir, const sc_run *run, bool prune, sc_cache *cache, FILE *log,
                       sc_error *err);

#endif
