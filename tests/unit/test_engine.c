/* test_engine.c - what enters an action key, seen through whole cooks: the
 * kernels a node lists (and the ones they build on) re-key exactly the nodes
 * that use them, a node that asks for a parameter or port its descriptor
 * does not declare fails its run, and with one job slot the node others wait
 * on cooks before a leaf declared ahead of it. */
#include "sc_engine.h"
#include "sc_registry.h"
#include "sc_test.h"

#include <stdlib.h>
#include <string.h>

/* ---------------------------------------------------------------- kernels */

/* Versions the tests bump between cooks, as a kernel's author would. */
static sc_kernel kernel_base = {"test_base", 1, NULL};
static const sc_kernel *const built_on_base[] = {&kernel_base, NULL};
static sc_kernel kernel_top = {"test_top", 1, built_on_base};

/* ---------------------------------------------------------------- nodes */

static const sc_port_desc image_port[] = {{.name = "image", .kind = SC_KIND_IMAGE}};

static int runs_source, runs_plain, runs_base, runs_top;
static char cooked_order[16];   /* the first letter of each node type, in the order they ran */
static int ncooked;

static sc_value *one_texel(float v) {
    sc_image_data *img = sc_image_alloc(1, 1, 1, SC_PIXEL_F32);
    if (!img) return NULL;
    ((float *)img->pixels)[0] = v;
    return sc_value_new_image(img);
}

/* Output "image": one texel of value v. */
static int emit(sc_ctx *ctx, sc_error *err, float v) {
    sc_value *out = one_texel(v);
    if (!out) return sc_fail(err, SC_ENOMEM, "out of memory");
    sc_ctx_set_output(ctx, "image", out);
    return SC_OK;
}

static int pass_on(sc_ctx *ctx, sc_error *err, int *runs, char letter) {
    (*runs)++;
    if (ncooked < (int)sizeof cooked_order - 1) cooked_order[ncooked++] = letter;
    return emit(ctx, err, ((const float *)sc_ctx_image(ctx, "image")->pixels)[0]);
}

static int run_source(sc_ctx *ctx, sc_error *err) {
    runs_source++;
    return emit(ctx, err, 1.0f);
}
static int run_plain(sc_ctx *ctx, sc_error *err) { return pass_on(ctx, err, &runs_plain, 'p'); }
static int run_base(sc_ctx *ctx, sc_error *err) { return pass_on(ctx, err, &runs_base, 'b'); }
static int run_top(sc_ctx *ctx, sc_error *err) { return pass_on(ctx, err, &runs_top, 't'); }

static const sc_kernel *const uses_base[] = {&kernel_base, NULL};
static const sc_kernel *const uses_top[] = {&kernel_top, NULL};

static const sc_node_desc source = {.type = "source", .version = 1, .outputs = image_port, .noutputs = 1,
                                    .run = run_source};
static const sc_node_desc plain = {.type = "plain", .version = 1, .inputs = image_port, .ninputs = 1,
                                   .outputs = image_port, .noutputs = 1, .run = run_plain};
static const sc_node_desc with_base = {.type = "with_base", .version = 1, .inputs = image_port, .ninputs = 1,
                                       .outputs = image_port, .noutputs = 1, .run = run_base,
                                       .kernels = uses_base};
static const sc_node_desc with_top = {.type = "with_top", .version = 1, .inputs = image_port, .ninputs = 1,
                                      .outputs = image_port, .noutputs = 1, .run = run_top,
                                      .kernels = uses_top};

/* source -> plain, source -> with_base, source -> with_top */
static sc_graph *kernel_graph(void) {
    sc_graph *g = sc_graph_new("kernels.lua");
    int s = sc_graph_add(g, &source, "kernels.lua", 1);
    const sc_node_desc *const consumers[] = {&plain, &with_base, &with_top};
    for (int k = 0; k < 3; k++) {
        int c = sc_graph_add(g, consumers[k], "kernels.lua", 2 + k);
        g->nodes[c].input_node[0] = s;
        g->nodes[c].input_port[0] = 0;
    }
    return g;
}

/* Cook once; the counts of runs of each node type. */
static void cook(sc_cache *cache, int ran[4]) {
    runs_source = runs_plain = runs_base = runs_top = 0;
    sc_graph *g = kernel_graph();
    sc_engine_options opt = {.jobs = 1};
    sc_run *r = NULL;
    sc_error err = {0};
    int rc = sc_engine_run(g, cache, &opt, &r, &err);
    SC_CHECK_MSG(rc == SC_OK, "cook: %s", err.message);
    sc_run_free(r);
    sc_graph_free(g);
    ran[0] = runs_source, ran[1] = runs_plain, ran[2] = runs_base, ran[3] = runs_top;
}

#define CHECK_RAN(ran, a, b, c, d)                                                                         \
    SC_CHECK_MSG(ran[0] == (a) && ran[1] == (b) && ran[2] == (c) && ran[3] == (d),                        \
                 "ran source %d plain %d with_base %d with_top %d, expected %d %d %d %d", ran[0], ran[1], \
                 ran[2], ran[3], a, b, c, d)

/* A fresh cache in a test folder of its own, named for `what`; NULL (the
 * failure checked) when it cannot be opened. */
static sc_cache *fresh_cache(const char *what, char **dir) {
    *dir = sc_test_tempdir(what);
    sc_cache *cache = NULL;
    sc_error err = {0};
    SC_CHECK_MSG(sc_cache_open(*dir, &cache, &err) == SC_OK, "cache: %s", err.message);
    if (!cache) free(*dir), *dir = NULL;
    return cache;
}

static void fresh_cache_close(sc_cache *cache, char *dir) {
    sc_cache_close(cache);
    sc_test_system("rm -rf '%s'", dir);
    free(dir);
}

SC_TEST(bumping_a_kernel_recooks_exactly_the_nodes_that_use_it) {
    char *dir;
    sc_cache *cache = fresh_cache("kernels", &dir);
    if (!cache) return;
    int ran[4];
    kernel_base.version = 1, kernel_top.version = 1;
    cook(cache, ran);
    CHECK_RAN(ran, 1, 1, 1, 1);
    cook(cache, ran);
    CHECK_RAN(ran, 0, 0, 0, 0);
    /* the kernel under test_top: both users re-key, through test_top's `uses` too */
    kernel_base.version = 2;
    cook(cache, ran);
    CHECK_RAN(ran, 0, 0, 1, 1);
    /* test_top alone: only its user */
    kernel_top.version = 2;
    cook(cache, ran);
    CHECK_RAN(ran, 0, 0, 0, 1);
    cook(cache, ran);
    CHECK_RAN(ran, 0, 0, 0, 0);
    /* going back finds the first cooks again */
    kernel_base.version = 1, kernel_top.version = 1;
    cook(cache, ran);
    CHECK_RAN(ran, 0, 0, 0, 0);
    fresh_cache_close(cache, dir);
}

/* source -> plain (a leaf, declared first) and source -> with_base ->
 * with_top: with one job slot, once the source has cooked, with_base (which
 * with_top waits on) starts before the leaf; then the leaf and with_top, each
 * the end of its chain, in graph order. */
SC_TEST(the_node_others_wait_on_starts_before_a_leaf) {
    char *dir;
    sc_cache *cache = fresh_cache("order", &dir);
    if (!cache) return;
    sc_error err = {0};
    sc_graph *g = sc_graph_new("order.lua");
    int s = sc_graph_add(g, &source, "order.lua", 1);
    int leaf = sc_graph_add(g, &plain, "order.lua", 2);
    int mid = sc_graph_add(g, &with_base, "order.lua", 3);
    int top = sc_graph_add(g, &with_top, "order.lua", 4);
    const int from[3][2] = {{leaf, s}, {mid, s}, {top, mid}};
    for (int k = 0; k < 3; k++) {
        g->nodes[from[k][0]].input_node[0] = from[k][1];
        g->nodes[from[k][0]].input_port[0] = 0;
    }
    ncooked = 0;
    memset(cooked_order, 0, sizeof cooked_order);
    sc_engine_options opt = {.jobs = 1};
    sc_run *r = NULL;
    SC_CHECK_MSG(sc_engine_run(g, cache, &opt, &r, &err) == SC_OK, "cook: %s", err.message);
    SC_CHECK_MSG(strcmp(cooked_order, "bpt") == 0, "cooked in the order '%s', expected 'bpt'", cooked_order);
    sc_run_free(r);
    sc_graph_free(g);
    fresh_cache_close(cache, dir);
}

/* Outputs reach the cache after their consumers may have started: a node
 * whose outputs cannot be stored (here every objects/xx is a file, so no
 * blob can be published) fails the run with the store's error, counts as
 * failed, not cooked, and leaves no cache entry: with the store mended,
 * every node cooks again. */
SC_TEST(outputs_that_cannot_be_stored_fail_the_run_and_record_nothing) {
    char *dir;
    sc_cache *cache = fresh_cache("unstored", &dir);
    if (!cache) return;
    sc_error err = {0};
    kernel_base.version = 1, kernel_top.version = 1;
    SC_CHECK_INT(sc_test_system("cd '%s/objects' && for i in $(seq 0 255); do touch $(printf %%02x $i); done", dir), 0);
    for (int jobs = 1; jobs <= 2; jobs++) {
        sc_graph *g = kernel_graph();
        sc_engine_options opt = {.jobs = jobs};
        sc_run *r = NULL;
        err = (sc_error){0};
        int rc = sc_engine_run(g, cache, &opt, &r, &err);
        SC_CHECK(rc != SC_OK);
        SC_CHECK_MSG(strstr(err.message, "cannot publish") != NULL, "error: %s", err.message);
        SC_CHECK(r && r->results[0].status == SC_STATUS_FAILED);
        SC_CHECK_MSG(r && r->failed >= 1 && r->ran + r->failed + r->skipped + r->cached == g->count,
                     "ran %d failed %d skipped %d cached %d of %d", r ? r->ran : -1, r ? r->failed : -1,
                     r ? r->skipped : -1, r ? r->cached : -1, g->count);
        sc_run_free(r);
        sc_graph_free(g);
    }
    SC_CHECK_INT(sc_test_system("cd '%s/objects' && rm -f ??", dir), 0);
    int ran[4];
    cook(cache, ran);
    CHECK_RAN(ran, 1, 1, 1, 1);
    fresh_cache_close(cache, dir);
}

/* A kernel's platform text enters the keys of exactly the nodes that reach
 * it: another platform (a Mesa or BLAS release) re-cooks them, and the same
 * platform again finds their first cooks. */
static const char *platform_now = "driver 1";
static const char *test_platform(void) { return platform_now; }

SC_TEST(a_platform_text_keys_the_nodes_that_reach_it) {
    char *dir;
    sc_cache *cache = fresh_cache("kernels", &dir);
    if (!cache) return;
    int ran[4];
    kernel_base.version = 1, kernel_top.version = 1;
    kernel_base.platform = test_platform;
    platform_now = "driver 1";
    cook(cache, ran);
    CHECK_RAN(ran, 1, 1, 1, 1);
    platform_now = "driver 2";   /* test_base's: with_base, and with_top through test_top */
    cook(cache, ran);
    CHECK_RAN(ran, 0, 0, 1, 1);
    platform_now = "driver 1";
    cook(cache, ran);
    CHECK_RAN(ran, 0, 0, 0, 0);
    kernel_base.platform = NULL;
    fresh_cache_close(cache, dir);
}

/* The kernels d reaches, breadth first, repeats kept (at most 64). */
static int reach(const sc_node_desc *d, const sc_kernel *seen[64]) {
    int n = 0;
    for (int i = 0; d->kernels && d->kernels[i] && n < 64; i++) seen[n++] = d->kernels[i];
    for (int i = 0; i < n; i++)
        for (int j = 0; seen[i]->uses && seen[i]->uses[j] && n < 64; j++) seen[n++] = seen[i]->uses[j];
    return n;
}

/* Every shipped node that erases (itself or through a kernel) reaches the
 * erase kernel, and no node's kernels outnumber what the engine keeps. */
SC_TEST(every_node_that_erases_is_keyed_by_the_erase_kernel) {
    const char *const erasers[] = {"erase_seams", "straighten", "bake_displacement", "mipmap"};
    for (int k = 0; k < 4; k++) {
        const sc_node_desc *d = sc_registry_find(erasers[k]);
        SC_CHECK(d != NULL);
        if (!d) continue;
        const sc_kernel *seen[64];
        int n = reach(d, seen);
        bool found = false;
        for (int i = 0; i < n; i++) found = found || strcmp(seen[i]->name, "erase") == 0;
        SC_CHECK_MSG(found, "%s does not reach the erase kernel", erasers[k]);
    }
    int count = 0;
    const sc_node_desc *const *all = sc_registry_all(&count);
    for (int k = 0; k < count; k++) {
        const sc_kernel *seen[64];
        SC_CHECK_MSG(reach(all[k], seen) < 64, "%s reaches 64 kernels or more", all[k]->type);
    }
}

/* ---------------------------------------------------------------- declared names */

static const sc_param_desc one_param[] = {{.name = "size", .type = SC_PARAM_INTEGER, .def = 4, .min = 1, .max = 8}};

static int run_typo(sc_ctx *ctx, sc_error *err) {
    return emit(ctx, err, (float)sc_ctx_integer(ctx, "sizes"));
}

static int run_wrong_type(sc_ctx *ctx, sc_error *err) {
    return emit(ctx, err, (float)strlen(sc_ctx_string(ctx, "size")));
}

static int run_bad_port(sc_ctx *ctx, sc_error *err) {
    (void)sc_ctx_input(ctx, "imge");
    return pass_on(ctx, err, &runs_plain, 'p');
}

static int run_declared(sc_ctx *ctx, sc_error *err) { return emit(ctx, err, (float)sc_ctx_integer(ctx, "size")); }

SC_TEST(reading_an_undeclared_name_fails_the_run) {
    static const sc_node_desc typo = {.type = "typo", .version = 1, .outputs = image_port, .noutputs = 1,
                                      .params = one_param, .nparams = 1, .run = run_typo};
    static const sc_node_desc wrong_type = {.type = "wrong_type", .version = 1, .outputs = image_port,
                                            .noutputs = 1, .params = one_param, .nparams = 1,
                                            .run = run_wrong_type};
    static const sc_node_desc bad_port = {.type = "bad_port", .version = 1, .inputs = image_port, .ninputs = 1,
                                          .outputs = image_port, .noutputs = 1, .run = run_bad_port};
    static const sc_node_desc declared = {.type = "declared", .version = 1, .outputs = image_port, .noutputs = 1,
                                          .params = one_param, .nparams = 1, .run = run_declared};
    const sc_node_desc *const bad[] = {&typo, &wrong_type, &bad_port};
    const char *const named[] = {"parameter 'sizes'", "parameter (as another type) 'size'", "input 'imge'"};
    sc_value *in = one_texel(2);
    for (int k = 0; k < 3; k++) {
        sc_test_run r = sc_test_run_node(bad[k], NULL, bad[k]->ninputs ? "image" : NULL, in, NULL, NULL);
        SC_CHECK_MSG(r.rc != SC_OK, "%s ran", bad[k]->type);
        SC_CHECK_MSG(strstr(r.err.message, named[k]) != NULL, "%s: %s", bad[k]->type, r.err.message);
        SC_CHECK(sc_ctx_output(r.ctx, 0) == NULL);
        sc_ctx_free(r.ctx);
    }
    sc_test_run ok = sc_test_run_node(&declared, NULL, NULL, NULL, NULL, NULL);
    SC_CHECK_MSG(ok.rc == SC_OK, "declared: %s", ok.err.message);
    sc_ctx_free(ok.ctx);
    sc_value_release(in);
}

/* Every node that ships runs its own smoke cooks in the other tests; here each
 * descriptor's names are checked to be unique, so that a read by name cannot
 * pick the wrong one. */
SC_TEST(shipped_descriptors_declare_unique_names) {
    int count = 0;
    const sc_node_desc *const *all = sc_registry_all(&count);
    SC_CHECK(count > 0);
    for (int k = 0; k < count; k++) {
        const sc_node_desc *d = all[k];
        for (int i = 0; i < d->nparams; i++)
            for (int j = i + 1; j < d->nparams; j++)
                SC_CHECK_MSG(strcmp(d->params[i].name, d->params[j].name) != 0, "%s: parameter %s twice", d->type,
                             d->params[i].name);
    }
}

int main(void) { return sc_test_main(); }
