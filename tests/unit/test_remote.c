/* test_remote.c - the remote cache's wire formats and the project file,
 * without a server: the ActionResult protobuf written and read back (its
 * bytes checked against a hand-worked encoding), malformed protobufs and
 * records refused, and seamcook.conf's settings and errors. The remote
 * against a real server: tests/farm/remote_server.sh. */
#include "sc_test.h"

#include <stdlib.h>

#include "sc_config.h"
#include "sc_remote.h"

static sc_digest dig_str(const char *s) {
    sc_digest d;
    sc_digest_bytes(s, strlen(s), &d);
    return d;
}

SC_TEST(action_result_round_trip) {
    sc_remote_output outs[2] = {
        {.path = "seamcook/action.json", .digest = dig_str("record"), .size = 300},
        {.path = "blobs/x", .digest = dig_str("blob"), .size = 5000000000LL},
    };
    sc_buf b;
    sc_buf_init(&b);
    SC_CHECK_INT(sc_remote_encode_result(outs, 2, &b), SC_OK);
    /* field 2 (output_files), length-delimited: tag 0x12; inside it field 1
     * (path) 0x0a and field 2 (digest) 0x12; inside that hash 0x0a, size 0x10 */
    SC_CHECK(b.len > 2 && b.data[0] == 0x12);
    SC_CHECK(b.data[2] == 0x0a && b.data[3] == 20 && !memcmp(b.data + 4, "seamcook/action.json", 20));
    SC_CHECK(b.data[24] == 0x12 && b.data[26] == 0x0a && b.data[27] == 64);
    SC_CHECK(b.data[92] == 0x10 && b.data[93] == ((300 & 0x7f) | 0x80) && b.data[94] == 300 >> 7);
    sc_remote_output *back;
    int n;
    sc_error err = {0};
    SC_CHECK_INT(sc_remote_decode_result(b.data, b.len, &back, &n, &err), SC_OK);
    SC_CHECK_INT(n, 2);
    for (int i = 0; i < n && i < 2; i++) {
        SC_CHECK_STR(back[i].path, outs[i].path);
        SC_CHECK(sc_digest_equal(&back[i].digest, &outs[i].digest));
        SC_CHECK(back[i].size == outs[i].size);
    }
    sc_remote_outputs_free(back, n);
    /* every shorter prefix is malformed, or holds fewer whole outputs */
    for (size_t cut = 1; cut < b.len; cut++) {
        int rc = sc_remote_decode_result(b.data, cut, &back, &n, &err);
        SC_CHECK(rc == SC_EINPUT || (rc == SC_OK && n < 2));
        if (rc == SC_OK) sc_remote_outputs_free(back, n);
    }
    /* a hash that is not hex */
    b.data[28] = 'z';
    SC_CHECK_INT(sc_remote_decode_result(b.data, b.len, &back, &n, &err), SC_EINPUT);
    SC_CHECK(strstr(err.message, "output file 1") != NULL);
    sc_buf_free(&b);
    /* unknown fields of every wire type are skipped: exit_code 4 (varint), a fixed64 */
    static const uint8_t other[] = {0x20, 0x01, 0x09, 1, 2, 3, 4, 5, 6, 7, 8};
    SC_CHECK_INT(sc_remote_decode_result(other, sizeof other, &back, &n, &err), SC_OK);
    SC_CHECK_INT(n, 0);
    sc_remote_outputs_free(back, n);
}

SC_TEST(record_round_trip) {
    sc_cache_dep dep = {.path = "assets/a.obj", .digest = dig_str("a")};
    sc_digest blobs[2] = {dig_str("b1"), dig_str("b2")};
    sc_cache_action a = {.key = dig_str("key"), .node_type = "save", .outputs = "{\"outputs\":[]}",
                         .metrics = "{\"x\":1}", .ndeps = 1, .deps = &dep, .nblobs = 2, .blobs = blobs,
                         .seconds = 1.5};
    char *text = sc_remote_record_encode(&a);
    SC_CHECK(text != NULL);
    sc_cache_action back;
    sc_error err = {0};
    SC_CHECK_INT(sc_remote_record_decode(text, strlen(text), &back, &err), SC_OK);
    SC_CHECK(sc_digest_equal(&back.key, &a.key));
    SC_CHECK_STR(back.node_type, "save");
    SC_CHECK_STR(back.outputs, a.outputs);
    SC_CHECK_STR(back.metrics, a.metrics);
    SC_CHECK_INT(back.ndeps, 1);
    SC_CHECK_INT(back.nblobs, 2);
    if (back.ndeps == 1) SC_CHECK_STR(back.deps[0].path, "assets/a.obj");
    if (back.nblobs == 2) SC_CHECK(sc_digest_equal(&back.blobs[1], &blobs[1]));
    SC_CHECK(back.seconds == 1.5);
    sc_cache_action_free(&back);
    static const char *const bad[] = {
        "", "[]", "{\"format\":2}", "{\"format\":1,\"key\":\"ab\",\"deps\":[],\"blobs\":[],\"seconds\":0}",
    };
    for (size_t k = 0; k < sizeof bad / sizeof bad[0]; k++)
        SC_CHECK_INT(sc_remote_record_decode(bad[k], strlen(bad[k]), &back, &err), SC_EINPUT);
    /* a dep without a path */
    char *hole = sc_strdup(text);
    char *p = strstr(hole, "assets/a.obj");
    if (p) memmove(p, p + 12, strlen(p + 12) + 1);
    SC_CHECK_INT(sc_remote_record_decode(hole, strlen(hole), &back, &err), SC_EINPUT);
    free(hole);
    free(text);
}

SC_TEST(project_file) {
    static const char text[] = "# the farm\n"
                               "remote_cache = http://cache:9090/x\n"
                               "  remote_header = Authorization: Bearer a=b#c  \n"
                               "remote_header=X-Team: seams\n"
                               "\n"
                               "remote_read_only = yes\r\n"
                               "remote_timeout = 2.5\n"
                               "remote_retries = 0\n";
    sc_config c;
    sc_config_init(&c);
    sc_error err = {0};
    SC_CHECK_INT(sc_config_parse(text, sizeof text - 1, "seamcook.conf", &c, &err), SC_OK);
    SC_CHECK_STR(c.remote_cache, "http://cache:9090/x");
    SC_CHECK_INT(c.nheaders, 2);
    if (c.nheaders == 2) {
        SC_CHECK_STR(c.headers[0], "Authorization: Bearer a=b#c");
        SC_CHECK_STR(c.headers[1], "X-Team: seams");
    }
    SC_CHECK_INT(c.read_only, 1);
    SC_CHECK(c.timeout == 2.5);
    SC_CHECK_INT(c.retries, 0);
    sc_config_free(&c);
    static const char *const bad[][2] = {
        {"remote_cache = x\nremote_cachee = y\n", "f.conf:2: unknown setting 'remote_cachee'"},
        {"\n\nno equals sign\n", "f.conf:3: expected 'name = value'"},
        {"remote_read_only = maybe\n", "f.conf:1: remote_read_only: 'maybe' is not true or false"},
        {"remote_timeout = -1\n", "f.conf:1: remote_timeout"},
        {"remote_retries = 99\n", "f.conf:1: remote_retries"},
        {"remote_header = no colon\n", "f.conf:1: remote_header"},
        {" = x\n", "f.conf:1: a setting without a name"},
    };
    for (size_t k = 0; k < sizeof bad / sizeof bad[0]; k++) {
        sc_config_init(&c);
        SC_CHECK_INT(sc_config_parse(bad[k][0], strlen(bad[k][0]), "f.conf", &c, &err), SC_EINPUT);
        SC_CHECK_MSG(strstr(err.message, bad[k][1]) != NULL, "'%s' said: %s", bad[k][0], err.message);
        sc_config_free(&c);
    }
    sc_config_init(&c);
    SC_CHECK_INT(sc_config_parse("a\0b", 3, "f.conf", &c, &err), SC_EINPUT);
    sc_config_free(&c);
}

SC_TEST(remote_refuses_bad_settings) {
    sc_remote *r = NULL;
    sc_error err = {0};
    sc_remote_config cfg = {.url = "ftp://x/"};
    SC_CHECK_INT(sc_remote_open(&cfg, NULL, &r, &err), SC_EUSAGE);
    SC_CHECK(strstr(err.message, "http://") != NULL);
    const char *headers[] = {"NoColon"};
    cfg = (sc_remote_config){.url = "http://127.0.0.1:1/", .headers = headers, .nheaders = 1};
    SC_CHECK_INT(sc_remote_open(&cfg, NULL, &r, &err), SC_EUSAGE);
    SC_CHECK(r == NULL);
}

/* A server that is not there: a lookup is a miss, and the remote is left
 * alone after one warning (no second round of timeouts). */
SC_TEST(remote_down_is_a_miss) {
    char *dir = sc_test_tempdir("remote");
    sc_cache *cache = NULL;
    sc_error err = {0};
    SC_CHECK_INT(sc_cache_open(dir, &cache, &err), SC_OK);
    FILE *log = tmpfile();
    sc_remote_config cfg = {.url = "http://farm:pw@127.0.0.1:1/cache", .timeout = 1, .retries = 0, .log = log};
    sc_remote *r = NULL;
    SC_CHECK_INT(sc_remote_open(&cfg, cache, &r, &err), SC_OK);
    sc_digest k = dig_str("k");
    SC_CHECK_INT(sc_remote_fetch(r, &k, &err), SC_EMISS);
    SC_CHECK_INT(sc_remote_fetch(r, &k, &err), SC_EMISS);
    sc_remote_stats st;
    sc_remote_stats_get(r, &st);
    SC_CHECK(st.disabled);
    sc_remote_close(r);
    char text[1024] = "";
    rewind(log);
    size_t n = fread(text, 1, sizeof text - 1, log);
    text[n] = 0;
    fclose(log);
    int warnings = 0;
    for (const char *p = strstr(text, "warning"); p; p = strstr(p + 1, "warning")) warnings++;
    SC_CHECK_MSG(strstr(text, "http://farm@127.0.0.1:1/cache") && !strstr(text, "pw") && warnings == 1,
                 "log: %s", text);
    sc_cache_close(cache);
    free(dir);
}

int main(void) { return sc_test_main(); }
