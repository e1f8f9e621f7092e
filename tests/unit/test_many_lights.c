/* test_many_lights.c: thousands of point and spot lights (scene/local_tree.c).
 *
 * A street of lamps over a ground plane. With more lights than
 * GI_LOCAL_EXACT_RATIO times the cut, a point's local-light samples come
 * from a light cut: at most the cut's size, every light that matters its
 * own, the rest one pick per group divided by its probability. Checked:
 * the cut's mean over many seeds against the exact sum over every light
 * (unbiased), its size, a lamp next to the point always sampled as
 * itself, fewer lights still sampled one by one, and a probe's direct
 * light against the closed form sum over every lamp. */
#include "test_util.h"
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "gi/gi.h"
#include "scene/lights.h"
#include "scene/scene_internal.h"

/* n lamps over the ground square [-60, 60]^2 (y up), heights 2-7 m, a
 * quarter of them spots aimed down; fixed pseudo-random layout. */
static gi_light *lamps(int n, int spots) {
  gi_light *l = calloc((size_t)n, sizeof *l);
  uint64_t r = 12345;
  for (int i = 0; i < n; i++) {
    float u[4];
    for (int k = 0; k < 4; k++) u[k] = gi__u01(&r);
    l[i].type = spots && i % 4 == 3 ? GI_LIGHT_SPOT : GI_LIGHT_POINT;
    l[i].position[0] = -60 + 120 * u[0];
    l[i].position[1] = 2 + 5 * u[1];
    l[i].position[2] = -60 + 120 * u[2];
    float I = 10 + 190 * u[3];
    l[i].color[0] = I, l[i].color[1] = 0.8f * I, l[i].color[2] = 0.6f * I;
    if (l[i].type == GI_LIGHT_SPOT) {
      l[i].direction[1] = -1;
      l[i].cos_inner = cosf(0.5f), l[i].cos_outer = cosf(0.8f);
    }
  }
  return l;
}

static gi_scene *street(const gi_light *l, int n) {
  gi_mesh_builder *b = gi_mesh_builder_new();
  gi_material m = {.albedo = {0.5f, 0.5f, 0.5f}, .roughness = 1};
  uint32_t mat = gi_mesh_builder_add_material(b, &m);
  double A[3] = {-100, 0, -100}, B[3] = {-100, 0, 100}, C[3] = {100, 0, 100}, D[3] = {100, 0, -100};
  gi_mesh_builder_add_quad(b, A, B, C, D, mat);
  return tu_build(b, "street", l, (size_t)n);
}

/* The cut's samples at p, over many seeds, against the sum over every
 * light of what it sends to p (unshadowed, every direction). */
static void check_unbiased(const gi_scene *s, const gi_light_plan *lp, const float p[3], int nearest, double max_sd) {
  double exact[3] = {0, 0, 0};
  for (uint32_t i = 0; i < s->num_lights; i++) {
    gi_lsample o;
    if (gi__local_sample(s, &s->lights[i], p, &o))
      for (int k = 0; k < 3; k++) exact[k] += o.V[k];
  }
  gi_lsample near_one;
  int have_near = nearest >= 0 && gi__local_sample(s, &s->lights[nearest], p, &near_one);
  int cap = gi__light_sample_cap(s, lp);
  assert_int_equal(cap, lp->local_cut);
  gi_lsample *buf = calloc((size_t)cap, sizeof *buf);
  const int N = 4000;
  double sum = 0, sum2 = 0;
  int most = 0;
  for (int seed = 1; seed <= N; seed++) {
    uint64_t rng = gi__mix64((uint64_t)seed);
    int n = gi__light_samples(s, lp, p, &rng, buf, cap);
    assert_true(n >= 1 && n <= lp->local_cut);
    most = n > most ? n : most;
    double e = 0;
    int found = 0;
    for (int i = 0; i < n; i++) {
      assert_true(buf[i].fx == GI_FX_LOCAL && isfinite(buf[i].V[0]) && buf[i].V[0] >= 0);
      e += buf[i].V[0];
      found |= have_near && !memcmp(buf[i].V, near_one.V, sizeof near_one.V) && buf[i].dist == near_one.dist;
    }
    /* The lamp beside the point brings most of its light: always its own sample. */
    if (have_near) assert_true(found);
    sum += e, sum2 += e * e;
  }
  double mean = sum / N, sd = sqrt(fmax(sum2 / N - mean * mean, 0)), se = sd / sqrt(N);
  double rel = fabs(mean - exact[0]) / exact[0];
  printf("p (%g, %g, %g): exact %.6g, cut mean %.6g (%+.3f%%, %.1f standard errors), one cut's sd %.2f%%, "
         "up to %d samples of %u lights\n",
         p[0], p[1], p[2], exact[0], mean, 100 * (mean - exact[0]) / exact[0], fabs(mean - exact[0]) / se,
         100 * sd / exact[0], most, s->num_local);
  assert_true(fabs(mean - exact[0]) < 4 * se + 1e-6 * exact[0]);
  assert_true(rel < 0.005);
  /* One cut's noise: the groups it samples bring at most a small share. */
  assert_true(sd / exact[0] < max_sd);
  free(buf);
}

static void test_cut_unbiased(void **state) {
  (void)state;
  const int n = 3000;
  gi_light *l = lamps(n, 1);
  gi_scene *s = street(l, n);
  assert_non_null(s);
  assert_non_null(s->local_tree);
  assert_int_equal(s->num_local, n);
  gi_light_plan lp = {.local = 1, .local_cut = GI_LOCAL_CUT_MIN};
  assert_true(gi__local_by_cut(s, &lp));
  const float pts[3][3] = {{0, 1, 0}, {37, 0.5f, -21}, {59, 4, 59}};
  for (int i = 0; i < 3; i++) check_unbiased(s, &lp, pts[i], -1, 0.10);
  /* 5 cm beside lamp 17 (a point light: i % 4 != 3). */
  float beside[3];
  for (int k = 0; k < 3; k++) beside[k] = (float)(l[17].position[k] - s->origin[k]) + (k == 0 ? 0.05f : 0.f);
  check_unbiased(s, &lp, beside, 17, 0.01);
  /* The larger cut of 64 samples per probe, over the same lamps. */
  lp.local_cut = 4 * 64;
  assert_true(gi__local_by_cut(s, &lp));
  check_unbiased(s, &lp, pts[0], -1, 0.03);
  gi_scene_release(s);
  free(l);
}

/* Up to GI_LOCAL_EXACT_RATIO times the cut, every light is its own sample,
 * in order, as without a tree. */
static void test_few_lights_exact(void **state) {
  (void)state;
  const int n = GI_LOCAL_EXACT_RATIO * GI_LOCAL_CUT_MIN;
  gi_light *l = lamps(n, 1);
  gi_scene *s = street(l, n);
  assert_non_null(s);
  assert_null(s->local_tree);
  gi_light_plan lp = {.local = 1, .local_cut = GI_LOCAL_CUT_MIN};
  assert_false(gi__local_by_cut(s, &lp));
  int cap = gi__light_sample_cap(s, &lp);
  assert_int_equal(cap, n);
  gi_lsample *buf = calloc((size_t)cap, sizeof *buf);
  const float p[3] = {3, 1, -4};
  uint64_t rng = 7;
  int got = gi__light_samples(s, &lp, p, &rng, buf, cap), m = 0;
  for (int i = 0; i < n; i++) {
    gi_lsample o;
    if (!gi__local_sample(s, &s->lights[i], p, &o)) continue;
    assert_true(m < got);
    assert_memory_equal(buf[m].V, o.V, sizeof o.V);
    m++;
  }
  assert_int_equal(got, m);
  free(buf);
  gi_scene_release(s);
  free(l);
}

/* A probe 1 m above the ground under 3000 point lamps (2-7 m high, so the
 * ground hides none): E(up) = sum of I cos / r^2, against the baked
 * probe's direct light, which samples them through a 256-light cut (64
 * samples per probe; the default 256 would take all 3000 one by one). */
static void test_cut_probe(void **state) {
  (void)state;
  const int n = 3000;
  gi_light *l = lamps(n, 0);
  gi_scene *s = street(l, n);
  assert_non_null(s);
  gi_quality q = {.levels = 2, .res = 16, .voxel0 = 1, .bounces = -1, .probe_samples = 64};
  gi_cascade *c = NULL;
  gi_bake_report rep;
  gi_error_info err = {0};
  double at[3] = {0, 1, 0};
  assert_int_equal(gi_cascade_bake(s, at, &q, &c, &rep, &err), GI_OK);
  /* The plan says how it samples them. */
  printf("local lights: %s\n", rep.effects[GI_FX_LOCAL].why);
  assert_string_equal(rep.effects[GI_FX_LOCAL].why, "3000 point/spot lights through a light cut: 64 rays per voxel, "
                                                    "256 per probe");
  const double pts[6][3] = {{0, 1, 0}, {10, 1, 3}, {-25, 1, 18}, {40, 1, -40}, {-58, 1, -5}, {5, 1, 55}};
  double worst = 0, mean = 0;
  for (int i = 0; i < 6; i++) {
    double E = 0;
    for (int j = 0; j < n; j++) {
      double v[3];
      for (int k = 0; k < 3; k++) v[k] = l[j].position[k] - pts[i][k];
      double r2 = v[0] * v[0] + v[1] * v[1] + v[2] * v[2];
      E += l[j].color[0] * (v[1] / sqrt(r2)) / r2;
    }
    gi_probe pr;
    assert_int_equal(gi_cascade_gather(c, pts[i], 1, &pr, NULL, &err), GI_OK);
    double rel = fabs(pr.direct[0] - E) / E;
    printf("probe (%g, %g, %g): direct %.5g, closed form %.5g (%.2f%%)\n", pts[i][0], pts[i][1], pts[i][2],
           pr.direct[0], E, 100 * rel);
    worst = fmax(worst, rel), mean += rel / 6;
  }
  printf("mean %.2f%%, worst %.2f%%\n", 100 * mean, 100 * worst);
  assert_true(mean < 0.01);
  assert_true(worst < 0.03);
  gi_cascade_free(c);
  gi_scene_release(s);
  free(l);
}

/* A glTF of 5000 lamps under one parent node 4000 km east: all of them
 * load, each where its node puts it to 1e-6 m (float would round 4e6 m
 * to 0.25 m). assimp 5.2 matched every light to its node by name through the
 * whole graph, twice (16,384 lamps: 3.6 s); the file's own reader places
 * them in one walk. */
static void test_many_lamps_file(void **state) {
  (void)state;
  const int n = 5000;
  size_t cap = (size_t)n * 128 + 4096, len = 0;
  char *j = malloc(cap);
  len += (size_t)snprintf(j + len, cap - len,
                          "{\"asset\":{\"version\":\"2.0\"},\"scene\":0,\"scenes\":[{\"nodes\":[0,1]}],"
                          "\"extensionsUsed\":[\"KHR_lights_punctual\"],\"extensions\":{\"KHR_lights_punctual\":"
                          "{\"lights\":[{\"type\":\"point\",\"intensity\":50}]}},"
                          "\"nodes\":[{\"mesh\":0},{\"translation\":[4000000.1,0,0],\"children\":[");
  for (int i = 0; i < n; i++) len += (size_t)snprintf(j + len, cap - len, "%s%d", i ? "," : "", i + 2);
  len += (size_t)snprintf(j + len, cap - len, "]}");
  for (int i = 0; i < n; i++)
    len += (size_t)snprintf(j + len, cap - len,
                            ",{\"translation\":[%d.25,%d,%d],\"extensions\":{\"KHR_lights_punctual\":{\"light\":0}}}",
                            i % 100, 3 + i % 5, i / 100);
  len += (size_t)snprintf(j + len, cap - len,
                          "],\"meshes\":[{\"primitives\":[{\"attributes\":{\"POSITION\":0},\"indices\":1}]}],"
                          "\"buffers\":[{\"byteLength\":44,\"uri\":\"data:application/octet-stream;base64,"
                          "AAAAAAAAAAAAAAAAAACAPwAAAAAAAAAAAAAAAAAAgD8AAAAAAAABAAIAAAA=\"}],"
                          "\"bufferViews\":[{\"buffer\":0,\"byteOffset\":0,\"byteLength\":36},"
                          "{\"buffer\":0,\"byteOffset\":36,\"byteLength\":6}],"
                          "\"accessors\":[{\"bufferView\":0,\"componentType\":5126,\"count\":3,"
                          "\"type\":\"VEC3\",\"min\":[0,0,0],\"max\":[1,1,0]},"
                          "{\"bufferView\":1,\"componentType\":5123,\"count\":3,\"type\":\"SCALAR\"}]}");
  assert_true(len < cap);
  const char *path = tu_write_file("lamps.gltf", j, len);
  free(j);
  gi_scene *s = NULL;
  gi_error_info err = {0};
  assert_int_equal(gi_scene_load(path, NULL, &s, &err), GI_OK);
  assert_int_equal(gi_scene_num_lights(s), n);
  assert_non_null(s->local_tree);
  for (int i = 0; i < n; i += 997) {
    const gi_light *l = gi_scene_light(s, (size_t)i);
    assert_int_equal(l->type, GI_LIGHT_POINT);
    assert_float_equal(l->position[0], 4000000.1 + i % 100 + 0.25, 1e-6);
    assert_true(l->position[1] == 3 + i % 5 && l->position[2] == i / 100);
    assert_float_equal(l->color[1], 50.0 / 683, 1e-7); /* candela to W/sr */
  }
  gi_scene_release(s);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_cut_unbiased),
      cmocka_unit_test(test_few_lights_exact),
      cmocka_unit_test(test_cut_probe),
      cmocka_unit_test(test_many_lamps_file),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
