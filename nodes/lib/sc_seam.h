/* sc_seam.h - texture seams: finding them, sampling across them, and the
 * exact seam operator of Liu et al. 2017 ("Seamless", §3-4).
 *
 * Texel convention (docs/design.md, shared with the renderer): texel (i, j) has
 * its centre at ((i + 1/2)/W, (j + 1/2)/H) in uv; row j = 0 is v = 0; pixel
 * memory is row-major from that bottom row. We work in *texel space*
 *     x = u W - 1/2,   y = v H - 1/2,
 * where texel centres are the integer lattice, a bilinear cell is a unit
 * square [cx, cx+1] x [cy, cy+1] with corner texels (cx, cy), (cx+1, cy),
 * (cx, cy+1), (cx+1, cy+1) taken through the wrap mode (repeat, clamp to
 * edge, mirrored repeat: the GL rules), and s = x - cx, t = y - cy.
 *
 * Vocabulary (docs/design.md, defined once in sc_topology.h):
 *   seam edge            a surface edge whose two half-edges use different uv
 *                        indices. The seams here are those of the edge table
 *                        built with uv_by_coordinates: sides that differ only
 *                        in their indices sample the same texels, so they
 *                        are no seam to erase.
 *   uv silhouette edge   a boundary edge of the parameter mesh: both sides of
 *                        every seam, surface boundaries, uv foldovers and
 *                        non-manifold edges.
 *
 * All of it is per material: a texture belongs to one material, and only the
 * faces of that material are seen.
 */
#ifndef SC_SEAM_H
#define SC_SEAM_H

#include "sc_sparse.h"
#include "sc_topology.h"
#include "sc_value.h"

/* Bump whenever results of this library can change for the same inputs:
 * every node listing sc_kernel_seam (or a kernel built on it) is re-keyed. */
#define SC_SEAM_VERSION 1
extern const sc_kernel sc_kernel_seam;

/* ---------------------------------------------------------------- sampling */

typedef struct sc_seam_grid {
    int32_t width, height;
    sc_wrap wrap_u, wrap_v;
} sc_seam_grid;

/* Texel index i (any integer) taken into [0, n) by the wrap mode (inline:
 * per-texel loops call it). */
static inline int32_t sc_seam_wrap(int64_t i, int32_t n, sc_wrap w) {
    if (n <= 1) return 0;
    if (w == SC_WRAP_CLAMP) return i < 0 ? 0 : i >= n ? n - 1 : (int32_t)i;
    if (w == SC_WRAP_MIRROR) {
        int64_t p = 2 * (int64_t)n, m = i % p;
        if (m < 0) m += p;
        return (int32_t)(m >= n ? p - 1 - m : m);
    }
    int64_t m = i % n;
    return (int32_t)(m < 0 ? m + n : m);
}

/* The four bilinear taps of uv: texel ids (j * W + i) and weights, in the
 * order (cx, cy), (cx+1, cy), (cx, cy+1), (cx+1, cy+1). Ids may repeat (clamp,
 * 1-texel-wide images); the weights always sum to 1. */
void sc_seam_taps(const sc_seam_grid *g, double u, double v, int32_t id[4], double w[4]);

/* Bilinear sample of a float image (channels interleaved) at uv into out[c]. */
void sc_seam_sample(const sc_seam_grid *g, const float *pixels, int32_t channels, double u,
                    double v, double *out);

/* ---------------------------------------------------------------- topology */

/* One side of an edge: a half-edge of `face`, with the uv indices it uses at
 * the edge's two surface vertices, and the uv index of the face's third
 * corner (which tells on which side the face lies). */
typedef struct sc_seam_side {
    int32_t face;
    int32_t uv0, uv1, uv_opp;
} sc_seam_side;

/* A seam edge: surface vertices v0 -> v1, both sides parametrised the same
 * way (gamma = 0 at v0, 1 at v1), and the 3D length l_e of eq. 9. */
typedef struct sc_seam_edge {
    int32_t v0, v1;
    double length;
    sc_seam_side side[2];
} sc_seam_edge;

typedef enum sc_seam_kind {
    SC_SEAM_SIDE = 0,        /* one side of a seam edge */
    SC_SEAM_BOUNDARY = 1,    /* surface boundary (one face in this material) */
    SC_SEAM_FOLDOVER = 2,    /* uv foldover */
    SC_SEAM_NONMANIFOLD = 3, /* one of three or more faces on a surface edge */
} sc_seam_kind;

typedef struct sc_seam_silhouette {
    int32_t v0, v1;          /* in the orientation of its face (or of its seam) */
    double length;
    sc_seam_side side;
    sc_seam_kind kind;
    int32_t seam;            /* index into seams for SC_SEAM_SIDE, else -1 */
} sc_seam_silhouette;

typedef struct sc_seam_set {
    int32_t material;        /* -1: all faces */
    int32_t nseams;
    sc_seam_edge *seams;
    int32_t nsil;
    sc_seam_silhouette *sil;
    int32_t nboundary, nfoldover, nnonmanifold;
    double seam_length;      /* L of eq. 9: sum of seam 3D edge lengths */
    double sil_length;       /* the same over silhouette half-edges (E_lerp, E_outside) */
} sc_seam_set;

/* Find the seams and uv silhouettes among the faces of `material` (-1: all):
 * sc_seam_from_topology on the edge table of those faces, uvs by coordinates.
 * Deterministic: seams are ordered by (min vertex, max vertex). */
int sc_seam_find(const sc_mesh *m, int32_t material, sc_seam_set *out, sc_error *err);
/* The seams and uv silhouettes of an edge table already built (its material
 * and its view of uvs); a seam runs v0 -> v1 as its first half-edge does. */
int sc_seam_from_topology(const sc_mesh *m, const sc_topology *t, sc_seam_set *out, sc_error *err);
void sc_seam_set_free(sc_seam_set *s);

/* ---------------------------------------------------------------- texel sets */

/* A set of texels of a W x H grid with O(1) membership and rank (the index of
 * a texel among the members in raster order), in ~1.5 bits per texel. */
typedef struct sc_seam_texset {
    int32_t width, height;
    int64_t words;
    uint64_t *bits;
    int32_t *rank;           /* members before each 64-bit word (after finish) */
    int32_t count;           /* members (after finish) */
} sc_seam_texset;

int sc_seam_texset_init(sc_seam_texset *s, int32_t width, int32_t height);
void sc_seam_texset_free(sc_seam_texset *s);
static inline void sc_seam_texset_add(sc_seam_texset *s, int32_t id) {
    s->bits[id >> 6] |= (uint64_t)1 << (id & 63);
}
static inline bool sc_seam_texset_has(const sc_seam_texset *s, int32_t id) {
    return (s->bits[id >> 6] >> (id & 63)) & 1;
}
/* Compute ranks; call once after the last add. */
int sc_seam_texset_finish(sc_seam_texset *s);
/* Set bits of x. */
static inline int32_t sc_seam_popcount64(uint64_t x) {
    x = x - ((x >> 1) & 0x5555555555555555ull);
    x = (x & 0x3333333333333333ull) + ((x >> 2) & 0x3333333333333333ull);
    x = (x + (x >> 4)) & 0x0f0f0f0f0f0f0f0full;
    return (int32_t)((x * 0x0101010101010101ull) >> 56);
}
/* Rank of a member, -1 for a non-member (inline: assembly asks it for
 * every texel of every piece). */
static inline int32_t sc_seam_texset_index(const sc_seam_texset *s, int32_t id) {
    uint64_t word = s->bits[id >> 6], bit = (uint64_t)1 << (id & 63);
    if (!(word & bit)) return -1;
    return s->rank[id >> 6] + sc_seam_popcount64(word & (bit - 1));
}
/* Texel id of the member of rank r (linear in the number of words; use
 * sc_seam_texset_members for all of them). */
int sc_seam_texset_members(const sc_seam_texset *s, int32_t **ids);

/* ---------------------------------------------------------------- coverage */

/* Texel centres inside the uv triangles of one material (top-left fill rule,
 * so triangles that only touch never share a texel), taken through the wrap
 * mode. covered: at least one face; shared: two or more faces (mirrored or
 * overlapping charts, foldovers, uvs wrapping onto other charts). */
typedef struct sc_seam_coverage {
    sc_seam_texset covered, shared;
    int64_t ncovered, nshared;
} sc_seam_coverage;

int sc_seam_coverage_build(const sc_mesh *m, int32_t material, const sc_seam_grid *g, int threads,
                           sc_seam_coverage *out, sc_error *err);
void sc_seam_coverage_free(sc_seam_coverage *c);

/* The share of m's surface area on faces whose uv have no area: missing uv
 * (loaded as (0, 0)) or a triangle squashed to a segment or a point, under
 * a millionth of the mesh's mean uv area per unit of surface. Such a face
 * holds no texel of its own, so no map can hold its points, and coverage
 * does not see it (its triangle contains no texel centre). 0 for a mesh
 * without surface area. */
double sc_seam_degenerate_uv_fraction(const sc_mesh *m);

/* Where two uv charts reach the same texel through their bilinear taps: a
 * texel is reached by a face when a point of its uv triangle lies less than
 * one texel from the texel's centre in u and in v (the point's four taps
 * include it), taken through the wrap modes; chart[f] names face f's chart.
 * Such a texel would have to hold the surface of both charts, so a map of
 * this grid cannot be right there for either. Faces of zero uv area reach
 * nothing (a rasteriser draws none of their points). Chart ids are >= 0.
 * *reached: texels some chart reaches; *met: texels two or more charts
 * reach. */
int sc_seam_taps_meet(const sc_mesh *m, int32_t material, const sc_seam_grid *g, const int32_t *chart,
                      int64_t *reached, int64_t *met, sc_error *err);

/* ---------------------------------------------------------------- pieces */

/* The splitting of eq. 5: the sorted parameters gamma in [0, 1] (0 and 1
 * included) where segment a (and segment b, when given) cross a texel-grid
 * line x or y = integer in texel space. Both segments are given in uv,
 * a0 -> a1 and b0 -> b1, parametrised by the same gamma. Returns the count
 * (>= 2) or -1 when the segments cross more than SC_SEAM_MAX_CROSSINGS lines.
 * *buf is grown as needed (free it when done). */
#define SC_SEAM_MAX_CROSSINGS (1 << 22)
int32_t sc_seam_crossings(const sc_seam_grid *g, const double a0[2], const double a1[2],
                          const double *b0, const double *b1, double **buf, int32_t *cap);

/* Bilinear reconstruction along the part of segment uv a -> b that lies in a
 * single cell, as quadratics in tau in [0, 1]:
 *     B(tau) = sum_k (q[k][0] + q[k][1] tau + q[k][2] tau^2) p[id[k]]      (eq. 2)
 * and its derivative along the texel-space unit vector n:
 *     dB/dn(tau) = sum_k (d[k][0] + d[k][1] tau) p[id[k]]. */
typedef struct sc_seam_cellpoly {
    int32_t id[4];
    double q[4][3];
    double d[4][2];
} sc_seam_cellpoly;

void sc_seam_cellpoly_make(const sc_seam_grid *g, const double a[2], const double b[2],
                           const double n[2], sc_seam_cellpoly *out);

/* The inward unit normal of a side in texel space (towards its face's third
 * corner); false when the side or its face is degenerate in uv. */
bool sc_seam_inward_normal(const sc_mesh *m, const sc_seam_grid *g, const sc_seam_side *s,
                           double n[2]);

/* ---------------------------------------------------------------- operators */

/* Which texels the operators touch: the four corners of every bilinear cell
 * a uv silhouette edge passes through (eq. 5 splitting). Adds to `set`, and
 * those of the seam edges alone to `seam_set` (may be NULL). */
int sc_seam_mark_texels(const sc_mesh *m, const sc_seam_set *s, const sc_seam_grid *g,
                        sc_seam_texset *set, sc_seam_texset *seam_set, int threads, sc_error *err);

/* Which seam chain each texel of `index` belongs to, for solvers that
 * eliminate the texels along a chain together. Seam edges join into chains
 * end to end, two at a time at a surface vertex where both go on in the
 * same two charts. group[r] is the chain (named by its first edge,
 * 0..nseams-1) or nseams + the silhouette whose cells alone reach texel r
 * (-1 when the cells of two or more chains or silhouettes reach it, or
 * none); gamma[r] is where the first piece that reaches it lies: along its
 * chain, in texels of the longer side from the chain's start (both sides
 * of a seam share it), or a silhouette's edge parameter; face[r] is the
 * face of that piece's side (-1 when none). */
int sc_seam_texel_groups(const sc_mesh *m, const sc_seam_set *s, const sc_seam_grid *g,
                         const sc_seam_texset *index, int32_t *group, double *gamma,
                         int32_t *face, sc_error *err);

/* sc_parallel (sc_base.h) under its older name. */

/* The terms of Liu et al. §3-4 over the texels of `index` (a texel outside
 * it is an error), each a quadratic E(x) = x^T Q x + linear + constant per
 * channel:
 *   w_seam    * (1/L) sum_e l_e D(e1, e2)                 (eq. 3-9)
 *   w_c1      * (1/L) sum_e l_e E_C1(e1, e2)              (§4.1)
 *   w_outside * (1/L') sum_s l_s E_outside(s)             (§4.1)
 *   w_lerp    * (1/L') sum_s l_s E_lerp(s)                (§4.1)
 * All integrals are exact (closed form over the pieces of eq. 5); L is the
 * total seam length, L' the total silhouette length; E_C1 uses derivatives
 * per texel along the texel-space unit inward normals.
 * With `out`, Q's triplets join it, list after list (in a fixed order for
 * any thread count). With `rhs` (index->count x channels, one column per
 * channel), the residual r = -1/2 grad E at p0 is added to it, term by term
 * and without forming Q p0 (seam differences are taken before they are
 * weighted, so a seam-free p0 gives an exact zero); the correction
 * d = x - p0 then solves Q d = r. E_outside is minimal at p0 and adds
 * nothing; E_lerp needs vertex_values (nv x channels). */
typedef struct sc_seam_terms {
    double w_seam, w_c1, w_outside, w_lerp;
    const sc_image_data *p0;      /* the texels the residual is taken at */
    const double *vertex_values;  /* nv x channels, for E_lerp */
    double *rhs;                  /* or NULL */
} sc_seam_terms;

int sc_seam_assemble(const sc_mesh *m, const sc_seam_set *s, const sc_seam_grid *g,
                     const sc_seam_texset *index, const sc_seam_terms *terms, int threads,
                     sc_triplet_parts *out, sc_error *err);

/* Seam discontinuity of an image (eq. 9, summed over channels), exactly, and
 * the largest |B(e1) - B(e2)| of any channel sampled at 5 points of every
 * piece. Either output may be NULL. */
int sc_seam_energy(const sc_mesh *m, const sc_seam_set *s, const sc_seam_grid *g,
                   const sc_image_data *img, int threads, double *energy, double *max_gap,
                   sc_error *err);

/* Channels of img equal to an earlier channel at every texel (a grey image
 * stored as RGB): src[c] is that channel, or -1 (channels from
 * SC_SEAM_MAX_CHANNELS on are never matched). Returns the number of
 * channels that are not copies. */
#define SC_SEAM_MAX_CHANNELS 4
int32_t sc_seam_same_channels(const sc_image_data *img, int32_t src[SC_SEAM_MAX_CHANNELS]);

/* The same for `count` images (at most SC_SEAM_ENERGY_IMAGES) of one grid,
 * in one pass over the pieces: energy[i] and max_gap[i] (either may be NULL)
 * are those sc_seam_energy gives image i, to the bit. */
#define SC_SEAM_ENERGY_IMAGES 4
int sc_seam_energies(const sc_mesh *m, const sc_seam_set *s, const sc_seam_grid *g,
                     const sc_image_data *const *imgs, int count, int threads, double *energy,
                     double *max_gap, sc_error *err);

/* The same, with image i's sRGB colour channels (alpha excepted) measured
 * in linear light where decode[i] (decode NULL: none): the energies of
 * sc_image_to_linear_f32(imgs[i]) to the bit, each tap decoded as it is
 * read instead of the whole image first. */
int sc_seam_energies_decoded(const sc_mesh *m, const sc_seam_set *s, const sc_seam_grid *g,
                             const sc_image_data *const *imgs, const bool *decode, int count, int threads,
                             double *energy, double *max_gap, sc_error *err);

/* The trace of the normalised seam operator M of eq. 9 (the sum of its
 * diagonal over all texels), exactly. */
int sc_seam_trace(const sc_mesh *m, const sc_seam_set *s, const sc_seam_grid *g, int threads,
                  double *trace, sc_error *err);

/* D(e1, e2) of one seam edge (eq. 3, not normalised), exactly. */
double sc_seam_edge_energy(const sc_mesh *m, const sc_seam_edge *e, const sc_seam_grid *g,
                           const sc_image_data *img);

/* Texel `id`, channel c of an image of any pixel type, as in sc_image_texel
 * (inline: the energies read it for every tap of every piece). */
static inline double sc_seam_texel(const sc_image_data *img, int32_t id, int32_t c) {
    size_t k = (size_t)id * (size_t)img->channels + (size_t)c;
    switch (img->pixel) {
    case SC_PIXEL_U8: return ((const uint8_t *)img->pixels)[k] * (1.0f / 255.0f);
    case SC_PIXEL_U16: return ((const uint16_t *)img->pixels)[k] * (1.0f / 65535.0f);
    default: return ((const float *)img->pixels)[k];
    }
}

/* How an image's texels are read: as stored, or with its sRGB colour
 * channels (alpha excepted) decoded to linear light as they are read (a
 * table for 8 and 16 bits), the values sc_image_to_linear_f32 gives, to the
 * bit, without converting the whole image. */
typedef struct sc_seam_reader {
    float *table;                          /* u8/u16 decoded: stored value -> linear light; else NULL */
    bool decode[SC_SEAM_MAX_CHANNELS];     /* per channel: through the sRGB curve */
    bool any;                              /* some channel is */
} sc_seam_reader;

/* The reader of img: decoded when `decode` and img is SC_COLOR_SRGB, else as
 * stored. false when out of memory. Free with sc_seam_reader_free. */
bool sc_seam_reader_make(const sc_image_data *img, bool decode, sc_seam_reader *r);
void sc_seam_reader_free(sc_seam_reader *r);

static inline double sc_seam_read(const sc_image_data *img, const sc_seam_reader *r, int32_t id, int32_t c) {
    if (!r->any || c >= SC_SEAM_MAX_CHANNELS || !r->decode[c]) return sc_seam_texel(img, id, c);
    size_t k = (size_t)id * (size_t)img->channels + (size_t)c;
    switch (img->pixel) {
    case SC_PIXEL_U8: return r->table[((const uint8_t *)img->pixels)[k]];
    case SC_PIXEL_U16: return r->table[((const uint16_t *)img->pixels)[k]];
    default: return sc_srgb_to_linear(((const float *)img->pixels)[k]);
    }
}

/* Bilinear sample of img, read through r, at uv into out[c]: sc_seam_sample
 * of the image r reads, to the bit. */
void sc_seam_sample_read(const sc_seam_grid *g, const sc_image_data *img, const sc_seam_reader *r, double u,
                         double v, double *out);

/* ---------------------------------------------------------------- threads */

/* sc_parallel (sc_base.h) under its older name. */
int sc_seam_parallel(int threads, int32_t nchunks, int (*fn)(void *ud, int32_t chunk), void *ud);

#endif
