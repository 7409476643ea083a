/* test_cli.c - end-to-end runs of the seamcook command line: cooking, the
 * cache (hits, early cutoff, corrupt blobs, two processes, kill -9, trimming),
 * explain, dry runs, --set, bad input and exit statuses, --help and
 * --version, --json, test --junit, what --out keeps, watch, and the command
 * installed into a prefix. Each test works in its own temporary folder with
 * its own cache. The properties are read back from the files the command
 * writes (report.json, outputs) and what it prints, not from its internals. */
#include "sc_test.h"

#include <signal.h>
#include <stdlib.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cjson/cJSON.h>

#include "sc_base.h"

static const char *bin(void) {
    const char *b = getenv("SC_BIN");
    return b ? b : "./seamcook";
}

static char *data(const char *rel) {
    char *r = sc_strprintf("tests/data/graphs/%s", rel);
    char *p = sc_test_source_path(r);
    free(r);
    return p;
}

/* Run seamcook with arguments; stderr goes to dir/err.txt. Returns exit status. */
static int cook(const char *dir, const char *args) {
    return sc_test_system("cd '%s' && '%s' %s >out.txt 2>err.txt", dir, bin(), args);
}

static char *slurp(const char *dir, const char *name) {
    char *path = sc_path_join(dir, name);
    sc_buf b;
    sc_buf_init(&b);
    sc_error err;
    char *s = NULL;
    if (sc_read_file(path, 1u << 30, &b, &err) == SC_OK) s = sc_buf_take_string(&b);
    sc_buf_free(&b);
    free(path);
    return s;
}

typedef struct counts {
    int ran, cached, failed, skipped, nodes;
} counts;

static counts report_counts(const char *out_dir) {
    counts c = {-1, -1, -1, -1, -1};
    char *json = slurp(out_dir, "report.json");
    cJSON *root = json ? cJSON_Parse(json) : NULL;
    const cJSON *nodes = cJSON_GetObjectItemCaseSensitive(root, "nodes");
    if (cJSON_IsArray(nodes)) {
        c = (counts){0, 0, 0, 0, cJSON_GetArraySize(nodes)};
        const cJSON *n;
        cJSON_ArrayForEach(n, nodes) {
            const char *st = cJSON_GetObjectItemCaseSensitive(n, "status")->valuestring;
            if (!strcmp(st, "ran")) c.ran++;
            else if (!strcmp(st, "cached")) c.cached++;
            else if (!strcmp(st, "failed")) c.failed++;
            else if (!strcmp(st, "skipped")) c.skipped++;
        }
    }
    cJSON_Delete(root);
    free(json);
    return c;
}

static const char *node_status(const char *out_dir, const char *name, char *buf, size_t n) {
    snprintf(buf, n, "?");
    char *json = slurp(out_dir, "report.json");
    cJSON *root = json ? cJSON_Parse(json) : NULL;
    const cJSON *node;
    cJSON_ArrayForEach(node, cJSON_GetObjectItemCaseSensitive(root, "nodes")) {
        if (strcmp(cJSON_GetObjectItemCaseSensitive(node, "name")->valuestring, name) == 0)
            snprintf(buf, n, "%s", cJSON_GetObjectItemCaseSensitive(node, "status")->valuestring);
    }
    cJSON_Delete(root);
    free(json);
    return buf;
}

static bool file_digest(const char *path, sc_digest *d) {
    sc_buf b;
    sc_buf_init(&b);
    sc_error err;
    bool ok = sc_read_file(path, 1u << 30, &b, &err) == SC_OK;
    if (ok) sc_digest_bytes(b.data, b.len, d);
    sc_buf_free(&b);
    return ok;
}

static bool same_file(const char *a, const char *b) {
    sc_digest da, db;
    return file_digest(a, &da) && file_digest(b, &db) && sc_digest_equal(&da, &db);
}

static bool exists(const char *path) {
    struct stat st;
    return stat(path, &st) == 0;
}

/* A tiny textured OBJ (a tetrahedron with a seam) and its PNG texture. */
static void write_obj_asset(const char *dir, const char *comment) {
    char *obj = sc_strprintf("%s/tet.obj", dir), *mtl = sc_strprintf("%s/tet.mtl", dir);
    char *text = sc_strprintf(
        "# %s\nmtllib tet.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\n"
        "vt 0.1 0.1\nvt 0.9 0.1\nvt 0.1 0.9\nvt 0.5 0.5\nvt 0.9 0.9\n"
        "usemtl skin\nf 1/1 3/3 2/2\nf 1/1 2/2 4/4\nf 1/1 4/4 3/3\nf 2/2 3/3 4/5\n", comment);
    sc_error err;
    sc_write_file_atomic(obj, text, strlen(text), &err);
    const char *m = "newmtl skin\nmap_Kd tet.png\n";
    sc_write_file_atomic(mtl, m, strlen(m), &err);
    free(obj), free(mtl), free(text);
}

/* Make tet.png with the procedural texture of a graph run (any PNG will do). */
static void write_png(const char *dir, const char *texture_size) {
    char *g = data("proc_save.lua");
    SC_CHECK_INT(sc_test_system("cd '%s' && '%s' run '%s' --cache pngcache --out pngout "
                                "--set texture_size=%s -q && cp pngout/asset_default_color.png tet.png",
                                dir, bin(), g, texture_size), 0);
    free(g);
}

/* ---------------------------------------------------------------- tests */

SC_TEST(second_run_cooks_nothing) {
    char *dir = sc_test_tempdir("cli");
    char *g = data("proc_save.lua");
    char *args = sc_strprintf("run '%s' --cache cache --out out", g);
    SC_CHECK_INT(cook(dir, args), 0);
    char *out = sc_path_join(dir, "out");
    counts c = report_counts(out);
    SC_CHECK_INT(c.nodes, 2);
    SC_CHECK_INT(c.ran, 2);
    char *obj = sc_path_join(out, "asset.obj");
    SC_CHECK(exists(obj));
    SC_CHECK_INT(cook(dir, args), 0);
    c = report_counts(out);
    SC_CHECK_INT(c.ran, 0);
    SC_CHECK_INT(c.cached, 2);
    /* outputs deleted from --out come back from the cache without cooking */
    unlink(obj);
    SC_CHECK_INT(cook(dir, args), 0);
    c = report_counts(out);
    SC_CHECK_INT(c.ran, 0);
    SC_CHECK(exists(obj));
    free(obj), free(out), free(args), free(g), free(dir);
}

SC_TEST(jobs_do_not_change_bytes) {
    char *dir = sc_test_tempdir("cli");
    char *g = data("proc_save.lua");
    char *a1 = sc_strprintf("run '%s' --cache c1 --out o1 -j 1", g);
    char *a2 = sc_strprintf("run '%s' --cache c2 --out o2 -j 2", g);
    SC_CHECK_INT(cook(dir, a1), 0);
    SC_CHECK_INT(cook(dir, a2), 0);
    const char *files[] = {"asset.obj", "asset.mtl", "asset_default_color.png"};
    for (int i = 0; i < 3; i++) {
        char *p1 = sc_strprintf("%s/o1/%s", dir, files[i]), *p2 = sc_strprintf("%s/o2/%s", dir, files[i]);
        SC_CHECK_MSG(same_file(p1, p2), "%s differs between -j1 and -j2", files[i]);
        free(p1), free(p2);
    }
    free(a1), free(a2), free(g), free(dir);
}

SC_TEST(parameter_change_explained) {
    char *dir = sc_test_tempdir("cli");
    char *g = data("proc_save.lua");
    char *a = sc_strprintf("run '%s' --cache cache --out out --set texture_size=96", g);
    char *b = sc_strprintf("run '%s' --cache cache --out out --set texture_size=128 --explain", g);
    SC_CHECK_INT(cook(dir, a), 0);
    SC_CHECK_INT(cook(dir, b), 0);
    char *err = slurp(dir, "err.txt");
    SC_CHECK_MSG(err && strstr(err, "parameter texture_size: 96 -> 128"), "explain said: %s", err ? err : "(nothing)");
    SC_CHECK_MSG(err && strstr(err, "input atlas changed (from asset)"), "explain said: %s", err ? err : "(nothing)");
    free(err);
    /* dry run: says what would cook and writes nothing */
    char *n = sc_strprintf("run '%s' --cache cache --out dry --set texture_size=160 -n", g);
    SC_CHECK_INT(cook(dir, n), 0);
    err = slurp(dir, "err.txt");
    SC_CHECK_MSG(err && strstr(err, "would cook asset"), "dry run said: %s", err ? err : "(nothing)");
    char *dry = sc_path_join(dir, "dry");
    SC_CHECK(!exists(dry));
    free(dry), free(err), free(n), free(a), free(b), free(g), free(dir);
}

SC_TEST(early_cutoff_and_texture_change) {
    char *dir = sc_test_tempdir("cli");
    write_png(dir, "64");
    write_obj_asset(dir, "first");
    char *g = data("obj_save.lua");
    char *args = sc_strprintf("run '%s' --cache cache --out out --set mesh=tet.obj --explain", g);
    SC_CHECK_INT(cook(dir, args), 0);
    char *out = sc_path_join(dir, "out");
    counts c = report_counts(out);
    SC_CHECK_INT(c.ran, 2);
    char st[32];
    /* a comment changes the file but not the atlas: load cooks, save does not */
    write_obj_asset(dir, "second, same mesh");
    SC_CHECK_INT(cook(dir, args), 0);
    SC_CHECK_STR(node_status(out, "load", st, sizeof st), "ran");
    SC_CHECK_STR(node_status(out, "save", st, sizeof st), "cached");
    char *err = slurp(dir, "err.txt");
    SC_CHECK_MSG(err && strstr(err, "tet.obj changed"), "explain said: %s", err ? err : "(nothing)");
    free(err);
    /* new texture bytes: everything downstream of the texture cooks */
    write_png(dir, "80");
    SC_CHECK_INT(cook(dir, args), 0);
    SC_CHECK_STR(node_status(out, "load", st, sizeof st), "ran");
    SC_CHECK_STR(node_status(out, "save", st, sizeof st), "ran");
    err = slurp(dir, "err.txt");
    SC_CHECK_MSG(err && strstr(err, "tet.png changed"), "explain said: %s", err ? err : "(nothing)");
    free(err);
    free(out), free(args), free(g), free(dir);
}

SC_TEST(corrupt_blobs_are_recooked) {
    char *dir = sc_test_tempdir("cli");
    char *g = data("proc_save.lua");
    char *args = sc_strprintf("run '%s' --cache cache --out out", g);
    SC_CHECK_INT(cook(dir, args), 0);
    SC_CHECK_INT(sc_test_system("cd '%s' && cp -r out good", dir), 0);
    /* flip a byte in the middle of every stored blob, and lose the outputs */
    SC_CHECK_INT(sc_test_system(
        "cd '%s' && rm -r out && for f in $(find cache/objects -type f); do "
        "n=$(stat -c %%s $f); printf '\\377' | dd of=$f bs=1 seek=$((n/2)) conv=notrunc status=none; done",
        dir), 0);
    SC_CHECK_INT(cook(dir, args), 0);
    char *out = sc_path_join(dir, "out");
    counts c = report_counts(out);
    SC_CHECK_MSG(c.ran >= 1, "ran %d: a corrupt blob must not be served", c.ran);
    const char *files[] = {"asset.obj", "asset.mtl", "asset_default_color.png"};
    for (int i = 0; i < 3; i++) {
        char *p1 = sc_strprintf("%s/good/%s", dir, files[i]), *p2 = sc_strprintf("%s/out/%s", dir, files[i]);
        SC_CHECK_MSG(same_file(p1, p2), "%s differs after re-cooking", files[i]);
        free(p1), free(p2);
    }
    /* verify removes the bad blobs nothing has read yet; after that the cache is clean */
    sc_test_system("cd '%s' && '%s' cache verify --cache cache >/dev/null", dir, bin());
    SC_CHECK_INT(sc_test_system("cd '%s' && '%s' cache verify --cache cache >/dev/null", dir, bin()), 0);
    free(out), free(args), free(g), free(dir);
}

SC_TEST(two_processes_share_a_cache) {
    char *dir = sc_test_tempdir("cli");
    char *g = data("proc_save.lua");
    SC_CHECK_INT(sc_test_system(
        "cd '%s' && ('%s' run '%s' --cache cache --out o1 --set texture_size=256 -q 2>e1.txt & "
        "'%s' run '%s' --cache cache --out o2 --set texture_size=256 -q 2>e2.txt & "
        "'%s' run '%s' --cache cache --out o3 --set texture_size=200 -q 2>e3.txt & "
        "wait %%1 && wait %%2 && wait %%3)",
        dir, bin(), g, bin(), g, bin(), g), 0);
    char *p1 = sc_strprintf("%s/o1/asset_default_color.png", dir);
    char *p2 = sc_strprintf("%s/o2/asset_default_color.png", dir);
    SC_CHECK(same_file(p1, p2));
    char *e = slurp(dir, "e1.txt");
    SC_CHECK_MSG(e && !strstr(e, "locked"), "stderr: %s", e ? e : "(nothing)");
    free(e);
    SC_CHECK_INT(sc_test_system("cd '%s' && '%s' cache verify --cache cache >/dev/null", dir, bin()), 0);
    free(p1), free(p2), free(g), free(dir);
}

/* SIGKILL a cook at 20 points spread over its length (jittered, seeded):
 * while it runs nodes, publishes blobs, records actions and writes --out.
 * After each kill `cache verify` finds nothing wrong, and a last full cook
 * writes the same bytes as a clean one in a cache of its own, leaving no
 * temporary file in --out. */
SC_TEST(kill_9_then_rerun_is_correct) {
    char *dir = sc_test_tempdir("cli");
    char *g = data("slow.lua");
    /* a reference in its own cache, timed */
    char *ref = sc_strprintf("run '%s' --cache refcache --out ref -q --set texture_size=1024", g);
    double t0 = sc_now();
    SC_CHECK_INT(cook(dir, ref), 0);
    double length = sc_now() - t0;
    srand(20261204);
    for (int k = 0; k < 20; k++) {
        double at = length * (k + (double)rand() / RAND_MAX) / 20;
        pid_t pid = fork();
        if (pid == 0) {
            if (chdir(dir) != 0) _exit(127);
            execl(bin(), bin(), "run", g, "--cache", "cache", "--out", "out", "-q",
                  "--set", "texture_size=1024", (char *)NULL);
            _exit(127);
        }
        usleep((useconds_t)(at * 1e6));
        kill(pid, SIGKILL);
        int status;
        waitpid(pid, &status, 0);
        SC_CHECK_MSG(sc_test_system("cd '%s' && '%s' cache verify --cache cache >verify.txt 2>&1", dir, bin()) == 0,
                     "verify after a kill at %.2f s of %.2f", at, length);
    }
    /* what a killed writer leaves in --out (its process gone) goes at the next run; a live one's stays */
    SC_CHECK_INT(sc_test_system("cd '%s' && mkdir -p out/sub && touch 'out/" SC_TMP_PREFIX "big.obj.999999999.aBcDeF' "
                                "'out/sub/" SC_TMP_PREFIX "x.png.999999999.QwErTy' 'out/" SC_TMP_PREFIX "y.png.%d.LiVeXx'",
                                dir, (int)getpid()), 0);
    char *args = sc_strprintf("run '%s' --cache cache --out out -q --set texture_size=1024", g);
    SC_CHECK_INT(cook(dir, args), 0);
    char *live = sc_strprintf("%s/out/" SC_TMP_PREFIX "y.png.%d.LiVeXx", dir, (int)getpid());
    SC_CHECK(exists(live));
    unlink(live);
    free(live);
    char *p1 = sc_strprintf("%s/ref/big_default_color.png", dir), *p2 = sc_strprintf("%s/out/big_default_color.png", dir);
    char *o1 = sc_strprintf("%s/ref/big.obj", dir), *o2 = sc_strprintf("%s/out/big.obj", dir);
    SC_CHECK(same_file(p1, p2));
    SC_CHECK(same_file(o1, o2));
    SC_CHECK_INT(sc_test_system("cd '%s' && '%s' cache verify --cache cache >/dev/null", dir, bin()), 0);
    SC_CHECK_INT(sc_test_system("cd '%s' && test -z \"$(find out -name '" SC_TMP_PREFIX "*')\"", dir), 0);
    free(p1), free(p2), free(o1), free(o2), free(args), free(ref), free(g), free(dir);
}

SC_TEST(bad_input_exit_statuses) {
    char *dir = sc_test_tempdir("cli");
    char *err;
    /* usage errors: 2 */
    SC_CHECK_INT(cook(dir, "frobnicate"), 2);
    SC_CHECK_INT(cook(dir, "run"), 2);
    SC_CHECK_INT(cook(dir, "run x.lua --jobs zero"), 2);
    SC_CHECK_INT(cook(dir, "run x.lua --bogus"), 2);
    /* a missing graph file: 1, naming it */
    SC_CHECK_INT(cook(dir, "run missing.lua --cache cache"), 1);
    err = slurp(dir, "err.txt");
    SC_CHECK_MSG(err && strstr(err, "missing.lua"), "stderr: %s", err ? err : "(nothing)");
    free(err);
    /* a Lua error: file:line */
    char *g = data("lua_error.lua");
    char *a = sc_strprintf("run '%s' --cache cache --out out", g);
    SC_CHECK_INT(cook(dir, a), 1);
    err = slurp(dir, "err.txt");
    SC_CHECK_MSG(err && strstr(err, "lua_error.lua:3"), "stderr: %s", err ? err : "(nothing)");
    free(err), free(a), free(g);
    /* a parameter out of range: file:line and node:param */
    g = data("bad_param.lua");
    a = sc_strprintf("run '%s' --cache cache --out out", g);
    SC_CHECK_INT(cook(dir, a), 1);
    err = slurp(dir, "err.txt");
    SC_CHECK_MSG(err && strstr(err, "bad_param.lua:1") && strstr(err, "resolution"), "stderr: %s", err ? err : "(nothing)");
    free(err), free(a), free(g);
    /* an unused --set is an error, not silence */
    g = data("proc_save.lua");
    a = sc_strprintf("run '%s' --cache cache --out out --set resolutoin=3", g);
    SC_CHECK_INT(cook(dir, a), 2);
    err = slurp(dir, "err.txt");
    SC_CHECK_MSG(err && strstr(err, "resolutoin"), "stderr: %s", err ? err : "(nothing)");
    free(err), free(a);
    /* a --set value the parameter refuses is a usage error naming node:param and the --set */
    const char *refused[][2] = {{"resolution=abc", "--set resolution=abc: not a number"},
                                {"resolution=100000", "--set resolution=100000: asset:resolution: 100000 is outside"},
                                {"asset.resolution=abc", "--set asset.resolution=abc: asset:resolution: 'abc' is not a number"},
                                {"asset.resolution=0", "--set asset.resolution=0: asset:resolution: 0 is outside"}};
    for (int i = 0; i < 4; i++) {
        a = sc_strprintf("run '%s' --cache cache --out out --set %s", g, refused[i][0]);
        SC_CHECK_INT(cook(dir, a), 2);
        err = slurp(dir, "err.txt");
        SC_CHECK_MSG(err && strstr(err, refused[i][1]) && strstr(err, "proc_save.lua"), "stderr: %s", err ? err : "");
        free(err), free(a);
    }
    /* options a command does not take, and bad values, are usage errors too */
    SC_CHECK_INT(cook(dir, "nodes --json"), 2);
    SC_CHECK_INT(cook(dir, "run x.lua --junit j.xml"), 2);
    SC_CHECK_INT(cook(dir, "watch x.lua --max-runs often"), 2);
    SC_CHECK_INT(cook(dir, "run x.lua --cache-max-size lots"), 2);
    SC_CHECK_INT(sc_test_system("cd '%s' && SEAMCOOK_CACHE_MAX_SIZE=lots '%s' run x.lua >out.txt 2>err.txt", dir, bin()), 2);
    /* a name set twice is a usage error, not the last one silently */
    a = sc_strprintf("run '%s' --cache cache --out out --set resolution=3 --set resolution=4", g);
    SC_CHECK_INT(cook(dir, a), 2);
    err = slurp(dir, "err.txt");
    SC_CHECK_MSG(err && strstr(err, "set twice"), "stderr: %s", err ? err : "(nothing)");
    free(err), free(a);
    /* with HOME unset and no cache given, say so instead of a cache in the working folder */
    a = sc_strprintf("cd '%s' && env -u HOME -u SEAMCOOK_CACHE -u XDG_CACHE_HOME '%s' run '%s' --out out >out.txt 2>err.txt",
                     dir, bin(), g);
    SC_CHECK_INT(sc_test_system("%s", a), 2);
    err = slurp(dir, "err.txt");
    SC_CHECK_MSG(err && strstr(err, "HOME is not set"), "stderr: %s", err ? err : "(nothing)");
    char *stray = sc_path_join(dir, ".seamcook-cache");
    SC_CHECK(!exists(stray));
    free(stray), free(err), free(a);
    /* a bad --lua-timeout is a usage error; a graph past it fails naming the limit */
    a = sc_strprintf("run '%s' --cache cache --out out --lua-timeout -1", g);
    SC_CHECK_INT(cook(dir, a), 2);
    free(a), free(g);
    g = data("slow_loop.lua");
    a = sc_strprintf("run '%s' --cache cache --out out --lua-timeout 0.3", g);
    SC_CHECK_INT(cook(dir, a), 1);
    err = slurp(dir, "err.txt");
    SC_CHECK_MSG(err && strstr(err, "graph evaluation exceeded 0.3 s"), "stderr: %s", err ? err : "(nothing)");
    free(err), free(a), free(g);
    /* a cache that cannot be opened is named once */
    a = sc_strprintf("run x.lua --cache /proc/no-such-cache");
    SC_CHECK_INT(cook(dir, a), 1);
    err = slurp(dir, "err.txt");
    SC_CHECK_MSG(err && strstr(err, "cache /proc/no-such-cache") &&
                     !strstr(strstr(err, "cache /proc/no-such-cache") + 1, "cache /proc/no-such-cache"),
                 "stderr: %s", err ? err : "(nothing)");
    free(err), free(a);
    free(dir);
}

SC_TEST(help_and_version) {
    char *dir = sc_test_tempdir("cli");
    char *o;
    SC_CHECK_INT(cook(dir, "--version"), 0);
    o = slurp(dir, "out.txt");
    SC_CHECK_MSG(o && !strncmp(o, "seamcook ", 9) && strlen(o) > 10, "stdout: %s", o ? o : "");
    free(o);
    SC_CHECK_INT(cook(dir, "version"), 0);
    o = slurp(dir, "out.txt");
    SC_CHECK_MSG(o && !strncmp(o, "seamcook ", 9), "stdout: %s", o ? o : "");
    free(o);
    /* every command's --help prints its usage on stdout and succeeds, whatever else is on the line */
    const char *commands[] = {"run", "watch", "test", "cache", "nodes", "graph", "version"};
    for (int i = 0; i < 7; i++) {
        char *args = sc_strprintf("%s --help", commands[i]), *want = sc_strprintf("usage: seamcook %s", commands[i]);
        SC_CHECK_INT(cook(dir, args), 0);
        o = slurp(dir, "out.txt");
        SC_CHECK_MSG(o && strstr(o, want), "%s: stdout: %s", args, o ? o : "");
        free(o), free(args), free(want);
    }
    SC_CHECK_INT(cook(dir, "run graph.lua --set a=1 -h"), 0);
    o = slurp(dir, "out.txt");
    SC_CHECK_MSG(o && strstr(o, "usage: seamcook run") && strstr(o, "--json"), "stdout: %s", o ? o : "");
    free(o);
    SC_CHECK_INT(cook(dir, "help cache"), 0);
    o = slurp(dir, "out.txt");
    SC_CHECK_MSG(o && strstr(o, "usage: seamcook cache"), "stdout: %s", o ? o : "");
    free(o);
    SC_CHECK_INT(cook(dir, "--help"), 0);
    o = slurp(dir, "out.txt");
    SC_CHECK_MSG(o && strstr(o, "seamcook watch") && strstr(o, "seamcook version"), "stdout: %s", o ? o : "");
    free(o), free(dir);
}

/* A dry run checks parameters exactly as the cook does: a list decimate
 * refuses fails both, as a usage error naming the --set; so does a list with
 * an element that is not a number (it used to shrink to one level). */
SC_TEST(dry_run_checks_parameters_like_the_cook) {
    char *dir = sc_test_tempdir("cli");
    char *g = data("lods_save.lua");
    const char *modes[] = {"-n", ""};
    for (int m = 0; m < 2; m++) {
        char *a = sc_strprintf("run '%s' --cache cache --out out %s --set ratios=0.1,0.5", g, modes[m]);
        SC_CHECK_INT(cook(dir, a), 2);
        char *err = slurp(dir, "err.txt");
        SC_CHECK_MSG(err && strstr(err, "lods_save.lua:3: --set ratios=0.1,0.5: lods:ratio: targets must not increase"),
                     "%s: stderr: %s", modes[m], err ? err : "");
        free(err), free(a);
        a = sc_strprintf("run '%s' --cache cache --out out %s --set ratios=0.5,abc", g, modes[m]);
        SC_CHECK_INT(cook(dir, a), 2);
        err = slurp(dir, "err.txt");
        SC_CHECK_MSG(err && strstr(err, "--set ratios=0.5,abc: element 2 ('abc') is not a number"), "stderr: %s",
                     err ? err : "");
        free(err), free(a);
        a = sc_strprintf("run '%s' --cache cache --out out %s --set lods.ratio=0.5,0.6", g, modes[m]);
        SC_CHECK_INT(cook(dir, a), 2);
        err = slurp(dir, "err.txt");
        SC_CHECK_MSG(err && strstr(err, "--set lods.ratio=0.5,0.6: lods:ratio: targets must not increase"),
                     "stderr: %s", err ? err : "");
        free(err), free(a);
    }
    /* a text a node would refuse when it cooks: a render mode it does not know */
    char *r = data("golden_small.lua");
    char *a = sc_strprintf("run '%s' --cache cache --out out -n --set check.modes=textured,wireframe", r);
    SC_CHECK_INT(cook(dir, a), 2);
    char *err = slurp(dir, "err.txt");
    SC_CHECK_MSG(err && strstr(err, "check:modes: unknown mode 'wireframe'"), "stderr: %s", err ? err : "");
    char *out = sc_path_join(dir, "out");
    SC_CHECK(!exists(out));
    free(out), free(err), free(a), free(r), free(g), free(dir);
}

/* The key of the node named `name` in dir/out/report.json ("" if none). */
static const char *node_key(const char *dir, const char *name, char *buf, size_t n) {
    snprintf(buf, n, "%s", "");
    char *out = sc_path_join(dir, "out");
    char *json = slurp(out, "report.json");
    cJSON *root = json ? cJSON_Parse(json) : NULL;
    const cJSON *node;
    cJSON_ArrayForEach(node, cJSON_GetObjectItemCaseSensitive(root, "nodes")) {
        const cJSON *key = cJSON_GetObjectItemCaseSensitive(node, "key");
        if (!strcmp(cJSON_GetObjectItemCaseSensitive(node, "name")->valuestring, name) && cJSON_IsString(key))
            snprintf(buf, n, "%s", key->valuestring);
    }
    cJSON_Delete(root);
    free(json), free(out);
    return buf;
}

/* The cache keeps the outputs a graph reads: erase_seams's float atlas,
 * which the first graph does not read, is not stored. The same graph again is
 * all cached (what it reads is there); a graph that reads the float atlas
 * cooks erase_seams again, saying why, to the same digests (so the first
 * save stays cached), and stores it; then everything is cached. */
SC_TEST(the_cache_keeps_what_the_graph_reads) {
    char *dir = sc_test_tempdir("cli");
    char *g = data("erase_reads.lua");
    char *out = sc_path_join(dir, "out");
    char *args = sc_strprintf("run '%s' --cache cache --out out", g);
    SC_CHECK_INT(cook(dir, args), 0);
    SC_CHECK_INT(report_counts(out).ran, 3);
    SC_CHECK_INT(cook(dir, args), 0);
    SC_CHECK_INT(report_counts(out).cached, 3);
    free(args);
    args = sc_strprintf("run '%s' --cache cache --out out --set float=1 --explain", g);
    SC_CHECK_INT(cook(dir, args), 0);
    char st[32];
    SC_CHECK_STR(node_status(out, "asset", st, sizeof st), "cached");
    SC_CHECK_STR(node_status(out, "erased", st, sizeof st), "ran");
    SC_CHECK_STR(node_status(out, "save", st, sizeof st), "cached");
    SC_CHECK_STR(node_status(out, "save_float", st, sizeof st), "ran");
    char *err = slurp(dir, "err.txt");
    SC_CHECK_MSG(err && strstr(err, "erased") && strstr(err, "an output this graph reads is not in the cache"),
                 "stderr: %s", err ? err : "");
    free(err);
    SC_CHECK_INT(cook(dir, args), 0);
    SC_CHECK_INT(report_counts(out).ran, 0);
    free(args), free(out), free(g), free(dir);
}

/* --set node.param=value is a parameter value like any: the same value
 * through param() or by the node's name makes the same key. */
SC_TEST(node_settings_enter_the_key) {
    char *dir = sc_test_tempdir("cli");
    char *g = data("proc_save.lua");
    char plain[80], by_param[80], by_node[80];
    char *a = sc_strprintf("run '%s' --cache cache --out out -q", g);
    SC_CHECK_INT(cook(dir, a), 0);
    node_key(dir, "asset", plain, sizeof plain);
    free(a);
    a = sc_strprintf("run '%s' --cache cache --out out -q --set resolution=5", g);
    SC_CHECK_INT(cook(dir, a), 0);
    node_key(dir, "asset", by_param, sizeof by_param);
    free(a);
    a = sc_strprintf("run '%s' --cache cache --out out --set asset.resolution=5 --explain", g);
    SC_CHECK_INT(cook(dir, a), 0);
    node_key(dir, "asset", by_node, sizeof by_node);
    SC_CHECK_MSG(*plain && strcmp(plain, by_param) != 0, "keys %s %s", plain, by_param);
    SC_CHECK_STR(by_node, by_param);
    char st[32];
    char *out = sc_path_join(dir, "out");
    SC_CHECK_STR(node_status(out, "asset", st, sizeof st), "cached");
    free(a);
    /* over what the graph gives: the node's name wins */
    a = sc_strprintf("run '%s' --cache cache --out out --set resolution=7 --set asset.resolution=5 --explain", g);
    SC_CHECK_INT(cook(dir, a), 0);
    SC_CHECK_STR(node_status(out, "asset", st, sizeof st), "cached");
    free(a);
    /* unknown node or parameter: a usage error naming it */
    a = sc_strprintf("run '%s' --cache cache --out out --set aset.resolution=5", g);
    SC_CHECK_INT(cook(dir, a), 2);
    char *err = slurp(dir, "err.txt");
    SC_CHECK_MSG(err && strstr(err, "no node named 'aset'; did you mean 'asset'?"), "stderr: %s", err ? err : "");
    free(err), free(a);
    a = sc_strprintf("run '%s' --cache cache --out out --set save.bogus=5", g);
    SC_CHECK_INT(cook(dir, a), 2);
    err = slurp(dir, "err.txt");
    SC_CHECK_MSG(err && strstr(err, "node 'save' (save) has no parameter 'bogus'"), "stderr: %s", err ? err : "");
    free(err), free(a), free(out), free(g), free(dir);
}

/* A number in a JSON object, or -1. */
static int json_int(const cJSON *o, const char *name) {
    const cJSON *v = cJSON_GetObjectItemCaseSensitive(o, name);
    return cJSON_IsNumber(v) ? v->valueint : -1;
}

/* --json: the run's summary on stdout and nothing else, also for a failure. */
SC_TEST(json_summary) {
    char *dir = sc_test_tempdir("cli");
    char *g = data("proc_save.lua");
    char *a = sc_strprintf("run '%s' --cache cache --out out --json", g);
    SC_CHECK_INT(cook(dir, a), 0);
    char *o = slurp(dir, "out.txt");
    cJSON *root = o ? cJSON_Parse(o) : NULL;
    SC_CHECK_MSG(root != NULL, "stdout is not JSON: %s", o ? o : "");
    SC_CHECK_INT(json_int(root, "exit_status"), 0);
    SC_CHECK_INT(json_int(cJSON_GetObjectItemCaseSensitive(root, "totals"), "ran"), 2);
    const cJSON *node;
    int n = 0;
    cJSON_ArrayForEach(node, cJSON_GetObjectItemCaseSensitive(root, "nodes")) {
        const char *fields[] = {"name", "type", "status", "seconds", "key", "metrics"};
        for (int f = 0; f < 6; f++)
            SC_CHECK_MSG(cJSON_GetObjectItemCaseSensitive(node, fields[f]), "node %d has no %s", n, fields[f]);
        n++;
    }
    SC_CHECK_INT(n, 2);
    cJSON_Delete(root);
    free(o), free(a), free(g);
    /* a node that fails: status 1, and the message */
    g = data("fails.lua");
    a = sc_strprintf("run '%s' --cache cache --out out --json", g);
    SC_CHECK_INT(cook(dir, a), 1);
    o = slurp(dir, "out.txt");
    root = o ? cJSON_Parse(o) : NULL;
    SC_CHECK_MSG(root != NULL, "stdout is not JSON: %s", o ? o : "");
    SC_CHECK_INT(json_int(root, "exit_status"), 1);
    const cJSON *error = cJSON_GetObjectItemCaseSensitive(root, "error");
    SC_CHECK(cJSON_IsString(error) && strstr(error->valuestring, "missing.obj"));
    cJSON_Delete(root);
    free(o), free(a);
    /* a usage error: status 2, no nodes */
    a = sc_strprintf("run '%s' --cache cache --out out --json --set nothing=1", g);
    SC_CHECK_INT(cook(dir, a), 2);
    o = slurp(dir, "out.txt");
    root = o ? cJSON_Parse(o) : NULL;
    SC_CHECK_MSG(json_int(root, "exit_status") == 2, "stdout: %s", o ? o : "");
    cJSON_Delete(root);
    free(o), free(a), free(g), free(dir);
}

/* test --junit FILE: a testcase per graph test file, failures with their message. */
SC_TEST(junit_report) {
    char *dir = sc_test_tempdir("cli");
    char *g = data("proc_save.lua");
    SC_CHECK_INT(sc_test_system("cd '%s' && cp '%s' pass.lua && cp '%s' fail.lua && "
                                "echo 'expect(asset, \"faces\", \">\", 0)' >> pass.lua && "
                                "echo 'expect(asset, \"faces\", \"<\", 3)' >> fail.lua", dir, g, g), 0);
    SC_CHECK_INT(cook(dir, "test pass.lua fail.lua --cache cache --out out --junit results.xml"), 1);
    char *xml = slurp(dir, "results.xml");
    SC_CHECK_MSG(xml && strstr(xml, "<?xml version=\"1.0\"") && strstr(xml, "tests=\"2\" failures=\"1\"") &&
                     strstr(xml, "<testcase classname=\"seamcook\" name=\"pass.lua\" time=\"") &&
                     strstr(xml, "name=\"fail.lua\"") && strstr(xml, "<failure message=\"") &&
                     strstr(xml, "faces") && strstr(xml, "&lt; 3"),
                 "results.xml: %s", xml ? xml : "(none)");
    const char *pass = xml ? strstr(xml, "name=\"pass.lua\"") : NULL;
    const char *end = pass ? strchr(pass, '>') : NULL;
    SC_CHECK_MSG(end && end[-1] == '/', "pass.lua must be a testcase with no failure: %s", xml ? xml : "");
    free(xml), free(g), free(dir);
}

/* --out keeps to what the graph writes: a file a run no longer writes goes at
 * that run; what the user put there, or changed, stays. */
SC_TEST(out_keeps_to_what_the_graph_writes) {
    char *dir = sc_test_tempdir("cli");
    char *g = data("lods_save.lua");
    char *three = sc_strprintf("run '%s' --cache cache --out out -q", g);
    char *two = sc_strprintf("run '%s' --cache cache --out out -q --set ratios=0.5,0.25", g);
    SC_CHECK_INT(cook(dir, three), 0);
    char *lod2 = sc_strprintf("%s/out/asset_lod2.obj", dir), *lod1 = sc_strprintf("%s/out/asset_lod1.obj", dir);
    SC_CHECK(exists(lod2));
    SC_CHECK_INT(sc_test_system("cd '%s' && echo mine > out/notes.txt && mkdir -p out/sub && echo mine > out/sub/x", dir), 0);
    SC_CHECK_INT(cook(dir, two), 0);
    SC_CHECK(!exists(lod2));
    SC_CHECK(exists(lod1));
    char *notes = sc_strprintf("%s/out/notes.txt", dir), *sub = sc_strprintf("%s/out/sub/x", dir);
    SC_CHECK(exists(notes) && exists(sub));
    /* a file changed since it was written is the user's now */
    SC_CHECK_INT(cook(dir, three), 0);
    SC_CHECK_INT(sc_test_system("cd '%s' && echo '# edited' >> out/asset_lod2.obj", dir), 0);
    SC_CHECK_INT(cook(dir, two), 0);
    SC_CHECK(exists(lod2));
    free(notes), free(sub), free(lod1), free(lod2), free(two), free(three), free(g), free(dir);
}

/* --explain compares a node with its last cook on the same asset: editing
 * the first of two assets cooked in turn is a file change, not a new path. */
SC_TEST(explain_follows_the_asset) {
    char *dir = sc_test_tempdir("cli");
    write_png(dir, "64");
    write_obj_asset(dir, "two assets");
    SC_CHECK_INT(sc_test_system("cd '%s' && cp tet.obj a.obj && sed 's/v 1 0 0/v 2 0 0/' tet.obj > b.obj", dir), 0);
    char *g = data("obj_save.lua");
    char *a = sc_strprintf("run '%s' --cache cache --out out -q --set mesh=a.obj", g);
    char *b = sc_strprintf("run '%s' --cache cache --out out -q --set mesh=b.obj", g);
    SC_CHECK_INT(cook(dir, a), 0);
    SC_CHECK_INT(cook(dir, b), 0);
    SC_CHECK_INT(sc_test_system("cd '%s' && sed -i 's/v 0 0 1/v 0 0 3/' a.obj", dir), 0);
    char *again = sc_strprintf("run '%s' --cache cache --out out --explain --set mesh=a.obj", g);
    SC_CHECK_INT(cook(dir, again), 0);
    char *err = slurp(dir, "err.txt");
    SC_CHECK_MSG(err && strstr(err, "why load: file") && strstr(err, "a.obj changed") && !strstr(err, "parameter path"),
                 "explain said: %s", err ? err : "(nothing)");
    free(err), free(again), free(a), free(b), free(g), free(dir);
}

/* The cache trims itself after a run, least recently used first, past
 * --cache-max-size or $SEAMCOOK_CACHE_MAX_SIZE. */
SC_TEST(cache_trims_itself) {
    char *dir = sc_test_tempdir("cli");
    char *g = data("proc_save.lua");
    char *a = sc_strprintf("run '%s' --cache cache --out out --cache-max-size 1K", g);
    SC_CHECK_INT(cook(dir, a), 0);
    char *err = slurp(dir, "err.txt");
    SC_CHECK_MSG(err && strstr(err, "cache trimmed"), "stderr: %s", err ? err : "");
    free(err);
    SC_CHECK_INT(cook(dir, "cache stats --cache cache"), 0);
    char *o = slurp(dir, "out.txt");
    SC_CHECK_MSG(o && strstr(o, "(0.0 MiB)"), "stats: %s", o ? o : "");
    free(o);
    /* what was trimmed cooks again */
    SC_CHECK_INT(cook(dir, a), 0);
    char *out = sc_path_join(dir, "out");
    SC_CHECK_INT(report_counts(out).ran, 2);
    free(a);
    /* the environment variable; the default keeps a small cache whole */
    SC_CHECK_INT(sc_test_system("cd '%s' && SEAMCOOK_CACHE_MAX_SIZE=1K '%s' run '%s' --cache env --out out >out.txt 2>err.txt",
                                dir, bin(), g), 0);
    err = slurp(dir, "err.txt");
    SC_CHECK_MSG(err && strstr(err, "cache trimmed"), "stderr: %s", err ? err : "");
    free(err);
    a = sc_strprintf("run '%s' --cache big --out out", g);
    SC_CHECK_INT(cook(dir, a), 0);
    SC_CHECK_INT(cook(dir, a), 0);
    SC_CHECK_INT(report_counts(out).cached, 2);
    free(out), free(a), free(g), free(dir);
}

/* cmake --install into a prefix: the installed command runs a graph that
 * reads a JPEG (which only the image module decodes; PNGs are read in C)
 * with the module installed beside it (not the build folder's), and writes
 * a PNG; the graphs, the Lua reference and the manual are there. */
SC_TEST(install_into_a_prefix) {
    char *dir = sc_test_tempdir("cli");
    char *build = sc_path_dirname(bin());
    SC_CHECK_INT(sc_test_system("cmake --install '%s' --prefix '%s/prefix' >'%s/install.txt' 2>&1", build, dir, dir), 0);
    char *proc = data("proc_save.lua");
    SC_CHECK_INT(sc_test_system("cd '%s' && '%s' run '%s' --cache jpgcache --out jpgout --set texture_size=64 "
                                "--set save.format=jpg -q && cp jpgout/asset_default_color.jpg tet.jpg",
                                dir, bin(), proc), 0);
    free(proc);
    write_obj_asset(dir, "installed");
    char *mtl = sc_strprintf("%s/tet.mtl", dir);
    sc_error werr;
    const char *jpg_mtl = "newmtl skin\nmap_Kd tet.jpg\n";
    SC_CHECK(sc_write_file_atomic(mtl, jpg_mtl, strlen(jpg_mtl), &werr) == SC_OK);
    free(mtl);
    char *g = data("obj_save.lua");
    SC_CHECK_INT(sc_test_system("cd '%s' && LD_DEBUG=files prefix/bin/seamcook run '%s' --cache cache --out out "
                                "--set mesh=tet.obj -q 2>ld.txt", dir, g), 0);
    SC_CHECK_INT(sc_test_system("cd '%s' && grep 'libseamcook_imageio.so .*dynamically loaded' ld.txt | "
                                "grep -q \"file=$(pwd -P)/prefix/\"", dir), 0);
    char *png = sc_strprintf("%s/out/copy_skin_color.png", dir);
    SC_CHECK_MSG(exists(png), "no %s", png);
    const char *installed[] = {"share/seamcook/graphs/lod_chain.lua", "share/seamcook/lua/seamcook.lua",
                               "share/man/man1/seamcook.1"};
    for (int i = 0; i < 3; i++) {
        char *p = sc_strprintf("%s/prefix/%s", dir, installed[i]);
        SC_CHECK_MSG(exists(p), "not installed: %s", p);
        free(p);
    }
    SC_CHECK_INT(sc_test_system("cd '%s' && prefix/bin/seamcook --version | grep -q '^seamcook '", dir), 0);
    free(png), free(g), free(build), free(dir);
}

SC_TEST(failed_node_leaves_no_entry_and_no_output) {
    char *dir = sc_test_tempdir("cli");
    char *g = data("fails.lua");
    char *a = sc_strprintf("run '%s' --cache cache --out out -j 1", g);
    SC_CHECK_INT(cook(dir, a), 1);
    char *err = slurp(dir, "err.txt");
    SC_CHECK_MSG(err && strstr(err, "fails.lua:4") && strstr(err, "missing.obj"), "stderr: %s", err ? err : "(nothing)");
    free(err);
    char *out = sc_path_join(dir, "out");
    char st[32];
    SC_CHECK_STR(node_status(out, "load", st, sizeof st), "failed");
    SC_CHECK_STR(node_status(out, "save_bad", st, sizeof st), "skipped");
    char *bad = sc_strprintf("%s/out/bad.obj", dir);
    SC_CHECK(!exists(bad));
    /* the failure was not cached: the same run fails again the same way */
    SC_CHECK_INT(cook(dir, a), 1);
    SC_CHECK_STR(node_status(out, "load", st, sizeof st), "failed");
    free(bad), free(out), free(a), free(g), free(dir);
}

SC_TEST(cache_commands) {
    char *dir = sc_test_tempdir("cli");
    char *g = data("proc_save.lua");
    char *a = sc_strprintf("run '%s' --cache cache --out out -q", g);
    SC_CHECK_INT(cook(dir, a), 0);
    SC_CHECK_INT(cook(dir, "cache stats --cache cache"), 0);
    char *o = slurp(dir, "out.txt");
    SC_CHECK_MSG(o && strstr(o, "actions 2"), "stats said: %s", o ? o : "(nothing)");
    free(o);
    SC_CHECK_INT(cook(dir, "cache verify --cache cache"), 0);
    SC_CHECK_INT(cook(dir, "cache gc --cache cache"), 2);
    SC_CHECK_INT(cook(dir, "cache gc --max-size 0 --cache cache"), 0);
    SC_CHECK_INT(cook(dir, "cache stats --cache cache"), 0);
    o = slurp(dir, "out.txt");
    SC_CHECK_MSG(o && strstr(o, "blobs 0") && strstr(o, "actions 0"), "stats after gc: %s", o ? o : "(nothing)");
    free(o);
    /* after gc everything cooks again */
    SC_CHECK_INT(cook(dir, a), 0);
    char *out = sc_path_join(dir, "out");
    SC_CHECK_INT(report_counts(out).ran, 2);
    free(out), free(a), free(g), free(dir);
}

SC_TEST(watch_recooks_on_rename_save) {
    char *dir = sc_test_tempdir("cli");
    write_png(dir, "64");
    write_obj_asset(dir, "v1");
    char *g = data("obj_save.lua");
    pid_t pid = fork();
    if (pid == 0) {
        if (chdir(dir) != 0) _exit(127);
        if (!freopen("watch.txt", "w", stderr)) _exit(127);
        execl(bin(), bin(), "watch", g, "--cache", "cache", "--out", "out", "--max-runs", "2", "--set",
              "mesh=tet.obj", (char *)NULL);
        _exit(127);
    }
    /* wait for the first cook, then save the OBJ the way editors do: new file + rename */
    char *report = sc_strprintf("%s/out/report.json", dir);
    for (int i = 0; i < 200 && !exists(report); i++) usleep(50000);
    usleep(300000);
    SC_CHECK_INT(sc_test_system("cd '%s' && sed 's/v 1 0 0/v 2 0 0/' tet.obj > tet.obj.new && mv tet.obj.new tet.obj", dir), 0);
    int status = -1;
    for (int i = 0; i < 200; i++) {
        if (waitpid(pid, &status, WNOHANG) == pid) break;
        usleep(50000);
    }
    if (waitpid(pid, &status, WNOHANG) == 0) {
        kill(pid, SIGKILL);
        waitpid(pid, &status, 0);
        SC_CHECK_MSG(0, "watch did not re-cook after the file was replaced");
    }
    SC_CHECK(WIFEXITED(status) && WEXITSTATUS(status) == 0);
    char *copy = slurp(dir, "out/copy.obj");
    SC_CHECK_MSG(copy && strstr(copy, "v 2 0 0"), "re-cooked output: %.200s", copy ? copy : "(none)");
    free(copy), free(report), free(g), free(dir);
}

/* Start `seamcook watch` on obj_save.lua in dir; stderr to dir/watch.txt. */
static pid_t start_watch(const char *dir, const char *graph) {
    pid_t pid = fork();
    if (pid == 0) {
        if (chdir(dir) != 0) _exit(127);
        if (!freopen("watch.txt", "w", stderr)) _exit(127);
        execl(bin(), bin(), "watch", graph, "--cache", "cache", "--out", "out", "--set", "mesh=tet.obj",
              (char *)NULL);
        _exit(127);
    }
    return pid;
}

/* Wait up to `seconds` for dir/out/copy.obj to hold `text`; then stop the watch. */
static bool wait_for_copy(const char *dir, pid_t pid, const char *text, double seconds) {
    bool found = false;
    for (double t = 0; t < seconds && !found; t += 0.05) {
        char *copy = slurp(dir, "out/copy.obj");
        found = copy && strstr(copy, text);
        free(copy);
        if (!found) usleep(50000);
    }
    kill(pid, SIGINT);
    int status;
    for (int i = 0; i < 100 && waitpid(pid, &status, WNOHANG) == 0; i++) usleep(50000);
    if (waitpid(pid, &status, WNOHANG) == 0) {
        kill(pid, SIGKILL);
        waitpid(pid, &status, 0);
    }
    return found;
}

/* A change that lands while a cook runs is cooked after it (it used to be
 * lost: the watches were down during the cook). */
SC_TEST(watch_cooks_a_change_made_during_a_cook) {
    char *dir = sc_test_tempdir("cli");
    write_png(dir, "2048");   /* the cook then takes a while: the PNG is read and written again */
    write_obj_asset(dir, "v1");
    char *g = data("obj_save.lua");
    pid_t pid = start_watch(dir, g);
    char *report = sc_strprintf("%s/out/report.json", dir);
    for (int i = 0; i < 400 && !exists(report); i++) usleep(50000);
    /* v2, then v3 while v2's cook runs (its debounce is 150 ms) */
    SC_CHECK_INT(sc_test_system("cd '%s' && sed 's/v 1 0 0/v 2 0 0/' tet.obj > v2 && sed 's/v 1 0 0/v 3 0 0/' tet.obj > v3 && "
                                "cp v2 tet.obj && sleep 0.3 && cp v3 tet.obj", dir), 0);
    bool v3 = wait_for_copy(dir, pid, "v 3 0 0", 30);
    char *log = slurp(dir, "watch.txt");
    SC_CHECK_MSG(v3, "the output never showed v3; watch said:\n%s", log ? log : "");
    free(log), free(report), free(g), free(dir);
}

/* A node that failed because a file was missing waits for that file. */
SC_TEST(watch_recooks_when_a_missing_file_appears) {
    char *dir = sc_test_tempdir("cli");
    write_obj_asset(dir, "v1");   /* names tet.png, which is not there yet */
    char *g = data("obj_save.lua");
    pid_t pid = start_watch(dir, g);
    char *log = NULL;
    for (int i = 0; i < 400; i++) {   /* the first cook fails */
        free(log);
        log = slurp(dir, "watch.txt");
        if (log && strstr(log, "watching")) break;
        usleep(50000);
    }
    SC_CHECK_MSG(log && strstr(log, "tet.png"), "watch said:\n%s", log ? log : "");
    free(log);
    char *copy = slurp(dir, "out/copy.obj");
    SC_CHECK(copy == NULL);
    free(copy);
    write_png(dir, "64");
    bool cooked = wait_for_copy(dir, pid, "v 1 0 0", 30);
    log = slurp(dir, "watch.txt");
    SC_CHECK_MSG(cooked, "restoring the texture cooked nothing; watch said:\n%s", log ? log : "");
    free(log), free(g), free(dir);
}

/* Two users share one cache: the folder is setgid to a group, both use
 * umask 002, and the second user (nobody, of that group) cooks, verifies and
 * collects garbage in what the first made; the files they make follow the
 * umask. Needs root (to be nobody); skipped where nobody cannot run the
 * binary (a checkout under a private home). */
SC_TEST(two_users_share_a_cache) {
    if (getuid() != 0 || sc_test_system("setpriv --reuid=65534 --regid=65534 --clear-groups test -x '%s'", bin()) != 0) {
        printf("  not root, or nobody cannot run %s: skipped\n", bin());
        return;
    }
    char *dir = sc_test_tempdir("cli");
    char *g = data("proc_save.lua");
    SC_CHECK_INT(sc_test_system("cd '%s' && chmod 0777 . && mkdir cache && chgrp 65534 cache && chmod 2775 cache", dir), 0);
    SC_CHECK_INT(sc_test_system("cd '%s' && umask 002 && '%s' run '%s' --cache cache --out out_root -q 2>err_root.txt",
                                dir, bin(), g), 0);
    SC_CHECK_INT(sc_test_system("cd '%s' && setpriv --reuid=65534 --regid=65534 --clear-groups sh -c \"umask 002 && "
                                "'%s' run '%s' --cache cache --out out_nobody --set resolution=5 -q && "
                                "'%s' cache verify --cache cache && '%s' cache gc --max-size 1 --cache cache\" "
                                ">out_nobody.txt 2>err_nobody.txt",
                                dir, bin(), g, bin(), bin()), 0);
    char *err = slurp(dir, "err_nobody.txt");
    SC_CHECK_MSG(err && !strstr(err, "readonly") && !strstr(err, "denied"), "nobody: %s", err ? err : "");
    free(err);
    /* what nobody left is usable by root, and nothing in the cache is private to one user */
    SC_CHECK_INT(sc_test_system("cd '%s' && '%s' cache verify --cache cache >verify.txt 2>&1", dir, bin()), 0);
    SC_CHECK_INT(sc_test_system("cd '%s' && test -z \"$(find cache -newer err_root.txt \\( -type f ! -perm -g+w \\) -o "
                                "\\( -type d ! -perm -g+ws \\) | grep -v reserve)\"", dir), 0);
    free(g), free(dir);
}

SC_TEST(golden_images_and_metrics) {
    char *dir = sc_test_tempdir("cli");
    char *src = data("golden_small.lua");
    /* a private copy of the graph, so its goldens are made in the temporary folder */
    SC_CHECK_INT(sc_test_system("cp '%s' '%s/g.lua'", src, dir), 0);
    SC_CHECK_INT(cook(dir, "test g.lua --cache cache --out out"), 1);   /* no goldens yet */
    char *err = slurp(dir, "err.txt");
    SC_CHECK_MSG(err && strstr(err, "--update-goldens"), "stderr: %s", err ? err : "(nothing)");
    free(err);
    SC_CHECK_INT(cook(dir, "test g.lua --cache cache --out out --update-goldens"), 0);
    SC_CHECK_INT(cook(dir, "test g.lua --cache cache --out out"), 0);
    char *o = slurp(dir, "out.txt");
    SC_CHECK_MSG(o && strstr(o, "1 passed, 0 failed"), "stdout: %s", o ? o : "(nothing)");
    free(o);
    /* another tint: the picture and a metric no longer match their goldens */
    SC_CHECK_INT(cook(dir, "test g.lua --cache cache --out out --set tint=0.5"), 1);
    err = slurp(dir, "err.txt");
    SC_CHECK_MSG(err && strstr(err, "golden image failed: render/lod0_textured_posx.png") && strstr(err, "diff: "),
                 "stderr: %s", err ? err : "(nothing)");
    free(err);
    char *diff = sc_strprintf("%s/out/g/diff/check/render_lod0_textured_posx.png", dir);
    SC_CHECK_MSG(exists(diff), "no diff picture at %s", diff);
    free(diff), free(src), free(dir);
}

/* The number of lines of text that contain what. */
static int lines_with(const char *text, const char *what) {
    int n = 0;
    for (const char *line = text; line && *line;) {
        const char *end = strchr(line, '\n');
        size_t len = end ? (size_t)(end - line) : strlen(line);
        char *copy = sc_strndup(line, len);
        n += copy && strstr(copy, what) != NULL;
        free(copy);
        line = end ? end + 1 : NULL;
    }
    return n;
}

SC_TEST(shortfalls_warn_and_strict_fails) {
    char *dir = sc_test_tempdir("cli");
    write_obj_asset(dir, "an MTL naming a normal map that is not there");
    write_png(dir, "32");
    char *mtl = sc_strprintf("%s/tet.mtl", dir);
    const char *m = "newmtl skin\nmap_Kd tet.png\nnorm tet_normal.png\n";
    sc_error err;
    SC_CHECK_INT(sc_write_file_atomic(mtl, m, strlen(m), &err), SC_OK);
    char *g = data("obj_save.lua");

    /* the job goes on without the optional map, says so once, and exits 0 */
    char *a = sc_strprintf("run '%s' --set mesh=tet.obj --cache cache --out out -q", g);
    SC_CHECK_INT(cook(dir, a), 0);
    char *text = slurp(dir, "err.txt");
    SC_CHECK_MSG(text && lines_with(text, "warning:") == 1 &&
                     lines_with(text, "obj_save.lua:2: load: ") == 1 &&
                     lines_with(text, "normal texture left out") == 1 && lines_with(text, "tet_normal.png") == 1,
                 "stderr: %s", text ? text : "(nothing)");
    free(text);
    char *copy = sc_strprintf("%s/out/copy.obj", dir);
    SC_CHECK_MSG(exists(copy), "the saved copy is missing");
    char *json = slurp(dir, "out/report.json");
    SC_CHECK_MSG(json && strstr(json, "\"warnings\"") && strstr(json, "normal texture left out"), "report.json");
    free(json);

    /* --strict: exit 1, also when the result comes from the cache */
    char *strict = sc_strprintf("%s --strict", a);
    for (int pass = 0; pass < 2; pass++) {
        SC_CHECK_INT(cook(dir, strict), 1);
        text = slurp(dir, "err.txt");
        SC_CHECK_MSG(text && lines_with(text, "normal texture left out") == 1 &&
                         strstr(text, "1 warning, and --strict"),
                     "pass %d stderr: %s", pass, text ? text : "(nothing)");
        free(text);
    }
    char *out = sc_path_join(dir, "out");
    SC_CHECK_INT(report_counts(out).cached, 2);
    free(out);

    /* the map appears: no warning, --strict passes */
    SC_CHECK_INT(sc_test_system("cd '%s' && cp tet.png tet_normal.png", dir), 0);
    SC_CHECK_INT(cook(dir, strict), 0);
    text = slurp(dir, "err.txt");
    SC_CHECK_MSG(text && lines_with(text, "warning:") == 0, "stderr: %s", text);
    free(text);

    /* a level that stops short names its target and what blocked it */
    char *lods = data("lods_save.lua");
    char *b = sc_strprintf("run '%s' --cache cache --out lods -q", lods);
    SC_CHECK_INT(cook(dir, b), 0);
    text = slurp(dir, "err.txt");
    SC_CHECK_MSG(text && lines_with(text, "warning:") == 0, "unbounded levels warned: %s", text);
    free(text);
    char *c = sc_strprintf("%s --set lods.max_error=1e-6 --strict", b);
    SC_CHECK_INT(cook(dir, c), 1);
    text = slurp(dir, "err.txt");
    SC_CHECK_MSG(text && lines_with(text, "lods: lod0: ") == 1 && lines_with(text, "faces for a target of") == 3 &&
                     lines_with(text, "blocked by ") == 3 && lines_with(text, " max_error") == 3,
                 "stderr: %s", text ? text : "(nothing)");
    free(text);

    /* an OBJ without its MTL cooks untextured, and says so */
    SC_CHECK_INT(sc_test_system("cd '%s' && grep -v mtllib tet.obj > bare.obj", dir), 0);
    char *d = sc_strprintf("run '%s' --set mesh=bare.obj --cache cache --out bare -q", g);
    SC_CHECK_INT(cook(dir, d), 0);
    text = slurp(dir, "err.txt");
    SC_CHECK_MSG(text && lines_with(text, "warning:") == 1 && lines_with(text, "no texture") == 1, "stderr: %s", text);
    free(text);
    free(mtl), free(g), free(a), free(copy), free(strict), free(lods), free(b), free(c), free(d), free(dir);
}

/* Open dir/report.html in headless Chromium at 1280 x 800 with a script
 * that, once everything loaded, puts into the title how many images there
 * are, how many decode and lie on the first screen, how many are broken, and
 * how many plot lines the page has (the script has no '&': sed would take
 * it for the matched text); returns the title (caller frees). Also
 * writes the page's screenshot, dir/shot_<tag>.png. */
static char *page_census(const char *dir, const char *tag) {
    SC_CHECK_INT(sc_test_system(
        "cd '%s' && cp report.html census_%s.html && sed -i 's#</body>#<script>"
        "addEventListener(\"load\",()=>{const im=[...document.images];"
        "const ok=im.filter(i=>i.complete).filter(i=>i.naturalWidth>0);"
        "const first=ok.filter(i=>i.getBoundingClientRect().top<innerHeight).filter(i=>i.height>40);"
        "document.title=\"images:\"+im.length+\" first:\"+first.length+\" broken:\"+(im.length-ok.length)+"
        "\" plots:\"+document.querySelectorAll(\"svg polyline\").length+\" end\";});</script></body>#' census_%s.html && "
        "timeout 120 chromium --headless --no-sandbox --disable-gpu --disable-quic --no-first-run "
        "--disable-background-networking --disable-component-update --disable-sync --user-data-dir=$PWD/chrome_%s "
        "--window-size=1280,800 --virtual-time-budget=5000 --dump-dom file://$PWD/census_%s.html > census_%s.dom 2>/dev/null && "
        "timeout 120 chromium --headless --no-sandbox --disable-gpu --disable-quic --no-first-run "
        "--disable-background-networking --disable-component-update --disable-sync --user-data-dir=$PWD/chrome_%s "
        "--window-size=1280,800 --virtual-time-budget=5000 --screenshot=$PWD/shot_%s.png file://$PWD/report.html "
        ">/dev/null 2>&1",
        dir, tag, tag, tag, tag, tag, tag, tag), 0);
    char *name = sc_strprintf("census_%s.dom", tag);
    char *dom = slurp(dir, name);
    free(name);
    char *title = dom && strstr(dom, "<title>images:") ? sc_strndup(strstr(dom, "<title>") + 7, 80) : NULL;
    free(dom);
    return title;
}

SC_TEST(report_html_shows_pictures_first_in_chromium) {
    if (access("/usr/bin/chromium", X_OK) != 0) {
        printf("  chromium not installed: skipped\n");
        return;
    }
    char *dir = sc_test_tempdir("cli");
    char *g = data("report_lods.lua");
    char *a = sc_strprintf("run '%s' --cache cache --out out -q", g);
    SC_CHECK_INT(cook(dir, a), 0);
    char *out = sc_strprintf("%s/out", dir);
    char *title = page_census(out, "lods");
    /* the reference and both levels on the first screen, nothing broken, the faces-error plot */
    int images = -1, first = -1, broken = -1, plots = -1;
    SC_CHECK_MSG(title && sscanf(title, "images:%d first:%d broken:%d plots:%d", &images, &first, &broken, &plots) == 4,
                 "title: %s", title ? title : "(none)");
    SC_CHECK_MSG(first >= 3 && broken == 0 && plots >= 1, "images %d, on the first screen %d, broken %d, plots %d",
                 images, first, broken, plots);
    char *shot = sc_strprintf("%s/shot_lods.png", out);
    struct stat st;
    SC_CHECK_MSG(stat(shot, &st) == 0 && st.st_size > 20000, "screenshot %s missing or blank", shot);
    free(title), free(shot);

    /* a picture the page names but that is gone counts as broken */
    SC_CHECK_INT(sc_test_system("cd '%s' && rm out/render/lod1_sheet.png", dir), 0);
    title = page_census(out, "gone");
    SC_CHECK_MSG(title && sscanf(title, "images:%d first:%d broken:%d", &images, &first, &broken) == 3 && broken >= 1,
                 "title: %s", title ? title : "(none)");
    free(title), free(out), free(a), free(g), free(dir);
}

/* The farm's options: a bad one is a usage error (2) naming it, before
 * anything cooks or any server is asked. */
SC_TEST(farm_options_checked) {
    char *dir = sc_test_tempdir("cli");
    char *g = data("proc_save.lua");
    static const char *const cases[][2] = {
        {"--base-dir no-such-folder", "--base-dir no-such-folder: not a folder"},
        {"--remote-cache ftp://x/", "expected an http:// or https:// URL"},
        {"--remote-header NoColon", "--remote-header NoColon: expected 'Name: value'"},
        {"--remote-timeout 0", "--remote-timeout 0: expected seconds"},
        {"--remote-retries 11", "--remote-retries 11: expected a number from 0 to 10"},
    };
    for (size_t k = 0; k < sizeof cases / sizeof cases[0]; k++) {
        char *a = sc_strprintf("run '%s' --cache cache --out out %s", g, cases[k][0]);
        SC_CHECK_INT(cook(dir, a), 2);
        char *err = slurp(dir, "err.txt");
        SC_CHECK_MSG(err && strstr(err, cases[k][1]), "%s: stderr: %s", cases[k][0], err ? err : "(nothing)");
        free(err), free(a);
    }
    SC_CHECK_INT(sc_test_system("cd '%s' && SEAMCOOK_REMOTE_RETRIES=x '%s' run '%s' --cache cache --out out "
                                "--remote-cache http://127.0.0.1:1/ >out.txt 2>err.txt", dir, bin(), g), 2);
    char *err = slurp(dir, "err.txt");
    SC_CHECK_MSG(err && strstr(err, "SEAMCOOK_REMOTE_RETRIES=x"), "stderr: %s", err ? err : "(nothing)");
    free(err);
    SC_CHECK_INT(cook(dir, "farm"), 2);
    SC_CHECK_INT(cook(dir, "farm launch"), 2);
    SC_CHECK_INT(cook(dir, "farm submit"), 2);
    char *a = sc_strprintf("farm submit '%s'", g);
    SC_CHECK_INT(cook(dir, a), 2);   /* no --assets */
    free(a);
    SC_CHECK_INT(cook(dir, "farm status --out nowhere"), 2);
    err = slurp(dir, "err.txt");
    SC_CHECK_MSG(err && strstr(err, "no farm job here"), "stderr: %s", err ? err : "(nothing)");
    free(err), free(g), free(dir);
}

int main(void) { return sc_test_main(); }
