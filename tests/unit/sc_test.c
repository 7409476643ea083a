/* sc_test.c - the harness behind sc_test.h. Tests register themselves from
 * constructors; sc_test_main runs them in registration order. */
#include "sc_test.h"

#include "sc_nodes.h"

#include <stdarg.h>
#include <stdlib.h>
#include <unistd.h>
#include <sys/stat.h>
#include <sys/wait.h>

#include <cjson/cJSON.h>

#define SC_TEST_MAX 256

static struct { const char *name; sc_test_fn fn; } tests[SC_TEST_MAX];
static int ntests;
static int current_failed;

/* The directories the running test made (sc_test_tempdir): removed when it
 * passes, kept (and named) when it fails. */
#define SC_TEST_MAX_DIRS 64
static char *temp_dirs[SC_TEST_MAX_DIRS];
static int ntemp_dirs;

static void temp_dirs_done(bool keep) {
    for (int i = 0; i < ntemp_dirs; i++) {
        if (keep) printf("     kept %s\n", temp_dirs[i]);
        else sc_test_system("rm -rf '%s'", temp_dirs[i]);
        free(temp_dirs[i]);
    }
    ntemp_dirs = 0;
}

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
        temp_dirs_done(current_failed > 0);
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
    if (ntemp_dirs < SC_TEST_MAX_DIRS) {
        char *copy = malloc(strlen(path) + 1);
        if (copy) temp_dirs[ntemp_dirs++] = strcpy(copy, path);
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

bool sc_test_sanitized(void) {
#if defined(__SANITIZE_ADDRESS__)
    return true;
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
    return true;
#endif
#endif
    return false;
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

sc_test_run sc_test_run_node(const sc_node_desc *d, const char *const *params, const char *port0, sc_value *in0,
                             const char *port1, sc_value *in1) {
    sc_test_run r = {0};
    r.ctx = sc_ctx_new(d, NULL, NULL);
    if (!r.ctx) {
        r.rc = SC_ENOMEM;
        snprintf(r.err.message, sizeof r.err.message, "out of memory");
        return r;
    }
    for (int i = 0; params && params[i] && r.rc == SC_OK; i += 2)
        r.rc = sc_ctx_set_param(r.ctx, params[i], params[i + 1], &r.err);
    if (port0 && in0) sc_ctx_set_input(r.ctx, port0, in0);
    if (port1 && in1) sc_ctx_set_input(r.ctx, port1, in1);
    sc_ctx_set_threads(r.ctx, 2);
    if (r.rc == SC_OK) r.rc = sc_ctx_run(r.ctx, &r.err);
    return r;
}

sc_value *sc_test_load_corpus(const char *rel, const char *texture, const char *slots) {
    const char *dir = sc_test_corpus();
    if (!dir) return NULL;
    char path[4096], texture_path[4096];
    snprintf(path, sizeof path, "%s/%s", dir, rel);
    if (texture) snprintf(texture_path, sizeof texture_path, "%s/%s", dir, texture);
    const char *params[7] = {"path", path, NULL, NULL, NULL, NULL, NULL};
    int n = 2;
    if (texture) params[n++] = "texture", params[n++] = texture_path;
    if (slots) params[n++] = "slots", params[n++] = slots;
    sc_test_run r = sc_test_run_node(&sc_node_load_atlas, params, NULL, NULL, NULL, NULL);
    sc_value *out = r.rc == SC_OK ? sc_value_retain(sc_ctx_output(r.ctx, 0)) : NULL;
    if (r.rc != SC_OK) sc_test_fail(__FILE__, __LINE__, "loading %s: %s", rel, r.err.message);
    sc_ctx_free(r.ctx);
    return out;
}

sc_value *sc_test_lods_without(const sc_value *lods, const char *slot) {
    sc_lods *out = sc_lods_new();
    for (int k = 0; k < lods->as.lods->count; k++) {
        const sc_atlas *a = lods->as.lods->levels[k]->as.atlas;
        sc_atlas *b = sc_atlas_new(sc_value_retain(a->mesh));
        for (int t = 0; t < a->ntex; t++)
            if (strcmp(a->textures[t].name, slot) != 0)
                sc_atlas_add_texture(b, a->textures[t].name, a->textures[t].material, a->textures[t].wrap_u,
                                     a->textures[t].wrap_v, a->textures[t].source, sc_value_retain(a->textures[t].image));
        sc_lods_add(out, sc_value_new_atlas(b));
    }
    return sc_value_new_lods(out);
}

cJSON *sc_test_corpus_stats(const char *corpus, const char *asset) {
    char path[4096];
    snprintf(path, sizeof path, "%s/%s/stats.json", corpus, asset);
    sc_buf b;
    sc_buf_init(&b);
    cJSON *j = NULL;
    if (sc_read_file(path, 1 << 20, &b, NULL) == SC_OK) j = cJSON_ParseWithLength((const char *)b.data, b.len);
    sc_buf_free(&b);
    return j;
}

double sc_test_stat(const cJSON *stats, const char *key) {
    const cJSON *v = cJSON_GetObjectItemCaseSensitive(stats, key);
    return cJSON_IsNumber(v) ? v->valuedouble : NAN;
}
