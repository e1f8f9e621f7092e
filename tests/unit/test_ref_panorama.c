/* test_ref_panorama.c: the path-traced lat-long panorama
 * (gi_reference_panorama) against answers known exactly, and its pixel
 * layout against the cone-traced one (gi_cascade_panorama).
 *
 * 1. A plane of albedo 0.5 under a sun at 60 degrees, no sky, seen from 3
 *    up: every path into a row looking down steeply enough to stay on the
 *    plane brings exactly a E cos60 / pi (next-event estimation of the
 *    sun, the continuation escapes into the black sky); every row looking
 *    up is exactly 0.
 * 2. One emissive square (albedo 0, facing the eye) 5 away along an axis:
 *    the pixels whose whole cell sees it show exactly Le, pixels looking
 *    away 0; with up Y it is at azimuth 90 degrees (columns 3-4 of 16, the
 *    middle rows), with up Z the same square is straight up (row 0). The
 *    cone-traced panorama's direct image agrees on those pixels.
 * 3. The cone-traced panorama marches a row's cones as one batch: inside
 *    a lit room, every pixel's indirect light is what one cone along its
 *    direction gathers alone (gi__gather_cone), to float rounding. */
#include "test_util.h"
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "gi/gi.h"
#include "trace/trace.h"

enum { W = 16, H = 16 };

static void test_plane_rows(void **state) {
  const double a = 0.5, E = 3.0;
  gi_scene *s = tu_sunlit_plane(a, E, 100);
  gi_error_info err = {0};
  static float img[W * H * 3];
  const double at[3] = {0, 3, 0};
  gi_render_opts o = {.spp = 8, .seed = 5, .threads = 2};
  double ms = 0;
  assert_int_equal(gi_reference_panorama(s, at, W, H, &o, img, &ms, &err), GI_OK);
  assert_true(ms > 0);
  const float L = (float)(a * E * 0.5 / M_PI);
  /* Rows 0-7 look up (polar angle < 90 degrees); rows 10-15 down at least
   * 22.5 degrees below the horizon: within 3 tan(67.5) = 7.2 of the foot. */
  for (int y = 0; y < H; y++)
    for (int x = 0; x < W; x++)
      for (int k = 0; k < 3; k++) {
        float v = img[3 * (y * W + x) + k];
        if (y < H / 2) assert_true(v == 0.f);
        else if (y >= 10) assert_true(fabsf(v - L) < 1e-5f * L);
      }
  printf("plane rows: %.6f (exact %.6f), %.1f ms\n", img[3 * (12 * W + 5)], L, ms);
  /* Bad arguments name themselves. */
  assert_int_equal(gi_reference_panorama(s, at, 1, H, &o, img, NULL, &err), GI_ERR_INVALID_ARG);
  const double far[3] = {NAN, 0, 0};
  assert_int_not_equal(gi_reference_panorama(s, far, W, H, &o, img, NULL, &err), GI_OK);
  gi_render_opts bad = {.spp = -1};
  assert_int_equal(gi_reference_panorama(s, at, W, H, &bad, img, NULL, &err), GI_ERR_INVALID_ARG);
  gi_scene_release(s);
}

/* The square z = 5, |x|, |y| <= 5, emitting toward -z, and a floor far
 * below it so the bake has a box to place; returns the scene. */
static gi_scene *square_scene(gi_up_axis up, float Le) {
  gi_mesh_builder *b = gi_mesh_builder_new();
  gi_material em = {.emission = {Le, Le, Le}, .roughness = 1};
  uint32_t mat = gi_mesh_builder_add_material(b, &em);
  /* (B - A) x (C - A) points along -z: toward the eye at the origin. */
  double A[3] = {-5, -5, 5}, B[3] = {-5, 5, 5}, C[3] = {5, 5, 5}, D[3] = {5, -5, 5};
  gi_mesh_builder_add_quad(b, A, B, C, D, mat);
  gi_scene_options opt = {.up = up};
  gi_scene *s = NULL;
  gi_error_info err = {0};
  assert_int_equal(gi_scene_build(b, "square", &opt, &s, &err), GI_OK);
  gi_mesh_builder_free(b);
  return s;
}

static void check_square(gi_up_axis up) {
  const float Le = 10;
  gi_scene *s = square_scene(up, Le);
  static float ref[W * H * 3], dir[W * H * 3], ind[W * H * 3];
  const double at[3] = {0, 0, 0};
  gi_render_opts o = {.spp = 16, .seed = 3, .threads = 2};
  gi_error_info err = {0};
  assert_int_equal(gi_reference_panorama(s, at, W, H, &o, ref, NULL, &err), GI_OK);
  gi_quality q = {.levels = 2, .res = 16, .voxel0 = 1, .threads = 2};
  gi_cascade *c = NULL;
  assert_int_equal(gi_cascade_bake(s, at, &q, &c, NULL, &err), GI_OK);
  assert_int_equal(gi_cascade_panorama(c, at, W, H, dir, ind, NULL, &err), GI_OK);
  /* Cells wholly on the square, and cells looking the other way. */
  int lit[4][2], dark[4][2];
  if (up == GI_UP_Y) { /* +z is azimuth 90 degrees: columns 3-4; the horizon rows 7-8 */
    int l[4][2] = {{3, 7}, {4, 7}, {3, 8}, {4, 8}}, d[4][2] = {{11, 7}, {12, 8}, {0, 0}, {7, 15}};
    memcpy(lit, l, sizeof lit), memcpy(dark, d, sizeof dark);
  } else { /* +z is straight up: row 0 (polar angle < 11.25 degrees) */
    int l[4][2] = {{0, 0}, {5, 0}, {9, 0}, {15, 0}}, d[4][2] = {{0, 15}, {5, 15}, {3, 8}, {11, 7}};
    memcpy(lit, l, sizeof lit), memcpy(dark, d, sizeof dark);
  }
  for (int i = 0; i < 4; i++) {
    size_t p = 3 * ((size_t)lit[i][1] * W + (size_t)lit[i][0]), q0 = 3 * ((size_t)dark[i][1] * W + (size_t)dark[i][0]);
    for (int k = 0; k < 3; k++) {
      assert_true(fabsf(ref[p + k] - Le) < 1e-5f * Le);
      assert_true(dir[p + k] == Le);
      assert_true(ref[q0 + k] == 0.f && dir[q0 + k] == 0.f);
    }
  }
  gi_cascade_free(c);
  gi_scene_release(s);
}

/* 3: the batched row against one cone at a time (the pixel directions of
 * panorama.c: polar angle from the up axis, azimuth from +x). */
static void test_cones_batched(void **state) {
  gi_scene *s = tu_lit_room(0.7f);
  gi_error_info err = {0};
  gi_quality q = {.levels = 3, .res = 32, .voxel0 = 0.125, .threads = 2};
  gi_cascade *c = NULL;
  const double at[3] = {0.3, 1.2, -0.2};
  assert_int_equal(gi_cascade_bake(s, at, &q, &c, NULL, &err), GI_OK);
  enum { PW = 96, PH = 48 };
  static float dir[PW * PH * 3], ind[PW * PH * 3];
  assert_int_equal(gi_cascade_panorama(c, at, PW, PH, dir, ind, NULL, &err), GI_OK);
  const float p[3] = {(float)(at[0] - c->scene->origin[0]), (float)(at[1] - c->scene->origin[1]),
                      (float)(at[2] - c->scene->origin[2])};
  gi_gather_start g;
  assert_true(gi__gather_start(c, p, NULL, GI_GATHER_FREE, -1, &g));
  float tan_half = tanf(0.5f * (float)M_PI / (float)PH);
  double worst = 0, sum = 0;
  for (int y = 0; y < PH; y++)
    for (int x = 0; x < PW; x++) {
      float th = (float)M_PI * ((float)y + 0.5f) / (float)PH, ph = 2 * (float)M_PI * ((float)x + 0.5f) / (float)PW;
      float w[3] = {sinf(th) * cosf(ph), cosf(th), sinf(th) * sinf(ph)};
      gi_cone_out one;
      gi__gather_cone(c, &g, w, tan_half, &one);
      for (int k = 0; k < 3; k++) {
        float v = ind[3 * (y * PW + x) + k];
        assert_true(one.L[k] > 0);
        double e = fabs(v - one.L[k]) / one.L[k];
        worst = fmax(worst, e), sum += one.L[k];
      }
    }
  printf("room panorama: %d cones batched by row against one at a time: largest relative difference %.2g "
         "(mean radiance %.4f)\n", PW * PH, worst, sum / (3.0 * PW * PH));
  assert_true(worst < 1e-4);
  gi_cascade_free(c);
  gi_scene_release(s);
}

static void test_square_up_y(void **state) { check_square(GI_UP_Y); }
static void test_square_up_z(void **state) { check_square(GI_UP_Z); }

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_plane_rows),
      cmocka_unit_test(test_square_up_y),
      cmocka_unit_test(test_square_up_z),
      cmocka_unit_test(test_cones_batched),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
