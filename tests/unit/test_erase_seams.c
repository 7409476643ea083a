/* test_erase_seams.c - the seam operator (sc_seam), the sparse layer
 * (sc_sparse) and the node `erase_seams`.
 *
 * Everything is checked against code that shares nothing with the
 * implementation (here and in sc_ref_seam.c): a plain bilinear sampler (texel centres at
 * ((i + 1/2)/W, (j + 1/2)/H), row 0 at v = 0, GL wrap rules), its own seam
 * finder, and quadrature: dense composite Gauss-Legendre over uniform
 * sub-intervals for the analytic checks, Gauss-Legendre over the pieces
 * between texel-grid crossings (which makes it exact) plus dense point
 * sampling for the corpus checks.
 */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "sc_atlas_ops.h"
#include "sc_exec.h"
#include "sc_imageio.h"
#include "sc_nodes.h"
#include "sc_ref_seam.h"
#include "sc_schur.h"
#include "sc_seam.h"
#include "sc_sparse.h"
#include "sc_tangent.h"
#include "sc_test.h"

/* ================================================================ reference quadrature */

/* Composite 3-point Gauss-Legendre of f over [0, 1]: `per` uniform
 * sub-intervals inside each piece between texel-grid crossings (the
 * integrands of §3-4 are smooth polynomials there, and only there). */
typedef double (*integrand)(void *ud, double g);
static double dense_quad(const sc_image_data *im, const ref_seam *s, int per, integrand f, void *ud) {
    double *t;
    int n = ref_breaks(im, s, &t);
    double sum = 0;
    for (int i = 0; i + 1 < n; i++) {
        double a = t[i], b = t[i + 1];
        if (!(b > a)) continue;
        for (int j = 0; j < per; j++) {
            double lo = a + (b - a) * j / per, hi = a + (b - a) * (j + 1) / per;
            for (int k = 0; k < 3; k++) sum += REF_GLW[k] * (hi - lo) * f(ud, lo + REF_GLX[k] * (hi - lo));
        }
    }
    free(t);
    return sum;
}

typedef struct gap_ud {
    const sc_image_data *im;
    sc_wrap wrap;
    const ref_seam *s;
} gap_ud;
static double gap_f(void *ud, double g) {
    gap_ud *u = ud;
    return ref_gap2(u->im, u->wrap, u->wrap, u->s, g, NULL);
}

/* ================================================================ synthetic data */

static uint64_t rng_state = 12345;
static double rnd(void) {
    rng_state = rng_state * 6364136223846793005ull + 1442695040888963407ull;
    return (double)(rng_state >> 11) / 9007199254740992.0;
}

static sc_image_data *noise_image(int w, int h, int c, sc_pixel px, double constant) {
    sc_image_data *im = sc_image_alloc(w, h, c, px);
    size_t n = (size_t)w * h * c;
    for (size_t k = 0; k < n; k++) {
        double v = constant >= 0 ? constant : 0.1 + 0.8 * rnd();
        if (px == SC_PIXEL_U8) ((uint8_t *)im->pixels)[k] = (uint8_t)lrint(v * 255);
        else ((float *)im->pixels)[k] = (float)v;
    }
    strcpy(im->format, px == SC_PIXEL_U8 ? "png" : "exr");
    im->colorspace = px == SC_PIXEL_U8 ? SC_COLOR_SRGB : SC_COLOR_LINEAR;
    return im;
}

/* Two triangles sharing the surface edge v0-v1, with separate uvs there:
 * face A (v0, v1, v2) uses a0 a1 a2, face B (v1, v0, v3) uses b1 b0 b3. */
static sc_mesh *pair_mesh(const double a0[2], const double a1[2], const double a2[2],
                          const double b0[2], const double b1[2], const double b3[2]) {
    sc_mesh *m = sc_mesh_alloc(4, 6, 0, 2, 1);
    const double V[12] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, -1, 0.5};
    memcpy(m->V, V, sizeof V);
    const double *U[6] = {a0, a1, a2, b0, b1, b3};
    for (int k = 0; k < 6; k++) m->U[2 * k] = U[k][0], m->U[2 * k + 1] = U[k][1];
    const int32_t FV[6] = {0, 1, 2, 1, 0, 3}, FU[6] = {0, 1, 2, 4, 3, 5};
    memcpy(m->FV, FV, sizeof FV);
    memcpy(m->FU, FU, sizeof FU);
    m->materials[0] = sc_strdup("m");
    return m;
}

static void uv_of(double x, double y, int W, int H, double out[2]) {
    out[0] = (x + 0.5) / W;
    out[1] = (y + 0.5) / H;
}

/* A cube with one square chart per face, each chart rotated by `angle`
 * degrees about its centre, in a 3 x 2 layout with margins. */
static sc_mesh *cube_mesh(double angle, bool open_top) {
    static const int quads[6][4] = {{0, 4, 6, 2}, {1, 3, 7, 5}, {0, 1, 5, 4},
                                    {2, 6, 7, 3}, {0, 2, 3, 1}, {4, 5, 7, 6}};
    int nq = open_top ? 5 : 6;
    sc_mesh *m = sc_mesh_alloc(8, 4 * nq, 0, 2 * nq, 1);
    for (int i = 0; i < 8; i++) {
        m->V[3 * i] = i & 1;
        m->V[3 * i + 1] = (i >> 1) & 1;
        m->V[3 * i + 2] = (i >> 2) & 1;
    }
    double rad = angle * M_PI / 180, cs = cos(rad), sn = sin(rad);
    for (int q = 0; q < nq; q++) {
        double cx = (q % 3 + 0.5) / 3, cy = (q / 3 + 0.5) / 2, half = 0.11 + 0.01 * q;
        static const double corner[4][2] = {{-1, -1}, {1, -1}, {1, 1}, {-1, 1}};
        for (int k = 0; k < 4; k++) {
            double x = corner[k][0] * half, y = corner[k][1] * half;
            m->U[2 * (4 * q + k)] = cx + cs * x - sn * y;
            m->U[2 * (4 * q + k) + 1] = cy + sn * x + cs * y;
        }
        const int tri[2][3] = {{0, 1, 2}, {0, 2, 3}};
        for (int t = 0; t < 2; t++)
            for (int k = 0; k < 3; k++) {
                m->FV[3 * (2 * q + t) + k] = quads[q][tri[t][k]];
                m->FU[3 * (2 * q + t) + k] = 4 * q + tri[t][k];
            }
    }
    m->materials[0] = sc_strdup("cube");
    return m;
}

/* A flat n x n grid of quads with one chart: no seams at all. */
static sc_mesh *grid_mesh(int n) {
    int nv = (n + 1) * (n + 1);
    sc_mesh *m = sc_mesh_alloc(nv, nv, 0, 2 * n * n, 1);
    for (int j = 0; j <= n; j++)
        for (int i = 0; i <= n; i++) {
            int v = j * (n + 1) + i;
            m->V[3 * v] = i, m->V[3 * v + 1] = j, m->V[3 * v + 2] = 0;
            m->U[2 * v] = 0.1 + 0.8 * i / n, m->U[2 * v + 1] = 0.1 + 0.8 * j / n;
        }
    int f = 0;
    for (int j = 0; j < n; j++)
        for (int i = 0; i < n; i++) {
            int a = j * (n + 1) + i, b = a + 1, c = a + n + 2, d = a + n + 1;
            int t[2][3] = {{a, b, c}, {a, c, d}};
            for (int q = 0; q < 2; q++, f++)
                for (int k = 0; k < 3; k++) m->FV[3 * f + k] = m->FU[3 * f + k] = t[q][k];
        }
    m->materials[0] = sc_strdup("grid");
    return m;
}

/* A pillow: two n x n sheets, bulging apart, sewn along their common
 * border, each its own chart (side by side in uv, the second mirrored). The
 * seam is the border: one closed loop whose every vertex joins two seam
 * edges in the same two charts. */
static sc_mesh *pillow_mesh(int n) {
    int per = (n + 1) * (n + 1), inner = (n - 1) * (n - 1);
    sc_mesh *m = sc_mesh_alloc(per + inner, 2 * per, 0, 4 * n * n, 1);
    int32_t *bottom = malloc(sizeof *bottom * (size_t)per);   /* the second sheet's vertex at each grid point */
    for (int j = 0; j <= n; j++)
        for (int i = 0; i <= n; i++) {
            int v = j * (n + 1) + i, b = v;
            bool border = i == 0 || j == 0 || i == n || j == n;
            double bulge = border ? 0 : 0.3 * sin(M_PI * i / n) * sin(M_PI * j / n);
            m->V[3 * v] = i, m->V[3 * v + 1] = j, m->V[3 * v + 2] = bulge * n;
            if (!border) {
                b = per + (j - 1) * (n - 1) + (i - 1);
                m->V[3 * b] = i, m->V[3 * b + 1] = j, m->V[3 * b + 2] = -bulge * n;
            }
            bottom[v] = b;
            m->U[2 * v] = 0.05 + 0.4 * i / n, m->U[2 * v + 1] = 0.05 + 0.4 * j / n;
            m->U[2 * (per + v)] = 0.95 - 0.4 * i / n, m->U[2 * (per + v) + 1] = 0.05 + 0.4 * j / n;
        }
    int f = 0;
    for (int sheet = 0; sheet < 2; sheet++)
        for (int j = 0; j < n; j++)
            for (int i = 0; i < n; i++) {
                int a = j * (n + 1) + i, b = a + 1, c = a + n + 2, d = a + n + 1;
                int t[2][3] = {{a, b, c}, {a, c, d}};
                for (int q = 0; q < 2; q++, f++)
                    for (int k = 0; k < 3; k++) {
                        int g = t[q][sheet ? 2 - k : k];   /* the second sheet faces the other way */
                        m->FV[3 * f + k] = sheet ? bottom[g] : g;
                        m->FU[3 * f + k] = sheet * per + g;
                    }
            }
    free(bottom);
    m->materials[0] = sc_strdup("pillow");
    return m;
}

static sc_value *atlas_of(sc_mesh *m, sc_value **images, const char **slots, int n, sc_wrap wrap) {
    sc_atlas *a = sc_atlas_new(sc_value_new_mesh(m));
    for (int i = 0; i < n; i++) sc_atlas_add_texture(a, slots[i], 0, wrap, wrap, "", images[i]);
    return sc_value_new_atlas(a);
}

static sc_value *one_texture_atlas(sc_mesh *m, sc_image_data *im, sc_wrap wrap) {
    sc_value *img = sc_value_new_image(im);
    const char *slot = "color";
    return atlas_of(m, &img, &slot, 1, wrap);
}

/* run erase_seams; returns the context (caller frees) or NULL on failure */
static const sc_bytes *report_file_bytes(const sc_report *r, const char *path) {
    for (int32_t f = 0; f < r->nfiles; f++)
        if (strcmp(r->files[f].path, path) == 0) return r->files[f].bytes->as.bytes;
    return NULL;
}

static sc_ctx *run_erase(sc_value *atlas, const char *const *kv, int threads, sc_error *err) {
    sc_ctx *ctx = sc_ctx_new(&sc_node_erase_seams, NULL, &atlas);
    for (int i = 0; kv && kv[i]; i += 2)
        if (sc_ctx_set_param(ctx, kv[i], kv[i + 1], err) != SC_OK) {
            sc_ctx_free(ctx);
            return NULL;
        }
    sc_ctx_set_threads(ctx, threads);
    if (sc_ctx_run(ctx, err) != SC_OK) {
        sc_ctx_free(ctx);
        return NULL;
    }
    return ctx;
}

static const sc_image_data *out_image(sc_ctx *ctx, int port, int tex) {
    sc_value *a = sc_ctx_output(ctx, port);
    return a ? a->as.atlas->textures[tex].image->as.image : NULL;
}

/* ================================================================ sparse layer */

SC_TEST(sparse_assembly_and_solve) {
    /* a 1D Laplacian plus identity, built from shuffled, duplicated triplets */
    int n = 50;
    sc_triplets t;
    sc_triplets_init(&t, n);
    for (int i = n - 1; i >= 0; i--) {
        sc_triplets_add(&t, i, i, 1.0);
        sc_triplets_add(&t, i, i, 1.0);
        if (i + 1 < n) {
            sc_triplets_add(&t, i + 1, i, -1.0); /* below the diagonal: mirrored */
            sc_triplets_add(&t, i, i, 1.0);
            sc_triplets_add(&t, i + 1, i + 1, 1.0);
        }
    }
    sc_sparse a;
    sc_error err = {0};
    SC_CHECK_INT(sc_sparse_from_triplets(&t, &a, &err), SC_OK);
    SC_CHECK_INT(a.nnz, 2 * n - 1);
    double x[50], y[50], b[100];
    for (int i = 0; i < n; i++) x[i] = sin(i * 0.3);
    sc_sparse_symv(&a, x, y);
    double xy = 0;
    for (int i = 0; i < n; i++) xy += x[i] * y[i];
    SC_CHECK_NEAR(sc_sparse_quadform(&a, x), xy, 1e-12);
    for (int i = 0; i < n; i++) b[i] = y[i], b[n + i] = 2 * y[i];
    sc_sparse_chol *f = NULL;
    SC_CHECK_INT(sc_sparse_chol_factor(&a, NULL, &f, &err), SC_OK);
    SC_CHECK_INT(sc_sparse_chol_solve(f, 2, b, &err), SC_OK);
    double e = 0;
    for (int i = 0; i < n; i++) e = fmax(e, fmax(fabs(b[i] - x[i]), fabs(b[n + i] - 2 * x[i])));
    SC_CHECK(e < 1e-12);
    sc_sparse_chol_free(f);
    /* sum and principal submatrix */
    sc_sparse s2, sub;
    SC_CHECK_INT(sc_sparse_add(&a, 2.0, &a, -1.0, &s2, &err), SC_OK);
    SC_CHECK_NEAR(sc_sparse_quadform(&s2, x), xy, 1e-12);
    int32_t keep[50];
    for (int i = 0; i < n; i++) keep[i] = i % 2 ? -1 : i / 2;
    SC_CHECK_INT(sc_sparse_submatrix(&a, keep, 25, &sub, &err), SC_OK);
    SC_CHECK_INT(sub.nnz, 25);
    SC_CHECK_NEAR(sc_sparse_diag(&sub, 3), sc_sparse_diag(&a, 6), 0);
    sc_sparse_free(&s2);
    sc_sparse_free(&sub);
    /* inertia: eigenvalues of 1 + L lie in [1, 5]: none below 0.5, all below 6 */
    int64_t cnt = -1;
    SC_CHECK_INT(sc_sparse_count_eigs_below(&a, 0.5, &cnt, &err), SC_OK);
    SC_CHECK_INT(cnt, 0);
    SC_CHECK_INT(sc_sparse_count_eigs_below(&a, 6.0, &cnt, &err), SC_OK);
    SC_CHECK_INT(cnt, n);
    sc_sparse_free(&a);
    sc_triplets_free(&t);
}

/* sc_sparse_chol_solve_threads on a 2D grid Laplacian plus 0.01 I (its
 * elimination tree splits well): x back to 1e-10 from b = A x formed here
 * from the stencil, the same bits on one thread and two, close to
 * cholmod_solve's; a supernodal factor takes cholmod_solve's path. */
SC_TEST(sparse_tree_split_solve) {
    const int side = 40, n = side * side;
    sc_triplets t;
    sc_triplets_init(&t, n);
    double *x = malloc(sizeof(double) * n), *b = malloc(sizeof(double) * 2 * n);
    double *b1 = malloc(sizeof(double) * 2 * n), *b2 = malloc(sizeof(double) * 2 * n);
    for (int i = 0; i < n; i++) x[i] = cos(0.37 * i) + 0.1 * (i % 7);
    for (int r = 0; r < side; r++)
        for (int c = 0; c < side; c++) {
            int i = r * side + c;
            double bi = 0.01 * x[i];
            sc_triplets_add(&t, i, i, 0.01);
            int nb[2] = {c + 1 < side ? i + 1 : -1, r + 1 < side ? i + side : -1};
            for (int k = 0; k < 2; k++) {
                if (nb[k] < 0) continue;
                sc_triplets_add(&t, i, i, 1.0), sc_triplets_add(&t, nb[k], nb[k], 1.0);
                sc_triplets_add(&t, i, nb[k], -1.0);
            }
            int nbr[4] = {c > 0 ? i - 1 : -1, c + 1 < side ? i + 1 : -1, r > 0 ? i - side : -1,
                          r + 1 < side ? i + side : -1};
            for (int k = 0; k < 4; k++)
                if (nbr[k] >= 0) bi += x[i] - x[nbr[k]];
            b[i] = bi, b[n + i] = -2 * bi;
        }
    sc_sparse a;
    sc_error err = {0};
    SC_CHECK_INT(sc_sparse_from_triplets(&t, &a, &err), SC_OK);
    sc_sparse_options opt = {.ordering = SC_SPARSE_ORDER_AMD, .kind = SC_SPARSE_SIMPLICIAL, .definite = true};
    sc_sparse_chol *f = NULL;
    SC_CHECK_INT(sc_sparse_chol_factor(&a, &opt, &f, &err), SC_OK);
    if (f) {
        memcpy(b1, b, sizeof(double) * 2 * n), memcpy(b2, b, sizeof(double) * 2 * n);
        SC_CHECK_INT(sc_sparse_chol_solve_threads(f, 2, b1, 1, &err), SC_OK);
        SC_CHECK_INT(sc_sparse_chol_solve_threads(f, 2, b2, 2, &err), SC_OK);
        SC_CHECK(memcmp(b1, b2, sizeof(double) * 2 * n) == 0);
        sc_sparse_stats st;
        sc_sparse_chol_stats(f, &st);
        SC_CHECK_MSG(st.split_share > 0.6, "split share %g", st.split_share);
        double e = 0, d = 0;
        for (int i = 0; i < n; i++) e = fmax(e, fmax(fabs(b2[i] - x[i]), fabs(b2[n + i] + 2 * x[i])));
        SC_CHECK_MSG(e < 1e-10, "error %g", e);
        memcpy(b1, b, sizeof(double) * 2 * n);
        SC_CHECK_INT(sc_sparse_chol_solve(f, 2, b1, &err), SC_OK);
        for (int i = 0; i < 2 * n; i++) d = fmax(d, fabs(b1[i] - b2[i]));
        SC_CHECK_MSG(d < 1e-12, "against cholmod_solve %g", d);
        sc_sparse_chol_free(f);
    }
    opt.kind = SC_SPARSE_SUPERNODAL;
    SC_CHECK_INT(sc_sparse_chol_factor(&a, &opt, &f, &err), SC_OK);
    if (f) {
        memcpy(b2, b, sizeof(double) * 2 * n);
        SC_CHECK_INT(sc_sparse_chol_solve_threads(f, 2, b2, 2, &err), SC_OK);
        double e = 0;
        for (int i = 0; i < n; i++) e = fmax(e, fmax(fabs(b2[i] - x[i]), fabs(b2[n + i] + 2 * x[i])));
        SC_CHECK_MSG(e < 1e-10, "supernodal: error %g", e);
        sc_sparse_stats st;
        sc_sparse_chol_stats(f, &st);
        SC_CHECK(st.split_share == 0);
        sc_sparse_chol_free(f);
    }
    sc_sparse_free(&a);
    sc_triplets_free(&t);
    free(x), free(b), free(b1), free(b2);
}

/* sc_schur against CHOLMOD on one matrix: chains of unknowns (clusters, as
 * the texels along an edge) that couple along themselves, a few unknowns
 * of no cluster joining chains, and weak couplings between chains (and one
 * to a joining unknown) that the factorisation leaves out and the
 * iterations on the interface take in (their unknowns made interface). */
SC_TEST(schur_clusters_match_direct_solve) {
    enum { CHAINS = 40, LEN = 30, JOINS = 20 };
    const int n = CHAINS * LEN + JOINS;
    int32_t group[CHAINS * LEN + JOINS];
    double key[CHAINS * LEN + JOINS];
    sc_triplets ta, tq, terms;
    sc_triplets_init(&ta, n);
    sc_triplets_init(&tq, n);
    sc_triplets_init(&terms, n);
    rng_state = 777;
    for (int c = 0; c < CHAINS; c++)
        for (int k = 0; k < LEN; k++) {
            int i = c * LEN + k;
            group[i] = (c * 7) % CHAINS;   /* group ids in any order */
            key[i] = (double)((k * 11) % LEN);   /* the chain's order is by key, not index */
            double d = 0.1 + rnd();
            sc_triplets_add(&ta, i, i, d);
            /* couple each unknown to the next two by key */
            for (int step = 1; step <= 2; step++)
                for (int k2 = 0; k2 < LEN; k2++)
                    if ((k2 * 11) % LEN == (int)key[i] + step) {
                        double w = 0.5 + rnd();
                        int j = c * LEN + k2;
                        sc_triplets_add(&ta, i, i, w), sc_triplets_add(&ta, j, j, w), sc_triplets_add(&ta, i, j, -w);
                    }
        }
    for (int q = 0; q < JOINS; q++) {   /* interface unknowns tying chain ends together */
        int i = CHAINS * LEN + q;
        group[i] = -1, key[i] = 0;
        sc_triplets_add(&ta, i, i, 1.0);
        for (int e = 0; e < 4; e++) {
            int j = ((q * 4 + e) % CHAINS) * LEN + (e * 7) % LEN;
            double w = 1e3 * (0.5 + rnd());   /* stiff, as the seam penalty */
            sc_triplets_add(&ta, i, i, w), sc_triplets_add(&ta, j, j, w), sc_triplets_add(&ta, i, j, -w);
        }
    }
    sc_triplets_append(&tq, &ta);
    for (int c = 0; c <= CHAINS; c++) {   /* weak couplings between neighbouring chains: Q only */
        int i = c * LEN + 3, j = (c + 1) * LEN + 17;
        if (c == CHAINS) i = 5, j = CHAINS * LEN + 1;   /* and one to a joining unknown */
        else if (c + 1 == CHAINS) continue;
        double w = 0.5 + rnd();
        sc_triplets_add(&tq, i, i, w), sc_triplets_add(&tq, j, j, w), sc_triplets_add(&tq, i, j, -w);
        sc_triplets_add(&terms, i, j, w);
        group[i] = group[j] = -1;
    }
    sc_sparse a, q, af;
    sc_error err = {0};
    SC_CHECK_INT(sc_sparse_from_triplets(&ta, &a, &err), SC_OK);
    SC_CHECK_INT(sc_sparse_from_triplets(&tq, &q, &err), SC_OK);
    SC_CHECK_INT(sc_sparse_full(&a, &af, &err), SC_OK);
    SC_CHECK_INT(af.nnz, 2 * a.nnz - n);
    double *x = malloc(sizeof(double) * 3 * n), *b = malloc(sizeof(double) * 3 * n);
    double *y = malloc(sizeof(double) * 3 * n);
    for (int i = 0; i < 2 * n; i++) x[i] = sin(0.37 * i) + (i % 5 == 0 ? 3.0 : 0.0);
    double e = 0;
    /* the factorisation solves A directly: two columns at once */
    sc_schur *f = NULL;
    SC_CHECK_INT(sc_schur_factor(&af, group, key, INFINITY, 2, &f, &err), SC_OK);
    if (f) {
        sc_schur_stats st;
        sc_schur_get_stats(f, &st);
        SC_CHECK_MSG(st.private_unknowns > CHAINS * LEN / 2 && st.interface_unknowns >= JOINS,
                     "private %d interface %d", (int)st.private_unknowns, (int)st.interface_unknowns);
        sc_sparse_symv(&a, x, b), sc_sparse_symv(&a, x + n, b + n);
        SC_CHECK_INT(sc_schur_solve(f, 2, b, &err), SC_OK);
        e = 0;
        for (int i = 0; i < 2 * n; i++) e = fmax(e, fabs(b[i] - x[i]));
        SC_CHECK_MSG(e < 1e-9, "schur solve off by %g", e);
        /* Q = A + the terms, against CHOLMOD on Q; the third column zero */
        sc_sparse_symv(&q, x, b), sc_sparse_symv(&q, x + n, b + n);
        for (int i = 0; i < n; i++) b[2 * n + i] = 0;
        memcpy(y, b, sizeof(double) * 3 * n);
        sc_schur_pcg_result res;
        SC_CHECK_INT(sc_schur_solve_terms(f, NULL, &terms, 3, b, 1e-13, 200, &res, &err), SC_OK);
        sc_sparse_chol *direct = NULL;
        SC_CHECK_INT(sc_sparse_chol_factor(&q, NULL, &direct, &err), SC_OK);
        SC_CHECK_INT(sc_sparse_chol_solve(direct, 3, y, &err), SC_OK);
        e = 0;
        for (int i = 0; i < 2 * n; i++) e = fmax(e, fabs(b[i] - y[i]));
        bool zero = true;
        for (int i = 0; i < n; i++) zero &= b[2 * n + i] == 0;
        printf("     schur: %d private, %d interface; %d iterations, off CHOLMOD by %.3g\n",
               (int)st.private_unknowns, (int)st.interface_unknowns, (int)res.iterations, e);
        SC_CHECK_MSG(res.iterations >= 2 && e < 1e-8, "terms: %d iterations, off by %g", (int)res.iterations, e);
        SC_CHECK(zero);
        /* refined on Q itself (full pattern): as close, and Q's residual
         * in A^-1's norm within the tolerance */
        sc_sparse qf;
        SC_CHECK_INT(sc_sparse_full(&q, &qf, &err), SC_OK);
        sc_sparse_symv(&q, x, b), sc_sparse_symv(&q, x + n, b + n);
        double *b0 = malloc(sizeof(double) * 2 * n);
        memcpy(b0, b, sizeof(double) * 2 * n);
        SC_CHECK_INT(sc_schur_solve_terms(f, &qf, &terms, 2, b, 1e-13, 200, &res, &err), SC_OK);
        double er = 0;
        for (int i = 0; i < 2 * n; i++) er = fmax(er, fabs(b[i] - y[i]));
        double *rr = malloc(sizeof(double) * n), *zz = malloc(sizeof(double) * n), *bb = malloc(sizeof(double) * n);
        sc_sparse_symv(&q, b, rr);
        for (int i = 0; i < n; i++) rr[i] = b0[i] - rr[i], zz[i] = rr[i], bb[i] = b0[i];
        SC_CHECK_INT(sc_schur_solve(f, 1, zz, &err), SC_OK);
        SC_CHECK_INT(sc_schur_solve(f, 1, bb, &err), SC_OK);
        double rz = 0, bz = 0;
        for (int i = 0; i < n; i++) rz += rr[i] * zz[i], bz += b0[i] * bb[i];
        printf("     refined on Q: %d iterations, off CHOLMOD by %.3g, residual ratio %.3g\n", (int)res.iterations,
               er, sqrt(fabs(rz) / bz));
        SC_CHECK_MSG(er < 1e-8 && sqrt(fabs(rz) / bz) < 1e-11, "refined: off by %g, residual ratio %g", er,
                     sqrt(fabs(rz) / bz));
        free(b0), free(rr), free(zz), free(bb);
        sc_sparse_free(&qf);
        /* a term on a private unknown: an error */
        sc_triplets bad;
        sc_triplets_init(&bad, n);
        sc_triplets_add(&bad, 0, 1, 1.0);
        SC_CHECK(sc_schur_solve_terms(f, NULL, &bad, 1, b, 1e-13, 200, &res, &err) == SC_EINPUT);
        sc_triplets_free(&bad);
        sc_sparse_chol_free(direct);
        /* not positive definite: an error, not a crash */
        sc_schur_free(f);
        f = NULL;
        for (int64_t k = 0; k < af.nnz; k++) af.val[k] = -af.val[k];
        SC_CHECK(sc_schur_factor(&af, group, key, INFINITY, 2, &f, &err) != SC_OK);
        sc_schur_free(f);
    }
    free(x), free(b), free(y);
    sc_sparse_free(&a), sc_sparse_free(&q), sc_sparse_free(&af);
    sc_triplets_free(&ta), sc_triplets_free(&tq), sc_triplets_free(&terms);
}

static bool same_sparse(const sc_sparse *a, const sc_sparse *b) {
    return a->n == b->n && a->nnz == b->nnz &&
           memcmp(a->colptr, b->colptr, ((size_t)a->n + 1) * sizeof *a->colptr) == 0 &&
           memcmp(a->rowind, b->rowind, (size_t)a->nnz * sizeof *a->rowind) == 0 &&
           memcmp(a->val, b->val, (size_t)a->nnz * sizeof *a->val) == 0;
}

SC_TEST(sparse_assembly_threads_same_bits) {
    /* many duplicates of irrational values in a scrambled order: the sums
     * depend on their order, which must not depend on the thread count */
    int32_t n = 40000;   /* enough entries for several parts */
    sc_triplets t;
    sc_triplets_init(&t, n);
    uint64_t x = 12345;
    for (int k = 0; k < 400000; k++) {
        x = x * 6364136223846793005ull + 1442695040888963407ull;
        int32_t i = (int32_t)((x >> 33) % (uint64_t)n), j = (int32_t)((x >> 13) % 7);
        j = i + j < n ? i + j : i;
        sc_triplets_add(&t, (k & 1) ? j : i, (k & 1) ? i : j, sin(k * 0.37) + 1e-9 * k);
    }
    sc_error err = {0};
    sc_sparse one, full1;
    SC_CHECK_INT(sc_sparse_from_triplets(&t, &one, &err), SC_OK);
    SC_CHECK_INT(sc_sparse_full(&one, &full1, &err), SC_OK);
    for (int threads = 2; threads <= 5; threads++) {
        sc_sparse more, fullm;
        SC_CHECK_INT(sc_sparse_from_triplets_threads(&t, threads, &more, &err), SC_OK);
        SC_CHECK(same_sparse(&one, &more));
        SC_CHECK_INT(sc_sparse_full_threads(&more, threads, &fullm, &err), SC_OK);
        SC_CHECK(same_sparse(&full1, &fullm));
        sc_sparse_free(&more), sc_sparse_free(&fullm);
    }
    /* the same triplets cut into lists of uneven lengths (one empty): the
     * same upper triangle, and straight into the full pattern the same
     * matrix as its mirror copy */
    for (int threads = 1; threads <= 4; threads++) {
        sc_triplet_parts parts;
        sc_triplet_parts_init(&parts, n);
        const size_t cuts[] = {0, 1000, 1000, 150001, 399999, t.count};
        for (int c = 0; c + 1 < 6; c++) {
            sc_triplets piece;
            sc_triplets_init(&piece, n);
            for (size_t k = cuts[c]; k < cuts[c + 1]; k++) sc_triplets_add(&piece, t.row[k], t.col[k], t.val[k]);
            sc_triplet_parts_take(&parts, &piece);
            sc_triplets_free(&piece);
        }
        sc_sparse up, full;
        SC_CHECK_INT(sc_sparse_from_triplet_parts(&parts, threads, &up, &err), SC_OK);
        SC_CHECK(same_sparse(&one, &up));
        SC_CHECK_INT(sc_sparse_full_from_triplet_parts(&parts, NULL, NULL, threads, &full, &err), SC_OK);
        SC_CHECK(same_sparse(&full1, &full));
        sc_sparse_free(&up), sc_sparse_free(&full);
        sc_triplet_parts_free(&parts);
    }
    /* an entry out of range is found whichever part holds it */
    sc_triplets_add(&t, 1, n, 1.0);
    sc_sparse bad;
    SC_CHECK(sc_sparse_from_triplets_threads(&t, 3, &bad, &err) == SC_EINPUT);

    /* extra rows: new entries are zeros, stored ones keep their values,
     * whatever the thread count */
    t.count--;   /* drop the bad entry again */
    int32_t *start = malloc(((size_t)n + 1) * sizeof *start), *rows = malloc(4 * (size_t)n * sizeof *rows);
    int32_t at = 0;
    for (int32_t j = 0; j < n; j++) {
        start[j] = at;
        if (j + 3 < n) rows[at++] = j + 3;
        rows[at++] = j;
        if (j >= 3) rows[at++] = j - 3, rows[at++] = j - 3;   /* any order, a repeat */
    }
    start[n] = at;
    sc_triplet_parts parts;
    sc_triplet_parts_init(&parts, n);
    sc_triplets copy;
    sc_triplets_init(&copy, n);
    sc_triplets_append(&copy, &t);
    sc_triplet_parts_take(&parts, &copy);
    sc_sparse wide, wide3;
    SC_CHECK_INT(sc_sparse_full_from_triplet_parts(&parts, start, rows, 1, &wide, &err), SC_OK);
    SC_CHECK_INT(sc_sparse_full_from_triplet_parts(&parts, start, rows, 3, &wide3, &err), SC_OK);
    SC_CHECK(same_sparse(&wide, &wide3));
    int64_t added = 0;
    for (int32_t j = 0; j < n; j++) {
        for (int32_t p = wide.colptr[j]; p + 1 < wide.colptr[j + 1]; p++) SC_CHECK(wide.rowind[p] < wide.rowind[p + 1]);
        for (int32_t p = wide.colptr[j]; p < wide.colptr[j + 1]; p++) {
            int32_t i = wide.rowind[p];
            int64_t at_full = sc_sparse_find(&full1, i, j);
            if (at_full >= 0) SC_CHECK(wide.val[p] == full1.val[at_full]);
            else {
                SC_CHECK(wide.val[p] == 0);
                added++;
            }
        }
        SC_CHECK(sc_sparse_find(&wide, j, j) >= 0);
        if (j >= 3) SC_CHECK(sc_sparse_find(&wide, j - 3, j) >= 0 && sc_sparse_find(&wide, j, j - 3) >= 0);
    }
    SC_CHECK(added > 0);
    SC_CHECK_INT(wide.nnz, full1.nnz + added);
    rows[0] = n;   /* a row out of range */
    SC_CHECK(sc_sparse_full_from_triplet_parts(&parts, start, rows, 2, &bad, &err) == SC_EINPUT);
    sc_sparse_free(&one), sc_sparse_free(&full1), sc_sparse_free(&wide), sc_sparse_free(&wide3);
    sc_triplet_parts_free(&parts);
    sc_triplets_free(&t);
    free(start), free(rows);
}

SC_TEST(sparse_not_positive_definite) {
    sc_triplets t;
    sc_triplets_init(&t, 3);
    sc_triplets_add(&t, 0, 0, 1);
    sc_triplets_add(&t, 1, 1, -1);
    sc_triplets_add(&t, 2, 2, 1);
    sc_sparse a;
    sc_error err = {0};
    SC_CHECK_INT(sc_sparse_from_triplets(&t, &a, &err), SC_OK);
    sc_sparse_chol *f = NULL;
    SC_CHECK(sc_sparse_chol_factor(&a, NULL, &f, &err) != SC_OK);
    SC_CHECK(f == NULL);
    SC_CHECK(strstr(err.message, "not positive definite") != NULL);
    sc_sparse_free(&a);
    sc_triplets_add(&t, 5, 1, 1.0); /* out of range */
    SC_CHECK(sc_sparse_from_triplets(&t, &a, &err) == SC_EINPUT);
    sc_triplets_free(&t);
}

/* A graph of random links (an expander: no ordering keeps its factor
 * sparse) is refused before its factorisation, by the factor's size and by
 * the inertia count's flops, with messages that say why. */
SC_TEST(sparse_expander_is_too_large) {
    const int32_t n = 100000;   /* AMD: 7.3e8 entries, 1.8e13 flops; METIS: 8.8e8 */
    sc_triplets t;
    sc_triplets_init(&t, n);
    uint64_t state = 12345;
    for (int32_t i = 0; i < n; i++) {
        sc_triplets_add(&t, i, i, 7.0);
        for (int k = 0; k < 3; k++) {
            state = state * 6364136223846793005ULL + 1442695040888963407ULL;
            int32_t j = (int32_t)((state >> 33) % (uint64_t)n);
            if (j != i) sc_triplets_add(&t, i, j, -1.0);
        }
    }
    sc_sparse a;
    sc_error err = {0};
    SC_CHECK_INT(sc_sparse_from_triplets(&t, &a, &err), SC_OK);
    sc_triplets_free(&t);
    sc_sparse_chol *f = NULL;
    sc_sparse_options opt = {.ordering = SC_SPARSE_ORDER_AMD, .kind = SC_SPARSE_AUTO};
    SC_CHECK_INT(sc_sparse_chol_factor(&a, &opt, &f, &err), SC_ENOMEM);
    SC_CHECK(f == NULL);
    SC_CHECK_MSG(strstr(err.message, "problem too large") && strstr(err.message, "entries"), "%s", err.message);
    int64_t below = -1;
    SC_CHECK_INT(sc_sparse_count_eigs_below(&a, 1.0, &below, &err), SC_ENOMEM);
    SC_CHECK_MSG(strstr(err.message, "flops") != NULL, "%s", err.message);
    sc_sparse_free(&a);
}

/* ================================================================ analytic D */

typedef struct pair_case {
    const char *name;
    int W, H;
    sc_wrap wrap;
    double a[2][2], b[2][2]; /* texel-space endpoints of both sides (from v0 to v1) */
} pair_case;

static const pair_case pair_cases[] = {
    {"many cells", 16, 16, SC_WRAP_REPEAT, {{0.3, 1.1}, {14.4, 10.8}}, {{12.6, 14.7}, {1.4, 4.8}}},
    {"one cell", 16, 16, SC_WRAP_REPEAT, {{5.1, 7.2}, {5.8, 7.9}}, {{9.2, 3.1}, {9.7, 3.6}}},
    {"axis aligned", 16, 16, SC_WRAP_REPEAT, {{1.3, 4.5}, {12.7, 4.5}}, {{3.5, 1.2}, {3.5, 14.1}}},
    {"on texel lines", 16, 16, SC_WRAP_REPEAT, {{2.0, 3.0}, {11.0, 3.0}}, {{7.0, 1.0}, {7.0, 10.0}}},
    {"through lattice points", 16, 16, SC_WRAP_REPEAT, {{2.0, 2.0}, {10.0, 10.0}}, {{12.0, 3.0}, {4.0, 11.0}}},
    {"repeat across the border", 16, 16, SC_WRAP_REPEAT, {{-6.3, 2.2}, {21.4, 9.9}}, {{3.3, -4.1}, {9.9, 19.2}}},
    {"clamp beyond the border", 16, 16, SC_WRAP_CLAMP, {{-3.3, 2.2}, {18.4, 9.9}}, {{3.3, -4.1}, {9.9, 17.2}}},
    {"mirror beyond the border", 16, 16, SC_WRAP_MIRROR, {{-6.3, 2.2}, {21.4, 9.9}}, {{3.3, -4.1}, {9.9, 19.2}}},
    {"non-square texture", 24, 10, SC_WRAP_REPEAT, {{0.7, 0.9}, {22.1, 8.3}}, {{20.2, 1.1}, {3.3, 7.6}}},
    {"same line both sides", 16, 16, SC_WRAP_REPEAT, {{2.2, 5.5}, {9.1, 8.3}}, {{9.1, 8.3}, {2.2, 5.5}}},
};

/* the third corners: any point off the edge, on a fixed side */
static void third_corner(const double *p0, const double *p1, double side, int W, int H, double out[2]) {
    double dx = p1[0] - p0[0], dy = p1[1] - p0[1];
    double x = 0.5 * (p0[0] + p1[0]) - side * dy * 0.5, y = 0.5 * (p0[1] + p1[1]) + side * dx * 0.5;
    uv_of(x, y, W, H, out);
}

SC_TEST(analytic_D_matches_quadrature) {
    for (size_t ci = 0; ci < sizeof pair_cases / sizeof pair_cases[0]; ci++) {
        const pair_case *pc = &pair_cases[ci];
        double a0[2], a1[2], b0[2], b1[2], a2[2], b3[2];
        uv_of(pc->a[0][0], pc->a[0][1], pc->W, pc->H, a0);
        uv_of(pc->a[1][0], pc->a[1][1], pc->W, pc->H, a1);
        uv_of(pc->b[0][0], pc->b[0][1], pc->W, pc->H, b0);
        uv_of(pc->b[1][0], pc->b[1][1], pc->W, pc->H, b1);
        third_corner(pc->a[0], pc->a[1], 1, pc->W, pc->H, a2);
        third_corner(pc->b[0], pc->b[1], -1, pc->W, pc->H, b3);
        sc_mesh *m = pair_mesh(a0, a1, a2, b0, b1, b3);
        sc_image_data *im = noise_image(pc->W, pc->H, 2, SC_PIXEL_F32, -1);
        sc_seam_grid g = {pc->W, pc->H, pc->wrap, pc->wrap};
        sc_seam_set s;
        sc_error err = {0};
        SC_CHECK_INT(sc_seam_find(m, 0, &s, &err), SC_OK);
        SC_CHECK_INT(s.nseams, 1);
        SC_CHECK_INT(s.nboundary, 4);
        ref_seam rs = {{a0[0], a0[1]}, {a1[0], a1[1]}, {b0[0], b0[1]}, {b1[0], b1[1]}, 1.0};
        gap_ud gu = {im, pc->wrap, &rs};
        double ref = dense_quad(im, &rs, 64, gap_f, &gu);
        double closed = sc_seam_edge_energy(m, &s.seams[0], &g, im);
        /* plain uniform composite quadrature, blind to the crossings: agrees to
         * its own (kink-limited) accuracy */
        double uni = 0;
        for (int i = 0; i < 20000; i++)
            for (int k = 0; k < 3; k++) uni += REF_GLW[k] * gap_f(&gu, (i + REF_GLX[k]) / 20000) / 20000;
        SC_CHECK_MSG(fabs(uni - ref) <= 1e-6 * ref, "%s: uniform quadrature %.12g, piecewise %.12g",
                     pc->name, uni, ref);
        SC_CHECK_MSG(fabs(closed - ref) <= 1e-9 * ref, "%s: closed form %.15g, quadrature %.15g",
                     pc->name, closed, ref);
        /* the same through the assembled operator: p^T M p */
        sc_seam_texset all;
        sc_seam_texset_init(&all, pc->W, pc->H);
        for (int t = 0; t < pc->W * pc->H; t++) sc_seam_texset_add(&all, t);
        sc_seam_texset_finish(&all);
        sc_triplet_parts tr;
        sc_triplet_parts_init(&tr, all.count);
        sc_seam_terms terms = {.w_seam = 1};
        SC_CHECK_INT(sc_seam_assemble(m, &s, &g, &all, &terms, 3, &tr, &err), SC_OK);
        sc_sparse M;
        SC_CHECK_INT(sc_sparse_from_triplet_parts(&tr, 1, &M, &err), SC_OK);
        double *x = malloc(sizeof *x * (size_t)all.count), viaM = 0;
        for (int c = 0; c < 2; c++) {
            for (int t = 0; t < all.count; t++) x[t] = ((float *)im->pixels)[2 * t + c];
            viaM += sc_sparse_quadform(&M, x);
        }
        SC_CHECK_MSG(fabs(viaM - ref) <= 1e-9 * ref, "%s: p^T M p %.15g, quadrature %.15g", pc->name,
                     viaM, ref);
        /* the residual r = -1/2 grad D at p: D(p + d) = D(p) - 2 r.d + d^T M d */
        sc_image_data *im1 = noise_image(pc->W, pc->H, 1, SC_PIXEL_F32, -1);
        double *res = calloc((size_t)all.count, sizeof *res), *dd = malloc(sizeof *dd * (size_t)all.count);
        sc_seam_terms rterms = {.w_seam = 1, .p0 = im1, .rhs = res};
        SC_CHECK_INT(sc_seam_assemble(m, &s, &g, &all, &rterms, 2, NULL, &err), SC_OK);
        sc_image_data *im2 = noise_image(pc->W, pc->H, 1, SC_PIXEL_F32, 0);
        double rd = 0;
        for (int t = 0; t < all.count; t++) {
            dd[t] = (float)(0.3 * (rnd() - 0.5));
            ((float *)im2->pixels)[t] = (float)(((float *)im1->pixels)[t] + dd[t]);
            dd[t] = (double)((float *)im2->pixels)[t] - ((float *)im1->pixels)[t];
            rd += res[t] * dd[t];
        }
        ref_seam rs1 = rs;
        gap_ud g1 = {im1, pc->wrap, &rs1}, g2 = {im2, pc->wrap, &rs1};
        double d1 = dense_quad(im1, &rs1, 16, gap_f, &g1), d2 = dense_quad(im2, &rs1, 16, gap_f, &g2);
        double pred = d1 - 2 * rd + sc_sparse_quadform(&M, dd);
        SC_CHECK_MSG(fabs(pred - d2) <= 1e-9 * d2, "%s: residual predicts %.15g, quadrature %.15g", pc->name,
                     pred, d2);
        free(res), free(dd);
        sc_image_free(im1), sc_image_free(im2);
        /* and the node-facing total (eq. 9 with one edge) */
        double tot = -1, gap = -1;
        SC_CHECK_INT(sc_seam_energy(m, &s, &g, im, 2, &tot, &gap, &err), SC_OK);
        SC_CHECK_NEAR(tot, closed, 1e-12 * closed);
        free(x);
        sc_sparse_free(&M);
        sc_triplet_parts_free(&tr);
        sc_seam_texset_free(&all);
        sc_seam_set_free(&s);
        sc_image_free(im);
        sc_mesh_free(m);
    }
}

typedef struct c1_ud {
    const sc_image_data *im;
    sc_wrap wrap;
    const double *a0, *a1, *b0, *b1;
    double n[2][2];
} c1_ud;
static double c1_f(void *ud, double gm) {
    c1_ud *u = ud;
    double p[2], q[2], gx[2], gy[2];
    ref_lerp_uv(u->a0, u->a1, gm, p);
    ref_lerp_uv(u->b0, u->b1, gm, q);
    ref_sample(u->im, u->wrap, u->wrap, p[0], p[1], NULL, &gx[0], &gy[0]);
    ref_sample(u->im, u->wrap, u->wrap, q[0], q[1], NULL, &gx[1], &gy[1]);
    double v = gx[0] * u->n[0][0] + gy[0] * u->n[0][1] + gx[1] * u->n[1][0] + gy[1] * u->n[1][1];
    return v * v;
}

typedef struct one_ud {
    const sc_image_data *im;
    sc_wrap wrap;
    const double *a0, *a1;
} one_ud;
static double one_f(void *ud, double gm) {
    one_ud *u = ud;
    double p[2], v;
    ref_lerp_uv(u->a0, u->a1, gm, p);
    ref_sample(u->im, u->wrap, u->wrap, p[0], p[1], &v, NULL, NULL);
    return v * v;
}

/* E_C1 and E_outside, checked the same way */
SC_TEST(analytic_c1_and_outside_match_quadrature) {
    for (size_t ci = 0; ci < sizeof pair_cases / sizeof pair_cases[0]; ci++) {
        const pair_case *pc = &pair_cases[ci];
        double a0[2], a1[2], b0[2], b1[2], a2[2], b3[2];
        uv_of(pc->a[0][0], pc->a[0][1], pc->W, pc->H, a0);
        uv_of(pc->a[1][0], pc->a[1][1], pc->W, pc->H, a1);
        uv_of(pc->b[0][0], pc->b[0][1], pc->W, pc->H, b0);
        uv_of(pc->b[1][0], pc->b[1][1], pc->W, pc->H, b1);
        third_corner(pc->a[0], pc->a[1], 1, pc->W, pc->H, a2);
        third_corner(pc->b[0], pc->b[1], -1, pc->W, pc->H, b3);
        sc_mesh *m = pair_mesh(a0, a1, a2, b0, b1, b3);
        sc_image_data *im = noise_image(pc->W, pc->H, 1, SC_PIXEL_F32, -1);
        sc_image_data *im0 = noise_image(pc->W, pc->H, 1, SC_PIXEL_F32, -1);
        sc_seam_grid g = {pc->W, pc->H, pc->wrap, pc->wrap};
        sc_seam_set s;
        sc_error err = {0};
        SC_CHECK_INT(sc_seam_find(m, 0, &s, &err), SC_OK);
        sc_seam_texset all;
        sc_seam_texset_init(&all, pc->W, pc->H);
        for (int t = 0; t < pc->W * pc->H; t++) sc_seam_texset_add(&all, t);
        sc_seam_texset_finish(&all);
        double *x = malloc(sizeof *x * (size_t)all.count), *d = malloc(sizeof *d * (size_t)all.count);
        for (int t = 0; t < all.count; t++) {
            x[t] = ((float *)im->pixels)[t];
            d[t] = (float)(x[t] - ((float *)im0->pixels)[t]); /* exactly representable below */
        }
        /* E_C1 = int (dB/dn1 (e1) + dB/dn2 (e2))^2, inward unit normals in texel space */
        double n[2][2];
        const double *ends[2][3] = {{pc->a[0], pc->a[1], NULL}, {pc->b[0], pc->b[1], NULL}};
        for (int q = 0; q < 2; q++) {
            double dx = ends[q][1][0] - ends[q][0][0], dy = ends[q][1][1] - ends[q][0][1];
            double len = sqrt(dx * dx + dy * dy), side = q ? -1 : 1; /* as third_corner placed them */
            n[q][0] = -side * dy / len, n[q][1] = side * dx / len;
        }
        c1_ud cu = {im, pc->wrap, a0, a1, b0, b1, {{n[0][0], n[0][1]}, {n[1][0], n[1][1]}}};
        ref_seam rs = {{a0[0], a0[1]}, {a1[0], a1[1]}, {b0[0], b0[1]}, {b1[0], b1[1]}, 1.0};
        double ref_c1 = dense_quad(im, &rs, 64, c1_f, &cu);
        sc_triplet_parts tr;
        sc_triplet_parts_init(&tr, all.count);
        sc_seam_terms terms = {.w_c1 = 1};
        SC_CHECK_INT(sc_seam_assemble(m, &s, &g, &all, &terms, 1, &tr, &err), SC_OK);
        sc_sparse Q;
        SC_CHECK_INT(sc_sparse_from_triplet_parts(&tr, 1, &Q, &err), SC_OK);
        double c1 = sc_sparse_quadform(&Q, x);
        SC_CHECK_MSG(fabs(c1 - ref_c1) <= 1e-9 * ref_c1, "%s: E_C1 %.15g, quadrature %.15g", pc->name,
                     c1, ref_c1);
        sc_sparse_free(&Q);
        sc_triplet_parts_free(&tr);
        /* E_outside = (1/L') sum_s l_s int |B_s(p - p0)|^2 over every silhouette half-edge */
        double num = 0, L = 0;
        sc_image_data *dm = noise_image(pc->W, pc->H, 1, SC_PIXEL_F32, 0);
        for (int t = 0; t < all.count; t++) ((float *)dm->pixels)[t] = (float)d[t];
        for (int q = 0; q < s.nsil; q++) {
            const sc_seam_silhouette *sl = &s.sil[q];
            ref_seam one = {{0}, {0}, {0}, {0}, 0};
            memcpy(one.a0, &m->U[2 * sl->side.uv0], sizeof one.a0);
            memcpy(one.a1, &m->U[2 * sl->side.uv1], sizeof one.a1);
            memcpy(one.b0, one.a0, sizeof one.b0); /* compared against a zero image below */
            memcpy(one.b1, one.a1, sizeof one.b1);
            one_ud ou = {dm, pc->wrap, one.a0, one.a1};
            double e = dense_quad(dm, &one, 64, one_f, &ou);
            num += sl->length * e;
            L += sl->length;
        }
        double ref_out = num / L;
        sc_triplet_parts_init(&tr, all.count);
        sc_seam_terms oterms = {.w_outside = 1};
        SC_CHECK_INT(sc_seam_assemble(m, &s, &g, &all, &oterms, 2, &tr, &err), SC_OK);
        SC_CHECK_INT(sc_sparse_from_triplet_parts(&tr, 1, &Q, &err), SC_OK);
        double eo = sc_sparse_quadform(&Q, d);
        SC_CHECK_MSG(fabs(eo - ref_out) <= 1e-9 * ref_out, "%s: E_outside %.15g, quadrature %.15g",
                     pc->name, eo, ref_out);
        /* E_outside is minimal at p0: its residual is zero */
        double *rhs = calloc((size_t)all.count, sizeof *rhs), rmax = 0;
        oterms.p0 = im0;
        oterms.rhs = rhs;
        SC_CHECK_INT(sc_seam_assemble(m, &s, &g, &all, &oterms, 2, NULL, &err), SC_OK);
        for (int t = 0; t < all.count; t++) rmax = fmax(rmax, fabs(rhs[t]));
        SC_CHECK(rmax == 0);
        free(rhs);
        sc_sparse_free(&Q);
        sc_triplet_parts_free(&tr);
        sc_image_free(dm);
        free(x), free(d);
        sc_seam_texset_free(&all);
        sc_seam_set_free(&s);
        sc_image_free(im), sc_image_free(im0);
        sc_mesh_free(m);
    }
}

SC_TEST(sampling_convention_and_wrap) {
    /* 4 x 2 image with texel value = i + 10 j: the texel centres sample exactly */
    sc_image_data *im = sc_image_alloc(4, 2, 1, SC_PIXEL_F32);
    for (int j = 0; j < 2; j++)
        for (int i = 0; i < 4; i++) ((float *)im->pixels)[j * 4 + i] = (float)(i + 10 * j);
    sc_seam_grid g = {4, 2, SC_WRAP_REPEAT, SC_WRAP_CLAMP};
    double v;
    sc_seam_sample(&g, im->pixels, 1, (2 + 0.5) / 4, (1 + 0.5) / 2, &v);
    SC_CHECK_NEAR(v, 12, 1e-12);
    sc_seam_sample(&g, im->pixels, 1, 0.0, 0.25, &v); /* halfway between texel 3 and texel 0 (repeat) */
    SC_CHECK_NEAR(v, 1.5, 1e-12);
    sc_seam_sample(&g, im->pixels, 1, 0.5, 0.0, &v); /* clamp in v: row 0 */
    SC_CHECK_NEAR(v, 1.5, 1e-12);
    for (int k = 0; k < 200; k++) {
        double u = -2 + 5 * rnd(), w = -2 + 5 * rnd(), r;
        for (int mode = 0; mode < 3; mode++) {
            sc_seam_grid gm = {4, 2, (sc_wrap)mode, (sc_wrap)((mode + 1) % 3)};
            sc_seam_sample(&gm, im->pixels, 1, u, w, &v);
            ref_sample(im, gm.wrap_u, gm.wrap_v, u, w, &r, NULL, NULL);
            SC_CHECK_NEAR(v, r, 1e-12);
        }
    }
    sc_image_free(im);
}

SC_TEST(coverage_partitions_texels) {
    /* a square [2, 10]^2 in texel space made of two triangles: 8 x 8 centres */
    double c[4][2];
    const double sq[4][2] = {{2, 2}, {10, 2}, {10, 10}, {2, 10}};
    for (int k = 0; k < 4; k++) uv_of(sq[k][0], sq[k][1], 16, 16, c[k]);
    sc_mesh *m = sc_mesh_alloc(4, 4, 0, 4, 1);
    for (int k = 0; k < 4; k++) {
        m->V[3 * k] = sq[k][0], m->V[3 * k + 1] = sq[k][1];
        m->U[2 * k] = c[k][0], m->U[2 * k + 1] = c[k][1];
    }
    /* faces 0, 1: the square; faces 2, 3: a mirrored copy (clockwise) on top of it */
    const int32_t F[12] = {0, 1, 2, 0, 2, 3, 0, 2, 1, 0, 3, 2};
    memcpy(m->FV, F, sizeof F);
    memcpy(m->FU, F, sizeof F);
    m->FM[2] = m->FM[3] = 0;
    m->materials[0] = sc_strdup("m");
    sc_seam_grid g = {16, 16, SC_WRAP_REPEAT, SC_WRAP_REPEAT};
    sc_seam_coverage cov;
    sc_error err = {0};
    m->nf = 2;
    SC_CHECK_INT(sc_seam_coverage_build(m, 0, &g, 2, &cov, &err), SC_OK);
    SC_CHECK_INT(cov.ncovered, 64);
    SC_CHECK_INT(cov.nshared, 0);
    sc_seam_coverage_free(&cov);
    m->nf = 4;
    SC_CHECK_INT(sc_seam_coverage_build(m, 0, &g, 2, &cov, &err), SC_OK);
    SC_CHECK_INT(cov.ncovered, 64);
    SC_CHECK_INT(cov.nshared, 64);
    sc_seam_coverage_free(&cov);
    sc_mesh_free(m);
}

/* Two rectangular charts (two triangles each) in texel space, where texel
 * i has its centre at x = i. */
static sc_mesh *two_rectangles(const double r[2][4], int W, int H) {
    sc_mesh *m = sc_mesh_alloc(8, 8, 0, 4, 1);
    for (int c = 0; c < 2; c++) {
        const double x[4] = {r[c][0], r[c][2], r[c][2], r[c][0]}, y[4] = {r[c][1], r[c][1], r[c][3], r[c][3]};
        for (int k = 0; k < 4; k++) {
            m->V[3 * (4 * c + k)] = x[k], m->V[3 * (4 * c + k) + 1] = y[k];
            uv_of(x[k], y[k], W, H, &m->U[2 * (4 * c + k)]);
        }
        const int32_t F[6] = {4 * c, 4 * c + 1, 4 * c + 2, 4 * c, 4 * c + 2, 4 * c + 3};
        memcpy(m->FV + 6 * c, F, sizeof F);
        memcpy(m->FU + 6 * c, F, sizeof F);
    }
    m->materials[0] = sc_strdup("m");
    return m;
}

/* Texels both rectangles reach, counted from the rectangles themselves: a
 * rectangle reaches texel i in x when x0 < i + 1 and x1 > i - 1 (and so in
 * y), through the wrap modes. */
static int64_t rectangles_meet(const double r[2][4], const sc_seam_grid *g) {
    uint8_t *mark = calloc((size_t)g->width * (size_t)g->height, 1);
    int64_t met = 0;
    for (int c = 0; c < 2; c++)
        for (int64_t j = (int64_t)floor(r[c][1]) - 1; j <= (int64_t)ceil(r[c][3]) + 1; j++)
            for (int64_t i = (int64_t)floor(r[c][0]) - 1; i <= (int64_t)ceil(r[c][2]) + 1; i++) {
                if (!(r[c][0] < i + 1 && r[c][2] > i - 1 && r[c][1] < j + 1 && r[c][3] > j - 1)) continue;
                size_t id = (size_t)sc_seam_wrap(j, g->height, g->wrap_v) * (size_t)g->width +
                            (size_t)sc_seam_wrap(i, g->width, g->wrap_u);
                if (mark[id] & (1 << c)) continue;
                mark[id] |= (uint8_t)(1 << c);
                met += mark[id] == 3;
            }
    free(mark);
    return met;
}

SC_TEST(two_charts_meet_where_their_taps_reach_one_texel) {
    const int32_t chart[4] = {0, 0, 1, 1};
    sc_error err = {0};
    sc_seam_grid g = {16, 16, SC_WRAP_CLAMP, SC_WRAP_CLAMP};
    int64_t reached, met;
    /* two texels apart: texel 6 is exactly one texel from each, a tap of weight 0 */
    const double apart[2][4] = {{2, 2, 5, 6}, {7, 2, 10, 6}};
    sc_mesh *m = two_rectangles(apart, 16, 16);
    SC_CHECK_INT(sc_seam_taps_meet(m, 0, &g, chart, &reached, &met, &err), SC_OK);
    SC_CHECK_INT(met, 0);
    SC_CHECK_INT(reached, 2 * 4 * 5);   /* columns 2..5 and 7..10, rows 2..6 */
    sc_mesh_free(m);
    /* closer by 0.02: texel 6 is within reach of both, on rows 2..6 */
    const double close[2][4] = {{2, 2, 5.01, 6}, {6.99, 2, 10, 6}};
    m = two_rectangles(close, 16, 16);
    SC_CHECK_INT(sc_seam_taps_meet(m, 0, &g, chart, &reached, &met, &err), SC_OK);
    SC_CHECK_INT(met, 5);
    SC_CHECK_INT(met, rectangles_meet(close, &g));
    /* one chart: nothing meets */
    const int32_t one[4] = {0, 0, 0, 0};
    SC_CHECK_INT(sc_seam_taps_meet(m, 0, &g, one, &reached, &met, &err), SC_OK);
    SC_CHECK_INT(met, 0);
    sc_mesh_free(m);
    /* across the texture's border: they meet through repeat, not through clamp */
    const double border[2][4] = {{0.5, 4, 3, 8}, {12, 4, 15.2, 8}};
    m = two_rectangles(border, 16, 16);
    SC_CHECK_INT(sc_seam_taps_meet(m, 0, &g, chart, &reached, &met, &err), SC_OK);
    SC_CHECK_INT(met, 0);
    g.wrap_u = SC_WRAP_REPEAT;
    SC_CHECK_INT(sc_seam_taps_meet(m, 0, &g, chart, &reached, &met, &err), SC_OK);
    SC_CHECK(met > 0);
    SC_CHECK_INT(met, rectangles_meet(border, &g));
    sc_mesh_free(m);
    /* random rectangles and wrap modes against the count from the rectangles */
    for (int k = 0; k < 300; k++) {
        double r[2][4];
        for (int c = 0; c < 2; c++) {
            double x = -3 + 20 * rnd(), y = -3 + 20 * rnd();
            r[c][0] = x, r[c][1] = y, r[c][2] = x + 0.2 + 5 * rnd(), r[c][3] = y + 0.2 + 5 * rnd();
        }
        sc_seam_grid gr = {16, 12, (sc_wrap)(k % 3), (sc_wrap)((k / 3) % 3)};
        m = two_rectangles(r, 16, 12);
        SC_CHECK_INT(sc_seam_taps_meet(m, 0, &gr, chart, &reached, &met, &err), SC_OK);
        SC_CHECK_INT(met, rectangles_meet(r, &gr));
        sc_mesh_free(m);
    }
    /* a slanted side: the triangle (a, b), (a + s, b), (a, b + s) reaches
     * texel (i, j) when a - 1 < i < a + s + 1, b - 1 < j < b + s + 1 and
     * (i - 1) + (j - 1) < a + b + s; beside it a rectangle, as above */
    for (int k = 0; k < 300; k++) {
        double a = 1 + 6 * rnd(), b = 1 + 6 * rnd(), sd = 1 + 4 * rnd();
        if (k == 0) a = 0, b = 0, sd = 4;   /* texel (3, 3): its square's corner touches the side */
        double r[2][4] = {{0}, {fmax(0.5, a + sd / 2 - 3 * rnd()), fmax(0.5, b + sd / 2 - 3 * rnd()), 0, 0}};
        if (k == 0) r[1][0] = r[1][1] = 3.5;
        r[1][2] = r[1][0] + 2.5, r[1][3] = r[1][1] + 2.5;
        sc_mesh *t = two_rectangles(r, 16, 16);
        const double tri[3][2] = {{a, b}, {a + sd, b}, {a, b + sd}};
        for (int v = 0; v < 3; v++) uv_of(tri[v][0], tri[v][1], 16, 16, &t->U[2 * v]);
        t->FU[0] = 0, t->FU[1] = 1, t->FU[2] = 2;
        t->FU[3] = t->FU[4] = t->FU[5] = 0;   /* the rectangle's second slot of chart 0: no area */
        sc_seam_grid gc = {16, 16, SC_WRAP_CLAMP, SC_WRAP_CLAMP};
        SC_CHECK_INT(sc_seam_taps_meet(t, 0, &gc, chart, &reached, &met, &err), SC_OK);
        int64_t expect = 0;
        for (int j = 0; j < 16; j++)
            for (int i = 0; i < 16; i++) {
                bool by_tri = a - 1 < i && i < a + sd + 1 && b - 1 < j && j < b + sd + 1 && i + j - 2 < a + b + sd;
                bool by_rect = r[1][0] < i + 1 && r[1][2] > i - 1 && r[1][1] < j + 1 && r[1][3] > j - 1;
                expect += by_tri && by_rect;
            }
        if (k == 0) SC_CHECK_INT(expect, 0);   /* (3, 3) is the rectangle's, and touches the side only */
        SC_CHECK_INT(met, expect);
        sc_mesh_free(t);
    }
}

SC_TEST(seam_finding_kinds) {
    sc_mesh *m = cube_mesh(0, false);
    sc_seam_set s;
    sc_error err = {0};
    SC_CHECK_INT(sc_seam_find(m, 0, &s, &err), SC_OK);
    SC_CHECK_INT(s.nseams, 12);
    SC_CHECK_INT(s.nboundary, 0);
    SC_CHECK_INT(s.nsil, 24);
    SC_CHECK_NEAR(s.seam_length, 12, 1e-12);
    sc_seam_set_free(&s);
    sc_mesh_free(m);
    m = cube_mesh(0, true);
    SC_CHECK_INT(sc_seam_find(m, 0, &s, &err), SC_OK);
    SC_CHECK_INT(s.nseams, 8);
    SC_CHECK_INT(s.nboundary, 4);
    sc_seam_set_free(&s);
    sc_mesh_free(m);
    m = grid_mesh(3);
    SC_CHECK_INT(sc_seam_find(m, 0, &s, &err), SC_OK);
    SC_CHECK_INT(s.nseams, 0);
    SC_CHECK_INT(s.nboundary, 12);
    SC_CHECK_INT(s.nfoldover, 0);
    sc_seam_set_free(&s);
    /* fold one triangle over its neighbour: move uv of the grid's corner vertex 0 across */
    m->U[0] = 0.1 + 0.8 * (2.0 / 3), m->U[1] = 0.1 + 0.8 * (2.0 / 3);
    SC_CHECK_INT(sc_seam_find(m, 0, &s, &err), SC_OK);
    SC_CHECK(s.nfoldover >= 1);
    sc_seam_set_free(&s);
    sc_mesh_free(m);
}

/* A strip of k quads cut lengthwise into two charts: the k seam edges along
 * the cut go on in the same two charts at every inner vertex, so they form
 * one chain. Its texels are one group (the texels around the inner
 * vertices too, which single-edge groups would leave to no group), and
 * their place along the chain grows with x, from 0 to the chain's length
 * in texels. On an open cube, whose seam vertices are corners of three
 * charts, every edge is a chain of its own. */
SC_TEST(seam_chains_group_texels) {
    const int k = 6, W = 64;
    sc_mesh *m = sc_mesh_alloc(3 * (k + 1), 4 * (k + 1), 0, 4 * k, 1);
    for (int r = 0; r < 3; r++)
        for (int i = 0; i <= k; i++) {
            double *v = &m->V[3 * (r * (k + 1) + i)];
            v[0] = i, v[1] = r, v[2] = 0;
        }
    /* uv rows: chart A uses rows 0, 1 at y 0.1, 0.3; chart B rows 1, 2 at 0.5, 0.7 */
    const double row_y[4] = {0.1, 0.3, 0.5, 0.7};
    for (int r = 0; r < 4; r++)
        for (int i = 0; i <= k; i++) {
            m->U[2 * (r * (k + 1) + i)] = 0.1 + 0.8 * i / k;
            m->U[2 * (r * (k + 1) + i) + 1] = row_y[r];
        }
    int f = 0;
    for (int c = 0; c < 2; c++)   /* chart c: surface rows c, c + 1; uv rows 2c, 2c + 1 */
        for (int i = 0; i < k; i++) {
            int32_t a = c * (k + 1) + i, b = a + 1, d = a + k + 1, e = d + 1;
            int32_t ua = 2 * c * (k + 1) + i, ub = ua + 1, ud = ua + k + 1, ue = ud + 1;
            const int32_t tv[2][3] = {{a, b, e}, {a, e, d}}, tu[2][3] = {{ua, ub, ue}, {ua, ue, ud}};
            for (int t = 0; t < 2; t++, f++)
                for (int q = 0; q < 3; q++) m->FV[3 * f + q] = tv[t][q], m->FU[3 * f + q] = tu[t][q];
        }
    m->materials[0] = sc_strdup("strip");
    sc_seam_set s;
    sc_error err = {0};
    SC_CHECK_INT(sc_seam_find(m, 0, &s, &err), SC_OK);
    SC_CHECK_INT(s.nseams, k);
    sc_seam_grid g = {W, W, SC_WRAP_CLAMP, SC_WRAP_CLAMP};
    sc_seam_texset set;
    sc_seam_texset_init(&set, W, W);
    SC_CHECK_INT(sc_seam_mark_texels(m, &s, &g, &set, NULL, 2, &err), SC_OK);
    sc_seam_texset_finish(&set);
    int32_t *ids = NULL;
    sc_seam_texset_members(&set, &ids);
    int32_t n = set.count, *group = malloc(sizeof *group * (size_t)n), *face = malloc(sizeof *face * (size_t)n);
    double *gamma = malloc(sizeof *gamma * (size_t)n);
    SC_CHECK_INT(sc_seam_texel_groups(m, &s, &g, &set, group, gamma, face, &err), SC_OK);
    int32_t chain = -1, in_chain = 0, near_inner = 0;
    bool one_chain = true, ordered = true;
    double length = 0.8 * W, lo = 1e30, hi = -1e30;
    for (int32_t r = 0; r < n; r++) {
        double x = ids[r] % W;
        if (group[r] < 0 || group[r] >= s.nseams) continue;
        if (chain < 0) chain = group[r];
        one_chain &= group[r] == chain;
        in_chain++;
        /* x in texel space runs 0.1 W - 0.5 .. 0.9 W - 0.5 along the chain (either direction) */
        double along = x + 0.5 - 0.1 * W;
        double d = fmin(fabs(gamma[r] - along), fabs(gamma[r] - (length - along)));
        ordered &= d <= 2.0;
        if (gamma[r] < lo) lo = gamma[r];
        if (gamma[r] > hi) hi = gamma[r];
        for (int i = 1; i < k; i++)
            near_inner += fabs(x + 0.5 - (0.1 + 0.8 * i / k) * W) < 0.5;
    }
    SC_CHECK(in_chain > 0);
    SC_CHECK(one_chain);
    SC_CHECK(ordered);
    SC_CHECK_MSG(lo >= 0 && hi <= length + 1e-9 && hi - lo > length - 4, "chain places %g .. %g of %g", lo, hi, length);
    SC_CHECK(near_inner >= 2 * (k - 1));   /* the texels at the inner vertices joined the chain */
    free(group), free(face), free(gamma), free(ids);
    sc_seam_texset_free(&set);
    sc_seam_set_free(&s);
    sc_mesh_free(m);

    /* the open cube: every seam vertex is a corner of three charts */
    m = cube_mesh(17, true);
    SC_CHECK_INT(sc_seam_find(m, 0, &s, &err), SC_OK);
    sc_seam_grid g2 = {64, 64, SC_WRAP_REPEAT, SC_WRAP_REPEAT};
    sc_seam_texset_init(&set, 64, 64);
    SC_CHECK_INT(sc_seam_mark_texels(m, &s, &g2, &set, NULL, 2, &err), SC_OK);
    sc_seam_texset_finish(&set);
    n = set.count;
    group = malloc(sizeof *group * (size_t)n), face = malloc(sizeof *face * (size_t)n);
    gamma = malloc(sizeof *gamma * (size_t)n);
    SC_CHECK_INT(sc_seam_texel_groups(m, &s, &g2, &set, group, gamma, face, &err), SC_OK);
    bool seen[64] = {false};
    int32_t distinct = 0;
    for (int32_t r = 0; r < n; r++)
        if (group[r] >= 0 && group[r] < s.nseams && !seen[group[r]]) seen[group[r]] = true, distinct++;
    SC_CHECK_INT(distinct, s.nseams);
    free(group), free(face), free(gamma);
    sc_seam_texset_free(&set);
    sc_seam_set_free(&s);
    sc_mesh_free(m);
}

/* Channels that copy an earlier one are found (bit for bit: -0 is not +0),
 * and the seam energy of a grey image stored as RGB, which takes each
 * piece's integral once for all three channels, is three times that of the
 * grey channel alone. */
SC_TEST(same_channels_and_grey_energy) {
    sc_image_data *im = sc_image_alloc(8, 8, 4, SC_PIXEL_F32);
    float *p = im->pixels;
    for (int t = 0; t < 64; t++) p[4 * t] = p[4 * t + 1] = p[4 * t + 3] = (float)t, p[4 * t + 2] = (float)(t % 5);
    int32_t same[SC_SEAM_MAX_CHANNELS];
    SC_CHECK_INT(sc_seam_same_channels(im, same), 2);
    SC_CHECK(same[0] == -1 && same[1] == 0 && same[2] == -1 && same[3] == 0);
    p[0] = 0.0f, p[1] = -0.0f;
    SC_CHECK_INT(sc_seam_same_channels(im, same), 3);
    SC_CHECK(same[1] == -1 && same[3] == 0);
    sc_image_free(im);

    sc_mesh *m = cube_mesh(17, true);
    sc_seam_set s;
    sc_error err = {0};
    SC_CHECK_INT(sc_seam_find(m, 0, &s, &err), SC_OK);
    sc_image_data *grey = noise_image(64, 64, 1, SC_PIXEL_U8, -1), *rgb = sc_image_alloc(64, 64, 3, SC_PIXEL_U8);
    for (int t = 0; t < 64 * 64; t++)
        for (int c = 0; c < 3; c++) ((uint8_t *)rgb->pixels)[3 * t + c] = ((uint8_t *)grey->pixels)[t];
    sc_seam_grid g = {64, 64, SC_WRAP_REPEAT, SC_WRAP_REPEAT};
    double e1 = 0, e3 = 0, g1 = 0, g3 = 0;
    SC_CHECK_INT(sc_seam_energy(m, &s, &g, grey, 2, &e1, &g1, &err), SC_OK);
    SC_CHECK_INT(sc_seam_energy(m, &s, &g, rgb, 2, &e3, &g3, &err), SC_OK);
    SC_CHECK(e1 > 0);
    SC_CHECK_NEAR(e3, 3 * e1, 1e-12 * e1);
    SC_CHECK(g3 == g1);
    sc_image_free(grey), sc_image_free(rgb);
    sc_seam_set_free(&s);
    sc_mesh_free(m);
}

/* Energies and bilinear samples read in linear light tap by tap are those
 * of the image converted first (sc_image_to_linear_f32), to the bit, for
 * sRGB images of every pixel type, with alpha as stored and grey stored as
 * RGB (the channel shortcut); a data image is read as stored however asked. */
SC_TEST(decoded_reads_are_those_of_the_converted_image) {
    sc_mesh *m = cube_mesh(17, true);
    sc_seam_set s;
    sc_error err = {0};
    SC_CHECK_INT(sc_seam_find(m, 0, &s, &err), SC_OK);
    sc_seam_grid g = {64, 64, SC_WRAP_REPEAT, SC_WRAP_REPEAT};
    const sc_pixel pixels[] = {SC_PIXEL_U8, SC_PIXEL_U16, SC_PIXEL_F32};
    for (int pi = 0; pi < 3; pi++)
        for (int32_t C = 1; C <= 4; C++)
            for (int srgb = 0; srgb < 2; srgb++) {
                sc_image_data *im = pixels[pi] == SC_PIXEL_U16 ? sc_image_alloc(64, 64, C, SC_PIXEL_U16)
                                                               : noise_image(64, 64, C, pixels[pi], -1);
                if (pixels[pi] == SC_PIXEL_U16)
                    for (size_t k = 0; k < (size_t)64 * 64 * (size_t)C; k++)
                        ((uint16_t *)im->pixels)[k] = (uint16_t)lrint((0.1 + 0.8 * rnd()) * 65535);
                if (C >= 3) /* channel 1 copies channel 0: grey stored as RGB */
                    for (int t = 0; t < 64 * 64; t++) {
                        size_t k = (size_t)t * (size_t)C, bytes = (size_t)pixels[pi];
                        memcpy((uint8_t *)im->pixels + (k + 1) * bytes, (uint8_t *)im->pixels + k * bytes, bytes);
                    }
                im->colorspace = srgb ? SC_COLOR_SRGB : SC_COLOR_DATA;
                sc_image_data *lin = sc_image_to_linear_f32(im, 1);
                const sc_image_data *imgs[2] = {im, im};
                const bool decode[2] = {true, false};
                double e[2], gap[2], e_lin = 0, gap_lin = 0, e_stored = 0, gap_stored = 0;
                SC_CHECK_INT(sc_seam_energies_decoded(m, &s, &g, imgs, decode, 2, 2, e, gap, &err), SC_OK);
                SC_CHECK_INT(sc_seam_energy(m, &s, &g, lin, 2, &e_lin, &gap_lin, &err), SC_OK);
                SC_CHECK_INT(sc_seam_energy(m, &s, &g, im, 2, &e_stored, &gap_stored, &err), SC_OK);
                SC_CHECK_MSG(e[0] == e_lin && gap[0] == gap_lin,
                             "pixel %d, %d channels, %s: %.17g %.17g against %.17g %.17g",
                             (int)pixels[pi], C, srgb ? "sRGB" : "data", e[0], gap[0], e_lin, gap_lin);
                SC_CHECK(e[1] == e_stored && gap[1] == gap_stored);
                SC_CHECK(e_lin > 0 && (srgb ? e_lin != e_stored : e_lin == e_stored));
                /* bilinear samples read through the reader: those of the converted image */
                sc_seam_reader reader;
                SC_CHECK(sc_seam_reader_make(im, true, &reader));
                int differ = 0;
                for (int k = 0; k < 200; k++) {
                    double u = rnd() * 1.2 - 0.1, v = rnd() * 1.2 - 0.1, a[4], b[4];
                    sc_seam_sample_read(&g, im, &reader, u, v, a);
                    sc_seam_sample(&g, lin->pixels, C, u, v, b);
                    for (int32_t c = 0; c < C; c++) differ += a[c] != b[c];
                }
                SC_CHECK_MSG(differ == 0, "%d samples differ", differ);
                sc_seam_reader_free(&reader);
                sc_image_free(lin), sc_image_free(im);
            }
    sc_seam_set_free(&s);
    sc_mesh_free(m);
}

/* ================================================================ the node, synthetic */

static void check_erased(sc_ctx *ctx, const char *what, double gap_limit) {
    double before = sc_ctx_metric_value(ctx, "seam_energy_before");
    double after = sc_ctx_metric_value(ctx, "seam_energy_after");
    SC_CHECK_MSG(before > 0 && after <= 1e-6 * before, "%s: seam energy %g -> %g", what, before, after);
    SC_CHECK_MSG(sc_ctx_metric_value(ctx, "max_seam_gap_after") <= gap_limit, "%s: gap %g", what,
                 sc_ctx_metric_value(ctx, "max_seam_gap_after"));
}

/* measure the node's output with the reference sampler */
static void ref_measure(sc_value *atlas_in, sc_ctx *ctx, int port, int tex, double *before,
                        double *after, double *gap_after) {
    const sc_atlas *a = atlas_in->as.atlas;
    const sc_mesh *m = a->mesh->as.mesh;
    ref_seam *rs;
    int ns = ref_find_seams(m, a->textures[tex].material, &rs);
    const sc_texture *t = &a->textures[tex];
    double g0;
    *before = ref_total(t->image->as.image, t->wrap_u, t->wrap_v, rs, ns, &g0);
    *after = ref_total(out_image(ctx, port, tex), t->wrap_u, t->wrap_v, rs, ns, gap_after);
    free(rs);
}

SC_TEST(node_erases_synthetic_cube) {
    const double angles[3] = {0, 17, -33};
    for (int k = 0; k < 3; k++) {
        sc_value *atlas = one_texture_atlas(cube_mesh(angles[k], k == 2),
                                            noise_image(64, 64, 3, SC_PIXEL_F32, -1), SC_WRAP_REPEAT);
        sc_error err = {0};
        sc_ctx *ctx = run_erase(atlas, NULL, 2, &err);
        SC_CHECK_MSG(ctx != NULL, "run failed: %s", err.message);
        if (ctx) {
            check_erased(ctx, "cube", 1e-4);
            double b, a, g;
            ref_measure(atlas, ctx, 0, 0, &b, &a, &g);
            SC_CHECK_NEAR(b, sc_ctx_metric_value(ctx, "seam_energy_before"), 1e-9 * b);
            SC_CHECK_MSG(a <= 1e-6 * b, "reference: %g -> %g", b, a);
            SC_CHECK_MSG(g <= 1e-4, "reference gap %g", g);
            SC_CHECK_INT(sc_ctx_metric_value(ctx, "seam_edges"), k == 2 ? 8 : 12);
            SC_CHECK(sc_ctx_metric_value(ctx, "nullity") > 0);
            SC_CHECK(out_image(ctx, 0, 0)->pixel == SC_PIXEL_F32);
            SC_CHECK(out_image(ctx, 1, 0) == out_image(ctx, 0, 0)); /* f32 input: native is f32 */
        }
        sc_ctx_free(ctx);
        sc_value_release(atlas);
    }
}

/* A grey image stored as RGB: the equal right-hand sides are solved once and
 * the equal channels rounded once; every channel must come out exactly as
 * the one-channel image does, on any thread count. */
SC_TEST(node_grey_as_rgb_matches_one_channel) {
    sc_image_data *grey = noise_image(64, 64, 1, SC_PIXEL_U8, -1);
    sc_image_data *rgb = sc_image_alloc(64, 64, 3, SC_PIXEL_U8);
    for (size_t k = 0; k < 64 * 64; k++)
        for (int c = 0; c < 3; c++)
            ((uint8_t *)rgb->pixels)[3 * k + c] = ((const uint8_t *)grey->pixels)[k];
    strcpy(rgb->format, grey->format);
    rgb->colorspace = grey->colorspace;
    sc_value *a1 = one_texture_atlas(cube_mesh(17, false), grey, SC_WRAP_REPEAT);
    sc_value *a3 = one_texture_atlas(cube_mesh(17, false), rgb, SC_WRAP_REPEAT);
    sc_error err = {0};
    sc_ctx *c1 = run_erase(a1, NULL, 1, &err);
    sc_ctx *c3 = run_erase(a3, NULL, 1, &err);
    sc_ctx *c3b = run_erase(a3, NULL, 2, &err);
    SC_CHECK_MSG(c1 && c3 && c3b, "run failed: %s", err.message);
    if (c1 && c3 && c3b) {
        check_erased(c3, "grey as rgb", 1e-4);
        for (int port = 0; port < 2; port++) {
            const sc_image_data *o1 = out_image(c1, port, 0), *o3 = out_image(c3, port, 0);
            const sc_image_data *o3b = out_image(c3b, port, 0);
            size_t bytes = (size_t)o3->width * o3->height * 3 * (size_t)o3->pixel;
            SC_CHECK(memcmp(o3->pixels, o3b->pixels, bytes) == 0);
            long differ = 0;
            for (size_t k = 0; k < 64 * 64; k++)
                for (int c = 0; c < 3; c++) {
                    size_t px = (size_t)o3->pixel;
                    differ += memcmp((const uint8_t *)o3->pixels + (3 * k + c) * px,
                                     (const uint8_t *)o1->pixels + k * px, px) != 0;
                }
            SC_CHECK_MSG(differ == 0, "port %d: %ld samples differ from the grey result", port, differ);
        }
        SC_CHECK_NEAR(sc_ctx_metric_value(c3, "seam_energy_after_u8_optimal"),
                      3 * sc_ctx_metric_value(c1, "seam_energy_after_u8_optimal"),
                      1e-9 * sc_ctx_metric_value(c3, "seam_energy_after_u8_optimal") + 1e-30);
    }
    sc_ctx_free(c1), sc_ctx_free(c3), sc_ctx_free(c3b);
    sc_value_release(a1), sc_value_release(a3);
}

SC_TEST(node_global_preset_and_weights) {
    sc_value *atlas = one_texture_atlas(cube_mesh(11, false), noise_image(48, 48, 1, SC_PIXEL_F32, -1),
                                        SC_WRAP_CLAMP);
    sc_error err = {0};
    const char *g[] = {"preset", "global", NULL};
    sc_ctx *c1 = run_erase(atlas, g, 1, &err);
    SC_CHECK(c1 != NULL);
    const char *o[] = {"outside", "true", "lerp", "true", NULL};
    sc_ctx *c2 = run_erase(atlas, o, 1, &err);
    SC_CHECK_MSG(c2 != NULL, "%s", err.message);
    const char *w[] = {"w_change", "1e4", "preset", "global", NULL};
    sc_ctx *c3 = run_erase(atlas, w, 1, &err);
    sc_ctx *c4 = run_erase(atlas, NULL, 1, &err);
    if (c1 && c2 && c3 && c4) {
        check_erased(c1, "global", 1e-4);
        check_erased(c2, "outside+lerp", 1e-4);
        /* an explicit w_change overrides the preset: the same as local */
        SC_CHECK(sc_digest_equal(sc_value_digest(sc_ctx_output(c3, 0)), sc_value_digest(sc_ctx_output(c4, 0))));
        SC_CHECK(!sc_digest_equal(sc_value_digest(sc_ctx_output(c1, 0)), sc_value_digest(sc_ctx_output(c4, 0))));
    }
    sc_ctx_free(c1), sc_ctx_free(c2), sc_ctx_free(c3), sc_ctx_free(c4);
    sc_value_release(atlas);
}

SC_TEST(node_same_output_for_any_thread_count) {
    sc_value *atlas = one_texture_atlas(cube_mesh(23, false), noise_image(64, 64, 4, SC_PIXEL_U8, -1),
                                        SC_WRAP_REPEAT);
    sc_error err = {0};
    sc_ctx *a = run_erase(atlas, NULL, 1, &err), *b = run_erase(atlas, NULL, 4, &err);
    SC_CHECK(a && b);
    if (a && b) {
        for (int port = 0; port < 2; port++)
            SC_CHECK(sc_digest_equal(sc_value_digest(sc_ctx_output(a, port)), sc_value_digest(sc_ctx_output(b, port))));
    }
    sc_ctx_free(a), sc_ctx_free(b);
    sc_value_release(atlas);
}

/* Bytes of the 8-bit result q one step or more from the float result f
 * (clamped to [0, 1]; linear light encoded to sRGB where q holds sRGB
 * colour); *worst gets the largest distance in steps. */
static size_t bytes_beyond_one_step(const sc_image_data *f, const sc_image_data *q, double *worst) {
    size_t n = (size_t)q->width * q->height * q->channels, beyond = 0;
    bool encode = f->colorspace == SC_COLOR_LINEAR && q->colorspace == SC_COLOR_SRGB;
    *worst = 0;
    for (size_t k = 0; k < n; k++) {
        double x = ((const float *)f->pixels)[k];
        if (encode && !ref_is_alpha(q, (int)(k % (size_t)q->channels))) x = ref_srgb_encode(x);
        x *= 255.0;
        x = x < 0 ? 0 : x > 255 ? 255 : x;
        double d = fabs(((const uint8_t *)q->pixels)[k] - x);
        *worst = d > *worst ? d : *worst;
        beyond += d >= 1.0;
    }
    return beyond;
}

SC_TEST(node_8bit_rounding) {
    sc_value *atlas = one_texture_atlas(cube_mesh(7, false), noise_image(96, 96, 3, SC_PIXEL_U8, -1),
                                        SC_WRAP_REPEAT);
    sc_error err = {0};
    sc_ctx *ctx = run_erase(atlas, NULL, 2, &err);
    SC_CHECK_MSG(ctx != NULL, "%s", err.message);
    if (ctx) {
        double naive = sc_ctx_metric_value(ctx, "seam_energy_after_u8_naive");
        double opt = sc_ctx_metric_value(ctx, "seam_energy_after_u8_optimal");
        double before = sc_ctx_metric_value(ctx, "seam_energy_before");
        SC_CHECK(naive > 0 && opt > 0);
        SC_CHECK_MSG(opt < 0.5 * naive, "optimal rounding %g vs naive %g", opt, naive);
        SC_CHECK(naive < 1e-2 * before);
        const sc_image_data *f = out_image(ctx, 0, 0), *q = out_image(ctx, 1, 0);
        const sc_image_data *in = atlas->as.atlas->textures[0].image->as.image;
        SC_CHECK(q->pixel == SC_PIXEL_U8 && f->pixel == SC_PIXEL_F32);
        SC_CHECK_STR(q->format, "png");
        /* every byte within one step of the float result; untouched texels exact */
        size_t n = (size_t)q->width * q->height * q->channels, changed = 0;
        for (size_t k = 0; k < n; k++) changed += ((uint8_t *)q->pixels)[k] != ((uint8_t *)in->pixels)[k];
        double worst;
        SC_CHECK_INT(bytes_beyond_one_step(f, q, &worst), 0);
        SC_CHECK(changed > 0);
        /* the independent measure agrees with the metric */
        ref_seam *rs;
        int ns = ref_find_seams(atlas->as.atlas->mesh->as.mesh, 0, &rs);
        double gq, eq = ref_total(q, SC_WRAP_REPEAT, SC_WRAP_REPEAT, rs, ns, &gq);
        /* the runtime decodes sRGB bytes in float, as GPUs do; the reference in double */
        SC_CHECK_NEAR(eq, opt, 1e-5 * opt);
        free(rs);
    }
    sc_ctx_free(ctx);
    sc_value_release(atlas);
}

/* sRGB colour is erased in the space GPUs filter it, linear light: the
 * float result holds seam-free linear values (what an EXR stores), and the
 * bytes, decoded, keep the seams within the rounding. Erasing the encoded
 * values instead (filter_space encoded) leaves seams in linear light. */
SC_TEST(node_erases_srgb_colour_in_linear_light) {
    sc_value *atlas = one_texture_atlas(cube_mesh(17, false), noise_image(64, 64, 3, SC_PIXEL_U8, -1),
                                        SC_WRAP_REPEAT);
    sc_error err = {0};
    const char *encoded[] = {"filter_space", "encoded", NULL};
    sc_ctx *lin = run_erase(atlas, NULL, 2, &err), *enc = run_erase(atlas, encoded, 2, &err);
    SC_CHECK_MSG(lin && enc, "%s", err.message);
    if (lin && enc) {
        const sc_image_data *f = out_image(lin, 0, 0), *q = out_image(lin, 1, 0), *fe = out_image(enc, 0, 0);
        SC_CHECK(f->colorspace == SC_COLOR_LINEAR && fe->colorspace == SC_COLOR_SRGB);
        SC_CHECK(q->pixel == SC_PIXEL_U8 && q->colorspace == SC_COLOR_SRGB);
        double before, after, gap, bytes_e, bytes_gap, enc_e, enc_gap;
        ref_measure(atlas, lin, 0, 0, &before, &after, &gap);   /* the reference decodes sRGB */
        ref_measure(atlas, lin, 1, 0, &before, &bytes_e, &bytes_gap);
        ref_measure(atlas, enc, 0, 0, &before, &enc_e, &enc_gap);
        printf("     linear light: before %.3g, float %.3g (gap %.2g), bytes %.3g (gap %.2g); "
               "encoded erasure %.3g (gap %.2g)\n", before, after, gap, bytes_e, bytes_gap, enc_e, enc_gap);
        /* the seam penalty (w_seam 1e10) leaves a few 1e-12 of white noise's energy */
        SC_CHECK_MSG(after <= 1e-11 * before, "float result: %g of %g", after, before);
        SC_CHECK_NEAR(after, sc_ctx_metric_value(lin, "seam_energy_after"), 1e-6 * before);
        SC_CHECK_MSG(bytes_e <= sc_ctx_metric_value(lin, "seam_energy_after_u8_naive"), "bytes %g", bytes_e);
        SC_CHECK_MSG(enc_e > 1e3 * after, "encoded erasure seen in linear light: %g", enc_e);
    }
    sc_ctx_free(lin), sc_ctx_free(enc);
    sc_value_release(atlas);
}

/* save measures the files it writes, decoded: a float EXR holds what the
 * erasure measured, an 8-bit PNG of it adds its rounding, a JPEG adds far
 * more, and max_seam_gap fails the save that adds more than it allows. */
static sc_ctx *run_save(sc_value *atlas, const char *format, const char *max_gap, sc_error *err) {
    sc_value *inputs[3] = {atlas, NULL, NULL};
    sc_ctx *ctx = sc_ctx_new(&sc_node_save, NULL, inputs);
    if (sc_ctx_set_param(ctx, "format", format, err) || sc_ctx_set_param(ctx, "max_seam_gap", max_gap, err) ||
        sc_ctx_run(ctx, err)) {
        sc_ctx_free(ctx);
        return NULL;
    }
    return ctx;
}

SC_TEST(save_measures_the_files_it_writes) {
    sc_value *atlas = one_texture_atlas(cube_mesh(17, false), noise_image(64, 64, 3, SC_PIXEL_U8, -1),
                                        SC_WRAP_REPEAT);
    sc_error err = {0};
    sc_ctx *erased = run_erase(atlas, NULL, 2, &err);
    SC_CHECK_MSG(erased != NULL, "%s", err.message);
    if (!erased) {
        sc_value_release(atlas);
        return;
    }
    sc_value *f32 = sc_ctx_output(erased, 0);
    const char *formats[3] = {"exr", "png", "jpg"};
    const char *files[3] = {"asset_cube_color.exr", "asset_cube_color.png", "asset_cube_color.jpg"};
    double added[3] = {0, 0, 0};
    for (int k = 0; k < 3; k++) {
        sc_ctx *ctx = run_save(f32, formats[k], "-1", &err);
        SC_CHECK_MSG(ctx != NULL, "%s: %s", formats[k], err.message);
        if (!ctx) continue;
        char name[128];
        snprintf(name, sizeof name, "%s.seam_energy", files[k]);
        double e = sc_ctx_metric_value(ctx, name);
        snprintf(name, sizeof name, "%s.seam_gap_added", files[k]);
        added[k] = sc_ctx_metric_value(ctx, name);
        /* the reference: the file decoded here, sampled as a GPU filters it */
        const sc_bytes *bytes = report_file_bytes(sc_ctx_output(ctx, 0)->as.report, files[k]);
        sc_image_data *back = NULL;
        SC_CHECK(bytes && sc_image_decode(files[k], bytes->data, bytes->size, &back, &err) == SC_OK);
        if (back) {
            ref_seam *rs;
            int ns = ref_find_seams(atlas->as.atlas->mesh->as.mesh, 0, &rs);
            double gap, ref = ref_total(back, SC_WRAP_REPEAT, SC_WRAP_REPEAT, rs, ns, &gap);
            printf("     %s: seam energy %.3g (reference %.3g), gap added %.3g\n", files[k], e, ref, added[k]);
            /* sRGB bytes decode in float in the runtime (as on a GPU), in double here: on the
             * small differences across seams that is up to a percent */
            SC_CHECK_NEAR(e, ref, (k == 0 ? 1e-5 : 1e-2) * ref + 1e-15);
            free(rs);
            sc_image_free(back);
        }
        sc_ctx_free(ctx);
    }
    SC_CHECK_MSG(added[0] == 0, "the EXR adds %g", added[0]);
    SC_CHECK_MSG(added[1] > 0 && added[1] < 0.01, "the PNG's rounding adds %g", added[1]);
    SC_CHECK_MSG(added[2] > 5 * added[1], "the JPEG adds %g, the PNG %g", added[2], added[1]);
    sc_ctx *gated = run_save(f32, "jpg", "1e-6", &err);
    SC_CHECK(gated == NULL && strstr(err.message, "asset_cube_color.jpg") && strstr(err.message, "max_seam_gap"));
    sc_ctx_free(gated);
    gated = run_save(f32, "exr", "1e-6", &err);
    SC_CHECK_MSG(gated != NULL, "%s", err.message);
    sc_ctx_free(gated);
    sc_ctx_free(erased);
    sc_value_release(atlas);
}

/* An 8-bit normal map is data: its PNG, read back as the material slot says
 * (not as the sRGB colour an 8-bit PNG would otherwise be taken for), holds
 * the very seams of the image, so the save's gate at 1e-6 passes. */
SC_TEST(saved_normal_map_keeps_its_seams) {
    sc_image_data *im = noise_image(64, 64, 3, SC_PIXEL_U8, -1);
    im->colorspace = SC_COLOR_DATA;
    sc_value *img = sc_value_new_image(im);
    const char *slot = "normal";
    sc_value *atlas = atlas_of(cube_mesh(17, false), &img, &slot, 1, SC_WRAP_REPEAT);
    sc_error err = {0};
    sc_ctx *ctx = run_save(atlas, "png", "1e-6", &err);
    SC_CHECK_MSG(ctx != NULL, "%s", err.message);
    if (ctx) {
        double gap = sc_ctx_metric_value(ctx, "asset_cube_normal.png.max_seam_gap");
        SC_CHECK_MSG(sc_ctx_metric_value(ctx, "asset_cube_normal.png.seam_gap_added") == 0 && gap > 0.01,
                     "added %g, gap %g", sc_ctx_metric_value(ctx, "asset_cube_normal.png.seam_gap_added"), gap);
    }
    sc_ctx_free(ctx);
    sc_value_release(atlas);
}

SC_TEST(node_controls) {
    sc_error err = {0};
    /* no seams: the very same atlas comes out */
    sc_value *flat = one_texture_atlas(grid_mesh(4), noise_image(32, 32, 3, SC_PIXEL_U8, -1), SC_WRAP_REPEAT);
    sc_ctx *ctx = run_erase(flat, NULL, 1, &err);
    SC_CHECK(ctx && sc_ctx_output(ctx, 0) == flat && sc_ctx_output(ctx, 1) == flat);
    if (ctx) SC_CHECK_INT(sc_ctx_metric_value(ctx, "textures_unchanged"), 1);
    sc_ctx_free(ctx);
    sc_value_release(flat);

    /* a constant texture stays constant: passed through (no seam gap), and
     * even when forced through the solver, bit for bit (float and bytes) */
    for (int px = 0; px < 2; px++) {
        sc_value *cst = one_texture_atlas(cube_mesh(13, false),
                                          noise_image(40, 40, 2, px ? SC_PIXEL_U8 : SC_PIXEL_F32, 0.4),
                                          SC_WRAP_REPEAT);
        ctx = run_erase(cst, NULL, 2, &err);
        SC_CHECK(ctx && sc_ctx_output(ctx, 0) == cst);
        sc_ctx_free(ctx);
        const char *force[] = {"gap_tolerance", "0", NULL};
        ctx = run_erase(cst, force, 2, &err);
        SC_CHECK(ctx != NULL);
        if (ctx) {
            SC_CHECK_INT(sc_ctx_metric_value(ctx, "textures_erased"), 1);
            const sc_image_data *in = cst->as.atlas->textures[0].image->as.image;
            const sc_image_data *o = out_image(ctx, 0, 0), *nat = out_image(ctx, 1, 0);
            size_t n = (size_t)in->width * in->height * in->channels;
            /* the float result: the input's constant (8-bit sRGB: as linear light), one value bit for bit */
            size_t diff = 0, C = (size_t)in->channels;
            for (size_t k = 0; k < n; k++) diff += ((float *)o->pixels)[k] != ((float *)o->pixels)[k % C];
            SC_CHECK_MSG(diff == 0, "constant texture: %zu texels changed", diff);
            for (int c = 0; c < (int)C; c++)
                SC_CHECK_NEAR(((float *)o->pixels)[c], px ? ref_texel(in, 0, 0, c) : ((float *)in->pixels)[c], 1e-6);
            SC_CHECK(nat->pixel == in->pixel);
            SC_CHECK(memcmp(nat->pixels, in->pixels, n * (size_t)in->pixel) == 0);
        }
        sc_ctx_free(ctx);
        sc_value_release(cst);
    }
}

SC_TEST(node_rerun_changes_nothing_measurable) {
    sc_value *atlas = one_texture_atlas(cube_mesh(29, false), noise_image(64, 64, 3, SC_PIXEL_F32, -1),
                                        SC_WRAP_REPEAT);
    sc_error err = {0};
    sc_ctx *c1 = run_erase(atlas, NULL, 2, &err);
    SC_CHECK(c1 != NULL);
    if (c1) {
        sc_value *once = sc_value_retain(sc_ctx_output(c1, 0));
        sc_ctx *c2 = run_erase(once, NULL, 2, &err);
        SC_CHECK(c2 != NULL);
        if (c2) {
            /* its seams are within the tolerance: the very same atlas comes out */
            double first = sc_ctx_metric_value(c1, "seam_energy_before");
            SC_CHECK(sc_ctx_metric_value(c2, "seam_energy_before") <= 1e-6 * first);
            SC_CHECK_INT(sc_ctx_metric_value(c2, "already_seam_free"), 1);
            SC_CHECK(sc_ctx_output(c2, 0) == once);
        }
        /* forcing a second solve (no tolerance) keeps the seams closed and moves
         * interior texels far less than the first erasure did */
        const char *force[] = {"gap_tolerance", "0", NULL};
        sc_ctx *c3 = run_erase(once, force, 2, &err);
        SC_CHECK(c3 != NULL);
        if (c3) {
            double ch1 = sc_ctx_metric_value(c1, "max_change_interior");
            double ch3 = sc_ctx_metric_value(c3, "max_change_interior");
            printf("     forced re-run: max interior change %.3g (first run %.3g), mean %.3g (first %.3g)\n", ch3,
                   ch1, sc_ctx_metric_value(c3, "mean_change_interior"),
                   sc_ctx_metric_value(c1, "mean_change_interior"));
            SC_CHECK(sc_ctx_metric_value(c3, "seam_energy_after") <= 1e-6 * sc_ctx_metric_value(c1, "seam_energy_before"));
            SC_CHECK(sc_ctx_metric_value(c3, "mean_change_interior") < 0.1 * sc_ctx_metric_value(c1, "mean_change_interior"));
        }
        sc_ctx_free(c3);
        sc_ctx_free(c2);
        sc_value_release(once);
    }
    sc_ctx_free(c1);
    sc_value_release(atlas);
}

SC_TEST(node_several_textures_and_params) {
    sc_value *imgs[3] = {sc_value_new_image(noise_image(64, 64, 3, SC_PIXEL_U8, -1)),
                         sc_value_new_image(noise_image(64, 64, 3, SC_PIXEL_U8, -1)),
                         sc_value_new_image(noise_image(32, 32, 1, SC_PIXEL_F32, -1))};
    const char *slots[3] = {"color", "normal", "occlusion"};
    sc_value *atlas = atlas_of(cube_mesh(5, false), imgs, slots, 3, SC_WRAP_REPEAT);
    sc_error err = {0};
    sc_ctx *ctx = run_erase(atlas, NULL, 2, &err);
    SC_CHECK_MSG(ctx != NULL, "%s", err.message);
    if (ctx) {
        SC_CHECK_INT(sc_ctx_metric_value(ctx, "textures_erased"), 3);
        SC_CHECK_INT(sc_ctx_metric_value(ctx, "factorizations"), 2); /* 64^2 shared, 32^2 */
        SC_CHECK(sc_ctx_metric_value(ctx, "color.seam_energy_after") <=
                 1e-6 * sc_ctx_metric_value(ctx, "color.seam_energy_before"));
        SC_CHECK(sc_ctx_metric_value(ctx, "occlusion.seam_energy_after") <=
                 1e-6 * sc_ctx_metric_value(ctx, "occlusion.seam_energy_before"));
        SC_CHECK(!isnan(sc_ctx_metric_value(ctx, "normal.tangent_space_suspect")));
    }
    sc_ctx_free(ctx);
    /* normal_space=tangent: the noise map goes through its tangent frames */
    const char *ts[] = {"normal_space", "tangent", "textures", "normal, occlusion", NULL};
    ctx = run_erase(atlas, ts, 1, &err);
    SC_CHECK_MSG(ctx != NULL, "%s", err.message);
    if (ctx) {
        SC_CHECK_INT(sc_ctx_metric_value(ctx, "normal.tangent_space"), 1);
        SC_CHECK_INT(sc_ctx_metric_value(ctx, "textures_erased"), 2);
        SC_CHECK(sc_ctx_metric_value(ctx, "normal.object_seam_energy_after") <=
                 1e-6 * sc_ctx_metric_value(ctx, "normal.object_seam_energy_before"));
        const sc_atlas *o = sc_ctx_output(ctx, 0)->as.atlas;
        SC_CHECK(o->textures[0].image == imgs[0] && o->textures[1].image != imgs[1]);
        SC_CHECK(o->textures[2].image != imgs[2]);
        SC_CHECK(o->mesh == atlas->as.atlas->mesh);
    }
    sc_ctx_free(ctx);
    const char *bad[] = {"textures", "colour", NULL};
    ctx = run_erase(atlas, bad, 1, &err);
    SC_CHECK(ctx == NULL);
    SC_CHECK(strstr(err.message, "colour") != NULL);
    sc_value_release(atlas);
}

/* ================================================================ tangent space */

/* The known object-space normal field of the tangent-space test. */
static void bumpy_normal(const double p[3], double n[3]) {
    double l = sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]);
    n[0] = p[0] / l + 0.3 * sin(3 * p[1]), n[1] = p[1] / l + 0.3 * sin(3 * p[2]), n[2] = p[2] / l + 0.3 * sin(3 * p[0]);
    double m = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    for (int d = 0; d < 3; d++) n[d] /= m;
}

/* Bilinear sample of an 8-bit map (repeat wrap), decoded to -1..1: the
 * test's own sampler, not sc_seam's. */
static void sample_u8_normal(const sc_image_data *im, double u, double v, double t[3]) {
    int W = im->width, H = im->height, C = im->channels;
    double x = u * W - 0.5, y = v * H - 0.5, fx = floor(x), fy = floor(y), s = x - fx, r = y - fy;
    const uint8_t *px = im->pixels;
    for (int c = 0; c < 3; c++) t[c] = 0;
    for (int k = 0; k < 4; k++) {
        long i = (long)fx + (k & 1), j = (long)fy + (k >> 1);
        i = ((i % W) + W) % W, j = ((j % H) + H) % H;
        double w = ((k & 1) ? s : 1 - s) * ((k >> 1) ? r : 1 - r);
        for (int c = 0; c < 3; c++) t[c] += w * (2.0 * px[((size_t)j * W + i) * C + c] / 255.0 - 1.0);
    }
}

/* The unit normal a renderer shades with at point gamma of seam edge e,
 * side s: frame of the side's face at that point times the map there. */
static void rendered_normal(const sc_mesh *m, const sc_tangent_frames *fr, const sc_seam_edge *e, int s, double gamma,
                            const sc_image_data *im, double n[3]) {
    const sc_seam_side *sd = &e->side[s];
    double b[3] = {0, 0, 0}, T[3], B[3], N[3], t[3];
    for (int c = 0; c < 3; c++) {
        if (m->FV[3 * sd->face + c] == e->v0) b[c] = 1 - gamma;
        if (m->FV[3 * sd->face + c] == e->v1) b[c] = gamma;
    }
    sc_tangent_frame_at(fr, sd->face, b, T, B, N);
    const double *a = m->U + 2 * (size_t)sd->uv0, *z = m->U + 2 * (size_t)sd->uv1;
    sample_u8_normal(im, a[0] + gamma * (z[0] - a[0]), a[1] + gamma * (z[1] - a[1]), t);
    double l = 0;
    for (int d = 0; d < 3; d++) n[d] = t[0] * T[d] + t[1] * B[d] + t[2] * N[d], l += n[d] * n[d];
    for (int d = 0; d < 3; d++) n[d] /= sqrt(l);
}

/* The largest and mean |n_a - n_b| over 16 points of every seam edge. */
static void rendered_gap(const sc_mesh *m, const sc_seam_set *seams, const sc_tangent_frames *fr,
                         const sc_image_data *im, double *max_gap, double *mean_gap) {
    double sum = 0;
    long count = 0;
    *max_gap = 0;
    for (int32_t e = 0; e < seams->nseams; e++)
        for (int k = 0; k < 16; k++, count++) {
            double a[3], b[3], g = 0;
            rendered_normal(m, fr, &seams->seams[e], 0, (k + 0.5) / 16, im, a);
            rendered_normal(m, fr, &seams->seams[e], 1, (k + 0.5) / 16, im, b);
            for (int d = 0; d < 3; d++) g += (a[d] - b[d]) * (a[d] - b[d]);
            g = sqrt(g), sum += g;
            if (g > *max_gap) *max_gap = g;
        }
    *mean_gap = count ? sum / count : 0;
}

/* A tangent-space map of a known object-space field on the sphere, with
 * noise on every texel so that its seams open: erasure (normal_space auto
 * finds it tangent-space) makes the normal a renderer rebuilds continuous
 * across the seams, measured with the test's own sampler, and keeps the
 * field. Frames are the library's MikkTSpace frames, which the glTF writer
 * also writes; their properties are checked here first. */
SC_TEST(tangent_space_normal_map_is_continuous_after_erasure) {
    const char *pp[] = {"resolution", "12", "texture_size", "512", NULL};
    sc_test_run r = sc_test_run_node(&sc_node_procedural, pp, NULL, NULL, NULL, NULL);
    SC_CHECK_MSG(r.rc == SC_OK, "procedural: %s", r.err.message);
    if (r.rc != SC_OK) return;
    sc_value *sphere = sc_value_retain(sc_ctx_output(r.ctx, 0));
    sc_ctx_free(r.ctx);
    const sc_mesh *m = sphere->as.atlas->mesh->as.mesh;
    sc_error err = {0};
    sc_tangent_frames fr;
    SC_CHECK(sc_tangent_frames_build(m, &fr, &err) == SC_OK);
    /* frames: unit tangents orthogonal to unit normals, along d position / d u */
    double worst_ortho = 0, worst_unit = 0;
    int along_u = 0;
    for (int32_t f = 0; f < m->nf; f++) {
        const double *P0 = m->V + 3 * (size_t)m->FV[3 * f], *P1 = m->V + 3 * (size_t)m->FV[3 * f + 1],
                     *P2 = m->V + 3 * (size_t)m->FV[3 * f + 2];
        const double *U0 = m->U + 2 * (size_t)m->FU[3 * f], *U1 = m->U + 2 * (size_t)m->FU[3 * f + 1],
                     *U2 = m->U + 2 * (size_t)m->FU[3 * f + 2];
        double s1 = U1[0] - U0[0], t1 = U1[1] - U0[1], s2 = U2[0] - U0[0], t2 = U2[1] - U0[1], du[3];
        double det = s1 * t2 - s2 * t1;
        for (int d = 0; d < 3; d++) du[d] = (t2 * (P1[d] - P0[d]) - t1 * (P2[d] - P0[d])) / det;
        for (int c = 0; c < 3; c++) {
            const double *T = fr.tangent + 12 * (size_t)f + 4 * c, *N = fr.normal + 9 * (size_t)f + 3 * c;
            worst_ortho = fmax(worst_ortho, fabs(T[0] * N[0] + T[1] * N[1] + T[2] * N[2]));
            worst_unit = fmax(worst_unit, fabs(sqrt(T[0] * T[0] + T[1] * T[1] + T[2] * T[2]) - 1));
            worst_unit = fmax(worst_unit, fabs(sqrt(N[0] * N[0] + N[1] * N[1] + N[2] * N[2]) - 1));
            along_u += T[0] * du[0] + T[1] * du[1] + T[2] * du[2] > 0 && fabs(T[3]) == 1;
        }
    }
    SC_CHECK_MSG(worst_ortho < 1e-12 && worst_unit < 1e-12, "T.N %g, |T|-1 %g", worst_ortho, worst_unit);
    SC_CHECK_INT(along_u, 3 * m->nf);
    /* the map: t = [T B N]^-1 n(p) at each texel's point, plus noise */
    const int W = 512;
    sc_seam_grid g = {W, W, SC_WRAP_REPEAT, SC_WRAP_REPEAT};
    sc_tangent_texels tx;
    SC_CHECK(sc_tangent_texels_build(m, 0, &g, 3.0, 2, &tx, &err) == SC_OK);
    sc_image_data *map = sc_image_alloc(W, W, 3, SC_PIXEL_U8);
    map->colorspace = SC_COLOR_DATA;
    uint8_t *px = map->pixels;
    uint64_t seed = 12345;
    for (size_t id = 0; id < (size_t)W * W; id++) {
        double t[3] = {0, 0, 1};
        if (tx.face[id] >= 0) {
            int32_t f = tx.face[id];
            double b[3] = {1 - tx.bary[2 * id] - tx.bary[2 * id + 1], tx.bary[2 * id], tx.bary[2 * id + 1]};
            double p[3] = {0, 0, 0}, n[3], M[3][3];
            for (int c = 0; c < 3; c++)
                for (int d = 0; d < 3; d++) p[d] += b[c] * m->V[3 * (size_t)m->FV[3 * f + c] + d];
            bumpy_normal(p, n);
            sc_tangent_frame_at(&fr, f, b, M[0], M[1], M[2]);
            ref_solve3(M[0], M[1], M[2], n, t);
        }
        for (int c = 0; c < 3; c++) {
            seed = seed * 6364136223846793005ull + 1442695040888963407ull;
            double noise = 0.06 * ((double)(seed >> 11) / 9007199254740992.0 - 0.5);
            double x = 0.5 * (fmax(-1, fmin(1, t[c] + noise)) + 1);
            px[id * 3 + c] = (uint8_t)lrint(255 * x);
        }
    }
    sc_atlas *a = sc_atlas_new(sc_value_retain(sphere->as.atlas->mesh));
    sc_atlas_add_texture(a, "normal", 0, SC_WRAP_REPEAT, SC_WRAP_REPEAT, "", sc_value_new_image(map));
    sc_value *atlas = sc_value_new_atlas(a);
    sc_seam_set seams = {0};
    SC_CHECK(sc_seam_find(m, 0, &seams, &err) == SC_OK);
    double before_max, before_mean, after_max = NAN, after_mean = NAN;
    rendered_gap(m, &seams, &fr, map, &before_max, &before_mean);
    sc_ctx *ctx = run_erase(atlas, NULL, 2, &err);
    SC_CHECK_MSG(ctx != NULL, "%s", err.message);
    if (ctx) {
        const sc_image_data *out = out_image(ctx, 1, 0);
        SC_CHECK(out->pixel == SC_PIXEL_U8);
        rendered_gap(m, &seams, &fr, out, &after_max, &after_mean);
        printf("     %d seams: rendered normal gap max %.4f mean %.4f before, %.4f %.4f after "
               "(metrics: %.4f %.4f after)\n",
               seams.nseams, before_max, before_mean, after_max, after_mean,
               sc_ctx_metric_value(ctx, "normal_gap_after"), sc_ctx_metric_value(ctx, "normal_gap_mean_after"));
        SC_CHECK_INT(sc_ctx_metric_value(ctx, "tangent_space"), 1);
        SC_CHECK(before_max > 0.03);
        SC_CHECK_MSG(after_max < 0.5 * before_max && after_mean < 0.5 * before_mean, "after %g %g", after_max,
                     after_mean);
        SC_CHECK(after_max <= SC_ERASE_NORMAL_GAP_LIMIT);
        SC_CHECK_INT(sc_ctx_metric_value(ctx, "tangent_space_discontinuous"), 0);
        /* the report measures what this test measures, at other points */
        SC_CHECK(fabs(sc_ctx_metric_value(ctx, "normal_gap_mean_after") - after_mean) < 0.5 * after_mean + 1e-3);
        /* and the field stays: inside the charts, within the noise */
        double worst = 0;
        for (int32_t f = 0; f < m->nf; f++) {
            double b[3] = {1.0 / 3, 1.0 / 3, 1.0 / 3}, p[3] = {0, 0, 0}, uv[2] = {0, 0}, n[3], M[3][3], t[3];
            for (int c = 0; c < 3; c++) {
                for (int d = 0; d < 3; d++) p[d] += b[c] * m->V[3 * (size_t)m->FV[3 * f + c] + d];
                for (int d = 0; d < 2; d++) uv[d] += b[c] * m->U[2 * (size_t)m->FU[3 * f + c] + d];
            }
            bumpy_normal(p, n);
            sc_tangent_frame_at(&fr, f, b, M[0], M[1], M[2]);
            sample_u8_normal(out, uv[0], uv[1], t);
            double r3[3], l = 0, e = 0;
            for (int d = 0; d < 3; d++) r3[d] = t[0] * M[0][d] + t[1] * M[1][d] + t[2] * M[2][d], l += r3[d] * r3[d];
            for (int d = 0; d < 3; d++) e += (r3[d] / sqrt(l) - n[d]) * (r3[d] / sqrt(l) - n[d]);
            worst = fmax(worst, sqrt(e));
        }
        printf("     field kept: largest error at face centres %.4f\n", worst);
        SC_CHECK(worst < 0.08);
        /* erased once, its object-space seams are within what 8-bit rounding
         * opens: a second erasure keeps the map as it is, byte for byte */
        sc_value *erased = sc_value_retain(sc_ctx_output(ctx, 1));
        sc_ctx *again = run_erase(erased, NULL, 2, &err);
        SC_CHECK_MSG(again != NULL, "%s", err.message);
        if (again) {
            const sc_image_data *kept = out_image(again, 1, 0);
            SC_CHECK_INT(sc_ctx_metric_value(again, "already_seam_free"), 1);
            SC_CHECK(kept->pixel == SC_PIXEL_U8 && memcmp(kept->pixels, out->pixels, (size_t)W * W * 3) == 0);
        }
        sc_ctx_free(again);
        sc_value_release(erased);
        /* erased as stored instead, the map meets across seams as stored (as a
         * re-chartified map does by construction) and auto takes it for an
         * object-space one; from a glTF asset (material constants stated),
         * auto takes it as the tangent-space map the spec says it is */
        const char *as_object[] = {"normal_space", "object", NULL};
        sc_ctx *flat = run_erase(atlas, as_object, 2, &err);
        SC_CHECK_MSG(flat != NULL, "%s", err.message);
        if (flat) {
            const sc_image_data *stored = out_image(flat, 1, 0);
            double flat_max, flat_mean, gltf_max = NAN, gltf_mean = NAN;
            rendered_gap(m, &seams, &fr, stored, &flat_max, &flat_mean);
            for (int gltf = 0; gltf < 2; gltf++) {
                sc_atlas *b = sc_atlas_new(sc_value_retain(sphere->as.atlas->mesh));
                sc_atlas_add_texture(b, "normal", 0, SC_WRAP_REPEAT, SC_WRAP_REPEAT, "",
                                     sc_value_retain(sc_ctx_output(flat, 1)->as.atlas->textures[0].image));
                if (gltf && (b->materials = calloc((size_t)m->nmat, sizeof *b->materials)))
                    for (int32_t k = 0; k < m->nmat; k++) b->materials[k] = sc_material_default();
                sc_value *in = sc_value_new_atlas(b);
                sc_ctx *c = run_erase(in, NULL, 2, &err);
                SC_CHECK_MSG(c != NULL, "%s", err.message);
                if (c) {
                    double tangent = sc_ctx_metric_value(c, "tangent_space");
                    SC_CHECK_MSG(gltf ? tangent == 1 : tangent != 1, "glTF %d: tangent_space %g", gltf, tangent);
                    if (gltf) rendered_gap(m, &seams, &fr, out_image(c, 1, 0), &gltf_max, &gltf_mean);
                }
                sc_ctx_free(c);
                sc_value_release(in);
            }
            printf("     erased as stored: rendered gap mean %.4f; as a glTF map, auto: %.4f\n", flat_mean, gltf_mean);
            SC_CHECK(gltf_mean < 0.5 * flat_mean);
        }
        sc_ctx_free(flat);
    }
    sc_ctx_free(ctx);
    sc_seam_set_free(&seams);
    sc_tangent_texels_free(&tx);
    sc_tangent_frames_free(&fr);
    sc_value_release(atlas);
    sc_value_release(sphere);
}

/* ================================================================ corpus */

/* erase, then check every texture with the reference sampler */
/* solver schur (edge clusters + CHOLMOD on the rest, conjugate gradients on
 * the whole system) against solver cholmod: both erase, measured by the
 * reference sampler, and agree texel by texel; the same bytes on any thread
 * count. BoomBox's charts lie side by side in its atlas, so the couplings
 * the preconditioner leaves out are many. */
static void schur_against_cholmod(const char *what, sc_value *atlas, const char *slots, double bound) {
    const char *kv_s[] = {"solver", "schur", "textures", slots, NULL}, *kv_c[] = {"solver", "cholmod", "textures", slots, NULL};
    sc_error err = {0};
    sc_ctx *s = run_erase(atlas, kv_s, 2, &err), *c = run_erase(atlas, kv_c, 2, &err), *s1 = run_erase(atlas, kv_s, 1, &err);
    SC_CHECK_MSG(s && c && s1, "%s: %s", what, err.message);
    if (s && c && s1) {
        SC_CHECK_MSG(sc_ctx_metric_value(s, "pcg_iterations") >= 1, "%s: the schur solver did not run", what);
        SC_CHECK(sc_digest_equal(sc_value_digest(sc_ctx_output(s, 0)), sc_value_digest(sc_ctx_output(s1, 0))));
        const sc_atlas *a = atlas->as.atlas;
        for (int i = 0; i < a->ntex; i++) {
            if (sc_ctx_output(s, 0)->as.atlas->textures[i].image == a->textures[i].image) continue;
            double b, af, g;
            ref_measure(atlas, s, 0, i, &b, &af, &g);
            const sc_image_data *x = out_image(s, 0, i), *y = out_image(c, 0, i);
            double diff = 0;
            size_t count = (size_t)x->width * x->height * x->channels;
            for (size_t k = 0; k < count; k++)
                diff = fmax(diff, fabs((double)((const float *)x->pixels)[k] - ((const float *)y->pixels)[k]));
            printf("     %s %s: schur D %.3g -> %.3g, gap %.3g, %g pcg iterations, largest texel difference to "
                   "cholmod %.3g\n", what, a->textures[i].name, b, af, g, sc_ctx_metric_value(s, "pcg_iterations"), diff);
            SC_CHECK_MSG(af <= 1e-6 * b && g <= 1e-4, "%s: D %g -> %g, gap %g", what, b, af, g);
            SC_CHECK_MSG(diff <= bound, "%s: schur and cholmod differ by %g", what, diff);
        }
    }
    sc_ctx_free(s), sc_ctx_free(c), sc_ctx_free(s1);
}

SC_TEST(node_schur_solver_synthetic_cube) {
    sc_value *atlas = one_texture_atlas(cube_mesh(17, true), noise_image(64, 64, 3, SC_PIXEL_F32, -1), SC_WRAP_REPEAT);
    schur_against_cholmod("cube", atlas, "all", 2e-6);   /* 6.2e-6 without the refinement on Q */
    sc_value_release(atlas);
}

/* A closed seam chain (the pillow's border, cut at one vertex): its texels
 * are one group whose places run the loop's length, the texels at the cut
 * couple both ends of it (more than SCHUR_KEY_SPAN apart at 512^2: the
 * interface takes them), and the edge-cluster solver agrees with CHOLMOD. */
SC_TEST(node_schur_solver_closed_chain) {
    const int W = 512;
    sc_mesh *m = pillow_mesh(8);
    sc_seam_set s;
    sc_error err = {0};
    SC_CHECK_INT(sc_seam_find(m, 0, &s, &err), SC_OK);
    SC_CHECK_INT(s.nseams, 32);
    sc_seam_grid g = {W, W, SC_WRAP_CLAMP, SC_WRAP_CLAMP};
    sc_seam_texset set;
    sc_seam_texset_init(&set, W, W);
    SC_CHECK_INT(sc_seam_mark_texels(m, &s, &g, &set, NULL, 2, &err), SC_OK);
    sc_seam_texset_finish(&set);
    int32_t n = set.count, *group = malloc(sizeof *group * (size_t)n), *face = malloc(sizeof *face * (size_t)n);
    double *key = malloc(sizeof *key * (size_t)n), hi = 0;
    SC_CHECK_INT(sc_seam_texel_groups(m, &s, &g, &set, group, key, face, &err), SC_OK);
    bool one = true;
    for (int32_t r = 0; r < n; r++) {
        if (group[r] < 0) continue;
        one &= group[r] == group[0 < n && group[0] >= 0 ? 0 : r];
        if (key[r] > hi) hi = key[r];
    }
    double loop = 4 * 0.4 * W;   /* the border's length in texels */
    SC_CHECK(one);
    SC_CHECK_MSG(hi > loop - 4 && hi <= loop + 1e-9, "places up to %g of %g", hi, loop);
    free(group), free(face), free(key);
    sc_seam_texset_free(&set);
    sc_seam_set_free(&s);
    sc_value *atlas = one_texture_atlas(m, noise_image(W, W, 3, SC_PIXEL_F32, -1), SC_WRAP_CLAMP);
    /* 5.2e-6 here, and 4.7e-6 with single-edge clusters as well: the
     * bound is the pillow's, not the chains' */
    schur_against_cholmod("pillow", atlas, "all", 1e-5);
    sc_value_release(atlas);
}

/* Solver auto on the edge-cluster solver (schur_from 0) whose iterations
 * cannot converge (one allowed) factors the whole system instead: the
 * fallback is reported and gives what solver cholmod gives, byte for byte;
 * solver schur under the same limit fails with a message. */
SC_TEST(node_auto_solver_falls_back_to_cholmod) {
    sc_value *atlas = one_texture_atlas(cube_mesh(17, true), noise_image(64, 64, 3, SC_PIXEL_F32, -1), SC_WRAP_REPEAT);
    const char *kv_auto[] = {"solver", "auto", "schur_from", "0", "pcg_iterations", "1", NULL};
    const char *kv_chol[] = {"solver", "cholmod", NULL};
    const char *kv_schur[] = {"solver", "schur", "pcg_iterations", "1", NULL};
    const char *kv_iter[] = {"solver", "auto", "schur_from", "0", NULL};
    sc_error err = {0};
    sc_ctx *a = run_erase(atlas, kv_auto, 2, &err), *c = run_erase(atlas, kv_chol, 2, &err);
    sc_ctx *it = run_erase(atlas, kv_iter, 2, &err);
    SC_CHECK_MSG(a && c && it, "cube: %s", err.message);
    if (a && c && it) {
        SC_CHECK(sc_ctx_metric_value(a, "solver_fallbacks") == 1);
        SC_CHECK(sc_digest_equal(sc_value_digest(sc_ctx_output(a, 0)), sc_value_digest(sc_ctx_output(c, 0))));
        SC_CHECK(sc_ctx_metric_value(it, "pcg_iterations") >= 2);   /* converged on its own */
        SC_CHECK(!(sc_ctx_metric_value(it, "solver_fallbacks") > 0));
    }
    sc_error serr = {0};
    sc_ctx *s = run_erase(atlas, kv_schur, 2, &serr);
    SC_CHECK(s == NULL && strstr(serr.message, "did not converge") != NULL);
    sc_ctx_free(a), sc_ctx_free(c), sc_ctx_free(it), sc_ctx_free(s);
    sc_value_release(atlas);
}

/* Two copies of one cube in one uv (as a geometry image of a mesh and its
 * levels has them): every texel lies in the cells of two edges, so the
 * edge-cluster solver would have no cluster (solver schur: every unknown is
 * interface) and solver auto factors the whole system instead, the same
 * bytes as solver cholmod, with no fallback to report. */
SC_TEST(node_auto_solver_takes_cholmod_without_clusters) {
    sc_mesh *cube = cube_mesh(17, true);
    const sc_mesh *two[2] = {cube, cube};
    sc_atlas *a = sc_atlas_new(sc_atlas_ops_mesh_union(two, 2));
    sc_mesh_free(cube);
    sc_atlas_add_texture(a, "color", 0, SC_WRAP_REPEAT, SC_WRAP_REPEAT, "",
                         sc_value_new_image(noise_image(64, 64, 3, SC_PIXEL_F32, -1)));
    sc_value *atlas = sc_value_new_atlas(a);
    const char *kv_auto[] = {"solver", "auto", "schur_from", "0", NULL};
    const char *kv_chol[] = {"solver", "cholmod", NULL};
    const char *kv_schur[] = {"solver", "schur", NULL};
    sc_error err = {0};
    sc_ctx *au = run_erase(atlas, kv_auto, 2, &err), *c = run_erase(atlas, kv_chol, 2, &err);
    sc_ctx *s = run_erase(atlas, kv_schur, 2, &err);
    SC_CHECK_MSG(au && c && s, "two cubes: %s", err.message);
    if (au && c && s) {
        printf("     two cubes in one uv: %g unknowns, %g of them interface for solver schur\n",
               sc_ctx_metric_value(s, "unknowns"), sc_ctx_metric_value(s, "interface_unknowns"));
        SC_CHECK(sc_ctx_metric_value(s, "interface_unknowns") == sc_ctx_metric_value(s, "unknowns"));
        SC_CHECK(isnan(sc_ctx_metric_value(au, "interface_unknowns")));
        SC_CHECK(!(sc_ctx_metric_value(au, "solver_fallbacks") > 0));
        SC_CHECK(sc_digest_equal(sc_value_digest(sc_ctx_output(au, 0)), sc_value_digest(sc_ctx_output(c, 0))));
        SC_CHECK(sc_ctx_metric_value(au, "seam_energy_after") <= 1e-6 * sc_ctx_metric_value(au, "seam_energy_before"));
    }
    sc_ctx_free(au), sc_ctx_free(c), sc_ctx_free(s);
    sc_value_release(atlas);
}

SC_TEST(corpus_boombox_schur_solver) {
    if (!sc_test_corpus()) {
        printf("     corpus absent: skipped\n");
        return;
    }
    sc_value *atlas = sc_test_load_corpus("BoomBox/BoomBox_welded.obj", NULL, NULL);
    if (atlas) schur_against_cholmod("BoomBox", atlas, "color", 2e-6);   /* 3.2e-6 without the refinement */
    sc_value_release(atlas);
}

static void corpus_check(const char *rel, const char *texture, const char *slots, bool expect_clean) {
    if (!sc_test_corpus()) {
        printf("     corpus absent: skipped %s\n", rel);
        return;
    }
    sc_value *atlas = sc_test_load_corpus(rel, texture, NULL);
    if (!atlas) return;
    const char *kv[] = {"textures", slots, NULL};
    sc_error err = {0};
    double t0 = sc_now();
    sc_ctx *ctx = run_erase(atlas, kv, 2, &err);
    double t1 = sc_now();
    SC_CHECK_MSG(ctx != NULL, "%s: %s", rel, err.message);
    if (!ctx) {
        sc_value_release(atlas);
        return;
    }
    const sc_atlas *a = atlas->as.atlas;
    const sc_atlas *o = sc_ctx_output(ctx, 0)->as.atlas;
    SC_CHECK_MSG(sc_ctx_metric_value(ctx, "textures_erased") >= 1, "%s: nothing erased", rel);
    double naive = sc_ctx_metric_value(ctx, "seam_energy_after_u8_naive");
    double opt = sc_ctx_metric_value(ctx, "seam_energy_after_u8_optimal");
    if (!isnan(naive)) {
        printf("     %s: 8-bit seam energy naive %.3g, optimal %.3g\n", rel, naive, opt);
        SC_CHECK_MSG(opt < naive, "%s: optimal rounding %g not below naive %g", rel, opt, naive);
    }
    for (int i = 0; i < a->ntex; i++) {
        if (o->textures[i].image == a->textures[i].image) continue;
        double b, af, g;
        ref_measure(atlas, ctx, 0, i, &b, &af, &g);
        printf("     %s %s: D %.3g -> %.3g, gap %.3g (%.2f s)\n", rel, a->textures[i].name, b, af, g, t1 - t0);
        /* the 8-bit result: every byte, shared texels included, within one step of the float one */
        const sc_image_data *f = out_image(ctx, 0, i), *q = out_image(ctx, 1, i);
        if (q->pixel == SC_PIXEL_U8) {
            double worst;
            size_t beyond = bytes_beyond_one_step(f, q, &worst);
            printf("     %s %s: bytes at most %.3f steps from the float result\n", rel, a->textures[i].name, worst);
            SC_CHECK_MSG(beyond == 0, "%s %s: %zu bytes a step or more from the float result (worst %.2f)", rel,
                         a->textures[i].name, beyond, worst);
        }
        char key[160];
        snprintf(key, sizeof key, "%s.tangent_space", a->textures[i].name);
        if (sc_ctx_metric_value(ctx, key) == 1) {
            /* tangent-space: what is continuous is the normal a renderer rebuilds */
            double mb, ma, xb, xa;
            snprintf(key, sizeof key, "%s.normal_gap_mean_before", a->textures[i].name), mb = sc_ctx_metric_value(ctx, key);
            snprintf(key, sizeof key, "%s.normal_gap_mean_after", a->textures[i].name), ma = sc_ctx_metric_value(ctx, key);
            snprintf(key, sizeof key, "%s.normal_gap_before", a->textures[i].name), xb = sc_ctx_metric_value(ctx, key);
            snprintf(key, sizeof key, "%s.normal_gap_after", a->textures[i].name), xa = sc_ctx_metric_value(ctx, key);
            printf("     %s %s (tangent-space): rendered normal gap mean %.4f -> %.4f, max %.4f -> %.4f\n", rel,
                   a->textures[i].name, mb, ma, xb, xa);
            SC_CHECK_MSG(ma < mb, "%s %s: mean rendered normal gap %g -> %g", rel, a->textures[i].name, mb, ma);
        } else if (expect_clean) {
            SC_CHECK_MSG(af <= 1e-6 * b, "%s %s: seam energy %g -> %g", rel, a->textures[i].name, b, af);
            SC_CHECK_MSG(g <= 1e-4, "%s %s: max gap %g", rel, a->textures[i].name, g);
        }
    }
    sc_ctx_free(ctx);
    sc_value_release(atlas);
}

SC_TEST(corpus_spot) { corpus_check("spot/spot_triangulated.obj", "spot/spot_texture.png", "all", true); }
SC_TEST(corpus_blub) { corpus_check("blub/blub.obj", "blub/blub_texture.png", "all", true); }
SC_TEST(corpus_avocado) { corpus_check("Avocado/Avocado.gltf", NULL, "color,normal", true); }
SC_TEST(corpus_boombox) { corpus_check("BoomBox/BoomBox_welded.obj", NULL, "all", true); }
/* mirrored and overlapping charts: erased as far as they can be, not held to the bar */
SC_TEST(corpus_murucat_two_materials) { corpus_check("MuruCat/MuruCat_welded.obj", NULL, "all", false); }

SC_TEST(corpus_suzanne_unchanged) {
    if (!sc_test_corpus()) {
        printf("     corpus absent: skipped\n");
        return;
    }
    sc_value *atlas = sc_test_load_corpus("Suzanne/Suzanne_welded.obj", NULL, NULL);
    if (!atlas) return;
    sc_error err = {0};
    sc_ctx *ctx = run_erase(atlas, NULL, 2, &err);
    SC_CHECK(ctx != NULL);
    if (ctx) {
        SC_CHECK(sc_ctx_output(ctx, 0) == atlas);
        SC_CHECK(sc_ctx_output(ctx, 1) == atlas);
    }
    sc_ctx_free(ctx);
    sc_value_release(atlas);
}

/* mirrored charts (94% of covered texels shared): every byte still within one step */
SC_TEST(corpus_duck_mirrored) { corpus_check("Duck/Duck_welded.obj", NULL, "all", false); }

SC_TEST(corpus_duck_shared_texels) {
    if (!sc_test_corpus()) {
        printf("     corpus absent: skipped\n");
        return;
    }
    sc_value *atlas = sc_test_load_corpus("Duck/Duck_welded.obj", NULL, NULL);
    if (!atlas) return;
    sc_error err = {0};
    sc_ctx *ctx = run_erase(atlas, NULL, 2, &err);
    SC_CHECK_MSG(ctx != NULL, "%s", err.message);
    if (ctx) {
        double frac = sc_ctx_metric_value(ctx, "shared_texel_fraction");
        printf("     Duck: shared %.3f, D %.3g -> %.3g\n", frac, sc_ctx_metric_value(ctx, "seam_energy_before"),
               sc_ctx_metric_value(ctx, "seam_energy_after"));
        SC_CHECK(frac > 0.5);
        SC_CHECK(sc_ctx_metric_value(ctx, "seam_energy_after") < sc_ctx_metric_value(ctx, "seam_energy_before"));
    }
    sc_ctx_free(ctx);
    sc_value_release(atlas);
}

int main(void) { return sc_test_main(); }

/* The rule sc_tangent_texels_build states, face by face in order: the
 * first face whose triangle holds a texel centre takes it; a texel none
 * holds takes the face strictly nearer than the one it has (the first
 * among equals) within the band, with the nearest point's barycentrics.
 * The arithmetic is the library's on purpose: the test compares owners and
 * barycentrics bit for bit, so it checks the order of the passes, not the
 * geometry. */
static bool ref_holds(const double x[3], const double y[3], double px, double py, double b[3]) {
    double d = (y[1] - y[2]) * (x[0] - x[2]) + (x[2] - x[1]) * (y[0] - y[2]);
    if (d == 0) return false;
    b[0] = ((y[1] - y[2]) * (px - x[2]) + (x[2] - x[1]) * (py - y[2])) / d;
    b[1] = ((y[2] - y[0]) * (px - x[2]) + (x[0] - x[2]) * (py - y[2])) / d;
    b[2] = 1 - b[0] - b[1];
    return b[0] >= 0 && b[1] >= 0 && b[2] >= 0;
}

static double ref_edge_distance2(const double x[3], const double y[3], double px, double py, double b[3]) {
    double best = INFINITY;
    for (int e = 0; e < 3; e++) {
        int i = e, j = (e + 1) % 3;
        double dx = x[j] - x[i], dy = y[j] - y[i], l2 = dx * dx + dy * dy;
        double s = l2 > 0 ? ((px - x[i]) * dx + (py - y[i]) * dy) / l2 : 0;
        s = s < 0 ? 0 : s > 1 ? 1 : s;
        double ex = x[i] + s * dx - px, ey = y[i] + s * dy - py, d2 = ex * ex + ey * ey;
        if (d2 < best) {
            best = d2;
            b[0] = b[1] = b[2] = 0;
            b[i] = 1 - s, b[j] = s;
        }
    }
    return best;
}

SC_TEST(tangent_texels_take_the_nearest_face_first_in_order) {
    /* faces on a lattice of texel centres (shared edges through texel
     * centres, ties everywhere), overlapping ones, and random ones */
    const int32_t W = 64, nf = 160;
    sc_mesh *m = sc_mesh_alloc(3 * nf, 3 * nf, 0, nf, 1);
    uint64_t seed = 99;
    for (int32_t f = 0; f < nf; f++)
        for (int k = 0; k < 3; k++) {
            seed = seed * 6364136223846793005ull + 1442695040888963407ull;
            double r = (double)(seed >> 11) / 9007199254740992.0;
            seed = seed * 6364136223846793005ull + 1442695040888963407ull;
            double q = (double)(seed >> 11) / 9007199254740992.0;
            bool lattice = f < nf / 2;
            double u = lattice ? (floor(r * 16) * 4 + 0.5) / W : r, v = lattice ? (floor(q * 16) * 4 + 0.5) / W : q;
            m->U[2 * (3 * f + k)] = u, m->U[2 * (3 * f + k) + 1] = v;
            m->V[3 * (3 * f + k)] = u, m->V[3 * (3 * f + k) + 1] = v, m->V[3 * (3 * f + k) + 2] = 0;
            m->FV[3 * f + k] = m->FU[3 * f + k] = 3 * f + k;
        }
    for (int32_t f = 0; f < nf; f++) m->FM[f] = 0;
    for (int w = 0; w < 2; w++) {
        sc_seam_grid g = {W, W, w ? SC_WRAP_REPEAT : SC_WRAP_CLAMP, w ? SC_WRAP_MIRROR : SC_WRAP_CLAMP};
        sc_tangent_texels tx;
        sc_error err = {0};
        SC_CHECK(sc_tangent_texels_build(m, 0, &g, 3.0, 2, &tx, &err) == SC_OK);
        int32_t *face = malloc(sizeof(int32_t) * W * W);
        float *dist = malloc(sizeof(float) * W * W), *bary = malloc(sizeof(float) * 2 * W * W);
        for (int32_t i = 0; i < W * W; i++) face[i] = -1, dist[i] = INFINITY;
        for (int32_t k = 0; k < 2 * nf; k++) {   /* every face for the texels it holds, then for the rest */
            const int32_t f = k % nf;
            const bool held_pass = k < nf;
            double x[3], y[3];
            for (int c = 0; c < 3; c++) {
                const double *U = m->U + 2 * m->FU[3 * f + c];
                x[c] = U[0] * W - 0.5, y[c] = U[1] * W - 0.5;
            }
            double x0 = fmin(x[0], fmin(x[1], x[2])) - 3, x1 = fmax(x[0], fmax(x[1], x[2])) + 3;
            double y0 = fmin(y[0], fmin(y[1], y[2])) - 3, y1 = fmax(y[0], fmax(y[1], y[2])) + 3;
            for (int64_t j = (int64_t)ceil(y0); j <= (int64_t)floor(y1); j++)
                for (int64_t i = (int64_t)ceil(x0); i <= (int64_t)floor(x1); i++) {
                    size_t id = (size_t)sc_seam_wrap(j, W, g.wrap_v) * W + sc_seam_wrap(i, W, g.wrap_u);
                    double b[3] = {1, 0, 0}, d2 = 0;
                    if (dist[id] == 0) continue;
                    if (held_pass && !ref_holds(x, y, (double)i, (double)j, b)) continue;
                    if (!held_pass && !ref_holds(x, y, (double)i, (double)j, b))
                        d2 = ref_edge_distance2(x, y, (double)i, (double)j, b);
                    if (d2 > 9 || !(d2 < dist[id])) continue;
                    dist[id] = (float)d2, face[id] = f, bary[2 * id] = (float)b[1], bary[2 * id + 1] = (float)b[2];
                }
        }
        int64_t differ = 0, held = 0;
        for (int32_t i = 0; i < W * W; i++) {
            held += face[i] >= 0;
            differ += face[i] != tx.face[i] ||
                      (face[i] >= 0 && memcmp(bary + 2 * i, tx.bary + 2 * i, 2 * sizeof(float)) != 0);
        }
        SC_CHECK_MSG(differ == 0 && held > W * W / 4, "wrap %d: %lld of %lld texels differ", w, (long long)differ,
                     (long long)held);
        free(face), free(dist), free(bary);
        sc_tangent_texels_free(&tx);
    }
    sc_mesh_free(m);
}
