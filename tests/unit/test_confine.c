/* test_confine.c - the files an asset names stay inside its folder: the path
 * rules of sc_path_confine, and load_atlas end to end on OBJ, MTL and glTF
 * files that try to leave it (.., absolute paths, URIs, symbolic links).
 * Nothing outside the folder is read, and no message quotes it. */
#include "sc_test.h"

#include <stdlib.h>
#include <sys/stat.h>
#include <unistd.h>

#include "sc_nodes.h"
#include "sc_obj.h"

static void write_text(const char *dir, const char *name, const char *text) {
    char *path = sc_path_join(dir, name);
    sc_error err;
    SC_CHECK_MSG(sc_write_file_atomic(path, text, strlen(text), &err) == SC_OK, "%s", err.message);
    free(path);
}

/* A folder tree: root/asset (the asset's folder, with sub/), root/outside
 * (a secret beside it). */
typedef struct tree {
    char *root, *asset, *outside;
} tree;

static tree make_tree(void) {
    tree t;
    t.root = sc_test_tempdir("confine");
    t.asset = sc_path_join(t.root, "asset");
    t.outside = sc_path_join(t.root, "outside");
    sc_test_system("mkdir -p '%s/sub' '%s'", t.asset, t.outside);
    write_text(t.outside, "secret.mtl", "SECRET-LINE-THAT-MUST-NOT-LEAK\n");
    write_text(t.asset, "inside.mtl", "newmtl skin\n");
    write_text(t.asset, "sub/deep.mtl", "newmtl skin\n");
    return t;
}

static void free_tree(tree *t) {
    sc_test_system("rm -rf '%s'", t->root);
    free(t->root), free(t->asset), free(t->outside);
}

static bool confined(const char *root, const char *dir, const char *rel, sc_error *err) {
    char *out = NULL;
    int rc = sc_path_confine(root, dir, rel, &out, err);
    bool ok = rc == SC_OK && out != NULL;
    if (ok) {
        char *expect = sc_path_join(dir, rel);
        SC_CHECK_MSG(strcmp(out, expect) == 0, "%s vs %s", out, expect);
        free(expect);
    }
    free(out);
    return ok;
}

SC_TEST(paths_inside_the_root_and_out_of_it) {
    tree t = make_tree();
    sc_error err;
    SC_CHECK(confined(t.asset, t.asset, "inside.mtl", &err));
    SC_CHECK(confined(t.asset, t.asset, "sub/deep.mtl", &err));
    SC_CHECK(confined(t.asset, t.asset, "sub/../inside.mtl", &err));
    SC_CHECK(confined(t.asset, t.asset, "./missing.png", &err));   /* missing but inside: the read says so */
    SC_CHECK(!confined(t.asset, t.asset, "../outside/secret.mtl", &err));
    SC_CHECK_MSG(strstr(err.message, "leads outside the asset folder"), "%s", err.message);
    SC_CHECK(!confined(t.asset, t.asset, "sub/../../outside/secret.mtl", &err));
    SC_CHECK(!confined(t.asset, t.asset, "../../../../../../../../etc/passwd", &err));
    SC_CHECK(!confined(t.asset, t.asset, "/etc/passwd", &err));
    SC_CHECK_MSG(strstr(err.message, "absolute path"), "%s", err.message);
    SC_CHECK(!confined(t.asset, t.asset, "file:///etc/passwd", &err));
    SC_CHECK_MSG(strstr(err.message, "URI"), "%s", err.message);
    SC_CHECK(!confined(t.asset, t.asset, "http://example.invalid/x.png", &err));
    SC_CHECK(!confined(t.asset, t.asset, "C:\\textures\\x.png", &err));
    SC_CHECK(!confined(t.asset, t.asset, "", &err));
    /* a folder beside the root's name is not inside it */
    sc_test_system("mkdir -p '%s2'", t.asset);
    char *beside = sc_strprintf("%s2", t.asset);
    write_text(beside, "x.mtl", "newmtl skin\n");
    SC_CHECK(!confined(t.asset, t.asset, "../asset2/x.mtl", &err));
    free(beside);
    /* symbolic links: out of the root refused, inside it followed */
    sc_test_system("ln -s ../outside/secret.mtl '%s/link_out.mtl' && ln -s ../outside '%s/dir_out' && "
                   "ln -s inside.mtl '%s/link_in.mtl'", t.asset, t.asset, t.asset);
    SC_CHECK(!confined(t.asset, t.asset, "link_out.mtl", &err));
    SC_CHECK(!confined(t.asset, t.asset, "dir_out/secret.mtl", &err));
    SC_CHECK(!confined(t.asset, t.asset, "dir_out/not_there.png", &err));
    SC_CHECK(confined(t.asset, t.asset, "link_in.mtl", &err));
    /* a wider root lets the same names through */
    SC_CHECK(confined(t.root, t.asset, "../outside/secret.mtl", &err));
    SC_CHECK(confined(t.root, t.asset, "link_out.mtl", &err));
    /* control characters are not echoed */
    SC_CHECK(!confined(t.asset, t.asset, "/etc/\x1b[31mx", &err));
    SC_CHECK(strchr(err.message, '\x1b') == NULL);
    free_tree(&t);
}

/* load_atlas on a model in t.asset; the run's result and its message. */
static int load(const tree *t, const char *model, const char *root, sc_error *err) {
    char *path = sc_path_join(t->asset, model);
    const char *params[] = {"path", path, "asset_root", root ? root : "", NULL};
    sc_test_run r = sc_test_run_node(&sc_node_load_atlas, params, NULL, NULL, NULL, NULL);
    *err = r.err;
    for (int i = 0; !root && i < sc_ctx_ndeps(r.ctx); i++) {
        const char *dep = sc_ctx_dep_path(r.ctx, i);
        SC_CHECK_MSG(!strstr(dep, "outside") && !strstr(dep, "/etc/"), "%s read %s", model, dep);
    }
    sc_ctx_free(r.ctx);
    free(path);
    return r.rc;
}

static const char *const cube_obj_body =
    "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nvt 0 0\nvt 1 0\nvt 0 1\n"
    "usemtl skin\nf 1/1 3/3 2/2\nf 1/1 2/2 4/3\nf 1/1 4/3 3/2\nf 2/1 3/2 4/3\n";

SC_TEST(load_atlas_reads_nothing_outside_the_asset_folder) {
    tree t = make_tree();
    sc_error err;
    char *text;
    /* mtllib climbing out */
    text = sc_strprintf("mtllib ../../../../../../../../etc/passwd\n%s", cube_obj_body);
    write_text(t.asset, "up.obj", text), free(text);
    SC_CHECK(load(&t, "up.obj", NULL, &err) == SC_EINPUT);
    SC_CHECK_MSG(strstr(err.message, "up.obj:1") && strstr(err.message, "leads outside"), "%s", err.message);
    SC_CHECK_MSG(!strstr(err.message, "root:"), "quotes the file: %s", err.message);
    text = sc_strprintf("mtllib ../outside/secret.mtl\n%s", cube_obj_body);
    write_text(t.asset, "beside.obj", text), free(text);
    SC_CHECK(load(&t, "beside.obj", NULL, &err) == SC_EINPUT);
    SC_CHECK_MSG(!strstr(err.message, "SECRET"), "quotes the file: %s", err.message);
    /* ... but with the parent as the root, the same MTL is read (and fails as no MTL, quoting a short excerpt) */
    SC_CHECK(load(&t, "beside.obj", t.root, &err) != SC_OK);
    SC_CHECK_MSG(!strstr(err.message, "leads outside"), "%s", err.message);
    /* a texture map named absolutely in an MTL inside the folder */
    write_text(t.asset, "abs.mtl", "newmtl skin\nmap_Kd /etc/passwd\n");
    text = sc_strprintf("mtllib abs.mtl\n%s", cube_obj_body);
    write_text(t.asset, "abs.obj", text), free(text);
    SC_CHECK(load(&t, "abs.obj", NULL, &err) == SC_EINPUT);
    SC_CHECK_MSG(strstr(err.message, "abs.mtl:2") && strstr(err.message, "absolute path"), "%s", err.message);
    /* a symbolic link inside the folder that leads out */
    sc_test_system("ln -s ../outside/secret.mtl '%s/link.mtl'", t.asset);
    text = sc_strprintf("mtllib link.mtl\n%s", cube_obj_body);
    write_text(t.asset, "link.obj", text), free(text);
    SC_CHECK(load(&t, "link.obj", NULL, &err) == SC_EINPUT);
    SC_CHECK_MSG(strstr(err.message, "leads outside") && !strstr(err.message, "SECRET"), "%s", err.message);
    /* glTF: a buffer at an absolute path, a file:// URI, an image that climbs out */
    const char *const gltf_uris[][2] = {{"/etc/passwd", "absolute path"},
                                        {"file:///etc/passwd", "not a relative file name"},
                                        {"..%2F..%2F..%2F..%2F..%2F..%2Fetc%2Fpasswd", "leads outside"}};
    for (int k = 0; k < 3; k++) {
        text = sc_strprintf("{\"asset\":{\"version\":\"2.0\"},\"buffers\":[{\"uri\":\"%s\",\"byteLength\":36}],"
                            "\"bufferViews\":[{\"buffer\":0,\"byteLength\":36}],"
                            "\"accessors\":[{\"bufferView\":0,\"componentType\":5126,\"count\":3,\"type\":\"VEC3\"},"
                            "{\"bufferView\":0,\"componentType\":5126,\"count\":3,\"type\":\"VEC2\"}],"
                            "\"meshes\":[{\"primitives\":[{\"attributes\":{\"POSITION\":0,\"TEXCOORD_0\":1}}]}],"
                            "\"nodes\":[{\"mesh\":0}],\"scenes\":[{\"nodes\":[0]}]}",
                            gltf_uris[k][0]);
        write_text(t.asset, "buf.gltf", text), free(text);
        SC_CHECK(load(&t, "buf.gltf", NULL, &err) == SC_EINPUT);
        SC_CHECK_MSG(strstr(err.message, gltf_uris[k][1]), "%s: %s", gltf_uris[k][0], err.message);
        SC_CHECK_MSG(!strstr(err.message, "root:"), "%s", err.message);
    }
    free_tree(&t);
}

/* Messages quote at most a short excerpt of what they reject, escaped. */
SC_TEST(messages_quote_short_escaped_excerpts) {
    char obj[700];
    int n = snprintf(obj, sizeof obj, "v 0 0 0\n\x01\x1b[2J");
    while (n < 600) obj[n++] = 'x';
    obj[n++] = '\n';
    obj[n] = 0;
    sc_obj parsed;
    sc_error err = {0};
    SC_CHECK(sc_obj_parse("junk.obj", obj, (size_t)n, NULL, NULL, &parsed, &err) != SC_OK);
    SC_CHECK_MSG(strstr(err.message, "junk.obj:2") && strstr(err.message, "\\x01\\x1b") && !strchr(err.message, '\x1b') &&
                     strlen(err.message) < 200,
                 "%s", err.message);
    char excerpt[64];
    SC_CHECK(strcmp(sc_excerpt("a\tb c", 10, true, excerpt, sizeof excerpt), "a") == 0);
    SC_CHECK(strcmp(sc_excerpt("abcdef", 3, false, excerpt, sizeof excerpt), "abc...") == 0);
    SC_CHECK(strcmp(sc_excerpt("\n", 3, false, excerpt, sizeof excerpt), "\\x0a") == 0);
}


/* Paths in action keys: relative to a base folder by their text alone, and
 * back again. */
SC_TEST(path_relative_and_back) {
    static const char *const cases[][3] = {
        {"/w/project", "/w/project/assets/a.obj", "assets/a.obj"},
        {"/w/project", "/w/project", "."},
        {"/w/project", "/w/projects/a.obj", "../projects/a.obj"},
        {"/w/project/graphs", "/w/assets/b.png", "../../assets/b.png"},
        {"/", "/etc/x", "etc/x"},
        {"/a/b", "/", "../.."},
    };
    for (size_t k = 0; k < sizeof cases / sizeof cases[0]; k++) {
        char *rel = sc_path_relative(cases[k][0], cases[k][1]);
        SC_CHECK_STR(rel, cases[k][2]);
        char *back = rel ? sc_path_resolve(cases[k][0], rel) : NULL;
        SC_CHECK_STR(back, cases[k][1]);
        free(rel), free(back);
    }
    char *kept = sc_path_resolve("/w", "/abs/x");
    SC_CHECK_STR(kept, "/abs/x");
    free(kept);
}

int main(void) { return sc_test_main(); }
