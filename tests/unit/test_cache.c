/* test_cache.c - the content-addressed store and its SQLite index: blobs,
 * actions, source stamps, history, upkeep, and several processes sharing one
 * cache (fork), including a writer killed with SIGKILL. */
#include "sc_test.h"
#include "sc_cache.h"

#include <errno.h>
#include <fcntl.h>
#include <signal.h>
#include <stdlib.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include <sqlite3.h>

/* ---------------------------------------------------------------- helpers */

static sc_digest dig_str(const char *s) {
    sc_digest d;
    sc_digest_bytes(s, strlen(s), &d);
    return d;
}

static sc_cache *open_cache(const char *dir) {
    sc_cache *c = NULL;
    sc_error err = {0};
    int rc = sc_cache_open(dir, &c, &err);
    SC_CHECK_MSG(rc == 0 && c, "open %s: %s", dir, err.message);
    return c;
}

static int put_bytes(sc_cache *c, const void *p, size_t n, sc_digest *d) {
    sc_error err = {0};
    sc_digest_bytes(p, n, d);
    int rc = sc_cache_put_blob(c, d, p, n, &err);
    SC_CHECK_MSG(rc == 0, "put_blob: %s", err.message);
    return rc;
}

static int put_text(sc_cache *c, const char *s, sc_digest *d) {
    return put_bytes(c, s, strlen(s), d);
}

static void write_text(const char *path, const char *s) {
    FILE *f = fopen(path, "wb");
    SC_CHECK(f != NULL);
    if (!f) return;
    fputs(s, f);
    fclose(f);
}

/* Overwrite bytes in place (same inode, same size when n fits). */
static void patch_file(const char *path, off_t at, const void *p, size_t n) {
    int fd = open(path, O_WRONLY);
    SC_CHECK(fd >= 0);
    if (fd < 0) return;
    SC_CHECK(pwrite(fd, p, n, at) == (ssize_t)n);
    close(fd);
}

static void set_mtime(const char *path, const struct timespec *t) {
    struct timespec ts[2] = {*t, *t};
    SC_CHECK(utimensat(AT_FDCWD, path, ts, 0) == 0);
}

static struct timespec mtime_of(const char *path) {
    struct stat st;
    memset(&st, 0, sizeof st);
    SC_CHECK(stat(path, &st) == 0);
    return st.st_mtim;
}

static sc_cache_stats stats_of(sc_cache *c) {
    sc_cache_stats s;
    sc_error err = {0};
    int rc = sc_cache_stats_get(c, &s, &err);
    SC_CHECK_MSG(rc == 0, "stats: %s", err.message);
    return s;
}

static int put_simple_action(sc_cache *c, const sc_digest *key, const char *outputs,
                             const sc_digest *blobs, int nblobs, sc_error *err) {
    sc_cache_action a;
    memset(&a, 0, sizeof a);
    a.key = *key;
    a.node_type = "test_node";
    a.outputs = (char *)outputs;
    a.metrics = "{}";
    a.nblobs = nblobs;
    a.blobs = (sc_digest *)blobs;
    a.seconds = 0.5;
    return sc_cache_put_action(c, &a, err);
}

static bool action_exists(sc_cache *c, const sc_digest *key) {
    sc_cache_action a;
    sc_error err = {0};
    int rc = sc_cache_get_action(c, key, &a, &err);
    if (rc == 0) sc_cache_action_free(&a);
    SC_CHECK_MSG(rc == 0 || rc == SC_EMISS, "get_action: %s", err.message);
    return rc == 0;
}

static void remove_tree(char *dir) {
    if (dir) sc_test_system("rm -rf '%s'", dir);
    free(dir);
}

/* ---------------------------------------------------------------- blobs */

SC_TEST(blob_round_trip) {
    char *dir = sc_test_tempdir("cache");
    sc_cache *c = open_cache(dir);
    if (!c) return;
    SC_CHECK_STR(sc_cache_dir(c), dir);
    sc_error err = {0};
    sc_buf b;
    sc_buf_init(&b);

    sc_digest d;
    put_text(c, "hello, cache", &d);
    SC_CHECK(sc_cache_has_blob(c, &d));
    SC_CHECK_INT(sc_cache_get_blob(c, &d, &b, &err), 0);
    SC_CHECK_INT(b.len, strlen("hello, cache"));
    SC_CHECK(b.len == 12 && memcmp(b.data, "hello, cache", 12) == 0);

    /* layout: objects/ab/cdef... */
    char hex[65], *path = sc_cache_blob_path(c, &d);
    sc_digest_hex(&d, hex);
    char *want = sc_strprintf("%s/objects/%.2s/%s", dir, hex, hex + 2);
    SC_CHECK_STR(path, want);
    free(want);
    free(path);

    /* a second put of the same bytes is fine and changes nothing */
    put_text(c, "hello, cache", &d);
    SC_CHECK_INT(stats_of(c).blobs, 1);

    /* the empty blob */
    sc_digest e;
    put_bytes(c, "", 0, &e);
    SC_CHECK_INT(sc_cache_get_blob(c, &e, &b, &err), 0);
    SC_CHECK_INT(b.len, 0);

    /* a large blob (several read chunks) */
    size_t big = 3u << 20;
    uint8_t *p = malloc(big);
    SC_CHECK(p != NULL);
    if (p) {
        for (size_t i = 0; i < big; i++) p[i] = (uint8_t)(i * 2654435761u >> 13);
        sc_digest bd;
        put_bytes(c, p, big, &bd);
        SC_CHECK_INT(sc_cache_get_blob(c, &bd, &b, &err), 0);
        SC_CHECK(b.len == big && memcmp(b.data, p, big) == 0);
        free(p);
    }

    /* absent */
    sc_digest absent = dig_str("never stored");
    SC_CHECK(!sc_cache_has_blob(c, &absent));
    b.len = 3;
    SC_CHECK_INT(sc_cache_get_blob(c, &absent, &b, &err), SC_EMISS);
    SC_CHECK_INT(b.len, 0);

    /* it survives close and reopen */
    sc_cache_close(c);
    c = open_cache(dir);
    if (c) {
        SC_CHECK_INT(sc_cache_get_blob(c, &d, &b, &err), 0);
        SC_CHECK(b.len == 12 && memcmp(b.data, "hello, cache", 12) == 0);
    }
    sc_buf_free(&b);
    sc_cache_close(c);
    remove_tree(dir);
}

SC_TEST(blob_corrupt_is_a_miss) {
    char *dir = sc_test_tempdir("cache");
    sc_cache *c = open_cache(dir);
    if (!c) return;
    sc_error err = {0};
    sc_buf b;
    sc_buf_init(&b);

    sc_digest d, keep;
    put_text(c, "the bytes that will be damaged", &d);
    put_text(c, "an innocent bystander", &keep);
    sc_digest key = dig_str("action needing the damaged blob");
    SC_CHECK_INT(put_simple_action(c, &key, "{}", &d, 1, &err), 0);

    char *path = sc_cache_blob_path(c, &d);
    patch_file(path, 4, "X", 1);   /* one byte, same size */
    memset(&err, 0, sizeof err);
    SC_CHECK_INT(sc_cache_get_blob(c, &d, &b, &err), SC_EMISS);
    SC_CHECK_MSG(strstr(err.message, "corrupt") != NULL, "message: %s", err.message);
    SC_CHECK_INT(b.len, 0);
    struct stat st;
    SC_CHECK(stat(path, &st) != 0 && errno == ENOENT);
    SC_CHECK(!sc_cache_has_blob(c, &d));
    SC_CHECK(!action_exists(c, &key));   /* its action went with it */
    SC_CHECK_INT(stats_of(c).blobs, 1);
    SC_CHECK_INT(sc_cache_get_blob(c, &keep, &b, &err), 0);

    /* the damaged blob can be stored again */
    put_text(c, "the bytes that will be damaged", &d);
    SC_CHECK_INT(sc_cache_get_blob(c, &d, &b, &err), 0);

    /* a truncated file is a miss too; put replaces a copy of the wrong size */
    SC_CHECK(truncate(path, 5) == 0);
    SC_CHECK_INT(sc_cache_get_blob(c, &d, &b, &err), SC_EMISS);
    SC_CHECK(truncate(path, 5) != 0);   /* removed */
    put_text(c, "the bytes that will be damaged", &d);
    SC_CHECK(truncate(path, 5) == 0);
    put_text(c, "the bytes that will be damaged", &d);
    SC_CHECK_INT(sc_cache_get_blob(c, &d, &b, &err), 0);
    SC_CHECK_INT(b.len, strlen("the bytes that will be damaged"));

    free(path);
    sc_buf_free(&b);
    sc_cache_close(c);
    remove_tree(dir);
}

/* ---------------------------------------------------------------- actions */

SC_TEST(action_round_trip_miss_replace) {
    char *dir = sc_test_tempdir("cache");
    sc_cache *c = open_cache(dir);
    if (!c) return;
    sc_error err = {0};

    sc_digest b1, b2, b3;
    put_text(c, "blob one", &b1);
    put_text(c, "blob two", &b2);
    put_text(c, "blob three", &b3);

    sc_cache_dep deps[3] = {
        {"/assets/mesh.obj", dig_str("mesh")},
        {"/assets/odd name with spaces 12 x.png", dig_str("png")},
        {"/assets/new\nline", dig_str("newline")},
    };
    sc_digest blobs[3] = {b2, b1, b2};   /* order kept, repeats allowed */
    sc_cache_action a;
    memset(&a, 0, sizeof a);
    a.key = dig_str("key 1");
    a.node_type = "decimate";
    a.outputs = "{\"mesh\":\"abc\"}";
    a.metrics = "{\"error\":0.25}";
    a.ndeps = 3;
    a.deps = deps;
    a.nblobs = 3;
    a.blobs = blobs;
    a.seconds = 1.25;
    SC_CHECK_INT(sc_cache_put_action(c, &a, &err), 0);

    sc_cache_action g;
    SC_CHECK_INT(sc_cache_get_action(c, &a.key, &g, &err), 0);
    SC_CHECK(sc_digest_equal(&g.key, &a.key));
    SC_CHECK_STR(g.node_type, "decimate");
    SC_CHECK_STR(g.outputs, a.outputs);
    SC_CHECK_STR(g.metrics, a.metrics);
    SC_CHECK_NEAR(g.seconds, 1.25, 0);
    SC_CHECK_INT(g.ndeps, 3);
    for (int i = 0; i < g.ndeps && i < 3; i++) {
        SC_CHECK_STR(g.deps[i].path, deps[i].path);
        SC_CHECK(sc_digest_equal(&g.deps[i].digest, &deps[i].digest));
    }
    SC_CHECK_INT(g.nblobs, 3);
    for (int i = 0; i < g.nblobs && i < 3; i++) SC_CHECK(sc_digest_equal(&g.blobs[i], &blobs[i]));
    sc_cache_action_free(&g);
    SC_CHECK(g.node_type == NULL && g.ndeps == 0);

    /* miss */
    sc_digest other = dig_str("key 2");
    memset(&err, 0, sizeof err);
    SC_CHECK_INT(sc_cache_get_action(c, &other, &g, &err), SC_EMISS);
    SC_CHECK(strstr(err.message, "not in the cache") != NULL);

    /* replace: new outputs, no deps, one other blob */
    a.outputs = "{\"mesh\":\"def\"}";
    a.ndeps = 0;
    a.deps = NULL;
    a.nblobs = 1;
    a.blobs = &b3;
    SC_CHECK_INT(sc_cache_put_action(c, &a, &err), 0);
    SC_CHECK_INT(sc_cache_get_action(c, &a.key, &g, &err), 0);
    SC_CHECK_STR(g.outputs, "{\"mesh\":\"def\"}");
    SC_CHECK_INT(g.ndeps, 0);
    SC_CHECK_INT(g.nblobs, 1);
    if (g.nblobs == 1) SC_CHECK(sc_digest_equal(&g.blobs[0], &b3));
    sc_cache_action_free(&g);
    SC_CHECK_INT(stats_of(c).actions, 1);

    /* the replaced record no longer holds b1/b2: a gc removing b1 keeps it */
    sc_cache_close(c);
    char *p1 = NULL;
    c = open_cache(dir);
    if (c) {
        p1 = sc_cache_blob_path(c, &b1);
        SC_CHECK(unlink(p1) == 0);
        sc_cache_verify_result v;
        SC_CHECK_INT(sc_cache_verify(c, &v, &err), 0);
        SC_CHECK_INT(v.missing, 1);
        SC_CHECK_INT(v.actions_dropped, 0);
        SC_CHECK(action_exists(c, &a.key));
    }
    free(p1);

    /* an action naming a blob the store does not have is refused */
    sc_digest ghost = dig_str("a blob nobody stored");
    sc_digest k3 = dig_str("key 3");
    memset(&err, 0, sizeof err);
    SC_CHECK_INT(put_simple_action(c, &k3, "{}", &ghost, 1, &err), SC_EMISS);
    SC_CHECK(!action_exists(c, &k3));

    sc_cache_close(c);
    remove_tree(dir);
}

SC_TEST(begin_commit_nesting) {
    char *dir = sc_test_tempdir("cache");
    sc_cache *c = open_cache(dir);
    sc_cache *other = open_cache(dir);
    if (!c || !other) {
        sc_cache_close(c);
        sc_cache_close(other);
        return;
    }
    sc_error err = {0};
    SC_CHECK_INT(sc_cache_commit(c, &err), SC_EIO);   /* no begin */

    sc_digest b;
    put_text(c, "blob for the batch", &b);
    SC_CHECK_INT(sc_cache_begin(c, &err), 0);
    SC_CHECK_INT(sc_cache_begin(c, &err), 0);
    sc_digest keys[10];
    for (int i = 0; i < 10; i++) {
        char name[32];
        snprintf(name, sizeof name, "batched %d", i);
        keys[i] = dig_str(name);
        SC_CHECK_INT(put_simple_action(c, &keys[i], "{}", &b, 1, &err), 0);
    }
    SC_CHECK_INT(sc_cache_put_history(c, "g.lua:n", "text", &err), 0);
    sc_digest ghost = dig_str("not stored");
    sc_digest bad = dig_str("bad action");
    /* a failed put inside the batch rolls back only itself */
    SC_CHECK_INT(put_simple_action(c, &bad, "{}", &ghost, 1, &err), SC_EMISS);
    SC_CHECK_INT(sc_cache_commit(c, &err), 0);   /* inner */
    SC_CHECK(action_exists(c, &keys[3]));          /* own writes are visible */
    SC_CHECK(!action_exists(other, &keys[3]));     /* others do not see them yet */
    SC_CHECK_INT(sc_cache_commit(c, &err), 0);   /* outer: now committed */
    for (int i = 0; i < 10; i++) SC_CHECK(action_exists(other, &keys[i]));
    SC_CHECK(!action_exists(other, &bad));
    char *text = NULL;
    SC_CHECK_INT(sc_cache_get_history(other, "g.lua:n", &text, &err), 0);
    SC_CHECK_STR(text, "text");
    free(text);

    /* an unfinished batch is discarded at close */
    sc_digest lost = dig_str("lost");
    SC_CHECK_INT(sc_cache_begin(c, &err), 0);
    SC_CHECK_INT(put_simple_action(c, &lost, "{}", &b, 1, &err), 0);
    sc_cache_close(c);
    SC_CHECK(!action_exists(other, &lost));
    sc_cache_close(other);
    remove_tree(dir);
}

SC_TEST(action_lookup_is_fast) {
    char *dir = sc_test_tempdir("cache");
    sc_cache *c = open_cache(dir);
    if (!c) return;
    sc_error err = {0};
    sc_digest blobs[3];
    put_text(c, "fast 1", &blobs[0]);
    put_text(c, "fast 2", &blobs[1]);
    put_text(c, "fast 3", &blobs[2]);
    sc_cache_dep deps[2] = {{"/a/b/c.obj", dig_str("c")}, {"/a/b/d.png", dig_str("d")}};
    sc_digest keys[500];
    SC_CHECK_INT(sc_cache_begin(c, &err), 0);
    for (int i = 0; i < 500; i++) {
        char name[32];
        snprintf(name, sizeof name, "fast action %d", i);
        keys[i] = dig_str(name);
        sc_cache_action a;
        memset(&a, 0, sizeof a);
        a.key = keys[i];
        a.node_type = "mipmap";
        a.outputs = "{\"image\":\"0123456789abcdef0123456789abcdef\"}";
        a.metrics = "{\"levels\":10}";
        a.ndeps = 2;
        a.deps = deps;
        a.nblobs = 3;
        a.blobs = blobs;
        SC_CHECK_INT(sc_cache_put_action(c, &a, &err), 0);
    }
    SC_CHECK_INT(sc_cache_commit(c, &err), 0);
    double t0 = sc_now();
    int hits = 0;
    for (int i = 0; i < 500; i++) {
        sc_cache_action a;
        if (sc_cache_get_action(c, &keys[i], &a, &err) == 0) {
            hits += a.nblobs == 3 && a.ndeps == 2;
            sc_cache_action_free(&a);
        }
    }
    double dt = sc_now() - t0;
    SC_CHECK_INT(hits, 500);
    printf("     500 action lookups: %.2f ms\n", dt * 1e3);
    SC_CHECK_MSG(dt < 0.25, "500 lookups took %.1f ms", dt * 1e3);
    sc_cache_close(c);
    remove_tree(dir);
}

/* ---------------------------------------------------------------- sources */

SC_TEST(file_digest_content_and_errors) {
    char *dir = sc_test_tempdir("cache");
    sc_cache *c = open_cache(dir);
    if (!c) return;
    sc_error err = {0};
    char *file = sc_path_join(dir, "source.txt");
    write_text(file, "version one");
    sc_digest d, want;
    SC_CHECK_INT(sc_cache_file_digest(c, file, &d, &err), 0);
    sc_digest_bytes("version one", 11, &want);
    SC_CHECK(sc_digest_equal(&d, &want));

    write_text(file, "version two, longer");
    SC_CHECK_INT(sc_cache_file_digest(c, file, &d, &err), 0);
    sc_digest_bytes("version two, longer", 19, &want);
    SC_CHECK(sc_digest_equal(&d, &want));

    /* an old file gets a stamp; a changed size is noticed */
    struct timespec old = {time(NULL) - 100, 0};
    set_mtime(file, &old);
    SC_CHECK_INT(sc_cache_file_digest(c, file, &d, &err), 0);
    SC_CHECK(sc_digest_equal(&d, &want));
    SC_CHECK_INT(stats_of(c).stamps, 1);
    write_text(file, "version three");
    set_mtime(file, &old);
    SC_CHECK_INT(sc_cache_file_digest(c, file, &d, &err), 0);
    sc_digest_bytes("version three", 13, &want);
    SC_CHECK(sc_digest_equal(&d, &want));

    /* a large file is streamed */
    char *bigfile = sc_path_join(dir, "big.bin");
    size_t big = (5u << 20) + 123;
    uint8_t *p = malloc(big);
    if (p) {
        for (size_t i = 0; i < big; i++) p[i] = (uint8_t)(i * 31 + (i >> 11));
        sc_write_file_atomic(bigfile, p, big, &err);
        SC_CHECK_INT(sc_cache_file_digest(c, bigfile, &d, &err), 0);
        sc_digest_bytes(p, big, &want);
        SC_CHECK(sc_digest_equal(&d, &want));
        free(p);
    }

    /* missing file, directory */
    char *missing = sc_path_join(dir, "nope.obj");
    memset(&err, 0, sizeof err);
    SC_CHECK_INT(sc_cache_file_digest(c, missing, &d, &err), SC_EINPUT);
    SC_CHECK(strstr(err.message, missing) != NULL && strstr(err.message, "cannot open") != NULL);
    SC_CHECK_INT(sc_cache_file_digest(c, dir, &d, &err), SC_EINPUT);
    free(missing);
    free(bigfile);
    free(file);
    sc_cache_close(c);
    remove_tree(dir);
}

SC_TEST(file_digest_stamps_and_racy_files) {
    char *dir = sc_test_tempdir("cache");
    sc_cache *c = open_cache(dir);
    if (!c) return;
    sc_error err = {0};
    sc_digest d, a_digest, b_digest;
    sc_digest_bytes("AAAAAAAA", 8, &a_digest);
    sc_digest_bytes("BBBBBBBB", 8, &b_digest);

    /* An old file: the stamp is recorded and then trusted. Changing the
     * bytes in place (same size, same inode) and setting the old mtime back
     * is the documented blind spot: the stored digest comes back without a
     * read, which shows the fast path is taken. */
    char *old_file = sc_path_join(dir, "old.txt");
    write_text(old_file, "AAAAAAAA");
    struct timespec old = {time(NULL) - 60, 123456789};
    set_mtime(old_file, &old);
    SC_CHECK_INT(sc_cache_file_digest(c, old_file, &d, &err), 0);
    SC_CHECK(sc_digest_equal(&d, &a_digest));
    SC_CHECK_INT(stats_of(c).stamps, 1);
    patch_file(old_file, 0, "BBBBBBBB", 8);
    set_mtime(old_file, &old);
    SC_CHECK_INT(sc_cache_file_digest(c, old_file, &d, &err), 0);
    SC_CHECK_MSG(sc_digest_equal(&d, &a_digest), "the stamp of an old file was not trusted");
    /* any other mtime is noticed */
    struct timespec older = {old.tv_sec, 123456788};
    set_mtime(old_file, &older);
    SC_CHECK_INT(sc_cache_file_digest(c, old_file, &d, &err), 0);
    SC_CHECK(sc_digest_equal(&d, &b_digest));

    /* A fresh file (mtime within 2 s of now) gets no stamp, so the same
     * in-place change within the same mtime tick is still seen. */
    char *fresh = sc_path_join(dir, "fresh.txt");
    write_text(fresh, "AAAAAAAA");
    struct timespec t = mtime_of(fresh);
    SC_CHECK_INT(sc_cache_file_digest(c, fresh, &d, &err), 0);
    SC_CHECK(sc_digest_equal(&d, &a_digest));
    SC_CHECK_INT(stats_of(c).stamps, 1);   /* no new stamp */
    patch_file(fresh, 0, "BBBBBBBB", 8);
    set_mtime(fresh, &t);                   /* same size, inode and mtime */
    SC_CHECK_INT(sc_cache_file_digest(c, fresh, &d, &err), 0);
    SC_CHECK_MSG(sc_digest_equal(&d, &b_digest), "a racily clean file was not re-hashed");

    /* once it has been quiet long enough, it is stamped too */
    struct timespec quiet = {time(NULL) - 5, 0};
    set_mtime(fresh, &quiet);
    SC_CHECK_INT(sc_cache_file_digest(c, fresh, &d, &err), 0);
    SC_CHECK(sc_digest_equal(&d, &b_digest));
    SC_CHECK_INT(stats_of(c).stamps, 2);

    /* a replaced file (new inode, same size and mtime) is noticed */
    char *tmp = sc_path_join(dir, "replacement");
    write_text(tmp, "AAAAAAAA");
    set_mtime(tmp, &quiet);
    SC_CHECK(rename(tmp, fresh) == 0);
    SC_CHECK_INT(sc_cache_file_digest(c, fresh, &d, &err), 0);
    SC_CHECK(sc_digest_equal(&d, &a_digest));

    free(tmp);
    free(fresh);
    free(old_file);
    sc_cache_close(c);
    remove_tree(dir);
}

/* ---------------------------------------------------------------- history, stats */

SC_TEST(history_runs_and_stats) {
    char *dir = sc_test_tempdir("cache");
    sc_cache *c = open_cache(dir);
    if (!c) return;
    sc_error err = {0};
    char *text = (char *)"untouched";
    SC_CHECK_INT(sc_cache_get_history(c, "graph.lua:lod0", &text, &err), SC_EMISS);
    SC_CHECK(text == NULL);
    SC_CHECK_INT(sc_cache_put_history(c, "graph.lua:lod0", "params a=1", &err), 0);
    SC_CHECK_INT(sc_cache_put_history(c, "graph.lua:lod1", "params b=2", &err), 0);
    SC_CHECK_INT(sc_cache_get_history(c, "graph.lua:lod0", &text, &err), 0);
    SC_CHECK_STR(text, "params a=1");
    free(text);
    SC_CHECK_INT(sc_cache_put_history(c, "graph.lua:lod0", "params a=2", &err), 0);
    SC_CHECK_INT(sc_cache_get_history(c, "graph.lua:lod0", &text, &err), 0);
    SC_CHECK_STR(text, "params a=2");
    free(text);

    sc_cache_stats s = stats_of(c);
    SC_CHECK(s.blobs == 0 && s.blob_bytes == 0 && s.actions == 0 && s.stamps == 0 && s.runs == 0);

    sc_digest b1, b2;
    put_text(c, "12345", &b1);
    put_text(c, "1234567890", &b2);
    put_text(c, "12345", &b1);
    sc_digest k1 = dig_str("k1"), k2 = dig_str("k2");
    SC_CHECK_INT(put_simple_action(c, &k1, "{}", &b1, 1, &err), 0);
    SC_CHECK_INT(put_simple_action(c, &k2, "{}", NULL, 0, &err), 0);
    SC_CHECK_INT(put_simple_action(c, &k2, "{}", &b2, 1, &err), 0);
    char *f = sc_path_join(dir, "src.txt");
    write_text(f, "source");
    struct timespec old = {time(NULL) - 30, 0};
    set_mtime(f, &old);
    sc_digest d;
    SC_CHECK_INT(sc_cache_file_digest(c, f, &d, &err), 0);
    SC_CHECK_INT(sc_cache_file_digest(c, f, &d, &err), 0);
    SC_CHECK_INT(sc_cache_put_run(c, "graph.lua", 3, 4, 0, 1.5, &err), 0);
    SC_CHECK_INT(sc_cache_put_run(c, "graph.lua", 0, 7, 0, 0.1, &err), 0);
    s = stats_of(c);
    SC_CHECK_INT(s.blobs, 2);
    SC_CHECK_INT(s.blob_bytes, 15);
    SC_CHECK_INT(s.actions, 2);
    SC_CHECK_INT(s.stamps, 1);
    SC_CHECK_INT(s.runs, 2);
    free(f);
    sc_cache_close(c);
    remove_tree(dir);
}

/* ---------------------------------------------------------------- upkeep */

SC_TEST(verify_finds_bad_and_missing) {
    char *dir = sc_test_tempdir("cache");
    sc_cache *c = open_cache(dir);
    if (!c) return;
    sc_error err = {0};
    sc_digest b[3], k[3];
    put_text(c, "verify blob 0", &b[0]);
    put_text(c, "verify blob 1", &b[1]);
    put_text(c, "verify blob 2", &b[2]);
    for (int i = 0; i < 3; i++) {
        char name[16];
        snprintf(name, sizeof name, "vk%d", i);
        k[i] = dig_str(name);
        SC_CHECK_INT(put_simple_action(c, &k[i], "{}", &b[i], 1, &err), 0);
    }
    sc_cache_verify_result v;
    SC_CHECK_INT(sc_cache_verify(c, &v, &err), 0);
    SC_CHECK(v.checked == 3 && v.bad == 0 && v.missing == 0 && v.actions_dropped == 0);

    char *p0 = sc_cache_blob_path(c, &b[0]), *p1 = sc_cache_blob_path(c, &b[1]);
    patch_file(p0, 0, "V", 1);
    SC_CHECK(unlink(p1) == 0);
    /* a stray file that is not a blob name is left alone */
    char *stray = sc_strprintf("%s/objects/README", dir);
    write_text(stray, "not a blob");
    SC_CHECK_INT(sc_cache_verify(c, &v, &err), 0);
    SC_CHECK_INT(v.checked, 2);
    SC_CHECK_INT(v.bad, 1);
    SC_CHECK_INT(v.missing, 1);
    SC_CHECK_INT(v.actions_dropped, 2);
    SC_CHECK(!action_exists(c, &k[0]));
    SC_CHECK(!action_exists(c, &k[1]));
    SC_CHECK(action_exists(c, &k[2]));
    SC_CHECK(!sc_cache_has_blob(c, &b[0]));
    SC_CHECK_INT(stats_of(c).blobs, 1);
    SC_CHECK_INT(sc_cache_verify(c, &v, &err), 0);
    SC_CHECK(v.checked == 1 && v.bad == 0 && v.missing == 0 && v.actions_dropped == 0);
    free(stray);
    free(p0);
    free(p1);
    sc_cache_close(c);
    remove_tree(dir);
}

SC_TEST(gc_keeps_recently_used) {
    char *dir = sc_test_tempdir("cache");
    sc_cache *c = open_cache(dir);
    if (!c) return;
    sc_error err = {0};
    sc_buf buf;
    sc_buf_init(&buf);
    char data[1000];
    sc_digest b[10];
    sc_digest ka = dig_str("needs 1"), kb = dig_str("needs 0 and 9"), kc = dig_str("needs 2 and 1");
    /* Uses, oldest first: 0 (put), 1 (put, then ka), 2 and 1 (kc), 3 ... 8
     * (puts), 9 and 0 (kb), and last 0 again (a read). A put of an action is
     * a use of its blobs. */
    for (int i = 0; i < 10; i++) {
        memset(data, 'a' + i, sizeof data);
        put_bytes(c, data, sizeof data, &b[i]);
        if (i == 1) SC_CHECK_INT(put_simple_action(c, &ka, "{}", &b[1], 1, &err), 0);
        if (i == 2) {
            sc_digest two[2] = {b[2], b[1]};
            SC_CHECK_INT(put_simple_action(c, &kc, "{}", two, 2, &err), 0);
        }
    }
    sc_digest both[2] = {b[9], b[0]};
    SC_CHECK_INT(put_simple_action(c, &kb, "{}", both, 2, &err), 0);
    /* an unrecorded blob file on disk (old), and temporary files */
    memset(data, 'z', sizeof data);
    sc_digest orphan;
    sc_digest_bytes(data, sizeof data, &orphan);
    char *op = sc_cache_blob_path(c, &orphan);
    char *opdir = sc_path_dirname(op);
    sc_make_dirs(opdir, &err);
    SC_CHECK_INT(sc_write_file_atomic(op, data, sizeof data, &err), 0);
    struct timespec two_hours_ago = {time(NULL) - 7200, 0};
    set_mtime(op, &two_hours_ago);
    char *stale_tmp = sc_strprintf("%s/tmp/stale-publish", dir);
    char *fresh_tmp = sc_strprintf("%s/tmp/fresh-publish", dir);
    write_text(stale_tmp, "half written");
    write_text(fresh_tmp, "in flight");
    set_mtime(stale_tmp, &two_hours_ago);

    /* blob 0 is used again: now the most recent */
    SC_CHECK_INT(sc_cache_get_blob(c, &b[0], &buf, &err), 0);

    /* 11 blobs of 1000 bytes; keep at most 5000: the orphan and 1..5 go */
    sc_cache_gc_result g;
    SC_CHECK_INT(sc_cache_gc(c, 5000, &g, &err), 0);
    SC_CHECK_INT(g.blobs_removed, 6);
    SC_CHECK_INT(g.bytes_removed, 6000);
    SC_CHECK_INT(g.bytes_left, 5000);
    SC_CHECK_INT(g.actions_dropped, 2);
    SC_CHECK(!sc_cache_has_blob(c, &orphan));
    for (int i = 1; i <= 5; i++) SC_CHECK_MSG(!sc_cache_has_blob(c, &b[i]), "blob %d kept", i);
    for (int i = 6; i <= 9; i++) SC_CHECK_MSG(sc_cache_has_blob(c, &b[i]), "blob %d removed", i);
    SC_CHECK(sc_cache_has_blob(c, &b[0]));
    SC_CHECK(!action_exists(c, &ka));
    SC_CHECK(action_exists(c, &kb));
    SC_CHECK(!action_exists(c, &kc));
    struct stat st;
    SC_CHECK(stat(stale_tmp, &st) != 0);
    SC_CHECK(stat(fresh_tmp, &st) == 0);
    sc_cache_stats s = stats_of(c);
    SC_CHECK_INT(s.blobs, 5);
    SC_CHECK_INT(s.blob_bytes, 5000);

    /* within the limit: nothing happens */
    SC_CHECK_INT(sc_cache_gc(c, 1 << 20, &g, &err), 0);
    SC_CHECK(g.blobs_removed == 0 && g.actions_dropped == 0 && g.bytes_left == 5000);

    /* the least recently used go first: 6, 7, 8 before 9 and 0 */
    SC_CHECK_INT(sc_cache_gc(c, 2500, &g, &err), 0);
    SC_CHECK_INT(g.blobs_removed, 3);
    SC_CHECK(g.bytes_left <= 2500);
    SC_CHECK(sc_cache_has_blob(c, &b[0]) && sc_cache_has_blob(c, &b[9]));
    SC_CHECK(action_exists(c, &kb));

    /* down to nothing */
    SC_CHECK_INT(sc_cache_gc(c, 0, &g, &err), 0);
    SC_CHECK_INT(g.bytes_left, 0);
    SC_CHECK_INT(g.actions_dropped, 1);
    SC_CHECK_INT(stats_of(c).actions, 0);
    SC_CHECK_INT(sc_cache_gc(c, -1, &g, &err), SC_EUSAGE);

    free(stale_tmp);
    free(fresh_tmp);
    free(op);
    free(opdir);
    sc_buf_free(&buf);
    sc_cache_close(c);
    remove_tree(dir);
}

SC_TEST(gc_counts_action_hits_as_use) {
    char *dir = sc_test_tempdir("cache");
    sc_cache *c = open_cache(dir);
    if (!c) return;
    sc_error err = {0};
    char data[1000];
    sc_digest x, y[4];
    memset(data, 'x', sizeof data);
    put_bytes(c, data, sizeof data, &x);
    sc_digest k = dig_str("uses x");
    SC_CHECK_INT(put_simple_action(c, &k, "{}", &x, 1, &err), 0);
    for (int i = 0; i < 4; i++) {
        memset(data, '0' + i, sizeof data);
        put_bytes(c, data, sizeof data, &y[i]);
    }
    /* x is the oldest put, but the action hit makes it the latest use */
    SC_CHECK(action_exists(c, &k));
    sc_cache_gc_result g;
    SC_CHECK_INT(sc_cache_gc(c, 2000, &g, &err), 0);
    SC_CHECK_INT(g.blobs_removed, 3);
    SC_CHECK_INT(g.actions_dropped, 0);
    SC_CHECK(sc_cache_has_blob(c, &x));
    SC_CHECK(sc_cache_has_blob(c, &y[3]));
    for (int i = 0; i < 3; i++) SC_CHECK(!sc_cache_has_blob(c, &y[i]));
    SC_CHECK(action_exists(c, &k));

    /* the same holds when the hit happens in another process: y4 is newer
     * than x until the other process looks the action up */
    memset(data, '4', sizeof data);
    sc_digest y4;
    put_bytes(c, data, sizeof data, &y4);
    sc_cache_close(c);
    fflush(NULL);
    pid_t pid = fork();
    if (pid == 0) {
        sc_cache *cc = NULL;
        sc_cache_action a;
        int rc = sc_cache_open(dir, &cc, &err) == 0 && sc_cache_get_action(cc, &k, &a, &err) == 0;
        if (rc) sc_cache_action_free(&a);
        sc_cache_close(cc);
        _exit(rc ? 0 : 1);
    }
    c = open_cache(dir);
    if (!c) return;
    int status = 0;
    SC_CHECK(waitpid(pid, &status, 0) == pid && WIFEXITED(status) && WEXITSTATUS(status) == 0);
    SC_CHECK_INT(sc_cache_gc(c, 1000, &g, &err), 0);
    SC_CHECK_INT(g.blobs_removed, 2);
    SC_CHECK(sc_cache_has_blob(c, &x));
    SC_CHECK(!sc_cache_has_blob(c, &y[3]));
    SC_CHECK(!sc_cache_has_blob(c, &y4));
    SC_CHECK(action_exists(c, &k));
    sc_cache_close(c);
    remove_tree(dir);
}

SC_TEST(open_errors) {
    char *dir = sc_test_tempdir("cache");
    sc_error err = {0};
    sc_cache *c = (sc_cache *)&err;   /* must be reset to NULL */
    char *file = sc_path_join(dir, "a-file");
    write_text(file, "x");
    char *under = sc_path_join(file, "cache");
    SC_CHECK(sc_cache_open(under, &c, &err) != 0);
    SC_CHECK(c == NULL);
    SC_CHECK(strlen(err.message) > 0);
    SC_CHECK_INT(sc_cache_open("", &c, &err), SC_EUSAGE);
    sc_cache_close(NULL);

    /* an index written by a newer format is refused, not misread */
    char *cdir = sc_path_join(dir, "c");
    c = open_cache(cdir);
    sc_cache_close(c);
    char *index = sc_path_join(cdir, "index.sqlite");
    sqlite3 *db = NULL;
    SC_CHECK(sqlite3_open(index, &db) == SQLITE_OK);
    SC_CHECK(sqlite3_exec(db, "PRAGMA user_version=99", NULL, NULL, NULL) == SQLITE_OK);
    sqlite3_close(db);
    memset(&err, 0, sizeof err);
    SC_CHECK(sc_cache_open(cdir, &c, &err) == SC_EIO);
    SC_CHECK(strstr(err.message, "newer") != NULL);
    free(index);
    free(cdir);
    free(under);
    free(file);
    remove_tree(dir);
}

/* ---------------------------------------------------------------- processes */

/* Child: put n blobs and n actions (one transaction each). Exit status 0 when
 * all succeeded. */
static void child_writer(const char *dir, int id, int n, int start_fd) {
    char go;
    if (start_fd >= 0) {
        ssize_t r = read(start_fd, &go, 1);
        (void)r;
    }
    sc_cache *c = NULL;
    sc_error err = {0};
    if (sc_cache_open(dir, &c, &err) != 0) {
        fprintf(stderr, "child %d: open: %s\n", id, err.message);
        _exit(1);
    }
    for (int i = 0; i < n; i++) {
        char text[64];
        sc_digest b, k;
        snprintf(text, sizeof text, "process %d action %d", id, i);
        sc_digest_bytes(text, strlen(text), &k);
        snprintf(text, sizeof text, "process %d blob %d", id, i);
        sc_digest_bytes(text, strlen(text), &b);
        if (sc_cache_put_blob(c, &b, text, strlen(text), &err) != 0 ||
            put_simple_action(c, &k, text, &b, 1, &err) != 0) {
            fprintf(stderr, "child %d: %s\n", id, err.message);
            _exit(strstr(err.message, "locked") ? 3 : 2);
        }
    }
    sc_cache_close(c);
    _exit(0);
}

SC_TEST(two_processes_share_a_cache) {
    char *dir = sc_test_tempdir("cache");
    int start[2];
    SC_CHECK(pipe(start) == 0);
    pid_t pids[2];
    for (int p = 0; p < 2; p++) {
        fflush(NULL);
        pids[p] = fork();
        SC_CHECK(pids[p] >= 0);
        if (pids[p] == 0) {
            close(start[1]);
            child_writer(dir, p, 200, start[0]);
        }
    }
    close(start[0]);
    close(start[1]);   /* both children start now (EOF), opening a new cache at once */
    for (int p = 0; p < 2; p++) {
        int status = 0;
        SC_CHECK(waitpid(pids[p], &status, 0) == pids[p]);
        SC_CHECK_MSG(WIFEXITED(status) && WEXITSTATUS(status) == 0,
                     "child %d: status %d (3 = database is locked)", p,
                     WIFEXITED(status) ? WEXITSTATUS(status) : -1);
    }
    sc_cache *c = open_cache(dir);
    if (c) {
        sc_cache_stats s = stats_of(c);
        SC_CHECK_INT(s.actions, 400);
        SC_CHECK_INT(s.blobs, 400);
        sc_error err = {0};
        sc_buf b;
        sc_buf_init(&b);
        int ok = 0;
        for (int p = 0; p < 2; p++)
            for (int i = 0; i < 200; i++) {
                char text[64];
                snprintf(text, sizeof text, "process %d action %d", p, i);
                sc_digest k = dig_str(text);
                sc_cache_action a;
                if (sc_cache_get_action(c, &k, &a, &err) != 0) continue;
                snprintf(text, sizeof text, "process %d blob %d", p, i);
                ok += a.nblobs == 1 && strcmp(a.outputs, text) == 0 &&
                      sc_cache_get_blob(c, &a.blobs[0], &b, &err) == 0 &&
                      b.len == strlen(text) && memcmp(b.data, text, b.len) == 0;
                sc_cache_action_free(&a);
            }
        SC_CHECK_INT(ok, 400);
        sc_buf_free(&b);
        sc_cache_close(c);
    }
    remove_tree(dir);
}

/* Child: put blobs and actions forever, one byte down the pipe after each. */
static void child_endless(const char *dir, int progress_fd) {
    sc_cache *c = NULL;
    sc_error err = {0};
    if (sc_cache_open(dir, &c, &err) != 0) _exit(1);
    static char data[64 * 1024];
    for (unsigned i = 0;; i++) {
        size_t n = 1000 + (i * 7919u) % (sizeof data - 1000);
        for (size_t j = 0; j < n; j++) data[j] = (char)(i * 131 + j * 7);
        sc_digest b[2], k;
        sc_digest_bytes(data, n, &b[0]);
        if (sc_cache_put_blob(c, &b[0], data, n, &err) != 0) _exit(2);
        data[0] ^= 0x55;
        sc_digest_bytes(data, n / 2, &b[1]);
        if (sc_cache_put_blob(c, &b[1], data, n / 2, &err) != 0) _exit(2);
        char key[48];
        snprintf(key, sizeof key, "endless %u", i);
        sc_digest_bytes(key, strlen(key), &k);
        if (i % 3 == 0) {   /* also batched puts */
            if (sc_cache_begin(c, &err) != 0) _exit(2);
            if (put_simple_action(c, &k, key, b, 2, &err) != 0) _exit(2);
            if (sc_cache_put_history(c, key, key, &err) != 0) _exit(2);
            if (sc_cache_commit(c, &err) != 0) _exit(2);
        } else if (put_simple_action(c, &k, key, b, 2, &err) != 0) {
            _exit(2);
        }
        char one = 1;
        if (write(progress_fd, &one, 1) != 1) _exit(3);
    }
}

SC_TEST(kill_9_leaves_a_consistent_cache) {
    char *dir = sc_test_tempdir("cache");
    for (int round = 0; round < 3; round++) {
        int progress[2];
        SC_CHECK(pipe(progress) == 0);
        fflush(NULL);
        pid_t pid = fork();
        SC_CHECK(pid >= 0);
        if (pid == 0) {
            close(progress[0]);
            child_endless(dir, progress[1]);
        }
        close(progress[1]);
        int seen = 0;
        char tmp[64];
        while (seen < 40 + 25 * round) {
            ssize_t r = read(progress[0], tmp, sizeof tmp);
            if (r <= 0) break;
            seen += (int)r;
        }
        struct timespec pause = {0, 1000000L * (1 + 3 * round)};
        nanosleep(&pause, NULL);
        kill(pid, SIGKILL);
        int status = 0;
        waitpid(pid, &status, 0);
        close(progress[0]);
        SC_CHECK_MSG(WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL,
                     "round %d: the writer ended by itself (status %d)", round, status);
    }

    sc_cache *c = open_cache(dir);
    if (!c) return;
    sc_error err = {0};
    sc_cache_verify_result v;
    SC_CHECK_INT(sc_cache_verify(c, &v, &err), 0);
    SC_CHECK(v.checked > 0);
    SC_CHECK_INT(v.bad, 0);
    SC_CHECK_INT(v.missing, 0);
    SC_CHECK_INT(v.actions_dropped, 0);

    /* every recorded action's blobs are there and intact */
    char *index = sc_path_join(dir, "index.sqlite");
    sqlite3 *db = NULL;
    SC_CHECK(sqlite3_open_v2(index, &db, SQLITE_OPEN_READONLY, NULL) == SQLITE_OK);
    sqlite3_stmt *s = NULL;
    SC_CHECK(sqlite3_prepare_v2(db, "SELECT key FROM actions", -1, &s, NULL) == SQLITE_OK);
    int actions = 0, good = 0;
    sc_buf b;
    sc_buf_init(&b);
    while (s && sqlite3_step(s) == SQLITE_ROW) {
        sc_digest k;
        if (sc_digest_parse((const char *)sqlite3_column_text(s, 0), &k) != 0) continue;
        actions++;
        sc_cache_action a;
        if (sc_cache_get_action(c, &k, &a, &err) != 0) continue;
        bool all = a.nblobs == 2;
        for (int i = 0; i < a.nblobs; i++)
            all = all && sc_cache_get_blob(c, &a.blobs[i], &b, &err) == 0;
        good += all;
        sc_cache_action_free(&a);
    }
    sqlite3_finalize(s);
    sqlite3_close(db);
    SC_CHECK(actions >= 40);
    SC_CHECK_INT(good, actions);
    printf("     %d actions survived 3 kills\n", actions);
    sc_buf_free(&b);
    free(index);
    sc_cache_close(c);
    remove_tree(dir);
}

/* Child: put 300 blobs and actions while another process runs gc. A put
 * of an action may find its blob collected meanwhile (SC_EMISS): the blob is
 * then put again. Any other failure is an error. */
static void child_beside_gc(const char *dir) {
    sc_cache *c = NULL;
    sc_error err = {0};
    if (sc_cache_open(dir, &c, &err) != 0) _exit(1);
    static char data[4096];
    for (int i = 0; i < 300; i++) {
        snprintf(data, sizeof data, "beside gc %d", i);
        sc_digest b, k;
        sc_digest_bytes(data, sizeof data, &b);
        sc_digest_bytes(data, strlen(data), &k);
        int rc = SC_EMISS;
        for (int attempt = 0; attempt < 1000 && rc == SC_EMISS; attempt++) {
            if (sc_cache_put_blob(c, &b, data, sizeof data, &err) != 0) {
                fprintf(stderr, "writer: %s\n", err.message);
                _exit(2);
            }
            struct timespec work = {0, 1000000};   /* the engine works between */
            nanosleep(&work, NULL);
            rc = put_simple_action(c, &k, "{}", &b, 1, &err);
        }
        if (rc != 0) {
            fprintf(stderr, "writer: %s\n", err.message);
            _exit(2);
        }
    }
    sc_cache_close(c);
    _exit(0);
}

SC_TEST(gc_beside_a_writer) {
    char *dir = sc_test_tempdir("cache");
    sc_cache *c = open_cache(dir);   /* the index exists before the fork */
    sc_cache_close(c);
    fflush(NULL);
    pid_t pid = fork();
    if (pid == 0) child_beside_gc(dir);
    c = open_cache(dir);
    if (!c) return;
    sc_error err = {0};
    /* A reader that looks, between gc passes, for an action naming a blob
     * the store no longer records (one snapshot per query). */
    char *index = sc_path_join(dir, "index.sqlite");
    sqlite3 *db = NULL;
    sqlite3_stmt *q = NULL;
    SC_CHECK(sqlite3_open_v2(index, &db, SQLITE_OPEN_READONLY, NULL) == SQLITE_OK);
    sqlite3_busy_timeout(db, 10000);
    SC_CHECK(sqlite3_prepare_v2(db,
                                "SELECT COUNT(*) FROM action_blobs ab WHERE NOT EXISTS "
                                "(SELECT 1 FROM blobs b WHERE b.digest = ab.digest)",
                                -1, &q, NULL) == SQLITE_OK);
    int gcs = 0, status = 0;
    int64_t removed = 0, dangling = 0;
    for (;;) {
        if (q && sqlite3_step(q) == SQLITE_ROW) dangling += sqlite3_column_int64(q, 0);
        if (q) sqlite3_reset(q);
        sc_cache_gc_result g;
        /* every other pass empties the store, so blobs the writer has just
         * put (and not yet named in an action) are collected too */
        SC_CHECK_INT(sc_cache_gc(c, gcs % 2 ? 0 : 8 * 4096, &g, &err), 0);
        removed += g.blobs_removed;
        gcs++;
        pid_t w = waitpid(pid, &status, WNOHANG);
        if (w == pid || w < 0) break;
        /* a breath between passes: back to back on a loaded 2-core machine,
         * gc won every race of the writer's 1,000 tries on one blob (the
         * writer starved; the store stayed consistent) */
        struct timespec pause = {0, 200000};
        nanosleep(&pause, NULL);
    }
    sqlite3_finalize(q);
    sqlite3_close(db);
    free(index);
    SC_CHECK_INT(dangling, 0);
    SC_CHECK_MSG(WIFEXITED(status) && WEXITSTATUS(status) == 0, "writer status %d", status);
    printf("     %d gc passes removed %lld blobs beside the writer\n", gcs, (long long)removed);
    SC_CHECK(removed > 0);
    /* no action ever points at a missing blob */
    sc_cache_verify_result v;
    SC_CHECK_INT(sc_cache_verify(c, &v, &err), 0);
    SC_CHECK_INT(v.bad, 0);
    SC_CHECK_INT(v.missing, 0);
    SC_CHECK_INT(v.actions_dropped, 0);
    /* one more full pass after the writer is gone empties the store */
    sc_cache_gc_result g;
    SC_CHECK_INT(sc_cache_gc(c, 0, &g, &err), 0);
    sc_cache_stats st = stats_of(c);
    SC_CHECK_INT(st.actions, 0);
    SC_CHECK_INT(st.blobs, 0);
    sc_cache_close(c);
    remove_tree(dir);
}

/* ---------------------------------------------------------------- healing */

/* A few blobs and an action that names one of them. */
static void fill(sc_cache *c, sc_digest blobs[3], sc_digest *key) {
    put_text(c, "first blob", &blobs[0]);
    put_text(c, "second blob", &blobs[1]);
    put_text(c, "third blob", &blobs[2]);
    *key = dig_str("the action");
    sc_error err = {0};
    SC_CHECK_MSG(put_simple_action(c, key, "{}", blobs, 1, &err) == 0, "%s", err.message);
}

/* Every blob readable again, and the cache usable for writing. */
static void check_usable(sc_cache *c, const sc_digest blobs[3]) {
    sc_buf b;
    sc_buf_init(&b);
    sc_error err = {0};
    for (int i = 0; i < 3; i++) SC_CHECK_MSG(sc_cache_get_blob(c, &blobs[i], &b, &err) == 0, "%s", err.message);
    sc_buf_free(&b);
    sc_digest d, key = dig_str("a new action");
    put_text(c, "a new blob", &d);
    SC_CHECK_MSG(put_simple_action(c, &key, "{}", &d, 1, &err) == 0, "%s", err.message);
    SC_CHECK(action_exists(c, &key));
    sc_cache_stats s = stats_of(c);
    SC_CHECK_INT(s.blobs, 4);
}

SC_TEST(a_damaged_index_is_rebuilt_from_the_store) {
    const char *const damages[] = {"junk", "truncated", "not a database"};
    for (int k = 0; k < 3; k++) {
        char *dir = sc_test_tempdir("cache");
        sc_cache *c = open_cache(dir);
        if (!c) return;
        sc_digest blobs[3], key;
        fill(c, blobs, &key);
        sc_cache_close(c);
        char *index = sc_path_join(dir, "index.sqlite");
        struct stat st;
        SC_CHECK(stat(index, &st) == 0);
        if (k == 0) {   /* 8 KiB of junk in the middle */
            char junk[8192];
            for (size_t i = 0; i < sizeof junk; i++) junk[i] = (char)(i * 7 + 13);
            patch_file(index, st.st_size / 2 > 4096 ? 4096 : st.st_size / 2, junk, sizeof junk);
        } else if (k == 1) {
            SC_CHECK(truncate(index, st.st_size / 2) == 0);
        } else {
            write_text(index, "this is not a database, it is text that is long enough to be read as a header\n");
        }
        sc_error err = {0};
        c = NULL;
        int rc = sc_cache_open(dir, &c, &err);
        SC_CHECK_MSG(rc == 0 && c, "%s: open: %s", damages[k], err.message);
        if (c) {
            const char *notice = sc_cache_notice(c);
            SC_CHECK_MSG(notice && strstr(notice, "the index was damaged") && strstr(notice, "3 blobs"), "%s: %s",
                         damages[k], notice ? notice : "(no notice)");
            SC_CHECK(!action_exists(c, &key));   /* actions are what is lost */
            check_usable(c, blobs);
            sc_cache_verify_result v;
            SC_CHECK(sc_cache_verify(c, &v, &err) == 0);
            SC_CHECK(!v.index_rebuilt && v.bad == 0 && v.missing == 0);
            sc_cache_close(c);
        }
        /* opened again: healthy, no notice */
        c = open_cache(dir);
        SC_CHECK(c && !sc_cache_notice(c));
        sc_cache_close(c);
        free(index);
        remove_tree(dir);
    }
}

SC_TEST(a_folder_in_place_of_a_blob_is_a_miss_and_verify_removes_it) {
    char *dir = sc_test_tempdir("cache");
    sc_cache *c = open_cache(dir);
    if (!c) return;
    sc_digest d;
    put_text(c, "blob that becomes a folder", &d);
    char *path = sc_cache_blob_path(c, &d);
    sc_test_system("rm -f '%s' && mkdir -p '%s/inside'", path, path);
    sc_buf b;
    sc_buf_init(&b);
    sc_error err = {0};
    SC_CHECK_INT(sc_cache_get_blob(c, &d, &b, &err), SC_EMISS);
    SC_CHECK(!sc_cache_has_blob(c, &d) || access(path, F_OK) != 0);
    /* and verify finds another one */
    sc_digest e;
    put_text(c, "another", &e);
    char *other = sc_cache_blob_path(c, &e);
    sc_test_system("rm -f '%s' && mkdir -p '%s'", other, other);
    sc_cache_verify_result v;
    SC_CHECK_MSG(sc_cache_verify(c, &v, &err) == 0, "%s", err.message);
    SC_CHECK_INT(v.not_files, 1);
    SC_CHECK(access(other, F_OK) != 0);
    sc_buf_free(&b);
    free(path), free(other);
    sc_cache_close(c);
    remove_tree(dir);
}

SC_TEST(a_path_too_long_for_sqlite_is_named) {
    char long_dir[700];
    char *base = sc_test_tempdir("cache");
    int n = snprintf(long_dir, sizeof long_dir, "%s/", base);
    while (n < 600) long_dir[n++] = 'x';
    long_dir[n] = 0;
    sc_cache *c = NULL;
    sc_error err = {0};
    SC_CHECK(sc_cache_open(long_dir, &c, &err) != 0);
    SC_CHECK_MSG(strstr(err.message, "too long") && strstr(err.message, "SQLite"), "%s", err.message);
    remove_tree(base);
}

/* gc frees space on a full disk (a small tmpfs, where the machine allows
 * mounting one), and a full disk is reported as one. */
SC_TEST(gc_runs_on_a_full_disk) {
    char *dir = sc_test_tempdir("cache");
    if (sc_test_system("mount -t tmpfs -o size=12m tmpfs '%s' 2>/dev/null", dir) != 0) {
        printf("  cannot mount a tmpfs here: skipped\n");
        remove_tree(dir);
        return;
    }
    sc_cache *c = open_cache(dir);
    int stored = 0, rc = 0;
    sc_error err = {0};
    char *chunk = malloc(256 << 10);
    for (int i = 0; c && chunk && rc == 0 && i < 200; i++) {
        memset(chunk, i, 256 << 10);
        sc_digest d;
        sc_digest_bytes(chunk, 256 << 10, &d);
        rc = sc_cache_put_blob(c, &d, chunk, 256 << 10, &err);
        if (rc == 0) stored++;
    }
    SC_CHECK_MSG(rc != 0 && strstr(err.message, "disk is full"), "after %d blobs: rc %d, %s", stored, rc,
                 err.message);
    sc_cache_gc_result g;
    memset(&g, 0, sizeof g);
    int grc = c ? sc_cache_gc(c, 1 << 20, &g, &err) : -1;
    SC_CHECK_MSG(grc == 0, "gc on a full disk: %s", err.message);
    SC_CHECK(g.blobs_removed > 0 && g.bytes_left <= (1 << 20));
    /* and there is room again */
    sc_digest d;
    memset(chunk, 255, 256 << 10);
    sc_digest_bytes(chunk, 256 << 10, &d);
    SC_CHECK_MSG(c && sc_cache_put_blob(c, &d, chunk, 256 << 10, &err) == 0, "%s", err.message);
    free(chunk);
    sc_cache_close(c);
    sc_test_system("umount '%s'", dir);
    remove_tree(dir);
}


/* Leases: one holder per action key. A live other process's lease is busy;
 * a dead one's is taken over; a released one is free. */
SC_TEST(leases_one_holder) {
    char *dir = sc_test_tempdir("cache");
    sc_digest k1 = dig_str("action one"), k2 = dig_str("action two");
    int ready[2], quit[2];
    SC_CHECK(pipe(ready) == 0 && pipe(quit) == 0);
    pid_t live = fork();
    if (live == 0) {   /* holds k1 until told to quit */
        sc_cache *c = NULL;
        sc_error err;
        int rc = sc_cache_open(dir, &c, &err) == SC_OK ? sc_cache_lease_take(c, &k1, 10, NULL, &err) : 1;
        char byte = rc == SC_OK ? 'y' : 'n';
        (void)!write(ready[1], &byte, 1);
        (void)!read(quit[0], &byte, 1);
        _exit(0);
    }
    char byte = 0;
    SC_CHECK(read(ready[0], &byte, 1) == 1 && byte == 'y');
    pid_t dead = fork();
    if (dead == 0) {   /* takes k2 and dies without giving it back */
        sc_cache *c = NULL;
        sc_error err;
        _exit(sc_cache_open(dir, &c, &err) == SC_OK && sc_cache_lease_take(c, &k2, 10, NULL, &err) == SC_OK ? 0 : 1);
    }
    int status = 0;
    waitpid(dead, &status, 0);
    SC_CHECK(WIFEXITED(status) && WEXITSTATUS(status) == 0);

    sc_cache *c = open_cache(dir);
    sc_error err = {0};
    sc_cache_lease_holder h;
    SC_CHECK_INT(sc_cache_lease_take(c, &k1, 10, &h, &err), SC_EBUSY);
    SC_CHECK_INT(h.pid, live);
    SC_CHECK(strstr(err.message, "is cooking it") != NULL);
    SC_CHECK_INT(sc_cache_lease_take(c, &k2, 10, &h, &err), SC_OK);   /* its holder is gone */
    SC_CHECK(h.taken_over);
    SC_CHECK_INT(h.pid, dead);
    SC_CHECK_INT(sc_cache_lease_take(c, &k2, 10, &h, &err), SC_OK);   /* ours already */
    SC_CHECK(!h.taken_over);
    SC_CHECK_INT(sc_cache_lease_renew(c, &err), SC_OK);
    (void)!write(quit[1], "q", 1);   /* the live holder exits without giving k1 back */
    waitpid(live, &status, 0);
    SC_CHECK_INT(sc_cache_lease_take(c, &k1, 10, &h, &err), SC_OK);
    SC_CHECK(h.taken_over);
    SC_CHECK_INT(sc_cache_lease_release(c, &k1, &err), SC_OK);
    SC_CHECK_INT(sc_cache_lease_take(c, &k1, 10, &h, &err), SC_OK);   /* free again */
    SC_CHECK(!h.taken_over && h.pid == 0);
    SC_CHECK_INT(sc_cache_lease_release(c, NULL, &err), SC_OK);
    sc_cache_close(c);
    close(ready[0]), close(ready[1]), close(quit[0]), close(quit[1]);
    free(dir);
}

int main(void) { return sc_test_main(); }
