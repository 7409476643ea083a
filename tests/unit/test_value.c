/* test_value.c - values: digests, canonical bytes, round trips through the
 * serialisation, parts shared by digest, and malformed bytes rejected; and
 * sc_run_beside, which the solvers use to run side work behind them. */
#include "sc_test.h"

#include <stdatomic.h>
#include <stdlib.h>
#ifdef __linux__
#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>
#endif

#include "sc_value.h"

static sc_value *make_mesh(double x) {
    sc_mesh *m = sc_mesh_alloc(3, 3, 0, 1, 1);
    m->materials[0] = sc_strdup("skin");
    double V[9] = {0, 0, 0, 1, 0, 0, 0, 1, x}, U[6] = {0, 0, 1, 0, 0, 1};
    memcpy(m->V, V, sizeof V);
    memcpy(m->U, U, sizeof U);
    for (int k = 0; k < 3; k++) m->FV[k] = m->FU[k] = k;
    return sc_value_new_mesh(m);
}

static sc_value *make_image(uint8_t fill) {
    sc_image_data *im = sc_image_alloc(4, 2, 3, SC_PIXEL_U8);
    memset(im->pixels, fill, 24);
    memcpy(im->format, "png", 4);
    return sc_value_new_image(im);
}

/* A resolver over a fixed table of values (stands in for the blob store). */
typedef struct table {
    sc_value *v[8];
    int n;
} table;

static sc_value *resolve(void *ud, const sc_digest *d, sc_error *err) {
    table *t = ud;
    for (int i = 0; i < t->n; i++)
        if (sc_digest_equal(sc_value_digest(t->v[i]), d)) return sc_value_retain(t->v[i]);
    sc_fail(err, SC_EMISS, "no such part");
    return NULL;
}

static sc_value *round_trip(const sc_value *v, table *t) {
    sc_buf b;
    sc_buf_init(&b);
    SC_CHECK_INT(sc_value_serialize(v, &b), SC_OK);
    sc_error err = {0};
    sc_value *back = sc_value_deserialize(b.data, b.len, sc_value_digest(v), resolve, t, &err);
    SC_CHECK_MSG(back != NULL, "deserialize failed: %s", err.message);
    sc_buf_free(&b);
    return back;
}

/* sc_run_beside: front on the calling thread, back on another one at
 * SC_BEHIND_NICE more (Linux), both run; on one thread, back after front on
 * the caller. */
typedef struct beside_log {
    long tid[2];
    int nice[2];
    int stamp[2];   /* the order they ran in */
    atomic_int ran;
} beside_log;

static long this_thread(void) {
#ifdef __linux__
    return (long)syscall(SYS_gettid);
#else
    return 0;
#endif
}

static int this_nice(void) {
#ifdef __linux__
    return getpriority(PRIO_PROCESS, (id_t)syscall(SYS_gettid));
#else
    return 0;
#endif
}

static void beside_record(beside_log *l, int which) {
    l->tid[which] = this_thread();
    l->nice[which] = this_nice();
    l->stamp[which] = atomic_fetch_add(&l->ran, 1);
}
static void beside_front(void *ud) { beside_record(ud, 0); }
static void beside_back(void *ud) { beside_record(ud, 1); }

SC_TEST(run_beside_puts_the_back_behind) {
    beside_log one = {{-1, -1}, {0, 0}, {-1, -1}, 0};
    sc_run_beside(1, beside_front, beside_back, &one);
    SC_CHECK_INT(atomic_load(&one.ran), 2);
    SC_CHECK(one.stamp[0] == 0 && one.stamp[1] == 1);
    SC_CHECK(one.tid[0] == this_thread() && one.tid[1] == this_thread());
    beside_log two = {{-1, -1}, {0, 0}, {-1, -1}, 0};
    sc_run_beside(2, beside_front, beside_back, &two);
    SC_CHECK_INT(atomic_load(&two.ran), 2);
    SC_CHECK(two.tid[0] == this_thread());
#ifdef __linux__
    SC_CHECK(two.tid[1] != this_thread());
    int want = this_nice() + SC_BEHIND_NICE > 19 ? 19 : this_nice() + SC_BEHIND_NICE;
    SC_CHECK_INT(two.nice[0], this_nice());
    SC_CHECK_INT(two.nice[1], want);
#endif
}

SC_TEST(digest_is_sha256_of_canonical_bytes) {
    sc_value *m = make_mesh(0);
    sc_buf b;
    sc_buf_init(&b);
    sc_value_serialize(m, &b);
    sc_digest d;
    sc_digest_bytes(b.data, b.len, &d);
    SC_CHECK(sc_digest_equal(&d, sc_value_digest(m)));
    sc_buf_free(&b);
    /* the same content gives the same digest; other content another */
    sc_value *same = make_mesh(0), *other = make_mesh(1e-300);
    SC_CHECK(sc_digest_equal(sc_value_digest(same), sc_value_digest(m)));
    SC_CHECK(!sc_digest_equal(sc_value_digest(other), sc_value_digest(m)));
    sc_value_release(m), sc_value_release(same), sc_value_release(other);
}

SC_TEST(round_trips_are_exact) {
    table t = {0};
    t.v[t.n++] = make_mesh(0.125);
    t.v[t.n++] = make_image(7);
    sc_atlas *a = sc_atlas_new(sc_value_retain(t.v[0]));
    SC_CHECK_INT(sc_atlas_add_texture(a, "color", 0, SC_WRAP_CLAMP, SC_WRAP_MIRROR, "c.png",
                                      sc_value_retain(t.v[1])), SC_OK);
    sc_value *atlas = sc_value_new_atlas(a);
    t.v[t.n++] = atlas;
    for (int i = 0; i < t.n; i++) {
        sc_value *back = round_trip(t.v[i], &t);
        if (back) SC_CHECK(sc_digest_equal(sc_value_digest(back), sc_value_digest(t.v[i])));
        if (back && back->kind == SC_KIND_ATLAS) {
            const sc_texture *tex = &back->as.atlas->textures[0];
            SC_CHECK_STR(tex->name, "color");
            SC_CHECK_INT(tex->wrap_u, SC_WRAP_CLAMP);
            SC_CHECK_INT(tex->wrap_v, SC_WRAP_MIRROR);
            SC_CHECK(back->as.atlas->mesh->as.mesh->V[8] == 0.125);
        }
        sc_value_release(back);
    }
    sc_lods *l = sc_lods_new();
    sc_lods_add(l, sc_value_retain(atlas));
    sc_value *lods = sc_value_new_lods(l);
    sc_value *back = round_trip(lods, &t);
    if (back) SC_CHECK_INT(back->as.lods->count, 1);
    sc_value_release(back);
    sc_value_release(lods);
    for (int i = 0; i < t.n; i++) sc_value_release(t.v[i]);
}

SC_TEST(parts_are_shared_not_copied) {
    sc_value *mesh = make_mesh(0), *image = make_image(9);
    sc_atlas *a1 = sc_atlas_new(sc_value_retain(mesh));
    sc_atlas_add_texture(a1, "color", 0, SC_WRAP_REPEAT, SC_WRAP_REPEAT, "", sc_value_retain(image));
    sc_value *atlas1 = sc_value_new_atlas(a1);
    /* a new mesh, same texture: the texture is the same value */
    sc_value *mesh2 = make_mesh(2);
    sc_atlas *a2 = sc_atlas_new(sc_value_retain(mesh2));
    sc_atlas_add_texture(a2, "color", 0, SC_WRAP_REPEAT, SC_WRAP_REPEAT, "", sc_value_retain(image));
    sc_value *atlas2 = sc_value_new_atlas(a2);
    SC_CHECK(atlas1->as.atlas->textures[0].image == atlas2->as.atlas->textures[0].image);
    SC_CHECK(!sc_digest_equal(sc_value_digest(atlas1), sc_value_digest(atlas2)));
    /* an atlas's bytes are small: parts appear as digests only */
    sc_buf b;
    sc_buf_init(&b);
    sc_value_serialize(atlas1, &b);
    SC_CHECK_MSG(b.len < 200, "atlas serialised to %zu bytes", b.len);
    sc_buf_free(&b);
    SC_CHECK_INT(image->refs, 3);
    sc_value_release(atlas1), sc_value_release(atlas2);
    SC_CHECK_INT(image->refs, 1);
    sc_value_release(image), sc_value_release(mesh), sc_value_release(mesh2);
}

SC_TEST(malformed_bytes_are_rejected) {
    sc_value *m = make_mesh(0);
    sc_buf b;
    sc_buf_init(&b);
    sc_value_serialize(m, &b);
    sc_error err = {0};
    /* every truncation fails cleanly */
    for (size_t n = 0; n < b.len; n++) {
        sc_value *v = sc_value_deserialize(b.data, n, NULL, NULL, NULL, &err);
        SC_CHECK_MSG(v == NULL, "accepted %zu of %zu bytes", n, b.len);
        sc_value_release(v);
    }
    /* a flipped byte no longer matches the digest (or no longer parses) */
    b.data[b.len - 5] ^= 0x40;
    sc_value *v = sc_value_deserialize(b.data, b.len, sc_value_digest(m), NULL, NULL, &err);
    SC_CHECK(v == NULL);
    sc_value_release(v);
    /* an index out of range inside otherwise valid bytes */
    sc_buf_reset(&b);
    sc_value_serialize(m, &b);
    size_t fv_offset = b.len - 4 * (3 + 3 + 1);   /* FV, FU, FM of one face */
    b.data[fv_offset] = 9;
    v = sc_value_deserialize(b.data, b.len, NULL, NULL, NULL, &err);
    SC_CHECK(v == NULL);
    sc_value_release(v);
    /* a huge claimed size does not allocate */
    uint8_t evil[] = {'S', 'C', 'V', SC_KIND_IMAGE, 1, 0, 0, 0, 0xff, 0x7f, 0, 0, 0xff, 0x7f, 0, 0, 4, 0, 0, 0, 4};
    v = sc_value_deserialize(evil, sizeof evil, NULL, NULL, NULL, &err);
    SC_CHECK(v == NULL);
    sc_buf_free(&b);
    sc_value_release(m);
}

SC_TEST(mesh_check_names_the_problem) {
    sc_mesh *m = sc_mesh_alloc(3, 3, 0, 1, 1);
    m->materials[0] = sc_strdup("x");
    for (int k = 0; k < 3; k++) m->FV[k] = m->FU[k] = k;
    sc_error err = {0};
    SC_CHECK_INT(sc_mesh_check(m, &err), SC_OK);
    m->V[4] = NAN;
    SC_CHECK_INT(sc_mesh_check(m, &err), SC_EINPUT);
    SC_CHECK_MSG(strstr(err.message, "vertex 2") != NULL, "%s", err.message);
    m->V[4] = 0;
    m->FU[2] = 3;
    SC_CHECK_INT(sc_mesh_check(m, &err), SC_EINPUT);
    SC_CHECK_MSG(strstr(err.message, "uv index 4 out of range") != NULL, "%s", err.message);
    m->FU[2] = 2;
    m->FV[2] = 0;
    SC_CHECK_INT(sc_mesh_check(m, &err), SC_EINPUT);
    SC_CHECK_MSG(strstr(err.message, "degenerate") != NULL, "%s", err.message);
    sc_mesh_free(m);
}

SC_TEST(image_limits_and_texels) {
    SC_CHECK(sc_image_alloc(100000, 100000, 4, SC_PIXEL_U8) == NULL);
    SC_CHECK(sc_image_alloc(0, 4, 4, SC_PIXEL_U8) == NULL);
    SC_CHECK(sc_image_alloc(4, 4, 5, SC_PIXEL_U8) == NULL);
    sc_image_data *im = sc_image_alloc(2, 2, 1, SC_PIXEL_U16);
    ((uint16_t *)im->pixels)[3] = 65535;
    SC_CHECK_NEAR(sc_image_texel(im, 1, 1, 0), 1.0, 0);
    sc_image_data *f = sc_image_to_f32(im);
    SC_CHECK_NEAR(((float *)f->pixels)[3], 1.0, 0);
    sc_image_free(im), sc_image_free(f);
}

/* Every pixel type and channel count, as stored and in linear light, on an
 * image whose samples span several of the conversion's chunks (a chunk
 * boundary falls inside a pixel): each sample equals its own conversion,
 * alpha as stored. */
SC_TEST(float_conversion_of_every_sample) {
    const sc_pixel pixels[] = {SC_PIXEL_U8, SC_PIXEL_U16, SC_PIXEL_F32};
    for (int pi = 0; pi < 3; pi++)
        for (int32_t C = 1; C <= 4; C++) {
            sc_image_data *im = sc_image_alloc(1031, 347, C, pixels[pi]);
            if (!im) continue;
            size_t n = (size_t)im->width * im->height * (size_t)C;
            for (size_t k = 0; k < n; k++) {
                uint32_t h = (uint32_t)(k * 2654435761u);
                if (pixels[pi] == SC_PIXEL_U8) ((uint8_t *)im->pixels)[k] = (uint8_t)(h >> 24);
                else if (pixels[pi] == SC_PIXEL_U16) ((uint16_t *)im->pixels)[k] = (uint16_t)(h >> 16);
                else ((float *)im->pixels)[k] = (float)(h >> 8) / 16777216.0f;
            }
            for (int linear = 0; linear < 2; linear++) {
                im->colorspace = linear ? SC_COLOR_SRGB : SC_COLOR_LINEAR;
                sc_image_data *f = linear ? sc_image_to_linear_f32(im, 2) : sc_image_to_f32_threads(im, 2);
                SC_CHECK(f != NULL);
                if (!f) continue;
                size_t wrong = 0;
                for (size_t k = 0; k < n; k++) {
                    int32_t c = (int32_t)(k % (size_t)C);
                    float v = sc_image_texel(im, (int32_t)(k / (size_t)C % (size_t)im->width),
                                             (int32_t)(k / (size_t)C / (size_t)im->width), c);
                    float want = linear && !sc_channel_is_alpha(C, c) ? sc_srgb_to_linear(v) : v;
                    wrong += ((const float *)f->pixels)[k] != want;
                }
                SC_CHECK_MSG(wrong == 0, "pixel %d, %d channels, %s: %zu samples differ", (int)pixels[pi], C,
                             linear ? "linear" : "as stored", wrong);
                sc_image_free(f);
            }
            sc_image_free(im);
        }
}

/* Threads that ask for one atlas's digest at once (its image's too, which
 * the atlas's asks for in turn) all get the SHA-256 of its canonical bytes;
 * a value dropped before anyone asked is freed with its hasher (the
 * sanitizer build checks the leak). */
typedef struct digest_race {
    sc_value *atlas, *image;
    sc_digest seen[8];
} digest_race;

static int ask_digest(void *ud, int32_t i) {
    digest_race *r = ud;
    r->seen[i] = *sc_value_digest(i % 2 ? r->image : r->atlas);
    return SC_OK;
}

SC_TEST(digests_asked_at_once_agree) {
    sc_image_data *im = sc_image_alloc(512, 512, 4, SC_PIXEL_F32);
    SC_CHECK(im != NULL);
    if (!im) return;
    for (size_t k = 0; k < (size_t)512 * 512 * 4; k++) ((float *)im->pixels)[k] = (float)(k % 977) / 977.0f;
    digest_race r = {0};
    r.image = sc_value_new_image(im);
    sc_atlas *a = sc_atlas_new(make_mesh(0));
    SC_CHECK(a && sc_atlas_add_texture(a, "color", 0, SC_WRAP_REPEAT, SC_WRAP_REPEAT, "", sc_value_retain(r.image)) ==
                      SC_OK);
    r.atlas = sc_value_new_atlas(a);
    SC_CHECK(sc_parallel(4, 8, ask_digest, &r) == SC_OK);
    sc_digest want[2];
    for (int w = 0; w < 2; w++) {
        sc_buf b;
        sc_buf_init(&b);
        sc_value_serialize(w ? r.image : r.atlas, &b);
        sc_digest_bytes(b.data, b.len, &want[w]);
        sc_buf_free(&b);
    }
    for (int i = 0; i < 8; i++) SC_CHECK_MSG(sc_digest_equal(&r.seen[i], &want[i % 2]), "thread %d", i);
    sc_value_release(r.atlas), sc_value_release(r.image);
    sc_value_release(sc_value_new_image(sc_image_alloc(4, 4, 1, SC_PIXEL_U8)));
}

SC_TEST(number_text_is_exact_and_shortest) {
    double samples[] = {0.1, 1.0 / 3.0, 1e-300, 123456789.0, -2.5, 5e-324, 1.7976931348623157e308};
    for (int i = 0; i < (int)(sizeof samples / sizeof *samples); i++) {
        char text[32];
        sc_format_double(samples[i], text);
        SC_CHECK_MSG(strtod(text, NULL) == samples[i], "%s does not read back", text);
    }
    char t[32];
    sc_format_double(0.1, t);
    SC_CHECK_STR(t, "0.1");
    sc_format_double(3.0, t);
    SC_CHECK_STR(t, "3");
    sc_format_double(-0.0, t);
    SC_CHECK_STR(t, "0");
}

int main(void) { return sc_test_main(); }
