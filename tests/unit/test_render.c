/* test_render.c: camera views against closed-form answers.
 *
 * A plane of albedo a under a sun of irradiance E at 60 degrees, seen from
 * above: every pixel that sees the plane shows L = a E cos60 / pi, in the
 * cone-traced view (one shadow ray, nothing to bounce) and in the
 * path-traced one (the continuation rays all escape), exactly up to float
 * rounding. The Cornell box's Mitsuba sensor is read as published (shared
 * scene; skips loudly when absent). Bad cameras name the field. */
#include "test_util.h"
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "gi/gi.h"

static void test_plane_under_sun(void **state) {
  const double c60 = 0.5, a = 0.5, E = 3.0;
  gi_scene *s = tu_sunlit_plane(a, E, 100);
  gi_error_info err = {0};
  gi_quality q = {.levels = 2, .res = 16, .voxel0 = 1};
  gi_cascade *c = NULL;
  double at[3] = {0, 1, 0};
  assert_int_equal(gi_cascade_bake(s, at, &q, &c, NULL, &err), GI_OK);
  gi_camera cam = {.eye = {0, 5, 0}, .target = {0, 0, 0}, .up = {0, 0, 1}, .fov_deg = 40, .width = 16, .height = 12};
  float cone[16 * 12 * 3], path[16 * 12 * 3];
  assert_int_equal(gi_cascade_render(c, &cam, 0, 0, cone, NULL, &err), GI_OK);
  assert_int_equal(gi_reference_render(s, &cam, 4, 1, 0, path, NULL, &err), GI_OK);
  double want = a * E * c60 / 3.14159265358979;
  printf("plane: cone %.6f, path %.6f, exact %.6f\n", cone[0], path[0], want);
  for (int i = 0; i < 16 * 12 * 3; i++) {
    assert_true(fabs(path[i] - want) < 1e-5);
    /* The cone view adds what the voxels bounce back: a flat plane has nothing above it. */
    assert_true(fabs(cone[i] - want) < 1e-3 * want);
  }
  /* A PNG of it: written atomically, non-empty. */
  const char *png = tu_write_file("view.png", "", 0);
  assert_int_equal(gi_image_write_png(png, cone, 16, 12, 1.0f, &err), GI_OK);
  FILE *f = fopen(png, "rb");
  unsigned char sig[8] = {0};
  assert_non_null(f);
  assert_int_equal(fread(sig, 1, 8, f), 8);
  fclose(f);
  assert_memory_equal(sig, "\x89PNG\r\n\x1a\n", 8);
  gi_cascade_free(c);
  gi_scene_release(s);
}

static void test_mitsuba_camera(void **state) {
  TU_SKIP_IF_NO_SCENE(path, "cornell-box/cbox-mitsuba.xml");
  gi_camera cam = {0};
  gi_error_info err = {0};
  assert_int_equal(gi_camera_from_mitsuba(path, &cam, &err), GI_OK);
  printf("cbox camera: eye %g %g %g, target %g %g %g, up %g %g %g, fov %g\n", cam.eye[0], cam.eye[1], cam.eye[2],
         cam.target[0], cam.target[1], cam.target[2], cam.up[0], cam.up[1], cam.up[2], cam.fov_deg);
  assert_true(cam.eye[0] == 278 && cam.eye[1] == 273 && cam.eye[2] == -800);
  assert_true(cam.target[2] == -799 && cam.up[1] == 1 && cam.up[0] == 0);
  assert_true(fabs(cam.fov_deg - 39.3077) < 1e-9);
}

static void test_bad_cameras(void **state) {
  gi_error_info err = {0};
  gi_camera cam = {.eye = {0, 0, 0}, .target = {0, 0, 0}, .up = {0, 1, 0}, .fov_deg = 40, .width = 8, .height = 8};
  assert_int_equal(gi_camera_validate(&cam, &err), GI_ERR_INVALID_ARG);
  assert_non_null(strstr(err.msg, "same point"));
  cam.target[2] = 1, cam.fov_deg = 180;
  assert_int_equal(gi_camera_validate(&cam, &err), GI_ERR_INVALID_ARG);
  assert_non_null(strstr(err.msg, "fov"));
  cam.fov_deg = 40, cam.up[1] = 0, cam.up[2] = 1;
  assert_int_equal(gi_camera_validate(&cam, &err), GI_ERR_INVALID_ARG);
  assert_non_null(strstr(err.msg, "up"));
  cam.up[1] = 1, cam.up[2] = 0, cam.eye[0] = NAN;
  assert_int_equal(gi_camera_validate(&cam, &err), GI_ERR_NONFINITE);
  const char *bad = "<scene><sensor type=\"perspective\"><float name=\"fov\" value=\"x\"/></sensor></scene>";
  const char *xml = tu_write_file("cam.xml", bad, strlen(bad));
  assert_int_equal(gi_camera_from_mitsuba(xml, &cam, &err), GI_ERR_FORMAT);
  assert_non_null(strstr(err.msg, "fov"));
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_plane_under_sun),
      cmocka_unit_test(test_mitsuba_camera),
      cmocka_unit_test(test_bad_cameras),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
