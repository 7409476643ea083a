/* render.c - the node `render`: draws every LOD headless in every mode and
 * proves, on the pictures and on the GPU's own numbers, that nothing cracks.
 *
 * Design note.
 *  - Context: one EGL/OpenGL 4.5 core context per run (sc_gl), made current
 *    on the calling worker thread and destroyed before returning, so runs on
 *    several threads never share GL state (only the EGL display, see
 *    sc_gl.c). Mesa's llvmpipe renders the same bytes for the same inputs,
 *    so the pictures are part of the output value.
 *  - Modes (a "pass" is one mode at one tessellation level):
 *      textured        base positions, colour texture, lit;
 *      geometry_image  positions fetched in the vertex stage from the texture
 *                      slot "geometry_image" at each vertex's uv;
 *      displaced       base position + slot "displacement" at the vertex uv;
 *      tessellated<L>  TCS/TES at uniform level L (tess_levels), the TES
 *                      sampling the geometry image (or, without one, adding
 *                      the displacement) at every generated vertex. The
 *                      pass is tessellated once, its triangles captured with
 *                      transform feedback and drawn from every view
 *                      (llvmpipe evaluates tessellation on one thread; the
 *                      captured floats give the same pictures).
 *    A tessellated pass other than the lowest level whose triangles outnumber
 *    a view's pixels (max_triangles_per_pixel) is probed, not drawn, when
 *    max_seam_gap is at or under the rasteriser's vertex grid and
 *    max_map_fold_pixels is off (probe_suffices): its seam gap is measured
 *    at its own tessellated points and bounded like any pass's, where its
 *    views draw sixteen triangles to a pixel at level 8 on a few thousand
 *    faces (lod<k>.<pass>.drawn says which were drawn).
 *    Every pass colours with the "color" slot when the material has one. A
 *    mode whose texture a material lacks is skipped, with the metric
 *    lod<k>.<mode>.skipped = 1. All sampling is bilinear without mipmaps, in
 *    the wrap mode of each texture, with docs/design.md's texel convention (which
 *    is GL's: uvs go to the GPU untouched and images go up bottom row first).
 *  - Seam gap, "what the hardware really computed": per pass, every seam edge
 *    (sc_seam_find) is evaluated on both of its sides and captured with
 *    transform feedback. Untessellated passes: seam_points points per side at
 *    the same parameters t, each placed by seam_vs.glsl with the very
 *    function (sc_surface) the render's vertex stage uses, with that side's
 *    uvs; t = 0 and 1 are the vertices themselves. Tessellated passes: the
 *    faces along seams are drawn as patches through the render program itself
 *    with rasterisation off; the TES outputs (position, tessellation
 *    coordinate, patch) are sorted onto their seam sides and each point is
 *    paired with the other side's point of nearest edge parameter. The gap is
 *    the largest distance between paired points over the level's
 *    bounding-box diagonal; max_vertex_gap is the same at t = 0 and 1 only.
 *    Beside it, for the passes whose positions come from maps,
 *    lod<k>.<pass>.map_seam_gap is the gap the maps themselves hold at the
 *    same parameters, each side sampled in double at its exact uv: the GPU's
 *    gap less the rounding of its own sampling (float32 uvs, its filtering),
 *    which grows with how steeply a map changes across a chart's border. A
 *    failing max_seam_gap names both.
 *  - Crack pixels: front faces shaded, back faces pure red, no culling; the
 *    alpha channel tells background (0), front (1) and back faces (1/2)
 *    apart, so a red texture never counts. A closed mesh (no boundary, no
 *    non-manifold edge) shows back faces only through cracks - and, now and
 *    then, on occluding contours, where the front and back sheets meet at
 *    sub-pixel distance and rasterisation can let a pixel of the back one
 *    through (a ray cast there in double precision hits neither sheet). So a
 *    back-face pixel next to the background or to a farther front face (3 x
 *    3, from the depth buffer) is not counted: through a crack the back face
 *    seen lies behind every front face around it. A crack along a contour is
 *    counted in the views where it is not one. For an open mesh, the
 *    `reference` mesh is drawn from the same views and a back-face pixel
 *    counts only when no back face of the reference lies within 2 pixels of
 *    it (silhouettes of holes move a little between LODs). Without a
 *    reference, every back-face pixel of an open mesh counts.
 *  - Pinholes: seam-free maps still leave the two sides of a seam apart by
 *    float rounding (about 1e-7 of the diagonal), and the rasteriser snaps
 *    vertices to a grid of 2^-GL_SUBPIXEL_BITS pixels (llvmpipe: 8 bits): two
 *    sides a rounding apart now and then land on neighbouring grid points,
 *    and a pixel centre in the sliver between shows the back face. When a
 *    pass's measured seam gap is above 0 (equal vertices rasterise
 *    watertight: the textured mode's gap is 0) and below one grid step, a
 *    crack pixel alone among its 8 neighbours and within a pixel of a seam
 *    side as the GPU placed it (the points the seam-gap check captured,
 *    projected) is counted as lod<k>.<pass>.pinhole_pixels, not as a crack;
 *    any larger gap keeps every such pixel a crack, as does a back-face pixel
 *    away from seams or next to another (a fold, a real crack, or a sliver
 *    along a seam that runs through a row of pixel centres: visible as a
 *    line). The main job's test (main_job_lod_chain) holds such a pinhole.
 *  - Folds: a position map can fold the surface over itself (thin fins in a
 *    coarse geometry image of a coarse level), and the back faces of a fold
 *    away from a contour look like a crack. When a position pass's seam gap
 *    is under a pixel and a view has crack pixels, the view is drawn again
 *    welded (SC_WELD in the shaders: every corner of a vertex samples the map
 *    at one uv, its first corner's, and every point on a seam edge at the
 *    edge's side-0 uvs, blended from the same products on both faces, so no
 *    seam can open; corner_data). A crack pixel that shows a back face in the
 *    welded picture too is lod<k>.<pass>.fold_pixels, not a crack: welding
 *    moved nothing by more than the gap, under a pixel, so the two pictures
 *    differ only where a seam opens. When the gap is also under the
 *    rasteriser's vertex grid, a crack pixel beside a back face of the welded
 *    picture is a fold pixel too: welding moved the fold's edge by less than
 *    a grid step, enough to turn the depth test at a pixel where the folded
 *    sheets cross, and a seam that narrow opens no more than a lone pixel
 *    (a pinhole, told apart above). A wider gap is not welded: moving a
 *    seam's sides by more than a pixel can fold a strip along it. A pass
 *    whose seam gap is exactly 0 (every side at the same vertices: the
 *    textured pass) of a level whose topology is the reference's (Euler
 *    characteristic, components, boundary loops and non-manifold edges over
 *    the faces' vertex indices: lod<k>.same_topology) has no seam open and no
 *    hole the reference lacks, so nothing to see through: its back-face
 *    pixels are fold_pixels too. Decimation keeps topology (its link
 *    conditions), and its coarse levels do fold: a thin open sheet tipped
 *    over the silhouette, a ring pushed through the body next to it. A split
 *    or a hole changes the topology (test_render: split_mesh_shows_cracks),
 *    and those back faces stay cracks.
 *  - Views: orthographic, all framing one bounding sphere (the box of every
 *    level's and the reference's vertices, each also where the position modes
 *    draw it: the geometry image at its uv, itself plus the displacement
 *    there: drawn positions only, not the longest vector anywhere in the
 *    displacement maps, whose gutter and fill texels would widen the views
 *    and shrink the asset to a few pixels), so a view is the same camera for
 *    every LOD, mode and the reference. 6 axis views (posx ... negz), then
 *    the cube's corners (obl0 ... obl7), then a Fibonacci sphere. Depth
 *    clamping keeps displaced geometry from being cut open by the near or far
 *    plane.
 *  - Output: a REPORT with one contact sheet render/lod<k>_sheet.png per LOD
 *    (of a mip chain, lod<k>_mip0_sheet.png, and lod<k>_mip<m>_sheet.png
 *    only for a level that shows cracks, or folds with max_map_fold_pixels
 *    set, or with pictures = all)
 *    (rows: passes in order, columns: views; each crack pixel marked with a
 *    yellow and each fold pixel with a cyan 3x3 square, so one pixel shows at
 *    thumbnail size), render/reference_sheet.png (the reference's textured
 *    views, when one is given), render/lod<k>_<pass>_<view>.png
 *    for each view with crack pixels (every view with pictures = all),
 *    render/lod<k>_uv.png (the colour texture with the level's uv
 *    silhouettes over it: seams red, boundaries yellow, foldovers magenta;
 *    lod<k>_uv_<material>.png with several materials; none with
 *    uv_pictures = 0),
 *    render/reference_<view>.png when a reference is given (pictures = all), and the
 *    deterministic metrics. Shading works in linear light, as an engine's:
 *    sRGB colour textures are sampled through sRGB formats (decoded before
 *    filtering) and the target encodes to sRGB on write, so the seams and
 *    gaps measured are those a renderer filtering sRGB textures shows, and
 *    the pictures look as displayed. PNGs are encoded (sc_imageio) on up to 4 worker
 *    threads (sc_ctx_threads) while GL draws the next picture, and go into
 *    the report in submission order, so the bytes never depend on the thread
 *    count. Timings are node metrics only (seconds_*), never part of the
 *    value.
 *  - Limits: max_crack_pixels bounds lod<k>.<pass>.crack_pixels (the sum over
 *    views), max_fold_pixels lod<k>.textured.fold_pixels, the folds of the
 *    level's own vertices, which decimation makes (by default, with a
 *    reference, fold_allowance = 2 times the reference's own back-face
 *    pixels: a decimated cloth collapsed through itself shows thousands, an
 *    open reference some of its own), max_map_fold_pixels those of the
 *    passes whose positions come from maps (a geometry image's bilinear
 *    cells fold where the map is too coarse for a thin part: another
 *    defect, so another gate, off by default) and max_seam_gap
 *    lod<k>.<pass>.max_seam_gap; the first pass over a limit fails the node
 *    with the LOD, the mode (and for cracks the view). Folds and cracks are
 *    separate gates: one never passes for the other.
 *  - Texture seams: lod<k>.seam_energy.<slot> and lod<k>.seam_gap.<slot> are
 *    every texture's exact seam energy (eq. 9) and sampled gap on the level's
 *    own seams (sc_seam_energy), so a colour seam that pictures only show is
 *    also a number an expectation can bound.
 *  - Mip levels: consecutive entries of `lods` with the same mesh whose
 *    textures halve (the mipmap node's `levels`) are the mip chain of one
 *    LOD; they are named lod<k>.mip<m> in metrics and lod<k>_mip<m> in files.
 * Measurements and history: docs/notes/render.md.
 */
#include <math.h>
#include <pthread.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "sc_atlas_ops.h"
#include "sc_geometry.h"
#include "sc_gl.h"
#include "sc_imageio.h"
#include "sc_nodes.h"
#include "sc_seam.h"
#include "sc_shaders.h"
#include "sc_topology.h"

#define MAX_TESS_LEVELS 16
#define MAX_PASSES (3 + MAX_TESS_LEVELS)
#define REFERENCE_SLACK 2      /* pixels of tolerance around reference back faces */
#define SHEET_THUMB 128        /* contact-sheet thumbnails are at most this wide */
#define SHEET_GAP 2
#define EDGE_COORD_EPS 1e-6f   /* a tessellation coordinate this small is on an edge */
#define CORNER_FLOATS 11       /* per face corner: x y z, u v, the welded pass's uvs (corner_data) */

enum { POS_BASE = 0, POS_GEOMETRY = 1, POS_DISPLACED = 2 };
enum { MODE_TEXTURED, MODE_GEOMETRY, MODE_DISPLACED, MODE_TESSELLATED, MODE_COUNT };
static const char *const mode_names[MODE_COUNT] = {"textured", "geometry_image", "displaced",
                                                   "tessellated"};

static const uint8_t background[3] = {38, 42, 48};

typedef struct pass {
    int mode;          /* MODE_* */
    int pos;           /* POS_* */
    int level;         /* tessellation level, 0 for none */
    char name[32];     /* "textured", "tessellated4" */
    bool probe_only;   /* its seam gap measured and bounded, no view drawn (finer than the pixels) */
} pass;

typedef struct view {
    char name[16];
    float view_proj[16];   /* column-major */
    float light[3], eye[3];
} view;

/* Textures of one material, as bound for a draw. */
typedef struct material_gl {
    GLuint color, geometry, displacement;
    GLuint color_sampler, geometry_sampler, displacement_sampler;
} material_gl;

typedef struct group {
    int32_t material, first, count;   /* in vertices (corners) */
} group;

/* Where a seam side sits in its face. */
typedef struct seam_corner {
    int32_t k0, k1, k2;   /* corners of v0, v1 and the third vertex */
} seam_corner;

/* The seam sides of one pass as the GPU placed them: one polyline of world
 * points per (seam edge, side), in edge order. */
typedef struct seam_trace {
    float *points;              /* 3 floats a point */
    size_t npoints, cap;
    int32_t *run_start;         /* nruns + 1 entries into points */
    int32_t nruns, run_cap;
} seam_trace;

/* The surface's topology through its faces' vertex indices (sc_topology:
 * seams share vertices, so they are no boundary): Euler characteristic,
 * connected components, boundary loops and non-manifold edges. */
typedef struct topology {
    int64_t euler;
    int32_t components, boundary_loops, nonmanifold_edges;
} topology;

/* One level, uploaded. */
typedef struct level_gl {
    const sc_atlas *atlas;
    const sc_mesh *mesh;
    GLuint vbo, vao;
    group *groups;
    int32_t ngroups;
    material_gl *materials;     /* mesh->nmat */
    sc_seam_set seams;
    seam_corner *corners;       /* 2 per seam edge */
    bool closed;
    double diag;
    topology topo;
} level_gl;

typedef struct uploaded {
    sc_digest digest;
    GLuint texture;
} uploaded;

/* A tessellated pass's surface, captured once (capture_surface) and drawn
 * from every view: llvmpipe evaluates tessellation on one thread, and a
 * pass's views all see the same surface. Group g's triangles are the
 * vertices [first[g], first[g] + count[g]) of the buffer, in draw order. */
typedef struct captured {
    GLuint vao, vbo;
    int32_t *first, *count;   /* per group of the level */
} captured;

typedef struct renderer {
    sc_gl *gl;
    sc_gl_target target;
    int32_t size;
    GLuint programs[3][2][2];   /* [pos][tessellated][welded] */
    GLuint seam_programs[3];
    GLuint capture_programs[3]; /* [pos]: a tessellated pass's surface, captured */
    GLuint samplers[3][3];      /* [wrap_u][wrap_v] */
    uploaded *textures;
    int32_t ntextures;
    uint8_t *rgba, *flags;      /* size*size*4, size*size */
    int32_t *cracks;            /* size*size: the crack pixels of the current picture */
    float *depth;               /* size*size */
    seam_trace trace;           /* the current pass's seam sides as drawn */
    captured surface;           /* the current tessellated pass's surface */
    int subpixel_bits;          /* GL_SUBPIXEL_BITS: the rasteriser's vertex grid is 2^-bits pixels */
    double subpixel;            /* that grid step in pixels, 0 when unknown */
    double t_render, t_gap;
} renderer;

/* The run's results and the report being built. */
typedef struct encoder encoder;

typedef struct outcome {
    sc_ctx *ctx;
    sc_report *report;
    encoder *enc;
    const char *folder;          /* report files go under it: "render" */
    double crack_total, pinhole_total, fold_total, gap_max, vertex_gap_max;
    int32_t renders, skipped;
} outcome;

/* How one entry of the lods list is named: "lod1" in metrics and files, or,
 * for the mip levels of a LOD, "lod1.mip2" in metrics and "lod1_mip2" in file
 * names; `human` goes into messages. */
typedef struct level_label {
    char metric[32], file[32], human[64];
    int mip;   /* the mip level of a chain's level, else 0 */
} level_label;

/* ---------------------------------------------------------------- small helpers */

static int metric(outcome *o, const char *name, double value) {
    sc_ctx_metric(o->ctx, name, value);
    return sc_report_metric(o->report, name, value);
}

static int metricf(outcome *o, double value, const char *fmt, ...) __attribute__((format(printf, 3, 4)));
static int metricf(outcome *o, double value, const char *fmt, ...) {
    char name[160];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(name, sizeof name, fmt, ap);
    va_end(ap);
    return metric(o, name, value);
}

/* ---------------------------------------------------------------- params */

static int parse_modes(const char *text, bool want[MODE_COUNT], sc_error *err) {
    memset(want, 0, sizeof(bool) * MODE_COUNT);
    int n = 0;
    const char *p = text;
    while (*p) {
        while (*p == ' ' || *p == ',') p++;
        if (!*p) break;
        const char *end = p;
        while (*end && *end != ',' && *end != ' ') end++;
        size_t len = (size_t)(end - p);
        int found = -1;
        for (int m = 0; m < MODE_COUNT; m++)
            if (strlen(mode_names[m]) == len && memcmp(mode_names[m], p, len) == 0) found = m;
        if (found < 0)
            return sc_fail(err, SC_EINPUT, "unknown mode '%.*s' (known: textured, geometry_image, "
                                           "displaced, tessellated)", (int)len, p);
        want[found] = true;
        n++;
        p = end;
    }
    if (n == 0) return sc_fail(err, SC_EINPUT, "no mode given");
    return SC_OK;
}

/* The parameters' rules, checked when the graph is built and again here. */
static int check_modes(const char *text, sc_error *err) {
    bool want[MODE_COUNT];
    return parse_modes(text, want, err);
}

static int check_tess_levels(const double *x, int count, sc_error *err) {
    if (count > MAX_TESS_LEVELS) return sc_fail(err, SC_EINPUT, "%d levels, at most %d", count, MAX_TESS_LEVELS);
    for (int i = 0; i < count; i++) {
        if (x[i] != floor(x[i]) || x[i] < 1 || x[i] > 64)
            return sc_fail(err, SC_EINPUT, "element %d (%g) is not an integer in [1, 64]", i + 1, x[i]);
        for (int j = 0; j < i; j++)
            if (x[j] == x[i]) return sc_fail(err, SC_EINPUT, "level %d is given twice", (int)x[i]);
    }
    return SC_OK;
}

static int check_folder(const char *folder, sc_error *err) {
    size_t len = strlen(folder);
    if (len == 0 || len > 64 || folder[0] == '/' || strstr(folder, "..") ||
        strspn(folder, "abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789_-/") != len)
        return sc_fail(err, SC_EINPUT, "'%s' is not a relative folder name of at most 64 letters, digits, "
                       "'_', '-' and '/'", folder);
    return SC_OK;
}

static int parse_levels(sc_ctx *ctx, int *levels, int *nlevels, sc_error *err) {
    int count = 0;
    const double *x = sc_ctx_numbers(ctx, "tess_levels", &count);
    *nlevels = 0;
    if (check_tess_levels(x, count, err) != SC_OK) return sc_error_prefix(err, "tess_levels");
    for (int i = 0; i < count; i++) levels[(*nlevels)++] = (int)x[i];
    return SC_OK;
}

/* ---------------------------------------------------------------- views */

static void make_view(view *v, const char *name, const double dir_in[3], const double center[3],
                      double radius) {
    snprintf(v->name, sizeof v->name, "%s", name);
    double d[3] = {dir_in[0], dir_in[1], dir_in[2]};
    sc_normalize3(d);
    double up[3] = {0, 1, 0};
    if (fabs(d[1]) > 0.99) up[0] = 0, up[1] = 0, up[2] = d[1] > 0 ? -1 : 1;
    double f[3] = {-d[0], -d[1], -d[2]}, r[3], u[3];
    sc_cross3(f, up, r);
    sc_normalize3(r);
    sc_cross3(r, f, u);
    double near = 0.5 * radius, far = 5.5 * radius, dist = 3.0 * radius;
    double m[4][4] = {{0}};   /* row-major */
    for (int c = 0; c < 3; c++) {
        m[0][c] = r[c] / radius;
        m[1][c] = u[c] / radius;
        m[2][c] = 2.0 * f[c] / (far - near);
    }
    m[0][3] = -sc_dot3(center, r) / radius;
    m[1][3] = -sc_dot3(center, u) / radius;
    m[2][3] = 2.0 * (-sc_dot3(center, f) + dist - near) / (far - near) - 1.0;
    m[3][3] = 1.0;
    for (int row = 0; row < 4; row++)
        for (int col = 0; col < 4; col++) v->view_proj[col * 4 + row] = (float)m[row][col];
    double light[3];
    for (int c = 0; c < 3; c++) light[c] = d[c] + 0.6 * u[c] + 0.4 * r[c];
    sc_normalize3(light);
    for (int c = 0; c < 3; c++) v->light[c] = (float)light[c], v->eye[c] = (float)d[c];
}

static void make_views(view *views, int n, const double center[3], double radius) {
    static const double axis[6][3] = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
    static const char *const axis_names[6] = {"posx", "negx", "posy", "negy", "posz", "negz"};
    static const double corner[8][3] = {{1, 1, 1},  {-1, 1, -1}, {1, -1, -1}, {-1, -1, 1},
                                        {-1, 1, 1}, {1, 1, -1},  {-1, -1, -1}, {1, -1, 1}};
    for (int i = 0; i < n; i++) {
        char name[16];
        if (i < 6) {
            make_view(&views[i], axis_names[i], axis[i], center, radius);
            continue;
        }
        snprintf(name, sizeof name, "obl%d", i - 6);
        if (i < 14) {
            make_view(&views[i], name, corner[i - 6], center, radius);
            continue;
        }
        /* a Fibonacci sphere for the rest */
        int k = i - 14, count = n - 14;
        double z = 1.0 - (2.0 * k + 1.0) / count, rho = sqrt(fmax(0.0, 1.0 - z * z));
        double phi = k * 2.399963229728653;
        double dir[3] = {rho * cos(phi), z, rho * sin(phi)};
        make_view(&views[i], name, dir, center, radius);
    }
}

/* The largest position map (geometry_image, displacement) of a level, else
 * its largest texture; NULL without textures. */
static const sc_image_data *largest_map(const sc_atlas *a) {
    const sc_image_data *best = NULL;
    bool best_is_map = false;
    for (int32_t t = 0; t < a->ntex; t++) {
        const sc_image_data *im = a->textures[t].image->as.image;
        bool is_map = !strcmp(a->textures[t].name, "geometry_image") || !strcmp(a->textures[t].name, "displacement");
        if (!best || (is_map && !best_is_map) ||
            (is_map == best_is_map && (int64_t)im->width * im->height > (int64_t)best->width * best->height))
            best = im, best_is_map = is_map;
    }
    return best;
}

/* ---------------------------------------------------------------- GL objects */

static int get_sampler(renderer *R, sc_wrap wu, sc_wrap wv, GLuint *out, sc_error *err) {
    int a = (int)wu, b = (int)wv;
    if (a < 0 || a > 2) a = 0;
    if (b < 0 || b > 2) b = 0;
    if (!R->samplers[a][b]) {
        int rc = sc_gl_sampler((sc_wrap)a, (sc_wrap)b, &R->samplers[a][b], err);
        if (rc != SC_OK) return rc;
    }
    *out = R->samplers[a][b];
    return SC_OK;
}

static int get_texture(renderer *R, const sc_value *image, GLuint *out, sc_error *err) {
    for (int32_t i = 0; i < R->ntextures; i++)
        if (sc_digest_equal(&R->textures[i].digest, sc_value_digest(image))) {
            *out = R->textures[i].texture;
            return SC_OK;
        }
    uploaded *t = realloc(R->textures, sizeof *t * (size_t)(R->ntextures + 1));
    if (!t) return sc_fail(err, SC_ENOMEM, "out of memory");
    R->textures = t;
    GLuint tex = 0;
    int rc = sc_gl_texture(image->as.image, &tex, err);
    if (rc != SC_OK) return rc;
    t[R->ntextures].digest = *sc_value_digest(image);
    t[R->ntextures].texture = tex;
    R->ntextures++;
    *out = tex;
    return SC_OK;
}

/* What a program is for: drawing a pass, probing seam points (seam_vs), or
 * capturing a tessellated pass's surface once. */
enum { PROGRAM_DRAW, PROGRAM_SEAM, PROGRAM_CAPTURE };

static int build_program(renderer *R, int purpose, int pos, bool tess, bool weld, GLuint *out, sc_error *err) {
    static const char *const pos_defines[3] = {"#define SC_POS 0\n", "#define SC_POS 1\n", "#define SC_POS 2\n"};
    const char *version = "#version 450 core\n";
    const char *tess_define = tess ? (weld ? "#define SC_TESS 1\n#define SC_WELD 1\n" : "#define SC_TESS 1\n")
                                   : weld ? "#define SC_WELD 1\n" : "";
    const char *common = sc_shader_source("render_common.glsl");
    const char *names[5] = {"render_vs.glsl", "render_tcs.glsl", "render_tes.glsl", "render_fs.glsl",
                            "seam_vs.glsl"};
    const char *src[5];
    for (int i = 0; i < 5; i++) {
        src[i] = sc_shader_source(names[i]);
        if (!src[i] || !common)
            return sc_fail(err, SC_EIO, "shader %s is not embedded in this build",
                           !common ? "render_common.glsl" : names[i]);
    }
    sc_gl_stage stages[4];
    int n = 0;
    char label[96];
    static const char *const purposes[3] = {"render", "seam probe", "surface capture"};
    snprintf(label, sizeof label, "%s%s%s (%s)", purposes[purpose], tess ? ", tessellated" : "",
             weld ? ", welded" : "",
             pos == POS_BASE ? "base" : pos == POS_GEOMETRY ? "geometry image" : "displacement");
    if (purpose == PROGRAM_SEAM) {
        stages[n++] = (sc_gl_stage){GL_VERTEX_SHADER, names[4], {version, pos_defines[pos], common, src[4], NULL}};
        const char *const feedback[] = {"f_pos"};
        return sc_gl_program(label, stages, n, feedback, 1, out, err);
    }
    stages[n++] = (sc_gl_stage){GL_VERTEX_SHADER, names[0],
                                {version, pos_defines[pos], tess_define, common, src[0], NULL}};
    if (tess) {
        stages[n++] = (sc_gl_stage){GL_TESS_CONTROL_SHADER, names[1],
                                    {version, pos_defines[pos], tess_define, common, src[1], NULL}};
        stages[n++] = (sc_gl_stage){GL_TESS_EVALUATION_SHADER, names[2],
                                    {version, pos_defines[pos], tess_define, common, src[2], NULL}};
    }
    stages[n++] = (sc_gl_stage){GL_FRAGMENT_SHADER, names[3],
                                {version, pos_defines[pos], tess_define, common, src[3], NULL}};
    /* a tessellated program also serves the seam-gap capture (v_world,
     * f_coord, f_patch); the surface capture takes what the fragment stage
     * reads (v_world, v_uv) */
    const char *const seam_feedback[] = {"v_world", "f_coord", "f_patch"};
    const char *const surface_feedback[] = {"v_world", "v_uv"};
    if (purpose == PROGRAM_CAPTURE) return sc_gl_program(label, stages, n, surface_feedback, 2, out, err);
    return sc_gl_program(label, stages, n, tess ? seam_feedback : NULL, tess ? 3 : 0, out, err);
}

static int get_program(renderer *R, int pos, bool tess, bool weld, GLuint *out, sc_error *err) {
    if (!R->programs[pos][tess][weld]) {
        int rc = build_program(R, PROGRAM_DRAW, pos, tess, weld, &R->programs[pos][tess][weld], err);
        if (rc != SC_OK) return rc;
    }
    *out = R->programs[pos][tess][weld];
    return SC_OK;
}

/* The program that captures a tessellated pass's surface (pos: its source). */
static int get_capture_program(renderer *R, int pos, GLuint *out, sc_error *err) {
    if (!R->capture_programs[pos]) {
        int rc = build_program(R, PROGRAM_CAPTURE, pos, true, false, &R->capture_programs[pos], err);
        if (rc != SC_OK) return rc;
    }
    *out = R->capture_programs[pos];
    return SC_OK;
}

static int get_seam_program(renderer *R, int pos, GLuint *out, sc_error *err) {
    if (!R->seam_programs[pos]) {
        int rc = build_program(R, PROGRAM_SEAM, pos, false, false, &R->seam_programs[pos], err);
        if (rc != SC_OK) return rc;
    }
    *out = R->seam_programs[pos];
    return SC_OK;
}

static void captured_free(captured *C) {
    if (C->vao) glDeleteVertexArrays(1, &C->vao);
    if (C->vbo) glDeleteBuffers(1, &C->vbo);
    free(C->first);
    free(C->count);
    memset(C, 0, sizeof *C);
}

static void renderer_free(renderer *R) {
    free(R->trace.points);
    free(R->trace.run_start);
    R->trace = (seam_trace){0};
    if (!R->gl) return;
    captured_free(&R->surface);
    sc_gl_target_destroy(&R->target);
    for (int p = 0; p < 3; p++) {
        for (int t = 0; t < 2; t++)
            for (int w = 0; w < 2; w++)
                if (R->programs[p][t][w]) glDeleteProgram(R->programs[p][t][w]);
        if (R->seam_programs[p]) glDeleteProgram(R->seam_programs[p]);
        if (R->capture_programs[p]) glDeleteProgram(R->capture_programs[p]);
        for (int q = 0; q < 3; q++)
            if (R->samplers[p][q]) glDeleteSamplers(1, &R->samplers[p][q]);
    }
    for (int32_t i = 0; i < R->ntextures; i++) glDeleteTextures(1, &R->textures[i].texture);
    free(R->textures);
    free(R->rgba);
    free(R->flags);
    free(R->cracks);
    free(R->depth);
    sc_gl_close(R->gl);
    memset(R, 0, sizeof *R);
}

/* ---------------------------------------------------------------- levels */

static void level_free(level_gl *L) {
    if (L->vao) glDeleteVertexArrays(1, &L->vao);
    if (L->vbo) glDeleteBuffers(1, &L->vbo);
    free(L->groups);
    free(L->materials);
    free(L->corners);
    sc_seam_set_free(&L->seams);
    memset(L, 0, sizeof *L);
}

/* Find the material's texture in `slot`, uploaded, with its sampler. */
static int bind_slot(renderer *R, const sc_atlas *a, int32_t material, const char *slot, GLuint *tex,
                     GLuint *sampler, sc_error *err) {
    int i = sc_atlas_find_texture(a, material, slot);
    if (i < 0) return SC_OK;
    const sc_texture *t = &a->textures[i];
    int rc = get_texture(R, t->image, tex, err);
    if (rc == SC_OK) rc = get_sampler(R, t->wrap_u, t->wrap_v, sampler, err);
    if (rc != SC_OK) return sc_error_prefix(err, "texture '%s' of material %d", slot, material);
    return SC_OK;
}

/* The vertex data: per face corner (CORNER_FLOATS), x y z and u v, then the
 * welded pass's uvs: the uv every corner of the corner's vertex samples at
 * (its first corner's, in face order), and the uvs at this corner's and the
 * next corner's vertex of the edge between them as the edge's canonical
 * side has them: the face's own, except on side 1 of a seam, which takes
 * side 0's. slot[f] is face f's place in data. Returns false when out of
 * memory. */
static bool corner_data(const sc_mesh *m, const level_gl *L, const int32_t *slot, float *data) {
    int32_t *first = sc_alloc_array((size_t)m->nv + 1, sizeof *first);
    if (!first) return false;
    for (int32_t v = 0; v < m->nv; v++) first[v] = -1;
    for (int32_t k = 0; k < 3 * m->nf; k++)
        if (first[m->FV[k]] < 0) first[m->FV[k]] = m->FU[k];
    for (int32_t f = 0; f < m->nf; f++)
        for (int c = 0; c < 3; c++) {
            float *v = data + CORNER_FLOATS * ((size_t)slot[f] * 3 + c);
            const double *p = m->V + 3 * m->FV[3 * f + c], *uv = m->U + 2 * m->FU[3 * f + c];
            const double *vu = m->U + 2 * first[m->FV[3 * f + c]], *next = m->U + 2 * m->FU[3 * f + (c + 1) % 3];
            v[0] = (float)p[0], v[1] = (float)p[1], v[2] = (float)p[2];
            v[3] = (float)uv[0], v[4] = (float)uv[1];
            v[5] = (float)vu[0], v[6] = (float)vu[1];
            v[7] = (float)uv[0], v[8] = (float)uv[1], v[9] = (float)next[0], v[10] = (float)next[1];
        }
    free(first);
    for (int32_t e = 0; e < L->seams.nseams; e++) {
        const sc_seam_edge *se = &L->seams.seams[e];
        const seam_corner *c0 = &L->corners[2 * e], *c1 = &L->corners[2 * e + 1];
        int32_t f0 = se->side[0].face, f1 = se->side[1].face;
        const double *u0 = m->U + 2 * m->FU[3 * f0 + c0->k0], *u1 = m->U + 2 * m->FU[3 * f0 + c0->k1];
        bool forward = (c1->k0 + 1) % 3 == c1->k1;   /* side 1's edge runs from v0 to v1 */
        float *v = data + CORNER_FLOATS * ((size_t)slot[f1] * 3 + (forward ? c1->k0 : c1->k1));
        const double *a = forward ? u0 : u1, *b = forward ? u1 : u0;
        v[7] = (float)a[0], v[8] = (float)a[1], v[9] = (float)b[0], v[10] = (float)b[1];
    }
    return true;
}

static bool topology_equal(const topology *a, const topology *b) {
    return a->euler == b->euler && a->components == b->components && a->boundary_loops == b->boundary_loops &&
           a->nonmanifold_edges == b->nonmanifold_edges;
}

static int level_upload(renderer *R, const sc_atlas *atlas, const char *who, level_gl *L, sc_error *err) {
    memset(L, 0, sizeof *L);
    L->atlas = atlas;
    const sc_mesh *m = L->mesh = atlas->mesh->as.mesh;
    if (m->nf < 1) return sc_fail(err, SC_EINPUT, "%s has no faces", who);
    int rc = sc_mesh_check(m, err);
    if (rc != SC_OK) return sc_error_prefix(err, "%s", who);
    L->diag = sc_bbox_diagonal(m->V, m->nv, NULL, 0);
    if (!(L->diag > 0)) L->diag = 1;

    /* one edge table for the seams (as sc_seam_find sees them) and the topology */
    sc_topology table;
    sc_topology_options opt = {.material = -1, .uv_by_coordinates = true};
    rc = sc_topology_build(m, &opt, &table, err);
    if (rc == SC_OK) rc = sc_seam_from_topology(m, &table, &L->seams, err);
    L->closed = table.nboundary == 0 && table.nnonmanifold == 0;
    L->topo = (topology){table.euler, table.components, table.boundary_loops, table.nnonmanifold};
    sc_topology_free(&table);
    if (rc != SC_OK) return sc_error_prefix(err, "%s", who);
    L->corners = calloc((size_t)L->seams.nseams * 2 + 1, sizeof *L->corners);
    if (!L->corners) return sc_fail(err, SC_ENOMEM, "out of memory");
    for (int32_t e = 0; e < L->seams.nseams; e++)
        for (int s = 0; s < 2; s++) {
            const sc_seam_edge *se = &L->seams.seams[e];
            const int32_t *fv = m->FV + 3 * se->side[s].face;
            seam_corner *c = &L->corners[2 * e + s];
            c->k0 = c->k1 = -1;
            for (int q = 0; q < 3; q++) {
                if (fv[q] == se->v0) c->k0 = q;
                if (fv[q] == se->v1) c->k1 = q;
            }
            if (c->k0 < 0 || c->k1 < 0 || c->k0 == c->k1)
                return sc_fail(err, SC_EINPUT, "%s: seam edge %d-%d is not an edge of face %d", who,
                               se->v0, se->v1, se->side[s].face);
            c->k2 = 3 - c->k0 - c->k1;
        }

    /* faces grouped by material (stable), three corners each (corner_data) */
    int32_t nmat = m->nmat;
    int32_t *count = calloc((size_t)nmat + 1, sizeof *count);
    int32_t *slot = sc_alloc_array((size_t)m->nf, sizeof *slot);
    float *data = sc_alloc_array((size_t)m->nf * 3, CORNER_FLOATS * sizeof(float));
    L->materials = calloc((size_t)nmat, sizeof *L->materials);
    L->groups = calloc((size_t)nmat, sizeof *L->groups);
    if (!count || !slot || !data || !L->materials || !L->groups) {
        free(count), free(slot), free(data);
        return sc_fail(err, SC_ENOMEM, "out of memory");
    }
    for (int32_t f = 0; f < m->nf; f++) count[m->FM[f] + 1]++;
    for (int32_t i = 0; i < nmat; i++) count[i + 1] += count[i];
    for (int32_t i = 0; i < nmat; i++)
        if (count[i + 1] > count[i])
            L->groups[L->ngroups++] = (group){i, 3 * count[i], 3 * (count[i + 1] - count[i])};
    for (int32_t f = 0; f < m->nf; f++) slot[f] = count[m->FM[f]]++;
    free(count);
    bool filled = corner_data(m, L, slot, data);
    free(slot);
    if (!filled) {
        free(data);
        return sc_fail(err, SC_ENOMEM, "out of memory");
    }
    glGenVertexArrays(1, &L->vao);
    glGenBuffers(1, &L->vbo);
    glBindVertexArray(L->vao);
    glBindBuffer(GL_ARRAY_BUFFER, L->vbo);
    const GLsizei stride = CORNER_FLOATS * sizeof(float);
    glBufferData(GL_ARRAY_BUFFER, (GLsizeiptr)((size_t)m->nf * 3 * stride), data, GL_STATIC_DRAW);
    free(data);
    static const GLint sizes[4] = {3, 2, 2, 4}, offsets[4] = {0, 3, 5, 7};
    for (GLuint a = 0; a < 4; a++) {
        glEnableVertexAttribArray(a);
        glVertexAttribPointer(a, sizes[a], GL_FLOAT, GL_FALSE, stride, (void *)(offsets[a] * sizeof(float)));
    }
    glBindVertexArray(0);
    rc = sc_gl_check("uploading a mesh", err);
    if (rc != SC_OK) return sc_error_prefix(err, "%s", who);

    for (int32_t i = 0; i < nmat && rc == SC_OK; i++) {
        material_gl *mg = &L->materials[i];
        rc = bind_slot(R, atlas, i, "color", &mg->color, &mg->color_sampler, err);
        if (rc == SC_OK)
            rc = bind_slot(R, atlas, i, "geometry_image", &mg->geometry, &mg->geometry_sampler, err);
        if (rc == SC_OK)
            rc = bind_slot(R, atlas, i, "displacement", &mg->displacement, &mg->displacement_sampler, err);
    }
    if (rc != SC_OK) return sc_error_prefix(err, "%s", who);

    return SC_OK;
}

/* Whether every material with faces has the texture a position source needs. */
static bool level_has(const level_gl *L, int pos) {
    for (int32_t g = 0; g < L->ngroups; g++) {
        const material_gl *mg = &L->materials[L->groups[g].material];
        if (pos == POS_GEOMETRY && !mg->geometry) return false;
        if (pos == POS_DISPLACED && !mg->displacement) return false;
    }
    return true;
}

/* A position texture must have three channels. */
static int check_position_texture(const level_gl *L, const char *who, int pos, sc_error *err) {
    const char *slot = pos == POS_GEOMETRY ? "geometry_image" : "displacement";
    for (int32_t g = 0; g < L->ngroups; g++) {
        int i = sc_atlas_find_texture(L->atlas, L->groups[g].material, slot);
        if (i < 0) continue;
        const sc_image_data *im = L->atlas->textures[i].image->as.image;
        if (im->channels < 3)
            return sc_fail(err, SC_EINPUT, "%s: texture '%s' has %d channel%s; it holds xyz and "
                           "needs 3 or 4", who, slot, im->channels, im->channels == 1 ? "" : "s");
    }
    return SC_OK;
}

static void bind_material(const material_gl *mg, GLuint program) {
    glActiveTexture(GL_TEXTURE0);
    glBindTexture(GL_TEXTURE_2D, mg->color);
    glBindSampler(0, mg->color_sampler);
    glActiveTexture(GL_TEXTURE1);
    glBindTexture(GL_TEXTURE_2D, mg->geometry);
    glBindSampler(1, mg->geometry_sampler);
    glActiveTexture(GL_TEXTURE2);
    glBindTexture(GL_TEXTURE_2D, mg->displacement);
    glBindSampler(2, mg->displacement_sampler);
    glActiveTexture(GL_TEXTURE0);
    glUniform1i(glGetUniformLocation(program, "u_has_color"), mg->color != 0);
}

/* ---------------------------------------------------------------- drawing */

/* Patches go to the GPU in draws of at most ~16k generated vertices:
 * llvmpipe's tessellation slows down by orders of magnitude once one draw
 * generates more than 64k vertices (docs/notes/render.md). The split changes
 * nothing in the picture: every patch is tessellated on its own either way. */
static void draw_patches(int32_t first, int32_t count, int level) {
    int32_t per_patch = (level + 1) * (level + 2) / 2 + 3 * level;
    int32_t chunk = 3 * (16384 / per_patch > 1 ? 16384 / per_patch : 1);
    for (int32_t i = 0; i < count; i += chunk)
        glDrawArrays(GL_PATCHES, first + i, count - i < chunk ? count - i : chunk);
}

/* Draw the pass from view v: the level's own triangles or patches, or, with
 * C, the pass's captured surface through the textured mode's program (base
 * positions are where a capture's points already are: the same floats, so
 * the same picture). */
static int draw(renderer *R, const level_gl *L, const pass *ps, const view *v, bool weld, const captured *C,
                sc_error *err) {
    GLuint program = 0;
    int rc = C ? get_program(R, POS_BASE, false, false, &program, err)
               : get_program(R, ps->pos, ps->level > 0, weld, &program, err);
    if (rc != SC_OK) return rc;
    glBindFramebuffer(GL_FRAMEBUFFER, R->target.fbo);
    glViewport(0, 0, R->size, R->size);
    /* the target encodes to sRGB: the background in linear light */
    const float bg[4] = {sc_srgb_to_linear(background[0] / 255.0f), sc_srgb_to_linear(background[1] / 255.0f),
                         sc_srgb_to_linear(background[2] / 255.0f), 0.0f};
    const float one = 1.0f;
    glClearBufferfv(GL_COLOR, 0, bg);
    glClearBufferfv(GL_DEPTH, 0, &one);
    glEnable(GL_DEPTH_TEST);
    glDepthFunc(GL_LESS);
    glEnable(GL_DEPTH_CLAMP);
    glDisable(GL_CULL_FACE);
    glDisable(GL_BLEND);
    glDisable(GL_RASTERIZER_DISCARD);
    glUseProgram(program);
    glUniformMatrix4fv(glGetUniformLocation(program, "u_view_proj"), 1, GL_FALSE, v->view_proj);
    glUniform3fv(glGetUniformLocation(program, "u_light"), 1, v->light);
    glUniform3fv(glGetUniformLocation(program, "u_eye_dir"), 1, v->eye);
    glUniform1f(glGetUniformLocation(program, "u_back_bias"), 1e-5f);
    if (C) {
        glBindVertexArray(C->vao);
        for (int32_t g = 0; g < L->ngroups; g++) {
            bind_material(&L->materials[L->groups[g].material], program);
            glDrawArrays(GL_TRIANGLES, C->first[g], C->count[g]);
        }
        glBindVertexArray(0);
        return sc_gl_check("drawing a captured surface", err);
    }
    if (ps->level > 0) {
        glUniform1f(glGetUniformLocation(program, "u_level"), (float)ps->level);
        glUniform1i(glGetUniformLocation(program, "u_patch_base"), 0);
        glPatchParameteri(GL_PATCH_VERTICES, 3);
    }
    glBindVertexArray(L->vao);
    for (int32_t g = 0; g < L->ngroups; g++) {
        bind_material(&L->materials[L->groups[g].material], program);
        if (ps->level == 0) {
            glDrawArrays(GL_TRIANGLES, L->groups[g].first, L->groups[g].count);
            continue;
        }
        draw_patches(L->groups[g].first, L->groups[g].count, ps->level);
    }
    glBindVertexArray(0);
    return sc_gl_check("drawing", err);
}

/* Read the picture back and sort its pixels by alpha: 0 background, 1 front
 * face, 2 back face (render_fs.glsl writes alpha 0, 1 and 1/2). */
static int read_target(renderer *R, sc_error *err) {
    int rc = sc_gl_target_read(&R->target, R->rgba, R->depth, err);
    if (rc != SC_OK) return rc;
    size_t n = (size_t)R->size * (size_t)R->size;
    for (size_t i = 0; i < n; i++) {
        uint8_t a = R->rgba[4 * i + 3];
        R->flags[i] = a == 0 ? 0 : a >= 192 ? 1 : 2;
    }
    return SC_OK;
}

/* ---------------------------------------------------------------- seam gap */

typedef struct gap_result {
    double gap, vertex_gap;     /* relative to the bounding-box diagonal */
    int32_t edge;               /* worst seam edge, -1 when none */
    double edge_t;
} gap_result;

static void gap_consider(gap_result *g, double d, double t, int32_t edge) {
    if (g->edge < 0 || d > g->gap) {
        g->gap = fmax(g->gap, d);
        g->edge = edge;
        g->edge_t = t;
    }
    if (t <= 0.0 || t >= 1.0) g->vertex_gap = fmax(g->vertex_gap, d);
}

static void trace_clear(seam_trace *t) { t->npoints = 0, t->nruns = 0; }

/* Starts the next polyline of the trace. */
static int trace_run(seam_trace *t, sc_error *err) {
    if (t->nruns + 2 > t->run_cap) {
        int32_t ncap = t->run_cap ? 2 * t->run_cap : 256;
        int32_t *r = realloc(t->run_start, sizeof *r * (size_t)ncap);
        if (!r) return sc_fail(err, SC_ENOMEM, "out of memory");
        t->run_start = r, t->run_cap = ncap;
    }
    t->run_start[t->nruns] = (int32_t)t->npoints;
    t->run_start[++t->nruns] = (int32_t)t->npoints;
    return SC_OK;
}

/* Appends a point to the polyline trace_run started last. */
static int trace_point(seam_trace *t, const float p[3], sc_error *err) {
    if (t->npoints == t->cap) {
        size_t ncap = t->cap ? 2 * t->cap : 4096;
        if (ncap > INT32_MAX) return sc_fail(err, SC_ENOMEM, "seam trace: too many points");
        float *q = realloc(t->points, sizeof *q * 3 * ncap);
        if (!q) return sc_fail(err, SC_ENOMEM, "out of memory");
        t->points = q, t->cap = ncap;
    }
    memcpy(t->points + 3 * t->npoints, p, 3 * sizeof *p);
    t->run_start[t->nruns] = (int32_t)++t->npoints;
    return SC_OK;
}

/* Whether the centre of pixel (x, y) (GL order: row 0 at the bottom) lies
 * within one pixel of a seam side of the current pass, projected in view v
 * (orthographic: w = 1). */
static bool near_seam(const renderer *R, const view *v, int32_t x, int32_t y) {
    const seam_trace *t = &R->trace;
    const float *M = v->view_proj;   /* column-major */
    double s = R->size, cx = x + 0.5, cy = y + 0.5, px0 = 0, py0 = 0;
    for (int32_t r = 0; r < t->nruns; r++)
        for (int32_t i = t->run_start[r]; i < t->run_start[r + 1]; i++) {
            const float *p = t->points + 3 * (size_t)i;
            double px = (M[0] * p[0] + M[4] * p[1] + M[8] * p[2] + M[12] + 1.0) * 0.5 * s;
            double py = (M[1] * p[0] + M[5] * p[1] + M[9] * p[2] + M[13] + 1.0) * 0.5 * s;
            if (i == t->run_start[r]) px0 = px, py0 = py;
            if (sc_atlas_ops_segment_distance2(cx, cy, px0, py0, px, py) <= 1.0) return true;
            px0 = px, py0 = py;
        }
    return false;
}

/* Capture into a buffer of `bytes`; returns primitives written, or -1 on overflow. */
typedef struct capture {
    GLuint buffer, q_written, q_generated;
    size_t bytes;
} capture;

static int capture_begin(capture *c, size_t bytes, GLenum primitive, sc_error *err) {
    memset(c, 0, sizeof *c);
    c->bytes = bytes ? bytes : 16;
    glGenBuffers(1, &c->buffer);
    glBindBuffer(GL_TRANSFORM_FEEDBACK_BUFFER, c->buffer);
    glBufferData(GL_TRANSFORM_FEEDBACK_BUFFER, (GLsizeiptr)c->bytes, NULL, GL_STREAM_READ);
    glBindBufferBase(GL_TRANSFORM_FEEDBACK_BUFFER, 0, c->buffer);
    glGenQueries(1, &c->q_written);
    glGenQueries(1, &c->q_generated);
    glEnable(GL_RASTERIZER_DISCARD);
    glBeginQuery(GL_TRANSFORM_FEEDBACK_PRIMITIVES_WRITTEN, c->q_written);
    glBeginQuery(GL_PRIMITIVES_GENERATED, c->q_generated);
    glBeginTransformFeedback(primitive);
    return sc_gl_check("starting transform feedback", err);
}

/* Ends the capture; *written = primitives written, *overflow when some did
 * not fit. With out, the data is read back (the caller frees *out) and the
 * buffer deleted; without, the buffer stays in c->buffer, the caller's. */
static int capture_end(capture *c, void **out, GLuint *written, bool *overflow, sc_error *err) {
    glEndTransformFeedback();
    glEndQuery(GL_PRIMITIVES_GENERATED);
    glEndQuery(GL_TRANSFORM_FEEDBACK_PRIMITIVES_WRITTEN);
    glDisable(GL_RASTERIZER_DISCARD);
    GLuint w = 0, g = 0;
    glGetQueryObjectuiv(c->q_written, GL_QUERY_RESULT, &w);
    glGetQueryObjectuiv(c->q_generated, GL_QUERY_RESULT, &g);
    *written = w;
    *overflow = g > w;
    void *data = out ? malloc(c->bytes) : NULL;
    if (data) glGetBufferSubData(GL_TRANSFORM_FEEDBACK_BUFFER, 0, (GLsizeiptr)c->bytes, data);
    glBindBufferBase(GL_TRANSFORM_FEEDBACK_BUFFER, 0, 0);
    if (out) {
        glDeleteBuffers(1, &c->buffer);
        c->buffer = 0;
    }
    glDeleteQueries(1, &c->q_written);
    glDeleteQueries(1, &c->q_generated);
    if (out && !data) return sc_fail(err, SC_ENOMEM, "out of memory");
    int rc = sc_gl_check("transform feedback", err);
    if (rc != SC_OK) free(data), data = NULL;
    if (out) *out = data;
    return rc;
}

/* The position maps of a pass, one per material (NULL where it has none):
 * "geometry_image" or "displacement". */
static const sc_texture **position_maps(const level_gl *L, int pos) {
    const sc_mesh *m = L->mesh;
    const char *slot = pos == POS_GEOMETRY ? "geometry_image" : "displacement";
    const sc_texture **maps = calloc((size_t)m->nmat + 1, sizeof *maps);
    for (int32_t mat = 0; maps && mat < m->nmat; mat++) {
        int i = sc_atlas_find_texture(L->atlas, mat, slot);
        maps[mat] = i >= 0 ? &L->atlas->textures[i] : NULL;
    }
    return maps;
}

/* The maps' own gap at t along seam edge e (relative to the diagonal; -1
 * when a side has no map): each side's map sampled bilinearly (its wrap
 * modes, GL's texel centres) at that side's exact uv, in double. The
 * displacement pass adds the same base point to both sides, so the maps'
 * difference is its gap too. */
static double map_point_gap(const level_gl *L, const sc_texture *const *maps, int32_t e, double t) {
    const sc_mesh *m = L->mesh;
    const sc_seam_edge *se = &L->seams.seams[e];
    double at[2][3];
    for (int s = 0; s < 2; s++) {
        const sc_texture *tex = maps[m->FM[se->side[s].face]];
        if (!tex) return -1;
        const double *u0 = m->U + 2 * se->side[s].uv0, *u1 = m->U + 2 * se->side[s].uv1;
        const sc_image_data *im = tex->image->as.image;
        sc_seam_grid g = {im->width, im->height, tex->wrap_u, tex->wrap_v};
        int32_t id[4];
        double w[4];
        sc_seam_taps(&g, (1 - t) * u0[0] + t * u1[0], (1 - t) * u0[1] + t * u1[1], id, w);
        for (int c = 0; c < 3; c++) {
            double v = 0;
            for (int k = 0; k < 4; k++) v += w[k] * sc_seam_texel(im, id[k], c);
            at[s][c] = v;
        }
    }
    double d[3] = {at[0][0] - at[1][0], at[0][1] - at[1][1], at[0][2] - at[1][2]};
    return sc_norm3(d) / L->diag;
}

/* The maps' own seam gap over a pass's points: t = i / steps along every
 * seam edge. The GPU's gap (seam_gap_points, seam_gap_tess) adds the
 * rounding of its sampling (float32 uvs, its filtering), which grows with
 * how steeply a map changes across a chart's border; this one is what the
 * maps themselves hold. */
static int map_seam_gap(const level_gl *L, int pos, int steps, gap_result *res, sc_error *err) {
    const sc_texture **maps = position_maps(L, pos);
    if (!maps) return sc_fail(err, SC_ENOMEM, "out of memory");
    for (int32_t e = 0; e < L->seams.nseams; e++)
        for (int i = 0; i <= steps; i++) {
            double t = i == steps ? 1.0 : (double)i / steps, d = map_point_gap(L, maps, e, t);
            if (d < 0) break;   /* a side without the map: the pass skips its material */
            gap_consider(res, d, t, e);
        }
    free(maps);
    return SC_OK;
}

/* Capture pass ps's tessellated surface into R->surface (see captured):
 * the level's patches, group by group as draw() sends them, through the
 * pass's own stages, with the evaluated points and uvs (v_world, v_uv)
 * recorded. Every patch splits alike (one level for all), so a one-patch
 * capture sizes the buffer exactly. */
static int capture_surface(renderer *R, const level_gl *L, const pass *ps, sc_error *err) {
    captured *C = &R->surface;
    GLuint program = 0;
    int rc = get_capture_program(R, ps->pos, &program, err);
    if (rc != SC_OK) return rc;
    const size_t vertex_bytes = 5 * sizeof(float);
    int64_t patches = 0;
    for (int32_t g = 0; g < L->ngroups; g++) patches += L->groups[g].count / 3;
    C->first = calloc((size_t)L->ngroups + 1, sizeof *C->first);
    C->count = calloc((size_t)L->ngroups + 1, sizeof *C->count);
    if (!C->first || !C->count) return sc_fail(err, SC_ENOMEM, "out of memory");
    if (patches == 0) return SC_OK;
    glUseProgram(program);
    glUniform1f(glGetUniformLocation(program, "u_level"), (float)ps->level);
    glUniform1i(glGetUniformLocation(program, "u_patch_base"), 0);
    glPatchParameteri(GL_PATCH_VERTICES, 3);
    glBindVertexArray(L->vao);
    /* one patch: the triangles every patch gives */
    int32_t g0 = 0;
    while (L->groups[g0].count < 3) g0++;
    capture cap;
    GLuint per_patch = 0, written = 0;
    bool overflow = false;
    size_t bound = 3 * (size_t)ps->level * (size_t)ps->level / 2 + 4;
    rc = capture_begin(&cap, bound * 3 * vertex_bytes, GL_TRIANGLES, err);
    if (rc == SC_OK) {
        bind_material(&L->materials[L->groups[g0].material], program);
        glDrawArrays(GL_PATCHES, L->groups[g0].first, 3);
        rc = capture_end(&cap, NULL, &per_patch, &overflow, err);
        glDeleteBuffers(1, &cap.buffer);
    }
    if (rc == SC_OK && (overflow || per_patch == 0))
        rc = sc_fail(err, SC_EIO, "OpenGL: a tessellated patch captured %u triangles%s", per_patch,
                     overflow ? ", more than the tessellation gives" : "");
    size_t total = (size_t)patches * per_patch * 3;
    if (rc == SC_OK && total > INT32_MAX) rc = sc_fail(err, SC_ENOMEM, "the tessellated surface is too large");
    if (rc == SC_OK) rc = capture_begin(&cap, total * vertex_bytes, GL_TRIANGLES, err);
    if (rc == SC_OK) {
        int32_t at = 0;
        for (int32_t g = 0; g < L->ngroups; g++) {
            bind_material(&L->materials[L->groups[g].material], program);
            draw_patches(L->groups[g].first, L->groups[g].count, ps->level);
            C->first[g] = at;
            C->count[g] = L->groups[g].count / 3 * (int32_t)per_patch * 3;
            at += C->count[g];
        }
        rc = capture_end(&cap, NULL, &written, &overflow, err);
        C->vbo = cap.buffer;   /* the capture is the vertex buffer */
    }
    glBindVertexArray(0);
    if (rc == SC_OK && (overflow || (size_t)written * 3 != total))
        rc = sc_fail(err, SC_EIO, "OpenGL: the tessellated surface captured %u of %zu triangles", written,
                     total / 3);
    if (rc == SC_OK) {
        glGenVertexArrays(1, &C->vao);
        glBindVertexArray(C->vao);
        glBindBuffer(GL_ARRAY_BUFFER, C->vbo);
        glEnableVertexAttribArray(0);
        glVertexAttribPointer(0, 3, GL_FLOAT, GL_FALSE, (GLsizei)vertex_bytes, (void *)0);
        glEnableVertexAttribArray(1);
        glVertexAttribPointer(1, 2, GL_FLOAT, GL_FALSE, (GLsizei)vertex_bytes, (void *)(3 * sizeof(float)));
        glBindVertexArray(0);
        rc = sc_gl_check("drawing from a captured surface", err);
    }
    return rc;
}

/* Untessellated passes: seam_points points per side. */
static int seam_gap_points(renderer *R, const level_gl *L, const pass *ps, int npoints, gap_result *res,
                           sc_error *err) {
    const sc_mesh *m = L->mesh;
    int32_t ne = L->seams.nseams;
    if (ne == 0) return SC_OK;
    size_t total = (size_t)ne * 2 * (size_t)npoints;
    /* points ordered by material (stable) so each draw binds one texture set */
    float *data = sc_alloc_array(total, 11 * sizeof(float));
    int32_t *slot_of = sc_alloc_array(total, sizeof(int32_t));   /* point -> capture slot */
    int32_t *start = calloc((size_t)m->nmat + 1, sizeof *start);
    if (!data || !slot_of || !start) {
        free(data), free(slot_of), free(start);
        return sc_fail(err, SC_ENOMEM, "out of memory");
    }
    for (int32_t e = 0; e < ne; e++)
        for (int s = 0; s < 2; s++) start[m->FM[L->seams.seams[e].side[s].face] + 1] += npoints;
    for (int32_t i = 0; i < m->nmat; i++) start[i + 1] += start[i];
    int32_t *fill = calloc((size_t)m->nmat + 1, sizeof *fill);
    if (!fill) {
        free(data), free(slot_of), free(start);
        return sc_fail(err, SC_ENOMEM, "out of memory");
    }
    memcpy(fill, start, sizeof *fill * (size_t)(m->nmat + 1));
    for (int32_t e = 0; e < ne; e++) {
        const sc_seam_edge *se = &L->seams.seams[e];
        const double *p0 = m->V + 3 * se->v0, *p1 = m->V + 3 * se->v1;
        for (int s = 0; s < 2; s++) {
            const double *u0 = m->U + 2 * se->side[s].uv0, *u1 = m->U + 2 * se->side[s].uv1;
            int32_t mat = m->FM[se->side[s].face];
            for (int i = 0; i < npoints; i++) {
                size_t point = ((size_t)e * 2 + (size_t)s) * (size_t)npoints + (size_t)i;
                int32_t slot = fill[mat]++;
                slot_of[point] = slot;
                float *d = data + 11 * (size_t)slot;
                for (int c = 0; c < 3; c++) d[c] = (float)p0[c], d[3 + c] = (float)p1[c];
                d[6] = (float)u0[0], d[7] = (float)u0[1], d[8] = (float)u1[0], d[9] = (float)u1[1];
                d[10] = i == npoints - 1 ? 1.0f : (float)((double)i / (npoints - 1));
            }
        }
    }
    free(fill);
    GLuint program = 0, vao = 0, vbo = 0;
    int rc = get_seam_program(R, ps->pos, &program, err);
    if (rc != SC_OK) {
        free(data), free(slot_of), free(start);
        return rc;
    }
    glGenVertexArrays(1, &vao);
    glGenBuffers(1, &vbo);
    glBindVertexArray(vao);
    glBindBuffer(GL_ARRAY_BUFFER, vbo);
    glBufferData(GL_ARRAY_BUFFER, (GLsizeiptr)(total * 11 * sizeof(float)), data, GL_STATIC_DRAW);
    free(data);
    static const int sizes[5] = {3, 3, 2, 2, 1}, offsets[5] = {0, 3, 6, 8, 10};
    for (int a = 0; a < 5; a++) {
        glEnableVertexAttribArray((GLuint)a);
        glVertexAttribPointer((GLuint)a, sizes[a], GL_FLOAT, GL_FALSE, 11 * sizeof(float),
                              (void *)(offsets[a] * sizeof(float)));
    }
    glUseProgram(program);
    capture cap;
    rc = capture_begin(&cap, total * 3 * sizeof(float), GL_POINTS, err);
    for (int32_t mat = 0; rc == SC_OK && mat < m->nmat; mat++) {
        if (start[mat + 1] == start[mat]) continue;
        bind_material(&L->materials[mat], program);
        glDrawArrays(GL_POINTS, start[mat], start[mat + 1] - start[mat]);
    }
    float *out = NULL;
    GLuint written = 0;
    bool overflow = false;
    if (rc == SC_OK) rc = capture_end(&cap, (void **)&out, &written, &overflow, err);
    glBindVertexArray(0);
    glDeleteVertexArrays(1, &vao);
    glDeleteBuffers(1, &vbo);
    free(start);
    if (rc == SC_OK && (overflow || written != total))
        rc = sc_fail(err, SC_EIO, "OpenGL: the seam probe captured %u of %zu points", written, total);
    if (rc == SC_OK)
        for (int32_t e = 0; e < ne; e++)
            for (int i = 0; i < npoints; i++) {
                const float *a = out + 3 * (size_t)slot_of[((size_t)e * 2) * (size_t)npoints + (size_t)i];
                const float *b = out + 3 * (size_t)slot_of[((size_t)e * 2 + 1) * (size_t)npoints + (size_t)i];
                double d[3] = {(double)a[0] - b[0], (double)a[1] - b[1], (double)a[2] - b[2]};
                double t = i == npoints - 1 ? 1.0 : (double)i / (npoints - 1);
                gap_consider(res, sc_norm3(d) / L->diag, t, e);
            }
    for (int32_t e = 0; rc == SC_OK && e < ne; e++)
        for (int s = 0; s < 2 && rc == SC_OK; s++) {
            rc = trace_run(&R->trace, err);
            const int32_t *slots = slot_of + ((size_t)e * 2 + (size_t)s) * (size_t)npoints;
            for (int i = 0; rc == SC_OK && i < npoints; i++) rc = trace_point(&R->trace, out + 3 * (size_t)slots[i], err);
        }
    free(out);
    free(slot_of);
    return rc;
}

typedef struct edge_sample {
    int32_t edge, side;
    float t;
    float p[3];
} edge_sample;

static int compare_samples(const void *pa, const void *pb) {
    const edge_sample *a = pa, *b = pb;
    if (a->edge != b->edge) return a->edge < b->edge ? -1 : 1;
    if (a->side != b->side) return a->side < b->side ? -1 : 1;
    if (a->t != b->t) return a->t < b->t ? -1 : 1;
    for (int c = 0; c < 3; c++)
        if (a->p[c] != b->p[c]) return a->p[c] < b->p[c] ? -1 : 1;
    return 0;
}

/* Pair each sample of run a with the sample of run b nearest in t. */
static void pair_runs(const edge_sample *a, int32_t na, const edge_sample *b, int32_t nb, double diag,
                      gap_result *res) {
    int32_t j = 0;
    for (int32_t i = 0; i < na; i++) {
        while (j + 1 < nb && fabsf(b[j + 1].t - a[i].t) <= fabsf(b[j].t - a[i].t)) j++;
        double d[3] = {(double)a[i].p[0] - b[j].p[0], (double)a[i].p[1] - b[j].p[1],
                       (double)a[i].p[2] - b[j].p[2]};
        gap_consider(res, sc_norm3(d) / diag, a[i].t, a[i].edge);
    }
}

/* The faces along seams as patches, once each and ordered by (material,
 * face), and the seam sides each carries. */
typedef struct seam_patches {
    int32_t npatches;
    int32_t *patch_of;      /* nf: face -> patch, -1 off the seams */
    int32_t *faces;         /* patch -> face */
    int32_t *start;         /* nmat + 1: the first patch of each material */
    int32_t *first_side;    /* npatches + 1: the first entry of each patch in sides */
    int32_t *sides;         /* entries: 2 * edge + side */
} seam_patches;

static void seam_patches_free(seam_patches *P) {
    free(P->patch_of), free(P->faces), free(P->start), free(P->first_side), free(P->sides);
    memset(P, 0, sizeof *P);
}

static int seam_patches_build(const level_gl *L, seam_patches *P, sc_error *err) {
    const sc_mesh *m = L->mesh;
    int32_t ne = L->seams.nseams;
    memset(P, 0, sizeof *P);
    P->patch_of = malloc(sizeof(int32_t) * (size_t)m->nf);
    P->faces = malloc(sizeof(int32_t) * (size_t)ne * 2);
    P->start = calloc((size_t)m->nmat + 1, sizeof *P->start);
    int32_t *fill = calloc((size_t)m->nmat + 1, sizeof *fill);
    if (!P->patch_of || !P->faces || !P->start || !fill) {
        free(fill);
        seam_patches_free(P);
        return sc_fail(err, SC_ENOMEM, "out of memory");
    }
    /* the faces along seams, once each, ordered by (material, face) */
    for (int32_t f = 0; f < m->nf; f++) P->patch_of[f] = -1;
    for (int32_t e = 0; e < ne; e++)
        for (int s = 0; s < 2; s++) P->patch_of[L->seams.seams[e].side[s].face] = 0;
    for (int32_t f = 0; f < m->nf; f++)
        if (P->patch_of[f] == 0) P->start[m->FM[f] + 1]++, P->npatches++;
    for (int32_t i = 0; i < m->nmat; i++) P->start[i + 1] += P->start[i];
    memcpy(fill, P->start, sizeof *fill * (size_t)(m->nmat + 1));
    for (int32_t f = 0; f < m->nf; f++)
        if (P->patch_of[f] == 0) {
            int32_t p = fill[m->FM[f]]++;
            P->faces[p] = f;
            P->patch_of[f] = p;
        }
    free(fill);
    /* which seam sides each patch carries */
    P->first_side = calloc((size_t)P->npatches + 1, sizeof *P->first_side);
    P->sides = malloc(sizeof(int32_t) * (size_t)ne * 2);
    fill = malloc(sizeof(int32_t) * ((size_t)P->npatches + 1));
    if (!P->first_side || !P->sides || !fill) {
        free(fill);
        seam_patches_free(P);
        return sc_fail(err, SC_ENOMEM, "out of memory");
    }
    for (int32_t e = 0; e < ne; e++)
        for (int s = 0; s < 2; s++) P->first_side[P->patch_of[L->seams.seams[e].side[s].face] + 1]++;
    for (int32_t p = 0; p < P->npatches; p++) P->first_side[p + 1] += P->first_side[p];
    memcpy(fill, P->first_side, sizeof(int32_t) * ((size_t)P->npatches + 1));
    for (int32_t e = 0; e < ne; e++)
        for (int s = 0; s < 2; s++) P->sides[fill[P->patch_of[L->seams.seams[e].side[s].face]]++] = 2 * e + s;
    free(fill);
    return SC_OK;
}

/* The patches' corners (position, uv) into a new vertex array, drawn by the
 * tessellated render program of the pass. */
static int seam_patches_upload(renderer *R, const level_gl *L, const pass *ps, const seam_patches *P,
                               GLuint *program, GLuint *vao, GLuint *vbo, sc_error *err) {
    const sc_mesh *m = L->mesh;
    float *data = sc_alloc_array((size_t)P->npatches * 3, 5 * sizeof(float));
    if (!data) return sc_fail(err, SC_ENOMEM, "out of memory");
    for (int32_t p = 0; p < P->npatches; p++)
        for (int c = 0; c < 3; c++) {
            int32_t f = P->faces[p];
            float *v = data + 5 * ((size_t)p * 3 + c);
            const double *x = m->V + 3 * m->FV[3 * f + c], *uv = m->U + 2 * m->FU[3 * f + c];
            v[0] = (float)x[0], v[1] = (float)x[1], v[2] = (float)x[2];
            v[3] = (float)uv[0], v[4] = (float)uv[1];
        }
    int rc = get_program(R, ps->pos, true, false, program, err);
    if (rc == SC_OK) {
        glGenVertexArrays(1, vao);
        glGenBuffers(1, vbo);
        glBindVertexArray(*vao);
        glBindBuffer(GL_ARRAY_BUFFER, *vbo);
        glBufferData(GL_ARRAY_BUFFER, (GLsizeiptr)((size_t)P->npatches * 15 * sizeof(float)), data, GL_STATIC_DRAW);
        glEnableVertexAttribArray(0);
        glVertexAttribPointer(0, 3, GL_FLOAT, GL_FALSE, 5 * sizeof(float), (void *)0);
        glEnableVertexAttribArray(1);
        glVertexAttribPointer(1, 2, GL_FLOAT, GL_FALSE, 5 * sizeof(float), (void *)(3 * sizeof(float)));
        glUseProgram(*program);
        glUniform1f(glGetUniformLocation(*program, "u_level"), (float)ps->level);
        glPatchParameteri(GL_PATCH_VERTICES, 3);
    }
    free(data);
    return rc;
}

typedef struct sample_list {
    edge_sample *v;
    size_t n, cap;
} sample_list;

/* The captured vertices of patches p0 .. p0 + n - 1 (7 words each) sorted
 * onto the seam sides they lie on. */
static int sort_onto_sides(const level_gl *L, const seam_patches *P, const float *out, size_t nvert, int32_t p0,
                           int32_t n, sample_list *S, sc_error *err) {
    for (size_t i = 0; i < nvert; i++) {
        const float *w = out + 7 * i;
        int32_t patch;
        memcpy(&patch, w + 6, sizeof patch);
        if (patch < p0 || patch >= p0 + n)
            return sc_fail(err, SC_EIO, "OpenGL: tessellated seam capture gave patch %d, not in [%d, %d)", patch, p0,
                           p0 + n);
        for (int32_t j = P->first_side[patch]; j < P->first_side[patch + 1]; j++) {
            int32_t e = P->sides[j] / 2, sd = P->sides[j] % 2;
            const seam_corner *c = &L->corners[2 * e + sd];
            if (fabsf(w[3 + c->k2]) > EDGE_COORD_EPS) continue;
            if (S->n == S->cap) {
                size_t ncap = S->cap ? 2 * S->cap : 1024;
                edge_sample *ns = realloc(S->v, ncap * sizeof *ns);
                if (!ns) return sc_fail(err, SC_ENOMEM, "out of memory");
                S->v = ns, S->cap = ncap;
            }
            edge_sample *es = &S->v[S->n++];
            es->edge = e, es->side = sd;
            es->t = w[3 + c->k1];
            memcpy(es->p, w, sizeof es->p);
        }
    }
    return SC_OK;
}

/* llvmpipe numbers a tessellation shader's gl_PrimitiveID from 0 again
 * after every 4,096 vertices a draw reads (1,365 triangle patches): a
 * capture draws at most that many, so the ids it reads back are its own. */
#define MAX_CAPTURE_PATCHES 1365

/* Draw the patches material by material and capture what the tessellator
 * made of them.
 * One capture per draw of at most ~16k generated vertices (see
 * draw_patches) and MAX_CAPTURE_PATCHES patches; gl_PrimitiveID restarts
 * with every draw, hence u_patch_base. A level-L patch makes 3L^2/2
 * triangles (L even; fewer when odd); a capture that overflows anyway is
 * retried larger. Each vertex is 7 words: position, tessellation
 * coordinate, patch. */
static int capture_patches(const level_gl *L, const pass *ps, const seam_patches *P, GLuint program, sample_list *S,
                           sc_error *err) {
    const sc_mesh *m = L->mesh;
    int32_t verts = (ps->level + 1) * (ps->level + 2) / 2 + 3 * ps->level;
    int32_t chunk = 16384 / verts > 1 ? 16384 / verts : 1;
    if (chunk > MAX_CAPTURE_PATCHES) chunk = MAX_CAPTURE_PATCHES;
    size_t tris_per_patch = 3 * (size_t)ps->level * (size_t)ps->level / 2 + 4;
    int rc = SC_OK;
    for (int32_t mat = 0; rc == SC_OK && mat < m->nmat; mat++) {
        if (P->start[mat + 1] == P->start[mat]) continue;
        bind_material(&L->materials[mat], program);
        for (int32_t p0 = P->start[mat]; rc == SC_OK && p0 < P->start[mat + 1]; p0 += chunk) {
            int32_t n = P->start[mat + 1] - p0 < chunk ? P->start[mat + 1] - p0 : chunk;
            float *out = NULL;
            GLuint written = 0;
            size_t bytes = (size_t)n * tris_per_patch * 3 * 7 * sizeof(float);
            for (int attempt = 0; rc == SC_OK; attempt++) {
                capture cap;
                bool overflow = false;
                rc = capture_begin(&cap, bytes, GL_TRIANGLES, err);
                if (rc == SC_OK) {
                    glUniform1i(glGetUniformLocation(program, "u_patch_base"), p0);
                    glDrawArrays(GL_PATCHES, 3 * p0, 3 * n);
                    rc = capture_end(&cap, (void **)&out, &written, &overflow, err);
                }
                if (rc != SC_OK || !overflow) break;
                free(out);
                out = NULL;
                bytes *= 4;
                if (attempt == 2) rc = sc_fail(err, SC_EIO, "OpenGL: tessellated seam capture overflowed");
            }
            if (rc == SC_OK) rc = sort_onto_sides(L, P, out, (size_t)written * 3, p0, n, S, err);
            free(out);
        }
    }
    return rc;
}

/* Pair the two sides of every seam edge (samples sorted) into the gap, and
 * trace them. */
static int pair_sides(renderer *R, const level_gl *L, const edge_sample *samples, size_t nsamples, gap_result *res,
                      sc_error *err) {
    int rc = SC_OK;
    size_t i = 0;
    while (i < nsamples && rc == SC_OK) {
        size_t a = i, mid = i, b;
        while (mid < nsamples && samples[mid].edge == samples[a].edge && samples[mid].side == 0) mid++;
        b = mid;
        while (b < nsamples && samples[b].edge == samples[a].edge) b++;
        if (mid == a || b == mid) {
            /* one side produced no vertex on its edge: the tessellator and
             * the seam disagree about this edge: count it as a gap of a
             * whole diagonal */
            gap_consider(res, 1.0, 0.5, samples[a].edge);
        } else {
            pair_runs(samples + a, (int32_t)(mid - a), samples + mid, (int32_t)(b - mid), L->diag, res);
            pair_runs(samples + mid, (int32_t)(b - mid), samples + a, (int32_t)(mid - a), L->diag, res);
        }
        for (size_t j = a; j < b && rc == SC_OK; j++) {
            if (j == a || j == mid) rc = trace_run(&R->trace, err);
            if (rc == SC_OK) rc = trace_point(&R->trace, samples[j].p, err);
        }
        i = b;
    }
    return rc;
}

/* Tessellated passes: the seam faces through the render program itself. */
static int seam_gap_tess(renderer *R, const level_gl *L, const pass *ps, gap_result *res, sc_error *err) {
    if (L->seams.nseams == 0) return SC_OK;
    seam_patches P;
    int rc = seam_patches_build(L, &P, err);
    if (rc != SC_OK) return rc;
    GLuint program = 0, vao = 0, vbo = 0;
    sample_list S = {0};
    rc = seam_patches_upload(R, L, ps, &P, &program, &vao, &vbo, err);
    if (rc == SC_OK) rc = capture_patches(L, ps, &P, program, &S, err);
    if (vao) {
        glBindVertexArray(0);
        glDeleteVertexArrays(1, &vao);
        glDeleteBuffers(1, &vbo);
    }
    if (rc == SC_OK && S.n > 0) {
        qsort(S.v, S.n, sizeof *S.v, compare_samples);
        rc = pair_sides(R, L, S.v, S.n, res, err);
    }
    free(S.v);
    seam_patches_free(&P);
    return rc;
}

/* ---------------------------------------------------------------- pictures */

/* PNG encoding (OpenImageIO) runs on worker threads while the GL thread
 * renders the next picture. Jobs are numbered in submission order and their
 * files go into the report in that order, so the output never depends on the
 * number of workers (sc_ctx_threads; with one, encoding happens inline). At
 * most `limit` pictures wait at a time. */
typedef struct png_job {
    char path[96];
    sc_image_data *image;
    sc_buf png;
    int rc;
    sc_error err;
} png_job;

typedef struct encoder {
    pthread_t workers[4];
    int nworkers;
    pthread_mutex_t lock;
    pthread_cond_t work, room;
    png_job **jobs;
    int32_t njobs, cap, next, done, limit;
    bool closing;
    double seconds;   /* summed over workers */
} encoder;

static void encode_job(png_job *j) {
    sc_buf_init(&j->png);
    j->rc = sc_image_encode_png(j->image, 8, &j->png, &j->err);
    if (j->rc == SC_OK && j->png.failed) j->rc = sc_fail(&j->err, SC_ENOMEM, "out of memory");
    sc_image_free(j->image);
    j->image = NULL;
}

static void *encoder_main(void *ud) {
    encoder *e = ud;
    pthread_mutex_lock(&e->lock);
    for (;;) {
        while (e->next == e->njobs && !e->closing) pthread_cond_wait(&e->work, &e->lock);
        if (e->next == e->njobs) break;
        png_job *j = e->jobs[e->next++];
        pthread_mutex_unlock(&e->lock);
        double t0 = sc_now();
        encode_job(j);
        double dt = sc_now() - t0;
        pthread_mutex_lock(&e->lock);
        e->seconds += dt;
        e->done++;
        pthread_cond_signal(&e->room);
    }
    pthread_mutex_unlock(&e->lock);
    return NULL;
}

static void encoder_start(encoder *e, int threads) {
    memset(e, 0, sizeof *e);
    pthread_mutex_init(&e->lock, NULL);
    pthread_cond_init(&e->work, NULL);
    pthread_cond_init(&e->room, NULL);
    int want = threads > 1 ? (threads < 4 ? threads : 4) : 0;
    for (int i = 0; i < want; i++)
        if (pthread_create(&e->workers[e->nworkers], NULL, encoder_main, e) == 0) e->nworkers++;
    e->limit = 2 * e->nworkers + 2;
}

/* Queue a picture (rgba, bottom-up unless top_down) for path. */
static int encoder_submit(encoder *e, const char *path, const uint8_t *rgba, int32_t w, int32_t h, bool top_down,
                          sc_error *err) {
    png_job *j = calloc(1, sizeof *j);
    sc_image_data *im = sc_image_alloc(w, h, 3, SC_PIXEL_U8);
    if (!j || !im) {
        free(j);
        sc_image_free(im);
        return sc_fail(err, SC_ENOMEM, "out of memory");
    }
    snprintf(j->path, sizeof j->path, "%s", path);
    im->colorspace = SC_COLOR_SRGB;
    memcpy(im->format, "png", 4);
    uint8_t *px = im->pixels;
    for (int32_t y = 0; y < h; y++) {
        const uint8_t *src = rgba + 4 * (size_t)(top_down ? h - 1 - y : y) * (size_t)w;
        uint8_t *dst = px + 3 * (size_t)y * (size_t)w;
        for (int32_t x = 0; x < w; x++) memcpy(dst + 3 * x, src + 4 * x, 3);
    }
    j->image = im;
    pthread_mutex_lock(&e->lock);
    if (e->njobs == e->cap) {
        int32_t ncap = e->cap ? 2 * e->cap : 64;
        png_job **nj = realloc(e->jobs, sizeof *nj * (size_t)ncap);
        if (!nj) {
            pthread_mutex_unlock(&e->lock);
            sc_image_free(im);
            free(j);
            return sc_fail(err, SC_ENOMEM, "out of memory");
        }
        e->jobs = nj, e->cap = ncap;
    }
    e->jobs[e->njobs++] = j;
    if (e->nworkers == 0) {
        pthread_mutex_unlock(&e->lock);
        double t0 = sc_now();
        encode_job(j);
        e->seconds += sc_now() - t0;
        e->next++, e->done++;
        return SC_OK;
    }
    pthread_cond_signal(&e->work);
    while (e->njobs - e->done > e->limit) pthread_cond_wait(&e->room, &e->lock);
    pthread_mutex_unlock(&e->lock);
    return SC_OK;
}

/* Wait for every job, stop the workers and, when `report` is given, add the
 * files in submission order (the first failure wins). Frees everything. */
static int encoder_finish(encoder *e, sc_report *report, sc_error *err) {
    pthread_mutex_lock(&e->lock);
    e->closing = true;
    pthread_cond_broadcast(&e->work);
    pthread_mutex_unlock(&e->lock);
    for (int i = 0; i < e->nworkers; i++) pthread_join(e->workers[i], NULL);
    int rc = SC_OK;
    for (int32_t i = 0; i < e->njobs; i++) {
        png_job *j = e->jobs[i];
        if (report && rc == SC_OK && j->rc != SC_OK) {
            if (err) *err = j->err;
            rc = sc_error_prefix(err, "%s", j->path);
        }
        if (report && rc == SC_OK) {
            if (sc_report_add_file(report, j->path, j->png.data, j->png.len) != SC_OK)   /* takes the bytes */
                rc = sc_fail(err, SC_ENOMEM, "out of memory");
        } else {
            sc_buf_free(&j->png);
        }
        sc_image_free(j->image);
        free(j);
    }
    free(e->jobs);
    pthread_cond_destroy(&e->work);
    pthread_cond_destroy(&e->room);
    pthread_mutex_destroy(&e->lock);
    e->jobs = NULL;
    e->njobs = 0;
    return rc;
}

static int add_png(outcome *o, renderer *R, const char *path, const uint8_t *rgba, int32_t w, int32_t h,
                   bool top_down, sc_error *err) {
    (void)R;
    int rc = encoder_submit(o->enc, path, rgba, w, h, top_down, err);
    if (rc != SC_OK) return sc_error_prefix(err, "%s", path);
    return SC_OK;
}

typedef struct sheet {
    int32_t thumb, factor, cols, rows, width, height;
    uint8_t *rgba;    /* top-down */
} sheet;

static int sheet_init(sheet *s, int32_t size, int32_t cols, int32_t rows, sc_error *err) {
    s->factor = (size + SHEET_THUMB - 1) / SHEET_THUMB;
    s->thumb = size / s->factor;
    s->cols = cols, s->rows = rows;
    s->width = cols * (s->thumb + SHEET_GAP) + SHEET_GAP;
    s->height = rows * (s->thumb + SHEET_GAP) + SHEET_GAP;
    s->rgba = calloc((size_t)s->width * (size_t)s->height, 4);
    if (!s->rgba) return sc_fail(err, SC_ENOMEM, "out of memory");
    for (size_t i = 0; i < (size_t)s->width * (size_t)s->height; i++) s->rgba[4 * i + 3] = 255;
    return SC_OK;
}

/* Box-filter a bottom-up render into cell (row, col) of the top-down sheet. */
static void sheet_put(sheet *s, int32_t row, int32_t col, const uint8_t *rgba, int32_t size) {
    int32_t x0 = SHEET_GAP + col * (s->thumb + SHEET_GAP), y0 = SHEET_GAP + row * (s->thumb + SHEET_GAP);
    int32_t f = s->factor;
    for (int32_t ty = 0; ty < s->thumb; ty++)
        for (int32_t tx = 0; tx < s->thumb; tx++) {
            uint32_t sum[3] = {0, 0, 0};
            for (int32_t dy = 0; dy < f; dy++)
                for (int32_t dx = 0; dx < f; dx++) {
                    int32_t sy = size - 1 - (ty * f + dy), sx = tx * f + dx;
                    const uint8_t *p = rgba + 4 * ((size_t)sy * (size_t)size + (size_t)sx);
                    for (int c = 0; c < 3; c++) sum[c] += p[c];
                }
            uint8_t *d = s->rgba + 4 * ((size_t)(y0 + ty) * (size_t)s->width + (size_t)(x0 + tx));
            for (int c = 0; c < 3; c++) d[c] = (uint8_t)((sum[c] + (uint32_t)(f * f) / 2) / (uint32_t)(f * f));
        }
}

/* Mark pixel `at` (an index into a bottom-up render of size^2) in cell
 * (row, col) with a 3x3 square of colour rgb, so that a crack or fold of a
 * single pixel still shows at thumbnail size. */
static void sheet_mark(sheet *s, int32_t row, int32_t col, int32_t at, int32_t size, const uint8_t rgb[3]) {
    int32_t x0 = SHEET_GAP + col * (s->thumb + SHEET_GAP), y0 = SHEET_GAP + row * (s->thumb + SHEET_GAP);
    int32_t tx = (at % size) / s->factor, ty = (size - 1 - at / size) / s->factor;
    for (int32_t dy = -1; dy <= 1; dy++)
        for (int32_t dx = -1; dx <= 1; dx++) {
            int32_t x = tx + dx, y = ty + dy;
            if (x < 0 || y < 0 || x >= s->thumb || y >= s->thumb) continue;
            memcpy(s->rgba + 4 * ((size_t)(y0 + y) * (size_t)s->width + (size_t)(x0 + x)), rgb, 3);
        }
}

static const uint8_t crack_mark[3] = {255, 230, 0}, fold_mark[3] = {0, 200, 255};

/* ---------------------------------------------------------------- the run */

typedef struct job {
    const view *views;
    int nviews;
    int32_t size;
    int seam_points;
    double max_cracks, max_gap;
    double max_folds;         /* fold pixels a LOD may show at its own vertices (textured); -1: no limit */
    double max_map_folds;     /* the same for the modes that take positions from maps; -1: no limit */
    double fold_allowance;    /* max_fold_pixels = -1: this times the reference's back-face pixels */
    bool max_folds_from_reference;
    double pixels_per_unit;   /* view scale: size / (2 radius) */
    double max_triangles_per_pixel;   /* a finer tessellated pass is probed, not drawn; 0: draw every pass */
    bool all_pictures;        /* every view's picture; else contact sheets and views with crack candidates */
    bool uv_pictures;         /* each pictured level's uv picture too */
    uint8_t *reference;   /* nviews masks of size*size (1: near a reference back face), or NULL */
    topology reference_topology;   /* when reference is not NULL */
} job;

/* Whether pixel (x, y) is the only back-face pixel of its 3 x 3 block. */
static bool lone_back_face(const uint8_t *flags, int32_t size, int32_t x, int32_t y) {
    for (int32_t yy = y - 1; yy <= y + 1; yy++)
        for (int32_t xx = x - 1; xx <= x + 1; xx++)
            if ((xx != x || yy != y) && xx >= 0 && yy >= 0 && xx < size && yy < size &&
                flags[(size_t)yy * size + xx] == 2)
                return false;
    return true;
}

/* Crack pixels of the picture in R: back-face pixels (not near a back face
 * of the reference, for an open mesh with a reference) that are not on an
 * occluding contour. A back-face pixel is on a contour when a neighbour (3 x
 * 3) shows the background or a front face farther away: there the back
 * sheet folds under the front one and rasterisation of the two at sub-pixel
 * distance can expose a pixel of it on a perfectly closed mesh. Through a
 * crack, the back face seen lies behind all the front faces around it.
 * When the pass's seam gap is below the rasteriser's vertex grid, a crack
 * pixel with no back face among its 8 neighbours, within a pixel of a seam
 * side as drawn, is a pinhole instead (*pinholes): the two sides' vertices,
 * equal but for float rounding, fell on neighbouring grid points, and a
 * sliver that thin holds one pixel centre at most. The crack pixels' indices
 * go to R->cracks. */
static int64_t count_cracks(renderer *R, const level_gl *L, const job *J, int v, bool gap_below_grid,
                            int64_t *pinholes) {
    int32_t s = J->size;
    size_t n = (size_t)s * (size_t)s;
    const uint8_t *ref = (!L->closed && J->reference) ? J->reference + n * (size_t)v : NULL;
    const uint8_t *f = R->flags;
    const float *z = R->depth;
    int64_t count = 0;
    for (int32_t y = 0; y < s; y++)
        for (int32_t x = 0; x < s; x++) {
            size_t i = (size_t)y * s + x;
            if (f[i] != 2 || (ref && ref[i])) continue;
            bool contour = false;
            for (int32_t yy = y - 1; yy <= y + 1 && !contour; yy++)
                for (int32_t xx = x - 1; xx <= x + 1; xx++) {
                    if (xx < 0 || yy < 0 || xx >= s || yy >= s) continue;
                    size_t j = (size_t)yy * s + xx;
                    if (f[j] == 0 || (f[j] == 1 && z[j] > z[i])) {
                        contour = true;
                        break;
                    }
                }
            if (contour) continue;
            if (gap_below_grid && lone_back_face(f, s, x, y) && near_seam(R, &J->views[v], x, y)) (*pinholes)++;
            else R->cracks[count++] = (int32_t)i;
        }
    return count;
}

/* A pass's seam gaps into the node's totals and its metrics; non-zero when
 * out of memory. */
static int gap_metrics(outcome *o, const level_label *k, const pass *ps, const gap_result *gap,
                       const gap_result *map_gap) {
    o->gap_max = fmax(o->gap_max, gap->gap);
    o->vertex_gap_max = fmax(o->vertex_gap_max, gap->vertex_gap);
    return metricf(o, gap->gap, "%s.%s.max_seam_gap", k->metric, ps->name) ||
           metricf(o, gap->vertex_gap, "%s.%s.max_vertex_gap", k->metric, ps->name) ||
           (ps->pos != POS_BASE && metricf(o, map_gap->gap, "%s.%s.map_seam_gap", k->metric, ps->name));
}

static int run_pass(renderer *R, const level_gl *L, const level_label *k, const pass *ps, const job *J, outcome *o,
                    sheet *sh, int32_t row, gap_result *gap_out, sc_error *err) {
    double t0 = sc_now();
    gap_result gap = {0, 0, -1, 0};
    trace_clear(&R->trace);
    int rc = ps->level > 0 ? seam_gap_tess(R, L, ps, &gap, err)
                           : seam_gap_points(R, L, ps, J->seam_points, &gap, err);
    gap_result map_gap = {0, 0, -1, 0};
    if (rc == SC_OK && ps->pos != POS_BASE)
        rc = map_seam_gap(L, ps->pos, ps->level > 0 ? ps->level : J->seam_points - 1, &map_gap, err);
    R->t_gap += sc_now() - t0;
    if (rc != SC_OK) return sc_error_prefix(err, "%s, mode %s: seam gap", k->human, ps->name);
    if (J->max_gap >= 0 && gap.gap > J->max_gap) {
        const sc_seam_edge *se = &L->seams.seams[gap.edge];
        /* how much of it the maps hold; the rest is the GPU's sampling */
        char own[200] = "";
        const sc_texture **maps = ps->pos != POS_BASE ? position_maps(L, ps->pos) : NULL;
        double d = maps ? map_point_gap(L, maps, gap.edge, gap.edge_t) : -1;
        free(maps);
        if (d >= 0)
            snprintf(own, sizeof own, "; the maps themselves differ by %.3g there: the rest comes from the GPU's "
                     "sampling (float32 uvs, its filtering) where a map changes steeply across a chart's border", d);
        return sc_fail(err, SC_EINPUT,
                       "max_seam_gap: %s, mode %s, every view: the seam gap is %.3g of the bounding-box "
                       "diagonal, over the limit %.3g (seam edge between vertices %d and %d, faces %d and %d, "
                       "at t = %.3g%s)",
                       k->human, ps->name, gap.gap, J->max_gap, se->v0, se->v1, se->side[0].face, se->side[1].face,
                       gap.edge_t, own);
    }
    *gap_out = gap;
    if (ps->probe_only)
        return metricf(o, 0, "%s.%s.drawn", k->metric, ps->name) || gap_metrics(o, k, ps, &gap, &map_gap)
                   ? sc_fail(err, SC_ENOMEM, "out of memory")
                   : SC_OK;
    int64_t total = 0, worst = -1, pinholes = 0, folds = 0;
    int worst_view = 0;
    double gap_pixels = gap.gap * L->diag * J->pixels_per_unit;
    /* sides a rounding apart (not 0: equal vertices rasterise watertight) */
    bool gap_below_grid = gap.gap > 0 && gap_pixels < R->subpixel;
    /* welding moves no point by more than the gap: under a pixel, the welded
     * picture differs from this one only where a seam opens (a wider gap,
     * welded, could fold a strip along the seam itself) */
    bool weld_check = ps->pos != POS_BASE && (L->closed || J->reference) && gap_pixels < 1.0;
    /* no seam open (the gap is exactly 0: every side at the same vertices)
     * and no hole the reference lacks (its topology): nothing to see
     * through, so back faces come from folds */
    bool no_opening = gap.gap == 0 && J->reference && topology_equal(&L->topo, &J->reference_topology);
    captured_free(&R->surface);
    if (ps->level > 0) {
        t0 = sc_now();
        rc = capture_surface(R, L, ps, err);
        R->t_render += sc_now() - t0;
        if (rc != SC_OK) return sc_error_prefix(err, "%s, mode %s: capturing the tessellated surface", k->human,
                                                ps->name);
    }
    for (int v = 0; v < J->nviews; v++) {
        t0 = sc_now();
        rc = draw(R, L, ps, &J->views[v], false, R->surface.vao ? &R->surface : NULL, err);
        if (rc == SC_OK) rc = read_target(R, err);
        R->t_render += sc_now() - t0;
        if (rc != SC_OK) return sc_error_prefix(err, "%s, mode %s, view %s", k->human, ps->name, J->views[v].name);
        int64_t cracks = count_cracks(R, L, J, v, gap_below_grid, &pinholes);
        /* the view's own picture: always with pictures = all, else only if
         * crack pixels remain once folds are told apart (the welded draw
         * below overwrites the picture, so it is held until then) */
        char path[200];
        snprintf(path, sizeof path, "%s/%s_%s_%s.png", o->folder, k->file, ps->name, J->views[v].name);
        size_t picture_bytes = (size_t)J->size * (size_t)J->size * 4;
        uint8_t *held = !J->all_pictures && cracks > 0 ? malloc(picture_bytes) : NULL;
        if (!J->all_pictures && cracks > 0 && !held) return sc_fail(err, SC_ENOMEM, "out of memory");
        if (held) memcpy(held, R->rgba, picture_bytes);
        if (J->all_pictures && (rc = add_png(o, R, path, R->rgba, J->size, J->size, false, err)) != SC_OK) return rc;
        sheet_put(sh, row, v, R->rgba, J->size);
        o->renders++;
        if (no_opening) {
            for (int64_t c = 0; c < cracks; c++) sheet_mark(sh, row, v, R->cracks[c], J->size, fold_mark);
            folds += cracks;
            cracks = 0;
        } else if (cracks > 0 && weld_check) {
            /* the same pass with every seam welded shut: a crack pixel that
             * shows a back face there too is a fold, not an opening seam;
             * so is one beside such a back face when the gap is under the
             * rasteriser's grid: welding moved the fold's edge by less than
             * a grid step, and a seam that narrow opens no more than a lone
             * pixel (a pinhole), so this pixel is the fold's edge */
            t0 = sc_now();
            rc = draw(R, L, ps, &J->views[v], true, NULL, err);
            if (rc == SC_OK) rc = read_target(R, err);
            R->t_render += sc_now() - t0;
            if (rc != SC_OK) {
                free(held);
                return sc_error_prefix(err, "%s, mode %s, view %s, welded", k->human, ps->name, J->views[v].name);
            }
            int64_t kept = 0;
            for (int64_t c = 0; c < cracks; c++) {
                int32_t x = R->cracks[c] % J->size, y = R->cracks[c] / J->size;
                bool fold = R->flags[R->cracks[c]] == 2 ||
                            (gap_below_grid && !lone_back_face(R->flags, J->size, x, y));
                sheet_mark(sh, row, v, R->cracks[c], J->size, fold ? fold_mark : crack_mark);
                if (fold) folds++;
                else kept++;
            }
            cracks = kept;
        } else {
            for (int64_t c = 0; c < cracks; c++) sheet_mark(sh, row, v, R->cracks[c], J->size, crack_mark);
        }
        if (held && cracks > 0) rc = add_png(o, R, path, held, J->size, J->size, false, err);
        free(held);
        if (rc != SC_OK) return rc;
        total += cracks;
        if (cracks > worst) worst = cracks, worst_view = v;
    }
    captured_free(&R->surface);
    o->crack_total += (double)total;
    o->pinhole_total += (double)pinholes;
    o->fold_total += (double)folds;
    if ((ps->level > 0 && metricf(o, 1, "%s.%s.drawn", k->metric, ps->name)) ||
        metricf(o, (double)total, "%s.%s.crack_pixels", k->metric, ps->name) ||
        metricf(o, (double)pinholes, "%s.%s.pinhole_pixels", k->metric, ps->name) ||
        metricf(o, (double)folds, "%s.%s.fold_pixels", k->metric, ps->name) || gap_metrics(o, k, ps, &gap, &map_gap))
        return sc_fail(err, SC_ENOMEM, "out of memory");
    /* folds at the level's own vertices are decimation's; those of the
     * positions maps give (geometry image, displacement) are the maps' */
    double max_folds = ps->pos == POS_BASE ? J->max_folds : J->max_map_folds;
    if (max_folds >= 0 && (double)folds > max_folds)
        return sc_fail(err, SC_EINPUT,
                       "%s: %s, mode %s: %lld fold pixels (back faces that no opening explains) over the limit "
                       "%.17g%s",
                       ps->pos == POS_BASE ? "max_fold_pixels" : "max_map_fold_pixels", k->human, ps->name,
                       (long long)folds, max_folds,
                       ps->pos == POS_BASE && J->reference && J->max_folds_from_reference
                           ? " (fold_allowance times the reference's back-face pixels)"
                           : "");
    if (J->max_cracks >= 0 && (double)total > J->max_cracks)
        return sc_fail(err, SC_EINPUT,
                       "max_crack_pixels: %s, mode %s, view %s: %lld crack pixels in this mode (%lld in view "
                       "%s), over the limit %.17g%s",
                       k->human, ps->name, J->views[worst_view].name, (long long)total, (long long)worst,
                       J->views[worst_view].name, J->max_cracks,
                       L->closed ? "" : J->reference ? " (open mesh, compared with the reference)"
                                                     : " (open mesh and no reference connected: every back "
                                                       "face counts)");
    return SC_OK;
}

/* Whether a tessellated pass at `level` may be probed without being drawn:
 * its triangles outnumber the pixels (max_triangles_per_pixel per pixel of
 * a view), and what its pictures could add, the probe bounds. Its views
 * would show a seam opening where the two sides' tessellated points lie
 * apart; the probe measures those very points (the pass's own program and
 * level), and max_seam_gap, at or under the rasteriser's vertex grid here,
 * fails every gap wide enough to move a vertex by a grid step. A narrower
 * opening shows as lone pinholes, or as a line where it runs along a row of
 * pixel centres, which the drawn levels still count on the same seams. The
 * other gates that read pictures (folds of the maps) are off, as they are
 * by default. */
static bool probe_suffices(const renderer *R, const level_gl *L, const job *J, int level) {
    if (!(J->max_triangles_per_pixel > 0) || J->max_gap < 0 || J->max_map_folds >= 0 || !(R->subpixel > 0))
        return false;
    double triangles = (double)L->mesh->nf * level * level, pixels = (double)J->size * J->size;
    return triangles > J->max_triangles_per_pixel * pixels && J->max_gap * L->diag * J->pixels_per_unit <= R->subpixel;
}

/* Render the reference from every view: masks of back faces, dilated, and
 * its contact sheet (render/reference_sheet.png), which the report shows
 * beside each level's. */
static int render_reference(renderer *R, const sc_atlas *ref, job *J, outcome *o, sc_error *err) {
    level_gl L;
    int rc = level_upload(R, ref, "reference", &L, err);
    if (rc != SC_OK) {
        level_free(&L);
        return rc;
    }
    size_t n = (size_t)J->size * (size_t)J->size;
    J->reference_topology = L.topo;
    J->reference = calloc((size_t)J->nviews, n);
    sheet sh = {0};
    if (!J->reference || sheet_init(&sh, J->size, J->nviews, 1, err) != SC_OK) {
        level_free(&L);
        return sc_fail(err, SC_ENOMEM, "out of memory");
    }
    pass ps = {MODE_TEXTURED, POS_BASE, 0, "textured"};
    int64_t back = 0;
    int v = 0;
    for (; v < J->nviews && rc == SC_OK; v++) {
        double t0 = sc_now();
        rc = draw(R, &L, &ps, &J->views[v], false, NULL, err);
        if (rc == SC_OK) rc = read_target(R, err);
        R->t_render += sc_now() - t0;
        if (rc != SC_OK) break;
        uint8_t *mask = J->reference + n * (size_t)v;
        int32_t s = J->size;
        sheet_put(&sh, 0, v, R->rgba, s);
        for (int32_t y = 0; y < s; y++)
            for (int32_t x = 0; x < s; x++) {
                if (R->flags[(size_t)y * s + x] != 2) continue;
                back++;
                for (int32_t dy = -REFERENCE_SLACK; dy <= REFERENCE_SLACK; dy++)
                    for (int32_t dx = -REFERENCE_SLACK; dx <= REFERENCE_SLACK; dx++) {
                        int32_t yy = y + dy, xx = x + dx;
                        if (yy >= 0 && yy < s && xx >= 0 && xx < s) mask[(size_t)yy * s + xx] = 1;
                    }
            }
        if (J->all_pictures) {
            char path[200];
            snprintf(path, sizeof path, "%s/reference_%s.png", o->folder, J->views[v].name);
            rc = add_png(o, R, path, R->rgba, s, s, false, err);
            if (rc != SC_OK) break;
        }
    }
    level_free(&L);
    if (rc != SC_OK) {
        free(sh.rgba);
        return sc_error_prefix(err, "reference, view %s", J->views[v].name);
    }
    char path[200];
    snprintf(path, sizeof path, "%s/reference_sheet.png", o->folder);
    rc = add_png(o, R, path, sh.rgba, sh.width, sh.height, true, err);
    free(sh.rgba);
    if (rc != SC_OK) return rc;
    if (metric(o, "reference.back_pixels", (double)back)) return sc_fail(err, SC_ENOMEM, "out of memory");
    if (J->max_folds < 0) {
        J->max_folds = J->fold_allowance * (double)back;
        J->max_folds_from_reference = true;
    }
    return SC_OK;
}

/* The colour texture of one material with the level's uv silhouettes drawn
 * over it: seam sides red, surface boundaries yellow, foldovers magenta,
 * non-manifold edges cyan. At most UV_PICTURE pixels a side (box-filtered);
 * grey where the material has no colour texture. */
#define UV_PICTURE 512

static void uv_line(uint8_t *rgba, int32_t w, int32_t h, const double *a, const double *b, const uint8_t c[3]) {
    double x0 = a[0] * w, y0 = (1.0 - a[1]) * h, x1 = b[0] * w, y1 = (1.0 - b[1]) * h;
    double len = fmax(fabs(x1 - x0), fabs(y1 - y0));
    if (!(len < 1e6)) return;   /* NaN or absurd uvs */
    int32_t steps = (int32_t)ceil(len) + 1;
    for (int32_t i = 0; i <= steps; i++) {
        double t = (double)i / steps;
        int32_t x = (int32_t)floor(x0 + t * (x1 - x0)), y = (int32_t)floor(y0 + t * (y1 - y0));
        if (x < 0 || y < 0 || x >= w || y >= h) continue;
        uint8_t *p = rgba + 4 * ((size_t)y * (size_t)w + (size_t)x);
        p[0] = c[0], p[1] = c[1], p[2] = c[2], p[3] = 255;
    }
}

/* The seam energy (eq. 9) and largest sampled gap of every texture of the
 * level, on the level's own seams: a seam left in a texture shows here as a
 * number, whatever the pictures show. Metrics <label>.seam_energy.<slot> and
 * <label>.seam_gap.<slot> (with _<material> after the slot when there are
 * several materials). */
static int texture_seam_metrics(outcome *o, const level_gl *L, const level_label *k, sc_error *err) {
    const sc_atlas *a = L->atlas;
    const sc_mesh *m = L->mesh;
    int rc = SC_OK;
    for (int32_t mat = 0; mat < m->nmat && rc == SC_OK; mat++) {
        bool any = false;
        for (int32_t t = 0; t < a->ntex; t++) any |= a->textures[t].material == mat;
        if (!any) continue;
        sc_seam_set own = {0};
        const sc_seam_set *seams = &own;
        if (m->nmat == 1) seams = &L->seams;   /* one material: the level's seams are its seams */
        else if ((rc = sc_seam_find(m, mat, &own, err)) != SC_OK) return rc;
        for (int32_t t = 0; t < a->ntex && rc == SC_OK; t++) {
            const sc_texture *tex = &a->textures[t];
            if (tex->material != mat) continue;
            const sc_image_data *im = tex->image->as.image;
            sc_seam_grid g = {im->width, im->height, tex->wrap_u, tex->wrap_v};
            double energy = 0, gap = 0;
            rc = sc_seam_energy(m, seams, &g, im, sc_ctx_threads(o->ctx), &energy, &gap, err);
            if (rc != SC_OK) break;
            char suffix[24] = "";
            if (m->nmat > 1) snprintf(suffix, sizeof suffix, "_%d", mat);
            if (metricf(o, energy, "%s.seam_energy.%s%s", k->metric, tex->name, suffix) ||
                metricf(o, gap, "%s.seam_gap.%s%s", k->metric, tex->name, suffix))
                rc = sc_fail(err, SC_ENOMEM, "out of memory");
        }
        if (seams == &own) sc_seam_set_free(&own);
    }
    return rc == SC_OK ? rc : sc_error_prefix(err, "%s: texture seams", k->human);
}

static int uv_picture(renderer *R, const level_gl *L, const level_label *k, int32_t material, outcome *o, sc_error *err) {
    int i = sc_atlas_find_texture(L->atlas, material, "color");
    const sc_image_data *im = i >= 0 ? L->atlas->textures[i].image->as.image : NULL;
    int32_t tw = im ? im->width : UV_PICTURE, th = im ? im->height : UV_PICTURE;
    int32_t f = (int32_t)((tw > th ? tw : th) + UV_PICTURE - 1) / UV_PICTURE;
    int32_t w = tw / f > 0 ? tw / f : 1, h = th / f > 0 ? th / f : 1;
    uint8_t *rgba = malloc((size_t)w * (size_t)h * 4);
    if (!rgba) return sc_fail(err, SC_ENOMEM, "out of memory");
    for (int32_t y = 0; y < h; y++)   /* top-down */
        for (int32_t x = 0; x < w; x++) {
            uint8_t *p = rgba + 4 * ((size_t)y * (size_t)w + (size_t)x);
            p[3] = 255;
            if (!im) {
                p[0] = p[1] = p[2] = 128;
                continue;
            }
            double sum[3] = {0, 0, 0};
            for (int32_t dy = 0; dy < f; dy++)
                for (int32_t dx = 0; dx < f; dx++) {
                    int32_t tx = x * f + dx, ty = th - 1 - (y * f + dy);
                    for (int c = 0; c < 3; c++)
                        sum[c] += sc_image_texel(im, tx, ty, im->channels >= 3 ? c : 0);
                }
            for (int c = 0; c < 3; c++) {
                double v = sum[c] / ((double)f * f);
                if (im->colorspace == SC_COLOR_LINEAR) v = sc_linear_to_srgb((float)v);   /* shown as displayed */
                p[c] = (uint8_t)lrint(255.0 * (v < 0 ? 0 : v > 1 ? 1 : v));
            }
        }
    static const uint8_t colors[4][3] = {{255, 40, 40}, {255, 220, 0}, {255, 0, 255}, {0, 230, 255}};
    const sc_mesh *m = L->mesh;
    for (int32_t s = 0; s < L->seams.nsil; s++) {
        const sc_seam_silhouette *sil = &L->seams.sil[s];
        if (m->FM[sil->side.face] != material) continue;
        int kind = (int)sil->kind >= 0 && (int)sil->kind < 4 ? (int)sil->kind : 0;
        uv_line(rgba, w, h, m->U + 2 * sil->side.uv0, m->U + 2 * sil->side.uv1, colors[kind]);
    }
    char path[200];
    if (m->nmat == 1) snprintf(path, sizeof path, "%s/%s_uv.png", o->folder, k->file);
    else snprintf(path, sizeof path, "%s/%s_uv_%d.png", o->folder, k->file, material);
    int rc = add_png(o, R, path, rgba, w, h, true, err);
    free(rgba);
    return rc;
}

static int run_level(renderer *R, const sc_atlas *atlas, const level_label *k, const char *who, const bool want[MODE_COUNT],
                     const int *levels, int nlevels, const job *J, outcome *o, sc_error *err) {
    level_gl L;
    int rc = level_upload(R, atlas, who, &L, err);
    if (rc != SC_OK) {
        level_free(&L);
        return rc;
    }
    if (metricf(o, L.mesh->nf, "%s.faces", k->metric) || metricf(o, L.seams.nseams, "%s.seam_edges", k->metric) ||
        metricf(o, L.closed ? 1 : 0, "%s.closed", k->metric) ||
        (J->reference && metricf(o, topology_equal(&L.topo, &J->reference_topology) ? 1 : 0,
                                 "%s.same_topology", k->metric))) {
        level_free(&L);
        return sc_fail(err, SC_ENOMEM, "out of memory");
    }
    rc = texture_seam_metrics(o, &L, k, err);
    if (rc != SC_OK) {
        level_free(&L);
        return rc;
    }
    pass passes[MAX_PASSES];
    int npasses = 0;
    static const int pos_of_mode[3] = {POS_BASE, POS_GEOMETRY, POS_DISPLACED};
    for (int m = 0; m < MODE_TESSELLATED && rc == SC_OK; m++) {
        if (!want[m]) continue;
        if (!level_has(&L, pos_of_mode[m])) {
            rc = metricf(o, 1, "%s.%s.skipped", k->metric, mode_names[m]);
            o->skipped++;
            continue;
        }
        if (m != MODE_TEXTURED) rc = check_position_texture(&L, who, pos_of_mode[m], err);
        pass *p = &passes[npasses++];
        *p = (pass){m, pos_of_mode[m], 0, ""};
        snprintf(p->name, sizeof p->name, "%s", mode_names[m]);
    }
    int tess_pos = level_has(&L, POS_GEOMETRY) ? POS_GEOMETRY : level_has(&L, POS_DISPLACED) ? POS_DISPLACED : -1;
    if (rc == SC_OK && want[MODE_TESSELLATED]) {
        if (tess_pos < 0 || nlevels == 0) {
            rc = metricf(o, 1, "%s.tessellated.skipped", k->metric);
            o->skipped++;
        } else {
            rc = check_position_texture(&L, who, tess_pos, err);
            if (rc == SC_OK)
                rc = metricf(o, tess_pos == POS_GEOMETRY ? 1 : 2, "%s.tessellated.source", k->metric);
            int lowest = levels[0];
            for (int i = 1; i < nlevels; i++) lowest = levels[i] < lowest ? levels[i] : lowest;
            for (int i = 0; i < nlevels && rc == SC_OK; i++) {
                pass *p = &passes[npasses++];
                *p = (pass){MODE_TESSELLATED, tess_pos, levels[i], "", false};
                snprintf(p->name, sizeof p->name, "tessellated%d", levels[i]);
                p->probe_only = levels[i] != lowest && probe_suffices(R, &L, J, levels[i]);
            }
        }
    }
    if (rc != SC_OK) {
        level_free(&L);
        return rc == SC_ENOMEM ? sc_fail(err, SC_ENOMEM, "out of memory") : rc;
    }
    int ndrawn = 0;
    for (int p = 0; p < npasses; p++) ndrawn += !passes[p].probe_only;
    sheet sh = {0};
    rc = sheet_init(&sh, J->size, J->nviews, ndrawn > 0 ? ndrawn : 1, err);
    double tess_cracks = 0, tess_gap = 0, tess_vgap = 0, level_gap = 0;
    const double cracks_before = o->crack_total, folds_before = o->fold_total;
    for (int p = 0, row = 0; p < npasses && rc == SC_OK; p++) {
        double before = o->crack_total;
        gap_result gap = {0, 0, -1, 0};
        rc = run_pass(R, &L, k, &passes[p], J, o, &sh, row, &gap, err);
        row += !passes[p].probe_only;
        level_gap = fmax(level_gap, gap.gap);
        if (rc == SC_OK && passes[p].level > 0) {
            tess_cracks += o->crack_total - before;
            tess_gap = fmax(tess_gap, gap.gap);
            tess_vgap = fmax(tess_vgap, gap.vertex_gap);
        }
    }
    if (rc == SC_OK && tess_pos >= 0 && want[MODE_TESSELLATED] && nlevels > 0) {
        if (metricf(o, tess_cracks, "%s.tessellated.crack_pixels", k->metric) ||
            metricf(o, tess_gap, "%s.tessellated.max_seam_gap", k->metric) ||
            metricf(o, tess_vgap, "%s.tessellated.max_vertex_gap", k->metric))
            rc = sc_fail(err, SC_ENOMEM, "out of memory");
    }
    /* the level's totals over its passes, the report's one row per level */
    if (rc == SC_OK && npasses > 0 &&
        (metricf(o, o->crack_total - cracks_before, "%s.crack_pixels", k->metric) ||
         metricf(o, o->fold_total - folds_before, "%s.fold_pixels", k->metric) ||
         metricf(o, level_gap, "%s.max_seam_gap", k->metric)))
        rc = sc_fail(err, SC_ENOMEM, "out of memory");
    /* one contact sheet per LOD: a mip level past the first has its sheet
     * and uv pictures only when it shows cracks, or folds that a gate
     * bounds (or pictures = all); the folds of coarse maps, ungated by
     * default, are numbers in the report */
    bool pictures = J->all_pictures || k->mip == 0 || o->crack_total > cracks_before ||
                    (J->max_map_folds >= 0 && o->fold_total > folds_before);
    if (rc == SC_OK && npasses > 0 && pictures) {
        char path[200];
        snprintf(path, sizeof path, "%s/%s_sheet.png", o->folder, k->file);
        rc = add_png(o, R, path, sh.rgba, sh.width, sh.height, true, err);
    }
    for (int32_t g = 0; g < L.ngroups && rc == SC_OK && pictures && J->uv_pictures; g++)
        rc = uv_picture(R, &L, k, L.groups[g].material, o, err);
    free(sh.rgba);
    level_free(&L);
    return rc;
}

/* Widen lo/hi by the vertices of atlas `a` where the position modes draw
 * them: the geometry image at the vertex's uv, and the vertex plus the
 * displacement there (bilinear, float maps of 3+ channels). */
static void add_drawn_vertices(const sc_atlas *a, double lo[3], double hi[3]) {
    const sc_mesh *m = a->mesh->as.mesh;
    for (int32_t t = 0; t < a->ntex; t++) {
        const sc_texture *tx = &a->textures[t];
        const sc_image_data *im = tx->image->as.image;
        bool offsets = strcmp(tx->name, "displacement") == 0;
        if ((!offsets && strcmp(tx->name, "geometry_image") != 0) || im->pixel != SC_PIXEL_F32 || im->channels < 3)
            continue;
        sc_seam_grid g = {im->width, im->height, tx->wrap_u, tx->wrap_v};
        for (int32_t f = 0; f < m->nf; f++) {
            if (m->FM[f] != tx->material) continue;
            for (int c = 0; c < 3; c++) {
                const double *uv = &m->U[2 * m->FU[3 * f + c]], *base = &m->V[3 * m->FV[3 * f + c]];
                double p[4];
                sc_seam_sample(&g, im->pixels, im->channels, uv[0], uv[1], p);
                for (int k = 0; k < 3; k++) {
                    double x = offsets ? base[k] + p[k] : p[k];
                    if (x < lo[k]) lo[k] = x;
                    if (x > hi[k]) hi[k] = x;
                }
            }
        }
    }
}

/* Entry b is the next mip level of entry a (the mipmap node's `levels`
 * output lists every LOD's mip chain in order): the same mesh, textures of
 * the same slots, each half the size (rounded down, at least 1) or, where its
 * chain has ended, the same size, and at least one of them halved. */
static bool is_mip_of(const sc_atlas *b, const sc_atlas *a) {
    if (!sc_digest_equal(sc_value_digest(a->mesh), sc_value_digest(b->mesh)) || a->ntex != b->ntex || a->ntex == 0)
        return false;
    bool halved = false;
    for (int32_t t = 0; t < a->ntex; t++) {
        const sc_image_data *ia = a->textures[t].image->as.image, *ib = b->textures[t].image->as.image;
        int32_t w = ia->width / 2 > 0 ? ia->width / 2 : 1, h = ia->height / 2 > 0 ? ia->height / 2 : 1;
        if (strcmp(a->textures[t].name, b->textures[t].name) != 0) return false;
        bool half = ib->width == w && ib->height == h && (ia->width > 1 || ia->height > 1);
        bool same = ib->width == ia->width && ib->height == ia->height;
        if (!half && !same) return false;
        halved |= half;
    }
    return halved;
}

/* What one level added to the run's totals, for a level that repeats it. */
typedef struct level_tally {
    double cracks, pinholes, folds;
} level_tally;

/* The entry of `lods` before k holding the same atlas (mesh and every map,
 * by digest: a decimation that stopped gives its next level the same mesh),
 * or -1. */
static int32_t same_level_before(const sc_lods *lods, int32_t k) {
    for (int32_t j = 0; lods && j < k; j++)
        if (sc_digest_equal(sc_value_digest(lods->levels[j]), sc_value_digest(lods->levels[k]))) return j;
    return -1;
}

/* Whether metric `name` belongs to level `prefix` ("lod1.mip2"): the name
 * itself, or the prefix and a dot. Returns the suffix ("" or ".faces"). */
static const char *level_suffix(const char *name, const char *prefix) {
    size_t n = strlen(prefix);
    if (strncmp(name, prefix, n) != 0 || (name[n] != 0 && name[n] != '.')) return NULL;
    return name + n;
}

/* Level k repeats level j: the same pictures render the same bytes, so its
 * metrics are j's under k's name, its totals count again, and it says
 * which level it repeats. */
static int repeat_level(outcome *o, const level_label *j, const level_label *k, int32_t j_index,
                        const level_tally *t) {
    int32_t n = o->report->nmetrics;
    for (int32_t i = 0; i < n; i++) {
        const char *suffix = level_suffix(o->report->metrics[i].name, j->metric);
        if (suffix && metricf(o, o->report->metrics[i].value, "%s%s", k->metric, suffix)) return SC_ENOMEM;
    }
    o->crack_total += t->cracks, o->pinhole_total += t->pinholes, o->fold_total += t->folds;
    return metricf(o, j_index, "%s.repeats_level", k->metric) ? SC_ENOMEM : SC_OK;
}

/* The pictures of level j again under level k's name (after the encoder has
 * finished): "render/lod1_sheet.png" as "render/lod2_sheet.png". */
static int repeat_pictures(outcome *o, const level_label *j, const level_label *k) {
    char from[96], to[96];
    snprintf(from, sizeof from, "%s/%s_", o->folder, j->file);
    snprintf(to, sizeof to, "%s/%s_", o->folder, k->file);
    return sc_report_copy_files(o->report, from, to);
}

static int run(sc_ctx *ctx, sc_error *err) {
    double t_start = sc_now();
    const sc_lods *lods = sc_ctx_lods(ctx, "lods");
    const sc_atlas *single = sc_ctx_atlas(ctx, "atlas");
    const sc_atlas *reference = sc_ctx_atlas(ctx, "reference");
    if (!lods && !single) return sc_fail(err, SC_EINPUT, "lods: connect `lods` or `atlas` (nothing to render)");
    if (lods && single) return sc_fail(err, SC_EINPUT, "atlas: connect `lods` or `atlas`, not both");
    int32_t nlevels = lods ? lods->count : 1;
    if (nlevels < 1) return sc_fail(err, SC_EINPUT, "lods: the list is empty");

    bool want[MODE_COUNT];
    int rc = parse_modes(sc_ctx_string(ctx, "modes"), want, err);
    if (rc != SC_OK) sc_error_prefix(err, "modes");
    int levels[MAX_TESS_LEVELS], ntess = 0;
    if (rc == SC_OK) rc = parse_levels(ctx, levels, &ntess, err);
    if (rc != SC_OK) return rc;

    job J = {0};
    J.nviews = (int)sc_ctx_integer(ctx, "views");
    J.size = (int32_t)sc_ctx_integer(ctx, "size");
    J.seam_points = (int)sc_ctx_integer(ctx, "seam_points");
    J.max_cracks = sc_ctx_number(ctx, "max_crack_pixels");
    J.max_folds = sc_ctx_number(ctx, "max_fold_pixels");   /* -1 and a reference: set with it */
    J.fold_allowance = sc_ctx_number(ctx, "fold_allowance");
    J.max_map_folds = sc_ctx_number(ctx, "max_map_fold_pixels");
    J.max_gap = sc_ctx_number(ctx, "max_seam_gap");
    J.all_pictures = strcmp(sc_ctx_string(ctx, "pictures"), "all") == 0;
    J.uv_pictures = sc_ctx_bool(ctx, "uv_pictures");
    if (check_folder(sc_ctx_string(ctx, "folder"), err) != SC_OK) return sc_error_prefix(err, "folder");

    /* one framing for every level and the reference */
    double lo[3] = {HUGE_VAL, HUGE_VAL, HUGE_VAL}, hi[3] = {-HUGE_VAL, -HUGE_VAL, -HUGE_VAL};
    for (int32_t k = 0; k < nlevels; k++) {
        const sc_atlas *a = lods ? lods->levels[k]->as.atlas : single;
        sc_bbox_add(a->mesh->as.mesh->V, a->mesh->as.mesh->nv, lo, hi);
    }
    if (reference) sc_bbox_add(reference->mesh->as.mesh->V, reference->mesh->as.mesh->nv, lo, hi);
    if (!(lo[0] <= hi[0])) return sc_fail(err, SC_EINPUT, "lods: no vertices to render");
    for (int32_t k = 0; k < nlevels; k++) add_drawn_vertices(lods ? lods->levels[k]->as.atlas : single, lo, hi);
    double center[3], ext[3];
    for (int c = 0; c < 3; c++) center[c] = 0.5 * (lo[c] + hi[c]), ext[c] = hi[c] - lo[c];
    double radius = 0.5 * sc_norm3(ext) * 1.02;
    if (!(radius > 0) || !isfinite(radius)) radius = 1;
    view *views = calloc((size_t)J.nviews, sizeof *views);
    if (!views) return sc_fail(err, SC_ENOMEM, "out of memory");
    make_views(views, J.nviews, center, radius);
    J.views = views;
    J.pixels_per_unit = J.size / (2.0 * radius);
    J.max_triangles_per_pixel = sc_ctx_number(ctx, "max_triangles_per_pixel");

    encoder enc;
    encoder_start(&enc, sc_ctx_threads(ctx));
    outcome o = {.ctx = ctx, .report = sc_report_new(), .enc = &enc, .folder = sc_ctx_string(ctx, "folder")};
    renderer R = {0};
    R.size = J.size;
    if (!o.report) rc = sc_fail(err, SC_ENOMEM, "out of memory");
    double t0 = sc_now();
    if (rc == SC_OK) rc = sc_gl_open(&R.gl, err);
    if (rc == SC_OK) {
        GLint bits = 0;
        glGetIntegerv(GL_SUBPIXEL_BITS, &bits);
        R.subpixel_bits = bits > 0 && bits < 30 ? bits : 0;
        R.subpixel = R.subpixel_bits ? ldexp(1.0, -R.subpixel_bits) : 0.0;
    }
    double t_context = sc_now() - t0;
    if (rc == SC_OK) {
        R.rgba = malloc((size_t)J.size * (size_t)J.size * 4);
        R.flags = malloc((size_t)J.size * (size_t)J.size);
        R.depth = malloc(sizeof(float) * (size_t)J.size * (size_t)J.size);
        R.cracks = malloc(sizeof(int32_t) * (size_t)J.size * (size_t)J.size);
        if (!R.rgba || !R.flags || !R.depth || !R.cracks) rc = sc_fail(err, SC_ENOMEM, "out of memory");
    }
    if (rc == SC_OK) rc = sc_gl_target_create(&R.target, J.size, J.size, err);
    if (rc == SC_OK && reference) rc = render_reference(&R, reference, &J, &o, err);
    int lod = -1, mip = 0;
    level_label *labels = calloc((size_t)nlevels, sizeof *labels);
    level_tally *tallies = calloc((size_t)nlevels, sizeof *tallies);
    int32_t *repeats = calloc((size_t)nlevels, sizeof *repeats);
    if (rc == SC_OK && (!labels || !tallies || !repeats)) rc = sc_fail(err, SC_ENOMEM, "out of memory");
    for (int32_t k = 0; k < nlevels && rc == SC_OK; k++) {
        const sc_atlas *a = lods ? lods->levels[k]->as.atlas : single;
        if (k > 0 && is_mip_of(a, lods->levels[k - 1]->as.atlas)) mip++;
        else lod++, mip = 0;
        bool has_mips = mip > 0 || (k + 1 < nlevels && is_mip_of(lods->levels[k + 1]->as.atlas, a));
        level_label label = {.mip = has_mips ? mip : 0};
        if (has_mips) {
            snprintf(label.metric, sizeof label.metric, "lod%d.mip%d", lod, mip);
            snprintf(label.file, sizeof label.file, "lod%d_mip%d", lod, mip);
            /* the size tells which mip_min would stop before this level */
            const sc_image_data *map = largest_map(a);
            if (map)
                snprintf(label.human, sizeof label.human, "lod %d, mip %d (%d x %d maps)", lod, mip,
                         (int)map->width, (int)map->height);
            else
                snprintf(label.human, sizeof label.human, "lod %d, mip %d", lod, mip);
        } else {
            snprintf(label.metric, sizeof label.metric, "lod%d", lod);
            snprintf(label.file, sizeof label.file, "lod%d", lod);
            snprintf(label.human, sizeof label.human, "lod %d", lod);
        }
        labels[k] = label;
        repeats[k] = same_level_before(lods, k);
        if (repeats[k] >= 0) {
            if (repeat_level(&o, &labels[repeats[k]], &label, repeats[k], &tallies[repeats[k]]) != SC_OK)
                rc = sc_fail(err, SC_ENOMEM, "out of memory");
            continue;
        }
        char who[48];
        if (lods) snprintf(who, sizeof who, "lods: level %d", k);
        else snprintf(who, sizeof who, "atlas");
        level_tally before = {o.crack_total, o.pinhole_total, o.fold_total};
        rc = run_level(&R, a, &label, who, want, levels, ntess, &J, &o, err);
        tallies[k] = (level_tally){o.crack_total - before.cracks, o.pinhole_total - before.pinholes,
                                   o.fold_total - before.folds};
    }
    if (rc == SC_OK &&
        (metric(&o, "levels", nlevels) || metric(&o, "views", J.nviews) || metric(&o, "size", J.size) ||
         metric(&o, "renders", o.renders) || metric(&o, "skipped_modes", o.skipped) ||
         metric(&o, "crack_pixels", o.crack_total) || metric(&o, "pinhole_pixels", o.pinhole_total) ||
         metric(&o, "fold_pixels", o.fold_total) ||
         metric(&o, "subpixel_bits", R.subpixel_bits) || metric(&o, "max_seam_gap", o.gap_max) ||
         metric(&o, "max_vertex_gap", o.vertex_gap_max)))
        rc = sc_fail(err, SC_ENOMEM, "out of memory");
    double t_render = R.t_render, t_gap = R.t_gap;
    t0 = sc_now();
    renderer_free(&R);
    t_context += sc_now() - t0;
    t0 = sc_now();
    int rc_png = encoder_finish(&enc, rc == SC_OK ? o.report : NULL, err);
    if (rc == SC_OK) rc = rc_png;
    for (int32_t k = 0; k < nlevels && rc == SC_OK; k++)
        if (repeats[k] >= 0 && repeat_pictures(&o, &labels[repeats[k]], &labels[k]) != SC_OK)
            rc = sc_fail(err, SC_ENOMEM, "out of memory");
    free(labels), free(tallies), free(repeats);
    double t_encode = enc.seconds, t_drain = sc_now() - t0;
    free(views);
    free(J.reference);
    if (rc != SC_OK) {
        sc_report_free(o.report);
        return rc;
    }
    sc_value *out = sc_value_new_report(o.report);
    if (!out) return sc_fail(err, SC_ENOMEM, "out of memory");
    /* timings: node metrics only, never part of the report value */
    sc_ctx_metric(ctx, "seconds_context", t_context);
    sc_ctx_metric(ctx, "seconds_render", t_render);
    sc_ctx_metric(ctx, "seconds_seam_gap", t_gap);
    sc_ctx_metric(ctx, "seconds_encode", t_encode);
    sc_ctx_metric(ctx, "seconds_encode_wait", t_drain);
    sc_ctx_metric(ctx, "seconds_total", sc_now() - t_start);
    sc_ctx_set_output(ctx, "report", out);
    return SC_OK;
}

static const char *const picture_choices[] = {"sheets", "all", NULL};

static const sc_param_desc params[] = {
    {.name = "modes", .type = SC_PARAM_STRING, .def_string = "textured,geometry_image,displaced,tessellated",
     .doc = "comma-separated render modes: textured, geometry_image (needs the texture slot geometry_image), "
            "displaced (needs displacement), tessellated (needs either)",
     .check_text = check_modes},
    {.name = "pictures", .type = SC_PARAM_ENUM, .def_string = "sheets", .choices = picture_choices,
     .doc = "sheets: one contact sheet per LOD (and its uv picture; for a mip chain, its first level's, and "
            "another level's only where it shows cracks, or folds that max_map_fold_pixels bounds), plus the "
            "picture of every view with crack candidates; all: every view's picture, every level's sheet and the "
            "reference's too"},
    {.name = "uv_pictures", .type = SC_PARAM_BOOL, .def = 1,
     .doc = "with each pictured level's sheet, its uv picture; 0 leaves them to another check of the same "
            "levels (the main job's map check, whose levels have the textured check's uv)"},
    {.name = "views", .type = SC_PARAM_INTEGER, .def = 10, .min = 1, .max = 64,
     .doc = "views per LOD and mode: 6 axis views, then oblique ones"},
    {.name = "size", .type = SC_PARAM_INTEGER, .def = 512, .min = 16, .max = 4096,
     .doc = "side of each render, in pixels"},
    {.name = "seam_points", .type = SC_PARAM_INTEGER, .def = 16, .min = 2, .max = 4096,
     .doc = "points per seam half-edge in the GPU seam-gap check (untessellated modes)"},
    {.name = "tess_levels", .type = SC_PARAM_NUMBERS, .def_string = "1,2,4,8", .min = 1, .max = 64,
     .doc = "uniform tessellation levels of the tessellated mode", .check_list = check_tess_levels},
    {.name = "max_triangles_per_pixel", .type = SC_PARAM_NUMBER, .def = 1, .min = 0, .max = 1e9,
     .doc = "a tessellated level (not the lowest) whose triangles outnumber this many per pixel of a view "
            "is probed, not drawn: its seam gap is measured and bounded, with max_seam_gap at or under the "
            "rasteriser's vertex grid and max_map_fold_pixels off; 0: every level is drawn"},
    {.name = "folder", .type = SC_PARAM_STRING, .def_string = "render",
     .doc = "folder of the report's pictures under --out (two render nodes in one graph need two)",
     .check_text = check_folder},
    {.name = "max_crack_pixels", .type = SC_PARAM_NUMBER, .def = -1, .min = -1, .max = 1e15,
     .doc = "fail when a LOD and mode shows more crack pixels (summed over views); -1: no limit"},
    {.name = "max_fold_pixels", .type = SC_PARAM_NUMBER, .def = -1, .min = -1, .max = 1e15,
     .doc = "fail when a LOD drawn at its own vertices (textured) shows more fold pixels (back faces no "
            "opening explains, summed over views): what decimation folds over; -1: fold_allowance times the "
            "reference's back-face pixels when a reference is connected, else no limit"},
    {.name = "max_map_fold_pixels", .type = SC_PARAM_NUMBER, .def = -1, .min = -1, .max = 1e15,
     .doc = "the same for the modes whose positions come from maps (geometry_image, displaced, tessellated): "
            "folds of the maps' reconstruction; -1: no limit"},
    {.name = "fold_allowance", .type = SC_PARAM_NUMBER, .def = 2, .min = 0, .max = 1e15,
     .doc = "with max_fold_pixels = -1: the fold pixels a LOD and mode may show, as a multiple of the "
            "reference's back-face pixels (0: none at all)"},
    {.name = "max_seam_gap", .type = SC_PARAM_NUMBER, .def = -1, .min = -1, .max = 1e15,
     .doc = "fail when a LOD and mode has a larger GPU seam gap (fraction of the bounding-box diagonal); "
            "-1: no limit"},
};

static const sc_port_desc inputs[] = {
    {.name = "lods", .kind = SC_KIND_LODS, .optional = true, .doc = "the levels of detail to check"},
    {.name = "atlas", .kind = SC_KIND_ATLAS, .optional = true, .doc = "a single level to check (instead of lods)"},
    {.name = "reference", .kind = SC_KIND_ATLAS, .optional = true,
     .doc = "the input mesh: back faces it already shows (holes of open meshes) are not cracks"},
};

static const sc_port_desc outputs[] = {
    {.name = "report", .kind = SC_KIND_REPORT,
     .doc = "render/lod<k>_<mode>_<view>.png, render/lod<k>_sheet.png, crack and seam-gap metrics"},
};

static const sc_kernel *const kernels[] = {&sc_kernel_atlas_ops, &sc_kernel_gl, &sc_kernel_imageio, &sc_kernel_seam,
                                            &sc_kernel_topology, NULL};

const sc_node_desc sc_node_render = {
    .type = "render",
    .version = 20,
    .summary = "renders every LOD headless (EGL, llvmpipe) in every mode and checks for cracks",
    .inputs = inputs,
    .ninputs = SC_COUNT(inputs),
    .outputs = outputs,
    .noutputs = SC_COUNT(outputs),
    .params = params,
    .nparams = SC_COUNT(params),
    .run = run,
    .kernels = kernels,
};
