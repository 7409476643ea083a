/* test_topology.c - the edge table (sc_topology): kinds of edges, Euler
 * characteristic, components and boundary loops.
 *
 * Every expected number comes from how the mesh is made, not from the
 * module: a closed cube has V - E + F = 8 - 18 + 12 = 2, one component and
 * no boundary; taking one face (two triangles) away leaves 8 - 17 + 10 = 1
 * and one hole; cutting the cube into one uv chart per face makes each of
 * its 12 edges a seam and leaves the 6 face diagonals inside their charts.
 */
#include <stdlib.h>

#include "sc_seam.h"
#include "sc_test.h"
#include "sc_topology.h"

/* The unit cube's faces as quads, outward counter-clockwise; vertex i is
 * (i & 1, (i >> 1) & 1, (i >> 2) & 1). */
static const int32_t cube_quads[6][4] = {
    {0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4}, {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5},
};

/* The cube without its last `open` quads. charts: one uv chart per quad (its
 * own four uv indices, side by side in a 3 x 2 grid); otherwise uv index =
 * vertex index, at the vertex's (x + z / 2, y + z / 2). */
static sc_mesh *cube(int open, bool charts) {
    int nq = 6 - open;
    sc_mesh *m = sc_mesh_alloc(8, charts ? 4 * nq : 8, 0, 2 * nq, 1);
    if (!m) return NULL;
    for (int i = 0; i < 8; i++) {
        m->V[3 * i] = i & 1, m->V[3 * i + 1] = (i >> 1) & 1, m->V[3 * i + 2] = (i >> 2) & 1;
        if (charts) continue;
        m->U[2 * i] = (i & 1) + 0.5 * ((i >> 2) & 1);
        m->U[2 * i + 1] = ((i >> 1) & 1) + 0.5 * ((i >> 2) & 1);
    }
    static const double square[4][2] = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};
    for (int q = 0; q < nq; q++) {
        int32_t uv[4];
        for (int k = 0; k < 4; k++) {
            uv[k] = charts ? 4 * q + k : cube_quads[q][k];
            if (charts) {
                m->U[2 * uv[k]] = (q % 3 + 0.1 + 0.8 * square[k][0]) / 3;
                m->U[2 * uv[k] + 1] = (q / 3 + 0.1 + 0.8 * square[k][1]) / 2;
            }
        }
        static const int tri[2][3] = {{0, 1, 2}, {0, 2, 3}};
        for (int t = 0; t < 2; t++)
            for (int k = 0; k < 3; k++) {
                m->FV[3 * (2 * q + t) + k] = cube_quads[q][tri[t][k]];
                m->FU[3 * (2 * q + t) + k] = uv[tri[t][k]];
            }
    }
    m->materials[0] = sc_strdup("cube");
    return m;
}

/* Two triangles on the quad (0,0) (1,0) (1,1) (0,1), split along 0-2. uv
 * index = vertex index at (x, y), except: `flip` puts the second triangle's
 * third corner (vertex 3) on the first one's side of the diagonal in uv;
 * `split` gives the second triangle its own uv indices 4, 5 for vertices 0
 * and 2, at the same coordinates. */
static sc_mesh *quad(bool flip, bool split) {
    sc_mesh *m = sc_mesh_alloc(4, split ? 6 : 4, 0, 2, 1);
    if (!m) return NULL;
    static const double xy[4][2] = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};
    for (int i = 0; i < 4; i++) {
        m->V[3 * i] = xy[i][0], m->V[3 * i + 1] = xy[i][1];
        m->U[2 * i] = xy[i][0], m->U[2 * i + 1] = xy[i][1];
    }
    if (flip) m->U[2 * 3] = 1, m->U[2 * 3 + 1] = 0.5;   /* right of 0 -> 2, as vertex 1 is */
    if (split) m->U[8] = 0, m->U[9] = 0, m->U[10] = 1, m->U[11] = 1;
    const int32_t FV[6] = {0, 1, 2, 0, 2, 3};
    const int32_t FU[6] = {0, 1, 2, split ? 4 : 0, split ? 5 : 2, 3};
    memcpy(m->FV, FV, sizeof FV);
    memcpy(m->FU, FU, sizeof FU);
    m->materials[0] = sc_strdup("quad");
    return m;
}

/* Every half-edge of the table's faces lies in exactly one edge, whose run
 * of half-edges it is in, and that edge joins the half-edge's two vertices. */
static void check_table(const sc_mesh *m, const sc_topology *t) {
    SC_CHECK(sc_mesh_check(m, NULL) == SC_OK);
    int32_t seen = 0;
    for (int32_t e = 0; e < t->nedges; e++) {
        const sc_topology_edge *d = &t->edges[e];
        SC_CHECK(d->v0 < d->v1);
        if (e > 0) SC_CHECK(t->edges[e - 1].v0 < d->v0 || (t->edges[e - 1].v0 == d->v0 && t->edges[e - 1].v1 < d->v1));
        SC_CHECK(d->count >= 1 && d->first == seen);
        for (int32_t k = 0; k < d->count; k++) {
            int32_t h = sc_topology_half(t, d, k), a = m->FV[h], b = m->FV[sc_topology_next(h)];
            SC_CHECK(t->edge_of[h] == e);
            SC_CHECK((a == d->v0 && b == d->v1) || (a == d->v1 && b == d->v0));
        }
        seen += d->count;
    }
    SC_CHECK(seen == t->nhalf);
}

static int32_t count_kind(const sc_topology *t, sc_edge_kind kind) {
    int32_t n = 0;
    for (int32_t e = 0; e < t->nedges; e++) n += t->edges[e].kind == kind;
    return n;
}

SC_TEST(closed_cube) {
    sc_mesh *m = cube(0, false);
    sc_topology t;
    SC_CHECK(sc_topology_build(m, NULL, &t, NULL) == SC_OK);
    check_table(m, &t);
    SC_CHECK(t.nedges == 18 && t.nhalf == 36);
    SC_CHECK(t.euler == 2);
    SC_CHECK(t.components == 1);
    SC_CHECK(t.boundary_loops == 0);
    SC_CHECK(t.nboundary == 0 && t.nnonmanifold == 0 && t.nseams == 0);
    sc_topology_free(&t);
    sc_mesh_free(m);
}

SC_TEST(open_cube_has_one_boundary_loop) {
    sc_mesh *m = cube(1, false);
    sc_topology t;
    SC_CHECK(sc_topology_build(m, NULL, &t, NULL) == SC_OK);
    check_table(m, &t);
    SC_CHECK(t.nedges == 17);
    SC_CHECK(t.euler == 1);
    SC_CHECK(t.components == 1);
    SC_CHECK(t.boundary_loops == 1);
    SC_CHECK(t.nboundary == 4 && count_kind(&t, SC_EDGE_BOUNDARY) == 4);
    /* the hole is the removed face's square x = 1: vertices 1, 3, 7, 5 */
    for (int32_t e = 0; e < t.nedges; e++)
        if (t.edges[e].kind == SC_EDGE_BOUNDARY) SC_CHECK((t.edges[e].v0 & 1) && (t.edges[e].v1 & 1));
    sc_topology_free(&t);
    sc_mesh_free(m);
}

SC_TEST(two_triangles_are_two_components) {
    sc_mesh *m = sc_mesh_alloc(6, 6, 0, 2, 1);
    for (int i = 0; i < 6; i++) {
        m->V[3 * i] = i % 3 == 1, m->V[3 * i + 1] = i % 3 == 2, m->V[3 * i + 2] = i / 3;
        m->U[2 * i] = m->V[3 * i] + 2 * (i / 3), m->U[2 * i + 1] = m->V[3 * i + 1];
    }
    for (int k = 0; k < 6; k++) m->FV[k] = m->FU[k] = k;
    m->materials[0] = sc_strdup("pair");
    sc_topology t;
    SC_CHECK(sc_topology_build(m, NULL, &t, NULL) == SC_OK);
    check_table(m, &t);
    SC_CHECK(t.nedges == 6 && t.nboundary == 6);
    SC_CHECK(t.euler == 2);   /* 6 - 6 + 2: two discs */
    SC_CHECK(t.components == 2);
    SC_CHECK(t.boundary_loops == 2);
    sc_topology_free(&t);
    sc_mesh_free(m);
}

SC_TEST(cube_in_six_charts_has_twelve_seams) {
    sc_mesh *m = cube(0, true);
    for (int by_coordinates = 0; by_coordinates < 2; by_coordinates++) {
        sc_topology t;
        sc_topology_options opt = {.material = -1, .uv_by_coordinates = by_coordinates};
        SC_CHECK(sc_topology_build(m, &opt, &t, NULL) == SC_OK);
        check_table(m, &t);
        /* the charts lie apart in uv: coordinates tell the same as indices */
        SC_CHECK(t.nseams == 12 && count_kind(&t, SC_EDGE_SEAM) == 12);
        for (int32_t e = 0; e < t.nedges; e++) {
            /* a cube edge joins vertices one coordinate apart, a diagonal two */
            int32_t diff = t.edges[e].v0 ^ t.edges[e].v1;
            bool cube_edge = diff == 1 || diff == 2 || diff == 4;
            SC_CHECK(t.edges[e].kind == (cube_edge ? SC_EDGE_SEAM : SC_EDGE_INTERIOR));
        }
        /* uv cuts leave the surface as it is */
        SC_CHECK(t.euler == 2 && t.components == 1 && t.boundary_loops == 0 && t.nboundary == 0);
        sc_topology_free(&t);
    }
    /* the seam operator sees the same seams, both sides of each a silhouette */
    sc_seam_set s;
    SC_CHECK(sc_seam_find(m, -1, &s, NULL) == SC_OK);
    SC_CHECK(s.nseams == 12 && s.nsil == 24 && s.nboundary == 0 && s.nfoldover == 0);
    sc_seam_set_free(&s);
    sc_mesh_free(m);
}

SC_TEST(flipped_uv_triangle_is_a_foldover) {
    for (int flip = 0; flip < 2; flip++) {
        sc_mesh *m = quad(flip, false);
        sc_topology t;
        SC_CHECK(sc_topology_build(m, NULL, &t, NULL) == SC_OK);
        check_table(m, &t);
        SC_CHECK(t.nedges == 5 && t.nboundary == 4);
        SC_CHECK(t.nfoldover == flip && count_kind(&t, SC_EDGE_FOLDOVER) == flip);
        SC_CHECK(count_kind(&t, SC_EDGE_INTERIOR) == 1 - flip);
        int32_t e = t.edge_of[0 * 3 + 2];   /* face 0's half-edge 2 -> 0: the diagonal */
        SC_CHECK(t.edges[e].v0 == 0 && t.edges[e].v1 == 2);
        SC_CHECK(t.edges[e].kind == (flip ? SC_EDGE_FOLDOVER : SC_EDGE_INTERIOR));
        SC_CHECK(t.euler == 1 && t.components == 1 && t.boundary_loops == 1);
        sc_topology_free(&t);
        sc_mesh_free(m);
    }
}

SC_TEST(equal_uv_coordinates_are_one_uv_by_option) {
    sc_mesh *m = quad(false, true);
    sc_topology t;
    SC_CHECK(sc_topology_build(m, NULL, &t, NULL) == SC_OK);
    SC_CHECK(t.nseams == 1);   /* by index (docs/design.md): the diagonal's sides use 0, 2 and 4, 5 */
    sc_topology_free(&t);
    sc_topology_options opt = {.material = -1, .uv_by_coordinates = true};
    SC_CHECK(sc_topology_build(m, &opt, &t, NULL) == SC_OK);
    SC_CHECK(t.nseams == 0 && t.nfoldover == 0 && count_kind(&t, SC_EDGE_INTERIOR) == 1);
    sc_topology_free(&t);
    sc_mesh_free(m);
}

SC_TEST(three_faces_on_an_edge_are_non_manifold) {
    /* a fan of three triangles on edge 0-1, third corners 2, 3, 4 */
    sc_mesh *m = sc_mesh_alloc(5, 5, 0, 3, 1);
    const double V[15] = {0, 0, 0, 1, 0, 0, 0.5, 1, 0, 0.5, -1, 0, 0.5, 0, 1};
    memcpy(m->V, V, sizeof V);
    for (int i = 0; i < 5; i++) m->U[2 * i] = V[3 * i], m->U[2 * i + 1] = V[3 * i + 1] + V[3 * i + 2];
    const int32_t F[9] = {0, 1, 2, 1, 0, 3, 0, 1, 4};
    memcpy(m->FV, F, sizeof F);
    memcpy(m->FU, F, sizeof F);
    m->materials[0] = sc_strdup("fan");
    sc_topology t;
    SC_CHECK(sc_topology_build(m, NULL, &t, NULL) == SC_OK);
    check_table(m, &t);
    SC_CHECK(t.nedges == 7);
    SC_CHECK(t.nnonmanifold == 1 && t.nboundary == 6);
    int32_t e = t.edge_of[0];
    SC_CHECK(t.edges[e].kind == SC_EDGE_NONMANIFOLD && t.edges[e].count == 3);
    SC_CHECK(t.euler == 1);   /* 5 - 7 + 3 */
    SC_CHECK(t.components == 1);
    SC_CHECK(t.boundary_loops == 1);   /* the six boundary edges meet at 0 and 1 */
    sc_topology_free(&t);
    sc_mesh_free(m);
}

SC_TEST(material_selects_faces) {
    /* the cube with its first quad (z = 0, two triangles) in material 1 */
    sc_mesh *m = cube(0, false), *two = sc_mesh_alloc(m->nv, m->nu, 0, m->nf, 2);
    memcpy(two->V, m->V, sizeof(double) * 3 * (size_t)m->nv);
    memcpy(two->U, m->U, sizeof(double) * 2 * (size_t)m->nu);
    memcpy(two->FV, m->FV, sizeof(int32_t) * 3 * (size_t)m->nf);
    memcpy(two->FU, m->FU, sizeof(int32_t) * 3 * (size_t)m->nf);
    for (int32_t f = 0; f < m->nf; f++) two->FM[f] = f < 2;
    two->materials[0] = sc_strdup("sides"), two->materials[1] = sc_strdup("bottom");
    sc_topology t;
    sc_topology_options opt = {.material = 1};
    SC_CHECK(sc_topology_build(two, &opt, &t, NULL) == SC_OK);
    check_table(two, &t);
    /* a square of two triangles: 4 - 5 + 2 */
    SC_CHECK(t.material == 1 && t.nhalf == 6 && t.nedges == 5 && t.nboundary == 4);
    SC_CHECK(t.euler == 1 && t.components == 1 && t.boundary_loops == 1);
    for (int32_t h = 6; h < 3 * two->nf; h++) SC_CHECK(t.edge_of[h] == -1);
    sc_topology_free(&t);
    sc_mesh_free(two);
    sc_mesh_free(m);
}

int main(void) { return sc_test_main(); }
