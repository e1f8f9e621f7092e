/* test_quality.c: the default cascade shape (gi_quality_resolve's voxel0
 * and levels). Compact scenes keep the extent rule (the coarsest of 6
 * levels spans 1.25x the scene); a scene wider than a street's reach keeps
 * that reach and gets more levels, not coarser voxels. */
#include <math.h>
#include <stdio.h>
#include <string.h>
#include "gi/gi.h"
#include "test_util.h"

enum { R = 32, DEFAULT_LEVELS = 6 };
/* The 600 m city's finest voxel: its coarsest of 6 levels spans 1.25 x 600 m. */
static const double CITY600_S0 = 1.25 * 600.0 / (R * 32.0);

/* |a - b| <= tol, saying both values when not. */
#define assert_near(a, b, tol) near_((a), (b), (tol), #a, __LINE__)
static void near_(double a, double b, double tol, const char *what, int line) {
  if (fabs(a - b) <= tol) return;
  print_error("line %d: %s = %.17g, expected %.17g within %g\n", line, what, a, b, tol);
  fail();
}

static gi_quality resolve(const gi_scene *s, const gi_quality *in) {
  gi_quality q;
  gi_error_info err = {0};
  assert_int_equal(gi_quality_resolve(s, in, &q, &err), GI_OK);
  return q;
}

static gi_scene *city(double extent, int detail) {
  gi_city_params p = {.extent = extent, .detail = detail};
  gi_scene *s = NULL;
  gi_error_info err = {0};
  assert_int_equal(gi_city_build(&p, NULL, &s, &err), GI_OK);
  return s;
}

/* A ground square of side w with one box of height h in the middle, built
 * `scale` times larger (a scene in millimetres is the same scene). */
static gi_scene *plain(double w, double h, double scale) {
  gi_mesh_builder *b = gi_mesh_builder_new();
  gi_material m = {.albedo = {0.5f, 0.5f, 0.5f}, .roughness = 1};
  uint32_t mat = gi_mesh_builder_add_material(b, &m);
  double A[3] = {-w / 2, 0, -w / 2}, B[3] = {-w / 2, 0, w / 2}, C[3] = {w / 2, 0, w / 2}, D[3] = {w / 2, 0, -w / 2};
  gi_mesh_builder_add_quad(b, A, B, C, D, mat);
  if (h > 0) {
    double lo[3] = {-h / 2, 0, -h / 2}, hi[3] = {h / 2, h, h / 2};
    gi_mesh_builder_add_box(b, lo, hi, mat);
  }
  gi_scene_options o = {.scale = scale, .default_lights = 1};
  gi_scene *s = NULL;
  gi_error_info err = {0};
  assert_int_equal(gi_scene_build(b, "plain", &o, &s, &err), GI_OK);
  gi_mesh_builder_free(b);
  return s;
}

/* The shipped compact scenes keep the shape their accuracy figures were
 * measured with: 6 levels, the coarsest spanning 1.25x the largest side. */
static void test_compact_scenes_keep_extent_rule(void **state) {
  (void)state;
  gi_scene *s = city(600, 0);
  gi_quality q = resolve(s, NULL);
  assert_int_equal(q.levels, DEFAULT_LEVELS);
  assert_near(q.voxel0, CITY600_S0, 1e-12);
  gi_scene_release(s);

  TU_SKIP_IF_NO_SCENE(cornell, "cornell-box/cornell-box.obj");
  gi_error_info err = {0};
  assert_int_equal(gi_scene_load(cornell, NULL, &s, &err), GI_OK);
  q = resolve(s, NULL);
  assert_int_equal(q.levels, DEFAULT_LEVELS);
  assert_near(q.voxel0, 1.25 * 559.2 / (R * 32.0), 1e-3); /* millimetres: the box is 559.2 deep */
  gi_scene_release(s);

  TU_SKIP_IF_NO_SCENE(munich, "munich/munich.obj");
  gi_scene_options zo = {.up = GI_UP_Z};
  assert_int_equal(gi_scene_load(munich, &zo, &s, &err), GI_OK);
  q = resolve(s, NULL);
  assert_int_equal(q.levels, DEFAULT_LEVELS);
  assert_near(q.voxel0, 1.80, 0.01); /* 1,475 m wide, 99 m tall: 15 heights, within reach */
  gi_scene_release(s);
}

/* The 5 km city is 42 heights wide, beyond a street's reach of 16: its
 * coarsest level keeps that reach and levels are added at the fine end
 * until s0 is no coarser than a compact piece's (4 heights across). The
 * piece's s0 (0.58 m for 119 m towers) is within a factor of 2 of the
 * 600 m city's (0.73 m): each added level halves s0, so the rule lands
 * within one halving of any target. Before, it was 2.32 m. */
static void test_wide_city_adds_levels(void **state) {
  (void)state;
  gi_scene *s = city(5000, 1);
  double lo[3], hi[3];
  gi_scene_bounds(s, lo, hi);
  double height = hi[1] - lo[1], reach = 16 * height;
  /* A street-level viewpoint: the plan resolves what the bake will use. */
  double at[3];
  gi_city_params p = {.extent = 5000};
  gi_city_default_viewpoint(&p, at);
  gi_effect fx[GI_FX_COUNT];
  gi_quality q;
  gi_error_info err = {0};
  assert_int_equal(gi_effect_plan(s, at, NULL, fx, &q, &err), GI_OK);
  assert_true(q.levels > DEFAULT_LEVELS);
  assert_int_equal(q.levels, DEFAULT_LEVELS + 2);
  assert_true(q.voxel0 <= CITY600_S0 && q.voxel0 >= 0.5 * CITY600_S0);
  assert_near(q.voxel0, 1.25 * 4 * height / (R * 32.0), 1e-9);
  /* The coarsest level reaches as far as before: 1.25 x 16 heights. */
  assert_near(q.voxel0 * R * (double)(1 << (q.levels - 1)), 1.25 * reach, 1e-6);
  /* The cascade costs levels x R^3 voxels: 8/6 of the default's. */
  gi_quality q6 = resolve(s, &(gi_quality){.levels = DEFAULT_LEVELS});
  assert_true(gi_cascade_bytes_estimate(&q) * DEFAULT_LEVELS == gi_cascade_bytes_estimate(&q6) * q.levels);

  /* An explicit level count or voxel size wins: the old shape. */
  assert_near(q6.voxel0, 1.25 * reach / (R * 32.0), 1e-9);
  gi_quality qv = resolve(s, &(gi_quality){.voxel0 = 0.5});
  assert_int_equal(qv.levels, DEFAULT_LEVELS);
  assert_true(qv.voxel0 == 0.5);
  gi_scene_release(s);
}

/* Levels stop at GI_MAX_LEVELS: beyond, s0 grows with the reach again, so
 * memory stays at most GI_MAX_LEVELS x R^3 voxels. No unit is assumed: the
 * same plain in millimetres gets the same levels and 1000x the voxel. */
static void test_levels_capped_and_unit_free(void **state) {
  (void)state;
  const double w = 1e5, h = 1; /* reach w/8 = 12,500 heights, a piece is 4 */
  gi_scene *m = plain(w, h, 1), *mm = plain(w, h, 1000);
  gi_quality a = resolve(m, NULL), b = resolve(mm, NULL);
  assert_int_equal(a.levels, GI_MAX_LEVELS);
  assert_near(a.voxel0, 1.25 * (w / 8) / (R * (double)(1 << (GI_MAX_LEVELS - 1))), 1e-9);
  assert_int_equal(b.levels, a.levels);
  assert_near(b.voxel0 / a.voxel0, 1000, 1e-6);
  gi_scene_release(m);
  gi_scene_release(mm);

  /* Just past reach, a piece's s0 is a quarter of the reach's: two levels. */
  m = plain(32 * 8, 8, 1); /* 32 heights wide: reach 16 heights */
  a = resolve(m, NULL);
  assert_int_equal(a.levels, DEFAULT_LEVELS + 2);
  gi_scene_release(m);
  m = plain(20 * 8, 8, 1); /* 20 heights wide: reach 16 heights, 4 pieces */
  a = resolve(m, NULL);
  assert_int_equal(a.levels, DEFAULT_LEVELS + 2);
  gi_scene_release(m);
  m = plain(16 * 8, 8, 1); /* 16 heights wide: within reach, the extent rule */
  a = resolve(m, NULL);
  assert_int_equal(a.levels, DEFAULT_LEVELS);
  assert_near(a.voxel0, 1.25 * 128 / (R * 32.0), 1e-12);
  gi_scene_release(m);

  /* A flat plane has no height to make a piece of, nor anything to
   * shade it from afar: the coarsest level spans all of it. (It spanned an
   * eighth, and a 10 m floor's lightmap took 676 tiles or failed.) */
  m = plain(w, 0, 1);
  a = resolve(m, NULL);
  assert_int_equal(a.levels, DEFAULT_LEVELS);
  assert_near(a.voxel0, 1.25 * w / (R * 32.0), 1e-9);
  gi_scene_release(m);

  /* A plane whose height is rounding (Blender's 20 m plane, turned, is
   * 8.7e-7 m high) is flat too: it took 12 levels and a 4.8e-5 m voxel. */
  gi_mesh_builder *bn = gi_mesh_builder_new();
  gi_material mat = {.albedo = {0.5f, 0.5f, 0.5f}, .roughness = 1};
  uint32_t mi = gi_mesh_builder_add_material(bn, &mat);
  double A[3] = {-10, 0, -10}, B[3] = {-10, 4.4e-7, 10}, C[3] = {10, 8.7e-7, 10}, D[3] = {10, 4.4e-7, -10};
  gi_mesh_builder_add_quad(bn, A, B, C, D, mi);
  gi_scene_options o = {.default_lights = 1};
  gi_error_info err = {0};
  assert_int_equal(gi_scene_build(bn, "noise", &o, &m, &err), GI_OK);
  gi_mesh_builder_free(bn);
  a = resolve(m, NULL);
  printf("  a 20 m plane 8.7e-7 high: %d levels, s0 %g\n", a.levels, a.voxel0);
  assert_int_equal(a.levels, DEFAULT_LEVELS);
  assert_near(a.voxel0, 1.25 * 20.0 / (R * 32.0), 1e-9);
  /* A voxel size past GI_MAX_VOXEL is refused by name (1e38 failed deep in
   * the bake with "triangle query ... non-finite value"). */
  gi_quality big = {.voxel0 = 1e38}, out;
  assert_int_equal(gi_quality_resolve(m, &big, &out, &err), GI_ERR_INVALID_ARG);
  assert_non_null(strstr(err.msg, "voxel size must be at most"));
  big.voxel0 = GI_MAX_VOXEL;
  assert_int_equal(gi_quality_resolve(m, &big, &out, &err), GI_OK);
  /* A tiny given voxel is the anchor's to judge (test_anchor), but its AO
   * falloff 1 / 4 s0 stays a float (1e-40 gave Inf, failing after the bake). */
  big.voxel0 = 1e-40;
  assert_int_equal(gi_quality_resolve(m, &big, &out, &err), GI_OK);
  assert_true(isfinite(out.ao_lambda) && out.ao_lambda > 0);
  gi_scene_release(m);
  /* A default outside that range is refused by name: a box 1e10 across
   * baked half its indirect light, 1e12 a NaN probe, 1e-10 nothing at all. */
  const double sides[3] = {1e10, 1e12, 1e-10};
  for (int i = 0; i < 3; i++) {
    m = plain(sides[i], sides[i], 1);
    assert_int_equal(gi_quality_resolve(m, NULL, &out, &err), GI_ERR_INVALID_ARG);
    printf("  a box %g across: %s\n", sides[i], err.msg);
    assert_non_null(strstr(err.msg, sides[i] > 1 ? "too large for a default voxel" : "too small for a default voxel"));
    gi_scene_release(m);
  }
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_compact_scenes_keep_extent_rule),
      cmocka_unit_test(test_wide_city_adds_levels),
      cmocka_unit_test(test_levels_capped_and_unit_free),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
