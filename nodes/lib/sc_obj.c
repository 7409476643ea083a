/* sc_obj.c - Wavefront OBJ + MTL reader (see sc_obj.h for what it accepts).
 *
 * Design note: one pass over the bytes, one logical line at a time (a line
 * with a trailing '\' continues on the next one). Each logical line is copied
 * into a NUL-terminated scratch buffer, so strtod never runs past the caller's
 * bytes and continuations need no special case in the statement parsers.
 * Elements (v, vt, vn) and fan-triangulated faces go into growable arrays;
 * faces keep their line number so that positive indices, which may point
 * forward, are checked against the final counts once the file is read and an
 * out-of-range index is still reported at its line. Negative indices are
 * resolved at once against the counts so far. The last step, shared with the
 * glTF reader, drops index-degenerate triangles and unreferenced elements.
 * Material names live in a small open-addressing hash table so that files
 * with many usemtl statements stay linear.
 */
#include "sc_obj.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

const sc_kernel sc_kernel_obj = {"obj", SC_OBJ_VERSION, NULL};

/* ---------------------------------------------------------------- helpers */

/* Grow *items (of elem bytes each) so that it holds at least `need`. */
static bool grow(void **items, int64_t *cap, int64_t need, size_t elem) {
    if (need <= *cap) return true;
    int64_t c = *cap ? *cap : 256;
    while (c < need) c *= 2;
    void *q = sc_realloc_array(*items, (size_t)c, elem);
    if (!q) return false;
    *items = q;
    *cap = c;
    return true;
}

static bool is_space(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\f' || c == '\v'; }
static bool is_alpha(char c) { return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z'); }
static bool is_digit(char c) { return c >= '0' && c <= '9'; }

static const char *skip_space(const char *s) {
    while (is_space(*s)) s++;
    return s;
}

/* Trim trailing white space in place. */
static void trim_end(char *s) {
    size_t n = strlen(s);
    while (n > 0 && is_space(s[n - 1])) s[--n] = 0;
}

/* A short printable quote of some text for messages: non-printable bytes as
 * \xNN, at most ~40 characters. */
static const char *snippet(const char *s, char out[256]) { return sc_excerpt(s, 40, true, out, 256); }

/* ---------------------------------------------------------------- name table */

/* Strings -> dense indices in insertion order. */
typedef struct name_table {
    char **names;
    int64_t count, cap;
    int32_t *slots;   /* open addressing; -1 = empty */
    int64_t nslots;
} name_table;

static uint64_t hash_string(const char *s) {
    uint64_t h = 1469598103934665603ull;   /* FNV-1a */
    for (; *s; s++) h = (h ^ (unsigned char)*s) * 1099511628211ull;
    return h;
}

static void names_free(name_table *t) {
    for (int64_t i = 0; i < t->count; i++) free(t->names[i]);
    free(t->names);
    free(t->slots);
    memset(t, 0, sizeof *t);
}

static int32_t names_find(const name_table *t, const char *name) {
    if (!t->nslots) return -1;
    for (uint64_t i = hash_string(name) & (uint64_t)(t->nslots - 1);; i = (i + 1) & (uint64_t)(t->nslots - 1)) {
        int32_t k = t->slots[i];
        if (k < 0) return -1;
        if (strcmp(t->names[k], name) == 0) return k;
    }
}

static bool names_rehash(name_table *t, int64_t nslots) {
    int32_t *slots = sc_alloc_array((size_t)nslots, sizeof *slots);
    if (!slots) return false;
    for (int64_t i = 0; i < nslots; i++) slots[i] = -1;
    for (int64_t k = 0; k < t->count; k++) {
        uint64_t i = hash_string(t->names[k]) & (uint64_t)(nslots - 1);
        while (slots[i] >= 0) i = (i + 1) & (uint64_t)(nslots - 1);
        slots[i] = (int32_t)k;
    }
    free(t->slots);
    t->slots = slots;
    t->nslots = nslots;
    return true;
}

/* Index of name, adding it when new; -1 when out of memory. */
static int32_t names_add(name_table *t, const char *name, bool *added) {
    int32_t k = names_find(t, name);
    if (added) *added = k < 0;
    if (k >= 0) return k;
    if ((t->count + 1) * 2 > t->nslots && !names_rehash(t, t->nslots ? t->nslots * 2 : 16))
        return -1;
    if (!grow((void **)&t->names, &t->cap, t->count + 1, sizeof(char *))) return -1;
    char *copy = sc_strdup(name);
    if (!copy) return -1;
    t->names[t->count] = copy;
    uint64_t i = hash_string(name) & (uint64_t)(t->nslots - 1);
    while (t->slots[i] >= 0) i = (i + 1) & (uint64_t)(t->nslots - 1);
    t->slots[i] = (int32_t)t->count;
    return (int32_t)t->count++;
}

/* ---------------------------------------------------------------- lines */

typedef struct line_reader {
    const char *name;        /* file name for messages */
    const char *p, *end;
    int next_line;           /* number of the next physical line */
    int line;                /* number of the first line of the current statement */
    sc_buf text;             /* the logical line, NUL-terminated */
} line_reader;

static void lines_init(line_reader *lr, const char *name, const void *bytes, size_t size) {
    memset(lr, 0, sizeof *lr);
    lr->name = name;
    lr->p = bytes;
    lr->end = lr->p + size;
    lr->next_line = 1;
    if (size >= 3 && memcmp(bytes, "\xEF\xBB\xBF", 3) == 0) lr->p += 3;   /* UTF-8 BOM */
}

/* The next logical line in lr->text; *got is false at the end of the input.
 * Returns SC_OK or an error code with err filled. */
static int lines_next(line_reader *lr, bool *got, sc_error *err) {
    *got = false;
    if (lr->p >= lr->end) return SC_OK;
    sc_buf_reset(&lr->text);
    lr->line = lr->next_line;
    for (;;) {
        const char *nl = memchr(lr->p, '\n', (size_t)(lr->end - lr->p));
        const char *e = nl ? nl : lr->end;
        if (memchr(lr->p, 0, (size_t)(e - lr->p)))
            return sc_fail(err, SC_EINPUT, "%s:%d: NUL byte: not a text file", lr->name,
                           lr->next_line);
        const char *s = lr->p;
        lr->p = nl ? nl + 1 : lr->end;
        lr->next_line++;
        while (e > s && is_space(e[-1])) e--;
        bool more = e > s && e[-1] == '\\';
        sc_buf_append(&lr->text, s, (size_t)(e - s - (more ? 1 : 0)));
        if (!more || lr->p >= lr->end) break;
        sc_buf_append(&lr->text, " ", 1);
    }
    if (!sc_buf_reserve(&lr->text, 0))
        return sc_fail(err, SC_ENOMEM, "%s:%d: out of memory", lr->name, lr->line);
    lr->text.data[lr->text.len] = 0;
    *got = true;
    return SC_OK;
}

/* Split "keyword rest": returns the keyword (NUL-terminated in place) or ""
 * for a blank/comment line; *rest points past the following white space.
 * Fills err and returns NULL for a line that does not start with a keyword. */
static char *split_keyword(line_reader *lr, char **rest, sc_error *err) {
    char *s = (char *)skip_space((char *)lr->text.data);
    if (*s == 0 || *s == '#') {
        *rest = s;
        return s + strlen(s);   /* "" */
    }
    char *k = s;
    bool ok = is_alpha(*s) || *s == '_';
    while (*s && !is_space(*s)) {
        if (!is_alpha(*s) && !is_digit(*s) && *s != '_') ok = false;
        s++;
    }
    if (!ok) {
        char q[256];
        sc_fail(err, SC_EINPUT, "%s:%d: unexpected text '%s' (not a statement)", lr->name,
                lr->line, snippet(k, q));
        return NULL;
    }
    if (*s) *s++ = 0;
    *rest = (char *)skip_space(s);
    return k;
}

/* Parse every white-space separated number of `s` (at least min, keeping at
 * most max in out). Fills err naming what and the line. */
static int parse_numbers(line_reader *lr, const char *what, const char *s, double *out, int min,
                         int max, int *count, sc_error *err) {
    int n = 0;
    for (;;) {
        s = skip_space(s);
        if (!*s) break;
        char *e = NULL;
        double x = strtod(s, &e);
        char q[256];
        if (e == s || (*e && !is_space(*e)))
            return sc_fail(err, SC_EINPUT, "%s:%d: %s: '%s' is not a number", lr->name,
                           lr->line, what, snippet(s, q));
        if (!isfinite(x))
            return sc_fail(err, SC_EINPUT, "%s:%d: %s: coordinate %d is not finite ('%s')",
                           lr->name, lr->line, what, n + 1, snippet(s, q));
        if (n < max) out[n] = x + 0.0;   /* -0 becomes +0 */
        n++;
        s = e;
    }
    if (n < min)
        return sc_fail(err, SC_EINPUT, "%s:%d: %s needs %d number%s, found %d", lr->name,
                       lr->line, what, min, min == 1 ? "" : "s", n);
    *count = n < max ? n : max;
    return SC_OK;
}

/* ---------------------------------------------------------------- the parser */

enum { SLOT_COLOR, SLOT_NORMAL, SLOT_EMISSIVE, NSLOTS };
static const char *const slot_names[NSLOTS] = {"color", "normal", "emissive"};

/* A material as an MTL defines it. */
typedef struct mtl_material {
    char *path[NSLOTS];
    int priority[NSLOTS];   /* lower wins: norm before map_Bump */
    int line[NSLOTS];
    int32_t file;           /* index into parser.mtl_files */
} mtl_material;

typedef struct parser {
    const char *name;
    sc_error *err;
    sc_obj_read_fn read_mtl;
    void *ud;

    double *v, *vt, *vn;
    int64_t nv, nvt, nvn, capv, capvt, capvn;

    int32_t *fv, *fu, *fn, *fm, *fline;   /* per triangle: 3, 3, 3, 1, 1 */
    int64_t nt, capfv, capfu, capfn, capfm, capfline;
    bool all_normals;
    int64_t polygons;
    int64_t faces_without_uv;   /* triangles whose corners name no vt */

    name_table used;         /* materials faces use, in order of first use */
    char *usemtl;            /* the current usemtl name (NULL: "default") */
    int32_t current;         /* its index in used, -1 until a face needs it */

    name_table mtl_names;    /* materials MTL files define */
    mtl_material *mtl;
    int64_t capmtl;
    name_table mtl_files;    /* MTL files read */

    int64_t *corner;         /* scratch: 3 per corner (v, vt, vn) of one face */
    int64_t capcorner;
} parser;

static void parser_free(parser *p) {
    free(p->v), free(p->vt), free(p->vn);
    free(p->fv), free(p->fu), free(p->fn), free(p->fm), free(p->fline);
    names_free(&p->used);
    free(p->usemtl);
    for (int64_t i = 0; i < p->mtl_names.count; i++)
        for (int s = 0; s < NSLOTS; s++) free(p->mtl[i].path[s]);
    free(p->mtl);
    names_free(&p->mtl_names);
    names_free(&p->mtl_files);
    free(p->corner);
}

static int out_of_memory(parser *p, const line_reader *lr) {
    return sc_fail(p->err, SC_ENOMEM, "%s:%d: out of memory", lr->name, lr->line);
}

static int too_many(parser *p, const line_reader *lr, const char *what) {
    return sc_fail(p->err, SC_ENOMEM, "%s:%d: more than %d %s (the limit)", lr->name, lr->line,
                   SC_OBJ_MAX_ELEMENTS, what);
}

/* v, vt, vn */
static int add_element(parser *p, line_reader *lr, const char *kw, const char *rest) {
    double x[3] = {0, 0, 0};
    int n = 0, rc;
    if (kw[1] == 0) {
        if ((rc = parse_numbers(lr, "vertex", rest, x, 3, 3, &n, p->err))) return rc;
        if (p->nv >= SC_OBJ_MAX_ELEMENTS) return too_many(p, lr, "vertices");
        if (!grow((void **)&p->v, &p->capv, 3 * (p->nv + 1), sizeof(double)))
            return out_of_memory(p, lr);
        memcpy(p->v + 3 * p->nv++, x, sizeof x);
    } else if (kw[1] == 't') {
        if ((rc = parse_numbers(lr, "texture coordinate", rest, x, 1, 2, &n, p->err))) return rc;
        if (p->nvt >= SC_OBJ_MAX_ELEMENTS) return too_many(p, lr, "texture coordinates");
        if (!grow((void **)&p->vt, &p->capvt, 2 * (p->nvt + 1), sizeof(double)))
            return out_of_memory(p, lr);
        memcpy(p->vt + 2 * p->nvt++, x, 2 * sizeof(double));
    } else {
        if ((rc = parse_numbers(lr, "normal", rest, x, 3, 3, &n, p->err))) return rc;
        if (p->nvn >= SC_OBJ_MAX_ELEMENTS) return too_many(p, lr, "normals");
        if (!grow((void **)&p->vn, &p->capvn, 3 * (p->nvn + 1), sizeof(double)))
            return out_of_memory(p, lr);
        memcpy(p->vn + 3 * p->nvn++, x, sizeof x);
    }
    return SC_OK;
}

/* One index of a face corner at *s. Positive indices are kept 1-based (checked
 * at the end); negative ones are resolved against `count` now. */
static int parse_index(parser *p, line_reader *lr, const char *token, const char **s,
                       int64_t count, const char *what, int64_t *out) {
    const char *c = *s;
    bool negative = *c == '-';
    if (*c == '-' || *c == '+') c++;
    char q[256];
    if (!is_digit(*c))
        return sc_fail(p->err, SC_EINPUT, "%s:%d: face corner '%s': missing or bad %s index",
                       lr->name, lr->line, snippet(token, q), what);
    int64_t value = 0;
    for (; is_digit(*c); c++) {
        value = value * 10 + (*c - '0');
        if (value > INT32_MAX)
            return sc_fail(p->err, SC_EINPUT, "%s:%d: face corner '%s': %s index is too large",
                           lr->name, lr->line, snippet(token, q), what);
    }
    *s = c;
    if (value == 0)
        return sc_fail(p->err, SC_EINPUT, "%s:%d: face corner '%s': %s index 0 (OBJ indices start at 1)",
                       lr->name, lr->line, snippet(token, q), what);
    if (negative) {
        if (value > count)
            return sc_fail(p->err, SC_EINPUT,
                           "%s:%d: face corner '%s': relative %s index -%lld is out of range "
                           "(%lld defined so far)",
                           lr->name, lr->line, snippet(token, q), what, (long long)value,
                           (long long)count);
        *out = count - value + 1;
    } else {
        *out = value;
    }
    return SC_OK;
}

static int current_material(parser *p, line_reader *lr, int32_t *out) {
    if (p->current < 0) {
        p->current = names_add(&p->used, p->usemtl ? p->usemtl : "default", NULL);
        if (p->current < 0) return out_of_memory(p, lr);
    }
    *out = p->current;
    return SC_OK;
}

static int add_face(parser *p, line_reader *lr, char *rest) {
    int64_t ncorner = 0;
    char q[256];
    bool normals = true;
    int without_uv = -1;   /* unknown until the first corner */
    for (const char *s = skip_space(rest); *s; s = skip_space(s)) {
        const char *token = s;
        int64_t c[3] = {0, 0, 0};
        int rc = parse_index(p, lr, token, &s, p->nv, "vertex", &c[0]);
        if (rc) return rc;
        if (*s == '/') {
            s++;
            if (*s != '/' && *s && !is_space(*s) &&
                (rc = parse_index(p, lr, token, &s, p->nvt, "texture coordinate", &c[1])))
                return rc;
            if (*s == '/') {
                s++;
                if (*s && !is_space(*s) && (rc = parse_index(p, lr, token, &s, p->nvn, "normal", &c[2])))
                    return rc;
            }
        }
        if (*s && !is_space(*s))
            return sc_fail(p->err, SC_EINPUT, "%s:%d: face corner '%s' is malformed", lr->name,
                           lr->line, snippet(token, q));
        if ((c[1] == 0) != (without_uv == 1) && ncorner > 0)
            return sc_fail(p->err, SC_EINPUT,
                           "%s:%d: face has texture coordinates at some corners only (corner '%s')", lr->name,
                           lr->line, snippet(token, q));
        without_uv = c[1] == 0;
        if (c[2] == 0) normals = false;
        if (ncorner >= SC_OBJ_MAX_ELEMENTS) return too_many(p, lr, "face corners");
        if (!grow((void **)&p->corner, &p->capcorner, 3 * (ncorner + 1), sizeof(int64_t)))
            return out_of_memory(p, lr);
        memcpy(p->corner + 3 * ncorner++, c, sizeof c);
    }
    if (ncorner < 3)
        return sc_fail(p->err, SC_EINPUT, "%s:%d: face has %lld corner%s, needs at least 3",
                       lr->name, lr->line, (long long)ncorner, ncorner == 1 ? "" : "s");
    if (!normals) p->all_normals = false;
    if (ncorner > 3) p->polygons++;
    int64_t ntri = ncorner - 2;
    if (without_uv == 1) p->faces_without_uv += ntri;
    if (p->nt + ntri > SC_OBJ_MAX_ELEMENTS) return too_many(p, lr, "triangles");
    int64_t need = p->nt + ntri;
    if (!grow((void **)&p->fv, &p->capfv, 3 * need, sizeof(int32_t)) ||
        !grow((void **)&p->fu, &p->capfu, 3 * need, sizeof(int32_t)) ||
        !grow((void **)&p->fn, &p->capfn, 3 * need, sizeof(int32_t)) ||
        !grow((void **)&p->fm, &p->capfm, need, sizeof(int32_t)) ||
        !grow((void **)&p->fline, &p->capfline, need, sizeof(int32_t)))
        return out_of_memory(p, lr);
    int32_t material = 0;
    int rc = current_material(p, lr, &material);
    if (rc) return rc;
    /* fan from the first corner; indices stay 1-based until the final check */
    for (int64_t k = 1; k + 1 < ncorner; k++) {
        const int64_t *a = p->corner, *b = p->corner + 3 * k, *c = p->corner + 3 * (k + 1);
        int32_t *fv = p->fv + 3 * p->nt, *fu = p->fu + 3 * p->nt, *fn = p->fn + 3 * p->nt;
        fv[0] = (int32_t)a[0], fv[1] = (int32_t)b[0], fv[2] = (int32_t)c[0];
        fu[0] = (int32_t)a[1], fu[1] = (int32_t)b[1], fu[2] = (int32_t)c[1];
        fn[0] = (int32_t)a[2], fn[1] = (int32_t)b[2], fn[2] = (int32_t)c[2];
        p->fm[p->nt] = material;
        p->fline[p->nt] = lr->line;
        p->nt++;
    }
    return SC_OK;
}

/* ---------------------------------------------------------------- MTL */

typedef struct map_option {
    const char *name;
    int max_args;
    bool numeric;   /* numeric args: take up to max_args numbers; else exactly one word */
} map_option;

static const map_option map_options[] = {
    {"-blendu", 1, false}, {"-blendv", 1, false}, {"-cc", 1, false},     {"-clamp", 1, false},
    {"-imfchan", 1, false}, {"-type", 1, false},  {"-bm", 1, true},      {"-boost", 1, true},
    {"-texres", 1, true},   {"-mm", 2, true},     {"-o", 3, true},       {"-s", 3, true},
    {"-t", 3, true},
};

static bool is_number_token(const char *s) {
    char *e = NULL;
    strtod(s, &e);
    return e != s && (*e == 0 || is_space(*e));
}

static const char *skip_token(const char *s) {
    while (*s && !is_space(*s)) s++;
    return skip_space(s);
}

/* The file name of a map statement: options skipped, the rest of the line. */
static const char *map_file_name(const char *s) {
    s = skip_space(s);
    while (*s == '-' && is_alpha(s[1])) {
        const char *opt = s;
        size_t len = 0;
        while (opt[len] && !is_space(opt[len])) len++;
        const map_option *o = NULL;
        for (int i = 0; i < (int)(sizeof map_options / sizeof map_options[0]); i++)
            if (strlen(map_options[i].name) == len && strncasecmp(map_options[i].name, opt, len) == 0)
                o = &map_options[i];
        s = skip_token(s);
        if (o && !o->numeric) {
            if (*s) s = skip_token(s);
        } else {
            /* known numeric option, or an unknown one: its numeric arguments */
            for (int k = 0; (!o || k < o->max_args) && *s && is_number_token(s); k++) s = skip_token(s);
        }
    }
    return s;
}

static int parse_mtl(parser *p, const char *mtl_name, int32_t file, const void *bytes, size_t size) {
    line_reader lr;
    lines_init(&lr, mtl_name, bytes, size);
    char *dir = sc_path_dirname(mtl_name);
    int rc = dir ? SC_OK : sc_fail(p->err, SC_ENOMEM, "out of memory");
    int64_t current = -1;   /* material being defined */
    bool skipping = false;  /* inside a material an earlier MTL already defined */
    while (rc == SC_OK) {
        bool got = false;
        if ((rc = lines_next(&lr, &got, p->err)) != SC_OK || !got) break;
        char *rest;
        char *kw = split_keyword(&lr, &rest, p->err);
        if (!kw) {
            rc = p->err ? p->err->code : SC_EINPUT;
            break;
        }
        trim_end(rest);
        if (strcmp(kw, "newmtl") == 0) {
            if (!*rest) {
                rc = sc_fail(p->err, SC_EINPUT, "%s:%d: newmtl without a name", lr.name, lr.line);
                break;
            }
            bool added = false;
            int32_t k = names_add(&p->mtl_names, rest, &added);
            if (k < 0 || !grow((void **)&p->mtl, &p->capmtl, p->mtl_names.count, sizeof *p->mtl)) {
                rc = out_of_memory(p, &lr);
                break;
            }
            skipping = !added;
            current = skipping ? -1 : k;
            if (added) {
                memset(&p->mtl[k], 0, sizeof p->mtl[k]);
                p->mtl[k].file = file;
            }
            continue;
        }
        int slot = -1, priority = 0;
        if (strcasecmp(kw, "map_Kd") == 0) slot = SLOT_COLOR;
        else if (strcasecmp(kw, "map_Ke") == 0) slot = SLOT_EMISSIVE;
        else if (strcasecmp(kw, "norm") == 0) slot = SLOT_NORMAL;
        else if (strcasecmp(kw, "map_Bump") == 0 || strcasecmp(kw, "bump") == 0)
            slot = SLOT_NORMAL, priority = 1;
        if (slot < 0 || skipping) continue;
        if (current < 0) {
            rc = sc_fail(p->err, SC_EINPUT, "%s:%d: %s before any newmtl", lr.name, lr.line, kw);
            break;
        }
        const char *file_name = map_file_name(rest);
        if (!*file_name) {
            rc = sc_fail(p->err, SC_EINPUT, "%s:%d: %s without a file name", lr.name, lr.line, kw);
            break;
        }
        mtl_material *m = &p->mtl[current];
        if (m->path[slot] && m->priority[slot] <= priority) continue;   /* first one wins */
        char *fixed = sc_strdup(file_name);
        if (fixed)
            for (char *c = fixed; *c; c++)
                if (*c == '\\') *c = '/';
        char *path = fixed ? (strcmp(dir, ".") == 0 ? sc_strdup(fixed) : sc_path_join(dir, fixed)) : NULL;
        free(fixed);
        if (!path) {
            rc = out_of_memory(p, &lr);
            break;
        }
        free(m->path[slot]);
        m->path[slot] = path;
        m->priority[slot] = priority;
        m->line[slot] = lr.line;
    }
    free(dir);
    sc_buf_free(&lr.text);
    return rc;
}

static int read_mtllib(parser *p, line_reader *lr, char *rest) {
    trim_end(rest);
    if (!*rest) return sc_fail(p->err, SC_EINPUT, "%s:%d: mtllib without a file name", lr->name, lr->line);
    if (!p->read_mtl) return SC_OK;
    bool added = false;
    int32_t file = names_add(&p->mtl_files, rest, &added);
    if (file < 0) return out_of_memory(p, lr);
    if (!added) return SC_OK;
    sc_buf bytes;
    sc_buf_init(&bytes);
    int rc = p->read_mtl(p->ud, rest, &bytes, p->err);
    if (rc != SC_OK) {
        if (!p->err || !p->err->message[0]) sc_fail(p->err, rc, "cannot read it");
        sc_error_prefix(p->err, "%s:%d: mtllib %s", lr->name, lr->line, rest);
    } else {
        rc = parse_mtl(p, p->mtl_files.names[file], file, bytes.data ? (const void *)bytes.data : "", bytes.len);
    }
    sc_buf_free(&bytes);
    return rc;
}

/* ---------------------------------------------------------------- mesh */

int sc_mesh_build_compact(const double *V, int64_t nv, const double *U, int64_t nu,
                          const double *N, int64_t nn, const int32_t *FV, const int32_t *FU,
                          const int32_t *FN, const int32_t *FM, int64_t nf,
                          char *const *materials, int32_t nmat, sc_mesh **out,
                          int64_t *degenerate, int64_t *unreferenced, sc_error *err) {
    *out = NULL;
    if (!N || !FN) nn = 0;
    int32_t *vmap = sc_alloc_array((size_t)nv + 1, sizeof(int32_t));
    int32_t *umap = sc_alloc_array((size_t)nu + 1, sizeof(int32_t));
    int32_t *nmap = sc_alloc_array((size_t)nn + 1, sizeof(int32_t));
    if (!vmap || !umap || !nmap) {
        free(vmap), free(umap), free(nmap);
        return sc_fail(err, SC_ENOMEM, "out of memory");
    }
    for (int64_t i = 0; i < nv; i++) vmap[i] = -1;
    for (int64_t i = 0; i < nu; i++) umap[i] = -1;
    for (int64_t i = 0; i < nn; i++) nmap[i] = -1;
    int64_t kept = 0, dropped = 0;
    for (int64_t f = 0; f < nf; f++) {
        const int32_t *fv = FV + 3 * f;
        if (fv[0] == fv[1] || fv[1] == fv[2] || fv[0] == fv[2]) {
            dropped++;
            continue;
        }
        kept++;
        for (int k = 0; k < 3; k++) {
            vmap[fv[k]] = 0;
            umap[FU[3 * f + k]] = 0;
            if (nn) nmap[FN[3 * f + k]] = 0;
        }
    }
    int32_t cv = 0, cu = 0, cn = 0;   /* number what is used, in the original order */
    for (int64_t i = 0; i < nv; i++)
        if (vmap[i] == 0) vmap[i] = cv++;
    for (int64_t i = 0; i < nu; i++)
        if (umap[i] == 0) umap[i] = cu++;
    for (int64_t i = 0; i < nn; i++)
        if (nmap[i] == 0) nmap[i] = cn++;
    if (degenerate) *degenerate = dropped;
    if (unreferenced) *unreferenced += (nv - cv) + (nu - cu) + (nn - cn);
    int rc = SC_OK;
    sc_mesh *m = NULL;
    if (kept == 0) {
        rc = sc_fail(err, SC_EINPUT, "no faces%s", dropped ? " (every face repeats a vertex)" : "");
    } else if (!(m = sc_mesh_alloc(cv, cu, cn, (int32_t)kept, nmat))) {
        rc = sc_fail(err, SC_ENOMEM, "out of memory for a mesh of %lld faces", (long long)kept);
    } else {
        for (int64_t i = 0; i < nv; i++)
            if (vmap[i] >= 0) memcpy(m->V + 3 * (int64_t)vmap[i], V + 3 * i, 3 * sizeof(double));
        for (int64_t i = 0; i < nu; i++)
            if (umap[i] >= 0) memcpy(m->U + 2 * (int64_t)umap[i], U + 2 * i, 2 * sizeof(double));
        for (int64_t i = 0; i < nn; i++)
            if (nmap[i] >= 0) memcpy(m->N + 3 * (int64_t)nmap[i], N + 3 * i, 3 * sizeof(double));
        int64_t t = 0;
        for (int64_t f = 0; f < nf; f++) {
            const int32_t *fv = FV + 3 * f;
            if (fv[0] == fv[1] || fv[1] == fv[2] || fv[0] == fv[2]) continue;
            for (int k = 0; k < 3; k++) {
                m->FV[3 * t + k] = vmap[fv[k]];
                m->FU[3 * t + k] = umap[FU[3 * f + k]];
                if (cn) m->FN[3 * t + k] = nmap[FN[3 * f + k]];
            }
            m->FM[t] = FM ? FM[f] : 0;
            t++;
        }
        for (int32_t i = 0; i < nmat && rc == SC_OK; i++)
            if (!(m->materials[i] = sc_strdup(materials[i])))
                rc = sc_fail(err, SC_ENOMEM, "out of memory");
    }
    free(vmap), free(umap), free(nmap);
    if (rc != SC_OK) {
        sc_mesh_free(m);
        return rc;
    }
    *out = m;
    return SC_OK;
}

/* Check the 1-based indices against the final counts, then make them 0-based.
 * Faces without texture coordinates get one more, (0, 0): uv with no area,
 * which quad_chartify's auto mode replaces with an atlas of its own. */
static int check_indices(parser *p) {
    if (p->faces_without_uv > 0) {
        if (p->nvt >= SC_OBJ_MAX_ELEMENTS)
            return sc_fail(p->err, SC_EINPUT, "%s: too many texture coordinates", p->name);
        if (!grow((void **)&p->vt, &p->capvt, 2 * (p->nvt + 1), sizeof(double)))
            return sc_fail(p->err, SC_ENOMEM, "out of memory");
        p->vt[2 * p->nvt] = p->vt[2 * p->nvt + 1] = 0;
        p->nvt++;
        for (int64_t i = 0; i < 3 * p->nt; i++)
            if (p->fu[i] == 0) p->fu[i] = (int32_t)p->nvt;
    }
    for (int64_t t = 0; t < p->nt; t++) {
        for (int k = 0; k < 3; k++) {
            int32_t *v = &p->fv[3 * t + k], *u = &p->fu[3 * t + k], *n = &p->fn[3 * t + k];
            if (*v > p->nv)
                return sc_fail(p->err, SC_EINPUT,
                               "%s:%d: vertex index %d is out of range (the file has %lld vertices)",
                               p->name, p->fline[t], *v, (long long)p->nv);
            if (*u > p->nvt)
                return sc_fail(p->err, SC_EINPUT,
                               "%s:%d: texture coordinate index %d is out of range (the file has %lld)",
                               p->name, p->fline[t], *u, (long long)p->nvt);
            if (p->all_normals && *n > p->nvn)
                return sc_fail(p->err, SC_EINPUT,
                               "%s:%d: normal index %d is out of range (the file has %lld normals)",
                               p->name, p->fline[t], *n, (long long)p->nvn);
            (*v)--, (*u)--, (*n)--;
        }
    }
    return SC_OK;
}

static int collect_maps(parser *p, sc_obj *out) {
    for (int32_t m = 0; m < (int32_t)p->used.count; m++) {
        int32_t k = names_find(&p->mtl_names, p->used.names[m]);
        if (k < 0) continue;
        for (int s = 0; s < NSLOTS; s++) {
            const mtl_material *mm = &p->mtl[k];
            if (!mm->path[s]) continue;
            sc_obj_map *maps = sc_realloc_array(out->maps, (size_t)out->nmaps + 1, sizeof *maps);
            if (!maps) return sc_fail(p->err, SC_ENOMEM, "out of memory");
            out->maps = maps;
            sc_obj_map *map = &maps[out->nmaps++];
            map->material = m;
            map->slot = sc_strdup(slot_names[s]);
            map->path = sc_strdup(mm->path[s]);
            map->mtl = sc_strdup(p->mtl_files.names[mm->file]);
            map->line = mm->line[s];
            if (!map->slot || !map->path || !map->mtl) return sc_fail(p->err, SC_ENOMEM, "out of memory");
        }
    }
    return SC_OK;
}

static int parse_obj(parser *p, const void *bytes, size_t size) {
    line_reader lr;
    lines_init(&lr, p->name, bytes, size);
    int rc = SC_OK;
    while (rc == SC_OK) {
        bool got = false;
        if ((rc = lines_next(&lr, &got, p->err)) != SC_OK || !got) break;
        char *rest;
        char *kw = split_keyword(&lr, &rest, p->err);
        if (!kw) {
            rc = p->err ? p->err->code : SC_EINPUT;
            break;
        }
        if (!*kw) continue;
        if (strcmp(kw, "v") == 0 || strcmp(kw, "vt") == 0 || strcmp(kw, "vn") == 0) {
            rc = add_element(p, &lr, kw, rest);
        } else if (strcmp(kw, "f") == 0) {
            rc = add_face(p, &lr, rest);
        } else if (strcmp(kw, "usemtl") == 0) {
            trim_end(rest);
            free(p->usemtl);
            p->usemtl = *rest ? sc_strdup(rest) : NULL;
            if (*rest && !p->usemtl) rc = out_of_memory(p, &lr);
            p->current = -1;
        } else if (strcmp(kw, "mtllib") == 0) {
            rc = read_mtllib(p, &lr, rest);
        }
        /* o, g, s, l, p, vp and other statements: ignored */
    }
    sc_buf_free(&lr.text);
    if (rc == SC_OK && p->nt == 0) rc = sc_fail(p->err, SC_EINPUT, "%s: no faces", p->name);
    return rc;
}

int sc_obj_parse(const char *name, const void *bytes, size_t size, sc_obj_read_fn read_mtl,
                 void *ud, sc_obj *out, sc_error *err) {
    memset(out, 0, sizeof *out);
    parser p;
    memset(&p, 0, sizeof p);
    p.name = name;
    p.err = err;
    p.read_mtl = read_mtl;
    p.ud = ud;
    p.all_normals = true;
    p.current = -1;
    int rc = parse_obj(&p, bytes ? bytes : "", bytes ? size : 0);
    if (rc == SC_OK) rc = check_indices(&p);
    if (rc == SC_OK) {
        out->normals_dropped = !p.all_normals && p.nvn > 0;
        rc = sc_mesh_build_compact(p.v, p.nv, p.vt, p.nvt, p.all_normals ? p.vn : NULL, p.nvn,
                                   p.fv, p.fu, p.all_normals ? p.fn : NULL, p.fm, p.nt,
                                   p.used.names, (int32_t)p.used.count, &out->mesh,
                                   &out->degenerate_faces_dropped, &out->unreferenced_dropped, err);
        if (rc != SC_OK) sc_error_prefix(err, "%s", name);
    }
    if (rc == SC_OK) rc = collect_maps(&p, out);
    out->polygons = p.polygons;
    out->faces_without_uv = p.faces_without_uv;
    out->uv_missing = p.nt > 0 && p.faces_without_uv == p.nt;
    parser_free(&p);
    if (rc != SC_OK) sc_obj_free(out);
    return rc;
}

void sc_obj_free(sc_obj *obj) {
    if (!obj) return;
    sc_mesh_free(obj->mesh);
    for (int32_t i = 0; i < obj->nmaps; i++) {
        free(obj->maps[i].slot);
        free(obj->maps[i].path);
        free(obj->maps[i].mtl);
    }
    free(obj->maps);
    memset(obj, 0, sizeof *obj);
}
