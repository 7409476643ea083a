/* erase_seams.c - the node `erase_seams`: Liu et al. 2017, §3-4.
 *
 * A thin wrapper over the erase kernel (nodes/lib/sc_erase.h), which holds
 * the whole method: it reads the parameters into sc_erase_options (`preset`
 * picks w_change unless w_change is given), runs sc_erase on every texture of
 * the atlas, passes its metrics on as they come, and outputs the atlas with
 * the erased textures as f32 (`atlas`; sRGB colour as linear light unless
 * filter_space is encoded) and in the input's pixel type and encoding
 * (`atlas_native`). When nothing is erased both outputs are the input atlas.
 */
#include <math.h>
#include <string.h>

#include "sc_erase.h"
#include "sc_nodes.h"

static int run(sc_ctx *ctx, sc_error *err) {
    const sc_value *in = sc_ctx_input(ctx, "atlas");
    if (!in || in->kind != SC_KIND_ATLAS) return sc_fail(err, SC_EINPUT, "atlas: no atlas given");
    const sc_atlas *a = in->as.atlas;
    sc_erase_options o;
    sc_erase_defaults(&o);
    o.w_seam = sc_ctx_number(ctx, "w_seam");
    o.w_grad_in = sc_ctx_number(ctx, "w_grad_in");
    o.w_c1 = sc_ctx_number(ctx, "w_c1");
    o.w_grad_out = sc_ctx_number(ctx, "w_grad_out");
    o.w_lerp = sc_ctx_number(ctx, "w_lerp");
    o.w_outside = sc_ctx_number(ctx, "w_outside");
    o.lerp = sc_ctx_bool(ctx, "lerp");
    o.outside = sc_ctx_bool(ctx, "outside");
    o.normal_space = sc_erase_normal_space_of(sc_ctx_string(ctx, "normal_space"), a);
    o.gap_tolerance = sc_ctx_number(ctx, "gap_tolerance");
    double wc = sc_ctx_number(ctx, "w_change");
    const char *preset = sc_ctx_string(ctx, "preset");
    o.w_change = wc >= 0                          ? wc
                 : strcmp(preset, "global") == 0 ? SC_ERASE_W_CHANGE_GLOBAL
                                                  : SC_ERASE_W_CHANGE_LOCAL;
    const char *qm = sc_ctx_string(ctx, "quantize");
    o.quantize = strcmp(qm, "none") == 0    ? SC_ERASE_QUANTIZE_NONE
                 : strcmp(qm, "naive") == 0 ? SC_ERASE_QUANTIZE_NAIVE
                                            : SC_ERASE_QUANTIZE_OPTIMAL;
    o.filter_space = sc_erase_filter_space_named(sc_ctx_string(ctx, "filter_space"));
    const char *sv = sc_ctx_string(ctx, "solver");
    o.solver = strcmp(sv, "schur") == 0     ? SC_ERASE_SOLVER_SCHUR
               : strcmp(sv, "cholmod") == 0 ? SC_ERASE_SOLVER_CHOLMOD
                                            : SC_ERASE_SOLVER_AUTO;
    o.schur_from = sc_ctx_integer(ctx, "schur_from");
    o.pcg_iterations = (int32_t)sc_ctx_integer(ctx, "pcg_iterations");
    o.textures = sc_ctx_string(ctx, "textures");

    sc_erase_result r;
    int rc = sc_erase(a->mesh->as.mesh, a->textures, a->ntex, &o, sc_ctx_threads(ctx), &r, err);
    if (rc != SC_OK) return rc;
    for (int32_t i = 0; i < r.metrics.count; i++) {
        const sc_metric *m = &r.metrics.items[i];
        sc_ctx_metric(ctx, m->name, m->value);
        char line[512];
        if (sc_erase_warning(&r.metrics, i, o.normal_space, line, sizeof line)) sc_ctx_warn(ctx, "%s", line);
    }
    sc_value *f32 = sc_erase_result_atlas(in, &r, false), *native = sc_erase_result_atlas(in, &r, true);
    sc_erase_result_free(&r);
    if (!f32 || !native) {
        sc_value_release(f32), sc_value_release(native);
        return sc_fail(err, SC_ENOMEM, "out of memory");
    }
    sc_ctx_set_output(ctx, "atlas", f32);
    sc_ctx_set_output(ctx, "atlas_native", native);
    return SC_OK;
}

/* ---------------------------------------------------------------- descriptor */

static const char *const preset_choices[] = {"local", "global", NULL};
static const char *const quantize_choices[] = {"none", "naive", "optimal", NULL};
static const char *const solver_choices[] = {"auto", "cholmod", "schur", NULL};
static const char *const filter_space_choices[] = {"linear", "encoded", NULL};
static const char *const normal_space_choices[] = {"auto", "tangent", "object", NULL};

static const sc_param_desc params[] = {
    {.name = "preset", .type = SC_PARAM_ENUM, .def_string = "local", .choices = preset_choices,
     .doc = "sets w_change: local 1e4 (keep interior texels), global 1e2 (favour gradients)"},
    {.name = "w_change", .type = SC_PARAM_NUMBER, .def = -1, .min = -1, .max = 1e30,
     .doc = "weight of E_change; negative: the preset's value"},
    {.name = "w_seam", .type = SC_PARAM_NUMBER, .def = SC_ERASE_W_SEAM, .min = 0, .max = 1e30,
     .doc = "penalty weight of the seam energy p^T M p (eq. 9)"},
    {.name = "w_grad_in", .type = SC_PARAM_NUMBER, .def = SC_ERASE_W_GRAD, .min = 0, .max = 1e30,
     .doc = "weight of E_grad_in (keep the gradients of inside texels)"},
    {.name = "w_c1", .type = SC_PARAM_NUMBER, .def = SC_ERASE_W_C1, .min = 0, .max = 1e30,
     .doc = "weight of E_C1 (matching derivatives across seams)"},
    {.name = "w_grad_out", .type = SC_PARAM_NUMBER, .def = SC_ERASE_W_GRAD, .min = 0, .max = 1e30,
     .doc = "weight of E_grad_out (smooth outside texels of silhouette cells)"},
    {.name = "lerp", .type = SC_PARAM_BOOL, .def = 0,
     .doc = "add E_lerp: silhouettes follow the linear interpolation of per-vertex values"},
    {.name = "w_lerp", .type = SC_PARAM_NUMBER, .def = SC_ERASE_W_LERP, .min = 0, .max = 1e30,
     .doc = "weight of E_lerp when lerp is on"},
    {.name = "outside", .type = SC_PARAM_BOOL, .def = 0,
     .doc = "add E_outside: trust the original texels outside the charts"},
    {.name = "w_outside", .type = SC_PARAM_NUMBER, .def = SC_ERASE_W_OUTSIDE, .min = 0, .max = 1e30,
     .doc = "weight of E_outside when outside is on"},
    {.name = "gap_tolerance", .type = SC_PARAM_NUMBER, .def = SC_ERASE_GAP_TOLERANCE, .min = 0, .max = 1,
     .doc = "a texture whose largest seam gap is at most this (or one step of its 8/16-bit "
            "encoding) is already seam-free and passes through unchanged; 0: always erase"},
    {.name = "textures", .type = SC_PARAM_STRING, .def_string = "all",
     .doc = "texture slots to erase, comma-separated (color, normal, ...), or all"},
    {.name = "normal_space", .type = SC_PARAM_ENUM, .def_string = "auto", .choices = normal_space_choices,
     .doc = SC_ERASE_NORMAL_SPACE_DOC},
    {.name = "filter_space", .type = SC_PARAM_ENUM, .def_string = "linear", .choices = filter_space_choices,
     .doc = SC_ERASE_FILTER_SPACE_DOC},
    {.name = "quantize", .type = SC_PARAM_ENUM, .def_string = "optimal", .choices = quantize_choices,
     .doc = "8/16-bit inputs in atlas_native: none (keep f32), naive (round), optimal (8-bit "
            "rounding that minimises the quantised seam energy)"},
    {.name = "solver", .type = SC_PARAM_ENUM, .def_string = "auto", .choices = solver_choices,
     .doc = "cholmod: one direct factorisation of the whole system; schur: the texels along each "
            "seam chain eliminated on their own and the rest factored by CHOLMOD, the couplings between "
            "charts this leaves out taken back in by conjugate gradients on the rest (to 1e-12); "
            "auto: schur from schur_from "
            "unknowns unless most texels lie in the cells of two or more seam chains, falling back to cholmod "
            "should it fail"},
    {.name = "schur_from", .type = SC_PARAM_INTEGER, .def = SC_ERASE_SCHUR_FROM, .min = 0, .max = 2147483647,
     .doc = "solver auto takes the edge-cluster solver (schur) for a system of this many unknowns or more"},
    {.name = "pcg_iterations", .type = SC_PARAM_INTEGER, .def = SC_ERASE_PCG_ITERATIONS, .min = 1, .max = 1000000,
     .doc = "the most conjugate-gradient iterations of the schur solver (in each of its two rounds); "
            "when they do not reach 1e-12, "
            "solver auto factors the whole system with cholmod instead, solver schur fails"},
};

static const sc_port_desc inputs[] = {
    {.name = "atlas", .kind = SC_KIND_ATLAS, .doc = "the textured mesh"},
};

static const sc_port_desc outputs[] = {
    {.name = "atlas", .kind = SC_KIND_ATLAS,
     .doc = "the same mesh with every selected texture erased, as f32 images"},
    {.name = "atlas_native", .kind = SC_KIND_ATLAS,
     .doc = "the erased textures in the input's pixel type (8/16-bit quantised once)"},
};

static const sc_kernel *const kernels[] = {&sc_kernel_erase, NULL};

const sc_node_desc sc_node_erase_seams = {
    .type = "erase_seams",
    .version = 9,
    .summary = "erase texture seams (Liu et al. 2017): project textures onto the seam operator's null space",
    .inputs = inputs,
    .ninputs = SC_COUNT(inputs),
    .outputs = outputs,
    .noutputs = SC_COUNT(outputs),
    .params = params,
    .nparams = SC_COUNT(params),
    .run = run,
    .kernels = kernels,
};
