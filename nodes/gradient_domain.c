/* gradient_domain.c - the node `gradient_domain`: Prada, Kazhdan, Chuang,
 * Hoppe 2018, gradient-domain processing within a texture atlas.
 *
 * A thin node over the gradient kernel (nodes/lib/sc_gradient.h): it reads
 * the parameters into sc_gradient_options (a negative gradient_scale or
 * screening takes the operation's default: smooth beta 0, sharpen beta 2,
 * screening 1e4, stitch 1e2), processes the texture of slot `texture`, and
 * outputs the result as an f32 image (`image`: geodesic gives the distance,
 * one channel), the atlas with that slot's image replaced (`atlas`), and the
 * same with the result rounded once to the input's pixel type and encoding
 * (`atlas_native`, what the main job carries on). The
 * kernel's metrics (residual after every V-cycle, seam energies before and
 * after) pass on as they come. `lic` replaces the slot's values by white
 * noise (`seed`) diffused along the largest principal curvature (§7.4).
 *
 * Seams. The paper's function space is continuous across seams, but the
 * bilinear texture it is written back to is not: the solve narrows the
 * seams (blub 2048^2: seam energy x 2e-4) without closing them. With
 * `seamless` (the default) the node ends with the seam-erasure kernel
 * (nodes/lib/sc_erase.h, every gap erased: no tolerance) on the result, so
 * both sides of every seam sample the same values; `atlas_native` is then
 * the erased result rounded by erasure's optimal rounding. The metrics
 * `seam_energy_seamless` and `seam_energy_seamless_ratio` (to the input's)
 * give the seam energy after it, beside `seam_energy_out`, the raw solve's,
 * and the erasure's own metrics under `seamless.`. seamless=false keeps the
 * paper's raw result (for a graph that erases after the node anyway).
 * Geodesic distances are left as solved.
 */
#include <stdio.h>
#include <string.h>

#include "sc_erase.h"
#include "sc_gradient.h"
#include "sc_nodes.h"
#include "sc_seam.h"

/* the atlas with texture k's image replaced (a new reference, NULL when out of memory) */
static sc_value *with_slot(const sc_value *atlas, int32_t k, sc_value *img) {
    const sc_atlas *a = atlas->as.atlas;
    sc_atlas *out = sc_atlas_new(sc_value_retain(a->mesh));
    if (out && sc_atlas_copy_materials(out, a) != SC_OK) sc_atlas_free(out), out = NULL;
    if (!out) return NULL;
    for (int32_t i = 0; i < a->ntex; i++) {
        const sc_texture *s = &a->textures[i];
        if (sc_atlas_add_texture(out, s->name, s->material, s->wrap_u, s->wrap_v, s->source,
                                 sc_value_retain(i == k ? img : s->image)) != SC_OK) {
            sc_atlas_free(out);
            return NULL;
        }
    }
    return sc_value_new_atlas(out);
}

/* The seam-erasure kernel on the solve's result (image, tagged as it comes:
 * linear light for sRGB colour): *f32 and *native (in src's pixel type and
 * encoding) get new references; the seam energy after it goes to the metrics. */

/* A solve whose V-cycles stopped at max_vcycles above the tolerance is said
 * on stderr, one line per solve (<solve>_residual in the metrics; the
 * per-cycle <solve>_vcycle_<k>_residual are passed over). */
static void warn_unconverged(sc_ctx *ctx, const sc_metric_list *ml, double tolerance) {
    for (int32_t i = 0; i < ml->count; i++) {
        const char *name = ml->items[i].name;
        size_t n = strlen(name), tail = strlen("_residual");
        if (n <= tail || strcmp(name + n - tail, "_residual") != 0 || strstr(name, "_vcycle_")) continue;
        double residual = ml->items[i].value;
        if (!(residual > tolerance)) continue;
        sc_ctx_warn(ctx, "the %.*s solve stopped at a relative residual of %.3g, above the tolerance %.3g "
                    "(max_vcycles: more V-cycles, or a direct solve)", (int)(n - tail), name, residual, tolerance);
    }
}

static int erase_result(sc_ctx *ctx, const sc_mesh *mesh, const sc_texture *t, sc_value *image,
                        const sc_image_data *src, double e_in, sc_value **f32, sc_value **native, sc_error *err) {
    sc_texture tt = *t;
    tt.image = image;
    sc_erase_options eo;
    sc_erase_defaults(&eo);
    eo.gap_tolerance = 0; /* the smallest gap is erased too: the output is seam-free to the float floor */
    const sc_image_data *like[1] = {src};
    eo.native_like = like;
    sc_erase_result er;
    int rc = sc_erase(mesh, &tt, 1, &eo, sc_ctx_threads(ctx), &er, err);
    if (rc != SC_OK) return rc;
    for (int32_t i = 0; i < er.metrics.count; i++) {
        char key[160];
        snprintf(key, sizeof key, "seamless.%s", er.metrics.items[i].name);
        sc_ctx_metric(ctx, key, er.metrics.items[i].value);
    }
    *f32 = sc_value_retain(er.f32[0]);
    *native = sc_value_retain(er.native[0]);
    sc_erase_result_free(&er);
    /* the seam energy of what the node outputs, by the function the solve reported with */
    sc_seam_set set;
    rc = sc_seam_find(mesh, t->material, &set, err);
    if (rc != SC_OK) return rc;
    const sc_image_data *im = (*f32)->as.image;
    sc_seam_grid g = {im->width, im->height, t->wrap_u, t->wrap_v};
    double e = 0, gap = 0;
    rc = sc_seam_energy(mesh, &set, &g, im, sc_ctx_threads(ctx), &e, &gap, err);
    sc_seam_set_free(&set);
    if (rc != SC_OK) return rc;
    sc_ctx_metric(ctx, "seam_energy_seamless", e);
    sc_ctx_metric(ctx, "seam_max_gap_seamless", gap);
    if (e_in > 0) sc_ctx_metric(ctx, "seam_energy_seamless_ratio", e / e_in);
    return SC_OK;
}

static int run(sc_ctx *ctx, sc_error *err) {
    const sc_value *in = sc_ctx_input(ctx, "atlas");
    if (!in || in->kind != SC_KIND_ATLAS) return sc_fail(err, SC_EINPUT, "atlas: no atlas given");
    const sc_atlas *a = in->as.atlas;
    int op = sc_gradient_op_named(sc_ctx_string(ctx, "operation"));
    if (op < 0) return sc_fail(err, SC_EINPUT, "operation: unknown");
    sc_gradient_options o;
    sc_gradient_defaults(&o, (sc_gradient_op)op);
    double beta = sc_ctx_number(ctx, "gradient_scale"), w = sc_ctx_number(ctx, "screening");
    if (beta >= 0) o.gradient_scale = beta;
    if (w >= 0) o.screening = w;
    o.time_step = sc_ctx_number(ctx, "time_step");
    o.sources = sc_ctx_string(ctx, "sources");
    o.lic_length = sc_ctx_number(ctx, "lic_length");
    o.lic_seed = (uint64_t)sc_ctx_integer(ctx, "seed");
    const char *solver = sc_ctx_string(ctx, "solver");
    o.solver = strcmp(solver, "direct") == 0    ? SC_GRADIENT_DIRECT
               : strcmp(solver, "vcycles") == 0 ? SC_GRADIENT_VCYCLES
                                                : SC_GRADIENT_MULTIGRID;
    o.levels = (int32_t)sc_ctx_integer(ctx, "levels");
    o.relaxations = (int32_t)sc_ctx_integer(ctx, "relaxations");
    o.max_vcycles = (int32_t)sc_ctx_integer(ctx, "max_vcycles");
    o.tolerance = sc_ctx_number(ctx, "tolerance");
    const sc_value *labels = sc_ctx_input(ctx, "labels");
    if (labels) o.labels = labels->as.image;
    const sc_value *field = sc_ctx_input(ctx, "field");
    if (field) o.lic_field = field->as.image;
    const char *slot = sc_ctx_string(ctx, "texture");
    int32_t k = 0;
    while (k < a->ntex && strcmp(a->textures[k].name, slot) != 0) k++;
    if (k == a->ntex) return sc_fail(err, SC_EINPUT, "texture: the atlas has no texture in slot '%s'", slot);
    const sc_texture *t = &a->textures[k];
    sc_gradient_result r;
    int rc = sc_gradient_apply(a->mesh->as.mesh, t, t->image->as.image, &o, sc_ctx_threads(ctx), &r, err);
    if (rc != SC_OK) return rc;
    for (int32_t i = 0; i < r.metrics.count; i++) sc_ctx_metric(ctx, r.metrics.items[i].name, r.metrics.items[i].value);
    warn_unconverged(ctx, &r.metrics, o.tolerance);
    const sc_image_data *src = t->image->as.image;
    bool seamless = sc_ctx_bool(ctx, "seamless") && op != SC_GRADIENT_GEODESIC;
    sc_image_data *nat = seamless || op == SC_GRADIENT_GEODESIC || src->pixel == SC_PIXEL_F32
                             ? NULL
                             : sc_image_quantize(r.image, src->pixel, src->colorspace);
    bool want_native = op != SC_GRADIENT_GEODESIC && src->pixel != SC_PIXEL_F32;
    double e_in = 0;
    for (int32_t i = 0; i < r.metrics.count; i++)
        if (!strcmp(r.metrics.items[i].name, "seam_energy_in")) e_in = r.metrics.items[i].value;
    sc_value *img = sc_value_new_image(r.image);
    r.image = NULL;
    sc_gradient_result_free(&r);
    sc_value *native = NULL;
    if (seamless && img) {
        sc_value *erased = NULL;
        rc = erase_result(ctx, a->mesh->as.mesh, t, img, src, e_in, &erased, &native, err);
        sc_value_release(img);
        if (rc != SC_OK) return rc;
        img = erased;
        if (!want_native) sc_value_release(native), native = sc_value_retain(img);
    } else {
        native = want_native ? (nat ? sc_value_new_image(nat) : NULL) : sc_value_retain(img);
    }
    sc_value *av = img ? with_slot(in, k, img) : NULL, *nv = native ? with_slot(in, k, native) : NULL;
    sc_value_release(img), sc_value_release(native);
    if (!av || !nv) {
        sc_value_release(av), sc_value_release(nv);
        return sc_fail(err, SC_ENOMEM, "out of memory");
    }
    sc_ctx_set_output(ctx, "atlas", av);
    sc_ctx_set_output(ctx, "image", sc_value_retain(av->as.atlas->textures[k].image));
    sc_ctx_set_output(ctx, "atlas_native", nv);
    return SC_OK;
}

/* ---------------------------------------------------------------- descriptor */

static const char *const operation_choices[] = {"smooth", "sharpen", "stitch", "geodesic", "lic", NULL};
static const char *const solver_choices[] = {"multigrid", "vcycles", "direct", NULL};

static const sc_param_desc params[] = {
    {.name = "operation", .type = SC_PARAM_ENUM, .def_string = "smooth", .choices = operation_choices,
     .doc = "smooth, sharpen (gradients scaled by gradient_scale), stitch (gradients kept inside each label of "
            "the labels image), geodesic (heat-method distance to sources), lic (white noise diffused along the "
            "direction of largest principal curvature: line integral convolution, §7.4)"},
    {.name = "texture", .type = SC_PARAM_STRING, .def_string = "color", .doc = "the texture slot processed"},
    {.name = "gradient_scale", .type = SC_PARAM_NUMBER, .def = -1, .min = -1, .max = 1e6,
     .doc = "beta, the factor of the gradients kept (smooth < 1 < sharpen); negative: 0 smooth, 2 sharpen"},
    {.name = "screening", .type = SC_PARAM_NUMBER, .def = -1, .min = -1, .max = 1e30,
     .doc = "w, the screening weight on a surface scaled to unit area; negative: 1e4 (smooth, sharpen), 1e2 (stitch); "
            "lic: a factor on one over a texel's area (negative: 1, streaks one texel wide)"},
    {.name = "lic_length", .type = SC_PARAM_NUMBER, .def = 16, .min = 1, .max = 1e4,
     .doc = "lic: the streaks' length in texels (epsilon of the metric = 1 / length^2)"},
    {.name = "seed", .type = SC_PARAM_INTEGER, .def = 1, .min = 0, .max = 2147483647,
     .doc = "lic: the seed of the white noise diffused"},
    {.name = "time_step", .type = SC_PARAM_NUMBER, .def = 1e-3, .min = 1e-12, .max = 1e6,
     .doc = "geodesic: the heat step t, on a surface scaled to unit area (the paper's 1e-3)"},
    {.name = "sources", .type = SC_PARAM_STRING, .def_string = "",
     .doc = "geodesic: ';'-separated sources, \"x y z\" (nearest mesh vertex) or \"texel i j\""},
    {.name = "solver", .type = SC_PARAM_ENUM, .def_string = "multigrid", .choices = solver_choices,
     .doc = "multigrid: conjugate gradients preconditioned by one V-cycle per iteration (interior texels "
            "relaxed, boundary texels solved by CHOLMOD); vcycles: V-cycles alone, as the paper; direct: one "
            "CHOLMOD factorisation"},
    {.name = "levels", .type = SC_PARAM_INTEGER, .def = 4, .min = 1, .max = 16, .doc = "multigrid levels"},
    {.name = "relaxations", .type = SC_PARAM_INTEGER, .def = 4, .min = 0, .max = 100,
     .doc = "Gauss-Seidel sweeps on each level, before and after the coarse correction"},
    {.name = "max_vcycles", .type = SC_PARAM_INTEGER, .def = 30, .min = 1, .max = 10000,
     .doc = "the most V-cycles per solve"},
    {.name = "tolerance", .type = SC_PARAM_NUMBER, .def = 1e-8, .min = 0, .max = 1,
     .doc = "V-cycles stop once the relative residual is below this"},
    {.name = "seamless", .type = SC_PARAM_BOOL, .def = 1,
     .doc = "end with seam erasure (Liu et al. 2017, every gap) so that the output is seam-free; false: the "
            "paper's raw result, whose seams the solve narrows but does not close (smooth, sharpen, stitch)"},
};

static const sc_port_desc inputs[] = {
    {.name = "atlas", .kind = SC_KIND_ATLAS, .doc = "the textured mesh"},
    {.name = "labels", .kind = SC_KIND_IMAGE, .optional = true,
     .doc = "stitch: the source of every texel as an index image (channel 0), the texture's size"},
    {.name = "field", .kind = SC_KIND_IMAGE, .optional = true,
     .doc = "lic: the vector field as an object-space direction map (xyz; signed float, else 0..1 for -1..1), the "
            "texture's size; without it, the directions of largest principal curvature"},
};

static const sc_port_desc outputs[] = {
    {.name = "atlas", .kind = SC_KIND_ATLAS, .doc = "the atlas with the processed slot's image replaced by `image`"},
    {.name = "image", .kind = SC_KIND_IMAGE,
     .doc = "the result as f32 (sRGB colour as linear light); geodesic: the distance, one channel"},
    {.name = "atlas_native", .kind = SC_KIND_ATLAS,
     .doc = "the same with the result in the input's pixel type and encoding (8/16-bit rounded once; "
            "geodesic: as atlas)"},
};

static const sc_kernel *const kernels[] = {&sc_kernel_gradient, &sc_kernel_erase, NULL};

const sc_node_desc sc_node_gradient_domain = {
    .type = "gradient_domain",
    .version = 4,
    .summary = "gradient-domain processing in the texture atlas (Prada et al. 2018): smooth, sharpen, stitch, geodesic",
    .inputs = inputs,
    .ninputs = SC_COUNT(inputs),
    .outputs = outputs,
    .noutputs = SC_COUNT(outputs),
    .params = params,
    .nparams = SC_COUNT(params),
    .run = run,
    .kernels = kernels,
};
