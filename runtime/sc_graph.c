/* sc_graph.c - graphs of node instances: building, checking, canonical params.
 *
 * Design note: a graph is a plain array of nodes in creation order. Because a
 * node can only name nodes made before it, creation order is a topological
 * order, and "no cycles" reduces to "every producer index is smaller than its
 * consumer's". Everything is C data; the Lua binding (sc_lua.c) only fills it.
 *
 * Parameters start at their descriptor defaults. A required parameter has no
 * default, so it starts "not given", marked in the value itself: NaN for
 * NUMBER/INTEGER/BOOL (no valid value is NaN), NULL for STRING/ENUM/PATH and an
 * empty list for NUMBERS (a required list must hold at least one number).
 * sc_graph_validate reports those before it checks the values. An optional
 * PATH may be empty ("none given"); a required one may not.
 *
 * Ranges: a descriptor that leaves both min and max at 0 declares no range
 * (a range admitting only 0 would be pointless), so designated initialisers
 * may simply omit them.
 *
 * Text forms (sc_param_parse): the command line and descriptor defaults give
 * values as text; a number is the whole text, a list is numbers between
 * commas, and any element that is not a number is an error, never dropped.
 * A descriptor may add a rule on a whole list (check_list) or on a text
 * (check_text), which sc_param_check applies wherever a value is checked.
 *
 * The canonical parameter text is what the cache key hashes, so it depends on
 * values only: names sorted bytewise, numbers as the shortest text that reads
 * back exactly (1 and 1.0 print alike), strings quoted with C escapes. A path
 * is absolute in the graph (the Lua binding resolves it) but enters the text
 * as the caller shows it, with its file's content digest (sc_path_key_fn): the
 * engine shows it relative to a base folder, so keys move with the tree.
 */
#include "sc_graph.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

/* ---------------------------------------------------------------- helpers */

static void param_value_free_contents(sc_param_value *v) {
    free(v->string);
    free(v->numbers);
    v->string = NULL;
    v->numbers = NULL;
    v->count = 0;
}

static void node_free_contents(sc_graph_node *n) {
    if (n->params && n->desc) {
        for (int i = 0; i < n->desc->nparams; i++) param_value_free_contents(&n->params[i]);
    }
    free(n->params);
    free(n->input_node);
    free(n->input_port);
    free(n->name);
    free(n->file);
    memset(n, 0, sizeof *n);
}

static bool has_range(const sc_param_desc *pd) {
    return !(pd->min == 0 && pd->max == 0);
}

/* Numbers in messages: the canonical text, or nan/inf, which it never prints. */
static void format_number(double v, char out[32]) {
    if (isnan(v)) strcpy(out, "nan");
    else if (isinf(v)) strcpy(out, v > 0 ? "inf" : "-inf");
    else sc_format_double(v, out);
}

/* ---------------------------------------------------------------- text */

bool sc_parse_bool(const char *s, bool *out) {
    static const char *const yes[] = {"true", "yes", "1"}, *const no[] = {"false", "no", "0"};
    for (int i = 0; i < 3; i++) {
        if (strcasecmp(s, yes[i]) == 0) return *out = true, true;
        if (strcasecmp(s, no[i]) == 0) return *out = false, true;
    }
    return false;
}

/* One number, the whole of [s, end) but for blanks around it. */
static bool parse_number(const char *s, const char *end, double *out) {
    while (s < end && (*s == ' ' || *s == '\t')) s++;
    while (end > s && (end[-1] == ' ' || end[-1] == '\t')) end--;
    if (s == end || end - s > 63) return false;
    char text[64], *stop;
    memcpy(text, s, (size_t)(end - s));
    text[end - s] = 0;
    *out = strtod(text, &stop);
    return *stop == 0;
}

int sc_parse_numbers(const char *text, double **out, int *count, sc_error *err) {
    *out = NULL;
    *count = 0;
    const char *p = text ? text : "";
    while (*p == ' ' || *p == '\t') p++;
    if (!*p) return SC_OK;   /* an empty list */
    int cap = 1;
    for (const char *c = p; *c; c++) cap += *c == ',';
    double *numbers = sc_alloc_array((size_t)cap, sizeof *numbers);
    if (!numbers) return sc_fail(err, SC_ENOMEM, "out of memory");
    int n = 0;
    for (;;) {
        const char *comma = strchr(p, ',');
        const char *end = comma ? comma : p + strlen(p);
        if (!parse_number(p, end, &numbers[n])) {
            free(numbers);
            return sc_fail(err, SC_EINPUT, "element %d ('%.*s') is not a number", n + 1,
                           (int)(end - p > 64 ? 64 : end - p), p);
        }
        n++;
        if (!comma) break;
        p = comma + 1;
    }
    *out = numbers;
    *count = n;
    return SC_OK;
}

int sc_param_parse(const sc_param_desc *pd, const char *text, sc_param_value *v, sc_error *err) {
    memset(v, 0, sizeof *v);
    v->type = pd->type;
    bool b;
    switch (pd->type) {
    case SC_PARAM_NUMBER:
    case SC_PARAM_INTEGER:
        if (!parse_number(text, text + strlen(text), &v->number))
            return sc_fail(err, SC_EINPUT, "'%s' is not a number", text);
        return SC_OK;
    case SC_PARAM_BOOL:
        if (!sc_parse_bool(text, &b))
            return sc_fail(err, SC_EINPUT, "'%s' is not a boolean (true/false, yes/no, 1/0)", text);
        v->number = b;
        return SC_OK;
    case SC_PARAM_STRING:
    case SC_PARAM_ENUM:
    case SC_PARAM_PATH:
        v->string = sc_strdup(text);
        return v->string ? SC_OK : sc_fail(err, SC_ENOMEM, "out of memory");
    case SC_PARAM_NUMBERS:
        return sc_parse_numbers(text, &v->numbers, &v->count, err);
    }
    return sc_fail(err, SC_EINPUT, "unknown parameter type %d", (int)pd->type);
}

static int param_default(const sc_param_desc *pd, sc_param_value *v) {
    memset(v, 0, sizeof *v);
    v->type = pd->type;
    switch (pd->type) {
    case SC_PARAM_NUMBER:
    case SC_PARAM_INTEGER:
    case SC_PARAM_BOOL:
        v->number = pd->required ? NAN : pd->def;
        return 0;
    case SC_PARAM_STRING:
    case SC_PARAM_PATH:
    case SC_PARAM_ENUM: {
        if (pd->required) return 0;
        const char *def = pd->def_string;
        if (!def && pd->type == SC_PARAM_ENUM && pd->choices) def = pd->choices[0];
        v->string = sc_strdup(def ? def : "");
        return v->string ? 0 : -1;
    }
    case SC_PARAM_NUMBERS:
        return pd->required || sc_parse_numbers(pd->def_string, &v->numbers, &v->count, NULL) == SC_OK ? 0 : -1;
    }
    return 0;
}

/* Whether a required parameter is still at its "not given" mark. */
static bool param_missing(const sc_param_desc *pd, const sc_param_value *v) {
    if (!pd->required) return false;
    switch (pd->type) {
    case SC_PARAM_NUMBER:
    case SC_PARAM_INTEGER:
    case SC_PARAM_BOOL: return isnan(v->number);
    case SC_PARAM_STRING:
    case SC_PARAM_ENUM:
    case SC_PARAM_PATH: return v->string == NULL;
    case SC_PARAM_NUMBERS: return v->count == 0;
    }
    return false;
}

static const char *param_type_label(sc_param_type t) {
    switch (t) {
    case SC_PARAM_NUMBER: return "a number";
    case SC_PARAM_INTEGER: return "an integer";
    case SC_PARAM_BOOL: return "a boolean";
    case SC_PARAM_STRING: return "a string";
    case SC_PARAM_ENUM: return "a choice";
    case SC_PARAM_PATH: return "a path";
    case SC_PARAM_NUMBERS: return "a list of numbers";
    }
    return "an unknown type";
}

/* ---------------------------------------------------------------- graph */

sc_graph *sc_graph_new(const char *file) {
    sc_graph *g = calloc(1, sizeof *g);
    if (!g) return NULL;
    g->file = sc_strdup(file ? file : "");
    if (!g->file) {
        free(g);
        return NULL;
    }
    return g;
}

void sc_graph_free(sc_graph *g) {
    if (!g) return;
    for (int i = 0; i < g->count; i++) node_free_contents(&g->nodes[i]);
    free(g->nodes);
    for (int i = 0; i < g->nexpect; i++) {
        sc_expect *e = &g->expects[i];
        free(e->node);
        free(e->metric);
        free(e->op);
        free(e->file);
    }
    free(g->expects);
    free(g->type_counts);
    free(g->file);
    free(g);
}

/* Nodes made per type. A graph uses a few dozen types at most, so a short
 * array searched linearly keeps sc_graph_add O(types), not O(nodes). */
struct sc_graph_type_count {
    const sc_node_desc *desc;
    int made;
};

/* "<type>_<n>", n counting the nodes of this type from 1. Two descriptors
 * with one type name share the count. */
static char *default_name(sc_graph *g, const sc_node_desc *desc) {
    struct sc_graph_type_count *tc = NULL;
    for (int i = 0; i < g->ntypes && !tc; i++) {
        const sc_node_desc *d = g->type_counts[i].desc;
        if (d == desc || strcmp(d->type, desc->type) == 0) tc = &g->type_counts[i];
    }
    if (!tc) {
        struct sc_graph_type_count *grown =
            sc_realloc_array(g->type_counts, (size_t)g->ntypes + 1, sizeof *grown);
        if (!grown) return NULL;
        g->type_counts = grown;
        tc = &g->type_counts[g->ntypes++];
        tc->desc = desc;
        tc->made = 0;
    }
    char *name = sc_strprintf("%s_%d", desc->type, tc->made + 1);
    if (name) tc->made++;
    return name;
}

int sc_graph_add(sc_graph *g, const sc_node_desc *desc, const char *file, int line) {
    if (!g || !desc) return -1;
    if (g->count == g->cap) {
        int cap = g->cap ? g->cap * 2 : 16;
        sc_graph_node *nodes = sc_realloc_array(g->nodes, (size_t)cap, sizeof *nodes);
        if (!nodes) return -1;
        g->nodes = nodes;
        g->cap = cap;
    }
    sc_graph_node n = {.desc = desc, .line = line};
    n.file = sc_strdup(file ? file : g->file);
    bool ok = n.file != NULL;
    if (ok && desc->nparams > 0) {
        n.params = sc_calloc_array((size_t)desc->nparams, sizeof *n.params);
        ok = n.params != NULL;
        for (int i = 0; ok && i < desc->nparams; i++)
            ok = param_default(&desc->params[i], &n.params[i]) == 0;
    }
    if (ok && desc->ninputs > 0) {
        n.input_node = sc_alloc_array((size_t)desc->ninputs, sizeof *n.input_node);
        n.input_port = sc_alloc_array((size_t)desc->ninputs, sizeof *n.input_port);
        ok = n.input_node && n.input_port;
        for (int i = 0; ok && i < desc->ninputs; i++) {
            n.input_node[i] = -1;
            n.input_port[i] = 0;
        }
    }
    if (ok) {   /* last: it counts the node as made */
        n.name = default_name(g, desc);
        ok = n.name != NULL;
    }
    if (!ok) {
        node_free_contents(&n);
        return -1;
    }
    g->nodes[g->count] = n;
    return g->count++;
}

/* ---------------------------------------------------------------- lookups */

int sc_desc_param(const sc_node_desc *d, const char *name) {
    for (int i = 0; d && name && i < d->nparams; i++)
        if (strcmp(d->params[i].name, name) == 0) return i;
    return -1;
}

int sc_desc_input(const sc_node_desc *d, const char *name) {
    for (int i = 0; d && name && i < d->ninputs; i++)
        if (strcmp(d->inputs[i].name, name) == 0) return i;
    return -1;
}

int sc_desc_output(const sc_node_desc *d, const char *name) {
    for (int i = 0; d && name && i < d->noutputs; i++)
        if (strcmp(d->outputs[i].name, name) == 0) return i;
    return -1;
}

bool sc_kind_feeds(sc_kind from, sc_kind to) {
    if (from == SC_KIND_NONE || to == SC_KIND_NONE) return false;
    return from == to || (from == SC_KIND_ATLAS && to == SC_KIND_MESH);
}

/* ---------------------------------------------------------------- params */

void sc_param_value_clear(sc_param_value *v) {
    if (!v) return;
    param_value_free_contents(v);
    v->number = 0;
}

/* One number of a NUMBER, INTEGER or NUMBERS parameter; `element` is its
 * 1-based place in a list, or 0 for a single number. Messages read
 * "who: 1.5 is outside [0, 1]" or "who: element 2 (1.5) is outside [0, 1]". */
static int check_number(const sc_param_desc *pd, double x, bool integral, const char *who,
                        int element, sc_error *err) {
    char text[32], label[64], lo[32], hi[32];
    format_number(x, text);
    if (element > 0) snprintf(label, sizeof label, "element %d (%s)", element, text);
    else snprintf(label, sizeof label, "%s", text);
    if (!isfinite(x))
        return sc_fail(err, SC_EINPUT, "%s: %s is not a finite number", who, label);
    if (integral && (x != floor(x) || fabs(x) > 9007199254740992.0))
        return sc_fail(err, SC_EINPUT, "%s: %s is not an integer", who, label);
    if (has_range(pd) && !(x >= pd->min && x <= pd->max)) {
        format_number(pd->min, lo);
        format_number(pd->max, hi);
        return sc_fail(err, SC_EINPUT, "%s: %s is outside [%s, %s]", who, label, lo, hi);
    }
    return SC_OK;
}

static int check_choice(const sc_param_desc *pd, const char *s, const char *who,
                        sc_error *err) {
    for (int i = 0; pd->choices && pd->choices[i]; i++)
        if (strcmp(pd->choices[i], s) == 0) return SC_OK;
    char list[512] = "";
    size_t len = 0;
    for (int i = 0; pd->choices && pd->choices[i] && len < sizeof list; i++) {
        int n = snprintf(list + len, sizeof list - len, "%s%s", i ? ", " : "", pd->choices[i]);
        if (n < 0) break;
        len += (size_t)n;
    }
    return sc_fail(err, SC_EINPUT, "%s: '%s' is not one of: %s", who, s, list);
}

int sc_param_check(const sc_param_desc *pd, const sc_param_value *v, const char *node,
                   sc_error *err) {
    char who[256];
    if (node && *node) snprintf(who, sizeof who, "%s:%s", node, pd->name);
    else snprintf(who, sizeof who, "%s", pd->name);

    if (v->type != pd->type)
        return sc_fail(err, SC_EINPUT, "%s: holds %s but is declared as %s", who,
                       param_type_label(v->type), param_type_label(pd->type));
    switch (pd->type) {
    case SC_PARAM_NUMBER:
        return check_number(pd, v->number, false, who, 0, err);
    case SC_PARAM_INTEGER:
        return check_number(pd, v->number, true, who, 0, err);
    case SC_PARAM_BOOL:
        if (v->number != 0 && v->number != 1)
            return sc_fail(err, SC_EINPUT, "%s: a boolean must be true or false", who);
        return SC_OK;
    case SC_PARAM_STRING:
    case SC_PARAM_PATH:
    case SC_PARAM_ENUM:
        if (!v->string) return sc_fail(err, SC_EINPUT, "%s: no value given", who);
        if (pd->type == SC_PARAM_PATH && pd->required && !*v->string)
            return sc_fail(err, SC_EINPUT, "%s: the path is empty", who);
        if (pd->type == SC_PARAM_ENUM) return check_choice(pd, v->string, who, err);
        if (pd->check_text && pd->check_text(v->string, err) != SC_OK) {
            sc_error_prefix(err, "%s", who);
            return SC_EINPUT;
        }
        return SC_OK;
    case SC_PARAM_NUMBERS:
        if (v->count < 0 || (v->count > 0 && !v->numbers))
            return sc_fail(err, SC_EINPUT, "%s: malformed list", who);
        for (int i = 0; i < v->count; i++) {
            int rc = check_number(pd, v->numbers[i], false, who, i + 1, err);
            if (rc) return rc;
        }
        if (pd->check_list && pd->check_list(v->numbers, v->count, err) != SC_OK) {
            sc_error_prefix(err, "%s", who);
            return SC_EINPUT;
        }
        return SC_OK;
    }
    return sc_fail(err, SC_EINPUT, "%s: unknown parameter type %d", who, (int)pd->type);
}

/* ---------------------------------------------------------------- validation */

static int compare_names(const void *a, const void *b, const sc_graph *g) {
    int ia = *(const int *)a, ib = *(const int *)b;
    int c = strcmp(g->nodes[ia].name, g->nodes[ib].name);
    return c ? c : (ia > ib) - (ia < ib);
}

/* qsort has no user data argument; sort the indices with a small merge sort. */
static void sort_by_name(int *idx, int *tmp, int n, const sc_graph *g) {
    if (n < 2) return;
    int h = n / 2;
    sort_by_name(idx, tmp, h, g);
    sort_by_name(idx + h, tmp, n - h, g);
    int i = 0, j = h, k = 0;
    while (i < h && j < n)
        tmp[k++] = compare_names(&idx[i], &idx[j], g) <= 0 ? idx[i++] : idx[j++];
    while (i < h) tmp[k++] = idx[i++];
    while (j < n) tmp[k++] = idx[j++];
    memcpy(idx, tmp, (size_t)n * sizeof *idx);
}

static int check_unique_names(const sc_graph *g, sc_error *err) {
    if (g->count < 2) return SC_OK;
    int *idx = sc_alloc_array((size_t)g->count, sizeof *idx);
    int *tmp = sc_alloc_array((size_t)g->count, sizeof *tmp);
    if (!idx || !tmp) {
        free(idx);
        free(tmp);
        return sc_fail(err, SC_ENOMEM, "%s: out of memory validating the graph", g->file);
    }
    for (int i = 0; i < g->count; i++) idx[i] = i;
    sort_by_name(idx, tmp, g->count, g);
    /* Sorted by (name, index), each run of equal names starts with the node
     * made first. Report the earliest-made node that repeats a name. */
    int dup = -1, first = -1;
    for (int k = 1; k < g->count; k++) {
        const sc_graph_node *a = &g->nodes[idx[k - 1]], *b = &g->nodes[idx[k]];
        if (strcmp(a->name, b->name) != 0) continue;
        if (dup < 0 || idx[k] < dup) {
            dup = idx[k];
            int f = k - 1;   /* the earliest node of this name */
            while (f > 0 && strcmp(g->nodes[idx[f - 1]].name, b->name) == 0) f--;
            first = idx[f];
        }
    }
    free(idx);
    free(tmp);
    if (dup < 0) return SC_OK;
    const sc_graph_node *n = &g->nodes[dup], *f = &g->nodes[first];
    return sc_fail(err, SC_EINPUT, "%s:%d: %s: duplicate node name (also used at %s:%d)",
                   n->file, n->line, n->name, f->file, f->line);
}

static int check_node(const sc_graph *g, int i, sc_error *err) {
    const sc_graph_node *n = &g->nodes[i];
    const sc_node_desc *d = n->desc;
    if (!d || !n->name || !*n->name)
        return sc_fail(err, SC_EINPUT, "%s:%d: node %d has no type or name",
                       n->file ? n->file : g->file, n->line, i + 1);
    for (int p = 0; p < d->ninputs; p++) {
        const sc_port_desc *in = &d->inputs[p];
        int src = n->input_node ? n->input_node[p] : -1;
        if (src < 0) {
            if (in->optional) continue;
            return sc_fail(err, SC_EINPUT, "%s:%d: %s: required input '%s' (%s) is not connected",
                           n->file, n->line, n->name, in->name, sc_kind_name(in->kind));
        }
        if (src >= i)
            return sc_fail(err, SC_EINPUT,
                           "%s:%d: %s: input '%s' comes from a node made later (node %d): "
                           "graphs must be acyclic", n->file, n->line, n->name, in->name, src + 1);
        const sc_graph_node *from = &g->nodes[src];
        int port = n->input_port[p];
        if (port < 0 || port >= from->desc->noutputs)
            return sc_fail(err, SC_EINPUT, "%s:%d: %s: input '%s': node '%s' has no output %d",
                           n->file, n->line, n->name, in->name, from->name, port);
        const sc_port_desc *out = &from->desc->outputs[port];
        if (!sc_kind_feeds(out->kind, in->kind))
            return sc_fail(err, SC_EINPUT,
                           "%s:%d: %s: input '%s' takes %s, but %s.%s gives %s",
                           n->file, n->line, n->name, in->name, sc_kind_name(in->kind),
                           from->name, out->name, sc_kind_name(out->kind));
    }
    for (int p = 0; p < d->nparams; p++) {
        const sc_param_desc *pd = &d->params[p];
        if (param_missing(pd, &n->params[p]))
            return sc_fail(err, SC_EINPUT, "%s:%d: %s: required parameter '%s' is not given",
                           n->file, n->line, n->name, pd->name);
        if (sc_param_check(pd, &n->params[p], n->name, err)) {
            sc_error_prefix(err, "%s:%d", n->file, n->line);
            return SC_EINPUT;
        }
    }
    return SC_OK;
}

int sc_graph_validate(const sc_graph *g, sc_error *err) {
    if (!g) return sc_fail(err, SC_EINPUT, "no graph");
    for (int i = 0; i < g->count; i++) {
        int rc = check_node(g, i, err);
        if (rc) return rc;
    }
    return check_unique_names(g, err);
}

/* ---------------------------------------------------------------- canonical text */

static void put_quoted(sc_buf *out, const char *s) {
    if (!s) {
        sc_buf_puts(out, "null");
        return;
    }
    sc_buf_u8(out, '"');
    for (const unsigned char *p = (const unsigned char *)s; *p; p++) {
        switch (*p) {
        case '"': sc_buf_puts(out, "\\\""); break;
        case '\\': sc_buf_puts(out, "\\\\"); break;
        case '\n': sc_buf_puts(out, "\\n"); break;
        case '\r': sc_buf_puts(out, "\\r"); break;
        case '\t': sc_buf_puts(out, "\\t"); break;
        default:
            /* Octal escapes are always three digits, so never ambiguous. */
            if (*p < 0x20 || *p == 0x7f) sc_buf_printf(out, "\\%03o", *p);
            else sc_buf_u8(out, *p);
        }
    }
    sc_buf_u8(out, '"');
}

static void put_number(sc_buf *out, double v) {
    char text[32];
    if (!isfinite(v)) {
        sc_buf_puts(out, "null");   /* never after validation */
        return;
    }
    sc_format_double(v, text);
    sc_buf_puts(out, text);
}

/* A PATH parameter's value, through path_key when given. */
static void put_path(sc_buf *out, const char *path, sc_path_key_fn path_key, void *ud) {
    char *shown = NULL;
    sc_digest content;
    bool has_content = path && *path && path_key && path_key(ud, path, &shown, &content);
    if (path && *path && path_key && !shown) {
        out->failed = true;
        return;
    }
    put_quoted(out, shown ? shown : path);
    free(shown);
    if (has_content) {
        char hex[65];
        sc_digest_hex(&content, hex);
        sc_buf_printf(out, " sha256:%s", hex);
    }
}

void sc_graph_canonical_params(const sc_graph_node *n, sc_path_key_fn path_key, void *ud, sc_buf *out) {
    const sc_node_desc *d = n->desc;
    if (!d || d->nparams <= 0) return;
    int *order = sc_alloc_array((size_t)d->nparams, sizeof *order);
    if (!order) {
        out->failed = true;
        return;
    }
    /* Insertion sort by name: parameter lists are short. */
    for (int i = 0; i < d->nparams; i++) {
        int j = i;
        while (j > 0 && strcmp(d->params[order[j - 1]].name, d->params[i].name) > 0) {
            order[j] = order[j - 1];
            j--;
        }
        order[j] = i;
    }
    for (int k = 0; k < d->nparams; k++) {
        const sc_param_desc *pd = &d->params[order[k]];
        const sc_param_value *v = &n->params[order[k]];
        sc_buf_puts(out, pd->name);
        sc_buf_u8(out, '=');
        switch (pd->type) {
        case SC_PARAM_NUMBER:
        case SC_PARAM_INTEGER: put_number(out, v->number); break;
        case SC_PARAM_BOOL: sc_buf_puts(out, v->number != 0 ? "true" : "false"); break;
        case SC_PARAM_STRING:
        case SC_PARAM_ENUM: put_quoted(out, v->string); break;
        case SC_PARAM_PATH: put_path(out, v->string, path_key, ud); break;
        case SC_PARAM_NUMBERS:
            sc_buf_u8(out, '[');
            for (int i = 0; i < v->count; i++) {
                if (i) sc_buf_u8(out, ',');
                put_number(out, v->numbers[i]);
            }
            sc_buf_u8(out, ']');
            break;
        }
        sc_buf_u8(out, '\n');
    }
    free(order);
}
