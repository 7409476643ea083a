/* test_lua.c - the graph language: building graphs from the files in
 * tests/data/lua, param()/--set, and the sandbox and its limits. Every bad
 * graph must fail with the right file:line and message, and never crash. */
#include "sc_lua.h"
#include "sc_lua_bounded.h"
#include "sc_test.h"

#include <lauxlib.h>
#include <lualib.h>

#include <stdlib.h>
#include <unistd.h>

/* ---------------------------------------------------------------- node types */

static const char *const modes[] = {"fast", "exact", NULL};

static int not_increasing(const double *x, int n, sc_error *err) {
    for (int i = 1; i < n; i++)
        if (x[i] > x[i - 1]) return sc_fail(err, SC_EINPUT, "element %d increases", i + 1);
    return SC_OK;
}

static const sc_param_desc src_params[] = {
    {.name = "size", .type = SC_PARAM_INTEGER, .def = 64, .min = 1, .max = 4096},
    {.name = "mode", .type = SC_PARAM_ENUM, .def_string = "fast", .choices = modes},
    {.name = "ratio", .type = SC_PARAM_NUMBER, .def = 0.5, .min = 0, .max = 1},
    {.name = "flag", .type = SC_PARAM_BOOL, .def = 0},
    {.name = "label", .type = SC_PARAM_STRING, .def_string = "plain"},
    {.name = "file", .type = SC_PARAM_PATH},
    {.name = "levels", .type = SC_PARAM_NUMBERS, .def_string = "0.5,0.1", .min = 0, .max = 1,
     .check_list = not_increasing},
};
static const sc_port_desc src_out[] = {{.name = "atlas", .kind = SC_KIND_ATLAS}};
static const sc_node_desc src = {
    .type = "src", .version = 1, .outputs = src_out, .noutputs = 1,
    .params = src_params, .nparams = SC_COUNT(src_params),
};

static const sc_port_desc mid_in[] = {{.name = "atlas", .kind = SC_KIND_ATLAS}};
static const sc_port_desc mid_out[] = {{.name = "mesh", .kind = SC_KIND_MESH}};
static const sc_node_desc mid = {
    .type = "mid", .version = 1, .inputs = mid_in, .ninputs = 1,
    .outputs = mid_out, .noutputs = 1,
};

static const sc_port_desc two_out[] = {
    {.name = "a", .kind = SC_KIND_ATLAS},
    {.name = "img", .kind = SC_KIND_IMAGE},
};
static const sc_node_desc two = {
    .type = "two", .version = 1, .outputs = two_out, .noutputs = 2,
};

static const sc_port_desc pair_out[] = {
    {.name = "left", .kind = SC_KIND_ATLAS},
    {.name = "right", .kind = SC_KIND_ATLAS},
};
static const sc_node_desc pair = {
    .type = "pair", .version = 1, .outputs = pair_out, .noutputs = 2,
};

static const sc_port_desc sink_in[] = {
    {.name = "mesh", .kind = SC_KIND_MESH, .optional = true},
    {.name = "image", .kind = SC_KIND_IMAGE, .optional = true},
};
static const sc_port_desc sink_out[] = {{.name = "report", .kind = SC_KIND_REPORT}};
static const sc_node_desc sink = {
    .type = "sink", .version = 1, .inputs = sink_in, .ninputs = 2,
    .outputs = sink_out, .noutputs = 1,
};

static const sc_param_desc need_params[] = {
    {.name = "path", .type = SC_PARAM_PATH, .required = true},
};
static const sc_node_desc need = {
    .type = "need", .version = 1, .outputs = src_out, .noutputs = 1,
    .params = need_params, .nparams = 1,
};

static const sc_node_desc *const types[] = {&src, &mid, &two, &pair, &sink, &need};

/* ---------------------------------------------------------------- helpers */

static const sc_lua_limits small_limits = {
    .max_instructions = 2000000,
    .max_memory = 32u << 20,
};

static int build_file(const char *path, const sc_setting *settings, int nsettings,
                      const sc_lua_limits *limits, sc_graph **g, sc_error *err) {
    err->code = 0;
    err->message[0] = 0;
    return sc_lua_build(path, types, SC_COUNT(types), settings, nsettings, limits, g, err);
}

static int build(const char *name, const sc_setting *settings, int nsettings,
                 const sc_lua_limits *limits, sc_graph **g, sc_error *err) {
    char rel[256];
    snprintf(rel, sizeof rel, "tests/data/lua/%s", name);
    char *path = sc_test_source_path(rel);
    int rc = build_file(path, settings, nsettings, limits, g, err);
    free(path);
    return rc;
}

static bool contains(const char *s, const char *part) {
    return s && part && strstr(s, part) != NULL;
}

static void check_contains(const char *file, int line, const char *s, const char *part) {
    if (!contains(s, part))
        sc_test_fail(file, line, "\"%s\" does not contain \"%s\"", s ? s : "(null)", part);
}

#define CHECK_CONTAINS(s, part) check_contains(__FILE__, __LINE__, (s), (part))

/* The graph file must fail with "name:line: " and the fragment. */
static void check_fails_at(const char *file, int at, const char *name, int line,
                           const char *fragment, const sc_lua_limits *limits) {
    sc_graph *g = (sc_graph *)1;
    sc_error err;
    int rc = build(name, NULL, 0, limits, &g, &err);
    char where[256];
    snprintf(where, sizeof where, "/%s:%d: ", name, line);
    if (rc != SC_EINPUT || g != NULL || !contains(err.message, where) ||
        !contains(err.message, fragment))
        sc_test_fail(file, at, "%s: rc %d, message \"%s\"; expected \"%s\" and \"%s\"", name, rc,
                     err.message, where, fragment);
    if (rc == SC_OK && g) sc_graph_free(g);
}

#define CHECK_FAILS(name, line, fragment) \
    check_fails_at(__FILE__, __LINE__, name, line, fragment, &small_limits)

static char *canonical(const sc_graph_node *n) {
    sc_buf b;
    sc_buf_init(&b);
    sc_graph_canonical_params(n, NULL, NULL, &b);
    return sc_buf_take_string(&b);
}

static const sc_param_value *param_of(const sc_graph_node *n, const char *name) {
    int i = sc_desc_param(n->desc, name);
    return i >= 0 ? &n->params[i] : NULL;
}

/* ---------------------------------------------------------------- good graphs */

SC_TEST(good_graph_builds) {
    sc_graph *g = NULL;
    sc_error err;
    int rc = build("good.lua", NULL, 0, NULL, &g, &err);
    SC_CHECK_MSG(rc == SC_OK, "%s", err.message);
    if (rc) return;
    SC_CHECK_INT(g->count, 6);
    const char *names[] = {"source", "mid_1", "two_1", "sink_1", "src_2", "src_3"};
    const int lines[] = {2, 3, 4, 5, 6, 8};
    for (int i = 0; i < 6 && i < g->count; i++) {
        SC_CHECK_STR(g->nodes[i].name, names[i]);
        SC_CHECK_INT(g->nodes[i].line, lines[i]);
        CHECK_CONTAINS(g->nodes[i].file, "tests/data/lua/good.lua");
    }
    CHECK_CONTAINS(g->file, "tests/data/lua/good.lua");

    /* edges */
    SC_CHECK_INT(g->nodes[1].input_node[0], 0);
    SC_CHECK_INT(g->nodes[1].input_port[0], 0);
    SC_CHECK_INT(g->nodes[3].input_node[0], 2);   /* sink.mesh <- two.a */
    SC_CHECK_INT(g->nodes[3].input_port[0], 0);
    SC_CHECK_INT(g->nodes[3].input_node[1], 2);   /* sink.image <- two.img */
    SC_CHECK_INT(g->nodes[3].input_port[1], 1);

    /* parameters */
    const sc_graph_node *s = &g->nodes[0];
    SC_CHECK_NEAR(param_of(s, "size")->number, 128, 0);
    SC_CHECK_STR(param_of(s, "mode")->string, "exact");
    SC_CHECK_NEAR(param_of(s, "ratio")->number, 0.5, 0);   /* default */
    const sc_graph_node *s2 = &g->nodes[4];
    const sc_param_value *levels = param_of(s2, "levels");
    SC_CHECK_INT(levels->count, 2);
    if (levels->count == 2) {
        SC_CHECK(levels->numbers[0] == 0.25);
        SC_CHECK(levels->numbers[1] == 0.125);
    }
    SC_CHECK_NEAR(param_of(s2, "flag")->number, 1, 0);
    char cwd[4096];
    SC_CHECK(getcwd(cwd, sizeof cwd) != NULL);
    char expect_path[4200];
    snprintf(expect_path, sizeof expect_path, "%s/data/x.obj", strcmp(cwd, "/") ? cwd : "");
    SC_CHECK_STR(param_of(s2, "file")->string, expect_path);
    const sc_graph_node *s3 = &g->nodes[5];
    SC_CHECK_INT(param_of(s3, "levels")->count, 1);   /* a single number is a list of one */

    /* Lua 1 and 1.0, 64 and 64.0 give the same canonical bytes. */
    char *c2 = canonical(s2), *c3 = canonical(s3);
    CHECK_CONTAINS(c2, "ratio=1\n");
    CHECK_CONTAINS(c3, "ratio=1\n");
    CHECK_CONTAINS(c3, "size=64\n");
    CHECK_CONTAINS(c3, "levels=[0.5]\n");
    CHECK_CONTAINS(c2, "levels=[0.25,0.125]\n");
    free(c2);
    free(c3);

    /* expectations */
    SC_CHECK_INT(g->nexpect, 2);
    if (g->nexpect == 2) {
        SC_CHECK_STR(g->expects[0].node, "sink_1");
        SC_CHECK_STR(g->expects[0].metric, "psnr");
        SC_CHECK_STR(g->expects[0].op, ">=");
        SC_CHECK_NEAR(g->expects[0].value, 30, 0);
        SC_CHECK_INT(g->expects[0].line, 9);
        SC_CHECK_STR(g->expects[1].node, "mid_1");
        SC_CHECK_STR(g->expects[1].op, "~");
        SC_CHECK_NEAR(g->expects[1].value, 1000, 0);
        SC_CHECK_NEAR(g->expects[1].tolerance, 10, 0);
        SC_CHECK_INT(g->expects[1].line, 10);
        CHECK_CONTAINS(g->expects[1].file, "good.lua");
    }

    /* A second build gives the same graph, byte for byte. */
    sc_graph *again = NULL;
    SC_CHECK_INT(build("good.lua", NULL, 0, NULL, &again, &err), SC_OK);
    if (again) {
        SC_CHECK_INT(again->count, g->count);
        for (int i = 0; i < g->count && i < again->count; i++) {
            char *a = canonical(&g->nodes[i]), *b = canonical(&again->nodes[i]);
            SC_CHECK_STR(a, b);
            free(a);
            free(b);
        }
        sc_graph_free(again);
    }
    sc_graph_free(g);
}

SC_TEST(param_defaults_and_settings) {
    sc_graph *g = NULL;
    sc_error err;
    SC_CHECK_INT(build("params.lua", NULL, 0, NULL, &g, &err), SC_OK);
    if (g) {
        const sc_graph_node *n = &g->nodes[0];
        SC_CHECK_NEAR(param_of(n, "size")->number, 64, 0);
        SC_CHECK_NEAR(param_of(n, "ratio")->number, 0.5, 0);
        SC_CHECK_NEAR(param_of(n, "flag")->number, 0, 0);
        SC_CHECK_STR(param_of(n, "label")->string, "plain");
        sc_graph_free(g);
    }

    const sc_setting set[] = {
        {"size", "256"}, {"ratio", "0.25"}, {"fast", "yes"}, {"label", "hello world"},
    };
    g = NULL;
    SC_CHECK_INT(build("params.lua", set, 4, NULL, &g, &err), SC_OK);
    if (g) {
        const sc_graph_node *n = &g->nodes[0];
        SC_CHECK_NEAR(param_of(n, "size")->number, 256, 0);
        SC_CHECK_NEAR(param_of(n, "ratio")->number, 0.25, 0);
        SC_CHECK_NEAR(param_of(n, "flag")->number, 1, 0);
        SC_CHECK_STR(param_of(n, "label")->string, "hello world");
        sc_graph_free(g);
    }

    /* The last --set of a name wins; booleans accept true/false, 1/0, yes/no. */
    const sc_setting twice[] = {{"fast", "true"}, {"fast", "0"}, {"size", "0x10"}};
    g = NULL;
    SC_CHECK_INT(build("params.lua", twice, 3, NULL, &g, &err), SC_OK);
    if (g) {
        SC_CHECK_NEAR(param_of(&g->nodes[0], "flag")->number, 0, 0);
        SC_CHECK_NEAR(param_of(&g->nodes[0], "size")->number, 16, 0);
        sc_graph_free(g);
    }
}

SC_TEST(param_errors) {
    sc_graph *g = (sc_graph *)1;
    sc_error err;
    /* What the command line gets wrong is a usage error (SC_EUSAGE: exit status 2). */
    const sc_setting not_number[] = {{"size", "abc"}};
    SC_CHECK_INT(build("params.lua", not_number, 1, NULL, &g, &err), SC_EUSAGE);
    SC_CHECK(g == NULL);
    CHECK_CONTAINS(err.message, "params.lua:1: --set size=abc: not a number");

    const sc_setting not_bool[] = {{"fast", "maybe"}};
    SC_CHECK_INT(build("params.lua", not_bool, 1, NULL, &g, &err), SC_EUSAGE);
    CHECK_CONTAINS(err.message, "params.lua:3: --set fast=maybe: not a boolean");

    const sc_setting infinite[] = {{"ratio", "1e999"}};
    SC_CHECK_INT(build("params.lua", infinite, 1, NULL, &g, &err), SC_EUSAGE);
    CHECK_CONTAINS(err.message, "params.lua:2: --set ratio=1e999: not a finite number");

    /* A converted value still meets the node's range, at the node's line,
     * naming the node's parameter and the --set it came from. */
    const sc_setting too_big[] = {{"ratio", "16"}};
    SC_CHECK_INT(build("params.lua", too_big, 1, NULL, &g, &err), SC_EUSAGE);
    CHECK_CONTAINS(err.message, "params.lua:5: --set ratio=16: src:ratio: 16 is outside [0, 1]");

    /* A typo on a farm must not pass silently. */
    const sc_setting typo[] = {{"size", "32"}, {"sise", "2"}, {"lable", "x"}};
    SC_CHECK_INT(build("params.lua", typo, 3, NULL, &g, &err), SC_EUSAGE);
    SC_CHECK(g == NULL);
    CHECK_CONTAINS(err.message, "params.lua: --set sise=2, --set lable=x are not read by any param()");
    SC_CHECK(!contains(err.message, "size=32"));

    SC_CHECK_INT(build("required.lua", NULL, 0, NULL, &g, &err), SC_EUSAGE);
    CHECK_CONTAINS(err.message, "required.lua:2: parameter 'asset' is required: pass --set asset=...");

    const sc_setting asset[] = {{"asset", "meshes/../meshes/a.obj"}};
    g = NULL;
    SC_CHECK_INT(build("required.lua", asset, 1, NULL, &g, &err), SC_OK);
    if (g) {
        char cwd[4096];
        SC_CHECK(getcwd(cwd, sizeof cwd) != NULL);
        char expect_path[4200];
        snprintf(expect_path, sizeof expect_path, "%s/meshes/a.obj", strcmp(cwd, "/") ? cwd : "");
        SC_CHECK_STR(param_of(&g->nodes[0], "file")->string, expect_path);
        sc_graph_free(g);
    }
}

/* A table default makes param() read a list of numbers, every element a
 * number; the list meets the node's rule when the graph is built. */
SC_TEST(param_lists) {
    sc_graph *g = NULL;
    sc_error err;
    SC_CHECK_INT(build("lists.lua", NULL, 0, NULL, &g, &err), SC_OK);
    if (g) {
        const sc_param_value *v = param_of(&g->nodes[0], "levels");
        SC_CHECK_INT(v->count, 2);
        SC_CHECK(v->count == 2 && v->numbers[0] == 0.5 && v->numbers[1] == 0.25);
        sc_graph_free(g);
    }
    const sc_setting three[] = {{"levels", " 0.4, 0.2,0.1"}};
    g = NULL;
    SC_CHECK_INT(build("lists.lua", three, 1, NULL, &g, &err), SC_OK);
    if (g) {
        const sc_param_value *v = param_of(&g->nodes[0], "levels");
        SC_CHECK(v->count == 3 && v->numbers[0] == 0.4 && v->numbers[2] == 0.1);
        sc_graph_free(g);
    }
    const sc_setting bad[] = {{"levels", "0.5,abc"}};
    SC_CHECK_INT(build("lists.lua", bad, 1, NULL, &g, &err), SC_EUSAGE);
    CHECK_CONTAINS(err.message, "lists.lua:2: --set levels=0.5,abc: element 2 ('abc') is not a number");
    const sc_setting empty_item[] = {{"levels", "0.5,,0.1"}};
    SC_CHECK_INT(build("lists.lua", empty_item, 1, NULL, &g, &err), SC_EUSAGE);
    CHECK_CONTAINS(err.message, "element 2 ('') is not a number");
    const sc_setting increasing[] = {{"levels", "0.1,0.5"}};
    SC_CHECK_INT(build("lists.lua", increasing, 1, NULL, &g, &err), SC_EUSAGE);
    CHECK_CONTAINS(err.message, "lists.lua:3: --set levels=0.1,0.5: first:levels: element 2 increases");
    /* the graph caught a bad --set and then failed for a reason of its own */
    const sc_setting caught[] = {{"size", "abc"}};
    SC_CHECK_INT(build("caught.lua", caught, 1, NULL, &g, &err), SC_EINPUT);
    CHECK_CONTAINS(err.message, "caught.lua:3: src:size: 5000 is outside [1, 4096]");
}

/* --set node.param=value sets a parameter of the node of that name, over
 * what the graph gave it; every mistake in it is a usage error. */
SC_TEST(node_settings) {
    sc_graph *g = NULL;
    sc_error err;
    const sc_setting good[] = {{"second.size", "128"}, {"size", "10"}, {"first.label", "a b"},
                               {"first.file", "x/../y.obj"}, {"first.levels", "0.3,0.2"}, {"first.flag", "yes"}};
    SC_CHECK_INT(build("lists.lua", good, SC_COUNT(good), NULL, &g, &err), SC_OK);
    if (g) {
        SC_CHECK_NEAR(param_of(&g->nodes[1], "size")->number, 128, 0);
        SC_CHECK_STR(param_of(&g->nodes[0], "label")->string, "a b");
        SC_CHECK(strncmp(param_of(&g->nodes[0], "file")->string, "/", 1) == 0 &&
                 contains(param_of(&g->nodes[0], "file")->string, "/y.obj") &&
                 !contains(param_of(&g->nodes[0], "file")->string, ".."));
        SC_CHECK_INT(param_of(&g->nodes[0], "levels")->count, 2);
        SC_CHECK_NEAR(param_of(&g->nodes[0], "flag")->number, 1, 0);
        sc_graph_free(g);
    }
    static const struct {
        const char *name, *value, *message;
    } bad[] = {
        {"first.size", "abc", "--set first.size=abc: first:size: 'abc' is not a number"},
        {"first.size", "5000", "--set first.size=5000: first:size: 5000 is outside [1, 4096]"},
        {"first.mode", "slow", "--set first.mode=slow: first:mode: 'slow' is not one of: fast, exact"},
        {"first.flag", "maybe", "first:flag: 'maybe' is not a boolean"},
        {"first.levels", "0.1,0.5", "--set first.levels=0.1,0.5: first:levels: element 2 increases"},
        {"frist.size", "1", "the graph has no node named 'frist'; did you mean 'first'? (nodes: first, second)"},
        {"first.sise", "1", "node 'first' (src) has no parameter 'sise'; did you mean 'size'?"},
    };
    for (size_t i = 0; i < SC_COUNT(bad); i++) {
        const sc_setting set[] = {{bad[i].name, bad[i].value}};
        g = NULL;
        SC_CHECK_INT(build("lists.lua", set, 1, NULL, &g, &err), SC_EUSAGE);
        SC_CHECK(g == NULL);
        CHECK_CONTAINS(err.message, bad[i].message);
        CHECK_CONTAINS(err.message, "lists.lua: ");
    }
}

/* ---------------------------------------------------------------- bad graphs */

SC_TEST(errors_in_lua) {
    CHECK_FAILS("syntax.lua", 3, "unexpected symbol near '='");
    CHECK_FAILS("runtime.lua", 2, "attempt to index a nil value (local 't')");
    CHECK_FAILS("error_call.lua", 2, "boom");
    CHECK_FAILS("error_table.lua", 2, "(error object is a table value)");
    CHECK_FAILS("error_level0.lua", 3, "no position");
    /* with room enough, deep recursion ends in Lua's own stack limit */
    check_fails_at(__FILE__, __LINE__, "recursion.lua", 2, "stack overflow", NULL);
}

SC_TEST(errors_in_nodes) {
    CHECK_FAILS("unknown_param.lua", 2,
                "src: unknown parameter 'aa' (known: size, mode, ratio, flag, label, file, "
                "levels, name)");
    CHECK_FAILS("wrong_type.lua", 2, "src:size: expected an integer, got string");
    CHECK_FAILS("out_of_range.lua", 1, "src:size: 5000 is outside [1, 4096]");
    CHECK_FAILS("not_integer.lua", 1, "src:size: 2.5 is not an integer");
    CHECK_FAILS("bad_enum.lua", 1, "src:mode: 'fastest' is not one of: fast, exact");
    CHECK_FAILS("numbers_bad.lua", 1, "src:levels: element 2 is string, expected a number");
    CHECK_FAILS("numbers_range.lua", 1, "src:levels: element 2 (2) is outside [0, 1]");
    CHECK_FAILS("numbers_holes.lua", 1, "without holes");
    CHECK_FAILS("missing_input.lua", 2, "mid_1: required input 'atlas' (atlas) is not connected");
    CHECK_FAILS("kind_mismatch.lua", 2, "mid: input 'atlas' takes atlas, but two_1.img gives image");
    CHECK_FAILS("ambiguous.lua", 2, "node 'pair_1' has several outputs that fit");
    CHECK_FAILS("bad_port.lua", 2,
                "node 'two_1' (two) has no output 'nope' (outputs: a (atlas), img (image))");
    CHECK_FAILS("not_a_node.lua", 1, "mid: input 'atlas' takes a node (atlas), got string");
    CHECK_FAILS("dup.lua", 3, "a: duplicate node name (also used at");
    CHECK_FAILS("bad_name.lua", 1, "src: name 'has space' must be");
    CHECK_FAILS("positional.lua", 2, "every field needs a name");
    CHECK_FAILS("need.lua", 2, "need_1: required parameter 'path' is not given");
    CHECK_FAILS("expect_bad.lua", 3, "unknown comparison '!='");
    CHECK_FAILS("expect_tol.lua", 2, "'~' needs a tolerance");
    CHECK_FAILS("tamper_handle.lua", 5, "node handles are read-only");
}

SC_TEST(typos_get_suggestions) {
    CHECK_FAILS("typo_global.lua", 2, "'sourse' is not defined (no such variable or node type); "
                                      "did you mean 'source'?");
    CHECK_FAILS("typo_type.lua", 1, "'scr' is not defined (no such variable or node type); "
                                    "did you mean 'src'?");
    CHECK_FAILS("typo_param.lua", 1, "src: unknown parameter 'sise' (known: size, mode, ratio, "
                                     "flag, label, file, levels, name); did you mean 'size'?");
}

SC_TEST(pairs_is_deterministic) {
    sc_graph *g = NULL;
    sc_error err;
    int rc = build("pairs_order.lua", NULL, 0, NULL, &g, &err);
    SC_CHECK_MSG(rc == SC_OK, "%s", err.message);
    if (!g) return;
    /* numbers ascending, then strings bytewise, then booleans */
    const double order[] = {0.5, 0.8, 0.3, 0.2, 0.7, 0.4, 0.1, 0.6};
    SC_CHECK_INT(g->count, 8);
    for (int i = 0; i < 8 && i < g->count; i++)
        SC_CHECK_NEAR(param_of(&g->nodes[i], "ratio")->number, order[i], 0);
    sc_graph_free(g);
}

SC_TEST(sandbox_blocks_escapes) {
    unlink("/tmp/seamcook-sandbox-escaped");
    CHECK_FAILS("os.lua", 2, "'os' is not defined");
    SC_CHECK(access("/tmp/seamcook-sandbox-escaped", F_OK) != 0);
    CHECK_FAILS("io.lua", 2, "'io' is not defined");
    CHECK_FAILS("require.lua", 1, "'require' is not defined");
    CHECK_FAILS("loadfile.lua", 1, "'loadfile' is not defined");
    CHECK_FAILS("dofile.lua", 2, "'dofile' is not defined");
    CHECK_FAILS("bytecode.lua", 3, "attempt to load a binary chunk");
    CHECK_FAILS("dump.lua", 1, "attempt to call a nil value (field 'dump')");
    CHECK_FAILS("string_meta.lua", 2, "attempt to call a nil value (local 'dump')");
    /* Lua runs finalizers with hooks off: they would escape the limits */
    CHECK_FAILS("finalizer.lua", 2, "__gc finalizers are not available");
}

SC_TEST(sandbox_keeps_the_language) {
    sc_graph *g = NULL, *h = NULL;
    sc_error err;
    int rc = build("sandbox_ok.lua", NULL, 0, NULL, &g, &err);
    SC_CHECK_MSG(rc == SC_OK, "%s", err.message);
    if (!g) return;
    SC_CHECK_INT(g->count, 3);
    if (g->count == 3) {
        SC_CHECK_STR(g->nodes[0].name, "from_load");
        SC_CHECK_INT(g->nodes[1].input_node[0], 0);
    }
    /* math.random is seeded the same on every build. */
    SC_CHECK_INT(build("sandbox_ok.lua", NULL, 0, NULL, &h, &err), SC_OK);
    if (h && g->count == 3 && h->count == 3) {
        double a = param_of(&g->nodes[2], "ratio")->number;
        double b = param_of(&h->nodes[2], "ratio")->number;
        SC_CHECK(a == b);
    }
    sc_graph_free(g);
    sc_graph_free(h);
}

SC_TEST(tampering_with_globals) {
    sc_graph *g = NULL;
    sc_error err;
    int rc = build("tamper.lua", NULL, 0, NULL, &g, &err);
    SC_CHECK_MSG(rc == SC_OK, "%s", err.message);
    if (!g) return;
    SC_CHECK_INT(g->count, 2);
    SC_CHECK_INT(g->nexpect, 1);
    sc_graph_free(g);

    /* A constructor that failed under pcall leaves no node behind. */
    g = NULL;
    rc = build("pcall_node.lua", NULL, 0, NULL, &g, &err);
    SC_CHECK_MSG(rc == SC_OK, "%s", err.message);
    if (!g) return;
    SC_CHECK_INT(g->count, 1);
    SC_CHECK_STR(g->nodes[0].name, "src_1");
    sc_graph_free(g);
}

SC_TEST(instruction_limit) {
    CHECK_FAILS("loop.lua", 2, "instruction limit exceeded");
    /* pcall cannot swallow the limit */
    CHECK_FAILS("loop_pcall.lua", 3, "instruction limit exceeded");
    /* and the default limit holds too */
    check_fails_at(__FILE__, __LINE__, "loop.lua", 2, "instruction limit exceeded", &(sc_lua_limits){.max_seconds = 600});
}

/* Loops inside C library functions count against the same limit: each of
 * these ran forever (or for hours) under the plain instruction hook. */
SC_TEST(c_library_loops_are_bounded) {
    double t0 = sc_now();
    CHECK_FAILS("hang_pattern.lua", 2, "instruction limit exceeded");
    CHECK_FAILS("hang_rep.lua", 3, "instruction limit exceeded");   /* line 2 returns "" at once */
    CHECK_FAILS("hang_move.lua", 2, "instruction limit exceeded");
    CHECK_FAILS("hang_pattern_pcall.lua", 2, "instruction limit exceeded");   /* where it tripped */
    /* with the default instruction limit too (100 million); the clock is
     * wide here so that a slow machine (a sanitizer build, a loaded CI)
     * still trips the count, not the time */
    const sc_lua_limits default_count = {.max_seconds = 600};
    check_fails_at(__FILE__, __LINE__, "hang_pattern.lua", 2, "instruction limit exceeded", &default_count);
    check_fails_at(__FILE__, __LINE__, "hang_move.lua", 2, "instruction limit exceeded", &default_count);
    /* a guard against a hang, not a speed target: the default limits are a
     * fraction of this */
    SC_CHECK_MSG(sc_now() - t0 < 60, "the bounded loops took %.1f s", sc_now() - t0);
}

/* The bounded library functions against Lua's own, as the oracle: the same
 * results (every value, its type) and the same error messages over a grid
 * of subjects, patterns, start positions and replacements. */
static void charge_nothing(lua_State *L, int64_t steps) { (void)L, (void)steps; }

static const char *const agreement_script =
    "local O = ...\n"
    "local subjects = {'', 'hello world', '  key = value  ', 'aaa', '(foo(bar))baz', 'THE (quick) fox',\n"
    "  'a,b,,c', 'x=1, y=22, z=333', '\\0a\\0b', '\\195\\164x', 'one two  three', 'ab]c-d%e', 'xyxyx'}\n"
    "local patterns = {'', 'o', 'l+', 'l*', 'l-', 'l?', '^h', 'd$', '^$', '%a+', '%A+', '%d+', '(%w+)=(%w+)',\n"
    "  '()ll()', '%s*(.-)%s*$', '%b()', '%bxy', '%f[%a]%a+', '%f[%A]', '[%a_][%w_]*', '[^,]*', '[]]', '[a-c]+',\n"
    "  '[%]]', '(a*(.)%w(%s*))', '(a)%1', '(%a+) %1', '%%', '.', '.-', '.*', '$', '^', 'a-b', '[a-]', '[-a]',\n"
    "  '%.', '\\0', '%w+$', '((a)(b))', 'x*', '(', ')', '%', '[a', '%1', '(()', '%b', '%f', '%fx', '[^]',\n"
    "  '%g+', '%p', '%c', '%x+', '%u%l+', '%S+', '[%w-]+', '(x)(y)', '^(%w+)', 'e-', '[^%s]+$', '%0'}\n"
    "local inits = {false, 1, 2, -3, 0, 100, -100}\n"
    "local function pack(ok, ...) local t = {tostring(ok)}\n"
    "  for i = 1, select('#', ...) do local v = select(i, ...); t[#t + 1] = type(v) .. ':' .. tostring(v) end\n"
    "  return table.concat(t, '|') end\n"
    "local function collect(f, ...) local ok, it = pcall(f, ...); if not ok then return pack(false, it) end\n"
    "  local out = {}; for i = 1, 50 do local r = pack(pcall(it)); out[#out + 1] = r; if r == 'true' then break end end\n"
    "  return table.concat(out, ';') end\n"
    "local n, bad = 0, nil\n"
    "local function same(what, a, b) n = n + 1; if a ~= b and not bad then bad = what .. ': ' .. a .. ' vs ' .. b end end\n"
    "local repls = {'%0-%1', '<%0>', '%%', '%2', '%x', '', {hello = 'HI', a = false, o = 7}, function(a, b) return b or a end}\n"
    "for _, s in ipairs(subjects) do for _, p in ipairs(patterns) do\n"
    "  local q = string.format('%q %q', s, p)\n"
    "  for _, i in ipairs(inits) do local init = i or nil\n"
    "    same('find ' .. q, pack(pcall(O.find, s, p, init)), pack(pcall(string.find, s, p, init)))\n"
    "    same('find plain ' .. q, pack(pcall(O.find, s, p, init, true)), pack(pcall(string.find, s, p, init, true)))\n"
    "    same('match ' .. q, pack(pcall(O.match, s, p, init)), pack(pcall(string.match, s, p, init)))\n"
    "    same('gmatch ' .. q, collect(O.gmatch, s, p, init), collect(string.gmatch, s, p, init))\n"
    "  end\n"
    "  for _, r in ipairs(repls) do for _, m in ipairs({false, 0, 1, 2}) do local max = m or nil\n"
    "    same('gsub ' .. q, pack(pcall(O.gsub, s, p, r, max)), pack(pcall(string.gsub, s, p, r, max)))\n"
    "  end end\n"
    "end end\n"
    "for _, a in ipairs({{'ab', 3}, {'ab', 3, ','}, {'', 5}, {'x', 0}, {'x', -1}, {'', 4, '-'}}) do\n"
    "  same('rep', pack(pcall(O.rep, table.unpack(a))), pack(pcall(string.rep, table.unpack(a)))) end\n"
    "local function moved(f, ...) local t = {1, 2, 3, 4, 5}; local ok, e = pcall(f, t, ...); return pack(ok, table.concat(t, ',')) end\n"
    "for _, a in ipairs({{1, 3, 2}, {2, 5, 1}, {1, 0, 3}, {1, 2, 6}}) do\n"
    "  same('move', moved(O.move, table.unpack(a)), moved(table.move, table.unpack(a))) end\n"
    "local function sorted(f, cmp) local t = {5, 3, 9, 1, 7, 2}; f(t, cmp); return table.concat(t, ',') end\n"
    "same('sort', sorted(O.sort), sorted(table.sort))\n"
    "same('sort desc', sorted(O.sort, function(a, b) return a > b end), sorted(table.sort, function(a, b) return a > b end))\n"
    "return n, bad\n";

SC_TEST(bounded_library_functions_agree_with_lua) {
    lua_State *L = luaL_newstate();
    luaL_openlibs(L);
    SC_CHECK(luaL_loadstring(L, agreement_script) == LUA_OK);
    lua_newtable(L);   /* Lua's own functions, before the replacement */
    const char *const string_fns[] = {"find", "match", "gmatch", "gsub", "rep"};
    for (int i = 0; i < 5; i++) {
        lua_getglobal(L, "string");
        lua_getfield(L, -1, string_fns[i]);
        lua_setfield(L, -3, string_fns[i]);
        lua_pop(L, 1);
    }
    const char *const table_fns[] = {"move", "sort"};
    for (int i = 0; i < 2; i++) {
        lua_getglobal(L, "table");
        lua_getfield(L, -1, table_fns[i]);
        lua_setfield(L, -3, table_fns[i]);
        lua_pop(L, 1);
    }
    sc_lua_open_bounded(L, charge_nothing);
    int rc = lua_pcall(L, 1, 2, 0);
    SC_CHECK_MSG(rc == LUA_OK, "%s", lua_tostring(L, -1));
    if (rc == LUA_OK) {
        SC_CHECK_MSG(lua_tointeger(L, -2) > 20000, "only %lld comparisons", (long long)lua_tointeger(L, -2));
        SC_CHECK_MSG(lua_isnil(L, -1), "%s", lua_tostring(L, -1));
    }
    lua_close(L);
}

SC_TEST(wall_clock_limit) {
    sc_lua_limits slow = {.max_instructions = INT64_MAX / 2, .max_seconds = 0.25};
    double t0 = sc_now();
    check_fails_at(__FILE__, __LINE__, "slow_loop.lua", 3, "graph evaluation exceeded 0.25 s", &slow);
    double took = sc_now() - t0;
    SC_CHECK_MSG(took >= 0.25 && took < 30, "the limit of 0.25 s ended evaluation after %.2f s", took);
    /* a C loop hits the clock too: the pattern's steps stay under this budget */
    check_fails_at(__FILE__, __LINE__, "hang_pattern.lua", 2, "graph evaluation exceeded 0.25 s", &slow);
}

SC_TEST(memory_limit) {
    CHECK_FAILS("membomb.lua", 2, "memory limit exceeded");
    CHECK_FAILS("membomb_concat.lua", 2, "memory limit exceeded");
    /* nodes live in C memory, which counts against the same limit */
    CHECK_FAILS("many_nodes.lua", 2, "memory limit exceeded (32 MiB) by the graph's nodes");
    /* A limit too small even for the sandbox fails cleanly. */
    sc_lua_limits tiny = {.max_memory = 4096};
    sc_graph *g = (sc_graph *)1;
    sc_error err;
    SC_CHECK_INT(build("good.lua", NULL, 0, &tiny, &g, &err), SC_EINPUT);
    SC_CHECK(g == NULL);
    CHECK_CONTAINS(err.message, "memory limit exceeded");
}

/* ---------------------------------------------------------------- files */

static char *write_temp_graph(const char *dir, const char *name, const char *text) {
    char *path = sc_path_join(dir, name);
    FILE *f = fopen(path, "wb");
    SC_CHECK(f != NULL);
    if (f) {
        fputs(text, f);
        fclose(f);
    }
    return path;
}

SC_TEST(long_paths_and_file_prologues) {
    char *dir = sc_test_tempdir("lua");
    SC_CHECK(dir != NULL);
    if (!dir) return;
    char *deep = sc_path_join(dir, "a-rather-long-folder-name-so-that-lua-would-shorten-it");
    SC_CHECK_INT(sc_make_dirs(deep, NULL), 0);
    sc_graph *g = (sc_graph *)1;
    sc_error err;

    /* Lua shortens long chunk names; messages still give the whole path. */
    char *path = write_temp_graph(deep, "graph.lua", "src{}\nlocal t = nil\nlocal x = t.y\n");
    SC_CHECK_INT(build_file(path, NULL, 0, NULL, &g, &err), SC_EINPUT);
    char want[1024];
    snprintf(want, sizeof want, "%s:3: attempt to index a nil value", path);
    SC_CHECK_MSG(strncmp(err.message, want, strlen(want)) == 0, "\"%s\" vs \"%s\"", err.message,
                 want);
    free(path);

    path = write_temp_graph(deep, "range.lua", "src{}\nsrc{ size = 0 }\n");
    SC_CHECK_INT(build_file(path, NULL, 0, NULL, &g, &err), SC_EINPUT);
    snprintf(want, sizeof want, "%s:2: src:size: 0 is outside [1, 4096]", path);
    SC_CHECK_STR(err.message, want);
    free(path);

    /* A "#!" line and a byte order mark are skipped; lines still count. */
    path = write_temp_graph(deep, "shebang.lua", "#!/usr/bin/env seamcook run\nsrc{}\nerror('x')\n");
    SC_CHECK_INT(build_file(path, NULL, 0, NULL, &g, &err), SC_EINPUT);
    CHECK_CONTAINS(err.message, "shebang.lua:3: x");
    free(path);
    path = write_temp_graph(deep, "bom.lua", "\xEF\xBB\xBFsrc{}\nsrc{ size = -1 }\n");
    SC_CHECK_INT(build_file(path, NULL, 0, NULL, &g, &err), SC_EINPUT);
    CHECK_CONTAINS(err.message, "bom.lua:2: src:size");
    free(path);

    /* A missing file is an input error naming it. */
    path = sc_path_join(deep, "missing.lua");
    SC_CHECK_INT(build_file(path, NULL, 0, NULL, &g, &err), SC_EINPUT);
    SC_CHECK(g == NULL);
    CHECK_CONTAINS(err.message, "missing.lua");
    free(path);

    sc_test_system("rm -rf '%s'", dir);
    free(deep);
    free(dir);
}

int main(void) { return sc_test_main(); }
