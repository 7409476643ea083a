/* sc_hausdorff.c - sampled symmetric Hausdorff distance through a BVH.
 *
 * Design note. The BVH is a binary tree over triangle indices, built by
 * splitting at the median centroid along the longest axis of the centroid
 * bounds (nth_element-style partition, so building is O(n log n) and the
 * tree is deterministic). The partition moves (centroid, index) records
 * side by side rather than indices into a centroid array, and an inner
 * box is the union of its children's, which keeps building cheap (decimate
 * builds one per run; docs/notes/decimate.md). Leaves
 * hold up to four triangles (two or more, as splits start at five, so
 * nf + 1 nodes suffice). A query walks the tree depth first, nearer child
 * first, and prunes boxes that are farther than the best distance so far.
 * Samples are visited in order along each
 * triangle, so the face closest to the previous sample is passed on as a
 * seed: its distance bounds the search from the start and most boxes are
 * never opened (the distance found is the same; only work is saved). A
 * caller that measures several meshes against one (the levels of a
 * decimation against their input) builds that mesh's BVH once. A caller
 * that only needs a maximum of distances (sc_hausdorff_bvh_closest_above)
 * lets the walk stop at the first face within the maximum found so far.
 *
 * Sampling is split into fixed chunks of triangles (independent of the
 * thread count); each chunk records its maximum and its sum, and the chunks
 * are combined in order, so the mean too is the same bytes for any number of
 * threads. The sample spacing is derived from the mesh area and the
 * requested count: each triangle gets the barycentric grid of resolution
 * r = ceil(sqrt(area / area_per_sample)) (its vertices, points along its
 * edges and inside), and every vertex is sampled once more on its own.
 */
#include "sc_hausdorff.h"

#include <math.h>
#include <pthread.h>
#include <stdlib.h>
#include <string.h>

#include "sc_geometry.h"

const sc_kernel sc_kernel_hausdorff = {"hausdorff", SC_HAUSDORFF_VERSION, NULL};

#define LEAF_SIZE 4
#define CHUNK_FACES 512
#define MAX_GRID 2048

typedef struct bvh_node {
    double lo[3], hi[3];
    int32_t first, count;   /* leaf: triangle range in order[]; inner: count = 0 */
    int32_t left, right;    /* inner: children */
} bvh_node;

struct sc_hausdorff_bvh {
    const sc_hausdorff_mesh *mesh;
    bvh_node *nodes;
    int32_t nnodes;
    int32_t *order;          /* per reference: its face */
    double *ref_box;         /* per reference: lo[3], hi[3] (a piece of its face, or all of it) */
    bool split;              /* thin faces were cut into pieces (build_split) */
};

static const double *corner(const sc_hausdorff_mesh *m, int32_t f, int k) { return m->V + 3 * m->F[3 * f + k]; }

/* A reference while the tree is built: its centroid, face and box side by
 * side, so partitioning reads memory in order. */
typedef struct build_item {
    double c[3];
    int32_t f;
    double lo[3], hi[3];
} build_item;

static void bounds_of(const build_item *it, int32_t first, int32_t count, double lo[3], double hi[3]) {
    for (int k = 0; k < 3; k++) lo[k] = INFINITY, hi[k] = -INFINITY;
    for (int32_t i = first; i < first + count; i++)
        for (int k = 0; k < 3; k++) {
            if (it[i].lo[k] < lo[k]) lo[k] = it[i].lo[k];
            if (it[i].hi[k] > hi[k]) hi[k] = it[i].hi[k];
        }
}

/* Partition items[lo, hi) so the median (by centroid along axis, ties by
 * triangle index) sits at `mid`: quickselect with a deterministic middle
 * pivot. */
static bool item_less(const build_item *x, const build_item *y, int axis) {
    return x->c[axis] < y->c[axis] || (x->c[axis] == y->c[axis] && x->f < y->f);
}

static void select_median(build_item *it, int axis, int32_t lo, int32_t hi, int32_t mid) {
    while (hi - lo > 1) {
        build_item pivot = it[lo + (hi - lo) / 2];
        int32_t i = lo, j = hi - 1;
        while (i <= j) {
            while (item_less(&it[i], &pivot, axis)) i++;
            while (item_less(&pivot, &it[j], axis)) j--;
            if (i <= j) {
                build_item t = it[i];
                it[i] = it[j];
                it[j] = t;
                i++, j--;
            }
        }
        if (mid <= j) hi = j + 1;
        else if (mid >= i) lo = i;
        else return;
    }
}

static int32_t build_node(sc_hausdorff_bvh *b, build_item *it, int32_t first, int32_t count) {
    int32_t id = b->nnodes++;
    bvh_node *n = &b->nodes[id];
    n->first = first;
    n->count = count;
    n->left = n->right = -1;
    if (count <= LEAF_SIZE) {
        for (int32_t i = first; i < first + count; i++) {
            b->order[i] = it[i].f;
            memcpy(b->ref_box + 6 * (size_t)i, it[i].lo, sizeof it[i].lo);
            memcpy(b->ref_box + 6 * (size_t)i + 3, it[i].hi, sizeof it[i].hi);
        }
        bounds_of(it, first, count, n->lo, n->hi);
        return id;
    }
    double clo[3] = {INFINITY, INFINITY, INFINITY}, chi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (int32_t i = first; i < first + count; i++)
        for (int k = 0; k < 3; k++) {
            double c = it[i].c[k];
            if (c < clo[k]) clo[k] = c;
            if (c > chi[k]) chi[k] = c;
        }
    int axis = 0;
    for (int k = 1; k < 3; k++)
        if (chi[k] - clo[k] > chi[axis] - clo[axis]) axis = k;
    int32_t half = count / 2;
    select_median(it, axis, first, first + count, first + half);
    int32_t left = build_node(b, it, first, half);
    int32_t right = build_node(b, it, first + half, count - half);
    n = &b->nodes[id];   /* not moved: nodes are preallocated */
    n->count = 0;
    n->left = left;
    n->right = right;
    for (int k = 0; k < 3; k++) {   /* the union of the children's boxes: the box of all its triangles */
        n->lo[k] = fmin(b->nodes[left].lo[k], b->nodes[right].lo[k]);
        n->hi[k] = fmax(b->nodes[left].hi[k], b->nodes[right].hi[k]);
    }
    return id;
}

static void piece_item(build_item *it, int32_t f, const double *const p[3]) {
    it->f = f;
    for (int k = 0; k < 3; k++) {
        it->c[k] = (p[0][k] + p[1][k] + p[2][k]) / 3.0;
        it->lo[k] = fmin(p[0][k], fmin(p[1][k], p[2][k]));
        it->hi[k] = fmax(p[0][k], fmax(p[1][k], p[2][k]));
    }
}

/* Whether a piece is a sliver across its box: its area under a quarter of
 * the box's largest face, and longer than `shortest`. */
static bool thin(const double *const p[3], double shortest) {
    double lo[3], hi[3], e[3], n[3];
    for (int k = 0; k < 3; k++) {
        lo[k] = fmin(p[0][k], fmin(p[1][k], p[2][k]));
        hi[k] = fmax(p[0][k], fmax(p[1][k], p[2][k]));
        e[k] = hi[k] - lo[k];
    }
    double face = fmax(e[0] * e[1], fmax(e[1] * e[2], e[0] * e[2]));
    sc_triangle_normal(p[0], p[1], p[2], n);
    double area = 0.5 * sqrt(sc_dot3(n, n));
    return sqrt(sc_dot3(e, e)) > shortest && area < 0.25 * face;
}

/* Face f as pieces (up to 2^depth): a sliver is cut at the midpoint of its
 * longest edge, each half again while it is one. `it` NULL: only counts
 * them. Corners of the pieces are kept in `mid` (three per cut). */
static int32_t add_pieces(build_item *it, int32_t f, const double *const p[3], int depth, double shortest,
                          double *mid, int32_t *nmid) {
    if (depth == 0 || !thin(p, shortest)) {
        if (it) piece_item(it, f, p);
        return 1;
    }
    int longest = 0;
    double best = -1;
    for (int k = 0; k < 3; k++) {
        double d[3];
        sc_sub3(p[(k + 1) % 3], p[k], d);
        if (sc_dot3(d, d) > best) best = sc_dot3(d, d), longest = k;
    }
    double *m = mid + 3 * (*nmid)++;
    for (int k = 0; k < 3; k++) m[k] = 0.5 * (p[longest][k] + p[(longest + 1) % 3][k]);
    const double *a = p[longest], *b = p[(longest + 1) % 3], *c = p[(longest + 2) % 3];
    const double *left[3] = {a, m, c}, *right[3] = {m, b, c};
    int32_t n = add_pieces(it, f, left, depth - 1, shortest, mid, nmid);
    return n + add_pieces(it ? it + n : NULL, f, right, depth - 1, shortest, mid, nmid);
}

/* Pieces of every face at this depth (it NULL: the count). */
static int64_t all_pieces(const sc_hausdorff_mesh *m, build_item *it, int depth, double shortest, double *mid) {
    int64_t n = 0;
    for (int32_t f = 0; f < m->nf; f++) {
        const double *p[3] = {corner(m, f, 0), corner(m, f, 1), corner(m, f, 2)};
        int32_t nmid = 0;
        n += add_pieces(it ? it + n : NULL, f, p, depth, shortest, mid, &nmid);
    }
    return n;
}

#define SPLIT_DEPTH 6    /* up to 64 pieces a face ... */
#define SPLIT_BUDGET 8    /* ... and up to 8 references a face in all: the depth falls until they fit */

/* The tree over every face whole, or (split) with thin faces in pieces, so
 * that long slivers meeting at one vertex (a fan) do not all overlap every
 * query. Distances are to whole faces either way: the same results. */
static sc_hausdorff_bvh *build(const sc_hausdorff_mesh *m, bool split) {
    if (!m || m->nf <= 0) return NULL;
    sc_hausdorff_bvh *b = calloc(1, sizeof *b);
    if (!b) return NULL;
    b->mesh = m;
    b->split = split;
    double area = 0;
    for (int32_t f = 0; split && f < m->nf; f++) {
        double n[3];
        sc_triangle_normal(corner(m, f, 0), corner(m, f, 1), corner(m, f, 2), n);
        area += 0.5 * sqrt(sc_dot3(n, n));
    }
    double shortest = 2 * sqrt(area / m->nf);   /* pieces stay longer than twice a typical face */
    double mid[3 << SPLIT_DEPTH];
    int depth = split ? SPLIT_DEPTH : 0;
    int64_t nref = all_pieces(m, NULL, depth, shortest, mid);
    while (depth > 0 && nref > (int64_t)SPLIT_BUDGET * m->nf) nref = all_pieces(m, NULL, --depth, shortest, mid);
    build_item *items = nref < INT32_MAX ? sc_alloc_array((size_t)nref, sizeof *items) : NULL;
    b->order = items ? sc_alloc_array((size_t)nref, sizeof *b->order) : NULL;
    b->ref_box = items ? sc_alloc_array((size_t)nref * 6, sizeof *b->ref_box) : NULL;
    /* splits happen from 5 references up, so every leaf holds 2 or more
     * (or the single reference of a one-face mesh): nref + 1 nodes suffice */
    b->nodes = items ? sc_alloc_array((size_t)nref + 1, sizeof *b->nodes) : NULL;
    if (!items || !b->order || !b->ref_box || !b->nodes) {
        free(items);
        sc_hausdorff_bvh_free(b);
        return NULL;
    }
    all_pieces(m, items, depth, shortest, mid);
    build_node(b, items, 0, (int32_t)nref);
    free(items);
    return b;
}

sc_hausdorff_bvh *sc_hausdorff_bvh_build(const sc_hausdorff_mesh *m) { return build(m, false); }

void sc_hausdorff_bvh_free(sc_hausdorff_bvh *b) {
    if (!b) return;
    free(b->order);
    free(b->ref_box);
    free(b->nodes);
    free(b);
}

static double sub_dot(const double a[3], const double b[3], const double c[3]) {
    return (a[0] - b[0]) * c[0] + (a[1] - b[1]) * c[1] + (a[2] - b[2]) * c[2];
}

static void closest_on_segment(const double p[3], const double a[3], const double b[3], double out[3]) {
    double ab[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
    double len2 = ab[0] * ab[0] + ab[1] * ab[1] + ab[2] * ab[2];
    double t = len2 > 0 ? sub_dot(p, a, ab) / len2 : 0;
    t = t < 0 ? 0 : t > 1 ? 1 : t;
    for (int k = 0; k < 3; k++) out[k] = a[k] + t * ab[k];
}

void sc_hausdorff_closest_on_triangle(const double p[3], const double a[3], const double b[3],
                                      const double c[3], double out[3]) {
    double ab[3], ac[3], ap[3];
    for (int k = 0; k < 3; k++) ab[k] = b[k] - a[k], ac[k] = c[k] - a[k], ap[k] = p[k] - a[k];
    double d1 = ab[0] * ap[0] + ab[1] * ap[1] + ab[2] * ap[2];
    double d2 = ac[0] * ap[0] + ac[1] * ap[1] + ac[2] * ap[2];
    if (d1 <= 0 && d2 <= 0) {
        memcpy(out, a, sizeof(double) * 3);
        return;
    }
    double d3 = sub_dot(p, b, ab), d4 = sub_dot(p, b, ac);   /* ab.bp, ac.bp */
    if (d3 >= 0 && d4 <= d3) {
        memcpy(out, b, sizeof(double) * 3);
        return;
    }
    double vc = d1 * d4 - d3 * d2;
    if (vc <= 0 && d1 >= 0 && d3 <= 0) {
        double v = d1 / (d1 - d3);
        for (int k = 0; k < 3; k++) out[k] = a[k] + v * ab[k];
        return;
    }
    double d5 = sub_dot(p, c, ab), d6 = sub_dot(p, c, ac);
    if (d6 >= 0 && d5 <= d6) {
        memcpy(out, c, sizeof(double) * 3);
        return;
    }
    double vb = d5 * d2 - d1 * d6;
    if (vb <= 0 && d2 >= 0 && d6 <= 0) {
        double w = d2 / (d2 - d6);
        for (int k = 0; k < 3; k++) out[k] = a[k] + w * ac[k];
        return;
    }
    double va = d3 * d6 - d5 * d4;
    if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {
        double w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        for (int k = 0; k < 3; k++) out[k] = b[k] + w * (c[k] - b[k]);
        return;
    }
    double total = va + vb + vc;
    if (!(total > 0)) {   /* degenerate triangle: the nearest of its edges */
        const double *ends[3][2] = {{a, b}, {b, c}, {c, a}};
        double best = INFINITY;
        for (int e = 0; e < 3; e++) {
            double q[3];
            closest_on_segment(p, ends[e][0], ends[e][1], q);
            double d = (q[0] - p[0]) * (q[0] - p[0]) + (q[1] - p[1]) * (q[1] - p[1]) + (q[2] - p[2]) * (q[2] - p[2]);
            if (d < best) best = d, memcpy(out, q, sizeof q);
        }
        return;
    }
    double v = vb / total, w = vc / total;
    for (int k = 0; k < 3; k++) out[k] = a[k] + ab[k] * v + ac[k] * w;
}

static double box_distance2(const bvh_node *n, const double p[3]) {
    double d = 0;
    for (int k = 0; k < 3; k++) {
        double e = p[k] < n->lo[k] ? n->lo[k] - p[k] : p[k] > n->hi[k] ? p[k] - n->hi[k] : 0;
        d += e * e;
    }
    return d;
}

/* Squared distance from p to reference i's box. */
static double ref_distance2(const sc_hausdorff_bvh *b, int32_t i, const double p[3]) {
    const double *lo = b->ref_box + 6 * (size_t)i, *hi = lo + 3;
    double d = 0;
    for (int k = 0; k < 3; k++) {
        double e = p[k] < lo[k] ? lo[k] - p[k] : p[k] > hi[k] ? p[k] - hi[k] : 0;
        d += e * e;
    }
    return d;
}

static double point_triangle2(const sc_hausdorff_mesh *m, int32_t f, const double p[3], double q[3]) {
    sc_hausdorff_closest_on_triangle(p, corner(m, f, 0), corner(m, f, 1), corner(m, f, 2), q);
    return (q[0] - p[0]) * (q[0] - p[0]) + (q[1] - p[1]) * (q[1] - p[1]) + (q[2] - p[2]) * (q[2] - p[2]);
}

/* The query, started from a face known to be near (seed >= 0): its distance
 * bounds the search from the start, so far fewer boxes are opened. The
 * distance found is the same with or without a seed. The walk stops as soon
 * as a face within `enough` (squared) is found (enough < 0: never). */
static double closest_seeded_until(const sc_hausdorff_bvh *b, const double p[3], int32_t seed, double enough,
                                   double closest[3], int32_t *face) {
    double best = INFINITY, best_point[3] = {0, 0, 0};
    int32_t best_face = -1;
    if (seed >= 0 && seed < b->mesh->nf) {
        best = point_triangle2(b->mesh, seed, p, best_point);
        best_face = seed;
    }
    /* each stacked node carries its box distance, computed once */
    int32_t stack[128];
    double stack_d[128];
    int top = 0;
    stack[top] = 0;
    stack_d[top++] = box_distance2(&b->nodes[0], p);
    while (top > 0 && best > enough) {
        --top;
        if (stack_d[top] >= best) continue;
        const bvh_node *n = &b->nodes[stack[top]];
        if (n->count > 0) {
            for (int32_t i = n->first; i < n->first + n->count; i++) {
                int32_t f = b->order[i];
                if (b->split && (f == best_face || ref_distance2(b, i, p) >= best)) continue;
                double q[3];
                double d = point_triangle2(b->mesh, f, p, q);
                if (d < best || (d == best && f < best_face)) {
                    best = d;
                    best_face = f;
                    memcpy(best_point, q, sizeof q);
                }
            }
            continue;
        }
        double dl = box_distance2(&b->nodes[n->left], p), dr = box_distance2(&b->nodes[n->right], p);
        if (top + 2 > (int)(sizeof stack / sizeof stack[0])) continue;   /* depth ~ log2(n): never */
        /* the nearer child goes on top; a child already too far is not stacked */
        int32_t near = dl < dr ? n->left : n->right, far = dl < dr ? n->right : n->left;
        double dn = dl < dr ? dl : dr, df = dl < dr ? dr : dl;
        if (df < best) stack[top] = far, stack_d[top++] = df;
        if (dn < best) stack[top] = near, stack_d[top++] = dn;
    }
    if (closest) memcpy(closest, best_point, sizeof best_point);
    if (face) *face = best_face;
    return best;
}

static double closest_seeded(const sc_hausdorff_bvh *b, const double p[3], int32_t seed, double closest[3],
                             int32_t *face) {
    return closest_seeded_until(b, p, seed, -1, closest, face);
}

double sc_hausdorff_bvh_closest(const sc_hausdorff_bvh *b, const double p[3], double closest[3],
                                int32_t *face) {
    return closest_seeded(b, p, -1, closest, face);
}

double sc_hausdorff_bvh_closest_above(const sc_hausdorff_bvh *b, const double p[3], double floor2, int32_t seed,
                                      int32_t *face) {
    if (seed >= b->mesh->nf) seed = -1;
    return closest_seeded_until(b, p, seed, floor2, NULL, face);
}

static double triangle_area(const sc_hausdorff_mesh *m, int32_t f) {
    double n[3];
    sc_triangle_normal(corner(m, f, 0), corner(m, f, 1), corner(m, f, 2), n);
    return 0.5 * sc_norm3(n);
}

/* ---------------------------------------------------------------- one direction */

typedef struct side_job {
    const sc_hausdorff_mesh *from;
    const sc_hausdorff_bvh *to;
    double area_per_sample;
    const unsigned char *used;   /* vertices faces use */
    int32_t nchunks;
    double *chunk_max, *chunk_sum;
    int64_t *chunk_count;
    int32_t next;                /* next chunk to take (under lock) */
    pthread_mutex_t lock;
} side_job;

/* One sample; *seed carries the face found for the previous (nearby) sample. */
static void sample_point(const side_job *j, const double p[3], int32_t *seed, double *mx, double *sum,
                         int64_t *count) {
    double d = sqrt(closest_seeded(j->to, p, *seed, NULL, seed));
    if (d > *mx) *mx = d;
    *sum += d;
    (*count)++;
}

/* Chunk c < nchunks - 1 covers faces [c * CHUNK_FACES, ...); the last chunk
 * samples the vertices the faces use. */
static void run_chunk(side_job *j, int32_t c) {
    const sc_hausdorff_mesh *m = j->from;
    double mx = 0, sum = 0;
    int64_t count = 0;
    int32_t seed = -1;
    if (c == j->nchunks - 1) {   /* every vertex a face uses, once, in index order */
        for (int32_t v = 0; v < m->nv; v++)
            if (j->used[v]) sample_point(j, m->V + 3 * v, &seed, &mx, &sum, &count);
    } else {
        int32_t f0 = c * CHUNK_FACES, f1 = f0 + CHUNK_FACES < m->nf ? f0 + CHUNK_FACES : m->nf;
        for (int32_t f = f0; f < f1; f++) {
            double area = triangle_area(m, f);
            double rr = j->area_per_sample > 0 ? ceil(sqrt(area / j->area_per_sample)) : 1;
            int r = rr < 1 ? 1 : rr > MAX_GRID ? MAX_GRID : (int)rr;
            const double *a = corner(m, f, 0), *b = corner(m, f, 1), *cc = corner(m, f, 2);
            for (int i = 0; i <= r; i++)
                for (int k = 0; k + i <= r; k++) {
                    if ((i == 0 && k == 0) || (i == r) || (k == r)) continue;   /* the corners come with the vertices */
                    double s = (double)i / r, t = (double)k / r;
                    double p[3];
                    for (int d = 0; d < 3; d++) p[d] = a[d] + s * (b[d] - a[d]) + t * (cc[d] - a[d]);
                    sample_point(j, p, &seed, &mx, &sum, &count);
                }
        }
    }
    j->chunk_max[c] = mx;
    j->chunk_sum[c] = sum;
    j->chunk_count[c] = count;
}

static void *worker(void *ud) {
    side_job *j = ud;
    for (;;) {
        pthread_mutex_lock(&j->lock);
        int32_t c = j->next < j->nchunks ? j->next++ : -1;
        pthread_mutex_unlock(&j->lock);
        if (c < 0) return NULL;
        run_chunk(j, c);
    }
}

static int one_side(const sc_hausdorff_mesh *from, const sc_hausdorff_bvh *to, int64_t samples, int threads,
                    double *max_out, double *mean_out, int64_t *count_out, sc_error *err) {
    side_job j;
    memset(&j, 0, sizeof j);
    j.from = from;
    j.to = to;
    double area = 0;
    for (int32_t f = 0; f < from->nf; f++) area += triangle_area(from, f);
    /* a grid of resolution r has about r^2/2 samples: aim for `samples` */
    j.area_per_sample = samples > 0 ? 2.0 * area / (double)samples : 0;
    j.nchunks = (from->nf + CHUNK_FACES - 1) / CHUNK_FACES + 1;
    j.chunk_max = calloc((size_t)j.nchunks, sizeof(double));
    j.chunk_sum = calloc((size_t)j.nchunks, sizeof(double));
    j.chunk_count = calloc((size_t)j.nchunks, sizeof(int64_t));
    unsigned char *used = calloc((size_t)from->nv + 1, 1);
    if (!j.chunk_max || !j.chunk_sum || !j.chunk_count || !used) {
        free(j.chunk_max), free(j.chunk_sum), free(j.chunk_count), free(used);
        return sc_fail(err, SC_ENOMEM, "hausdorff: out of memory");
    }
    for (int64_t i = 0; i < (int64_t)from->nf * 3; i++) used[from->F[i]] = 1;
    j.used = used;
    pthread_mutex_init(&j.lock, NULL);
    if (threads < 1) threads = 1;
    if (threads > 64) threads = 64;
    if (threads > j.nchunks) threads = j.nchunks;
    pthread_t tid[64];
    int started = 0;
    for (int t = 1; t < threads; t++)
        if (pthread_create(&tid[started], NULL, worker, &j) == 0) started++;
    worker(&j);
    for (int t = 0; t < started; t++) pthread_join(tid[t], NULL);
    pthread_mutex_destroy(&j.lock);
    double mx = 0, sum = 0;
    int64_t count = 0;
    for (int32_t c = 0; c < j.nchunks; c++) {
        if (j.chunk_max[c] > mx) mx = j.chunk_max[c];
        sum += j.chunk_sum[c];
        count += j.chunk_count[c];
    }
    free(j.chunk_max), free(j.chunk_sum), free(j.chunk_count), free(used);
    *max_out = mx;
    *mean_out = count ? sum / (double)count : 0;
    *count_out = count;
    return SC_OK;
}

int sc_hausdorff(const sc_hausdorff_mesh *a, const sc_hausdorff_mesh *b, int64_t samples, int threads,
                 sc_hausdorff_result *out, sc_error *err) {
    return sc_hausdorff_with_bvh(a, NULL, b, samples, threads, out, err);
}

int sc_hausdorff_with_bvh(const sc_hausdorff_mesh *a, const sc_hausdorff_bvh *a_bvh, const sc_hausdorff_mesh *b,
                          int64_t samples, int threads, sc_hausdorff_result *out, sc_error *err) {
    memset(out, 0, sizeof *out);
    if (a->nf <= 0 || b->nf <= 0) return sc_fail(err, SC_EINPUT, "hausdorff: a mesh has no faces");
    if (a_bvh && a_bvh->mesh->nf != a->nf) return sc_fail(err, SC_EINPUT, "hausdorff: the BVH is not of mesh a");
    sc_hausdorff_bvh *owned = a_bvh && a_bvh->split ? NULL : build(a, true), *bb = build(b, true);
    const sc_hausdorff_bvh *ba = a_bvh && a_bvh->split ? a_bvh : owned;
    if (!ba || !bb) {
        sc_hausdorff_bvh_free(owned);
        sc_hausdorff_bvh_free(bb);
        return sc_fail(err, SC_ENOMEM, "hausdorff: out of memory");
    }
    int rc = one_side(a, bb, samples, threads, &out->a_to_b, &out->mean_a_to_b, &out->samples_a, err);
    if (rc == SC_OK) rc = one_side(b, ba, samples, threads, &out->b_to_a, &out->mean_b_to_a, &out->samples_b, err);
    out->distance = out->a_to_b > out->b_to_a ? out->a_to_b : out->b_to_a;
    sc_hausdorff_bvh_free(owned);
    sc_hausdorff_bvh_free(bb);
    return rc;
}
