/* sc_main.c - the seamcook command line.
 *
 *   seamcook run GRAPH [--set k=v]... [-j N] [--out DIR] [--cache DIR] [-n] [--explain] [--check]
 *   seamcook watch GRAPH [same options]
 *   seamcook test [FILES...] [--update-goldens] [--cache DIR] [--out DIR] [-j N]
 *   seamcook cache stats|verify|gc [--max-size N[K|M|G]] [--cache DIR]
 *   seamcook nodes
 *   seamcook graph GRAPH --dot [--set k=v]...
 *
 * Design note: this file only parses arguments, wires the modules together
 * and maps errors to exit statuses (0 ok, 1 a node or input failed, 2 usage).
 * Everything it prints about a failure comes from an sc_error, which already
 * names the graph file:line or the node and parameter at fault.
 */
#include <errno.h>
#include <limits.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include <uv.h>

#include "sc_cache.h"
#include "sc_engine.h"
#include "sc_golden.h"
#include "sc_lua.h"
#include "sc_registry.h"
#include "sc_report.h"

enum { EXIT_OK = 0, EXIT_FAIL = 1, EXIT_USAGE = 2 };

static const char *usage_text =
    "usage: seamcook run GRAPH [--set k=v]... [-j N] [--out DIR] [--cache DIR] [-n] [--explain] [--check]\n"
    "       seamcook watch GRAPH [options of run]\n"
    "       seamcook test [FILES...] [--update-goldens] [--cache DIR] [--out DIR] [-j N]\n"
    "       seamcook cache stats|verify|gc [--max-size N[K|M|G]] [--cache DIR]\n"
    "       seamcook nodes\n"
    "       seamcook graph GRAPH --dot [--set k=v]...\n";

typedef struct options {
    const char *command;
    const char *subcommand;     /* cache stats|verify|gc */
    const char **files;         /* graph files */
    int nfiles;
    sc_setting *settings;
    int nsettings;
    int jobs;
    const char *out_dir;
    const char *cache_dir;
    bool dry_run, explain, check, dot, quiet, update_goldens;
    int64_t max_size;
    bool max_size_given;
    int max_runs;               /* watch: stop after this many cooks (0: never) */
    double lua_timeout;         /* seconds a graph file may take to build its graph (0: the default) */
    const char *asset_root;     /* --asset-root: every load_atlas's asset_root */
} options;

static int usage(const char *fmt, const char *arg) {
    fputs("seamcook: ", stderr);
    fprintf(stderr, fmt, arg);
    fputc('\n', stderr);
    fputs(usage_text, stderr);
    return EXIT_USAGE;
}

static int parse_size(const char *s, int64_t *out) {
    char *end;
    errno = 0;
    double v = strtod(s, &end);
    if (end == s || errno || v < 0) return -1;
    double mul = 1;
    if (*end == 'K' || *end == 'k') mul = 1024, end++;
    else if (*end == 'M' || *end == 'm') mul = 1024.0 * 1024, end++;
    else if (*end == 'G' || *end == 'g') mul = 1024.0 * 1024 * 1024, end++;
    if (*end == 'B' || *end == 'b') end++;
    if (*end || v * mul > 9e18) return -1;
    *out = (int64_t)(v * mul);
    return 0;
}

static int parse_args(int argc, char **argv, options *o) {
    memset(o, 0, sizeof *o);
    o->jobs = 0;
    if (argc < 2) return usage("%s", "no command given");
    o->command = argv[1];
    o->files = calloc((size_t)argc, sizeof(char *));
    o->settings = calloc((size_t)argc, sizeof(sc_setting));
    if (!o->files || !o->settings) return usage("%s", "out of memory");
    int i = 2;
    if (strcmp(o->command, "cache") == 0) {
        if (argc < 3) return usage("%s", "cache needs stats, verify or gc");
        o->subcommand = argv[2];
        i = 3;
    }
    for (; i < argc; i++) {
        const char *a = argv[i];
        const char *next = i + 1 < argc ? argv[i + 1] : NULL;
#define NEED_VALUE() do { if (!next) return usage("%s needs a value", a); i++; } while (0)
        if (strcmp(a, "--set") == 0 || strcmp(a, "-s") == 0) {
            NEED_VALUE();
            const char *eq = strchr(next, '=');
            if (!eq || eq == next) return usage("--set %s: expected name=value", next);
            for (int k = 0; k < o->nsettings; k++)
                if (strlen(o->settings[k].name) == (size_t)(eq - next) &&
                    strncmp(o->settings[k].name, next, (size_t)(eq - next)) == 0)
                    return usage("--set %s: this name is set twice", next);
            char *name = sc_strndup(next, (size_t)(eq - next));
            o->settings[o->nsettings].name = name;
            o->settings[o->nsettings].value = eq + 1;
            o->nsettings++;
        } else if (strncmp(a, "--set=", 6) == 0) {
            return usage("%s: write --set name=value", a);
        } else if (strcmp(a, "-j") == 0 || strcmp(a, "--jobs") == 0) {
            NEED_VALUE();
            char *end;
            long j = strtol(next, &end, 10);
            if (*end || j < 1 || j > 256) return usage("-j %s: expected a number of jobs from 1 to 256", next);
            o->jobs = (int)j;
        } else if (strncmp(a, "-j", 2) == 0 && a[2]) {
            char *end;
            long j = strtol(a + 2, &end, 10);
            if (*end || j < 1 || j > 256) return usage("%s: expected a number of jobs from 1 to 256", a);
            o->jobs = (int)j;
        } else if (strcmp(a, "--out") == 0 || strcmp(a, "-o") == 0) {
            NEED_VALUE();
            o->out_dir = next;
        } else if (strcmp(a, "--cache") == 0) {
            NEED_VALUE();
            o->cache_dir = next;
        } else if (strcmp(a, "--max-size") == 0) {
            NEED_VALUE();
            if (parse_size(next, &o->max_size) != 0) return usage("--max-size %s: expected a size like 500M", next);
            o->max_size_given = true;
        } else if (strcmp(a, "--asset-root") == 0) {
            NEED_VALUE();
            o->asset_root = next;
        } else if (strcmp(a, "--lua-timeout") == 0) {
            NEED_VALUE();
            char *end;
            double t = strtod(next, &end);
            if (end == next || *end || !(t > 0) || t > 86400)
                return usage("--lua-timeout %s: expected seconds, more than 0", next);
            o->lua_timeout = t;
        } else if (strcmp(a, "--max-runs") == 0) {
            NEED_VALUE();
            o->max_runs = atoi(next);
        } else if (strcmp(a, "-n") == 0 || strcmp(a, "--dry-run") == 0) {
            o->dry_run = true;
        } else if (strcmp(a, "--explain") == 0) {
            o->explain = true;
        } else if (strcmp(a, "--check") == 0) {
            o->check = true;
        } else if (strcmp(a, "--update-goldens") == 0) {
            o->update_goldens = true;
        } else if (strcmp(a, "--dot") == 0) {
            o->dot = true;
        } else if (strcmp(a, "-q") == 0 || strcmp(a, "--quiet") == 0) {
            o->quiet = true;
        } else if (a[0] == '-' && a[1]) {
            return usage("unknown option %s", a);
        } else {
            o->files[o->nfiles++] = a;
        }
#undef NEED_VALUE
    }
    if (o->jobs == 0) {
        long n = sysconf(_SC_NPROCESSORS_ONLN);
        o->jobs = n > 0 ? (int)n : 1;
    }
    return EXIT_OK;
}

static void free_options(options *o) {
    for (int i = 0; i < o->nsettings; i++) free((char *)o->settings[i].name);
    free(o->settings);
    free(o->files);
}

/* $SEAMCOOK_CACHE, else $XDG_CACHE_HOME/seamcook, else ~/.cache/seamcook;
 * NULL when none of them is set (open_cache says so). */
static char *default_cache_dir(void) {
    const char *env = getenv("SEAMCOOK_CACHE");
    if (env && *env) return sc_strdup(env);
    env = getenv("XDG_CACHE_HOME");
    if (env && *env) return sc_strprintf("%s/seamcook", env);
    env = getenv("HOME");
    if (env && *env) return sc_strprintf("%s/.cache/seamcook", env);
    return NULL;
}

static int open_cache(const options *o, sc_cache **cache) {
    char *dir = o->cache_dir ? sc_strdup(o->cache_dir) : default_cache_dir();
    if (!dir && !o->cache_dir) {
        fprintf(stderr, "seamcook: no cache directory: HOME is not set; give --cache DIR or set SEAMCOOK_CACHE\n");
        return EXIT_USAGE;
    }
    sc_error err = {0};
    int rc = dir ? sc_cache_open(dir, cache, &err) : sc_fail(&err, SC_ENOMEM, "out of memory");
    if (rc != SC_OK) fprintf(stderr, "seamcook: %s\n", err.message);   /* the message names the cache */
    else if (sc_cache_notice(*cache)) fprintf(stderr, "seamcook: note: %s\n", sc_cache_notice(*cache));
    free(dir);
    return rc == SC_OK ? EXIT_OK : rc == SC_EUSAGE ? EXIT_USAGE : EXIT_FAIL;
}

/* --asset-root DIR: the asset_root of every node that has one (load_atlas),
 * as an absolute path, so that it enters their keys like any PATH. */
static int set_asset_root(sc_graph **graph, const char *dir) {
    sc_graph *g = *graph;
    struct stat st;
    if (stat(dir, &st) != 0 || !S_ISDIR(st.st_mode)) {
        fprintf(stderr, "seamcook: --asset-root %s: not a folder\n", dir);
        sc_graph_free(g);
        *graph = NULL;
        return EXIT_USAGE;
    }
    char cwd[PATH_MAX];
    char *abs = dir[0] == '/' ? sc_strdup(dir) : getcwd(cwd, sizeof cwd) ? sc_path_join(cwd, dir) : NULL;
    if (!abs) {
        fprintf(stderr, "seamcook: --asset-root %s: cannot make it absolute\n", dir);
        sc_graph_free(g);
        *graph = NULL;
        return EXIT_FAIL;
    }
    for (int i = 0; i < g->count; i++) {
        int p = sc_desc_param(g->nodes[i].desc, "asset_root");
        if (p < 0) continue;
        free(g->nodes[i].params[p].string);
        g->nodes[i].params[p].string = sc_strdup(abs);
    }
    free(abs);
    return EXIT_OK;
}

static int build_graph(const char *file, const options *o, sc_graph **g) {
    int ntypes;
    const sc_node_desc *const *types = sc_registry_all(&ntypes);
    sc_error err = {0};
    const sc_lua_limits limits = {.max_seconds = o->lua_timeout};
    int rc = sc_lua_build(file, types, ntypes, o->settings, o->nsettings, &limits, g, &err);
    if (rc != SC_OK) {
        fprintf(stderr, "seamcook: %s\n", err.message);
        return rc == SC_EUSAGE ? EXIT_USAGE : EXIT_FAIL;
    }
    return o->asset_root ? set_asset_root(g, o->asset_root) : EXIT_OK;
}

/* ---------------------------------------------------------------- run */

static int write_text(const char *out_dir, const char *name, char *text) {
    sc_error err = {0};
    char *path = sc_path_join(out_dir, name);
    int rc = (text && path) ? sc_make_dirs(out_dir, &err) : sc_fail(&err, SC_ENOMEM, "out of memory");
    if (rc == SC_OK) rc = sc_write_file_atomic(path, text, strlen(text), &err);
    if (rc != SC_OK) fprintf(stderr, "seamcook: %s\n", err.message);
    free(text), free(path);
    return rc;
}

static int write_report(const sc_run *run, const char *out_dir) {
    int rc = write_text(out_dir, "report.json", sc_run_report_json(run));
    if (rc == SC_OK) rc = write_text(out_dir, "report.html", sc_run_report_html(run));
    return rc;
}

/* Cook one graph file; returns the exit status. run_out and graph_out
 * (optional) receive the results and the graph, for test and watch. */
static int cook(const char *file, const options *o, sc_cache *cache, const char *out_dir,
                bool check, sc_run **run_out, sc_graph **graph_out) {
    sc_graph *g = NULL;
    int status = build_graph(file, o, &g);
    if (status != EXIT_OK) return status;
    sc_engine_options eo = {
        .jobs = o->jobs, .out_dir = out_dir, .dry_run = o->dry_run, .explain = o->explain,
        .log = o->quiet ? NULL : stderr, .live = !o->quiet && isatty(2),
    };
    if (out_dir && !o->dry_run) sc_remove_stale_tmp(out_dir, NULL);   /* a killed run's half-written files */
    sc_run *run = NULL;
    sc_error err = {0};
    int rc = sc_engine_run(g, cache, &eo, &run, &err);
    status = rc == SC_OK ? EXIT_OK : EXIT_FAIL;
    if (run && !o->dry_run && out_dir && write_report(run, out_dir) != SC_OK) status = EXIT_FAIL;
    if (rc != SC_OK) fprintf(stderr, "seamcook: %s\n", err.message);
    if (run && !o->quiet)
        fprintf(stderr, "%s: %d nodes, %d cooked, %d cached, %d failed, %d skipped in %.3f s%s%s\n",
                file, g->count, run->ran, run->cached, run->failed, run->skipped, run->seconds,
                (out_dir && !o->dry_run) ? "; report: " : "", (out_dir && !o->dry_run) ? out_dir : "");
    if (run && status == EXIT_OK && check && !o->dry_run && sc_golden_check(run, out_dir, false, stderr) > 0)
        status = EXIT_FAIL;
    if (run_out) *run_out = run;
    else sc_run_free(run);
    if (graph_out) *graph_out = g;
    else sc_graph_free(g);
    return status;
}

static int cmd_run(const options *o) {
    if (o->nfiles != 1) return usage("%s", "run needs exactly one graph file");
    sc_cache *cache = NULL;
    int opened = open_cache(o, &cache);
    if (opened != EXIT_OK) return opened;
    int status = cook(o->files[0], o, cache, o->out_dir ? o->out_dir : "out", o->check, NULL, NULL);
    sc_cache_close(cache);
    return status;
}

/* ---------------------------------------------------------------- watch */

/* One watched folder: the names of the files in it we care about. */
typedef struct watched_dir {
    uv_fs_event_t handle;
    char *path;
    char *names;               /* "\nname1\nname2\n" */
} watched_dir;

typedef struct watcher {
    uv_loop_t *loop;
    uv_timer_t debounce;
    uv_signal_t sigint;
    int nwatch;
    watched_dir **dirs;
    const options *o;
    sc_cache *cache;
    const char *out_dir;
    int runs;
} watcher;

static void watch_rebuild(uv_timer_t *timer);

static void on_fs_event(uv_fs_event_t *h, const char *filename, int events, int status) {
    (void)events;
    watched_dir *wd = (watched_dir *)h;
    watcher *w = h->data;
    if (status < 0 || !filename) return;
    char probe[1024];
    snprintf(probe, sizeof probe, "\n%s\n", filename);
    if (!strstr(wd->names, probe)) return;
    uv_timer_start(&w->debounce, watch_rebuild, 150, 0);
}

static void free_watched_dir(uv_handle_t *h) {
    watched_dir *wd = (watched_dir *)h;
    free(wd->path), free(wd->names), free(wd);
}

static void close_watches(watcher *w) {
    for (int i = 0; i < w->nwatch; i++) {
        uv_fs_event_stop(&w->dirs[i]->handle);
        uv_close((uv_handle_t *)&w->dirs[i]->handle, free_watched_dir);
    }
    free(w->dirs);
    w->dirs = NULL, w->nwatch = 0;
}

/* Watch the folder of each file (not the file: editors that save by writing
 * a new file and renaming it over the old one replace the inode). A file
 * whose folder is missing too is waited for in the nearest folder that
 * exists, under the name of the first missing one. */
static void watch_files(watcher *w, char **files, int nfiles) {
    w->dirs = calloc((size_t)nfiles + 1, sizeof *w->dirs);
    if (!w->dirs) return;
    for (int f = 0; f < nfiles; f++) {
        char *dir = sc_path_dirname(files[f]);
        char *base = sc_strdup(strrchr(files[f], '/') ? strrchr(files[f], '/') + 1 : files[f]);
        struct stat st;
        while (dir && base && stat(dir, &st) != 0 && strcmp(dir, "/") != 0 && strcmp(dir, ".") != 0) {
            char *up = sc_path_dirname(dir);
            free(base);
            base = sc_strdup(strrchr(dir, '/') ? strrchr(dir, '/') + 1 : dir);
            free(dir);
            dir = up;
        }
        watched_dir *wd = NULL;
        for (int k = 0; dir && k < w->nwatch; k++)
            if (strcmp(w->dirs[k]->path, dir) == 0) wd = w->dirs[k];
        if (!wd && dir) {
            wd = calloc(1, sizeof *wd);
            if (!wd) {
                free(dir), free(base);
                break;
            }
            wd->path = dir;
            wd->names = sc_strdup("\n");
            dir = NULL;
            uv_fs_event_init(w->loop, &wd->handle);
            wd->handle.data = w;
            if (uv_fs_event_start(&wd->handle, on_fs_event, wd->path, 0) != 0) {
                uv_close((uv_handle_t *)&wd->handle, free_watched_dir);
                free(base);
                continue;
            }
            w->dirs[w->nwatch++] = wd;
        }
        if (wd && wd->names && base) {
            char *joined = sc_strprintf("%s%s\n", wd->names, base);
            if (joined) free(wd->names), wd->names = joined;
        }
        free(dir), free(base);
    }
}

/* Whether `path` no longer holds what a cook saw: `seen` is the content it
 * read, all zero when it found the file missing. */
static bool changed_since(sc_cache *cache, const char *path, const sc_digest *seen) {
    static const sc_digest missing;
    sc_digest now;
    sc_error ignored;
    bool exists = sc_cache_file_digest(cache, path, &now, &ignored) == SC_OK;
    if (sc_digest_equal(seen, &missing)) return exists;
    return !exists || !sc_digest_equal(&now, seen);
}

static void watch_rebuild(uv_timer_t *timer) {
    watcher *w = timer->data;
    close_watches(w);
    char graph[PATH_MAX];
    if (!realpath(w->o->files[0], graph)) snprintf(graph, sizeof graph, "%s", w->o->files[0]);
    sc_digest graph_seen = {0};
    sc_error ignored;
    sc_cache_file_digest(w->cache, graph, &graph_seen, &ignored);
    sc_run *run = NULL;
    sc_graph *g = NULL;
    cook(w->o->files[0], w->o, w->cache, w->out_dir, w->o->check, &run, &g);
    w->runs++;
    sc_release_memory();   /* a watch waits long between cooks */
    /* the graph file itself plus every file any node read or found missing */
    int cap = 1, n = 0;
    if (run)
        for (int i = 0; i < g->count; i++) cap += run->results[i].ndeps;
    char **files = calloc((size_t)cap + 1, sizeof(char *));
    if (files) files[n++] = sc_strdup(graph);
    if (files && run)
        for (int i = 0; i < g->count; i++)
            for (int d = 0; d < run->results[i].ndeps; d++) files[n++] = sc_strdup(run->results[i].deps[d]);
    for (int k = 0; files && k < n; k++)
        if (!files[k]) files[k--] = files[--n];   /* drop what could not be copied */
    if (files) watch_files(w, files, n);
    /* a change that landed while the cook ran is cooked next, not lost */
    bool stale = changed_since(w->cache, graph, &graph_seen);
    for (int i = 0; run && !stale && i < g->count; i++)
        for (int d = 0; run->results[i].dep_digests && !stale && d < run->results[i].ndeps; d++)
            stale = changed_since(w->cache, run->results[i].deps[d], &run->results[i].dep_digests[d]);
    for (int k = 0; files && k < n; k++) free(files[k]);
    free(files);
    sc_run_free(run);
    sc_graph_free(g);
    bool last = w->o->max_runs > 0 && w->runs >= w->o->max_runs;
    if (stale && !last) {
        if (!w->o->quiet) fprintf(stderr, "a file changed during the cook: cooking again\n");
        uv_timer_start(&w->debounce, watch_rebuild, 150, 0);
    } else if (!w->o->quiet) {
        fprintf(stderr, "watching %d folder(s) for changes (Ctrl-C stops)\n", w->nwatch);
    }
    if (last) {
        close_watches(w);
        uv_close((uv_handle_t *)&w->debounce, NULL);
        uv_close((uv_handle_t *)&w->sigint, NULL);
    }
}

static void on_sigint(uv_signal_t *h, int sig) {
    (void)sig;
    watcher *w = h->data;
    close_watches(w);
    uv_timer_stop(&w->debounce);
    uv_close((uv_handle_t *)&w->debounce, NULL);
    uv_close((uv_handle_t *)&w->sigint, NULL);
}

static int cmd_watch(const options *o) {
    if (o->nfiles != 1) return usage("%s", "watch needs exactly one graph file");
    if (o->dry_run) return usage("%s", "watch cannot be a dry run");
    sc_cache *cache = NULL;
    int opened = open_cache(o, &cache);
    if (opened != EXIT_OK) return opened;
    watcher w = {.loop = uv_default_loop(), .o = o, .cache = cache,
                 .out_dir = o->out_dir ? o->out_dir : "out"};
    uv_timer_init(w.loop, &w.debounce);
    w.debounce.data = &w;
    uv_signal_init(w.loop, &w.sigint);
    w.sigint.data = &w;
    uv_signal_start(&w.sigint, on_sigint, SIGINT);
    watch_rebuild(&w.debounce);
    uv_run(w.loop, UV_RUN_DEFAULT);
    uv_loop_close(w.loop);
    sc_cache_close(cache);
    return EXIT_OK;
}

/* ---------------------------------------------------------------- test */

static int cmd_test(const options *o) {
    if (o->nfiles == 0) return usage("%s", "test needs graph test files");
    sc_cache *cache = NULL;
    int opened = open_cache(o, &cache);
    if (opened != EXIT_OK) return opened;
    int passed = 0, failed = 0;
    for (int f = 0; f < o->nfiles; f++) {
        const char *file = o->files[f];
        const char *base = strrchr(file, '/') ? strrchr(file, '/') + 1 : file;
        char *out = sc_strprintf("%s/%.*s", o->out_dir ? o->out_dir : "out/test",
                                 (int)(strcspn(base, ".")), base);
        sc_run *run = NULL;
        sc_graph *g = NULL;
        int status = out ? cook(file, o, cache, out, false, &run, &g) : EXIT_FAIL;
        int bad = status == EXIT_OK ? sc_golden_check(run, out, o->update_goldens, stderr) : 1;
        if (status == EXIT_OK && g->nexpect == 0) {
            fprintf(stderr, "%s: states no expectation\n", file);
            bad = 1;
        }
        if (bad) failed++;
        else passed++;
        printf("%s %s (%d expectations)\n", bad ? "FAIL" : "ok  ", file, g ? g->nexpect : 0);
        sc_run_free(run);
        sc_graph_free(g);
        free(out);
    }
    sc_cache_close(cache);
    printf("%d passed, %d failed\n", passed, failed);
    return failed ? EXIT_FAIL : EXIT_OK;
}

/* ---------------------------------------------------------------- cache, nodes, graph */

static int cmd_cache(const options *o) {
    sc_cache *cache = NULL;
    if (strcmp(o->subcommand, "stats") && strcmp(o->subcommand, "verify") && strcmp(o->subcommand, "gc"))
        return usage("unknown cache command '%s'", o->subcommand);
    if (!strcmp(o->subcommand, "gc") && !o->max_size_given)
        return usage("%s", "gc needs --max-size");
    int opened = open_cache(o, &cache);
    if (opened != EXIT_OK) return opened;
    sc_error err = {0};
    int rc;
    if (!strcmp(o->subcommand, "stats")) {
        sc_cache_stats s;
        rc = sc_cache_stats_get(cache, &s, &err);
        if (rc == SC_OK)
            printf("cache %s\nblobs %lld (%.1f MiB)\nactions %lld\nsource stamps %lld\nruns %lld\n",
                   sc_cache_dir(cache), (long long)s.blobs, s.blob_bytes / 1048576.0,
                   (long long)s.actions, (long long)s.stamps, (long long)s.runs);
    } else if (!strcmp(o->subcommand, "verify")) {
        sc_cache_verify_result v;
        rc = sc_cache_verify(cache, &v, &err);
        if (rc == SC_OK) {
            printf("checked %lld blobs: %lld bad (removed), %lld not files (removed), %lld missing, "
                   "%lld actions dropped; index %s\n",
                   (long long)v.checked, (long long)v.bad, (long long)v.not_files, (long long)v.missing,
                   (long long)v.actions_dropped, v.index_rebuilt ? "damaged (rebuilt)" : "ok");
            if (v.bad || v.missing || v.not_files || v.index_rebuilt) rc = SC_EIO;
        }
    } else {
        sc_cache_gc_result gr;
        rc = sc_cache_gc(cache, o->max_size, &gr, &err);
        if (rc == SC_OK)
            printf("removed %lld blobs (%.1f MiB), dropped %lld actions; %.1f MiB left\n",
                   (long long)gr.blobs_removed, gr.bytes_removed / 1048576.0,
                   (long long)gr.actions_dropped, gr.bytes_left / 1048576.0);
    }
    if (rc != SC_OK && err.message[0]) fprintf(stderr, "seamcook: %s\n", err.message);
    sc_cache_close(cache);
    return rc == SC_OK ? EXIT_OK : EXIT_FAIL;
}

static const char *param_type_name(sc_param_type t) {
    switch (t) {
    case SC_PARAM_NUMBER: return "number";
    case SC_PARAM_INTEGER: return "integer";
    case SC_PARAM_BOOL: return "boolean";
    case SC_PARAM_STRING: return "string";
    case SC_PARAM_ENUM: return "choice";
    case SC_PARAM_PATH: return "path";
    case SC_PARAM_NUMBERS: return "numbers";
    }
    return "?";
}

static int cmd_nodes(void) {
    int n;
    const sc_node_desc *const *all = sc_registry_all(&n);
    for (int i = 0; i < n; i++) {
        const sc_node_desc *d = all[i];
        printf("%s (version %d): %s\n", d->type, d->version, d->summary);
        for (int k = 0; k < d->ninputs; k++)
            printf("  input  %-16s %-7s %s%s\n", d->inputs[k].name, sc_kind_name(d->inputs[k].kind),
                   d->inputs[k].optional ? "(optional) " : "", d->inputs[k].doc ? d->inputs[k].doc : "");
        for (int k = 0; k < d->noutputs; k++)
            printf("  output %-16s %-7s %s\n", d->outputs[k].name, sc_kind_name(d->outputs[k].kind),
                   d->outputs[k].doc ? d->outputs[k].doc : "");
        for (int k = 0; k < d->nparams; k++) {
            const sc_param_desc *p = &d->params[k];
            char def[64] = "";
            if (p->required) snprintf(def, sizeof def, "required");
            else if (p->type == SC_PARAM_NUMBER || p->type == SC_PARAM_INTEGER) {
                char num[32];
                sc_format_double(p->def, num);
                snprintf(def, sizeof def, "default %s", num);
            } else if (p->type == SC_PARAM_BOOL) snprintf(def, sizeof def, "default %s", p->def ? "true" : "false");
            else if (p->def_string) snprintf(def, sizeof def, "default \"%s\"", p->def_string);
            printf("  param  %-16s %-7s %s; %s\n", p->name, param_type_name(p->type), def, p->doc ? p->doc : "");
        }
    }
    return EXIT_OK;
}

static int cmd_graph(const options *o) {
    if (o->nfiles != 1) return usage("%s", "graph needs exactly one graph file");
    if (!o->dot) return usage("%s", "graph needs --dot");
    sc_graph *g = NULL;
    int status = build_graph(o->files[0], o, &g);
    if (status != EXIT_OK) return status;
    printf("digraph seamcook {\n  rankdir=LR;\n  node [shape=box, fontname=\"sans-serif\"];\n");
    for (int i = 0; i < g->count; i++)
        printf("  n%d [label=\"%s\\n(%s)\"];\n", i, g->nodes[i].name, g->nodes[i].desc->type);
    for (int i = 0; i < g->count; i++) {
        const sc_graph_node *n = &g->nodes[i];
        for (int port = 0; port < n->desc->ninputs; port++)
            if (n->input_node[port] >= 0)
                printf("  n%d -> n%d [label=\"%s\"];\n", n->input_node[port], i, n->desc->inputs[port].name);
    }
    printf("}\n");
    sc_graph_free(g);
    return EXIT_OK;
}

int main(int argc, char **argv) {
    options o;
    int status = parse_args(argc, argv, &o);
    if (status != EXIT_OK) {
        free_options(&o);
        return status;
    }
    sc_tune_allocator();
    /* the thread pool is sized once, at its first use: cooking jobs plus loads */
    char pool[16];
    snprintf(pool, sizeof pool, "%d", o.jobs + 1);
    setenv("UV_THREADPOOL_SIZE", pool, 1);

    if (!strcmp(o.command, "run")) status = cmd_run(&o);
    else if (!strcmp(o.command, "watch")) status = cmd_watch(&o);
    else if (!strcmp(o.command, "test")) status = cmd_test(&o);
    else if (!strcmp(o.command, "cache")) status = cmd_cache(&o);
    else if (!strcmp(o.command, "nodes")) status = cmd_nodes();
    else if (!strcmp(o.command, "graph")) status = cmd_graph(&o);
    else if (!strcmp(o.command, "help") || !strcmp(o.command, "--help") || !strcmp(o.command, "-h")) {
        fputs(usage_text, stdout);
        status = EXIT_OK;
    } else status = usage("unknown command '%s'", o.command);
    free_options(&o);
    return status;
}
