/* test_written_textures.c - every texture file the main job (graphs/
 * lod_chain.lua) writes, decoded and its seams measured with the tests' own
 * sampler (sc_ref_seam.c, no sc_seam code), in the space a renderer filters
 * it: sRGB colour (color, emissive) in linear light, data maps (normal,
 * occlusion, metallic_roughness) and float EXR as stored.
 *
 * The folders are the main job's outputs (the procedural asset, the same
 * with erased_exr=1, and every corpus main job), named in $SC_MAIN_JOB_OUTPUTS (':'-separated) by
 * the ctest registration, which runs this test after the jobs; a folder
 * without report.json is passed over, and none at all skips (exit 77).
 *
 * Why: the nodes measure what they hold in memory; this reads the bytes a
 * consumer gets, so an encoder, a colour conversion or a file that does not
 * belong to the mesh it is written with shows here.
 *
 * Checked per file, on the seams of the mesh written with it: asset.obj (the
 * full level; every level shares its uv), asset_erased.obj for the EXR files
 * of erase_seams's own output:
 *   - the seam energy save reports for the file is what its bytes hold;
 *   - 8-bit: the energy is within twice the naive-rounding floor the erasure
 *     reports for its texture (seam_energy_after_u8_naive), and the files are
 *     below their floors on average; a texture the erasure found seam-free
 *     already has no floor: its file must be seam-free (numerically zero).
 *     The largest gap is within one code value in the filtering space;
 *   - float EXR (asset_erased_*, written with --set erased_exr=1): the energy
 *     is within 1e-12 of the input's (seam_energy_before), the gap within
 *     the job's max_file_seam_gap (1e-6).
 * The floors are those of the node whose erasure the file holds: straighten
 * (`straight`, its erase.* metrics), which erases every texture whether it
 * moves uv or not; erase_seams (`erased`) with straighten=0 and for the EXR
 * files of erased_exr=1.
 * Tangent-space normal maps (<slot>.tangent_space 1 in the erasing node's
 * metrics) are erased in object space through the tangent frames, so their
 * stored values do not meet across seams by design: what matters there is
 * the rendered normal's gap, which erase_seams and render measure. They are
 * measured and printed here but not checked.
 * Textures are sampled with repeat wrap (the main job's outputs use it).
 */
#include <dirent.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include <cjson/cJSON.h>

#include "sc_imageio.h"
#include "sc_obj.h"
#include "sc_ref_seam.h"
#include "sc_test.h"

/* Twice the naive floor per file; the mean ratio below 1. */
#define FLOOR_FACTOR 2.0
/* A float file within this fraction of its input's energy. */
#define EXR_RELATIVE 1e-12
/* Energy that is zero but for double rounding (a seam-free texture reads
 * 1e-30 here: both sides sample the same texel values). */
#define NUMERICAL_ZERO 1e-20

static const char *const slots[] = {"color", "emissive", "normal", "occlusion", "metallic_roughness"};

static char *read_all(const char *path, size_t *size) {
    FILE *f = fopen(path, "rb");
    if (!f) return NULL;
    sc_buf b = {0};
    char chunk[65536];
    size_t n;
    while ((n = fread(chunk, 1, sizeof chunk, f)) > 0) sc_buf_append(&b, chunk, n);
    fclose(f);
    sc_buf_append(&b, "", 1);
    *size = b.len - 1;
    return (char *)b.data;
}

static const cJSON *node_metrics(const cJSON *report, const char *name) {
    const cJSON *n;
    cJSON_ArrayForEach(n, cJSON_GetObjectItemCaseSensitive(report, "nodes")) {
        const cJSON *nm = cJSON_GetObjectItemCaseSensitive(n, "name");
        if (cJSON_IsString(nm) && !strcmp(nm->valuestring, name)) return cJSON_GetObjectItemCaseSensitive(n, "metrics");
    }
    return NULL;
}

static double metric(const cJSON *metrics, const char *key) {
    const cJSON *v = metrics ? cJSON_GetObjectItemCaseSensitive(metrics, key) : NULL;
    return cJSON_IsNumber(v) ? v->valuedouble : NAN;
}

/* The erase kernel's metric for one texture, after `prefix` (erase_seams's:
 * none; straighten's: "erase."): "<material>.<slot>.NAME" with several
 * materials, "<slot>.NAME" with several textures, "NAME" with one. */
static double texture_metric(const cJSON *metrics, const char *prefix, const char *material, const char *slot,
                             const char *name, bool one_texture) {
    char key[512];
    snprintf(key, sizeof key, "%s%s.%s.%s", prefix, material, slot, name);
    double v = metric(metrics, key);
    if (isnan(v)) snprintf(key, sizeof key, "%s%s.%s", prefix, slot, name), v = metric(metrics, key);
    if (isnan(v) && one_texture) snprintf(key, sizeof key, "%s%s", prefix, name), v = metric(metrics, key);
    return v;
}

/* "asset_[erased_]<material>_<slot>.png|exr" -> material, slot, erased. */
static bool parse_name(const char *name, char *material, size_t cap, const char **slot, bool *erased, bool *exr) {
    size_t n = strlen(name);
    if (strncmp(name, "asset_", 6) != 0 || n < 10) return false;
    if (!strcmp(name + n - 4, ".png")) *exr = false;
    else if (!strcmp(name + n - 4, ".exr")) *exr = true;
    else return false;
    const char *p = name + 6;
    *erased = !strncmp(p, "erased_", 7);
    if (*erased) p += 7;
    size_t stem = (size_t)(name + n - 4 - p);
    for (size_t i = 0; i < sizeof slots / sizeof *slots; i++) {
        size_t k = strlen(slots[i]);
        if (stem > k + 1 && p[stem - k - 1] == '_' && !strncmp(p + stem - k, slots[i], k) && stem - k - 1 < cap) {
            memcpy(material, p, stem - k - 1);
            material[stem - k - 1] = 0;
            *slot = slots[i];
            return true;
        }
    }
    return false;
}

static int material_index(const sc_mesh *m, const char *name) {
    for (int i = 0; i < m->nmat; i++)
        if (!strcmp(m->materials[i], name)) return i;
    return m->nmat == 1 ? 0 : -1;
}

/* One code value of an 8-bit file in its filtering space, at its widest:
 * the top sRGB step in linear light, 1/255 for data. */
static double one_code_value(bool srgb) { return srgb ? 1.0 - ref_srgb_decode(254.0 / 255.0) : 1.0 / 255.0; }

typedef struct totals {
    int files, checked_floor;
    double ratio_sum;
} totals;

static void check_file(const char *dir, const char *name, const sc_mesh *full, const sc_mesh *erased_mesh,
                       const cJSON *report, bool one_texture, totals *tot) {
    char material[256];
    const char *slot;
    bool erased_file, exr;
    if (!parse_name(name, material, sizeof material, &slot, &erased_file, &exr)) return;
    /* erase_seams's own files go with the mesh written beside them (its uv,
     * before straighten) */
    const sc_mesh *m = erased_file && erased_mesh ? erased_mesh : full;
    char path[4096];
    snprintf(path, sizeof path, "%s/%s", dir, name);
    size_t size = 0;
    char *bytes = read_all(path, &size);
    SC_CHECK_MSG(bytes, "%s: cannot read", path);
    if (!bytes) return;
    sc_image_data *im = NULL;
    sc_error err = {0};
    int rc = sc_image_decode(name, bytes, size, &im, &err);
    free(bytes);
    SC_CHECK_MSG(rc == SC_OK, "%s: %s", path, err.message);
    if (rc != SC_OK) return;
    bool colour = !strcmp(slot, "color") || !strcmp(slot, "emissive");
    /* 8/16-bit files decode as sRGB; data maps are stored values */
    if (!colour && im->colorspace == SC_COLOR_SRGB) im->colorspace = SC_COLOR_DATA;
    int mat = material_index(m, material);
    SC_CHECK_MSG(mat >= 0, "%s: material %s is not in its mesh", path, material);
    if (mat < 0) {
        sc_image_free(im);
        return;
    }
    ref_seam *rs;
    int ns = ref_find_seams(m, mat, &rs);
    double gap, e = ref_total(im, SC_WRAP_REPEAT, SC_WRAP_REPEAT, rs, ns, &gap);
    free(rs);
    tot->files++;

    /* the erasing node: straighten when the graph has it (erase_seams's own files aside) */
    const cJSON *erase = node_metrics(report, "erased"), *straight = node_metrics(report, "straight");
    const char *prefix = "";
    if (!erased_file && straight) erase = straight, prefix = "erase.";
    const cJSON *save = node_metrics(report, erased_file ? "save_erased_exr" : "save");
    char key[512];
    snprintf(key, sizeof key, "%s.seam_energy", name);
    double saved = metric(save, key);
    printf("%s: %dx%dx%d %s, %d seams, energy %.4g, gap %.3g, save reports %.4g", path, im->width, im->height,
           im->channels, exr ? "f32" : im->pixel == SC_PIXEL_U8 ? "u8" : "u16", ns, e, gap, saved);
    SC_CHECK_MSG(!isnan(saved), "%s: save reports no seam energy for it", path);
    SC_CHECK_MSG(fabs(e - saved) <= 0.01 * saved + NUMERICAL_ZERO, "%s: the bytes hold energy %.6g, save reports %.6g",
                 path, e, saved);

    if (texture_metric(erase, prefix, material, slot, "tangent_space", one_texture) == 1) {
        printf(", tangent-space normal map: not checked here\n");
        sc_image_free(im);
        return;
    }
    bool seam_free = texture_metric(erase, prefix, material, slot, "already_seam_free", one_texture) == 1;
    if (exr) {
        double before = texture_metric(erase, prefix, material, slot, "seam_energy_before", one_texture);
        double bound = fmax(EXR_RELATIVE * before, NUMERICAL_ZERO);
        printf(", input %.4g (bound %.3g)\n", before, bound);
        SC_CHECK_MSG(!isnan(before), "%s: the erasure reports no input energy", path);
        SC_CHECK_MSG(e <= bound, "%s: energy %.6g above %g of the input's %.6g", path, e, EXR_RELATIVE, before);
        SC_CHECK_MSG(gap <= 1e-6, "%s: gap %.6g above 1e-6", path, gap);
    } else if (seam_free) {
        printf(", seam-free before erasure: no floor\n");
        SC_CHECK_MSG(e <= NUMERICAL_ZERO, "%s: the erasure found it seam-free, the file holds energy %.6g", path, e);
    } else {
        double floor_naive = texture_metric(erase, prefix, material, slot, "seam_energy_after_u8_naive", one_texture);
        printf(", naive floor %.4g (ratio %.4g)\n", floor_naive, e / floor_naive);
        SC_CHECK_MSG(im->pixel == SC_PIXEL_U8, "%s: not an 8-bit file", path);
        SC_CHECK_MSG(!isnan(floor_naive) && floor_naive > 0, "%s: the erasure reports no naive floor", path);
        if (!isnan(floor_naive) && floor_naive > 0) {
            SC_CHECK_MSG(e <= FLOOR_FACTOR * floor_naive, "%s: energy %.6g above twice the naive floor %.6g", path, e,
                         floor_naive);
            tot->ratio_sum += e / floor_naive;
            tot->checked_floor++;
        }
    }
    if (!exr)
        SC_CHECK_MSG(gap <= one_code_value(colour), "%s: gap %.6g wider than one code value (%.6g)", path, gap,
                     one_code_value(colour));
    sc_image_free(im);
}

/* The mesh of an OBJ file in dir, or NULL (with a failed check when it must
 * be there). */
static sc_mesh *read_mesh(const char *dir, const char *file, bool required) {
    char path[4096];
    snprintf(path, sizeof path, "%s/%s", dir, file);
    size_t size;
    char *text = read_all(path, &size);
    SC_CHECK_MSG(text || !required, "%s: cannot read", path);
    if (!text) return NULL;
    sc_obj obj = {0};
    sc_error err = {0};
    int rc = sc_obj_parse(file, text, size, NULL, NULL, &obj, &err);
    free(text);
    SC_CHECK_MSG(rc == SC_OK, "%s: %s", path, err.message);
    sc_mesh *m = rc == SC_OK ? obj.mesh : NULL;
    obj.mesh = NULL;
    sc_obj_free(&obj);
    return m;
}

static int cmp_str(const void *a, const void *b) { return strcmp(*(char *const *)a, *(char *const *)b); }

static void check_folder(const char *dir, totals *tot) {
    char path[4096];
    snprintf(path, sizeof path, "%s/report.json", dir);
    size_t size;
    char *text = read_all(path, &size);
    cJSON *report = text ? cJSON_Parse(text) : NULL;
    free(text);
    SC_CHECK_MSG(report, "%s: not JSON", path);
    sc_mesh *full = read_mesh(dir, "asset.obj", true), *erased_mesh = read_mesh(dir, "asset_erased.obj", false);
    DIR *d = opendir(dir);
    if (full && report && d) {
        /* several texture files of erase_seams's: its metrics carry prefixes */
        char **names = NULL;
        int n = 0, textures = 0;
        for (struct dirent *de; (de = readdir(d));) {
            names = realloc(names, sizeof *names * (size_t)(n + 1));
            names[n++] = strdup(de->d_name);
        }
        qsort(names, (size_t)n, sizeof *names, cmp_str);
        for (int i = 0; i < n; i++) {
            char material[256];
            const char *slot;
            bool erased_file, exr;
            if (parse_name(names[i], material, sizeof material, &slot, &erased_file, &exr) && !erased_file) textures++;
        }
        for (int i = 0; i < n; i++) check_file(dir, names[i], full, erased_mesh, report, textures == 1, tot);
        for (int i = 0; i < n; i++) free(names[i]);
        free(names);
    }
    if (d) closedir(d);
    if (full) sc_mesh_free(full);
    if (erased_mesh) sc_mesh_free(erased_mesh);
    cJSON_Delete(report);
}

static char *outputs;

SC_TEST(written_textures_hold_seam_free_bytes) {
    totals tot = {0};
    char *list = strdup(outputs);
    for (char *save = NULL, *dir = strtok_r(list, ":", &save); dir; dir = strtok_r(NULL, ":", &save)) {
        char report[4096];
        snprintf(report, sizeof report, "%s/report.json", dir);
        FILE *f = fopen(report, "rb");
        if (!f) {
            printf("%s: no main-job output, passed over\n", dir);
            continue;
        }
        fclose(f);
        check_folder(dir, &tot);
    }
    free(list);
    SC_CHECK_MSG(tot.files > 0, "no texture file found in %s", outputs);
    if (tot.checked_floor > 0) {
        double mean = tot.ratio_sum / tot.checked_floor;
        printf("%d files measured; mean ratio to the naive floor over %d 8-bit files: %.4g\n", tot.files,
               tot.checked_floor, mean);
        SC_CHECK_MSG(mean < 1, "the files are not below their naive floors on average (%.4g)", mean);
    }
}

int main(void) {
    outputs = getenv("SC_MAIN_JOB_OUTPUTS");
    bool any = false;
    char *list = outputs ? strdup(outputs) : NULL;
    for (char *save = NULL, *dir = list ? strtok_r(list, ":", &save) : NULL; dir; dir = strtok_r(NULL, ":", &save)) {
        char report[4096];
        snprintf(report, sizeof report, "%s/report.json", dir);
        FILE *f = fopen(report, "rb");
        if (f) any = true, fclose(f);
    }
    free(list);
    if (!any) {
        printf("no main-job output in $SC_MAIN_JOB_OUTPUTS: skipped\n");
        return 77;
    }
    return sc_test_main();
}
