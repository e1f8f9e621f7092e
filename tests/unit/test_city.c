/* test_city.c: the procedural city: determinism, scaling, bounds, lights,
 * the default viewpoint and parameter validation. Sizes stay <= 1500 m so
 * the run is quick; the 5 km figures are measured by hand (see the commit). */
#include "test_util.h"
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#include "gi/gi_city.h"
#include "scene/scene_internal.h"

static uint64_t fnv(uint64_t h, const void *data, size_t n) {
  const unsigned char *p = data;
  for (size_t i = 0; i < n; i++) h = (h ^ p[i]) * 0x100000001B3ull;
  return h;
}

/* FNV-1a over everything that defines the geometry. */
static uint64_t scene_hash(const gi_scene *s) {
  uint64_t h = 0xCBF29CE484222325ull;
  h = fnv(h, s->origin, sizeof s->origin);
  h = fnv(h, s->vertices, 3 * sizeof(float) * s->num_vertices);
  h = fnv(h, s->indices, 3 * sizeof(uint32_t) * s->num_triangles);
  h = fnv(h, s->tri_material, sizeof(uint32_t) * s->num_triangles);
  return h;
}

static gi_scene *build(uint64_t seed, double extent, int detail) {
  gi_city_params p = {.seed = seed, .extent = extent, .detail = detail};
  gi_scene *s = NULL;
  gi_error_info err = {0};
  gi_result rc = gi_city_build(&p, NULL, &s, &err);
  if (rc != GI_OK) fprintf(stderr, "gi_city_build: %s\n", err.msg);
  assert_int_equal(rc, GI_OK);
  assert_non_null(s);
  return s;
}

static uint64_t tris(const gi_scene *s) {
  gi_scene_stats st;
  gi_scene_get_stats(s, &st);
  return st.triangles;
}

static void test_deterministic(void **state) {
  gi_scene *a = build(7, 300, 2), *b = build(7, 300, 2), *c = build(8, 300, 2);
  gi_scene_stats sa, sb;
  gi_scene_get_stats(a, &sa);
  gi_scene_get_stats(b, &sb);
  assert_memory_equal(&sa, &sb, sizeof sa);
  assert_int_equal(a->num_vertices, b->num_vertices);
  assert_true(scene_hash(a) == scene_hash(b));
  assert_int_equal(a->num_lights, b->num_lights);
  assert_memory_equal(a->lights, b->lights, a->num_lights * sizeof *a->lights);
  /* Another seed: another city. */
  assert_true(scene_hash(a) != scene_hash(c));
  /* Nothing was dropped: the generator makes no degenerate triangles. */
  assert_int_equal(sa.dropped_degenerate, 0);
  assert_int_equal(sa.dropped_nonfinite, 0);
  assert_int_equal(sa.input_triangles, sa.triangles);
  gi_scene_release(a);
  gi_scene_release(b);
  gi_scene_release(c);
}

static void test_scaling(void **state) {
  gi_scene *s300 = build(1, 300, 2), *s600 = build(1, 600, 2), *s1200 = build(1, 1200, 2);
  gi_scene *d1 = build(1, 300, 1), *d4 = build(1, 300, 4);
  uint64_t t300 = tris(s300), t600 = tris(s600), t1200 = tris(s1200);
  printf("city triangles at detail 2: 300 m %llu, 600 m %llu, 1200 m %llu; 300 m detail 1 %llu, detail 4 %llu\n",
         (unsigned long long)t300, (unsigned long long)t600, (unsigned long long)t1200,
         (unsigned long long)tris(d1), (unsigned long long)tris(d4));
  /* Area grows 4x per doubling; heights fall off from the centre, so allow slack. */
  assert_true(t600 > 2.5 * t300 && t600 < 6.0 * t300);
  assert_true(t1200 > 2.5 * t600 && t1200 < 6.0 * t600);
  /* The default town is a few 10^5 triangles. */
  assert_true(t600 > 100000 && t600 < 1000000);
  assert_true(tris(d4) > 1.5 * t300);
  assert_true(t300 > 1.5 * tris(d1));
  gi_scene_release(s300);
  gi_scene_release(s600);
  gi_scene_release(s1200);
  gi_scene_release(d1);
  gi_scene_release(d4);
}

static void test_default_params(void **state) {
  gi_city_params zero = {0};
  gi_scene *a = NULL, *b = build(1, 600, 2);
  gi_error_info err = {0};
  assert_int_equal(gi_city_build(&zero, NULL, &a, &err), GI_OK);
  assert_true(scene_hash(a) == scene_hash(b));
  /* Printed, not pinned: compare it across machines and compilers by hand. */
  printf("default city: %llu triangles, hash %016llx\n", (unsigned long long)tris(a),
         (unsigned long long)scene_hash(a));
  gi_scene_release(a);
  assert_int_equal(gi_city_build(NULL, NULL, &a, &err), GI_OK);
  assert_true(scene_hash(a) == scene_hash(b));
  assert_string_equal(gi_scene_name(a), "city");
  assert_int_equal(gi_scene_up(a), GI_UP_Y);
  gi_scene_release(a);
  gi_scene_release(b);
}

static void test_bounds_and_materials(void **state) {
  const double extent = 1500;
  gi_scene *s = build(3, extent, 2);
  double lo[3], hi[3];
  gi_scene_bounds(s, lo, hi);
  for (uint32_t i = 0; i < s->num_vertices; i++) {
    const float *v = s->vertices + 3 * (size_t)i;
    double w[3];
    for (int k = 0; k < 3; k++) {
      assert_true(isfinite(v[k]));
      w[k] = s->origin[k] + v[k];
    }
    assert_true(w[0] >= -extent / 2 - 1 && w[0] <= extent / 2 + 1);
    assert_true(w[2] >= -extent / 2 - 1 && w[2] <= extent / 2 + 1);
    assert_true(w[1] >= -1e-3 && w[1] <= 130);
  }
  /* Ground reaches the edges; some towers rise above 60 m. */
  assert_true(lo[0] <= -extent / 2 + 1e-3 && hi[0] >= extent / 2 - 1e-3);
  assert_true(lo[1] > -1e-3 && hi[1] > 60);
  /* A small fixed palette, some of it emissive. */
  gi_scene_stats st;
  gi_scene_get_stats(s, &st);
  assert_true(st.materials >= 8 && st.materials <= 16);
  assert_true(st.emissive_triangles > 0);
  assert_true(st.emissive_triangles < st.triangles / 5);
  int dark = 0, bright = 0;
  for (size_t m = 0; m < gi_scene_num_materials(s); m++) {
    const gi_material *g = gi_scene_material(s, m);
    if (g->albedo[0] < 0.13f && g->emission[0] == 0) dark = 1;
    if (g->albedo[0] >= 0.75f && g->emission[0] == 0) bright = 1;
  }
  assert_true(dark && bright);
  gi_scene_release(s);
}

static void test_lights(void **state) {
  gi_scene *s = build(1, 600, 2);
  assert_true(gi_scene_num_lights(s) > 2);
  const gi_light *sun = gi_scene_light(s, 0), *sky = gi_scene_light(s, 1);
  assert_int_equal(sun->type, GI_LIGHT_SUN);
  assert_true(sun->direction[1] < -0.5f);
  double len = sqrt((double)sun->direction[0] * sun->direction[0] + (double)sun->direction[1] * sun->direction[1] +
                    (double)sun->direction[2] * sun->direction[2]);
  assert_true(fabs(len - 1) < 1e-5);
  assert_true(sun->color[0] > 1 && sun->color[2] > 1);
  assert_int_equal(sky->type, GI_LIGHT_SKY);
  assert_true(sky->color[2] > sky->color[0]);
  for (size_t i = 2; i < gi_scene_num_lights(s); i++) {
    const gi_light *l = gi_scene_light(s, i);
    assert_int_equal(l->type, GI_LIGHT_POINT);
    assert_true(l->position[1] > 3 && l->position[1] < 10);
    assert_true(l->color[0] >= 50 && l->color[0] <= 200);
    /* A lamp's light is outside all geometry: nothing blocks it from just below. */
    float org[3] = {(float)(l->position[0] - s->origin[0]), (float)(l->position[1] - s->origin[1]),
                    (float)(l->position[2] - s->origin[2])};
    float down[3] = {0, -1, 0}, t;
    assert_true(gi__intersect1(s, org, down, 0, 10, &t, NULL, NULL));
    assert_true(fabsf(t - org[1] - (float)s->origin[1]) < 1e-3f); /* hits the ground first */
  }

  /* The caller's lights come after the city's. */
  gi_light extra = {.type = GI_LIGHT_POINT, .color = {1, 2, 3}, .position = {1, 2, 3}};
  gi_scene_options opt = {.lights = &extra, .num_lights = 1, .up = GI_UP_Z};
  gi_scene *t = NULL;
  gi_error_info err = {0};
  assert_int_equal(gi_city_build(NULL, &opt, &t, &err), GI_OK);
  assert_int_equal(gi_scene_up(t), GI_UP_Y);
  size_t n = gi_scene_num_lights(t);
  assert_int_equal(n, gi_scene_num_lights(s) + 1);
  assert_int_equal(gi_scene_light(t, 0)->type, GI_LIGHT_SUN);
  assert_int_equal(gi_scene_light(t, 1)->type, GI_LIGHT_SKY);
  assert_true(gi_scene_light(t, n - 1)->color[2] == 3.f);
  gi_scene_release(t);
  gi_scene_release(s);
}

static void test_generate_light_caps(void **state) {
  gi_light lights[600];
  size_t n = 99;
  gi_error_info err = {0};
  gi_city_params p = {.extent = 300};
  for (size_t cap = 0; cap <= 3; cap++) {
    gi_mesh_builder *b = gi_mesh_builder_new();
    assert_int_equal(gi_city_generate(&p, b, cap ? lights : NULL, cap, &n, &err), GI_OK);
    assert_int_equal(n, cap);
    if (cap >= 1) assert_int_equal(lights[0].type, GI_LIGHT_SUN);
    if (cap >= 2) assert_int_equal(lights[1].type, GI_LIGHT_SKY);
    if (cap >= 3) assert_int_equal(lights[2].type, GI_LIGHT_POINT);
    gi_mesh_builder_free(b);
  }
  /* With room for all, every lamp is a light, nearest the centre first. */
  gi_mesh_builder *b = gi_mesh_builder_new();
  assert_int_equal(gi_city_generate(&p, b, lights, 600, &n, &err), GI_OK);
  assert_true(n > 20 && n < 600);
  for (size_t i = 3; i < n; i++) {
    double r0 = lights[i - 1].position[0] * lights[i - 1].position[0] +
                lights[i - 1].position[2] * lights[i - 1].position[2];
    double r1 = lights[i].position[0] * lights[i].position[0] + lights[i].position[2] * lights[i].position[2];
    assert_true(r1 >= r0 - 2 * sqrt(r0) - 2); /* sorted by whole metres */
    assert_true(fabs(lights[i].position[0]) <= 150 && fabs(lights[i].position[2]) <= 150);
  }
  gi_mesh_builder_free(b);
}

static void test_viewpoint(void **state) {
  const double extents[] = {300, 600, 1500};
  for (int e = 0; e < 3; e++) {
    gi_city_params p = {.seed = 5, .extent = extents[e]};
    gi_scene *s = build(5, extents[e], 2);
    double at[3];
    gi_city_default_viewpoint(&p, at);
    assert_true(at[1] == 1.7);
    assert_true(fabs(at[0]) < 50 && fabs(at[2]) < 50);
    float org[3] = {(float)(at[0] - s->origin[0]), (float)(at[1] - s->origin[1]), (float)(at[2] - s->origin[2])};
    /* In a street: open sky above, ground 1.7 m below. */
    float up[3] = {0, 1, 0}, down[3] = {0, -1, 0}, t;
    assert_false(gi__intersect1(s, org, up, 0, 200, &t, NULL, NULL));
    assert_true(gi__intersect1(s, org, down, 0, 10, &t, NULL, NULL));
    assert_true(fabsf(t - 1.7f) < 1e-3f);
    /* And a few metres of free space around the eye in every horizontal direction. */
    const float dirs[4][3] = {{1, 0, 0}, {-1, 0, 0}, {0, 0, 1}, {0, 0, -1}};
    for (int d = 0; d < 4; d++) assert_false(gi__intersect1(s, org, dirs[d], 0, 2.5f, &t, NULL, NULL));
    gi_scene_release(s);
  }
}

static void expect_invalid(gi_city_params p, const char *field) {
  gi_scene *s = (gi_scene *)1;
  gi_error_info err = {0};
  assert_int_equal(gi_city_build(&p, NULL, &s, &err), GI_ERR_INVALID_ARG);
  assert_null(s);
  assert_int_equal(err.code, GI_ERR_INVALID_ARG);
  if (!strstr(err.msg, field)) fprintf(stderr, "message '%s' does not name '%s'\n", err.msg, field);
  assert_non_null(strstr(err.msg, field));
  gi_mesh_builder *b = gi_mesh_builder_new();
  gi_light l[4];
  size_t n = 7;
  assert_int_equal(gi_city_generate(&p, b, l, 4, &n, &err), GI_ERR_INVALID_ARG);
  assert_int_equal(n, 0);
  gi_mesh_builder_free(b);
}

/* The memory estimate: near the triangles a 1.2 km city makes, and a city
 * whose estimate exceeds the machine's memory is refused before it is
 * made (a 20 km one was killed by the kernel at 23.9 GB of 24). */
static void test_memory_estimate(void **state) {
  gi_scene *s = build(1, 1200, 2);
  double est_tris, bytes = gi_city_bytes_estimate(&(gi_city_params){.extent = 1200}, &est_tris);
  printf("city 1200 m: %llu triangles, estimated %.0f (%.0f MB)\n", (unsigned long long)tris(s), est_tris, bytes / 1e6);
  assert_true(est_tris > 0.8 * (double)tris(s) && est_tris < 1.5 * (double)tris(s));
  gi_scene_release(s);
  assert_true(gi_city_bytes_estimate(&(gi_city_params){.extent = -1}, NULL) == 0);
  gi_city_params big = {.extent = 20000, .detail = 8};
  double need = gi_city_bytes_estimate(&big, NULL), have = (double)sysconf(_SC_PHYS_PAGES) * sysconf(_SC_PAGESIZE);
  if (!(need > have)) {
    printf("SKIP: this machine's %.0f GiB hold a 20 km city at detail 8 (%.0f GiB): not built here\n", have / 1073741824.0,
           need / 1073741824.0);
    return;
  }
  gi_scene *out = NULL;
  gi_error_info err = {0};
  assert_int_equal(gi_city_build(&big, NULL, &out, &err), GI_ERR_NOMEM);
  assert_null(out);
  printf("refused: %s\n", err.msg);
  assert_non_null(strstr(err.msg, "more than this machine's"));
}

static void test_bad_params(void **state) {
  expect_invalid((gi_city_params){.extent = -1}, "extent");
  expect_invalid((gi_city_params){.extent = NAN}, "extent");
  expect_invalid((gi_city_params){.extent = INFINITY}, "extent");
  expect_invalid((gi_city_params){.extent = 1e9}, "extent");
  expect_invalid((gi_city_params){.block = 10, .street = 10}, "block");
  expect_invalid((gi_city_params){.block = 8}, "block"); /* default street 14 m */
  expect_invalid((gi_city_params){.block = -60}, "block");
  expect_invalid((gi_city_params){.street = NAN}, "street");
  expect_invalid((gi_city_params){.detail = 9}, "detail");
  expect_invalid((gi_city_params){.detail = -1}, "detail");
  expect_invalid((gi_city_params){.extent = 20000, .block = 1, .street = 0.5}, "block");
  gi_error_info err = {0};
  assert_int_equal(gi_city_generate(NULL, NULL, NULL, 0, NULL, &err), GI_ERR_INVALID_ARG);
  assert_int_equal(gi_city_build(NULL, NULL, NULL, &err), GI_ERR_INVALID_ARG);
}

static void test_odd_sizes(void **state) {
  /* Tiny, non-multiple and oddly gridded cities still build cleanly. */
  const gi_city_params ps[] = {
      {.extent = 5}, {.extent = 97.3}, {.extent = 250, .block = 33.3, .street = 9.1, .detail = 8},
      {.extent = 400, .block = 15, .street = 14.5}, {.extent = 200, .detail = 1, .seed = UINT64_MAX}};
  for (size_t i = 0; i < sizeof ps / sizeof ps[0]; i++) {
    gi_scene *s = NULL;
    gi_error_info err = {0};
    gi_result rc = gi_city_build(&ps[i], NULL, &s, &err);
    if (rc != GI_OK) fprintf(stderr, "case %zu: %s\n", i, err.msg);
    assert_int_equal(rc, GI_OK);
    gi_scene_stats st;
    gi_scene_get_stats(s, &st);
    assert_true(st.triangles > 0);
    assert_int_equal(st.dropped_degenerate, 0);
    double lo[3], hi[3];
    gi_scene_bounds(s, lo, hi);
    assert_true(lo[0] >= -ps[i].extent / 2 - 1e-3 && hi[0] <= ps[i].extent / 2 + 1e-3);
    assert_true(lo[2] >= -ps[i].extent / 2 - 1e-3 && hi[2] <= ps[i].extent / 2 + 1e-3);
    double at[3];
    gi_city_default_viewpoint(&ps[i], at);
    assert_true(fabs(at[0]) <= ps[i].extent / 2 && fabs(at[2]) <= ps[i].extent / 2);
    gi_scene_release(s);
  }
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_deterministic),
      cmocka_unit_test(test_scaling),
      cmocka_unit_test(test_default_params),
      cmocka_unit_test(test_bounds_and_materials),
      cmocka_unit_test(test_lights),
      cmocka_unit_test(test_generate_light_caps),
      cmocka_unit_test(test_viewpoint),
      cmocka_unit_test(test_bad_params),
      cmocka_unit_test(test_memory_estimate),
      cmocka_unit_test(test_odd_sizes),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
