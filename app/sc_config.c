/* sc_config.c - the project file (see sc_config.h).
 *
 * Design note: the format is the smallest that a farm's checkout can carry
 * beside its graphs and a person can edit: no sections, no quoting, one
 * setting a line. Values run to the end of the line, so a header value may
 * hold '=' and '#'. Every line is checked, so a typo in a name is an error
 * rather than a setting silently ignored.
 */
#include "sc_config.h"

#include <errno.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "sc_graph.h"

#define MAX_CONFIG_BYTES (1u << 20)

void sc_config_init(sc_config *c) {
    memset(c, 0, sizeof *c);
    c->read_only = -1;
    c->retries = -1;
}

void sc_config_free(sc_config *c) {
    if (!c) return;
    free(c->remote_cache);
    for (int i = 0; i < c->nheaders; i++) free(c->headers[i]);
    free(c->headers);
    sc_config_init(c);
}

static bool is_blank(char ch) { return ch == ' ' || ch == '\t' || ch == '\r'; }

/* [s, e) without blanks at either end, as a new string. */
static char *trimmed(const char *s, const char *e) {
    while (s < e && is_blank(*s)) s++;
    while (e > s && is_blank(e[-1])) e--;
    return sc_strndup(s, (size_t)(e - s));
}

static int set(sc_config *c, const char *name, char *value, const char *file, int line, sc_error *err) {
    char *end;
    if (!strcmp(name, "remote_cache")) {
        free(c->remote_cache);
        c->remote_cache = value;
        return SC_OK;
    }
    if (!strcmp(name, "remote_header")) {
        if (!strchr(value, ':') || value[0] == ':') {
            sc_fail(err, SC_EINPUT, "%s:%d: remote_header: '%.60s' is not 'Name: value'", file, line, value);
            free(value);
            return SC_EINPUT;
        }
        char **grown = sc_realloc_array(c->headers, (size_t)c->nheaders + 1, sizeof *grown);
        if (!grown) {
            free(value);
            return sc_fail(err, SC_ENOMEM, "out of memory");
        }
        c->headers = grown;
        c->headers[c->nheaders++] = value;
        return SC_OK;
    }
    int rc = SC_OK;
    if (!strcmp(name, "remote_read_only")) {
        bool b;
        if (!sc_parse_bool(value, &b))
            rc = sc_fail(err, SC_EINPUT, "%s:%d: remote_read_only: '%.60s' is not true or false", file, line, value);
        else c->read_only = b;
    } else if (!strcmp(name, "remote_timeout")) {
        errno = 0;
        double t = strtod(value, &end);
        if (end == value || *end || errno || !(t > 0) || t > 3600)
            rc = sc_fail(err, SC_EINPUT, "%s:%d: remote_timeout: '%.60s' is not a number of seconds in (0, 3600]",
                         file, line, value);
        else c->timeout = t;
    } else if (!strcmp(name, "remote_retries")) {
        errno = 0;
        long n = strtol(value, &end, 10);
        if (end == value || *end || errno || n < 0 || n > 10)
            rc = sc_fail(err, SC_EINPUT, "%s:%d: remote_retries: '%.60s' is not a whole number from 0 to 10", file,
                         line, value);
        else c->retries = (int)n;
    } else {
        rc = sc_fail(err, SC_EINPUT, "%s:%d: unknown setting '%.60s' (settings: remote_cache, remote_header, "
                                     "remote_read_only, remote_timeout, remote_retries)", file, line, name);
    }
    free(value);
    return rc;
}

int sc_config_parse(const char *text, size_t n, const char *file, sc_config *c, sc_error *err) {
    if (memchr(text, 0, n)) return sc_fail(err, SC_EINPUT, "%s: holds a NUL byte: not a text file", file);
    const char *p = text, *end = text + n;
    for (int line = 1; p < end; line++) {
        const char *eol = memchr(p, '\n', (size_t)(end - p));
        if (!eol) eol = end;
        const char *s = p;
        while (s < eol && is_blank(*s)) s++;
        if (s < eol && *s != '#') {
            const char *eq = memchr(s, '=', (size_t)(eol - s));
            if (!eq) return sc_fail(err, SC_EINPUT, "%s:%d: expected 'name = value'", file, line);
            char *name = trimmed(s, eq), *value = trimmed(eq + 1, eol);
            if (!name || !value) {
                free(name), free(value);
                return sc_fail(err, SC_ENOMEM, "out of memory");
            }
            int rc = *name ? set(c, name, value, file, line, err)
                           : (free(value), sc_fail(err, SC_EINPUT, "%s:%d: a setting without a name", file, line));
            free(name);
            if (rc) return rc;
        }
        p = eol + 1;
    }
    return SC_OK;
}

int sc_config_load(const char *dir, sc_config *c, sc_error *err) {
    char *path = sc_path_join(dir, SC_CONFIG_FILE);
    if (!path) return sc_fail(err, SC_ENOMEM, "out of memory");
    struct stat st;
    int rc = SC_OK;
    if (stat(path, &st) == 0) {
        sc_buf b;
        sc_buf_init(&b);
        rc = sc_read_file(path, MAX_CONFIG_BYTES, &b, err);
        if (rc == SC_OK) rc = sc_config_parse(b.data ? (const char *)b.data : "", b.len, path, c, err);
        sc_buf_free(&b);
    }
    free(path);
    return rc;
}
