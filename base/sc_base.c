/* sc_base.c - errors, buffers, digests, files, number formatting and a
 * chunked parallel loop.
 *
 * Design note: everything here is small and dependency-free except SHA-256,
 * which comes from OpenSSL's libcrypto (EVP), so it uses the CPU's SHA
 * extensions where present. Binary encodings are little endian and written
 * byte by byte, so the canonical bytes do not depend on the host.
 */
#include "sc_base.h"

#include <dirent.h>
#include <errno.h>
#include <sys/mman.h>
#include <fcntl.h>
#include <limits.h>
#ifdef __GLIBC__
#include <malloc.h>
#endif
#include <math.h>
#include <pthread.h>
#include <signal.h>
#include <stdarg.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/syscall.h>
#include <time.h>
#include <unistd.h>

#include <openssl/evp.h>

/* ---------------------------------------------------------------- errors */

int sc_fail(sc_error *err, int code, const char *fmt, ...) {
    if (err) {
        va_list ap;
        va_start(ap, fmt);
        vsnprintf(err->message, sizeof err->message, fmt, ap);
        va_end(ap);
        err->code = code;
    }
    return code;
}

int sc_error_prefix(sc_error *err, const char *fmt, ...) {
    if (!err) return SC_EINPUT;
    char prefix[512], old[sizeof err->message];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(prefix, sizeof prefix, fmt, ap);
    va_end(ap);
    memcpy(old, err->message, sizeof old);
    size_t n = strlen(prefix);
    if (n > sizeof err->message - 3) n = sizeof err->message - 3;
    memcpy(err->message, prefix, n);
    memcpy(err->message + n, ": ", 2);
    size_t room = sizeof err->message - n - 3;
    size_t m = strnlen(old, room);
    memcpy(err->message + n + 2, old, m);
    err->message[n + 2 + m] = 0;
    return err->code ? err->code : SC_EINPUT;
}

/* ---------------------------------------------------------------- memory */

#ifndef MADV_POPULATE_WRITE
#define MADV_POPULATE_WRITE 23   /* Linux 5.14; older kernels refuse it, which changes nothing */
#endif
#define POPULATE_MIN_BYTES (1u << 20)

/* Map the whole pages of a large block now, in one call, instead of one
 * page fault at a time as it is first written (sc_base.h: memory). Pages
 * already mapped (memory the heap reuses) cost a walk of the page table. */
static void *populated(void *p, size_t bytes) {
    if (p && bytes >= POPULATE_MIN_BYTES) {
        uintptr_t a = ((uintptr_t)p + 4095) & ~(uintptr_t)4095, b = ((uintptr_t)p + bytes) & ~(uintptr_t)4095;
        if (b > a) madvise((void *)a, b - a, MADV_POPULATE_WRITE);
    }
    return p;
}

void *sc_alloc_array(size_t count, size_t size) {
    if (count == 0 || size == 0 || count > SIZE_MAX / size) return NULL;
    return populated(malloc(count * size), count * size);
}

void *sc_calloc_array(size_t count, size_t size) {
    if (count == 0 || size == 0 || count > SIZE_MAX / size) return NULL;
    return populated(calloc(count, size), count * size);
}

void *sc_realloc_array(void *p, size_t count, size_t size) {
    if (count == 0 || size == 0 || count > SIZE_MAX / size) return NULL;
    return populated(realloc(p, count * size), count * size);
}

char *sc_strdup(const char *s) {
    return s ? sc_strndup(s, strlen(s)) : NULL;
}

char *sc_strndup(const char *s, size_t n) {
    char *d = malloc(n + 1);
    if (!d) return NULL;
    memcpy(d, s, n);
    d[n] = 0;
    return d;
}

char *sc_strprintf(const char *fmt, ...) {
    va_list ap, ap2;
    va_start(ap, fmt);
    va_copy(ap2, ap);
    int n = vsnprintf(NULL, 0, fmt, ap);
    va_end(ap);
    char *s = n >= 0 ? malloc((size_t)n + 1) : NULL;
    if (s) vsnprintf(s, (size_t)n + 1, fmt, ap2);
    va_end(ap2);
    return s;
}

/* ---------------------------------------------------------------- buffer */

void sc_buf_init(sc_buf *b) { memset(b, 0, sizeof *b); }

void sc_buf_free(sc_buf *b) {
    free(b->data);
    memset(b, 0, sizeof *b);
}

void sc_buf_reset(sc_buf *b) {
    b->len = 0;
    b->failed = false;
}

bool sc_buf_reserve(sc_buf *b, size_t extra) {
    if (b->failed) return false;
    if (extra > SIZE_MAX - b->len - 1) {
        b->failed = true;
        return false;
    }
    size_t need = b->len + extra + 1;   /* room for a terminating NUL */
    if (need <= b->cap) return true;
    size_t cap = b->cap ? b->cap : 64;
    while (cap < need) cap = cap > SIZE_MAX / 2 ? need : cap * 2;
    uint8_t *d = realloc(b->data, cap);
    if (!d) {
        b->failed = true;
        return false;
    }
    b->data = d;
    b->cap = cap;
    return true;
}

void sc_buf_append(sc_buf *b, const void *p, size_t n) {
    if (!sc_buf_reserve(b, n)) return;
    if (n) memcpy(b->data + b->len, p, n);
    b->len += n;
    b->data[b->len] = 0;
}

void sc_buf_puts(sc_buf *b, const char *s) { sc_buf_append(b, s, strlen(s)); }

void sc_buf_printf(sc_buf *b, const char *fmt, ...) {
    va_list ap, ap2;
    va_start(ap, fmt);
    va_copy(ap2, ap);
    int n = vsnprintf(NULL, 0, fmt, ap);
    va_end(ap);
    if (n > 0 && sc_buf_reserve(b, (size_t)n)) {
        vsnprintf((char *)b->data + b->len, (size_t)n + 1, fmt, ap2);
        b->len += (size_t)n;
    }
    va_end(ap2);
}

void sc_buf_u8(sc_buf *b, uint8_t v) { sc_buf_append(b, &v, 1); }

void sc_buf_u32(sc_buf *b, uint32_t v) {
    uint8_t x[4] = {(uint8_t)v, (uint8_t)(v >> 8), (uint8_t)(v >> 16), (uint8_t)(v >> 24)};
    sc_buf_append(b, x, 4);
}

void sc_buf_u64(sc_buf *b, uint64_t v) {
    sc_buf_u32(b, (uint32_t)v);
    sc_buf_u32(b, (uint32_t)(v >> 32));
}

void sc_buf_f64(sc_buf *b, double v) {
    uint64_t u;
    memcpy(&u, &v, 8);
    sc_buf_u64(b, u);
}

void sc_buf_str(sc_buf *b, const char *s) {
    size_t n = s ? strlen(s) : 0;
    sc_buf_u32(b, (uint32_t)n);
    if (n) sc_buf_append(b, s, n);
}

char *sc_buf_take_string(sc_buf *b) {
    if (b->failed) {
        sc_buf_free(b);
        return NULL;
    }
    if (!b->data && !sc_buf_reserve(b, 0)) return NULL;
    b->data[b->len] = 0;
    char *s = (char *)b->data;
    memset(b, 0, sizeof *b);
    return s;
}

/* ---------------------------------------------------------------- reader */

void sc_reader_init(sc_reader *r, const void *data, size_t n) {
    r->p = data;
    r->end = r->p + n;
    r->failed = false;
}

const void *sc_read_bytes(sc_reader *r, size_t n) {
    if (r->failed || (size_t)(r->end - r->p) < n) {
        r->failed = true;
        return NULL;
    }
    const void *p = r->p;
    r->p += n;
    return p;
}

uint8_t sc_read_u8(sc_reader *r) {
    const uint8_t *p = sc_read_bytes(r, 1);
    return p ? p[0] : 0;
}

uint32_t sc_read_u32(sc_reader *r) {
    const uint8_t *p = sc_read_bytes(r, 4);
    if (!p) return 0;
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

uint64_t sc_read_u64(sc_reader *r) {
    uint64_t lo = sc_read_u32(r);
    uint64_t hi = sc_read_u32(r);
    return lo | hi << 32;
}

double sc_read_f64(sc_reader *r) {
    uint64_t u = sc_read_u64(r);
    double v;
    memcpy(&v, &u, 8);
    return v;
}

char *sc_read_str(sc_reader *r) {
    uint32_t n = sc_read_u32(r);
    const char *p = sc_read_bytes(r, n);
    if (!p) return NULL;
    if (memchr(p, 0, n)) {
        r->failed = true;
        return NULL;
    }
    return sc_strndup(p, n);
}

/* ---------------------------------------------------------------- digests */

struct sc_hasher {
    EVP_MD_CTX *ctx;
};

sc_hasher *sc_hasher_new(void) {
    sc_hasher *h = malloc(sizeof *h);
    if (!h) return NULL;
    h->ctx = EVP_MD_CTX_new();
    if (!h->ctx || EVP_DigestInit_ex(h->ctx, EVP_sha256(), NULL) != 1) {
        EVP_MD_CTX_free(h->ctx);
        free(h);
        return NULL;
    }
    return h;
}

void sc_hasher_update(sc_hasher *h, const void *p, size_t n) {
    if (h && n) EVP_DigestUpdate(h->ctx, p, n);
}

void sc_hasher_final(sc_hasher *h, sc_digest *out) {
    memset(out, 0, sizeof *out);
    if (!h) return;
    unsigned int len = 0;
    EVP_DigestFinal_ex(h->ctx, out->bytes, &len);
    EVP_MD_CTX_free(h->ctx);
    free(h);
}

void sc_digest_bytes(const void *p, size_t n, sc_digest *out) {
    unsigned int len = 0;
    if (EVP_Digest(p, n, out->bytes, &len, EVP_sha256(), NULL) != 1)
        memset(out, 0, sizeof *out);
}

void sc_digest_hex(const sc_digest *d, char out[65]) {
    static const char hex[] = "0123456789abcdef";
    for (int i = 0; i < 32; i++) {
        out[2 * i] = hex[d->bytes[i] >> 4];
        out[2 * i + 1] = hex[d->bytes[i] & 15];
    }
    out[64] = 0;
}

static int hex_value(char c) {
    if (c >= '0' && c <= '9') return c - '0';
    if (c >= 'a' && c <= 'f') return c - 'a' + 10;
    if (c >= 'A' && c <= 'F') return c - 'A' + 10;
    return -1;
}

int sc_digest_parse(const char *hex, sc_digest *out) {
    if (!hex || strlen(hex) != 64) return -1;
    for (int i = 0; i < 32; i++) {
        int hi = hex_value(hex[2 * i]), lo = hex_value(hex[2 * i + 1]);
        if (hi < 0 || lo < 0) return -1;
        out->bytes[i] = (uint8_t)(hi << 4 | lo);
    }
    return 0;
}

bool sc_digest_equal(const sc_digest *a, const sc_digest *b) {
    return memcmp(a->bytes, b->bytes, 32) == 0;
}

bool sc_digest_is_zero(const sc_digest *d) {
    static const sc_digest zero;
    return sc_digest_equal(d, &zero);
}

/* ---------------------------------------------------------------- files */

int sc_read_file(const char *path, size_t max_bytes, sc_buf *out, sc_error *err) {
    int fd = open(path, O_RDONLY | O_CLOEXEC);
    if (fd < 0) return sc_fail(err, SC_EINPUT, "%s: cannot open: %s", path, strerror(errno));
    struct stat st;
    if (fstat(fd, &st) != 0 || !S_ISREG(st.st_mode)) {
        close(fd);
        return sc_fail(err, SC_EINPUT, "%s: not a regular file", path);
    }
    if ((uint64_t)st.st_size > max_bytes) {
        close(fd);
        return sc_fail(err, SC_ENOMEM, "%s: %lld bytes is larger than the limit of %zu",
                       path, (long long)st.st_size, max_bytes);
    }
    sc_buf_reset(out);
    if (!sc_buf_reserve(out, (size_t)st.st_size)) {
        close(fd);
        return sc_fail(err, SC_ENOMEM, "%s: out of memory", path);
    }
    for (;;) {
        if (out->len >= max_bytes) break;
        if (!sc_buf_reserve(out, 65536)) {
            close(fd);
            return sc_fail(err, SC_ENOMEM, "%s: out of memory", path);
        }
        size_t room = out->cap - out->len - 1;
        if (room > max_bytes - out->len + 1) room = max_bytes - out->len + 1;
        ssize_t n = read(fd, out->data + out->len, room);
        if (n < 0) {
            if (errno == EINTR) continue;
            close(fd);
            return sc_fail(err, SC_EINPUT, "%s: read failed: %s", path, strerror(errno));
        }
        if (n == 0) break;
        out->len += (size_t)n;
    }
    close(fd);
    if (out->len > max_bytes)
        return sc_fail(err, SC_ENOMEM, "%s: larger than the limit of %zu bytes", path, max_bytes);
    out->data[out->len] = 0;
    return SC_OK;
}

char *sc_excerpt(const char *s, size_t max, bool word, char *out, size_t n) {
    size_t k = 0, i = 0;
    for (; s[i] && !(word && (s[i] == ' ' || s[i] == '\t')) && i < max && k + 5 < n; i++) {
        unsigned char c = (unsigned char)s[i];
        if (c >= 32 && c < 127) out[k++] = (char)c;
        else k += (size_t)snprintf(out + k, n - k, "\\x%02x", c);
    }
    if (s[i] && !(word && (s[i] == ' ' || s[i] == '\t')) && k + 4 <= n) memcpy(out + k, "...", 3), k += 3;
    out[k < n ? k : n - 1] = 0;
    return out;
}

/* The process's umask, read once from /proc (umask(2) can only read it by
 * changing it, which races with other threads creating files). */
static mode_t process_umask = 022;
static pthread_once_t umask_once = PTHREAD_ONCE_INIT;

static void read_umask(void) {
    FILE *f = fopen("/proc/self/status", "r");
    char line[256];
    while (f && fgets(line, sizeof line, f)) {
        unsigned m;
        if (sscanf(line, "Umask: %o", &m) == 1) {
            process_umask = (mode_t)m;
            break;
        }
    }
    if (f) fclose(f);
}

unsigned sc_file_mode(void) {
    pthread_once(&umask_once, read_umask);
    return 0666u & ~(unsigned)process_umask;
}

int sc_remove_stale_tmp(const char *dir, int *removed) {
    DIR *d = opendir(dir);
    if (!d) return errno == ENOENT ? SC_OK : SC_EIO;
    struct dirent *de;
    time_t old = time(NULL) - 3600;
    size_t plen = strlen(SC_TMP_PREFIX);
    while ((de = readdir(d))) {
        if (de->d_name[0] == '.' && (de->d_name[1] == 0 || (de->d_name[1] == '.' && de->d_name[2] == 0))) continue;
        char *p = sc_path_join(dir, de->d_name);
        struct stat st;
        if (p && lstat(p, &st) == 0) {
            if (S_ISDIR(st.st_mode)) {
                sc_remove_stale_tmp(p, removed);
            } else if (S_ISREG(st.st_mode) && strncmp(de->d_name, SC_TMP_PREFIX, plen) == 0) {
                /* NAME.PID.XXXXXX: in flight while its process lives (and for an hour at most) */
                const char *dot = strrchr(de->d_name, '.');
                const char *pid_at = dot && dot > de->d_name ? dot - 1 : NULL;
                while (pid_at && pid_at > de->d_name && *pid_at != '.') pid_at--;
                long pid = pid_at ? strtol(pid_at + 1, NULL, 10) : 0;
                bool alive = pid > 0 && (kill((pid_t)pid, 0) == 0 || errno == EPERM);
                if ((!alive || st.st_mtime < old) && unlink(p) == 0 && removed) (*removed)++;
            }
        }
        free(p);
    }
    closedir(d);
    return SC_OK;
}

int sc_write_file_atomic(const char *path, const void *p, size_t n, sc_error *err) {
    size_t plen = strlen(path);
    char *tmp = malloc(plen + 64);
    if (!tmp) return sc_fail(err, SC_ENOMEM, "out of memory");
    const char *slash = strrchr(path, '/');
    size_t dl = slash ? (size_t)(slash - path) + 1 : 0;
    snprintf(tmp, plen + 64, "%.*s" SC_TMP_PREFIX "%s.%ld.XXXXXX", (int)dl, path, path + dl, (long)getpid());
    int fd = mkstemp(tmp);
    if (fd < 0) {
        int e = errno;
        free(tmp);
        return sc_fail(err, SC_EIO, "%s: cannot create: %s", path, strerror(e));
    }
    const uint8_t *q = p;
    size_t left = n;
    while (left > 0) {
        ssize_t w = write(fd, q, left);
        if (w < 0) {
            if (errno == EINTR) continue;
            int e = errno;
            close(fd);
            unlink(tmp);
            free(tmp);
            return sc_fail(err, SC_EIO, "%s: write failed: %s", path, strerror(e));
        }
        q += w;
        left -= (size_t)w;
    }
    if (fchmod(fd, sc_file_mode()) != 0 || fsync(fd) != 0 || close(fd) != 0) {
        int e = errno;
        unlink(tmp);
        free(tmp);
        return sc_fail(err, SC_EIO, "%s: cannot finish writing: %s", path, strerror(e));
    }
    if (rename(tmp, path) != 0) {
        int e = errno;
        unlink(tmp);
        free(tmp);
        return sc_fail(err, SC_EIO, "%s: cannot publish: %s", path, strerror(e));
    }
    free(tmp);
    return SC_OK;
}

int sc_make_dirs(const char *path, sc_error *err) {
    char *p = sc_strdup(path);
    if (!p) return sc_fail(err, SC_ENOMEM, "out of memory");
    for (char *s = p + 1; *s; s++) {
        if (*s != '/') continue;
        *s = 0;
        if (mkdir(p, 0777) != 0 && errno != EEXIST) {   /* the umask decides */
            int e = errno;
            int rc = sc_fail(err, SC_EIO, "%s: cannot make directory: %s", p, strerror(e));
            free(p);
            return rc;
        }
        *s = '/';
    }
    if (mkdir(p, 0777) != 0 && errno != EEXIST) {
        int e = errno;
        int rc = sc_fail(err, SC_EIO, "%s: cannot make directory: %s", p, strerror(e));
        free(p);
        return rc;
    }
    free(p);
    return SC_OK;
}

char *sc_path_join(const char *dir, const char *name) {
    if (name[0] == '/' || !dir || !*dir) return sc_strdup(name);
    size_t dl = strlen(dir);
    if (dir[dl - 1] == '/') return sc_strprintf("%s%s", dir, name);
    return sc_strprintf("%s/%s", dir, name);
}

char *sc_path_dirname(const char *path) {
    const char *slash = strrchr(path, '/');
    if (!slash) return sc_strdup(".");
    if (slash == path) return sc_strdup("/");
    return sc_strndup(path, (size_t)(slash - path));
}

bool sc_path_is_plain_relative(const char *path) {
    if (!*path || path[0] == '/') return false;
    for (const char *s = path; *s;) {
        const char *slash = strchr(s, '/');
        size_t l = slash ? (size_t)(slash - s) : strlen(s);
        if (l == 0 || (l == 2 && s[0] == '.' && s[1] == '.') || (l == 1 && s[0] == '.')) return false;
        s += l + (slash ? 1 : 0);
    }
    return true;
}

/* path (absolute) with "." and ".." removed by the text alone, in place. */
static void normalise_lexically(char *path) {
    char *out = path;   /* path[0] == '/' */
    for (const char *p = path; *p;) {
        while (*p == '/') p++;
        const char *end = strchr(p, '/');
        size_t n = end ? (size_t)(end - p) : strlen(p);
        if (n == 0 || (n == 1 && p[0] == '.')) {
        } else if (n == 2 && p[0] == '.' && p[1] == '.') {
            while (out > path && *--out != '/') {}
        } else {
            *out++ = '/';
            memmove(out, p, n);
            out += n;
        }
        p += n;
    }
    if (out == path) *out++ = '/';
    *out = 0;
}

char *sc_path_relative(const char *dir, const char *path) {
    /* the longest common prefix that ends at a segment boundary */
    size_t common = 0;
    for (size_t k = 0;; k++) {
        bool dir_end = dir[k] == 0 || dir[k] == '/', path_end = path[k] == 0 || path[k] == '/';
        if (dir_end && path_end) common = k;
        if (!dir[k] || !path[k] || dir[k] != path[k]) break;
    }
    sc_buf b;
    sc_buf_init(&b);
    for (const char *s = dir + common; *s;) {   /* one ".." per segment of dir past the prefix */
        while (*s == '/') s++;
        if (!*s) break;
        sc_buf_puts(&b, b.len ? "/.." : "..");
        while (*s && *s != '/') s++;
    }
    const char *rest = path + common;
    while (*rest == '/') rest++;
    if (*rest) {
        if (b.len) sc_buf_u8(&b, '/');
        sc_buf_puts(&b, rest);
    }
    if (b.len == 0) sc_buf_u8(&b, '.');
    return sc_buf_take_string(&b);
}

char *sc_path_resolve(const char *dir, const char *path) {
    char *joined = sc_path_join(dir, path);
    if (joined && joined[0] == '/') normalise_lexically(joined);
    return joined;
}

/* The real path of `path`: symbolic links resolved in the longest part that
 * exists, the rest appended and normalised by its text. NULL when out of
 * memory or the working directory cannot be read. */
static char *real_path_of(const char *path) {
    char *abs = NULL;
    if (path[0] == '/') {
        abs = sc_strdup(path);
    } else {
        char cwd[PATH_MAX];
        if (!getcwd(cwd, sizeof cwd)) return NULL;
        abs = sc_path_join(cwd, path);
    }
    if (!abs) return NULL;
    normalise_lexically(abs);
    /* the longest existing prefix, resolved; the missing rest kept */
    size_t len = strlen(abs);
    for (;;) {
        char saved = abs[len];
        abs[len] = 0;
        char *real = realpath(len ? abs : "/", NULL);
        abs[len] = saved;
        if (real) {
            char *joined = sc_strprintf("%s%s", strcmp(real, "/") == 0 && abs[len] ? "" : real, abs + len);
            free(real), free(abs);
            if (joined) normalise_lexically(joined);
            return joined;
        }
        while (len > 0 && abs[--len] != '/') {}
    }
}

int sc_path_confine(const char *root, const char *dir, const char *rel, char **out, sc_error *err) {
    *out = NULL;
    if (!*rel) return sc_fail(err, SC_EINPUT, "an empty file name");
    char shown[320];
    sc_excerpt(rel, 60, false, shown, sizeof shown);
    if (rel[0] == '/' || rel[0] == '\\' || (rel[0] && rel[1] == ':' && (rel[2] == '/' || rel[2] == '\\')))
        return sc_fail(err, SC_EINPUT, "'%s' is an absolute path: an asset may name files inside its folder only "
                       "(--asset-root widens it)", shown);
    if (strstr(rel, "://") || strncmp(rel, "file:", 5) == 0)
        return sc_fail(err, SC_EINPUT, "'%s' is a URI: an asset may name files inside its folder only", shown);
    char *joined = strcmp(dir, ".") == 0 ? sc_strdup(rel) : sc_path_join(dir, rel);
    char *real = joined ? real_path_of(joined) : NULL;
    char *real_root = real_path_of(root);
    int rc = SC_OK;
    if (!joined || !real || !real_root) {
        rc = sc_fail(err, SC_ENOMEM, "'%s': out of memory, or the working folder cannot be read", shown);
    } else {
        size_t n = strlen(real_root);
        bool inside = strcmp(real_root, "/") == 0 ||
                      (strncmp(real, real_root, n) == 0 && (real[n] == '/' || real[n] == 0));
        if (!inside)
            rc = sc_fail(err, SC_EINPUT, "'%s' leads outside the asset folder %s (--asset-root widens it)", shown,
                         root);
    }
    free(real), free(real_root);
    if (rc != SC_OK) {
        free(joined);
        return rc;
    }
    *out = joined;
    return SC_OK;
}

double sc_now(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* ---------------------------------------------------------------- memory */

void sc_tune_allocator(void) {
#ifdef __GLIBC__
    mallopt(M_MMAP_THRESHOLD, 32 << 20);   /* fixed: frees do not move it */
    mallopt(M_TRIM_THRESHOLD, INT_MAX);
    mallopt(M_MMAP_MAX, 0);                /* large blocks from the heap too: reused, not re-faulted */
    mallopt(M_ARENA_MAX, 1);               /* pool threads share the heap that keeps them */
#endif
}

void sc_release_memory(void) {
#ifdef __GLIBC__
    malloc_trim(0);
#endif
}

/* ---------------------------------------------------------------- threads */

typedef struct parallel_state {
    int (*fn)(void *ud, int32_t chunk);
    void *ud;
    int32_t nchunks;
    atomic_int next;
    int *rcs;
} parallel_state;

static void *parallel_worker(void *arg) {
    parallel_state *st = arg;
    for (;;) {
        int32_t c = atomic_fetch_add(&st->next, 1);
        if (c >= st->nchunks) break;
        st->rcs[c] = st->fn(st->ud, c);
    }
    return NULL;
}

int sc_parallel(int threads, int32_t nchunks, int (*fn)(void *ud, int32_t chunk), void *ud) {
    if (nchunks <= 0) return SC_OK;
    int *rcs = sc_calloc_array((size_t)nchunks, sizeof *rcs);
    if (!rcs) return SC_ENOMEM;
    parallel_state st = {.fn = fn, .ud = ud, .nchunks = nchunks, .rcs = rcs};
    atomic_init(&st.next, 0);
    int nt = threads < 1 ? 1 : threads > 64 ? 64 : threads;
    if (nt > nchunks) nt = nchunks;
    pthread_t tid[64];
    int started = 0;
    for (int t = 1; t < nt; t++) {
        if (pthread_create(&tid[started], NULL, parallel_worker, &st) != 0) break;
        started++;
    }
    parallel_worker(&st);
    for (int t = 0; t < started; t++) pthread_join(tid[t], NULL);
    int rc = SC_OK;
    for (int32_t c = 0; c < nchunks && rc == SC_OK; c++) rc = rcs[c];
    free(rcs);
    return rc;
}

typedef struct behind {
    void (*fn)(void *ud);
    void *ud;
} behind;

static void *behind_main(void *arg) {
    behind *b = arg;
#ifdef __linux__
    /* this thread only: a thread's nice value is its own on Linux */
    (void)setpriority(PRIO_PROCESS, (id_t)syscall(SYS_gettid), SC_BEHIND_NICE);
#endif
    b->fn(b->ud);
    return NULL;
}

void sc_run_beside(int threads, void (*front)(void *ud), void (*back)(void *ud), void *ud) {
    behind b = {back, ud};
    pthread_t tid;
    bool beside = threads >= 2 && pthread_create(&tid, NULL, behind_main, &b) == 0;
    front(ud);
    if (beside) pthread_join(tid, NULL);
    else back(ud);
}

struct sc_pipe {
    void (*fn)(void *ud, int32_t item);
    void *ud;
    int32_t *items, capacity;
    int32_t ready, next, done;   /* items[0..ready) handed over; items[next] the next to run; done: finished */
    bool closed, worker;
    pthread_t thread;
    pthread_mutex_t mu;
    pthread_cond_t cv;
};

/* Run items until none is handed over and waiting (and, unless `until_closed`
 * is false, until the pipe is closed). */
static void pipe_work(sc_pipe *p, bool until_closed) {
    for (;;) {
        pthread_mutex_lock(&p->mu);
        while (until_closed && p->next >= p->ready && !p->closed) pthread_cond_wait(&p->cv, &p->mu);
        if (p->next >= p->ready) {
            pthread_mutex_unlock(&p->mu);
            return;
        }
        int32_t item = p->items[p->next++];
        pthread_mutex_unlock(&p->mu);
        p->fn(p->ud, item);
        pthread_mutex_lock(&p->mu);
        p->done++;
        pthread_cond_broadcast(&p->cv);
        pthread_mutex_unlock(&p->mu);
    }
}

static void *pipe_main(void *ud) {
    pipe_work(ud, true);
    return NULL;
}

sc_pipe *sc_pipe_start(int threads, int32_t capacity, void (*fn)(void *ud, int32_t item), void *ud) {
    sc_pipe *p = calloc(1, sizeof *p);
    if (!p) return NULL;
    p->items = sc_alloc_array((size_t)capacity + 1, sizeof *p->items);
    if (!p->items) {
        free(p);
        return NULL;
    }
    p->fn = fn, p->ud = ud, p->capacity = capacity;
    pthread_mutex_init(&p->mu, NULL);
    pthread_cond_init(&p->cv, NULL);
    p->worker = threads > 1 && pthread_create(&p->thread, NULL, pipe_main, p) == 0;
    return p;
}

void sc_pipe_hand(sc_pipe *p, int32_t item) {
    pthread_mutex_lock(&p->mu);
    bool taken = !p->closed && p->ready < p->capacity;
    if (taken) p->items[p->ready++] = item;
    pthread_cond_broadcast(&p->cv);
    pthread_mutex_unlock(&p->mu);
    if (taken && !p->worker) pipe_work(p, false);
}

int32_t sc_pipe_finish(sc_pipe *p, sc_pipe_end how) {
    pthread_mutex_lock(&p->mu);
    p->closed = true;
    if (how == SC_PIPE_DROP) p->ready = p->next;
    pthread_cond_broadcast(&p->cv);
    pthread_mutex_unlock(&p->mu);
    if (how == SC_PIPE_HELP || !p->worker) pipe_work(p, false);
    if (p->worker) pthread_join(p->thread, NULL);
    p->worker = false;
    return p->done;
}

void sc_pipe_free(sc_pipe *p) {
    if (!p) return;
    sc_pipe_finish(p, SC_PIPE_DROP);
    pthread_mutex_destroy(&p->mu);
    pthread_cond_destroy(&p->cv);
    free(p->items);
    free(p);
}

void sc_format_double(double v, char out[32]) {
    if (v == 0) {   /* both zeros print as 0: they compare equal everywhere */
        strcpy(out, "0");
        return;
    }
    if (v == floor(v) && fabs(v) < 9007199254740992.0) {
        snprintf(out, 32, "%.0f", v);
        return;
    }
    /* %g drops trailing zeros, and a double is exact to ~1e-17, so 15 digits
     * already give the shortest text of any value that has <= 15 digits */
    for (int prec = 15; prec <= 17; prec++) {
        snprintf(out, 32, "%.*g", prec, v);
        if (strtod(out, NULL) == v) return;
    }
}
