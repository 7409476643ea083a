/* sc_base.h - the few things every module of seamcook shares.
 *
 *   sc_error   an error as a value: a code and a message, filled by the callee.
 *   sc_buf     a growable byte buffer, owned by the caller (sc_buf_free).
 *   sc_digest  a SHA-256 digest (OpenSSL), printed as 64 lower-case hex digits.
 *   sc_set_root  union-find over an int32 parent array.
 *   sc_kernel  a versioned library whose results nodes store.
 *
 * Convention: a function that can fail returns int (0 = ok, non-zero = the
 * error code) and takes `sc_error *err` last; on failure it fills err. err may
 * be NULL when the caller does not want the message.
 */
#ifndef SC_BASE_H
#define SC_BASE_H

#include <stddef.h>
#include <stdint.h>
#include <stdbool.h>

/* ---------------------------------------------------------------- errors */

enum {
    SC_OK = 0,
    SC_EINPUT = 1,   /* bad input: file, parameter, graph, value (exit status 1) */
    SC_EUSAGE = 2,   /* bad command line (exit status 2) */
    SC_EIO = 3,      /* the file system or the cache failed */
    SC_ENOMEM = 4,   /* out of memory, or a size beyond the limits */
    SC_EMISS = 5,    /* not found (a cache miss); not a failure in itself */
    SC_EBUSY = 6,    /* another process holds it (a lease); not a failure in itself */
};

typedef struct sc_error {
    int code;
    char message[1024];
} sc_error;

/* Fill err (if not NULL) with printf-style text; returns code. */
int sc_fail(sc_error *err, int code, const char *fmt, ...)
    __attribute__((format(printf, 3, 4)));

/* Prefix an existing message: "prefix: old message". Returns err->code. */
int sc_error_prefix(sc_error *err, const char *fmt, ...)
    __attribute__((format(printf, 2, 3)));

/* ---------------------------------------------------------------- memory */

/* malloc/calloc/realloc that return NULL for a zero or overflowing size
 * product instead of wrapping around. A block of 1 MB or more has its pages
 * mapped at once (Linux: madvise MADV_POPULATE_WRITE): one call maps them
 * faster than a first-touch page fault per page as the block is written
 * (docs/notes/base.md). The memory is counted as used from then on, as it
 * would be once written. */
void *sc_alloc_array(size_t count, size_t size);
void *sc_calloc_array(size_t count, size_t size);
void *sc_realloc_array(void *p, size_t count, size_t size);
char *sc_strdup(const char *s);
char *sc_strndup(const char *s, size_t n);
/* printf into a new heap string (caller frees). */
char *sc_strprintf(const char *fmt, ...) __attribute__((format(printf, 1, 2)));

/* ---------------------------------------------------------------- disjoint sets */

/* The root of x's set in a union-find forest (parent[i] == i at a root),
 * halving the path on the way; join two sets by parent[root_a] = root_b. */
static inline int32_t sc_set_root(int32_t *parent, int32_t x) {
    while (parent[x] != x) x = parent[x] = parent[parent[x]];
    return x;
}

/* ---------------------------------------------------------------- kernels */

/* A library of shared algorithms (nodes/lib) whose results nodes store: its
 * name and version, and the kernels it builds on (NULL-terminated, or NULL).
 * A node lists the kernels it calls in its descriptor; the action key hashes
 * every kernel they reach, so bumping a kernel's version re-keys exactly the
 * nodes that use it. */
typedef struct sc_kernel {
    const char *name;
    int version;
    const struct sc_kernel *const *uses;
    /* For a kernel whose results depend on system libraries as well as on its
     * own code (the GL driver, the BLAS): a text naming what it runs on, which
     * enters the action key of every node that reaches the kernel. NULL when
     * the kernel's bytes depend on its inputs alone. */
    const char *(*platform)(void);
} sc_kernel;

/* ---------------------------------------------------------------- buffer */

typedef struct sc_buf {
    uint8_t *data;
    size_t len, cap;
    bool failed;          /* set once an allocation failed; appends then no-op */
} sc_buf;

void sc_buf_init(sc_buf *b);
void sc_buf_free(sc_buf *b);
void sc_buf_reset(sc_buf *b);                      /* len = 0, keeps capacity */
bool sc_buf_reserve(sc_buf *b, size_t extra);
void sc_buf_append(sc_buf *b, const void *p, size_t n);
void sc_buf_puts(sc_buf *b, const char *s);
void sc_buf_printf(sc_buf *b, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
void sc_buf_u8(sc_buf *b, uint8_t v);
void sc_buf_u32(sc_buf *b, uint32_t v);            /* little endian */
void sc_buf_u64(sc_buf *b, uint64_t v);
void sc_buf_f64(sc_buf *b, double v);
void sc_buf_str(sc_buf *b, const char *s);         /* u32 length + bytes */
/* Take the bytes out as a NUL-terminated string; the buffer is left empty. */
char *sc_buf_take_string(sc_buf *b);

/* A bounds-checked reader over bytes (for deserialisation). Reads past the
 * end set `failed` and return zeros; check it once at the end. */
typedef struct sc_reader {
    const uint8_t *p, *end;
    bool failed;
} sc_reader;

void sc_reader_init(sc_reader *r, const void *data, size_t n);
uint8_t sc_read_u8(sc_reader *r);
uint32_t sc_read_u32(sc_reader *r);
uint64_t sc_read_u64(sc_reader *r);
double sc_read_f64(sc_reader *r);
const void *sc_read_bytes(sc_reader *r, size_t n);  /* NULL when short */
char *sc_read_str(sc_reader *r);                    /* new string, NULL when bad */

/* ---------------------------------------------------------------- digests */

typedef struct sc_digest {
    uint8_t bytes[32];
} sc_digest;

typedef struct sc_hasher sc_hasher;   /* incremental SHA-256 */

sc_hasher *sc_hasher_new(void);
void sc_hasher_update(sc_hasher *h, const void *p, size_t n);
void sc_hasher_final(sc_hasher *h, sc_digest *out);   /* also frees h */

void sc_digest_bytes(const void *p, size_t n, sc_digest *out);
void sc_digest_hex(const sc_digest *d, char out[65]);
int sc_digest_parse(const char *hex, sc_digest *out);  /* 0 ok, -1 bad */
bool sc_digest_equal(const sc_digest *a, const sc_digest *b);
bool sc_digest_is_zero(const sc_digest *d);

/* ---------------------------------------------------------------- files */

/* Read a whole file. Fails with SC_EINPUT naming the path when it is missing
 * or unreadable, and with SC_ENOMEM when larger than max_bytes. */
int sc_read_file(const char *path, size_t max_bytes, sc_buf *out, sc_error *err);

/* Write bytes to path atomically: a temporary file beside it (named
 * SC_TMP_PREFIX + the file's name + ".PID.XXXXXX"), fsync, rename. A failure
 * leaves no partial file at path. The file's mode follows the umask. */
#define SC_TMP_PREFIX ".seamcook-tmp."
int sc_write_file_atomic(const char *path, const void *p, size_t n, sc_error *err);

/* Remove, under dir and its subfolders, the temporary files of
 * sc_write_file_atomic that a killed process left: those whose process is
 * gone, or older than an hour. *removed (may be NULL) counts them. */
int sc_remove_stale_tmp(const char *dir, int *removed);

/* At most `max` bytes of s (to its end, or to its first space or tab when
 * `word`), for an error message: bytes outside printable ASCII as \xNN,
 * "..." when cut. Returns out (n >= 5 * max + 4 holds any excerpt). */
char *sc_excerpt(const char *s, size_t max, bool word, char *out, size_t n);

/* The mode for a new file: 0666 less the process's umask. */
unsigned sc_file_mode(void);

/* mkdir -p */
int sc_make_dirs(const char *path, sc_error *err);

/* Join a directory and a relative name into a new string. A name that is
 * already absolute is returned as is. */
char *sc_path_join(const char *dir, const char *name);
/* The directory part of path ("." when none), as a new string. */
char *sc_path_dirname(const char *path);
/* Whether path names something inside a folder by its text alone: relative,
 * not empty, no empty, "." or ".." segment. */
bool sc_path_is_plain_relative(const char *path);
/* path as seen from the folder dir, both absolute and free of "." and ".."
 * segments: "a/b.obj", "../x/c.png", or "." for dir itself; a new string. The
 * text alone decides (no file system access), so the answer moves with the
 * tree: the same for a checkout anywhere. */
char *sc_path_relative(const char *dir, const char *path);
/* The inverse: path (relative, or absolute and kept) read from the absolute
 * folder dir, with "." and ".." segments removed by the text; a new string. */
char *sc_path_resolve(const char *dir, const char *path);

/* A file that an asset names (`rel`, as written in an MTL, OBJ or glTF),
 * resolved against the folder `dir` that names it, when it stays inside the
 * folder `root`: no absolute path, no URI, no ".." that climbs out of root,
 * and no symbolic link that leads out of it (the existing part of the path
 * is resolved). *out receives dir/rel as a new string. Fails with
 * SC_EINPUT naming rel, never reading the file. */
int sc_path_confine(const char *root, const char *dir, const char *rel, char **out, sc_error *err);

/* Monotonic seconds, for timings that go into reports (never into values). */
double sc_now(void);

/* For a process that cooks (the command line, the benchmarks), called
 * early in main, before it starts threads:
 *  - No huge pages of its own. Whether malloc advising its heap for
 *    transparent huge pages (glibc.malloc.hugetlb=1) wins depends on what
 *    the host does with fresh memory: on some machines fresh 2 MB pages
 *    fault far slower than 4 KB ones. So it is left to the environment:
 *    GLIBC_TUNABLES=glibc.malloc.hugetlb=1 turns it on.
 *  - Keep the memory freed by one stage for the next instead of handing it
 *    back to the system (glibc: mmap threshold fixed at its 32 MB ceiling,
 *    no trimming). Blocks above that ceiling come from the heap too (no
 *    mmap), so a stage's large arrays reuse the pages an earlier stage freed
 *    instead of faulting fresh ones.
 *  - One arena for every thread (glibc: M_ARENA_MAX 1). Nodes run on pool
 *    threads, and a thread's own arena lives in 64 MB heaps that are
 *    trimmed and unmapped whatever the trim threshold, so each node faulted
 *    in again the pages the one before it freed.
 * Nothing on other C libraries. sc_release_memory hands the retained memory
 * back (watch mode, between cooks). Measurements: docs/notes/base.md. */
void sc_tune_allocator(void);
void sc_release_memory(void);

/* Run fn(ud, chunk) for every chunk in [0, nchunks) on up to `threads`
 * threads (the caller's among them). Chunks are handed out in order; callers
 * that need the same bytes for any thread count make each chunk's work
 * independent of which thread runs it. Returns the first non-zero result in
 * chunk order, SC_OK when every chunk succeeded, or SC_ENOMEM. */
int sc_parallel(int threads, int32_t nchunks, int (*fn)(void *ud, int32_t chunk), void *ud);

/* Run front(ud) on the calling thread and back(ud) beside it, on a thread
 * of its own at a lower scheduling priority (Linux: nice SC_BEHIND_NICE;
 * the threads its own sc_parallel calls start inherit it), so that when the
 * two together ask for more threads than there are cores, the front - the
 * longer path - keeps its core. With threads < 2 (or no thread to start)
 * back runs after front. Results go through ud. */
#define SC_BEHIND_NICE 10
void sc_run_beside(int threads, void (*front)(void *ud), void (*back)(void *ud), void *ud);

/* A worker that runs fn(ud, item) for the items handed over, one at a time
 * in hand-over order, while the caller goes on: a stage that overlaps the
 * next one's work. With threads <= 1 (or no thread to be had) there is no
 * worker and sc_pipe_hand runs the item itself. sc_pipe_start returns NULL
 * out of memory; capacity bounds the items handed over. */
typedef struct sc_pipe sc_pipe;
typedef enum sc_pipe_end {
    SC_PIPE_WAIT = 0,   /* the worker runs what is left; the caller waits */
    SC_PIPE_HELP = 1,   /* the caller runs items too until none is left */
    SC_PIPE_DROP = 2,   /* items not yet started are never run */
} sc_pipe_end;
sc_pipe *sc_pipe_start(int threads, int32_t capacity, void (*fn)(void *ud, int32_t item), void *ud);
void sc_pipe_hand(sc_pipe *p, int32_t item);
/* No more items; returns when no item is running. Returns how many items
 * ran in all. A second call changes nothing. */
int32_t sc_pipe_finish(sc_pipe *p, sc_pipe_end how);
void sc_pipe_free(sc_pipe *p);

/* Shortest decimal text that reads back to exactly v ("nan"/"inf" never
 * occur: callers reject them first). Integral values print without ".0". */
void sc_format_double(double v, char out[32]);

#endif
