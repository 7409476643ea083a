/* sc_main.c - the seamcook command line.
 *
 *   seamcook run GRAPH [--set k=v]... [-j N] [-o DIR] [--cache DIR] [-n] [--explain] [--check] [--json]
 *   seamcook watch GRAPH [options of run] [--max-runs N]
 *   seamcook test [FILES...] [--update-goldens] [--junit FILE] [options of run]
 *   seamcook cache stats|verify|gc [--max-size N[K|M|G]] [--cache DIR]
 *   seamcook farm submit GRAPH --assets LIST [options of run] | farm status [--out DIR]
 *   seamcook nodes
 *   seamcook graph GRAPH --dot [--set k=v]...
 *   seamcook version | --version;  seamcook [COMMAND] --help
 *
 * Design note: this file only parses arguments, wires the modules together
 * and maps errors to exit statuses (0 ok, 1 a node or input failed, 2 usage:
 * a bad command line, or a --set value a node refuses). Options are a table:
 * each says which commands take it, so an option a command would ignore is
 * a usage error rather than silence. Everything it prints about a failure
 * comes from an sc_error, which already names the graph file:line or the
 * node and parameter at fault. Standard output carries only what a command
 * is asked for (a summary with --json, the DOT text, the node list), so it
 * can be piped; progress and messages go to standard error.
 */
#include <errno.h>
#include <limits.h>
#include <signal.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include <uv.h>

#include "sc_cache.h"
#include "sc_config.h"
#include "sc_engine.h"
#include "sc_farm.h"
#include "sc_golden.h"
#include "sc_lua.h"
#include "sc_manifest.h"
#include "sc_registry.h"
#include "sc_report.h"

#ifndef SC_VERSION
#define SC_VERSION "unknown"
#endif

enum { EXIT_OK = 0, EXIT_FAIL = 1, EXIT_USAGE = 2 };

#define DEFAULT_CACHE_MAX_SIZE ((int64_t)10 << 30)

/* ---------------------------------------------------------------- usage */

#define OPTIONS_OF_COOKS                                                                               \
    "  -s, --set NAME=VALUE     a graph parameter, read by param(NAME) in the graph file\n"          \
    "  -s, --set NODE.PARAM=VALUE  the parameter PARAM of the node named NODE\n"                     \
    "  -j, --jobs N             nodes cooking at once (default: the number of processors)\n"         \
    "  -o, --out DIR            where saved files, report.json and report.html go (default out)\n" \
    "  --cache DIR              the cache (default: $SEAMCOOK_CACHE, else\n"                         \
    "                           $XDG_CACHE_HOME/seamcook, else ~/.cache/seamcook)\n"                 \
    "  --cache-max-size SIZE    trim the cache to SIZE (500M, 10G) after cooking, least recently\n"  \
    "                           used first (default: $SEAMCOOK_CACHE_MAX_SIZE, else 10G)\n"          \
    "  --explain                say why each node cooks\n"                                          \
    "  --asset-root DIR         the folder every load_atlas may read below\n"                       \
    "  --base-dir DIR           paths enter cache keys relative to DIR (default: the graph file's\n" \
    "                           folder), so keys are the same for a checkout anywhere\n"           \
    "  --lua-timeout SECONDS    how long the graph file may take to build the graph (default 5)\n"  \
    "  --remote-cache URL       a remote cache (Bazel's HTTP protocol: /cas/, /ac/), asked on a local\n" \
    "                           miss and given what cooks; \"\" for none (default:\n"                    \
    "                           $SEAMCOOK_REMOTE_CACHE, else remote_cache in seamcook.conf)\n"           \
    "  --remote-header 'NAME: VALUE'  a header for every remote request (may repeat)\n"             \
    "  --remote-read-only       look up the remote cache, never upload\n"                           \
    "  --remote-timeout SECONDS to connect, and a transfer may stall (default 10)\n"                \
    "  --remote-retries N       tries after the first on a network error (default 2)\n"            \
    "  -q, --quiet              no progress, no summary line (warnings are still printed)\n"         \
    "  --strict                 exit status 1 when a node warns of a shortfall (a level above its\n" \
    "                           target, a texture missing or skipped, a map left unerased)\n"       \
    "  -h, --help               this text\n"

static const char run_usage[] =
    "usage: seamcook run GRAPH [options]\n"
    "Cooks the graph: every node whose inputs, parameters, version or files changed; the rest\n"
    "comes from the cache. Exit status: 0 ok, 1 a node or an input failed, 2 a usage error.\n"
    OPTIONS_OF_COOKS
    "  -n, --dry-run            say what would cook and why; cook and write nothing\n"
    "  --check                  fail (exit status 1) when an expect() of the graph does not hold\n"
    "  --json                   print a summary of the run as JSON on standard output\n";

static const char watch_usage[] =
    "usage: seamcook watch GRAPH [options]\n"
    "Cooks the graph, then again whenever the graph file or a file it read changes.\n"
    OPTIONS_OF_COOKS
    "  --check                  report failed expect()s of the graph\n"
    "  --max-runs N             stop after N cooks (default: never; Ctrl-C stops)\n";

static const char test_usage[] =
    "usage: seamcook test FILES... [options]\n"
    "Runs graph test files and checks what they state: expect(), expect_image() and\n"
    "expect_metrics() against goldens/<graph>/ beside each file. Exit status 1 when one fails.\n"
    OPTIONS_OF_COOKS
    "  --update-goldens         write the goldens from this run instead of comparing\n"
    "  --junit FILE             write the outcome as JUnit XML to FILE\n";

static const char cache_usage[] =
    "usage: seamcook cache stats|verify|gc [options]\n"
    "  stats                    what the cache holds\n"
    "  verify                   re-hash every blob; remove bad ones (exit status 1 when any)\n"
    "  gc --max-size SIZE       remove least recently used blobs down to SIZE (500M, 10G)\n"
    "  --cache DIR              the cache (default as for run)\n"
    "  -h, --help               this text\n";

static const char nodes_usage[] =
    "usage: seamcook nodes\n"
    "Lists every node type: ports, parameters, defaults and ranges.\n";

static const char graph_usage[] =
    "usage: seamcook graph GRAPH --dot [--set NAME=VALUE]...\n"
    "Prints the graph in Graphviz's DOT language.\n"
    "  --set NAME=VALUE, --set NODE.PARAM=VALUE, --asset-root DIR, --lua-timeout SECONDS: as for run\n";

static const char farm_usage[] =
    "usage: seamcook farm submit GRAPH --assets LIST [--asset-param NAME] [--out DIR] [options of run]\n"
    "       seamcook farm status [--out DIR]\n"
    "submit cooks GRAPH once per asset of LIST (a path a line, relative to the list's folder) as a\n"
    "Slurm job array (sbatch): task i runs `seamcook run GRAPH --set NAME=ASSET_i --out DIR/<i>_<asset>`\n"
    "with the options given here, in this folder. status says what each task did.\n"
    "  --assets LIST            the asset list\n"
    "  --asset-param NAME       the graph parameter an asset goes into (default mesh)\n"
    "  -o, --out DIR            where the tasks' folders and the job's (.seamcook-farm) go (default out)\n"
    "  --set, -j, --cache, --cache-max-size, --asset-root, --base-dir, --lua-timeout, --explain,\n"
    "  --remote-*, -q           passed to every task's run\n";

static const char version_usage[] =
    "usage: seamcook version (or seamcook --version)\n"
    "Prints the version.\n";

static const char general_usage[] =
    "usage: seamcook run GRAPH [--set k=v]... [-j N] [-o DIR] [--cache DIR] [-n] [--explain] [--check] [--json]\n"
    "       seamcook watch GRAPH [options of run] [--max-runs N]\n"
    "       seamcook test FILES... [options of run] [--update-goldens] [--junit FILE]\n"
    "       seamcook cache stats|verify|gc [--max-size N[K|M|G]] [--cache DIR]\n"
    "       seamcook farm submit GRAPH --assets LIST [options of run] | farm status [--out DIR]\n"
    "       seamcook nodes\n"
    "       seamcook graph GRAPH --dot [--set k=v]...\n"
    "       seamcook version\n"
    "seamcook COMMAND --help says more about each.\n";

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
    bool dry_run, explain, check, dot, quiet, update_goldens, json, help, strict;
    int64_t max_size;           /* cache gc --max-size */
    bool max_size_given;
    int64_t cache_max_size;     /* trimmed to after cooking */
    int max_runs;               /* watch: stop after this many cooks (0: never) */
    double lua_timeout;         /* seconds a graph file may take to build its graph (0: the default) */
    const char *asset_root;     /* --asset-root: every load_atlas's asset_root */
    const char *base_dir;       /* --base-dir: paths in keys are relative to it */
    const char *junit;          /* test --junit FILE */
    const char *remote_cache;   /* --remote-cache URL ("" none; NULL not given) */
    const char **remote_headers;/* --remote-header, each */
    int nremote_headers;
    bool remote_read_only;
    double remote_timeout;      /* 0: not given */
    int remote_retries;         /* -1: not given */
    const char *assets;         /* farm --assets LIST */
    const char *asset_param;    /* farm --asset-param NAME */
    const char **passed;        /* farm submit: the options each task's run gets, as given */
    int npassed;
} options;

static int usage(const char *fmt, ...) __attribute__((format(printf, 1, 2)));
static int usage(const char *fmt, ...) {
    fputs("seamcook: ", stderr);
    va_list ap;
    va_start(ap, fmt);
    vfprintf(stderr, fmt, ap);
    va_end(ap);
    fputs("\n(seamcook --help lists the commands; seamcook COMMAND --help their options)\n", stderr);
    return EXIT_USAGE;
}

/* ---------------------------------------------------------------- arguments */

static int parse_size(const char *s, int64_t *out) {
    char *end;
    errno = 0;
    double v = strtod(s, &end);
    if (end == s || errno || v < 0) return -1;
    double mul = 1;
    if (*end == 'K' || *end == 'k') mul = 1024, end++;
    else if (*end == 'M' || *end == 'm') mul = 1024.0 * 1024, end++;
    else if (*end == 'G' || *end == 'g') mul = 1024.0 * 1024 * 1024, end++;
    else if (*end == 'T' || *end == 't') mul = 1024.0 * 1024 * 1024 * 1024, end++;
    if (*end == 'B' || *end == 'b') end++;
    if (*end || v * mul > 9e18) return -1;
    *out = (int64_t)(v * mul);
    return 0;
}

enum {
    OPT_SET, OPT_JOBS, OPT_OUT, OPT_CACHE, OPT_CACHE_MAX_SIZE, OPT_MAX_SIZE, OPT_ASSET_ROOT, OPT_BASE_DIR, OPT_LUA_TIMEOUT,
    OPT_MAX_RUNS, OPT_JUNIT, OPT_DRY_RUN, OPT_EXPLAIN, OPT_CHECK, OPT_UPDATE_GOLDENS, OPT_DOT, OPT_QUIET,
    OPT_JSON, OPT_STRICT, OPT_HELP, OPT_REMOTE_CACHE, OPT_REMOTE_HEADER, OPT_REMOTE_READ_ONLY, OPT_REMOTE_TIMEOUT,
    OPT_REMOTE_RETRIES, OPT_ASSETS, OPT_ASSET_PARAM, OPT_COUNT
};

static const struct option_spec {
    const char *name, *alias;   /* "--out", "-o" */
    bool value;                 /* takes the next argument */
    const char *commands;       /* the commands that take it, each followed by a space */
} option_specs[OPT_COUNT] = {
    [OPT_SET] = {"--set", "-s", true, "run watch test graph farm "},
    [OPT_JOBS] = {"--jobs", "-j", true, "run watch test farm "},
    [OPT_OUT] = {"--out", "-o", true, "run watch test farm "},
    [OPT_CACHE] = {"--cache", NULL, true, "run watch test cache farm "},
    [OPT_CACHE_MAX_SIZE] = {"--cache-max-size", NULL, true, "run watch test farm "},
    [OPT_MAX_SIZE] = {"--max-size", NULL, true, "cache "},
    [OPT_ASSET_ROOT] = {"--asset-root", NULL, true, "run watch test graph farm "},
    [OPT_BASE_DIR] = {"--base-dir", NULL, true, "run watch test farm "},
    [OPT_LUA_TIMEOUT] = {"--lua-timeout", NULL, true, "run watch test graph farm "},
    [OPT_MAX_RUNS] = {"--max-runs", NULL, true, "watch "},
    [OPT_JUNIT] = {"--junit", NULL, true, "test "},
    [OPT_DRY_RUN] = {"--dry-run", "-n", false, "run "},
    [OPT_EXPLAIN] = {"--explain", NULL, false, "run watch test farm "},
    [OPT_CHECK] = {"--check", NULL, false, "run watch "},
    [OPT_UPDATE_GOLDENS] = {"--update-goldens", NULL, false, "test "},
    [OPT_DOT] = {"--dot", NULL, false, "graph "},
    [OPT_QUIET] = {"--quiet", "-q", false, "run watch test farm "},
    [OPT_JSON] = {"--json", NULL, false, "run "},
    [OPT_STRICT] = {"--strict", NULL, false, "run watch test "},
    [OPT_HELP] = {"--help", "-h", false, "run watch test cache nodes graph version farm "},
    [OPT_REMOTE_CACHE] = {"--remote-cache", NULL, true, "run watch test farm "},
    [OPT_REMOTE_HEADER] = {"--remote-header", NULL, true, "run watch test farm "},
    [OPT_REMOTE_READ_ONLY] = {"--remote-read-only", NULL, false, "run watch test farm "},
    [OPT_REMOTE_TIMEOUT] = {"--remote-timeout", NULL, true, "run watch test farm "},
    [OPT_REMOTE_RETRIES] = {"--remote-retries", NULL, true, "run watch test farm "},
    [OPT_ASSETS] = {"--assets", NULL, true, "farm "},
    [OPT_ASSET_PARAM] = {"--asset-param", NULL, true, "farm "},
};

static bool takes(const char *commands, const char *command) {
    size_t n = strlen(command);
    for (const char *p = strstr(commands, command); p; p = strstr(p + 1, command))
        if ((p == commands || p[-1] == ' ') && p[n] == ' ') return true;
    return false;
}

/* --set NAME=VALUE, once per name. */
static int add_setting(options *o, const char *text) {
    const char *eq = strchr(text, '=');
    if (!eq || eq == text) return usage("--set %s: expected name=value or node.param=value", text);
    for (int k = 0; k < o->nsettings; k++)
        if (strlen(o->settings[k].name) == (size_t)(eq - text) &&
            strncmp(o->settings[k].name, text, (size_t)(eq - text)) == 0)
            return usage("--set %s: this name is set twice", text);
    char *name = sc_strndup(text, (size_t)(eq - text));
    if (!name) return usage("%s", "out of memory");
    o->settings[o->nsettings].name = name;
    o->settings[o->nsettings].value = eq + 1;
    o->nsettings++;
    return EXIT_OK;
}

/* A whole number from 1 to max, the whole text. */
static bool parse_count(const char *text, long max, int *out) {
    char *end;
    errno = 0;
    long n = strtol(text, &end, 10);
    if (end == text || *end || errno || n < 1 || n > max) return false;
    *out = (int)n;
    return true;
}

/* The value of option `id`. */
static int set_option(options *o, int id, const char *name, const char *v) {
    char *end;
    switch (id) {
    case OPT_SET: return add_setting(o, v);
    case OPT_JOBS:
        if (!parse_count(v, 256, &o->jobs)) return usage("%s %s: expected a number of jobs from 1 to 256", name, v);
        return EXIT_OK;
    case OPT_OUT: o->out_dir = v; return EXIT_OK;
    case OPT_CACHE: o->cache_dir = v; return EXIT_OK;
    case OPT_ASSET_ROOT: o->asset_root = v; return EXIT_OK;
    case OPT_BASE_DIR: {
        struct stat st;
        if (stat(v, &st) != 0 || !S_ISDIR(st.st_mode)) return usage("%s %s: not a folder", name, v);
        o->base_dir = v;
        return EXIT_OK;
    }
    case OPT_JUNIT: o->junit = v; return EXIT_OK;
    case OPT_CACHE_MAX_SIZE:
    case OPT_MAX_SIZE:
        if (parse_size(v, id == OPT_MAX_SIZE ? &o->max_size : &o->cache_max_size) != 0)
            return usage("%s %s: expected a size like 500M or 10G", name, v);
        if (id == OPT_MAX_SIZE) o->max_size_given = true;
        return EXIT_OK;
    case OPT_LUA_TIMEOUT: {
        double t = strtod(v, &end);
        if (end == v || *end || !(t > 0) || t > 86400) return usage("%s %s: expected seconds, more than 0", name, v);
        o->lua_timeout = t;
        return EXIT_OK;
    }
    case OPT_MAX_RUNS:
        if (!parse_count(v, INT_MAX, &o->max_runs)) return usage("%s %s: expected a number of cooks, 1 or more", name, v);
        return EXIT_OK;
    case OPT_DRY_RUN: o->dry_run = true; return EXIT_OK;
    case OPT_EXPLAIN: o->explain = true; return EXIT_OK;
    case OPT_CHECK: o->check = true; return EXIT_OK;
    case OPT_UPDATE_GOLDENS: o->update_goldens = true; return EXIT_OK;
    case OPT_DOT: o->dot = true; return EXIT_OK;
    case OPT_QUIET: o->quiet = true; return EXIT_OK;
    case OPT_JSON: o->json = true; return EXIT_OK;
    case OPT_STRICT: o->strict = true; return EXIT_OK;
    case OPT_HELP: o->help = true; return EXIT_OK;
    case OPT_REMOTE_CACHE: o->remote_cache = v; return EXIT_OK;
    case OPT_REMOTE_HEADER:
        if (!strchr(v, ':') || v[0] == ':') return usage("%s %s: expected 'Name: value'", name, v);
        o->remote_headers[o->nremote_headers++] = v;
        return EXIT_OK;
    case OPT_REMOTE_READ_ONLY: o->remote_read_only = true; return EXIT_OK;
    case OPT_ASSETS: o->assets = v; return EXIT_OK;
    case OPT_ASSET_PARAM: o->asset_param = v; return EXIT_OK;
    case OPT_REMOTE_TIMEOUT: {
        double t = strtod(v, &end);
        if (end == v || *end || !(t > 0) || t > 3600) return usage("%s %s: expected seconds, more than 0", name, v);
        o->remote_timeout = t;
        return EXIT_OK;
    }
    case OPT_REMOTE_RETRIES: {
        long n = strtol(v, &end, 10);
        if (end == v || *end || n < 0 || n > 10) return usage("%s %s: expected a number from 0 to 10", name, v);
        o->remote_retries = (int)n;
        return EXIT_OK;
    }
    }
    return usage("unknown option %s", name);
}

/* argv[1] is a known command. */
static int parse_args(int argc, char **argv, options *o) {
    memset(o, 0, sizeof *o);
    o->command = argv[1];
    o->files = calloc((size_t)argc, sizeof(char *));
    o->settings = calloc((size_t)argc, sizeof(sc_setting));
    o->remote_headers = calloc((size_t)argc, sizeof(char *));
    o->passed = calloc((size_t)argc, sizeof(char *));
    o->remote_retries = -1;
    if (!o->files || !o->settings || !o->remote_headers || !o->passed) return usage("%s", "out of memory");
    int i = 2;
    if ((strcmp(o->command, "cache") == 0 || strcmp(o->command, "farm") == 0) && argc > 2 && argv[2][0] != '-')
        o->subcommand = argv[i++];
    for (; i < argc; i++) {
        const char *a = argv[i];
        if (a[0] != '-' || !a[1]) {
            o->files[o->nfiles++] = a;
            continue;
        }
        int id = -1;
        const char *value = NULL;
        for (int k = 0; k < OPT_COUNT && id < 0; k++)
            if (!strcmp(a, option_specs[k].name) || (option_specs[k].alias && !strcmp(a, option_specs[k].alias)))
                id = k;
        const char *name = a;
        if (id < 0 && strncmp(a, "-j", 2) == 0 && a[2]) id = OPT_JOBS, name = "-j", value = a + 2;   /* -j8 */
        if (id < 0 && strncmp(a, "--set=", 6) == 0) return usage("%s: write --set name=value", a);
        if (id < 0) return usage("unknown option %s", a);
        if (!takes(option_specs[id].commands, o->command))
            return usage("%s does not apply to seamcook %s", a, o->command);
        bool joined = value != NULL;   /* -j8 */
        if (option_specs[id].value && !value) {
            if (i + 1 >= argc) return usage("%s needs a value", a);
            value = argv[++i];
        }
        int status = set_option(o, id, name, value);
        if (status != EXIT_OK) return status;
        if (id != OPT_ASSETS && id != OPT_ASSET_PARAM && id != OPT_OUT && id != OPT_HELP) {   /* farm: for each task */
            o->passed[o->npassed++] = a;
            if (option_specs[id].value && !joined) o->passed[o->npassed++] = value;
        }
        if (o->help) return EXIT_OK;   /* the rest does not matter */
    }
    if (o->jobs == 0) {
        long n = sysconf(_SC_NPROCESSORS_ONLN);
        o->jobs = n > 0 ? (int)n : 1;
    }
    if (o->cache_max_size == 0) {
        const char *env = getenv("SEAMCOOK_CACHE_MAX_SIZE");
        o->cache_max_size = DEFAULT_CACHE_MAX_SIZE;
        if (env && *env && parse_size(env, &o->cache_max_size) != 0)
            return usage("SEAMCOOK_CACHE_MAX_SIZE=%s: expected a size like 500M or 10G", env);
    }
    return EXIT_OK;
}

static void free_options(options *o) {
    for (int i = 0; i < o->nsettings; i++) free((char *)o->settings[i].name);
    free(o->settings);
    free(o->files);
    free(o->remote_headers);
    free(o->passed);
}

/* ---------------------------------------------------------------- the cache */

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

/* The exit status an error stands for. */
static int exit_status_of(int rc) {
    return rc == SC_OK ? EXIT_OK : rc == SC_EUSAGE ? EXIT_USAGE : EXIT_FAIL;
}

/* Open the cache; a failure is printed and kept in err. */
static int open_cache(const options *o, sc_cache **cache, sc_error *err) {
    char *dir = o->cache_dir ? sc_strdup(o->cache_dir) : default_cache_dir();
    int rc;
    if (!dir && !o->cache_dir)
        rc = sc_fail(err, SC_EUSAGE, "no cache directory: HOME is not set; give --cache DIR or set SEAMCOOK_CACHE");
    else
        rc = dir ? sc_cache_open(dir, cache, err) : sc_fail(err, SC_ENOMEM, "out of memory");
    if (rc != SC_OK) fprintf(stderr, "seamcook: %s\n", err->message);   /* the message names the cache */
    else if (sc_cache_notice(*cache)) fprintf(stderr, "seamcook: note: %s\n", sc_cache_notice(*cache));
    free(dir);
    return exit_status_of(rc);
}

/* After cooking: trim the cache to its maximum size, least recently used
 * first. The sum is one indexed query; gc, which scans the store, runs only
 * past the limit. A trim that fails is worth a note, not a failed cook. */
static void trim_cache(sc_cache *cache, const options *o) {
    sc_cache_stats st;
    sc_cache_gc_result gr;
    sc_error err;
    if (o->dry_run || sc_cache_stats_get(cache, &st, &err) != SC_OK || st.blob_bytes <= o->cache_max_size) return;
    if (sc_cache_gc(cache, o->cache_max_size, &gr, &err) != SC_OK)
        fprintf(stderr, "seamcook: note: the cache was not trimmed: %s\n", err.message);
    else if (!o->quiet)
        fprintf(stderr, "cache trimmed to its maximum size (%.1f MiB): %lld blobs (%.1f MiB) removed\n",
                o->cache_max_size / 1048576.0, (long long)gr.blobs_removed, gr.bytes_removed / 1048576.0);
}

/* ---------------------------------------------------------------- building */

/* --asset-root DIR: the asset_root of every node that has one (load_atlas),
 * as an absolute path, so that it enters their keys like any PATH; a node
 * whose asset_root a --set NODE.asset_root gives keeps that. */
static int set_asset_root(sc_graph *g, const options *o, sc_error *err) {
    const char *dir = o->asset_root;
    struct stat st;
    if (stat(dir, &st) != 0 || !S_ISDIR(st.st_mode))
        return sc_fail(err, SC_EUSAGE, "--asset-root %s: not a folder", dir);
    char cwd[PATH_MAX];
    char *abs = dir[0] == '/' ? sc_strdup(dir) : getcwd(cwd, sizeof cwd) ? sc_path_join(cwd, dir) : NULL;
    if (!abs) return sc_fail(err, SC_EINPUT, "--asset-root %s: cannot make it absolute", dir);
    for (int i = 0; i < g->count; i++) {
        const char *name = g->nodes[i].name;
        int p = sc_desc_param(g->nodes[i].desc, "asset_root");
        bool given = false;
        for (int k = 0; k < o->nsettings && p >= 0 && !given; k++)
            given = !strncmp(o->settings[k].name, name, strlen(name)) &&
                    !strcmp(o->settings[k].name + strlen(name), ".asset_root");
        if (p < 0 || given) continue;
        free(g->nodes[i].params[p].string);
        g->nodes[i].params[p].string = sc_strdup(abs);
    }
    free(abs);
    return SC_OK;
}

static int build_graph(const char *file, const options *o, sc_graph **g, sc_error *err) {
    int ntypes;
    const sc_node_desc *const *types = sc_registry_all(&ntypes);
    const sc_lua_limits limits = {.max_seconds = o->lua_timeout};
    int rc = sc_lua_build(file, types, ntypes, o->settings, o->nsettings, &limits, g, err);
    if (rc == SC_OK && o->asset_root) rc = set_asset_root(*g, o, err);
    if (rc != SC_OK) {
        sc_graph_free(*g);
        *g = NULL;
    }
    return rc;
}

/* ---------------------------------------------------------------- cooking */

static int write_text(const char *out_dir, const char *name, char *text, sc_error *err) {
    char *path = sc_path_join(out_dir, name);
    int rc = (text && path) ? sc_make_dirs(out_dir, err) : sc_fail(err, SC_ENOMEM, "out of memory");
    if (rc == SC_OK) rc = sc_write_file_atomic(path, text, strlen(text), err);
    free(text), free(path);
    return rc;
}

/* report.json, report.html and the manifest: a run that cooked every node
 * removes what an earlier one wrote and this one did not. */
static int write_outputs(const sc_run *run, const char *out_dir, bool complete, sc_cache *cache, const options *o,
                         sc_error *err) {
    int rc = write_text(out_dir, "report.json", sc_run_report_json(run), err);
    if (rc == SC_OK) rc = write_text(out_dir, "report.html", sc_run_report_html(run), err);
    if (rc == SC_OK) rc = sc_manifest_update(out_dir, run, complete, cache, o->quiet ? NULL : stderr, err);
    return rc;
}

/* sc_golden_check with its lines on stderr and, when some failed, in
 * failure too (for the JUnit file). Returns how many failed. */
static int check_goldens(const sc_run *run, const char *out_dir, bool update, sc_error *failure) {
    char *text = NULL;
    size_t len = 0;
    FILE *log = open_memstream(&text, &len);
    int bad = sc_golden_check(run, out_dir, update, log ? log : stderr);
    if (log && fclose(log) == 0 && text) {
        fputs(text, stderr);
        if (bad) sc_fail(failure, SC_EINPUT, "%s", text);
    }
    free(text);
    return bad;
}

/* What cooking one graph file left: the graph and the results (either may
 * be NULL) and, when something failed, the message printed for it. */
typedef struct cooked {
    sc_graph *graph;
    sc_run *run;
    sc_error failure;
} cooked;

static void cooked_free(cooked *c) {
    sc_run_free(c->run);
    sc_graph_free(c->graph);
    memset(c, 0, sizeof *c);
}

/* Every node's warnings, one line each on stderr; returns how many. */
static int print_warnings(const sc_run *run) {
    int count = 0;
    for (int i = 0; i < run->graph->count; i++) {
        const sc_graph_node *n = &run->graph->nodes[i];
        for (int k = 0; k < run->results[i].nwarnings; k++, count++)
            fprintf(stderr, "seamcook: warning: %s:%d: %s: %s\n", n->file, n->line, n->name, run->results[i].warnings[k]);
    }
    return count;
}

/* ---------------------------------------------------------------- the remote cache */

/* One remote setting: the command line's, else the environment's, else the
 * project file's. */
static const char *env_of(const char *name) {
    const char *v = getenv(name);
    return v && *v ? v : NULL;
}

/* The remote cache for a graph file, from --remote-* options, then
 * SEAMCOOK_REMOTE_* variables, then seamcook.conf beside the graph file;
 * *out stays NULL when none of them names one. */
static int open_remote(const char *graph_file, const options *o, sc_cache *cache, sc_remote **out, sc_error *err) {
    *out = NULL;
    sc_config fc;
    sc_config_init(&fc);
    char *dir = sc_path_dirname(graph_file);
    int rc = dir ? sc_config_load(dir, &fc, err) : sc_fail(err, SC_ENOMEM, "out of memory");
    free(dir);
    const char *url = o->remote_cache ? o->remote_cache : env_of("SEAMCOOK_REMOTE_CACHE") ? env_of("SEAMCOOK_REMOTE_CACHE")
                                                                                          : fc.remote_cache;
    sc_remote_config rc_cfg = {.url = url, .timeout = fc.timeout, .retries = fc.retries,
                               .read_only = fc.read_only == 1, .log = o->quiet ? NULL : stderr};
    const char *env_header = env_of("SEAMCOOK_REMOTE_HEADER");
    char *env_headers = NULL;
    const char **headers = NULL;
    if (o->nremote_headers) {
        rc_cfg.headers = o->remote_headers, rc_cfg.nheaders = o->nremote_headers;
    } else if (env_header) {   /* several: one a line */
        env_headers = sc_strdup(env_header);
        headers = calloc(strlen(env_header) + 1, sizeof *headers);
        int n = 0;
        for (char *line = env_headers ? strtok(env_headers, "\n") : NULL; line && headers; line = strtok(NULL, "\n"))
            headers[n++] = line;
        rc_cfg.headers = headers, rc_cfg.nheaders = n;
        if (rc == SC_OK && (!env_headers || !headers)) rc = sc_fail(err, SC_ENOMEM, "out of memory");
    } else {
        rc_cfg.headers = (const char *const *)fc.headers, rc_cfg.nheaders = fc.nheaders;
    }
    const char *v;
    bool b;
    char *end;
    if (o->remote_read_only) rc_cfg.read_only = true;
    else if ((v = env_of("SEAMCOOK_REMOTE_READ_ONLY")) && rc == SC_OK) {
        if (!sc_parse_bool(v, &b)) rc = sc_fail(err, SC_EUSAGE, "SEAMCOOK_REMOTE_READ_ONLY=%s: expected true or false", v);
        rc_cfg.read_only = b;
    }
    if (o->remote_timeout > 0) rc_cfg.timeout = o->remote_timeout;
    else if ((v = env_of("SEAMCOOK_REMOTE_TIMEOUT")) && rc == SC_OK) {
        rc_cfg.timeout = strtod(v, &end);
        if (end == v || *end || !(rc_cfg.timeout > 0) || rc_cfg.timeout > 3600)
            rc = sc_fail(err, SC_EUSAGE, "SEAMCOOK_REMOTE_TIMEOUT=%s: expected seconds, more than 0", v);
    }
    if (o->remote_retries >= 0) rc_cfg.retries = o->remote_retries;
    else if ((v = env_of("SEAMCOOK_REMOTE_RETRIES")) && rc == SC_OK) {
        long n = strtol(v, &end, 10);
        if (end == v || *end || n < 0 || n > 10)
            rc = sc_fail(err, SC_EUSAGE, "SEAMCOOK_REMOTE_RETRIES=%s: expected a number from 0 to 10", v);
        rc_cfg.retries = (int)n;
    }
    if (rc == SC_OK && url && *url) rc = sc_remote_open(&rc_cfg, cache, out, err);
    free(headers);
    free(env_headers);
    sc_config_free(&fc);
    return rc;
}

/* Finish the uploads and say what the remote did. */
static void close_remote(sc_remote *remote, const options *o) {
    if (!remote) return;
    sc_remote_flush(remote);
    sc_remote_stats st;
    sc_remote_stats_get(remote, &st);
    sc_remote_close(remote);
    if (o->quiet) return;
    fprintf(stderr, "remote cache: %lld of %lld lookups hit (%lld blobs, %.1f MB down); %lld actions uploaded "
                    "(%lld blobs, %.1f MB up; %lld already there); %lld blobs with wrong bytes\n",
            (long long)st.ac_hits, (long long)(st.ac_hits + st.ac_misses), (long long)st.blobs_downloaded,
            st.bytes_downloaded / 1e6, (long long)st.actions_uploaded, (long long)st.blobs_uploaded,
            st.bytes_uploaded / 1e6, (long long)st.blobs_present, (long long)st.bad_blobs);
}

/* Cook one graph file into out_dir; returns the exit status. */
static int cook(const char *file, const options *o, sc_cache *cache, const char *out_dir, bool check, cooked *c) {
    memset(c, 0, sizeof *c);
    int rc = build_graph(file, o, &c->graph, &c->failure);
    if (rc != SC_OK) {
        fprintf(stderr, "seamcook: %s\n", c->failure.message);
        return exit_status_of(rc);
    }
    const sc_graph *g = c->graph;
    sc_remote *remote = NULL;
    rc = o->dry_run ? SC_OK : open_remote(file, o, cache, &remote, &c->failure);
    if (rc != SC_OK) {
        fprintf(stderr, "seamcook: %s\n", c->failure.message);
        return exit_status_of(rc);
    }
    sc_engine_options eo = {
        .jobs = o->jobs, .out_dir = out_dir, .dry_run = o->dry_run, .explain = o->explain,
        .log = o->quiet ? NULL : stderr, .live = !o->quiet && isatty(2), .base_dir = o->base_dir,
        .remote = remote,
    };
    bool writes = out_dir && !o->dry_run;
    if (writes) sc_remove_stale_tmp(out_dir, NULL);   /* a killed run's half-written files */
    rc = sc_engine_run(g, cache, &eo, &c->run, &c->failure);
    if (rc != SC_OK) fprintf(stderr, "seamcook: %s\n", c->failure.message);
    sc_error err = {0};
    if (c->run && writes && write_outputs(c->run, out_dir, rc == SC_OK, cache, o, &err) != SC_OK) {
        fprintf(stderr, "seamcook: %s\n", err.message);
        if (rc == SC_OK) {
            rc = err.code ? err.code : SC_EIO;
            c->failure = err;
        }
    }
    close_remote(remote, o);
    const sc_run *run = c->run;
    int warnings = run ? print_warnings(run) : 0;
    if (run && !o->quiet)
        fprintf(stderr, "%s: %d nodes, %d cooked, %d cached, %d failed, %d skipped in %.3f s%s%s\n",
                file, g->count, run->ran, run->cached, run->failed, run->skipped, run->seconds,
                writes ? "; report: " : "", writes ? out_dir : "");
    if (run && rc == SC_OK && check && writes && check_goldens(run, out_dir, false, &c->failure) > 0) rc = SC_EINPUT;
    if (rc == SC_OK && o->strict && warnings > 0) {
        rc = sc_fail(&c->failure, SC_EINPUT, "%s: %d warning%s, and --strict", file, warnings, warnings == 1 ? "" : "s");
        fprintf(stderr, "seamcook: %s\n", c->failure.message);
    }
    return rc == SC_OK ? EXIT_OK : EXIT_FAIL;
}

static int cmd_run(const options *o) {
    if (o->nfiles != 1) return usage("%s", "run needs exactly one graph file");
    sc_cache *cache = NULL;
    cooked c = {0};
    int status = open_cache(o, &cache, &c.failure);
    if (status == EXIT_OK) {
        status = cook(o->files[0], o, cache, o->out_dir ? o->out_dir : "out", o->check, &c);
        trim_cache(cache, o);
    }
    if (o->json) {
        char *summary = sc_run_summary_json(o->files[0], c.run, status, status ? c.failure.message : NULL);
        if (summary) puts(summary);
        free(summary);
    }
    cooked_free(&c);
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

static void watch_rebuild(uv_timer_t *timer) {
    watcher *w = timer->data;
    close_watches(w);
    char graph[PATH_MAX];
    if (!realpath(w->o->files[0], graph)) snprintf(graph, sizeof graph, "%s", w->o->files[0]);
    sc_digest graph_seen = {0};
    sc_error ignored;
    sc_cache_file_digest(w->cache, graph, &graph_seen, &ignored);
    cooked c;
    cook(w->o->files[0], w->o, w->cache, w->out_dir, w->o->check, &c);
    trim_cache(w->cache, w->o);
    const sc_run *run = c.run;
    const sc_graph *g = c.graph;
    w->runs++;
    sc_release_memory();   /* a watch waits long between cooks */
    /* the graph file itself plus every file any node read or found missing */
    int cap = 1, n = 0;
    if (run)
        for (int i = 0; i < g->count; i++) cap += run->results[i].ndeps;
    char **files = calloc((size_t)cap + 1, sizeof(char *));
    if (files && (files[n] = sc_strdup(graph))) n++;
    for (int i = 0; files && run && i < g->count; i++)
        for (int d = 0; d < run->results[i].ndeps; d++)
            if ((files[n] = sc_strdup(run->results[i].deps[d]))) n++;
    if (files) watch_files(w, files, n);
    /* a change that landed while the cook ran is cooked next, not lost */
    bool stale = sc_cache_file_changed(w->cache, graph, &graph_seen, NULL);
    for (int i = 0; run && !stale && i < g->count; i++)
        for (int d = 0; run->results[i].dep_digests && !stale && d < run->results[i].ndeps; d++)
            stale = sc_cache_file_changed(w->cache, run->results[i].deps[d], &run->results[i].dep_digests[d], NULL);
    for (int k = 0; files && k < n; k++) free(files[k]);
    free(files);
    cooked_free(&c);
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
    sc_cache *cache = NULL;
    sc_error err;
    int opened = open_cache(o, &cache, &err);
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

/* A graph test file's own output folder: OUT/<file name up to its first '.'>. */
static char *test_out_dir(const options *o, const char *file) {
    const char *base = strrchr(file, '/') ? strrchr(file, '/') + 1 : file;
    return sc_strprintf("%s/%.*s", o->out_dir ? o->out_dir : "out/test", (int)strcspn(base, "."), base);
}

static int write_junit(const char *path, const sc_test_case *cases, int n) {
    char *xml = sc_junit_xml(cases, n);
    sc_error err = {0};
    int rc = xml ? sc_write_file_atomic(path, xml, strlen(xml), &err) : sc_fail(&err, SC_ENOMEM, "out of memory");
    if (rc != SC_OK) fprintf(stderr, "seamcook: --junit %s: %s\n", path, err.message);
    free(xml);
    return rc;
}

static int cmd_test(const options *o) {
    if (o->nfiles == 0) return usage("%s", "test needs graph test files");
    sc_cache *cache = NULL;
    sc_error err;
    int opened = open_cache(o, &cache, &err);
    if (opened != EXIT_OK) return opened;
    sc_test_case *cases = calloc((size_t)o->nfiles, sizeof *cases);
    char **failures = calloc((size_t)o->nfiles, sizeof *failures);
    int passed = 0, failed = 0;
    for (int f = 0; cases && failures && f < o->nfiles; f++) {
        const char *file = o->files[f];
        char *out = test_out_dir(o, file);
        cooked c = {0};
        double t0 = sc_now();
        int status = out ? cook(file, o, cache, out, false, &c) : EXIT_FAIL;
        if (!out) sc_fail(&c.failure, SC_ENOMEM, "out of memory");
        int bad = status == EXIT_OK ? check_goldens(c.run, out, o->update_goldens, &c.failure) : 1;
        if (status == EXIT_OK && c.graph->nexpect == 0) {
            fprintf(stderr, "%s: states no expectation\n", file);
            sc_fail(&c.failure, SC_EINPUT, "%s: states no expectation", file);
            bad = 1;
        }
        if (bad) failed++;
        else passed++;
        printf("%s %s (%d expectations)\n", bad ? "FAIL" : "ok  ", file, c.graph ? c.graph->nexpect : 0);
        cases[f] = (sc_test_case){.name = file, .seconds = sc_now() - t0};
        if (bad) cases[f].failure = failures[f] = sc_strdup(c.failure.message[0] ? c.failure.message : "failed");
        cooked_free(&c);
        free(out);
    }
    trim_cache(cache, o);
    sc_cache_close(cache);
    printf("%d passed, %d failed\n", passed, failed);
    int status = failed || !cases || !failures ? EXIT_FAIL : EXIT_OK;
    if (o->junit && cases && failures && write_junit(o->junit, cases, o->nfiles) != SC_OK) status = EXIT_FAIL;
    for (int f = 0; failures && f < o->nfiles; f++) free(failures[f]);
    free(failures), free(cases);
    return status;
}

/* ---------------------------------------------------------------- cache, nodes, graph, version */

static int cmd_cache(const options *o) {
    if (!o->subcommand) return usage("%s", "cache needs stats, verify or gc");
    if (strcmp(o->subcommand, "stats") && strcmp(o->subcommand, "verify") && strcmp(o->subcommand, "gc"))
        return usage("unknown cache command '%s'", o->subcommand);
    if (!strcmp(o->subcommand, "gc") && !o->max_size_given)
        return usage("%s", "gc needs --max-size");
    if (strcmp(o->subcommand, "gc") && o->max_size_given)
        return usage("--max-size goes with gc, not %s", o->subcommand);
    if (o->nfiles) return usage("cache %s: unexpected argument '%s'", o->subcommand, o->files[0]);
    sc_cache *cache = NULL;
    sc_error err = {0};
    int opened = open_cache(o, &cache, &err);
    if (opened != EXIT_OK) return opened;
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

static int cmd_nodes(const options *o) {
    if (o->nfiles) return usage("nodes: unexpected argument '%s'", o->files[0]);
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
    sc_error err;
    int rc = build_graph(o->files[0], o, &g, &err);
    if (rc != SC_OK) {
        fprintf(stderr, "seamcook: %s\n", err.message);
        return exit_status_of(rc);
    }
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

static int cmd_version(const options *o) {
    if (o->nfiles) return usage("version: unexpected argument '%s'", o->files[0]);
    printf("seamcook %s\n", SC_VERSION);
    return EXIT_OK;
}

/* ---------------------------------------------------------------- farm */

static int cmd_farm(const options *o) {
    if (!o->subcommand) return usage("%s", "farm needs submit or status");
    sc_error err = {0};
    const char *out_dir = o->out_dir ? o->out_dir : "out";
    if (!strcmp(o->subcommand, "status")) {
        if (o->nfiles) return usage("farm status: unexpected argument '%s'", o->files[0]);
        int unfinished, failed;
        int rc = sc_farm_status(out_dir, stdout, &unfinished, &failed, &err);
        if (rc != SC_OK) fprintf(stderr, "seamcook: %s\n", err.message);
        return rc != SC_OK ? exit_status_of(rc) : failed ? EXIT_FAIL : EXIT_OK;
    }
    if (strcmp(o->subcommand, "submit")) return usage("unknown farm command '%s'", o->subcommand);
    if (o->nfiles != 1) return usage("%s", "farm submit needs exactly one graph file");
    if (!o->assets) return usage("%s", "farm submit needs --assets LIST");
    char self[4096];
    ssize_t n = readlink("/proc/self/exe", self, sizeof self - 1);
    if (n <= 0) return usage("%s", "farm submit: cannot find the seamcook command itself");
    self[n] = 0;
    char cwd[4096];
    char *graph = getcwd(cwd, sizeof cwd) ? sc_path_resolve(cwd, o->files[0]) : NULL;
    struct stat st;
    if (!graph || stat(graph, &st) != 0 || !S_ISREG(st.st_mode)) {
        free(graph);
        return usage("farm submit: %s: not a file", o->files[0]);
    }
    sc_farm_job job = {.seamcook = self, .graph = graph, .assets = o->assets,
                       .param = o->asset_param ? o->asset_param : "mesh", .out_dir = out_dir,
                       .run_args = o->passed, .nrun_args = o->npassed};
    char *id = NULL;
    int rc = sc_farm_submit(&job, &id, &err);
    if (rc != SC_OK) fprintf(stderr, "seamcook: %s\n", err.message);
    else printf("%s\n", id);
    if (rc == SC_OK && !o->quiet) fprintf(stderr, "submitted job %s; seamcook farm status --out %s\n", id, out_dir);
    free(id), free(graph);
    return exit_status_of(rc);
}

static const struct command {
    const char *name;
    const char *usage;
    int (*run)(const options *o);
} commands[] = {
    {"run", run_usage, cmd_run},
    {"watch", watch_usage, cmd_watch},
    {"test", test_usage, cmd_test},
    {"cache", cache_usage, cmd_cache},
    {"farm", farm_usage, cmd_farm},
    {"nodes", nodes_usage, cmd_nodes},
    {"graph", graph_usage, cmd_graph},
    {"version", version_usage, cmd_version},
};

int main(int argc, char **argv) {
    const char *first = argc > 1 ? argv[1] : "";
    if (!strcmp(first, "--version")) argv[1] = "version";
    if (!strcmp(first, "help") && argc > 2) {   /* seamcook help COMMAND */
        argv[1] = argv[2];
        argv[2] = "--help";
    } else if (!strcmp(first, "--help") || !strcmp(first, "-h") || !strcmp(first, "help")) {
        fputs(general_usage, stdout);
        return EXIT_OK;
    }
    const struct command *cmd = NULL;
    for (size_t i = 0; argc > 1 && i < sizeof commands / sizeof commands[0]; i++)
        if (!strcmp(argv[1], commands[i].name)) cmd = &commands[i];
    if (!cmd) return argc > 1 ? usage("unknown command '%s'", argv[1]) : usage("%s", "no command given");
    options o;
    int status = parse_args(argc, argv, &o);
    if (status == EXIT_OK && o.help) fputs(cmd->usage, stdout);
    if (status != EXIT_OK || o.help) {
        free_options(&o);
        return status;
    }
    sc_tune_allocator();
    /* the thread pool is sized once, at its first use: cooking jobs, the
     * stores of the nodes they cooked, and loads */
    char pool[16];
    snprintf(pool, sizeof pool, "%d", 2 * o.jobs + 1);
    setenv("UV_THREADPOOL_SIZE", pool, 1);
    status = cmd->run(&o);
    free_options(&o);
    return status;
}
