/* test_proto.c: the request parser and the answer encoders (proto/).
 *
 * Every rejection must be a specific status whose message names the
 * parameter; every accepted request must land in the exact gi_quality the
 * core resolves, with zero left for "default". */
#include "test_util.h"
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "gi_proto.h"

#define KV(...) ((gi_proto_kv[]){__VA_ARGS__})
#define NKV(a) (sizeof(a) / sizeof((a)[0]))

static gi_proto_limits lim(void) {
  gi_proto_limits l;
  gi_proto_limits_default(&l);
  return l;
}

static void expect_fail(const gi_proto_kv *kv, size_t n, int status, const char *needle) {
  gi_proto_limits l = lim();
  gi_proto_bake b;
  gi_proto_error e = {0};
  int st = gi_proto_parse_lighting(kv, n, &l, &b, &e);
  if (st != status || !strstr(e.message, needle))
    fprintf(stderr, "got %d '%s', want %d containing '%s'\n", st, e.message, status, needle);
  assert_int_equal(st, status);
  assert_int_equal(e.status, status);
  assert_non_null(strstr(e.message, needle));
}

static void test_lightmap_ok(void **state) {
  (void)state;
  gi_proto_limits l = lim();
  gi_proto_bake b;
  gi_proto_error e = {0};
  gi_proto_kv kv[] = {{"at", "1,2,3"}, {"kind", "lightmap"}, {"region", "-1,0,-2.5,4,3,5e1"}, {"texel", "0.25"},
                      {"atlas", "512"}};
  assert_int_equal(gi_proto_parse_lighting(kv, NKV(kv), &l, &b, &e), 0);
  assert_int_equal(b.kind, GI_PROTO_LIGHTMAP);
  assert_int_equal(b.has_region, 1);
  double want[6] = {-1, 0, -2.5, 4, 3, 50};
  for (int i = 0; i < 6; i++) assert_true(b.region[i] == want[i]);
  assert_true(b.texel == 0.25);
  assert_int_equal(b.atlas, 512);
  /* The glTF endpoint takes the same parameters but no kind. */
  gi_proto_kv uv[] = {{"at", "1,2,3"}, {"texel", "0.5"}};
  assert_int_equal(gi_proto_parse_lightmap_uv(uv, NKV(uv), &l, &b, &e), 0);
  assert_int_equal(b.kind, GI_PROTO_LIGHTMAP);
  assert_true(b.texel == 0.5 && !b.has_region && b.atlas == 0);
  gi_proto_kv bad[] = {{"at", "1,2,3"}, {"kind", "lightmap"}};
  assert_int_equal(gi_proto_parse_lightmap_uv(bad, NKV(bad), &l, &b, &e), 400);
  assert_non_null(strstr(e.message, "'kind'"));
}

static void test_lighting_ok(void **state) {
  gi_proto_limits l = lim();
  gi_proto_bake b;
  gi_proto_error e = {0};
  gi_proto_kv kv[] = {{"at", "1.5,-2,3e2"}, {"levels", "4"}, {"res", "16"}, {"bounces", "0"}, {"half", "1"}};
  assert_int_equal(gi_proto_parse_lighting(kv, NKV(kv), &l, &b, &e), 0);
  assert_int_equal(b.has_at, 1);
  assert_true(b.at[0] == 1.5 && b.at[1] == -2 && b.at[2] == 300);
  assert_int_equal(b.kind, GI_PROTO_PROBE);
  assert_int_equal(b.quality.levels, 4);
  assert_int_equal(b.quality.res, 16);
  assert_int_equal(b.quality.bounces, -1); /* HTTP 0 = none = the core's -1 */
  assert_int_equal(b.quality.cones, 0);    /* untouched knobs stay default */
  assert_int_equal(b.half, 1);
}

static void test_effects(void **state) {
  gi_proto_limits l = lim();
  gi_proto_bake b;
  gi_proto_error e = {0};
  gi_proto_kv kv[] = {{"at", "0,0,0"}, {"effects", "sky:off,specular:on,bounce:auto"}};
  assert_int_equal(gi_proto_parse_lighting(kv, 2, &l, &b, &e), 0);
  assert_int_equal(b.quality.effects[GI_FX_SKY], GI_FX_OFF);
  assert_int_equal(b.quality.effects[GI_FX_SPECULAR], GI_FX_ON);
  assert_int_equal(b.quality.effects[GI_FX_BOUNCE], GI_FX_AUTO);
  assert_int_equal(b.quality.effects[GI_FX_SUN], GI_FX_AUTO);
  expect_fail(KV({"at", "0,0,0"}, {"effects", "fog:on"}), 2, 400, "unknown effect 'fog'");
  expect_fail(KV({"at", "0,0,0"}, {"effects", "sky"}), 2, 400, "NAME:on|off|auto");
  expect_fail(KV({"at", "0,0,0"}, {"effects", "sky:maybe"}), 2, 400, "after 'sky:'");
  gi_proto_probes p;
  const char *body = "{\"points\":[[1,2,3]],\"quality\":{\"effects\":\"emissive:off\"}}";
  assert_int_equal(gi_proto_parse_probes(body, strlen(body), &l, &p, &e), 0);
  assert_int_equal(p.bake.quality.effects[GI_FX_EMISSIVE], GI_FX_OFF);
  gi_proto_probes_free(&p);
  body = "{\"points\":[[1,2,3]],\"quality\":{\"effects\":1}}";
  assert_int_equal(gi_proto_parse_probes(body, strlen(body), &l, &p, &e), 400);
  assert_non_null(strstr(e.message, "quality.effects"));
}

static void test_preset_then_override(void **state) {
  gi_proto_limits l = lim();
  gi_proto_bake b;
  gi_proto_error e = {0};
  /* The explicit knob wins whatever the order. */
  gi_proto_kv kv[] = {{"cones", "32"}, {"quality", "low"}, {"at", "0,0,0"}};
  assert_int_equal(gi_proto_parse_lighting(kv, NKV(kv), &l, &b, &e), 0);
  assert_int_equal(b.quality.cones, 32);
  assert_int_equal(b.quality.res, 16);
  assert_int_equal(b.quality.levels, 5);
  /* high leaves the bounce count to the plan (its albedo rule and tail):
   * a fixed 3 read a room of albedo 0.95 at a fifth of the default's
   * indirect light, 78% under the path tracer. */
  gi_proto_kv hi[] = {{"quality", "high"}, {"at", "0,0,0"}};
  assert_int_equal(gi_proto_parse_lighting(hi, NKV(hi), &l, &b, &e), 0);
  assert_int_equal(b.quality.cones, 32);
  assert_int_equal(b.quality.bounces, 0);
}

static void test_panorama(void **state) {
  gi_proto_limits l = lim();
  gi_proto_bake b;
  gi_proto_error e = {0};
  gi_proto_kv kv[] = {{"at", "0,0,0"}, {"kind", "panorama"}, {"width", "64"}, {"height", "32"}};
  assert_int_equal(gi_proto_parse_lighting(kv, NKV(kv), &l, &b, &e), 0);
  assert_int_equal(b.kind, GI_PROTO_PANORAMA);
  assert_int_equal(b.width, 64);
  assert_int_equal(b.height, 32);
  l.max_panorama_pixels = 1000;
  assert_int_equal(gi_proto_parse_lighting(kv, NKV(kv), &l, &b, &e), 400);
  assert_non_null(strstr(e.message, "1000 pixels"));
}

static void test_rejections(void **state) {
  expect_fail(KV({"levels", "3"}), 1, 400, "'at' is required");
  expect_fail(KV({"at", "1,2"}), 1, 400, "'at'");
  expect_fail(KV({"at", "1,2,3,4"}), 1, 400, "'at'");
  expect_fail(KV({"at", "nan,0,0"}), 1, 400, "'at'");
  expect_fail(KV({"at", "inf,0,0"}), 1, 400, "'at'");
  expect_fail(KV({"at", "1e999,0,0"}), 1, 400, "'at'");
  expect_fail(KV({"at", "0x10,0,0"}), 1, 400, "'at'");
  expect_fail(KV({"at", "0,0,0"}, {"bogus", "1"}), 2, 400, "unknown parameter 'bogus'");
  expect_fail(KV({"at", "0,0,0"}, {"at", "1,1,1"}), 2, 400, "given twice");
  expect_fail(KV({"at", "0,0,0"}, {"levels", ""}), 2, 400, "no value");
  expect_fail(KV({"at", "0,0,0"}, {"levels", "9"}), 2, 400, "'levels': expected 1..8");
  expect_fail(KV({"at", "0,0,0"}, {"levels", "2.5"}), 2, 400, "expected an integer");
  expect_fail(KV({"at", "0,0,0"}, {"res", "30"}), 2, 400, "multiple of 4");
  expect_fail(KV({"at", "0,0,0"}, {"res", "128"}), 2, 400, "server limit");
  expect_fail(KV({"at", "0,0,0"}, {"cones", "5"}), 2, 400, "4, 6, 8, 16 or 32");
  expect_fail(KV({"at", "0,0,0"}, {"voxel", "-1"}), 2, 400, "'voxel'");
  expect_fail(KV({"at", "0,0,0"}, {"voxel", "nan"}), 2, 400, "'voxel'");
  expect_fail(KV({"at", "0,0,0"}, {"quality", "ultra"}), 2, 400, "low, default or high");
  expect_fail(KV({"at", "0,0,0"}, {"kind", "hdri"}), 2, 400, "probe, panorama or lightmap");
  /* kind=lightmap: its own parameters, checked; they belong to it alone. */
  expect_fail(KV({"at", "0,0,0"}, {"kind", "lightmap"}, {"texel", "0"}), 3, 400, "'texel'");
  expect_fail(KV({"at", "0,0,0"}, {"kind", "lightmap"}, {"texel", "nan"}), 3, 400, "'texel'");
  expect_fail(KV({"at", "0,0,0"}, {"kind", "lightmap"}, {"atlas", "8"}), 3, 400, "'atlas'");
  expect_fail(KV({"at", "0,0,0"}, {"kind", "lightmap"}, {"atlas", "99999"}), 3, 400, "'atlas'");
  expect_fail(KV({"at", "0,0,0"}, {"kind", "lightmap"}, {"region", "0,0,0,1,1"}), 3, 400, "'region'");
  expect_fail(KV({"at", "0,0,0"}, {"kind", "lightmap"}, {"region", "0,0,0,1,1,1,"}), 3, 400, "'region'");
  expect_fail(KV({"at", "0,0,0"}, {"kind", "lightmap"}, {"region", "0,0,0,1,-1,1"}), 3, 400, "min must be below");
  expect_fail(KV({"at", "0,0,0"}, {"texel", "0.5"}), 2, 400, "kind=lightmap only");
  expect_fail(KV({"at", "0,0,0"}, {"width", "64"}), 2, 400, "kind=panorama only");
  expect_fail(KV({"at", "0,0,0"}, {"faces", "1"}), 2, 400, "unknown parameter 'faces'");
  expect_fail(KV({"at", "0,0,0"}, {"half", "yes"}), 2, 400, "0 or 1");
}

/* Integers are integers, values are whole, and finite-but-huge is "out of range" (issue 15, item 7). */
static void test_strict_numbers(void **state) {
  const char *not_int[] = {"64.0", "6.4e1", "1e0", "+8", "0x10", " 8", "8 ", "1_0"};
  for (size_t i = 0; i < sizeof not_int / sizeof not_int[0]; i++) {
    expect_fail(KV({"at", "0,0,0"}, {"res", not_int[i]}), 2, 400, "parameter 'res': expected an integer");
    expect_fail(KV({"at", "0,0,0"}, {"levels", not_int[i]}), 2, 400, "parameter 'levels': expected an integer");
  }
  expect_fail(KV({"at", "0,0,0"}, {"res", "032"}), 2, 400, "parameter 'res': expected an integer without leading zeros");
  expect_fail(KV({"at", "0,0,0"}, {"seed", "00"}), 2, 400, "parameter 'seed': expected an integer without leading zeros");
  expect_fail(KV({"at", "0,0,0"}, {"seed", "99999999999999999999999"}), 2, 400, "parameter 'seed': expected 1..2^53, got 99999999999999999999999 (out of range)");
  expect_fail(KV({"at", "0,0,0"}, {"bounces", "-1"}), 2, 400, "parameter 'bounces': expected 0..8, got -1 (out of range)");
  expect_fail(KV({"at", "0,0,0"}, {"kind", "panorama"}, {"width", "64.0"}), 3, 400, "parameter 'width': expected an integer");
  expect_fail(KV({"at", "0,0,0"}, {"kind", "panorama"}, {"width", "20000"}), 3, 400,
              "parameter 'width': expected an integer in 2..16384, got '20000' (out of range)");
  expect_fail(KV({"at", "0,0,0"}, {"kind", "panorama"}, {"width", "1"}), 3, 400,
              "parameter 'width': expected an integer in 2..16384, got '1' (out of range)");
  /* Finite but too large is "out of range", never "not finite". */
  expect_fail(KV({"at", "1e300,0,0"}), 1, 400, "parameter 'at': out of range");
  expect_fail(KV({"at", "0,0,-2e30"}), 1, 400, "parameter 'at': out of range");
  expect_fail(KV({"at", "1e999,0,0"}), 1, 400, "parameter 'at': out of range");
  /* Underflow is a number within 1e-308 of 0: in range, and a voxel of 0. */
  {
    double v[3];
    assert_int_equal(gi_proto_parse_vec3("1e-320,-1e-400,2", v), 0);
    assert_true(v[0] > 0 && v[0] < 1e-319 && v[1] == 0.0 && v[2] == 2.0);
  }
  expect_fail(KV({"at", "0,0,0"}, {"voxel", "1e-400"}), 2, 400, "parameter 'voxel': expected a voxel size in (0, 1e7]");
  expect_fail(KV({"at", "0,0,0"}, {"voxel", "1e400"}), 2, 400, "parameter 'voxel': '1e400' is out of range");
  expect_fail(KV({"at", "0,0,0"}, {"voxel", "1e300"}), 2, 400, "parameter 'voxel': expected a voxel size in (0, 1e7], got 1e+300 (out of range)");
  /* A value that is not a multiple of 4 is wrong, not out of range. */
  expect_fail(KV({"at", "0,0,0"}, {"res", "30"}), 2, 400, "got 30");
  {
    gi_proto_limits l = lim();
    gi_proto_bake b;
    gi_proto_error e = {0};
    gi_proto_kv kv[] = {{"at", "0,0,0"}, {"res", "30"}};
    assert_int_equal(gi_proto_parse_lighting(kv, 2, &l, &b, &e), 400);
    assert_null(strstr(e.message, "out of range"));
  }
  /* Trailing bytes after the third number. */
  expect_fail(KV({"at", "1,2,3garbage"}), 1, 400, "parameter 'at': expected three finite numbers");
  expect_fail(KV({"at", "1,2,3,"}), 1, 400, "parameter 'at'");
  /* What stays valid: 0, negative coordinates, exponents in reals, the largest seed. */
  gi_proto_limits l = lim();
  gi_proto_bake b;
  gi_proto_error e = {0};
  gi_proto_kv ok[] = {{"at", "-1e29,0,2.5e-3"}, {"bounces", "0"}, {"voxel", "2.5e-1"}, {"seed", "9007199254740992"}};
  assert_int_equal(gi_proto_parse_lighting(ok, NKV(ok), &l, &b, &e), 0);
  assert_true(b.at[0] == -1e29 && b.at[2] == 2.5e-3);
  assert_true(b.quality.voxel0 == 0.25);
  assert_true(b.quality.seed == 9007199254740992ull);
  /* The body keeps 64 and 64.0 apart too. */
  gi_proto_probes p;
  const char *bad[][2] = {
      {"{\"points\":[[1,2,3]],\"quality\":{\"res\":16.0}}", "quality.res: expected an integer"},
      {"{\"points\":[[1,2,3]],\"quality\":{\"levels\":1e0}}", "quality.levels: expected an integer"},
      {"{\"points\":[[1e300,2,3]]}", "points[0]: out of range"},
      {"{\"points\":[[1,2,3]],\"at\":[0,0,1e31]}", "'at': out of range"},
      {"{\"points\":[[1,2,3]],\"quality\":{\"effects\":\"sky:off,sky:on\"}}", "effect 'sky' given twice"},
      /* An unknown key is named as such whatever its value (a string or a
       * boolean read "expected a number"), with the keys the object takes. */
      {"{\"points\":[[1,2,3]],\"quality\":{\"quality\":\"low\"}}", "quality.quality: unknown quality knob (expected preset,"},
      {"{\"points\":[[1,2,3]],\"quality\":{\"half\":true}}", "quality.half: unknown quality knob"},
      {"{\"points\":[[1,2,3]],\"quality\":{\"width\":4}}", "quality.width: unknown quality knob"},
  };
  for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
    int st = gi_proto_parse_probes(bad[i][0], strlen(bad[i][0]), &l, &p, &e);
    if (st != 400 || !strstr(e.message, bad[i][1])) fprintf(stderr, "body %zu: got %d '%s'\n", i, st, e.message);
    assert_int_equal(st, 400);
    assert_non_null(strstr(e.message, bad[i][1]));
  }
}

/* Effects: each entry once, none empty. */
static void test_effects_strict(void **state) {
  expect_fail(KV({"at", "0,0,0"}, {"effects", "sky:off,sky:on"}), 2, 400, "parameter 'effects': effect 'sky' given twice");
  expect_fail(KV({"at", "0,0,0"}, {"effects", "sky:off,sky:off"}), 2, 400, "given twice");
  const char *empty[] = {",,,,", ",sky:off", "sky:off,", "sky:off,,sun:on", ","};
  for (size_t i = 0; i < sizeof empty / sizeof empty[0]; i++)
    expect_fail(KV({"at", "0,0,0"}, {"effects", empty[i]}), 2, 400, "parameter 'effects': empty entry");
}

static void test_cascades(void **state) {
  gi_proto_limits l = lim();
  gi_proto_bake b;
  gi_proto_error e = {0};
  gi_proto_kv ok[] = {{"at", "0,0,0"}, {"faces", "1"}, {"levels", "2"}};
  assert_int_equal(gi_proto_parse_cascades(ok, 3, &l, &b, &e), 0);
  assert_int_equal(b.faces, 1);
  gi_proto_kv bad[] = {{"at", "0,0,0"}, {"kind", "probe"}};
  assert_int_equal(gi_proto_parse_cascades(bad, 2, &l, &b, &e), 400);
  assert_non_null(strstr(e.message, "'kind'"));
  assert_int_equal(gi_proto_parse_none(bad, 1, &e), 400);
  assert_int_equal(gi_proto_parse_none(NULL, 0, &e), 0);
}

static int probes(const char *body, gi_proto_probes *p, gi_proto_error *e, size_t max_job) {
  gi_proto_limits l = lim();
  l.max_probes_job = max_job;
  return gi_proto_parse_probes(body, strlen(body), &l, p, e);
}

static void test_probes_body(void **state) {
  gi_proto_probes p;
  gi_proto_error e = {0};
  assert_int_equal(probes("{\"points\":[[1,2,3],[4.5,-5,6e1]],\"quality\":{\"preset\":\"low\",\"res\":24},"
                          "\"half\":true,\"ao\":true,\"at\":[7,8,9]}", &p, &e, 100), 0);
  assert_int_equal(p.num_points, 2);
  assert_true(p.points[3] == 4.5 && p.points[4] == -5 && p.points[5] == 60);
  assert_int_equal(p.bake.quality.res, 24);
  assert_int_equal(p.bake.quality.levels, 5);
  assert_int_equal(p.bake.quality.ao, 1);
  assert_int_equal(p.bake.half, 1);
  assert_true(p.bake.has_at && p.bake.at[2] == 9);
  gi_proto_probes_free(&p);

  struct { const char *body; int status; const char *needle; } bad[] = {
      {"", 400, "line 1"},
      {"[1,2,3]", 400, "JSON object"},
      {"{\"points\":[]}", 400, "non-empty"},
      {"{\"points\":[[1,2]]}", 400, "points[0]"},
      {"{\"points\":[[1,2,3],[1,2,\"x\"]]}", 400, "points[1]"},
      {"{\"points\":[[1,2,1e999]]}", 400, "overflow"},
      {"{\"points\":[[1,2,3]],\"extra\":1}", 400, "unknown field 'extra'"},
      {"{\"points\":[[1,2,3]],\"points\":[[1,2,3]]}", 400, "duplicate"},
      {"{\"points\":[[1,2,3]],\"quality\":{\"levels\":99}}", 400, "quality.levels"},
      {"{\"points\":[[1,2,3]],\"quality\":\"max\"}", 400, "low, default or high"},
      {"{\"points\":[[1,2,3]],\"half\":1}", 400, "'half'"},
      {"{\"points\":[[1,2,3],[1,2,3],[1,2,3]]}", 413, "3 points exceed"},
  };
  for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
    int st = probes(bad[i].body, &p, &e, 2);
    if (st != bad[i].status || !strstr(e.message, bad[i].needle))
      fprintf(stderr, "body %zu: got %d '%s'\n", i, st, e.message);
    assert_int_equal(st, bad[i].status);
    assert_non_null(strstr(e.message, bad[i].needle));
    assert_null(p.points);
  }
  /* A body over the byte limit is refused before parsing. */
  gi_proto_limits l = lim();
  l.max_body_bytes = 8;
  assert_int_equal(gi_proto_parse_probes("{\"points\":[[1,2,3]]}", 20, &l, &p, &e), 413);
}

static void test_error_roundtrip(void **state) {
  gi_proto_error e, back;
  gi_proto_fail(&e, 503, "busy \"now\" %d", 7);
  assert_string_equal(e.name, "overloaded");
  char *js = gi_proto_error_json(&e);
  assert_non_null(js);
  assert_int_equal(gi_proto_error_parse(js, strlen(js), &back), 0);
  assert_int_equal(back.status, 503);
  assert_string_equal(back.name, "overloaded");
  assert_string_equal(back.message, "busy \"now\" 7");
  free(js);
  /* A message quoting bytes that are not UTF-8 (or cut inside a character)
   * still encodes: each such byte is '?', a whole character is kept. */
  gi_proto_fail(&e, 404, "no such endpoint: %s", "/a\xff\xc0\xaf\xed\xa0\x80\xc3\xa9\xe2\x82");
  js = gi_proto_error_json(&e);
  assert_non_null(js);
  assert_int_equal(gi_proto_error_parse(js, strlen(js), &back), 0);
  assert_string_equal(back.message, "no such endpoint: /a??????\xc3\xa9??");
  free(js);
  assert_int_equal(gi_proto_error_parse("{\"x\":1}", 7, &back), -1);
  assert_string_equal(gi_proto_status_name(413), "payload_too_large");
  assert_string_equal(gi_proto_status_name(504), "timeout");
}

static void test_job_roundtrip(void **state) {
  gi_proto_job j = {.state = GI_JOB_RUNNING, .probes = 10, .probes_done = 4, .tiles = 5, .tiles_done = 2,
                    .elapsed_s = 1.25}, back;
  strcpy(j.id, "abc123");
  char *js = gi_proto_job_json(&j);
  assert_non_null(strstr(js, "\"progress\":0.4"));
  assert_int_equal(gi_proto_job_parse(js, strlen(js), &back), 0);
  assert_string_equal(back.id, "abc123");
  assert_int_equal(back.state, GI_JOB_RUNNING);
  assert_int_equal(back.probes_done, 4);
  assert_int_equal(back.tiles, 5);
  assert_true(fabs(back.elapsed_s - 1.25) < 1e-12);
  free(js);
  j.state = GI_JOB_FAILED;
  gi_proto_fail(&j.error, 500, "bake failed");
  js = gi_proto_job_json(&j);
  assert_int_equal(gi_proto_job_parse(js, strlen(js), &back), 0);
  assert_int_equal(back.state, GI_JOB_FAILED);
  assert_string_equal(back.error.message, "bake failed");
  free(js);
}

/* Sessions: the start 'at' is optional, quality from the query or a body
 * (not both); a session's lighting takes no quality and no lightmap. */
static void test_sessions(void **state) {
  (void)state;
  gi_proto_limits l = lim();
  gi_proto_bake b;
  gi_proto_error e = {0};
  gi_proto_kv q[] = {{"quality", "low"}, {"levels", "4"}};
  assert_int_equal(gi_proto_parse_session(q, NKV(q), NULL, 0, &l, &b, &e), 0);
  assert_int_equal(b.has_at, 0);
  assert_int_equal(b.quality.levels, 4);
  const char *body = "{\"at\":[1,2.5,-3],\"quality\":{\"preset\":\"low\",\"res\":16}}";
  assert_int_equal(gi_proto_parse_session(NULL, 0, body, strlen(body), &l, &b, &e), 0);
  assert_true(b.has_at && b.at[0] == 1 && b.at[1] == 2.5 && b.at[2] == -3);
  assert_int_equal(b.quality.res, 16);
  assert_int_equal(gi_proto_parse_session(q, NKV(q), body, strlen(body), &l, &b, &e), 400);
  assert_non_null(strstr(e.message, "not both"));
  /* 'at' alone in both places: the message names 'at', not the quality. */
  gi_proto_kv qa[] = {{"at", "1,2.5,-3"}};
  const char *at_body = "{\"at\":[1,2.5,-3]}";
  assert_int_equal(gi_proto_parse_session(qa, NKV(qa), at_body, strlen(at_body), &l, &b, &e), 400);
  assert_non_null(strstr(e.message, "start 'at' and quality come in the JSON body or in the query, not both: the "
                                    "query has 'at'"));
  const char *bad = "{\"points\":[[0,0,0]]}";
  assert_int_equal(gi_proto_parse_session(NULL, 0, bad, strlen(bad), &l, &b, &e), 400);
  assert_non_null(strstr(e.message, "unknown field 'points'"));
  gi_proto_kv far[] = {{"at", "1e31,0,0"}};
  assert_int_equal(gi_proto_parse_session(far, NKV(far), NULL, 0, &l, &b, &e), 400);
  assert_non_null(strstr(e.message, "parameter 'at': out of range"));

  gi_proto_kv mv[] = {{"at", "1,2,3"}, {"kind", "panorama"}, {"width", "64"}, {"height", "32"}, {"half", "1"}};
  assert_int_equal(gi_proto_parse_session_lighting(mv, NKV(mv), &l, &b, &e), 0);
  assert_true(b.kind == GI_PROTO_PANORAMA && b.width == 64 && b.height == 32 && b.half == 1 && b.at[2] == 3);
  gi_proto_kv knob[] = {{"at", "1,2,3"}, {"bounces", "2"}};
  assert_int_equal(gi_proto_parse_session_lighting(knob, NKV(knob), &l, &b, &e), 400);
  assert_non_null(strstr(e.message, "parameter 'bounces': a session's quality is set when it is created"));
  gi_proto_kv lm[] = {{"at", "1,2,3"}, {"kind", "lightmap"}};
  assert_int_equal(gi_proto_parse_session_lighting(lm, NKV(lm), &l, &b, &e), 400);
  assert_non_null(strstr(e.message, "parameter 'kind'"));
  gi_proto_kv none[] = {{"kind", "probe"}};
  assert_int_equal(gi_proto_parse_session_lighting(none, NKV(none), &l, &b, &e), 400);
  assert_non_null(strstr(e.message, "parameter 'at' is required"));
  gi_proto_kv nan[] = {{"at", "nan,2,3"}};
  assert_int_equal(gi_proto_parse_session_lighting(nan, NKV(nan), &l, &b, &e), 400);
  assert_non_null(strstr(e.message, "parameter 'at'"));
  /* The session's JSON reads back. */
  gi_proto_session ss = {.ttl_s = 300, .at = {1, 2, 3}, .moves = 7, .bytes = 4096}, back;
  strcpy(ss.id, "0123456789abcdef0123456789abcdef");
  strcpy(ss.scene, "city");
  char *js = gi_proto_session_json(&ss);
  assert_non_null(strstr(js, "\"lighting\":\"/v1/sessions/0123456789abcdef0123456789abcdef/lighting\""));
  assert_int_equal(gi_proto_session_parse(js, strlen(js), &back), 0);
  assert_string_equal(back.id, ss.id);
  assert_string_equal(back.scene, "city");
  assert_true(back.ttl_s == 300 && back.at[1] == 2 && back.moves == 7 && back.bytes == 4096);
  free(js);
  assert_int_equal(gi_proto_session_parse("{}", 2, &back), -1);
}

static void test_headers(void **state) {
  gi_timings t = {.voxelize = 1.5, .inject = 2, .filter = 0.25, .bounce = 10, .gather = 0.5, .encode = 1};
  char buf[320];
  gi_proto_server_timing(&t, 16.25, buf, sizeof buf);
  assert_string_equal(buf, "voxelize;dur=1.50, inject;dur=2.00, filter;dur=0.25, bounce;dur=10.00, "
                           "gather;dur=0.50, encode;dur=1.00, total;dur=16.25");
  gi_proto_server_timing_layout(0.4, &t, 16.5, buf, sizeof buf);
  assert_string_equal(buf, "layout;dur=0.40, voxelize;dur=1.50, inject;dur=2.00, filter;dur=0.25, bounce;dur=10.00, "
                           "gather;dur=0.50, encode;dur=1.00, total;dur=16.50");
  /* Cut short, never past the buffer. */
  gi_proto_server_timing_layout(3, &t, 16.5, buf, 8);
  assert_string_equal(buf, "layout;");
  gi_effect fx[GI_FX_COUNT] = {{0}};
  fx[GI_FX_SUN].ran = 1;
  fx[GI_FX_BOUNCE].ran = 1;
  gi_proto_effects_header(fx, buf, sizeof buf);
  assert_string_equal(buf, "sun=ran, local_lights=skipped, sky=skipped, emissive=skipped, bounce=ran, "
                           "specular=skipped, ao=skipped");
}

/* Cell URLs (issue 14): the path segment, q required and strict, no 'at'
 * there and no 'q' on a viewpoint URL; redirect defaults to 1. */
static void test_cell_requests(void **state) {
  (void)state;
  long long c[3];
  assert_int_equal(gi_proto_parse_cell("2,-5,0", c), 0);
  assert_true(c[0] == 2 && c[1] == -5 && c[2] == 0);
  assert_int_equal(gi_proto_parse_cell("-123456789012345678,1,1", c), 0);
  assert_true(c[0] == -123456789012345678ll);
  const char *bad[] = {"1,2", "1,2,3,", "1,,3", "01,2,3", "-0,1,1", "+1,2,3", "1,2,3x", "1.5,2,3", "", "a,b,c",
                       "1, 2,3", "12345678901234567890,0,x"};
  for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) assert_int_equal(gi_proto_parse_cell(bad[i], c), -1);
  /* Well-formed but too long to address: told apart, so the server names the cell (400, not 404). */
  const char *far[] = {"1234567890123456789,0,0", "0,-1000000000000000000,0", "1,2,99999999999999999999999999"};
  for (size_t i = 0; i < sizeof far / sizeof far[0]; i++) assert_int_equal(gi_proto_parse_cell(far[i], c), -2);

  gi_proto_limits l = lim();
  gi_proto_bake b;
  gi_proto_error e = {0};
  gi_proto_kv ok[] = {{"q", "0123456789abcdef"}, {"kind", "panorama"}, {"levels", "3"}, {"width", "32"}};
  assert_int_equal(gi_proto_parse_cell_lighting(ok, NKV(ok), &l, &b, &e), 0);
  assert_true(b.cell == 1 && !b.has_at && b.kind == GI_PROTO_PANORAMA && b.width == 32);
  assert_string_equal(b.q, "0123456789abcdef");
  gi_proto_kv noq[] = {{"kind", "probe"}};
  assert_int_equal(gi_proto_parse_cell_lighting(noq, NKV(noq), &l, &b, &e), 400);
  assert_non_null(strstr(e.message, "'q'"));
  gi_proto_kv badq[] = {{"q", "0123456789ABCDEF"}};
  assert_int_equal(gi_proto_parse_cell_cascades(badq, NKV(badq), &l, &b, &e), 400);
  gi_proto_kv at[] = {{"q", "0123456789abcdef"}, {"at", "1,2,3"}};
  assert_int_equal(gi_proto_parse_cell_lighting(at, NKV(at), &l, &b, &e), 400);
  assert_non_null(strstr(e.message, "'at'"));
  gi_proto_kv lm[] = {{"q", "0123456789abcdef"}, {"kind", "lightmap"}};
  assert_int_equal(gi_proto_parse_cell_lighting(lm, NKV(lm), &l, &b, &e), 501);
  gi_proto_kv vp[] = {{"at", "1,2,3"}};
  assert_int_equal(gi_proto_parse_lighting(vp, NKV(vp), &l, &b, &e), 0);
  assert_int_equal(b.redirect, 1);
  gi_proto_kv vp0[] = {{"at", "1,2,3"}, {"redirect", "0"}};
  assert_int_equal(gi_proto_parse_cascades(vp0, NKV(vp0), &l, &b, &e), 0);
  assert_int_equal(b.redirect, 0);
  gi_proto_kv vpq[] = {{"at", "1,2,3"}, {"q", "0123456789abcdef"}};
  assert_int_equal(gi_proto_parse_lighting(vpq, NKV(vpq), &l, &b, &e), 400);
  gi_proto_kv sc[] = {{"quality", "low"}, {"res", "8"}};
  assert_int_equal(gi_proto_parse_scene(sc, NKV(sc), &l, &b, &e), 0);
  assert_true(b.quality.res == 8 && b.quality.levels == 5);
  gi_proto_kv sca[] = {{"at", "1,2,3"}};
  assert_int_equal(gi_proto_parse_scene(sca, NKV(sca), &l, &b, &e), 400);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_lighting_ok),   cmocka_unit_test(test_cell_requests),
      cmocka_unit_test(test_lightmap_ok),   cmocka_unit_test(test_preset_then_override),
      cmocka_unit_test(test_effects),       cmocka_unit_test(test_strict_numbers),
      cmocka_unit_test(test_effects_strict),
      cmocka_unit_test(test_panorama),      cmocka_unit_test(test_rejections),
      cmocka_unit_test(test_cascades),      cmocka_unit_test(test_probes_body),
      cmocka_unit_test(test_error_roundtrip), cmocka_unit_test(test_job_roundtrip),
      cmocka_unit_test(test_headers),       cmocka_unit_test(test_sessions),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
