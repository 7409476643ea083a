/* sc_remote.c - a remote cache over Bazel's HTTP remote-cache protocol (see
 * sc_remote.h).
 *
 * Design note.
 *  - libcurl, one easy handle per thread: the caller's (lookups, on the
 *    thread that calls sc_remote_fetch) and the upload thread's. Requests
 *    carry the configured headers; the URL's user:password is Basic
 *    authentication, and ~/.netrc is read when the URL has none
 *    (CURL_NETRC_OPTIONAL). Messages show the URL without its password.
 *  - A request that fails in transport (refused, timed out, reset) or gets a
 *    5xx is tried again up to `retries` times, 100 ms, 200 ms, ... apart. A
 *    transport failure after that, a 401/403, or another unexpected status
 *    disables the remote: one warning, then no more requests, so a cook
 *    whose server is down costs at most one round of timeouts.
 *  - Downloads are read into memory, hashed, and put into the local cache
 *    only when they hash to the digest they were asked for. A blob whose
 *    bytes are wrong is remembered as bad: its upload then PUTs over the
 *    server's copy instead of trusting HEAD.
 *  - Uploads are a queue served by one thread, in order: per action, HEAD
 *    then PUT for each blob (streamed from the store's file), the record,
 *    and the ActionResult last. A blob the local cache no longer holds (gc
 *    ran) drops that action's upload.
 *  - The ActionResult is written and read by hand: a few varint and
 *    length-delimited fields, no protobuf library.
 */
#include "sc_remote.h"

#include <pthread.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>

#include <cjson/cJSON.h>
#include <curl/curl.h>

#define RECORD_PATH "seamcook/action.json"
static char record_path[] = RECORD_PATH;
#define BLOB_PREFIX "blobs/"
#define MAX_RECORD_BYTES ((size_t)64 << 20)
#define MAX_BLOB_BYTES ((int64_t)16 << 30)
#define MAX_RESULT_BYTES ((size_t)64 << 20)

typedef struct upload {
    struct upload *next;
    sc_digest key;
    char *record;            /* JSON */
    int nblobs;
    sc_digest *blobs;
} upload;

struct sc_remote {
    sc_remote_config cfg;
    void (*local_lock)(void *ud), (*local_unlock)(void *ud);   /* sc_remote_set_lock */
    void *local_ud;
    sc_cache *local;
    char *base;              /* the URL without a trailing slash */
    char *shown;             /* the URL as messages show it: no password */
    struct curl_slist *headers;
    CURL *fetcher;           /* the caller's handle */
    pthread_mutex_t lock;    /* everything below */
    pthread_cond_t wake, idle;
    upload *head, *tail;
    bool busy;               /* the upload thread is on a job */
    bool stopping;
    bool disabled, warned;
    sc_digest *bad;          /* blobs seen with wrong bytes on the server */
    int nbad, capbad;
    sc_remote_stats stats;
    pthread_t thread;
    bool thread_started;
};

/* ---------------------------------------------------------------- small helpers */

static void local_lock(sc_remote *r) {
    if (r->local_lock) r->local_lock(r->local_ud);
}

static void local_unlock(sc_remote *r) {
    if (r->local_unlock) r->local_unlock(r->local_ud);
}

void sc_remote_set_lock(sc_remote *r, void (*lock)(void *ud), void (*unlock)(void *ud), void *ud) {
    if (!r) return;
    r->local_lock = lock;
    r->local_unlock = unlock;
    r->local_ud = ud;
}

static void count(sc_remote *r, int64_t *field, int64_t by) {
    pthread_mutex_lock(&r->lock);
    *field += by;
    pthread_mutex_unlock(&r->lock);
}

static bool is_disabled(sc_remote *r) {
    pthread_mutex_lock(&r->lock);
    bool d = r->disabled;
    pthread_mutex_unlock(&r->lock);
    return d;
}

/* Leave the server alone from now on, saying why once. */
static void give_up(sc_remote *r, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static void give_up(sc_remote *r, const char *fmt, ...) {
    char why[512];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(why, sizeof why, fmt, ap);
    va_end(ap);
    pthread_mutex_lock(&r->lock);
    r->disabled = true;
    r->stats.disabled = true;
    bool say = !r->warned;
    r->warned = true;
    pthread_mutex_unlock(&r->lock);
    if (say && r->cfg.log) {
        fprintf(r->cfg.log, "seamcook: warning: remote cache %s: %s; cooking without it\n", r->shown, why);
        fflush(r->cfg.log);
    }
}

static bool is_bad(sc_remote *r, const sc_digest *d) {
    pthread_mutex_lock(&r->lock);
    bool bad = false;
    for (int i = 0; i < r->nbad && !bad; i++) bad = sc_digest_equal(&r->bad[i], d);
    pthread_mutex_unlock(&r->lock);
    return bad;
}

static void mark_bad(sc_remote *r, const sc_digest *d) {
    if (is_bad(r, d)) return;
    pthread_mutex_lock(&r->lock);
    r->stats.bad_blobs++;
    if (r->nbad == r->capbad) {
        int cap = r->capbad ? 2 * r->capbad : 16;
        sc_digest *grown = sc_realloc_array(r->bad, (size_t)cap, sizeof *grown);
        if (grown) r->bad = grown, r->capbad = cap;
    }
    if (r->nbad < r->capbad) r->bad[r->nbad++] = *d;
    pthread_mutex_unlock(&r->lock);
}

static void sleep_ms(long ms) {
    struct timespec ts = {ms / 1000, (ms % 1000) * 1000000L};
    nanosleep(&ts, NULL);
}

/* ---------------------------------------------------------------- HTTP */

typedef struct request {
    CURL *h;
    const char *method;      /* GET, HEAD, PUT */
    const char *ns;          /* "cas" or "ac" */
    const sc_digest *name;
    sc_buf *body;            /* GET: the answer's body */
    size_t max_body;
    FILE *file;              /* PUT: from a file ... */
    const void *mem;         /* ... or from memory */
    size_t len, sent;
    int64_t size;
    bool too_large;          /* GET: the body passed max_body */
} request;

static size_t on_body(char *p, size_t size, size_t n, void *ud) {
    request *q = ud;
    size_t bytes = size * n;
    long status = 0;
    curl_easy_getinfo(q->h, CURLINFO_RESPONSE_CODE, &status);
    if (status < 200 || status >= 300) return bytes;   /* the server's page about a 404 or a 401 */
    if (q->body->len + bytes > q->max_body) {   /* the transfer fails */
        q->too_large = true;
        return 0;
    }
    sc_buf_append(q->body, p, bytes);
    return q->body->failed ? 0 : bytes;
}

static size_t on_discard(char *p, size_t size, size_t n, void *ud) {
    (void)p, (void)ud;
    return size * n;
}

static size_t on_send(char *p, size_t size, size_t n, void *ud) {
    request *q = ud;
    if (q->file) return fread(p, 1, size * n, q->file);
    size_t left = q->len - q->sent, bytes = size * n < left ? size * n : left;
    memcpy(p, (const char *)q->mem + q->sent, bytes);
    q->sent += bytes;
    return bytes;
}

/* One request, retried on a transport error or a 5xx. SC_OK with *status
 * for an HTTP answer (any status), SC_EIO for a transport failure. */
static int http(sc_remote *r, CURL *h, request *q, long *status, sc_error *err) {
    char hex[65], *url;
    sc_digest_hex(q->name, hex);
    url = sc_strprintf("%s/%s/%s", r->base, q->ns, hex);   /* messages say "/ns/hex" */
    if (!url) return sc_fail(err, SC_ENOMEM, "out of memory");
    long timeout_ms = (long)(r->cfg.timeout * 1000);
    int rc = SC_EIO;
    q->h = h;
    for (int attempt = 0; attempt <= r->cfg.retries; attempt++) {
        if (attempt > 0) sleep_ms(100L << (attempt - 1 < 6 ? attempt - 1 : 6));
        curl_easy_reset(h);
        curl_easy_setopt(h, CURLOPT_URL, url);
        curl_easy_setopt(h, CURLOPT_NOSIGNAL, 1L);
        curl_easy_setopt(h, CURLOPT_HTTPHEADER, r->headers);
        curl_easy_setopt(h, CURLOPT_NETRC, (long)CURL_NETRC_OPTIONAL);
        curl_easy_setopt(h, CURLOPT_CONNECTTIMEOUT_MS, timeout_ms);
        curl_easy_setopt(h, CURLOPT_LOW_SPEED_LIMIT, 1L);
        curl_easy_setopt(h, CURLOPT_LOW_SPEED_TIME, timeout_ms / 1000 > 0 ? timeout_ms / 1000 : 1L);
        curl_easy_setopt(h, CURLOPT_PROTOCOLS_STR, "http,https");
        if (!strcmp(q->method, "HEAD")) {
            curl_easy_setopt(h, CURLOPT_NOBODY, 1L);
        } else if (!strcmp(q->method, "GET")) {
            sc_buf_reset(q->body);
            curl_easy_setopt(h, CURLOPT_WRITEFUNCTION, on_body);
            curl_easy_setopt(h, CURLOPT_WRITEDATA, q);
        } else {
            curl_easy_setopt(h, CURLOPT_WRITEFUNCTION, on_discard);   /* the server's page about the PUT */
            if (q->file) rewind(q->file);
            q->sent = 0;
            curl_easy_setopt(h, CURLOPT_UPLOAD, 1L);
            curl_easy_setopt(h, CURLOPT_READFUNCTION, on_send);
            curl_easy_setopt(h, CURLOPT_READDATA, q);
            curl_easy_setopt(h, CURLOPT_INFILESIZE_LARGE, (curl_off_t)q->size);
        }
        CURLcode cc = curl_easy_perform(h);
        if (cc == CURLE_OK) {
            curl_easy_getinfo(h, CURLINFO_RESPONSE_CODE, status);
            rc = SC_OK;
            if (*status < 500) break;
            sc_fail(err, SC_EIO, "%s /%s/%s: HTTP %ld", q->method, q->ns, hex, *status);
        } else if (cc == CURLE_WRITE_ERROR && q->too_large) {
            rc = sc_fail(err, SC_EINPUT, "%s /%s/%s: larger than the %zu bytes expected", q->method, q->ns, hex,
                         q->max_body);
            break;
        } else {
            rc = sc_fail(err, SC_EIO, "%s /%s/%s: %s", q->method, q->ns, hex, curl_easy_strerror(cc));
        }
    }
    free(url);
    return rc;
}

/* A status that disables the remote, with the reason; NULL for one the
 * caller handles (2xx, 404). */
static bool status_fatal(sc_remote *r, const char *method, const char *ns, long status) {
    if ((status >= 200 && status < 300) || status == 404) return false;
    if (status == 401 || status == 403)
        give_up(r, "%s /%s/ answered %ld %s: give credentials with --remote-header, user:password in the URL, "
                   "or ~/.netrc", method, ns, status, status == 401 ? "Unauthorized" : "Forbidden");
    else
        give_up(r, "%s /%s/ answered HTTP %ld", method, ns, status);
    return true;
}

/* GET a blob or an AC entry into body, at most max bytes. SC_OK, SC_EMISS
 * (404), or another code when the remote is now disabled. */
static int get(sc_remote *r, CURL *h, const char *ns, const sc_digest *name, sc_buf *body, size_t max,
               sc_error *err) {
    request q = {.method = "GET", .ns = ns, .name = name, .body = body, .max_body = max};
    long status = 0;
    int rc = http(r, h, &q, &status, err);
    if (rc == SC_EIO) {
        give_up(r, "%s", err->message);
        return rc;
    }
    if (rc != SC_OK) return rc;   /* too large: a miss, the server stays */
    if (status == 404) return sc_fail(err, SC_EMISS, "not on the remote");
    if (status_fatal(r, "GET", ns, status)) return sc_fail(err, SC_EIO, "remote disabled");
    return SC_OK;
}

/* ---------------------------------------------------------------- protobuf */

static void put_varint(sc_buf *b, uint64_t v) {
    while (v >= 0x80) {
        sc_buf_u8(b, (uint8_t)(v | 0x80));
        v >>= 7;
    }
    sc_buf_u8(b, (uint8_t)v);
}

static void put_bytes_field(sc_buf *b, int field, const void *p, size_t n) {
    put_varint(b, (uint64_t)field << 3 | 2);
    put_varint(b, n);
    sc_buf_append(b, p, n);
}

int sc_remote_encode_result(const sc_remote_output *outs, int n, sc_buf *out) {
    sc_buf file, digest;
    sc_buf_init(&file);
    sc_buf_init(&digest);
    for (int i = 0; i < n; i++) {
        char hex[65];
        sc_digest_hex(&outs[i].digest, hex);
        sc_buf_reset(&digest);
        put_bytes_field(&digest, 1, hex, 64);                     /* Digest.hash */
        put_varint(&digest, 2 << 3 | 0);                          /* Digest.size_bytes */
        put_varint(&digest, (uint64_t)outs[i].size);
        sc_buf_reset(&file);
        put_bytes_field(&file, 1, outs[i].path, strlen(outs[i].path));   /* OutputFile.path */
        put_bytes_field(&file, 2, digest.data, digest.len);               /* OutputFile.digest */
        put_bytes_field(out, 2, file.data, file.len);                     /* ActionResult.output_files */
    }
    /* exit_code 0 is proto3's default and so is not written */
    bool failed = file.failed || digest.failed || out->failed;
    sc_buf_free(&file);
    sc_buf_free(&digest);
    return failed ? SC_ENOMEM : SC_OK;
}

typedef struct pb {
    const uint8_t *p, *end;
} pb;

static bool get_varint(pb *r, uint64_t *v) {
    *v = 0;
    for (int shift = 0; shift < 64; shift += 7) {
        if (r->p >= r->end) return false;
        uint8_t byte = *r->p++;
        *v |= (uint64_t)(byte & 0x7f) << shift;
        if (!(byte & 0x80)) return true;
    }
    return false;
}

/* The next field: its number, wire type, and for a length-delimited one
 * its bytes (*sub), for a varint its value. */
static bool next_field(pb *r, int *field, int *type, pb *sub, uint64_t *value) {
    uint64_t tag;
    if (!get_varint(r, &tag) || tag >> 3 == 0 || tag >> 3 > 536870911) return false;
    *field = (int)(tag >> 3);
    *type = (int)(tag & 7);
    switch (*type) {
    case 0: return get_varint(r, value);
    case 1:
        if (r->end - r->p < 8) return false;
        r->p += 8;
        return true;
    case 2: {
        uint64_t n;
        if (!get_varint(r, &n) || n > (uint64_t)(r->end - r->p)) return false;
        sub->p = r->p;
        sub->end = r->p + n;
        r->p += n;
        return true;
    }
    case 5:
        if (r->end - r->p < 4) return false;
        r->p += 4;
        return true;
    default: return false;   /* groups (3, 4) are not in this message */
    }
}

/* Calls fn on every field of a message; false when the bytes are malformed
 * or fn refuses a field. */
typedef bool (*field_fn)(void *ud, int field, int type, pb sub, uint64_t value);

static bool each_field(pb r, field_fn fn, void *ud) {
    while (r.p < r.end) {
        int field, type;
        pb sub = {0};
        uint64_t v = 0;
        if (!next_field(&r, &field, &type, &sub, &v) || !fn(ud, field, type, sub, v)) return false;
    }
    return true;
}

/* Digest {hash = 1 (64 hex digits), size_bytes = 2} into o. */
static bool digest_field(void *ud, int field, int type, pb sub, uint64_t v) {
    sc_remote_output *o = ud;
    if (field == 1 && type == 2) {
        char hex[65];
        if (sub.end - sub.p != 64) return false;
        memcpy(hex, sub.p, 64);
        hex[64] = 0;
        return sc_digest_parse(hex, &o->digest) == 0 && (o->hashed = true);
    }
    if (field == 2 && type == 0) {
        if (v > (uint64_t)INT64_MAX) return false;
        o->size = (int64_t)v;
    }
    return true;
}

/* OutputFile {path = 1, digest = 2} into o. */
static bool file_field(void *ud, int field, int type, pb sub, uint64_t v) {
    (void)v;
    sc_remote_output *o = ud;
    if (field == 1 && type == 2) {
        free(o->path);
        o->path = sc_strndup((const char *)sub.p, (size_t)(sub.end - sub.p));
        return o->path && strlen(o->path) == (size_t)(sub.end - sub.p);   /* no NUL inside */
    }
    if (field == 2 && type == 2) return each_field(sub, digest_field, o) && o->hashed;
    return true;
}

void sc_remote_outputs_free(sc_remote_output *outs, int count) {
    for (int i = 0; outs && i < count; i++) free(outs[i].path);
    free(outs);
}

int sc_remote_decode_result(const void *bytes, size_t n, sc_remote_output **outs, int *count, sc_error *err) {
    *outs = NULL;
    *count = 0;
    pb r = {bytes, (const uint8_t *)bytes + n};
    sc_remote_output *list = NULL;
    int len = 0, cap = 0;
    while (r.p < r.end) {
        int field, type;
        pb sub = {0};
        uint64_t v = 0;
        if (!next_field(&r, &field, &type, &sub, &v)) {
            sc_remote_outputs_free(list, len);
            return sc_fail(err, SC_EINPUT, "the action result is not a well-formed protobuf");
        }
        if (field != 2 || type != 2) continue;
        if (len == cap) {
            cap = cap ? 2 * cap : 8;
            sc_remote_output *grown = sc_realloc_array(list, (size_t)cap, sizeof *grown);
            if (!grown) {
                sc_remote_outputs_free(list, len);
                return sc_fail(err, SC_ENOMEM, "out of memory");
            }
            list = grown;
        }
        memset(&list[len], 0, sizeof list[len]);
        bool ok = each_field(sub, file_field, &list[len]) && list[len].path && list[len].hashed;
        len++;
        if (!ok) {
            sc_remote_outputs_free(list, len);
            return sc_fail(err, SC_EINPUT, "output file %d of the action result is malformed", len);
        }
    }
    *outs = list;
    *count = len;
    return SC_OK;
}

/* ---------------------------------------------------------------- records */

char *sc_remote_record_encode(const sc_cache_action *a) {
    char hex[65];
    cJSON *o = cJSON_CreateObject();
    cJSON_AddNumberToObject(o, "format", 1);
    sc_digest_hex(&a->key, hex);
    cJSON_AddStringToObject(o, "key", hex);
    cJSON_AddStringToObject(o, "node_type", a->node_type ? a->node_type : "");
    cJSON_AddStringToObject(o, "outputs", a->outputs ? a->outputs : "");
    cJSON_AddStringToObject(o, "metrics", a->metrics ? a->metrics : "{}");
    cJSON_AddNumberToObject(o, "seconds", a->seconds);
    cJSON *deps = cJSON_AddArrayToObject(o, "deps");
    for (int i = 0; i < a->ndeps; i++) {
        cJSON *d = cJSON_CreateObject();
        cJSON_AddStringToObject(d, "path", a->deps[i].path);
        sc_digest_hex(&a->deps[i].digest, hex);
        cJSON_AddStringToObject(d, "digest", hex);
        cJSON_AddItemToArray(deps, d);
    }
    cJSON *blobs = cJSON_AddArrayToObject(o, "blobs");
    for (int i = 0; i < a->nblobs; i++) {
        sc_digest_hex(&a->blobs[i], hex);
        cJSON_AddItemToArray(blobs, cJSON_CreateString(hex));
    }
    char *text = cJSON_PrintUnformatted(o);
    cJSON_Delete(o);
    return text;
}

static bool digest_of(const cJSON *s, sc_digest *d) {
    return cJSON_IsString(s) && strlen(s->valuestring) == 64 && sc_digest_parse(s->valuestring, d) == 0;
}

static char *string_of(const cJSON *o, const char *name) {
    const cJSON *s = cJSON_GetObjectItemCaseSensitive(o, name);
    return cJSON_IsString(s) ? sc_strdup(s->valuestring) : NULL;
}

int sc_remote_record_decode(const char *text, size_t n, sc_cache_action *out, sc_error *err) {
    memset(out, 0, sizeof *out);
    cJSON *o = cJSON_ParseWithLength(text, n);
    const cJSON *deps = cJSON_GetObjectItemCaseSensitive(o, "deps");
    const cJSON *blobs = cJSON_GetObjectItemCaseSensitive(o, "blobs");
    const cJSON *seconds = cJSON_GetObjectItemCaseSensitive(o, "seconds");
    const cJSON *format = cJSON_GetObjectItemCaseSensitive(o, "format");
    bool ok = cJSON_IsObject(o) && cJSON_IsNumber(format) && format->valuedouble == 1 && cJSON_IsArray(deps) &&
              cJSON_IsArray(blobs) && cJSON_IsNumber(seconds) &&
              digest_of(cJSON_GetObjectItemCaseSensitive(o, "key"), &out->key);
    if (ok) {
        out->node_type = string_of(o, "node_type");
        out->outputs = string_of(o, "outputs");
        out->metrics = string_of(o, "metrics");
        out->seconds = seconds->valuedouble;
        ok = out->node_type && out->outputs && out->metrics;
    }
    int nd = ok ? cJSON_GetArraySize(deps) : 0, nb = ok ? cJSON_GetArraySize(blobs) : 0;
    if (ok) {
        out->deps = sc_calloc_array((size_t)nd + 1, sizeof *out->deps);
        out->blobs = sc_calloc_array((size_t)nb + 1, sizeof *out->blobs);
        ok = out->deps && out->blobs;
    }
    const cJSON *item;
    if (ok) {
        cJSON_ArrayForEach(item, deps) {
            char *path = string_of(item, "path");
            if (!path || !*path || !digest_of(cJSON_GetObjectItemCaseSensitive(item, "digest"),
                                              &out->deps[out->ndeps].digest)) {
                free(path);
                ok = false;
                break;
            }
            out->deps[out->ndeps++].path = path;
        }
    }
    if (ok) {
        cJSON_ArrayForEach(item, blobs) {
            if (!digest_of(item, &out->blobs[out->nblobs])) {
                ok = false;
                break;
            }
            out->nblobs++;
        }
    }
    cJSON_Delete(o);
    if (ok) return SC_OK;
    sc_cache_action_free(out);
    return sc_fail(err, SC_EINPUT, "the action record is malformed");
}

/* ---------------------------------------------------------------- fetching */

/* GET a blob, verify it, and put it into the local cache. */
static int fetch_blob(sc_remote *r, const sc_digest *d, int64_t size_hint, sc_buf *body, sc_error *err) {
    size_t max = size_hint > 0 && size_hint <= MAX_BLOB_BYTES ? (size_t)size_hint : (size_t)MAX_BLOB_BYTES;
    int rc = get(r, r->fetcher, "cas", d, body, max, err);
    if (rc == SC_EMISS) count(r, &r->stats.missing_blobs, 1);
    if (rc == SC_EINPUT) mark_bad(r, d);   /* longer than its size says */
    if (rc != SC_OK) return rc == SC_EIO ? SC_EIO : SC_EMISS;
    sc_digest got;
    sc_digest_bytes(body->data, body->len, &got);
    if (!sc_digest_equal(&got, d)) {
        mark_bad(r, d);
        char hex[65];
        sc_digest_hex(d, hex);
        return sc_fail(err, SC_EMISS, "blob %.12s: its bytes on the remote do not match its digest", hex);
    }
    local_lock(r);
    rc = sc_cache_put_blob(r->local, d, body->data, body->len, err);
    local_unlock(r);
    if (rc == SC_OK) {
        count(r, &r->stats.blobs_downloaded, 1);
        count(r, &r->stats.bytes_downloaded, (int64_t)body->len);
    }
    return rc;
}

int sc_remote_fetch(sc_remote *r, const sc_digest *key, sc_error *err) {
    if (!r || is_disabled(r)) return sc_fail(err, SC_EMISS, "no remote");
    sc_buf body;
    sc_buf_init(&body);
    sc_remote_output *outs = NULL;
    int nouts = 0;
    sc_cache_action act = {0};
    int rc = get(r, r->fetcher, "ac", key, &body, MAX_RESULT_BYTES, err);
    if (rc == SC_OK) rc = sc_remote_decode_result(body.data, body.len, &outs, &nouts, err);
    const sc_remote_output *record = NULL;
    for (int i = 0; rc == SC_OK && i < nouts; i++)
        if (!strcmp(outs[i].path, RECORD_PATH)) record = &outs[i];
    if (rc == SC_OK && !record) rc = sc_fail(err, SC_EINPUT, "the action result names no record");
    if (rc == SC_OK) rc = fetch_blob(r, &record->digest, record->size, &body, err);
    if (rc == SC_OK) rc = sc_remote_record_decode((const char *)body.data, body.len, &act, err);
    if (rc == SC_OK && !sc_digest_equal(&act.key, key)) rc = sc_fail(err, SC_EINPUT, "the record is another action's");
    for (int i = 0; rc == SC_OK && i < act.nblobs; i++) {
        local_lock(r);
        bool have = sc_cache_has_blob(r->local, &act.blobs[i]);
        local_unlock(r);
        if (have) continue;
        int64_t size = 0;
        for (int k = 0; k < nouts; k++)
            if (sc_digest_equal(&outs[k].digest, &act.blobs[i])) size = outs[k].size;
        rc = fetch_blob(r, &act.blobs[i], size, &body, err);
    }
    if (rc == SC_OK) {
        local_lock(r);
        rc = sc_cache_put_action(r->local, &act, err);
        local_unlock(r);
    }
    count(r, rc == SC_OK ? &r->stats.ac_hits : &r->stats.ac_misses, 1);
    sc_cache_action_free(&act);
    sc_remote_outputs_free(outs, nouts);
    sc_buf_free(&body);
    if (rc != SC_OK && rc != SC_ENOMEM) err->code = rc = SC_EMISS;
    return rc;
}

/* ---------------------------------------------------------------- uploading */

/* HEAD, then PUT the store's file unless the server has it. SC_OK, SC_EMISS
 * (the local file is gone), SC_EIO (the remote is now disabled). */
static int upload_blob(sc_remote *r, CURL *h, const sc_digest *d, int64_t *size, sc_error *err) {
    char *path = sc_cache_blob_path(r->local, d);
    FILE *f = path ? fopen(path, "rb") : NULL;
    free(path);
    struct stat st;
    if (!f || fstat(fileno(f), &st) != 0) {
        if (f) fclose(f);
        return sc_fail(err, SC_EMISS, "a blob left the local cache");
    }
    *size = (int64_t)st.st_size;
    long status = 0;
    int rc = SC_OK;
    if (!is_bad(r, d)) {
        request head = {.method = "HEAD", .ns = "cas", .name = d};
        rc = http(r, h, &head, &status, err);
        if (rc == SC_OK && status == 200) {
            fclose(f);
            count(r, &r->stats.blobs_present, 1);
            return SC_OK;
        }
    }
    if (rc == SC_OK) {
        request put = {.method = "PUT", .ns = "cas", .name = d, .file = f, .size = *size};
        rc = http(r, h, &put, &status, err);
    }
    fclose(f);
    if (rc != SC_OK) {
        give_up(r, "%s", err->message);
        return SC_EIO;
    }
    if (status_fatal(r, "PUT", "cas", status) || status == 404) {
        if (status == 404) give_up(r, "PUT /cas/ answered 404: the server does not take uploads");
        return sc_fail(err, SC_EIO, "remote disabled");
    }
    count(r, &r->stats.blobs_uploaded, 1);
    count(r, &r->stats.bytes_uploaded, *size);
    return SC_OK;
}

static int put_memory(sc_remote *r, CURL *h, const char *ns, const sc_digest *name, const void *p, size_t n,
                      sc_error *err) {
    request put = {.method = "PUT", .ns = ns, .name = name, .mem = p, .len = n, .size = (int64_t)n};
    long status = 0;
    int rc = http(r, h, &put, &status, err);
    if (rc != SC_OK) {
        give_up(r, "%s", err->message);
        return SC_EIO;
    }
    if (status_fatal(r, "PUT", ns, status) || status == 404) {
        if (status == 404) give_up(r, "PUT /%s/ answered 404: the server does not take uploads", ns);
        return sc_fail(err, SC_EIO, "remote disabled");
    }
    return SC_OK;
}

static void run_upload(sc_remote *r, CURL *h, const upload *u) {
    sc_error err;
    int n = u->nblobs;
    sc_remote_output *outs = sc_calloc_array((size_t)n + 1, sizeof *outs);
    char *paths = sc_alloc_array((size_t)n + 1, 6 + 65);
    int rc = outs && paths ? SC_OK : SC_ENOMEM;
    for (int i = 0; rc == SC_OK && i < n; i++) {
        if (is_disabled(r)) rc = SC_EIO;
        else rc = upload_blob(r, h, &u->blobs[i], &outs[i + 1].size, &err);
        char hex[65];
        sc_digest_hex(&u->blobs[i], hex);
        outs[i + 1].path = paths + (size_t)i * 71;
        snprintf(outs[i + 1].path, 71, BLOB_PREFIX "%s", hex);
        outs[i + 1].digest = u->blobs[i];
    }
    size_t len = strlen(u->record);
    if (rc == SC_OK) {
        outs[0].path = record_path;
        sc_digest_bytes(u->record, len, &outs[0].digest);
        outs[0].size = (int64_t)len;
        if (!is_bad(r, &outs[0].digest)) {
            request head = {.method = "HEAD", .ns = "cas", .name = &outs[0].digest};
            long status = 0;
            if (http(r, h, &head, &status, &err) == SC_OK && status == 200) len = 0;   /* there already */
        }
        if (len) rc = put_memory(r, h, "cas", &outs[0].digest, u->record, len, &err);
    }
    sc_buf result;
    sc_buf_init(&result);
    if (rc == SC_OK) rc = sc_remote_encode_result(outs, n + 1, &result);
    if (rc == SC_OK) rc = put_memory(r, h, "ac", &u->key, result.data, result.len, &err);
    if (rc == SC_OK) count(r, &r->stats.actions_uploaded, 1);
    sc_buf_free(&result);
    free(outs);
    free(paths);
}

static void upload_free(upload *u) {
    if (!u) return;
    free(u->record);
    free(u->blobs);
    free(u);
}

static void *upload_thread(void *arg) {
    sc_remote *r = arg;
    CURL *h = curl_easy_init();
    pthread_mutex_lock(&r->lock);
    for (;;) {
        while (!r->head && !r->stopping) pthread_cond_wait(&r->wake, &r->lock);
        if (!r->head) break;
        upload *u = r->head;
        r->head = u->next;
        if (!r->head) r->tail = NULL;
        r->busy = true;
        bool skip = r->disabled || !h;
        pthread_mutex_unlock(&r->lock);
        if (!skip) run_upload(r, h, u);
        upload_free(u);
        pthread_mutex_lock(&r->lock);
        r->busy = false;
        if (!r->head) pthread_cond_broadcast(&r->idle);
    }
    pthread_mutex_unlock(&r->lock);
    if (h) curl_easy_cleanup(h);
    return NULL;
}

int sc_remote_upload(sc_remote *r, const sc_cache_action *a, sc_error *err) {
    if (!r || r->cfg.read_only || is_disabled(r)) return SC_OK;
    upload *u = calloc(1, sizeof *u);
    if (!u) return sc_fail(err, SC_ENOMEM, "out of memory");
    u->key = a->key;
    u->record = sc_remote_record_encode(a);
    u->nblobs = a->nblobs;
    u->blobs = sc_alloc_array((size_t)a->nblobs + 1, sizeof *u->blobs);
    if (!u->record || !u->blobs) {
        upload_free(u);
        return sc_fail(err, SC_ENOMEM, "out of memory");
    }
    if (a->nblobs) memcpy(u->blobs, a->blobs, (size_t)a->nblobs * sizeof *u->blobs);
    pthread_mutex_lock(&r->lock);
    if (r->tail) r->tail->next = u;
    else r->head = u;
    r->tail = u;
    pthread_cond_signal(&r->wake);
    pthread_mutex_unlock(&r->lock);
    return SC_OK;
}

void sc_remote_flush(sc_remote *r) {
    if (!r) return;
    pthread_mutex_lock(&r->lock);
    while (r->head || r->busy) pthread_cond_wait(&r->idle, &r->lock);
    pthread_mutex_unlock(&r->lock);
}

/* ---------------------------------------------------------------- open, close */

static pthread_once_t curl_once = PTHREAD_ONCE_INIT;
static void curl_start(void) { curl_global_init(CURL_GLOBAL_DEFAULT); }

int sc_remote_open(const sc_remote_config *cfg, sc_cache *local, sc_remote **out, sc_error *err) {
    *out = NULL;
    const char *url = cfg->url ? cfg->url : "";
    if (strncmp(url, "http://", 7) != 0 && strncmp(url, "https://", 8) != 0)
        return sc_fail(err, SC_EUSAGE, "remote cache '%s': expected an http:// or https:// URL", url);
    for (int i = 0; i < cfg->nheaders; i++) {
        const char *colon = strchr(cfg->headers[i], ':');
        if (!colon || colon == cfg->headers[i] || strpbrk(cfg->headers[i], "\r\n"))
            return sc_fail(err, SC_EUSAGE, "remote cache header '%s': expected 'Name: value'", cfg->headers[i]);
    }
    pthread_once(&curl_once, curl_start);
    sc_remote *r = calloc(1, sizeof *r);
    if (!r) return sc_fail(err, SC_ENOMEM, "out of memory");
    r->cfg = *cfg;
    if (r->cfg.timeout <= 0) r->cfg.timeout = 10;
    if (r->cfg.retries < 0) r->cfg.retries = 2;
    r->local = local;
    r->base = sc_strdup(url);
    size_t n = r->base ? strlen(r->base) : 0;
    while (n > 0 && r->base[n - 1] == '/') r->base[--n] = 0;
    /* shown: scheme://host..., the user kept and the password dropped */
    const char *scheme_end = strstr(url, "://") + 3, *at = strchr(scheme_end, '@'), *slash = strchr(scheme_end, '/');
    if (at && (!slash || at < slash)) {
        const char *colon = memchr(scheme_end, ':', (size_t)(at - scheme_end));
        r->shown = colon ? sc_strprintf("%.*s%s", (int)(colon - url), url, at) : sc_strdup(url);
    } else {
        r->shown = sc_strdup(url);
    }
    bool ok = r->base && r->shown;
    for (int i = 0; ok && i < cfg->nheaders; i++) {
        struct curl_slist *grown = curl_slist_append(r->headers, cfg->headers[i]);
        ok = grown != NULL;
        if (ok) r->headers = grown;
    }
    /* nginx and others answer a PUT without this header the same; curl would otherwise wait for 100-continue */
    struct curl_slist *grown = ok ? curl_slist_append(r->headers, "Expect:") : NULL;
    if (grown) r->headers = grown;
    r->fetcher = ok && grown ? curl_easy_init() : NULL;
    ok = ok && grown && r->fetcher;
    pthread_mutex_init(&r->lock, NULL);
    pthread_cond_init(&r->wake, NULL);
    pthread_cond_init(&r->idle, NULL);
    if (ok && !r->cfg.read_only) ok = r->thread_started = pthread_create(&r->thread, NULL, upload_thread, r) == 0;
    if (!ok) {
        sc_remote_close(r);
        return sc_fail(err, SC_ENOMEM, "out of memory starting the remote cache");
    }
    *out = r;
    return SC_OK;
}

void sc_remote_close(sc_remote *r) {
    if (!r) return;
    if (r->thread_started) {
        pthread_mutex_lock(&r->lock);
        r->stopping = true;
        pthread_cond_broadcast(&r->wake);
        pthread_mutex_unlock(&r->lock);
        pthread_join(r->thread, NULL);
    }
    while (r->head) {
        upload *u = r->head;
        r->head = u->next;
        upload_free(u);
    }
    if (r->fetcher) curl_easy_cleanup(r->fetcher);
    curl_slist_free_all(r->headers);
    pthread_mutex_destroy(&r->lock);
    pthread_cond_destroy(&r->wake);
    pthread_cond_destroy(&r->idle);
    free(r->bad);
    free(r->base);
    free(r->shown);
    free(r);
}

void sc_remote_stats_get(sc_remote *r, sc_remote_stats *out) {
    memset(out, 0, sizeof *out);
    if (!r) return;
    pthread_mutex_lock(&r->lock);
    *out = r->stats;
    pthread_mutex_unlock(&r->lock);
}
