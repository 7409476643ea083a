/* sc_lua_bounded.c - Lua's pattern matching, string.rep, table.move and
 * table.sort with their C loops charged to the graph's budget (see
 * sc_lua_bounded.h).
 *
 * Pattern matching is a matcher of its own with Lua 5.4's pattern language
 * and results (classes, sets, the four repetitions, %b, %f, back references,
 * position captures, anchors), because Lua's own gives no way to interrupt a
 * backtracking search: every attempt to match a pattern item is a step, and
 * steps reach the budget in batches of STEP_BATCH. rep, move and sort do the
 * same work as Lua's own, which they call, after charging it up front (a
 * step per element moved, per 64 repetitions and bytes repeated, n log n for
 * sort); rep of an empty string and separator returns "" at once instead of
 * looping (the memory limit bounds every other rep).
 */
#define _GNU_SOURCE   /* memmem */
#include "sc_lua_bounded.h"

#include <lauxlib.h>
#include <lualib.h>

#include <ctype.h>
#include <stdbool.h>
#include <stddef.h>
#include <string.h>

#define MAX_CAPTURES 32     /* LUA_MAXCAPTURES */
#define MAX_DEPTH 200       /* nested items before "pattern too complex", as Lua's MAXCCALLS */
#define CAP_UNFINISHED (-1)
#define CAP_POSITION (-2)
#define STEP_BATCH 4096

typedef struct bounds {
    sc_lua_charge_fn charge;
} bounds;

typedef struct matcher {
    const char *src_init, *src_end;   /* the subject */
    const char *p_end;                /* the pattern's end */
    lua_State *L;
    sc_lua_charge_fn charge;
    int64_t pending;                  /* steps not charged yet */
    int depth, level;                 /* nesting; captures open or closed */
    struct {
        const char *init;
        ptrdiff_t len;                /* or CAP_UNFINISHED, CAP_POSITION */
    } capture[MAX_CAPTURES];
} matcher;

static int uchar(char c) { return (unsigned char)c; }

static void step(matcher *ms) {
    if (++ms->pending >= STEP_BATCH) {
        int64_t n = ms->pending;
        ms->pending = 0;
        ms->charge(ms->L, n);
    }
}

static void flush(matcher *ms) {
    int64_t n = ms->pending;
    ms->pending = 0;
    if (n) ms->charge(ms->L, n);
}

static void prepare(matcher *ms, lua_State *L, sc_lua_charge_fn charge, const char *s, size_t ls, const char *p,
                    size_t lp) {
    ms->src_init = s, ms->src_end = s + ls, ms->p_end = p + lp;
    ms->L = L, ms->charge = charge, ms->pending = 0;
    ms->depth = 0, ms->level = 0;
}

/* ---------------------------------------------------------------- single characters */

/* The end of the class that starts at p: a character, %x or [set]. */
static const char *class_end(matcher *ms, const char *p) {
    char c = *p++;
    if (c == '%') {
        if (p == ms->p_end) luaL_error(ms->L, "malformed pattern (ends with '%%')");
        return p + 1;
    }
    if (c == '[') {
        if (*p == '^') p++;
        do {   /* the first character may be ']' itself */
            if (p == ms->p_end) luaL_error(ms->L, "malformed pattern (missing ']')");
            if (*(p++) == '%' && p < ms->p_end) p++;
        } while (*p != ']');
        return p + 1;
    }
    return p;
}

/* c in the class %cl (a letter class, its complement in upper case, or cl itself). */
static bool in_class(int c, int cl) {
    bool res;
    switch (tolower(cl)) {
    case 'a': res = isalpha(c); break;
    case 'c': res = iscntrl(c); break;
    case 'd': res = isdigit(c); break;
    case 'g': res = isgraph(c); break;
    case 'l': res = islower(c); break;
    case 'p': res = ispunct(c); break;
    case 's': res = isspace(c); break;
    case 'u': res = isupper(c); break;
    case 'w': res = isalnum(c); break;
    case 'x': res = isxdigit(c); break;
    default: return cl == c;
    }
    return isupper(cl) ? !res : res;
}

/* c in the set [p .. ec], p at '[' and ec at its ']'. */
static bool in_set(int c, const char *p, const char *ec) {
    bool yes = true;
    if (*(p + 1) == '^') {
        yes = false;
        p++;
    }
    while (++p < ec) {
        if (*p == '%') {
            p++;
            if (in_class(c, uchar(*p))) return yes;
        } else if (*(p + 1) == '-' && p + 2 < ec) {
            p += 2;
            if (uchar(*(p - 2)) <= c && c <= uchar(*p)) return yes;
        } else if (uchar(*p) == c) {
            return yes;
        }
    }
    return !yes;
}

static bool single_match(matcher *ms, const char *s, const char *p, const char *ep) {
    if (s >= ms->src_end) return false;
    int c = uchar(*s);
    switch (*p) {
    case '.': return true;
    case '%': return in_class(c, uchar(*(p + 1)));
    case '[': return in_set(c, p, ep - 1);
    default: return uchar(*p) == c;
    }
}

/* ---------------------------------------------------------------- items */

static const char *match(matcher *ms, const char *s, const char *p);

static const char *match_balance(matcher *ms, const char *s, const char *p) {
    if (p >= ms->p_end - 1) luaL_error(ms->L, "malformed pattern (missing arguments to '%%b')");
    if (s >= ms->src_end || *s != *p) return NULL;
    int open = *p, close = *(p + 1), depth = 1;
    while (++s < ms->src_end) {
        step(ms);
        if (*s == close) {
            if (--depth == 0) return s + 1;
        } else if (*s == open) {
            depth++;
        }
    }
    return NULL;
}

static const char *max_expand(matcher *ms, const char *s, const char *p, const char *ep) {
    ptrdiff_t i = 0;
    while (single_match(ms, s + i, p, ep)) i++, step(ms);
    for (; i >= 0; i--) {   /* try the rest with the longest run first */
        const char *res = match(ms, s + i, ep + 1);
        if (res) return res;
    }
    return NULL;
}

static const char *min_expand(matcher *ms, const char *s, const char *p, const char *ep) {
    for (;;) {
        const char *res = match(ms, s, ep + 1);
        if (res) return res;
        if (!single_match(ms, s, p, ep)) return NULL;
        s++;
    }
}

static const char *start_capture(matcher *ms, const char *s, const char *p, ptrdiff_t what) {
    if (ms->level >= MAX_CAPTURES) luaL_error(ms->L, "too many captures");
    ms->capture[ms->level].init = s;
    ms->capture[ms->level].len = what;
    ms->level++;
    const char *res = match(ms, s, p);
    if (!res) ms->level--;
    return res;
}

static const char *end_capture(matcher *ms, const char *s, const char *p) {
    int l = ms->level - 1;
    while (l >= 0 && ms->capture[l].len != CAP_UNFINISHED) l--;
    if (l < 0) luaL_error(ms->L, "invalid pattern capture");
    ms->capture[l].len = s - ms->capture[l].init;
    const char *res = match(ms, s, p);
    if (!res) ms->capture[l].len = CAP_UNFINISHED;
    return res;
}

static int capture_index(matcher *ms, int digit) {
    int l = digit - '1';
    if (l < 0 || l >= ms->level || ms->capture[l].len == CAP_UNFINISHED)
        luaL_error(ms->L, "invalid capture index %%%d", l + 1);
    return l;
}

static const char *match_capture(matcher *ms, const char *s, int digit) {
    int l = capture_index(ms, digit);
    size_t len = (size_t)ms->capture[l].len;   /* a position capture matches nothing */
    if ((size_t)(ms->src_end - s) >= len && memcmp(ms->capture[l].init, s, len) == 0) {
        ms->pending += (int64_t)(len / 64);
        return s + len;
    }
    return NULL;
}

/* The end of the match of pattern p at s, or NULL. */
static const char *match(matcher *ms, const char *s, const char *p) {
    if (ms->depth++ >= MAX_DEPTH) luaL_error(ms->L, "pattern too complex");
    for (;;) {
        step(ms);
        if (p == ms->p_end) break;
        if (*p == '(') {
            s = *(p + 1) == ')' ? start_capture(ms, s, p + 2, CAP_POSITION)
                                : start_capture(ms, s, p + 1, CAP_UNFINISHED);
            break;
        }
        if (*p == ')') {
            s = end_capture(ms, s, p + 1);
            break;
        }
        if (*p == '$' && p + 1 == ms->p_end) {
            s = s == ms->src_end ? s : NULL;
            break;
        }
        if (*p == '%' && *(p + 1) == 'b') {
            if ((s = match_balance(ms, s, p + 2)) == NULL) break;
            p += 4;
            continue;
        }
        if (*p == '%' && *(p + 1) == 'f') {
            p += 2;
            if (*p != '[') luaL_error(ms->L, "missing '[' after '%%f' in pattern");
            const char *ep = class_end(ms, p);
            int previous = s == ms->src_init ? '\0' : uchar(*(s - 1));
            int current = s < ms->src_end ? uchar(*s) : '\0';
            if (in_set(previous, p, ep - 1) || !in_set(current, p, ep - 1)) {
                s = NULL;
                break;
            }
            p = ep;
            continue;
        }
        if (*p == '%' && isdigit(uchar(*(p + 1)))) {
            if ((s = match_capture(ms, s, uchar(*(p + 1)))) == NULL) break;
            p += 2;
            continue;
        }
        /* a single-character class, perhaps repeated */
        const char *ep = class_end(ms, p);
        if (!single_match(ms, s, p, ep)) {
            if (*ep == '*' || *ep == '?' || *ep == '-') {   /* may match nothing */
                p = ep + 1;
                continue;
            }
            s = NULL;
            break;
        }
        if (*ep == '?') {
            const char *res = match(ms, s + 1, ep + 1);
            if (res) {
                s = res;
                break;
            }
            p = ep + 1;
            continue;
        }
        if (*ep == '+') s = max_expand(ms, s + 1, p, ep);
        else if (*ep == '*') s = max_expand(ms, s, p, ep);
        else if (*ep == '-') s = min_expand(ms, s, p, ep);
        else {
            s++;
            p = ep;
            continue;
        }
        break;
    }
    ms->depth--;
    return s;
}

/* ---------------------------------------------------------------- captures */

static void push_capture(matcher *ms, int i, const char *s, const char *e) {
    if (i >= ms->level) {
        if (i != 0) luaL_error(ms->L, "invalid capture index %%%d", i + 1);
        lua_pushlstring(ms->L, s, (size_t)(e - s));   /* the whole match */
        return;
    }
    ptrdiff_t len = ms->capture[i].len;
    if (len == CAP_UNFINISHED) luaL_error(ms->L, "unfinished capture");
    if (len == CAP_POSITION) lua_pushinteger(ms->L, (ms->capture[i].init - ms->src_init) + 1);
    else lua_pushlstring(ms->L, ms->capture[i].init, (size_t)len);
}

/* Every capture, or the whole match when there are none and s is given. */
static int push_captures(matcher *ms, const char *s, const char *e) {
    int n = (ms->level == 0 && s) ? 1 : ms->level;
    luaL_checkstack(ms->L, n, "too many captures");
    for (int i = 0; i < n; i++) push_capture(ms, i, s, e);
    return n;
}

/* ---------------------------------------------------------------- library functions */

static sc_lua_charge_fn charge_of(lua_State *L) {
    return ((const bounds *)lua_touserdata(L, lua_upvalueindex(1)))->charge;
}

static size_t start_index(lua_Integer pos, size_t len) {
    if (pos > 0) return (size_t)pos;
    if (pos == 0 || pos < -(lua_Integer)len) return 1;
    return len + (size_t)pos + 1;
}

static bool has_specials(const char *p, size_t lp) {
    for (size_t i = 0; i < lp; i++)
        if (strchr("^$*+?.([%-", p[i]) && p[i] != '\0') return true;
    return false;
}

static int find_or_match(lua_State *L, bool find) {
    sc_lua_charge_fn charge = charge_of(L);
    size_t ls, lp;
    const char *s = luaL_checklstring(L, 1, &ls);
    const char *p = luaL_checklstring(L, 2, &lp);
    size_t init = start_index(luaL_optinteger(L, 3, 1), ls) - 1;
    if (init > ls) {
        luaL_pushfail(L);
        return 1;
    }
    if (find && (lua_toboolean(L, 4) || !has_specials(p, lp))) {
        charge(L, (int64_t)((ls - init) / 64 + 1));
        const char *hit = memmem(s + init, ls - init, p, lp);
        if (hit) {
            lua_pushinteger(L, (hit - s) + 1);
            lua_pushinteger(L, (lua_Integer)((size_t)(hit - s) + lp));
            return 2;
        }
        luaL_pushfail(L);
        return 1;
    }
    bool anchor = *p == '^';
    if (anchor) p++, lp--;
    matcher ms;
    prepare(&ms, L, charge, s, ls, p, lp);
    const char *at = s + init;
    do {
        ms.level = 0, ms.depth = 0;
        const char *e = match(&ms, at, p);
        if (e) {
            flush(&ms);
            if (!find) return push_captures(&ms, at, e);
            lua_pushinteger(L, (at - s) + 1);
            lua_pushinteger(L, e - s);
            return push_captures(&ms, NULL, NULL) + 2;
        }
    } while (at++ < ms.src_end && !anchor);
    flush(&ms);
    luaL_pushfail(L);
    return 1;
}

static int bounded_find(lua_State *L) { return find_or_match(L, true); }
static int bounded_match(lua_State *L) { return find_or_match(L, false); }

typedef struct gmatch_state {
    const char *src, *p, *last;
    matcher ms;
} gmatch_state;

static int gmatch_next(lua_State *L) {
    gmatch_state *gm = lua_touserdata(L, lua_upvalueindex(4));
    gm->ms.L = L;
    for (const char *at = gm->src; at <= gm->ms.src_end; at++) {
        gm->ms.level = 0, gm->ms.depth = 0;
        const char *e = match(&gm->ms, at, gm->p);
        if (e && e != gm->last) {
            gm->src = gm->last = e;
            flush(&gm->ms);
            return push_captures(&gm->ms, at, e);
        }
    }
    gm->src = gm->ms.src_end + 1;
    flush(&gm->ms);
    return 0;
}

static int bounded_gmatch(lua_State *L) {
    size_t ls, lp;
    const char *s = luaL_checklstring(L, 1, &ls);
    const char *p = luaL_checklstring(L, 2, &lp);
    size_t init = start_index(luaL_optinteger(L, 3, 1), ls) - 1;
    lua_settop(L, 2);
    gmatch_state *gm = lua_newuserdatauv(L, sizeof *gm, 0);
    if (init > ls) init = ls + 1;
    prepare(&gm->ms, L, charge_of(L), s, ls, p, lp);
    gm->src = s + init, gm->p = p, gm->last = NULL;
    lua_pushvalue(L, lua_upvalueindex(1));   /* upvalues: bounds, subject, pattern, state */
    lua_insert(L, 1);
    lua_pushcclosure(L, gmatch_next, 4);
    return 1;
}

/* The replacement string (argument 3) with %0-%9 and %% expanded. */
static void add_replacement(matcher *ms, luaL_Buffer *b, const char *s, const char *e) {
    lua_State *L = ms->L;
    size_t l;
    const char *text = lua_tolstring(L, 3, &l);
    const char *p;
    while ((p = memchr(text, '%', l)) != NULL) {
        luaL_addlstring(b, text, (size_t)(p - text));
        p++;
        if (*p == '%') luaL_addchar(b, '%');
        else if (*p == '0') luaL_addlstring(b, s, (size_t)(e - s));
        else if (isdigit(uchar(*p))) {
            push_capture(ms, *p - '1', s, e);
            luaL_tolstring(L, -1, NULL);   /* a position capture is a number */
            lua_remove(L, -2);
            luaL_addvalue(b);
        } else {
            luaL_error(L, "invalid use of '%c' in replacement string", '%');
        }
        l -= (size_t)(p + 1 - text);
        text = p + 1;
    }
    luaL_addlstring(b, text, l);
}

/* Add the replacement of the match s..e; false when it keeps the match. */
static bool add_value(matcher *ms, luaL_Buffer *b, const char *s, const char *e, int type) {
    lua_State *L = ms->L;
    if (type == LUA_TFUNCTION) {
        lua_pushvalue(L, 3);
        int n = push_captures(ms, s, e);
        lua_call(L, n, 1);
    } else if (type == LUA_TTABLE) {
        push_capture(ms, 0, s, e);
        lua_gettable(L, 3);
    } else {
        add_replacement(ms, b, s, e);
        return true;
    }
    if (!lua_toboolean(L, -1)) {   /* nil or false: keep the match */
        lua_pop(L, 1);
        luaL_addlstring(b, s, (size_t)(e - s));
        return false;
    }
    if (!lua_isstring(L, -1)) luaL_error(L, "invalid replacement value (a %s)", luaL_typename(L, -1));
    luaL_addvalue(b);
    return true;
}

static int bounded_gsub(lua_State *L) {
    size_t ls, lp;
    const char *src = luaL_checklstring(L, 1, &ls);
    const char *p = luaL_checklstring(L, 2, &lp);
    int type = lua_type(L, 3);
    lua_Integer max = luaL_optinteger(L, 4, (lua_Integer)ls + 1);
    luaL_argexpected(L, type == LUA_TNUMBER || type == LUA_TSTRING || type == LUA_TFUNCTION || type == LUA_TTABLE,
                     3, "string/function/table");
    bool anchor = *p == '^', changed = false;
    if (anchor) p++, lp--;
    luaL_Buffer b;
    luaL_buffinit(L, &b);
    matcher ms;
    prepare(&ms, L, charge_of(L), src, ls, p, lp);
    const char *last = NULL;
    lua_Integer n = 0;
    while (n < max) {
        ms.level = 0, ms.depth = 0;
        const char *e = match(&ms, src, p);
        if (e && e != last) {
            n++;
            changed = add_value(&ms, &b, src, e, type) || changed;
            src = last = e;
        } else if (src < ms.src_end) {
            luaL_addchar(&b, *src++);
        } else {
            break;
        }
        if (anchor) break;
    }
    flush(&ms);
    if (!changed) {
        lua_pushvalue(L, 1);
    } else {
        luaL_addlstring(&b, src, (size_t)(ms.src_end - src));
        luaL_pushresult(&b);
    }
    lua_pushinteger(L, n);
    return 2;
}

/* Call the original function (upvalue 2) with this call's arguments. */
static int call_original(lua_State *L) {
    int n = lua_gettop(L);
    lua_pushvalue(L, lua_upvalueindex(2));
    lua_insert(L, 1);
    lua_call(L, n, LUA_MULTRET);
    return lua_gettop(L);
}

static int64_t saturating(lua_Unsigned n) { return n > (lua_Unsigned)INT64_MAX ? INT64_MAX : (int64_t)n; }

static int bounded_rep(lua_State *L) {
    size_t l, lsep;
    luaL_checklstring(L, 1, &l);
    lua_Integer n = luaL_checkinteger(L, 2);
    luaL_optlstring(L, 3, "", &lsep);
    if (n <= 0 || l + lsep == 0) {   /* "" however many times */
        lua_pushliteral(L, "");
        return 1;
    }
    lua_Unsigned bytes = (lua_Unsigned)n * (lua_Unsigned)(l + lsep);
    if (bytes / (lua_Unsigned)n != (lua_Unsigned)(l + lsep)) bytes = (lua_Unsigned)-1;
    charge_of(L)(L, saturating(((lua_Unsigned)n + bytes) / 64 + 1));
    return call_original(L);
}

static int bounded_move(lua_State *L) {
    lua_Integer f = luaL_checkinteger(L, 2), e = luaL_checkinteger(L, 3);
    if (e >= f) charge_of(L)(L, saturating((lua_Unsigned)e - (lua_Unsigned)f + 1));
    return call_original(L);
}

static int bounded_sort(lua_State *L) {
    lua_Unsigned n = lua_type(L, 1) == LUA_TTABLE ? lua_rawlen(L, 1) : 0, log = 1;
    while (((lua_Unsigned)1 << log) < n && log < 63) log++;
    charge_of(L)(L, saturating(n * log));
    return call_original(L);
}

/* Replace lib[name] (lib at index `lib`) by f with upvalues (bounds, original). */
static void replace(lua_State *L, int lib, const char *name, lua_CFunction f, const bounds *b) {
    lua_pushlightuserdata(L, (void *)b);
    lua_getfield(L, lib, name);
    lua_pushcclosure(L, f, 2);
    lua_setfield(L, lib, name);
}

void sc_lua_open_bounded(lua_State *L, sc_lua_charge_fn charge) {
    bounds *b = lua_newuserdatauv(L, sizeof *b, 0);   /* kept alive in the registry */
    b->charge = charge;
    lua_rawsetp(L, LUA_REGISTRYINDEX, (void *)b);
    lua_getglobal(L, LUA_STRLIBNAME);
    int lib = lua_gettop(L);
    replace(L, lib, "find", bounded_find, b);
    replace(L, lib, "match", bounded_match, b);
    replace(L, lib, "gmatch", bounded_gmatch, b);
    replace(L, lib, "gsub", bounded_gsub, b);
    replace(L, lib, "rep", bounded_rep, b);
    lua_pop(L, 1);
    lua_getglobal(L, LUA_TABLIBNAME);
    lib = lua_gettop(L);
    replace(L, lib, "move", bounded_move, b);
    replace(L, lib, "sort", bounded_sort, b);
    lua_pop(L, 1);
}
