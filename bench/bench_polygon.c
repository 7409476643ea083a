/* bench_polygon.c - decimate on one polygon of n vertices, fan-triangulated
 * as the OBJ reader does (every face shares vertex 0): how its cost grows
 * with n, where every look at an edge of the fan's centre could walk the
 * whole fan. meshoptimizer's meshopt_simplify on the same triangles, side by
 * side, where it is installed.
 *
 * Usage: bench_polygon [n n ...]   (default 5000 20000 50000 200000)
 *
 * The polygon is a circle (points rounded to 9 digits, as an OBJ holds
 * them), its uv the same circle scaled into the unit square; the target is
 * 10% of the faces. Per n: faces reached, decimate's seconds without and with
 * its Hausdorff metric (100,000 samples a side), seconds / (n log2 n) in
 * microseconds (flat for O(n log n)), and meshoptimizer's seconds.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#include "sc_base.h"
#include "sc_exec.h"
#include "sc_nodes.h"

#ifdef SC_HAVE_MESHOPT
#include <meshoptimizer.h>
#endif

static sc_value *polygon(int32_t n) {
    sc_mesh *m = sc_mesh_alloc(n, n, 0, n - 2, 1);
    if (!m || !(m->materials[0] = sc_strdup("default"))) {
        sc_mesh_free(m);
        return NULL;
    }
    for (int32_t i = 0; i < n; i++) {
        double a = 2 * M_PI * i / n, x = round(cos(a) * 1e9) / 1e9, y = round(sin(a) * 1e9) / 1e9;
        m->V[3 * i] = x, m->V[3 * i + 1] = y, m->V[3 * i + 2] = 0;
        m->U[2 * i] = 0.5 + 0.5 * x, m->U[2 * i + 1] = 0.5 + 0.5 * y;
    }
    for (int32_t f = 0; f < n - 2; f++) {
        int32_t c[3] = {0, f + 1, f + 2};
        for (int k = 0; k < 3; k++) m->FV[3 * f + k] = m->FU[3 * f + k] = c[k];
        m->FM[f] = 0;
    }
    return sc_value_new_mesh(m);
}

/* decimate to 10%; seconds of the run, faces reached through *faces. */
static double decimate(sc_value *mesh, const char *samples, double *faces) {
    sc_ctx *ctx = sc_ctx_new(&sc_node_decimate, NULL, NULL);
    sc_error err = {0};
    double t0 = sc_now();
    int rc = ctx ? sc_ctx_set_input(ctx, "mesh", mesh) : SC_ENOMEM;
    if (rc == SC_OK) rc = sc_ctx_set_param(ctx, "ratio", "0.1", &err);
    if (rc == SC_OK) rc = sc_ctx_set_param(ctx, "hausdorff_samples", samples, &err);
    if (rc == SC_OK) rc = sc_ctx_run(ctx, &err);
    double t = sc_now() - t0;
    if (rc != SC_OK) fprintf(stderr, "bench_polygon: %s\n", err.message);
    *faces = rc == SC_OK ? sc_ctx_metric_value(ctx, "lod0.faces") : NAN;
    sc_ctx_free(ctx);
    return rc == SC_OK ? t : NAN;
}

#ifdef SC_HAVE_MESHOPT
static double meshopt(const sc_mesh *m) {
    float *pos = malloc(sizeof(float) * 3 * (size_t)m->nv);
    unsigned *idx = malloc(sizeof(unsigned) * 3 * (size_t)m->nf), *out = malloc(sizeof(unsigned) * 3 * (size_t)m->nf);
    double t = NAN;
    if (pos && idx && out) {
        for (int32_t i = 0; i < 3 * m->nv; i++) pos[i] = (float)m->V[i];
        for (int32_t i = 0; i < 3 * m->nf; i++) idx[i] = (unsigned)m->FV[i];
        double t0 = sc_now();
        meshopt_simplify(out, idx, 3 * (size_t)m->nf, pos, (size_t)m->nv, sizeof(float) * 3,
                         3 * (size_t)(m->nf / 10), 1e30f, 0, NULL);
        t = sc_now() - t0;
    }
    free(pos), free(idx), free(out);
    return t;
}
#endif

int main(int argc, char **argv) {
    static const int32_t defaults[] = {5000, 20000, 50000, 200000};
    int count = argc > 1 ? argc - 1 : 4;
    printf("%8s %8s %8s %12s %12s %14s %12s\n", "n", "faces", "target", "decimate s", "+hausdorff s",
           "us/(n log2 n)", "meshopt s");
    for (int i = 0; i < count; i++) {
        int32_t n = argc > 1 ? (int32_t)atol(argv[i + 1]) : defaults[i];
        if (n < 3) continue;
        sc_value *mesh = polygon(n);
        if (!mesh) return 1;
        double faces = 0, with = 0;
        double t = decimate(mesh, "0", &faces);
        double th = decimate(mesh, "100000", &with);
        double meshopt_s = NAN;
#ifdef SC_HAVE_MESHOPT
        meshopt_s = meshopt(mesh->as.mesh);
#endif
        printf("%8d %8.0f %8d %12.3f %12.3f %14.3f %12.4f\n", (int)n, faces, (int)((n - 2) / 10), t, th,
               1e6 * t / (n * log2((double)n)), meshopt_s);
        sc_value_release(mesh);
    }
    return 0;
}
