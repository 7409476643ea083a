/* sc_lua.c - the graph language: a sandboxed Lua 5.4 state that builds a graph.
 *
 * Design note. One build = one lua_State, closed before sc_lua_build returns;
 * the graph it leaves behind is plain C data (sc_graph.h).
 *
 * The sandbox opens base, table, string, math and utf8 only, then removes
 * dofile, loadfile, collectgarbage and string.dump (the string metatable's
 * __index is that same table, so it is covered), makes `load` text-only,
 * refuses __gc finalizers (Lua runs them with hooks off, out of reach of the
 * instruction limit), sends print to stderr (stdout belongs to the command
 * line, e.g. `graph --dot`) and seeds math.random with a constant so a graph
 * file builds the same graph on every run. Everything the engine needs later (constructors, the handle
 * metatable, the original load) lives in upvalues or the registry, never in
 * _G, so a graph that rewrites its globals hurts only itself.
 *
 * Two departures from stock Lua, both for farms: reading an undefined global
 * is an error with a "did you mean" (Starlark does the same; a misspelt handle
 * would otherwise arrive as nil, i.e. an unconnected input), and pairs visits
 * keys in a fixed order, since Lua seeds its string hash per process and a
 * loop over a table would otherwise make nodes in a different order on each
 * run. rawget and next stay raw.
 *
 * Limits. A count hook runs every HOOK_STEP instructions: it adds to the
 * instruction count and samples where the graph is running, because a memory
 * error carries no position of its own and calling lua_getinfo from inside the
 * allocator is not safe. Once the instruction limit trips, the hook fires on
 * every instruction, so a pcall in the graph cannot swallow the error and run
 * on. The library functions that loop in C (pattern matching, string.rep,
 * table.move, table.sort) are replaced by versions that charge their loops
 * to the same count (sc_lua_bounded.h), and both the hook and those charges
 * check the wall clock, so no graph file runs past --lua-timeout. The
 * allocator refuses any growth beyond the memory limit; Lua then collects
 * garbage, retries, and raises a memory error we rename.
 *
 * Constructors. A node is staged in a userdata with a __gc (so a Lua error
 * thrown halfway, even out of memory, leaks nothing) and reaches the graph
 * only once every input and parameter is checked; after sc_graph_add nothing
 * can raise. So a failed constructor never leaves half a node behind, even
 * when the graph catches the error with pcall. Table keys are checked in a
 * fixed order (descriptor order, unknown keys by name) so the same mistake
 * always gives the same message, whatever Lua's hash order.
 *
 * Settings. param() converts a --set's text to its default's type (a table
 * default reads a list of numbers) and records, in a registry table keyed by
 * the value it returns, which --set it came from. A constructor whose check
 * refuses a value found there blames that --set: the build fails with
 * SC_EUSAGE, "--set name=value: node:param: why", because the command line,
 * not the graph, is at fault. The same goes for param()'s own errors, unless
 * the graph caught one and failed later for a reason of its own. Once the
 * file has run, every --set that no param() read and whose name has a dot,
 * NODE.PARAM, sets that parameter of the node so named, parsed as the
 * parameter's type and checked like any value.
 *
 * Positions. Messages say "file:line:" with the file as the graph named it
 * (the chunk is "@path"); Lua's own messages use short_src, which truncates
 * long paths, so the final message maps the main chunk's short_src back.
 */
#include "sc_lua.h"
#include "sc_lua_bounded.h"

#include <lauxlib.h>
#include <lua.h>
#include <lualib.h>

#include <ctype.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <unistd.h>

#define DEFAULT_MAX_INSTRUCTIONS 100000000
#define DEFAULT_MAX_MEMORY ((size_t)256 << 20)
#define DEFAULT_MAX_SECONDS 5.0
#define HOOK_STEP 100
#define MAX_GRAPH_FILE ((size_t)16 << 20)

typedef struct builder {
    sc_graph *graph;
    const char *path;
    const sc_node_desc *const *types;
    int ntypes;
    const sc_setting *settings;
    int nsettings;
    bool *setting_used;
    char *cwd;                        /* for PATH parameters, read once */
    const char *code;
    size_t code_len;
    int status;                       /* the chunk's own status (LUA_ERRMEM...) */
    char main_short_src[LUA_IDSIZE];

    int64_t max_instructions, instructions;
    int hook_step;
    double max_seconds, deadline;     /* wall clock, sc_now() */
    bool limit_exceeded;              /* instructions or time: limit_message says which */
    size_t max_memory, memory_used;
    bool memory_refused;

    char where_file[512];             /* where the graph last ran (sampled) */
    int where_line;
    char limit_message[640];
    char usage_message[1024];         /* the last error raised about the command line */
} builder;

/* Registry keys: their addresses are unique. origins maps each value param()
 * returned for a --set to that setting's index. */
static const char handle_meta_key = 'h';
static const char staging_meta_key = 's';
static const char origins_key = 'o';

static builder *builder_of(lua_State *L) {
    void *ud;
    lua_getallocf(L, &ud);
    return ud;
}

/* ---------------------------------------------------------------- limits */

static void count_hook(lua_State *L, lua_Debug *ar);

static void *limited_alloc(void *ud, void *ptr, size_t osize, size_t nsize) {
    builder *B = ud;
    size_t old = ptr ? osize : 0;   /* with ptr NULL, osize is a type tag */
    if (nsize == 0) {
        free(ptr);
        B->memory_used -= old;
        return NULL;
    }
    if (nsize > old && nsize - old > B->max_memory - B->memory_used) {
        B->memory_refused = true;
        return NULL;
    }
    void *p = realloc(ptr, nsize);
    if (!p) return NULL;
    B->memory_used = B->memory_used - old + nsize;
    return p;
}

/* The file name to show for a function: the chunk name without its '@' or
 * '=' mark (full, never truncated), else Lua's short form ([string "..."]). */
static const char *frame_file(const lua_Debug *ar) {
    if (ar->source && (ar->source[0] == '@' || ar->source[0] == '='))
        return ar->source + 1;
    return ar->short_src;
}

/* "256 MiB", or bytes when the limit is not whole mebibytes. */
static void limit_text(const builder *B, char *out, size_t n) {
    size_t mib = (size_t)1 << 20;
    if (B->max_memory % mib == 0) snprintf(out, n, "%zu MiB", B->max_memory / mib);
    else snprintf(out, n, "%zu bytes", B->max_memory);
}

static void where_text(const builder *B, char *out, size_t n) {
    if (B->where_line > 0) snprintf(out, n, "%s:%d", B->where_file, B->where_line);
    else snprintf(out, n, "%s", B->path);
}

/* Past a limit (instructions, or the wall clock), raise the limit's error,
 * and from then on on every instruction, so that a pcall in the graph cannot
 * swallow it and run on. */
static void check_limits(lua_State *L, builder *B) {
    if (B->instructions <= B->max_instructions && sc_now() <= B->deadline && !B->limit_exceeded) return;
    if (!B->limit_exceeded) {
        char where[560];
        where_text(B, where, sizeof where);
        if (B->instructions > B->max_instructions)
            snprintf(B->limit_message, sizeof B->limit_message, "%s: instruction limit exceeded (%lld instructions)",
                     where, (long long)B->max_instructions);
        else
            snprintf(B->limit_message, sizeof B->limit_message, "%s: graph evaluation exceeded %g s", where,
                     B->max_seconds);
        B->limit_exceeded = true;
        B->hook_step = 1;
        lua_sethook(L, count_hook, LUA_MASKCOUNT, 1);
    }
    lua_pushstring(L, B->limit_message);
    lua_error(L);
}

static void count_hook(lua_State *L, lua_Debug *ar) {
    builder *B = builder_of(L);
    if (lua_getinfo(L, "Sl", ar) && ar->currentline > 0) {
        snprintf(B->where_file, sizeof B->where_file, "%s", frame_file(ar));
        B->where_line = ar->currentline;
    }
    B->instructions += B->hook_step;
    check_limits(L, B);
}

/* The work of a library function's C loop (sc_lua_bounded.h), counted as
 * instructions. */
static void charge_steps(lua_State *L, int64_t steps) {
    builder *B = builder_of(L);
    lua_Debug ar;   /* where: the innermost Lua function calling the library */
    for (int level = 0; lua_getstack(L, level, &ar); level++)
        if (lua_getinfo(L, "Sl", &ar) && ar.currentline > 0) {
            snprintf(B->where_file, sizeof B->where_file, "%s", frame_file(&ar));
            B->where_line = ar.currentline;
            break;
        }
    B->instructions = steps > INT64_MAX - B->instructions ? INT64_MAX : B->instructions + steps;
    check_limits(L, B);
}

/* ---------------------------------------------------------------- positions */

typedef struct position {
    char file[512];
    int line;
} position;

/* The innermost Lua function at or above `level`: C functions such as pcall
 * have no line of their own. */
static void caller_position(lua_State *L, int level, position *pos) {
    lua_Debug ar;
    while (lua_getstack(L, level++, &ar)) {
        if (lua_getinfo(L, "Sl", &ar) && ar.currentline > 0) {
            snprintf(pos->file, sizeof pos->file, "%s", frame_file(&ar));
            pos->line = ar.currentline;
            return;
        }
    }
    snprintf(pos->file, sizeof pos->file, "%s", builder_of(L)->path);
    pos->line = 0;
}

/* Raise "file:line: message" at the Lua code that called the running C
 * function (or the metamethod). A usage error is one the command line made
 * (a --set): the build then fails with SC_EUSAGE, unless the graph caught it
 * and failed later for a reason of its own. */
static int raise_text(lua_State *L, bool usage, const char *msg) {
    if (usage) snprintf(builder_of(L)->usage_message, sizeof builder_of(L)->usage_message, "%s", msg);
    position pos;
    caller_position(L, 1, &pos);
    if (pos.line > 0) lua_pushfstring(L, "%s:%d: %s", pos.file, pos.line, msg);
    else lua_pushfstring(L, "%s: %s", pos.file, msg);
    return lua_error(L);
}

static int raise_error(lua_State *L, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static int raise_error(lua_State *L, const char *fmt, ...) {
    char msg[1024];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    return raise_text(L, false, msg);
}

/* An error the command line made: "--set name=value: why", or `why` alone
 * without a setting. */
static int raise_usage(lua_State *L, const char *setting, const char *value, const char *why) {
    char msg[1024];
    if (setting) snprintf(msg, sizeof msg, "--set %s=%s: %s", setting, value, why);
    else snprintf(msg, sizeof msg, "%s", why);
    return raise_text(L, true, msg);
}

/* Whether a message already starts with a "something:123:" position. */
static bool has_position(const char *msg) {
    for (const char *p = msg; *p && *p != '\n'; p++) {
        if (*p != ':' || !isdigit((unsigned char)p[1])) continue;
        const char *q = p + 1;
        while (isdigit((unsigned char)*q)) q++;
        if (*q == ':') return true;
    }
    return false;
}

/* Runs where the error happened: turn any error object into a message that
 * says where (error("x", 0) and error({}) carry no position). */
static int message_handler(lua_State *L) {
    const char *msg = lua_tostring(L, 1);
    if (!msg) msg = lua_pushfstring(L, "(error object is a %s value)", luaL_typename(L, 1));
    if (has_position(msg)) {
        lua_pushstring(L, msg);
        return 1;
    }
    position pos;
    caller_position(L, 1, &pos);
    if (pos.line > 0) lua_pushfstring(L, "%s:%d: %s", pos.file, pos.line, msg);
    else lua_pushfstring(L, "%s: %s", pos.file, msg);
    return 1;
}

/* ---------------------------------------------------------------- handles */

/* A node handle; port -1 is the node itself, else a selected output. */
typedef struct handle {
    const builder *owner;
    int node;
    int port;
} handle;

static handle *to_handle(lua_State *L, int idx) {
    if (lua_type(L, idx) != LUA_TUSERDATA || !lua_getmetatable(L, idx)) return NULL;
    lua_rawgetp(L, LUA_REGISTRYINDEX, &handle_meta_key);
    bool ours = lua_rawequal(L, -1, -2);
    lua_pop(L, 2);
    return ours ? lua_touserdata(L, idx) : NULL;
}

static bool handle_valid(const builder *B, const handle *h) {
    return h->owner == B && h->node >= 0 && h->node < B->graph->count;
}

static handle *push_handle(lua_State *L, const builder *B, int node, int port) {
    handle *h = lua_newuserdatauv(L, sizeof *h, 0);
    h->owner = B;
    h->node = node;
    h->port = port;
    lua_rawgetp(L, LUA_REGISTRYINDEX, &handle_meta_key);
    lua_setmetatable(L, -2);
    return h;
}

/* Append ", name" to a list held in out[n]; a full list stays truncated. */
static void list_append(char *out, size_t n, size_t *len, const char *name) {
    if (*len >= n) return;
    int k = snprintf(out + *len, n - *len, "%s%s", *len ? ", " : "", name);
    if (k > 0) *len += (size_t)k;
}

/* A value's type for messages; handles are "node". */
static const char *value_type(lua_State *L, int idx) {
    return to_handle(L, idx) ? "node" : luaL_typename(L, idx);
}

/* "a (atlas), b (image)" */
static void list_outputs(const sc_node_desc *d, char *out, size_t n) {
    size_t len = 0;
    out[0] = 0;
    for (int i = 0; i < d->noutputs; i++) {
        char item[256];
        snprintf(item, sizeof item, "%s (%s)", d->outputs[i].name,
                 sc_kind_name(d->outputs[i].kind));
        list_append(out, n, &len, item);
    }
}

static int handle_index(lua_State *L) {
    builder *B = builder_of(L);
    handle *h = to_handle(L, 1);
    if (!h || !handle_valid(B, h)) return raise_error(L, "stale node handle");
    const sc_graph_node *n = &B->graph->nodes[h->node];
    if (lua_type(L, 2) != LUA_TSTRING)
        return raise_error(L, "node '%s': index it with an output name, not a %s", n->name,
                           luaL_typename(L, 2));
    const char *port = lua_tostring(L, 2);
    if (h->port >= 0)
        return raise_error(L, "'%s.%s' already selects an output; '.%s' selects nothing",
                           n->name, n->desc->outputs[h->port].name, port);
    int p = sc_desc_output(n->desc, port);
    if (p < 0) {
        char outputs[512];
        list_outputs(n->desc, outputs, sizeof outputs);
        return raise_error(L, "node '%s' (%s) has no output '%s' (outputs: %s)", n->name,
                           n->desc->type, port, n->desc->noutputs ? outputs : "none");
    }
    push_handle(L, B, h->node, p);
    return 1;
}

static int handle_newindex(lua_State *L) {
    return raise_error(L, "node handles are read-only");
}

static int handle_tostring(lua_State *L) {
    builder *B = builder_of(L);
    handle *h = to_handle(L, 1);
    if (!h || !handle_valid(B, h)) {
        lua_pushliteral(L, "node (stale)");
    } else {
        const sc_graph_node *n = &B->graph->nodes[h->node];
        if (h->port >= 0) lua_pushfstring(L, "%s.%s", n->name, n->desc->outputs[h->port].name);
        else lua_pushstring(L, n->name);
    }
    return 1;
}

/* ---------------------------------------------------------------- staging */

/* A node under construction, owned by a userdata so an error frees it. A
 * parameter with type 0 was not given and keeps its default. */
typedef struct staging {
    int nparams, ninputs;
    sc_param_value *params;
    int *input_node, *input_port;
    char *name;
} staging;

static void staging_clear(staging *st) {
    for (int i = 0; st->params && i < st->nparams; i++) sc_param_value_clear(&st->params[i]);
    free(st->params);
    free(st->input_node);
    free(st->input_port);
    free(st->name);
    memset(st, 0, sizeof *st);
}

static int staging_gc(lua_State *L) {
    staging_clear(lua_touserdata(L, 1));
    return 0;
}

static staging *push_staging(lua_State *L, const sc_node_desc *d) {
    staging *st = lua_newuserdatauv(L, sizeof *st, 0);
    memset(st, 0, sizeof *st);
    lua_rawgetp(L, LUA_REGISTRYINDEX, &staging_meta_key);
    lua_setmetatable(L, -2);
    st->nparams = d->nparams;
    st->ninputs = d->ninputs;
    if (d->nparams > 0) st->params = sc_calloc_array((size_t)d->nparams, sizeof *st->params);
    if (d->ninputs > 0) {
        st->input_node = sc_alloc_array((size_t)d->ninputs, sizeof *st->input_node);
        st->input_port = sc_calloc_array((size_t)d->ninputs, sizeof *st->input_port);
    }
    if ((d->nparams > 0 && !st->params) ||
        (d->ninputs > 0 && (!st->input_node || !st->input_port)))
        raise_error(L, "%s: out of memory", d->type);
    for (int i = 0; i < d->ninputs; i++) st->input_node[i] = -1;
    return st;
}

/* ---------------------------------------------------------------- suggestions */

/* Edit distance between two short names (longer names are never close). */
static int edit_distance(const char *a, const char *b) {
    size_t la = strlen(a), lb = strlen(b);
    if (la > 63 || lb > 63) return 99;
    int row[64];
    for (size_t j = 0; j <= lb; j++) row[j] = (int)j;
    for (size_t i = 1; i <= la; i++) {
        int diagonal = row[0];
        row[0] = (int)i;
        for (size_t j = 1; j <= lb; j++) {
            int above = row[j];
            int best = diagonal + (a[i - 1] != b[j - 1]);
            if (above + 1 < best) best = above + 1;
            if (row[j - 1] + 1 < best) best = row[j - 1] + 1;
            row[j] = best;
            diagonal = above;
        }
    }
    return row[lb];
}

/* Keep `candidate` in *best when it is the closest plausible spelling so far. */
static void consider(const char *wrong, const char *candidate, const char **best, int *dist) {
    int d = edit_distance(wrong, candidate);
    size_t shorter = strlen(wrong) < strlen(candidate) ? strlen(wrong) : strlen(candidate);
    if (d > 2 || (size_t)d >= shorter) return;
    if (!*best || d < *dist || (d == *dist && strcmp(candidate, *best) < 0)) {
        *best = candidate;
        *dist = d;
    }
}

/* "; did you mean 'size'?" or "" */
static void did_you_mean(const char *best, char *out, size_t n) {
    if (best) snprintf(out, n, "; did you mean '%s'?", best);
    else if (n) out[0] = 0;
}

/* ---------------------------------------------------------------- constructors */

static bool key_known(const sc_node_desc *d, const char *key) {
    return sc_desc_input(d, key) >= 0 || sc_desc_param(d, key) >= 0 || strcmp(key, "name") == 0;
}

/* "atlas, mode, size, name": inputs, parameters, then name. */
static void list_known_keys(const sc_node_desc *d, char *out, size_t n) {
    size_t len = 0;
    out[0] = 0;
    for (int i = 0; i < d->ninputs; i++) list_append(out, n, &len, d->inputs[i].name);
    for (int i = 0; i < d->nparams; i++) list_append(out, n, &len, d->params[i].name);
    if (sc_desc_input(d, "name") < 0 && sc_desc_param(d, "name") < 0)
        list_append(out, n, &len, "name");
}

/* Reject positional values and unknown keys; of several unknown keys, name
 * the smallest, so the message does not depend on hash order. */
static void check_keys(lua_State *L, int table, const sc_node_desc *d) {
    const char *unknown = NULL;
    bool positional = false;
    lua_pushnil(L);
    while (lua_next(L, table)) {
        if (lua_type(L, -2) != LUA_TSTRING) {
            positional = true;
        } else {
            const char *key = lua_tostring(L, -2);
            if (!key_known(d, key) && (!unknown || strcmp(key, unknown) < 0)) unknown = key;
        }
        lua_pop(L, 1);
    }
    if (unknown) {
        char known[768], hint[128];
        const char *best = NULL;
        int dist = 0;
        for (int i = 0; i < d->ninputs; i++) consider(unknown, d->inputs[i].name, &best, &dist);
        for (int i = 0; i < d->nparams; i++) consider(unknown, d->params[i].name, &best, &dist);
        list_known_keys(d, known, sizeof known);
        did_you_mean(best, hint, sizeof hint);
        raise_error(L, "%s: unknown parameter '%s' (known: %s)%s", d->type, unknown, known, hint);
    }
    if (positional)
        raise_error(L, "%s: every field needs a name: %s{input = node, parameter = value}",
                    d->type, d->type);
}

/* The output of `from` to connect to an input of kind `want` when the graph
 * passed the node itself: its only output, or the only one that fits. */
static int pick_output(const sc_node_desc *from, sc_kind want, int *fitting) {
    if (from->noutputs == 1) {
        *fitting = sc_kind_feeds(from->outputs[0].kind, want);
        return 0;
    }
    int found = -1;
    *fitting = 0;
    for (int i = 0; i < from->noutputs; i++) {
        if (sc_kind_feeds(from->outputs[i].kind, want)) {
            found = i;
            (*fitting)++;
        }
    }
    return *fitting == 1 ? found : -1;
}

/* The value on top of the stack goes to input port p. */
static void connect_input(lua_State *L, builder *B, const sc_node_desc *d, int p, staging *st) {
    const sc_port_desc *in = &d->inputs[p];
    handle *h = to_handle(L, -1);
    if (!h)
        raise_error(L, "%s: input '%s' takes a node (%s), got %s", d->type, in->name,
                    sc_kind_name(in->kind), value_type(L, -1));
    if (!handle_valid(B, h))
        raise_error(L, "%s: input '%s': the node handle is not from this graph", d->type,
                    in->name);
    const sc_graph_node *from = &B->graph->nodes[h->node];
    int port = h->port;
    if (port < 0) {
        int fitting;
        port = pick_output(from->desc, in->kind, &fitting);
        if (port < 0) {
            char outputs[512];
            list_outputs(from->desc, outputs, sizeof outputs);
            if (from->desc->noutputs == 0)
                raise_error(L, "%s: input '%s': node '%s' has no outputs", d->type, in->name,
                            from->name);
            if (fitting == 0)
                raise_error(L, "%s: input '%s' takes %s, but no output of node '%s' gives it "
                            "(outputs: %s)", d->type, in->name, sc_kind_name(in->kind),
                            from->name, outputs);
            char choices[512];
            size_t len = 0;
            choices[0] = 0;
            for (int i = 0; i < from->desc->noutputs; i++) {
                if (!sc_kind_feeds(from->desc->outputs[i].kind, in->kind)) continue;
                char item[128];
                snprintf(item, sizeof item, ".%s", from->desc->outputs[i].name);
                list_append(choices, sizeof choices, &len, item);
            }
            raise_error(L, "%s: input '%s': node '%s' has several outputs that fit (%s); "
                        "select one with %s", d->type, in->name, from->name, outputs, choices);
        }
    }
    const sc_port_desc *out = &from->desc->outputs[port];
    if (!sc_kind_feeds(out->kind, in->kind))
        raise_error(L, "%s: input '%s' takes %s, but %s.%s gives %s", d->type, in->name,
                    sc_kind_name(in->kind), from->name, out->name, sc_kind_name(out->kind));
    st->input_node[p] = h->node;
    st->input_port[p] = port;
}

/* Remove "." and ".." segments and repeated slashes from an absolute path, in
 * place (the result is never longer). */
static void normalise_path(char *p) {
    size_t w = 0, r = 0;
    while (p[r]) {
        while (p[r] == '/') r++;
        if (!p[r]) break;
        size_t s = r;
        while (p[r] && p[r] != '/') r++;
        size_t n = r - s;
        if (n == 1 && p[s] == '.') continue;
        if (n == 2 && p[s] == '.' && p[s + 1] == '.') {
            while (w > 0 && p[w - 1] != '/') w--;
            if (w > 0) w--;
            continue;
        }
        p[w++] = '/';
        memmove(p + w, p + s, n);
        w += n;
    }
    if (w == 0) p[w++] = '/';
    p[w] = 0;
}

/* An absolute path for a PATH parameter: realpath when the file exists, else
 * the working directory joined and normalised. Existence is the node's call. */
static char *resolve_path(builder *B, const char *path) {
    char *joined;
    if (path[0] == '/') {
        joined = sc_strdup(path);
    } else {
        if (!B->cwd) B->cwd = getcwd(NULL, 0);
        if (!B->cwd) return NULL;
        joined = sc_path_join(B->cwd, path);
    }
    if (!joined) return NULL;
    char *real = realpath(joined, NULL);
    if (real) {
        free(joined);
        return real;
    }
    normalise_path(joined);
    return joined;
}

static const char *param_expects(const sc_param_desc *pd) {
    switch (pd->type) {
    case SC_PARAM_NUMBER: return "a number";
    case SC_PARAM_INTEGER: return "an integer";
    case SC_PARAM_BOOL: return "a boolean";
    case SC_PARAM_STRING: return "a string";
    case SC_PARAM_ENUM: return "a string (a choice)";
    case SC_PARAM_PATH: return "a path (a string)";
    case SC_PARAM_NUMBERS: return "a number or a list of numbers";
    }
    return "?";
}

/* The --set (its index) that param() returned the value at idx for, or -1. */
static int origin_of(lua_State *L, int idx) {
    idx = lua_absindex(L, idx);
    lua_rawgetp(L, LUA_REGISTRYINDEX, &origins_key);
    lua_pushvalue(L, idx);
    int from = lua_rawget(L, -2) == LUA_TNUMBER ? (int)lua_tointeger(L, -1) : -1;
    lua_pop(L, 2);
    return from;
}

/* Read a list of numbers (or one number) into v, which the staging owns;
 * `who` is "node:param". */
static void convert_numbers(lua_State *L, const char *who, sc_param_value *v) {
    if (lua_type(L, -1) == LUA_TNUMBER) {
        v->numbers = malloc(sizeof *v->numbers);
        if (!v->numbers) raise_error(L, "%s: out of memory", who);
        v->numbers[0] = lua_tonumber(L, -1);
        v->count = 1;
        return;
    }
    lua_Unsigned n = lua_rawlen(L, -1);
    lua_Unsigned keys = 0;
    lua_pushnil(L);
    while (lua_next(L, -2)) {
        keys++;
        lua_pop(L, 1);
    }
    if (keys != n || n > (lua_Unsigned)(INT32_MAX / 8))
        raise_error(L, "%s: expected a list of numbers {a, b, ...} without holes or named fields", who);
    if (n == 0) return;
    v->numbers = sc_alloc_array((size_t)n, sizeof *v->numbers);
    if (!v->numbers) raise_error(L, "%s: out of memory", who);
    for (lua_Unsigned i = 1; i <= n; i++) {
        int t = lua_rawgeti(L, -1, (lua_Integer)i);
        if (t != LUA_TNUMBER)
            raise_error(L, "%s: element %llu is %s, expected a number", who, (unsigned long long)i,
                        value_type(L, -1));
        v->numbers[v->count++] = lua_tonumber(L, -1);
        lua_pop(L, 1);
    }
}

/* The value on top of the stack becomes parameter p of the node `node`
 * (its name, or its type when it has none). A value that fails the check
 * because of a --set is the command line's error. */
static void convert_param(lua_State *L, builder *B, const sc_node_desc *d, const char *node, int p,
                          sc_param_value *v) {
    const sc_param_desc *pd = &d->params[p];
    char who[320];
    snprintf(who, sizeof who, "%s:%s", node, pd->name);
    int t = lua_type(L, -1);
    bool fits;
    switch (pd->type) {
    case SC_PARAM_NUMBER:
    case SC_PARAM_INTEGER: fits = t == LUA_TNUMBER; break;
    case SC_PARAM_BOOL: fits = t == LUA_TBOOLEAN; break;
    case SC_PARAM_STRING:
    case SC_PARAM_ENUM:
    case SC_PARAM_PATH: fits = t == LUA_TSTRING; break;
    case SC_PARAM_NUMBERS: fits = t == LUA_TNUMBER || t == LUA_TTABLE; break;
    default: fits = false;
    }
    if (!fits) raise_error(L, "%s: expected %s, got %s", who, param_expects(pd), value_type(L, -1));
    v->type = pd->type;
    switch (pd->type) {
    case SC_PARAM_NUMBER:
    case SC_PARAM_INTEGER: v->number = lua_tonumber(L, -1); break;
    case SC_PARAM_BOOL: v->number = lua_toboolean(L, -1) ? 1 : 0; break;
    case SC_PARAM_STRING:
    case SC_PARAM_ENUM:
    case SC_PARAM_PATH: {
        size_t len;
        const char *s = lua_tolstring(L, -1, &len);
        if (strlen(s) != len) raise_error(L, "%s: the string holds a zero byte", who);
        if (pd->type == SC_PARAM_PATH && len == 0 && pd->required) raise_error(L, "%s: the path is empty", who);
        /* an empty optional path means "none" and stays empty */
        v->string = (pd->type == SC_PARAM_PATH && len > 0) ? resolve_path(B, s) : sc_strdup(s);
        if (!v->string)
            raise_error(L, "%s: cannot resolve '%s' (out of memory or no working directory)", who, s);
        break;
    }
    case SC_PARAM_NUMBERS: convert_numbers(L, who, v); break;
    }
    sc_error err;
    if (sc_param_check(pd, v, node, &err) == SC_OK) return;
    int from = origin_of(L, -1);
    if (from >= 0) raise_usage(L, B->settings[from].name, B->settings[from].value, err.message);
    raise_error(L, "%s", err.message);
}

static bool name_char(char c) {
    return isalnum((unsigned char)c) || c == '_' || c == '-' || c == '.';
}

static void convert_name(lua_State *L, const sc_node_desc *d, staging *st) {
    if (lua_type(L, -1) != LUA_TSTRING)
        raise_error(L, "%s: name must be a string, got %s", d->type, value_type(L, -1));
    size_t len;
    const char *s = lua_tolstring(L, -1, &len);
    bool ok = len > 0 && len <= 200 && s[0] != '.';
    for (size_t i = 0; ok && i < len; i++) ok = name_char(s[i]);
    if (!ok)
        raise_error(L, "%s: name '%s' must be 1 to 200 letters, digits, '_', '-' or '.' "
                    "(not starting with '.')", d->type, s);
    st->name = sc_strdup(s);
    if (!st->name) raise_error(L, "%s: out of memory", d->type);
}

/* The C memory a node will hold, roughly (each allocation counted with some
 * overhead): it counts against the same budget as Lua's own memory, or a loop
 * making nodes could use gigabytes within the instruction limit. */
static size_t node_cost(const sc_node_desc *d, const staging *st, size_t file_len) {
    const size_t overhead = 32;
    size_t cost = 2 * sizeof(sc_graph_node) + file_len + 24 + 3 * overhead;
    cost += (size_t)d->nparams * sizeof(sc_param_value) + (size_t)d->ninputs * 2 * sizeof(int);
    if (st->name) cost += strlen(st->name);
    for (int p = 0; p < d->nparams; p++) {
        const sc_param_value *v = st->params[p].type ? &st->params[p] : NULL;
        const char *text = v ? v->string : d->params[p].def_string;
        if (text) cost += strlen(text) + 1 + overhead;
        if (v) cost += (size_t)v->count * sizeof(double) + overhead;
        else if (d->params[p].type == SC_PARAM_NUMBERS && text) cost += strlen(text) * sizeof(double);
    }
    return cost;
}

static void charge_memory(lua_State *L, builder *B, size_t bytes, const char *what) {
    if (bytes <= B->max_memory - B->memory_used) {
        B->memory_used += bytes;
        return;
    }
    B->memory_refused = true;
    char limit[48];
    limit_text(B, limit, sizeof limit);
    raise_error(L, "memory limit exceeded (%s) by %s", limit, what);
}

/* Push t[key] without metamethods. */
static int raw_field(lua_State *L, int table, const char *key) {
    lua_pushstring(L, key);
    return lua_rawget(L, table);
}

/* type{...}: the constructor of every node type; upvalue 1 is its descriptor. */
static int construct_node(lua_State *L) {
    builder *B = builder_of(L);
    const sc_node_desc *d = lua_touserdata(L, lua_upvalueindex(1));
    int nargs = lua_gettop(L);
    if (nargs == 0) lua_newtable(L);
    else if (nargs > 1 || lua_type(L, 1) != LUA_TTABLE)
        return raise_error(L, "%s: takes one table of inputs and parameters, e.g. %s{...}",
                           d->type, d->type);
    staging *st = push_staging(L, d);   /* index 2 */
    check_keys(L, 1, d);

    for (int p = 0; p < d->ninputs; p++) {
        if (raw_field(L, 1, d->inputs[p].name) != LUA_TNIL) connect_input(L, B, d, p, st);
        lua_pop(L, 1);
    }
    if (sc_desc_input(d, "name") < 0 && sc_desc_param(d, "name") < 0) {
        if (raw_field(L, 1, "name") != LUA_TNIL) convert_name(L, d, st);
        lua_pop(L, 1);
    }
    for (int p = 0; p < d->nparams; p++) {
        if (raw_field(L, 1, d->params[p].name) != LUA_TNIL)
            convert_param(L, B, d, st->name ? st->name : d->type, p, &st->params[p]);
        lua_pop(L, 1);
    }

    /* Everything that can raise happens before the node joins the graph. */
    position pos;
    caller_position(L, 1, &pos);
    charge_memory(L, B, node_cost(d, st, strlen(pos.file)), "the graph's nodes");
    handle *h = push_handle(L, B, -1, -1);
    int idx = sc_graph_add(B->graph, d, pos.file, pos.line);
    if (idx < 0) return raise_error(L, "%s: out of memory", d->type);
    sc_graph_node *n = &B->graph->nodes[idx];
    for (int p = 0; p < d->nparams; p++) {
        if (st->params[p].type == 0) continue;
        sc_param_value_clear(&n->params[p]);
        n->params[p] = st->params[p];
        memset(&st->params[p], 0, sizeof st->params[p]);
    }
    for (int p = 0; p < d->ninputs; p++) {
        n->input_node[p] = st->input_node[p];
        n->input_port[p] = st->input_port[p];
    }
    if (st->name) {
        free(n->name);
        n->name = st->name;
        st->name = NULL;
    }
    h->node = idx;
    return 1;
}

/* ---------------------------------------------------------------- param, expect */

/* Push the --set text converted to the type of the default at index 2. */
static void push_setting(lua_State *L, int def, const char *name, const char *text) {
    if (def == LUA_TNUMBER) {
        if (!lua_stringtonumber(L, text)) raise_usage(L, name, text, "not a number");
        if (!isfinite(lua_tonumber(L, -1))) raise_usage(L, name, text, "not a finite number");
    } else if (def == LUA_TBOOLEAN) {
        bool b;
        if (!sc_parse_bool(text, &b)) raise_usage(L, name, text, "not a boolean (true/false, yes/no, 1/0)");
        lua_pushboolean(L, b);
    } else if (def == LUA_TTABLE) {
        int cap = 1;
        for (const char *c = text; *c; c++) cap += *c == ',';
        lua_createtable(L, cap, 0);   /* sized before the parse: filling it cannot raise and leak x */
        double *x;
        int n;
        sc_error err;
        if (sc_parse_numbers(text, &x, &n, &err) != SC_OK) raise_usage(L, name, text, err.message);
        for (int i = 0; i < n; i++) {
            lua_pushnumber(L, x[i]);
            lua_rawseti(L, -2, i + 1);
        }
        free(x);
    } else {
        lua_pushstring(L, text);
    }
}

/* param(name [, default]): the --set value, converted to default's type (a
 * list of numbers, "0.5,0.1", when the default is a table). */
static int graph_param(lua_State *L) {
    builder *B = builder_of(L);
    if (lua_type(L, 1) != LUA_TSTRING)
        return raise_error(L, "param: the first argument must be the parameter's name, got %s",
                           value_type(L, 1));
    const char *name = lua_tostring(L, 1);
    int def = lua_type(L, 2);
    if (def != LUA_TNONE && def != LUA_TNIL && def != LUA_TNUMBER && def != LUA_TBOOLEAN &&
        def != LUA_TSTRING && def != LUA_TTABLE)
        return raise_error(L, "param('%s', ...): the default must be a number, a boolean, "
                           "a string, a list of numbers or nil, got %s", name, value_type(L, 2));
    int from = -1;
    for (int i = 0; i < B->nsettings; i++) {
        if (strcmp(B->settings[i].name, name) != 0) continue;
        from = i;
        B->setting_used[i] = true;   /* the last one wins; all count as read */
    }
    if (from < 0) {
        if (def == LUA_TNONE || def == LUA_TNIL) {
            char why[512];
            snprintf(why, sizeof why, "parameter '%s' is required: pass --set %s=...", name, name);
            return raise_usage(L, NULL, NULL, why);
        }
        lua_settop(L, 2);
        return 1;
    }
    const char *text = B->settings[from].value ? B->settings[from].value : "";
    lua_settop(L, 2);
    push_setting(L, def, name, text);
    lua_rawgetp(L, LUA_REGISTRYINDEX, &origins_key);   /* remember where the value came from */
    lua_pushvalue(L, 3);
    lua_pushinteger(L, from);
    lua_rawset(L, -3);
    lua_pop(L, 1);
    return 1;
}

static bool number_arg(lua_State *L, int idx, double *out) {
    if (lua_type(L, idx) != LUA_TNUMBER) return false;
    *out = lua_tonumber(L, idx);
    return isfinite(*out);
}

/* The node handle a graph function takes first; raises an error otherwise. */
static handle *node_argument(lua_State *L, builder *B, const char *fn) {
    handle *h = to_handle(L, 1);
    if (!h || !handle_valid(B, h))
        raise_error(L, "%s: the first argument must be a node of this graph, got %s", fn, value_type(L, 1));
    return h;
}

/* Append one expectation on node h (all strings copied). */
static void add_expect(lua_State *L, builder *B, handle *h, const char *metric, const char *op,
                       double value, double tolerance) {
    position pos;
    caller_position(L, 1, &pos);
    charge_memory(L, B, sizeof(sc_expect) + strlen(metric) + strlen(pos.file) + 160,
                  "the graph's expectations");
    sc_graph *g = B->graph;
    sc_expect e = {
        .node = sc_strdup(g->nodes[h->node].name),
        .metric = sc_strdup(metric),
        .op = sc_strdup(op),
        .value = value,
        .tolerance = tolerance,
        .file = sc_strdup(pos.file),
        .line = pos.line,
    };
    sc_expect *grown = sc_realloc_array(g->expects, (size_t)g->nexpect + 1, sizeof *grown);
    if (grown) g->expects = grown;
    if (!grown || !e.node || !e.metric || !e.op || !e.file) {
        free(e.node);
        free(e.metric);
        free(e.op);
        free(e.file);
        raise_error(L, "expect: out of memory");
        return;
    }
    g->expects[g->nexpect++] = e;
}

/* expect(node, metric, op, value [, tolerance]) */
static int graph_expect(lua_State *L) {
    static const char *const ops[] = {"<", "<=", "==", ">=", ">", "~"};
    builder *B = builder_of(L);
    handle *h = node_argument(L, B, "expect");
    if (lua_type(L, 2) != LUA_TSTRING || lua_rawlen(L, 2) == 0)
        return raise_error(L, "expect: the second argument must be a metric name");
    const char *metric = lua_tostring(L, 2);
    const char *op = lua_type(L, 3) == LUA_TSTRING ? lua_tostring(L, 3) : "";
    bool op_ok = false;
    for (size_t i = 0; i < sizeof ops / sizeof ops[0]; i++) op_ok |= strcmp(op, ops[i]) == 0;
    if (!op_ok)
        return raise_error(L, "expect: unknown comparison '%s' (use <, <=, ==, >=, > or ~)", op);
    double value, tolerance = 0;
    if (!number_arg(L, 4, &value))
        return raise_error(L, "expect: the value must be a finite number, got %s",
                           lua_type(L, 4) == LUA_TNUMBER ? "nan or inf" : value_type(L, 4));
    bool approx = strcmp(op, "~") == 0;
    if (approx && (!number_arg(L, 5, &tolerance) || tolerance < 0))
        return raise_error(L, "expect: '~' needs a tolerance >= 0: expect(node, '%s', '~', "
                           "value, tolerance)", metric);
    if (!approx && !lua_isnoneornil(L, 5))
        return raise_error(L, "expect: a tolerance goes only with '~'");

    add_expect(L, B, h, metric, op, value, tolerance);
    return 0;
}

/* A number field of an options table, or def. */
static double option_number(lua_State *L, int table, const char *field, double def, const char *fn) {
    if (lua_isnoneornil(L, table)) return def;
    if (!lua_istable(L, table)) {
        raise_error(L, "%s: options must be a table", fn);
        return def;
    }
    lua_getfield(L, table, field);
    double v = def;
    if (!lua_isnil(L, -1) && !number_arg(L, -1, &v))
        raise_error(L, "%s: option '%s' must be a finite number", fn, field);
    lua_pop(L, 1);
    return v;
}

/* expect_image(node, "render/lod0_textured_posx.png" [, {threshold = 2, max_share = 0.001}]) */
static int graph_expect_image(lua_State *L) {
    builder *B = builder_of(L);
    handle *h = node_argument(L, B, "expect_image");
    if (lua_type(L, 2) != LUA_TSTRING || lua_rawlen(L, 2) == 0)
        return raise_error(L, "expect_image: the second argument must be the path of a PNG the node writes");
    double threshold = option_number(L, 3, "threshold", 2, "expect_image");
    double share = option_number(L, 3, "max_share", 0.001, "expect_image");
    if (threshold < 0 || threshold > 255 || share < 0 || share > 1)
        return raise_error(L, "expect_image: threshold must be in [0, 255] and max_share in [0, 1]");
    add_expect(L, B, h, lua_tostring(L, 2), "image", threshold, share);
    return 0;
}

/* expect_metrics(node [, {tolerance = 1e-9}]) */
static int graph_expect_metrics(lua_State *L) {
    builder *B = builder_of(L);
    handle *h = node_argument(L, B, "expect_metrics");
    double tolerance = option_number(L, 2, "tolerance", 1e-9, "expect_metrics");
    if (tolerance < 0) return raise_error(L, "expect_metrics: tolerance must be >= 0");
    add_expect(L, B, h, "*", "metrics", 0, tolerance);
    return 0;
}

/* ---------------------------------------------------------------- sandbox */

/* print, to stderr: stdout carries the command line's own output. */
static int sandbox_print(lua_State *L) {
    int n = lua_gettop(L);
    for (int i = 1; i <= n; i++) {
        size_t len;
        const char *s = luaL_tolstring(L, i, &len);
        if (i > 1) fputc('\t', stderr);
        fwrite(s, 1, len, stderr);
        lua_pop(L, 1);
    }
    fputc('\n', stderr);
    return 0;
}

/* pairs visits keys in a fixed order: numbers ascending, strings bytewise,
 * false before true, node handles by creation, then anything else. Lua seeds
 * its string hash per process, so raw hash order would change from run to run
 * and with it the order (and default names) of nodes a loop makes. */
static int key_rank(lua_State *L, int idx) {
    switch (lua_type(L, idx)) {
    case LUA_TNUMBER: return 0;
    case LUA_TSTRING: return 1;
    case LUA_TBOOLEAN: return 2;
    default: return to_handle(L, idx) ? 3 : 4;
    }
}

static int key_less(lua_State *L) {
    int ra = key_rank(L, 1), rb = key_rank(L, 2);
    bool less = ra < rb;
    if (ra == rb) {
        switch (ra) {
        case 0: less = lua_compare(L, 1, 2, LUA_OPLT); break;
        case 1: {
            size_t la, lb;
            const char *a = lua_tolstring(L, 1, &la), *b = lua_tolstring(L, 2, &lb);
            int c = memcmp(a, b, la < lb ? la : lb);
            less = c < 0 || (c == 0 && la < lb);
            break;
        }
        case 2: less = !lua_toboolean(L, 1) && lua_toboolean(L, 2); break;
        case 3: {
            const handle *a = to_handle(L, 1), *b = to_handle(L, 2);
            less = a->node < b->node || (a->node == b->node && a->port < b->port);
            break;
        }
        default: less = false;
        }
    }
    lua_pushboolean(L, less);
    return 1;
}

/* The iterator: upvalues are the sorted keys, the table and the position.
 * Keys whose value became nil during the loop are skipped. */
static int sorted_next(lua_State *L) {
    lua_Integer i = lua_tointeger(L, lua_upvalueindex(3));
    for (;;) {
        if (lua_rawgeti(L, lua_upvalueindex(1), ++i) == LUA_TNIL) return 0;
        lua_pushvalue(L, -1);
        if (lua_rawget(L, lua_upvalueindex(2)) != LUA_TNIL) {
            lua_pushinteger(L, i);
            lua_replace(L, lua_upvalueindex(3));
            return 2;
        }
        lua_pop(L, 2);
    }
}

/* pairs(t); upvalue 1 is the original table.sort. A __pairs metamethod is
 * honoured as in stock Lua. */
static int sandbox_pairs(lua_State *L) {
    luaL_checkany(L, 1);
    if (luaL_getmetafield(L, 1, "__pairs") != LUA_TNIL) {
        lua_pushvalue(L, 1);
        lua_call(L, 1, 3);
        return 3;
    }
    luaL_checktype(L, 1, LUA_TTABLE);
    lua_settop(L, 1);
    lua_newtable(L);   /* 2: the keys */
    lua_Integer n = 0;
    lua_pushnil(L);
    while (lua_next(L, 1)) {
        lua_pop(L, 1);
        lua_pushvalue(L, -1);
        lua_rawseti(L, 2, ++n);
    }
    lua_pushvalue(L, lua_upvalueindex(1));
    lua_pushvalue(L, 2);
    lua_pushcfunction(L, key_less);
    lua_call(L, 2, 0);
    lua_pushvalue(L, 1);
    lua_pushinteger(L, 0);
    lua_pushcclosure(L, sorted_next, 3);
    return 1;
}

/* __index of _G: reading a global nobody defined is a mistake (a typo in a
 * node handle's name would otherwise arrive as an unconnected input). */
static int undefined_global(lua_State *L) {
    if (lua_type(L, 2) != LUA_TSTRING) return 0;
    const char *name = lua_tostring(L, 2);
    const char *best = NULL;
    int dist = 0;
    lua_pushnil(L);
    while (lua_next(L, 1)) {
        lua_pop(L, 1);
        if (lua_type(L, -1) == LUA_TSTRING) consider(name, lua_tostring(L, -1), &best, &dist);
    }
    /* Locals and upvalues of the function that read the name; their names
     * live in its prototype, which is alive while it runs. */
    lua_Debug ar;
    if (lua_getstack(L, 1, &ar)) {
        const char *local;
        for (int i = 1; (local = lua_getlocal(L, &ar, i)) != NULL; i++) {
            lua_pop(L, 1);
            if (local[0] != '(') consider(name, local, &best, &dist);
        }
        lua_getinfo(L, "f", &ar);
        const char *up;
        for (int i = 1; (up = lua_getupvalue(L, -1, i)) != NULL; i++) {
            lua_pop(L, 1);
            if (*up && strcmp(up, "_ENV") != 0) consider(name, up, &best, &dist);
        }
        lua_pop(L, 1);
    }
    char hint[128];
    did_you_mean(best, hint, sizeof hint);
    return raise_error(L, "'%s' is not defined (no such variable or node type)%s", name, hint);
}

/* load(chunk [, chunkname [, mode [, env]]]) with mode forced to text. */
static int sandbox_load(lua_State *L) {
    int n = lua_gettop(L);
    lua_settop(L, 4);
    lua_pushvalue(L, lua_upvalueindex(1));
    lua_pushvalue(L, 1);
    lua_pushvalue(L, 2);
    lua_pushliteral(L, "t");
    if (n >= 4) lua_pushvalue(L, 4);
    lua_call(L, n >= 4 ? 4 : 3, LUA_MULTRET);
    return lua_gettop(L) - 4;
}

/* setmetatable without finalizers: Lua runs __gc with hooks off, so a
 * finalizer would escape the instruction limit (and could run while the
 * state closes). An object is marked for finalization only when it gets a
 * metatable that already has __gc, so checking here is enough. */
static int sandbox_setmetatable(lua_State *L) {
    if (lua_type(L, 2) == LUA_TTABLE) {
        lua_pushliteral(L, "__gc");
        if (lua_rawget(L, 2) != LUA_TNIL)
            return raise_error(L, "setmetatable: __gc finalizers are not available in graph "
                               "files");
        lua_pop(L, 1);
    }
    lua_pushvalue(L, lua_upvalueindex(1));
    lua_insert(L, 1);
    lua_call(L, lua_gettop(L) - 1, 1);
    return 1;
}

/* math.randomseed(x) with a seed only: an unseeded call would pick a random
 * seed, and the graph would differ from run to run. */
static int sandbox_randomseed(lua_State *L) {
    if (lua_type(L, 1) != LUA_TNUMBER)
        return raise_error(L, "math.randomseed needs a seed: graphs must build the same way "
                           "every time");
    lua_pushvalue(L, lua_upvalueindex(1));
    lua_insert(L, 1);
    lua_call(L, lua_gettop(L) - 1, 0);
    return 0;
}

static void open_sandbox(lua_State *L, builder *B) {
    static const luaL_Reg libs[] = {
        {LUA_GNAME, luaopen_base},         {LUA_TABLIBNAME, luaopen_table},
        {LUA_STRLIBNAME, luaopen_string},  {LUA_MATHLIBNAME, luaopen_math},
        {LUA_UTF8LIBNAME, luaopen_utf8},
    };
    for (size_t i = 0; i < sizeof libs / sizeof libs[0]; i++) {
        luaL_requiref(L, libs[i].name, libs[i].func, 1);
        lua_pop(L, 1);
    }
    lua_pushglobaltable(L);
    int G = lua_gettop(L);
    static const char *const removed[] = {"dofile", "loadfile", "collectgarbage", "require"};
    for (size_t i = 0; i < sizeof removed / sizeof removed[0]; i++) {
        lua_pushnil(L);
        lua_setfield(L, G, removed[i]);
    }
    lua_getfield(L, G, "load");
    lua_pushcclosure(L, sandbox_load, 1);
    lua_setfield(L, G, "load");
    lua_pushcfunction(L, sandbox_print);
    lua_setfield(L, G, "print");
    lua_getfield(L, G, "setmetatable");
    lua_pushcclosure(L, sandbox_setmetatable, 1);
    lua_setfield(L, G, "setmetatable");

    lua_getfield(L, G, LUA_STRLIBNAME);   /* also getmetatable("").__index */
    lua_pushnil(L);
    lua_setfield(L, -2, "dump");
    lua_pop(L, 1);

    lua_getfield(L, G, LUA_MATHLIBNAME);
    lua_getfield(L, -1, "randomseed");
    lua_pushvalue(L, -1);
    lua_pushinteger(L, 0);
    lua_call(L, 1, 0);
    lua_pushcclosure(L, sandbox_randomseed, 1);
    lua_setfield(L, -2, "randomseed");
    lua_pop(L, 1);

    lua_newtable(L);   /* the handle metatable */
    lua_pushcfunction(L, handle_index);
    lua_setfield(L, -2, "__index");
    lua_pushcfunction(L, handle_newindex);
    lua_setfield(L, -2, "__newindex");
    lua_pushcfunction(L, handle_tostring);
    lua_setfield(L, -2, "__tostring");
    lua_pushliteral(L, "node");
    lua_setfield(L, -2, "__name");
    lua_pushboolean(L, 0);
    lua_setfield(L, -2, "__metatable");
    lua_rawsetp(L, LUA_REGISTRYINDEX, &handle_meta_key);

    lua_newtable(L);   /* the staging metatable */
    lua_pushcfunction(L, staging_gc);
    lua_setfield(L, -2, "__gc");
    lua_pushboolean(L, 0);
    lua_setfield(L, -2, "__metatable");
    lua_rawsetp(L, LUA_REGISTRYINDEX, &staging_meta_key);

    lua_newtable(L);
    lua_rawsetp(L, LUA_REGISTRYINDEX, &origins_key);

    sc_lua_open_bounded(L, charge_steps);

    for (int i = 0; i < B->ntypes; i++) {
        if (!B->types[i] || !B->types[i]->type) continue;
        lua_pushlightuserdata(L, (void *)B->types[i]);
        lua_pushcclosure(L, construct_node, 1);
        lua_setfield(L, G, B->types[i]->type);
    }
    lua_pushcfunction(L, graph_param);
    lua_setfield(L, G, "param");
    lua_pushcfunction(L, graph_expect);
    lua_setfield(L, G, "expect");
    lua_pushcfunction(L, graph_expect_image);
    lua_setfield(L, G, "expect_image");
    lua_pushcfunction(L, graph_expect_metrics);
    lua_setfield(L, G, "expect_metrics");

    lua_getfield(L, G, LUA_TABLIBNAME);
    lua_getfield(L, -1, "sort");
    lua_pushcclosure(L, sandbox_pairs, 1);
    lua_setfield(L, G, "pairs");
    lua_pop(L, 1);

    lua_newtable(L);   /* _G's metatable: reading an undefined global fails */
    lua_pushcfunction(L, undefined_global);
    lua_setfield(L, -2, "__index");
    lua_setmetatable(L, G);
    lua_settop(L, G - 1);
}

/* Everything that touches Lua runs here, under one lua_pcall: the sandbox
 * set-up can run out of memory too. */
static int build_protected(lua_State *L) {
    builder *B = lua_touserdata(L, 1);
    open_sandbox(L, B);
    lua_pushcfunction(L, message_handler);
    int handler = lua_gettop(L);
    const char *chunkname = lua_pushfstring(L, "@%s", B->path);
    B->status = luaL_loadbufferx(L, B->code, B->code_len, chunkname, "t");
    if (B->status != LUA_OK) return lua_error(L);
    lua_Debug ar;
    lua_pushvalue(L, -1);
    lua_getinfo(L, ">S", &ar);
    snprintf(B->main_short_src, sizeof B->main_short_src, "%s", ar.short_src);
    B->status = lua_pcall(L, 0, 0, handler);
    if (B->status != LUA_OK) return lua_error(L);
    return 0;
}

static int memory_failure(const builder *B, const char *where, sc_error *err) {
    char limit[48];
    limit_text(B, limit, sizeof limit);
    return sc_fail(err, SC_EINPUT, "%s: memory limit exceeded (%s)", where, limit);
}

/* The final message for a failed build. */
static int build_failure(builder *B, lua_State *L, int status, sc_error *err) {
    char where[560];
    if (B->limit_exceeded)
        return sc_fail(err, SC_EINPUT, "%s", B->limit_message);
    const char *msg = lua_type(L, -1) == LUA_TSTRING ? lua_tostring(L, -1) : NULL;
    bool memory = status == LUA_ERRMEM || B->status == LUA_ERRMEM || B->status == LUA_ERRERR ||
                  (msg && strcmp(msg, "not enough memory") == 0);
    if (B->memory_refused && memory) {
        where_text(B, where, sizeof where);
        return memory_failure(B, where, err);
    }
    if (!msg) return sc_fail(err, SC_EINPUT, "%s: the graph failed with a non-string error", B->path);
    int code = B->usage_message[0] && strstr(msg, B->usage_message) ? SC_EUSAGE : SC_EINPUT;
    size_t n = strlen(B->main_short_src);
    if (n && strcmp(B->main_short_src, B->path) != 0 && strncmp(msg, B->main_short_src, n) == 0 &&
        msg[n] == ':')
        return sc_fail(err, code, "%s%s", B->path, msg + n);
    if (!has_position(msg)) return sc_fail(err, code, "%s: %s", B->path, msg);
    return sc_fail(err, code, "%s", msg);
}

/* The names a mistaken one may have meant: "; did you mean 'x'?" in hint
 * (or "") and all of them, "a, b, c", in list. */
typedef const char *(*name_at)(const void *items, int k);
static const char *graph_node_name(const void *g, int k) { return ((const sc_graph *)g)->nodes[k].name; }
static const char *desc_param_name(const void *d, int k) { return ((const sc_node_desc *)d)->params[k].name; }

static void suggest(const char *wrong, const void *items, int count, name_at name, char *hint, size_t nhint,
                    char *list, size_t nlist) {
    const char *best = NULL;
    int dist = 0;
    size_t len = 0;
    list[0] = 0;
    for (int k = 0; k < count; k++) {
        consider(wrong, name(items, k), &best, &dist);
        list_append(list, nlist, &len, name(items, k));
    }
    did_you_mean(best, hint, nhint);
}

/* --set node.param=value: the parameter `param` of the node named `node`,
 * set once the graph file has run (over what the file gave it), read as the
 * parameter's type and checked like any value. Every mistake is the command
 * line's. */
static int set_node_param(builder *B, const sc_setting *set, sc_error *err) {
    const char *dot = strrchr(set->name, '.');
    const char *value = set->value ? set->value : "";
    char node[256], hint[128], list[512];
    snprintf(node, sizeof node, "%.*s", (int)(dot - set->name), set->name);
    sc_graph_node *n = NULL;
    for (int k = 0; k < B->graph->count && !n; k++)
        if (strcmp(B->graph->nodes[k].name, node) == 0) n = &B->graph->nodes[k];
    if (!n) {
        suggest(node, B->graph, B->graph->count, graph_node_name, hint, sizeof hint, list, sizeof list);
        return sc_fail(err, SC_EUSAGE, "%s: --set %s=%s: the graph has no node named '%s'%s (nodes: %s)", B->path,
                       set->name, value, node, hint, list);
    }
    int p = sc_desc_param(n->desc, dot + 1);
    if (p < 0) {
        suggest(dot + 1, n->desc, n->desc->nparams, desc_param_name, hint, sizeof hint, list, sizeof list);
        return sc_fail(err, SC_EUSAGE, "%s: --set %s=%s: node '%s' (%s) has no parameter '%s'%s (parameters: %s)",
                       B->path, set->name, value, node, n->desc->type, dot + 1, hint, list);
    }
    const sc_param_desc *pd = &n->desc->params[p];
    sc_param_value v;
    int rc = sc_param_parse(pd, value, &v, err);
    if (rc == SC_OK && pd->type == SC_PARAM_PATH && *v.string) {
        char *abs = resolve_path(B, v.string);
        free(v.string);
        v.string = abs;
        if (!abs) rc = sc_fail(err, SC_ENOMEM, "cannot resolve '%s' (out of memory or no working directory)", value);
    }
    if (rc != SC_OK) sc_error_prefix(err, "%s:%s", node, pd->name);
    else rc = sc_param_check(pd, &v, node, err);
    if (rc != SC_OK) {
        sc_param_value_clear(&v);
        sc_error_prefix(err, "%s: --set %s=%s", B->path, set->name, value);
        if (rc != SC_ENOMEM) err->code = rc = SC_EUSAGE;
        return rc;
    }
    sc_param_value_clear(&n->params[p]);
    n->params[p] = v;
    return SC_OK;
}

/* Every --set that no param() read and whose name has a dot sets a node's
 * parameter. */
static int set_node_params(builder *B, sc_error *err) {
    for (int i = 0; i < B->nsettings; i++) {
        if (B->setting_used[i] || !strchr(B->settings[i].name, '.')) continue;
        int rc = set_node_param(B, &B->settings[i], err);
        if (rc) return rc;
        B->setting_used[i] = true;
    }
    return SC_OK;
}

/* Every --set must have been read by some param() call. */
static int check_settings_used(const builder *B, sc_error *err) {
    char list[768] = "";
    size_t len = 0;
    int unused = 0;
    for (int i = 0; i < B->nsettings; i++) {
        if (B->setting_used[i]) continue;
        char item[256];
        snprintf(item, sizeof item, "--set %s=%s", B->settings[i].name,
                 B->settings[i].value ? B->settings[i].value : "");
        list_append(list, sizeof list, &len, item);
        unused++;
    }
    if (!unused) return SC_OK;
    return sc_fail(err, SC_EUSAGE, "%s: %s %s not read by any param() call in the graph",
                   B->path, list, unused == 1 ? "is" : "are");
}

/* Skip a UTF-8 byte order mark and turn a "#!" first line into a comment, as
 * lua's own file loader does, keeping line numbers. */
static void prepare_source(sc_buf *code, const char **start, size_t *len) {
    char *s = (char *)code->data;
    size_t n = code->len;
    if (n >= 3 && memcmp(s, "\xEF\xBB\xBF", 3) == 0) {
        s += 3;
        n -= 3;
    }
    if (n >= 1 && s[0] == '#') {
        if (n >= 2 && s[1] != '\n') s[0] = s[1] = '-';
        else s[0] = ' ';
    }
    *start = s;
    *len = n;
}

int sc_lua_build(const char *path, const sc_node_desc *const *types, int ntypes,
                 const sc_setting *settings, int nsettings,
                 const sc_lua_limits *limits, sc_graph **out, sc_error *err) {
    *out = NULL;
    builder B;
    memset(&B, 0, sizeof B);
    B.path = path;
    B.types = types;
    B.ntypes = ntypes;
    B.settings = settings;
    B.nsettings = nsettings > 0 ? nsettings : 0;
    B.max_instructions = limits && limits->max_instructions > 0 ? limits->max_instructions
                                                                 : DEFAULT_MAX_INSTRUCTIONS;
    B.max_memory = limits && limits->max_memory > 0 ? limits->max_memory : DEFAULT_MAX_MEMORY;
    B.hook_step = B.max_instructions < HOOK_STEP ? (int)B.max_instructions : HOOK_STEP;
    B.max_seconds = limits && limits->max_seconds > 0 ? limits->max_seconds : DEFAULT_MAX_SECONDS;

    sc_buf code;
    sc_buf_init(&code);
    int rc = sc_read_file(path, MAX_GRAPH_FILE, &code, err);
    if (rc) return rc;
    prepare_source(&code, &B.code, &B.code_len);

    B.graph = sc_graph_new(path);
    B.setting_used = B.nsettings ? calloc((size_t)B.nsettings, sizeof *B.setting_used) : NULL;
    lua_State *L = B.graph && (B.setting_used || !B.nsettings) ? lua_newstate(limited_alloc, &B)
                                                               : NULL;
    if (!L) {
        rc = B.memory_refused ? memory_failure(&B, path, err)
                              : sc_fail(err, SC_ENOMEM, "%s: out of memory", path);
    } else {
        lua_sethook(L, count_hook, LUA_MASKCOUNT, B.hook_step);
        B.deadline = sc_now() + B.max_seconds;
        lua_pushcfunction(L, build_protected);
        lua_pushlightuserdata(L, &B);
        int status = lua_pcall(L, 1, 0, 0);
        if (status != LUA_OK || B.limit_exceeded) rc = build_failure(&B, L, status, err);
        lua_close(L);
    }
    if (!rc) rc = set_node_params(&B, err);
    if (!rc) rc = check_settings_used(&B, err);
    if (!rc) rc = sc_graph_validate(B.graph, err);

    sc_buf_free(&code);
    free(B.setting_used);
    free(B.cwd);
    if (rc) {
        sc_graph_free(B.graph);
        return rc;
    }
    *out = B.graph;
    return SC_OK;
}
