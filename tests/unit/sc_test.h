/* sc_test.h - a very small test harness for the unit tests.
 *
 *   SC_TEST(name) { ... SC_CHECK(cond); SC_CHECK_NEAR(a, b, tol); ... }
 *   int main(void) { return sc_test_main(); }
 *
 * Each test runs in order; a failed check prints file:line and the values and
 * the test goes on. The summary line is "N passed, N failed". The exit
 * status is 1 when any check failed.
 */
#ifndef SC_TEST_H
#define SC_TEST_H

#include <stdio.h>
#include <math.h>
#include <string.h>

#include "sc_exec.h"

typedef void (*sc_test_fn)(void);
void sc_test_register(const char *name, sc_test_fn fn);
void sc_test_fail(const char *file, int line, const char *fmt, ...)
    __attribute__((format(printf, 3, 4)));
int sc_test_main(void);
/* A fresh empty directory under the system temp dir (caller frees the
 * path); removed with everything in it once the test passes. */
char *sc_test_tempdir(const char *tag);
/* Path of a file in the source tree (caller frees). */
char *sc_test_source_path(const char *rel);
/* The shared corpus folder (../shared/corpus from the source tree), or NULL
 * when it is absent; corpus tests then print that they skipped. */
const char *sc_test_corpus(void);
/* Whether this build runs under AddressSanitizer. The heaviest corpus checks
 * skip there (the release run makes them): their code paths are those of the
 * small cases that do run, at 20-50 times the time. */
bool sc_test_sanitized(void);
/* Run a shell command, return its exit status (or -1). */
int sc_test_system(const char *fmt, ...) __attribute__((format(printf, 1, 2)));

/* A node run outside any graph (sc_exec): the ctx (free it with sc_ctx_free;
 * outputs live until then), the status and the error. */
typedef struct sc_test_run {
    sc_ctx *ctx;
    int rc;
    sc_error err;
} sc_test_run;

/* Run node d on 2 threads with params (name, value pairs, NULL-terminated;
 * may be NULL) and up to two inputs (a NULL port or value is skipped). */
sc_test_run sc_test_run_node(const sc_node_desc *d, const char *const *params, const char *port0, sc_value *in0,
                             const char *port1, sc_value *in1);

/* load_atlas on corpus files (paths relative to sc_test_corpus(); texture
 * and slots may be NULL): a new reference, or NULL when the corpus is absent
 * or the load failed (a failed check then says why). */
sc_value *sc_test_load_corpus(const char *rel, const char *texture, const char *slots);

/* The corpus's stats.json of an asset (cJSON_Delete it), or NULL; a number
 * in it, or NAN. */
struct cJSON *sc_test_corpus_stats(const char *corpus, const char *asset);
double sc_test_stat(const struct cJSON *stats, const char *key);

/* A copy of a lods value whose levels lack the texture slot `slot`. */
sc_value *sc_test_lods_without(const sc_value *lods, const char *slot);

#define SC_TEST(name)                                                      \
    static void name(void);                                                \
    __attribute__((constructor)) static void name##_register(void) {       \
        sc_test_register(#name, name);                                     \
    }                                                                      \
    static void name(void)

#define SC_CHECK(cond)                                                     \
    do {                                                                   \
        if (!(cond)) sc_test_fail(__FILE__, __LINE__, "%s", #cond);        \
    } while (0)

#define SC_CHECK_MSG(cond, ...)                                            \
    do {                                                                   \
        if (!(cond)) sc_test_fail(__FILE__, __LINE__, __VA_ARGS__);        \
    } while (0)

#define SC_CHECK_NEAR(a, b, tol)                                           \
    do {                                                                   \
        double sc_a_ = (a), sc_b_ = (b);                                   \
        if (!(fabs(sc_a_ - sc_b_) <= (tol)))                               \
            sc_test_fail(__FILE__, __LINE__, "%s = %.17g, %s = %.17g, tol %g", \
                         #a, sc_a_, #b, sc_b_, (double)(tol));             \
    } while (0)

#define SC_CHECK_INT(a, b)                                                 \
    do {                                                                   \
        long long sc_a_ = (long long)(a), sc_b_ = (long long)(b);          \
        if (sc_a_ != sc_b_)                                                \
            sc_test_fail(__FILE__, __LINE__, "%s = %lld, expected %s = %lld", \
                         #a, sc_a_, #b, sc_b_);                            \
    } while (0)

#define SC_CHECK_STR(a, b)                                                 \
    do {                                                                   \
        const char *sc_a_ = (a), *sc_b_ = (b);                             \
        if (!sc_a_ || !sc_b_ || strcmp(sc_a_, sc_b_) != 0)                 \
            sc_test_fail(__FILE__, __LINE__, "%s = \"%s\", expected \"%s\"", \
                         #a, sc_a_ ? sc_a_ : "(null)", sc_b_ ? sc_b_ : "(null)"); \
    } while (0)

#endif
