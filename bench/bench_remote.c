/* bench_remote.c - the remote cache on loopback: hit latency and throughput.
 *
 *   bench_remote [URL]
 *
 * Without a URL it starts nginx (WebDAV PUT) on a random loopback port with
 * a temporary prefix, as tests/farm/remote_server.sh does, and stops it at
 * the end; nginx must be on PATH. Through sc_remote directly (no graph, no
 * node):
 *
 * 1. small actions: 500 actions of one 4 KiB blob each, uploaded (queued,
 *    then flushed) into an empty prefix, then fetched into a fresh local
 *    cache one by one: actions/s both ways, and the latency of one remote
 *    hit (median and 90th percentile; a hit is GET ac, GET record, GET blob);
 * 2. large blobs: 8 actions of one 32 MiB blob each: MB/s up and down;
 * 3. a miss: GET ac answered 404 (median latency).
 */
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <unistd.h>

#include "sc_cache.h"
#include "sc_remote.h"

static int cmp_double(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

static void die(const char *what, const sc_error *err) {
    fprintf(stderr, "bench_remote: %s: %s\n", what, err ? err->message : "");
    exit(1);
}

/* nginx on a random port under dir; its pid, and the URL in url. */
static pid_t start_nginx(const char *dir, char *url, size_t n) {
    for (int attempt = 0; attempt < 8; attempt++) {
        int port = 20000 + (int)(((unsigned)getpid() * 7919u + (unsigned)attempt * 104729u) % 40000u);
        char *conf = sc_strprintf("%s/nginx.conf", dir);
        FILE *f = fopen(conf, "w");
        if (!f) die("cannot write nginx.conf", NULL);
        fprintf(f,
                "daemon off; master_process off; worker_processes 1; pid %s/nginx.pid; error_log %s/error.log;\n"
                "events { worker_connections 256; }\n"
                "http { access_log off; client_body_temp_path %s/body; client_max_body_size 0;\n"
                "  server { listen 127.0.0.1:%d; root %s/store; dav_methods PUT; create_full_put_path on; } }\n",
                dir, dir, dir, port, dir);
        fclose(f);
        char *body = sc_strprintf("%s/body", dir), *store = sc_strprintf("%s/store", dir);
        sc_make_dirs(body, NULL);
        sc_make_dirs(store, NULL);
        pid_t pid = fork();
        if (pid == 0) {
            execlp("nginx", "nginx", "-p", dir, "-c", conf, "-e", "stderr", (char *)NULL);
            _exit(127);
        }
        free(conf), free(body), free(store);
        usleep(300000);
        int status;
        if (waitpid(pid, &status, WNOHANG) == 0) {
            snprintf(url, n, "http://127.0.0.1:%d", port);
            return pid;
        }
    }
    die("nginx did not start (is it installed?)", NULL);
    return -1;
}

typedef struct set {
    int n;
    sc_digest *keys;
} set;

/* n actions of one blob of `size` bytes each into the local cache c. */
static set make_actions(sc_cache *c, int n, size_t size, unsigned seed) {
    set s = {n, calloc((size_t)n, sizeof(sc_digest))};
    uint8_t *bytes = malloc(size);
    sc_error err;
    for (int i = 0; i < n; i++) {
        for (size_t k = 0; k < size; k++) bytes[k] = (uint8_t)((k * 31u + (unsigned)i * 7u + seed) >> 3);
        memcpy(bytes, &i, sizeof i);
        sc_digest blob;
        sc_digest_bytes(bytes, size, &blob);
        if (sc_cache_put_blob(c, &blob, bytes, size, &err) != SC_OK) die("put_blob", &err);
        char *key_text = sc_strprintf("bench action %u %d", seed, i);
        sc_digest_bytes(key_text, strlen(key_text), &s.keys[i]);
        free(key_text);
        sc_cache_action a = {.key = s.keys[i], .node_type = "bench", .outputs = "{}", .metrics = "{}",
                             .nblobs = 1, .blobs = &blob};
        if (sc_cache_put_action(c, &a, &err) != SC_OK) die("put_action", &err);
    }
    free(bytes);
    return s;
}

static double upload_all(sc_cache *c, const char *url, const set *s) {
    sc_remote_config cfg = {.url = url, .log = stderr};
    sc_remote *r;
    sc_error err;
    if (sc_remote_open(&cfg, c, &r, &err) != SC_OK) die("open", &err);
    double t = sc_now();
    for (int i = 0; i < s->n; i++) {
        sc_cache_action a;
        if (sc_cache_get_action(c, &s->keys[i], &a, &err) != SC_OK) die("get_action", &err);
        if (sc_remote_upload(r, &a, &err) != SC_OK) die("upload", &err);
        sc_cache_action_free(&a);
    }
    sc_remote_flush(r);
    t = sc_now() - t;
    sc_remote_stats st;
    sc_remote_stats_get(r, &st);
    if (st.actions_uploaded != s->n) die("not every action was uploaded", NULL);
    sc_remote_close(r);
    return t;
}

/* Fetch every action into the fresh cache at dir; per-fetch seconds into lat. */
static double fetch_all(const char *dir, const char *url, const set *s, double *lat) {
    sc_cache *c;
    sc_error err;
    if (sc_cache_open(dir, &c, &err) != SC_OK) die("open cache", &err);
    sc_remote_config cfg = {.url = url, .read_only = true, .log = stderr};
    sc_remote *r;
    if (sc_remote_open(&cfg, c, &r, &err) != SC_OK) die("open", &err);
    double t = sc_now();
    for (int i = 0; i < s->n; i++) {
        double t1 = sc_now();
        if (sc_remote_fetch(r, &s->keys[i], &err) != SC_OK) die("fetch", &err);
        if (lat) lat[i] = sc_now() - t1;
    }
    t = sc_now() - t;
    sc_remote_close(r);
    sc_cache_close(c);
    return t;
}

int main(int argc, char **argv) {
    char tmp[] = "/tmp/sc-bench-remote-XXXXXX";
    if (!mkdtemp(tmp)) return 1;
    char url[128];
    pid_t nginx = 0;
    if (argc > 1) {
        snprintf(url, sizeof url, "%s", argv[1]);
    } else {
        char *ngx = sc_strprintf("%s/nginx", tmp);
        sc_make_dirs(ngx, NULL);
        nginx = start_nginx(ngx, url, sizeof url);
        free(ngx);
    }
    printf("remote: %s%s\n", url, nginx ? " (nginx on loopback, started here)" : "");
    char *src_dir = sc_strprintf("%s/src", tmp);
    sc_cache *src;
    sc_error err;
    if (sc_cache_open(src_dir, &src, &err) != SC_OK) die("open cache", &err);

    /* 1. small actions */
    char *small_url = sc_strprintf("%s/small", url);
    set small = make_actions(src, 500, 4096, 1);
    double up = upload_all(src, small_url, &small);
    double *lat = calloc((size_t)small.n, sizeof *lat);
    char *dst = sc_strprintf("%s/dst-small", tmp);
    double down = fetch_all(dst, small_url, &small, lat);
    qsort(lat, (size_t)small.n, sizeof *lat, cmp_double);
    printf("500 actions of one 4 KiB blob: upload %.0f actions/s (%.2f s); fetch %.0f actions/s (%.2f s)\n",
           small.n / up, up, small.n / down, down);
    printf("remote hit latency (GET ac + record + blob, into the local cache): median %.2f ms, p90 %.2f ms, "
           "max %.2f ms\n", lat[small.n / 2] * 1e3, lat[small.n * 9 / 10] * 1e3, lat[small.n - 1] * 1e3);

    /* 2. large blobs */
    char *big_url = sc_strprintf("%s/big", url);
    size_t big_size = (size_t)32 << 20;
    set big = make_actions(src, 8, big_size, 2);
    up = upload_all(src, big_url, &big);
    char *dst_big = sc_strprintf("%s/dst-big", tmp);
    down = fetch_all(dst_big, big_url, &big, NULL);
    double mb = big.n * (double)big_size / 1e6;
    printf("8 actions of one 32 MiB blob (%.0f MB): upload %.0f MB/s (%.2f s), fetch and verify %.0f MB/s (%.2f s)\n",
           mb, mb / up, up, mb / down, down);

    /* 3. misses */
    sc_remote_config cfg = {.url = small_url, .read_only = true, .log = stderr};
    sc_remote *r;
    if (sc_remote_open(&cfg, src, &r, &err) != SC_OK) die("open", &err);
    for (int i = 0; i < 200; i++) {
        char *text = sc_strprintf("absent %d", i);
        sc_digest k;
        sc_digest_bytes(text, strlen(text), &k);
        free(text);
        double t = sc_now();
        if (sc_remote_fetch(r, &k, &err) != SC_EMISS) die("a miss was not a miss", &err);
        lat[i] = sc_now() - t;
    }
    sc_remote_stats st;
    sc_remote_stats_get(r, &st);
    if (st.disabled || st.ac_misses != 200) die("the misses did not reach the server", NULL);
    qsort(lat, 200, sizeof *lat, cmp_double);
    printf("remote miss latency (GET ac, 404): median %.2f ms, p90 %.2f ms\n", lat[100] * 1e3, lat[180] * 1e3);
    sc_remote_close(r);

    sc_cache_close(src);
    if (nginx > 0) {
        kill(nginx, SIGTERM);
        waitpid(nginx, NULL, 0);
    }
    char *rm = sc_strprintf("rm -rf %s", tmp);
    if (system(rm) != 0) fprintf(stderr, "bench_remote: could not remove %s\n", tmp);
    free(rm), free(lat), free(small.keys), free(big.keys), free(small_url), free(big_url), free(dst), free(dst_big),
        free(src_dir);
    return 0;
}
