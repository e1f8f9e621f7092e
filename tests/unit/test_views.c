/* test_views.c: gi-accuracy's camera-view comparison (tools/gi-accuracy/views.c)
 * on a view whose answer is known.
 *
 * A plane of albedo 0.5 under a sun at 60 degrees, no sky: every pixel
 * that sees the plane shows L = a E cos60 / pi in both renderers (the
 * cone view exactly up to float rounding plus what the voxels bounce back
 * from a flat plane: nothing; the path tracer exactly, every continuation
 * escapes), and every other pixel is black in both (the sky is black):
 * those are left out of the error. So the comparison must count exactly
 * the plane's pixels, measure ~0 error for the cone and every path-tracer
 * sample count, estimate ~0 noise for the reference, read the reference
 * back from its cache the second time with the same figures, and write
 * the picture. */
#include "test_util.h"
#include <math.h>
#include <stdio.h>
#include <string.h>
#include "acc.h"
#include "gi/gi.h"

static void test_plane_view(void **state) {
  const double a = 0.5, E = 3.0;
  /* The plane y = 0 over x in [-100, 100], z in [-100, 10]. */
  gi_scene *s = tu_sunlit_plane(a, E, 10);

  /* From 3 up, looking at the plane's far edge (0, 0, 10): the edge is a
   * horizontal line through the image centre, the border between rows 7
   * and 8 of 16, and the plane is wider than the view. So rows 8..15 see
   * only the plane, every sample of them, path-traced with jitter or not;
   * rows 0..7 only the black sky. */
  gi_camera cam = {.eye = {0, 3, 0}, .target = {0, 0, 10}, .up = {0, 1, 0}, .fov_deg = 60, .width = 24, .height = 16};
  const size_t plane_px = 8 * 24;

  const char *dir = tu_tmpdir();
  char png[1024];
  snprintf(png, sizeof png, "%s/view-plane.png", dir);
  const double at[3] = {0, 1, 4};
  acc_view v1, v2;
  assert_int_equal(acc_run_view("plane", s, at, &cam, 64, 0, 1, dir, png, 1, &v1), 1);
  printf("cone MRE %.3g (bake %.1f + render %.1f ms), reference's own %.3g, path MRE at 1 spp %.3g\n", v1.cone_mre,
         v1.cone_bake_ms, v1.cone_render_ms, v1.ref_mre, v1.path_mre[0]);
  assert_int_equal(v1.pixels, plane_px);
  assert_true(v1.ref_ms > 0);
  assert_true(v1.ref_mre < 1e-5);
  assert_true(v1.cone_mre < 1e-3);
  /* A flat, uniform region in both: structurally identical. */
  assert_true(fabs(v1.cone_ssim - 1) < 1e-6);
  /* 1, 4 and 16 paths per pixel: a quarter of the 64-path reference. */
  assert_int_equal(v1.num_path, 3);
  for (int k = 0; k < v1.num_path; k++) assert_true(v1.path_mre[k] < 1e-5 && fabs(v1.path_ssim[k] - 1) < 1e-6);
  /* Again: the reference comes from the cache, and the figures are the same. */
  assert_int_equal(acc_run_view("plane", s, at, &cam, 64, 0, 1, dir, png, 1, &v2), 1);
  assert_true(v2.ref_ms == 0);
  assert_true(v2.ref_mre == v1.ref_mre && v2.cone_mre == v1.cone_mre && v2.pixels == v1.pixels);
  FILE *pf = fopen(png, "rb");
  unsigned char sig[8] = {0};
  assert_non_null(pf);
  assert_int_equal(fread(sig, 1, 8, pf), 8);
  fclose(pf);
  assert_memory_equal(sig, "\x89PNG\r\n\x1a\n", 8);
  gi_scene_release(s);
}

static void test_image_metrics(void **state) {
  /* 16 x 16, flat: the reference shows display value 0.5, the test image
   * 0.25 (linear 0.5^2.2 and 0.25^2.2, grey, exposure 1). Within a window
   * both variances are 0, so SSIM is the luminance term alone:
   * (2 * 0.5 * 0.25 + C1) / (0.5^2 + 0.25^2 + C1), C1 = 1e-4: 0.800064. */
  enum { W = 16 };
  static float a[W * W * 3], r[W * W * 3];
  static unsigned char mask[W * W];
  for (int i = 0; i < W * W * 3; i++) r[i] = (float)pow(0.5, 2.2), a[i] = (float)pow(0.25, 2.2);
  memset(mask, 1, sizeof mask);
  double ssim = acc_image_ssim(a, r, mask, W, W, 1.0);
  printf("ssim %.6f (exact 0.800064)\n", ssim);
  assert_true(fabs(ssim - (0.25 + 1e-4) / (0.3125 + 1e-4)) < 1e-5);
  /* MRE: |0.25^2.2 - 0.5^2.2| / 0.5^2.2 = 1 - 0.5^2.2 = 0.782371. */
  double mre = acc_image_mre(a, r, mask, W * W, 0);
  assert_true(fabs(mre - (1 - pow(0.5, 2.2))) < 1e-5);
  /* Masked pixels do not count; windows that touch them do not either. */
  for (int i = 0; i < W * W / 2; i++) a[3 * i] = a[3 * i + 1] = a[3 * i + 2] = 100, mask[i] = 0;
  assert_true(fabs(acc_image_mre(a, r, mask, W * W, 0) - (1 - pow(0.5, 2.2))) < 1e-5);
  assert_true(fabs(acc_image_ssim(a, r, mask, W, W, 1.0) - ssim) < 1e-9);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_image_metrics),
      cmocka_unit_test(test_plane_view),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
