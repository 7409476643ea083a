/* sc_test.c - the harness behind sc_test.h. Tests register themselves from
 * constructors; sc_test_main runs them in registration order. */
#include "sc_test.h"

#include <stdarg.h>
#include <stdlib.h>
#include <unistd.h>
#include <sys/stat.h>
#include <sys/wait.h>

#define SC_TEST_MAX 256

static struct { const char *name; sc_test_fn fn; } tests[SC_TEST_MAX];
static int ntests;
static int current_failed;

void sc_test_register(const char *name, sc_test_fn fn) {
    if (ntests < SC_TEST_MAX) {
        tests[ntests].name = name;
        tests[ntests].fn = fn;
        ntests++;
    }
}

void sc_test_fail(const char *file, int line, const char *fmt, ...) {
    va_list ap;
    fprintf(stderr, "%s:%d: check failed: ", file, line);
    va_start(ap, fmt);
    vfprintf(stderr, fmt, ap);
    va_end(ap);
    fputc('\n', stderr);
    current_failed++;
}

int sc_test_main(void) {
    int passed = 0, failed = 0;
    const char *only = getenv("SC_TEST_ONLY");
    for (int i = 0; i < ntests; i++) {
        if (only && !strstr(tests[i].name, only)) continue;
        current_failed = 0;
        tests[i].fn();
        if (current_failed) {
            failed++;
            printf("FAIL %s\n", tests[i].name);
        } else {
            passed++;
            printf("ok   %s\n", tests[i].name);
        }
        fflush(stdout);
    }
    printf("%d passed, %d failed\n", passed, failed);
    return failed ? 1 : 0;
}

char *sc_test_tempdir(const char *tag) {
    const char *base = getenv("TMPDIR");
    if (!base || !*base) base = "/tmp";
    size_t n = strlen(base) + strlen(tag) + 32;
    char *path = malloc(n);
    if (!path) return NULL;
    snprintf(path, n, "%s/sc-%s-XXXXXX", base, tag);
    if (!mkdtemp(path)) {
        free(path);
        return NULL;
    }
    return path;
}

static const char *source_dir(void) {
    const char *s = getenv("SC_SOURCE_DIR");
    return (s && *s) ? s : SC_SOURCE_DIR;
}

char *sc_test_source_path(const char *rel) {
    size_t n = strlen(source_dir()) + strlen(rel) + 2;
    char *p = malloc(n);
    if (p) snprintf(p, n, "%s/%s", source_dir(), rel);
    return p;
}

const char *sc_test_corpus(void) {
    static char path[4096];
    struct stat st;
    const char *env = getenv("SC_CORPUS");
    if (env && *env) snprintf(path, sizeof path, "%s", env);
    else snprintf(path, sizeof path, "%s/../shared/corpus", source_dir());
    if (stat(path, &st) != 0 || !S_ISDIR(st.st_mode)) return NULL;
    return path;
}

int sc_test_system(const char *fmt, ...) {
    char cmd[8192];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(cmd, sizeof cmd, fmt, ap);
    va_end(ap);
    int st = system(cmd);
    if (st == -1) return -1;
    if (WIFEXITED(st)) return WEXITSTATUS(st);
    return 128 + (WIFSIGNALED(st) ? WTERMSIG(st) : 0);
}
