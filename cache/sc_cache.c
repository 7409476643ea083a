/* sc_cache.c - the content-addressed store and its SQLite index.
 *
 * Design note.
 *
 * Layout: objects/ab/cdef... (blobs), tmp/ (publishes in flight),
 * index.sqlite (WAL, synchronous=NORMAL, busy timeout 10 s). Every write
 * transaction starts with BEGIN IMMEDIATE, so a transaction never reads and
 * then fails to upgrade to a writer ("database is locked"); inside
 * sc_cache_begin/commit the puts use SAVEPOINTs of the enclosing transaction.
 * Schema creation is itself a BEGIN IMMEDIATE transaction of CREATE ... IF
 * NOT EXISTS guarded by PRAGMA user_version, so concurrent opens are safe.
 * Every statement is prepared once per sc_cache and reused; one sc_cache is
 * used by one thread at a time.
 *
 * Tables: blobs(digest, size, last_used), actions(key, node_type, outputs,
 * metrics, deps, blobs, seconds, created), action_blobs(key, idx, digest)
 * indexed on digest, stamps(path, size, mtime_ns, inode, digest),
 * history(node_id, text), runs(...). An action row also keeps its blob list
 * (64-hex digests, concatenated) so a lookup is one primary-key read;
 * action_blobs is the index gc and verify use to find the actions that need
 * a blob. Deps are encoded as lines "HEX LEN PATH\n" (LEN = bytes of PATH, so
 * any path reads back exactly).
 *
 * Blobs: written to tmp/ under a unique name, fsync'd, renamed into place,
 * directory fsync'd, and only then recorded in the blobs table. put_blob
 * re-checks that the file still exists after its row is written (under the
 * write lock), so a concurrent gc cannot leave a row without bytes. get
 * re-hashes the bytes; a mismatch is a miss: the row and the actions that
 * need the blob are dropped and the file is removed.
 *
 * Removing blobs (gc, verify, a corrupt get) is two-phase: first one
 * transaction drops the actions that need them and their rows; then, in a
 * second transaction, a file is unlinked only if no row was written for it
 * meanwhile. A crash between the two leaves only unreferenced files, which
 * the next gc finds by scanning objects/. put_action checks, in its own
 * transaction, that every blob it names still has a row (else SC_EMISS), so
 * a gc running beside a build never leaves an action pointing at missing
 * bytes, and a concurrent put of the same blob is never undone.
 *
 * last_used: wall-clock microseconds (made strictly increasing within one
 * process). A put sets it. Lookups do not write it: a verified blob read, or an
 * action hit (for every blob the action needs), queues the digest in memory;
 * the queue is written, each digest once, inside the next sc_cache_begin or
 * the outermost sc_cache_commit, before gc/verify, at close, or in a batch of
 * its own once 4096 uses are queued. A process killed before that loses only
 * these recency hints. gc orders blobs by last_used (no index: gc is rare, and
 * an index would make every touch dearer).
 *
 * Source stamps: a (path, size, mtime_ns, inode) stamp is recorded only when
 * the file's mtime is at least 2 s older than the wall clock taken before the
 * file was read, and the file's fstat did not change while it was hashed. A
 * file modified within the same mtime tick as a previous hash (same size) is
 * therefore never trusted: its stamp was never recorded, so it is re-hashed
 * until it has been quiet for 2 s (the "racily clean" rule of git and ninja).
 * Any later write gets a newer mtime than a recorded stamp. The documented
 * limit: a tool that rewrites a file with the same size and then sets its
 * mtime back to an old value (utimensat) on the same inode is not noticed.
 */
#include "sc_cache.h"

#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include <sqlite3.h>

#define SCHEMA_VERSION 1
#define BUSY_TIMEOUT_MS 10000
#define STAMP_RACY_NS 2000000000LL   /* a stamp needs an mtime this old */
#define TMP_MAX_AGE_S 3600           /* gc removes older tmp/ files, and
                                        adopts older unrecorded blob files */
#define TOUCH_BATCH 4096              /* queued uses written at once */
#define HASH_CHUNK (1u << 20)
#define RESERVE_BYTES ((size_t)4 << 20)   /* released by gc on a full disk */
#define SQLITE_PATH_MAX 512               /* the unix VFS's longest path name */

/* ---------------------------------------------------------------- statements */

enum {
    ST_BEGIN,
    ST_COMMIT,
    ST_ROLLBACK,
    ST_SAVEPOINT,
    ST_RELEASE,
    ST_ROLLBACK_TO,
    ST_BLOB_UPSERT,
    ST_BLOB_INSERT_IGNORE,
    ST_BLOB_TOUCH,
    ST_BLOB_EXISTS,
    ST_BLOB_DELETE,
    ST_BLOB_DIGESTS,
    ST_BLOB_BY_AGE,
    ST_BLOB_TOTAL,
    ST_ACTION_GET,
    ST_ACTION_PUT,
    ST_ACTION_BLOBS_CLEAR,
    ST_ACTION_BLOB_ADD,
    ST_ACTIONS_DROP_FOR,
    ST_ACTION_BLOBS_DROP_FOR,
    ST_ACTIONS_DROP_DANGLING,
    ST_ACTION_BLOBS_DROP_ORPHAN,
    ST_STAMP_GET,
    ST_STAMP_PUT,
    ST_HISTORY_GET,
    ST_HISTORY_PUT,
    ST_RUN_PUT,
    ST_STATS,
    ST_LEASE_GET,
    ST_LEASE_PUT,
    ST_LEASE_RENEW,
    ST_LEASE_DROP,
    ST_LEASE_DROP_MINE,
    ST_COUNT
};

static const char *const sql_text[ST_COUNT] = {
    [ST_BEGIN] = "BEGIN IMMEDIATE",
    [ST_COMMIT] = "COMMIT",
    [ST_ROLLBACK] = "ROLLBACK",
    [ST_SAVEPOINT] = "SAVEPOINT sc_put",
    [ST_RELEASE] = "RELEASE sc_put",
    [ST_ROLLBACK_TO] = "ROLLBACK TO sc_put",
    [ST_BLOB_UPSERT] =
        "INSERT INTO blobs(digest, size, last_used) VALUES(?1, ?2, ?3) "
        "ON CONFLICT(digest) DO UPDATE SET size = excluded.size, "
        "last_used = MAX(last_used, excluded.last_used)",
    [ST_BLOB_INSERT_IGNORE] =
        "INSERT OR IGNORE INTO blobs(digest, size, last_used) VALUES(?1, ?2, ?3)",
    [ST_BLOB_TOUCH] = "UPDATE blobs SET last_used = MAX(last_used, ?2) WHERE digest = ?1",
    [ST_BLOB_EXISTS] = "SELECT 1 FROM blobs WHERE digest = ?1",
    [ST_BLOB_DELETE] = "DELETE FROM blobs WHERE digest = ?1",
    [ST_BLOB_DIGESTS] = "SELECT digest FROM blobs",
    [ST_BLOB_BY_AGE] = "SELECT digest, size FROM blobs ORDER BY last_used, digest",
    [ST_BLOB_TOTAL] = "SELECT COALESCE(SUM(size), 0) FROM blobs",
    [ST_ACTION_GET] =
        "SELECT node_type, outputs, metrics, deps, blobs, seconds FROM actions WHERE key = ?1",
    [ST_ACTION_PUT] =
        "INSERT OR REPLACE INTO actions(key, node_type, outputs, metrics, deps, blobs, "
        "seconds, created) VALUES(?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8)",
    [ST_ACTION_BLOBS_CLEAR] = "DELETE FROM action_blobs WHERE key = ?1",
    [ST_ACTION_BLOB_ADD] = "INSERT INTO action_blobs(key, idx, digest) VALUES(?1, ?2, ?3)",
    [ST_ACTIONS_DROP_FOR] =
        "DELETE FROM actions WHERE key IN (SELECT key FROM action_blobs WHERE digest = ?1)",
    [ST_ACTION_BLOBS_DROP_FOR] =
        "DELETE FROM action_blobs WHERE key IN "
        "(SELECT key FROM action_blobs WHERE digest = ?1)",
    [ST_ACTIONS_DROP_DANGLING] =
        "DELETE FROM actions WHERE key IN (SELECT ab.key FROM action_blobs ab "
        "WHERE NOT EXISTS (SELECT 1 FROM blobs b WHERE b.digest = ab.digest))",
    [ST_ACTION_BLOBS_DROP_ORPHAN] =
        "DELETE FROM action_blobs WHERE NOT EXISTS "
        "(SELECT 1 FROM actions a WHERE a.key = action_blobs.key)",
    [ST_STAMP_GET] = "SELECT size, mtime_ns, inode, digest FROM stamps WHERE path = ?1",
    [ST_STAMP_PUT] =
        "INSERT OR REPLACE INTO stamps(path, size, mtime_ns, inode, digest) "
        "VALUES(?1, ?2, ?3, ?4, ?5)",
    [ST_HISTORY_GET] = "SELECT text FROM history WHERE node_id = ?1",
    [ST_HISTORY_PUT] = "INSERT OR REPLACE INTO history(node_id, text) VALUES(?1, ?2)",
    [ST_RUN_PUT] =
        "INSERT INTO runs(graph, ran, cached, failed, seconds, at) "
        "VALUES(?1, ?2, ?3, ?4, ?5, ?6)",
    [ST_STATS] =
        "SELECT (SELECT COUNT(*) FROM blobs), (SELECT COALESCE(SUM(size), 0) FROM blobs), "
        "(SELECT COUNT(*) FROM actions), (SELECT COUNT(*) FROM stamps), "
        "(SELECT COUNT(*) FROM runs)",
    [ST_LEASE_GET] = "SELECT host, pid, beat FROM leases WHERE key = ?1",
    [ST_LEASE_PUT] = "INSERT OR REPLACE INTO leases(key, host, pid, beat) VALUES(?1, ?2, ?3, ?4)",
    [ST_LEASE_RENEW] = "UPDATE leases SET beat = ?3 WHERE host = ?1 AND pid = ?2",
    [ST_LEASE_DROP] = "DELETE FROM leases WHERE key = ?1 AND host = ?2 AND pid = ?3",
    [ST_LEASE_DROP_MINE] = "DELETE FROM leases WHERE host = ?1 AND pid = ?2",
};

static const char schema_sql[] =
    "CREATE TABLE IF NOT EXISTS blobs(digest TEXT PRIMARY KEY, size INTEGER NOT NULL, "
    "  last_used INTEGER NOT NULL) WITHOUT ROWID;"
    "CREATE TABLE IF NOT EXISTS actions(key TEXT PRIMARY KEY, node_type TEXT, outputs TEXT, "
    "  metrics TEXT, deps TEXT, blobs TEXT, seconds REAL, created INTEGER);"
    "CREATE TABLE IF NOT EXISTS action_blobs(key TEXT NOT NULL, idx INTEGER NOT NULL, "
    "  digest TEXT NOT NULL, PRIMARY KEY(key, idx)) WITHOUT ROWID;"
    "CREATE INDEX IF NOT EXISTS action_blobs_digest ON action_blobs(digest);"
    "CREATE TABLE IF NOT EXISTS stamps(path TEXT PRIMARY KEY, size INTEGER, mtime_ns INTEGER, "
    "  inode INTEGER, digest TEXT) WITHOUT ROWID;"
    "CREATE TABLE IF NOT EXISTS history(node_id TEXT PRIMARY KEY, text TEXT);"
    "CREATE TABLE IF NOT EXISTS runs(id INTEGER PRIMARY KEY, graph TEXT, ran INTEGER, "
    "  cached INTEGER, failed INTEGER, seconds REAL, at INTEGER);"
    "CREATE TABLE IF NOT EXISTS leases(key TEXT PRIMARY KEY, host TEXT NOT NULL, "
    "  pid INTEGER NOT NULL, beat INTEGER NOT NULL) WITHOUT ROWID;";

/* ---------------------------------------------------------------- the struct */

typedef struct touch {
    sc_digest d;      /* a blob digest */
    int64_t when;
} touch;

struct sc_cache {
    char *dir, *objects, *tmp;
    char *notice;            /* said once by the caller: the index was rebuilt */
    sqlite3 *db;
    sqlite3_stmt *st[ST_COUNT];
    int depth;               /* sc_cache_begin nesting */
    int64_t last_clock;      /* last value handed out by clock_us */
    _Atomic unsigned tmp_seq;   /* publish may run on several threads at once */
    touch *touches;
    int ntouches, cap_touches;
};

/* A blob found on disk by a scan of objects/. */
typedef struct disk_blob {
    sc_digest d;
    int64_t size, mtime_us;
} disk_blob;

/* ---------------------------------------------------------------- helpers */

static bool index_damaged_code(int code) {
    code &= 0xff;
    return code == SQLITE_CORRUPT || code == SQLITE_NOTADB;
}

/* A failed statement. A damaged index leaves a marker, so the next open
 * rebuilds it (sc_cache_open). */
static int db_fail(sc_cache *c, sc_error *err, const char *what) {
    int code = sqlite3_errcode(c->db);
    if (index_damaged_code(code)) {
        char *marker = sc_path_join(c->dir, "index.damaged");
        int fd = marker ? open(marker, O_WRONLY | O_CREAT | O_CLOEXEC, 0666) : -1;
        if (fd >= 0) close(fd);
        free(marker);
        return sc_fail(err, SC_EIO, "cache %s: %s: %s (the next run rebuilds the index)", c->dir, what,
                       sqlite3_errmsg(c->db));
    }
    return sc_fail(err, SC_EIO, "cache %s: %s: %s%s", c->dir, what, sqlite3_errmsg(c->db),
                   (code & 0xff) == SQLITE_FULL ? " (the disk is full)" : "");
}

static int64_t wall_ns(void) {
    struct timespec ts;
    clock_gettime(CLOCK_REALTIME, &ts);
    return (int64_t)ts.tv_sec * 1000000000LL + ts.tv_nsec;
}

/* Wall-clock microseconds, strictly increasing within this process. */
static int64_t clock_us(sc_cache *c) {
    int64_t t = wall_ns() / 1000;
    if (t <= c->last_clock) t = c->last_clock + 1;
    c->last_clock = t;
    return t;
}

static int64_t mtime_ns_of(const struct stat *st) {
    return (int64_t)st->st_mtim.tv_sec * 1000000000LL + st->st_mtim.tv_nsec;
}

static sqlite3_stmt *stmt(sc_cache *c, int id, sc_error *err) {
    if (!c->st[id] &&
        sqlite3_prepare_v3(c->db, sql_text[id], -1, SQLITE_PREPARE_PERSISTENT, &c->st[id],
                           NULL) != SQLITE_OK) {
        db_fail(c, err, "cannot prepare a statement");
        sqlite3_finalize(c->st[id]);
        c->st[id] = NULL;
    }
    return c->st[id];
}

static void done(sqlite3_stmt *s) {
    sqlite3_reset(s);
    sqlite3_clear_bindings(s);
}

/* Run a statement with no result rows (bindings already made). */
static int step_done(sc_cache *c, sqlite3_stmt *s, sc_error *err, const char *what) {
    int rc = sqlite3_step(s);
    int out = SC_OK;
    if (rc != SQLITE_DONE && rc != SQLITE_ROW) out = db_fail(c, err, what);
    done(s);
    return out;
}

static int run_simple(sc_cache *c, int id, sc_error *err, const char *what) {
    sqlite3_stmt *s = stmt(c, id, err);
    if (!s) return SC_EIO;
    return step_done(c, s, err, what);
}

static void bind_hex(sqlite3_stmt *s, int i, const sc_digest *d) {
    char hex[65];
    sc_digest_hex(d, hex);
    sqlite3_bind_text(s, i, hex, 64, SQLITE_TRANSIENT);
}

/* Run a statement bound to one digest; adds its change count to *changes. */
static int run_digest(sc_cache *c, int id, const sc_digest *d, int64_t *changes,
                      sc_error *err, const char *what) {
    sqlite3_stmt *s = stmt(c, id, err);
    if (!s) return SC_EIO;
    bind_hex(s, 1, d);
    int rc = step_done(c, s, err, what);
    if (rc == SC_OK && changes) *changes += sqlite3_changes(c->db);
    return rc;
}

/* ---------------------------------------------------------------- transactions */

static void tx_rollback(sc_cache *c) {
    if (c->depth == 0) {
        if (!sqlite3_get_autocommit(c->db)) run_simple(c, ST_ROLLBACK, NULL, "rollback");
    } else if (!sqlite3_get_autocommit(c->db)) {
        run_simple(c, ST_ROLLBACK_TO, NULL, "rollback");
        run_simple(c, ST_RELEASE, NULL, "rollback");
    }
}

/* A write transaction of its own (BEGIN IMMEDIATE), or a savepoint inside
 * the one sc_cache_begin opened. */
static int tx_begin(sc_cache *c, sc_error *err) {
    if (c->depth == 0) return run_simple(c, ST_BEGIN, err, "cannot begin a write transaction");
    if (sqlite3_get_autocommit(c->db))
        return sc_fail(err, SC_EIO,
                       "cache %s: the enclosing transaction was rolled back by an earlier error",
                       c->dir);
    return run_simple(c, ST_SAVEPOINT, err, "cannot begin a savepoint");
}

static int tx_commit(sc_cache *c, sc_error *err) {
    int rc = run_simple(c, c->depth ? ST_RELEASE : ST_COMMIT, err, "cannot commit");
    if (rc) tx_rollback(c);
    return rc;
}

/* Finish a transaction: commit when rc is 0, else roll back and keep rc. */
static int tx_end(sc_cache *c, int rc, sc_error *err) {
    if (rc == SC_OK) return tx_commit(c, err);
    tx_rollback(c);
    return rc;
}

/* ---------------------------------------------------------------- touches */

static int apply_touch(sc_cache *c, const touch *t, sc_error *err) {
    sqlite3_stmt *s = stmt(c, ST_BLOB_TOUCH, err);
    if (!s) return SC_EIO;
    bind_hex(s, 1, &t->d);
    sqlite3_bind_int64(s, 2, t->when);
    return step_done(c, s, err, "cannot record a use");
}

static int cmp_touch(const void *a, const void *b) {
    const touch *x = a, *y = b;
    int r = memcmp(x->d.bytes, y->d.bytes, 32);
    if (r) return r;
    return (x->when > y->when) - (x->when < y->when);
}

/* Write the queued touches, each digest once with its latest time, inside
 * the current transaction (or a savepoint of it). Best effort: they are only
 * hints for gc, so a failure is not reported. */
static void apply_touches(sc_cache *c) {
    if (c->ntouches > 1) qsort(c->touches, (size_t)c->ntouches, sizeof *c->touches, cmp_touch);
    for (int i = 0; i < c->ntouches; i++) {
        if (i + 1 < c->ntouches && sc_digest_equal(&c->touches[i].d, &c->touches[i + 1].d))
            continue;   /* the next one has the same digest and a later time */
        if (apply_touch(c, &c->touches[i], NULL) != SC_OK) break;
    }
    c->ntouches = 0;
}

static void flush_touches(sc_cache *c) {
    if (c->ntouches == 0) return;
    if (tx_begin(c, NULL) == SC_OK) {
        apply_touches(c);
        tx_end(c, SC_OK, NULL);
    }
    c->ntouches = 0;
}

static void add_touches(sc_cache *c, const sc_digest *ds, int n) {
    if (n <= 0) return;
    int64_t now = clock_us(c);
    if (c->ntouches + n > c->cap_touches) {
        int cap = c->cap_touches ? c->cap_touches : 64;
        while (cap < c->ntouches + n) cap *= 2;
        touch *t = sc_realloc_array(c->touches, (size_t)cap, sizeof *t);
        if (!t) return;   /* a lost hint, not an error */
        c->touches = t;
        c->cap_touches = cap;
    }
    for (int i = 0; i < n; i++) c->touches[c->ntouches++] = (touch){ds[i], now};
    if (c->ntouches >= TOUCH_BATCH) flush_touches(c);
}

/* ---------------------------------------------------------------- open/close */

static int exec_sql(sc_cache *c, const char *sql, sc_error *err, const char *what) {
    char *msg = NULL;
    int rc = sqlite3_exec(c->db, sql, NULL, NULL, &msg);
    if (rc == SQLITE_OK) return SC_OK;
    sc_fail(err, SC_EIO, "cache %s: %s: %s", c->dir, what, msg ? msg : sqlite3_errstr(rc));
    sqlite3_free(msg);
    return SC_EIO;
}

static int read_user_version(sc_cache *c, int *version, sc_error *err) {
    sqlite3_stmt *s = NULL;
    if (sqlite3_prepare_v2(c->db, "PRAGMA user_version", -1, &s, NULL) != SQLITE_OK)
        return db_fail(c, err, "cannot read the schema version");
    int rc = sqlite3_step(s);
    if (rc != SQLITE_ROW) {
        int out = db_fail(c, err, "cannot read the schema version");
        sqlite3_finalize(s);
        return out;
    }
    *version = sqlite3_column_int(s, 0);
    sqlite3_finalize(s);
    return SC_OK;
}

static int set_wal(sc_cache *c, sc_error *err) {
    /* Switching a new database to WAL needs a short exclusive lock; a
     * concurrent opener may see SQLITE_BUSY once, so retry for a while. */
    for (int attempt = 0;; attempt++) {
        sqlite3_stmt *s = NULL;
        int rc = sqlite3_prepare_v2(c->db, "PRAGMA journal_mode=WAL", -1, &s, NULL);
        if (rc == SQLITE_OK) rc = sqlite3_step(s);
        sqlite3_finalize(s);
        if (rc == SQLITE_ROW || rc == SQLITE_DONE) return SC_OK;
        if ((rc & 0xff) != SQLITE_BUSY && (rc & 0xff) != SQLITE_LOCKED)
            return db_fail(c, err, "cannot switch to WAL mode");
        if (attempt >= 1000) return db_fail(c, err, "cannot switch to WAL mode");
        struct timespec ts = {0, 10 * 1000 * 1000};
        nanosleep(&ts, NULL);
    }
}

static int init_schema(sc_cache *c, sc_error *err) {
    int version = 0;
    int rc = read_user_version(c, &version, err);
    if (rc) return rc;
    if (version == SCHEMA_VERSION) return SC_OK;
    if (version > SCHEMA_VERSION)
        return sc_fail(err, SC_EIO,
                       "cache %s: index format %d is newer than this seamcook's (%d)",
                       c->dir, version, SCHEMA_VERSION);
    rc = exec_sql(c, "BEGIN IMMEDIATE", err, "cannot begin creating the index");
    if (rc) return rc;
    rc = read_user_version(c, &version, err);   /* another process may have won */
    if (rc == SC_OK && version < SCHEMA_VERSION) {
        rc = exec_sql(c, schema_sql, err, "cannot create the index tables");
        if (rc == SC_OK) {
            char sql[64];
            snprintf(sql, sizeof sql, "PRAGMA user_version=%d", SCHEMA_VERSION);
            rc = exec_sql(c, sql, err, "cannot set the schema version");
        }
    }
    if (rc == SC_OK) return exec_sql(c, "COMMIT", err, "cannot commit the index tables");
    exec_sql(c, "ROLLBACK", NULL, "rollback");
    return rc;
}

static int scan_objects(sc_cache *c, disk_blob **out, size_t *count, int64_t *not_files, sc_error *err);
static int reconcile(sc_cache *c, const disk_blob *disk, size_t ndisk, bool adopt_all, int64_t *missing,
                     int64_t *actions_dropped, sc_error *err);

/* Open the index (created with the umask's mode, which its -wal and -shm
 * files then share), in WAL mode, with the schema. */
static int open_index(sc_cache *c, const char *index, sc_error *err) {
    int fd = open(index, O_RDWR | O_CREAT | O_CLOEXEC, 0666);
    if (fd >= 0) close(fd);
    int src = sqlite3_open_v2(index, &c->db, SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE, NULL);
    if (src != SQLITE_OK)
        return sc_fail(err, SC_EIO, "cache %s: cannot open %s: %s", c->dir, index,
                       c->db ? sqlite3_errmsg(c->db) : sqlite3_errstr(src));
    sqlite3_busy_timeout(c->db, BUSY_TIMEOUT_MS);
    int rc;
    if ((rc = set_wal(c, err)) ||
        (rc = exec_sql(c, "PRAGMA synchronous=NORMAL", err, "cannot set synchronous mode")) ||
        (rc = init_schema(c, err)))
        return rc;
    return SC_OK;
}

/* Whether the open index fails SQLite's quick check: a result other than
 * "ok", or a malformed / not-a-database error. Any other failure (busy,
 * locked, I/O) says nothing of the index and is not taken for damage. */
static bool index_fails_check(sc_cache *c, char *why, size_t n) {
    sqlite3_stmt *s = NULL;
    int rc = sqlite3_prepare_v2(c->db, "PRAGMA quick_check(1)", -1, &s, NULL);
    if (rc == SQLITE_OK) rc = sqlite3_step(s);
    const char *text = rc == SQLITE_ROW ? (const char *)sqlite3_column_text(s, 0) : NULL;
    bool bad = (rc == SQLITE_ROW && (!text || strcmp(text, "ok") != 0)) ||
               (rc != SQLITE_ROW && index_damaged_code(sqlite3_errcode(c->db)));
    if (bad) snprintf(why, n, "%.200s", text ? text : sqlite3_errmsg(c->db));
    sqlite3_finalize(s);
    return bad;
}

static void close_index(sc_cache *c) {
    for (int i = 0; i < ST_COUNT; i++) sqlite3_finalize(c->st[i]), c->st[i] = NULL;
    sqlite3_close(c->db);
    c->db = NULL;
}

/* Move a damaged index aside and make a new one from the blob store: blobs
 * are named by their content, so only action records (and stamps, history)
 * are lost, and the next cooks record them again. One process heals at a
 * time (a lock file); one that finds the index healed meanwhile leaves it. */
static int heal_index(sc_cache *c, const char *index, const char *why, sc_error *err) {
    char *lock = sc_path_join(c->dir, "index.lock");
    int lfd = lock ? open(lock, O_RDWR | O_CREAT | O_CLOEXEC, 0666) : -1;
    free(lock);
    if (lfd >= 0) flock(lfd, LOCK_EX);
    close_index(c);
    char again[256] = "";
    int rc = open_index(c, index, err);
    /* healed meanwhile by another process? (a failure other than damage is
     * that failure, and the index stays where it is) */
    bool still = rc == SC_OK ? index_fails_check(c, again, sizeof again)
                             : index_damaged_code(c->db ? sqlite3_errcode(c->db) : 0);
    char *marker = sc_path_join(c->dir, "index.damaged");
    struct stat st;
    if (!still && rc == SC_OK && marker && stat(marker, &st) == 0) still = true;   /* a statement found it damaged */
    if (still) rc = SC_OK;
    if (still) {
        close_index(c);
        char *aside = sc_strprintf("%s.damaged-%lld", index, (long long)time(NULL));
        char *wal = sc_strprintf("%s-wal", index), *shm = sc_strprintf("%s-shm", index);
        if (aside && rename(index, aside) != 0 && errno != ENOENT)
            rc = sc_fail(err, SC_EIO, "cache %s: the index is damaged (%s) and cannot be moved aside: %s", c->dir,
                         why, strerror(errno));
        if (wal) unlink(wal);
        if (shm) unlink(shm);
        if (marker) unlink(marker);
        disk_blob *disk = NULL;
        size_t ndisk = 0;
        if (rc == SC_OK) rc = open_index(c, index, err);
        if (rc == SC_OK) rc = scan_objects(c, &disk, &ndisk, NULL, err);
        if (rc == SC_OK && (rc = tx_begin(c, err)) == SC_OK) {
            rc = reconcile(c, disk, ndisk, true, NULL, NULL, err);
            rc = tx_end(c, rc, err);
        }
        if (rc == SC_OK)
            c->notice = sc_strprintf("cache %s: the index was damaged (%s); it is now %s, and a new one "
                                     "was made from the %zu blobs in the store (cached actions will be "
                                     "cooked and recorded again)",
                                     c->dir, why, aside ? aside : "moved aside", ndisk);
        free(disk), free(aside), free(wal), free(shm);
    }
    free(marker);
    if (lfd >= 0) close(lfd);   /* releases the lock */
    return rc;
}

/* A file of RESERVE_BYTES that gc deletes first, so that gc can run (its
 * index transactions need a little space) when the disk is full. */
static void make_reserve(const sc_cache *c) {
    char *path = sc_path_join(c->dir, "reserve");
    struct stat st;
    if (path && (stat(path, &st) != 0 || (size_t)st.st_size < RESERVE_BYTES)) {
        int fd = open(path, O_WRONLY | O_CREAT | O_CLOEXEC, 0666);
        if (fd >= 0) {
            if (posix_fallocate(fd, 0, (off_t)RESERVE_BYTES) != 0) {
                if (ftruncate(fd, 0) != 0) {}   /* no room now: try again at the next open */
            }
            close(fd);
        }
    }
    free(path);
}

int sc_cache_open(const char *dir, sc_cache **out, sc_error *err) {
    if (out) *out = NULL;
    if (!dir || !*dir || !out) return sc_fail(err, SC_EUSAGE, "cache: no directory given");
    sc_cache *c = calloc(1, sizeof *c);
    if (!c) return sc_fail(err, SC_ENOMEM, "out of memory");
    c->dir = sc_strdup(dir);
    c->objects = sc_path_join(dir, "objects");
    c->tmp = sc_path_join(dir, "tmp");
    char *index = sc_path_join(dir, "index.sqlite");
    int rc = SC_OK;
    if (!c->dir || !c->objects || !c->tmp || !index) {
        rc = sc_fail(err, SC_ENOMEM, "out of memory");
        goto fail;
    }
    if (strlen(index) + 4 >= SQLITE_PATH_MAX) {   /* + "-wal" */
        rc = sc_fail(err, SC_EUSAGE, "cache %s: the path is too long: SQLite opens files of at most %d bytes, and "
                     "%s is %zu", dir, SQLITE_PATH_MAX - 5, index, strlen(index));
        goto fail;
    }
    if ((rc = sc_make_dirs(c->objects, err)) || (rc = sc_make_dirs(c->tmp, err))) {
        sc_error_prefix(err, "cache %s", dir);
        goto fail;
    }
    char why[256] = "";
    sc_error first = {0};
    char *marker = sc_path_join(dir, "index.damaged");
    struct stat st;
    bool marked = marker && stat(marker, &st) == 0;
    free(marker);
    rc = open_index(c, index, &first);
    bool damaged = marked || (rc != SC_OK && index_damaged_code(c->db ? sqlite3_errcode(c->db) : 0)) ||
                   (rc == SC_OK && index_fails_check(c, why, sizeof why));
    if (damaged) {
        if (!why[0]) snprintf(why, sizeof why, "%.200s", marked ? "a statement found it malformed" : first.message);
        rc = heal_index(c, index, why, err);
    } else if (rc != SC_OK) {
        *err = first;
    }
    if (rc != SC_OK) goto fail;
    make_reserve(c);
    free(index);
    *out = c;
    return SC_OK;
fail:
    free(index);
    sc_cache_close(c);
    return rc;
}

const char *sc_cache_notice(const sc_cache *c) { return c ? c->notice : NULL; }

void sc_cache_close(sc_cache *c) {
    if (!c) return;
    if (c->db) {
        if (c->depth > 0) {   /* an unfinished sc_cache_begin: discard it */
            c->depth = 0;
            tx_rollback(c);
        }
        flush_touches(c);
        for (int i = 0; i < ST_COUNT; i++) sqlite3_finalize(c->st[i]);
        sqlite3_close(c->db);
    }
    free(c->touches);
    free(c->notice);
    free(c->dir);
    free(c->objects);
    free(c->tmp);
    free(c);
}

const char *sc_cache_dir(const sc_cache *c) { return c ? c->dir : NULL; }

/* ---------------------------------------------------------------- transactions (public) */

int sc_cache_begin(sc_cache *c, sc_error *err) {
    if (c->depth == 0) {
        int rc = run_simple(c, ST_BEGIN, err, "cannot begin a write transaction");
        if (rc) return rc;
        c->depth = 1;
        apply_touches(c);
        return SC_OK;
    }
    c->depth++;
    return SC_OK;
}

int sc_cache_commit(sc_cache *c, sc_error *err) {
    if (c->depth == 0)
        return sc_fail(err, SC_EIO, "cache %s: commit without a matching begin", c->dir);
    if (--c->depth > 0) return SC_OK;
    if (!sqlite3_get_autocommit(c->db)) apply_touches(c);
    if (sqlite3_get_autocommit(c->db))
        return sc_fail(err, SC_EIO,
                       "cache %s: the transaction was rolled back by an earlier error", c->dir);
    int rc = run_simple(c, ST_COMMIT, err, "cannot commit");
    if (rc) tx_rollback(c);
    return rc;
}

/* ---------------------------------------------------------------- blobs */

char *sc_cache_blob_path(const sc_cache *c, const sc_digest *d) {
    char hex[65];
    sc_digest_hex(d, hex);
    return sc_strprintf("%s/%.2s/%s", c->objects, hex, hex + 2);
}

bool sc_cache_has_blob(sc_cache *c, const sc_digest *d) {
    char *path = sc_cache_blob_path(c, d);
    struct stat st;
    bool ok = path && stat(path, &st) == 0 && S_ISREG(st.st_mode);
    free(path);
    return ok;
}

static void fsync_dir(const char *dir) {
    int fd = open(dir, O_RDONLY | O_DIRECTORY | O_CLOEXEC);
    if (fd >= 0) {
        fsync(fd);
        close(fd);
    }
}

/* Write bytes to tmp/, fsync, rename to path. */
static int publish(sc_cache *c, const char *hex, const char *path, const void *bytes, size_t n,
                   sc_error *err) {
    char *tmp = sc_strprintf("%s/%.16s-%ld-%u-XXXXXX", c->tmp, hex, (long)getpid(), c->tmp_seq++);
    char *sub = sc_strprintf("%s/%.2s", c->objects, hex);
    if (!tmp || !sub) {
        free(tmp);
        free(sub);
        return sc_fail(err, SC_ENOMEM, "out of memory");
    }
    int rc = SC_OK;
    const char *step = "cannot create a temporary file";
    int fd = mkstemp(tmp);
    if (fd < 0) {
        if (errno == ENOENT && mkdir(c->tmp, 0777) == 0) fd = mkstemp(tmp);
        if (fd < 0) {
            rc = sc_fail(err, SC_EIO, "cache %s: blob %s: %s: %s", c->dir, hex, step,
                         strerror(errno));
            goto out;
        }
    }
    const uint8_t *p = bytes;
    size_t left = n;
    while (left > 0) {
        ssize_t w = write(fd, p, left);
        if (w < 0) {
            if (errno == EINTR) continue;
            step = "write failed";
            goto io_fail;
        }
        p += w;
        left -= (size_t)w;
    }
    step = "cannot finish writing";
    if (fchmod(fd, sc_file_mode()) != 0 || fsync(fd) != 0) goto io_fail;   /* the umask decides */
    if (close(fd) != 0) {
        fd = -1;
        goto io_fail;
    }
    fd = -1;
    step = "cannot publish";
    if (mkdir(sub, 0777) != 0 && errno != EEXIST) goto io_fail;
    if (rename(tmp, path) != 0) goto io_fail;
    fsync_dir(sub);
    goto out;
io_fail:
    rc = sc_fail(err, SC_EIO, "cache %s: blob %s: %s: %s%s", c->dir, hex, step, strerror(errno),
                 errno == ENOSPC || errno == EDQUOT ? " (the disk is full)" : "");
    if (fd >= 0) close(fd);
    unlink(tmp);
out:
    free(tmp);
    free(sub);
    return rc;
}

static bool file_has_size(const char *path, size_t n) {
    struct stat st;
    return stat(path, &st) == 0 && S_ISREG(st.st_mode) && (uint64_t)st.st_size == (uint64_t)n;
}

int sc_cache_write_blob_file(sc_cache *c, const sc_digest *d, const void *bytes, size_t n, sc_error *err) {
    if (!bytes && n > 0) return sc_fail(err, SC_EUSAGE, "cache: write_blob_file without bytes");
    char hex[65];
    sc_digest_hex(d, hex);
    char *path = sc_cache_blob_path(c, d);
    if (!path) return sc_fail(err, SC_ENOMEM, "out of memory");
    int rc = file_has_size(path, n) ? SC_OK : publish(c, hex, path, bytes, n, err);
    free(path);
    return rc;
}

int sc_cache_put_blob(sc_cache *c, const sc_digest *d, const void *bytes, size_t n,
                      sc_error *err) {
    if (!bytes && n > 0) return sc_fail(err, SC_EUSAGE, "cache: put_blob without bytes");
    char hex[65];
    sc_digest_hex(d, hex);
    char *path = sc_cache_blob_path(c, d);
    if (!path) return sc_fail(err, SC_ENOMEM, "out of memory");
    int rc = SC_OK;
    for (int attempt = 0;; attempt++) {
        /* A file of another size is a damaged copy: replace it. */
        if (!file_has_size(path, n) && (rc = publish(c, hex, path, bytes, n, err))) break;
        if ((rc = tx_begin(c, err))) break;
        sqlite3_stmt *s = stmt(c, ST_BLOB_UPSERT, err);
        if (!s) rc = SC_EIO;
        else {
            sqlite3_bind_text(s, 1, hex, 64, SQLITE_TRANSIENT);
            sqlite3_bind_int64(s, 2, (sqlite3_int64)n);
            sqlite3_bind_int64(s, 3, clock_us(c));
            rc = step_done(c, s, err, "cannot record a blob");
        }
        /* Under the write lock now: a gc that removed the file before we got
         * here has finished; put it back rather than record missing bytes. */
        bool vanished = rc == SC_OK && !file_has_size(path, n);
        if (vanished) rc = SC_EMISS;
        rc = tx_end(c, rc, err);
        if (!vanished || rc != SC_EMISS) break;
        if (attempt >= 5) {
            rc = sc_fail(err, SC_EIO, "cache %s: blob %s keeps vanishing while it is stored",
                         c->dir, hex);
            break;
        }
    }
    free(path);
    return rc;
}

/* rm -r: what stands where a blob should (a folder) goes whole. */
static int remove_tree(const char *path) {
    struct stat st;
    if (lstat(path, &st) != 0) return -1;
    if (!S_ISDIR(st.st_mode)) return unlink(path);
    DIR *d = opendir(path);
    if (!d) return -1;
    struct dirent *de;
    while ((de = readdir(d))) {
        if (strcmp(de->d_name, ".") == 0 || strcmp(de->d_name, "..") == 0) continue;
        char *p = sc_path_join(path, de->d_name);
        if (p) remove_tree(p);
        free(p);
    }
    closedir(d);
    return rmdir(path);
}

/* Drop the actions that need these blobs and their rows (one transaction),
 * then remove each file that no row claims again (a second transaction).
 * Adds to the counters that are not NULL. */
static int remove_blobs(sc_cache *c, const sc_digest *ds, const int64_t *sizes, size_t n,
                        int64_t *actions_dropped, int64_t *blobs_removed,
                        int64_t *bytes_removed, sc_error *err) {
    if (n == 0) return SC_OK;
    int64_t dropped = 0;
    int rc = tx_begin(c, err);
    if (rc) return rc;
    for (size_t i = 0; i < n && rc == SC_OK; i++) {
        if ((rc = run_digest(c, ST_ACTIONS_DROP_FOR, &ds[i], &dropped, err,
                             "cannot drop actions")) ||
            (rc = run_digest(c, ST_ACTION_BLOBS_DROP_FOR, &ds[i], NULL, err,
                             "cannot drop actions")) ||
            (rc = run_digest(c, ST_BLOB_DELETE, &ds[i], NULL, err, "cannot forget a blob")))
            break;
    }
    if ((rc = tx_end(c, rc, err))) return rc;
    if (actions_dropped) *actions_dropped += dropped;

    if ((rc = tx_begin(c, err))) return rc;
    int unlink_errno = 0;
    sqlite3_stmt *s = stmt(c, ST_BLOB_EXISTS, err);
    if (!s) rc = SC_EIO;
    for (size_t i = 0; i < n && rc == SC_OK; i++) {
        bind_hex(s, 1, &ds[i]);
        int src = sqlite3_step(s);
        done(s);
        if (src == SQLITE_ROW) continue;   /* stored again meanwhile: keep it */
        if (src != SQLITE_DONE) {
            rc = db_fail(c, err, "cannot look up a blob");
            break;
        }
        char *path = sc_cache_blob_path(c, &ds[i]);
        if (!path) {
            rc = sc_fail(err, SC_ENOMEM, "out of memory");
            break;
        }
        if (unlink(path) == 0 || ((errno == EISDIR || errno == EPERM) && remove_tree(path) == 0)) {
            if (blobs_removed) (*blobs_removed)++;
            if (bytes_removed && sizes) *bytes_removed += sizes[i];
        } else if (errno != ENOENT && !unlink_errno) {
            unlink_errno = errno;
        }
        free(path);
    }
    rc = tx_end(c, rc, err);
    if (rc == SC_OK && unlink_errno)
        rc = sc_fail(err, SC_EIO, "cache %s: cannot remove a blob file: %s", c->dir,
                     strerror(unlink_errno));
    return rc;
}

/* Read a whole file descriptor into out. Returns 0 or an errno value. */
static int read_fd(int fd, sc_buf *out) {
    struct stat st;
    /* One byte more than the size, so the read that sees EOF needs no growth. */
    if (fstat(fd, &st) == 0 && st.st_size > 0 && !sc_buf_reserve(out, (size_t)st.st_size + 1))
        return ENOMEM;
    for (;;) {
        if ((out->cap < out->len + 2) && !sc_buf_reserve(out, 65536)) return ENOMEM;
        ssize_t r = read(fd, out->data + out->len, out->cap - out->len - 1);
        if (r < 0) {
            if (errno == EINTR) continue;
            return errno;
        }
        if (r == 0) break;
        out->len += (size_t)r;
    }
    out->data[out->len] = 0;
    return 0;
}

int sc_cache_get_blob(sc_cache *c, const sc_digest *d, sc_buf *out, sc_error *err) {
    char hex[65];
    sc_digest_hex(d, hex);
    sc_buf_reset(out);
    char *path = sc_cache_blob_path(c, d);
    if (!path) return sc_fail(err, SC_ENOMEM, "out of memory");
    int fd = open(path, O_RDONLY | O_CLOEXEC);
    free(path);
    if (fd < 0) {
        if (errno == ENOENT || errno == ENOTDIR)
            return sc_fail(err, SC_EMISS, "blob %s: not in the cache", hex);
        return sc_fail(err, SC_EIO, "cache %s: blob %s: cannot open: %s", c->dir, hex,
                       strerror(errno));
    }
    struct stat st;
    if (fstat(fd, &st) == 0 && !S_ISREG(st.st_mode)) {   /* a folder, say: no blob there */
        close(fd);
        sc_error ignored;
        remove_blobs(c, d, NULL, 1, NULL, NULL, NULL, &ignored);
        return sc_fail(err, SC_EMISS, "blob %s: not a file in the cache; removed", hex);
    }
    int e = read_fd(fd, out);
    close(fd);
    if (e) {
        sc_buf_reset(out);
        return sc_fail(err, e == ENOMEM ? SC_ENOMEM : SC_EIO, "cache %s: blob %s: cannot read: %s",
                       c->dir, hex, strerror(e));
    }
    sc_digest got;
    sc_digest_bytes(out->data, out->len, &got);
    if (!sc_digest_equal(&got, d)) {
        sc_buf_reset(out);
        char ghex[65];
        sc_digest_hex(&got, ghex);
        sc_error ignored;
        remove_blobs(c, d, NULL, 1, NULL, NULL, NULL, &ignored);
        return sc_fail(err, SC_EMISS,
                       "blob %s: corrupt in the cache (its bytes hash to %s); removed", hex, ghex);
    }
    add_touches(c, d, 1);
    return SC_OK;
}

/* ---------------------------------------------------------------- actions */

void sc_cache_action_free(sc_cache_action *a) {
    if (!a) return;
    free(a->node_type);
    free(a->outputs);
    free(a->metrics);
    for (int i = 0; i < a->ndeps; i++) free(a->deps[i].path);
    free(a->deps);
    free(a->blobs);
    memset(a, 0, sizeof *a);
}

/* 64 hex digits (either case) to a digest; false when malformed. */
static bool parse_hex64(const char *p, sc_digest *d) {
    for (int i = 0; i < 32; i++) {
        int v[2];
        for (int k = 0; k < 2; k++) {
            unsigned char ch = (unsigned char)p[2 * i + k];
            if (ch >= '0' && ch <= '9') v[k] = ch - '0';
            else if ((ch | 0x20) >= 'a' && (ch | 0x20) <= 'f') v[k] = (ch | 0x20) - 'a' + 10;
            else return false;
        }
        d->bytes[i] = (uint8_t)(v[0] << 4 | v[1]);
    }
    return true;
}

static char *column_dup(sqlite3_stmt *s, int col) {
    const unsigned char *t = sqlite3_column_text(s, col);
    int n = sqlite3_column_bytes(s, col);
    return t ? sc_strndup((const char *)t, (size_t)n) : sc_strdup("");
}

/* deps text: "HEX LEN PATH\n" per dep. Returns false when malformed. */
static bool parse_deps(const char *p, size_t n, sc_cache_action *a) {
    const char *end = p + n;
    int cap = 0;
    while (p < end) {
        sc_digest d;
        if (end - p < 66 || p[64] != ' ' || !parse_hex64(p, &d)) return false;
        p += 65;
        size_t len = 0;
        const char *q = p;
        while (q < end && *q >= '0' && *q <= '9' && q - p < 12)
            len = len * 10 + (size_t)(*q++ - '0');
        if (q == p || q >= end || *q != ' ') return false;
        q++;
        if ((size_t)(end - q) < len + 1 || q[len] != '\n') return false;
        if (a->ndeps == cap) {
            cap = cap ? cap * 2 : 4;
            sc_cache_dep *nd = sc_realloc_array(a->deps, (size_t)cap, sizeof *nd);
            if (!nd) return false;
            a->deps = nd;
        }
        char *path = sc_strndup(q, len);
        if (!path) return false;
        a->deps[a->ndeps].path = path;
        a->deps[a->ndeps].digest = d;
        a->ndeps++;
        p = q + len + 1;
    }
    return true;
}

static bool parse_blobs(const char *p, size_t n, sc_cache_action *a) {
    if (n % 64 != 0) return false;
    size_t count = n / 64;
    if (count == 0) return true;
    if (count > INT32_MAX) return false;
    a->blobs = sc_alloc_array(count, sizeof *a->blobs);
    if (!a->blobs) return false;
    for (size_t i = 0; i < count; i++) {
        if (!parse_hex64(p + 64 * i, &a->blobs[i])) return false;
        a->nblobs++;
    }
    return true;
}

int sc_cache_get_action(sc_cache *c, const sc_digest *key, sc_cache_action *out,
                        sc_error *err) {
    memset(out, 0, sizeof *out);
    sqlite3_stmt *s = stmt(c, ST_ACTION_GET, err);
    if (!s) return SC_EIO;
    char hex[65];
    sc_digest_hex(key, hex);
    sqlite3_bind_text(s, 1, hex, 64, SQLITE_STATIC);
    int rc = sqlite3_step(s);
    if (rc == SQLITE_DONE) {
        done(s);
        return sc_fail(err, SC_EMISS, "action %s: not in the cache", hex);
    }
    if (rc != SQLITE_ROW) {
        int out_rc = db_fail(c, err, "cannot look up an action");
        done(s);
        return out_rc;
    }
    out->key = *key;
    out->node_type = column_dup(s, 0);
    out->outputs = column_dup(s, 1);
    out->metrics = column_dup(s, 2);
    out->seconds = sqlite3_column_double(s, 5);
    bool ok = out->node_type && out->outputs && out->metrics;
    const char *deps = (const char *)sqlite3_column_text(s, 3);
    if (ok && deps) ok = parse_deps(deps, (size_t)sqlite3_column_bytes(s, 3), out);
    const char *blobs = (const char *)sqlite3_column_text(s, 4);
    if (ok && blobs) ok = parse_blobs(blobs, (size_t)sqlite3_column_bytes(s, 4), out);
    done(s);
    if (!ok) {
        sc_cache_action_free(out);
        return sc_fail(err, SC_EMISS, "action %s: unreadable record in the cache", hex);
    }
    add_touches(c, out->blobs, out->nblobs);
    return SC_OK;
}

/* Inside put_action's transaction: the blob must still be in the store (a
 * concurrent gc may have removed it since it was put). Its row, when there,
 * gets this use as its last; a file with no row is recorded. Under the write
 * lock, gc cannot remove it after that. */
static int claim_blob(sc_cache *c, const char *key, const sc_digest *d, int64_t now,
                      sc_error *err) {
    touch t = {*d, now};
    int rc = apply_touch(c, &t, err);
    if (rc) return rc;
    if (sqlite3_changes(c->db) > 0) return SC_OK;
    sqlite3_stmt *s;
    char *path = sc_cache_blob_path(c, d);
    struct stat st;
    bool there = path && stat(path, &st) == 0 && S_ISREG(st.st_mode);
    free(path);
    char hex[65];
    sc_digest_hex(d, hex);
    if (!there)
        return sc_fail(err, SC_EMISS,
                       "action %s: blob %s is not in the cache (removed by a concurrent gc?)",
                       key, hex);
    if (!(s = stmt(c, ST_BLOB_INSERT_IGNORE, err))) return SC_EIO;
    sqlite3_bind_text(s, 1, hex, 64, SQLITE_TRANSIENT);
    sqlite3_bind_int64(s, 2, (sqlite3_int64)st.st_size);
    sqlite3_bind_int64(s, 3, now);
    return step_done(c, s, err, "cannot record a blob");
}

int sc_cache_put_action(sc_cache *c, const sc_cache_action *a, sc_error *err) {
    if ((a->ndeps > 0 && !a->deps) || (a->nblobs > 0 && !a->blobs) || a->ndeps < 0 ||
        a->nblobs < 0)
        return sc_fail(err, SC_EUSAGE, "cache: malformed action record");
    char key[65];
    sc_digest_hex(&a->key, key);
    sc_buf deps, blobs;
    sc_buf_init(&deps);
    sc_buf_init(&blobs);
    for (int i = 0; i < a->ndeps; i++) {
        char hex[65];
        const char *path = a->deps[i].path ? a->deps[i].path : "";
        sc_digest_hex(&a->deps[i].digest, hex);
        sc_buf_printf(&deps, "%s %zu ", hex, strlen(path));
        sc_buf_puts(&deps, path);
        sc_buf_u8(&deps, '\n');
    }
    for (int i = 0; i < a->nblobs; i++) {
        char hex[65];
        sc_digest_hex(&a->blobs[i], hex);
        sc_buf_append(&blobs, hex, 64);
    }
    int rc = SC_OK;
    if (deps.failed || blobs.failed || deps.len > INT32_MAX || blobs.len > INT32_MAX) {
        rc = sc_fail(err, SC_ENOMEM, "out of memory");
        goto out;
    }
    if ((rc = tx_begin(c, err))) goto out;
    sqlite3_stmt *s = NULL;
    int64_t now = clock_us(c);
    for (int i = 0; i < a->nblobs && rc == SC_OK; i++)
        rc = claim_blob(c, key, &a->blobs[i], now, err);
    if (rc == SC_OK && !(s = stmt(c, ST_ACTION_PUT, err))) rc = SC_EIO;
    else if (rc == SC_OK) {
        sqlite3_bind_text(s, 1, key, 64, SQLITE_STATIC);
        sqlite3_bind_text(s, 2, a->node_type ? a->node_type : "", -1, SQLITE_STATIC);
        sqlite3_bind_text(s, 3, a->outputs ? a->outputs : "", -1, SQLITE_STATIC);
        sqlite3_bind_text(s, 4, a->metrics ? a->metrics : "", -1, SQLITE_STATIC);
        sqlite3_bind_text(s, 5, deps.data ? (const char *)deps.data : "", (int)deps.len,
                          SQLITE_STATIC);
        sqlite3_bind_text(s, 6, blobs.data ? (const char *)blobs.data : "", (int)blobs.len,
                          SQLITE_STATIC);
        sqlite3_bind_double(s, 7, a->seconds);
        sqlite3_bind_int64(s, 8, (sqlite3_int64)time(NULL));
        rc = step_done(c, s, err, "cannot record an action");
    }
    if (rc == SC_OK) {
        if (!(s = stmt(c, ST_ACTION_BLOBS_CLEAR, err))) rc = SC_EIO;
        else {
            sqlite3_bind_text(s, 1, key, 64, SQLITE_STATIC);
            rc = step_done(c, s, err, "cannot record an action");
        }
    }
    if (rc == SC_OK && !(s = stmt(c, ST_ACTION_BLOB_ADD, err))) rc = SC_EIO;
    for (int i = 0; i < a->nblobs && rc == SC_OK; i++) {
        sqlite3_bind_text(s, 1, key, 64, SQLITE_STATIC);
        sqlite3_bind_int(s, 2, i);
        bind_hex(s, 3, &a->blobs[i]);
        rc = step_done(c, s, err, "cannot record an action's blobs");
    }
    rc = tx_end(c, rc, err);
out:
    sc_buf_free(&deps);
    sc_buf_free(&blobs);
    return rc;
}

/* ---------------------------------------------------------------- sources */

/* Hash an open file in chunks. Returns 0 or an errno value. */
static int hash_fd(int fd, sc_digest *out) {
    uint8_t *chunk = malloc(HASH_CHUNK);
    sc_hasher *h = sc_hasher_new();
    if (!chunk || !h) {
        free(chunk);
        if (h) sc_hasher_final(h, out);
        return ENOMEM;
    }
    int e = 0;
    for (;;) {
        ssize_t r = read(fd, chunk, HASH_CHUNK);
        if (r < 0) {
            if (errno == EINTR) continue;
            e = errno;
            break;
        }
        if (r == 0) break;
        sc_hasher_update(h, chunk, (size_t)r);
    }
    sc_hasher_final(h, out);
    free(chunk);
    return e;
}

static bool same_stat(const struct stat *a, const struct stat *b) {
    return a->st_size == b->st_size && a->st_ino == b->st_ino && a->st_dev == b->st_dev &&
           mtime_ns_of(a) == mtime_ns_of(b);
}

bool sc_cache_file_changed(sc_cache *c, const char *path, const sc_digest *seen, sc_digest *now) {
    sc_digest cur = {0};
    sc_error ignored;
    bool exists = sc_cache_file_digest(c, path, &cur, &ignored) == SC_OK;
    if (now) *now = cur;
    if (sc_digest_is_zero(seen)) return exists;
    return !exists || !sc_digest_equal(&cur, seen);
}

int sc_cache_file_digest(sc_cache *c, const char *path, sc_digest *out, sc_error *err) {
    struct stat st;
    if (stat(path, &st) != 0)
        return sc_fail(err, SC_EINPUT, "%s: cannot open: %s", path, strerror(errno));
    if (!S_ISREG(st.st_mode)) return sc_fail(err, SC_EINPUT, "%s: not a regular file", path);

    sqlite3_stmt *s = stmt(c, ST_STAMP_GET, err);
    if (!s) return SC_EIO;
    sqlite3_bind_text(s, 1, path, -1, SQLITE_STATIC);
    int rc = sqlite3_step(s);
    if (rc == SQLITE_ROW && sqlite3_column_int64(s, 0) == (sqlite3_int64)st.st_size &&
        sqlite3_column_int64(s, 1) == mtime_ns_of(&st) &&
        sqlite3_column_int64(s, 2) == (sqlite3_int64)st.st_ino) {
        const char *hex = (const char *)sqlite3_column_text(s, 3);
        if (hex && sc_digest_parse(hex, out) == 0) {
            done(s);
            return SC_OK;
        }
    } else if (rc != SQLITE_ROW && rc != SQLITE_DONE) {
        int out_rc = db_fail(c, err, "cannot look up a file stamp");
        done(s);
        return out_rc;
    }
    done(s);

    int64_t now = wall_ns();   /* taken before the read: see the design note */
    int fd = open(path, O_RDONLY | O_CLOEXEC);
    if (fd < 0) return sc_fail(err, SC_EINPUT, "%s: cannot open: %s", path, strerror(errno));
    struct stat before, after;
    if (fstat(fd, &before) != 0 || !S_ISREG(before.st_mode)) {
        close(fd);
        return sc_fail(err, SC_EINPUT, "%s: not a regular file", path);
    }
    int e = hash_fd(fd, out);
    bool stable = fstat(fd, &after) == 0 && same_stat(&before, &after);
    close(fd);
    if (e == ENOMEM) return sc_fail(err, SC_ENOMEM, "%s: out of memory", path);
    if (e) return sc_fail(err, SC_EINPUT, "%s: read failed: %s", path, strerror(e));

    int64_t mt = mtime_ns_of(&before);
    if (!stable || now - mt < STAMP_RACY_NS) return SC_OK;   /* too fresh to trust */
    if ((rc = tx_begin(c, err))) return rc;
    if (!(s = stmt(c, ST_STAMP_PUT, err))) rc = SC_EIO;
    else {
        sqlite3_bind_text(s, 1, path, -1, SQLITE_STATIC);
        sqlite3_bind_int64(s, 2, (sqlite3_int64)before.st_size);
        sqlite3_bind_int64(s, 3, mt);
        sqlite3_bind_int64(s, 4, (sqlite3_int64)before.st_ino);
        bind_hex(s, 5, out);
        rc = step_done(c, s, err, "cannot record a file stamp");
    }
    return tx_end(c, rc, err);
}

/* ---------------------------------------------------------------- history */

int sc_cache_get_history(sc_cache *c, const char *node_id, char **text, sc_error *err) {
    *text = NULL;
    sqlite3_stmt *s = stmt(c, ST_HISTORY_GET, err);
    if (!s) return SC_EIO;
    sqlite3_bind_text(s, 1, node_id, -1, SQLITE_STATIC);
    int rc = sqlite3_step(s);
    int out = SC_OK;
    if (rc == SQLITE_ROW) {
        *text = column_dup(s, 0);
        if (!*text) out = sc_fail(err, SC_ENOMEM, "out of memory");
    } else if (rc == SQLITE_DONE) {
        out = sc_fail(err, SC_EMISS, "%s: no history", node_id);
    } else {
        out = db_fail(c, err, "cannot read history");
    }
    done(s);
    return out;
}

int sc_cache_put_history(sc_cache *c, const char *node_id, const char *text, sc_error *err) {
    int rc = tx_begin(c, err);
    if (rc) return rc;
    sqlite3_stmt *s = stmt(c, ST_HISTORY_PUT, err);
    if (!s) rc = SC_EIO;
    else {
        sqlite3_bind_text(s, 1, node_id, -1, SQLITE_STATIC);
        sqlite3_bind_text(s, 2, text ? text : "", -1, SQLITE_STATIC);
        rc = step_done(c, s, err, "cannot record history");
    }
    return tx_end(c, rc, err);
}

int sc_cache_put_run(sc_cache *c, const char *graph, int ran, int cached, int failed,
                     double seconds, sc_error *err) {
    int rc = tx_begin(c, err);
    if (rc) return rc;
    sqlite3_stmt *s = stmt(c, ST_RUN_PUT, err);
    if (!s) rc = SC_EIO;
    else {
        sqlite3_bind_text(s, 1, graph ? graph : "", -1, SQLITE_STATIC);
        sqlite3_bind_int(s, 2, ran);
        sqlite3_bind_int(s, 3, cached);
        sqlite3_bind_int(s, 4, failed);
        sqlite3_bind_double(s, 5, seconds);
        sqlite3_bind_int64(s, 6, (sqlite3_int64)time(NULL));
        rc = step_done(c, s, err, "cannot record a run");
    }
    return tx_end(c, rc, err);
}

/* ---------------------------------------------------------------- leases */

/* This process: the host name and the pid. */
static void lease_self(char host[256], int64_t *pid) {
    if (gethostname(host, 255) != 0) strcpy(host, "localhost");
    host[255] = 0;
    *pid = (int64_t)getpid();
}

static int64_t wall_ms(void) { return wall_ns() / 1000000; }

/* Whether a lease holder is gone: a process on this host that no longer
 * exists, or a heartbeat older than stale_ms (another host, or a process
 * that hangs). */
static bool holder_gone(const char *host, int64_t pid, int64_t beat, int64_t stale_ms) {
    char me[256];
    int64_t my_pid;
    lease_self(me, &my_pid);
    if (strcmp(host, me) == 0 && pid > 0 && kill((pid_t)pid, 0) != 0 && errno == ESRCH) return true;
    return wall_ms() - beat > stale_ms;
}

int sc_cache_lease_take(sc_cache *c, const sc_digest *key, double stale_seconds,
                        sc_cache_lease_holder *holder, sc_error *err) {
    char me[256];
    int64_t my_pid;
    lease_self(me, &my_pid);
    if (holder) memset(holder, 0, sizeof *holder);
    int rc = tx_begin(c, err);
    if (rc) return rc;
    sqlite3_stmt *s = stmt(c, ST_LEASE_GET, err);
    if (!s) return tx_end(c, SC_EIO, err);
    bind_hex(s, 1, key);
    int step = sqlite3_step(s);
    bool busy = false;
    if (step == SQLITE_ROW) {
        const char *host = (const char *)sqlite3_column_text(s, 0);
        int64_t pid = sqlite3_column_int64(s, 1), beat = sqlite3_column_int64(s, 2);
        bool mine = host && strcmp(host, me) == 0 && pid == my_pid;
        if (!mine && holder) {
            snprintf(holder->host, sizeof holder->host, "%s", host ? host : "");
            holder->pid = pid;
            holder->age_seconds = (double)(wall_ms() - beat) / 1000.0;
        }
        busy = !mine && !holder_gone(host ? host : "", pid, beat, (int64_t)(stale_seconds * 1000));
        if (!mine && !busy && holder) holder->taken_over = true;
    } else if (step != SQLITE_DONE) {
        rc = db_fail(c, err, "cannot read a lease");
    }
    done(s);
    if (rc == SC_OK && !busy) {
        s = stmt(c, ST_LEASE_PUT, err);
        if (!s) rc = SC_EIO;
        else {
            bind_hex(s, 1, key);
            sqlite3_bind_text(s, 2, me, -1, SQLITE_TRANSIENT);
            sqlite3_bind_int64(s, 3, my_pid);
            sqlite3_bind_int64(s, 4, wall_ms());
            rc = step_done(c, s, err, "cannot take a lease");
        }
    }
    rc = tx_end(c, rc, err);
    if (rc == SC_OK && busy)
        return sc_fail(err, SC_EBUSY, "%s (pid %lld) is cooking it", holder ? holder->host : "another process",
                       holder ? (long long)holder->pid : 0LL);
    return rc;
}

/* Run a lease statement bound to (host, pid) at 1-2 and, for ST_LEASE_DROP,
 * the key at 1 and (host, pid) at 2-3. */
static int lease_write(sc_cache *c, int id, const sc_digest *key, sc_error *err, const char *what) {
    char me[256];
    int64_t my_pid;
    lease_self(me, &my_pid);
    int rc = tx_begin(c, err);
    if (rc) return rc;
    sqlite3_stmt *s = stmt(c, id, err);
    if (!s) return tx_end(c, SC_EIO, err);
    int at = 1;
    if (key) bind_hex(s, at++, key);
    sqlite3_bind_text(s, at++, me, -1, SQLITE_TRANSIENT);
    sqlite3_bind_int64(s, at++, my_pid);
    if (id == ST_LEASE_RENEW) sqlite3_bind_int64(s, at, wall_ms());
    return tx_end(c, step_done(c, s, err, what), err);
}

int sc_cache_lease_renew(sc_cache *c, sc_error *err) {
    return lease_write(c, ST_LEASE_RENEW, NULL, err, "cannot renew leases");
}

int sc_cache_lease_release(sc_cache *c, const sc_digest *key, sc_error *err) {
    return lease_write(c, key ? ST_LEASE_DROP : ST_LEASE_DROP_MINE, key, err, "cannot release a lease");
}

/* ---------------------------------------------------------------- upkeep */

int sc_cache_stats_get(sc_cache *c, sc_cache_stats *out, sc_error *err) {
    memset(out, 0, sizeof *out);
    sqlite3_stmt *s = stmt(c, ST_STATS, err);
    if (!s) return SC_EIO;
    int rc = sqlite3_step(s);
    int res = SC_OK;
    if (rc == SQLITE_ROW) {
        out->blobs = sqlite3_column_int64(s, 0);
        out->blob_bytes = sqlite3_column_int64(s, 1);
        out->actions = sqlite3_column_int64(s, 2);
        out->stamps = sqlite3_column_int64(s, 3);
        out->runs = sqlite3_column_int64(s, 4);
    } else {
        res = db_fail(c, err, "cannot count");
    }
    done(s);
    return res;
}

static bool is_lower_hex(const char *s, size_t n) {
    for (size_t i = 0; i < n; i++)
        if (!((s[i] >= '0' && s[i] <= '9') || (s[i] >= 'a' && s[i] <= 'f'))) return false;
    return s[n] == 0;
}

static int cmp_disk_blob(const void *a, const void *b) {
    return memcmp(((const disk_blob *)a)->d.bytes, ((const disk_blob *)b)->d.bytes, 32);
}

/* Every blob file under objects/, sorted by digest. Entries with a blob's
 * name that are not regular files (a folder, a device) are removed, and
 * counted in *not_files (may be NULL). */
static int scan_objects(sc_cache *c, disk_blob **out, size_t *count, int64_t *not_files, sc_error *err) {
    *out = NULL;
    *count = 0;
    DIR *top = opendir(c->objects);
    if (!top) {
        if (errno == ENOENT) return SC_OK;
        return sc_fail(err, SC_EIO, "cache %s: cannot list %s: %s", c->dir, c->objects,
                       strerror(errno));
    }
    size_t cap = 0;
    int rc = SC_OK;
    struct dirent *de;
    while (rc == SC_OK && (de = readdir(top))) {
        if (strlen(de->d_name) != 2 || !is_lower_hex(de->d_name, 2)) continue;
        char *sub = sc_strprintf("%s/%s", c->objects, de->d_name);
        DIR *dd = sub ? opendir(sub) : NULL;
        if (!dd) {
            free(sub);
            continue;
        }
        struct dirent *fe;
        while ((fe = readdir(dd))) {
            if (strlen(fe->d_name) != 62 || !is_lower_hex(fe->d_name, 62)) continue;
            char hex[65];
            memcpy(hex, de->d_name, 2);
            memcpy(hex + 2, fe->d_name, 63);
            char *fp = sc_strprintf("%s/%s", sub, fe->d_name);
            struct stat st;
            bool there = fp && lstat(fp, &st) == 0;
            bool ok = there && S_ISREG(st.st_mode);
            if (there && !ok && remove_tree(fp) == 0 && not_files) (*not_files)++;
            free(fp);
            if (!ok) continue;
            if (*count == cap) {
                size_t ncap = cap ? cap * 2 : 256;
                disk_blob *n = sc_realloc_array(*out, ncap, sizeof *n);
                if (!n) {
                    rc = sc_fail(err, SC_ENOMEM, "out of memory");
                    break;
                }
                *out = n;
                cap = ncap;
            }
            disk_blob *b = &(*out)[(*count)++];
            sc_digest_parse(hex, &b->d);
            b->size = (int64_t)st.st_size;
            b->mtime_us = mtime_ns_of(&st) / 1000;
        }
        closedir(dd);
        free(sub);
    }
    closedir(top);
    if (rc) {
        free(*out);
        *out = NULL;
        *count = 0;
        return rc;
    }
    if (*count > 1) qsort(*out, *count, sizeof **out, cmp_disk_blob);
    return SC_OK;
}

/* Inside a write transaction: make the blobs table match the disk (record
 * files it lacks, forget rows whose file is gone) and drop the actions that
 * need a blob with no row. A file with no row that is younger than an hour
 * is left alone: it may be a publish whose row is about to be written (a
 * crashed publish leaves an old file, adopted later); adopt_all takes them
 * all (an index rebuilt from the store). */
static int reconcile(sc_cache *c, const disk_blob *disk, size_t ndisk, bool adopt_all, int64_t *missing,
                     int64_t *actions_dropped, sc_error *err) {
    sqlite3_stmt *s = stmt(c, ST_BLOB_INSERT_IGNORE, err);
    if (!s) return SC_EIO;
    int rc = SC_OK;
    int64_t adopt_before = wall_ns() / 1000 - (int64_t)TMP_MAX_AGE_S * 1000000;
    for (size_t i = 0; i < ndisk && rc == SC_OK; i++) {
        if (!adopt_all && disk[i].mtime_us > adopt_before) continue;
        bind_hex(s, 1, &disk[i].d);
        sqlite3_bind_int64(s, 2, disk[i].size);
        sqlite3_bind_int64(s, 3, disk[i].mtime_us);
        rc = step_done(c, s, err, "cannot record a blob");
    }
    if (rc) return rc;

    /* Rows whose file is gone: collect first, then delete. */
    sc_digest *gone = NULL;
    size_t ngone = 0, cap = 0;
    if (!(s = stmt(c, ST_BLOB_DIGESTS, err))) return SC_EIO;
    int src;
    while ((src = sqlite3_step(s)) == SQLITE_ROW) {
        const char *hex = (const char *)sqlite3_column_text(s, 0);
        disk_blob key;
        if (!hex || sc_digest_parse(hex, &key.d) != 0) continue;
        if (ndisk && bsearch(&key, disk, ndisk, sizeof *disk, cmp_disk_blob)) continue;
        char *path = sc_cache_blob_path(c, &key.d);
        struct stat st;
        bool there = path && stat(path, &st) == 0;
        free(path);
        if (there) continue;
        if (ngone == cap) {
            size_t ncap = cap ? cap * 2 : 64;
            sc_digest *n = sc_realloc_array(gone, ncap, sizeof *n);
            if (!n) {
                rc = sc_fail(err, SC_ENOMEM, "out of memory");
                break;
            }
            gone = n;
            cap = ncap;
        }
        gone[ngone++] = key.d;
    }
    if (rc == SC_OK && src != SQLITE_DONE && src != SQLITE_ROW)
        rc = db_fail(c, err, "cannot list blobs");
    done(s);
    for (size_t i = 0; i < ngone && rc == SC_OK; i++)
        rc = run_digest(c, ST_BLOB_DELETE, &gone[i], NULL, err, "cannot forget a blob");
    free(gone);
    if (rc) return rc;
    if (missing) *missing += (int64_t)ngone;

    if ((rc = run_simple(c, ST_ACTIONS_DROP_DANGLING, err, "cannot drop actions"))) return rc;
    if (actions_dropped) *actions_dropped += sqlite3_changes(c->db);
    return run_simple(c, ST_ACTION_BLOBS_DROP_ORPHAN, err, "cannot drop actions");
}

int sc_cache_verify(sc_cache *c, sc_cache_verify_result *out, sc_error *err) {
    memset(out, 0, sizeof *out);
    if (c->depth > 0)
        return sc_fail(err, SC_EUSAGE, "cache %s: verify inside a transaction", c->dir);
    flush_touches(c);
    char why[256];
    if (index_fails_check(c, why, sizeof why)) {
        char *index = sc_path_join(c->dir, "index.sqlite");
        int rc = index ? heal_index(c, index, why, err) : sc_fail(err, SC_ENOMEM, "out of memory");
        free(index);
        if (rc) return rc;
        out->index_rebuilt = true;
    }
    disk_blob *disk = NULL;
    size_t ndisk = 0;
    int rc = scan_objects(c, &disk, &ndisk, &out->not_files, err);
    if (rc) return rc;
    size_t ngood = 0;
    for (size_t i = 0; i < ndisk && rc == SC_OK; i++) {
        char *path = sc_cache_blob_path(c, &disk[i].d);
        if (!path) {
            rc = sc_fail(err, SC_ENOMEM, "out of memory");
            break;
        }
        int fd = open(path, O_RDONLY | O_CLOEXEC);
        free(path);
        if (fd < 0) continue;   /* removed meanwhile */
        sc_digest got;
        int e = hash_fd(fd, &got);
        close(fd);
        if (e == ENOMEM) {
            rc = sc_fail(err, SC_ENOMEM, "out of memory");
            break;
        }
        out->checked++;
        if (e || !sc_digest_equal(&got, &disk[i].d)) {
            out->bad++;
            rc = remove_blobs(c, &disk[i].d, NULL, 1, &out->actions_dropped, NULL, NULL, err);
        } else {
            disk[ngood++] = disk[i];   /* stays sorted */
        }
    }
    if (rc == SC_OK && (rc = tx_begin(c, err)) == SC_OK) {
        rc = reconcile(c, disk, ngood, false, &out->missing, &out->actions_dropped, err);
        rc = tx_end(c, rc, err);
    }
    free(disk);
    return rc;
}

static void clean_tmp(sc_cache *c) {
    DIR *d = opendir(c->tmp);
    if (!d) return;
    time_t limit = time(NULL) - TMP_MAX_AGE_S;
    struct dirent *de;
    while ((de = readdir(d))) {
        if (de->d_name[0] == '.') continue;
        char *p = sc_strprintf("%s/%s", c->tmp, de->d_name);
        struct stat st;
        if (p && lstat(p, &st) == 0 && S_ISREG(st.st_mode) && st.st_mtime < limit) unlink(p);
        free(p);
    }
    closedir(d);
}

int sc_cache_gc(sc_cache *c, int64_t max_bytes, sc_cache_gc_result *out, sc_error *err) {
    memset(out, 0, sizeof *out);
    if (max_bytes < 0) return sc_fail(err, SC_EUSAGE, "cache gc: the size limit must be >= 0");
    if (c->depth > 0)
        return sc_fail(err, SC_EUSAGE, "cache %s: gc inside a transaction", c->dir);
    flush_touches(c);
    char *reserve = sc_path_join(c->dir, "reserve");
    if (reserve) unlink(reserve);   /* room for the index's transactions on a full disk */
    free(reserve);
    clean_tmp(c);
    disk_blob *disk = NULL;
    size_t ndisk = 0;
    int rc = scan_objects(c, &disk, &ndisk, NULL, err);
    if (rc) return rc;

    /* Phase 1 (one transaction): reconcile, choose the least recently used
     * blobs to remove until the total fits. remove_blobs then drops them. */
    sc_digest *victims = NULL;
    int64_t *sizes = NULL;
    size_t nvictims = 0, cap = 0;
    if ((rc = tx_begin(c, err))) goto out;
    rc = reconcile(c, disk, ndisk, false, NULL, &out->actions_dropped, err);
    int64_t total = 0;
    sqlite3_stmt *s = NULL;
    if (rc == SC_OK && !(s = stmt(c, ST_BLOB_TOTAL, err))) rc = SC_EIO;
    if (rc == SC_OK) {
        if (sqlite3_step(s) == SQLITE_ROW) total = sqlite3_column_int64(s, 0);
        else rc = db_fail(c, err, "cannot sum blob sizes");
        done(s);
    }
    if (rc == SC_OK && total > max_bytes) {
        if (!(s = stmt(c, ST_BLOB_BY_AGE, err))) rc = SC_EIO;
        int src = SQLITE_DONE;
        while (rc == SC_OK && total > max_bytes && (src = sqlite3_step(s)) == SQLITE_ROW) {
            const char *hex = (const char *)sqlite3_column_text(s, 0);
            sc_digest d;
            if (!hex || sc_digest_parse(hex, &d) != 0) continue;
            if (nvictims == cap) {
                size_t ncap = cap ? cap * 2 : 64;
                sc_digest *nv = sc_realloc_array(victims, ncap, sizeof *nv);
                int64_t *ns = sc_realloc_array(sizes, ncap, sizeof *ns);
                if (nv) victims = nv;
                if (ns) sizes = ns;
                if (!nv || !ns) {
                    rc = sc_fail(err, SC_ENOMEM, "out of memory");
                    break;
                }
                cap = ncap;
            }
            victims[nvictims] = d;
            sizes[nvictims] = sqlite3_column_int64(s, 1);
            total -= sizes[nvictims];
            nvictims++;
        }
        if (rc == SC_OK && src != SQLITE_ROW && src != SQLITE_DONE)
            rc = db_fail(c, err, "cannot list blobs");
        if (s) done(s);
    }
    if ((rc = tx_end(c, rc, err))) goto out;

    rc = remove_blobs(c, victims, sizes, nvictims, &out->actions_dropped, &out->blobs_removed,
                      &out->bytes_removed, err);
    if (rc == SC_OK) {
        if (!(s = stmt(c, ST_BLOB_TOTAL, err))) rc = SC_EIO;
        else {
            if (sqlite3_step(s) == SQLITE_ROW) out->bytes_left = sqlite3_column_int64(s, 0);
            else rc = db_fail(c, err, "cannot sum blob sizes");
            done(s);
        }
    }
out:
    free(victims);
    free(sizes);
    free(disk);
    make_reserve(c);
    return rc;
}
