/* test_graph.c - graphs built through the C API: defaults, parameter checks,
 * whole-graph validation and the canonical parameter text the cache hashes. */
#include "sc_graph.h"
#include "sc_test.h"

#include <stdlib.h>

/* ---------------------------------------------------------------- descriptors */

static const char *const modes[] = {"fast", "exact", NULL};

static const sc_param_desc knob_params[] = {
    {.name = "zeta", .type = SC_PARAM_NUMBER, .def = 0.5, .min = 0, .max = 1},
    {.name = "alpha", .type = SC_PARAM_INTEGER, .def = 64, .min = 1, .max = 4096},
    {.name = "mode", .type = SC_PARAM_ENUM, .def_string = "fast", .choices = modes},
    {.name = "flag", .type = SC_PARAM_BOOL, .def = 1},
    {.name = "label", .type = SC_PARAM_STRING, .def_string = "plain"},
    {.name = "levels", .type = SC_PARAM_NUMBERS, .def_string = "0.5,0.1, 0.01", .min = 0, .max = 1},
    {.name = "free", .type = SC_PARAM_NUMBER, .def = -3},   /* no range */
};

/* The same parameters declared in another order. */
static const sc_param_desc knob_params_shuffled[] = {
    knob_params[4], knob_params[6], knob_params[1], knob_params[5],
    knob_params[0], knob_params[3], knob_params[2],
};

static const sc_port_desc atlas_out[] = {{.name = "atlas", .kind = SC_KIND_ATLAS}};
static const sc_port_desc mesh_out[] = {{.name = "mesh", .kind = SC_KIND_MESH}};
static const sc_port_desc image_out[] = {{.name = "image", .kind = SC_KIND_IMAGE}};
static const sc_port_desc atlas_in[] = {{.name = "atlas", .kind = SC_KIND_ATLAS}};
static const sc_port_desc sink_in[] = {
    {.name = "mesh", .kind = SC_KIND_MESH},
    {.name = "extra", .kind = SC_KIND_IMAGE, .optional = true},
};

static const sc_node_desc knob = {
    .type = "knob", .version = 1, .outputs = atlas_out, .noutputs = 1,
    .params = knob_params, .nparams = SC_COUNT(knob_params),
};
static const sc_node_desc knob_shuffled = {
    .type = "knob", .version = 1, .outputs = atlas_out, .noutputs = 1,
    .params = knob_params_shuffled, .nparams = SC_COUNT(knob_params_shuffled),
};
static const sc_node_desc picture = {
    .type = "picture", .version = 1, .outputs = image_out, .noutputs = 1,
};
static const sc_node_desc mid = {
    .type = "mid", .version = 1, .inputs = atlas_in, .ninputs = 1,
    .outputs = mesh_out, .noutputs = 1,
};
static const sc_node_desc sink = {
    .type = "sink", .version = 1, .inputs = sink_in, .ninputs = SC_COUNT(sink_in),
};

static const sc_param_desc need_params[] = {
    {.name = "path", .type = SC_PARAM_PATH, .required = true},
    {.name = "count", .type = SC_PARAM_INTEGER, .required = true, .min = 1, .max = 10},
};
static const sc_node_desc need = {
    .type = "need", .version = 1, .outputs = atlas_out, .noutputs = 1,
    .params = need_params, .nparams = SC_COUNT(need_params),
};

/* ---------------------------------------------------------------- helpers */

static char *canonical(const sc_graph_node *n) {
    sc_buf b;
    sc_buf_init(&b);
    sc_graph_canonical_params(n, NULL, NULL, &b);
    return sc_buf_take_string(&b);
}

static void set_string(sc_param_value *v, const char *s) {
    free(v->string);
    v->string = sc_strdup(s);
}

static bool contains(const char *s, const char *part) {
    return s && part && strstr(s, part) != NULL;
}

static void check_contains(const char *file, int line, const char *s, const char *part) {
    if (!contains(s, part))
        sc_test_fail(file, line, "\"%s\" does not contain \"%s\"", s ? s : "(null)", part);
}

#define CHECK_CONTAINS(s, part) check_contains(__FILE__, __LINE__, (s), (part))

/* ---------------------------------------------------------------- tests */

SC_TEST(defaults_and_names) {
    sc_graph *g = sc_graph_new("g.lua");
    SC_CHECK(g != NULL);
    SC_CHECK_INT(sc_graph_add(g, &knob, "g.lua", 3), 0);
    SC_CHECK_INT(sc_graph_add(g, &mid, "g.lua", 4), 1);
    SC_CHECK_INT(sc_graph_add(g, &knob, "g.lua", 5), 2);
    SC_CHECK_STR(g->nodes[0].name, "knob_1");
    SC_CHECK_STR(g->nodes[1].name, "mid_1");
    SC_CHECK_STR(g->nodes[2].name, "knob_2");
    SC_CHECK_STR(g->nodes[2].file, "g.lua");
    SC_CHECK_INT(g->nodes[2].line, 5);
    SC_CHECK_INT(g->nodes[1].input_node[0], -1);

    const sc_param_value *p = g->nodes[0].params;
    SC_CHECK_NEAR(p[0].number, 0.5, 0);
    SC_CHECK_NEAR(p[1].number, 64, 0);
    SC_CHECK_STR(p[2].string, "fast");
    SC_CHECK_NEAR(p[3].number, 1, 0);
    SC_CHECK_STR(p[4].string, "plain");
    SC_CHECK_INT(p[5].count, 3);
    if (p[5].count == 3) {
        SC_CHECK(p[5].numbers[0] == 0.5);
        SC_CHECK(p[5].numbers[1] == 0.1);
        SC_CHECK(p[5].numbers[2] == 0.01);
    }
    /* Defaults pass their own checks. */
    for (int i = 0; i < knob.nparams; i++)
        SC_CHECK_INT(sc_param_check(&knob.params[i], &p[i], "knob_1", NULL), SC_OK);

    SC_CHECK_INT(sc_desc_param(&knob, "mode"), 2);
    SC_CHECK_INT(sc_desc_param(&knob, "nope"), -1);
    SC_CHECK_INT(sc_desc_input(&sink, "extra"), 1);
    SC_CHECK_INT(sc_desc_input(&knob, "atlas"), -1);
    SC_CHECK_INT(sc_desc_output(&knob, "atlas"), 0);
    SC_CHECK_INT(sc_desc_output(&knob, "mesh"), -1);
    SC_CHECK_INT(sc_graph_add(g, NULL, "g.lua", 1), -1);
    sc_graph_free(g);
}

SC_TEST(kind_feeds) {
    SC_CHECK(sc_kind_feeds(SC_KIND_MESH, SC_KIND_MESH));
    SC_CHECK(sc_kind_feeds(SC_KIND_ATLAS, SC_KIND_ATLAS));
    SC_CHECK(sc_kind_feeds(SC_KIND_ATLAS, SC_KIND_MESH));
    SC_CHECK(!sc_kind_feeds(SC_KIND_MESH, SC_KIND_ATLAS));
    SC_CHECK(!sc_kind_feeds(SC_KIND_IMAGE, SC_KIND_MESH));
    SC_CHECK(!sc_kind_feeds(SC_KIND_LODS, SC_KIND_ATLAS));
    SC_CHECK(!sc_kind_feeds(SC_KIND_NONE, SC_KIND_NONE));
}

SC_TEST(canonical_sorted_and_stable) {
    sc_graph *g = sc_graph_new("g.lua");
    sc_graph_add(g, &knob, "g.lua", 1);
    sc_graph_add(g, &knob_shuffled, "g.lua", 2);
    char *a = canonical(&g->nodes[0]);
    char *b = canonical(&g->nodes[1]);
    SC_CHECK_STR(a, "alpha=64\n"
                    "flag=true\n"
                    "free=-3\n"
                    "label=\"plain\"\n"
                    "levels=[0.5,0.1,0.01]\n"
                    "mode=\"fast\"\n"
                    "zeta=0.5\n");
    SC_CHECK_STR(a, b);   /* declaration order does not matter */

    /* The same values set in a different order give the same bytes. */
    sc_graph_node *n0 = &g->nodes[0], *n1 = &g->nodes[1];
    n0->params[sc_desc_param(&knob, "zeta")].number = 0.25;
    set_string(&n0->params[sc_desc_param(&knob, "label")], "x");
    n0->params[sc_desc_param(&knob, "flag")].number = 0;
    n1->params[sc_desc_param(&knob_shuffled, "flag")].number = 0;
    set_string(&n1->params[sc_desc_param(&knob_shuffled, "label")], "x");
    n1->params[sc_desc_param(&knob_shuffled, "zeta")].number = 0.25;
    char *c = canonical(n0);
    char *d = canonical(n1);
    SC_CHECK_STR(c, d);
    CHECK_CONTAINS(c, "flag=false\n");
    CHECK_CONTAINS(c, "zeta=0.25\n");
    char *again = canonical(n0);
    SC_CHECK_STR(c, again);
    free(a);
    free(b);
    free(c);
    free(d);
    free(again);
    sc_graph_free(g);
}

SC_TEST(canonical_numbers) {
    sc_graph *g = sc_graph_new("g.lua");
    sc_graph_add(g, &knob, "g.lua", 1);
    sc_graph_node *n = &g->nodes[0];
    sc_param_value *zeta = &n->params[0], *freev = &n->params[6];

    /* Integral values print without a fraction; both zeros alike. */
    zeta->number = 1.0;
    freev->number = -0.0;
    char *s = canonical(n);
    CHECK_CONTAINS(s, "zeta=1\n");
    CHECK_CONTAINS(s, "free=0\n");
    free(s);

    /* Non-integral values round-trip exactly. */
    const double samples[] = {0.1, 1.0 / 3.0, 2.0 / 3.0, 1e-300, 5e-324, 123456.789,
                              -2.5e-8, 0.30000000000000004, 1e22, 9007199254740993.0};
    for (size_t i = 0; i < sizeof samples / sizeof samples[0]; i++) {
        freev->number = samples[i];
        s = canonical(n);
        const char *at = strstr(s, "free=");
        SC_CHECK(at != NULL);
        if (at) {
            double back = strtod(at + 5, NULL);
            SC_CHECK_MSG(back == samples[i], "%.17g printed as %s", samples[i], at + 5);
        }
        free(s);
    }
    freev->number = 0.1;
    s = canonical(n);
    CHECK_CONTAINS(s, "free=0.1\n");   /* the shortest form, not 0.10000000000000001 */
    free(s);
    sc_graph_free(g);
}

SC_TEST(canonical_string_escapes) {
    sc_graph *g = sc_graph_new("g.lua");
    sc_graph_add(g, &knob, "g.lua", 1);
    sc_graph_node *n = &g->nodes[0];
    set_string(&n->params[4], "say \"hi\"\\\n\ttab\r\x01\x7f end");
    char *s = canonical(n);
    CHECK_CONTAINS(s, "label=\"say \\\"hi\\\"\\\\\\n\\ttab\\r\\001\\177 end\"\n");
    /* One line per parameter: no raw newline leaked from the value. */
    int lines = 0;
    for (const char *p = s; *p; p++) lines += *p == '\n';
    SC_CHECK_INT(lines, knob.nparams);
    free(s);

    /* UTF-8 passes through untouched. */
    set_string(&n->params[4], "caf\xc3\xa9");
    s = canonical(n);
    CHECK_CONTAINS(s, "label=\"caf\xc3\xa9\"\n");
    free(s);
    sc_graph_free(g);
}

SC_TEST(param_check_rules) {
    sc_error err;
    const sc_param_desc *zeta = &knob_params[0], *alpha = &knob_params[1];
    const sc_param_desc *mode = &knob_params[2], *levels = &knob_params[5];
    const sc_param_desc *freep = &knob_params[6];
    sc_param_value v = {.type = SC_PARAM_NUMBER, .number = 1.5};

    SC_CHECK_INT(sc_param_check(zeta, &v, "decimate", &err), SC_EINPUT);
    SC_CHECK_STR(err.message, "decimate:zeta: 1.5 is outside [0, 1]");
    v.number = 0;   /* bounds are inclusive */
    SC_CHECK_INT(sc_param_check(zeta, &v, "decimate", &err), SC_OK);
    v.number = 1;
    SC_CHECK_INT(sc_param_check(zeta, &v, "decimate", &err), SC_OK);
    v.number = -1e-12;
    SC_CHECK_INT(sc_param_check(zeta, &v, "decimate", &err), SC_EINPUT);
    v.number = NAN;
    SC_CHECK_INT(sc_param_check(zeta, &v, "decimate", &err), SC_EINPUT);
    CHECK_CONTAINS(err.message, "decimate:zeta: nan is not a finite number");
    v.number = INFINITY;
    SC_CHECK_INT(sc_param_check(freep, &v, "n", &err), SC_EINPUT);
    CHECK_CONTAINS(err.message, "inf is not a finite number");
    v.number = -1e300;   /* no range declared: any finite number */
    SC_CHECK_INT(sc_param_check(freep, &v, "n", &err), SC_OK);

    sc_param_value i = {.type = SC_PARAM_INTEGER, .number = 2.5};
    SC_CHECK_INT(sc_param_check(alpha, &i, "n", &err), SC_EINPUT);
    SC_CHECK_STR(err.message, "n:alpha: 2.5 is not an integer");
    i.number = 4096;
    SC_CHECK_INT(sc_param_check(alpha, &i, "n", &err), SC_OK);
    i.number = 4097;
    SC_CHECK_INT(sc_param_check(alpha, &i, "n", &err), SC_EINPUT);
    SC_CHECK_STR(err.message, "n:alpha: 4097 is outside [1, 4096]");
    i.number = 0;
    SC_CHECK_INT(sc_param_check(alpha, &i, NULL, &err), SC_EINPUT);
    SC_CHECK_STR(err.message, "alpha: 0 is outside [1, 4096]");

    /* A value of the wrong type. */
    SC_CHECK_INT(sc_param_check(alpha, &v, "n", &err), SC_EINPUT);
    CHECK_CONTAINS(err.message, "n:alpha: holds a number but is declared as an integer");

    sc_param_value e = {.type = SC_PARAM_ENUM, .string = "exact"};
    SC_CHECK_INT(sc_param_check(mode, &e, "n", &err), SC_OK);
    e.string = "fastest";
    SC_CHECK_INT(sc_param_check(mode, &e, "n", &err), SC_EINPUT);
    SC_CHECK_STR(err.message, "n:mode: 'fastest' is not one of: fast, exact");
    e.string = NULL;
    SC_CHECK_INT(sc_param_check(mode, &e, "n", &err), SC_EINPUT);

    double list[] = {0.5, 1.5, 0.2};
    sc_param_value l = {.type = SC_PARAM_NUMBERS, .numbers = list, .count = 3};
    SC_CHECK_INT(sc_param_check(levels, &l, "n", &err), SC_EINPUT);
    SC_CHECK_STR(err.message, "n:levels: element 2 (1.5) is outside [0, 1]");
    list[1] = NAN;
    SC_CHECK_INT(sc_param_check(levels, &l, "n", &err), SC_EINPUT);
    CHECK_CONTAINS(err.message, "element 2 (nan) is not a finite number");
    list[1] = 1;
    SC_CHECK_INT(sc_param_check(levels, &l, "n", &err), SC_OK);
    l.count = 0;
    l.numbers = NULL;
    SC_CHECK_INT(sc_param_check(levels, &l, "n", &err), SC_OK);

    sc_param_value b = {.type = SC_PARAM_BOOL, .number = 2};
    SC_CHECK_INT(sc_param_check(&knob_params[3], &b, "n", &err), SC_EINPUT);

    /* clear frees and resets */
    sc_param_value owned = {.type = SC_PARAM_STRING, .string = sc_strdup("x")};
    sc_param_value_clear(&owned);
    SC_CHECK(owned.string == NULL);
    sc_param_value_clear(NULL);
}

static sc_graph *valid_graph(void) {
    sc_graph *g = sc_graph_new("v.lua");
    int k = sc_graph_add(g, &knob, "v.lua", 1);
    int m = sc_graph_add(g, &mid, "v.lua", 2);
    int s = sc_graph_add(g, &sink, "v.lua", 3);
    g->nodes[m].input_node[0] = k;
    g->nodes[s].input_node[0] = k;   /* an atlas feeds a mesh port */
    return g;
}

SC_TEST(validate_accepts_good_graph) {
    sc_graph *g = valid_graph();
    sc_error err;
    SC_CHECK_INT(sc_graph_validate(g, &err), SC_OK);
    sc_graph_free(g);
}

SC_TEST(validate_missing_input) {
    sc_graph *g = valid_graph();
    sc_error err;
    g->nodes[1].input_node[0] = -1;
    SC_CHECK_INT(sc_graph_validate(g, &err), SC_EINPUT);
    SC_CHECK_STR(err.message, "v.lua:2: mid_1: required input 'atlas' (atlas) is not connected");
    sc_graph_free(g);
}

SC_TEST(validate_kind_mismatch) {
    sc_graph *g = valid_graph();
    sc_error err;
    int p = sc_graph_add(g, &picture, "v.lua", 4);
    int m = sc_graph_add(g, &mid, "v.lua", 5);
    g->nodes[m].input_node[0] = p;
    SC_CHECK_INT(sc_graph_validate(g, &err), SC_EINPUT);
    CHECK_CONTAINS(err.message, "v.lua:5: mid_2: input 'atlas' takes atlas, but picture_1.image gives image");
    /* A mesh cannot feed an atlas port. */
    g->nodes[m].input_node[0] = 1;
    SC_CHECK_INT(sc_graph_validate(g, &err), SC_EINPUT);
    CHECK_CONTAINS(err.message, "mid_1.mesh gives mesh");
    /* An optional port may stay empty, but a connected one is checked. */
    g->nodes[m].input_node[0] = 0;
    SC_CHECK_INT(sc_graph_validate(g, &err), SC_OK);
    g->nodes[2].input_node[1] = 0;   /* sink.extra (image) from an atlas */
    SC_CHECK_INT(sc_graph_validate(g, &err), SC_EINPUT);
    CHECK_CONTAINS(err.message, "v.lua:3: sink_1: input 'extra' takes image");
    sc_graph_free(g);
}

SC_TEST(validate_order_and_ports) {
    sc_graph *g = valid_graph();
    sc_error err;
    g->nodes[1].input_node[0] = 2;   /* from a later node: a cycle in disguise */
    SC_CHECK_INT(sc_graph_validate(g, &err), SC_EINPUT);
    CHECK_CONTAINS(err.message, "v.lua:2: mid_1: input 'atlas' comes from a node made later");
    g->nodes[1].input_node[0] = 1;   /* from itself */
    SC_CHECK_INT(sc_graph_validate(g, &err), SC_EINPUT);
    CHECK_CONTAINS(err.message, "made later");
    g->nodes[1].input_node[0] = 0;
    g->nodes[1].input_port[0] = 3;   /* knob has one output */
    SC_CHECK_INT(sc_graph_validate(g, &err), SC_EINPUT);
    CHECK_CONTAINS(err.message, "has no output 3");
    sc_graph_free(g);
}

SC_TEST(validate_duplicate_names) {
    sc_graph *g = valid_graph();
    sc_error err;
    sc_graph_add(g, &knob, "v.lua", 7);
    sc_graph_add(g, &knob, "v.lua", 9);
    free(g->nodes[3].name);
    g->nodes[3].name = sc_strdup("mid_1");
    free(g->nodes[4].name);
    g->nodes[4].name = sc_strdup("knob_1");
    SC_CHECK_INT(sc_graph_validate(g, &err), SC_EINPUT);
    /* The first repeat in creation order is reported, with the first use. */
    SC_CHECK_STR(err.message, "v.lua:7: mid_1: duplicate node name (also used at v.lua:2)");
    free(g->nodes[3].name);
    g->nodes[3].name = sc_strdup("other");
    SC_CHECK_INT(sc_graph_validate(g, &err), SC_EINPUT);
    SC_CHECK_STR(err.message, "v.lua:9: knob_1: duplicate node name (also used at v.lua:1)");
    sc_graph_free(g);
}

SC_TEST(validate_params) {
    sc_graph *g = sc_graph_new("p.lua");
    sc_error err;
    sc_graph_add(g, &need, "p.lua", 4);
    SC_CHECK_INT(sc_graph_validate(g, &err), SC_EINPUT);
    SC_CHECK_STR(err.message, "p.lua:4: need_1: required parameter 'path' is not given");
    set_string(&g->nodes[0].params[0], "/tmp/x.obj");
    SC_CHECK_INT(sc_graph_validate(g, &err), SC_EINPUT);
    SC_CHECK_STR(err.message, "p.lua:4: need_1: required parameter 'count' is not given");
    g->nodes[0].params[1].number = 11;
    SC_CHECK_INT(sc_graph_validate(g, &err), SC_EINPUT);
    SC_CHECK_STR(err.message, "p.lua:4: need_1:count: 11 is outside [1, 10]");
    g->nodes[0].params[1].number = 10;
    SC_CHECK_INT(sc_graph_validate(g, &err), SC_OK);
    char *s = canonical(&g->nodes[0]);
    SC_CHECK_STR(s, "count=10\npath=\"/tmp/x.obj\"\n");
    free(s);
    sc_graph_free(g);

    g = sc_graph_new("empty.lua");
    SC_CHECK_INT(sc_graph_validate(g, &err), SC_OK);
    sc_graph_free(g);
    sc_graph_free(NULL);
}

int main(void) { return sc_test_main(); }
