/* sc_config.h - the project file: settings kept beside the graph files.
 *
 * `seamcook.conf` in the graph file's folder, one `name = value` a line;
 * blank lines and lines starting with # are ignored, blanks around names and
 * values too. Names:
 *
 *   remote_cache = URL          the remote cache (Bazel's HTTP protocol)
 *   remote_header = Name: value a header for every request (may repeat)
 *   remote_read_only = BOOL     look up, never upload (true/false, yes/no, 1/0)
 *   remote_timeout = SECONDS    to connect, and a transfer may stall (default 10)
 *   remote_retries = N          tries after the first on a network error (default 2)
 *
 * An unknown name, a line without '=', or a value of the wrong kind is an
 * error naming file:line. The command line and the environment (SEAMCOOK_
 * REMOTE_CACHE, ...) win over the file, setting by setting.
 */
#ifndef SC_CONFIG_H
#define SC_CONFIG_H

#include "sc_base.h"

#define SC_CONFIG_FILE "seamcook.conf"

typedef struct sc_config {
    char *remote_cache;      /* NULL: not given */
    char **headers;
    int nheaders;
    int read_only;           /* -1: not given, else 0 or 1 */
    double timeout;          /* 0: not given */
    int retries;             /* -1: not given */
} sc_config;

void sc_config_init(sc_config *c);
void sc_config_free(sc_config *c);   /* frees the members */

/* Parse a project file's text (n bytes; NUL bytes are an error) into c,
 * which sc_config_init prepared; `file` names it in messages. */
int sc_config_parse(const char *text, size_t n, const char *file, sc_config *c, sc_error *err);

/* Read the project file in folder dir when there is one (SC_OK and nothing
 * set when not). */
int sc_config_load(const char *dir, sc_config *c, sc_error *err);

#endif
