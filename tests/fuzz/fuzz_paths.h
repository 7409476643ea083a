/* fuzz_paths.h - the fuzzers' own check of sc_path_confine's promise: a
 * path it accepts, with "." and ".." taken by their text, lies inside the
 * root. ROOT does not exist, so no symbolic link can be involved and the
 * text decides (written apart from base/sc_base.c's resolution). */
#ifndef FUZZ_PATHS_H
#define FUZZ_PATHS_H

#include <stdlib.h>
#include <string.h>

#include "sc_base.h"

#define FUZZ_ROOT "/seamcook-fuzz/asset"

/* Aborts when sc_path_confine accepts rel and it leaves FUZZ_ROOT, or fails
 * without saying why. */
static void fuzz_check_confined(const char *rel) {
    char *path = NULL;
    sc_error err = {0};
    if (sc_path_confine(FUZZ_ROOT, FUZZ_ROOT, rel, &path, &err) != SC_OK) {
        if (!err.message[0] || path) abort();
        return;
    }
    if (!path || path[0] != '/') abort();
    /* the components that remain after "." and ".." */
    const char *kept[4096];
    size_t kept_len[4096];
    int n = 0;
    for (const char *p = path; *p;) {
        while (*p == '/') p++;
        const char *e = strchr(p, '/');
        size_t len = e ? (size_t)(e - p) : strlen(p);
        if (len == 2 && p[0] == '.' && p[1] == '.') {
            if (n > 0) n--;
        } else if (len && !(len == 1 && p[0] == '.') && n < 4096) {
            kept[n] = p, kept_len[n++] = len;
        }
        p += len;
    }
    /* FUZZ_ROOT's two components first (a file in it, or the folder itself) */
    if (n < 2 || kept_len[0] != 13 || strncmp(kept[0], "seamcook-fuzz", 13) != 0 || kept_len[1] != 5 ||
        strncmp(kept[1], "asset", 5) != 0)
        abort();
    free(path);
}

#endif
